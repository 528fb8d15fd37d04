"""The page beside a running twin (python -m reciprocating_drive.page, docs/page.md "Beside a
twin"): a real process following a database the test writes as the twin's SQLite sink does, and
its command-line errors."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from reciprocating_drive.twin import SUMMARY_FIELDS
from test_page import Database, Feed, browser, chromium, page_of, sample_lines, wait_ready  # noqa: F401 (fixtures)

ROOT = Path(__file__).resolve().parents[2]


class Samples(Database):
    """The database with the samples table's card columns (the plant schema's names)."""

    def __init__(self, path, time_origin=None):
        super().__init__(path, time_origin)
        self.db.execute(
            "CREATE TABLE samples (run INTEGER NOT NULL, seq INTEGER NOT NULL, t REAL NOT NULL, "
            "crank_model_angle REAL, suspension_position REAL, rod_force REAL, "
            "PRIMARY KEY (run, seq))"
        )
        self.seq = 0


class SinkLike:
    """What the plant's SQLite sink writes per chunk: samples, revolutions (one transaction)."""

    def __init__(self, db: Samples):
        self.db = db

    def open(self, outputs, time_origin=None):
        names = ("crank.model_angle", "suspension.position", "rod.force")
        self.cols = [1 + outputs.index(n) for n in names]

    def add(self, rows, _first, sums, _r, _e):
        d = self.db
        with d.lock:
            d.db.execute("BEGIN")
            d.db.executemany(
                "INSERT INTO samples VALUES (1, ?, ?, ?, ?, ?)",
                [
                    (d.seq + i, float(r[0]), *(float(r[c]) for c in self.cols))
                    for i, r in enumerate(rows)
                ],
            )
            d.seq += len(rows)
            names = ", ".join(SUMMARY_FIELDS)
            d.db.executemany(
                f"INSERT INTO revolutions (run, {names}) VALUES (1{', ?' * len(SUMMARY_FIELDS)})",
                [tuple(s[f] for f in SUMMARY_FIELDS) for s in sums],
            )
            d.db.execute("COMMIT")


def start(args, env=None):
    e = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "python"), *sys.path]))
    e.update(env or {})
    return subprocess.Popen(
        [sys.executable, "-m", "reciprocating_drive.page", *args],
        stderr=subprocess.PIPE,
        text=True,
        env=e,
    )


def url_of(proc, timeout=20.0):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        line = proc.stderr.readline()
        m = re.search(r"on (http://\S+/)", line)
        if m:
            return m.group(1)
        if proc.poll() is not None:
            break
    proc.kill()
    pytest.fail(f"the page did not start: {line!r}")


def stop(proc):
    proc.send_signal(signal.SIGTERM)
    try:
        assert proc.wait(10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)


def test_follows_the_database_while_the_twin_commits(fmu_path, tmp_path, page_of):  # noqa: F811
    db = Samples(tmp_path / "twin.sqlite")

    # The twin writes to the database only (as a plant sink would); the page process reads it.
    feed = Feed(fmu_path, SinkLike(db), _NoDb())
    feed.feed(sample_lines(0, 4, 0.0))
    proc = start(["--database", db.path, "--port", "0", "--poll", "0.1"])
    try:
        url = url_of(proc)
        tab = page_of(url)
        wait_ready(tab)
        tab.wait_for_function(
            "() => document.getElementById('rev-label').dataset.revolution === '3'"
        )
        tab.evaluate(
            """() => { window.seen = {};
            new MutationObserver(() => {
                const r = document.getElementById('rev-label').dataset.revolution;
                if (!(r in window.seen)) window.seen[r] = Date.now() / 1000;
            }).observe(document.getElementById('rev-label'), {attributes: true}); }"""
        )
        committed = {}
        t = 4.0
        while t < 8.0:
            sums = feed.feed(sample_lines(t, t + 0.1, 0.0))
            for s in sums:
                committed[str(s["revolution"])] = time.time()
            time.sleep(0.1)
            t += 0.1
        time.sleep(1.0)
        seen = tab.evaluate("() => window.seen")
        assert set(committed) <= set(seen), (committed, seen)
        late = [seen[k] - committed[k] for k in committed]
        assert len(late) >= 3 and max(late) < 1.0, late
        assert tab.inner_text("#health tr[data-key=run_status] td:nth-child(2)") == "running"
        # The card comes from the samples table.
        assert int(tab.get_attribute("#card", "data-cards")) >= 4
        row = db.db.execute(
            "SELECT friction_work FROM revolutions ORDER BY revolution DESC LIMIT 1"
        ).fetchone()
        assert float(tab.get_attribute("#now .num[data-key=friction_work]", "data-value")) == row[0]
        assert tab.errors == []
    finally:
        stop(proc)


