//! FMI 3.0 layer: every FMI 3.0 function, generic over the model, each a few lines over the same
//! core as FMI 2.0 ([`crate::fmi::ffi`]: argument checks, panic barrier, the get/set and
//! FMU-state families; [`Instance`]: state machine, get/set, FMU states, logging), so both
//! standards run the same code and give the same numbers (docs/fmi-interface.md "FMI 3.0").
//!
//! Co-simulation for every FMU; Model Exchange where the model declares it
//! ([`FmuModel::MODEL_EXCHANGE`]: the DriveTrain with its states, the pump's rigid mechanisms
//! without any); no event mode in co-simulation, no events, no clocks, one Float64/Int32/Boolean
//! scalar per value reference. Every function of `fmi3Functions.h` is exported, so an importer
//! that binds them all finds them; those of interfaces this FMU does not declare fail with a
//! message saying why. [`export_fmu3!`](crate::export_fmu3) instantiates them for one model as
//! `#[no_mangle] extern "C"` functions, their types checked at compile time against the types
//! bindgen generated from the official FMI 3.0 headers (`fmi3…TYPE`).

#![allow(non_snake_case)]
#![allow(clippy::missing_safety_doc)]
#![allow(clippy::too_many_arguments)]

use std::ffi::{c_char, CStr};

use fmi_sys::fmi3::*;

use crate::fmi::ffi::{self, null_argument, opt_str, Dialect};
use crate::fmi::handle::{free_instance, live};
use crate::fmi::instance::{copy_name, Failure, Instance, Mode};
use crate::fmi::logging::Logger;
use crate::fmi::model::FmuModel;
use crate::fmi::model_exchange as me_core;
use crate::fmi::resources::resource_path;
use crate::fmi::structure::time_vr;
use crate::fmi::variables::VarType;
use crate::fmi3::model_description::token;

static VERSION: &CStr = c"3.0";

