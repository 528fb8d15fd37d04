//! Guide friction from the support reactions (docs/model.md §5.3) and the implicit rod-force
//! equation `P = p_base + F_fr(P)` (docs/model.md §4, §5.4).
//!
//! Friction magnitude of a support with net force R and moment M about its centre:
//! two-edge guide (and a clamp of length l_n > 0) `f·(|N₁| + |N₂|) = f·max(|R|, 2|M|/l_n)` with
//! `N₁,₂ = R/2 ± M/l_n`; pin `f·|R|`. Signed friction `F = −|F|·tanh(v/v_ε)`.
//!
//! Rigid slider rod: R and M are affine in P (side load −P·tanβ), so each magnitude is the
//! maximum of at most four affine functions of P: convex and piecewise linear. The total
//! friction `−tanh(v/v_ε)·Σ f·g(P)` is therefore concave or convex as a whole, and
//! `h(P) = P − p_base − F_fr(P)` is convex or concave and strictly increasing (slope ≥ 1 − K > 0,
//! K the uniqueness number of §4). Newton's method on such a function reaches the exact root
//! of the active linear piece and, being monotone after its first step, cannot cycle: it
//! terminates after at most (number of kinks + 2) steps, typically two. A bisection on the
//! a-priori bracket `|P − p_base| ≤ |F_fr(p_base)|/(1 − K)` is kept as a safety net for rounding.
// Index loops mirror the matrix formulas above; `!(a > b)` tests deliberately reject NaN.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::supports::ForceMoment;
use super::{SupportKind, SupportSpec};

/// The regularised sign `tanh(x)` of the friction law, x = v/v_ε (docs/model.md §5.3), within
/// 2.3e-16 absolute and 7e-16 relative of the correctly rounded value.
///
/// WHY not `f64::tanh`: glibc computes it through `expm1` and a division, and in the elastic
/// rod's integrator it is evaluated at every stage (17 times per 1 ms step of kvo630), where it
/// took a fifth of the step's time. Here: |x| < 1/16 the odd Taylor series through x¹³ (first
/// omitted term < 2e-17·|x|); up to 20 `(1 − t)/(1 + t)` with t = e^(−2|x|) (`exp` is table
/// driven and fast; the cancellation in 1 − t is at most a factor 8.5 since t ≤ e^(−1/8));
/// beyond, ±1 (1 − tanh 20 < 1e-17).
#[inline]
pub fn regularized_sign(x: f64) -> f64 {
    let a = x.abs();
    let r = if a < 0.0625 {
        const C: [f64; 6] = [
            -1.0 / 3.0,
            2.0 / 15.0,
            -17.0 / 315.0,
            62.0 / 2835.0,
            -1382.0 / 155925.0,
            21844.0 / 6081075.0,
        ];
        let q = a * a;
        let mut p = C[5];
        for &c in C[..5].iter().rev() {
            p = p * q + c;
        }
        a + a * (q * p)
    } else if a < 20.0 {
        let t = (-2.0 * a).exp();
        (1.0 - t) / (1.0 + t)
    } else {
        // Also NaN (then `a < …` is false and NaN must stay NaN).
        if a.is_nan() {
            return x;
        }
        1.0
    };
    r.copysign(x)
}

/// How a support rubs (docs/model.md §5.3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum FrictionLaw {
    /// No friction (absent support, or friction coefficient 0).
    None,
    /// A pin: f·|R|.
    Pin { f: f64 },
    /// Two edges (guide, or clamp of length l_n): f·max(|R|, 2|M|/l_n).
    Edges { f: f64, two_over_l: f64 },
}

impl FrictionLaw {
    pub fn from_spec(spec: &SupportSpec) -> FrictionLaw {
        if spec.kind == SupportKind::None || spec.friction == 0.0 {
            return FrictionLaw::None;
        }
        match spec.kind {
            SupportKind::Pin => FrictionLaw::Pin { f: spec.friction },
            // Validation guarantees length > 0 for a guide and for a clamp with friction.
            _ => FrictionLaw::Edges { f: spec.friction, two_over_l: 2.0 / spec.length },
        }
    }

