//! The whole pump (docs/model.md §4.1) against references independent of its code:
//! * N cylinders on one crankshaft against N one-cylinder machines whose crank.angle_offset is
//!   the cylinder's phase, at the same inputs and pressures: every per-cylinder output equal, the
//!   crank torque the sum of theirs, the flow the sum of theirs;
//! * the flow's pulsation (Q_max − Q_min)/Q_mean in the textbook limit (r/l → 0, rod area → 0,
//!   ideal valves v_ε → 0): duplex double-acting (√2 − 1)·π/4, triplex single-acting
//!   (1 − √3/2)·π/3, simplex single-acting π;
//! * the mean flow over a revolution, by Gauss–Legendre quadrature, equal to the volume the
//!   chambers sweep per revolution times the speed (any r/l, rod area);
//! * energy over a revolution at constant speed: crank work = fluid work + friction work + ΔKE.

use std::f64::consts::PI;

use reciprocating_drive::model::crank::CrankState;
use reciprocating_drive::model::drive::{Inputs, Model, Outputs, RodState};
use reciprocating_drive::model::params::Params;

/// The per-cylinder outputs of cylinder `k` (0-based), as the variable table reads them
/// (`cylinder_1.*` are the link's own outputs).
fn cylinder(o: &Outputs, k: usize) -> [f64; 9] {
    let c = &o.cylinders[k];
    if k == 0 {
        [
            o.position,
            o.velocity,
            o.acceleration,
            o.inertia_force,
            c.fluid_force,
            o.guide.friction_total,
            o.rod_force,
            c.crank_torque,
            c.flow,
        ]
    } else {
        [
            c.position,
            c.velocity,
            c.acceleration,
            c.inertia_force,
            c.fluid_force,
            c.friction,
            c.rod_force,
            c.crank_torque,
            c.flow,
        ]
    }
}

/// A pump of `n` cylinders with the given phases (φ_1 = 0), all single- or double-acting.
fn pump(base: &Params, n: usize, phases: &[f64], acting: i32) -> Params {
    let mut p = base.clone();
    p.cylinders = n as i32;
    p.load_profile = 3;
    for k in 0..n {
        p.cylinder[k].acting = acting;
        p.cylinder[k].phase = if k == 0 { 0.0 } else { phases[k - 1] };
        // Liners differ, so that a cylinder mixed up with another shows.
        p.cylinder[k].piston_diameter = 0.13 + 0.01 * k as f64;
    }
    p
}

/// The one-cylinder machine of cylinder `k` of `p`: its liner, its phase as the angle offset.
fn single(p: &Params, k: usize) -> Params {
    let mut s = p.clone();
    s.cylinders = 1;
    s.cylinder[0] = p.cylinder[k];
    s.cylinder[0].phase = 0.0;
    s.crank_angle_offset = p.cylinder[k].phase;
    s
}

fn eval(m: &Model, theta: f64, w: f64, eps: f64, inputs: &Inputs) -> Outputs {
    m.evaluate(
        &CrankState { angle: theta, speed: w, acceleration: eps },
        inputs,
        &RodState::default(),
    )
    .unwrap()
}

const DUPLEX: &[f64] = &[PI / 2.0];
const TRIPLEX: &[f64] = &[2.0 * PI / 3.0, 4.0 * PI / 3.0];

