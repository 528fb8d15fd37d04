//! Guide friction from the link's redundant supports (docs/model.md §4, §5) through the C ABI,
//! loaded with libloading as an importer loads it:
//!
//! * every kind of rejected support configuration fails fmi2ExitInitializationMode with a message
//!   that names the cause, the variables and their values, and correcting it lets
//!   initialization finish;
//! * a self-locking guide (§4 uniqueness condition violated) fails the fmi2GetReal that asks for
//!   a friction-dependent output where it is reached (outputs are evaluated on demand) with
//!   fmi2Error, leaves the FMU's state bit-for-bit as it was, and the kinematics stay readable;
//! * over a revolution of the default machine and of a machine with elastic supports, a
//!   frame-fixed gland C with friction, a lateral load, offsets, tilts, a slider offset, a
//!   process force and the balancer, the outputs satisfy the identities of §4 and §5.3 that
//!   follow from physics alone (force balance along the stroke, lateral equilibrium of the free
//!   link, edge forces, friction law, virtual power);
//! * with every support kind 0 the friction outputs are 0 and P = F_ext + Φ.
//!
//! The identities use outputs only plus parameters set here; none of them holds for a model
//! without friction or with a lag, a wrong sign or a missing side load (each check is paired with
//! a check that the friction is not negligible). The independent beam model that checks the
//! reaction values themselves is tests/python/test_guide_friction.py.

mod common;
use common::*;
use reciprocating_drive::fmi::variables::VarType;
use reciprocating_drive::fmus::reciprocating_drive::VARIABLES;
use std::f64::consts::PI;

const W: f64 = 2.0 * PI * 65.0 / 60.0;

/// Sets a parameter or input by name, through fmi2SetReal/Integer/Boolean by its declared type.
fn set_any(f: &Inst, name: &str, value: f64) {
    let r = vr(name);
    let st = match VARIABLES[r as usize].ty {
        VarType::Real => f.set(name, value),
        VarType::Integer => f.set_int(name, value as i32),
        VarType::Boolean => {
            let b = (value != 0.0) as i32;
            unsafe { (f.api.fmi2SetBoolean)(f.c, &r, 1, &b) }
        }
    };
    assert_eq!(st, OK, "set {name} = {value}: {}", f.log.last());
}

fn start_value(name: &str) -> f64 {
    VARIABLES[vr(name) as usize].start().unwrap_or_else(|| panic!("{name} has no start value"))
}

/// A fresh instance in initialization mode with `settings` applied.
fn configured<'a>(api: &'a Api, name: &str, settings: &[(&str, f64)]) -> Inst<'a> {
    let f = Inst::new(api, name);
    assert_eq!(f.setup(0.0), OK);
    assert_eq!(f.enter(), OK);
    for (n, v) in settings {
        set_any(&f, n, *v);
    }
    f
}

// ---------------------------------------------------------------------------------------------
// Rejected configurations (docs/model.md §5.2; src/model/guide/validation.rs, link_beam.rs,
// params.rs and the variable table's ranges)

