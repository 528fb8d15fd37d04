//! Every FMI 3.0 function, generic over the model: a thin layer over the same instance core as
//! FMI 2.0 ([`Instance`]: state machine, get/set, FMU states, logging), so both standards run the
//! same code and give the same numbers (docs/fmi-interface.md "FMI 3.0").
//!
//! Co-simulation for every FMU; Model Exchange where the model declares it
//! ([`FmuModel::MODEL_EXCHANGE`]: the DriveTrain with its states, the pump's rigid mechanisms
//! without any); no event mode in co-simulation, no events,
//! no clocks, one Float64/Int32/Boolean scalar per value reference. Every function of `fmi3Functions.h` is exported, so an importer
//! that binds them all finds them; those of interfaces this FMU does not declare fail with a
//! message saying why. [`export_fmu3!`](crate::export_fmu3) instantiates them for one model as
//! `#[no_mangle] extern "C"` functions, their types checked at compile time against the types
//! bindgen generated from the official FMI 3.0 headers (`fmi3…TYPE`).

#![allow(non_snake_case)]
#![allow(clippy::missing_safety_doc)]
#![allow(clippy::too_many_arguments)]

use std::ffi::{c_char, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr;

use fmi_sys::fmi3::*;

use crate::fmi::ffi::{opt_str, slice, snapshot_ref, store_snapshot};
use crate::fmi::fmu_state;
use crate::fmi::handle::{free_instance, live, new_handle, report_freed};
use crate::fmi::instance::{
    copy_name, snapshot_magic, Failure, Instance, Mode, Severity, Snapshot,
};
use crate::fmi::logging::{Category, Logger};
use crate::fmi::model::FmuModel;
use crate::fmi::structure::time_vr;
use crate::fmi::variables::VarType;
use crate::fmi3::model_description::token;
use std::path::PathBuf;

static VERSION: &CStr = c"3.0";

fn status_of(s: Severity) -> fmi3Status {
    match s {
        Severity::Discard => fmi3Status_fmi3Discard,
        Severity::Error => fmi3Status_fmi3Error,
        Severity::Fatal => fmi3Status_fmi3Fatal,
    }
}

/// Runs `f` on the instance behind `c`: NULL and freed-instance check, panic barrier, status and
/// logging (the logger translates the core's FMI 2.0 names, [`dialect`]).
unsafe fn call<M: FmuModel>(
    c: fmi3Instance,
    function: &str,
    f: impl FnOnce(&mut Instance<M>) -> Result<(), Failure>,
) -> fmi3Status {
    let Some(inst) = live::<M>(c) else {
        if !c.is_null() {
            report_freed::<M>(c, function);
        }
        return fmi3Status_fmi3Error;
    };
    match catch_unwind(AssertUnwindSafe(|| f(&mut *inst))) {
        Ok(Ok(())) => {
            (*inst).log(fmi3Status_fmi3OK, Category::Calls, function);
            fmi3Status_fmi3OK
        }
        Ok(Err(failure)) => {
            let status = status_of(failure.severity);
            let category = if failure.severity == Severity::Discard {
                Category::Warning
            } else {
                Category::Error
            };
            // Every message names the function that failed.
            if failure.message.starts_with("fmi") {
                (*inst).log(status, category, &failure.message);
            } else {
                (*inst).log(status, category, &format!("{function}: {}", failure.message));
            }
            status
        }
        Err(_) => panicked(inst, function),
    }
}

#[cold]
#[inline(never)]
unsafe fn panicked<M: FmuModel>(inst: *mut Instance<M>, function: &str) -> fmi3Status {
    let _ = catch_unwind(AssertUnwindSafe(|| {
        (*inst).set_fatal();
        (*inst).log(
            fmi3Status_fmi3Fatal,
            Category::Error,
            &format!("{function}: internal error (panic caught)"),
        );
    }));
    fmi3Status_fmi3Fatal
}

fn null_argument(function: &str, what: &str) -> Failure {
    Failure::error(format!("{function}: {what} is NULL"))
}

/// A function of an interface or feature this FMU does not declare.
unsafe fn unsupported<M: FmuModel>(c: fmi3Instance, function: &str, why: &str) -> fmi3Status {
    call::<M>(c, function, |_| Err(Failure::error(format!("{function}: {why}"))))
}

const NOT_ME: &str = "this FMU offers no Model Exchange (no <ModelExchange> element)";
const NO_CLOCKS: &str = "this FMU has no clocks";
const NO_EVENTS: &str = "this FMU has no event mode (hasEventMode=\"false\")";
const NOT_ME_INSTANCE: &str = "not an instance for Model Exchange (fmi3InstantiateModelExchange)";

// ------------------------------------------------------------------------------ common functions

#[inline]
pub fn fmi3GetVersion() -> *const c_char {
    VERSION.as_ptr()
}

pub unsafe fn fmi3SetDebugLogging<M: FmuModel>(
    c: fmi3Instance,
    loggingOn: fmi3Boolean,
    nCategories: usize,
    categories: *const fmi3String,
) -> fmi3Status {
    call::<M>(c, "fmi3SetDebugLogging", |inst| {
        let cats = slice(categories, nCategories)
            .ok_or_else(|| null_argument("fmi3SetDebugLogging", "categories"))?;
        let mut names = Vec::with_capacity(cats.len());
        for &p in cats {
            names.push(
                opt_str(p)
                    .ok_or_else(|| null_argument("fmi3SetDebugLogging", "a category name"))?,
            );
        }
        inst.logger
            .set_debug_logging(loggingOn, &names)
            .map_err(|e| Failure::error(format!("fmi3SetDebugLogging: {e}")))
    })
}

/// FMI 3.0 passes the resources folder as a native path with a trailing separator (FMI 2.0: a
/// file URI); NULL or empty: none.
fn resource_path(p: Option<&str>) -> Option<PathBuf> {
    let p = p?;
    let trimmed = p.trim_end_matches(['/', '\\']);
    match (p.is_empty(), trimmed.is_empty()) {
        (true, _) => None,
        (false, true) => Some(PathBuf::from(&p[..1])),
        (false, false) => Some(PathBuf::from(trimmed)),
    }
}

/// What the three fmi3Instantiate… functions share: the logger, the instance name, the token.
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
    let result = catch_unwind(AssertUnwindSafe(|| {
        let name = opt_str(instanceName).unwrap_or("");
        let logger = Logger::new_fmi3(logMessage, instanceEnvironment, copy_name(name), loggingOn);
        let refuse = |why: String| {
            logger.log(fmi3Status_fmi3Error, Category::Error, &format!("{function}: {why}"));
            ptr::null_mut()
        };
        if let Some(why) = refusal {
            return refuse(why);
        }
        if name.is_empty() {
            return refuse("instanceName is NULL or empty".into());
        }
        match opt_str(instantiationToken) {
            Some(g) if g == token::<M>() => {}
            other => {
                return refuse(format!(
                    "instantiationToken {:?} is not this FMU's {}",
                    other.unwrap_or("NULL"),
                    token::<M>()
                ))
            }
        }
        let dir = resource_path(opt_str(resourcePath));
        let mut inst = Box::new(Instance::<M>::new(logger, dir));
        inst.model_exchange = model_exchange;
        inst.log(
            fmi3Status_fmi3OK,
            Category::Events,
            &format!("instantiated; resources: {:?}", inst.resource_dir),
        );
        new_handle(inst)
    }));
    result.unwrap_or(ptr::null_mut())
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
        // A failed call leaves the instance as it was (in initialization mode, with its values).
        let before = inst.snapshot();
        inst.exit_initialization_mode()?;
        let refusal = inst.me_parts().and_then(|(built, _, _)| M::model_exchange_refusal(built));
        if let Some(why) = refusal {
            inst.restore(&before)?;
            return Err(Failure::error(format!("fmi3ExitInitializationMode: {why}")));
        }
        Ok(())
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

/// FMI 3.0 passes the length of the values array too: with scalar variables only it must equal
/// the number of value references.
fn check_count(function: &str, nvr: usize, nValues: usize) -> Result<(), Failure> {
    if nValues != nvr {
        return Err(Failure::error(format!(
            "{function}: nValues = {nValues} does not match nValueReferences = {nvr} (every \
             variable of this FMU is a scalar)"
        )));
    }
    Ok(())
}

#[inline(never)]
unsafe fn get_values<M: FmuModel, T: Copy>(
    c: fmi3Instance,
    function: &'static str,
    ty: VarType,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *mut T,
    nValues: usize,
    convert: impl Fn(f64) -> T,
) -> fmi3Status {
    call::<M>(c, function, |inst| {
        let vrs = slice(vr, nvr).ok_or_else(|| null_argument(function, "valueReferences"))?;
        check_count(function, nvr, nValues)?;
        if nvr > 0 && value.is_null() {
            return Err(null_argument(function, "values"));
        }
        inst.get(function, ty, vrs, |k, v| *value.add(k) = convert(v))
    })
}

#[inline(never)]
unsafe fn set_values<M: FmuModel, T: Copy>(
    c: fmi3Instance,
    function: &'static str,
    ty: VarType,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *const T,
    nValues: usize,
    convert: impl Fn(T) -> f64,
) -> fmi3Status {
    call::<M>(c, function, |inst| {
        let vrs = slice(vr, nvr).ok_or_else(|| null_argument(function, "valueReferences"))?;
        check_count(function, nvr, nValues)?;
        let vals = slice(value, nvr).ok_or_else(|| null_argument(function, "values"))?;
        inst.set(function, ty, vrs, |k| convert(vals[k]))
    })
}

/// Get/set of a type this FMU has no variable of: only an empty list is accepted.
unsafe fn no_variables<M: FmuModel>(
    c: fmi3Instance,
    function: &str,
    type_name: &str,
    vr: *const fmi3ValueReference,
    nvr: usize,
) -> fmi3Status {
    call::<M>(c, function, |_| match slice(vr, nvr) {
        Some([]) => Ok(()),
        Some(v) => Err(Failure::error(format!(
            "{function}: value reference {} is not a {type_name} variable (this FMU has none; \
             its variables are Float64, Int32 and Boolean)",
            v[0]
        ))),
        None => Err(null_argument(function, "valueReferences")),
    })
}

pub unsafe fn fmi3GetFloat64<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *mut fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    // The fast path of the core (as for fmi2GetReal), behind the panic barrier.
    if let (Some(inst), Some(vrs), false, true) =
        (live::<M>(c), slice(vr, nvr), nvr > 0 && value.is_null(), nValues == nvr)
    {
        let out: &mut [fmi3Float64] =
            if nvr == 0 { &mut [] } else { std::slice::from_raw_parts_mut(value, nvr) };
        match catch_unwind(AssertUnwindSafe(|| (*inst).quick_get_real(vrs, out))) {
            Ok(true) => return fmi3Status_fmi3OK,
            Ok(false) => {}
            Err(_) => return panicked(inst, "fmi3GetFloat64"),
        }
    }
    // The independent variable `time` and the state derivatives (Model Exchange) are not in the
    // table: read them from the instance core.
    let extra = time_vr::<M>();
    if let (false, Some(vrs)) = (c.is_null(), slice(vr, nvr)) {
        if vrs.iter().any(|&r| r >= extra) && nValues == nvr && !value.is_null() {
            return call::<M>(c, "fmi3GetFloat64", |inst| {
                for (k, &r) in vrs.iter().enumerate() {
                    *value.add(k) = if r >= extra {
                        extra_value(inst, r)?
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
    get_values::<M, _>(c, "fmi3GetFloat64", VarType::Real, vr, nvr, value, nValues, |v| v)
}

/// `time`, or the derivative of a continuous state (after initialization).
fn extra_value<M: FmuModel>(inst: &mut Instance<M>, vr: u32) -> Result<f64, Failure> {
    let f = "fmi3GetFloat64";
    let n = M::CONTINUOUS_STATES.len();
    if vr == time_vr::<M>() {
        return Ok(inst.time());
    }
    let k = (vr - time_vr::<M>() - 1) as usize;
    // A state's own variable (FmuModel::STATE_VARIABLES), after the derivatives.
    if k >= n && k < 2 * n && crate::fmi::structure::own_state::<M>(k - n).is_some() {
        let (_, _, state) = inst.me_parts_initial()?.ok_or_else(|| {
            Failure::error(format!(
                "{f}: {} is not available before fmi3EnterInitializationMode",
                M::CONTINUOUS_STATES[k - n].0
            ))
        })?;
        let mut x = vec![0.0; n];
        M::continuous_states(state, &mut x);
        return Ok(x[k - n]);
    }
    if k >= n {
        return Err(Failure::error(format!(
            "{f}: value reference {vr} is not a variable of this FMU"
        )));
    }
    let (built, values, state) = inst.me_parts_initial()?.ok_or_else(|| {
        Failure::error(format!(
            "{f}: der({}) is not available before fmi3EnterInitializationMode",
            M::CONTINUOUS_STATES[k].0
        ))
    })?;
    let mut dx = vec![0.0; n];
    M::derivatives(built, values, state, &mut dx)?;
    Ok(dx[k])
}

pub unsafe fn fmi3SetFloat64<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *const fmi3Float64,
    nValues: usize,
) -> fmi3Status {
    if let (Some(inst), Some(vrs), Some(vals), true) =
        (live::<M>(c), slice(vr, nvr), slice(value, nvr), nValues == nvr)
    {
        if (*inst).quick_set_real::<3>(vrs, vals) {
            return fmi3Status_fmi3OK;
        }
    }
    set_values::<M, _>(c, "fmi3SetFloat64", VarType::Real, vr, nvr, value, nValues, |v| v)
}

pub unsafe fn fmi3GetInt32<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *mut fmi3Int32,
    nValues: usize,
) -> fmi3Status {
    get_values::<M, _>(c, "fmi3GetInt32", VarType::Integer, vr, nvr, value, nValues, |v| {
        v as fmi3Int32
    })
}

pub unsafe fn fmi3SetInt32<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *const fmi3Int32,
    nValues: usize,
) -> fmi3Status {
    set_values::<M, _>(c, "fmi3SetInt32", VarType::Integer, vr, nvr, value, nValues, |v| v as f64)
}

pub unsafe fn fmi3GetBoolean<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *mut fmi3Boolean,
    nValues: usize,
) -> fmi3Status {
    get_values::<M, _>(c, "fmi3GetBoolean", VarType::Boolean, vr, nvr, value, nValues, |v| v != 0.0)
}

pub unsafe fn fmi3SetBoolean<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    value: *const fmi3Boolean,
    nValues: usize,
) -> fmi3Status {
    // Read as bytes: a C caller may pass any non-zero byte for true, which is not a valid Rust
    // bool.
    set_values::<M, u8>(
        c,
        "fmi3SetBoolean",
        VarType::Boolean,
        vr,
        nvr,
        value as *const u8,
        nValues,
        |v| (v != 0) as i32 as f64,
    )
}

/// The get and set functions of the types this FMU has no variable of.
macro_rules! no_variables_of_type {
    ($($get:ident, $set:ident, $t:ty, $name:literal;)*) => {$(
        pub unsafe fn $get<M: FmuModel>(
            c: fmi3Instance,
            vr: *const fmi3ValueReference,
            nvr: usize,
            _value: *mut $t,
            _nValues: usize,
        ) -> fmi3Status {
            no_variables::<M>(c, stringify!($get), $name, vr, nvr)
        }
        pub unsafe fn $set<M: FmuModel>(
            c: fmi3Instance,
            vr: *const fmi3ValueReference,
            nvr: usize,
            _value: *const $t,
            _nValues: usize,
        ) -> fmi3Status {
            no_variables::<M>(c, stringify!($set), $name, vr, nvr)
        }
    )*};
}

no_variables_of_type! {
    fmi3GetFloat32, fmi3SetFloat32, fmi3Float32, "Float32";
    fmi3GetInt8, fmi3SetInt8, fmi3Int8, "Int8";
    fmi3GetUInt8, fmi3SetUInt8, fmi3UInt8, "UInt8";
    fmi3GetInt16, fmi3SetInt16, fmi3Int16, "Int16";
    fmi3GetUInt16, fmi3SetUInt16, fmi3UInt16, "UInt16";
    fmi3GetUInt32, fmi3SetUInt32, fmi3UInt32, "UInt32";
    fmi3GetInt64, fmi3SetInt64, fmi3Int64, "Int64";
    fmi3GetUInt64, fmi3SetUInt64, fmi3UInt64, "UInt64";
    fmi3GetString, fmi3SetString, fmi3String, "String";
}

pub unsafe fn fmi3GetBinary<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    _valueSizes: *mut usize,
    _values: *mut fmi3Binary,
    _nValues: usize,
) -> fmi3Status {
    no_variables::<M>(c, "fmi3GetBinary", "Binary", vr, nvr)
}

