#!/usr/bin/env python3
"""Runs a design study (a TOML study file, docs/sweeps.md) on Dask and writes
<out>/<study>.parquet, <out>/<study>.csv and <out>/<study>.png.

    .venv/bin/python scripts/sweep.py studies/kvo630_resonance.toml
    .venv/bin/python scripts/sweep.py STUDY --workers 2               # LocalCluster with 2 workers
    .venv/bin/python scripts/sweep.py STUDY --scheduler tcp://host:8786  # an existing cluster

A killed sweep resumes: run the same command again and only the missing cases are computed.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive.study import StudyError, load_study  # noqa: E402
from reciprocating_drive.sweep import load_rows, run_sweep  # noqa: E402
from reciprocating_drive.sweep_plot import plot_sweep  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("study", type=pathlib.Path)
    ap.add_argument("--fmu", default=str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
    ap.add_argument("--out-dir", type=pathlib.Path, default=ROOT / "results" / "sweeps")
    ap.add_argument(
        "--scheduler",
        default=None,
        help="address of a running Dask scheduler (default: a LocalCluster)",
    )
    ap.add_argument(
        "--workers", type=int, default=None, help="LocalCluster workers (default: one per core)"
    )
    ap.add_argument(
        "--batch-size",
        type=int,
        default=None,
        help="cases per Dask task (default: ~4 tasks per worker)",
    )
    ap.add_argument(
        "--max-cases", type=int, default=None, help="compute at most this many new cases, then stop"
    )
    ap.add_argument("--no-progress", action="store_true")
    a = ap.parse_args(argv)
    try:
        study = load_study(a.study)
    except (OSError, StudyError) as e:
        print(f"sweep.py: {e}", file=sys.stderr)
        return 2
    if not pathlib.Path(a.fmu).is_file():
        print(f"sweep.py: {a.fmu} not found: build it with scripts/build-fmu.sh", file=sys.stderr)
        return 2
    r = run_sweep(
        study,
        a.fmu,
        a.out_dir,
        scheduler=a.scheduler,
        workers=a.workers,
        batch_size=a.batch_size,
        progress=not a.no_progress,
        max_cases=a.max_cases,
    )
    rows = load_rows(r.csv, study)
    png = a.out_dir / f"{study.name}.png"
    plot_sweep(study, rows, png)
    n_err = sum(1 for x in rows if x["status"] != "ok")
    print(
        f"{study.name}: {r.computed} cases computed, {r.skipped} found in {r.csv}, {n_err} rejected; "
        f"{r.computed / r.wall if r.wall > 0 and r.computed else 0:.1f} cases/s on {r.workers} worker(s)"
    )
    print(f"wrote {r.parquet}, {r.csv} and {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
