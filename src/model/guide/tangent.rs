//! Exact directional derivatives of the rigid rod's guide solve (docs/fmi-interface.md
//! "Directional derivatives"; the solve is docs/model.md §4, §5.3, §5.4).
//!
//! `Guide::solve_rigid` finds P = p_base + F_fr(P) exactly; F_fr is piecewise linear in P with
//! coefficients that depend on s (the influence of the supports), v (through tanh(v/v_ε)) and
//! tanβ (the side load −P·tanβ). On the piece the solution lies on, implicit differentiation
//! gives the tangent of P in closed form,
//! `dP·(1 + tanh·Σ g_x'(slope_x)) = dp_base − d(tanh)·Σ g_x − tanh·Σ g_x'(A_x)`,
//! with g_x the friction magnitude of support x, g_x' its rate along a change of its force and
//! moment (the branch that gives the value, as `FrictionLaw::magnitude_rate`), `slope_x` the
//! change of its reactions per newton of P and `A_x` their change at fixed P. At a kink of the
//! friction law (a reaction through zero, or |R| = 2|M|/l_n) the derivative is one-sided: the
//! branch that gives the value is differentiated, as everywhere else in the model.

use num_dual::Dual64;

use super::friction::{self, FrictionLaw};
use super::supports::ForceMoment;
use super::{Guide, GuideOutputs};
use crate::model::error::{num, ModelError};

/// Rate of a friction magnitude along (dR, dM): `FrictionLaw::magnitude_rate`.
#[inline]
fn rate(law: &FrictionLaw, fm: ForceMoment, d: ForceMoment) -> f64 {
    law.magnitude_rate(fm, d)
}

impl Guide {
    /// The tangent of every output of [`Guide::solve_rigid`] along the direction carried by the
    /// dual parts of `s`, `v`, `p_base` and `tan_beta`, whose real parts gave `value`.
    pub fn solve_rigid_tangent(
        &self,
        s: Dual64,
        v: Dual64,
        p_base: Dual64,
        tan_beta: Dual64,
        value: &GuideOutputs,
    ) -> Result<GuideOutputs, ModelError> {
        let (base, per_q) = self.system.rigid_influence(s.re)?;
        // The rate with respect to s is needed only when the direction moves the link.
        let influence_rate = if s.eps == 0.0 {
            Some(([ForceMoment::default(); 3], [ForceMoment::default(); 3]))
        } else {
            self.system.rigid_influence_rate(s.re)?
        };
        let Some((dbase, dper_q)) = influence_rate else {
            return Err(ModelError::evaluation(format!(
                "directional derivative: the support reactions at s = {} m come from a linear \
                 solve at each position (more than one support fixed in the frame, or the load \
                 point fixed in the frame), for which no exact rate with respect to crank.angle \
                 is provided",
                num(s.re)
            )));
        };
        let p = value.rod_force;
        let (dq_dp, d_dq_dp) =
            if self.rod_side_force { (-tan_beta.re, -tan_beta.eps) } else { (0.0, 0.0) };
        let sign = friction::regularized_sign(v.re / self.velocity_scale);
        // d tanh(x)/dx = 1 − tanh²(x) (also 0 where the regularized sign is ±1 exactly).
        let dsign = (1.0 - sign * sign) * v.eps / self.velocity_scale;
        let mut at_p = [ForceMoment::default(); 3];
        // The change of each support's reactions at fixed P (A_x) and per newton of P (slope_x).
        let mut fixed_p = [ForceMoment::default(); 3];
        let mut slope = [ForceMoment::default(); 3];
        for x in 0..3 {
            slope[x] = ForceMoment { r: dq_dp * per_q[x].r, m: dq_dp * per_q[x].m };
            let dslope = ForceMoment {
                r: d_dq_dp * per_q[x].r + dq_dp * dper_q[x].r * s.eps,
                m: d_dq_dp * per_q[x].m + dq_dp * dper_q[x].m * s.eps,
            };
            at_p[x] = base[x].plus_scaled(p, slope[x]);
            fixed_p[x] = ForceMoment {
                r: dbase[x].r * s.eps + p * dslope.r,
                m: dbase[x].m * s.eps + p * dslope.m,
            };
        }
        // Uniqueness (checked by solve_rigid: |tanh|·K < 1) keeps the factor away from 0.
        Ok(self.implicit_tangent(&at_p, &fixed_p, &slope, p_base.eps, sign, dsign))
    }

