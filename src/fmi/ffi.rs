//! Core layer: what the exported functions of both standards do around the instance core, written
//! once, so that a fix to an argument check or the panic barrier is made in one place: the NULL
//! and freed-instance check, the panic barrier (no unwinding crosses the C boundary), a failure
//! turned into its status and one log line naming the function ([`call`]); C strings and arrays
//! read with their checks; and the function families both standards have: debug logging, typed
//! get/set, FMU states, directional derivatives, instantiation. Each standard's C ABI
//! (`fmi2::abi`, `fmi3::abi`) calls these with its function and argument names ([`Dialect`]).
//!
//! An `fmi2Component` and an `fmi3Instance` are both `void*` (a handle, `crate::fmi::handle`), as
//! are an `fmi2FMUstate` and an `fmi3FMUState`; the statuses of both standards have the same
//! values (checked below), so the core returns one [`Status`].

// The shared functions take the C arguments of the functions they serve, as many as those have.
#![allow(clippy::too_many_arguments)]

use std::ffi::{c_char, c_void, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::ptr;

use fmi_sys::fmi2::{
    fmi2Status_fmi2Discard, fmi2Status_fmi2Error, fmi2Status_fmi2Fatal, fmi2Status_fmi2OK,
};
use fmi_sys::fmi3::{
    fmi3Status_fmi3Discard, fmi3Status_fmi3Error, fmi3Status_fmi3Fatal, fmi3Status_fmi3OK,
};

use crate::fmi::directional::{directional_derivative, model_exchange_refs};
use crate::fmi::fmu_state;
use crate::fmi::handle::{live, new_handle, report_freed};
use crate::fmi::instance::{snapshot_magic, Failure, Instance, Severity, Snapshot};
use crate::fmi::logging::{Category, Logger};
use crate::fmi::model::FmuModel;
use crate::fmi::variables::VarType;

/// The status of an FMI call, `fmi2Status` or `fmi3Status`: the same numbers in both standards.
pub type Status = u32;
pub const OK: Status = fmi2Status_fmi2OK;
pub const ERROR: Status = fmi2Status_fmi2Error;
pub const FATAL: Status = fmi2Status_fmi2Fatal;
const _: () = assert!(
    fmi2Status_fmi2OK == fmi3Status_fmi3OK
        && fmi2Status_fmi2Discard == fmi3Status_fmi3Discard
        && fmi2Status_fmi2Error == fmi3Status_fmi3Error
        && fmi2Status_fmi2Fatal == fmi3Status_fmi3Fatal
);

fn status_of(s: Severity) -> Status {
    match s {
        Severity::Discard => fmi2Status_fmi2Discard,
        Severity::Error => fmi2Status_fmi2Error,
        Severity::Fatal => fmi2Status_fmi2Fatal,
    }
}

/// What differs between the standards in the shared functions: how their messages name things.
pub(crate) trait Dialect {
    /// Whether a failure message that starts with any FMI function's name already names the
    /// function (FMI 3.0: the core's messages name FMI 2.0 functions, which its logger translates,
    /// `crate::fmi::logging::dialect`), or only one that starts with the called function's name.
    const ANY_NAME: bool;
    /// The names of the value-reference and the values arguments of get/set.
    const VR: &'static str;
    const VALUES: &'static str;
    /// The arguments of the directional derivative: unknowns, knowns, seed, sensitivity.
    const DIRECTIONAL: [&'static str; 4];
    /// How the standard spells an FMU state (`FMUstate`, `FMUState`).
    const FMU_STATE: &'static str;
    /// Model Exchange: the names of the number of states and of the states and nominals arrays.
    const NX: &'static str;
    const STATES: &'static str;
    const NOMINALS: &'static str;
    /// The function that starts initialization (before it, no state derivative can be read).
    const ENTER_INITIALIZATION: &'static str;
}

/// Runs `f` on the instance behind `c`: NULL and freed-instance check (`crate::fmi::handle`),
/// panic barrier, status and logging.
pub(crate) unsafe fn call<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    f: impl FnOnce(&mut Instance<M>) -> Result<(), Failure>,
) -> Status {
    let Some(inst) = live::<M>(c) else {
        if !c.is_null() {
            report_freed::<M>(c, function);
        }
        return ERROR;
    };
    match catch_unwind(AssertUnwindSafe(|| f(&mut *inst))) {
        Ok(Ok(())) => {
            (*inst).log(OK, Category::Calls, function);
            OK
        }
        Ok(Err(failure)) => failed::<D, M>(inst, function, failure),
        Err(_) => panicked(inst, function),
    }
}

/// `function` refused or failed: its status, and its message to the logger. Out of line (cold):
/// the successful path of every call stays short (docs/performance.md "Model Exchange").
#[cold]
#[inline(never)]
unsafe fn failed<D: Dialect, M: FmuModel>(
    inst: *mut Instance<M>,
    function: &str,
    failure: Failure,
) -> Status {
    let status = status_of(failure.severity);
    let category =
        if failure.severity == Severity::Discard { Category::Warning } else { Category::Error };
    // Every message names the function that failed.
    let named = if D::ANY_NAME {
        failure.message.starts_with("fmi")
    } else {
        failure.message.starts_with(function)
    };
    if named {
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
pub(crate) unsafe fn panicked<M: FmuModel>(inst: *mut Instance<M>, function: &str) -> Status {
    let _ = catch_unwind(AssertUnwindSafe(|| {
        (*inst).set_fatal();
        (*inst).log(FATAL, Category::Error, &format!("{function}: internal error (panic caught)"));
    }));
    FATAL
}

/// A function of an interface or feature this FMU does not declare: an error naming it and why.
pub(crate) unsafe fn unsupported<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    why: &str,
) -> Status {
    call::<D, M>(c, function, |_| Err(Failure::error(format!("{function}: {why}"))))
}

/// A C string (`fmi2String`, `fmi3String`); None for NULL or text that is not UTF-8.
pub(crate) unsafe fn opt_str<'a>(s: *const c_char) -> Option<&'a str> {
    if s.is_null() {
        None
    } else {
        CStr::from_ptr(s).to_str().ok()
    }
}

/// A slice from a C array; NULL is only accepted for an empty array.
pub(crate) unsafe fn slice<'a, T>(p: *const T, n: usize) -> Option<&'a [T]> {
    if n == 0 {
        Some(&[])
    } else if p.is_null() {
        None
    } else {
        Some(std::slice::from_raw_parts(p, n))
    }
}

#[cold]
#[inline(never)]
pub(crate) fn null_argument(function: &str, what: &str) -> Failure {
    Failure::error(format!("{function}: {what} is NULL"))
}

/// Stores a snapshot in the importer's FMUstate: reuses a state it passes back (FMI 2.0 allows
/// that), else allocates one, which the instance keeps track of so that fmi2FreeInstance frees
/// it if the importer does not.
pub(crate) unsafe fn store_snapshot<M: FmuModel>(
    inst: &mut Instance<M>,
    state: *mut *mut c_void,
    snap: Snapshot<M>,
) {
    let existing = *state as *mut Snapshot<M>;
    if !existing.is_null()
        && inst.states.contains(&(existing as usize))
        && (*existing).magic == snapshot_magic::<M>()
    {
        *existing = snap;
    } else {
        *state = Box::into_raw(Box::new(snap)) as *mut c_void;
        inst.states.push(*state as usize);
    }
}

pub(crate) unsafe fn snapshot_ref<'a, M: FmuModel>(
    function: &str,
    state: *mut c_void,
) -> Result<&'a Snapshot<M>, Failure> {
    let s = state as *const Snapshot<M>;
    if s.is_null() {
        return Err(null_argument(function, "FMUstate"));
    }
    if (*s).magic != snapshot_magic::<M>() {
        return Err(Failure::error(format!("{function}: FMUstate was not made by this FMU")));
    }
    Ok(&*s)
}