class _NoDb:
    def revolutions(self, sums):
        pass


def run_cli(args, env=None, timeout=30):
    p = start(args, env)
    try:
        _, err = p.communicate(timeout=timeout)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(5)
    return p.returncode, err


def test_command_line_errors_are_one_line(tmp_path):
    db = Database(tmp_path / "twin.sqlite")
    bad = tmp_path / "limits.toml"
    bad.write_text('[[limit]]\nvalue = "crank_torque_peak"\nhigh = "a lot"\n')
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        busy = s.getsockname()[1]
        cases = [
            (["--database", str(tmp_path / "none.sqlite")], "none.sqlite: no such file"),
            (["--database", db.path, "--limits", str(bad)], "limit[0].high = 'a lot'"),
            (["--database", db.path, "--host", "127.0.0.2"], "an access token is required"),
            (["--database", db.path, "--port", str(busy)], f"port {busy} on 127.0.0.1 is in use"),
            (["--database", db.path, "--poll", "0"], "--poll 0: must be 0.01 to 60 seconds"),
            (["--database", db.path, "--port", "x"], "argument --port: invalid int value"),
            (
                ["--database", db.path, "--host", "127.0.0.2", "--token-file", str(tmp_path)],
                "--token-file",
            ),
        ]
        for args, msg in cases:
            code, err = run_cli(args)
            assert code == 2 and msg in err and err.count("\n") == 1, (args, code, err)
            assert "Traceback" not in err


def test_token_from_the_environment_never_on_the_command_line(tmp_path):
    db = Database(tmp_path / "twin.sqlite")
    token = "env-token-0123456789abcdef"
    proc = start(
        ["--database", db.path, "--host", "127.0.0.2", "--port", "0"], {"RD_PAGE_TOKEN": token}
    )
    try:
        url = url_of(proc)
        import urllib.error
        import urllib.request

        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(url + "api/state", timeout=5)
        assert e.value.code == 401
        req = urllib.request.Request(
            url + "api/state", headers={"Authorization": f"Bearer {token}"}
        )
        with urllib.request.urlopen(req, timeout=5) as r:
            assert r.status == 200
        cmdline = Path(f"/proc/{proc.pid}/cmdline").read_bytes().decode()
        assert token not in cmdline
    finally:
        stop(proc)


def test_alarms_of_a_followed_run_are_logged_one_line_each(fmu_path, tmp_path):
    """The command-line page evaluates the limits on the revolutions it reads while the twin
    writes them, and writes each alarm raised or cleared to its standard error, one line each."""
    import select

    db = Samples(tmp_path / "twin.sqlite")
    feed = Feed(fmu_path, SinkLike(db), _NoDb())
    feed.feed(sample_lines(0, 4, 0.0))
    limits = tmp_path / "limits.toml"
    limits.write_text(
        '[[limit]]\nname = "torque"\nvalue = "crank_torque_peak"\nhigh = 8000.0\n'
        "hysteresis = 500.0\ndelay = 2\n"
    )
    proc = start(["--database", db.path, "--port", "0", "--limits", str(limits), "--poll", "0.1"])
    lines = []
    try:
        url_of(proc)
        time.sleep(0.5)
        feed.feed(sample_lines(4, 9, 50e3))
        time.sleep(0.5)
        feed.feed(sample_lines(9, 15, 0.0))
        t0 = time.monotonic()
        while len(lines) < 2 and time.monotonic() - t0 < 20:
            if select.select([proc.stderr], [], [], 0.5)[0]:
                lines.append(proc.stderr.readline())
    finally:
        stop(proc)
    assert len(lines) == 2, lines
    assert lines[0].startswith("page: alarm torque (warning) raised: crank_torque_peak = ")
    assert lines[1].startswith("page: alarm torque (warning) cleared: crank_torque_peak = ")
