//! Native host-loop benchmark through the C ABI (loaded with libloading, as an importer does):
//! per step `fmi2SetReal` of the 3 crank inputs, `fmi2DoStep` (h = 1 ms) and `fmi2GetReal` of 8
//! outputs. Reports ns per step, the median of several runs.
//!
//! Run: `cargo bench --bench host_loop` (optionally a scenario name filter as argument).

#[path = "../tests/common/mod.rs"]
mod common;

use common::*;
use std::time::Instant;

struct Scenario {
    name: &'static str,
    /// (name, value) parameters set in initialization mode.
    reals: &'static [(&'static str, f64)],
    ints: &'static [(&'static str, i32)],
    speed: f64,
}

const SCENARIOS: &[Scenario] = &[
    Scenario {
        name: "crank-slider, friction off",
        reals: &[],
        ints: &[("support_A.kind", 0), ("support_B.kind", 0), ("support_C.kind", 0)],
        speed: 2.0 * std::f64::consts::PI * 65.0 / 60.0,
    },
    Scenario {
        name: "default machine (guide friction on)",
        reals: &[],
        ints: &[],
        speed: 2.0 * std::f64::consts::PI * 65.0 / 60.0,
    },
    Scenario {
        name: "beam unit (sk8-3.5-4000)",
        reals: &[
            ("geometry.beam_front_arm", 3.5),
            ("geometry.beam_rear_arm", 2.5),
            ("geometry.pivot_dx", 2.195),
            ("geometry.pivot_dy", 3.0),
            ("geometry.rod_length", 3.0),
            ("geometry.crank_radius", 1.01),
            ("mass.reciprocating", 3000.0),
            ("load.mean", -40e3),
        ],
        ints: &[("mechanism", 2), ("rotation", -1), ("support_B.kind", 0), ("support_C.kind", 0)],
        speed: 2.0 * std::f64::consts::PI * 10.9 / 60.0,
    },
    Scenario {
        name: "kvo630 (spring rod, friction on)",
        reals: &[
            ("geometry.crank_radius", 0.001),
            ("mass.reciprocating", 0.02),
            ("load.mean", 14.7),
            ("link.l1", 0.010),
            ("link.l2", 0.0),
            ("link.l3", 0.0),
            ("link.l4", 0.0),
            ("link.d1", 0.008),
            ("support_B.z", 0.005),
            ("support_B.length", 0.010),
            ("support_B.offset", 0.0),
            ("support_B.tilt", 0.0),
        ],
        ints: &[("rod.kind", 2), ("support_A.kind", 0), ("support_C.kind", 0)],
        speed: 2.0 * std::f64::consts::PI * 1500.0 / 60.0,
    },
];

const OUTPUTS: [&str; 8] = [
    "suspension.position",
    "suspension.velocity",
    "suspension.acceleration",
    "kinematics.torque_factor",
    "inertia.force",
    "rod.force",
    "crank.torque",
    "rod.angle",
];

fn run(api: &Api, sc: &Scenario, steps: usize) -> f64 {
    let f = Inst::with(api, "bench", None, false);
    assert_eq!(f.setup(0.0), OK);
    assert_eq!(f.enter(), OK);
    for (n, v) in sc.reals {
        assert_eq!(f.set(n, *v), OK);
    }
    for (n, v) in sc.ints {
        assert_eq!(f.set_int(n, *v), OK);
    }
    assert_eq!(f.exit(), OK, "{}", f.log.last());
    let in_vr = [vr("crank.angle"), vr("crank.speed"), vr("crank.acceleration")];
    let out_vr: Vec<u32> = OUTPUTS.iter().map(|n| vr(n)).collect();
    let mut out = [0.0f64; 8];
    let h = 1e-3;
    let mut sink = 0.0;
    let t0 = Instant::now();
    for k in 0..steps {
        let t = k as f64 * h;
        let inputs = [sc.speed * t, sc.speed, 0.0];
        unsafe {
            let s1 = (api.fmi2SetReal)(f.c, in_vr.as_ptr(), 3, inputs.as_ptr());
            let s2 = (api.fmi2DoStep)(f.c, t, h, 1);
            let s3 = (api.fmi2GetReal)(f.c, out_vr.as_ptr(), 8, out.as_mut_ptr());
            if (s1 | s2 | s3) != OK {
                panic!("step {k} failed: {}", f.log.last());
            }
        }
        sink += out[2];
    }
    let ns = t0.elapsed().as_nanos() as f64 / steps as f64;
    std::hint::black_box(sink);
    ns
}

