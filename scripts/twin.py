#!/usr/bin/env python3
"""The drilling-pump digital twin (docs/twin.md): measured crank data in, the FMU's loads out.

    .venv/bin/python scripts/twin.py data/twin/pump_encoder.csv --angle-unit counts --counts-per-rev 4096
    producer | .venv/bin/python scripts/twin.py - --live ...          # samples on standard input
    .venv/bin/python scripts/twin.py growing.csv --follow --live ...   # follow a growing file

Writes --out (every sample: time and every FMU output), --summary (one row per completed crank
revolution) and, with --plots DIR, time series, the card and per-revolution trends. With
--checkpoint FILE the FMU's state and the twin's position are saved every --checkpoint-every
samples and at the end; --resume FILE continues a run from its checkpoint.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import queue
import sys
import threading
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive.batch import format_csv  # noqa: E402
from reciprocating_drive.fmu import FmuError  # noqa: E402
from reciprocating_drive.twin import SUMMARY_FIELDS, DataError, Options, Twin, save_checkpoint  # noqa: E402


def chunks_of(raw, follow: bool, size: int, poll: float = 0.05):
    """Lists of consecutive lines of a binary stream, each list as soon as it is available: one
    read blocks until there is at least one complete line, and takes whatever else has arrived
    (a pipe or a growing file gives what is there now; a file gives blocks of `size` bytes). With
    `follow`, waits for more at the end until a line 'EOF'; a line still being written waits for
    its end. Bytes that are not UTF-8 become U+FFFD (and are reported as not a number)."""
    tail = b""
    while True:
        data = raw.read(size)
        if not data:
            if follow:
                time.sleep(poll)
                continue
            if tail:
                yield [tail.decode("utf-8", "replace")]
            return
        data = tail + data
        cut = data.rfind(b"\n")
        if cut < 0:
            tail = data
            continue
        lines, tail = data[:cut].decode("utf-8", "replace").split("\n"), data[cut + 1 :]
        if follow:
            ends = [i for i, line in enumerate(lines) if line.strip() == "EOF"]
            if ends:
                if ends[0]:
                    yield lines[: ends[0]]
                return
        yield lines


class Writer:
    """Writes the output rows (CSV formatted natively) and makes and writes the revolution
    summaries on a worker thread, in order: this runs on the second core while the FMU computes
    the next chunk (the native calls release the GIL, and the FMU's is most of the main thread's
    time). With `live` every chunk is flushed once written. `wait()` returns when everything put
    is written. A failure of the worker is raised once, in the main thread, by the next `put` or
    `wait`; after it nothing more is written."""

    def __init__(self, twin, out, summ, live: bool):
        self.twin, self.out, self.summ, self.live = twin, out, summ, live
        self.q: queue.Queue = queue.Queue(maxsize=8)
        self.text = bytearray()  # format_csv's buffer, reused
        self.error = None
        self.reported = False
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def put(self, rows, pieces) -> None:
        """Rows to write, and the pieces of the summaries (Twin.defer_summaries)."""
        self._raise()
        if len(rows) or pieces:
            self.q.put((rows, pieces))

    def _run(self) -> None:
        while True:
            rows, pieces = self.q.get()
            try:
                if self.error is None:
                    # The rows first: formatting them is native and leaves Python's lock to the
                    # main thread, which is parsing and conditioning the next chunk; the summaries
                    # (Python) then run while the main thread is in the FMU's native batch.
                    if len(rows):
                        self.out.write(format_csv(rows, self.text))
                    sums = self.twin.summaries(pieces)
                    for s in sums:
                        self.summ.write(",".join(fmt(s[k]) for k in SUMMARY_FIELDS) + "\n")
                    if self.live:
                        self.out.flush()
                        self.summ.flush()
            except BaseException as e:  # noqa: BLE001 - re-raised in the main thread by wait()
                self.error = e
            finally:
                self.q.task_done()

    def wait(self) -> None:
        self.q.join()
        self._raise()

    def _raise(self) -> None:
        if self.error is not None and not self.reported:
            self.reported = True
            raise self.error


def fmt(v) -> str:
    return "" if v is None else repr(v)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("input", help="CSV file, or - for standard input")
    ap.add_argument("--fmu", default=str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
    ap.add_argument("--machine", default="default", help="a preset, 'default', or an .ssv file")
    ap.add_argument("--angle-unit", choices=("rad", "deg", "counts"), default="rad")
    ap.add_argument("--counts-per-rev", type=float, default=None)
    ap.add_argument(
        "--continuous",
        action="store_true",
        help="angles do not wrap (default: wrapped every revolution)",
    )
    ap.add_argument("--speed-unit", choices=("rad/s", "rpm"), default="rad/s")
    ap.add_argument(
        "--ignore-speed",
        action="store_true",
        help="estimate ω from the angle even if crank_speed is given",
    )
    ap.add_argument("--duplicates", choices=("drop", "error"), default="drop")
    ap.add_argument("--window", type=float, default=0.1, help="smoothing window [s] (default 0.1)")
    ap.add_argument(
        "--gap-limit",
        type=float,
        default=0.05,
        help="a longer interval is a gap [s] (default 0.05)",
    )
    ap.add_argument(
        "--max-speed",
        type=float,
        default=100.0,
        help="fastest possible crank speed [rad/s] (default 100)",
    )
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "twin" / "outputs.csv")
    ap.add_argument(
        "--summary", type=pathlib.Path, default=None, help="default: <out>-revolutions.csv"
    )
    ap.add_argument(
        "--plots", type=pathlib.Path, default=None, help="folder for the plots (replay)"
    )
    ap.add_argument(
        "--live", action="store_true", help="flush every output line as soon as it is computed"
    )
    ap.add_argument(
        "--follow", action="store_true", help="follow a growing file (ends at a line 'EOF')"
    )
    ap.add_argument("--checkpoint", type=pathlib.Path, default=None)
    ap.add_argument("--checkpoint-every", type=int, default=10000)
    ap.add_argument(
        "--resume", type=pathlib.Path, default=None, help="continue from this checkpoint"
    )
    ap.add_argument(
        "--stop-after",
        type=int,
        default=None,
        help="stop after this many input lines (and checkpoint)",
    )
    a = ap.parse_args(argv)

    summary = a.summary or a.out.with_name(a.out.stem + "-revolutions.csv")
    opts = Options(
        angle_unit=a.angle_unit,
        counts_per_rev=a.counts_per_rev,
        wrapped=not a.continuous,
        speed_unit=a.speed_unit,
        duplicates=a.duplicates,
        window=a.window,
        gap_limit=a.gap_limit,
        max_speed=a.max_speed,
        use_measured_speed=not a.ignore_speed,
    )
    a.out.parent.mkdir(parents=True, exist_ok=True)
    try:
        if a.resume:
            cp = json.loads(a.resume.read_text())
            twin = Twin.from_checkpoint(a.fmu, cp)
            skip = cp["lines_read"]
            for path, size in ((a.out, cp["out_bytes"]), (summary, cp["summary_bytes"])):
                with open(path, "r+b") as f:
                    f.truncate(size)
            out, summ = open(a.out, "ab"), open(summary, "a")
        else:
            twin = Twin(a.fmu, a.machine, opts)
            skip = 0
            out, summ = open(a.out, "wb"), open(summary, "w")
            out.write((",".join(twin.header) + "\n").encode())
            summ.write(",".join(SUMMARY_FIELDS) + "\n")
        # Ready: the headers are out before the first sample is read.
        out.flush()
        summ.flush()
    except (FmuError, KeyError, OSError, ValueError) as e:
        print(f"twin.py: {e}", file=sys.stderr)
        return 2

    # Unbuffered reads: each returns what is available now (live), or a large block (replay).
    src = sys.stdin.buffer.raw if a.input == "-" else open(a.input, "rb", buffering=0)
    # Blocks of at most 64 KiB (about 2000 lines): what a pipe holds, bounded memory in replay,
    # and chunks small enough that writing one overlaps computing the next.
    size = 1 << 16
    twin.defer_summaries = True  # made on the writer's thread
    writer = Writer(twin, out, summ, a.live)
    emit = writer.put

    def checkpoint():
        writer.wait()
        out.flush()
        summ.flush()
        cp = twin.checkpoint()
        cp["out_bytes"], cp["summary_bytes"] = out.tell(), summ.tell()
        save_checkpoint(a.checkpoint, cp)

    lineno = 0  # input lines consumed
    n_since = 0  # lines since the last checkpoint
    try:
        for lines in chunks_of(src, a.follow, size):
            if lineno + len(lines) <= skip:
                lineno += len(lines)
                continue
            if lineno < skip:
                lines, lineno = lines[skip - lineno :], skip
            while lines:
                # Cut the chunk where a checkpoint or --stop-after falls.
                take = len(lines)
                if a.checkpoint:
                    take = min(take, a.checkpoint_every - n_since)
                if a.stop_after:
                    take = min(take, a.stop_after - lineno)
                emit(*twin.feed(lines[:take], lineno + 1))
                lines, lineno, n_since = lines[take:], lineno + take, n_since + take
                if a.checkpoint and n_since >= a.checkpoint_every:
                    checkpoint()
                    n_since = 0
                if a.stop_after and lineno >= a.stop_after:
                    if a.checkpoint:
                        checkpoint()
                    writer.wait()
                    out.close()
                    summ.close()
                    print(
                        f"stopped after line {lineno}"
                        + (f"; checkpoint {a.checkpoint}" if a.checkpoint else "")
                    )
                    return 0
        emit(*twin.finish())
        writer.wait()
    except (DataError, FmuError, ValueError, OSError) as e:
        # What was computed before the bad sample is written, then the run stops.
        if getattr(e, "rows", None) is not None:
            emit(e.rows, getattr(e, "summaries", []))
        writer.wait()
        out.close()
        summ.close()
        print(f"twin.py: {e}", file=sys.stderr)
        return 1
    if a.checkpoint:
        checkpoint()
    out.close()
    summ.close()
    for m in twin.messages:
        print(f"twin.py: {m}", file=sys.stderr)
    print(
        f"{twin.rows_out} samples, {twin.duplicates} duplicate timestamps dropped, {len(twin.gaps)} gap(s); "
        f"wrote {a.out} and {summary}"
    )
    if a.plots:
        from reciprocating_drive.twin_plots import plot_twin

        plot_twin(a.out, summary, a.plots)
        print(f"wrote plots to {a.plots}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
