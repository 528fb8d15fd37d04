//! The rod's lower cage on the crank pin (docs/model.md §6): the piston law of the clamped elastic
//! rod, the cage equation solved for ϑ̈, and the quasi-static initial state.

use serde::{Deserialize, Serialize};

use super::beam_column::BeamColumn;
use super::stiffness::RodStiffness;
use super::stress::stress_max;
use super::RodSpec;
use crate::model::error::ModelError;
use crate::model::kinematics::Kinematics;

/// The continuous state of the FMU: cage rotation ϑ [rad] and its rate ϑ̇ [rad/s].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CageState {
    pub theta: f64,
    pub rate: f64,
}

/// Piston law with a clamped elastic rod (§6, first-order theory): the piston follows the crank
/// pin's axial coordinate, s = r(1 − cosθ); the pin's lateral offset Δ = r·sinθ − e bends the rod.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PistonLaw {
    pub r: f64,
    pub e: f64,
}

impl PistonLaw {
    #[inline]
    pub fn kinematics(&self, theta: f64) -> (Kinematics, f64, f64) {
        let (sin, cos) = theta.sin_cos();
        let k = Kinematics {
            s: self.r * (1.0 - cos),
            tf: self.r * sin,
            tfp: self.r * cos,
            rod_angle: 0.0,
            rod_angle_rate: 0.0,
        };
        // (kinematics, Δ, dΔ/dθ)
        (k, self.r * sin - self.e, self.r * cos)
    }

    /// Δ̈ = r(ε·cosθ − ω²·sinθ).
    #[inline]
    pub fn delta_ddot(&self, theta: f64, omega: f64, epsilon: f64) -> f64 {
        let (sin, cos) = theta.sin_cos();
        self.r * (epsilon * cos - omega * omega * sin)
    }

    /// Kinematics, Δ, dΔ/dθ and Δ̈ at θ, from one sin_cos (what `kinematics` and `delta_ddot`
    /// give separately).
    #[inline]
    pub fn at(&self, theta: f64, omega: f64, epsilon: f64) -> PistonPoint {
        let (sin, cos) = theta.sin_cos();
        self.at_sin_cos(sin, cos, omega, epsilon)
    }

    /// [`PistonLaw::at`] from sinθ, cosθ.
    #[inline]
    pub fn at_sin_cos(&self, sin: f64, cos: f64, omega: f64, epsilon: f64) -> PistonPoint {
        PistonPoint {
            k: Kinematics {
                s: self.r * (1.0 - cos),
                tf: self.r * sin,
                tfp: self.r * cos,
                rod_angle: 0.0,
                rod_angle_rate: 0.0,
            },
            delta: self.r * sin - self.e,
            delta_rate: self.r * cos,
            delta_ddot: self.r * (epsilon * cos - omega * omega * sin),
        }
    }

    pub fn stroke(&self) -> f64 {
        2.0 * self.r
    }
}

/// The piston law at one instant (§6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PistonPoint {
    pub k: Kinematics,
    /// Δ = r·sinθ − e [m].
    pub delta: f64,
    /// dΔ/dθ = r·cosθ [m/rad].
    pub delta_rate: f64,
    /// Δ̈ = r(ε·cosθ − ω²·sinθ) [m/s²].
    pub delta_ddot: f64,
}

/// The elastic rod and its cage, validated; everything independent of P precomputed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElasticRod {
    pub spec: RodSpec,
    pub stiffness: RodStiffness,
    /// J_m [kg·m²].
    pub cage_inertia: f64,
    /// B_d [N·m·s/rad]: `rod.damping` if > 0, else 2ζ·sqrt(K_ϑ(0)·J_m).
    pub damping: f64,
    /// e_P [m].
    pub load_eccentricity: f64,
    /// m_f·f_m [kg·m].
    pub rigid_moment: f64,
    /// Ω0 = sqrt(K_ϑ(0)/J_m) [rad/s]: the fixed scale of the absolute tolerance on ϑ̇.
    pub omega0: f64,
}

/// What the cage equation needs besides ϑ, ϑ̇.
#[derive(Clone, Copy, Debug)]
pub struct CageLoads {
    pub delta: f64,
    pub delta_ddot: f64,
    pub rod_force: f64,
}

impl ElasticRod {
    pub fn new(
        spec: RodSpec,
        cage_inertia: f64,
        damping_ratio: f64,
        damping: f64,
        load_eccentricity: f64,
        rigid_mass: f64,
        rigid_lever: f64,
    ) -> Result<ElasticRod, ModelError> {
        let stiffness = RodStiffness::new(&spec)?;
        if !(cage_inertia > 0.0 && cage_inertia.is_finite()) {
            return Err(ModelError::out_of_range(
                "rod.cage_inertia",
                cage_inertia,
                "(0, inf) kg.m2",
            ));
        }
        let unloaded = BeamColumn::new(&stiffness, spec.flex_length, spec.rigid_length, 0.0)?;
        let omega0 = (unloaded.k_theta / cage_inertia).sqrt();
        let damping = if damping > 0.0 {
            damping
        } else {
            2.0 * damping_ratio * (unloaded.k_theta * cage_inertia).sqrt()
        };
        Ok(ElasticRod {
            spec,
            stiffness,
            cage_inertia,
            damping,
            load_eccentricity,
            rigid_moment: rigid_mass * rigid_lever,
            omega0,
        })
    }

