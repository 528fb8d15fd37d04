//! Every FMI 2.0 common and co-simulation function (34), generic over the model.
//!
//! Each function checks its pointers, catches panics (no unwinding crosses the C boundary),
//! delegates to [`Instance`] and turns a [`Failure`] into its status plus one log line naming the
//! function. [`export_fmu!`](crate::export_fmu) instantiates them for one model as the 34
//! `#[no_mangle] extern "C"` functions of that FMU's shared object (one cdylib per FMU, each with
//! its own exports and GUID); their signatures are checked at compile time against the types
//! bindgen generated from the official FMI 2.0 headers.

#![allow(non_snake_case)]
#![allow(clippy::missing_safety_doc)]

use std::ffi::{c_char, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr;

use fmi_sys::fmi2::*;

use crate::fmi::ffi::{null_argument, opt_str, slice, snapshot_ref, store_snapshot};
use crate::fmi::fmu_state;
use crate::fmi::handle::{free_instance, live, new_handle, report_freed};
use crate::fmi::instance::{copy_name, snapshot_magic, Failure, Instance, Severity, Snapshot};
use crate::fmi::logging::{Category, Logger};
use crate::fmi::model::FmuModel;
use crate::fmi::resources::resource_dir;
use crate::fmi::variables::VarType;
use crate::fmi2::model_description::guid;
use crate::fmi2::model_exchange;

static TYPES_PLATFORM: &CStr = c"default";
static VERSION: &CStr = c"2.0";

fn status_of(s: Severity) -> fmi2Status {
    match s {
        Severity::Discard => fmi2Status_fmi2Discard,
        Severity::Error => fmi2Status_fmi2Error,
        Severity::Fatal => fmi2Status_fmi2Fatal,
    }
}

/// Runs `f` on the instance behind `c`: NULL and freed-instance check (`crate::fmi::handle`),
/// panic barrier, status and logging.
pub(crate) unsafe fn call<M: FmuModel>(
    c: fmi2Component,
    function: &str,
    f: impl FnOnce(&mut Instance<M>) -> Result<(), Failure>,
) -> fmi2Status {
    let Some(inst) = live::<M>(c) else {
        if !c.is_null() {
            report_freed::<M>(c, function);
        }
        return fmi2Status_fmi2Error;
    };
    match catch_unwind(AssertUnwindSafe(|| f(&mut *inst))) {
        Ok(Ok(())) => {
            (*inst).log(fmi2Status_fmi2OK, Category::Calls, function);
            fmi2Status_fmi2OK
        }
        Ok(Err(failure)) => failed(inst, function, failure),
        Err(_) => panicked(inst, function),
    }
}

/// `function` refused or failed: its status, and its message to the logger. Out of line (cold):
/// the successful path of every call stays short (docs/performance.md "Model Exchange").
#[cold]
#[inline(never)]
unsafe fn failed<M: FmuModel>(
    inst: *mut Instance<M>,
    function: &str,
    failure: Failure,
) -> fmi2Status {
    let status = status_of(failure.severity);
    let category =
        if failure.severity == Severity::Discard { Category::Warning } else { Category::Error };
    // Every message names the function that failed.
    if failure.message.starts_with(function) {
        (*inst).log(status, category, &failure.message);
    } else {
        (*inst).log(status, category, &format!("{function}: {}", failure.message));
    }
    status
}

/// A panic was caught in `function`: it left the instance in an unknown state, which must not be
/// used any more.
#[cold]
#[inline(never)]
unsafe fn panicked<M: FmuModel>(inst: *mut Instance<M>, function: &str) -> fmi2Status {
    let _ = catch_unwind(AssertUnwindSafe(|| {
        (*inst).set_fatal();
        (*inst).log(
            fmi2Status_fmi2Fatal,
            Category::Error,
            &format!("{function}: internal error (panic caught)"),
        );
    }));
    fmi2Status_fmi2Fatal
}

// ------------------------------------------------------------------------------ common functions

#[inline]
pub fn fmi2GetTypesPlatform() -> *const c_char {
    TYPES_PLATFORM.as_ptr()
}

#[inline]
pub fn fmi2GetVersion() -> *const c_char {
    VERSION.as_ptr()
}

#[inline]
pub unsafe fn fmi2SetDebugLogging<M: FmuModel>(
    c: fmi2Component,
    loggingOn: fmi2Boolean,
    nCategories: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    call::<M>(c, "fmi2SetDebugLogging", |inst| {
        let cats = slice(categories, nCategories)
            .ok_or_else(|| null_argument("fmi2SetDebugLogging", "categories"))?;
        let mut names = Vec::with_capacity(cats.len());
        for &p in cats {
            names.push(
                opt_str(p)
                    .ok_or_else(|| null_argument("fmi2SetDebugLogging", "a category name"))?,
            );
        }
        inst.logger
            .set_debug_logging(loggingOn != 0, &names)
            .map_err(|e| Failure::error(format!("fmi2SetDebugLogging: {e}")))
    })
}

#[inline]
pub unsafe fn fmi2Instantiate<M: FmuModel>(
    instanceName: fmi2String,
    fmuType: fmi2Type,
    fmuGUID: fmi2String,
    fmuResourceLocation: fmi2String,
    functions: *const fmi2CallbackFunctions,
    _visible: fmi2Boolean,
    loggingOn: fmi2Boolean,
) -> fmi2Component {
    let result = catch_unwind(AssertUnwindSafe(|| {
        if functions.is_null() {
            return ptr::null_mut();
        }
        let cb = &*functions;
        let name = opt_str(instanceName).unwrap_or("");
        let logger =
            Logger::new(cb.logger, cb.componentEnvironment, copy_name(name), loggingOn != 0);
        let refuse = |why: String| {
            logger.log(fmi2Status_fmi2Error, Category::Error, &format!("fmi2Instantiate: {why}"));
            ptr::null_mut()
        };
        if name.is_empty() {
            return refuse("instanceName is NULL or empty".into());
        }
        // Model Exchange beside co-simulation (docs/fmi-interface.md "Model Exchange (FMI 2.0)").
        let model_exchange = fmuType == fmi2Type_fmi2ModelExchange && M::MODEL_EXCHANGE;
        if fmuType != fmi2Type_fmi2CoSimulation && !model_exchange {
            return refuse(format!(
                "fmuType {fmuType} is not supported: allowed: {} ({})",
                fmi2Type_fmi2CoSimulation,
                if M::MODEL_EXCHANGE {
                    "fmi2CoSimulation) or 0 (fmi2ModelExchange"
                } else {
                    "fmi2CoSimulation; this FMU has no Model Exchange"
                }
            ));
        }
        match opt_str(fmuGUID) {
            Some(g) if g == guid::<M>() => {}
            other => {
                return refuse(format!(
                    "GUID {:?} is not this FMU's GUID {}",
                    other.unwrap_or("NULL"),
                    guid::<M>()
                ))
            }
        }
        let location = opt_str(fmuResourceLocation);
        let dir = resource_dir(location);
        let mut inst = Box::new(Instance::<M>::new(logger, dir));
        inst.model_exchange = model_exchange;
        inst.log(
            fmi2Status_fmi2OK,
            Category::Events,
            &format!("instantiated; resources: {:?}", inst.resource_dir),
        );
        new_handle(inst)
    }));
    result.unwrap_or(ptr::null_mut())
}

/// Frees the instance and keeps its handle (`crate::fmi::handle`): a second call is reported
/// and does nothing.
#[inline]
pub unsafe fn fmi2FreeInstance<M: FmuModel>(c: fmi2Component) {
    free_instance::<M>(c, "fmi2FreeInstance")
}

#[inline]
pub unsafe fn fmi2SetupExperiment<M: FmuModel>(
    c: fmi2Component,
    toleranceDefined: fmi2Boolean,
    tolerance: fmi2Real,
    startTime: fmi2Real,
    stopTimeDefined: fmi2Boolean,
    stopTime: fmi2Real,
) -> fmi2Status {
    call::<M>(c, "fmi2SetupExperiment", |inst| {
        inst.setup_experiment(
            (toleranceDefined != 0).then_some(tolerance),
            startTime,
            (stopTimeDefined != 0).then_some(stopTime),
        )
    })
}

#[inline]
pub unsafe fn fmi2EnterInitializationMode<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    call::<M>(c, "fmi2EnterInitializationMode", |inst| inst.enter_initialization_mode())
}

