//! Test-only independent reference: a dense beam finite-element model of the link (docs/model.md
//! §5.1, §5.5), written separately from production by a different method.
//!
//! Production uses the flexibility method on the free link (Mohr integrals, bordered system of
//! the contact forces). Here: Hermite cubic beam elements (exact nodal values for point loads on
//! piecewise-constant EJ), nodes at every section boundary, contact and load point plus
//! `extra` equally spaced nodes per section, elastic contacts as springs added to the stiffness
//! matrix, rigid contacts as Lagrange multipliers, one dense LU per evaluation. Geometry
//! (positions, frame axes) is recomputed here from the raw spec with the formulas of §5.2 as
//! written (Z = z + s, Z_ref at mid-stroke), not with production's simplified forms.
//!
//! Why double-double arithmetic (~32 digits) for the assembly and the LU: a stiffness model of a
//! link with a 0.3 m crosshead next to a 0.07 m rod, rigid and stiff elastic contacts, computes
//! reactions of ~500 N as differences of nodal forces of ~1e7 N; in f64 the FE answer moves by
//! up to 1e-7 of the reactions between meshes. In double-double that rounding is far below the
//! f64 result, so the reference is more accurate than production and the comparison tolerance
//! can be tight.
// Index loops mirror the matrix formulas above; `!(a > b)` tests deliberately reject NaN.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use super::{GuideSpec, SupportKind};
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Double-double number hi + lo (|lo| ≤ ulp(hi)/2), error-free transformations (Dekker, Knuth).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dd {
    hi: f64,
    lo: f64,
}

impl Dd {
    pub const ZERO: Dd = Dd { hi: 0.0, lo: 0.0 };
    pub fn new(x: f64) -> Dd {
        Dd { hi: x, lo: 0.0 }
    }
    pub fn to_f64(self) -> f64 {
        self.hi + self.lo
    }
    fn abs(self) -> Dd {
        if self.hi < 0.0 {
            -self
        } else {
            self
        }
    }
}

fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

impl Add for Dd {
    type Output = Dd;
    fn add(self, o: Dd) -> Dd {
        let (s, e) = two_sum(self.hi, o.hi);
        let (t, f) = two_sum(self.lo, o.lo);
        let (s, e) = quick_two_sum(s, e + t);
        let (hi, lo) = quick_two_sum(s, e + f);
        Dd { hi, lo }
    }
}

impl Neg for Dd {
    type Output = Dd;
    fn neg(self) -> Dd {
        Dd { hi: -self.hi, lo: -self.lo }
    }
}

impl Sub for Dd {
    type Output = Dd;
    fn sub(self, o: Dd) -> Dd {
        self + (-o)
    }
}

impl Mul for Dd {
    type Output = Dd;
    fn mul(self, o: Dd) -> Dd {
        let p = self.hi * o.hi;
        let e = self.hi.mul_add(o.hi, -p);
        let e = e + (self.hi * o.lo + self.lo * o.hi);
        let (hi, lo) = quick_two_sum(p, e);
        Dd { hi, lo }
    }
}

impl Div for Dd {
    type Output = Dd;
    fn div(self, o: Dd) -> Dd {
        // Long division: q1 = a/b, r = a − q1·b, q2 = r/b, r' = r − q2·b, q3 = r'/b.
        let q1 = self.hi / o.hi;
        let r = self - o * Dd::new(q1);
        let q2 = r.hi / o.hi;
        let r = r - o * Dd::new(q2);
        let q3 = r.hi / o.hi;
        let (hi, lo) = quick_two_sum(q1, q2);
        Dd { hi, lo } + Dd::new(q3)
    }
}

/// Dense LU with partial pivoting in double-double, kept for repeated solves.
struct DdLu {
    n: usize,
    a: Vec<Vec<Dd>>,
    perm: Vec<usize>,
}

impl DdLu {
    fn new(mut a: Vec<Vec<Dd>>) -> DdLu {
        let n = a.len();
        let mut perm: Vec<usize> = (0..n).collect();
        for k in 0..n {
            let p = (k..n)
                .max_by(|&i, &j| {
                    a[i][k].abs().to_f64().partial_cmp(&a[j][k].abs().to_f64()).unwrap()
                })
                .unwrap();
            assert!(a[p][k].hi != 0.0, "reference FE model singular");
            a.swap(p, k);
            perm.swap(p, k);
            let pivot = a[k][k];
            for i in (k + 1)..n {
                if a[i][k].hi == 0.0 {
                    continue;
                }
                let f = a[i][k] / pivot;
                a[i][k] = f;
                for j in (k + 1)..n {
                    let t = a[k][j];
                    if t.hi != 0.0 {
                        a[i][j] = a[i][j] - f * t;
                    }
                }
            }
        }
        DdLu { n, a, perm }
    }

