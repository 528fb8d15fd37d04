//! ReciprocatingDrive: an FMI 2.0 co-simulation FMU of crank-driven reciprocating mechanisms.
//!
//! * [`model`]: the pure physics (physics.md), usable on its own from Rust.
//! * [`fmi2`]: the FMI 2.0 layer: variable table, instances, state machine, C ABI, XML generator.

pub mod fmi2;
pub mod model;
