//! FMI 3.0 layer (docs/architecture.md "The FMUs (Rust)").
//!
//! Generates a model's FMI 3.0 modelDescription.xml from the same variable table as the FMI 2.0
//! one (the FMI 2.0 writer): names, value references, units and display units,
//! descriptions, causality, variability, ranges, start values and output dependencies come from
//! the one table, so the two descriptions cannot disagree (docs/fmi-interface.md "FMI 3.0").
//! Deterministic (no generation date): the checked-in copy under `modelDescription/fmi3/` is
//! compared byte for byte with what this produces.
//!
//! What differs from 2.0 is only the dialect: one element per type (`<Float64>`, `<Int32>`,
//! `<Boolean>`) instead of `<ScalarVariable>`, `instantiationToken` instead of `guid`, and
//! ModelStructure naming value references instead of 1-based indices.

use std::fmt::Write;

use crate::fmi::model::FmuModel;
use crate::fmi::structure::{dependencies_of, derivative_vr, own_state, state_vr, time_vr};
use crate::fmi::variables::{Binding, Causality, VarType, Variability};
use crate::fmi::xml::{
    bool_attr, categories_and_experiment, causality_name, esc, interface_id, type_attributes, units,
};

const TOKEN_PLACEHOLDER: &str = "@TOKEN@";

fn ty_name(t: VarType) -> &'static str {
    match t {
        VarType::Real => "Float64",
        VarType::Integer => "Int32",
        VarType::Boolean => "Boolean",
    }
}

