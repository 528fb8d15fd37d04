//! FMI 2.0 layer: every FMI 2.0 common and co-simulation function (34), generic over the model,
//! each a few lines over the core ([`crate::fmi::ffi`]: argument checks, panic barrier, the
//! get/set and FMU-state families; [`Instance`]: the state machine). A [`Failure`] becomes its
//! status plus one log line naming the function. [`export_fmu!`](crate::export_fmu) instantiates
//! them for one model as the 34 `#[no_mangle] extern "C"` functions of that FMU's shared object
//! (one cdylib per FMU, each with its own exports and GUID); their signatures are checked at
//! compile time against the types bindgen generated from the official FMI 2.0 headers.

#![allow(non_snake_case)]
#![allow(clippy::missing_safety_doc)]

use std::ffi::{c_char, CStr};

use fmi_sys::fmi2::*;

use crate::fmi::ffi::{self, null_argument, opt_str, Dialect};
use crate::fmi::handle::{free_instance, live};
use crate::fmi::instance::{copy_name, Failure, Instance};
use crate::fmi::logging::Logger;
use crate::fmi::model::FmuModel;
use crate::fmi::resources::resource_dir;
use crate::fmi::variables::VarType;
use crate::fmi2::model_description::guid;
use crate::fmi2::model_exchange;

static TYPES_PLATFORM: &CStr = c"default";
static VERSION: &CStr = c"2.0";

/// FMI 2.0's names in the core's messages.
pub(crate) struct Fmi2;
impl Dialect for Fmi2 {
    const ANY_NAME: bool = false;
    const VR: &'static str = "vr";
    const VALUES: &'static str = "value";
    const DIRECTIONAL: [&'static str; 4] = ["vUnknown_ref", "vKnown_ref", "dvKnown", "dvUnknown"];
    const FMU_STATE: &'static str = "FMUstate";
    const NX: &'static str = "nx";
    const STATES: &'static str = "x";
    const NOMINALS: &'static str = "x_nominal";
    const ENTER_INITIALIZATION: &'static str = "fmi2EnterInitializationMode";
}

/// Runs `f` on the instance behind `c` (`crate::fmi::ffi::call`).
#[inline]
pub(crate) unsafe fn call<M: FmuModel>(
    c: fmi2Component,
    function: &str,
    f: impl FnOnce(&mut Instance<M>) -> Result<(), Failure>,
) -> fmi2Status {
    ffi::call::<Fmi2, M>(c, function, f)
}

// ------------------------------------------------------------------------------ common functions

#[inline]
pub fn fmi2GetTypesPlatform<M: FmuModel>() -> *const c_char {
    TYPES_PLATFORM.as_ptr()
}

#[inline]
pub fn fmi2GetVersion<M: FmuModel>() -> *const c_char {
    VERSION.as_ptr()
}

#[inline]
pub unsafe fn fmi2SetDebugLogging<M: FmuModel>(
    c: fmi2Component,
    loggingOn: fmi2Boolean,
    nCategories: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    let f = "fmi2SetDebugLogging";
    ffi::set_debug_logging::<Fmi2, M>(c, f, loggingOn != 0, nCategories, categories)
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
    if functions.is_null() {
        return std::ptr::null_mut();
    }
    let name = opt_str(instanceName).unwrap_or("");
    let logger = || {
        let cb = &*functions;
        Logger::new(cb.logger, cb.componentEnvironment, copy_name(name), loggingOn != 0)
    };
    // Model Exchange beside co-simulation (docs/fmi-interface.md "Model Exchange (FMI 2.0)").
    let model_exchange = fmuType == fmi2Type_fmi2ModelExchange && M::MODEL_EXCHANGE;
    let check = || {
        if name.is_empty() {
            return Some("instanceName is NULL or empty".into());
        }
        if fmuType != fmi2Type_fmi2CoSimulation && !model_exchange {
            return Some(format!(
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
            Some(g) if g == guid::<M>() => None,
            other => Some(format!(
                "GUID {:?} is not this FMU's GUID {}",
                other.unwrap_or("NULL"),
                guid::<M>()
            )),
        }
    };
    let dir = || resource_dir(opt_str(fmuResourceLocation));
    ffi::instantiate::<M>("fmi2Instantiate", logger, check, dir, model_exchange)
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
    let tolerance = (toleranceDefined != 0).then_some(tolerance);
    let stop = (stopTimeDefined != 0).then_some(stopTime);
    call::<M>(c, "fmi2SetupExperiment", |inst| inst.setup_experiment(tolerance, startTime, stop))
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

// ------------------------------------------------------------------------------ get and set

#[inline]
pub unsafe fn fmi2GetReal<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Real,
) -> fmi2Status {
    if let Some(status) = ffi::quick_get_real::<M, 2>(c, "fmi2GetReal", vr, nvr, value) {
        return status;
    }
    // Model Exchange: the state derivatives are not in the table.
    if let Some(status) = model_exchange::get_real_with_derivatives::<M>(c, vr, nvr, value) {
        return status;
    }
    ffi::get_values::<Fmi2, M, _>(c, "fmi2GetReal", VarType::Real, vr, nvr, value, None, |v| v)
}

#[inline]
pub unsafe fn fmi2GetInteger<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Integer,
) -> fmi2Status {
    let ty = VarType::Integer;
    ffi::get_values::<Fmi2, M, _>(c, "fmi2GetInteger", ty, vr, nvr, value, None, |v| v as i32)
}

#[inline]
pub unsafe fn fmi2GetBoolean<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    let (f, ty) = ("fmi2GetBoolean", VarType::Boolean);
    ffi::get_values::<Fmi2, M, _>(c, f, ty, vr, nvr, value, None, |v| (v != 0.0) as fmi2Boolean)
}

#[inline]
pub unsafe fn fmi2GetString<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *mut fmi2String,
) -> fmi2Status {
    ffi::no_variables::<Fmi2, M>(c, "fmi2GetString", "String", NO_STRINGS, vr, nvr)
}

