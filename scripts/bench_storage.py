#!/usr/bin/env python3
"""Benchmark of the plant database's storage (docs/plant.md "Storage"): bytes per sample and the
time to recompute an hour.

    .venv/bin/python scripts/bench_storage.py [--hours 1] [--machines default,kvo630]

1. Blocks: the shipped sample's input lines as the CSV source reads them and as the OPC UA source
   writes them (`repr` numbers), encoded in blocks of 2000 lines (a live source's checkpoint every
   2 s at 1 kHz) and 20 000 (a replay's): bytes per sample of the block alone.
2. A run: the shipped sample repeated to `--hours` of data at its ~1 kHz, replayed into SQLite
   with `keep_samples = 60` (the per-sample rows of the last minute held); the database's size
   over the samples, all inclusive, and without the rows of the window (what each further sample
   adds: input blocks, summaries, events, snapshots, checkpoint, indexes), per machine.
3. Recompute: the whole run's last hour recomputed from the database (`recompute_chunks`), wall
   and CPU time, against the rows it yields.
"""

from __future__ import annotations

import argparse
import pathlib
import sqlite3
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
SAMPLE = ROOT / "data" / "twin" / "pump_encoder.csv"
FMU = str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu")


def blocks() -> None:
    from reciprocating_drive.plant.samples import sample_lines
    from reciprocating_drive.plant.storage import encode_lines

    body = SAMPLE.read_text().splitlines()[1:]
    t = np.array([float(x.split(",")[0]) for x in body])
    a = np.array([float(x.split(",")[1]) for x in body])
    opc = sample_lines(t, a)
    # The demo's process force: a 7 Hz ripple of doubles, noise in every one of its 17 digits.
    force = sample_lines(t, a, None, 2000.0 + 10.0 * np.sin(2 * np.pi * 7.0 * t))
    for name, lines in (("CSV file", body), ("OPC UA (repr)", opc), ("OPC UA + force", force)):
        for n in (2000, 20000):
            size = cnt = 0
            for i in range(0, len(lines), n):
                part = lines[i : i + n]
                codec, data = encode_lines(part)
                size += len(data) + 64 + 40  # the checksum's hex and the row's other columns
                cnt += len(part)
            print(f"block  {name:14s} {n:6d} lines: {size / cnt:.2f} bytes a sample ({codec})")


def long_file(path: pathlib.Path, hours: float) -> tuple[int, float]:
    lines = SAMPLE.read_text().splitlines()
    head, body = lines[0], lines[1:]
    t = np.array([float(x.split(",")[0]) for x in body])
    rest = [x.split(",", 1)[1] for x in body]
    span = float(t[-1]) + 0.1
    repeats = int(np.ceil(hours * 3600 / span))
    with open(path, "w") as f:
        f.write(head + "\n")
        for k in range(repeats):
            f.write("".join(f"{v:.6f},{r}\n" for v, r in zip(t + k * span, rest)))
    return len(body) * repeats, repeats * span - 0.1


def run(d: pathlib.Path, data: pathlib.Path, machine: str) -> pathlib.Path:
    db = d / f"{machine}.sqlite"
    cfg = d / f"{machine}.toml"
    cfg.write_text(
        f'[run]\nid = "bench"\nmachine_id = "pump-1"\nmachine = "{machine}"\nfmu = "{FMU}"\n'
        f'[source]\ntype = "csv"\npath = "{data}"\nangle_unit = "counts"\ncounts_per_rev = 4096\n'
        f'[[sink]]\ntype = "sqlite"\npath = "{db}"\nkeep_samples = 60\n'
    )
    t0 = time.monotonic()
    p = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "twin_plant.py"), "--config", str(cfg)],
        capture_output=True,
        text=True,
    )
    if p.returncode != 0:
        raise SystemExit(p.stderr)
    print(f"run    {machine}: replayed in {time.monotonic() - t0:.1f} s")
    return db


def sizes(db: pathlib.Path, machine: str) -> None:
    c = sqlite3.connect(db)
    samples = c.execute("SELECT samples FROM checkpoints").fetchone()[0]
    size = db.stat().st_size
    parts = dict(c.execute("SELECT name, SUM(pgsize) FROM dbstat GROUP BY name").fetchall())
    rows = parts.get("samples", 0) + parts.get("samples_time", 0)
    held = c.execute("SELECT COUNT(*) FROM samples").fetchone()[0]
    free = (
        c.execute("PRAGMA freelist_count").fetchone()[0]
        * c.execute("PRAGMA page_size").fetchone()[0]
    )
    c.close()
    grow = size - rows - free
    print(
        f"size   {machine}: {size / 1e6:.1f} MB for {samples} samples: {size / samples:.2f} bytes "
        f"a sample all inclusive; {(size - rows) / samples:.2f} without the {held} rows of the "
        f"last 60 s ({rows / 1e6:.1f} MB); {grow / samples:.2f} without them and the "
        f"{free / 1e6:.1f} MB of free pages their deletion left for the next ones"
    )
    for name, b in sorted(parts.items(), key=lambda x: -x[1])[:8]:
        print(f"         {name:28s} {b / samples:6.2f} bytes a sample")


def recompute(db: pathlib.Path, machine: str, t_end: float, workers: int) -> None:
    import resource

    from reciprocating_drive.plant.query import recompute_chunks

    t0 = max(0.0, t_end - 3600.0)
    c0 = resource.getrusage(resource.RUSAGE_SELF)
    k0 = resource.getrusage(resource.RUSAGE_CHILDREN)  # the replay's process is one already
    w0 = time.monotonic()
    n = 0
    for seq, _rows in recompute_chunks(str(db), "bench", t0, t_end, fmu=FMU, workers=workers):
        n += len(seq)
    wall = time.monotonic() - w0
    c1 = resource.getrusage(resource.RUSAGE_SELF)
    k1 = resource.getrusage(resource.RUSAGE_CHILDREN)  # the workers, once ended
    cpu = c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime
    cpu += k1.ru_utime + k1.ru_stime - k0.ru_utime - k0.ru_stime
    print(
        f"query  {machine}: {n} samples ({t_end - t0:.0f} s of data) recomputed by {workers} "
        f"process(es) in {wall:.1f} s wall, {cpu:.1f} s CPU"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--machines", default="default,kvo630")
    ap.add_argument("--keep", action="store_true", help="keep the temporary folder")
    a = ap.parse_args()
    print(time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "|", " ".join(sys.argv))
    blocks()
    d = pathlib.Path(tempfile.mkdtemp(prefix="bench-storage-"))
    data = d / "long.csv"
    n, span = long_file(data, a.hours)
    print(f"data   {n} samples, {span:.0f} s ({n / span:.0f} samples a second)")
    for m in a.machines.split(","):
        db = run(d, data, m)
        sizes(db, m)
        for w in (1, 2):
            recompute(db, m, span, w)
    if a.keep:
        print("kept", d)
    else:
        import shutil

        shutil.rmtree(d)


if __name__ == "__main__":
    main()