pub unsafe fn fmi3SetBinary<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    _valueSizes: *const usize,
    _values: *const fmi3Binary,
    _nValues: usize,
) -> fmi3Status {
    no_variables::<M>(c, "fmi3SetBinary", "Binary", vr, nvr)
}

pub unsafe fn fmi3GetClock<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    _values: *mut fmi3Clock,
) -> fmi3Status {
    no_variables::<M>(c, "fmi3GetClock", "Clock", vr, nvr)
}

pub unsafe fn fmi3SetClock<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    _values: *const fmi3Clock,
) -> fmi3Status {
    no_variables::<M>(c, "fmi3SetClock", "Clock", vr, nvr)
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
    call::<M>(c, "fmi3GetFMUState", |inst| {
        if state.is_null() {
            return Err(null_argument("fmi3GetFMUState", "FMUState"));
        }
        let snap = inst.snapshot();
        store_snapshot(inst, state, snap);
        Ok(())
    })
}

pub unsafe fn fmi3SetFMUState<M: FmuModel>(c: fmi3Instance, state: fmi3FMUState) -> fmi3Status {
    call::<M>(c, "fmi3SetFMUState", |inst| {
        inst.restore(snapshot_ref::<M>("fmi3SetFMUState", state)?)
    })
}

pub unsafe fn fmi3FreeFMUState<M: FmuModel>(
    c: fmi3Instance,
    state: *mut fmi3FMUState,
) -> fmi3Status {
    call::<M>(c, "fmi3FreeFMUState", |inst| {
        if state.is_null() || (*state).is_null() {
            return Ok(());
        }
        let s = *state as *mut Snapshot<M>;
        let Some(pos) = inst.states.iter().position(|&p| p == s as usize) else {
            return Err(Failure::error(
                "fmi3FreeFMUState: FMUState was not made by this instance (or was freed)",
            ));
        };
        if (*s).magic != snapshot_magic::<M>() {
            return Err(Failure::error("fmi3FreeFMUState: FMUState was not made by this FMU"));
        }
        inst.states.swap_remove(pos);
        (*s).magic = 0;
        drop(Box::from_raw(s));
        *state = ptr::null_mut();
        Ok(())
    })
}