/// An output array of `n` values; NULL is only accepted for an empty one.
pub(crate) unsafe fn out_slice<'a, T>(
    function: &str,
    what: &str,
    p: *mut T,
    n: usize,
) -> Result<&'a mut [T], Failure> {
    if n == 0 {
        Ok(&mut [])
    } else if p.is_null() {
        Err(null_argument(function, what))
    } else {
        Ok(std::slice::from_raw_parts_mut(p, n))
    }
}

// ------------------------------------------------------------------------------ instantiation

/// What every instantiate function does, inside the panic barrier: the importer's logger
/// (`logger`), then `check` (the standard's checks of the arguments, in its order) refuses with
/// one line naming `function`, else a new instance behind a new handle. NULL on a refusal or a
/// panic.
pub(crate) fn instantiate<M: FmuModel>(
    function: &str,
    logger: impl FnOnce() -> Logger,
    check: impl FnOnce() -> Option<String>,
    resource_dir: impl FnOnce() -> Option<PathBuf>,
    model_exchange: bool,
) -> *mut c_void {
    let result = catch_unwind(AssertUnwindSafe(|| {
        let logger = logger();
        if let Some(why) = check() {
            logger.log(ERROR, Category::Error, &format!("{function}: {why}"));
            return ptr::null_mut();
        }
        let mut inst = Box::new(Instance::<M>::new(logger, resource_dir()));
        inst.model_exchange = model_exchange;
        inst.log(
            OK,
            Category::Events,
            &format!("instantiated; resources: {:?}", inst.resource_dir),
        );
        new_handle(inst)
    }));
    result.unwrap_or(ptr::null_mut())
}

