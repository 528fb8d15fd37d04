#!/usr/bin/env python3
"""The drilling-pump digital twin (docs/twin.md): measured crank data in, the FMU's loads out.

    rdrive twin data/twin/pump_encoder.csv --angle-unit counts --counts-per-rev 4096
    producer | rdrive twin - --live ...          # samples on standard input
    rdrive twin growing.csv --follow --live ...   # follow a growing file

The paths above are those of a checkout, or of a folder made by `rdrive examples DIR` (the sample
data, configurations and studies of an installed package).

Writes --out (every sample: time and every FMU output), --summary (one row per completed crank
revolution) and, with --plots DIR, time series, the card and per-revolution trends. With
--checkpoint FILE the FMU's state and the twin's position are saved every --checkpoint-every
samples and at the end; --resume FILE continues a run from its checkpoint.
"""

# Layer: commands (docs/architecture.md); a comment, as --help prints the docstring.

from __future__ import annotations

import argparse
import hashlib
import os
import pathlib
import queue
import signal
import sys
import threading

from .. import artifacts
from ..fmu.batch import format_csv
from ..fmu.instance import FmuError
from ..twin.core import (
    SUMMARY_FIELDS,
    CheckpointError,
    DataError,
    Options,
    Twin,
    load_checkpoint,
    save_checkpoint,
    summary_header,
)
from ..twin.line_input import Idle, InputChanged, chunks_of
from . import prefix


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


class Parser(argparse.ArgumentParser):
    """argparse with its errors on one line (the option, the value and what is allowed)."""

    def error(self, message):
        self.exit(2, f"{prefix('twin.py')}: {message} (see --help)\n")


