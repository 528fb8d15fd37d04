"""The stored input, recomputed ranges, retention and the checks at resume (docs/plant.md
"Storage", "Recomputing a range", "Retention", "Exactly once").

The reference is independent of the database: the clean run of the same file through the twin's
core in one go, in this process. A recomputed range comes out of the core too, not of SQLite, so
it is compared bit for bit (-0.0 included); the rows an SQLite database holds have SQLite's one
exception (no -0.0, docs/plant.md "Schema")."""

from __future__ import annotations

import random
import signal
import sqlite3
import subprocess
import sys
import time

import numpy as np
import plant_util as pu
import pytest

SEED = 2037
FMU = pu.ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"
REPEATS = 3
SPAN = 11.8 + 0.1  # the shipped sample's length and the gap between repetitions (bench_plant.py)


@pytest.fixture(scope="module")
def long_sample(tmp_path_factory):
    """The shipped sample three times, each 0.1 s after the last (a gap between them)."""
    path = tmp_path_factory.mktemp("data") / "long.csv"
    lines = pu.SAMPLE.read_text().splitlines()
    body = lines[1:]
    t = np.array([float(x.split(",")[0]) for x in body])
    rest = [x.split(",", 1)[1] for x in body]
    span = float(t[-1]) + 0.1
    with open(path, "w") as f:
        f.write(lines[0] + "\n")
        for k in range(REPEATS):
            f.write("".join(f"{v:.6f},{r}\n" for v, r in zip(t + k * span, rest)))
    return path


@pytest.fixture(scope="module")
def reference(fmu_path, long_sample):
    return pu.clean_run(fmu_path, long_sample)


def _recompute(db, run, t0, t1, **kw):
    from reciprocating_drive.plant.query import recompute

    seq, rows, _ = recompute(str(db), run, t0, t1, **kw)
    return np.column_stack([seq, rows]) if len(seq) else np.empty((0, rows.shape[1] + 1))


def _slice(ref, t0, t1):
    t = ref[:, 1]
    return ref[(t >= t0) & (t <= t1)]


def _config(tmp_path, data, sink_extra="", run_extra="", name="r1", pace=8.0, db=None):
    db = db or tmp_path / f"{name}.sqlite"
    return pu.write_config(
        tmp_path / f"{name}.toml",
        run=name,
        source=pu.csv_source(data, pace=pace),
        sinks=pu.sqlite_sink(db) + sink_extra,
        fmu=FMU,
        run_extra="commit_interval = 0.05\ncommit_samples = 2000\n" + run_extra,
    ), db


def test_sigkill_three_times_every_range_recomputes_bit_for_bit(tmp_path, long_sample, reference):
    """Killed three times with SIGKILL at random points: every recomputed range equals the clean
    run, which the rows the live run committed equal too; the rows still in the recent window
    (10 s) equal the recomputed ones."""
    ref = reference[0]
    cfg, db = _config(
        tmp_path,
        long_sample,
        sink_extra="keep_samples = 10\n",
        run_extra="snapshot_interval = 4\n",
    )
    rng = random.Random(SEED)
    progress = [0]
    for _ in range(3):
        p = pu.start(cfg)
        try:
            pu.wait_for_commit(pu_db := str(db), "r1", progress[-1], p)
            time.sleep(rng.uniform(0.0, 0.8))
            assert p.poll() is None, f"the run ended before the kill: {p.stderr.read()}"
            p.send_signal(signal.SIGKILL)
            p.wait(timeout=10)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait(timeout=10)
        progress.append(pu.committed(pu_db, "r1"))
    assert progress == sorted(progress) and len(set(progress)) == 4, progress
    assert progress[-1] < len(ref), progress
    done = pu.run(cfg)
    assert done.returncode == 0, done.stderr
    # The whole run, and ranges at random (across blocks, snapshots, gaps and restarts).
    t_end = float(ref[-1, 1])
    whole = _recompute(db, "r1", -1.0, t_end + 1)
    assert whole.shape == ref.shape
    assert np.array_equal(pu.bits(whole), pu.bits(ref)), "the recomputed run differs"
    for _ in range(6):
        t0 = rng.uniform(0, t_end)
        t1 = t0 + rng.uniform(0.0, 6.0)
        got = _recompute(db, "r1", t0, t1)
        assert np.array_equal(pu.bits(got), pu.bits(_slice(ref, t0, t1))), (t0, t1)
    # Retention: the rows held are those of the last 10 s, as recomputed.
    held = pu.samples(str(db), "r1")
    assert 0 < len(held) < len(ref) / 2
    assert held[0, 1] >= float(held[-1, 1]) - 10.0 - 0.01
    assert np.array_equal(held[:, 0], np.arange(held[0, 0], held[0, 0] + len(held)))
    again = _recompute(db, "r1", float(held[0, 1]), float(held[-1, 1]))
    assert pu.same_values(held, again, sqlite=True)
    # The snapshots: every 4 s of input, and the first one before any input.
    snaps = pu.query(str(db), "SELECT lines, t FROM snapshots ORDER BY lines")
    assert snaps[0] == (0, None) and len(snaps) >= 6, snaps


