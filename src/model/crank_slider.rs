//! Exact kinematics of the (optionally offset) crank-slider, docs/model.md §3.1.
//!
//! Frame: x along the stroke axis from the crank centre toward the crosshead; crank pin at
//! (r cosθ, r sinθ); stroke axis y = e. Rod angle β from l·sinβ = r·sinθ − e.
//! X(θ) = r cosθ + l cosβ, s = X_max − X. The derivatives below are the exact analytic ones
//! (never finite differences, never the truncated λ-series of older handbooks, §2).

use crate::model::error::{given, num, require_finite, ModelError};
use crate::model::kinematics::{Kinematics, Scalar};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrankSlider {
    r: f64,
    l: f64,
    e: f64,
    /// X_max = sqrt((l + r)² − e²): crosshead position at the outer dead centre.
    x_max: f64,
    /// X_min = sqrt((l − r)² − e²): at the inner dead centre.
    x_min: f64,
}

impl CrankSlider {
    /// Validates r > 0, l > r + |e| (strict: at equality the rod would stand perpendicular to
    /// the stroke and the mechanism locks, §3.1).
    pub fn new(r: f64, l: f64, e: f64) -> Result<Self, ModelError> {
        require_finite("geometry.crank_radius", r)?;
        require_finite("geometry.rod_length", l)?;
        require_finite("geometry.slider_offset", e)?;
        if r <= 0.0 {
            return Err(ModelError::out_of_range("geometry.crank_radius", r, "(0, inf) m"));
        }
        if l <= r + e.abs() {
            return Err(ModelError::invalid(format!(
                "the crank-slider cannot assemble: geometry.rod_length = {} m must exceed \
                 geometry.crank_radius + |geometry.slider_offset| = {} + {} = {} m (docs/model.md §3.1)",
                given(l),
                given(r),
                given(e.abs()),
                num(r + e.abs())
            )));
        }
        let x_max = ((l + r) * (l + r) - e * e).sqrt();
        let x_min = ((l - r) * (l - r) - e * e).sqrt();
        Ok(CrankSlider { r, l, e, x_max, x_min })
    }

    /// Stroke S = X_max − X_min (= 2r for e = 0).
    pub fn stroke(&self) -> f64 {
        self.x_max - self.x_min
    }

    /// Exact s, TF, TF', β and dβ/dθ at model angle θ (§3.1).
    #[inline]
    pub fn kinematics(&self, theta: f64) -> Kinematics {
        self.kinematics_and_tan_beta(theta).0
    }

    /// [`CrankSlider::kinematics`] and tanβ, from the same sinθ: the rigid rod's side load on the
    /// crosshead is −P·tanβ (§5.4).
    #[inline]
    pub fn kinematics_and_tan_beta(&self, theta: f64) -> (Kinematics, f64) {
        self.kinematics_and_tan_beta_of(theta)
    }

