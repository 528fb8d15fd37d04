//! The checked-in modelDescription/*.xml must equal what the generator produces from the
//! variable tables now (regenerate with `cargo run --bin gen-model-description [-- --model ID]`).

use reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive;

/// The checked-in file equals what the generator makes from model M's table now.
fn assert_current<M: reciprocating_drive::fmi::model::FmuModel>(file: &str, regenerate: &str) {
    let path = format!("{}/modelDescription/{file}", env!("CARGO_MANIFEST_DIR"));
    let on_disk = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let generated = reciprocating_drive::fmi2::model_description::generate::<M>();
    assert!(on_disk == generated, "{file} is stale: regenerate it with {regenerate}");
}

#[test]
fn checked_in_model_description_is_current() {
    assert_current::<ReciprocatingDrive>(
        "modelDescription.xml",
        "cargo run --bin gen-model-description > modelDescription/modelDescription.xml",
    );
}

#[test]
fn checked_in_drive_train_model_description_is_current() {
    assert_current::<reciprocating_drive::fmus::drive_train::DriveTrainFmu>(
        "DriveTrain.xml",
        "cargo run --bin gen-model-description -- --model DriveTrain > modelDescription/DriveTrain.xml",
    );
}

#[test]
fn every_contract_name_of_this_feature_set_is_declared() {
    // docs/model.md §10 names that the crank-slider feature set must expose, spelled out here.
    let xml = reciprocating_drive::fmi2::model_description::generate::<ReciprocatingDrive>();
    for name in [
        "crank.angle",
        "crank.speed",
        "crank.acceleration",
        "link.external_force",
        "suspension.position",
        "suspension.velocity",
        "suspension.acceleration",
        "kinematics.torque_factor",
        "inertia.force",
        "rod.force",
        "crank.torque",
        "rod.angle",
        "rod.angular_velocity",
        "mechanism",
        "crank.angle_offset",
        "geometry.crank_radius",
        "geometry.rod_length",
        "geometry.slider_offset",
        "mass.reciprocating",
        "load.profile",
        "load.mean",
        "load.amplitude",
        "load.phase",
    ] {
        assert!(xml.contains(&format!("name=\"{name}\"")), "{name} missing");
    }
}