pub unsafe fn fmi3SerializedFMUStateSize<M: FmuModel>(
    c: fmi3Instance,
    state: fmi3FMUState,
    size: *mut usize,
) -> fmi3Status {
    call::<M>(c, "fmi3SerializedFMUStateSize", |_| {
        let snap = snapshot_ref::<M>("fmi3SerializedFMUStateSize", state)?;
        if size.is_null() {
            return Err(null_argument("fmi3SerializedFMUStateSize", "size"));
        }
        *size = fmu_state::serialize::<M>(&snap.core)?.len();
        Ok(())
    })
}

pub unsafe fn fmi3SerializeFMUState<M: FmuModel>(
    c: fmi3Instance,
    state: fmi3FMUState,
    bytes: *mut fmi3Byte,
    size: usize,
) -> fmi3Status {
    call::<M>(c, "fmi3SerializeFMUState", |_| {
        let snap = snapshot_ref::<M>("fmi3SerializeFMUState", state)?;
        let data = fmu_state::serialize::<M>(&snap.core)?;
        if bytes.is_null() || size < data.len() {
            return Err(Failure::error(format!(
                "fmi3SerializeFMUState: buffer of {size} bytes is too small; {} needed",
                data.len()
            )));
        }
        ptr::copy_nonoverlapping(data.as_ptr(), bytes, data.len());
        Ok(())
    })
}

