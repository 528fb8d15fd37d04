#!/usr/bin/env python3
"""Benchmark of the design sweeps (docs/sweeps.md "Speed"), for each example study in one run:

(a) the floor: the FMU's calls alone for the cases (the study's grid made denser, about
    --seconds of them, as one batch): per case fmi2Reset,
    fmi2SetupExperiment, fmi2EnterInitializationMode, the fmi2Set* of the case's values,
    fmi2ExitInitializationMode, the first fmi2SetReal/fmi2GetReal, and every step's
    fmi2SetReal/fmi2DoStep/fmi2GetReal driven by the native batch driver (libfmi2_batch.so), with
    every argument prepared beforehand: no Python work per step, none between the calls of a case
    but the calls themselves;
(a') the stricter floor: the same cases' calls all made from native code: the sweep's own driver
    (`fmi2_batch_cases`, libfmi2_batch.so) on the cases' value rows prepared beforehand, a few
    hundred cases per call, no metrics; (a) minus (a') is what calling the FMU from Python costs
    any Python importer;
(b) one worker's time per case: `sweep.run_batch_csv` (a sweep's Dask task) on the same cases in
    this process, one call (and, as the baseline, `run_batch(..., reference=True)`, the per-step
    Python loop, on 24 of them);
(c) cases per second of `run_sweep` on a LocalCluster (processes, one thread each) with 1 and with
    2 workers, on the study with a denser grid (the same cases' kind, enough of them for several
    seconds of one worker's work), from the first submission to the last result; and the CPU
    time the worker processes spent per case (their whole work, the cases and Dask's).

The ratios printed: floor time / worker time (≥ 0.8 is the target: a worker's cases/s at least 0.8×
the floor's (a)), the same against (a'), and 2-worker / 1-worker cases/s (≥ 1.8). (a), (a') and
(b) run on the same FMU instance, the one `run_batch` loads, in turn: each of --repeat rounds runs
each once. Every time is the minimum over the rounds, by wall time and by CPU time: on a shared
machine the minimum is the run least disturbed, and the CPU time leaves out the time other
processes had the core (but not their effect on the caches).

    .venv/bin/python scripts/bench_sweep.py [--repeat 5] [--seconds 0.5] [--dask-seconds 8]
    .venv/bin/python scripts/bench_sweep.py --no-dask        # (a), (a') and (b) only
"""

from __future__ import annotations

import argparse
import ctypes
import math
import os
import pathlib
import platform
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
import numpy as np  # noqa: E402
from reciprocating_drive.fmu import Fmu, batch  # noqa: E402
from reciprocating_drive.revolution import TWO_PI  # noqa: E402
from reciprocating_drive.sweeps import cases as sweep_cases  # noqa: E402
from reciprocating_drive.sweeps import sweep  # noqa: E402
from reciprocating_drive.sweeps.study import load_study, study_from_dict  # noqa: E402

STUDIES = ("unb600a_friction", "kvo630_resonance", "default_balancer")


def sample_cases(study, k: int) -> list[int]:
    """k cases spread over the study (every case if it has fewer)."""
    if study.n_cases <= k:
        return list(range(study.n_cases))
    return sorted({round(i * (study.n_cases - 1) / (k - 1)) for i in range(k)})


