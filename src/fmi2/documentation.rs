//! An FMU's documentation/index.html: the model's own text (its conventions) and the variable
//! list, generated from the variable table so it cannot drift from the interface.

use std::fmt::Write;

use crate::fmi2::model::FmuModel;
use crate::fmi2::variables::{Causality, VarType, Variability};

pub fn generate<M: FmuModel>() -> String {
    let info = M::info();
    let mut h = String::new();
    let _ = writeln!(h, "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{} FMU</title>", info.model_name);
    h.push_str("<style>body{font-family:sans-serif;max-width:70em;margin:auto}td,th{border:1px solid #ccc;padding:2px 6px;vertical-align:top}table{border-collapse:collapse}code{background:#f4f4f4}</style>\n");
    let _ = writeln!(h, "</head><body>\n<h1>{}</h1>", info.model_name);
    h.push_str(info.documentation);
    h.push_str("\n<h2>Variables</h2>\n<table><tr><th>name</th><th>vr</th><th>causality</th><th>type</th><th>unit</th><th>start</th><th>allowed</th><th>description</th></tr>\n");
    for (vr, v) in M::table().variables.iter().enumerate() {
        let causality = match (v.causality, v.variability) {
            (Causality::Parameter, Variability::Tunable) => "parameter (tunable)",
            (Causality::Parameter, _) => "parameter",
            (Causality::CalculatedParameter, _) => "calculated parameter",
            (Causality::Input, _) => "input",
            (Causality::Output, _) => "output",
        };
        let start = v.start().map(|s| format!("{s}")).unwrap_or_default();
        let allowed = if v.causality == Causality::Parameter { v.range.describe("") } else { String::new() };
        let ty = match v.ty {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Boolean => "Boolean",
        };
        let _ = writeln!(
            h,
            "<tr><td><code>{}</code></td><td>{vr}</td><td>{causality}</td><td>{ty}</td><td>{}</td><td>{start}</td><td>{}</td><td>{}</td></tr>",
            v.name,
            v.unit,
            allowed.replace("a finite number in ", ""),
            v.description.replace('&', "&amp;").replace('<', "&lt;")
        );
    }
    h.push_str("</table>\n</body></html>\n");
    h
}
