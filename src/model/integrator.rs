//! Adaptive integrator of the cage equation (docs/model.md §6, "Cage equation", "Integration").
//!
//! The FMU's continuous state is y = (ϑ, ϑ̇) of
//! `J_m ϑ̈ + B_d ϑ̇ + K_ϑ(P)·ϑ = K_Δ(P)·Δ + e_P·P + m_f·f_m·Δ̈`: a lightly damped oscillator
//! (Ω0 ≈ 1500 rad/s for kvo630, 5–100× the crank frequency, ζ ≈ 0.05) whose coefficients vary with
//! the crank angle and, through guide friction, weakly with ϑ. The caller supplies ϑ̈ through
//! [`SecondOrderRhs`]; [`advance`] integrates across one communication step with error control.
//!
//! # Method: Verner's "most efficient" 6(5) pair (9 stages, FSAL)
//!
//! J. H. Verner, "RKV65.IIIXb Efficient" (coefficients from Verner's pages at SFU, as in
//! jacobwilliams/rklib `rkv65e`): 6th-order solution, 5th-order embedded estimate, local
//! extrapolation, the 9th stage is the derivative at the new point (first same as last), so a
//! step costs 8 new RHS evaluations and the end point of every step, including the last one of a
//! communication step, is evaluated: an end state at which the RHS fails (buckling) is never
//! accepted. The coefficients are checked in the tests against all order conditions up to order 6
//! (rooted trees), independently of where they were copied from.
//!
//! WHY this pair: each RHS evaluation costs a `BeamColumn::new` plus the caller's load/friction
//! evaluation, so RHS evaluations per simulated second decide the cost. Measured on the kvo630
//! problem (docs/model.md §8: P = 14.7 N + inertia, J_m = 5e-7, ζ = 0.05, ω = 2π·1500/60, started
//! quasi-statically), tolerance 1e-8 (relative and absolute on ϑ and ϑ̇/Ω0), RHS evaluations per
//! simulated second for communication steps h_c (same controller for all candidates):
//!
//! | pair                        | h_c = 0.1 ms | h_c = 1 ms | h_c = 10 ms | 1 ms, tol 1e-10 |
//! |-----------------------------|-------------:|-----------:|------------:|----------------:|
//! | Dormand–Prince 5(4)         |       70 000 |     19 000 |      14 800 |          40 600 |
//! | Tsitouras 5(4)              |       70 000 |     19 000 |      12 400 |          34 700 |
//! | **Verner 6(5) efficient**   |       90 000 | **17 000** |      14 100 |          33 000 |
//! | Verner 7(6) efficient       |      100 000 |     20 000 |      12 300 |          30 000 |
//! | Dormand–Prince 8(5,3) DOP853|      120 000 |     24 000 |      13 700 |          31 100 |
//!
//! At the design point (1 ms, 1e-8) the step the error control allows is 0.4–0.9 ms for every
//! pair, so each communication step takes two internal steps and the cost is set by the stages
//! per step: Verner 6(5) is cheapest there (1 + 2·8 = 17 evaluations), and within 15 % of the
//! best pair at the other points. The high-order pairs do not reach a 1 ms step: the forced
//! response (amplitude ~0.04 rad against an absolute tolerance of 1e-8) is integrated through
//! terms like (hΩ0)^k (hω)^m that do not shrink with the order when hΩ0 > 1. The observed global
//! error stays ~10× below the tolerance (DP5/Tsitouras reach ~1–2× tolerance).
//!
//! The elastic rod's caller does not integrate ϑ itself but φ = ϑ − c·Δ(τ), c = K_Δ/K_ϑ at the
//! step's start (drive/cage_step.rs, `CageRhs::shift`): the same equation, less the quasi-static part of
//! the forced response that those terms act on. On this problem (the shift as a wrapper of the
//! RHS, c from P at the start of each communication step) Verner 6(5) then needs 9 940 RHS
//! evaluations per simulated second at 1 ms (about 1.1 internal steps per call; 9 is the floor
//! of one step per call) and 8 290 at 10 ms; at 0.1 ms one step per call, 90 000, as before.
//! Compared again on φ (`model::drive` test `pairs_compared_on_the_shifted_cage_variable`,
//! docs/performance.md): at the same accuracy (1e-8 rad) Verner 6(5) needs 9.7 evaluations per
//! 1 ms step for the kvo630 spring, Tsitouras 5(4) about 12, Dormand–Prince 5(4) about 13.5 and
//! Verner 7(6) 11.4; at the same tolerance the 5(4) pairs make fewer evaluations but miss it 2 to
//! 6 times (they need a second step per call more often: error ∝ h⁵ instead of h⁶), and Verner
//! 7(6) (10 evaluations a step, not FSAL) is cheaper only below about 3e-9 rad.
//!
//! Verner 6(5) also integrates the shortest communication steps (0.1 ms and below), where one
//! internal step covers the call: Tsitouras 5(4) would save 2 of 9 evaluations there, but its
//! embedded estimate accepted steps of 0.1 ms across the kinks of the guide friction (where an
//! edge force changes sign) and at hΩ0 ≈ 1.5 (a thin rod) whose errors were 7 (kvo630) to 10
//! (thin rod) times Verner's, not falling with the tolerance
//! (tests/python/test_tolerance_proportionality.py, docs/performance.md "The elastic rod").
//!
//! Any pair can also run in Lawson's integrating-factor form with the RHS's frozen oscillator
//! treated exactly ([`Form::Lawson`], `lawson.rs`). On φ that is not
//! cheaper at the design point: the rest it integrates, e^(−τL)·N, turns at the cage frequency
//! (docs/performance.md "The elastic rod", work-precision diagram; study in
//! `model::drive::cage_step::work_precision`).
//!
//! Cost with the bare kvo630 RHS (BeamColumn::new ≈ 35 ns + crank trigonometry), release build:
//! ≈ 1.3 µs per 1 ms communication step (17 RHS evaluations, ≈ 76 ns each including the stage
//! arithmetic); with a costlier RHS the call costs ≈ 17 × RHS per 1 ms.
//!
//! # Step control
//!
//! Error norm: RMS over (ϑ, ϑ̇) of `h·Σ e_j k_j / (atol_i + rtol·max(|y0_i|, |y1_i|))`; accept when
//! ≤ 1. PI controller (Gustafsson; Hairer's DOPRI5 constants: safety 0.9, β = 0.04, growth within
//! [0.2, 10], no growth right after a rejection). A stage at which the RHS returns `Err` (or a
//! non-finite value) rejects the step and retries with a quarter of the step; only when the step
//! falls below ~16 ulp of t is the call given up, with the last stage error in the message.
//! Internal steps end exactly at t0 + h: when fewer than four steps remain they are made equal;
//! a step shortened for that reason does not reduce the suggestion kept in [`IntegratorState`]
//! unless its own error predicts that the suggested step would fail, so consecutive communication
//! steps keep the natural step; it raises the suggestion when its error supports a longer step
//! (`h·0.9·err^(−1/6)`, at most 10·h), so a suggestion that once fell (transient, rejection)
//! grows back instead of fixing the number of steps per call for good. No allocation on the success path; deterministic (the same
//! inputs and state give bit-identical results; all arithmetic is plain IEEE f64 in a fixed
//! order).

// The tableau keeps Verner's published digits (the compiler rounds them correctly), and the
// `!(x <= y)` tests are deliberate: they also catch NaN.
#![allow(clippy::excessive_precision, clippy::neg_cmp_op_on_partial_ord)]

pub mod lawson;

use crate::model::error::{num, ModelError};
use lawson::{ExpCache, Linear};
use serde::{Deserialize, Serialize};

/// Right-hand side of the second-order cage equation, `ϑ̈ = accel(t, ϑ, ϑ̇)`.
pub trait SecondOrderRhs {
    /// Returns ϑ̈ [rad/s²] at (t, ϑ, ϑ̇). `Err` rejects the stage (e.g. the rod buckles at a trial
    /// state, docs/model.md §6 "Validity"): the integrator shrinks the step and retries.
    fn accel(&mut self, t: f64, theta: f64, theta_dot: f64) -> Result<f64, ModelError>;

    /// The frozen linear part of ϑ̈, (Ω², 2a) of ϑ̈ ≈ −Ω²·ϑ − 2a·ϑ̇ + forcing, for the integrator
    /// forms that treat the oscillator exactly ([`Form::Lawson`]); queried at the start of the
    /// call and after each accepted step (an RHS may freeze it once per call or follow its last
    /// evaluation). None (the default): not known, the plain pair runs.
    fn linear_part(&self) -> Option<(f64, f64)> {
        None
    }
}