#[test]
fn rejected_support_configurations_fail_initialization_with_precise_messages() {
    let api = Api::load();
    // (settings, what the message must contain). Default machine (docs/model.md §8): L = 2.1 m,
    // S = 0.4 m; A clamp at 0.125; B guide at 1.9, length 0.4 (edges 1.7 and 2.1); C pin fixed
    // in the frame at 1.6 − s, stiffness 2e6 N/m.
    type Case = (&'static [(&'static str, f64)], &'static [&'static str]);
    let cases: &[Case] = &[
        // Supports that do not hold the link.
        (
            &[("support_A.kind", 0.0), ("support_B.kind", 0.0)],
            &[
                "do not hold the link",
                "rigid-body mode",
                "single pin",
                "support_C.kind = 1 (pin)",
                "support_C.z = 1.6",
            ],
        ),
        (
            &[("support_A.kind", 0.0), ("support_C.kind", 0.0), ("support_B.kind", 1.0)],
            &[
                "do not hold the link",
                "single pin",
                "support_B.kind = 1 (pin)",
                "support_B.z = 1.9",
            ],
        ),
        // Two pins, link-fixed at 1.0 and frame-fixed at 1.2 − s: they meet at s = 0.2.
        (
            &[
                ("support_A.kind", 0.0),
                ("support_B.kind", 1.0),
                ("support_B.z", 1.0),
                ("support_C.z", 1.2),
            ],
            &[
                "do not hold the link",
                "coincide at s = 0.2",
                "support_B.z = 1",
                "support_C.z = 1.2 m (frame-fixed)",
            ],
        ),
        // A frame-fixed support leaving [0, L] during the stroke.
        (
            &[("support_C.z", 0.3)],
            &[
                "support_C.z = 0.3",
                "out of range",
                "[S, L] = [0.4, 2.1]",
                "frame-fixed",
                "[-0.1, 0.3]",
            ],
        ),
        (&[("support_C.z", 2.2)], &["support_C.z = 2.2", "[S, L] = [0.4, 2.1]", "[1.8, 2.2]"]),
        // A frame-fixed two-edge gland whose piston-side edge (0.5 − 0.2 − s) leaves the link.
        (
            &[("support_C.kind", 3.0), ("support_C.z", 0.5), ("support_C.length", 0.4)],
            &[
                "a guide edge leaves the link",
                "support_C.z = 0.5",
                "support_C.length = 0.4",
                "frame-fixed",
                "[-0.1, 0.3]",
            ],
        ),
        // A link-fixed guide edge beyond L (1.95 + 0.2 = 2.15 > 2.1).
        (
            &[("support_B.z", 1.95)],
            &[
                "a guide edge leaves the link",
                "support_B.z = 1.95",
                "support_B.length = 0.4",
                "2.15",
                "[0, L] = [0, 2.1]",
            ],
        ),
        // Link-fixed centres off the link.
        (
            &[("support_C.attached", 0.0), ("support_C.z", 2.5)],
            &["support_C.z = 2.5", "[0, L] = [0, 2.1]"],
        ),
        (&[("support_A.z", -0.01)], &["support_A.z = -0.01", "[0, L] = [0, 2.1]"]),
        // Invalid kind and attached codes.
        (&[("support_A.kind", 4.0)], &["support_A.kind = 4", "out of range", "[0, 3]"]),
        (&[("support_C.kind", -1.0)], &["support_C.kind = -1", "out of range"]),
        (&[("support_B.attached", 2.0)], &["support_B.attached = 2", "out of range", "[0, 1]"]),
        // A clamp with friction needs a length; a guide always does.
        (
            &[("support_A.friction", 0.1), ("support_A.length", 0.0)],
            &["support_A.length = 0", "support_A.friction = 0.1", "clamp with friction"],
        ),
        (&[("support_B.length", 0.0)], &["support_B.length = 0", "two-edge guide"]),
        // Negative lengths and diameters, non-positive diameters of present sections.
        (&[("link.l3", -1.0)], &["link.l3 = -1", "out of range", "[0, 1000] m"]),
        (&[("support_B.length", -0.4)], &["support_B.length = -0.4", "out of range"]),
        (&[("support_A.length", -0.25)], &["support_A.length = -0.25", "out of range"]),
        (&[("link.d2", -0.13)], &["link.d2 = -0.13", "out of range"]),
        (&[("link.d4", 0.0)], &["link.d4 = 0", "(0, inf) m for a present section"]),
        (
            &[("link.l1", 0.0), ("link.l2", 0.0), ("link.l3", 0.0), ("link.l4", 0.0)],
            &["link.l1 + link.l2 + link.l3 + link.l4 = 0"],
        ),
        // Young's modulus.
        (&[("link.E", 0.0)], &["link.E = 0", "(0, 1e+13] Pa"]),
        (&[("link.E", -2.1e11)], &["link.E = -210000000000", "(0, 1e+13] Pa"]),
        // Negative stiffness and friction coefficients, non-finite values.
        (&[("support_C.stiffness", -1.0)], &["support_C.stiffness = -1", "[0, 1e+15] N/m"]),
        (
            &[("guide.friction_coefficient", -0.1)],
            &["guide.friction_coefficient = -0.1", "[0, 10]"],
        ),
        (&[("support_C.friction", -0.2)], &["support_C.friction = -0.2"]),
        (&[("support_B.offset", f64::NAN)], &["support_B.offset = NaN"]),
        (&[("support_A.tilt", f64::INFINITY)], &["support_A.tilt = inf"]),
        (&[("link.lateral_load", f64::NAN)], &["link.lateral_load = NaN"]),
        (&[("guide.velocity_scale", 0.0)], &["guide.velocity_scale = 0"]),
        // Rigid contacts that meet: the frame-fixed rigid pin C passes B's piston-side edge
        // (1.7 m) at s = 0.2; two rigid clamps at the same point.
        (
            &[("support_C.z", 1.9), ("support_C.stiffness", 0.0)],
            &[
                "support_B and support_C",
                "rigidly",
                "indeterminate",
                "s = 0.2",
                "support_C.stiffness",
            ],
        ),
        (
            &[
                ("support_C.kind", 2.0),
                ("support_C.attached", 0.0),
                ("support_C.z", 0.125),
                ("support_C.stiffness", 0.0),
            ],
            &[
                "support_A and support_C",
                "indeterminate",
                "support_A.z = 0.125",
                "support_C.z = 0.125",
            ],
        ),
    ];
    for (settings, needles) in cases {
        let f = configured(&api, "bad-guide", settings);
        assert_eq!(f.exit(), ERROR, "accepted: {settings:?}");
        let m = f.log.last();
        assert!(m.starts_with("fmi2ExitInitializationMode"), "{m}");
        for n in *needles {
            assert!(m.contains(n), "{settings:?}: message lacks {n:?}: {m}");
        }
        // The instance stays in initialization mode; restoring the defaults lets it finish, so
        // the settings were the cause.
        for (n, _) in *settings {
            set_any(&f, n, start_value(n));
        }
        assert_eq!(f.exit(), OK, "{settings:?} restored: {}", f.log.last());
    }
}

