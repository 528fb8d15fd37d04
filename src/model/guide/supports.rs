//! Support reactions of the link (docs/model.md §5.2, §5.3): the statically indeterminate beam
//! problem, solved by the flexibility method on the free link.
//!
//! Unknowns: one generalised force λ per contact (lateral force of a pin / clamp / guide edge,
//! moment of a clamp's slope restraint; forces on the link along +y, moments turning +z toward
//! +y) and the rigid-body motion `y = a + b·z` of the link. Equations (symmetric, bordered):
//!
//! * compatibility at every contact i: `a + b·zᵢ + Σⱼ Gᵢⱼ λⱼ + cᵢ λᵢ = uᵢ − wᵢ(loads)`
//!   (for a slope contact: `b + …`), where G is the cantilever flexibility of `link_beam.rs`,
//!   `cᵢ = 1/k` the compliance of an elastic lateral contact (a spring in series: the link point
//!   sits at `u − λ/k`), `uᵢ` the prescribed frame-axis displacement `δ + α(Z − Z_ref)` (or the
//!   slope α) and `wᵢ` the cantilever deflection caused by the applied loads;
//! * equilibrium of the free link: `Σ λ_lateral + Σ F_applied = 0` and
//!   `Σ λ_lateral·z + Σ λ_slope + Σ F_applied·z + Σ C_applied = 0`.
//!
//! The reactions are affine in the applied loads (side load Q at B's centre, clamp loads M0 and
//! V at z = L) and in the prescribed displacements, so one factorisation per s yields the
//! reactions as `base + Q·per_q + M0·per_m0 + V·per_v` for every load the friction iteration
//! will try. When no support is frame-fixed nothing in the matrix depends on s: everything is
//! precomputed in `new` and `base` is affine in s (a link-fixed support on a tilted axis moves
//! laterally by α·s). With frame-fixed supports (glands the link slides through) only their
//! rows change with s: the link-fixed block is inverted once in `new` and eliminated (static
//! condensation), so per s only a Schur complement of the frame-fixed contacts' size (1×1 for
//! one gland) is solved; with a single gland and a link-fixed load point that solve is tabulated
//! in closed form over the stroke (`gland.rs`). The full bordered system remains as the fallback
//! when the link-fixed supports alone do not hold the link or an elimination would lose digits
//! (`agree_with_full_solve`), and as the reference for the tests.
// Index loops mirror the matrix formulas above; `!(a > b)` tests deliberately reject NaN.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::dense_solve::{solve_in_place, Matrix, Rhs, MAX_EQ, MAX_RHS};
use super::gland::{self, GlandTable, Miss};
use super::link_beam::{Dof, LinkBeam, Station};
use super::validation::{contacts, is_rigid, NAMES};
use super::{GuideSpec, SupportKind};
use crate::model::error::{num, ModelError};

/// Maximum number of contacts: three supports with two each.
const MAX_CONTACTS: usize = 6;

/// One contact, in the scaled units of `link_beam.rs`.
#[derive(Clone, Copy, Debug)]
struct Constraint {
    support: usize,
    /// Link coordinate at s = 0 (scaled).
    z0: f64,
    /// Frame-fixed support: the contact sits at `z0 − s̃` on the link.
    moving: bool,
    /// Prescribed generalised displacement `u0 + u1·s̃` (deflection/L or slope).
    u0: f64,
    u1: f64,
    /// Scaled compliance 1/k of an elastic lateral contact, 0 when rigid.
    compliance: f64,
    /// Offset from the support's centre (scaled), the lever of its force about the centre.
    arm: f64,
    /// The station at s = 0 (valid at every s when not moving).
    station: Station,
}

impl Constraint {
    /// Adds this contact's multiplier λ to its support's net force and moment about the
    /// support's centre: a lateral contact contributes R += λ and M += λ·arm, a slope
    /// restraint M += λ.
    #[inline]
    fn add_to(&self, out: &mut [ForceMoment; 3], lam: f64) {
        let fm = &mut out[self.support];
        match self.station.dof {
            Dof::Deflection => {
                fm.r += lam;
                fm.m += lam * self.arm;
            }
            Dof::Slope => fm.m += lam,
        }
    }
}

/// Net lateral force R [N] and moment M about the support's centre [N·m] (docs/model.md §5.3).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct ForceMoment {
    pub r: f64,
    pub m: f64,
}

impl ForceMoment {
    /// `self + k·other`.
    #[inline]
    pub fn plus_scaled(self, k: f64, other: ForceMoment) -> ForceMoment {
        ForceMoment { r: self.r + k * other.r, m: self.m + k * other.m }
    }
}

/// The rigid rod's load cases (base, per Q) of the three supports, or their rates.
pub(super) type RigidInfluence = ([ForceMoment; 3], [ForceMoment; 3]);

/// Support reactions at one s as affine functions of the loads (SI units).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Influence {
    /// Prescribed support displacements plus `link.lateral_load` at the load point.
    pub base: [ForceMoment; 3],
    /// Per newton of side load Q at the load point (B's centre, or z = L without B).
    pub per_q: [ForceMoment; 3],
    /// Per newton-metre of the clamp moment M0 at z = L.
    pub per_m0: [ForceMoment; 3],
    /// Per newton of the clamp's transverse force V at z = L.
    pub per_v: [ForceMoment; 3],
    /// Link coordinates of the support centres at this s [m].
    pub centres: [f64; 3],
    /// Link coordinate of the side load at this s [m].
    pub load_point: f64,
}

/// The clamp load cases of an [`Influence`]: reactions = base + M0·per_m0 + V·per_v.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct ClampInfluence {
    pub base: [ForceMoment; 3],
    pub per_m0: [ForceMoment; 3],
    pub per_v: [ForceMoment; 3],
}

/// Which load cases a caller needs (each is one right-hand side of the same factorisation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum LoadSet {
    /// Base and Q (rigid slider rod).
    Rigid,
    /// Base, M0 and V (elastic rod clamped in the piston).
    Clamp,
    /// All four.
    All,
}

