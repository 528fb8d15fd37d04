//! FMI 2.0 layer: Model Exchange, in the same shared object as co-simulation (one `.fmu`, one model
//! description with both elements): the ten Model Exchange functions, generic over the model, and
//! the FMI 2.0 Model Exchange state machine on top of the instance core that co-simulation and
//! FMI 3.0 use (docs/fmi-interface.md "Model Exchange (FMI 2.0)").
//!
//! After fmi2ExitInitializationMode the core is in its initialized mode; which of Model
//! Exchange's two modes the instance is in, event mode or continuous-time mode, is
//! [`Instance::me_continuous_time`]. The FMUs have no event indicators and no time events, so the
//! two modes differ only in which calls they allow (FMI 2.0 §3.2.3 state machine). A Model
//! Exchange function on a co-simulation instance, and a co-simulation function on a Model
//! Exchange instance, return fmi2Error with one line naming the function.

#![allow(non_snake_case)]
#![allow(clippy::missing_safety_doc)]

use fmi_sys::fmi2::*;

use crate::fmi::ffi::{null_argument, slice};
use crate::fmi::instance::{Failure, Instance, Mode};
use crate::fmi::model::FmuModel;
use crate::fmi::model_exchange::{
    completed_integrator_step, get_continuous_states, get_derivatives, get_nominals,
    set_continuous_states, set_time, state_value,
};
use crate::fmi::structure::{derivative_vr, own_state};
use crate::fmi::variables::VarType;
use crate::fmi2::abi::{call, Fmi2};

/// Where a Model Exchange function may be called, after initialization.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Allowed {
    /// Event mode only (fmi2NewDiscreteStates, fmi2EnterContinuousTimeMode).
    Event,
    /// Continuous-time mode only (fmi2EnterEventMode, fmi2SetContinuousStates,
    /// fmi2CompletedIntegratorStep).
    ContinuousTime,
    /// Either (fmi2SetTime).
    Both,
    /// Either, and initialization mode (the getters of states, derivatives, nominals and event
    /// indicators: FMI 2.0 allows them there, on the initial values set so far).
    Getter,
}

/// The message of a call a co-simulation instance does not take.
#[cold]
#[inline(never)]
pub fn not_me_instance(function: &str) -> Failure {
    Failure::error(format!(
        "{function}: not an instance for Model Exchange (fmi2Instantiate with fmuType \
         fmi2ModelExchange makes one)"
    ))
}

/// Co-simulation functions refuse a Model Exchange instance: its importer's solver moves time.
pub fn refuse_model_exchange<M: FmuModel>(
    inst: &Instance<M>,
    function: &str,
) -> Result<(), Failure> {
    if inst.model_exchange {
        return Err(Failure::error(format!(
            "{function}: an instance for Model Exchange does not step ({function} is \
             co-simulation's; use fmi2SetTime and fmi2SetContinuousStates)"
        )));
    }
    Ok(())
}

/// Runs a Model Exchange function after checking the instance and its mode.
unsafe fn me<M: FmuModel>(
    c: fmi2Component,
    function: &str,
    allowed: Allowed,
    f: impl FnOnce(&mut Instance<M>) -> Result<(), Failure>,
) -> fmi2Status {
    call::<M>(c, function, |inst| {
        if !inst.model_exchange {
            return Err(not_me_instance(function));
        }
        let initializing = inst.mode() == Mode::InitializationMode && allowed == Allowed::Getter;
        if inst.mode() != Mode::StepComplete && !initializing {
            return Err(Failure::illegal(function, inst.mode()));
        }
        let ct = inst.me_continuous_time;
        match (allowed, ct) {
            (Allowed::Event, true) | (Allowed::ContinuousTime, false) => {
                Err(wrong_me_mode(function, ct))
            }
            _ => f(inst),
        }
    })
}

/// The refusal of a call in the other of Model Exchange's two modes (out of line: the checks
/// run at every evaluation of a solver, the message almost never).
#[cold]
#[inline(never)]
fn wrong_me_mode(function: &str, continuous_time: bool) -> Failure {
    Failure::error(if continuous_time {
        format!(
            "{function}: illegal call sequence: not allowed in continuous-time mode, only in \
             event mode (fmi2EnterEventMode enters it)"
        )
    } else {
        format!(
            "{function}: illegal call sequence: not allowed in event mode, only in \
             continuous-time mode (fmi2EnterContinuousTimeMode enters it)"
        )
    })
}

