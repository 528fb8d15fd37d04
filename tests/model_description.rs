//! The checked-in modelDescription/modelDescription.xml must equal what the generator produces
//! from the variable table now (regenerate with
//! `cargo run --bin gen-model-description > modelDescription/modelDescription.xml`).

use reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive;

#[test]
fn checked_in_model_description_is_current() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/modelDescription/modelDescription.xml");
    let on_disk = std::fs::read_to_string(path).expect("modelDescription/modelDescription.xml exists");
    let generated = reciprocating_drive::fmi2::model_description::generate::<ReciprocatingDrive>();
    assert!(on_disk == generated, "modelDescription.xml is stale: regenerate it (see this file's doc)");
}

#[test]
fn checked_in_drive_train_model_description_is_current() {
    use reciprocating_drive::fmus::drive_train::DriveTrainFmu;
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/modelDescription/DriveTrain.xml");
    let on_disk = std::fs::read_to_string(path).expect("modelDescription/DriveTrain.xml exists");
    let generated = reciprocating_drive::fmi2::model_description::generate::<DriveTrainFmu>();
    assert!(on_disk == generated, "DriveTrain.xml is stale: cargo run --bin gen-model-description -- --model DriveTrain");
}

#[test]
fn every_contract_name_of_this_feature_set_is_declared() {
    // docs/model.md §10 names that the crank-slider feature set must expose, spelled out here.
    let xml = reciprocating_drive::fmi2::model_description::generate::<ReciprocatingDrive>();
    for name in [
        "crank.angle", "crank.speed", "crank.acceleration", "link.external_force",
        "suspension.position", "suspension.velocity", "suspension.acceleration",
        "kinematics.torque_factor", "inertia.force", "rod.force", "crank.torque", "rod.angle",
        "rod.angular_velocity", "mechanism", "crank.angle_offset", "geometry.crank_radius",
        "geometry.rod_length", "geometry.slider_offset", "mass.reciprocating", "load.profile",
        "load.mean", "load.amplitude", "load.phase",
    ] {
        assert!(xml.contains(&format!("name=\"{name}\"")), "{name} missing");
    }
}
