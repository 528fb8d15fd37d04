//! The ReciprocatingDrive FMU's shared object: the 34 FMI 2.0 functions for its model.
#![allow(non_snake_case)]

reciprocating_drive::export_fmu!(
    reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive
);