/// How a pair is applied (docs/performance.md "The elastic rod").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// The pair on y' = f(t, y).
    Plain,
    /// The pair in Lawson's integrating-factor form with the RHS's frozen oscillator
    /// ([`SecondOrderRhs::linear_part`]) treated exactly (`lawson.rs`); the plain pair where the
    /// RHS gives no underdamped linear part.
    Lawson,
}

/// Error tolerances (docs/model.md §6): `rtol` relative, `atol_theta` [rad] and `atol_rate` [rad/s]
/// absolute (`atol_rate = tol·ω_s`, ω_s the caller's frequency scale of the rate: the crank's speed
/// for the cage, drive/cage_step.rs `rate_scale`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    pub rtol: f64,
    pub atol_theta: f64,
    pub atol_rate: f64,
}

impl Tolerance {
    /// The §6 convention: `tol` (`solver.tolerance`) as relative tolerance and as absolute
    /// tolerance on ϑ [rad] and on ϑ̇/ω_s (`rate_scale` [rad/s]).
    pub fn from_solver_tolerance(tol: f64, rate_scale: f64) -> Tolerance {
        Tolerance { rtol: tol, atol_theta: tol, atol_rate: tol * rate_scale }
    }
}

/// Everything the integrator carries from one communication step to the next (part of the FMU
/// state: serializable, and sufficient for a bit-identical continuation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct IntegratorState {
    /// Suggested size of the next internal step [s]; 0 (the default) = unknown, an initial step
    /// is estimated from the RHS (Hairer's `hinit`, one extra evaluation).
    pub h_next: f64,
    /// Error norm of the last full (not end-shortened) accepted step, the memory of the PI
    /// controller; 0 = none yet.
    pub err_prev: f64,
}

/// Work counters (accumulated by successful [`advance`] calls only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IntegratorStats {
    /// RHS evaluations, including those of rejected steps.
    pub rhs_evals: u64,
    /// Accepted internal steps.
    pub steps: u64,
    /// Rejected internal steps (error test failed or a stage returned `Err`).
    pub rejected: u64,
}

// ---------------------------------------------------------------------------------------------
// Verner 6(5) "most efficient" pair, RKV65.IIIXb (coefficients as published by J. H. Verner).
// ---------------------------------------------------------------------------------------------

const STAGES: usize = 9;

const C: [f64; STAGES] = [
    0.0,
    3.0 / 50.0,
    1439.0 / 15000.0,
    1439.0 / 10000.0,
    4973.0 / 10000.0,
    389.0 / 400.0,
    1999.0 / 2000.0,
    1.0,
    1.0,
];

/// 6th-order weights; also the last row of A (FSAL).
const B: [f64; STAGES] = [
    0.03438957868357036009278820124728322386520,
    0.0,
    0.0,
    0.2582624555633503404659558098586120858767,
    0.4209371189673537150642551514069801967032,
    4.405396469669310170148836816197095664891,
    -176.4831190242986576151740942499002125029,
    172.3641334014150730294022582711902413315,
    0.0,
];

/// 5th-order embedded weights.
const B_HAT: [f64; STAGES] = [
    0.04909967648382489730906854927971225836479,
    0.0,
    0.0,
    0.2251112229516524153401395320539875329485,
    0.4694682253029562039431948525047387412553,
    0.8065792249988867707634161808995217981443,
    0.0,
    -0.6071194891777959797672951465256217122488,
    0.05686113944047569241147603178766138153594,
];