/// Right-hand-side columns of one solve: column 0 is always the base case.
#[derive(Clone, Copy, Debug)]
struct Columns {
    q: Option<usize>,
    m0: Option<usize>,
    v: Option<usize>,
    count: usize,
    rate_only: bool,
}

impl Columns {
    fn new(set: LoadSet, rate_only: bool) -> Columns {
        let (q, m0, v) = match (rate_only, set) {
            (true, _) => (None, None, None),
            (false, LoadSet::Rigid) => (Some(1), None, None),
            (false, LoadSet::Clamp) => (None, Some(1), Some(2)),
            (false, LoadSet::All) => (Some(1), Some(2), Some(3)),
        };
        let count = 1 + [q, m0, v].iter().filter(|c| c.is_some()).count();
        Columns { q, m0, v, count, rate_only }
    }
}

/// Precomputed static condensation onto the frame-fixed contacts (block 1 = link-fixed
/// contacts followed by the rigid-body unknowns a, b). Every array is zero beyond block 1's
/// size n1: the per-s products run over the whole width and rely on it.
#[derive(Clone, Debug)]
struct Condensed {
    k11_inv: Matrix,
    /// K₁₁⁻¹ times the block-1 right-hand sides (precomputed only for a link-fixed load point):
    /// base = y_base0 + s̃·y_base1, and the unit loads.
    y_base0: [f64; MAX_EQ],
    y_base1: [f64; MAX_EQ],
    y_q: [f64; MAX_EQ],
    y_m0: [f64; MAX_EQ],
    y_v: [f64; MAX_EQ],
    /// The link-fixed contacts' reactions (scaled R̃, M̃ per support) of those y vectors.
    g_base0: [ForceMoment; 3],
    g_base1: [ForceMoment; 3],
    g_q: [ForceMoment; 3],
    g_m0: [ForceMoment; 3],
    g_v: [ForceMoment; 3],
    /// Station of the (link-fixed) load point.
    load: Station,
}

/// Everything about the supports that does not change with s.
#[derive(Clone, Debug)]
pub(super) struct SupportSystem {
    beam: LinkBeam,
    cons: [Constraint; MAX_CONTACTS],
    /// Number of contacts; the first `n_fixed` are link-fixed, the rest frame-fixed.
    n: usize,
    n_fixed: usize,
    /// Support centres: scaled link coordinate at s = 0 and whether they move along the link.
    centre_z0: [f64; 3],
    centre_moving: [bool; 3],
    /// Side-load point (B's centre, or z = L when B is absent), scaled, and whether it moves.
    load_z0: f64,
    load_moving: bool,
    /// `link.lateral_load` in scaled force units.
    lateral: f64,
    /// Scale factors: L [m] and the force unit EJ_ref/L² [N].
    length: f64,
    force_unit: f64,
    /// Matrix entries among link-fixed contacts and their border entries (constant).
    fixed_block: Matrix,
    /// Stations of the clamp loads at z = L (force and moment).
    end_force: Station,
    end_moment: Station,
    /// When nothing moves along the link: influence at s = 0 and d(base)/ds [N/m, N·m/m].
    precomputed: Option<(Influence, [ForceMoment; 3])>,
    /// When some contacts are frame-fixed and the link-fixed ones hold the link by themselves.
    condensed: Option<Condensed>,
    /// When, besides, there is one frame-fixed contact and the load point is link-fixed: the
    /// condensed solve tabulated in closed form over the stroke (`gland.rs`).
    gland: Option<GlandTable>,
}

impl SupportSystem {
    /// Builds the contacts of the (already validated) supports. `stroke` is S [m]; the frame
    /// axis of each support is referred to its centre's frame position at mid-stroke (§5.2).
    pub fn new(spec: &GuideSpec, beam: LinkBeam, stroke: f64) -> Result<SupportSystem, ModelError> {
        let length = beam.length;
        let force_unit = beam.ej_ref / (length * length);
        let s_half = 0.5 * stroke / length;
        let placeholder = Constraint {
            support: 0,
            z0: 0.0,
            moving: false,
            u0: 0.0,
            u1: 0.0,
            compliance: 0.0,
            arm: 0.0,
            station: beam.station(Dof::Deflection, 0.0),
        };
        let mut fixed = [placeholder; MAX_CONTACTS];
        let mut moving = [placeholder; MAX_CONTACTS];
        let (mut n_fixed, mut n_moving) = (0usize, 0usize);
        let mut centre_z0 = [0.0; 3];
        let mut centre_moving = [false; 3];
        for (x, sup) in spec.supports.iter().enumerate() {
            centre_z0[x] = sup.z / length;
            centre_moving[x] = sup.frame_fixed;
            let (cs, count) = contacts(sup);
            for c in cs.iter().take(count) {
                let e = c.offset / length;
                let delta = sup.offset / length;
                let alpha = sup.tilt;
                // Frame axis y = δ + α(Z − Z_ref), Z = z + s (§5.2):
                // link-fixed: Z_ref = z_X + S/2, contact at Z = z_X + e + s → δ + α(e + s − S/2);
                // frame-fixed: Z_ref = z_X, contact at Z = z_X + e      → δ + α·e.
                let (u0, u1) = match (c.dof, sup.frame_fixed) {
                    (Dof::Slope, _) => (alpha, 0.0),
                    (Dof::Deflection, false) => (delta + alpha * (e - s_half), alpha),
                    (Dof::Deflection, true) => (delta + alpha * e, 0.0),
                };
                let compliance = if is_rigid(sup, c) {
                    0.0
                } else {
                    // Scaled compliance: (1/k)·EJ_ref/L³.
                    beam.ej_ref / (sup.stiffness * length * length * length)
                };
                let z0 = (sup.z + c.offset) / length;
                let con = Constraint {
                    support: x,
                    z0,
                    moving: sup.frame_fixed,
                    u0,
                    u1,
                    compliance,
                    arm: e,
                    station: beam.station(c.dof, z0),
                };
                if sup.frame_fixed {
                    moving[n_moving] = con;
                    n_moving += 1;
                } else {
                    fixed[n_fixed] = con;
                    n_fixed += 1;
                }
            }
        }
        let mut cons = [placeholder; MAX_CONTACTS];
        cons[..n_fixed].copy_from_slice(&fixed[..n_fixed]);
        cons[n_fixed..n_fixed + n_moving].copy_from_slice(&moving[..n_moving]);
        let n = n_fixed + n_moving;

        let b = &spec.supports[1];
        let (load_z0, load_moving) =
            if b.kind == SupportKind::None { (1.0, false) } else { (b.z / length, b.frame_fixed) };

        let mut fixed_block: Matrix = [[0.0; MAX_EQ]; MAX_EQ];
        for i in 0..n_fixed {
            for j in 0..n_fixed {
                fixed_block[i][j] = LinkBeam::flexibility(&cons[i].station, &cons[j].station);
            }
            fixed_block[i][i] += cons[i].compliance;
            let (p, q) = border(&cons[i].station);
            fixed_block[i][n] = p;
            fixed_block[i][n + 1] = q;
            fixed_block[n][i] = p;
            fixed_block[n + 1][i] = q;
        }

        let mut system = SupportSystem {
            end_force: beam.station(Dof::Deflection, 1.0),
            end_moment: beam.station(Dof::Slope, 1.0),
            beam,
            cons,
            n,
            n_fixed,
            centre_z0,
            centre_moving,
            load_z0,
            load_moving,
            lateral: spec.lateral_load / force_unit,
            length,
            force_unit,
            fixed_block,
            precomputed: None,
            condensed: None,
            gland: None,
        };
        if n_moving == 0 && !load_moving {
            let at_zero = system.solve_full(0.0, LoadSet::All, false)?;
            let rate = system.solve_full(0.0, LoadSet::All, true)?;
            system.precomputed = Some((at_zero, rate.base));
        } else {
            system.condensed = system.condense();
            if n_moving == 1 && !load_moving {
                system.gland = system.gland_table(stroke);
            }
            let (condensed_ok, gland_ok) = system.agree_with_full_solve(stroke);
            if !condensed_ok {
                system.condensed = None;
            }
            if !gland_ok {
                system.gland = None;
            }
        }
        Ok(system)
    }

