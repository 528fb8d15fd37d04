"""Design sweeps on Dask (docs/sweeps.md): a LocalCluster and a real `dask scheduler` with two
`dask worker` processes started here on the loopback interface give identical results; a case the
FMU rejects is a row with its message; a killed sweep resumes without recomputing finished cases;
one case of each example study agrees with a direct fmpy.simulate_fmu run whose metrics are
computed here from the raw samples, not by the sweep's code."""

from __future__ import annotations

import math
import os
import pathlib
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import ROOT
from reciprocating_drive.study import StudyError, load_study, study_from_dict
from reciprocating_drive.sweep import load_rows, run_batch, run_sweep

VENV_BIN = pathlib.Path(sys.executable).parent

SMALL = {
    "name": "small",
    "machine": "default",
    "strokes_per_minute": 65,
    "skip_revolutions": 0,
    "revolutions": 1,
    "steps_per_revolution": 120,
    "metrics": ["friction_work", "torque_peak", "acceleration_max"],
    # rod_length 0.15 m < crank radius 0.2 m: the crank-slider cannot assemble (rejected case).
    "parameters": {
        "mass.reciprocating": {"values": [200.0, 300.0, 400.0]},
        "geometry.rod_length": {"values": [1.19, 0.15]},
    },
}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def real_cluster():
    """`dask scheduler` and two `dask worker` processes on 127.0.0.1, as on a real cluster."""
    port = free_port()
    addr = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "python")}
    procs = [
        subprocess.Popen(
            [
                str(VENV_BIN / "dask"),
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--no-dashboard",
            ],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    ]
    for _ in range(2):
        procs.append(
            subprocess.Popen(
                [
                    str(VENV_BIN / "dask"),
                    "worker",
                    addr,
                    "--nthreads",
                    "1",
                    "--nworkers",
                    "1",
                    "--no-dashboard",
                    "--host",
                    "127.0.0.1",
                ],
                env=env,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        )
    from dask.distributed import Client

    deadline = time.time() + 60
    while True:
        try:
            with Client(addr, timeout=5) as c:
                c.wait_for_workers(2, timeout=30)
            break
        except OSError:
            if time.time() > deadline:
                raise
            time.sleep(0.5)
    yield addr
    for p in procs[::-1]:
        p.terminate()
    for p in procs:
        p.wait(timeout=30)


def test_local_cluster_and_real_scheduler_agree(fmu_path, tmp_path, real_cluster):
    study = study_from_dict(SMALL)
    a = run_sweep(study, fmu_path, tmp_path / "local", workers=2, progress=False, batch_size=1)
    b = run_sweep(
        study, fmu_path, tmp_path / "remote", scheduler=real_cluster, progress=False, batch_size=1
    )
    assert a.computed == b.computed == 6 and b.workers == 2
    ra, rb = load_rows(a.csv, study), load_rows(b.csv, study)
    keys = ["case", *study.varied, *study.metrics, "status", "message"]
    for x, y in zip(ra, rb):
        for k in keys:
            same = (x[k] == y[k]) or (
                isinstance(x[k], float) and math.isnan(x[k]) and math.isnan(y[k])
            )
            assert same, (k, x[k], y[k])
    # Both clusters really spread the work over two worker processes.
    assert len({r["worker"] for r in rb}) == 2
    # The rejected cases are rows with the FMU's message, not the end of the sweep.
    bad = [r for r in ra if r["status"] == "error"]
    assert len(bad) == 3 and all(
        "cannot assemble" in r["message"] and "geometry.rod_length = 0.15" in r["message"]
        for r in bad
    )
    assert all(math.isnan(r["friction_work"]) for r in bad)
    # Parquet holds the same table.
    import pyarrow.parquet as pq

    t = pq.read_table(a.parquet).to_pylist()
    assert [r["case"] for r in t] == [r["case"] for r in ra]
    assert [r["status"] for r in t] == [r["status"] for r in ra]


def test_killed_sweep_resumes_without_recomputing(fmu_path, tmp_path):
    """A sweep process killed with SIGKILL after some cases, then started again: the finished
    cases are kept as they were (their timings prove they were not recomputed) and the final
    table equals an uninterrupted sweep's."""
    study_file = tmp_path / "slow.toml"
    study_file.write_text("""
name = "slow"
machine = "default"
revolutions = 2
steps_per_revolution = 720
metrics = ["friction_work", "torque_peak"]
[parameters]
"mass.reciprocating" = { start = 100, stop = 500, num = 24 }
""")
    out = tmp_path / "out"
    cmd = [
        sys.executable,
        str(ROOT / "scripts" / "sweep.py"),
        str(study_file),
        "--fmu",
        fmu_path,
        "--out-dir",
        str(out),
        "--workers",
        "1",
        "--batch-size",
        "1",
        "--no-progress",
    ]
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    csv_path = out / "slow.csv"
    deadline = time.time() + 120
    while time.time() < deadline:
        if csv_path.is_file() and csv_path.read_text().count("\n") >= 4:
            break
        time.sleep(0.05)
    p.kill()
    p.wait()
    study = load_study(study_file)
    before = {r["case"]: r for r in load_rows(csv_path, study)} if csv_path.is_file() else {}
    assert 3 <= len(before) < 24, len(before)
    r = run_sweep(study, fmu_path, out, workers=1, progress=False)
    assert r.skipped == len(before) and r.computed == 24 - len(before)
    after = {x["case"]: x for x in load_rows(csv_path, study)}
    assert sorted(after) == list(range(24))
    for c, row in before.items():
        assert after[c]["seconds_case"] == row["seconds_case"]  # the same row, not a new run
    fresh = run_sweep(study, fmu_path, tmp_path / "fresh", workers=1, progress=False)
    for x in load_rows(fresh.csv, study):
        assert after[x["case"]]["friction_work"] == x["friction_work"]


def direct_fmpy(fmu_path, study, params):
    """The case run by fmpy.simulate_fmu, metrics from the raw samples (independent code)."""
    from fmpy import simulate_fmu

    sv = {
        k: v
        for k, v in study.base_values.items()
        if k not in ("crank.angle", "crank.speed", "crank.acceleration")
    }
    w = study.crank_speed
    for k, v in params.items():
        if k == "strokes_per_minute":
            w = v * 2 * math.pi / 60
        else:
            sv[k] = v
    sv["crank.speed"] = w
    n_per = study.steps_per_revolution
    h = 2 * math.pi / w / n_per
    n = (study.skip_revolutions + study.revolutions) * n_per
    t = np.arange(n + 1) * h
    sig = np.zeros(n + 1, dtype=[("time", float), ("crank.angle", float), ("crank.speed", float)])
    sig["time"], sig["crank.angle"], sig["crank.speed"] = t, w * t, w
    res = simulate_fmu(
        fmu_path,
        stop_time=n * h,
        output_interval=h,
        start_values=sv,
        input=sig,
        output=[
            "suspension.position",
            "link.friction_total",
            "crank.torque",
            "rod.angle",
            "rod.stress_max",
        ],
    )
    ev = slice(study.skip_revolutions * n_per, n + 1)
    x, f = res["suspension.position"][ev], res["link.friction_total"][ev]
    tq = np.abs(res["crank.torque"][ev])
    i = int(np.argmax(tq))
    # A parabola through the peak sample and its neighbours moves the sampled peak by at most
    # |second difference|/8 (vertex within half a sample of the peak sample).
    d2 = abs(tq[i - 1] - 2 * tq[i] + tq[i + 1]) if 0 < i < len(tq) - 1 else 0.0
    return {
        "friction_work": float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x))) / study.revolutions,
        "torque_peak": float(tq[i]),
        "torque_peak_bound": d2 / 8 * 1.01 + 1e-12 * float(tq[i]),
        "rod_angle_amplitude": float(np.max(np.abs(res["rod.angle"][ev]))),
        "stress_max": float(np.max(res["rod.stress_max"][ev])),
    }