def test_a_block_changed_by_one_byte_is_named_with_its_range(tmp_path, long_sample, reference):
    """One byte of one stored block changed: a query that needs it names the block, its lines
    and times (exit 1, one line); a range before it is still recomputed; the resume names it
    and goes on."""
    cfg, db = _config(tmp_path, long_sample, run_extra="snapshot_interval = 4\n")
    p = pu.start(cfg)
    try:
        pu.wait_for_commit(str(db), "r1", 20000, p)
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    c = sqlite3.connect(db)
    blocks = c.execute(
        "SELECT first_line, last_line, t_first, t_last, data FROM input_blocks ORDER BY first_line"
    ).fetchall()
    assert len(blocks) >= 6, len(blocks)
    first, last, t0, t1, data = blocks[5]
    bad = bytearray(data)
    bad[len(bad) // 2] ^= 0x01
    c.execute("UPDATE input_blocks SET data = ? WHERE first_line = ?", (bytes(bad), first))
    c.commit()
    c.close()
    named = [f"lines {first}-{last}", f"{t0!r} s", f"{t1!r} s", "damaged"]
    p = _query_cli(db, "r1", t1 - 0.5, t1, tmp_path / "out.csv")
    lines = [x for x in p.stderr.splitlines() if x.strip()]
    assert p.returncode == 1 and len(lines) == 1, p.stderr
    assert all(w in lines[0] for w in named), lines[0]
    # Nothing else affected: a range before the block; the run resumes, says so, and ends.
    ref = reference[0]
    ok = _recompute(db, "r1", 1.0, 2.0)
    assert np.array_equal(pu.bits(ok), pu.bits(_slice(ref, 1.0, 2.0)))
    done = pu.run(cfg)
    assert done.returncode == 0, done.stderr
    said = [x for x in done.stderr.splitlines() if "damaged" in x]
    assert len(said) == 1 and all(w in said[0] for w in named), done.stderr
    assert any(e[1] == "damaged_input" for e in pu.events(str(db)))
    assert pu.same_values(pu.samples(str(db)), _slice(ref, pu.samples(str(db))[0, 1], 1e9), True)


def _query_cli(db, run, t0, t1, out, *extra):
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "reciprocating_drive.cli",
            "twin-query",
            "--db",
            str(db),
            "--run",
            run,
            "--from",
            repr(t0),
            "--to",
            repr(t1),
            "--out",
            str(out),
            *extra,
        ],
        env=pu.env(),
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_query_cli_writes_csv_and_parquet_of_a_range(tmp_path, reference):
    """`rdrive twin-query`: the range as CSV (as `rdrive twin` writes its rows) and as Parquet,
    both the clean run's values bit for bit."""
    import pyarrow.parquet as pq

    cfg, db = _config(tmp_path, pu.SAMPLE, pace=0.0)
    assert pu.run(cfg).returncode == 0
    ref = _slice(pu.clean_run(FMU)[0], 2, 4)
    p = _query_cli(db, "r1", 2.0, 4.0, tmp_path / "r.csv")
    assert p.returncode == 0, p.stderr
    text = (tmp_path / "r.csv").read_text().splitlines()
    assert text[0].startswith("time [s],")
    got = np.array([[float(v) for v in x.split(",")] for x in text[1:]])
    assert np.array_equal(pu.bits(got), pu.bits(ref[:, 1:]))
    p = _query_cli(db, "r1", 2.0, 4.0, tmp_path / "r.parquet")
    assert p.returncode == 0, p.stderr
    table = pq.read_table(tmp_path / "r.parquet")
    assert table.column_names[:2] == ["seq", "t"], table.column_names
    got = np.column_stack([table.column(i).to_numpy() for i in range(table.num_columns)])
    assert np.array_equal(pu.bits(got.astype(float)), pu.bits(ref))
    # A run computed with another build of the FMU (its GUID in the run's row): this FMU is
    # refused unless asked for, naming both GUIDs.
    other = "{00000000-0000-0000-0000-000000000037}"
    c = sqlite3.connect(db)
    c.execute("UPDATE runs SET fmu_guid = ?", (other,))
    c.commit()
    c.close()
    p = _query_cli(db, "r1", 2.0, 4.0, tmp_path / "x.csv")
    assert p.returncode == 1 and "--other-fmu" in p.stderr and other in p.stderr, p.stderr
    assert not (tmp_path / "x.csv").exists()
    p = _query_cli(db, "r1", 2.0, 4.0, tmp_path / "x.csv", "--other-fmu")
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "x.csv").read_text() == (tmp_path / "r.csv").read_text()


