"""fmpy.simulate_fmu with the crank motion as input signals, against the 30-digit mpmath reference
of reference.py (exact crank-slider vector loop, derivatives by mpmath.diff).

How fmpy drives a co-simulation FMU (fmpy 0.3.32, simulation.simulateCS), and why the comparison
is exact:
  * at every communication point t_k fmpy first sets the inputs, interpolating the signal table
    linearly in time (at a time that equals a table time it returns that sample exactly), then
    calls fmi2DoStep(t_k, h), then records the outputs at t_{k+1} = start + (k+1)·h. It reads them
    after doStep and *before* it sets the inputs of t_{k+1}: the recorded outputs are the FMU's own,
    computed at its in-step extrapolation of the crank, θ(t_k) + ω h + ε h²/2, ω(t_k) + ε h
    (docs/model.md §2). The sample at t = 0 is taken after exitInitializationMode, at the inputs of
    t = 0.
  * for constant speed (θ = ω t, ε = 0) and for a uniform ramp with ε supplied
    (θ = ω0 t + ε t²/2, ω = ω0 + ε t) that extrapolation is exact, so every recorded output must
    equal the reference at the exact crank motion of its time. Without the extrapolation (outputs of
    the step's start), without the ε h²/2 term, or without ε in a = TF·ε + TF'·ω², the results are
    off by far more than the tolerance.
  * the signal tables are sampled on the communication grid itself, so the linear interpolation of
    the quadratic θ of the ramp is never used between samples.

Tolerance: 1e-9 of each output's natural scale (r for s and TF, r ω² for a, m r ω² for forces,
...). Double precision gives about 1e-15 relative, times θ ≈ 20 rad of accumulated angle for the
rounding of θ itself: 1e-9 leaves a wide margin for float evaluation order but catches any wrong
formula, a first-harmonic approximation (error ≈ λ³ r ω² ≈ 1e-3 r ω²) or a time lag of one step.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import simulate_fmu
from reference import OUTPUTS, Machine

OMEGA = 2 * math.pi * 65 / 60  # default machine: 65 strokes/min (docs/model.md §8)
RTOL = 1e-9


def run(fmu_path, machine: Machine, t_stop, dt, theta, omega, eps=0.0, f_ext=0.0):
    """Simulate with the crank motion theta(t), omega(t), eps (a constant or a function of t) and
    a constant f_ext as input signals sampled on the communication grid t_k = k dt. Returns fmpy's
    result array."""
    n = int(round(t_stop / dt))
    t = np.array([k * dt for k in range(n + 1)])
    sig = np.zeros(
        n + 1,
        dtype=[
            ("time", np.float64),
            ("crank.angle", np.float64),
            ("crank.speed", np.float64),
            ("crank.acceleration", np.float64),
            ("link.external_force", np.float64),
        ],
    )
    sig["time"] = t
    sig["crank.angle"] = [theta(x) for x in t]
    sig["crank.speed"] = [omega(x) for x in t]
    sig["crank.acceleration"] = [eps(x) for x in t] if callable(eps) else eps
    sig["link.external_force"] = f_ext
    return simulate_fmu(
        fmu_path,
        start_time=0.0,
        stop_time=t_stop,
        output_interval=dt,
        start_values=machine.start_values(),
        input=sig,
        output=list(OUTPUTS),
    )


def compare(res, machine: Machine, theta, omega, eps=0.0, f_ext=0.0, expect_points=None):
    if expect_points is not None:
        assert len(res) == expect_points
    worst = {k: 0.0 for k in OUTPUTS}
    for row in res:
        t = float(row["time"])
        ref = machine.outputs(theta(t), omega(t), eps, f_ext)
        scale = machine.scales(omega(t), eps, f_ext)
        for k in OUTPUTS:
            err = abs(float(row[k]) - ref[k]) / scale[k]
            worst[k] = max(worst[k], err)
            assert err <= RTOL, (
                f"{k} at t = {t}: FMU {row[k]!r}, reference {ref[k]!r}, "
                f"error {err:.3g} of scale {scale[k]:.4g}"
            )
    return worst


def test_constant_speed_default_machine(fmu_path):
    """Three crank revolutions of the default machine (§8) at 65 strokes/min."""
    m = Machine()
    theta, omega = (lambda t: OMEGA * t), (lambda t: OMEGA)
    res = run(fmu_path, m, 3.0, 0.01, theta, omega)
    compare(res, m, theta, omega, expect_points=301)
    # The dead centres of §3.1 are visited: s spans the stroke 2r, a(ODC) = r ω² (1 + λ).
    s = res["suspension.position"]
    assert abs((s.max() - s.min()) - 2 * m.r) < 1e-4  # sampled every 3.9°: near, not at, the ends
    assert abs(res["suspension.acceleration"][0] - m.r * OMEGA**2 * (1 + m.r / m.l)) < 1e-12


def test_constant_speed_offset_machine_with_loads(fmu_path):
    """A different geometry with a guide offset e ≠ 0 and a crank.angle_offset, set through start
    values, plus a process force (input + profile 0) so rod.force and crank.torque carry load."""
    m = Machine(
        r=0.15,
        l=0.62,
        e=-0.07,
        m=120.0,
        angle_offset=0.4,
        load_mean=-3.0e3,
        load_amplitude=8.0e3,
        load_phase=0.7,
    )
    th, dth = m.odc_check()
    assert abs(dth) < 1e-25  # the reference's X_max is the true maximum
    w = 9.5
    theta, omega = (lambda t: w * t), (lambda t: w)
    res = run(fmu_path, m, 1.5, 0.005, theta, omega, f_ext=2.5e4)
    compare(res, m, theta, omega, f_ext=2.5e4, expect_points=301)
    # s ≥ 0 everywhere, also with the offset (ODC at θ ≠ 0).
    assert res["suspension.position"].min() > -1e-12


@pytest.mark.parametrize("omega0,eps", [(2.0, 3.0), (9.0, -2.5)])
def test_speed_ramp_with_acceleration_supplied(fmu_path, omega0, eps):
    """ω = ω0 + ε t, θ = ω0 t + ε t²/2, crank.acceleration = ε: a = TF·ε + TF'·ω² exactly."""
    m = Machine(e=0.03, angle_offset=-0.2)
    theta = lambda t: omega0 * t + 0.5 * eps * t * t  # noqa: E731
    omega = lambda t: omega0 + eps * t  # noqa: E731
    res = run(fmu_path, m, 2.0, 0.01, theta, omega, eps=eps)
    compare(res, m, theta, omega, eps=eps, expect_points=201)
    # The ε term matters: the same outputs with ε ignored would be off by |TF·ε| ~ r ε.
    ref_no_eps = [
        m.outputs(theta(t), omega(t), 0.0)["suspension.acceleration"] for t in res["time"]
    ]
    assert np.max(np.abs(res["suspension.acceleration"] - ref_no_eps)) > 0.1 * m.r * abs(eps)


