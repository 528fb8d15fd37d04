//! The whole drive: validated parameters + crank motion + inputs (+ the cage state of an
//! elastic rod) → every output; the time step of that state is in `drive/cage_step.rs`.
//! Data flows one way (architecture.md): crank → kinematics → loads → guide (P implicit) →
//! elastic rod → outputs.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::model::balancer::{Balancer, BalancerSpec, MachineFacts};
use crate::model::beam_unit::{BeamClass, BeamUnit, BeamUnitGeometry};
use crate::model::crank::CrankState;
use crate::model::crank_slider::CrankSlider;
use crate::model::elastic_rod::cage::{CageLoads, CageState, ElasticRod, PistonLaw, PistonPoint};
use crate::model::elastic_rod::table::StiffnessTable;
use crate::model::elastic_rod::{BeamColumn, RodKind, RodSpec};
use crate::model::error::{require_finite, ModelError};
use crate::model::guide::{Guide, GuideOutputs};
use crate::model::integrator::IntegratorState;
use crate::model::kinematics::{max_abs_torque_factor, Kinematics};
use crate::model::loads;
use crate::model::pump::Pump;
use cage_step::solve_on_table;

mod cage_rate;
mod cage_step;
mod tangent;
pub use tangent::Seed;

use crate::model::params::{
    Params, LOAD_PROFILE_PRESSURES, MAX_CYLINDERS, MECHANISM_BEAM_CLASS_I,
    MECHANISM_BEAM_CLASS_III, MECHANISM_CRANK_SLIDER,
};

/// Inputs of one evaluation besides the crank motion.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs {
    /// `link.external_force` [N], positive along +s (cylinder 1's link).
    pub external_force: f64,
    /// `fluid_end.discharge_pressure`, `fluid_end.suction_pressure` [Pa] (§4.1).
    pub discharge_pressure: f64,
    pub suction_pressure: f64,
}

/// The FMU's continuous state and what its integrator carries between steps (part of the FMU
/// state). Zero and unused for a rigid rod.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RodState {
    pub cage: CageState,
    pub integrator: IntegratorState,
}

/// Groups of outputs evaluated together, as bits of [`Outputs::ready`]. A rigid mechanism's
/// outputs are evaluated on demand, a group at a time, each with the groups it needs
/// ([`Model::evaluate_groups`]); an elastic rod evaluates all of them at once (one beam column
/// serves every group beyond the kinematics).
pub mod groups {
    /// Crank state and kinematics (§2, §3): model angle and speed, position, velocity,
    /// acceleration, torque factor, rod angle and its rate.
    pub const KINEMATICS: u8 = 1;
    /// Loads that do not depend on P (§4, §7): inertia force, balancer force and residual, and
    /// P without friction. Needs KINEMATICS.
    pub const LOADS: u8 = 2;
    /// The rod force P (implicit through the guide friction, §4, §5), crank torque, support
    /// reactions and friction, an elastic rod's stress and deflection (§6). Needs LOADS.
    pub const FORCES: u8 = 4;
    /// Cylinders 2.. of the pump (everything of theirs, §4.1), the crank torque summed over the
    /// cylinders and the mechanical power. Needs FORCES (cylinder 1's torque).
    pub const CYLINDERS: u8 = 8;
    /// Flow of each cylinder and of the pump, hydraulic power (§4.1). Needs the velocities:
    /// KINEMATICS, and CYLINDERS when there is more than one cylinder.
    pub const FLOW: u8 = 16;
    /// `crank.torque`, `crank.mechanical_power`: every cylinder's torque.
    pub const TORQUE: u8 = FORCES | CYLINDERS;
    pub const ALL: u8 = KINEMATICS | LOADS | FORCES | CYLINDERS | FLOW;
}

/// The outputs of one cylinder of the pump (§4.1). Cylinder 1's kinematics, inertia force,
/// friction and rod force are the link's outputs of [`Outputs`] (`position`, …); its entry here
/// holds its fluid force, torque and flow.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CylinderOutputs {
    pub position: f64,
    pub velocity: f64,
    pub acceleration: f64,
    pub inertia_force: f64,
    /// The process force of `load.profile` on its piston (without `link.external_force`).
    pub fluid_force: f64,
    /// F_fr of its supports (`link.friction_total` of its link).
    pub friction: f64,
    pub rod_force: f64,
    /// T_k = −P_k·TF_k.
    pub crank_torque: f64,
    pub flow: f64,
}

/// Every output of docs/model.md §10.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outputs {
    /// The [`groups`] whose fields below are up to date (0: none; set to 0 to invalidate).
    pub ready: u8,
    /// F_ext + Φ + F_bal, P without friction (§4): the LOADS group's input to FORCES.
    pub p_base: f64,
    /// tanβ of a rigid slider rod, whose side load on the crosshead is −P·tanβ (§5.4); 0 for a
    /// beam unit, whose polished rod hangs from the horsehead arc. The KINEMATICS group's input
    /// to FORCES.
    pub side_slope: f64,
    /// The model angle θ the other outputs belong to: the crank angle as last set plus
    /// `crank.angle_offset`, carried forward through the steps since (§2).
    pub model_angle: f64,
    /// The crank speed ω the other outputs belong to (as last set, carried forward with ε).
    pub model_speed: f64,
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
    /// The pump's cylinders (§4.1); entries beyond `fluid_end.cylinders` stay 0.
    pub cylinders: [CylinderOutputs; MAX_CYLINDERS],
    /// The guide's solution of cylinders 2.. (cylinder 1's is `guide`; the tangent starts from
    /// them).
    pub cylinder_guides: [GuideOutputs; MAX_CYLINDERS],
    /// Q = Σ Q_k, (p_d − p_s)·Q, T·ω (§4.1).
    pub flow: f64,
    pub hydraulic_power: f64,
    pub mechanical_power: f64,
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
    /// Elastic rod: K_ϑ, K_Δ and the clamp-load coefficients as piecewise polynomials of P
    /// (table.rs), for the integrator's stages. Shared, immutable (cloning a Model for an FMU
    /// state snapshot copies a pointer).
    rod_table: Option<Arc<StiffnessTable>>,
    /// The cylinders on the crankshaft (§4.1).
    pump: Pump,
}