pub unsafe fn fmi3DeserializeFMUState<M: FmuModel>(
    c: fmi3Instance,
    bytes: *const fmi3Byte,
    size: usize,
    state: *mut fmi3FMUState,
) -> fmi3Status {
    call::<M>(c, "fmi3DeserializeFMUState", |inst| {
        let data = slice(bytes, size)
            .ok_or_else(|| null_argument("fmi3DeserializeFMUState", "serializedState"))?;
        if state.is_null() {
            return Err(null_argument("fmi3DeserializeFMUState", "FMUState"));
        }
        let snap = Instance::<M>::snapshot_from_core(fmu_state::deserialize::<M>(data)?)?;
        store_snapshot(inst, state, snap);
        Ok(())
    })
}

// ------------------------------------------------------------------------------ derivatives

#[allow(clippy::too_many_arguments)]
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
    use crate::fmi::directional::{directional_derivative, model_exchange_refs};
    let f = "fmi3GetDirectionalDerivative";
    call::<M>(c, f, |inst| {
        if nSeed != nKnowns || nSensitivity != nUnknowns {
            return Err(Failure::error(format!(
                "{f}: nSeed = {nSeed} must equal nKnowns = {nKnowns} and nSensitivity = \
                 {nSensitivity} must equal nUnknowns = {nUnknowns}"
            )));
        }
        let u = slice(unknowns, nUnknowns).ok_or_else(|| null_argument(f, "unknowns"))?;
        let k = slice(knowns, nKnowns).ok_or_else(|| null_argument(f, "knowns"))?;
        let s = slice(seed, nSeed).ok_or_else(|| null_argument(f, "seed"))?;
        if nSensitivity > 0 && sensitivity.is_null() {
            return Err(null_argument(f, "sensitivity"));
        }
        let out: &mut [fmi3Float64] = if nSensitivity == 0 {
            &mut []
        } else {
            std::slice::from_raw_parts_mut(sensitivity, nSensitivity)
        };
        // FMI 3.0 numbering (`model_description.rs`), which the 2.0 file shares.
        directional_derivative::<M>(inst, f, u, k, s, out, &model_exchange_refs::<M>())
    })
}

pub unsafe fn fmi3GetAdjointDerivative<M: FmuModel>(
    c: fmi3Instance,
    _unknowns: *const fmi3ValueReference,
    _nUnknowns: usize,
    _knowns: *const fmi3ValueReference,
    _nKnowns: usize,
    _seed: *const fmi3Float64,
    _nSeed: usize,
    _sensitivity: *mut fmi3Float64,
    _nSensitivity: usize,
) -> fmi3Status {
    unsupported::<M>(
        c,
        "fmi3GetAdjointDerivative",
        "not provided by this FMU (providesAdjointDerivatives=\"false\")",
    )
}

pub unsafe fn fmi3GetOutputDerivatives<M: FmuModel>(
    c: fmi3Instance,
    _vr: *const fmi3ValueReference,
    _nvr: usize,
    _orders: *const fmi3Int32,
    _values: *mut fmi3Float64,
    _nValues: usize,
) -> fmi3Status {
    unsupported::<M>(
        c,
        "fmi3GetOutputDerivatives",
        "not supported (maxOutputDerivativeOrder=\"0\")",
    )
}

// ------------------------------------------------------------------------------ configuration,
// clocks, discrete states: not declared by this FMU

pub unsafe fn fmi3EnterConfigurationMode<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    unsupported::<M>(c, "fmi3EnterConfigurationMode", "this FMU has no structural parameters")
}

pub unsafe fn fmi3ExitConfigurationMode<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    unsupported::<M>(c, "fmi3ExitConfigurationMode", "this FMU has no structural parameters")
}

pub unsafe fn fmi3GetIntervalDecimal<M: FmuModel>(
    c: fmi3Instance,
    _vr: *const fmi3ValueReference,
    _nvr: usize,
    _intervals: *mut fmi3Float64,
    _qualifiers: *mut fmi3IntervalQualifier,
) -> fmi3Status {
    unsupported::<M>(c, "fmi3GetIntervalDecimal", NO_CLOCKS)
}

pub unsafe fn fmi3GetIntervalFraction<M: FmuModel>(
    c: fmi3Instance,
    _vr: *const fmi3ValueReference,
    _nvr: usize,
    _counters: *mut fmi3UInt64,
    _resolutions: *mut fmi3UInt64,
    _qualifiers: *mut fmi3IntervalQualifier,
) -> fmi3Status {
    unsupported::<M>(c, "fmi3GetIntervalFraction", NO_CLOCKS)
}

pub unsafe fn fmi3GetShiftDecimal<M: FmuModel>(
    c: fmi3Instance,
    _vr: *const fmi3ValueReference,
    _nvr: usize,
    _shifts: *mut fmi3Float64,
) -> fmi3Status {
    unsupported::<M>(c, "fmi3GetShiftDecimal", NO_CLOCKS)
}

pub unsafe fn fmi3GetShiftFraction<M: FmuModel>(
    c: fmi3Instance,
    _vr: *const fmi3ValueReference,
    _nvr: usize,
    _counters: *mut fmi3UInt64,
    _resolutions: *mut fmi3UInt64,
) -> fmi3Status {
    unsupported::<M>(c, "fmi3GetShiftFraction", NO_CLOCKS)
}

pub unsafe fn fmi3SetIntervalDecimal<M: FmuModel>(
    c: fmi3Instance,
    _vr: *const fmi3ValueReference,
    _nvr: usize,
    _intervals: *const fmi3Float64,
) -> fmi3Status {
    unsupported::<M>(c, "fmi3SetIntervalDecimal", NO_CLOCKS)
}

pub unsafe fn fmi3SetIntervalFraction<M: FmuModel>(
    c: fmi3Instance,
    _vr: *const fmi3ValueReference,
    _nvr: usize,
    _counters: *const fmi3UInt64,
    _resolutions: *const fmi3UInt64,
) -> fmi3Status {
    unsupported::<M>(c, "fmi3SetIntervalFraction", NO_CLOCKS)
}

pub unsafe fn fmi3SetShiftDecimal<M: FmuModel>(
    c: fmi3Instance,
    _vr: *const fmi3ValueReference,
    _nvr: usize,
    _shifts: *const fmi3Float64,
) -> fmi3Status {
    unsupported::<M>(c, "fmi3SetShiftDecimal", NO_CLOCKS)
}

pub unsafe fn fmi3SetShiftFraction<M: FmuModel>(
    c: fmi3Instance,
    _vr: *const fmi3ValueReference,
    _nvr: usize,
    _counters: *const fmi3UInt64,
    _resolutions: *const fmi3UInt64,
) -> fmi3Status {
    unsupported::<M>(c, "fmi3SetShiftFraction", NO_CLOCKS)
}

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

