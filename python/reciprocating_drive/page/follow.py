"""The page beside a running twin (docs/page.md, "Beside a twin"): follows the database another
process writes (the plant sinks' SQLite schema, version 2) and feeds a `PageServer` with what is
new: revolution summaries, data-health events and, when the twin stores per-sample rows, the card.

    python -m reciprocating_drive.page --database twin.sqlite --limits examples/twin/limits.toml

Read-only (the database is opened with mode=ro). A revolution appears once the twin has committed
it: the page is as fresh as the twin's commit interval, plus the poll interval.

Layer: workflows, the page (docs/architecture.md).
"""

from __future__ import annotations

import sqlite3
import time

import numpy as np

from ..twin.core import SUMMARY_FIELDS
from .history import HistoryError


def elastic_of(machine: str) -> bool | None:
    """Whether the run's machine (a preset name or an .ssv file, the runs table's `machine`) has
    an elastic rod (rod.kind != 0); its preset leaving rod.kind out means the FMU's own start
    value, read from the model description. None when it cannot be told (the page then shows
    what an elastic rod has too)."""
    from ..presets import preset_values
    from ..sweeps.study import MODEL_DESCRIPTION

    try:
        kind = preset_values(machine).get("rod.kind")
        if kind is None:
            from fmpy import read_model_description

            md = read_model_description(str(MODEL_DESCRIPTION))
            kind = next(v.start for v in md.modelVariables if v.name == "rod.kind")
        return int(float(kind)) != 0
    except Exception:  # noqa: BLE001 - an unknown machine or no model description: not known
        return None


def pump_of(machine: str) -> bool | None:
    """Whether the run's machine is a pump (mission.is_pump of its preset); None when it cannot
    be told (the page then leaves the pump's values out)."""
    from ..mission import is_pump
    from ..presets import preset_values

    try:
        return is_pump(preset_values(machine))
    except Exception:  # noqa: BLE001 - an unknown machine: not known
        return None


#: The samples-table columns of the card (the plant schema's column names of the FMU outputs).
CARD_COLUMNS = ("crank_model_angle", "suspension_position", "rod_force")