def test_uneven_step_sizes_are_exact_too(fmu_path):
    """canHandleVariableCommunicationStepSize: an output interval that does not divide the
    revolution, and a stop time that is not a multiple of it (fmpy shortens the last step)."""
    m = Machine()
    theta, omega = (lambda t: OMEGA * t + 1.0), (lambda t: OMEGA)
    n = 137
    dt = 0.0173
    t_stop = n * dt + 0.0061
    tt = [k * dt for k in range(n + 1)] + [t_stop]
    sig = np.zeros(
        len(tt),
        dtype=[
            ("time", np.float64),
            ("crank.angle", np.float64),
            ("crank.speed", np.float64),
            ("crank.acceleration", np.float64),
            ("link.external_force", np.float64),
        ],
    )
    sig["time"] = tt
    sig["crank.angle"] = [theta(x) for x in tt]
    sig["crank.speed"] = OMEGA
    res = simulate_fmu(
        fmu_path,
        stop_time=t_stop,
        output_interval=dt,
        input=sig,
        start_values=m.start_values(),
        output=list(OUTPUTS),
    )
    assert abs(res["time"][-1] - t_stop) < 1e-12
    compare(res, m, theta, omega)


def test_fmpy_simulate_without_inputs_uses_start_values(fmu_path):
    """No input signal: fmpy leaves the inputs at their start values (θ = 0, ω = 65 strokes/min,
    ε = 0) and the FMU advances the crank itself by its extrapolation, θ = ω t (docs/model.md §2)."""
    m = Machine()
    w = 2 * np.pi * 65 / 60
    res = simulate_fmu(
        fmu_path,
        stop_time=1.0,
        output_interval=0.01,
        start_values=m.start_values(),
        output=list(OUTPUTS),
    )
    sc = m.scales(w)
    for row in res[::10]:
        ref = m.outputs(w * row["time"], w)
        for name in OUTPUTS:
            assert abs(row[name] - ref[name]) <= 1e-9 * sc[name], (name, row["time"])
