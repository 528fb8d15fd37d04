"""FMI 2.0 Model Exchange in the same .fmu as co-simulation (docs/fmi-interface.md "Model
Exchange (FMI 2.0)"): one model description with both elements, one binary.

* fmpy's validator (API and `fmpy validate`) reports nothing for either FMU;
* the DriveTrain's two states integrated by fmpy's CVODE (rtol 1e-10) agree with the co-simulation
  FMU (its own integrator at 1e-8) to 1e-6 of the synchronous speed, the bound of
  test_drive_train.py; fmpy's explicit Euler converges to it at first order (the error halves
  with the step), which no tolerance could fake;
* every rigid preset as Model Exchange (no states: outputs functions of the crank inputs) gives
  the co-simulation FMU's outputs at every recorded point to rounding (1e-9 of each output's
  scale), with CVODE and with Euler;
* the FMI 2.0 Model Exchange state machine: the calls in their modes, the derivatives readable
  as `der(...)` variables, no event indicators; every illegal sequence, a Model Exchange call on
  a co-simulation instance and a co-simulation call on a Model Exchange instance return fmi2Error
  with one line naming the function.
"""

from __future__ import annotations

import ctypes
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from reciprocating_drive import preset_values

MODELS = ["ReciprocatingDrive", "DriveTrain"]
LOGGER6 = ctypes.CFUNCTYPE(
    None,
    ctypes.c_void_p,
    ctypes.c_char_p,
    ctypes.c_int,
    ctypes.c_char_p,
    ctypes.c_char_p,
    ctypes.c_char_p,
)
RIGID_PRESETS = ["default", "sk8-3.5-4000", "unb600a"]
DT_START = {"crank.speed_start": 0.0, "load.torque": 600.0}
W0 = 2 * np.pi * 1500 / 60 / 23.0  # synchronous crank speed of the default drive train [rad/s]


def fmu(fmu_path, model):
    return str(pathlib.Path(fmu_path).parent / f"{model}.fmu")