#[inline]
pub unsafe fn fmi2ExitInitializationMode<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    call::<M>(c, "fmi2ExitInitializationMode", |inst| {
        if inst.model_exchange {
            return model_exchange::exit_initialization_mode(inst);
        }
        inst.exit_initialization_mode()
    })
}

#[inline]
pub unsafe fn fmi2Terminate<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    call::<M>(c, "fmi2Terminate", |inst| inst.terminate())
}

#[inline]
pub unsafe fn fmi2Reset<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    call::<M>(c, "fmi2Reset", |inst| inst.reset())
}

/// fmi2GetReal/Integer/Boolean's general path; out of line so that fmi2GetReal's fast path sets
/// up no stack frame for it (its messages need kilobytes).
#[inline(never)]
unsafe fn get_values<M: FmuModel, T: Copy>(
    c: fmi2Component,
    function: &'static str,
    ty: VarType,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut T,
    convert: impl Fn(f64) -> T,
) -> fmi2Status {
    call::<M>(c, function, |inst| {
        let vrs = slice(vr, nvr).ok_or_else(|| null_argument(function, "vr"))?;
        if nvr > 0 && value.is_null() {
            return Err(null_argument(function, "value"));
        }
        inst.get(function, ty, vrs, |k, v| *value.add(k) = convert(v))
    })
}

