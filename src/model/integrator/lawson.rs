//! The exact linear part: an embedded Runge–Kutta pair applied in Lawson's integrating-factor
//! form to y' = L·y + N(t, y) (docs/performance.md "The elastic rod", work-precision study).
//!
//! L = [[0, 1], [−Ω², −2a]] is the cage oscillator frozen at the start of the communication step
//! (Ω² = K_ϑ(P)/J_m with P of that instant, 2a = B_d/J_m, [`SecondOrderRhs::linear_part`]);
//! N = f − L·y is the rest: the forcing, the variation of K_ϑ(P) along the step and the
//! friction's dependence on ϑ. In v = e^(−τL)·y the pair integrates
//! v' = e^(−τL)·N(τ, e^(τL)·v), so the stages are
//!
//! Y_i = e^(c_i hL)·(y_n + h Σ_j a_ij K_j),  K_j = e^(−c_j hL)·N(t + c_j h, Y_j),
//! y_(n+1) = e^(hL)·(y_n + h Σ_j b_j K_j),
//!
//! and the embedded estimate is e^(hL)·h Σ_j e_j K_j (J. D. Lawson, SIAM J. Numer. Anal. 4 (1967)
//! 372–380; Hochbruck & Ostermann, Acta Numerica 19 (2010), §2.4). The order of the pair is kept
//! (it is the pair's order on the transformed equation), a linear L·y is integrated exactly for
//! any h, and an FSAL pair stays FSAL (its last stage is at the new point: c = 1, E(0) = I).
//!
//! The 2×2 exponential in closed form (underdamped, Ω² > a², ν = √(Ω² − a²)):
//! e^(sL) = e^(−as)·[cos νs·I + (sin νs/ν)·(L + a·I)].

use super::{eval, IntegratorStats, Pair, SecondOrderRhs};
use crate::model::error::ModelError;

/// The frozen oscillator L = [[0, 1], [−w2, −d]] (w2 = Ω² [1/s²], d = 2a [1/s]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Linear {
    pub w2: f64,
    pub d: f64,
}

impl Linear {
    /// The underdamped frozen oscillator, or None (the plain pair is used then): non-finite,
    /// Ω² ≤ a² (no oscillation to treat exactly) or a negative damping.
    pub fn new(w2: f64, d: f64) -> Option<Linear> {
        let a = 0.5 * d;
        (w2.is_finite() && d.is_finite() && d >= 0.0 && w2 > a * a).then_some(Linear { w2, d })
    }

    /// N = f − L·y from f = (y[1], acc): (0, acc + Ω²·y0 + 2a·y1).
    #[inline(always)]
    fn rest(&self, y: [f64; 2], f: [f64; 2]) -> [f64; 2] {
        [f[0] - y[1], f[1] + self.w2 * y[0] + self.d * y[1]]
    }
}

/// A 2×2 matrix, row-major.
type M2 = [f64; 4];

#[inline(always)]
fn mul(m: &M2, v: [f64; 2]) -> [f64; 2] {
    [m[0] * v[0] + m[1] * v[1], m[2] * v[0] + m[3] * v[1]]
}

/// e^(sL) and e^(−sL) from one sin_cos and one exp.
#[inline]
fn exp_pair(lin: &Linear, s: f64) -> (M2, M2) {
    let a = 0.5 * lin.d;
    let nu = (lin.w2 - a * a).sqrt();
    let (sn, cs) = (nu * s).sin_cos();
    let q = sn / nu;
    let decay = (-a * s).exp();
    // e^(sL) = e^(−as)[cos·I + q·(L + aI)], L + aI = [[a, 1], [−w2, −a]]; e^(−sL) the same
    // with s → −s (cos even, q odd).
    let pos = [decay * (cs + a * q), decay * q, -decay * lin.w2 * q, decay * (cs - a * q)];
    let g = 1.0 / decay;
    let neg = [g * (cs - a * q), -g * q, g * lin.w2 * q, g * (cs + a * q)];
    (pos, neg)
}

/// The exponentials of one step (h, L), kept while neither changes (equal internal steps with
/// the same frozen L reuse them).
pub struct ExpCache<const S: usize> {
    key: Option<(f64, Linear)>,
    pos: [M2; S],
    neg: [M2; S],
}

impl<const S: usize> Default for ExpCache<S> {
    fn default() -> Self {
        ExpCache { key: None, pos: [[0.0; 4]; S], neg: [[0.0; 4]; S] }
    }
}

impl<const S: usize> ExpCache<S> {
    #[inline]
    fn update(&mut self, pair: &Pair<S>, lin: &Linear, h: f64) {
        if self.key == Some((h, *lin)) {
            return;
        }
        for i in 0..S {
            let same = (0..i).find(|&j| pair.c[j] == pair.c[i]);
            (self.pos[i], self.neg[i]) = match same {
                Some(j) => (self.pos[j], self.neg[j]),
                None if pair.c[i] == 0.0 => ([1.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0]),
                None => exp_pair(lin, pair.c[i] * h),
            };
        }
        self.key = Some((h, *lin));
    }
}

