//! The ReciprocatingDrive FMU's shared object: the 34 FMI 2.0 functions and the FMI 3.0
//! functions for its model (one binary for target/fmu/ReciprocatingDrive.fmu and
//! target/fmu/ReciprocatingDrive-fmi3.fmu).
#![allow(non_snake_case)]

reciprocating_drive::export_fmu!(
    reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive
);
reciprocating_drive::export_fmu3!(
    reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive
);