#[rustfmt::skip]
const A: [[f64; STAGES]; STAGES] = [
    [0.0; STAGES],
    [0.06, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [
        0.01923996296296296296296296296296296296296,
        0.07669337037037037037037037037037037037037,
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    ],
    [0.035975, 0.0, 0.107925, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [
        1.318683415233148260919747276431735612861,
        0.0,
        -5.042058063628562225427761634715637693344,
        4.220674648395413964508014358283902080483,
        0.0, 0.0, 0.0, 0.0, 0.0,
    ],
    [
        -41.87259166432751461803757780644346812905,
        0.0,
        159.4325621631374917700365669070346830453,
        -122.1192135650100309202516203389242140663,
        5.531743066200053768252631238332999150076,
        0.0, 0.0, 0.0, 0.0,
    ],
    [
        -54.43015693531650433250642051294142461271,
        0.0,
        207.0672513650184644273657173866509835987,
        -158.6108137845899991828742424365058599469,
        6.991816585950242321992597280791793907096,
        -0.01859723106220323397765171799549294623692,
        0.0, 0.0, 0.0,
    ],
    [
        -54.66374178728197680241215648050386959351,
        0.0,
        207.9528062553893734515824816699834244238,
        -159.2889574744995071508959805871426654216,
        7.018743740796944434698170760964252490817,
        -0.01833878590504572306472782005141738268361,
        -0.0005119484997882099077875432497245168395840,
        0.0, 0.0,
    ],
    B,
];

/// Error weights `B − B_HAT`.
const E: [f64; STAGES] = error_weights(B, B_HAT);

/// A pair's error weights: the solution's weights less the embedded ones (at compile time).
pub const fn error_weights<const S: usize>(b: [f64; S], b_hat: [f64; S]) -> [f64; S] {
    let mut e = [0.0; S];
    let mut i = 0;
    while i < S {
        e[i] = b[i] - b_hat[i];
        i += 1;
    }
    e
}

/// An embedded explicit Runge–Kutta pair. With `fsal` its last stage is the derivative at the
/// new point (the last row of `a` holds the solution's weights `b` and `c` ends at 1); without,
/// the derivative at the new point is one more evaluation after the step is accepted.
pub struct Pair<const S: usize> {
    pub c: [f64; S],
    pub a: [[f64; S]; S],
    /// The solution's weights.
    pub b: [f64; S],
    pub fsal: bool,
    /// Error weights: the solution's weights less the embedded ones.
    pub e: [f64; S],
    /// Order of the solution (for the initial step estimate).
    pub order: f64,
    /// 1/(q + 1), q the embedded order: the error estimate behaves like h^(q+1).
    pub est_exponent: f64,
}

/// Tsitouras 5(4), compared in the tests and the work-precision study (Ch. Tsitouras, Comput. Math. Appl. 62 (2011) 770–775; digits as in
/// diffrax's tableau).
pub const TSIT5_B: [f64; 7] = [
    0.09646076681806522951816731316512876333712,
    0.01,
    0.4798896504144995747752495322905965199130,
    1.379008574103741893192274821856872770756,
    -3.290069515436080679901047585711363850116,
    2.324710524099773982415355918398765796109,
    0.0,
];
pub const TSIT5_B_HAT: [f64; 7] = [
    0.09468075576583945807478876255758922856118,
    0.009183565540343253096776363936645313759814,
    0.4877705284247615707855642599631228241517,
    1.234297566930478985655109673884237654036,
    -2.707712349983525454881109975059321670690,
    1.866628418170587035753719399566211498666,
    1.0 / 66.0,
];
#[rustfmt::skip]
pub const TSIT5: Pair<7> = Pair {
    c: [0.0, 0.161, 0.327, 0.9, 0.9800255409045096857298102862870245954942, 1.0, 1.0],
    a: [
        [0.0; 7],
        [0.161, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [-0.008480655492356988544426874250230774675121, 0.3354806554923569885444268742502307746751, 0.0, 0.0, 0.0, 0.0, 0.0],
        [2.897153057105493432130432594192938764925, -6.359448489975074843148159912383825625953,
         4.362295432869581411017727318190886861028, 0.0, 0.0, 0.0, 0.0],
        [5.325864828439256604428877920840511317836, -11.74888356406282787774717033978577296189,
         7.495539342889836208304604784564358155659, -0.09249506636175524925650207933207191611350, 0.0, 0.0, 0.0],
        [5.861455442946420028659251486982647890394, -12.92096931784710929170611868178335939542,
         8.159367898576158643180400794539253485182, -0.07158497328140099722453054252582973869127,
         -0.02826905039406838290900305721271224146718, 0.0, 0.0],
        TSIT5_B,
    ],
    b: TSIT5_B,
    fsal: true,
    e: error_weights(TSIT5_B, TSIT5_B_HAT),
    order: 5.0,
    est_exponent: 1.0 / 5.0,
};

/// The pair the FMU integrates with (see the module doc).
pub const VERNER_65: Pair<STAGES> =
    Pair { c: C, a: A, b: B, fsal: true, e: E, order: 6.0, est_exponent: 1.0 / 6.0 };
const SAFETY: f64 = 0.9;
const FAC_MIN: f64 = 0.2;
const FAC_MAX: f64 = 10.0;
/// PI controller: factor `err^−(1/6 − 0.75β) · err_prev^β`.
const BETA: f64 = 0.04;
/// Floor of the controller's error memory (Hairer's `facold` floor).
const ERR_FLOOR: f64 = 1e-4;
/// Step reduction after a stage returned `Err`.
const STAGE_FAIL_FACTOR: f64 = 0.25;
/// Hard limit of internal steps per call (more means the tolerance cannot be met sensibly).
const MAX_STEPS_PER_CALL: u64 = 1_000_000;
/// Time scale [s] of the step-size floor (16 ulp of max(|t|, this)) and the shortest interval the
/// initial step estimate looks at: a communication step far below it (1e-300 s) must neither
/// fail nor leave a suggestion of its own size for the next call.
const TIME_SCALE: f64 = 1e-3;

#[inline]
fn eval(
    rhs: &mut impl SecondOrderRhs,
    t: f64,
    y: [f64; 2],
    stats: &mut IntegratorStats,
) -> Result<[f64; 2], ModelError> {
    stats.rhs_evals += 1;
    let acc = rhs.accel(t, y[0], y[1])?;
    if acc.is_finite() {
        Ok([y[1], acc])
    } else {
        Err(ModelError::evaluation(format!(
            "non-finite second derivative {} {} s into the step, state ({}, {})",
            num(acc),
            num(t),
            num(y[0]),
            num(y[1])
        )))
    }
}

#[inline]
fn scale(tol: &Tolerance, y0: [f64; 2], y1: [f64; 2]) -> [f64; 2] {
    [
        tol.atol_theta + tol.rtol * y0[0].abs().max(y1[0].abs()),
        tol.atol_rate + tol.rtol * y0[1].abs().max(y1[1].abs()),
    ]
}

// Always inlined: called from each pair's instance, it was otherwise left out of line (a call
// and its checks cost about 50 instructions more per step than inlined).
#[inline(always)]
fn validate(t0: f64, y0: [f64; 2], h: f64, tol: &Tolerance) -> Result<(), ModelError> {
    if !(t0.is_finite() && y0[0].is_finite() && y0[1].is_finite()) {
        return Err(ModelError::evaluation(format!(
            "rod cage equation: non-finite start t = {} s, rod.angle = {} rad, \
             rod.angular_velocity = {} rad/s",
            num(t0),
            num(y0[0]),
            num(y0[1])
        )));
    }
    if !(h.is_finite() && h > 0.0) {
        return Err(ModelError::out_of_range("communicationStepSize", h, "a finite number > 0 s"));
    }
    for v in [tol.rtol, tol.atol_theta, tol.atol_rate] {
        if !(v.is_finite() && v > 0.0) {
            return Err(ModelError::out_of_range(
                "solver.tolerance",
                v,
                "a finite number > 0 (relative and absolute tolerances of the rod integrator)",
            ));
        }
    }
    Ok(())
}

/// One step from (t, y) with `k[0] = f(t, y)` already set: fills the stages and returns the new
/// solution and the error estimate `Σ e_j k_j` (without the factor h). `k[8]` is f at the new
/// point (FSAL).
// Indices as in the tableau's notation (a_ij k_j), in a fixed order.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn step<const S: usize>(
    pair: &Pair<S>,
    rhs: &mut impl SecondOrderRhs,
    t: f64,
    y: [f64; 2],
    h: f64,
    k: &mut [[f64; 2]; S],
    stats: &mut IntegratorStats,
) -> Result<([f64; 2], [f64; 2]), ModelError> {
    let mut y_new = y;
    for i in 1..S {
        let mut yi = y;
        for j in 0..i {
            let aij = pair.a[i][j];
            if aij != 0.0 {
                yi[0] += h * aij * k[j][0];
                yi[1] += h * aij * k[j][1];
            }
        }
        if pair.fsal && i == S - 1 {
            y_new = yi; // last row of A = B
        }
        k[i] = eval(rhs, t + pair.c[i] * h, yi, stats)?;
    }
    if !pair.fsal {
        for j in 0..S {
            y_new[0] += h * pair.b[j] * k[j][0];
            y_new[1] += h * pair.b[j] * k[j][1];
        }
    }
    let mut est = [0.0_f64; 2];
    for j in 0..S {
        est[0] += pair.e[j] * k[j][0];
        est[1] += pair.e[j] * k[j][1];
    }
    Ok((y_new, est))
}

/// Advances y = (ϑ, ϑ̇) from `t0` to `t0 + h` (any h > 0; designed for 1e-5 s … 0.1 s) with error
/// control to `tol`, never returning an unconverged state.
///
/// `state` carries the suggested internal step between calls (start from
/// `IntegratorState::default()`); `stats` accumulates work. Both are updated only on success:
/// on `Err` (the RHS fails at the start point, or the step size underflows because the RHS keeps
/// failing or the tolerance cannot be met) the caller's `state` and `stats` are untouched
/// (the function works on copies), as docs/model.md §6 requires for a failed fmi2DoStep.
pub fn advance(
    rhs: &mut impl SecondOrderRhs,
    t0: f64,
    y0: [f64; 2],
    h: f64,
    tol: &Tolerance,
    state: &mut IntegratorState,
    stats: &mut IntegratorStats,
) -> Result<[f64; 2], ModelError> {
    #[cfg(test)]
    if let Some(r) =
        tests::compared::advance_with_pair_under_test(rhs, t0, y0, h, tol, state, stats)
    {
        return r;
    }
    advance_with(&VERNER_65, Form::Plain, rhs, t0, y0, h, tol, state, stats)
}

/// [`advance`] with the pair `pair` (inlined, so that each pair's coefficients are constants)
/// in the form `form`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn advance_with<const S: usize>(
    pair: &Pair<S>,
    form: Form,
    rhs: &mut impl SecondOrderRhs,
    t0: f64,
    y0: [f64; 2],
    h: f64,
    tol: &Tolerance,
    state: &mut IntegratorState,
    stats: &mut IntegratorStats,
) -> Result<[f64; 2], ModelError> {
    // One instance per form: the plain one carries nothing of the Lawson form.
    match form {
        Form::Plain => advance_in::<S, false>(pair, rhs, t0, y0, h, tol, state, stats),
        Form::Lawson => advance_in::<S, true>(pair, rhs, t0, y0, h, tol, state, stats),
    }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn advance_in<const S: usize, const LAWSON: bool>(
    pair: &Pair<S>,
    rhs: &mut impl SecondOrderRhs,
    t0: f64,
    y0: [f64; 2],
    h: f64,
    tol: &Tolerance,
    state: &mut IntegratorState,
    stats: &mut IntegratorStats,
) -> Result<[f64; 2], ModelError> {
    validate(t0, y0, h, tol)?;
    let mut work = *stats;
    let t_end = t0 + h;
    let mut t = t0;
    let mut y = y0;
    let mut k = [[0.0_f64; 2]; S];
    // The start point must be valid: no step size can repair it.
    k[0] = eval(rhs, t, y, &mut work)?;
    // The frozen oscillator (queried again after each accepted step; kept across a rejection).
    let frozen = |rhs: &mut _| {
        if LAWSON {
            SecondOrderRhs::linear_part(rhs).and_then(|(w2, d)| Linear::new(w2, d))
        } else {
            None
        }
    };
    let mut lin: Option<Linear> = frozen(rhs);
    // Made on the first Lawson step only (the plain path sets up nothing).
    let mut cache: Option<ExpCache<S>> = None;

    let mut h_try = state.h_next;
    if !(h_try.is_finite() && h_try > 0.0) {
        h_try = initial_step(rhs, t, y, k[0], h.max(TIME_SCALE), tol, pair.order, &mut work);
    }
    let mut err_prev = if state.err_prev > 0.0 { state.err_prev } else { ERR_FLOOR };
    let mut last_rejected = false;
    let mut last_failure: Option<ModelError> = None;
    let alpha = pair.est_exponent - 0.75 * BETA;
    let mut n_steps: u64 = 0;

    'steps: while t < t_end {
        let remaining = t_end - t;
        let h_min = 16.0 * f64::EPSILON * t.abs().max(t_end.abs()).max(TIME_SCALE);
        // The remaining interval itself is always a step the integrator may try (a communication
        // step below the floor, e.g. 1e-300 s, is one step to its end).
        if !(h_try >= h_min || h_try >= remaining) || n_steps >= MAX_STEPS_PER_CALL {
            let why = match &last_failure {
                Some(e) => format!("; last rejected stage: {e}"),
                None => String::new(),
            };
            // Times are relative to the start of the communication step (the caller, which
            // knows the absolute time, names the interval).
            let reason = if n_steps >= MAX_STEPS_PER_CALL {
                format!("the internal step limit of {MAX_STEPS_PER_CALL} steps per communication step is reached")
            } else if n_steps == 0 && h_try >= 16.0 * f64::EPSILON * t.abs().max(TIME_SCALE) {
                // Nothing failed: the floor is set by the interval's end time alone.
                format!(
                    "communicationStepSize = {} s is too long: at its end time internal steps \
                     of {} s cannot be resolved",
                    num(h),
                    num(h_try)
                )
            } else {
                format!("the step size fell to {} s", num(h_try))
            };
            return Err(ModelError::evaluation(format!(
                "the integrator cannot meet solver.tolerance (rtol = {}) within the step: {reason} \
                 at {} s after the start of the step{why}",
                num(tol.rtol),
                num(t - t0)
            )));
        }
        n_steps += 1;
        let (h, to_end) = if h_try >= remaining {
            (remaining, true)
        } else if h_try * 4.0 >= remaining {
            // Near the end: equal steps instead of full steps and a short rest.
            (remaining / (remaining / h_try).ceil(), false)
        } else {
            (h_try, false)
        };
        let shortened = h < h_try;

        // A failing stage (or, without FSAL, a failing evaluation at the new point) rejects the
        // step: one path for both, below.
        let attempt = 'attempt: {
            let stepped = match &lin {
                Some(l) => {
                    let cache = cache.get_or_insert_with(ExpCache::default);
                    lawson::step(pair, l, cache, rhs, t, y, h, &mut k, &mut work)
                }
                None => step(pair, rhs, t, y, h, &mut k, &mut work),
            };
            let (y_new, est) = match stepped {
                Ok(v) => v,
                Err(e) => break 'attempt Err(e),
            };
            let sc = scale(tol, y, y_new);
            let err = h * (0.5 * ((est[0] / sc[0]).powi(2) + (est[1] / sc[1]).powi(2))).sqrt();
            if !(err <= 1.0) {
                // Rejected (NaN included).
                work.rejected += 1;
                let fac = if err.is_finite() {
                    (SAFETY * err.powf(-pair.est_exponent)).clamp(FAC_MIN, 1.0)
                } else {
                    FAC_MIN
                };
                h_try = h * fac;
                last_rejected = true;
                continue 'steps;
            }
            // The derivative at the new point: the last stage of an FSAL pair, else one more
            // evaluation.
            if pair.fsal {
                Ok((y_new, err, k[S - 1]))
            } else {
                eval(rhs, if to_end { t_end } else { t + h }, y_new, &mut work)
                    .map(|f| (y_new, err, f))
            }
        };
        let (y_new, err, f_new) = match attempt {
            Ok(v) => v,
            Err(e) => {
                work.rejected += 1;
                last_failure = Some(e);
                h_try = h * STAGE_FAIL_FACTOR;
                last_rejected = true;
                continue 'steps;
            }
        };
        work.steps += 1;
        let err_c = err.max(ERR_FLOOR);
        let mut fac = (SAFETY * err_c.powf(-alpha) * err_prev.powf(BETA)).clamp(FAC_MIN, FAC_MAX);
        if last_rejected {
            fac = fac.min(1.0);
        }
        if shortened {
            // Keep the natural step unless this step's error predicts that it would fail, but
            // let it grow when the error of this (shorter) step allows a longer one: otherwise
            // a suggestion that once fell (a transient, a rejection) could never recover while
            // every step is an equal split of the communication step (with h_c = 1 ms and a
            // suggestion of 0.32 ms the kvo630 run stayed at 4 steps per call for good).
            // Only within the controller's own range of factors: a step far shorter than the
            // suggestion (the rest of a 1e-300 s communication step) predicts nothing about it.
            let predicted = if err > 0.0 && h * FAC_MAX >= h_try {
                h * SAFETY * err.powf(-pair.est_exponent)
            } else {
                f64::INFINITY
            };
            let supported = predicted.min(FAC_MAX * h);
            h_try = if supported > h_try { supported } else { h_try.min(predicted.max(h * fac)) };
        } else {
            h_try = h * fac;
            err_prev = err_c;
        }
        last_rejected = false;
        t = if to_end { t_end } else { t + h };
        y = y_new;
        k[0] = f_new;
        lin = frozen(rhs);
    }
    state.h_next = h_try;
    state.err_prev = err_prev;
    *stats = work;
    Ok(y)
}

