#!/usr/bin/env python3
"""Resident memory of the twin through a long standstill (docs/twin.md "Machine states").

The default machine runs 10 s at 65 strokes/min, ramps down in 2 s and stands still for
`--minutes`, read by a 4096-count encoder at 1 kHz that dithers by one count at standstill (a flip
every 20 ms on average). The samples go to a `Twin` in chunks of 4096 lines, as a live source
hands them over; the rows are dropped as a sink would have stored them. Prints the resident
memory (VmRSS) after the first minute of standstill and at the end, and the samples per second.

    .venv/bin/python scripts/bench_standstill.py --minutes 120
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))

from reciprocating_drive.twin import Options, Twin  # noqa: E402
from reciprocating_drive.twin.sample import OMEGA0  # noqa: E402

RATE = 1000.0
CHUNK = 4096


def rss_mib() -> float:
    for line in pathlib.Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS in /proc/self/status")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=120.0, help="standstill [min] (default 120)")
    ap.add_argument("--fmu", default=str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
    a = ap.parse_args(argv)
    tw = Twin(a.fmu, "default", Options(angle_unit="counts", counts_per_rev=4096))
    rng = np.random.default_rng(7)
    run, down = 10.0, 2.0
    stop_at = run + down
    n = int((stop_at + 60.0 * a.minutes) * RATE) + 1
    one_minute = int((stop_at + 60.0) * RATE)
    theta_stop = OMEGA0 * run + 0.5 * OMEGA0 * down
    flip = 0
    rss_minute = None
    rows = revs = 0
    tw.feed(["time,crank_angle"], 1)
    t_start = time.perf_counter()
    for lo in range(0, n, CHUNK):
        k = np.arange(lo, min(n, lo + CHUNK))
        t = k / RATE
        th = np.where(
            t < run,
            OMEGA0 * t,
            np.where(
                t < stop_at,
                OMEGA0 * run + OMEGA0 * (t - run) - 0.5 * OMEGA0 / down * (t - run) ** 2,
                theta_stop,
            ),
        )
        c = np.floor(th / (2 * math.pi) * 4096)
        still = t >= stop_at
        flips = (np.cumsum(still & (rng.random(len(t)) < 0.05)) + flip) % 2
        flips[~still] = 0
        flip = int(flips[-1])
        counts = ((c + flips) % 4096).astype(np.int64)
        lines = [f"{x!r},{y}" for x, y in zip(t.tolist(), counts.tolist())]
        out, sums = tw.feed(lines, 2 + lo)
        rows, revs = rows + len(out), revs + len(sums)
        if rss_minute is None and k[-1] >= one_minute:
            rss_minute = rss_mib()
    out, sums = tw.finish()
    rows, revs = rows + len(out), revs + len(sums)
    wall = time.perf_counter() - t_start
    rss_end = rss_mib()
    assert rows == n, (rows, n)
    print(
        f"{n} samples ({a.minutes:g} min of standstill at 1 kHz) in {wall:.1f} s "
        f"({n / wall:.0f} samples/s), {revs} revolutions, state {tw.machine_state}; "
        f"resident memory {rss_minute:.1f} MiB after the first minute of standstill, "
        f"{rss_end:.1f} MiB at the end ({100 * (rss_end / rss_minute - 1):+.1f} %)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