@pytest.mark.parametrize("model", MODELS)
def test_both_interfaces_in_one_fmu_and_fmpy_validate_reports_nothing(fmu_path, model):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    md = read_model_description(fmu(fmu_path, model))
    assert md.modelExchange is not None and md.coSimulation is not None
    assert md.modelExchange.modelIdentifier == md.coSimulation.modelIdentifier == model
    assert md.numberOfEventIndicators == 0
    problems = validate_fmu(fmu(fmu_path, model))
    assert problems == [], "\n".join(problems)
    p = subprocess.run(
        [sys.executable, "-c", "import sys; from fmpy.cli import main; sys.exit(main())"]
        + ["validate", fmu(fmu_path, model)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    assert "problem" not in (p.stdout + p.stderr).lower().replace("no problems", "")


def _drive_train(fmu_path, fmi_type, stop, output_interval=1e-3, **kw):
    from fmpy import simulate_fmu

    return simulate_fmu(
        fmu(fmu_path, "DriveTrain"),
        fmi_type=fmi_type,
        stop_time=stop,
        output_interval=output_interval,
        start_values=DT_START,
        output=["crank.angle", "crank.speed", "crank.acceleration", "motor.torque"],
        **kw,
    )


def test_drive_train_cvode_matches_co_simulation(fmu_path):
    """Run-up under 600 N·m over 3 s: CVODE at rtol 1e-10 against the co-simulation FMU at its
    default 1e-8; the bound is the co-simulation's own (1e-6 of ω_0, test_drive_train.py)."""
    stop = 3.0
    me = _drive_train(fmu_path, "ModelExchange", stop, solver="CVode", relative_tolerance=1e-10)
    cs = _drive_train(fmu_path, "CoSimulation", stop)
    assert len(me) == len(cs) > 2900
    assert np.allclose(me["time"], cs["time"], rtol=0, atol=1e-12)
    dw = np.max(np.abs(me["crank.speed"] - cs["crank.speed"]))
    print(f"DriveTrain CVODE - CS: crank.speed {dw:.2g} rad/s")
    assert dw <= 1e-6 * W0, f"crank speed: ME - CS = {dw:.3g} rad/s"
    da = np.max(np.abs(me["crank.angle"] - cs["crank.angle"]))
    assert da <= 1e-6, f"crank angle: ME - CS = {da:.3g} rad"
    # Not a trivial run: the motor runs up to near its synchronous speed.
    assert 0.8 * W0 < me["crank.speed"][-1] < W0


def test_drive_train_euler_converges_to_co_simulation_at_first_order(fmu_path):
    """Explicit Euler is first order: its error against the co-simulation (1e-8, far below)
    halves when the step halves (ratio 2 ± 10 %), and at 5e-5 s it is below 1e-3·ω_0. (fmpy's
    Euler steps from one output point to the next: the output interval is its step.)"""
    stop = 1.0
    cs = _drive_train(fmu_path, "CoSimulation", stop)
    err = []
    for h in (1e-4, 5e-5):
        me = _drive_train(
            fmu_path, "ModelExchange", stop, output_interval=h, step_size=h, solver="Euler"
        )
        every = round(1e-3 / h)
        me = me[::every]
        assert len(me) == len(cs) and np.allclose(me["time"], cs["time"], rtol=0, atol=1e-9)
        err.append(float(np.max(np.abs(me["crank.speed"] - cs["crank.speed"]))))
    ratio = err[0] / err[1]
    assert 1.8 < ratio < 2.2, f"Euler errors {err}: ratio {ratio:.3g}, expected 2 (first order)"
    assert err[1] < 1e-3 * W0


def crank_input(stop, h, omega):
    """crank.angle = ω·t and crank.speed = ω at every communication point (fmpy's input)."""
    t = np.arange(0.0, stop + h / 2, h)
    sig = np.zeros(len(t), dtype=[("time", float), ("crank.angle", float), ("crank.speed", float)])
    sig["time"], sig["crank.angle"], sig["crank.speed"] = t, omega * t, omega
    return sig


@pytest.mark.parametrize("solver", ["CVode", "Euler"])
@pytest.mark.parametrize("machine", RIGID_PRESETS)
def test_rigid_preset_model_exchange_matches_co_simulation(fmu_path, machine, solver):
    """No continuous state: every output is a function of the crank inputs (fed as ω·t, which
    fmpy interpolates linearly in Model Exchange: exact for a linear signal), evaluated when read;
    at the recorded points it equals the co-simulation FMU's to rounding (1e-9 of each output's
    scale)."""
    from fmpy import read_model_description, simulate_fmu

    path = fmu(fmu_path, "ReciprocatingDrive")
    md = read_model_description(path)
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    start = {k: v for k, v in preset_values(machine).items() if k != "crank.angle"}
    omega = float(
        start.pop(
            "crank.speed", next(v.start for v in md.modelVariables if v.name == "crank.speed")
        )
    )
    stop, h = 0.5, 1e-3
    kw = dict(
        stop_time=stop,
        output_interval=h,
        start_values=start,
        input=crank_input(stop, h, omega),
        output=outputs,
    )
    me = simulate_fmu(path, fmi_type="ModelExchange", solver=solver, step_size=h, **kw)
    cs = simulate_fmu(path, fmi_type="CoSimulation", **kw)
    assert len(me) == len(cs) > stop / h / 2
    assert np.allclose(me["time"], cs["time"], rtol=0, atol=1e-12)
    for name in outputs:
        scale = max(np.max(np.abs(cs[name])), 1e-300)
        d = np.max(np.abs(me[name] - cs[name])) / scale
        assert d <= 1e-9, f"{name}: Model Exchange and co-simulation differ by {d:.3g} of its scale"
    assert np.ptp(me["suspension.position"]) > 0


@pytest.mark.parametrize("solver", ["CVode", "Euler"])
@pytest.mark.parametrize("fmi", [2, 3])
def test_a_crank_driven_by_its_speed_alone_turns_in_model_exchange(fmu_path, fmi, solver):
    """crank.angle never set, crank.speed (and once crank.acceleration) only as start values, as
    docs/user-guide.md advises for a crank without an angle signal: fmpy's Model Exchange run
    turns the crank as co-simulation does (fmi2/fmi3SetTime carries it, docs/model.md §2).
    crank.model_angle is θ₀ + ω·t + ε·t²/2, the closed form, to rounding (a few ulp of the angle
    per carry, over about 2 000 carries), and every output equals the co-simulation FMU's at
    every recorded point to 1e-9 of its scale. (An FMU that only carries in co-simulation holds
    the angle at θ₀ here.)"""
    from fmpy import read_model_description, simulate_fmu

    cs_path = fmu(fmu_path, "ReciprocatingDrive")
    path = cs_path if fmi == 2 else fmu(fmu_path, "ReciprocatingDrive-fmi3")
    md = read_model_description(path)
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    stop, h = 1.0, 1e-3
    for theta0, omega, eps in [(0.0, 6.8, 0.0), (0.4, 5.3, 0.6)]:
        start = {"crank.angle": theta0, "crank.speed": omega, "crank.acceleration": eps}
        kw = dict(stop_time=stop, output_interval=h, start_values=start, output=outputs)
        me = simulate_fmu(path, fmi_type="ModelExchange", solver=solver, step_size=h, **kw)
        cs = simulate_fmu(cs_path, fmi_type="CoSimulation", **kw)
        t = me["time"]
        assert len(t) == len(cs) > stop / h / 2 and t[-1] == pytest.approx(stop)
        closed = theta0 + omega * t + 0.5 * eps * t**2
        d = np.max(np.abs(me["crank.model_angle"] - closed))
        print(f"FMI {fmi}.0 {solver} ω = {omega}, ε = {eps}: |θ - closed form| <= {d:.2g} rad")
        assert d <= 1e-12 * (1 + np.max(np.abs(closed))), d
        speed = omega + eps * t
        assert np.max(np.abs(me["crank.model_speed"] - speed)) <= 1e-12 * (1 + np.max(speed))
        for name in outputs:
            scale = max(np.max(np.abs(cs[name])), 1e-300)
            e = np.max(np.abs(me[name] - cs[name])) / scale
            assert e <= 1e-9, f"{name}: Model Exchange and co-simulation differ by {e:.3g}"
        assert np.ptp(me["suspension.position"]) > 0.1


def test_a_time_the_carried_crank_cannot_reach_is_refused(fmu_path, tmp_path):
    """fmi2SetTime to a time where the crank carried forward overflows is refused in one line
    naming the time, and changes nothing: the next time works from where the crank was."""
    me = Logged(fmu_path, "ReciprocatingDrive", tmp_path)
    m, vr = me.m, me.vr
    m.setupExperiment(startTime=0.0)
    m.enterInitializationMode()
    m.setReal([vr["crank.speed"]], [6.0])
    m.exitInitializationMode()
    m.newDiscreteStates()
    m.enterContinuousTimeMode()
    me.refused("fmi2SetTime", ctypes.c_double(1e308), says="time = 1e+308: the crank inputs")
    assert m.getReal([vr["crank.model_angle"]]) == [0.0]
    m.setTime(0.5)
    assert m.getReal([vr["crank.model_angle"], vr["crank.model_speed"]]) == [3.0, 6.0]
    m.terminate()
    m.freeInstance()


# ------------------------------------------------------------------------------ the calls


class Logged:
    """An FMI 2.0 instance through fmpy's low-level API with its messages collected."""

    def __init__(self, fmu_path, model, tmp_path, model_exchange=True):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import (
            FMU2Model,
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        path = fmu(fmu_path, model)
        md = read_model_description(path)
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.md = md
        d = extract(path, unzipdir=str(tmp_path / ("me" if model_exchange else "cs")))
        cls = FMU2Model if model_exchange else FMU2Slave
        self.m = cls(guid=md.guid, unzipDirectory=d, modelIdentifier=model, instanceName="i")
        self.messages: list[str] = []

        # The logger takes the FMU's one variadic argument (it logs through "%s"), as in
        # test_lowlevel.py, not through fmpy's process-wide proxy.
        def log(env, name, status, category, fmt, message):
            assert fmt == b"%s"
            self.messages.append(message.decode())

        self._fn = LOGGER6(log)  # keep a reference: ctypes does not
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(ctypes.cast(self._fn, ctypes.c_void_p).value)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(ctypes.CDLL(None).calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(ctypes.CDLL(None).free)
        self._cb = cb
        self.m.instantiate(callbacks=cb)

    def raw(self, name, *args):
        """Calls the exported function directly (fmpy raises on an error status)."""
        self.messages.clear()
        return getattr(self.m.dll, name)(ctypes.c_void_p(self.m.component), *args)

    def refused(self, name, *args, says):
        st = self.raw(name, *args)
        assert st == 3, f"{name} returned {st}, expected fmi2Error"
        assert len(self.messages) == 1, self.messages
        assert self.messages[0].startswith(f"{name}: ") and says in self.messages[0], self.messages
        assert "\n" not in self.messages[0]


def kloss_acceleration(w, load):
    """(i·T_m(ω) − T_L)/J with Kloss's curve and the default parameters (docs/closed-loop.md),
    written here from the formulas, not from the FMU."""
    i, ws, tb, sb = 23.0, 2 * np.pi * 1500 / 60, 200.0, 0.15
    J = 50.0 + i**2 * 0.5
    s = 1 - i * w / ws
    return (i * 2 * tb * s * sb / (s * s + sb * sb) - load) / J


def test_state_machine_calls_and_refusals(fmu_path, tmp_path):
    dbl2 = ctypes.c_double * 2
    x, dx = dbl2(), dbl2()
    flag, term = ctypes.c_int(), ctypes.c_int()
    me = Logged(fmu_path, "DriveTrain", tmp_path)
    vr, m = me.vr, me.m
    # Before initialization: no Model Exchange call.
    me.refused("fmi2SetTime", ctypes.c_double(0.0), says="illegal call sequence")
    me.refused("fmi2GetDerivatives", dx, ctypes.c_size_t(2), says="illegal call sequence")
    m.setupExperiment(startTime=0.0)
    m.enterInitializationMode()
    me.refused("fmi2EnterContinuousTimeMode", says="illegal call sequence")
    m.setReal([vr["load.torque"]], [300.0])
    # Initial unknowns are readable in initialization mode (libcosim reads every variable there).
    w_start = next(v.start for v in me.md.modelVariables if v.name == "crank.speed_start")
    d0 = m.getReal([vr["der(crank.angle)"], vr["der(crank.speed)"]])
    assert d0[0] == float(w_start)
    assert abs(d0[1] - kloss_acceleration(float(w_start), 300.0)) <= 1e-13 * abs(d0[1])
    assert me.raw("fmi2GetDerivatives", dx, ctypes.c_size_t(2)) == 0 and list(dx) == d0
    assert me.raw("fmi2GetContinuousStates", x, ctypes.c_size_t(2)) == 0
    assert list(x) == [0.0, float(w_start)]
    me.refused("fmi2SetTime", ctypes.c_double(0.0), says="illegal call sequence")
    m.exitInitializationMode()
    # Event mode: no continuous states set, no integrator step, no second event mode.
    me.refused("fmi2SetContinuousStates", dx, ctypes.c_size_t(2), says="not allowed in event mode")
    me.refused(
        "fmi2CompletedIntegratorStep",
        0,
        ctypes.byref(flag),
        ctypes.byref(term),
        says="not allowed in event mode",
    )
    me.refused("fmi2EnterEventMode", says="not allowed in event mode")
    assert m.newDiscreteStates() == (False, False, False, False, False, 0.0)
    m.enterContinuousTimeMode()
    me.refused("fmi2NewDiscreteStates", None, says="only in event mode")
    me.refused("fmi2EnterContinuousTimeMode", says="only in event mode")
    # Continuous-time mode: states in and out, derivatives from the formulas.
    assert me.raw("fmi2GetContinuousStates", x, ctypes.c_size_t(2)) == 0
    assert list(x) == [0.0, float(w_start)]
    assert me.raw("fmi2GetNominalsOfContinuousStates", x, ctypes.c_size_t(2)) == 0
    assert list(x) == [1.0, 1.0]
    m.setTime(0.25)
    m.setContinuousStates(dbl2(1.5, 5.0), 2)
    assert me.raw("fmi2GetContinuousStates", x, ctypes.c_size_t(2)) == 0
    assert list(x) == [1.5, 5.0]
    assert me.raw("fmi2GetDerivatives", dx, ctypes.c_size_t(2)) == 0
    assert dx[0] == 5.0
    assert abs(dx[1] - kloss_acceleration(5.0, 300.0)) <= 1e-13 * abs(dx[1])
    got = m.getReal([vr["der(crank.angle)"], vr["der(crank.speed)"], vr["crank.speed"]])
    assert got == [dx[0], dx[1], 5.0]
    assert vr["der(crank.angle)"] == 18 and vr["der(crank.speed)"] == 19  # as in FMI 3.0
    assert me.raw("fmi2GetEventIndicators", x, ctypes.c_size_t(0)) == 0
    me.refused("fmi2GetEventIndicators", x, ctypes.c_size_t(1), says="no event indicators")
    me.refused("fmi2GetDerivatives", dx, ctypes.c_size_t(3), says="2 continuous states")
    me.refused(
        "fmi2SetContinuousStates",
        dbl2(float("nan"), 0.0),
        ctypes.c_size_t(2),
        says="crank.angle = NaN",
    )
    me.refused("fmi2SetTime", ctypes.c_double(float("inf")), says="time = inf")
    assert me.raw("fmi2CompletedIntegratorStep", 1, ctypes.byref(flag), ctypes.byref(term)) == 0
    assert flag.value == 0 and term.value == 0
    # Co-simulation calls on a Model Exchange instance.
    me.refused("fmi2DoStep", ctypes.c_double(0.25), ctypes.c_double(1e-3), 1, says="Model Exchange")
    m.enterEventMode()
    m.terminate()
    me.refused("fmi2SetTime", ctypes.c_double(1.0), says="illegal call sequence")
    m.freeInstance()

    # Model Exchange calls on a co-simulation instance.
    cs = Logged(fmu_path, "DriveTrain", tmp_path, model_exchange=False)
    cs.m.setupExperiment(startTime=0.0)
    cs.m.enterInitializationMode()
    cs.m.exitInitializationMode()
    for name, args in [
        ("fmi2SetTime", (ctypes.c_double(0.0),)),
        ("fmi2EnterEventMode", ()),
        ("fmi2GetDerivatives", (dx, ctypes.c_size_t(2))),
        ("fmi2SetContinuousStates", (dx, ctypes.c_size_t(2))),
    ]:
        cs.refused(name, *args, says="not an instance for Model Exchange")
    cs.m.doStep(0.0, 1e-3)
    cs.m.terminate()
    cs.m.freeInstance()


def test_rigid_pump_steps_only_in_co_simulation(fmu_path, tmp_path):
    """The pump's rigid mechanism as Model Exchange: fmi2DoStep (whose fast path otherwise skips
    every check) is refused on its instance."""
    me = Logged(fmu_path, "ReciprocatingDrive", tmp_path)
    me.m.setupExperiment(startTime=0.0)
    me.m.enterInitializationMode()
    me.m.exitInitializationMode()
    me.m.newDiscreteStates()
    me.m.enterContinuousTimeMode()
    dx = (ctypes.c_double * 2)(1.0, 1.0)
    assert me.raw("fmi2GetDerivatives", dx, ctypes.c_size_t(2)) == 0 and list(dx) == [0.0, 0.0]
    me.refused("fmi2DoStep", ctypes.c_double(0.0), ctypes.c_double(1e-3), 1, says="Model Exchange")
    me.m.terminate()
    me.m.freeInstance()


# ------------------------------------------------------------------------------ the elastic rod

ROD_CASES = {
    "kvo630": {},  # a helical spring (rod.kind 2), the elastic-rod preset
    "thin-rod": {"rod.kind": 1},  # the same machine with a thin elastic rod
}


def _rod_values(case):
    v = dict(preset_values("kvo630"))
    v.update(ROD_CASES[case])
    return v


def _omega0(v):
    """Ω0 = sqrt(K_ϑ(0)/J_m) of the cage from the independent §6 code (rod_reference.py)."""
    from rod_reference import Drive

    return Drive(v).omega0


class MeInstance:
    """A Model Exchange instance of the pump (FMI 2.0 or 3.0) through fmpy's low-level API,
    initialized with `values`, in continuous-time mode; `rhs(t, y, crank)` sets the time, the
    crank inputs and the states and returns the derivatives, as an importer's solver does."""

    def __init__(self, fmu_path, tmp_path, fmi, values):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Model
        from fmpy.fmi3 import FMU3Model

        name = "ReciprocatingDrive"
        path = fmu(fmu_path, name) if fmi == 2 else fmu(fmu_path, f"{name}-fmi3")
        md = read_model_description(path)
        var = {v.name: v for v in md.modelVariables}
        d = extract(path, unzipdir=str(tmp_path / f"rod{fmi}"))
        cls = FMU2Model if fmi == 2 else FMU3Model
        self.m = m = cls(guid=md.guid, unzipDirectory=d, modelIdentifier=name, instanceName="r")
        self.fmi = fmi
        m.instantiate()
        if fmi == 2:
            m.setupExperiment(startTime=0.0)
            m.enterInitializationMode()
        else:
            m.enterInitializationMode(startTime=0.0)
        set_real = m.setReal if fmi == 2 else m.setFloat64
        set_int = m.setInteger if fmi == 2 else m.setInt32
        for k, val in values.items():
            if var[k].type in ("Real", "Float64"):
                set_real([var[k].valueReference], [float(val)])
            elif var[k].type in ("Integer", "Int32"):
                set_int([var[k].valueReference], [int(val)])
            else:
                m.setBoolean([var[k].valueReference], [bool(val)])
        m.exitInitializationMode()
        if fmi == 2:
            m.newDiscreteStates()
        else:
            m.updateDiscreteStates()
        m.enterContinuousTimeMode()
        self.set_real = set_real
        self.get_real = m.getReal if fmi == 2 else m.getFloat64
        self.vr = {k: v.valueReference for k, v in var.items()}
        self.crank = [self.vr[n] for n in ("crank.angle", "crank.speed", "crank.acceleration")]
        self.x, self.dx = (ctypes.c_double * 2)(), (ctypes.c_double * 2)()
        self.evaluations = 0

    def states(self):
        self.m.getContinuousStates(self.x, 2)
        return list(self.x)

    def rhs(self, t, y, crank=None):
        self.evaluations += 1
        self.m.setTime(t)
        if crank is not None:
            self.set_real(self.crank, crank)
        self.x[0], self.x[1] = y
        self.m.setContinuousStates(self.x, 2)
        if self.fmi == 2:
            self.m.getDerivatives(self.dx, 2)
        else:
            self.m.getContinuousStateDerivatives(self.dx, 2)
        return [self.dx[0], self.dx[1]]

    def free(self):
        self.m.terminate()
        self.m.freeInstance()


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("case", list(ROD_CASES))
def test_elastic_rod_model_exchange_in_scipy_matches_co_simulation(fmu_path, tmp_path, case, fmi):
    """The cage integrated by scipy (solve_ivp DOP853, rtol 1e-10) through the Model Exchange
    functions, the crank ω·t set at every evaluation, against the co-simulation FMU (its own
    integrator at the same tolerance 1e-10) over 0.05 s (about 1.3 crank turns, from the
    quasi-static start through the first oscillations): ϑ within ten tolerance units
    1e-10·(1 + max|ϑ|) and ϑ̇ within the same times Ω0 (test_elastic_rod.py's bound)."""
    from fmpy import simulate_fmu
    from scipy.integrate import solve_ivp

    v = _rod_values(case)
    omega = float(v["crank.speed"])
    stop, h, tol = 0.05, 2e-4, 1e-10
    t = np.arange(0.0, stop + h / 2, h)
    me = MeInstance(fmu_path, tmp_path, fmi, {**v, "crank.angle": 0.0})
    y0 = me.states()
    sol = solve_ivp(
        lambda s, y: me.rhs(s, y, [omega * s, omega, 0.0]),
        (0.0, stop),
        y0,
        method="DOP853",
        rtol=tol,
        atol=tol * 1e-2,
        t_eval=t,
    )
    assert sol.status == 0, sol.message
    # The outputs read back at a state equal it (rod.angle is ϑ for an elastic rod).
    me.rhs(stop, sol.y[:, -1], [omega * stop, omega, 0.0])
    got = me.get_real([me.vr["rod.angle"], me.vr["rod.angular_velocity"], me.vr["rod.cage_angle"]])
    assert got == [sol.y[0, -1], sol.y[1, -1], sol.y[0, -1]]
    me.free()
    start = {k: val for k, val in v.items() if k not in ("crank.angle", "crank.speed")}
    sig = np.zeros(len(t), dtype=[("time", float), ("crank.angle", float), ("crank.speed", float)])
    sig["time"], sig["crank.angle"], sig["crank.speed"] = t, omega * t, omega
    cs = simulate_fmu(
        fmu(fmu_path, "ReciprocatingDrive"),
        stop_time=stop,
        output_interval=h,
        start_values=start,
        input=sig,
        output=["rod.angle", "rod.angular_velocity"],
        relative_tolerance=tol,
    )
    assert len(cs) == len(t) and sol.y.shape == (2, len(t))
    theta_max = np.max(np.abs(cs["rod.angle"]))
    unit = tol * (1 + theta_max)
    d_theta = np.max(np.abs(sol.y[0] - cs["rod.angle"]))
    d_rate = np.max(np.abs(sol.y[1] - cs["rod.angular_velocity"]))
    print(f"{case} FMI {fmi}.0: scipy ME - CS: rod.angle {d_theta:.2g} rad, rate {d_rate:.2g}")
    assert d_theta <= 10 * unit, f"rod.angle: ME - CS = {d_theta:.3g} rad"
    assert d_rate <= 10 * unit * _omega0(v), f"rod.angular_velocity: ME - CS = {d_rate:.3g}"
    assert theta_max > 0.01  # not a trivial run: the cage swings


@pytest.mark.parametrize("case", list(ROD_CASES))
def test_elastic_rod_fmpy_cvode_matches_scipy(fmu_path, tmp_path, case):
    """fmpy's own Model Exchange run (CVODE, rtol 1e-10) of the cage with the crank driven by its
    speed alone (crank.angle never set: fmi2SetTime carries it, θ = ω·t, docs/model.md §2), so
    no input jumps at fmpy's output points. Compared with scipy's DOP853 at rtol 1e-12 through
    the same functions with the crank ω·t set at every evaluation, within ten tolerance units
    1e-10·(1 + max|ϑ|) (ϑ̇: times Ω0)."""
    from fmpy import simulate_fmu
    from scipy.integrate import solve_ivp

    v = _rod_values(case)
    omega = float(v["crank.speed"])
    stop, h, tol = 0.05, 2e-4, 1e-10
    start = {k: val for k, val in v.items() if k != "crank.angle"}
    got = simulate_fmu(
        fmu(fmu_path, "ReciprocatingDrive"),
        fmi_type="ModelExchange",
        solver="CVode",
        relative_tolerance=tol,
        stop_time=stop,
        output_interval=h,
        start_values=start,
        output=["rod.angle", "rod.angular_velocity"],
    )
    t = got["time"]
    me = MeInstance(fmu_path, tmp_path, 2, {**v, "crank.angle": 0.0})
    sol = solve_ivp(
        lambda s, y: me.rhs(s, y, [omega * s, omega, 0.0]),
        (0.0, stop),
        me.states(),
        method="DOP853",
        rtol=1e-12,
        atol=1e-14,
        t_eval=t,
    )
    me.free()
    assert sol.status == 0, sol.message
    theta_max = np.max(np.abs(sol.y[0]))
    unit = tol * (1 + theta_max)
    d_theta = np.max(np.abs(got["rod.angle"] - sol.y[0]))
    d_rate = np.max(np.abs(got["rod.angular_velocity"] - sol.y[1]))
    print(f"{case}: fmpy CVODE - scipy: rod.angle {d_theta:.2g} rad, rate {d_rate:.2g} rad/s")
    assert d_theta <= 10 * unit, f"rod.angle: fmpy CVODE - scipy = {d_theta:.3g} rad"
    assert d_rate <= 10 * unit * _omega0(v), f"rod.angular_velocity: {d_rate:.3g} rad/s"
    assert np.ptp(sol.y[1]) > 1.0  # the cage moves


def test_rigid_mechanism_keeps_its_cage_states_at_zero(fmu_path, tmp_path):
    """Every machine declares the two cage states; a rigid one has no cage: they start at 0, their
    derivatives are 0 whatever the crank, and rod.angle stays the swing angle."""
    me = MeInstance(fmu_path, tmp_path, 2, dict(preset_values("sk8-3.5-4000")))
    assert me.states() == [0.0, 0.0]
    assert me.rhs(0.3, [0.0, 0.0], [1.0, 0.8, 0.1]) == [0.0, 0.0]
    assert me.get_real([me.vr["rod.cage_angle"], me.vr["rod.cage_rate"]]) == [0.0, 0.0]
    assert me.get_real([me.vr["rod.angle"]])[0] != 0.0
    me.free()


# ------------------------------------------------------------------------------ the ME system

SSD_NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}


def _unpacked(ssp, where):
    import xml.etree.ElementTree as ET
    import zipfile

    with zipfile.ZipFile(ssp) as z:
        z.extractall(where)
    return ET.parse(where / "SystemStructure.ssd").getroot()


def test_model_exchange_system_resolves_against_both_model_descriptions(fmu_path, tmp_path):
    """ClosedLoopME.ssp (no importer here runs an SSP as Model Exchange: fmpy's SSP support is
    co-simulation only, OMSimulator cannot be installed from a registry): the co-simulation
    system's components, parameter sets and connections, the OMSimulator annotation of a
    variable-step (Model Exchange) solver instead of the fixed-step master; every connector is a
    variable of its FMU with that causality, every connection joins declared connectors output to
    input, every parameter of the .ssv files is a parameter of its FMU, and both FMUs offer
    Model Exchange."""
    from fmpy import read_model_description
    from reciprocating_drive.closed_loop.system import build_ssp
    from reciprocating_drive.presets import read_ssv

    fmu_dir = pathlib.Path(fmu_path).parent
    me = _unpacked(
        build_ssp(tmp_path / "me.ssp", fmu_dir=fmu_dir, model_exchange=True), tmp_path / "me"
    )
    cs = _unpacked(build_ssp(tmp_path / "cs.ssp", fmu_dir=fmu_dir), tmp_path / "cs")
    info = me.find(".//oms:SimulationInformation", SSD_NS)
    solver = info.find("oms:VariableStepSolver", SSD_NS)
    assert solver is not None and solver.get("description") == "cvode"
    assert info.find("oms:FixedStepMaster", SSD_NS) is None
    assert cs.find(".//oms:FixedStepMaster", SSD_NS) is not None

    def structure(root):
        comps = {
            c.get("name"): (
                c.get("source"),
                [(k.get("name"), k.get("kind")) for k in c.iterfind(".//ssd:Connector", SSD_NS)],
                c.find(".//ssd:ParameterBinding", SSD_NS).get("source"),
            )
            for c in root.iterfind(".//ssd:Component", SSD_NS)
        }
        conns = sorted(
            tuple(
                c.get(a) for a in ("startElement", "startConnector", "endElement", "endConnector")
            )
            for c in root.iterfind(".//ssd:Connection", SSD_NS)
        )
        return comps, conns

    comps, conns = structure(me)
    assert (comps, conns) == structure(cs)
    assert len(comps) == 2 and len(conns) == 4
    kinds = {}
    for name, (source, connectors, ssv) in comps.items():
        md = read_model_description(str(tmp_path / "me" / source))
        assert md.fmiVersion == "2.0" and md.modelExchange is not None, name
        variables = {v.name: v for v in md.modelVariables}
        for conn, kind in connectors:
            assert conn in variables and variables[conn].causality == kind, (name, conn)
            kinds[(name, conn)] = kind
        for k in read_ssv(tmp_path / "me" / ssv):
            assert k in variables and variables[k].causality == "parameter", (name, k)
    for a, ac, b, bc in conns:
        assert kinds[(a, ac)] == "output" and kinds[(b, bc)] == "input"


def test_model_exchange_system_runs_in_the_repository_master(fmu_path, tmp_path):
    """me_loop.run_model_exchange_ssp reads ClosedLoopME.ssp (its FMI 2.0 FMUs through their
    Model Exchange interface, its parameter sets) and integrates the loop exactly; over 1 s it
    gives the crank speed the FMI 3.0 Model Exchange FMUs give with the same parameters to 1e-9
    of its mean (the same equations through the other standard's calls)."""
    from reciprocating_drive.closed_loop.me_loop import run_model_exchange, run_model_exchange_ssp
    from reciprocating_drive.closed_loop.system import SSD, build_ssp
    from reciprocating_drive.presets import read_ssv

    fmu_dir = pathlib.Path(fmu_path).parent
    ssp = build_ssp(tmp_path / "ClosedLoopME.ssp", fmu_dir=fmu_dir, model_exchange=True)
    t = np.arange(1, 1001) * 1e-3
    a = run_model_exchange_ssp(ssp, t)
    b = run_model_exchange(
        t,
        read_ssv(SSD.parent / "pump.ssv"),
        read_ssv(SSD.parent / "drivetrain.ssv"),
        fmu_dir=fmu_dir,
    )
    w = b["drivetrain.crank.speed"]
    d = np.max(np.abs(a["drivetrain.crank.speed"] - w)) / np.mean(w)
    print(f"ClosedLoopME.ssp in me_loop vs FMI 3.0 ME: {d:.2g} of the mean speed")
    assert d <= 1e-9
    assert np.ptp(w) > 0 and np.all(np.isfinite(a["pump.crank.torque"]))
    # Another system is refused in one line naming the file.
    import zipfile

    bad = tmp_path / "other.ssp"
    with zipfile.ZipFile(ssp) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "SystemStructure.ssd":
                data = data.replace(b'endConnector="crank.speed"', b'endConnector="crank.angle"')
            zout.writestr(item, data)
    with pytest.raises(ValueError, match="not the closed loop"):
        run_model_exchange_ssp(bad, t[:10])
