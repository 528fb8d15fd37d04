//! Core layer: Model Exchange evaluation shared by both standards' Model Exchange functions
//! (docs/fmi-interface.md "Model Exchange (FMI 2.0)", "FMI 3.0"): moving the time of an instance
//! and what the model carries forward to it, the continuous states and their derivatives read
//! and set with their checks, and the values of the variables that are not in the table (the
//! state derivatives, a state's own variable; `crate::fmi::structure`). Each standard's C ABI
//! checks its own state machine first and names its arguments ([`Dialect`]).

use crate::fmi::ffi::{null_argument, out_slice, slice, Dialect};
use crate::fmi::instance::{Failure, Instance};
use crate::fmi::model::FmuModel;
use crate::fmi::structure::{derivative_vr, own_state};

/// fmi2ExitInitializationMode and fmi3ExitInitializationMode (`function`) of a Model Exchange
/// instance: the core's, then the model's refusal of a machine it cannot offer as Model Exchange;
/// a failed call leaves the instance as it was (in initialization mode, with its values).
pub(crate) fn exit_initialization_mode<M: FmuModel>(
    inst: &mut Instance<M>,
    function: &str,
) -> Result<(), Failure> {
    let before = inst.snapshot();
    inst.exit_initialization_mode()?;
    let refusal = inst.me_parts().and_then(|(built, _, _)| M::model_exchange_refusal(built));
    if let Some(why) = refusal {
        inst.restore(&before)?;
        return Err(Failure::error(format!("{function}: {why}")));
    }
    Ok(())
}

/// The number of states the importer passes must be the model's.
#[inline]
fn state_count<D: Dialect, M: FmuModel>(function: &str, nx: usize) -> Result<(), Failure> {
    let n = M::CONTINUOUS_STATES.len();
    if n != nx {
        return Err(wrong_state_count(function, D::NX, nx, n));
    }
    Ok(())
}

#[cold]
#[inline(never)]
fn wrong_state_count(function: &str, what: &str, nx: usize, n: usize) -> Failure {
    Failure::error(format!("{function}: {what} = {nx}; this FMU has {n} continuous states"))
}

#[cold]
#[inline(never)]
fn state_not_finite(function: &str, name: &str, x: f64) -> Failure {
    Failure::error(format!("{function}: {name} = {x}; allowed: a finite number"))
}

/// fmi2SetContinuousStates, fmi3SetContinuousStates: finite values only.
#[inline(always)]
pub(crate) unsafe fn set_continuous_states<D: Dialect, M: FmuModel>(
    inst: &mut Instance<M>,
    f: &str,
    x: *const f64,
    nx: usize,
) -> Result<(), Failure> {
    state_count::<D, M>(f, nx)?;
    let x = slice(x, nx).ok_or_else(|| null_argument(f, D::STATES))?;
    if let Some(k) = x.iter().position(|v| !v.is_finite()) {
        return Err(state_not_finite(f, M::CONTINUOUS_STATES[k].0, x[k]));
    }
    inst.me_update(|_, state| M::set_continuous_states(state, x));
    Ok(())
}

/// fmi2GetDerivatives, fmi3GetContinuousStateDerivatives (also in initialization mode, on the
/// initial values set so far).
#[inline(always)]
pub(crate) unsafe fn get_derivatives<D: Dialect, M: FmuModel>(
    inst: &mut Instance<M>,
    f: &str,
    derivatives: *mut f64,
    nx: usize,
) -> Result<(), Failure> {
    state_count::<D, M>(f, nx)?;
    let dx = out_slice(f, "derivatives", derivatives, nx)?;
    let mode = inst.mode();
    let (built, values, state) =
        inst.me_parts_initial()?.ok_or_else(|| Failure::illegal(f, mode))?;
    M::derivatives(built, values, state, dx)?;
    Ok(())
}

/// fmi2GetContinuousStates, fmi3GetContinuousStates.
pub(crate) unsafe fn get_continuous_states<D: Dialect, M: FmuModel>(
    inst: &mut Instance<M>,
    f: &str,
    x: *mut f64,
    nx: usize,
) -> Result<(), Failure> {
    state_count::<D, M>(f, nx)?;
    let out = out_slice(f, D::STATES, x, nx)?;
    let mode = inst.mode();
    let (_, _, state) = inst.me_parts_initial()?.ok_or_else(|| Failure::illegal(f, mode))?;
    M::continuous_states(state, out);
    Ok(())
}

