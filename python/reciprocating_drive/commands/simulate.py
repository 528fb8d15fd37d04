#!/usr/bin/env python3
"""The main job's simulation (`rdrive run`; a checkout's main job builds the FMU, then runs it):
runs one machine at constant crank speed with fmpy and writes, in results/ (or --out-dir):

  <preset>.csv    time, the model angle (crank.model_angle, rad and deg) and the outputs
  <preset>.png    the mission plot (python/reciprocating_drive/plots.py)
  <preset>.json   the summary of a steady revolution (keys: docs/results.md)

and prints the summary. The work is done by python/reciprocating_drive/mission.py.

Presets: "default" is the FMU's own start values (docs/model.md §8); any other NAME is the
shipped parameter set NAME.ssv (resources/presets/ of a checkout, also inside the FMU), or a path
to an .ssv file.
"""

# Layer: commands (docs/architecture.md); a comment, as --help prints the docstring.

from __future__ import annotations

import argparse
import csv
import math
import pathlib
import sys

from .. import artifacts
from ..mission import OUTPUTS, PUMP_OUTPUTS, PUMP_UNITS, format_summary, run_mission, write_summary
from ..plots import plot_mission
from ..presets import PRESET_DIR, available_presets, preset_values
from . import prefix

UNITS = {
    "crank.model_speed": "rad/s",
    "suspension.position": "m",
    "suspension.velocity": "m/s",
    "suspension.acceleration": "m/s2",
    "kinematics.torque_factor": "m",
    "inertia.force": "N",
    "guide.friction": "N",
    "link.friction_total": "N",
    "rod.force": "N",
    "crank.torque": "N.m",
    "rod.angle": "rad",
    "rod.angular_velocity": "rad/s",
    "rod.stress_max": "Pa",
}
CSV_OUTPUTS = [(n, UNITS[n]) for n in OUTPUTS if n != "crank.model_angle"]


def write_csv(path: pathlib.Path, data: dict) -> None:
    # A pump preset's run adds its flow, powers and per-cylinder torques.
    columns = CSV_OUTPUTS + [(n, PUMP_UNITS[n]) for n in PUMP_OUTPUTS if n in data]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            ["time [s]", "crank angle [rad]", "crank angle [deg]"]
            + [f"{n} [{u}]" for n, u in columns]
        )
        for i in range(len(data["time"])):
            th = float(data["crank.model_angle"][i])
            w.writerow(
                [repr(float(data["time"][i])), repr(th), repr(math.degrees(th))]
                + [repr(float(data[n][i])) for n, _ in columns]
            )


def main(argv=None, prog: str | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("preset", nargs="?", default="default")
    ap.add_argument("--fmu", default=str(artifacts.fmu()))
    ap.add_argument("--resources", default=str(PRESET_DIR), help="folder of the .ssv presets")
    ap.add_argument("--out-dir", default=str(artifacts.results_dir()))
    ap.add_argument(
        "--revolutions",
        type=int,
        default=None,
        help="revolutions to simulate (default 2, 30 for an elastic rod)",
    )
    ap.add_argument(
        "--step", type=float, default=None, help="communication step [s] (default 1/900 revolution)"
    )
    a = ap.parse_args(argv)

    resources = pathlib.Path(a.resources)
    try:
        preset_values(a.preset, resources)
    except KeyError:
        print(
            f'simulate.py: unknown preset "{a.preset}"; available: '
            f"{', '.join(available_presets(resources))}",
            file=sys.stderr,
        )
        return 2
    if (a.step is not None and not a.step > 0) or (a.revolutions is not None and a.revolutions < 1):
        print(
            f"{prefix('simulate.py')}: --step must be positive and --revolutions at least 1",
            file=sys.stderr,
        )
        return 2
    try:
        m = run_mission(
            a.fmu, a.preset, step=a.step, revolutions=a.revolutions, preset_dir=resources
        )
    except Exception as e:  # an FMU error or an invalid preset: a message, not a traceback
        print(f"{prefix('simulate.py')}: {e}", file=sys.stderr)
        return 2
    out = pathlib.Path(a.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = pathlib.Path(a.preset).stem if a.preset.endswith(".ssv") else a.preset
    write_csv(out / f"{stem}.csv", m.data)
    plot_mission(m, out / f"{stem}.png")
    write_summary(m, out / f"{stem}.json")
    print(format_summary(m.summary))
    print(f"wrote {out / stem}.csv, .png and .json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
