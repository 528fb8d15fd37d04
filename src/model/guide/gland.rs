//! Closed-form support reactions of a link held by link-fixed supports and one gland
//! (docs/model.md §5.3): the usual machine (piston in its liner, crosshead in its guide, a
//! diaphragm gland fixed in the frame), built once in `SupportSystem::new`.
//!
//! Why this exists: with the frame-fixed contact eliminated by static condensation
//! (`supports.rs`), everything that changes with s is where the gland sits on the link,
//! `z = z₀ − s̃`. Its coupling column K₁₂ is made of cantilever flexibilities, which are
//! polynomials of degree ≤ 3 in z between the link's section boundaries and the other contacts
//! (`link_beam.rs`: the compliance moments I_k(z) are polynomials there, and the Mohr integral of
//! two stations uses the moments of the nearer one). Hence, on each such interval of s̃:
//! * `X = K₁₁⁻¹K₁₂` and the link-fixed reactions it causes, `g(s̃)`, are cubics;
//! * the condensed right-hand sides `b_k(s̃)` (prescribed displacement and unit loads, minus
//!   `K₁₂ᵀy_k`) are of degree ≤ 4 (the base case's `y` is affine in s̃);
//! * the Schur complement `S(s̃) = K₂₂ + 1/k − K₁₂ᵀX` is of degree ≤ 6;
//!
//! and the reactions of load case k are `pre_k + (b_k/S)·(e − g)` (e: the gland's own force and
//! moment about its centre). These twelve polynomials are tabulated per interval, in a local
//! variable t ∈ [−1, 1], from the condensed solve itself at 7 Chebyshev points: a polynomial of
//! degree ≤ 6 is reproduced exactly by its interpolant, so the table differs from the condensed
//! path by rounding only (`gland_table_equals_full_solve` in `tests.rs` compares both with the
//! full bordered system on random configurations; `SupportSystem::new` drops the table where it
//! would differ from the full solve by more than 1e-11). Per evaluation: find the interval,
//! evaluate the polynomials by Horner's rule in monomials of t (ten cubics side by side, b₀ and S
//! to degree 6), one division. WHY monomials: Clenshaw's recurrence in the Chebyshev basis gave
//! the same results where the condensation itself lost digits, for about 50 more instructions.

// `!(a > b)` tests deliberately reject NaN; index loops mirror the lanes.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use num_dual::{Dual64, DualNum};

use super::supports::{ForceMoment, LoadSet};

/// The tabulated quantities (lanes): b_k for the unit loads Q, M0, V (SI-scaled), e − g for R
/// and M of the three supports (M in SI-scaled moment units) and K₂₂ + 1/k (the scale of the
/// singularity test), all cubics; then b₀ of the base case (degree 4) and S (degree 6).
pub(super) const LANES: usize = 12;
/// The cubic lanes come first.
const CUBIC: usize = 10;
pub(super) const B_Q: usize = 0;
pub(super) const B_M0: usize = 1;
pub(super) const B_V: usize = 2;
/// e − g of support x: R in lane `E_MINUS_G + 2x`, M in the next.
pub(super) const E_MINUS_G: usize = 3;
pub(super) const SCALE: usize = 9;
pub(super) const B_BASE: usize = 10;
pub(super) const SCHUR: usize = 11;
/// Degree of the interpolants (that of S).
const DEGREE: usize = 6;
const NODES: usize = DEGREE + 1;
/// At most 3 interior section boundaries, 5 link-fixed contacts and the load point split the
/// stroke: 10 intervals.
pub(super) const MAX_PIECES: usize = 10;

/// One interval of s̃: monomial coefficients in t = (s̃ − mid)·inv_half, lowest degree first,
/// of the cubic lanes and of the two of higher degree (b₀, S).
#[derive(Clone, Copy, Debug)]
struct Piece {
    mid: f64,
    inv_half: f64,
    cubic: [[f64; CUBIC]; 4],
    high: [[f64; LANES - CUBIC]; NODES],
}

/// The table over the stroke (scaled s̃ ∈ [lo, hi], a little beyond [0, S̃] for rounding).
#[derive(Clone, Debug)]
pub(super) struct GlandTable {
    /// Upper ends of the intervals but the last (a search over at most 9 values).
    ends: [f64; MAX_PIECES],
    pieces: Vec<Piece>,
    lo: f64,
    hi: f64,
    /// Link-fixed reactions of the block-1 solutions y_k in SI units, per load case; the base
    /// case is `pre[0] + s̃·pre_base_rate`.
    pre: [[ForceMoment; 3]; 4],
    pre_base_rate: [ForceMoment; 3],
}

/// The reactions of the load cases a caller asked for (zeros for the others).
pub(super) struct GlandReactions {
    pub base: [ForceMoment; 3],
    pub per_q: [ForceMoment; 3],
    pub per_m0: [ForceMoment; 3],
    pub per_v: [ForceMoment; 3],
}

