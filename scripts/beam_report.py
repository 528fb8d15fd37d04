#!/usr/bin/env python3
"""Extremes of the suspension-point acceleration of a beam-unit preset over one revolution,
evaluated through the FMU (fmpy's low-level API, direct feedthrough: set crank.angle, read
suspension.acceleration), refined by golden-section search to 1e-10 rad. Prints value and angle
both as API θ and as seed 001's φ1 = θ + 90° − atan2(H−G, I).

    .venv/bin/python scripts/beam_report.py [target/fmu/ReciprocatingDrive.fmu] [sk8-3.5-4000]
"""

from __future__ import annotations

import math
import pathlib
import shutil
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "python"))
from reciprocating_drive.presets import preset_values_from_fmu  # noqa: E402


def main(fmu="target/fmu/ReciprocatingDrive.fmu", preset="sk8-3.5-4000"):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    v = preset_values_from_fmu(fmu, preset)
    md = read_model_description(fmu)
    vr = {x.name: x.valueReference for x in md.modelVariables}
    d = extract(fmu)
    s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier)
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    for k, x in v.items():
        if isinstance(x, bool):
            s.setBoolean([vr[k]], [x])
        elif isinstance(x, int):
            s.setInteger([vr[k]], [x])
        else:
            s.setReal([vr[k]], [x])
    s.exitInitializationMode()
    a_vr, th_vr = vr["suspension.acceleration"], vr["crank.angle"]

    def acc(th):
        s.setReal([th_vr], [th])
        return s.getReal([a_vr])[0]

    n = 36000
    grid = [2 * math.pi * i / n for i in range(n)]
    vals = [acc(t) for t in grid]
    shift = math.pi / 2 - math.atan2(v["geometry.pivot_dy"], v["geometry.pivot_dx"])
    print(f"{preset}: omega = {v['crank.speed']:.9g} rad/s, rotation = {v['rotation']}")
    for sign, label in ((1, "maximum"), (-1, "minimum")):
        i = max(range(n), key=lambda k: sign * vals[k])
        lo, hi = grid[i] - 2 * math.pi / n, grid[i] + 2 * math.pi / n
        g = (math.sqrt(5) - 1) / 2
        while hi - lo > 1e-10:
            x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
            if sign * acc(x1) > sign * acc(x2):
                hi = x2
            else:
                lo = x1
        th = 0.5 * (lo + hi)
        print(
            f"  {label}: a = {acc(th):.7f} m/s2 at API theta = {math.degrees(th) % 360:.4f} deg, "
            f"phi1 = {math.degrees(th + shift) % 360:.4f} deg"
        )
    s.terminate()
    s.freeInstance()
    shutil.rmtree(d, ignore_errors=True)


if __name__ == "__main__":
    main(*sys.argv[1:])
