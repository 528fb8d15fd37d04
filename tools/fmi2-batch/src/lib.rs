//! The per-sample inner loops of the digital twin, called from Python through ctypes
//! (python/reciprocating_drive/fmu/batch.py): a batch driver of any loaded FMI 2.0 co-simulation FMU
//! (`fmi2_batch_run`), the cases of a design sweep, each initialized and run over all its steps
//! (`fmi2_batch_cases`), rows of numbers as CSV exactly as Python's repr writes them
//! (`fmi2_batch_format_csv`), the local-cubic speed and acceleration estimate
//! (`fmi2_batch_local_cubic`) and the clean lines of the input CSV (`fmi2_batch_parse_csv`).
//!
//! The driver knows nothing about the FMU it drives: the caller passes the FMU's own
//! `fmi2DoStep`, `fmi2SetReal` and `fmi2GetReal` (as loaded by fmpy) and the component. Every
//! exported function checks its pointers and catches panics, so nothing unwinds across the C
//! boundary; failures are return codes.

pub mod cases;
mod csv;
pub mod fit;
pub mod parse;

use std::os::raw::{c_int, c_uint, c_void};
use std::panic::{catch_unwind, AssertUnwindSafe};

pub use cases::{CaseFailure, CaseFunctions, SetGroup};
pub use csv::{format_number, MAX_NUMBER_LEN};

/// `fmi2SetReal(c, vr[], nvr, value[])`
pub type SetReal = unsafe extern "C" fn(*mut c_void, *const c_uint, usize, *const f64) -> c_int;
/// `fmi2GetReal(c, vr[], nvr, value[])`
pub type GetReal = unsafe extern "C" fn(*mut c_void, *const c_uint, usize, *mut f64) -> c_int;
/// `fmi2DoStep(c, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint)`
pub type DoStep = unsafe extern "C" fn(*mut c_void, f64, f64, c_int) -> c_int;

/// Which call of a sample failed (`Failure::function`).
pub const FAILED_NONE: c_int = 0;
pub const FAILED_DO_STEP: c_int = 1;
pub const FAILED_SET_REAL: c_int = 2;
pub const FAILED_GET_REAL: c_int = 3;

/// Return codes other than a count of samples.
pub const BAD_ARGUMENTS: isize = -1;
pub const PANICKED: isize = -2;

/// The order of the calls at each communication point k.
/// `ORDER_STEP_SET_GET`: fmi2DoStep to t[k], fmi2SetReal of input row k, fmi2GetReal into output
/// row k (inputs are the state at t[k] and the outputs read belong to them: the digital twin).
/// `ORDER_SET_STEP_GET`: fmi2SetReal of row k, fmi2DoStep to t[k], fmi2GetReal (inputs held over
/// the step that ends at t[k]: a classic co-simulation master).
pub const ORDER_STEP_SET_GET: c_int = 0;
pub const ORDER_SET_STEP_GET: c_int = 1;

/// Where a batch stopped: the status of the first call whose status exceeded `worst_ok`, and
/// which call it was (`FAILED_*`); `FAILED_NONE` and status 0 when every sample succeeded.
#[repr(C)]
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Failure {
    pub status: c_int,
    pub function: c_int,
}

/// The FMU's functions and component, and the value references of the batch.
pub struct Fmu {
    pub set_real: SetReal,
    pub do_step: DoStep,
    pub get_real: GetReal,
    pub component: *mut c_void,
}

/// Runs communication points `t` (sample k's inputs at `inputs[k * in_stride..][..vr_in.len()]`,
/// its outputs into `outputs[k * out_stride..][..vr_out.len()]`) from the FMU time `t_start`.
/// Stops at the first call whose status exceeds `worst_ok` (fmi2Warning = 1 accepts warnings).
/// Returns the number of samples completed and the failure, if any; the rows before it are
/// written, the rows after it untouched.
///
/// # Safety
/// The function pointers and component must be a live FMU instance; the slices must hold the
/// rows described.
#[allow(clippy::too_many_arguments)]
pub unsafe fn run(
    fmu: &Fmu,
    vr_in: &[c_uint],
    vr_out: &[c_uint],
    t_start: f64,
    t: &[f64],
    inputs: &[f64],
    in_stride: usize,
    outputs: &mut [f64],
    out_stride: usize,
    order: c_int,
    worst_ok: c_int,
) -> (usize, Failure) {
    let mut now = t_start;
    for (k, &tk) in t.iter().enumerate() {
        let x = inputs[k * in_stride..][..vr_in.len()].as_ptr();
        let set = || (fmu.set_real)(fmu.component, vr_in.as_ptr(), vr_in.len(), x);
        let step = || (fmu.do_step)(fmu.component, now, tk - now, 1);
        let calls: [(c_int, &dyn Fn() -> c_int); 2] = if order == ORDER_SET_STEP_GET {
            [(FAILED_SET_REAL, &set), (FAILED_DO_STEP, &step)]
        } else {
            [(FAILED_DO_STEP, &step), (FAILED_SET_REAL, &set)]
        };
        for (function, call) in calls {
            let status = call();
            if status > worst_ok {
                return (k, Failure { status, function });
            }
        }
        now = tk;
        let y = outputs[k * out_stride..][..vr_out.len()].as_mut_ptr();
        let status = (fmu.get_real)(fmu.component, vr_out.as_ptr(), vr_out.len(), y);
        if status > worst_ok {
            return (k, Failure { status, function: FAILED_GET_REAL });
        }
    }
    (t.len(), Failure::default())
}

