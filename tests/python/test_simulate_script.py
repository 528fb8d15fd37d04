"""scripts/simulate.py (the work of scripts/run.sh): its CSV against the mpmath reference, a preset
read from an SSV file, and the error for an unknown preset. The summary it writes is checked
against closed forms in test_mission.py."""

from __future__ import annotations

import csv
import math

from reciprocating_drive.commands import simulate
from reference import OUTPUTS, Machine

SSV = """<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
                  version="1.0" name="small">
  <ssv:Parameters>
    <ssv:Parameter name="geometry.crank_radius"><ssv:Real value="0.1"/></ssv:Parameter>
    <ssv:Parameter name="geometry.rod_length"><ssv:Real value="0.45"/></ssv:Parameter>
    <ssv:Parameter name="geometry.slider_offset"><ssv:Real value="0.01"/></ssv:Parameter>
    <ssv:Parameter name="mass.reciprocating"><ssv:Real value="40"/></ssv:Parameter>
    <ssv:Parameter name="crank.angle_offset"><ssv:Real value="0.5"/></ssv:Parameter>
    <ssv:Parameter name="load.profile"><ssv:Integer value="0"/></ssv:Parameter>
    <ssv:Parameter name="crank.speed"><ssv:Real value="12.5"/></ssv:Parameter>
  </ssv:Parameters>
</ssv:ParameterSet>
"""


def read(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], [[float(x) for x in r] for r in rows[1:]]


def check_rows(header, rows, machine, omega, every=25):
    col = {h.split(" [")[0]: i for i, h in enumerate(header)}
    col["crank angle"] = header.index("crank angle [rad]")
    sc = machine.scales(omega)
    for r in rows[::every]:
        theta_in = r[col["crank angle"]] - machine.angle_offset
        assert abs(theta_in - omega * r[col["time"]]) < 1e-12
        assert (
            abs(math.degrees(r[col["crank angle"]]) - r[header.index("crank angle [deg]")]) < 1e-9
        )
        ref = machine.outputs(theta_in, omega)
        # The reference has no guide friction; the run's friction (checked against an independent
        # beam model in test_guide_friction.py) enters the rod force and the crank torque (§4).
        f_fr = r[col["link.friction_total"]]
        ref["rod.force"] += f_fr
        ref["crank.torque"] = -ref["rod.force"] * ref["kinematics.torque_factor"]
        for n in OUTPUTS:
            assert abs(r[col[n]] - ref[n]) <= 1e-9 * sc[n], (n, r[col["time"]])


def test_default_run_writes_csv_and_png(fmu_path, tmp_path):
    rc = simulate.main(
        [
            "default",
            "--fmu",
            fmu_path,
            "--out-dir",
            str(tmp_path),
            "--resources",
            str(tmp_path / "none"),
            "--revolutions",
            "1",
            "--step",
            "0.001",
        ]
    )
    assert rc == 0
    header, rows = read(tmp_path / "default.csv")
    period = 2 * math.pi / (2 * math.pi * 65 / 60)
    assert rows[-1][0] >= period  # at least one whole revolution
    for n, unit in simulate.CSV_OUTPUTS:
        assert f"{n} [{unit}]" in header
    check_rows(header, rows, Machine(), 2 * math.pi * 65 / 60)
    png = (tmp_path / "default.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000


def test_ssv_preset(fmu_path, tmp_path):
    res = tmp_path / "resources"
    res.mkdir()
    (res / "small.ssv").write_text(SSV)
    assert simulate.available_presets(res) == ["default", "small"]
    rc = simulate.main(
        [
            "small",
            "--fmu",
            fmu_path,
            "--out-dir",
            str(tmp_path),
            "--resources",
            str(res),
            "--revolutions",
            "1",
            "--step",
            "0.002",
        ]
    )
    assert rc == 0
    header, rows = read(tmp_path / "small.csv")
    assert rows[-1][0] >= 2 * math.pi / 12.5
    check_rows(
        header, rows, Machine(r=0.1, l=0.45, e=0.01, m=40.0, angle_offset=0.5), 12.5, every=10
    )


def test_unknown_preset_is_an_error(tmp_path, capsys):
    for name in ("nosuch", "../etc/passwd", ""):
        rc = simulate.main([name, "--out-dir", str(tmp_path), "--resources", str(tmp_path)])
        assert rc == 2
        assert "unknown preset" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
