//! FMI 2.0 layer (docs/architecture.md "The FMUs (Rust)").
//!
//! Generates a model's modelDescription.xml from its variable table. The output is deterministic
//! (no generation date), so the checked-in copy under `modelDescription/` can be compared byte for
//! byte with what this produces.

use std::fmt::Write;

use crate::fmi::model::FmuModel;
use crate::fmi::structure::{dependencies_of, derivative_vr, own_state, state_vr};
use crate::fmi::variables::{Binding, Causality, VarType, Variability};
use crate::fmi::xml::{
    bool_attr, categories_and_experiment, causality_name, esc, interface_id, type_attributes, units,
};

const GUID_PLACEHOLDER: &str = "@GUID@";

fn ty_name(t: VarType) -> &'static str {
    match t {
        VarType::Real => "Real",
        VarType::Integer => "Integer",
        VarType::Boolean => "Boolean",
    }
}

/// The knowns the output or state derivative `vr` depends on, as 1-based indices in
/// ModelVariables: its inputs and, for Model Exchange, its continuous states (FMI 2.0 §3.3.1:
/// the knowns of <Outputs> and <Derivatives> are the inputs and the continuous states), the same
/// dependencies as the FMI 3.0 file (`dependencies_of`).
fn dependency_indices<M: FmuModel>(vr: usize) -> Vec<String> {
    let n = M::CONTINUOUS_STATES.len();
    let deps = dependencies_of::<M>(vr).unwrap_or_default();
    deps.iter()
        .map(|&d| match (0..n).find(|&k| state_vr::<M>(k) == d as usize) {
            Some(k) => state_index::<M>(k),
            None => d as usize + 1,
        })
        .map(|i| i.to_string())
        .collect()
}

