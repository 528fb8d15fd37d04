//! The FMU through its C ABI, loaded with libloading as an importer loads it: every legal
//! sequence, illegal sequences, reset, FMU state round trips, interleaved instances, bad
//! parameters and NaN inputs. Expected numbers come from the closed forms of docs/model.md §3.1,
//! written out here independently of src/.

mod common;
use common::*;
use std::f64::consts::PI;

const W: f64 = 2.0 * PI * 65.0 / 60.0;

/// Closed form for e = 0 (docs/model.md §3.1): s, TF, TF'.
fn slider(r: f64, l: f64, t: f64) -> (f64, f64, f64) {
    let lam = r / l;
    let d = (1.0 - lam * lam * t.sin().powi(2)).sqrt();
    let s = r * (1.0 - t.cos()) + l * (1.0 - d);
    let tf = r * t.sin() * (1.0 + lam * t.cos() / d);
    let tfp = r * (t.cos() + lam * ((2.0 * t).cos() + lam * lam * t.sin().powi(4)) / d.powi(3));
    (s, tf, tfp)
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn exports_version_and_platform() {
    let api = Api::load();
    unsafe {
        assert_eq!(std::ffi::CStr::from_ptr((api.fmi2GetVersion)()).to_str().unwrap(), "2.0");
        assert_eq!(
            std::ffi::CStr::from_ptr((api.fmi2GetTypesPlatform)()).to_str().unwrap(),
            "default"
        );
    }
}

#[test]
fn full_lifecycle_matches_closed_form_and_extrapolates_the_crank() {
    let api = Api::load();
    let f = Inst::new(&api, "pump");
    assert_eq!(f.setup(0.0), OK);
    assert_eq!(f.enter(), OK);
    // Kinematics and loads alone: the guide-friction model (tests/guide_friction.rs) is off.
    f.frictionless();
    // libcosim reads outputs in initialization mode.
    let s0 = f.get("suspension.position");
    assert!(s0.abs() < 1e-15);
    assert_eq!(f.set("crank.angle", 0.4), OK);
    assert_eq!(f.set("crank.acceleration", 1.5), OK);
    assert_eq!(f.exit(), OK);
    let (r, l, m) = (0.2, 1.19, 300.0);
    let check = |theta: f64, w: f64, eps: f64| {
        let (s, tf, tfp) = slider(r, l, theta);
        let a = tf * eps + tfp * w * w;
        let o = f.get_many(&[
            "suspension.position",
            "suspension.velocity",
            "suspension.acceleration",
            "kinematics.torque_factor",
            "inertia.force",
            "rod.force",
            "crank.torque",
            "rod.angle",
            "rod.angular_velocity",
        ]);
        assert!(close(o[0], s, 1e-14), "s {} vs {s}", o[0]);
        assert!(close(o[1], tf * w, 1e-13));
        assert!(close(o[2], a, 1e-12));
        assert!(close(o[3], tf, 1e-14));
        assert!(close(o[4], -m * a, 1e-9));
        assert!(close(o[5], -m * a, 1e-9));
        assert!(close(o[6], m * a * tf, 1e-9));
        let beta = (r * theta.sin() / l).asin();
        assert!(close(o[7], beta, 1e-15));
        assert!(close(o[8], r * w * theta.cos() / (l * beta.cos()), 1e-13));
    };
    check(0.4, W, 1.5);
    // A step without new inputs: the FMU extrapolates θ + ωh + εh²/2, ω + εh (docs/model.md §2).
    let h = 0.01;
    assert_eq!(f.step(0.0, h), OK);
    check(0.4 + W * h + 0.5 * 1.5 * h * h, W + 1.5 * h, 1.5);
    // New inputs are authoritative at the next point, and visible before the next step.
    assert_eq!(f.set("crank.angle", 2.0), OK);
    assert_eq!(f.set("crank.speed", 5.0), OK);
    check(2.0, 5.0, 1.5);
    assert_eq!(f.step(h, 0.02), OK);
    assert_eq!(unsafe { (api.fmi2Terminate)(f.c) }, OK);
    // Outputs are still readable after termination.
    assert!(f.try_get("suspension.position").is_ok());
}

#[test]
fn variable_step_sizes_and_communication_point_checks() {
    let api = Api::load();
    let f = Inst::new(&api, "steps");
    f.init();
    let mut t = 0.0;
    for h in [1e-5, 0.1, 0.003, 1e-4, 0.05] {
        assert_eq!(f.step(t, h), OK);
        t += h;
    }
    assert_eq!(f.step(t + 0.5, 0.01), ERROR);
    assert!(f.log.last().contains("currentCommunicationPoint"), "{}", f.log.last());
    assert_eq!(f.step(t, 0.0), ERROR);
    assert_eq!(f.step(t, -1.0), ERROR);
    assert_eq!(f.step(t, f64::NAN), ERROR);
    assert!(f.log.last().contains("communicationStepSize"));
    assert_eq!(f.step(t, 0.01), OK, "the FMU keeps working after rejected steps");
}

#[test]
fn illegal_call_sequences_are_errors_naming_the_function() {
    let api = Api::load();
    let f = Inst::new(&api, "seq");
    let illegal = |st: fmi_sys::fmi2::fmi2Status, func: &str| {
        assert_eq!(st, ERROR, "{func}");
        let m = f.log.last();
        assert!(m.contains(func) && m.contains("illegal call sequence"), "{m}");
    };
    illegal(f.step(0.0, 0.1), "fmi2DoStep");
    illegal(f.exit(), "fmi2ExitInitializationMode");
    illegal(unsafe { (api.fmi2Terminate)(f.c) }, "fmi2Terminate");
    assert_eq!(f.try_get("suspension.position"), Err(ERROR)); // outputs not before initialization
    assert!(f.try_get("geometry.crank_radius").is_ok()); // parameters are readable
    assert_eq!(f.enter(), OK);
    illegal(f.setup(0.0), "fmi2SetupExperiment");
    illegal(f.enter(), "fmi2EnterInitializationMode");
    assert_eq!(f.exit(), OK);
    // Fixed parameters cannot change after initialization.
    assert_eq!(f.set("geometry.crank_radius", 0.3), ERROR);
    assert!(f.log.last().contains("fixed parameter"));
    assert_eq!(f.get("geometry.crank_radius"), 0.2);
    // Outputs cannot be set; unknown references and wrong types are errors.
    assert_eq!(f.set("suspension.position", 1.0), ERROR);
    let bad = 9999u32;
    let mut v = 0.0;
    assert_eq!(unsafe { (api.fmi2GetReal)(f.c, &bad, 1, &mut v) }, ERROR);
    let mech = vr("mechanism");
    assert_eq!(unsafe { (api.fmi2GetReal)(f.c, &mech, 1, &mut v) }, ERROR);
    let mut iv = 0;
    assert_eq!(unsafe { (api.fmi2GetInteger)(f.c, &mech, 1, &mut iv) }, OK);
    assert_eq!(iv, 1);
    // NULL arrays.
    assert_eq!(unsafe { (api.fmi2GetReal)(f.c, std::ptr::null(), 1, &mut v) }, ERROR);
    assert_eq!(unsafe { (api.fmi2GetReal)(f.c, std::ptr::null(), 0, std::ptr::null_mut()) }, OK);
    // NULL instance.
    assert_eq!(unsafe { (api.fmi2DoStep)(std::ptr::null_mut(), 0.0, 0.1, 0) }, ERROR);
    // A directional derivative with a value reference that is not an input: refused, naming it.
    assert_eq!(
        unsafe { (api.fmi2GetDirectionalDerivative)(f.c, &bad, 1, &bad, 1, &v, &mut v) },
        ERROR
    );
    assert!(f.log.last().contains(&format!("value reference {bad} is not an input")));
    // Unsupported optional functions exist and say why they fail.
    assert_eq!(unsafe { (api.fmi2GetRealOutputDerivatives)(f.c, &bad, 1, &iv, &mut v) }, ERROR);
    assert_eq!(unsafe { (api.fmi2SetRealInputDerivatives)(f.c, &bad, 1, &iv, &v) }, ERROR);
    assert_eq!(unsafe { (api.fmi2CancelStep)(f.c) }, ERROR);
    let mut t = -1.0;
    assert_eq!(
        unsafe {
            (api.fmi2GetRealStatus)(
                f.c,
                fmi_sys::fmi2::fmi2StatusKind_fmi2LastSuccessfulTime,
                &mut t,
            )
        },
        OK
    );
    assert_eq!(t, 0.0);
    assert_eq!(unsafe { (api.fmi2Terminate)(f.c) }, OK);
    illegal(f.step(0.0, 0.1), "fmi2DoStep");
    illegal(unsafe { (api.fmi2Terminate)(f.c) }, "fmi2Terminate");
    // Reset from terminated returns to a fresh instance that runs again.
    assert_eq!(unsafe { (api.fmi2Reset)(f.c) }, OK);
    f.init();
    assert_eq!(f.step(0.0, 0.1), OK);
}

#[test]
fn reset_reproduces_a_fresh_run_bit_for_bit() {
    let api = Api::load();
    let f = Inst::new(&api, "reset");
    let run = || {
        f.init();
        let mut out = vec![];
        for k in 0..50 {
            assert_eq!(f.set("crank.angle", W * k as f64 * 0.01), OK);
            assert_eq!(f.step(k as f64 * 0.01, 0.01), OK);
            out.push(f.get("suspension.acceleration").to_bits());
        }
        out
    };
    let a = run();
    assert_eq!(f.set("mass.reciprocating", 1.0), ERROR); // fixed after init
    assert_eq!(unsafe { (api.fmi2Reset)(f.c) }, OK);
    assert_eq!(f.get("crank.angle"), 0.0, "reset restores start values");
    assert_eq!(run(), a);
}

#[test]
fn instantiate_checks_its_arguments() {
    let api = Api::load();
    let guid = reciprocating_drive::fmi2::model_description::guid::<
        reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive,
    >();
    // Wrong GUID, empty name: NULL with a logged reason.
    let log = Inst::try_with(&api, "x", None, false, "{00000000-0000-0000-0000-000000000000}")
        .err()
        .expect("NULL");
    assert!(log.last().contains("GUID"), "{}", log.last());
    let log = Inst::try_with(&api, "", None, false, guid).err().expect("NULL");
    assert!(log.last().contains("instanceName"));
    // An fmuType other than co-simulation (1) and Model Exchange (0) is refused.
    let name = std::ffi::CString::new("me").unwrap();
    let g = std::ffi::CString::new(guid).unwrap();
    let cb = fmi_sys::fmi2::fmi2CallbackFunctions {
        logger: None,
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: std::ptr::null_mut(),
    };
    let c =
        unsafe { (api.fmi2Instantiate)(name.as_ptr(), 7, g.as_ptr(), std::ptr::null(), &cb, 0, 0) };
    assert!(c.is_null());
    // Model Exchange is offered beside co-simulation (docs/fmi-interface.md).
    let c = unsafe {
        (api.fmi2Instantiate)(
            name.as_ptr(),
            fmi_sys::fmi2::fmi2Type_fmi2ModelExchange,
            g.as_ptr(),
            std::ptr::null(),
            &cb,
            0,
            0,
        )
    };
    assert!(!c.is_null());
    unsafe { (api.fmi2FreeInstance)(c) };
    // NULL callbacks struct: NULL, no crash.
    let c = unsafe {
        (api.fmi2Instantiate)(
            name.as_ptr(),
            fmi_sys::fmi2::fmi2Type_fmi2CoSimulation,
            g.as_ptr(),
            std::ptr::null(),
            std::ptr::null(),
            0,
            0,
        )
    };
    assert!(c.is_null());
    // A NULL logger is tolerated, and errors then go nowhere without crashing.
    let c = unsafe {
        (api.fmi2Instantiate)(
            name.as_ptr(),
            fmi_sys::fmi2::fmi2Type_fmi2CoSimulation,
            g.as_ptr(),
            std::ptr::null(),
            &cb,
            0,
            1,
        )
    };
    assert!(!c.is_null());
    assert_eq!(unsafe { (api.fmi2DoStep)(c, 0.0, 1.0, 0) }, ERROR);
    unsafe { (api.fmi2FreeInstance)(c) };
    // Every resource-location form, including NULL, and a name with spaces.
    for loc in [
        None,
        Some("file:///tmp/r"),
        Some("file:/tmp/r/"),
        Some("file://localhost/tmp/a%20b"),
        Some("file:///"),
    ] {
        let f = Inst::with(&api, "my pump instance 1", loc, true);
        f.init();
        assert_eq!(f.step(0.0, 0.001), OK);
    }
}

#[test]
fn logger_gets_the_component_environment_and_categories_work() {
    let api = Api::load();
    let f = Inst::with(&api, "with spaces in name", None, false);
    assert_eq!(f.step(0.0, 1.0), ERROR);
    let lines = f.log.lines.lock().unwrap().clone();
    // The sink is only reachable through componentEnvironment: receiving the line proves it.
    let (name, status, cat, msg) = lines.last().unwrap().clone();
    assert_eq!(name, "with spaces in name");
    assert_eq!(status, ERROR);
    assert_eq!(cat, "logStatusError");
    assert!(msg.contains("fmi2DoStep"));
    // Debug logging off: no per-call messages; on with logAll: every call is logged.
    f.log.clear();
    assert_eq!(f.setup(0.0), OK);
    assert!(f.log.messages().is_empty());
    let cats = [std::ffi::CString::new("logAll").unwrap()];
    let ptrs: Vec<_> = cats.iter().map(|c| c.as_ptr()).collect();
    assert_eq!(unsafe { (api.fmi2SetDebugLogging)(f.c, 1, 1, ptrs.as_ptr()) }, OK);
    assert_eq!(f.enter(), OK);
    assert!(f.log.messages().iter().any(|m| m.contains("fmi2EnterInitializationMode")));
    let bad = [std::ffi::CString::new("noSuchCategory").unwrap()];
    let ptrs: Vec<_> = bad.iter().map(|c| c.as_ptr()).collect();
    assert_eq!(unsafe { (api.fmi2SetDebugLogging)(f.c, 1, 1, ptrs.as_ptr()) }, ERROR);
    assert!(f.log.last().contains("noSuchCategory"));
    // A message containing '%' reaches the logger verbatim (it goes through "%s").
    assert_eq!(f.set("crank.speed", f64::NAN), ERROR);
}

#[test]
fn bad_parameters_are_rejected_at_initialization_with_precise_messages() {
    let api = Api::load();
    let cases: &[(&str, f64, &[&str])] = &[
        ("geometry.rod_length", 0.2, &["geometry.rod_length", "0.2", "geometry.crank_radius"]),
        ("geometry.crank_radius", 0.0, &["geometry.crank_radius", "= 0", "(0, 1000] m"]),
        ("geometry.crank_radius", f64::NAN, &["geometry.crank_radius", "NaN"]),
        ("mass.reciprocating", -5.0, &["mass.reciprocating", "-5", "[0, 1e+09] kg"]),
        // Values whose products overflow (docs/hardening.md): bounded ranges, short numbers.
        ("support_B.offset", 1e308, &["support_B.offset = 1e+308", "[-1, 1] m"]),
        ("support_C.tilt", -1e308, &["support_C.tilt = -1e+308", "[-1, 1] rad"]),
        ("guide.friction_coefficient", 1e308, &["guide.friction_coefficient = 1e+308", "[0, 10]"]),
        ("link.l1", 1e200, &["link.l1 = 1e+200", "[0, 1000] m"]),
        ("geometry.beam_front_arm", 1e200, &["geometry.beam_front_arm = 1e+200", "(0, 1000] m"]),
        ("mass.reciprocating", f64::INFINITY, &["mass.reciprocating", "inf"]),
        ("geometry.slider_offset", 1.0, &["geometry.rod_length", "geometry.slider_offset"]),
        ("guide.velocity_scale", 0.0, &["guide.velocity_scale"]),
    ];
    for (name, value, expect) in cases {
        let f = Inst::new(&api, "bad");
        assert_eq!(f.setup(0.0), OK);
        assert_eq!(f.enter(), OK);
        assert_eq!(f.set(name, *value), OK, "parameters are validated at exit");
        assert_eq!(f.exit(), ERROR, "{name} = {value}");
        let m = f.log.last();
        for e in *expect {
            assert!(m.contains(e), "message for {name} = {value} lacks {e:?}: {m}");
        }
        // Correcting the parameter lets initialization finish.
        let default = reciprocating_drive::fmus::reciprocating_drive::VARIABLES[vr(name) as usize]
            .start()
            .unwrap();
        assert_eq!(f.set(name, default), OK);
        assert_eq!(f.exit(), OK, "{}", f.log.last());
    }
    for (name, value) in [("mechanism", 9), ("load.profile", 4), ("fluid_end.cylinders", 4)] {
        let f = Inst::new(&api, "bad");
        assert_eq!(f.enter(), OK);
        assert_eq!(f.set_int(name, value), OK);
        assert_eq!(f.exit(), ERROR);
        assert!(
            f.log.last().contains(name) && f.log.last().contains(&value.to_string()),
            "{}",
            f.log.last()
        );
    }
}

#[test]
fn nan_inputs_are_rejected_and_leave_the_state_unchanged() {
    let api = Api::load();
    let f = Inst::new(&api, "nan");
    f.init();
    assert_eq!(f.set("crank.angle", 1.0), OK);
    assert_eq!(f.step(0.0, 0.01), OK);
    let before = f.serialize(f.get_state());
    let s_before = f.get("suspension.position");
    for (name, bad) in [
        ("crank.angle", f64::NAN),
        ("crank.speed", f64::INFINITY),
        ("crank.acceleration", f64::NEG_INFINITY),
        ("link.external_force", f64::NAN),
    ] {
        assert_eq!(f.set(name, bad), ERROR);
        let m = f.log.last();
        assert!(m.contains(name) && m.contains("finite"), "{m}");
    }
    // A vector set with one bad value stores none of them.
    let vrs = [vr("crank.angle"), vr("crank.speed")];
    let vals = [3.0, f64::NAN];
    assert_eq!(unsafe { (api.fmi2SetReal)(f.c, vrs.as_ptr(), 2, vals.as_ptr()) }, ERROR);
    assert_eq!(f.get("crank.angle"), 1.0);
    assert_eq!(f.get("suspension.position"), s_before);
    let st = f.get_state();
    assert_eq!(f.serialize(st), before, "state unchanged by the rejected calls");
    f.free_state(st);
    assert_eq!(f.step(0.01, 0.01), OK);
}

#[test]
fn tunable_parameters_change_while_stepping_and_bad_values_are_refused() {
    let api = Api::load();
    let f = Inst::new(&api, "tune");
    f.init();
    assert_eq!(f.set("crank.speed", 0.0), OK);
    assert_eq!(f.set("load.mean", 1000.0), OK);
    assert!(close(f.get("rod.force"), 1000.0, 1e-9));
    assert_eq!(f.set_int("load.profile", 5), ERROR);
    assert!(f.log.last().contains("load.profile"));
    assert_eq!(f.set("load.amplitude", f64::NAN), ERROR);
    assert!(close(f.get("rod.force"), 1000.0, 1e-9), "old values kept");
    assert_eq!(f.step(0.0, 0.01), OK);
}

#[test]
fn fmu_state_round_trips_continue_bit_identically() {
    let api = Api::load();
    let f = Inst::new(&api, "state");
    f.init();
    let drive = |k0: usize, n: usize| -> Vec<u64> {
        (k0..k0 + n)
            .flat_map(|k| {
                let t = k as f64 * 0.002;
                assert_eq!(f.set("crank.angle", W * t + 0.1 * t * t), OK);
                assert_eq!(f.set("crank.speed", W + 0.2 * t), OK);
                assert_eq!(f.set("crank.acceleration", 0.2), OK);
                assert_eq!(f.step(t, 0.002), OK);
                f.get_many(&["suspension.position", "suspension.acceleration", "crank.torque"])
                    .into_iter()
                    .map(f64::to_bits)
            })
            .collect()
    };
    drive(0, 20);
    let s = f.get_state();
    let bytes = f.serialize(s);
    let reference = drive(20, 30);
    // In-memory state.
    assert_eq!(f.set_state(s), OK);
    assert_eq!(drive(20, 30), reference);
    // Serialized state, restored in this instance and in a second one.
    let s2 = f.deserialize(&bytes).expect("deserialize");
    assert_eq!(f.set_state(s2), OK);
    assert_eq!(drive(20, 30), reference);
    let g = Inst::new(&api, "other");
    let s3 = g.deserialize(&bytes).expect("deserialize in another instance");
    assert_eq!(g.set_state(s3), OK);
    let other: Vec<u64> = (20..50)
        .flat_map(|k| {
            let t = k as f64 * 0.002;
            assert_eq!(g.set("crank.angle", W * t + 0.1 * t * t), OK);
            assert_eq!(g.set("crank.speed", W + 0.2 * t), OK);
            assert_eq!(g.set("crank.acceleration", 0.2), OK);
            assert_eq!(g.step(t, 0.002), OK);
            g.get_many(&["suspension.position", "suspension.acceleration", "crank.torque"])
                .into_iter()
                .map(f64::to_bits)
        })
        .collect();
    assert_eq!(other, reference);
    // Reusing an existing state object overwrites it.
    let mut reuse = s;
    assert_eq!(unsafe { (api.fmi2GetFMUstate)(f.c, &mut reuse) }, OK);
    assert_eq!(reuse, s);
    // Foreign, truncated and corrupted bytes are rejected and change nothing.
    let t_before = f.get("suspension.position");
    assert!(f.deserialize(b"garbage").is_err());
    assert!(f.deserialize(&bytes[..bytes.len() - 1]).is_err());
    let mut bad = bytes.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 1;
    assert!(f.deserialize(&bad).is_err());
    assert!(f.log.last().contains("fmi2DeSerializeFMUstate"));
    assert_eq!(f.get("suspension.position"), t_before);
    // A too-small buffer is refused.
    let mut tiny = [0 as std::ffi::c_char; 4];
    assert_eq!(unsafe { (api.fmi2SerializeFMUstate)(f.c, s, tiny.as_mut_ptr(), 4) }, ERROR);
    f.free_state(s);
    f.free_state(s2);
    g.free_state(s3);
}

#[test]
fn interleaved_instances_do_not_interfere() {
    let api = Api::load();
    let run_alone = |r: f64| {
        let f = Inst::new(&api, "alone");
        assert_eq!(f.enter(), OK);
        assert_eq!(f.set("geometry.crank_radius", r), OK);
        assert_eq!(f.exit(), OK);
        (0..40)
            .map(|k| {
                assert_eq!(f.set("crank.angle", 0.05 * k as f64), OK);
                assert_eq!(f.step(k as f64 * 0.01, 0.01), OK);
                f.get("suspension.acceleration").to_bits()
            })
            .collect::<Vec<_>>()
    };
    let (ra, rb) = (run_alone(0.2), run_alone(0.3));
    let a = Inst::new(&api, "a");
    let b = Inst::new(&api, "b");
    for (f, r) in [(&a, 0.2), (&b, 0.3)] {
        assert_eq!(f.enter(), OK);
        assert_eq!(f.set("geometry.crank_radius", r), OK);
        assert_eq!(f.exit(), OK);
    }
    let (mut xa, mut xb) = (vec![], vec![]);
    for k in 0..40 {
        for (f, x) in [(&a, &mut xa), (&b, &mut xb)] {
            assert_eq!(f.set("crank.angle", 0.05 * k as f64), OK);
            assert_eq!(f.step(k as f64 * 0.01, 0.01), OK);
            x.push(f.get("suspension.acceleration").to_bits());
        }
    }
    assert_eq!(xa, ra);
    assert_eq!(xb, rb);
    assert_ne!(ra, rb);
}

#[test]
fn library_reloads_after_unload() {
    // fmpy and the FMI Library unload the library after each run; loading it again must work.
    for _ in 0..3 {
        let api = Api::load();
        let f = Inst::new(&api, "reload");
        f.init();
        assert_eq!(f.step(0.0, 0.1), OK);
    }
}
