"""The OPC UA source (docs/plant.md) against the simulated pump PLC (scripts/plc_sim.py), both as
real processes on 127.0.0.1. The reference is the clean run of the same data file through the
twin's core: the PLC stamps sample i with origin + t_i, so a twin that loses nothing computes the
same numbers bit for bit."""

from __future__ import annotations

import pathlib

import numpy as np
import plant_util as pu
import pytest

SPEED = "4"  # the PLC plays 4x real time: 12 s of data in 3 s
START_DELAY = "2"  # s from the PLC listening to its first sample: the twin is subscribed by then


def _twin_then_plc(cfg, plc, timeout=90):
    """Starts the twin, then the PLC (the twin retries until it is up); the twin's result."""
    import subprocess

    p = pu.start(cfg)
    try:
        with plc:
            out, err = p.communicate(timeout=timeout)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


@pytest.fixture(scope="module")
def reference(fmu_path):
    return pu.clean_run(fmu_path)


def opcua_source(endpoint, mode="scalar", extra="") -> str:
    angle = "Pump.Block.CrankAngle" if mode == "block" else "Pump.CrankAngle"
    text = (
        f'type = "opcua"\nendpoint = "{endpoint}"\nmode = "{mode}"\n'
        f'angle_node = "ns=2;s={angle}"\nend_node = "ns=2;s=Pump.Finished"\n'
        'angle_unit = "counts"\ncounts_per_rev = 4096\nreconnect_max = 0.5\n'
    )
    if mode == "block":
        text += 'time_node = "ns=2;s=Pump.Block.Time"\n'
    return text + extra


def twin_config(tmp_path, name, source, fmu_path):
    return pu.write_config(
        tmp_path / f"{name}.toml",
        run=name,
        source=source,
        sinks=pu.sqlite_sink(tmp_path / f"{name}.sqlite"),
        fmu=fmu_path,
    )


def _check_equal(db, run, reference):
    ref_s, ref_r, _ = reference
    got = pu.samples(db, run)
    assert len(got) == len(ref_s), f"{len(got)} samples, the file has {len(ref_s)}"
    assert pu.same_values(got, ref_s, sqlite=True)
    assert [r[1:] for r in pu.revolutions(db, run)] == ref_r
    gaps = [e[3] for e in pu.events(db, run) if e[1] == "gap"]
    assert gaps == reference[2], gaps  # the file's one gap, reported once


def test_scalar_and_block_nodes_give_the_file_replay_bit_for_bit(fmu_path, tmp_path, reference):
    # The twins start first and keep trying to connect until the PLC is up (reconnect back-off).
    plc = pu.PlcProcess("--speed", SPEED, "--start-delay", START_DELAY)
    procs = {
        mode: pu.start(twin_config(tmp_path, mode, opcua_source(plc.endpoint, mode), fmu_path))
        for mode in ("scalar", "block")
    }
    try:
        with plc:
            outs = {m: p.communicate(timeout=60) for m, p in procs.items()}
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
                p.wait(timeout=10)
    for mode, p in procs.items():
        assert p.returncode == 0, outs[mode][1]
        _check_equal(tmp_path / f"{mode}.sqlite", mode, reference)


def test_server_stopped_5_s_with_history_loses_no_sample(fmu_path, tmp_path, reference):
    # The endpoint closes at data time 4 s for 5 s (the PLC goes on recording into its history).
    plc = pu.PlcProcess("--speed", "2", "--start-delay", START_DELAY, "--outage", "4:5")
    p = _twin_then_plc(twin_config(tmp_path, "hist", opcua_source(plc.endpoint), fmu_path), plc)
    assert p.returncode == 0, p.stderr
    db = tmp_path / "hist.sqlite"
    _check_equal(db, "hist", reference)
    ev = pu.events(db, "hist")
    rec = [e for e in ev if e[1] == "reconnect"]
    assert len(rec) == 1 and "read back from the server's history" in rec[0][3], ev
    assert len([e for e in ev if e[1] == "gap"]) == 1  # the file's own gap only


