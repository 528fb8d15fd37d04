//! Exact kinematics of beam pumping units (mechanisms 2 and 3), docs/model.md §3.2, in API 11E
//! notation, returning the stroke coordinate of docs/model.md §2 and its exact derivatives.
//!
//! # Frame and unknowns (docs/model.md §3.2)
//!
//! Origin at the crankshaft, x toward the well, y up. Crank pin `Cp = R(sin q, cos q)` with
//! `q = rotation·θ` (q measured clockwise from 12 o'clock, the unit seen with the well on the
//! right). Centre bearing `B = (I, H−G)` for class I and `B = (−I, H−G)` for class III; equalizer
//! `E = B + σ·C·u(b)` with `u(b) = (cos b, sin b)`, `σ = −1` for class I (equalizer behind the
//! centre bearing) and `σ = +1` for class III (equalizer between the bearing and the horsehead).
//! b is the beam angle, b > 0 with the horsehead up. The horsehead is an arc of radius A about the
//! centre bearing, so the polished rod moves exactly `A·b` and `s = A(b − b_min)`.
//!
//! # Closed-form position
//!
//! With `D = B − Cp` (ρ = |D|) the loop closure `|E − Cp| = P` reads
//! `ρ² + C² + 2σC·D·u = P²`, i.e. `cos α = D·u/ρ = σ(P² − ρ² − C²)/(2Cρ)`, where α is the angle
//! from D to the beam direction u. The two assemblies are `u = rot(±α)·D/ρ`; which sign is the
//! physical one (`kappa`) is decided once, in [`BeamUnit::new`], and never re-decided per call, so
//! the whole revolution stays on one branch. The branch cannot switch inside a revolution: for a
//! crank-rocker `|cos α| < 1` strictly at every crank angle (see the validation below).
//!
//! # Analytic derivatives
//!
//! With `W = E − Cp` (the pitman, from crank pin to equalizer), implicit differentiation of
//! `W·W = P²` with respect to q gives
//! `b_q = (W·Cp_q)/(W·E_b)` and
//! `b_qq = −(|V|² + (W·E_bb)·b_q² + W·Cp)/(W·E_b)` with `V = dW/dq = E_b·b_q − Cp_q`,
//! `E_b = σC·u⊥`, `E_bb = −σC·u`, `Cp_q = R(cos q, −sin q)`, `Cp_qq = −Cp`.
//! `W·E_b = 0` only at a toggle of the rocker, which a crank-rocker never reaches; on the
//! solution `W·E_b = σC·(D·u⊥) = −σ·kappa·sqrt(4C²ρ² − cnum²)/2` exactly, which shares its
//! reciprocal with the normalisation of u (one division per call). Then
//! `TF = A·rotation·b_q`, `TF' = A·b_qq` (rotation² = 1). No finite differences (docs/model.md §2).

use crate::model::error::{given, num, ModelError};
use crate::model::kinematics::{Kinematics, Scalar};

/// Lever class of the beam unit (docs/model.md §1, mechanism kinds 2 and 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BeamClass {
    /// API class I, conventional (`mechanism` = 2): the centre bearing lies between the equalizer
    /// and the horsehead. Bottom of stroke at the *extended* dead position (|E − O| = P + R).
    Conventional,
    /// Class III, Mark II / air balanced (`mechanism` = 3): the centre bearing is at the rear and
    /// the equalizer lies between it and the horsehead. Bottom of stroke at the *folded* dead
    /// position (|E − O| = P − R).
    ///
    /// Direction of rotation: with the equalizer shifted forward of the crankshaft toward the
    /// horsehead (the Mark II layout, C > I), `rotation = -1` (counter-clockwise, API 11E view with
    /// the well on the right) is the one that makes the upstroke last more than 180° of crank
    /// rotation (test `class3_upstroke_longer_than_180_for_ccw`); `rotation = +1` gives the
    /// mirror image (upstroke shorter than 180°).
    Class3,
}

/// Geometry of a beam unit in API 11E notation (docs/model.md §3.2). All lengths in m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamUnitGeometry {
    /// Lever class (mechanism 2 or 3).
    pub class: BeamClass,
    /// +1 clockwise, −1 counter-clockwise (API 11E view, well on the right); `rotation`.
    pub rotation: f64,
    /// A, centre bearing to horsehead arc (`geometry.beam_front_arm`).
    pub front_arm: f64,
    /// C, centre bearing to equalizer bearing (`geometry.beam_rear_arm`).
    pub rear_arm: f64,
    /// I, horizontal distance crankshaft → centre bearing (`geometry.pivot_dx`).
    pub pivot_dx: f64,
    /// H − G, vertical distance crankshaft → centre bearing (`geometry.pivot_dy`).
    pub pivot_dy: f64,
    /// P, pitman length (`geometry.rod_length`).
    pub pitman: f64,
    /// R, crank radius (`geometry.crank_radius`).
    pub crank: f64,
}

/// A validated beam unit with the constants that make [`BeamUnit::kinematics`] cheap
/// (one `sin_cos`, one `sqrt`, two `asin`, one division; no allocation, no iteration).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamUnit {
    /// A [m].
    a: f64,
    /// R [m].
    r: f64,
    /// σ·C [m]: E = B + σC·u.
    sc: f64,
    /// −2σ·kappa: `1/(W·E_b) = −2σκ/sd` (module docs).
    neg_two_sk: f64,
    /// 1/P² [1/m²].
    inv_p2: f64,
    /// 1/P [1/m].
    inv_p: f64,
    /// P/2 [m].
    half_p: f64,
    /// Loop constants.
    lp: Loop,
    /// rotation (±1).
    rot: f64,
    /// Assembly branch (±1), fixed at construction.
    kappa: f64,
    /// Beam angle at the bottom dead position [rad].
    b_min: f64,
    /// Polished-rod stroke A(b_max − b_min) [m].
    stroke: f64,
}

/// Requires a finite, strictly positive length; the error names the contract variable.
fn positive_length(variable: &'static str, value: f64) -> Result<f64, ModelError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ModelError::out_of_range(variable, value, "a finite length > 0 m"))
    }
}