def test_retention_of_rows_and_of_input(tmp_path, long_sample, reference):
    """keep_samples: rows older than the window are gone, their range still recomputes.
    keep_input: input older than the age is gone from the last snapshot before it, and a query
    for it says so."""
    cfg, db = _config(
        tmp_path,
        long_sample,
        pace=0.0,
        sink_extra="keep_samples = 5\nkeep_input = 12\n",
        run_extra="snapshot_interval = 3\n",
    )
    done = pu.run(cfg)
    assert done.returncode == 0, done.stderr
    ref = reference[0]
    t_end = float(ref[-1, 1])
    held = pu.samples(str(db), "r1")
    assert held[0, 1] >= t_end - 5.0 - 0.05 and held[-1, 1] == t_end
    assert pu.same_values(held, _slice(ref, held[0, 1], t_end), sqlite=True)
    first_block = pu.query(str(db), "SELECT MIN(t_first) FROM input_blocks")[0][0]
    assert t_end - 12.0 - 3.5 <= first_block <= t_end - 12.0, first_block
    # Older than the rows held, still stored as input: recomputed.
    t0 = t_end - 11.0
    got = _recompute(db, "r1", t0, t0 + 1.0)
    assert np.array_equal(pu.bits(got), pu.bits(_slice(ref, t0, t0 + 1.0)))
    # Older than the input held: the query says so, with the time from which it can.
    p = _query_cli(db, "r1", 1.0, 2.0, tmp_path / "o.csv")
    assert p.returncode == 1 and "was removed (sink.keep_input)" in p.stderr, p.stderr


def _stopped_run(tmp_path, **kw):
    """A run stopped after some checkpoints (SIGKILL), its database to edit."""
    cfg, db = _config(tmp_path, pu.SAMPLE, **kw)
    p = pu.start(cfg)
    try:
        pu.wait_for_commit(str(db), "r1", 4000, p)
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    return cfg, db