#[test]
fn valid_variants_of_the_same_settings_are_accepted() {
    // Controls for the cases above: the same variables at values that hold and stay on the link.
    let api = Api::load();
    let ok: &[&[(&str, f64)]] = &[
        &[],
        &[("support_A.friction", 0.1)], // clamp with friction and its length 0.25 m
        &[("support_C.z", 0.4)],        // frame-fixed C reaches z = 0 at s = S exactly
        &[("support_C.z", 2.1)],        // and z = L at s = 0
        &[("support_B.z", 1.9), ("support_B.length", 0.4)],
        &[("support_A.kind", 0.0), ("support_C.kind", 0.0)], // a guide alone holds the link
        &[("support_B.kind", 0.0), ("support_C.kind", 0.0)], // a clamp alone too (friction 0)
        &[("support_C.z", 1.9)],                             // elastic C may pass B's edge
        &[("link.l2", 0.0), ("link.l3", 1.15)],              // an absent section
    ];
    for settings in ok {
        let f = configured(&api, "ok-guide", settings);
        assert_eq!(f.exit(), OK, "{settings:?}: {}", f.log.last());
        assert_eq!(f.step(0.0, 0.2), OK, "{settings:?}: {}", f.log.last());
    }
}

// ---------------------------------------------------------------------------------------------
// Self-locking guide (docs/model.md §4)

