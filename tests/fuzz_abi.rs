//! A seeded fuzzer of the C ABI (docs/hardening.md): random sequences of FMI calls with random
//! values (NaN, infinities, extremes, valid values) and crafted or corrupted FMU-state bytes. After
//! every call it checks:
//! * no crash and no panic (a panic crossing the boundary would abort this process);
//! * the status the FMI state machine requires: a call not allowed in the current state is
//!   refused with fmi2Error;
//! * every output is finite whenever fmi2GetReal returned fmi2OK;
//! * a failed call changed nothing: the serialized FMU state (mode, time, values, model state)
//!   is the same before and after.
//!
//! CI runs `RD_FUZZ_SEQUENCES` sequences (default 20 000); scripts/fuzz.sh runs a long campaign.
//! `RD_FUZZ_SEED` picks the seed (default 1); a failure prints the seed and sequence number.

mod common;
use common::*;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// Calls made, refused, and steps that succeeded: printed, so a campaign shows what it covered.
static CALLS: AtomicU64 = AtomicU64::new(0);
static REFUSED: AtomicU64 = AtomicU64::new(0);
static STEPS_OK: AtomicU64 = AtomicU64::new(0);
use fmi_sys::fmi2::fmi2FMUstate;
use reciprocating_drive::fmi::variables::{Causality, VarType};
use reciprocating_drive::fmus::reciprocating_drive::VARIABLES;

/// splitmix64: small, seedable, good enough to spread the calls.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A hostile or harmless value.
    fn value(&mut self, start: f64) -> f64 {
        match self.below(12) {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => f64::NEG_INFINITY,
            3 => 1e308 * if self.below(2) == 0 { 1.0 } else { -1.0 },
            4 => 1e-300,
            5 => 0.0,
            6 => -start,
            7 => start * (1.0 + 0.5 * (self.unit() - 0.5)),
            8 => (self.unit() - 0.5) * 20.0,
            9 => start * 1e3,
            _ => start,
        }
    }
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Mode {
    Instantiated,
    Init,
    Step,
}

struct Checker<'a> {
    f: Inst<'a>,
    mode: Mode,
    time: f64,
    setup_done: bool,
    /// Saved states with the mode and time they hold.
    states: Vec<(fmi2FMUstate, Mode, f64)>,
    outputs: Vec<u32>,
}

impl Checker<'_> {
    /// The serialized state, to compare before and after a failed call.
    fn fingerprint(&self) -> Vec<u8> {
        let s = self.f.get_state();
        let b = self.f.serialize(s);
        self.f.free_state(s);
        b
    }

    fn check_outputs(&self, ctx: &str) {
        let mut v = vec![0.0; self.outputs.len()];
        let st = unsafe {
            (self.f.api.fmi2GetReal)(
                self.f.c,
                self.outputs.as_ptr(),
                self.outputs.len(),
                v.as_mut_ptr(),
            )
        };
        if st == OK {
            for (x, vr) in v.iter().zip(&self.outputs) {
                assert!(
                    x.is_finite(),
                    "{ctx}: fmi2GetReal returned OK with {} = {x}",
                    VARIABLES[*vr as usize].name
                );
            }
        } else {
            assert_eq!(st, ERROR, "{ctx}: fmi2GetReal status {st}");
            assert!(self.f.log.last().contains("fmi2GetReal"), "{ctx}: {}", self.f.log.last());
        }
    }
}

