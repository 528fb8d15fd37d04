"""Timestamps as data (docs/plant.md "Timestamps", "Sample assembly", "Final status"): the OPC UA
source against the simulated PLC playing the behaviours of other PLCs (a clock glitch, a clock
step back, a late duplicate, constant speed and force, values of one sample stamped apart). Each
run must end `finished` with every sample the PLC wrote either stored or counted in a `dropped`
event, and the stored rows must be the expected ones: the clean run of the data without the
dropped samples, bit for bit, or the expected sample times."""

from __future__ import annotations

import math
import subprocess

import numpy as np
import plant_util as pu
import pytest

N = 11801  # samples in data/twin/pump_encoder.csv


def _source(endpoint, extra="") -> str:
    return (
        f'type = "opcua"\nendpoint = "{endpoint}"\nmode = "scalar"\n'
        'angle_node = "ns=2;s=Pump.CrankAngle"\nend_node = "ns=2;s=Pump.Finished"\n'
        "reconnect_max = 0.5\n" + extra
    )


def _run(tmp_path, fmu_path, name, plc_args, extra="", data=pu.SAMPLE, units=True):
    plc = pu.PlcProcess("--speed", "4", "--start-delay", "2", *plc_args, data=data)
    unit = 'angle_unit = "counts"\ncounts_per_rev = 4096\n' if units else ""
    cfg = pu.write_config(
        tmp_path / f"{name}.toml",
        run=name,
        source=_source(plc.endpoint, unit + extra),
        sinks=pu.sqlite_sink(tmp_path / f"{name}.sqlite"),
        fmu=fmu_path,
    )
    p = pu.start(cfg)
    try:
        with plc:
            out, err = p.communicate(timeout=90)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    db = tmp_path / f"{name}.sqlite"
    return subprocess.CompletedProcess(p.args, p.returncode, out, err), db


def _dropped(db, name) -> dict:
    out: dict = {}
    for _seq, kind, count, msg in pu.events(db, name):
        if kind == "dropped":
            why = msg.split("dropped: ", 1)[1].split(" (first at")[0]
            out[why] = out.get(why, 0) + count
    return out


SAME = "duplicate timestamp, same values"


def _accounted(p, db, name, written=N):
    """finished, exit 0, and every sample written either stored or counted as dropped for a
    reason. A sample delivered twice with the same values (the subscription and the history
    after a reconnection both give it) is counted as a duplicate on top."""
    assert p.returncode == 0, p.stderr
    assert pu.query(db, "SELECT status FROM runs")[0][0] == "finished"
    stored = len(pu.samples(db, name))
    drops = _dropped(db, name)
    assert stored + sum(v for k, v in drops.items() if k != SAME) == written, (stored, drops)
    assert f"{stored} samples stored, {sum(drops.values())} dropped" in p.stderr, p.stderr
    drops.pop(SAME, None)
    return stored, drops


@pytest.fixture(scope="module")
def reference(fmu_path):
    return pu.clean_run(fmu_path)


def _without(fmu_path, tmp_path, skip: set, path=pu.SAMPLE, counts=True):
    """The clean run of the data file without the samples (0-based) in `skip`."""
    lines = pathlib_read(path)
    kept = [lines[0]] + [x for i, x in enumerate(lines[1:]) if i not in skip]
    f = tmp_path / "without.csv"
    f.write_text("\n".join(kept) + "\n")
    return pu.clean_run(fmu_path, f, counts=counts)


def pathlib_read(path):
    import pathlib

    return pathlib.Path(path).read_text().splitlines()


def test_one_sample_stamped_a_day_ahead_is_dropped_and_the_rest_stored(fmu_path, tmp_path):
    p, db = _run(tmp_path, fmu_path, "glitch", ["--clock-glitch", "2000:86400"])
    stored, drops = _accounted(p, db, "glitch")
    assert stored == N - 1 and len(drops) == 1 and "glitch of the PLC clock" in next(iter(drops))
    ev = pu.events(db, "glitch")
    assert sum(e[1] == "clock_jump" for e in ev) == 1, ev
    ref = _without(fmu_path, tmp_path, {2000})
    assert pu.same_values(pu.samples(db, "glitch"), ref[0], sqlite=True)


def test_initial_value_stamped_by_another_clock_is_a_glitch_not_a_day_of_gap(fmu_path, tmp_path):
    # The first sample an hour ahead (a server stamping initial values with its own clock).
    p, db = _run(tmp_path, fmu_path, "first", ["--clock-glitch", "0:3600"])
    stored, drops = _accounted(p, db, "first")
    assert stored == N - 1, drops
    assert not [e for e in pu.events(db, "first") if e[1] == "gap" and "3600" in e[3]]


