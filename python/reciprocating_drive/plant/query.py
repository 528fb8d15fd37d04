"""Any range of a run's per-sample outputs, recomputed from the stored input (docs/plant.md
"Recomputing a range"): the twin restored from the last snapshot before the range, fed the
stored input blocks from there, gives the rows the live run computed, bit for bit (the core is
deterministic, and the checkpoint-and-resume path is the one every restart of the plant takes).

    from reciprocating_drive.plant.query import recompute
    seq, rows, header = recompute("results/twin/sample-replay.sqlite", "sample-replay", 2.0, 3.0)

`recompute_chunks` yields the rows block by block (an hour at 1 kHz is 3.6 million rows of 26
doubles: written out as they come, never held whole); `rdrive twin-query` writes them as CSV or
Parquet.
"""

from __future__ import annotations

import json
import sqlite3

import numpy as np

from .. import artifacts
from ..fmu.instance import FmuError
from ..twin.core import CheckpointError, DataError, Twin
from .storage import BlockError, checksum, decode_lines, decode_state


class QueryError(RuntimeError):
    """A range that cannot be recomputed (one line: the run, the range, why)."""


class Database:
    """A plant database to read: an SQLite file (read-only) or a PostgreSQL connection string."""

    def __init__(self, target, password: str | None = None):
        if isinstance(target, Database):
            self.conn, self.name, self.pg = target.conn, target.name, target.pg
            self.target, self.password = target.target, target.password
            return
        target = str(target)
        self.target, self.password = target, password
        self.pg = "=" in target or target.startswith(("postgres://", "postgresql://"))
        if self.pg:
            import psycopg

            from .config import mask_dsn

            self.name = f"postgres {mask_dsn(target)}"
            kw = {"password": password} if password is not None else {}
            try:
                self.conn = psycopg.connect(target, autocommit=True, **kw)
            except psycopg.Error as e:
                raise QueryError(f"{self.name}: {str(e).strip().splitlines()[-1]}") from None
        else:
            import pathlib

            self.name = f"sqlite {target}"
            if not pathlib.Path(target).is_file():
                raise QueryError(f"{self.name}: no such database file")
            self.conn = sqlite3.connect(f"file:{target}?mode=ro", uri=True)

    def ex(self, sql: str, args=()):
        if self.pg:
            return self.conn.execute(sql.replace("?", "%s"), args)
        return self.conn.execute(sql, args)


def _feed(twin: Twin, lines: list[str], first_lineno: int) -> tuple[np.ndarray, bool]:
    """The one place the recomputation drives the core (its narrowest entry point: the input
    lines, as the live run fed them). Returns the rows and whether the input stopped the run
    (the live run stopped there too, after committing these rows)."""
    try:
        rows, _ = twin.feed(lines, first_lineno)
        return rows, False
    except (DataError, FmuError) as e:
        rows = getattr(e, "rows", None)
        return (rows if rows is not None else twin._empty()), True


def run_info(db: Database, run: str) -> dict:
    row = db.ex(
        "SELECT run, outputs, fmu_guid, status, time_origin FROM runs WHERE name = ?", (run,)
    ).fetchone()
    if row is None:
        names = [r[0] for r in db.ex("SELECT name FROM runs ORDER BY run")]
        raise QueryError(
            f"{db.name}: no run {run!r} (runs: {', '.join(names[:10]) or 'none'}"
            f"{', ...' if len(names) > 10 else ''})"
        )
    key, outputs, guid, status, origin = row
    return {
        "key": key,
        "outputs": json.loads(outputs),
        "fmu_guid": guid,
        "status": status,
        "time_origin": origin,
    }


def _snapshot(db: Database, info: dict, run: str, t_from: float) -> tuple:
    key = info["key"]
    row = db.ex(
        "SELECT lines, samples, t, checksum, state FROM snapshots WHERE run = ? "
        "AND (t IS NULL OR t < ?) ORDER BY lines DESC LIMIT 1",
        (key, t_from),
    ).fetchone()
    if row is None:
        first = db.ex(
            "SELECT lines, t FROM snapshots WHERE run = ? ORDER BY lines LIMIT 1", (key,)
        ).fetchone()
        if first is None:
            raise QueryError(
                f"{db.name}: run {run!r} has no stored input (a run written before schema "
                "version 3): its ranges cannot be recomputed"
            )
        raise QueryError(
            f"{db.name}: run {run!r}: the input before t = {first[1]!r} s was removed "
            "(sink.keep_input); a range from there on can be recomputed"
        )
    lines, samples, t, cs, data = row
    data = bytes(data)
    if checksum(data) != cs:
        raise QueryError(
            f"{db.name}: run {run!r}: the snapshot at input line {lines} (after t = {t!r} s) is "
            "damaged (its checksum does not match)"
        )
    return lines, samples, decode_state(data)


