#!/usr/bin/env python3
"""CPU per sample of the OPC UA source's hand-off to the twin (docs/twin.md "Speed"): the same
samples, in the same chunks, through the two ways a source of numbers can reach the twin's core,
measured in one run:

* text: each sample written as a CSV line with `repr` (`plant.samples.sample_lines`) and read back
  by the twin's CSV reader (`Twin.feed`), the OPC UA source's way before the core took numbers;
* numbers: the arrays handed over as they are (`Twin.feed_samples`), its way now.

Both twins get 1 kHz samples of the default machine's crank with the measured speed (the shipped
sample's truth, twin/sample.py), 20 s in chunks of 50 samples (what a 1 kHz PLC gives every
50 ms); every output row of the two is compared bit for bit. Reported: process CPU time per
sample of the whole hand-off (formatting, parsing, conditioning, the FMU), and of the
conversion alone (the lines written and parsed, against the arrays made), the best of --repeat
runs, and their ratios.

    .venv/bin/python scripts/bench_samples.py [--repeat 5] [--seconds 20]
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive.fmu import Fmu  # noqa: E402
from reciprocating_drive.plant.samples import sample_header, sample_lines  # noqa: E402
from reciprocating_drive.twin import Twin  # noqa: E402
from reciprocating_drive.twin.line_input import parse_header, parse_lines  # noqa: E402
from reciprocating_drive.twin.sample import truth  # noqa: E402
from reciprocating_drive.twin.samples import Samples  # noqa: E402

FMU = str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu")
CHUNK = 50


def chunks(seconds: float):
    t = np.arange(int(seconds * 1000) + 1) / 1000.0
    theta, omega, _ = truth(t)
    a = np.mod(theta, 2 * np.pi)
    # As the OPC UA source holds them: Python floats in lists, a chunk at a time.
    return [
        (t[i : i + CHUNK].tolist(), a[i : i + CHUNK].tolist(), omega[i : i + CHUNK].tolist())
        for i in range(0, len(t), CHUNK)
    ]


def run_text(fmu, data) -> tuple[float, np.ndarray]:
    twin, out = Twin(fmu), []
    c0 = time.process_time()
    lineno = 0
    for k, (t, a, w) in enumerate(data):
        lines = sample_lines(t, a, w, None)
        if k == 0:
            lines = [sample_header(True, False), *lines]
        rows, _ = twin.feed(lines, lineno + 1)
        lineno += len(lines)
        out.append(rows)
    out.append(twin.finish()[0])
    return time.process_time() - c0, np.concatenate(out)


def run_numbers(fmu, data) -> tuple[float, np.ndarray]:
    twin, out = Twin(fmu), []
    c0 = time.process_time()
    for t, a, w in data:
        rows, _ = twin.feed_samples(
            Samples.of(time=t, crank_angle=a, crank_speed=w), twin.lines_read + 1
        )
        out.append(rows)
    out.append(twin.finish()[0])
    return time.process_time() - c0, np.concatenate(out)


def convert_text(data) -> float:
    cols = parse_header(sample_header(True, False))
    c0 = time.process_time()
    for t, a, w in data:
        parse_lines(sample_lines(t, a, w, None), 2, cols)
    return time.process_time() - c0


def convert_numbers(data) -> float:
    c0 = time.process_time()
    for t, a, w in data:
        Samples.of(time=t, crank_angle=a, crank_speed=w)
    return time.process_time() - c0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=20.0)
    a = ap.parse_args()
    fmu = Fmu(FMU)
    data = chunks(a.seconds)
    n = sum(len(c[0]) for c in data)
    best = {"text": np.inf, "numbers": np.inf, "convert text": np.inf, "convert numbers": np.inf}
    for _ in range(a.repeat):
        s_text, r_text = run_text(fmu, data)
        s_num, r_num = run_numbers(fmu, data)
        if r_text.shape != r_num.shape or r_text.tobytes() != r_num.tobytes():
            raise SystemExit("bench_samples.py: the two paths' rows differ")
        best["text"] = min(best["text"], s_text)
        best["numbers"] = min(best["numbers"], s_num)
        best["convert text"] = min(best["convert text"], convert_text(data))
        best["convert numbers"] = min(best["convert numbers"], convert_numbers(data))
    print(f"{n} samples in chunks of {CHUNK}, the best of {a.repeat} runs (process CPU time):")
    for k, v in best.items():
        print(f"  {k:16s} {v / n * 1e6:8.3f} µs per sample")
    print(f"  whole hand-off: numbers / text = {best['numbers'] / best['text']:.3f}")
    print(
        f"  conversion:     numbers / text = {best['convert numbers'] / best['convert text']:.3f}"
    )
    print("  rows of the two paths identical bit for bit")
    return 0


if __name__ == "__main__":
    sys.exit(main())
