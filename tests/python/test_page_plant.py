"""The page on the database the plant twin really writes (its pipeline and SQLite sink, docs/plant.md):
the page beside the twin shows the run's last revolution, its events and its trends. Runs where
the plant package is there (reciprocating_drive.plant)."""

from __future__ import annotations

import math
import sqlite3
import time
from pathlib import Path

import pytest

pipeline = pytest.importorskip("reciprocating_drive.plant.pipeline")

from reciprocating_drive.page.follow import Follower  # noqa: E402
from reciprocating_drive.page.server import PageServer  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def test_page_follows_the_plant_twins_sqlite_database(fmu_path, tmp_path, monkeypatch):
    monkeypatch.setenv("RD_FMU", fmu_path)
    db = tmp_path / "twin.sqlite"
    cfg = _config(tmp_path, db, page=None, pace=0, samples="all")
    assert pipeline.run_config(str(cfg), log=lambda m: None) == 0
    page = PageServer(port=0, database=str(db)).start()
    try:
        follower = Follower(str(db), page, warmup=1e9)
        assert follower.poll() > 5
        time.sleep(0.4)
        st = page.state.snapshot()
        con = sqlite3.connect(db)
        rev, w, tmax, tmin, fw = con.execute(
            "SELECT revolution, mean_speed, crank_torque_max, crank_torque_min, friction_work "
            "FROM revolutions ORDER BY revolution DESC LIMIT 1"
        ).fetchone()
        last = st["last"]
        assert last["revolution"] == rev and last["friction_work"] == fw
        assert last["strokes_per_minute"] == w * 60.0 / (2.0 * math.pi)
        assert last["crank_torque_peak"] == max(abs(tmax), abs(tmin))
        # The shipped sample has one gap; its event reached the health counts.
        assert st["health"]["gaps"] == 1 and st["health"]["run_status"] == "finished"
        assert len(st["cards"]) >= 5
        (n,) = con.execute("SELECT COUNT(*) FROM revolutions").fetchone()
        trend = page.trend_from_database(1e6)
        assert len(trend["t"]) == n
        follower.close()
    finally:
        page.close()


def _config(tmp_path, db, page: str | None, pace: float = 1.0, samples: str = "none") -> Path:
    """A twin configuration replaying the shipped sample into SQLite, with a [page] table of the
    given lines (None: none)."""
    cfg = tmp_path / "twin.toml"
    page_table = "" if page is None else f"\n[page]\n{page}\n"
    cfg.write_text(
        f"""[run]
id = "page-test"
machine_id = "pump-1"
machine = "default"

[source]
type = "csv"
path = "{ROOT / "data" / "twin" / "pump_encoder.csv"}"
angle_unit = "counts"
counts_per_rev = 4096
pace = {pace}

[[sink]]
type = "sqlite"
path = "{db}"
samples = "{samples}"
{page_table}"""
    )
    return cfg


def test_a_plant_run_with_a_page_table_serves_its_revolutions(fmu_path, tmp_path):
    """The [page] table of a twin configuration (docs/page.md): the page is served while the run
    goes on, and the revolutions it shows are the ones the run commits to its database."""
    import json
    import os
    import signal
    import subprocess
    import sys
    import urllib.request

    db = tmp_path / "twin.sqlite"
    limits = ROOT / "examples" / "twin" / "limits.toml"
    cfg = _config(tmp_path, db, f'port = 0\nlimits = "{limits}"')
    env = {**os.environ, "RD_FMU": fmu_path, "PYTHONPATH": str(ROOT / "python")}
    p = subprocess.Popen(
        [sys.executable, str(ROOT / "scripts" / "twin_plant.py"), "--config", str(cfg)],
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        line = p.stderr.readline()  # the first line names the page's address
        assert line.startswith("page: http://127.0.0.1:"), line
        url = line.split()[1]
        deadline = time.monotonic() + 30
        last = None
        while time.monotonic() < deadline:
            with urllib.request.urlopen(url + "api/state", timeout=5) as r:
                st = json.load(r)
            last = st.get("last")
            if last and last.get("revolution", 0) >= 3:
                break
            time.sleep(0.2)
        assert last and last["revolution"] >= 3, st
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 130, err  # stopped before the input's end: not 0
    con = sqlite3.connect(db)
    row = con.execute(
        "SELECT friction_work FROM revolutions WHERE revolution = ?", (last["revolution"],)
    ).fetchone()
    assert row is not None and row[0] == last["friction_work"]


def test_a_bad_page_table_is_one_line_and_exit_2(fmu_path, tmp_path):
    import os
    import socket
    import subprocess
    import sys

    env = {**os.environ, "RD_FMU": fmu_path, "PYTHONPATH": str(ROOT / "python")}
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        for page, words in (
            (f"port = {port}", f"port {port} on 127.0.0.1 is in use"),
            ('host = "127.0.0.2"', "access token is required"),
            ("colour = 1", "page.colour: unknown key"),
        ):
            cfg = _config(tmp_path, tmp_path / "x.sqlite", page, pace=0)
            r = subprocess.run(
                [sys.executable, str(ROOT / "scripts" / "twin_plant.py"), "--config", str(cfg)],
                capture_output=True,
                text=True,
                env=env,
                timeout=120,
            )
            assert r.returncode == 2, (page, r.stderr)
            assert words in r.stderr and r.stderr.count("\n") == 1, (page, r.stderr)
