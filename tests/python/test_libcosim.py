"""The same FMU under libcosim (Open Simulation Platform, through libcosimpy), a second importer
built on the FMI Library, which also calls fmi2GetReal in initialization mode (docs/fmi-interface.md).

libcosim has no input signal table, so the test is the master: before each step it overrides
crank.angle, crank.speed and crank.acceleration with θ(t_k), ω(t_k), ε(t_k) through an override
manipulator (CosimManipulator.create_override: the values are set on the FMU at the start of the
next step, before fmi2DoStep), then calls execution.step() and reads the outputs at t_{k+1} from a
last-value observer. The machine's parameters are initial values (CosimExecution.real_initial_value).
That is the sequence of fmpy.simulate_fmu with signal tables sampled on the same grid
(test_fmpy_kinematics.run), so both importers must give the same numbers at the same times: to
1e-12 of each output's scale (same binary, same doubles; only the time of a communication point is
computed differently, and the outputs do not depend on it).

The crank motion is a speed oscillation, θ = ω0 t + A sin(Ω t): the FMU's own extrapolation inside
a step (θ + ωh + εh²/2) is then not exact, so an importer that failed to pass the inputs (the FMU
left to extrapolate by itself) gives visibly different outputs. The outputs at t_{k+1} are checked
against the mpmath reference at the crank state the FMU must have extrapolated to from the inputs of
t_k (docs/model.md §2): θ_k + ω_k h + ε_k h²/2, ω_k + ε_k h, ε_k.
"""

from __future__ import annotations

import math

import numpy as np
from reference import OUTPUTS, Machine
from test_fmpy_kinematics import run

STEP_NS = int(1e7)  # 10 ms
T_END = 10.0
W0, A, BIG_OMEGA = 7.3, 0.4, 2.1  # rad/s, rad, rad/s


def theta(t):
    return W0 * t + A * math.sin(BIG_OMEGA * t)


def omega(t):
    return W0 + A * BIG_OMEGA * math.cos(BIG_OMEGA * t)


def eps(t):
    return -A * BIG_OMEGA**2 * math.sin(BIG_OMEGA * t)


def cosim_run(fmu_path, machine: Machine, n_steps: int, instance_name: str):
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    ex = CosimExecution.from_step_size(step_size=STEP_NS)
    idx = ex.add_local_slave(CosimLocalSlave(fmu_path=fmu_path, instance_name=instance_name))
    assert idx >= 0
    vr = {v.name.decode(): v.reference for v in ex.slave_variables(idx)}
    for name, value in machine.start_values().items():
        if isinstance(value, int):
            assert ex.integer_initial_value(idx, vr[name], int(value))
        else:
            assert ex.real_initial_value(idx, vr[name], float(value)), name
    manip = CosimManipulator.create_override()
    obs = CosimObserver.create_last_value()
    assert ex.add_manipulator(manip)
    assert ex.add_observer(obs)
    in_vrs = [vr["crank.angle"], vr["crank.speed"], vr["crank.acceleration"]]
    out_vrs = [vr[n] for n in OUTPUTS]
    dt = STEP_NS * 1e-9
    times, rows = [], []
    for k in range(n_steps):
        t = k * dt
        assert manip.slave_real_values(idx, in_vrs, [theta(t), omega(t), eps(t)])
        assert ex.step(), f"libcosim step {k} failed"
        times.append(ex.status().current_time * 1e-9)
        rows.append(obs.last_real_values(idx, out_vrs))
    return np.array(times), np.array(rows)


def test_libcosim_agrees_with_fmpy_and_reference(fmu_path):
    m = Machine(
        r=0.2,
        l=1.19,
        e=0.04,
        m=300.0,
        angle_offset=0.25,
        load_mean=1.0e3,
        load_amplitude=4.0e3,
        load_phase=-0.3,
    )
    h = STEP_NS * 1e-9
    n = int(round(T_END / h))
    t_cs, y_cs = cosim_run(fmu_path, m, n, instance_name="mud pump drive")
    assert len(t_cs) == n and abs(t_cs[-1] - T_END) < 1e-9

    res = run(fmu_path, m, T_END, h, theta, omega, eps=eps)
    # fmpy records t = 0 too; libcosim's samples are t_1 .. t_n.
    assert len(res) == n + 1
    assert np.allclose(res["time"][1:], t_cs, rtol=0, atol=1e-9)
    w_max = W0 + A * BIG_OMEGA
    scales = m.scales(w_max, A * BIG_OMEGA**2)
    for j, name in enumerate(OUTPUTS):
        err = np.max(np.abs(y_cs[:, j] - res[name][1:])) / scales[name]
        assert err <= 1e-12, f"{name}: libcosim vs fmpy differ by {err:.3g} of scale"

    # Against the reference at the extrapolated crank state (every 5th point: 200 points).
    worst_exact = 0.0
    for i in range(0, n, 5):
        tk = i * h
        th_x = theta(tk) + omega(tk) * h + 0.5 * eps(tk) * h * h
        w_x = omega(tk) + eps(tk) * h
        ref = m.outputs(th_x, w_x, eps(tk))
        for j, name in enumerate(OUTPUTS):
            assert abs(y_cs[i, j] - ref[name]) <= 1e-9 * scales[name], (
                name,
                t_cs[i],
                y_cs[i, j],
                ref[name],
            )
        # The true motion at t_{k+1} differs by the cubic term ~ A Ω³ h³ / 6: far above 1e-9.
        true = m.outputs(theta(tk + h), omega(tk + h), eps(tk + h))
        worst_exact = max(
            worst_exact, abs(true["suspension.position"] - ref["suspension.position"]) / m.r
        )
    assert worst_exact > 1e-8, (
        "the test motion should not be reproduced exactly by the extrapolation"
    )


