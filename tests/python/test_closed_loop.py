"""The closed loop of docs/closed-loop.md, co-simulated from the SSP system by libcosim and by fmpy,
against the same two-part system written here as ONE ordinary differential equation and solved by
scipy at tight tolerance (independent of both FMUs' code):

    (J + m·TF²)·ω̇ = i·T_m(ω) + F·TF − m·TF·TF′·ω²,   θ̇ = ω

the pump's crank torque T = −P·TF with P = F + Φ, Φ = −m(TF·ω̇ + TF′·ω²) (guide friction off,
constant process force F), its ω̇ term moved to the left as the inertia m·TF²; TF, TF′ of the
crank-slider in closed form (docs/model.md §3.1); Kloss's T_m(s) = 2T_b/(s/s_b + s_b/s).

Co-simulation breaks the algebraic loop with a one-step delay, a first-order error: the crank speed
must agree within 1e-3 of ω_mean at h = 1 ms, and the error must fall at least linearly with h.
"""

from __future__ import annotations

import math
import pathlib
import zipfile

import numpy as np
import pytest
from reciprocating_drive.closed_loop.system import (
    build_ssp,
    run_fmpy,
    run_libcosim,
    speed_fluctuation,
)
from scipy.integrate import solve_ivp

R, L, M, F = 0.2, 1.19, 300.0, 5000.0
I, WS, TB, SB, JM, JC = 23.0, 2 * math.pi * 1500 / 60, 200.0, 0.15, 0.5, 50.0
W0 = 2 * math.pi * 65 / 60
T_END = 3.0

PUMP = {
    "support_A.kind": 0,
    "support_B.kind": 0,
    "support_C.kind": 0,
    "mass.reciprocating": M,
    "load.profile": 0,
    "load.mean": F,
    "load.amplitude": 0.0,
}
DRIVE = {
    "drive.gear_ratio": I,
    "motor.synchronous_speed": WS,
    "motor.breakdown_torque": TB,
    "motor.breakdown_slip": SB,
    "motor.inertia": JM,
    "crank.inertia": JC,
    "crank.angle_start": 0.0,
    "crank.speed_start": W0,
}


def tf(th):
    lam = R / L
    s, c = math.sin(th), math.cos(th)
    d = math.sqrt(1 - (lam * s) ** 2)
    return R * s * (1 + lam * c / d), R * (c + lam * (math.cos(2 * th) + lam**2 * s**4) / d**3)