/// fmi2SetReal/Integer/Boolean's general path; out of line so that fmi2SetReal's fast path sets
/// up no stack frame for it (its messages need kilobytes).
#[inline(never)]
unsafe fn set_values<M: FmuModel, T: Copy>(
    c: fmi2Component,
    function: &'static str,
    ty: VarType,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const T,
    convert: impl Fn(T) -> f64,
) -> fmi2Status {
    call::<M>(c, function, |inst| {
        let vrs = slice(vr, nvr).ok_or_else(|| null_argument(function, "vr"))?;
        let vals = slice(value, nvr).ok_or_else(|| null_argument(function, "value"))?;
        inst.set(function, ty, vrs, |k| convert(vals[k]))
    })
}

#[inline]
pub unsafe fn fmi2GetReal<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Real,
) -> fmi2Status {
    // Outputs read at every step take the fast path (`Instance::quick_get_real`), still behind
    // the panic barrier: it evaluates the model. Anything that needs a message takes the general
    // path, which evaluates again and reports.
    if let Some(inst) = live::<M>(c) {
        if let (Some(vrs), false) = (slice(vr, nvr), nvr > 0 && value.is_null()) {
            let out: &mut [fmi2Real] =
                if nvr == 0 { &mut [] } else { std::slice::from_raw_parts_mut(value, nvr) };
            match catch_unwind(AssertUnwindSafe(|| (*inst).quick_get_real(vrs, out))) {
                Ok(true) => return fmi2Status_fmi2OK,
                Ok(false) => {}
                Err(_) => return panicked(inst, "fmi2GetReal"),
            }
        }
    }
    // Model Exchange: the state derivatives are not in the table.
    if let Some(status) = model_exchange::get_real_with_derivatives::<M>(c, vr, nvr, value) {
        return status;
    }
    get_values::<M, _>(c, "fmi2GetReal", VarType::Real, vr, nvr, value, |v| v)
}

#[inline]
pub unsafe fn fmi2GetInteger<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Integer,
) -> fmi2Status {
    get_values::<M, _>(c, "fmi2GetInteger", VarType::Integer, vr, nvr, value, |v| v as fmi2Integer)
}

#[inline]
pub unsafe fn fmi2GetBoolean<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    get_values::<M, _>(c, "fmi2GetBoolean", VarType::Boolean, vr, nvr, value, |v| {
        (v != 0.0) as fmi2Boolean
    })
}

#[inline]
pub unsafe fn fmi2GetString<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *mut fmi2String,
) -> fmi2Status {
    call::<M>(c, "fmi2GetString", |_| no_strings("fmi2GetString", vr, nvr))
}

#[inline]
pub unsafe fn fmi2SetReal<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Real,
) -> fmi2Status {
    // Finite crank inputs at every step cannot panic (proved at link time,
    // `Instance::quick_set_real`) and need no barrier; anything else takes the general path.
    if let Some(inst) = live::<M>(c) {
        if let (Some(vrs), Some(vals)) = (slice(vr, nvr), slice(value, nvr)) {
            if (*inst).quick_set_real::<2>(vrs, vals) {
                return fmi2Status_fmi2OK;
            }
        }
    }
    set_values::<M, _>(c, "fmi2SetReal", VarType::Real, vr, nvr, value, |v| v)
}

#[inline]
pub unsafe fn fmi2SetInteger<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Integer,
) -> fmi2Status {
    set_values::<M, _>(c, "fmi2SetInteger", VarType::Integer, vr, nvr, value, |v| v as f64)
}

