//! Piecewise-polynomial table of the P-dependent rod coefficients (docs/model.md §6, §5.4) for the
//! integrator's stages.
//!
//! # Why
//!
//! Every right-hand side of the cage equation needs `K_ϑ(P)`, `K_Δ(P)` at the rod force P, and P
//! is implicit through the guide friction (§4, §5.4): the clamp loads `M_0`, `V` that load the
//! link depend on P through the same beam column. Building a [`BeamColumn`] (a square root, a
//! sine/cosine and a chain of divisions) at every iterate of that solve dominated the cost of a
//! communication step. All the integrator needs are five smooth functions of P alone:
//!
//! * `K_ϑ = A2·W/W*`, `K_Δ = A2·ē/(s_N·W*)` (cage equation),
//! * `m_Δ = A2·V4'/(s_N·W*)`, `m_ϑ = −A2·d̄/W*` (`M_0 = m_Δ·Δ + m_ϑ·ϑ`, from `M_0 = A2·C3/s_N`),
//! * `v_Δ = A2·V3'/(s_N²·W*)` (`V = v_Δ·Δ − K_Δ·ϑ`, from `V = −A2·C4/s_N²`; the coefficient of ϑ
//!   is exactly −K_Δ, Maxwell's reciprocity of the rod's flexibility).
//!
//! They are analytic in P on the table's range: the fundamental functions are entire in x, and
//! the only singularities are s_N = 0 (P = −A1) and the zeros of W* (κ·l_f = 2π and beyond, real
//! and far above the range, see `beam_column.rs`, "Validity"). So on a cell of width w at a
//! distance d from the nearest singularity a degree-n interpolant converges like (w/4d)^(n+1).
//!
//! # What it is
//!
//! Cells cover `[p_min, p_max]` without gaps; on each cell every function is the degree-`DEGREE`
//! polynomial interpolating the exact [`BeamColumn`] values at the Chebyshev–Lobatto points, so
//! neighbouring cells share their end values (the table is continuous to rounding). Each cell is
//! accepted only after checking the interpolant against exact values at the `DEGREE` points
//! halfway (in angle) between the nodes, where the interpolation error of an analytic function
//! is largest: the error must stay below `ACCURACY` times the function's scale (its largest
//! magnitude on the cell or at P = 0); otherwise the cell is halved. Construction is
//! deterministic (a pure function of the rod), so a stage evaluates the same table whatever
//! the history: results stay bit-identical after fmi2SetFMUstate.
//!
//! The range stops short of buckling (`K_ϑ ≥ K_MIN_FRACTION·K_ϑ(0)`) and of extreme tension; outside
//! it, or for a tolerance too tight for the table (`accuracy()`), the caller uses the exact
//! [`BeamColumn`], which also reports buckling (docs/model.md §6 "Validity").
//!
//! # Accuracy needed
//!
//! A relative error ε of the coefficients perturbs ϑ̈ by about ε·Ω0²·|ϑ| and, through the friction,
//! P by about ε·|F_fr|. With ε = `ACCURACY` = 1e-13 both are far below what the integrator's error
//! control at a tolerance ≥ 1e-10 can see (see `drive/cage_step.rs`,
//! `STAGE_P_TOLERANCE_FACTOR`); the outputs (`Model::evaluate`) always use the exact beam column.

// `!(a <= b)` is deliberate: it also rejects NaN; index loops mirror the lane formulas.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use super::beam_column::BeamColumn;
use super::stiffness::RodStiffness;
use std::f64::consts::PI;

/// Polynomial degree per cell (9 Chebyshev–Lobatto nodes).
pub const DEGREE: usize = 6;
/// Number of tabulated functions: [K_ϑ, K_Δ, m_Δ, m_ϑ, v_Δ].
pub const FUNCTIONS: usize = 5;
/// Lanes per coefficient row (one unused lane: rows of 3 × 2 doubles vectorize cleanly).
const LANES: usize = 6;
/// Required interpolation accuracy relative to each function's scale on the cell.
pub const ACCURACY: f64 = 1e-13;
/// The table ends where K_ϑ has fallen to this fraction of K_ϑ(0) (towards buckling).
const K_MIN_FRACTION: f64 = 0.25;
/// Cells are not split below this fraction of the table's range (then the table is not built).
const MIN_CELL_FRACTION: f64 = 1e-7;
/// Hard limit on the number of cells.
const MAX_CELLS: usize = 4096;

