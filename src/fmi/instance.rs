//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! One FMU instance and the FMI 2.0 co-simulation state machine. Every public method returns
//! `Result<_, Failure>`; the ABI layer turns a failure into its status plus one log line.
//!
//! Generic over the model ([`FmuModel`]): the same state machine serves every FMU of the crate.
//!
//! Error policy: a call that fails leaves the instance exactly as it was (values, time, state and
//! mode), so a master may correct an input or roll back with fmi2SetFMUstate. Only a caught panic
//! (an internal bug) moves the instance to the terminal Fatal mode.

use serde::{Deserialize, Serialize};
use std::ffi::CString;
use std::path::PathBuf;

use crate::fmi::logging::{Category, Logger};
use crate::fmi::model::FmuModel;
use crate::fmi::plans::{InputPlan, ReadPlan, Source};
use crate::fmi::variables::{Binding, Causality, Range, VarType, Variability};
use crate::model::error::{given, num, ModelError};

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
    #[cold]
    #[inline(never)]
    pub fn illegal(function: &str, mode: Mode) -> Failure {
        // The state as FMI 2.0's state machine names it, and what the importer can do from there.
        let (state, hint) = match mode {
            Mode::Instantiated => (
                "instantiated",
                "initialize first (fmi2SetupExperiment, fmi2EnterInitializationMode, \
                 fmi2ExitInitializationMode)",
            ),
            Mode::InitializationMode => (
                "initializationMode",
                "fmi2ExitInitializationMode has not succeeded (a failed one leaves the instance \
                 here: set valid values and call it again, or fmi2Reset, or fmi2FreeInstance)",
            ),
            Mode::StepComplete => (
                "stepComplete",
                "the instance is initialized; fmi2Reset returns it to instantiated",
            ),
            Mode::Terminated => ("terminated", "only fmi2Reset or fmi2FreeInstance remain"),
            Mode::Fatal => {
                ("fatal", "an earlier call failed fatally; only fmi2FreeInstance remains")
            }
        };
        Failure::error(format!(
            "{function}: illegal call sequence: not allowed in state {state}: {hint}"
        ))
    }
}

impl From<ModelError> for Failure {
    fn from(e: ModelError) -> Failure {
        Failure::error(e.to_string())
    }
}

/// Everything an FMU state snapshot holds (get/set and serialization, `fmu_state.rs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Core<S> {
    pub mode: Mode,
    pub time: f64,
    pub tolerance: Option<f64>,
    pub stop_time: Option<f64>,
    /// Values of parameters and inputs indexed by value reference (output slots unused: the
    /// outputs live in the model's cache).
    pub values: Vec<f64>,
    /// The model's state ([`FmuModel::State`]).
    pub state: S,
    /// Whether the model's output cache belongs to the current time, inputs, parameters and state.
    /// A cache flag, not state: serialized as false (deserialized states recompute their outputs),
    /// so that reading outputs, which may evaluate them on demand, never changes the serialized
    /// state. The byte layout is that of a plain bool.
    #[serde(serialize_with = "serialize_as_stale")]
    pub outputs_valid: bool,
}

fn serialize_as_stale<S: serde::Serializer>(_: &bool, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_bool(false)
}

impl<S> Core<S> {
    pub fn fresh<M: FmuModel<State = S>>() -> Core<S> {
        let values: Vec<f64> =
            M::table().variables.iter().map(|v| v.start().unwrap_or(0.0)).collect();
        let state = M::fresh_state(&values);
        Core {
            mode: Mode::Instantiated,
            time: 0.0,
            tolerance: None,
            stop_time: None,
            values,
            state,
            outputs_valid: false,
        }
    }

    /// Parameters as currently set, each checked against its declared range.
    pub fn params<M: FmuModel<State = S>>(&self) -> Result<M::Params, Failure> {
        let mut p = M::Params::default();
        for (vr, var) in M::table().variables.iter().enumerate() {
            if let Binding::Param { set, .. } = var.binding {
                let v = self.values[vr];
                if !var.range.contains(v) {
                    return Err(ModelError::out_of_range(var.name, v, var.allowed()).into());
                }
                set(&mut p, v);
            }
        }
        Ok(p)
    }
}