@pytest.mark.parametrize(
    "name,case", [("unb600a_friction", 30), ("kvo630_resonance", 25), ("default_balancer", 12)]
)
def test_example_case_agrees_with_direct_fmpy(fmu_path, name, case):
    study = load_study(ROOT / "studies" / f"{name}.toml")
    (row,) = run_batch(fmu_path, study, [case])
    assert row["status"] == "ok", row["message"]
    ref = direct_fmpy(fmu_path, study, study.case(case))
    for m in study.metrics:
        if m == "torque_peak":
            # Same samples; the sweep refines the sampled peak by a parabola (docs/sweeps.md).
            assert ref[m] - 1e-12 * ref[m] <= row[m] <= ref[m] + ref["torque_peak_bound"], (
                row[m],
                ref[m],
            )
        elif m in ref:
            assert row[m] == pytest.approx(ref[m], rel=1e-9, abs=1e-12), (m, row[m], ref[m])


def test_lhs_design_is_stratified_and_bad_studies_are_refused(tmp_path):
    st = study_from_dict(
        {
            "name": "l",
            "design": {"kind": "lhs", "samples": 16, "seed": 3},
            "parameters": {
                "mass.reciprocating": {"min": 100, "max": 500},
                "guide.friction_coefficient": {"min": 0.0, "max": 0.2},
            },
        }
    )
    assert st.n_cases == len(st.case_values) == 16
    for p, (lo, hi) in {
        "mass.reciprocating": (100, 500),
        "guide.friction_coefficient": (0.0, 0.2),
    }.items():
        u = sorted((c[p] - lo) / (hi - lo) for c in st.case_values)
        # Latin hypercube: exactly one sample in each of the 16 strata of every dimension.
        assert [int(x * 16) for x in u] == list(range(16))
    with pytest.raises(StudyError, match="metrics.0. = 'nonsense'; allowed: friction_work"):
        study_from_dict(
            {"metrics": ["nonsense"], "parameters": {"mass.reciprocating": {"values": [1.0]}}}
        )
    with pytest.raises(StudyError, match="parameters = {}; allowed: at least one entry"):
        study_from_dict({"parameters": {}})
    with pytest.raises(StudyError, match="machine = 'nosuch'; allowed: default, kvo630"):
        study_from_dict(
            {"machine": "nosuch", "parameters": {"mass.reciprocating": {"values": [1.0]}}}
        )