#[inline]
pub unsafe fn fmi2SetReal<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Real,
) -> fmi2Status {
    if ffi::quick_set_real::<M, 2>(c, vr, nvr, value) {
        return fmi2Status_fmi2OK;
    }
    ffi::set_values::<Fmi2, M, _>(c, "fmi2SetReal", VarType::Real, vr, nvr, value, None, |v| v)
}

#[inline]
pub unsafe fn fmi2SetInteger<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Integer,
) -> fmi2Status {
    let ty = VarType::Integer;
    ffi::set_values::<Fmi2, M, _>(c, "fmi2SetInteger", ty, vr, nvr, value, None, |v| v as f64)
}

#[inline]
pub unsafe fn fmi2SetBoolean<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    value: *const fmi2Boolean,
) -> fmi2Status {
    let (f, ty) = ("fmi2SetBoolean", VarType::Boolean);
    ffi::set_values::<Fmi2, M, _>(c, f, ty, vr, nvr, value, None, |v| (v != 0) as i32 as f64)
}

#[inline]
pub unsafe fn fmi2SetString<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    _value: *const fmi2String,
) -> fmi2Status {
    ffi::no_variables::<Fmi2, M>(c, "fmi2SetString", "String", NO_STRINGS, vr, nvr)
}

const NO_STRINGS: &str = "this FMU has none";

// ------------------------------------------------------------------------------ FMU state

#[inline]
pub unsafe fn fmi2GetFMUstate<M: FmuModel>(
    c: fmi2Component,
    state: *mut fmi2FMUstate,
) -> fmi2Status {
    ffi::get_fmu_state::<Fmi2, M>(c, "fmi2GetFMUstate", state)
}

#[inline]
pub unsafe fn fmi2SetFMUstate<M: FmuModel>(c: fmi2Component, state: fmi2FMUstate) -> fmi2Status {
    ffi::set_fmu_state::<Fmi2, M>(c, "fmi2SetFMUstate", state)
}

#[inline]
pub unsafe fn fmi2FreeFMUstate<M: FmuModel>(
    c: fmi2Component,
    state: *mut fmi2FMUstate,
) -> fmi2Status {
    ffi::free_fmu_state::<Fmi2, M>(c, "fmi2FreeFMUstate", state)
}

#[inline]
pub unsafe fn fmi2SerializedFMUstateSize<M: FmuModel>(
    c: fmi2Component,
    state: fmi2FMUstate,
    size: *mut usize,
) -> fmi2Status {
    ffi::serialized_size::<Fmi2, M>(c, "fmi2SerializedFMUstateSize", state, size)
}

#[inline]
pub unsafe fn fmi2SerializeFMUstate<M: FmuModel>(
    c: fmi2Component,
    state: fmi2FMUstate,
    bytes: *mut fmi2Byte,
    size: usize,
) -> fmi2Status {
    ffi::serialize::<Fmi2, M>(c, "fmi2SerializeFMUstate", state, bytes as *mut u8, size)
}

