//! FMU layer (docs/architecture.md "The FMUs (Rust)").
//!
//! The FMUs this crate builds, one module each: the model's variable table and the few calls that
//! connect its physics (in [`crate::model`]) to the shared FMI core ([`crate::fmi`]). Each FMU's
//! shared object is a thin cdylib crate under `cdylib/<modelIdentifier>/` that exports the glue
//! for its model with [`export_fmu!`](crate::export_fmu).

pub mod drive_train;
pub mod reciprocating_drive;
