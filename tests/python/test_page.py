"""The twin's live page in a real browser (docs/page.md): Debian's chromium, headless, driven by
Playwright for Python pointed at it (never a browser of Playwright's own).

The twin computes from the sample data's crank (twin_sample.truth) with the real FMU; its
revolution summaries go to the page and to an SQLite database of the plant sinks' schema (the
`revolutions` and `runs` tables). The page's numbers are compared with the database's, which the
page never wrote."""

from __future__ import annotations

import json
import math
import socket
import sqlite3
import subprocess
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from reciprocating_drive.alarms import parse_limits
from reciprocating_drive.page import PageError, PageServer
from reciprocating_drive.twin import SUMMARY_FIELDS, Twin
from reciprocating_drive.twin.sample import truth

ROOT = Path(__file__).resolve().parents[2]
# A screenshot of a file replay's page (twin times), into target/; the one in docs/page.md is the
# demo's (test_page_operator.py).
SCREENSHOT = ROOT / "target" / "page" / "twin_page.png"
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
TOKEN = "test-token-0123456789abcdef"
LIMITS = {
    "limit": [
        {
            "name": "crank torque high",
            "value": "crank_torque_peak",
            "high": 8000.0,
            "hysteresis": 500.0,
            "delay": 2,
            "severity": "critical",
        },
        {"name": "speed", "value": "strokes_per_minute", "low": 55.0, "high": 75.0},
    ],
    "trend": [
        {
            "name": "friction work rising",
            "value": "friction_work",
            "recent": 20,
            "reference": 20,
            "rise": 0.15,
            "min_revolutions": 10,
        }
    ],
}


def sample_lines(t0, t1, force, rate=1000.0):
    t = np.arange(round(t0 * rate), round(t1 * rate)) / rate
    theta, _, _ = truth(t)
    return [
        f"{float(a)!r},{float(b)!r},{float(force)!r}" for a, b in zip(t, np.mod(theta, 2 * math.pi))
    ]


class Database:
    """The twin database the plant sinks write (their DDL when the package is there, else the
    same two tables written out), filled by the test."""

    def __init__(self, path, time_origin=None):
        self.path = str(path)
        db = sqlite3.connect(self.path, isolation_level=None)
        db.execute("PRAGMA journal_mode=WAL")
        cols = ", ".join(f"{f} REAL" for f in SUMMARY_FIELDS[1:])
        db.execute(
            "CREATE TABLE runs (run INTEGER PRIMARY KEY AUTOINCREMENT, name TEXT NOT NULL UNIQUE, "
            "time_origin REAL, status TEXT NOT NULL DEFAULT 'running')"
        )
        db.execute(
            f"CREATE TABLE revolutions (run INTEGER NOT NULL, revolution INTEGER NOT NULL, {cols}, "
            "PRIMARY KEY (run, revolution))"
        )
        db.execute(
            "CREATE TABLE events (run INTEGER NOT NULL, seq INTEGER NOT NULL, t REAL, "
            "wall_time REAL NOT NULL, kind TEXT NOT NULL, count INTEGER NOT NULL, "
            "message TEXT NOT NULL)"
        )
        db.execute("INSERT INTO runs (name, time_origin) VALUES ('test', ?)", (time_origin,))
        self.db = db
        self.lock = threading.Lock()

    def revolutions(self, sums):
        names = ", ".join(SUMMARY_FIELDS)
        with self.lock:
            self.db.executemany(
                f"INSERT INTO revolutions (run, {names}) VALUES (1{', ?' * len(SUMMARY_FIELDS)})",
                [tuple(s[f] for f in SUMMARY_FIELDS) for s in sums],
            )

    def alarm(self, ch):
        with self.lock:
            n = self.db.execute("SELECT COUNT(*) FROM events").fetchone()[0]
            self.db.execute(
                "INSERT INTO events VALUES (1, ?, ?, ?, 'alarm', 1, ?)",
                (n, ch.t, time.time(), ch.message),
            )


class Feed:
    """The twin: lines in, rows and summaries to the page and the database."""

    def __init__(self, fmu, page, db, extra=None):
        self.twin = Twin(fmu, extra_values=extra)
        self.page, self.db = page, db
        self.lineno = 1
        self.first = True
        page.open(self.twin.outputs, time_origin=getattr(db, "origin", None))

    def feed(self, lines):
        if self.first:
            lines = ["time,crank_angle,process_force", *lines]
            self.first = False
        rows, sums = self.twin.feed(lines, self.lineno)
        self.lineno += len(lines)
        self.db.revolutions(sums)
        self.page.add(rows, 0, sums, 0, [])
        return sums


