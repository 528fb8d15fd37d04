"""The closed loop (docs/closed-loop.md "A whole pump on the drive train") runs a multi-cylinder
pump given by `--pump`, its pressures held as start values of the unconnected inputs.

What is checked, independently of the FMU's code: the number of torque pulses per revolution the
drive train feels. Each chamber that delivers against the discharge pressure loads the crank once
per revolution, with a torque pulse centred on its delivery stroke; chambers whose delivery strokes
are spread over the revolution (their cylinders' phases distinct modulo half a turn) give one
maximum of the crank torque each, so the count is Σ acting_k over the cylinders: a duplex
double-acting pump at 90° 4, a triplex single-acting one at 120° 3; two double-acting cylinders in
phase pulse together, 2. Maxima are counted with scipy's find_peaks at a prominence of 10 % of the
torque's range (the loop's speed ripple and the crossheads' inertia add small wiggles, not pulses)
over the last three complete revolutions of the crank angle the drive train computes. The crank's
work over them is the fluid's, the discharge pressure times the volume displaced.
"""

from __future__ import annotations

import csv
import json
import math
import pathlib

import numpy as np
import pytest
from pump_presets import pump, write_ssv
from reciprocating_drive.commands import closed_loop
from scipy.signal import find_peaks

CASES = [
    ("duplex_90", 2, 2, [0.0, math.pi / 2], 4),
    ("triplex_120", 3, 1, [0.0, 2 * math.pi / 3, 4 * math.pi / 3], 3),
    ("duplex_in_phase", 2, 2, [0.0, 0.0], 2),
]


#: The trapezoids over ~1 ms samples, the window's ends between samples and the speed ripple
#: (measured: 1.3e-5 to 3e-4 of the work).
RTOL = 2e-3


@pytest.mark.parametrize("name, n, acting, phases, pulses", CASES)
def test_torque_pulses_per_revolution(fmu_path, tmp_path, name, n, acting, phases, pulses):
    # 4 MPa against a drive of 10x the shipped motor's breakdown torque (2000 N·m, 46 kN·m at the
    # crank): a mean crank torque of about 13 kN·m for the duplex, with the pulses well resolved.
    values = pump(
        n,
        acting,
        phases,
        **{"fluid_end.discharge_pressure": 4e6, "fluid_end.suction_pressure": 0.0},
    )
    values["guide.velocity_scale"] = 1e-3
    ssv = write_ssv(tmp_path / f"{name}.ssv", values)
    args = ["--importer", "fmpy", "--pump", str(ssv), "--time", "6", "--out-dir", str(tmp_path)]
    args += [
        "--fmu-dir",
        str(pathlib.Path(fmu_path).parent),
        "--set",
        "drivetrain.motor.breakdown_torque=2000",
    ]
    assert closed_loop.main(args) == 0
    summary = json.loads((tmp_path / "closed_loop.json").read_text())
    assert summary["parameters"]["pump"]["fluid_end.cylinders"] == n
    with open(tmp_path / "closed_loop.csv") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    data = np.array(rows[1:], dtype=float)
    col = {h.split(" [")[0]: i for i, h in enumerate(head)}
    theta = data[:, col["drivetrain.crank.angle"]]
    torque = data[:, col["pump.crank.torque"]]
    k_end = math.floor(theta[-1] / (2 * math.pi))
    assert k_end >= 4, "the run must hold the three revolutions counted"
    peaks, _ = find_peaks(torque, prominence=0.1 * (torque.max() - torque.min()))
    lo, hi = 2 * math.pi * (k_end - 3), 2 * math.pi * k_end
    counted = [p for p in peaks if lo <= theta[p] < hi]
    assert len(counted) == 3 * pulses, (len(counted), np.degrees(theta[counted]) % 360)
    # The pressures did act: the crank's work over the three revolutions is the fluid's,
    # 4 MPa times the volume displaced, Σ (A_h + A_c)·2r per revolution (no friction; the
    # crossheads' kinetic energy returns to nearly its value a whole number of turns later).
    m = (theta >= lo) & (theta < hi)
    work = np.trapezoid(torque[m], theta[m])
    area = math.pi / 4 * 0.13**2 * acting
    expected = 3 * 4e6 * n * area * 2 * values.get("geometry.crank_radius", 0.2)
    assert work == pytest.approx(expected, rel=RTOL)


@pytest.mark.parametrize(
    "args, words",
    [
        (["--pump", "nope"], "--pump 'nope': no such preset; allowed: default,"),
        (["--pump", "BAD"], "--pump '"),
        (["--set", "pump.fluid_end.discharge_pressure=abc"], "allowed: a number"),
    ],
)
def test_bad_pump_options_are_one_line(fmu_path, tmp_path, capsys, args, words):
    bad = tmp_path / "bad.ssv"
    bad.write_text("<x/>\n")
    args = [str(bad) if a == "BAD" else a for a in args]
    fmu_dir = str(pathlib.Path(fmu_path).parent)
    code = closed_loop.main(
        ["--importer", "fmpy", "--fmu-dir", fmu_dir, "--out-dir", str(tmp_path), *args]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and words in err, err
    assert not (tmp_path / "closed_loop.csv").exists()
