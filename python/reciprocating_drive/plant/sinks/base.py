"""What every database sink does (docs/plant.md, "Exactly once").

The pipeline hands a sink rows, revolution summaries and events as the twin produces them (`add`);
they wait in memory until `commit(state)`, which writes all of them, and the checkpoint `state` if
one is given, in one transaction. A live twin commits rows often (their latency) and checkpoints
less often (a checkpoint holds a revolution of rows, hundreds of kB). When the run is opened
again, the rows after the last checkpoint are deleted in the same transaction that reads it, so
the database holds exactly what that checkpoint covers, and the twin resumes from it and computes
them again: nothing is lost and nothing is stored twice.

A commit that fails because the database is unreachable keeps everything in memory, reconnects and
retries with a bounded back-off (`retry_for` seconds in all, doubling delays up to `retry_max`); a
commit whose outcome is unknown (the connection died during COMMIT) is settled by reading back the
checkpoint's commit number. Only when `retry_for` has passed does the run stop, with one line, and
the database still holds a consistent state to resume from. A database that stops answering (a
call that fails, or one that has not returned for ANSWER_WITHIN s) is a line at once, then one
every `notice_interval` s while it stays so (docs/plant.md "Unresponsive server or database").

The transactions run on a writer thread, in order, while the pipeline computes the next chunk
(the database's own work releases Python's lock, and the machine has a second core). At most
`depth` commits wait for it; then `commit` waits, and the source's queue buffers (a database
that is down slows the twin, it never loses a row).

Layer: workflows, the plant (docs/architecture.md).
"""

from __future__ import annotations

import functools
import json
import queue
import sys
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from ...cli_errors import one_line
from ..samples import Event


class SinkError(RuntimeError):
    """A sink that cannot go on (one-line message naming the sink)."""


@dataclass
class RunInfo:
    name: str
    machine_id: str
    machine: str
    outputs: list[str]
    options: dict
    source: dict  # the source's settings without secrets
    time_origin: float | None = None
    header: list[str] | None = None  # `time` and the outputs as `name [unit]` (the CSV sink's)
    fmu_guid: str | None = None  # the FMU's guid (a recomputation uses the same FMU)


@dataclass
class Counters:
    """How much of the run a checkpoint covers: sample rows (the next sample's seq), revolution
    summaries and events handed out, the number of the last revolution handed out (None: none
    yet), and the number of commits."""

    samples: int = 0
    revolutions: int = 0
    events: int = 0
    commits: int = 0
    rev_upto: int | None = None
    lines: int = 0  # input lines consumed (where the stored input ends)


@dataclass
class _Batch:
    rows: list = field(default_factory=list)  # (first seq, 2-D array) pieces
    summaries: list = field(default_factory=list)  # (index, dict)
    events: list = field(default_factory=list)  # (seq, wall time, Event)
    # The stored input (docs/plant.md "Storage"): (first line, lines, t_first, t_last) and the
    # twin's snapshots (lines, samples, t of the last row, t of the last input, state dict).
    blocks: list = field(default_factory=list)
    snapshots: list = field(default_factory=list)
    origin: float | None = None  # the run's time origin, once known (stored at once)
    first: dict = field(default_factory=dict)  # the first sample seq, revolution, event given
    rewind: dict | None = None  # the state to go back to (several sinks, docs/plant.md)


