"""The drilling-pump digital twin (docs/twin.md): measured crank data in, the FMU's loads out, per
sample and per revolution, replayed from a file or live.

The pipeline works on chunks of input lines (`Twin.feed`): a whole block of a file in replay, the
lines available now in live mode. Every sample's numbers are computed on their own, so the size of
the chunks changes when rows appear, never their values: replay, live and resumed runs give the
same numbers bit for bit.

1. **Reader** (`parse_lines`): a CSV with a header naming `time`, `crank_angle` and optionally
   `crank_speed` and `process_force`. A bad field, time going backwards, a duplicate timestamp
   (dropped and counted, or an error), an angle step faster than `max_speed` or a crank turning
   backwards stops the run with the line number (`DataError`), after the samples before it.
2. **Conditioning** (`conditioning.py`, vectorised over the chunk): angle to rad and unwrapped;
   ω and ε from a local cubic over the smoothing window where they are not measured (natively,
   `batch.local_cubic`, the algorithm of `conditioning.fit`). A gap longer
   than `gap_limit` ends a segment: the smoother does not bridge it, the gap is reported, and the
   FMU is re-initialized at the first sample after it (its dynamic state, an elastic rod's cage,
   starts quasi-statically again, docs/model.md §6), because the crank's motion inside the gap is
   unknown.
3. **FMU**: the sample times are the communication points (variable step); at each sample the
   crank inputs are set and every output is read, for a whole chunk in one call of the native
   batch driver (`fmu.Channel.run`, tools/fmi2-batch).
4. **Per revolution** (`revolution.py`): when the model angle completes a revolution its summary
   is emitted.

Checkpoints (`Twin.checkpoint`/`Twin.from_checkpoint`) hold the FMU's serialized state and the
twin's own position and buffers; a run resumed from one continues exactly as if uninterrupted.
"""

from __future__ import annotations

import base64
import json
import math
from dataclasses import dataclass, field

import numpy as np

from . import conditioning as cond
from .batch import local_cubic, parse_csv
from .fmu import Fmu, FmuError
from .presets import preset_values
from .revolution import TWO_PI, revolution_table

INPUTS = ("crank.angle", "crank.speed", "crank.acceleration", "link.external_force")

#: Samples conditioned and sent to the FMU per call at most (bounds the memory of the windows).
BLOCK = 4096


class DataError(ValueError):
    """Bad measured data, with the input line number. `rows` and `summaries` are what the twin
    computed from the samples before it (to be written before the run stops)."""

    rows = None
    summaries: list = []


@dataclass
class Options:
    angle_unit: str = "rad"  # rad | deg | counts
    counts_per_rev: float | None = None
    wrapped: bool = True  # angles wrap every revolution (else continuous)
    speed_unit: str = "rad/s"  # rad/s | rpm
    duplicates: str = "drop"  # drop | error
    window: float = 0.1  # smoothing window [s]
    gap_limit: float = 0.05  # a longer interval between samples is a gap [s]
    max_speed: float = 100.0  # fastest physically possible crank speed [rad/s]
    use_measured_speed: bool = True  # take crank_speed from the data when present

    def to_dict(self) -> dict:
        return dict(self.__dict__)


SUMMARY_FIELDS = (
    "revolution",
    "start_time",
    "mean_speed",
    "speed_fluctuation",
    "acceleration_max",
    "acceleration_min",
    "inertia_force_max",
    "inertia_force_min",
    "guide_friction_max",
    "guide_friction_min",
    "rod_force_max",
    "rod_force_min",
    "crank_torque_max",
    "crank_torque_min",
    "friction_work",
    "rod_angle_amplitude",
    "stress_max",
)

_EXTREMES = (
    ("suspension.acceleration", "acceleration"),
    ("inertia.force", "inertia_force"),
    ("guide.friction", "guide_friction"),
    ("rod.force", "rod_force"),
    ("crank.torque", "crank_torque"),
)
#: The column of revolution_table behind each of SUMMARY_FIELDS.
_EXTREME_KEYS = {f"{key}_{m}": f"{q}.{m}" for q, key in _EXTREMES for m in ("max", "min")}
_SUMMARY_KEYS = tuple(_EXTREME_KEYS.get(f, f) for f in SUMMARY_FIELDS)


