"""`rdrive plant` and `rdrive plc-sim` against hostile input (docs/install.md "Exit codes",
docs/plant.md): every configuration file, option and database content a user can give ends in one
line naming the file, key or option and the documented exit code, never a traceback or an
internal error (70). Each case runs the real command as a subprocess."""

from __future__ import annotations

import socket
import sqlite3
import subprocess
import sys

import plant_util as pu
import pytest

PLC = pu.ROOT / "scripts" / "plc_sim.py"


def _one_line(p, *words, code):
    text = p.stdout + p.stderr
    assert "Traceback" not in text and "internal error" not in text, text
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert p.returncode == code, (p.returncode, p.stderr)
    assert len(lines) == 1, p.stderr
    for w in words:
        assert str(w) in lines[0], (w, lines[0])
    return lines[0]


def _command(script, *args, timeout=60, **kw):
    return subprocess.run(
        [sys.executable, str(script), *map(str, args)],
        env=pu.env(),
        capture_output=True,
        text=True,
        timeout=timeout,
        **kw,
    )


def _config(tmp_path, text: str):
    p = tmp_path / "hostile.toml"
    p.write_text(text, encoding="utf-8")
    return p


OPCUA = (
    '[source]\ntype = "opcua"\nendpoint = "opc.tcp://127.0.0.1:1/plc"\n'
    'angle_node = "ns=2;s=Pump.CrankAngle"\n'
)
RUN = '[run]\nid = "r1"\nmachine_id = "pump-1"\n'


def test_nul_in_a_path_is_one_line_naming_the_key(tmp_path):
    cfg = _config(
        tmp_path,
        RUN
        + "[source]\n"
        + pu.csv_source()
        + '[[sink]]\ntype = "sqlite"\npath = "a\\u0000b.sqlite"\n',
    )
    _one_line(pu.run(cfg), cfg, "sink[0].path", "NUL", code=2)


def test_trust_list_of_numbers_is_one_line(tmp_path):
    cfg = _config(tmp_path, RUN + OPCUA + "trust = [1, 2]\n" + pu.sqlite_sink(tmp_path / "x.db"))
    _one_line(pu.run(cfg), cfg, "source.trust = [1, 2]", "certificate files", code=2)


@pytest.mark.parametrize(
    "text",
    [
        "x = " + "[" * 100_000 + "]" * 100_000 + "\n",
        "x = " + "{a = " * 100_000 + "1" + "}" * 100_000 + "\n",
    ],
    ids=["arrays", "inline tables"],
)
def test_100000_deep_nesting_is_one_line(tmp_path, text):
    cfg = tmp_path / "deep.toml"
    cfg.write_text(text)
    _one_line(pu.run(cfg), cfg, "nested too deep", code=2)


def test_non_utf8_configuration_is_one_line(tmp_path):
    cfg = tmp_path / "latin1.toml"
    cfg.write_bytes((RUN + "# Pumpe Nr. 1 \xe4\n").encode("latin-1"))
    _one_line(pu.run(cfg), cfg, "is not UTF-8", code=2)


def test_pace_of_1e_minus_300_is_one_line(tmp_path):
    cfg = _config(
        tmp_path,
        RUN + "[source]\n" + pu.csv_source(pace=1e-300) + pu.sqlite_sink(tmp_path / "x.sqlite"),
    )
    _one_line(pu.run(cfg), cfg, "source.pace = 1e-300", code=2)


def test_bad_run_machine_and_fmu_are_named_as_keys(tmp_path, fmu_path):
    ssv = tmp_path / "broken.ssv"
    ssv.write_text("this is not an SSV file")
    cfg = pu.write_config(
        tmp_path / "m.toml",
        source=pu.csv_source(),
        sinks=pu.sqlite_sink(tmp_path / "m.sqlite"),
        run_extra=f'machine = "{ssv}"\n',
        fmu=fmu_path,
    )
    line = _one_line(pu.run(cfg), cfg, "run.machine", "broken.ssv", code=2)
    assert "--machine" not in line
    cfg = pu.write_config(
        tmp_path / "f.toml",
        source=pu.csv_source(),
        sinks=pu.sqlite_sink(tmp_path / "f.sqlite"),
        fmu=tmp_path / "nope.fmu",
    )
    line = _one_line(pu.run(cfg), cfg, "run.fmu", "nope.fmu", code=2)
    assert "--fmu" not in line


