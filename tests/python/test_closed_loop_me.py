"""The closed loop solved exactly (python/reciprocating_drive/closed_loop/me_loop.py): the pump and the drive
train as FMI 3.0 Model Exchange FMUs in one ODE (scipy DOP853), the torque–acceleration loop
solved at every evaluation. Against the monolithic ODE of test_closed_loop.py (written there from
the formulas, independent of both FMUs) the crank speed must agree to 1e-6 of its mean over 10 s
(the co-simulation's one-step delay gives 1e-3 at h = 1 ms), and the ρ_eff = 2.1 machine of
docs/closed-loop.md, which diverges with the one-step delay, runs smoothly and agrees as well."""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from reciprocating_drive.closed_loop.me_loop import run_model_exchange
from scipy.integrate import solve_ivp
from test_closed_loop import DRIVE, PUMP, SB, TB, W0, WS, F, I, M, tf


def monolithic(t_eval, jc, jm, sb):
    """(J + m·TF²)·ω̇ = i·T_m(ω) + F·TF − m·TF·TF′·ω² (test_closed_loop.py), for a given J, s_b."""
    J = jc + I * I * jm

    def rhs(t, y):
        th, w = y
        s = 1 - I * w / WS
        tm = 2 * TB / (s / sb + sb / s) if s != 0 else 0.0
        a, b = tf(th)
        return [w, (I * tm + F * a - M * a * b * w * w) / (J + M * a * a)]

    sol = solve_ivp(
        rhs, (0.0, t_eval[-1]), [0.0, W0], method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t_eval
    )
    assert sol.success
    return sol.y[1]


@pytest.mark.parametrize(
    "name,drive,t_end",
    [
        ("validation machine", {}, 10.0),
        # docs/closed-loop.md: soft motor, no motor inertia, J = 4 kg·m²: ρ_eff = 2.1.
        (
            "rho_eff 2.1",
            {"motor.inertia": 0.0, "crank.inertia": 4.0, "motor.breakdown_slip": 0.9},
            2.0,
        ),
    ],
)
def test_model_exchange_loop_agrees_with_the_monolithic_ode(fmu_path, name, drive, t_end):
    d = dict(DRIVE, **drive)
    t = np.linspace(0.0, t_end, int(round(t_end / 1e-2)) + 1)
    r = run_model_exchange(t, pump=PUMP, drive=d, fmu_dir=pathlib.Path(fmu_path).parent)
    w = r["drivetrain.crank.speed"]
    ref = monolithic(t, d["crank.inertia"], d["motor.inertia"], d["motor.breakdown_slip"])
    err = float(np.max(np.abs(w - ref)) / np.mean(ref))
    print(f"{name}: max |ω - ω_mono| / mean ω = {err:.3g} over {t_end:g} s")
    assert np.all(np.isfinite(w)) and err <= 1e-6, err
    # The loop is consistent: the torque the drive sees is the pump's at the solved ε.
    eps = r["drivetrain.crank.acceleration"]
    assert np.all(np.isfinite(eps)) and np.max(np.abs(eps)) < 1e3
    # Not trivial: the crank turns more than a revolution.
    assert r["drivetrain.crank.angle"][-1] > 2 * math.pi


def test_rho_eff_case_is_the_one_that_diverges_in_co_simulation():
    """The second case above is docs/closed-loop.md's ρ_eff = 2.1 (so the Model Exchange run is
    the one the one-step delay cannot do)."""
    jc, sb = 4.0, 0.9
    tau = jc / (I * I * 2 * TB / (sb * WS))
    rho = M * max(tf(x)[0] ** 2 for x in np.linspace(0, math.pi, 2001)) / jc * math.exp(-1e-3 / tau)
    assert 2.0 < rho < 2.2 and SB != sb


def test_shipped_system_with_guide_friction_agrees_with_libcosim(fmu_path, tmp_path):
    """The shipped parameter sets (ssp/ClosedLoop: guide friction on, so the pump's torque is only
    piecewise affine in ε): the Model Exchange loop against libcosim's co-simulation of the same
    system at h = 0.25 ms, whose one-step delay is first order (test_closed_loop.py: 1e-3 of the
    mean speed at 1 ms, so 2.5e-4 at 0.25 ms)."""
    from reciprocating_drive.closed_loop.system import SSD, build_ssp, run_libcosim
    from reciprocating_drive.presets import read_ssv

    fmu_dir = pathlib.Path(fmu_path).parent
    h, t_end = 0.25e-3, 2.0
    co = run_libcosim(build_ssp(tmp_path / "loop.ssp", fmu_dir=fmu_dir), h, t_end)
    me = run_model_exchange(
        co["time"],
        pump=read_ssv(SSD.parent / "pump.ssv"),
        drive=read_ssv(SSD.parent / "drivetrain.ssv"),
        fmu_dir=fmu_dir,
    )
    w = me["drivetrain.crank.speed"]
    err = float(np.max(np.abs(w - co["drivetrain.crank.speed"])) / np.mean(w))
    print(f"shipped system: max |ω_ME - ω_libcosim| / mean ω = {err:.3g} at h = {h:g} s")
    assert err <= 2.5e-4, err
