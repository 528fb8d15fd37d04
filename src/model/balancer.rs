//! Torsion-bar balancer (docs/model.md §7, seed 004): a linear spring on the link,
//! F_bal = −k_b·(s − s_0), that offsets the inertia force of the reciprocating mass.

use crate::model::error::ModelError;

pub const TUNING_GIVEN: i32 = 0;
pub const TUNING_ENERGY_RULE: i32 = 1;
pub const TUNING_DEAD_CENTRES: i32 = 2;

/// The balancer parameters as the user sets them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BalancerSpec {
    pub tuning: i32,
    /// `balancer.stiffness` [N/m], used by tuning 0.
    pub stiffness: f64,
    /// ω_d = `balancer.design_speed` [rad/s], used by tunings 1 and 2.
    pub design_speed: f64,
    /// `balancer.neutral_position` [m]; negative means mid-stroke. Used by tuning 0 only.
    pub neutral_position: f64,
}

/// What the balancer needs to know about the machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineFacts {
    pub mass: f64,
    pub stroke: f64,
    pub crank_radius: f64,
    /// max |TF| over a revolution (exact kinematics).
    pub max_torque_factor: f64,
    /// λ = r/l of a central crank-slider; None for any other mechanism (tuning 2 needs it).
    pub central_slider_lambda: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Balancer {
    /// k_b in use [N/m] (`balancer.stiffness_used`).
    pub stiffness: f64,
    /// s_0 [m].
    pub neutral_position: f64,
}

impl Balancer {
    pub fn new(spec: &BalancerSpec, m: &MachineFacts) -> Result<Balancer, ModelError> {
        let mid = 0.5 * m.stroke;
        match spec.tuning {
            TUNING_GIVEN => Ok(Balancer {
                stiffness: spec.stiffness,
                neutral_position: if spec.neutral_position < 0.0 { mid } else { spec.neutral_position },
            }),
            // The paper's energy rule at the design speed: k_b = m·B²·ω_d² with B = v_max/(rω)
            // = max|TF|/r of the exact kinematics; s_0 at mid-stroke.
            TUNING_ENERGY_RULE => {
                let b = m.max_torque_factor / m.crank_radius;
                Ok(Balancer { stiffness: m.mass * b * b * spec.design_speed.powi(2), neutral_position: mid })
            }
            // Exact cancellation at both dead centres of a central crank-slider:
            // k_b = m·ω_d², s_0 = r(1 + λ), since a(0) = rω²(1+λ) and a(π) = −rω²(1−λ) (§3.1).
            TUNING_DEAD_CENTRES => match m.central_slider_lambda {
                Some(lambda) => Ok(Balancer {
                    stiffness: m.mass * spec.design_speed.powi(2),
                    neutral_position: m.crank_radius * (1.0 + lambda),
                }),
                None => Err(ModelError::invalid(
                    "balancer.tuning = 2 (cancellation at both dead centres) exists only for a central \
                     crank-slider (mechanism = 1, geometry.slider_offset = 0, rod.kind = 0)",
                )),
            },
            other => Err(ModelError::out_of_range("balancer.tuning", other as f64, "0, 1 or 2")),
        }
    }

    /// F_bal = −k_b·(s − s_0), along +s.
    #[inline]
    pub fn force(&self, s: f64) -> f64 {
        -self.stiffness * (s - self.neutral_position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::crank_slider::CrankSlider;
    use crate::model::kinematics::max_abs_torque_factor;
    use std::f64::consts::PI;

    fn facts(r: f64, l: f64) -> MachineFacts {
        let m = CrankSlider::new(r, l, 0.0).unwrap();
        MachineFacts {
            mass: 300.0,
            stroke: m.stroke(),
            crank_radius: r,
            max_torque_factor: max_abs_torque_factor(|t| m.kinematics(t)),
            central_slider_lambda: Some(r / l),
        }
    }

    #[test]
    fn tuning_2_cancels_inertia_at_both_dead_centres() {
        let (r, l, w) = (0.2, 1.19, 2.0 * PI * 65.0 / 60.0);
        let spec =
            BalancerSpec { tuning: 2, stiffness: 0.0, design_speed: w, neutral_position: -1.0 };
        let b = Balancer::new(&spec, &facts(r, l)).unwrap();
        let m = CrankSlider::new(r, l, 0.0).unwrap();
        for theta in [0.0, PI] {
            let k = m.kinematics(theta);
            let phi = -300.0 * k.acceleration(w, 0.0);
            assert!((phi + b.force(k.s)).abs() < 1e-9 * phi.abs(), "θ = {theta}");
        }
    }

    #[test]
    fn tuning_1_follows_the_energy_rule_with_the_exact_speed_maximum() {
        // Independent maximum of |TF|: golden-section search on the closed form of §3.1.
        let (r, l, w) = (0.2, 1.19, 6.0);
        let lam = r / l;
        let tf = |t: f64| {
            r * t.sin() * (1.0 + lam * t.cos() / (1.0 - lam * lam * t.sin().powi(2)).sqrt())
        };
        let (mut a, mut c) = (0.5, 2.5);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..200 {
            let (x1, x2) = (c - g * (c - a), a + g * (c - a));
            if tf(x1) > tf(x2) {
                c = x2
            } else {
                a = x1
            }
        }
        let vmax_over_rw = tf(0.5 * (a + c)) / r;
        let spec =
            BalancerSpec { tuning: 1, stiffness: 0.0, design_speed: w, neutral_position: 5.0 };
        let b = Balancer::new(&spec, &facts(r, l)).unwrap();
        let expect = 300.0 * vmax_over_rw.powi(2) * w * w;
        assert!((b.stiffness - expect).abs() < 1e-10 * expect, "{} vs {expect}", b.stiffness);
        assert!((b.neutral_position - 0.2).abs() < 1e-15, "mid-stroke, ignoring neutral_position");
        // B exceeds 1 (the maximum speed is above rω) and the first-harmonic angle is only close.
        assert!(vmax_over_rw > 1.0);
    }

    #[test]
    fn tuning_0_uses_the_given_values_and_mid_stroke_default() {
        let f = facts(0.2, 1.19);
        let b = Balancer::new(
            &BalancerSpec { tuning: 0, stiffness: 5e4, design_speed: 1.0, neutral_position: -1.0 },
            &f,
        )
        .unwrap();
        assert_eq!(b.stiffness, 5e4);
        assert!((b.neutral_position - 0.2).abs() < 1e-15, "mid-stroke");
        assert!((b.force(0.3) + 5e4 * 0.1).abs() < 1e-9);
        let b = Balancer::new(
            &BalancerSpec { tuning: 0, stiffness: 5e4, design_speed: 1.0, neutral_position: 0.05 },
            &f,
        )
        .unwrap();
        assert_eq!(b.neutral_position, 0.05);
        let e = Balancer::new(
            &BalancerSpec { tuning: 2, stiffness: 0.0, design_speed: 1.0, neutral_position: 0.0 },
            &MachineFacts { central_slider_lambda: None, ..f },
        )
        .unwrap_err();
        assert!(e.to_string().contains("balancer.tuning"));
    }
}