    /// K₁₁⁻¹ of the link-fixed block and its products with the constant right-hand sides;
    /// None when the link-fixed contacts alone do not hold the link (K₁₁ singular).
    fn condense(&self) -> Option<Condensed> {
        let nf = self.n_fixed;
        let n = self.n;
        let n1 = nf + 2;
        // K₁₁ with the rigid-body unknowns at nf, nf + 1.
        let mut k11: Matrix = [[0.0; MAX_EQ]; MAX_EQ];
        for i in 0..nf {
            for j in 0..nf {
                k11[i][j] = self.fixed_block[i][j];
            }
            k11[i][nf] = self.fixed_block[i][n];
            k11[i][nf + 1] = self.fixed_block[i][n + 1];
            k11[nf][i] = self.fixed_block[n][i];
            k11[nf + 1][i] = self.fixed_block[n + 1][i];
        }
        // Inverse column by column (identity right-hand sides, MAX_RHS at a time).
        let mut k11_inv: Matrix = [[0.0; MAX_EQ]; MAX_EQ];
        let mut start = 0;
        while start < n1 {
            let width = MAX_RHS.min(n1 - start);
            let mut a = k11;
            let mut b: Rhs = [[0.0; MAX_RHS]; MAX_EQ];
            for k in 0..width {
                b[start + k][k] = 1.0;
            }
            solve_in_place(&mut a, &mut b, n1, width).ok()?;
            for i in 0..n1 {
                for k in 0..width {
                    k11_inv[i][start + k] = b[i][k];
                }
            }
            start += width;
        }
        // K₁₁ is symmetric, so is its inverse: remove the rounding asymmetry (the per-s product
        // uses rows for columns).
        for i in 0..n1 {
            for j in 0..i {
                let v = 0.5 * (k11_inv[i][j] + k11_inv[j][i]);
                k11_inv[i][j] = v;
                k11_inv[j][i] = v;
            }
        }
        // Condense only when K₁₁ is well conditioned (∞-norm condition number): nearly
        // coincident link-fixed contacts would make the condensed path lose digits that the
        // full system, held also by the frame-fixed contacts, keeps (about 2·cond·ε of the
        // largest reaction, measured on random configurations; default machine: cond 2.4e3).
        // `new` also checks the condensed solve against the full one over the stroke.
        let norm = |m: &Matrix| {
            (0..n1).map(|i| (0..n1).map(|j| m[i][j].abs()).sum::<f64>()).fold(0.0, f64::max)
        };
        let condition = norm(&k11) * norm(&k11_inv);
        if !(condition < 1e10) {
            return None;
        }
        let mut c = Condensed {
            k11_inv,
            y_base0: [0.0; MAX_EQ],
            y_base1: [0.0; MAX_EQ],
            y_q: [0.0; MAX_EQ],
            y_m0: [0.0; MAX_EQ],
            y_v: [0.0; MAX_EQ],
            g_base0: [ForceMoment::default(); 3],
            g_base1: [ForceMoment::default(); 3],
            g_q: [ForceMoment::default(); 3],
            g_m0: [ForceMoment::default(); 3],
            g_v: [ForceMoment::default(); 3],
            load: self.beam.station(Dof::Deflection, self.load_z0),
        };
        if !self.load_moving {
            let load_z = self.load_z0;
            let load = self.beam.station(Dof::Deflection, load_z);
            let all = Columns::new(LoadSet::All, false);
            let rate = Columns::new(LoadSet::All, true);
            let mut r: Rhs = [[0.0; MAX_RHS]; MAX_EQ];
            let mut r1: Rhs = [[0.0; MAX_RHS]; MAX_EQ];
            for i in 0..nf {
                r[i] = self.contact_rhs(i, &self.cons[i].station, &load, 0.0, &all);
                r1[i] = self.contact_rhs(i, &self.cons[i].station, &load, 0.0, &rate);
            }
            let (ef, em) = self.equilibrium_rhs(load_z, &all);
            r[nf] = ef;
            r[nf + 1] = em;
            for i in 0..n1 {
                let dot =
                    |col: &Rhs, k: usize| (0..n1).map(|j| c.k11_inv[i][j] * col[j][k]).sum::<f64>();
                c.y_base0[i] = dot(&r, 0);
                c.y_base1[i] = dot(&r1, 0);
                c.y_q[i] = dot(&r, 1);
                c.y_m0[i] = dot(&r, 2);
                c.y_v[i] = dot(&r, 3);
            }
            c.g_base0 = self.sum_fixed(&c.y_base0);
            c.g_base1 = self.sum_fixed(&c.y_base1);
            c.g_q = self.sum_fixed(&c.y_q);
            c.g_m0 = self.sum_fixed(&c.y_m0);
            c.g_v = self.sum_fixed(&c.y_v);
        }
        Some(c)
    }

