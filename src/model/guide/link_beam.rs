//! The link as a stepped Euler–Bernoulli beam (docs/model.md §5.1) and its exact flexibility
//! coefficients (Mohr integrals).
//!
//! Why the flexibility method: the beam problem has at most six support constraints, while an FE
//! model needs nodes at every section boundary, support point and load point, and those nodes
//! re-sort as frame-fixed supports slide along the link. With piecewise-constant EJ the Mohr
//! integrals are closed-form polynomials of the compliance moments
//! `I_k(x) = ∫₀ˣ tᵏ/EJ(t) dt` (k = 0, 1, 2), so every coefficient is exact and costs a few flops;
//! no node has to be inserted anywhere, and "inserting a node" (splitting a section into two of
//! equal diameter) cannot change any result.
//!
//! Base structure: the link cantilevered at z = 0. For a load system in equilibrium the clamp at
//! z = 0 carries nothing, so the cantilever's deflection is the free link's elastic deflection up
//! to a rigid-body motion `a + b·z`, which the caller keeps as two extra unknowns (see
//! `supports.rs`).
//!
//! Internal units (all quantities handled here are *scaled*): lengths by L, flexural rigidity by
//! EJ_ref, hence forces by EJ_ref/L², moments by EJ_ref/L, deflections by L, slopes unscaled. This
//! keeps every matrix entry of order one so partial pivoting in the small dense solve is sound.
// Index loops mirror the matrix formulas above; `!(a > b)` tests deliberately reject NaN.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use crate::model::error::{given, num, ModelError};

/// Names of the section variables (docs/model.md §10), indexed by section.
const LENGTH_NAMES: [&str; 4] = ["link.l1", "link.l2", "link.l3", "link.l4"];
const DIAMETER_NAMES: [&str; 4] = ["link.d1", "link.d2", "link.d3", "link.d4"];

/// Generalised coordinate of a point of the link: its lateral deflection (conjugate to a
/// lateral force) or its slope (conjugate to a moment).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Dof {
    Deflection,
    Slope,
}

/// A generalised coordinate at a (scaled) link coordinate z, with the compliance moments
/// `I_k(z)` already evaluated so that a flexibility coefficient costs a handful of flops.
#[derive(Clone, Copy, Debug)]
pub(super) struct Station {
    pub dof: Dof,
    pub z: f64,
    pub moments: [f64; 3],
}

/// Stepped beam with up to four sections; zero-length sections are dropped.
#[derive(Clone, Copy, Debug)]
pub(super) struct LinkBeam {
    /// L = l1 + … + l4 [m].
    pub length: f64,
    /// Reference flexural rigidity [N·m²]: the length-weighted harmonic mean L/∫dz/EJ.
    pub ej_ref: f64,
    /// Number of present sections.
    count: usize,
    /// Scaled section boundaries z/L; `bounds[0] = 0`, `bounds[count] = 1`.
    bounds: [f64; 5],
    /// Scaled compliance EJ_ref/EJ_i of each present section.
    inv_ej: [f64; 4],
    /// Scaled `I_k` at each boundary.
    cumulative: [[f64; 3]; 5],
}

