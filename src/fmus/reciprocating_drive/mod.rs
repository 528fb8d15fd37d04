//! The ReciprocatingDrive FMU: the physics of `crate::model` (docs/model.md §2–§7) behind the
//! shared FMI glue. This module only connects the two: the variable table, the FMU's identity, and
//! which model call answers which glue call.
//!
//! Outputs are evaluated on demand (docs/fmi-interface.md "Evaluation on demand"): a step or a
//! set input only marks the cache stale, and `fmi2GetReal` evaluates the groups of the outputs it
//! is asked for (kinematics; loads; rod force, friction and reactions), each at most once per
//! communication point. An elastic rod's step integrates the cage equation and evaluates every
//! output at its end, so that a step to a state where the rod cannot be evaluated fails as a step.

pub mod documentation;
pub mod variables;

use serde::{Deserialize, Serialize};

use crate::fmi::model::{FmuModel, GroupedOutput, ModelInfo};
use crate::fmi::variables::Table;
use crate::model::crank::CrankState;
use crate::model::drive::{Inputs, Model, Outputs, RodState, Seed};
use crate::model::error::{num, ModelError};
use crate::model::integrator::IntegratorStats;
use crate::model::params::Params;

pub use variables::{input_vr, input_vrs, value_reference, InputSlot, TABLE, UNITS, VARIABLES};
use variables::{DISCHARGE_PRESSURE_VR, EXTERNAL_FORCE_VR, SUCTION_PRESSURE_VR};

/// The model type the glue is instantiated with (`fmi2::abi::export_fmu!`).
pub struct ReciprocatingDrive;

/// What evolves: the crank as the FMU knows it (the inputs after fmi2SetReal, their extrapolation
/// after a step, docs/model.md §2) and the continuous state of an elastic rod (cage angle and
/// rate) with its integrator's memory.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct State {
    pub crank: CrankState,
    pub rod: RodState,
}

/// |ϑ| above which the linear theory of the elastic rod is no longer valid (docs/model.md §6).
const ROD_ANGLE_VALIDITY: f64 = 0.2;

static INFO: ModelInfo = ModelInfo {
    model_identifier: "ReciprocatingDrive",
    model_name: "ReciprocatingDrive",
    description: "Crank-driven reciprocating mechanism (crank-slider of a drilling mud pump, beam pumping units API class I and III, elastic connecting rod clamped in the piston): exact kinematics, inertia load, guide friction from redundant supports, rod angular oscillation, crank torque",
    default_experiment: (0.0, 3.0, 0.001),
    documentation: documentation::CONVENTIONS,
    input_derivatives_hint: "supply crank.acceleration as an input instead",
};

#[inline]
fn inputs(values: &[f64]) -> Inputs {
    // Constant value references (`variables.rs`), one bounds check for the three.
    let v = &values[..=SUCTION_PRESSURE_VR];
    Inputs {
        external_force: v[EXTERNAL_FORCE_VR],
        discharge_pressure: v[DISCHARGE_PRESSURE_VR],
        suction_pressure: v[SUCTION_PRESSURE_VR],
    }
}

impl FmuModel for ReciprocatingDrive {
    type Params = Params;
    type Built = Model;
    type State = State;
    type Outputs = Outputs;
    type Input = InputSlot;
    type Output = GroupedOutput<Outputs>;
    type Stats = IntegratorStats;