def test_server_stopped_5_s_without_history_is_one_gap(fmu_path, tmp_path, reference):
    # Real time, closed at data time 1 s for 5 s: the data goes on from 6 s to its end at 12 s.
    plc = pu.PlcProcess(
        "--speed", "1", "--start-delay", START_DELAY, "--outage", "1:5", "--no-history"
    )
    cfg = twin_config(
        tmp_path, "nohist", opcua_source(plc.endpoint, extra="history = false\n"), fmu_path
    )
    p = _twin_then_plc(cfg, plc)
    assert p.returncode == 0, p.stderr
    db = tmp_path / "nohist.sqlite"
    ev = pu.events(db, "nohist")
    rec = [e for e in ev if e[1] == "reconnect"]
    assert len(rec) == 1 and "no history: the interval is a gap" in rec[0][3], ev
    gaps = [e for e in ev if e[1] == "gap"]
    # One gap for the outage (5 s and the reconnection); besides it only the file's own gap (at
    # 6 s, unless the outage swallowed it).
    long = [e for e in gaps if float(e[3].split()[2]) > 4.5]
    assert len(long) == 1, gaps

    # Compared by where the gap is (its times), not by its "(line N)": a live source's line numbers
    # count samples received, not the file's lines.
    def where(msg):
        return msg.split(" (line")[0]

    assert all(e in long or where(e[3]) in {where(m) for m in reference[2]} for e in gaps), gaps
    got, ref = pu.samples(db, "nohist"), reference[0]
    assert len(got) < len(ref)
    # Up to the outage every sample is there, and exactly the clean run's (the smoothing window
    # of the last 50 ms before the gap closes at the gap, so those are left out).
    t_gap = float(long[0][3].split("from t = ")[1].split(" s")[0])
    n = int(np.searchsorted(ref[:, 1], t_gap - 0.06))
    assert 700 < n and pu.same_values(got[:n], ref[:n], sqlite=True)
    # After it, the samples are the file's own times.
    assert np.isin(got[:, 1], ref[:, 1]).all()


def test_bad_status_nan_and_wrong_type_are_dropped_counted_reported(fmu_path, tmp_path, reference):
    faults = ["--fault", "1000:bad_status", "--fault", "2000:nan", "--fault", "3000:wrong_type"]
    plc = pu.PlcProcess("--speed", SPEED, "--start-delay", START_DELAY, *faults)
    p = _twin_then_plc(twin_config(tmp_path, "faults", opcua_source(plc.endpoint), fmu_path), plc)
    assert p.returncode == 0, p.stderr
    db = tmp_path / "faults.sqlite"
    got, ref = pu.samples(db, "faults"), reference[0]
    # Every sample but the three bad ones; none of the three fed to the FMU.
    bad_t = ref[[1000, 2000, 3000], 1]
    assert len(got) == len(ref) - 3
    assert np.array_equal(got[:, 1], np.delete(ref[:, 1], [1000, 2000, 3000]))
    assert not np.isin(bad_t, got[:, 1]).any()
    drops = [e for e in pu.events(db, "faults") if e[1] == "dropped"]
    assert sum(e[2] for e in drops) == 3, drops
    text = " ".join(e[3] for e in drops)
    assert "BadSensorFailure" in text and "not finite" in text and "String, not a number" in text


# ---- security ------------------------------------------------------------------------------------

PASSWORD = "s3cret-Pump-Pw"


@pytest.fixture(scope="module")
def secured(tmp_path_factory):
    """A PLC requiring Basic256Sha256 SignAndEncrypt and a user name + password, its certificate
    made at start into a temporary folder, playing in real time (12 s: the data flows while the
    cases run); a client certificate; another (untrusted) server's."""
    from reciprocating_drive.plant.plc_sim import make_certificate

    d = tmp_path_factory.mktemp("certs")
    client_cert, client_key = make_certificate(d, "twin-client", server=False)
    other_cert, _ = make_certificate(d, "other-server", server=True)
    (d / "pw").write_text(PASSWORD + "\n")
    with pu.PlcProcess(
        "--speed",
        "1",
        "--security",
        "SignAndEncrypt",
        "--cert-dir",
        str(d / "plc"),
        "--user",
        "operator",
        "--password-env",
        "PLC_TEST_PW",
        "--start-delay",
        "0",
        env_extra={"PLC_TEST_PW": PASSWORD},
    ) as plc:
        yield plc, d, client_cert, client_key, other_cert


def _secure_source(plc, d, cert, key, trust, user=True, pw_file=None):
    extra = (
        'security_policy = "Basic256Sha256"\nsecurity_mode = "SignAndEncrypt"\n'
        f'certificate = "{cert}"\nprivate_key = "{key}"\ntrust = ["{trust}"]\n'
    )
    if user:
        extra += f'username = "operator"\npassword_file = "{pw_file or d / "pw"}"\n'
    return opcua_source(plc.endpoint, extra=extra)


def _no_secret(p, db=None):
    text = p.stdout + p.stderr
    assert PASSWORD not in text and "Traceback" not in text
    if db is not None and pathlib.Path(db).exists():
        assert PASSWORD.encode() not in pathlib.Path(db).read_bytes()


