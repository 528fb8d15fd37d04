//! The elastic rod's step: the cage equation as the integrator sees it (`CageRhs`: the crank
//! extrapolated inside the step, P solved on the stiffness table at every stage, the shifted
//! variable φ = ϑ − c·Δ) and `Model::step`, which advances the cage state over one communication
//! step (docs/model.md §6 "Integration").

use super::{Inputs, LinkLoads, Mechanism, Model, RodState};
use crate::model::crank::{sin_cos_shifted, CrankState};
use crate::model::elastic_rod::cage::{CageLoads, CageState, ElasticRod};
use crate::model::elastic_rod::table::{self, StiffnessTable};
use crate::model::error::ModelError;
use crate::model::guide::ClampFriction;
use crate::model::integrator::{self, IntegratorStats, SecondOrderRhs, Tolerance};

impl Model {
    /// Advances the cage state over one communication step [t, t+h] with the crank extrapolated
    /// inside it (§2), to the tolerance `tol` (§6 "Integration"). A rigid rod has no state.
    /// On error nothing is changed (the caller's state is only replaced on success).
    pub fn step(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        state: &RodState,
        h: f64,
        tol: f64,
        stats: &mut IntegratorStats,
    ) -> Result<RodState, ModelError> {
        Self::check_inputs(crank, inputs)?;
        let Mechanism::ElasticRodSlider(_, rod) = &self.mechanism else {
            return Ok(*state);
        };
        // The table's coefficients are exact to table::ACCURACY; the stages use them only when
        // that and the stage tolerance on P are far below what the tolerance can see.
        let table = self.rod_table.as_deref().filter(|_| tol >= TABLE_MIN_TOLERANCE);
        let mut rhs = CageRhs {
            model: self,
            rod,
            crank,
            inputs,
            table,
            p_tolerance: STAGE_P_TOLERANCE_FACTOR * tol,
            friction_guess: 0.0,
            cell_hint: 0,
            sin_cos0: self.model_angle(crank).sin_cos(),
            shift: 0.0,
            start: None,
        };
        // The integrator follows φ = ϑ − c·Δ(τ) (`CageRhs::shift`).
        let (crank0, start) = rhs.link_at(0.0);
        // The cell of p_base is the first stage's hint (its P is p_base plus a small friction):
        // the binary search is made once, here.
        (rhs.shift, _, rhs.cell_hint) = rhs.quasi_static_ratio(start.p_base);
        let g0 = rhs.offset(&crank0, &start);
        rhs.start = Some((crank0, start));
        let mut integ = state.integrator;
        let y0 = [state.cage.theta - g0[0], state.cage.rate - g0[1]];
        let tolerance = Tolerance::from_solver_tolerance(tol, rate_scale(crank.speed));
        let y = integrator::advance(&mut rhs, 0.0, y0, h, &tolerance, &mut integ, stats)?;
        let (crank1, end) = rhs.link_at(h);
        let g1 = rhs.offset(&crank1, &end);
        Ok(RodState {
            cage: CageState { theta: y[0] + g1[0], rate: y[1] + g1[1] },
            integrator: integ,
        })
    }
}

/// The frequency [rad/s] that turns `solver.tolerance` into the absolute tolerance on ϑ̇
/// (docs/model.md §6 "Integration"): the crank's speed |ω|, not below RATE_SCALE_FLOOR. WHY: the
/// cage follows the crank, so ϑ̇'s amplitude is about |ω| times ϑ's, and an error of tol·|ω| on
/// ϑ̇ is the same share of its amplitude as tol on ϑ is of ϑ's. The integration errors are free
/// oscillations of the cage, Ω0 times larger in ϑ̇ than in ϑ; with the natural frequency Ω0 as
/// the scale (10 to 100 times |ω| for kvo630's spring and a 2 mm thin rod) ϑ̇ erred up to
/// 3 000·tol of its amplitude (tests/python/test_tolerance_proportionality.py).
#[inline]
pub(super) fn rate_scale(crank_speed: f64) -> f64 {
    crank_speed.abs().max(RATE_SCALE_FLOOR)
}

/// Lower bound [rad/s] of [`rate_scale`]: a crank at rest still gives ϑ̇ an absolute tolerance
/// (then 1 rad/s·tol, tighter than a moving crank's; only a free transient is left to integrate).
const RATE_SCALE_FLOOR: f64 = 1.0;

