"""Alarms of the twin (docs/page.md, "Alarms"): a limits file (TOML) -> an engine that watches the
revolution summaries and says when an alarm is raised and when it clears.

    engine = AlarmEngine(load_limits("examples/twin/limits.toml"))
    for change in engine.update(summary):      # one revolution summary (twin.SUMMARY_FIELDS)
        log(change.message)                    # and to the database, the page, OPC UA

Two kinds, both evaluated once per completed revolution:

* **limit**: a high and/or low limit on one value, with a hysteresis (the value must come back
  inside the limit by that much to clear) and a delay in revolutions (that many revolutions in a
  row beyond the limit raise it, that many in a row inside the clear band clear it). A value that
  is missing or not finite (no elastic rod, say) changes nothing.
* **trend**: the mean of a value over the recent window against its mean over the reference window
  just before it, both in the twin's time (the summaries' start_time): raised when the recent mean
  exceeds the reference mean by `rise` (relative, 0.15 = +15 %), or falls below it by `fall`;
  cleared when it is back within `clear`. Evaluated only once each window holds `min_revolutions`.

A revolution flagged `interrupted` (a stop or a reversal fell inside it) is skipped: it neither
raises, clears nor counts towards a delay or a trend window.

Each alarm is raised once and cleared once: the engine keeps its state, so a value that stays
beyond its limit does not raise it again.

Layer: shared, below the FMU access (docs/architecture.md).
"""

from __future__ import annotations

import math
import re
from collections import deque
from dataclasses import dataclass, field

from .cli_errors import read_toml

#: The values an alarm can watch: the revolution summary's fields (twin.SUMMARY_FIELDS) and the
#: quantities the page shows, derived from them (`derived_values`), with their units.
UNITS = {
    "strokes_per_minute": "1/min",
    "mean_speed": "rad/s",
    "speed_fluctuation": "1",
    "crank_torque_peak": "N·m",
    "crank_torque_max": "N·m",
    "crank_torque_min": "N·m",
    "rod_force_largest": "N",
    "rod_force_max": "N",
    "rod_force_min": "N",
    "friction_work": "J",
    "rod_angle_amplitude": "rad",
    "stress_max": "Pa",
    "acceleration_max": "m/s²",
    "acceleration_min": "m/s²",
    "inertia_force_max": "N",
    "inertia_force_min": "N",
    "guide_friction_max": "N",
    "guide_friction_min": "N",
    "flow_mean": "m³/s",
    "flow_pulsation": "1",
    "hydraulic_power_mean": "W",
    "mechanical_power_mean": "W",
}
SEVERITIES = ("info", "warning", "critical")

_LIMIT_KEYS = {"name", "value", "high", "low", "hysteresis", "delay", "severity"}
_TREND_KEYS = {
    "name",
    "value",
    "recent",
    "reference",
    "rise",
    "fall",
    "clear",
    "min_revolutions",
    "delay",
    "severity",
}
_DURATION = re.compile(r"^\s*([0-9]*\.?[0-9]+)\s*(s|min|h|d)\s*$")
_SECONDS = {"s": 1.0, "min": 60.0, "h": 3600.0, "d": 86400.0}


class LimitsError(ValueError):
    """A bad limits file: one line naming the file, the key, the value and what is allowed."""


def _f(s, key):
    v = s.get(key)
    return float(v) if v is not None else math.nan


def derived_values(summary: dict) -> dict:
    """The summary's fields plus what the page shows: strokes per minute (from the mean speed, one
    stroke per revolution), the peak crank torque and the largest rod force (largest magnitude of
    the revolution's max and min)."""
    out = {k: _f(summary, k) for k in UNITS if k in summary}
    w = _f(summary, "mean_speed")
    out["strokes_per_minute"] = w * 60.0 / (2.0 * math.pi)
    out["crank_torque_peak"] = max(
        abs(_f(summary, "crank_torque_max")), abs(_f(summary, "crank_torque_min"))
    )
    out["rod_force_largest"] = max(
        abs(_f(summary, "rod_force_max")), abs(_f(summary, "rod_force_min"))
    )
    return out


@dataclass
class Limit:
    name: str
    value: str
    high: float | None = None
    low: float | None = None
    hysteresis: float = 0.0
    delay: int = 1
    severity: str = "warning"


@dataclass
class Trend:
    name: str
    value: str
    recent: float  # s
    reference: float  # s
    rise: float | None = None
    fall: float | None = None
    clear: float = 0.0
    min_revolutions: int = 10
    delay: int = 1
    severity: str = "warning"


