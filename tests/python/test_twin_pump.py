"""The twin of a pump (docs/twin.md "Input", "Output"): the discharge and suction pressures come
from CSV columns (or, absent, from the machine), and each revolution's summary gives the mean flow,
its pulsation and the mean hydraulic and mechanical powers. Checked against closed forms that do
not use the FMU's or the twin's code:

* mean flow = displaced volume per revolution × revolutions per second, less the tanh transition's
  deficit (π²/24)·v_ε²/(r²ω²(1 − λ²)) (tests/python/test_sweep_pump.py derives it); the crank
  turns at a constant speed, which the twin's local cubic recovers exactly from the angle: 1e-6;
* hydraulic power = (p_d − p_s)·Q at every sample, so its mean is (p_d − p_s)·Q_mean: 1e-9;
* without friction the crank's mean power equals the fluid's over a revolution: 1e-5
  (trapezoids over 960 samples per revolution at the torque's kinks);
* the duplex's pulsation in the textbook limit (r/l = 1e-6, no rod): (√2 − 1)·π/4, 1e-5 (the
  samples fall on its extremes at the dead centres and at 45°);
* the pressures are those of the columns, not the machine's: the machine says 1 MPa, the columns
  10 MPa and 0.2 MPa; without the columns the machine's 1 MPa acts.
"""

from __future__ import annotations

import csv
import math

import pytest
from pump_presets import pump, write_ssv
from reciprocating_drive.commands import twin as twin_cmd

R, L, D, D_ROD = 0.2, 1.19, 0.13, 0.07
W = 2 * math.pi / 0.96  # one revolution in 0.96 s: 960 samples of 1 ms, one every 0.375°


def write_input(path, pressures: bool, revolutions: int = 5):
    n = int(round(revolutions * 0.96 / 1e-3)) + 1
    with open(path, "w") as f:
        f.write(
            "time,crank_angle" + (",discharge_pressure,suction_pressure\n" if pressures else "\n")
        )
        for k in range(n):
            t = k * 1e-3
            a = math.remainder(W * t, 2 * math.pi)
            f.write(f"{t!r},{a!r}" + (",10e6,0.2e6\n" if pressures else "\n"))