/// Relative tolerance on P inside the integrator's stages, as a fraction of the integrator
/// tolerance `tol` (§4 and §6 "Integration"). WHY 1e-3: an error δP changes ϑ̈ by about
/// (K_Δ'·Δ − K_ϑ'·ϑ + e_P)·δP/J_m. For kvo630 at P = 14.7 N (K_Δ' = −0.88 N/N,
/// K_ϑ' = −0.033 N·m/(rad·N), Δ ≤ 1 mm, |ϑ| ≤ 0.04 rad, J_m = 5e-7 kg·m²) a relative δP of
/// 1e-3·tol = 1e-11 at tol = 1e-8 (1.5e-10 N) is |δϑ̈| ≤ 7e-7 rad/s²: below 10 % of what the
/// error estimate h·Σ|e_j|·|δϑ̈| (Σ|e_j| ≈ 353, h ≈ 0.5 ms) may contain before it reaches the
/// tolerance on ϑ̇ (tol·|ω| ≈ 1.6e-6 rad/s at 1 500 strokes/min), and a static error of |δϑ̈|/Ω0² ≈ 3e-13 rad in ϑ.
/// P is still solved at every stage from that stage's crank angle and ϑ (no lag, nothing frozen).
pub(super) const STAGE_P_TOLERANCE_FACTOR: f64 = 1e-3;
/// Smallest integrator tolerance at which the stages use the stiffness table (its accuracy
/// 1e-13 is then STAGE_P_TOLERANCE_FACTOR·tol or better); tighter tolerances use the exact
/// beam column in every stage.
pub(super) const TABLE_MIN_TOLERANCE: f64 = table::ACCURACY / STAGE_P_TOLERANCE_FACTOR;
/// Newton iterations on the table (each a full step and a simplified one) before a stage falls
/// back to the exact solve.
const MAX_TABLE_NEWTON_STEPS: usize = 8;

/// P, K_ϑ(P), K_Δ(P) solved on the stiffness table.
#[derive(Clone, Copy, Debug)]
pub(super) struct TableSolution {
    pub(super) p: f64,
    pub(super) k_theta: f64,
    pub(super) k_delta: f64,
    pub(super) cell: usize,
}

/// Solves `P = p_base + F_fr(P)` (§4, §5.4) with the clamp loads `M0 = m_Δ(P)·Δ + m_ϑ(P)·ϑ`,
/// `V = v_Δ(P)·Δ − K_Δ(P)·ϑ` from the stiffness table, by Newton's method from `guess`; P = p_base
/// without guide. Stops when a step is ≤ `rel_tol`·max(|P|, |p_base|, |F_fr|) (or exactly
/// zero), and then moves K_ϑ, K_Δ to the new P to first order (the remaining error is second
/// order in a step that small). None when P leaves the table or Newton does not settle (the
/// caller then solves exactly, which also reports buckling and non-convergence).
///
/// WHY Newton: the residual `p_base + F_fr(P) − P` is piecewise smooth with slope −1 + F_fr'
/// (|F_fr'| ~ 1e-3 for kvo630), so from the previous stage's friction the first step leaves an
/// error ~F_fr''·e0² (~1e-12 N) and the second step meets the test; the slope comes with the
/// values (table.rs gives d/dP). At a kink of the friction law the one-sided slope still
/// contracts. WHY the second step with the first one's slope (a simplified Newton step): the
/// slope changes by ~F_fr''·e0 across the first step, which changes a step of ~1e-12 N by a
/// relative ~1e-8, so only the values are evaluated there (`StiffnessTable::values`,
/// `ClampFriction::total`), at about half the cost of values and slopes; a step that does not
/// yet meet the test continues as a full Newton iteration from its end.
// `!(d > 0)` also catches NaN.
#[allow(clippy::too_many_arguments, clippy::neg_cmp_op_on_partial_ord)]
#[inline]
pub(super) fn solve_on_table(
    table: &StiffnessTable,
    friction: Option<&ClampFriction>,
    p_base: f64,
    delta: f64,
    theta: f64,
    guess: f64,
    hint: usize,
    rel_tol: f64,
) -> Option<TableSolution> {
    use table::{FUNCTIONS, K_DELTA, K_THETA, M_DELTA, M_THETA, V_DELTA};
    let Some(cf) = friction else {
        let cell = table.find(p_base, hint)?;
        let c = table.eval(cell, p_base);
        return Some(TableSolution {
            p: p_base,
            k_theta: c.value[K_THETA],
            k_delta: c.value[K_DELTA],
            cell,
        });
    };
    // The solution when the step from p meets the stopping test, K_ϑ and K_Δ moved along it.
    let settled =
        |p: f64, step: f64, f: f64, v: &[f64; FUNCTIONS], d: &[f64; FUNCTIONS], cell: usize| {
            (step.abs() <= rel_tol * p.abs().max(p_base.abs()).max(f.abs())).then(|| {
                TableSolution {
                    p: p + step,
                    k_theta: v[K_THETA] + d[K_THETA] * step,
                    k_delta: v[K_DELTA] + d[K_DELTA] * step,
                    cell,
                }
            })
        };
    let mut p = guess;
    let mut cell = hint;
    for _ in 0..MAX_TABLE_NEWTON_STEPS {
        cell = table.find(p, cell)?;
        let c = table.eval(cell, p);
        let (v, d) = (&c.value, &c.slope);
        let m0 = v[M_DELTA] * delta + v[M_THETA] * theta;
        let vc = v[V_DELTA] * delta - v[K_DELTA] * theta;
        let dm0 = d[M_DELTA] * delta + d[M_THETA] * theta;
        let dvc = d[V_DELTA] * delta - d[K_DELTA] * theta;
        let (f, df) = cf.total_and_rate(m0, vc, dm0, dvc);
        let denominator = 1.0 - df;
        // A guide at or near self-locking (or NaN): leave it to the exact solve's diagnosis.
        if !(denominator > 0.0) {
            return None;
        }
        let step = (p_base + f - p) / denominator;
        if let Some(solution) = settled(p, step, f, v, d, cell) {
            return Some(solution);
        }
        // The simplified Newton step from the end of this one.
        p += step;
        cell = table.find(p, cell)?;
        let v = table.values(cell, p);
        let f = cf.total(
            v[M_DELTA] * delta + v[M_THETA] * theta,
            v[V_DELTA] * delta - v[K_DELTA] * theta,
        );
        let step = (p_base + f - p) / denominator;
        if let Some(solution) = settled(p, step, f, &v, d, cell) {
            return Some(solution);
        }
        p += step;
    }
    None
}