/// fmi2GetNominalsOfContinuousStates, fmi3GetNominalsOfContinuousStates: 1 for every state.
pub(crate) unsafe fn get_nominals<D: Dialect, M: FmuModel>(
    f: &str,
    nominals: *mut f64,
    nx: usize,
) -> Result<(), Failure> {
    state_count::<D, M>(f, nx)?;
    out_slice(f, D::NOMINALS, nominals, nx)?.fill(1.0);
    Ok(())
}

/// The value of `vr` if it is the derivative of a continuous state or a state's own variable
/// ([`FmuModel::STATE_VARIABLES`]), which are not in the table: from the model (also in
/// initialization mode, on the initial values set so far); the derivatives evaluated once per
/// call of the importer (`dx`). None: `vr` is neither.
pub(crate) fn state_value<D: Dialect, M: FmuModel>(
    inst: &mut Instance<M>,
    f: &str,
    vr: u32,
    dx: &mut Option<Vec<f64>>,
) -> Result<Option<f64>, Failure> {
    let n = M::CONTINUOUS_STATES.len();
    let first = derivative_vr::<M>(0);
    let k = vr.wrapping_sub(first) as usize;
    let enter = D::ENTER_INITIALIZATION;
    if k < n {
        if dx.is_none() {
            let (built, values, state) = inst.me_parts_initial()?.ok_or_else(|| {
                Failure::error(format!(
                    "{f}: der({}) is not available before {enter}",
                    M::CONTINUOUS_STATES[k].0
                ))
            })?;
            let mut d = vec![0.0; n];
            M::derivatives(built, values, state, &mut d)?;
            *dx = Some(d);
        }
        return Ok(dx.as_ref().map(|d| d[k]));
    }
    let j = k.wrapping_sub(n);
    if j < n && own_state::<M>(j).is_some() {
        let (_, _, state) = inst.me_parts_initial()?.ok_or_else(|| {
            Failure::error(format!(
                "{f}: {} is not available before {enter}",
                M::CONTINUOUS_STATES[j].0
            ))
        })?;
        let mut x = vec![0.0; n];
        M::continuous_states(state, &mut x);
        return Ok(Some(x[j]));
    }
    Ok(None)
}

/// fmi2SetTime and fmi3SetTime: the new time, and what the model carries forward to it
/// ([`FmuModel::time_moved`]: the pump's crank, as between co-simulation steps). Inlined into
/// both callers, its refusals out of line (cold): a solver calls it at every evaluation.
#[inline(always)]
pub fn set_time<M: FmuModel>(
    inst: &mut Instance<M>,
    function: &str,
    time: f64,
) -> Result<(), Failure> {
    if !time.is_finite() {
        return Err(time_not_finite(function, time));
    }
    let from = inst.time();
    let mut carried = true;
    inst.me_update(|t, state| {
        carried = M::time_moved(state, time - *t);
        if carried {
            *t = time;
        }
    });
    if !carried {
        return Err(carry_overflows(function, time, from));
    }
    Ok(())
}

#[cold]
#[inline(never)]
fn time_not_finite(function: &str, time: f64) -> Failure {
    Failure::error(format!("{function}: time = {time}; allowed: a finite number"))
}

#[cold]
#[inline(never)]
fn carry_overflows(function: &str, time: f64, from: f64) -> Failure {
    Failure::error(format!(
        "{function}: time = {}: the crank inputs carried forward from t = {} overflow there; set \
         them at the new time",
        crate::model::error::given(time),
        crate::model::error::num(from)
    ))
}

/// fmi2CompletedIntegratorStep, fmi3CompletedIntegratorStep: no event to enter, no reason to
/// stop (no event indicators, no time events).
pub(crate) unsafe fn completed_integrator_step<T: From<bool>>(
    f: &str,
    enter_event_mode: *mut T,
    terminate_simulation: *mut T,
) -> Result<(), Failure> {
    if enter_event_mode.is_null() || terminate_simulation.is_null() {
        return Err(null_argument(f, "enterEventMode or terminateSimulation"));
    }
    *enter_event_mode = T::from(false);
    *terminate_simulation = T::from(false);
    Ok(())
}
