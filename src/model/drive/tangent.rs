//! Exact directional derivatives of the outputs (docs/fmi-interface.md "Directional
//! derivatives"): forward-mode automatic differentiation over the model's own code. The
//! kinematics (§2, §3) and the loads that do not depend on P (§4, §7) are generic over the
//! scalar and run once with a dual number (`num_dual::Dual64`) whose dual part is the direction;
//! the rod force, implicit through the guide friction, is differentiated implicitly
//! (`guide/tangent.rs`).

use num_dual::{Dual64, DualNum};

use super::{groups, CylinderOutputs, Inputs, Mechanism, Model, Outputs, RodState};
use crate::model::crank::CrankState;
use crate::model::elastic_rod::cage::{ElasticRod, PistonLaw};
use crate::model::elastic_rod::tangent as rod_tangent;
use crate::model::error::ModelError;
use crate::model::guide::GuideOutputs;
use crate::model::kinematics::Kinematics;
use crate::model::loads;
use crate::model::params::LOAD_PROFILE_PRESSURES;

/// A direction in the space of the inputs and the cage state: the changes of crank.angle,
/// crank.speed, crank.acceleration, link.external_force, fluid_end.discharge_pressure,
/// fluid_end.suction_pressure and (Model Exchange, an elastic rod)
/// of the cage states rod.cage_angle ϑ and rod.cage_rate ϑ̇ (ignored by a rigid mechanism).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Seed {
    pub angle: f64,
    pub speed: f64,
    pub acceleration: f64,
    pub external_force: f64,
    pub discharge_pressure: f64,
    pub suction_pressure: f64,
    pub cage_angle: f64,
    pub cage_rate: f64,
}

impl Model {
    /// The outputs at (crank, inputs, rod) and their directional derivatives along `seed`
    /// (the tangent, in the same fields; `ready` marks every group of both). The cage state of
    /// an elastic rod moves along `seed.cage_angle`, `seed.cage_rate` (0 in co-simulation,
    /// which holds it).
    pub fn tangent(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        rod: &RodState,
        seed: &Seed,
    ) -> Result<(Outputs, Outputs), ModelError> {
        self.state_tangent(crank, inputs, rod, seed).map(|(value, tangent, _)| (value, tangent))
    }