    /// Whether the condensed solve and the gland table agree with the full bordered system
    /// within 1e-11 of the largest reaction of each load case at 24 points of the stroke (true
    /// for a path that is absent). Both eliminations lose digits where the full system with
    /// pivoting does not (link-fixed contacts nearly coincident, a rigid gland passing close to
    /// a rigid contact: about 2·cond·ε); where they would lose more than that, `new` drops them,
    /// so that every path stays well inside the 1e-10 the FE reference tests allow.
    fn agree_with_full_solve(&self, stroke: f64) -> (bool, bool) {
        const POINTS: usize = 24;
        let close = |a: &Influence, b: &Influence| {
            let cases = |i: &Influence| [i.base, i.per_q, i.per_m0, i.per_v];
            cases(a).iter().zip(cases(b).iter()).all(|(p, q)| {
                let scale = q.iter().map(|f| f.r.abs().max(f.m.abs())).fold(0.0, f64::max);
                (0..3)
                    .all(|x| (p[x].r - q[x].r).abs().max((p[x].m - q[x].m).abs()) <= 1e-11 * scale)
            })
        };
        let (mut condensed_ok, mut gland_ok) = (true, true);
        for i in 0..POINTS {
            // Not at the stroke's ends only: a fraction away from simple ratios.
            let s_scaled = stroke * ((i as f64 + 0.381_966) / POINTS as f64) / self.length;
            let Ok(full) = self.solve_full(s_scaled, LoadSet::All, false) else { continue };
            if let Some(c) = &self.condensed {
                if let Ok(a) = self.solve_condensed(c, s_scaled, &Columns::new(LoadSet::All, false))
                {
                    condensed_ok &= close(&a, &full);
                }
            }
            if let Some(g) = &self.gland {
                if let Some(Ok(a)) = self.gland_influence(g, s_scaled, LoadSet::All) {
                    gland_ok &= close(&a, &full);
                }
            }
        }
        (condensed_ok, gland_ok)
    }

    /// The closed-form table of one frame-fixed contact (`gland.rs`) over the stroke, a little
    /// beyond it for the rounding `Guide::check_inputs` allows; None without a condensation.
    fn gland_table(&self, stroke: f64) -> Option<GlandTable> {
        let c = self.condensed.as_ref()?;
        let nf = self.n_fixed;
        let l = self.length;
        let tol = 2e-9 * (stroke + l) / l;
        // The gland sits at z₀ − s̃: the polynomials change where it meets a section boundary,
        // a link-fixed contact or the load point.
        let z0 = self.cons[nf].z0;
        let mut breaks = [0.0; gland::MAX_PIECES];
        let mut count = 0;
        let points = self.beam.interior_bounds().iter().copied();
        let points =
            points.chain(self.cons[..nf].iter().map(|k| k.z0)).chain(std::iter::once(self.load_z0));
        for z in points {
            if count == breaks.len() {
                return None;
            }
            breaks[count] = z0 - z;
            count += 1;
        }
        let fu = self.force_unit;
        let factor = [fu, 1.0, 1.0 / l, 1.0];
        let si = |g: &[ForceMoment; 3], f: f64| -> [ForceMoment; 3] {
            std::array::from_fn(|x| ForceMoment { r: g[x].r * f, m: g[x].m * f * l })
        };
        let pre = [
            si(&c.g_base0, factor[0]),
            si(&c.g_q, factor[1]),
            si(&c.g_m0, factor[2]),
            si(&c.g_v, factor[3]),
        ];
        GlandTable::new(
            -tol,
            stroke / l + tol,
            &breaks[..count],
            pre,
            si(&c.g_base1, factor[0]),
            |s| self.gland_sample(c, s, &factor),
        )
    }

    /// The quantities `gland.rs` tabulates, from the condensed solve at scaled s̃ for the one
    /// frame-fixed contact: the condensed right-hand sides b_k of the four load cases times
    /// `factor[k]` (SI), e − g per support (R, and M times L), S and K₂₂ + 1/k.
    fn gland_sample(&self, c: &Condensed, s_scaled: f64, factor: &[f64; 4]) -> [f64; gland::LANES] {
        let nf = self.n_fixed;
        let n1 = nf + 2;
        let st = self.station_at(nf, s_scaled);
        let mut col = [0.0; MAX_EQ];
        for i in 0..nf {
            col[i] = LinkBeam::flexibility(&self.cons[i].station, &st);
        }
        let (p, q) = border(&st);
        col[nf] = p;
        col[nf + 1] = q;
        let mut x = [0.0; MAX_EQ];
        for j in 0..n1 {
            for i in 0..n1 {
                x[i] += c.k11_inv[j][i] * col[j];
            }
        }
        let gx = self.sum_fixed(&x);
        let b = self.contact_rhs(nf, &st, &c.load, s_scaled, &Columns::new(LoadSet::All, false));
        let mut y_base = c.y_base0;
        for i in 0..MAX_EQ {
            y_base[i] += s_scaled * c.y_base1[i];
        }
        let dot = |u: &[f64; MAX_EQ], v: &[f64; MAX_EQ]| (0..n1).map(|i| u[i] * v[i]).sum::<f64>();
        let mut lanes = [0.0; gland::LANES];
        let lane = [gland::B_BASE, gland::B_Q, gland::B_M0, gland::B_V];
        for (k, y) in [&y_base, &c.y_q, &c.y_m0, &c.y_v].into_iter().enumerate() {
            lanes[lane[k]] = (b[k] - dot(&col, y)) * factor[k];
        }
        let mut e = [ForceMoment::default(); 3];
        self.cons[nf].add_to(&mut e, 1.0);
        for s in 0..3 {
            lanes[gland::E_MINUS_G + 2 * s] = e[s].r - gx[s].r;
            lanes[gland::E_MINUS_G + 1 + 2 * s] = (e[s].m - gx[s].m) * self.length;
        }
        let k22 = LinkBeam::flexibility(&st, &st) + self.cons[nf].compliance;
        lanes[gland::SCHUR] = k22 - dot(&col, &x);
        lanes[gland::SCALE] = k22;
        lanes
    }

