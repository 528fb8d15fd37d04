"""What every database sink does (docs/plant.md, "Exactly once").

The pipeline hands a sink rows, revolution summaries and events as the twin produces them (`add`);
they wait in memory until `commit(state)`, which writes all of them AND the checkpoint `state` in
one transaction. After a crash the database holds exactly what the last committed checkpoint
covers, and the twin resumes from that checkpoint: nothing is lost and nothing is stored twice.

A commit that fails because the database is unreachable keeps everything in memory, reconnects and
retries with a bounded back-off (`retry_for` seconds in all, doubling delays up to `retry_max`); a
commit whose outcome is unknown (the connection died during COMMIT) is settled by reading back the
checkpoint's commit number. Only when `retry_for` has passed does the run stop, with one line, and
the database still holds a consistent state to resume from.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field

import numpy as np

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


@dataclass
class Counters:
    """How much of the run a checkpoint covers: sample rows (the next sample's seq), revolution
    summaries and events handed out, and the number of commits."""

    samples: int = 0
    revolutions: int = 0
    events: int = 0
    commits: int = 0


@dataclass
class _Batch:
    rows: list = field(default_factory=list)  # (first seq, 2-D array) pieces
    summaries: list = field(default_factory=list)  # (index, dict)
    events: list = field(default_factory=list)  # (seq, wall time, Event)


class Sink:
    """Base of the database sinks. `samples`: "all", "none" or N (every N-th sample by seq)."""

    name = "sink"
    transient: tuple = ()  # exceptions meaning "the database is unreachable now"

    def __init__(self, samples="all", retry_for: float = 300.0, retry_max: float = 5.0):
        self.samples = samples
        self.retry_for, self.retry_max = retry_for, retry_max
        self.batch = _Batch()
        self.done = Counters()  # what the database holds (from its checkpoint)
        self.run_key = None
        self.retries = 0  # commits that had to be retried (reported as events by the pipeline)
        self.notes: list[str] = []

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
        return state

    def add(self, rows: np.ndarray, first_seq: int, summaries: list, first_rev: int, events):
        """Rows (seq first_seq, first_seq + 1, ...), summaries (index first_rev, ...), events
        ((seq, wall time, Event) tuples); what this database already holds is skipped."""
        b = self.batch
        if len(rows) and self.samples != "none":
            seq = np.arange(first_seq, first_seq + len(rows))
            keep = seq >= self.done.samples
            if self.samples != "all":
                keep &= seq % int(self.samples) == 0
            if keep.all():
                b.rows.append((first_seq, rows))
            elif keep.any():
                # Decimated or partly held already: the kept rows with their own seq.
                b.rows.append((seq[keep], rows[keep]))
        for i, s in enumerate(summaries):
            if first_rev + i >= self.done.revolutions:
                b.summaries.append(s)
        for seq, wall, ev in events:
            if seq >= self.done.events:
                b.events.append((seq, wall, ev))

    def commit(self, state: dict, c: Counters, status: str | None = None) -> None:
        """Writes the batch and the checkpoint `state` in one transaction (retried, bounded)."""
        c = Counters(c.samples, c.revolutions, c.events, self.done.commits + 1)
        text = json.dumps({**state, "counters": c.__dict__})
        batch = self.batch

        def once():
            self._write(batch, text, c, status)

        def settled() -> bool:
            # After a lost connection: did the COMMIT we were waiting for go through?
            return self._committed() >= c.commits

        self._retrying(once, settled)
        self.batch = _Batch()
        self.done = Counters(
            max(c.samples, self.done.samples),
            max(c.revolutions, self.done.revolutions),
            max(c.events, self.done.events),
            c.commits,
        )

    def _retrying(self, fn, settled=None):
        start, delay, reconnect = time.monotonic(), 0.05, False
        while True:
            try:
                if reconnect:
                    self._connect()
                    reconnect = False
                    if settled is not None and settled():
                        return None
                return fn()
            except self.transient as e:
                first_line = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
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


def new_event(seq: int, ev: Event) -> tuple:
    return (seq, time.time(), ev)
