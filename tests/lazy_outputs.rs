//! Evaluation on demand (docs/fmi-interface.md "Evaluation on demand") through the C ABI: outputs
//! read in every order and subset, in one fmi2GetReal or several, before and after inputs are set
//! between steps, equal bit for bit the values of the pure model evaluating every output at once
//! (`Model::evaluate`, no FMI layer, no cache) at the crank state the FMU reports; and a second
//! instance reading everything at once in table order agrees bit for bit too.
//!
//! Machines: the default pump (guide friction on), the crank-slider without supports, a
//! crank-slider with the balancer and a process-force profile, the beam unit sk8-3.5-4000 and the
//! elastic rod kvo630 (its cage is integrated in the step; its outputs are read on demand after
//! an input is set), and pumps of two and three cylinders loaded by the pressures (load.profile 3).

mod common;
use common::*;
use reciprocating_drive::fmi::variables::{Binding, Causality};
use reciprocating_drive::fmus::reciprocating_drive::{value_reference, VARIABLES};
use reciprocating_drive::model::crank::CrankState;
use reciprocating_drive::model::drive::{Inputs, Model, Outputs, RodState};
use reciprocating_drive::model::params::Params;

/// Reads one output from `Outputs`.
type Reader = fn(&Outputs) -> f64;

/// Every Real output and calculated parameter, in table order, with its value in `Outputs`.
fn outputs() -> Vec<(&'static str, Reader)> {
    VARIABLES
        .iter()
        .filter(|v| matches!(v.causality, Causality::Output | Causality::CalculatedParameter))
        .map(|v| {
            let Some(o) = reciprocating_drive::fmus::reciprocating_drive::TABLE.info()
                [value_reference(v.name).unwrap()]
            .output
            else {
                unreachable!()
            };
            (v.name, o.get)
        })
        .collect()
}

/// A small deterministic generator (the test needs variety, not statistics).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        self.0 >> 33
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// A machine: its preset (if any) and the overrides on top, as (name, type, value) like a
/// preset's entries.
struct Machine {
    name: &'static str,
    preset: Option<&'static str>,
    overrides: &'static [(&'static str, &'static str, &'static str)],
    speed: f64,
    /// Amplitude of the process force the test sets [N].
    force: f64,
}

const MACHINES: &[Machine] = &[
    Machine { name: "default", preset: None, overrides: &[], speed: 6.8, force: 300.0 },
    Machine {
        name: "no supports",
        preset: None,
        overrides: &[
            ("support_A.kind", "Integer", "0"),
            ("support_B.kind", "Integer", "0"),
            ("support_C.kind", "Integer", "0"),
        ],
        speed: 6.8,
        force: 300.0,
    },
    Machine {
        name: "balancer + pump profile",
        preset: None,
        overrides: &[
            ("balancer.enabled", "Boolean", "true"),
            ("balancer.tuning", "Integer", "1"),
            ("balancer.design_speed", "Real", "6.8"),
            ("load.profile", "Integer", "1"),
            ("load.mean", "Real", "5e3"),
            ("geometry.slider_offset", "Real", "0.02"),
        ],
        speed: 6.8,
        force: 300.0,
    },
    Machine {
        name: "sk8-3.5-4000",
        preset: Some("sk8-3.5-4000"),
        overrides: &[],
        speed: 1.14,
        force: 3e3,
    },
    Machine { name: "kvo630", preset: Some("kvo630"), overrides: &[], speed: 157.0, force: 1.0 },
    Machine {
        name: "duplex double-acting, pressures",
        preset: None,
        overrides: &[
            ("fluid_end.cylinders", "Integer", "2"),
            ("cylinder_2.phase", "Real", "1.5707963267948966"),
            ("load.profile", "Integer", "3"),
        ],
        speed: 6.8,
        force: 300.0,
    },
    Machine {
        name: "triplex single-acting, pressures, balancer",
        preset: None,
        overrides: &[
            ("fluid_end.cylinders", "Integer", "3"),
            ("cylinder_1.acting", "Integer", "1"),
            ("cylinder_2.acting", "Integer", "1"),
            ("cylinder_3.acting", "Integer", "1"),
            ("cylinder_2.phase", "Real", "2.0943951023931953"),
            ("cylinder_3.phase", "Real", "4.1887902047863905"),
            ("load.profile", "Integer", "3"),
            ("balancer.enabled", "Boolean", "true"),
            ("balancer.tuning", "Integer", "1"),
            ("balancer.design_speed", "Real", "6.8"),
        ],
        speed: 6.8,
        force: 300.0,
    },
];

