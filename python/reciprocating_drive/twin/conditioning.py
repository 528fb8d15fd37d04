"""Signal conditioning of measured crank data for the digital twin (docs/twin.md "Conditioning").

* Angles in rad, deg or encoder counts, wrapped (every revolution) or continuous, are unwrapped to
  a continuous angle in rad: each step is taken as the smallest one modulo a revolution.
* Speed ω and acceleration ε, where they are not measured, are the first and second derivative
  at each sample of a local cubic fitted by least squares to the samples within ±window/2 of its
  time (the Savitzky–Golay smoother, on the measured timestamps, so that timestamp jitter does
  not bias it). Near the edge of a segment (the start, the end, a gap) the window keeps its
  width in time and shifts inward. A window holding fewer than MIN_SAMPLES samples is sparse: it
  takes the MIN_SAMPLES samples nearest in time to its centre instead, and the twin reports it. The estimate
  at a sample depends only on the samples of its window, so a live run, which sees the data piece
  by piece, a run started later or resumed, and a replay give the same numbers.

This module is the reference in numpy; the twin runs the same algorithm natively
(tools/fmi2-batch/src/fit.rs, `batch.local_cubic`). Accuracy: docs/twin.md "Conditioning".

Layer: workflows, the twin (docs/architecture.md).
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi

#: Polynomial degree of the local fit: a cubic differentiates a smooth angle to O(window³) in ω
#: and O(window²) in ε, and is exact for constant acceleration.
DEGREE = 3
#: The fewest samples a window may hold (one residual beyond the cubic's four coefficients);
#: a window with fewer is sparse.
MIN_SAMPLES = DEGREE + 2
#: The most samples a sparse window reaches to either side of its centre.
SPARSE_REACH = MIN_SAMPLES - 1


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


def window(
    t: np.ndarray, c: int, half: float, t_start: float, t_end: float = math.inf
) -> tuple[int, int, int]:
    """The window of sample c of a segment of strictly increasing times t spanning t_start ..
    t_end (infinite while it goes on): the index range lo..hi its fit uses and the number of
    samples in it before a sparse one is widened. The samples within ±half seconds of t[c],
    shifted inward at the ends keeping its width in time (the whole segment if it is shorter);
    where a dropout cuts a side short (not shifted: the longest interval from t[c] to the first
    sample beyond the window on that side is longer than half of half and than twice the other
    side's), that side reaches further by that interval.
    Below MIN_SAMPLES the window is sparse and the range is the MIN_SAMPLES samples nearest in
    time to t[c] (at most SPARSE_REACH to either side)."""
    n = len(t)
    a, b = t[c] - half, t[c] + half
    shifted = False
    if a < t_start:
        a, b, shifted = t_start, t_start + 2.0 * half, True
    if b > t_end:
        a, b, shifted = max(t_end - 2.0 * half, t_start), t_end, True
    lo = int(np.searchsorted(t, a, side="left"))
    hi = int(np.searchsorted(t, b, side="right"))
    inside = hi - lo
    if not shifted and lo > 0 and hi < n:
        right = float(np.max(np.diff(t[c : hi + 1])))
        left = float(np.max(np.diff(t[lo - 1 : c + 1])))
        if right > 0.5 * half and right > 2.0 * left:
            b += right
            hi = int(np.searchsorted(t, b, side="right"))
        elif left > 0.5 * half and left > 2.0 * right:
            a -= left
            lo = int(np.searchsorted(t, a, side="left"))
    inside = max(inside, hi - lo)
    if inside >= MIN_SAMPLES:
        return lo, hi, inside
    # Sparse: widened one sample at a time to the nearer neighbour (the earlier on a tie).
    tc = t[c]
    lo, hi = c, c + 1
    while hi - lo < MIN_SAMPLES and (lo > 0 or hi < n):
        if hi == n or (lo > 0 and tc - t[lo - 1] <= t[hi] - tc):
            lo -= 1
        else:
            hi += 1
    return lo, hi, inside


def complete(t: np.ndarray, half: float, t_start: float, first: int = 0) -> int:
    """How many of the samples t[first:] of a segment that goes on (its first sample at
    t_start), counted from `first`, have a window (`window`) that no later sample can change:
    a sample beyond its end has arrived (t + half; t_start + 2·half where it is shifted inward
    at the start; further by the longest interval where a dropout cuts it short) and
    SPARSE_REACH samples follow (the reach of a sparse window)."""
    n = len(t)
    if n < MIN_SAMPLES or first >= n:
        return 0
    tc = t[first:]
    end = tc + half
    shifted = tc - half < t_start
    if shifted[0]:  # only near the segment's start (a live run calls this for every line)
        end = np.where(shifted, t_start + 2.0 * half, end)
    # A window whose end has no sample after it yet (end >= the last sample) waits for one: it
    # decides whether a dropout widens the window (`window`), by an interval of t[first:].
    d = np.diff(tc)
    if d.size and float(d.max()) > 0.5 * half:
        hi = np.searchsorted(t, tc + half, side="right")
        # Those with a long interval between them and the first sample beyond their window.
        big = np.concatenate(([0], np.cumsum(d > 0.5 * half)))
        ks = np.arange(len(tc))
        cand = ~shifted & (hi < n)
        cand[cand] = big[hi[cand] - first] > big[ks[cand]]
        for k in np.flatnonzero(cand).tolist():
            c, h = first + k, int(hi[k])
            right = float(np.max(d[k : h - first]))
            lo = int(np.searchsorted(t, tc[k] - half, side="left"))
            if lo == 0 or right <= 0.5 * half:
                continue
            if right > 2.0 * float(np.max(np.diff(t[lo - 1 : c + 1]))):
                end[k] = end[k] + right
    late = end >= t[-1]
    k = int(late.argmax()) if late.any() else len(tc)
    return max(0, min(k, n - SPARSE_REACH - first))


def window_counts(t: np.ndarray, half: float) -> np.ndarray:
    """The `inside` count of `window` for every sample of a whole segment (vectorised but for
    the windows a dropout widens): the same doubles as `window` and fit.rs."""
    a, b = t - half, t + half
    start = a < t[0]
    a, b = np.where(start, t[0], a), np.where(start, t[0] + 2.0 * half, b)
    end = b > t[-1]
    a = np.where(end, np.maximum(t[-1] - 2.0 * half, t[0]), a)
    b = np.where(end, t[-1], b)
    lo = np.searchsorted(t, a, side="left")
    hi = np.searchsorted(t, b, side="right")
    n = len(t)
    out = hi - lo
    # Where a dropout may widen the window (an interval longer than half of half in reach).
    big = np.concatenate(([0], np.cumsum(np.diff(t) > 0.5 * half)))
    maybe = ~start & ~end & (lo > 0) & (hi < n)
    maybe[maybe] = big[hi[maybe]] - big[lo[maybe] - 1] > 0
    for c in np.flatnonzero(maybe).tolist():
        out[c] = window(t, c, half, float(t[0]), float(t[-1]))[2]
    return out


def derivatives(
    t: np.ndarray, theta: np.ndarray, half: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ω and ε at every sample of one segment (no gaps inside) from the samples within ±half
    seconds of it, and the number of samples within each window (one fit per sample: a
    reference, not fast)."""
    n = len(t)
    if n < DEGREE + 1:
        raise ValueError(
            f"a segment of {n} samples is too short to estimate the speed (needs {DEGREE + 1})"
        )
    w, e, inside = np.empty(n), np.empty(n), np.empty(n, dtype=np.int64)
    for c in range(n):
        lo, hi, inside[c] = window(t, c, half, float(t[0]), float(t[-1]))
        wc, ec = fit(t[None, lo:hi], theta[None, lo:hi], t[c : c + 1, None], theta[c : c + 1, None])
        w[c], e[c] = wc[0], ec[0]
    return w, e, inside
