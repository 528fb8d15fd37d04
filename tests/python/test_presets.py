"""Each preset of docs/model.md §8, read from the FMU's own resources/presets/*.ssv, loads and runs a
few revolutions in fmpy and in libcosim, and both importers agree (same binary, same inputs, so to
1e-12 of scale). Preset-specific checks against independent references:

* sk8-3.5-4000: seed 001's printed accelerations (2.72 m/s² at φ1 = 37.51°, −1.4909 at
  192.51°; φ1 = θ + 90° − atan2(H−G, I)) and the closed-form class-I stroke
  S = A·|ψ(P+R) − ψ(P−R)|, ψ(d) = acos((C² + K² − d²)/(2CK)) (docs/model.md §3.2);
* unb600a and kvo630: the rod force carries the preset's process load.
"""

from __future__ import annotations

import math
import zipfile

import numpy as np
import pytest
from reciprocating_drive.presets import preset_values_from_fmu  # noqa: E402

PRESETS = ["unb600a", "unb600a-simplex", "triplex-1600", "sk8-3.5-4000", "kvo630"]
OUTS = [
    "suspension.position",
    "suspension.acceleration",
    "inertia.force",
    "rod.force",
    "crank.torque",
]


def fmpy_run(fmu_path, values, revolutions=2, n_per_rev=720):
    from fmpy import simulate_fmu

    w = values["crank.speed"]
    h = 2 * math.pi / w / n_per_rev
    t_end = revolutions * n_per_rev * h
    t = np.arange(0, revolutions * n_per_rev + 1) * h
    sig = np.zeros(t.size, dtype=[("time", float), ("crank.angle", float), ("crank.speed", float)])
    sig["time"], sig["crank.angle"], sig["crank.speed"] = t, w * t, w
    start = {k: v for k, v in values.items() if k != "crank.speed"}
    res = simulate_fmu(
        fmu_path,
        stop_time=t_end,
        step_size=h,
        output_interval=h,
        input=sig,
        start_values=start,
        output=OUTS,
    )
    return res, h


def cosim_run(fmu_path, values, n_steps, h):
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    step_ns = int(round(h * 1e9))
    ex = CosimExecution.from_step_size(step_size=step_ns)
    idx = ex.add_local_slave(CosimLocalSlave(fmu_path=fmu_path, instance_name="preset run"))
    variables = {v.name.decode(): v for v in ex.slave_variables(idx)}
    for name, value in values.items():
        ref = variables[name].reference
        if isinstance(value, bool):
            assert ex.boolean_initial_value(idx, ref, value), name
        elif isinstance(value, int):
            assert ex.integer_initial_value(idx, ref, value), name
        else:
            assert ex.real_initial_value(idx, ref, float(value)), name
    manip, obs = CosimManipulator.create_override(), CosimObserver.create_last_value()
    assert ex.add_manipulator(manip) and ex.add_observer(obs)
    w = values["crank.speed"]
    ins = [variables[n].reference for n in ("crank.angle", "crank.speed")]
    outs = [variables[n].reference for n in OUTS]
    rows = []
    for k in range(n_steps):
        t = k * step_ns * 1e-9
        assert manip.slave_real_values(idx, ins, [w * t, w])
        assert ex.step(), f"step {k}"
        rows.append(obs.last_real_values(idx, outs))
    return np.array(rows), step_ns * 1e-9


@pytest.mark.parametrize("name", PRESETS)
def test_preset_runs_in_fmpy_and_libcosim(fmu_path, name):
    values = preset_values_from_fmu(fmu_path, name)
    assert "crank.speed" in values and "mechanism" in values
    res, h = fmpy_run(fmu_path, values, revolutions=1, n_per_rev=200)
    assert np.all(np.isfinite([res[o] for o in OUTS]))
    # libcosim steps in whole nanoseconds: run it on its own grid and compare with fmpy on the same.
    y, h_ns = cosim_run(fmu_path, values, 200, h)
    res2, _ = fmpy_run_on_grid(fmu_path, values, h_ns, 200)
    for j, o in enumerate(OUTS):
        scale = max(1.0, np.max(np.abs(res2[o])))
        assert np.max(np.abs(y[:, j] - res2[o][1:])) <= 1e-12 * scale, (name, o)


def fmpy_run_on_grid(fmu_path, values, h, n):
    from fmpy import simulate_fmu

    w = values["crank.speed"]
    t = np.arange(n + 1) * h
    sig = np.zeros(t.size, dtype=[("time", float), ("crank.angle", float), ("crank.speed", float)])
    sig["time"], sig["crank.angle"], sig["crank.speed"] = t, w * t, w
    start = {k: v for k, v in values.items() if k != "crank.speed"}
    return simulate_fmu(
        fmu_path,
        stop_time=n * h,
        step_size=h,
        output_interval=h,
        input=sig,
        start_values=start,
        output=OUTS,
    ), h


