"""Distributed replay (`rdrive twin --distributed`, docs/twin.md "Distributed replay").

The reference is always the sequential replay of the same file (scripts/twin.py without
--distributed): a rigid rod's files must be identical byte for byte wherever the cuts fall; an
elastic rod's rod.angle within 1e-8 rad. Dask runs for real: a LocalCluster of worker processes
on 127.0.0.1, and the resume test kills the replay with a real signal."""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import ROOT
from reciprocating_drive.commands.twin_distributed import worker_options
from reciprocating_drive.twin import Options, summary_header
from reciprocating_drive.twin import replay as R
from reciprocating_drive.twin.sample import encoder_samples, truth

TWIN = [sys.executable, str(ROOT / "scripts" / "twin.py")]
SAMPLE = ROOT / "data" / "twin" / "pump_encoder.csv"
COUNTS = ["--angle-unit", "counts", "--counts-per-rev", "4096"]


def twin(args, fmu_path, timeout=300, check=True):
    p = subprocess.run(
        [*TWIN, *map(str, args), "--fmu", fmu_path], capture_output=True, text=True, timeout=timeout
    )
    if check and p.returncode != 0:
        raise AssertionError(f"exit {p.returncode}: {p.stderr}")
    return p


def sequential(fmu_path, tmp_path, inp, args):
    out = tmp_path / "seq.csv"
    twin([inp, *args, "--out", out], fmu_path)
    return out.read_bytes(), (tmp_path / "seq-revolutions.csv").read_bytes()


def local_pieces(sc, pieces, fmu_path):
    """The pieces computed in this process (the function the workers run), assembled."""
    names = ("line", "t", "theta", "speed", "force")
    outs, revs = [], []
    for p in pieces:
        w, f = p[2], p[3]
        out, rev, _, _ = R.run_piece(
            fmu_path,
            sc.values,
            worker_options(sc.options),
            sc.cols,
            sc.offset,
            p,
            tuple(sc.data[n][w:f] for n in names),
        )
        outs.append(out)
        revs.append(rev)
    head = (",".join(sc.header) + "\n").encode()
    return head + b"".join(outs), (",".join(summary_header()) + "\n").encode() + b"".join(revs)


def one_line_error(p, code, *words):
    assert p.returncode == code, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert "Traceback" not in p.stderr
    for w in words:
        assert w in lines[0], lines[0]


def test_cuts_anywhere_are_bit_identical(fmu_path, tmp_path):
    """Cuts next to the gap (either side), at the first and last samples, every revolution:
    the unwrapped angle, the window, the FMU and the revolutions are all carried exactly."""
    seq = sequential(fmu_path, tmp_path, SAMPLE, COUNTS)
    sc = R.scan(str(SAMPLE), fmu_path, "default", Options(angle_unit="counts", counts_per_rev=4096))
    n = len(sc.data["t"])
    g = int(np.flatnonzero(np.diff(sc.data["t"]) > sc.options.gap_limit)[0]) + 1
    cases = [
        (None, [1, n - 1]),  # one sample in the first and in the last piece
        (None, [g - 1, g + 1]),  # next to the gap, both sides
        (None, [g - 2, 2, n - 2]),
        (1, []),  # every revolution
        (4, [g + 3]),
    ]
    for n_rev, cuts in cases:
        pieces = R.plan(sc, n_rev, None, cuts)
        assert len(pieces) >= 2 + len(cuts)
        assert local_pieces(sc, pieces, fmu_path) == seq, (n_rev, cuts)