/// Shortest trial step [s] of [`initial_step`]'s difference quotient (1e-6 of TIME_SCALE).
const MIN_FIRST_TRIAL: f64 = 1e-6 * TIME_SCALE;

/// Initial step (Hairer, Nørsett & Wanner, Solving ODE I, II.4 "hinit"): from the sizes of y,
/// f(y) and a difference quotient of f; one extra RHS evaluation.
#[allow(clippy::too_many_arguments)] // the step's context, as `advance_with` has it
fn initial_step(
    rhs: &mut impl SecondOrderRhs,
    t: f64,
    y: [f64; 2],
    f0: [f64; 2],
    remaining: f64,
    tol: &Tolerance,
    order: f64,
    stats: &mut IntegratorStats,
) -> f64 {
    let sc = scale(tol, y, y);
    let rms = |v: [f64; 2]| (0.5 * ((v[0] / sc[0]).powi(2) + (v[1] / sc[1]).powi(2))).sqrt();
    let d0 = rms(y);
    let d1 = rms(f0);
    // Not below MIN_FIRST_TRIAL: a y at the level of rounding (the cage's φ = ϑ − c·Δ at a
    // quasi-static start, against the tolerance tol·|ω| of φ̇ at tol = 1e-13) is not "small
    // against f", and 0.01·d0/d1 then gave 4e-20 s, a difference quotient of rounding noise and a
    // first step below the step-size floor.
    let h0 = if d0 < 1e-5 || d1 < 1e-5 { 1e-6 } else { (0.01 * d0 / d1).max(MIN_FIRST_TRIAL) }
        .min(remaining);
    let y1 = [y[0] + h0 * f0[0], y[1] + h0 * f0[1]];
    let d2 = match eval(rhs, t + h0, y1, stats) {
        Ok(f1) => rms([f1[0] - f0[0], f1[1] - f0[1]]) / h0,
        // The trial point is invalid: start small, the step control takes over.
        Err(_) => return 0.1 * h0,
    };
    let dm = d1.max(d2);
    let h1 =
        if dm <= 1e-15 { (h0 * 1e-3).max(1e-6) } else { (0.01 / dm).powf(1.0 / (order + 1.0)) };
    (100.0 * h0).min(h1).min(remaining)
}

#[cfg(test)]
pub(crate) mod tests {
    //! Tests of the cage-equation integrator, each against an independent reference.
    #![allow(clippy::needless_range_loop)]
    use super::*;
    use crate::model::elastic_rod::{BeamColumn, RodKind, RodSpec, RodStiffness};
    use std::f64::consts::PI;

    // -----------------------------------------------------------------------------------------
    // Coefficients: order conditions (rooted trees, Butcher), independent of the integrator
    // -----------------------------------------------------------------------------------------

    /// A rooted tree: its children as (order, index into the list of trees of that order),
    /// sorted, so every unordered tree appears exactly once.
    type Tree = Vec<(usize, usize)>;

    fn generate(
        all: &[Vec<Tree>],
        rem: usize,
        min: (usize, usize),
        cur: &mut Tree,
        out: &mut Vec<Tree>,
    ) {
        if rem == 0 {
            out.push(cur.clone());
            return;
        }
        for ord in min.0..=rem {
            let start = if ord == min.0 { min.1 } else { 0 };
            for idx in start..all[ord].len() {
                cur.push((ord, idx));
                generate(all, rem - ord, (ord, idx), cur, out);
                cur.pop();
            }
        }
    }

    fn trees_up_to(max: usize) -> Vec<Vec<Tree>> {
        let mut all: Vec<Vec<Tree>> = vec![Vec::new(); max + 1];
        all[1].push(Vec::new());
        for n in 2..=max {
            let mut out = Vec::new();
            generate(&all, n - 1, (1, 0), &mut Vec::new(), &mut out);
            all[n] = out;
        }
        all
    }

    /// Largest residual |b·Φ(t) − 1/γ(t)| over the trees of each order 1..=max, for the
    /// weights `b` with the stages of `a`.
    fn order_residuals<const S: usize>(a: &[[f64; S]; S], b: &[f64; S], max: usize) -> Vec<f64> {
        let all = trees_up_to(max);
        // Known counts of rooted trees (OEIS A000081) validate the enumeration.
        let counts: Vec<usize> = all.iter().skip(1).map(|v| v.len()).collect();
        assert_eq!(counts, [1, 1, 2, 4, 9, 20, 48][..max].to_vec());
        let mut phi: Vec<Vec<[f64; S]>> = vec![Vec::new(); max + 1];
        let mut gamma: Vec<Vec<f64>> = vec![Vec::new(); max + 1];
        let mut res = vec![0.0_f64; max + 1];
        for n in 1..=max {
            for t in &all[n] {
                let mut v = [1.0; S];
                let mut g = n as f64;
                for &(o, i) in t {
                    let child = &phi[o][i];
                    for s in 0..S {
                        let aw: f64 = (0..S).map(|j| a[s][j] * child[j]).sum();
                        v[s] *= aw;
                    }
                    g *= gamma[o][i];
                }
                let w: f64 = (0..S).map(|s| b[s] * v[s]).sum();
                res[n] = res[n].max((w - 1.0 / g).abs());
                phi[n].push(v);
                gamma[n].push(g);
            }
        }
        res
    }