@pytest.mark.parametrize(
    "path, words",
    [("/dev/full", "No space left on device"), ("/sys/rd-plant-test.csv", "Permission denied")],
    ids=["full", "unwritable"],
)
def test_full_or_unwritable_csv_sink_is_one_clear_line(tmp_path, fmu_path, path, words):
    cfg = pu.write_config(
        tmp_path / "c.toml",
        source=pu.csv_source(),
        sinks=(
            f'[[sink]]\ntype = "csv"\npath = "{path}"\nsummary = "{tmp_path / "s.csv"}"\n'
            f'checkpoint = "{tmp_path / "c.json"}"\n'
        ),
        fmu=fmu_path,
    )
    line = _one_line(pu.run(cfg), f"cannot write {path}", words, code=1)
    assert "[Errno" not in line


def test_non_utf8_limits_file_is_one_line(tmp_path, fmu_path):
    limits = tmp_path / "limits.toml"
    limits.write_bytes("# Grenzwerte f\xfcr Pumpe 1\n".encode("latin-1"))
    cfg = pu.write_config(
        tmp_path / "l.toml",
        source=pu.csv_source(),
        sinks=pu.sqlite_sink(tmp_path / "l.sqlite") + f'\n[page]\nport = 0\nlimits = "{limits}"\n',
        fmu=fmu_path,
    )
    _one_line(pu.run(cfg), limits, "is not UTF-8", code=2)


@pytest.mark.parametrize(
    "state, words",
    [
        ("{not json", "is not JSON"),
        ('{"twin": {}}', "has no counters"),
        ('{"twin": {}, "counters": {"samples": "x"}}', "are not samples"),
        (
            '{"counters": {"samples": 1, "revolutions": 0, "events": 1, "commits": 1}}',
            "no state of the twin",
        ),
        (
            '{"twin": {"x": 1}, "counters": {"samples": 1, "revolutions": 0, "events": 1, '
            '"commits": 1}}',
            "the twin's state is not readable",
        ),
    ],
    ids=["not json", "no counters", "bad counter", "no twin", "bad twin"],
)
def test_corrupt_checkpoint_row_is_one_line_naming_the_run(tmp_path, fmu_path, state, words):
    db = tmp_path / "cp.sqlite"
    cfg = pu.write_config(
        tmp_path / "cp.toml",
        source=pu.csv_source(),
        sinks=pu.sqlite_sink(db),
        fmu=fmu_path,
        run_extra="commit_samples = 2000\n",
    )
    # A run stopped before its end: its checkpoint is what a restart resumes from.
    c = sqlite3.connect(db)
    p = pu.run(cfg)
    assert p.returncode == 0, p.stderr
    c.execute("UPDATE runs SET status = 'running'")
    # Without its checksum (as a checkpoint of schema version 2): the state's own checks; with
    # it, an edited state is found by the checksum first (test_plant_storage.py).
    c.execute("UPDATE checkpoints SET state = ?, checksum = NULL", (state,))
    c.commit()
    c.close()
    line = _one_line(pu.run(cfg), "run 'r1'", words, code=1)
    assert "JSONDecodeError" not in line and "KeyError" not in line


@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf", "soon"])
def test_demo_seconds_not_a_positive_number_is_one_line(value):
    p = _command(pu.SCRIPT, "--demo", "--seconds", value, "--page-port", "0")
    _one_line(p, "--seconds", code=2)


def test_demo_seconds_ends_complete_with_exit_0_and_says_so(tmp_path):
    """--demo --seconds S: the demo asked for is complete after S seconds: exit 0 (docs/install.md
    "Exit codes"), with a line saying so, and no word of a signal."""
    db = tmp_path / "demo.sqlite"
    p = _command(pu.SCRIPT, "--demo", "--seconds", "5", "--db", db, "--page-port", "0", timeout=90)
    assert p.returncode == 0, p.stderr
    assert "SIGINT" not in p.stderr and "Traceback" not in p.stderr, p.stderr
    assert "stopped after 5 s as asked (--seconds)" in p.stderr, p.stderr
    assert pu.query(db, "SELECT COUNT(*) FROM samples")[0][0] > 500


def test_plc_sim_port_out_of_range_is_one_line():
    _one_line(_command(PLC, "--port", "99999"), "--port", "99999", code=2)


def test_plc_sim_busy_port_is_one_line():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        p = _command(PLC, "--port", port, "--linger", "0", timeout=60)
    _one_line(p, f"--port {port}", "cannot listen", code=2)