    /// The beam-column quantities at rod force P (compression positive). Fails at or beyond
    /// buckling (s_N ≤ 0 or K_ϑ ≤ 0, §6 "Validity").
    #[inline]
    pub fn beam_column(&self, p: f64) -> Result<BeamColumn, ModelError> {
        BeamColumn::new(&self.stiffness, self.spec.flex_length, self.spec.rigid_length, p)
    }

    /// The cage equation solved for ϑ̈ (§6):
    /// J_m ϑ̈ + B_d ϑ̇ + K_ϑ(P)·ϑ = K_Δ(P)·Δ + e_P·P + m_f f_m·Δ̈.
    #[inline]
    pub fn acceleration(&self, bc: &BeamColumn, l: &CageLoads, x: &CageState) -> f64 {
        self.acceleration_with(bc.k_theta, bc.k_delta, l, x)
    }

    /// [`ElasticRod::acceleration`] with K_ϑ(P), K_Δ(P) given (from the stiffness table).
    #[inline]
    pub fn acceleration_with(
        &self,
        k_theta: f64,
        k_delta: f64,
        l: &CageLoads,
        x: &CageState,
    ) -> f64 {
        (k_delta * l.delta
            + self.load_eccentricity * l.rod_force
            + self.rigid_moment * l.delta_ddot
            - self.damping * x.rate
            - k_theta * x.theta)
            / self.cage_inertia
    }

    /// Quasi-static cage state (§6 "Initial state", `rod.initial_state` = 1): ϑ solves
    /// K_ϑ ϑ = K_Δ Δ + e_P P + m_f f_m Δ̈, and ϑ̇ = K_Δ·Δ̇/K_ϑ with P held fixed.
    pub fn quasi_static(&self, bc: &BeamColumn, l: &CageLoads, delta_dot: f64) -> CageState {
        CageState {
            theta: (bc.k_delta * l.delta
                + self.load_eccentricity * l.rod_force
                + self.rigid_moment * l.delta_ddot)
                / bc.k_theta,
            rate: bc.k_delta * delta_dot / bc.k_theta,
        }
    }

    /// Largest wire (spring) or fibre (thin rod) stress (§6 "Stress").
    pub fn stress_max(&self, bc: &BeamColumn, delta: f64, theta: f64, p: f64) -> f64 {
        stress_max(&self.spec, &self.stiffness, bc, delta, theta, p)
    }

    /// Static axial shortening P·l_f/A3 (§6).
    pub fn axial_deflection(&self, p: f64) -> f64 {
        self.stiffness.axial_deflection(p, self.spec.flex_length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kvo630() -> ElasticRod {
        ElasticRod::new(crate::model::elastic_rod::tests::kvo630(), 5e-7, 0.05, 0.0, 0.0, 0.0, 0.0)
            .unwrap()
    }

    #[test]
    fn quasi_static_state_is_an_equilibrium_of_the_cage_equation() {
        // At the quasi-static ϑ with ϑ̇ = 0 the cage equation gives ϑ̈ = 0 (independent check:
        // the residual of the equation itself).
        let rod = kvo630();
        let bc = rod.beam_column(10.0).unwrap();
        let l = CageLoads { delta: 7e-4, delta_ddot: -3.0, rod_force: 10.0 };
        let q = rod.quasi_static(&bc, &l, 0.0);
        let acc = rod.acceleration(&bc, &l, &CageState { theta: q.theta, rate: 0.0 });
        assert!(acc.abs() < 1e-9 * rod.omega0.powi(2) * q.theta.abs());
    }

    #[test]
    fn damping_from_ratio_uses_the_unloaded_stiffness() {
        let rod = kvo630();
        let k0 = rod.beam_column(0.0).unwrap().k_theta;
        assert!((rod.damping - 2.0 * 0.05 * (k0 * 5e-7).sqrt()).abs() < 1e-18);
        assert!((rod.omega0 - (k0 / 5e-7).sqrt()).abs() < 1e-9);
        let e = ElasticRod::new(rod.spec, 0.0, 0.05, 0.0, 0.0, 0.0, 0.0).unwrap_err().to_string();
        assert!(e.contains("rod.cage_inertia"));
    }

    #[test]
    fn piston_law_of_section_6() {
        let law = PistonLaw { r: 0.001, e: 1e-4 };
        let (k, d, dd) = law.kinematics(0.7);
        assert!((k.s - 0.001 * (1.0 - 0.7f64.cos())).abs() < 1e-18);
        assert!(
            (k.tf - 0.001 * 0.7f64.sin()).abs() < 1e-18
                && (k.tfp - 0.001 * 0.7f64.cos()).abs() < 1e-18
        );
        assert!(
            (d - (0.001 * 0.7f64.sin() - 1e-4)).abs() < 1e-18
                && (dd - 0.001 * 0.7f64.cos()).abs() < 1e-18
        );
        // Δ̈ against the second derivative of Δ(θ(t)) for θ = ωt + εt²/2 (closed form).
        let (w, eps) = (150.0, 20.0);
        let expect = 0.001 * (eps * 0.7f64.cos() - w * w * 0.7f64.sin());
        assert!((law.delta_ddot(0.7, w, eps) - expect).abs() < 1e-15);
        let at = law.at(0.7, w, eps);
        assert_eq!((at.k, at.delta, at.delta_rate), (k, d, dd));
        assert_eq!(at.delta_ddot, law.delta_ddot(0.7, w, eps));
    }
}
