"""What the live page costs (docs/page.md, "Cost"): the twin fed live at 1 kHz in 50 ms chunks, for
the default machine (65 strokes/min) and kvo630 (1500 rpm, 25 revolutions a second), first without
the page (the baseline), then with the page served and open in headless chromium, in one run.

    PYTHONPATH=python .venv/bin/python -m reciprocating_drive.page.bench [--seconds 60]

Measured: the CPU time of the page server's thread (psutil, the thread's user + system time), the
CPU time the twin's thread spends handing rows and summaries to the page (`PageServer.add`,
time.thread_time), the twin's own CPU time per second of data, and the largest time to process a
chunk (it must stay below the 50 ms the chunk covers to keep up live) and the largest CPU time of
one `PageServer.add`. The page's last revolution is checked to be the twin's after each run.
"""

# Layer: workflows, the page (docs/architecture.md); a comment, as --help prints the docstring.

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil

from ..alarms import load_limits
from ..twin.core import Options, Twin
from ..twin.sample import truth
from .server import PageServer

ROOT = Path(__file__).resolve().parents[3]
FMU = os.environ.get("RD_FMU", str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
CHUNK = 0.05
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def lines_of(machine: str, t0: float, t1: float) -> list[str]:
    t = np.arange(round(t0 * 1000), round(t1 * 1000)) / 1000.0
    if machine == "kvo630":
        theta = 2 * math.pi * 1500 / 60 * t
    else:
        theta = truth(t)[0]
    return [f"{float(a)!r},{float(b)!r}" for a, b in zip(t, np.mod(theta, 2 * math.pi))]


def thread_cpu(native_id) -> float:
    for th in psutil.Process().threads():
        if th.id == native_id:
            return th.user_time + th.system_time
    return math.nan


def live(machine: str, seconds: float, page: PageServer | None) -> dict:
    opts = Options(window=0.006, max_speed=400.0) if machine == "kvo630" else Options()
    tw = Twin(FMU, machine, opts)
    if page is not None:
        page.open(tw.outputs, time_origin=None)
    lineno, first = 1, True
    twin_cpu = add_cpu = 0.0
    worst = worst_add = 0.0
    revs = 0
    origin = time.time()
    page_cpu0 = thread_cpu(page.native_thread_id) if page else 0.0
    t = 0.0
    while t < seconds - 1e-9:
        due = origin + t + CHUNK
        now = time.time()
        if now < due:
            time.sleep(due - now)
        lines = lines_of(machine, t, t + CHUNK)
        if first:
            lines, first = ["time,crank_angle", *lines], False
        w0, c0 = time.perf_counter(), time.thread_time()
        rows, sums = tw.feed(lines, lineno)
        c1 = time.thread_time()
        if page is not None:
            page.add(rows, 0, sums, 0, [])
        c2 = time.thread_time()
        w2 = time.perf_counter()
        worst = max(worst, w2 - w0)
        worst_add = max(worst_add, c2 - c1)
        twin_cpu += c1 - c0
        add_cpu += c2 - c1
        revs += len(sums)
        lineno += len(lines)
        t += CHUNK
    wall = time.time() - origin
    page_cpu = (thread_cpu(page.native_thread_id) - page_cpu0) if page else 0.0
    return {
        "wall": wall,
        "revs": revs,
        "twin": twin_cpu / wall,
        "add": add_cpu / wall,
        "server": page_cpu / wall,
        "worst_chunk_ms": worst * 1e3,
        "worst_add_ms": worst_add * 1e3,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    a = ap.parse_args(argv)
    from playwright.sync_api import sync_playwright

    limits = load_limits(ROOT / "examples" / "twin" / "limits.toml")
    print(
        f"{'machine':8} {'page':5} {'revs':>5} {'twin CPU':>9} {'add CPU':>8} {'server CPU':>11} "
        f"{'worst chunk':>12} {'worst add':>10}"
    )
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=a.chromium, args=FLAGS, headless=True)
        for machine in ("default", "kvo630"):
            for with_page in (False, True):
                page = None
                if with_page:
                    page = PageServer(port=0, limits=limits).start()
                    tab = browser.new_page()
                    tab.goto(page.url)
                    tab.wait_for_selector("body[data-ready='1']")
                r = live(machine, a.seconds, page)
                if page is not None:
                    # The page shows the last revolution once the next push is done (0.1 s).
                    tab.wait_for_function(
                        f"() => document.getElementById('rev-label').dataset.revolution === "
                        f"'{r['revs'] - 1}'",
                        timeout=5000,
                    )
                    tab.close()
                    page.close()
                print(
                    f"{machine:8} {'open' if with_page else 'none':5} {r['revs']:5d} "
                    f"{r['twin']:9.1%} {r['add']:8.2%} {r['server']:11.2%} "
                    f"{r['worst_chunk_ms']:9.1f} ms {r['worst_add_ms']:7.2f} ms",
                    flush=True,
                )
        browser.close()
    cpu = subprocess.run(
        ["bash", "-c", "grep -m1 'model name' /proc/cpuinfo | cut -d: -f2"],
        capture_output=True,
        text=True,
    ).stdout.strip()
    print(f"{a.seconds:g} s live per row; CPU as a share of one core; machine: {cpu}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