def check_blocks(db: Database, run: str) -> list[str]:
    """Every input block of a run whose checksum does not match, as a line naming its lines and
    times (the resume reports them: nothing else is affected)."""
    key = run_info(db, run)["key"]
    out = []
    for first, last, t0, t1, cs, data in db.ex(
        "SELECT first_line, last_line, t_first, t_last, checksum, data FROM input_blocks "
        "WHERE run = ? ORDER BY first_line",
        (key,),
    ):
        if checksum(bytes(data)) != cs:
            out.append(_damaged(db, run, first, last, t0, t1))
    return out


def _damaged(db, run, first, last, t0, t1) -> str:
    return (
        f"{db.name}: run {run!r}: the input block of lines {first}-{last} (t = {t0!r} s to "
        f"{t1!r} s) is damaged (its checksum does not match): outputs after t = {t0!r} s up to "
        "the next snapshot after it cannot be recomputed"
    )


def recompute_chunks(
    target,
    run: str,
    t_from: float,
    t_to: float,
    fmu: str | None = None,
    other_fmu: bool = False,
    password: str | None = None,
    workers: int = 1,
    open_end: bool = False,
):
    """Yields (seq, rows) pieces of the run's per-sample outputs with t_from <= t <= t_to (rows:
    time then the outputs, as the samples table holds them; t < t_to with `open_end`). The FMU is
    the run's (by GUID): another is refused unless `other_fmu`, and then its results are its own.
    `workers` > 1 recomputes the stretches between the snapshots inside the range in that many
    processes at once, and yields them in order."""
    if workers > 1:
        yield from _parallel(target, run, t_from, t_to, workers, fmu, other_fmu, password)
        return
    if not t_from <= t_to:
        raise QueryError(f"the range {t_from!r} s to {t_to!r} s is empty (from > to)")
    db = Database(target, password)
    info = run_info(db, run)
    lines_at, samples_at, state = _snapshot(db, info, run, t_from)
    fmu = str(fmu or artifacts.fmu())
    try:
        from ..fmu.instance import Fmu

        guid = Fmu(fmu).model_description.guid
    except Exception as e:  # noqa: BLE001 - not a zip, not an FMU: one line
        raise QueryError(f"--fmu {fmu!r}: not a usable FMU ({e})") from None
    used = info["fmu_guid"] or state.get("fmu_guid")
    if used != guid:
        if not other_fmu:
            raise QueryError(
                f"run {run!r} was computed with the FMU {used!r}; {fmu!r} is {guid!r}: name "
                "that FMU with --fmu, or give --other-fmu to recompute with this one"
            )
        state = {**state, "fmu_guid": guid}
    try:
        twin = Twin.from_checkpoint(fmu, state)
    except (CheckpointError, ValueError, FmuError) as e:
        raise QueryError(f"run {run!r}: the snapshot at input line {lines_at}: {e}") from None
    key = info["key"]
    nxt = lines_at + 1
    cur = db.ex(
        "SELECT first_line, last_line, t_first, t_last, codec, checksum, data FROM input_blocks "
        "WHERE run = ? AND last_line >= ? ORDER BY first_line",
        (key, nxt),
    )
    stopped = False
    while not stopped:
        got = cur.fetchmany(8)
        if not got:
            break
        for first, last, t0, t1, codec, cs, data in got:
            data = bytes(data)
            if checksum(data) != cs:
                raise QueryError(_damaged(db, run, first, last, t0, t1))
            if first > nxt:
                raise QueryError(
                    f"{db.name}: run {run!r}: the input lines {nxt}-{first - 1} are missing"
                )
            try:
                lines = decode_lines(codec, data)
            except (BlockError, ValueError) as e:
                raise QueryError(_damaged(db, run, first, last, t0, t1) + f" ({e})") from None
            lines = lines[nxt - first :]
            rows, stopped = _feed(twin, lines, nxt)
            nxt = last + 1
            piece = _within(rows, twin.rows_out - len(rows), t_from, t_to, open_end)
            if piece is not None:
                yield piece
            if len(rows) and rows[-1, 0] > t_to:
                return
            if stopped:
                break
    if not stopped and info["status"] == "finished":
        # The live run's end: the rows the core held for its smoothing window.
        try:
            rows, _ = twin.finish()
        except DataError as e:
            rows = e.rows if e.rows is not None else twin._empty()
        piece = _within(rows, twin.rows_out - len(rows), t_from, t_to, open_end)
        if piece is not None:
            yield piece