    /// [`Model::tangent`] and the directional derivative of ϑ̈ (`Model::cage_acceleration`,
    /// docs/model.md §6) along `seed`; 0 for a rigid mechanism, which has no cage.
    pub fn state_tangent(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        rod: &RodState,
        seed: &Seed,
    ) -> Result<(Outputs, Outputs, f64), ModelError> {
        if let Mechanism::ElasticRodSlider(law, elastic) = &self.mechanism {
            return self.elastic_tangent(law, elastic, crank, inputs, rod, seed);
        }
        let value = self.evaluate(crank, inputs, rod)?;
        let dual = Dual64::new;
        let theta = dual(self.model_angle(crank), seed.angle);
        let w = dual(crank.speed, seed.speed);
        let eps = dual(crank.acceleration, seed.acceleration);
        let (k, side_slope) = match &self.mechanism {
            Mechanism::CrankSlider(m) => m.kinematics_and_tan_beta_of(theta),
            Mechanism::BeamUnit(m) => (m.kinematics_of(theta), Dual64::from(0.0)),
            // Dispatched at the top.
            Mechanism::ElasticRodSlider(..) => unreachable!(),
        };
        let velocity = k.velocity(w);
        let acceleration = k.acceleration(w, eps);
        let (inertia_force, balancer_force, p_base, process) =
            self.dual_loads(0, theta, k.s, velocity, acceleration, inputs, seed);
        let guide = match &self.guide {
            Some(g) => g.solve_rigid_tangent(k.s, velocity, p_base, side_slope, &value.guide)?,
            None => GuideOutputs { rod_force: p_base.eps, ..GuideOutputs::default() },
        };
        // T = −P·TF (§4).
        let crank_torque = -(guide.rod_force * k.tf.re + value.rod_force * k.tf.eps);
        let mut cylinders = [CylinderOutputs::default(); crate::model::params::MAX_CYLINDERS];
        cylinders[0].fluid_force = process.eps;
        cylinders[0].crank_torque = crank_torque;
        let mut torque = crank_torque;
        let mut velocities = [velocity; crate::model::params::MAX_CYLINDERS];
        for c in 1..self.pump.n {
            let (cyl, v) =
                self.cylinder_tangent(c, theta, w, eps, inputs, seed, &value.cylinder_guides[c])?;
            torque += cyl.crank_torque;
            cylinders[c] = cyl;
            velocities[c] = v;
        }
        let (flow, hydraulic_power) = self.dual_flow(&velocities, &mut cylinders, inputs, seed);
        let tangent = Outputs {
            ready: groups::ALL,
            p_base: p_base.eps,
            side_slope: side_slope.eps,
            model_angle: seed.angle,
            model_speed: seed.speed,
            position: k.s.eps,
            velocity: velocity.eps,
            acceleration: acceleration.eps,
            torque_factor: k.tf.eps,
            inertia_force: inertia_force.eps,
            rod_force: guide.rod_force,
            crank_torque: torque,
            rod_angle: k.rod_angle.eps,
            rod_angular_velocity: (k.rod_angle_rate * w).eps,
            balancer_force: balancer_force.eps,
            balancer_residual: (inertia_force + balancer_force).eps,
            balancer_stiffness_used: 0.0,
            guide,
            rod_stress_max: 0.0,
            rod_axial_deflection: 0.0,
            cylinders,
            cylinder_guides: Default::default(),
            flow,
            hydraulic_power,
            // d(T·ω) = dT·ω + T·dω.
            mechanical_power: torque * crank.speed + value.crank_torque * seed.speed,
        };
        Ok((value, tangent, 0.0))
    }
}

