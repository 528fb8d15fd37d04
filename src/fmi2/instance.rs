//! One FMU instance and the FMI 2.0 co-simulation state machine. Every public method returns
//! `Result<_, Failure>`; the ABI layer turns a failure into its status plus one log line.
//!
//! Error policy: a call that fails leaves the instance exactly as it was (values, time, crank and
//! mode), so a master may correct an input or roll back with fmi2SetFMUstate. Only a caught panic
//! (an internal bug) moves the instance to the terminal Fatal mode.

use serde::{Deserialize, Serialize};
use std::ffi::CString;
use std::path::PathBuf;

use crate::fmi2::logging::{Category, Logger};
use crate::fmi2::variables::{var_info, Binding, Causality, InputSlot, VarType, Variability, VARIABLES};
use crate::model::crank::CrankState;
use crate::model::drive::{Inputs, Model, Outputs, RodState};
use crate::model::integrator::IntegratorStats;
use crate::model::error::ModelError;
use crate::model::params::Params;

/// The states of the FMI 2.0 co-simulation state machine this FMU can be in. It never returns
/// fmi2Pending or fmi2Discard from a step, so "step failed/canceled" do not occur; a failed call
/// leaves the mode unchanged (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Mode {
    Instantiated,
    InitializationMode,
    StepComplete,
    Terminated,
    Fatal,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Severity {
    Discard,
    Error,
    Fatal,
}

/// A failed call: its status and the message that goes to the logger.
#[derive(Clone, Debug, PartialEq)]
pub struct Failure {
    pub severity: Severity,
    pub message: String,
}

impl Failure {
    pub fn error(message: impl Into<String>) -> Failure {
        Failure { severity: Severity::Error, message: message.into() }
    }
    pub fn discard(message: impl Into<String>) -> Failure {
        Failure { severity: Severity::Discard, message: message.into() }
    }
    pub fn illegal(function: &str, mode: Mode) -> Failure {
        Failure::error(format!("{function}: illegal call sequence: not allowed in state {mode:?}"))
    }
}

impl From<ModelError> for Failure {
    fn from(e: ModelError) -> Failure {
        Failure::error(e.to_string())
    }
}

/// Everything an FMU state snapshot holds (get/set and serialization, `fmu_state.rs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Core {
    pub mode: Mode,
    pub time: f64,
    pub tolerance: Option<f64>,
    pub stop_time: Option<f64>,
    /// Values of parameters and inputs indexed by value reference (output slots unused: the
    /// outputs live in `outputs`).
    pub values: Vec<f64>,
    /// The crank as the FMU knows it: the inputs after fmi2SetReal, their extrapolation after a
    /// step (physics.md §2).
    pub crank: CrankState,
    /// The continuous state of an elastic rod (cage angle and rate) and its integrator's memory.
    pub rod: RodState,
    /// The last evaluation. Not serialized: a deserialized state recomputes it on demand.
    #[serde(skip)]
    pub outputs: Outputs,
    /// Whether `outputs` belongs to the current time, inputs, parameters and state.
    pub outputs_valid: bool,
}

impl Core {
    pub fn fresh() -> Core {
        let values: Vec<f64> = VARIABLES.iter().map(|v| v.start().unwrap_or(0.0)).collect();
        let mut core = Core {
            mode: Mode::Instantiated,
            time: 0.0,
            tolerance: None,
            stop_time: None,
            values,
            crank: CrankState::default(),
            rod: RodState::default(),
            outputs: Outputs::default(),
            outputs_valid: false,
        };
        core.crank = core.crank_from_inputs();
        core
    }

    fn input(&self, slot: InputSlot) -> f64 {
        self.values[crate::fmi2::variables::input_vr(slot)]
    }

    fn crank_from_inputs(&self) -> CrankState {
        CrankState {
            angle: self.input(InputSlot::CrankAngle),
            speed: self.input(InputSlot::CrankSpeed),
            acceleration: self.input(InputSlot::CrankAcceleration),
        }
    }