/// The cage equation as the integrator sees it: time τ from the start of the step, the crank
/// extrapolated to τ, P (inertia, process force, friction) following the crank at every stage.
///
/// Stages solve P on the stiffness table (`solve_on_table`), starting from the previous stage's
/// friction (a warm start local to this communication step: deterministic, nothing carried
/// between steps), and fall back to the exact `Model::instant` where the table does not apply.
pub(super) struct CageRhs<'a> {
    pub(super) model: &'a Model,
    pub(super) rod: &'a ElasticRod,
    pub(super) crank: &'a CrankState,
    pub(super) inputs: &'a Inputs,
    pub(super) table: Option<&'a StiffnessTable>,
    /// Relative stopping tolerance on P in the stages (STAGE_P_TOLERANCE_FACTOR·tol).
    pub(super) p_tolerance: f64,
    /// F_fr = P − p_base of the previous table stage (first guess P = p_base + this).
    pub(super) friction_guess: f64,
    /// Table cell of the previous table stage.
    pub(super) cell_hint: usize,
    /// sinθ, cosθ at the start of the step.
    pub(super) sin_cos0: (f64, f64),
    /// c of the variable the integrator follows, φ = ϑ − c·Δ(τ), with c = K_Δ/K_ϑ at the step's
    /// start (0: ϑ itself). WHY: most of ϑ is the quasi-static response K_Δ·Δ/K_ϑ to the crank
    /// (~0.04 rad for kvo630), and an explicit pair integrates that slow part through error
    /// terms ~(hΩ0)^k·(hω)^m that do not shrink with its order while hΩ0 ≳ 1 (integrator.rs);
    /// φ is the same equation (c·Δ, c·Δ̇, c·Δ̈ are exact functions of the crank, §6 piston law)
    /// with a forcing a few per cent of ϑ's, so the same tolerance allows ~1 ms internal steps
    /// instead of ~0.5 ms. The error control then works on φ: the same absolute tolerances, and
    /// the relative one on |φ| instead of |ϑ|; they differ by |c·Δ| (≲ 0.05 rad), which moves the
    /// bound by rtol·|c·Δ|, a few per cent of the absolute tolerance.
    pub(super) shift: f64,
    /// The crank and the link's loads at τ = 0, made for the shift and reused by the stages there.
    pub(super) start: Option<(CrankState, LinkLoads)>,
}

