//! The FMI 2.0 co-simulation layer: no physics here. It owns instances, the state machine, value
//! references, FMU state snapshots, logging and the C ABI, and calls into [`crate::model`].

pub mod abi;
pub mod documentation;
pub mod fmu_state;
pub mod instance;
pub mod logging;
pub mod model_description;
pub mod resources;
pub mod variables;