@pytest.mark.parametrize(
    "edit, words",
    [
        ("DELETE FROM samples WHERE seq < 100", ["table samples", "holds", "covers"]),
        ("DELETE FROM events WHERE seq = 0", ["table events", "holds", "covers"]),
        ("UPDATE checkpoints SET samples = samples - 10", ["table checkpoints", "samples ="]),
        ("UPDATE runs SET status = 'finished'", ["table runs", "status 'finished'"]),
        (
            "UPDATE checkpoints SET state = replace(state, '\"events\": ', '\"events\": 1')",
            ["table checkpoints", "checksum"],
        ),
    ],
    ids=["rows deleted", "event deleted", "counts edited", "status edited", "state edited"],
)
def test_resume_checks_the_database_against_its_checkpoint(tmp_path, edit, words):
    """At resume the database is checked against its checkpoint: a mismatch is one line naming
    the table and the counts, exit 1, never a silent partial result."""
    cfg, db = _stopped_run(tmp_path)
    c = sqlite3.connect(db)
    c.execute(edit)
    c.commit()
    c.close()
    p = pu.run(cfg)
    lines = [x for x in p.stderr.splitlines() if x.strip()]
    assert p.returncode == 1 and len(lines) == 1, p.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert "run 'r1'" in lines[0]


def test_several_sinks_hold_the_same_events_after_one_lagged(tmp_path):
    """Two databases, one of them behind the other after a kill (its file as it was one restart
    earlier): when the run ends both hold the same rows and the same events, each once, numbered
    alike."""
    import shutil

    a, b = tmp_path / "a.sqlite", tmp_path / "b.sqlite"
    cfg = pu.write_config(
        tmp_path / "two.toml",
        source=pu.csv_source(pace=6.0),
        sinks=pu.sqlite_sink(a) + pu.sqlite_sink(b),
        fmu=FMU,
        run_extra="commit_interval = 0.05\ncommit_samples = 1000\n",
    )
    saved = tmp_path / "saved"
    saved.mkdir()
    progress = 0
    for k in range(2):
        p = pu.start(cfg)
        try:
            progress = pu.wait_for_commit(str(b), "r1", progress + 1500, p)
            p.send_signal(signal.SIGKILL)
            p.wait(timeout=10)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait(timeout=10)
        if k == 0:
            for f in tmp_path.glob("a.sqlite*"):
                shutil.copy(f, saved / f.name)
    # Sink a lags: its files as they were after the first kill.
    for f in tmp_path.glob("a.sqlite*"):
        f.unlink()
    for f in saved.iterdir():
        shutil.copy(f, tmp_path / f.name)
    assert pu.committed(str(a), "r1") < pu.committed(str(b), "r1")
    done = pu.run(cfg)
    assert done.returncode == 0, done.stderr
    ev_a = pu.query(
        str(a), "SELECT seq, t, wall_time, kind, count, message FROM events ORDER BY seq"
    )
    ev_b = pu.query(
        str(b), "SELECT seq, t, wall_time, kind, count, message FROM events ORDER BY seq"
    )
    assert ev_a == ev_b
    assert [e[0] for e in ev_a] == list(range(len(ev_a)))
    sa, sb = pu.samples(str(a)), pu.samples(str(b))
    assert len(sa) == len(sb) and pu.same_values(sa, sb, sqlite=False)
    assert pu.revolutions(str(a)) == pu.revolutions(str(b))


def test_an_older_schema_is_migrated(tmp_path):
    """A database of schema version 2 (no stored input) is migrated when the twin opens it: its
    runs keep their rows, new runs store their input; a range of an old run says why it cannot
    be recomputed."""
    from reciprocating_drive.revolution import PUMP_COLUMNS

    cfg, db = _config(tmp_path, pu.SAMPLE, pace=0.0, name="old")
    assert pu.run(cfg).returncode == 0
    c = sqlite3.connect(db)
    # Back to version 2: without the columns and tables version 3 added.
    for table, col in [
        ("runs", "fmu_guid"),
        ("checkpoints", "checksum"),
        ("checkpoints", "samples_from"),
        ("checkpoints", "revolutions_from"),
        ("checkpoints", "events_from"),
        *(("revolutions", c) for c in PUMP_COLUMNS),
    ]:
        c.execute(f"ALTER TABLE {table} DROP COLUMN {col}")
    c.execute("DROP TABLE input_blocks")
    c.execute("DROP TABLE snapshots")
    c.execute("UPDATE schema_info SET version = 2")
    c.commit()
    c.close()
    n_old = len(pu.samples(str(db), "old"))
    cfg2, _ = _config(tmp_path, pu.SAMPLE, pace=0.0, name="new", db=db)
    done = pu.run(cfg2)
    assert done.returncode == 0, done.stderr
    assert pu.query(str(db), "SELECT version FROM schema_info") == [(3,)]
    cols = {r[1] for r in pu.query(str(db), "PRAGMA table_info(revolutions)")}
    assert set(PUMP_COLUMNS) <= cols  # a pump's summary columns added
    assert len(pu.samples(str(db), "old")) == n_old
    ref = pu.clean_run(FMU)[0]
    assert np.array_equal(pu.bits(_recompute(db, "new", 0, 1)), pu.bits(_slice(ref, 0, 1)))
    p = _query_cli(db, "old", 0, 1, tmp_path / "o.csv")
    assert p.returncode == 1 and "no stored input" in p.stderr, p.stderr