def number(text: str) -> float:
    """A finite number > 0 (an option's value)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"{text!r}: must be a finite number > 0")
    return v


def non_negative(text: str) -> float:
    """A finite number >= 0 (an option's value)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (v >= 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"{text!r}: must be a finite number >= 0")
    return v


def count(text: str) -> int:
    """A whole number >= 1 (an option's value)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: must be at least 1")
    return v


#: The options a checkpoint fixes: (command-line flag, attribute of args, Options field).
FIXED = (
    ("--angle-unit", "angle_unit", "angle_unit"),
    ("--counts-per-rev", "counts_per_rev", "counts_per_rev"),
    ("--speed-unit", "speed_unit", "speed_unit"),
    ("--duplicates", "duplicates", "duplicates"),
    ("--window", "window", "window"),
    ("--gap-limit", "gap_limit", "gap_limit"),
    ("--max-speed", "max_speed", "max_speed"),
    ("--separator", "separator", "separator"),
    ("--timezone", "timezone", "timezone"),
    ("--speed-check", "speed_check", "speed_check"),
    ("--speed-tolerance", "speed_tolerance", "speed_tolerance"),
    ("--stop-speed", "stop_speed", "stop_speed"),
    ("--stop-duration", "stop_duration", "stop_duration"),
)


def options_of(a) -> tuple[Options, dict]:
    """The Options of the command line (machine-dependent ones left to the machine) and the
    options given explicitly, by flag."""
    given = {flag: getattr(a, attr) for flag, attr, _ in FIXED if getattr(a, attr) is not None}
    if a.continuous is not None:
        given["--continuous"] = True
    if a.ignore_speed is not None:
        given["--ignore-speed"] = True
    kw = {field: getattr(a, attr) for _, attr, field in FIXED if getattr(a, attr) is not None}
    return Options(**kw, wrapped=not a.continuous, use_measured_speed=not a.ignore_speed), given


def check_resume(cp: dict, a, given: dict) -> None:
    """Refuses (ValueError) a resume whose command line differs from the checkpoint's run."""
    o = cp["options"]
    if a.machine is not None and a.machine != cp["machine"]:
        raise ValueError(f"--machine {a.machine!r} differs from the checkpoint's {cp['machine']!r}")
    for flag, _, field in FIXED:
        if flag in given and given[flag] != o.get(field):
            raise ValueError(
                f"{flag} {given[flag]!r} differs from the checkpoint's {o.get(field)!r}"
            )
    if "--continuous" in given and o.get("wrapped", True):
        raise ValueError("--continuous differs from the checkpoint's wrapped angles")
    if "--ignore-speed" in given and o.get("use_measured_speed", True):
        raise ValueError("--ignore-speed differs from the checkpoint's use of crank_speed")


def main(argv=None, prog: str | None = None) -> int:
    ap = Parser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "input",
        help="CSV file, or - for standard input; with --distributed also an SQLite database or "
        "a postgresql://USER@HOST:PORT/DATABASE URI (see --table)",
    )
    ap.add_argument("--fmu", default=str(artifacts.fmu()))
    ap.add_argument(
        "--machine", default=None, help="a preset, 'default' (the default), or an .ssv file"
    )
    ap.add_argument("--angle-unit", choices=("rad", "deg", "counts"), default=None)
    ap.add_argument("--counts-per-rev", type=number, default=None)
    ap.add_argument(
        "--continuous",
        action="store_true",
        default=None,
        help="angles do not wrap (default: wrapped every revolution)",
    )
    ap.add_argument("--speed-unit", choices=("rad/s", "rpm"), default=None)
    ap.add_argument(
        "--ignore-speed",
        action="store_true",
        default=None,
        help="estimate ω from the angle even if crank_speed is given",
    )
    ap.add_argument(
        "--speed-check",
        choices=("refuse", "warn"),
        default=None,
        help="a measured speed that contradicts the angle: stop (default) or warn and ignore it",
    )
    ap.add_argument(
        "--speed-tolerance",
        type=number,
        default=None,
        help="allowed relative difference of crank_speed from the angle's rate (default 0.1)",
    )
    ap.add_argument(
        "--stop-speed",
        type=number,
        default=None,
        help="below this |crank speed| [rpm] the crank is stopped, at minus it reversing "
        "(default 1)",
    )
    ap.add_argument(
        "--stop-duration",
        type=number,
        default=None,
        help="a machine state counts once it has lasted this long [s] (default 0.5)",
    )
    ap.add_argument("--duplicates", choices=("drop", "error"), default=None)
    ap.add_argument(
        "--separator",
        choices=("auto", ",", ";"),
        default=None,
        help="field separator; ';' reads decimal commas (default: auto, from the header)",
    )
    ap.add_argument(
        "--timezone",
        default=None,
        metavar="ZONE",
        help="the zone of ISO 8601 timestamps without a UTC offset, an IANA name such as "
        "Europe/Berlin (timestamps with Z or an offset need none)",
    )
    ap.add_argument(
        "--window",
        type=number,
        default=None,
        help="smoothing window [s] (default: 0.1 s at 65 strokes/min, scaled to the machine)",
    )
    ap.add_argument(
        "--gap-limit",
        type=number,
        default=None,
        help="a longer interval is a gap [s] (default: 0.05 s at 65 strokes/min, scaled)",
    )
    ap.add_argument(
        "--max-speed",
        type=number,
        default=None,
        help="fastest possible crank speed [rad/s] (default: 100 at 65 strokes/min, scaled)",
    )
    ap.add_argument(
        "--out", type=pathlib.Path, default=artifacts.results_dir() / "twin" / "outputs.csv"
    )
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
    ap.add_argument(
        "--idle-limit",
        type=number,
        default=None,
        help="with --follow or standard input: stop after this many seconds without new data",
    )
    ap.add_argument("--checkpoint", type=pathlib.Path, default=None)
    ap.add_argument("--checkpoint-every", type=count, default=10000)
    ap.add_argument(
        "--resume", type=pathlib.Path, default=None, help="continue from this checkpoint"
    )
    ap.add_argument(
        "--stop-after",
        type=count,
        default=None,
        help="stop after this many input lines (and checkpoint)",
    )
    dist = ap.add_argument_group(
        'distributed replay (docs/twin.md "Distributed replay")',
        "--distributed replays a recorded file (CSV, or a table of SQLite or PostgreSQL) in\n"
        "pieces on Dask and writes the same --out and --summary files: byte for byte those of\n"
        "the sequential replay for a rigid rod. For an elastic rod each piece starts\n"
        "ln(1/1e-8)/sigma before its cut, sigma = B_d/(2 J_m) the cage's decay rate from its\n"
        "damping (kvo630: 0.246 s), so rod.angle agrees within 1e-8 rad. Progress (pieces,\n"
        "samples/s) goes to standard error. Each piece is written to --work-dir; after a stop\n"
        "(exit code 128 + signal) the same command resumes from them. Exit codes: 0 done,\n"
        "1 bad data or an FMU error, 2 a bad option, input, scheduler or work folder.",
    )
    dist.add_argument(
        "--distributed", action="store_true", help="replay the file in pieces on Dask"
    )
    dist.add_argument(
        "--workers",
        metavar="K",
        type=count,
        default=None,
        help="worker processes of the local Dask cluster (default: one per core)",
    )
    dist.add_argument(
        "--scheduler",
        metavar="ADDR",
        default=None,
        help="tcp://HOST:PORT of a Dask scheduler (instead)",
    )
    dist.add_argument(
        "--connect-timeout",
        metavar="SECONDS",
        type=number,
        default=10.0,
        help="seconds to wait for the scheduler's answer (default 10)",
    )
    dist.add_argument(
        "--revolutions-per-piece",
        metavar="N",
        type=count,
        default=None,
        help="cut every N crank revolutions too (default: only at the gaps)",
    )
    dist.add_argument(
        "--overlap",
        metavar="SECONDS",
        type=non_negative,
        default=None,
        help="warm-up before each cut [s] (default: 0 for a rigid rod, from the cage's "
        "damping for an elastic one; the smoothing window's half-width is always added)",
    )
    dist.add_argument(
        "--work-dir",
        metavar="DIR",
        type=pathlib.Path,
        default=None,
        help="folder for the pieces and their manifest (default: <out>.parts)",
    )
    dist.add_argument(
        "--table",
        metavar="NAME",
        default=None,
        help="the input is a database (SQLite or PostgreSQL): its table of samples, columns "
        "named as the CSV's (default: samples)",
    )
    dist.add_argument("--quiet", action="store_true", help="no progress on standard error")
    a = ap.parse_args(argv)
    if not a.distributed:
        for flag, v in (
            ("--workers", a.workers),
            ("--scheduler", a.scheduler),
            ("--revolutions-per-piece", a.revolutions_per_piece),
            ("--overlap", a.overlap),
            ("--work-dir", a.work_dir),
            ("--table", a.table),
        ):
            if v is not None:
                ap.error(f"argument {flag}: needs --distributed")
    if a.distributed and a.workers and a.scheduler:
        ap.error("argument --workers: not with --scheduler (the cluster has its workers)")
    if a.follow and a.input == "-":
        ap.error("argument --follow: follows a file, not standard input")

    stopping = []

    def on_signal(signum, frame):
        stopping.append(signum)

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        if a.distributed:
            from . import twin_distributed

            return twin_distributed.run(a, options_of(a)[0], stopping)
        return run(a, stopping)
    except KeyboardInterrupt:
        print(f"{prefix('twin.py')}: stopped", file=sys.stderr)
        return 130
    except Exception:  # noqa: BLE001 - a bug: one line for the user, the details in a file
        import tempfile
        import traceback

        fd, path = tempfile.mkstemp(prefix="twin-internal-error-", suffix=".txt")
        with os.fdopen(fd, "w") as f:
            traceback.print_exc(file=f)
        print(
            f"{prefix('twin.py')}: internal error ({sys.exc_info()[1]!r:.200}); please report it with "
            f"the details written to {path}",
            file=sys.stderr,
        )
        return 70