/// The loop constants needed to solve `|E − Cp| = P` for the beam direction (docs/model.md §3.2).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Loop {
    /// Centre bearing B [m].
    bx: f64,
    by: f64,
    /// σ = −1 (class I) or +1 (class III).
    sigma: f64,
    /// C² [m²].
    c2: f64,
    /// 4C² [m²].
    four_c2: f64,
    /// 2C [m].
    two_c: f64,
    /// P² [m²].
    p2: f64,
}

impl Loop {
    /// Unit beam direction u on assembly branch `kappa` for crank pin `(px, py)`, and
    /// `1/sqrt(4C²ρ² − cnum²)` (= 1/(2Cρ·sin α)).
    ///
    /// `u = cos α·D/ρ + kappa·sin α·D⊥/ρ` with `cos α = cnum/(2Cρ)`, written as
    /// `(cnum·D + kappa·sd·D⊥)/(2Cρ²)`, `sd = sqrt(4C²ρ² − cnum²)`: one square root, and one
    /// division shared by both reciprocals.
    #[inline(always)]
    fn solve<T: Scalar>(&self, kappa: f64, px: T, py: T) -> (T, T, T) {
        let dx = T::from(self.bx) - px;
        let dy = T::from(self.by) - py;
        let rho2 = dx * dx + dy * dy;
        let cnum = (T::from(self.p2) - rho2 - self.c2) * self.sigma;
        // > 0 on a validated crank-rocker (|cos α| < 1); max() only guards the last ulp.
        let sd = (rho2 * self.four_c2 - cnum * cnum).at_least_zero().sqrt();
        let two_c_rho2 = rho2 * self.two_c;
        let t = (two_c_rho2 * sd).recip();
        let scale = t * sd;
        (
            (cnum * dx - sd * kappa * dy) * scale,
            (cnum * dy + sd * kappa * dx) * scale,
            t * two_c_rho2,
        )
    }
}

impl BeamUnit {
    /// Validates the geometry and precomputes the constants (docs/model.md §3.2).
    ///
    /// Checks, in this order, each with an error naming the contract variables and values:
    /// 1. every length finite and > 0 (`ModelError::OutOfRange`);
    /// 2. `rotation` exactly +1 or −1 (`ModelError::OutOfRange`);
    /// 3. the loop closes at some crank angle at all, i.e. the ranges `[K − R, K + R]` of |B − Cp|
    ///    and `[|C − P|, C + P]` overlap (`ModelError::Invalid`);
    /// 4. R is strictly the shortest of the four-bar links (R, P, C, K) (`Invalid`);
    /// 5. Grashof, strict: `R + longest < sum of the other two` (`Invalid`).
    ///
    /// Why 4 + 5: the FMU is driven by a fully rotating crank, so the four-bar must be a
    /// crank-rocker (docs/model.md §3.2). Together they are equivalent to
    /// `|C − P| < K − R` and `K + R < C + P`, i.e. the loop closes at every crank angle with a
    /// non-degenerate triangle (B, E, Cp); that is re-checked last as a guard (6).
    ///
    /// The physical assembly (docs/model.md §3.2: beam near horizontal, horsehead toward the well)
    /// is fixed here. Its dead positions are closed form (crank and pitman collinear,
    /// `|E − O| = d`, `d = P ± R`): with `ψ(d) = acos((C² + K² − d²)/(2CK))` and
    /// `β0 = atan2(H−G, I)`,
    /// * class I:  `b = β0 − ψ(d)`: bottom at `d = P + R` (extended), top at `d = P − R`;
    /// * class III: `b = ψ(d) − β0`: bottom at `d = P − R` (folded), top at `d = P + R`.
    ///
    /// (The other root, `β0 + ψ` resp. `−β0 − ψ`, points the horsehead away from the well.) So
    /// `b_min` is exact and the stroke is `A·(ψ(P+R) − ψ(P−R))` for both classes. The running
    /// branch `kappa` is the one that reproduces `b_min` at the bottom dead crank angle.
    pub fn new(g: &BeamUnitGeometry) -> Result<BeamUnit, ModelError> {
        let a = positive_length("geometry.beam_front_arm", g.front_arm)?;
        let c = positive_length("geometry.beam_rear_arm", g.rear_arm)?;
        let i = positive_length("geometry.pivot_dx", g.pivot_dx)?;
        let hg = positive_length("geometry.pivot_dy", g.pivot_dy)?;
        let p = positive_length("geometry.rod_length", g.pitman)?;
        let r = positive_length("geometry.crank_radius", g.crank)?;
        let rot = g.rotation;
        if !(rot == 1.0 || rot == -1.0) {
            return Err(ModelError::out_of_range(
                "rotation",
                rot,
                "+1 (clockwise) or -1 (counter-clockwise), API 11E view with the well on the right",
            ));
        }
        let k = i.hypot(hg);
        // Parameters as given, computed lengths to 6 digits (docs/hardening.md "Messages").
        let links = format!(
            "geometry.crank_radius R = {} m, geometry.rod_length P = {} m, \
             geometry.beam_rear_arm C = {} m, K = sqrt(geometry.pivot_dx² + geometry.pivot_dy²) \
             = sqrt({}² + {}²) = {} m",
            given(r),
            given(p),
            given(c),
            given(i),
            given(hg),
            num(k)
        );
        // 3. Closes nowhere: the crank-pin-to-bearing distance range misses the pitman/arm range.
        if k - r >= c + p || k + r <= (c - p).abs() {
            return Err(ModelError::invalid(format!(
                "beam unit does not assemble at any crank angle (the loop |E − Cp| = P never \
                 closes): need K − R < C + P and K + R > |C − P|; {links}"
            )));
        }
        // 4. R strictly the shortest link.
        let shortest_other = p.min(c).min(k);
        if r >= shortest_other {
            return Err(ModelError::invalid(format!(
                "beam unit is not a crank-rocker: the crank radius must be the shortest link of \
                 the four-bar (R, P, C, K), but R = {} m >= {} m; {links}",
                given(r),
                num(shortest_other)
            )));
        }
        // 5. Grashof (strict) with R shortest.
        let longest = p.max(c).max(k);
        let others = p + c + k - longest;
        if r + longest >= others {
            return Err(ModelError::invalid(format!(
                "beam unit is not a crank-rocker (Grashof condition violated): need R + longest \
                 < sum of the other two links, but {} + {} = {} >= {} m; {links}",
                given(r),
                num(longest),
                num(r + longest),
                num(others)
            )));
        }
        // 6. Guard (implied by 4 + 5): the loop closes at every crank angle.
        if !(k - r > (c - p).abs() && k + r < c + p) {
            return Err(ModelError::invalid(format!(
                "beam unit loop does not close over the whole revolution: need K − R > |C − P| \
                 and K + R < C + P; {links}"
            )));
        }

        let (sigma, bx) = match g.class {
            BeamClass::Conventional => (-1.0, i),
            BeamClass::Class3 => (1.0, -i),
        };
        let by = hg;
        let beta0 = hg.atan2(i);
        let psi = |d: f64| ((c * c + k * k - d * d) / (2.0 * c * k)).clamp(-1.0, 1.0).acos();
        let (psi_ext, psi_fold) = (psi(p + r), psi(p - r));
        let b_min = match g.class {
            BeamClass::Conventional => beta0 - psi_ext,
            BeamClass::Class3 => psi_fold - beta0,
        };
        let stroke = a * (psi_ext - psi_fold);

        // Bottom dead crank angle: extended (class I, Cp along E) or folded (class III, Cp
        // opposite to E).
        let (ex, ey) = (bx + sigma * c * b_min.cos(), by + sigma * c * b_min.sin());
        let q_bottom = match g.class {
            BeamClass::Conventional => ex.atan2(ey),
            BeamClass::Class3 => (-ex).atan2(-ey),
        };
        let (sq, cq) = q_bottom.sin_cos();
        let (px, py) = (r * sq, r * cq);
        let lp = Loop { bx, by, sigma, c2: c * c, four_c2: 4.0 * c * c, two_c: 2.0 * c, p2: p * p };
        let branch_error = |kappa: f64| {
            let (ux, uy, _) = lp.solve(kappa, px, py);
            (uy.atan2(ux) - b_min).abs()
        };
        let (err_minus, err_plus) = (branch_error(-1.0), branch_error(1.0));
        let (kappa, err) = if err_minus <= err_plus { (-1.0, err_minus) } else { (1.0, err_plus) };
        // Guard: the two branches differ by 2α, bounded away from 0 on a crank-rocker, so a
        // mismatch here means a geometry too close to degenerate to be trusted.
        if err.is_nan() || err > 1e-6 {
            return Err(ModelError::invalid(format!(
                "beam unit geometry is too close to a degenerate four-bar to fix the assembly \
                 branch (mismatch {} rad at the bottom dead position); {links}",
                num(err)
            )));
        }

        Ok(BeamUnit {
            a,
            r,
            sc: sigma * c,
            neg_two_sk: -2.0 * sigma * kappa,
            inv_p2: 1.0 / (p * p),
            inv_p: 1.0 / p,
            half_p: 0.5 * p,
            lp,
            rot,
            kappa,
            b_min,
            stroke,
        })
    }

