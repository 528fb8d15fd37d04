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
from reciprocating_drive.twin.sample import CYCLE, OMEGA0


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
    from reciprocating_drive.twin.core import SUMMARY_FIELDS

    k = SUMMARY_FIELDS.index("interrupted")  # `revs` rows: SUMMARY_FIELDS (the run dropped)
    assert [r[k] for r in revs].count(1) == 3  # one interrupted revolution per cycle
    ev = [e for e in pu.events(db, "cycles") if e[1].startswith("machine_")]
    assert [e[1] for e in ev] == ["machine_stopped", "machine_started"] * 3
    period = sum(CYCLE)
    stop = 2 * (2 * math.pi / 60) / OMEGA0  # 1 rpm on the 2 s ramps
    for c in range(3):
        t_stop = float(ev[2 * c][3].split("t = ")[1].split(" s")[0])
        t_start = float(ev[2 * c + 1][3].split("t = ")[1].split(" s")[0])
        assert t_stop == pytest.approx(c * period + 8 - stop, abs=0.05)
        assert t_start == pytest.approx(c * period + 14 + stop, abs=0.05)


def test_the_page_shows_the_machine_state(fmu_path, tmp_path):
    """The page following the plant's database: the machine's state and since when, from its
    events (stopped at 7.97 s, running again from 14.03 s, docs/plant.md "Machine states"); with a
    stop/start cycle cut in its standstill, 'stopped since'."""
    import time

    from reciprocating_drive.page.follow import Follower
    from reciprocating_drive.page.server import PageServer

    data = stop_cycle.write(tmp_path / "cycles.csv", 1)
    lines = data.read_text().splitlines()
    cut = tmp_path / "cut.csv"
    cut.write_text("\n".join(lines[:11002]) + "\n")  # to t = 11 s: at rest since 7.97 s
    stop = 2 * (2 * math.pi / 60) / OMEGA0
    for path, state, since in ((data, "running", 14 + stop), (cut, "stopped", 8 - stop)):
        db = tmp_path / f"{path.stem}.sqlite"
        cfg = pu.write_config(
            tmp_path / f"{path.stem}.toml",
            run=path.stem,
            source=pu.csv_source(path),
            sinks=pu.sqlite_sink(db),
            fmu=fmu_path,
        )
        assert pu.run(cfg).returncode == 0
        page = PageServer(port=0, database=str(db)).start()
        try:
            follower = Follower(str(db), page, warmup=1e9)
            follower.poll()
            time.sleep(0.4)
            m = page.state.snapshot()["health"]["machine"]
            assert m["state"] == state and m["since"] == pytest.approx(since, abs=0.05), m
            follower.close()
        finally:
            page.close()


@pytest.mark.parametrize(
    "script,args,words",
    [
        ("plc_sim.py", ["--stop-cycle", "0"], ["--stop-cycle 0", "whole number >= 1"]),
        (
            "twin_plant.py",
            ["--config", "x.toml", "--stop-cycle", "2"],
            ["--stop-cycle 2", "--demo"],
        ),
    ],
)
def test_a_bad_stop_cycle_option_is_one_line(script, args, words):
    import subprocess
    import sys

    p = subprocess.run(
        [sys.executable, str(pu.ROOT / "scripts" / script), *args],
        capture_output=True,
        text=True,
        timeout=60,
        env=pu.env(),
    )
    assert p.returncode == 2, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr
    for w in words:
        assert w in p.stderr, p.stderr