/// Index of each function in a coefficient row.
pub const K_THETA: usize = 0;
pub const K_DELTA: usize = 1;
pub const M_DELTA: usize = 2;
pub const M_THETA: usize = 3;
pub const V_DELTA: usize = 4;

/// The five tabulated functions from an exact beam column, in table order.
#[inline]
pub fn coefficients(bc: &BeamColumn) -> [f64; FUNCTIONS] {
    let a2_over_w = bc.a2 / bc.w_star;
    [
        bc.k_theta,
        bc.k_delta,
        a2_over_w * bc.ff.v4p / bc.s_n,
        -a2_over_w * bc.d_bar,
        a2_over_w * bc.ff.v3p / (bc.s_n * bc.s_n),
    ]
}

/// One cell: `f(P) = Σ_k c[k]·t^k`, `t = (P − mid)·inv_half ∈ [−1, 1]`.
#[derive(Clone, Debug)]
struct Cell {
    hi: f64,
    mid: f64,
    inv_half: f64,
    c: [[f64; LANES]; DEGREE + 1],
}

/// Values and P-derivatives of the five functions at one P.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Coefficients {
    pub value: [f64; FUNCTIONS],
    pub slope: [f64; FUNCTIONS],
}

/// The table (see the module docs).
#[derive(Clone, Debug)]
pub struct StiffnessTable {
    p_min: f64,
    p_max: f64,
    cells: Vec<Cell>,
}

