"""The live page as an operator reads it (docs/page.md), in Debian's chromium driven by Playwright:
the demo's alarm raised and cleared at clock times, values a rigid machine does not have hidden,
every data-health field filled, trends with a y-range that does not stretch rounding noise; and the
demo's and the simulated PLC's ends (docs/plant.md, "Demo", "Simulated PLC")."""

from __future__ import annotations

import math
import os
import shutil
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import plant_util as pu
import pytest
from test_page import (  # noqa: F401 (fixtures)
    Database,
    Feed,
    browser,
    chromium,
    page_of,
    sample_lines,
    server,
    wait_ready,
)

ROOT = Path(__file__).resolve().parents[2]
#: The page's screenshot in docs/page.md: taken by the demo's test, written there only when asked
#: (RD_WRITE_DOC_FIGURES=1), otherwise into target/page/.
SCREENSHOT = (
    ROOT / "docs" / "figures" / "twin_page.png"
    if os.environ.get("RD_WRITE_DOC_FIGURES") == "1"
    else ROOT / "target" / "page" / "twin_page_demo.png"
)


def cell(tab, key):
    return tab.inner_text(f"#health tr[data-key={key}] td:nth-child(2)")


def y_axes(tab) -> dict:
    """Per trend: the y scale's range, the tick labels uPlot drew, and the data."""
    return tab.evaluate(
        """() => Object.fromEntries(Object.entries(S.charts).map(([k, c]) =>
            [k, {min: c.scales.y.min, max: c.scales.y.max, labels: c.axes[1]._values,
                 data: S.trend[k]}]))"""
    )