/// fmi2ExitInitializationMode of a Model Exchange instance: the core's, then the model's refusal
/// of a machine it cannot offer as Model Exchange (the instance then stays in initialization
/// mode, as after any failed fmi2ExitInitializationMode); on success the instance is in event
/// mode (FMI 2.0 §3.2.3).
pub fn exit_initialization_mode<M: FmuModel>(inst: &mut Instance<M>) -> Result<(), Failure> {
    crate::fmi::model_exchange::exit_initialization_mode(inst, "fmi2ExitInitializationMode")?;
    inst.me_continuous_time = false;
    Ok(())
}

/// fmi2GetReal of a list that names a state derivative (`der(...)`) or a state's own variable
/// ([`FmuModel::STATE_VARIABLES`]), which are not in the table: each value read on its own,
/// those from the model (`crate::fmi::model_exchange::state_value`). None: the list names none
/// (the ordinary fmi2GetReal answers).
pub unsafe fn get_real_with_derivatives<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Real,
) -> Option<fmi2Status> {
    let n = M::CONTINUOUS_STATES.len();
    if n == 0 || c.is_null() || value.is_null() {
        return None;
    }
    let vrs = slice(vr, nvr)?;
    let first = derivative_vr::<M>(0);
    let is_der = |r: u32| r >= first && r < first + n as u32;
    let own = |r: u32| {
        let k = r.wrapping_sub(first + n as u32) as usize;
        k < n && own_state::<M>(k).is_some()
    };
    if !vrs.iter().any(|&r| is_der(r) || own(r)) {
        return None;
    }
    let f = "fmi2GetReal";
    Some(call::<M>(c, f, |inst| {
        let mut dx = None;
        for (k, &r) in vrs.iter().enumerate() {
            *value.add(k) = match state_value::<Fmi2, M>(inst, f, r, &mut dx)? {
                Some(v) => v,
                None => {
                    let mut x = f64::NAN;
                    inst.get(f, VarType::Real, &[r], |_, v| x = v)?;
                    x
                }
            };
        }
        Ok(())
    }))
}

pub unsafe fn fmi2EnterEventMode<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    enter_mode::<M>(c, "fmi2EnterEventMode", Allowed::ContinuousTime, false)
}

/// Enters event mode or continuous-time mode (`continuous_time`) from the other.
unsafe fn enter_mode<M: FmuModel>(
    c: fmi2Component,
    function: &str,
    from: Allowed,
    continuous_time: bool,
) -> fmi2Status {
    me::<M>(c, function, from, |inst| {
        inst.me_continuous_time = continuous_time;
        Ok(())
    })
}

/// No discrete states, no events, no time events: nothing to update (docs/fmi-interface.md).
pub unsafe fn fmi2NewDiscreteStates<M: FmuModel>(
    c: fmi2Component,
    eventInfo: *mut fmi2EventInfo,
) -> fmi2Status {
    me::<M>(c, "fmi2NewDiscreteStates", Allowed::Event, |_| {
        if eventInfo.is_null() {
            return Err(null_argument("fmi2NewDiscreteStates", "fmi2EventInfo"));
        }
        *eventInfo = fmi2EventInfo::default();
        Ok(())
    })
}

pub unsafe fn fmi2EnterContinuousTimeMode<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    enter_mode::<M>(c, "fmi2EnterContinuousTimeMode", Allowed::Event, true)
}

pub unsafe fn fmi2CompletedIntegratorStep<M: FmuModel>(
    c: fmi2Component,
    _noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
    enterEventMode: *mut fmi2Boolean,
    terminateSimulation: *mut fmi2Boolean,
) -> fmi2Status {
    let f = "fmi2CompletedIntegratorStep";
    me::<M>(c, f, Allowed::ContinuousTime, |_| {
        completed_integrator_step(f, enterEventMode, terminateSimulation)
    })
}

pub unsafe fn fmi2SetTime<M: FmuModel>(c: fmi2Component, time: fmi2Real) -> fmi2Status {
    me::<M>(c, "fmi2SetTime", Allowed::Both, |inst| set_time(inst, "fmi2SetTime", time))
}