impl Model {
    /// [`Model::state_tangent`] of an elastic rod (§6): the piston law and the loads in dual
    /// numbers, the rod force by implicit differentiation of the clamp solve
    /// (`Guide::solve_clamp_tangent`; ϑ moves the clamp loads at fixed P as Δ does), the clamp
    /// loads, the stress and K_ϑ, K_Δ by the dual beam column (`elastic_rod/tangent.rs`), ϑ̈ by
    /// the cage equation (`ElasticRod::acceleration_with`) in dual numbers.
    fn elastic_tangent(
        &self,
        law: &PistonLaw,
        elastic: &ElasticRod,
        crank: &CrankState,
        inputs: &Inputs,
        rod: &RodState,
        seed: &Seed,
    ) -> Result<(Outputs, Outputs, f64), ModelError> {
        let value = self.evaluate(crank, inputs, rod)?;
        let theta = Dual64::new(self.model_angle(crank), seed.angle);
        let w = Dual64::new(crank.speed, seed.speed);
        let eps = Dual64::new(crank.acceleration, seed.acceleration);
        // The piston law of §6: s = r(1 − cosθ), TF = r·sinθ, TF' = r·cosθ, Δ = r·sinθ − e.
        let (sin, cos) = theta.sin_cos();
        let k = Kinematics {
            s: (-cos + 1.0) * law.r,
            tf: sin * law.r,
            tfp: cos * law.r,
            rod_angle: Dual64::from(0.0),
            rod_angle_rate: Dual64::from(0.0),
        };
        let delta = sin * law.r - law.e;
        let delta_rate = cos * law.r;
        let velocity = k.velocity(w);
        let acceleration = k.acceleration(w, eps);
        let (inertia_force, balancer_force, p_base, process) =
            self.dual_loads(0, theta, k.s, velocity, acceleration, inputs, seed);
        let cage_theta = Dual64::new(rod.cage.theta, seed.cage_angle);
        let cage_rate = Dual64::new(rod.cage.rate, seed.cage_rate);
        let bc = elastic.beam_column(value.rod_force)?;
        let stiff = &elastic.stiffness;
        let guide = match &self.guide {
            Some(g) => g.solve_clamp_tangent(k.s, velocity, p_base, &value.guide, |p, along| {
                let (d, t) = if along {
                    (delta, cage_theta)
                } else {
                    (Dual64::from(delta.re), Dual64::from(cage_theta.re))
                };
                rod_tangent::clamp_loads(stiff, &bc, p, d, t)
            })?,
            None => GuideOutputs { rod_force: p_base.eps, ..GuideOutputs::default() },
        };
        let p = Dual64::new(value.rod_force, guide.rod_force);
        let (_, transverse) = rod_tangent::clamp_loads(stiff, &bc, p, delta, cage_theta);
        // §4: T = −P·TF + V·dΔ/dθ (as `evaluate_elastic`).
        let crank_torque = transverse * delta_rate - p * k.tf;
        let stress = rod_tangent::stress_max(&elastic.spec, stiff, &bc, p, delta, cage_theta);
        // The cage equation of §6 (`ElasticRod::acceleration_with`), Δ̈ = r(ε·cosθ − ω²·sinθ).
        let (k_theta, k_delta) = rod_tangent::stiffnesses(stiff, &bc, p);
        let delta_ddot = (eps * cos - w * w * sin) * law.r;
        let cage_acceleration =
            (k_delta * delta + p * elastic.load_eccentricity + delta_ddot * elastic.rigid_moment
                - cage_rate * elastic.damping
                - k_theta * cage_theta)
                / elastic.cage_inertia;
        let tangent = Outputs {
            ready: groups::ALL,
            p_base: p_base.eps,
            side_slope: 0.0,
            model_angle: seed.angle,
            model_speed: seed.speed,
            position: k.s.eps,
            velocity: velocity.eps,
            acceleration: acceleration.eps,
            torque_factor: k.tf.eps,
            inertia_force: inertia_force.eps,
            rod_force: guide.rod_force,
            crank_torque: crank_torque.eps,
            // rod.angle = ϑ, rod.angular_velocity = ϑ̇ (§6).
            rod_angle: seed.cage_angle,
            rod_angular_velocity: seed.cage_rate,
            balancer_force: balancer_force.eps,
            balancer_residual: (inertia_force + balancer_force).eps,
            balancer_stiffness_used: 0.0,
            guide,
            rod_stress_max: stress.eps,
            // P·l_f/A3, linear in P.
            rod_axial_deflection: elastic.axial_deflection(guide.rod_force),
            cylinders: Default::default(),
            cylinder_guides: Default::default(),
            flow: 0.0,
            hydraulic_power: 0.0,
            mechanical_power: crank_torque.eps * crank.speed + value.crank_torque * seed.speed,
        };
        let mut tangent = tangent;
        tangent.cylinders[0].fluid_force = process.eps;
        tangent.cylinders[0].crank_torque = crank_torque.eps;
        let velocities = [velocity; crate::model::params::MAX_CYLINDERS];
        (tangent.flow, tangent.hydraulic_power) =
            self.dual_flow(&velocities, &mut tangent.cylinders, inputs, seed);
        Ok((value, tangent, cage_acceleration.eps))
    }