/// Why an evaluation could not use the table.
pub(super) enum Miss {
    /// s̃ outside the tabulated range (the caller takes the condensed solve).
    OutOfRange,
    /// S below 1e-13 of its scale: the support problem is singular at this s̃.
    Singular,
}

impl GlandTable {
    /// Tabulates `sample(s̃) → lanes` (the condensed solve) over [lo, hi], split at `breaks`
    /// (unsorted, those outside ignored). `pre`, `pre_base_rate`: see the fields.
    pub fn new(
        lo: f64,
        hi: f64,
        breaks: &[f64],
        pre: [[ForceMoment; 3]; 4],
        pre_base_rate: [ForceMoment; 3],
        mut sample: impl FnMut(f64) -> [f64; LANES],
    ) -> Option<GlandTable> {
        let mut cuts: Vec<f64> = breaks.iter().copied().filter(|&b| b > lo && b < hi).collect();
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        let mut edges = vec![lo];
        edges.extend(cuts);
        edges.push(hi);
        if edges.len() - 1 > MAX_PIECES || !(lo < hi) {
            return None;
        }
        let mut pieces = Vec::with_capacity(edges.len() - 1);
        let mut ends = [f64::INFINITY; MAX_PIECES];
        for w in edges.windows(2) {
            let (a, b) = (w[0], w[1]);
            let mid = 0.5 * (a + b);
            let half = 0.5 * (b - a);
            // Chebyshev points of the first kind and the interpolant's Chebyshev coefficients
            // c_j = (2/N)·Σ f(t_i)·T_j(t_i) (c₀ halved), exact for a polynomial of degree < N.
            let mut cheb = [[0.0; LANES]; NODES];
            for i in 0..NODES {
                let angle = std::f64::consts::PI * (i as f64 + 0.5) / NODES as f64;
                let t = angle.cos();
                let f = sample(mid + half * t);
                for (j, c) in cheb.iter_mut().enumerate() {
                    let tj = (j as f64 * angle).cos();
                    for l in 0..LANES {
                        c[l] += f[l] * tj;
                    }
                }
            }
            for (j, c) in cheb.iter_mut().enumerate() {
                let w = if j == 0 { 1.0 } else { 2.0 } / NODES as f64;
                for v in c.iter_mut() {
                    *v *= w;
                }
            }
            let mut coef = [[0.0; LANES]; NODES];
            for (j, c) in cheb.iter().enumerate() {
                for (d, &m) in CHEBYSHEV_MONOMIALS[j].iter().enumerate() {
                    if m != 0.0 {
                        for l in 0..LANES {
                            coef[d][l] += m * c[l];
                        }
                    }
                }
            }
            ends[pieces.len()] = b;
            // The cubic lanes' coefficients of degree > 3 are rounding (dropped).
            let cubic = std::array::from_fn(|d| std::array::from_fn(|l| coef[d][l]));
            let high = std::array::from_fn(|d| std::array::from_fn(|l| coef[d][CUBIC + l]));
            pieces.push(Piece { mid, inv_half: 1.0 / half, cubic, high });
        }
        Some(GlandTable { ends, pieces, lo, hi, pre, pre_base_rate })
    }

    /// The polynomials at scaled s̃ (cubic lanes, then b₀ and S) and 1/S.
    #[inline(always)]
    fn lanes(&self, s_scaled: f64) -> Result<([f64; CUBIC], f64, f64), Miss> {
        // Written so that NaN misses too.
        if !(s_scaled >= self.lo && s_scaled <= self.hi) {
            return Err(Miss::OutOfRange);
        }
        let mut i = 0;
        while s_scaled > self.ends[i] {
            i += 1;
        }
        let p = &self.pieces[i];
        let t = (s_scaled - p.mid) * p.inv_half;
        let mut v = p.cubic[3];
        for d in (0..3).rev() {
            let c = &p.cubic[d];
            for l in 0..CUBIC {
                v[l] = v[l] * t + c[l];
            }
        }
        let mut h = p.high[DEGREE];
        for d in (0..DEGREE).rev() {
            let c = &p.high[d];
            for l in 0..LANES - CUBIC {
                h[l] = h[l] * t + c[l];
            }
        }
        let schur = h[SCHUR - CUBIC];
        // The test of the condensed solve (`supports.rs`); NaN fails it too.
        if !(schur.abs() > 1e-13 * v[SCALE]) {
            return Err(Miss::Singular);
        }
        Ok((v, h[B_BASE - CUBIC], 1.0 / schur))
    }

    /// Reactions `pre + (b/S)·(e − g)` of one load case.
    #[inline(always)]
    fn column(v: &[f64; CUBIC], b_over_s: f64, pre: &[ForceMoment; 3]) -> [ForceMoment; 3] {
        std::array::from_fn(|x| ForceMoment {
            r: pre[x].r + b_over_s * v[E_MINUS_G + 2 * x],
            m: pre[x].m + b_over_s * v[E_MINUS_G + 1 + 2 * x],
        })
    }

