//! The drive train of a reciprocating pump (docs/closed-loop.md "The DriveTrain FMU"): an induction
//! motor with Kloss's torque curve drives the crank shaft through a gearbox; the crank torque the
//! mechanism demands is the load.
//!
//! ```text
//! T_m = 2·T_b / (s/s_b + s_b/s) = 2·T_b·s·s_b / (s² + s_b²)     (Kloss; the second form is
//! s   = 1 − ω_m/ω_s,   ω_m = i·ω                                  regular at s = 0 and holds for
//! J·ω̇ = i·T_m − T_L,   J = J_c + i²·J_m,   θ̇ = ω                  generating, s < 0)
//! ```
//!
//! T_L (`load.torque`, the pump's `crank.torque`) is held over a communication step. The state
//! (θ, ω) is integrated inside the step with error control by the same Verner 6(5) pair as the
//! elastic rod (`crate::model::integrator`), seen as the second-order equation θ̈ = ω̇(θ̇).

use num_dual::Dual64;

use crate::model::kinematics::Scalar;
use serde::{Deserialize, Serialize};

use crate::model::error::{given, num, ModelError};
use crate::model::integrator::{
    advance, IntegratorState, IntegratorStats, SecondOrderRhs, Tolerance,
};

/// Parameters as the variable table writes them; `Default` is the documented default drive
/// (docs/closed-loop.md): a 4-pole 50 Hz motor through a 23:1 gearbox, the default pump at about
/// 65 strokes/min.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveTrainParams {
    /// i = ω_m/ω (motor speed over crank speed).
    pub gear_ratio: f64,
    /// ω_s [rad/s], motor shaft (2π·f/p).
    pub synchronous_speed: f64,
    /// T_b [N·m], motor shaft.
    pub breakdown_torque: f64,
    /// s_b.
    pub breakdown_slip: f64,
    /// J_m [kg·m²]: motor rotor and flywheel, motor shaft.
    pub motor_inertia: f64,
    /// J_c [kg·m²]: crank shaft, gear and rotating parts, crank side.
    pub crank_inertia: f64,
    /// Initial crank angle [rad] and speed [rad/s].
    pub angle_start: f64,
    pub speed_start: f64,
    /// Integrator tolerance when fmi2SetupExperiment gives none.
    pub tolerance: f64,
}

impl Default for DriveTrainParams {
    fn default() -> Self {
        DriveTrainParams {
            gear_ratio: 23.0,
            synchronous_speed: 2.0 * std::f64::consts::PI * 1500.0 / 60.0,
            breakdown_torque: 200.0,
            breakdown_slip: 0.15,
            motor_inertia: 0.5,
            crank_inertia: 50.0,
            angle_start: 0.0,
            speed_start: 2.0 * std::f64::consts::PI * 65.0 / 60.0,
            tolerance: 1e-8,
        }
    }
}

/// The smallest time constant of the drive accepted: the crank speed's relaxation time on the
/// steepest part of Kloss's curve (s = 0), τ = s_b·ω_s·J / (2·i²·T_b) (docs/hardening.md
/// "DriveTrain bounds"). An explicit integrator needs steps of about τ; its smallest step is
/// 16·ε·t (3.6e-9 s at t = 10⁶ s, 11.6 days of simulated time), so a drive with τ below 1e-9 s
/// cannot be integrated at all late in a run, and at 1 ms communication steps it needs over
/// 10⁵ internal steps per step. Real drives have τ of milliseconds to seconds (the default:
/// 35 ms).
pub const MIN_TIME_CONSTANT: f64 = 1e-9;

/// A validated drive train.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveTrain {
    pub p: DriveTrainParams,
    /// J = J_c + i²·J_m [kg·m²], crank side.
    pub inertia: f64,
    /// τ = s_b·ω_s·J / (2·i²·T_b) [s], the drive's smallest time constant.
    pub time_constant: f64,
}

/// The continuous state and the integrator's memory (part of the FMU state).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DriveState {
    pub angle: f64,
    pub speed: f64,
    pub integrator: IntegratorState,
}