def _parallel(target, run, t_from, t_to, workers, fmu, other_fmu, password):
    """The range cut just after snapshots inside it (a snapshot at t follows the row at t, so a
    stretch from the next double after t starts from it with no lead-in), each stretch in
    a process of its own, yielded in order (each written to a temporary file as it is computed:
    half an hour at 1 kHz is about 400 MB)."""
    import concurrent.futures
    import multiprocessing
    import os

    db = Database(target, password)
    target, password = db.target, db.password  # to open in the workers
    info = run_info(db, run)
    cuts = [
        float(np.nextafter(t, np.inf))
        for (t,) in db.ex(
            "SELECT t FROM snapshots WHERE run = ? AND t > ? AND t < ? ORDER BY lines",
            (info["key"], t_from, t_to),
        )
    ]
    kw = {"fmu": fmu, "other_fmu": other_fmu, "password": password}
    # One stretch per worker: the snapshots nearest to equal parts (each stretch loads the FMU
    # and hands its rows over through a file, so fewer is cheaper).
    even = [t_from + k * (t_to - t_from) / workers for k in range(1, workers)]
    cuts = sorted({min(cuts, key=lambda c, e=e: abs(c - e)) for e in even}) if cuts else []
    if not cuts:
        yield from recompute_chunks(db, run, t_from, t_to, **kw)
        return
    bounds = [t_from, *cuts, t_to]
    jobs = [
        (target, run, bounds[i], bounds[i + 1], i < len(bounds) - 2, kw)
        for i in range(len(bounds) - 1)
    ]
    # spawn: a fresh process per worker (the FMU's library is loaded there, never forked).
    ctx = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(workers, mp_context=ctx) as ex:
        futures = [ex.submit(_stretch, *job) for job in jobs]
        try:
            for f in futures:
                path = f.result()
                try:
                    with open(path, "rb") as fh:
                        end = os.fstat(fh.fileno()).st_size
                        while fh.tell() < end:
                            seq = np.load(fh)
                            yield seq, np.load(fh)
                finally:
                    os.unlink(path)
        finally:
            for f in futures:
                f.cancel()
            for f in futures:  # the files of stretches done but not read
                if f.done() and not f.cancelled() and f.exception() is None:
                    if os.path.exists(f.result()):
                        os.unlink(f.result())


def _stretch(target, run, a, b, open_end, kw) -> str:
    """One stretch of `_parallel`, in its worker process: the file its rows are in."""
    import os
    import tempfile

    fd, path = tempfile.mkstemp(prefix="twin-query-", suffix=".npy")
    # The rows as they come, array after array (bounded memory; the parent reads them in turn).
    with os.fdopen(fd, "wb") as f:
        for s, r in recompute_chunks(target, run, a, b, open_end=open_end, **kw):
            np.save(f, s)
            np.save(f, r)
    return path


def _within(rows: np.ndarray, first_seq: int, t_from: float, t_to: float, open_end=False):
    if not len(rows):
        return None
    t = rows[:, 0]
    keep = (t >= t_from) & ((t < t_to) if open_end else (t <= t_to))
    if not keep.any():
        return None
    seq = np.arange(first_seq, first_seq + len(rows))
    return seq[keep], rows[keep]


def recompute(target, run: str, t_from: float, t_to: float, **kw):
    """(seq, rows, header) of the range, in memory (for a few minutes at 1 kHz; larger ranges
    through `recompute_chunks` or `rdrive twin-query`)."""
    db = Database(target, kw.pop("password", None))
    info = run_info(db, run)
    seqs, parts = [np.empty(0, dtype=np.int64)], [np.empty((0, 1 + len(info["outputs"])))]
    for s, r in recompute_chunks(db, run, t_from, t_to, **kw):
        seqs.append(s)
        parts.append(r)
    return np.concatenate(seqs), np.concatenate(parts), ["time", *info["outputs"]]


