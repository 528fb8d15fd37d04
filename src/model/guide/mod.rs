//! Guide friction caused by the redundant (statically indeterminate) supports of the
//! reciprocating link (docs/model.md §5, seed 000 corrected per §9).
//!
//! Where things are:
//! * `link_beam.rs`  – the link as a stepped Euler–Bernoulli beam; exact Mohr flexibilities (§5.1);
//! * `supports.rs`   – support contacts, frame axes, the beam problem → reactions R, M (§5.2, §5.3);
//! * `gland.rs`      – the reactions of a link with one gland in closed form over the stroke;
//! * `friction.rs`   – friction from the reactions, the implicit rod-force equation (§4, §5.3, §5.4);
//! * `validation.rs` – rejected configurations and their messages (§5.2);
//! * `dense_solve.rs`– the small allocation-free linear solve.
//!
//! Why this structure: the geometry is fixed at initialization and only s and the loads change
//! during the simulation; the reactions are affine in the loads, so one factorisation per
//! evaluation (none at all when no support is frame-fixed) gives everything the friction
//! iteration needs, and the rigid-rod equation, piecewise linear in P, is solved exactly.

// Index loops over the three supports mirror the formulas of §5.3.
#![allow(clippy::needless_range_loop)]

mod dense_solve;
mod friction;
mod gland;
mod link_beam;
mod supports;
mod tangent;
mod validation;

#[cfg(test)]
mod reference_fe;
#[cfg(test)]
mod tests;

use crate::model::error::{num, ModelError};
use friction::{AffineReaction, FrictionLaw};
use supports::{ClampInfluence, ForceMoment, Influence, LoadSet, SupportSystem};

/// `support_X.kind` (docs/model.md §5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SupportKind {
    None = 0,
    Pin = 1,
    Clamp = 2,
    TwoEdgeGuide = 3,
}

impl SupportKind {
    /// From the Integer parameter `support_X.kind`; `None` (the Rust value) for other integers.
    pub fn from_i32(value: i32) -> Option<SupportKind> {
        match value {
            0 => Some(SupportKind::None),
            1 => Some(SupportKind::Pin),
            2 => Some(SupportKind::Clamp),
            3 => Some(SupportKind::TwoEdgeGuide),
            _ => None,
        }
    }
}

/// One support (docs/model.md §5.2). Units: m, rad, N/m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupportSpec {
    pub kind: SupportKind,
    /// `support_X.attached == 1`: fixed in the frame, the link slides through it; its centre is
    /// at link coordinate `z − s`.
    pub frame_fixed: bool,
    /// Link coordinate of the centre (at s = 0 for a frame-fixed support) [m].
    pub z: f64,
    /// δ: lateral offset of the support's frame axis from the reference axis (A's) [m].
    pub offset: f64,
    /// α: tilt of the support's frame axis [rad]; the axis is `y = δ + α(Z − Z_ref)`.
    pub tilt: f64,
    /// Length l_n [m]: edge distance of a two-edge guide; a clamp's length for its friction.
    pub length: f64,
    /// Stiffness of each lateral contact [N/m]; 0 = rigid. A clamp's slope restraint is rigid.
    pub stiffness: f64,
    /// Friction coefficient (B's is `guide.friction_coefficient`).
    pub friction: f64,
}

impl SupportSpec {
    /// An absent support (kind 0).
    pub const NONE: SupportSpec = SupportSpec {
        kind: SupportKind::None,
        frame_fixed: false,
        z: 0.0,
        offset: 0.0,
        tilt: 0.0,
        length: 0.0,
        stiffness: 0.0,
        friction: 0.0,
    };
}

