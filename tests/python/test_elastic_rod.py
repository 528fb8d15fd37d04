"""The elastic connecting rod of docs/model.md §6 through fmpy (issue 5), against an independent
solution: rod_reference.py codes §6 (A1-A3, fundamental functions, W*, ē, d̄, K_ϑ, K_Δ, C3, C4, the
cage equation, the stress), the piston law, the loads of §4 and the statically determinate link of
kvo630 (§5.3-5.4) apart from production, solves P by brentq at every evaluation and integrates the
cage equation with scipy's DOP853 at rtol 1e-11 on the same exact crank motion.

Tolerances. The FMU integrates to tol = solver.tolerance (1e-8 in kvo630), used as relative
tolerance and as absolute tolerance on ϑ [rad] and on ϑ̇/Ω0 (§6). With |ϑ| < 0.05 rad the absolute
part dominates, so one tolerance unit on ϑ is atol + rtol·max|ϑ| = tol·(1 + max|ϑ|), and on ϑ̇ it
is Ω0 times that. The brief's bound on rod.angle, 1e-7 rad, is ten such units; the reference's own
error is checked to be < 1e-9 rad (rtol 1e-11 against 1e-13). Outputs that are functions of the
state (rod.force through the friction, rod.stress_max, the guide reaction and moment) are compared
with the angle tolerance propagated through the reference's own sensitivity ∂y/∂ϑ (central
differences), plus 1e-12 of their scale for rounding.

Run with `pytest -s` to see the key numbers (scripts/rod_report.py adds the timing comparison).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from fmpy.fmi2 import FMU2Slave
from reciprocating_drive.presets import preset_values  # noqa: E402
from rod_reference import SERIES_CUT, Buckled, Drive, Motion, Rod, fundamental  # noqa: E402

KVO = preset_values("kvo630")
W = KVO["crank.speed"]  # 2π·1500/60
ANGLE_TOL = 1e-7  # rad, the brief's bound on rod.angle (10 tolerance units of the FMU, see above)
STATE_OUTPUTS = [
    "rod.force",
    "rod.stress_max",
    "guide.reaction",
    "guide.moment",
    "guide.friction",
    "rod.axial_deflection",
]
OUTPUTS = ["rod.angle", "rod.angular_velocity"] + STATE_OUTPUTS


# ------------------------------------------------------------------------------ FMU driver


def run_fmu(
    md,
    unzipdir,
    values: dict,
    motion: Motion,
    t_end: float,
    h: float,
    outputs=OUTPUTS,
    tolerance=None,
    f_ext=0.0,
    eps_input=True,
):
    """Sets `values` in initialization mode, the crank inputs θ(t_k), ω(t_k), ε at every
    communication point t_k = k·h (θ, ω from `motion`, exact), steps to t_end; returns the times
    and the outputs at t_0 = 0 (after initialization) and after each step. `eps_input=False`
    withholds crank.acceleration (left at 0) as a master that does not supply it would."""
    vr = {v.name: v.valueReference for v in md.modelVariables}
    types = {v.name: v.type for v in md.modelVariables}
    fmu = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzipdir,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="elastic rod",
    )
    fmu.instantiate()
    try:
        fmu.setupExperiment(tolerance=tolerance, startTime=0.0)
        fmu.enterInitializationMode()
        for name, value in values.items():
            if types[name] == "Real":
                fmu.setReal([vr[name]], [float(value)])
            elif types[name] == "Integer":
                fmu.setInteger([vr[name]], [int(value)])
            else:
                fmu.setBoolean([vr[name]], [bool(value)])
        ins = [vr["crank.angle"], vr["crank.speed"], vr["crank.acceleration"]]

        def crank(t):
            th, w, e = motion.at(t)
            return [th, w, e if eps_input else 0.0]

        fmu.setReal(ins + [vr["link.external_force"]], crank(0.0) + [f_ext])
        fmu.exitInitializationMode()
        n = int(round(t_end / h))
        out_vr = [vr[o] for o in outputs]
        rows = [fmu.getReal(out_vr)]
        for k in range(n):
            t = k * h
            fmu.setReal(ins, crank(t))
            fmu.doStep(t, h)
            rows.append(fmu.getReal(out_vr))
        fmu.terminate()
    finally:
        fmu.freeInstance()
    y = np.array(rows)
    return np.arange(n + 1) * h, {o: y[:, i] for i, o in enumerate(outputs)}


def unit(tol: float, theta_max: float) -> float:
    """One tolerance unit on ϑ of the FMU's error control: atol + rtol·max|ϑ| (§6)."""
    return tol * (1.0 + theta_max)