    /// The loads of `Model::loads_at` (§4, §4.1, §7) of cylinder `cyl` in dual numbers: (Φ,
    /// F_bal, p_base, process force). Inlined in both callers (out of line it cost the rigid
    /// mechanisms' derivative 14 instructions).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn dual_loads(
        &self,
        cyl: usize,
        theta: Dual64,
        s: Dual64,
        velocity: Dual64,
        acceleration: Dual64,
        inputs: &Inputs,
        seed: &Seed,
    ) -> (Dual64, Dual64, Dual64, Dual64) {
        let p = &self.params;
        let inertia_force = acceleration * -p.mass;
        let process = if p.load_profile == LOAD_PROFILE_PRESSURES {
            self.pump.cylinders[cyl].fluid_force(
                Dual64::new(inputs.discharge_pressure, seed.discharge_pressure),
                Dual64::new(inputs.suction_pressure, seed.suction_pressure),
                velocity,
                p.velocity_scale,
            )
        } else {
            loads::process_force_profile_of(
                p.load_profile,
                p.load_mean,
                p.load_amplitude,
                p.load_phase,
                theta,
                velocity,
                p.velocity_scale,
            )
        };
        let external = if cyl == 0 {
            Dual64::new(inputs.external_force, seed.external_force)
        } else {
            Dual64::from(0.0)
        };
        let f_ext = external + process;
        let balancer_force = match &self.balancer {
            Some(b) => (s - b.neutral_position) * -b.stiffness,
            None => Dual64::from(0.0),
        };
        (inertia_force, balancer_force, f_ext + inertia_force + balancer_force, process)
    }

    /// Cylinder `c` ≥ 1 of a rigid crank-slider (§4.1) in dual numbers, as
    /// `Model::cylinder_outputs`, from its guide solution `value`: its outputs' tangent and its
    /// velocity (dual).
    #[allow(clippy::too_many_arguments)]
    fn cylinder_tangent(
        &self,
        c: usize,
        theta: Dual64,
        w: Dual64,
        eps: Dual64,
        inputs: &Inputs,
        seed: &Seed,
        value: &GuideOutputs,
    ) -> Result<(CylinderOutputs, Dual64), ModelError> {
        let Mechanism::CrankSlider(m) = &self.mechanism else {
            return Err(ModelError::evaluation("internal: several cylinders need a crank-slider"));
        };
        let th = theta + self.pump.cylinders[c].phase;
        let (k, side_slope) = m.kinematics_and_tan_beta_of(th);
        let velocity = k.velocity(w);
        let acceleration = k.acceleration(w, eps);
        let (inertia_force, _, p_base, process) =
            self.dual_loads(c, th, k.s, velocity, acceleration, inputs, seed);
        let guide = match &self.guide {
            Some(g) => {
                (value.rod_force, g.solve_rigid_tangent(k.s, velocity, p_base, side_slope, value)?)
            }
            None => (p_base.re, GuideOutputs { rod_force: p_base.eps, ..GuideOutputs::default() }),
        };
        let (rod_force, t) = guide;
        Ok((
            CylinderOutputs {
                position: k.s.eps,
                velocity: velocity.eps,
                acceleration: acceleration.eps,
                inertia_force: inertia_force.eps,
                fluid_force: process.eps,
                friction: t.friction_total,
                rod_force: t.rod_force,
                crank_torque: -(t.rod_force * k.tf.re + rod_force * k.tf.eps),
                flow: 0.0,
            },
            velocity,
        ))
    }

    /// The FLOW group's tangent (§4.1): Q_k into `cylinders`, and (Q, (p_d − p_s)·Q).
    fn dual_flow(
        &self,
        velocities: &[Dual64],
        cylinders: &mut [CylinderOutputs],
        inputs: &Inputs,
        seed: &Seed,
    ) -> (f64, f64) {
        let mut q = Dual64::from(0.0);
        for c in 0..self.pump.n {
            let qc = self.pump.cylinders[c].flow(velocities[c], self.params.velocity_scale);
            cylinders[c].flow = qc.eps;
            q += qc;
        }
        let dp = Dual64::new(
            inputs.discharge_pressure - inputs.suction_pressure,
            seed.discharge_pressure - seed.suction_pressure,
        );
        (q.eps, (dp * q).eps)
    }
}