@pytest.fixture(scope="module")
def chromium():
    """Debian's chromium, installed by scripts/lib/chromium.sh when missing."""
    r = subprocess.run(
        ["bash", "-c", f"source {ROOT}/scripts/lib/chromium.sh && ensure_chromium"],
        capture_output=True,
        text=True,
        timeout=900,
    )
    path = r.stdout.strip().splitlines()[-1] if r.returncode == 0 and r.stdout.strip() else ""
    if not path:
        pytest.fail(f"no chromium (scripts/lib/chromium.sh): {r.stderr.strip()[-300:]}")
    return path


@pytest.fixture(scope="module")
def browser(chromium):
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=chromium, args=FLAGS, headless=True, timeout=60_000)
        yield b
        b.close()


@pytest.fixture
def page_of(browser):
    """A new browser tab; console errors and page errors are collected and must stay empty."""
    opened = []

    def make(url=None):
        ctx = browser.new_context(viewport={"width": 1400, "height": 1300})
        tab = ctx.new_page()
        tab.errors = []
        tab.on("console", lambda m: tab.errors.append(m.text) if m.type == "error" else None)
        tab.on("pageerror", lambda e: tab.errors.append(str(e)))
        tab.set_default_timeout(15_000)
        opened.append(ctx)
        if url:
            tab.goto(url)
        return tab

    yield make
    for ctx in opened:
        ctx.close()


@pytest.fixture
def server():
    started = []

    def make(**kw):
        s = PageServer(port=0, **kw).start()
        started.append(s)
        return s

    yield make
    for s in started:
        s.close()


def wait_ready(tab):
    tab.wait_for_selector("body[data-ready='1']")


def shown(tab) -> dict:
    return tab.eval_on_selector_all(
        "#now .num", "els => Object.fromEntries(els.map(e => [e.dataset.key, e.dataset.value]))"
    )


def test_page_loads_without_console_errors_and_shows_the_database_values(
    fmu_path, tmp_path, server, page_of
):
    db = Database(tmp_path / "twin.sqlite")
    page = server(database=db.path, limits=parse_limits(LIMITS))
    feed = Feed(fmu_path, page, db)
    feed.feed(sample_lines(0, 6, 20e3))
    time.sleep(0.3)
    tab = page_of()
    requests = []
    tab.on("request", lambda r: requests.append(r.url))
    tab.goto(page.url)
    wait_ready(tab)
    # Every asset from the twin itself (a plant network has no internet).
    assert requests and all(u.startswith(page.url) for u in requests), requests
    row = db.db.execute(
        "SELECT revolution, mean_speed, speed_fluctuation, crank_torque_max, crank_torque_min, "
        "rod_force_max, rod_force_min, friction_work, rod_angle_amplitude, stress_max "
        "FROM revolutions ORDER BY revolution DESC LIMIT 1"
    ).fetchone()
    rev, w, fl, tmax, tmin, fmax, fmin, fw, amp, smax = row
    want = {
        "strokes_per_minute": w * 60.0 / (2.0 * math.pi),
        "speed_fluctuation": fl,
        "crank_torque_peak": max(abs(tmax), abs(tmin)),
        "rod_force_largest": max(abs(fmax), abs(fmin)),
        "friction_work": fw,
        "rod_angle_amplitude": amp,
        "stress_max": smax,
    }
    got = shown(tab)
    # The page's data-value is the double JavaScript received, written as its shortest
    # round-tripping string: equal bit for bit to the database's.
    assert {k: float(v) for k, v in got.items()} == want
    assert tab.get_attribute("#rev-label", "data-revolution") == str(rev)
    # The trends hold every revolution of the database (the window is wider than the run).
    (n,) = db.db.execute("SELECT COUNT(*) FROM revolutions").fetchone()
    assert tab.get_attribute("#trends", "data-points") == str(n)
    assert "from the database" in tab.inner_text("#trend-source")
    assert int(tab.get_attribute("#card", "data-cards")) >= 5
    # Units and limits with each value.
    torque = tab.inner_text("#v-crank_torque_peak")
    assert "kN·m" in torque and "high 8 kN·m" in torque
    assert "low 55 1/min, high 75 1/min" in tab.inner_text("#v-strokes_per_minute")
    assert tab.errors == []