def test_secured_connection_with_trusted_certificate_and_password(fmu_path, tmp_path, secured):
    plc, d, cert, key, _ = secured
    src = _secure_source(plc, d, cert, key, d / "plc" / "plc-sim.der")
    # The PLC has started playing already: the twin takes what comes, with history from its
    # first sample on; this case checks the login, not completeness.
    cfg = twin_config(tmp_path, "secure", src.replace("end_node", "#end_node"), fmu_path)
    p = pu.start(cfg)
    try:
        import time

        deadline = time.monotonic() + 30
        while pu.committed(tmp_path / "secure.sqlite", "secure") < 200:
            assert p.poll() is None, p.stderr.read()
            assert time.monotonic() < deadline, "nothing committed over the secured channel"
            time.sleep(0.1)
        cmdline = pathlib.Path(f"/proc/{p.pid}/cmdline").read_bytes()
        assert PASSWORD.encode() not in cmdline
        p.terminate()
        out, err = p.communicate(timeout=20)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 128 + 15, err  # stopped before its input ended: not a success
    assert "stopped by SIGTERM" in err
    _no_secret(type("P", (), {"stdout": out, "stderr": err}), tmp_path / "secure.sqlite")


@pytest.mark.parametrize(
    "case, message",
    [
        ("anonymous", "refuses anonymous connections"),
        ("wrong password", "refused user 'operator'"),
        ("untrusted server", "is not in the trust list"),
        ("another application", "not 'urn:other-plc' (source.server_uri); refused"),
    ],
)
def test_secured_server_refusals_are_one_clear_line(fmu_path, tmp_path, secured, case, message):
    plc, d, cert, key, other = secured
    trust = other if case == "untrusted server" else d / "plc" / "plc-sim.der"
    wrong = tmp_path / "wrong-pw"
    wrong.write_text("not-the-" + PASSWORD)
    src = _secure_source(
        plc,
        d,
        cert,
        key,
        trust,
        user=case != "anonymous",
        pw_file=wrong if case == "wrong password" else None,
    )
    if case == "another application":
        src += 'server_uri = "urn:other-plc"\n'
    cfg = twin_config(tmp_path, "refused", src, fmu_path)
    p = pu.run(cfg, timeout=60)
    assert p.returncode == 1, p.stderr
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], p.stderr
    _no_secret(p)
    assert "not-the-" not in p.stderr


def test_sigkill_and_restart_on_a_live_source_with_history_loses_nothing(
    fmu_path, tmp_path, reference
):
    import random
    import signal
    import time

    plc = pu.PlcProcess("--speed", "2", "--start-delay", START_DELAY)
    cfg = twin_config(tmp_path, "killed", opcua_source(plc.endpoint), fmu_path)
    db = tmp_path / "killed.sqlite"
    p = pu.start(cfg)
    try:
        with plc:
            pu.wait_for_commit(db, "killed", 500, p)
            time.sleep(random.Random(7).uniform(0.0, 0.5))
            p.send_signal(signal.SIGKILL)
            p.wait(timeout=10)
            at_kill = pu.committed(db, "killed")
            # Restarted while the PLC goes on: it resumes from the checkpoint and reads the
            # samples since then back from the server's history.
            p = pu.start(cfg)
            out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 0, err
    assert 500 < at_kill < len(reference[0])
    _check_equal(db, "killed", reference)
    ev = pu.events(db, "killed")
    assert any(e[1] == "reconnect" and "resumed on" in e[3] for e in ev), ev


def test_the_one_command_demo(tmp_path):
    """scripts/twin_plant.py --demo: the simulated PLC in real time, the twin subscribed, SQLite;
    stopped after 6 s as asked: what it computed is committed, exit status 0 (the demo asked for
    is complete; docs/install.md "Exit codes")."""
    import subprocess
    import sys

    db = tmp_path / "demo.sqlite"
    p = subprocess.run(
        [
            sys.executable,
            str(pu.SCRIPT),
            "--demo",
            "--seconds",
            "6",
            "--db",
            str(db),
            "--page-port",
            "0",
        ],  # fmt: skip
        env=pu.env(),
        capture_output=True,
        text=True,
        timeout=90,
    )
    assert p.returncode == 0, p.stderr
    assert "stopped after 6 s as asked" in p.stderr and "Traceback" not in p.stderr
    assert "SIGINT" not in p.stderr
    assert "page: http://127.0.0.1:" in p.stderr  # the demo serves the live page
    n = pu.query(db, "SELECT COUNT(*) FROM samples")[0][0]
    t = pu.query(db, "SELECT MAX(t) FROM samples")[0][0]
    # Real time: about 1000 rows per second of the run after the PLC's 2 s start delay.
    assert 500 < n and abs(n - 1000 * t) < 50, (n, t)
    assert pu.query(db, "SELECT status FROM runs") == [("running",)]
