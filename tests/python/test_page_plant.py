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
    cfg = tmp_path / "twin.toml"
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

[[sink]]
type = "sqlite"
path = "{db}"
samples = "all"
"""
    )
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