fn state_count(function: &str, n: usize, nx: usize) -> Result<(), Failure> {
    if n != nx {
        return Err(Failure::error(format!(
            "{function}: nContinuousStates = {nx}; this FMU has {n} continuous states"
        )));
    }
    Ok(())
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
    me::<M>(c, "fmi3CompletedIntegratorStep", |_| {
        if enterEventMode.is_null() || terminateSimulation.is_null() {
            return Err(null_argument(
                "fmi3CompletedIntegratorStep",
                "enterEventMode or terminateSimulation",
            ));
        }
        *enterEventMode = false;
        *terminateSimulation = false;
        Ok(())
    })
}

pub unsafe fn fmi3SetTime<M: FmuModel>(c: fmi3Instance, time: fmi3Float64) -> fmi3Status {
    me::<M>(c, "fmi3SetTime", |inst| {
        crate::fmi::model_exchange::set_time(inst, "fmi3SetTime", time)
    })
}

pub unsafe fn fmi3SetContinuousStates<M: FmuModel>(
    c: fmi3Instance,
    x: *const fmi3Float64,
    nx: usize,
) -> fmi3Status {
    let f = "fmi3SetContinuousStates";
    me::<M>(c, f, |inst| {
        let n = M::CONTINUOUS_STATES.len();
        state_count(f, n, nx)?;
        let x = slice(x, nx).ok_or_else(|| null_argument(f, "continuousStates"))?;
        if let Some(k) = x.iter().position(|v| !v.is_finite()) {
            return Err(Failure::error(format!(
                "{f}: {} = {}; allowed: a finite number",
                M::CONTINUOUS_STATES[k].0,
                x[k]
            )));
        }
        inst.me_update(|_, state| M::set_continuous_states(state, x));
        Ok(())
    })
}

pub unsafe fn fmi3GetContinuousStateDerivatives<M: FmuModel>(
    c: fmi3Instance,
    derivatives: *mut fmi3Float64,
    nx: usize,
) -> fmi3Status {
    let f = "fmi3GetContinuousStateDerivatives";
    me::<M>(c, f, |inst| {
        state_count(f, M::CONTINUOUS_STATES.len(), nx)?;
        if nx > 0 && derivatives.is_null() {
            return Err(null_argument(f, "derivatives"));
        }
        let (built, values, state) =
            inst.me_parts().ok_or_else(|| Failure::illegal(f, inst.mode()))?;
        let dx =
            if nx == 0 { &mut [][..] } else { std::slice::from_raw_parts_mut(derivatives, nx) };
        M::derivatives(built, values, state, dx)?;
        Ok(())
    })
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
    me::<M>(c, f, |inst| {
        state_count(f, M::CONTINUOUS_STATES.len(), nx)?;
        if nx > 0 && x.is_null() {
            return Err(null_argument(f, "continuousStates"));
        }
        let (_, _, state) = inst.me_parts().ok_or_else(|| Failure::illegal(f, inst.mode()))?;
        let out = if nx == 0 { &mut [][..] } else { std::slice::from_raw_parts_mut(x, nx) };
        M::continuous_states(state, out);
        Ok(())
    })
}

pub unsafe fn fmi3GetNominalsOfContinuousStates<M: FmuModel>(
    c: fmi3Instance,
    nominals: *mut fmi3Float64,
    nx: usize,
) -> fmi3Status {
    let f = "fmi3GetNominalsOfContinuousStates";
    me::<M>(c, f, |_| {
        state_count(f, M::CONTINUOUS_STATES.len(), nx)?;
        if nx > 0 && nominals.is_null() {
            return Err(null_argument(f, "nominals"));
        }
        for k in 0..nx {
            *nominals.add(k) = 1.0;
        }
        Ok(())
    })
}

pub unsafe fn fmi3GetNumberOfEventIndicators<M: FmuModel>(
    c: fmi3Instance,
    n: *mut usize,
) -> fmi3Status {
    call::<M>(c, "fmi3GetNumberOfEventIndicators", |_| {
        if n.is_null() {
            return Err(null_argument("fmi3GetNumberOfEventIndicators", "nEventIndicators"));
        }
        *n = 0;
        Ok(())
    })
}

pub unsafe fn fmi3GetNumberOfContinuousStates<M: FmuModel>(
    c: fmi3Instance,
    n: *mut usize,
) -> fmi3Status {
    call::<M>(c, "fmi3GetNumberOfContinuousStates", |_| {
        if n.is_null() {
            return Err(null_argument("fmi3GetNumberOfContinuousStates", "nContinuousStates"));
        }
        *n = M::CONTINUOUS_STATES.len();
        Ok(())
    })
}

// ------------------------------------------------------------------------------ co-simulation

pub unsafe fn fmi3EnterStepMode<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    // Only from event mode, which this FMU never enters: fmi3ExitInitializationMode goes straight
    // to step mode.
    unsupported::<M>(c, "fmi3EnterStepMode", NO_EVENTS)
}

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

