//! The pump's cylinders on one crankshaft (docs/model.md §4.1): the chambers' areas, the fluid
//! force of the pressures on a piston and the flow a cylinder discharges. Forces are positive
//! along +s (toward the crank), as in §4.

use std::f64::consts::PI;

use crate::model::error::{require_finite, ModelError};
use crate::model::kinematics::Scalar;
use crate::model::params::{CylinderParams, MAX_CYLINDERS};

/// One cylinder, validated: its crank phase and the areas of its two chambers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cylinder {
    /// φ_k [rad]: the cylinder's link sees the model angle θ + φ_k (φ_1 = 0).
    pub phase: f64,
    /// Head-end chamber (away from the crank, full piston): A_h = π·D²/4 [m²]. Its volume
    /// A_h·(s + s_0) grows with s.
    pub head_area: f64,
    /// Crank-end chamber (around the piston rod): A_c = π·(D² − d²)/4 for a double-acting
    /// cylinder, 0 for a single-acting one (open to the ambient) [m²]. Its volume shrinks with s.
    pub crank_area: f64,
}

/// The active cylinders (1 ≤ n ≤ [`MAX_CYLINDERS`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pump {
    pub n: usize,
    pub cylinders: [Cylinder; MAX_CYLINDERS],
    /// `drive::groups::CYLINDERS` when the FLOW group needs the velocities of cylinders 2..
    /// (n > 1), else 0.
    pub flow_needs: u8,
}

const NAMES: [[&str; 4]; MAX_CYLINDERS] = [
    [
        "cylinder_1.phase",
        "cylinder_1.acting",
        "cylinder_1.piston_diameter",
        "cylinder_1.rod_diameter",
    ],
    [
        "cylinder_2.phase",
        "cylinder_2.acting",
        "cylinder_2.piston_diameter",
        "cylinder_2.rod_diameter",
    ],
    [
        "cylinder_3.phase",
        "cylinder_3.acting",
        "cylinder_3.piston_diameter",
        "cylinder_3.rod_diameter",
    ],
];

impl Pump {
    /// Checks `fluid_end.cylinders` and the active cylinders' parameters (inactive ones are ignored).
    pub fn new(count: i32, params: &[CylinderParams; MAX_CYLINDERS]) -> Result<Pump, ModelError> {
        if !(1..=MAX_CYLINDERS as i32).contains(&count) {
            return Err(ModelError::out_of_range("fluid_end.cylinders", count as f64, "1, 2 or 3"));
        }
        let n = count as usize;
        let mut cylinders = [Cylinder::default(); MAX_CYLINDERS];
        for (k, (c, p)) in cylinders.iter_mut().zip(params).take(n).enumerate() {
            let [phase, acting, piston, rod] = NAMES[k];
            require_finite(phase, p.phase)?;
            if !(p.acting == 1 || p.acting == 2) {
                return Err(ModelError::out_of_range(
                    acting,
                    p.acting as f64,
                    "1 (single-acting) or 2 (double-acting)",
                ));
            }
            if !(p.piston_diameter > 0.0 && p.piston_diameter.is_finite()) {
                return Err(ModelError::out_of_range(piston, p.piston_diameter, "(0, inf) m"));
            }
            if p.acting == 2 && !(p.rod_diameter >= 0.0 && p.rod_diameter < p.piston_diameter) {
                return Err(ModelError::invalid(format!(
                    "{rod} = {} m must be in [0, {piston}) = [0, {}) m for a double-acting cylinder",
                    crate::model::error::num(p.rod_diameter),
                    crate::model::error::num(p.piston_diameter)
                )));
            }
            let d2 = p.piston_diameter * p.piston_diameter;
            *c = Cylinder {
                phase: p.phase,
                head_area: 0.25 * PI * d2,
                crank_area: if p.acting == 2 {
                    0.25 * PI * (d2 - p.rod_diameter * p.rod_diameter)
                } else {
                    0.0
                },
            };
        }
        let flow_needs = if n > 1 { crate::model::drive::groups::CYLINDERS } else { 0 };
        Ok(Pump { n, cylinders, flow_needs })
    }

