//! The whole drive: validated parameters + crank motion + inputs (+ the cage state of an
//! elastic rod) → every output, and the time step of that state.
//! Data flows one way (architecture.md): crank → kinematics → loads → guide (P implicit) →
//! elastic rod → outputs.

use serde::{Deserialize, Serialize};

use crate::model::balancer::{Balancer, BalancerSpec, MachineFacts};
use crate::model::beam_unit::{BeamClass, BeamUnit, BeamUnitGeometry};
use crate::model::crank::CrankState;
use crate::model::crank_slider::CrankSlider;
use crate::model::elastic_rod::cage::{CageLoads, CageState, ElasticRod, PistonLaw};
use crate::model::elastic_rod::{BeamColumn, RodKind, RodSpec};
use crate::model::error::{require_finite, ModelError};
use crate::model::guide::{Guide, GuideOutputs};
use crate::model::integrator::{self, IntegratorState, IntegratorStats, SecondOrderRhs, Tolerance};
use crate::model::kinematics::{max_abs_torque_factor, Kinematics};
use crate::model::loads;
use crate::model::params::{Params, MECHANISM_BEAM_CLASS_I, MECHANISM_BEAM_CLASS_III, MECHANISM_CRANK_SLIDER};

/// Inputs of one evaluation besides the crank motion.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs {
    /// `link.external_force` [N], positive along +s.
    pub external_force: f64,
}

/// The FMU's continuous state and what its integrator carries between steps (part of the FMU
/// state). Zero and unused for a rigid rod.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RodState {
    pub cage: CageState,
    pub integrator: IntegratorState,
}

/// Every output of physics.md §10.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outputs {
    pub position: f64,
    pub velocity: f64,
    pub acceleration: f64,
    pub torque_factor: f64,
    pub inertia_force: f64,
    pub rod_force: f64,
    pub crank_torque: f64,
    pub rod_angle: f64,
    pub rod_angular_velocity: f64,
    pub balancer_force: f64,
    /// Φ + F_bal: what the balancer leaves of the inertia force (§7).
    pub balancer_residual: f64,
    /// The calculated parameter `balancer.stiffness_used` (0 when the balancer is off).
    pub balancer_stiffness_used: f64,
    /// Guide friction and support reactions (§5.3); all 0 when every support kind is 0.
    pub guide: GuideOutputs,
    /// Elastic rod (§6): largest stress and static axial shortening; 0 for a rigid rod.
    pub rod_stress_max: f64,
    pub rod_axial_deflection: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Mechanism {
    CrankSlider(CrankSlider),
    BeamUnit(BeamUnit),
    /// Crank-slider whose connecting rod is an elastic rod clamped in the piston (§6).
    ElasticRodSlider(PistonLaw, ElasticRod),
}

/// A validated machine. Built once at the end of initialization (and again when a tunable
/// parameter changes); immutable while stepping.
#[derive(Clone, Debug)]
pub struct Model {
    params: Params,
    mechanism: Mechanism,
    balancer: Option<Balancer>,
    guide: Option<Guide>,
}

/// Everything at one instant that the outputs and the cage equation share.
struct Instant {
    k: Kinematics,
    velocity: f64,
    acceleration: f64,
    inertia_force: f64,
    balancer_force: f64,
    guide: GuideOutputs,
    /// Elastic rod: the beam column at the final P, Δ and dΔ/dθ, and the clamp's transverse force.
    rod: Option<(BeamColumn, CageLoads, f64, f64)>,
}

