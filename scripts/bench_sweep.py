#!/usr/bin/env python3
"""Benchmark of the design sweeps (docs/sweeps.md "Speed"), for each example study in one run:

(a) the floor: the FMU's calls alone for a sample of the study's cases: per case fmi2Reset,
    fmi2SetupExperiment, fmi2EnterInitializationMode, the fmi2Set* of the case's values,
    fmi2ExitInitializationMode, the first fmi2SetReal/fmi2GetReal, and every step's
    fmi2SetReal/fmi2DoStep/fmi2GetReal driven by the native batch driver (libfmi2_batch.so), with
    every argument prepared beforehand: no Python work per step, none between the calls of a case
    but the calls themselves;
(b) one worker's time per case: `sweep.run_batch` on the same cases in this process (and the same
    with `reference=True`, the per-step Python loop, as the baseline);
(c) cases per second of `run_sweep` on a LocalCluster (processes, one thread each) with 1 and with
    2 workers, on the study with a denser grid (the same cases' kind, enough of them for several
    seconds of one worker's work), from the first submission to the last result.

The ratios printed: floor time / worker time (≥ 0.8 is the target: a worker's cases/s at least 0.8×
the floor's), and 2-worker / 1-worker cases/s (≥ 1.8). Every time is the minimum over --repeat
repetitions (wall time; the machine is shared, and the minimum is the run least disturbed).

    .venv/bin/python scripts/bench_sweep.py [--repeat 5] [--sample 24] [--dask-seconds 4]
    .venv/bin/python scripts/bench_sweep.py --no-dask        # (a) and (b) only
"""

from __future__ import annotations

import argparse
import ctypes
import math
import os
import pathlib
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
import numpy as np  # noqa: E402
from reciprocating_drive import batch, sweep  # noqa: E402
from reciprocating_drive.fmu import Fmu  # noqa: E402
from reciprocating_drive.revolution import TWO_PI  # noqa: E402
from reciprocating_drive.study import SPEED_PARAMETERS, load_study, study_from_dict  # noqa: E402

STUDIES = ("unb600a_friction", "kvo630_resonance", "default_balancer")


def sample_cases(study, k: int) -> list[int]:
    """k cases spread over the study (every case if it has fewer)."""
    if study.n_cases <= k:
        return list(range(study.n_cases))
    return sorted({round(i * (study.n_cases - 1) / (k - 1)) for i in range(k)})


def prepared_calls(fmu: Fmu, study, cases: list[int]) -> list:
    """Per case the arguments of every FMU call `run_case` makes, built in advance."""
    from fmpy.fmi2 import fmi2Boolean, fmi2Integer, fmi2Real, fmi2ValueReference

    ctype = {"Real": fmi2Real, "Integer": fmi2Integer, "Boolean": fmi2Boolean}
    ch = fmu.channel(["crank.angle", "crank.speed"], list(sweep.OUTPUTS))
    lib = batch.library()
    prepared = []
    for i in cases:
        params = study.case(i)
        omega = sweep._speed(study, params)
        values = {
            k: v
            for k, v in study.base_values.items()
            if k not in ("crank.angle", "crank.speed", "crank.acceleration")
        }
        values.update({k: v for k, v in params.items() if k not in SPEED_PARAMETERS})
        values["crank.speed"] = omega
        groups: dict = {}
        for name, v in values.items():
            var = fmu.variables[name]
            vrs, vals = groups.setdefault(var.type, ([], []))
            vrs.append(var.valueReference)
            vals.append(float(v) if var.type == "Real" else int(v))
        sets = [
            (
                fmu._raw[f"fmi2Set{ty}"],
                (fmi2ValueReference * len(v))(*v),
                len(v),
                (ctype[ty] * len(x))(*x),
            )
            for ty, (v, x) in groups.items()
        ]
        n = (study.skip_revolutions + study.revolutions) * study.steps_per_revolution + 2
        h = TWO_PI / omega / study.steps_per_revolution
        t = np.arange(1, n + 1) * h
        xin = np.empty((n, 2))
        xin[:, 0], xin[:, 1] = omega * (t - h), omega
        out = np.empty((n + 1, len(sweep.OUTPUTS)))
        x0 = (fmi2Real * 2)(0.0, omega)
        fail = batch.Failure()
        run_args = (
            *ch._addresses, fmu._component, ctypes.addressof(ch._vin), 2,
            ctypes.addressof(ch._vout), len(sweep.OUTPUTS), 0.0, n, t.ctypes.data,
            xin.ctypes.data, 2, out[1:].ctypes.data, len(sweep.OUTPUTS),
            batch.ORDER_SET_STEP_GET, 1, ctypes.byref(fail),
        )  # fmt: skip
        out0 = out.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        prepared.append((sets, x0, out0, run_args, (t, xin, out, fail)))
    return prepared, ch, lib