def test_new_revolutions_appear_within_one_second(fmu_path, tmp_path, server, page_of):
    """Real time: the samples of twin time t are handed over at wall time origin + t, in 50 ms
    chunks as a live source delivers them. A revolution is complete at the next one's start; the
    browser notes the wall time at which its label shows it."""
    db = Database(tmp_path / "twin.sqlite")
    page = server(database=db.path)
    feed = Feed(fmu_path, page, db)
    feed.feed(sample_lines(0, 2, 0.0))  # history before the page opens
    tab = page_of(page.url)
    wait_ready(tab)
    tab.evaluate(
        """() => { window.seen = {};
        new MutationObserver(() => {
            const r = document.getElementById('rev-label').dataset.revolution;
            if (!(r in window.seen)) window.seen[r] = Date.now() / 1000;
        }).observe(document.getElementById('rev-label'), {attributes: true}); }"""
    )
    origin = time.time() - 2.0
    sums = []
    t = 2.0
    while t < 8.0:
        now = time.time() - origin
        if now < t + 0.05:
            time.sleep(t + 0.05 - now)
        sums += feed.feed(sample_lines(t, t + 0.05, 0.0))
        t += 0.05
    time.sleep(1.2)
    seen = tab.evaluate("() => window.seen")
    assert len(sums) >= 5
    late = []
    for a, b in zip(sums, sums[1:]):
        completed = origin + b["start_time"]  # its last sample's wall time
        appeared = seen.get(str(a["revolution"]))
        assert appeared is not None, (a["revolution"], seen)
        late.append(appeared - completed)
    assert max(late) < 1.0, late
    assert tab.errors == []


def test_torque_step_raises_the_alarm_on_the_page_and_stepping_back_clears_it(
    fmu_path, tmp_path, server, page_of
):
    db = Database(tmp_path / "twin.sqlite")
    page = server(database=db.path, limits=parse_limits(LIMITS), on_alarm=db.alarm)
    feed = Feed(fmu_path, page, db)
    tab = page_of()
    feed.feed(sample_lines(0, 4, 0.0))
    tab.goto(page.url)
    wait_ready(tab)
    assert tab.query_selector_all("#alarms tbody tr") == []
    loaded = feed.feed(sample_lines(4, 9, 50e3))
    row = tab.wait_for_selector("#alarms tr[data-name='crank torque high'][data-state='raised']")
    assert "critical" in row.inner_text()
    assert "crank_torque_peak" in row.get_attribute("title")
    assert tab.get_attribute("#v-crank_torque_peak", "class") == "value beyond"
    unloaded = feed.feed(sample_lines(9, 15, 0.0))
    tab.wait_for_selector("#alarms tr[data-name='crank torque high'][data-state='cleared']")
    assert len(tab.query_selector_all("#alarms tbody tr")) == 1  # raised once, cleared once
    # As worked out in test_alarms: raised by the 2nd revolution holding loaded samples, cleared
    # by the 2nd revolution wholly after the step back; both written to the database.
    starts = [s["start_time"] for s in loaded + unloaded]
    msgs = db.db.execute("SELECT t, message FROM events ORDER BY seq").fetchall()
    assert len(msgs) == 2 and "raised" in msgs[0][1] and "cleared" in msgs[1][1]
    first_unloaded = next(i for i, t in enumerate(starts) if t >= 9.0)
    # Stamped when the condition was met: at the end of that revolution, the next one's start.
    assert msgs[1][0] == pytest.approx(starts[first_unloaded + 2], abs=2e-3)
    cells = tab.eval_on_selector_all("#alarms tbody tr td", "tds => tds.map(td => td.textContent)")
    # Without a clock (time_origin None) the times are the twin's, with the wall clock beside.
    assert cells[2].startswith(f"t = {msgs[0][0]:.6g} s (") and cells[3].startswith(
        f"t = {msgs[1][0]:.6g} s ("
    )
    tab.wait_for_timeout(300)
    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    tab.screenshot(path=str(SCREENSHOT), full_page=True)
    assert SCREENSHOT.stat().st_size > 20_000
    assert tab.errors == []