fn run_sequence(api: &Api, rng: &mut Rng, ctx: &str) {
    let outputs: Vec<u32> = VARIABLES
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Output)
        .map(|(i, _)| i as u32)
        .collect();
    // Half the instances log nothing but errors: fmi2GetReal, fmi2SetReal and fmi2DoStep then
    // take their fast paths (docs/performance.md), which must hold everything checked here too.
    let logging_on = rng.below(2) == 0;
    let f = Inst::with(api, "fuzz", Some("file:///nonexistent/resources"), logging_on);
    let mut c = Checker {
        f,
        mode: Mode::Instantiated,
        time: 0.0,
        setup_done: false,
        states: vec![],
        outputs,
    };
    let n_ops = 4 + rng.below(24);
    // Half the sequences start with the regular life cycle (setup, enter, a few values, exit) so
    // that stepping, states and outputs are exercised, not only refusals.
    let prologue: &[u64] = if rng.below(2) == 0 { &[0, 1, 3, 3, 2] } else { &[] };
    for op in 0..n_ops {
        let ctx = format!("{ctx} op {op} in {:?}", c.mode);
        // Fingerprint where the FMU can serialize (after initialization starts).
        let can_fp = matches!(c.mode, Mode::Init | Mode::Step);
        let before = can_fp.then(|| c.fingerprint());
        let choice = prologue.get(op as usize).copied().unwrap_or_else(|| rng.below(11));
        let (st, allowed, changes) = match choice {
            0 => {
                let st = c.f.setup(0.0);
                c.setup_done |= st == OK;
                (st, c.mode == Mode::Instantiated, true)
            }
            1 => {
                let st = c.f.enter();
                if st == OK {
                    c.mode = Mode::Init;
                }
                (st, c.mode == Mode::Instantiated || st == OK, true)
            }
            2 => {
                let was = c.mode;
                let st = c.f.exit();
                if st == OK {
                    c.mode = Mode::Step;
                }
                (st, was == Mode::Init, true)
            }
            3 | 4 => {
                // Set a random parameter or input.
                let i = rng.below(VARIABLES.len() as u64) as usize;
                let v = &VARIABLES[i];
                let start = v.start().unwrap_or(1.0);
                let x = rng.value(start);
                let vr = i as u32;
                let st = unsafe {
                    match v.ty {
                        VarType::Real => (api.fmi2SetReal)(c.f.c, &vr, 1, &x),
                        VarType::Integer => {
                            let k = if x.is_finite() { x.clamp(-1e9, 1e9) as i32 } else { 7 };
                            (api.fmi2SetInteger)(c.f.c, &vr, 1, &k)
                        }
                        VarType::Boolean => {
                            let k = (x.is_finite() && x != 0.0) as i32;
                            (api.fmi2SetBoolean)(c.f.c, &vr, 1, &k)
                        }
                    }
                };
                // Outputs and calculated parameters can never be set.
                (
                    st,
                    !matches!(v.causality, Causality::Output | Causality::CalculatedParameter),
                    true,
                )
            }
            5 | 6 => {
                let h = match rng.below(6) {
                    0 => f64::NAN,
                    1 => -1e-3,
                    2 => 0.0,
                    3 => 0.05,
                    _ => 1e-3,
                };
                let t = if rng.below(8) == 0 { c.time + 0.5 } else { c.time };
                let st = c.f.step(t, h);
                if st == OK {
                    STEPS_OK.fetch_add(1, Relaxed);
                }
                let allowed = c.mode == Mode::Step && h > 0.0 && t == c.time;
                if st == OK {
                    c.time = t + h;
                }
                (st, allowed, true)
            }
            7 => {
                c.check_outputs(&ctx);
                (OK, true, false)
            }
            8 => {
                // Save a state, or restore / free one saved earlier.
                if can_fp && (c.states.is_empty() || rng.below(2) == 0) {
                    c.states.push((c.f.get_state(), c.mode, c.time));
                    (OK, true, false)
                } else if let Some((s, m, t)) = c.states.pop() {
                    if rng.below(2) == 0 {
                        let st = c.f.set_state(s);
                        c.states.push((s, m, t));
                        if st == OK {
                            c.mode = m;
                            c.time = t;
                        }
                        (st, true, true)
                    } else {
                        c.f.free_state(s);
                        (OK, true, false)
                    }
                } else {
                    (OK, true, false)
                }
            }
            9 if can_fp => {
                // Crafted bytes: a serialized state with a corrupted byte, or truncated.
                let s = c.f.get_state();
                let mut b = c.f.serialize(s);
                c.f.free_state(s);
                match rng.below(3) {
                    0 => {
                        let k = rng.below(b.len() as u64) as usize;
                        b[k] ^= 1 << rng.below(8);
                    }
                    1 => b.truncate(rng.below(b.len() as u64) as usize),
                    _ => {}
                }
                match c.f.deserialize(&b) {
                    Ok(s) => {
                        c.states.push((s, c.mode, c.time));
                        (OK, true, false)
                    }
                    Err(st) => (st, true, false),
                }
            }
            _ => {
                let st = unsafe { (api.fmi2Reset)(c.f.c) };
                if st == OK {
                    c.mode = Mode::Instantiated;
                    c.setup_done = false;
                    c.time = 0.0;
                }
                (st, true, true)
            }
        };
        CALLS.fetch_add(1, Relaxed);
        if st == ERROR {
            REFUSED.fetch_add(1, Relaxed);
        }
        // The state machine: a call that is not allowed must be refused.
        if !allowed {
            assert_eq!(
                st,
                ERROR,
                "{ctx}: a call not allowed here returned {st}: {}",
                c.f.log.last()
            );
        }
        assert!(
            st == OK || st == ERROR || st == fmi_sys::fmi2::fmi2Status_fmi2Warning,
            "{ctx}: status {st}"
        );
        if st == ERROR {
            if let (Some(b), true) = (before, changes) {
                let after = c.fingerprint();
                assert!(
                    b == after,
                    "{ctx}: a failed call changed the FMU state: {}",
                    c.f.log.last()
                );
            }
        }
        c.check_outputs(&ctx);
    }
    // Leave the remaining states to fmi2FreeInstance (Drop of Inst): it must free them.
}

#[test]
fn random_call_sequences_keep_every_guarantee() {
    let n: u64 =
        std::env::var("RD_FUZZ_SEQUENCES").ok().and_then(|s| s.parse().ok()).unwrap_or(20_000);
    let seed: u64 = std::env::var("RD_FUZZ_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let api = Api::load();
    let mut rng = Rng(seed);
    for k in 0..n {
        run_sequence(&api, &mut rng, &format!("seed {seed} sequence {k}"));
    }
    let (calls, refused, steps) =
        (CALLS.load(Relaxed), REFUSED.load(Relaxed), STEPS_OK.load(Relaxed));
    println!("fuzz_abi: {n} sequences, seed {seed}: {calls} calls ({refused} refused, {steps} successful steps); every check held");
    // The campaign must reach stepping, or it would test little.
    assert!(steps > n / 10, "only {steps} successful steps in {n} sequences");
}