impl StiffnessTable {
    /// Builds the table for a rod; None when the rod does not allow one (then every stage uses
    /// the exact beam column).
    pub fn build(
        stiff: &RodStiffness,
        flex_length: f64,
        rigid_length: f64,
    ) -> Option<StiffnessTable> {
        let exact = |p: f64| {
            BeamColumn::new(stiff, flex_length, rigid_length, p).ok().map(|bc| coefficients(&bc))
        };
        let k0 = exact(0.0)?[K_THETA];
        // Upper end: bisection for K_ϑ(P) = K_MIN_FRACTION·K_ϑ(0) (K_ϑ falls monotonically with
        // compression up to buckling; an Err counts as "beyond").
        let inside = |p: f64| exact(p).is_some_and(|c| c[K_THETA] >= K_MIN_FRACTION * k0);
        let mut hi = stiff.a2 / (flex_length * flex_length); // below any buckling load (Euler: π²·this)
        while inside(hi) {
            hi *= 2.0;
            if !hi.is_finite() {
                return None;
            }
        }
        let mut lo = 0.0;
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if inside(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let p_max = lo;
        // Lower end (tension): as far as the compression side reaches, four times over, but at
        // most half-way to s_N = 0 (P = −A1).
        let p_min = -(4.0 * p_max).min(0.5 * stiff.a1);
        if !(p_max > 0.0 && p_min < 0.0) {
            return None;
        }
        let scale0 = exact(0.0)?.map(f64::abs);
        let min_width = MIN_CELL_FRACTION * (p_max - p_min);
        // Depth-first over a stack of pending intervals, left to right: the cells come out sorted.
        let mut cells = Vec::new();
        let mut pending: Vec<(f64, f64)> = Vec::new();
        const START_CELLS: usize = 16;
        for i in (0..START_CELLS).rev() {
            let a = p_min + (p_max - p_min) * i as f64 / START_CELLS as f64;
            let b = if i + 1 == START_CELLS {
                p_max
            } else {
                p_min + (p_max - p_min) * (i + 1) as f64 / START_CELLS as f64
            };
            pending.push((a, b));
        }
        while let Some((a, b)) = pending.pop() {
            match fit_cell(&exact, a, b, &scale0) {
                Some(cell) => {
                    cells.push(cell);
                    if cells.len() > MAX_CELLS {
                        return None;
                    }
                }
                None => {
                    if b - a < min_width {
                        return None;
                    }
                    let m = 0.5 * (a + b);
                    pending.push((m, b));
                    pending.push((a, m));
                }
            }
        }
        Some(StiffnessTable { p_min, p_max, cells })
    }

    /// The range covered, [p_min, p_max] [N].
    pub fn range(&self) -> (f64, f64) {
        (self.p_min, self.p_max)
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether the table has no cells (never true for a built table).
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// Index of the cell containing P, trying `hint` first; None outside the range (or NaN).
    #[inline]
    pub fn find(&self, p: f64, hint: usize) -> Option<usize> {
        if !(p >= self.p_min && p <= self.p_max) {
            return None;
        }
        let lo_of = |i: usize| if i == 0 { self.p_min } else { self.cells[i - 1].hi };
        if hint < self.cells.len() && p >= lo_of(hint) && p <= self.cells[hint].hi {
            return Some(hint);
        }
        // First cell whose upper end is ≥ P.
        let i = self.cells.partition_point(|c| c.hi < p);
        (i < self.cells.len()).then_some(i)
    }

    /// Values and slopes d/dP of the five functions at P, on cell `i` (from `find`).
    #[inline]
    pub fn eval(&self, i: usize, p: f64) -> Coefficients {
        let cell = &self.cells[i];
        let t = (p - cell.mid) * cell.inv_half;
        let mut v = cell.c[DEGREE];
        let mut d = [0.0; LANES];
        for k in (0..DEGREE).rev() {
            for f in 0..LANES {
                d[f] = d[f] * t + v[f];
                v[f] = v[f] * t + cell.c[k][f];
            }
        }
        let mut out = Coefficients::default();
        for f in 0..FUNCTIONS {
            out.value[f] = v[f];
            out.slope[f] = d[f] * cell.inv_half;
        }
        out
    }

    /// The values of [`StiffnessTable::eval`] alone (the same operations for them, so the same
    /// bits), at about half its cost.
    #[inline]
    pub fn values(&self, i: usize, p: f64) -> [f64; FUNCTIONS] {
        let cell = &self.cells[i];
        let t = (p - cell.mid) * cell.inv_half;
        let mut v = cell.c[DEGREE];
        for k in (0..DEGREE).rev() {
            for f in 0..LANES {
                v[f] = v[f] * t + cell.c[k][f];
            }
        }
        let mut out = [0.0; FUNCTIONS];
        out.copy_from_slice(&v[..FUNCTIONS]);
        out
    }
}

/// Chebyshev–Lobatto interpolant on [a, b], verified halfway between the nodes; None when the
/// check fails (or the beam column fails inside).
fn fit_cell(
    exact: &impl Fn(f64) -> Option<[f64; FUNCTIONS]>,
    a: f64,
    b: f64,
    scale0: &[f64; FUNCTIONS],
) -> Option<Cell> {
    const N: usize = DEGREE;
    let mid = 0.5 * (a + b);
    let half = 0.5 * (b - a);
    let at = |t: f64| {
        if t <= -1.0 {
            a
        } else if t >= 1.0 {
            b
        } else {
            mid + half * t
        }
    };
    // Values at t_j = cos(jπ/N), j = 0..N (t_0 = 1 ↔ b, t_N = −1 ↔ a).
    let mut vals = [[0.0; FUNCTIONS]; N + 1];
    let mut scale = *scale0;
    for (j, row) in vals.iter_mut().enumerate() {
        let t = if j == 0 {
            1.0
        } else if j == N {
            -1.0
        } else {
            (j as f64 * PI / N as f64).cos()
        };
        *row = exact(at(t))?;
        for f in 0..FUNCTIONS {
            scale[f] = scale[f].max(row[f].abs());
        }
    }
    // Chebyshev coefficients a_k = (2/N)·Σ''_j f_j·cos(jkπ/N), halved for k = 0 and k = N.
    let mut cheb = [[0.0; FUNCTIONS]; N + 1];
    for (k, ck) in cheb.iter_mut().enumerate() {
        for (j, row) in vals.iter().enumerate() {
            let w = if j == 0 || j == N { 0.5 } else { 1.0 };
            let cos = ((j * k) as f64 * PI / N as f64).cos();
            for f in 0..FUNCTIONS {
                ck[f] += w * row[f] * cos;
            }
        }
        let norm = if k == 0 || k == N { 1.0 / N as f64 } else { 2.0 / N as f64 };
        for v in ck.iter_mut() {
            *v *= norm;
        }
    }
    // Monomial coefficients in t: T_0 = 1, T_1 = t, T_{k+1} = 2t·T_k − T_{k−1}.
    let mut c = [[0.0; LANES]; N + 1];
    let mut t_prev = [0.0; N + 1];
    let mut t_cur = [0.0; N + 1];
    t_prev[0] = 1.0; // T_0
    t_cur[1] = 1.0; // T_1
    for (k, ck) in cheb.iter().enumerate() {
        let basis = if k == 0 { &t_prev } else { &t_cur };
        for (m, &bm) in basis.iter().enumerate() {
            if bm != 0.0 {
                for f in 0..FUNCTIONS {
                    c[m][f] += ck[f] * bm;
                }
            }
        }
        if k >= 1 {
            let mut next = [0.0; N + 1];
            for m in 0..=N {
                let shifted = if m > 0 { 2.0 * t_cur[m - 1] } else { 0.0 };
                next[m] = shifted - t_prev[m];
            }
            t_prev = t_cur;
            t_cur = next;
        }
    }
    let cell = Cell { hi: b, mid, inv_half: 1.0 / half, c };
    // Check halfway (in angle) between the nodes, with the evaluation used at run time.
    let table = StiffnessTable { p_min: a, p_max: b, cells: vec![cell] };
    for m in 0..N {
        let t = ((m as f64 + 0.5) * PI / N as f64).cos();
        let p = at(t);
        let want = exact(p)?;
        let got = table.eval(0, p).value;
        for f in 0..FUNCTIONS {
            if !((got[f] - want[f]).abs() <= ACCURACY * scale[f]) {
                return None;
            }
        }
    }
    table.cells.into_iter().next()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::elastic_rod::tests::{kvo630, thin_rod};
    use crate::model::elastic_rod::RodSpec;

    fn exact(st: &RodStiffness, spec: &RodSpec, p: f64) -> [f64; FUNCTIONS] {
        coefficients(&BeamColumn::new(st, spec.flex_length, spec.rigid_length, p).unwrap())
    }

    #[test]
    fn coefficients_are_the_clamp_loads_and_stiffnesses_of_the_beam_column() {
        // M0 = m_Δ·Δ + m_ϑ·ϑ and V = v_Δ·Δ − K_Δ·ϑ reproduce BeamColumn::clamp_loads (the
        // coefficient of ϑ in V is −K_Δ: reciprocity), for compression and tension.
        for spec in [kvo630(), thin_rod()] {
            let st = RodStiffness::new(&spec).unwrap();
            for &p in &[-80.0, -3.0, 0.0, 7.5, 14.7, 20.0] {
                let bc = BeamColumn::new(&st, spec.flex_length, spec.rigid_length, p).unwrap();
                let c = coefficients(&bc);
                assert_eq!((c[K_THETA], c[K_DELTA]), (bc.k_theta, bc.k_delta));
                for &(delta, theta) in &[(1e-3, 0.0), (0.0, 0.03), (7e-4, -0.02)] {
                    let (m0, v) = bc.clamp_loads(delta, theta);
                    let m0_c = c[M_DELTA] * delta + c[M_THETA] * theta;
                    let v_c = c[V_DELTA] * delta - c[K_DELTA] * theta;
                    let scale_m = (c[M_DELTA] * delta).abs() + (c[M_THETA] * theta).abs();
                    let scale_v = (c[V_DELTA] * delta).abs() + (c[K_DELTA] * theta).abs();
                    assert!(
                        (m0 - m0_c).abs() <= 1e-14 * scale_m,
                        "{p} {delta} {theta}: M0 {m0} {m0_c}"
                    );
                    assert!((v - v_c).abs() <= 1e-14 * scale_v, "{p} {delta} {theta}: V {v} {v_c}");
                }
            }
        }
    }

    #[test]
    fn table_matches_the_exact_beam_column_densely() {
        // Every function within 2·ACCURACY of its scale (largest of |f(0)| and |f(P)|) at 20 001
        // loads across the whole range, including the cell ends and points between the nodes
        // that the construction did not check; slopes against central differences of the exact
        // values.
        for spec in [kvo630(), thin_rod()] {
            let st = RodStiffness::new(&spec).unwrap();
            let tab = StiffnessTable::build(&st, spec.flex_length, spec.rigid_length).unwrap();
            let (a, b) = tab.range();
            let s0 = exact(&st, &spec, 0.0);
            let mut worst = [0.0f64; FUNCTIONS];
            let n = 20_000;
            let mut hint = 0;
            for i in 0..=n {
                let p = if i == n { b } else { a + (b - a) * i as f64 / n as f64 };
                let e = exact(&st, &spec, p);
                hint = tab.find(p, hint).unwrap();
                let g = tab.eval(hint, p);
                assert_eq!(tab.values(hint, p), g.value);
                for f in 0..FUNCTIONS {
                    let scale = s0[f].abs().max(e[f].abs());
                    worst[f] = worst[f].max((g.value[f] - e[f]).abs() / scale);
                }
                if i % 50 == 25 {
                    let h = 1e-4 * (b - a);
                    let (ep, em) = (exact(&st, &spec, p + h), exact(&st, &spec, p - h));
                    for f in 0..FUNCTIONS {
                        let fd = (ep[f] - em[f]) / (2.0 * h);
                        let scale = (s0[f].abs().max(e[f].abs())) / (b - a);
                        assert!(
                            (g.slope[f] - fd).abs() <= 1e-6 * scale,
                            "{:?} f{f} P {p}: {} vs {fd}",
                            spec.kind,
                            g.slope[f]
                        );
                    }
                }
            }
            println!(
                "{:?}: {} cells over [{a}, {b}] N, worst relative error {worst:?}",
                spec.kind,
                tab.len()
            );
            for f in 0..FUNCTIONS {
                assert!(worst[f] <= 2.0 * ACCURACY, "{:?} f{f}: {}", spec.kind, worst[f]);
            }
        }
    }

    #[test]
    fn range_reaches_from_tension_to_near_buckling() {
        // Upper end: K_ϑ = K_MIN_FRACTION·K_ϑ(0) (so the working point of kvo630, 14.7 N ± the
        // inertia load, is inside); lower end: tension four times that; outside: None.
        let spec = kvo630();
        let st = RodStiffness::new(&spec).unwrap();
        let tab = StiffnessTable::build(&st, spec.flex_length, spec.rigid_length).unwrap();
        let (a, b) = tab.range();
        let k0 = exact(&st, &spec, 0.0)[K_THETA];
        assert!((exact(&st, &spec, b)[K_THETA] / k0 - K_MIN_FRACTION).abs() < 1e-9);
        assert!(b > 16.0 && a == -4.0 * b, "{a} {b}");
        for p in [b * (1.0 + 1e-12), a * (1.0 + 1e-12), f64::NAN, f64::INFINITY] {
            assert_eq!(tab.find(p, 0), None, "{p}");
        }
        assert!(tab.find(a, 3).is_some() && tab.find(b, 0) == Some(tab.len() - 1));
    }

    #[test]
    fn lookup_finds_the_cell_whatever_the_hint_and_cells_join_continuously() {
        let spec = thin_rod();
        let st = RodStiffness::new(&spec).unwrap();
        let tab = StiffnessTable::build(&st, spec.flex_length, spec.rigid_length).unwrap();
        let (a, b) = tab.range();
        for i in 0..=997 {
            let p = if i == 997 { b } else { a + (b - a) * i as f64 / 997.0 };
            let want = tab.find(p, usize::MAX).unwrap();
            for hint in [0, want, tab.len() - 1, tab.len() + 5] {
                let got = tab.find(p, hint).unwrap();
                let lo = if got == 0 { a } else { tab.cells[got - 1].hi };
                assert!(p >= lo && p <= tab.cells[got].hi, "P {p} hint {hint}");
            }
        }
        // Neighbouring cells interpolate the same exact values at their common end.
        for i in 0..tab.len() - 1 {
            let p = tab.cells[i].hi;
            let (l, r) = (tab.eval(i, p).value, tab.eval(i + 1, p).value);
            for f in 0..FUNCTIONS {
                assert!(
                    (l[f] - r[f]).abs() <= 1e-14 * l[f].abs().max(1e-300),
                    "cell {i} f{f}: {} {}",
                    l[f],
                    r[f]
                );
            }
        }
    }

    #[test]
    fn construction_is_deterministic() {
        let spec = kvo630();
        let st = RodStiffness::new(&spec).unwrap();
        let t1 = StiffnessTable::build(&st, spec.flex_length, spec.rigid_length).unwrap();
        let t2 = StiffnessTable::build(&st, spec.flex_length, spec.rigid_length).unwrap();
        assert_eq!(t1.range(), t2.range());
        for (c1, c2) in t1.cells.iter().zip(&t2.cells) {
            assert_eq!((c1.hi, c1.mid, c1.inv_half, c1.c), (c2.hi, c2.mid, c2.inv_half, c2.c));
        }
    }
}
