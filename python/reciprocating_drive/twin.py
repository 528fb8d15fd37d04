"""The drilling-pump digital twin (docs/twin.md): measured crank data in, the FMU's loads out, per
sample and per revolution, replayed from a file or live.

The pipeline, one sample at a time (`Twin.push`), so that replay and live mode run the same code
and give the same numbers bit for bit:

1. **Reader** (`parse_line`): a CSV with a header naming `time`, `crank_angle` and optionally
   `crank_speed` and `process_force`. A bad field, time going backwards, a duplicate timestamp
   (dropped and counted, or an error) or an angle step faster than `max_speed` stops the run with
   the line number (`DataError`).
2. **Conditioning** (`conditioning.py`): angle to rad and unwrapped; ω and ε from a local cubic
   over the smoothing window where they are not measured. A gap longer than `gap_limit` ends a
   segment: the smoother does not bridge it, the gap is reported, and the FMU is re-initialized at
   the first sample after it (its dynamic state, an elastic rod's cage, starts quasi-statically
   again, docs/model.md §6), because the crank's motion inside the gap is unknown.
3. **FMU**: the sample times are the communication points (variable step); at each sample the
   crank inputs are set and every output is read.
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
from .fmu import Fmu
from .presets import preset_values
from .revolution import TWO_PI, summarize_revolutions


class DataError(ValueError):
    """Bad measured data, with the input line number."""


@dataclass
class Options:
    angle_unit: str = "rad"           # rad | deg | counts
    counts_per_rev: float | None = None
    wrapped: bool = True              # angles wrap every revolution (else continuous)
    speed_unit: str = "rad/s"         # rad/s | rpm
    duplicates: str = "drop"          # drop | error
    window: float = 0.1               # smoothing window [s]
    gap_limit: float = 0.05           # a longer interval between samples is a gap [s]
    max_speed: float = 100.0          # fastest physically possible crank speed [rad/s]
    use_measured_speed: bool = True   # take crank_speed from the data when present

    def to_dict(self) -> dict:
        return dict(self.__dict__)


SUMMARY_FIELDS = ("revolution", "start_time", "mean_speed", "speed_fluctuation",
                  "acceleration_max", "acceleration_min", "inertia_force_max", "inertia_force_min",
                  "guide_friction_max", "guide_friction_min", "rod_force_max", "rod_force_min",
                  "crank_torque_max", "crank_torque_min", "friction_work", "rod_angle_amplitude",
                  "stress_max")

_EXTREMES = (("suspension.acceleration", "acceleration"), ("inertia.force", "inertia_force"),
             ("guide.friction", "guide_friction"), ("rod.force", "rod_force"), ("crank.torque", "crank_torque"))


def parse_header(line: str) -> dict:
    names = [c.strip() for c in line.strip().split(",")]
    cols = {n: i for i, n in enumerate(names)}
    for need in ("time", "crank_angle"):
        if need not in cols:
            raise DataError(f"line 1: the header must name '{need}' (found: {', '.join(names)})")
    return cols


def parse_line(line: str, lineno: int, cols: dict) -> tuple[float, float, float | None, float | None]:
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
    w = num("crank_speed") if "crank_speed" in cols and parts[cols["crank_speed"]].strip() != "" else None
    f = num("process_force") if "process_force" in cols and parts[cols["process_force"]].strip() != "" else None
    return t, a, w, f


@dataclass
class _Pending:
    """Samples of the current segment whose outputs are not computed yet, with the window
    history before them."""
    t: list = field(default_factory=list)
    theta: list = field(default_factory=list)
    speed: list = field(default_factory=list)
    force: list = field(default_factory=list)
    line: list = field(default_factory=list)
    done: int = 0          # samples of the buffer already sent to the FMU
    segment_start: bool = True


class Twin:
    """One twin run. `push(line, lineno)` takes an input line; it returns the output rows now
    ready (each a list of floats: time then the FMU's outputs) and the revolution summaries now
    complete. `finish()` flushes the rest at the end of the input."""

    def __init__(self, fmu_path: str, machine: str = "default", options: Options | None = None,
                 extra_values: dict | None = None, batch: int = 1):
        self.o = options or Options()
        # Samples conditioned together: 1 in live mode (each as soon as its window is complete),
        # more in replay. Every sample's numbers are computed on their own (conditioning.fit), so
        # the batch changes when rows appear, never their values.
        self.batch = max(1, int(batch))
        self.machine = machine
        self.values = {k: v for k, v in preset_values(machine).items()
                       if k not in ("crank.angle", "crank.speed", "crank.acceleration", "link.external_force")}
        self.values.update(extra_values or {})
        self.fmu = Fmu(fmu_path)
        self.outputs = list(self.fmu.outputs)
        self.channel = None
        self.cols = None
        self.half = None
        self.buf = _Pending()
        self.last_raw = None       # previous accepted raw angle (rad), unwrapped angle, time
        self.last_unwrapped = None
        self.last_t = None
        self.duplicates = 0
        self.gaps: list = []
        self.rev_rows: list = []   # rows of the current and previous revolution (summaries)
        self.rev_next = None       # index of the next revolution boundary to complete
        self.fmu_time = None
        self.lines_read = 0        # input lines consumed (header included)
        self.rows_out = 0
        self.messages: list = []

    # ---- output columns ------------------------------------------------------------------------

    @property
    def header(self) -> list[str]:
        return ["time", *self.outputs]

    # ---- reading -------------------------------------------------------------------------------

    def push(self, line: str, lineno: int) -> tuple[list, list]:
        self.lines_read = lineno
        if self.cols is None:
            self.cols = parse_header(line)
            return [], []
        if not line.strip():
            return [], []
        t, a, w, f = parse_line(line, lineno, self.cols)
        a = float(cond.to_radians(np.array([a]), self.o.angle_unit, self.o.counts_per_rev)[0])
        if w is not None and self.o.use_measured_speed:
            w = w * TWO_PI / 60.0 if self.o.speed_unit == "rpm" else w
        else:
            w = None
        rows, sums = [], []
        if self.last_t is not None:
            if t < self.last_t:
                raise DataError(f"line {lineno}: time {t!r} s goes backwards (previous sample at {self.last_t!r} s)")
            if t == self.last_t:
                if self.o.duplicates == "error":
                    raise DataError(f"line {lineno}: duplicate timestamp {t!r} s")
                self.duplicates += 1
                return [], []
            dt = t - self.last_t
            if self.o.wrapped:
                theta = cond.unwrap_step(self.last_raw, self.last_unwrapped, a)
            else:
                theta = a
            if dt <= self.o.gap_limit and abs(theta - self.last_unwrapped) > self.o.max_speed * dt + 1e-9:
                raise DataError(
                    f"line {lineno}: the crank angle moves {theta - self.last_unwrapped:.6g} rad in {dt:.6g} s "
                    f"(more than the largest possible crank speed, --max-speed {self.o.max_speed:g} rad/s, allows)")
            if dt > self.o.gap_limit:
                self.gaps.append((self.last_t, t))
                self.messages.append(f"gap of {dt:.6g} s from t = {self.last_t!r} s to {t!r} s (line {lineno}): "
                                     "the FMU is re-initialized after it")
                r, s = self._drain(final=True)
                rows += r
                sums += s
                self.buf = _Pending()
        else:
            theta = a
        if self.half is None:
            # The smoothing window in samples, from the first interval (1 kHz data: ±window/2).
            self.half = None if self.last_t is None else cond.window_samples(self.o.window, t - self.last_t)
        self.last_raw, self.last_unwrapped, self.last_t = a, theta, t
        b = self.buf
        b.t.append(t)
        b.theta.append(theta)
        b.speed.append(w)
        b.force.append(f)
        b.line.append(lineno)
        if self.half is not None:
            r, s = self._drain(final=False)
            rows += r
            sums += s
        return rows, sums

    def finish(self) -> tuple[list, list]:
        if self.half is None:
            self.half = 2
        return self._drain(final=True)

    # ---- conditioning and the FMU ---------------------------------------------------------------

    def _drain(self, final: bool) -> tuple[list, list]:
        b = self.buf
        n = len(b.t)
        half = self.half or 2
        width = 2 * half + 1
        # A sample's window is complete when `half` samples follow it (or the segment ended).
        ready = n if final else max(0, n - half)
        if n < width and not final:
            ready = 0
        if ready <= b.done or (not final and ready - b.done < self.batch):
            return [], []
        if n < cond.DEGREE + 1:
            raise DataError(f"line {b.line[0]}: a segment of {n} sample(s) between gaps is too short "
                            f"(at least {cond.DEGREE + 1} are needed)")
        t = np.asarray(b.t)
        th = np.asarray(b.theta)
        centres = np.arange(b.done, ready)
        idx = cond.windows(n, half, centres)
        w_est, e_est = cond.fit(t[idx], th[idx], t[centres][:, None], th[centres][:, None])
        rows, sums = [], []
        for j, k in enumerate(centres):
            w = b.speed[k] if b.speed[k] is not None else float(w_est[j])
            e = float(e_est[j])
            f = b.force[k] if b.force[k] is not None else 0.0
            row = self._fmu_sample(float(t[k]), float(th[k]), w, e, f, b.segment_start and k == 0)
            rows.append(row)
            sums += self._revolution(row)
        b.done = ready
        # Keep only what later windows can still reach.
        keep_from = max(0, b.done - width)
        if keep_from > 0:
            for name in ("t", "theta", "speed", "force", "line"):
                del getattr(b, name)[:keep_from]
            b.done -= keep_from
            b.segment_start = False
        return rows, sums

    def _fmu_sample(self, t, theta, w, e, f, new_segment) -> list:
        if new_segment or self.channel is None:
            self.fmu.start({**self.values, "crank.angle": theta, "crank.speed": w,
                            "crank.acceleration": e, "link.external_force": f}, start_time=t)
            self.channel = self.fmu.channel(["crank.angle", "crank.speed", "crank.acceleration", "link.external_force"],
                                            self.outputs)
            self._out = np.empty(len(self.outputs))
            self.rev_rows = []
            self.rev_next = None
        else:
            self.channel.advance(t)
            self.channel.set_inputs([theta, w, e, f])
        self.channel.read(self._out)
        self.rows_out += 1
        return [t, *self._out.tolist()]

    def _revolution(self, row) -> list:
        """Summary of a revolution of the model angle as soon as it is complete."""
        ia = 1 + self.outputs.index("crank.model_angle")
        ang = row[ia]
        self.rev_rows.append(row)
        if self.rev_next is None:
            self.rev_next = math.ceil(ang / TWO_PI)  # the first revolution starts there
            return []
        if ang < TWO_PI * (self.rev_next + 1):
            return []
        arr = np.array(self.rev_rows)
        series = {name: arr[:, 1 + i] for i, name in enumerate(self.outputs)}
        revs = summarize_revolutions(arr[:, 0], arr[:, ia], series,
                                     speed=series["crank.model_speed"])
        out = [self._summary_row(r) for r in revs if r.index == self.rev_next]
        # Keep the samples from just before the next revolution's start.
        start = np.searchsorted(arr[:, ia], TWO_PI * (self.rev_next + 1)) - 1
        self.rev_rows = self.rev_rows[max(0, start):]
        self.rev_next += 1
        return out

    @staticmethod
    def _summary_row(r) -> dict:
        d = {"revolution": r.index, "start_time": r.start_time, "mean_speed": r.mean_speed,
             "speed_fluctuation": r.speed_fluctuation, "friction_work": r.friction_work,
             "rod_angle_amplitude": r.rod_angle_amplitude, "stress_max": r.stress_max}
        for q, key in _EXTREMES:
            e = r.extremes.get(q)
            d[f"{key}_max"] = None if e is None else e.max
            d[f"{key}_min"] = None if e is None else e.min
        return d

    # ---- checkpoints ---------------------------------------------------------------------------

    def checkpoint(self) -> dict:
        """Everything needed to continue exactly: the FMU's serialized state and time, the
        position in the input, and the twin's buffers."""
        b = self.buf
        return {
            "version": 1,
            "machine": self.machine,
            "options": self.o.to_dict(),
            "fmu_state": base64.b64encode(self.fmu.serialize()).decode() if self.channel is not None else None,
            "fmu_time": self.fmu.time,
            "lines_read": self.lines_read,
            "rows_out": self.rows_out,
            "cols": self.cols,
            "half": self.half,
            "buf": {"t": b.t, "theta": b.theta, "speed": b.speed, "force": b.force, "line": b.line,
                    "done": b.done, "segment_start": b.segment_start},
            "last": [self.last_raw, self.last_unwrapped, self.last_t],
            "duplicates": self.duplicates,
            "gaps": self.gaps,
            "rev_rows": self.rev_rows,
            "rev_next": self.rev_next,
        }

    @classmethod
    def from_checkpoint(cls, fmu_path: str, cp: dict, extra_values: dict | None = None, batch: int = 1) -> "Twin":
        tw = cls(fmu_path, cp["machine"], Options(**cp["options"]), extra_values, batch)
        tw.lines_read, tw.rows_out, tw.cols, tw.half = cp["lines_read"], cp["rows_out"], cp["cols"], cp["half"]
        tw.buf = _Pending(**cp["buf"])
        tw.last_raw, tw.last_unwrapped, tw.last_t = cp["last"]
        tw.duplicates, tw.gaps = cp["duplicates"], [tuple(g) for g in cp["gaps"]]
        tw.rev_rows, tw.rev_next = cp["rev_rows"], cp["rev_next"]
        if cp["fmu_state"] is not None:
            tw.fmu.start(tw.values)
            tw.fmu.restore(base64.b64decode(cp["fmu_state"]), cp["fmu_time"])
            tw.channel = tw.fmu.channel(["crank.angle", "crank.speed", "crank.acceleration", "link.external_force"],
                                        tw.outputs)
            tw._out = np.empty(len(tw.outputs))
        return tw


def save_checkpoint(path, cp: dict) -> None:
    import os
    import pathlib

    p = pathlib.Path(path)
    tmp = p.with_suffix(p.suffix + ".tmp")
    tmp.write_text(json.dumps(cp))
    os.replace(tmp, p)