def test_friction_ramp_raises_the_trend_alarm_on_the_page(fmu_path, server, page_of):
    """The guide's friction coefficient ramped up revolution by revolution (a new twin each step:
    the parameter is fixed within one FMU instance), the summaries placed on one time axis."""
    page = server(limits=parse_limits(LIMITS))
    tab = page_of(page.url)
    wait_ready(tab)
    lines = ["time,crank_angle,process_force", *sample_lines(0, 2.9, 0.0)]
    period = 60 / 65
    for step in range(40):
        mu = 0.1 if step < 20 else 0.1 * (1 + 0.04 * (step - 19))
        tw = Twin(fmu_path, extra_values={"guide.friction_coefficient": mu})
        if step == 0:
            page.open(tw.outputs)
        _, sums = tw.feed(lines, 1)
        s = dict(sums[1], revolution=step, start_time=step * period)
        page.add(None, 0, [s], 0, [])
    row = tab.wait_for_selector("#alarms tr[data-name='friction work rising'][data-state='raised']")
    assert "friction_work mean" in row.get_attribute("title")
    assert "from the memory" in tab.inner_text("#trend-source")
    assert tab.errors == []


def get(url, headers=None):
    req = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=5) as r:
            return r.status, r.read().decode(), dict(r.headers)
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode(), dict(e.headers)


def test_other_address_needs_a_token_and_answers_401_without_it(fmu_path, server, page_of):
    """127.0.0.2 stands for any interface other than 127.0.0.1 (the tests may not bind another):
    the page refuses to start without a token, and with one answers 401 to every request that
    does not carry it."""
    with pytest.raises(PageError, match=r"^page: bound to 127\.0\.0\.2, which is not 127\.0\.0\.1"):
        PageServer(host="127.0.0.2", port=0)
    page = server(host="127.0.0.2", token=TOKEN)
    feed = Feed(fmu_path, page, Database(":memory:"))
    feed.feed(sample_lines(0, 3, 0.0))
    time.sleep(0.3)
    base = page.url
    assert base.startswith("http://127.0.0.2:")
    for path in ("", "api/state", "api/trend?window=60", "stream", "static/page.js"):
        status, body, _ = get(base + path)
        assert status == 401, path
        assert "revolution" not in body and "strokes" not in body and TOKEN not in body
    status, body, _ = get(base + "api/state", {"Authorization": "Bearer wrong-token-0123456789"})
    assert status == 401
    status, body, _ = get(base + "api/state", {"Authorization": f"Bearer {TOKEN}"})
    assert status == 200 and json.loads(body)["revolutions"] >= 2
    # In the browser: the login form, then the page with a session cookie the script cannot read.
    tab = page_of()
    resp = tab.goto(base)
    assert resp.status == 401 and tab.query_selector("#now") is None
    tab.fill("input[name=token]", "not the token")
    tab.click("button[type=submit]")
    assert "Wrong access token" in tab.inner_text("body")
    tab.fill("input[name=token]", TOKEN)
    tab.click("button[type=submit]")
    wait_ready(tab)
    assert TOKEN not in tab.url and TOKEN not in tab.content()
    assert tab.evaluate("() => document.cookie") == ""  # HttpOnly
    cookies = tab.context.cookies()
    assert len(cookies) == 1 and cookies[0]["httpOnly"] and cookies[0]["value"] != TOKEN
    assert tab.get_attribute("#rev-label", "data-revolution") is not None
    # The 401 before login was the only one; the rest loaded without errors.
    assert [e for e in tab.errors if "401" not in e] == []


def test_port_in_use_is_one_clear_line():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(PageError) as e:
            PageServer(port=port).start()
    msg = str(e.value)
    assert msg == (
        f"page: port {port} on 127.0.0.1 is in use (another page or program); choose another "
        "port (page.port)"
    )


def test_short_token_refused():
    with pytest.raises(PageError, match="at least 16 characters"):
        PageServer(host="127.0.0.2", port=0, token="short")


CONFIG_BAD = [
    ({"token": TOKEN}, "page.token: not allowed; put the token in a file"),
    ({"colour": 1}, "page.colour: unknown key"),
    ({"port": 70000}, "page.port = 70000: must be a whole number 0 to 65535"),
    ({"port": "8050"}, "page.port = '8050': must be a whole number"),
    ({"host": "127.0.0.2"}, "twin.toml: page: bound to 127.0.0.2, which is not 127.0.0.1"),
    ({"token_file": "missing.token"}, "page.token_file = 'missing.token': cannot read it"),
    ({"token_env": "RD_PAGE_TOKEN_NOT_SET_X"}, "page.token_env = 'RD_PAGE_TOKEN_NOT_SET_X': the"),
    ({"limits": "missing.toml"}, "missing.toml: cannot read the limits file"),
]


