//! Hardening of the FMI layer through the C ABI (docs/hardening.md): FMU states the importer never
//! frees are released by fmi2FreeInstance (scripts/valgrind.sh runs this file under valgrind,
//! where a leak is an error), and a deserialized state is validated like values the importer sets,
//! naming the variable.

mod common;
use common::*;
use reciprocating_drive::fmi::fmu_state;
use reciprocating_drive::fmi::model::FmuModel;
use reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive;

fn running(api: &Api) -> Inst<'_> {
    let f = Inst::new(api, "hardening");
    assert_eq!(f.setup(0.0), OK);
    assert_eq!(f.enter(), OK);
    assert_eq!(f.exit(), OK);
    for k in 0..5 {
        assert_eq!(f.step(k as f64 * 1e-3, 1e-3), OK);
    }
    f
}

#[test]
fn states_not_freed_by_the_importer_are_freed_with_the_instance() {
    let api = Api::load();
    for _ in 0..20 {
        let f = running(&api);
        let kept: Vec<_> = (0..10).map(|_| f.get_state()).collect();
        let bytes = f.serialize(kept[0]);
        let restored = f.deserialize(&bytes).expect("deserialize");
        // One state freed by the importer, the others left to fmi2FreeInstance (Drop of Inst).
        f.free_state(kept[3]);
        assert_eq!(f.set_state(restored), OK);
        // A state is freed once: a second free is refused, not a double free.
        let mut again = kept[3];
        assert_eq!(unsafe { (api.fmi2FreeFMUstate)(f.c, &mut again) }, ERROR);
    }
}

#[test]
fn deserialized_states_are_validated_like_set_calls() {
    let api = Api::load();
    let f = running(&api);
    let s = f.get_state();
    let bytes = f.serialize(s);
    let core = fmu_state::deserialize::<ReciprocatingDrive>(&bytes).expect("decode");
    type Corrupt = Box<
        dyn Fn(
            &mut reciprocating_drive::fmi::instance::Core<<ReciprocatingDrive as FmuModel>::State>,
        ),
    >;
    let cases: Vec<(Corrupt, &str)> = vec![
        (Box::new(|c| c.tolerance = Some(f64::NAN)), "tolerance = NaN"),
        (Box::new(|c| c.tolerance = Some(-1e-8)), "tolerance = -1e-08"),
        (Box::new(|c| c.values[vr("crank.speed") as usize] = f64::NAN), "crank.speed = NaN"),
        (
            Box::new(|c| c.values[vr("support_B.offset") as usize] = 1e308),
            "support_B.offset = 1e+308",
        ),
        (
            Box::new(|c| c.values[vr("guide.friction_coefficient") as usize] = -1.0),
            "guide.friction_coefficient = -1",
        ),
    ];
    for (corrupt, expect) in cases {
        let mut c = core.clone();
        corrupt(&mut c);
        // A valid checksum: the bytes are well-formed, only their content is wrong.
        let crafted = fmu_state::serialize::<ReciprocatingDrive>(&c).unwrap();
        assert_eq!(f.deserialize(&crafted), Err(ERROR), "{expect}");
        let m = f.log.last();
        assert!(m.contains(expect) && m.contains("fmi2DeSerializeFMUstate"), "{expect}: {m}");
    }
    // The instance is unharmed and the genuine bytes still restore.
    let ok = f.deserialize(&bytes).expect("genuine state");
    assert_eq!(f.set_state(ok), OK);
    assert_eq!(f.step(5e-3, 1e-3), OK);
    f.free_state(ok);
    f.free_state(s);
}

#[test]
fn a_crank_carried_forward_past_the_largest_double_fails_the_step_and_changes_nothing() {
    // The inputs are finite, but θ + ω·h overflows (docs/model.md §2): the rigid mechanism's
    // step reports it, naming the input, and the instance steps on from where it was.
    let api = Api::load();
    let f = running(&api);
    let before = f.get("crank.model_angle");
    assert_eq!(f.set("crank.speed", 1e308), OK);
    assert_eq!(f.step(5e-3, 10.0), ERROR);
    let m = f.log.last();
    assert!(m.contains("fmi2DoStep") && m.contains("crank.angle"), "{m}");
    assert_eq!(f.set("crank.speed", 6.8), OK);
    assert_eq!(f.get("crank.model_angle"), before);
    assert_eq!(f.step(5e-3, 1e-3), OK);
}

