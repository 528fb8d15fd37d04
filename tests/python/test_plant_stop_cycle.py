"""`rdrive plant` over OPC UA with the simulated PLC playing three stop/start cycles
(`plc_sim.py --stop-cycle 3`: ramp down, a 2° rollback, an encoder dithering at standstill, ramp
up; docs/plant.md "Machine states"). The reference is the file replay of the same cycles through
the twin's core: the run finishes (exit 0, status finished), every sample is stored, with the same
outputs bit for bit and the same revolution summaries, and the machine's stops and starts are
events at the times of the closed form."""

from __future__ import annotations

import math

import plant_util as pu
import pytest
from reciprocating_drive.plant import stop_cycle
from reciprocating_drive.twin_sample import CYCLE, OMEGA0


def test_plant_through_three_stop_start_cycles_over_opcua(fmu_path, tmp_path):
    data = stop_cycle.write(tmp_path / "cycles.csv", 3)
    ref_s, ref_r, _ = pu.clean_run(fmu_path, path=data)
    plc = pu.PlcProcess("--stop-cycle", "3", "--speed", "8", "--start-delay", "2")
    source = (
        f'type = "opcua"\nendpoint = "{plc.endpoint}"\nmode = "scalar"\n'
        'angle_node = "ns=2;s=Pump.CrankAngle"\nend_node = "ns=2;s=Pump.Finished"\n'
        'angle_unit = "counts"\ncounts_per_rev = 4096\nreconnect_max = 0.5\n'
    )
    cfg = pu.write_config(
        tmp_path / "c.toml",
        run="cycles",
        source=source,
        sinks=pu.sqlite_sink(tmp_path / "c.sqlite"),
        fmu=fmu_path,
    )
    p = pu.start(cfg)
    try:
        with plc:
            out, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 0, err
    db = tmp_path / "c.sqlite"
    assert pu.query(db, "SELECT status FROM runs WHERE name = 'cycles'") == [("finished",)]
    got = pu.samples(db, "cycles")
    assert len(got) == len(ref_s) == 3 * 22000 + 1
    assert pu.same_values(got, ref_s, sqlite=True)
    revs = [r[1:] for r in pu.revolutions(db, "cycles")]
    assert revs == ref_r
    assert [r[-1] for r in revs].count(1) == 3  # one interrupted revolution per cycle
    ev = [e for e in pu.events(db, "cycles") if e[1].startswith("machine_")]
    assert [e[1] for e in ev] == ["machine_stopped", "machine_started"] * 3
    period = sum(CYCLE)
    stop = 2 * (2 * math.pi / 60) / OMEGA0  # 1 rpm on the 2 s ramps
    for c in range(3):
        t_stop = float(ev[2 * c][3].split("t = ")[1].split(" s")[0])
        t_start = float(ev[2 * c + 1][3].split("t = ")[1].split(" s")[0])
        assert t_stop == pytest.approx(c * period + 8 - stop, abs=0.05)
        assert t_start == pytest.approx(c * period + 14 + stop, abs=0.05)
