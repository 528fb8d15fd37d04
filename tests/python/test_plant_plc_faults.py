"""Other PLCs' ways, played by the simulated PLC (docs/plant.md "Sample assembly", "History",
"Odd values", "Unresponsive server or database"): block arrays written one after another and
joined by a counter node, a history that fails or caps its responses, values of odd types or
without a timestamp, a server that accepts the connection and never answers. Each run ends with
every sample the PLC wrote stored or counted in a `dropped` event, or with one line saying why
not; the stored rows are compared with the clean run of the same data (bit for bit)."""

from __future__ import annotations

import math
import subprocess
import threading
import time

import plant_util as pu
import pytest

N = 11801  # samples in data/twin/pump_encoder.csv
SAME = "duplicate timestamp, same values"


def _source(endpoint, mode="scalar", extra="", units=True) -> str:
    angle = "Pump.Block.CrankAngle" if mode == "block" else "Pump.CrankAngle"
    text = (
        f'type = "opcua"\nendpoint = "{endpoint}"\nmode = "{mode}"\n'
        f'angle_node = "ns=2;s={angle}"\nend_node = "ns=2;s=Pump.Finished"\n'
        "reconnect_max = 0.5\n"
    )
    if units:
        text += 'angle_unit = "counts"\ncounts_per_rev = 4096\n'
    if mode == "block":
        text += 'time_node = "ns=2;s=Pump.Block.Time"\n'
    return text + extra


def _run(
    tmp_path,
    fmu_path,
    name,
    plc_args,
    source_extra="",
    mode="scalar",
    data=pu.SAMPLE,
    units=True,
    speed="4",
    timeout=90,
):
    plc = pu.PlcProcess("--speed", speed, "--start-delay", "2", *plc_args, data=data)
    cfg = pu.write_config(
        tmp_path / f"{name}.toml",
        run=name,
        source=_source(plc.endpoint, mode, source_extra, units),
        sinks=pu.sqlite_sink(tmp_path / f"{name}.sqlite"),
        fmu=fmu_path,
    )
    p = pu.start(cfg)
    try:
        with plc:
            out, err = p.communicate(timeout=timeout)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err), tmp_path / f"{name}.sqlite"


def _dropped(db, name) -> dict:
    out: dict = {}
    for _seq, kind, count, msg in pu.events(db, name):
        if kind == "dropped":
            why = msg.split("dropped: ", 1)[1].split(" (first at")[0]
            out[why] = out.get(why, 0) + count
    return out


def _accounted(p, db, name, written=N):
    """finished, exit 0, every sample written stored or counted (docs/plant.md "Final status")."""
    assert p.returncode == 0 and "Traceback" not in p.stderr, p.stderr
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


