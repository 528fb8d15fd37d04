"""A pump's pressures over OPC UA (docs/plant.md "OPC UA source": source.discharge_node,
source.suction_node) from the simulated PLC (scripts/plc_sim.py plays a data file's
discharge_pressure and suction_pressure columns on Pump.DischargePressure, Pump.SuctionPressure
and their Pump.Block arrays), both as real processes on 127.0.0.1. The reference is the same file
through the twin's core with its pressure columns: a source that joins each pressure to its sample
gives the same revolutions bit for bit, in scalar and in block mode; and the mean hydraulic power
of a revolution is (p_d − p_s)·Q at each sample averaged, bounded by the pressures' extremes times
the mean flow."""

from __future__ import annotations

import math

import plant_util as pu
from pump_presets import pump, write_ssv

SPEED = "4"
START_DELAY = "2"


def data_with_pressures(path):
    """The shipped encoder sample with a discharge pressure of 10 MPa ± 0.5 MPa at 0.7 Hz and a
    suction pressure of 0.2 MPa."""
    lines = pu.SAMPLE.read_text().splitlines()
    out = [lines[0] + ",discharge_pressure,suction_pressure"]
    for line in lines[1:]:
        t = float(line.split(",")[0])
        pd = 10e6 + 0.5e6 * math.sin(2 * math.pi * 0.7 * t)
        out.append(f"{line},{pd!r},200000.0")
    path.write_text("\n".join(out) + "\n")
    return path


def test_pressure_nodes_give_the_file_replay_bit_for_bit(fmu_path, tmp_path):
    from reciprocating_drive.twin import SUMMARY_FIELDS, Options, Twin

    machine = pump(2, 2, [0.0, math.pi / 2], **{"guide.velocity_scale": 0.02})
    machine.update({"fluid_end.discharge_pressure": 1e6, "fluid_end.suction_pressure": 0.0})
    machine.pop("crank.speed")
    ssv = write_ssv(tmp_path / "duplex.ssv", machine)
    data = data_with_pressures(tmp_path / "data.csv")
    tw = Twin(fmu_path, str(ssv), Options(angle_unit="counts", counts_per_rev=4096))
    _, sums = tw.feed(data.read_text().splitlines(), 1)
    _, more = tw.finish()
    ref = [tuple(s[k] for k in SUMMARY_FIELDS) for s in sums + more]
    assert len(ref) > 5
    plc = pu.PlcProcess("--speed", SPEED, "--start-delay", START_DELAY, data=data)
    procs = {}
    for mode in ("scalar", "block"):
        block = "Block." if mode == "block" else ""
        source = (
            f'type = "opcua"\nendpoint = "{plc.endpoint}"\nmode = "{mode}"\n'
            f'angle_node = "ns=2;s=Pump.{block}CrankAngle"\nend_node = "ns=2;s=Pump.Finished"\n'
            f'discharge_node = "ns=2;s=Pump.{block}DischargePressure"\n'
            f'suction_node = "ns=2;s=Pump.{block}SuctionPressure"\n'
            'angle_unit = "counts"\ncounts_per_rev = 4096\nreconnect_max = 0.5\n'
        )
        if mode == "block":
            source += 'time_node = "ns=2;s=Pump.Block.Time"\n'
        cfg = pu.write_config(
            tmp_path / f"{mode}.toml",
            run=mode,
            source=source,
            sinks=pu.sqlite_sink(tmp_path / f"{mode}.sqlite"),
            fmu=fmu_path,
            run_extra=f'machine = "{ssv}"\n',
        )
        procs[mode] = pu.start(cfg)
    try:
        with plc:
            outs = {m: p.communicate(timeout=90) for m, p in procs.items()}
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
                p.wait(timeout=10)
    for mode, p in procs.items():
        assert p.returncode == 0, outs[mode][1]
        got = [r[1:] for r in pu.revolutions(tmp_path / f"{mode}.sqlite", mode)]
        assert got == ref, mode
    i_q, i_h = SUMMARY_FIELDS.index("flow_mean"), SUMMARY_FIELDS.index("hydraulic_power_mean")
    for r in ref:
        if r[i_q] is not None:
            assert 9.3e6 * r[i_q] < r[i_h] < 10.3e6 * r[i_q]
