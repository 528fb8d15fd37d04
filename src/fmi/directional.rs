//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! The glue of `fmi2GetDirectionalDerivative` and `fmi3GetDirectionalDerivative`
//! (docs/fmi-interface.md "Directional derivatives"), for any instance kind: value references
//! resolved and checked, the model's exact tangent ([`FmuModel::tangent`]) evaluated once for
//! the whole seed, the unknowns read from it. The standard's meaning: `dvUnknown = J·dvKnown`,
//! J the partial derivatives of the unknowns with respect to the knowns at the current inputs
//! and continuous states. The states are knowns (and their derivatives unknowns) in both
//! interfaces: the one `<ModelStructure>` of an FMI 2.0 file (and of an FMI 3.0 one) lists them
//! among the outputs' dependencies, and the knowns at a communication point are "inputs,
//! continuous states and independent variable" (FMI 2.0 schema, fmi2VariableDependency); a loop
//! solver such as OMSimulator's passes every listed dependency as a known, seeding the one it
//! wants (docs/closed-loop.md "In OMSimulator"). In co-simulation the state is the one the
//! instance holds at its communication point.

use crate::fmi::instance::{Failure, Instance, Mode};
use crate::fmi::model::FmuModel;
use crate::fmi::structure::derivative_vr;
use crate::fmi::variables::Causality;
use crate::model::error::num;

/// How an importer's value references map onto the continuous states of a Model Exchange
/// instance, which each standard numbers its own way (`crate::fmi::structure`).
pub struct StateRefs<'a> {
    /// The index of the continuous state whose value reference this is, if any.
    pub state: &'a dyn Fn(u32) -> Option<usize>,
    /// The index of the continuous state whose derivative has this value reference, if any.
    pub derivative: &'a dyn Fn(u32) -> Option<usize>,
}

/// The index of the continuous state whose variable has value reference `vr`: the same number
/// in the FMI 2.0 and the FMI 3.0 model description (`crate::fmi::structure`).
fn state_of<M: FmuModel>(vr: u32) -> Option<usize> {
    // From the table's cached list: looking the names up at every call cost about 2 700
    // instructions per derivative (docs/performance.md "Directional derivatives").
    M::table().state_vrs().iter().position(|&s| s == vr as usize)
}

/// The index of the continuous state whose derivative has value reference `vr` (both
/// standards).
fn derivative_of<M: FmuModel>(vr: u32) -> Option<usize> {
    (0..M::CONTINUOUS_STATES.len()).find(|&k| derivative_vr::<M>(k) == vr)
}

/// The continuous states and their derivatives as knowns and unknowns: both standards number
/// them alike, so `fmi2GetDirectionalDerivative` and `fmi3GetDirectionalDerivative` address the
/// same partials, in co-simulation and in Model Exchange.
pub fn model_exchange_refs<M: FmuModel>() -> StateRefs<'static> {
    StateRefs { state: &state_of::<M>, derivative: &derivative_of::<M> }
}

/// Tables up to this many variables keep the seed on the stack.
const STACK_VALUES: usize = 256;
/// Continuous states a model may have here.
const MAX_STATES: usize = 8;

fn name<M: FmuModel>(vr: u32) -> String {
    match M::table().variables.get(vr as usize) {
        Some(v) => format!("{vr} (\"{}\")", v.name),
        None => vr.to_string(),
    }
}