fn body<M: FmuModel>() -> String {
    let info = M::info();
    let table = M::table();
    let mut x = String::new();
    let w = &mut x;
    let _ = writeln!(w, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        w,
        r#"<fmiModelDescription fmiVersion="3.0" modelName="{}" instantiationToken="{TOKEN_PLACEHOLDER}" description="{}" version="{}" generationTool="reciprocating_drive {}" variableNamingConvention="structured">"#,
        esc(info.model_name),
        esc(info.description),
        env!("CARGO_PKG_VERSION"),
        env!("CARGO_PKG_VERSION")
    );
    if M::MODEL_EXCHANGE {
        let _ = writeln!(
            w,
            r#"  <ModelExchange modelIdentifier="{}" needsExecutionTool="false" canBeInstantiatedOnlyOncePerProcess="false" canGetAndSetFMUState="true" canSerializeFMUState="true" providesDirectionalDerivatives="{}" providesAdjointDerivatives="false" needsCompletedIntegratorStep="false" providesEvaluateDiscreteStates="false"/>"#,
            info.model_identifier,
            bool_attr(M::DIRECTIONAL_DERIVATIVES)
        );
    }
    let _ = writeln!(
        w,
        r#"  <CoSimulation modelIdentifier="{}" needsExecutionTool="false" canBeInstantiatedOnlyOncePerProcess="false" canGetAndSetFMUState="true" canSerializeFMUState="true" providesDirectionalDerivatives="{}" providesAdjointDerivatives="false" canHandleVariableCommunicationStepSize="true" maxOutputDerivativeOrder="0" providesIntermediateUpdate="false" mightReturnEarlyFromDoStep="false" canReturnEarlyAfterIntermediateUpdate="false" hasEventMode="false"/>"#,
        info.model_identifier,
        bool_attr(M::DIRECTIONAL_DERIVATIVES)
    );
    let _ = writeln!(w, "  <UnitDefinitions>");
    units::<M>(w);
    // The unit of the independent variable `time`, unless the table has it already.
    if !table.units.iter().any(|(name, _)| *name == "s") {
        let _ = writeln!(w, r#"    <Unit name="s"><BaseUnit s="1"/></Unit>"#);
    }
    let _ = writeln!(w, "  </UnitDefinitions>");
    categories_and_experiment::<M>(w);
    let _ = writeln!(w, "  <ModelVariables>");
    // FMI 3.0 requires the independent variable; it takes the value reference after the table's.
    let _ = writeln!(
        w,
        r#"    <Float64 name="time" valueReference="{}" causality="independent" variability="continuous" description="Simulation time" unit="s"/>"#,
        time_vr::<M>()
    );
    for (vr, v) in table.variables.iter().enumerate() {
        let causality = causality_name(v.causality);
        // FMI 3.0 allows "continuous" for Float variables only; an Int32 or Boolean input or
        // output changes only at communication points (discrete).
        let variability = match (v.variability, v.ty) {
            (Variability::Fixed, _) => "fixed",
            (Variability::Tunable, _) => "tunable",
            (Variability::Continuous, VarType::Real) => "continuous",
            (Variability::Continuous, _) => "discrete",
        };
        let attrs = type_attributes(v);
        let _ = writeln!(
            w,
            r#"    <{} name="{}" valueReference="{vr}" causality="{causality}" variability="{variability}" description="{}"{attrs}/>"#,
            ty_name(v.ty),
            esc(v.name),
            esc(v.description)
        );
    }
    // Model Exchange: the derivative of each continuous state, after `time`.
    for (k, (state, unit)) in M::CONTINUOUS_STATES.iter().enumerate() {
        let _ = writeln!(
            w,
            r#"    <Float64 name="der({})" valueReference="{}" causality="local" variability="continuous" description="Derivative of {} (Model Exchange)" unit="{}" derivative="{}"/>"#,
            esc(state),
            derivative_vr::<M>(k),
            esc(state),
            esc(unit),
            state_vr::<M>(k)
        );
    }
    own_state_variables::<M>(w);
    let _ = writeln!(w, "  </ModelVariables>");
    let _ = writeln!(w, "  <ModelStructure>");
    for (vr, v) in table.variables.iter().enumerate() {
        if let (Causality::Output, Binding::Output { .. }) = (v.causality, v.binding) {
            let deps: Vec<String> = dependencies::<M>(vr).iter().map(|i| i.to_string()).collect();
            let kinds: Vec<&str> = deps.iter().map(|_| "dependent").collect();
            let _ = writeln!(
                w,
                r#"    <Output valueReference="{vr}" dependencies="{}" dependenciesKind="{}"/>"#,
                deps.join(" "),
                kinds.join(" ")
            );
        }
    }
    for k in 0..M::CONTINUOUS_STATES.len() {
        let vr = derivative_vr::<M>(k);
        if M::DERIVATIVE_DEPENDENCIES.is_empty() {
            let _ = writeln!(w, r#"    <ContinuousStateDerivative valueReference="{vr}"/>"#);
            continue;
        }
        let deps: Vec<String> =
            dependencies::<M>(vr as usize).iter().map(|i| i.to_string()).collect();
        let kinds: Vec<&str> = deps.iter().map(|_| "dependent").collect();
        let _ = writeln!(
            w,
            r#"    <ContinuousStateDerivative valueReference="{vr}" dependencies="{}" dependenciesKind="{}"/>"#,
            deps.join(" "),
            kinds.join(" ")
        );
    }
    // Outputs and calculated parameters are computed at initialization from all knowns (inputs
    // and parameters): no `dependencies` attribute means exactly that (as in the 2.0 file).
    for (vr, v) in table.variables.iter().enumerate() {
        if matches!(v.causality, Causality::Output | Causality::CalculatedParameter) {
            let _ = writeln!(w, r#"    <InitialUnknown valueReference="{vr}"/>"#);
        }
    }
    for k in 0..M::CONTINUOUS_STATES.len() {
        let _ = writeln!(w, r#"    <InitialUnknown valueReference="{}"/>"#, derivative_vr::<M>(k));
    }
    for k in (0..M::CONTINUOUS_STATES.len()).filter(|&k| own_state::<M>(k).is_some()) {
        let _ = writeln!(w, r#"    <InitialUnknown valueReference="{}"/>"#, state_vr::<M>(k));
    }
    let _ = writeln!(w, "  </ModelStructure>");
    let _ = writeln!(w, "</fmiModelDescription>");
    x
}

fn dependencies<M: FmuModel>(vr: usize) -> Vec<u32> {
    dependencies_of::<M>(vr).unwrap_or_default()
}

/// Model Exchange: the states that are no table variable, as local continuous variables.
fn own_state_variables<M: FmuModel>(w: &mut String) {
    for k in 0..M::CONTINUOUS_STATES.len() {
        if let Some((unit, description)) = own_state::<M>(k) {
            let _ = writeln!(
                w,
                r#"    <Float64 name="{}" valueReference="{}" causality="local" variability="continuous" description="{}" unit="{}"/>"#,
                esc(M::CONTINUOUS_STATES[k].0),
                state_vr::<M>(k),
                esc(description),
                esc(unit)
            );
        }
    }
}

/// The instantiationToken, derived from the 3.0 interface itself (as the 2.0 GUID is from the
/// 2.0 one): any change to the table changes it, so an importer holding an old
/// modelDescription.xml cannot instantiate a new binary by mistake.
pub fn token<M: FmuModel>() -> &'static str {
    M::table().token3.get_or_init(|| interface_id(&body::<M>()))
}

/// The complete FMI 3.0 modelDescription.xml.
pub fn generate<M: FmuModel>() -> String {
    body::<M>().replacen(TOKEN_PLACEHOLDER, token::<M>(), 1)
}