fn instance<'a>(api: &'a Api, m: &Machine, name: &str) -> Inst<'a> {
    let f = Inst::with(api, name, None, false);
    assert_eq!(f.setup(0.0), OK);
    assert_eq!(f.enter(), OK);
    f.apply_preset(&entries(m));
    assert_eq!(f.set("crank.speed", m.speed), OK);
    assert_eq!(f.exit(), OK, "{}", f.log.last());
    f
}

/// The preset's entries and the overrides of a machine (crank.speed is the test's).
fn entries(m: &Machine) -> Vec<(String, String, String)> {
    let mut e: Vec<_> = m
        .preset
        .map(preset)
        .unwrap_or_default()
        .into_iter()
        .filter(|e| e.0 != "crank.speed")
        .collect();
    e.extend(m.overrides.iter().map(|&(n, t, v)| (n.to_string(), t.to_string(), v.to_string())));
    e
}

/// The parameters the instance was given, as the pure model reads them.
fn params(m: &Machine) -> Params {
    let mut p = Params::default();
    for (name, ty, v) in entries(m) {
        if let Some(Binding::Param { set, .. }) =
            VARIABLES.iter().find(|x| x.name == name).map(|x| x.binding)
        {
            set(
                &mut p,
                if ty == "Boolean" { (v == "true") as i32 as f64 } else { v.parse().unwrap() },
            );
        }
    }
    p
}

/// Reads `names` in the given order, split into fmi2GetReal calls of the given sizes.
fn read(f: &Inst, names: &[&str], split: &[usize]) -> Vec<f64> {
    let mut out = Vec::new();
    let mut i = 0;
    for &n in split.iter().chain(std::iter::once(&usize::MAX)) {
        let end = (i + n).min(names.len());
        if end > i {
            out.extend(f.get_many(&names[i..end]));
        }
        i = end;
        if i == names.len() {
            break;
        }
    }
    out
}