def sensitivity(drive: Drive, motion: Motion, times, y, names, d=1e-6) -> dict:
    """max over the samples of |∂y/∂ϑ| of each output (central differences in the reference)."""
    out = {n: 0.0 for n in names}
    for t, th, rt in zip(times, y[0], y[1]):
        k = drive.kinematics(*motion.at(t))
        hi, lo = drive.outputs(k, th + d, rt), drive.outputs(k, th - d, rt)
        for n in names:
            out[n] = max(out[n], abs(hi[n] - lo[n]) / (2 * d))
    return out


@functools.cache
def kvo630_reference(t_end: float, h: float, rtol: float = 1e-11):
    d, m = Drive(KVO), Motion(W)
    times = np.arange(int(round(t_end / h)) + 1) * h
    sol = d.integrate(m, times, rtol=rtol, atol_theta=rtol * 1e-3)
    return times, sol.y, d.outputs_along(m, times, sol.y)


# ------------------------------------------------------------------------------ the reference itself


def test_reference_reproduces_the_textbook_limits_of_section_6():
    """The independent §6 code reproduces the limits docs/model.md §6 lists (so a disagreement with
    the FMU points at the FMU): Euler-Bernoulli (A1 → ∞, P → 0), shear at P = 0, the
    clamped-pinned buckling load with shear, the clamp loads of a beam clamped at both ends, and a
    continuous switch between the power series and the closed forms."""
    rod = Rod.from_values(KVO)
    l, f, EJ = rod.l, rod.f, rod.a2
    eb = Rod.from_values(KVO)
    eb.a1 = 1e30
    c = eb.column(1e-12)
    assert c.w_star == pytest.approx(l**4 / 12, rel=1e-12)
    assert c.k_theta == pytest.approx(EJ * (4 / l + 12 * f / l**2 + 12 * f**2 / l**3), rel=1e-12)
    assert c.k_delta == pytest.approx(EJ * (6 / l**2 + 12 * f / l**3), rel=1e-12)
    eb.f = 0.0
    c = eb.column(0.0)
    assert c.k_delta / c.k_theta == pytest.approx(3 / (2 * l), rel=1e-13)  # propped cantilever
    c3, c4 = eb.constants(c, 1e-3, 0.0)  # beam clamped at both ends, end offset Δ (§5.5)
    assert (c3, c4) == (
        pytest.approx(6e-3 / l**2, rel=1e-13),
        pytest.approx(-12e-3 / l**3, rel=1e-13),
    )
    # Shear, P = 0, f = 0.
    sh = Rod.from_values(KVO)
    sh.f = 0.0
    phi = 12 * EJ / (sh.a1 * l**2)
    assert sh.column(0.0).k_theta == pytest.approx(EJ * (4 + phi) / (l * (1 + phi)), rel=1e-13)
    # Buckling of the clamped-pinned column with shear (f = 0): tan(κl) = κl/(1 + P/A1).
    from scipy.optimize import brentq

    def g(P):
        kap = math.sqrt(P * (1 + P / sh.a1) / EJ)
        return math.tan(kap * l) - kap * l / (1 + P / sh.a1)

    # κl between π and 3π/2 (the clamped-pinned root 4.49 without shear)
    lo = brentq(lambda P: math.sqrt(P * (1 + P / sh.a1) / EJ) * l - 1.0001 * math.pi, 1e-9, 1e6)
    hi = brentq(
        lambda P: math.sqrt(P * (1 + P / sh.a1) / EJ) * l - 0.9999 * 1.5 * math.pi, 1e-9, 1e6
    )
    p_cr = brentq(g, lo, hi, xtol=1e-14)
    assert 0 < sh.column(p_cr * (1 - 1e-7)).k_theta < 1e-5 * sh.column(0.0).k_theta
    with pytest.raises(Buckled):
        sh.column(p_cr * (1 + 1e-7))
    # Series vs closed forms across the switch, both signs of x.
    z = rod.l
    for sign in (1, -1):
        x_in, x_out = sign * SERIES_CUT / z**2 * (1 - 2e-15), sign * SERIES_CUT / z**2 * (1 + 2e-15)
        a, b = fundamental(x_in, z), fundamental(x_out, z)
        for u, v in zip(a, b):
            assert u == pytest.approx(v, rel=1e-13)
    # The kvo630 rod (f > 0) buckles at ~33 N compression: bisection on "column() raises".
    lo, hi = 0.0, 100.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        try:
            rod.column(mid)
            lo = mid
        except Buckled:
            hi = mid
    p_kvo = lo
    print(
        f"\nkvo630 rod: A1 = {rod.a1:.6g} N, A2 = {rod.a2:.6g} N·m², A3 = {rod.a3:.6g} N, "
        f"buckling load {p_kvo:.6g} N"
    )
    assert 25.0 < p_kvo < 40.0


