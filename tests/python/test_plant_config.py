"""The twin's configuration file (docs/plant.md "Configuration") and the sinks' options: every
mistake one line naming the file, the key, the value and what is allowed; the examples of the
repository valid; decimation and summaries-only sinks against the clean run."""

from __future__ import annotations

import pathlib

import numpy as np
import plant_util as pu
import pytest
from reciprocating_drive.plant.config import ConfigError, load, parse

# The twin configurations (limits.toml beside them is an alarm limits file: tests/python/test_alarms.py).
EXAMPLES = sorted(
    p for p in (pu.ROOT / "examples" / "twin").glob("*.toml") if p.name != "limits.toml"
)


def test_the_examples_are_valid(monkeypatch):
    monkeypatch.setenv("TWIN_DB_PASSWORD", "x")
    assert len(EXAMPLES) >= 4
    for p in EXAMPLES:
        if "secure" in p.name:
            # Its certificates and password file are made by the user; the rest must be valid.
            monkeypatch.chdir(p.parent)
            with pytest.raises(ConfigError, match="password_file"):
                load(str(p))
            continue
        cfg = load(str(p))
        assert cfg.run_id and cfg.sinks


BASE = {
    "run": {"id": "r1", "machine_id": "pump-1"},
    "source": {"type": "csv", "path": "x.csv"},
    "sink": [{"type": "sqlite", "path": "x.sqlite"}],
}


def _with(table, key, value):
    import copy

    d = copy.deepcopy(BASE)
    if table == "sink":
        d["sink"][0][key] = value
    else:
        d.setdefault(table, {})[key] = value
    return d


@pytest.mark.parametrize(
    "table, key, value, message",
    [
        ("run", "id", "a b", "run.id = 'a b': letters, digits"),
        ("run", "machine", "nope", "run.machine = 'nope': allowed: default"),
        ("run", "commit_interval", -1, "run.commit_interval = -1.0: must be a number > 0"),
        ("run", "commit_interval", float("nan"), "run.commit_interval = nan: must be a number > 0"),
        ("run", "commit_samples", 0, "run.commit_samples = 0: must be an integer >= 1"),
        ("source", "type", "modbus", "source.type = 'modbus': allowed: csv, opcua, stdin"),
        ("source", "angle_unit", "grad", "source.angle_unit = 'grad': allowed: rad, deg, counts"),
        ("source", "angle_unit", "counts", "source.counts_per_rev is missing"),
        ("source", "pace", "fast", "source.pace = 'fast': must be a number >= 0"),
        ("source", "speed_node", "x", "source.speed_node is not a known key"),
        ("conditioning", "window", 0, "conditioning.window = 0.0: must be a number > 0"),
        ("conditioning", "duplicates", "keep", "conditioning.duplicates = 'keep': allowed"),
        ("sink", "type", "mysql", "sink[0].type = 'mysql': allowed: sqlite, postgres, csv"),
        ("sink", "samples", 0, 'sink[0].samples = 0: allowed: "all", "none", or N >= 1'),
        ("sink", "samples", "some", "sink[0].samples = 'some'"),
        ("sink", "password", "hunter2", "a password is never written in the configuration"),
        ("sink", "retry_for", True, "sink[0].retry_for = True: must be a number > 0"),
    ],
)
def test_bad_configuration_is_one_line_naming_key_and_value(table, key, value, message):
    with pytest.raises(ConfigError) as e:
        parse(_with(table, key, value), "twin.toml")
    text = str(e.value)
    assert text.startswith("twin.toml: ") and message in text and "\n" not in text
    assert "hunter2" not in text


def test_opcua_security_needs_certificates_and_a_trust_list():
    src = {
        "type": "opcua",
        "endpoint": "opc.tcp://127.0.0.1:4840/plc",
        "angle_node": "ns=2;s=A",
        "security_policy": "Basic256Sha256",
    }
    with pytest.raises(ConfigError, match="source.certificate is missing"):
        parse({**BASE, "source": src}, "t.toml")
    src = {**src, "certificate": "c.der", "private_key": "k.pem"}
    with pytest.raises(ConfigError, match="source.trust is missing"):
        parse({**BASE, "source": src}, "t.toml")
    with pytest.raises(ConfigError, match="password_env = 'NO_SUCH_VAR_X'"):
        parse({**BASE, "source": {**src, "trust": ["s.der"], "password_env": "NO_SUCH_VAR_X"}})
    with pytest.raises(ConfigError, match="source.endpoint = 'http://x': an opc.tcp:// URL"):
        parse({**BASE, "source": {**src, "endpoint": "http://x"}})


