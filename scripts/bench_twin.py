#!/usr/bin/env python3
"""Speed of the digital twin (docs/twin.md "Speed"): replay and live mode on 1 kHz data of the
default machine (the shipped encoder sample) and of kvo630 (generated here: 1500 strokes/min,
exact angles), as real-time factors (seconds of data per second of wall time, after start-up),
with the cost of the FMU calls alone measured in the same run as the baseline.

    .venv/bin/python scripts/bench_twin.py
"""

from __future__ import annotations

import math
import pathlib
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive.fmu import Fmu  # noqa: E402
from reciprocating_drive.twin import Options, Twin  # noqa: E402

FMU = str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu")


def kvo_data(path: pathlib.Path, seconds=3.0):
    w = 2 * math.pi * 1500 / 60
    t = np.arange(int(seconds * 1000) + 1) / 1000.0
    path.write_text("time,crank_angle\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, np.mod(w * t, 2 * math.pi))))
    return t[-1]


def run(path, machine, opts, live):
    lines = path.read_text().splitlines(keepends=True)
    twin = Twin(FMU, machine, opts, batch=1 if live else 4096)
    t0 = time.perf_counter()
    n = 0
    for i, line in enumerate(lines, 1):
        rows, _ = twin.push(line, i)
        n += len(rows)
    n += len(twin.finish()[0])
    return time.perf_counter() - t0, n


def fmu_only(machine_values, n, h=1e-3):
    f = Fmu(FMU)
    f.start(machine_values)
    ch = f.channel(["crank.angle", "crank.speed", "crank.acceleration", "link.external_force"], f.outputs)
    out = np.empty(len(f.outputs))
    t0 = time.perf_counter()
    for k in range(1, n + 1):
        ch.advance(k * h)
        ch.set_inputs([0.001 * k, 6.8, 0.0, 0.0])
        ch.read(out)
    return time.perf_counter() - t0


def main() -> int:
    from reciprocating_drive.presets import preset_values

    with tempfile.TemporaryDirectory() as d:
        kvo = pathlib.Path(d) / "kvo.csv"
        kvo_seconds = kvo_data(kvo)
        cases = [("default machine, encoder sample", ROOT / "data" / "twin" / "pump_encoder.csv", "default",
                  Options(angle_unit="counts", counts_per_rev=4096), 12.0, {}),
                 ("kvo630, exact angles", kvo, "kvo630", Options(window=0.006, max_speed=400.0), kvo_seconds,
                  {k: v for k, v in preset_values("kvo630").items() if k != "crank.speed"})]
        for name, path, machine, opts, seconds, values in cases:
            for live in (False, True):
                wall, n = run(path, machine, opts, live)
                print(f"{name:34s} {'live  ' if live else 'replay'}: {n} samples in {wall:.3f} s = "
                      f"{seconds / wall:6.1f}× real time ({wall / n * 1e6:.1f} µs per sample)")
            base = fmu_only(values, n)
            print(f"{name:34s} FMU calls alone: {base / n * 1e6:.1f} µs per sample = {seconds / base:.1f}× real time")
    return 0


if __name__ == "__main__":
    sys.exit(main())