class Follower:
    def __init__(self, path: str, page, run: str | None = None, warmup: float = 0.0):
        """`warmup`: seconds of the run's history (twin time) fed before following, so that the
        trend alarms have their windows (the largest recent + reference window of the limits)."""
        self.path, self.page, self.run_name, self.warmup = str(path), page, run, warmup
        try:
            self.db = sqlite3.connect(f"file:{self.path}?mode=ro", uri=True, timeout=5.0)
            self.db.execute("SELECT 1 FROM runs LIMIT 1").fetchall()
        except sqlite3.Error as e:
            raise HistoryError(f"{self.path}: not a twin database ({e})") from None
        self.run = None
        self.next_rev = None
        self.next_event = 0
        self.next_seq = None
        self.cards = False
        self.origin = None
        self.status = None
        self.elastic = None
        self.pump = None

    def _find_run(self) -> bool:
        q = self.db.execute
        if self.run_name is None:
            row = q("SELECT run, name, time_origin FROM runs ORDER BY run DESC LIMIT 1").fetchone()
        else:
            row = q(
                "SELECT run, name, time_origin FROM runs WHERE name = ?", (self.run_name,)
            ).fetchone()
        if row is None:
            return False
        self.run, self.run_name, self.origin = row
        try:
            (machine,) = q("SELECT machine FROM runs WHERE run = ?", (self.run,)).fetchone()
            self.elastic = elastic_of(machine)
            self.pump = pump_of(machine)
        except sqlite3.Error:  # a database of an older schema without the column
            self.elastic = self.pump = None
        cols = {r[1] for r in q("PRAGMA table_info(samples)")}
        self.cards = all(c in cols for c in CARD_COLUMNS)
        self.page.open(
            ["crank.model_angle", "suspension.position", "rod.force"],
            self.origin,
            self.elastic,
            self.pump,
        )
        last = q("SELECT MAX(start_time) FROM revolutions WHERE run = ?", (self.run,)).fetchone()[0]
        if last is None:
            self.next_rev, self.next_seq = 0, 0
        else:
            # Start with the warm-up window (at least the last revolution) and, for the card, the
            # samples of the last few revolutions.
            self.next_rev = q(
                "SELECT COALESCE(MIN(revolution), 0) FROM revolutions WHERE run = ? AND "
                "start_time >= ?",
                (self.run, last - self.warmup),
            ).fetchone()[0]
            self.next_seq = 0
            if self.cards:
                starts = q(
                    "SELECT start_time FROM revolutions WHERE run = ? ORDER BY revolution DESC "
                    "LIMIT 6",
                    (self.run,),
                ).fetchall()
                (seq,) = q(
                    "SELECT MIN(seq) FROM samples WHERE run = ? AND t >= ?",
                    (self.run, starts[-1][0]),
                ).fetchone()
                self.next_seq = seq or 0
        return True

    def poll(self) -> int:
        """Feeds what was committed since the last poll; returns the number of revolutions."""
        if self.run is None and not self._find_run():
            return 0
        q = self.db.execute
        if self.origin is None:
            (origin,) = q("SELECT time_origin FROM runs WHERE run = ?", (self.run,)).fetchone()
            if origin is not None:
                self.origin = origin
                self.page.open(
                    ["crank.model_angle", "suspension.position", "rod.force"],
                    origin,
                    self.elastic,
                    self.pump,
                )
        rows = None
        if self.cards:
            got = q(
                f"SELECT seq, t, {', '.join(CARD_COLUMNS)} FROM samples WHERE run = ? AND seq >= ? "
                "ORDER BY seq LIMIT 200000",
                (self.run, self.next_seq),
            ).fetchall()
            if got:
                rows = np.array([g[1:] for g in got], dtype=float)
                self.next_seq = got[-1][0] + 1
        names = ", ".join(SUMMARY_FIELDS)
        revs = q(
            f"SELECT {names} FROM revolutions WHERE run = ? AND revolution >= ? ORDER BY revolution",
            (self.run, self.next_rev),
        ).fetchall()
        sums = [dict(zip(SUMMARY_FIELDS, r)) for r in revs]
        if sums:
            self.next_rev = sums[-1]["revolution"] + 1
        evs = q(
            "SELECT seq, t, wall_time, kind, count, message FROM events WHERE run = ? AND seq >= ? "
            "ORDER BY seq",
            (self.run, self.next_event),
        ).fetchall()
        events = [_Event(kind, msg, t, count) for _s, t, _w, kind, count, msg in evs]
        if evs:
            self.next_event = evs[-1][0] + 1
        if rows is not None or sums or events:
            self.page.add(rows, 0, sums, 0, events)
        (status,) = q("SELECT status FROM runs WHERE run = ?", (self.run,)).fetchone()
        if status != self.status:
            self.status = status
            self.page.health(run_status=status)
        return len(sums)

    def run_forever(self, interval: float, stop, log=None) -> None:
        """Polls until `stop` is set. A database busy or briefly unreadable (the twin migrating
        it, a lock beyond the timeout) is reported once and tried again at the next poll."""
        failing = False
        while not stop.is_set():
            t0 = time.monotonic()
            try:
                self.poll()
                failing = False
            except sqlite3.OperationalError as e:
                if not failing and log is not None:
                    log(f"page: {self.path}: {e}; trying again every {interval:g} s")
                failing = True
            stop.wait(max(0.0, interval - (time.monotonic() - t0)))

    def close(self) -> None:
        self.db.close()


class _Event:
    """A data-health event as the page takes it (the plant sinks' Event fields)."""

    def __init__(self, kind, message, t, count):
        self.kind, self.message, self.t, self.count = kind, message, t, count