def test_clock_step_back_drops_counted_and_goes_on_after_a_gap(fmu_path, tmp_path, reference):
    step, at = 0.5, 3000
    p, db = _run(tmp_path, fmu_path, "back", ["--clock-step", f"{at}:{step}"])
    stored, drops = _accounted(p, db, "back")
    ev = pu.events(db, "back")
    assert sum(e[1] == "clock_jump" and "stepped back" in e[3] for e in ev) == 1, ev
    # The rule (docs/plant.md "Timestamps"): samples stamped before the last one handed out are
    # dropped, and after it until the clock passes it by more than gap_limit (0.05 s).
    t = reference[0][:, 1]
    us = np.array([round(x * 1e6) for x in t])
    stamped = us.copy()
    stamped[at:] -= round(step * 1e6)
    keep = np.ones(N, bool)
    keep[at:] = stamped[at:] > stamped[at - 1] + 50_000
    got = pu.samples(db, "back")[:, 1]
    assert np.array_equal(got, stamped[keep] / 1e6), (len(got), keep.sum())
    assert len(got) < N - math.floor(step / 0.00102)
    gaps = [e for e in ev if e[1] == "gap"]
    assert any("re-initialized" in e[3] for e in gaps), gaps


def _step_rule(reference, at, step):
    """The sample times the rule keeps (docs/plant.md "Timestamps"): samples stamped before the
    last one handed out are dropped, and after it until the clock passes it by more than
    gap_limit (0.05 s)."""
    us = np.array([round(x * 1e6) for x in reference[0][:, 1]])
    stamped = us.copy()
    stamped[at:] -= round(step * 1e6)
    keep = np.ones(N, bool)
    keep[at:] = stamped[at:] > stamped[at - 1] + 50_000
    return stamped[keep] / 1e6


@pytest.mark.parametrize("outage_at", [3.3, 2.99])
def test_clock_step_back_across_an_outage_is_one_jump_each_sample_counted_once(
    fmu_path, tmp_path, reference, outage_at
):
    # The endpoint closes 0.3 s (1.2 s of data at 4x) after the step (3.3 s) or just before it
    # (2.99 s): the samples around the step come back from the server's history, which must
    # show the step as the live samples would (not sorted by time, which hides it), and from
    # before the last sample handed out (or a step during the outage is not in it at all).
    # Each sample is stored or counted once (one dropped live and read back again is a
    # same-values duplicate, not a second drop for its reason).
    step, at = 0.5, 3000
    name = f"outage{round(outage_at * 100)}"
    p, db = _run(
        tmp_path, fmu_path, name, ["--clock-step", f"{at}:{step}", "--outage", f"{outage_at}:0.3"]
    )
    stored, drops = _accounted(p, db, name)
    ev = pu.events(db, name)
    assert any(e[1] == "reconnect" and "history" in e[3] for e in ev), ev
    assert sum(e[1] == "clock_jump" and "stepped back" in e[3] for e in ev) == 1, ev
    got = pu.samples(db, name)[:, 1]
    want = _step_rule(reference, at, step)
    assert np.array_equal(got, want), (len(got), len(want))
    assert any(e[1] == "gap" and "re-initialized" in e[3] for e in ev), ev


@pytest.mark.parametrize(
    "kind, reason",
    [
        ("same", "duplicate timestamp, same values"),
        ("other", "duplicate timestamp with other values (the first kept)"),
    ],
)
def test_late_duplicate_is_dropped_counted_and_named(fmu_path, tmp_path, reference, kind, reason):
    p, db = _run(tmp_path, fmu_path, f"dup{kind}", ["--duplicate", f"1000:{kind}"])
    # The PLC wrote N samples and one more value of the angle.
    written = N if kind == "same" else N + 1
    stored, drops = _accounted(p, db, f"dup{kind}", written=written)
    assert stored == N and drops == ({} if kind == "same" else {reason: 1}), drops
    assert reason in {
        e[3].split("dropped: ")[1].split(" (first")[0]
        for e in pu.events(db, f"dup{kind}")
        if e[1] == "dropped"
    }
    assert pu.same_values(pu.samples(db, f"dup{kind}"), reference[0], sqlite=True)