/// The per-call trace is opt-in by name (docs/fmi-interface.md "Logging categories"): debug
/// logging switched on at instantiation, or by fmi2SetDebugLogging with no categories, logs the
/// model's events and warnings but not one line per call; naming logCalls or logAll adds exactly
/// one line per call, in category logCalls.
#[test]
fn per_call_trace_only_when_its_category_is_named() {
    let api = Api::load();
    // A trace line is the bare name of the function called, whatever its category.
    let calls = |f: &Inst| {
        let lines = f.log.lines.lock().unwrap();
        lines.iter().filter(|l| l.3 == "fmi2DoStep" || l.3 == "fmi2GetReal").count()
    };
    let set_logging = |f: &Inst, names: &[&str]| {
        let cats: Vec<_> = names.iter().map(|n| std::ffi::CString::new(*n).unwrap()).collect();
        let ptrs: Vec<_> = cats.iter().map(|c| c.as_ptr()).collect();
        unsafe { (api.fmi2SetDebugLogging)(f.c, 1, ptrs.len(), ptrs.as_ptr()) }
    };
    // loggingOn = true at fmi2Instantiate (Inst::new), as the FMI Library does for libcosim.
    let f = running(&api);
    for k in 5..1005 {
        assert_eq!(f.step(k as f64 * 1e-3, 1e-3), OK);
    }
    assert_eq!(calls(&f), 0, "{:?}", f.log.messages().last());
    // fmi2SetDebugLogging(loggingOn = true, nCategories = 0).
    assert_eq!(set_logging(&f, &[]), OK);
    for k in 1005..2005 {
        assert_eq!(f.step(k as f64 * 1e-3, 1e-3), OK);
        let _ = f.get("rod.force");
    }
    assert_eq!(calls(&f), 0);
    // Named: one line per call (1000 steps and 1000 reads), whichever of the two names.
    for (names, t0) in [(&["logCalls"][..], 2005), (&["logAll"][..], 3005)] {
        f.log.clear();
        assert_eq!(set_logging(&f, names), OK);
        for k in t0..t0 + 1000 {
            assert_eq!(f.step(k as f64 * 1e-3, 1e-3), OK);
            let _ = f.get("rod.force");
        }
        let lines = f.log.lines.lock().unwrap().clone();
        let steps = lines.iter().filter(|l| l.2 == "logCalls" && l.3 == "fmi2DoStep").count();
        let reads = lines.iter().filter(|l| l.2 == "logCalls" && l.3 == "fmi2GetReal").count();
        assert_eq!((steps, reads), (1000, 1000), "{names:?}");
    }
    // Only logEvents named: no trace.
    f.log.clear();
    assert_eq!(set_logging(&f, &["logEvents"]), OK);
    assert_eq!(f.step(4.005, 1e-3), OK);
    assert_eq!(calls(&f), 0);
}

/// The numbers of a message with more than 6 significant digits (docs/hardening.md
/// "Messages"): a number is a run of digits with an optional point, exponent and sign.
fn long_numbers(message: &str) -> Vec<String> {
    let b = message.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit() && (i == 0 || !(b[i - 1].is_ascii_alphanumeric()));
        if !starts {
            i += 1;
            continue;
        }
        let start = i;
        while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
            i += 1;
        }
        let mantissa = message[start..i].trim_end_matches('.');
        if i + 1 < b.len() && b[i] == b'e' && (b[i + 1] == b'+' || b[i + 1] == b'-') {
            i += 2;
            while i < b.len() && b[i].is_ascii_digit() {
                i += 1;
            }
        }
        let digits: String = mantissa.chars().filter(|c| c.is_ascii_digit()).collect();
        let digits = digits.trim_start_matches('0');
        // Trailing zeros of an integer are not significant (1000000 has 1 significant digit).
        let digits = if mantissa.contains('.') { digits } else { digits.trim_end_matches('0') };
        if digits.len() > 6 {
            out.push(message[start..i].to_string());
        }
    }
    out
}