    /// Friction magnitude |F| for net force R and moment M about the centre.
    #[inline]
    pub fn magnitude(&self, fm: ForceMoment) -> f64 {
        match *self {
            FrictionLaw::None => 0.0,
            FrictionLaw::Pin { f } => f * fm.r.abs(),
            FrictionLaw::Edges { f, two_over_l } => f * fm.r.abs().max(two_over_l * fm.m.abs()),
        }
    }

    /// Rate of [`FrictionLaw::magnitude`] when R and M change at rates `d`: the derivative of
    /// the branch that gives the value (|R| or 2|M|/l_n, the sign of R or M).
    #[inline]
    pub fn magnitude_rate(&self, fm: ForceMoment, d: ForceMoment) -> f64 {
        let signed = |x: f64, dx: f64| if x < 0.0 { -dx } else { dx };
        match *self {
            FrictionLaw::None => 0.0,
            FrictionLaw::Pin { f } => f * signed(fm.r, d.r),
            FrictionLaw::Edges { f, two_over_l } => {
                if fm.r.abs() >= two_over_l * fm.m.abs() {
                    f * signed(fm.r, d.r)
                } else {
                    f * two_over_l * signed(fm.m, d.m)
                }
            }
        }
    }
}

/// Edge forces of a support with net force R and moment M about its centre (§5.3):
/// `N₁ = R/2 + M/l_n` at the crank-side edge, `N₂ = R/2 − M/l_n`. For a pin, or a clamp without
/// length, the moment is not carried by edges; both "edges" then report R/2, so that
/// `N₁ + N₂ = R` and `f(|N₁| + |N₂|) = f|R|` still hold.
#[inline]
pub(super) fn edge_forces(kind: SupportKind, length: f64, fm: ForceMoment) -> (f64, f64) {
    match kind {
        SupportKind::None => (0.0, 0.0),
        SupportKind::TwoEdgeGuide | SupportKind::Clamp if length > 0.0 => {
            let half = 0.5 * fm.r;
            let c = fm.m / length;
            (half + c, half - c)
        }
        _ => (0.5 * fm.r, 0.5 * fm.r),
    }
}

/// Reactions of one support as affine functions of P: `base + P·slope`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct AffineReaction {
    pub base: ForceMoment,
    pub slope: ForceMoment,
}

/// Sum over supports of f·max(|∂R/∂P|, 2|∂M/∂P|/l_n) (pin: f·|∂R/∂P|): times |tanh(v/v_ε)| the
/// largest slope of F_fr(P), i.e. the uniqueness number K of docs/model.md §4 (there written per
/// unit side load Q, with |∂Q/∂P| = |tanβ|).
// Always inlined, like `solve_piecewise_linear`: `Guide::solve_rigid_into` has two copies, and
// left to itself the compiler then calls them out of line (docs/performance.md).
#[inline(always)]
pub(super) fn sensitivity(laws: &[FrictionLaw; 3], r: &[AffineReaction; 3]) -> f64 {
    let mut k = 0.0;
    for x in 0..3 {
        k += laws[x].magnitude(r[x].slope);
    }
    k
}

/// g(P) of one support (the friction magnitude, the maximum of its candidate affine pieces
/// ±R(P), ±2M(P)/l_n) with its left and right slopes: at a kink the left slope is the smallest,
/// the right slope the largest slope among the active pieces.
#[inline]
fn piece(law: &FrictionLaw, r: &AffineReaction, p: f64) -> (f64, f64, f64) {
    let (f, k) = match *law {
        FrictionLaw::None => return (0.0, 0.0, 0.0),
        FrictionLaw::Pin { f } => (f, 0.0),
        FrictionLaw::Edges { f, two_over_l } => (f, two_over_l),
    };
    // |a + b·P| with its one-sided slopes.
    let abs_piece = |a: f64, b: f64| {
        let v = a + p * b;
        if v > 0.0 {
            (v, b, b)
        } else if v < 0.0 {
            (-v, -b, -b)
        } else {
            (0.0, -b.abs(), b.abs())
        }
    };
    let mut best = abs_piece(r.base.r, r.slope.r);
    if k > 0.0 {
        let cand = abs_piece(k * r.base.m, k * r.slope.m);
        if cand.0 > best.0 {
            best = cand;
        } else if cand.0 == best.0 {
            best = (best.0, best.1.min(cand.1), best.2.max(cand.2));
        }
    }
    (f * best.0, f * best.1, f * best.2)
}

