//! The P-dependent part of the elastic rod (docs/model.md §6, "Boundary conditions"; §5.4).
//!
//! # Derivation (independent check of §6)
//!
//! Haringx model, compression P > 0, lateral force H that the pin transmits, section rotation ψ:
//! `M = A2·ψ'`, equilibrium of the deformed rod beyond z: `M' = −H − P·v'`, shear along the rotated
//! section: `v' − ψ = (H + P·ψ)/A1`. Eliminating gives `ψ'' + κ²ψ = −H·s_N/A2` with
//! `κ² = P(1 + P/A1)/A2 = −x`, `s_N = 1 + P/A1`, and indeed `v'''' = x·v''`, `ψ = v' + η·v'''`
//! (η = A2/(A1 s_N²)), `M = A2·v''/s_N`, `H = −A2·v'''(0)/s_N²`. The clamp conditions give
//! `v = C3·V3 + C4·(V4 − ηz)`, hence `ψ(z) = (C3·S + C4·V3)/s_N` (using 1 + η·x = 1/s_N), and
//! the cage conditions `v(l) + fϑ = Δ`, `ψ(l) = ϑ` give the C3, C4 of §6 with determinant W*.
//!
//! The moment of the rod on the cage about the pin is `−M(l) + f·H + f·P·ϑ` (the axial force acts
//! at the pin, which is offset by f·ϑ from the rod end); substituting `s_N·ϑ = C3·S + C4·V3`
//! turns it into `−(A2/s_N)(C3·ℓ3 + C4·ℓ4) = −K_ϑ·ϑ + K_Δ·Δ` with exactly the ℓ3, ℓ4, W, w_Δ,
//! K_ϑ, K_Δ of §6. At the clamp the rod acts on the link with `M(0) = A2·C3/s_N` and the lateral
//! force `H = −A2·C4/s_N²` (§5.4). The tests verify all of this against a direct numerical
//! solution of the equilibrium equations above (no fundamental functions involved).
//!
//! # Numerically stable forms
//!
//! In tension (x > 0, a = √x·l_f large) `V3·V4' − V3'·V4`, `ē·ℓ4 − d̄·ℓ3` and `V3'·ℓ4 − V4'·ℓ3` are
//! differences of terms of size e^{2a} whose result is only of size e^{a}: with a = 20 the §6
//! forms lose 9 digits. With the exact identity `C² − x·S² = 1` (cosh² − sinh² = 1, cos² + sin² =
//! 1), `x·V3 = C − 1` and `x·V4 = S − z` they reduce to
//!
//! * `V3·V4' − V3'·V4 = V3² − S·V4 = (l·S − 2·V3)/x` (power series `l⁴ Σ 2(m+1)uᵐ/(2m+4)!`),
//! * `W = l·V3 − V4 + f1·(l + f1)·S + η·l·ℓ3`,
//! * `w_Δ = V3 + f1·S = ē`,
//!
//! which are used here; W* takes `V3² − S·V4` inside the series range (cancellation ≤ 3) and
//! `(l·S − 2V3)/x` beyond it (cancellation ≤ 4 at the switch, none for large |u|).
//!
//! # Validity
//!
//! W* vanishes first at κ·l_f = 2π (factor `sin(κl/2)` of `κ⁴W* = 2sin(κl/2)(2sin(κl/2) −
//! (κl/s_N)cos(κl/2))`, the other factor has no root below κl = 2π for s_N ≥ 1), while K_ϑ
//! vanishes earlier, at the first buckling load (clamped–pinned with shear for f = 0, lower for
//! f > 0). Beyond W* = 0 the ratio `A2·W/W*` can be positive again on a higher (meaningless)
//! branch, so besides `K_ϑ > 0` the constructor also requires `κ·l_f < 2π` and `W* > 0`.

// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::fundamental_functions::{fundamental_functions, FundamentalFunctions, SERIES_LIMIT};
use super::stiffness::RodStiffness;
use crate::model::error::{num, ModelError};
use std::f64::consts::PI;