#[inline]
pub unsafe fn fmi2SetBoolean<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Boolean,
) -> fmi2Status {
    set_values::<M, _>(c, "fmi2SetBoolean", VarType::Boolean, vr, nvr, value, |v| {
        (v != 0) as i32 as f64
    })
}

#[inline]
pub unsafe fn fmi2SetString<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *const fmi2String,
) -> fmi2Status {
    call::<M>(c, "fmi2SetString", |_| no_strings("fmi2SetString", vr, nvr))
}

unsafe fn no_strings(
    function: &str,
    vr: *const fmi2ValueReference,
    nvr: usize,
) -> Result<(), Failure> {
    match slice(vr, nvr) {
        Some([]) => Ok(()),
        Some(v) => Err(Failure::error(format!(
            "{function}: value reference {} is not a String variable (this FMU has none)",
            v[0]
        ))),
        None => Err(null_argument(function, "vr")),
    }
}

// ------------------------------------------------------------------------------ FMU state

#[inline]
pub unsafe fn fmi2GetFMUstate<M: FmuModel>(
    c: fmi2Component,
    state: *mut fmi2FMUstate,
) -> fmi2Status {
    call::<M>(c, "fmi2GetFMUstate", |inst| {
        if state.is_null() {
            return Err(null_argument("fmi2GetFMUstate", "FMUstate"));
        }
        let snap = inst.snapshot();
        store_snapshot(inst, state, snap);
        Ok(())
    })
}

#[inline]
pub unsafe fn fmi2SetFMUstate<M: FmuModel>(c: fmi2Component, state: fmi2FMUstate) -> fmi2Status {
    call::<M>(c, "fmi2SetFMUstate", |inst| {
        inst.restore(snapshot_ref::<M>("fmi2SetFMUstate", state)?)
    })
}

#[inline]
pub unsafe fn fmi2FreeFMUstate<M: FmuModel>(
    c: fmi2Component,
    state: *mut fmi2FMUstate,
) -> fmi2Status {
    call::<M>(c, "fmi2FreeFMUstate", |inst| {
        if state.is_null() || (*state).is_null() {
            return Ok(());
        }
        let s = *state as *mut Snapshot<M>;
        let Some(pos) = inst.states.iter().position(|&p| p == s as usize) else {
            return Err(Failure::error(
                "fmi2FreeFMUstate: FMUstate was not made by this instance (or was freed)",
            ));
        };
        if (*s).magic != snapshot_magic::<M>() {
            return Err(Failure::error("fmi2FreeFMUstate: FMUstate was not made by this FMU"));
        }
        inst.states.swap_remove(pos);
        (*s).magic = 0;
        drop(Box::from_raw(s));
        *state = ptr::null_mut();
        Ok(())
    })
}

#[inline]
pub unsafe fn fmi2SerializedFMUstateSize<M: FmuModel>(
    c: fmi2Component,
    state: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    call::<M>(c, "fmi2SerializedFMUstateSize", |_| {
        let snap = snapshot_ref::<M>("fmi2SerializedFMUstateSize", state)?;
        if size.is_null() {
            return Err(null_argument("fmi2SerializedFMUstateSize", "size"));
        }
        *size = fmu_state::serialize::<M>(&snap.core)?.len();
        Ok(())
    })
}

#[inline]
pub unsafe fn fmi2SerializeFMUstate<M: FmuModel>(
    c: fmi2Component,
    state: fmi2FMUstate,
    bytes: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    call::<M>(c, "fmi2SerializeFMUstate", |_| {
        let snap = snapshot_ref::<M>("fmi2SerializeFMUstate", state)?;
        let data = fmu_state::serialize::<M>(&snap.core)?;
        if bytes.is_null() || size < data.len() {
            return Err(Failure::error(format!(
                "fmi2SerializeFMUstate: buffer of {size} bytes is too small; {} needed",
                data.len()
            )));
        }
        ptr::copy_nonoverlapping(data.as_ptr(), bytes as *mut u8, data.len());
        Ok(())
    })
}

#[inline]
pub unsafe fn fmi2DeSerializeFMUstate<M: FmuModel>(
    c: fmi2Component,
    bytes: *const fmi2Byte,
    size: usize,
    state: *mut fmi2FMUstate,
) -> fmi2Status {
    call::<M>(c, "fmi2DeSerializeFMUstate", |inst| {
        let data = slice(bytes as *const u8, size)
            .ok_or_else(|| null_argument("fmi2DeSerializeFMUstate", "serializedState"))?;
        if state.is_null() {
            return Err(null_argument("fmi2DeSerializeFMUstate", "FMUstate"));
        }
        let snap = Instance::<M>::snapshot_from_core(fmu_state::deserialize::<M>(data)?)?;
        store_snapshot(inst, state, snap);
        Ok(())
    })
}