    /// The tangent of the outputs from the fixed point P = p_base + F_fr differentiated on its
    /// piece (the module's formula): `at_p` the supports' reactions at the solution, `fixed_p`
    /// their change at fixed P (A_x), `slope` their change per newton of P; `sign` the
    /// regularized sign tanh(v/v_ε) and `dsign` its change.
    fn implicit_tangent(
        &self,
        at_p: &[ForceMoment; 3],
        fixed_p: &[ForceMoment; 3],
        slope: &[ForceMoment; 3],
        dp_base: f64,
        sign: f64,
        dsign: f64,
    ) -> GuideOutputs {
        let (mut g_sum, mut a_sum, mut k_sum) = (0.0, 0.0, 0.0);
        for x in 0..3 {
            g_sum += self.laws[x].magnitude(at_p[x]);
            a_sum += rate(&self.laws[x], at_p[x], fixed_p[x]);
            k_sum += rate(&self.laws[x], at_p[x], slope[x]);
        }
        let dp = (dp_base - dsign * g_sum - sign * a_sum) / (1.0 + sign * k_sum);
        let mut fr = [0.0; 3];
        let mut dfm = [ForceMoment::default(); 3];
        for x in 0..3 {
            dfm[x] = fixed_p[x].plus_scaled(dp, slope[x]);
            fr[x] = -dsign * self.laws[x].magnitude(at_p[x])
                - sign * rate(&self.laws[x], at_p[x], dfm[x]);
        }
        let (n1, n2) = friction::edge_forces(self.kinds[1], self.lengths[1], dfm[1]);
        GuideOutputs {
            rod_force: dp,
            friction_b: fr[1],
            reaction_b: dfm[1].r,
            moment_b: dfm[1].m,
            edge_force_1: n1,
            edge_force_2: n2,
            reaction_a: dfm[0].r,
            reaction_c: dfm[2].r,
            friction_total: fr[0] + fr[1] + fr[2],
        }
    }
}

impl Guide {
    /// The tangent of every output of the elastic rod's clamp solve ([`Guide::solve_clamp_from`],
    /// docs/model.md §4, §5.4) along the direction carried by the dual parts of `s`, `v` and
    /// `p_base`, whose real parts gave `value`. `clamp_loads(P, along_delta)` gives the rod's
    /// clamp loads (M0, V) at the dual P, with the dual part of Δ when `along_delta` (else Δ
    /// held). The fixed point `P = p_base + F_fr(M0(P, Δ), V(P, Δ))` differentiated implicitly:
    /// `dP·(1 + tanh·Σ g_x'(slope_x)) = dp_base − d(tanh)·Σ g_x − tanh·Σ g_x'(A_x)`, with
    /// `slope_x` the change of the reactions of support x per newton of P (through M0, V) and
    /// `A_x` their change at fixed P (through s and Δ); one-sided at a kink of the friction law.
    pub fn solve_clamp_tangent(
        &self,
        s: Dual64,
        v: Dual64,
        p_base: Dual64,
        value: &GuideOutputs,
        clamp_loads: impl Fn(Dual64, bool) -> (Dual64, Dual64),
    ) -> Result<GuideOutputs, ModelError> {
        let cf = self.clamp_friction(s.re, v.re, p_base.re)?;
        let dbase = if s.eps == 0.0 {
            [ForceMoment::default(); 3]
        } else {
            self.system.clamp_influence_rate().ok_or_else(|| {
                ModelError::evaluation(format!(
                    "directional derivative: not provided with respect to crank.angle for an \
                     elastic rod whose support reactions at s = {} m come from a solve at each \
                     position (a support fixed in the frame); seed only crank.speed, \
                     crank.acceleration or link.external_force",
                    num(s.re)
                ))
            })?
        };
        let p = value.rod_force;
        // The loads along Δ at fixed P, and per newton of P at fixed Δ.
        let (m0_fixed, v_fixed) = clamp_loads(Dual64::from(p), true);
        let (m0_per_p, v_per_p) = clamp_loads(Dual64::new(p, 1.0), false);
        let infl = &cf.infl;
        let sign = cf.sign;
        let dsign = (1.0 - sign * sign) * v.eps / self.velocity_scale;
        let mut at_p = [ForceMoment::default(); 3];
        let mut fixed_p = [ForceMoment::default(); 3];
        let mut slope = [ForceMoment::default(); 3];
        for x in 0..3 {
            at_p[x] = infl.base[x]
                .plus_scaled(m0_fixed.re, infl.per_m0[x])
                .plus_scaled(v_fixed.re, infl.per_v[x]);
            fixed_p[x] = ForceMoment { r: dbase[x].r * s.eps, m: dbase[x].m * s.eps }
                .plus_scaled(m0_fixed.eps, infl.per_m0[x])
                .plus_scaled(v_fixed.eps, infl.per_v[x]);
            slope[x] = ForceMoment::default()
                .plus_scaled(m0_per_p.eps, infl.per_m0[x])
                .plus_scaled(v_per_p.eps, infl.per_v[x]);
        }
        // The solve converged by contraction (|tanh|·K < 1), which keeps the factor from 0.
        Ok(self.implicit_tangent(&at_p, &fixed_p, &slope, p_base.eps, sign, dsign))
    }
}
