//! Model parameters with the defaults of the default machine (docs/model.md §8: a UNB-600A-like
//! drilling mud pump), and the checks that no single-variable range can express.

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

use crate::model::error::ModelError;
use crate::model::guide::{GuideSpec, SupportKind, SupportSpec};

/// `load.profile` (docs/model.md §4).
pub const LOAD_PROFILE_COSINE: i32 = 0;
pub const LOAD_PROFILE_DOUBLE_ACTING: i32 = 1;
pub const LOAD_PROFILE_SINGLE_ACTING: i32 = 2;
/// Chambers at `fluid_end.discharge_pressure` while their volume shrinks, at `fluid_end.suction_pressure`
/// while it grows (docs/model.md §4.1).
pub const LOAD_PROFILE_PRESSURES: i32 = 3;

/// Cylinders on one crankshaft the variable table has room for (`cylinder_1` … `cylinder_3`;
/// docs/model.md §4.1).
pub const MAX_CYLINDERS: usize = 3;

/// `mechanism` (docs/model.md §1).
pub const MECHANISM_CRANK_SLIDER: i32 = 1;
pub const MECHANISM_BEAM_CLASS_I: i32 = 2;
pub const MECHANISM_BEAM_CLASS_III: i32 = 3;

/// One support of the link (docs/model.md §5.2), as the user sets it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SupportParams {
    /// 0 none, 1 pin, 2 clamp, 3 two-edge guide.
    pub kind: i32,
    /// 0 moves with the link, 1 fixed in the frame.
    pub attached: i32,
    pub z: f64,
    pub offset: f64,
    pub tilt: f64,
    pub length: f64,
    pub stiffness: f64,
    pub friction: f64,
}

/// One cylinder of the pump (docs/model.md §4.1): `cylinder_k.*`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CylinderParams {
    /// Crank phase φ_k [rad], added to the model angle: cylinder k's link sees θ + φ_k.
    pub phase: f64,
    /// 1 single-acting (the head-end chamber only), 2 double-acting (both chambers).
    pub acting: i32,
    /// Piston (liner) diameter D [m].
    pub piston_diameter: f64,
    /// Piston-rod diameter d [m] through the crank-end chamber (double-acting).
    pub rod_diameter: f64,
}

/// All parameters, in SI units and radians. Field names follow the variable names of
/// docs/model.md §10 (`geometry.crank_radius` → `crank_radius`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Params {
    pub mechanism: i32,
    /// +1 clockwise, −1 counter-clockwise (beam units, API 11E view with the well on the right).
    pub rotation: i32,
    pub crank_angle_offset: f64,
    pub crank_radius: f64,
    pub rod_length: f64,
    pub slider_offset: f64,
    /// Beam units (§3.2): A, C, I, H−G.
    pub beam_front_arm: f64,
    pub beam_rear_arm: f64,
    pub pivot_dx: f64,
    pub pivot_dy: f64,
    pub mass: f64,
    pub load_profile: i32,
    pub load_mean: f64,
    pub load_amplitude: f64,
    pub load_phase: f64,
    /// v_ε of the regularised sign tanh(v/v_ε) (§4 load profiles 1 and 2, §5.3 friction).
    pub velocity_scale: f64,
    /// The link as a stepped beam (§5.1): `link.l1..l4`, `link.d1..d4`, `link.E`.
    pub link_lengths: [f64; 4],
    pub link_diameters: [f64; 4],
    pub link_e_modulus: f64,
    pub link_lateral_load: f64,
    /// Supports A, B, C (§5.2); B's friction is `guide.friction_coefficient`.
    pub supports: [SupportParams; 3],
    pub rod_side_force: bool,
    /// Elastic connecting rod clamped in the piston (§6): 0 rigid, 1 thin rod, 2 helical spring.
    pub rod_kind: i32,
    pub rod_flex_length: f64,
    pub rod_rigid_length: f64,
    pub rod_wire_diameter: f64,
    pub rod_coil_diameter: f64,
    pub rod_coils: f64,
    pub rod_e_modulus: f64,
    pub rod_poisson: f64,
    pub rod_cage_inertia: f64,
    pub rod_damping_ratio: f64,
    pub rod_damping: f64,
    pub rod_load_eccentricity: f64,
    pub rod_rigid_mass: f64,
    pub rod_rigid_lever: f64,
    /// 1 quasi-static, 0 at rest (§6 "Initial state").
    pub rod_initial_state: i32,
    /// Default tolerance of the cage-equation integrator when fmi2SetupExperiment gives none.
    pub solver_tolerance: f64,
    /// Torsion-bar balancer (§7).
    pub balancer_enabled: bool,
    pub balancer_tuning: i32,
    pub balancer_stiffness: f64,
    pub balancer_design_speed: f64,
    pub balancer_neutral_position: f64,
    /// Active cylinders on the crankshaft, 1..=[`MAX_CYLINDERS`] (§4.1).
    pub cylinders: i32,
    pub cylinder: [CylinderParams; MAX_CYLINDERS],
}

/// Default crank speed: 65 strokes per minute (§8).
pub const DEFAULT_CRANK_SPEED: f64 = 2.0 * PI * 65.0 / 60.0;