#[test]
fn outputs_read_in_any_order_and_subset_equal_the_eager_evaluation_bit_for_bit() {
    let api = Api::load();
    let all = outputs();
    let all_names: Vec<&str> = all.iter().map(|o| o.0).collect();
    // One representative of each group (kinematics, loads, forces): every order of every
    // non-empty subset of them, then the rest of that step's reads at random.
    let reps = ["suspension.acceleration", "inertia.force", "guide.friction"];
    let mut orders: Vec<Vec<&str>> = Vec::new();
    for mask in 1..8u32 {
        let sub: Vec<&str> = (0..3).filter(|i| mask & (1 << i) != 0).map(|i| reps[i]).collect();
        let perms: Vec<Vec<&str>> = match sub.len() {
            1 => vec![sub.clone()],
            2 => vec![sub.clone(), vec![sub[1], sub[0]]],
            _ => [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]]
                .iter()
                .map(|p| p.iter().map(|&i| sub[i]).collect())
                .collect(),
        };
        orders.extend(perms);
    }
    assert_eq!(orders.len(), 3 + 3 * 2 + 6);
    let mut rng = Lcg(0x5eed);
    let mut compared = 0usize;
    for m in MACHINES {
        let lazy = instance(&api, m, "lazy");
        let eager = instance(&api, m, "eager");
        let model = Model::new(&params(m)).expect("machine");
        let h = if m.name == "kvo630" { 2e-4 } else { 1e-2 };
        for k in 0..60usize {
            let t = k as f64 * h;
            // Every third step the master sets new inputs (the outputs become stale), the others
            // only step (the FMU carries the crank forward itself).
            if k % 3 == 1 {
                let x = k as f64;
                let inputs = [
                    m.speed * t + 0.01 * x.sin(),
                    m.speed * (1.0 + 0.05 * (0.3 * x).cos()),
                    0.5 * (0.2 * x).sin(),
                    m.force * (0.1 * x).cos(),
                    1e6 * (1.0 + 0.2 * (0.13 * x).cos()),
                    1e5 * (1.0 + 0.3 * (0.07 * x).sin()),
                ];
                let names = [
                    "crank.angle",
                    "crank.speed",
                    "crank.acceleration",
                    "link.external_force",
                    "fluid_end.discharge_pressure",
                    "fluid_end.suction_pressure",
                ];
                for f in [&lazy, &eager] {
                    for (n, v) in names.iter().zip(inputs) {
                        assert_eq!(f.set(n, v), OK);
                    }
                }
            }
            // The reference: the pure model at the crank state the FMU reports (offset 0, so the
            // model angle is the crank angle), with the elastic rod's cage state from its outputs.
            let e = eager.get_many(&all_names);
            let get = |n: &str| e[all_names.iter().position(|x| *x == n).unwrap()];
            let crank = CrankState {
                angle: get("crank.model_angle"),
                speed: get("crank.model_speed"),
                acceleration: eager.get("crank.acceleration"),
            };
            let mut rod = RodState::default();
            rod.cage.theta = if model.has_state() { get("rod.angle") } else { 0.0 };
            rod.cage.rate = if model.has_state() { get("rod.angular_velocity") } else { 0.0 };
            let reference = model
                .evaluate(
                    &crank,
                    &Inputs {
                        external_force: eager.get("link.external_force"),
                        discharge_pressure: eager.get("fluid_end.discharge_pressure"),
                        suction_pressure: eager.get("fluid_end.suction_pressure"),
                    },
                    &rod,
                )
                .expect("evaluate");
            for (i, (name, field)) in all.iter().enumerate() {
                assert_eq!(
                    e[i].to_bits(),
                    field(&reference).to_bits(),
                    "{} step {k}: {name} {} vs pure model {}",
                    m.name,
                    e[i],
                    field(&reference)
                );
            }
            // The lazy instance: a fixed group order, then a random subset in random order, in
            // random call sizes, some outputs read twice.
            let mut names: Vec<&str> = orders[k % orders.len()].clone();
            for _ in 0..rng.below(all_names.len() + 1) {
                names.push(all_names[rng.below(all_names.len())]);
            }
            let split: Vec<usize> = (0..4).map(|_| 1 + rng.below(6)).collect();
            let got = read(&lazy, &names, &split);
            for (n, v) in names.iter().zip(&got) {
                let want = get(n);
                assert_eq!(
                    v.to_bits(),
                    want.to_bits(),
                    "{} step {k}: {n} read lazily {v} vs eager {want} (order {names:?})",
                    m.name
                );
                compared += 1;
            }
            for f in [&lazy, &eager] {
                assert_eq!(f.step(t, h), OK, "{}: {}", m.name, f.log.last());
            }
        }
    }
    println!("{compared} lazily read values compared");
}

