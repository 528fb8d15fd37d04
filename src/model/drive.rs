//! The whole drive: validated parameters + crank motion + inputs → every output.
//! Data flows one way (architecture.md): crank → kinematics → loads → outputs.

use crate::model::balancer::{Balancer, BalancerSpec, MachineFacts};
use crate::model::beam_unit::{BeamClass, BeamUnit, BeamUnitGeometry};
use crate::model::crank::CrankState;
use crate::model::crank_slider::CrankSlider;
use crate::model::error::{require_finite, ModelError};
use crate::model::guide::{Guide, GuideOutputs};
use crate::model::kinematics::{max_abs_torque_factor, Kinematics};
use crate::model::loads;
use crate::model::params::{Params, MECHANISM_BEAM_CLASS_I, MECHANISM_BEAM_CLASS_III, MECHANISM_CRANK_SLIDER};

/// Inputs of one evaluation besides the crank motion.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs {
    /// `link.external_force` [N], positive along +s.
    pub external_force: f64,
}

/// Every output of physics.md §10 implemented so far.
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
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Mechanism {
    CrankSlider(CrankSlider),
    BeamUnit(BeamUnit),
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
        let mechanism = match p.mechanism {
            MECHANISM_CRANK_SLIDER => {
                Mechanism::CrankSlider(CrankSlider::new(p.crank_radius, p.rod_length, p.slider_offset)?)
            }
            MECHANISM_BEAM_CLASS_I => beam(BeamClass::Conventional)?,
            MECHANISM_BEAM_CLASS_III => beam(BeamClass::Class3)?,
            other => {
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

    pub fn params(&self) -> &Params {
        &self.params
    }

    /// Stroke S of the link [m].
    pub fn stroke(&self) -> f64 {
        match &self.mechanism {
            Mechanism::CrankSlider(m) => m.stroke(),
            Mechanism::BeamUnit(m) => m.stroke(),
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
        }
    }

    /// Position-level kinematics at the model angle θ = θ_in + offset (§2).
    #[inline]
    pub fn kinematics(&self, crank: &CrankState) -> Kinematics {
        self.kinematics_at(crank.angle + self.params.crank_angle_offset)
    }

    /// All outputs at one instant. Inputs must be finite (checked here, so a NaN never reaches
    /// an output).
    #[inline]
    pub fn evaluate(&self, crank: &CrankState, inputs: &Inputs) -> Result<Outputs, ModelError> {
        require_finite("crank.angle", crank.angle)?;
        require_finite("crank.speed", crank.speed)?;
        require_finite("crank.acceleration", crank.acceleration)?;
        require_finite("link.external_force", inputs.external_force)?;
        let p = &self.params;
        let (w, eps) = (crank.speed, crank.acceleration);
        let k = self.kinematics(crank);
        let velocity = k.velocity(w);
        let acceleration = k.acceleration(w, eps);
        let inertia_force = loads::inertia_force(p.mass, acceleration);
        let theta = crank.angle + p.crank_angle_offset;
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
        // §4: P = F_ext + Φ + F_fr + F_bal, implicit in P through the friction (the rod's side
        // load moves the reactions), solved exactly by the guide (§5.3, §5.4).
        let p_base = f_ext + inertia_force + balancer_force;
        let guide = match &self.guide {
            Some(g) => {
                // The rigid slider rod pushes the crosshead sideways with −P·tanβ; a beam unit's
                // polished rod hangs from the horsehead arc and has no side force (§5.4).
                let tan_beta = match &self.mechanism {
                    Mechanism::CrankSlider(m) => m.tan_beta(theta),
                    Mechanism::BeamUnit(_) => 0.0,
                };
                g.solve_rigid(k.s, velocity, p_base, tan_beta)?
            }
            None => GuideOutputs { rod_force: p_base, ..GuideOutputs::default() },
        };
        let rod_force = guide.rod_force;
        Ok(Outputs {
            position: k.s,
            velocity,
            acceleration,
            torque_factor: k.tf,
            inertia_force,
            rod_force,
            crank_torque: loads::crank_torque_rigid(rod_force, k.tf),
            rod_angle: k.rod_angle,
            rod_angular_velocity: k.rod_angle_rate * w,
            balancer_force,
            balancer_residual: inertia_force + balancer_force,
            balancer_stiffness_used: self.balancer.as_ref().map_or(0.0, |b| b.stiffness),
            guide,
        })
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
        let o = m.evaluate(&CrankState { angle: 0.0, speed: w, acceleration: 0.0 }, &Inputs::default()).unwrap();
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
        let (a, b) = (m.evaluate(&c, &Inputs::default()).unwrap(), m0.evaluate(&c0, &Inputs::default()).unwrap());
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
            .evaluate(&CrankState { angle: f64::NAN, speed: 1.0, acceleration: 0.0 }, &Inputs::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("crank.angle") && e.contains("NaN"), "{e}");
    }
}