def parse_header(line: str) -> dict:
    names = [c.strip() for c in line.strip().split(",")]
    cols = {n: i for i, n in enumerate(names)}
    for need in ("time", "crank_angle"):
        if need not in cols:
            raise DataError(f"line 1: the header must name '{need}' (found: {', '.join(names)})")
    return cols


def parse_line(
    line: str, lineno: int, cols: dict
) -> tuple[float, float, float | None, float | None]:
    parts = line.strip().split(",")
    if len(parts) < len(cols):
        raise DataError(f"line {lineno}: {len(parts)} fields, the header names {len(cols)}")

    def num(name):
        raw = parts[cols[name]].strip()
        try:
            v = float(raw)
        except ValueError:
            raise DataError(f"line {lineno}: {name} = {raw!r} is not a number") from None
        if not math.isfinite(v):
            raise DataError(f"line {lineno}: {name} = {raw!r} is not a finite number")
        return v

    t, a = num("time"), num("crank_angle")
    w = (
        num("crank_speed")
        if "crank_speed" in cols and parts[cols["crank_speed"]].strip() != ""
        else None
    )
    f = (
        num("process_force")
        if "process_force" in cols and parts[cols["process_force"]].strip() != ""
        else None
    )
    return t, a, w, f


def parse_lines(lines: list[str], first_lineno: int, cols: dict):
    """Consecutive data lines (the first is line `first_lineno`) as arrays: line numbers, time,
    angle, speed (NaN where absent) and force (0 where absent), blank lines skipped. Returns the
    arrays of the lines before the first bad one and its DataError (or None). The clean lines are
    parsed natively (`batch.parse_csv`), from the first other one on in Python."""
    names = [c for c in ("time", "crank_angle", "crank_speed", "process_force") if c in cols]
    defaults = [{"crank_speed": math.nan, "process_force": 0.0}.get(c) for c in names]
    n, pos, parts = len(lines), 0, []
    while pos < n:
        got = parse_csv(
            "\n".join(lines[pos:]).encode(), len(cols), [cols[c] for c in names], defaults, n - pos
        )
        k = len(got[0])
        parts.append(
            (
                np.arange(first_lineno + pos, first_lineno + pos + k),
                got[0],
                got[1],
                got[names.index("crank_speed")] if "crank_speed" in cols else np.full(k, math.nan),
                got[names.index("process_force")] if "process_force" in cols else np.zeros(k),
            )
        )
        pos += k
        if pos < n:
            # One line for Python: blank, bad (the message), or a number only Python reads.
            arrays, err = _parse_slowly(lines[pos : pos + 1], first_lineno + pos, cols)
            parts.append(arrays)
            pos += 1
            if err is not None:
                return tuple(np.concatenate(p) for p in zip(*parts)), err
    if not parts:
        return _parse_slowly([], first_lineno, cols)
    return tuple(np.concatenate(p) for p in zip(*parts)), None


def _parse_slowly(lines, first_lineno, cols):
    """parse_lines line by line: finds the first bad line and its message."""
    out, err = [], None
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            t, a, w, f = parse_line(line, first_lineno + i, cols)
        except DataError as e:
            err = e
            break
        out.append((first_lineno + i, t, a, math.nan if w is None else w, 0.0 if f is None else f))
    cols_ = list(zip(*out)) if out else [()] * 5
    return (np.array(cols_[0], dtype=np.int64), *(np.array(c, dtype=float) for c in cols_[1:])), err


def remainder_2pi(x: np.ndarray) -> np.ndarray:
    """math.remainder(x, 2π) elementwise (IEEE remainder: exact, ties to an even quotient)."""
    r = np.fmod(x, TWO_PI)
    r = np.where(r > math.pi, r - TWO_PI, np.where(r < -math.pi, r + TWO_PI, r))
    for i in np.flatnonzero(np.abs(r) == math.pi):
        r[i] = math.remainder(float(x[i]), TWO_PI)
    return r