impl Default for Params {
    fn default() -> Self {
        Params {
            mechanism: MECHANISM_CRANK_SLIDER,
            rotation: 1,
            crank_angle_offset: 0.0,
            crank_radius: 0.2,
            rod_length: 1.19,
            slider_offset: 0.0,
            // The beam geometry of the SK8-3.5-4000 unit (§8), so that a beam unit only needs
            // its crank, pitman and mechanism set (or the preset).
            beam_front_arm: 3.5,
            beam_rear_arm: 2.5,
            pivot_dx: 2.195,
            pivot_dy: 3.0,
            mass: 300.0,
            load_profile: LOAD_PROFILE_COSINE,
            load_mean: 0.0,
            load_amplitude: 0.0,
            load_phase: 0.0,
            velocity_scale: 0.02,
            // §8: assumed link of the UNB-600A-like pump and its three supports.
            link_lengths: [0.55, 0.15, 1.00, 0.40],
            link_diameters: [0.070, 0.130, 0.100, 0.300],
            link_e_modulus: 2.1e11,
            link_lateral_load: 0.0,
            supports: [
                // A: piston in its liner (clamp moving with the link), the reference axis.
                SupportParams {
                    kind: 2,
                    attached: 0,
                    z: 0.125,
                    offset: 0.0,
                    tilt: 0.0,
                    length: 0.25,
                    stiffness: 0.0,
                    friction: 0.0,
                },
                // B: crosshead in its guide (two-edge guide), slightly misaligned.
                SupportParams {
                    kind: 3,
                    attached: 0,
                    z: 1.90,
                    offset: 0.3e-3,
                    tilt: 1e-4,
                    length: 0.40,
                    stiffness: 0.0,
                    friction: 0.10,
                },
                // C: diaphragm gland (pin fixed in the frame), elastic.
                SupportParams {
                    kind: 1,
                    attached: 1,
                    z: 1.60,
                    offset: 0.1e-3,
                    tilt: 0.0,
                    length: 0.0,
                    stiffness: 2e6,
                    friction: 0.0,
                },
            ],
            rod_side_force: true,
            // Rigid rod by default; the elastic-rod data are those of the kvo630 spring (§8), so
            // switching rod.kind to 2 gives a coherent spring (J_m and ζ assumed there).
            rod_kind: 0,
            rod_flex_length: 0.023,
            rod_rigid_length: 0.015,
            rod_wire_diameter: 0.001,
            rod_coil_diameter: 0.005,
            rod_coils: 8.0,
            rod_e_modulus: 2.06e11,
            rod_poisson: 0.304,
            rod_cage_inertia: 5e-7,
            rod_damping_ratio: 0.05,
            rod_damping: 0.0,
            rod_load_eccentricity: 0.0,
            rod_rigid_mass: 0.0,
            rod_rigid_lever: 0.0,
            rod_initial_state: 1,
            solver_tolerance: 1e-8,
            balancer_enabled: false,
            balancer_tuning: 0,
            balancer_stiffness: 0.0,
            balancer_design_speed: DEFAULT_CRANK_SPEED,
            balancer_neutral_position: -1.0,
            // One cylinder (today's machine). Its liner: 130 mm piston on the 70 mm piston rod
            // of link.d1 (§8).
            cylinders: 1,
            cylinder: [CylinderParams {
                phase: 0.0,
                acting: 2,
                piston_diameter: 0.13,
                rod_diameter: 0.07,
            }; MAX_CYLINDERS],
        }
    }
}

impl Params {
    /// The link and its supports as the guide model takes them (§5). Integer codes are checked
    /// here; lengths, positions and whether the supports hold the link are checked by the guide.
    pub fn guide_spec(&self) -> Result<GuideSpec, ModelError> {
        const NAMES: [(&str, &str); 3] = [
            ("support_A.kind", "support_A.attached"),
            ("support_B.kind", "support_B.attached"),
            ("support_C.kind", "support_C.attached"),
        ];
        let mut supports = [SupportSpec::NONE; 3];
        for (x, sp) in self.supports.iter().enumerate() {
            let kind = SupportKind::from_i32(sp.kind).ok_or_else(|| {
                ModelError::out_of_range(
                    NAMES[x].0,
                    sp.kind as f64,
                    "0 (none), 1 (pin), 2 (clamp) or 3 (two-edge guide)",
                )
            })?;
            if !(sp.attached == 0 || sp.attached == 1) {
                return Err(ModelError::out_of_range(
                    NAMES[x].1,
                    sp.attached as f64,
                    "0 (moves with the link) or 1 (fixed in the frame)",
                ));
            }
            supports[x] = SupportSpec {
                kind,
                frame_fixed: sp.attached == 1,
                z: sp.z,
                offset: sp.offset,
                tilt: sp.tilt,
                length: sp.length,
                stiffness: sp.stiffness,
                friction: sp.friction,
            };
        }
        Ok(GuideSpec {
            section_lengths: self.link_lengths,
            section_diameters: self.link_diameters,
            e_modulus: self.link_e_modulus,
            supports,
            lateral_load: self.link_lateral_load,
            rod_side_force: self.rod_side_force,
            velocity_scale: self.velocity_scale,
        })
    }
}