    fn solve(&self, b: &[Dd]) -> Vec<Dd> {
        let n = self.n;
        let mut y: Vec<Dd> = self.perm.iter().map(|&p| b[p]).collect();
        for i in 0..n {
            let mut acc = y[i];
            for j in 0..i {
                acc = acc - self.a[i][j] * y[j];
            }
            y[i] = acc;
        }
        for i in (0..n).rev() {
            let mut acc = y[i];
            for j in (i + 1)..n {
                acc = acc - self.a[i][j] * y[j];
            }
            y[i] = acc / self.a[i][i];
        }
        y
    }
}

/// Reactions per support: net force R, moment about the centre M, and the centre's link coordinate.
#[derive(Clone, Copy, Debug, Default)]
pub struct RefReaction {
    pub r: f64,
    pub m: f64,
    pub centre: f64,
}

/// One contact of the reference model.
struct RefContact {
    support: usize,
    z: f64,
    slope: bool,
    prescribed: f64,
    stiffness: f64,
}

/// A factorised FE model at one s; loads can be applied repeatedly.
pub struct RefModel {
    nodes: Vec<f64>,
    contacts: Vec<RefContact>,
    lu: DdLu,
    ndof: usize,
    multiplier_scale: f64,
    load_point: f64,
    length: f64,
    centres: [f64; 3],
    lateral_load: f64,
}

fn node_index(nodes: &[f64], z: f64) -> usize {
    let mut best = 0;
    for (i, &n) in nodes.iter().enumerate() {
        if (n - z).abs() < (nodes[best] - z).abs() {
            best = i;
        }
    }
    best
}

impl RefModel {
    /// Builds and factorises the model at stroke coordinate `s` of a link with stroke `stroke`.
    pub fn new(spec: &GuideSpec, stroke: f64, s: f64, extra: usize) -> RefModel {
        let lengths = spec.section_lengths;
        let length: f64 = lengths.iter().sum();
        // Sections (start, end, EJ).
        let mut sections = Vec::new();
        let mut z = 0.0;
        for i in 0..4 {
            if lengths[i] > 0.0 {
                let d = spec.section_diameters[i];
                let ej = spec.e_modulus * std::f64::consts::PI * d.powi(4) / 64.0;
                sections.push((z, z + lengths[i], ej));
                z += lengths[i];
            }
        }
        let mut nodes = vec![0.0, length];
        for &(a, b, _) in &sections {
            nodes.push(a);
            nodes.push(b);
        }
        // Contacts at this s, frame axis y = δ + α(Z − Z_ref), Z = z + s.
        let mut contacts = Vec::new();
        let mut centres = [0.0; 3];
        for (x, sup) in spec.supports.iter().enumerate() {
            let centre = if sup.frame_fixed { sup.z - s } else { sup.z };
            centres[x] = centre;
            let z_ref = if sup.frame_fixed { sup.z } else { sup.z + stroke / 2.0 };
            let axis = |zl: f64| sup.offset + sup.tilt * (zl + s - z_ref);
            let lateral = |zl: f64, contacts: &mut Vec<RefContact>| {
                contacts.push(RefContact {
                    support: x,
                    z: zl,
                    slope: false,
                    prescribed: axis(zl),
                    stiffness: sup.stiffness,
                })
            };
            match sup.kind {
                SupportKind::None => {}
                SupportKind::Pin => lateral(centre, &mut contacts),
                SupportKind::Clamp => {
                    lateral(centre, &mut contacts);
                    contacts.push(RefContact {
                        support: x,
                        z: centre,
                        slope: true,
                        prescribed: sup.tilt,
                        stiffness: 0.0,
                    });
                }
                SupportKind::TwoEdgeGuide => {
                    lateral(centre + sup.length / 2.0, &mut contacts);
                    lateral(centre - sup.length / 2.0, &mut contacts);
                }
            }
        }
        let load_point =
            if spec.supports[1].kind == SupportKind::None { length } else { centres[1] };
        for c in &contacts {
            nodes.push(c.z);
        }
        nodes.push(load_point);
        // Extra equally spaced nodes inside each section, skipped where they would come closer
        // than 1 % of L to a node that must be there: very short elements (EJ/h³) ruin the
        // conditioning of the FE matrix, not its exactness.
        let essential = nodes.clone();
        for &(a, b, _) in &sections {
            for k in 1..=extra {
                let z = a + (b - a) * k as f64 / (extra + 1) as f64;
                if essential.iter().all(|&e| (e - z).abs() > 0.01 * length) {
                    nodes.push(z);
                }
            }
        }
        nodes.sort_by(|a, b| a.partial_cmp(b).unwrap());
        nodes.dedup_by(|a, b| (*a - *b).abs() < 1e-12);

        let nn = nodes.len();
        let ndof = 2 * nn;
        let rigid: Vec<usize> = (0..contacts.len())
            .filter(|&i| contacts[i].slope || contacts[i].stiffness == 0.0)
            .collect();
        let nsys = ndof + rigid.len();
        let mut k = vec![vec![Dd::ZERO; nsys]; nsys];
        let mut ej_max: f64 = 0.0;
        for e in 0..nn - 1 {
            let (a, b) = (nodes[e], nodes[e + 1]);
            let mid = 0.5 * (a + b);
            let ej =
                sections.iter().find(|&&(s0, s1, _)| mid >= s0 && mid <= s1).map(|t| t.2).unwrap();
            ej_max = ej_max.max(ej);
            // Element length and stiffness in double-double (h from the exact difference).
            let h = Dd::new(b) - Dd::new(a);
            let c = Dd::new(ej) / (h * h * h);
            let n = |x: f64| Dd::new(x);
            let h2 = h * h;
            let ke = [
                [n(12.0), n(6.0) * h, n(-12.0), n(6.0) * h],
                [n(6.0) * h, n(4.0) * h2, n(-6.0) * h, n(2.0) * h2],
                [n(-12.0), n(-6.0) * h, n(12.0), n(-6.0) * h],
                [n(6.0) * h, n(2.0) * h2, n(-6.0) * h, n(4.0) * h2],
            ];
            let dofs = [2 * e, 2 * e + 1, 2 * e + 2, 2 * e + 3];
            for i in 0..4 {
                for j in 0..4 {
                    k[dofs[i]][dofs[j]] = k[dofs[i]][dofs[j]] + c * ke[i][j];
                }
            }
        }
        for c in &contacts {
            if !c.slope && c.stiffness > 0.0 {
                let d = 2 * node_index(&nodes, c.z);
                k[d][d] = k[d][d] + Dd::new(c.stiffness);
            }
        }
        let multiplier_scale = ej_max / length.powi(3);
        for (row, &ci) in rigid.iter().enumerate() {
            let c = &contacts[ci];
            let d = 2 * node_index(&nodes, c.z) + usize::from(c.slope);
            k[ndof + row][d] = Dd::new(multiplier_scale);
            k[d][ndof + row] = Dd::new(multiplier_scale);
        }
        let lu = DdLu::new(k);
        RefModel {
            nodes,
            contacts,
            lu,
            ndof,
            multiplier_scale,
            load_point,
            length,
            centres,
            lateral_load: spec.lateral_load,
        }
    }