def prepared_calls(fmu: Fmu, study, cases: list[int]) -> list:
    """Per case the arguments of every FMU call `run_case` makes, built in advance (the time and
    input arrays shared by the cases of one speed, one output array for all)."""
    from fmpy.fmi2 import fmi2Boolean, fmi2Integer, fmi2Real, fmi2ValueReference

    ctype = {"Real": fmi2Real, "Integer": fmi2Integer, "Boolean": fmi2Boolean}
    ch = fmu.channel(["crank.angle", "crank.speed"], list(sweep_cases.OUTPUTS))
    lib = batch.library()
    n = (study.skip_revolutions + study.revolutions) * study.steps_per_revolution + 2
    out = np.empty((n + 1, len(sweep_cases.OUTPUTS)))
    out0 = out.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
    fail = batch.Failure()
    inputs: dict = {}
    prepared = []
    for i in cases:
        params = study.case(i)
        omega = sweep_cases._speed(study, params)
        groups: dict = {}
        for name, v in sweep_cases.case_values(study, params, omega).items():
            var = fmu.variables[name]
            vrs, vals = groups.setdefault(var.type, ([], []))
            vrs.append(var.valueReference)
            vals.append(float(v) if var.type == "Real" else int(v))
        sets = [
            (fmu._raw[f"fmi2Set{ty}"], (fmi2ValueReference * len(v))(*v), len(v),
             (ctype[ty] * len(x))(*x))
            for ty, (v, x) in groups.items()
        ]  # fmt: skip
        if omega not in inputs:
            h = TWO_PI / omega / study.steps_per_revolution
            t = np.arange(1, n + 1) * h
            xin = np.empty((n, 2))
            xin[:, 0], xin[:, 1] = omega * (t - h), omega
            inputs[omega] = (t, xin)
        t, xin = inputs[omega]
        x0 = (fmi2Real * 2)(0.0, omega)
        run_args = (
            *ch._addresses, fmu._component, ctypes.addressof(ch._vin), 2,
            ctypes.addressof(ch._vout), len(sweep_cases.OUTPUTS), 0.0, n, t.ctypes.data,
            xin.ctypes.data, 2, out[1:].ctypes.data, len(sweep_cases.OUTPUTS),
            batch.ORDER_SET_STEP_GET, 1, ctypes.byref(fail),
        )  # fmt: skip
        prepared.append((sets, x0, out0, run_args))
    return prepared, ch, lib, (inputs, out, fail)


def floor_run(fmu: Fmu, study, cases: list[int]):
    """(a): a function that makes the FMU's calls of the cases alone once and returns its (wall,
    CPU) seconds."""
    prepared, ch, lib, keep = prepared_calls(fmu, study, cases)
    raw, c = fmu._raw, fmu._component
    reset, setup = raw["fmi2Reset"], raw["fmi2SetupExperiment"]
    enter, leave = raw["fmi2EnterInitializationMode"], raw["fmi2ExitInitializationMode"]
    set_real, get_real, run = ch._set, ch._get, lib.fmi2_batch_run
    vin, vout, no = ch._vin, ch._vout, len(sweep_cases.OUTPUTS)
    fmu.start({})  # an instance that has run: every case begins with fmi2Reset, as in a sweep

    def once():
        _keep = keep  # the arrays the prepared arguments point into
        t0 = clocks()
        for sets, x0, out0, run_args in prepared:
            reset(c)
            setup(c, 0, 0.0, 0.0, 0, 0.0)
            enter(c)
            for fn, vr, k, vals in sets:
                fn(c, vr, k, vals)
            leave(c)
            set_real(c, vin, 2, x0)
            get_real(c, vout, no, out0)
            run(*run_args)
        return clocks() - t0

    return once


def native_floor_run(fmu: Fmu, study, cases: list[int]):
    """(a'): a function that makes the cases' calls from native code alone once
    (fmi2_batch_cases on value rows prepared beforehand, 256 cases per call into one reused
    output array) and returns its (wall, CPU) seconds."""
    p = sweep_cases._prepared(fmu, study, sweep_cases.OUTPUTS)
    params = study.case_array(cases)
    omega = sweep_cases.speeds(study, params)
    h = TWO_PI / omega / study.steps_per_revolution
    chunks = []
    for a in range(0, len(cases), 256):
        work = sweep_cases.Workspace()  # each chunk's value rows kept
        groups = p.values(params[a : a + 256], omega[a : a + 256], work)
        chunks.append((groups, work, omega[a : a + 256].copy(), h[a : a + 256].copy()))
    data = np.empty((256, p.n + 1, len(sweep_cases.OUTPUTS)))
    seconds = np.empty(256)

    def once():
        t0 = clocks()
        for groups, _work, w, hc in chunks:
            if p.run(groups, 0, len(w), w, hc, data, seconds) != len(w):
                raise SystemExit(f"{study.name}: a case failed in the native floor")
        return clocks() - t0

    return once


