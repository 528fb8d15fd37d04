#!/usr/bin/env python3
"""Speed of the distributed replay (docs/twin.md "Distributed replay"): the shipped encoder sample
made ten times longer (`longer_sample`: copies one after the other, time and angle continued),
replayed by `scripts/twin.py --distributed` on a LocalCluster of 1 and of 2 worker processes
(one thread each), beside the sequential replay of the same file in the same run.

Each figure is `scripts/twin.py`'s own last line, "N samples computed in T s": the clock runs from
the workers being ready (the FMU shipped to them) until the result files are written, so it
includes sending the pieces, computing them, the workers writing them to the work folder, and
assembling the result. The cluster's start-up and the scan of the input (sequential, reported)
are not in it. The sequential baseline is the twin's wall time less its start-up (the time to a run of a
ten-line file). The last line gives the floor of 2 workers on this machine from CPU times, which
the machine's load changes little: half the pieces' CPU, or the pieces' and the client's CPU
(the client hosts the LocalCluster's scheduler) over the cores, against 1 worker's pieces' CPU.
The machine's load (`uptime`) is printed before and after: figures from a shared
machine carry its noise.

    .venv/bin/python scripts/bench_replay.py [--repeat N] [--times 10] [--revolutions-per-piece 10]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import re
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "data" / "twin" / "pump_encoder.csv"
TWIN = [sys.executable, str(ROOT / "scripts" / "twin.py")]
COUNTS = 4096
ARGS = ["--angle-unit", "counts", "--counts-per-rev", str(COUNTS)]


def longer_sample(path: pathlib.Path, times: int = 10, sample: pathlib.Path = SAMPLE) -> int:
    """Writes `times` copies of the sample one after the other: each copy's time starts one mean
    interval after the previous copy's end, and its encoder counts continue the previous copy's
    unwrapped count by one mean step (so the junction is neither a gap nor a jump). Returns the
    number of samples."""
    t, c = np.loadtxt(sample, delimiter=",", skiprows=1, unpack=True)
    u = np.unwrap(c, period=COUNTS)  # unwrapped counts
    dt = float(np.median(np.diff(t)))
    du = float(np.round(np.median(np.diff(u))))
    span_t, span_u = t[-1] - t[0] + dt, u[-1] - u[0] + du
    with open(path, "w") as f:
        f.write("time,crank_angle\n")
        for k in range(times):
            tk = np.round(t + k * span_t, 6)
            ck = np.mod(u + k * span_u, COUNTS).astype(np.int64)
            f.write("".join(f"{a:.6f},{b}\n" for a, b in zip(tk.tolist(), ck.tolist())))
    return times * len(t)


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def distributed(src, out, workers: int, n_rev: int) -> tuple:
    """(seconds, samples, pieces, the workers' CPU seconds in the pieces, the client's CPU
    seconds meanwhile, the share of the machine's cores busy meanwhile) of one distributed
    replay, from its own last line."""
    p = subprocess.run(
        [*TWIN, str(src), *ARGS, "--out", str(out), "--distributed", "--workers", str(workers)]
        + ["--revolutions-per-piece", str(n_rev)],
        capture_output=True,
        text=True,
        timeout=1200,
    )
    if p.returncode != 0:
        raise SystemExit(f"bench_replay.py: the distributed replay failed: {p.stderr.strip()}")
    m = re.search(r"replay: (\d+) samples computed in ([0-9.]+) s", p.stderr)
    pieces = re.search(r"in (\d+) pieces", p.stderr)
    cpu = re.search(r"CPU in the pieces ([0-9.]+) s, the client's ([0-9.]+) s", p.stderr)
    busy = re.search(r"cores (\d+)% busy", p.stderr)
    return (
        float(m.group(2)),
        int(m.group(1)),
        int(pieces.group(1)),
        float(cpu.group(1)),
        float(cpu.group(2)),
        float(busy.group(1)) / 100 if busy else float("nan"),
    )


def sequential(src, out) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one sequential replay (a process, start-up included)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([*TWIN, str(src), *ARGS, "--out", str(out)], check=True, capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=10, help="the best of N runs (default 10)")
    ap.add_argument("--times", type=int, default=10, help="copies of the sample (default 10)")
    ap.add_argument("--revolutions-per-piece", type=int, default=10)
    a = ap.parse_args(argv)
    print(f"load before: {uptime()}")
    with tempfile.TemporaryDirectory(prefix="bench-replay-") as d:
        d = pathlib.Path(d)
        src = d / "long.csv"
        n = longer_sample(src, a.times)
        one = d / "one.csv"
        one.write_text("\n".join(SAMPLE.read_text().splitlines()[:11]) + "\n")
        start = min(sequential(one, d / "o.csv") for _ in range(a.repeat))
        runs = [sequential(src, d / "s.csv") for _ in range(a.repeat)]
        seq = min(r[0] for r in runs) - start[0]
        cpu = min(r[1] for r in runs) - start[1]
        print(f"{n} samples ({a.times} × the shipped sample), {os.cpu_count()} cores")
        print(
            f"sequential replay: {seq:.3f} s, {n / seq:.0f} samples/s, CPU {cpu:.3f} s "
            f"(start-up {start[0]:.2f} s, CPU {start[1]:.2f} s, subtracted)"
        )
        # 1 and 2 workers alternate, so that a change of the machine's load hits both alike.
        runs: dict = {1: [], 2: []}
        for _ in range(a.repeat):
            for k in (1, 2):
                runs[k].append(distributed(src, d / f"d{k}.csv", k, a.revolutions_per_piece))
        rates = {}
        for k in (1, 2):
            best = min(r[0] for r in runs[k])
            busy = min(runs[k])[5]  # that of the best run
            samples, pieces = runs[k][0][1], runs[k][0][2]
            work_cpu = min(r[3] for r in runs[k])
            rates[k] = samples / best
            same = (d / f"d{k}.csv").read_bytes() == (d / "s.csv").read_bytes()
            print(
                f"distributed, {k} worker(s): {best:.3f} s, {rates[k]:.0f} samples/s "
                f"(workers' CPU in the pieces {work_cpu:.3f} s; {pieces} pieces of "
                f"{a.revolutions_per_piece} revolutions; the cores {busy:.0%} busy; result "
                f"{'identical to' if same else 'DIFFERENT from'} the sequential one)"
            )
        print(f"2 workers / 1 worker: {rates[2] / rates[1]:.2f}× (target ≥ 1.8×)")
        # The floor of 2 workers on this machine: no worker finishes before half the pieces'
        # CPU, and the pieces' CPU and the client's (which hosts the LocalCluster's scheduler)
        # share the cores. One worker's floor is its pieces' CPU (the client on another core).
        pieces1 = min(r[3] for r in runs[1])
        pieces2 = min(r[3] for r in runs[2])
        client2 = min(r[4] for r in runs[2])
        cores = os.cpu_count() or 1
        floor = max(pieces2 / 2, (pieces2 + client2) / cores)
        print(
            f"2 workers' floor: max(pieces' CPU {pieces2:.3f} s / 2, (pieces' {pieces2:.3f} + "
            f"client's {client2:.3f} s CPU) / {cores} cores) = {floor:.3f} s; 1 worker's: "
            f"its pieces' CPU {pieces1:.3f} s; at best {pieces1 / floor:.2f}× on an idle machine"
        )
    print(f"load after: {uptime()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