#[test]
fn self_locking_guide_fails_the_read_of_the_forces_and_leaves_the_state_unchanged() {
    let api = Api::load();
    // The side load Q = −P·tanβ acts at B's centre, and B takes it almost entirely
    // (∂R_B/∂Q ≈ −1, ∂M_B/∂Q ≈ 0), so the uniqueness number of §4 is about
    // f·|tanβ|·|tanh(v/v_ε)|: the classic wedge condition f·tanβ ≥ 1. With λ = r/l = 0.168 the
    // largest |tanβ| is 0.1705 (at θ = π/2), so f = 7 self-locks there (K ≈ 1.19) and f = 5 does
    // not (K ≈ 0.85, the control below).
    let f = configured(&api, "locking", &[("guide.friction_coefficient", 7.0)]);
    // At θ = 0 the link is at rest (tanh(v/v_ε) = 0): initialization succeeds.
    assert_eq!(f.exit(), OK, "{}", f.log.last());
    let h_small = 0.01; // θ = 0.068 rad: still unique
    assert_eq!(f.step(0.0, h_small), OK, "{}", f.log.last());
    let before = f.get_state();
    let bytes_before = f.serialize(before);
    let forces =
        ["rod.force", "guide.friction", "guide.reaction", "link.friction_total", "crank.torque"];
    let forces_before = f.get_many(&forces);
    // A step to θ = π/2 (|tanβ| largest, |v| near its largest) meets the self-locking guide. The
    // step only carries the crank forward (its outputs are evaluated when read): it succeeds.
    let h_lock = (PI / 2.0 - W * h_small) / W;
    assert_eq!(f.step(h_small, h_lock), OK, "{}", f.log.last());
    let after_step = f.get_state();
    let bytes_after_step = f.serialize(after_step);
    f.free_state(after_step);
    // Every output that needs the rod force fails, alone or with others, naming the cause.
    for names in [&forces[..1], &forces[1..2], &["suspension.position", "crank.torque"][..]] {
        let vrs: Vec<u32> = names.iter().map(|n| vr(n)).collect();
        let mut v = vec![f64::NAN; vrs.len()];
        let s = unsafe { (api.fmi2GetReal)(f.c, vrs.as_ptr(), vrs.len(), v.as_mut_ptr()) };
        assert_eq!(s, ERROR, "{names:?}");
        let m = f.log.last();
        assert!(m.starts_with("fmi2GetReal"), "{m}");
        for n in ["self-locking", "≥ 1", "tanβ = 0.17", "docs/model.md §4"] {
            assert!(m.contains(n), "message lacks {n:?}: {m}");
        }
    }
    // The kinematics do not depend on the guide: still readable, at θ = π/2.
    let theta = f.get("crank.model_angle");
    assert!((theta - PI / 2.0).abs() < 1e-12, "{theta}");
    let s = f.get("suspension.position");
    let (r, l) = (0.2, 1.19);
    let expect = r + l - r * (theta.cos()) - (l * l - (r * theta.sin()).powi(2)).sqrt();
    assert!((s - expect).abs() < 1e-12, "{s} vs {expect}");
    // The failed reads changed nothing.
    let after = f.get_state();
    assert_eq!(f.serialize(after), bytes_after_step, "a failed fmi2GetReal changed the FMU state");
    f.free_state(after);
    // Rolling back to the state before the step gives the forces there bit for bit, and smaller
    // steps go on up to the region of non-uniqueness.
    assert_eq!(f.set_state(before), OK);
    let restored = f.get_state();
    assert_eq!(f.serialize(restored), bytes_before);
    f.free_state(restored);
    assert_eq!(
        f.get_many(&forces).iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        forces_before.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
    assert_eq!(f.step(h_small, 0.01), OK, "{}", f.log.last());
    assert!(f.get("guide.friction").is_finite());
    f.free_state(before);

    // Control: the same guide with f = 5 passes θ = π/2.
    let g = configured(&api, "not-locking", &[("guide.friction_coefficient", 5.0)]);
    assert_eq!(g.exit(), OK);
    assert_eq!(g.step(0.0, PI / 2.0 / W), OK, "{}", g.log.last());
    assert!(g.get("guide.friction").abs() > 1.0);
}

// ---------------------------------------------------------------------------------------------
// Identities over a revolution

/// Outputs read at every point.
const NAMES: [&str; 18] = [
    "suspension.position",
    "suspension.velocity",
    "kinematics.torque_factor",
    "inertia.force",
    "rod.force",
    "crank.torque",
    "rod.angle",
    "balancer.force",
    "guide.friction",
    "guide.reaction",
    "guide.moment",
    "guide.edge_force_1",
    "guide.edge_force_2",
    "support_A.reaction",
    "support_C.reaction",
    "link.friction_total",
    "crank.speed",
    "link.external_force",
];

struct Row {
    s: f64,
    v: f64,
    tf: f64,
    phi: f64,
    p: f64,
    torque: f64,
    beta: f64,
    f_bal: f64,
    f_b: f64,
    r_b: f64,
    m_b: f64,
    n1: f64,
    n2: f64,
    r_a: f64,
    r_c: f64,
    f_total: f64,
    omega: f64,
    ext_input: f64,
    /// Model angle θ of the point (set by `revolution`: the FMU's extrapolated crank).
    theta: f64,
}

fn row(f: &Inst) -> Row {
    let o = f.get_many(&NAMES);
    Row {
        s: o[0],
        v: o[1],
        tf: o[2],
        phi: o[3],
        p: o[4],
        torque: o[5],
        beta: o[6],
        f_bal: o[7],
        f_b: o[8],
        r_b: o[9],
        m_b: o[10],
        n1: o[11],
        n2: o[12],
        r_a: o[13],
        r_c: o[14],
        f_total: o[15],
        omega: o[16],
        ext_input: o[17],
        theta: f64::NAN,
    }
}

/// One revolution in `n` fmi2DoStep calls at constant speed, with a process force input that
/// changes at every communication point. Returns the outputs after initialization and after
/// every step.
fn revolution(f: &Inst, n: usize, theta0: f64) -> Vec<Row> {
    assert_eq!(f.set("crank.angle", theta0), OK);
    assert_eq!(f.set("crank.speed", W), OK);
    let mut rows = vec![Row { theta: theta0, ..row(f) }];
    let h = 2.0 * PI / W / n as f64;
    for k in 0..n {
        let t = k as f64 * h;
        // Authoritative inputs at every point (docs/model.md §2) and a varying process force.
        assert_eq!(f.set("crank.angle", theta0 + W * t), OK);
        assert_eq!(f.set("link.external_force", 2.0e4 * (3.0 * W * t).sin()), OK);
        assert_eq!(f.step(t, h), OK, "step {k}: {}", f.log.last());
        // The outputs are at the end of the step: θ + ω h (ε = 0).
        rows.push(Row { theta: theta0 + W * t + W * h, ..row(f) });
    }
    rows
}

/// What the identity checks need to know about the machine.
struct Machine {
    /// Process force of the load profile as a function of (v, θ); the input is added from the row.
    profile: Box<dyn Fn(f64, f64) -> f64>,
    f_b: f64,
    /// Support C's friction coefficient when C is a pin (its friction is f_C·|R_C|·|tanh|).
    f_c_pin: f64,
    v_eps: f64,
    lateral_load: f64,
}

/// Checks every identity at every row; returns (max |guide.friction|, max |R_C|).
fn check_identities(rows: &[Row], m: &Machine) -> (f64, f64) {
    let (mut max_fb, mut max_rc) = (0.0f64, 0.0f64);
    let mut sliding = 0;
    for (k, r) in rows.iter().enumerate() {
        let f_ext = r.ext_input + (m.profile)(r.v, r.theta);
        let th = (r.v / m.v_eps).tanh();
        // §4: P = F_ext + Φ + F_fr + F_bal (to rounding of the sum's largest term).
        let scale =
            f_ext.abs().max(r.phi.abs()).max(r.f_total.abs()).max(r.f_bal.abs()).max(r.p.abs());
        let resid = r.p - (f_ext + r.phi + r.f_total + r.f_bal);
        assert!(
            resid.abs() <= 1e-12 * scale,
            "row {k}: P = {} vs F_ext + Φ + F_fr + F_bal, residual {resid}",
            r.p
        );
        // Lateral equilibrium of the free link (§5.3, §5.4): the side load of the rod
        // Q = −P·tanβ and the lateral load act at B's centre; the supports take the rest.
        let q = -r.p * r.beta.tan();
        let lat = [r.r_a, r.r_b, r.r_c, q, m.lateral_load];
        let lat_scale = lat.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let sum: f64 = lat.iter().sum();
        assert!(sum.abs() <= 1e-9 * lat_scale, "row {k}: lateral sum {sum} of {lat:?}");
        // Edge forces (§5.3): N1 + N2 = R_B and N1 − N2 = 2 M_B / l_n is the same moment.
        let ns = r.n1.abs().max(r.n2.abs());
        assert!(
            (r.n1 + r.n2 - r.r_b).abs() <= 1e-12 * ns.max(r.r_b.abs()),
            "row {k}: N1 + N2 ≠ R_B"
        );
        // Friction law: |F_B| = f·(|N1| + |N2|)·|tanh(v/v_ε)|, opposing the motion.
        let mag = m.f_b * (r.n1.abs() + r.n2.abs()) * th.abs();
        assert!(
            (r.f_b.abs() - mag).abs() <= 1e-12 * mag.max(1e-300),
            "row {k}: |F_B| = {} vs {mag}",
            r.f_b
        );
        assert!(
            r.f_b * r.v <= 0.0,
            "row {k}: guide friction {} does not oppose v = {}",
            r.f_b,
            r.v
        );
        if r.v != 0.0 && mag > 0.0 {
            assert!(r.f_b.signum() == -r.v.signum());
            sliding += 1;
        }
        // Friction of the other supports: only C's pin rubs in these machines.
        let fc = -m.f_c_pin * r.r_c.abs() * th;
        let fs = r.f_total.abs().max(r.f_b.abs()).max(fc.abs());
        assert!(
            (r.f_total - r.f_b - fc).abs() <= 1e-12 * fs.max(1e-300),
            "row {k}: F_total {} vs F_B {} + F_C {fc}",
            r.f_total,
            r.f_b
        );
        // Virtual power (§4): T·ω = −P·v, with v = TF·ω.
        let pw = (r.p * r.v).abs().max(r.torque.abs() * r.omega);
        assert!(
            (r.torque * r.omega + r.p * r.v).abs() <= 1e-12 * pw.max(1e-300),
            "row {k}: T ω ≠ −P v"
        );
        assert!((r.v - r.tf * r.omega).abs() <= 1e-14 * r.tf.abs().max(0.2) * r.omega);
        assert!(r.s >= -1e-12 && r.s <= 0.4 + 1e-3);
        max_fb = max_fb.max(r.f_b.abs());
        max_rc = max_rc.max(r.r_c.abs());
    }
    assert!(sliding > rows.len() * 9 / 10, "friction is active at almost every point");
    (max_fb, max_rc)
}

#[test]
fn default_machine_revolution_satisfies_the_identities() {
    let api = Api::load();
    let f = configured(&api, "default", &[]);
    assert_eq!(f.exit(), OK);
    let rows = revolution(&f, 720, 0.0);
    let m = Machine {
        profile: Box::new(|_, _| 0.0),
        f_b: 0.1,
        f_c_pin: 0.0,
        v_eps: 0.02,
        lateral_load: 0.0,
    };
    let (max_fb, max_rc) = check_identities(&rows, &m);
    // The friction is not negligible: the misaligned guide rubs with O(100 N) (a model without
    // friction, or with zero reactions, would make the identities above trivially true).
    assert!(max_fb > 10.0, "max |guide.friction| = {max_fb}");
    assert!(max_rc > 1.0);
    // The guide's friction changes with the crank angle (the supports move and the side load
    // changes): it is not a constant times tanh.
    let ratios: Vec<f64> =
        rows.iter().filter(|r| r.v.abs() > 0.5).map(|r| r.f_b / (r.v / 0.02).tanh()).collect();
    let (lo, hi) =
        ratios.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
    assert!(hi - lo > 0.05 * hi.abs().max(lo.abs()), "{lo} .. {hi}");
}

#[test]
fn unb600a_revolution_satisfies_the_identities() {
    let api = Api::load();
    let f = configured(&api, "unb600a-simplex", &[("load.profile", 1.0), ("load.mean", 150e3)]);
    assert_eq!(f.exit(), OK);
    let rows = revolution(&f, 720, 0.3);
    let m = Machine {
        profile: Box::new(|v, _| -150e3 * (v / 0.02).tanh()),
        f_b: 0.1,
        f_c_pin: 0.0,
        v_eps: 0.02,
        lateral_load: 0.0,
    };
    let (max_fb, _) = check_identities(&rows, &m);
    // The pump load presses the crosshead into its guide through the rod's side load:
    // friction of the order f·P·tanβ = 0.1 · 150 kN · 0.17.
    assert!(max_fb > 1000.0, "max |guide.friction| = {max_fb}");
}

#[test]
fn elastic_frame_fixed_gland_lateral_load_tilts_and_balancer_satisfy_the_identities() {
    let api = Api::load();
    let settings: &[(&str, f64)] = &[
        ("geometry.slider_offset", 0.03),
        ("load.profile", 0.0),
        ("load.mean", 1.0e4),
        ("load.amplitude", 3.0e4),
        ("load.phase", 0.3),
        ("balancer.enabled", 1.0),
        ("balancer.tuning", 0.0),
        ("balancer.stiffness", 1.0e5),
        ("link.lateral_load", -2.5e3),
        ("support_A.stiffness", 5.0e7),
        ("support_A.tilt", 1.0e-4),
        ("support_B.offset", -2.0e-4),
        ("support_B.tilt", 3.0e-4),
        ("support_B.stiffness", 1.0e8),
        ("guide.friction_coefficient", 0.12),
        ("support_C.attached", 1.0),
        ("support_C.z", 1.5),
        ("support_C.offset", 2.5e-4),
        ("support_C.tilt", -2.0e-4),
        ("support_C.stiffness", 4.0e6),
        ("support_C.friction", 0.15),
    ];
    let f = configured(&api, "elastic", settings);
    assert_eq!(f.exit(), OK, "{}", f.log.last());
    let rows = revolution(&f, 720, -0.2);
    let m = Machine {
        // Profile 0: load.mean + load.amplitude·cos(θ + load.phase) (docs/model.md §4).
        profile: Box::new(|_, th| 1.0e4 + 3.0e4 * (th + 0.3).cos()),
        f_b: 0.12,
        f_c_pin: 0.15,
        v_eps: 0.02,
        lateral_load: -2.5e3,
    };
    let (max_fb, max_rc) = check_identities(&rows, &m);
    assert!(max_fb > 10.0 && max_rc > 10.0, "{max_fb} {max_rc}");
    // C rubs too: the total differs from the guide's friction.
    assert!(rows.iter().any(|r| (r.f_total - r.f_b).abs() > 1.0));
    // The balancer is in P.
    assert!(rows.iter().any(|r| r.f_bal.abs() > 1.0e3));
}

// ---------------------------------------------------------------------------------------------
// Friction off

#[test]
fn friction_off_gives_zero_friction_outputs_and_p_equals_f_ext_plus_inertia() {
    let api = Api::load();
    let f = configured(&api, "off", &[("load.mean", 5.0e3), ("load.amplitude", 2.0e4)]);
    f.frictionless();
    // Parameters of absent supports are not looked at (beyond their declared ranges).
    set_any(&f, "support_C.z", 99.0);
    assert_eq!(f.exit(), OK, "{}", f.log.last());
    let rows = revolution(&f, 360, 0.0);
    for (k, r) in rows.iter().enumerate() {
        let th = r.theta;
        for (name, x) in [
            ("guide.friction", r.f_b),
            ("guide.reaction", r.r_b),
            ("guide.moment", r.m_b),
            ("guide.edge_force_1", r.n1),
            ("guide.edge_force_2", r.n2),
            ("support_A.reaction", r.r_a),
            ("support_C.reaction", r.r_c),
            ("link.friction_total", r.f_total),
        ] {
            assert_eq!(x, 0.0, "row {k}: {name}");
        }
        let f_ext = r.ext_input + 5.0e3 + 2.0e4 * th.cos();
        let scale = f_ext.abs().max(r.phi.abs());
        assert!(
            (r.p - (f_ext + r.phi)).abs() <= 1e-12 * scale,
            "row {k}: P {} vs {}",
            r.p,
            f_ext + r.phi
        );
    }
    // Control: the same machine with friction on has a nonzero friction and P ≠ F_ext + Φ.
    let g = configured(&api, "on", &[("load.mean", 5.0e3), ("load.amplitude", 2.0e4)]);
    assert_eq!(g.exit(), OK);
    assert_eq!(g.step(0.0, 1.0 / W), OK);
    let r = row(&g);
    assert!(r.f_total.abs() > 1.0);
    assert!((r.p - (r.ext_input + 5.0e3 + 2.0e4 * 1.0f64.cos() + r.phi)).abs() > 1.0);
}