/// The link and its supports (docs/model.md §5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuideSpec {
    /// `link.l1..l4` [m]; a section of length 0 is absent.
    pub section_lengths: [f64; 4],
    /// `link.d1..d4` [m] (equivalent diameters: J = πd⁴/64).
    pub section_diameters: [f64; 4],
    /// `link.E` [Pa].
    pub e_modulus: f64,
    /// Supports A, B, C.
    pub supports: [SupportSpec; 3],
    /// `link.lateral_load` [N]: constant lateral force at B's centre (z = L without B). Like the
    /// rod's side load (§5.4) it acts at the current link coordinate of B's centre, which is
    /// `z_B − s` should B be frame-fixed.
    pub lateral_load: f64,
    /// `guide.rod_side_force`: the rigid rod's side load −P·tanβ acts at B's centre.
    pub rod_side_force: bool,
    /// `guide.velocity_scale` v_ε [m/s] of tanh(v/v_ε).
    pub velocity_scale: f64,
}

#[cfg(test)]
impl GuideSpec {
    /// The default machine of docs/model.md §8, from the one place its defaults live (`Params`).
    pub fn default_machine() -> GuideSpec {
        crate::model::params::Params::default()
            .guide_spec()
            .unwrap_or_else(|e| unreachable!("the defaults are valid: {e}"))
    }
}

/// Friction-related outputs at one evaluation (docs/model.md §5.3, §10 names in brackets).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GuideOutputs {
    /// P [N] (`rod.force`), satisfying P = p_base + friction_total.
    pub rod_force: f64,
    /// B's signed friction (`guide.friction`).
    pub friction_b: f64,
    /// R_B (`guide.reaction`).
    pub reaction_b: f64,
    /// M_B about B's centre (`guide.moment`).
    pub moment_b: f64,
    /// N₁ = R_B/2 + M_B/l_n, crank-side edge (`guide.edge_force_1`).
    pub edge_force_1: f64,
    /// N₂ = R_B/2 − M_B/l_n (`guide.edge_force_2`).
    pub edge_force_2: f64,
    /// R_A (`support_A.reaction`).
    pub reaction_a: f64,
    /// R_C (`support_C.reaction`).
    pub reaction_c: f64,
    /// A's + B's + C's signed friction (`link.friction_total`).
    pub friction_total: f64,
}

/// The friction of the elastic-rod machine at one (s, v) as a function of the clamp loads
/// (M0, V) (docs/model.md §5.3, §5.4), from [`Guide::clamp_friction`].
#[derive(Clone, Copy, Debug)]
pub struct ClampFriction<'a> {
    infl: ClampInfluence,
    laws: &'a [FrictionLaw; 3],
    /// tanh(v/v_ε).
    sign: f64,
    s: f64,
    v: f64,
}

impl ClampFriction<'_> {
    /// Reactions of A, B, C and their signed friction for clamp loads (M0, V).
    #[inline]
    fn reactions_and_friction(&self, m0: f64, vc: f64) -> ([ForceMoment; 3], [f64; 3]) {
        let mut at_p = [ForceMoment::default(); 3];
        let mut fr = [0.0; 3];
        for x in 0..3 {
            at_p[x] = self.infl.base[x]
                .plus_scaled(m0, self.infl.per_m0[x])
                .plus_scaled(vc, self.infl.per_v[x]);
            fr[x] = -self.sign * self.laws[x].magnitude(at_p[x]);
        }
        (at_p, fr)
    }

    /// Total signed friction F_fr for clamp loads (M0, V) [N].
    #[inline]
    pub fn total(&self, m0: f64, vc: f64) -> f64 {
        let (_, fr) = self.reactions_and_friction(m0, vc);
        fr[0] + fr[1] + fr[2]
    }

    /// F_fr and its derivative along a direction of the clamp loads: with (M0, V) moving at
    /// rates (dM0, dV) per unit of some parameter, the rate of F_fr (one-sided at a kink of
    /// the friction law, where the branch the value takes is differentiated).
    #[inline]
    pub fn total_and_rate(&self, m0: f64, vc: f64, dm0: f64, dvc: f64) -> (f64, f64) {
        let mut fr = [0.0; 3];
        let mut rate = 0.0;
        for x in 0..3 {
            let fm = self.infl.base[x]
                .plus_scaled(m0, self.infl.per_m0[x])
                .plus_scaled(vc, self.infl.per_v[x]);
            fr[x] = -self.sign * self.laws[x].magnitude(fm);
            let dfm = ForceMoment {
                r: dm0 * self.infl.per_m0[x].r + dvc * self.infl.per_v[x].r,
                m: dm0 * self.infl.per_m0[x].m + dvc * self.infl.per_v[x].m,
            };
            rate -= self.sign * self.laws[x].magnitude_rate(fm, dfm);
        }
        (fr[0] + fr[1] + fr[2], rate)
    }
}

