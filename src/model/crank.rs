//! Crank motion (docs/model.md §2): the master supplies θ_in, ω, ε at communication points; inside a
//! step the FMU extrapolates with constant ε. The model angle is θ = θ_in + `crank.angle_offset`.

// `!(a <= b)` is deliberate: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use serde::{Deserialize, Serialize};

/// The crank motion as the FMU currently knows it (inputs, or their extrapolation inside a step).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CrankState {
    /// Input angle θ_in [rad] (before the offset).
    pub angle: f64,
    /// ω [rad/s].
    pub speed: f64,
    /// ε [rad/s²].
    pub acceleration: f64,
}

impl CrankState {
    /// The crank τ seconds later, assuming constant ε (§2):
    /// θ(t+τ) = θ + ωτ + ετ²/2, ω(t+τ) = ω + ετ.
    #[inline]
    pub fn extrapolate(&self, tau: f64) -> CrankState {
        CrankState {
            angle: self.angle + self.speed * tau + 0.5 * self.acceleration * tau * tau,
            speed: self.speed + self.acceleration * tau,
            acceleration: self.acceleration,
        }
    }
}

/// Largest |φ| for which [`sin_cos_shifted`] uses its series.
pub const SHIFT_SERIES_LIMIT: f64 = 0.5;

/// sin(θ₀ + φ), cos(θ₀ + φ) from sinθ₀, cosθ₀ by the addition theorems, with sin φ, cos φ from
/// their Taylor series (through φ¹⁵ and φ¹⁶: for |φ| ≤ 0.5 the first omitted terms are below
/// 3e-20, so the result is within a few ulp of the libm values); None for larger |φ| or NaN.
///
/// WHY: inside one communication step the crank angle of every integrator stage is θ₀ + φ(τ)
/// with φ = ωτ + ετ²/2 small (0.16 rad for kvo630 at h = 1 ms); this replaces a libm sin_cos
/// (range reduction included) per stage by 17 multiply-adds.
#[inline]
pub fn sin_cos_shifted(sin0: f64, cos0: f64, phi: f64) -> Option<(f64, f64)> {
    if !(phi.abs() <= SHIFT_SERIES_LIMIT) {
        return None;
    }
    const SIN: [f64; 8] = [
        1.0,
        -0.16666666666666666,
        0.008333333333333333,
        -0.0001984126984126984,
        2.7557319223985893e-06,
        -2.505210838544172e-08,
        1.6059043836821613e-10,
        -7.647163731819816e-13,
    ];
    const COS: [f64; 9] = [
        1.0,
        -0.5,
        0.041666666666666664,
        -0.001388888888888889,
        2.48015873015873e-05,
        -2.755731922398589e-07,
        2.08767569878681e-09,
        -1.1470745597729725e-11,
        4.779477332387385e-14,
    ];
    let q = phi * phi;
    let mut sp = SIN[7];
    for &c in SIN[..7].iter().rev() {
        sp = sp * q + c;
    }
    let sp = sp * phi;
    // cos φ − 1, so that the rounding of 1 + (small) happens only once, in the combination below.
    let mut cm = COS[8];
    for &c in COS[1..8].iter().rev() {
        cm = cm * q + c;
    }
    let cm = cm * q;
    Some((sin0 + (sin0 * cm + cos0 * sp), cos0 + (cos0 * cm - sin0 * sp)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shifted_sin_cos_matches_libm() {
        // Against libm's sin_cos of θ₀ + φ (θ₀ + φ exactly representable: φ on a binary grid
        // and θ₀ of moderate size) within 3 ulp of 1, over the whole series range and large θ₀.
        let mut worst = 0.0_f64;
        for &theta0 in &[0.0, 0.296875, -1.1875, 2.0, 3.140625, 100.0, -5000.25] {
            let (s0, c0) = f64::sin_cos(theta0);
            for i in -512..=512 {
                let phi = i as f64 / 1024.0; // |φ| ≤ 0.5, exact
                let (s, c) = sin_cos_shifted(s0, c0, phi).unwrap();
                let (se, ce) = (theta0 + phi).sin_cos();
                assert_eq!(theta0 + phi - theta0, phi);
                worst = worst.max((s - se).abs()).max((c - ce).abs());
            }
        }
        assert!(worst <= 3.0 * f64::EPSILON, "{worst:e}");
        assert_eq!(sin_cos_shifted(0.0, 1.0, 0.5 + 1e-12), None);
        assert_eq!(sin_cos_shifted(0.0, 1.0, f64::NAN), None);
        assert_eq!(sin_cos_shifted(0.3, 0.9, 0.0), Some((0.3, 0.9)));
    }

    #[test]
    fn extrapolation_is_exact_for_constant_acceleration() {
        // Against the closed form of uniformly accelerated rotation, evaluated independently.
        let c = CrankState { angle: 0.3, speed: 6.0, acceleration: -2.0 };
        let tau = 0.25;
        let e = c.extrapolate(tau);
        assert!((e.angle - (0.3 + 6.0 * 0.25 - 0.0625)).abs() < 1e-15);
        assert!((e.speed - 5.5).abs() < 1e-15);
        // Two half steps equal one whole step (the law composes).
        let two = c.extrapolate(tau / 2.0).extrapolate(tau / 2.0);
        assert!((two.angle - e.angle).abs() < 1e-15 && (two.speed - e.speed).abs() < 1e-15);
    }
}
