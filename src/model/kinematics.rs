//! The result every kinematic law returns (docs/model.md §2): the stroke coordinate and its exact
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

/// Largest |TF| over a revolution, exactly: |TF| is extreme where TF' = 0, so bracket the sign
/// changes of TF' on a fine grid and bisect each to machine precision (docs/model.md §7: the
/// zero-acceleration angle is a root of TF' = 0, not the first-harmonic formula).
pub fn max_abs_torque_factor(kin: impl Fn(f64) -> Kinematics) -> f64 {
    const N: usize = 1440;
    let step = std::f64::consts::TAU / N as f64;
    let mut best = 0.0f64;
    let mut prev = kin(0.0);
    for i in 1..=N {
        let (a, b) = ((i - 1) as f64 * step, i as f64 * step);
        let cur = kin(b);
        best = best.max(cur.tf.abs());
        if prev.tfp.signum() != cur.tfp.signum() {
            let (mut lo, mut hi, lo_sign) = (a, b, prev.tfp.signum());
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if kin(mid).tfp.signum() == lo_sign {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            best = best.max(kin(0.5 * (lo + hi)).tf.abs());
        }
        prev = cur;
    }
    best
}
