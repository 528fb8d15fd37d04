//! The core layer: everything an FMU instance is and does, whichever standard an importer speaks
//! through (no C signatures of either standard here, no physics). It owns the model trait
//! ([`model::FmuModel`]) and the variable tables, instances and their state machine, value
//! references and variable access, FMU state snapshots and their serialization, logging, Model
//! Exchange evaluation, directional derivatives, the handles the importer holds, and the checks
//! and panic barrier around every exported function ([`ffi`]). The two standards' C ABIs and
//! model-description writers ([`crate::fmi2`], [`crate::fmi3`]) are thin layers on top of it;
//! the models and their variable tables live in [`crate::fmus`].

pub mod directional;
pub mod display_units;
pub mod documentation;
pub(crate) mod ffi;
pub mod fmu_state;
pub(crate) mod handle;
pub mod instance;
pub mod logging;
pub mod model;
pub mod model_exchange;
mod plans;
pub mod resources;
pub mod structure;
pub mod variables;
pub mod xml;
