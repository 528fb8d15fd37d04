//! Crank motion (physics.md §2): the master supplies θ_in, ω, ε at communication points; inside a
//! step the FMU extrapolates with constant ε. The model angle is θ = θ_in + `crank.angle_offset`.

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

#[cfg(test)]
mod tests {
    use super::*;

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