def test_opcua_run_killed_before_its_first_checkpoint_restarts_from_its_first_sample(tmp_path):
    """An OPC UA run killed before its first checkpoint (rows committed, no checkpoint yet):
    its run and time origin were committed at once, so the restart reads the server's history
    from the run's first sample and the run holds the file replay's rows bit for bit."""
    ref = pu.clean_run(FMU)
    plc = pu.PlcProcess("--speed", "2", "--start-delay", "2")
    source = (
        f'type = "opcua"\nendpoint = "{plc.endpoint}"\nangle_node = "ns=2;s=Pump.CrankAngle"\n'
        'end_node = "ns=2;s=Pump.Finished"\nangle_unit = "counts"\ncounts_per_rev = 4096\n'
        "reconnect_max = 0.5\n"
    )
    db = tmp_path / "early.sqlite"
    cfg = pu.write_config(
        tmp_path / "early.toml",
        run="early",
        source=source,
        sinks=pu.sqlite_sink(db),
        fmu=FMU,
        run_extra="checkpoint_interval = 1000\n",
    )

    def rows_held():
        try:
            return pu.query(str(db), "SELECT COUNT(*) FROM samples")[0][0]
        except sqlite3.Error:
            return 0

    p = pu.start(cfg)
    try:
        with plc:
            deadline = time.monotonic() + 60
            while rows_held() < 500:
                assert p.poll() is None and time.monotonic() < deadline, p.stderr.read()
                time.sleep(0.02)
            p.send_signal(signal.SIGKILL)
            p.wait(timeout=10)
            assert pu.query(str(db), "SELECT state FROM checkpoints") in ([], [("",)])
            assert pu.query(str(db), "SELECT time_origin FROM runs")[0][0] is not None
            p = pu.start(cfg)
            out, err = p.communicate(timeout=90)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 0, err
    got = pu.samples(str(db), "early")
    assert got.shape == ref[0].shape, (got.shape, ref[0].shape)
    assert pu.same_values(got, ref[0], sqlite=True)
    assert [r[1:] for r in pu.revolutions(str(db), "early")] == ref[1]


def test_the_page_opens_a_range_at_full_resolution(tmp_path):
    """The page's /api/range: every output of a range as CSV, recomputed, the clean run's values
    bit for bit; a range too long or of no run is a status and one line."""
    import urllib.error
    import urllib.request

    from reciprocating_drive.page.server import PageServer
    from reciprocating_drive.plant.query import page_recompute

    cfg, db = _config(tmp_path, pu.SAMPLE, pace=0.0)
    assert pu.run(cfg).returncode == 0
    ref = _slice(pu.clean_run(FMU)[0], 2.5, 3.5)
    page = PageServer(port=0, database=str(db), run="r1")
    page.recompute = page_recompute(str(db), "r1")  # as the plant and the page's command do
    page.start()
    try:
        base = f"http://127.0.0.1:{page.port}"
        with urllib.request.urlopen(f"{base}/api/range?from=2.5&to=3.5", timeout=60) as r:
            text = r.read().decode().splitlines()
        got = np.array([[float(v) for v in x.split(",")] for x in text[1:]])
        assert np.array_equal(pu.bits(got), pu.bits(ref[:, 1:]))
        for q, code in (("from=0&to=1000", 400), ("from=x&to=1", 400)):
            with pytest.raises(urllib.error.HTTPError) as e:
                urllib.request.urlopen(f"{base}/api/range?{q}", timeout=60)
            assert e.value.code == code
        index = urllib.request.urlopen(f"{base}/", timeout=10).read().decode()
        assert 'action="/api/range"' in index
    finally:
        page.close()


