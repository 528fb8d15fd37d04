#!/usr/bin/env python3
"""Key numbers of the elastic connecting rod (docs/model.md §6) for the kvo630 preset, for the
closing note of issue 5:

* the steady-state cage amplitude max|ϑ| over the last revolution of 1 s (transient decayed:
  1/(ζΩ0) ≈ 13 ms) and the largest coil stress max rod.stress_max, from the FMU and from the
  independent reference (tests/python/rod_reference.py at rtol 1e-13);
* the wall time scipy's DOP853 needs, on the reference's right-hand side (Python, P by brentq at
  every evaluation), to reach max|Δϑ| ≤ 1e-7 rad at the 1 ms communication points over 1 s
  (the loosest tolerance of a scan that does, with the FMU's error scaling: rtol = atol on ϑ =
  tol, atol on ϑ̇ = tol·Ω0), against the FMU's wall time for 1 s at h = 1 ms through fmpy's
  low-level API (set crank inputs, fmi2DoStep, get rod.angle each step; best of 5).

Timings are reported, never asserted. Usage (after scripts/build-fmu.sh, in the project venv):

    .venv/bin/python scripts/rod_report.py [FMU]
"""

from __future__ import annotations

import math
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
sys.path.insert(0, str(ROOT / "tests" / "python"))
from reciprocating_drive.presets import preset_values  # noqa: E402
from rod_reference import Drive, Motion  # noqa: E402

T_END, H, TARGET = 1.0, 1e-3, 1e-7


def fmu_run(fmu_file: str, values: dict, w: float, outputs: list[str]):
    """Runs the FMU over [0, T_END] with h = H; returns (wall time of the stepping loop, rows)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(fmu_file)
    unzipdir = extract(fmu_file)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    types = {v.name: v.type for v in md.modelVariables}
    fmu = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzipdir,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="rod report",
    )
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    for name, value in values.items():
        if types[name] == "Real":
            fmu.setReal([vr[name]], [float(value)])
        elif types[name] == "Integer":
            fmu.setInteger([vr[name]], [int(value)])
        else:
            fmu.setBoolean([vr[name]], [bool(value)])
    ins = [vr["crank.angle"], vr["crank.speed"]]
    outs = [vr[o] for o in outputs]
    fmu.setReal(ins, [0.0, w])
    fmu.exitInitializationMode()
    n = int(round(T_END / H))
    rows = [fmu.getReal(outs)]
    t0 = time.perf_counter()
    for k in range(n):
        t = k * H
        fmu.setReal(ins, [w * t, w])
        fmu.doStep(t, H)
        rows.append(fmu.getReal(outs))
    wall = time.perf_counter() - t0
    fmu.terminate()
    fmu.freeInstance()
    return wall, np.array(rows)


def main() -> None:
    fmu_file = (
        sys.argv[1]
        if len(sys.argv) > 1
        else str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu")
    )
    values = preset_values("kvo630")
    w = values["crank.speed"]
    drive, motion = Drive(values), Motion(w)
    times = np.arange(int(round(T_END / H)) + 1) * H

    t0 = time.perf_counter()
    truth = drive.integrate(motion, times, rtol=1e-13, atol_theta=1e-16)
    t_truth = time.perf_counter() - t0
    ref = drive.outputs_along(motion, times, truth.y)

    runs = [fmu_run(fmu_file, values, w, ["rod.angle", "rod.stress_max"]) for _ in range(5)]
    t_fmu = min(r[0] for r in runs)
    rows = runs[0][1]
    fmu_err = np.abs(rows[:, 0] - truth.y[0]).max()

    last = times >= T_END - 2 * math.pi / w
    amp, amp_ref = np.abs(rows[last, 0]).max(), np.abs(ref["rod.angle"][last]).max()
    tau, tau_ref = rows[:, 1].max(), ref["rod.stress_max"].max()

    found = None
    scan = []
    for tol in (1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9, 1e-10):
        t0 = time.perf_counter()
        sol = drive.integrate(motion, times, rtol=tol, atol_theta=tol)
        wall = time.perf_counter() - t0
        err = np.abs(sol.y[0] - truth.y[0]).max()
        scan.append((tol, err, wall, sol.nfev))
        if err <= TARGET:
            found = scan[-1]
            break

    print(f"kvo630 (docs/model.md §8), 1 s at 1500 rpm, communication step {H * 1e3:g} ms")
    print(
        f"  rod: Ω0 = {drive.omega0:.1f} rad/s (P = 0), damping time 1/(ζΩ0) = {2 * drive.J / drive.B * 1e3:.2f} ms"
    )
    print(
        f"  steady-state cage amplitude max|ϑ| (last revolution): FMU {amp:.9f} rad, reference {amp_ref:.9f} rad"
    )
    print(
        f"  largest coil stress max rod.stress_max: FMU {tau / 1e6:.4f} MPa, reference {tau_ref / 1e6:.4f} MPa"
    )
    print(
        f"  FMU (solver.tolerance 1e-8): max |ϑ - reference| = {fmu_err:.2e} rad; "
        f"wall time for 1 s through fmpy's low-level API = {t_fmu * 1e3:.1f} ms (best of 5, "
        f"{int(round(T_END / H))} x setReal + doStep + getReal)"
    )
    print(f"  reference truth: DOP853 rtol 1e-13, {truth.nfev} RHS evaluations, {t_truth:.2f} s")
    print("  scipy DOP853 on the same problem (rtol = atol = tol, atol on ϑ̇ = tol·Ω0):")
    for tol, err, wall, nfev in scan:
        print(
            f"    tol {tol:7.0e}: max |Δϑ| = {err:.2e} rad, {nfev:6d} RHS evaluations, {wall:.3f} s"
        )
    if found:
        print(
            f"  => DOP853 needs {found[2]:.3f} s (tol {found[0]:.0e}) for {TARGET:g} rad over 1 s; "
            f"the FMU {t_fmu:.4f} s: ratio {found[2] / t_fmu:.0f}x"
        )
    else:
        print("  => no tolerance of the scan reached the target")


if __name__ == "__main__":
    main()