    /// Exact kinematics at model crank angle θ (API 11E: θ = 0 crank at 12 o'clock,
    /// `q = rotation·θ`; docs/model.md §2, §3.2).
    ///
    /// * `s = A(b − b_min) ≥ 0`, 0 at the bottom of stroke, growing upward (docs/model.md §2);
    /// * `tf = ds/dθ`, `tfp = d²s/dθ²` from the analytic implicit derivatives (module docs);
    /// * `rod_angle`: the pitman's inclination from the vertical, positive when its crank-pin end
    ///   is nearer the well (larger x) than its equalizer end: `atan2(Cp_x − E_x, E_y − Cp_y)`;
    /// * `rod_angle_rate = d(rod_angle)/dθ = rotation·(W × V)/P²`.
    #[inline]
    pub fn kinematics(&self, theta: f64) -> Kinematics {
        self.kinematics_of(theta)
    }

    /// [`BeamUnit::kinematics`] for any [`Scalar`]: with a dual number it also gives the exact
    /// derivatives of every field (the directional derivatives); with `f64` it is the same
    /// arithmetic in the same order.
    #[inline(always)]
    pub fn kinematics_of<T: Scalar>(&self, theta: T) -> Kinematics<T> {
        let q = theta * self.rot;
        let (sq, cq) = q.sin_cos();
        let (px, py) = (sq * self.r, cq * self.r);
        let (ux, uy, inv_sd) = self.lp.solve(self.kappa, px, py);
        // |u| = 1 (to rounding), so b = asin(u_y) while the beam is within 60° of horizontal
        // (always, for a real unit): well conditioned there and about twice as fast as atan2.
        let b = if ux.re() > 0.5 { uy.asin() } else { uy.atan2(ux) };
        // Pitman W = E − Cp.
        let wx = ux * self.sc + self.lp.bx - px;
        let wy = uy * self.sc + self.lp.by - py;
        // dE/db = σC·u⊥ ; dCp/dq = R(cos q, −sin q) = (py, −px).
        let (ebx, eby) = (uy * -self.sc, ux * self.sc);
        let (cqx, cqy) = (py, -px);
        // W·E_b = σC·(D·u⊥) = −σκ·sd/2 exactly (u from `Loop::solve`): no extra division.
        let inv_den = inv_sd * self.neg_two_sk;
        let bq = (wx * cqx + wy * cqy) * inv_den;
        let (vx, vy) = (ebx * bq - cqx, eby * bq - cqy);
        let w_dot_u = wx * ux + wy * uy;
        // W·E_bb = −σC (W·u);  −W·Cp_qq = +W·Cp.
        let bqq =
            -((vx * vx + vy * vy - w_dot_u * self.sc * bq * bq + wx * px + wy * py) * inv_den);
        // Clamp only the last-ulp undershoot at the bottom dead position (s ≥ 0, §2).
        Kinematics {
            s: ((b - self.b_min) * self.a).at_least_zero(),
            tf: bq * (self.a * self.rot),
            tfp: bqq * self.a,
            // Same fast path: |W| = P, and the pitman points up within 60° of the vertical.
            rod_angle: if wy.re() > self.half_p {
                (-(wx * self.inv_p)).asin()
            } else {
                (-wx).atan2(wy)
            },
            rod_angle_rate: (wx * vy - wy * vx) * self.rot * self.inv_p2,
        }
    }

