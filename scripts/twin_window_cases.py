#!/usr/bin/env python3
"""The smoothing window's dependence on where a record starts (docs/twin.md "Conditioning"),
against the closed-form crank state of python/reciprocating_drive/twin/sample.py: a 2 kHz
encoder of 14 bits read in rad (wrapped), timestamps with ±80 µs uniform jitter, a 40 ms dropout
at 3 s, no speed channel, `--window 0.05`, run by the twin (`Twin.feed`) in one process:

* the whole record;
* the same record whose first interval is 40 ms (the samples of the first 40 ms but the first
  left out: a dropout below the gap limit at the very start);
* the same record started 0.637 s later (a live run that subscribes then).

For each, the largest error of `suspension.acceleration` over its peak beyond the run's first
window (half a window and the gap limit), and for the later start the difference of the speed
(`crank.model_speed`) from the whole record's at the same samples beyond its first window.

    .venv/bin/python scripts/twin_window_cases.py [--fmu target/fmu/ReciprocatingDrive.fmu]
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive.fmu import Fmu  # noqa: E402
from reciprocating_drive.twin import Options, Twin  # noqa: E402
from reciprocating_drive.twin.sample import crank_slider_acceleration, truth  # noqa: E402

WINDOW = 0.05


def record(duration=6.0, rate=2000.0, bits=14, jitter=80e-6, dropout=(3.0, 0.04), seed=39):
    """(time, wrapped angle in rad) of the encoder described above."""
    rng = np.random.default_rng(seed)
    k = np.arange(int(duration * rate) + 1)
    t = k / rate + rng.uniform(-jitter, jitter, len(k))
    t[0] = 0.0
    t = np.round(t, 7)
    t = t[(t <= dropout[0]) | (t >= dropout[0] + dropout[1])]
    counts = 2**bits
    theta, _, _ = truth(t)
    c = np.floor(theta / (2 * math.pi) * counts) % counts
    return t, c * (2 * math.pi / counts)


def run(fmu, t, angle, window=WINDOW, **options):
    """The twin's rows (time, outputs) for these samples, and its output names."""
    tw = Twin(fmu, "default", Options(window=window, **options))
    lines = ["time,crank_angle"] + [f"{a!r},{b!r}" for a, b in zip(t.tolist(), angle.tolist())]
    rows, _ = tw.feed(lines, 1)
    tail, _ = tw.finish()
    return np.concatenate([rows, tail]), tw.outputs, tw.messages


def acceleration_error(rows, names, window=WINDOW, gap_limit=0.05):
    """The largest |error| of suspension.acceleration over its peak, beyond the first window
    (the samples whose window cannot reach the first sample: half a window and the gap limit,
    docs/twin.md "Conditioning")."""
    t = rows[:, 0]
    acc = rows[:, 1 + names.index("suspension.acceleration")]
    th, w, e = truth(t)
    exact = crank_slider_acceleration(th, w, e)
    beyond = t >= t[0] + 0.5 * window + gap_limit
    return float(np.max(np.abs(acc - exact)[beyond]) / np.max(np.abs(exact)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmu", default=str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
    a = ap.parse_args()
    fmu = Fmu(a.fmu)
    t, angle = record()
    full, names, _ = run(fmu, t, angle)
    print(f"whole record ({len(t)} samples): error {acceleration_error(full, names):.3g} of peak")
    keep = np.ones(len(t), dtype=bool)
    keep[1 : int(np.searchsorted(t, 0.04))] = False
    late, _, _ = run(fmu, t[keep], angle[keep])
    print(
        f"first interval {t[keep][1] - t[0]:.3g} s: error {acceleration_error(late, names):.3g} "
        "of peak"
    )
    s = int(np.searchsorted(t, 0.637))
    part, _, _ = run(fmu, t[s:], angle[s:])
    print(f"started at t = {t[s]:.4g} s: error {acceleration_error(part, names):.3g} of peak")
    i_w = 1 + names.index("crank.model_speed")
    beyond = part[:, 0] >= part[0, 0] + 0.5 * WINDOW + 0.05
    d = np.abs(part[beyond, i_w] - full[s:][beyond, i_w])
    print(
        f"  its speed against the whole record's beyond its first window: median "
        f"{np.median(d):.3g} rad/s, largest {d.max():.3g} rad/s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
