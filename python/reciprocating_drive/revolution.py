"""Per-revolution summaries of a run: the numbers the main job, the digital twin and the design
sweeps report for each complete crank revolution.

A revolution k is the interval in which the model angle θ (the angle the FMU's outputs belong
to, after the angle offset; continuous, not wrapped) runs from 2πk to 2π(k+1); its start and end
times are interpolated linearly between the samples. Only complete revolutions are summarised.
For each quantity the largest and smallest value are reported with the crank angle (degrees in
[0, 360)) where they occur; a sampled extreme is refined by the parabola through it and its two
neighbours (exact for a quadratic peak, so the error falls with the cube of the sample spacing
instead of its square). Friction work is ∫ F_fr ds over the revolution (link.friction_total along
suspension.position; trapezoidal rule), negative because friction dissipates energy.

Layer: shared, below the FMU access (docs/architecture.md).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

TWO_PI = 2.0 * math.pi

#: Quantities whose extremes every summary reports (docs/model.md §10 names).
DEFAULT_QUANTITIES = (
    "suspension.acceleration",
    "inertia.force",
    "guide.friction",
    "rod.force",
    "crank.torque",
)

#: The per-revolution numbers of a pump (from fluid_end.flow, fluid_end.hydraulic_power and
#: crank.mechanical_power; docs/results.md "Pump presets").
PUMP_COLUMNS = ("flow_mean", "flow_pulsation", "hydraulic_power_mean", "mechanical_power_mean")


@dataclass
class Extreme:
    max: float
    max_angle_deg: float
    min: float
    min_angle_deg: float


@dataclass
class RevolutionSummary:
    index: int
    start_time: float
    duration: float
    #: 2π / duration [rad/s]
    mean_speed: float
    #: (ω_max − ω_min) / ω_mean over the revolution, from the speed series when one is given
    speed_fluctuation: float | None
    extremes: dict[str, Extreme] = field(default_factory=dict)
    #: ∫ F_fr ds over the revolution [J]
    friction_work: float | None = None
    #: max |ϑ| of an elastic rod [rad]
    rod_angle_amplitude: float | None = None
    #: largest rod stress [Pa]
    stress_max: float | None = None
    #: a pump's mean flow [m³/s], (Q_max − Q_min)/Q_mean, mean hydraulic and mechanical power [W]
    flow_mean: float | None = None
    flow_pulsation: float | None = None
    hydraulic_power_mean: float | None = None
    mechanical_power_mean: float | None = None

    def as_row(self) -> dict:
        """A flat dict (CSV/Parquet row): extremes as '<name>.max', '<name>.max_angle_deg', …"""
        row = {
            "revolution": self.index,
            "start_time": self.start_time,
            "duration": self.duration,
            "mean_speed": self.mean_speed,
            "speed_fluctuation": self.speed_fluctuation,
        }
        for name, e in self.extremes.items():
            row[f"{name}.max"] = e.max
            row[f"{name}.max_angle_deg"] = e.max_angle_deg
            row[f"{name}.min"] = e.min
            row[f"{name}.min_angle_deg"] = e.min_angle_deg
        row["friction_work"] = self.friction_work
        row["rod_angle_amplitude"] = self.rod_angle_amplitude
        row["stress_max"] = self.stress_max
        if self.flow_mean is not None:  # a pump's run (fluid_end.flow recorded)
            for name in PUMP_COLUMNS:
                row[name] = getattr(self, name)
        return row


def _refined_peaks(
    theta: np.ndarray, y: np.ndarray, i: np.ndarray, inner: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(values, angles) of the extremes at samples i, each refined by the parabola through i-1, i,
    i+1 when it has both neighbours and its vertex lies between them (else the sample itself).
    `inner`: which samples have both neighbours, when theta and y hold several runs one after
    the other (the sweep's batches); by default every sample but the first and the last."""
    if inner is None:
        inner = (i > 0) & (i < len(y) - 1)
    im, ip = np.where(inner, i - 1, i), np.where(inner, i + 1, i)
    x0, x1, x2 = theta[im], theta[i], theta[ip]
    y0, y1, y2 = y[im], y[i], y[ip]
    with np.errstate(all="ignore"):
        d01, d12 = (y1 - y0) / (x1 - x0), (y2 - y1) / (x2 - x1)
        a = (d12 - d01) / (x2 - x0)
        xv = 0.5 * (x0 + x1) - d01 / (2.0 * a)
        use = inner & (a != 0.0) & (x0 <= xv) & (xv <= x2)
        value = np.where(use, y1 + d01 * (xv - x1) + a * (xv - x0) * (xv - x1), y1)
    return value, np.where(use, xv, x1)


def _degrees(a: np.ndarray) -> np.ndarray:
    """Angles [rad] as degrees in [0, 360)."""
    return np.mod(np.degrees(np.mod(a, TWO_PI)), 360.0)