@dataclass
class Limits:
    limits: list[Limit] = field(default_factory=list)
    trends: list[Trend] = field(default_factory=list)
    path: str = ""

    def for_value(self, value: str) -> dict:
        """The high and low limits on `value` (the lowest high and highest low, for the page)."""
        highs = [x.high for x in self.limits if x.value == value and x.high is not None]
        lows = [x.low for x in self.limits if x.value == value and x.low is not None]
        return {"high": min(highs) if highs else None, "low": max(lows) if lows else None}


def parse_duration(v) -> float:
    """Seconds from a number or a string "90 s", "10 min", "1 h", "2 d"."""
    if isinstance(v, bool):
        raise ValueError
    if isinstance(v, (int, float)):
        if not math.isfinite(v) or v <= 0:
            raise ValueError
        return float(v)
    m = _DURATION.match(str(v))
    if not m or float(m.group(1)) <= 0:
        raise ValueError
    return float(m.group(1)) * _SECONDS[m.group(2)]


def load_limits(path) -> Limits:
    """Reads and checks a limits file; LimitsError (one line) on anything wrong."""
    path = str(path)
    doc = read_toml(path, LimitsError, "the limits file")
    return parse_limits(doc, path)


def parse_limits(doc: dict, path: str = "<limits>") -> Limits:
    extra = set(doc) - {"limit", "trend"}
    if extra:
        raise LimitsError(
            f"{path}: unknown key {sorted(extra)[0]!r} (allowed: [[limit]] and [[trend]] tables)"
        )
    out = Limits(path=path)
    names: set = set()
    for kind, keys in (("limit", _LIMIT_KEYS), ("trend", _TREND_KEYS)):
        items = doc.get(kind, [])
        if not isinstance(items, list) or not all(isinstance(t, dict) for t in items):
            raise LimitsError(f"{path}: {kind} must be an array of tables ([[{kind}]])")
        for i, t in enumerate(items):
            where = f"{path}: {kind}[{i}]"
            item = _parse_item(kind, keys, t, where)
            if item.name in names:
                raise LimitsError(f"{where}.name = {item.name!r}: used twice (names are unique)")
            names.add(item.name)
            (out.limits if kind == "limit" else out.trends).append(item)
    return out


def _parse_item(kind, keys, t, where):
    bad = sorted(set(t) - keys)
    if bad:
        raise LimitsError(f"{where}: unknown key {bad[0]!r} (allowed: {', '.join(sorted(keys))})")

    def num(key, lo=None, positive=False, default=None):
        if key not in t:
            return default
        v = t[key]
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        if ok and lo is not None:
            ok = v > lo if positive else v >= lo
        if not ok:
            what = "a finite number" + (
                "" if lo is None else f" {'>' if positive else '>='} {lo:g}"
            )
            raise LimitsError(f"{where}.{key} = {v!r}: must be {what}")
        return float(v)

    def integer(key, default):
        v = t.get(key, default)
        if not isinstance(v, int) or isinstance(v, bool) or v < 1:
            raise LimitsError(f"{where}.{key} = {v!r}: must be a whole number >= 1")
        return v

    value = t.get("value")
    if value not in UNITS:
        raise LimitsError(f"{where}.value = {value!r}: must be one of {', '.join(sorted(UNITS))}")
    severity = t.get("severity", "warning")
    if severity not in SEVERITIES:
        raise LimitsError(
            f"{where}.severity = {severity!r}: must be one of {', '.join(SEVERITIES)}"
        )
    name = t.get("name", f"{value}.{kind}")
    if not isinstance(name, str) or not name.strip():
        raise LimitsError(f"{where}.name = {name!r}: must be a non-empty string")
    delay = integer("delay", 1)
    if kind == "limit":
        high, low = num("high"), num("low")
        if high is None and low is None:
            raise LimitsError(f"{where}: needs 'high' or 'low' (or both)")
        if high is not None and low is not None and low >= high:
            raise LimitsError(f"{where}.low = {low:g}: must be below high = {high:g}")
        hyst = num("hysteresis", 0.0, default=0.0)
        return Limit(name, value, high, low, hyst, delay, severity)
    durations = {}
    for key in ("recent", "reference"):
        if key not in t:
            raise LimitsError(f"{where}: needs '{key}' (a duration: seconds, or '10 min', '1 h')")
        try:
            durations[key] = parse_duration(t[key])
        except ValueError:
            raise LimitsError(
                f"{where}.{key} = {t[key]!r}: must be a duration > 0 (seconds, or a string like "
                "'90 s', '10 min', '1 h', '2 d')"
            ) from None
    rise, fall = num("rise", 0.0, positive=True), num("fall", 0.0, positive=True)
    if rise is None and fall is None:
        raise LimitsError(f"{where}: needs 'rise' or 'fall' (relative change, 0.15 = 15 %)")
    if fall is not None and fall >= 1:
        raise LimitsError(f"{where}.fall = {fall:g}: must be below 1 (a relative drop)")
    clear = num("clear", 0.0, default=0.0)
    for key, v in (("rise", rise), ("fall", fall)):
        if v is not None and clear >= v:
            raise LimitsError(f"{where}.clear = {clear:g}: must be below {key} = {v:g}")
    return Trend(
        name,
        value,
        durations["recent"],
        durations["reference"],
        rise,
        fall,
        clear,
        integer("min_revolutions", 10),
        delay,
        severity,
    )


