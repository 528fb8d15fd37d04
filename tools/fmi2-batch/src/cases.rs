//! Many cases of a design sweep in one call (`fmi2_batch_cases`): for each case the FMU is
//! initialized with the case's values and run over all its communication steps with the crank
//! turning at the case's constant speed, the outputs of every point written into the case's rows.
//! The calls and their arguments are those of the per-step reference path of the sweeps
//! (python/reciprocating_drive/sweeps/cases.py, `run_case`; docs/sweeps.md "Execution"), in the same
//! order, so the FMU computes the same numbers bit for bit.

use std::os::raw::{c_int, c_uint, c_void};
use std::time::Instant;

use crate::{run, DoStep, Failure, Fmu, GetReal, SetReal, ORDER_SET_STEP_GET};

/// `fmi2Reset(c)`, `fmi2EnterInitializationMode(c)`, `fmi2ExitInitializationMode(c)`
pub type Call = unsafe extern "C" fn(*mut c_void) -> c_int;
/// `fmi2SetupExperiment(c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime)`
pub type Setup = unsafe extern "C" fn(*mut c_void, c_int, f64, f64, c_int, f64) -> c_int;
/// `fmi2SetReal`, `fmi2SetInteger` or `fmi2SetBoolean(c, vr[], nvr, value[])`, the values
/// untyped (the group says how wide one is).
pub type SetValues =
    unsafe extern "C" fn(*mut c_void, *const c_uint, usize, *const c_void) -> c_int;

/// Which call of a case failed (`CaseFailure::function`), beyond `FAILED_DO_STEP`,
/// `FAILED_SET_REAL` and `FAILED_GET_REAL` of the steps (and of the first point).
pub const FAILED_RESET: c_int = 4;
pub const FAILED_SETUP: c_int = 5;
pub const FAILED_ENTER: c_int = 6;
pub const FAILED_SET_VALUES: c_int = 7;
pub const FAILED_EXIT: c_int = 8;

/// The FMU's functions a case calls (as loaded by the host, e.g. fmpy).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct CaseFunctions {
    pub reset: Option<Call>,
    pub setup: Option<Setup>,
    pub enter: Option<Call>,
    pub exit: Option<Call>,
    pub set_real: Option<SetReal>,
    pub do_step: Option<DoStep>,
    pub get_real: Option<GetReal>,
}

/// The values of one type set in initialization mode: one `set` call per case with the `n` value
/// references `vr` and row `c` of the value matrix (`values + c * row_bytes`, `n` values of
/// `value_bytes` bytes each: 8 for fmi2Real, 4 for fmi2Integer and fmi2Boolean).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct SetGroup {
    pub set: Option<SetValues>,
    pub vr: *const c_uint,
    pub n: usize,
    pub values: *const u8,
    pub value_bytes: usize,
    pub row_bytes: usize,
}

/// Where a call of cases stopped: the case, its call (`FAILED_*`), the status it returned and,
/// for a step's call, the step (0 for the first point, k for the step to t_k); for
/// `FAILED_SET_VALUES` the group. All zero when every case succeeded.
#[repr(C)]
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct CaseFailure {
    pub case: usize,
    pub step: usize,
    pub status: c_int,
    pub function: c_int,
}

/// The arguments of [`run_cases`] once checked.
pub struct Cases<'a> {
    pub reset: Call,
    pub setup: Setup,
    pub enter: Call,
    pub exit: Call,
    pub fmu: Fmu,
    /// (set, value references, values of every case, bytes per case's row)
    pub groups: Vec<(SetValues, &'a [c_uint], &'a [u8], usize)>,
    /// The crank's angle and speed.
    pub vr_in: &'a [c_uint],
    pub vr_out: &'a [c_uint],
    pub omega: &'a [f64],
    pub h: &'a [f64],
    pub n_steps: usize,
}