    /// The influence from the gland table at scaled s̃; None outside its range.
    #[inline]
    fn gland_influence(
        &self,
        g: &GlandTable,
        s_scaled: f64,
        set: LoadSet,
    ) -> Option<Result<Influence, ModelError>> {
        match g.evaluate(s_scaled, set) {
            Ok(r) => {
                let l = self.length;
                let mut infl = Influence {
                    base: r.base,
                    per_q: r.per_q,
                    per_m0: r.per_m0,
                    per_v: r.per_v,
                    centres: [0.0; 3],
                    load_point: self.load_z0 * l,
                };
                for x in 0..3 {
                    infl.centres[x] = (self.centre_z0[x]
                        - if self.centre_moving[x] { s_scaled } else { 0.0 })
                        * l;
                }
                Some(Ok(infl))
            }
            Err(Miss::Singular) => Some(Err(self.singular_error(s_scaled))),
            Err(Miss::OutOfRange) => None,
        }
    }

    /// Whether the per-s solve uses the gland table (for tests).
    #[cfg(test)]
    pub fn has_gland_table(&self) -> bool {
        self.gland.is_some()
    }

    /// Whether the per-s solve uses static condensation (for tests).
    #[cfg(test)]
    pub fn has_condensation(&self) -> bool {
        self.condensed.is_some()
    }

    /// L [m].
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Support reactions at stroke coordinate s [m] as affine functions of the loads.
    #[inline]
    pub fn influence(&self, s: f64, set: LoadSet) -> Result<Influence, ModelError> {
        if let Some((at_zero, rate)) = &self.precomputed {
            let mut infl = *at_zero;
            for x in 0..3 {
                infl.base[x] = at_zero.base[x].plus_scaled(s, rate[x]);
            }
            return Ok(infl);
        }
        self.solve_moving(s / self.length, set)
    }

    /// The rigid rod's load cases of [`SupportSystem::influence`] only (base, per Q): what
    /// `Guide::solve_rigid` needs, without building the rest. Always inlined: the rigid
    /// evaluation's hot path (a second caller, the directional derivative, would otherwise make
    /// it an out-of-line call there).
    #[inline(always)]
    pub fn rigid_influence(
        &self,
        s: f64,
    ) -> Result<([ForceMoment; 3], [ForceMoment; 3]), ModelError> {
        if let Some((at_zero, rate)) = &self.precomputed {
            let base = std::array::from_fn(|x| at_zero.base[x].plus_scaled(s, rate[x]));
            return Ok((base, at_zero.per_q));
        }
        if let Some(g) = &self.gland {
            match g.evaluate_rigid(s / self.length) {
                Ok(r) => return Ok(r),
                Err(Miss::Singular) => return Err(self.singular_error(s / self.length)),
                Err(Miss::OutOfRange) => {}
            }
        }
        let infl = self.solve(s / self.length, LoadSet::Rigid, false)?;
        Ok((infl.base, infl.per_q))
    }

    /// d/ds of [`SupportSystem::rigid_influence`] (base, per Q) [N/m, N·m/m, 1/m], for the exact
    /// directional derivatives: exact where the reactions are known in closed form in s (nothing
    /// moves along the link: base affine in s; one gland: the tabulated rational functions,
    /// `gland.rs`). None where only a linear solve at each s gives them (more than one
    /// frame-fixed contact, or a frame-fixed load point): no rate is offered there.
    pub fn rigid_influence_rate(&self, s: f64) -> Result<Option<RigidInfluence>, ModelError> {
        if let Some((_, rate)) = &self.precomputed {
            return Ok(Some((*rate, [ForceMoment::default(); 3])));
        }
        if let Some(g) = &self.gland {
            let per_metre = 1.0 / self.length;
            let scale = |a: [ForceMoment; 3]| {
                a.map(|f| ForceMoment { r: f.r * per_metre, m: f.m * per_metre })
            };
            return match g.evaluate_rigid_rate(s / self.length) {
                Ok((base, per_q)) => Ok(Some((scale(base), scale(per_q)))),
                Err(Miss::Singular) => Err(self.singular_error(s / self.length)),
                Err(Miss::OutOfRange) => Ok(None),
            };
        }
        Ok(None)
    }

    /// d(base)/ds of [`SupportSystem::clamp_influence`] [N/m, N·m/m] when nothing moves along
    /// the link (base affine in s, per M0 and per V constant); `None` otherwise, where the
    /// reactions come from a solve at each position (the directional derivative of an elastic
    /// rod with respect to crank.angle is then not provided).
    pub fn clamp_influence_rate(&self) -> Option<[ForceMoment; 3]> {
        self.precomputed.as_ref().map(|(_, rate)| *rate)
    }

    /// The clamp load cases of [`SupportSystem::influence`] only (base, per M0, per V): what the
    /// elastic rod's friction needs at every stage of the integrator, without copying the rest.
    #[inline]
    pub fn clamp_influence(&self, s: f64) -> Result<ClampInfluence, ModelError> {
        if let Some((at_zero, rate)) = &self.precomputed {
            let mut base = [ForceMoment::default(); 3];
            for x in 0..3 {
                base[x] = at_zero.base[x].plus_scaled(s, rate[x]);
            }
            return Ok(ClampInfluence { base, per_m0: at_zero.per_m0, per_v: at_zero.per_v });
        }
        let infl = self.solve_moving(s / self.length, LoadSet::Clamp)?;
        Ok(ClampInfluence { base: infl.base, per_m0: infl.per_m0, per_v: infl.per_v })
    }

