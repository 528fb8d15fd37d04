"""Exactly once (docs/plant.md): the twin killed with SIGKILL at random points and restarted, and
PostgreSQL restarted in the middle of a run, against an uninterrupted run into a fresh database.
The reference is the uninterrupted run; the comparison is bit for bit on every per-sample value,
and the primary keys of the schema make any repeated row an error of its transaction."""

from __future__ import annotations

import random
import signal
import time

import numpy as np
import plant_util as pu
import pytest

SEED = 2025


@pytest.fixture(scope="module")
def reference(fmu_path):
    return pu.clean_run(fmu_path)


def _same(db, reference, run="r1"):
    ref_s, ref_r, ref_gaps = reference
    got = pu.samples(db, run)
    assert got.shape == ref_s.shape, f"{len(got)} samples stored, the clean run has {len(ref_s)}"
    assert np.array_equal(got[:, 0], np.arange(len(got))), "a sample is missing or repeated"
    assert pu.same_values(got, ref_s, sqlite=not db.startswith("host=")), "values differ"
    assert [r[1:] for r in pu.revolutions(db, run)] == ref_r
    ev = pu.events(db, run)
    assert [e[3] for e in ev if e[1] == "gap"] == ref_gaps
    assert [e[0] for e in ev] == list(range(len(ev))), "event numbers not consecutive"
    return ev


def _rows_after_checkpoint(db, run) -> int:
    """Sample rows committed beyond what the run's checkpoint covers."""
    got = pu.query(
        db,
        "SELECT COUNT(*) FROM samples s JOIN runs r ON r.run = s.run JOIN checkpoints c "
        "ON c.run = r.run WHERE r.name = ? AND s.seq >= c.samples",
        (run,),
    )
    return got[0][0] if got else 0


@pytest.mark.parametrize("kind", ["sqlite", "postgres"])
def test_sigkill_three_times_loses_nothing_and_repeats_nothing(
    kind, fmu_path, tmp_path, reference, request
):
    db = str(tmp_path / "twin.sqlite")
    if kind == "postgres":
        pg = request.getfixturevalue("pg")
        db = pg.dsn
        run_id = "kill-" + str(time.time_ns())
        sink = pu.pg_sink(db)
    else:
        run_id = "r1"
        sink = pu.sqlite_sink(db)
    # Paced at 6x real time (12 s of data in about 2 s) so that the kills fall inside the run.
    cfg = pu.write_config(
        tmp_path / "t.toml",
        run=run_id,
        source=pu.csv_source(pace=6.0),
        sinks=sink,
        fmu=fmu_path,
        run_extra="commit_interval = 0.05\ncommit_samples = 2000\n",
    )
    rng = random.Random(SEED + (kind == "postgres"))
    progress = [0]

    uncovered = []
    for k in range(3):
        p = pu.start(cfg)
        try:
            # Once this run has committed a checkpoint of its own, a random moment later: SIGKILL.
            # The first kill waits until rows after the checkpoint are committed (rows go out
            # every 0.05 s, checkpoints every 2000 lines): they must be deleted and made again.
            pu.wait_for_commit(db, run_id, progress[-1], p)
            if k == 0:
                deadline = time.monotonic() + 30
                while _rows_after_checkpoint(db, run_id) == 0:
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
        progress.append(pu.committed(db, run_id))
        uncovered.append(_rows_after_checkpoint(db, run_id))
    # Each restart got further, and the kills fell inside the run (not after its end).
    assert progress == sorted(progress) and len(set(progress)) == 4, progress
    assert uncovered[0] > 0, uncovered
    assert progress[-1] < len(reference[0]), progress
    done = pu.run(cfg)
    assert done.returncode == 0, done.stderr
    ev = _same(db, reference, run_id)
    assert 1 <= len([e for e in ev if e[1] == "resumed"]) <= 4
    assert pu.query(db, "SELECT status FROM runs WHERE name = ?", (run_id,)) == [("finished",)]
    # Run once more: nothing to do, nothing added.
    again = pu.run(cfg)
    assert again.returncode == 0 and "already finished" in again.stderr
    assert len(pu.samples(db, run_id)) == len(reference[0])


def test_postgres_restart_mid_run_buffers_and_loses_nothing(pg, fmu_path, tmp_path, reference):
    run_id = "restart-" + str(time.time_ns())
    cfg = pu.write_config(
        tmp_path / "t.toml",
        run=run_id,
        source=pu.csv_source(pace=4.0),
        sinks=pu.pg_sink(pg.dsn, extra="retry_for = 60\nretry_max = 0.5\n"),
        fmu=fmu_path,
        run_extra="commit_interval = 0.05\ncommit_samples = 300\n",
    )
    p = pu.start(cfg)
    try:
        before = pu.wait_for_commit(pg.dsn, run_id, 0, p)
        pg.restart_after(3.0)  # down for 3 s: the twin goes on reading and computing
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 0, err
    assert 0 < before < len(reference[0])
    ev = _same(pg.dsn, reference, run_id)
    retries = [e for e in ev if e[1] == "sink_retry"]
    assert retries and retries[0][2] >= 1, ev


def test_postgres_password_from_the_environment_and_a_refused_login(pg, fmu_path, tmp_path):
    """The password comes from an environment variable; a wrong one is refused at once (not
    retried as an outage) with one line, and neither password is printed."""
    import os
    import subprocess
    import sys

    secret = "pg-S3cret-pw"
    dsn = pg.add_password_user("pwuser", secret)
    short = tmp_path / "short.csv"
    short.write_text("\n".join(pu.SAMPLE.read_text().splitlines()[:1001]) + "\n")
    cfg = pu.write_config(
        tmp_path / "pw.toml",
        run="pw-" + str(time.time_ns()),
        source=pu.csv_source(short),
        sinks=pu.pg_sink(dsn, extra='password_env = "TWIN_TEST_PG_PW"\n'),
        fmu=fmu_path,
    )
    for pw, status in ((secret, 0), ("wrong-" + secret, 1)):
        p = subprocess.run(
            [sys.executable, str(pu.SCRIPT), "--config", str(cfg)],
            env={**pu.env(), "TWIN_TEST_PG_PW": pw},
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert p.returncode == status, p.stderr
        assert secret not in p.stdout + p.stderr
    assert "password authentication failed" in p.stderr and p.stderr.count("\n") == 1
    assert len(pu.samples(pg.dsn, cfg.read_text().split('"')[1])) == 1000
    assert "TWIN_TEST_PG_PW" not in os.environ