/// FMI 3.0's names in the core's messages.
pub(crate) struct Fmi3;
impl Dialect for Fmi3 {
    const ANY_NAME: bool = true;
    const VR: &'static str = "valueReferences";
    const VALUES: &'static str = "values";
    const DIRECTIONAL: [&'static str; 4] = ["unknowns", "knowns", "seed", "sensitivity"];
    const FMU_STATE: &'static str = "FMUState";
    const NX: &'static str = "nContinuousStates";
    const STATES: &'static str = "continuousStates";
    const NOMINALS: &'static str = "nominals";
    const ENTER_INITIALIZATION: &'static str = "fmi3EnterInitializationMode";
}

/// Runs `f` on the instance behind `c` (`crate::fmi::ffi::call`; the logger translates the
/// core's FMI 2.0 names, `crate::fmi::logging::dialect`).
#[inline]
unsafe fn call<M: FmuModel>(
    c: fmi3Instance,
    function: &str,
    f: impl FnOnce(&mut Instance<M>) -> Result<(), Failure>,
) -> fmi3Status {
    ffi::call::<Fmi3, M>(c, function, f)
}

const NOT_ME: &str = "this FMU offers no Model Exchange (no <ModelExchange> element)";
const NO_CLOCKS: &str = "this FMU has no clocks";
const NO_EVENTS: &str = "this FMU has no event mode (hasEventMode=\"false\")";
const NOT_ME_INSTANCE: &str = "not an instance for Model Exchange (fmi3InstantiateModelExchange)";
const NO_STRUCTURAL: &str = "this FMU has no structural parameters";

/// Functions of interfaces or features this FMU does not declare: an error naming the function
/// and saying why, whatever the arguments after the instance.
macro_rules! unsupported {
    ($($name:ident($($t:ty),*) => $why:expr;)*) => {$(
        pub unsafe fn $name<M: FmuModel>(c: fmi3Instance, $(_: $t),*) -> fmi3Status {
            ffi::unsupported::<Fmi3, M>(c, stringify!($name), $why)
        }
    )*};
}

/// The get and set functions of a type this FMU has variables of, through the core's general
/// path (`set` reads the values as `$read`); Float64 has its own, with the fast path.
macro_rules! typed_get_set {
    ($($get:ident, $set:ident, $t:ty, $read:ty, $ty:ident, $to:expr, $from:expr;)*) => {$(
        pub unsafe fn $get<M: FmuModel>(
            c: fmi3Instance,
            vr: *const fmi3ValueReference,
            nvr: usize,
            value: *mut $t,
            nValues: usize,
        ) -> fmi3Status {
            let (f, ty, n) = (stringify!($get), VarType::$ty, Some(nValues));
            ffi::get_values::<Fmi3, M, _>(c, f, ty, vr, nvr, value, n, $to)
        }
        pub unsafe fn $set<M: FmuModel>(
            c: fmi3Instance,
            vr: *const fmi3ValueReference,
            nvr: usize,
            value: *const $t,
            nValues: usize,
        ) -> fmi3Status {
            let (f, ty, n) = (stringify!($set), VarType::$ty, Some(nValues));
            ffi::set_values::<Fmi3, M, $read>(c, f, ty, vr, nvr, value as *const $read, n, $from)
        }
    )*};
}

/// The get and set functions of the types this FMU has no variable of: only an empty list of
/// value references is accepted.
macro_rules! no_variables {
    ($($name:ident, $type_name:literal, ($($t:ty),*);)*) => {$(
        pub unsafe fn $name<M: FmuModel>(
            c: fmi3Instance,
            vr: *const fmi3ValueReference,
            nvr: usize,
            $(_: $t),*
        ) -> fmi3Status {
            let what = "this FMU has none; its variables are Float64, Int32 and Boolean";
            ffi::no_variables::<Fmi3, M>(c, stringify!($name), $type_name, what, vr, nvr)
        }
    )*};
}

// ------------------------------------------------------------------------------ common functions

#[inline]
pub fn fmi3GetVersion<M: FmuModel>() -> *const c_char {
    VERSION.as_ptr()
}

pub unsafe fn fmi3SetDebugLogging<M: FmuModel>(
    c: fmi3Instance,
    loggingOn: fmi3Boolean,
    nCategories: usize,
    categories: *const fmi3String,
) -> fmi3Status {
    ffi::set_debug_logging::<Fmi3, M>(c, "fmi3SetDebugLogging", loggingOn, nCategories, categories)
}

/// What the three fmi3Instantiate… functions share: the logger, the instance name, the token
/// (`refusal`: the interface's own reason to refuse, checked first).
unsafe fn instantiate<M: FmuModel>(
    function: &str,
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    refusal: Option<String>,
    model_exchange: bool,
) -> fmi3Instance {
    let name = opt_str(instanceName).unwrap_or("");
    let logger = || Logger::new_fmi3(logMessage, instanceEnvironment, copy_name(name), loggingOn);
    let check = || {
        if refusal.is_some() {
            return refusal;
        }
        if name.is_empty() {
            return Some("instanceName is NULL or empty".into());
        }
        match opt_str(instantiationToken) {
            Some(g) if g == token::<M>() => None,
            other => Some(format!(
                "instantiationToken {:?} is not this FMU's {}",
                other.unwrap_or("NULL"),
                token::<M>()
            )),
        }
    };
    let dir = || resource_path(opt_str(resourcePath));
    ffi::instantiate::<M>(function, logger, check, dir, model_exchange)
}

pub unsafe fn fmi3InstantiateModelExchange<M: FmuModel>(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    _visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
) -> fmi3Instance {
    instantiate::<M>(
        "fmi3InstantiateModelExchange",
        instanceName,
        instantiationToken,
        resourcePath,
        loggingOn,
        instanceEnvironment,
        logMessage,
        (!M::MODEL_EXCHANGE).then(|| NOT_ME.into()),
        true,
    )
}

pub unsafe fn fmi3InstantiateCoSimulation<M: FmuModel>(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    _visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    eventModeUsed: fmi3Boolean,
    _earlyReturnAllowed: fmi3Boolean,
    _requiredIntermediateVariables: *const fmi3ValueReference,
    nRequiredIntermediateVariables: usize,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    _intermediateUpdate: fmi3IntermediateUpdateCallback,
) -> fmi3Instance {
    // earlyReturnAllowed is only a permission: fmi3DoStep never returns early.
    let refusal = if eventModeUsed {
        Some(format!("eventModeUsed = true, but {NO_EVENTS}"))
    } else if nRequiredIntermediateVariables > 0 {
        Some(format!(
            "{nRequiredIntermediateVariables} requiredIntermediateVariables, but this FMU \
             provides no intermediate update (providesIntermediateUpdate=\"false\")"
        ))
    } else {
        None
    };
    instantiate::<M>(
        "fmi3InstantiateCoSimulation",
        instanceName,
        instantiationToken,
        resourcePath,
        loggingOn,
        instanceEnvironment,
        logMessage,
        refusal,
        false,
    )
}

pub unsafe fn fmi3InstantiateScheduledExecution<M: FmuModel>(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    _visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    _clockUpdate: fmi3ClockUpdateCallback,
    _lockPreemption: fmi3LockPreemptionCallback,
    _unlockPreemption: fmi3UnlockPreemptionCallback,
) -> fmi3Instance {
    instantiate::<M>(
        "fmi3InstantiateScheduledExecution",
        instanceName,
        instantiationToken,
        resourcePath,
        loggingOn,
        instanceEnvironment,
        logMessage,
        Some("this FMU has no <ScheduledExecution> element".into()),
        false,
    )
}

/// Frees the instance and keeps its handle (`crate::fmi::handle`): a second call is reported
/// and does nothing.
pub unsafe fn fmi3FreeInstance<M: FmuModel>(c: fmi3Instance) {
    free_instance::<M>(c, "fmi3FreeInstance")
}

/// FMI 3.0 merges fmi2SetupExperiment into fmi3EnterInitializationMode: both run, and a failure
/// of either leaves the instance as it was.
pub unsafe fn fmi3EnterInitializationMode<M: FmuModel>(
    c: fmi3Instance,
    toleranceDefined: fmi3Boolean,
    tolerance: fmi3Float64,
    startTime: fmi3Float64,
    stopTimeDefined: fmi3Boolean,
    stopTime: fmi3Float64,
) -> fmi3Status {
    call::<M>(c, "fmi3EnterInitializationMode", |inst| {
        inst.setup_experiment(
            toleranceDefined.then_some(tolerance),
            startTime,
            stopTimeDefined.then_some(stopTime),
        )?;
        inst.enter_initialization_mode()
    })
}

pub unsafe fn fmi3ExitInitializationMode<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    call::<M>(c, "fmi3ExitInitializationMode", |inst| {
        if !inst.model_exchange {
            return inst.exit_initialization_mode();
        }
        me_core::exit_initialization_mode(inst, "fmi3ExitInitializationMode")
    })
}

pub unsafe fn fmi3EnterEventMode<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    // Model Exchange: the FMU has no events, so event mode changes nothing (an importer enters
    // it after initialization all the same).
    me::<M>(c, "fmi3EnterEventMode", |_| Ok(()))
}

pub unsafe fn fmi3Terminate<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    call::<M>(c, "fmi3Terminate", |inst| inst.terminate())
}

