"""Helpers of the plant tests (tests/python/test_plant_*.py): configuration files, running the
pipeline as a real process, reading a database back."""

from __future__ import annotations

import os
import pathlib
import sqlite3
import subprocess
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "data" / "twin" / "pump_encoder.csv"
SCRIPT = ROOT / "scripts" / "twin_plant.py"


def write_config(
    path,
    *,
    run="r1",
    source: str,
    sinks: str,
    run_extra: str = "",
    fmu=None,
    conditioning: str = "",
) -> pathlib.Path:
    fmu_line = f'fmu = "{fmu}"\n' if fmu else ""
    text = (
        f'[run]\nid = "{run}"\nmachine_id = "pump-1"\n{fmu_line}{run_extra}\n'
        f"[source]\n{source}\n[conditioning]\n{conditioning}\n{sinks}"
    )
    p = pathlib.Path(path)
    p.write_text(text)
    return p


def csv_source(path=SAMPLE, pace=0.0, counts=True) -> str:
    units = 'angle_unit = "counts"\ncounts_per_rev = 4096\n' if counts else ""
    return f'type = "csv"\npath = "{path}"\npace = {pace}\n{units}'


def sqlite_sink(path, samples='"all"') -> str:
    return f'[[sink]]\ntype = "sqlite"\npath = "{path}"\nsamples = {samples}\n'


def pg_sink(dsn, samples='"all"', extra="") -> str:
    return f'[[sink]]\ntype = "postgres"\ndsn = "{dsn}"\nsamples = {samples}\n{extra}'


def env() -> dict:
    e = dict(os.environ)
    e["PYTHONPATH"] = str(ROOT / "python") + os.pathsep + e.get("PYTHONPATH", "")
    return e


def start(config, **kw) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, str(SCRIPT), "--config", str(config)],
        env=env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kw,
    )


def run(config, timeout=120) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), "--config", str(config)],
        env=env(),
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def query(db, sql, args=()) -> list:
    """Rows of a query on an SQLite file or a PostgreSQL connection string."""
    if str(db).startswith("host="):
        import psycopg

        with psycopg.connect(db) as c:
            return [tuple(r) for r in c.execute(sql.replace("?", "%s"), args).fetchall()]
    c = sqlite3.connect(str(db))
    try:
        return c.execute(sql, args).fetchall()
    finally:
        c.close()


def samples(db, run="r1") -> np.ndarray:
    """seq, t and every output of a run's samples, ordered by seq, as float64 (bit-comparable)."""
    rows = query(
        db,
        "SELECT s.* FROM samples s JOIN runs r ON r.run = s.run WHERE r.name = ? ORDER BY s.seq",
        (run,),
    )
    return np.array([r[1:] for r in rows], dtype=float)


def revolutions(db, run="r1") -> list:
    return query(
        db,
        "SELECT v.* FROM revolutions v JOIN runs r ON r.run = v.run WHERE r.name = ? "
        "ORDER BY v.revolution",
        (run,),
    )


def events(db, run="r1") -> list:
    return query(
        db,
        "SELECT e.seq, e.kind, e.count, e.message FROM events e JOIN runs r ON r.run = e.run "
        "WHERE r.name = ? ORDER BY e.seq",
        (run,),
    )


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def committed(db, run) -> int:
    """Samples covered by the run's committed checkpoint (0 before the first commit)."""
    try:
        rows = query(
            db,
            "SELECT c.samples FROM checkpoints c JOIN runs r ON r.run = c.run WHERE r.name = ?",
            (run,),
        )
    except Exception:  # noqa: BLE001 - the schema is not there yet
        return 0
    return rows[0][0] if rows else 0


def wait_for_commit(db, run, above: int, proc, timeout=30.0) -> int:
    """Waits (bounded) until the run's checkpoint covers more than `above` samples."""
    import time

    deadline = time.monotonic() + timeout
    while (n := committed(db, run)) <= above:
        if proc.poll() is not None:
            raise AssertionError(f"the twin ended early: {proc.stderr.read()}")
        if time.monotonic() > deadline:
            raise AssertionError(f"no commit beyond {above} samples within {timeout} s")
        time.sleep(0.02)
    return n


def clean_run(fmu_path, path=SAMPLE, counts=True):
    """The clean run: a CSV file through the twin's core in one go, in this process (seq, t and
    outputs as one array; summaries as tuples; the gap messages), no database involved."""
    from reciprocating_drive.twin import SUMMARY_FIELDS, Options, Twin

    opts = Options(angle_unit="counts", counts_per_rev=4096) if counts else Options()
    tw = Twin(fmu_path, "default", opts)
    rows, sums = tw.feed(pathlib.Path(path).read_text().splitlines(), 1)
    rest, more = tw.finish()
    rows = np.concatenate([rows, rest])
    table = np.column_stack([np.arange(len(rows)), rows])
    revs = [tuple(s[k] for k in SUMMARY_FIELDS) for s in sums + more]
    return table, revs, list(tw.messages)


def same_values(got: np.ndarray, ref: np.ndarray, sqlite: bool) -> bool:
    """Bit for bit; SQLite stores a whole-number REAL as an integer, which has no -0.0
    (docs/plant.md "Schema"), so there -0.0 and 0.0 count as the same."""
    if got.shape != ref.shape:
        return False
    if sqlite:
        got, ref = got + 0.0, ref + 0.0
    return bool(np.array_equal(bits(got), bits(ref)))


class PlcProcess:
    """scripts/plc_sim.py as a real process on 127.0.0.1; stopped (bounded) on exit."""

    def __init__(self, *args, env_extra=None, data=SAMPLE):
        import socket

        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.port = s.getsockname()[1]
        self.endpoint = f"opc.tcp://127.0.0.1:{self.port}/plc"
        self.args = [
            sys.executable,
            str(ROOT / "scripts" / "plc_sim.py"),
            "--port",
            str(self.port),
            "--data",
            str(data),
            "--linger",
            "60",
            *args,
        ]
        self.env = {**env(), **(env_extra or {})}

    def __enter__(self):
        import time

        self.p = subprocess.Popen(
            self.args, env=self.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        deadline = time.monotonic() + 30
        self.out = []
        while time.monotonic() < deadline:
            line = self.p.stdout.readline()
            if not line:
                break
            self.out.append(line)
            if "listening on" in line:
                return self
        self.__exit__()
        raise AssertionError("plc_sim did not start: " + "".join(self.out))

    def __exit__(self, *exc):
        if self.p.poll() is None:
            self.p.terminate()
            try:
                self.p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait(timeout=10)
