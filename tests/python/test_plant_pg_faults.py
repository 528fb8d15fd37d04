"""A PostgreSQL sink against a real server that refuses SSL or stops answering (docs/plant.md
"Unresponsive server or database"): Debian's server started by the tests (tests/python/
pg_server.py), without SSL as initdb makes it, stopped with SIGSTOP (its processes alive, the
kernel still accepting the bytes: a hung server, not a closed one)."""

from __future__ import annotations

import os
import signal
import threading
import time

import plant_util as pu


def test_sslmode_require_against_a_server_without_ssl_is_one_line_at_once(pg, tmp_path):
    cfg = pu.write_config(
        tmp_path / "ssl.toml",
        source=pu.csv_source(),
        sinks=pu.pg_sink(pg.dsn + " sslmode=require"),
    )
    t0 = time.monotonic()
    p = pu.run(cfg, timeout=60)
    took = time.monotonic() - t0
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 1, p.stderr  # docs/install.md "Exit codes": the run could not start
    assert len(lines) == 1 and "does not support SSL" in lines[0] and "sslmode" in lines[0], lines
    assert took < 20, took  # not retried as an outage for retry_for (300 s)


def _server_pids(pg) -> list[int]:
    """The postmaster of this server (postmaster.pid) and its children: only ours."""
    with open(os.path.join(pg.data, "postmaster.pid")) as f:
        main = int(f.readline())
    kids = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
            if ppid == main:
                kids.append(int(d))
    return [main, *kids]


def test_database_that_stops_answering_gives_a_line_then_one_every_notice_interval(
    pg, tmp_path, fmu_path
):
    # 12 s of data in real time; the server stopped 9 s from 3 s on, then let go on.
    cfg = pu.write_config(
        tmp_path / "hung.toml",
        run="hung",
        source=pu.csv_source(pace=1.0),
        sinks=pu.pg_sink(pg.dsn, extra="notice_interval = 2\n"),
        fmu=fmu_path,
    )
    p = pu.start(cfg)
    got = []

    def read():
        for line in p.stderr:
            got.append((time.monotonic(), line.rstrip("\n")))

    th = threading.Thread(target=read, daemon=True)
    th.start()
    pids = []
    try:
        time.sleep(3)
        pids = _server_pids(pg)
        stopped = time.monotonic()
        for pid in pids:
            os.kill(pid, signal.SIGSTOP)
        time.sleep(9)
    finally:
        for pid in pids:
            try:
                os.kill(pid, signal.SIGCONT)
            except ProcessLookupError:
                pass
    try:
        p.wait(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(timeout=10)
    th.join(timeout=5)
    down = [t - stopped for t, x in got if ": not answering (" in x]
    more = [t - stopped for t, x in got if "still not answering after" in x]
    back = [x for _t, x in got if "answering again after" in x]
    # ANSWER_WITHIN (5 s) after the first call that hangs (a commit every 0.1 s or so).
    assert len(down) == 1 and down[0] < 7.5, got
    assert 1 <= len(more) <= 3, got  # every 2 s until the server goes on at 9 s
    assert back, got
    assert p.returncode == 0 and not any("Traceback" in x for _t, x in got), got
    assert len(pu.samples(pg.dsn, "hung")) == 11801
