//! The elastic rod's P- and Δ-dependent quantities in dual numbers (docs/fmi-interface.md
//! "Directional derivatives"): the clamp loads (§5.4), the largest stress (§6 "Stress") and the
//! cage stiffnesses K_ϑ, K_Δ (§6) along a direction of the axial load P, the pin offset Δ and the
//! cage angle ϑ. The same formulas as
//! `beam_column.rs`, `fundamental_functions.rs` and `stress.rs`, branch for branch (the branch is
//! chosen by the real part, as the f64 code chooses it), run once with `num_dual::Dual64`: a
//! forward-mode derivative of the model's own arithmetic, not a difference. They are a separate
//! copy rather than a generic version of the f64 code so that the integrator's hot path (the
//! stiffness table and the beam column of every stage) stays exactly as it is.

use num_dual::{Dual64, DualNum};

use super::beam_column::BeamColumn;
use super::fundamental_functions::{INV_FACT_EVEN, INV_FACT_ODD, SERIES_LIMIT};
use super::stress::station_intervals;
use super::{RodKind, RodSpec, RodStiffness};
use std::f64::consts::PI;

/// C, S, V3, V4 at z (V3' = S, V4' = V3, as in `fundamental_functions`).
#[derive(Clone, Copy)]
struct Ff {
    c: Dual64,
    s: Dual64,
    v3: Dual64,
    v4: Dual64,
}

fn horner(u: Dual64, coef: &[f64; 12]) -> Dual64 {
    let mut acc = Dual64::from(coef[11]);
    for &c in coef[..11].iter().rev() {
        acc = acc * u + c;
    }
    acc
}

/// `fundamental_functions(x, z)` with x a dual number (docs/model.md §6).
fn fundamental_functions(x: Dual64, z: f64) -> Ff {
    let u = x * (z * z);
    if u.re.abs() <= SERIES_LIMIT {
        let p3 = horner(u, &INV_FACT_EVEN);
        let p4 = horner(u, &INV_FACT_ODD);
        Ff { c: u * p3 + 1.0, s: (u * p4 + 1.0) * z, v3: p3 * (z * z), v4: p4 * (z * z * z) }
    } else {
        let (c, s) = if x.re > 0.0 {
            let r = x.sqrt();
            let e = (r * z).exp();
            let ei = e.recip();
            ((e + ei) * 0.5, (e - ei) * 0.5 / r)
        } else {
            let r = (-x).sqrt();
            let (sn, cs) = (r * z).sin_cos();
            (cs, sn / r)
        };
        Ff { c, s, v3: (c - 1.0) / x, v4: (s - z) / x }
    }
}

/// The beam column of `BeamColumn::new` at a dual P: what the clamp loads and the stress need.
struct DualColumn {
    a2: f64,
    s_n: Dual64,
    x: Dual64,
    ff: Ff,
    eta: Dual64,
    f1: Dual64,
    e_bar: Dual64,
    d_bar: Dual64,
    w_star: Dual64,
    flex_length: f64,
}

impl DualColumn {
    /// `bc` is the f64 beam column at `p.re` (it has passed the validity checks).
    fn new(stiff: &RodStiffness, bc: &BeamColumn, p: Dual64) -> DualColumn {
        let (a1, a2, l) = (stiff.a1, stiff.a2, bc.flex_length);
        let n = -p;
        let s_n = -n / a1 + 1.0;
        let x = n * s_n / a2;
        let eta = (s_n * s_n * a1).recip() * a2;
        let f1 = s_n.recip() * bc.rigid_length;
        let ff = fundamental_functions(x, l);
        let e_bar = ff.v3 + f1 * ff.s;
        let d_bar = ff.v4 + f1 * ff.v3 - eta * l;
        // `wronskian_core` of beam_column.rs (the same branch as the f64 value).
        let core = if (x.re * l * l).abs() <= SERIES_LIMIT {
            ff.v3 * ff.v3 - ff.s * ff.v4
        } else {
            (ff.s * l - ff.v3 * 2.0) / x
        };
        let w_star = core + eta * l * ff.s;
        DualColumn { a2, s_n, x, ff, eta, f1, e_bar, d_bar, w_star, flex_length: l }
    }

    /// `BeamColumn::c3_c4`.
    fn c3_c4(&self, delta: Dual64, theta: Dual64) -> (Dual64, Dual64) {
        let c3 = (self.ff.v3 * delta - self.s_n * self.d_bar * theta) / self.w_star;
        let c4 = (self.s_n * self.e_bar * theta - self.ff.s * delta) / self.w_star;
        (c3, c4)
    }
}