class Sink:
    """Base of the database sinks. `samples`: "all", "none" or N (every N-th sample by seq)."""

    name = "sink"
    transient: tuple = ()  # exceptions meaning "the database is unreachable now"

    ANSWER_WITHIN = 5.0  # s a database call may take before it counts as not answering

    def __init__(
        self,
        samples="all",
        retry_for: float = 300.0,
        retry_max: float = 5.0,
        depth: int = 2,
        notice_interval: float = 30.0,
        keep_samples: float | None = None,
        keep_input: float | None = None,
    ):
        self.samples = samples
        # Retention (docs/plant.md "Retention"): seconds of the twin's time; None keeps all.
        self.keep_samples, self.keep_input = keep_samples, keep_input
        self.stored_origin = None  # the run's time origin as the database holds it
        self.run_status = "running"
        self.retry_for, self.retry_max = retry_for, retry_max
        self.notice_interval = notice_interval
        self.log = lambda m: print(m, file=sys.stderr, flush=True)  # set by the pipeline
        self._busy_since = None  # monotonic start of the database call under way
        self._down_since = None  # since when the database has not answered
        self._noticed = None  # when the last "not answering" line was printed
        self._watch_lock = threading.Lock()
        self._watchdog = None
        self.batch = _Batch()
        self.done = Counters()  # what the database holds (from its checkpoint)
        self.skip = Counters()  # what it held when the run resumed: not handed to it again
        self.commits = 0
        self.run_key = None
        self.retries = 0  # commits that had to be retried (reported as events by the pipeline)
        self.notes: list[str] = []
        self._q: queue.Queue = queue.Queue(maxsize=depth)
        self._error: BaseException | None = None
        self._worker: threading.Thread | None = None

    # ---- to implement --------------------------------------------------------------------------
    def _connect(self) -> None: ...
    def _open_run(self, run: RunInfo) -> tuple[int, dict | None]: ...
    def _write(self, batch: _Batch, state: str, c: Counters, status: str | None) -> None: ...
    def _committed(self) -> int: ...  # commit number of the run's checkpoint in the database
    def close(self) -> None: ...

    # ---- the protocol --------------------------------------------------------------------------
    def open(self, run: RunInfo) -> dict | None:
        """Connects, creates the schema and the run if new; returns the last committed state
        (with its counters under "counters") or None for a new run."""
        self._retrying(self._connect)
        self.run_key, state = self._retrying(lambda: self._open_run(run))
        if state is not None:
            self.done = Counters(**state["counters"])
            self.skip = Counters(**state["counters"])
            self.commits = self.done.commits
        self._worker = threading.Thread(target=self._work, name=f"sink {self.name}", daemon=True)
        self._worker.start()
        return state

    def add(self, rows: np.ndarray, first_seq: int, summaries: list, first_rev: int, events):
        """Rows (seq first_seq, first_seq + 1, ...), summaries (index first_rev, ...), events
        ((seq, wall time, Event) tuples); what this database already holds is skipped."""
        b = self.batch
        if len(rows) and self.samples != "none":
            seq = np.arange(first_seq, first_seq + len(rows))
            keep = seq >= self.skip.samples
            if self.samples != "all":
                keep &= seq % int(self.samples) == 0
            if keep.all():
                b.rows.append((first_seq, rows))
                b.first.setdefault("samples", first_seq)
            elif keep.any():
                # Decimated or partly held already: the kept rows with their own seq.
                b.rows.append((seq[keep], rows[keep]))
                b.first.setdefault("samples", int(seq[keep][0]))
        for i, s in enumerate(summaries):
            if first_rev + i >= self.skip.revolutions:
                b.summaries.append(s)
                b.first.setdefault("revolutions", first_rev + i)
        for seq, wall, ev in events:
            if seq >= self.skip.events:
                b.events.append((seq, wall, ev))
                b.first.setdefault("events", seq)

    def add_input(self, first_line: int, lines: list, t_first, t_last, snapshots: list) -> None:
        """The input lines first_line, ... consumed since the last checkpoint and the twin's
        snapshots due; what this database holds already is skipped."""
        have = self.skip.lines
        if lines and first_line + len(lines) - 1 > have:
            cut = max(0, have + 1 - first_line)
            self.batch.blocks.append((first_line + cut, lines[cut:], t_first, t_last))
        for snap in snapshots:
            if snap[0] >= have:
                self.batch.snapshots.append(snap)

    def rewind(self, state: dict) -> None:
        """Back to `state`, a checkpoint that covers less than this sink's own: several sinks
        resume from the one that covers least, and every sink drops what lies beyond it and
        stores it again, so all hold the same rows and events, numbered alike."""
        # The input this sink holds already stays (the same lines come again; blocks end at
        # checkpoints, which differ between sinks).
        lines = max(self.done.lines, state["counters"].get("lines", 0))
        self.skip = Counters(**{**state["counters"], "lines": lines})
        self.done = Counters(**self.skip.__dict__)
        self.batch.rewind = {**state, "counters": self.skip.__dict__}
        self.commit({k: v for k, v in state.items() if k not in ("counters", "status")}, self.skip)

    def commit(self, state: dict | None, c: Counters, status: str | None = None) -> None:
        """Hands the batch and the checkpoint `state` (None: rows only) to the writer thread, which
        writes them in one transaction (retried, bounded). Raises the writer's failure, if any."""
        self._check()
        self.commits += 1
        c = Counters(c.samples, c.revolutions, c.events, self.commits, c.rev_upto, c.lines)
        if status is not None:
            self.run_status = status
        # The run's status is in the checkpoint too: runs.status edited by hand is found.
        text = (
            None
            if state is None
            else json.dumps({**state, "counters": c.__dict__, "run_status": self.run_status})
        )
        batch, self.batch = self.batch, _Batch()
        while True:
            try:
                self._q.put((batch, text, c, status), timeout=0.5)
                return
            except queue.Full:
                self._check()

    def flush(self) -> None:
        """Waits until every commit handed over is in the database (or raises its failure)."""
        if self._worker is not None:
            while self._worker.is_alive() and self._q.unfinished_tasks:
                time.sleep(0.005)
        self._check()

    def _check(self) -> None:
        if self._error is not None:
            e, self._error = self._error, None
            self._worker = None
            raise e

    def _settled(self, commits: int) -> bool:
        """After a lost connection: did the COMMIT we were waiting for go through?"""
        return self._committed() >= commits

    def shutdown(self) -> None:
        """Ends the writer thread (after what it holds) and closes the connection."""
        if self._worker is not None and self._worker.is_alive():
            try:
                self._q.put(None, timeout=self.retry_for + 10)
                self._worker.join(timeout=self.retry_for + 10)
            except queue.Full:
                pass
        self.close()

    def _work(self) -> None:
        while True:
            item = self._q.get()
            if item is None:
                self._q.task_done()
                return
            batch, text, c, status = item
            try:
                if self._error is None:
                    self._retrying(
                        functools.partial(self._write, batch, text, c, status),
                        functools.partial(self._settled, c.commits),
                    )
                    self.done = c
            except BaseException as e:  # noqa: BLE001 - raised in the pipeline's thread
                self._error = e
            finally:
                self._q.task_done()
            if self._error is not None:
                return

    def _notice(self, why: str) -> None:
        """The "not answering" line: at once, then every notice_interval s while it lasts."""
        now = time.monotonic()
        with self._watch_lock:
            if self._noticed is not None and now - self._noticed < self.notice_interval:
                return
            first = self._down_since is None
            self._down_since = self._down_since or now
            self._noticed = now
            since = now - self._down_since
        self.log(
            f"{self.name}: "
            + ("not answering" if first else f"still not answering after {since:.0f} s")
            + f" ({why}); retrying for up to retry_for = {self.retry_for:g} s"
        )

    def _answered(self) -> None:
        with self._watch_lock:
            down, self._down_since, self._noticed = self._down_since, None, None
        if down is not None:
            self.log(f"{self.name}: answering again after {time.monotonic() - down:.3g} s")

    def _watch(self) -> None:
        """A call that hangs (a server stopped, a network that drops packets) gives no error
        to retry on: its lines come from here."""
        while True:
            time.sleep(0.25)
            busy = self._busy_since
            if busy is not None and time.monotonic() - busy >= self.ANSWER_WITHIN:
                self._notice(f"a call has not returned for {time.monotonic() - busy:.0f} s")

    def _call(self, fn):
        if self._watchdog is None:
            self._watchdog = threading.Thread(target=self._watch, name="sink watch", daemon=True)
            self._watchdog.start()
        self._busy_since = time.monotonic()
        try:
            out = fn()
        finally:
            self._busy_since = None
        self._answered()
        return out

    def _retrying(self, fn, settled=None):
        start, delay, reconnect = time.monotonic(), 0.05, False
        while True:
            try:
                if reconnect:
                    self._call(self._connect)
                    reconnect = False
                    if settled is not None and settled():
                        return None
                return self._call(fn)
            except self.transient as e:
                first_line = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
                self._notice(first_line)
                if time.monotonic() - start > self.retry_for:
                    raise SinkError(
                        f"{self.name}: unreachable for {self.retry_for:g} s (retry_for), giving up: "
                        f"{first_line}"
                    ) from None
                self.retries += 1
                if len(self.notes) < 1:
                    self.notes.append(f"{self.name}: {first_line}; retried")
                time.sleep(delay)
                delay = min(delay * 2, self.retry_max)
                reconnect = True