impl Model {
    /// Checks everything a single-variable range cannot (assembly, finiteness) and precomputes.
    pub fn new(params: &Params) -> Result<Model, ModelError> {
        let p = params;
        for (name, v) in [
            ("crank.angle_offset", p.crank_angle_offset),
            ("load.mean", p.load_mean),
            ("load.amplitude", p.load_amplitude),
            ("load.phase", p.load_phase),
        ] {
            require_finite(name, v)?;
        }
        if !(p.mass >= 0.0 && p.mass.is_finite()) {
            return Err(ModelError::out_of_range("mass.reciprocating", p.mass, "[0, inf) kg"));
        }
        if !(p.velocity_scale > 0.0 && p.velocity_scale.is_finite()) {
            return Err(ModelError::out_of_range(
                "guide.velocity_scale",
                p.velocity_scale,
                "(0, inf) m/s",
            ));
        }
        if !(0..=2).contains(&p.load_profile) {
            return Err(ModelError::out_of_range("load.profile", p.load_profile as f64, "0, 1 or 2"));
        }
        if p.rotation != 1 && p.rotation != -1 {
            return Err(ModelError::out_of_range("rotation", p.rotation as f64, "-1 or +1"));
        }
        let beam = |class| -> Result<Mechanism, ModelError> {
            Ok(Mechanism::BeamUnit(BeamUnit::new(&BeamUnitGeometry {
                class,
                rotation: p.rotation as f64,
                front_arm: p.beam_front_arm,
                rear_arm: p.beam_rear_arm,
                pivot_dx: p.pivot_dx,
                pivot_dy: p.pivot_dy,
                pitman: p.rod_length,
                crank: p.crank_radius,
            })?))
        };
        let mechanism = match (p.mechanism, p.rod_kind) {
            (MECHANISM_CRANK_SLIDER, 0) => {
                Mechanism::CrankSlider(CrankSlider::new(p.crank_radius, p.rod_length, p.slider_offset)?)
            }
            (MECHANISM_CRANK_SLIDER, 1 | 2) => Self::elastic_rod_slider(p)?,
            (MECHANISM_BEAM_CLASS_I, 0) => beam(BeamClass::Conventional)?,
            (MECHANISM_BEAM_CLASS_III, 0) => beam(BeamClass::Class3)?,
            (MECHANISM_BEAM_CLASS_I | MECHANISM_BEAM_CLASS_III, 1 | 2) => {
                return Err(ModelError::invalid(format!(
                    "rod.kind = {} (elastic rod) exists only for the crank-slider (mechanism = 1), not for mechanism = {}",
                    p.rod_kind, p.mechanism
                )))
            }
            (MECHANISM_CRANK_SLIDER | MECHANISM_BEAM_CLASS_I | MECHANISM_BEAM_CLASS_III, other) => {
                return Err(ModelError::out_of_range(
                    "rod.kind",
                    other as f64,
                    "0 (rigid), 1 (thin rod) or 2 (helical spring)",
                ))
            }
            (other, _) => {
                return Err(ModelError::out_of_range(
                    "mechanism",
                    other as f64,
                    "1 (crank-slider), 2 (beam unit, class I) or 3 (beam unit, class III)",
                ))
            }
        };
        let mut model = Model { params: params.clone(), mechanism, balancer: None, guide: None };
        model.guide = Guide::new(&p.guide_spec()?, model.stroke())?;
        if p.balancer_enabled {
            for (name, v) in [
                ("balancer.stiffness", p.balancer_stiffness),
                ("balancer.design_speed", p.balancer_design_speed),
            ] {
                if !(v >= 0.0 && v.is_finite()) {
                    return Err(ModelError::out_of_range(name, v, "[0, inf)"));
                }
            }
            require_finite("balancer.neutral_position", p.balancer_neutral_position)?;
            let central = match model.mechanism {
                Mechanism::CrankSlider(_) if p.slider_offset == 0.0 => Some(p.crank_radius / p.rod_length),
                _ => None,
            };
            let facts = MachineFacts {
                mass: p.mass,
                stroke: model.stroke(),
                crank_radius: p.crank_radius,
                max_torque_factor: max_abs_torque_factor(|t| model.kinematics_at(t)),
                central_slider_lambda: central,
            };
            let spec = BalancerSpec {
                tuning: p.balancer_tuning,
                stiffness: p.balancer_stiffness,
                design_speed: p.balancer_design_speed,
                neutral_position: p.balancer_neutral_position,
            };
            model.balancer = Some(Balancer::new(&spec, &facts)?);
        }
        Ok(model)
    }

