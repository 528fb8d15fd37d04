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
    little inertia (1e-5 kg.m2: the time constant 1.1e-9 s is just above the bound of
    docs/hardening.md "DriveTrain bounds") and an enormous load has an infinite acceleration:
    fmi2GetReal fails naming it, and the other outputs stay readable."""
    with Fmu(drive_fmu) as f:
        f.start({"crank.inertia": 1e-5, "motor.inertia": 0.0, "load.torque": -1e308})
        with pytest.raises(
            FmuError,
            match=r"non-finite outputs.*crank\.acceleration = inf.*crank\.inertia = 1e-05",
        ):
            f.get(["crank.speed", "crank.acceleration"])
        assert f.get(["crank.speed"]) == [pytest.approx(2 * math.pi * 65 / 60)]


def _long_numbers(message: str) -> list[str]:
    """Numbers of a message with more than 6 significant digits (docs/hardening.md
    "Messages")."""
    import re

    out = []
    for m in re.finditer(r"(?<![\w.])(\d[\d.]*)(e[-+]\d+)?", message):
        mantissa = m.group(1).rstrip(".")
        digits = mantissa.replace(".", "").lstrip("0")
        if "." not in mantissa:
            digits = digits.rstrip("0")
        if len(digits) > 6:
            out.append(m.group(0))
    return out


def _fmpy_messages(capsys, drive_fmu, start_values, step_size=1e-3, tolerance=None, load=None):
    """Runs the DriveTrain in fmpy.simulate_fmu (0.01 s) and returns (error, FMU messages).

    The messages are read from what fmpy's own logger prints ("[ERROR] ..."): a logger passed to
    simulate_fmu goes through fmpy's process-wide logger proxy, which keeps pointing at the
    Python callback after it is freed, and a later FMU in the same process crashes on it."""
    from fmpy import simulate_fmu

    sig = None
    if load is not None:
        sig = np.array([(0.0, load), (1.0, load)], dtype=[("time", float), ("load.torque", float)])
    capsys.readouterr()
    try:
        simulate_fmu(
            drive_fmu,
            stop_time=0.01,
            step_size=step_size,
            start_values=start_values,
            relative_tolerance=tolerance,
            input=sig,
        )
        error = None
    except Exception as e:  # fmpy raises a plain Exception naming the failed call
        error = str(e)
    out = capsys.readouterr().out.splitlines()
    return error, [line.split("] ", 1)[1] for line in out if line.startswith("[")]


@pytest.mark.parametrize(
    "start, load, expect",
    [
        # issue: "the step size fell to 0e0 s" named no variable; now refused at initialization
        # by the drive's time constant τ = s_b·ω_s·J/(2·i²·T_b) >= 1e-9 s, naming its factors.
        (
            {"crank.inertia": 1e-300, "motor.inertia": 0.0},
            None,
            [r"fmi2ExitInitializationMode: the drive train is too stiff", r"= 1e-300 \+ 23²·0 ="],
        ),
        (
            {"motor.breakdown_torque": 1e300},
            None,
            [r"too stiff", r"motor\.breakdown_torque T_b = 1e\+300 N\.m", r"τ >= 1e-09 s"],
        ),
        # A load far beyond the motor: the step fails naming load.torque and its ratio to the
        # motor's breakdown torque at the crank (i·T_b = 23·200 = 4600 N·m).
        (
            {},
            1e300,
            [r"load\.torque = 1e\+300 N\.m is 2\.17391e\+296 times", r"= 4600 N\.m\)"],
        ),
        ({}, -1e300, [r"load\.torque = -1e\+300 N\.m is 2\.17391e\+296 times"]),
        # Bounds where a physical one exists.
        ({"crank.speed_start": 1e300}, None, [r"crank\.speed_start = 1e\+300 is out of range"]),
        (
            {"solver.tolerance": 1e-300},
            None,
            [
                r"solver\.tolerance = 1e-300 is out of range; allowed: a finite number in \[1e-13, 1\)"
            ],
        ),
    ],
)
def test_impossible_drives_are_named_with_short_numbers(capsys, drive_fmu, start, load, expect):
    """Issue: DriveTrain failures said only "the step size fell to 0e0 s"; through fmpy each
    abuse now fails with one message naming the variable and its value, and every number in it
    has at most 6 significant digits (the values set are echoed as given)."""
    import re

    error, messages = _fmpy_messages(capsys, drive_fmu, start, load=load)
    assert error is not None, "the run must fail"
    text = "\n".join(messages)
    for pattern in expect:
        assert re.search(pattern, text), (pattern, text)
    assert "0e0" not in text
    echoed = {repr(v).replace("1e+300", "1e+300") for v in start.values()} | {"157.07963267948966"}
    assert [n for n in _long_numbers(text) if n not in echoed] == [], text


def test_setup_tolerance_and_tiny_steps(capsys, drive_fmu):
    """fmi2SetupExperiment's tolerance 1e-300 is refused where it is given, with the allowed
    range; a step of 1e-300 s (any positive step must work, FMI 2.0) moves the state by the
    Taylor step θ + ω·h, ω + ω̇·h (the speed's change is below rounding) and the run goes on."""
    error, messages = _fmpy_messages(capsys, drive_fmu, {}, tolerance=1e-300)
    assert error and any(
        m.endswith("tolerance = 1e-300; allowed: a finite number in [1e-13, 1)") for m in messages
    ), messages
    with Fmu(drive_fmu) as f:
        f.start()
        before = f.get(["crank.angle", "crank.speed"])
        f.step(1e-300)
        # θ + ω·h (6.8e-300 rad, a subnormal-free double) and ω + ω̇·h, which rounds to ω.
        assert f.get(["crank.angle", "crank.speed"]) == [before[0] + before[1] * 1e-300, before[1]]
        f.step(1e-3)
        assert f.get(["crank.speed"])[0] == pytest.approx(
            2 * math.pi * 65 / 60 + 0.6497e-3, rel=1e-4
        )