def parse_state(text, where: str, run: str) -> dict:
    """A checkpoint row's state, checked before anything is resumed from it: JSON, an object
    with the twin's state and the counters of what it covers (Counters). A row edited or damaged
    by hand is one line naming the database and the run (SinkError), not a parser's message."""
    fix = "restore the database from a copy, or name a new run"
    try:
        state = json.loads(text)
    except (TypeError, ValueError) as e:
        raise SinkError(
            f"{where}: the checkpoint of run {run!r} is not JSON ({one_line(e, 80)}); {fix}"
        ) from None
    c = state.get("counters") if isinstance(state, dict) else None
    ints = ("samples", "revolutions", "events", "commits", "lines")
    bad = None
    if not isinstance(c, dict):
        bad = "it has no counters"
    elif set(c) - {*ints, "rev_upto"} or any(
        type(c.get(k, 0)) is not int or c.get(k, 0) < 0 for k in ints
    ):
        bad = f"its counters {one_line(c, 120)} are not {', '.join(ints)} (integers >= 0)"
    elif c.get("rev_upto") is not None and type(c["rev_upto"]) is not int:
        bad = f"its counter rev_upto = {c['rev_upto']!r} is not an integer"
    elif not isinstance(state.get("twin"), dict):
        bad = "it has no state of the twin"
    if bad:
        raise SinkError(f"{where}: the checkpoint of run {run!r} is damaged: {bad}; {fix}")
    return state