def _constant_data(path, n=12000):
    """n samples at 1 kHz of a crank at a constant 6.8 rad/s, speed constant, the process force
    0, then 20 kN from 4 s to 8 s, then 0."""
    w = 6.8
    lines = ["time,crank_angle,crank_speed,process_force"]
    for i in range(n):
        t = i / 1000
        f = 20000.0 if 4 <= t < 8 else 0.0
        lines.append(f"{t!r},{math.fmod(w * t, 2 * math.pi)!r},{w!r},{f!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


BLOCK_NODES = (
    'speed_node = "ns=2;s=Pump.Block.CrankSpeed"\nforce_node = "ns=2;s=Pump.Block.ProcessForce"\n'
)


# ---- block arrays written one after another ----------------------------------------------------
def test_block_arrays_written_one_after_another_are_joined_by_seq_node(fmu_path, tmp_path):
    # Time, angle, speed, force, then the counter: five writes, five server stamps per block.
    data = _constant_data(tmp_path / "constant.csv")
    p, db = _run(
        tmp_path,
        fmu_path,
        "seq",
        ["--nodes", "block", "--block-writes", "sequential"],
        BLOCK_NODES + 'seq_node = "ns=2;s=Pump.Block.Seq"\n',
        mode="block",
        data=data,
        units=False,
    )
    stored, drops = _accounted(p, db, "seq", written=12000)
    ref = pu.clean_run(fmu_path, data, counts=False)
    assert stored == 12000 and not drops, drops
    assert pu.same_values(pu.samples(db, "seq"), ref[0], sqlite=True)


def test_block_arrays_stamped_apart_without_seq_node_are_reported_while_running(fmu_path, tmp_path):
    # Real time (12 s of data after 2 s): the incomplete groups must be reported in the database
    # within seconds, not at the end; with nothing complete the run ends failed, exit 1.
    plc = pu.PlcProcess(
        "--speed", "1", "--start-delay", "2", "--nodes", "block", "--block-writes", "sequential"
    )
    cfg = pu.write_config(
        tmp_path / "apart.toml",
        run="apart",
        source=_source(plc.endpoint, "block"),
        sinks=pu.sqlite_sink(tmp_path / "apart.sqlite"),
        fmu=fmu_path,
    )
    db = tmp_path / "apart.sqlite"
    p = pu.start(cfg)
    try:
        with plc:
            t0 = time.monotonic()
            seen = None
            while time.monotonic() - t0 < 9 and p.poll() is None:
                try:
                    ev = pu.events(db, "apart")
                except Exception:  # noqa: BLE001 - the schema is not there yet
                    ev = []
                if any(e[1] == "dropped" and "incomplete" in e[3] for e in ev):
                    seen = time.monotonic() - t0
                    break
                time.sleep(0.1)
            out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    # The first block is written 2.05 s after the PLC starts; reported within GROUP_WAIT (1 s)
    # plus a commit interval, long before the data's end at 14 s.
    assert seen is not None and seen < 8, (seen, err)
    assert p.returncode == 1 and "Traceback" not in err, err
    assert pu.query(db, "SELECT status FROM runs")[0][0] == "failed"
    drops = _dropped(db, "apart")
    assert drops and all("incomplete" in k and "seq_node" in k for k in drops), drops


# ---- history ------------------------------------------------------------------------------------
def _hist(tmp_path, fmu_path, name, extra_plc, extra_src=""):
    return _run(tmp_path, fmu_path, name, ["--outage", "4:5", *extra_plc], extra_src, speed="2")


def _check_equal(db, run, reference):
    ref_s, ref_r, _ = reference
    got = pu.samples(db, run)
    assert len(got) == len(ref_s), f"{len(got)} samples, the file has {len(ref_s)}"
    assert pu.same_values(got, ref_s, sqlite=True)
    assert [r[1:] for r in pu.revolutions(db, run)] == ref_r


def test_history_failing_twice_is_retried_and_nothing_is_lost(fmu_path, tmp_path, reference):
    p, db = _hist(tmp_path, fmu_path, "hfail", ["--history-fail", "2"])
    assert p.returncode == 0, p.stderr
    _check_equal(db, "hfail", reference)
    rec = [e for e in pu.events(db, "hfail") if e[1] == "reconnect"]
    assert len(rec) == 1 and "read back from the server's history" in rec[0][3], rec
    assert "HistoryRead failed (BadInternalError); retrying" in p.stderr, p.stderr
    assert "history read on attempt 3" in p.stderr, p.stderr


def test_history_failing_always_becomes_a_gap_after_the_retries(fmu_path, tmp_path):
    p, db = _hist(
        tmp_path, fmu_path, "hnever", ["--history-fail", "always"], "history_retry_for = 2\n"
    )
    assert p.returncode == 0, p.stderr
    ev = pu.events(db, "hnever")
    rec = [e for e in ev if e[1] == "reconnect"]
    assert len(rec) == 1 and "history not available (BadInternalError" in rec[0][3], rec
    assert "attempts over" in rec[0][3] and "the interval is a gap" in rec[0][3], rec
    # The outage (from data time 4 s to the data's end at 2x speed) is a gap, and an event.
    gaps = [e[3] for e in ev if e[1] == "gap"]
    assert any(" from t = 3.9" in g or " from t = 4.0" in g for g in gaps), gaps
    line = [x for x in p.stderr.splitlines() if "HistoryRead failed" in x and "times" in x]
    assert len(line) == 1, p.stderr


def test_history_capped_per_response_is_followed_through_continuation_points(
    fmu_path, tmp_path, reference
):
    # 5 s of missed samples (about 5 000) read back 97 values per response.
    p, db = _hist(tmp_path, fmu_path, "hcap", ["--history-cap", "97"])
    assert p.returncode == 0, p.stderr
    _check_equal(db, "hcap", reference)
    rec = [e for e in pu.events(db, "hcap") if e[1] == "reconnect"]
    got = int(rec[0][3].split("; ")[1].split(" missed")[0])
    assert got > 4000, rec


# ---- odd values ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "mode, fault, reason",
    [
        ("scalar", "double2", "angle is an array (2 values), not a number"),
        ("scalar", "no_stamp", "no SourceTimestamp on angle"),
        ("block", "block2d", "angle is an array of more than one dimension"),
    ],
)
def test_odd_value_is_a_counted_drop_with_its_reason(
    fmu_path, tmp_path, reference, mode, fault, reason
):
    at = 3000
    p, db = _run(tmp_path, fmu_path, f"odd{fault}", ["--fault", f"{at}:{fault}"], mode=mode)
    stored, drops = _accounted(p, db, f"odd{fault}")
    assert list(drops) == [reason], drops
    if mode == "scalar":
        assert drops[reason] == 1 and stored == N - 1
    else:  # the whole block (50 ms of samples) holding that sample
        assert 40 <= drops[reason] <= 60, drops
    t_ref = reference[0][:, 1]
    assert set(pu.samples(db, f"odd{fault}")[:, 1]) <= set(t_ref)