    #[test]
    fn coefficients_satisfy_order_conditions() {
        // Consistency of the stage abscissae and the FSAL row.
        for i in 1..STAGES {
            let row: f64 = A[i].iter().sum();
            let mag: f64 = A[i].iter().map(|v| v.abs()).sum();
            assert!((row - C[i]).abs() <= 4.0 * f64::EPSILON * mag, "row {i}");
        }
        assert_eq!(A[STAGES - 1], B);
        // 6th order for B, 5th for B_HAT. Residual bound 1e-10: the published 40-digit
        // coefficients rounded to f64 (|a_ij| up to 208, |b_j| up to 176) leave ~3e-11.
        let rb = order_residuals(&A, &B, 7);
        let rh = order_residuals(&A, &B_HAT, 7);
        for n in 1..=6 {
            assert!(rb[n] < 1e-10, "B, order {n}: residual {:e}", rb[n]);
        }
        for n in 1..=5 {
            assert!(rh[n] < 1e-10, "B_HAT, order {n}: residual {:e}", rh[n]);
        }
        // And the test is sensitive: the next orders are violated.
        assert!(rb[7] > 1e-8 && rh[6] > 1e-6, "{rb:?} {rh:?}");
    }

    // -----------------------------------------------------------------------------------------
    // Closed-form damped forced oscillator
    // -----------------------------------------------------------------------------------------

    struct Forced {
        w0: f64,
        zeta: f64,
        a: f64,
        w: f64,
    }

    impl SecondOrderRhs for Forced {
        fn accel(&mut self, t: f64, th: f64, thd: f64) -> Result<f64, ModelError> {
            Ok(self.a * (self.w * t).cos()
                - 2.0 * self.zeta * self.w0 * thd
                - self.w0 * self.w0 * th)
        }
    }

    impl Forced {
        /// x'' + 2ζΩx' + Ω²x = a cos ωt, x(0) = x0, x'(0) = v0 (textbook solution).
        fn exact(&self, t: f64, x0: f64, v0: f64) -> [f64; 2] {
            let (w0, z, a, w) = (self.w0, self.zeta, self.a, self.w);
            let den = (w0 * w0 - w * w).powi(2) + (2.0 * z * w0 * w).powi(2);
            let zr = a * (w0 * w0 - w * w) / den;
            let zi = -a * 2.0 * z * w0 * w / den;
            let (sw, cw) = (w * t).sin_cos();
            let xp = zr * cw - zi * sw;
            let vp = -w * zr * sw - w * zi * cw;
            let wd = w0 * (1.0 - z * z).sqrt();
            let c1 = x0 - zr;
            let c2 = (v0 + w * zi + z * w0 * c1) / wd;
            let e = (-z * w0 * t).exp();
            let (sd, cd) = (wd * t).sin_cos();
            let xh = e * (c1 * cd + c2 * sd);
            let vh = e * ((-z * w0 * c1 + wd * c2) * cd + (-z * w0 * c2 - wd * c1) * sd);
            [xp + xh, vp + vh]
        }
    }

    /// max over both components of |error| / tolerance scale (ϑ: atol + rtol|ϑ|, ϑ̇ likewise).
    fn err_over_tol(tol: &Tolerance, y: [f64; 2], r: [f64; 2]) -> f64 {
        let s = scale(tol, r, r);
        ((y[0] - r[0]).abs() / s[0]).max((y[1] - r[1]).abs() / s[1])
    }

    #[test]
    fn damped_forced_oscillator_matches_closed_form() {
        // kvo630-like: Ω0 = 1500 rad/s, ζ = 0.05, forcing at the crank frequency with a static
        // response of 0.035 rad, started at rest (full transient). Over 1 s in 1 ms steps the
        // global error must stay within 10× the tolerance (errors are damped with ζΩ0 = 75/s).
        let mut f = Forced { w0: 1500.0, zeta: 0.05, a: 1500.0 * 1500.0 * 0.035, w: 157.08 };
        for &tolv in &[1e-6, 1e-8, 1e-10] {
            let tol = Tolerance::from_solver_tolerance(tolv, 1500.0);
            let mut st = IntegratorState::default();
            let mut stats = IntegratorStats::default();
            let mut y = [0.0, 0.0];
            let mut worst = 0.0_f64;
            for i in 0..1000 {
                y = advance(&mut f, i as f64 * 1e-3, y, 1e-3, &tol, &mut st, &mut stats).unwrap();
                let r = f.exact((i + 1) as f64 * 1e-3, 0.0, 0.0);
                worst = worst.max(err_over_tol(&tol, y, r));
            }
            println!("forced oscillator tol {tolv:e}: worst error/tol {worst:.3}, {stats:?}");
            assert!(worst < 10.0, "tol {tolv}: error {worst} x tol");
        }
    }

    // -----------------------------------------------------------------------------------------
    // The kvo630 cage equation (docs/model.md §8) and a fine-step RK4 reference
    // -----------------------------------------------------------------------------------------

    #[derive(Clone, Copy)]
    struct Kvo {
        st: RodStiffness,
        j: f64,
        b: f64,
        omega: f64,
        /// Optional stage failure: Err whenever |ϑ| exceeds this (a stand-in for buckling at a
        /// wild trial state).
        theta_limit: f64,
        /// Err for every evaluation at t > this (a rod that buckles for good).
        fail_after: f64,
        failures: u64,
    }

    const R: f64 = 1e-3;
    const L_F: f64 = 0.023;
    const F_RIGID: f64 = 0.015;

    impl Kvo {
        fn new() -> Kvo {
            let spec = RodSpec {
                kind: RodKind::HelicalSpring,
                flex_length: L_F,
                rigid_length: F_RIGID,
                wire_diameter: 1e-3,
                coil_diameter: 5e-3,
                coils: 8.0,
                e_modulus: 2.06e11,
                poisson: 0.304,
            };
            let st = RodStiffness::new(&spec).unwrap();
            let j = 5e-7;
            let k0 = BeamColumn::new(&st, L_F, F_RIGID, 0.0).unwrap().k_theta;
            Kvo {
                st,
                j,
                b: 2.0 * 0.05 * (k0 * j).sqrt(),
                omega: 2.0 * PI * 1500.0 / 60.0,
                theta_limit: f64::INFINITY,
                fail_after: f64::INFINITY,
                failures: 0,
            }
        }
        fn omega0(&self) -> f64 {
            (BeamColumn::new(&self.st, L_F, F_RIGID, 0.0).unwrap().k_theta / self.j).sqrt()
        }
        /// Δ, Δ̇, P at time t (crank at constant speed, θ = ωt; P = 14.7 N − m·rω²cosθ).
        fn load(&self, t: f64) -> (f64, f64, f64) {
            let (s, c) = (self.omega * t).sin_cos();
            (R * s, R * self.omega * c, 14.7 - 0.02 * R * self.omega * self.omega * c)
        }
        /// Quasi-static initial state (docs/model.md §6 "Initial state").
        fn initial(&self) -> [f64; 2] {
            let (d, dd, p) = self.load(0.0);
            let bc = BeamColumn::new(&self.st, L_F, F_RIGID, p).unwrap();
            [bc.k_delta * d / bc.k_theta, bc.k_delta * dd / bc.k_theta]
        }
        fn tol(&self, tolv: f64) -> Tolerance {
            Tolerance::from_solver_tolerance(tolv, self.omega0())
        }
    }

    impl SecondOrderRhs for Kvo {
        fn accel(&mut self, t: f64, th: f64, thd: f64) -> Result<f64, ModelError> {
            if th.abs() > self.theta_limit || t > self.fail_after {
                self.failures += 1;
                return Err(ModelError::evaluation(format!("test rod buckled at t = {t}")));
            }
            let (d, _, p) = self.load(t);
            let bc = BeamColumn::new(&self.st, L_F, F_RIGID, p)?;
            Ok((bc.k_delta * d - bc.k_theta * th - self.b * thd) / self.j)
        }
    }

