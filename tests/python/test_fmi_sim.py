"""rust-fmi's `fmi-sim` 0.7.0 (crates.io), a second FMI 3.0 importer besides fmpy, installed by
scripts/test.sh into target/tools/ (scripts/lib/fmi_sim.sh): for every preset, its FMI 3.0
co-simulation run of ReciprocatingDrive-fmi3.fmu gives the outputs of fmpy's FMI 2.0
co-simulation run with the same inputs and parameters, and for the rigid presets its Model
Exchange run too (docs/fmi-interface.md "FMI 3.0").

fmi-sim 0.7.0 (its fmi-schema 0.8.0) refuses every FMI 3.0 model description whose Float64
variables carry a `unit` or `displayUnit` attribute, which FMI 3.0 allows ("unknown field "unit" in
element "FmiFloat64""): the test runs it on a copy of the FMU whose model description has those
two attributes removed, the binary and everything else unchanged (units are information for the
importer; no call of the FMU depends on them).

Skipped, with the reason, only when the installation failed (its log names why); a run of
scripts/test.sh without fmi-sim fails.
"""

from __future__ import annotations

import csv
import os
import pathlib
import re
import subprocess
import zipfile

import numpy as np
import pytest
from conftest import ROOT
from reciprocating_drive import preset_values

FMI_SIM = ROOT / "target" / "tools" / "bin" / "fmi-sim"
LOG = ROOT / "target" / "tools" / "fmi-sim-install.log"
PRESETS = ["default", "sk8-3.5-4000", "unb600a", "kvo630"]
RIGID = PRESETS[:3]


@pytest.fixture(scope="module")
def fmi_sim():
    if FMI_SIM.is_file():
        return FMI_SIM
    if LOG.is_file():
        last = [line for line in LOG.read_text().splitlines() if line.strip()][-1:]
        pytest.skip(f"cargo install fmi-sim 0.7.0 failed ({LOG}): {' '.join(last)}")
    msg = f"{FMI_SIM} not installed: scripts/test.sh installs it (scripts/lib/fmi_sim.sh)"
    if os.environ.get("CI") or os.environ.get("RD_REQUIRE_FMU"):
        pytest.fail(msg)
    pytest.skip(msg)


@pytest.fixture(scope="module")
def fmu3_for_fmi_sim(fmu_path, tmp_path_factory):
    """ReciprocatingDrive-fmi3.fmu with `unit` and `displayUnit` removed from its Float64
    variables (see the module doc), everything else byte for byte."""
    src = pathlib.Path(fmu_path).parent / "ReciprocatingDrive-fmi3.fmu"
    out = tmp_path_factory.mktemp("fmi-sim") / "ReciprocatingDrive-fmi3.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                for attr in ("unit", "displayUnit"):
                    text = re.sub(rf'(<Float64 [^>]*?) {attr}="[^"]*"', r"\1", text)
                data = text.encode()
            zout.writestr(item, data)
    return out


def _inputs(path, stop, h, omega):
    t = np.arange(0.0, stop + h / 2, h)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time", "crank.angle", "crank.speed"])
        for tk in t:
            w.writerow([repr(float(tk)), repr(float(omega * tk)), repr(float(omega))])
    return t


def _read(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], np.array(rows[1:], dtype=float)
    return {name: body[:, k] for k, name in enumerate(head)}


def _fmi_sim(fmi_sim, fmu, interface, values, inputs, out, stop, h):
    init = []
    for k, v in values.items():
        text = str(v).lower() if isinstance(v, bool) else repr(v) if isinstance(v, float) else v
        init += ["--init-values", f"{k}={text}"]
    cmd = [str(fmi_sim), "--model", str(fmu), "-i", str(inputs), "-o", str(out), interface]
    cmd += ["-s", "0", "-f", repr(stop), "--output-interval", repr(h), "-n", "0", "--step", repr(h)]
    p = subprocess.run(cmd + init, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    return _read(out)


def _case(name):
    values = dict(preset_values(name))
    values.pop("crank.angle", None)
    omega = float(values.pop("crank.speed", 2 * np.pi * 65 / 60))
    stop, h = (0.05, 2e-4) if name == "kvo630" else (1.0, 1e-3)
    return values, omega, stop, h


def _fmpy_cs(fmu_path, values, omega, stop, h, outputs):
    from fmpy import simulate_fmu

    t = np.arange(0.0, stop + h / 2, h)
    sig = np.zeros(len(t), dtype=[("time", float), ("crank.angle", float), ("crank.speed", float)])
    sig["time"], sig["crank.angle"], sig["crank.speed"] = t, omega * t, omega
    return simulate_fmu(
        fmu_path,
        stop_time=stop,
        output_interval=h,
        start_values=values,
        input=sig,
        output=outputs,
    )


@pytest.mark.parametrize(
    "name,interface",
    [(p, "co-simulation") for p in PRESETS] + [(p, "model-exchange") for p in RIGID],
)
def test_fmi_sim_fmi3_agrees_with_fmpy_fmi2_co_simulation(
    fmi_sim, fmu3_for_fmi_sim, fmu_path, tmp_path, name, interface
):
    """fmi-sim's FMI 3.0 run against fmpy's FMI 2.0 co-simulation, both fed crank.angle = ω·t,
    crank.speed = ω at the same points: the same binary through two standards and two importers,
    so the outputs agree to rounding (1e-12 of each output's scale; the elastic rod integrates
    with the same steps and tolerance). Model Exchange (fmi-sim's forward Euler) for the rigid
    presets only: their outputs are functions of the inputs, and the cage states stay 0; the
    explicit Euler of fmi-sim cannot integrate the elastic rod's stiff cage at a usable step."""
    values, omega, stop, h = _case(name)
    inputs = tmp_path / "in.csv"
    t = _inputs(inputs, stop, h, omega)
    got = _fmi_sim(
        fmi_sim, fmu3_for_fmi_sim, interface, values, inputs, tmp_path / "out.csv", stop, h
    )
    outputs = [n for n in got if n != "time"]
    assert "crank.torque" in outputs and len(got["time"]) == len(t)
    assert np.allclose(got["time"], t, rtol=0, atol=1e-9)
    ref = _fmpy_cs(fmu_path, values, omega, stop, h, outputs)
    assert len(ref) == len(t)
    worst = 0.0
    for n in outputs:
        scale = max(np.max(np.abs(ref[n])), 1e-300)
        d = np.max(np.abs(got[n] - ref[n])) / scale
        worst = max(worst, d)
        assert d <= 1e-12, f"{n}: fmi-sim {interface} and fmpy differ by {d:.3g} of its scale"
    print(f"{name} {interface}: fmi-sim FMI 3.0 vs fmpy FMI 2.0, worst {worst:.2g} of scale")
    assert np.ptp(ref["suspension.position"]) > 0
