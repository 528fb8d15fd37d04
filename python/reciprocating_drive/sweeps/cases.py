"""The cases of one sweep batch at the speed of the FMU's own calls (docs/sweeps.md "Speed").

`run_cases` runs the cases of a batch one after the other on a worker's loaded FMU, as `run_case`
(the reference path, below) does, with the same FMI calls in the same order and the same
arguments, but:

* what every case of a study needs is built once per worker and study (`_Prepared`): the value
  references, the typed rows of values in the order `run_case` sets them (a case writes only its
  varied parameters and the speed into its row), the FMU's functions;
* the cases of a batch are one call of the native batch driver (batch.py, tools/fmi2-batch,
  `fmi2_batch_cases`): per case fmi2Reset, fmi2SetupExperiment, fmi2EnterInitializationMode,
  the fmi2Set* of its row of values, fmi2ExitInitializationMode, and fmi2SetReal, fmi2DoStep,
  fmi2GetReal per step, no Python in between; the outputs go straight into the block's array;
* the metrics of all cases of a batch are computed together, vectorised over cases and
  revolutions (`batch_metrics`), with the arithmetic of `revolution.revolution_table` and
  `metrics_of` element for element, so every number is the same bit for bit.

Anything unusual falls back to the reference path for that one case, which then decides the row:
a case the FMU rejects (the native call stops at the call that failed; its row and message are
exactly `run_case`'s, and the next cases go on natively), and samples for which the
batched summary is not certain to hold (a non-finite value, an angle that decreases, an evaluated
revolution missing or of fewer than three samples, a non-finite metric) go through
`summarize_revolutions` and `metrics_of`, the reference summary.

Layer: workflows, the sweeps (docs/architecture.md).
"""

from __future__ import annotations

import ctypes
import math
import time
from dataclasses import dataclass

import numpy as np

from ..fmu import batch
from ..fmu.instance import FmuError
from ..revolution import TWO_PI, _degrees, _refined_peaks, summarize_revolutions
from .study import PUMP_METRICS, SPEED_PARAMETERS, Study

#: Outputs read at every step of a case.
OUTPUTS = (
    "crank.model_angle",
    "suspension.position",
    "suspension.acceleration",
    "inertia.force",
    "guide.friction",
    "link.friction_total",
    "rod.force",
    "crank.torque",
    "rod.angle",
    "rod.stress_max",
)
#: Read besides OUTPUTS when a study asks for a pump's metric (study.PUMP_METRICS).
PUMP_OUTPUTS = ("fluid_end.flow",)


def outputs_of(study: Study) -> tuple:
    """The outputs a case of `study` reads: OUTPUTS, and fluid_end.flow for a pump's metrics."""
    return OUTPUTS + (PUMP_OUTPUTS if set(study.metrics) & set(PUMP_METRICS) else ())


def _speed(study: Study, params: dict) -> float:
    if "strokes_per_minute" in params:
        return float(params["strokes_per_minute"]) * TWO_PI / 60.0
    if "crank.speed" in params:
        return float(params["crank.speed"])
    return study.crank_speed


def case_values(study: Study, params: dict, omega: float) -> dict:
    """The values a case sets in initialization mode, in the order they are set: the machine's
    (without the crank's state), the case's parameters, the crank speed."""
    values = {
        k: v
        for k, v in study.base_values.items()
        if k not in ("crank.angle", "crank.speed", "crank.acceleration")
    }
    values.update({k: v for k, v in params.items() if k not in SPEED_PARAMETERS})
    values["crank.speed"] = omega
    return values


def _check_speed(omega: float) -> None:
    if not (omega > 0 and math.isfinite(omega)):
        raise ValueError(f"crank speed = {omega} rad/s; allowed: > 0")


