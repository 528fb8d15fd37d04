//! The result every kinematic law returns (docs/model.md §2): the stroke coordinate and its exact
//! derivatives with respect to the crank angle, plus the connecting rod's swing.

use num_dual::DualNum;

/// A real scalar of the model's generic code: `f64` for evaluation, a dual number
/// (`num_dual::Dual64`) for the exact directional derivatives by forward-mode automatic
/// differentiation (docs/fmi-interface.md "Directional derivatives").
pub trait Scalar: DualNum<Primitive = f64> + Copy {
    /// `max(self, 0)` on the real part (a guard against the last ulp below 0): `f64::max`,
    /// branch-free, for `f64`.
    fn at_least_zero(self) -> Self;
}

impl Scalar for f64 {
    #[inline(always)]
    fn at_least_zero(self) -> f64 {
        self.max(0.0)
    }
}

impl Scalar for num_dual::Dual64 {
    #[inline(always)]
    fn at_least_zero(self) -> Self {
        if self.re > 0.0 {
            self
        } else {
            Self::from(0.0)
        }
    }
}

/// Position-level kinematics at one crank angle θ (model angle, offset already applied).
/// Generic over the scalar (`f64` unless a dual number carries derivatives, see [`Scalar`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Kinematics<T = f64> {
    /// Stroke coordinate s [m], 0 at the outer end of the stroke (§2).
    pub s: T,
    /// Torque factor TF = ds/dθ [m/rad].
    pub tf: T,
    /// TF' = d²s/dθ² [m/rad²].
    pub tfp: T,
    /// Rod swing angle [rad]: β of the slider rod (§3.1) or the pitman's inclination (§3.2).
    pub rod_angle: T,
    /// dβ/dθ [1], so that the swing rate is `rod_angle_rate * ω`.
    pub rod_angle_rate: T,
}

impl<T: Scalar> Kinematics<T> {
    /// Velocity v = TF·ω (§2).
    #[inline]
    pub fn velocity(&self, omega: T) -> T {
        self.tf * omega
    }
    /// Acceleration a = TF·ε + TF'·ω² (§2).
    #[inline]
    pub fn acceleration(&self, omega: T, epsilon: T) -> T {
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