def write_range(target, run: str, t_from: float, t_to: float, out: str, **kw) -> int:
    """The range into a CSV file (as `rdrive twin` writes its rows: `time [s]` and `name [unit]`
    columns, numbers as repr) or a Parquet file (`seq`, `t` and the samples table's columns,
    float64), written as it is recomputed; `out` "-" is CSV on standard output. Returns the
    number of samples."""
    import pathlib
    import sys

    from ..fmu.batch import format_csv
    from ..fmu.instance import Fmu
    from ..twin.core import with_unit
    from .schema import column

    db = Database(target, kw.pop("password", None))
    info = run_info(db, run)
    outputs = info["outputs"]
    n = 0
    import itertools

    chunks = recompute_chunks(db, run, t_from, t_to, **kw)
    # The run, the range and the FMU are checked before a file is made.
    head = next(chunks, None)
    chunks = itertools.chain([head] if head is not None else [], chunks)
    if out != "-":
        try:  # its folder is made as an output folder is (results/twin/ of a fresh clone)
            pathlib.Path(out).parent.mkdir(parents=True, exist_ok=True)
            pathlib.Path(out).touch()
        except OSError as e:
            raise QueryError(f"--out {out!r}: {e.strerror or e}") from None
    if out.endswith(".parquet"):
        import pyarrow as pa
        import pyarrow.parquet as pq

        schema = pa.schema(
            [("seq", pa.int64()), ("t", pa.float64())]
            + [(column(o), pa.float64()) for o in outputs]
        )
        with pq.ParquetWriter(out, schema) as w:
            for seq, rows in chunks:
                cols = [pa.array(seq, pa.int64())]
                cols += [pa.array(rows[:, j]) for j in range(rows.shape[1])]
                w.write_table(pa.Table.from_arrays(cols, schema=schema))
                n += len(seq)
            if n == 0:
                w.write_table(schema.empty_table())
        return n
    variables = Fmu(kw.get("fmu") or str(artifacts.fmu())).variables  # loaded above already
    header = ["time [s]"] + [with_unit(o, variables[o].unit or "-") for o in outputs]
    f = sys.stdout.buffer if out == "-" else open(pathlib.Path(out), "wb")
    try:
        f.write((",".join(header) + "\n").encode())
        buf = bytearray()
        for seq, rows in chunks:
            f.write(format_csv(rows, buf))
            n += len(seq)
    finally:
        if out != "-":
            f.close()
        else:
            f.flush()
    return n


def status(target, password: str | None = None) -> list[str]:
    """The database's size and growth (docs/plant.md "Retention"): its bytes, the samples its
    runs cover and the bytes per sample, the input rate of the latest blocks, and the days until
    its disk is full at that rate (SQLite; a PostgreSQL server's disk is not seen from here)."""
    import pathlib
    import shutil

    db = Database(target, password)
    if db.pg:
        size = db.ex("SELECT pg_database_size(current_database())").fetchone()[0]
        free = None
    else:
        p = pathlib.Path(str(target))
        # The file and its write-ahead log (the -shm index is a reader's scratch).
        size = sum(q.stat().st_size for q in (p, p.with_name(p.name + "-wal")) if q.is_file())
        free = shutil.disk_usage(p.parent).free
    runs, samples = db.ex("SELECT COUNT(*), COALESCE(SUM(samples), 0) FROM checkpoints").fetchone()
    held = db.ex("SELECT COUNT(*) FROM samples").fetchone()[0]
    per = size / samples if samples else float("nan")
    out = [
        f"{db.name}: {size / 1e6:.1f} MB, {samples} samples in {runs} run(s), "
        f"{per:.1f} bytes a sample all inclusive ({held} per-sample rows held)"
    ]
    # The rate of the latest input: the last blocks' lines over their time.
    rows = db.ex(
        "SELECT first_line, last_line, t_first, t_last FROM input_blocks "
        "WHERE t_first IS NOT NULL ORDER BY run DESC, first_line DESC LIMIT 200"
    ).fetchall()
    span = sum(r[3] - r[2] for r in rows)
    if rows and span > 0 and samples:
        rate = sum(r[1] - r[0] + 1 for r in rows) / span
        # Per sample beyond the rows of the recent window, which stay as many as it holds.
        grow = max(size - _rows_bytes(db, held), 0) / samples
        day = grow * rate * 86400
        text = f"input {rate:.0f} samples/s: {day / 1e9:.2f} GB a day ({grow:.1f} bytes a sample)"
        if free is not None:
            text += f"; {free / 1e9:.1f} GB free: full in {free / day:.0f} days at this rate"
        else:
            text += "; the server's free disk is not known from here"
        out.append(text)
    db.conn.close()
    return out


def _rows_bytes(db: Database, held: int) -> float:
    """What the per-sample rows held take, estimated from the table's own size (SQLite: the
    pages of the table and its index when the dbstat table exists; else 8 bytes a column)."""
    if db.pg:
        got = db.ex("SELECT pg_total_relation_size('samples')").fetchone()
        return float(got[0] or 0)
    try:
        got = db.ex(
            "SELECT SUM(pgsize) FROM dbstat WHERE name IN ('samples', 'samples_time')"
        ).fetchone()
        return float(got[0] or 0)
    except sqlite3.Error:
        cols = len(db.ex("PRAGMA table_info(samples)").fetchall())
        return held * 8.0 * cols


def page_recompute(database: str, run: str):
    """The page's `recompute` (page/server.py, its range form) for run `run` of the SQLite file
    `database`: the page lies below the plant and knows nothing of the stored input."""
    from ..page.server import RangeUnavailable

    def recompute(t0: float, t1: float, path: str) -> None:
        try:
            write_range(database, run, t0, t1, path)
        except QueryError as e:
            raise RangeUnavailable(str(e)) from None

    return recompute