def test_the_demo_raises_and_clears_an_alarm_at_clock_times(tmp_path, page_of):  # noqa: F811
    """`rdrive plant --demo`: the page's address is its first line; the PLC's process-force step
    (2 kN from 3 s to 8 s) raises the crank torque alarm of the example limits and it clears
    before the end; the OPC UA source has a clock, so the header, the trends and the alarms read
    clock times; the default machine's rod is rigid, so no stress is shown and its swing is named
    as such; at the end every data-health field is filled, the run finished, no "reconnecting";
    the database is checkpointed: no WAL file, the .sqlite alone holds every sample."""
    db = tmp_path / "demo.sqlite"
    p = subprocess.Popen(
        [sys.executable, str(pu.SCRIPT), "--demo", "--db", str(db), "--page-port", "0"],
        env=pu.env(),
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        first = p.stderr.readline()
        assert first.startswith("page: http://127.0.0.1:"), first
        url = first.split()[1]
        tab = page_of(url)
        wait_ready(tab)
        # Rigid rod: its swing named as such, no stress value or trend (once the twin is made).
        tab.wait_for_function(
            "() => document.querySelector('#v-rod_angle_amplitude .name').textContent"
            " === 'rod swing amplitude (rigid rod)'"
        )
        assert tab.query_selector("#v-stress_max") is None
        assert tab.query_selector("#t-stress_max") is None
        tab.wait_for_selector(
            "#alarms tr[data-name='crank torque high'][data-state='raised']", timeout=30_000
        )
        # Live: clock times on the trends' axis and in the header once the first sample is in.
        tab.wait_for_function("() => document.getElementById('trends').dataset.clock === '1'")
        assert "t =" not in tab.inner_text("#rev-label")
        lag = cell(tab, "lag")
        assert lag.endswith(" s") and abs(float(lag.split()[0])) < 5.0, lag
        assert cell(tab, "connected") == "connected"
        tab.wait_for_selector(
            "#alarms tr[data-name='crank torque high'][data-state='cleared']", timeout=30_000
        )
        # Read through the same buffered reader as the first line (communicate with a timeout
        # would read the pipe beneath it and miss what the reader already holds).
        p.wait(timeout=60)
        err = p.stderr.read()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    assert p.returncode == 0, err
    lines = (first + err).splitlines()
    assert lines[1].startswith("demo: PLC at opc.tcp://127.0.0.1:"), lines[:3]
    # The alarms in the database: raised and cleared once each, stamped when the condition was
    # met (the end of the revolution that met it: its start + 2π/mean speed), the raise after the
    # step at 3 s, the clear after the step back at 8 s.
    con = sqlite3.connect(db)
    (origin,) = con.execute("SELECT time_origin FROM runs").fetchone()
    revs = con.execute(
        "SELECT start_time, mean_speed FROM revolutions ORDER BY revolution"
    ).fetchall()
    ends = [s + 2 * math.pi / w for s, w in revs]
    alarms = con.execute(
        "SELECT t, message FROM events WHERE kind = 'alarm' AND message LIKE '%crank torque high%' "
        "ORDER BY seq"
    ).fetchall()
    assert [("raised" in m, "cleared" in m) for _, m in alarms] == [(True, False), (False, True)]
    (t_raised, _), (t_cleared, _) = alarms
    assert min(abs(t_raised - e) for e in ends) < 1e-9 and 3.0 < t_raised < 8.0
    assert min(abs(t_cleared - e) for e in ends) < 1e-9 and 8.0 < t_cleared < 12.1
    # The page: the same times, shown as clock times of the run's origin.
    row = tab.query_selector("#alarms tr[data-name='crank torque high']")
    assert float(row.get_attribute("data-raised")) == t_raised
    assert float(row.get_attribute("data-cleared")) == t_cleared
    cells = tab.eval_on_selector_all(
        "#alarms tr[data-name='crank torque high'] td", "tds => tds.map(td => td.textContent)"
    )
    clock = tab.evaluate(
        "([o, a, b]) => [new Date((o + a) * 1000).toLocaleString(),"
        " new Date((o + b) * 1000).toLocaleString()]",
        [origin, t_raised, t_cleared],
    )
    assert cells[2:4] == clock, (cells, clock)
    # The trends' x values are clock times (Unix seconds of origin + start time).
    xmax = tab.evaluate("() => S.charts.crank_torque_peak.data[0].at(-1)")
    assert xmax == pytest.approx(origin + revs[-1][0], abs=1e-6)
    # The end: the page says the run finished and stops listening; every health field filled.
    tab.wait_for_function(
        "() => document.getElementById('stream').textContent.startsWith('stopped')"
    )
    tab.wait_for_timeout(1500)  # an EventSource that tried to reconnect would now say so
    assert tab.inner_text("#stream") == "stopped: page no longer updated"
    health = {
        k: cell(tab, k)
        for k in tab.eval_on_selector_all("#health tr", "trs => trs.map(t => t.dataset.key)")
    }
    assert all(v and "—" not in v for v in health.values()), health
    assert health["run_status"].startswith("finished: ") and health["connected"].startswith(
        "closed: the run finished"
    )
    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    tab.screenshot(path=str(SCREENSHOT), full_page=True)
    assert tab.errors == []
    # Checkpointed at close: no WAL left, and the .sqlite file alone (copied without it) holds
    # every sample.
    wal = Path(str(db) + "-wal")
    assert not wal.exists() or wal.stat().st_size == 0
    (n,) = con.execute("SELECT COUNT(*) FROM samples").fetchone()
    con.close()
    alone = tmp_path / "alone" / "demo.sqlite"
    alone.parent.mkdir()
    shutil.copy(db, alone)
    (m,) = sqlite3.connect(alone).execute("SELECT COUNT(*) FROM samples").fetchone()
    assert n > 11_000 and m == n, (n, m)


def test_plc_sim_exits_after_playing_unless_told_to_linger():
    """scripts/plc_sim.py ends by itself after "finished playing" (a short grace for the last
    notifications); with --linger it stays up."""
    args = [sys.executable, str(ROOT / "scripts" / "plc_sim.py"), "--speed", "20"]
    t0 = time.monotonic()
    p = subprocess.run(args, env=pu.env(), capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert "plc_sim: finished playing" in p.stdout
    assert time.monotonic() - t0 < 30
    q = subprocess.Popen([*args, "--linger"], env=pu.env(), stdout=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        while "finished playing" not in q.stdout.readline() and time.monotonic() < deadline:
            pass
        time.sleep(4)  # twice the grace of the default
        assert q.poll() is None
    finally:
        q.terminate()
        q.wait(timeout=10)


def test_a_rigid_machine_and_steady_values_read_as_an_operator_reads_them(
    fmu_path,
    tmp_path,
    server,  # noqa: F811
    page_of,  # noqa: F811
):
    """The default machine (rigid rod) from the sample's crank: its friction work is constant
    to the sixth digit and its rod swing constant; the trends must not stretch that rounding to
    full height (a span of at least 2 % of the value, docs/page.md "Trends"), and their tick
    labels must differ. The speed fluctuation reads in %, the card's axes without exponents."""
    db = Database(tmp_path / "twin.sqlite")
    page = server(database=db.path)
    feed = Feed(fmu_path, page, db)
    page.open(feed.twin.outputs, None, elastic=False)
    sums = feed.feed(sample_lines(0, 10, 0.0))
    time.sleep(0.3)
    tab = page_of(page.url)
    wait_ready(tab)
    keys = tab.eval_on_selector_all("#now .value", "els => els.map(e => e.id)")
    assert "v-stress_max" not in keys and "v-rod_angle_amplitude" in keys
    assert tab.inner_text("#v-rod_angle_amplitude .name") == "rod swing amplitude (rigid rod)"
    assert tab.query_selector("#t-stress_max") is None
    titles = tab.eval_on_selector_all(".trend-title", "els => els.map(e => e.textContent)")
    assert len(titles) == 6 and "friction work [J]" in titles and "speed fluctuation [%]" in titles
    # Speed fluctuation in percent: the number shown is 100 times the summary's ratio.
    last = sums[-1]
    fl = tab.inner_text("#v-speed_fluctuation .num")
    assert float(fl) == pytest.approx(100 * last["speed_fluctuation"], rel=1e-4)
    assert tab.inner_text("#v-speed_fluctuation .unit").strip() == "%"
    # The card's axes: SI prefixes and rounding to the axis' span, no "e-7".
    axis = tab.get_attribute("#card", "data-axis")
    assert "e-" not in axis and "e+" not in axis, axis
    fw = [s["friction_work"] for s in sums]
    assert 0 < max(fw) - min(fw) < 1e-4 * abs(fw[0])  # constant but for rounding
    for key, ax in y_axes(tab).items():
        vals = [v for v in ax["data"] if v is not None]
        size = max(abs(v) for v in vals)
        assert ax["max"] - ax["min"] >= 0.02 * size * (1 - 1e-12), (key, ax)
        labels = ax["labels"]
        assert len(labels) >= 2 and len(set(labels)) == len(labels), (key, labels)
    assert tab.errors == []


def test_a_failed_run_and_the_end_of_the_page_are_shown(server, page_of):  # noqa: F811
    """The twin's pipeline calls `end` when its run stops, then closes the page: the run's status
    and message are shown, the source as closed, and the page stops listening instead of showing
    "reconnecting"."""
    page = server()
    page.open(["crank.model_angle", "suspension.position", "rod.force"], time_origin=None)
    page.health(connected=True)
    tab = page_of(page.url)
    wait_ready(tab)
    assert cell(tab, "run_status") == "running"
    assert cell(tab, "lag") == "none: a file replay has no clock"
    page.end("failed", "line 7: crank_angle = 'x' is not a number")
    page.close()
    tab.wait_for_function(
        "() => document.getElementById('stream').textContent.startsWith('stopped')"
    )
    tab.wait_for_timeout(1500)
    assert tab.inner_text("#stream") == "stopped: page no longer updated"
    assert cell(tab, "run_status") == "failed: line 7: crank_angle = 'x' is not a number"
    assert tab.get_attribute("#health tr[data-key=run_status]", "class") == "bad"
    assert cell(tab, "connected") == "closed: the run failed"
    assert tab.errors == []


def test_the_clock_of_a_live_source_reaches_the_page_when_it_is_known(server, page_of):  # noqa: F811
    """An OPC UA source knows its clock from its first sample, after the page opened: `clock`
    switches the page to clock times and fills the lag."""
    page = server()
    page.open(["crank.model_angle", "suspension.position", "rod.force"], time_origin=None)
    tab = page_of(page.url)
    wait_ready(tab)
    assert tab.get_attribute("#trends", "data-clock") == "0"
    origin = time.time() - 10.0
    page.clock(origin)
    page.add(np.array([[9.5, 1.0, 0.1, 5.0]]), 0, [], 0, [])
    tab.wait_for_function("() => document.getElementById('trends').dataset.clock === '1'")
    lag = float(cell(tab, "lag").split()[0])
    assert 0.0 < lag < 2.0, lag
    assert tab.errors == []


def test_a_followed_run_knows_its_rod_from_its_machine():
    """`python -m reciprocating_drive.page --database` has no twin: it tells the rod from the
    runs table's machine. The default machine takes the FMU's start value rod.kind = 0 (rigid,
    modelDescription/modelDescription.xml); kvo630's preset sets rod.kind = 2 (a helical spring,
    resources/presets/kvo630.ssv); an unknown machine is not known (both values shown)."""
    from reciprocating_drive.page.follow import elastic_of

    assert elastic_of("default") is False
    assert elastic_of("kvo630") is True
    assert elastic_of("no-such-machine") is None
