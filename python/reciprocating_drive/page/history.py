"""The page's reader of the twin's database (docs/page.md, "Trends"): per-revolution values of a
run over a time window, from the `revolutions` table of the plant sinks' schema (version 2), opened
read-only.

A long window (days at 25 revolutions a second are millions of rows) is cut into at most
`MAX_POINTS` buckets by SQL itself: the peak values (torque, rod force, fluctuation, ϑ amplitude,
stress) keep each bucket's largest, so a short excursion stays visible; strokes per minute and
friction work keep each bucket's mean.

Layer: workflows, the page (docs/architecture.md).
"""

from __future__ import annotations

import sqlite3

MAX_POINTS = 2000

#: The page's trend values as SQL over a revolutions row, and how a bucket combines them.
TREND_SQL = {
    "strokes_per_minute": ("mean_speed * 60.0 / (2.0 * 3.141592653589793)", "AVG"),
    "speed_fluctuation": ("speed_fluctuation", "MAX"),
    "crank_torque_peak": ("MAX(ABS(crank_torque_max), ABS(crank_torque_min))", "MAX"),
    "rod_force_largest": ("MAX(ABS(rod_force_max), ABS(rod_force_min))", "MAX"),
    "friction_work": ("friction_work", "AVG"),
    "rod_angle_amplitude": ("rod_angle_amplitude", "MAX"),
    "stress_max": ("stress_max", "MAX"),
    "flow_mean": ("flow_mean", "AVG"),
    "flow_pulsation": ("flow_pulsation", "MAX"),
    "hydraulic_power_mean": ("hydraulic_power_mean", "AVG"),
    "mechanical_power_mean": ("mechanical_power_mean", "AVG"),
}


class HistoryError(RuntimeError):
    """The database cannot be read as the twin's (one line naming the file)."""


class History:
    """Read-only access to one run of a twin database (SQLite). `run` is the run's name (the
    twin configuration's run.id); None takes the most recent run. One instance per thread."""

    def __init__(self, path: str, run: str | None = None):
        self.path = str(path)
        try:
            # mode=ro: the page never writes, and cannot create an empty file by mistake.
            self.db = sqlite3.connect(f"file:{self.path}?mode=ro", uri=True, timeout=5.0)
        except sqlite3.Error as e:
            raise HistoryError(
                f"{self.path}: cannot open the twin database read-only: {e}"
            ) from None
        self.run_name = run
        self._run_key = None
        self.time_origin = None

    def run_key(self):
        if self._run_key is None:
            try:
                if self.run_name is None:
                    row = self.db.execute(
                        "SELECT run, name, time_origin FROM runs ORDER BY run DESC LIMIT 1"
                    ).fetchone()
                else:
                    row = self.db.execute(
                        "SELECT run, name, time_origin FROM runs WHERE name = ?", (self.run_name,)
                    ).fetchone()
            except sqlite3.Error as e:
                raise HistoryError(f"{self.path}: not a twin database ({e})") from None
            if row is None:
                return None
            self._run_key, self.run_name, self.time_origin = row
        return self._run_key

    def trend(self, window: float) -> dict:
        """{"t": [...], value: [...]} of the revolutions whose start lies in the last `window`
        seconds of the run (twin time), oldest first; `t` is the revolution's start_time."""
        key = self.run_key()
        empty = {"t": [], **{k: [] for k in TREND_SQL}}
        if key is None:
            return empty
        q = self.db.execute
        last, n = q(
            "SELECT MAX(start_time), COUNT(*) FROM revolutions WHERE run = ?", (key,)
        ).fetchone()
        if last is None:
            return empty
        t0 = last - window
        (count,) = q(
            "SELECT COUNT(*) FROM revolutions WHERE run = ? AND start_time >= ?", (key, t0)
        ).fetchone()
        names = list(TREND_SQL)
        if count <= MAX_POINTS:
            cols = ", ".join(TREND_SQL[k][0] for k in names)
            rows = q(
                f"SELECT start_time, {cols} FROM revolutions WHERE run = ? AND start_time >= ? "
                "ORDER BY start_time",
                (key, t0),
            ).fetchall()
        else:
            width = window / (MAX_POINTS - 1)  # bucket indices 0 .. MAX_POINTS - 1
            cols = ", ".join(f"{TREND_SQL[k][1]}({TREND_SQL[k][0]})" for k in names)
            rows = q(
                f"SELECT MIN(start_time), {cols} FROM revolutions WHERE run = ? AND start_time >= ? "
                "GROUP BY CAST((start_time - ?) / ? AS INTEGER) ORDER BY 1",
                (key, t0, t0, width),
            ).fetchall()
        out = {"t": [r[0] for r in rows]}
        for i, k in enumerate(names):
            out[k] = [r[i + 1] for r in rows]
        return out

    def close(self) -> None:
        self.db.close()