/// Reaction of one support.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SupportReaction {
    /// Net lateral force on the link R [N] (+y).
    pub force: f64,
    /// Net moment on the link about the support's centre M [N·m] (turning +z toward +y).
    pub moment: f64,
    /// N₁, N₂ (see `GuideOutputs`); R/2 each for a pin or a clamp without length.
    pub edge_force_1: f64,
    pub edge_force_2: f64,
    /// Link coordinate of the support's centre at this s [m].
    pub centre: f64,
}

/// Reactions of A, B, C for given loads (absent supports report zeros).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reactions {
    pub supports: [SupportReaction; 3],
    /// Link coordinate where the side load (q + lateral_load) acts [m].
    pub load_point: f64,
}

/// The link's support system, everything independent of s precomputed.
#[derive(Clone, Debug)]
pub struct Guide {
    system: SupportSystem,
    laws: [FrictionLaw; 3],
    kinds: [SupportKind; 3],
    lengths: [f64; 3],
    rod_side_force: bool,
    velocity_scale: f64,
    stroke: f64,
}

/// Largest number of fixed-point iterations of the elastic-rod friction loop.
const MAX_FIXED_POINT_ITERATIONS: usize = 200;
/// Relative stopping test of the fixed-point iteration (docs/model.md §4: machine precision).
const FIXED_POINT_TOLERANCE: f64 = 1e-14;

impl Guide {
    /// Validates the link and supports and precomputes what does not change with s.
    /// `stroke` = S (s ∈ [0, S]); Z_ref uses mid-stroke s = S/2 (§5.2).
    /// Ok(None) when every support's kind is None: the friction model is off (§5.2).
    pub fn new(spec: &GuideSpec, stroke: f64) -> Result<Option<Guide>, ModelError> {
        if spec.supports.iter().all(|s| s.kind == SupportKind::None) {
            return Ok(None);
        }
        validation::check_scalars(spec, stroke)?;
        let beam = link_beam::LinkBeam::new(
            &spec.section_lengths,
            &spec.section_diameters,
            spec.e_modulus,
        )?;
        validation::check_positions(spec, beam.length, stroke)?;
        validation::check_held(spec, beam.length, stroke)?;
        let system = SupportSystem::new(spec, beam, stroke)?;
        let mut laws = [FrictionLaw::None; 3];
        let mut kinds = [SupportKind::None; 3];
        let mut lengths = [0.0; 3];
        for x in 0..3 {
            laws[x] = FrictionLaw::from_spec(&spec.supports[x]);
            kinds[x] = spec.supports[x].kind;
            lengths[x] = spec.supports[x].length;
        }
        Ok(Some(Guide {
            system,
            laws,
            kinds,
            lengths,
            rod_side_force: spec.rod_side_force,
            velocity_scale: spec.velocity_scale,
            stroke,
        }))
    }

    /// Link length L [m].
    pub fn link_length(&self) -> f64 {
        self.system.length()
    }