    fn elastic_rod_slider(p: &Params) -> Result<Mechanism, ModelError> {
        require_finite("geometry.slider_offset", p.slider_offset)?;
        if !(p.crank_radius > 0.0 && p.crank_radius.is_finite()) {
            return Err(ModelError::out_of_range("geometry.crank_radius", p.crank_radius, "(0, inf) m"));
        }
        for (name, v) in [
            ("rod.load_eccentricity", p.rod_load_eccentricity),
            ("rod.rigid_lever", p.rod_rigid_lever),
        ] {
            require_finite(name, v)?;
        }
        for (name, v) in [
            ("rod.damping_ratio", p.rod_damping_ratio),
            ("rod.damping", p.rod_damping),
            ("rod.rigid_mass", p.rod_rigid_mass),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(ModelError::out_of_range(name, v, "[0, inf)"));
            }
        }
        if !(p.solver_tolerance > 0.0 && p.solver_tolerance < 1.0) {
            return Err(ModelError::out_of_range("solver.tolerance", p.solver_tolerance, "(0, 1)"));
        }
        if !(p.rod_initial_state == 0 || p.rod_initial_state == 1) {
            return Err(ModelError::out_of_range(
                "rod.initial_state",
                p.rod_initial_state as f64,
                "0 (at rest) or 1 (quasi-static)",
            ));
        }
        let spec = RodSpec {
            kind: if p.rod_kind == 1 { RodKind::ThinRod } else { RodKind::HelicalSpring },
            flex_length: p.rod_flex_length,
            rigid_length: p.rod_rigid_length,
            wire_diameter: p.rod_wire_diameter,
            coil_diameter: p.rod_coil_diameter,
            coils: p.rod_coils,
            e_modulus: p.rod_e_modulus,
            poisson: p.rod_poisson,
        };
        let rod = ElasticRod::new(
            spec,
            p.rod_cage_inertia,
            p.rod_damping_ratio,
            p.rod_damping,
            p.rod_load_eccentricity,
            p.rod_rigid_mass,
            p.rod_rigid_lever,
        )?;
        Ok(Mechanism::ElasticRodSlider(PistonLaw { r: p.crank_radius, e: p.slider_offset }, rod))
    }

    pub fn params(&self) -> &Params {
        &self.params
    }

    /// Whether the FMU has a continuous state (an elastic rod, §6).
    pub fn has_state(&self) -> bool {
        matches!(self.mechanism, Mechanism::ElasticRodSlider(..))
    }

    /// Stroke S of the link [m].
    pub fn stroke(&self) -> f64 {
        match &self.mechanism {
            Mechanism::CrankSlider(m) => m.stroke(),
            Mechanism::BeamUnit(m) => m.stroke(),
            Mechanism::ElasticRodSlider(law, _) => law.stroke(),
        }
    }

    /// The balancer in use, if enabled.
    pub fn balancer(&self) -> Option<&Balancer> {
        self.balancer.as_ref()
    }

    /// Position-level kinematics at the model angle θ (offset already applied).
    #[inline]
    pub fn kinematics_at(&self, theta: f64) -> Kinematics {
        match &self.mechanism {
            Mechanism::CrankSlider(m) => m.kinematics(theta),
            Mechanism::BeamUnit(m) => m.kinematics(theta),
            Mechanism::ElasticRodSlider(law, _) => law.kinematics(theta).0,
        }
    }

    /// Position-level kinematics at the model angle θ = θ_in + offset (§2).
    #[inline]
    pub fn kinematics(&self, crank: &CrankState) -> Kinematics {
        self.kinematics_at(crank.angle + self.params.crank_angle_offset)
    }

    /// Kinematics, loads and the rod force at one instant (§2–§6). P is implicit through the
    /// friction: exactly (piecewise linear) for a rigid rod, by the guide's contracting
    /// iteration for an elastic rod, whose clamp loads depend on P and ϑ.
    // Always inlined: `Instant` is large (it carries the beam column of an elastic rod), and
    // returning it through a `Result` otherwise costs a memcpy per evaluation.
    #[inline(always)]
    fn instant(&self, crank: &CrankState, inputs: &Inputs, cage: &CageState) -> Result<Instant, ModelError> {
        let p = &self.params;
        let (w, eps) = (crank.speed, crank.acceleration);
        let theta = crank.angle + p.crank_angle_offset;
        let (k, rod_geometry) = match &self.mechanism {
            Mechanism::CrankSlider(m) => (m.kinematics(theta), None),
            Mechanism::BeamUnit(m) => (m.kinematics(theta), None),
            Mechanism::ElasticRodSlider(law, rod) => {
                let (k, delta, ddelta) = law.kinematics(theta);
                (k, Some((law, rod, delta, ddelta)))
            }
        };
        let velocity = k.velocity(w);
        let acceleration = k.acceleration(w, eps);
        let inertia_force = loads::inertia_force(p.mass, acceleration);
        let f_ext = inputs.external_force
            + loads::process_force_profile(
                p.load_profile,
                p.load_mean,
                p.load_amplitude,
                p.load_phase,
                theta,
                velocity,
                p.velocity_scale,
            );
        let balancer_force = self.balancer.as_ref().map_or(0.0, |b| b.force(k.s));
        // §4: P = F_ext + Φ + F_fr + F_bal.
        let p_base = f_ext + inertia_force + balancer_force;
        let (guide, rod) = match rod_geometry {
            None => {
                let guide = match &self.guide {
                    Some(g) => {
                        // The rigid slider rod pushes the crosshead sideways with −P·tanβ; a beam
                        // unit's polished rod hangs from the horsehead arc: no side force (§5.4).
                        let tan_beta = match &self.mechanism {
                            Mechanism::CrankSlider(m) => m.tan_beta(theta),
                            _ => 0.0,
                        };
                        g.solve_rigid(k.s, velocity, p_base, tan_beta)?
                    }
                    None => GuideOutputs { rod_force: p_base, ..GuideOutputs::default() },
                };
                (guide, None)
            }
            Some((law, rod, delta, ddelta)) => {
                let guide = match &self.guide {
                    Some(g) => {
                        // The rod's moment and transverse force at the clamp (z = L) load the
                        // link (§5.4); they depend on P through the beam column.
                        let mut failure = None;
                        let solved = g.solve_with_clamp_loads(k.s, velocity, p_base, |pp| {
                            match rod.beam_column(pp) {
                                Ok(bc) => bc.clamp_loads(delta, cage.theta),
                                Err(e) => {
                                    failure = Some(e);
                                    (f64::NAN, f64::NAN)
                                }
                            }
                        });
                        if let Some(e) = failure {
                            return Err(e);
                        }
                        solved?
                    }
                    None => GuideOutputs { rod_force: p_base, ..GuideOutputs::default() },
                };
                let bc = rod.beam_column(guide.rod_force)?;
                let loads = CageLoads {
                    delta,
                    delta_ddot: law.delta_ddot(theta, w, eps),
                    rod_force: guide.rod_force,
                };
                let transverse = bc.clamp_loads(delta, cage.theta).1;
                (guide, Some((bc, loads, ddelta, transverse)))
            }
        };
        Ok(Instant { k, velocity, acceleration, inertia_force, balancer_force, guide, rod })
    }

    fn check_inputs(crank: &CrankState, inputs: &Inputs) -> Result<(), ModelError> {
        require_finite("crank.angle", crank.angle)?;
        require_finite("crank.speed", crank.speed)?;
        require_finite("crank.acceleration", crank.acceleration)?;
        require_finite("link.external_force", inputs.external_force)?;
        Ok(())
    }

    /// All outputs at one instant. Inputs must be finite (checked here, so a NaN never reaches
    /// an output). `rod` is the cage state (ignored for a rigid rod).
    pub fn evaluate(&self, crank: &CrankState, inputs: &Inputs, rod: &RodState) -> Result<Outputs, ModelError> {
        let mut out = Outputs::default();
        self.evaluate_into(crank, inputs, rod, &mut out)?;
        Ok(out)
    }

    /// [`Model::evaluate`] writing into `out` (the FMU's per-step path: no large moves). On error
    /// `out` is unspecified.
    #[inline]
    pub fn evaluate_into(&self, crank: &CrankState, inputs: &Inputs, rod: &RodState, out: &mut Outputs) -> Result<(), ModelError> {
        Self::check_inputs(crank, inputs)?;
        let i = self.instant(crank, inputs, &rod.cage)?;
        let rod_force = i.guide.rod_force;
        *out = Outputs {
            position: i.k.s,
            velocity: i.velocity,
            acceleration: i.acceleration,
            torque_factor: i.k.tf,
            inertia_force: i.inertia_force,
            rod_force,
            crank_torque: loads::crank_torque_rigid(rod_force, i.k.tf),
            rod_angle: i.k.rod_angle,
            rod_angular_velocity: i.k.rod_angle_rate * crank.speed,
            balancer_force: i.balancer_force,
            balancer_residual: i.inertia_force + i.balancer_force,
            balancer_stiffness_used: self.balancer.as_ref().map_or(0.0, |b| b.stiffness),
            guide: i.guide,
            rod_stress_max: 0.0,
            rod_axial_deflection: 0.0,
        };
        if let (Some((bc, loads, ddelta, transverse)), Mechanism::ElasticRodSlider(_, elastic)) = (&i.rod, &self.mechanism) {
            // §4: the lateral pin force does work too: T = −P·TF + V·dΔ/dθ.
            out.crank_torque += transverse * ddelta;
            out.rod_angle = rod.cage.theta;
            out.rod_angular_velocity = rod.cage.rate;
            out.rod_stress_max = elastic.stress_max(bc, loads.delta, rod.cage.theta, rod_force);
            out.rod_axial_deflection = elastic.axial_deflection(rod_force);
        }
        Ok(())
    }

    /// The cage state at the start (§6 "Initial state"): quasi-static (ϑ solves the static cage
    /// equation together with P, found by iterating ϑ ↔ P; ϑ̇ = K_Δ·Δ̇/K_ϑ) or at rest.
    pub fn initial_rod_state(&self, crank: &CrankState, inputs: &Inputs) -> Result<RodState, ModelError> {
        Self::check_inputs(crank, inputs)?;
        let Mechanism::ElasticRodSlider(law, rod) = &self.mechanism else {
            return Ok(RodState::default());
        };
        let mut cage = CageState::default();
        if self.params.rod_initial_state == 0 {
            return Ok(RodState { cage, ..RodState::default() });
        }
        let theta = crank.angle + self.params.crank_angle_offset;
        let delta_dot = law.kinematics(theta).2 * crank.speed;
        // P depends on ϑ only through the guide friction (weakly): a contracting iteration.
        for _ in 0..100 {
            let i = self.instant(crank, inputs, &cage)?;
            let (bc, loads, _, _) = i.rod.as_ref().ok_or_else(|| ModelError::evaluation("elastic rod state missing"))?;
            let next = rod.quasi_static(bc, loads, delta_dot);
            let done = (next.theta - cage.theta).abs() <= 1e-15 * next.theta.abs().max(1e-300);
            cage = next;
            if done {
                return Ok(RodState { cage, ..RodState::default() });
            }
        }
        Err(ModelError::evaluation(format!(
            "rod.initial_state = 1: the quasi-static cage angle did not converge (last ϑ = {} rad)",
            cage.theta
        )))
    }

    /// Advances the cage state over one communication step [t, t+h] with the crank extrapolated
    /// inside it (§2), to the tolerance `tol` (§6 "Integration"). A rigid rod has no state.
    /// On error nothing is changed (the caller's state is only replaced on success).
    pub fn step(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        state: &RodState,
        h: f64,
        tol: f64,
        stats: &mut IntegratorStats,
    ) -> Result<RodState, ModelError> {
        Self::check_inputs(crank, inputs)?;
        let Mechanism::ElasticRodSlider(_, rod) = &self.mechanism else {
            return Ok(*state);
        };
        let mut rhs = CageRhs { model: self, rod, crank, inputs };
        let mut integ = state.integrator;
        let y = integrator::advance(
            &mut rhs,
            0.0,
            [state.cage.theta, state.cage.rate],
            h,
            &Tolerance::from_solver_tolerance(tol, rod.omega0),
            &mut integ,
            stats,
        )?;
        Ok(RodState { cage: CageState { theta: y[0], rate: y[1] }, integrator: integ })
    }

    /// `solver.tolerance` (used when the master gives no tolerance).
    pub fn default_tolerance(&self) -> f64 {
        self.params.solver_tolerance
    }
}