pub unsafe fn fmi3ActivateModelPartition<M: FmuModel>(
    c: fmi3Instance,
    _clockReference: fmi3ValueReference,
    _activationTime: fmi3Float64,
) -> fmi3Status {
    unsupported::<M>(c, "fmi3ActivateModelPartition", NO_CLOCKS)
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
            type M = $model;

            #[no_mangle]
            pub extern "C" fn fmi3GetVersion() -> *const ::std::ffi::c_char {
                glue::fmi3GetVersion()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetDebugLogging(
                c: fmi3Instance,
                loggingOn: fmi3Boolean,
                nCategories: usize,
                categories: *const fmi3String,
            ) -> fmi3Status {
                glue::fmi3SetDebugLogging::<M>(c, loggingOn, nCategories, categories)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3InstantiateModelExchange(
                instanceName: fmi3String,
                instantiationToken: fmi3String,
                resourcePath: fmi3String,
                visible: fmi3Boolean,
                loggingOn: fmi3Boolean,
                instanceEnvironment: fmi3InstanceEnvironment,
                logMessage: fmi3LogMessageCallback,
            ) -> fmi3Instance {
                glue::fmi3InstantiateModelExchange::<M>(
                    instanceName,
                    instantiationToken,
                    resourcePath,
                    visible,
                    loggingOn,
                    instanceEnvironment,
                    logMessage,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
                instanceName: fmi3String,
                instantiationToken: fmi3String,
                resourcePath: fmi3String,
                visible: fmi3Boolean,
                loggingOn: fmi3Boolean,
                eventModeUsed: fmi3Boolean,
                earlyReturnAllowed: fmi3Boolean,
                requiredIntermediateVariables: *const fmi3ValueReference,
                nRequiredIntermediateVariables: usize,
                instanceEnvironment: fmi3InstanceEnvironment,
                logMessage: fmi3LogMessageCallback,
                intermediateUpdate: fmi3IntermediateUpdateCallback,
            ) -> fmi3Instance {
                glue::fmi3InstantiateCoSimulation::<M>(
                    instanceName,
                    instantiationToken,
                    resourcePath,
                    visible,
                    loggingOn,
                    eventModeUsed,
                    earlyReturnAllowed,
                    requiredIntermediateVariables,
                    nRequiredIntermediateVariables,
                    instanceEnvironment,
                    logMessage,
                    intermediateUpdate,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
                instanceName: fmi3String,
                instantiationToken: fmi3String,
                resourcePath: fmi3String,
                visible: fmi3Boolean,
                loggingOn: fmi3Boolean,
                instanceEnvironment: fmi3InstanceEnvironment,
                logMessage: fmi3LogMessageCallback,
                clockUpdate: fmi3ClockUpdateCallback,
                lockPreemption: fmi3LockPreemptionCallback,
                unlockPreemption: fmi3UnlockPreemptionCallback,
            ) -> fmi3Instance {
                glue::fmi3InstantiateScheduledExecution::<M>(
                    instanceName,
                    instantiationToken,
                    resourcePath,
                    visible,
                    loggingOn,
                    instanceEnvironment,
                    logMessage,
                    clockUpdate,
                    lockPreemption,
                    unlockPreemption,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3FreeInstance(c: fmi3Instance) {
                glue::fmi3FreeInstance::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterInitializationMode(
                c: fmi3Instance,
                toleranceDefined: fmi3Boolean,
                tolerance: fmi3Float64,
                startTime: fmi3Float64,
                stopTimeDefined: fmi3Boolean,
                stopTime: fmi3Float64,
            ) -> fmi3Status {
                glue::fmi3EnterInitializationMode::<M>(
                    c,
                    toleranceDefined,
                    tolerance,
                    startTime,
                    stopTimeDefined,
                    stopTime,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3ExitInitializationMode(c: fmi3Instance) -> fmi3Status {
                glue::fmi3ExitInitializationMode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterEventMode(c: fmi3Instance) -> fmi3Status {
                glue::fmi3EnterEventMode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3Terminate(c: fmi3Instance) -> fmi3Status {
                glue::fmi3Terminate::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3Reset(c: fmi3Instance) -> fmi3Status {
                glue::fmi3Reset::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetFloat64(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3Float64,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetFloat64::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetFloat64(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3Float64,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetFloat64::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetInt32(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3Int32,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetInt32::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetInt32(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3Int32,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetInt32::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetBoolean(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3Boolean,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetBoolean::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetBoolean(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3Boolean,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetBoolean::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetBinary(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                valueSizes: *mut usize,
                values: *mut fmi3Binary,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetBinary::<M>(c, vr, nvr, valueSizes, values, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetBinary(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                valueSizes: *const usize,
                values: *const fmi3Binary,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetBinary::<M>(c, vr, nvr, valueSizes, values, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetClock(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                values: *mut fmi3Clock,
            ) -> fmi3Status {
                glue::fmi3GetClock::<M>(c, vr, nvr, values)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetClock(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                values: *const fmi3Clock,
            ) -> fmi3Status {
                glue::fmi3SetClock::<M>(c, vr, nvr, values)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNumberOfVariableDependencies(
                c: fmi3Instance,
                valueReference: fmi3ValueReference,
                nDependencies: *mut usize,
            ) -> fmi3Status {
                glue::fmi3GetNumberOfVariableDependencies::<M>(c, valueReference, nDependencies)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetVariableDependencies(
                c: fmi3Instance,
                dependent: fmi3ValueReference,
                elementIndicesOfDependent: *mut usize,
                independents: *mut fmi3ValueReference,
                elementIndicesOfIndependents: *mut usize,
                dependencyKinds: *mut fmi3DependencyKind,
                nDependencies: usize,
            ) -> fmi3Status {
                glue::fmi3GetVariableDependencies::<M>(
                    c,
                    dependent,
                    elementIndicesOfDependent,
                    independents,
                    elementIndicesOfIndependents,
                    dependencyKinds,
                    nDependencies,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetFMUState(
                c: fmi3Instance,
                state: *mut fmi3FMUState,
            ) -> fmi3Status {
                glue::fmi3GetFMUState::<M>(c, state)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetFMUState(
                c: fmi3Instance,
                state: fmi3FMUState,
            ) -> fmi3Status {
                glue::fmi3SetFMUState::<M>(c, state)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3FreeFMUState(
                c: fmi3Instance,
                state: *mut fmi3FMUState,
            ) -> fmi3Status {
                glue::fmi3FreeFMUState::<M>(c, state)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
                c: fmi3Instance,
                state: fmi3FMUState,
                size: *mut usize,
            ) -> fmi3Status {
                glue::fmi3SerializedFMUStateSize::<M>(c, state, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SerializeFMUState(
                c: fmi3Instance,
                state: fmi3FMUState,
                bytes: *mut fmi3Byte,
                size: usize,
            ) -> fmi3Status {
                glue::fmi3SerializeFMUState::<M>(c, state, bytes, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3DeserializeFMUState(
                c: fmi3Instance,
                bytes: *const fmi3Byte,
                size: usize,
                state: *mut fmi3FMUState,
            ) -> fmi3Status {
                glue::fmi3DeserializeFMUState::<M>(c, bytes, size, state)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetDirectionalDerivative(
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
                glue::fmi3GetDirectionalDerivative::<M>(
                    c,
                    unknowns,
                    nUnknowns,
                    knowns,
                    nKnowns,
                    seed,
                    nSeed,
                    sensitivity,
                    nSensitivity,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetAdjointDerivative(
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
                glue::fmi3GetAdjointDerivative::<M>(
                    c,
                    unknowns,
                    nUnknowns,
                    knowns,
                    nKnowns,
                    seed,
                    nSeed,
                    sensitivity,
                    nSensitivity,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetOutputDerivatives(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                orders: *const fmi3Int32,
                values: *mut fmi3Float64,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetOutputDerivatives::<M>(c, vr, nvr, orders, values, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterConfigurationMode(c: fmi3Instance) -> fmi3Status {
                glue::fmi3EnterConfigurationMode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3ExitConfigurationMode(c: fmi3Instance) -> fmi3Status {
                glue::fmi3ExitConfigurationMode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetIntervalDecimal(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                intervals: *mut fmi3Float64,
                qualifiers: *mut fmi3IntervalQualifier,
            ) -> fmi3Status {
                glue::fmi3GetIntervalDecimal::<M>(c, vr, nvr, intervals, qualifiers)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetIntervalFraction(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                counters: *mut fmi3UInt64,
                resolutions: *mut fmi3UInt64,
                qualifiers: *mut fmi3IntervalQualifier,
            ) -> fmi3Status {
                glue::fmi3GetIntervalFraction::<M>(c, vr, nvr, counters, resolutions, qualifiers)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetShiftDecimal(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                shifts: *mut fmi3Float64,
            ) -> fmi3Status {
                glue::fmi3GetShiftDecimal::<M>(c, vr, nvr, shifts)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetShiftFraction(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                counters: *mut fmi3UInt64,
                resolutions: *mut fmi3UInt64,
            ) -> fmi3Status {
                glue::fmi3GetShiftFraction::<M>(c, vr, nvr, counters, resolutions)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetIntervalDecimal(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                intervals: *const fmi3Float64,
            ) -> fmi3Status {
                glue::fmi3SetIntervalDecimal::<M>(c, vr, nvr, intervals)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetIntervalFraction(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                counters: *const fmi3UInt64,
                resolutions: *const fmi3UInt64,
            ) -> fmi3Status {
                glue::fmi3SetIntervalFraction::<M>(c, vr, nvr, counters, resolutions)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetShiftDecimal(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                shifts: *const fmi3Float64,
            ) -> fmi3Status {
                glue::fmi3SetShiftDecimal::<M>(c, vr, nvr, shifts)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetShiftFraction(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                counters: *const fmi3UInt64,
                resolutions: *const fmi3UInt64,
            ) -> fmi3Status {
                glue::fmi3SetShiftFraction::<M>(c, vr, nvr, counters, resolutions)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EvaluateDiscreteStates(c: fmi3Instance) -> fmi3Status {
                glue::fmi3EvaluateDiscreteStates::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3UpdateDiscreteStates(
                c: fmi3Instance,
                discreteStatesNeedUpdate: *mut fmi3Boolean,
                terminateSimulation: *mut fmi3Boolean,
                nominalsOfContinuousStatesChanged: *mut fmi3Boolean,
                valuesOfContinuousStatesChanged: *mut fmi3Boolean,
                nextEventTimeDefined: *mut fmi3Boolean,
                nextEventTime: *mut fmi3Float64,
            ) -> fmi3Status {
                glue::fmi3UpdateDiscreteStates::<M>(
                    c,
                    discreteStatesNeedUpdate,
                    terminateSimulation,
                    nominalsOfContinuousStatesChanged,
                    valuesOfContinuousStatesChanged,
                    nextEventTimeDefined,
                    nextEventTime,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterContinuousTimeMode(c: fmi3Instance) -> fmi3Status {
                glue::fmi3EnterContinuousTimeMode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3CompletedIntegratorStep(
                c: fmi3Instance,
                noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
                enterEventMode: *mut fmi3Boolean,
                terminateSimulation: *mut fmi3Boolean,
            ) -> fmi3Status {
                glue::fmi3CompletedIntegratorStep::<M>(
                    c,
                    noSetFMUStatePriorToCurrentPoint,
                    enterEventMode,
                    terminateSimulation,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetTime(c: fmi3Instance, time: fmi3Float64) -> fmi3Status {
                glue::fmi3SetTime::<M>(c, time)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetContinuousStates(
                c: fmi3Instance,
                x: *const fmi3Float64,
                nx: usize,
            ) -> fmi3Status {
                glue::fmi3SetContinuousStates::<M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetContinuousStateDerivatives(
                c: fmi3Instance,
                derivatives: *mut fmi3Float64,
                nx: usize,
            ) -> fmi3Status {
                glue::fmi3GetContinuousStateDerivatives::<M>(c, derivatives, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetEventIndicators(
                c: fmi3Instance,
                indicators: *mut fmi3Float64,
                n: usize,
            ) -> fmi3Status {
                glue::fmi3GetEventIndicators::<M>(c, indicators, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetContinuousStates(
                c: fmi3Instance,
                x: *mut fmi3Float64,
                nx: usize,
            ) -> fmi3Status {
                glue::fmi3GetContinuousStates::<M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNominalsOfContinuousStates(
                c: fmi3Instance,
                nominals: *mut fmi3Float64,
                nx: usize,
            ) -> fmi3Status {
                glue::fmi3GetNominalsOfContinuousStates::<M>(c, nominals, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNumberOfEventIndicators(
                c: fmi3Instance,
                n: *mut usize,
            ) -> fmi3Status {
                glue::fmi3GetNumberOfEventIndicators::<M>(c, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNumberOfContinuousStates(
                c: fmi3Instance,
                n: *mut usize,
            ) -> fmi3Status {
                glue::fmi3GetNumberOfContinuousStates::<M>(c, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterStepMode(c: fmi3Instance) -> fmi3Status {
                glue::fmi3EnterStepMode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3DoStep(
                c: fmi3Instance,
                currentCommunicationPoint: fmi3Float64,
                communicationStepSize: fmi3Float64,
                noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
                eventHandlingNeeded: *mut fmi3Boolean,
                terminateSimulation: *mut fmi3Boolean,
                earlyReturn: *mut fmi3Boolean,
                lastSuccessfulTime: *mut fmi3Float64,
            ) -> fmi3Status {
                glue::fmi3DoStep::<M>(
                    c,
                    currentCommunicationPoint,
                    communicationStepSize,
                    noSetFMUStatePriorToCurrentPoint,
                    eventHandlingNeeded,
                    terminateSimulation,
                    earlyReturn,
                    lastSuccessfulTime,
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3ActivateModelPartition(
                c: fmi3Instance,
                clockReference: fmi3ValueReference,
                activationTime: fmi3Float64,
            ) -> fmi3Status {
                glue::fmi3ActivateModelPartition::<M>(c, clockReference, activationTime)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetFloat32(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3Float32,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetFloat32::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetFloat32(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3Float32,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetFloat32::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetInt8(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3Int8,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetInt8::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetInt8(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3Int8,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetInt8::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetUInt8(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3UInt8,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetUInt8::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetUInt8(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3UInt8,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetUInt8::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetInt16(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3Int16,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetInt16::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetInt16(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3Int16,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetInt16::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetUInt16(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3UInt16,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetUInt16::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetUInt16(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3UInt16,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetUInt16::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetUInt32(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3UInt32,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetUInt32::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetUInt32(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3UInt32,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetUInt32::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetInt64(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3Int64,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetInt64::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetInt64(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3Int64,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetInt64::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetUInt64(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3UInt64,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetUInt64::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetUInt64(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3UInt64,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetUInt64::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetString(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *mut fmi3String,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3GetString::<M>(c, vr, nvr, value, nValues)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetString(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                value: *const fmi3String,
                nValues: usize,
            ) -> fmi3Status {
                glue::fmi3SetString::<M>(c, vr, nvr, value, nValues)
            }

            // Each exported function must have exactly the type the FMI 3.0 headers declare.
            const _: fmi3GetVersionTYPE = Some(fmi3GetVersion);
            const _: fmi3SetDebugLoggingTYPE = Some(fmi3SetDebugLogging);
            const _: fmi3InstantiateModelExchangeTYPE = Some(fmi3InstantiateModelExchange);
            const _: fmi3InstantiateCoSimulationTYPE = Some(fmi3InstantiateCoSimulation);
            const _: fmi3InstantiateScheduledExecutionTYPE =
                Some(fmi3InstantiateScheduledExecution);
            const _: fmi3FreeInstanceTYPE = Some(fmi3FreeInstance);
            const _: fmi3EnterInitializationModeTYPE = Some(fmi3EnterInitializationMode);
            const _: fmi3ExitInitializationModeTYPE = Some(fmi3ExitInitializationMode);
            const _: fmi3EnterEventModeTYPE = Some(fmi3EnterEventMode);
            const _: fmi3TerminateTYPE = Some(fmi3Terminate);
            const _: fmi3ResetTYPE = Some(fmi3Reset);
            const _: fmi3GetFloat64TYPE = Some(fmi3GetFloat64);
            const _: fmi3SetFloat64TYPE = Some(fmi3SetFloat64);
            const _: fmi3GetInt32TYPE = Some(fmi3GetInt32);
            const _: fmi3SetInt32TYPE = Some(fmi3SetInt32);
            const _: fmi3GetBooleanTYPE = Some(fmi3GetBoolean);
            const _: fmi3SetBooleanTYPE = Some(fmi3SetBoolean);
            const _: fmi3GetBinaryTYPE = Some(fmi3GetBinary);
            const _: fmi3SetBinaryTYPE = Some(fmi3SetBinary);
            const _: fmi3GetClockTYPE = Some(fmi3GetClock);
            const _: fmi3SetClockTYPE = Some(fmi3SetClock);
            const _: fmi3GetNumberOfVariableDependenciesTYPE =
                Some(fmi3GetNumberOfVariableDependencies);
            const _: fmi3GetVariableDependenciesTYPE = Some(fmi3GetVariableDependencies);
            const _: fmi3GetFMUStateTYPE = Some(fmi3GetFMUState);
            const _: fmi3SetFMUStateTYPE = Some(fmi3SetFMUState);
            const _: fmi3FreeFMUStateTYPE = Some(fmi3FreeFMUState);
            const _: fmi3SerializedFMUStateSizeTYPE = Some(fmi3SerializedFMUStateSize);
            const _: fmi3SerializeFMUStateTYPE = Some(fmi3SerializeFMUState);
            const _: fmi3DeserializeFMUStateTYPE = Some(fmi3DeserializeFMUState);
            const _: fmi3GetDirectionalDerivativeTYPE = Some(fmi3GetDirectionalDerivative);
            const _: fmi3GetAdjointDerivativeTYPE = Some(fmi3GetAdjointDerivative);
            const _: fmi3GetOutputDerivativesTYPE = Some(fmi3GetOutputDerivatives);
            const _: fmi3EnterConfigurationModeTYPE = Some(fmi3EnterConfigurationMode);
            const _: fmi3ExitConfigurationModeTYPE = Some(fmi3ExitConfigurationMode);
            const _: fmi3GetIntervalDecimalTYPE = Some(fmi3GetIntervalDecimal);
            const _: fmi3GetIntervalFractionTYPE = Some(fmi3GetIntervalFraction);
            const _: fmi3GetShiftDecimalTYPE = Some(fmi3GetShiftDecimal);
            const _: fmi3GetShiftFractionTYPE = Some(fmi3GetShiftFraction);
            const _: fmi3SetIntervalDecimalTYPE = Some(fmi3SetIntervalDecimal);
            const _: fmi3SetIntervalFractionTYPE = Some(fmi3SetIntervalFraction);
            const _: fmi3SetShiftDecimalTYPE = Some(fmi3SetShiftDecimal);
            const _: fmi3SetShiftFractionTYPE = Some(fmi3SetShiftFraction);
            const _: fmi3EvaluateDiscreteStatesTYPE = Some(fmi3EvaluateDiscreteStates);
            const _: fmi3UpdateDiscreteStatesTYPE = Some(fmi3UpdateDiscreteStates);
            const _: fmi3EnterContinuousTimeModeTYPE = Some(fmi3EnterContinuousTimeMode);
            const _: fmi3CompletedIntegratorStepTYPE = Some(fmi3CompletedIntegratorStep);
            const _: fmi3SetTimeTYPE = Some(fmi3SetTime);
            const _: fmi3SetContinuousStatesTYPE = Some(fmi3SetContinuousStates);
            const _: fmi3GetContinuousStateDerivativesTYPE =
                Some(fmi3GetContinuousStateDerivatives);
            const _: fmi3GetEventIndicatorsTYPE = Some(fmi3GetEventIndicators);
            const _: fmi3GetContinuousStatesTYPE = Some(fmi3GetContinuousStates);
            const _: fmi3GetNominalsOfContinuousStatesTYPE =
                Some(fmi3GetNominalsOfContinuousStates);
            const _: fmi3GetNumberOfEventIndicatorsTYPE = Some(fmi3GetNumberOfEventIndicators);
            const _: fmi3GetNumberOfContinuousStatesTYPE = Some(fmi3GetNumberOfContinuousStates);
            const _: fmi3EnterStepModeTYPE = Some(fmi3EnterStepMode);
            const _: fmi3DoStepTYPE = Some(fmi3DoStep);
            const _: fmi3ActivateModelPartitionTYPE = Some(fmi3ActivateModelPartition);
            const _: fmi3GetFloat32TYPE = Some(fmi3GetFloat32);
            const _: fmi3SetFloat32TYPE = Some(fmi3SetFloat32);
            const _: fmi3GetInt8TYPE = Some(fmi3GetInt8);
            const _: fmi3SetInt8TYPE = Some(fmi3SetInt8);
            const _: fmi3GetUInt8TYPE = Some(fmi3GetUInt8);
            const _: fmi3SetUInt8TYPE = Some(fmi3SetUInt8);
            const _: fmi3GetInt16TYPE = Some(fmi3GetInt16);
            const _: fmi3SetInt16TYPE = Some(fmi3SetInt16);
            const _: fmi3GetUInt16TYPE = Some(fmi3GetUInt16);
            const _: fmi3SetUInt16TYPE = Some(fmi3SetUInt16);
            const _: fmi3GetUInt32TYPE = Some(fmi3GetUInt32);
            const _: fmi3SetUInt32TYPE = Some(fmi3SetUInt32);
            const _: fmi3GetInt64TYPE = Some(fmi3GetInt64);
            const _: fmi3SetInt64TYPE = Some(fmi3SetInt64);
            const _: fmi3GetUInt64TYPE = Some(fmi3GetUInt64);
            const _: fmi3SetUInt64TYPE = Some(fmi3SetUInt64);
            const _: fmi3GetStringTYPE = Some(fmi3GetString);
            const _: fmi3SetStringTYPE = Some(fmi3SetString);
        };
    };
}