#[inline]
pub unsafe fn fmi2DeSerializeFMUstate<M: FmuModel>(
    c: fmi2Component,
    bytes: *const fmi2Byte,
    size: usize,
    state: *mut fmi2FMUstate,
) -> fmi2Status {
    ffi::deserialize::<Fmi2, M>(c, "fmi2DeSerializeFMUstate", bytes as *const u8, size, state)
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
    let (f, u, k) = ("fmi2GetDirectionalDerivative", vUnknown_ref, vKnown_ref);
    ffi::get_directional_derivative::<Fmi2, M>(
        c, f, u, nUnknown, k, nKnown, dvKnown, dvUnknown, None,
    )
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
            use ::std::ffi::c_char;
            type M = $model;
            type C = fmi2Component;
            type S = fmi2Status;
            type Vr = *const fmi2ValueReference;

            $crate::__fmi_exports! {
                fmi2GetTypesPlatform: fmi2GetTypesPlatformTYPE() -> *const c_char;
                fmi2GetVersion: fmi2GetVersionTYPE() -> *const c_char;
                fmi2SetDebugLogging: fmi2SetDebugLoggingTYPE(c: C, loggingOn: fmi2Boolean, nCategories: usize, categories: *const fmi2String) -> S;
                fmi2Instantiate: fmi2InstantiateTYPE(instanceName: fmi2String, fmuType: fmi2Type, fmuGUID: fmi2String, fmuResourceLocation: fmi2String, functions: *const fmi2CallbackFunctions, visible: fmi2Boolean, loggingOn: fmi2Boolean) -> C;
                fmi2FreeInstance: fmi2FreeInstanceTYPE(c: C) -> ();
                fmi2SetupExperiment: fmi2SetupExperimentTYPE(c: C, toleranceDefined: fmi2Boolean, tolerance: fmi2Real, startTime: fmi2Real, stopTimeDefined: fmi2Boolean, stopTime: fmi2Real) -> S;
                fmi2EnterInitializationMode: fmi2EnterInitializationModeTYPE(c: C) -> S;
                fmi2ExitInitializationMode: fmi2ExitInitializationModeTYPE(c: C) -> S;
                fmi2Terminate: fmi2TerminateTYPE(c: C) -> S;
                fmi2Reset: fmi2ResetTYPE(c: C) -> S;
                fmi2GetReal: fmi2GetRealTYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi2Real) -> S;
                fmi2GetInteger: fmi2GetIntegerTYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi2Integer) -> S;
                fmi2GetBoolean: fmi2GetBooleanTYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi2Boolean) -> S;
                fmi2GetString: fmi2GetStringTYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi2String) -> S;
                fmi2SetReal: fmi2SetRealTYPE(c: C, vr: Vr, nvr: usize, value: *const fmi2Real) -> S;
                fmi2SetInteger: fmi2SetIntegerTYPE(c: C, vr: Vr, nvr: usize, value: *const fmi2Integer) -> S;
                fmi2SetBoolean: fmi2SetBooleanTYPE(c: C, vr: Vr, nvr: usize, value: *const fmi2Boolean) -> S;
                fmi2SetString: fmi2SetStringTYPE(c: C, vr: Vr, nvr: usize, value: *const fmi2String) -> S;
                fmi2GetFMUstate: fmi2GetFMUstateTYPE(c: C, state: *mut fmi2FMUstate) -> S;
                fmi2SetFMUstate: fmi2SetFMUstateTYPE(c: C, state: fmi2FMUstate) -> S;
                fmi2FreeFMUstate: fmi2FreeFMUstateTYPE(c: C, state: *mut fmi2FMUstate) -> S;
                fmi2SerializedFMUstateSize: fmi2SerializedFMUstateSizeTYPE(c: C, state: fmi2FMUstate, size: *mut usize) -> S;
                fmi2SerializeFMUstate: fmi2SerializeFMUstateTYPE(c: C, state: fmi2FMUstate, bytes: *mut fmi2Byte, size: usize) -> S;
                fmi2DeSerializeFMUstate: fmi2DeSerializeFMUstateTYPE(c: C, bytes: *const fmi2Byte, size: usize, state: *mut fmi2FMUstate) -> S;
                fmi2GetDirectionalDerivative: fmi2GetDirectionalDerivativeTYPE(c: C, vUnknown_ref: Vr, nUnknown: usize, vKnown_ref: Vr, nKnown: usize, dvKnown: *const fmi2Real, dvUnknown: *mut fmi2Real) -> S;
                fmi2SetRealInputDerivatives: fmi2SetRealInputDerivativesTYPE(c: C, vr: Vr, nvr: usize, order: *const fmi2Integer, value: *const fmi2Real) -> S;
                fmi2GetRealOutputDerivatives: fmi2GetRealOutputDerivativesTYPE(c: C, vr: Vr, nvr: usize, order: *const fmi2Integer, value: *mut fmi2Real) -> S;
                fmi2DoStep: fmi2DoStepTYPE(c: C, currentCommunicationPoint: fmi2Real, communicationStepSize: fmi2Real, noSetFMUStatePriorToCurrentPoint: fmi2Boolean) -> S;
                fmi2CancelStep: fmi2CancelStepTYPE(c: C) -> S;
                fmi2GetStatus: fmi2GetStatusTYPE(c: C, s: fmi2StatusKind, value: *mut fmi2Status) -> S;
                fmi2GetRealStatus: fmi2GetRealStatusTYPE(c: C, s: fmi2StatusKind, value: *mut fmi2Real) -> S;
                fmi2GetIntegerStatus: fmi2GetIntegerStatusTYPE(c: C, s: fmi2StatusKind, value: *mut fmi2Integer) -> S;
                fmi2GetBooleanStatus: fmi2GetBooleanStatusTYPE(c: C, s: fmi2StatusKind, value: *mut fmi2Boolean) -> S;
                fmi2GetStringStatus: fmi2GetStringStatusTYPE(c: C, s: fmi2StatusKind, value: *mut fmi2String) -> S;
            }
        };
        // FMI 2.0 Model Exchange in the same shared object (src/fmi2/model_exchange.rs).
        $crate::export_fmu2_model_exchange!($model);
    };
}