/// fmi2SetDebugLogging, fmi3SetDebugLogging.
pub(crate) unsafe fn set_debug_logging<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    on: bool,
    n: usize,
    categories: *const *const c_char,
) -> Status {
    call::<D, M>(c, function, |inst| {
        let cats = slice(categories, n).ok_or_else(|| null_argument(function, "categories"))?;
        let mut names = Vec::with_capacity(cats.len());
        for &p in cats {
            names.push(opt_str(p).ok_or_else(|| null_argument(function, "a category name"))?);
        }
        inst.logger
            .set_debug_logging(on, &names)
            .map_err(|e| Failure::error(format!("{function}: {e}")))
    })
}

// ------------------------------------------------------------------------------ get and set

/// The fast path of fmi2GetReal and fmi3GetFloat64 (`Instance::quick_get_real`), still behind
/// the panic barrier: it evaluates the model. None: the call needs the general path (anything
/// that needs a message), which evaluates again and reports. One copy per caller (`API`: 2 for
/// fmi2GetReal, 3 for fmi3GetFloat64), as `Instance::quick_set_real`: with one copy shared by
/// both, LLVM kept the panic barrier's closure out of line, 31 more instructions per fmi2GetReal
/// (callgrind, scripts/bench_ratio.py --instructions).
#[inline(always)]
pub(crate) unsafe fn quick_get_real<M: FmuModel, const API: u8>(
    c: *mut c_void,
    function: &str,
    vr: *const u32,
    nvr: usize,
    value: *mut f64,
) -> Option<Status> {
    let inst = live::<M>(c)?;
    if let (Some(vrs), false) = (slice(vr, nvr), nvr > 0 && value.is_null()) {
        let out: &mut [f64] =
            if nvr == 0 { &mut [] } else { std::slice::from_raw_parts_mut(value, nvr) };
        match catch_unwind(AssertUnwindSafe(|| (*inst).quick_get_real(vrs, out))) {
            Ok(true) => return Some(OK),
            Ok(false) => {}
            Err(_) => return Some(panicked(inst, function)),
        }
    }
    None
}

/// The fast path of fmi2SetReal and fmi3SetFloat64: finite crank inputs at every step cannot
/// panic (proved at link time, `Instance::quick_set_real`) and need no barrier. False: the call
/// needs the general path.
#[inline(always)]
pub(crate) unsafe fn quick_set_real<M: FmuModel, const N: u8>(
    c: *mut c_void,
    vr: *const u32,
    nvr: usize,
    value: *const f64,
) -> bool {
    if let Some(inst) = live::<M>(c) {
        if let (Some(vrs), Some(vals)) = (slice(vr, nvr), slice(value, nvr)) {
            return (*inst).quick_set_real::<N>(vrs, vals);
        }
    }
    false
}

/// FMI 3.0 passes the length of the values array too: with scalar variables only it must equal
/// the number of value references.
fn check_count(function: &str, nvr: usize, n_values: Option<usize>) -> Result<(), Failure> {
    match n_values {
        Some(n) if n != nvr => Err(Failure::error(format!(
            "{function}: nValues = {n} does not match nValueReferences = {nvr} (every variable \
             of this FMU is a scalar)"
        ))),
        _ => Ok(()),
    }
}