/// Everything that depends on the axial load P (compression positive), docs/model.md §6.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamColumn {
    /// Axial load P [N], compression positive (N = −P).
    pub p: f64,
    /// Bending stiffness A2 [N·m²] (copied for the load formulas).
    pub a2: f64,
    /// `s_N = 1 − N/A1` [1].
    pub s_n: f64,
    /// `x = N·s_N/A2` [1/m²] (< 0 in compression).
    pub x: f64,
    /// `η = A2/(A1·s_N²)` [m²].
    pub eta: f64,
    /// `f1 = f/s_N` [m].
    pub f1: f64,
    /// Elastic length l_f [m].
    pub flex_length: f64,
    /// Rigid length f [m].
    pub rigid_length: f64,
    /// Fundamental functions at z = l_f.
    pub ff: FundamentalFunctions,
    /// `ē = V3 + f1·V3'`.
    pub e_bar: f64,
    /// `d̄ = V4 + f1·V4' − η·l_f`.
    pub d_bar: f64,
    /// `ℓ3 = V3'' + f1·V3'''`.
    pub l3: f64,
    /// `ℓ4 = V4'' + f1·V4'''`.
    pub l4: f64,
    /// `W* = V3·V4' − V3'·V4 + η·l_f·V3'` [m⁴] (l_f⁴/12 in the Euler–Bernoulli limit).
    pub w_star: f64,
    /// `W = ē·ℓ4 − d̄·ℓ3` [m³].
    pub w: f64,
    /// `w_Δ = V3'·ℓ4 − V4'·ℓ3` [m²].
    pub w_delta: f64,
    /// `K_ϑ = A2·W/W*` [N·m/rad].
    pub k_theta: f64,
    /// `K_Δ = A2·w_Δ/(s_N·W*)` [N].
    pub k_delta: f64,
}

impl BeamColumn {
    /// Evaluates the beam-column at the axial load `p` [N] (compression positive).
    ///
    /// Err(ModelError::Evaluation) with the numbers when s_N ≤ 0 (tension at or above A1), when
    /// the load is at or above the first buckling load (K_ϑ ≤ 0, or past κ·l_f = 2π where W*
    /// changes sign), or when the inputs are not finite / the functions overflow (tension with
    /// √x·l_f ≳ 700, far beyond the strength of any rod).
    pub fn new(
        stiff: &RodStiffness,
        flex_length: f64,
        rigid_length: f64,
        p: f64,
    ) -> Result<BeamColumn, ModelError> {
        if !p.is_finite() {
            return Err(ModelError::evaluation(format!(
                "elastic rod: rod.force P = {} N is not finite",
                num(p)
            )));
        }
        let (a1, a2) = (stiff.a1, stiff.a2);
        let n = -p;
        let s_n = 1.0 - n / a1;
        if !(s_n > 0.0) {
            return Err(ModelError::evaluation(format!(
                "elastic rod: tension N = {} N (rod.force P = {} N) reaches the shear stiffness \
                 A1 = {} N: s_N = 1 - N/A1 = {} <= 0, outside the Haringx theory",
                num(n),
                num(p),
                num(a1),
                num(s_n)
            )));
        }
        let l = flex_length;
        let x = n * s_n / a2;
        if x < 0.0 && -x * l * l >= 4.0 * PI * PI {
            return Err(ModelError::evaluation(format!(
                "elastic rod buckled: rod.force P = {} N gives kappa*l_f = {} >= 2*pi \
                 (beyond the clamped-clamped load; the first buckling load is lower)",
                num(p),
                num((-x).sqrt() * l)
            )));
        }
        let eta = a2 / (a1 * s_n * s_n);
        let f1 = rigid_length / s_n;
        let ff = fundamental_functions(x, l);
        let e_bar = ff.v3 + f1 * ff.v3p;
        let d_bar = ff.v4 + f1 * ff.v4p - eta * l;
        let l3 = ff.v3pp + f1 * ff.v3ppp;
        let l4 = ff.v4pp + f1 * ff.v4ppp;
        // Same quantities as §6, in forms free of the e^{2a} cancellation in tension (see the
        // module docs "Numerically stable forms"; the tests check them against the §6 forms).
        let w_star = wronskian_core(x, l, &ff) + eta * l * ff.v3p;
        let w = l * ff.v3 - ff.v4 + f1 * (l + f1) * ff.s + eta * l * l3;
        let w_delta = e_bar;
        let k_theta = a2 * w / w_star;
        let k_delta = a2 * w_delta / (s_n * w_star);
        if !(k_theta.is_finite() && k_delta.is_finite()) {
            return Err(ModelError::evaluation(format!(
                "elastic rod: rod.force P = {} N gives non-finite stiffnesses \
                 (x = {} 1/m^2, K_theta = {}, K_Delta = {})",
                num(p),
                num(x),
                num(k_theta),
                num(k_delta)
            )));
        }
        if !(w_star > 0.0 && k_theta > 0.0) {
            return Err(ModelError::evaluation(format!(
                "elastic rod buckled: rod.force P = {} N is at or above the buckling load: \
                 K_theta = {} N*m/rad <= 0 (W* = {} m^4, s_N = {}, x = {} 1/m^2)",
                num(p),
                num(k_theta),
                num(w_star),
                num(s_n),
                num(x)
            )));
        }
        Ok(BeamColumn {
            p,
            a2,
            s_n,
            x,
            eta,
            f1,
            flex_length,
            rigid_length,
            ff,
            e_bar,
            d_bar,
            l3,
            l4,
            w_star,
            w,
            w_delta,
            k_theta,
            k_delta,
        })
    }

