"""The cases of one sweep batch at the speed of the FMU's own calls (docs/sweeps.md "Speed").

`run_cases` runs the cases of a batch one after the other on a worker's loaded FMU, as
`sweep.run_case` does, with the same FMI calls in the same order and the same arguments, but:

* what every case of a study needs is built once per worker and study (`_Prepared`): the value
  references, the typed value arrays in the order `run_case` sets them (a case writes only its
  varied parameters and the speed into them), the channel's arrays and the call's arguments;
* the communication steps of a case are one call of the native batch driver (batch.py,
  tools/fmi2-batch: fmi2SetReal, fmi2DoStep, fmi2GetReal per step, no Python in between);
* the metrics of all cases of a batch are computed together, vectorised over cases and
  revolutions (`batch_metrics`), with the arithmetic of `revolution.revolution_table` and
  `sweep.metrics_of` element for element, so every number is the same bit for bit.

Anything unusual falls back to the reference path for that one case, which then decides the row:
a case the FMU rejects (its row and message are exactly `run_case`'s), and samples for which the
batched summary is not certain to hold (a non-finite value, an angle that decreases, an evaluated
revolution missing or of fewer than three samples, a non-finite metric) go through
`summarize_revolutions` and `metrics_of` as before.
"""

from __future__ import annotations

import ctypes
import math
import time

import numpy as np

from . import batch
from .fmu import FmuError
from .revolution import TWO_PI, _degrees, _refined_peaks

#: Samples × outputs per block of cases whose metrics are computed together (about 16 MB).
_BLOCK_VALUES = 2_000_000

_PREPARED: dict = {}

_VP, _INT, _SZ = ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t
# fmi2SetReal/fmi2GetReal(component, vr[], n, value[]) called with plain addresses: fmpy's
# prototypes would build a ctypes pointer object per call.
_RW = ctypes.CFUNCTYPE(_INT, _VP, _VP, _SZ, _VP)


class _Prepared:
    """One worker FMU's set-up for the cases of one study, reused by every case."""

    def __init__(self, fmu, study, outputs: tuple):
        from fmpy.fmi2 import fmi2Boolean, fmi2Integer, fmi2Real, fmi2ValueReference

        from .sweep import SPEED_PARAMETERS, case_values

        self.fmu = fmu
        # The order of run_case's values: the same dict with placeholders.
        varied = [k for k in study.varied if k not in SPEED_PARAMETERS]
        order = case_values(study, {k: 0.0 for k in varied}, 1.0)
        ctype = {"Real": fmi2Real, "Integer": fmi2Integer, "Boolean": fmi2Boolean}
        groups: dict = {}
        for name in order:
            var = fmu.variables[name]
            if var.type not in ctype:
                raise TypeError(f"variables of type {var.type} are not supported")
            groups.setdefault(var.type, []).append(name)
        self.sets = []  # (function name, raw function, vr array, n, value array)
        self.slots = []  # (name, value array, index, conversion) written per case
        for ty, names in groups.items():
            conv = float if ty == "Real" else int
            # Placeholders of the varied values and the speed: every case writes its own.
            vals = (ctype[ty] * len(names))(*[conv(order[k]) for k in names])
            vrs = (fmi2ValueReference * len(names))(*[fmu.vr[k] for k in names])
            self.sets.append((f"fmi2Set{ty}", fmu._raw[f"fmi2Set{ty}"], vrs, len(names), vals))
            for j, k in enumerate(names):
                if k in varied or k == "crank.speed":
                    self.slots.append((k, vals, j, conv))
        raw = fmu._raw
        self.reset, self.setup = raw["fmi2Reset"], raw["fmi2SetupExperiment"]
        self.enter = raw["fmi2EnterInitializationMode"]
        self.leave = raw["fmi2ExitInitializationMode"]
        ch = fmu.channel(["crank.angle", "crank.speed"], list(outputs))
        self.vin, self.vout = ch._vin, ch._vout
        self.n_out = len(outputs)
        self.addresses = ch._addresses
        self.set_real = _RW(self.addresses[0])
        self.get_real = _RW(self.addresses[2])
        self.x0 = np.zeros(2)
        self.n = (study.skip_revolutions + study.revolutions) * study.steps_per_revolution + 2
        self.k = np.arange(1, self.n + 1)
        self.t = np.empty(self.n)
        self.xin = np.empty((self.n, 2))
        self.fail = batch.Failure()
        self.run_native = batch.library().fmi2_batch_run

    def _call(self, name: str, function, *args) -> None:
        """An FMI call checked as Fmu._call checks it (the FMU's messages of that call)."""
        log = self.fmu._log
        mark = len(log.lines)
        status = function(self.fmu._component, *args)
        if status > 1:
            raise FmuError(name, status, log.since(mark))

    def run(self, params: dict, omega: float, h: float, out: np.ndarray) -> None:
        """One case: Fmu.start's calls with the case's values, then the channel's first
        fmi2SetReal/fmi2GetReal and every step through the native driver, into `out` (n+1 rows)."""
        fmu, c = self.fmu, self.fmu._component
        for name, vals, j, conv in self.slots:
            vals[j] = conv(omega if name == "crank.speed" else params[name])
        if fmu._started:
            self._call("fmi2Reset", self.reset)
        fmu._started = True
        self._call("fmi2SetupExperiment", self.setup, 0, 0.0, 0.0, 0, 0.0)
        self._call("fmi2EnterInitializationMode", self.enter)
        for name, function, vrs, k, vals in self.sets:
            self._call(name, function, vrs, k, vals)
        self._call("fmi2ExitInitializationMode", self.leave)
        fmu.time = 0.0
        # The inputs of step k are the crank's state at the step's start (docs/model.md §2), the
        # same numbers as run_case's omega * (k*h - h).
        t, xin = self.t, self.xin
        np.multiply(self.k, h, out=t)
        np.subtract(t, h, out=xin[:, 0])
        np.multiply(xin[:, 0], omega, out=xin[:, 0])
        xin[:, 1] = omega
        self.x0[1] = omega
        addr = ctypes.addressof
        self._call("fmi2SetReal", self.set_real, addr(self.vin), 2, self.x0.ctypes.data)
        self._call("fmi2GetReal", self.get_real, addr(self.vout), self.n_out, out.ctypes.data)
        done = self.run_native(
            *self.addresses, c, addr(self.vin), 2, addr(self.vout), self.n_out, 0.0, self.n,
            t.ctypes.data, xin.ctypes.data, 2, out.ctypes.data + 8 * self.n_out, self.n_out,
            batch.ORDER_SET_STEP_GET, 1, ctypes.byref(self.fail),
        )  # fmt: skip
        if done != self.n:
            # The reference path runs the case again and makes its row and message.
            raise FmuError(batch.FUNCTIONS.get(self.fail.function, "?"), self.fail.status, [])
        fmu.time = float(t[-1])


