//! The result every kinematic law returns (physics.md §2): the stroke coordinate and its exact
//! derivatives with respect to the crank angle, plus the connecting rod's swing.

/// Position-level kinematics at one crank angle θ (model angle, offset already applied).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Kinematics {
    /// Stroke coordinate s [m], 0 at the outer end of the stroke (§2).
    pub s: f64,
    /// Torque factor TF = ds/dθ [m/rad].
    pub tf: f64,
    /// TF' = d²s/dθ² [m/rad²].
    pub tfp: f64,
    /// Rod swing angle [rad]: β of the slider rod (§3.1) or the pitman's inclination (§3.2).
    pub rod_angle: f64,
    /// dβ/dθ [1], so that the swing rate is `rod_angle_rate * ω`.
    pub rod_angle_rate: f64,
}

impl Kinematics {
    /// Velocity v = TF·ω (§2).
    #[inline]
    pub fn velocity(&self, omega: f64) -> f64 {
        self.tf * omega
    }
    /// Acceleration a = TF·ε + TF'·ω² (§2).
    #[inline]
    pub fn acceleration(&self, omega: f64, epsilon: f64) -> f64 {
        self.tf * epsilon + self.tfp * omega * omega
    }
}