    /// Parameters as currently set, each checked against its declared range.
    pub fn params(&self) -> Result<Params, Failure> {
        let mut p = Params::default();
        for (vr, var) in VARIABLES.iter().enumerate() {
            if let Binding::Param { set, .. } = var.binding {
                let v = self.values[vr];
                if !var.range.contains(v) {
                    return Err(ModelError::out_of_range(var.name, v, var.range.describe(var.unit)).into());
                }
                set(&mut p, v);
            }
        }
        Ok(p)
    }

    fn inputs(&self) -> Inputs {
        Inputs { external_force: self.input(InputSlot::ExternalForce) }
    }

    fn write_outputs(&mut self, out: &Outputs) {
        self.outputs = *out;
        self.outputs_valid = true;
    }
}

/// A saved FMU state (fmi2GetFMUstate). The magic number lets fmi2SetFMUstate refuse a pointer
/// that is not one of ours (as far as that can be told).
#[derive(Clone)]
pub struct Snapshot {
    pub magic: u64,
    pub core: Core,
    pub model: Option<Model>,
}

pub const SNAPSHOT_MAGIC: u64 = 0x5244_4655_5354_4154; // "RDFUSTAT"

pub struct Instance {
    pub logger: Logger,
    pub resource_dir: Option<PathBuf>,
    core: Core,
    /// The validated machine; Some from fmi2ExitInitializationMode on.
    model: Option<Model>,
    /// Work of the cage-equation integrator (diagnostics only, not part of the FMU state).
    pub stats: IntegratorStats,
    /// Where a step evaluates its outputs before they replace the current ones (a failed step
    /// must leave the current ones as they were).
    scratch: Outputs,
}

/// |ϑ| above which the linear theory of the elastic rod is no longer valid (physics.md §6).
const ROD_ANGLE_VALIDITY: f64 = 0.2;

impl Instance {
    pub fn new(logger: Logger, resource_dir: Option<PathBuf>) -> Instance {
        Instance {
            logger,
            resource_dir,
            core: Core::fresh(),
            model: None,
            stats: IntegratorStats::default(),
            scratch: Outputs::default(),
        }
    }

    pub fn time(&self) -> f64 {
        self.core.time
    }

    pub fn set_fatal(&mut self) {
        self.core.mode = Mode::Fatal;
    }