def summaries(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return [{k.split(" [")[0]: (float(v) if v else None) for k, v in r.items()} for r in rows]


def run_twin(tmp_path, machine: dict, pressures: bool):
    ssv = write_ssv(tmp_path / "duplex.ssv", machine)
    write_input(tmp_path / "in.csv", pressures)
    out = tmp_path / "out.csv"
    args = [str(tmp_path / "in.csv"), "--machine", str(ssv), "--out", str(out)]
    assert twin_cmd.main(args) == 0
    sums = summaries(tmp_path / "out-revolutions.csv")
    assert len(sums) >= 3
    return sums[1:]  # whole revolutions of a steady crank


def machine(**extra):
    v = pump(2, 2, [0.0, math.pi / 2], **{"guide.velocity_scale": 0.02, **extra})
    v.update({"fluid_end.discharge_pressure": 1e6, "fluid_end.suction_pressure": 0.0})
    v.update({"geometry.crank_radius": R, "geometry.rod_length": L})
    for k in (1, 2):
        v[f"cylinder_{k}.rod_diameter"] = D_ROD
    return v


@pytest.mark.parametrize("columns", [True, False])
def test_pressures_flow_and_powers(fmu_path, tmp_path, columns):
    m = machine()
    lam, ve = R / L, m["guide.velocity_scale"]
    volume = 2 * math.pi / 4 * (2 * D * D - D_ROD * D_ROD) * 2 * R
    deficit = math.pi**2 / 24 * ve**2 / (R * R * W * W * (1 - lam * lam))
    q = volume * W / (2 * math.pi) * (1 - deficit)
    dp = 10e6 - 0.2e6 if columns else 1e6
    for s in run_twin(tmp_path, m, columns):
        assert s["flow_mean"] == pytest.approx(q, rel=1e-6)
        assert s["hydraulic_power_mean"] == pytest.approx(dp * s["flow_mean"], rel=1e-9)
        assert s["mechanical_power_mean"] == pytest.approx(dp * q, rel=1e-5)
        assert s["flow_pulsation"] > 0


def test_pulsation_in_the_textbook_limit(fmu_path, tmp_path):
    m = machine()
    m.update(
        {"geometry.crank_radius": 1e-3, "geometry.rod_length": 1e3, "guide.velocity_scale": 1e-9}
    )
    for k in (1, 2):
        m[f"cylinder_{k}.rod_diameter"] = 0.0
    for s in run_twin(tmp_path, m, True):
        assert s["flow_pulsation"] == pytest.approx((math.sqrt(2) - 1) * math.pi / 4, rel=1e-5)


def test_bad_pressure_field_is_one_line(fmu_path, tmp_path, capsys):
    ssv = write_ssv(tmp_path / "duplex.ssv", machine())
    (tmp_path / "in.csv").write_text(
        "time,crank_angle,discharge_pressure\n0,0,1e6\n0.001,0.007,abc\n"
    )
    args = [str(tmp_path / "in.csv"), "--machine", str(ssv), "--out", str(tmp_path / "o.csv")]
    assert twin_cmd.main(args) == 1
    err = capsys.readouterr().err
    assert "line 3: discharge_pressure = 'abc' is not a number" in err, err


def test_the_pages_pump_limits_watch_the_twins_summaries(fmu_path, tmp_path):
    """docs/page.md's limits of a pump: a 10 MPa duplex (pulsation ~0.65, 19.7 L/s) raises
    neither; with the second crank in phase with the first (pulsation ≥ π/2 > 0.9) the
    pulsation alarm rises after its delay of 3 revolutions."""
    import re

    from conftest import ROOT
    from reciprocating_drive.alarms import AlarmEngine, parse_limits
    from reciprocating_drive.cli_errors import read_toml

    page = (ROOT / "docs" / "page.md").read_text()
    block = re.search(r"```toml\n(\[\[limit\]\]\nvalue = \"flow_pulsation\".*?)```", page, re.S)
    (tmp_path / "limits.toml").write_text(block.group(1))
    limits = parse_limits(read_toml(tmp_path / "limits.toml"), "limits.toml")
    for phase, raised in ((math.pi / 2, False), (0.0, True)):
        engine = AlarmEngine(limits)
        m = machine(**{"cylinder_2.phase": phase})
        d = tmp_path / f"p{phase:.1f}"
        d.mkdir()
        sums = run_twin(d, m, True)
        changes = [c for s in sums for c in engine.update(s)]
        assert bool(changes) == raised, (phase, [s["flow_pulsation"] for s in sums])
        if raised:
            assert changes[0].name == "flow_pulsation.limit"


def test_the_page_shows_a_pumps_values(fmu_path, tmp_path, server, page_of):  # noqa: F811
    """The live page (headless Chromium) shows a pump's mean flow, pulsation and powers of the
    last revolution, bit for bit as the database holds them; for a machine that is no pump it
    leaves them out (test_page.py's machine shows exactly its seven values)."""
    import time

    from test_page import Database, Feed, sample_lines, shown, wait_ready

    db = Database(tmp_path / "twin.sqlite")
    page = server(database=db.path)
    extra = {k: v for k, v in machine().items() if not k.startswith("crank.")}
    feed = Feed(fmu_path, page, db, extra=extra)
    page.open(feed.twin.outputs, time_origin=None, elastic=False, pump=True)
    feed.feed(sample_lines(0, 4, 0.0))
    time.sleep(0.3)
    tab = page_of()
    tab.goto(page.url)
    wait_ready(tab)
    keys = ("flow_mean", "flow_pulsation", "hydraulic_power_mean", "mechanical_power_mean")
    row = db.db.execute(
        f"SELECT {', '.join(keys)} FROM revolutions ORDER BY revolution DESC LIMIT 1"
    ).fetchone()
    got = shown(tab)
    assert {k: float(got[k]) for k in keys} == dict(zip(keys, row))
    assert row[2] > 0 and row[1] > 0
    assert "stress_max" not in got  # a rigid rod
    assert not tab.errors, tab.errors


def test_distributed_replay_of_the_pressure_columns_is_the_sequential_one(fmu_path, tmp_path):
    """The distributed replay (Dask LocalCluster, pieces of 2 revolutions) of an input with its
    pressure columns, from the CSV file and from an SQLite table of the same samples, writes the
    sequential twin's files byte for byte."""
    ssv = write_ssv(tmp_path / "duplex.ssv", machine())
    write_input(tmp_path / "in.csv", True, revolutions=8)
    base = [str(tmp_path / "in.csv"), "--machine", str(ssv)]
    assert twin_cmd.main([*base, "--out", str(tmp_path / "seq.csv")]) == 0
    dist = ["--distributed", "--workers", "2", "--quiet", "--revolutions-per-piece", "2"]
    assert twin_cmd.main([*base, "--out", str(tmp_path / "dist.csv"), *dist]) == 0
    # The same samples as an SQLite table (REAL columns named as the CSV's).
    import sqlite3

    rows = [line.split(",") for line in (tmp_path / "in.csv").read_text().splitlines()]
    db = sqlite3.connect(tmp_path / "in.sqlite")
    db.execute(f"CREATE TABLE samples ({', '.join(f'{c} REAL' for c in rows[0])})")
    db.executemany(
        f"INSERT INTO samples VALUES ({', '.join('?' * len(rows[0]))})",
        [[float(x) for x in r] for r in rows[1:]],
    )
    db.commit()
    db.close()
    table = [str(tmp_path / "in.sqlite"), "--machine", str(ssv)]
    assert twin_cmd.main([*table, "--out", str(tmp_path / "table.csv"), *dist]) == 0
    for name in ("{}.csv", "{}-revolutions.csv"):
        seq = (tmp_path / name.format("seq")).read_bytes()
        assert (tmp_path / name.format("dist")).read_bytes() == seq, name
        assert (tmp_path / name.format("table")).read_bytes() == seq, name
    assert seq.count(b"\n") > 3  # the revolutions of the run


# The page's fixtures (headless Chromium, a page server) from its own tests.
from test_page import browser, chromium, page_of, server  # noqa: E402, F401