# ------------------------------------------------------------------------------ kvo630, full model


def test_kvo630_preset_against_independent_solution(model_description, unzipdir):
    """The full kvo630 preset (P = 14.7 N + inertia + guide friction, quasi-static start) over
    0.24 s = 6 revolutions at 1500 rpm, h = 1 ms, crank θ = ωt: every communication point."""
    t_end, h = 0.24, 1e-3
    times, y, ref = kvo630_reference(t_end, h)
    # The reference's own error is far below the tolerance: rtol 1e-11 against 1e-13.
    _, y_fine, _ = kvo630_reference(t_end, h, 1e-13)
    assert np.abs(y[0] - y_fine[0]).max() < 1e-9
    t, got = run_fmu(model_description, unzipdir, KVO, Motion(W), t_end, h)
    assert np.allclose(t, times, rtol=0, atol=1e-15)
    d = Drive(KVO)
    err = np.abs(got["rod.angle"] - ref["rod.angle"])
    assert err.max() <= ANGLE_TOL, (
        f"rod.angle: max error {err.max():.3e} rad at t = {t[err.argmax()]}"
    )
    # ϑ̇: the same tolerance in the FMU's scaling of the rate, ϑ̇/Ω0 (Ω0 at P = 0).
    err_rate = np.abs(got["rod.angular_velocity"] - ref["rod.angular_velocity"])
    assert err_rate.max() <= ANGLE_TOL * d.omega0, (
        f"rod.angular_velocity: {err_rate.max():.3e} rad/s"
    )
    sens = sensitivity(d, Motion(W), times, y, STATE_OUTPUTS)
    for n in STATE_OUTPUTS:
        e = np.abs(got[n] - ref[n])
        bound = ANGLE_TOL * sens[n] + 1e-12 * np.abs(ref[n]).max()
        assert e.max() <= bound, (
            f"{n}: max error {e.max():.3e} > {bound:.3e} (|∂/∂ϑ| ≤ {sens[n]:.3e})"
        )
    # Not trivially satisfied: the cage really swings, the friction is really on.
    assert np.abs(ref["rod.angle"]).max() > 0.03 and np.abs(ref["guide.friction"]).max() > 0.01
    print(
        f"\nkvo630 vs reference: max |Δϑ| = {err.max():.2e} rad, max |Δϑ̇| = {err_rate.max():.2e} rad/s, "
        f"max |ΔP| = {np.abs(got['rod.force'] - ref['rod.force']).max():.2e} N, "
        f"max |Δτ| = {np.abs(got['rod.stress_max'] - ref['rod.stress_max']).max():.3g} Pa"
    )


