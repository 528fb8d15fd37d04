#!/usr/bin/env python3
"""Speed of the closed loop (docs/closed-loop.md "Speed"): one simulated minute at h = 1 ms of the
shipped SSP system in libcosim (simulate_until only, and loading the system separately), the same
in fmpy's SSP simulation for comparison, and the two FMUs' own work per step measured through
fmpy's low-level calls with time.perf_counter around the fmi2DoStep calls alone. Best of --repeat.

    .venv/bin/python scripts/bench_closed_loop.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import ctypes
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
from reciprocating_drive import Fmu  # noqa: E402
from reciprocating_drive.closed_loop.system import build_ssp, run_fmpy, run_libcosim  # noqa: E402

H, T = 1e-3, 60.0


def fmu_step_cost(n: int) -> float:
    """Seconds of fmi2DoStep of both FMUs per communication step (inputs wired by hand)."""
    pump = Fmu(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu")
    drive = Fmu(ROOT / "target" / "fmu" / "DriveTrain.fmu")
    pump.start({"load.profile": 1, "load.mean": 10000.0})
    drive.start()
    pc = pump.channel(["crank.angle", "crank.speed", "crank.acceleration"], ["crank.torque"])
    dc = drive.channel(["load.torque"], ["crank.angle", "crank.speed", "crank.acceleration"])
    import numpy as np

    pout, dout = np.zeros(1), np.zeros(3)
    do_p, do_d = pump._raw["fmi2DoStep"], drive._raw["fmi2DoStep"]
    inside = 0.0
    for k in range(n):
        dc.read(dout)
        pc.set_inputs(dout)
        pc.read(pout)
        dc.set_inputs(pout)
        t = ctypes.c_double(k * H)
        t0 = time.perf_counter()
        do_p(pump._component, t, ctypes.c_double(H), 1)
        do_d(drive._component, t, ctypes.c_double(H), 1)
        inside += time.perf_counter() - t0
        pump.time = drive.time = (k + 1) * H
    pump.close()
    drive.close()
    return inside / n


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    ssp = build_ssp(ROOT / "target" / "fmu" / "ClosedLoop.ssp")
    best = None
    for _ in range(a.repeat):
        tm = {}
        run_libcosim(ssp, H, T, timing=tm)
        best = tm if best is None or tm["simulate"] < best["simulate"] else best
    t0 = time.perf_counter()
    run_fmpy(ssp, H, T)
    fmpy_s = time.perf_counter() - t0
    per_step = min(fmu_step_cost(20000) for _ in range(a.repeat))
    n = int(T / H)
    print(f"one simulated minute, h = 1 ms ({n} steps), best of {a.repeat}:")
    print(
        f"  libcosim simulate_until   {best['simulate']:.3f} s  ({best['simulate'] / n * 1e6:.1f} µs per step; "
        f"loading the SSP {best['load']:.3f} s)"
    )
    print(f"  fmpy simulate_ssp         {fmpy_s:.3f} s")
    print(f"  both FMUs' fmi2DoStep     {per_step * n:.3f} s  ({per_step * 1e6:.2f} µs per step)")
    print(
        f"  libcosim's share beyond the FMUs' steps: {100 * (1 - per_step * n / best['simulate']):.0f} %"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
