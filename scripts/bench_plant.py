#!/usr/bin/env python3
"""Benchmark of the twin in a plant (docs/plant.md, "Speed and memory").

    .venv/bin/python scripts/bench_plant.py [--repeats 10] [--live-seconds 12] [--samples 10000000]

1. Replay: the shipped sample repeated `--repeats` times (12 s each) from a file, into SQLite and
   PostgreSQL (a temporary server, tests/python/pg_server.py), with every sample's row and with
   summaries only; beside it, in the same run, the baseline: the twin's core alone on the same
   lines (Twin.feed, no source, no sink). Figures: multiples of real time of the whole process,
   by wall time and by CPU time (all its threads, and for PostgreSQL the server's backend too):
   on a shared machine the wall time says how busy the others were, the CPU time what the twin
   needs.
2. Live at 1 kHz: the simulated PLC in real time, the twin subscribed over OPC UA (scalar nodes),
   SQLite; the database is polled every 10 ms and each sample's latency is the poll's wall time
   minus the sample's source timestamp (an upper bound, by at most the poll interval). Default
   machine and kvo630.
3. Memory: `--samples` synthetic 1 kHz samples piped into a summaries-only SQLite run; the twin's
   resident memory (VmRSS) sampled every 0.5 s with the samples committed by then.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import resource
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
sys.path.insert(0, str(ROOT / "tests" / "python"))
SAMPLE = ROOT / "data" / "twin" / "pump_encoder.csv"
FMU = str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu")
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "python")}


def long_file(path: pathlib.Path, repeats: int) -> tuple[int, float]:
    """The sample `repeats` times, each shifted by 12.1 s (a 0.1 s gap between them)."""
    lines = SAMPLE.read_text().splitlines()
    head, body = lines[0], lines[1:]
    t = np.array([float(x.split(",")[0]) for x in body])
    rest = [x.split(",", 1)[1] for x in body]
    span = float(t[-1]) + 0.1
    with open(path, "w") as f:
        f.write(head + "\n")
        for k in range(repeats):
            f.write("".join(f"{v:.6f},{r}\n" for v, r in zip(t + k * span, rest)))
    return len(body) * repeats, repeats * span - 0.1


def config(path, run, source, sink, machine="default", extra=""):
    pathlib.Path(path).write_text(
        f'[run]\nid = "{run}"\nmachine_id = "bench"\nmachine = "{machine}"\nfmu = "{FMU}"\n{extra}\n'
        f"[source]\n{source}\n{sink}"
    )
    return path


def run_twin(cfg, stdin=None) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, str(ROOT / "scripts" / "twin_plant.py"), "--config", str(cfg)],
        env=ENV,
        stdin=stdin,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=stdin is None,
    )


def timed(cfg) -> tuple[float, float]:
    """Wall time and CPU time (user + system, all threads) of a whole twin process."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = run_twin(cfg)
    _, err = p.communicate(timeout=1800)
    if p.returncode != 0:
        raise SystemExit(f"bench_plant.py: the twin failed: {err.strip()}")
    w = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return w, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def server_cpu(pg) -> float:
    """CPU seconds of the PostgreSQL server's finished backends (the postmaster's children)."""
    if pg is None:
        return 0.0
    pid = pathlib.Path(pg.data, "postmaster.pid").read_text().split()[0]
    f = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(f[13]) + int(f[14])) / os.sysconf("SC_CLK_TCK")  # cutime + cstime


def baseline(path) -> float:
    """The twin's core alone on the file's lines (blocks of 64 KiB worth of lines)."""
    from reciprocating_drive.twin import Options, Twin

    lines = pathlib.Path(path).read_text().splitlines()
    t0 = time.perf_counter()
    tw = Twin(FMU, "default", Options(angle_unit="counts", counts_per_rev=4096))
    for i in range(0, len(lines), 3000):
        tw.feed(lines[i : i + 3000], i + 1)
    tw.finish()
    return time.perf_counter() - t0


def replay(repeats: int, d: pathlib.Path) -> None:
    from pg_server import PgServer

    data = d / "long.csv"
    n, span = long_file(data, repeats)
    src = f'type = "csv"\npath = "{data}"\nangle_unit = "counts"\ncounts_per_rev = 4096\n'
    print(f"replay: {n} samples, {span:.1f} s of data ({repeats} x the shipped sample)")
    b = baseline(data)
    print(f"  baseline, the twin's core alone (in process): {b:6.2f} s  {span / b:7.1f}x real time")
    with PgServer() as pg:
        for kind in ("sqlite", "postgres"):
            for samples in ('"all"', '"none"'):
                run = f"{kind}-{samples.strip(chr(34))}-{time.time_ns()}"
                sink = (
                    f'[[sink]]\ntype = "sqlite"\npath = "{d / run}.sqlite"\nsamples = {samples}\n'
                    if kind == "sqlite"
                    else f'[[sink]]\ntype = "postgres"\ndsn = "{pg.dsn}"\nsamples = {samples}\n'
                )
                server = pg if kind == "postgres" else None
                s0 = server_cpu(server)
                w, cpu = timed(config(d / f"{run}.toml", run, src, sink))
                time.sleep(0.2)  # the backend of the closed connection is reaped
                cpu += server_cpu(server) - s0
                label = f"{kind}, samples = {samples}"
                print(
                    f"  {label:<28} whole process: {w:6.2f} s wall {span / w:7.1f}x real time; "
                    f"CPU {cpu:5.2f} s ({span / cpu:6.1f}x real time per CPU second)"
                )