    /// Classical RK4 with fixed steps (Ω0·dt = 3e-3: local error ~(Ω0 dt)^5/120 ≈ 2e-15 of the
    /// amplitude per step, global ~1e-12), sampled every `every` seconds.
    fn rk4(rhs: &mut impl SecondOrderRhs, y0: [f64; 2], t_end: f64, every: f64) -> Vec<[f64; 2]> {
        let per = ((every / 2e-6).round() as usize).max(1);
        let dt = every / per as f64;
        let n = (t_end / every).round() as usize;
        let mut f = |t: f64, y: [f64; 2]| [y[1], rhs.accel(t, y[0], y[1]).unwrap()];
        let mut y = y0;
        let mut out = vec![y];
        for i in 0..n {
            for k in 0..per {
                let t = i as f64 * every + k as f64 * dt;
                let k1 = f(t, y);
                let k2 = f(t + 0.5 * dt, [y[0] + 0.5 * dt * k1[0], y[1] + 0.5 * dt * k1[1]]);
                let k3 = f(t + 0.5 * dt, [y[0] + 0.5 * dt * k2[0], y[1] + 0.5 * dt * k2[1]]);
                let k4 = f(t + dt, [y[0] + dt * k3[0], y[1] + dt * k3[1]]);
                for c in 0..2 {
                    y[c] += dt / 6.0 * (k1[c] + 2.0 * k2[c] + 2.0 * k3[c] + k4[c]);
                }
            }
            out.push(y);
        }
        out
    }

    fn run_chunks(
        kvo: &mut Kvo,
        tol: &Tolerance,
        hc: f64,
        n: usize,
        st: &mut IntegratorState,
        stats: &mut IntegratorStats,
    ) -> Vec<[f64; 2]> {
        let mut y = kvo.initial();
        let mut out = vec![y];
        for i in 0..n {
            y = advance(kvo, i as f64 * hc, y, hc, tol, st, stats).unwrap();
            out.push(y);
        }
        out
    }

    #[test]
    fn kvo630_matches_fine_rk4_over_one_second() {
        let kvo = Kvo::new();
        let reference = rk4(&mut kvo.clone(), kvo.initial(), 1.0, 1e-3);
        for &tolv in &[1e-6, 1e-8] {
            let tol = kvo.tol(tolv);
            let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
            let ys = run_chunks(&mut kvo.clone(), &tol, 1e-3, 1000, &mut st, &mut stats);
            let worst = ys
                .iter()
                .zip(&reference)
                .map(|(y, r)| err_over_tol(&tol, *y, *r))
                .fold(0.0, f64::max);
            println!("kvo630 tol {tolv:e}, h = 1 ms: worst error/tol {worst:.3}, {stats:?}");
            assert!(worst < 10.0, "tol {tolv}: {worst}");
        }
    }

    /// Strongly parametric oscillator (stiffness ±30 % at the forcing frequency, plus a mildly
    /// nonlinear term) against the fine RK4.
    struct Parametric;
    impl SecondOrderRhs for Parametric {
        fn accel(&mut self, t: f64, th: f64, thd: f64) -> Result<f64, ModelError> {
            let w0 = 1200.0;
            let w = 130.0;
            let k = w0 * w0 * (1.0 + 0.3 * (w * t).sin());
            Ok(w0 * w0 * 0.03 * (w * t).sin() - 2.0 * 0.04 * w0 * thd - k * th - 5e5 * th * th * th)
        }
    }

    #[test]
    fn parametric_oscillator_matches_fine_rk4() {
        let y0 = [0.01, 0.0];
        let reference = rk4(&mut Parametric, y0, 1.0, 1e-3);
        let tol = Tolerance::from_solver_tolerance(1e-8, 1200.0);
        let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
        let mut y = y0;
        let mut worst = 0.0_f64;
        for i in 0..1000 {
            y = advance(&mut Parametric, i as f64 * 1e-3, y, 1e-3, &tol, &mut st, &mut stats)
                .unwrap();
            worst = worst.max(err_over_tol(&tol, y, reference[i + 1]));
        }
        println!("parametric: worst error/tol {worst:.3}, {stats:?}");
        assert!(worst < 10.0, "{worst}");
    }

    #[test]
    fn chunking_does_not_change_the_solution() {
        // 1e-4, 1e-3 and 1e-2 s communication steps agree at common times (every 10 ms) within
        // 10× the tolerance, and each agrees with the fine RK4.
        let kvo = Kvo::new();
        let tol = kvo.tol(1e-8);
        let t_end: f64 = 0.3;
        let reference = rk4(&mut kvo.clone(), kvo.initial(), t_end, 1e-2);
        let mut runs = Vec::new();
        for &hc in &[1e-4, 1e-3, 1e-2] {
            let n = (t_end / hc).round() as usize;
            let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
            let ys = run_chunks(&mut kvo.clone(), &tol, hc, n, &mut st, &mut stats);
            let stride = (1e-2 / hc).round() as usize;
            let sampled: Vec<[f64; 2]> = ys.iter().step_by(stride).copied().collect();
            assert_eq!(sampled.len(), reference.len());
            runs.push(sampled);
        }
        for i in 0..reference.len() {
            for a in 0..3 {
                assert!(err_over_tol(&tol, runs[a][i], reference[i]) < 10.0, "run {a} sample {i}");
                for b in 0..a {
                    assert!(
                        err_over_tol(&tol, runs[a][i], runs[b][i]) < 10.0,
                        "runs {a},{b} sample {i}"
                    );
                }
            }
        }
    }

    #[test]
    fn deterministic_and_bit_identical_continuation() {
        let kvo = Kvo::new();
        let tol = kvo.tol(1e-8);
        let go = |st: &mut IntegratorState, y0: [f64; 2], i0: usize, n: usize| {
            let mut r = Kvo::new();
            let mut stats = IntegratorStats::default();
            let mut y = y0;
            for i in i0..i0 + n {
                y = advance(&mut r, i as f64 * 1e-3, y, 1e-3, &tol, st, &mut stats).unwrap();
            }
            y
        };
        let mut s1 = IntegratorState::default();
        let mut s2 = IntegratorState::default();
        let y1 = go(&mut s1, kvo.initial(), 0, 200);
        let y2 = go(&mut s2, kvo.initial(), 0, 200);
        assert_eq!(y1, y2);
        assert_eq!(s1, s2);
        // Stop after 100 steps, copy the state (as fmi2GetFMUstate/serialization would), go on.
        let mut s3 = IntegratorState::default();
        let mid = go(&mut s3, kvo.initial(), 0, 100);
        let mut s4 = s3;
        let y4 = go(&mut s4, mid, 100, 100);
        assert_eq!(y4.map(f64::to_bits), y1.map(f64::to_bits));
        assert_eq!(s4, s1);
    }

    #[test]
    fn suggested_step_survives_communication_points() {
        // In steady state every 1 ms call takes the same two internal steps, none rejected:
        // the step is not restarted small at each communication point.
        let tol = Kvo::new().tol(1e-8);
        let mut yy = Kvo::new().initial();
        let mut r = Kvo::new();
        let (mut st2, mut stats2) = (IntegratorState::default(), IntegratorStats::default());
        for i in 0..400 {
            yy = advance(&mut r, i as f64 * 1e-3, yy, 1e-3, &tol, &mut st2, &mut stats2).unwrap();
        }
        let before = stats2;
        for i in 400..500 {
            yy = advance(&mut r, i as f64 * 1e-3, yy, 1e-3, &tol, &mut st2, &mut stats2).unwrap();
        }
        assert_eq!(stats2.rejected - before.rejected, 0);
        assert_eq!(stats2.steps - before.steps, 200, "{stats2:?}");
        assert_eq!(stats2.rhs_evals - before.rhs_evals, 100 * 17);
        assert!(st2.h_next > 5e-4 && st2.h_next < 1e-3, "{st2:?}");
    }

    #[test]
    fn a_small_suggestion_recovers_within_equal_split_steps() {
        // A suggestion far below the natural step (as after a transient or a rejection) makes
        // every step of a 1 ms call an equal split of it; the error of those steps must still
        // let the suggestion grow back: after a few calls the steady 2 steps per call of
        // `suggested_step_survives_communication_points` are reached (it stayed at 5 before).
        let tol = Kvo::new().tol(1e-8);
        let mut r = Kvo::new();
        let mut y = Kvo::new().initial();
        let mut st = IntegratorState { h_next: 2e-4, err_prev: 0.0 };
        let mut stats = IntegratorStats::default();
        for i in 0..400 {
            y = advance(&mut r, i as f64 * 1e-3, y, 1e-3, &tol, &mut st, &mut stats).unwrap();
        }
        let before = stats;
        for i in 400..500 {
            y = advance(&mut r, i as f64 * 1e-3, y, 1e-3, &tol, &mut st, &mut stats).unwrap();
        }
        assert_eq!(stats.rejected - before.rejected, 0, "{stats:?}");
        assert_eq!(stats.steps - before.steps, 200, "{stats:?} {st:?}");
        assert!(st.h_next > 5e-4, "{st:?}");
    }