#[inline]
pub unsafe fn fmi2GetDirectionalDerivative<M: FmuModel>(
    c: fmi2Component,
    vUnknown_ref: *const fmi2ValueReference,
    nUnknown: usize,
    vKnown_ref: *const fmi2ValueReference,
    nKnown: usize,
    dvKnown: *const fmi2Real,
    dvUnknown: *mut fmi2Real,
) -> fmi2Status {
    fmi2_directional_derivative::<M>(
        c,
        vUnknown_ref,
        nUnknown,
        vKnown_ref,
        nKnown,
        dvKnown,
        dvUnknown,
        &crate::fmi::directional::model_exchange_refs::<M>(),
    )
}

/// `fmi2GetDirectionalDerivative` with the value references of the continuous states and their
/// derivatives of a Model Exchange instance (`refs`, used by a Model Exchange instance only), every
/// argument checked, inside the panic barrier (`crate::fmi::directional`).
#[allow(clippy::too_many_arguments)]
pub unsafe fn fmi2_directional_derivative<M: FmuModel>(
    c: fmi2Component,
    vUnknown_ref: *const fmi2ValueReference,
    nUnknown: usize,
    vKnown_ref: *const fmi2ValueReference,
    nKnown: usize,
    dvKnown: *const fmi2Real,
    dvUnknown: *mut fmi2Real,
    refs: &crate::fmi::directional::StateRefs,
) -> fmi2Status {
    let f = "fmi2GetDirectionalDerivative";
    call::<M>(c, f, |inst| {
        let unknowns =
            slice(vUnknown_ref, nUnknown).ok_or_else(|| null_argument(f, "vUnknown_ref"))?;
        let knowns = slice(vKnown_ref, nKnown).ok_or_else(|| null_argument(f, "vKnown_ref"))?;
        let seed = slice(dvKnown, nKnown).ok_or_else(|| null_argument(f, "dvKnown"))?;
        if nUnknown > 0 && dvUnknown.is_null() {
            return Err(null_argument(f, "dvUnknown"));
        }
        let out: &mut [fmi2Real] = if nUnknown == 0 {
            &mut []
        } else {
            std::slice::from_raw_parts_mut(dvUnknown, nUnknown)
        };
        crate::fmi::directional::directional_derivative::<M>(
            inst, f, unknowns, knowns, seed, out, refs,
        )
    })
}

// ------------------------------------------------------------------------------ co-simulation

#[inline]
pub unsafe fn fmi2SetRealInputDerivatives<M: FmuModel>(
    c: fmi2Component,
    _vr: *const fmi2ValueReference,
    _nvr: usize,
    _order: *const fmi2Integer,
    _value: *const fmi2Real,
) -> fmi2Status {
    call::<M>(c, "fmi2SetRealInputDerivatives", |_| {
        Err(Failure::error(format!(
            "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs=\"false\"); {}",
            M::info().input_derivatives_hint
        )))
    })
}

#[inline]
pub unsafe fn fmi2GetRealOutputDerivatives<M: FmuModel>(
    c: fmi2Component,
    _vr: *const fmi2ValueReference,
    _nvr: usize,
    _order: *const fmi2Integer,
    _value: *mut fmi2Real,
) -> fmi2Status {
    call::<M>(c, "fmi2GetRealOutputDerivatives", |_| {
        Err(Failure::error(
            "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder=\"0\")",
        ))
    })
}

#[inline]
pub unsafe fn fmi2DoStep<M: FmuModel>(
    c: fmi2Component,
    currentCommunicationPoint: fmi2Real,
    communicationStepSize: fmi2Real,
    _noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
) -> fmi2Status {
    // A rigid mechanism's ordinary step cannot panic (proved at link time, `Instance::quick_step`)
    // and needs no barrier; anything else takes the general path.
    if live::<M>(c)
        .is_some_and(|i| (*i).quick_step(currentCommunicationPoint, communicationStepSize))
    {
        return fmi2Status_fmi2OK;
    }
    do_step::<M>(c, currentCommunicationPoint, communicationStepSize)
}

