//! The presets of docs/model.md §8, shipped as SSP parameter-value files (resources/presets/*.ssv):
//! each names only variables of the table with their declared type, sets every parameter (so a
//! preset is a complete machine, independent of the defaults), stays in range, and initializes
//! and runs a revolution through the C ABI.

mod common;
use common::*;
use reciprocating_drive::fmi::variables::{Binding, Causality, VarType};
use reciprocating_drive::fmus::reciprocating_drive::VARIABLES;

/// (preset name, its (name, type, value) entries).
type Preset = (String, Vec<(String, String, String)>);

fn presets() -> Vec<Preset> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/resources/presets");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .expect("resources/presets")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ssv"))
        .map(|p| {
            (
                p.file_stem().unwrap().to_string_lossy().into_owned(),
                parse_ssv(&std::fs::read_to_string(&p).unwrap()),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn the_three_presets_of_physics_md_exist_and_are_complete() {
    let ps = presets();
    let names: Vec<&str> = ps.iter().map(|p| p.0.as_str()).collect();
    assert_eq!(names, ["kvo630", "sk8-3.5-4000", "triplex-1600", "unb600a", "unb600a-simplex"]);
    for (preset, entries) in &ps {
        for (name, ty, value) in entries {
            let var = VARIABLES
                .iter()
                .find(|v| v.name == name)
                .unwrap_or_else(|| panic!("{preset}: unknown {name}"));
            let expect = match var.ty {
                VarType::Real => "Real",
                VarType::Integer => "Integer",
                VarType::Boolean => "Boolean",
            };
            assert_eq!(ty, expect, "{preset}: type of {name}");
            assert!(
                matches!(var.causality, Causality::Parameter | Causality::Input),
                "{preset}: {name} cannot be set"
            );
            if var.ty != VarType::Boolean {
                let v: f64 = value.parse().unwrap();
                assert!(
                    var.causality == Causality::Input || var.range.contains(v),
                    "{preset}: {name} = {v} out of range"
                );
            }
        }
        for var in VARIABLES.iter().filter(|v| matches!(v.binding, Binding::Param { .. })) {
            assert!(entries.iter().any(|e| e.0 == var.name), "{preset} does not set {}", var.name);
        }
    }
}

#[test]
fn each_preset_initializes_and_runs_a_revolution_through_the_c_abi() {
    let api = Api::load();
    for (preset, entries) in presets() {
        let f = Inst::new(&api, &preset);
        assert_eq!(f.enter(), OK);
        let mut speed = None;
        for (name, ty, value) in &entries {
            let r = vr(name);
            let st = match ty.as_str() {
                "Real" => f.set(name, value.parse().unwrap()),
                "Integer" => f.set_int(name, value.parse().unwrap()),
                _ => {
                    let b = (value == "true") as i32;
                    unsafe { (api.fmi2SetBoolean)(f.c, &r, 1, &b) }
                }
            };
            assert_eq!(st, OK, "{preset}: {name}");
            if name == "crank.speed" {
                speed = Some(value.parse::<f64>().unwrap());
            }
        }
        assert_eq!(f.exit(), OK, "{preset}: {}", f.log.last());
        let w = speed.expect("a preset gives the crank speed");
        let h = 1e-3;
        let n = (std::f64::consts::TAU / w / h).ceil() as usize;
        let mut s_max: f64 = 0.0;
        for k in 0..n {
            assert_eq!(f.set("crank.angle", w * k as f64 * h), OK);
            assert_eq!(f.step(k as f64 * h, h), OK, "{preset}: {}", f.log.last());
            s_max = s_max.max(f.get("suspension.position"));
        }
        assert!(s_max > 0.0);
    }
}
