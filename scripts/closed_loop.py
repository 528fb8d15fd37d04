#!/usr/bin/env python3
"""The pump and its drive train in a closed loop (docs/closed-loop.md): builds
target/fmu/ClosedLoop.ssp from ssp/ClosedLoop/ and both FMUs, simulates it in libcosim (default)
or fmpy, prints the per-revolution speed fluctuation δ = (ω_max − ω_min)/ω_mean and writes
results/closed_loop.png (crank speed, motor torque and power, δ per revolution).

    .venv/bin/python scripts/closed_loop.py [--importer libcosim|fmpy] [--step 1e-3] [--time 10]
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive.system import build_ssp, run_fmpy, run_libcosim, speed_fluctuation  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--importer", choices=("libcosim", "fmpy"), default="libcosim")
    ap.add_argument("--step", type=float, default=1e-3)
    ap.add_argument("--time", type=float, default=10.0)
    ap.add_argument("--out-dir", type=pathlib.Path, default=ROOT / "results")
    ap.add_argument(
        "--fmu-dir",
        type=pathlib.Path,
        default=ROOT / "target" / "fmu",
        help="where ReciprocatingDrive.fmu and DriveTrain.fmu are",
    )
    a = ap.parse_args(argv)
    ssp = build_ssp(
        a.out_dir / "ClosedLoop.ssp"
        if a.fmu_dir != ROOT / "target" / "fmu"
        else ROOT / "target" / "fmu" / "ClosedLoop.ssp",
        fmu_dir=a.fmu_dir,
    )
    t0 = time.perf_counter()
    r = (run_libcosim if a.importer == "libcosim" else run_fmpy)(ssp, a.step, a.time)
    wall = time.perf_counter() - t0
    d = speed_fluctuation(r["time"], r["drivetrain.crank.angle"], r["drivetrain.crank.speed"])
    w = r["drivetrain.crank.speed"]
    print(f"{a.importer}: {a.time:g} s at h = {a.step:g} s in {wall:.2f} s wall; wrote {ssp}")
    print(
        f"crank speed at the end {w[-1]:.5g} rad/s ({w[-1] * 60 / (2 * math.pi):.4g} strokes/min)"
    )
    print("speed fluctuation δ per revolution: " + ", ".join(f"{x:.4%}" for x in d))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 1, figsize=(10, 10))
    t = r["time"]
    ax[0].plot(t, w * 60 / (2 * math.pi))
    ax[0].set_ylabel("crank speed\n[strokes/min]")
    ax[1].plot(t, r["drivetrain.motor.torque"], label="motor torque (motor shaft)")
    ax[1].set_ylabel("motor torque\n[N·m]")
    ax[2].plot(t, r["drivetrain.motor.power"] * 1e-3)
    ax[2].set_ylabel("motor power\n[kW]")
    for x in ax[:3]:
        x.set_xlabel("time [s]")
        x.grid(True, alpha=0.4)
    ax[3].plot(range(1, len(d) + 1), [100 * x for x in d], "o-")
    ax[3].set_xlabel("revolution")
    ax[3].set_ylabel("δ = (ω_max − ω_min)/ω_mean\n[%]")
    ax[3].grid(True, alpha=0.4)
    fig.suptitle(f"Pump and drive train in a closed loop ({a.importer}, h = {a.step * 1e3:g} ms)")
    fig.tight_layout()
    a.out_dir.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.out_dir / "closed_loop.png", dpi=90)
    print(f"wrote {a.out_dir / 'closed_loop.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