def run_case(fmu, study: Study, params: dict) -> tuple[dict, float]:
    """The reference path of one case, one FMU call per communication step from Python (the
    sweep runs `run_cases`, whose rows equal this path's bit for bit; the tests compare them, and
    `run_batch(..., reference=True)` runs it). Returns (metrics, seconds spent in FMU calls);
    raises the FMU's error (FmuError) for a rejected case."""
    omega = _speed(study, params)
    _check_speed(omega)
    values = case_values(study, params, omega)
    n_rev = study.skip_revolutions + study.revolutions
    n = n_rev * study.steps_per_revolution + 2
    h = TWO_PI / omega / study.steps_per_revolution
    outputs = outputs_of(study)
    rows = np.empty((n + 1, len(outputs)))
    t0 = time.perf_counter()
    fmu.start(values)
    ch = fmu.channel(["crank.angle", "crank.speed"], list(outputs))
    ch.set_inputs([0.0, omega])
    ch.read(rows[0])
    for k in range(1, n + 1):
        t = k * h
        ch.step(
            t, [omega * (t - h), omega], rows[k]
        )  # inputs at the step's start (docs/model.md §2)
    inside = time.perf_counter() - t0
    return _summary_metrics(study, np.arange(n + 1) * h, rows), inside


def _summary_metrics(study: Study, time_: np.ndarray, rows: np.ndarray) -> dict:
    """The metrics of one run's samples through summarize_revolutions (the reference). Raises
    ValueError (the case's row is an error) for a sample the FMU returned as NaN or infinite:
    summarize_revolutions would fail on it with an IndexError, which would end the batch."""
    outputs = outputs_of(study)
    bad = ~np.isfinite(rows)
    if bad.any():
        k, q = (int(x) for x in np.argwhere(bad)[0])
        raise ValueError(
            f"the FMU returned {outputs[q]} = {rows[k, q]} at t = {time_[k]:.6g} s (communication "
            f"point {k}); allowed: finite values (the case's metrics cannot be computed)"
        )
    data = {name: rows[:, i] for i, name in enumerate(outputs)}
    revs = [
        r
        for r in summarize_revolutions(time_, data["crank.model_angle"], data)
        if r.index >= study.skip_revolutions
    ][: study.revolutions]
    return metrics_of(revs, study.metrics)


def metrics_of(revs, wanted) -> dict:
    if not revs:
        raise RuntimeError("no complete evaluated revolution")

    def ext(q, key):
        vals = [getattr(r.extremes[q], key) for r in revs]
        return max(vals) if key == "max" else min(vals)

    last = revs[-1]
    all_metrics = {
        "friction_work": lambda: float(np.mean([r.friction_work for r in revs])),
        "torque_peak": lambda: max(
            abs(ext("crank.torque", "max")), abs(ext("crank.torque", "min"))
        ),
        "torque_max": lambda: ext("crank.torque", "max"),
        "torque_min": lambda: ext("crank.torque", "min"),
        "acceleration_max": lambda: ext("suspension.acceleration", "max"),
        "acceleration_max_angle": lambda: last.extremes["suspension.acceleration"].max_angle_deg,
        "acceleration_min": lambda: ext("suspension.acceleration", "min"),
        "inertia_force_max": lambda: ext("inertia.force", "max"),
        "inertia_force_min": lambda: ext("inertia.force", "min"),
        "guide_friction_max": lambda: ext("guide.friction", "max"),
        "guide_friction_min": lambda: ext("guide.friction", "min"),
        "rod_force_max": lambda: ext("rod.force", "max"),
        "rod_force_max_angle": lambda: last.extremes["rod.force"].max_angle_deg,
        "rod_force_min": lambda: ext("rod.force", "min"),
        "rod_angle_amplitude": lambda: max(r.rod_angle_amplitude for r in revs),
        "stress_max": lambda: max(r.stress_max for r in revs),
        "flow_mean": lambda: float(np.mean([r.flow_mean for r in revs])),
        "flow_pulsation": lambda: float(np.mean([r.flow_pulsation for r in revs])),
    }
    return {m: float(all_metrics[m]()) for m in wanted}


