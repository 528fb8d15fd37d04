//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! What an `fmi2Component` and an `fmi3Instance` point to: a handle to the instance, not the
//! instance itself, so that an instance freed by fmi2FreeInstance or fmi3FreeInstance is
//! recognised (docs/fmi-interface.md "A freed instance"). Both standards' C ABIs
//! (`fmi2::abi`, `fmi3::abi`) share it, as they share the instance core.
//!
//! The handle outlives its instance, its pointer set to NULL by the free, and a second free or
//! any call on it returns an error instead of reading freed memory. A handle is never freed nor
//! reused (a reused one would let a stale pointer reach another instance of the importer): 16
//! bytes per instance made (41 with the allocator's overhead and the entry in [`HANDLES`]) stay
//! for the life of the process, kept in [`HANDLES`] so that leak checkers see them as reachable.
//! A call on a live instance pays one load for it (the handle's pointer, [`live`]).

use std::ffi::c_void;
use std::io::Write;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use crate::fmi::instance::{Instance, Snapshot};
use crate::fmi::model::FmuModel;

/// See the module's documentation.
struct Handle {
    /// The `Instance<M>`; NULL once freed.
    inst: *mut c_void,
    /// Whether a call on the freed instance was reported already (once per handle).
    reported: AtomicBool,
}

/// Every handle made in this process (see the module's documentation).
static HANDLES: Mutex<Vec<usize>> = Mutex::new(Vec::new());

/// A new handle to `inst`, which it owns until [`free_instance`]: the `fmi2Component` or
/// `fmi3Instance` the importer gets.
pub(crate) fn new_handle<M: FmuModel>(inst: Box<Instance<M>>) -> *mut c_void {
    let inst = Box::into_raw(inst) as *mut c_void;
    let h = Box::into_raw(Box::new(Handle { inst, reported: AtomicBool::new(false) }));
    HANDLES.lock().unwrap_or_else(|e| e.into_inner()).push(h as usize);
    h as *mut c_void
}

/// The live instance behind the handle `c`: None for NULL and for an instance already freed
/// (quietly: the caller reports it with [`report_freed`], or falls back to a path that does).
///
/// # Safety
/// `c` is NULL or a handle [`new_handle`] made for an `Instance<M>` (what the standard asks of the
/// importer: the pointer fmi2Instantiate or fmi3Instantiate… returned).
#[inline(always)]
pub(crate) unsafe fn live<M: FmuModel>(c: *mut c_void) -> Option<*mut Instance<M>> {
    if c.is_null() {
        return None;
    }
    let inst = (*(c as *const Handle)).inst;
    (!inst.is_null()).then_some(inst as *mut Instance<M>)
}

/// fmi2FreeInstance and fmi3FreeInstance (`function`): frees the instance behind `c` with the
/// FMU states the importer did not free (they belong to the instance, FMI 2.0 §2.1.5) and keeps
/// the handle, its pointer NULL. Nothing for NULL; an instance freed already is reported.
///
/// # Safety
/// `c` is NULL or a handle [`new_handle`] made for an `Instance<M>` (what the standard asks of the
/// importer: the pointer fmi2Instantiate or fmi3Instantiate… returned).
pub(crate) unsafe fn free_instance<M: FmuModel>(c: *mut c_void, function: &str) {
    if c.is_null() {
        return;
    }
    let Some(inst) = live::<M>(c) else {
        report_freed::<M>(c, function);
        return;
    };
    (*(c as *mut Handle)).inst = ptr::null_mut();
    let _ = catch_unwind(AssertUnwindSafe(|| {
        let mut inst = Box::from_raw(inst);
        for p in inst.states.drain(..) {
            let s = p as *mut Snapshot<M>;
            (*s).magic = 0;
            drop(Box::from_raw(s));
        }
        drop(inst);
    }));
}

/// A call of `function` on the non-NULL handle `c` of an instance that was freed: its logger went
/// with it (the importer may have released the callback's environment), so one line goes to
/// standard error instead, the first time per instance; the caller returns fmi2Error or
/// fmi3Error. `function` is named as the standard names it, and its prefix (`fmi2`, `fmi3`)
/// names the standard's free function and error status in the message.
///
/// # Safety
/// `c` is a handle [`new_handle`] made, not NULL.
#[cold]
#[inline(never)]
pub(crate) unsafe fn report_freed<M: FmuModel>(c: *mut c_void, function: &str) {
    let h = &*(c as *const Handle);
    if !h.reported.swap(true, Ordering::Relaxed) {
        let fmi = function.get(..4).unwrap_or("fmi2");
        let _ = catch_unwind(|| {
            let _ = writeln!(
                std::io::stderr(),
                "{}: {function}: instance {c:p} was freed by {fmi}FreeInstance; no call is \
                 allowed on it ({fmi}Error); instantiate a new one",
                M::info().model_identifier
            );
        });
    }
}
