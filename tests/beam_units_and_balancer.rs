//! Beam pumping units (docs/model.md §3.2), loads (§4) and the torsion-bar balancer (§7) through the
//! FMU's C ABI. References: seed 001's printed values with the angle mapping of §3.2, an
//! independent loop solution written here, closed forms, and the virtual-power identity.

mod common;
use common::*;
use std::f64::consts::PI;

/// Parameter settings as (name, value).
type Settings<'a> = &'a [(&'a str, f64)];

const SK8: Settings = &[
    ("geometry.beam_front_arm", 3.5),
    ("geometry.beam_rear_arm", 2.5),
    ("geometry.pivot_dx", 2.195),
    ("geometry.pivot_dy", 3.0),
    ("geometry.rod_length", 3.0),
    ("geometry.crank_radius", 1.01),
];

fn beam_unit<'a>(api: &'a Api, mechanism: i32, rotation: i32, reals: &[(&str, f64)]) -> Inst<'a> {
    let f = Inst::new(api, "beam unit");
    assert_eq!(f.enter(), OK);
    assert_eq!(f.set_int("mechanism", mechanism), OK);
    assert_eq!(f.set_int("rotation", rotation), OK);
    f.single_clamp();
    for (n, v) in SK8.iter().chain(reals) {
        assert_eq!(f.set(n, *v), OK);
    }
    assert_eq!(f.exit(), OK, "{}", f.log.last());
    f
}

fn at(f: &Inst, theta: f64, w: f64, eps: f64) {
    assert_eq!(f.set("crank.angle", theta), OK);
    assert_eq!(f.set("crank.speed", w), OK);
    assert_eq!(f.set("crank.acceleration", eps), OK);
}