    #[inline(always)]
    fn base(&self, v: &[f64; CUBIC], b0: f64, inv: f64, s_scaled: f64) -> [ForceMoment; 3] {
        let pre: [ForceMoment; 3] =
            std::array::from_fn(|x| self.pre[0][x].plus_scaled(s_scaled, self.pre_base_rate[x]));
        Self::column(v, b0 * inv, &pre)
    }

    /// The reactions at scaled s̃ for the load cases of `set` (zeros for the others).
    #[inline]
    pub fn evaluate(&self, s_scaled: f64, set: LoadSet) -> Result<GlandReactions, Miss> {
        let (v, b0, inv) = self.lanes(s_scaled)?;
        let zero = [ForceMoment::default(); 3];
        let (q, m0v) = match set {
            LoadSet::Rigid => (true, false),
            LoadSet::Clamp => (false, true),
            LoadSet::All => (true, true),
        };
        Ok(GlandReactions {
            base: self.base(&v, b0, inv, s_scaled),
            per_q: if q { Self::column(&v, v[B_Q] * inv, &self.pre[1]) } else { zero },
            per_m0: if m0v { Self::column(&v, v[B_M0] * inv, &self.pre[2]) } else { zero },
            per_v: if m0v { Self::column(&v, v[B_V] * inv, &self.pre[3]) } else { zero },
        })
    }

    /// The rigid rod's load cases only (base, per Q), as `Guide::solve_rigid` uses them. Always
    /// inlined: `SupportSystem::rigid_influence`, always inlined into two callers, would otherwise
    /// make it an out-of-line call on the rigid evaluation's hot path.
    #[inline(always)]
    pub fn evaluate_rigid(
        &self,
        s_scaled: f64,
    ) -> Result<([ForceMoment; 3], [ForceMoment; 3]), Miss> {
        let (v, b0, inv) = self.lanes(s_scaled)?;
        Ok((self.base(&v, b0, inv, s_scaled), Self::column(&v, v[B_Q] * inv, &self.pre[1])))
    }
}

impl GlandTable {
    /// d/ds̃ of [`GlandTable::evaluate_rigid`] (base, per Q) at scaled s̃, for the exact
    /// directional derivatives (docs/fmi-interface.md "Directional derivatives"): the same
    /// polynomials and the same division by S, evaluated by Horner's rule in dual numbers
    /// (forward-mode automatic differentiation), so the rate is that of the tabulated rational
    /// function itself, which equals the condensed solve to rounding.
    pub fn evaluate_rigid_rate(
        &self,
        s_scaled: f64,
    ) -> Result<([ForceMoment; 3], [ForceMoment; 3]), Miss> {
        // The same checks (range, singularity) as the value.
        self.lanes(s_scaled)?;
        let mut i = 0;
        while s_scaled > self.ends[i] {
            i += 1;
        }
        let p = &self.pieces[i];
        let t = Dual64::new((s_scaled - p.mid) * p.inv_half, p.inv_half);
        let mut v: [Dual64; CUBIC] = p.cubic[3].map(Dual64::from);
        for d in (0..3).rev() {
            for l in 0..CUBIC {
                v[l] = v[l] * t + p.cubic[d][l];
            }
        }
        let mut h: [Dual64; LANES - CUBIC] = p.high[DEGREE].map(Dual64::from);
        for d in (0..DEGREE).rev() {
            for l in 0..LANES - CUBIC {
                h[l] = h[l] * t + p.high[d][l];
            }
        }
        let inv = h[SCHUR - CUBIC].recip();
        // Reactions pre + (b/S)·(e − g); the base case's pre grows with s̃ at pre_base_rate.
        let column = |b_over_s: Dual64, pre_rate: [ForceMoment; 3]| -> [ForceMoment; 3] {
            std::array::from_fn(|x| ForceMoment {
                r: pre_rate[x].r + (b_over_s * v[E_MINUS_G + 2 * x]).eps,
                m: pre_rate[x].m + (b_over_s * v[E_MINUS_G + 1 + 2 * x]).eps,
            })
        };
        let base = column(h[B_BASE - CUBIC] * inv, self.pre_base_rate);
        let per_q = column(v[B_Q] * inv, [ForceMoment::default(); 3]);
        Ok((base, per_q))
    }
}

/// Monomial coefficients of the Chebyshev polynomials T₀ … T₆, lowest degree first.
const CHEBYSHEV_MONOMIALS: [[f64; NODES]; NODES] = [
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [-1.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, -3.0, 0.0, 4.0, 0.0, 0.0, 0.0],
    [1.0, 0.0, -8.0, 0.0, 8.0, 0.0, 0.0],
    [0.0, 5.0, 0.0, -20.0, 0.0, 16.0, 0.0],
    [-1.0, 0.0, 18.0, 0.0, -48.0, 0.0, 32.0],
];