/// Length of a strided array of `rows` rows of `width` values; None on overflow.
fn strided_len(rows: usize, stride: usize, width: usize) -> Option<usize> {
    if rows == 0 {
        return Some(0);
    }
    if stride < width {
        return None;
    }
    (rows - 1).checked_mul(stride)?.checked_add(width)
}

unsafe fn slice<'a, T>(p: *const T, len: usize) -> Option<&'a [T]> {
    if len == 0 {
        return Some(&[]);
    }
    (!p.is_null()).then(|| std::slice::from_raw_parts(p, len))
}

unsafe fn slice_mut<'a, T>(p: *mut T, len: usize) -> Option<&'a mut [T]> {
    if len == 0 {
        return Some(&mut []);
    }
    (!p.is_null()).then(|| std::slice::from_raw_parts_mut(p, len))
}

/// C entry of [`run`]. Returns the number of samples completed (then `*failure` says whether and
/// where it stopped), `BAD_ARGUMENTS` for a null pointer, a stride narrower than its row or an
/// unknown order, `PANICKED` if a panic was caught.
///
/// # Safety
/// As [`run`]; `failure` must be writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2_batch_run(
    set_real: Option<SetReal>,
    do_step: Option<DoStep>,
    get_real: Option<GetReal>,
    component: *mut c_void,
    vr_in: *const c_uint,
    n_in: usize,
    vr_out: *const c_uint,
    n_out: usize,
    t_start: f64,
    n: usize,
    t: *const f64,
    inputs: *const f64,
    in_stride: usize,
    outputs: *mut f64,
    out_stride: usize,
    order: c_int,
    worst_ok: c_int,
    failure: *mut Failure,
) -> isize {
    let result = catch_unwind(AssertUnwindSafe(|| {
        let (Some(set_real), Some(do_step), Some(get_real)) = (set_real, do_step, get_real) else {
            return BAD_ARGUMENTS;
        };
        if failure.is_null()
            || component.is_null()
            || !(order == ORDER_STEP_SET_GET || order == ORDER_SET_STEP_GET)
        {
            return BAD_ARGUMENTS;
        }
        let (Some(ni), Some(no)) =
            (strided_len(n, in_stride, n_in), strided_len(n, out_stride, n_out))
        else {
            return BAD_ARGUMENTS;
        };
        let (Some(vr_in), Some(vr_out), Some(t), Some(x), Some(y)) = (
            slice(vr_in, n_in),
            slice(vr_out, n_out),
            slice(t, n),
            slice(inputs, ni),
            slice_mut(outputs, no),
        ) else {
            return BAD_ARGUMENTS;
        };
        let fmu = Fmu { set_real, do_step, get_real, component };
        let (done, f) =
            run(&fmu, vr_in, vr_out, t_start, t, x, in_stride, y, out_stride, order, worst_ok);
        *failure = f;
        done as isize
    }));
    result.unwrap_or(PANICKED)
}

/// A slice of `len` doubles at `p`: None if `p` is null or not aligned for f64.
unsafe fn doubles<'a>(p: *const f64, len: usize) -> Option<&'a [f64]> {
    (p as usize).is_multiple_of(std::mem::align_of::<f64>()).then_some(())?;
    slice(p, len)
}

unsafe fn doubles_mut<'a>(p: *mut f64, len: usize) -> Option<&'a mut [f64]> {
    (p as usize).is_multiple_of(std::mem::align_of::<f64>()).then_some(())?;
    slice_mut(p, len)
}