/// Runs every case c: fmi2Reset (if the instance ran before: `started`, or an earlier case),
/// fmi2SetupExperiment(no tolerance, start 0, no stop time), fmi2EnterInitializationMode, each
/// group's set of row c, fmi2ExitInitializationMode, fmi2SetReal of the crank's state (0, ω) and
/// fmi2GetReal into row 0 of the case's outputs, then for k = 1 ..= n_steps fmi2SetReal of
/// (ω·(t_k − h), ω), fmi2DoStep from t_{k−1} to t_k = k·h and fmi2GetReal into row k: the inputs
/// at the step's start (docs/model.md §2), the same operations on the same numbers as run_case's
/// `omega * (t - h)` with `t = k * h`. Case c's n_steps + 1 rows go to `outputs[c * case_stride..]`
/// and the seconds its calls took to `seconds[c]`. Stops at the first call whose status exceeds
/// `worst_ok`; returns the cases completed and where it stopped.
///
/// # Safety
/// The functions and component must be a live FMU instance; the group's value rows must be of
/// the types its function expects.
pub unsafe fn run_cases(
    a: &Cases,
    started: bool,
    outputs: &mut [f64],
    case_stride: usize,
    seconds: &mut [f64],
    worst_ok: c_int,
) -> (usize, CaseFailure) {
    let c = a.fmu.component;
    let n_out = a.vr_out.len();
    let mut ran = started;
    // Times and inputs of the steps of one speed, kept while the next case has the same ω and h.
    let mut t = vec![0.0; a.n_steps];
    let mut x = vec![0.0; 2 * a.n_steps];
    let mut inputs_of: Option<(u64, u64)> = None;
    for case in 0..a.omega.len() {
        let clock = Instant::now();
        let fail = |function, status, step| CaseFailure { case, step, status, function };
        let (omega, h) = (a.omega[case], a.h[case]);
        if ran {
            let status = (a.reset)(c);
            if status > worst_ok {
                return (case, fail(FAILED_RESET, status, 0));
            }
        }
        ran = true;
        let status = (a.setup)(c, 0, 0.0, 0.0, 0, 0.0);
        if status > worst_ok {
            return (case, fail(FAILED_SETUP, status, 0));
        }
        let status = (a.enter)(c);
        if status > worst_ok {
            return (case, fail(FAILED_ENTER, status, 0));
        }
        for (g, &(set, vr, values, row)) in a.groups.iter().enumerate() {
            let status = set(c, vr.as_ptr(), vr.len(), values[case * row..].as_ptr().cast());
            if status > worst_ok {
                return (case, fail(FAILED_SET_VALUES, status, g));
            }
        }
        let status = (a.exit)(c);
        if status > worst_ok {
            return (case, fail(FAILED_EXIT, status, 0));
        }
        if inputs_of != Some((omega.to_bits(), h.to_bits())) {
            for k in 0..a.n_steps {
                let tk = (k + 1) as f64 * h;
                t[k] = tk;
                x[2 * k] = omega * (tk - h);
                x[2 * k + 1] = omega;
            }
            inputs_of = Some((omega.to_bits(), h.to_bits()));
        }
        let rows = &mut outputs[case * case_stride..][..(a.n_steps + 1) * n_out];
        let x0 = [0.0, omega];
        let status = (a.fmu.set_real)(c, a.vr_in.as_ptr(), a.vr_in.len(), x0.as_ptr());
        if status > worst_ok {
            return (case, fail(crate::FAILED_SET_REAL, status, 0));
        }
        let status = (a.fmu.get_real)(c, a.vr_out.as_ptr(), n_out, rows.as_mut_ptr());
        if status > worst_ok {
            return (case, fail(crate::FAILED_GET_REAL, status, 0));
        }
        let (done, f) = run(
            &a.fmu,
            a.vr_in,
            a.vr_out,
            0.0,
            &t,
            &x,
            2,
            &mut rows[n_out..],
            n_out,
            ORDER_SET_STEP_GET,
            worst_ok,
        );
        if f != Failure::default() {
            return (case, fail(f.function, f.status, done + 1));
        }
        seconds[case] = clock.elapsed().as_secs_f64();
    }
    (a.omega.len(), CaseFailure::default())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{fmi2_batch_cases, BAD_ARGUMENTS, FAILED_DO_STEP};
    use std::cell::RefCell;

    /// A toy FMU: it logs every call; its outputs are (time, angle, speed, the first Real value
    /// set in initialization mode); fmi2DoStep fails at the time `FAIL_AT` if one is set.
    #[derive(Default)]
    struct Toy {
        log: Vec<String>,
        time: f64,
        x: [f64; 2],
        p: f64,
        fail_at: Option<f64>,
    }
    thread_local!(static TOY: RefCell<Toy> = RefCell::new(Toy::default()));
    fn toy<R>(f: impl FnOnce(&mut Toy) -> R) -> R {
        TOY.with(|t| f(&mut t.borrow_mut()))
    }

    unsafe extern "C" fn reset(_: *mut c_void) -> c_int {
        toy(|t| t.log.push("reset".into()));
        0
    }
    unsafe extern "C" fn setup(
        _: *mut c_void,
        a: c_int,
        b: f64,
        c: f64,
        d: c_int,
        e: f64,
    ) -> c_int {
        toy(|t| {
            t.log.push(format!("setup {a} {b} {c} {d} {e}"));
            t.time = c;
        });
        0
    }
    unsafe extern "C" fn enter(_: *mut c_void) -> c_int {
        toy(|t| t.log.push("enter".into()));
        0
    }
    unsafe extern "C" fn exit(_: *mut c_void) -> c_int {
        toy(|t| t.log.push("exit".into()));
        0
    }
    unsafe extern "C" fn set_values(
        _: *mut c_void,
        vr: *const c_uint,
        n: usize,
        v: *const c_void,
    ) -> c_int {
        let vr = std::slice::from_raw_parts(vr, n);
        let v = std::slice::from_raw_parts(v.cast::<f64>(), n);
        toy(|t| {
            t.log.push(format!("set {vr:?} {v:?}"));
            t.p = v[0];
        });
        0
    }
    unsafe extern "C" fn set_real(
        _: *mut c_void,
        vr: *const c_uint,
        n: usize,
        v: *const f64,
    ) -> c_int {
        assert_eq!(std::slice::from_raw_parts(vr, n), [7, 8]);
        toy(|t| t.x.copy_from_slice(std::slice::from_raw_parts(v, 2)));
        0
    }
    unsafe extern "C" fn get_real(
        _: *mut c_void,
        _: *const c_uint,
        n: usize,
        v: *mut f64,
    ) -> c_int {
        let v = std::slice::from_raw_parts_mut(v, n);
        toy(|t| v.copy_from_slice(&[t.time, t.x[0], t.x[1], t.p]));
        0
    }
    unsafe extern "C" fn do_step(_: *mut c_void, now: f64, h: f64, _: c_int) -> c_int {
        toy(|t| {
            assert_eq!(now, t.time);
            t.time = now + h;
            if t.fail_at == Some(t.time) {
                3
            } else {
                0
            }
        })
    }

    const FUNCTIONS: CaseFunctions = CaseFunctions {
        reset: Some(reset),
        setup: Some(setup),
        enter: Some(enter),
        exit: Some(exit),
        set_real: Some(set_real),
        do_step: Some(do_step),
        get_real: Some(get_real),
    };

    struct Call {
        functions: CaseFunctions,
        component: *mut c_void,
        groups: Vec<SetGroup>,
        vr_in: [c_uint; 2],
        vr_out: [c_uint; 4],
        omega: Vec<f64>,
        h: Vec<f64>,
        n_steps: usize,
        outputs: Vec<f64>,
        stride: usize,
        seconds: Vec<f64>,
        values: Vec<f64>,
        /// Other pointers than the vectors' (null, misaligned)
        h_at: Option<*const f64>,
        outputs_at: Option<*mut f64>,
    }

    impl Call {
        fn new(omega: Vec<f64>, h: Vec<f64>, n_steps: usize) -> Call {
            let n = omega.len();
            let stride = (n_steps + 1) * 4;
            let values: Vec<f64> = (0..n).flat_map(|c| [c as f64 + 0.5, -1.0]).collect();
            let mut call = Call {
                functions: FUNCTIONS,
                component: std::ptr::dangling_mut::<c_void>(),
                groups: vec![],
                vr_in: [7, 8],
                vr_out: [1, 2, 3, 4],
                omega,
                h,
                n_steps,
                outputs: vec![f64::NAN; n * stride],
                stride,
                seconds: vec![-1.0; n],
                values,
                h_at: None,
                outputs_at: None,
            };
            call.groups = vec![SetGroup {
                set: Some(set_values),
                vr: [11, 12].as_ptr(),
                n: 2,
                values: call.values.as_ptr().cast(),
                value_bytes: 8,
                row_bytes: 16,
            }];
            call
        }

        fn run(&mut self, started: c_int) -> (isize, CaseFailure) {
            let mut failure = CaseFailure { case: 99, step: 99, status: 99, function: 99 };
            let done = unsafe {
                fmi2_batch_cases(
                    &self.functions,
                    self.component,
                    started,
                    self.groups.as_ptr(),
                    self.groups.len(),
                    self.vr_in.as_ptr(),
                    self.vr_out.as_ptr(),
                    4,
                    self.omega.len(),
                    self.omega.as_ptr(),
                    self.h_at.unwrap_or(self.h.as_ptr()),
                    self.n_steps,
                    self.outputs_at.unwrap_or(self.outputs.as_mut_ptr()),
                    self.stride,
                    self.seconds.as_mut_ptr(),
                    1,
                    &mut failure,
                )
            };
            (done, failure)
        }
    }

    #[test]
    fn every_case_is_initialized_and_run_with_its_values_and_speed() {
        toy(|t| *t = Toy::default());
        let (w, h) = (vec![3.0, 3.0, 7.5], vec![0.125, 0.125, 0.375]);
        let mut call = Call::new(w.clone(), h.clone(), 5);
        assert_eq!(call.run(0), (3, CaseFailure::default()));
        let log = toy(|t| std::mem::take(&mut t.log));
        let case = |c: usize| {
            vec![
                "setup 0 0 0 0 0".to_string(),
                "enter".into(),
                format!("set [11, 12] [{:?}, -1.0]", c as f64 + 0.5),
                "exit".into(),
            ]
        };
        let mut want = case(0);
        for c in 1..3 {
            want.push("reset".into());
            want.extend(case(c));
        }
        assert_eq!(log, want);
        for c in 0..3 {
            let rows = &call.outputs[c * call.stride..][..call.stride];
            // The first point: the crank at angle 0, speed ω.
            assert_eq!(rows[..4], [0.0, 0.0, w[c], c as f64 + 0.5]);
            for k in 1..=5 {
                // Time k·h reached by steps of h from k·h − h; the inputs of the step: the crank
                // at its start, (k − 1)·h·ω written as run_case writes it, ω·(k·h − h).
                let t = k as f64 * h[c];
                assert_eq!(rows[4 * k..][..4], [t, w[c] * (t - h[c]), w[c], c as f64 + 0.5]);
            }
            assert!(call.seconds[c] >= 0.0);
        }
    }

    #[test]
    fn a_failing_step_stops_at_its_case_and_says_where() {
        toy(|t| *t = Toy { fail_at: Some(3.0 * 0.25), ..Toy::default() });
        let mut call = Call::new(vec![2.0, 4.0, 4.0], vec![0.5, 0.25, 0.25], 4);
        let (done, failure) = call.run(1);
        assert_eq!(done, 1);
        let want = CaseFailure { case: 1, step: 3, status: 3, function: FAILED_DO_STEP };
        assert_eq!(failure, want);
        // Case 0 is complete and was reset first (the instance had run); case 2 is untouched.
        assert_eq!(toy(|t| t.log[0].clone()), "reset");
        assert_eq!(call.outputs[4 * 4], 2.0);
        assert!(call.seconds[0] >= 0.0 && call.seconds[2] == -1.0);
        assert!(call.outputs[2 * call.stride..].iter().all(|v| v.is_nan()));
        // Started again from the next case, it goes on.
        toy(|t| t.fail_at = None);
        let mut rest = Call::new(vec![4.0], vec![0.25], 4);
        assert_eq!(rest.run(1), (1, CaseFailure::default()));
    }

    #[test]
    fn bad_arguments_are_refused() {
        let check = |edit: &dyn Fn(&mut Call)| {
            let mut call = Call::new(vec![1.0, 2.0], vec![0.1, 0.1], 3);
            edit(&mut call);
            call.run(0).0
        };
        assert_eq!(check(&|_| {}), 2);
        assert_eq!(check(&|c| c.functions.reset = None), BAD_ARGUMENTS);
        assert_eq!(check(&|c| c.functions.do_step = None), BAD_ARGUMENTS);
        assert_eq!(check(&|c| c.component = std::ptr::null_mut()), BAD_ARGUMENTS);
        assert_eq!(check(&|c| c.stride = 4), BAD_ARGUMENTS); // narrower than a case's rows
        assert_eq!(check(&|c| c.groups[0].value_bytes = 2), BAD_ARGUMENTS);
        assert_eq!(check(&|c| c.groups[0].row_bytes = 8), BAD_ARGUMENTS);
        assert_eq!(check(&|c| c.groups[0].values = std::ptr::null()), BAD_ARGUMENTS);
        assert_eq!(check(&|c| c.groups[0].set = None), BAD_ARGUMENTS);
        assert_eq!(check(&|c| c.h_at = Some(std::ptr::null())), BAD_ARGUMENTS);
        let misaligned = |c: &mut Call| {
            c.outputs_at = Some(unsafe { c.outputs.as_mut_ptr().cast::<u8>().add(1).cast() });
        };
        assert_eq!(check(&misaligned), BAD_ARGUMENTS);
        let mut failure = CaseFailure::default();
        let refused = unsafe {
            fmi2_batch_cases(
                std::ptr::null(),
                std::ptr::dangling_mut::<c_void>(),
                0,
                std::ptr::null(),
                0,
                std::ptr::null(),
                std::ptr::null(),
                0,
                0,
                std::ptr::null(),
                std::ptr::null(),
                0,
                std::ptr::null_mut(),
                0,
                std::ptr::null_mut(),
                1,
                &mut failure,
            )
        };
        assert_eq!(refused, BAD_ARGUMENTS);
    }
}