pub unsafe fn fmi3Reset<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    call::<M>(c, "fmi3Reset", |inst| inst.reset())
}

// ------------------------------------------------------------------------------ get and set

pub unsafe fn fmi3GetFloat64<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *mut fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    // The fast path of the core (as for fmi2GetReal), behind the panic barrier.
    if nValues == nvr {
        if let Some(status) = ffi::quick_get_real::<M, 3>(c, "fmi3GetFloat64", vr, nvr, value) {
            return status;
        }
    }
    // The independent variable `time` and the state derivatives (Model Exchange) are not in the
    // table: read them from the instance core.
    let extra = time_vr::<M>();
    if let (false, Some(vrs)) = (c.is_null(), ffi::slice(vr, nvr)) {
        if vrs.iter().any(|&r| r >= extra) && nValues == nvr && !value.is_null() {
            return call::<M>(c, "fmi3GetFloat64", |inst| {
                let mut dx = None;
                for (k, &r) in vrs.iter().enumerate() {
                    *value.add(k) = if r >= extra {
                        extra_value(inst, r, &mut dx)?
                    } else {
                        let mut x = f64::NAN;
                        inst.get("fmi3GetFloat64", VarType::Real, &[r], |_, v| x = v)?;
                        x
                    };
                }
                Ok(())
            });
        }
    }
    let (f, ty) = ("fmi3GetFloat64", VarType::Real);
    ffi::get_values::<Fmi3, M, _>(c, f, ty, vr, nvr, value, Some(nValues), |v| v)
}

/// `time`, or the derivative of a continuous state or a state's own variable.
fn extra_value<M: FmuModel>(
    inst: &mut Instance<M>,
    vr: u32,
    dx: &mut Option<Vec<f64>>,
) -> Result<f64, Failure> {
    let f = "fmi3GetFloat64";
    if vr == time_vr::<M>() {
        return Ok(inst.time());
    }
    me_core::state_value::<Fmi3, M>(inst, f, vr, dx)?.ok_or_else(|| {
        Failure::error(format!("{f}: value reference {vr} is not a variable of this FMU"))
    })
}

pub unsafe fn fmi3SetFloat64<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *const fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    if nValues == nvr && ffi::quick_set_real::<M, 3>(c, vr, nvr, value) {
        return fmi3Status_fmi3OK;
    }
    let (f, ty) = ("fmi3SetFloat64", VarType::Real);
    ffi::set_values::<Fmi3, M, _>(c, f, ty, vr, nvr, value, Some(nValues), |v| v)
}

typed_get_set! {
    fmi3GetInt32, fmi3SetInt32, fmi3Int32, fmi3Int32, Integer, |v: f64| v as i32, |v: i32| v as f64;
    // Set reads bytes: a C caller may pass any non-zero byte for true, which is not a valid Rust
    // bool.
    fmi3GetBoolean, fmi3SetBoolean, fmi3Boolean, u8, Boolean, |v: f64| v != 0.0,
        |v: u8| (v != 0) as i32 as f64;
}

no_variables! {
    fmi3GetFloat32, "Float32", (*mut fmi3Float32, usize);
    fmi3SetFloat32, "Float32", (*const fmi3Float32, usize);
    fmi3GetInt8, "Int8", (*mut fmi3Int8, usize);
    fmi3SetInt8, "Int8", (*const fmi3Int8, usize);
    fmi3GetUInt8, "UInt8", (*mut fmi3UInt8, usize);
    fmi3SetUInt8, "UInt8", (*const fmi3UInt8, usize);
    fmi3GetInt16, "Int16", (*mut fmi3Int16, usize);
    fmi3SetInt16, "Int16", (*const fmi3Int16, usize);
    fmi3GetUInt16, "UInt16", (*mut fmi3UInt16, usize);
    fmi3SetUInt16, "UInt16", (*const fmi3UInt16, usize);
    fmi3GetUInt32, "UInt32", (*mut fmi3UInt32, usize);
    fmi3SetUInt32, "UInt32", (*const fmi3UInt32, usize);
    fmi3GetInt64, "Int64", (*mut fmi3Int64, usize);
    fmi3SetInt64, "Int64", (*const fmi3Int64, usize);
    fmi3GetUInt64, "UInt64", (*mut fmi3UInt64, usize);
    fmi3SetUInt64, "UInt64", (*const fmi3UInt64, usize);
    fmi3GetString, "String", (*mut fmi3String, usize);
    fmi3SetString, "String", (*const fmi3String, usize);
    fmi3GetBinary, "Binary", (*mut usize, *mut fmi3Binary, usize);
    fmi3SetBinary, "Binary", (*const usize, *const fmi3Binary, usize);
    fmi3GetClock, "Clock", (*mut fmi3Clock);
    fmi3SetClock, "Clock", (*const fmi3Clock);
}

// ------------------------------------------------------------------------------ dependencies

/// The inputs an output depends on (the table's `depends_on`, as in `<ModelStructure>`); an
/// error for a value reference that is not an output.
fn dependencies<M: FmuModel>(function: &str, vr: fmi3ValueReference) -> Result<Vec<u32>, Failure> {
    crate::fmi::structure::dependencies_of::<M>(vr as usize).ok_or_else(|| {
        Failure::error(format!(
            "{function}: value reference {vr} is not an output, calculated parameter or state \
             derivative with declared dependencies"
        ))
    })
}

pub unsafe fn fmi3GetNumberOfVariableDependencies<M: FmuModel>(
    c: fmi3Instance,
    valueReference: fmi3ValueReference,
    nDependencies: *mut usize,
) -> fmi3Status {
    let f = "fmi3GetNumberOfVariableDependencies";
    call::<M>(c, f, |_| {
        if nDependencies.is_null() {
            return Err(null_argument(f, "nDependencies"));
        }
        *nDependencies = dependencies::<M>(f, valueReference)?.len();
        Ok(())
    })
}