def floor_seconds(fmu: Fmu, study, cases: list[int], repeat: int) -> float:
    """(a): the FMU's calls of the cases alone, min over `repeat` (seconds for all cases)."""
    prepared, ch, lib = prepared_calls(fmu, study, cases)
    raw, c = fmu._raw, fmu._component
    reset, setup = raw["fmi2Reset"], raw["fmi2SetupExperiment"]
    enter, leave = raw["fmi2EnterInitializationMode"], raw["fmi2ExitInitializationMode"]
    set_real, get_real, run = ch._set, ch._get, lib.fmi2_batch_run
    vin, vout, no = ch._vin, ch._vout, len(sweep.OUTPUTS)
    fmu.start({})  # an instance that has run: every case begins with fmi2Reset, as in a sweep
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for sets, x0, out0, run_args, _keep in prepared:
            reset(c)
            setup(c, 0, 0.0, 0.0, 0, 0.0)
            enter(c)
            for fn, vr, k, vals in sets:
                fn(c, vr, k, vals)
            leave(c)
            set_real(c, vin, 2, x0)
            get_real(c, vout, no, out0)
            run(*run_args)
        best = min(best, time.perf_counter() - t0)
    return best


def worker_seconds(fmu_path: str, study, cases: list[int], repeat: int, **kw) -> float:
    """(b): `run_batch` of the cases in this process, min over `repeat` (seconds for all cases)."""
    sweep.run_batch(fmu_path, study, cases[:1], **kw)  # the FMU loaded once, as on a worker
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        rows = sweep.run_batch(fmu_path, study, cases, **kw)
        best = min(best, time.perf_counter() - t0)
    bad = [r for r in rows if r["status"] != "ok"]
    if bad:
        raise SystemExit(f"{study.name}: case {bad[0]['case']} failed: {bad[0]['message']}")
    return best


def denser(study_path: pathlib.Path, fmu: str, n_cases: int):
    """The study with each parameter's grid made denser, to about n_cases cases (same kind of
    case: the same machine, speed range, revolutions and steps)."""
    import tomllib

    doc = tomllib.loads(study_path.read_text())
    axes = doc["parameters"]
    grow = (n_cases / math.prod(a["num"] for a in axes.values())) ** (1 / len(axes))
    for a in axes.values():
        a["num"] = max(a["num"], round(a["num"] * grow))
    return study_from_dict(doc, base_dir=study_path.parent, source=str(study_path), fmu=fmu)


def dask_rate(study, fmu: str, workers: int, repeat: int) -> tuple[float, float]:
    """(c): cases/s of run_sweep with `workers` LocalCluster workers (best of `repeat`), and the
    share of the workers' time outside the FMU calls of run_batch."""
    best = None
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as d:
            r = sweep.run_sweep(study, fmu, d, workers=workers, progress=False)
        if best is None or r.wall < best.wall:
            best = r
    return best.computed / best.wall, best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--fmu", default=str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
    ap.add_argument(
        "--study", action="append", help="a study name of studies/ (default: all three)"
    )
    ap.add_argument("--repeat", type=int, default=5, help="repetitions of (a) and (b); min taken")
    ap.add_argument("--dask-repeat", type=int, default=2, help="repetitions of (c); min taken")
    ap.add_argument("--sample", type=int, default=24, help="cases per study for (a) and (b)")
    ap.add_argument(
        "--dask-seconds",
        type=float,
        default=4.0,
        help="seconds of one worker's work per study in (c)",
    )
    ap.add_argument("--no-dask", action="store_true", help="skip (c)")
    ap.add_argument("--no-reference", action="store_true", help="skip the per-step baseline")
    a = ap.parse_args(argv)
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores; "
          f"uptime: {os.popen('uptime').read().strip()}")  # fmt: skip
    print("times: minimum over repetitions (wall clock, the machine may be shared)")
    fmu_path = str(pathlib.Path(a.fmu).resolve())
    fmu = Fmu(fmu_path)
    for name in a.study or STUDIES:
        path = ROOT / "studies" / f"{name}.toml"
        study = load_study(path, fmu=fmu_path)
        cases = sample_cases(study, a.sample)
        fl = floor_seconds(fmu, study, cases, a.repeat) / len(cases)
        wk = worker_seconds(fmu_path, study, cases, a.repeat) / len(cases)
        steps = (study.skip_revolutions + study.revolutions) * study.steps_per_revolution + 2
        print(f"\n{name}: {study.n_cases} cases of {steps} steps; {len(cases)} sampled")
        print(f"  (a) FMU calls alone     {1e3 * fl:8.3f} ms/case  {1 / fl:8.1f} cases/s")
        print(f"  (b) run_batch           {1e3 * wk:8.3f} ms/case  {1 / wk:8.1f} cases/s"
              f"   (a)/(b) = {fl / wk:.2f}")  # fmt: skip
        if not a.no_reference and "reference" in sweep.run_batch.__code__.co_varnames:
            rf = worker_seconds(fmu_path, study, cases, a.repeat, reference=True) / len(cases)
            print(f"      per-step reference  {1e3 * rf:8.3f} ms/case  {1 / rf:8.1f} cases/s"
                  f"   (a)/(ref) = {fl / rf:.2f}")  # fmt: skip
        if a.no_dask:
            continue
        big = denser(path, fmu_path, max(study.n_cases, round(a.dask_seconds / wk)))
        rate = {}
        for workers in (1, 2):
            rate[workers], r = dask_rate(big, fmu_path, workers, a.dask_repeat)
            print(f"  (c) {workers} worker(s), {big.n_cases} cases: {rate[workers]:8.1f} cases/s "
                  f"(wall {r.wall:.2f} s; per worker {rate[workers] / workers * fl:.2f}× "
                  "the floor)")  # fmt: skip
        print(f"      2 workers / 1 worker = {rate[2] / rate[1]:.2f}")
    print(f"\nuptime after: {os.popen('uptime').read().strip()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