/// The get functions' general path (`n_values`: FMI 3.0's length of the values array); out of
/// line so that the fast path of fmi2GetReal sets up no stack frame for it (its messages need
/// kilobytes).
#[inline(never)]
pub(crate) unsafe fn get_values<D: Dialect, M: FmuModel, T: Copy>(
    c: *mut c_void,
    function: &'static str,
    ty: VarType,
    vr: *const u32,
    nvr: usize,
    value: *mut T,
    n_values: Option<usize>,
    convert: impl Fn(f64) -> T,
) -> Status {
    call::<D, M>(c, function, |inst| {
        let vrs = slice(vr, nvr).ok_or_else(|| null_argument(function, D::VR))?;
        check_count(function, nvr, n_values)?;
        if nvr > 0 && value.is_null() {
            return Err(null_argument(function, D::VALUES));
        }
        inst.get(function, ty, vrs, |k, v| *value.add(k) = convert(v))
    })
}

/// The set functions' general path, as [`get_values`].
#[inline(never)]
pub(crate) unsafe fn set_values<D: Dialect, M: FmuModel, T: Copy>(
    c: *mut c_void,
    function: &'static str,
    ty: VarType,
    vr: *const u32,
    nvr: usize,
    value: *const T,
    n_values: Option<usize>,
    convert: impl Fn(T) -> f64,
) -> Status {
    call::<D, M>(c, function, |inst| {
        let vrs = slice(vr, nvr).ok_or_else(|| null_argument(function, D::VR))?;
        check_count(function, nvr, n_values)?;
        let vals = slice(value, nvr).ok_or_else(|| null_argument(function, D::VALUES))?;
        inst.set(function, ty, vrs, |k| convert(vals[k]))
    })
}

/// Get or set of a type this FMU has no variable of: only an empty list is accepted; `what` says
/// which types it has.
pub(crate) unsafe fn no_variables<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    type_name: &str,
    what: &str,
    vr: *const u32,
    nvr: usize,
) -> Status {
    call::<D, M>(c, function, |_| match slice(vr, nvr) {
        Some([]) => Ok(()),
        Some(v) => Err(Failure::error(format!(
            "{function}: value reference {} is not a {type_name} variable ({what})",
            v[0]
        ))),
        None => Err(null_argument(function, D::VR)),
    })
}

// ------------------------------------------------------------------------------ FMU state

/// fmi2GetFMUstate, fmi3GetFMUState.
pub(crate) unsafe fn get_fmu_state<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    state: *mut *mut c_void,
) -> Status {
    call::<D, M>(c, function, |inst| {
        if state.is_null() {
            return Err(null_argument(function, D::FMU_STATE));
        }
        let snap = inst.snapshot();
        store_snapshot(inst, state, snap);
        Ok(())
    })
}

/// fmi2SetFMUstate, fmi3SetFMUState.
pub(crate) unsafe fn set_fmu_state<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    state: *mut c_void,
) -> Status {
    call::<D, M>(c, function, |inst| inst.restore(snapshot_ref::<M>(function, state)?))
}

/// fmi2FreeFMUstate, fmi3FreeFMUState: NULL or a pointer to NULL is nothing to free.
pub(crate) unsafe fn free_fmu_state<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    state: *mut *mut c_void,
) -> Status {
    call::<D, M>(c, function, |inst| {
        if state.is_null() || (*state).is_null() {
            return Ok(());
        }
        let s = *state as *mut Snapshot<M>;
        let what = D::FMU_STATE;
        let Some(pos) = inst.states.iter().position(|&p| p == s as usize) else {
            return Err(Failure::error(format!(
                "{function}: {what} was not made by this instance (or was freed)"
            )));
        };
        if (*s).magic != snapshot_magic::<M>() {
            return Err(Failure::error(format!("{function}: {what} was not made by this FMU")));
        }
        inst.states.swap_remove(pos);
        (*s).magic = 0;
        drop(Box::from_raw(s));
        *state = ptr::null_mut();
        Ok(())
    })
}