def _constant_data(path):
    """12 s at 1 kHz of a crank at a constant 6.8 rad/s: speed constant, the process force 0,
    then 20 kN from 4 s to 8 s, then 0 again (both nodes constant for seconds)."""
    w = 6.8
    lines = ["time,crank_angle,crank_speed,process_force"]
    for i in range(12000):
        t = i / 1000
        f = 20000.0 if 4 <= t < 8 else 0.0
        lines.append(f"{t!r},{math.fmod(w * t, 2 * math.pi)!r},{w!r},{f!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("apart_us", [0, 1, 300])
def test_constant_speed_and_force_and_stamps_apart_give_the_file_replay(
    fmu_path, tmp_path, apart_us
):
    data = _constant_data(tmp_path / "constant.csv")
    nodes = 'speed_node = "ns=2;s=Pump.CrankSpeed"\nforce_node = "ns=2;s=Pump.ProcessForce"\n'
    p, db = _run(
        tmp_path,
        fmu_path,
        "const",
        ["--stamp-apart", str(apart_us)],
        extra=nodes,
        data=data,
        units=False,
    )
    stored, drops = _accounted(p, db, "const", written=12000)
    ref = pu.clean_run(fmu_path, data, counts=False)
    assert stored == 12000 and not drops, drops
    assert pu.same_values(pu.samples(db, "const"), ref[0], sqlite=True)


def test_clock_step_back_across_an_outage_with_history_sorted_by_time_is_the_same_rule(
    fmu_path, tmp_path, reference
):
    # A server that answers HistoryRead sorted by SourceTimestamp (OPC UA Part 11's raw history):
    # in it the samples before the step back interleave with those after it. The twin puts each
    # node's history back in the order written by the ServerTimestamps (the server's own clock),
    # so the outcome is the rule of a step back seen live: one clock_jump, the same rows.
    step, at = 0.5, 3000
    name = "sorted"
    p, db = _run(
        tmp_path,
        fmu_path,
        name,
        ["--clock-step", f"{at}:{step}", "--outage", "2.99:0.3", "--history-order", "time"],
    )
    stored, drops = _accounted(p, db, name)
    ev = pu.events(db, name)
    assert any(e[1] == "reconnect" and "history" in e[3] for e in ev), ev
    assert sum(e[1] == "clock_jump" and "stepped back" in e[3] for e in ev) == 1, ev
    got = pu.samples(db, name)[:, 1]
    want = _step_rule(reference, at, step)
    assert np.array_equal(got, want), (len(got), len(want))


@pytest.mark.parametrize(
    "writes, seq",
    [("together", False), ("together", True), ("sequential", True)],
    ids=["together", "together-seq", "sequential-seq"],
)
def test_clock_step_back_in_block_mode_is_one_jump_each_sample_counted_once(
    fmu_path, tmp_path, reference, writes, seq
):
    # The PLC's clock steps back 0.5 s at sample 3000: its block time arrays (and, written
    # together, the blocks' SourceTimestamps) go back with it. Block mode applies the rule of
    # docs/plant.md "Timestamps" sample by sample, as scalar mode does.
    step, at = 0.5, 3000
    name = f"block{writes}{int(seq)}"
    extra = 'time_node = "ns=2;s=Pump.Block.Time"\n'
    extra += 'seq_node = "ns=2;s=Pump.Block.Seq"\n' if seq else ""
    plc = pu.PlcProcess(
        "--speed", "4", "--start-delay", "2", "--nodes", "block", "--block-writes", writes,
        "--clock-step", f"{at}:{step}",
    )  # fmt: skip
    src = (
        f'type = "opcua"\nendpoint = "{plc.endpoint}"\nmode = "block"\n'
        'angle_node = "ns=2;s=Pump.Block.CrankAngle"\nend_node = "ns=2;s=Pump.Finished"\n'
        'reconnect_max = 0.5\nangle_unit = "counts"\ncounts_per_rev = 4096\n' + extra
    )
    cfg = pu.write_config(
        tmp_path / f"{name}.toml",
        run=name,
        source=src,
        sinks=pu.sqlite_sink(tmp_path / f"{name}.sqlite"),
        fmu=fmu_path,
    )
    proc = pu.start(cfg)
    try:
        with plc:
            out, err = proc.communicate(timeout=90)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    db = tmp_path / f"{name}.sqlite"
    p = subprocess.CompletedProcess(proc.args, proc.returncode, out, err)
    stored, drops = _accounted(p, db, name)
    ev = pu.events(db, name)
    assert sum(e[1] == "clock_jump" and "stepped back" in e[3] for e in ev) == 1, ev
    got = pu.samples(db, name)[:, 1]
    want = _step_rule(reference, at, step)
    assert np.array_equal(got, want), (len(got), len(want))