impl CageRhs<'_> {
    /// The crank extrapolated to τ and the link's loads there (sinθ, cosθ from those at the
    /// step's start, crank.rs).
    #[inline]
    fn link_at(&self, tau: f64) -> (CrankState, LinkLoads) {
        let crank = self.crank.extrapolate(tau);
        let phi = self.crank.speed * tau + 0.5 * self.crank.acceleration * tau * tau;
        let trig = sin_cos_shifted(self.sin_cos0.0, self.sin_cos0.1, phi);
        let ll = self.model.link_loads(&crank, self.inputs, trig);
        (crank, ll)
    }

    /// K_Δ/K_ϑ at P = `p` (from the table where it covers `p`), the c of [`CageRhs::shift`],
    /// K_ϑ, and the table's cell of `p` (0 off the table); (0, NaN, _) (ϑ itself is integrated)
    /// where the rod cannot take P (the stages then report it).
    fn quasi_static_ratio(&self, p: f64) -> (f64, f64, usize) {
        use table::{K_DELTA, K_THETA};
        let (k, cell) = match self.table.and_then(|t| t.find(p, 0).map(|c| (t.values(c, p), c))) {
            Some((v, cell)) => (Some((v[K_THETA], v[K_DELTA])), cell),
            None => (self.rod.beam_column(p).ok().map(|bc| (bc.k_theta, bc.k_delta)), 0),
        };
        match k {
            Some((k_theta, k_delta)) if k_theta > 0.0 && (k_delta / k_theta).is_finite() => {
                (k_delta / k_theta, k_theta, cell)
            }
            _ => (0.0, f64::NAN, cell),
        }
    }

    /// (c·Δ, c·Δ̇) at the instant of `crank` and `ll`: ϑ = φ + c·Δ, ϑ̇ = φ̇ + c·Δ̇.
    #[inline]
    fn offset(&self, crank: &CrankState, ll: &LinkLoads) -> [f64; 2] {
        match ll.piston {
            Some(pp) => [self.shift * pp.delta, self.shift * pp.delta_rate * crank.speed],
            None => [0.0, 0.0],
        }
    }

    /// ϑ̈ at τ for the cage state `cage`, with the crank and the link's loads there.
    #[inline]
    fn theta_ddot(
        &mut self,
        crank: &CrankState,
        ll: &LinkLoads,
        cage: &CageState,
    ) -> Result<f64, ModelError> {
        if let (Some(table), Some(pp)) = (self.table, ll.piston) {
            let friction = match &self.model.guide {
                Some(g) => Some(g.clamp_friction(ll.k.s, ll.velocity, ll.p_base)?),
                None => None,
            };
            let guess = ll.p_base + self.friction_guess;
            if let Some(sol) = solve_on_table(
                table,
                friction.as_ref(),
                ll.p_base,
                pp.delta,
                cage.theta,
                guess,
                self.cell_hint,
                self.p_tolerance,
            ) {
                self.friction_guess = sol.p - ll.p_base;
                self.cell_hint = sol.cell;
                let loads =
                    CageLoads { delta: pp.delta, delta_ddot: pp.delta_ddot, rod_force: sol.p };
                return Ok(self.rod.acceleration_with(sol.k_theta, sol.k_delta, &loads, cage));
            }
        }
        let i = self.model.instant(crank, self.inputs, cage)?;
        let (bc, loads, _, _) = &i.rod;
        Ok(self.rod.acceleration(bc, loads, cage))
    }
}

impl SecondOrderRhs for CageRhs<'_> {
    /// φ̈ at (τ, φ, φ̇): ϑ̈ at ϑ = φ + c·Δ, ϑ̇ = φ̇ + c·Δ̇, less c·Δ̈.
    #[inline]
    fn accel(&mut self, tau: f64, phi: f64, phi_rate: f64) -> Result<f64, ModelError> {
        let (crank, ll) = match self.start {
            Some(start) if tau == 0.0 => start,
            _ => self.link_at(tau),
        };
        let g = self.offset(&crank, &ll);
        let cage = CageState { theta: phi + g[0], rate: phi_rate + g[1] };
        let delta_ddot = ll.piston.map_or(0.0, |pp| pp.delta_ddot);
        Ok(self.theta_ddot(&crank, &ll, &cage)? - self.shift * delta_ddot)
    }

    /// (K_ϑ/J_m, B_d/J_m) at the step's start (P without friction, as for the shift): the cage
    /// equation's linear part in ϑ, and so in φ = ϑ − c·Δ (c·Δ is a function of time only),
    /// docs/model.md §6 "Cage equation". Computed when asked (the Lawson form only), so the
    /// FMU's own path carries nothing for it.
    fn linear_part(&self) -> Option<(f64, f64)> {
        let (_, start) = self.start?;
        let k_theta = self.quasi_static_ratio(start.p_base).1;
        let j = self.rod.cage_inertia;
        k_theta.is_finite().then(|| (k_theta / j, self.rod.damping / j))
    }
}

#[cfg(test)]
mod work_precision;