/// C entry of [`cases::run_cases`]: `n_cases` cases, case c at crank speed `omega[c]` with
/// communication step `h[c]`, its initialization values row c of each of the `n_groups` groups,
/// its `n_steps + 1` rows of the `n_out` outputs `vr_out` at `outputs + c * case_stride`, the
/// seconds of its calls at `seconds[c]`; `vr_in` the two value references of the crank's angle
/// and speed; `started` non-zero if the instance has run (the first case resets it). Returns the
/// number of cases completed (then `*failure` says whether and where it stopped),
/// `BAD_ARGUMENTS` for a null or misaligned pointer, a missing function, a value width other
/// than 4 or 8 bytes or a stride narrower than its row, `PANICKED` if a panic was caught.
///
/// # Safety
/// As [`cases::run_cases`]; every pointer must hold what its count and stride describe and
/// `failure` must be writable.
#[no_mangle]
pub unsafe extern "C" fn fmi2_batch_cases(
    functions: *const CaseFunctions,
    component: *mut c_void,
    started: c_int,
    groups: *const SetGroup,
    n_groups: usize,
    vr_in: *const c_uint,
    vr_out: *const c_uint,
    n_out: usize,
    n_cases: usize,
    omega: *const f64,
    h: *const f64,
    n_steps: usize,
    outputs: *mut f64,
    case_stride: usize,
    seconds: *mut f64,
    worst_ok: c_int,
    failure: *mut CaseFailure,
) -> isize {
    let result = catch_unwind(AssertUnwindSafe(|| {
        if functions.is_null() || component.is_null() || failure.is_null() {
            return BAD_ARGUMENTS;
        }
        let f = *functions;
        let (Some(reset), Some(setup), Some(enter), Some(exit)) =
            (f.reset, f.setup, f.enter, f.exit)
        else {
            return BAD_ARGUMENTS;
        };
        let (Some(set_real), Some(do_step), Some(get_real)) = (f.set_real, f.do_step, f.get_real)
        else {
            return BAD_ARGUMENTS;
        };
        let Some(rows) = n_steps.checked_add(1).and_then(|r| r.checked_mul(n_out)) else {
            return BAD_ARGUMENTS;
        };
        let (Some(no), Some(groups)) =
            (strided_len(n_cases, case_stride, rows), slice(groups, n_groups))
        else {
            return BAD_ARGUMENTS;
        };
        let (Some(vr_in), Some(vr_out), Some(omega), Some(h), Some(y), Some(s)) = (
            slice(vr_in, 2),
            slice(vr_out, n_out),
            doubles(omega, n_cases),
            doubles(h, n_cases),
            doubles_mut(outputs, no),
            doubles_mut(seconds, n_cases),
        ) else {
            return BAD_ARGUMENTS;
        };
        let mut sets = Vec::with_capacity(groups.len());
        for g in groups {
            let width = g.n.checked_mul(g.value_bytes);
            let len = width.and_then(|w| strided_len(n_cases, g.row_bytes, w));
            let (Some(set), true, Some(len)) = (g.set, matches!(g.value_bytes, 4 | 8), len) else {
                return BAD_ARGUMENTS;
            };
            let (Some(vr), Some(values)) = (slice(g.vr, g.n), slice(g.values, len)) else {
                return BAD_ARGUMENTS;
            };
            sets.push((set, vr, values, g.row_bytes));
        }
        let a = cases::Cases {
            reset,
            setup,
            enter,
            exit,
            fmu: Fmu { set_real, do_step, get_real, component },
            groups: sets,
            vr_in,
            vr_out,
            omega,
            h,
            n_steps,
        };
        let (done, fail) = cases::run_cases(&a, started != 0, y, case_stride, s, worst_ok);
        *failure = fail;
        done as isize
    }));
    result.unwrap_or(PANICKED)
}

/// Formats `rows` rows of `cols` numbers (row k at `values + k * row_stride`) as CSV lines, each
/// number exactly as Python's `repr(float)` writes it, into `out` (`capacity` bytes). Returns the
/// bytes written, `BAD_ARGUMENTS` for null pointers, a narrow stride or a buffer shorter than
/// `rows * (cols * (MAX_NUMBER_LEN + 1))` bytes, `PANICKED` if a panic was caught.
///
/// # Safety
/// `values` must hold the rows described and `out` `capacity` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn fmi2_batch_format_csv(
    values: *const f64,
    rows: usize,
    cols: usize,
    row_stride: usize,
    out: *mut u8,
    capacity: usize,
) -> isize {
    let result = catch_unwind(AssertUnwindSafe(|| {
        let need = cols.checked_mul(MAX_NUMBER_LEN + 1).and_then(|r| r.checked_mul(rows));
        let (Some(len), Some(need)) = (strided_len(rows, row_stride, cols), need) else {
            return BAD_ARGUMENTS;
        };
        if need > capacity || cols == 0 {
            return BAD_ARGUMENTS;
        }
        let (Some(v), Some(buf)) = (slice(values, len), slice_mut(out, capacity)) else {
            return BAD_ARGUMENTS;
        };
        csv::format_rows(v, rows, cols, row_stride, buf) as isize
    }));
    result.unwrap_or(PANICKED)
}