def uncovered(state: dict | None, run: int) -> list:
    """Statements (with ? marks) deleting a run's rows that its checkpoint `state` does not cover
    (all of them without a checkpoint): they were committed after it and are computed again."""
    c = Counters(**state["counters"]) if state else Counters()
    out = [
        ("DELETE FROM samples WHERE run = ? AND seq >= ?", (run, c.samples)),
        ("DELETE FROM events WHERE run = ? AND seq >= ?", (run, c.events)),
    ]
    if c.rev_upto is None:
        out.append(("DELETE FROM revolutions WHERE run = ?", (run,)))
    else:
        out.append(("DELETE FROM revolutions WHERE run = ? AND revolution > ?", (run, c.rev_upto)))
    return out


def new_event(seq: int, ev: Event) -> tuple:
    return (seq, time.time(), ev)


# ---- the stored input and the checks at resume, the same SQL for SQLite and PostgreSQL ----------
# `ex(sql, args)` runs a statement with ? marks in the open transaction and returns its cursor.


def write_storage(ex, sink: Sink, run: int, batch: _Batch, state: str | None, c: Counters) -> None:
    """In the commit's transaction (docs/plant.md "Storage"): the input blocks and snapshots, the
    first rows this database holds, and with a checkpoint the retention's deletions."""
    from ..storage import checksum, encode_lines, encode_state

    for first, lines, t0, t1 in batch.blocks:
        codec, data = encode_lines(lines)
        ex(
            "INSERT INTO input_blocks (run, first_line, last_line, t_first, t_last, codec, "
            "checksum, data) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (run, first, first + len(lines) - 1, t0, t1, codec, checksum(data), data),
        )
    for lines, samples, t, t_in, st in batch.snapshots:
        data = encode_state(st)
        ex(
            "INSERT INTO snapshots (run, lines, samples, t, t_input, checksum, state) "
            "VALUES (?, ?, ?, ?, ?, ?, ?) ON CONFLICT (run, lines) DO NOTHING",
            (run, lines, samples, t, t_in, checksum(data), data),
        )
    for k, v in batch.first.items():
        ex(f"UPDATE checkpoints SET {k}_from = COALESCE({k}_from, ?) WHERE run = ?", (v, run))
    if batch.rows:
        sink.last_row_t = float(batch.rows[-1][1][-1, 0])
    if batch.blocks:
        sink.last_input_t = batch.blocks[-1][3]
    if state is None:
        return
    if sink.keep_samples is not None and getattr(sink, "last_row_t", None) is not None:
        # Rows older than the recent window (docs/plant.md "Retention"); the first one kept is
        # found through the time index, the older ones deleted by the key.
        row = ex(
            "SELECT seq FROM samples WHERE run = ? AND t >= ? ORDER BY t LIMIT 1",
            (run, sink.last_row_t - sink.keep_samples),
        ).fetchone()
        if row is not None:
            ex("DELETE FROM samples WHERE run = ? AND seq < ?", (run, row[0]))
            ex(
                "UPDATE checkpoints SET samples_from = ? WHERE run = ? AND samples_from < ?",
                (row[0], run, row[0]),
            )
    if sink.keep_input is not None and getattr(sink, "last_input_t", None) is not None:
        # Input older than keep_input: from the last snapshot before the age on, what comes
        # before it can no longer be recomputed, and goes.
        row = ex(
            "SELECT lines FROM snapshots WHERE run = ? AND t_input < ? ORDER BY lines DESC LIMIT 1",
            (run, sink.last_input_t - sink.keep_input),
        ).fetchone()
        if row is not None:
            ex("DELETE FROM snapshots WHERE run = ? AND lines < ?", (run, row[0]))
            ex("DELETE FROM input_blocks WHERE run = ? AND last_line <= ?", (run, row[0]))


