"""The known truth behind the twin's sample data (scripts/make_twin_sample.py, docs/twin.md): the
default machine's crank at 65 strokes/min whose speed fluctuates by ±`FLUCTUATION` twice per
revolution, as the crank of a pump driven through a compliant drive does:

    ω(t) = ω0·(1 + δ·sin(Ω·t)),  Ω = 2·ω0,   θ(t) = ω0·t + (δ·ω0/Ω)·(1 − cos(Ω·t)),   ε = δ·ω0·Ω·cos(Ω·t)

Layer: workflows, the twin (docs/architecture.md).
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


#: A stop/start cycle (docs/twin.md "Machine states"), in closed form: (phase end [s], kind).
#: Running at ω0, a linear ramp down, a standstill in which the crank rocks back ROLLBACK rad with
#: a half-cosine speed (the fluid pushing the pistons back), a linear ramp up, running again.
CYCLE = (6.0, 2.0, 0.2, 1.0, 4.8, 2.0, 6.0)  # run, ramp down, still, rollback, still, ramp up, run
ROLLBACK = math.radians(2.0)


def cycle_truth(t, omega0=OMEGA0, phases=CYCLE, rollback=ROLLBACK, cycles=1):
    """θ, ω, ε of `cycles` stop/start cycles one after the other (θ(0) = 0), piecewise in closed
    form: constant speed, constant deceleration, rest, θ = θs − R·(1 − cos(π·τ/T))/2, rest,
    constant acceleration, constant speed. Returns also the phases' start times (one list per
    cycle)."""
    t = np.asarray(t, dtype=float)
    theta, omega, eps = np.zeros_like(t), np.zeros_like(t), np.zeros_like(t)
    run1, down, still1, back, still2, up, run2 = phases
    period = sum(phases)
    th0, starts = 0.0, []
    for c in range(cycles):
        t0 = c * period
        edges = np.cumsum([t0, *phases])
        starts.append(edges.tolist())
        a_down, a_up = omega0 / down, omega0 / up
        th_stop = th0 + omega0 * run1 + 0.5 * omega0 * down
        th_back = th_stop - rollback
        for lo, hi, kind in zip(edges[:-1], edges[1:], range(7)):
            last = c == cycles - 1 and kind == 6  # the record may run on after the last phase
            m = (t >= lo) & (last | (t < hi))
            tau = t[m] - lo
            if kind == 0:
                theta[m], omega[m], eps[m] = th0 + omega0 * tau, omega0, 0.0
            elif kind == 1:
                theta[m] = th0 + omega0 * run1 + omega0 * tau - 0.5 * a_down * tau**2
                omega[m], eps[m] = omega0 - a_down * tau, -a_down
            elif kind == 2:
                theta[m] = th_stop
            elif kind == 3:
                x = math.pi * tau / back
                theta[m] = th_stop - rollback * (1 - np.cos(x)) / 2
                omega[m] = -rollback * math.pi / (2 * back) * np.sin(x)
                eps[m] = -rollback * (math.pi / back) ** 2 / 2 * np.cos(x)
            elif kind == 4:
                theta[m] = th_back
            elif kind == 5:
                theta[m] = th_back + 0.5 * a_up * tau**2
                omega[m], eps[m] = a_up * tau, a_up
            else:
                th_run = th_back + 0.5 * omega0 * up
                theta[m], omega[m] = th_run + omega0 * tau, omega0
        th0 = th_back + 0.5 * omega0 * up + omega0 * run2
    return theta, omega, eps, starts


def jog_truth(t, speed=-2 * math.pi * 2 / 60, ramp=1.0, rest=1.0, hold=40.0):
    """A crank jogged slowly (default backwards at 2 strokes/min): rest, a linear ramp to `speed`,
    `hold` s at it, a linear ramp to rest, rest. θ(0) = 0; θ, ω, ε in closed form."""
    t = np.asarray(t, dtype=float)
    a = speed / ramp
    e1, e2, e3 = rest, rest + ramp, rest + ramp + hold
    e4 = e3 + ramp
    tau1, tau2 = np.clip(t - e1, 0, ramp), np.clip(t - e2, 0, hold)
    tau3 = np.clip(t - e3, 0, ramp)
    theta = 0.5 * a * tau1**2 + speed * tau2 + speed * tau3 - 0.5 * a * tau3**2
    omega = np.where(
        t < e1, 0.0, np.where(t < e2, a * (t - e1), np.where(t < e3, speed, speed - a * tau3))
    )
    omega = np.where(t >= e4, 0.0, omega)
    eps = np.where((t >= e1) & (t < e2), a, np.where((t >= e3) & (t < e4), -a, 0.0))
    return theta, omega, eps, [e1, e2, e3, e4]
