//! Writes the generated interface files from the variable table (src/fmi2/variables.rs):
//! * no argument: modelDescription.xml on stdout
//!   (`cargo run --bin gen-model-description > modelDescription/modelDescription.xml`);
//! * `--doc`: the FMU's documentation/index.html on stdout.
fn main() {
    if std::env::args().any(|a| a == "--doc") {
        print!("{}", reciprocating_drive::fmi2::documentation::generate());
    } else {
        print!("{}", reciprocating_drive::fmi2::model_description::generate());
    }
}
