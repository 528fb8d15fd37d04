"""python/reciprocating_drive/revolution.py against closed forms (no FMU needed): revolution
boundaries of a non-uniform rotation, extremes and their angles, friction work."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reciprocating_drive.revolution import revolution_table, summarize_revolutions

W = 2 * math.pi * 65 / 60


def rotation(n_rev=3.0, dt=1e-3, fluct=0.1):
    """θ(t) = ωt + fluct·sin(ωt): θ = 2πk exactly at t = 2πk/ω, speed ω(1 + fluct·cos ωt)."""
    t = np.arange(0.0, (n_rev + 0.01) * 2 * math.pi / W, dt)
    return t, W * t + fluct * np.sin(W * t), W * (1 + fluct * np.cos(W * t))


def test_boundaries_and_speed_of_a_non_uniform_rotation():
    t, th, w = rotation()
    revs = summarize_revolutions(t, th, {}, speed=w)
    assert [r.index for r in revs] == [0, 1, 2]
    for r in revs:
        # The crossing time is interpolated linearly over 1 ms: error ≤ θ''·dt²/8 / ω ≈ 1e-8 s.
        assert r.start_time == pytest.approx(2 * math.pi * r.index / W, abs=1e-7)
        assert r.mean_speed == pytest.approx(W, rel=1e-6)
        # (ω_max − ω_min)/ω_mean = 2·fluct for ω(1 + fluct cos); samples miss the peaks by ≤ (ω dt)²/2.
        assert r.speed_fluctuation == pytest.approx(0.2, abs=1e-4)


def test_extremes_and_their_angles():
    t, th, _ = rotation(fluct=0.0, dt=2e-3)
    phi = 1.0  # rad: the maximum of cos(θ − φ) is 1 at θ = φ, the minimum −1 at φ + π
    revs = summarize_revolutions(
        t, th, {"rod.force": 5.0 * np.cos(th - phi)}, quantities=["rod.force"]
    )
    for r in revs:
        e = r.extremes["rod.force"]
        # Parabolic refinement over Δθ = ω·dt ≈ 0.0136 rad: error ~ 5·Δθ³ ≈ 1e-5 in value.
        assert e.max == pytest.approx(5.0, abs=1e-5) and e.min == pytest.approx(-5.0, abs=1e-5)
        assert e.max_angle_deg == pytest.approx(math.degrees(phi), abs=1e-3)
        assert e.min_angle_deg == pytest.approx(math.degrees(phi) + 180.0, abs=1e-3)


def test_friction_work_and_rod_quantities():
    t, th, _ = rotation(fluct=0.05)
    r_crank, amp = 0.2, 300.0
    series = {
        # s = r(1 − cos θ), F = −A sin θ: ∫F ds over a revolution = −A r ∫ sin²θ dθ = −π A r.
        "suspension.position": r_crank * (1 - np.cos(th)),
        "link.friction_total": -amp * np.sin(th),
        "rod.angle": 0.03 * np.sin(3 * th),
        "rod.stress_max": 2e8 + 1e7 * np.cos(th),
    }
    for r in summarize_revolutions(t, th, series):
        assert r.friction_work == pytest.approx(-math.pi * amp * r_crank, rel=1e-5)
        assert r.rod_angle_amplitude == pytest.approx(0.03, rel=1e-3)
        assert r.stress_max == pytest.approx(2.1e8, rel=1e-6)


def test_a_crank_that_turns_back_completes_a_revolution_when_it_first_reaches_its_end():
    """The angle stops, rocks back below the revolution's start and turns forward again: the
    revolution runs from the first sample at 2πk to the first at 2π(k+1) (the running maximum),
    every sample in between is its own, and one whose speed fell below stop_speed is flagged."""
    # Forward at 1 rad/s to 2π + 1, back by 2 rad (below 2π), forward at 1 rad/s to 4π + 1.
    t1 = np.linspace(0, 2 * math.pi + 1, 801)
    th = np.concatenate((t1, t1[-1] - np.linspace(0, 2, 201)[1:], t1[-1] - 2 + t1[1:]))
    t = np.arange(len(th)) * (t1[1] - t1[0])
    w = np.gradient(th, t)
    x = 0.2 * (1 - np.cos(th))
    tab = revolution_table(t, th, {"suspension.position": x}, speed=w, stop_speed=0.1)
    assert tab["revolution"].tolist() == [0, 1]
    # Revolution 1 begins at the first crossing of 2π (sample 800 is 2π + 1 > 2π, the first
    # above it is at t = 2π within a step), ends at the first crossing of 4π after the rollback.
    step = t[1] - t[0]
    assert tab["start_time"][1] == pytest.approx(2 * math.pi, abs=step)
    # Forward at 1 rad/s, 200 samples back, forward at 1 rad/s from 2π - 1 to 4π.
    end = t1[-1] + 200 * step + (4 * math.pi - (t1[-1] - 2))
    assert tab["start_time"][1] + tab["duration"][1] == pytest.approx(end, abs=step)
    assert tab["interrupted"].tolist() == [0, 1]
    assert tab["samples"].sum() <= len(t)
    assert tab["stroke"][1] == pytest.approx(0.4, rel=1e-6)


def test_a_revolution_does_not_depend_on_the_others_in_the_call():
    """Summaries are vectorised over revolutions: each must equal, bit for bit, the summary of its
    own samples and their two neighbours alone (what the live twin computes, one at a time)."""
    t, th, w = rotation(n_rev=6.0, fluct=0.05)
    rng = np.random.default_rng(3)
    series = {
        "suspension.position": 0.2 * (1 - np.cos(th)),
        "link.friction_total": -300 * np.sin(th) + rng.normal(size=len(t)),
        "rod.angle": 0.03 * np.sin(3 * th),
        "rod.stress_max": 2e8 + 1e7 * np.cos(th),
        "rod.force": rng.normal(size=len(t)),
        "crank.torque": np.round(np.cos(2 * th), 1),
    }
    whole = summarize_revolutions(t, th, series, speed=w)
    assert [r.index for r in whole] == list(range(6))
    for r in whole:
        a = max(0, int(np.searchsorted(th, 2 * math.pi * r.index)) - 1)
        b = int(np.searchsorted(th, 2 * math.pi * (r.index + 1))) + 1
        alone = [
            s
            for s in summarize_revolutions(
                t[a:b], th[a:b], {k: v[a:b] for k, v in series.items()}, speed=w[a:b]
            )
            if s.index == r.index
        ]
        assert [s.as_row() for s in alone] == [r.as_row()]
