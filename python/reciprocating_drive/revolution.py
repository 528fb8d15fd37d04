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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

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
        return row


def _refined_peak(theta: np.ndarray, y: np.ndarray, i: int) -> tuple[float, float]:
    """(value, angle) of the extreme at sample i, refined by the parabola through i-1, i, i+1."""
    if 0 < i < len(y) - 1:
        x0, x1, x2 = theta[i - 1], theta[i], theta[i + 1]
        y0, y1, y2 = y[i - 1], y[i], y[i + 1]
        d01, d12 = (y1 - y0) / (x1 - x0), (y2 - y1) / (x2 - x1)
        a = (d12 - d01) / (x2 - x0)
        if a != 0.0:
            xv = 0.5 * (x0 + x1) - d01 / (2.0 * a)
            if x0 <= xv <= x2:
                return float(y1 + d01 * (xv - x1) + a * (xv - x0) * (xv - x1)), float(xv)
    return float(y[i]), float(theta[i])


def _extreme(theta: np.ndarray, y: np.ndarray, sl: slice) -> Extreme:
    """Extremes of y over the samples `sl`. The parabola may use the neighbours just outside the
    slice, so that a peak at a revolution's boundary (the acceleration at an outer dead centre) is
    refined like any other and reported at its true angle."""
    imax, imin = sl.start + int(np.argmax(y[sl])), sl.start + int(np.argmin(y[sl]))
    vmax, amax = _refined_peak(theta, y, imax)
    vmin, amin = _refined_peak(theta, y, imin)
    deg = lambda a: math.degrees(a % TWO_PI) % 360.0  # noqa: E731
    return Extreme(vmax, deg(amax), vmin, deg(amin))


def _crossing_time(t: np.ndarray, theta: np.ndarray, target: float) -> tuple[int, float] | None:
    """First sample index j with θ_j ≥ target (j ≥ 1) and the interpolated time of θ = target."""
    j = int(np.searchsorted(theta, target, side="left"))
    if j == 0 or j >= len(theta):
        return None
    t0, t1, a0, a1 = t[j - 1], t[j], theta[j - 1], theta[j]
    return j, float(t0 + (t1 - t0) * (target - a0) / (a1 - a0)) if a1 != a0 else float(t1)


def summarize_revolutions(
    time: Sequence[float],
    angle: Sequence[float],
    series: Mapping[str, Sequence[float]],
    speed: Sequence[float] | None = None,
    quantities: Sequence[str] = DEFAULT_QUANTITIES,
) -> list[RevolutionSummary]:
    """Summaries of every complete revolution. `angle` is the model angle [rad], continuous and
    non-decreasing (forward rotation); `series` maps output names to sampled values (quantities
    missing from it are skipped; link.friction_total with suspension.position gives the friction
    work, rod.angle the ϑ amplitude, rod.stress_max the largest stress)."""
    t = np.asarray(time, dtype=float)
    th = np.asarray(angle, dtype=float)
    if t.shape != th.shape or t.ndim != 1:
        raise ValueError("time and angle must be 1-D arrays of equal length")
    if len(t) < 3:
        return []
    if np.any(np.diff(th) < 0):
        raise ValueError("the crank angle must not decrease (unwrap it; forward rotation only)")
    cols = {k: np.asarray(v, dtype=float) for k, v in series.items()}
    w = None if speed is None else np.asarray(speed, dtype=float)
    out: list[RevolutionSummary] = []
    k = math.ceil(th[0] / TWO_PI - 1e-12)
    while True:
        a = _crossing_time(t, th, TWO_PI * k) if th[0] < TWO_PI * k else (0, float(t[0]))
        b = _crossing_time(t, th, TWO_PI * (k + 1))
        if a is None or b is None:
            break
        (ja, ta), (jb, tb) = a, b
        sl = slice(ja, jb)  # samples with 2πk ≤ θ < 2π(k+1)
        if jb - ja < 3:
            k += 1
            continue
        dur = tb - ta
        s = RevolutionSummary(index=k, start_time=ta, duration=dur, mean_speed=TWO_PI / dur,
                              speed_fluctuation=None)
        if w is not None:
            ws = w[sl]
            s.speed_fluctuation = float((ws.max() - ws.min()) / ws.mean())
        for q in quantities:
            if q in cols:
                s.extremes[q] = _extreme(th, cols[q], sl)
        if "link.friction_total" in cols and "suspension.position" in cols:
            # Over exactly [t_a, t_b]: the samples inside plus the values interpolated at both ends.
            f = np.concatenate(([np.interp(ta, t, cols["link.friction_total"])], cols["link.friction_total"][sl],
                                [np.interp(tb, t, cols["link.friction_total"])]))
            x = np.concatenate(([np.interp(ta, t, cols["suspension.position"])], cols["suspension.position"][sl],
                                [np.interp(tb, t, cols["suspension.position"])]))
            s.friction_work = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x)))
        if "rod.angle" in cols:
            s.rod_angle_amplitude = float(np.max(np.abs(cols["rod.angle"][sl])))
        if "rod.stress_max" in cols:
            s.stress_max = float(np.max(cols["rod.stress_max"][sl]))
        out.append(s)
        k += 1
    return out