/// fmi2SerializedFMUstateSize, fmi3SerializedFMUStateSize.
pub(crate) unsafe fn serialized_size<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    state: *mut c_void,
    size: *mut usize,
) -> Status {
    call::<D, M>(c, function, |_| {
        let snap = snapshot_ref::<M>(function, state)?;
        if size.is_null() {
            return Err(null_argument(function, "size"));
        }
        *size = fmu_state::serialize::<M>(&snap.core)?.len();
        Ok(())
    })
}

/// fmi2SerializeFMUstate, fmi3SerializeFMUState.
pub(crate) unsafe fn serialize<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    state: *mut c_void,
    bytes: *mut u8,
    size: usize,
) -> Status {
    call::<D, M>(c, function, |_| {
        let snap = snapshot_ref::<M>(function, state)?;
        let data = fmu_state::serialize::<M>(&snap.core)?;
        if bytes.is_null() || size < data.len() {
            return Err(Failure::error(format!(
                "{function}: buffer of {size} bytes is too small; {} needed",
                data.len()
            )));
        }
        ptr::copy_nonoverlapping(data.as_ptr(), bytes, data.len());
        Ok(())
    })
}

/// fmi2DeSerializeFMUstate, fmi3DeserializeFMUState.
pub(crate) unsafe fn deserialize<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    bytes: *const u8,
    size: usize,
    state: *mut *mut c_void,
) -> Status {
    call::<D, M>(c, function, |inst| {
        let data = slice(bytes, size).ok_or_else(|| null_argument(function, "serializedState"))?;
        if state.is_null() {
            return Err(null_argument(function, D::FMU_STATE));
        }
        let snap = Instance::<M>::snapshot_from_core(fmu_state::deserialize::<M>(data)?)?;
        store_snapshot(inst, state, snap);
        Ok(())
    })
}

// ------------------------------------------------------------------------------ derivatives

/// fmi2GetDirectionalDerivative, fmi3GetDirectionalDerivative (`counts`: FMI 3.0's nSeed and
/// nSensitivity, which must equal nKnowns and nUnknowns), every argument checked, inside the
/// panic barrier (`crate::fmi::directional`).
pub(crate) unsafe fn get_directional_derivative<D: Dialect, M: FmuModel>(
    c: *mut c_void,
    function: &str,
    unknowns: *const u32,
    n_unknowns: usize,
    knowns: *const u32,
    n_knowns: usize,
    seed: *const f64,
    sensitivity: *mut f64,
    counts: Option<(usize, usize)>,
) -> Status {
    let f = function;
    let [unknowns_name, knowns_name, seed_name, sensitivity_name] = D::DIRECTIONAL;
    call::<D, M>(c, f, |inst| {
        if let Some((n_seed, n_sensitivity)) = counts {
            if n_seed != n_knowns || n_sensitivity != n_unknowns {
                return Err(Failure::error(format!(
                    "{f}: nSeed = {n_seed} must equal nKnowns = {n_knowns} and nSensitivity = \
                     {n_sensitivity} must equal nUnknowns = {n_unknowns}"
                )));
            }
        }
        let u = slice(unknowns, n_unknowns).ok_or_else(|| null_argument(f, unknowns_name))?;
        let k = slice(knowns, n_knowns).ok_or_else(|| null_argument(f, knowns_name))?;
        let s = slice(seed, n_knowns).ok_or_else(|| null_argument(f, seed_name))?;
        let out = out_slice(f, sensitivity_name, sensitivity, n_unknowns)?;
        // Both standards number the states and their derivatives alike (`crate::fmi::structure`).
        directional_derivative::<M>(inst, f, u, k, s, out, &model_exchange_refs::<M>())
    })
}

// ------------------------------------------------------------------------------ exports

/// The `#[no_mangle] extern "C"` shims of the export macros (`export_fmu!`, `export_fmu3!`, the
/// FMI 2.0 Model Exchange exports), one line per function: each calls the function of the same
/// name in the standard's `glue` module for the model `M` (both in scope where it expands), and
/// its type is checked at compile time against the official headers (the `…TYPE` named beside
/// it, generated by bindgen in fmi-sys).
#[doc(hidden)]
#[macro_export]
macro_rules! __fmi_exports {
    ($($name:ident: $ty:ident($($arg:ident: $t:ty),* $(,)?) -> $ret:ty;)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $name($($arg: $t),*) -> $ret {
            glue::$name::<M>($($arg),*)
        }
        const _: $ty = Some($name);
    )*};
}
