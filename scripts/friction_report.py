#!/usr/bin/env python3
"""Closing-note figures of the guide friction (docs/model.md §5) from the FMU itself.

For the default machine and for the unb600a preset: the extremes of `guide.friction` over one
revolution at 65 strokes/min (value and crank angle θ in degrees, θ = 0 at the outer dead centre),
and the friction work per revolution ∮ F_fr·v dt with F_fr = `link.friction_total`.

How: fmpy's low-level FMU2Slave; after initialization the crank inputs are set and the outputs
read without stepping (direct feedthrough, docs/model.md §2), so any θ can be evaluated.
* Extremes: a 0.1° scan, then golden-section search on the ±0.1° bracket around the best sample,
  to 1e-7° (guide.friction is unimodal there; it has kinks where an edge force changes sign,
  which golden section tolerates), then a check that no sample of a 0.01° grid over the bracket
  exceeds the result.
* Friction work: ∮ F_fr v dt = ∫₀^{2π} F_fr(θ)·v(θ)/ω dθ (constant speed), trapezoid on a
  0.01° grid (36000 points); the 0.1° grid's value is printed too, as a convergence check.

Usage: .venv/bin/python scripts/friction_report.py [FMU]   (default target/fmu/ReciprocatingDrive.fmu)
"""

from __future__ import annotations

import math
import pathlib
import shutil
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive.presets import preset_values  # noqa: E402

GOLDEN = (math.sqrt(5) - 1) / 2


class Evaluator:
    """One FMU instance initialized with a preset; `at(θ)` returns the requested outputs."""

    def __init__(
        self,
        fmu: str,
        preset: str,
        outputs=("guide.friction", "link.friction_total", "suspension.velocity"),
    ):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.md = read_model_description(fmu)
        self.dir = tempfile.mkdtemp(prefix="friction_report_")
        extract(fmu, unzipdir=self.dir)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        types = {v.name: v.type for v in self.md.modelVariables}
        values = preset_values(preset)
        start = {v.name: float(v.start) for v in self.md.modelVariables if v.name == "crank.speed"}
        self.omega = float(values.get("crank.speed", start["crank.speed"]))
        self.fmu = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self.dir,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=preset,
        )
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for name, value in values.items():
            if name == "crank.speed":
                continue
            if types[name] == "Integer":
                self.fmu.setInteger([self.vr[name]], [int(value)])
            elif types[name] == "Boolean":
                self.fmu.setBoolean([self.vr[name]], [bool(value)])
            else:
                self.fmu.setReal([self.vr[name]], [float(value)])
        self.fmu.setReal([self.vr["crank.speed"]], [self.omega])
        self.fmu.exitInitializationMode()
        self.inputs = [self.vr["crank.angle"], self.vr["crank.speed"]]
        self.outputs = list(outputs)
        self.out_vrs = [self.vr[n] for n in outputs]

    def at(self, theta: float) -> dict:
        self.fmu.setReal(self.inputs, [theta, self.omega])
        return dict(zip(self.outputs, self.fmu.getReal(self.out_vrs)))

    def value(self, name, theta):
        return self.at(theta)[name]

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


def golden_max(f, a, b, tol):
    """Maximum of f on [a, b] (unimodal) by golden-section search; returns (x, f(x))."""
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tol:
        if fc >= fd:
            b, d, fd = d, c, fc
            c = b - GOLDEN * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + GOLDEN * (b - a)
            fd = f(d)
    x = 0.5 * (a + b)
    return x, f(x)


def extreme(ev: Evaluator, name: str, sign: float, coarse_deg=0.1, tol_deg=1e-7):
    """(θ in degrees, value) of the maximum of sign·output over a revolution."""
    grid = np.arange(0.0, 360.0, coarse_deg)
    vals = np.array([sign * ev.value(name, math.radians(t)) for t in grid])
    k = int(np.argmax(vals))
    lo, hi = grid[k] - coarse_deg, grid[k] + coarse_deg
    x, fx = golden_max(lambda t: sign * ev.value(name, math.radians(t)), lo, hi, tol_deg)
    fine = np.linspace(lo, hi, int(round((hi - lo) / 0.01)) + 1)
    best_fine = max(sign * ev.value(name, math.radians(t)) for t in fine)
    assert fx >= best_fine - 1e-12 * abs(fx) and fx >= vals[k], (name, x, fx, best_fine)
    return x % 360.0, sign * fx


def friction_work(ev: Evaluator, step_deg: float, name="link.friction_total") -> float:
    """∮ F_fr v dt over one revolution at constant speed, trapezoid on a step_deg grid."""
    n = int(round(360.0 / step_deg))
    th = np.linspace(0.0, 2 * math.pi, n + 1)
    rows = [ev.at(t) for t in th]
    integrand = np.array([r[name] * r["suspension.velocity"] for r in rows]) / ev.omega
    return float(np.trapezoid(integrand, th))


def report(fmu: str, preset: str, fine_deg=0.01, coarse_deg=0.1) -> dict:
    ev = Evaluator(fmu, preset)
    try:
        t_max, f_max = extreme(ev, "guide.friction", +1.0)
        t_min, f_min = extreme(ev, "guide.friction", -1.0)
        return {
            "preset": preset,
            "omega": ev.omega,
            "max": (t_max, f_max),
            "min": (t_min, f_min),
            "work": friction_work(ev, fine_deg),
            "work_coarse": friction_work(ev, coarse_deg),
            "work_guide": friction_work(ev, fine_deg, "guide.friction"),
        }
    finally:
        ev.close()


def main(argv):
    fmu = argv[1] if len(argv) > 1 else str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu")
    for preset in ("default", "unb600a-simplex"):
        r = report(fmu, preset)
        print(f"{preset} (ω = {r['omega']:.7f} rad/s):")
        print(f"  guide.friction max {r['max'][1]:+.6f} N at θ = {r['max'][0]:.4f}°")
        print(f"  guide.friction min {r['min'][1]:+.6f} N at θ = {r['min'][0]:.4f}°")
        print(
            f"  friction work per revolution ∮ F_fr·v dt = {r['work']:.6f} J (0.01° grid; "
            f"0.1° grid: {r['work_coarse']:.6f} J; guide alone: {r['work_guide']:.6f} J)"
        )


if __name__ == "__main__":
    main(sys.argv)