/// fmi2GetReal and fmi2SetReal keep, per instance, the value references of the array a master
/// passes at every step resolved (docs/performance.md "Read and input plans"). One array of the
/// caller's, changed in place between calls (the same address with new contents and lengths),
/// must read and set exactly what a second instance reads and sets that resolves every value
/// reference at every call (debug logging on: the general path), and a value reference or a
/// value that is wrong fails naming it, also where the array it replaced had been resolved.
#[test]
fn an_array_of_value_references_changed_in_place_is_resolved_again() {
    let api = Api::load();
    let planned = Inst::with(&api, "planned", None, false);
    let general = Inst::with(&api, "general", None, true);
    for f in [&planned, &general] {
        f.init();
    }
    let vrs_of = |names: &[&str]| names.iter().map(|n| vr(n)).collect::<Vec<u32>>();
    // Arrays of the same and of other lengths, of outputs of every group, inputs and parameters.
    let reads: [&[&str]; 6] = [
        &["suspension.position", "suspension.velocity", "rod.force", "crank.torque"],
        &["suspension.position", "suspension.velocity", "rod.force", "guide.friction"],
        &["crank.speed", "geometry.crank_radius", "rod.angle", "inertia.force"],
        &["suspension.position", "suspension.velocity"],
        &[
            "guide.reaction",
            "support_A.reaction",
            "load.mean",
            "crank.acceleration",
            "rod.stress_max",
        ],
        &["suspension.position", "suspension.velocity", "rod.force", "crank.torque"],
    ];
    let mut buffer = [0u32; 8];
    let mut values = [0.0f64; 8];
    let get = |f: &Inst, buffer: &[u32; 8], n: usize, out: &mut [f64; 8]| unsafe {
        (f.api.fmi2GetReal)(f.c, buffer.as_ptr(), n, out.as_mut_ptr())
    };
    let set = |f: &Inst, buffer: &[u32; 8], n: usize, v: &[f64; 8]| unsafe {
        (f.api.fmi2SetReal)(f.c, buffer.as_ptr(), n, v.as_ptr())
    };
    let h = 1e-3;
    let mut compared = 0;
    for k in 0..60 {
        let t = k as f64 * h;
        // The crank inputs in one array, sometimes in another order or with the process force.
        let inputs: &[(&str, f64)] = match k % 3 {
            0 => &[("crank.angle", 6.8 * t), ("crank.speed", 6.8), ("crank.acceleration", 0.1)],
            1 => &[("crank.speed", 6.9), ("crank.angle", 6.8 * t), ("crank.acceleration", -0.2)],
            _ => &[
                ("crank.angle", 6.8 * t),
                ("crank.speed", 6.7),
                ("crank.acceleration", 0.0),
                ("link.external_force", 1e3),
            ],
        };
        for (i, (n, v)) in inputs.iter().enumerate() {
            buffer[i] = vr(n);
            values[i] = *v;
        }
        for f in [&planned, &general] {
            assert_eq!(set(f, &buffer, inputs.len(), &values), OK, "{}", f.log.last());
        }
        let names = reads[k % reads.len()];
        buffer[..names.len()].copy_from_slice(&vrs_of(names));
        let (mut a, mut b) = ([f64::NAN; 8], [f64::NAN; 8]);
        assert_eq!(get(&planned, &buffer, names.len(), &mut a), OK, "{}", planned.log.last());
        assert_eq!(get(&general, &buffer, names.len(), &mut b), OK, "{}", general.log.last());
        for (i, n) in names.iter().enumerate() {
            assert_eq!(a[i].to_bits(), b[i].to_bits(), "step {k}: {n} {} vs {}", a[i], b[i]);
            compared += 1;
        }
        // The same array again, now with an Integer in it: refused, naming it.
        if k % 10 == 9 {
            buffer[1] = vr("support_A.kind");
            assert_eq!(get(&planned, &buffer, names.len(), &mut a), ERROR);
            assert!(planned.log.last().contains("support_A.kind"), "{}", planned.log.last());
        }
        for f in [&planned, &general] {
            assert_eq!(f.step(t, h), OK, "{}", f.log.last());
        }
    }
    assert!(compared > 200);
    // A set of the resolved input array with a value that is not finite, or with a fixed
    // parameter in it, is refused naming it, and changes nothing.
    let inputs = ["crank.angle", "crank.speed", "crank.acceleration"];
    buffer[..3].copy_from_slice(&vrs_of(&inputs));
    values[..3].copy_from_slice(&[0.5, 6.8, 0.0]);
    assert_eq!(set(&planned, &buffer, 3, &values), OK);
    let before = planned.get_many(&inputs);
    values[1] = f64::NAN;
    assert_eq!(set(&planned, &buffer, 3, &values), ERROR);
    assert!(planned.log.last().contains("crank.speed"), "{}", planned.log.last());
    values[1] = 7.0;
    buffer[2] = vr("geometry.crank_radius");
    assert_eq!(set(&planned, &buffer, 3, &values), ERROR);
    assert!(planned.log.last().contains("geometry.crank_radius"), "{}", planned.log.last());
    assert_eq!(planned.get_many(&inputs), before);
    // And the array as resolved before still sets what it holds.
    buffer[2] = vr("crank.acceleration");
    assert_eq!(set(&planned, &buffer, 3, &values), OK);
    assert_eq!(planned.get_many(&inputs), vec![0.5, 7.0, 0.0]);
}