def run(a, stopping: list) -> int:
    summary = a.summary or a.out.with_name(a.out.stem + "-revolutions.csv")
    opts, given = options_of(a)
    name = "standard input" if a.input == "-" else a.input
    try:
        if a.input != "-" and not os.path.exists(a.input):
            raise ValueError(f"{a.input}: no such file")
        if a.input != "-" and os.path.isdir(a.input):
            raise ValueError(f"{a.input}: a folder, not a CSV file")
        # An output written over the input or the checkpoint would destroy it.
        files = [("--out", a.out), ("--summary", summary), ("--checkpoint", a.checkpoint)]
        files += [("--resume", a.resume), ("input", None if a.input == "-" else a.input)]
        seen = {}
        for flag, path in files:
            if path is None or not os.path.exists(path):
                continue
            key = (os.stat(path).st_dev, os.stat(path).st_ino)
            if key in seen and {flag, seen[key]} != {"--checkpoint", "--resume"}:
                raise ValueError(f"{flag} {path}: the same file as {seen[key]}")
            seen.setdefault(key, flag)
        if len({str(pathlib.Path(p).resolve()) for _, p in files[:3] if p is not None}) < sum(
            p is not None for _, p in files[:3]
        ):
            raise ValueError("--out, --summary and --checkpoint must name different files")
        a.out.parent.mkdir(parents=True, exist_ok=True)
        summary.parent.mkdir(parents=True, exist_ok=True)
        if a.resume:
            cp = load_checkpoint(a.resume)
            for key in ("out_bytes", "summary_bytes", "input_sha256", "input_bytes"):
                if not isinstance(cp.get(key), (int, str)) or isinstance(cp.get(key), bool):
                    raise CheckpointError(f"{a.resume}: not a twin.py checkpoint (no {key})")
            check_resume(cp, a, given)
            twin = Twin.from_checkpoint(a.fmu, cp)
            skip = twin.lines_read
            if a.stop_after is not None and a.stop_after <= skip:
                raise ValueError(
                    f"--stop-after {a.stop_after}: the checkpoint {a.resume} is at line {skip} "
                    "already; give a later line"
                )
            for path, size in ((a.out, cp["out_bytes"]), (summary, cp["summary_bytes"])):
                # The outputs must hold at least what the checkpoint covers: a shorter file was
                # changed since (it is never padded); what follows that size is cut.
                have = path.stat().st_size if path.is_file() else None
                if have is None:
                    raise ValueError(
                        f"{path}: missing; the checkpoint {a.resume} covers {size} bytes of it"
                    )
                if have < size:
                    raise ValueError(
                        f"{path}: {have} bytes, shorter than the {size} the checkpoint "
                        f"{a.resume} covers: it was changed since; start afresh"
                    )
                if have > size:
                    os.truncate(path, size)
            out, summ = open(a.out, "ab"), open(summary, "a")
        else:
            cp = None
            twin = Twin(a.fmu, a.machine or "default", opts)
            skip = 0
            out, summ = open(a.out, "wb"), open(summary, "w")
            out.write((",".join(twin.header_with_units()) + "\n").encode())
            summ.write(",".join(summary_header()) + "\n")
        # Ready: the headers are out before the first sample is read.
        out.flush()
        summ.flush()
        src = sys.stdin.buffer.raw if a.input == "-" else open(a.input, "rb", buffering=0)
    except (FmuError, OSError, ValueError) as e:
        print(f"{prefix('twin.py')}: {error_text(e)}", file=sys.stderr)
        return 2

    # Blocks of at most 64 KiB (about 2000 lines): what a pipe holds, bounded memory in replay,
    # and chunks small enough that writing one overlaps computing the next.
    size = 1 << 16
    twin.defer_summaries = True  # made on the writer's thread
    writer = Writer(twin, out, summ, a.live)
    emit = writer.put
    # The identity of the input read so far: its bytes (lines as read, each ended by a newline)
    # and their SHA-256, saved with every checkpoint and compared on resume (docs/twin.md).
    digest = hashlib.sha256()
    consumed = 0

    def account(lines):
        nonlocal consumed
        text = ("\n".join(lines) + "\n").encode()
        digest.update(text)
        consumed += len(text)

    def checkpoint():
        writer.wait()
        out.flush()
        summ.flush()
        c = twin.checkpoint()
        c["out_bytes"], c["summary_bytes"] = out.tell(), summ.tell()
        c["input_sha256"], c["input_bytes"] = digest.hexdigest(), consumed
        save_checkpoint(a.checkpoint, c)

    def close():
        try:
            writer.wait()
        finally:
            out.close()
            summ.close()

    def resume_hint(lineno):
        if not a.checkpoint:
            return f"stopped after line {lineno}; no checkpoint (--checkpoint FILE makes one)"
        return (
            f"stopped after line {lineno}; resume with: {sys.argv[0]} {' '.join(sys.argv[1:])}"
            f"{'' if a.resume == a.checkpoint else f' --resume {a.checkpoint}'}"
        )

    lineno = 0  # input lines consumed
    n_since = 0  # lines since the last checkpoint
    verified = skip == 0
    try:
        chunks = chunks_of(
            src,
            a.follow,
            size,
            path=a.input,
            idle=a.idle_limit,
            stop=lambda: bool(stopping),
        )
        for lines in chunks:
            if lineno < skip:
                # Lines the checkpoint consumed: they must be the same as then.
                k = min(len(lines), skip - lineno)
                account(lines[:k])
                lines, lineno = lines[k:], lineno + k
                if lineno < skip:
                    continue
            if not verified:
                verify_input(cp, digest, consumed, name, a.resume)
                verified = True
            while lines:
                # Cut the chunk where a checkpoint or --stop-after falls.
                take = len(lines)
                if a.checkpoint:
                    take = min(take, a.checkpoint_every - n_since)
                if a.stop_after:
                    take = min(take, a.stop_after - lineno)
                account(lines[:take])
                emit(*twin.feed(lines[:take], lineno + 1))
                lines, lineno, n_since = lines[take:], lineno + take, n_since + take
                if a.checkpoint and n_since >= a.checkpoint_every:
                    checkpoint()
                    n_since = 0
                if a.stop_after and lineno >= a.stop_after or stopping:
                    break
            if a.stop_after and lineno >= a.stop_after or stopping:
                if a.checkpoint and verified:
                    checkpoint()
                close()
                if stopping:
                    print(f"{prefix('twin.py')}: {resume_hint(lineno)}", file=sys.stderr)
                    return 128 + stopping[0]
                print(
                    f"stopped after line {lineno}"
                    + (f"; checkpoint {a.checkpoint}" if a.checkpoint else "")
                )
                return 0
        if stopping:
            if a.checkpoint and verified:
                checkpoint()
            close()
            print(f"{prefix('twin.py')}: {resume_hint(lineno)}", file=sys.stderr)
            return 128 + stopping[0]
        if not verified:
            if lineno < skip:
                raise DataError(
                    f"has {lineno} lines, fewer than the {skip} the checkpoint {a.resume} "
                    "consumed: it is not the input of that run"
                )
            verify_input(cp, digest, consumed, name, a.resume)
        emit(*twin.finish())
        writer.wait()
    except (DataError, FmuError, ValueError, OSError, InputChanged, Idle) as e:
        # What was computed before the bad sample is written, then the run stops.
        if getattr(e, "rows", None) is not None:
            emit(e.rows, getattr(e, "summaries", []))
        close()
        where = f"{name}: " if isinstance(e, (DataError, FmuError)) else ""
        print(f"{prefix('twin.py')}: {where}{error_text(e)}", file=sys.stderr)
        return 1
    if a.checkpoint:
        checkpoint()
    out.close()
    summ.close()
    for m in twin.messages:
        print(f"{prefix('twin.py')}: {m}", file=sys.stderr)
    # The machine's state changes (docs/twin.md "Machine states"), the last MOTION_KEEP of them.
    if twin.motion_count > len(twin.motion_events):
        print(
            f"{prefix('twin.py')}: {twin.motion_count - len(twin.motion_events)} earlier "
            "machine-state change(s) not listed",
            file=sys.stderr,
        )
    for ev in twin.motion_events:
        print(f"{prefix('twin.py')}: {twin.motion_message(ev)}", file=sys.stderr)
    print(
        f"{twin.rows_out} samples, {twin.duplicates} duplicate timestamps dropped, "
        f"{len(twin.gaps)} gap(s)"
        + (f", {twin.speed_ignored} measured speeds ignored" if twin.speed_ignored else "")
        + f"; wrote {a.out} and {summary}"
    )
    if a.plots:
        from ..twin.plots import plot_twin

        plot_twin(
            a.out,
            summary,
            a.plots,
            machine=twin.machine,
            source=name,
            gap_limit=twin.o.gap_limit,
        )
        print(f"wrote plots to {a.plots}")
    return 0


def verify_input(cp: dict, digest, consumed: int, name: str, resume) -> None:
    """Refuses (ValueError) an input whose first lines are not those the checkpoint consumed."""
    if consumed != cp["input_bytes"] or digest.hexdigest() != cp["input_sha256"]:
        raise ValueError(
            f"{name}: its first {cp['lines_read']} lines ({consumed} bytes) are not those the "
            f"checkpoint {resume} consumed ({cp['input_bytes']} bytes, another SHA-256): "
            "it is not the input of that run"
        )


def error_text(e: BaseException) -> str:
    """One line for the user."""
    if isinstance(e, OSError) and e.filename is not None:
        return f"{e.filename}: {e.strerror or e}"
    return " ".join(str(e).split("\n"))


if __name__ == "__main__":
    sys.exit(main())
