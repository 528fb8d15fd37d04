//! Core layer: Model Exchange evaluation shared by both standards' Model Exchange functions
//! (docs/fmi-interface.md "Model Exchange (FMI 2.0)", "FMI 3.0"): moving the time of an instance
//! and what the model carries forward to it.

use crate::fmi::instance::{Failure, Instance};
use crate::fmi::model::FmuModel;

/// fmi2SetTime and fmi3SetTime: the new time, and what the model carries forward to it
/// ([`FmuModel::time_moved`]: the pump's crank, as between co-simulation steps). Inlined into
/// both callers, its refusals out of line (cold): a solver calls it at every evaluation.
#[inline(always)]
pub fn set_time<M: FmuModel>(
    inst: &mut Instance<M>,
    function: &str,
    time: f64,
) -> Result<(), Failure> {
    if !time.is_finite() {
        return Err(time_not_finite(function, time));
    }
    let from = inst.time();
    let mut carried = true;
    inst.me_update(|t, state| {
        carried = M::time_moved(state, time - *t);
        if carried {
            *t = time;
        }
    });
    if !carried {
        return Err(carry_overflows(function, time, from));
    }
    Ok(())
}

#[cold]
#[inline(never)]
fn time_not_finite(function: &str, time: f64) -> Failure {
    Failure::error(format!("{function}: time = {time}; allowed: a finite number"))
}

#[cold]
#[inline(never)]
fn carry_overflows(function: &str, time: f64, from: f64) -> Failure {
    Failure::error(format!(
        "{function}: time = {}: the crank inputs carried forward from t = {} overflow there; set \
         them at the new time",
        crate::model::error::given(time),
        crate::model::error::num(from)
    ))
}
