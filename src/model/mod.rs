//! The pure physics of ReciprocatingDrive: plain structs and functions mapping parameters and
//! inputs to outputs. No FFI, no global state, no logging (the FMI layer in `crate::fmi2` owns
//! those). Each file cites the section of `docs/model.md` it implements.

pub mod balancer;
pub mod beam_unit;
pub mod crank;
pub mod crank_slider;
pub mod drive;
pub mod drive_train;
pub mod elastic_rod;
pub mod error;
pub mod guide;
pub mod integrator;
pub mod kinematics;
pub mod loads;
pub mod params;
pub mod pump;
