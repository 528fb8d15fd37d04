#!/usr/bin/env python3
"""Simulates the ReciprocatingDrive FMU with fmpy at constant crank speed and writes
results/<preset>.csv and results/<preset>.png (called by scripts/run.sh).

The master supplies the crank motion as input signals: crank.angle = ω t, crank.speed = ω,
crank.acceleration = 0 (physics.md §2), ω = the preset's crank.speed, else the FMU's start value
(65 strokes/min for the default machine).

Presets: "default" is the FMU's own start values (physics.md §8). Any other name NAME is the
parameter set resources/presets/NAME.ssv (SSP 1.0 System Structure Parameter Values: ssv:Parameter elements
with an ssv:Real, ssv:Integer or ssv:Boolean value).
"""

from __future__ import annotations

import argparse
import csv
import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "python"))
from reciprocating_drive.presets import PRESET_DIR, available_presets, preset_values  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUTPUTS = [
    ("suspension.position", "m"),
    ("suspension.velocity", "m/s"),
    ("suspension.acceleration", "m/s2"),
    ("kinematics.torque_factor", "m"),
    ("inertia.force", "N"),
    ("rod.force", "N"),
    ("crank.torque", "N.m"),
    ("rod.angle", "rad"),
    ("rod.angular_velocity", "rad/s"),
    ("guide.friction", "N"),
    ("link.friction_total", "N"),
]


def simulate(fmu: str, values: dict, duration: float, step: float):
    import numpy as np
    from fmpy import read_model_description, simulate_fmu

    md = read_model_description(fmu)
    by_name = {v.name: v for v in md.modelVariables}
    unknown = [n for n in values if n not in by_name]
    if unknown:
        raise ValueError(f"preset names variables the FMU does not have: {', '.join(unknown)}")
    values = dict(values)
    omega = float(values.pop("crank.speed", by_name["crank.speed"].start))
    theta0 = float(values.pop("crank.angle", 0.0))
    values.pop("crank.acceleration", None)
    f_ext = float(values.pop("link.external_force", 0.0))
    n = int(round(duration / step))
    t = np.array([k * step for k in range(n + 1)])
    sig = np.zeros(n + 1, dtype=[("time", np.float64), ("crank.angle", np.float64),
                                 ("crank.speed", np.float64), ("crank.acceleration", np.float64),
                                 ("link.external_force", np.float64)])
    sig["time"] = t
    sig["crank.angle"] = theta0 + omega * t
    sig["crank.speed"] = omega
    sig["link.external_force"] = f_ext
    res = simulate_fmu(fmu, start_time=0.0, stop_time=duration, output_interval=step,
                       start_values=values, input=sig, output=[n for n, _ in OUTPUTS])
    offset = float(values.get("crank.angle_offset", by_name["crank.angle_offset"].start))
    # The model angle θ = θ_in + offset (physics.md §2) at each recorded time.
    theta = theta0 + omega * res["time"] + offset
    return res, theta, omega


def write_csv(path: pathlib.Path, res, theta):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time [s]", "crank angle [rad]", "crank angle [deg]"]
                   + [f"{n} [{u}]" for n, u in OUTPUTS])
        for i, row in enumerate(res):
            w.writerow([repr(float(row["time"])), repr(float(theta[i])), repr(math.degrees(theta[i]))]
                       + [repr(float(row[n])) for n, _ in OUTPUTS])


def plot(path: pathlib.Path, res, theta, omega, title: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    deg = np.degrees(theta)
    panels = [
        ("suspension.position", 1.0, "position s [m]"),
        ("suspension.velocity", 1.0, "velocity v [m/s]"),
        ("suspension.acceleration", 1.0, "acceleration a [m/s²]"),
        ("inertia.force", 1e-3, "inertia force Φ = −m·a [kN]"),
    ]
    fig, axes = plt.subplots(4, 1, figsize=(10, 10), sharex=True)
    for ax, (name, k, label) in zip(axes, panels):
        ax.plot(deg, res[name] * k, lw=1.4)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.4)
        ax.axhline(0.0, color="k", lw=0.6)
    lo, hi = deg.min(), deg.max()
    ticks = np.arange(math.ceil(lo / 90) * 90, hi + 1e-9, 90)
    axes[-1].set_xticks(ticks)
    axes[-1].set_xticklabels([f"{x:g}" if x % 180 == 0 else "" for x in ticks])
    axes[-1].set_xlim(lo, hi)
    axes[-1].set_xlabel("crank angle θ [deg] (0 = outer dead centre for zero guide offset)")
    fig.suptitle(f"{title}: crank-slider at ω = {omega:.4g} rad/s "
                 f"({omega * 60 / (2 * math.pi):.4g} strokes/min)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("preset", nargs="?", default="default")
    ap.add_argument("--fmu", default=str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
    ap.add_argument("--resources", default=str(PRESET_DIR))
    ap.add_argument("--out-dir", default=str(ROOT / "results"))
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time [s] (default 3)")
    ap.add_argument("--step", type=float, default=1e-3, help="communication step [s] (default 1 ms)")
    a = ap.parse_args(argv)

    resources = pathlib.Path(a.resources)
    try:
        values = preset_values(a.preset, resources)
    except KeyError:
        print(f"simulate.py: unknown preset \"{a.preset}\"; available: "
              f"{', '.join(available_presets(resources))}", file=sys.stderr)
        return 2
    if not (a.duration > 0 and a.step > 0):
        print("simulate.py: --duration and --step must be positive", file=sys.stderr)
        return 2
    try:
        res, theta, omega = simulate(a.fmu, values, a.duration, a.step)
    except ValueError as e:
        print(f"simulate.py: {e}", file=sys.stderr)
        return 2
    out = pathlib.Path(a.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / f"{a.preset}.csv", res, theta)
    plot(out / f"{a.preset}.png", res, theta, omega, a.preset)
    print(f"wrote {out / (a.preset + '.csv')} ({len(res)} rows) and {out / (a.preset + '.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