def test_local_cluster_is_bit_identical_and_shows_progress(fmu_path, tmp_path):
    seq = sequential(fmu_path, tmp_path, SAMPLE, COUNTS)
    out = tmp_path / "d.csv"
    args = [SAMPLE, *COUNTS, "--out", out, "--distributed", "--workers", "2"]
    p = twin([*args, "--revolutions-per-piece", "3"], fmu_path)
    assert (out.read_bytes(), (tmp_path / "d-revolutions.csv").read_bytes()) == seq
    assert "6/6 pieces, 11801/11801 samples" in p.stderr and "samples/s" in p.stderr
    assert "11801 samples, 0 duplicate timestamps dropped, 1 gap(s)" in p.stdout
    assert not (tmp_path / "d.csv.parts").exists()  # the work folder goes once assembled
    q = twin([*args, "--quiet"], fmu_path)  # pieces only at the gap
    assert q.stderr.strip().splitlines() == [
        line for line in p.stderr.splitlines() if line.startswith("twin.py: gap")
    ]
    assert (out.read_bytes(), (tmp_path / "d-revolutions.csv").read_bytes()) == seq


def test_pieces_placed_by_workers_or_by_the_client_assemble_the_sequential_files(
    fmu_path, tmp_path
):
    """The shared-disk path without Dask, each step the real function: a "worker" finds piece 1
    claimed by another, so it cannot know where pieces 2.. start: it keeps them waiting and
    writes them to files of their own at the end of its list; the other worker then computes
    piece 1, whose place is known, and writes it into the rows file. The assembler copies the
    waiting ones to their places. The files equal the sequential replay's; the records say
    which piece went which way."""
    seq = sequential(fmu_path, tmp_path, SAMPLE, COUNTS)
    sc = R.scan(str(SAMPLE), fmu_path, "default", Options(angle_unit="counts", counts_per_rev=4096))
    pieces = R.plan(sc, 3, None)
    assert len(pieces) >= 4
    work = tmp_path / "work"
    head = R.header_bytes(sc.header)
    assert R.open_work(work, R.manifest_of(sc, "default", pieces, {}), head) == set()
    R.save_inputs(work, sc.data)
    common = (fmu_path, sc.values, worker_options(sc.options), sc.cols, sc.offset)
    items = [(i, p) for i, p in enumerate(pieces)]
    assert R._claim(work, 1)  # "another worker" has piece 1
    assert R.run_claimed(*common, items, str(work), len(head)) == len(pieces) - 1
    (work / "claim-000001").unlink()
    assert R.run_claimed(*common, items[1:2], str(work), len(head)) == 1
    recs = [json.loads((work / f"piece-{i:06d}.json").read_text()) for i in range(len(pieces))]
    placed = [i for i, r in enumerate(recs) if "at" in r]
    assert placed == [0, 1]  # pieces 2.. waited for piece 1's length: in files of their own
    assert all((work / f"piece-{i:06d}.csv").exists() for i in range(2, len(pieces)))
    out, summary = tmp_path / "d.csv", tmp_path / "d-revolutions.csv"
    asm = R.Assembler(work, len(pieces), out, summary, summary_header())
    for i in reversed(range(len(pieces))):  # in any order: each is placed once those before are
        asm.add(i)
    asm.finish()
    assert (out.read_bytes(), summary.read_bytes()) == seq
    assert not list(tmp_path.glob("*.tmp"))


def test_a_local_worker_killed_its_claimed_piece_is_computed_again(fmu_path, tmp_path):
    """A LocalCluster: one worker process killed (SIGKILL) while pieces run. The piece it had
    claimed is computed in another round; the files are the sequential replay's, byte for
    byte."""
    import psutil

    inp = longer_encoder_file(tmp_path / "long.csv", 30.0)
    seq = sequential(fmu_path, tmp_path, inp, COUNTS)
    out = tmp_path / "d.csv"
    work = tmp_path / "d.csv.parts"
    args = [inp, *COUNTS, "--out", out, "--distributed", "--workers", "2"]
    args += ["--revolutions-per-piece", "5", "--fmu", fmu_path]

    def kill_a_worker(run):
        # The worker processes: the replay's children that run multiprocessing's spawn.
        workers = [
            c
            for c in psutil.Process(run.pid).children()
            if "multiprocessing.spawn" in " ".join(c.cmdline())
        ]
        assert len(workers) == 2, [c.cmdline() for c in workers]
        workers[0].kill()

    code, err = interrupted(args, work, 2, kill_a_worker)
    assert code == 0, err
    # Killed mid-piece (a piece takes about 30 ms, the step between two a fraction of one).
    assert "claimed by a worker that was lost are computed again" in err, err
    assert (out.read_bytes(), (tmp_path / "d-revolutions.csv").read_bytes()) == seq


