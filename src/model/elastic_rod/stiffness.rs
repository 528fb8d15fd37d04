//! Equivalent beam-column stiffnesses A1 (shear), A2 (bending), A3 (extension) of the elastic
//! connecting rod (docs/model.md §6, "Equivalent beam-column").

use super::{RodKind, RodSpec};
use crate::model::error::{given, num, ModelError};
use std::f64::consts::PI;

/// Shear correction factor of a solid circular section used for the thin rod (docs/model.md §6).
pub const SHEAR_CORRECTION_THIN_ROD: f64 = 0.9;

/// Haringx–Timoshenko stiffnesses of the equivalent beam-column (docs/model.md §6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RodStiffness {
    /// Shear stiffness A1 [N].
    pub a1: f64,
    /// Bending stiffness A2 [N·m²].
    pub a2: f64,
    /// Extension stiffness A3 [N].
    pub a3: f64,
}

fn positive(variable: &'static str, value: f64, unit: &str) -> Result<f64, ModelError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ModelError::out_of_range(variable, value, format!("a finite number > 0 {unit}")))
    }
}

impl RodStiffness {
    /// Validates the rod parameters and computes A1, A2, A3 (docs/model.md §6).
    ///
    /// * thin rod: `A2 = E·πd⁴/64`, `A1 = 0.9·G·πd²/4`, `A3 = E·πd²/4`;
    /// * helical spring (open coils), pitch `h = l_f/i`, `B_t = G·πd⁴/32`, `B_b = E·πd⁴/64`:
    ///   `A1 = 8h·B_b/(πD³)`, `A3 = 4h·B_t/(πD³)`, `A2 = (2h/(πD))·B_t·B_b/(B_t + B_b)`.
    ///
    /// The spring formulas were re-derived (not copied from seed 003): A3 is the classic
    /// `k·l_f = G d⁴ h/(8D³)`; A2 follows from the energy of a coil under a bending moment, which
    /// is carried half as wire bending and half as wire torsion around the turn.
    ///
    /// Ranges (errors name the variable, the value and what is allowed): `rod.flex_length`,
    /// `rod.wire_diameter`, `rod.E` > 0; `rod.rigid_length` ≥ 0; −1 < `rod.poisson` ≤ 0.5; for a
    /// spring `rod.coils` ≥ 1, `rod.coil_diameter` > `rod.wire_diameter` (spring index c > 1, the
    /// Wahl factor is singular at c = 1), and the pitch `l_f/i` ≥ d (coils cannot interpenetrate).
    pub fn new(spec: &RodSpec) -> Result<RodStiffness, ModelError> {
        let l_f = positive("rod.flex_length", spec.flex_length, "m")?;
        if !(spec.rigid_length.is_finite() && spec.rigid_length >= 0.0) {
            return Err(ModelError::out_of_range(
                "rod.rigid_length",
                spec.rigid_length,
                "a finite number >= 0 m",
            ));
        }
        let d = positive("rod.wire_diameter", spec.wire_diameter, "m")?;
        let e = positive("rod.E", spec.e_modulus, "Pa")?;
        let nu = spec.poisson;
        if !(nu.is_finite() && nu > -1.0 && nu <= 0.5) {
            return Err(ModelError::out_of_range("rod.poisson", nu, "-1 < rod.poisson <= 0.5"));
        }
        let g = e / (2.0 * (1.0 + nu));
        let d2 = d * d;
        let d4 = d2 * d2;
        match spec.kind {
            RodKind::ThinRod => Ok(RodStiffness {
                a1: SHEAR_CORRECTION_THIN_ROD * g * PI * d2 / 4.0,
                a2: e * PI * d4 / 64.0,
                a3: e * PI * d2 / 4.0,
            }),
            RodKind::HelicalSpring => {
                let i = spec.coils;
                if !(i.is_finite() && i >= 1.0) {
                    return Err(ModelError::out_of_range(
                        "rod.coils",
                        i,
                        "a finite number >= 1 (active coils)",
                    ));
                }
                let dc = spec.coil_diameter;
                if !(dc.is_finite() && dc > d) {
                    return Err(ModelError::out_of_range(
                        "rod.coil_diameter",
                        dc,
                        format!(
                            "a finite number > rod.wire_diameter = {} m (spring index > 1)",
                            given(d)
                        ),
                    ));
                }
                let h = l_f / i;
                if h < d {
                    return Err(ModelError::invalid(format!(
                        "helical spring rod: pitch rod.flex_length/rod.coils = {} m / {} = {} m \
                         is smaller than rod.wire_diameter = {} m (the coils would interpenetrate)",
                        given(l_f),
                        given(i),
                        num(h),
                        given(d)
                    )));
                }
                let b_t = g * PI * d4 / 32.0;
                let b_b = e * PI * d4 / 64.0;
                let pi_d3 = PI * dc * dc * dc;
                Ok(RodStiffness {
                    a1: 8.0 * h * b_b / pi_d3,
                    a2: (2.0 * h / (PI * dc)) * b_t * b_b / (b_t + b_b),
                    a3: 4.0 * h * b_t / pi_d3,
                })
            }
        }
    }

    /// Static axial shortening `P·l_f/A3` [m] (output `rod.axial_deflection`, docs/model.md §6).
    #[inline]
    pub fn axial_deflection(&self, p: f64, flex_length: f64) -> f64 {
        p * flex_length / self.a3
    }
}
