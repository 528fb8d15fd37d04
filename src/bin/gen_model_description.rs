//! Writes the generated interface files of an FMU from its variable table:
//! * no argument: the ReciprocatingDrive FMU's modelDescription.xml on stdout
//!   (`cargo run --bin gen-model-description > modelDescription/modelDescription.xml`);
//! * `--model <modelIdentifier>`: another FMU's;
//! * `--fmi3`: the FMI 3.0 modelDescription.xml instead (from the same table);
//! * `--doc [--pages DIR]`: the FMU's documentation/index.html instead, linking the pages of the
//!   Markdown folder DIR (docs/) that scripts/build-fmu.sh puts beside it as HTML;
//! * `--page FILE.md`: one Markdown page as HTML (links to other pages become .html).
use std::path::Path;

use reciprocating_drive::fmi::{documentation, model::FmuModel};
use reciprocating_drive::fmi2::model_description;
use reciprocating_drive::fmi3::model_description as model_description3;
use reciprocating_drive::fmus::drive_train::DriveTrainFmu;
use reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive;

fn pages(dir: &Path) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        eprintln!("gen-model-description: cannot read {}", dir.display());
        std::process::exit(2);
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.extension().and_then(|x| x.to_str()) == Some("md") {
            let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or_default().to_string();
            let text = std::fs::read_to_string(&p).unwrap_or_default();
            let title = documentation::markdown_title(&text).unwrap_or_else(|| stem.clone());
            out.push((stem, title));
        }
    }
    // The folder's README (its index) first, then by name.
    out.sort_by_key(|(stem, _)| (stem != "README", stem.clone()));
    out
}

fn emit<M: FmuModel>(doc: bool, fmi3: bool, pages_dir: Option<&str>) {
    if doc {
        let pages = pages_dir.map(|d| pages(Path::new(d))).unwrap_or_default();
        print!("{}", documentation::generate_with_pages::<M>(&pages));
    } else if fmi3 {
        print!("{}", model_description3::generate::<M>());
    } else {
        print!("{}", model_description::generate::<M>());
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1)).map(|s| s.as_str())
    };
    if let Some(file) = value("--page") {
        match std::fs::read_to_string(file) {
            Ok(md) => print!("{}", documentation::markdown_page(&md)),
            Err(e) => {
                eprintln!("gen-model-description: {file}: {e}");
                std::process::exit(2);
            }
        }
        return;
    }
    let doc = args.iter().any(|a| a == "--doc");
    let fmi3 = args.iter().any(|a| a == "--fmi3");
    let model = value("--model").unwrap_or("ReciprocatingDrive");
    match model {
        "ReciprocatingDrive" => emit::<ReciprocatingDrive>(doc, fmi3, value("--pages")),
        "DriveTrain" => emit::<DriveTrainFmu>(doc, fmi3, value("--pages")),
        other => {
            eprintln!("gen-model-description: unknown model \"{other}\"; known: ReciprocatingDrive, DriveTrain");
            std::process::exit(2);
        }
    }
}