def test_sk8_preset_reproduces_seed_001_and_the_closed_form_stroke(fmu_path):
    v = preset_values_from_fmu(fmu_path, "sk8-3.5-4000")
    A, C, I, HG, P, R = (
        v[k]
        for k in (
            "geometry.beam_front_arm",
            "geometry.beam_rear_arm",
            "geometry.pivot_dx",
            "geometry.pivot_dy",
            "geometry.rod_length",
            "geometry.crank_radius",
        )
    )
    res, h = fmpy_run(fmu_path, v, revolutions=1, n_per_rev=3600)
    K = math.hypot(I, HG)
    psi = lambda d: math.acos((C * C + K * K - d * d) / (2 * C * K))  # noqa: E731
    stroke = A * abs(psi(P + R) - psi(P - R))
    # The 0.1° grid misses the top by at most (0.05°)²·max|TF'|/2 ≈ 1e-6 m.
    assert abs(res["suspension.position"].max() - stroke) < 2e-6
    assert abs(res["suspension.position"].min()) < 2e-6
    # Seed 001 at the paper's two angles, through the FMU's input and the §3.2 angle mapping.
    from fmpy import simulate_fmu

    shift = math.pi / 2 - math.atan2(HG, I)
    w = v["crank.speed"]
    for phi1, printed, digits in [(37.51, 2.72, 2), (192.51, -1.4909, 4)]:
        th = math.radians(phi1) - shift
        sig = np.array(
            [(0.0, th, w), (1.0, th, w)],
            dtype=[("time", float), ("crank.angle", float), ("crank.speed", float)],
        )
        start = {k: x for k, x in v.items() if k != "crank.speed"}
        r = simulate_fmu(
            fmu_path,
            stop_time=1e-9,
            step_size=1e-9,
            input=sig,
            start_values=start,
            output=["suspension.acceleration"],
        )
        assert round(r["suspension.acceleration"][0], digits) == printed


def test_presets_ship_inside_the_fmu(fmu_path):
    with zipfile.ZipFile(fmu_path) as z:
        shipped = sorted(
            n for n in z.namelist() if n.startswith("resources/presets/") and n.endswith(".ssv")
        )
    assert shipped == sorted(f"resources/presets/{p}.ssv" for p in PRESETS)


SSV_NS = "{http://ssp-standard.org/SSP1/SystemStructureParameterValues}"


def _ssv_declarations(xml_bytes):
    """(name, type element, unit or None) of every parameter of an .ssv file, read with the
    standard library's XML parser (independent of reciprocating_drive.presets)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(xml_bytes)
    out = []
    for p in root.iter(f"{SSV_NS}Parameter"):
        (value,) = list(p)
        out.append((p.get("name"), value.tag.removeprefix(SSV_NS), value.get("unit")))
    return out


def _unit_mismatches(xml_bytes, md):
    declared = {v.name: v for v in md.modelVariables}
    bad = []
    for name, ty, unit in _ssv_declarations(xml_bytes):
        v = declared.get(name)
        if v is None:
            bad.append(f"{name}: not a variable of the FMU")
        elif ty != v.type:
            bad.append(f"{name}: ssv:{ty}, the model description says {v.type}")
        elif unit != v.unit:
            bad.append(f"{name}: unit {unit!r}, the model description says {v.unit!r}")
    return bad


@pytest.mark.parametrize("name", PRESETS)
def test_every_preset_unit_matches_the_model_description(fmu_path, model_description, name):
    """Issue: the presets gave link.lateral_load unit="m" where the FMU declares N. Every
    parameter of every preset (the repository's file and the copy shipped in the FMU) must name
    a variable of the FMU, with its type and exactly its declared unit (none where it has none)."""
    import pathlib

    repo_file = pathlib.Path(__file__).resolve().parents[2] / "resources" / "presets"
    with zipfile.ZipFile(fmu_path) as z:
        shipped = z.read(f"resources/presets/{name}.ssv")
    for xml_bytes in (shipped, (repo_file / f"{name}.ssv").read_bytes()):
        assert len(_ssv_declarations(xml_bytes)) > 50
        assert _unit_mismatches(xml_bytes, model_description) == []


def test_unit_check_catches_a_wrong_unit(model_description):
    """The check above is not vacuous: a preset line with a wrong or missing unit is reported."""
    doc = (
        b'<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
        b' version="1.0" name="x"><ssv:Parameters>'
        b'<ssv:Parameter name="link.lateral_load"><ssv:Real value="0" unit="m"/></ssv:Parameter>'
        b'<ssv:Parameter name="load.mean"><ssv:Real value="0"/></ssv:Parameter>'
        b'<ssv:Parameter name="mechanism"><ssv:Real value="1"/></ssv:Parameter>'
        b"</ssv:Parameters></ssv:ParameterSet>"
    )
    bad = _unit_mismatches(doc, model_description)
    assert [b.split(":")[0] for b in bad] == ["link.lateral_load", "load.mean", "mechanism"]
