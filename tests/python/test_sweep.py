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
from reciprocating_drive.sweeps.study import StudyError, load_study, study_from_dict
from reciprocating_drive.sweeps.sweep import load_rows, run_batch, run_sweep

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


# ---- parameters that cannot act (docs/sweeps.md "Parameters that cannot act") --------------

NO_SUPPORTS = {"support_A.kind": 0, "support_B.kind": 0, "support_C.kind": 0}
KVO = "kvo630"
# (parameter, value 1, value 2, where the rule says it cannot act, where it says it acts).
# A machine is the default one with these values over it, or a preset named by "machine".
CLAIMS = [
    ("support_C.tilt", 0.0, 2e-4, {}, {"support_C.attached": 0}),
    ("support_C.length", 0.05, 0.1, {}, {"support_C.kind": 3}),
    ("support_C.offset", 0.0, 2e-4, {"support_C.kind": 0}, {}),
    ("support_C.stiffness", 2e6, 4e6, {"support_C.kind": 0}, {}),
    ("support_C.z", 1.6, 1.4, {"support_C.kind": 0}, {}),
    ("support_C.attached", 1, 0, {"support_C.kind": 0}, {}),
    ("support_C.friction", 0.0, 0.1, {"support_C.kind": 0}, {}),
    ("support_B.offset", 3e-4, 1e-4, {"support_B.kind": 0}, {}),
    ("support_B.length", 0.4, 0.3, {"support_B.kind": 0}, {}),
    ("guide.friction_coefficient", 0.1, 0.2, {"support_B.kind": 0}, {}),
    (
        "support_B.tilt",
        0.0,
        2e-4,
        {"support_B.kind": 1, "support_B.attached": 1},
        {"support_B.kind": 1, "support_B.attached": 0},
    ),  # fmt: skip
    ("support_A.offset", 0.0, 2e-4, {"support_A.kind": 0}, {}),
    ("support_A.tilt", 0.0, 2e-4, {"support_A.kind": 0}, {}),
    ("link.d3", 0.1, 0.12, NO_SUPPORTS, {}),
    ("link.l3", 1.0, 1.1, NO_SUPPORTS, {}),
    ("link.E", 2.1e11, 1.0e11, NO_SUPPORTS, {}),
    ("link.lateral_load", 0.0, 500.0, NO_SUPPORTS, {}),
    ("guide.rod_side_force", True, False, NO_SUPPORTS, {}),
    ("balancer.stiffness", 1e4, 2e4, {}, {"balancer.enabled": True}),
    (
        "balancer.design_speed",
        6.8,
        5.0,
        {"balancer.enabled": True},
        {"balancer.enabled": True, "balancer.tuning": 1},
    ),  # fmt: skip
    (
        "balancer.neutral_position",
        0.05,
        0.1,
        {"balancer.enabled": True, "balancer.tuning": 1},
        {"balancer.enabled": True, "balancer.stiffness": 1e4},
    ),  # fmt: skip
    (
        "balancer.neutral_position",
        0.05,
        0.1,
        {"balancer.enabled": True},
        {"balancer.enabled": True, "balancer.stiffness": 1e4},
    ),  # fmt: skip
    ("geometry.pivot_dx", 2.195, 2.3, {}, {"mechanism": 2, "geometry.rod_length": 3.0}),
    ("rod.cage_inertia", 5e-7, 1e-6, {}, {"machine": KVO}),
    ("rod.flex_length", 0.023, 0.02, {}, {"machine": KVO}),
    ("rod.damping_ratio", 0.05, 0.1, {}, {"machine": KVO}),
    ("geometry.rod_length", 1.19, 1.3, {"machine": KVO}, {}),
]


def _outputs(fmu, names, values, omega, n=90):
    """Every output at n + 1 points of one revolution at constant speed."""
    rows = np.empty((n + 1, len(names)))
    fmu.start(values)
    ch = fmu.channel(["crank.angle", "crank.speed"], names)
    ch.set_inputs([0.0, omega])
    ch.read(rows[0])
    h = 2 * math.pi / omega / n
    for k in range(1, n + 1):
        ch.step(k * h, [omega * (k - 1) * h, omega], rows[k])
    return rows


