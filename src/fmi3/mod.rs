//! The FMI 3.0 layer: its C ABI ([`abi`], thin functions over the core [`crate::fmi`], the same
//! instance core and variable tables as FMI 2.0, so both standards share the state machine,
//! get/set, FMU states and the numbers) and its modelDescription.xml dialect
//! ([`model_description`]). It does not use the FMI 2.0 layer.

pub mod abi;
pub mod model_description;
