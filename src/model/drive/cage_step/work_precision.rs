//! The work-precision study of the cage integrator (docs/performance.md "The elastic rod"):
//! Verner 6(5) on φ against pairs that treat the frozen oscillator exactly (Lawson form,
//! integrator/lawson.rs), for the kvo630 spring and the thin rod, communication steps 0.1, 1 and
//! 10 ms, tolerances 1e-6 … 1e-10. Errors: the largest |Δϑ|/max|ϑ| and |Δϑ̇|/max|ϑ̇| (each
//! relative to its own amplitude) over the 10 ms points of 0.2 s against a reference run of
//! Verner 6(5) at tolerance 1e-13 with 0.1 ms communication steps (exact beam column in every stage), itself checked against the Lawson
//! form at 1e-13 (a second method: their difference bounds the reference's own error).
//! Cost: RHS evaluations and wall time (release build, the shortest of 7 runs: the least
//! disturbed by other jobs on a shared machine) per simulated second.
//!
//! `cargo test --release --lib work_precision -- --ignored --nocapture` writes the table to
//! `target/work_precision.csv` (`scripts/work_precision.py` runs it and draws the figure).

use crate::model::crank::CrankState;
use crate::model::drive::{Inputs, Model};
use crate::model::elastic_rod::cage::CageState;
use crate::model::integrator::tests::compared::{with_pair, Which};
use crate::model::integrator::IntegratorStats;
use crate::model::params::Params;
use std::io::Write;
use std::time::Instant;

const SPEED: f64 = 2.0 * std::f64::consts::PI * 1500.0 / 60.0;
const DURATION: f64 = 0.2;
const SAMPLE: f64 = 0.01;

/// The kvo630 machine of `model::drive`'s tests (docs/model.md §8), `rod_kind` 2 (the spring)
/// or 1 (a thin straight rod).
fn kvo630(rod_kind: i32) -> Params {
    Params { rod_kind, ..crate::model::drive::tests::kvo630() }
}

/// The cage state at every SAMPLE point over DURATION with communication step `h`.
fn trajectory(m: &Model, h: f64, tol: f64) -> (Vec<CageState>, IntegratorStats) {
    let inputs = Inputs::default();
    let crank0 = CrankState { angle: 0.0, speed: SPEED, acceleration: 0.0 };
    let mut state = m.initial_rod_state(&crank0, &inputs).unwrap();
    let mut stats = IntegratorStats::default();
    let n = (DURATION / h).round() as usize;
    let every = (SAMPLE / h).round() as usize;
    let mut out = Vec::new();
    for k in 0..n {
        let crank = CrankState { angle: SPEED * k as f64 * h, ..crank0 };
        state = m.step(&crank, &inputs, &state, h, tol, &mut stats).unwrap();
        if (k + 1) % every == 0 {
            out.push(state.cage);
        }
    }
    (out, stats)
}

/// The largest errors of ϑ and of ϑ̇ in `a` against `b`, each relative to its own amplitude in
/// `b` (max|ϑ|, max|ϑ̇|).
fn largest_errors(a: &[CageState], b: &[CageState]) -> (f64, f64) {
    assert_eq!(a.len(), b.len());
    let amp = |f: fn(&CageState) -> f64| b.iter().map(|s| f(s).abs()).fold(0.0, f64::max);
    let (amp_theta, amp_rate) = (amp(|s| s.theta), amp(|s| s.rate));
    a.iter().zip(b).fold((0.0, 0.0), |(e0, e1), (a, b)| {
        (e0.max((a.theta - b.theta).abs() / amp_theta), e1.max((a.rate - b.rate).abs() / amp_rate))
    })
}

#[test]
#[ignore]
fn work_precision() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/work_precision.csv");
    let mut csv = std::fs::File::create(&path).unwrap();
    writeln!(csv, "rod,method,step_ms,tol,error,error_rate,evals_per_s,ns_per_s,steps,rejected")
        .unwrap();
    for (rod_name, kind) in [("kvo630 spring", 2), ("thin rod", 1)] {
        let m = Model::new(&kvo630(kind)).unwrap();
        let (reference, _) = with_pair(Which::Verner65, || trajectory(&m, 1e-4, 1e-13));
        let (check, _) = with_pair(Which::LawsonVerner65, || trajectory(&m, 1e-4, 1e-13));
        let ref_err = largest_errors(&check, &reference);
        println!(
            "{rod_name}: reference against the Lawson form at 1e-13: {:.2e} (ϑ), {:.2e} (ϑ̇)",
            ref_err.0, ref_err.1
        );
        assert!(ref_err.0 < 1e-10 && ref_err.1 < 1e-9, "{ref_err:?}");
        for which in [
            Which::Verner65,
            Which::LawsonVerner65,
            Which::Tsit5,
            Which::LawsonTsit5,
            Which::LawsonDp5,
        ] {
            for h in [1e-4, 1e-3, 1e-2] {
                for tol in [1e-6, 1e-7, 1e-8, 1e-9, 1e-10] {
                    let mut times = Vec::new();
                    let mut result = None;
                    for _ in 0..7 {
                        let t0 = Instant::now();
                        let r = with_pair(which, || trajectory(&m, h, tol));
                        times.push(t0.elapsed().as_nanos() as f64 / DURATION);
                        result = Some(r);
                    }
                    times.sort_by(f64::total_cmp);
                    let (run, stats) = result.unwrap();
                    let (err, err_rate) = largest_errors(&run, &reference);
                    let evals = stats.rhs_evals as f64 / DURATION;
                    println!(
                        "{rod_name} {which:?} h {h:e} tol {tol:e}: error {err:.2e} (rate {err_rate:.2e}), \
                         {evals:.0} evaluations/s, {:.3} ms/s, {stats:?}",
                        times[0] * 1e-6
                    );
                    writeln!(
                        csv,
                        "{rod_name},{which:?},{},{tol:e},{err:e},{err_rate:e},{evals},{},{},{}",
                        h * 1e3,
                        times[0],
                        stats.steps,
                        stats.rejected
                    )
                    .unwrap();
                }
            }
        }
    }
}