def live(seconds: float, machine: str, d: pathlib.Path) -> None:
    from plant_util import PlcProcess

    db = d / f"live-{machine}.sqlite"
    lines = SAMPLE.read_text().splitlines()
    n = min(len(lines) - 1, int(seconds * 1000))
    data = d / "live.csv"
    data.write_text("\n".join(lines[: n + 1]) + "\n")
    plc = PlcProcess("--speed", "1", "--start-delay", "3", "--nodes", "scalar", data=data)
    src = (
        f'type = "opcua"\nendpoint = "{plc.endpoint}"\nangle_node = "ns=2;s=Pump.CrankAngle"\n'
        'end_node = "ns=2;s=Pump.Finished"\nangle_unit = "counts"\ncounts_per_rev = 4096\n'
        "reconnect_max = 0.2\n"
    )
    sink = f'[[sink]]\ntype = "sqlite"\npath = "{db}"\n'
    p = run_twin(config(d / f"live-{machine}.toml", "live", src, sink, machine))
    lat: list = []
    try:
        with plc:
            seen, origin, c = -1, None, None
            while p.poll() is None:
                time.sleep(0.01)
                now = time.time()
                try:
                    c = c or sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1)
                    if origin is None:
                        r = c.execute(
                            "SELECT json_extract(state, '$.time_origin') FROM checkpoints"
                        ).fetchone()
                        origin = r[0] if r else None
                    rows = c.execute("SELECT seq, t FROM samples WHERE seq > ?", (seen,)).fetchall()
                except sqlite3.Error:
                    c = None
                    continue
                if rows and origin is not None:
                    lat += [now - (origin + t) for _, t in rows]
                    seen = max(s for s, _ in rows)
            _, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    if p.returncode != 0 or not lat:
        raise SystemExit(f"bench_plant.py: live run failed: {err.strip()}")
    a = np.array(lat)
    print(
        f"live 1 kHz, {machine:<8} {len(a)} samples: latency median {np.median(a) * 1e3:5.0f} ms, "
        f"p99 {np.percentile(a, 99) * 1e3:5.0f} ms, max {a.max() * 1e3:5.0f} ms; "
        f"{np.mean(a <= 0.5) * 100:.2f} % within 0.5 s"
    )


def produce(out, n: int) -> None:
    """n synthetic 1 kHz samples of a crank at 65 strokes/min, wrapped counts (4096/rev)."""
    out.write(b"time,crank_angle\n")
    w = 65 / 60 * 4096
    block = 100_000
    for lo in range(0, n, block):
        i = np.arange(lo, min(n, lo + block))
        t = i / 1000.0
        counts = np.floor(w * t) % 4096
        text = "\n".join(f"{a:.3f},{int(c)}" for a, c in zip(t, counts)) + "\n"
        out.write(text.encode())
    out.close()


def memory(n: int, d: pathlib.Path) -> None:
    db = d / "mem.sqlite"
    src = 'type = "csv"\npath = "/dev/stdin"\nangle_unit = "counts"\ncounts_per_rev = 4096\n'
    sink = f'[[sink]]\ntype = "sqlite"\npath = "{db}"\nsamples = "none"\n'
    cfg = config(d / "mem.toml", "mem", src, sink)
    p = run_twin(cfg, stdin=subprocess.PIPE)
    feeder = threading.Thread(target=produce, args=(p.stdin, n), daemon=True)
    t0 = time.perf_counter()
    feeder.start()
    points = []
    while p.poll() is None:
        time.sleep(0.5)
        try:
            rss = int(
                next(
                    x
                    for x in open(f"/proc/{p.pid}/status").read().splitlines()
                    if x.startswith("VmRSS")
                ).split()[1]
            )
            c = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1)
            done = (c.execute("SELECT samples FROM checkpoints").fetchone() or (0,))[0]
            c.close()
        except (OSError, StopIteration, sqlite3.Error):
            continue
        points.append((done, rss))
    err = p.stderr.read().decode()
    p.wait(timeout=60)
    w = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"bench_plant.py: memory run failed: {err.strip()}")
    after = [r for s, r in points if s >= 100_000]
    ref = after[0] if after else None
    top = max(after) if after else None
    print(
        f"memory: {n} samples in {w:.0f} s ({n / 1000 / w:.0f}x real time); VmRSS at 1e5 samples "
        f"{ref} kB, largest after {top} kB ({(top / ref - 1) * 100:+.1f} %); "
        f"{len(points)} readings"
    )
    marks = [(s, r) for s, r in points if s > 0]
    for k in np.unique(np.linspace(0, len(marks) - 1, 8).astype(int)):
        print(f"  {marks[k][0]:>9} samples: VmRSS {marks[k][1]} kB")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--live-seconds", type=float, default=12.0)
    ap.add_argument("--samples", type=int, default=10_000_000)
    ap.add_argument("--only", choices=("replay", "live", "memory"), default=None)
    a = ap.parse_args(argv)
    print(
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.uname().nodename}, "
        f"{os.cpu_count()} cores"
    )
    with tempfile.TemporaryDirectory(prefix="bench-plant-") as d:
        d = pathlib.Path(d)
        if a.only in (None, "replay"):
            replay(a.repeats, d)
        if a.only in (None, "live"):
            for machine in ("default", "kvo630"):
                live(a.live_seconds, machine, d)
        if a.only in (None, "memory"):
            memory(a.samples, d)
    return 0


if __name__ == "__main__":
    sys.exit(main())