/// Beam angle b of the class I unit by bisection on |E − Cp| = P (no closed form): a second
/// formulation independent of src/model/beam_unit.rs. Crank pin R(sin q, cos q), q = rotation·θ.
fn class1_beam_angle(theta: f64, rotation: f64) -> f64 {
    let (a_c, i, hg, p, r) = (2.5, 2.195, 3.0, 3.0, 1.01);
    let q = rotation * theta;
    let (cx, cy) = (r * q.sin(), r * q.cos());
    let g = |b: f64| {
        let (ex, ey) = (i - a_c * b.cos(), hg - a_c * b.sin());
        ((ex - cx).powi(2) + (ey - cy).powi(2)).sqrt() - p
    };
    // The physical branch keeps the beam near horizontal: bracket within ±0.9 rad.
    let (mut lo, mut hi) = (-0.9, 0.9);
    assert!(g(lo) * g(hi) < 0.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if g(lo) * g(mid) <= 0.0 {
            hi = mid
        } else {
            lo = mid
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn seed_001_values_through_the_fmu() {
    // SK8-3.5-4000, counter-clockwise, φ1 = θ + (90° − atan2(H−G, I)), ω = 2π·10.9/60, ε = 0:
    // the paper prints a = 2.72 m/s² at φ1 = 37.51° and −1.4909 m/s² at φ1 = 192.51°.
    let api = Api::load();
    let f = beam_unit(&api, 2, -1, &[]);
    let shift = PI / 2.0 - 3.0f64.atan2(2.195);
    let w = 2.0 * PI * 10.9 / 60.0;
    for (phi1_deg, printed, digits) in [(37.51f64, 2.72, 2), (192.51, -1.4909, 4)] {
        at(&f, phi1_deg.to_radians() - shift, w, 0.0);
        let a = f.get("suspension.acceleration");
        let scale = 10f64.powi(digits);
        assert_eq!((a * scale).round() / scale, printed, "a = {a} at φ1 = {phi1_deg}°");
    }
}

#[test]
fn class_1_position_matches_an_independent_loop_solution() {
    let api = Api::load();
    for rotation in [1.0, -1.0] {
        let f = beam_unit(&api, 2, rotation as i32, &[]);
        let b: Vec<f64> =
            (0..360).map(|k| class1_beam_angle(k as f64 * PI / 180.0, rotation)).collect();
        let b_min = b.iter().cloned().fold(f64::INFINITY, f64::min);
        for (k, bk) in b.iter().enumerate() {
            at(&f, k as f64 * PI / 180.0, 1.0, 0.0);
            let s = f.get("suspension.position");
            // The sampled minimum is within (1°)²·|d²b/dθ²|/8 ≈ 1e-5 rad of the true one.
            assert!((s - 3.5 * (bk - b_min)).abs() < 1e-4, "θ = {k}°: {s}");
            assert!(s >= -1e-12);
        }
    }
}

#[test]
fn invalid_beam_geometries_are_rejected_through_the_c_abi() {
    let api = Api::load();
    let cases: &[(i32, Settings, &[&str])] = &[
        (2, &[("geometry.crank_radius", 2.6)], &["shortest", "geometry.crank_radius", "2.6"]),
        (2, &[("geometry.rod_length", 1.2)], &["Grashof", "geometry.rod_length", "1.2"]),
        (3, &[("geometry.pivot_dx", 40.0)], &["does not assemble", "geometry.pivot_dx", "40"]),
        (2, &[("geometry.beam_rear_arm", -1.0)], &["geometry.beam_rear_arm", "-1"]),
    ];
    for (mech, reals, expect) in cases {
        let f = Inst::new(&api, "bad beam");
        assert_eq!(f.enter(), OK);
        assert_eq!(f.set_int("mechanism", *mech), OK);
        f.single_clamp();
        for (n, v) in SK8.iter().chain(reals.iter()) {
            assert_eq!(f.set(n, *v), OK);
        }
        assert_eq!(f.exit(), ERROR, "{reals:?}");
        let m = f.log.last();
        for e in *expect {
            assert!(m.contains(e), "message lacks {e:?}: {m}");
        }
    }
    let f = Inst::new(&api, "bad rotation");
    assert_eq!(f.enter(), OK);
    assert_eq!(f.set_int("rotation", 0), OK);
    assert_eq!(f.exit(), ERROR);
    assert!(f.log.last().contains("rotation"));
}

#[test]
fn virtual_power_identity_for_every_mechanism_and_rotation() {
    // T·ω = −(F_ext + Φ + F_fr + F_bal)·v at every sample (§4), with F_ext from the input plus
    // a cosine profile, a balancer of given stiffness, and guide friction where the supports
    // allow (the crank-slider's default supports; a single clamp for the beam units).
    let api = Api::load();
    let mark2: Settings = &[
        ("geometry.beam_front_arm", 3.8),
        ("geometry.beam_rear_arm", 2.4),
        ("geometry.pivot_dx", 1.4),
        ("geometry.pivot_dy", 3.2),
        ("geometry.rod_length", 3.4),
        ("geometry.crank_radius", 0.9),
    ];
    let machines: Vec<(i32, i32, Settings)> = vec![
        (1, 1, &[]),
        (1, 1, &[("geometry.slider_offset", 0.1)]),
        (2, 1, SK8),
        (2, -1, SK8),
        (3, 1, mark2),
        (3, -1, mark2),
    ];
    for (mech, rot, reals) in machines {
        let f = Inst::new(&api, "vp");
        assert_eq!(f.enter(), OK);
        assert_eq!(f.set_int("mechanism", mech), OK);
        assert_eq!(f.set_int("rotation", rot), OK);
        if mech != 1 {
            f.single_clamp();
        }
        for (n, v) in reals {
            assert_eq!(f.set(n, *v), OK);
        }
        assert_eq!(f.set("load.mean", -4.0e4), OK);
        assert_eq!(f.set("load.amplitude", 5.0e3), OK);
        assert_eq!(f.set("load.phase", 0.3), OK);
        let vrb = vr("balancer.enabled");
        assert_eq!(unsafe { (api.fmi2SetBoolean)(f.c, &vrb, 1, &1) }, OK);
        assert_eq!(f.set("balancer.stiffness", 2.0e4), OK);
        assert_eq!(f.exit(), OK, "{}", f.log.last());
        for k in 0..360 {
            let theta = k as f64 * PI / 180.0;
            at(&f, theta, 1.3, -0.4);
            assert_eq!(f.set("link.external_force", 1.0e3 * theta.sin()), OK);
            let o = f.get_many(&[
                "crank.torque",
                "suspension.velocity",
                "inertia.force",
                "balancer.force",
                "rod.force",
                "link.friction_total",
            ]);
            let theta_model = theta; // crank.angle_offset = 0
            let f_ext = 1.0e3 * theta.sin() - 4.0e4 + 5.0e3 * (theta_model + 0.3).cos();
            let p = f_ext + o[2] + o[3] + o[5];
            assert!((o[4] - p).abs() < 1e-9 * 4.0e4, "rod.force");
            assert!(
                (o[0] * 1.3 + p * o[1]).abs() < 1e-9 * 4.0e4 * 1.3,
                "mech {mech} rot {rot} θ {k}°"
            );
            assert!(o[3] != 0.0 || k == 0, "the balancer acts");
        }
    }
}

#[test]
fn balancer_tunings_through_the_fmu() {
    let api = Api::load();
    let w_d = 2.0 * PI * 65.0 / 60.0;
    let vrb = vr("balancer.enabled");
    let setup = |tuning: i32| {
        let f = Inst::new(&api, "balancer");
        assert_eq!(f.enter(), OK);
        assert_eq!(unsafe { (api.fmi2SetBoolean)(f.c, &vrb, 1, &1) }, OK);
        assert_eq!(f.set_int("balancer.tuning", tuning), OK);
        assert_eq!(f.exit(), OK, "{}", f.log.last());
        f
    };
    // Tuning 2: the residual Φ + F_bal vanishes at both dead centres at the design speed.
    let f = setup(2);
    for theta in [0.0, PI] {
        at(&f, theta, w_d, 0.0);
        let phi = f.get("inertia.force");
        assert!(phi.abs() > 1e3);
        assert!(f.get("balancer.residual").abs() < 1e-9 * phi.abs(), "θ = {theta}");
    }
    assert!((f.get("balancer.stiffness_used") - 300.0 * w_d * w_d).abs() < 1e-9);
    // Tuning 1: k_b = m·B²·ω_d², B = v_max/(rω), v_max from a golden-section search on the
    // closed-form TF of §3.1 (independent of the production root finder).
    let f = setup(1);
    let (r, l) = (0.2f64, 1.19f64);
    let lam = r / l;
    let tf =
        |t: f64| r * t.sin() * (1.0 + lam * t.cos() / (1.0 - lam * lam * t.sin().powi(2)).sqrt());
    let (mut a, mut c) = (0.5, 2.5);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..200 {
        let (x1, x2) = (c - g * (c - a), a + g * (c - a));
        if tf(x1) > tf(x2) {
            c = x2
        } else {
            a = x1
        }
    }
    let b = tf(0.5 * (a + c)) / r;
    let expect = 300.0 * b * b * w_d * w_d;
    assert!((f.get("balancer.stiffness_used") - expect).abs() < 1e-9 * expect);
    // With the balancer off, the calculated parameter is 0 and the force is 0.
    let f = Inst::new(&api, "off");
    f.init();
    assert_eq!(f.get("balancer.stiffness_used"), 0.0);
    assert_eq!(f.get("balancer.force"), 0.0);
    // Tuning 2 on a beam unit is rejected with a message.
    let f = Inst::new(&api, "beam t2");
    assert_eq!(f.enter(), OK);
    assert_eq!(f.set_int("mechanism", 2), OK);
    f.single_clamp();
    for (n, v) in SK8 {
        assert_eq!(f.set(n, *v), OK);
    }
    assert_eq!(unsafe { (api.fmi2SetBoolean)(f.c, &vrb, 1, &1) }, OK);
    assert_eq!(f.set_int("balancer.tuning", 2), OK);
    assert_eq!(f.exit(), ERROR);
    assert!(f.log.last().contains("balancer.tuning"));
}
