#!/usr/bin/env python3
"""Work-precision diagram of the elastic rod's cage integrator (docs/performance.md "The elastic
rod"): runs the study `model::drive::cage_step::work_precision` (cargo test, release build,
ignored by default), which writes target/work_precision.csv, keeps that table as
docs/figures/work_precision.csv (scripts/make_docs.py redraws the figure from it) and draws
docs/figures/work_precision.png: for the kvo630 spring and the thin rod (rows) and communication
steps of 0.1, 1 and 10 ms (columns), the largest error of ϑ and of ϑ̇ against the reference, each
relative to its own amplitude, over the right-hand-side evaluations per simulated second (top two
blocks: ϑ, then ϑ̇) and the error of ϑ̇ over the wall time per simulated second (bottom block), one
line per method through tolerances 1e-6 … 1e-10.

    python3 scripts/work_precision.py [--no-run] [--out PNG]

With --no-run the kept table is drawn.
"""

from __future__ import annotations

import argparse
import csv
import pathlib
import shutil
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
CSV = ROOT / "target" / "work_precision.csv"
TABLE = ROOT / "docs" / "figures" / "work_precision.csv"
OUT = ROOT / "docs" / "figures" / "work_precision.png"

LABELS = {
    "Verner65": "Verner 6(5) (the FMU's)",
    "LawsonVerner65": "Lawson–Verner 6(5)",
    "Tsit5": "Tsitouras 5(4)",
    "LawsonTsit5": "Lawson–Tsitouras 5(4)",
    "LawsonDp5": "Lawson–Dormand–Prince 5(4)",
}
STYLE = {
    "Verner65": ("k", "o", "-"),
    "LawsonVerner65": ("tab:red", "s", "-"),
    "Tsit5": ("tab:gray", "^", "--"),
    "LawsonTsit5": ("tab:blue", "^", "-"),
    "LawsonDp5": ("tab:green", "v", "-"),
}


def run_study() -> None:
    cmd = ["cargo", "test", "--release", "--lib", "work_precision", "--", "--ignored"]
    result = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if result.returncode != 0:
        tail = (result.stdout + result.stderr).strip().splitlines()[-1:]
        sys.exit(f"work_precision.py: {' '.join(cmd)} failed: {' '.join(tail)}")


def read(path: pathlib.Path) -> list[dict]:
    try:
        with path.open(newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"work_precision.py: cannot read {path}: {e.strerror}")
    for r in rows:
        for k in ("step_ms", "tol", "error", "error_rate", "evals_per_s", "ns_per_s"):
            r[k] = float(r[k])
    return rows


def draw(rows: list[dict], out: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

    rods = list(dict.fromkeys(r["rod"] for r in rows))
    steps = sorted({r["step_ms"] for r in rows})
    methods = list(dict.fromkeys(r["method"] for r in rows))
    blocks = [
        ("evals_per_s", "RHS evaluations per simulated s", "error", "ϑ"),
        ("evals_per_s", "RHS evaluations per simulated s", "error_rate", "ϑ̇"),
        ("ns_per_s", "ms per simulated s", "error_rate", "ϑ̇"),
    ]
    fig, axes = plt.subplots(
        len(blocks) * len(rods),
        len(steps),
        figsize=(4.2 * len(steps), 3.2 * len(blocks) * len(rods)),
        squeeze=False,
    )
    for b, (key, xlabel, err_key, var) in enumerate(blocks):
        for i, rod in enumerate(rods):
            for j, step in enumerate(steps):
                ax = axes[b * len(rods) + i][j]
                for m in methods:
                    pts = sorted(
                        (
                            r
                            for r in rows
                            if (r["rod"], r["step_ms"], r["method"]) == (rod, step, m)
                        ),
                        key=lambda r: -r["tol"],
                    )
                    scale = 1e-6 if key == "ns_per_s" else 1.0
                    color, marker, line = STYLE.get(m, (None, "x", ":"))
                    ax.loglog(
                        [p[key] * scale for p in pts],
                        [p[err_key] for p in pts],
                        color=color,
                        marker=marker,
                        linestyle=line,
                        markersize=4,
                        label=LABELS.get(m, m),
                    )
                ax.set_title(f"{rod}, h = {step:g} ms", fontsize=9)
                ax.set_xlabel(xlabel, fontsize=8)
                ax.set_ylabel(f"largest error of {var} / amplitude", fontsize=8)
                ax.grid(True, which="both", alpha=0.3)
                ax.tick_params(labelsize=7)
                # Labels at 1, 2, 3, 5, 7 of each decade (x) and 1, 2, 5 (y): a panel spans less
                # than a decade at 0.1 ms, and all minor labels of a log axis overlap.
                ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 3.0, 5.0, 7.0)))
                ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
                ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
                ax.xaxis.set_minor_formatter(NullFormatter())
                ax.yaxis.set_minor_formatter(NullFormatter())
    axes[0][0].legend(fontsize=7)
    fig.suptitle(
        "Cage integrator: error against work, tolerances 1e-6 (left of each line) to 1e-10",
        fontsize=10,
    )
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-run", action="store_true", help="draw the kept table")
    ap.add_argument("--out", type=pathlib.Path, default=OUT)
    args = ap.parse_args()
    if not args.no_run:
        run_study()
        shutil.copyfile(CSV, TABLE)
    draw(read(TABLE), args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
