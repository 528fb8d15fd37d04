//! The DriveTrain FMU: the induction motor, gearbox and crank shaft of `crate::model::drive_train`
//! behind the shared FMI glue (docs/closed-loop.md). Its only input, `load.torque`, is held over a
//! communication step; it has no crank inputs, so the pump's carry-forward rule for crank inputs
//! (docs/model.md §2) does not concern it.

pub mod variables;

use crate::fmi::model::{FmuModel, ModelInfo};
use crate::fmi::variables::Table;
use crate::model::drive_train::{DriveOutputs, DriveState, DriveTrain, DriveTrainParams};
use crate::model::error::ModelError;
use crate::model::integrator::IntegratorStats;

pub use variables::{InputSlot, LOAD_TORQUE_VR, TABLE, VARIABLES};

pub struct DriveTrainFmu;

static INFO: ModelInfo = ModelInfo {
    model_identifier: "DriveTrain",
    model_name: "DriveTrain",
    description: "Drive train of a reciprocating pump: induction motor (Kloss torque curve), gearbox and crank shaft; load torque in, crank angle, speed and acceleration out",
    default_experiment: (0.0, 10.0, 0.001),
    documentation: "<p>Induction motor with Kloss's torque curve driving a crank shaft through a gearbox: \
J&middot;d&omega;/dt = i&middot;T<sub>m</sub> &minus; T<sub>L</sub>, J = J<sub>c</sub> + i&sup2;J<sub>m</sub>, \
T<sub>m</sub> = 2T<sub>b</sub>s&middot;s<sub>b</sub>/(s&sup2; + s<sub>b</sub>&sup2;), s = 1 &minus; i&omega;/&omega;<sub>s</sub>. \
The load torque (the pump's crank.torque) is held over each step; the state is integrated inside fmi2DoStep \
with error control. See closed-loop.html for the closed loop with the ReciprocatingDrive FMU.</p>",
    input_derivatives_hint: "the load torque is held over each step",
};

#[inline]
fn load(values: &[f64]) -> f64 {
    values[LOAD_TORQUE_VR]
}

impl FmuModel for DriveTrainFmu {
    type Params = DriveTrainParams;
    type Built = DriveTrain;
    type State = DriveState;
    type Outputs = DriveOutputs;
    type Input = InputSlot;
    type Output = fn(&DriveOutputs) -> f64;
    type Stats = IntegratorStats;

    fn info() -> &'static ModelInfo {
        &INFO
    }

    #[inline]
    fn table() -> &'static Table<Self> {
        &TABLE
    }

    fn fresh_state(_values: &[f64]) -> DriveState {
        DriveState::default()
    }

    fn build(params: &DriveTrainParams) -> Result<DriveTrain, ModelError> {
        DriveTrain::new(params)
    }

    fn initialize(
        d: &DriveTrain,
        values: &[f64],
        _state: &DriveState,
        out: &mut DriveOutputs,
    ) -> Result<DriveState, ModelError> {
        let st = d.initial_state();
        *out = d.outputs(&st, load(values));
        Ok(st)
    }

    #[inline]
    fn update_outputs(
        d: &DriveTrain,
        values: &[f64],
        state: &DriveState,
        cache: &mut DriveOutputs,
    ) -> Result<(), ModelError> {
        *cache = d.outputs(state, load(values));
        Ok(())
    }

    /// Eager: a valid cache holds every output.
    #[inline]
    fn read(cache: &DriveOutputs, get: fn(&DriveOutputs) -> f64) -> Option<f64> {
        Some(get(cache))
    }

    fn step(
        d: &DriveTrain,
        values: &[f64],
        state: &DriveState,
        h: f64,
        tol: f64,
        stats: &mut IntegratorStats,
        out: &mut DriveOutputs,
    ) -> Result<DriveState, ModelError> {
        let st = d.step(state, load(values), 0.0, h, tol, stats)?;
        *out = d.outputs(&st, load(values));
        Ok(st)
    }

    fn default_tolerance(d: &DriveTrain) -> f64 {
        d.p.tolerance
    }

    /// Model Exchange: θ and ω, d/dt (θ, ω) = (ω, (i·T_m(ω) − T_L)/J) (docs/closed-loop.md).
    const CONTINUOUS_STATES: &'static [(&'static str, &'static str)] =
        &[("crank.angle", "rad/s"), ("crank.speed", "rad/s2")];

    /// θ itself, ω itself, and every other output through ω (docs/closed-loop.md); the
    /// acceleration also through the load (the table).
    const OUTPUT_STATES: &'static [(&'static str, &'static [usize])] = &[
        ("crank.angle", &[0]),
        ("crank.speed", &[1]),
        ("crank.acceleration", &[1]),
        ("motor.speed", &[1]),
        ("motor.torque", &[1]),
        ("motor.slip", &[1]),
        ("motor.power", &[1]),
    ];

    /// dθ/dt = ω; dω/dt = (i·T_m(ω) − T_L)/J.
    const DERIVATIVE_DEPENDENCIES: &'static [(&'static [InputSlot], &'static [usize])] =
        &[(&[], &[1]), (&[InputSlot::LoadTorque], &[1])];

    fn continuous_states(state: &DriveState, x: &mut [f64]) {
        x[0] = state.angle;
        x[1] = state.speed;
    }

    fn set_continuous_states(state: &mut DriveState, x: &[f64]) {
        state.angle = x[0];
        state.speed = x[1];
    }

    fn derivatives(
        d: &DriveTrain,
        values: &[f64],
        state: &DriveState,
        dx: &mut [f64],
    ) -> Result<(), ModelError> {
        dx[0] = state.speed;
        dx[1] = d.acceleration(state.speed, load(values));
        Ok(())
    }

    /// Exact directional derivatives (docs/fmi-interface.md "Directional derivatives"): of the
    /// outputs and d/dt (θ, ω) with respect to load.torque and the states (in co-simulation the
    /// state the instance holds).
    const DIRECTIONAL_DERIVATIVES: bool = true;

    fn tangent(
        d: &DriveTrain,
        values: &[f64],
        state: &DriveState,
        d_values: &[f64],
        d_states: &[f64],
        tangent: &mut DriveOutputs,
        d_derivatives: &mut [f64],
    ) -> Result<(), ModelError> {
        let (out, dd) = d.tangent(state, load(values), d_states[0], d_states[1], load(d_values));
        *tangent = out;
        d_derivatives.copy_from_slice(&dd);
        Ok(())
    }

    fn check_state(state: &DriveState) -> Result<(), &'static str> {
        let i = &state.integrator;
        if ![state.angle, state.speed, i.h_next, i.err_prev].iter().all(|v| v.is_finite()) {
            return Err("drive-train state");
        }
        Ok(())
    }
}
