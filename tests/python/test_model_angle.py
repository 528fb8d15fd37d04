"""The crank angle and speed the outputs belong to (issue 14, docs/model.md §2): outputs
crank.model_angle and crank.model_speed follow the rule "a set input is authoritative at the
communication point where it is set; between sets the FMU carries the crank forward with
θ += ωh + εh²/2, ω += εh (ε as last set)", whatever the master's pattern of setting inputs, and
through fmi2GetFMUstate/fmi2SetFMUstate and serialization.

The reference below recomputes the rule in closed form from the master's own record of what it
set and when, independently of the FMU; suspension.position is checked against the exact
crank-slider position (§3.1) at the reported model angle, so the outputs do belong to it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from reciprocating_drive import Fmu

R, L = 0.2, 1.19  # default machine (§8)
OFFSET = 0.25
H = 1e-3
N = 400
FRICTION_OFF = {"support_A.kind": 0, "support_B.kind": 0, "support_C.kind": 0}


def measured(t):
    """A master's crank signal: θ, ω, ε at time t (smooth, not constant-speed)."""
    return (
        2.0 + 5.0 * t + 0.1 * math.sin(3 * t),
        5.0 + 0.3 * math.cos(3 * t),
        -0.9 * math.sin(3 * t),
    )


def position(theta):
    lam = R / L
    return R * (1 - math.cos(theta)) + L * (1 - math.sqrt(1 - (lam * math.sin(theta)) ** 2))


def drive(fmu, set_every, last, n=N, h=H, start=0):
    """Steps n times from step index `start`; sets the crank inputs at communication points whose
    index is a multiple of `set_every` (0 = never). `last` = (time, θ, ω, ε) of the last set
    before `start`. Returns rows of (t, model angle, model speed, position, expected angle,
    expected speed)."""
    rows = []
    for k in range(start, start + n + 1):
        t = k * h
        if set_every and k % set_every == 0:
            fmu.set(dict(zip(["crank.angle", "crank.speed", "crank.acceleration"], measured(t))))
            last = (t, *measured(t))
        ts, th, w, e = last
        tau = t - ts
        expect = (th + w * tau + 0.5 * e * tau * tau + OFFSET, w + e * tau)
        got = fmu.get(["crank.model_angle", "crank.model_speed", "suspension.position"])
        rows.append((t, *got, *expect))
        if k < start + n:
            fmu.step(h)
    return np.array(rows)


def start(fmu_path):
    f = Fmu(fmu_path)
    th, w, e = measured(0.0)
    f.start(
        {
            **FRICTION_OFF,
            "crank.angle_offset": OFFSET,
            "crank.angle": th,
            "crank.speed": w,
            "crank.acceleration": e,
        }
    )
    return f


SET_AT_0 = (0.0, *measured(0.0))
SET_AT_20MS = (0.02, *measured(0.02))


def check_rule(rows):
    t, ang, spd, pos, ang_ref, spd_ref = rows.T
    # Rounding only: the FMU accumulates the extrapolation over up to 400 steps (|θ| ≤ 5 rad).
    assert np.max(np.abs(ang - ang_ref)) < 1e-11
    assert np.max(np.abs(spd - spd_ref)) < 1e-11
    # The outputs belong to that angle: exact position at the model angle (to rounding, §3.1).
    assert np.max(np.abs(pos - np.array([position(a) for a in ang]))) < 1e-12


@pytest.mark.parametrize(
    "set_every", [1, 0, 10], ids=["every step", "once, then held", "every 10th step"]
)
def test_model_angle_follows_the_rule(fmu_path, set_every):
    with start(fmu_path) as f:
        rows = drive(f, set_every, SET_AT_0)
    check_rule(rows)
    ang = rows[:, 1]
    if set_every != 1:
        # The crank did turn by itself between sets: the model angle is not the last set value.
        assert np.ptp(ang) > 1.0


def test_rule_survives_state_restore_and_serialization(fmu_path):
    with start(fmu_path) as f:
        drive(f, 10, SET_AT_0, n=25)  # stop between two sets (t = 25 ms, last set at 20 ms)
        state, data, t_saved = f.get_state(), f.serialize(), f.time
        ahead = drive(f, 10, SET_AT_20MS, n=30, start=25)
        check_rule(ahead)
        f.set_state(state)
        f.time = t_saved
        again = drive(f, 10, SET_AT_20MS, n=30, start=25)
        f.free_state(state)
        assert np.array_equal(ahead, again)
    with start(fmu_path) as g:  # a fresh instance continues from the serialized bytes
        g.restore(data, t_saved)
        assert np.array_equal(drive(g, 10, SET_AT_20MS, n=30, start=25), ahead)