/// Kinematics and the loads on the link that do not depend on P, at one instant.
#[derive(Clone, Copy)]
struct LinkLoads {
    k: Kinematics,
    velocity: f64,
    acceleration: f64,
    inertia_force: f64,
    balancer_force: f64,
    /// F_ext + Φ + F_bal: P without friction (§4).
    p_base: f64,
    /// The process force of `load.profile` (§4, §4.1).
    process: f64,
    /// Elastic rod: the piston law's Δ, dΔ/dθ, Δ̈ (§6).
    piston: Option<PistonPoint>,
}

/// Everything at one instant that an elastic rod's outputs and its cage equation share.
struct Instant {
    k: Kinematics,
    velocity: f64,
    acceleration: f64,
    inertia_force: f64,
    balancer_force: f64,
    p_base: f64,
    process: f64,
    guide: GuideOutputs,
    /// The beam column at the final P, the cage loads, dΔ/dθ, and the clamp's transverse force.
    rod: (BeamColumn, CageLoads, f64, f64),
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
        if !(0..=LOAD_PROFILE_PRESSURES).contains(&p.load_profile) {
            return Err(ModelError::out_of_range(
                "load.profile",
                p.load_profile as f64,
                "0, 1, 2 or 3",
            ));
        }
        let pump = Pump::new(p.cylinders, &p.cylinder)?;
        // §4.1: several cylinders share the rigid crank-slider's kinematics with their phases;
        // the elastic rod's cage (§6) is modelled for one rod clamped in one piston, and a beam
        // unit has one horsehead.
        if pump.n > 1 && (p.mechanism != MECHANISM_CRANK_SLIDER || p.rod_kind != 0) {
            return Err(ModelError::invalid(format!(
                "fluid_end.cylinders = {} needs the rigid crank-slider (mechanism = 1, rod.kind = 0), \
                 not mechanism = {}, rod.kind = {}: the elastic rod and the beam units are \
                 modelled for one cylinder",
                pump.n, p.mechanism, p.rod_kind
            )));
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
        let rod_table = match &mechanism {
            Mechanism::ElasticRodSlider(_, rod) => {
                StiffnessTable::build(&rod.stiffness, rod.spec.flex_length, rod.spec.rigid_length)
                    .map(Arc::new)
            }
            _ => None,
        };
        let mut model = Model {
            params: params.clone(),
            mechanism,
            balancer: None,
            guide: None,
            rod_table,
            pump,
        };
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
                Mechanism::CrankSlider(_) if p.slider_offset == 0.0 => {
                    Some(p.crank_radius / p.rod_length)
                }
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
            return Err(ModelError::out_of_range(
                "geometry.crank_radius",
                p.crank_radius,
                "(0, inf) m",
            ));
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

    /// Position-level kinematics at the model angle θ (offset already applied).
    #[inline]
    pub fn kinematics_at(&self, theta: f64) -> Kinematics {
        match &self.mechanism {
            Mechanism::CrankSlider(m) => m.kinematics(theta),
            Mechanism::BeamUnit(m) => m.kinematics(theta),
            Mechanism::ElasticRodSlider(law, _) => law.kinematics(theta).0,
        }
    }

    /// The model angle θ = θ_in + `crank.angle_offset` (§2), θ_in being the crank angle as the
    /// FMU knows it: the value last set, carried forward by the steps since.
    #[inline]
    pub fn model_angle(&self, crank: &CrankState) -> f64 {
        crank.angle + self.params.crank_angle_offset
    }

    /// Position-level kinematics at the model angle θ = θ_in + offset (§2).
    #[inline]
    pub fn kinematics(&self, crank: &CrankState) -> Kinematics {
        self.kinematics_at(self.model_angle(crank))
    }

    /// The link's kinematics and the loads on it that do not depend on P (§2–§4, §7); for an
    /// elastic rod also Δ, dΔ/dθ, Δ̈ of the piston law (§6), from the same sin_cos of θ.
    /// `sin_cos`: sinθ, cosθ when the caller has them (the integrator's stages), else computed.
    #[inline]
    fn link_loads(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        sin_cos: Option<(f64, f64)>,
    ) -> LinkLoads {
        let (w, eps) = (crank.speed, crank.acceleration);
        let theta = self.model_angle(crank);
        let (k, piston) = match &self.mechanism {
            Mechanism::CrankSlider(m) => (m.kinematics(theta), None),
            Mechanism::BeamUnit(m) => (m.kinematics(theta), None),
            Mechanism::ElasticRodSlider(law, _) => {
                let pp = match sin_cos {
                    Some((sin, cos)) => law.at_sin_cos(sin, cos, w, eps),
                    None => law.at(theta, w, eps),
                };
                (pp.k, Some(pp))
            }
        };
        let velocity = k.velocity(w);
        let acceleration = k.acceleration(w, eps);
        let (inertia_force, balancer_force, p_base, process) =
            self.loads_at(0, theta, k.s, velocity, acceleration, inputs);
        LinkLoads {
            k,
            velocity,
            acceleration,
            inertia_force,
            balancer_force,
            p_base,
            process,
            piston,
        }
    }

    /// The loads on cylinder `cyl`'s link that do not depend on P at its angle θ (θ + φ_k),
    /// position s, velocity v and acceleration a (§4, §4.1, §7): (Φ, F_bal,
    /// p_base = F_ext + Φ + F_bal, the process force of `load.profile`). `link.external_force`
    /// acts on cylinder 1 (`cyl` 0) only.
    #[inline]
    fn loads_at(
        &self,
        cyl: usize,
        theta: f64,
        s: f64,
        velocity: f64,
        acceleration: f64,
        inputs: &Inputs,
    ) -> (f64, f64, f64, f64) {
        let p = &self.params;
        let inertia_force = loads::inertia_force(p.mass, acceleration);
        let process = if p.load_profile == LOAD_PROFILE_PRESSURES {
            self.pump.cylinders[cyl].fluid_force(
                inputs.discharge_pressure,
                inputs.suction_pressure,
                velocity,
                p.velocity_scale,
            )
        } else {
            loads::process_force_profile(
                p.load_profile,
                p.load_mean,
                p.load_amplitude,
                p.load_phase,
                theta,
                velocity,
                p.velocity_scale,
            )
        };
        let external = if cyl == 0 { inputs.external_force } else { 0.0 };
        let f_ext = external + process;
        let balancer_force = self.balancer.as_ref().map_or(0.0, |b| b.force(s));
        // §4: P = F_ext + Φ + F_fr + F_bal.
        (inertia_force, balancer_force, f_ext + inertia_force + balancer_force, process)
    }

    /// Kinematics, loads and the rod force of an elastic rod at one instant (§2–§6). P is
    /// implicit through the friction: found by the guide's contracting iteration, as the clamp
    /// loads depend on P and ϑ. The iteration starts from P solved on the stiffness table (its error is that of the friction
    /// from the table, ~1e-13·|F_fr|, far inside the iteration's 1e-14 relative test), so it
    /// usually needs a single beam column, which is then reused for the outputs.
    // Always inlined: `Instant` is large (it carries the beam column of an elastic rod), and
    // returning it through a `Result` otherwise costs a memcpy per evaluation.
    #[inline(always)]
    fn instant(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        cage: &CageState,
    ) -> Result<Instant, ModelError> {
        let ll = self.link_loads(crank, inputs, None);
        let (guide, rod) = match (&self.mechanism, ll.piston) {
            (Mechanism::ElasticRodSlider(_, rod), Some(pp)) => {
                let (guide, bc) = match &self.guide {
                    Some(g) => {
                        // The rod's moment and transverse force at the clamp (z = L) load the
                        // link (§5.4); they depend on P through the beam column.
                        let cf = g.clamp_friction(ll.k.s, ll.velocity, ll.p_base)?;
                        let guess = self
                            .rod_table
                            .as_deref()
                            .and_then(|t| {
                                solve_on_table(
                                    t,
                                    Some(&cf),
                                    ll.p_base,
                                    pp.delta,
                                    cage.theta,
                                    ll.p_base,
                                    0,
                                    1e-15,
                                )
                            })
                            .map_or(ll.p_base, |sol| sol.p);
                        let mut failure = None;
                        let mut last = None;
                        let solved = g.solve_clamp_from(&cf, ll.p_base, guess, |pp_k| {
                            match rod.beam_column(pp_k) {
                                Ok(bc) => {
                                    let loads = bc.clamp_loads(pp.delta, cage.theta);
                                    last = Some(bc);
                                    loads
                                }
                                Err(e) => {
                                    failure = Some(e);
                                    (f64::NAN, f64::NAN)
                                }
                            }
                        });
                        if let Some(e) = failure {
                            return Err(e);
                        }
                        let guide = solved?;
                        // The beam column of the last iterate, within the solve's relative
                        // tolerance (1e-14) of the returned P.
                        let bc = match last {
                            Some(bc) => bc,
                            None => rod.beam_column(guide.rod_force)?,
                        };
                        (guide, bc)
                    }
                    None => (
                        GuideOutputs { rod_force: ll.p_base, ..GuideOutputs::default() },
                        rod.beam_column(ll.p_base)?,
                    ),
                };
                let loads = CageLoads {
                    delta: pp.delta,
                    delta_ddot: pp.delta_ddot,
                    rod_force: guide.rod_force,
                };
                let transverse = bc.clamp_loads(pp.delta, cage.theta).1;
                (guide, (bc, loads, pp.delta_rate, transverse))
            }
            // Rigid rods are evaluated by groups (`evaluate_groups`), never here.
            _ => {
                return Err(ModelError::evaluation(
                    "internal: Model::instant is for an elastic rod only",
                ))
            }
        };
        Ok(Instant {
            k: ll.k,
            velocity: ll.velocity,
            acceleration: ll.acceleration,
            inertia_force: ll.inertia_force,
            balancer_force: ll.balancer_force,
            p_base: ll.p_base,
            process: ll.process,
            guide,
            rod,
        })
    }

    /// Inputs (and the crank state carried forward from them) must be finite.
    #[inline]
    pub fn check_inputs(crank: &CrankState, inputs: &Inputs) -> Result<(), ModelError> {
        if (crank.angle
            + crank.speed
            + crank.acceleration
            + inputs.external_force
            + inputs.discharge_pressure
            + inputs.suction_pressure)
            .is_finite()
        {
            // The sum of finite numbers can overflow; then the checks below tell which is not.
            return Ok(());
        }
        Self::name_non_finite_input(crank, inputs)
    }

    #[cold]
    fn name_non_finite_input(crank: &CrankState, inputs: &Inputs) -> Result<(), ModelError> {
        require_finite("crank.angle", crank.angle)?;
        require_finite("crank.speed", crank.speed)?;
        require_finite("crank.acceleration", crank.acceleration)?;
        require_finite("link.external_force", inputs.external_force)?;
        require_finite("fluid_end.discharge_pressure", inputs.discharge_pressure)?;
        require_finite("fluid_end.suction_pressure", inputs.suction_pressure)?;
        Ok(())
    }

    /// All outputs at one instant. Inputs must be finite (checked here, so a NaN never reaches
    /// an output). `rod` is the cage state (ignored for a rigid rod).
    pub fn evaluate(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        rod: &RodState,
    ) -> Result<Outputs, ModelError> {
        let mut out = Outputs::default();
        self.evaluate_into(crank, inputs, rod, &mut out)?;
        Ok(out)
    }

    /// [`Model::evaluate`] writing into `out`: every group at once. On error `out` is
    /// unspecified.
    #[inline]
    pub fn evaluate_into(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        rod: &RodState,
        out: &mut Outputs,
    ) -> Result<(), ModelError> {
        out.ready = 0;
        self.evaluate_groups(crank, inputs, rod, out, groups::ALL)
    }

    /// Brings the [`groups`] in `want` of `out` up to date, with the groups they need, keeping
    /// those already marked ready (the FMU's evaluation on demand: a group is computed at most
    /// once per communication point, and only when an output of it is read). The values are
    /// those of evaluating every group at once, bit for bit: each group does the same
    /// arithmetic in the same order whenever it runs. A group that fails (a self-locking guide)
    /// leaves the groups before it ready and itself not ready, so it fails again when asked again.
    #[inline(always)]
    pub fn evaluate_groups(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        rod: &RodState,
        out: &mut Outputs,
        want: u8,
    ) -> Result<(), ModelError> {
        if want & !out.ready == 0 {
            return Ok(());
        }
        self.evaluate_missing(crank, inputs, rod, out, want)
    }

    /// [`Model::evaluate_groups`] when something is missing.
    #[inline(never)]
    fn evaluate_missing(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        rod: &RodState,
        out: &mut Outputs,
        want: u8,
    ) -> Result<(), ModelError> {
        // The groups a group needs (`groups`), without branches (the single cylinder's loop
        // step counts them): FLOW (16) needs CYLINDERS (8) when there is more than one
        // cylinder, CYLINDERS needs FORCES (4).
        let want = want | ((want >> 1) & self.pump.flow_needs);
        let want = want | ((want >> 1) & groups::FORCES);
        let missing = want & !out.ready;
        if out.ready == 0 {
            Self::check_inputs(crank, inputs)?;
        }
        if let Mechanism::ElasticRodSlider(_, elastic) = &self.mechanism {
            return self.evaluate_elastic(crank, inputs, rod, elastic, out);
        }
        let theta = self.model_angle(crank);
        let (w, eps) = (crank.speed, crank.acceleration);
        if out.ready & groups::KINEMATICS == 0 {
            let (k, side_slope) = match &self.mechanism {
                Mechanism::CrankSlider(m) => m.kinematics_and_tan_beta(theta),
                // A beam unit's polished rod hangs from the horsehead arc: no side force (§5.4).
                _ => (self.kinematics_at(theta), 0.0),
            };
            out.side_slope = side_slope;
            out.model_angle = theta;
            out.model_speed = w;
            out.position = k.s;
            out.velocity = k.velocity(w);
            out.acceleration = k.acceleration(w, eps);
            out.torque_factor = k.tf;
            out.rod_angle = k.rod_angle;
            out.rod_angular_velocity = k.rod_angle_rate * w;
            out.ready |= groups::KINEMATICS;
        }
        if missing & (groups::LOADS | groups::FORCES) != 0 && out.ready & groups::LOADS == 0 {
            let (inertia_force, balancer_force, p_base, process) =
                self.loads_at(0, theta, out.position, out.velocity, out.acceleration, inputs);
            out.cylinders[0].fluid_force = process;
            out.inertia_force = inertia_force;
            out.balancer_force = balancer_force;
            out.balancer_residual = inertia_force + balancer_force;
            out.balancer_stiffness_used = self.balancer.as_ref().map_or(0.0, |b| b.stiffness);
            out.p_base = p_base;
            out.ready |= groups::LOADS;
        }
        if missing & groups::FORCES != 0 {
            // The rigid slider rod pushes the crosshead sideways with −P·tanβ (§5.4); P is
            // solved exactly (piecewise linear in P).
            match &self.guide {
                Some(g) => g.solve_rigid_into::<0>(
                    out.position,
                    out.velocity,
                    out.p_base,
                    out.side_slope,
                    &mut out.guide,
                )?,
                None => {
                    out.guide = GuideOutputs { rod_force: out.p_base, ..GuideOutputs::default() }
                }
            };
            out.rod_force = out.guide.rod_force;
            out.crank_torque = loads::crank_torque_rigid(out.rod_force, out.torque_factor);
            out.cylinders[0].crank_torque = out.crank_torque;
            out.rod_stress_max = 0.0;
            out.rod_axial_deflection = 0.0;
            out.ready |= groups::FORCES;
        }
        if missing & groups::CYLINDERS != 0 {
            // §4.1: cylinders 2.. (none for one cylinder), T = Σ T_k, mechanical power T·ω.
            for k in 1..self.pump.n {
                (out.cylinders[k], out.cylinder_guides[k]) =
                    self.cylinder_outputs(k, theta, w, eps, inputs)?;
                out.crank_torque += out.cylinders[k].crank_torque;
            }
            out.mechanical_power = out.crank_torque * w;
            out.ready |= groups::CYLINDERS;
        }
        if missing & groups::FLOW != 0 {
            self.flow_into(out, inputs);
        }
        Ok(())
    }

    /// Everything of cylinder k ≥ 2 (index `k` ≥ 1) of a rigid crank-slider at model angle θ
    /// (§4.1): its link at θ + φ_k, loaded by its own process force, guided by its own supports.
    #[inline(never)]
    fn cylinder_outputs(
        &self,
        k: usize,
        theta: f64,
        w: f64,
        eps: f64,
        inputs: &Inputs,
    ) -> Result<(CylinderOutputs, GuideOutputs), ModelError> {
        let Mechanism::CrankSlider(m) = &self.mechanism else {
            // `Model::new` refuses several cylinders on any other mechanism.
            return Err(ModelError::evaluation("internal: several cylinders need a crank-slider"));
        };
        let th = theta + self.pump.cylinders[k].phase;
        let (kin, side_slope) = m.kinematics_and_tan_beta(th);
        let velocity = kin.velocity(w);
        let acceleration = kin.acceleration(w, eps);
        let (inertia_force, _, p_base, process) =
            self.loads_at(k, th, kin.s, velocity, acceleration, inputs);
        let guide = match &self.guide {
            Some(g) => g.solve_rigid(kin.s, velocity, p_base, side_slope)?,
            None => GuideOutputs { rod_force: p_base, ..GuideOutputs::default() },
        };
        let c = CylinderOutputs {
            position: kin.s,
            velocity,
            acceleration,
            inertia_force,
            fluid_force: process,
            friction: guide.friction_total,
            rod_force: guide.rod_force,
            crank_torque: loads::crank_torque_rigid(guide.rod_force, kin.tf),
            flow: 0.0,
        };
        Ok((c, guide))
    }

    /// The FLOW group (§4.1) from the velocities already in `out`: Q_k, Q = Σ Q_k,
    /// hydraulic power (p_d − p_s)·Q.
    #[inline]
    fn flow_into(&self, out: &mut Outputs, inputs: &Inputs) {
        let v_eps = self.params.velocity_scale;
        let mut q = self.pump.cylinders[0].flow(out.velocity, v_eps);
        out.cylinders[0].flow = q;
        for k in 1..self.pump.n {
            let qk = self.pump.cylinders[k].flow(out.cylinders[k].velocity, v_eps);
            out.cylinders[k].flow = qk;
            q += qk;
        }
        out.flow = q;
        out.hydraulic_power = (inputs.discharge_pressure - inputs.suction_pressure) * q;
        out.ready |= groups::FLOW;
    }

    /// Every output of an elastic-rod machine at once: its kinematics, loads, rod force and
    /// stress share the piston law's point and one beam column (§6).
    fn evaluate_elastic(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        rod: &RodState,
        elastic: &ElasticRod,
        out: &mut Outputs,
    ) -> Result<(), ModelError> {
        let i = self.instant(crank, inputs, &rod.cage)?;
        let (bc, loads, ddelta, transverse) = &i.rod;
        let rod_force = i.guide.rod_force;
        *out = Outputs {
            ready: groups::ALL,
            p_base: i.p_base,
            // The elastic rod's transverse force is part of its own solution (§6).
            side_slope: 0.0,
            model_angle: self.model_angle(crank),
            model_speed: crank.speed,
            position: i.k.s,
            velocity: i.velocity,
            acceleration: i.acceleration,
            torque_factor: i.k.tf,
            inertia_force: i.inertia_force,
            rod_force,
            // §4: the lateral pin force does work too: T = −P·TF + V·dΔ/dθ.
            crank_torque: loads::crank_torque_rigid(rod_force, i.k.tf) + transverse * ddelta,
            rod_angle: rod.cage.theta,
            rod_angular_velocity: rod.cage.rate,
            balancer_force: i.balancer_force,
            balancer_residual: i.inertia_force + i.balancer_force,
            balancer_stiffness_used: self.balancer.as_ref().map_or(0.0, |b| b.stiffness),
            guide: i.guide,
            rod_stress_max: elastic.stress_max(bc, loads.delta, rod.cage.theta, rod_force),
            rod_axial_deflection: elastic.axial_deflection(rod_force),
            cylinders: Default::default(),
            cylinder_guides: Default::default(),
            flow: 0.0,
            hydraulic_power: 0.0,
            mechanical_power: 0.0,
        };
        // One cylinder (`Model::new`): its process force, torque, flow and the powers (§4.1).
        out.cylinders[0].fluid_force = i.process;
        out.cylinders[0].crank_torque = out.crank_torque;
        out.mechanical_power = out.crank_torque * crank.speed;
        self.flow_into(out, inputs);
        Ok(())
    }

    /// The cage state at the start (§6 "Initial state"): quasi-static (ϑ solves the static cage
    /// equation together with P, found by iterating ϑ ↔ P; ϑ̇ = K_Δ·Δ̇/K_ϑ) or at rest.
    pub fn initial_rod_state(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
    ) -> Result<RodState, ModelError> {
        Self::check_inputs(crank, inputs)?;
        let Mechanism::ElasticRodSlider(law, rod) = &self.mechanism else {
            return Ok(RodState::default());
        };
        let mut cage = CageState::default();
        if self.params.rod_initial_state == 0 {
            return Ok(RodState { cage, ..RodState::default() });
        }
        let theta = self.model_angle(crank);
        let delta_dot = law.kinematics(theta).2 * crank.speed;
        // P depends on ϑ only through the guide friction (weakly): a contracting iteration.
        for _ in 0..100 {
            let i = self.instant(crank, inputs, &cage)?;
            let (bc, loads, _, _) = &i.rod;
            let next = rod.quasi_static(bc, loads, delta_dot);
            let done = (next.theta - cage.theta).abs() <= 1e-15 * next.theta.abs().max(1e-300);
            cage = next;
            if done {
                return Ok(RodState { cage, ..RodState::default() });
            }
        }
        Err(ModelError::evaluation(format!(
            "rod.initial_state = 1: the quasi-static cage angle did not converge (last ϑ = {} rad)",
            crate::model::error::num(cage.theta)
        )))
    }

    /// The same machine without the stiffness table: every stage uses the exact beam column
    /// (the reference of the table's tests).
    #[cfg(test)]
    fn without_rod_table(&self) -> Model {
        Model { rod_table: None, ..self.clone() }
    }

    /// `solver.tolerance` (used when the master gives no tolerance).
    pub fn default_tolerance(&self) -> f64 {
        self.params.solver_tolerance
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::cage_step::{CageRhs, STAGE_P_TOLERANCE_FACTOR};
    use super::*;
    use crate::model::integrator::{IntegratorStats, SecondOrderRhs};
    use crate::model::params::DEFAULT_CRANK_SPEED;

    #[test]
    fn default_machine_dead_centres() {
        // §3.1 closed forms through the whole evaluation: Φ(0) = −m·rω²(1+λ).
        let m = Model::new(&Params::default()).unwrap();
        let w = DEFAULT_CRANK_SPEED;
        let o = m
            .evaluate(
                &CrankState { angle: 0.0, speed: w, acceleration: 0.0 },
                &Inputs::default(),
                &RodState::default(),
            )
            .unwrap();
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
        let (a, b) = (
            m.evaluate(&c, &Inputs::default(), &RodState::default()).unwrap(),
            m0.evaluate(&c0, &Inputs::default(), &RodState::default()).unwrap(),
        );
        assert!(
            (a.position - b.position).abs() < 1e-15
                && (a.acceleration - b.acceleration).abs() < 1e-12
        );
    }

    /// The kvo630 machine of docs/model.md §8 (as in benches/host_loop.rs).
    pub(crate) fn kvo630() -> Params {
        let d = Params::default();
        let mut supports = d.supports;
        supports[0].kind = 0;
        supports[1].z = 0.005;
        supports[1].length = 0.010;
        supports[1].offset = 0.0;
        supports[1].tilt = 0.0;
        supports[2].kind = 0;
        Params {
            crank_radius: 0.001,
            mass: 0.02,
            load_mean: 14.7,
            link_lengths: [0.010, 0.0, 0.0, 0.0],
            link_diameters: [0.008, d.link_diameters[1], d.link_diameters[2], d.link_diameters[3]],
            supports,
            rod_kind: 2,
            ..d
        }
    }

    const KVO_SPEED: f64 = 2.0 * std::f64::consts::PI * 1500.0 / 60.0;

    /// Runs `n` communication steps of `h` at constant crank speed from the quasi-static start.
    fn run(m: &Model, h: f64, n: usize, tol: f64) -> (RodState, IntegratorStats) {
        let inputs = Inputs::default();
        let crank0 = CrankState { angle: 0.0, speed: KVO_SPEED, acceleration: 0.0 };
        let mut rod = m.initial_rod_state(&crank0, &inputs).unwrap();
        let mut stats = IntegratorStats::default();
        for k in 0..n {
            let crank = CrankState { angle: KVO_SPEED * k as f64 * h, ..crank0 };
            rod = m.step(&crank, &inputs, &rod, h, tol, &mut stats).unwrap();
        }
        (rod, stats)
    }

    #[test]
    fn stage_on_the_table_matches_the_exact_instant() {
        // Over a revolution (dead centres included, where the friction changes sign), for
        // several cage angles, with and without friction, with a double-acting load profile:
        // P and ϑ̈ of a table stage (cold and warm started) against the exact solve. The warm
        // stages integrate the shifted variable φ = ϑ − c·Δ (`CageRhs::shift`): given φ, φ̇ their
        // φ̈ + c·Δ̈ must be ϑ̈, with Δ = r·sinθ − e and its derivatives in closed form (§6).
        let mut profiles = kvo630();
        profiles.load_profile = 1;
        let mut no_friction = kvo630();
        no_friction.supports[1].kind = 0;
        for params in [kvo630(), profiles, no_friction] {
            let m = Model::new(&params).unwrap();
            let Mechanism::ElasticRodSlider(_, rod) = &m.mechanism else { unreachable!() };
            let table = m.rod_table.as_deref().unwrap();
            let scale = rod.omega0 * rod.omega0 * 0.04;
            let inputs = Inputs::default();
            let tol = 1e-8;
            let crank = CrankState { angle: 0.0, speed: KVO_SPEED, acceleration: 300.0 };
            for &theta in &[-0.03, 0.0, 0.021] {
                let mut warm = CageRhs {
                    model: &m,
                    rod,
                    crank: &crank,
                    inputs: &inputs,
                    table: Some(table),
                    p_tolerance: STAGE_P_TOLERANCE_FACTOR * tol,
                    friction_guess: 0.0,
                    cell_hint: 0,
                    sin_cos0: (crank.angle + params.crank_angle_offset).sin_cos(),
                    shift: 41.9,
                    start: None,
                };
                for i in 0..=400 {
                    let tau = i as f64 * 1e-4; // 0.04 s: 1.5 revolutions
                    let c = crank.extrapolate(tau);
                    let cage = CageState { theta, rate: 30.0 };
                    let exact = m.instant(&c, &inputs, &cage).unwrap();
                    let (bc, loads, _, _) = exact.rod;
                    let a_exact = rod.acceleration(&bc, &loads, &cage);
                    let ll = m.link_loads(&c, &inputs, None);
                    let pp = ll.piston.unwrap();
                    let cf = m
                        .guide
                        .as_ref()
                        .map(|g| g.clamp_friction(ll.k.s, ll.velocity, ll.p_base).unwrap());
                    let p_tol = STAGE_P_TOLERANCE_FACTOR * tol;
                    let cold = solve_on_table(
                        table,
                        cf.as_ref(),
                        ll.p_base,
                        pp.delta,
                        theta,
                        ll.p_base,
                        0,
                        p_tol,
                    )
                    .unwrap();
                    let p = exact.guide.rod_force;
                    assert!((cold.p - p).abs() <= p_tol * p.abs(), "τ {tau}: P {} vs {p}", cold.p);
                    let th = c.angle + params.crank_angle_offset;
                    let (r, e) = (params.crank_radius, params.slider_offset);
                    let delta = r * th.sin() - e;
                    let delta_dot = r * c.speed * th.cos();
                    let delta_ddot = r * (c.acceleration * th.cos() - c.speed * c.speed * th.sin());
                    let shift = warm.shift;
                    let a_warm =
                        warm.accel(tau, theta - shift * delta, 30.0 - shift * delta_dot).unwrap()
                            + shift * delta_ddot;
                    assert!(
                        (a_warm - a_exact).abs() <= 1e-12 * scale,
                        "τ {tau}: ϑ̈ {a_warm} vs {a_exact}"
                    );
                }
            }
        }
    }

    #[test]
    fn table_stages_give_the_exact_solution_within_a_small_fraction_of_the_tolerance() {
        // kvo630, 0.3 s in 1 ms steps at tol 1e-8 (ϑ ≈ 0.04 rad, ϑ̇ ≈ 70 rad/s), and the same
        // machine with a thin straight rod (rod.kind 1, stiffer): the run with the table against
        // the run with the exact beam column in every stage.
        let thin = Params { rod_kind: 1, ..kvo630() };
        for params in [kvo630(), thin] {
            let m = Model::new(&params).unwrap();
            let (a, sa) = run(&m, 1e-3, 300, 1e-8);
            let (b, sb) = run(&m.without_rod_table(), 1e-3, 300, 1e-8);
            let Mechanism::ElasticRodSlider(_, rod) = &m.mechanism else { unreachable!() };
            let d_theta = (a.cage.theta - b.cage.theta).abs() / 1e-8;
            let d_rate = (a.cage.rate - b.cage.rate).abs() / (1e-8 * rod.omega0);
            println!(
                "rod.kind {}: table vs exact |Δϑ|/tol {d_theta:.2e}, |Δϑ̇|/(tol Ω0) {d_rate:.2e}; {sa:?} {sb:?}",
                params.rod_kind
            );
            assert!(d_theta < 1e-3 && d_rate < 1e-3, "{d_theta} {d_rate}");
            assert_eq!(sa, sb);
            // Below TABLE_MIN_TOLERANCE the stages solve exactly (only the exact solve's first
            // iterate still comes from the table): the same solution to far below the tolerance.
            // The steps may differ by a marginal accept or reject (the stage solves differ in
            // rounding), not by more.
            let (c, sc) = run(&m, 1e-3, 30, 1e-11);
            let (d, sd) = run(&m.without_rod_table(), 1e-3, 30, 1e-11);
            assert!(sc.rhs_evals.abs_diff(sd.rhs_evals) * 50 <= sd.rhs_evals, "{sc:?} {sd:?}");
            assert!((c.cage.theta - d.cage.theta).abs() < 1e-2 * 1e-11, "{c:?} {d:?}");
            assert!((c.cage.rate - d.cage.rate).abs() < 1e-2 * 1e-11 * rod.omega0, "{c:?} {d:?}");
        }
    }

    #[test]
    fn the_shifted_cage_variable_saves_right_hand_sides() {
        // `CageRhs::shift`: integrating φ = ϑ − c·Δ instead of ϑ takes fewer internal steps per
        // 1 ms communication step (docs/performance.md "The elastic rod"). 0.3 s at tol 1e-8
        // (ϑ̇'s tolerance tol·|ω|): 4 501 evaluations for the spring, 8 109 for the thin rod.
        // The accuracy of the result is checked against an independent solution in
        // tests/python/test_elastic_rod.py.
        let thin = Params { rod_kind: 1, ..kvo630() };
        for (params, bound) in [(kvo630(), 16.0), (thin, 28.0)] {
            let m = Model::new(&params).unwrap();
            let (_, stats) = run(&m, 1e-3, 300, 1e-8);
            let per_step = stats.rhs_evals as f64 / 300.0;
            assert!(
                per_step <= bound,
                "rod.kind {}: {per_step} evaluations per 1 ms step",
                params.rod_kind
            );
        }
    }

    /// The pairs compared on φ (docs/performance.md "The elastic rod"): RHS evaluations per
    /// 1 ms communication step over 300 ms at tolerances from 3e-8 to 3e-10, and the largest
    /// error of ϑ [rad] and ϑ̇/Ω0 against a run of Verner 6(5) at 1e-12, for the spring and the
    /// thin rod of kvo630: the work of each pair at a given accuracy.
    /// `cargo test --release --lib pairs_compared -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn pairs_compared_on_the_shifted_cage_variable() {
        use crate::model::integrator::tests::compared::{with_pair, Which};
        let thin = Params { rod_kind: 1, ..kvo630() };
        for params in [kvo630(), thin] {
            let m = Model::new(&params).unwrap();
            let Mechanism::ElasticRodSlider(_, rod) = &m.mechanism else { unreachable!() };
            let omega0 = rod.omega0;
            let trajectory = |tol: f64| {
                let inputs = Inputs::default();
                let crank0 = CrankState { angle: 0.0, speed: KVO_SPEED, acceleration: 0.0 };
                let mut state = m.initial_rod_state(&crank0, &inputs).unwrap();
                let mut stats = IntegratorStats::default();
                let mut out = Vec::new();
                for k in 0..300 {
                    let crank = CrankState { angle: KVO_SPEED * k as f64 * 1e-3, ..crank0 };
                    state = m.step(&crank, &inputs, &state, 1e-3, tol, &mut stats).unwrap();
                    out.push(state.cage);
                }
                (out, stats)
            };
            let (reference, _) = with_pair(Which::Verner65, || trajectory(1e-12));
            for which in [Which::Verner65, Which::Tsit5, Which::Dp5, Which::Verner76] {
                for tol in [3e-8, 1e-8, 3e-9, 1e-9, 3e-10] {
                    let (run, stats) = with_pair(which, || trajectory(tol));
                    let err = run
                        .iter()
                        .zip(&reference)
                        .map(|(a, b)| {
                            (a.theta - b.theta).abs().max((a.rate - b.rate).abs() / omega0)
                        })
                        .fold(0.0, f64::max);
                    println!(
                        "rod.kind {} {which:?} tol {tol:e}: {:.2} evaluations per 1 ms step, {} steps, {} rejected, largest error {err:.2e}",
                        params.rod_kind,
                        stats.rhs_evals as f64 / 300.0,
                        stats.steps,
                        stats.rejected
                    );
                }
            }
        }
    }

    #[test]
    fn steps_are_deterministic_and_continue_bit_identically() {
        let m = Model::new(&kvo630()).unwrap();
        let (a, _) = run(&m, 1e-3, 150, 1e-8);
        let (b, _) = run(&m, 1e-3, 150, 1e-8);
        assert_eq!(a, b);
        // Stop after 100 steps, rebuild the model (as a restored FMU state does), go on.
        let inputs = Inputs::default();
        let (mid, _) = run(&m, 1e-3, 100, 1e-8);
        let m2 = Model::new(&kvo630()).unwrap();
        let mut rod = mid;
        let mut stats = IntegratorStats::default();
        for k in 100..150 {
            let crank = CrankState {
                angle: KVO_SPEED * k as f64 * 1e-3,
                speed: KVO_SPEED,
                acceleration: 0.0,
            };
            rod = m2.step(&crank, &inputs, &rod, 1e-3, 1e-8, &mut stats).unwrap();
        }
        assert_eq!(rod, a);
    }

    #[test]
    fn near_buckling_the_stages_are_exact_and_buckling_fails_the_step() {
        let m = Model::new(&kvo630()).unwrap();
        let Mechanism::ElasticRodSlider(_, rod) = &m.mechanism else { unreachable!() };
        let p_max = m.rod_table.as_ref().unwrap().range().1;
        // The buckling load (largest P the beam column accepts), by bisection.
        let (mut lo, mut hi) = (p_max, 4.0 * p_max);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if rod.beam_column(mid).is_ok() {
                lo = mid
            } else {
                hi = mid
            }
        }
        // Mean load between the table's end and buckling, the inertia (±0.5 N) keeping P there:
        // every stage takes the exact path, bit-identical to the model without table.
        let between = Params { load_mean: 0.5 * (p_max + lo), ..kvo630() };
        assert!(0.5 * (lo - p_max) > 0.6, "{p_max} {lo}");
        let m = Model::new(&between).unwrap();
        assert_eq!(run(&m, 1e-3, 20, 1e-8), run(&m.without_rod_table(), 1e-3, 20, 1e-8));
        // Mean load 0.2 N below buckling: the inertia load pushes P past it within a revolution;
        // the step fails naming the buckling (docs/model.md §6 "Validity"), the state is untouched.
        let m = Model::new(&Params { load_mean: lo - 0.2, ..kvo630() }).unwrap();
        let inputs = Inputs::default();
        let crank0 = CrankState { angle: 0.0, speed: KVO_SPEED, acceleration: 0.0 };
        let mut rod_state = m.initial_rod_state(&crank0, &inputs).unwrap();
        let mut stats = IntegratorStats::default();
        let mut failed = None;
        for k in 0..40 {
            let crank = CrankState { angle: KVO_SPEED * k as f64 * 1e-3, ..crank0 };
            match m.step(&crank, &inputs, &rod_state, 1e-3, 1e-8, &mut stats) {
                Ok(next) => rod_state = next,
                Err(e) => {
                    failed = Some(e.to_string());
                    break;
                }
            }
        }
        let msg = failed.expect("P exceeds the buckling load within a revolution");
        assert!(msg.contains("buckl"), "{msg}");
    }

    #[test]
    fn rejects_bad_parameters_and_inputs() {
        for (p, name) in [
            (Params { mass: -1.0, ..Params::default() }, "mass.reciprocating"),
            (Params { mass: f64::NAN, ..Params::default() }, "mass.reciprocating"),
            (Params { rod_length: 0.1, ..Params::default() }, "geometry.rod_length"),
            (Params { load_profile: 4, ..Params::default() }, "load.profile"),
            (Params { cylinders: 2, rod_kind: 2, ..Params::default() }, "fluid_end.cylinders"),
            (Params { cylinders: 2, mechanism: 2, ..Params::default() }, "fluid_end.cylinders"),
            (Params { mechanism: 7, ..Params::default() }, "mechanism"),
        ] {
            let e = Model::new(&p).unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
        let m = Model::new(&Params::default()).unwrap();
        let e = m
            .evaluate(
                &CrankState { angle: f64::NAN, speed: 1.0, acceleration: 0.0 },
                &Inputs::default(),
                &RodState::default(),
            )
            .unwrap_err()
            .to_string();
        assert!(e.contains("crank.angle") && e.contains("NaN"), "{e}");
    }
}
