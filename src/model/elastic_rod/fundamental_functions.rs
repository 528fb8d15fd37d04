//! Normal fundamental functions of the beam-column equation `v'''' − x·v'' = 0` (docs/model.md §6).
//!
//! With `C = cosh(√x z)`, `S = sinh(√x z)/√x` (x > 0) or `C = cos(√−x z)`, `S = sin(√−x z)/√−x`
//! (x < 0), the normal solutions (V_i^(j−1)(0) = δ_ij) are `V1 = 1, V2 = z, V3 = (C − 1)/x,
//! V4 = (S − z)/x`, with `V3' = S, V3'' = C, V3''' = x·S, V4' = V3, V4'' = S, V4''' = C`
//! (checked: `d/dz (S − z)/x = (C − 1)/x = V3`, `d/dz (C − 1)/x = x·S/x = S`, `S' = C`, `C' = x·S`).
//!
//! All four are entire functions of `x` (only powers of `u = x·z²` occur), so the formulas with a
//! division by `x` are merely a representation. Near `u = 0` they cancel catastrophically
//! (`C − 1 ≈ u/2`, `S − z ≈ z·u/6`), so for `|u| ≤ SERIES_LIMIT` the power series of §6 is summed
//! instead; `C` and `S` are then formed as `1 + u·(V3/z²)` and `z·(1 + u·(V4/z³))`, which have no
//! cancellation either. This makes P → 0 (x → 0) smooth and exact, and keeps ~1e-15 relative error
//! on both sides of x = 0 (tests compare with 40-digit mpmath values).

/// `|u| = |x|·z²` up to which the power series is used.
///
/// WHY 4: above it the closed form loses at most ~2 bits in `V4 = (S − z)/x` (the cancellation
/// factor `S/(S − z)` is ≤ 2.3 for u ≥ 4 and < 1 for u ≤ −4), below it 12 terms of the series
/// reach full double precision (the first omitted term is < 3e-19 of the sum).
pub const SERIES_LIMIT: f64 = 4.0;

/// 1/(2n+2)!, n = 0..11: coefficients of `V3/z² = Σ uⁿ/(2n+2)!` (correctly rounded).
pub(super) const INV_FACT_EVEN: [f64; 12] = [
    0.5,
    0.041666666666666664,
    0.001388888888888889,
    2.48015873015873e-05,
    2.755731922398589e-07,
    2.08767569878681e-09,
    1.1470745597729725e-11,
    4.779477332387385e-14,
    1.5619206968586225e-16,
    4.110317623312165e-19,
    8.896791392450574e-22,
    1.6117375710961184e-24,
];

/// 1/(2n+3)!, n = 0..11: coefficients of `V4/z³ = Σ uⁿ/(2n+3)!` (correctly rounded).
pub(super) const INV_FACT_ODD: [f64; 12] = [
    0.16666666666666666,
    0.008333333333333333,
    0.0001984126984126984,
    2.7557319223985893e-06,
    2.505210838544172e-08,
    1.6059043836821613e-10,
    7.647163731819816e-13,
    2.8114572543455206e-15,
    8.22063524662433e-18,
    1.9572941063391263e-20,
    3.868170170630684e-23,
    6.446950284384474e-26,
];

/// Values of the normal fundamental functions and the derivatives the boundary conditions and
/// the stress need, all at one abscissa `z` (docs/model.md §6).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FundamentalFunctions {
    /// `C(z)` = V3'' = V4'''.
    pub c: f64,
    /// `S(z)` = V3' = V4''.
    pub s: f64,
    /// `V3 = (C − 1)/x`.
    pub v3: f64,
    /// `V3' = S`.
    pub v3p: f64,
    /// `V3'' = C`.
    pub v3pp: f64,
    /// `V3''' = x·S`.
    pub v3ppp: f64,
    /// `V4 = (S − z)/x`.
    pub v4: f64,
    /// `V4' = V3`.
    pub v4p: f64,
    /// `V4'' = S`.
    pub v4pp: f64,
    /// `V4''' = C`.
    pub v4ppp: f64,
}

#[inline]
fn horner(u: f64, coef: &[f64; 12]) -> f64 {
    let mut acc = coef[11];
    let mut i = 11;
    while i > 0 {
        i -= 1;
        acc = acc * u + coef[i];
    }
    acc
}

/// Normal fundamental functions of `v'''' − x·v'' = 0` at `z` (docs/model.md §6).
///
/// Entire in `x`: exact at `x = 0` (`C = 1, S = z, V3 = z²/2, V4 = z³/6`), power series for
/// `|x z²| ≤ SERIES_LIMIT`, `cosh/sinh` (tension, x > 0) or `cos/sin` (compression, x < 0) beyond.
/// Non-finite input or overflow (tension with `√x·z ≳ 710`) yields non-finite values, which the
/// callers ([`super::BeamColumn::new`]) turn into an error.
pub fn fundamental_functions(x: f64, z: f64) -> FundamentalFunctions {
    let u = x * z * z;
    let (c, s, v3, v4);
    if u.abs() <= SERIES_LIMIT {
        let p3 = horner(u, &INV_FACT_EVEN); // V3/z²
        let p4 = horner(u, &INV_FACT_ODD); // V4/z³
        v3 = z * z * p3;
        v4 = z * z * z * p4;
        c = 1.0 + u * p3;
        s = z * (1.0 + u * p4);
    } else if x > 0.0 {
        let r = x.sqrt();
        let e = (r * z).exp();
        let ei = 1.0 / e;
        c = 0.5 * (e + ei);
        s = 0.5 * (e - ei) / r;
        v3 = (c - 1.0) / x;
        v4 = (s - z) / x;
    } else {
        // x < 0 here, or NaN (which propagates).
        let r = (-x).sqrt();
        let (sn, cs) = (r * z).sin_cos();
        c = cs;
        s = sn / r;
        v3 = (c - 1.0) / x;
        v4 = (s - z) / x;
    }
    FundamentalFunctions { c, s, v3, v3p: s, v3pp: c, v3ppp: x * s, v4, v4p: v3, v4pp: s, v4ppp: c }
}