def test_the_command_reports_a_bad_file_in_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[run]\nid = "r"\nmachine_id = "m"\n[source]\ntype = "csv"\npath = 3\n')
    p = pu.run(bad)
    assert p.returncode == 2
    assert p.stderr.strip() == (
        f'{bad}: source.path = 3: the CSV file to replay, or "-" for standard input'
    )
    broken = tmp_path / "broken.toml"
    broken.write_text("[run\n")
    p = pu.run(broken)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "not valid TOML" in p.stderr


def test_decimated_and_summary_only_sinks(fmu_path, tmp_path):
    ref_s, ref_r, _ = pu.clean_run(fmu_path)
    cfg = pu.write_config(
        tmp_path / "d.toml",
        source=pu.csv_source(),
        sinks=pu.sqlite_sink(tmp_path / "every10.sqlite", samples=10)
        + pu.sqlite_sink(tmp_path / "none.sqlite", samples='"none"'),
        fmu=fmu_path,
    )
    p = pu.run(cfg)
    assert p.returncode == 0, p.stderr
    every = pu.samples(tmp_path / "every10.sqlite")
    assert pu.same_values(every, ref_s[::10], sqlite=True)
    assert len(pu.samples(tmp_path / "none.sqlite")) == 0
    for db in ("every10", "none"):
        assert [r[1:] for r in pu.revolutions(tmp_path / f"{db}.sqlite")] == ref_r


def test_bom_is_accepted_and_an_empty_input_is_an_error(fmu_path, tmp_path):
    ref_s, _, _ = pu.clean_run(fmu_path)
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + pu.SAMPLE.read_bytes())
    cfg = pu.write_config(
        tmp_path / "b.toml",
        source=pu.csv_source(bom),
        sinks=pu.sqlite_sink(tmp_path / "b.sqlite"),
        fmu=fmu_path,
    )
    p = pu.run(cfg)
    assert p.returncode == 0, p.stderr
    assert pu.same_values(pu.samples(tmp_path / "b.sqlite"), ref_s, sqlite=True)
    empty = tmp_path / "empty.csv"
    empty.write_text("time,crank_angle\n")
    cfg = pu.write_config(
        tmp_path / "e.toml",
        source=pu.csv_source(empty),
        sinks=pu.sqlite_sink(tmp_path / "e.sqlite"),
        fmu=fmu_path,
    )
    p = pu.run(cfg)
    assert p.returncode == 1 and "has no sample" in p.stderr and p.stderr.count("\n") == 1
    assert "empty.csv" in p.stderr  # names the input
    assert pu.query(tmp_path / "e.sqlite", "SELECT status FROM runs") == [("failed",)]


def test_bad_data_commits_the_rows_before_it_and_names_the_line(fmu_path, tmp_path):
    lines = pu.SAMPLE.read_text().splitlines()
    lines[3000] = "2.99,abc"
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    cfg = pu.write_config(
        tmp_path / "x.toml",
        source=pu.csv_source(bad),
        sinks=pu.sqlite_sink(tmp_path / "x.sqlite"),
        fmu=fmu_path,
    )
    p = pu.run(cfg)
    assert p.returncode == 1
    assert p.stderr.strip() == f"{bad}: line 3001: crank_angle = 'abc' is not a number"
    db = tmp_path / "x.sqlite"
    got = pu.samples(db)
    ref_s, _, _ = pu.clean_run(fmu_path)
    # Rows up to the bad line whose smoothing window closed before it, exactly the clean run's.
    assert 2900 < len(got) < 3000 and pu.same_values(got, ref_s[: len(got)], sqlite=True)
    ev = pu.events(db)
    assert ev[-1][1] == "data_error" and "line 3001" in ev[-1][3]
    assert pu.query(db, "SELECT status FROM runs") == [("failed",)]


def test_a_run_of_another_machine_is_refused(fmu_path, tmp_path):
    db = tmp_path / "m.sqlite"
    short = tmp_path / "short.csv"
    short.write_text("\n".join(pu.SAMPLE.read_text().splitlines()[:500]) + "\n")
    cfg = pu.write_config(
        tmp_path / "a.toml", source=pu.csv_source(short), sinks=pu.sqlite_sink(db), fmu=fmu_path
    )
    assert pu.run(cfg).returncode == 0
    text = pathlib.Path(cfg).read_text().replace('machine_id = "pump-1"', 'machine_id = "pump-2"')
    pathlib.Path(cfg).write_text(text)
    p = pu.run(cfg)
    assert p.returncode == 1 and "belongs to machine 'pump-1'" in p.stderr
    assert np.array_equal(pu.samples(db)[:, 0], np.arange(len(pu.samples(db))))