/// Work of the cage-equation integrator for kvo630 (the pure model, no FMI layer): right-hand-side
/// evaluations per simulated second at three communication step sizes, default tolerance.
fn kvo630_rhs_evaluations() {
    use reciprocating_drive::model::crank::CrankState;
    use reciprocating_drive::model::drive::{Inputs, Model};
    use reciprocating_drive::model::integrator::IntegratorStats;
    use reciprocating_drive::model::params::Params;
    let mut p = Params {
        crank_radius: 0.001,
        mass: 0.02,
        load_mean: 14.7,
        link_lengths: [0.010, 0.0, 0.0, 0.0],
        link_diameters: [0.008, 0.0, 0.0, 0.0],
        rod_kind: 2,
        ..Params::default()
    };
    p.supports[0].kind = 0;
    p.supports[2].kind = 0;
    p.supports[1].z = 0.005;
    p.supports[1].length = 0.010;
    p.supports[1].offset = 0.0;
    p.supports[1].tilt = 0.0;
    let Ok(model) = Model::new(&p) else { panic!("kvo630 parameters rejected") };
    let w = 2.0 * std::f64::consts::PI * 1500.0 / 60.0;
    let inputs = Inputs::default();
    for h in [1e-4f64, 1e-3, 1e-2] {
        let crank0 = CrankState { angle: 0.0, speed: w, acceleration: 0.0 };
        let mut state = model.initial_rod_state(&crank0, &inputs).unwrap_or_else(|e| panic!("{e}"));
        let mut stats = IntegratorStats::default();
        let n = (1.0 / h).round() as usize;
        for k in 0..n {
            let crank = CrankState { angle: w * k as f64 * h, speed: w, acceleration: 0.0 };
            state = model
                .step(&crank, &inputs, &state, h, model.default_tolerance(), &mut stats)
                .unwrap_or_else(|e| panic!("{e}"));
        }
        println!(
            "kvo630 cage equation, h = {h:e} s: {} RHS evaluations per simulated second ({} steps, {} rejected)",
            stats.rhs_evals, stats.steps, stats.rejected
        );
    }
}

fn main() {
    let filter: Option<String> = std::env::args().skip(1).find(|a| !a.starts_with('-'));
    let api = Api::load();
    println!("library: {}", library_path().display());
    if filter.as_ref().is_none_or(|f| "kvo630".contains(f.as_str())) {
        kvo630_rhs_evaluations();
    }
    for sc in SCENARIOS {
        if filter.as_ref().is_some_and(|f| !sc.name.contains(f.as_str())) {
            continue;
        }
        // BENCH_STEPS shortens the runs (e.g. under valgrind --tool=callgrind).
        let steps =
            std::env::var("BENCH_STEPS").ok().and_then(|s| s.parse().ok()).unwrap_or(200_000);
        run(&api, sc, steps / 10); // warm-up
        let mut runs: Vec<f64> = (0..9).map(|_| run(&api, sc, steps)).collect();
        runs.sort_by(f64::total_cmp);
        println!(
            "{:<40} median {:>8.1} ns/step  (min {:.1}, max {:.1}; 9 runs x {steps} steps, h = 1 ms)",
            sc.name, runs[4], runs[0], runs[8]
        );
    }
}