    #[test]
    fn failing_stages_only_shrink_the_step() {
        // A far too large suggested step (hΩ0 = 30) sends the trial stages to |ϑ| > 0.1, where
        // this RHS fails (as a rod that buckles at a wild trial state). The call must still
        // succeed, agree with an undisturbed run, and the failures must have happened.
        let base = Kvo::new();
        let tol = base.tol(1e-8);
        let mut failing = Kvo { theta_limit: 0.1, ..Kvo::new() };
        let mut st = IntegratorState { h_next: 0.02, err_prev: 0.0 };
        let mut stats = IntegratorStats::default();
        let y =
            advance(&mut failing, 0.0, base.initial(), 0.01, &tol, &mut st, &mut stats).unwrap();
        assert!(failing.failures > 0 && stats.rejected > 0, "{stats:?}");
        let mut clean = Kvo::new();
        let (mut st0, mut stats0) = (IntegratorState::default(), IntegratorStats::default());
        let y0 =
            advance(&mut clean, 0.0, base.initial(), 0.01, &tol, &mut st0, &mut stats0).unwrap();
        assert!(err_over_tol(&tol, y, y0) < 10.0);
        // Continuing from there works normally.
        let y2 = advance(&mut failing, 0.01, y, 0.01, &tol, &mut st, &mut stats).unwrap();
        assert!(y2[0].is_finite());
    }

