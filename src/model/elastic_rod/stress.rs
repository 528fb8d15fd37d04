//! Largest stress in the elastic rod (docs/model.md §6, "Stress"; output `rod.stress_max`).

use super::beam_column::BeamColumn;
use super::fundamental_functions::fundamental_functions;
use super::stiffness::RodStiffness;
use super::{RodKind, RodSpec};
use std::f64::consts::PI;

/// Number of equal intervals of the thin rod's stress stations (docs/model.md §6).
pub const THIN_ROD_STATIONS: usize = 16;

/// Number of intervals n of the stress stations `z_j = j·l_f/n`, j = 0..n: 16 for a thin rod,
/// the number of coils for a spring (§6 says n = i; for a non-integer i we take ⌈i⌉ so that no
/// two stations are farther apart than one pitch).
pub fn station_intervals(spec: &RodSpec) -> usize {
    match spec.kind {
        RodKind::ThinRod => THIN_ROD_STATIONS,
        // RodStiffness::new guarantees 1 <= coils < inf; the clamp keeps this total anyway.
        RodKind::HelicalSpring => spec.coils.ceil().clamp(1.0, 10_000.0) as usize,
    }
}

/// Largest stress [Pa] (docs/model.md §6): with `M(z) = (A2/s_N)(C3·C(z) + C4·S(z))` at the
/// stations `z_j = j·l_f/n`, N = −P,
///
/// * spring: wire shear stress `τ = k_W·(max_j |M(z_j)| + |N|·D/2)/(πd³/16)` with the Wahl factor
///   `k_W = (4c − 1)/(4c − 4) + 0.615/c`, c = D/d (the bending moment of the coil axis and the
///   axial force both load the wire mainly in torsion);
/// * thin rod: `σ = max_j |M(z_j)|·32/(πd³) + |N|·4/(πd²)`.
///
/// `bc` must have been built from `stiff`, `spec.flex_length`, `spec.rigid_length` and `p`.
/// C(z_j), S(z_j) come from the addition theorems `C(a+b) = C(a)C(b) + x·S(a)S(b)`,
/// `S(a+b) = S(a)C(b) + C(a)S(b)` (valid for both signs of x), so one evaluation of the
/// fundamental functions serves all stations; the last station uses the stored values at l_f.
pub fn stress_max(
    spec: &RodSpec,
    stiff: &RodStiffness,
    bc: &BeamColumn,
    delta: f64,
    theta: f64,
    p: f64,
) -> f64 {
    let n = station_intervals(spec);
    let (c3, c4) = bc.c3_c4(delta, theta);
    let scale = stiff.a2 / bc.s_n;
    let step = fundamental_functions(bc.x, bc.flex_length / n as f64);
    let (mut c, mut s) = (1.0_f64, 0.0_f64);
    let mut m_max = (scale * c3).abs(); // station z_0 = 0: C = 1, S = 0
    for j in 1..=n {
        if j == n {
            c = bc.ff.c;
            s = bc.ff.s;
        } else {
            let c_next = c * step.c + bc.x * s * step.s;
            s = s * step.c + c * step.s;
            c = c_next;
        }
        m_max = m_max.max((scale * (c3 * c + c4 * s)).abs());
    }
    let n_abs = p.abs();
    let d = spec.wire_diameter;
    match spec.kind {
        RodKind::HelicalSpring => {
            let dc = spec.coil_diameter;
            let ci = dc / d;
            let k_w = (4.0 * ci - 1.0) / (4.0 * ci - 4.0) + 0.615 / ci;
            k_w * (m_max + n_abs * dc / 2.0) / (PI * d * d * d / 16.0)
        }
        RodKind::ThinRod => m_max * 32.0 / (PI * d * d * d) + n_abs * 4.0 / (PI * d * d),
    }
}
