//! Elastic connecting rod clamped in the piston (docs/model.md §6, seed 003 corrected per §9).
//!
//! The rod is a Haringx–Timoshenko beam-column of length `l_f` clamped in the piston (z = 0),
//! followed by a rigid part of length `f` up to the crank-pin centre, where the lower cage (moment
//! of inertia J_m) turns on the pin. The crank pin imposes the lateral offset Δ; the cage rotation
//! ϑ is the FMU's continuous state. This module provides everything that is a pure function of
//! the rod, the axial force P and (Δ, ϑ):
//!
//! * [`RodStiffness`]: A1, A2, A3 from the rod parameters (thin rod or helical spring);
//! * [`fundamental_functions`]: the normal solutions of `v'''' − x·v'' = 0`, entire in x;
//! * [`BeamColumn`]: the P-dependent coefficients (s_N, x, η, W*, K_ϑ, K_Δ, ...), the integration
//!   constants C3, C4 and the loads on the link at the clamp (§5.4);
//! * [`stress_max`]: the largest wire shear stress (spring) or normal stress (thin rod).
//!
//! The cage equation itself, `J_m ϑ̈ + B_d ϑ̇ + K_ϑ(P)ϑ = K_Δ(P)Δ + e_P·P + m_f f_m Δ̈`, is assembled
//! by the caller; [`crate::model::integrator`] integrates it.
//!
//! Sign conventions (derived independently from equilibrium of the deformed rod, see
//! `beam_column.rs`): compression P > 0, N = −P; v and ψ positive in the same sense as Δ and ϑ;
//! the moment of the rod on the cage about the pin is `−K_ϑ·ϑ + K_Δ·Δ`.

pub mod beam_column;
pub mod cage;
pub mod fundamental_functions;
pub mod stiffness;
pub mod stress;
pub mod table;
pub mod tangent;

pub use beam_column::BeamColumn;
pub use fundamental_functions::{fundamental_functions, FundamentalFunctions};
pub use stiffness::RodStiffness;
pub use stress::stress_max;

/// `rod.kind` for an elastic rod (0 = rigid rod is handled by the kinematics of §3.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RodKind {
    /// Thin straight rod of solid circular section, diameter `rod.wire_diameter`.
    ThinRod = 1,
    /// Helical spring with open coils: wire `rod.wire_diameter`, mean coil diameter
    /// `rod.coil_diameter`, `rod.coils` active coils over `rod.flex_length`.
    HelicalSpring = 2,
}

/// Geometry and material of the elastic rod (docs/model.md §6; variable names in the field docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RodSpec {
    /// `rod.kind`.
    pub kind: RodKind,
    /// `rod.flex_length` l_f [m]: elastic part, from the clamp in the piston.
    pub flex_length: f64,
    /// `rod.rigid_length` f [m]: rigid part from the end of the elastic part to the pin centre.
    pub rigid_length: f64,
    /// `rod.wire_diameter` d [m] (rod diameter for a thin rod).
    pub wire_diameter: f64,
    /// `rod.coil_diameter` D [m], mean coil diameter (spring only).
    pub coil_diameter: f64,
    /// `rod.coils` i, active coils (spring only).
    pub coils: f64,
    /// `rod.E` [Pa].
    pub e_modulus: f64,
    /// `rod.poisson` ν [1]; G = E/(2(1+ν)).
    pub poisson: f64,
}

#[cfg(test)]
mod tests;