    #[test]
    fn failure_leaves_state_and_stats_untouched() {
        let base = Kvo::new();
        let tol = base.tol(1e-8);
        let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
        let y = run_chunks(&mut Kvo::new(), &tol, 1e-3, 50, &mut st, &mut stats)[50];
        let (st0, stats0) = (st, stats);
        // The rod buckles for good in the middle of the next step.
        let mut bad = Kvo { fail_after: 0.0505, ..Kvo::new() };
        let err = advance(&mut bad, 0.05, y, 1e-3, &tol, &mut st, &mut stats).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("cannot meet") && msg.contains("test rod buckled"), "{msg}");
        assert_eq!((st, stats), (st0, stats0));
        // Failing at the start point: immediate error, nothing changed.
        let mut bad = Kvo { fail_after: 0.0, ..Kvo::new() };
        let err = advance(&mut bad, 0.05, y, 1e-3, &tol, &mut st, &mut stats).unwrap_err();
        assert!(err.to_string().contains("test rod buckled"));
        assert_eq!(bad.failures, 1);
        assert_eq!((st, stats), (st0, stats0));
    }

    #[test]
    fn rejects_invalid_arguments() {
        let mut kvo = Kvo::new();
        let tol = kvo.tol(1e-8);
        let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
        let y = kvo.initial();
        for h in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
            assert!(advance(&mut kvo, 0.0, y, h, &tol, &mut st, &mut stats).is_err());
        }
        let bad = Tolerance { rtol: 0.0, ..tol };
        assert!(advance(&mut kvo, 0.0, y, 1e-3, &bad, &mut st, &mut stats).is_err());
        assert!(advance(&mut kvo, 0.0, [f64::NAN, 0.0], 1e-3, &tol, &mut st, &mut stats).is_err());
        assert_eq!(stats, IntegratorStats::default());
        // A non-finite acceleration is a failed stage, and at the start point an error.
        struct Nan;
        impl SecondOrderRhs for Nan {
            fn accel(&mut self, _: f64, _: f64, _: f64) -> Result<f64, ModelError> {
                Ok(f64::NAN)
            }
        }
        assert!(advance(&mut Nan, 0.0, y, 1e-3, &tol, &mut st, &mut stats).is_err());
    }

    #[test]
    fn communication_steps_from_1e5_to_0_1_seconds() {
        let kvo = Kvo::new();
        let tol = kvo.tol(1e-8);
        let reference = rk4(&mut kvo.clone(), kvo.initial(), 0.4, 1e-4);
        let mut r = Kvo::new();
        let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
        let mut y = kvo.initial();
        let mut t = 0.0;
        // 100 tiny steps, then 0.1 s steps, then small again.
        for (h, n) in [(1e-5, 100), (0.1, 3), (1e-4, 990)] {
            for _ in 0..n {
                y = advance(&mut r, t, y, h, &tol, &mut st, &mut stats).unwrap();
                t += h;
            }
        }
        let idx = (t / 1e-4).round() as usize;
        assert_eq!(idx, 4000);
        assert!(err_over_tol(&tol, y, reference[idx]) < 10.0);
    }

    #[test]
    fn a_1e_300_s_step_succeeds_and_leaves_the_natural_step() {
        // A communication step far below the step-size floor is one step to its end; it must
        // not leave a suggestion of its own size (which the next, normal call could not grow
        // from: "the step size fell to ..."). Fresh and warm states, at t = 0 as the FMU calls.
        let kvo = Kvo::new();
        let tol = kvo.tol(1e-8);
        for warm in [false, true] {
            let mut r = Kvo::new();
            let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
            let mut y = kvo.initial();
            if warm {
                y = advance(&mut r, 0.0, y, 1e-3, &tol, &mut st, &mut stats).unwrap();
            }
            let (st0, y0) = (st, y);
            let y1 = advance(&mut r, 0.0, y, 1e-300, &tol, &mut st, &mut stats).unwrap();
            // y moves by 1e-300·ẏ at most (ϑ̇ ≈ 6.5 rad/s: below an ulp unless ϑ = 0).
            assert!((y1[0] - y0[0]).abs() <= 1e-299 && y1[1] == y0[1], "warm {warm}: {y1:?}");
            assert!(st.h_next > 1e-5, "warm {warm}: {st:?}");
            if warm {
                assert_eq!(st, st0);
            }
            // The next millisecond is the one without the tiny step (to 1e-3 of the tolerance).
            let next = advance(&mut r, 0.0, y1, 1e-3, &tol, &mut st, &mut stats).unwrap();
            let mut st_direct = st0;
            let direct = advance(&mut r, 0.0, y0, 1e-3, &tol, &mut st_direct, &mut stats).unwrap();
            assert!(err_over_tol(&tol, next, direct) < 1e-3, "warm {warm}: {next:?} {direct:?}");
        }
    }

    #[test]
    fn a_1e300_s_step_fails_naming_the_communication_step() {
        let kvo = Kvo::new();
        let tol = kvo.tol(1e-8);
        let mut r = Kvo::new();
        let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
        let y = advance(&mut r, 0.0, kvo.initial(), 1e-3, &tol, &mut st, &mut stats).unwrap();
        let (st0, stats0) = (st, stats);
        let e = advance(&mut r, 0.0, y, 1e300, &tol, &mut st, &mut stats).unwrap_err().to_string();
        assert!(
            e.contains("communicationStepSize = 1e+300 s is too long") && !e.contains('\n'),
            "{e}"
        );
        assert_eq!((st, stats), (st0, stats0));
    }

    /// Cost report (run: cargo test --release -- --ignored --nocapture kvo630_cost_report).
    #[test]
    #[ignore]
    fn kvo630_cost_report() {
        let kvo = Kvo::new();
        for &hc in &[1e-4_f64, 1e-3, 1e-2] {
            let tol = kvo.tol(1e-8);
            let n = (1.0 / hc).round() as usize;
            let mut best = f64::INFINITY;
            let mut stats = IntegratorStats::default();
            for _ in 0..5 {
                let mut r = Kvo::new();
                let (mut st, mut s) = (IntegratorState::default(), IntegratorStats::default());
                let mut y = kvo.initial();
                let start = std::time::Instant::now();
                for i in 0..n {
                    y = advance(&mut r, i as f64 * hc, y, hc, &tol, &mut st, &mut s).unwrap();
                }
                best = best.min(start.elapsed().as_secs_f64());
                std::hint::black_box(y);
                stats = s;
            }
            println!(
                "kvo630, tol 1e-8, h = {hc} s: {} RHS evaluations per simulated second, {} steps, \
                 {} rejected, {:.0} ns per call, {:.0} ns per simulated ms",
                stats.rhs_evals,
                stats.steps,
                stats.rejected,
                best / n as f64 * 1e9,
                best * 1e6
            );
        }
    }

    // -----------------------------------------------------------------------------------------
    // The pairs compared with Verner 6(5) on the elastic rod (docs/performance.md)
    // -----------------------------------------------------------------------------------------

    /// Other FSAL pairs, for the comparison of `model::drive`'s ignored test
    /// `pairs_compared_on_the_shifted_cage_variable`: [`advance`] integrates with the pair set by
    /// [`compared::with_pair`] on this thread (test builds only).
    pub(crate) mod compared {
        use super::super::*;
        use std::cell::Cell;

        /// Dormand–Prince 5(4) (Hairer, Nørsett & Wanner, Solving ODE I, Table II.5.2).
        pub const DP5_B: [f64; 7] =
            [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0, 0.0];
        pub const DP5_B_HAT: [f64; 7] = [
            5179.0 / 57600.0,
            0.0,
            7571.0 / 16695.0,
            393.0 / 640.0,
            -92097.0 / 339200.0,
            187.0 / 2100.0,
            1.0 / 40.0,
        ];
        #[rustfmt::skip]
        pub const DP5: Pair<7> = Pair {
            c: [0.0, 0.2, 0.3, 0.8, 8.0 / 9.0, 1.0, 1.0],
            a: [
                [0.0; 7],
                [0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0, 0.0],
                [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0, 0.0],
                [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0, 0.0],
                DP5_B,
            ],
            b: DP5_B,
            fsal: true,
            e: error_weights(DP5_B, DP5_B_HAT),
            order: 5.0,
            est_exponent: 1.0 / 5.0,
        };

        /// Verner's "most efficient" 7(6) pair, RKV76.IIa (10 stages, not FSAL: 10 evaluations
        /// a step; coefficients as published by J. H. Verner, as in jacobwilliams/rklib `rkv76e`).
        pub const V76_B: [f64; 10] = [
            0.04715561848627222170431765108838175679569,
            0.0,
            0.0,
            0.2575056429843415189596436101037687580986,
            0.2621665397741262047713863095764527711129,
            0.1521609265673855740323133199165117535523,
            0.4939969170032484246907175893227876844296,
            -0.2943031171403250441557244744092703429139,
            0.08131747232495109999734599440136761892478,
            0.0,
        ];
        pub const V76_B_HAT: [f64; 10] = [
            0.04460860660634117628731817597479197781432,
            0.0,
            0.0,
            0.2671640378571372680509102260943837899738,
            0.2201018300177293019979715776650753096323,
            0.2188431703143156830983120833512893824578,
            0.2289871705411202883378173889763552365362,
            0.0,
            0.0,
            0.02029518466335628222767054793810430358554,
        ];
        #[rustfmt::skip]
        pub const V76: Pair<10> = Pair {
            c: [0.0, 0.005, 0.1088888888888888888888888888888888888889, 0.1633333333333333333333333333333333333333,
                0.4555, 0.6095094489978381317087004421486024949638, 0.884, 0.925, 1.0, 1.0],
            a: [
                [0.0; 10],
                [0.005, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [-1.076790123456790123456790123456790123457, 1.185679012345679012345679012345679012346,
                 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [0.04083333333333333333333333333333333333333, 0.0, 0.1225, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [0.6389139236255726780508121615993336109954, 0.0, -2.455672638223656809662640566430653894211,
                 2.272258714598084131611828404831320283215, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [-2.661577375018757131119259297861818119279, 0.0, 10.80451388645613769565396655365532838482,
                 -8.353914657396199411968048547819291691541, 0.8204875949566569791420417341743839209619,
                 0.0, 0.0, 0.0, 0.0, 0.0],
                [6.067741434696770992718360183877276714679, 0.0, -24.71127363591108579734203485290746001803,
                 20.42751793078889394045773111748346612697, -1.906157978816647150624096784352757010879,
                 1.006172249242068014790040335899474187268, 0.0, 0.0, 0.0, 0.0],
                [12.05467007625320299509109452892778311648, 0.0, -49.75478495046898932807257615331444758322,
                 41.14288863860467663259698416710157354209, -4.461760149974004185641911603484815375051,
                 2.042334822239174959821717077708608543738, -0.09834843665406107379530801693870224403537,
                 0.0, 0.0, 0.0],
                [10.13814652288180787641845141981689030769, 0.0, -42.64113603171750214622846006736635730625,
                 35.76384003992257007135021178023160054034, -4.348022840392907653340370296908245943710,
                 2.009862268377035895441943593011827554771, 0.3487490460338272405953822853053145879140,
                 -0.2714390051048312842371587140910297407572, 0.0, 0.0],
                [-45.03007203429867712435322405073769635151, 0.0, 187.3272437654588840752418206154201997384,
                 -154.0288236935018690596728621034510402582, 18.56465306347536233859492332958439136765,
                 -7.141809679295078854925420496823551192821, 1.308808578161378625114762706007696696508,
                 0.0, 0.0, 0.0],
            ],
            b: V76_B,
            fsal: false,
            e: error_weights(V76_B, V76_B_HAT),
            order: 7.0,
            est_exponent: 1.0 / 7.0,
        };

        /// Which pair [`advance`] uses on this thread (None: Verner 6(5)).
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub enum Which {
            Verner65,
            Dp5,
            Tsit5,
            Verner76,
            LawsonVerner65,
            LawsonTsit5,
            LawsonDp5,
        }

        thread_local! {
            static UNDER_TEST: Cell<Option<Which>> = const { Cell::new(None) };
        }

        /// Runs `f` with [`advance`] integrating with `which` on this thread.
        pub fn with_pair<R>(which: Which, f: impl FnOnce() -> R) -> R {
            UNDER_TEST.with(|u| u.set(Some(which)));
            let r = f();
            UNDER_TEST.with(|u| u.set(None));
            r
        }

        pub(in crate::model::integrator) fn advance_with_pair_under_test(
            rhs: &mut impl SecondOrderRhs,
            t0: f64,
            y0: [f64; 2],
            h: f64,
            tol: &Tolerance,
            state: &mut IntegratorState,
            stats: &mut IntegratorStats,
        ) -> Option<Result<[f64; 2], ModelError>> {
            use Form::{Lawson, Plain};
            match UNDER_TEST.with(|u| u.get())? {
                Which::Verner65 => {
                    Some(advance_with(&VERNER_65, Plain, rhs, t0, y0, h, tol, state, stats))
                }
                Which::Dp5 => Some(advance_with(&DP5, Plain, rhs, t0, y0, h, tol, state, stats)),
                Which::Tsit5 => {
                    Some(advance_with(&TSIT5, Plain, rhs, t0, y0, h, tol, state, stats))
                }
                Which::Verner76 => {
                    Some(advance_with(&V76, Plain, rhs, t0, y0, h, tol, state, stats))
                }
                Which::LawsonVerner65 => {
                    Some(advance_with(&VERNER_65, Lawson, rhs, t0, y0, h, tol, state, stats))
                }
                Which::LawsonTsit5 => {
                    Some(advance_with(&TSIT5, Lawson, rhs, t0, y0, h, tol, state, stats))
                }
                Which::LawsonDp5 => {
                    Some(advance_with(&DP5, Lawson, rhs, t0, y0, h, tol, state, stats))
                }
            }
        }
    }

    #[test]
    fn the_compared_pairs_satisfy_their_order_conditions() {
        use compared::*;
        for (name, pair, b, b_hat) in
            [("DP5", &DP5, DP5_B, DP5_B_HAT), ("Tsit5", &TSIT5, TSIT5_B, TSIT5_B_HAT)]
        {
            for i in 1..7 {
                let row: f64 = pair.a[i].iter().sum();
                assert!((row - pair.c[i]).abs() < 1e-14, "{name} row {i}: {row} vs {}", pair.c[i]);
            }
            let rb = order_residuals(&pair.a, &b, 6);
            let rh = order_residuals(&pair.a, &b_hat, 6);
            for n in 1..=5 {
                assert!(rb[n] < 1e-12, "{name} b, order {n}: residual {:e}", rb[n]);
            }
            for n in 1..=4 {
                assert!(rh[n] < 1e-12, "{name} b_hat, order {n}: residual {:e}", rh[n]);
            }
            assert!(rb[6] > 1e-6 && rh[5] > 1e-6, "{name}: {rb:?} {rh:?}");
        }
        // Verner 7(6): 7th order for the solution, 6th for the estimate (not 7th).
        for i in 1..10 {
            let row: f64 = V76.a[i].iter().sum();
            let mag: f64 = V76.a[i].iter().map(|v| v.abs()).sum();
            assert!(
                (row - V76.c[i]).abs() <= 8.0 * f64::EPSILON * mag,
                "V76 row {i}: {row} vs {}",
                V76.c[i]
            );
        }
        let rb = order_residuals(&V76.a, &V76_B, 7);
        let rh = order_residuals(&V76.a, &V76_B_HAT, 7);
        for n in 1..=7 {
            assert!(rb[n] < 1e-10, "V76 b, order {n}: residual {:e}", rb[n]);
        }
        for n in 1..=6 {
            assert!(rh[n] < 1e-10, "V76 b_hat, order {n}: residual {:e}", rh[n]);
        }
        assert!(rh[7] > 1e-8, "V76: {rh:?}");
    }
}
