"""The DriveTrain FMU (docs/closed-loop.md) through fmpy: a valid model description, the run-up
of the crank against scipy's solution of J·ω̇ = i·T_m(ω) − T_L written here, the steady slip under a
constant load against the Kloss curve solved by bisection, parameter errors named, and FMU state
save/restore and serialization bit for bit."""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from reciprocating_drive import Fmu, FmuError
from scipy.integrate import solve_ivp

I, WS, TB, SB, JM, JC = 23.0, 2 * math.pi * 1500 / 60, 200.0, 0.15, 0.5, 50.0


@pytest.fixture(scope="module")
def drive_fmu(fmu_path):
    p = pathlib.Path(fmu_path).parent / "DriveTrain.fmu"
    assert p.is_file(), "scripts/build-fmu.sh builds DriveTrain.fmu"
    return str(p)


def kloss(w):
    s = 1 - I * w / WS
    return 2 * TB * s * SB / (s * s + SB * SB)


def test_validates(drive_fmu):
    from fmpy.validation import validate_fmu

    assert validate_fmu(drive_fmu) == []


def test_run_up_and_steady_slip(drive_fmu):
    load = 600.0  # below the starting torque i·T_m(s = 1) = 1350 N·m: the motor runs up
    h, n = 1e-3, 3000
    with Fmu(drive_fmu) as f:
        f.start({"crank.speed_start": 0.0, "load.torque": load})
        w = [f.get(["crank.speed"])[0]]
        for _ in range(n):
            f.step(h)
            w.append(f.get(["crank.speed"])[0])
        slip, torque, acc = f.get(["motor.slip", "motor.torque", "crank.acceleration"])
    J = JC + I * I * JM
    t = np.arange(n + 1) * h
    ref = solve_ivp(
        lambda t, y: [(I * kloss(y[0]) - load) / J],
        (0, t[-1]),
        [0.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=t,
    ).y[0]
    assert np.max(np.abs(np.array(w) - ref)) < 1e-6 * WS / I  # the FMU's tolerance is 1e-8
    # Steady state: i·T_m(s*) = T_L on the stable branch (s < s_b), by bisection.
    lo, hi = 0.0, SB
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if I * 2 * TB * mid * SB / (mid * mid + SB * SB) < load else (lo, mid)
    assert slip == pytest.approx(lo, rel=1e-6)
    assert I * torque == pytest.approx(load, rel=1e-6) and abs(acc) < 1e-6


def test_bad_parameter_is_named(drive_fmu):
    with Fmu(drive_fmu) as f:
        with pytest.raises(FmuError, match=r"motor\.breakdown_slip.*1\.5"):
            f.start({"motor.breakdown_slip": 1.5})


def test_state_restore_and_serialization_bit_for_bit(drive_fmu):
    with Fmu(drive_fmu) as f:
        f.start({"load.torque": 800.0})
        for _ in range(50):
            f.step(1e-3)
        st, data, t = f.get_state(), f.serialize(), f.time
        names = ["crank.angle", "crank.speed", "crank.acceleration", "motor.torque"]

        def run(g):
            out = []
            for k in range(100):
                g.set({"load.torque": 800.0 + 300.0 * math.sin(k / 7)})
                g.step(1e-3)
                out.append(g.get(names))
            return out

        a = run(f)
        f.set_state(st)
        f.time = t
        b = run(f)
        f.free_state(st)
        assert a == b
    with Fmu(drive_fmu) as g:
        g.start()
        g.restore(data, t)
        assert run(g) == a


def test_no_non_finite_output_with_ok(drive_fmu):
    """docs/hardening.md: the glue refuses to return a non-finite output. A drive train with almost
    no inertia and an enormous load has an infinite acceleration: fmi2GetReal fails naming it, and
    the other outputs stay readable."""
    with Fmu(drive_fmu) as f:
        f.start({"crank.inertia": 1e-300, "motor.inertia": 0.0, "load.torque": -1e308})
        with pytest.raises(
            FmuError,
            match=r"non-finite outputs.*crank\.acceleration = inf.*crank\.inertia = 1e-300",
        ):
            f.get(["crank.speed", "crank.acceleration"])
        assert f.get(["crank.speed"]) == [pytest.approx(2 * math.pi * 65 / 60)]