#: Samples × outputs per block of cases whose metrics are computed together (about 16 MB).
_BLOCK_VALUES = 2_000_000

_PREPARED: dict = {}


class _Prepared:
    """One worker FMU's set-up for the cases of one study, reused by every batch: the value
    references and the rows of values `run_case` sets in initialization mode (one group per type,
    in its order; a case writes only its varied parameters and the speed into its row), the
    FMU's functions and the arguments of the native call of many cases (`fmi2_batch_cases`)."""

    def __init__(self, fmu, study, outputs: tuple):
        from fmpy.fmi2 import fmi2ValueReference

        self.fmu = fmu
        # The order of run_case's values: the same dict with placeholders.
        varied = [k for k in study.varied if k not in SPEED_PARAMETERS]
        order = case_values(study, {k: 0.0 for k in varied}, 1.0)
        # fmi2Real is a double, fmi2Integer and fmi2Boolean are C ints (fmpy.fmi2).
        dtype = {"Real": np.float64, "Integer": np.intc, "Boolean": np.intc}
        groups: dict = {}
        for name in order:
            var = fmu.variables[name]
            if var.type not in dtype:
                raise TypeError(f"variables of type {var.type} are not supported")
            groups.setdefault(var.type, []).append(name)
        raw = fmu._raw
        self.groups = []  # (fmi2Set* address, vr array, base row)
        self.slots = []  # (group, column, index of the varied parameter or None: the speed)
        for g, (ty, names) in enumerate(groups.items()):
            conv = float if ty == "Real" else int
            base = np.array([conv(order[k]) for k in names], dtype=dtype[ty])
            vrs = (fmi2ValueReference * len(names))(*[fmu.vr[k] for k in names])
            self.groups.append((batch.address(raw[f"fmi2Set{ty}"]), vrs, base))
            for j, k in enumerate(names):
                if k in varied:
                    self.slots.append((g, j, study.varied.index(k)))
                elif k == "crank.speed":
                    self.slots.append((g, j, None))
        ch = fmu.channel(["crank.angle", "crank.speed"], list(outputs))
        self.vin, self.vout = ch._vin, ch._vout  # kept alive: their addresses are used
        self.n_out = len(outputs)
        self.functions = batch.CaseFunctions(
            *(batch.address(raw[f]) for f in ("fmi2Reset", "fmi2SetupExperiment")),
            *(batch.address(raw[f]) for f in ("fmi2EnterInitializationMode",
                                              "fmi2ExitInitializationMode")),
            *ch._addresses,
        )  # fmt: skip
        self.n = (study.skip_revolutions + study.revolutions) * study.steps_per_revolution + 2
        self.fail = batch.CaseFailure()
        self.work = Workspace()
        self.native = batch.library().fmi2_batch_cases

    def values(self, params: np.ndarray, omega: np.ndarray, work=None) -> ctypes.Array:
        """The groups of values of cases with parameters `params` (rows of Study.case_array)
        and speeds `omega`: each a row per case (fmi2_batch_cases's SetGroup array, valid until
        the next call with the same Workspace `work`, by default the set-up's own). An Integer
        or Boolean is its float's integer, as run_case's int()."""
        rows = []
        work = work or self.work
        for g, (_, _, base) in enumerate(self.groups):
            m = work.get(f"values{g}", (len(omega), len(base)), base.dtype)
            m[:] = base
            rows.append(m)
        for g, j, v in self.slots:
            rows[g][:, j] = omega if v is None else params[:, v]
        return (batch.SetGroup * len(rows))(
            *[
                batch.SetGroup(f, ctypes.addressof(vrs), len(vrs), m.ctypes.data, m.itemsize,
                               m.strides[0])
                for (f, vrs, _), m in zip(self.groups, rows)
            ]
        )  # fmt: skip

    def run(self, groups, first: int, count: int, omega, h, data, seconds) -> int:
        """Cases first .. first+count-1 of a block (their values rows of `groups`, speeds,
        steps) through the native driver, the outputs into data[c], the seconds of the calls into
        seconds[c]. Returns the cases completed: fewer than `count` when a call of the next
        returned fmi2Discard or worse (`self.fail` says which), for the reference path."""
        if count == 0:
            return 0
        fmu = self.fmu
        moved = [
            batch.SetGroup(g.set, g.vr, g.n, g.values + first * g.row_bytes, g.value_bytes,
                           g.row_bytes)
            for g in groups
        ]  # fmt: skip
        done = self.native(
            ctypes.byref(self.functions), fmu._component, int(fmu._started),
            (batch.SetGroup * len(moved))(*moved), len(moved),
            ctypes.addressof(self.vin), ctypes.addressof(self.vout), self.n_out,
            count, omega[first:].ctypes.data, h[first:].ctypes.data, self.n,
            data[first:].ctypes.data, data.strides[0] // 8, seconds[first:].ctypes.data,
            1, ctypes.byref(self.fail),
        )  # fmt: skip
        if done < 0:
            raise RuntimeError("fmi2_batch_cases: " + ("bad arguments" if done == -1 else "panic"))
        fmu._started = True
        if done:
            fmu.time = float(self.n * h[first + done - 1])
        return done


