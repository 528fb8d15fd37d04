//! Prints modelDescription.xml generated from the variable table (src/fmi2/variables.rs).
//! Usage: `cargo run --bin gen-model-description > modelDescription/modelDescription.xml`
fn main() {
    print!("{}", reciprocating_drive::fmi2::model_description::generate());
}
