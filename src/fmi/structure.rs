//! Core layer (standard-independent): how the variables of a model are numbered beyond its
//! variable table, the same in the FMI 2.0 and the FMI 3.0 model description, so a master
//! addresses both standards with the same value references: the independent variable `time`
//! after the table's variables, then the derivatives of the continuous states (Model Exchange),
//! then the states that are no table variable ([`FmuModel::STATE_VARIABLES`]); and which knowns
//! each output and state derivative depends on (`<ModelStructure>` of both files,
//! `fmi3GetVariableDependencies`).

use crate::fmi::model::FmuModel;
use crate::fmi::variables::Binding;

/// The knowns (value references of inputs and continuous states, ascending) the output or state
/// derivative `vr` depends on: the table's `depends_on` and [`FmuModel::OUTPUT_STATES`], or
/// [`FmuModel::DERIVATIVE_DEPENDENCIES`]; None for any other value reference (or a derivative
/// whose dependencies are not declared).
pub fn dependencies_of<M: FmuModel>(vr: usize) -> Option<Vec<u32>> {
    let table = M::table();
    let (inputs, states): (&[M::Input], &[usize]) = match table.variables.get(vr) {
        Some(v) => match v.binding {
            Binding::Output { depends_on, .. } => (depends_on, M::output_states(v.name)),
            _ => return None,
        },
        None => {
            let k =
                (0..M::CONTINUOUS_STATES.len()).find(|&k| derivative_vr::<M>(k) as usize == vr)?;
            let (i, s) = M::DERIVATIVE_DEPENDENCIES.get(k)?;
            (i, s)
        }
    };
    let mut deps: Vec<u32> = inputs
        .iter()
        .filter_map(|s| table.input_vr(*s))
        .chain(states.iter().map(|&k| state_vr::<M>(k)))
        .map(|i| i as u32)
        .collect();
    deps.sort_unstable();
    deps.dedup();
    Some(deps)
}

/// The value reference of the independent variable `time`: the first after the table's.
pub fn time_vr<M: FmuModel>() -> u32 {
    M::table().variables.len() as u32
}

/// The value reference of the derivative of the k-th continuous state (Model Exchange): after
/// `time`'s.
pub fn derivative_vr<M: FmuModel>(k: usize) -> u32 {
    time_vr::<M>() + 1 + k as u32
}

/// The value reference of the variable that is the k-th continuous state: the table's variable
/// of that name, or the state's own variable ([`FmuModel::STATE_VARIABLES`]) after the
/// derivatives.
pub fn state_vr<M: FmuModel>(k: usize) -> usize {
    let name = M::CONTINUOUS_STATES[k].0;
    M::table()
        .variables
        .iter()
        .position(|v| v.name == name)
        .unwrap_or_else(|| derivative_vr::<M>(M::CONTINUOUS_STATES.len() + k) as usize)
}

/// The k-th continuous state's own variable (unit, description), if it is no table variable.
pub fn own_state<M: FmuModel>(k: usize) -> Option<(&'static str, &'static str)> {
    let name = M::CONTINUOUS_STATES[k].0;
    if M::table().variables.iter().any(|v| v.name == name) {
        return None;
    }
    M::STATE_VARIABLES.iter().find(|s| s.0 == name).map(|s| (s.1, s.2))
}