    /// Checks an evaluation input; s may exceed [0, S] by rounding only. Always inlined: with
    /// two callers it was left out of line, a call on every rigid evaluation.
    #[inline(always)]
    fn check_inputs(&self, s: f64, v: f64, p_base: f64) -> Result<(), ModelError> {
        let tol = 1e-9 * (self.stroke + self.system.length());
        if !s.is_finite() || s < -tol || s > self.stroke + tol {
            return Err(ModelError::evaluation(format!(
                "guide friction: stroke coordinate s = {} m outside the stroke [0, {}] m",
                num(s),
                num(self.stroke)
            )));
        }
        if !v.is_finite() || !p_base.is_finite() {
            return Err(ModelError::evaluation(format!(
                "guide friction: the link velocity v = {} m/s or the rod force without friction \
                 F_ext + Φ + F_bal = {} N is not finite (crank.speed, crank.acceleration or \
                 link.external_force too large for the machine)",
                num(v),
                num(p_base)
            )));
        }
        Ok(())
    }

    /// Rigid slider rod (§4, §5.4): solves `P = p_base + F_fr(P)` exactly.
    ///
    /// F_fr is piecewise linear in P through the side load `Q = −P·tanβ` at B's centre (when
    /// `rod_side_force`; plus `lateral_load` there; at z = L if B is absent), so the root is
    /// found exactly by Newton steps on linear pieces (see `friction.rs`). `p_base` = F_ext + Φ +
    /// F_bal [N], `v` the link velocity [m/s]. Returns ModelError::Evaluation when the
    /// uniqueness condition of §4 fails (self-locking guide).
    pub fn solve_rigid(
        &self,
        s: f64,
        v: f64,
        p_base: f64,
        tan_beta: f64,
    ) -> Result<GuideOutputs, ModelError> {
        let mut out = GuideOutputs::default();
        self.solve_rigid_into::<1>(s, v, p_base, tan_beta, &mut out)?;
        Ok(out)
    }

    /// [`Guide::solve_rigid`] writing its outputs into `out` (left alone on an error; a
    /// solution returned by value cost the single cylinder's loop step its copy). The pump's
    /// cylinders solve from two places (docs/model.md §4.1): `SITE` gives each its own copy
    /// (the first cylinder 0, the others and `solve_rigid` 1), so each copy has one caller and
    /// is inlined there, and the friction solver's helpers are `#[inline(always)]` so that they
    /// are inlined in both copies; one shared copy was a call on every evaluation (docs/performance.md).
    #[inline]
    pub fn solve_rigid_into<const SITE: u8>(
        &self,
        s: f64,
        v: f64,
        p_base: f64,
        tan_beta: f64,
        out: &mut GuideOutputs,
    ) -> Result<(), ModelError> {
        self.check_inputs(s, v, p_base)?;
        if !tan_beta.is_finite() {
            return Err(ModelError::evaluation(format!(
                "guide friction: tanβ = {} is not finite",
                num(tan_beta)
            )));
        }
        let (base, per_q) = self.system.rigid_influence(s)?;
        let dq_dp = if self.rod_side_force { -tan_beta } else { 0.0 };
        let affine: [AffineReaction; 3] = std::array::from_fn(|x| AffineReaction {
            base: base[x],
            slope: ForceMoment { r: dq_dp * per_q[x].r, m: dq_dp * per_q[x].m },
        });
        let sign = friction::regularized_sign(v / self.velocity_scale);
        let k = friction::sensitivity(&self.laws, &affine);
        let k_unique = sign.abs() * k;
        // Written so that NaN also fails.
        if k_unique.partial_cmp(&1.0) != Some(std::cmp::Ordering::Less) {
            return Err(ModelError::evaluation(format!(
                "the guide is (close to) self-locking at s = {} m: |tanh(v/v_ε)|·|tanβ|·Σ f·max(|∂R/∂Q|, \
                 2|∂M/∂Q|/l_n) = {} · {} · {} = {} ≥ 1 (v = {} m/s, tanβ = {}), so \
                 the rod force P = p_base + F_fr(P) has no unique solution (docs/model.md §4)",
                num(s),
                num(sign.abs()),
                num(tan_beta.abs()),
                num(if tan_beta != 0.0 { k / tan_beta.abs() } else { 0.0 }),
                num(k_unique),
                num(v),
                num(tan_beta),
            )));
        }
        let p = friction::solve_piecewise_linear(&self.laws, &affine, sign, p_base, k_unique);
        let mut at_p = [ForceMoment::default(); 3];
        for x in 0..3 {
            at_p[x] = affine[x].base.plus_scaled(p, affine[x].slope);
        }
        let fr = friction::signed_friction(&self.laws, &affine, sign, p);
        *out = self.outputs(p, &at_p, &fr);
        Ok(())
    }