/// The clamp loads (M0, V) of `BeamColumn::clamp_loads` (§5.4) at the dual P, Δ and cage angle
/// ϑ; `bc` is the f64 beam column at `p.re`.
pub fn clamp_loads(
    stiff: &RodStiffness,
    bc: &BeamColumn,
    p: Dual64,
    delta: Dual64,
    theta: Dual64,
) -> (Dual64, Dual64) {
    let col = DualColumn::new(stiff, bc, p);
    let (c3, c4) = col.c3_c4(delta, theta);
    (c3 * col.a2 / col.s_n, -c4 * col.a2 / (col.s_n * col.s_n))
}

/// `stress_max` (§6 "Stress") at the dual P, Δ and cage angle ϑ. The largest |M(z_j)|
/// is the station the real parts pick (the derivative of a maximum is that of its argument,
/// one-sided where two stations tie, as at every other kink of the model).
pub fn stress_max(
    spec: &RodSpec,
    stiff: &RodStiffness,
    bc: &BeamColumn,
    p: Dual64,
    delta: Dual64,
    theta: Dual64,
) -> Dual64 {
    let col = DualColumn::new(stiff, bc, p);
    let n = station_intervals(spec);
    let (c3, c4) = col.c3_c4(delta, theta);
    let scale = col.s_n.recip() * stiff.a2;
    let step = fundamental_functions(col.x, col.flex_length / n as f64);
    let (mut c, mut s) = (Dual64::from(1.0), Dual64::from(0.0));
    let abs = |m: Dual64| if m.re < 0.0 { -m } else { m };
    let mut m_max = abs(scale * c3);
    for j in 1..=n {
        if j == n {
            c = col.ff.c;
            s = col.ff.s;
        } else {
            let c_next = c * step.c + col.x * s * step.s;
            s = s * step.c + c * step.s;
            c = c_next;
        }
        let m = abs(scale * (c3 * c + c4 * s));
        // `f64::max` keeps the first of two equal values.
        if m.re > m_max.re {
            m_max = m;
        }
    }
    let n_abs = abs(p);
    let d = spec.wire_diameter;
    match spec.kind {
        RodKind::HelicalSpring => {
            let dc = spec.coil_diameter;
            let ci = dc / d;
            let k_w = (4.0 * ci - 1.0) / (4.0 * ci - 4.0) + 0.615 / ci;
            (m_max + n_abs * (dc / 2.0)) * (k_w / (PI * d * d * d / 16.0))
        }
        RodKind::ThinRod => m_max * (32.0 / (PI * d * d * d)) + n_abs * (4.0 / (PI * d * d)),
    }
}

/// The cage stiffnesses (K_ϑ, K_Δ) of `BeamColumn::new` (§6) at the dual P: K_ϑ = A2·W/W*,
/// K_Δ = A2·ē/(s_N·W*), W = l·V3 − V4 + f1(l + f1)·S + η·l·(C + f1·x·S) (V3'' = C, V3''' = x·S);
/// `bc` is the f64 beam column at `p.re`.
pub fn stiffnesses(stiff: &RodStiffness, bc: &BeamColumn, p: Dual64) -> (Dual64, Dual64) {
    let col = DualColumn::new(stiff, bc, p);
    let (l, ff, f1) = (col.flex_length, col.ff, col.f1);
    let l3 = ff.c + f1 * col.x * ff.s;
    let w = ff.v3 * l - ff.v4 + f1 * (f1 + l) * ff.s + col.eta * l * l3;
    (w * col.a2 / col.w_star, col.e_bar * col.a2 / (col.s_n * col.w_star))
}

#[cfg(test)]
mod tests {
    //! The dual clamp loads and stress have the f64 values as their real parts, and their dual
    //! parts agree with 8th-order central differences of the f64 code (an independent path: the
    //! f64 beam column rebuilt at each shifted P) over compression, the unloaded rod and
    //! tension, both series and closed-form branches.
    use num_dual::Dual64;

    use super::{clamp_loads, stiffnesses, stress_max};
    use crate::model::elastic_rod::tests::{kvo630, thin_rod};
    use crate::model::elastic_rod::{BeamColumn, RodStiffness};

    fn diff(f: &dyn Fn(f64) -> f64, x: f64, h: f64) -> f64 {
        let c = [4.0 / 5.0, -1.0 / 5.0, 4.0 / 105.0, -1.0 / 280.0];
        (1..=4).map(|k| c[k - 1] * (f(x + k as f64 * h) - f(x - k as f64 * h))).sum::<f64>() / h
    }