fn body<M: FmuModel>() -> String {
    let info = M::info();
    let mut x = String::new();
    let w = &mut x;
    let _ = writeln!(w, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        w,
        r#"<fmiModelDescription fmiVersion="2.0" modelName="{}" guid="{GUID_PLACEHOLDER}" description="{}" version="{}" generationTool="reciprocating_drive {}" variableNamingConvention="structured" numberOfEventIndicators="0">"#,
        esc(info.model_name),
        esc(info.description),
        env!("CARGO_PKG_VERSION"),
        env!("CARGO_PKG_VERSION")
    );
    model_exchange_element::<M>(w);
    let _ = writeln!(
        w,
        r#"  <CoSimulation modelIdentifier="{}" needsExecutionTool="false" canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" maxOutputDerivativeOrder="0" canRunAsynchronuously="false" canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="true" canSerializeFMUstate="true" providesDirectionalDerivative="{}"/>"#,
        info.model_identifier,
        bool_attr(M::DIRECTIONAL_DERIVATIVES)
    );
    let _ = writeln!(w, "  <UnitDefinitions>");
    units::<M>(w);
    let _ = writeln!(w, "  </UnitDefinitions>");
    categories_and_experiment::<M>(w);
    let _ = writeln!(w, "  <ModelVariables>");
    for (vr, v) in M::table().variables.iter().enumerate() {
        let causality = causality_name(v.causality);
        let variability = match v.variability {
            Variability::Fixed => "fixed",
            Variability::Tunable => "tunable",
            Variability::Continuous => "continuous",
        };
        let _ = writeln!(w, "    <!-- {} -->", vr + 1);
        let _ = writeln!(
            w,
            r#"    <ScalarVariable name="{}" valueReference="{vr}" causality="{causality}" variability="{variability}" description="{}">"#,
            esc(v.name),
            esc(v.description)
        );
        let attrs = type_attributes(v);
        let _ = writeln!(w, "      <{}{attrs}/>", ty_name(v.ty));
        let _ = writeln!(w, "    </ScalarVariable>");
    }
    derivative_variables::<M>(w);
    let _ = writeln!(w, "  </ModelVariables>");
    let _ = writeln!(w, "  <ModelStructure>");
    let _ = writeln!(w, "    <Outputs>");
    for (vr, v) in M::table().variables.iter().enumerate() {
        if let (Causality::Output, Binding::Output { .. }) = (v.causality, v.binding) {
            let deps = dependency_indices::<M>(vr);
            let kinds: Vec<&str> = deps.iter().map(|_| "dependent").collect();
            let _ = writeln!(
                w,
                r#"      <Unknown index="{}" dependencies="{}" dependenciesKind="{}"/>"#,
                vr + 1,
                deps.join(" "),
                kinds.join(" ")
            );
        }
    }
    let _ = writeln!(w, "    </Outputs>");
    derivatives_structure::<M>(w);
    // Outputs and calculated parameters are computed at initialization from all knowns (inputs
    // and parameters): no `dependencies` attribute means exactly that.
    let _ = writeln!(w, "    <InitialUnknowns>");
    for (vr, v) in M::table().variables.iter().enumerate() {
        if matches!(v.causality, Causality::Output | Causality::CalculatedParameter) {
            let _ = writeln!(w, r#"      <Unknown index="{}"/>"#, vr + 1);
        }
    }
    derivative_initial_unknowns::<M>(w);
    own_state_initial_unknowns::<M>(w);
    let _ = writeln!(w, "    </InitialUnknowns>");
    let _ = writeln!(w, "  </ModelStructure>");
    let _ = writeln!(w, "</fmiModelDescription>");
    x
}

// ------------------------------------------------------------------------------ Model Exchange
// (docs/fmi-interface.md "Model Exchange (FMI 2.0)"): the <ModelExchange> element beside
// <CoSimulation> (same modelIdentifier, one binary), a `der(...)` variable per continuous state
// after the table's (value references as in the FMI 3.0 file), and their <Derivatives>.

fn model_exchange_element<M: FmuModel>(w: &mut String) {
    if !M::MODEL_EXCHANGE {
        return;
    }
    // completedIntegratorStepNotNeeded: the FMU has no events a step could trigger.
    // providesDirectionalDerivative: with the states as knowns and their derivatives as unknowns
    // (`crate::fmi::directional`), as in the FMI 3.0 file.
    let _ = writeln!(
        w,
        r#"  <ModelExchange modelIdentifier="{}" needsExecutionTool="false" completedIntegratorStepNotNeeded="true" canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="true" canSerializeFMUstate="true" providesDirectionalDerivative="{}"/>"#,
        M::info().model_identifier,
        bool_attr(M::DIRECTIONAL_DERIVATIVES)
    );
}

/// The 1-based index in ModelVariables of the variable that is the k-th state (the table's, or
/// its own after the derivatives), and of its derivative (after the table's variables).
fn state_index<M: FmuModel>(k: usize) -> usize {
    match own_state::<M>(k) {
        Some(_) => M::table().variables.len() + M::CONTINUOUS_STATES.len() + 1 + k,
        None => state_vr::<M>(k) + 1,
    }
}

fn derivative_index<M: FmuModel>(k: usize) -> usize {
    M::table().variables.len() + 1 + k
}

fn derivative_variables<M: FmuModel>(w: &mut String) {
    for (k, (state, unit)) in M::CONTINUOUS_STATES.iter().enumerate() {
        let _ = writeln!(w, "    <!-- {} -->", derivative_index::<M>(k));
        let _ = writeln!(
            w,
            r#"    <ScalarVariable name="der({})" valueReference="{}" causality="local" variability="continuous" description="Derivative of {} (Model Exchange)">"#,
            esc(state),
            derivative_vr::<M>(k),
            esc(state)
        );
        let _ = writeln!(
            w,
            r#"      <Real unit="{}" derivative="{}"/>"#,
            esc(unit),
            state_index::<M>(k)
        );
        let _ = writeln!(w, "    </ScalarVariable>");
    }
    // The states that are no table variable (FmuModel::STATE_VARIABLES), after the derivatives.
    for k in 0..M::CONTINUOUS_STATES.len() {
        if let Some((unit, description)) = own_state::<M>(k) {
            let _ = writeln!(w, "    <!-- {} -->", state_index::<M>(k));
            let _ = writeln!(
                w,
                r#"    <ScalarVariable name="{}" valueReference="{}" causality="local" variability="continuous" description="{}">"#,
                esc(M::CONTINUOUS_STATES[k].0),
                state_vr::<M>(k),
                esc(description)
            );
            let _ = writeln!(w, r#"      <Real unit="{}"/>"#, esc(unit));
            let _ = writeln!(w, "    </ScalarVariable>");
        }
    }
}

fn own_state_initial_unknowns<M: FmuModel>(w: &mut String) {
    for k in 0..M::CONTINUOUS_STATES.len() {
        if own_state::<M>(k).is_some() {
            let _ = writeln!(w, r#"      <Unknown index="{}"/>"#, state_index::<M>(k));
        }
    }
}

/// Each derivative's inputs and states ([`FmuModel::DERIVATIVE_DEPENDENCIES`]); not declared:
/// no `dependencies` attribute, each derivative may depend on every state and input.
fn derivatives_structure<M: FmuModel>(w: &mut String) {
    if M::CONTINUOUS_STATES.is_empty() {
        return;
    }
    let _ = writeln!(w, "    <Derivatives>");
    for k in 0..M::CONTINUOUS_STATES.len() {
        if M::DERIVATIVE_DEPENDENCIES.is_empty() {
            let _ = writeln!(w, r#"      <Unknown index="{}"/>"#, derivative_index::<M>(k));
            continue;
        }
        let vr = derivative_vr::<M>(k) as usize;
        let deps = dependency_indices::<M>(vr);
        let kinds: Vec<&str> = deps.iter().map(|_| "dependent").collect();
        let _ = writeln!(
            w,
            r#"      <Unknown index="{}" dependencies="{}" dependenciesKind="{}"/>"#,
            derivative_index::<M>(k),
            deps.join(" "),
            kinds.join(" ")
        );
    }
    let _ = writeln!(w, "    </Derivatives>");
}

fn derivative_initial_unknowns<M: FmuModel>(w: &mut String) {
    for k in 0..M::CONTINUOUS_STATES.len() {
        let _ = writeln!(w, r#"      <Unknown index="{}"/>"#, derivative_index::<M>(k));
    }
}

/// GUID derived from the interface itself: any change to the table changes it, so an importer
/// holding an old modelDescription.xml cannot instantiate a new binary by mistake.
pub fn guid<M: FmuModel>() -> &'static str {
    M::table().guid.get_or_init(|| interface_id(&body::<M>()))
}

/// The complete modelDescription.xml.
pub fn generate<M: FmuModel>() -> String {
    body::<M>().replacen(GUID_PLACEHOLDER, guid::<M>(), 1)
}
