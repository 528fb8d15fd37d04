//! Loads on the reciprocating link, docs/model.md §4. Forces are positive along +s.

use crate::model::kinematics::Scalar;
use crate::model::params::{LOAD_PROFILE_DOUBLE_ACTING, LOAD_PROFILE_SINGLE_ACTING};

/// d'Alembert inertia force Φ = −m·a of the reciprocating mass reduced to the link (§4).
#[inline]
pub fn inertia_force(mass: f64, acceleration: f64) -> f64 {
    -mass * acceleration
}

/// The process-force profile chosen by `load.profile` (§4); the input `link.external_force` is
/// added by the caller.
/// * 0: mean + amplitude·cos(θ + phase);
/// * 1 (double-acting pump): −mean·tanh(v/v_ε), the fluid always opposes the piston;
/// * 2 (single-acting pump): mean·(1 − tanh(v/v_ε))/2, pushing toward the crank only while v < 0.
#[inline]
pub fn process_force_profile(
    profile: i32,
    mean: f64,
    amplitude: f64,
    phase: f64,
    theta: f64,
    velocity: f64,
    velocity_scale: f64,
) -> f64 {
    process_force_profile_of(profile, mean, amplitude, phase, theta, velocity, velocity_scale)
}

/// [`process_force_profile`] for any [`Scalar`] (a dual number carries its exact derivatives);
/// with `f64` the same arithmetic in the same order.
#[inline(always)]
pub fn process_force_profile_of<T: Scalar>(
    profile: i32,
    mean: f64,
    amplitude: f64,
    phase: f64,
    theta: T,
    velocity: T,
    velocity_scale: f64,
) -> T {
    match profile {
        LOAD_PROFILE_DOUBLE_ACTING => (velocity / velocity_scale).tanh() * -mean,
        LOAD_PROFILE_SINGLE_ACTING => {
            (T::from(1.0) - (velocity / velocity_scale).tanh()) * (0.5 * mean)
        }
        // The cosine costs as much as the rest of the kinematics: skip it when it contributes 0.
        _ if amplitude == 0.0 => T::from(mean),
        _ => (theta + phase).cos() * amplitude + mean,
    }
}

/// Crank torque the drive supplies for a rigid rod, from virtual power: T·ω = −P·v with
/// v = TF·ω, so T = −P·TF (§4).
#[inline]
pub fn crank_torque_rigid(rod_force: f64, torque_factor: f64) -> f64 {
    -rod_force * torque_factor
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profiles_match_their_definitions() {
        // Cosine profile at a few angles (closed form).
        let f = process_force_profile(0, 10.0, 5.0, 0.5, 1.0, 3.0, 0.02);
        assert!((f - (10.0 + 5.0 * 1.5f64.cos())).abs() < 1e-14);
        // Double-acting: opposes the motion, saturates at ±mean far from v = 0.
        assert!((process_force_profile(1, 150e3, 0.0, 0.0, 0.0, 1.0, 0.02) + 150e3).abs() < 1e-6);
        assert!((process_force_profile(1, 150e3, 0.0, 0.0, 0.0, -1.0, 0.02) - 150e3).abs() < 1e-6);
        assert_eq!(process_force_profile(1, 150e3, 0.0, 0.0, 0.0, 0.0, 0.02), 0.0);
        // Single-acting: full mean on the discharge stroke (v < 0), zero on suction.
        assert!((process_force_profile(2, 100.0, 0.0, 0.0, 0.0, -1.0, 0.02) - 100.0).abs() < 1e-9);
        assert!(process_force_profile(2, 100.0, 0.0, 0.0, 0.0, 1.0, 0.02).abs() < 1e-9);
    }

    #[test]
    fn torque_satisfies_virtual_power() {
        // T·ω + P·v = 0 for v = TF·ω.
        let (p, tf, w) = (1234.5, 0.137, 6.8);
        let t = crank_torque_rigid(p, tf);
        assert!((t * w + p * tf * w).abs() < 1e-10);
        assert_eq!(inertia_force(300.0, 2.0), -600.0);
    }
}