    /// [`CrankSlider::kinematics_and_tan_beta`] for any [`Scalar`]: with a dual number it also
    /// gives the exact derivatives of every field (the directional derivatives); with `f64` it is
    /// the same arithmetic in the same order.
    #[inline(always)]
    pub fn kinematics_and_tan_beta_of<T: Scalar>(&self, theta: T) -> (Kinematics<T>, T) {
        let (sin, cos) = theta.sin_cos();
        let (r, l) = (self.r, self.l);
        let sin_beta = (sin * r - self.e) / l;
        // l > r + |e| keeps |sinβ| < 1, so cosβ > 0 and the square root is safe.
        let cos_beta = (T::from(1.0) - sin_beta * sin_beta).sqrt();
        let tan_beta = sin_beta / cos_beta;
        // dβ/dθ from differentiating l·sinβ = r·sinθ − e.
        let beta_rate = cos * r / (cos_beta * l);
        let x = cos * r + cos_beta * l;
        // TF = −dX/dθ = r sinθ + l sinβ·β' = r sinθ + r cosθ·tanβ.
        let tf = sin * r + cos * r * tan_beta;
        // TF' = d/dθ of the line above, using d(tanβ)/dθ = β'/cos²β.
        let tfp = cos * r - sin * r * tan_beta + cos * r * beta_rate / (cos_beta * cos_beta);
        let k = Kinematics {
            s: T::from(self.x_max) - x,
            tf,
            tfp,
            rod_angle: sin_beta.asin(),
            rod_angle_rate: beta_rate,
        };
        (k, tan_beta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Independent formulation: the vector loop solved for the crosshead position X by Newton's
    /// method on |pin − crosshead|² = l² (no use of the closed form), then differentiated by an
    /// 8th-order central difference. With step h = 1e-3 rad the truncation error is ~h⁸·s⁽⁹⁾ ≈ 1e-25 m
    /// and the round-off ~ε·X/h² ≈ 3e-10 m/rad² for TF', so 1e-8 relative to r is a safe bound.
    fn x_by_newton(r: f64, l: f64, e: f64, theta: f64) -> f64 {
        let (px, py) = (r * theta.cos(), r * theta.sin());
        let mut x = px + l; // start on the physical branch (crosshead beyond the pin)
        for _ in 0..60 {
            let g = (x - px).powi(2) + (e - py).powi(2) - l * l;
            let dg = 2.0 * (x - px);
            let dx = g / dg;
            x -= dx;
            if dx.abs() < 1e-16 * l {
                break;
            }
        }
        x
    }

    fn derivs(f: &dyn Fn(f64) -> f64, t: f64, h: f64) -> (f64, f64) {
        // 8th-order central differences for the first and second derivative.
        let c1 = [4.0 / 5.0, -1.0 / 5.0, 4.0 / 105.0, -1.0 / 280.0];
        let c2 = [8.0 / 5.0, -1.0 / 5.0, 8.0 / 315.0, -1.0 / 560.0];
        let c0 = -205.0 / 72.0;
        let (mut d1, mut d2) = (0.0, c0 * f(t));
        for k in 0..4 {
            let kh = (k + 1) as f64 * h;
            let (fp, fm) = (f(t + kh), f(t - kh));
            d1 += c1[k] * (fp - fm);
            d2 += c2[k] * (fp + fm);
        }
        (d1 / h, d2 / (h * h))
    }

    #[test]
    fn matches_vector_loop_at_720_angles_with_offset() {
        for &(r, l, e) in
            &[(0.2, 1.19, 0.0), (0.2, 1.19, 0.05), (0.1, 0.35, -0.04), (1.0, 2.2, 0.9)]
        {
            let m = CrankSlider::new(r, l, e).unwrap();
            let x_max = ((l + r).powi(2) - e * e).sqrt();
            for i in 0..720 {
                let theta = -PI + 2.0 * PI * (i as f64 + 0.37) / 720.0;
                let k = m.kinematics(theta);
                let s = |t: f64| x_max - x_by_newton(r, l, e, t);
                let (d1, d2) = derivs(&s, theta, 1e-3);
                assert!((k.s - s(theta)).abs() < 1e-13 * l, "s at {theta}");
                assert!((k.tf - d1).abs() < 1e-9 * r, "TF at {theta}: {} vs {d1}", k.tf);
                assert!((k.tfp - d2).abs() < 1e-7 * r, "TF' at {theta}: {} vs {d2}", k.tfp);
                // Rod angle from the geometry of the loop: sinβ = (pin_y − e)/l.
                let beta = ((r * theta.sin() - e) / l).asin();
                assert!((k.rod_angle - beta).abs() < 1e-14);
                let beta_of = |t: f64| ((r * t.sin() - e) / l).asin();
                let (b1, _) = derivs(&beta_of, theta, 1e-3);
                assert!((k.rod_angle_rate - b1).abs() < 1e-9);
                assert!(k.s >= -1e-15 * l && k.s <= m.stroke() + 1e-12 * l);
            }
        }
    }

    #[test]
    fn dead_centre_closed_forms_and_stroke() {
        // docs/model.md §3.1 checks: a(0) = rω²(1+λ), a(π) = −rω²(1−λ) for ε = 0; stroke 2r.
        let (r, l) = (0.2, 1.19);
        let lambda = r / l;
        let m = CrankSlider::new(r, l, 0.0).unwrap();
        let w = 2.0 * PI * 65.0 / 60.0;
        let k0 = m.kinematics(0.0);
        let kpi = m.kinematics(PI);
        assert!(k0.s.abs() < 1e-15);
        assert!((kpi.s - 2.0 * r).abs() < 1e-15);
        assert!((m.stroke() - 2.0 * r).abs() < 1e-15);
        assert!((k0.acceleration(w, 0.0) - r * w * w * (1.0 + lambda)).abs() < 1e-12);
        assert!((kpi.acceleration(w, 0.0) + r * w * w * (1.0 - lambda)).abs() < 1e-12);
        assert!(k0.tf.abs() < 1e-16 && kpi.tf.abs() < 1e-15);
    }

    #[test]
    fn central_closed_forms_of_physics_md() {
        // The λ, D closed forms of §3.1 for e = 0, written out independently.
        let (r, l) = (0.2, 1.19);
        let lam = r / l;
        let m = CrankSlider::new(r, l, 0.0).unwrap();
        for i in 0..720 {
            let t = 2.0 * PI * i as f64 / 720.0;
            let d = (1.0 - lam * lam * t.sin().powi(2)).sqrt();
            let s = r * (1.0 - t.cos()) + l * (1.0 - d);
            let tf = r * t.sin() * (1.0 + lam * t.cos() / d);
            let tfp =
                r * (t.cos() + lam * ((2.0 * t).cos() + lam * lam * t.sin().powi(4)) / d.powi(3));
            let k = m.kinematics(t);
            assert!(
                (k.s - s).abs() < 1e-15 && (k.tf - tf).abs() < 1e-15 && (k.tfp - tfp).abs() < 1e-15
            );
        }
    }

    #[test]
    fn offset_stroke_and_odc_position() {
        // For e ≠ 0 the stroke is X_max − X_min (> 2r) and s ≥ 0 with its zero at the ODC,
        // where the crank and rod are collinear: θ_odc = asin(e/(l+r)).
        let (r, l, e) = (0.2, 1.19, 0.1);
        let m = CrankSlider::new(r, l, e).unwrap();
        let th = (e / (l + r)).asin();
        assert!(m.kinematics(th).s.abs() < 1e-15);
        assert!(m.kinematics(th).tf.abs() < 1e-14);
        let expected = ((l + r).powi(2) - e * e).sqrt() - ((l - r).powi(2) - e * e).sqrt();
        assert!((m.stroke() - expected).abs() < 1e-15 && m.stroke() > 2.0 * r);
    }

    #[test]
    fn rejects_linkages_that_cannot_assemble() {
        let err = CrankSlider::new(0.2, 0.25, 0.05).unwrap_err().to_string();
        assert!(err.contains("geometry.rod_length") && err.contains("0.25"), "{err}");
        let err = CrankSlider::new(0.0, 1.0, 0.0).unwrap_err().to_string();
        assert!(err.contains("geometry.crank_radius") && err.contains("(0, inf)"), "{err}");
        assert!(CrankSlider::new(f64::NAN, 1.0, 0.0).is_err());
    }
}