    fn info() -> &'static ModelInfo {
        &INFO
    }

    #[inline]
    fn table() -> &'static Table<Self> {
        &TABLE
    }

    fn fresh_state(values: &[f64]) -> State {
        State {
            crank: CrankState {
                angle: values[input_vr(InputSlot::CrankAngle)],
                speed: values[input_vr(InputSlot::CrankSpeed)],
                acceleration: values[input_vr(InputSlot::CrankAcceleration)],
            },
            rod: RodState::default(),
        }
    }

    #[inline]
    fn input_changed(state: &mut State, input: InputSlot, v: f64) {
        match input {
            InputSlot::CrankAngle => state.crank.angle = v,
            InputSlot::CrankSpeed => state.crank.speed = v,
            InputSlot::CrankAcceleration => state.crank.acceleration = v,
            InputSlot::ExternalForce
            | InputSlot::DischargePressure
            | InputSlot::SuctionPressure => {}
        }
    }

    fn build(params: &Params) -> Result<Model, ModelError> {
        Model::new(params)
    }

    fn initialize(
        model: &Model,
        values: &[f64],
        state: &State,
        out: &mut Outputs,
    ) -> Result<State, ModelError> {
        let rod = model.initial_rod_state(&state.crank, &inputs(values))?;
        model.evaluate_into(&state.crank, &inputs(values), &rod, out)?;
        Ok(State { crank: state.crank, rod })
    }

    /// Lazy: only marks the cache stale; [`Self::prepare`] evaluates what is read.
    #[inline]
    fn update_outputs(
        _: &Model,
        _: &[f64],
        _: &State,
        cache: &mut Outputs,
    ) -> Result<(), ModelError> {
        cache.ready = 0;
        Ok(())
    }

    #[inline]
    fn needs(output: GroupedOutput<Outputs>) -> u8 {
        output.group
    }

    /// The groups of every output of one fmi2GetReal, evaluated in one call.
    #[inline]
    fn prepare(
        model: &Model,
        values: &[f64],
        state: &State,
        cache: &mut Outputs,
        need: u8,
    ) -> Result<(), ModelError> {
        model.evaluate_groups(&state.crank, &inputs(values), &state.rod, cache, need)
    }

    #[inline]
    fn read(cache: &Outputs, output: GroupedOutput<Outputs>) -> Option<f64> {
        (output.group & !cache.ready == 0).then(|| (output.get)(cache))
    }

    /// `prepare` evaluated every group the call's outputs need (`evaluate_groups`).
    #[inline]
    fn read_prepared(cache: &Outputs, output: GroupedOutput<Outputs>) -> f64 {
        debug_assert!(output.group & !cache.ready == 0, "read before its group was evaluated");
        (output.get)(cache)
    }

    /// Advances the crank by the in-step extrapolation of docs/model.md §2 and an elastic rod's
    /// cage state by its integrator, and evaluates every output at the end. The glue steps a rigid
    /// mechanism with [`Self::carry_without_state`] and comes here only when that refuses: a crank
    /// carried forward that overflows, which the evaluation reports naming the input
    /// (`Model::step` leaves a rigid mechanism's rod state alone).
    #[inline]
    fn step(
        model: &Model,
        values: &[f64],
        state: &State,
        h: f64,
        tol: f64,
        stats: &mut IntegratorStats,
        out: &mut Outputs,
    ) -> Result<State, ModelError> {
        let crank = state.crank.extrapolate(h);
        let inputs = inputs(values);
        let rod = model.step(&state.crank, &inputs, &state.rod, h, tol, stats)?;
        model.evaluate_into(&crank, &inputs, &rod, out)?;
        Ok(State { crank, rod })
    }

    /// A rigid rod: the step only carries the crank forward (§2).
    #[inline]
    fn carry_without_state(model: &Model, state: &mut State, h: f64) -> bool {
        if model.has_state() {
            return false;
        }
        let crank = state.crank.extrapolate(h);
        // The inputs were checked when set; the crank carried forward may still overflow.
        if !(crank.angle + crank.speed + crank.acceleration).is_finite() {
            return false;
        }
        state.crank = crank;
        true
    }

    /// Model Exchange: the crank carried forward to the new time with constant acceleration, as a
    /// co-simulation step carries it (docs/model.md §2), so that a crank driven by its speed
    /// alone turns; the inputs the importer sets after fmi2SetTime replace their carried values.
    #[inline]
    fn time_moved(state: &mut State, dt: f64) -> bool {
        let crank = state.crank.extrapolate(dt);
        if !(crank.angle + crank.speed + crank.acceleration).is_finite() {
            return false;
        }
        state.crank = crank;
        true
    }

    /// Model Exchange (FMI 2.0 and 3.0, docs/fmi-interface.md "Model Exchange (FMI 2.0)"): the
    /// two states of the elastic rod's cage (docs/model.md §6), ϑ and ϑ̇, in every machine, so
    /// that their number does not depend on the parameters; a rigid mechanism has no cage and
    /// keeps them at 0 with derivative 0, its outputs functions of the crank inputs evaluated
    /// when read. They are variables of their own: `rod.angle` is ϑ only for an elastic rod.
    const CONTINUOUS_STATES: &'static [(&'static str, &'static str)] =
        &[("rod.cage_angle", "rad/s"), ("rod.cage_rate", "rad/s2")];

    const STATE_VARIABLES: &'static [(&'static str, &'static str, &'static str)] = &[
        (
            "rod.cage_angle",
            "rad",
            "Model Exchange state: rotation theta of the elastic rod's lower cage (equals \
             rod.angle for an elastic rod; 0 for a rigid mechanism, which has no cage)",
        ),
        (
            "rod.cage_rate",
            "rad/s",
            "Model Exchange state: rate of rod.cage_angle (equals rod.angular_velocity for an \
             elastic rod; 0 for a rigid mechanism)",
        ),
    ];

    /// An elastic rod's outputs on its cage (docs/model.md §6): ϑ and ϑ̇ themselves, and everything
    /// downstream of the clamp loads (M0, V depend on ϑ): the rod force through the clamp
    /// friction, the torque, the guide's and supports' loads, the stress and the shortening (the
    /// outputs that depend on `link.external_force`). Listed for every machine (the
    /// `<ModelStructure>` does not depend on the parameters); a rigid mechanism's partials are 0.
    const OUTPUT_STATES: &'static [(&'static str, &'static [usize])] = &[
        ("rod.angle", &[0]),
        ("rod.angular_velocity", &[1]),
        ("rod.force", &[0]),
        ("crank.torque", &[0]),
        ("guide.friction", &[0]),
        ("guide.reaction", &[0]),
        ("guide.moment", &[0]),
        ("guide.edge_force_1", &[0]),
        ("guide.edge_force_2", &[0]),
        ("support_A.reaction", &[0]),
        ("support_C.reaction", &[0]),
        ("link.friction_total", &[0]),
        ("rod.stress_max", &[0]),
        ("rod.axial_deflection", &[0]),
        ("cylinder_1.friction", &[0]),
        ("cylinder_1.rod_force", &[0]),
        ("cylinder_1.crank_torque", &[0]),
        ("crank.mechanical_power", &[0]),
    ];

    /// dϑ/dt = ϑ̇; dϑ̇/dt = ϑ̈ from the cage equation (docs/model.md §6), whose clamp loads
    /// follow the crank's angle, speed and acceleration and the process force, as `rod.force`
    /// does. A rigid mechanism's derivatives are 0: these lists hold for every machine.
    const DERIVATIVE_DEPENDENCIES: &'static [(&'static [InputSlot], &'static [usize])] = &[
        (&[], &[1]),
        (
            &[
                InputSlot::CrankAngle,
                InputSlot::CrankSpeed,
                InputSlot::CrankAcceleration,
                InputSlot::ExternalForce,
                InputSlot::DischargePressure,
                InputSlot::SuctionPressure,
            ],
            &[0, 1],
        ),
    ];

    fn continuous_states(state: &State, x: &mut [f64]) {
        x[0] = state.rod.cage.theta;
        x[1] = state.rod.cage.rate;
    }

    fn set_continuous_states(state: &mut State, x: &[f64]) {
        state.rod.cage.theta = x[0];
        state.rod.cage.rate = x[1];
    }

    /// ϑ̇ and ϑ̈ (`Model::cage_acceleration`); 0 and 0 for a rigid mechanism (inlined into
    /// fmi2GetDerivatives, so that a rigid mechanism's answer costs no call).
    #[inline]
    fn derivatives(
        model: &Model,
        values: &[f64],
        state: &State,
        dx: &mut [f64],
    ) -> Result<(), ModelError> {
        if !model.has_state() {
            dx[0] = 0.0;
            dx[1] = 0.0;
            return Ok(());
        }
        elastic_derivatives(model, values, state, dx)
    }

    /// Exact directional derivatives of the outputs and state derivatives with respect to the
    /// inputs and the cage states (docs/fmi-interface.md "Directional derivatives"), rigid and
    /// elastic rods.
    const DIRECTIONAL_DERIVATIVES: bool = true;

    fn tangent(
        model: &Model,
        values: &[f64],
        state: &State,
        d_values: &[f64],
        d_states: &[f64],
        tangent: &mut Outputs,
        d_derivatives: &mut [f64],
    ) -> Result<(), ModelError> {
        // The cage states are knowns in both interfaces (co-simulation: the state it holds); a
        // rigid mechanism's outputs do not depend on them and its derivatives are 0
        // (`Model::state_tangent`).
        let seed = Seed {
            angle: d_values[input_vr(InputSlot::CrankAngle)],
            speed: d_values[input_vr(InputSlot::CrankSpeed)],
            acceleration: d_values[input_vr(InputSlot::CrankAcceleration)],
            external_force: d_values[input_vr(InputSlot::ExternalForce)],
            discharge_pressure: d_values[input_vr(InputSlot::DischargePressure)],
            suction_pressure: d_values[input_vr(InputSlot::SuctionPressure)],
            cage_angle: d_states.first().copied().unwrap_or(0.0),
            cage_rate: d_states.get(1).copied().unwrap_or(0.0),
        };
        let (_, t, d_acc) =
            model.state_tangent(&state.crank, &inputs(values), &state.rod, &seed)?;
        *tangent = t;
        if d_derivatives.len() >= 2 {
            // der(ϑ) = ϑ̇, der(ϑ̇) = ϑ̈; both 0 for a rigid mechanism (`derivatives`).
            let has = model.has_state();
            d_derivatives[0] = if has { seed.cage_rate } else { 0.0 };
            d_derivatives[1] = if has { d_acc } else { 0.0 };
        }
        Ok(())
    }

    fn default_tolerance(model: &Model) -> f64 {
        model.default_tolerance()
    }

    /// The elastic rod's cage angle left the range of the linear theory (§6 "Validity"): warned
    /// when it starts there and whenever a step crosses the limit.
    fn initial_warning(model: &Model, state: &State) -> Option<String> {
        (model.has_state() && state.rod.cage.theta.abs() > ROD_ANGLE_VALIDITY)
            .then(|| rod_angle_warning(state.rod.cage.theta))
    }

    fn step_warning(model: &Model, before: &State, after: &State) -> Option<String> {
        (model.has_state()
            && after.rod.cage.theta.abs() > ROD_ANGLE_VALIDITY
            && before.rod.cage.theta.abs() <= ROD_ANGLE_VALIDITY)
            .then(|| rod_angle_warning(after.rod.cage.theta))
    }

    fn check_state(state: &State) -> Result<(), &'static str> {
        let r = &state.rod;
        if ![r.cage.theta, r.cage.rate, r.integrator.h_next, r.integrator.err_prev]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err("elastic-rod state");
        }
        Ok(())
    }
}

#[cold]
fn rod_angle_warning(theta: f64) -> String {
    format!(
        "the cage angle rod.angle = {} rad exceeds {} rad: \
         the linear theory of the elastic rod (docs/model.md §6) is no longer valid",
        num(theta),
        num(ROD_ANGLE_VALIDITY)
    )
}

/// The elastic rod's ϑ̇ and ϑ̈ ([`FmuModel::derivatives`] of an elastic machine), out of line so
/// that the rigid branch inlines into fmi2GetDerivatives.
#[inline(never)]
fn elastic_derivatives(
    model: &Model,
    values: &[f64],
    state: &State,
    dx: &mut [f64],
) -> Result<(), ModelError> {
    dx[0] = state.rod.cage.rate;
    dx[1] = model.cage_acceleration(&state.crank, &inputs(values), &state.rod.cage)?;
    Ok(())
}