def test_kvo630_key_results(model_description, unzipdir):
    """Numbers for the closing note (pytest -s), both from the FMU and from the reference: the
    steady-state cage amplitude max|ϑ| over the last revolution of 0.5 s (the transient has
    decayed: 1/(ζΩ0) = 13 ms) and the largest coil stress."""
    t_end, h = 0.5, 1e-3
    times, y, ref = kvo630_reference(t_end, h)
    t, got = run_fmu(model_description, unzipdir, KVO, Motion(W), t_end, h)
    last = t >= t_end - 2 * math.pi / W
    amp, amp_ref = np.abs(got["rod.angle"][last]).max(), np.abs(ref["rod.angle"][last]).max()
    tau, tau_ref = got["rod.stress_max"].max(), ref["rod.stress_max"].max()
    assert abs(amp - amp_ref) <= ANGLE_TOL
    sens = sensitivity(Drive(KVO), Motion(W), times, y, ["rod.stress_max"])["rod.stress_max"]
    assert abs(tau - tau_ref) <= ANGLE_TOL * sens + 1e-12 * tau_ref
    d = Drive(KVO)
    print(
        f"\nkvo630: damping time 1/(ζ·Ω0) = {2 * d.J / d.B * 1e3:.2f} ms; steady-state cage amplitude "
        f"max|ϑ| = {amp:.9f} rad (reference {amp_ref:.9f}); largest coil stress "
        f"max rod.stress_max = {tau / 1e6:.4f} MPa (reference {tau_ref / 1e6:.4f} MPa)"
    )


# ------------------------------------------------------------------------------ linear case


def linear_case(p_const: float) -> dict:
    v = dict(KVO)
    v.update(
        {
            "support_A.kind": 0,
            "support_B.kind": 0,
            "support_C.kind": 0,
            "mass.reciprocating": 0.0,
            "load.profile": 0,
            "load.amplitude": 0.0,
            "load.mean": p_const,
            "geometry.slider_offset": 0.0,
        }
    )
    return v


@pytest.mark.parametrize("tol", [None, 1e-10])
@pytest.mark.parametrize(
    "p_const", [14.7, 0.0, -20.0]
)  # compression (cos/sin), P = 0 (series), tension
def test_constant_load_reaches_the_exact_periodic_steady_state(
    model_description, unzipdir, p_const, tol
):
    """No friction, m = 0, P = load.mean constant, e = 0: J ϑ̈ + B ϑ̇ + K ϑ = K_Δ r sin(ωt), whose
    periodic solution is A·sin(ωt − φ), A = K_Δ r / sqrt((K − Jω²)² + (Bω)²), φ = atan2(Bω, K − Jω²),
    with K, K_Δ, B from the independent §6 code. Compared after 25 damping times 1/(ζΩ0) (the
    transient is then < e⁻²⁵ of its start) within 10 tolerance units."""
    v = linear_case(p_const)
    d = Drive(v)
    col = d.rod.column(p_const)
    K, KD, B, J, r = col.k_theta, col.k_delta, d.B, d.J, d.r
    amp = KD * r / math.hypot(K - J * W * W, B * W)
    phi = math.atan2(B * W, K - J * W * W)
    settle = 25 * 2 * J / B
    t_end, h = settle + 0.05, 1e-3
    t, got = run_fmu(
        model_description,
        unzipdir,
        v,
        Motion(W),
        t_end,
        h,
        ["rod.angle", "rod.angular_velocity"],
        tolerance=tol,
    )
    sel = t >= settle
    exact = amp * np.sin(W * t[sel] - phi)
    exact_rate = amp * W * np.cos(W * t[sel] - phi)
    tol_used = 1e-8 if tol is None else tol  # None: solver.tolerance of the preset
    assert KVO["solver.tolerance"] == 1e-8
    bound = 10 * unit(tol_used, amp)
    err = np.abs(got["rod.angle"][sel] - exact).max()
    err_rate = np.abs(got["rod.angular_velocity"][sel] - exact_rate).max()
    assert err <= bound, f"rod.angle: {err:.3e} > {bound:.3e} (amplitude {amp:.6f} rad)"
    assert err_rate <= bound * d.omega0, (
        f"rod.angular_velocity: {err_rate:.3e} > {bound * d.omega0:.3e}"
    )
    # P really is the constant load (no inertia, no friction).
    assert amp > 0.02