#[test]
fn long_numbers_finds_what_it_should() {
    assert_eq!(
        long_numbers("h = 1e+300 s, 0.357516 s, 592.25 N, -5.91963e-16, 0 s"),
        Vec::<String>::new()
    );
    assert_eq!(long_numbers("1000000 and 100000000000000000000"), Vec::<String>::new());
    assert_eq!(long_numbers("a = 0.3575157167540676 s"), vec!["0.3575157167540676"]);
    assert_eq!(long_numbers("K = -5.919626723903517e-16 N"), vec!["5.919626723903517e-16"]);
    assert_eq!(
        long_numbers("z = 0.000000000000000000001 m; link.l4 = 592.2499999999999"),
        vec!["592.2499999999999"]
    );
    assert_eq!(long_numbers("x = 1234567"), vec!["1234567"]);
}

/// Issue: numbers of 300 digits and odd forms in the FMU's messages. Every Real parameter at
/// ±1e300, ±1e-300 and 0.30000000000000004, every integer parameter at 2147483647, steps of
/// 1e300 and 1e-300 s and a mismatched communication point, on the default machine and on the
/// kvo630 preset (elastic rod, whose buckling message printed K_theta with 31 digits): every
/// number a message prints has at most 6 significant digits, except the value the case set,
/// echoed as given; integer ranges read as integers.
#[test]
fn every_number_an_fmu_prints_has_at_most_six_digits_unless_it_is_the_value_set() {
    use reciprocating_drive::fmi::variables::{Causality, VarType};
    use reciprocating_drive::model::error::given;
    let api = Api::load();
    let table = ReciprocatingDrive::table();
    let mut failures = Vec::new();
    let mut messages = 0;
    let mut check = |case: &str, echoed: Option<f64>, f: &Inst| {
        for m in f.log.messages() {
            messages += 1;
            let echo = echoed.map(given);
            for n in long_numbers(&m) {
                if Some(&n) != echo.as_ref() && Some(n.trim_start_matches('-')) != echo.as_deref() {
                    failures.push(format!("{case}: {n} in {m}"));
                }
            }
            if m.contains(" is out of range; allowed: a finite number in [0, 3]")
                || m.contains("allowed: a finite number in [1, 3]")
            {
                failures.push(format!("{case}: integer range as a real: {m}"));
            }
        }
    };
    for machine in ["default", "kvo630"] {
        for v in table.variables.iter().filter(|v| v.causality == Causality::Parameter) {
            let values: &[f64] = match v.ty {
                VarType::Real => &[1e300, -1e300, 1e-300, -1e-300, 0.30000000000000004],
                VarType::Integer => &[2147483647.0],
                VarType::Boolean => &[],
            };
            for &x in values {
                let f = Inst::new(&api, "digits");
                assert_eq!(f.setup(0.0), OK);
                assert_eq!(f.enter(), OK);
                if machine == "kvo630" {
                    f.apply_preset(&preset("kvo630"));
                }
                let st = if v.ty == VarType::Integer {
                    f.set_int(v.name, x as i32)
                } else {
                    f.set(v.name, x)
                };
                assert_eq!(st, OK);
                if f.exit() == OK {
                    for k in 0..3 {
                        let _ = f.step(k as f64 * 1e-3, 1e-3);
                    }
                    let _ = f.get_many(&["rod.force", "crank.torque", "link.friction_total"]);
                }
                check(&format!("{machine}: {} = {}", v.name, given(x)), Some(x), &f);
            }
        }
        // Step sizes and a communication point off the FMU's time.
        for (t, h) in [(0.0, 1e300), (0.0, 1e-300), (0.0010000001, 1e-3)] {
            let f = Inst::new(&api, "digits");
            assert_eq!(f.setup(0.0), OK);
            assert_eq!(f.enter(), OK);
            if machine == "kvo630" {
                f.apply_preset(&preset("kvo630"));
            }
            assert_eq!(f.exit(), OK);
            let _ = f.step(0.0, 1e-3);
            let _ = f.step(t, h);
            let _ = f.get("rod.force");
            let echoed = if h == 1e-3 { t } else { h };
            check(&format!("{machine}: step ({t}, {h})"), Some(echoed), &f);
        }
        // Buckling of the elastic rod: a process force far above the buckling load.
        if machine == "kvo630" {
            let f = Inst::new(&api, "digits");
            assert_eq!(f.setup(0.0), OK);
            assert_eq!(f.enter(), OK);
            f.apply_preset(&preset("kvo630"));
            assert_eq!(f.set("load.mean", 2000.0), OK);
            let st = f.exit();
            let m = f.log.last();
            assert!(st == ERROR && m.contains("buckl"), "{m}");
            check("kvo630 buckled", None, &f);
        }
    }
    assert!(messages > 300, "{messages} messages only");
    assert!(
        failures.is_empty(),
        "{} of {messages} messages:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Integer parameters' ranges read as integers, the tolerance's bound is refused where it is
/// given (fmi2SetupExperiment) or at initialization (solver.tolerance), with its range.
#[test]
fn integer_ranges_and_the_tolerance_bound_in_messages() {
    let api = Api::load();
    let f = Inst::new(&api, "ranges");
    assert_eq!(f.setup(0.0), OK);
    assert_eq!(f.enter(), OK);
    assert_eq!(f.set_int("mechanism", 7), OK);
    assert_eq!(f.exit(), ERROR);
    assert!(
        f.log.last().ends_with("mechanism = 7 is out of range; allowed: an integer in [1, 3]"),
        "{}",
        f.log.last()
    );
    let f = Inst::new(&api, "tolerance");
    assert_eq!(unsafe { (api.fmi2SetupExperiment)(f.c, 1, 1e-300, 0.0, 0, 0.0) }, ERROR);
    assert!(
        f.log.last().ends_with("tolerance = 1e-300; allowed: a finite number in [1e-13, 1)"),
        "{}",
        f.log.last()
    );
    assert_eq!(unsafe { (api.fmi2SetupExperiment)(f.c, 1, 1e-13, 0.0, 0, 0.0) }, OK);
    let f = Inst::new(&api, "solver.tolerance");
    assert_eq!(f.setup(0.0), OK);
    assert_eq!(f.enter(), OK);
    assert_eq!(f.set("solver.tolerance", 1e-300), OK);
    assert_eq!(f.exit(), ERROR);
    assert!(
        f.log.last().ends_with(
            "solver.tolerance = 1e-300 is out of range; allowed: a finite number in [1e-13, 1)"
        ),
        "{}",
        f.log.last()
    );
    // A support so soft that the link is barely held names its stiffness (it read only
    // "singular ... supports nearly coincide or do not hold the link").
    let f = Inst::new(&api, "soft");
    assert_eq!(f.setup(0.0), OK);
    assert_eq!(f.enter(), OK);
    assert_eq!(f.set("support_A.stiffness", 1e-300), OK);
    assert_eq!(f.exit(), ERROR);
    let m = f.log.last();
    assert!(m.contains("support_A.stiffness = 1e-300 N/m") && m.contains("EJ/L³ = "), "{m}");
    // A call out of sequence says what state the instance is in and what to do.
    let f = Inst::new(&api, "sequence");
    assert_eq!(f.step(0.0, 1e-3), ERROR);
    assert!(
        f.log.last().contains("not allowed in state instantiated: initialize first"),
        "{}",
        f.log.last()
    );
}

/// The kvo630 elastic rod at the smallest tolerance accepted still steps, so the bound refuses
/// nothing that works: 1e-13 is met (and the result agrees with 1e-10 to 1e-7 of its scale,
/// the error of the run at 1e-10).
#[test]
fn the_smallest_tolerance_accepted_works() {
    let api = Api::load();
    let run = |tol: f64| {
        let f = Inst::new(&api, "tol");
        assert_eq!(unsafe { (api.fmi2SetupExperiment)(f.c, 1, tol, 0.0, 0, 0.0) }, OK);
        assert_eq!(f.enter(), OK);
        f.apply_preset(&preset("kvo630"));
        assert_eq!(f.exit(), OK, "{}", f.log.last());
        let w = 157.07963267948966;
        for k in 0..40 {
            let t = k as f64 * 1e-3;
            assert_eq!(f.set("crank.angle", w * t), OK);
            assert_eq!(f.set("crank.speed", w), OK);
            assert_eq!(f.step(t, 1e-3), OK, "tol {tol}: {}", f.log.last());
        }
        f.get("rod.angle")
    };
    let (a, b) = (run(1e-13), run(1e-10));
    assert!((a - b).abs() <= 1e-7 * a.abs().max(1e-6), "{a} vs {b}");
}

/// FMI 3.0: an instance freed by fmi3FreeInstance is recognised (docs/fmi-interface.md "A freed
/// instance"): a second free and calls on it return fmi3Error without reading freed memory
/// (under valgrind, scripts/valgrind.sh, a read of freed memory is an error), and the handle the
/// importer held is not reused by the next instance.
#[test]
fn a_freed_fmi3_instance_is_refused_without_touching_freed_memory() {
    use fmi_sys::fmi3::*;
    use std::ffi::CString;
    let lib = unsafe { libloading::Library::new(library_path()) }.expect("load the FMU library");
    macro_rules! sym {
        ($name:ident: $ty:ident) => {
            *unsafe { lib.get::<<$ty as OptionFn>::F>(concat!(stringify!($name), "\0").as_bytes()) }
                .expect(stringify!($name))
        };
    }
    let instantiate = sym!(fmi3InstantiateCoSimulation: fmi3InstantiateCoSimulationTYPE);
    let free = sym!(fmi3FreeInstance: fmi3FreeInstanceTYPE);
    let enter = sym!(fmi3EnterInitializationMode: fmi3EnterInitializationModeTYPE);
    let exit = sym!(fmi3ExitInitializationMode: fmi3ExitInitializationModeTYPE);
    let do_step = sym!(fmi3DoStep: fmi3DoStepTYPE);
    let get = sym!(fmi3GetFloat64: fmi3GetFloat64TYPE);
    let set = sym!(fmi3SetFloat64: fmi3SetFloat64TYPE);
    let name = CString::new("freed").unwrap();
    let token =
        CString::new(reciprocating_drive::fmi3::model_description::token::<ReciprocatingDrive>())
            .unwrap();
    let make = || unsafe {
        instantiate(
            name.as_ptr(),
            token.as_ptr(),
            std::ptr::null(),
            false,
            false,
            false,
            false,
            std::ptr::null(),
            0,
            std::ptr::null_mut(),
            None,
            None,
        )
    };
    const ERR: fmi3Status = fmi3Status_fmi3Error;
    let c = make();
    assert!(!c.is_null());
    unsafe {
        assert_eq!(enter(c, false, 0.0, 0.0, false, 0.0), fmi3Status_fmi3OK);
        assert_eq!(exit(c), fmi3Status_fmi3OK);
        free(c);
        free(c);
        let (mut a, mut b, mut e, mut t) = (false, false, false, 0.0);
        assert_eq!(do_step(c, 0.0, 1e-3, false, &mut a, &mut b, &mut e, &mut t), ERR);
        let output = [vr("crank.torque")];
        let mut out = [0.0];
        assert_eq!(get(c, output.as_ptr(), 1, out.as_mut_ptr(), 1), ERR);
        let input = [vr("crank.speed")];
        assert_eq!(set(c, input.as_ptr(), 1, [1.0].as_ptr(), 1), ERR);
        assert_eq!(enter(c, false, 0.0, 0.0, false, 0.0), ERR);
        // A new instance gets a handle of its own: the freed one stays refused.
        let d = make();
        assert!(!d.is_null() && d != c);
        assert_eq!(exit(c), ERR);
        assert_eq!(enter(d, false, 0.0, 0.0, false, 0.0), fmi3Status_fmi3OK);
        free(d);
    }
}

/// FMI 2.0, as FMI 3.0 above: an instance freed by fmi2FreeInstance, co-simulation and Model
/// Exchange, is recognised (docs/fmi-interface.md "A freed instance"): a second free and calls on
/// it (the fast paths of fmi2SetReal, fmi2GetReal and fmi2DoStep among them, and an FMU state it
/// made, freed with it) return fmi2Error without reading freed memory (under valgrind,
/// scripts/valgrind.sh, a read of freed memory is an error), its logger is not called again, and
/// the next instance gets a handle of its own while the freed one stays refused.
#[test]
fn a_freed_fmi2_instance_is_refused_without_touching_freed_memory() {
    use fmi_sys::fmi2::*;
    use std::ffi::{c_void, CString};
    use std::sync::Arc;
    let api = Api::load();
    let lib = unsafe { libloading::Library::new(library_path()) }.expect("load the FMU library");
    macro_rules! sym {
        ($name:ident: $ty:ident) => {
            *unsafe { lib.get::<<$ty as OptionFn>::F>(concat!(stringify!($name), "\0").as_bytes()) }
                .expect(stringify!($name))
        };
    }
    let set_time = sym!(fmi2SetTime: fmi2SetTimeTYPE);
    let get_derivatives = sym!(fmi2GetDerivatives: fmi2GetDerivativesTYPE);
    let enter_event_mode = sym!(fmi2EnterEventMode: fmi2EnterEventModeTYPE);
    let set_states = sym!(fmi2SetContinuousStates: fmi2SetContinuousStatesTYPE);
    let log = Arc::new(LogSink::default());
    let callbacks = fmi2CallbackFunctions {
        logger: logger_fn(),
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: Arc::as_ptr(&log) as *mut c_void,
    };
    let name = CString::new("freed").unwrap();
    let guid =
        CString::new(reciprocating_drive::fmi2::model_description::guid::<ReciprocatingDrive>())
            .unwrap();
    let make = |ty: fmi2Type| unsafe {
        (api.fmi2Instantiate)(name.as_ptr(), ty, guid.as_ptr(), std::ptr::null(), &callbacks, 0, 1)
    };
    let der0 = reciprocating_drive::fmi::structure::derivative_vr::<ReciprocatingDrive>(0);
    for ty in [fmi2Type_fmi2CoSimulation, fmi2Type_fmi2ModelExchange] {
        let cs = ty == fmi2Type_fmi2CoSimulation;
        let c = make(ty);
        assert!(!c.is_null());
        let mut state: fmi2FMUstate = std::ptr::null_mut();
        unsafe {
            assert_eq!((api.fmi2SetupExperiment)(c, 0, 0.0, 0.0, 0, 0.0), OK);
            assert_eq!((api.fmi2EnterInitializationMode)(c), OK);
            assert_eq!((api.fmi2ExitInitializationMode)(c), OK);
            if cs {
                assert_eq!((api.fmi2DoStep)(c, 0.0, 1e-3, 1), OK);
            }
            // A state the importer leaves to fmi2FreeInstance.
            assert_eq!((api.fmi2GetFMUstate)(c, &mut state), OK);
            (api.fmi2FreeInstance)(c);
            let logged = log.messages().len();
            (api.fmi2FreeInstance)(c);
            let output = [vr("crank.torque")];
            let mut out = [0.0];
            assert_eq!((api.fmi2GetReal)(c, output.as_ptr(), 1, out.as_mut_ptr()), ERROR);
            let der = [der0];
            assert_eq!((api.fmi2GetReal)(c, der.as_ptr(), 1, out.as_mut_ptr()), ERROR);
            let input = [vr("crank.speed")];
            assert_eq!((api.fmi2SetReal)(c, input.as_ptr(), 1, [1.0].as_ptr()), ERROR);
            assert_eq!((api.fmi2DoStep)(c, 1e-3, 1e-3, 1), ERROR);
            assert_eq!((api.fmi2SetupExperiment)(c, 0, 0.0, 0.0, 0, 0.0), ERROR);
            assert_eq!((api.fmi2Terminate)(c), ERROR);
            assert_eq!((api.fmi2Reset)(c), ERROR);
            // The state was freed with the instance: not read either.
            assert_eq!((api.fmi2SetFMUstate)(c, state), ERROR);
            assert_eq!((api.fmi2FreeFMUstate)(c, &mut state), ERROR);
            assert_eq!(set_time(c, 1.0), ERROR);
            assert_eq!(enter_event_mode(c), ERROR);
            assert_eq!(get_derivatives(c, out.as_mut_ptr(), 1), ERROR);
            assert_eq!(set_states(c, [0.0].as_ptr(), 1), ERROR);
            assert_eq!(log.messages().len(), logged, "the freed instance's logger was called");
            // A new instance gets a handle of its own: the freed one stays refused.
            let d = make(ty);
            assert!(!d.is_null() && d != c);
            assert_eq!((api.fmi2EnterInitializationMode)(c), ERROR);
            assert_eq!((api.fmi2SetupExperiment)(d, 0, 0.0, 0.0, 0, 0.0), OK);
            assert_eq!((api.fmi2EnterInitializationMode)(d), OK);
            assert_eq!((api.fmi2ExitInitializationMode)(d), OK);
            if cs {
                assert_eq!((api.fmi2DoStep)(d, 0.0, 1e-3, 1), OK);
            } else {
                assert_eq!(set_time(d, 0.0), OK);
            }
            (api.fmi2FreeInstance)(d);
        }
    }
}
