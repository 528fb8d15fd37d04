//! The FMI 2.0 layer: its C ABI (co-simulation [`abi`] and Model Exchange [`model_exchange`],
//! thin functions over the core [`crate::fmi`]) and its modelDescription.xml dialect
//! ([`model_description`]). It does not use the FMI 3.0 layer.

pub mod abi;
pub mod model_description;
pub mod model_exchange;