pub unsafe fn fmi3GetVariableDependencies<M: FmuModel>(
    c: fmi3Instance,
    dependent: fmi3ValueReference,
    elementIndicesOfDependent: *mut usize,
    independents: *mut fmi3ValueReference,
    elementIndicesOfIndependents: *mut usize,
    dependencyKinds: *mut fmi3DependencyKind,
    nDependencies: usize,
) -> fmi3Status {
    let f = "fmi3GetVariableDependencies";
    call::<M>(c, f, |_| {
        let deps = dependencies::<M>(f, dependent)?;
        if nDependencies != deps.len() {
            return Err(Failure::error(format!(
                "{f}: nDependencies = {nDependencies}, but value reference {dependent} has {}",
                deps.len()
            )));
        }
        if !deps.is_empty()
            && (elementIndicesOfDependent.is_null()
                || independents.is_null()
                || elementIndicesOfIndependents.is_null()
                || dependencyKinds.is_null())
        {
            return Err(null_argument(f, "an output array"));
        }
        for (k, d) in deps.iter().enumerate() {
            // Scalars: element index 0 (FMI 3.0 §2.2.10: 0 means the whole variable).
            *elementIndicesOfDependent.add(k) = 0;
            *independents.add(k) = *d;
            *elementIndicesOfIndependents.add(k) = 0;
            *dependencyKinds.add(k) = fmi3DependencyKind_fmi3Dependent;
        }
        Ok(())
    })
}

// ------------------------------------------------------------------------------ FMU state

pub unsafe fn fmi3GetFMUState<M: FmuModel>(
    c: fmi3Instance,
    state: *mut fmi3FMUState,
) -> fmi3Status {
    ffi::get_fmu_state::<Fmi3, M>(c, "fmi3GetFMUState", state)
}

pub unsafe fn fmi3SetFMUState<M: FmuModel>(c: fmi3Instance, state: fmi3FMUState) -> fmi3Status {
    ffi::set_fmu_state::<Fmi3, M>(c, "fmi3SetFMUState", state)
}

pub unsafe fn fmi3FreeFMUState<M: FmuModel>(
    c: fmi3Instance,
    state: *mut fmi3FMUState,
) -> fmi3Status {
    ffi::free_fmu_state::<Fmi3, M>(c, "fmi3FreeFMUState", state)
}

pub unsafe fn fmi3SerializedFMUStateSize<M: FmuModel>(
    c: fmi3Instance,
    state: fmi3FMUState,
    size: *mut usize,
) -> fmi3Status {
    ffi::serialized_size::<Fmi3, M>(c, "fmi3SerializedFMUStateSize", state, size)
}

pub unsafe fn fmi3SerializeFMUState<M: FmuModel>(
    c: fmi3Instance,
    state: fmi3FMUState,
    bytes: *mut fmi3Byte,
    size: usize,
) -> fmi3Status {
    ffi::serialize::<Fmi3, M>(c, "fmi3SerializeFMUState", state, bytes, size)
}

pub unsafe fn fmi3DeserializeFMUState<M: FmuModel>(
    c: fmi3Instance,
    bytes: *const fmi3Byte,
    size: usize,
    state: *mut fmi3FMUState,
) -> fmi3Status {
    ffi::deserialize::<Fmi3, M>(c, "fmi3DeserializeFMUState", bytes, size, state)
}

// ------------------------------------------------------------------------------ derivatives

pub unsafe fn fmi3GetDirectionalDerivative<M: FmuModel>(
    c: fmi3Instance,
    unknowns: *const fmi3ValueReference,
    nUnknowns: usize,
    knowns: *const fmi3ValueReference,
    nKnowns: usize,
    seed: *const fmi3Float64,
    nSeed: usize,
    sensitivity: *mut fmi3Float64,
    nSensitivity: usize,
) -> fmi3Status {
    let (f, counts) = ("fmi3GetDirectionalDerivative", Some((nSeed, nSensitivity)));
    ffi::get_directional_derivative::<Fmi3, M>(
        c,
        f,
        unknowns,
        nUnknowns,
        knowns,
        nKnowns,
        seed,
        sensitivity,
        counts,
    )
}

unsupported! {
    fmi3GetAdjointDerivative(*const fmi3ValueReference, usize, *const fmi3ValueReference, usize, *const fmi3Float64, usize, *mut fmi3Float64, usize)
        => "not provided by this FMU (providesAdjointDerivatives=\"false\")";
    fmi3GetOutputDerivatives(*const fmi3ValueReference, usize, *const fmi3Int32, *mut fmi3Float64, usize)
        => "not supported (maxOutputDerivativeOrder=\"0\")";
    fmi3EnterConfigurationMode() => NO_STRUCTURAL;
    fmi3ExitConfigurationMode() => NO_STRUCTURAL;
    fmi3GetIntervalDecimal(*const fmi3ValueReference, usize, *mut fmi3Float64, *mut fmi3IntervalQualifier) => NO_CLOCKS;
    fmi3GetIntervalFraction(*const fmi3ValueReference, usize, *mut fmi3UInt64, *mut fmi3UInt64, *mut fmi3IntervalQualifier) => NO_CLOCKS;
    fmi3GetShiftDecimal(*const fmi3ValueReference, usize, *mut fmi3Float64) => NO_CLOCKS;
    fmi3GetShiftFraction(*const fmi3ValueReference, usize, *mut fmi3UInt64, *mut fmi3UInt64) => NO_CLOCKS;
    fmi3SetIntervalDecimal(*const fmi3ValueReference, usize, *const fmi3Float64) => NO_CLOCKS;
    fmi3SetIntervalFraction(*const fmi3ValueReference, usize, *const fmi3UInt64, *const fmi3UInt64) => NO_CLOCKS;
    fmi3SetShiftDecimal(*const fmi3ValueReference, usize, *const fmi3Float64) => NO_CLOCKS;
    fmi3SetShiftFraction(*const fmi3ValueReference, usize, *const fmi3UInt64, *const fmi3UInt64) => NO_CLOCKS;
    // Only from event mode, which this FMU never enters in co-simulation:
    // fmi3ExitInitializationMode goes straight to step mode.
    fmi3EnterStepMode() => NO_EVENTS;
    fmi3ActivateModelPartition(fmi3ValueReference, fmi3Float64) => NO_CLOCKS;
}