/// A saved FMU state (fmi2GetFMUstate). The magic number lets fmi2SetFMUstate refuse a pointer
/// that is not one of ours (as far as that can be told); `repr(C)` keeps it the first field for
/// every model.
#[repr(C)]
pub struct Snapshot<M: FmuModel> {
    pub magic: u64,
    pub core: Core<M::State>,
    outputs: M::Outputs,
    model: Option<M::Built>,
    provisional: Option<(M::Built, M::State)>,
}

impl<M: FmuModel> Clone for Snapshot<M> {
    fn clone(&self) -> Self {
        Snapshot {
            magic: self.magic,
            core: self.core.clone(),
            outputs: self.outputs.clone(),
            model: self.model.clone(),
            provisional: self.provisional.clone(),
        }
    }
}

pub const SNAPSHOT_MAGIC: u64 = 0x5244_4655_5354_4154; // "RDFUSTAT"

/// The snapshot magic of model `M`: a state of another model (another FMU loaded in the same
/// process) is refused.
pub fn snapshot_magic<M: FmuModel>() -> u64 {
    SNAPSHOT_MAGIC ^ crate::fmi::fmu_state::interface_fingerprint::<M>()
}

pub struct Instance<M: FmuModel> {
    pub logger: Logger,
    pub resource_dir: Option<PathBuf>,
    core: Core<M::State>,
    /// The model's output cache (valid when `core.outputs_valid`).
    outputs: M::Outputs,
    /// The validated machine; Some from fmi2ExitInitializationMode on.
    model: Option<M::Built>,
    /// In initialization mode: the machine and initial state the current values would give,
    /// built for fmi2GetReal of an output; dropped whenever the outputs become invalid.
    provisional: Option<(M::Built, M::State)>,
    /// Work of the model's integrator (diagnostics only, not part of the FMU state).
    pub stats: M::Stats,
    /// Where a step evaluates its outputs before they replace the current ones (a failed step
    /// must leave the current ones as they were).
    scratch: M::Outputs,
    /// FMU states made by fmi2GetFMUstate for this instance and not yet freed: fmi2FreeInstance
    /// frees them (FMI 2.0: freeing the instance frees everything the FMU allocated for it).
    pub states: Vec<usize>,
    /// The value references of the last fmi2GetReal, resolved (see [`ReadPlan`]).
    plan: ReadPlan<M>,
    /// The inputs of the last fmi2SetReal of inputs only, resolved (see [`InputPlan`]).
    inputs: InputPlan<M>,
    /// Instantiated for Model Exchange (FMI 3.0, `crate::fmi3`): the ME functions are allowed,
    /// fmi3DoStep is not.
    pub model_exchange: bool,
    /// FMI 2.0 Model Exchange (`fmi2::model_exchange`): after initialization, in
    /// continuous-time mode (true) or event mode (false).
    pub me_continuous_time: bool,
}

/// Model Exchange: the built model, the values and the state ([`Instance::me_parts_initial`]).
pub type MeParts<'a, M> = (&'a <M as FmuModel>::Built, &'a [f64], &'a <M as FmuModel>::State);

impl<M: FmuModel> Instance<M> {
    pub fn new(logger: Logger, resource_dir: Option<PathBuf>) -> Instance<M> {
        Instance {
            logger,
            resource_dir,
            core: Core::fresh::<M>(),
            outputs: M::Outputs::default(),
            model: None,
            provisional: None,
            stats: M::Stats::default(),
            scratch: M::Outputs::default(),
            states: Vec::new(),
            plan: ReadPlan::empty(),
            inputs: InputPlan::empty(),
            model_exchange: false,
            me_continuous_time: false,
        }
    }

    pub fn time(&self) -> f64 {
        self.core.time
    }

    pub fn mode(&self) -> Mode {
        self.core.mode
    }

    /// Model Exchange (`crate::fmi3`): the built model, the values and the state, once
    /// initialized.
    pub fn me_parts(&self) -> Option<(&M::Built, &[f64], &M::State)> {
        Some((self.model.as_ref()?, &self.core.values, &self.core.state))
    }