# ---- a server that never answers ----------------------------------------------------------------
def _lines_with_times(p):
    got = []

    def read():
        for line in p.stderr:
            got.append((time.monotonic(), line.rstrip("\n")))

    th = threading.Thread(target=read, daemon=True)
    th.start()
    return got, th


def test_server_that_never_answers_gives_a_line_at_once_then_every_notice_interval(
    fmu_path, tmp_path
):
    plc = pu.PlcProcess("--silent")
    cfg = pu.write_config(
        tmp_path / "silent.toml",
        run="silent",
        source=_source(plc.endpoint) + "timeout = 1\nreconnect_for = 8\nnotice_interval = 2.5\n",
        sinks=pu.sqlite_sink(tmp_path / "silent.sqlite"),
        fmu=fmu_path,
    )
    with plc:
        t0 = time.monotonic()
        p = pu.start(cfg)
        got, th = _lines_with_times(p)
        try:
            p.wait(timeout=40)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait(timeout=10)
        th.join(timeout=5)
    first = [t - t0 for t, x in got if "not answering (no answer within timeout = 1 s)" in x]
    more = [t - t0 for t, x in got if "still not answering after" in x]
    assert first and first[0] < 5, got  # timeout 1 s + the interpreter's start
    assert 1 <= len(more) <= 4, got  # every 2.5 s over 8 s
    assert p.returncode == 1, got
    assert any("unreachable for 8 s (reconnect_for)" in x for _t, x in got), got
    assert not any("Traceback" in x for _t, x in got), got


def test_incomplete_groups_and_unclaimed_arrays_stay_bounded_in_memory():
    # A server that floods the source with values that never complete a group (time arrays only,
    # each with its own stamp, faster than GROUP_WAIT lets them go): what waits stays bounded and
    # every one comes out as a counted drop. Real asyncua DataValues, the source's own joiners.
    import datetime as dt

    from asyncua import ua
    from reciprocating_drive.plant.sources import opcua as O

    t0 = dt.datetime(2026, 1, 1, tzinfo=dt.UTC)

    def array_dv(k):
        ts = t0 + dt.timedelta(microseconds=k)  # 1 µs apart: none older than GROUP_WAIT
        return ua.DataValue(ua.Variant([ts, ts], ua.VariantType.DateTime), SourceTimestamp=ts)

    settings = {
        "mode": "block",
        "angle_node": "ns=2;s=A",
        "time_node": "ns=2;s=T",
        "seq_node": "ns=2;s=S",
    }
    for joiner, limit, waiting in (
        (O._Joiner, O._Joiner.MAX_GROUPS, lambda j: len(j.groups)),
        (O._SeqJoiner, O._SeqJoiner.MAX_PENDING, lambda j: len(j.pending["time"])),
    ):
        src = O.OpcUaSource(dict(settings, seq_node=settings["seq_node"]))
        j = joiner(src)
        out, most = 0, 0
        for k in range(0, 30000, 100):
            out += len(j.feed([("time", array_dv(k + i)) for i in range(100)]))
            most = max(most, waiting(j))
        assert most <= limit + 100, (joiner.__name__, most)
        out += len(j.feed([], flush=True))
        assert out == 30000 * 2, (joiner.__name__, out)  # two samples per time array, all dropped


def test_seq_node_in_scalar_mode_is_one_line_exit_2(tmp_path):
    cfg = pu.write_config(
        tmp_path / "s.toml",
        source=_source(
            "opc.tcp://127.0.0.1:1/plc", "scalar", 'seq_node = "ns=2;s=Pump.Block.Seq"\n'
        ),
        sinks=pu.sqlite_sink(tmp_path / "s.sqlite"),
    )
    p = pu.run(cfg, timeout=60)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert "source.seq_node = 'ns=2;s=Pump.Block.Seq': only with mode = \"block\"" in lines[0]