/// The cage equation as the integrator sees it: time τ from the start of the step, the crank
/// extrapolated to τ, P (inertia, process force, friction) following the crank at every stage.
struct CageRhs<'a> {
    model: &'a Model,
    rod: &'a ElasticRod,
    crank: &'a CrankState,
    inputs: &'a Inputs,
}

impl SecondOrderRhs for CageRhs<'_> {
    #[inline]
    fn accel(&mut self, tau: f64, theta: f64, rate: f64) -> Result<f64, ModelError> {
        let cage = CageState { theta, rate };
        let i = self.model.instant(&self.crank.extrapolate(tau), self.inputs, &cage)?;
        let (bc, loads, _, _) = i.rod.as_ref().ok_or_else(|| ModelError::evaluation("elastic rod state missing"))?;
        Ok(self.rod.acceleration(bc, loads, &cage))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::params::DEFAULT_CRANK_SPEED;

    #[test]
    fn default_machine_dead_centres() {
        // §3.1 closed forms through the whole evaluation: Φ(0) = −m·rω²(1+λ).
        let m = Model::new(&Params::default()).unwrap();
        let w = DEFAULT_CRANK_SPEED;
        let o = m.evaluate(&CrankState { angle: 0.0, speed: w, acceleration: 0.0 }, &Inputs::default(), &RodState::default()).unwrap();
        let expect = -300.0 * 0.2 * w * w * (1.0 + 0.2 / 1.19);
        assert!((o.inertia_force - expect).abs() < 1e-9 * expect.abs());
        // At the dead centre v = 0, so tanh(v/v_ε) = 0 and the guide adds no friction.
        assert_eq!(o.rod_force, o.inertia_force);
        assert!(o.crank_torque.abs() < 1e-9);
    }

    #[test]
    fn angle_offset_shifts_the_model_angle() {
        let p = Params { crank_angle_offset: 0.7, ..Params::default() };
        let m = Model::new(&p).unwrap();
        let m0 = Model::new(&Params::default()).unwrap();
        let c = CrankState { angle: 0.3, speed: 5.0, acceleration: 1.0 };
        let c0 = CrankState { angle: 1.0, ..c };
        let (a, b) = (m.evaluate(&c, &Inputs::default(), &RodState::default()).unwrap(), m0.evaluate(&c0, &Inputs::default(), &RodState::default()).unwrap());
        assert!((a.position - b.position).abs() < 1e-15 && (a.acceleration - b.acceleration).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_parameters_and_inputs() {
        for (p, name) in [
            (Params { mass: -1.0, ..Params::default() }, "mass.reciprocating"),
            (Params { mass: f64::NAN, ..Params::default() }, "mass.reciprocating"),
            (Params { rod_length: 0.1, ..Params::default() }, "geometry.rod_length"),
            (Params { load_profile: 3, ..Params::default() }, "load.profile"),
            (Params { mechanism: 7, ..Params::default() }, "mechanism"),
        ] {
            let e = Model::new(&p).unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
        let m = Model::new(&Params::default()).unwrap();
        let e = m
            .evaluate(&CrankState { angle: f64::NAN, speed: 1.0, acceleration: 0.0 }, &Inputs::default(), &RodState::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("crank.angle") && e.contains("NaN"), "{e}");
    }
}
