//! The FMI 3.0 layer: a second dialect over the FMI 2.0 layer's instance core
//! ([`crate::fmi2::instance::Instance`]) and variable table, so both standards share the state
//! machine, get/set, FMU states and the numbers. Only the C ABI ([`abi`]) and the
//! modelDescription.xml dialect ([`model_description`]) are FMI 3.0's own.

pub mod abi;
pub mod model_description;