/// Total signed friction F(P) = −tanh·Σ f·g and its left and right slopes (a constant factor
/// scales one-sided derivatives without swapping them).
#[inline]
fn total(laws: &[FrictionLaw; 3], r: &[AffineReaction; 3], sign: f64, p: f64) -> (f64, f64, f64) {
    let (mut v, mut dl, mut dr) = (0.0, 0.0, 0.0);
    for x in 0..3 {
        let (gv, gl, gr) = piece(&laws[x], &r[x], p);
        v += gv;
        dl += gl;
        dr += gr;
    }
    (-sign * v, -sign * dl, -sign * dr)
}

/// Signed friction of every support at P.
#[inline]
pub(super) fn signed_friction(
    laws: &[FrictionLaw; 3],
    r: &[AffineReaction; 3],
    sign: f64,
    p: f64,
) -> [f64; 3] {
    let mut out = [0.0; 3];
    for x in 0..3 {
        let fm = r[x].base.plus_scaled(p, r[x].slope);
        out[x] = -sign * laws[x].magnitude(fm);
    }
    out
}

/// Solves `P = p_base + F_fr(P)` exactly for piecewise-linear friction. `sign` = tanh(v/v_ε);
/// requires `|sign|·sensitivity < 1` (checked by the caller).
#[inline(always)]
pub(super) fn solve_piecewise_linear(
    laws: &[FrictionLaw; 3],
    r: &[AffineReaction; 3],
    sign: f64,
    p_base: f64,
    k_unique: f64,
) -> f64 {
    if sign == 0.0 {
        return p_base;
    }
    let mut p = p_base;
    for _ in 0..40 {
        let (fv, left, right) = total(laws, r, sign, p);
        let h = p - p_base - fv;
        let tol = 4.0 * f64::EPSILON * (p.abs() + p_base.abs() + fv.abs());
        if h.abs() <= tol {
            return p;
        }
        // Newton on the piece in the direction of the root (h is increasing): left if h > 0.
        let slope = if h > 0.0 { left } else { right };
        let next = p - h / (1.0 - slope);
        if next == p || !next.is_finite() {
            break;
        }
        p = next;
    }
    // Safety net (rounding at a kink): bisection on the a-priori bracket.
    let (f0, _, _) = total(laws, r, sign, p_base);
    let radius = f0.abs() / (1.0 - k_unique).max(f64::EPSILON) * (1.0 + 1e-12) + f64::MIN_POSITIVE;
    let (mut lo, mut hi) = (p_base - radius, p_base + radius);
    for _ in 0..2200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        let (fv, _, _) = total(laws, r, sign, mid);
        if mid - p_base - fv > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regularized_sign_matches_libm_tanh() {
        // Dense sweep across the branch points (1/16, 20) and far beyond, plus special values.
        let (mut worst_abs, mut worst_rel) = (0.0_f64, 0.0_f64);
        for i in -400_000..=400_000 {
            let x = i as f64 * 6.1e-5; // |x| <= 24.4
            let (a, b) = (regularized_sign(x), x.tanh());
            worst_abs = worst_abs.max((a - b).abs());
            if b != 0.0 {
                worst_rel = worst_rel.max(((a - b) / b).abs());
            }
        }
        assert!(worst_abs <= 2.3e-16 && worst_rel <= 7e-16, "{worst_abs:e} {worst_rel:e}");
        for x in [0.0, 1e-300, 1e-12, 0.0625, 19.999, 20.0, 1e3, f64::INFINITY] {
            assert!((regularized_sign(x) - x.tanh()).abs() <= 2.3e-16, "{x}");
            assert_eq!(regularized_sign(-x), -regularized_sign(x), "{x}");
        }
        assert!(regularized_sign(f64::NAN).is_nan());
        assert_eq!(regularized_sign(-0.0).to_bits(), (-0.0_f64).to_bits());
    }
}