/// What the drive train reports at a communication point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DriveOutputs {
    pub angle: f64,
    pub speed: f64,
    pub acceleration: f64,
    pub motor_speed: f64,
    pub motor_torque: f64,
    pub slip: f64,
    pub motor_power: f64,
}

impl DriveTrain {
    pub fn new(p: &DriveTrainParams) -> Result<DriveTrain, ModelError> {
        let pos = |name: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(ModelError::out_of_range(name, v, "(0, inf)"))
            }
        };
        pos("drive.gear_ratio", p.gear_ratio)?;
        pos("motor.synchronous_speed", p.synchronous_speed)?;
        pos("motor.breakdown_torque", p.breakdown_torque)?;
        if !(p.breakdown_slip > 0.0 && p.breakdown_slip < 1.0) {
            return Err(ModelError::out_of_range(
                "motor.breakdown_slip",
                p.breakdown_slip,
                "(0, 1)",
            ));
        }
        for (name, v) in [("motor.inertia", p.motor_inertia), ("crank.inertia", p.crank_inertia)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ModelError::out_of_range(name, v, "[0, inf) kg.m2"));
            }
        }
        let inertia = p.crank_inertia + p.gear_ratio * p.gear_ratio * p.motor_inertia;
        if !(inertia > 0.0 && inertia.is_finite()) {
            return Err(ModelError::invalid(format!(
                "the drive train's inertia J = crank.inertia + drive.gear_ratio²·motor.inertia = \
                 {} + {}²·{} = {} kg.m2 is not a positive finite number (crank.inertia = {}, \
                 drive.gear_ratio = {}, motor.inertia = {})",
                given(p.crank_inertia),
                given(p.gear_ratio),
                given(p.motor_inertia),
                num(inertia),
                given(p.crank_inertia),
                given(p.gear_ratio),
                given(p.motor_inertia)
            )));
        }
        // docs/hardening.md "DriveTrain bounds": the steepest slope of the motor torque.
        let tau = p.breakdown_slip * p.synchronous_speed * inertia
            / (2.0 * p.gear_ratio * p.gear_ratio * p.breakdown_torque);
        // Written so that a NaN τ (from overflowing factors) is refused too.
        if tau.is_nan() || tau < MIN_TIME_CONSTANT {
            return Err(ModelError::invalid(format!(
                "the drive train is too stiff to integrate: its time constant \
                 τ = s_b·ω_s·J / (2·i²·T_b) = {} s with motor.breakdown_slip s_b = {}, \
                 motor.synchronous_speed ω_s = {} rad/s, J = crank.inertia + \
                 drive.gear_ratio²·motor.inertia = {} + {}²·{} = {} kg.m2, drive.gear_ratio \
                 i = {}, motor.breakdown_torque T_b = {} N.m; allowed: τ >= {} s (a larger \
                 inertia, or a smaller breakdown torque or gear ratio)",
                num(tau),
                given(p.breakdown_slip),
                given(p.synchronous_speed),
                given(p.crank_inertia),
                given(p.gear_ratio),
                given(p.motor_inertia),
                num(inertia),
                given(p.gear_ratio),
                given(p.breakdown_torque),
                num(MIN_TIME_CONSTANT)
            )));
        }
        for (name, v) in
            [("crank.angle_start", p.angle_start), ("crank.speed_start", p.speed_start)]
        {
            if !v.is_finite() {
                return Err(ModelError::out_of_range(name, v, "a finite number"));
            }
        }
        if !(p.tolerance > 0.0 && p.tolerance < 1.0) {
            return Err(ModelError::out_of_range("solver.tolerance", p.tolerance, "(0, 1)"));
        }
        Ok(DriveTrain { p: *p, inertia, time_constant: tau })
    }

    /// Motor slip and torque [N·m, motor shaft] at crank speed ω (Kloss).
    #[inline]
    pub fn motor(&self, omega: f64) -> (f64, f64) {
        self.motor_of(omega)
    }

    /// [`DriveTrain::motor`] for any [`Scalar`] (a dual number carries its exact derivative, for
    /// the directional derivatives); with `f64` the same arithmetic in the same order.
    #[inline(always)]
    pub fn motor_of<T: Scalar>(&self, omega: T) -> (T, T) {
        let s = T::from(1.0) - omega * self.p.gear_ratio / self.p.synchronous_speed;
        let sb = self.p.breakdown_slip;
        (s, s * (2.0 * self.p.breakdown_torque) * sb / (s * s + sb * sb))
    }

    /// The outputs at `state` with load `load` and their tangent along the changes `d_angle`,
    /// `d_speed` of the state and `d_load` of the load (forward-mode automatic
    /// differentiation), and the tangent of d/dt (θ, ω).
    pub fn tangent(
        &self,
        state: &DriveState,
        load: f64,
        d_angle: f64,
        d_speed: f64,
        d_load: f64,
    ) -> (DriveOutputs, [f64; 2]) {
        let w = Dual64::new(state.speed, d_speed);
        let (slip, torque) = self.motor_of(w);
        let motor_speed = w * self.p.gear_ratio;
        let acceleration = (torque * self.p.gear_ratio - Dual64::new(load, d_load)) / self.inertia;
        let out = DriveOutputs {
            angle: d_angle,
            speed: d_speed,
            acceleration: acceleration.eps,
            motor_speed: motor_speed.eps,
            motor_torque: torque.eps,
            slip: slip.eps,
            motor_power: (torque * motor_speed).eps,
        };
        (out, [d_speed, acceleration.eps])
    }

    /// ω̇ = (i·T_m − T_L)/J.
    #[inline]
    pub fn acceleration(&self, omega: f64, load: f64) -> f64 {
        (self.p.gear_ratio * self.motor(omega).1 - load) / self.inertia
    }

    pub fn initial_state(&self) -> DriveState {
        DriveState {
            angle: self.p.angle_start,
            speed: self.p.speed_start,
            integrator: IntegratorState::default(),
        }
    }

    /// Integrates (θ, ω) over [t, t+h] with the load held. Tolerances: `tol` relative, and absolute
    /// on θ [rad] and on ω/ω_0 with ω_0 = ω_s/i, the synchronous crank speed (a fixed scale).
    pub fn step(
        &self,
        state: &DriveState,
        load: f64,
        t: f64,
        h: f64,
        tol: f64,
        stats: &mut IntegratorStats,
    ) -> Result<DriveState, ModelError> {
        if !load.is_finite() {
            return Err(ModelError::out_of_range("load.torque", load, "a finite number"));
        }
        struct Rhs<'a>(&'a DriveTrain, f64);
        impl SecondOrderRhs for Rhs<'_> {
            #[inline]
            fn accel(&mut self, _t: f64, _theta: f64, omega: f64) -> Result<f64, ModelError> {
                Ok(self.0.acceleration(omega, self.1))
            }
        }
        // A step shorter than the integrator resolves at this time (its floor, 16·ε·max(|t|,
        // |t + h|, 1e-3), `crate::model::integrator::advance`) would fail although FMI allows
        // any positive step: one Taylor step instead, θ + ωh + ω̇h²/2, ω + ω̇h, whose error
        // (h²·ω̈ with h below 1e-17 s at t <= 1 ms) is far below the rounding of θ and ω.
        if h < 16.0 * f64::EPSILON * t.abs().max((t + h).abs()).max(1e-3) {
            let acc = self.acceleration(state.speed, load);
            return Ok(DriveState {
                angle: state.angle + state.speed * h + 0.5 * acc * h * h,
                speed: state.speed + acc * h,
                integrator: state.integrator,
            });
        }
        let omega0 = self.p.synchronous_speed / self.p.gear_ratio;
        let tolerance = Tolerance::from_solver_tolerance(tol, omega0);
        let mut integ = state.integrator;
        let [angle, speed] = advance(
            &mut Rhs(self, load),
            t,
            [state.angle, state.speed],
            h,
            &tolerance,
            &mut integ,
            stats,
        )
        .map_err(|e| self.step_failure(state, load, h, e))?;
        Ok(DriveState { angle, speed, integrator: integ })
    }

    /// The integrator's failure, with what the drive was doing at the start of the step: the
    /// crank's acceleration and the torques that make it, naming the load when it exceeds
    /// what the motor can deliver.
    #[cold]
    fn step_failure(&self, state: &DriveState, load: f64, h: f64, e: ModelError) -> ModelError {
        let (_, motor_torque) = self.motor(state.speed);
        let drive_torque = self.p.gear_ratio * motor_torque;
        let acc = self.acceleration(state.speed, load);
        let peak = self.p.gear_ratio * self.p.breakdown_torque;
        let cause = if h > 1e5 * self.time_constant {
            format!(
                "; the communication step h = {} s is {} times the drive's time constant \
                 τ = {} s, more than the integrator covers in its limit of steps: use shorter \
                 communication steps",
                given(h),
                num(h / self.time_constant),
                num(self.time_constant)
            )
        } else if load.abs() > 10.0 * peak {
            format!(
                "; load.torque = {} N.m is {} times the most the motor delivers at the crank \
                 (drive.gear_ratio·motor.breakdown_torque = {} N.m)",
                given(load),
                num(load.abs() / peak),
                num(peak)
            )
        } else {
            String::new()
        };
        ModelError::evaluation(format!(
            "the drive train cannot follow the step: at its start crank.speed = {} rad/s and \
             crank.acceleration = (drive.gear_ratio·motor.torque − load.torque)/J = ({} − {}) \
             N.m / {} kg.m2 = {} rad/s2, a change of crank.speed of {} rad/s over the step{cause}; \
             integrator: {e}",
            num(state.speed),
            num(drive_torque),
            // A negative load in parentheses, so that the subtraction reads as one.
            if load < 0.0 { format!("({})", num(load)) } else { num(load) },
            num(self.inertia),
            num(acc),
            num(acc * h)
        ))
    }

    pub fn outputs(&self, state: &DriveState, load: f64) -> DriveOutputs {
        let (slip, torque) = self.motor(state.speed);
        let motor_speed = self.p.gear_ratio * state.speed;
        DriveOutputs {
            angle: state.angle,
            speed: state.speed,
            acceleration: self.acceleration(state.speed, load),
            motor_speed,
            motor_torque: torque,
            slip,
            motor_power: torque * motor_speed,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kloss_curve_peaks_at_the_breakdown_slip_and_vanishes_at_synchronous_speed() {
        let d = DriveTrain::new(&DriveTrainParams::default()).unwrap();
        let ws = d.p.synchronous_speed / d.p.gear_ratio;
        assert_eq!(d.motor(ws).1, 0.0);
        let at = |s: f64| d.motor(ws * (1.0 - s)).1;
        // T(s_b) = T_b, and the textbook form 2T_b/(s/s_b + s_b/s) away from s = 0.
        assert!((at(0.15) - 200.0).abs() < 1e-9);
        for s in [0.01, 0.05, 0.3, 0.9, -0.1] {
            assert!((at(s) - 2.0 * 200.0 / (s / 0.15 + 0.15 / s)).abs() < 1e-9 * 200.0, "{s}");
            assert!(at(0.15) >= at(s));
        }
    }

    #[test]
    fn constant_load_steady_state_and_exponential_approach() {
        // Linearised about the steady slip s*, ω approaches ω* with rate 1/τ = i·(dT/dω)/J.
        let d = DriveTrain::new(&DriveTrainParams::default()).unwrap();
        let load = 400.0;
        let mut st = d.initial_state();
        let mut stats = IntegratorStats::default();
        for k in 0..20000 {
            st = d.step(&st, load, k as f64 * 1e-3, 1e-3, 1e-10, &mut stats).unwrap();
        }
        // Steady: i·T_m(s*) = T_L, solved here by bisection on the Kloss curve (independent of step()).
        let (mut lo, mut hi) = (0.0, 0.15);
        for _ in 0..200 {
            let s = 0.5 * (lo + hi);
            if d.p.gear_ratio * 2.0 * 200.0 * s * 0.15 / (s * s + 0.0225) < load {
                lo = s
            } else {
                hi = s
            }
        }
        let w_star = d.p.synchronous_speed * (1.0 - lo) / d.p.gear_ratio;
        assert!((st.speed - w_star).abs() < 1e-9 * w_star, "{} vs {w_star}", st.speed);
    }

    #[test]
    fn rejects_bad_parameters_by_name() {
        let mut p = DriveTrainParams { breakdown_slip: 1.5, ..Default::default() };
        assert!(DriveTrain::new(&p).unwrap_err().to_string().contains("motor.breakdown_slip"));
        p = DriveTrainParams { crank_inertia: 0.0, motor_inertia: 0.0, ..Default::default() };
        let m = DriveTrain::new(&p).unwrap_err().to_string();
        assert!(m.contains("inertia J") && m.contains("crank.inertia = 0"), "{m}");
        p = DriveTrainParams { gear_ratio: f64::NAN, ..Default::default() };
        assert!(DriveTrain::new(&p).unwrap_err().to_string().contains("drive.gear_ratio"));
    }

    /// The time constant bound names the parameters that make the drive too stiff, with their
    /// values as given and τ to 6 digits; the default drive's τ is 35.0 ms.
    #[test]
    fn too_stiff_drives_are_refused_with_their_time_constant() {
        let d = DriveTrain::new(&DriveTrainParams::default()).unwrap();
        let tau = 0.15 * (50.0 * std::f64::consts::PI) * (50.0 + 23.0 * 23.0 * 0.5)
            / (2.0 * 23.0 * 23.0 * 200.0);
        assert!((tau - 0.0350200).abs() < 1e-6, "{tau}");
        // Just above the bound passes, just below is refused.
        let at = |j: f64| DriveTrainParams { crank_inertia: j, motor_inertia: 0.0, ..d.p };
        let j_min =
            MIN_TIME_CONSTANT * 2.0 * 23.0 * 23.0 * 200.0 / (0.15 * 50.0 * std::f64::consts::PI);
        assert!(DriveTrain::new(&at(j_min * 1.01)).is_ok());
        for (p, names) in [
            (
                at(1e-300),
                &["τ = s_b", "= 1e-300 + 23²·0 = 1e-300 kg.m2", "allowed: τ >= 1e-09 s"][..],
            ),
            (DriveTrainParams { breakdown_torque: 1e300, ..d.p }, &["1e+300", "τ = "][..]),
            (DriveTrainParams { breakdown_slip: 1e-300, ..d.p }, &["1e-300", "τ = "][..]),
            (DriveTrainParams { synchronous_speed: 1e-300, ..d.p }, &["1e-300", "τ = "][..]),
        ] {
            let m = DriveTrain::new(&p).unwrap_err().to_string();
            for n in names {
                assert!(m.contains(n), "{n:?} not in {m}");
            }
        }
    }

    /// A load far beyond the motor fails the step with the load named and its ratio to the
    /// motor's breakdown torque at the crank, not only the integrator's step size.
    #[test]
    fn an_impossible_load_is_named_when_the_step_fails() {
        let d = DriveTrain::new(&DriveTrainParams::default()).unwrap();
        for load in [1e300, -1e300] {
            let m = d
                .step(&d.initial_state(), load, 0.0, 1e-3, 1e-8, &mut IntegratorStats::default())
                .unwrap_err()
                .to_string();
            assert!(
                m.contains(&format!(
                    "load.torque = {} N.m is 2.17391e+296 times",
                    crate::model::error::given(load)
                )),
                "{m}"
            );
            assert!(m.contains("(drive.gear_ratio·motor.breakdown_torque = 4600 N.m)"), "{m}");
        }
    }
}
