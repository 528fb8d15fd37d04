//! Hardening of the FMI layer through the C ABI (docs/hardening.md): FMU states the importer never
//! frees are released by fmi2FreeInstance (scripts/valgrind.sh runs this file under valgrind,
//! where a leak is an error), and a deserialized state is validated like values the importer sets,
//! naming the variable.

mod common;
use common::*;
use reciprocating_drive::fmi2::fmu_state;
use reciprocating_drive::fmi2::model::FmuModel;
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
            &mut reciprocating_drive::fmi2::instance::Core<<ReciprocatingDrive as FmuModel>::State>,
        ),
    >;
    let cases: Vec<(Corrupt, &str)> = vec![
        (Box::new(|c| c.tolerance = Some(f64::NAN)), "tolerance = NaN"),
        (Box::new(|c| c.tolerance = Some(-1e-8)), "tolerance = -1e-8"),
        (Box::new(|c| c.values[vr("crank.speed") as usize] = f64::NAN), "crank.speed = NaN"),
        (
            Box::new(|c| c.values[vr("support_B.offset") as usize] = 1e308),
            "support_B.offset = 1e308",
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