impl LinkBeam {
    /// Validates `link.l1..l4`, `link.d1..d4`, `link.E` and precomputes the compliance moments.
    pub fn new(
        lengths: &[f64; 4],
        diameters: &[f64; 4],
        e_modulus: f64,
    ) -> Result<LinkBeam, ModelError> {
        for i in 0..4 {
            let l = lengths[i];
            if !l.is_finite() || l < 0.0 {
                return Err(ModelError::out_of_range(
                    LENGTH_NAMES[i],
                    l,
                    "[0, inf) m (0 means the section is absent)",
                ));
            }
            let d = diameters[i];
            if l > 0.0 && (!d.is_finite() || d <= 0.0) {
                return Err(ModelError::out_of_range(
                    DIAMETER_NAMES[i],
                    d,
                    "(0, inf) m for a present section (its length is > 0)",
                ));
            }
        }
        if !e_modulus.is_finite() || e_modulus <= 0.0 {
            return Err(ModelError::out_of_range("link.E", e_modulus, "(0, inf) Pa"));
        }
        let length: f64 = lengths.iter().sum();
        if !(length > 0.0) || !length.is_finite() {
            return Err(ModelError::invalid(format!(
                "the link has no length: link.l1 + link.l2 + link.l3 + link.l4 = {} m; \
                 at least one section must have a positive length when a support is defined \
                 (docs/model.md §5.1)",
                num(length)
            )));
        }
        // Physical section data, present sections only.
        let mut count = 0usize;
        let mut seg_len = [0.0f64; 4];
        let mut ej = [0.0f64; 4];
        for i in 0..4 {
            if lengths[i] > 0.0 {
                let d = diameters[i];
                seg_len[count] = lengths[i];
                ej[count] = e_modulus * std::f64::consts::PI * d * d * d * d / 64.0;
                // A diameter so small (or E and d so large) that E·J under- or overflows has no
                // stiffness to compute with: name the section rather than the mean below.
                if !(ej[count].is_normal() && ej[count] > 0.0) {
                    return Err(ModelError::invalid(format!(
                        "the link's section {} has no representable flexural rigidity: \
                         E·J = link.E·π·{}⁴/64 = {} N·m² with link.E = {} Pa, {} = {} m; \
                         allowed: a diameter and modulus whose E·J is a positive double \
                         (docs/model.md §5.1)",
                        i + 1,
                        DIAMETER_NAMES[i],
                        num(ej[count]),
                        given(e_modulus),
                        DIAMETER_NAMES[i],
                        given(d)
                    )));
                }
                count += 1;
            }
        }
        let compliance_integral: f64 = (0..count).map(|i| seg_len[i] / ej[i]).sum();
        let ej_ref = length / compliance_integral;
        if !ej_ref.is_finite() || ej_ref <= 0.0 {
            return Err(ModelError::invalid(format!(
                "the link's flexural rigidity is not representable: mean E·J = {} N·m² \
                 (link.E = {} Pa, link.d1..d4 = [{}] m)",
                num(ej_ref),
                given(e_modulus),
                diameters.map(given).join(", ")
            )));
        }
        let mut beam = LinkBeam {
            length,
            ej_ref,
            count,
            bounds: [1.0; 5],
            inv_ej: [0.0; 4],
            cumulative: [[0.0; 3]; 5],
        };
        beam.bounds[0] = 0.0;
        let mut z = 0.0;
        for i in 0..count {
            beam.inv_ej[i] = ej_ref / ej[i];
            z += seg_len[i];
            // The last boundary is exactly 1 so that z = L lies in the last section.
            beam.bounds[i + 1] = if i + 1 == count { 1.0 } else { z / length };
        }
        for i in 0..count {
            let (a, b) = (beam.bounds[i], beam.bounds[i + 1]);
            let c = beam.inv_ej[i];
            let prev = beam.cumulative[i];
            beam.cumulative[i + 1] = [
                prev[0] + c * (b - a),
                prev[1] + c * (b * b - a * a) / 2.0,
                prev[2] + c * (b * b * b - a * a * a) / 3.0,
            ];
        }
        Ok(beam)
    }

    /// Scaled compliance moments `I_k(x) = ∫₀ˣ tᵏ·EJ_ref/EJ(t) dt`, k = 0, 1, 2, at scaled x.
    /// Points slightly outside [0, 1] (rounding of the stroke coordinate) use the end sections.
    #[inline]
    pub fn moments(&self, x: f64) -> [f64; 3] {
        let mut i = 0usize;
        while i + 1 < self.count && x > self.bounds[i + 1] {
            i += 1;
        }
        let a = self.bounds[i];
        let c = self.inv_ej[i];
        let base = self.cumulative[i];
        // Differences x^k − a^k factored so that x close to a loses no digits.
        let d = x - a;
        [
            base[0] + c * d,
            base[1] + c * d * (x + a) / 2.0,
            base[2] + c * d * (x * x + x * a + a * a) / 3.0,
        ]
    }

