"""The elastic rod's cage integrator delivers `solver.tolerance` in proportion (docs/model.md §6
"Integration", docs/performance.md "The elastic rod"): for communication steps of 0.01, 0.1, 1 and
10 ms and tolerances 1e-6 to 1e-10, the errors of `rod.angle` and `rod.angular_velocity`, each
relative to its own amplitude (max|ϑ|, max|ϑ̇| of the reference), stay below FACTOR·tol, so they fall
with the tolerance.

Cases: the kvo630 preset (helical spring, guide friction with its kinks where an edge force changes
sign), the thin rod (rod.kind 1 with a 2 mm wire: Ω0 = 15 300 rad/s, a hundred times the crank's
speed, so hΩ0 ≈ 1.5 at 0.1 ms) and the eccentric case (rod.load_eccentricity 13 mm without the
guide, as the validity-warning tests of tests/elastic_rod.rs: the cage sits at about 0.3 rad and
swings around it), all at 1 500 strokes/min for 0.05 s (1.25 revolutions, the start transient, both
dead centres and the friction's kinks).

Reference: rod_reference.py (the specification coded again in plain Python, P by brentq) integrated
by scipy's DOP853 at rtol 1e-13 on the exact crank motion: no code and no integrator shared with the
FMU. Its own error is bounded by a second method, scipy's Radau (implicit, of another family) at
rtol 1e-12: they agree to below 1e-10 of each amplitude, far below the smallest bound checked
(FACTOR·1e-10).

FACTOR: the FMU's tolerance is absolute in rad on ϑ (and tol·|ω| on ϑ̇), so against amplitudes of
0.04 rad one tolerance unit is already 25·tol of the amplitude; the errors are global (summed over
the steps of a damping time 1/(ζΩ0)) and the guide friction's kinks, where a step's embedded
estimate sees less than the error it makes, add to them. The largest measured ratio is about
320 (kvo630's rate at 1 ms and 1e-10; docs/performance.md "The elastic rod" has the table);
FACTOR = 500 leaves room for other machines' rounding. Before the rate's tolerance followed the
crank's speed and Verner 6(5) took the short steps too, the thin rod's rate reached 11 000·tol at
0.1 ms and tolerance 1e-9.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from reciprocating_drive.presets import preset_values
from rod_reference import Drive, Motion
from scipy.integrate import solve_ivp
from test_elastic_rod import run_fmu

KVO = preset_values("kvo630")
W = KVO["crank.speed"]  # 2π·1500/60
CASES = {
    "kvo630": dict(KVO),
    "thin rod": dict(KVO, **{"rod.kind": 1, "rod.wire_diameter": 0.002}),
    "eccentric": dict(KVO, **{"rod.load_eccentricity": 0.013, "support_B.kind": 0}),
}
T_END = 0.05
GRID = 1e-4  # the reference's sampling; every run is compared at the multiples of max(h, GRID)
STEPS = (1e-5, 1e-4, 1e-3, 1e-2)
TOLERANCES = (1e-6, 1e-8, 1e-9, 1e-10)
FACTOR = 500.0


@functools.cache
def reference(case: str, method: str = "DOP853", rtol: float = 1e-13) -> np.ndarray:
    """ϑ, ϑ̇ at the multiples of GRID up to T_END (rows), from the quasi-static start."""
    d, m = Drive(CASES[case]), Motion(W)
    times = np.arange(int(round(T_END / GRID)) + 1) * GRID
    sol = solve_ivp(
        d.rhs(m),
        (0.0, T_END),
        list(d.initial_state(m)),
        method=method,
        t_eval=times,
        rtol=rtol,
        atol=[1e-16, 1e-16 * d.omega0],
    )
    assert sol.success, sol.message
    return sol.y


def relative_errors(case: str, h: float, got: dict) -> tuple[float, float]:
    ref = reference(case)
    amp = np.abs(ref).max(axis=1)
    every_ref = max(1, int(round(h / GRID)))
    every_run = max(1, int(round(GRID / h)))
    errs = []
    for i, name in enumerate(("rod.angle", "rod.angular_velocity")):
        run = got[name][::every_run]
        errs.append(np.abs(run - ref[i][::every_ref]).max() / amp[i])
    return errs[0], errs[1]


@pytest.mark.parametrize("case", list(CASES))
def test_the_reference_agrees_with_a_second_method(case):
    a, b = reference(case), reference(case, "Radau", 1e-12)
    amp = np.abs(a).max(axis=1)
    diff = np.abs(a - b).max(axis=1) / amp
    assert (diff < 1e-10).all(), f"{case}: DOP853 1e-13 vs Radau 1e-12: {diff}"
    # Not trivial: the cage swings (and, eccentric, sits far from 0).
    assert amp[0] > 0.03 and amp[1] > 5.0, amp


@pytest.mark.parametrize("case", list(CASES))
def test_errors_fall_with_the_tolerance_at_every_communication_step(
    model_description, unzipdir, case
):
    rows, failures = [], []
    for h in STEPS:
        by_tol = {}
        for tol in TOLERANCES:
            values = dict(CASES[case], **{"solver.tolerance": tol})
            _, got = run_fmu(
                model_description,
                unzipdir,
                values,
                Motion(W),
                T_END,
                h,
                ["rod.angle", "rod.angular_velocity"],
            )
            e_angle, e_rate = relative_errors(case, h, got)
            by_tol[tol] = (e_angle, e_rate)
            rows.append(
                f"{case:9s} h {h * 1e3:5.2f} ms tol {tol:.0e}: angle {e_angle:.2e} "
                f"({e_angle / tol:6.1f}·tol), rate {e_rate:.2e} ({e_rate / tol:6.1f}·tol)"
            )
            for what, e in (("rod.angle", e_angle), ("rod.angular_velocity", e_rate)):
                if not e <= FACTOR * tol:
                    failures.append(f"{what} h = {h * 1e3:g} ms, tol {tol:g}: {e / tol:.0f}·tol")
        # Tightening the tolerance never makes the result worse.
        loose, tight = by_tol[TOLERANCES[0]], by_tol[TOLERANCES[-1]]
        for i, what in enumerate(("rod.angle", "rod.angular_velocity")):
            if not tight[i] <= loose[i] * (1 + 1e-6) + 1e-14:
                failures.append(
                    f"{what} h = {h * 1e3:g} ms: {tight[i]:.2e} at 1e-10 > {loose[i]:.2e}"
                )
    print("\n" + "\n".join(rows))
    assert not failures, f"{case}: errors beyond {FACTOR:g}·tol of the amplitude: " + "; ".join(
        failures
    )