def _prepared(fmu, study, outputs: tuple) -> _Prepared:
    key = (id(fmu), study.content_hash, outputs)
    p = _PREPARED.get(key)
    if p is None or p.fmu is not fmu:
        _PREPARED.clear()  # one study at a time per worker
        p = _PREPARED[key] = _Prepared(fmu, study, outputs)
    return p


@dataclass
class Results:
    """The rows of a batch's cases as columns: `params` one row of the varied values per case
    (Study.case_array; the values of `study.case` exactly when `study.floats_only`), `metrics`
    one row of the study's metrics per case (NaN for a rejected case), per case its status
    ("ok" or "error"), message, seconds in FMU calls and seconds of the whole case."""

    study: object
    cases: list
    params: np.ndarray
    metrics: np.ndarray
    status: list
    message: list
    seconds_fmu: np.ndarray
    seconds_case: np.ndarray

    def params_of(self, c: int) -> dict:
        """Row c's parameters as `study.case` gives them (types included)."""
        if self.study.floats_only:
            return dict(zip(self.study.varied, self.params[c].tolist()))
        return self.study.case(self.cases[c])


def speeds(study, params: np.ndarray) -> np.ndarray:
    """The crank speed of each case (rows of Study.case_array), as _speed computes it."""
    names = study.varied
    if "strokes_per_minute" in names:
        return params[:, names.index("strokes_per_minute")] * TWO_PI / 60.0
    if "crank.speed" in names:
        return params[:, names.index("crank.speed")].copy()
    return np.full(len(params), study.crank_speed)