    /// The friction of the elastic-rod machine at one (s, v) as a function of the clamp loads
    /// (§5.3, §5.4): the reactions are affine in (M0, V) at fixed s, so this is everything the
    /// rod-force equation needs besides M0(P), V(P). Checks the inputs like the solvers.
    #[inline]
    pub fn clamp_friction(
        &self,
        s: f64,
        v: f64,
        p_base: f64,
    ) -> Result<ClampFriction<'_>, ModelError> {
        self.check_inputs(s, v, p_base)?;
        Ok(ClampFriction {
            infl: self.system.clamp_influence(s)?,
            laws: &self.laws,
            sign: friction::regularized_sign(v / self.velocity_scale),
            s,
            v,
        })
    }

    /// Elastic rod clamped in the piston (§5.4, §6): the rod exerts moment M0 and transverse
    /// force V at z = L, both functions of P through `clamp_loads(P) -> (M0, V)`;
    /// `lateral_load` still acts at B's centre; no −P·tanβ term.
    ///
    /// Solves `P = p_base + F_fr(P)` starting from P = p_base; see [`Guide::solve_clamp_from`].
    pub fn solve_with_clamp_loads(
        &self,
        s: f64,
        v: f64,
        p_base: f64,
        clamp_loads: impl FnMut(f64) -> (f64, f64),
    ) -> Result<GuideOutputs, ModelError> {
        let cf = self.clamp_friction(s, v, p_base)?;
        self.solve_clamp_from(&cf, p_base, p_base, clamp_loads)
    }

    /// Solves `P = g(P) = p_base + F_fr(P)` for the friction `cf` from the first iterate
    /// `guess` (p_base when not finite) to the relative stopping test
    /// |g(P) − P| ≤ 1e-14·max(|g(P)|, |p_base|, |F_fr|) (§4: machine precision), and returns
    /// P = g(P_k) with the reactions and friction at the last iterate P_k, so that
    /// P = p_base + friction_total holds exactly. ModelError::Evaluation if it does not converge
    /// within 200 iterations or `clamp_loads` returns non-finite values.
    ///
    /// g is a contraction with a small slope (friction depends weakly on P, through the rod's
    /// side loads), so the plain iteration P ← g(P) gains only the factor |g'| per clamp-loads
    /// evaluation (each one a beam column, §6). The secant on g(P) − P through the last two
    /// iterates converges superlinearly (2–3 evaluations from p_base, one from a good guess);
    /// it is used only while the secant slope of g shows a contraction (|g'| < 1, which also
    /// holds across the kinks of the friction law: g is Lipschitz), else the plain step is taken,
    /// so where the plain iteration diverges the error of the contracting iteration is reported.
    pub fn solve_clamp_from(
        &self,
        cf: &ClampFriction,
        p_base: f64,
        guess: f64,
        mut clamp_loads: impl FnMut(f64) -> (f64, f64),
    ) -> Result<GuideOutputs, ModelError> {
        let mut p = if guess.is_finite() { guess } else { p_base };
        let mut last_step = f64::INFINITY;
        // (P_k, g(P_k)) of the previous iterate.
        let mut previous: Option<(f64, f64)> = None;
        for _ in 0..MAX_FIXED_POINT_ITERATIONS {
            let (m0, vc) = clamp_loads(p);
            if !m0.is_finite() || !vc.is_finite() {
                return Err(ModelError::evaluation(format!(
                    "guide friction: the rod's clamp loads at P = {} N are not finite \
                     (M0 = {} N·m, V = {} N)",
                    num(p),
                    num(m0),
                    num(vc)
                )));
            }
            let (at_p, fr) = cf.reactions_and_friction(m0, vc);
            let f_total = fr[0] + fr[1] + fr[2];
            let next = p_base + f_total;
            let step = (next - p).abs();
            if step <= FIXED_POINT_TOLERANCE * next.abs().max(p_base.abs()).max(f_total.abs()) {
                // Reactions and friction are those at the last iterate, which differs from
                // `next` by at most the tolerance; P = p_base + friction_total holds exactly.
                return Ok(self.outputs(next, &at_p, &fr));
            }
            last_step = step;
            let mut candidate = next;
            if let Some((p0, g0)) = previous {
                let slope = (next - g0) / (p - p0); // secant slope of g
                if slope.abs() < 1.0 {
                    // Root of the secant of g(P) − P.
                    let secant = p + (next - p) / (1.0 - slope);
                    if secant.is_finite() {
                        candidate = secant;
                    }
                }
            }
            previous = Some((p, next));
            p = candidate;
        }
        Err(ModelError::evaluation(format!(
            "guide friction with the elastic rod: the fixed-point iteration P = p_base + F_fr(P) did \
             not converge in {MAX_FIXED_POINT_ITERATIONS} iterations at s = {} m (v = {} m/s, \
             p_base = {} N, last P = {} N, last change {} N): friction depends too \
             strongly on the rod force (docs/model.md §4)",
            num(cf.s),
            num(cf.v),
            num(p_base),
            num(p),
            num(last_step)
        )))
    }

    /// Reactions for given loads, no friction: side load `q` [N] at the load point (B's centre,
    /// or z = L without B) in addition to `link.lateral_load`, and the clamp loads `m0` [N·m],
    /// `v_clamp` [N] at z = L. After a successful `new` the beam problem is regular; should it
    /// still fail numerically, every field is NaN (use `try_reactions` for the error).
    pub fn reactions(&self, s: f64, q: f64, m0: f64, v_clamp: f64) -> Reactions {
        self.try_reactions(s, q, m0, v_clamp).unwrap_or_else(|_| {
            let nan = SupportReaction {
                force: f64::NAN,
                moment: f64::NAN,
                edge_force_1: f64::NAN,
                edge_force_2: f64::NAN,
                centre: f64::NAN,
            };
            Reactions { supports: [nan; 3], load_point: f64::NAN }
        })
    }

    /// `reactions` with the error of a singular beam problem.
    pub fn try_reactions(
        &self,
        s: f64,
        q: f64,
        m0: f64,
        v_clamp: f64,
    ) -> Result<Reactions, ModelError> {
        let infl: Influence = self.system.influence(s, LoadSet::All)?;
        let mut out = Reactions { load_point: infl.load_point, ..Reactions::default() };
        for x in 0..3 {
            if self.kinds[x] == SupportKind::None {
                continue;
            }
            let fm = infl.base[x]
                .plus_scaled(q, infl.per_q[x])
                .plus_scaled(m0, infl.per_m0[x])
                .plus_scaled(v_clamp, infl.per_v[x]);
            let (n1, n2) = friction::edge_forces(self.kinds[x], self.lengths[x], fm);
            out.supports[x] = SupportReaction {
                force: fm.r,
                moment: fm.m,
                edge_force_1: n1,
                edge_force_2: n2,
                centre: infl.centres[x],
            };
        }
        Ok(out)
    }

    #[inline(always)]
    fn outputs(&self, p: f64, at_p: &[ForceMoment; 3], fr: &[f64; 3]) -> GuideOutputs {
        let b = at_p[1];
        let (n1, n2) = friction::edge_forces(self.kinds[1], self.lengths[1], b);
        GuideOutputs {
            rod_force: p,
            friction_b: fr[1],
            reaction_b: b.r,
            moment_b: b.m,
            edge_force_1: n1,
            edge_force_2: n2,
            reaction_a: at_p[0].r,
            reaction_c: at_p[2].r,
            friction_total: fr[0] + fr[1] + fr[2],
        }
    }
}