#[test]
fn n_cylinders_equal_n_single_cylinder_machines_with_their_phases() {
    let base = Params::default(); // guide friction on, the gland elastic (docs/model.md §8)
    let mut with_balancer = base.clone();
    with_balancer.balancer_enabled = true;
    with_balancer.balancer_tuning = 1;
    let cases = [
        ("duplex double-acting", pump(&base, 2, DUPLEX, 2)),
        ("triplex single-acting", pump(&base, 3, TRIPLEX, 1)),
        ("triplex double-acting, odd phases, balancer", pump(&with_balancer, 3, &[1.0, 2.5], 2)),
    ];
    for (name, p) in cases {
        let n = p.cylinders as usize;
        let multi = Model::new(&p).unwrap();
        let singles: Vec<Model> = (0..n).map(|k| Model::new(&single(&p, k)).unwrap()).collect();
        for i in 0..97 {
            let x = i as f64;
            let theta = 0.0731 * x * x;
            let (w, eps) = (6.8 * (1.0 + 0.3 * (0.7 * x).sin()), 3.0 * (1.3 * x).cos());
            let pressures = Inputs {
                external_force: 0.0,
                discharge_pressure: 2.0e7 * (1.0 + 0.2 * (0.3 * x).cos()),
                suction_pressure: 3.0e5 * (1.0 + 0.5 * (0.5 * x).sin()),
            };
            let o = eval(&multi, theta, w, eps, &pressures);
            let (mut torque, mut flow, mut scale) = (0.0, 0.0, 0.0);
            for (k, s) in singles.iter().enumerate() {
                let r = eval(s, theta, w, eps, &pressures);
                let (a, b) = (cylinder(&o, k), cylinder(&r, 0));
                for (j, (u, v)) in a.iter().zip(&b).enumerate() {
                    // Same arithmetic on the same angle θ + φ_k: equal to rounding.
                    assert!(
                        (u - v).abs() <= 1e-12 * v.abs().max(1e-300),
                        "{name}, cylinder {}, output {j}, θ {theta}: {u} vs {v}",
                        k + 1
                    );
                }
                torque += r.crank_torque;
                scale += r.crank_torque.abs();
                flow += r.flow;
            }
            assert!(
                (o.crank_torque - torque).abs() <= 1e-13 * scale,
                "{name}: {} vs {torque}",
                o.crank_torque
            );
            assert!((o.flow - flow).abs() <= 1e-15 * flow.abs().max(1e-3), "{name}");
            let dp = pressures.discharge_pressure - pressures.suction_pressure;
            assert!((o.hydraulic_power - dp * flow).abs() <= 1e-13 * (dp * flow).abs());
            assert_eq!(o.mechanical_power, o.crank_torque * w);
            // link.external_force acts on cylinder 1 only.
            let pushed = Inputs { external_force: 1.0e4, ..pressures };
            let q = eval(&multi, theta, w, eps, &pushed);
            let r0 = eval(&singles[0], theta, w, eps, &pushed);
            assert_eq!(cylinder(&q, 0), cylinder(&r0, 0), "{name}");
            for k in 1..n {
                assert_eq!(cylinder(&q, k), cylinder(&o, k), "{name}");
            }
        }
    }
}

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n from Chebyshev guesses; the
/// textbook construction, e.g. Numerical Recipes, chapter 4), to rounding.
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let k = k as f64;
                    (p0, p1) = (p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k);
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// ∫ f over [a, b] by 20-point Gauss–Legendre on `panels` equal panels.
fn integrate(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64, panels: usize) -> f64 {
    let rule = gauss_legendre(20);
    let w = (b - a) / panels as f64;
    (0..panels)
        .map(|i| {
            let c = a + (i as f64 + 0.5) * w;
            rule.iter().map(|(x, wt)| wt * 0.5 * w * f(c + 0.5 * w * x)).sum::<f64>()
        })
        .sum()
}

/// The angles in [0, 2π) where some cylinder of a central crank-slider is at a dead centre
/// (θ + φ_k ∈ {0, π}), sorted, with 2π appended: between two of them every velocity keeps its
/// sign, so the flow is analytic there (the chamber weights switch within ~v_ε/(rω) of them).
fn dead_centres(phases: &[f64]) -> Vec<f64> {
    let mut t: Vec<f64> = std::iter::once(0.0)
        .chain(phases.iter().copied())
        .flat_map(|phi| [(-phi).rem_euclid(2.0 * PI), (PI - phi).rem_euclid(2.0 * PI)])
        .collect();
    t.push(0.0);
    t.push(2.0 * PI);
    t.sort_by(f64::total_cmp);
    t.dedup_by(|a, b| (*a - *b).abs() < 1e-15);
    t
}

/// ∫₀^{2π} f(θ) dθ split at the dead centres.
fn over_a_revolution(f: &mut dyn FnMut(f64) -> f64, phases: &[f64], panels: usize) -> f64 {
    dead_centres(phases).windows(2).map(|ab| integrate(f, ab[0], ab[1], panels)).sum()
}