// ------------------------------------------------------------------------------ discrete states

pub unsafe fn fmi3EvaluateDiscreteStates<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    me::<M>(c, "fmi3EvaluateDiscreteStates", |_| Ok(()))
}

pub unsafe fn fmi3UpdateDiscreteStates<M: FmuModel>(
    c: fmi3Instance,
    discreteStatesNeedUpdate: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    nominalsOfContinuousStatesChanged: *mut fmi3Boolean,
    valuesOfContinuousStatesChanged: *mut fmi3Boolean,
    nextEventTimeDefined: *mut fmi3Boolean,
    _nextEventTime: *mut fmi3Float64,
) -> fmi3Status {
    // No discrete states and no events: nothing to update, no time event.
    me::<M>(c, "fmi3UpdateDiscreteStates", |_| {
        for p in [
            discreteStatesNeedUpdate,
            terminateSimulation,
            nominalsOfContinuousStatesChanged,
            valuesOfContinuousStatesChanged,
            nextEventTimeDefined,
        ] {
            if p.is_null() {
                return Err(null_argument("fmi3UpdateDiscreteStates", "an output argument"));
            }
            *p = false;
        }
        Ok(())
    })
}

// ------------------------------------------------------------------------------ model exchange:
// not declared in FMI 3.0 by this FMU

/// Runs a Model Exchange function: the instance must have been instantiated for Model Exchange
/// and be initialized (the core's step mode stands for event and continuous-time mode: without
/// events the two differ in nothing this FMU does).
unsafe fn me<M: FmuModel>(
    c: fmi3Instance,
    function: &str,
    f: impl FnOnce(&mut Instance<M>) -> Result<(), Failure>,
) -> fmi3Status {
    call::<M>(c, function, |inst| {
        if !inst.model_exchange {
            return Err(Failure::error(format!("{function}: {NOT_ME_INSTANCE}")));
        }
        if inst.mode() != Mode::StepComplete {
            return Err(Failure::illegal(function, inst.mode()));
        }
        f(inst)
    })
}

pub unsafe fn fmi3EnterContinuousTimeMode<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    me::<M>(c, "fmi3EnterContinuousTimeMode", |_| Ok(()))
}

pub unsafe fn fmi3CompletedIntegratorStep<M: FmuModel>(
    c: fmi3Instance,
    _noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
    enterEventMode: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
) -> fmi3Status {
    let f = "fmi3CompletedIntegratorStep";
    me::<M>(c, f, |_| me_core::completed_integrator_step(f, enterEventMode, terminateSimulation))
}

pub unsafe fn fmi3SetTime<M: FmuModel>(c: fmi3Instance, time: fmi3Float64) -> fmi3Status {
    me::<M>(c, "fmi3SetTime", |inst| me_core::set_time(inst, "fmi3SetTime", time))
}

pub unsafe fn fmi3SetContinuousStates<M: FmuModel>(
    c: fmi3Instance,
    x: *const fmi3Float64,
    nx: usize,
) -> fmi3Status {
    let f = "fmi3SetContinuousStates";
    me::<M>(c, f, |inst| me_core::set_continuous_states::<Fmi3, M>(inst, f, x, nx))
}

pub unsafe fn fmi3GetContinuousStateDerivatives<M: FmuModel>(
    c: fmi3Instance,
    derivatives: *mut fmi3Float64,
    nx: usize,
) -> fmi3Status {
    let f = "fmi3GetContinuousStateDerivatives";
    me::<M>(c, f, |inst| me_core::get_derivatives::<Fmi3, M>(inst, f, derivatives, nx))
}

pub unsafe fn fmi3GetEventIndicators<M: FmuModel>(
    c: fmi3Instance,
    _indicators: *mut fmi3Float64,
    n: usize,
) -> fmi3Status {
    // No event indicators: the motor's torque curve and the load are smooth in the states.
    me::<M>(c, "fmi3GetEventIndicators", |_| {
        if n != 0 {
            return Err(Failure::error(format!(
                "fmi3GetEventIndicators: nEventIndicators = {n}; this FMU has none"
            )));
        }
        Ok(())
    })
}

pub unsafe fn fmi3GetContinuousStates<M: FmuModel>(
    c: fmi3Instance,
    x: *mut fmi3Float64,
    nx: usize,
) -> fmi3Status {
    let f = "fmi3GetContinuousStates";
    me::<M>(c, f, |inst| me_core::get_continuous_states::<Fmi3, M>(inst, f, x, nx))
}

pub unsafe fn fmi3GetNominalsOfContinuousStates<M: FmuModel>(
    c: fmi3Instance,
    nominals: *mut fmi3Float64,
    nx: usize,
) -> fmi3Status {
    let f = "fmi3GetNominalsOfContinuousStates";
    me::<M>(c, f, |_| me_core::get_nominals::<Fmi3, M>(f, nominals, nx))
}

