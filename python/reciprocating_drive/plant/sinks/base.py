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


@dataclass
class _Batch:
    rows: list = field(default_factory=list)  # (first seq, 2-D array) pieces
    summaries: list = field(default_factory=list)  # (index, dict)
    events: list = field(default_factory=list)  # (seq, wall time, Event)


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
    ):
        self.samples = samples
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
            elif keep.any():
                # Decimated or partly held already: the kept rows with their own seq.
                b.rows.append((seq[keep], rows[keep]))
        for i, s in enumerate(summaries):
            if first_rev + i >= self.skip.revolutions:
                b.summaries.append(s)
        for seq, wall, ev in events:
            if seq >= self.skip.events:
                b.events.append((seq, wall, ev))

    def commit(self, state: dict | None, c: Counters, status: str | None = None) -> None:
        """Hands the batch and the checkpoint `state` (None: rows only) to the writer thread, which
        writes them in one transaction (retried, bounded). Raises the writer's failure, if any."""
        self._check()
        self.commits += 1
        c = Counters(c.samples, c.revolutions, c.events, self.commits, c.rev_upto)
        text = None if state is None else json.dumps({**state, "counters": c.__dict__})
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
    ints = ("samples", "revolutions", "events", "commits")
    bad = None
    if not isinstance(c, dict):
        bad = "it has no counters"
    elif set(c) - {*ints, "rev_upto"} or any(type(c.get(k)) is not int or c[k] < 0 for k in ints):
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