pub unsafe fn fmi2SetContinuousStates<M: FmuModel>(
    c: fmi2Component,
    x: *const fmi2Real,
    nx: usize,
) -> fmi2Status {
    let f = "fmi2SetContinuousStates";
    me::<M>(c, f, Allowed::ContinuousTime, |inst| set_continuous_states::<Fmi2, M>(inst, f, x, nx))
}

pub unsafe fn fmi2GetDerivatives<M: FmuModel>(
    c: fmi2Component,
    derivatives: *mut fmi2Real,
    nx: usize,
) -> fmi2Status {
    let f = "fmi2GetDerivatives";
    me::<M>(c, f, Allowed::Getter, |inst| get_derivatives::<Fmi2, M>(inst, f, derivatives, nx))
}

/// No event indicators: the drive train's torque curve and load, and the pump's outputs as
/// functions of the crank inputs and cage states, are smooth (docs/fmi-interface.md).
pub unsafe fn fmi2GetEventIndicators<M: FmuModel>(
    c: fmi2Component,
    _indicators: *mut fmi2Real,
    ni: usize,
) -> fmi2Status {
    me::<M>(c, "fmi2GetEventIndicators", Allowed::Getter, |_| {
        if ni != 0 {
            return Err(Failure::error(format!(
                "fmi2GetEventIndicators: ni = {ni}; this FMU has no event indicators \
                 (numberOfEventIndicators=\"0\")"
            )));
        }
        Ok(())
    })
}

pub unsafe fn fmi2GetContinuousStates<M: FmuModel>(
    c: fmi2Component,
    x: *mut fmi2Real,
    nx: usize,
) -> fmi2Status {
    let f = "fmi2GetContinuousStates";
    me::<M>(c, f, Allowed::Getter, |inst| get_continuous_states::<Fmi2, M>(inst, f, x, nx))
}

pub unsafe fn fmi2GetNominalsOfContinuousStates<M: FmuModel>(
    c: fmi2Component,
    nominals: *mut fmi2Real,
    nx: usize,
) -> fmi2Status {
    let f = "fmi2GetNominalsOfContinuousStates";
    me::<M>(c, f, Allowed::Getter, |_| get_nominals::<Fmi2, M>(f, nominals, nx))
}

/// Exports the ten FMI 2.0 Model Exchange functions for one model (called by
/// [`export_fmu!`](crate::export_fmu)), their types checked against the FMI 2.0 headers.
#[macro_export]
macro_rules! export_fmu2_model_exchange {
    ($model:ty) => {
        const _: () = {
            use $crate::fmi2::model_exchange as glue;
            use $crate::fmi_sys::fmi2::*;
            type M = $model;
            type C = fmi2Component;
            type S = fmi2Status;

            $crate::__fmi_exports! {
                fmi2EnterEventMode: fmi2EnterEventModeTYPE(c: C) -> S;
                fmi2NewDiscreteStates: fmi2NewDiscreteStatesTYPE(c: C, eventInfo: *mut fmi2EventInfo) -> S;
                fmi2EnterContinuousTimeMode: fmi2EnterContinuousTimeModeTYPE(c: C) -> S;
                fmi2CompletedIntegratorStep: fmi2CompletedIntegratorStepTYPE(c: C, noSetFMUStatePriorToCurrentPoint: fmi2Boolean, enterEventMode: *mut fmi2Boolean, terminateSimulation: *mut fmi2Boolean) -> S;
                fmi2SetTime: fmi2SetTimeTYPE(c: C, time: fmi2Real) -> S;
                fmi2SetContinuousStates: fmi2SetContinuousStatesTYPE(c: C, x: *const fmi2Real, nx: usize) -> S;
                fmi2GetDerivatives: fmi2GetDerivativesTYPE(c: C, derivatives: *mut fmi2Real, nx: usize) -> S;
                fmi2GetEventIndicators: fmi2GetEventIndicatorsTYPE(c: C, eventIndicators: *mut fmi2Real, ni: usize) -> S;
                fmi2GetContinuousStates: fmi2GetContinuousStatesTYPE(c: C, x: *mut fmi2Real, nx: usize) -> S;
                fmi2GetNominalsOfContinuousStates: fmi2GetNominalsOfContinuousStatesTYPE(c: C, x_nominal: *mut fmi2Real, nx: usize) -> S;
            }
        };
    };
}