    /// Volume all active cylinders displace per revolution, Σ (A_h + A_c)·S [m³] (§4.1).
    pub fn displacement(&self, stroke: f64) -> f64 {
        self.cylinders[..self.n].iter().map(|c| (c.head_area + c.crank_area) * stroke).sum()
    }
}

impl Cylinder {
    /// Fluid force on the piston along +s at velocity v (§4.1): the head-end chamber, shrinking
    /// while v < 0, at p_h = p_s + Δp·(1 − σ)/2, the crank-end chamber, shrinking while v > 0, at
    /// p_c = p_s + Δp·(1 + σ)/2, σ = tanh(v/v_ε), Δp = p_d − p_s; F = p_h·A_h − p_c·A_c.
    #[inline(always)]
    pub fn fluid_force<T: Scalar>(&self, p_d: T, p_s: T, velocity: T, velocity_scale: f64) -> T {
        let sigma = (velocity / velocity_scale).tanh();
        let half = (p_d - p_s) * 0.5;
        let p_head = p_s + half - half * sigma;
        let p_crank = p_s + half + half * sigma;
        p_head * self.head_area - p_crank * self.crank_area
    }

    /// Flow the cylinder discharges at velocity v (§4.1): each chamber's shrinking rate times
    /// the weight of its discharge state, Q = A_h·(−v)·(1 − σ)/2 + A_c·v·(1 + σ)/2.
    #[inline(always)]
    pub fn flow<T: Scalar>(&self, velocity: T, velocity_scale: f64) -> T {
        let sigma = (velocity / velocity_scale).tanh();
        let half_v = velocity * 0.5;
        (half_v * sigma - half_v) * self.head_area + (half_v + half_v * sigma) * self.crank_area
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::params::Params;

    #[test]
    fn areas_and_limits_of_the_chamber_weights() {
        // D = 0.13 m, d = 0.07 m: A_h = π·0.13²/4, A_c = π·(0.13² − 0.07²)/4 (closed forms).
        let p = Params::default();
        let pump = Pump::new(1, &p.cylinder).unwrap();
        let c = pump.cylinders[0];
        assert!((c.head_area - 0.013_273_228_961_416_876).abs() < 1e-17);
        assert!((c.crank_area - 0.009_424_777_960_769_38).abs() < 1e-17);
        // Far from the dead centres the chambers are at p_d or p_s (ideal valves):
        // v < 0: head at p_d, crank-end at p_s: F = p_d·A_h − p_s·A_c; Q = A_h·|v|.
        let (pd, ps, v) = (20e6, 0.3e6, -1.0);
        let f = c.fluid_force(pd, ps, v, 1e-6);
        assert!((f - (pd * c.head_area - ps * c.crank_area)).abs() < 1e-9 * f.abs());
        assert!((c.flow(v, 1e-6) - c.head_area).abs() < 1e-15);
        let f = c.fluid_force(pd, ps, -v, 1e-6);
        assert!((f - (ps * c.head_area - pd * c.crank_area)).abs() < 1e-9 * f.abs());
        assert!((c.flow(-v, 1e-6) - c.crank_area).abs() < 1e-15);
    }

    #[test]
    fn bad_cylinders_are_refused_by_name() {
        let p = Params::default();
        for (count, edit, name) in [
            (4, None, "fluid_end.cylinders"),
            (0, None, "fluid_end.cylinders"),
            (2, Some((1, 0, 3.0)), "cylinder_2.acting"),
            (2, Some((1, 1, 0.0)), "cylinder_2.piston_diameter"),
            (3, Some((2, 2, 0.2)), "cylinder_3.rod_diameter"),
        ] {
            let mut cyl = p.cylinder;
            if let Some((k, what, v)) = edit {
                match what {
                    0 => cyl[k].acting = v as i32,
                    1 => cyl[k].piston_diameter = v,
                    _ => cyl[k].rod_diameter = v,
                }
            }
            let e = Pump::new(count, &cyl).unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
        // An inactive cylinder is not checked.
        let mut cyl = p.cylinder;
        cyl[2].acting = 7;
        assert!(Pump::new(2, &cyl).is_ok());
    }
}