def _kept(first, end: int, samples) -> int:
    """How many of the seq first..end-1 a sink keeps as rows (`samples`: all, none, every N-th)."""
    if first is None or end <= first or samples == "none":
        return 0
    if samples == "all":
        return end - first
    n = int(samples)
    return (end - 1) // n - (first - 1) // n if first > 0 else (end - 1) // n + 1


def verify(ex, sink: Sink, run: int, name: str, state: dict, status: str) -> None:
    """The database against its checkpoint before the twin resumes (docs/plant.md "Exactly
    once"): the checkpoint's checksum, its counts against its state, the run's status, and the
    rows each table holds. A mismatch (rows deleted or a checkpoint edited by hand) is one line
    naming the table and the counts, never a silent partial result."""
    from ..storage import checksum

    row = ex(
        "SELECT samples, revolutions, events, checksum, samples_from, revolutions_from, "
        "events_from, state FROM checkpoints WHERE run = ?",
        (run,),
    ).fetchone()
    if row is None or row[3] is None:
        return  # a checkpoint of schema version 2 (migrated): nothing to check it against
    samples, revs, evs, cs, s_from, r_from, e_from, text = row
    where, fix = sink.name, "restore the database from a copy, or name a new run"
    if checksum(text.encode()) != cs:
        raise SinkError(
            f"{where}: table checkpoints: the checkpoint of run {name!r} does not match its "
            f"checksum (edited or damaged); {fix}"
        )
    c = state["counters"]
    for col, v in (("samples", samples), ("revolutions", revs), ("events", evs)):
        if c[col] != v:
            raise SinkError(
                f"{where}: table checkpoints: run {name!r} has {col} = {v}, its checkpoint's "
                f"state {c[col]}; {fix}"
            )
    if state.get("run_status", status) != status:
        raise SinkError(
            f"{where}: table runs: run {name!r} has status {status!r}, its checkpoint "
            f"{state['run_status']!r}; {fix}"
        )
    expect = {
        "samples": _kept(s_from, c["samples"], sink.samples),
        "revolutions": 0 if r_from is None else c["revolutions"] - r_from,
        "events": 0 if e_from is None else c["events"] - e_from,
    }
    for table, n_exp in expect.items():
        n = ex(f"SELECT COUNT(*) FROM {table} WHERE run = ?", (run,)).fetchone()[0]
        if n != n_exp:
            raise SinkError(
                f"{where}: table {table}: run {name!r} holds {n} rows, its checkpoint covers "
                f"{n_exp}; {fix}"
            )