/// The longest number `fmi2_batch_format_csv` writes, in bytes (for sizing its buffer).
#[no_mangle]
pub extern "C" fn fmi2_batch_max_number_len() -> usize {
    MAX_NUMBER_LEN
}

/// ω and ε (`fit::at`) at the centres `first .. first + count` of the `n` samples (times `t`,
/// strictly increasing, unwrapped angles `theta`) of a segment spanning `t_start .. t_end`
/// (`t_end` infinite while it goes on), each from the samples within ±`half` seconds of it
/// (`fit::window`), into `out_w` and `out_e`, and the number of samples within that time span
/// into `out_count` (below `fit::MIN_SAMPLES`: a sparse window, fitted to the samples around
/// the centre). Returns `count`, or the index of the first centre whose window is singular (its
/// outputs NaN), `BAD_ARGUMENTS` for null pointers, `n` < 4, a `half` that is not finite and
/// >= 0, or a range outside the samples, `PANICKED` if a panic was caught.
///
/// # Safety
/// `t` and `theta` must hold `n` values, `out_w`, `out_e` and `out_count` `count` writable
/// values.
#[no_mangle]
#[allow(clippy::too_many_arguments)] // a C ABI: each argument is a pointer or a scalar
pub unsafe extern "C" fn fmi2_batch_local_cubic(
    t: *const f64,
    theta: *const f64,
    n: usize,
    half: f64,
    t_start: f64,
    t_end: f64,
    first: usize,
    count: usize,
    out_w: *mut f64,
    out_e: *mut f64,
    out_count: *mut u64,
) -> isize {
    let result = catch_unwind(AssertUnwindSafe(|| {
        // A window of width 0 (a subnormal --window halved) is legal: every window is sparse.
        #[allow(clippy::neg_cmp_op_on_partial_ord)] // `!(half >= 0)` also rejects NaN
        let bad_half = !(half >= 0.0) || !half.is_finite();
        if n < 4 || bad_half || first.checked_add(count).is_none_or(|end| end > n) {
            return BAD_ARGUMENTS;
        }
        let (Some(t), Some(theta), Some(w), Some(e), Some(k)) = (
            slice(t, n),
            slice(theta, n),
            slice_mut(out_w, count),
            slice_mut(out_e, count),
            slice_mut(out_count, count),
        ) else {
            return BAD_ARGUMENTS;
        };
        let long = fit::long_intervals(t, half);
        let mut singular = None;
        for j in 0..count {
            let c = first + j;
            let (lo, hi, inside) = fit::window_in(t, &long, c, half, t_start, t_end);
            k[j] = inside as u64;
            (w[j], e[j]) = fit::at(t, theta, lo, hi, c).unwrap_or_else(|| {
                singular.get_or_insert(j);
                (f64::NAN, f64::NAN)
            });
        }
        singular.unwrap_or(count) as isize
    }));
    result.unwrap_or(PANICKED)
}

/// Parses the clean lines (`parse::clean_prefix`) of `text` (`len` bytes, lines separated by
/// '\n', at most `max_lines`): `n_cols` wanted fields at indices `cols`, empty ones given
/// `defaults[j]` when `required[j]` is 0, into `out[j]` (each `max_lines` values). Returns the
/// number of lines parsed, `BAD_ARGUMENTS` for null pointers, `PANICKED` if a panic was caught.
///
/// # Safety
/// The pointers must hold the values described; `out` `n_cols` pointers to `max_lines` values.
#[no_mangle]
pub unsafe extern "C" fn fmi2_batch_parse_csv(
    text: *const u8,
    len: usize,
    n_fields: usize,
    n_cols: usize,
    cols: *const usize,
    required: *const c_int,
    defaults: *const f64,
    out: *const *mut f64,
    max_lines: usize,
) -> isize {
    let result = catch_unwind(AssertUnwindSafe(|| {
        let (Some(text), Some(cols), Some(required), Some(defaults), Some(out)) = (
            slice(text, len),
            slice(cols, n_cols),
            slice(required, n_cols),
            slice(defaults, n_cols),
            slice(out, n_cols),
        ) else {
            return BAD_ARGUMENTS;
        };
        if cols.iter().any(|&c| c >= n_fields) {
            return BAD_ARGUMENTS;
        }
        let mut columns = Vec::with_capacity(n_cols);
        for &p in out {
            let Some(col) = slice_mut(p, max_lines) else {
                return BAD_ARGUMENTS;
            };
            columns.push(col);
        }
        let defaults: Vec<Option<f64>> =
            required.iter().zip(defaults).map(|(&r, &d)| (r == 0).then_some(d)).collect();
        parse::clean_prefix(text, n_fields, cols, &defaults, &mut columns) as isize
    }));
    result.unwrap_or(PANICKED)
}