@dataclass
class AlarmChange:
    """An alarm raised or cleared at a revolution. `t` is when its condition was met: the end of
    that revolution, its start_time + 2π/mean_speed (the twin's time, s); `value` the value (for
    a trend: the recent mean) and `limit` the threshold crossed."""

    state: str  # "raised" | "cleared"
    name: str
    value_name: str
    severity: str
    revolution: int | None
    t: float | None
    value: float
    limit: float
    message: str

    def to_dict(self) -> dict:
        return dict(self.__dict__)


class _Counter:
    """A condition held for `delay` revolutions in a row."""

    def __init__(self, delay):
        self.delay, self.n = delay, 0

    def step(self, cond: bool) -> bool:
        self.n = self.n + 1 if cond else 0
        return self.n >= self.delay


class _Window:
    """Values of a sliding window with their running sum; the sum is recomputed exactly
    (math.fsum) each time as many values have left as the window holds, so a run of months
    accumulates no rounding and the cost per revolution stays O(1) on average."""

    def __init__(self):
        self.items: deque = deque()
        self.sum = 0.0
        self.popped = 0

    def push(self, item) -> None:
        self.items.append(item)
        self.sum += item[1]

    def pop(self):
        item = self.items.popleft()
        self.sum -= item[1]
        self.popped += 1
        if self.popped >= len(self.items):
            self.sum, self.popped = math.fsum(v for _, v in self.items), 0
        return item

    def mean(self):
        return self.sum / len(self.items) if self.items else math.nan