@pytest.mark.parametrize("table,msg", CONFIG_BAD)
def test_page_table_errors_name_file_and_key(tmp_path, table, msg):
    from reciprocating_drive.page.config import page_from_table

    with pytest.raises(PageError) as e:
        page_from_table(table, "twin.toml", tmp_path)
    assert msg in str(e.value) and "\n" not in str(e.value), str(e.value)
    assert TOKEN not in str(e.value)


def test_page_table_reads_token_file_and_limits(tmp_path):
    from reciprocating_drive.page.config import page_from_table

    (tmp_path / "page.token").write_text(TOKEN + "\n")
    (tmp_path / "limits.toml").write_text((ROOT / "examples" / "twin" / "limits.toml").read_text())
    p = page_from_table(
        {"host": "127.0.0.2", "port": 0, "token_file": "page.token", "limits": "limits.toml"},
        "twin.toml",
        tmp_path,
    )
    assert p.token == TOKEN and p.limits.limits[0].name == "crank torque high"
    p.start()
    try:
        status, _, _ = get(p.url + "api/state")
        assert status == 401
        status, _, _ = get(p.url + "api/state", {"Authorization": f"Bearer {TOKEN}"})
        assert status == 200
    finally:
        p.close()


def test_trend_window_from_the_database_and_zoom(tmp_path, server, page_of):
    """Three hours of revolutions (one every 2 s, written straight into the database) with one
    torque spike: the window picked on the page selects the database's rows of that span; a
    window of more rows than the page draws is bucketed by SQL and keeps the spike; dragging over
    a chart zooms into the span dragged over."""
    db = Database(tmp_path / "twin.sqlite", time_origin=1.7e9)
    n = 3 * 3600 // 2
    sums = []
    for i in range(n):
        s = dict.fromkeys(SUMMARY_FIELDS, 0.0)
        s.update(revolution=i, start_time=2.0 * i, mean_speed=6.8, friction_work=-180.0)
        s.update(crank_torque_max=9e3 if i == 2500 else 400.0 + (i % 7), crank_torque_min=-50.0)
        sums.append(s)
    db.revolutions(sums)
    page = server(database=db.path)
    page.open(["crank.model_angle", "suspension.position", "rod.force"], time_origin=1.7e9)
    time.sleep(0.2)
    tab = page_of(page.url)
    wait_ready(tab)
    (in_hour,) = db.db.execute(
        "SELECT COUNT(*) FROM revolutions WHERE start_time >= ?", (2.0 * (n - 1) - 3600,)
    ).fetchone()
    assert in_hour == 1801
    assert tab.get_attribute("#trends", "data-points") == str(in_hour)  # the default: last hour
    tab.select_option("#window", "600")
    tab.wait_for_function("() => document.getElementById('trends').dataset.points === '301'")
    tab.select_option("#window", "21600")
    tab.wait_for_function("() => S.trend.window === 21600")
    got = tab.evaluate("() => S.trend.crank_torque_peak")
    # All 5 400 rows are in the window: more than 2 000, so buckets of 21600/1999 s (about 5
    # rows each), each keeping its largest torque.
    t = 2.0 * np.arange(n)
    torque = np.array([s["crank_torque_max"] for s in sums])
    bucket = np.floor((t - (t[-1] - 21600)) / (21600 / 1999)).astype(int)
    want = [torque[bucket == b].max() for b in np.unique(bucket)]
    assert len(got) <= 2000 and got == want and max(got) == 9e3
    # Zoom: drag over the middle half of the torque chart.
    over = tab.query_selector("#t-crank_torque_peak .u-over").bounding_box()
    y = over["y"] + over["height"] / 2
    x0 = tab.evaluate(
        "() => [S.charts.crank_torque_peak.scales.x.min, S.charts.crank_torque_peak.scales.x.max]"
    )
    tab.mouse.move(over["x"] + over["width"] * 0.25, y)
    tab.mouse.down()
    tab.mouse.move(over["x"] + over["width"] * 0.75, y, steps=5)
    tab.mouse.up()
    x1 = tab.evaluate(
        "() => [S.charts.crank_torque_peak.scales.x.min, S.charts.crank_torque_peak.scales.x.max]"
    )
    assert x0[0] < x1[0] < x1[1] < x0[1]
    assert 0.4 < (x1[1] - x1[0]) / (x0[1] - x0[0]) < 0.6
    # Clock times: the x values are time_origin + start_time.
    assert x0[1] == pytest.approx(1.7e9 + 2.0 * (n - 1), abs=240)
    assert tab.errors == []