/// `sensitivity[i]` = the change of `unknowns[i]` for the inputs and states `knowns` changing by
/// `seed`. Every argument is checked before anything is evaluated; a failure names the array,
/// the index, the value reference and what is allowed, and changes nothing.
pub fn directional_derivative<M: FmuModel>(
    inst: &Instance<M>,
    function: &str,
    unknowns: &[u32],
    knowns: &[u32],
    seed: &[f64],
    sensitivity: &mut [f64],
    refs: &StateRefs,
) -> Result<(), Failure> {
    if !M::DIRECTIONAL_DERIVATIVES {
        return Err(Failure::error(format!("{function}: not provided by this FMU")));
    }
    if inst.mode() == Mode::Fatal {
        return Err(Failure::illegal(function, Mode::Fatal));
    }
    let n_states = M::CONTINUOUS_STATES.len();
    // Model Exchange and co-simulation alike (module doc).
    let states_known = n_states > 0;
    let what_known = if states_known { "an input or a continuous state" } else { "an input" };
    let table = M::table();
    let info = table.info();
    let Some((built, values, state)) = inst.me_parts() else {
        return Err(Failure::error(format!(
            "{function}: only after the end of initialization (the machine is built there)"
        )));
    };
    // On the stack for the tables of this crate (a heap allocation per call costs as much as a
    // quarter of the derivative itself, docs/performance.md "Directional derivatives").
    let (mut values_stack, mut values_heap) = ([0.0; STACK_VALUES], Vec::new());
    let d_values: &mut [f64] = if values.len() <= STACK_VALUES {
        &mut values_stack[..values.len()]
    } else {
        values_heap.resize(values.len(), 0.0);
        &mut values_heap
    };
    let mut d_states = [0.0; MAX_STATES];
    let mut d_derivatives = [0.0; MAX_STATES];
    if n_states > MAX_STATES {
        return Err(Failure::error(format!(
            "{function}: more than {MAX_STATES} continuous states (internal limit)"
        )));
    }
    let (d_states, d_derivatives) = (&mut d_states[..n_states], &mut d_derivatives[..n_states]);
    for (i, (&vr, &dv)) in knowns.iter().zip(seed).enumerate() {
        if !dv.is_finite() {
            return Err(Failure::error(format!(
                "{function}: seed[{i}] = {} for value reference {} is not finite",
                num(dv),
                name::<M>(vr)
            )));
        }
        match (info.get(vr as usize), (refs.state)(vr)) {
            (_, Some(k)) if states_known && k < n_states => d_states[k] += dv,
            (Some(v), _) if v.causality == Causality::Input => d_values[vr as usize] += dv,
            _ => {
                return Err(Failure::error(format!(
                    "{function}: known[{i}] = value reference {} is not {what_known}",
                    name::<M>(vr)
                )))
            }
        }
    }
    // The unknowns: outputs of the table, or state derivatives (Model Exchange).
    for (i, &vr) in unknowns.iter().enumerate() {
        let is_output = info
            .get(vr as usize)
            .is_some_and(|v| v.causality == Causality::Output && v.output.is_some());
        let is_derivative = states_known && (refs.derivative)(vr).is_some_and(|k| k < n_states);
        if !is_output && !is_derivative {
            return Err(Failure::error(format!(
                "{function}: unknown[{i}] = value reference {} is not an output{}",
                name::<M>(vr),
                if states_known { " or a state derivative" } else { "" }
            )));
        }
    }
    // A machine without exact state partials refuses any call that needs one.
    // A state listed with seed 0 (a loop solver passes every dependency) needs no state partial.
    let needs_states =
        knowns.iter().zip(seed).any(|(&vr, &dv)| dv != 0.0 && (refs.state)(vr).is_some())
            || unknowns.iter().any(|&vr| (refs.derivative)(vr).is_some());
    if let Some(why) = M::state_partials_refusal(built).filter(|_| states_known && needs_states) {
        return Err(Failure::error(format!("{function}: {why}")));
    }
    let mut tangent = M::Outputs::default();
    M::tangent(built, values, state, d_values, d_states, &mut tangent, d_derivatives)
        .map_err(|e| Failure::error(format!("{function}: {e}")))?;
    for (i, &vr) in unknowns.iter().enumerate() {
        let v = match info.get(vr as usize).and_then(|v| v.output) {
            Some(get) => M::read(&tangent, get).unwrap_or(f64::NAN),
            None => (refs.derivative)(vr).map_or(f64::NAN, |k| d_derivatives[k]),
        };
        if !v.is_finite() {
            return Err(Failure::error(format!(
                "{function}: the derivative of value reference {} is not finite ({}) here",
                name::<M>(vr),
                num(v)
            )));
        }
        sensitivity[i] = v;
    }
    Ok(())
}