def worker_run(fmu_path: str, study, cases: list[int], reference: bool = False):
    """(b): a function that runs the cases as a sweep's Dask task does (`run_batch_csv`; with
    `reference`, `run_batch(..., reference=True)`) once, in this process, and returns its (wall,
    CPU) seconds."""
    rows = sweep.run_batch(fmu_path, study, cases, reference=reference)  # loads the FMU once
    bad = [r for r in rows if r["status"] != "ok"]
    if bad:
        raise SystemExit(f"{study.name}: case {bad[0]['case']} failed: {bad[0]['message']}")
    cols, fp = sweep.columns(study), sweep.fingerprint(study, fmu_path)

    def once():
        t0 = clocks()
        if reference:
            sweep.run_batch(fmu_path, study, cases, reference=True)
        else:
            sweep.run_batch_csv(fmu_path, study, cases, False, cols, fp)
        return clocks() - t0

    return once


def interleaved(runs: list, repeat: int) -> list[np.ndarray]:
    """The minimum (wall, CPU) seconds of each of `runs` over `repeat` rounds, each round running
    every one once: a disturbance of the shared machine falls on all of them alike."""
    best = [np.array([math.inf, math.inf]) for _ in runs]
    for _ in range(repeat):
        for k, once in enumerate(runs):
            best[k] = np.minimum(best[k], once())
    return best


def clocks() -> np.ndarray:
    """(wall time, this process's CPU time) [s]: on a shared machine the CPU time is the less
    disturbed of the two (it leaves out the time other processes had the core)."""
    return np.array([time.perf_counter(), time.process_time()])


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


def _cpu() -> float:
    return time.process_time()