/// fmi2DoStep's general path, out of line so that the fast path sets up no stack frame for it.
#[inline(never)]
unsafe fn do_step<M: FmuModel>(c: fmi2Component, current: fmi2Real, h: fmi2Real) -> fmi2Status {
    call::<M>(c, "fmi2DoStep", |inst| {
        model_exchange::refuse_model_exchange(inst, "fmi2DoStep")?;
        inst.do_step(current, h)
    })
}

#[inline]
pub unsafe fn fmi2CancelStep<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    call::<M>(c, "fmi2CancelStep", |_| {
        Err(Failure::error("fmi2CancelStep: no asynchronous step is running (fmi2DoStep never returns fmi2Pending)"))
    })
}

#[inline]
pub unsafe fn fmi2GetStatus<M: FmuModel>(
    c: fmi2Component,
    _s: fmi2StatusKind,
    _value: *mut fmi2Status,
) -> fmi2Status {
    call::<M>(c, "fmi2GetStatus", |_| {
        Err(Failure::discard("fmi2GetStatus: no status available (no asynchronous steps)"))
    })
}

#[inline]
pub unsafe fn fmi2GetRealStatus<M: FmuModel>(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Real,
) -> fmi2Status {
    call::<M>(c, "fmi2GetRealStatus", |inst| {
        model_exchange::refuse_model_exchange(inst, "fmi2GetRealStatus")?;
        if s != fmi2StatusKind_fmi2LastSuccessfulTime {
            return Err(Failure::discard(format!(
                "fmi2GetRealStatus: status kind {s} is not available"
            )));
        }
        if value.is_null() {
            return Err(null_argument("fmi2GetRealStatus", "value"));
        }
        *value = inst.time();
        Ok(())
    })
}

#[inline]
pub unsafe fn fmi2GetIntegerStatus<M: FmuModel>(
    c: fmi2Component,
    s: fmi2StatusKind,
    _value: *mut fmi2Integer,
) -> fmi2Status {
    call::<M>(c, "fmi2GetIntegerStatus", |_| {
        Err(Failure::discard(format!("fmi2GetIntegerStatus: status kind {s} is not available")))
    })
}

#[inline]
pub unsafe fn fmi2GetBooleanStatus<M: FmuModel>(
    c: fmi2Component,
    s: fmi2StatusKind,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    call::<M>(c, "fmi2GetBooleanStatus", |_| {
        if s != fmi2StatusKind_fmi2Terminated {
            return Err(Failure::discard(format!(
                "fmi2GetBooleanStatus: status kind {s} is not available"
            )));
        }
        if value.is_null() {
            return Err(null_argument("fmi2GetBooleanStatus", "value"));
        }
        // The FMU never asks the master to stop.
        *value = 0;
        Ok(())
    })
}

#[inline]
pub unsafe fn fmi2GetStringStatus<M: FmuModel>(
    c: fmi2Component,
    s: fmi2StatusKind,
    _value: *mut fmi2String,
) -> fmi2Status {
    call::<M>(c, "fmi2GetStringStatus", |_| {
        Err(Failure::discard(format!("fmi2GetStringStatus: status kind {s} is not available")))
    })
}

// ------------------------------------------------------------------------------ exports

