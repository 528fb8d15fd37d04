//! Writes the generated interface files of an FMU from its variable table:
//! * no argument: the ReciprocatingDrive FMU's modelDescription.xml on stdout
//!   (`cargo run --bin gen-model-description > modelDescription/modelDescription.xml`);
//! * `--model <modelIdentifier>`: another FMU's;
//! * `--doc`: the FMU's documentation/index.html instead.
use reciprocating_drive::fmi2::{documentation, model::FmuModel, model_description};
use reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive;

fn emit<M: FmuModel>(doc: bool) {
    if doc {
        print!("{}", documentation::generate::<M>());
    } else {
        print!("{}", model_description::generate::<M>());
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let doc = args.iter().any(|a| a == "--doc");
    let model = args.iter().position(|a| a == "--model").and_then(|i| args.get(i + 1)).map_or("ReciprocatingDrive", |s| s.as_str());
    match model {
        "ReciprocatingDrive" => emit::<ReciprocatingDrive>(doc),
        other => {
            eprintln!("gen-model-description: unknown model \"{other}\"; known: ReciprocatingDrive");
            std::process::exit(2);
        }
    }
}