def test_a_work_folder_on_another_file_system(fmu_path, tmp_path):
    """--work-dir on another file system than --out (tmpfs /dev/shm against the test's folder):
    the rows file cannot be renamed there, so it is copied; the files are the sequential
    replay's and the work folder goes."""
    import tempfile

    if not os.path.isdir("/dev/shm") or os.stat("/dev/shm").st_dev == os.stat(tmp_path).st_dev:
        pytest.skip("no second file system (/dev/shm) here")
    seq = sequential(fmu_path, tmp_path, SAMPLE, COUNTS)
    out = tmp_path / "d.csv"
    with tempfile.TemporaryDirectory(dir="/dev/shm") as shm:
        work = os.path.join(shm, "parts")
        args = [SAMPLE, *COUNTS, "--out", out, "--distributed", "--workers", "2"]
        twin([*args, "--revolutions-per-piece", "3", "--work-dir", work], fmu_path)
        assert not os.path.exists(work)
    assert (out.read_bytes(), (tmp_path / "d-revolutions.csv").read_bytes()) == seq
    assert not list(tmp_path.glob("*.tmp"))


def kvo630_file(path, seconds=2.0):
    """Exact crank angles of kvo630 at its design speed (157.08 rad/s, the sample's ±3 % speed
    fluctuation twice per revolution, time scaled), 1 kHz, wrapped, in rad."""
    scale = 157.07963267948966 / truth(0.0)[1]
    t = np.arange(int(seconds * 1000) + 1) / 1000.0
    theta = truth(t * scale)[0]
    wrapped = np.mod(theta, 2 * math.pi)
    rows = zip(t.tolist(), wrapped.tolist())
    path.write_text("time,crank_angle\n" + "".join(f"{a!r},{b!r}\n" for a, b in rows))
    return path


def test_elastic_rod_warm_up_from_the_damping(fmu_path, tmp_path):
    """kvo630: the cage's decay rate from the model's damping (checked against the reference
    formulation of docs/model.md §6), and rod.angle of pieces with that warm-up within 1e-8 rad
    of the sequential replay; without the warm-up it is far outside."""
    import rod_reference
    from reciprocating_drive.fmu import Fmu
    from reciprocating_drive.presets import preset_values

    starts = {n: v.start for n, v in Fmu(fmu_path).variables.items()}
    values = preset_values("kvo630")
    rod = rod_reference.Rod.from_values({**starts, **values})
    sigma = R.cage_decay_rate(values, starts)
    ref = values["rod.damping_ratio"] * math.sqrt(
        rod.column(0.0).k_theta / values["rod.cage_inertia"]
    )
    assert sigma == pytest.approx(ref, rel=1e-12)
    assert R.cage_decay_rate({}, starts) is None  # the default machine's rigid rod
    assert R.warm_up_time(sigma) == pytest.approx(math.log(1e8) / sigma)

    inp = kvo630_file(tmp_path / "kvo.csv")
    args = ["--machine", "kvo630"]
    seq_out, _ = sequential(fmu_path, tmp_path, inp, args)
    sc = R.scan(str(inp), fmu_path, "kvo630", Options())
    assert sc.sigma == sigma
    ref_rows = np.loadtxt(seq_out.decode().splitlines()[1:], delimiter=",")
    col = sc.header.index("rod.angle [rad]")

    def error(overlap):
        pieces = R.plan(sc, 10, overlap)
        assert len(pieces) >= 5
        rows = np.loadtxt(
            local_pieces(sc, pieces, fmu_path)[0].decode().splitlines()[1:], delimiter=","
        )
        assert rows.shape == ref_rows.shape and np.array_equal(rows[:, 0], ref_rows[:, 0])
        return float(np.max(np.abs(rows[:, col] - ref_rows[:, col])))

    assert error(None) <= 1e-8
    assert error(0.0) > 1e-5  # the cage did not forget its start: the warm-up is what works