    /// Reactions at scaled s̃ when something moves along the link: the gland table, else
    /// [`SupportSystem::solve`].
    fn solve_moving(&self, s_scaled: f64, set: LoadSet) -> Result<Influence, ModelError> {
        if let Some(g) = &self.gland {
            if let Some(r) = self.gland_influence(g, s_scaled, set) {
                return r;
            }
        }
        self.solve(s_scaled, set, false)
    }

    /// Reactions at scaled s̃: by static condensation onto the frame-fixed contacts when the
    /// link-fixed ones hold the link by themselves (precomputed inverse), else by the full
    /// bordered system. With `rate_only` the only right-hand side is d(u)/ds̃ (no loads), giving
    /// d(base)/ds in SI units per metre (precomputation when nothing moves along the link).
    pub(super) fn solve(
        &self,
        s_scaled: f64,
        set: LoadSet,
        rate_only: bool,
    ) -> Result<Influence, ModelError> {
        match &self.condensed {
            Some(c) if !rate_only => self.solve_condensed(c, s_scaled, &Columns::new(set, false)),
            _ => self.solve_full(s_scaled, set, rate_only),
        }
    }

    /// The full bordered system, one Gaussian elimination (the reference path).
    pub(super) fn solve_full(
        &self,
        s_scaled: f64,
        set: LoadSet,
        rate_only: bool,
    ) -> Result<Influence, ModelError> {
        let cols = Columns::new(set, rate_only);
        let n = self.n;
        let mut a = self.fixed_block;
        let mut stations = [self.cons[0].station; MAX_CONTACTS];
        for i in 0..n {
            stations[i] = self.station_at(i, s_scaled);
        }
        for i in self.n_fixed..n {
            for j in 0..n {
                let g = LinkBeam::flexibility(&stations[i], &stations[j]);
                a[i][j] = g;
                a[j][i] = g;
            }
            a[i][i] += self.cons[i].compliance;
            let (p, q) = border(&stations[i]);
            a[i][n] = p;
            a[i][n + 1] = q;
            a[n][i] = p;
            a[n + 1][i] = q;
        }
        let load_z = self.load_z(s_scaled);
        let load = self.beam.station(Dof::Deflection, load_z);
        let mut rhs: Rhs = [[0.0; MAX_RHS]; MAX_EQ];
        for i in 0..n {
            rhs[i] = self.contact_rhs(i, &stations[i], &load, s_scaled, &cols);
        }
        let (eq_f, eq_m) = self.equilibrium_rhs(load_z, &cols);
        rhs[n] = eq_f;
        rhs[n + 1] = eq_m;
        if solve_in_place(&mut a, &mut rhs, n + 2, cols.count).is_err() {
            return Err(self.singular_error(s_scaled));
        }
        Ok(self.gather(&rhs, load_z, s_scaled, &cols, rate_only))
    }

    /// Static condensation onto the frame-fixed contacts: with K₁₁ (link-fixed contacts and the
    /// rigid-body unknowns) inverted once in `new`, per s only the frame-fixed contacts'
    /// coupling columns `K₁₂`, `X = K₁₁⁻¹K₁₂` and a Schur complement of their size (usually 1×1)
    /// are formed. With a link-fixed load point (the usual case: only glands are frame-fixed)
    /// the block-1 load solutions `y₁ = K₁₁⁻¹rhs₁` and their reactions are precomputed too.
    fn solve_condensed(
        &self,
        c: &Condensed,
        s_scaled: f64,
        cols: &Columns,
    ) -> Result<Influence, ModelError> {
        let nf = self.n_fixed;
        let n1 = nf + 2;
        let n2 = self.n - nf;
        // Block-1 solutions of the load columns (column-major) and their link-fixed reactions.
        let mut ycols = [[0.0; MAX_EQ]; MAX_RHS];
        let mut pre = [[ForceMoment::default(); 3]; MAX_RHS];
        let load_z = self.load_z(s_scaled);
        let load = if self.load_moving {
            let load = self.beam.station(Dof::Deflection, load_z);
            let mut rhs1: Rhs = [[0.0; MAX_RHS]; MAX_EQ];
            for i in 0..nf {
                rhs1[i] = self.contact_rhs(i, &self.cons[i].station, &load, s_scaled, cols);
            }
            let (eq_f, eq_m) = self.equilibrium_rhs(load_z, cols);
            rhs1[nf] = eq_f;
            rhs1[nf + 1] = eq_m;
            // y = K₁₁⁻¹·rhs₁ (K₁₁⁻¹ symmetric: accumulate rows).
            for j in 0..n1 {
                let row = &c.k11_inv[j];
                for k in 0..cols.count {
                    let r = rhs1[j][k];
                    let y = &mut ycols[k];
                    for i in 0..n1 {
                        y[i] += row[i] * r;
                    }
                }
            }
            for k in 0..cols.count {
                pre[k] = self.sum_fixed(&ycols[k]);
            }
            load
        } else {
            ycols[0] = c.y_base0;
            for i in 0..MAX_EQ {
                ycols[0][i] += s_scaled * c.y_base1[i];
            }
            pre[0] = c.g_base0;
            for sup in 0..3 {
                pre[0][sup] = pre[0][sup].plus_scaled(s_scaled, c.g_base1[sup]);
            }
            if let Some(k) = cols.q {
                ycols[k] = c.y_q;
                pre[k] = c.g_q;
            }
            if let Some(k) = cols.m0 {
                ycols[k] = c.y_m0;
                pre[k] = c.g_m0;
            }
            if let Some(k) = cols.v {
                ycols[k] = c.y_v;
                pre[k] = c.g_v;
            }
            c.load
        };
        // The frame-fixed part for their number: arrays of that size, so that a single gland
        // (the usual case) sets up no 6-contact arrays and no 8×8 matrix.
        match n2 {
            1 => self.condensed_tail::<1>(c, s_scaled, cols, &ycols, &pre, &load, load_z),
            2 => self.condensed_tail::<2>(c, s_scaled, cols, &ycols, &pre, &load, load_z),
            3 => self.condensed_tail::<3>(c, s_scaled, cols, &ycols, &pre, &load, load_z),
            4 => self.condensed_tail::<4>(c, s_scaled, cols, &ycols, &pre, &load, load_z),
            5 => self.condensed_tail::<5>(c, s_scaled, cols, &ycols, &pre, &load, load_z),
            _ => {
                self.condensed_tail::<MAX_CONTACTS>(c, s_scaled, cols, &ycols, &pre, &load, load_z)
            }
        }
    }