    /// Polished-rod stroke `A·(ψ(P+R) − ψ(P−R))` in m (docs/model.md §3.2), exact.
    pub fn stroke(&self) -> f64 {
        self.stroke
    }
}

#[cfg(test)]
mod tests {
    //! Every test compares against something computed independently of `BeamUnit`'s formulas:
    //! a second formulation of the loop solved by bisection (`Indep`), circle intersections for
    //! the dead positions, the statics identity, the closed-form stroke, or the seed paper's
    //! printed numbers (docs/model.md §3.2).
    use super::*;
    use std::f64::consts::PI;

    const TAU: f64 = 2.0 * PI;

    /// Seed 001, SK8-3.5-4000 (docs/model.md §3.2, §8 preset `sk8-3.5-4000`).
    fn sk8(rotation: f64) -> BeamUnitGeometry {
        BeamUnitGeometry {
            class: BeamClass::Conventional,
            rotation,
            front_arm: 3.5,
            rear_arm: 2.5,
            pivot_dx: 2.195,
            pivot_dy: 3.0,
            pitman: 3.0,
            crank: 1.01,
        }
    }

    /// A plausible Mark II-like class III geometry (assumed, not catalogue data): equalizer
    /// shifted forward of the crankshaft (C − I = 1.0 m), stroke ≈ 3.06 m (≈ 120 in).
    /// K = sqrt(1.4² + 3.2²) = 3.493 m; R = 0.9 shortest; 0.9 + 3.493 < 3.4 + 2.4 (Grashof).
    fn mark2(rotation: f64) -> BeamUnitGeometry {
        BeamUnitGeometry {
            class: BeamClass::Class3,
            rotation,
            front_arm: 3.8,
            rear_arm: 2.4,
            pivot_dx: 1.4,
            pivot_dy: 3.2,
            pitman: 3.4,
            crank: 0.9,
        }
    }

    fn all_configs() -> [BeamUnitGeometry; 4] {
        [sk8(-1.0), sk8(1.0), mark2(-1.0), mark2(1.0)]
    }

    fn unit(g: &BeamUnitGeometry) -> BeamUnit {
        match BeamUnit::new(g) {
            Ok(u) => u,
            Err(e) => panic!("valid test geometry rejected: {e}"),
        }
    }

    /// Independent second formulation: positions written directly from docs/model.md §3.2 and the
    /// loop residual `F(b) = |E(b) − Cp|² − P²` solved by bisection on a bracket around a guess
    /// (continuation), never using the closed form or `kappa`.
    struct Indep {
        g: BeamUnitGeometry,
    }

    impl Indep {
        fn bearing(&self) -> (f64, f64) {
            match self.g.class {
                BeamClass::Conventional => (self.g.pivot_dx, self.g.pivot_dy),
                BeamClass::Class3 => (-self.g.pivot_dx, self.g.pivot_dy),
            }
        }
        fn equalizer(&self, b: f64) -> (f64, f64) {
            let (bx, by) = self.bearing();
            let c = self.g.rear_arm;
            match self.g.class {
                BeamClass::Conventional => (bx - c * b.cos(), by - c * b.sin()),
                BeamClass::Class3 => (bx + c * b.cos(), by + c * b.sin()),
            }
        }
        fn pin(&self, theta: f64) -> (f64, f64) {
            let q = self.g.rotation * theta;
            (self.g.crank * q.sin(), self.g.crank * q.cos())
        }
        fn residual(&self, theta: f64, b: f64) -> f64 {
            let (ex, ey) = self.equalizer(b);
            let (px, py) = self.pin(theta);
            (ex - px).hypot(ey - py) - self.g.pitman
        }
        fn bisect(&self, theta: f64, mut lo: f64, mut hi: f64) -> f64 {
            let mut flo = self.residual(theta, lo);
            assert!(flo * self.residual(theta, hi) <= 0.0, "bracket lost at θ = {theta}");
            loop {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                let fm = self.residual(theta, mid);
                if fm == 0.0 {
                    return mid;
                }
                if (fm < 0.0) == (flo < 0.0) {
                    lo = mid;
                    flo = fm;
                } else {
                    hi = mid;
                }
            }
            if self.residual(theta, lo).abs() <= self.residual(theta, hi).abs() {
                lo
            } else {
                hi
            }
        }
        /// Root within ±0.1 rad of `guess` (the two assemblies are > 1 rad apart here).
        fn solve_near(&self, theta: f64, guess: f64) -> f64 {
            self.bisect(theta, guess - 0.1, guess + 0.1)
        }
        /// No guess: scan b ∈ (−π/2, π/2) and keep the root with the beam most horizontal.
        fn solve_fresh(&self, theta: f64) -> f64 {
            let n = 3000;
            let mut best: Option<f64> = None;
            for j in 0..n {
                let lo = -1.5 + 3.0 * j as f64 / n as f64;
                let hi = -1.5 + 3.0 * (j + 1) as f64 / n as f64;
                if self.residual(theta, lo) * self.residual(theta, hi) <= 0.0 {
                    let b = self.bisect(theta, lo, hi);
                    if best.is_none() || best.is_some_and(|x: f64| b.abs() < x.abs()) {
                        best = Some(b);
                    }
                }
            }
            best.expect("no assembly found")
        }
        /// Beam angles at `n` equally spaced θ over a revolution, by continuation.
        fn revolution(&self, n: usize) -> Vec<(f64, f64)> {
            let mut out = Vec::with_capacity(n);
            let mut b = self.solve_fresh(0.0);
            for j in 0..n {
                let th = TAU * j as f64 / n as f64;
                b = self.solve_near(th, b);
                out.push((th, b));
            }
            out
        }
        /// Pitman inclination from the vertical, + when the crank-pin end is nearer the well.
        fn rod_angle(&self, theta: f64, b: f64) -> f64 {
            let (ex, ey) = self.equalizer(b);
            let (px, py) = self.pin(theta);
            (px - ex).atan2(ey - py)
        }
    }