/// One Lawson step from (t, y) with `k[0] = f(t, y)` already set, as `integrator::step`: fills
/// the stages (k holds f, not N, so that the FSAL stage is f at the new point for the next
/// step) and returns the new solution and the estimate (without the factor h).
#[allow(clippy::needless_range_loop, clippy::too_many_arguments)]
#[inline(always)]
pub fn step<const S: usize>(
    pair: &Pair<S>,
    lin: &Linear,
    cache: &mut ExpCache<S>,
    rhs: &mut impl SecondOrderRhs,
    t: f64,
    y: [f64; 2],
    h: f64,
    k: &mut [[f64; 2]; S],
    stats: &mut IntegratorStats,
) -> Result<([f64; 2], [f64; 2]), ModelError> {
    cache.update(pair, lin, h);
    // K_j in the transformed variable (K_0 = N(t, y): e^0 = I).
    let mut kt = [[0.0_f64; 2]; S];
    kt[0] = lin.rest(y, k[0]);
    let mut v_new = y;
    let mut y_new = y;
    for i in 1..S {
        let mut vi = y;
        for j in 0..i {
            let aij = pair.a[i][j];
            if aij != 0.0 {
                vi[0] += h * aij * kt[j][0];
                vi[1] += h * aij * kt[j][1];
            }
        }
        let yi = mul(&cache.pos[i], vi);
        if pair.fsal && i == S - 1 {
            (v_new, y_new) = (vi, yi); // last row of A = B
        }
        k[i] = eval(rhs, t + pair.c[i] * h, yi, stats)?;
        kt[i] = mul(&cache.neg[i], lin.rest(yi, k[i]));
    }
    if !pair.fsal {
        for j in 0..S {
            v_new[0] += h * pair.b[j] * kt[j][0];
            v_new[1] += h * pair.b[j] * kt[j][1];
        }
        y_new = mul(&exp_pair(lin, h).0, v_new);
    }
    let mut est = [0.0_f64; 2];
    for j in 0..S {
        est[0] += pair.e[j] * kt[j][0];
        est[1] += pair.e[j] * kt[j][1];
    }
    // The estimate of v's error carried to y like v itself (e^(hL) of the FSAL pair's last
    // stage, c = 1; else computed above).
    let e1 = if pair.fsal { cache.pos[S - 1] } else { exp_pair(lin, h).0 };
    Ok((y_new, mul(&e1, est)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// e^(sL) against its Taylor series (independent of the closed form), and e^(sL)·e^(−sL) = I.
    #[test]
    fn closed_form_exponential_matches_the_series() {
        for (w2, d, s) in [(1500.0_f64.powi(2), 150.0, 1e-3), (4.0, 0.1, 0.7), (1e6, 0.0, 3e-4)] {
            let lin = Linear::new(w2, d).unwrap();
            let l = [0.0, 1.0, -w2, -d];
            let mm = |a: &M2, b: &M2| {
                [
                    a[0] * b[0] + a[1] * b[2],
                    a[0] * b[1] + a[1] * b[3],
                    a[2] * b[0] + a[3] * b[2],
                    a[2] * b[1] + a[3] * b[3],
                ]
            };
            // Scaling and squaring: the series of e^(sL/2^8), squared 8 times.
            let sc = s / 256.0;
            let x = [l[0] * sc, l[1] * sc, l[2] * sc, l[3] * sc];
            let mut term = [1.0, 0.0, 0.0, 1.0];
            let mut sum = term;
            for n in 1..30 {
                term = mm(&term, &x).map(|v| v / n as f64);
                for i in 0..4 {
                    sum[i] += term[i];
                }
            }
            for _ in 0..8 {
                sum = mm(&sum, &sum);
            }
            let (pos, neg) = exp_pair(&lin, s);
            let scale = [1.0, 1.0 / w2.sqrt(), w2.sqrt(), 1.0];
            for i in 0..4 {
                assert!(
                    (pos[i] - sum[i]).abs() < 1e-12 * scale[i],
                    "{w2} {d} {s}: {pos:?} {sum:?}"
                );
            }
            let id = mm(&pos, &neg);
            for (i, v) in id.iter().enumerate() {
                let want = if i == 0 || i == 3 { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 1e-12 * scale[i], "{id:?}");
            }
        }
        assert!(Linear::new(1.0, 3.0).is_none() && Linear::new(f64::NAN, 1.0).is_none());
    }
}

#[cfg(test)]
mod advance_tests {
    use super::super::{
        advance_with, Form, IntegratorState, IntegratorStats, SecondOrderRhs, Tolerance, VERNER_65,
    };
    use crate::model::error::ModelError;

    /// x'' + 2ζΩx' + Ω²x = a·cos ωt with its linear part known (the textbook closed form is
    /// the reference), failing beyond `limit` like a buckling rod.
    struct Osc {
        w0: f64,
        zeta: f64,
        a: f64,
        w: f64,
        limit: f64,
    }

    impl SecondOrderRhs for Osc {
        fn accel(&mut self, t: f64, x: f64, v: f64) -> Result<f64, ModelError> {
            if x.abs() > self.limit {
                return Err(ModelError::evaluation("test rod buckled".to_string()));
            }
            Ok(self.a * (self.w * t).cos() - 2.0 * self.zeta * self.w0 * v - self.w0 * self.w0 * x)
        }
        fn linear_part(&self) -> Option<(f64, f64)> {
            Some((self.w0 * self.w0, 2.0 * self.zeta * self.w0))
        }
    }

    impl Osc {
        fn exact(&self, t: f64, x0: f64, v0: f64) -> [f64; 2] {
            let (w0, z, a, w) = (self.w0, self.zeta, self.a, self.w);
            let den = (w0 * w0 - w * w).powi(2) + (2.0 * z * w0 * w).powi(2);
            let zr = a * (w0 * w0 - w * w) / den;
            let zi = -a * 2.0 * z * w0 * w / den;
            let (sw, cw) = (w * t).sin_cos();
            let (xp, vp) = (zr * cw - zi * sw, -w * zr * sw - w * zi * cw);
            let wd = w0 * (1.0 - z * z).sqrt();
            let c1 = x0 - zr;
            let c2 = (v0 + w * zi + z * w0 * c1) / wd;
            let e = (-z * w0 * t).exp();
            let (sd, cd) = (wd * t).sin_cos();
            [
                xp + e * (c1 * cd + c2 * sd),
                vp + e * ((-z * w0 * c1 + wd * c2) * cd + (-z * w0 * c2 - wd * c1) * sd),
            ]
        }
    }

    #[test]
    fn the_free_oscillator_is_exact_in_one_step_of_any_length() {
        // No forcing: N = 0, so one step of 20 ms (hΩ = 30, far beyond any explicit pair's
        // stability) is the closed form to rounding, and the estimate is zero.
        let mut osc = Osc { w0: 1500.0, zeta: 0.05, a: 0.0, w: 0.0, limit: f64::INFINITY };
        let tol = Tolerance::from_solver_tolerance(1e-8, 1500.0);
        let (mut st, mut stats) =
            (IntegratorState { h_next: 0.02, ..Default::default() }, IntegratorStats::default());
        let y = advance_with(
            &VERNER_65,
            Form::Lawson,
            &mut osc,
            0.0,
            [0.01, 3.0],
            0.02,
            &tol,
            &mut st,
            &mut stats,
        )
        .unwrap();
        let r = osc.exact(0.02, 0.01, 3.0);
        assert!((y[0] - r[0]).abs() < 1e-15 && (y[1] - r[1]).abs() < 1e-12, "{y:?} {r:?}");
        assert_eq!((stats.steps, stats.rejected), (1, 0));
        // The plain pair needs many steps for the same interval.
        let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
        advance_with(
            &VERNER_65,
            Form::Plain,
            &mut osc,
            0.0,
            [0.01, 3.0],
            0.02,
            &tol,
            &mut st,
            &mut stats,
        )
        .unwrap();
        assert!(stats.steps > 10, "{stats:?}");
    }

    #[test]
    fn forced_oscillator_matches_the_closed_form_within_the_tolerance() {
        let mut osc = Osc { w0: 1500.0, zeta: 0.05, a: 2000.0, w: 157.0, limit: f64::INFINITY };
        for tolv in [1e-6, 1e-8, 1e-10] {
            let tol = Tolerance::from_solver_tolerance(tolv, 1500.0);
            let (mut st, mut stats) = (IntegratorState::default(), IntegratorStats::default());
            let mut y = [0.0, 0.0];
            let mut worst: f64 = 0.0;
            for k in 0..200 {
                let t0 = k as f64 * 1e-3;
                y = advance_with(
                    &VERNER_65,
                    Form::Lawson,
                    &mut osc,
                    t0,
                    y,
                    1e-3,
                    &tol,
                    &mut st,
                    &mut stats,
                )
                .unwrap();
                let r = osc.exact(t0 + 1e-3, 0.0, 0.0);
                worst = worst
                    .max((y[0] - r[0]).abs() / (tolv * (1.0 + r[0].abs())))
                    .max((y[1] - r[1]).abs() / (tolv * (1500.0 + r[1].abs())));
            }
            assert!(worst < 10.0, "tol {tolv}: error/tolerance {worst}, {stats:?}");
        }
    }

    #[test]
    fn a_failing_stage_leaves_state_and_stats_untouched() {
        // The oscillator leaves |x| ≤ 1e-4 within the step: every retry fails, the call fails
        // and the caller's state and counters are as before.
        let mut osc = Osc { w0: 1500.0, zeta: 0.05, a: 0.0, w: 0.0, limit: 1e-4 };
        let tol = Tolerance::from_solver_tolerance(1e-8, 1500.0);
        let mut st = IntegratorState { h_next: 3e-4, err_prev: 0.5 };
        let mut stats = IntegratorStats { rhs_evals: 7, steps: 3, rejected: 1 };
        let (st0, stats0) = (st, stats);
        let e = advance_with(
            &VERNER_65,
            Form::Lawson,
            &mut osc,
            0.0,
            [0.0, 1.0],
            1e-3,
            &tol,
            &mut st,
            &mut stats,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("buckled"), "{e}");
        assert_eq!((st, stats), (st0, stats0));
    }
}