    /// The part of [`SupportSystem::solve_condensed`] that involves the `N2` frame-fixed
    /// contacts (`N2 = n − n_fixed`, at most [`MAX_CONTACTS`]), given the block-1 load
    /// solutions `ycols` and their link-fixed reactions `pre`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn condensed_tail<const N2: usize>(
        &self,
        c: &Condensed,
        s_scaled: f64,
        cols: &Columns,
        ycols: &[[f64; MAX_EQ]; MAX_RHS],
        pre: &[[ForceMoment; 3]; MAX_RHS],
        load: &Station,
        load_z: f64,
    ) -> Result<Influence, ModelError> {
        let nf = self.n_fixed;
        let n1 = nf + 2;
        let n2 = N2.min(self.n - nf);
        let mut st2 = [self.cons[0].station; N2];
        let mut k12 = [[0.0; MAX_EQ]; N2];
        let mut x = [[0.0; MAX_EQ]; N2];
        let mut gx = [[ForceMoment::default(); 3]; N2];
        let mut b2 = [[0.0; MAX_RHS]; N2];
        for m in 0..n2 {
            st2[m] = self.station_at(nf + m, s_scaled);
            let st = &st2[m];
            let col = &mut k12[m];
            for i in 0..nf {
                col[i] = LinkBeam::flexibility(&self.cons[i].station, st);
            }
            let (p, q) = border(st);
            col[nf] = p;
            col[nf + 1] = q;
            // X = K₁₁⁻¹·col as a sum of K₁₁⁻¹'s rows (it is symmetric): scalar reads of the
            // freshly written column (cheaper than vector reads across separate stores).
            // The inner loop runs over the whole width: K₁₁⁻¹ is zero beyond n1, so the extra
            // terms add exact zeros, and a loop of constant length runs without a test per
            // element and is vectorised (n1 is known only at run time).
            let xm = &mut x[m];
            for j in 0..n1 {
                let cj = col[j];
                let row = &c.k11_inv[j];
                for i in 0..MAX_EQ {
                    xm[i] += row[i] * cj;
                }
            }
            gx[m] = self.sum_fixed(&x[m]);
            b2[m] = self.contact_rhs(nf + m, st, load, s_scaled, cols);
            for k in 0..cols.count {
                let y = &ycols[k];
                let mut acc = b2[m][k];
                // Both zero beyond n1 (whole width, as above).
                for i in 0..MAX_EQ {
                    acc -= col[i] * y[i];
                }
                b2[m][k] = acc;
            }
        }
        // Schur complement S = K₂₂ − K₁₂ᵀX: the flexibility of the link held by the link-fixed
        // contacts at the frame-fixed ones; compared with K₂₂'s scale to detect coincidences.
        let mut schur = [[0.0; N2]; N2];
        let mut scale = 0.0f64;
        for m in 0..n2 {
            for mm in 0..n2 {
                let mut acc = LinkBeam::flexibility(&st2[m], &st2[mm]);
                if m == mm {
                    acc += self.cons[nf + m].compliance;
                    scale = scale.max(acc.abs());
                }
                for i in 0..MAX_EQ {
                    acc -= k12[m][i] * x[mm][i];
                }
                schur[m][mm] = acc;
            }
        }
        if n2 == 1 {
            if !(schur[0][0].abs() > 1e-13 * scale) {
                return Err(self.singular_error(s_scaled));
            }
            let inv = 1.0 / schur[0][0];
            for k in 0..cols.count {
                b2[0][k] *= inv;
            }
        } else {
            let mut a: Matrix = [[0.0; MAX_EQ]; MAX_EQ];
            let mut rhs: Rhs = [[0.0; MAX_RHS]; MAX_EQ];
            for m in 0..n2 {
                a[m][..n2].copy_from_slice(&schur[m][..n2]);
                rhs[m] = b2[m];
            }
            if solve_in_place(&mut a, &mut rhs, n2, cols.count).is_err() {
                return Err(self.singular_error(s_scaled));
            }
            b2[..n2].copy_from_slice(&rhs[..n2]);
        }
        // Reactions per column: link-fixed contacts y₁ − X·x₂ (gathered), plus the frame-fixed
        // contacts' own forces x₂.
        let mut per_col = [[ForceMoment::default(); 3]; MAX_RHS];
        for k in 0..cols.count {
            let mut out = pre[k];
            for m in 0..n2 {
                let lam = b2[m][k];
                for sup in 0..3 {
                    out[sup] = out[sup].plus_scaled(-lam, gx[m][sup]);
                }
                self.cons[nf + m].add_to(&mut out, lam);
            }
            per_col[k] = out;
        }
        Ok(self.to_influence(&per_col, load_z, s_scaled, cols, false))
    }

    /// Per support R̃ = Σ lateral λ and M̃ = Σ slope λ + Σ lateral λ·arm over the link-fixed
    /// contacts, for a block-1 vector (scaled units).
    #[inline]
    fn sum_fixed(&self, lam: &[f64; MAX_EQ]) -> [ForceMoment; 3] {
        let mut out = [ForceMoment::default(); 3];
        for i in 0..self.n_fixed {
            self.cons[i].add_to(&mut out, lam[i]);
        }
        out
    }

    #[inline]
    fn station_at(&self, i: usize, s_scaled: f64) -> Station {
        let c = &self.cons[i];
        if c.moving {
            self.beam.station(c.station.dof, c.z0 - s_scaled)
        } else {
            c.station
        }
    }

    #[inline]
    fn load_z(&self, s_scaled: f64) -> f64 {
        if self.load_moving {
            self.load_z0 - s_scaled
        } else {
            self.load_z0
        }
    }

    /// Right-hand side of contact i's compatibility equation for every column: prescribed
    /// displacement minus the cantilever deflection under the lateral load (column 0), minus the
    /// deflection under a unit Q, M0, V.
    #[inline]
    fn contact_rhs(
        &self,
        i: usize,
        st: &Station,
        load: &Station,
        s_scaled: f64,
        cols: &Columns,
    ) -> [f64; MAX_RHS] {
        let c = &self.cons[i];
        let mut row = [0.0; MAX_RHS];
        if cols.rate_only {
            row[0] = c.u1;
            return row;
        }
        let w_q = LinkBeam::flexibility(st, load);
        row[0] = c.u0 + c.u1 * s_scaled - self.lateral * w_q;
        if let Some(k) = cols.q {
            row[k] = -w_q;
        }
        if let Some(k) = cols.m0 {
            row[k] = -LinkBeam::flexibility(st, &self.end_moment);
        }
        if let Some(k) = cols.v {
            row[k] = -LinkBeam::flexibility(st, &self.end_force);
        }
        row
    }

    /// Right-hand sides of the two equilibrium equations (forces, moments about z = 0): minus
    /// the applied loads' resultant and moment.
    #[inline]
    fn equilibrium_rhs(&self, load_z: f64, cols: &Columns) -> ([f64; MAX_RHS], [f64; MAX_RHS]) {
        let mut f = [0.0; MAX_RHS];
        let mut m = [0.0; MAX_RHS];
        if !cols.rate_only {
            f[0] = -self.lateral;
            m[0] = -self.lateral * load_z;
        }
        if let Some(k) = cols.q {
            f[k] = -1.0;
            m[k] = -load_z;
        }
        if let Some(k) = cols.m0 {
            m[k] = -1.0;
        }
        if let Some(k) = cols.v {
            f[k] = -1.0;
            m[k] = -1.0;
        }
        (f, m)
    }

    /// Per support: R = Σ lateral λ, M about the centre = Σ slope λ + Σ lateral λ·arm.
    fn gather(
        &self,
        lam: &Rhs,
        load_z: f64,
        s_scaled: f64,
        cols: &Columns,
        rate_only: bool,
    ) -> Influence {
        let mut per_col = [[ForceMoment::default(); 3]; MAX_RHS];
        for (k, out) in per_col.iter_mut().enumerate().take(cols.count) {
            for i in 0..self.n {
                self.cons[i].add_to(out, lam[i][k]);
            }
        }
        self.to_influence(&per_col, load_z, s_scaled, cols, rate_only)
    }

    /// Scaled per-column support reactions → SI influence (units: see link_beam.rs): the base
    /// column in force units EJ_ref/L², the unit-load columns per newton (Q, V) or per N·m (M0).
    #[inline]
    fn to_influence(
        &self,
        per_col: &[[ForceMoment; 3]; MAX_RHS],
        load_z: f64,
        s_scaled: f64,
        cols: &Columns,
        rate_only: bool,
    ) -> Influence {
        let l = self.length;
        let fu = self.force_unit;
        let mut infl = Influence::default();
        for x in 0..3 {
            infl.centres[x] =
                (self.centre_z0[x] - if self.centre_moving[x] { s_scaled } else { 0.0 }) * l;
        }
        infl.load_point = load_z * l;
        let base_factor = if rate_only { fu / l } else { fu };
        for x in 0..3 {
            let b = per_col[0][x];
            infl.base[x] = ForceMoment { r: b.r * base_factor, m: b.m * base_factor * l };
        }
        if let Some(k) = cols.q {
            for x in 0..3 {
                let g = per_col[k][x];
                infl.per_q[x] = ForceMoment { r: g.r, m: g.m * l };
            }
        }
        if let Some(k) = cols.m0 {
            for x in 0..3 {
                let g = per_col[k][x];
                infl.per_m0[x] = ForceMoment { r: g.r / l, m: g.m };
            }
        }
        if let Some(k) = cols.v {
            for x in 0..3 {
                let g = per_col[k][x];
                infl.per_v[x] = ForceMoment { r: g.r, m: g.m * l };
            }
        }
        infl
    }

    fn singular_error(&self, s_scaled: f64) -> ModelError {
        let positions: Vec<String> = self.cons[..self.n]
            .iter()
            .map(|c| {
                let z = if c.moving { c.z0 - s_scaled } else { c.z0 } * self.length;
                let what = match c.station.dof {
                    Dof::Deflection => "lateral contact",
                    Dof::Slope => "slope restraint",
                };
                // A spring's stiffness, from its scaled compliance (1/k)·EJ_ref/L³.
                let spring = if c.compliance > 0.0 {
                    let k = self.force_unit / (self.length * c.compliance);
                    format!(" ({}.stiffness = {} N/m)", NAMES[c.support].label, num(k))
                } else {
                    String::new()
                };
                format!("{} {what} at z = {} m{spring}", NAMES[c.support].label, num(z))
            })
            .collect();
        // Springs far softer than the link's bending stiffness scale hold it too weakly to solve.
        let soft = if self.cons[..self.n].iter().any(|c| c.compliance > 0.0) {
            format!(
                "; the link's bending stiffness scale is EJ/L³ = {} N/m, and a support much \
                 softer than that barely holds it",
                num(self.force_unit / self.length)
            )
        } else {
            String::new()
        };
        ModelError::evaluation(format!(
            "the link's support problem is singular at s = {} m (supports nearly coincide or do \
             not hold the link): {}{soft} (docs/model.md §5.2)",
            num(s_scaled * self.length),
            positions.join(", ")
        ))
    }
}

/// Border entries of a contact: coefficients of the rigid-body unknowns (a, b) in its
/// compatibility equation, which are also its weights in the two equilibrium equations.
#[inline]
fn border(st: &Station) -> (f64, f64) {
    match st.dof {
        Dof::Deflection => (1.0, st.z),
        Dof::Slope => (0.0, 1.0),
    }
}