    #[test]
    fn dual_parts_match_differences_of_the_f64_code() {
        for spec in [kvo630(), thin_rod()] {
            let st = RodStiffness::new(&spec).unwrap();
            let col =
                |p: f64| BeamColumn::new(&st, spec.flex_length, spec.rigid_length, p).unwrap();
            // The buckling load bounds the compression side; sample up to 60 % of the first P
            // where K_ϑ vanishes (found by bisection on the f64 code), none of the stencils
            // straddling P = 0 (the kink of |N| in the stress).
            let (mut lo, mut hi) = (0.0, 1e7);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if BeamColumn::new(&st, spec.flex_length, spec.rigid_length, mid).is_ok() {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let (delta, theta) = (7e-4, 0.03);
            let th = Dual64::from(theta);
            for frac in [-3.0, -0.5, -0.02, 0.01, 0.2, 0.45, 0.6] {
                let p = frac * lo;
                let bc = col(p);
                // Small enough that no stencil crosses a change of the stress station that is largest.
                let h = 1e-4 * lo;
                let f_m0 = |q: f64| col(q).clamp_loads(delta, theta).0;
                let f_v = |q: f64| col(q).clamp_loads(delta, theta).1;
                let f_s = |q: f64| {
                    crate::model::elastic_rod::stress_max(&spec, &st, &col(q), delta, theta, q)
                };
                let f_vd = |d: f64| bc.clamp_loads(d, theta).1;
                let (m0, v) = clamp_loads(&st, &bc, Dual64::new(p, 1.0), Dual64::from(delta), th);
                let (_, v_d) = clamp_loads(&st, &bc, Dual64::from(p), Dual64::new(delta, 1.0), th);
                let s = stress_max(&spec, &st, &bc, Dual64::new(p, 1.0), Dual64::from(delta), th);
                // Along the cage angle ϑ, and the stiffnesses along P.
                let th_seed = Dual64::new(theta, 1.0);
                let (m0_t, v_t) =
                    clamp_loads(&st, &bc, Dual64::from(p), Dual64::from(delta), th_seed);
                let s_t =
                    stress_max(&spec, &st, &bc, Dual64::from(p), Dual64::from(delta), th_seed);
                let (k_t, k_d) = stiffnesses(&st, &bc, Dual64::new(p, 1.0));
                let f_m0t = |t: f64| bc.clamp_loads(delta, t).0;
                let f_vt = |t: f64| bc.clamp_loads(delta, t).1;
                let f_st =
                    |t: f64| crate::model::elastic_rod::stress_max(&spec, &st, &bc, delta, t, p);
                let f_kt = |q: f64| col(q).k_theta;
                let f_kd = |q: f64| col(q).k_delta;
                let (m0_ref, v_ref) = bc.clamp_loads(delta, theta);
                let s_ref = crate::model::elastic_rod::stress_max(&spec, &st, &bc, delta, theta, p);
                for (name, got, want) in [
                    ("M0", m0.re, m0_ref),
                    ("V", v.re, v_ref),
                    ("σ", s.re, s_ref),
                    ("K_ϑ", k_t.re, bc.k_theta),
                    ("K_Δ", k_d.re, bc.k_delta),
                ] {
                    assert!(
                        (got - want).abs() <= 1e-12 * want.abs(),
                        "{name} at {p}: {got} vs {want}"
                    );
                }
                for (name, got, want) in [
                    ("dM0/dP", m0.eps, diff(&f_m0, p, h)),
                    ("dV/dP", v.eps, diff(&f_v, p, h)),
                    ("dσ/dP", s.eps, diff(&f_s, p, h)),
                    ("dV/dΔ", v_d.eps, diff(&f_vd, delta, 1e-5)),
                    ("dM0/dϑ", m0_t.eps, diff(&f_m0t, theta, 1e-4)),
                    ("dV/dϑ", v_t.eps, diff(&f_vt, theta, 1e-4)),
                    // A small step: a wider stencil crosses a change of the largest station.
                    ("dσ/dϑ", s_t.eps, diff(&f_st, theta, 1e-7)),
                    ("dK_ϑ/dP", k_t.eps, diff(&f_kt, p, h)),
                    ("dK_Δ/dP", k_d.eps, diff(&f_kd, p, h)),
                ] {
                    assert!(
                        (got - want).abs() <= 1e-7 * want.abs().max(1e-300),
                        "{name} at P = {p}: {got} vs {want}"
                    );
                }
            }
        }
    }
}