    /// Richardson-extrapolated central differences (error O(h⁶) after two levels):
    /// returns (f', f'') at x with base step h0 and steps h0, h0/2, h0/4.
    fn richardson(f: &dyn Fn(f64) -> f64, x: f64, h0: f64) -> (f64, f64) {
        let f0 = f(x);
        let d = |h: f64| {
            let (fp, fm) = (f(x + h), f(x - h));
            ((fp - fm) / (2.0 * h), (fp - 2.0 * f0 + fm) / (h * h))
        };
        let (a, b, c) = (d(h0), d(h0 / 2.0), d(h0 / 4.0));
        let extrap = |x0: f64, x1: f64, x2: f64| {
            let (y0, y1) = ((4.0 * x1 - x0) / 3.0, (4.0 * x2 - x1) / 3.0);
            (16.0 * y1 - y0) / 15.0
        };
        (extrap(a.0, b.0, c.0), extrap(a.1, b.1, c.1))
    }

    fn round_to(x: f64, digits: i32) -> f64 {
        let m = 10f64.powi(digits);
        (x * m).round() / m
    }

    /// Crank angles θ ∈ [0, 2π) where TF = 0, by sign-change bracketing on 720 samples and
    /// bisection to ~1e-15 rad.
    fn tf_roots(u: &BeamUnit) -> Vec<f64> {
        let n = 720;
        let mut roots = Vec::new();
        for j in 0..n {
            let (mut lo, mut hi) = (TAU * j as f64 / n as f64, TAU * (j + 1) as f64 / n as f64);
            let (mut flo, fhi) = (u.kinematics(lo).tf, u.kinematics(hi).tf);
            if flo == 0.0 {
                roots.push(lo);
                continue;
            }
            if flo * fhi > 0.0 || fhi == 0.0 {
                continue;
            }
            while hi - lo > 1e-15 {
                let mid = 0.5 * (lo + hi);
                let fm = u.kinematics(mid).tf;
                if (fm < 0.0) == (flo < 0.0) {
                    lo = mid;
                    flo = fm;
                } else {
                    hi = mid;
                }
            }
            roots.push(0.5 * (lo + hi));
        }
        roots
    }