def longer_encoder_file(path, seconds):
    t, c = encoder_samples(duration=seconds, gap=(6.0, 6.2))
    rows = zip(t.tolist(), c.tolist())
    path.write_text("time,crank_angle\n" + "".join(f"{a!r},{b}\n" for a, b in rows))
    return path


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_killed_replay_resumes_bit_identical(fmu_path, tmp_path, sig):
    inp = longer_encoder_file(tmp_path / "long.csv", 40.0)
    seq = sequential(fmu_path, tmp_path, inp, COUNTS)
    out = tmp_path / "d.csv"
    work = tmp_path / "d.csv.parts"
    args = [inp, *COUNTS, "--out", out, "--distributed", "--workers", "1"]
    args += ["--revolutions-per-piece", "2", "--fmu", fmu_path]
    code, err = interrupted(args, work, 3, lambda p: p.send_signal(sig), timeout=60)
    assert code == 128 + sig, err
    assert "run the same command again to resume" in err and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.glob("*.tmp"))  # nothing half-assembled
    done = sorted(work.glob("piece-*.json"))
    assert 3 <= len(done) < 22

    # Another run's options: refused in one line, nothing touched.
    p = twin([*args, "--window", "0.2"], fmu_path, check=False)
    one_line_error(p, 2, "manifest.json", "--window 0.1 differs from this run's 0.2")
    # A piece's rows damaged after they were written (a byte changed at their place in the
    # rows file, found by its record's CRC-32): that piece is computed again.
    rec = json.loads((work / "piece-000000.json").read_text())
    assert rec["at"] > 0  # placed in the rows file by its worker
    with open(work / "rows.csv", "r+b") as fh:
        fh.seek(rec["at"] + rec["out"][0] // 2)
        b = fh.read(1)
        fh.seek(-1, os.SEEK_CUR)
        fh.write(bytes([b[0] ^ 1]))
    p = twin(args, fmu_path)
    assert f"resuming: {len(done) - 1} of " in p.stderr
    assert (out.read_bytes(), (tmp_path / "d-revolutions.csv").read_bytes()) == seq


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_hostile_options_and_files(fmu_path, tmp_path):
    out = tmp_path / "d.csv"
    base = [SAMPLE, *COUNTS, "--out", out]
    p = twin([*base, "--distributed", "--revolutions-per-piece", "0"], fmu_path, check=False)
    one_line_error(p, 2, "--revolutions-per-piece", "'0'", "at least 1")
    p = twin([*base, "--distributed", "--overlap", "-1"], fmu_path, check=False)
    one_line_error(p, 2, "--overlap", "'-1'", ">= 0")
    p = twin([*base, "--distributed", "--overlap", "nan"], fmu_path, check=False)
    one_line_error(p, 2, "--overlap", "'nan'")
    p = twin([*base, "--workers", "2"], fmu_path, check=False)
    one_line_error(p, 2, "--workers", "needs --distributed")
    p = twin([*base, "--distributed", "--follow"], fmu_path, check=False)
    one_line_error(p, 2, "--follow", "--distributed")
    p = twin(["-", "--out", out, "--distributed"], fmu_path, check=False)
    one_line_error(p, 2, "standard input")
    # No sample at all: the scan refuses it before any cluster starts.
    empty = tmp_path / "empty.csv"
    empty.write_text("time,crank_angle\n")
    p = twin([empty, "--out", out, "--distributed"], fmu_path, check=False)
    one_line_error(p, 1, "empty.csv", "no sample")
    bad = tmp_path / "bad.csv"
    bad.write_text(SAMPLE.read_text().replace("\n5.0", "\nx5.0", 1))
    p = twin([bad, *COUNTS, "--out", out, "--distributed"], fmu_path, check=False)
    one_line_error(p, 1, "bad.csv: line", "is not a number")
    assert not out.exists()
    # A scheduler nobody runs: refused within the connect timeout.
    t0 = time.monotonic()
    port = free_port()
    p = twin(
        [
            *base,
            "--distributed",
            "--scheduler",
            f"tcp://127.0.0.1:{port}",
            "--connect-timeout",
            "2",
        ],
        fmu_path,
        check=False,
        timeout=60,
    )
    one_line_error(p, 2, "--scheduler", "connection refused")
    assert time.monotonic() - t0 < 30
    # A damaged manifest: refused, the folder left as it is.
    work = tmp_path / "w"
    work.mkdir()
    (work / "manifest.json").write_text('{"version": 1, "pieces": [')
    p = twin([*base, "--distributed", "--work-dir", work], fmu_path, check=False)
    one_line_error(p, 2, "manifest.json", "damaged")
    assert (work / "manifest.json").read_text() == '{"version": 1, "pieces": ['
    assert not out.exists()


@contextlib.contextmanager
def scheduler_and_workers(where, n_workers):
    """A real scheduler and `n_workers` worker processes (no nanny: a killed one stays dead) on
    127.0.0.1, started in `where`; yields (address, worker processes); stops them all."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "python")}
    quiet = {"cwd": where, "env": env, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1"]
            + ["--port", str(port), "--dashboard-address", ":0"],
            **quiet,
        )
    ]
    try:
        for _ in range(n_workers):
            procs.append(
                subprocess.Popen(
                    [sys.executable, "-m", "distributed.cli.dask_worker", address]
                    + ["--nthreads", "1", "--no-nanny", "--local-directory", str(where)]
                    + ["--dashboard-address", ":0"],
                    **quiet,
                )
            )
        from dask.distributed import Client

        with Client(address, timeout=30) as client:
            client.wait_for_workers(n_workers, timeout=90)
        yield address, procs[1:]
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=10)


def interrupted(args, work, pieces, act, timeout=300):
    """Runs the replay and calls act(process) once `pieces` pieces are written to `work`;
    (exit code, stderr). The replay is killed if it is still running at the end."""
    run = subprocess.Popen(
        [*TWIN, *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        deadline = time.monotonic() + 120
        while len(list(work.glob("piece-*.json"))) < pieces:
            assert run.poll() is None, run.communicate()
            assert time.monotonic() < deadline, "no piece written within 120 s"
            time.sleep(0.01)
        act(run)
        _, err = run.communicate(timeout=timeout)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait(10)
    return run.returncode, err


def start_and_kill_a_worker(args, work, worker, timeout=300):
    """Runs the replay, kills `worker` once two pieces are written; (exit code, stderr)."""
    code, err = interrupted(args, work, 2, lambda _: worker.kill(), timeout)
    assert worker.wait(10) != 0  # it was killed, not done
    return code, err


def test_a_cluster_without_shared_disk_and_a_worker_killed(fmu_path, tmp_path):
    """--scheduler: a real scheduler and two worker processes on 127.0.0.1, started in their own
    empty folder (the pieces come back as bytes; the FMU arrives through the worker plugin). One
    worker is killed (SIGKILL) while pieces run: Dask runs its pieces on the other, and the result
    is still the sequential replay's, byte for byte."""
    inp = longer_encoder_file(tmp_path / "long.csv", 30.0)
    seq = sequential(fmu_path, tmp_path, inp, COUNTS)
    where = tmp_path / "cluster"
    where.mkdir()
    out = tmp_path / "d.csv"
    with scheduler_and_workers(where, 2) as (address, workers):
        args = [inp, *COUNTS, "--out", out, "--distributed", "--scheduler", address]
        args += ["--revolutions-per-piece", "1", "--fmu", fmu_path]
        code, err = start_and_kill_a_worker(args, tmp_path / "d.csv.parts", workers[0])
    assert code == 0, err
    assert (out.read_bytes(), (tmp_path / "d-revolutions.csv").read_bytes()) == seq


def test_a_cluster_left_without_workers_stops_bounded_and_resumes(fmu_path, tmp_path):
    """The only worker killed: the replay does not wait for ever (exit code 1 after 30 s without
    a worker, one line); on a cluster with a worker again the same command finishes it."""
    inp = longer_encoder_file(tmp_path / "long.csv", 30.0)
    seq = sequential(fmu_path, tmp_path, inp, COUNTS)
    where = tmp_path / "cluster"
    where.mkdir()
    out = tmp_path / "d.csv"
    work = tmp_path / "d.csv.parts"
    base = [inp, *COUNTS, "--out", out, "--distributed", "--revolutions-per-piece", "1"]
    base += ["--fmu", fmu_path, "--quiet"]
    with scheduler_and_workers(where, 1) as (address, workers):
        t0 = time.monotonic()
        code, err = start_and_kill_a_worker([*base, "--scheduler", address], work, workers[0])
        assert time.monotonic() - t0 < 90
    assert code == 1 and "Traceback" not in err, err
    assert "no worker on the cluster for 30 s" in err and "run the same command again" in err
    with scheduler_and_workers(where, 1) as (address, _):
        p = twin([*base, "--scheduler", address], fmu_path)
    assert "Traceback" not in p.stderr
    assert (out.read_bytes(), (tmp_path / "d-revolutions.csv").read_bytes()) == seq


def test_a_table_of_an_sqlite_database(fmu_path, tmp_path):
    """The shipped sample as a table (time REAL, crank_angle INTEGER, and a column the twin does
    not read): the distributed replay of the table writes the files of the sequential replay of
    the CSV file, byte for byte. A table that is not there and a NULL are one-line errors."""
    import sqlite3

    seq = sequential(fmu_path, tmp_path, SAMPLE, COUNTS)
    t, c = np.loadtxt(SAMPLE, delimiter=",", skiprows=1, unpack=True)
    db = tmp_path / "history.db"
    with sqlite3.connect(db) as con:
        con.execute("CREATE TABLE samples (time REAL, crank_angle INTEGER, note TEXT)")
        rows = zip(t.tolist(), c.astype(int).tolist(), ["a,b"] * len(t))
        con.executemany("INSERT INTO samples VALUES (?, ?, ?)", rows)
        con.execute("CREATE TABLE other (x REAL)")
    con.close()
    out = tmp_path / "d.csv"
    args = [db, *COUNTS, "--out", out, "--distributed", "--workers", "2"]
    twin([*args, "--revolutions-per-piece", "4"], fmu_path)
    assert (out.read_bytes(), (tmp_path / "d-revolutions.csv").read_bytes()) == seq

    p = twin([*args, "--table", "nope"], fmu_path, check=False)
    one_line_error(p, 2, "--table 'nope'", "samples, other")
    with sqlite3.connect(db) as con:
        con.execute("UPDATE samples SET crank_angle = NULL WHERE rowid = 7")
    con.close()
    p = twin([*args, "--quiet"], fmu_path, check=False)
    one_line_error(p, 1, "history.db: line 8: crank_angle is empty")


def variant(path, kind):
    """The sample's first 4 s in another form the twin reads (docs/twin.md "Input")."""
    lines = SAMPLE.read_text().splitlines()[:4001]
    if kind == "duplicates":  # two repeated timestamps, dropped and counted
        lines = [*lines[:1000], lines[999], *lines[1000:3000], lines[2999], *lines[3000:]]
    elif kind == "semicolon":  # a European export
        lines = [ln.replace(",", ";").replace(".", ",") for ln in lines]
    elif kind == "speed-force":  # measured speed in rpm and a process force
        t, c = np.loadtxt(lines[1:], delimiter=",", unpack=True)
        w = truth(t)[1] * 60 / (2 * math.pi)
        rows = zip(t.tolist(), c.astype(int).tolist(), w.tolist(), (1000 * np.sin(t)).tolist())
        lines = ["time,crank_angle,crank_speed,process_force"]
        lines += [f"{a!r},{b},{s!r},{f!r}" for a, b, s, f in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("kind", ["duplicates", "semicolon", "speed-force"])
def test_input_forms_are_bit_identical(fmu_path, tmp_path, kind):
    inp = variant(tmp_path / f"{kind}.csv", kind)
    args = [*COUNTS] + (["--speed-unit", "rpm"] if kind == "speed-force" else [])
    seq = sequential(fmu_path, tmp_path, inp, args)
    o = Options(angle_unit="counts", counts_per_rev=4096)
    if kind == "speed-force":
        o.speed_unit = "rpm"
    sc = R.scan(str(inp), fmu_path, "default", o)
    assert sc.duplicates == (2 if kind == "duplicates" else 0)
    for n_rev, cuts in ((1, []), (None, [998, 999, 1000, 2999, 3001])):
        assert local_pieces(sc, R.plan(sc, n_rev, None, cuts), fmu_path) == seq, (n_rev, cuts)


def test_a_table_of_a_postgresql_database(fmu_path, tmp_path):
    """The shipped sample as a PostgreSQL table (a real server on 127.0.0.1, double precision
    columns): the distributed replay writes the sequential replay's files of the CSV, byte for
    byte. A password in the URI is refused before anything connects."""
    import psycopg
    from pg_server import PgServer, pg_bindir

    if pg_bindir() is None:
        pytest.fail("PostgreSQL is not installed: scripts/test.sh installs it")
    seq = sequential(fmu_path, tmp_path, SAMPLE, COUNTS)
    t, c = np.loadtxt(SAMPLE, delimiter=",", skiprows=1, unpack=True)
    with PgServer() as pg:
        with psycopg.connect(pg.dsn, autocommit=True) as con:
            con.execute(
                "CREATE TABLE history (crank_angle double precision, time double precision)"
            )
            with con.cursor().copy("COPY history (time, crank_angle) FROM STDIN") as cp:
                for row in zip(t.tolist(), c.tolist()):
                    cp.write_row(row)
        uri = f"postgresql://twin@127.0.0.1:{pg.port}/twin"
        out = tmp_path / "d.csv"
        args = [uri, *COUNTS, "--out", out, "--distributed", "--workers", "2", "--table", "history"]
        twin([*args, "--revolutions-per-piece", "4"], fmu_path)
        assert (out.read_bytes(), (tmp_path / "d-revolutions.csv").read_bytes()) == seq
        p = twin([*args[:-1], "samples"], fmu_path, check=False)
        one_line_error(p, 2, "--table 'samples'", "it has: history")
    secret = f"postgresql://twin:hunter2@127.0.0.1:{free_port()}/twin"
    p = twin([secret, *COUNTS, "--out", out, "--distributed"], fmu_path, check=False)
    one_line_error(p, 2, "PGPASSWORD")
    assert "hunter2" not in p.stderr


def test_cuts_through_stops_and_rollbacks_are_bit_identical(fmu_path, tmp_path):
    """A stop/start cycle with a rollback across the wrap and a dithering encoder (docs/twin.md
    "Machine states"): the revolutions are bounded by the running maximum of the angle, so cuts
    every revolution, and inside the standstill, give the sequential files."""
    from reciprocating_drive.twin.sample import cycle_truth

    t = np.arange(22001) / 1000.0
    th, w, _, _ = cycle_truth(t)
    stop = cycle_truth(np.array([8.1]))[0][0]
    th = th + math.radians(1.0) - stop % (2 * math.pi)
    rng = np.random.default_rng(5)
    flips = np.cumsum((w == 0) & (rng.random(len(t)) < 0.05)) % 2
    c = ((np.floor(th / (2 * math.pi) * 4096) + np.where(w == 0, flips, 0)) % 4096).astype(int)
    inp = tmp_path / "cycle.csv"
    inp.write_text(
        "time,crank_angle\n" + "".join(f"{a!r},{b}\n" for a, b in zip(t.tolist(), c.tolist()))
    )
    seq = sequential(fmu_path, tmp_path, inp, COUNTS)
    assert b"interrupted" in seq[1]
    sc = R.scan(str(inp), fmu_path, "default", Options(angle_unit="counts", counts_per_rev=4096))
    for n_rev, cuts in ((1, []), (2, [8500, 9000, 12000])):
        pieces = R.plan(sc, n_rev, None, cuts)
        assert len(pieces) >= 10
        assert local_pieces(sc, pieces, fmu_path) == seq, (n_rev, cuts)
