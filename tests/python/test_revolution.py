"""python/reciprocating_drive/revolution.py against closed forms (no FMU needed): revolution
boundaries of a non-uniform rotation, extremes and their angles, friction work."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reciprocating_drive.revolution import summarize_revolutions

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


def test_rejects_a_decreasing_angle():
    with pytest.raises(ValueError, match="must not decrease"):
        summarize_revolutions([0, 1, 2, 3], [0, 1, 0.5, 2], {})


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