/// The textbook machine: r/l = 1e-6, rod area 0, v_ε = 1e-9 m/s (ideal valves), no supports.
fn textbook(n: usize, phases: &[f64], acting: i32) -> Params {
    let mut p = pump(&Params::default(), n, phases, acting);
    p.rod_length = 0.2e6;
    p.velocity_scale = 1e-9;
    for c in &mut p.cylinder {
        c.rod_diameter = 0.0;
        c.piston_diameter = 0.13;
    }
    for s in &mut p.supports {
        s.kind = 0;
    }
    p
}

#[test]
fn flow_pulsation_in_the_textbook_limit() {
    let w = 6.8;
    let cases = [
        ("simplex single-acting", textbook(1, &[], 1), &[][..], PI),
        ("duplex double-acting", textbook(2, DUPLEX, 2), DUPLEX, (2f64.sqrt() - 1.0) * PI / 4.0),
        (
            "triplex single-acting",
            textbook(3, TRIPLEX, 1),
            TRIPLEX,
            (1.0 - 3f64.sqrt() / 2.0) * PI / 3.0,
        ),
    ];
    for (name, p, phases, expect) in cases {
        let m = Model::new(&p).unwrap();
        let q = |theta: f64| eval(&m, theta, w, 0.0, &Inputs::default()).flow;
        // Extremes: the best of a 7 200-point grid (the textbook extremes sit on it: multiples
        // of 15°), refined by golden-section search around it.
        let n = 7200;
        let grid: Vec<(f64, f64)> =
            (0..n).map(|i| 2.0 * PI * i as f64 / n as f64).map(|t| (t, q(t))).collect();
        let refine = |t0: f64, sign: f64| {
            let (mut a, mut b) = (t0 - 2.0 * PI / n as f64, t0 + 2.0 * PI / n as f64);
            let g = 0.5 * (5f64.sqrt() - 1.0);
            for _ in 0..80 {
                let (c, d) = (b - g * (b - a), a + g * (b - a));
                if sign * q(c) > sign * q(d) {
                    b = d
                } else {
                    a = c
                }
            }
            q(0.5 * (a + b))
        };
        let max = grid.iter().max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        let min = grid.iter().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        let (q_max, q_min) = (refine(max.0, 1.0).max(max.1), refine(min.0, -1.0).min(min.1));
        let mean = over_a_revolution(&mut |t| q(t), phases, 16) / (2.0 * PI);
        let delta = (q_max - q_min) / mean;
        println!("{name}: pulsation {delta:.10} (textbook {expect:.10})");
        // r/l = 1e-6 moves the extremes by O(r/l) of the flow.
        assert!((delta - expect).abs() < 1e-5, "{name}: {delta} vs {expect}");
    }
}

#[test]
fn mean_flow_is_the_swept_volume_times_the_speed() {
    // The real geometry (r/l = 0.168, a 70 mm rod), ideal valves: Q̄ = Σ (A_h + A_c)·S·ω/(2π)
    // for double-acting cylinders, Σ A_h·S·ω/(2π) for single-acting ones, S = 2r.
    let w = 6.8;
    for (name, n, phases, acting) in [
        ("simplex double-acting", 1, &[][..], 2),
        ("duplex double-acting", 2, DUPLEX, 2),
        ("triplex single-acting", 3, TRIPLEX, 1),
        ("triplex double-acting, odd phases", 3, &[1.0, 2.5][..], 2),
    ] {
        let mut p = pump(&Params::default(), n, phases, acting);
        p.velocity_scale = 1e-9;
        let m = Model::new(&p).unwrap();
        let mean =
            over_a_revolution(&mut |t| eval(&m, t, w, 0.0, &Inputs::default()).flow, phases, 16)
                / (2.0 * PI);
        let stroke = 2.0 * p.crank_radius;
        let swept: f64 = p.cylinder[..n]
            .iter()
            .map(|c| {
                let head = PI / 4.0 * c.piston_diameter.powi(2);
                let crank = PI / 4.0 * (c.piston_diameter.powi(2) - c.rod_diameter.powi(2));
                (head + if c.acting == 2 { crank } else { 0.0 }) * stroke
            })
            .sum();
        let expect = swept * w / (2.0 * PI);
        println!("{name}: mean flow {mean:.15e} m3/s, swept volume × speed {expect:.15e}");
        assert!((mean - expect).abs() <= 1e-12 * expect, "{name}: {mean} vs {expect}");
    }
}