# ------------------------------------------------------------------------------ communication step


def test_result_does_not_depend_on_the_communication_step(model_description, unzipdir):
    """kvo630 with h = 1e-4, 1e-3 and 1e-2 s: ϑ at the common points t = 0, 0.01, ..., 0.2 s agree
    within ten tolerance units tol·(1 + max|ϑ|) (the FMU integrates inside each step with error
    control, §6 "across any communication step size")."""
    tol = KVO["solver.tolerance"]
    common = {}
    for h in (1e-4, 1e-3, 1e-2):
        t, got = run_fmu(model_description, unzipdir, KVO, Motion(W), 0.2, h, ["rod.angle"])
        stride = int(round(1e-2 / h))
        common[h] = got["rod.angle"][::stride]
        assert np.allclose(t[::stride], np.arange(21) * 1e-2, rtol=0, atol=1e-12)
    theta_max = max(np.abs(a).max() for a in common.values())
    bound = 10 * unit(tol, theta_max)
    for a, b in ((1e-4, 1e-3), (1e-3, 1e-2), (1e-4, 1e-2)):
        diff = np.abs(common[a] - common[b]).max()
        assert diff <= bound, f"h = {a} vs {b}: {diff:.3e} > {bound:.3e}"
    # The comparison is not vacuous: at t = 0.01 s ... 0.2 s the cage swings through ±0.04 rad.
    assert theta_max > 0.03


# ------------------------------------------------------------------------------ speed ramp


def test_speed_ramp_with_acceleration_input(model_description, unzipdir):
    """ω = ω0 + εt (ω0 = 100 rad/s, ε = 400 rad/s²: 955 to 1872 rpm in 0.24 s) with crank.angle,
    crank.speed and crank.acceleration supplied at every point: the FMU's in-step extrapolation
    θ + ωτ + ετ²/2 is then the exact motion, which the reference also follows. Negative control:
    withholding crank.acceleration (left at 0, an approximated ramp) changes ϑ by far more than the
    tolerance, so this test would notice ε being ignored."""
    motion = Motion(100.0, 400.0)
    t_end, h = 0.24, 1e-3
    d = Drive(KVO)
    times = np.arange(int(round(t_end / h)) + 1) * h
    sol = d.integrate(motion, times)
    ref = d.outputs_along(motion, times, sol.y)
    t, got = run_fmu(model_description, unzipdir, KVO, motion, t_end, h)
    err = np.abs(got["rod.angle"] - ref["rod.angle"]).max()
    assert err <= ANGLE_TOL, f"rod.angle: {err:.3e}"
    err_rate = np.abs(got["rod.angular_velocity"] - ref["rod.angular_velocity"]).max()
    assert err_rate <= ANGLE_TOL * d.omega0
    sens = sensitivity(d, motion, times, sol.y, ["rod.force", "rod.stress_max"])
    for n in ("rod.force", "rod.stress_max"):
        e = np.abs(got[n] - ref[n]).max()
        assert e <= ANGLE_TOL * sens[n] + 1e-12 * np.abs(ref[n]).max(), f"{n}: {e:.3e}"
    _, no_eps = run_fmu(
        model_description, unzipdir, KVO, motion, t_end, h, ["rod.angle"], eps_input=False
    )
    assert np.abs(no_eps["rod.angle"] - ref["rod.angle"]).max() > 10 * ANGLE_TOL
