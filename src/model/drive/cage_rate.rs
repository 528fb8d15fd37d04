//! The cage equation as a Model Exchange importer's solver sees it: ϑ̈ at one instant, for the
//! crank as the inputs give it and the cage state the solver sets (docs/model.md §6), so that the
//! importer integrates the cage instead of the FMU (docs/fmi-interface.md "Model Exchange").

use super::{Inputs, Mechanism, Model};
use crate::model::crank::CrankState;
use crate::model::elastic_rod::cage::CageState;
use crate::model::error::ModelError;

impl Model {
    /// ϑ̈ of the elastic rod's lower cage at `crank` (not extrapolated: the importer sets the
    /// inputs at every instant it evaluates) and `cage`, with P solved exactly from the beam
    /// column (`Model::instant`, the outputs' own solve: no stiffness table, no shifted
    /// variable, no integrator memory). 0 for a rigid mechanism, which has no cage state.
    pub fn cage_acceleration(
        &self,
        crank: &CrankState,
        inputs: &Inputs,
        cage: &CageState,
    ) -> Result<f64, ModelError> {
        Self::check_inputs(crank, inputs)?;
        let Mechanism::ElasticRodSlider(_, rod) = &self.mechanism else {
            return Ok(0.0);
        };
        let i = self.instant(crank, inputs, cage)?;
        let (bc, loads, _, _) = &i.rod;
        Ok(rod.acceleration(bc, loads, cage))
    }
}