def monolithic(t_eval):
    J = JC + I * I * JM

    def rhs(t, y):
        th, w = y
        s = 1 - I * w / WS
        tm = 2 * TB / (s / SB + SB / s) if s != 0 else 0.0
        a, b = tf(th)
        return [w, (I * tm + F * a - M * a * b * w * w) / (J + M * a * a)]

    sol = solve_ivp(
        rhs,
        (0.0, t_eval[-1]),
        [0.0, W0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=t_eval,
        dense_output=False,
    )
    assert sol.success
    return sol.y[1]


@pytest.fixture(scope="module")
def ssp(tmp_path_factory, fmu_path):
    import pathlib

    fmu_dir = pathlib.Path(fmu_path).parent
    assert (fmu_dir / "DriveTrain.fmu").is_file(), "DriveTrain.fmu: scripts/build-fmu.sh builds it"
    return build_ssp(
        tmp_path_factory.mktemp("ssp") / "Validation.ssp", pump=PUMP, drive=DRIVE, fmu_dir=fmu_dir
    )


def errors(run, ssp):
    out = {}
    for h in (1e-3, 0.5e-3, 0.25e-3):
        r = run(ssp, h, T_END)
        ref = monolithic(r["time"])
        w = r["drivetrain.crank.speed"]
        out[h] = float(np.max(np.abs(w - ref)) / np.mean(ref))
    return out


@pytest.mark.parametrize("importer", ["libcosim", "fmpy"])
def test_cosimulation_converges_to_the_monolithic_system(ssp, importer):
    e = errors(run_libcosim if importer == "libcosim" else run_fmpy, ssp)
    print(importer, {f"{h * 1e3:g} ms": f"{x:.3g}" for h, x in e.items()})
    assert e[1e-3] <= 1e-3
    # At least linear: halving h at least halves the error (to 10 % for the ratio's own noise).
    assert e[1e-3] / e[0.5e-3] >= 1.8 and e[0.5e-3] / e[0.25e-3] >= 1.8, e


def test_default_system_runs_in_both_importers_and_agrees(fmu_path, tmp_path):
    """The shipped system (ssp/ClosedLoop: the default pump with guide friction and a process load,
    the default drive train): libcosim and fmpy give the same crank speed to within the difference
    of their first step (fmpy starts the connections at zero), and the speed fluctuation is steady."""
    import pathlib

    ssp = build_ssp(tmp_path / "ClosedLoop.ssp", fmu_dir=pathlib.Path(fmu_path).parent)
    a, b = run_libcosim(ssp, 1e-3, 4.0), run_fmpy(ssp, 1e-3, 4.0)
    assert np.allclose(a["time"], b["time"], atol=1e-9)
    w = a["drivetrain.crank.speed"]
    assert np.max(np.abs(w - b["drivetrain.crank.speed"])) <= 1e-4 * np.mean(w)
    d = speed_fluctuation(a["time"], a["drivetrain.crank.angle"], w)
    assert len(d) >= 3 and 0 < d[-1] < 0.2 and abs(d[-1] - d[-2]) < 1e-3 * d[-1]
    # The motor drives (positive slip, torque and power), well below breakdown.
    assert np.all(a["drivetrain.motor.slip"][100:] > 0) and np.all(
        a["drivetrain.motor.power"][100:] > 0
    )
    assert np.max(a["drivetrain.motor.torque"]) < 200.0


@pytest.mark.parametrize("jc,stable", [(20.0, True), (4.0, False)])
def test_loop_stability_condition(tmp_path, fmu_path, jc, stable):
    """docs/closed-loop.md "The algebraic loop": with the one-step delay a perturbation of the
    acceleration passed around the loop is multiplied per round trip by
    ρ_eff = (m·TF²/J)·exp(−h/τ), τ = J/(i²·k_m), k_m = 2T_b/(s_b·ω_s) the slope of the motor
    torque (the motor damps the crank within the step). A soft motor (s_b = 0.9) and no motor
    inertia: J = 20 kg·m² gives ρ_eff,max = 0.57, smooth; J = 4 kg·m² gives 2.1, and the
    co-simulation diverges until the FMUs refuse the non-finite torque."""
    import pathlib

    from reciprocating_drive import FmuError

    sb = 0.9
    drive = dict(DRIVE, **{"motor.inertia": 0.0, "crank.inertia": jc, "motor.breakdown_slip": sb})
    s = build_ssp(
        tmp_path / "loop.ssp", pump=PUMP, drive=drive, fmu_dir=pathlib.Path(fmu_path).parent
    )
    tau = jc / (I * I * 2 * TB / (sb * WS))
    rho = M * max(tf(x)[0] ** 2 for x in np.linspace(0, math.pi, 2001)) / jc * math.exp(-1e-3 / tau)
    assert (rho < 1) == stable, rho
    if stable:
        a = run_fmpy(s, 1e-3, 2.0)["drivetrain.crank.acceleration"]
        # Smooth after fmpy's start from zero inputs: a step changes ε by about ε̇·h.
        assert np.all(np.isfinite(a)) and np.max(np.abs(np.diff(a[100:]))) < 0.2
    else:
        try:
            a = run_fmpy(s, 1e-3, 2.0)["drivetrain.crank.acceleration"]
        except Exception as e:  # fmpy raises when an FMU refuses the non-finite value
            assert "status 3" in str(e) or isinstance(e, FmuError), e
        else:
            assert not np.all(np.isfinite(a)) or np.max(np.abs(a)) > 1e6


def test_shipped_system_is_ready_for_omsimulator(fmu_path, tmp_path):
    """What OMSimulator (v3.0) needs beyond libcosim and fmpy (docs/closed-loop.md, "In
    OMSimulator"). OMSimulator is not installable here from a package registry (its PyPI package
    downloads its binaries from build.openmodelica.org at build time), so the two conditions under
    which it loads and runs the system are checked on the shipped archive itself:
    * the system carries its master in the org.openmodelica annotation
      (oms:SimulationInformation/oms:FixedStepMaster), since OMSimulator refuses a system without
      one ("Unable to add System"), with the communication step of scripts/closed_loop.py;
    * no component name followed by "." starts a variable name of an FMU: OMSimulator addresses
      a parameter as system.component.variable and would read "drive" + "gear_ratio" for the
      variable drive.gear_ratio ("Unknown signal").
    The same archive still runs in libcosim and fmpy (the other tests of this file)."""
    import xml.etree.ElementTree as ET

    from fmpy import read_model_description

    ssp = build_ssp(tmp_path / "ClosedLoop.ssp", fmu_dir=pathlib.Path(fmu_path).parent)
    ns = {
        "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
        "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
        "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
    }
    with zipfile.ZipFile(ssp) as z:
        z.extractall(tmp_path / "x")
    root = ET.parse(tmp_path / "x" / "SystemStructure.ssd").getroot()
    system = root.find("ssd:System", ns)
    ann = system.find("ssd:Annotations/ssc:Annotation[@type='org.openmodelica']", ns)
    assert ann is not None, "the system has no org.openmodelica annotation"
    master = ann.find("oms:Annotations/oms:SimulationInformation/oms:FixedStepMaster", ns)
    assert master is not None and float(master.get("stepSize")) == 1e-3
    components = system.findall("ssd:Elements/ssd:Component", ns)
    names = [c.get("name") for c in components]
    assert sorted(names) == ["drivetrain", "pump"]
    for c in components:
        md = read_model_description(str(tmp_path / "x" / c.get("source")))
        for v in md.modelVariables:
            for other in names:
                assert not v.name.startswith(other + "."), (
                    f"{c.get('name')}.{v.name}: the component name {other} is a prefix of it"
                )
    # Every parameter of each component's .ssv names a variable of its FMU.
    for c in components:
        md = read_model_description(str(tmp_path / "x" / c.get("source")))
        known = {v.name for v in md.modelVariables}
        ssv = ET.parse(tmp_path / "x" / "resources" / f"{c.get('name')}.ssv").getroot()
        for p in ssv.iter("{http://ssp-standard.org/SSP1/SystemStructureParameterValues}Parameter"):
            assert p.get("name") in known, f"{c.get('name')}.ssv: {p.get('name')}"