    /// Scaled section boundaries inside the link (where the compliance moments change formula).
    pub fn interior_bounds(&self) -> &[f64] {
        &self.bounds[1..self.count]
    }

    /// A station (generalised coordinate at scaled z) for repeated flexibility evaluations.
    #[inline]
    pub fn station(&self, dof: Dof, z: f64) -> Station {
        Station { dof, z, moments: self.moments(z) }
    }

    /// Flexibility coefficient of the cantilever clamped at z = 0: the generalised displacement
    /// at `i` caused by a unit generalised force at `j` (force for a deflection, moment for a
    /// slope). Mohr: ∫₀^min (zᵢ − t)^{pᵢ}(zⱼ − t)^{pⱼ}/EJ dt with p = 1 for a deflection and 0
    /// for a slope (the moment of a unit force at ξ is ξ − t for t < ξ; of a unit moment, 1).
    /// Symmetric in i, j (Maxwell).
    #[inline]
    pub fn flexibility(i: &Station, j: &Station) -> f64 {
        let m = if i.z <= j.z { &i.moments } else { &j.moments };
        match (i.dof, j.dof) {
            (Dof::Deflection, Dof::Deflection) => i.z * j.z * m[0] - (i.z + j.z) * m[1] + m[2],
            (Dof::Deflection, Dof::Slope) => i.z * m[0] - m[1],
            (Dof::Slope, Dof::Deflection) => j.z * m[0] - m[1],
            (Dof::Slope, Dof::Slope) => m[0],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform cantilever of length L: tip deflection under a tip force is L³/(3EJ), tip slope
    /// under a tip moment L/EJ, cross term L²/(2EJ) (textbook, exact).
    #[test]
    fn cantilever_textbook_flexibilities() {
        let d = 0.05;
        let beam = LinkBeam::new(&[2.0, 0.0, 0.0, 0.0], &[d, 0.0, 0.0, 0.0], 2e11).unwrap();
        let ej = 2e11 * std::f64::consts::PI * d.powi(4) / 64.0;
        let tip_d = beam.station(Dof::Deflection, 1.0);
        let tip_s = beam.station(Dof::Slope, 1.0);
        let l = beam.length;
        // Unscale: deflection/force = flex·L³/EJ_ref.
        let s = l * l * l / beam.ej_ref;
        let dd = LinkBeam::flexibility(&tip_d, &tip_d) * s;
        let ds = LinkBeam::flexibility(&tip_d, &tip_s) * s / l;
        let ss = LinkBeam::flexibility(&tip_s, &tip_s) * s / (l * l);
        assert!((dd / (l.powi(3) / (3.0 * ej)) - 1.0).abs() < 1e-14);
        assert!((ds / (l * l / (2.0 * ej)) - 1.0).abs() < 1e-14);
        assert!((ss / (l / ej) - 1.0).abs() < 1e-14);
    }

    /// Splitting a section into two of equal diameter changes no coefficient (exactness of the
    /// piecewise-constant integrals), to rounding.
    #[test]
    fn split_section_is_invisible() {
        let a = LinkBeam::new(&[0.5, 1.0, 0.0, 0.0], &[0.1, 0.2, 0.0, 0.0], 2e11).unwrap();
        let b = LinkBeam::new(&[0.5, 0.3, 0.7, 0.0], &[0.1, 0.2, 0.2, 0.0], 2e11).unwrap();
        for &(zi, zj) in &[(0.1, 0.9), (0.45, 0.62), (1.0, 1.0), (0.3, 0.3)] {
            for &(di, dj) in &[
                (Dof::Deflection, Dof::Deflection),
                (Dof::Deflection, Dof::Slope),
                (Dof::Slope, Dof::Slope),
            ] {
                let fa = LinkBeam::flexibility(&a.station(di, zi), &a.station(dj, zj)) / a.ej_ref;
                let fb = LinkBeam::flexibility(&b.station(di, zi), &b.station(dj, zj)) / b.ej_ref;
                assert!((fa - fb).abs() <= 1e-14 * fa.abs().max(1e-300), "{fa} vs {fb}");
            }
        }
    }
}
