//! Core layer: what both model-description writers (`fmi2::model_description`,
//! `fmi3::model_description`) write alike: text helpers, the units, the log categories and the
//! default experiment, a variable's causality and its type's attributes (unit, display unit,
//! range, start value), all from the one variable table.

use std::fmt::Write;

use crate::fmi::display_units;
use crate::fmi::logging::CATEGORIES;
use crate::fmi::model::FmuModel;
use crate::fmi::variables::{Causality, Var, VarType};

/// Text escaped for an XML attribute value.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// xs:double text that round-trips (Rust's shortest representation).
pub fn num(v: f64) -> String {
    format!("{v:?}")
}

/// An xs:boolean attribute value, e.g. `providesDirectionalDerivative(s)` of both standards
/// ([`FmuModel::DIRECTIONAL_DERIVATIVES`](crate::fmi::model::FmuModel::DIRECTIONAL_DERIVATIVES)).
pub fn bool_attr(b: bool) -> &'static str {
    if b {
        "true"
    } else {
        "false"
    }
}

/// The `<Unit>` elements of `<UnitDefinitions>`: each unit of the table with its SI base-unit
/// exponents and its display units.
pub fn units<M: FmuModel>(w: &mut String) {
    for (name, [kg, m, s, rad]) in M::table().units {
        let mut attrs = String::new();
        for (sym, e) in [("kg", kg), ("m", m), ("s", s), ("rad", rad)] {
            if *e != 0 {
                let _ = write!(attrs, r#" {sym}="{e}""#);
            }
        }
        let mut display = String::new();
        for d in display_units::for_unit(name) {
            let _ = write!(
                display,
                r#"<DisplayUnit name="{}" factor="{}"/>"#,
                esc(d.name),
                num(d.factor)
            );
        }
        let _ = writeln!(w, r#"    <Unit name="{}"><BaseUnit{attrs}/>{display}</Unit>"#, esc(name));
    }
}

/// `<LogCategories>` and `<DefaultExperiment>`.
pub fn categories_and_experiment<M: FmuModel>(w: &mut String) {
    let (start, stop, step) = M::info().default_experiment;
    let _ = writeln!(w, "  <LogCategories>");
    for (name, desc) in CATEGORIES {
        let _ = writeln!(w, r#"    <Category name="{name}" description="{}"/>"#, esc(desc));
    }
    let _ = writeln!(w, "  </LogCategories>");
    let _ = writeln!(
        w,
        r#"  <DefaultExperiment startTime="{}" stopTime="{}" stepSize="{}"/>"#,
        num(start),
        num(stop),
        num(step)
    );
}

/// The `causality` attribute's value.
pub fn causality_name(c: Causality) -> &'static str {
    match c {
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
        Causality::Input => "input",
        Causality::Output => "output",
    }
}

/// The attributes of a variable's type element: unit and display unit (Real), range (not
/// Boolean), start value.
pub fn type_attributes<M: FmuModel>(v: &Var<M>) -> String {
    let mut attrs = String::new();
    if v.ty == VarType::Real && !v.unit.is_empty() {
        let _ = write!(attrs, r#" unit="{}""#, esc(v.unit));
        if let Some(d) = display_units::default_for(v.unit) {
            let _ = write!(attrs, r#" displayUnit="{}""#, esc(d));
        }
    }
    if v.ty != VarType::Boolean {
        let fmt = |b: f64| if v.ty == VarType::Integer { format!("{}", b as i64) } else { num(b) };
        if v.range.min.is_finite() {
            let _ = write!(attrs, r#" min="{}""#, fmt(v.range.min));
        }
        if v.range.max.is_finite() {
            let _ = write!(attrs, r#" max="{}""#, fmt(v.range.max));
        }
    }
    if let Some(s) = v.start() {
        let text = match v.ty {
            VarType::Real => num(s),
            VarType::Integer => format!("{}", s as i64),
            VarType::Boolean => (if s != 0.0 { "true" } else { "false" }).to_string(),
        };
        let _ = write!(attrs, r#" start="{text}""#);
    }
    attrs
}

/// The GUID (FMI 2.0) or instantiationToken (FMI 3.0) of a model description, derived from its
/// text (`body`, with the identifier's placeholder) by two FNV-1a hashes: any change to the
/// interface changes it, so an importer holding an old modelDescription.xml cannot instantiate a
/// new binary by mistake.
pub fn interface_id(body: &str) -> String {
    let h = |seed: u64| {
        body.bytes().fold(seed, |h, c| (h ^ c as u64).wrapping_mul(0x0000_0100_0000_01b3))
    };
    let (a, c) = (h(0xcbf2_9ce4_8422_2325), h(0x84222325cbf29ce4));
    format!(
        "{{{:08x}-{:04x}-{:04x}-{:04x}-{:012x}}}",
        a >> 32,
        (a >> 16) & 0xffff,
        a & 0xffff,
        c >> 48,
        c & 0xffff_ffff_ffff
    )
}