#[cfg(test)]
mod tests {
    //! The dual-number kinematics against the hand-derived closed forms of §3 (two independent
    //! derivations of the same derivatives): d(s)/dθ by AD equals TF, d(TF)/dθ equals TF', and
    //! d(β)/dθ equals dβ/dθ, to 1e-13 of each one's largest magnitude over a revolution.
    use num_dual::Dual64;

    use super::{Mechanism, Model};
    use crate::model::kinematics::Kinematics;
    use crate::model::params::Params;

    fn machines() -> Vec<(&'static str, Params)> {
        let offset = Params { slider_offset: 0.07, ..Params::default() };
        let beam = |mechanism: i32, rotation: i32| {
            let mut p = Params { mechanism, rotation, ..Params::default() };
            if mechanism == 2 {
                // sk8-3.5-4000 (docs/model.md §8).
                (p.beam_front_arm, p.beam_rear_arm, p.pivot_dx, p.pivot_dy) =
                    (3.5, 2.5, 2.195, 3.0);
                (p.rod_length, p.crank_radius) = (3.0, 1.01);
            } else {
                // The Mark II-like class III geometry of beam_unit.rs's tests.
                (p.beam_front_arm, p.beam_rear_arm, p.pivot_dx, p.pivot_dy) = (3.8, 2.4, 1.4, 3.2);
                (p.rod_length, p.crank_radius) = (3.4, 0.9);
            }
            p.supports.iter_mut().for_each(|s| s.kind = 0);
            p
        };
        vec![
            ("central crank-slider", Params::default()),
            ("offset crank-slider", offset),
            ("class I clockwise", beam(2, 1)),
            ("class I counter-clockwise", beam(2, -1)),
            ("class III clockwise", beam(3, 1)),
            ("class III counter-clockwise", beam(3, -1)),
        ]
    }

    #[test]
    fn dual_kinematics_match_the_closed_form_derivatives() {
        for (name, p) in machines() {
            let m = Model::new(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
            let at = |theta: f64| -> (Kinematics, Kinematics<Dual64>) {
                let d = Dual64::new(theta, 1.0);
                match &m.mechanism {
                    Mechanism::CrankSlider(c) => {
                        (c.kinematics(theta), c.kinematics_and_tan_beta_of(d).0)
                    }
                    Mechanism::BeamUnit(b) => (b.kinematics(theta), b.kinematics_of(d)),
                    Mechanism::ElasticRodSlider(..) => unreachable!(),
                }
            };
            let n = 720;
            let samples: Vec<_> =
                (0..n).map(|i| at(std::f64::consts::TAU * (i as f64 + 0.37) / n as f64)).collect();
            let max = |f: &dyn Fn(&Kinematics) -> f64| {
                samples.iter().map(|(k, _)| f(k).abs()).fold(0.0, f64::max)
            };
            let (tf_max, tfp_max, rate_max) =
                (max(&|k| k.tf), max(&|k| k.tfp), max(&|k| k.rod_angle_rate));
            for (k, d) in &samples {
                // The real parts are the f64 values (to rounding: a dual divides through a
                // reciprocal).
                for (a, b, scale) in
                    [(k.s, d.s.re, 1.0), (k.tf, d.tf.re, tf_max), (k.tfp, d.tfp.re, tfp_max)]
                {
                    assert!((a - b).abs() <= 4.0 * f64::EPSILON * scale, "{name}: {a} vs {b}");
                }
                assert!(
                    (d.s.eps - k.tf).abs() <= 1e-13 * tf_max,
                    "{name}: {} vs {}",
                    d.s.eps,
                    k.tf
                );
                assert!(
                    (d.tf.eps - k.tfp).abs() <= 1e-13 * tfp_max,
                    "{name}: {} vs {}",
                    d.tf.eps,
                    k.tfp
                );
                assert!(
                    (d.rod_angle.eps - k.rod_angle_rate).abs() <= 1e-13 * rate_max,
                    "{name}: {} vs {}",
                    d.rod_angle.eps,
                    k.rod_angle_rate
                );
            }
        }
    }
}
