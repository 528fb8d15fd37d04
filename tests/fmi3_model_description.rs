//! The checked-in FMI 3.0 model descriptions (modelDescription/fmi3/*.xml) must equal what the
//! generator produces from the variable tables now, as for FMI 2.0 (tests/model_description.rs);
//! and the 3.0 file names the same variables as the 2.0 file, in the same order with the same
//! value references (one table), read back from the two generated texts.

use reciprocating_drive::fmi::model::FmuModel;
use reciprocating_drive::fmus::drive_train::DriveTrainFmu;
use reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive;

fn assert_current<M: FmuModel>(id: &str) {
    let file = format!("modelDescription/fmi3/{id}.xml");
    let path = format!("{}/{file}", env!("CARGO_MANIFEST_DIR"));
    let on_disk = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let generated = reciprocating_drive::fmi3::model_description::generate::<M>();
    assert!(
        on_disk == generated,
        "{file} is stale: regenerate it with \
         cargo run --bin gen-model-description -- --fmi3 --model {id} > {file}"
    );
}

/// (name, valueReference) of every variable, in document order, from attributes in a line.
fn names_and_refs(xml: &str) -> Vec<(String, String)> {
    let attr = |line: &str, a: &str| {
        let key = format!(" {a}=\"");
        line.find(&key).map(|i| {
            let rest = &line[i + key.len()..];
            rest[..rest.find('"').unwrap()].to_string()
        })
    };
    xml.lines()
        .filter(|l| l.contains(" valueReference=\"") && l.contains(" name=\""))
        .map(|l| (attr(l, "name").unwrap(), attr(l, "valueReference").unwrap()))
        .collect()
}

#[test]
fn checked_in_fmi3_model_descriptions_are_current() {
    assert_current::<ReciprocatingDrive>("ReciprocatingDrive");
    assert_current::<DriveTrainFmu>("DriveTrain");
}

#[test]
fn fmi3_declares_the_same_variables_as_fmi2() {
    fn check<M: FmuModel>() {
        let two = reciprocating_drive::fmi2::model_description::generate::<M>();
        let three = reciprocating_drive::fmi3::model_description::generate::<M>();
        let (a, mut b) = (names_and_refs(&two), names_and_refs(&three));
        let n = M::table().variables.len();
        let own = M::STATE_VARIABLES.len();
        assert_eq!(a.len(), n + M::CONTINUOUS_STATES.len() + own);
        // FMI 3.0's independent variable, after the table's value references.
        assert_eq!(b.remove(0), ("time".to_string(), n.to_string()));
        // Then, in both files, the derivatives of the continuous states (Model Exchange), if
        // any, with the same value references.
        let ders: Vec<String> = a[n..a.len() - own].iter().map(|(name, _)| name.clone()).collect();
        let expected: Vec<String> =
            M::CONTINUOUS_STATES.iter().map(|(s, _)| format!("der({s})")).collect();
        assert_eq!(ders, expected);
        // Then the states that are no table variable (the pump's cage), after the derivatives.
        let states: Vec<String> = a[a.len() - own..].iter().map(|(name, _)| name.clone()).collect();
        let expected: Vec<String> = M::STATE_VARIABLES.iter().map(|s| s.0.to_string()).collect();
        assert_eq!(states, expected);
        assert_eq!(a, b);
        assert!(three.contains("fmiVersion=\"3.0\""));
        // The instantiation token differs from the 2.0 GUID (another interface).
        let guid = reciprocating_drive::fmi2::model_description::guid::<M>();
        assert!(!three.contains(guid));
    }
    check::<ReciprocatingDrive>();
    check::<DriveTrainFmu>();
}
