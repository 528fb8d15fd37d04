"""The known truth behind the twin's sample data (scripts/make_twin_sample.py, docs/twin.md): the
default machine's crank at 65 strokes/min whose speed fluctuates by ±`FLUCTUATION` twice per
revolution, as the crank of a pump driven through a compliant drive does:

    ω(t) = ω0·(1 + δ·sin(Ω·t)),  Ω = 2·ω0,   θ(t) = ω0·t + (δ·ω0/Ω)·(1 − cos(Ω·t)),   ε = δ·ω0·Ω·cos(Ω·t)
"""

from __future__ import annotations

import math

import numpy as np

OMEGA0 = 2 * math.pi * 65 / 60
FLUCTUATION = 0.03
BIG_OMEGA = 2 * OMEGA0


def truth(t):
    t = np.asarray(t, dtype=float)
    d = FLUCTUATION
    theta = OMEGA0 * t + d * OMEGA0 / BIG_OMEGA * (1 - np.cos(BIG_OMEGA * t))
    omega = OMEGA0 * (1 + d * np.sin(BIG_OMEGA * t))
    eps = d * OMEGA0 * BIG_OMEGA * np.cos(BIG_OMEGA * t)
    return theta, omega, eps


def crank_slider_acceleration(theta, omega, eps, r=0.2, l=1.19):
    """a = TF·ε + TF′·ω² of the central crank-slider in closed form (docs/model.md §3.1)."""
    lam = r / l
    s, c = np.sin(theta), np.cos(theta)
    d = np.sqrt(1 - (lam * s) ** 2)
    tf = r * s * (1 + lam * c / d)
    tf2 = r * (c + lam * (np.cos(2 * theta) + lam**2 * s**4) / d**3)
    return tf * eps + tf2 * omega**2


def encoder_samples(duration=12.0, rate=1000.0, counts=4096, jitter=20e-6, gap=(6.0, 6.2), seed=1):
    """(time, counts) of a wrapped incremental encoder read at `rate` with timestamp jitter and
    one gap."""
    rng = np.random.default_rng(seed)
    k = np.arange(int(duration * rate) + 1)
    t = k / rate + rng.normal(0.0, jitter, len(k))
    t[0] = 0.0
    t = np.round(t, 6)  # the logger writes microseconds
    keep = (t < gap[0]) | (t > gap[1])
    t = t[keep]
    theta, _, _ = truth(t)
    c = np.floor(theta / (2 * math.pi) * counts).astype(np.int64) % counts
    return t, c
