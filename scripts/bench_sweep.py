#!/usr/bin/env python3
"""Benchmark of the design sweeps (docs/sweeps.md "Speed"): study (b), kvo630's resonance curve,
on a LocalCluster with 1 and with 2 workers, in one run. Reports cases per second, the scaling,
and the share of the workers' time spent outside the FMU's calls (Dask scheduling, transfer,
result writing, summaries): 1 − Σ(time inside FMU calls) / (wall time × workers).

    .venv/bin/python scripts/bench_sweep.py [--repeat 2]
    .venv/bin/python scripts/bench_sweep.py --batching      # batches of ~1 s against ~4 per worker

--batching compares, on 2 workers, the default batching (about one second of work per batch, two
batches per worker in flight: what a kill loses) with a fixed size of about four batches per
worker (the baseline: fewest tasks).
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive.study import load_study  # noqa: E402
from reciprocating_drive.sweep import run_sweep  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--fmu", default=str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
    ap.add_argument("--study", default=str(ROOT / "studies" / "kvo630_resonance.toml"))
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--batching", action="store_true")
    a = ap.parse_args(argv)
    study = load_study(a.study)
    print(
        f"study {study.name}: {study.n_cases} cases, "
        f"{study.skip_revolutions + study.revolutions} revolutions × {study.steps_per_revolution} steps each"
    )
    if a.batching:
        return batching(study, a)
    rate = {}
    for workers in (1, 2):
        best = None
        for _ in range(a.repeat):
            with tempfile.TemporaryDirectory() as d:
                r = run_sweep(study, a.fmu, d, workers=workers, progress=False)
            if best is None or r.wall < best.wall:
                best = r
        rate[workers] = best.computed / best.wall
        outside = 1 - best.seconds_fmu / (best.wall * workers)
        print(
            f"{workers} worker(s): {rate[workers]:6.1f} cases/s  (wall {best.wall:.2f} s, "
            f"inside FMU calls {best.seconds_fmu:.2f} s, outside the FMU {100 * outside:.1f} %)"
        )
    print(f"scaling 1 → 2 workers: {rate[2] / rate[1]:.2f}×")
    return 0


def batching(study, a) -> int:
    import math

    fixed = math.ceil(study.n_cases / (4 * 2))
    for label, size in (("~1 s per batch (default)", None), (f"{fixed} cases per batch", fixed)):
        best = None
        for _ in range(a.repeat):
            with tempfile.TemporaryDirectory() as d:
                r = run_sweep(study, a.fmu, d, workers=2, progress=False, batch_size=size)
            if best is None or r.wall < best.wall:
                best = r
        print(
            f"2 workers, {label}: {best.computed / best.wall:6.1f} cases/s (wall {best.wall:.2f} s)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