    /// Integration constants `C3 = (V4'·Δ − s_N·d̄·ϑ)/W*`, `C4 = (s_N·ē·ϑ − V3'·Δ)/W*` of
    /// `v = C3·V3 + C4·(V4 − η z)` for the pin offset Δ [m] and cage rotation ϑ [rad].
    #[inline]
    pub fn c3_c4(&self, delta: f64, theta: f64) -> (f64, f64) {
        let c3 = (self.ff.v4p * delta - self.s_n * self.d_bar * theta) / self.w_star;
        let c4 = (self.s_n * self.e_bar * theta - self.ff.v3p * delta) / self.w_star;
        (c3, c4)
    }

    /// Loads the rod exerts on the link at the clamp (§5.4): `(M_0 = A2·C3/s_N [N·m],
    /// V = −A2·C4/s_N² [N])`.
    #[inline]
    pub fn clamp_loads(&self, delta: f64, theta: f64) -> (f64, f64) {
        let (c3, c4) = self.c3_c4(delta, theta);
        (self.a2 * c3 / self.s_n, -self.a2 * c4 / (self.s_n * self.s_n))
    }

    /// Moment of the rod on the cage about the crank-pin axis, `K_Δ·Δ − K_ϑ·ϑ` [N·m] (§6).
    #[inline]
    pub fn cage_moment(&self, delta: f64, theta: f64) -> f64 {
        self.k_delta * delta - self.k_theta * theta
    }

    /// Bending moment `M(z) = (A2/s_N)(C3·C(z) + C4·S(z))` [N·m] at one abscissa 0 ≤ z ≤ l_f.
    pub fn moment_at(&self, delta: f64, theta: f64, z: f64) -> f64 {
        let (c3, c4) = self.c3_c4(delta, theta);
        let ffz = fundamental_functions(self.x, z);
        self.a2 / self.s_n * (c3 * ffz.c + c4 * ffz.s)
    }
}

/// `V3·V4' − V3'·V4` at z = l (the Euler–Bernoulli part of W*), without the e^{2a} cancellation
/// of the product form in tension: `V3² − S·V4` where the fundamental functions come from the
/// series, `(l·S − 2·V3)/x` where they come from cosh/sinh or cos/sin (identity `C² − xS² = 1`).
#[inline]
fn wronskian_core(x: f64, l: f64, ff: &FundamentalFunctions) -> f64 {
    if (x * l * l).abs() <= SERIES_LIMIT {
        ff.v3 * ff.v3 - ff.s * ff.v4
    } else {
        (l * ff.s - 2.0 * ff.v3) / x
    }
}