def _prepared(fmu, study, outputs: tuple) -> _Prepared:
    key = (id(fmu), study.content_hash, outputs)
    p = _PREPARED.get(key)
    if p is None or p.fmu is not fmu:
        _PREPARED.clear()  # one study at a time per worker
        p = _PREPARED[key] = _Prepared(fmu, study, outputs)
    return p


def run_cases(fmu, study, cases: list[int], outputs: tuple) -> list[tuple]:
    """The cases `cases` of `study` on a loaded Fmu: per case (params, metrics, status, message,
    seconds in FMU calls, seconds of the case), as run_batch's rows need them."""
    from .sweep import _speed, _summary_metrics, run_case

    p = _prepared(fmu, study, outputs)
    n_rows = p.n + 1
    block = max(1, _BLOCK_VALUES // (n_rows * len(outputs)))
    out = []
    for b in range(0, len(cases), block):
        ids = cases[b : b + block]
        data = np.empty((len(ids), n_rows, len(outputs)))
        hs = np.ones(len(ids))
        rows: list = [None] * len(ids)
        fast = []
        for c, i in enumerate(ids):
            t0 = time.perf_counter()
            params = study.case(i)
            t1 = time.perf_counter()
            try:
                omega = _speed(study, params)
                if not (omega > 0 and math.isfinite(omega)):
                    raise ValueError
                h = TWO_PI / omega / study.steps_per_revolution
                p.run(params, omega, h, data[c])
                hs[c] = h
                t2 = time.perf_counter()
                rows[c] = [params, None, "ok", "", t2 - t1, t2 - t0]
                fast.append(c)
            except (FmuError, ValueError, RuntimeError, ArithmeticError):
                rows[c] = _reference_row(fmu, study, params, run_case, t0)
        if fast:
            t0 = time.perf_counter()
            sel = np.asarray(fast)
            values, good = batch_metrics(hs[sel], data[sel], study, outputs)
            share = (time.perf_counter() - t0) / len(fast)
            for j, c in enumerate(fast):
                r = rows[c]
                if good[j]:
                    r[1] = dict(zip(study.metrics, values[j].tolist()))
                else:
                    t1 = time.perf_counter()
                    time_ = np.arange(n_rows) * hs[c]
                    try:
                        r[1] = _summary_metrics(study, time_, data[c])
                    except (ValueError, RuntimeError) as e:
                        r[1] = {m: math.nan for m in study.metrics}
                        r[2], r[3] = "error", str(e)
                    r[5] += time.perf_counter() - t1
                r[5] += share
        out += [(ids[c], *rows[c]) for c in range(len(ids))]
    return out


def _reference_row(fmu, study, params, run_case, t0: float) -> list:
    """run_batch's row of one case through the reference path (run_case)."""
    status, message = "ok", ""
    metrics, inside = {}, 0.0
    try:
        metrics, inside = run_case(fmu, study, params)
    except (FmuError, ValueError, RuntimeError) as e:
        status, message = "error", str(e)
        metrics = {m: math.nan for m in study.metrics}
    return [params, metrics, status, message, inside, time.perf_counter() - t0]


def _first_max(v: np.ndarray) -> np.ndarray:
    """Python's max over the columns of each row (the first of equal values kept)."""
    m = v[:, 0]
    for r in range(1, v.shape[1]):
        m = np.where(v[:, r] > m, v[:, r], m)
    return m


def _first_min(v: np.ndarray) -> np.ndarray:
    m = v[:, 0]
    for r in range(1, v.shape[1]):
        m = np.where(v[:, r] < m, v[:, r], m)
    return m


def _interp(x: np.ndarray, t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """np.interp(x[c], t[c], f[c]) for every row c at once, with numpy's arithmetic: the value at
    a sample where x is one, else the slope of the interval times the distance from its start
    (numpy/_core/src/multiarray/compiled_base.c, arr_interp); values beyond the ends are the end
    values. t increases strictly along each row."""
    rows = np.arange(len(t))[:, None]
    last = t.shape[1] - 1
    j = np.minimum((t[:, :, None] <= x[:, None, :]).sum(axis=1) - 1, last - 1)
    j = np.maximum(j, 0)
    tj, tj1, fj, fj1 = t[rows, j], t[rows, j + 1], f[rows, j], f[rows, j + 1]
    with np.errstate(all="ignore"):
        v = (fj1 - fj) / (tj1 - tj) * (x - tj) + fj
    v = np.where(x == tj, fj, v)
    v = np.where(x < t[:, :1], f[:, :1], v)
    return np.where(x >= t[:, -1:], f[:, -1:], v)


def batch_metrics(
    h: np.ndarray, data: np.ndarray, study, outputs: tuple
) -> tuple[np.ndarray, np.ndarray]:
    """The metrics of C runs (data[c]: run c's samples, one row per communication point at
    times k·h[c], one column per output): (values (C × metrics), good (C)). A run whose `good`
    is False must go through the reference (`sweep._summary_metrics`); its values are
    meaningless. Every other value equals the reference's bit for bit: the operations of
    revolution.revolution_table and sweep.metrics_of on the same operands, gathered over all
    runs and revolutions instead of one run at a time."""
    C, N, _ = data.shape
    col = {name: i for i, name in enumerate(outputs)}
    skip, R = study.skip_revolutions, study.revolutions
    th_all = data[:, :, col["crank.model_angle"]]
    good = np.isfinite(data).all(axis=(1, 2)) & np.isfinite(h) & (N >= 3)
    good &= ~(np.diff(th_all, axis=1) < 0).any(axis=1)
    with np.errstate(all="ignore"):
        k0 = np.ceil(th_all[:, 0] / TWO_PI - 1e-12)
    ks = np.arange(skip, skip + R)
    lo, hi = TWO_PI * ks.astype(float), TWO_PI * (ks + 1).astype(float)
    # Revolutions skip .. skip+R-1 are among revolution_table's (k0 <= skip, the last complete).
    good &= (k0 <= skip) & (hi[-1] <= th_all[:, -1])
    values = np.full((C, len(study.metrics)), np.nan)
    F = np.flatnonzero(good)
    if len(F) == 0:
        return values, good
    th = np.ascontiguousarray(th_all[F])
    t = np.arange(N) * h[F][:, None]  # np.arange(n + 1) * h of each run
    Cf, rows = len(F), np.arange(len(F))[:, None]

    def crossing(target):
        """_crossing_times: the first sample j with θ_j ≥ target, the interpolated time."""
        j = (th[:, :, None] < target[None, None, :]).sum(axis=1)  # searchsorted(side="left")
        jm = np.maximum(j - 1, 0)
        jj = np.minimum(j, N - 1)
        t0, t1, a0, a1 = t[rows, jm], t[rows, jj], th[rows, jm], th[rows, jj]
        with np.errstate(all="ignore"):
            return j, np.where(a1 != a0, t0 + (t1 - t0) * (target - a0) / (a1 - a0), t1)

    inside = th[:, :1] < lo[None, :]
    ja, ta = crossing(lo)
    ja, ta = np.where(inside, ja, 0), np.where(inside, ta, t[:, :1])
    jb, tb = crossing(hi)
    ok3 = (jb - ja >= 3).all(axis=1)
    # The samples of every revolution (run-major), flat over the runs' samples one after the
    # other: revolution r owns flat[off[r]:off[r] + n[r]] (as in revolution_table).
    ga, gb = (ja + rows * N).ravel(), (jb + rows * N).ravel()
    n = np.maximum(gb - ga, 1)
    off = np.cumsum(n) - n
    flat = np.repeat(ga - off, n) + np.arange(n.sum())
    pos = np.arange(len(flat))
    TH = th.ravel()

    def inner_of(i):
        """Samples with both neighbours in their own run."""
        return (i % N > 0) & (i % N < N - 1)

    def seg_max(y):
        return np.maximum.reduceat(y[flat], off)

    def seg_min(y):
        return np.minimum.reduceat(y[flat], off)

    def first_where(y, value):
        return flat[
            np.minimum.reduceat(np.where(y[flat] == np.repeat(value, n), pos, len(pos)), off)
        ]

    def series(name):
        return np.ascontiguousarray(data[F, :, col[name]]).ravel()

    per_rev: dict = {}

    def extremes(q):
        if q not in per_rev:
            y = series(q)
            imax, imin = first_where(y, seg_max(y)), first_where(y, seg_min(y))
            vmax, amax = _refined_peaks(TH, y, imax, inner_of(imax))
            vmin, amin = _refined_peaks(TH, y, imin, inner_of(imin))
            per_rev[q] = [a.reshape(Cf, R) for a in (vmax, _degrees(amax), vmin, _degrees(amin))]
        return per_rev[q]

    def friction_work():
        f, x = series("link.friction_total"), series("suspension.position")
        f2, x2 = f.reshape(Cf, N), x.reshape(Cf, N)
        fa, fb = _interp(ta, t, f2).ravel(), _interp(tb, t, f2).ravel()
        xa, xb = _interp(ta, t, x2).ravel(), _interp(tb, t, x2).ravel()
        toff = off + np.arange(len(n))
        terms = np.empty(len(flat) + len(n))
        seg = np.repeat(np.arange(len(n)), n)
        terms[toff[seg] + 1 + pos - off[seg]] = (
            0.5 * (f[flat + 1] + f[flat]) * (x[flat + 1] - x[flat])
        )
        terms[toff] = 0.5 * (f[ga] + fa) * (x[ga] - xa)
        terms[toff + n] = 0.5 * (fb + f[gb - 1]) * (xb - x[gb - 1])
        # Each revolution's sum by numpy's pairwise sum, row by row: a row of a 2-D reduce along
        # its last axis is summed exactly as np.add.reduce of the same numbers alone.
        work = np.empty(len(n))
        for length in np.unique(n):
            which = np.flatnonzero(n == length)
            work[which] = np.add.reduce(terms[toff[which][:, None] + np.arange(length + 1)], 1)
        return np.mean(work.reshape(Cf, R), axis=1)

    def ext(q, key):
        vmax, _, vmin, _ = extremes(q)
        return _first_max(vmax) if key == "max" else _first_min(vmin)

    def last_angle(q):
        return extremes(q)[1][:, -1]

    all_metrics = {
        "friction_work": friction_work,
        "torque_peak": lambda: _first_max(
            np.stack([np.abs(ext("crank.torque", "max")), np.abs(ext("crank.torque", "min"))], 1)
        ),
        "torque_max": lambda: ext("crank.torque", "max"),
        "torque_min": lambda: ext("crank.torque", "min"),
        "acceleration_max": lambda: ext("suspension.acceleration", "max"),
        "acceleration_max_angle": lambda: last_angle("suspension.acceleration"),
        "acceleration_min": lambda: ext("suspension.acceleration", "min"),
        "inertia_force_max": lambda: ext("inertia.force", "max"),
        "inertia_force_min": lambda: ext("inertia.force", "min"),
        "guide_friction_max": lambda: ext("guide.friction", "max"),
        "guide_friction_min": lambda: ext("guide.friction", "min"),
        "rod_force_max": lambda: ext("rod.force", "max"),
        "rod_force_max_angle": lambda: last_angle("rod.force"),
        "rod_force_min": lambda: ext("rod.force", "min"),
        "rod_angle_amplitude": lambda: _first_max(
            seg_max(np.abs(series("rod.angle"))).reshape(Cf, R)
        ),
        "stress_max": lambda: _first_max(seg_max(series("rod.stress_max")).reshape(Cf, R)),
    }
    for m, name in enumerate(study.metrics):
        values[F, m] = all_metrics[name]()
    good[F] &= ok3 & np.isfinite(values[F]).all(axis=1)
    return values, good