    fn require(&self, function: &str, allowed: &[Mode]) -> Result<(), Failure> {
        if allowed.contains(&self.core.mode) {
            Ok(())
        } else {
            Err(Failure::illegal(function, self.core.mode))
        }
    }

    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: Option<f64>) -> Result<(), Failure> {
        self.require("fmi2SetupExperiment", &[Mode::Instantiated])?;
        if !start.is_finite() {
            return Err(Failure::error(format!("fmi2SetupExperiment: startTime = {start} must be finite")));
        }
        if let Some(t) = tolerance {
            if !(t > 0.0 && t < 1.0) {
                return Err(Failure::error(format!("fmi2SetupExperiment: tolerance = {t}; allowed: (0, 1)")));
            }
        }
        if let Some(s) = stop {
            if s.is_nan() || s < start {
                return Err(Failure::error(format!(
                    "fmi2SetupExperiment: stopTime = {s} must be finite and >= startTime = {start}"
                )));
            }
        }
        self.core.tolerance = tolerance;
        self.core.stop_time = stop;
        self.core.time = start;
        Ok(())
    }

    pub fn enter_initialization_mode(&mut self) -> Result<(), Failure> {
        self.require("fmi2EnterInitializationMode", &[Mode::Instantiated])?;
        self.core.mode = Mode::InitializationMode;
        self.core.outputs_valid = false;
        Ok(())
    }

    /// Validates every parameter (ranges, then the machine as a whole) and evaluates the outputs
    /// at the initial inputs. On failure the instance stays in initialization mode, so the
    /// parameters can be corrected.
    pub fn exit_initialization_mode(&mut self) -> Result<(), Failure> {
        self.require("fmi2ExitInitializationMode", &[Mode::InitializationMode])?;
        let model = Model::new(&self.core.params()?)?;
        let rod = model.initial_rod_state(&self.core.crank, &self.core.inputs())?;
        let out = model.evaluate(&self.core.crank, &self.core.inputs(), &rod)?;
        if model.has_state() && rod.cage.theta.abs() > ROD_ANGLE_VALIDITY {
            self.warn_rod_angle("fmi2ExitInitializationMode", rod.cage.theta);
        }
        self.core.rod = rod;
        self.core.write_outputs(&out);
        self.model = Some(model);
        self.core.mode = Mode::StepComplete;
        Ok(())
    }

    pub fn terminate(&mut self) -> Result<(), Failure> {
        self.require("fmi2Terminate", &[Mode::StepComplete])?;
        self.core.mode = Mode::Terminated;
        Ok(())
    }

    pub fn reset(&mut self) -> Result<(), Failure> {
        self.require(
            "fmi2Reset",
            &[Mode::Instantiated, Mode::InitializationMode, Mode::StepComplete, Mode::Terminated],
        )?;
        self.core = Core::fresh();
        self.model = None;
        Ok(())
    }

    #[inline]
    fn lookup(&self, function: &str, vr: u32, ty: VarType) -> Result<usize, Failure> {
        let i = vr as usize;
        match var_info().get(i) {
            Some(v) if v.ty == ty => Ok(i),
            _ => Err(Self::lookup_failure(function, vr, ty)),
        }
    }

    #[cold]
    fn lookup_failure(function: &str, vr: u32, ty: VarType) -> Failure {
        match VARIABLES.get(vr as usize) {
            Some(v) => Failure::error(format!(
                "{function}: value reference {vr} is \"{}\" of type {:?}, not {ty:?}",
                v.name, v.ty
            )),
            None => Failure::error(format!(
                "{function}: unknown value reference {vr} (valid: 0..{})",
                VARIABLES.len() - 1
            )),
        }
    }

    /// Makes the outputs current: in initialization mode from the parameters as set so far,
    /// afterwards from the validated model.
    fn refresh_outputs(&mut self) -> Result<(), Failure> {
        if self.core.outputs_valid {
            return Ok(());
        }
        let out = match &self.model {
            Some(m) => m.evaluate(&self.core.crank, &self.core.inputs(), &self.core.rod)?,
            None => {
                // Initialization mode: the state the FMU would start from with these values.
                let m = Model::new(&self.core.params()?)?;
                let rod = m.initial_rod_state(&self.core.crank, &self.core.inputs())?;
                m.evaluate(&self.core.crank, &self.core.inputs(), &rod)?
            }
        };
        self.core.write_outputs(&out);
        Ok(())
    }

    /// fmi2GetReal/Integer/Boolean: `out(i, value)` receives the i-th requested value.
    /// Outputs are evaluated at most once per change of time, inputs or parameters.
    pub fn get(&mut self, function: &str, ty: VarType, vrs: &[u32], mut out: impl FnMut(usize, f64)) -> Result<(), Failure> {
        let outputs_available = match self.core.mode {
            Mode::InitializationMode | Mode::StepComplete | Mode::Terminated => true,
            // Parameters and inputs can be read right after instantiation (some importers do).
            Mode::Instantiated => false,
            Mode::Fatal => return Err(Failure::illegal(function, self.core.mode)),
        };
        let info = var_info();
        for (k, &vr) in vrs.iter().enumerate() {
            let i = self.lookup(function, vr, ty)?;
            match info[i].output {
                Some(get) => {
                    if !self.core.outputs_valid {
                        if !outputs_available {
                            return Err(Failure::error(format!(
                                "{function}: output \"{}\" is not available before fmi2EnterInitializationMode",
                                VARIABLES[i].name
                            )));
                        }
                        self.refresh_outputs()?;
                    }
                    out(k, get(&self.core.outputs));
                }
                None => out(k, self.core.values[i]),
            }
        }
        Ok(())
    }

    /// fmi2SetReal/Integer/Boolean. All values are checked before any is stored, so a failing
    /// call changes nothing. Inputs must be finite; a tunable parameter set while stepping is
    /// validated with the whole machine at once; other parameters are validated at
    /// fmi2ExitInitializationMode.
    pub fn set(&mut self, function: &str, ty: VarType, vrs: &[u32], value: impl Fn(usize) -> f64) -> Result<(), Failure> {
        let stepping = match self.core.mode {
            Mode::Instantiated | Mode::InitializationMode => false,
            Mode::StepComplete => true,
            _ => return Err(Failure::illegal(function, self.core.mode)),
        };
        // Fast path, taken at every step by every master: finite values for inputs only.
        let info = var_info();
        let inputs_only = vrs.iter().enumerate().all(|(k, &vr)| {
            matches!(info.get(vr as usize), Some(v) if v.ty == ty && v.slot.is_some()) && value(k).is_finite()
        });
        if inputs_only {
            for (k, &vr) in vrs.iter().enumerate() {
                self.store_value(vr as usize, value(k));
            }
            self.core.outputs_valid = false;
            return Ok(());
        }
        let mut tunable_changed = false;
        for (k, &vr) in vrs.iter().enumerate() {
            let i = self.lookup(function, vr, ty)?;
            let var = &VARIABLES[i];
            let v = value(k);
            match var.causality {
                Causality::Output | Causality::CalculatedParameter => {
                    return Err(Failure::error(format!("{function}: \"{}\" is computed by the FMU and cannot be set", var.name)))
                }
                Causality::Input if !v.is_finite() => {
                    return Err(ModelError::out_of_range(var.name, v, var.range.describe(var.unit)).into())
                }
                Causality::Parameter if stepping => {
                    if var.variability != Variability::Tunable {
                        return Err(Failure::error(format!(
                            "{function}: \"{}\" is a fixed parameter and cannot be changed after initialization",
                            var.name
                        )));
                    }
                    if !var.range.contains(v) {
                        return Err(ModelError::out_of_range(var.name, v, var.range.describe(var.unit)).into());
                    }
                    tunable_changed = true;
                }
                _ => {}
            }
        }
        let saved = tunable_changed.then(|| self.core.values.clone());
        for (k, &vr) in vrs.iter().enumerate() {
            self.store_value(vr as usize, value(k));
        }
        if let Some(saved) = saved {
            match self.core.params().and_then(|p| Model::new(&p).map_err(Failure::from)) {
                Ok(model) => self.model = Some(model),
                Err(e) => {
                    self.core.values = saved;
                    return Err(e);
                }
            }
        }
        self.core.outputs_valid = false;
        Ok(())
    }

    /// Stores a value; for a crank input also updates the crank state the model uses.
    #[inline]
    fn store_value(&mut self, vr: usize, v: f64) {
        self.core.values[vr] = v;
        match var_info()[vr].slot {
            Some(InputSlot::CrankAngle) => self.core.crank.angle = v,
            Some(InputSlot::CrankSpeed) => self.core.crank.speed = v,
            Some(InputSlot::CrankAcceleration) => self.core.crank.acceleration = v,
            _ => {}
        }
    }

    /// fmi2DoStep: advances the crank by the in-step extrapolation of physics.md §2 and evaluates
    /// the outputs at the new communication point. Nothing changes unless everything succeeds.
    pub fn do_step(&mut self, current: f64, h: f64) -> Result<(), Failure> {
        self.require("fmi2DoStep", &[Mode::StepComplete])?;
        if !(h > 0.0 && h.is_finite()) {
            return Err(Failure::error(format!(
                "fmi2DoStep: communicationStepSize = {h}; allowed: a finite number > 0"
            )));
        }
        // Masters accumulate time in floating point; accept their point within a small fraction
        // of the step, but reject a skipped or repeated step.
        let slack = 1e-6 * h + 1e-12 * self.core.time.abs();
        if !current.is_finite() || (current - self.core.time).abs() > slack {
            return Err(Failure::error(format!(
                "fmi2DoStep: currentCommunicationPoint = {current} does not match the FMU's time {} \
                 (roll back with fmi2SetFMUstate to repeat a step)",
                self.core.time
            )));
        }
        let model = self.model.as_ref().ok_or_else(|| Failure::illegal("fmi2DoStep", self.core.mode))?;
        let fail = |e: ModelError| Failure::error(format!("fmi2DoStep from t = {current} s with h = {h} s failed: {e}"));
        let inputs = self.core.inputs();
        // The master's tolerance (fmi2SetupExperiment) wins over solver.tolerance (§6).
        let tol = self.core.tolerance.unwrap_or_else(|| model.default_tolerance());
        let mut stats = self.stats;
        let rod = if model.has_state() {
            model.step(&self.core.crank, &inputs, &self.core.rod, h, tol, &mut stats).map_err(fail)?
        } else {
            self.core.rod
        };
        let crank = self.core.crank.extrapolate(h);
        model.evaluate_into(&crank, &inputs, &rod, &mut self.scratch).map_err(fail)?;
        let warn = model.has_state()
            && rod.cage.theta.abs() > ROD_ANGLE_VALIDITY
            && self.core.rod.cage.theta.abs() <= ROD_ANGLE_VALIDITY;
        self.core.crank = crank;
        self.core.rod = rod;
        self.core.time = current + h;
        std::mem::swap(&mut self.core.outputs, &mut self.scratch);
        self.core.outputs_valid = true;
        self.stats = stats;
        if warn {
            self.warn_rod_angle("fmi2DoStep", rod.cage.theta);
        }
        Ok(())
    }

    /// The elastic rod's cage angle left the range of the linear theory (§6 "Validity"): warned
    /// when it starts there and whenever a step crosses the limit.
    fn warn_rod_angle(&self, function: &str, theta: f64) {
        self.logger.log(
            fmi_sys::fmi2::fmi2Status_fmi2Warning,
            Category::Warning,
            &format!(
                "{function}: at t = {} s the cage angle rod.angle = {theta} rad exceeds {ROD_ANGLE_VALIDITY} rad: \
                 the linear theory of the elastic rod (physics.md §6) is no longer valid",
                self.core.time
            ),
        );
    }

    pub fn snapshot(&self) -> Snapshot {
        Snapshot { magic: SNAPSHOT_MAGIC, core: self.core.clone(), model: self.model.clone() }
    }

    pub fn restore(&mut self, s: &Snapshot) -> Result<(), Failure> {
        if self.core.mode == Mode::Fatal {
            return Err(Failure::illegal("fmi2SetFMUstate", self.core.mode));
        }
        if s.magic != SNAPSHOT_MAGIC {
            return Err(Failure::error("fmi2SetFMUstate: the state was not made by this FMU"));
        }
        self.core = s.core.clone();
        self.model = s.model.clone();
        Ok(())
    }

    /// Rebuilds a snapshot from deserialized data, validating it as untrusted input.
    pub fn snapshot_from_core(core: Core) -> Result<Snapshot, Failure> {
        let bad = |what: &str| Failure::error(format!("fmi2DeSerializeFMUstate: invalid state: {what}"));
        if core.values.len() != VARIABLES.len() {
            return Err(bad("wrong number of variables"));
        }
        if !core.time.is_finite() || core.mode == Mode::Fatal {
            return Err(bad("time or mode"));
        }
        let r = &core.rod;
        if ![r.cage.theta, r.cage.rate, r.integrator.h_next, r.integrator.err_prev].iter().all(|v| v.is_finite()) {
            return Err(bad("elastic-rod state"));
        }
        // The outputs are not part of the serialized form: recompute them when asked.
        let core = Core { outputs_valid: false, ..core };
        for (v, var) in core.values.iter().zip(VARIABLES) {
            let integral = matches!(var.ty, VarType::Integer | VarType::Boolean);
            if integral && !(v.fract() == 0.0 && v.abs() <= i32::MAX as f64) {
                return Err(bad(var.name));
            }
        }
        let model = match core.mode {
            Mode::StepComplete | Mode::Terminated => Some(Model::new(&core.params()?)?),
            _ => None,
        };
        Ok(Snapshot { magic: SNAPSHOT_MAGIC, core, model })
    }

    #[inline]
    pub fn log(&self, status: fmi_sys::fmi2::fmi2Status, category: Category, message: &str) {
        self.logger.log(status, category, message);
    }
}

/// Instance names are copied (the importer's string may not outlive the call).
pub fn copy_name(name: &str) -> CString {
    CString::new(name.replace('\0', " ")).unwrap_or_default()
}