def _crossing_times(
    t: np.ndarray, theta: np.ndarray, target: np.ndarray, reached: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """For each target (inside theta's range): the first sample index j with θ_j ≥ target and the
    interpolated time of θ = target. `reached`: the running maximum of theta (theta itself when
    it never decreases), so θ_(j-1) < target ≤ θ_j whichever way the crank turned before."""
    j = np.searchsorted(theta if reached is None else reached, target, side="left")
    t0, t1, a0, a1 = t[j - 1], t[j], theta[j - 1], theta[j]
    with np.errstate(all="ignore"):
        return j, np.where(a1 != a0, t0 + (t1 - t0) * (target - a0) / (a1 - a0), t1)


def summarize_revolutions(
    time: Sequence[float],
    angle: Sequence[float],
    series: Mapping[str, Sequence[float]],
    speed: Sequence[float] | None = None,
    quantities: Sequence[str] = DEFAULT_QUANTITIES,
) -> list[RevolutionSummary]:
    """Summaries of every complete revolution. `angle` is the model angle [rad], continuous
    (unwrapped; it may stand still or turn back, see `revolution_table`); `series` maps output
    names to sampled values (quantities missing from it are skipped; link.friction_total with
    suspension.position gives the friction work, rod.angle the ϑ amplitude, rod.stress_max the
    largest stress). The numbers are those of `revolution_table`, one object per revolution."""
    tab = {
        k: v.tolist() for k, v in revolution_table(time, angle, series, speed, quantities).items()
    }
    out = []
    for i, k in enumerate(tab["revolution"]):
        s = RevolutionSummary(
            index=k,
            start_time=tab["start_time"][i],
            duration=tab["duration"][i],
            mean_speed=tab["mean_speed"][i],
            speed_fluctuation=None,
        )
        if "speed_fluctuation" in tab:
            s.speed_fluctuation = tab["speed_fluctuation"][i]
        for q in quantities:
            if f"{q}.max" in tab:
                s.extremes[q] = Extreme(
                    tab[f"{q}.max"][i],
                    tab[f"{q}.max_angle_deg"][i],
                    tab[f"{q}.min"][i],
                    tab[f"{q}.min_angle_deg"][i],
                )
        for name in ("friction_work", "rod_angle_amplitude", "stress_max", *PUMP_COLUMNS):
            if name in tab:
                setattr(s, name, tab[name][i])
        out.append(s)
    return out


def revolution_table(
    time: Sequence[float],
    angle: Sequence[float],
    series: Mapping[str, Sequence[float]],
    speed: Sequence[float] | None = None,
    quantities: Sequence[str] = DEFAULT_QUANTITIES,
    stop_speed: float | None = None,
) -> dict[str, np.ndarray]:
    """`summarize_revolutions` as columns, one element per complete revolution: 'revolution'
    (int), 'start_time', 'duration', 'mean_speed', and where their inputs are given
    'speed_fluctuation', '<q>.max', '<q>.max_angle_deg', '<q>.min', '<q>.min_angle_deg' for
    each quantity q, 'friction_work', 'stroke', 'rod_angle_amplitude', 'stress_max'. No Python object per
    revolution: the digital twin summarises some 25 revolutions a second this way.

    Vectorised over the revolutions: a revolution's numbers depend only on its own samples and
    their two neighbours, so they are the same whichever other revolutions share the call.

    The angle may stand still and turn back (a pump that stops and rocks back, a crank jogged
    backwards; docs/twin.md "Machine states"): revolution k runs from the first sample at which
    the angle reaches 2πk to the first at which it reaches 2π(k+1), i.e. it is bounded by the
    running maximum of the angle, so only complete forward revolutions are summarised and every
    sample in between, forwards or backwards, belongs to one. 'samples' counts a revolution's
    samples; with `speed` and `stop_speed` [rad/s], 'interrupted' is 1 for a revolution in which
    the speed fell below `stop_speed` (a stop or a reversal fell inside it), else 0."""
    t = np.asarray(time, dtype=float)
    th = np.asarray(angle, dtype=float)
    none = {
        "revolution": np.empty(0, dtype=int),
        "start_time": np.empty(0),
        "duration": np.empty(0),
        "mean_speed": np.empty(0),
        "samples": np.empty(0, dtype=int),
    }
    if t.shape != th.shape or t.ndim != 1:
        raise ValueError("time and angle must be 1-D arrays of equal length")
    if len(t) < 3:
        return none
    # The angle reached so far: the revolutions' bounds (for a crank that only turns forward it
    # is the angle itself, and the numbers are those of that case bit for bit).
    reached = np.maximum.accumulate(th)
    top = float(reached[-1])
    # Revolutions k with 2π(k+1) reached by the data.
    k0 = math.ceil(th[0] / TWO_PI - 1e-12)
    ks = np.arange(k0, max(k0, math.floor(top / TWO_PI) + 1))
    ks = ks[TWO_PI * (ks + 1).astype(float) <= top]
    if len(ks) == 0:
        return none
    lo, hi = TWO_PI * ks.astype(float), TWO_PI * (ks + 1).astype(float)
    inside = th[0] < lo
    ja, ta = _crossing_times(t, th, np.where(inside, lo, top), reached)
    ja, ta = np.where(inside, ja, 0), np.where(inside, ta, t[0])
    jb, tb = _crossing_times(t, th, hi, reached)
    keep = jb - ja >= 3
    ks, ja, jb, ta, tb = ks[keep], ja[keep], jb[keep], ta[keep], tb[keep]
    if len(ks) == 0:
        return none
    # The samples of every revolution, flat: revolution r owns flat[off[r]:off[r] + n[r]].
    n = jb - ja
    off = np.cumsum(n) - n
    flat = np.repeat(ja - off, n) + np.arange(n.sum())
    pos = np.arange(len(flat))

    def seg_max(y):
        return np.maximum.reduceat(y[flat], off)

    def seg_min(y):
        return np.minimum.reduceat(y[flat], off)

    def first_where(y, value):
        """The first sample of each revolution where y equals its value (np.argmax's choice)."""
        return flat[
            np.minimum.reduceat(np.where(y[flat] == np.repeat(value, n), pos, len(pos)), off)
        ]

    cols = {k: np.asarray(v, dtype=float) for k, v in series.items()}
    dur = tb - ta
    tab = {"revolution": ks, "start_time": ta, "duration": dur, "mean_speed": TWO_PI / dur}
    tab["samples"] = n
    if speed is not None:
        w = np.asarray(speed, dtype=float)
        if stop_speed is not None:
            tab["interrupted"] = (seg_min(w) < stop_speed).astype(int)
        # The mean by numpy's (pairwise) sum of each revolution, as ws.mean() would.
        means = np.array(
            [np.add.reduce(w[a:b]) / (b - a) for a, b in zip(ja.tolist(), jb.tolist())]
        )
        tab["speed_fluctuation"] = (seg_max(w) - seg_min(w)) / means
    for q in quantities:
        if q not in cols:
            continue
        y = cols[q]
        vmax, amax = _refined_peaks(th, y, first_where(y, seg_max(y)))
        vmin, amin = _refined_peaks(th, y, first_where(y, seg_min(y)))
        tab[f"{q}.max"], tab[f"{q}.max_angle_deg"] = vmax, _degrees(amax)
        tab[f"{q}.min"], tab[f"{q}.min_angle_deg"] = vmin, _degrees(amin)

    def integral(f, x):
        """∫ f dx over exactly [t_a, t_b] of each revolution (trapezoidal rule): the samples
        inside plus the values interpolated at both ends; the trapezoids of revolution r are
        terms[toff[r]:toff[r] + n[r] + 1]."""
        fa, fb, xa, xb = (
            np.interp(ta, t, f),
            np.interp(tb, t, f),
            np.interp(ta, t, x),
            np.interp(tb, t, x),
        )
        toff = off + np.arange(len(n))
        terms = np.empty(len(flat) + len(n))
        seg = np.repeat(np.arange(len(n)), n)
        terms[toff[seg] + 1 + pos - off[seg]] = (
            0.5 * (f[flat + 1] + f[flat]) * (x[flat + 1] - x[flat])
        )
        terms[toff] = 0.5 * (f[ja] + fa) * (x[ja] - xa)
        terms[toff + n] = 0.5 * (fb + f[jb - 1]) * (xb - x[jb - 1])
        return np.array(
            [np.add.reduce(terms[a:b]) for a, b in zip(toff.tolist(), (toff + n + 1).tolist())]
        )

    if "link.friction_total" in cols and "suspension.position" in cols:
        tab["friction_work"] = integral(cols["link.friction_total"], cols["suspension.position"])
    if "fluid_end.flow" in cols:
        # The pump (docs/results.md "Pump presets"): the time means over the revolution, and
        # the flow pulsation (Q_max − Q_min)/Q_mean from the sampled extremes: the flow's
        # extremes often sit at kinks (a chamber's delivery starts at its dead centre), where
        # the parabola of `_refined_peaks` would overshoot by up to an eighth of a step's rise.
        q = cols["fluid_end.flow"]
        tab["flow_mean"] = integral(q, t) / dur
        with np.errstate(all="ignore"):
            tab["flow_pulsation"] = (seg_max(q) - seg_min(q)) / tab["flow_mean"]
        for name, out in (
            ("hydraulic_power", "fluid_end.hydraulic_power"),
            ("mechanical_power", "crank.mechanical_power"),
        ):
            if out in cols:
                tab[f"{name}_mean"] = integral(cols[out], t) / dur
    if "suspension.position" in cols:
        # The stroke: the travel between the extreme positions of the revolution, each refined
        # like the other extremes (docs/twin.md "Output").
        x = cols["suspension.position"]
        xmax, _ = _refined_peaks(th, x, first_where(x, seg_max(x)))
        xmin, _ = _refined_peaks(th, x, first_where(x, seg_min(x)))
        tab["stroke"] = xmax - xmin
    if "rod.angle" in cols:
        tab["rod_angle_amplitude"] = seg_max(np.abs(cols["rod.angle"]))
    if "rod.stress_max" in cols:
        tab["stress_max"] = seg_max(cols["rod.stress_max"])
    return tab