    /// Model Exchange: [`Instance::me_parts`], and in initialization mode the machine and initial
    /// state the values set so far give (the provisional model fmi2GetReal of an output builds
    /// there), so that the states and their derivatives, initial unknowns, are readable there.
    pub fn me_parts_initial(&mut self) -> Result<Option<MeParts<'_, M>>, Failure> {
        if self.model.is_none() && self.core.mode == Mode::InitializationMode {
            self.refresh_outputs()?;
        }
        let Self { core, model, provisional, .. } = self;
        Ok(match (model.as_ref(), provisional.as_ref()) {
            (Some(m), _) => Some((m, &core.values[..], &core.state)),
            (None, Some((m, s))) => Some((m, &core.values[..], s)),
            (None, None) => None,
        })
    }

    /// Model Exchange: the importer's solver sets the time or the continuous states; the outputs
    /// are evaluated again when read.
    pub fn me_update(&mut self, f: impl FnOnce(&mut f64, &mut M::State)) {
        f(&mut self.core.time, &mut self.core.state);
        self.invalidate_outputs();
    }

    /// The parameters set furthest from their start values (by order of magnitude), to name in a
    /// message when no finite result exists.
    fn extreme_parameters(&self) -> String {
        let mut cand: Vec<(f64, String)> = M::table()
            .variables
            .iter()
            .enumerate()
            .filter(|(_, v)| v.causality == Causality::Parameter && v.ty == VarType::Real)
            .filter_map(|(i, v)| {
                let x = self.core.values[i];
                let s = v.start().unwrap_or(0.0);
                let ratio = (x.abs().max(1e-300) / s.abs().max(1e-300)).log10().abs();
                (x != s).then(|| (ratio, format!("{} = {}", v.name, given(x))))
            })
            .collect();
        cand.sort_by(|a, b| b.0.total_cmp(&a.0));
        if cand.is_empty() {
            return "(start values)".into();
        }
        cand.into_iter().take(3).map(|c| c.1).collect::<Vec<_>>().join(", ")
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

    /// Inputs, parameters or state changed: the output cache no longer answers for them.
    #[inline]
    fn invalidate_outputs(&mut self) {
        self.core.outputs_valid = false;
        if self.provisional.is_some() {
            self.provisional = None;
        }
    }

    pub fn setup_experiment(
        &mut self,
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    ) -> Result<(), Failure> {
        self.require("fmi2SetupExperiment", &[Mode::Instantiated])?;
        if !start.is_finite() {
            return Err(Failure::error(format!(
                "fmi2SetupExperiment: startTime = {} must be finite",
                given(start)
            )));
        }
        if let Some(t) = tolerance {
            if !Range::TOLERANCE.contains(t) {
                return Err(Failure::error(format!(
                    "fmi2SetupExperiment: tolerance = {}; allowed: {}",
                    given(t),
                    Range::TOLERANCE.describe("")
                )));
            }
        }
        if let Some(s) = stop {
            if s.is_nan() || s < start {
                return Err(Failure::error(format!(
                    "fmi2SetupExperiment: stopTime = {} must be finite and >= startTime = {}",
                    given(s),
                    given(start)
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
        self.invalidate_outputs();
        Ok(())
    }

    /// Validates every parameter (ranges, then the machine as a whole) and evaluates the outputs
    /// at the initial inputs. On failure the instance stays in initialization mode, so the
    /// parameters can be corrected.
    pub fn exit_initialization_mode(&mut self) -> Result<(), Failure> {
        self.require("fmi2ExitInitializationMode", &[Mode::InitializationMode])?;
        let model = M::build(&self.core.params::<M>()?)?;
        let state = M::initialize(&model, &self.core.values, &self.core.state, &mut self.scratch)?;
        if let Some(w) = M::initial_warning(&model, &state) {
            self.warn("fmi2ExitInitializationMode", &w);
        }
        self.core.state = state;
        std::mem::swap(&mut self.outputs, &mut self.scratch);
        self.core.outputs_valid = true;
        self.provisional = None;
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
        self.core = Core::fresh::<M>();
        self.model = None;
        self.provisional = None;
        Ok(())
    }

    #[inline]
    fn lookup(&self, function: &str, vr: u32, ty: VarType) -> Result<usize, Failure> {
        let i = vr as usize;
        match M::table().info().get(i) {
            Some(v) if v.ty == ty => Ok(i),
            _ => Err(Self::lookup_failure(function, vr, ty)),
        }
    }

    #[cold]
    fn lookup_failure(function: &str, vr: u32, ty: VarType) -> Failure {
        let vars = M::table().variables;
        match vars.get(vr as usize) {
            Some(v) => Failure::error(format!(
                "{function}: value reference {vr} is \"{}\" of type {:?}, not {ty:?}",
                v.name, v.ty
            )),
            None => Failure::error(format!(
                "{function}: unknown value reference {vr} (valid: 0..{})",
                vars.len() - 1
            )),
        }
    }

    /// Makes the output cache current: in initialization mode from the parameters as set so far
    /// (the state the FMU would start from with these values), afterwards from the validated model.
    fn refresh_outputs(&mut self) -> Result<(), Failure> {
        if self.core.outputs_valid {
            return Ok(());
        }
        match &self.model {
            Some(m) => {
                M::update_outputs(m, &self.core.values, &self.core.state, &mut self.outputs)?
            }
            None => {
                let m = M::build(&self.core.params::<M>()?)?;
                let state =
                    M::initialize(&m, &self.core.values, &self.core.state, &mut self.outputs)?;
                self.provisional = Some((m, state));
            }
        }
        self.core.outputs_valid = true;
        Ok(())
    }

    /// fmi2GetReal/Integer/Boolean: `out(i, value)` receives the i-th requested value.
    /// Every value reference is checked before anything is evaluated (a failing call changes
    /// nothing); outputs are evaluated at most once per change of time, inputs or parameters (a
    /// lazy model evaluates, in one [`FmuModel::prepare`], only what the call reads).
    pub fn get(
        &mut self,
        function: &str,
        ty: VarType,
        vrs: &[u32],
        mut out: impl FnMut(usize, f64),
    ) -> Result<(), Failure> {
        let outputs_available = match self.core.mode {
            Mode::InitializationMode | Mode::StepComplete | Mode::Terminated => true,
            // Parameters and inputs can be read right after instantiation (some importers do).
            Mode::Instantiated => false,
            Mode::Fatal => return Err(Failure::illegal(function, self.core.mode)),
        };
        let info = M::table().info();
        let mut first_output = None;
        let mut need = 0u8;
        for &vr in vrs {
            match info.get(vr as usize) {
                Some(v) if v.ty == ty => {
                    if let Some(o) = v.output {
                        need |= M::needs(o);
                        if first_output.is_none() {
                            first_output = Some(vr as usize);
                        }
                    }
                }
                _ => return Err(Self::lookup_failure(function, vr, ty)),
            }
        }
        if let (Some(i), false) = (first_output, self.core.outputs_valid) {
            if !outputs_available {
                return Err(Failure::error(format!(
                    "{function}: output \"{}\" is not available before fmi2EnterInitializationMode",
                    M::table().variables[i].name
                )));
            }
            self.refresh_outputs()?;
        }
        let Self { core, outputs, model, provisional, .. } = self;
        let context = match (model.as_ref(), provisional.as_ref()) {
            (Some(m), _) => Some((m, &core.state)),
            (None, Some((m, s))) => Some((m, s)),
            (None, None) => None,
        };
        match context {
            Some((m, state)) if need != 0 => M::prepare(m, &core.values, state, outputs, need)?,
            _ => {}
        }
        let mut non_finite: Vec<String> = Vec::new();
        for (k, &vr) in vrs.iter().enumerate() {
            let i = vr as usize;
            match info[i].output {
                Some(get) => {
                    let Some(v) = M::read(outputs, get) else {
                        return Err(Failure::error(
                            "output requested but not evaluated (internal error)",
                        ));
                    };
                    // No non-finite value leaves the FMU with fmi2OK (docs/hardening.md).
                    if !v.is_finite() && non_finite.len() < 8 {
                        non_finite.push(format!("{} = {}", M::table().variables[i].name, num(v)));
                    }
                    out(k, v);
                }
                None => out(k, core.values[i]),
            }
        }
        if !non_finite.is_empty() {
            return Err(Failure::error(format!(
                "{function}: non-finite outputs at t = {} s: {}; the parameters {} give no finite result \
                 here (the FMU's state is unchanged)",
                num(self.core.time),
                non_finite.join(", "),
                self.extreme_parameters()
            )));
        }
        Ok(())
    }

    /// `get` of Reals when nothing needs a message: in `StepComplete`, every value reference a
    /// Real, every value finite, no debug log of the call. Returns false in every other case
    /// (having possibly written some of `out` and brought the output cache up to date, which
    /// `get` does too): the general path (`get`) then evaluates again, decides and reports.
    /// WHY: masters read outputs at every step, and the general path's plumbing (the position of
    /// the first output for a message, the list of non-finite names, the closure over the
    /// caller's array, the status and log) cost more than the evaluation of the kinematics. It
    /// evaluates the model, so it runs behind the panic barrier.
    // Always inlined: with two callers (fmi2GetReal and fmi3GetFloat64) plain `#[inline]` left it
    // out of line, a call and its argument spills on every read (docs/performance.md "The FMI
    // layer").
    #[inline(always)]
    pub fn quick_get_real(&mut self, vrs: &[u32], out: &mut [f64]) -> bool {
        if self.core.mode != Mode::StepComplete
            || self.logger.wants(Category::Calls)
            || vrs.len() != out.len()
        {
            return false;
        }
        if !self.plan.is_for(vrs) {
            let Some(plan) = M::table().info_ready().and_then(|info| ReadPlan::resolve(info, vrs))
            else {
                return false;
            };
            self.plan = plan;
        }
        let Self { core, outputs, model, plan, .. } = self;
        let Some(model) = model.as_ref() else { return false };
        if !core.outputs_valid {
            if let Err(e) = M::update_outputs(model, &core.values, &core.state, outputs) {
                return Self::drop_error(e);
            }
            core.outputs_valid = true;
        }
        if plan.need != 0 {
            if let Err(e) = M::prepare(model, &core.values, &core.state, outputs, plan.need) {
                return Self::drop_error(e);
            }
        }
        // Σ v·0 stays 0 while every v is finite and is NaN from the first that is not: two
        // floating-point operations a value instead of a test of the bits and a branch.
        let mut zero = 0.0;
        for (source, slot) in plan.sources.iter().zip(out.iter_mut()) {
            let v = match *source {
                Source::Output(o) => M::read_prepared(outputs, o),
                Source::Value(i) => core.values[i],
            };
            zero += v * 0.0;
            *slot = v;
        }
        zero == 0.0
    }

    /// An error the fast path leaves to the general path, which meets it again and reports it.
    #[cold]
    #[inline(never)]
    fn drop_error(_: ModelError) -> bool {
        false
    }

    /// fmi2SetReal/Integer/Boolean. All values are checked before any is stored, so a failing
    /// call changes nothing. Inputs must be finite; a tunable parameter set while stepping is
    /// validated with the whole machine at once; other parameters are validated at
    /// fmi2ExitInitializationMode.
    pub fn set(
        &mut self,
        function: &str,
        ty: VarType,
        vrs: &[u32],
        value: impl Fn(usize) -> f64,
    ) -> Result<(), Failure> {
        let stepping = match self.core.mode {
            Mode::Instantiated | Mode::InitializationMode => false,
            Mode::StepComplete => true,
            _ => return Err(Failure::illegal(function, self.core.mode)),
        };
        // Fast path, taken at every step by every master: finite values for inputs only.
        let info = M::table().info();
        let inputs_only = vrs.iter().enumerate().all(|(k, &vr)| {
            matches!(info.get(vr as usize), Some(v) if v.ty == ty && v.slot.is_some())
                && value(k).is_finite()
        });
        if inputs_only {
            for (k, &vr) in vrs.iter().enumerate() {
                let (i, v) = (vr as usize, value(k));
                self.core.values[i] = v;
                if let Some(slot) = info[i].slot {
                    M::input_changed(&mut self.core.state, slot, v);
                }
            }
            self.invalidate_outputs();
            return Ok(());
        }
        let mut tunable_changed = false;
        for (k, &vr) in vrs.iter().enumerate() {
            let i = self.lookup(function, vr, ty)?;
            let var = &M::table().variables[i];
            let v = value(k);
            match var.causality {
                Causality::Output | Causality::CalculatedParameter => {
                    return Err(Failure::error(format!(
                        "{function}: \"{}\" is computed by the FMU and cannot be set",
                        var.name
                    )))
                }
                Causality::Input if !v.is_finite() => {
                    return Err(ModelError::out_of_range(var.name, v, var.allowed()).into())
                }
                Causality::Parameter if stepping => {
                    if var.variability != Variability::Tunable {
                        return Err(Failure::error(format!(
                            "{function}: \"{}\" is a fixed parameter and cannot be changed after initialization",
                            var.name
                        )));
                    }
                    if !var.range.contains(v) {
                        return Err(ModelError::out_of_range(var.name, v, var.allowed()).into());
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
            match self.core.params::<M>().and_then(|p| M::build(&p).map_err(Failure::from)) {
                Ok(model) => self.model = Some(model),
                Err(e) => {
                    self.core.values = saved;
                    return Err(e);
                }
            }
        }
        self.invalidate_outputs();
        Ok(())
    }

    /// `set` of Real inputs when nothing needs a message: finite values for inputs only, in
    /// `StepComplete`, no debug log of the call. Returns false, having changed nothing, in every
    /// other case: the general path (`set`, behind the panic barrier) then decides, reports and
    /// logs. WHY: every master sets the crank inputs at every step, and the general path's
    /// plumbing (closures over the caller's array, the panic barrier, the status and log) cost
    /// more than the values it stores. It cannot panic, which release builds prove at link time
    /// (as for [`Self::quick_step`]).
    #[cfg_attr(not(debug_assertions), no_panic::no_panic)]
    // One copy per caller (`API`: 2 for fmi2SetReal, 3 for fmi3SetFloat64): with a single shared
    // copy and two callers LLVM kept it, or no_panic's inner closure, out of line, a call and
    // argument spills on every step; each copy has one caller and is inlined whole
    // (docs/performance.md "The FMI layer").
    #[inline]
    pub fn quick_set_real<const API: u8>(&mut self, vrs: &[u32], values: &[f64]) -> bool {
        if self.core.mode != Mode::StepComplete
            || self.logger.wants(Category::Calls)
            || vrs.len() != values.len()
            || self.provisional.is_some()
        {
            return false;
        }
        if !self.inputs.is_for(vrs) {
            let Some(plan) = M::table()
                .info_ready()
                .and_then(|info| InputPlan::resolve(info, self.core.values.len(), vrs))
            else {
                return false;
            };
            self.inputs = plan;
        }
        // Σ v·0 is 0 when every value is finite (NaN otherwise), as in `quick_get_real`.
        if values.iter().fold(0.0, |zero, v| zero + v * 0.0) != 0.0 {
            return false;
        }
        let Self { core, inputs, .. } = self;
        for ((&vr, &v), &slot) in vrs.iter().zip(values).zip(&inputs.slots) {
            if let (Some(slot), Some(stored)) = (slot, core.values.get_mut(vr as usize)) {
                *stored = v;
                M::input_changed(&mut core.state, slot, v);
            }
        }
        // `invalidate_outputs` without the provisional model to drop (there is none, above).
        core.outputs_valid = false;
        true
    }

    /// Stores a value; for an input also tells the model (it may keep a copy in its state).
    #[inline]
    fn store_value(&mut self, vr: usize, v: f64) {
        self.core.values[vr] = v;
        if let Some(slot) = M::table().info()[vr].slot {
            M::input_changed(&mut self.core.state, slot, v);
        }
    }

    /// fmi2DoStep: advances the model's state over [t, t+h] and brings the outputs to the new
    /// communication point, or, for a model without continuous state
    /// ([`FmuModel::carry_without_state`]), marks them stale to be evaluated when read. Nothing
    /// changes unless everything succeeds.
    pub fn do_step(&mut self, current: f64, h: f64) -> Result<(), Failure> {
        if self.core.mode != Mode::StepComplete {
            return Err(Failure::illegal("fmi2DoStep", self.core.mode));
        }
        if !self.step_arguments_ok(current, h) {
            return Err(self.step_arguments_failure(current, h));
        }
        if self.carry(current, h) {
            return Ok(());
        }
        // A state to integrate, or a carried-forward state the model refuses: the model's step
        // integrates it, or fails naming what is wrong.
        self.integrate_step(current, h)
    }

    /// `do_step` when nothing needs a message: a model without continuous state in
    /// `StepComplete`, valid arguments, a crank carried forward that stays finite, and no debug
    /// log of the call. Returns false, having changed nothing, in every other case: the general
    /// path (`do_step`, behind the panic barrier) then decides, reports and logs. WHY: a rigid
    /// mechanism's step only moves the crank, and the panic barrier with the plumbing of its
    /// result was a third of the step's cost. It cannot panic, which release builds prove at
    /// link time (`no_panic`: a path that could panic fails to link); debug builds, which cannot
    /// prove it, leave it unchecked.
    #[cfg_attr(not(debug_assertions), no_panic::no_panic)]
    #[inline]
    pub fn quick_step(&mut self, current: f64, h: f64) -> bool {
        self.core.mode == Mode::StepComplete
            && !self.model_exchange
            && !self.logger.wants(Category::Calls)
            && self.step_arguments_ok(current, h)
            && self.carry(current, h)
    }

    /// The step of a model without continuous state ([`FmuModel::carry_without_state`]), after
    /// the checks: the state moves in place, the outputs are evaluated when read. False, with
    /// nothing changed, when the model has a state to integrate or refuses the step.
    #[inline]
    fn carry(&mut self, current: f64, h: f64) -> bool {
        let Some(model) = self.model.as_ref() else { return false };
        if !M::carry_without_state(model, &mut self.core.state, h) {
            return false;
        }
        self.core.time = current + h;
        self.core.outputs_valid = false;
        true
    }

    /// fmi2DoStep's arguments: h > 0 and finite, the current point finite and at the FMU's time
    /// within a small fraction of the step (masters accumulate time in floating point; a skipped
    /// or repeated step is rejected).
    #[inline]
    fn step_arguments_ok(&self, current: f64, h: f64) -> bool {
        let slack = 1e-6 * h + 1e-12 * self.core.time.abs();
        // One expression over all conditions (NaN fails each; h·0 and current·0 are 0 only when
        // finite), which keeps the test on the floating-point side.
        (h > 0.0)
            & (h * 0.0 == 0.0)
            & (current * 0.0 == 0.0)
            & ((current - self.core.time).abs() <= slack)
    }

    /// The step of a model with continuous state, after `do_step`'s checks. Out of line: its
    /// integrator would otherwise give the rigid path a kilobyte of stack frame to set up.
    #[inline(never)]
    fn integrate_step(&mut self, current: f64, h: f64) -> Result<(), Failure> {
        let Some(model) = self.model.as_ref() else {
            return Err(Failure::illegal("fmi2DoStep", self.core.mode));
        };
        // The master's tolerance (fmi2SetupExperiment) wins over the model's own (§6).
        let tol = self.core.tolerance.unwrap_or_else(|| M::default_tolerance(model));
        let mut stats = self.stats;
        let state = match M::step(
            model,
            &self.core.values,
            &self.core.state,
            h,
            tol,
            &mut stats,
            &mut self.scratch,
        ) {
            Ok(state) => state,
            Err(e) => return Err(Self::step_failure(current, h, e)),
        };
        let warning = M::step_warning(model, &self.core.state, &state);
        self.core.state = state;
        self.core.time = current + h;
        std::mem::swap(&mut self.outputs, &mut self.scratch);
        self.core.outputs_valid = true;
        self.stats = stats;
        if let Some(w) = warning {
            self.warn("fmi2DoStep", &w);
        }
        Ok(())
    }

    #[cold]
    #[inline(never)]
    fn step_arguments_failure(&self, current: f64, h: f64) -> Failure {
        if !(h > 0.0 && h.is_finite()) {
            Failure::error(format!(
                "fmi2DoStep: communicationStepSize = {}; allowed: a finite number > 0",
                given(h)
            ))
        } else {
            Failure::error(format!(
                "fmi2DoStep: currentCommunicationPoint = {} does not match the FMU's time {} s \
                 (it differs by {} s; roll back with fmi2SetFMUstate to repeat a step)",
                given(current),
                num(self.core.time),
                num(current - self.core.time)
            ))
        }
    }

    #[cold]
    #[inline(never)]
    fn step_failure(current: f64, h: f64, e: ModelError) -> Failure {
        Failure::error(format!(
            "fmi2DoStep from t = {} s with h = {} s failed: {e}",
            num(current),
            given(h)
        ))
    }

    /// A model warning, with the function and the FMU's time.
    fn warn(&self, function: &str, message: &str) {
        self.logger.log(
            fmi_sys::fmi2::fmi2Status_fmi2Warning,
            Category::Warning,
            &format!("{function}: at t = {} s {message}", num(self.core.time)),
        );
    }

    pub fn snapshot(&self) -> Snapshot<M> {
        Snapshot {
            magic: snapshot_magic::<M>(),
            core: self.core.clone(),
            outputs: self.outputs.clone(),
            model: self.model.clone(),
            provisional: self.provisional.clone(),
        }
    }

    pub fn restore(&mut self, s: &Snapshot<M>) -> Result<(), Failure> {
        if self.core.mode == Mode::Fatal {
            return Err(Failure::illegal("fmi2SetFMUstate", self.core.mode));
        }
        if s.magic != snapshot_magic::<M>() {
            return Err(Failure::error("fmi2SetFMUstate: the state was not made by this FMU"));
        }
        self.core = s.core.clone();
        self.outputs = s.outputs.clone();
        self.model = s.model.clone();
        self.provisional = s.provisional.clone();
        Ok(())
    }

    /// Rebuilds a snapshot from deserialized data, validating it as untrusted input.
    pub fn snapshot_from_core(core: Core<M::State>) -> Result<Snapshot<M>, Failure> {
        let bad =
            |what: &str| Failure::error(format!("fmi2DeSerializeFMUstate: invalid state: {what}"));
        let vars = M::table().variables;
        if core.values.len() != vars.len() {
            return Err(bad("wrong number of variables"));
        }
        if !core.time.is_finite() || core.mode == Mode::Fatal {
            return Err(bad("time or mode"));
        }
        M::check_state(&core.state).map_err(bad)?;
        // The outputs are not part of the serialized form: recompute them when asked.
        let core = Core { outputs_valid: false, ..core };
        // Validated like values set by the importer: parameters in their ranges, finite inputs,
        // a tolerance in (0, 1).
        for (v, var) in core.values.iter().zip(vars) {
            let integral = matches!(var.ty, VarType::Integer | VarType::Boolean);
            if integral && !(v.fract() == 0.0 && v.abs() <= i32::MAX as f64) {
                return Err(bad(var.name));
            }
            let ok = match var.causality {
                Causality::Parameter => var.range.contains(*v),
                Causality::Input => v.is_finite(),
                _ => true,
            };
            if !ok {
                return Err(bad(&format!(
                    "{} = {}; allowed: {}",
                    var.name,
                    given(*v),
                    var.allowed()
                )));
            }
        }
        if let Some(t) = core.tolerance {
            if !Range::TOLERANCE.contains(t) {
                return Err(bad(&format!(
                    "tolerance = {}; allowed: {}",
                    given(t),
                    Range::TOLERANCE.describe("")
                )));
            }
        }
        let model = match core.mode {
            Mode::StepComplete | Mode::Terminated => Some(M::build(&core.params::<M>()?)?),
            _ => None,
        };
        Ok(Snapshot {
            magic: snapshot_magic::<M>(),
            core,
            outputs: M::Outputs::default(),
            model,
            provisional: None,
        })
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