pub unsafe fn fmi3GetNumberOfEventIndicators<M: FmuModel>(
    c: fmi3Instance,
    n: *mut usize,
) -> fmi3Status {
    number_of::<M>(c, "fmi3GetNumberOfEventIndicators", "nEventIndicators", n, 0)
}

pub unsafe fn fmi3GetNumberOfContinuousStates<M: FmuModel>(
    c: fmi3Instance,
    n: *mut usize,
) -> fmi3Status {
    number_of::<M>(
        c,
        "fmi3GetNumberOfContinuousStates",
        "nContinuousStates",
        n,
        M::CONTINUOUS_STATES.len(),
    )
}

/// fmi3GetNumberOf…: `value` into the importer's `n` (named `what`).
unsafe fn number_of<M: FmuModel>(
    c: fmi3Instance,
    function: &str,
    what: &str,
    n: *mut usize,
    value: usize,
) -> fmi3Status {
    call::<M>(c, function, |_| {
        if n.is_null() {
            return Err(null_argument(function, what));
        }
        *n = value;
        Ok(())
    })
}

// ------------------------------------------------------------------------------ co-simulation

pub unsafe fn fmi3DoStep<M: FmuModel>(
    c: fmi3Instance,
    currentCommunicationPoint: fmi3Float64,
    communicationStepSize: fmi3Float64,
    _noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
    eventHandlingNeeded: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    earlyReturn: *mut fmi3Boolean,
    lastSuccessfulTime: *mut fmi3Float64,
) -> fmi3Status {
    let outs_ok = !eventHandlingNeeded.is_null()
        && !terminateSimulation.is_null()
        && !earlyReturn.is_null()
        && !lastSuccessfulTime.is_null();
    // A rigid mechanism's ordinary step takes the core's fast path (as fmi2DoStep).
    let done = outs_ok
        && live::<M>(c)
            .is_some_and(|i| (*i).quick_step(currentCommunicationPoint, communicationStepSize));
    let status = if done {
        fmi3Status_fmi3OK
    } else {
        call::<M>(c, "fmi3DoStep", |inst| {
            if inst.model_exchange {
                return Err(Failure::error(
                    "fmi3DoStep: an instance for Model Exchange does not step (fmi3DoStep is \
                     co-simulation's)",
                ));
            }
            if !outs_ok {
                return Err(null_argument(
                    "fmi3DoStep",
                    "eventHandlingNeeded, terminateSimulation, earlyReturn or lastSuccessfulTime",
                ));
            }
            inst.do_step(currentCommunicationPoint, communicationStepSize)
        })
    };
    if let (true, Some(inst)) = (outs_ok, live::<M>(c)) {
        // No events, no request to stop, never early: a failed step leaves the time as it was.
        *eventHandlingNeeded = false;
        *terminateSimulation = false;
        *earlyReturn = false;
        *lastSuccessfulTime = (*inst).time();
    }
    status
}

// ------------------------------------------------------------------------------ exports

