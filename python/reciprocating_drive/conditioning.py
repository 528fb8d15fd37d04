"""Signal conditioning of measured crank data for the digital twin (docs/twin.md "Conditioning").

* Angles in rad, deg or encoder counts, wrapped (every revolution) or continuous, are unwrapped to
  a continuous angle in rad: each step is taken as the smallest one modulo a revolution.
* Speed ω and acceleration ε, where they are not measured, are the first and second derivative
  at each sample of a local cubic fitted by least squares to the samples within ±window/2 of it
  (the Savitzky–Golay smoother, on the measured timestamps, so that timestamp jitter does not
  bias it). A sample near the edge of a segment (the start, the end, a gap) takes the same number
  of neighbours from one side. The estimate at a sample depends only on the samples of its window,
  so a live run, which sees the data piece by piece, gives the same numbers as a replay.

Accuracy (measured with scripts/twin_accuracy.py, docs/twin.md): exact angles at 1 kHz give
ω and ε to rounding; an encoder of 4096 counts/rev at 1 kHz with 65 strokes/min and a window of
0.1 s gives the suspension acceleration within 1 % of its peak.
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi

#: Polynomial degree of the local fit: a cubic differentiates a smooth angle to O(window³) in ω
#: and O(window²) in ε, and is exact for constant acceleration.
DEGREE = 3


def to_radians(values: np.ndarray, unit: str, counts_per_rev: float | None = None) -> np.ndarray:
    if unit == "rad":
        return np.asarray(values, dtype=float)
    if unit == "deg":
        return np.radians(np.asarray(values, dtype=float))
    if unit == "counts":
        if not counts_per_rev or counts_per_rev <= 0:
            raise ValueError("--counts-per-rev must be given (> 0) for angles in encoder counts")
        return np.asarray(values, dtype=float) * (TWO_PI / counts_per_rev)
    raise ValueError(f"angle unit {unit!r}; allowed: rad, deg, counts")


def unwrap_step(previous_raw: float, previous_unwrapped: float, raw: float) -> float:
    """The continuous angle of `raw` given the previous sample: the step modulo 2π nearest zero."""
    d = math.remainder(raw - previous_raw, TWO_PI)
    return previous_unwrapped + d


def fit(
    T: np.ndarray, TH: np.ndarray, tc: np.ndarray, thc: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """ω and ε at K centres from K windows: rows of T (times) and TH (angles) of equal width,
    tc and thc the centres' time and angle (shape (K, 1)). Least squares by the normal equations
    of a cubic in x = τ/max|τ| (well conditioned: x ∈ [−1, 1]); every row is computed on its own,
    so the result for a sample does not depend on which other samples share the call."""
    tau = T - tc
    scale = np.max(np.abs(tau), axis=1, keepdims=True)
    scale[scale == 0.0] = 1.0
    x = tau / scale
    y = TH - thc
    powers = [np.ones_like(x)]
    for _ in range(2 * DEGREE):
        powers.append(powers[-1] * x)
    s = [p.sum(axis=1) for p in powers]
    m = np.empty((x.shape[0], DEGREE + 1, DEGREE + 1))
    for i in range(DEGREE + 1):
        for j in range(DEGREE + 1):
            m[:, i, j] = s[i + j]
    b = np.stack([(powers[p] * y).sum(axis=1) for p in range(DEGREE + 1)], axis=1)
    c = np.linalg.solve(m, b[..., None])[..., 0]
    sc = scale[:, 0]
    return c[:, 1] / sc, 2.0 * c[:, 2] / (sc * sc)


def windows(n: int, half: int, centres: np.ndarray) -> np.ndarray:
    """Index rows of the windows of `centres` in a segment of n samples: 2·half+1 samples around
    each (fewer if the segment is shorter), shifted inward at the ends."""
    width = min(2 * half + 1, n)
    lo = np.clip(centres - half, 0, n - width)
    return lo[:, None] + np.arange(width)[None, :]


def derivatives(t: np.ndarray, theta: np.ndarray, half: int) -> tuple[np.ndarray, np.ndarray]:
    """ω and ε at every sample of one segment (no gaps inside)."""
    n = len(t)
    if n < DEGREE + 1:
        raise ValueError(
            f"a segment of {n} samples is too short to estimate the speed (needs {DEGREE + 1})"
        )
    k = np.arange(n)
    idx = windows(n, half, k)
    return fit(t[idx], theta[idx], t[k][:, None], theta[k][:, None])


def window_samples(window: float, dt: float) -> int:
    """Half-width in samples of a smoothing window of `window` seconds at sample spacing dt."""
    return max(2, int(round(0.5 * window / dt)))