class AlarmEngine:
    def __init__(self, limits: Limits):
        self.limits = limits
        self.active: dict[str, AlarmChange] = {}
        self._raise = {}
        self._clear = {}
        for x in limits.limits:
            for side in ("high", "low"):
                if getattr(x, side) is not None:
                    key = f"{x.name}.{side}" if x.high is not None and x.low is not None else x.name
                    self._raise[key] = _Counter(x.delay)
                    self._clear[key] = _Counter(x.delay)
        self._recent = {}
        self._reference = {}
        for tr in limits.trends:
            self._raise[tr.name] = _Counter(tr.delay)
            self._clear[tr.name] = _Counter(tr.delay)
            self._recent[tr.name] = _Window()
            self._reference[tr.name] = _Window()

    def checkpoint(self) -> dict:
        """The engine's whole state as JSON-able data (floats round-trip exactly through json),
        to be committed with the twin's checkpoint: restored with `restore`, the engine goes on
        exactly as if never stopped, so an alarm active before a restart is not raised again."""
        return {
            "active": {k: ch.to_dict() for k, ch in self.active.items()},
            "raise": {k: c.n for k, c in self._raise.items()},
            "clear": {k: c.n for k, c in self._clear.items()},
            "windows": {
                name: [[w.sum, w.popped, [list(i) for i in w.items]] for w in (rec, ref)]
                for name, rec, ref in (
                    (n, self._recent[n], self._reference[n]) for n in self._recent
                )
            },
        }

    def restore(self, cp: dict) -> AlarmEngine:
        """Takes the state of `checkpoint()` (of an engine with the same limits; an alarm or a
        trend the limits no longer have is dropped, a new one starts afresh)."""
        self.active = {
            k: AlarmChange(**v) for k, v in cp.get("active", {}).items() if k in self._raise
        }
        for key, counters in (("raise", self._raise), ("clear", self._clear)):
            for k, n in cp.get(key, {}).items():
                if k in counters:
                    counters[k].n = int(n)
        for name, pair in cp.get("windows", {}).items():
            if name in self._recent:
                for w, (total, popped, items) in zip(
                    (self._recent[name], self._reference[name]), pair
                ):
                    w.items = deque((float(t), float(v)) for t, v in items)
                    w.sum, w.popped = float(total), int(popped)
        return self

    def update(self, summary: dict) -> list[AlarmChange]:
        """One completed revolution: the alarms it raises or clears (usually none). A revolution
        in which the machine stopped or turned back (`interrupted`, docs/twin.md "Machine
        states") is not evaluated: its mean speed and extremes describe the stop, not the pump
        running, and the delays count revolutions of the pump running, not its stops."""
        if summary.get("interrupted"):
            return []
        vals = derived_values(summary)
        rev = summary.get("revolution")
        t = summary.get("start_time")
        t = float(t) if t is not None else None
        # The condition is met when the revolution is complete: at its end, start + 2π/mean
        # speed (revolution.py: mean_speed = 2π/duration), the time of its last sample. The
        # trend windows keep the revolutions' start times.
        t_met = t
        w = _f(summary, "mean_speed")
        if t is not None and math.isfinite(w) and w > 0:
            t_met = t + 2.0 * math.pi / w
        out: list[AlarmChange] = []
        for x in self.limits.limits:
            v = vals.get(x.value, math.nan)
            if not math.isfinite(v):
                continue
            for side in ("high", "low"):
                lim = getattr(x, side)
                if lim is None:
                    continue
                key = f"{x.name}.{side}" if x.high is not None and x.low is not None else x.name
                if side == "high":
                    beyond, back = v > lim, v < lim - x.hysteresis
                else:
                    beyond, back = v < lim, v > lim + x.hysteresis
                word = "above" if side == "high" else "below"
                out += self._transition(
                    key, x, rev, t_met, v, lim, beyond, back,
                    f"{x.value} = {v:.6g} {UNITS[x.value]} {word} its {side} limit {lim:.6g}",
                    f"{x.value} = {v:.6g} {UNITS[x.value]} back within its {side} limit "
                    f"{lim:.6g} (hysteresis {x.hysteresis:g})",
                )  # fmt: skip
        for tr in self.limits.trends:
            v = vals.get(tr.value, math.nan)
            if t is None or not math.isfinite(v):
                continue
            out += self._trend(tr, rev, t, v, t_met)
        return out

    def _trend(self, tr: Trend, rev, t, v, t_met) -> list[AlarmChange]:
        recent, ref = self._recent[tr.name], self._reference[tr.name]
        recent.push((t, v))
        # Revolutions leave the recent window into the reference window, then drop out of it.
        while recent.items and recent.items[0][0] <= t - tr.recent:
            ref.push(recent.pop())
        while ref.items and ref.items[0][0] <= t - tr.recent - tr.reference:
            ref.pop()
        if len(recent.items) < tr.min_revolutions or len(ref.items) < tr.min_revolutions:
            return []
        m_recent, m_ref = recent.mean(), ref.mean()
        if not (math.isfinite(m_ref) and m_ref != 0):
            return []
        change = m_recent / m_ref - 1.0
        beyond = (tr.rise is not None and change > tr.rise) or (
            tr.fall is not None and change < -tr.fall
        )
        back = abs(change) < tr.clear if tr.clear > 0 else not beyond
        lim = m_ref * (1 + (tr.rise if change > 0 and tr.rise is not None else -(tr.fall or 0)))
        span = f"over the last {_dur(tr.recent)} against the {_dur(tr.reference)} before"
        return self._transition(
            tr.name, tr, rev, t_met, m_recent, lim, beyond, back,
            f"{tr.value} mean {m_recent:.6g} {UNITS[tr.value]} {span}: {change:+.1%} "
            f"(mean {m_ref:.6g})",
            f"{tr.value} mean {m_recent:.6g} {UNITS[tr.value]} {span}: {change:+.1%}, "
            "back within the trend limit",
        )  # fmt: skip

    def _transition(self, key, item, rev, t, v, lim, beyond, back, raise_msg, clear_msg):
        up, down = self._raise[key].step(beyond), self._clear[key].step(back)
        if key not in self.active and up:
            ch = AlarmChange(
                "raised", key, item.value, item.severity, rev, t, v, lim,
                f"alarm {key} ({item.severity}) raised: {raise_msg}",
            )  # fmt: skip
            self.active[key] = ch
            self._clear[key].n = 0
            return [ch]
        if key in self.active and down:
            del self.active[key]
            self._raise[key].n = 0
            return [
                AlarmChange(
                    "cleared",
                    key,
                    item.value,
                    item.severity,
                    rev,
                    t,
                    v,
                    lim,
                    f"alarm {key} ({item.severity}) cleared: {clear_msg}",
                )  # fmt: skip
            ]
        return []


def _dur(s: float) -> str:
    for unit in ("d", "h", "min"):
        if s >= _SECONDS[unit] and s % _SECONDS[unit] == 0:
            return f"{s / _SECONDS[unit]:g} {unit}"
    return f"{s:g} s"