class Ev:
    """A data-health event as the plant sources and the pipeline make them (kind, message, t,
    count)."""

    def __init__(self, kind, message, count=1, t=None):
        self.kind, self.message, self.count, self.t = kind, message, count, t


def test_data_health_shows_connection_lag_gaps_drops_and_fmu_errors(server, page_of):
    page = server()
    outputs = ["crank.model_angle", "suspension.position", "rod.force"]
    origin = time.time() - 10.0
    page.open(outputs, time_origin=origin)
    tab = page_of(page.url)
    wait_ready(tab)
    rows = np.array([[9.0, 1.0, 0.1, 5.0], [9.5, 1.1, 0.11, 6.0]])
    events = [
        (0, time.time(), Ev("gap", "gap of 0.2 s at t = 3", t=3.0)),
        (1, time.time(), Ev("dropped", "5 sample(s) dropped: status BadSensorFailure", count=5)),
        (2, time.time(), Ev("dropped", "2 sample(s) dropped: not finite", count=2)),
        (3, time.time(), Ev("fmu_error", "FMU: fmi2DoStep failed at t = 9.2")),
    ]
    before = time.time()
    page.add(rows, 0, [], 0, events)
    after = time.time()
    page.health(connected=False)
    page.add(rows[:0], 0, [], 0, [Ev("reconnect", "reconnected after 5 s; no history")])

    def cell(key):
        return tab.inner_text(f"#health tr[data-key={key}] td:nth-child(2)")

    tab.wait_for_function(
        "() => document.querySelector('#health tr[data-key=connected] td:nth-child(2)')"
        ".textContent === 'connected'"
    )
    assert cell("gaps") == "1" and cell("dropped") == "7" and cell("fmu_errors") == "1"
    assert cell("last_event") == "reconnect: reconnected after 5 s; no history"
    # The machine's state (docs/twin.md "Machine states"): running before any stop is seen,
    # then stopped since the event's time (a clock time: the source has one).
    assert cell("machine") == "running (no stop seen yet)"
    stop = Ev("machine_stopped", "t = 9.25 s (line 9251): stopped (...)", t=9.25)
    page.add(rows[:0], 0, [], 0, [stop])
    tab.wait_for_function(
        "() => document.querySelector('#health tr[data-key=machine] td:nth-child(2)')"
        ".textContent.startsWith('stopped since ')"
    )
    assert cell("machine").startswith("stopped since ")
    # The lag: the wall clock when the rows arrived minus the last sample's, origin + 9.5 (shown
    # with 3 digits).
    lag = float(cell("lag").split()[0])
    assert before - origin - 9.5 - 0.01 < lag < after - origin - 9.5 + 0.01, lag
    page.health(connected=False)
    tab.wait_for_function(
        "() => document.querySelector('#health tr[data-key=connected] td:nth-child(2)')"
        ".textContent === 'NOT connected'"
    )
    assert tab.errors == []


def test_hostile_requests_get_a_status_and_one_line(server):
    page = server()
    for path, code in [
        ("api/trend?window=nan", 400),
        ("api/trend?window=-1", 400),
        ("api/trend?window=1e99", 400),
        ("api/trend?window=abc", 400),
        ("api/nothing", 404),
        ("static/../server.py", 403),
        ("static/nothing.js", 404),
    ]:
        status, body, headers = get(page.url + path)
        assert status == code, (path, status, body)
        assert body.count("\n") <= 1 and "Traceback" not in body, body
        assert "default-src 'self'" in headers.get("Content-Security-Policy", "") or code != 400
    req = urllib.request.Request(page.url + "api/state", data=b"x=1", method="POST")
    with pytest.raises(urllib.error.HTTPError) as e:
        urllib.request.urlopen(req, timeout=5)
    assert e.value.code == 405  # read-only: nothing but GET (and the login form's POST)