#[test]
fn energy_over_a_revolution_at_constant_speed() {
    // With guide friction (the default supports, v_ε = 0.02 m/s) and the pressures:
    // ∫T·ω dt = Σ_k ∫(−F_fluid,k·v_k) dt + Σ_k ∫(−F_fr,k·v_k) dt + ΔKE, ΔKE = Σ m/2·(v_k(T)² −
    // v_k(0)²) from the end points (0 over a revolution). At constant ω, dt = dθ/ω.
    // Quadrature: 20-point Gauss–Legendre on panels of 0.01 rad between the dead centres. The
    // integrands are analytic between kinks of the friction law (a support reaction through 0),
    // and the work terms share the nodes, so what the balance tests beside the pointwise
    // identity T = −Σ P_k·TF_k is ∫m·a·v dt = ΔKE, whose integrand is analytic: its error is
    // ~(0.01/0.05)^40 of it, far below 1e-9. The pressures' tanh weights switch over
    // v_ε/(r·ω) ≈ 0.013 rad, their poles ~0.02 rad off the real axis: also resolved.
    let w = 6.8;
    for (name, n, phases, acting) in [
        ("simplex double-acting", 1, &[][..], 2),
        ("duplex double-acting", 2, DUPLEX, 2),
        ("triplex single-acting", 3, TRIPLEX, 1),
    ] {
        let p = pump(&Params::default(), n, phases, acting);
        let m = Model::new(&p).unwrap();
        let inputs =
            Inputs { external_force: 0.0, discharge_pressure: 2.0e7, suction_pressure: 3.0e5 };
        let at = |t: f64| eval(&m, t, w, 0.0, &inputs);
        let panels = |ab: &[f64]| ((ab[1] - ab[0]) / 0.01).ceil() as usize;
        let sum = |f: &dyn Fn(&Outputs) -> f64| -> f64 {
            dead_centres(phases)
                .windows(2)
                .map(|ab| integrate(&mut |t| f(&at(t)), ab[0], ab[1], panels(ab)))
                .sum::<f64>()
                / w
        };
        let per = |o: &Outputs, f: &dyn Fn(&[f64; 9]) -> f64| -> f64 {
            (0..n).map(|k| f(&cylinder(o, k))).sum()
        };
        let crank = sum(&|o| o.crank_torque * w);
        let fluid = sum(&|o| per(o, &|c| -c[4] * c[1]));
        let friction = sum(&|o| per(o, &|c| -c[5] * c[1]));
        let kinetic = sum(&|o| per(o, &|c| p.mass * c[2] * c[1]));
        let hydraulic = sum(&|o| o.hydraulic_power);
        let (a, b) = (at(0.0), at(2.0 * PI));
        let delta_ke: f64 = (0..n)
            .map(|k| 0.5 * p.mass * (cylinder(&b, k)[1].powi(2) - cylinder(&a, k)[1].powi(2)))
            .sum();
        let residual = crank - fluid - friction - delta_ke;
        println!(
            "{name}: crank {crank:.6e} J, fluid {fluid:.6e} J, friction {friction:.6e} J, \
             ΔKE {delta_ke:.1e} J, ∫m·a·v {kinetic:.1e} J; residual {:.1e} of the fluid work",
            residual / fluid
        );
        assert!(friction > 0.0 && fluid > 0.0);
        assert!(residual.abs() <= 1e-9 * fluid, "{name}: residual {residual} J");
        // Over a revolution the fluid work is the hydraulic work (p_d − p_s)·∫Q dt: the suction
        // pressure's work on the net volume change Σ −(A_h − A_c)·v_k integrates to 0 (§4.1).
        assert!((hydraulic - fluid).abs() <= 1e-9 * fluid, "{name}: {hydraulic} vs {fluid}");
    }
}