def dask_rate(study, fmu: str, workers: int, repeat: int) -> tuple[float, float, object]:
    """(c): run_sweep on a LocalCluster of `workers` single-threaded worker processes (best of
    `repeat` by wall time): (cases/s, the workers' CPU seconds per case, the SweepResult). The
    cluster is started here, as run_sweep starts its own, and attached with `scheduler=`, so that
    the workers' CPU time (their whole process: the cases and Dask's work) can be read before and
    after."""
    import dask
    from dask.distributed import Client, LocalCluster

    best = None
    for _ in range(repeat):
        with (
            # As run_sweep's own LocalCluster (sweep._client): no statistical profiler.
            dask.config.set({"distributed.worker.profile.enabled": False}),
            LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True,
                dashboard_address=":0", host="127.0.0.1",
            ) as cluster,
            Client(cluster) as client,
            tempfile.TemporaryDirectory() as d,
        ):  # fmt: skip
            cpu0 = sum(client.run(_cpu).values())
            r = sweep.run_sweep(study, fmu, d, scheduler=cluster.scheduler_address, progress=False)
            cpu = (sum(client.run(_cpu).values()) - cpu0) / r.computed
        if best is None or r.wall < best[2].wall:
            best = (r.computed / r.wall, cpu, r)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--fmu", default=str(ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu"))
    ap.add_argument("--study", action="append", help="a study of studies/ (default: all three)")
    ap.add_argument("--repeat", type=int, default=5, help="repetitions of (a) and (b); min taken")
    ap.add_argument("--dask-repeat", type=int, default=4, help="repetitions of (c); min taken")
    ap.add_argument(
        "--seconds", type=float, default=0.5, help="floor seconds of the cases of (a) and (b)"
    )
    ap.add_argument(
        "--dask-seconds", type=float, default=8.0, help="seconds of one worker's work in (c)"
    )
    ap.add_argument("--no-dask", action="store_true", help="skip (c)")
    ap.add_argument("--no-reference", action="store_true", help="skip the per-step baseline")
    a = ap.parse_args(argv)
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, "
          f"{platform.processor() or platform.machine()}; uptime: {uptime()}")  # fmt: skip
    print("times: minimum over repetitions (wall clock, the machine may be shared)")
    fmu_path = str(pathlib.Path(a.fmu).resolve())
    # The instance run_batch uses: two loads of the FMU are two copies of its code and data in
    # memory, whose speeds differ by some percent (caches, alignment) for no reason of the calls'.
    fmu = sweep._worker_fmu(fmu_path)
    summary = []
    for name in a.study or STUDIES:
        path = ROOT / "studies" / f"{name}.toml"
        study = load_study(path, fmu=fmu_path)
        few8 = sample_cases(study, 8)
        pilot = interleaved([floor_run(fmu, study, few8)], 2)[0][0] / len(few8)
        # The cases of (a) and (b): the study's grid made denser, to about --seconds of floor,
        # as one batch (a sweep's batches hold about a second of work).
        k = int(min(2000, max(24, a.seconds / pilot)))
        dense = denser(path, fmu_path, k)
        cases = sample_cases(dense, k)
        runs = [floor_run(fmu, dense, cases), native_floor_run(fmu, dense, cases),
                worker_run(fmu_path, dense, cases)]  # fmt: skip
        fl, nf, wk = (x / len(cases) for x in interleaved(runs, a.repeat))
        steps = (study.skip_revolutions + study.revolutions) * study.steps_per_revolution + 2
        print(f"\n{name}: cases of {steps} steps; {len(cases)} cases of its grid made denser")
        print("                          wall ms/case  cases/s   CPU ms/case  cases/s")
        for label, x in (
            ("(a) FMU calls alone", fl), ("(a') all native", nf), ("(b) run_batch_csv", wk)
        ):  # fmt: skip
            print(
                f"  {label:<22}{1e3 * x[0]:10.3f} {1 / x[0]:9.1f} {1e3 * x[1]:11.3f} {1 / x[1]:9.1f}"
            )
        print(f"      (a)/(b): wall {fl[0] / wk[0]:.2f}, CPU {fl[1] / wk[1]:.2f}; "
              f"(a')/(b): wall {nf[0] / wk[0]:.2f}, CPU {nf[1] / wk[1]:.2f}")  # fmt: skip
        row = [name, fl[0] / wk[0], fl[1] / wk[1], nf[1] / wk[1]]
        if not a.no_reference:
            few = cases[:: max(1, len(cases) // 24)][:24]
            rf = interleaved([worker_run(fmu_path, dense, few, True)], min(a.repeat, 2))[0]
            rf = rf / len(few)
            print(f"      per-step reference ({len(few)} of the cases): {1e3 * rf[0]:.3f} ms/case "
                  f"wall, {1e3 * rf[1]:.3f} CPU; (a)/(reference) wall {fl[0] / rf[0]:.2f}")  # fmt: skip
        if not a.no_dask:
            big = denser(path, fmu_path, max(study.n_cases, round(a.dask_seconds / wk[0])))
            rate = {}
            for workers in (1, 2):
                rate[workers], cpu, r = dask_rate(big, fmu_path, workers, a.dask_repeat)
                print(f"  (c) {workers} worker(s), {big.n_cases} cases: {rate[workers]:8.1f} "
                      f"cases/s (wall {r.wall:.2f} s); per worker {rate[workers] / workers * fl[0]:.2f}"
                      f"× the floor's cases/s (wall); workers' CPU {1e3 * cpu:.3f} ms/case, "
                      f"{fl[1] / cpu:.2f}× the floor's (CPU), {nf[1] / cpu:.2f}× (a')'s")  # fmt: skip
                # Dask's share: the workers' wall time not spent in tasks (task overhead, transfer,
                # waiting for the next batch, the last batches' unequal ends).
                outside = 1 - r.seconds_cases / (r.wall * workers)
                print(
                    f"      {r.batches} batches; workers' time outside the tasks: {100 * outside:.1f} %"
                )
                row += [rate[workers] / workers * fl[0], fl[1] / cpu, nf[1] / cpu]
            print(f"      2 workers / 1 worker = {rate[2] / rate[1]:.2f}")
            row.append(rate[2] / rate[1])
        summary.append(row)
    print(
        "\nper worker: a worker's cases/s ÷ the floor's (a), by wall time and by CPU time, and "
        "÷ (a')'s by CPU time; 2/1: cases/s of 2 workers ÷ 1 worker's"
    )
    print(
        "study               (a)/(b) wall  (a)/(b) CPU  (a')/(b) CPU"
        + ("" if a.no_dask else "  1 worker wall, CPU, (a')  2 workers wall, CPU, (a')   2/1")
    )
    for row in summary:
        print(
            f"{row[0]:<20}{row[1]:12.2f}{row[2]:13.2f}{row[3]:14.2f}"
            + "".join(f"{v:9.2f}" for v in row[4:])
        )
    print(f"uptime after: {uptime()}")
    return 0


def uptime() -> str:
    with open("/proc/loadavg") as f:
        return "load average " + ", ".join(f.read().split()[:3])


if __name__ == "__main__":
    sys.exit(main())