    /// Reactions for side load q (plus the lateral load) at the load point and clamp loads
    /// (m0, v) at z = L.
    pub fn reactions(&self, q: f64, m0: f64, v: f64) -> [RefReaction; 3] {
        let rigid: Vec<usize> = (0..self.contacts.len())
            .filter(|&i| self.contacts[i].slope || self.contacts[i].stiffness == 0.0)
            .collect();
        let nsys = self.ndof + rigid.len();
        let mut f = vec![Dd::ZERO; nsys];
        let ql = 2 * node_index(&self.nodes, self.load_point);
        f[ql] = f[ql] + Dd::new(q) + Dd::new(self.lateral_load);
        let end = 2 * node_index(&self.nodes, self.length);
        f[end] = f[end] + Dd::new(v);
        f[end + 1] = f[end + 1] + Dd::new(m0);
        for c in &self.contacts {
            if !c.slope && c.stiffness > 0.0 {
                let d = 2 * node_index(&self.nodes, c.z);
                f[d] = f[d] + Dd::new(c.stiffness) * Dd::new(c.prescribed);
            }
        }
        for (row, &ci) in rigid.iter().enumerate() {
            f[self.ndof + row] =
                Dd::new(self.multiplier_scale) * Dd::new(self.contacts[ci].prescribed);
        }
        let y = self.lu.solve(&f);
        let mut out = [RefReaction::default(); 3];
        for x in 0..3 {
            out[x].centre = self.centres[x];
        }
        let mut row = 0;
        for c in &self.contacts {
            let force = if c.slope || c.stiffness == 0.0 {
                // K y + Cᵀ μ = f: the constraint acts on the link with −Cᵀμ.
                let r = -(y[self.ndof + row] * Dd::new(self.multiplier_scale)).to_f64();
                row += 1;
                r
            } else {
                let w = y[2 * node_index(&self.nodes, c.z)];
                (Dd::new(c.stiffness) * (Dd::new(c.prescribed) - w)).to_f64()
            };
            let o = &mut out[c.support];
            if c.slope {
                o.m += force;
            } else {
                o.r += force;
                o.m += force * (c.z - self.centres[c.support]);
            }
        }
        out
    }
}