def test_postgres_stores_the_input_and_recomputes_bit_for_bit(pg, tmp_path, long_sample, reference):
    """PostgreSQL: the same storage; killed once and finished, a recomputed range equals the rows
    the live run committed (float8, -0.0 included) bit for bit; keep_samples deletes there too."""
    run_id = "pg-" + str(time.time_ns())
    cfg = pu.write_config(
        tmp_path / "pg.toml",
        run=run_id,
        source=pu.csv_source(long_sample, pace=8.0),
        sinks=pu.pg_sink(pg.dsn, extra="keep_samples = 20\n"),
        fmu=FMU,
        run_extra="commit_interval = 0.05\ncommit_samples = 2000\nsnapshot_interval = 4\n",
    )
    p = pu.start(cfg)
    try:
        pu.wait_for_commit(pg.dsn, run_id, 8000, p)
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    done = pu.run(cfg)
    assert done.returncode == 0, done.stderr
    held = pu.samples(pg.dsn, run_id)
    ref = reference[0]
    assert 0 < len(held) < len(ref)
    from reciprocating_drive.plant.query import recompute

    seq, rows, _ = recompute(pg.dsn, run_id, float(held[0, 1]), float(held[-1, 1]), fmu=str(FMU))
    assert np.array_equal(pu.bits(np.column_stack([seq, rows])), pu.bits(held))
    seq, rows, _ = recompute(pg.dsn, run_id, 0.0, 5.0, fmu=str(FMU))
    assert np.array_equal(pu.bits(np.column_stack([seq, rows])), pu.bits(_slice(ref, 0.0, 5.0)))


def test_a_range_recomputed_by_two_processes_is_the_same(tmp_path, long_sample, reference):
    """--workers 2: the stretches between the snapshots inside the range, each in a process of
    its own, joined in order: the clean run's rows, each once."""
    cfg, db = _config(tmp_path, long_sample, pace=0.0, run_extra="snapshot_interval = 4\n")
    assert pu.run(cfg).returncode == 0
    ref = reference[0]
    got = _recompute(db, "r1", 3.0, 30.0, workers=2)
    assert np.array_equal(pu.bits(got), pu.bits(_slice(ref, 3.0, 30.0)))
    p = _query_cli(db, "r1", 3.0, 30.0, tmp_path / "w.parquet", "--workers", "2")
    assert p.returncode == 0, p.stderr


def test_plant_status_shows_size_bytes_per_sample_and_days_until_full(tmp_path):
    """`rdrive plant --status`: the database's size and samples, bytes a sample (its file size
    over the checkpoint's samples), and the days until its disk is full at the input's rate."""
    import shutil

    cfg, db = _config(tmp_path, pu.SAMPLE, pace=0.0)
    assert pu.run(cfg).returncode == 0
    size = db.stat().st_size  # the run's end emptied its write-ahead log into the file
    p = subprocess.run(
        [sys.executable, str(pu.SCRIPT), "--status", "--config", str(cfg)],
        env=pu.env(),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert p.returncode == 0, p.stderr
    first, second = p.stdout.splitlines()[:2]
    n = len(pu.samples(str(db)))
    assert f"{size / 1e6:.1f} MB, {n} samples in 1 run(s), {size / n:.1f} bytes a sample" in first
    rate = float(second.split(" samples/s")[0].split()[-1])
    assert 950 < rate < 1000, second  # the shipped sample: 11 801 samples in 12 s
    free = shutil.disk_usage(tmp_path).free / 1e9
    said = float(second.split(" GB free")[0].split()[-1])
    day = float(second.split(" GB a day")[0].split()[-1])
    days = float(second.split("full in ")[1].split()[0])
    assert abs(said - free) < 1.0 and day > 0, second
    assert abs(days - said / day) <= max(1.0, 0.05 * days), second
