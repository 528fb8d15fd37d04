"""The CSV sink (docs/plant.md "CSV sink"): the files equal those of `rdrive twin` (the older,
independent writer of the same format) byte for byte; parsed back they are the clean run's
values bit for bit; SIGKILL three times at random points loses and repeats nothing; files changed
behind the sink's back are refused with one line."""

from __future__ import annotations

import json
import random
import signal
import subprocess
import sys
import time

import numpy as np
import plant_util as pu
import pytest

SEED = 2026


def csv_sink(path, extra="") -> str:
    return f'[[sink]]\ntype = "csv"\npath = "{path}"\n{extra}'


def rdrive_twin(tmp_path, fmu_path):
    """The per-sample and revolution files of `rdrive twin` on the sample data."""
    out = tmp_path / "ref" / "out.csv"
    p = subprocess.run(
        [sys.executable, "-m", "reciprocating_drive.commands.twin", str(pu.SAMPLE), "--fmu",
         fmu_path, "--angle-unit", "counts", "--counts-per-rev", "4096", "--out", str(out)],
        env=pu.env(), capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    return out.read_bytes(), out.with_name("out-revolutions.csv").read_bytes()


@pytest.fixture(scope="module")
def reference(fmu_path, tmp_path_factory):
    return rdrive_twin(tmp_path_factory.mktemp("ref"), fmu_path)


def _files(out):
    return out.read_bytes(), out.with_name(out.stem + "-revolutions.csv").read_bytes()


def _sidecar(out) -> dict | None:
    try:
        return json.loads(out.with_name(out.name + ".checkpoint.json").read_text())
    except (OSError, ValueError):
        return None


def _covered(out) -> int:
    m = _sidecar(out)
    return m["state"]["counters"]["samples"] if m and m["state"] else 0


def test_csv_sink_writes_what_rdrive_twin_writes(fmu_path, tmp_path, reference):
    out = tmp_path / "res" / "out.csv"
    cfg = pu.write_config(
        tmp_path / "t.toml", source=pu.csv_source(), sinks=csv_sink(out), fmu=fmu_path
    )
    p = pu.run(cfg)
    assert p.returncode == 0, p.stderr
    assert _files(out) == reference
    # Parsed back: the clean run's values, bit for bit (repr reads back exactly).
    table, revs, _ = pu.clean_run(fmu_path)
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    assert pu.same_values(got, table[:, 1:], sqlite=False)
    assert len(out.with_name("out-revolutions.csv").read_text().splitlines()) == len(revs) + 1
    # Run again: the run is finished, nothing is written.
    again = pu.run(cfg)
    assert again.returncode == 0 and "already finished" in again.stderr
    assert _files(out) == reference


def test_csv_sink_with_sqlite_and_decimation(fmu_path, tmp_path, reference):
    out, db = tmp_path / "out.csv", tmp_path / "t.sqlite"
    cfg = pu.write_config(
        tmp_path / "t.toml",
        source=pu.csv_source(),
        sinks=csv_sink(out, "samples = 10\n") + pu.sqlite_sink(db),
        fmu=fmu_path,
    )
    p = pu.run(cfg)
    assert p.returncode == 0, p.stderr
    ref = reference[0].split(b"\n")
    assert out.read_bytes() == b"\n".join([ref[0], *ref[1:-1][::10]]) + b"\n"
    assert _files(out)[1] == reference[1]
    assert len(pu.samples(db)) == len(ref) - 2


@pytest.mark.parametrize("with_sqlite", [False, True])
def test_sigkill_three_times_the_csv_equals_a_clean_run(with_sqlite, fmu_path, tmp_path, reference):
    """With an SQLite sink beside it, the two sinks' checkpoints differ at a kill: the twin
    resumes from the one that covers least and each sink skips what it holds."""
    out, db = tmp_path / "out.csv", tmp_path / "t.sqlite"
    # Paced at 6x real time (12 s of data in about 2 s) so that the kills fall inside the run.
    cfg = pu.write_config(
        tmp_path / "t.toml",
        source=pu.csv_source(pace=6.0),
        sinks=csv_sink(out) + (pu.sqlite_sink(db) if with_sqlite else ""),
        fmu=fmu_path,
        run_extra="commit_interval = 0.05\ncommit_samples = 2000\n",
    )
    rng = random.Random(SEED)
    progress, beyond = [0], []
    for k in range(3):
        p = pu.start(cfg)
        try:
            deadline = time.monotonic() + 30
            while _covered(out) <= progress[-1]:
                assert time.monotonic() < deadline and p.poll() is None, "no checkpoint"
                time.sleep(0.005)
            if k == 0:
                # Rows after the checkpoint are in the file: they must be cut and made again.
                while out.stat().st_size <= _sidecar(out)["sizes"]["samples"]:
                    assert time.monotonic() < deadline and p.poll() is None
                    time.sleep(0.005)
            else:
                time.sleep(rng.uniform(0.0, 0.5))
            assert p.poll() is None, f"the run ended before the kill: {p.stderr.read()}"
            p.send_signal(signal.SIGKILL)
            p.wait(timeout=10)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait(timeout=10)
        progress.append(_covered(out))
        m = _sidecar(out)
        beyond.append(out.stat().st_size - m["sizes"]["samples"])
        if k == 0:
            # Opened again, the sink cuts the file to what the checkpoint covers.
            from reciprocating_drive.plant.sinks.base import RunInfo
            from reciprocating_drive.plant.sinks.csv import CsvSink

            s = CsvSink(str(out))
            s._connect()
            info = RunInfo(m["run"], m["machine_id"], m["machine"], [], {}, {}, header=m["header"])
            s._open_run(info)
            s.close()
            assert out.stat().st_size == m["sizes"]["samples"]
    assert progress == sorted(progress) and len(set(progress)) == 4, progress
    assert beyond[0] > 0, beyond
    done = pu.run(cfg)
    assert done.returncode == 0, done.stderr
    assert _files(out) == reference
    if with_sqlite:
        table, revs, _ = pu.clean_run(fmu_path)
        assert pu.same_values(pu.samples(db), table, sqlite=True)
        assert [r[1:] for r in pu.revolutions(db)] == revs


def test_files_changed_behind_the_sinks_back_are_refused(fmu_path, tmp_path):
    out = tmp_path / "out.csv"
    cfg = pu.write_config(
        tmp_path / "t.toml",
        source=pu.csv_source(),
        sinks=csv_sink(out),
        fmu=fmu_path,
        run_extra="commit_samples = 2000\n",
    )
    # A file that is not this sink's (no checkpoint beside it) is never overwritten.
    out.write_text("precious\n")
    p = pu.run(cfg)
    assert p.returncode == 1 and p.stderr.count("\n") == 1, p.stderr
    assert str(out) in p.stderr and "has no checkpoint" in p.stderr
    assert out.read_text() == "precious\n"
    out.unlink()
    assert pu.run(cfg).returncode == 0
    side = out.with_name("out.csv.checkpoint.json")
    m = json.loads(side.read_text())
    m["status"] = "running"  # as if killed before the end: a resume is due
    side.write_text(json.dumps(m))
    size = out.stat().st_size
    with open(out, "r+b") as f:
        f.truncate(size - 10)
    p = pu.run(cfg)
    assert p.returncode == 1 and p.stderr.count("\n") == 1, p.stderr
    assert f"{out}: {size - 10} bytes, shorter than the {size}" in p.stderr
    assert out.stat().st_size == size - 10  # never padded
    side.write_text("{not json")
    p = pu.run(cfg)
    assert p.returncode == 1 and p.stderr.count("\n") == 1, p.stderr
    assert f"{side}: not a CSV sink checkpoint" in p.stderr
    for bad in ({**m, "sizes": {"samples": "x", "summary": 0}}, {**m, "state": 3}, [1]):
        side.write_text(json.dumps(bad))
        p = pu.run(cfg)
        assert p.returncode == 1 and p.stderr.count("\n") == 1, p.stderr
        assert f"{side}: not a CSV sink checkpoint" in p.stderr
    # Another run's files.
    side.write_text(json.dumps({**m, "run": "other"}))
    p = pu.run(cfg)
    assert p.returncode == 1 and "belong to run 'other'" in p.stderr, p.stderr


@pytest.mark.parametrize(
    "sinks, message",
    [
        (csv_sink(pu.SAMPLE), f"sink[0].path = '{pu.SAMPLE}': the same file as source.path"),
        (
            csv_sink("a.csv") + csv_sink("b.csv", 'summary = "a.csv"\n'),
            "sink[1].summary = ",
        ),
        (csv_sink("a.csv", "colour = 1\n"), "sink[0].colour is not a known key"),
        (csv_sink("a.csv", "summary = 3\n"), "sink[0].summary = 3: must be a str"),
    ],
)
def test_csv_sink_configuration_errors(tmp_path, fmu_path, sinks, message):
    cfg = pu.write_config(tmp_path / "t.toml", source=pu.csv_source(), sinks=sinks, fmu=fmu_path)
    p = pu.run(cfg)
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert message in p.stderr and str(cfg) in p.stderr
