//! The FMI 2.0 co-simulation layer, shared by every FMU of the crate: no physics here. It owns
//! instances, the state machine, value references, FMU state snapshots, logging, the generators of
//! modelDescription.xml and documentation, and the C ABI, generic over a model ([`model::FmuModel`]).
//! The models and their variable tables live in [`crate::fmus`].

pub mod abi;
pub mod directional;
pub mod display_units;
pub mod documentation;
pub mod fmu_state;
pub(crate) mod handle;
pub mod instance;
pub mod logging;
pub mod model;
pub mod model_description;
pub mod model_exchange;
mod plans;
pub mod resources;
pub mod variables;