/// Exports the 34 FMI 2.0 co-simulation functions for one model: put
/// `reciprocating_drive::export_fmu!(path::to::Model);` in the root of that FMU's cdylib crate.
/// Each export is a thin `extern "C"` shim over the generic function of this module, and its
/// type is checked at compile time against the official FMI 2.0 headers (`fmi2…TYPE`).
#[macro_export]
macro_rules! export_fmu {
    ($model:ty) => {
        const _: () = {
            use $crate::fmi2::abi as glue;
            use $crate::fmi_sys::fmi2::*;
            type M = $model;

            #[no_mangle]
            pub extern "C" fn fmi2GetTypesPlatform() -> *const ::std::ffi::c_char {
                glue::fmi2GetTypesPlatform()
            }
            #[no_mangle]
            pub extern "C" fn fmi2GetVersion() -> *const ::std::ffi::c_char {
                glue::fmi2GetVersion()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetDebugLogging(
                c: fmi2Component,
                loggingOn: fmi2Boolean,
                nCategories: usize,
                categories: *const fmi2String,
            ) -> fmi2Status {
                glue::fmi2SetDebugLogging::<M>(c, loggingOn, nCategories, categories)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Instantiate(
                instanceName: fmi2String,
                fmuType: fmi2Type,
                fmuGUID: fmi2String,
                fmuResourceLocation: fmi2String,
                functions: *const fmi2CallbackFunctions,
                visible: fmi2Boolean,
                loggingOn: fmi2Boolean,
            ) -> fmi2Component {
                glue::fmi2Instantiate::<M>(
                    instanceName,
                    fmuType,
                    fmuGUID,
                    fmuResourceLocation,
                    functions,
                    visible,
                    loggingOn,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
                glue::fmi2FreeInstance::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetupExperiment(
                c: fmi2Component,
                toleranceDefined: fmi2Boolean,
                tolerance: fmi2Real,
                startTime: fmi2Real,
                stopTimeDefined: fmi2Boolean,
                stopTime: fmi2Real,
            ) -> fmi2Status {
                glue::fmi2SetupExperiment::<M>(
                    c,
                    toleranceDefined,
                    tolerance,
                    startTime,
                    stopTimeDefined,
                    stopTime,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
                glue::fmi2EnterInitializationMode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
                glue::fmi2ExitInitializationMode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
                glue::fmi2Terminate::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
                glue::fmi2Reset::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetReal(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *mut fmi2Real,
            ) -> fmi2Status {
                glue::fmi2GetReal::<M>(c, vr, nvr, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetInteger(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *mut fmi2Integer,
            ) -> fmi2Status {
                glue::fmi2GetInteger::<M>(c, vr, nvr, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBoolean(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *mut fmi2Boolean,
            ) -> fmi2Status {
                glue::fmi2GetBoolean::<M>(c, vr, nvr, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetString(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *mut fmi2String,
            ) -> fmi2Status {
                glue::fmi2GetString::<M>(c, vr, nvr, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetReal(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *const fmi2Real,
            ) -> fmi2Status {
                glue::fmi2SetReal::<M>(c, vr, nvr, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetInteger(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *const fmi2Integer,
            ) -> fmi2Status {
                glue::fmi2SetInteger::<M>(c, vr, nvr, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetBoolean(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *const fmi2Boolean,
            ) -> fmi2Status {
                glue::fmi2SetBoolean::<M>(c, vr, nvr, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetString(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                value: *const fmi2String,
            ) -> fmi2Status {
                glue::fmi2SetString::<M>(c, vr, nvr, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetFMUstate(
                c: fmi2Component,
                state: *mut fmi2FMUstate,
            ) -> fmi2Status {
                glue::fmi2GetFMUstate::<M>(c, state)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetFMUstate(
                c: fmi2Component,
                state: fmi2FMUstate,
            ) -> fmi2Status {
                glue::fmi2SetFMUstate::<M>(c, state)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeFMUstate(
                c: fmi2Component,
                state: *mut fmi2FMUstate,
            ) -> fmi2Status {
                glue::fmi2FreeFMUstate::<M>(c, state)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
                c: fmi2Component,
                state: fmi2FMUstate,
                size: *mut usize,
            ) -> fmi2Status {
                glue::fmi2SerializedFMUstateSize::<M>(c, state, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializeFMUstate(
                c: fmi2Component,
                state: fmi2FMUstate,
                bytes: *mut fmi2Byte,
                size: usize,
            ) -> fmi2Status {
                glue::fmi2SerializeFMUstate::<M>(c, state, bytes, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
                c: fmi2Component,
                bytes: *const fmi2Byte,
                size: usize,
                state: *mut fmi2FMUstate,
            ) -> fmi2Status {
                glue::fmi2DeSerializeFMUstate::<M>(c, bytes, size, state)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
                c: fmi2Component,
                vUnknown_ref: *const fmi2ValueReference,
                nUnknown: usize,
                vKnown_ref: *const fmi2ValueReference,
                nKnown: usize,
                dvKnown: *const fmi2Real,
                dvUnknown: *mut fmi2Real,
            ) -> fmi2Status {
                glue::fmi2GetDirectionalDerivative::<M>(
                    c,
                    vUnknown_ref,
                    nUnknown,
                    vKnown_ref,
                    nKnown,
                    dvKnown,
                    dvUnknown,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                order: *const fmi2Integer,
                value: *const fmi2Real,
            ) -> fmi2Status {
                glue::fmi2SetRealInputDerivatives::<M>(c, vr, nvr, order, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                nvr: usize,
                order: *const fmi2Integer,
                value: *mut fmi2Real,
            ) -> fmi2Status {
                glue::fmi2GetRealOutputDerivatives::<M>(c, vr, nvr, order, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DoStep(
                c: fmi2Component,
                currentCommunicationPoint: fmi2Real,
                communicationStepSize: fmi2Real,
                noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
            ) -> fmi2Status {
                glue::fmi2DoStep::<M>(
                    c,
                    currentCommunicationPoint,
                    communicationStepSize,
                    noSetFMUStatePriorToCurrentPoint,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
                glue::fmi2CancelStep::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2Status,
            ) -> fmi2Status {
                glue::fmi2GetStatus::<M>(c, s, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2Real,
            ) -> fmi2Status {
                glue::fmi2GetRealStatus::<M>(c, s, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetIntegerStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2Integer,
            ) -> fmi2Status {
                glue::fmi2GetIntegerStatus::<M>(c, s, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBooleanStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2Boolean,
            ) -> fmi2Status {
                glue::fmi2GetBooleanStatus::<M>(c, s, value)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStringStatus(
                c: fmi2Component,
                s: fmi2StatusKind,
                value: *mut fmi2String,
            ) -> fmi2Status {
                glue::fmi2GetStringStatus::<M>(c, s, value)
            }

            // Each exported function must have exactly the type the FMI 2.0 headers declare.
            const _: fmi2GetTypesPlatformTYPE = Some(fmi2GetTypesPlatform);
            const _: fmi2GetVersionTYPE = Some(fmi2GetVersion);
            const _: fmi2SetDebugLoggingTYPE = Some(fmi2SetDebugLogging);
            const _: fmi2InstantiateTYPE = Some(fmi2Instantiate);
            const _: fmi2FreeInstanceTYPE = Some(fmi2FreeInstance);
            const _: fmi2SetupExperimentTYPE = Some(fmi2SetupExperiment);
            const _: fmi2EnterInitializationModeTYPE = Some(fmi2EnterInitializationMode);
            const _: fmi2ExitInitializationModeTYPE = Some(fmi2ExitInitializationMode);
            const _: fmi2TerminateTYPE = Some(fmi2Terminate);
            const _: fmi2ResetTYPE = Some(fmi2Reset);
            const _: fmi2GetRealTYPE = Some(fmi2GetReal);
            const _: fmi2GetIntegerTYPE = Some(fmi2GetInteger);
            const _: fmi2GetBooleanTYPE = Some(fmi2GetBoolean);
            const _: fmi2GetStringTYPE = Some(fmi2GetString);
            const _: fmi2SetRealTYPE = Some(fmi2SetReal);
            const _: fmi2SetIntegerTYPE = Some(fmi2SetInteger);
            const _: fmi2SetBooleanTYPE = Some(fmi2SetBoolean);
            const _: fmi2SetStringTYPE = Some(fmi2SetString);
            const _: fmi2GetFMUstateTYPE = Some(fmi2GetFMUstate);
            const _: fmi2SetFMUstateTYPE = Some(fmi2SetFMUstate);
            const _: fmi2FreeFMUstateTYPE = Some(fmi2FreeFMUstate);
            const _: fmi2SerializedFMUstateSizeTYPE = Some(fmi2SerializedFMUstateSize);
            const _: fmi2SerializeFMUstateTYPE = Some(fmi2SerializeFMUstate);
            const _: fmi2DeSerializeFMUstateTYPE = Some(fmi2DeSerializeFMUstate);
            const _: fmi2GetDirectionalDerivativeTYPE = Some(fmi2GetDirectionalDerivative);
            const _: fmi2SetRealInputDerivativesTYPE = Some(fmi2SetRealInputDerivatives);
            const _: fmi2GetRealOutputDerivativesTYPE = Some(fmi2GetRealOutputDerivatives);
            const _: fmi2DoStepTYPE = Some(fmi2DoStep);
            const _: fmi2CancelStepTYPE = Some(fmi2CancelStep);
            const _: fmi2GetStatusTYPE = Some(fmi2GetStatus);
            const _: fmi2GetRealStatusTYPE = Some(fmi2GetRealStatus);
            const _: fmi2GetIntegerStatusTYPE = Some(fmi2GetIntegerStatus);
            const _: fmi2GetBooleanStatusTYPE = Some(fmi2GetBooleanStatus);
            const _: fmi2GetStringStatusTYPE = Some(fmi2GetStringStatus);
        };
        // FMI 2.0 Model Exchange in the same shared object (src/fmi2/model_exchange.rs).
        $crate::export_fmu2_model_exchange!($model);
    };
}