def run_cases(fmu, study, cases: list[int], outputs: tuple) -> Results:
    """The cases `cases` of `study` on a loaded Fmu, as run_batch's rows need them."""
    p = _prepared(fmu, study, outputs)
    n_rows, n_out = p.n + 1, len(outputs)
    block = max(1, _BLOCK_VALUES // (n_rows * n_out))
    n = len(cases)
    res = Results(
        study, list(cases), study.case_array(cases), np.full((n, len(study.metrics)), np.nan),
        ["ok"] * n, [""] * n, np.zeros(n), np.zeros(n),
    )  # fmt: skip
    clock = time.perf_counter
    for b in range(0, n, block):
        t_block = clock()
        C = min(block, n - b)
        params = res.params[b : b + C]
        data = p.work.get("data", (C, n_rows, n_out))
        omega = speeds(study, params)
        with np.errstate(all="ignore"):
            h = TWO_PI / omega / study.steps_per_revolution
        seconds = res.seconds_fmu[b : b + C]
        native = (omega > 0) & np.isfinite(omega)
        groups = p.values(params, np.where(native, omega, 1.0))
        fast = np.zeros(C, dtype=bool)
        c, spent = 0, 0.0  # spent: seconds of the reference path
        while c < C:
            if native[c]:
                # The cases up to the next one whose speed is not > 0, in one native call.
                stop = np.flatnonzero(~native[c:])
                end = c + int(stop[0]) if len(stop) else C
                done = p.run(groups, c, end - c, omega, h, data, seconds)
                fast[c : c + done] = True
                c += done
                if c == end:
                    continue
            # A call of case c failed, or its speed is not > 0: the reference path runs it and
            # makes its row (with the FMU's message); the next cases go on natively.
            t0 = clock()
            _reference_row(fmu, study, res, b + c, run_case)
            data[c, 0] = np.nan  # not for the batched metrics
            res.seconds_case[b + c] = clock() - t0
            spent += clock() - t0
            c += 1
        idx = np.flatnonzero(fast)
        if len(idx):
            values, good = batch_metrics(h, data, study, outputs, p.work)
            ok = idx[good[idx]]
            res.metrics[b + ok] = values[ok]
            res.seconds_case[b + idx] = seconds[idx]
            for c in idx[~good[idx]].tolist():
                t1 = clock()
                try:
                    m = _summary_metrics(study, np.arange(n_rows) * h[c], data[c])
                    res.metrics[b + c] = [m[k] for k in study.metrics]
                except (ValueError, RuntimeError) as e:
                    res.status[b + c], res.message[b + c] = "error", str(e)
                res.seconds_case[b + c] += clock() - t1
                spent += clock() - t1
            # The rest of the block's time (the native calls' Python side, the metrics) is
            # shared among its natively run cases.
            share = (clock() - t_block - spent - float(seconds[idx].sum())) / len(idx)
            res.seconds_case[b + idx] += share
    return res


def _reference_row(fmu, study, res: Results, c: int, run_case) -> None:
    """Row c of `res` through the reference path (run_case), as run_batch(reference=True)."""
    try:
        metrics, res.seconds_fmu[c] = run_case(fmu, study, res.params_of(c))
        res.metrics[c] = [metrics[k] for k in study.metrics]
    except (FmuError, ValueError, RuntimeError) as e:
        res.status[c], res.message[c] = "error", str(e)


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


def _interp(x: np.ndarray, t: np.ndarray, f: np.ndarray, j: np.ndarray) -> np.ndarray:
    """np.interp(x[c], t[c], f[c]) for every row c at once, with numpy's arithmetic: the value
    at a sample where x is one, else the slope of the interval times the distance from its start
    (numpy/_core/src/multiarray/compiled_base.c, arr_interp); beyond the ends the end values."""
    rows = np.arange(len(t))[:, None]
    tj, tj1, fj, fj1 = t[rows, j], t[rows, j + 1], f[rows, j], f[rows, j + 1]
    v = (fj1 - fj) / (tj1 - tj) * (x - tj) + fj
    v = np.where(x == tj, fj, v)
    v = np.where(x < t[:, :1], f[:, :1], v)
    return np.where(x >= t[:, -1:], f[:, -1:], v)


class Workspace:
    """Arrays reused from one block of cases to the next. Fresh temporaries the size of a block
    (hundreds of kB) come from the kernel as new pages each time (glibc maps and unmaps them, or
    grows and trims its heap), which costs more than the arithmetic on them."""

    def __init__(self):
        self._buffers: dict = {}

    def get(self, name: str, shape: tuple, dtype=np.float64) -> np.ndarray:
        size = math.prod(shape)
        buf = self._buffers.get(name)
        if buf is None or buf.dtype != dtype or buf.size < size:
            buf = self._buffers[name] = np.empty(size, dtype)
        return buf[:size].reshape(shape)

    def copy(self, name: str, a: np.ndarray) -> np.ndarray:
        out = self.get(name, a.shape, a.dtype)
        np.copyto(out, a)
        return out


#: The outputs each metric is computed from.
_SERIES = {
    "friction_work": ("link.friction_total", "suspension.position"),
    "torque_peak": ("crank.torque",),
    "torque_max": ("crank.torque",),
    "torque_min": ("crank.torque",),
    "acceleration_max": ("suspension.acceleration",),
    "acceleration_max_angle": ("suspension.acceleration",),
    "acceleration_min": ("suspension.acceleration",),
    "inertia_force_max": ("inertia.force",),
    "inertia_force_min": ("inertia.force",),
    "guide_friction_max": ("guide.friction",),
    "guide_friction_min": ("guide.friction",),
    "rod_force_max": ("rod.force",),
    "rod_force_max_angle": ("rod.force",),
    "rod_force_min": ("rod.force",),
    "rod_angle_amplitude": ("rod.angle",),
    "stress_max": ("rod.stress_max",),
}


def batch_metrics(
    h: np.ndarray, data: np.ndarray, study, outputs: tuple, work: Workspace | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The metrics of C runs (data[c]: run c's samples, one row per communication point at
    times k·h[c], one column per output): (values (C × metrics), good (C)). A run whose `good`
    is False must go through the reference (`_summary_metrics`); its values are
    meaningless. Every other value equals the reference's bit for bit: the operations of
    revolution.revolution_table and metrics_of on the same operands, for all runs and
    revolutions at once instead of one run at a time."""
    if set(study.metrics) & set(PUMP_METRICS):
        # A pump's flow metrics have no batched form: every run goes through the reference.
        return np.full((data.shape[0], len(study.metrics)), np.nan), np.zeros(data.shape[0], bool)
    with np.errstate(all="ignore"):
        return _batch_metrics(h, data, study, outputs, work or Workspace())


def _batch_metrics(h, data, study, outputs, w: Workspace):
    C, N, _ = data.shape
    col = {name: i for i, name in enumerate(outputs)}
    skip, R = study.skip_revolutions, study.revolutions
    values = np.full((C, len(study.metrics)), np.nan)
    # Each needed output as a contiguous (C × N) array, copied a few runs at a time: the runs'
    # rows of all outputs stay in the cache while their columns are taken out.
    need = ["crank.model_angle", *{q: 0 for m in study.metrics for q in _SERIES[m]}]
    cache = {q: w.get(q, (C, N)) for q in need}
    total = np.empty(C)
    for a in range(0, C, 16):
        part = data[a : a + 16]
        for q in need:
            np.copyto(cache[q][a : a + 16], part[:, :, col[q]])
        # Every output, also those no metric reads: the reference refuses a run with a NaN or an
        # infinity in any (_summary_metrics). A sum is finite only if every term is (an
        # overflow sends a run to the reference too).
        np.sum(part, axis=(1, 2), out=total[a : a + 16])
    good = np.isfinite(total) & np.isfinite(h) & (N >= 3)
    th = cache["crank.model_angle"]
    good &= ~np.less(th[:, 1:], th[:, :-1], out=w.get("less", (C, N - 1), bool)).any(axis=1)
    k0 = np.ceil(th[:, 0] / TWO_PI - 1e-12)
    ks = np.arange(skip, skip + R)
    lo, hi = TWO_PI * ks.astype(float), TWO_PI * (ks + 1).astype(float)
    # Revolutions skip .. skip+R-1 are among revolution_table's (k0 <= skip, the last complete).
    good &= (k0 <= skip) & (hi[-1] <= th[:, -1])
    if not good.any():
        return values, good
    # np.arange(n + 1) * h of each run
    t = np.multiply(np.arange(N), h[:, None], out=w.get("t", (C, N)))
    rows = np.arange(C)[:, None]
    flags = w.get("flags", (C, N), bool)

    def count(compare, a, x):
        """Per run and column r of x: how many of a[c] compare true with x[c, r]."""
        return np.stack(
            [np.count_nonzero(compare(a, x[:, r : r + 1], out=flags), axis=1) for r in range(R)],
            axis=1,
        )

    def crossing(target):
        """_crossing_times: the first sample j with θ_j ≥ target, the interpolated time."""
        x = np.broadcast_to(target, (C, R))
        j = np.minimum(count(np.less, th, x), N - 1)  # searchsorted(side="left")
        jm = np.maximum(j - 1, 0)
        t0, t1, a0, a1 = t[rows, jm], t[rows, j], th[rows, jm], th[rows, j]
        return j, np.where(a1 != a0, t0 + (t1 - t0) * (target - a0) / (a1 - a0), t1)

    inside = th[:, :1] < lo[None, :]
    if inside.any():
        ja, ta = crossing(lo)
        ja, ta = np.where(inside, ja, 0), np.where(inside, ta, t[:, :1])
    else:  # every evaluated revolution starts at the first sample (a rigid study, skip 0)
        ja, ta = np.zeros((C, R), dtype=np.intp), np.repeat(t[:, :1], R, axis=1)
    jb, tb = crossing(hi)
    good &= (jb - ja >= 3).all(axis=1)
    if not good.any():
        return values, good
    # The samples every evaluated revolution of a good run lies in: columns w0 .. w1-1 (w1-1 is
    # the sample after the last, which the friction work's last trapezoid reads).
    w0, w1 = int(ja[good].min()), int(jb[good].max()) + 1
    W = w1 - w0
    cols = np.arange(w0, w1)
    masks = []
    for r in range(R):
        if (ja[good, r] == w0).all() and (jb[good, r] == w1 - 1).all():
            masks.append(None)  # revolution r is columns w0 .. w1-2 of every good run
            continue
        m = np.greater_equal(cols, ja[:, r : r + 1], out=w.get(f"mask{r}", (C, W), bool))
        masks.append(np.logical_and(m, np.less(cols, jb[:, r : r + 1], out=flags[:, :W]), out=m))
    TH = th.ravel()

    def series(name):
        return cache[name]

    def masked(yw, m, fill, contiguous=False):
        """yw where m, else fill (m None: the columns of a revolution that fills the window,
        copied to a contiguous array if `contiguous`)."""
        if m is None:
            if not contiguous:
                return yw[:, : W - 1]
            # np.argmax/argmin along a strided axis would copy the rows into a fresh array of
            # their own, of megabytes: memory that a Dask worker's malloc returns to the system
            # at once (its MALLOC_TRIM_THRESHOLD_ of 64 kB), every block's page faults again.
            out = w.get("window", (C, W - 1))
            np.copyto(out, yw[:, : W - 1])
            return out
        out = w.get("masked", (C, W))
        out.fill(fill)
        np.copyto(out, yw, where=m)
        return out

    extremes: dict = {}

    def ext_of(q, key):
        """The largest (key "max") or smallest value of q in each evaluated revolution and its
        angle in degrees, (C × R) each: the first sample of the extreme, as np.argmax/argmin
        choose it (revolution_table's first_where), refined by its parabola."""
        if (q, key) not in extremes:
            y = series(q)
            yw = y[:, w0:w1]
            fill, pick = (-np.inf, np.argmax) if key == "max" else (np.inf, np.argmin)
            j = np.stack([w0 + pick(masked(yw, m, fill, True), axis=1) for m in masks], axis=1)
            i = rows * N + j
            v, a = _refined_peaks(TH, y.ravel(), i, (j > 0) & (j < N - 1))
            extremes[q, key] = v, _degrees(a)
        return extremes[q, key]

    def seg_max(y):
        yw = y[:, w0:w1]
        return np.stack([masked(yw, m, -np.inf).max(axis=1) for m in masks], axis=1)

    def friction_work():
        f, x = series("link.friction_total"), series("suspension.position")
        ia = np.clip(count(np.less_equal, t, ta) - 1, 0, N - 2)  # np.interp's interval
        ib = np.clip(count(np.less_equal, t, tb) - 1, 0, N - 2)
        fa, fb, xa, xb = _interp(ta, t, f, ia), _interp(tb, t, f, ib), _interp(ta, t, x, ia), \
            _interp(tb, t, x, ib)  # fmt: skip
        # The trapezoids over [t_a, t_b] (revolution_table): from t_a to the first sample, between
        # the samples, from the last sample before t_b to t_b. Inner: 0.5 * (f1 + f0) * (x1 - x0).
        inner = np.add(f[:, w0 + 1 : w1], f[:, w0 : w1 - 1], out=w.get("inner", (C, W - 1)))
        np.multiply(0.5, inner, out=inner)
        dx = np.subtract(x[:, w0 + 1 : w1], x[:, w0 : w1 - 1], out=w.get("dx", (C, W - 1)))
        np.multiply(inner, dx, out=inner)
        first = 0.5 * (f[rows, ja] + fa) * (x[rows, ja] - xa)
        last = 0.5 * (fb + f[rows, jb - 1]) * (xb - x[rows, jb - 1])
        n = jb - ja
        work = np.full((C, R), np.nan)
        # Each revolution's sum by numpy's pairwise sum, row by row: a row of a 2-D reduce
        # along its last axis is summed exactly as np.add.reduce of the same numbers alone.
        # Revolutions of the same length and first sample are summed together (in a rigid
        # study at one speed, all of them).
        use = good[:, None] & (n >= 1)
        for length, start in set(zip(n[use].tolist(), ja[use].tolist())):
            c, r = np.nonzero(use & (n == length) & (ja == start))
            terms = w.get("terms", (len(c), length + 1))
            terms[:, 0], terms[:, length] = first[c, r], last[c, r]
            span = slice(start - w0, start - w0 + length - 1)
            if c[-1] - c[0] + 1 == len(c):  # consecutive runs: a slice, not a fresh copy
                terms[:, 1:length] = inner[c[0] : c[-1] + 1, span]
            else:
                terms[:, 1:length] = inner[c, span]
            work[c, r] = np.add.reduce(terms, axis=1)
        return np.mean(work, axis=1)

    def ext(q, key):
        v = ext_of(q, key)[0]
        return _first_max(v) if key == "max" else _first_min(v)

    all_metrics = {
        "friction_work": friction_work,
        "torque_peak": lambda: _first_max(
            np.stack([np.abs(ext("crank.torque", "max")), np.abs(ext("crank.torque", "min"))], 1)
        ),
        "torque_max": lambda: ext("crank.torque", "max"),
        "torque_min": lambda: ext("crank.torque", "min"),
        "acceleration_max": lambda: ext("suspension.acceleration", "max"),
        "acceleration_max_angle": lambda: ext_of("suspension.acceleration", "max")[1][:, -1],
        "acceleration_min": lambda: ext("suspension.acceleration", "min"),
        "inertia_force_max": lambda: ext("inertia.force", "max"),
        "inertia_force_min": lambda: ext("inertia.force", "min"),
        "guide_friction_max": lambda: ext("guide.friction", "max"),
        "guide_friction_min": lambda: ext("guide.friction", "min"),
        "rod_force_max": lambda: ext("rod.force", "max"),
        "rod_force_max_angle": lambda: ext_of("rod.force", "max")[1][:, -1],
        "rod_force_min": lambda: ext("rod.force", "min"),
        "rod_angle_amplitude": lambda: _first_max(
            seg_max(np.abs(series("rod.angle"), out=w.get("abs", (C, N))))
        ),
        "stress_max": lambda: _first_max(seg_max(series("rod.stress_max"))),
    }
    for m, name in enumerate(study.metrics):
        values[:, m] = all_metrics[name]()
    good &= np.isfinite(values).all(axis=1)
    return values, good