def test_parameters_that_cannot_act_are_exactly_those_the_rule_names(fmu_path, model_description):
    """Issue 24, finding 3: varying support_C.tilt of the unb600a gland gave bit-identical results.
    For each rule of study.inert_in, the FMU is run with two values of the parameter where the
    rule says it cannot act (every output at every point identical, bit for bit) and where the
    rule says it acts (some output differs)."""
    from reciprocating_drive.fmu import Fmu
    from reciprocating_drive.presets import preset_values
    from reciprocating_drive.sweeps.study import inert_in, model_parameters

    variables, _, _ = model_parameters(fmu_path)
    names = [v.name for v in model_description.modelVariables if v.causality == "output"]
    fmu = Fmu(fmu_path)
    for name, v1, v2, inert_cfg, acting_cfg in CLAIMS:
        for cfg, inert in ((inert_cfg, True), (acting_cfg, False)):
            cfg = dict(cfg)
            base = {k: v.start for k, v in variables.items()}
            preset = preset_values(cfg.pop("machine", "default"))
            omega = float(preset.pop("crank.speed", 2 * math.pi * 65 / 60))
            preset.pop("crank.angle", None)
            values = {**base, **preset, **cfg}
            said = inert_in(values)
            assert (name in said) == inert, (name, cfg, said.get(name))
            a = _outputs(fmu, names, {**values, name: v1}, omega)
            b = _outputs(fmu, names, {**values, name: v2}, omega)
            same = np.array_equal(a, b)
            assert same == inert, (name, cfg, "identical" if same else "different")


def test_sweep_warns_of_a_parameter_that_cannot_act(fmu_path, tmp_path):
    """The gland's tilt of unb600a varied with the clamp's offset: the command says in its output,
    in the plot and in the Parquet table's metadata that the tilt cannot act; the offset acts."""
    import pyarrow.parquet as pq

    f = tmp_path / "gland.toml"
    f.write_text(
        'name = "gland"\nmachine = "unb600a-simplex"\nskip_revolutions = 0\nsteps_per_revolution = 60\n'
        '[parameters]\n"support_C.tilt" = { values = [0.0, 1e-3] }\n'
        '"support_A.offset" = { values = [0.0, 1e-4] }\n'
    )
    p = subprocess.run(
        [
            sys.executable,
            str(ROOT / "scripts" / "sweep.py"),
            str(f),
            "--fmu",
            fmu_path,
            "--out-dir",
            str(tmp_path / "o"),
            "--no-progress",
            "--workers",
            "1",
        ],  # fmt: skip
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert p.returncode == 0, p.stderr
    warn = [ln for ln in p.stdout.splitlines() if ln.startswith("warning: ")]
    assert len(warn) == 1 and "support_C.tilt cannot act" in warn[0], p.stdout
    meta = pq.read_schema(tmp_path / "o" / "gland.parquet").metadata
    assert b"support_C.tilt cannot act" in meta[b"warnings"]
    rows = load_rows(tmp_path / "o" / "gland.csv", load_study(f))
    # The claim holds in the results: same numbers for both tilts, different for both offsets.
    by = {(r["support_C.tilt"], r["support_A.offset"]): r["friction_work"] for r in rows}
    assert by[(0.0, 0.0)] == by[(1e-3, 0.0)] and by[(0.0, 1e-4)] == by[(1e-3, 1e-4)]
    assert by[(0.0, 0.0)] != by[(0.0, 1e-4)]


def test_plot_uses_display_units_and_drops_all_zero_panels():
    """Issue 24, finding 7: axes in display units, no offset notation, no panel for a metric that
    is 0 in every case (sk8's guide friction: a single clamp) but a line saying why."""
    from reciprocating_drive.sweeps.plots import plot_sweep

    study = study_from_dict(
        {
            "machine": "sk8-3.5-4000",
            "metrics": ["guide_friction_max", "stress_max"],
            "parameters": {"support_A.offset": {"values": [0.0, 1e-4, 2e-4]}},
        }
    )
    rows = [
        {
            "case": i,
            "support_A.offset": x,
            "guide_friction_max": 0.0,
            "stress_max": 3.0e8 + 1e-3 * i,
            "status": "ok",
        }  # fmt: skip
        for i, x in enumerate([0.0, 1e-4, 2e-4])
    ]
    fig = plot_sweep(study, rows)
    fig.canvas.draw()
    panels = [ax for ax in fig.axes if ax.axison]
    assert len(panels) == 1
    ax = panels[0]
    assert ax.get_xlabel() == "support_A.offset [mm]"
    assert ax.get_ylabel() == "largest rod stress [MPa]"
    assert ax.yaxis.get_offset_text().get_text() == ""
    ticks = [float(t.get_text().replace("−", "-")) for t in ax.get_xticklabels() if t.get_text()]
    assert 0.15 <= max(ticks) <= 0.3, ticks  # 0.2 mm, not 0.0002 m
    texts = " ".join(t.get_text() for t in fig.texts)
    assert "no guide friction: a single clamp (support A) holds the link" in texts