/// Exports every FMI 3.0 function for one model: put
/// `reciprocating_drive::export_fmu3!(path::to::Model);` in the root of that FMU's cdylib crate
/// (beside `export_fmu!`: one shared object serves the FMI 2.0 and the FMI 3.0 FMU). Each export
/// is a thin `extern "C"` shim over the generic function of this module, and its type is checked
/// at compile time against the official FMI 3.0 headers (`fmi3…TYPE`).
#[macro_export]
macro_rules! export_fmu3 {
    ($model:ty) => {
        const _: () = {
            use $crate::fmi3::abi as glue;
            use $crate::fmi_sys::fmi3::*;
            use ::std::ffi::c_char;
            type M = $model;
            type C = fmi3Instance;
            type S = fmi3Status;
            type Vr = *const fmi3ValueReference;

            $crate::__fmi_exports! {
                fmi3GetVersion: fmi3GetVersionTYPE() -> *const c_char;
                fmi3SetDebugLogging: fmi3SetDebugLoggingTYPE(c: C, loggingOn: fmi3Boolean, nCategories: usize, categories: *const fmi3String) -> S;
                fmi3InstantiateModelExchange: fmi3InstantiateModelExchangeTYPE(instanceName: fmi3String, instantiationToken: fmi3String, resourcePath: fmi3String, visible: fmi3Boolean, loggingOn: fmi3Boolean, instanceEnvironment: fmi3InstanceEnvironment, logMessage: fmi3LogMessageCallback) -> C;
                fmi3InstantiateCoSimulation: fmi3InstantiateCoSimulationTYPE(instanceName: fmi3String, instantiationToken: fmi3String, resourcePath: fmi3String, visible: fmi3Boolean, loggingOn: fmi3Boolean, eventModeUsed: fmi3Boolean, earlyReturnAllowed: fmi3Boolean, requiredIntermediateVariables: Vr, nRequiredIntermediateVariables: usize, instanceEnvironment: fmi3InstanceEnvironment, logMessage: fmi3LogMessageCallback, intermediateUpdate: fmi3IntermediateUpdateCallback) -> C;
                fmi3InstantiateScheduledExecution: fmi3InstantiateScheduledExecutionTYPE(instanceName: fmi3String, instantiationToken: fmi3String, resourcePath: fmi3String, visible: fmi3Boolean, loggingOn: fmi3Boolean, instanceEnvironment: fmi3InstanceEnvironment, logMessage: fmi3LogMessageCallback, clockUpdate: fmi3ClockUpdateCallback, lockPreemption: fmi3LockPreemptionCallback, unlockPreemption: fmi3UnlockPreemptionCallback) -> C;
                fmi3FreeInstance: fmi3FreeInstanceTYPE(c: C) -> ();
                fmi3EnterInitializationMode: fmi3EnterInitializationModeTYPE(c: C, toleranceDefined: fmi3Boolean, tolerance: fmi3Float64, startTime: fmi3Float64, stopTimeDefined: fmi3Boolean, stopTime: fmi3Float64) -> S;
                fmi3ExitInitializationMode: fmi3ExitInitializationModeTYPE(c: C) -> S;
                fmi3EnterEventMode: fmi3EnterEventModeTYPE(c: C) -> S;
                fmi3Terminate: fmi3TerminateTYPE(c: C) -> S;
                fmi3Reset: fmi3ResetTYPE(c: C) -> S;
                fmi3GetFloat64: fmi3GetFloat64TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3Float64, nValues: usize) -> S;
                fmi3SetFloat64: fmi3SetFloat64TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3Float64, nValues: usize) -> S;
                fmi3GetInt32: fmi3GetInt32TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3Int32, nValues: usize) -> S;
                fmi3SetInt32: fmi3SetInt32TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3Int32, nValues: usize) -> S;
                fmi3GetBoolean: fmi3GetBooleanTYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3Boolean, nValues: usize) -> S;
                fmi3SetBoolean: fmi3SetBooleanTYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3Boolean, nValues: usize) -> S;
                fmi3GetBinary: fmi3GetBinaryTYPE(c: C, vr: Vr, nvr: usize, valueSizes: *mut usize, values: *mut fmi3Binary, nValues: usize) -> S;
                fmi3SetBinary: fmi3SetBinaryTYPE(c: C, vr: Vr, nvr: usize, valueSizes: *const usize, values: *const fmi3Binary, nValues: usize) -> S;
                fmi3GetClock: fmi3GetClockTYPE(c: C, vr: Vr, nvr: usize, values: *mut fmi3Clock) -> S;
                fmi3SetClock: fmi3SetClockTYPE(c: C, vr: Vr, nvr: usize, values: *const fmi3Clock) -> S;
                fmi3GetNumberOfVariableDependencies: fmi3GetNumberOfVariableDependenciesTYPE(c: C, valueReference: fmi3ValueReference, nDependencies: *mut usize) -> S;
                fmi3GetVariableDependencies: fmi3GetVariableDependenciesTYPE(c: C, dependent: fmi3ValueReference, elementIndicesOfDependent: *mut usize, independents: *mut fmi3ValueReference, elementIndicesOfIndependents: *mut usize, dependencyKinds: *mut fmi3DependencyKind, nDependencies: usize) -> S;
                fmi3GetFMUState: fmi3GetFMUStateTYPE(c: C, state: *mut fmi3FMUState) -> S;
                fmi3SetFMUState: fmi3SetFMUStateTYPE(c: C, state: fmi3FMUState) -> S;
                fmi3FreeFMUState: fmi3FreeFMUStateTYPE(c: C, state: *mut fmi3FMUState) -> S;
                fmi3SerializedFMUStateSize: fmi3SerializedFMUStateSizeTYPE(c: C, state: fmi3FMUState, size: *mut usize) -> S;
                fmi3SerializeFMUState: fmi3SerializeFMUStateTYPE(c: C, state: fmi3FMUState, bytes: *mut fmi3Byte, size: usize) -> S;
                fmi3DeserializeFMUState: fmi3DeserializeFMUStateTYPE(c: C, bytes: *const fmi3Byte, size: usize, state: *mut fmi3FMUState) -> S;
                fmi3GetDirectionalDerivative: fmi3GetDirectionalDerivativeTYPE(c: C, unknowns: Vr, nUnknowns: usize, knowns: Vr, nKnowns: usize, seed: *const fmi3Float64, nSeed: usize, sensitivity: *mut fmi3Float64, nSensitivity: usize) -> S;
                fmi3GetAdjointDerivative: fmi3GetAdjointDerivativeTYPE(c: C, unknowns: Vr, nUnknowns: usize, knowns: Vr, nKnowns: usize, seed: *const fmi3Float64, nSeed: usize, sensitivity: *mut fmi3Float64, nSensitivity: usize) -> S;
                fmi3GetOutputDerivatives: fmi3GetOutputDerivativesTYPE(c: C, vr: Vr, nvr: usize, orders: *const fmi3Int32, values: *mut fmi3Float64, nValues: usize) -> S;
                fmi3EnterConfigurationMode: fmi3EnterConfigurationModeTYPE(c: C) -> S;
                fmi3ExitConfigurationMode: fmi3ExitConfigurationModeTYPE(c: C) -> S;
                fmi3GetIntervalDecimal: fmi3GetIntervalDecimalTYPE(c: C, vr: Vr, nvr: usize, intervals: *mut fmi3Float64, qualifiers: *mut fmi3IntervalQualifier) -> S;
                fmi3GetIntervalFraction: fmi3GetIntervalFractionTYPE(c: C, vr: Vr, nvr: usize, counters: *mut fmi3UInt64, resolutions: *mut fmi3UInt64, qualifiers: *mut fmi3IntervalQualifier) -> S;
                fmi3GetShiftDecimal: fmi3GetShiftDecimalTYPE(c: C, vr: Vr, nvr: usize, shifts: *mut fmi3Float64) -> S;
                fmi3GetShiftFraction: fmi3GetShiftFractionTYPE(c: C, vr: Vr, nvr: usize, counters: *mut fmi3UInt64, resolutions: *mut fmi3UInt64) -> S;
                fmi3SetIntervalDecimal: fmi3SetIntervalDecimalTYPE(c: C, vr: Vr, nvr: usize, intervals: *const fmi3Float64) -> S;
                fmi3SetIntervalFraction: fmi3SetIntervalFractionTYPE(c: C, vr: Vr, nvr: usize, counters: *const fmi3UInt64, resolutions: *const fmi3UInt64) -> S;
                fmi3SetShiftDecimal: fmi3SetShiftDecimalTYPE(c: C, vr: Vr, nvr: usize, shifts: *const fmi3Float64) -> S;
                fmi3SetShiftFraction: fmi3SetShiftFractionTYPE(c: C, vr: Vr, nvr: usize, counters: *const fmi3UInt64, resolutions: *const fmi3UInt64) -> S;
                fmi3EvaluateDiscreteStates: fmi3EvaluateDiscreteStatesTYPE(c: C) -> S;
                fmi3UpdateDiscreteStates: fmi3UpdateDiscreteStatesTYPE(c: C, discreteStatesNeedUpdate: *mut fmi3Boolean, terminateSimulation: *mut fmi3Boolean, nominalsOfContinuousStatesChanged: *mut fmi3Boolean, valuesOfContinuousStatesChanged: *mut fmi3Boolean, nextEventTimeDefined: *mut fmi3Boolean, nextEventTime: *mut fmi3Float64) -> S;
                fmi3EnterContinuousTimeMode: fmi3EnterContinuousTimeModeTYPE(c: C) -> S;
                fmi3CompletedIntegratorStep: fmi3CompletedIntegratorStepTYPE(c: C, noSetFMUStatePriorToCurrentPoint: fmi3Boolean, enterEventMode: *mut fmi3Boolean, terminateSimulation: *mut fmi3Boolean) -> S;
                fmi3SetTime: fmi3SetTimeTYPE(c: C, time: fmi3Float64) -> S;
                fmi3SetContinuousStates: fmi3SetContinuousStatesTYPE(c: C, x: *const fmi3Float64, nx: usize) -> S;
                fmi3GetContinuousStateDerivatives: fmi3GetContinuousStateDerivativesTYPE(c: C, derivatives: *mut fmi3Float64, nx: usize) -> S;
                fmi3GetEventIndicators: fmi3GetEventIndicatorsTYPE(c: C, indicators: *mut fmi3Float64, n: usize) -> S;
                fmi3GetContinuousStates: fmi3GetContinuousStatesTYPE(c: C, x: *mut fmi3Float64, nx: usize) -> S;
                fmi3GetNominalsOfContinuousStates: fmi3GetNominalsOfContinuousStatesTYPE(c: C, nominals: *mut fmi3Float64, nx: usize) -> S;
                fmi3GetNumberOfEventIndicators: fmi3GetNumberOfEventIndicatorsTYPE(c: C, n: *mut usize) -> S;
                fmi3GetNumberOfContinuousStates: fmi3GetNumberOfContinuousStatesTYPE(c: C, n: *mut usize) -> S;
                fmi3EnterStepMode: fmi3EnterStepModeTYPE(c: C) -> S;
                fmi3DoStep: fmi3DoStepTYPE(c: C, currentCommunicationPoint: fmi3Float64, communicationStepSize: fmi3Float64, noSetFMUStatePriorToCurrentPoint: fmi3Boolean, eventHandlingNeeded: *mut fmi3Boolean, terminateSimulation: *mut fmi3Boolean, earlyReturn: *mut fmi3Boolean, lastSuccessfulTime: *mut fmi3Float64) -> S;
                fmi3ActivateModelPartition: fmi3ActivateModelPartitionTYPE(c: C, clockReference: fmi3ValueReference, activationTime: fmi3Float64) -> S;
                fmi3GetFloat32: fmi3GetFloat32TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3Float32, nValues: usize) -> S;
                fmi3SetFloat32: fmi3SetFloat32TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3Float32, nValues: usize) -> S;
                fmi3GetInt8: fmi3GetInt8TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3Int8, nValues: usize) -> S;
                fmi3SetInt8: fmi3SetInt8TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3Int8, nValues: usize) -> S;
                fmi3GetUInt8: fmi3GetUInt8TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3UInt8, nValues: usize) -> S;
                fmi3SetUInt8: fmi3SetUInt8TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3UInt8, nValues: usize) -> S;
                fmi3GetInt16: fmi3GetInt16TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3Int16, nValues: usize) -> S;
                fmi3SetInt16: fmi3SetInt16TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3Int16, nValues: usize) -> S;
                fmi3GetUInt16: fmi3GetUInt16TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3UInt16, nValues: usize) -> S;
                fmi3SetUInt16: fmi3SetUInt16TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3UInt16, nValues: usize) -> S;
                fmi3GetUInt32: fmi3GetUInt32TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3UInt32, nValues: usize) -> S;
                fmi3SetUInt32: fmi3SetUInt32TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3UInt32, nValues: usize) -> S;
                fmi3GetInt64: fmi3GetInt64TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3Int64, nValues: usize) -> S;
                fmi3SetInt64: fmi3SetInt64TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3Int64, nValues: usize) -> S;
                fmi3GetUInt64: fmi3GetUInt64TYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3UInt64, nValues: usize) -> S;
                fmi3SetUInt64: fmi3SetUInt64TYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3UInt64, nValues: usize) -> S;
                fmi3GetString: fmi3GetStringTYPE(c: C, vr: Vr, nvr: usize, value: *mut fmi3String, nValues: usize) -> S;
                fmi3SetString: fmi3SetStringTYPE(c: C, vr: Vr, nvr: usize, value: *const fmi3String, nValues: usize) -> S;
            }
        };
    };
}
