"""The sweep's fast path (sweeps/cases.py: the native batch driver, set-up reused across a batch,
metrics vectorised over the batch) against the reference path it replaces (cases.run_case: one
FMU call per step from Python, metrics through summarize_revolutions one run at a time): every
row of every example study, of rejected cases and of every metric on every machine is the same
bit for bit (but for the timings). docs/sweeps.md "Speed"."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from conftest import ROOT
from reciprocating_drive.sweeps import cases as sweep_cases
from reciprocating_drive.sweeps import sweep
from reciprocating_drive.sweeps.cases import OUTPUTS, _summary_metrics
from reciprocating_drive.sweeps.study import load_study, study_from_dict
from reciprocating_drive.sweeps.sweep import run_batch

ALL_METRICS = [
    "friction_work",
    "torque_peak",
    "torque_max",
    "torque_min",
    "acceleration_max",
    "acceleration_max_angle",
    "acceleration_min",
    "inertia_force_max",
    "inertia_force_min",
    "guide_friction_max",
    "guide_friction_min",
    "rod_force_max",
    "rod_force_max_angle",
    "rod_force_min",
    "rod_angle_amplitude",
    "stress_max",
]


def bits(v):
    """A value as its exact bits (a float's sign of zero and NaN included)."""
    return struct.pack("<d", v) if isinstance(v, float) else v


def assert_rows_equal(fast: list[dict], ref: list[dict]) -> None:
    assert len(fast) == len(ref)
    for a, b in zip(fast, ref):
        keys = [k for k in b if not k.startswith("seconds_")]
        assert [k for k in a if not k.startswith("seconds_")] == keys
        for k in keys:
            assert bits(a[k]) == bits(b[k]), (a["case"], k, a[k], b[k], a["message"])


@pytest.fixture
def no_reference(monkeypatch):
    """The reference path made unusable: a test that passes with it runs the fast path."""

    def refuse(*a, **k):
        raise AssertionError("the per-step reference path ran")

    monkeypatch.setattr(sweep, "run_case", refuse)
    monkeypatch.setattr(sweep_cases, "run_case", refuse)


@pytest.mark.parametrize("name", sorted(p.stem for p in (ROOT / "studies").glob("*.toml")))
def test_every_row_of_an_example_study_equals_the_reference_bit_for_bit(fmu_path, name):
    st = load_study(ROOT / "studies" / f"{name}.toml", fmu=fmu_path)
    cases = list(range(st.n_cases))
    ref = run_batch(fmu_path, st, cases, reference=True)
    assert all(r["status"] == "ok" for r in ref)
    assert_rows_equal(run_batch(fmu_path, st, cases), ref)


def test_the_example_studies_need_no_per_step_path(fmu_path, no_reference):
    """Every case of the examples goes through the native driver and the batched metrics."""
    for p in sorted((ROOT / "studies").glob("*.toml")):
        st = load_study(p, fmu=fmu_path)
        rows = run_batch(fmu_path, st, list(range(st.n_cases)))
        assert all(r["status"] == "ok" for r in rows)


@pytest.mark.parametrize(
    "machine,skip,revs,steps,spm,mass",
    [("default", 0, 2, 90, 700, 600), ("unb600a-simplex", 0, 1, 120, 700, 600),
     ("sk8-3.5-4000", 1, 2, 72, 700, 6000), ("kvo630", 3, 2, 180, 3000, 0.04)],
)  # fmt: skip
def test_every_metric_on_every_machine_equals_the_reference(
    fmu_path, machine, skip, revs, steps, spm, mass
):
    """A random design over the speed and the mass: 16 metrics, several revolutions per case
    (and on kvo630 cases whose steps the FMU rejects)."""
    st = study_from_dict(
        {
            "name": "all",
            "machine": machine,
            "skip_revolutions": skip,
            "revolutions": revs,
            "steps_per_revolution": steps,
            "metrics": ALL_METRICS,
            "design": {"kind": "random", "samples": 12, "seed": 3},
            "parameters": {
                "strokes_per_minute": {"min": 30, "max": spm},
                "mass.reciprocating": {"min": mass / 12, "max": mass},
            },
        },
        fmu=fmu_path,
    )
    cases = list(range(st.n_cases))
    ref = run_batch(fmu_path, st, cases, reference=True)
    assert sum(r["status"] == "ok" for r in ref) >= 4
    assert_rows_equal(run_batch(fmu_path, st, cases), ref)


def _rejected_study(fmu_path):
    """rod_length 0.15 m < crank radius 0.2 m: the linkage cannot assemble."""
    return study_from_dict(
        {
            "name": "rejected",
            "machine": "default",
            "skip_revolutions": 0,
            "revolutions": 1,
            "steps_per_revolution": 120,
            "metrics": ["friction_work", "torque_peak"],
            "parameters": {
                "mass.reciprocating": {"values": [200.0, 300.0]},
                "geometry.rod_length": {"values": [1.19, 0.15, 1.3]},
            },
        },
        fmu=fmu_path,
    )


def test_rejected_cases_have_the_reference_rows_and_messages(fmu_path, monkeypatch):
    """The native call stops at fmi2ExitInitializationMode (8) of a rejected case; the reference
    path makes its row, the next cases go on natively."""
    st = _rejected_study(fmu_path)
    cases = list(range(st.n_cases))
    ref = run_batch(fmu_path, st, cases, reference=True)
    assert [r["status"] for r in ref] == ["ok", "error", "ok"] * 2
    assert "geometry.rod_length" in ref[1]["message"]
    calls, native = [], sweep_cases._Prepared.run

    def spy(self, groups, first, count, *a):
        done = native(self, groups, first, count, *a)
        calls.append((first, count, done, self.fail.function))
        return done

    monkeypatch.setattr(sweep_cases._Prepared, "run", spy)
    assert_rows_equal(run_batch(fmu_path, st, cases), ref)
    assert calls == [(0, 6, 1, 8), (2, 4, 2, 8), (5, 1, 1, 0)]


def _steps_fail_study(fmu_path):
    """kvo630 at 3000 strokes/min: a reciprocating mass of 0.5 or 2 kg loads the spring rod so
    that the FMU fails in the middle of the run (fmi2DoStep at steps 29 and 24), the others run."""
    return study_from_dict(
        {
            "name": "mid",
            "machine": "kvo630",
            "skip_revolutions": 0,
            "revolutions": 2,
            "steps_per_revolution": 90,
            "metrics": ["rod_angle_amplitude", "stress_max", "friction_work"],
            "parameters": {
                "strokes_per_minute": {"values": [3000.0]},
                "mass.reciprocating": {"values": [0.02, 0.03, 0.5, 2.0, 0.04, 0.01]},
            },
        },
        fmu=fmu_path,
    )


def test_a_case_failing_in_the_middle_of_a_native_batch(fmu_path, monkeypatch):
    """One native call runs the batch's cases; it stops at the case whose fmi2DoStep fails, the
    reference path runs that one case (its row and the FMU's message), and the next cases go on
    natively: only the failing cases reach the per-step path, every row equals the reference's."""
    st = _steps_fail_study(fmu_path)
    cases = list(range(st.n_cases))
    ref = run_batch(fmu_path, st, cases, reference=True)
    assert [r["status"] for r in ref] == ["ok", "ok", "error", "error", "ok", "ok"]
    assert "fmi2DoStep" in ref[2]["message"]
    ran, calls = [], []
    run_case, native = sweep_cases.run_case, sweep_cases._Prepared.run

    def counted(fmu, study, params):
        ran.append(params["mass.reciprocating"])
        return run_case(fmu, study, params)

    def spy(self, groups, first, count, *a):
        done = native(self, groups, first, count, *a)
        calls.append((first, count, done, self.fail.function, self.fail.step))
        return done

    monkeypatch.setattr(sweep_cases, "run_case", counted)
    monkeypatch.setattr(sweep_cases._Prepared, "run", spy)
    fast = run_batch(fmu_path, st, cases)
    assert ran == [0.5, 2.0]
    # fmi2DoStep (1) failed at step 29 of case 2 and at step 24 of case 3.
    assert calls == [(0, 6, 2, 1, 29), (3, 3, 0, 1, 24), (4, 2, 2, 0, 0)]
    assert_rows_equal(fast, ref)


def test_a_non_finite_output_makes_an_error_row_not_a_failed_batch(fmu_path, monkeypatch):
    """A NaN or an infinity among a case's outputs (put into the native driver's output array
    after its call, as an FMU returning one with fmi2OK would), also in an output no metric
    reads: the case's row is an error naming the output, the value and the point, from the
    reference summary (cases._summary_metrics, which summarize_revolutions would fail in with an
    IndexError); the other rows of the batch are the reference's."""
    st = load_study(ROOT / "studies" / "default_balancer.toml", fmu=fmu_path)
    assert "rod.stress_max" not in {q for m in st.metrics for q in sweep_cases._SERIES[m]}
    put = {2: ("crank.torque", 50, math.nan), 4: ("rod.stress_max", 60, -math.inf)}
    native = sweep_cases._Prepared.run

    def spoil(self, groups, first, count, omega, h, data, seconds):
        done = native(self, groups, first, count, omega, h, data, seconds)
        for c, (name, k, v) in put.items():
            if first <= c < first + done:
                data[c, k, OUTPUTS.index(name)] = v
        return done

    cases = list(range(7))
    ref = run_batch(fmu_path, st, cases, reference=True)
    monkeypatch.setattr(sweep_cases._Prepared, "run", spoil)
    fast = run_batch(fmu_path, st, cases)
    for c, (name, k, v) in put.items():
        r = fast[c]
        assert r["status"] == "error" and f"the FMU returned {name} = {v} at t = " in r["message"]
        assert f"(communication point {k}); allowed: finite values" in r["message"]
        assert all(math.isnan(r[m]) for m in st.metrics)
        ref[c] = {**ref[c], **{m: math.nan for m in st.metrics}}
        ref[c].update(status="error", message=r["message"])
    assert_rows_equal(fast, ref)


def _typed_study(fmu_path):
    """Integer and Boolean parameters (their values written as 1, -1, 0, 1 in a row) beside an
    Integer range (floats) and a Real's values."""
    return study_from_dict(
        {
            "name": "typed",
            "machine": "default",
            "skip_revolutions": 0,
            "revolutions": 1,
            "steps_per_revolution": 60,
            "metrics": ["torque_peak", "friction_work"],
            "parameters": {
                "rotation": {"values": [-1, 1]},
                "balancer.enabled": {"values": [False, True]},
                "load.profile": {"start": 0, "stop": 2, "num": 2},
                "mass.reciprocating": {"values": [250.0, 300.0]},
            },
        },
        fmu=fmu_path,
    )


@pytest.mark.parametrize(
    "doc",
    [
        {"parameters": {"mass.reciprocating": {"start": 100.0, "stop": 700.0, "num": 7},
                        "geometry.rod_length": {"values": [1.19, 1.3, 1.25]},
                        "strokes_per_minute": {"start": 0.3, "stop": 0.1, "num": 3},
                        "crank.angle_offset": {"start": 0.25, "stop": 0.25, "num": 1}}},
        {"design": {"kind": "random", "samples": 40, "seed": 11},
         "parameters": {"mass.reciprocating": {"min": 100.0, "max": 700.0},
                        "strokes_per_minute": {"min": 10, "max": 90}}},
        {"design": {"kind": "lhs", "samples": 40, "seed": 5},
         "parameters": {"mass.reciprocating": {"min": 100.0, "max": 700.0},
                        "crank.speed": {"min": 1, "max": 9}}},
    ],
    ids=["grid", "random", "lhs"],
)  # fmt: skip
def test_case_array_is_every_case_bit_for_bit(fmu_path, doc):
    """Study.case_array (a batch's values at once) against Study.case (one case), on cases in
    runs with gaps and out of order; and the speeds of the batch against cases._speed."""
    st = study_from_dict({"name": "arr", **doc}, fmu=fmu_path)
    ids = [0, 1, 2, 5, 6, 7, 8, 20, 19, 3, st.n_cases - 1]
    got = st.case_array(ids)
    assert st.floats_only
    for k, i in enumerate(ids):
        want = st.case(i)
        assert [bits(v) for v in got[k].tolist()] == [bits(v) for v in want.values()], i
        assert bits(float(sweep_cases.speeds(st, got)[k])) == bits(sweep_cases._speed(st, want))
    with pytest.raises(IndexError):
        st.case_array([st.n_cases])


def test_case_array_of_integer_and_boolean_values(fmu_path):
    st = _typed_study(fmu_path)
    assert not st.floats_only
    got = st.case_array(range(st.n_cases))
    for i in range(st.n_cases):
        assert got[i].tolist() == [float(v) for v in st.case(i).values()]


def _reference_text(fmu_path, st, cases, text: str) -> str:
    """What csv.writer writes for the reference path's rows (the columns of the result file,
    fingerprint "f-p"), their timings taken from `text` (they differ from run to run)."""
    import csv
    import io

    cols = sweep.columns(st)
    timing = [cols.index("seconds_fmu"), cols.index("seconds_case")]
    got = list(csv.reader(io.StringIO(text, newline="")))
    assert len(got) == len(cases)
    lines = []
    for r, g in zip(run_batch(fmu_path, st, cases, reference=True), got):
        row = [int(v) if isinstance(v, bool) else v for v in (r[k] for k in cols[:-1])] + ["f-p"]
        for j in timing:
            row[j] = float(g[j])  # repr's digits read back exactly
        lines.append(row)
    buf = io.StringIO()
    csv.writer(buf).writerows(lines)
    return buf.getvalue()


@pytest.mark.parametrize("which", ["unb600a_friction", "default_balancer", "rejected", "steps",
                                   "typed"])  # fmt: skip
def test_a_dask_tasks_lines_are_csv_writers_byte_for_byte(fmu_path, which):
    """run_batch_csv's text (numbers by the native formatter) is, byte for byte, what
    csv.writer writes for the reference rows: repr of every float, NaN metrics of rejected rows,
    the FMU's messages quoted, integers and booleans as before."""
    if which == "rejected":
        st = _rejected_study(fmu_path)
    elif which == "steps":
        st = _steps_fail_study(fmu_path)
    elif which == "typed":
        st = _typed_study(fmu_path)
    else:
        st = load_study(ROOT / "studies" / f"{which}.toml", fmu=fmu_path)
    cases = list(range(st.n_cases))[::-1][:40]
    text, n, inside, seconds = sweep.run_batch_csv(fmu_path, st, cases, False, sweep.columns(st),
                                                   "f-p")  # fmt: skip
    assert n == len(cases) and 0 < inside <= seconds
    if which in ("rejected", "steps"):
        assert ",error," in text
    if which == "steps":
        assert ',error,"fmi2DoStep returned fmi2Error: ' in text  # a message with commas, quoted
    assert text == _reference_text(fmu_path, st, cases, text)


def synthetic(rng, n_runs: int, n: int, steps: int):
    """Runs of smooth random outputs whose model angle starts anywhere in (−2π, 0] and advances
    unevenly (a crank that speeds up and slows down), at random step sizes."""
    h = rng.uniform(1e-4, 1e-2, n_runs)
    data = np.empty((n_runs, n, len(OUTPUTS)))
    k = np.arange(n)
    for c in range(n_runs):
        dth = 2 * math.pi / steps * (1 + 0.3 * np.sin(k / rng.uniform(5, 40)))
        data[c, :, 0] = -rng.uniform(0, 2 * math.pi) + np.concatenate([[0], np.cumsum(dth[1:])])
        for j in range(1, len(OUTPUTS)):
            a = rng.normal(size=4) * 10.0 ** rng.uniform(-3, 4)
            data[c, :, j] = a[0] * np.sin(k / steps * 2 * math.pi * (j % 3 + 1) + a[1]) + a[2]
            data[c, :, j] += a[3] * 1e-3 * rng.normal(size=n)
    return h, data


def test_batched_metrics_equal_the_reference_on_synthetic_runs():
    """Independent of the FMU: uneven angles, arbitrary starts, noisy outputs, ties (a constant
    output), and runs the batch must leave to the reference (NaN, infinity, an angle that falls
    back, too few revolutions)."""
    rng = np.random.default_rng(7)
    steps, skip, revs = 50, 1, 3
    n = (skip + revs + 1) * steps
    h, data = synthetic(rng, 40, n, steps)
    data[3, :, OUTPUTS.index("guide.friction")] = 0.0  # every sample a tie
    data[4, :, OUTPUTS.index("crank.torque")] = -0.0
    data[5, 100, 3] = math.nan
    data[6, 17, 6] = math.inf
    data[7, 60, 0] = data[7, 59, 0] - 1e-3  # the angle decreases once
    data[8, :, 0] *= 0.5  # not enough revolutions
    st = study_from_dict(
        {
            "name": "synthetic",
            "skip_revolutions": skip,
            "revolutions": revs,
            "steps_per_revolution": steps,
            "metrics": ALL_METRICS,
            "parameters": {"mass.reciprocating": {"values": [1.0]}},
        }
    )
    values, good = sweep_cases.batch_metrics(h, data, st, OUTPUTS)
    assert not good[[5, 6, 7, 8]].any()
    assert good.sum() >= 30
    for c in np.flatnonzero(good):
        ref = _summary_metrics(st, np.arange(n) * h[c], data[c])
        got = dict(zip(st.metrics, values[c].tolist()))
        assert {k: bits(v) for k, v in got.items()} == {k: bits(v) for k, v in ref.items()}, c


def test_a_dask_task_returns_the_lines_the_client_wrote_before(fmu_path):
    """run_batch_csv's text is what csv.DictWriter wrote from the reference rows (but for the
    timings), rejected cases included."""
    import csv
    import io

    st = load_study(ROOT / "studies" / "default_balancer.toml", fmu=fmu_path)
    cols = sweep.columns(st)
    cases = [0, 5, 30]
    text, n, inside, seconds = sweep.run_batch_csv(fmu_path, st, cases, False, cols, "f-p")
    assert n == 3 and 0 < inside <= seconds
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols)
    for r in run_batch(fmu_path, st, cases, reference=True):
        w.writerow({k: "f-p" if k == "fingerprint" else r[k] for k in cols})
    timing = [cols.index("seconds_fmu"), cols.index("seconds_case")]

    def cells(s):
        return [
            [c for j, c in enumerate(row) if j not in timing] for row in csv.reader(io.StringIO(s))
        ]

    assert cells(text) == cells(buf.getvalue())
    assert text.endswith("\r\n") and text.count("\r\n") == 3