    /// Golden-section search for the maximum of `f` on [lo, hi] (unimodal there).
    fn golden_max(f: &dyn Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> (f64, f64) {
        let g = (5f64.sqrt() - 1.0) / 2.0;
        for _ in 0..200 {
            let (x1, x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
            if f(x1) < f(x2) {
                lo = x1;
            } else {
                hi = x2;
            }
        }
        let x = 0.5 * (lo + hi);
        (x, f(x))
    }

    // ---- 1. Seed 001 -------------------------------------------------------------------------

    /// Seed 001 (docs/model.md §3.2, §9): a = TF'·ω² (ε = 0) at φ1 = 37.51° and 192.51°, with
    /// φ1 = θ + 90° − atan2(H−G, I), rotation −1, must round to the paper's printed 2.72 and
    /// −1.4909 m/s², for both the exact ω = 2π·10.9/60 and the paper's rounded 1.141445.
    /// Sign: docs/model.md §2 says a > 0 at the bottom in steady rotation; the paper's 37.51° is the
    /// bottom dead position (s = 0, TF = 0) and its a = +2.72 > 0, so the paper's sign agrees.
    #[test]
    fn seed001_accelerations() {
        let u = unit(&sk8(-1.0));
        let offset = 90f64.to_radians() - 3.0f64.atan2(2.195);
        assert!((offset.to_degrees() - 36.1917).abs() < 5e-5);
        for omega in [TAU * 10.9 / 60.0, 1.141445] {
            let a1 = u.kinematics(37.51f64.to_radians() - offset).acceleration(omega, 0.0);
            let a2 = u.kinematics(192.51f64.to_radians() - offset).acceleration(omega, 0.0);
            assert_eq!(round_to(a1, 2), 2.72, "a(37.51°) = {a1}");
            assert_eq!(round_to(a2, 4), -1.4909, "a(192.51°) = {a2}");
        }
        // 37.51° is the bottom dead position (to the printed digits), and a > 0 there (§2).
        let bottom = tf_roots(&u)
            .into_iter()
            .min_by(|x, y| u.kinematics(*x).s.total_cmp(&u.kinematics(*y).s))
            .expect("dead positions");
        let k = u.kinematics(bottom);
        assert!(k.s < 1e-12 && k.tfp > 0.0);
        assert_eq!(round_to((bottom + offset).to_degrees(), 2), 37.51);
    }

    /// docs/model.md §9: 37.51° is not the maximum and 192.51° is not the minimum of a. The true
    /// extremes (ε = 0) are located by golden-section search on the analytic TF' and printed.
    #[test]
    fn seed001_true_acceleration_extremes() {
        let u = unit(&sk8(-1.0));
        let omega = TAU * 10.9 / 60.0;
        let offset = 90f64.to_radians() - 3.0f64.atan2(2.195);
        let a = |th: f64| u.kinematics(th).acceleration(omega, 0.0);
        let n = 3600;
        let (mut imax, mut imin) = (0, 0);
        for j in 0..n {
            let th = TAU * j as f64 / n as f64;
            if a(th) > a(TAU * imax as f64 / n as f64) {
                imax = j;
            }
            if a(th) < a(TAU * imin as f64 / n as f64) {
                imin = j;
            }
        }
        let step = TAU / n as f64;
        let c = TAU * imax as f64 / n as f64;
        let (th_max, a_max) = golden_max(&a, c - step, c + step);
        let c = TAU * imin as f64 / n as f64;
        let (th_min, neg_min) = golden_max(&|t| -a(t), c - step, c + step);
        let a_min = -neg_min;
        let deg = |t: f64| t.to_degrees().rem_euclid(360.0);
        println!(
            "SK8 a_max = {a_max:.6} m/s² at θ = {:.3}°, φ1 = {:.3}°; a_min = {a_min:.6} m/s² at \
             θ = {:.3}°, φ1 = {:.3}°",
            deg(th_max),
            deg(th_max + offset),
            deg(th_min),
            deg(th_min + offset)
        );
        let a_paper_max = a(37.51f64.to_radians() - offset);
        let a_paper_min = a(192.51f64.to_radians() - offset);
        assert!(a_max > a_paper_max + 0.1, "{a_max} vs {a_paper_max}");
        assert!(a_min < a_paper_min - 1e-3, "{a_min} vs {a_paper_min}");
        // Extremes are where d(TF')/dθ = 0: check by Richardson derivative of TF'.
        for th in [th_max, th_min] {
            let (d, _) = richardson(&|t| u.kinematics(t).tfp, th, 0.02);
            assert!(d.abs() < 1e-6, "dTF'/dθ = {d} at an extreme");
        }
    }

    // ---- 2. Stroke -----------------------------------------------------------------------------

    /// The closed-form stroke S = A·|ψ(P+R) − ψ(P−R)| (docs/model.md §3.2), written here from the
    /// formula, against max s over the revolution at the roots of TF (bracketing + bisection),
    /// and against `stroke()`. Also the minimum of s is 0 (docs/model.md §2). The same formula holds
    /// for class III (its dead positions are ψ(d) − β0), checked too.
    /// Tolerance 1e-12 m: s is flat (quadratic) at the extremes, so a root error of 1e-15 rad
    /// costs nothing; what remains is rounding of A·b (≈ 1e-15 m).
    #[test]
    fn stroke_closed_form() {
        for g in all_configs() {
            let u = unit(&g);
            let k = g.pivot_dx.hypot(g.pivot_dy);
            let (a, c, p, r) = (g.front_arm, g.rear_arm, g.pitman, g.crank);
            let psi = |d: f64| ((c * c + k * k - d * d) / (2.0 * c * k)).acos();
            let s_formula = a * (psi(p + r) - psi(p - r)).abs();
            let roots = tf_roots(&u);
            assert_eq!(roots.len(), 2, "{g:?}");
            let s: Vec<f64> = roots.iter().map(|t| u.kinematics(*t).s).collect();
            let (smax, smin) = (s[0].max(s[1]), s[0].min(s[1]));
            assert!((smax - s_formula).abs() < 1e-12, "{smax} vs {s_formula}");
            assert!((u.stroke() - s_formula).abs() < 1e-12);
            assert!(smin.abs() < 1e-12);
            // s ≥ 0 everywhere.
            for j in 0..3600 {
                assert!(u.kinematics(TAU * j as f64 / 3600.0).s >= 0.0);
            }
        }
        // SK8 stroke, for the record: 2.9128 m with R = 1.01 m.
        assert!((unit(&sk8(-1.0)).stroke() - 2.9127546).abs() < 1e-6);
    }

    // ---- 3. Dead positions ---------------------------------------------------------------------

    /// Dead positions computed independently as circle intersections |E − O| = P ± R,
    /// |E − B| = C (keeping the intersection with the horsehead toward the well, most horizontal),
    /// crank angle from the collinearity of crank and pitman. TF must vanish there (tolerance
    /// 1e-12 m/rad: TF ≈ TF'·δθ with δθ ~ 1e-15 rad from rounding), and s must be 0 at the lower
    /// one and the stroke at the upper one. Both classes, both rotations.
    #[test]
    fn tf_zero_at_dead_positions() {
        for g in all_configs() {
            let u = unit(&g);
            let ind = Indep { g };
            let (bx, by) = ind.bearing();
            let k = bx.hypot(by);
            let c = g.rear_arm;
            let mut ends = Vec::new();
            for (d, extended) in [(g.pitman + g.crank, true), (g.pitman - g.crank, false)] {
                let along = (d * d - c * c + k * k) / (2.0 * k);
                let h = (d * d - along * along).sqrt();
                let (ex0, ey0) = (along * bx / k, along * by / k);
                let (nx, ny) = (-by / k, bx / k);
                let cands = [(ex0 + h * nx, ey0 + h * ny), (ex0 - h * nx, ey0 - h * ny)];
                let beam = |e: (f64, f64)| match g.class {
                    BeamClass::Conventional => ((bx - e.0) / c, (by - e.1) / c),
                    BeamClass::Class3 => ((e.0 - bx) / c, (e.1 - by) / c),
                };
                let e = if beam(cands[0]).0 >= beam(cands[1]).0 { cands[0] } else { cands[1] };
                let (ux, uy) = beam(e);
                let q = if extended { e.0.atan2(e.1) } else { (-e.0).atan2(-e.1) };
                let theta = g.rotation * q;
                let kin = u.kinematics(theta);
                assert!(kin.tf.abs() < 1e-12, "TF = {} at dead position {g:?}", kin.tf);
                ends.push((uy.atan2(ux), kin.s));
            }
            let (lower, upper) =
                if ends[0].0 < ends[1].0 { (ends[0], ends[1]) } else { (ends[1], ends[0]) };
            assert!(lower.1.abs() < 1e-12, "s at bottom = {}", lower.1);
            assert!((upper.1 - u.stroke()).abs() < 1e-12);
            assert!(((upper.0 - lower.0) * g.front_arm - u.stroke()).abs() < 1e-12);
            // Bottom is extended for class I, folded for class III (BeamClass docs).
            let bottom_extended = ends[0].0 < ends[1].0;
            assert_eq!(bottom_extended, g.class == BeamClass::Conventional);
        }
    }

    // ---- 4. Statics identity -------------------------------------------------------------------

    /// |TF| = A·R·sin α/(C·sin β_p) (docs/model.md §3.2; virtual work through the pitman), with α
    /// (crank–pitman) and β_p (beam arm–pitman) from the independently solved positions, at 720
    /// angles for both classes and rotations. Tolerance 1e-11 m/rad: positions are accurate to
    /// ~1e-15 m, the angles' sines are ≥ 0.3 away from the dead positions and the ratio's
    /// condition number is O(10).
    #[test]
    fn statics_identity() {
        for g in all_configs() {
            let u = unit(&g);
            let ind = Indep { g };
            let (bx, by) = ind.bearing();
            for (th, b) in ind.revolution(720) {
                let (px, py) = ind.pin(th);
                let (ex, ey) = ind.equalizer(b);
                let (wx, wy) = (ex - px, ey - py);
                let sin_alpha = (px * wy - py * wx).abs() / (g.crank * wx.hypot(wy));
                let (ax, ay) = (ex - bx, ey - by);
                let sin_beta = (ax * wy - ay * wx).abs() / (g.rear_arm * wx.hypot(wy));
                let tf = g.front_arm * g.crank * sin_alpha / (g.rear_arm * sin_beta);
                let k = u.kinematics(th);
                assert!((k.tf.abs() - tf).abs() < 1e-11, "θ = {th}: {} vs {tf}", k.tf);
            }
        }
    }

    // ---- 5. TF and TF' against numerical derivatives of an independent position --------------

    /// s and a = TF·ε + TF'·ω²: TF, TF' against Richardson-extrapolated central differences
    /// (h = 0.02, 0.01, 0.005 rad; truncation O(h⁶) ≈ 1e-10·|s⁽⁸⁾|) of A·b from the independent
    /// bisection solver, whose b is accurate to ~1e-15 rad (residual rounding / |dF/db|).
    /// Rounding then bounds the error of TF by ~A·1e-15/h_min ≈ 1e-12 and of TF' by
    /// ~A·4e-15/h_min² ≈ 1e-9 (times ≈ 2 for the extrapolation). Tolerances: 1e-9 m/rad (TF),
    /// 2e-8 m/rad² (TF'), i.e. ≥ 10× the estimate. Also s differences against A·Δb (1e-13 m).
    /// 720 angles, both classes, both rotations.
    #[test]
    fn tf_and_tfp_against_numerical_derivatives() {
        let omega = 1.3;
        let eps = 0.4;
        for g in all_configs() {
            let u = unit(&g);
            let ind = Indep { g };
            let rev = ind.revolution(720);
            let (th0, b0) = rev[0];
            let s0 = u.kinematics(th0).s;
            let (mut e1, mut e2) = (0f64, 0f64);
            for &(th, b) in &rev {
                let f = |t: f64| g.front_arm * ind.solve_near(t, b);
                let (d1, d2) = richardson(&f, th, 0.02);
                let k = u.kinematics(th);
                e1 = e1.max((k.tf - d1).abs());
                e2 = e2.max((k.tfp - d2).abs());
                let a_num = d1 * eps + d2 * omega * omega;
                assert!((k.acceleration(omega, eps) - a_num).abs() < 1e-7);
                assert!(((k.s - s0) - g.front_arm * (b - b0)).abs() < 1e-13);
            }
            println!(
                "{:?} rot {}: max |ΔTF| = {e1:.2e}, max |ΔTF'| = {e2:.2e}",
                g.class, g.rotation
            );
            assert!(e1 < 1e-9, "TF error {e1}");
            assert!(e2 < 2e-8, "TF' error {e2}");
        }
    }

    // ---- 6. Mirror -----------------------------------------------------------------------------

    /// Counter-clockwise at θ is clockwise at −θ (q = rotation·θ, docs/model.md §3.2): s equal, TF
    /// opposite, TF' equal, rod angle equal, its rate opposite. The positions coincide exactly,
    /// so the tolerance is a few ulps.
    #[test]
    fn mirror_relation() {
        for (ccw, cw) in [(sk8(-1.0), sk8(1.0)), (mark2(-1.0), mark2(1.0))] {
            let (uc, uw) = (unit(&ccw), unit(&cw));
            for j in 0..720 {
                let th = TAU * j as f64 / 720.0 - PI;
                let (a, b) = (uc.kinematics(th), uw.kinematics(-th));
                assert!((a.s - b.s).abs() <= 1e-15);
                assert!((a.tf + b.tf).abs() <= 1e-15);
                assert!((a.tfp - b.tfp).abs() <= 1e-15);
                assert!((a.rod_angle - b.rod_angle).abs() <= 1e-15);
                assert!((a.rod_angle_rate + b.rod_angle_rate).abs() <= 1e-15);
            }
        }
    }

    // ---- 7. Class III time asymmetry ------------------------------------------------------------

    /// Mark II-like geometry (`mark2`): with `rotation = -1` (counter-clockwise, well on the
    /// right) the upstroke (bottom → top in the direction of rotation) takes more than 180° of
    /// crank rotation (≈ 189.5° here); with +1 it takes 360° minus that. Dead positions from the
    /// TF roots (bisection), bottom/top told apart by s.
    #[test]
    fn class3_upstroke_longer_than_180_for_ccw() {
        let upstroke = |rot: f64| {
            let u = unit(&mark2(rot));
            let r = tf_roots(&u);
            assert_eq!(r.len(), 2);
            let (bottom, top) = if u.kinematics(r[0]).s < u.kinematics(r[1]).s {
                (r[0], r[1])
            } else {
                (r[1], r[0])
            };
            (top - bottom).rem_euclid(TAU).to_degrees()
        };
        let (ccw, cw) = (upstroke(-1.0), upstroke(1.0));
        println!("Mark II-like upstroke: rotation -1: {ccw:.2}°, rotation +1: {cw:.2}°");
        assert!(ccw > 185.0, "{ccw}");
        assert!(cw < 175.0, "{cw}");
        assert!((ccw + cw - 360.0).abs() < 1e-9);
        // Between the dead positions s rises monotonically on the upstroke: TF > 0.
        let u = unit(&mark2(-1.0));
        let r = tf_roots(&u);
        let bottom = if u.kinematics(r[0]).s < u.kinematics(r[1]).s { r[0] } else { r[1] };
        for j in 1..100 {
            let th = bottom + (ccw.to_radians()) * j as f64 / 100.0;
            assert!(u.kinematics(th).tf > 0.0);
        }
    }

    // ---- 8. Invalid geometries ------------------------------------------------------------------

    fn err_text(g: &BeamUnitGeometry) -> (ModelError, String) {
        match BeamUnit::new(g) {
            Ok(_) => panic!("invalid geometry accepted: {g:?}"),
            Err(e) => {
                let t = e.to_string();
                (e, t)
            }
        }
    }

    #[test]
    fn invalid_geometries_rejected() {
        let base = sk8(-1.0);
        // Lengths: non-finite or non-positive, each named with its value.
        let cases: [(&str, BeamUnitGeometry); 6] = [
            ("geometry.beam_front_arm", BeamUnitGeometry { front_arm: f64::NAN, ..base }),
            ("geometry.beam_rear_arm", BeamUnitGeometry { rear_arm: -2.5, ..base }),
            ("geometry.pivot_dx", BeamUnitGeometry { pivot_dx: 0.0, ..base }),
            ("geometry.pivot_dy", BeamUnitGeometry { pivot_dy: f64::INFINITY, ..base }),
            ("geometry.rod_length", BeamUnitGeometry { pitman: 0.0, ..base }),
            ("geometry.crank_radius", BeamUnitGeometry { crank: -1.01, ..base }),
        ];
        for (name, g) in cases {
            let (e, t) = err_text(&g);
            assert!(
                matches!(e, ModelError::OutOfRange { variable, .. } if variable == name),
                "{t}"
            );
            assert!(t.contains(name) && t.contains("> 0"), "{t}");
        }
        for rot in [0.0, 2.0, -0.5, f64::NAN] {
            let (e, t) = err_text(&BeamUnitGeometry { rotation: rot, ..base });
            assert!(matches!(e, ModelError::OutOfRange { variable: "rotation", .. }), "{t}");
        }
        // Loop closes at no crank angle: pitman far too short (K − R = 3.517 ≥ C + P = 3.0).
        let (e, t) = err_text(&BeamUnitGeometry { pitman: 0.5, crank: 0.2, ..base });
        assert!(matches!(e, ModelError::Invalid { .. }));
        assert!(
            t.contains("does not assemble") && t.contains("geometry.rod_length P = 0.5"),
            "{t}"
        );
        // R not the shortest link (R = 2.6 > C = 2.5), although the loop closes somewhere.
        let (e, t) = err_text(&BeamUnitGeometry { crank: 2.6, ..base });
        assert!(matches!(e, ModelError::Invalid { .. }));
        assert!(t.contains("shortest") && t.contains("R = 2.6") && t.contains("2.5"), "{t}");
        // Grashof violated with R shortest: 1.9 + 3.717 ≥ 2.5 + 3.0.
        let (e, t) = err_text(&BeamUnitGeometry { crank: 1.9, ..base });
        assert!(matches!(e, ModelError::Invalid { .. }));
        assert!(t.contains("Grashof") && t.contains("1.9 + 3.717") && t.contains(">= 5.5"), "{t}");
        // Same conditions for class III.
        let (_, t) = err_text(&BeamUnitGeometry { crank: 2.5, ..mark2(-1.0) });
        assert!(t.contains("shortest"), "{t}");
    }

    // ---- 9. Rod angle ---------------------------------------------------------------------------

    /// rod_angle against the independent positions (1e-13 rad) and rod_angle_rate against the
    /// Richardson derivative of the independent rod angle (tolerance 1e-9: the angle is accurate
    /// to ~1e-15 rad and O(h⁶) truncation ≈ 1e-10). Sign convention at a clear configuration:
    /// crank pin at 3 o'clock (toward the well) puts the pin end of the pitman nearer the well
    /// than the equalizer end of a conventional unit (equalizer above the crankshaft, E_x ≈ −0.09 m
    /// vs pin x = +1.01 m), so rod_angle > 0; at 9 o'clock, < 0 for both classes. (The Mark II
    /// equalizer sits ≈ 1 m forward of the crankshaft, beyond the pin at 3 o'clock, so there the
    /// east check would not be a clear configuration.)
    #[test]
    fn rod_angle_and_rate() {
        for g in all_configs() {
            let u = unit(&g);
            let ind = Indep { g };
            for &(th, b) in ind.revolution(360).iter() {
                let k = u.kinematics(th);
                assert!((k.rod_angle - ind.rod_angle(th, b)).abs() < 1e-13);
                let f = |t: f64| ind.rod_angle(t, ind.solve_near(t, b));
                let (d1, _) = richardson(&f, th, 0.02);
                assert!((k.rod_angle_rate - d1).abs() < 1e-9, "{} vs {d1}", k.rod_angle_rate);
            }
            // q = 90° (pin toward the well) and q = 270°; θ = rotation·q.
            let east = u.kinematics(g.rotation * PI / 2.0);
            let west = u.kinematics(g.rotation * 1.5 * PI);
            assert!(west.rod_angle < -0.2, "{g:?}");
            if g.class == BeamClass::Conventional {
                assert!(east.rod_angle > 0.2, "{g:?}");
            }
        }
    }

    /// Branch fixed at construction: the beam stays on the near-horizontal assembly over several
    /// revolutions and negative angles (s continuous, bounded by the stroke).
    #[test]
    fn branch_is_stable_over_revolutions() {
        for g in all_configs() {
            let u = unit(&g);
            let mut prev = u.kinematics(-3.0 * TAU).s;
            for j in 1..=7200 {
                let th = -3.0 * TAU + 6.0 * TAU * j as f64 / 7200.0;
                let s = u.kinematics(th).s;
                assert!(s <= u.stroke() + 1e-12 && (s - prev).abs() < 0.01);
                prev = s;
            }
        }
    }

    /// Timing check (run with `cargo test --release -- --ignored --nocapture`): best of 10
    /// batches, since the host is shared.
    #[test]
    #[ignore]
    fn timing() {
        let u = unit(&sk8(-1.0));
        let n = 2_000_000;
        let mut best = f64::INFINITY;
        let mut acc = 0.0;
        for _ in 0..10 {
            let t0 = std::time::Instant::now();
            for j in 0..n {
                let k = u.kinematics(std::hint::black_box((j % 1000) as f64 * 6.3e-3));
                acc += k.s + k.tf + k.tfp + k.rod_angle + k.rod_angle_rate;
            }
            best = best.min(t0.elapsed().as_secs_f64() / n as f64);
        }
        println!("kinematics(): {:.1} ns per call (best of 10; {acc})", best * 1e9);
    }
}