@dataclass
class _Segment:
    """Samples of the current segment whose outputs are not computed yet, with the window
    history before them."""

    t: np.ndarray = field(default_factory=lambda: np.empty(0))
    theta: np.ndarray = field(default_factory=lambda: np.empty(0))
    speed: np.ndarray = field(default_factory=lambda: np.empty(0))  # NaN: not measured
    force: np.ndarray = field(default_factory=lambda: np.empty(0))
    line: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    done: int = 0  # samples of the buffer already sent to the FMU
    segment_start: bool = True

    NAMES = ("t", "theta", "speed", "force", "line")

    def append(self, **arrays) -> None:
        for name in self.NAMES:
            setattr(self, name, np.concatenate((getattr(self, name), arrays[name])))

    def drop(self, k: int) -> None:
        for name in self.NAMES:
            setattr(self, name, getattr(self, name)[k:])
        self.done -= k


class Twin:
    """One twin run. `feed(lines, first_lineno)` takes consecutive input lines; it returns the
    output rows now ready (a 2-D array: time then the FMU's outputs) and the revolution summaries
    now complete. `finish()` flushes the rest at the end of the input.

    With `defer_summaries` set, `feed` and `finish` return, instead of the summaries, the pieces
    they are made from, and `summaries(pieces)` makes them: on another thread, in order, while
    this one goes on with the next input (scripts/twin.py does so). The revolution state is then
    only touched by `summaries`, so the caller takes `checkpoint()` only once every piece handed
    out has been summarized (feed and finish hand out all they emitted)."""

    def __init__(
        self,
        fmu_path: str,
        machine: str = "default",
        options: Options | None = None,
        extra_values: dict | None = None,
    ):
        self.o = options or Options()
        self.machine = machine
        self.values = {k: v for k, v in preset_values(machine).items() if k not in INPUTS}
        self.values.update(extra_values or {})
        self.fmu = Fmu(fmu_path)
        self.outputs = list(self.fmu.outputs)
        self.i_angle = 1 + self.outputs.index("crank.model_angle")
        self.channel = None
        self.cols = None
        self.half = None
        self.buf = _Segment()
        self.last_raw = None  # previous accepted raw angle (rad), unwrapped angle, time
        self.last_unwrapped = None
        self.last_t = None
        self.duplicates = 0
        self.gaps: list = []
        self.rev_parts: list = []  # rows of the revolution in progress (and the sample before it)
        self.rev_next = None  # index of the next revolution to complete
        self.defer_summaries = False
        self._pending: list = []  # rows for the summaries, None where a segment starts
        self.lines_read = 0  # input lines consumed (header included)
        self.rows_out = 0
        self.messages: list = []

    @property
    def header(self) -> list[str]:
        return ["time", *self.outputs]

    def _empty(self) -> np.ndarray:
        return np.empty((0, 1 + len(self.outputs)))

    # ---- reading -------------------------------------------------------------------------------

    def feed(self, lines: list[str], first_lineno: int) -> tuple[np.ndarray, list]:
        """Lines first_lineno, first_lineno + 1, ... of the input. On bad data the samples before
        it are processed and DataError carries their rows and summaries (pieces, when deferred)."""
        rows = [self._empty()]
        if lines and self.cols is None:
            self.cols = parse_header(lines[0])
            lines, first_lineno = lines[1:], first_lineno + 1
        self.lines_read = first_lineno + len(lines) - 1
        if not lines:
            return self._hand_out(rows, None)
        (ln, t, a, w, f), err = parse_lines(lines, first_lineno, self.cols)
        try:
            err = self._accept(ln, t, a, w, f, rows) or err
        except (DataError, FmuError) as e:
            err = e
        return self._hand_out(rows, err)

    def _accept(self, ln, t, a, w, f, rows) -> DataError | None:
        """Validates, unwraps and conditions parsed samples; returns the first DataError of the
        checks that depend on the previous samples, after processing the samples before it."""
        o = self.o
        a = cond.to_radians(a, o.angle_unit, o.counts_per_rev)
        if not o.use_measured_speed:
            w = np.full(len(w), math.nan)
        elif o.speed_unit == "rpm":
            w = w * TWO_PI / 60.0
        n = len(t)
        err = None
        if n == 0:
            return err
        # Intervals to the previous line (time never goes backwards up to the first error, so the
        # previous accepted sample of a line is the line before it, duplicates included).
        prev = (
            np.concatenate(([self.last_t], t[:-1]))
            if self.last_t is not None
            else np.concatenate(([math.nan], t[:-1]))
        )
        with np.errstate(invalid="ignore"):
            back = np.flatnonzero(t < prev)
            dup = np.flatnonzero(t == prev)
        stop = n
        if back.size:
            k = stop = int(back[0])
            err = DataError(
                f"line {ln[k]}: time {float(t[k])!r} s goes backwards (previous sample at {float(prev[k])!r} s)"
            )
        dup = dup[dup < stop]
        if dup.size and o.duplicates == "error":
            k = stop = int(dup[0])
            err = DataError(f"line {ln[k]}: duplicate timestamp {float(t[k])!r} s")
            dup = dup[:0]
        keep = np.ones(stop, dtype=bool)
        keep[dup] = False
        self.duplicates += int(dup.size)
        ln, t, a, w, f = (
            ln[:stop][keep],
            t[:stop][keep],
            a[:stop][keep],
            w[:stop][keep],
            f[:stop][keep],
        )
        if len(t) == 0:
            return err
        # Unwrap: each step is the smallest one modulo a revolution.
        first = self.last_t is None
        if o.wrapped:
            steps = remainder_2pi(np.diff(a, prepend=a[0] if first else self.last_raw))
            theta = np.cumsum(
                np.concatenate(
                    ([a[0] if first else self.last_unwrapped], steps[1:] if first else steps)
                )
            )
            theta = theta if first else theta[1:]
        else:
            theta = a
        tp = np.concatenate(([t[0] if first else self.last_t], t[:-1]))
        thp = np.concatenate(([theta[0] if first else self.last_unwrapped], theta[:-1]))
        dt, dth = t - tp, theta - thp
        near = dt <= o.gap_limit
        bad = np.flatnonzero(near & (np.abs(dth) > o.max_speed * dt + 1e-9))
        if bad.size and (err is None or bad[0] < len(t)):
            k = int(bad[0])
            err = DataError(
                f"line {ln[k]}: the crank angle moves {float(dth[k]):.6g} rad in {float(dt[k]):.6g} s "
                f"(more than the largest possible crank speed, --max-speed {o.max_speed:g} rad/s, allows)"
            )
            ln, t, theta, w, f, dt, near, dth = (x[:k] for x in (ln, t, theta, w, f, dt, near, dth))
            a = a[:k]
        back = np.flatnonzero(near & (dth < 0))
        if back.size:
            k = int(back[0])
            err = DataError(
                f"line {ln[k]}: the crank angle goes backwards by {float(-dth[k]):.6g} rad "
                "(the twin needs forward rotation)"
            )
            ln, t, theta, w, f, dt = (x[:k] for x in (ln, t, theta, w, f, dt))
            a = a[:k]
        if len(t) == 0:
            return err
        # Segments: a gap (an interval longer than gap_limit) starts a new one.
        gaps = [k for k in np.flatnonzero(dt > o.gap_limit).tolist() if not (first and k == 0)]
        for lo, hi in zip([0, *gaps], [*gaps, len(t)]):
            if lo in gaps:
                t0, t1 = (self.last_t if lo == 0 else float(t[lo - 1])), float(t[lo])
                self.gaps.append((t0, t1))
                self.messages.append(
                    f"gap of {t1 - t0:.6g} s from t = {t0!r} s to {t1!r} s (line {ln[lo]}): "
                    "the FMU is re-initialized after it"
                )
                self._drain(True, rows)
                self.buf = _Segment()
            if hi > lo:
                self.buf.append(
                    t=t[lo:hi], theta=theta[lo:hi], speed=w[lo:hi], force=f[lo:hi], line=ln[lo:hi]
                )
                if self.half is None and (self.last_t is not None or hi - lo > 1):
                    # The smoothing window in samples, from the first interval.
                    d = float(t[1] - t[0]) if first else float(t[0]) - self.last_t
                    self.half = cond.window_samples(o.window, d)
                self.last_raw, self.last_unwrapped, self.last_t = (
                    float(a[hi - 1]),
                    float(theta[hi - 1]),
                    float(t[hi - 1]),
                )
        if self.half is not None:
            self._drain(False, rows)
        return err

    def finish(self) -> tuple[np.ndarray, list]:
        if self.half is None:
            self.half = 2
        rows, err = [self._empty()], None
        try:
            self._drain(True, rows)
        except (DataError, FmuError) as e:
            err = e
        return self._hand_out(rows, err)

    def _hand_out(self, rows: list, err: Exception | None) -> tuple[np.ndarray, list]:
        """The rows emitted and their summaries; with an error, raises it carrying them."""
        parts = [r for r in rows if len(r)] or rows[:1]
        # One block (the usual case) goes out as it is: nothing writes to it any more.
        out = (parts[0] if len(parts) == 1 else np.concatenate(parts)), self._take_summaries()
        if err is not None:
            err.rows, err.summaries = out
            raise err
        return out

    def _emit(self, r: np.ndarray, rows: list) -> None:
        rows.append(r)
        if len(r):
            self._pending.append(r)

    def _take_summaries(self) -> list:
        """The summaries of what was emitted since the last call (or its pieces, when deferred)."""
        pieces, self._pending = self._pending, []
        return pieces if self.defer_summaries else self.summaries(pieces)

    def summaries(self, pieces: list) -> list:
        """Summaries of the revolutions completed by these pieces (rows; None starts a segment)."""
        out = []
        for r in pieces:
            if r is None:
                self.rev_parts, self.rev_next = [], None
            else:
                out += self._revolutions(r)
        return out

    # ---- conditioning and the FMU ---------------------------------------------------------------

    def _drain(self, final: bool, rows: list) -> None:
        """Emits into `rows` the outputs of the samples whose smoothing window is complete (all of
        them when the segment ends), in blocks of at most BLOCK. When the FMU fails, the samples
        before the failing one are emitted before the error goes on."""
        b = self.buf
        n = len(b.t)
        half = self.half or 2
        width = 2 * half + 1
        # A sample's window is complete when `half` samples follow it (or the segment ended).
        ready = n if final else (max(0, n - half) if n >= width else 0)
        if ready <= b.done:
            return
        if n < cond.DEGREE + 1:
            raise DataError(
                f"line {b.line[0]}: a segment of {n} sample(s) between gaps is too short "
                f"(at least {cond.DEGREE + 1} are needed)"
            )
        for lo in range(b.done, ready, BLOCK):
            centres = np.arange(lo, min(ready, lo + BLOCK))
            w_est, e_est = local_cubic(b.t, b.theta, half, lo, len(centres))
            w = np.where(np.isnan(b.speed[centres]), w_est, b.speed[centres])
            inputs = np.column_stack([b.theta[centres], w, e_est, b.force[centres]])
            block = np.empty((len(centres), 1 + len(self.outputs)))
            block[:, 0] = b.t[centres]
            try:
                self._fmu_rows(block, inputs, b.segment_start and lo == 0)
            except FmuError as e:
                k = getattr(e, "index", 0)
                self._emit(block[:k], rows)
                if k < len(centres):
                    e.args = (
                        f"line {int(b.line[centres[k]])} (t = {float(b.t[centres[k]])!r} s): {e}",
                    )
                raise
            self._emit(block, rows)
            b.done = int(centres[-1]) + 1
        # Keep only what later windows can still reach.
        keep_from = max(0, b.done - width)
        if keep_from > 0:
            b.drop(keep_from)
            b.segment_start = False

    def _fmu_rows(self, rows, inputs, new_segment) -> None:
        """Outputs into rows[:, 1:] for the inputs at the times rows[:, 0]."""
        first = 0
        if new_segment or self.channel is None:
            self.fmu.start(
                {**self.values, **dict(zip(INPUTS, map(float, inputs[0])))},
                start_time=float(rows[0, 0]),
            )
            self.channel = self.fmu.channel(list(INPUTS), self.outputs)
            self.channel.read(rows[0, 1:])
            self._pending.append(None)  # the summaries start again with this segment
            self.rows_out += 1
            first = 1
        try:
            self.channel.run(rows[first:, 0], inputs[first:], rows[first:, 1:])
        except FmuError as e:
            e.index = first + e.index
            self.rows_out += e.index - first
            raise
        self.rows_out += len(rows) - first

    def _revolutions(self, rows: np.ndarray) -> list:
        """Summaries of the revolutions of the model angle completed by these rows."""
        if len(rows) == 0:
            return []
        ang = rows[:, self.i_angle]
        if self.rev_next is None:
            self.rev_next = math.ceil(ang[0] / TWO_PI)  # the first revolution starts there
        self.rev_parts.append(rows)
        last = self.rev_next
        top = float(np.max(ang))
        while TWO_PI * (last + 1) <= top:
            last += 1
        if last == self.rev_next:
            return []
        arr = np.concatenate(self.rev_parts)
        series = {name: arr[:, 1 + i] for i, name in enumerate(self.outputs)}
        tab = revolution_table(
            arr[:, 0], arr[:, self.i_angle], series, speed=series["crank.model_speed"]
        )
        pick = (tab["revolution"] >= self.rev_next) & (tab["revolution"] < last)
        n = int(np.count_nonzero(pick))
        columns = [tab[key][pick].tolist() if key in tab else [None] * n for key in _SUMMARY_KEYS]
        out = [dict(zip(SUMMARY_FIELDS, values)) for values in zip(*columns)]
        # Keep the samples from just before the next revolution's start.
        start = int(np.searchsorted(arr[:, self.i_angle], TWO_PI * last)) - 1
        self.rev_parts = [arr[max(0, start) :].copy()]
        self.rev_next = last
        return out

    # ---- checkpoints ---------------------------------------------------------------------------

    def checkpoint(self) -> dict:
        """Everything needed to continue exactly: the FMU's serialized state and time, the
        position in the input, and the twin's buffers."""
        b = self.buf
        rev = np.concatenate(self.rev_parts) if self.rev_parts else self._empty()
        return {
            "version": 2,
            "machine": self.machine,
            "options": self.o.to_dict(),
            "fmu_state": base64.b64encode(self.fmu.serialize()).decode()
            if self.channel is not None
            else None,
            "fmu_time": self.fmu.time,
            "lines_read": self.lines_read,
            "rows_out": self.rows_out,
            "cols": self.cols,
            "half": self.half,
            "buf": {
                "t": b.t.tolist(),
                "theta": b.theta.tolist(),
                "speed": [None if math.isnan(v) else v for v in b.speed.tolist()],
                "force": b.force.tolist(),
                "line": b.line.tolist(),
                "done": b.done,
                "segment_start": b.segment_start,
            },
            "last": [self.last_raw, self.last_unwrapped, self.last_t],
            "duplicates": self.duplicates,
            "gaps": self.gaps,
            "rev_rows": rev.tolist(),
            "rev_next": self.rev_next,
        }

    @classmethod
    def from_checkpoint(cls, fmu_path: str, cp: dict, extra_values: dict | None = None) -> Twin:
        if cp.get("version") != 2:
            raise ValueError(f"checkpoint version {cp.get('version')!r}; this twin reads version 2")
        tw = cls(fmu_path, cp["machine"], Options(**cp["options"]), extra_values)
        tw.lines_read, tw.rows_out, tw.cols, tw.half = (
            cp["lines_read"],
            cp["rows_out"],
            cp["cols"],
            cp["half"],
        )
        bb = cp["buf"]
        tw.buf = _Segment(
            t=np.array(bb["t"], dtype=float),
            theta=np.array(bb["theta"], dtype=float),
            speed=np.array([math.nan if v is None else v for v in bb["speed"]], dtype=float),
            force=np.array(bb["force"], dtype=float),
            line=np.array(bb["line"], dtype=np.int64),
            done=bb["done"],
            segment_start=bb["segment_start"],
        )
        tw.last_raw, tw.last_unwrapped, tw.last_t = cp["last"]
        tw.duplicates, tw.gaps = cp["duplicates"], [tuple(g) for g in cp["gaps"]]
        rev = np.array(cp["rev_rows"], dtype=float).reshape(-1, 1 + len(tw.outputs))
        tw.rev_parts, tw.rev_next = ([rev] if len(rev) else []), cp["rev_next"]
        if cp["fmu_state"] is not None:
            tw.fmu.start(tw.values)
            tw.fmu.restore(base64.b64decode(cp["fmu_state"]), cp["fmu_time"])
            tw.channel = tw.fmu.channel(list(INPUTS), tw.outputs)
        return tw


def save_checkpoint(path, cp: dict) -> None:
    import os
    import pathlib

    p = pathlib.Path(path)
    tmp = p.with_suffix(p.suffix + ".tmp")
    tmp.write_text(json.dumps(cp))
    os.replace(tmp, p)
