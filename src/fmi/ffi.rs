//! Core layer: what the exported functions of both standards do around the instance core, written
//! once: C strings and arrays read with their checks, the refusal of a NULL argument, and the FMU
//! states the importer holds (a pointer to a [`Snapshot`], freed by the instance if the importer
//! does not). An `fmi2FMUstate` and an `fmi3FMUState` are both `void*`.

use std::ffi::{c_char, c_void, CStr};

use crate::fmi::instance::{snapshot_magic, Failure, Instance, Snapshot};
use crate::fmi::model::FmuModel;

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