def test_libcosim_two_instances_in_one_execution(fmu_path):
    """Two slaves of the same FMU in one execution (and process), different machines: each
    follows its own parameters (no shared state between instances)."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    ex = CosimExecution.from_step_size(step_size=STEP_NS)
    a = ex.add_local_slave(CosimLocalSlave(fmu_path=fmu_path, instance_name="pump A"))
    b = ex.add_local_slave(CosimLocalSlave(fmu_path=fmu_path, instance_name="pump B"))
    vr = {v.name.decode(): v.reference for v in ex.slave_variables(a)}
    ma, mb = Machine(), Machine(r=0.1, l=0.5, m=50.0)
    for idx, m in ((a, ma), (b, mb)):
        for name in ("geometry.crank_radius", "geometry.rod_length", "mass.reciprocating"):
            assert ex.real_initial_value(idx, vr[name], m.start_values()[name])
        for name in ("support_A.kind", "support_B.kind", "support_C.kind"):
            assert ex.integer_initial_value(idx, vr[name], 0)
        assert ex.real_initial_value(idx, vr["crank.speed"], 5.0)
    manip = CosimManipulator.create_override()
    obs = CosimObserver.create_last_value()
    ex.add_manipulator(manip)
    ex.add_observer(obs)
    out_vrs = [vr[n] for n in OUTPUTS]
    for k in range(50):
        for idx in (a, b):
            manip.slave_real_values(idx, [vr["crank.angle"]], [5.0 * k * 0.01])
        assert ex.step()
        t = ex.status().current_time * 1e-9
        for idx, m in ((a, ma), (b, mb)):
            got = obs.last_real_values(idx, out_vrs)
            ref, sc = m.outputs(5.0 * t, 5.0), m.scales(5.0)
            for j, name in enumerate(OUTPUTS):
                assert abs(got[j] - ref[name]) <= 1e-9 * sc[name], (idx, name, t)


def _user_guide_libcosim_example() -> str:
    """The code block of docs/user-guide.md's "libcosim" section, as a user copies it."""
    import pathlib
    import re

    text = (pathlib.Path(__file__).resolve().parents[2] / "docs" / "user-guide.md").read_text()
    section = text.split("\n## libcosim\n", 1)[1].split("\n## ", 1)[0]
    (code,) = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    return code


def test_user_guide_libcosim_example_prints_no_per_call_trace(fmu_path, tmp_path):
    """The user guide's libcosim example (3 s at 1 ms: 3000 steps) used to print one
    `[trace] ... fmi2DoStep` line per step, because libcosim switches the FMU's debug logging on
    without naming categories. The per-call trace is now the opt-in category logCalls
    (docs/fmi-interface.md "Logging categories"): the example prints no such line, while
    libcosim's own debug lines (the FMI Library's) still show that its log level lets an FMU's
    messages through. Run as a user runs it, in its own process, bounded in time."""
    import subprocess
    import sys

    code = _user_guide_libcosim_example()
    assert "target/fmu/ReciprocatingDrive.fmu" in code and "simulate_until" in code
    script = tmp_path / "example.py"
    script.write_text(code.replace("target/fmu/ReciprocatingDrive.fmu", str(fmu_path)))
    r = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert r.returncode == 0, r.stderr[-2000:]
    out = (r.stdout + r.stderr).splitlines()
    assert sum("[FMI Library" in line for line in out) > 5, "libcosim's debug lines are missing"
    trace = [line for line in out if "fmi2DoStep" in line or "logCalls" in line]
    assert trace == [], f"{len(trace)} per-call lines, e.g. {trace[:2]}"
