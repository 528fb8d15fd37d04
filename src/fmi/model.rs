//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! What a model gives the shared FMI glue (the core and both standards' layers): the counterpart
//! of the `config.h` + `model.c` pair of each of the Modelica Reference FMUs over their one shared
//! `fmi2Functions.c`.
//!
//! The glue (instances, state machine, get/set, logging, FMU states, modelDescription.xml and
//! documentation generation, the C ABI) is written once, generic over [`FmuModel`]. A model
//! supplies its variable table, its identity, and the physics behind a few calls; it never sees
//! FMI types, and the glue never computes physics.
//!
//! Outputs: the glue does not hold an `Outputs` struct. It tells the model when its inputs or
//! state changed ([`FmuModel::update_outputs`]), lets it evaluate what one fmi2GetReal needs
//! ([`FmuModel::prepare`]) and reads one output at a time ([`FmuModel::read`]); the model owns
//! the cache in between. A model may evaluate everything at once in `update_outputs` (eager) or
//! only mark its cache stale there and evaluate in `prepare` what the outputs read need (lazy).

use std::fmt::Debug;

use serde::de::DeserializeOwned;
use serde::Serialize;

use crate::fmi::variables::Table;
use crate::model::error::ModelError;

/// The identity of an FMU and the texts the generators put around its variable table.
pub struct ModelInfo {
    /// `modelIdentifier`: the name of the shared object in `binaries/<platform>/`.
    pub model_identifier: &'static str,
    pub model_name: &'static str,
    /// `description` attribute of `<fmiModelDescription>`.
    pub description: &'static str,
    /// `<DefaultExperiment>` start, stop, step size [s].
    pub default_experiment: (f64, f64, f64),
    /// HTML of documentation/index.html before the generated variable list.
    pub documentation: &'static str,
    /// The hint of the fmi2SetRealInputDerivatives error (what to do instead).
    pub input_derivatives_hint: &'static str,
}

/// An output of a model that evaluates its outputs on demand by groups (see the module doc):
/// `group` is the model's own mark of what must be evaluated before `get` reads the cache (the
/// glue does not interpret it).
pub struct GroupedOutput<O> {
    pub group: u8,
    pub get: fn(&O) -> f64,
}

impl<O> Clone for GroupedOutput<O> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<O> Copy for GroupedOutput<O> {}

/// One model served by the FMI glue. All functions are associated functions (the glue keeps the
/// data; the model keeps none between calls besides what the glue hands it).
pub trait FmuModel: Sized + 'static {
    /// Parameters as the variable table writes them; `Default` is the start values.
    type Params: Default;
    /// The validated machine, built from the parameters at fmi2ExitInitializationMode (and again
    /// when a tunable parameter changes); immutable while stepping.
    type Built: Clone;
    /// Everything that evolves with time and must survive fmi2GetFMUstate/fmi2SerializeFMUstate:
    /// continuous states, integrator memory, the model's copy of its inputs.
    type State: Clone + Default + PartialEq + Debug + Serialize + DeserializeOwned;
    /// The model's output cache (see the module doc).
    type Outputs: Default + Clone;
    /// Names an input of the table (where `fmi2SetReal` delivers it in the model).
    type Input: Copy + PartialEq + Debug + Send + Sync + 'static;
    /// Names an output (or calculated parameter) of the table, as [`FmuModel::read`] reads it.
    type Output: Copy + Send + Sync + 'static;
    /// Work counters kept per instance (diagnostics only, not part of the FMU state).
    type Stats: Default + Copy;

    fn info() -> &'static ModelInfo;
    /// The variable table (value reference = index).
    fn table() -> &'static Table<Self>;

    /// The state of a fresh instance (fmi2Instantiate, fmi2Reset) with the table's start values
    /// in `values` (indexed by value reference).
    fn fresh_state(values: &[f64]) -> Self::State;

    /// `fmi2SetReal` stored a finite value of `input` (already in `values`): keep the state's copy
    /// of it, if the model keeps one.
    #[inline]
    fn input_changed(_state: &mut Self::State, _input: Self::Input, _value: f64) {}

    /// Checks the machine as a whole (what single-variable ranges cannot) and precomputes.
    fn build(params: &Self::Params) -> Result<Self::Built, ModelError>;

    /// The state the simulation starts from, and the outputs there written to `out`
    /// (fmi2ExitInitializationMode; in initialization mode also for fmi2GetReal). An error leaves
    /// the caller's state as it was (`out` is then unspecified and not used).
    fn initialize(
        built: &Self::Built,
        values: &[f64],
        state: &Self::State,
        out: &mut Self::Outputs,
    ) -> Result<Self::State, ModelError>;

    /// Inputs, parameters or state changed since `cache` was last brought up to date: make it
    /// answer for `values` and `state` (eagerly, or by marking it stale). On error `cache` is
    /// unspecified and asked again only after another `update_outputs`.
    fn update_outputs(
        built: &Self::Built,
        values: &[f64],
        state: &Self::State,
        cache: &mut Self::Outputs,
    ) -> Result<(), ModelError>;

    /// The model's mark of what `output` needs evaluated (a bit set; 0 for an eager model). The
    /// glue ORs the marks of every output one fmi2GetReal asks for and passes them to
    /// [`FmuModel::prepare`] once.
    #[inline]
    fn needs(_output: Self::Output) -> u8 {
        0
    }

    /// Evaluates in one go what the outputs of one call need (`need`, from [`FmuModel::needs`]),
    /// so that reading them finds them cached. An error fails the call.
    #[inline]
    fn prepare(
        _built: &Self::Built,
        _values: &[f64],
        _state: &Self::State,
        _cache: &mut Self::Outputs,
        _need: u8,
    ) -> Result<(), ModelError> {
        Ok(())
    }

    /// The value of `output` from the cache; None if the cache does not hold it (after
    /// [`FmuModel::prepare`] of what `output` needs, it always does).
    fn read(cache: &Self::Outputs, output: Self::Output) -> Option<f64>;

    /// [`FmuModel::read`] right after a successful [`FmuModel::prepare`] of what `output` needs,
    /// without asking again whether the cache holds it (fmi2GetReal's fast path reads many
    /// outputs after one prepare). NaN if it does not: the glue's general path then reads
    /// through `read` and reports.
    #[inline]
    fn read_prepared(cache: &Self::Outputs, output: Self::Output) -> f64 {
        Self::read(cache, output).unwrap_or(f64::NAN)
    }

    /// One communication step of size `h` from `state`, to the tolerance `tol`, when
    /// [`FmuModel::carry_without_state`] did not make it: returns the new state and brings `out`
    /// up to date for it (as `update_outputs` would), so that a step to a state whose outputs
    /// cannot be evaluated fails as a step, with the message that names why. An error changes
    /// nothing the caller keeps.
    #[allow(clippy::too_many_arguments)]
    fn step(
        built: &Self::Built,
        values: &[f64],
        state: &Self::State,
        h: f64,
        tol: f64,
        stats: &mut Self::Stats,
        out: &mut Self::Outputs,
    ) -> Result<Self::State, ModelError>;

    /// A step with nothing to integrate, made in place: true when the built model has no
    /// continuous state and the state carried forward is valid (the glue then skips
    /// [`FmuModel::step`], the integrator's statistics, the tolerance and the step warning, and
    /// evaluates the outputs when read); false, with the state unchanged, when
    /// [`FmuModel::step`] must run (a state to integrate, or a step to refuse with a message).
    /// It runs without the panic barrier and must not panic (the glue proves that at link time).
    fn carry_without_state(_built: &Self::Built, _state: &mut Self::State, _h: f64) -> bool {
        false
    }

    /// Model Exchange: the importer moved the time by `dt` (fmi2SetTime, fmi3SetTime). Carries
    /// forward what a co-simulation step carries without integrating (the pump's crank inputs
    /// between the points where they are set, docs/model.md §2), so that an input the importer
    /// does not set behaves as in co-simulation; an input set afterwards replaces its carried
    /// value. false, with the state unchanged: what it carries would overflow.
    fn time_moved(_state: &mut Self::State, _dt: f64) -> bool {
        true
    }

    /// The integrator tolerance when fmi2SetupExperiment gives none.
    fn default_tolerance(built: &Self::Built) -> f64;

    /// A warning about the initial state (logged by the glue with the function and the time).
    fn initial_warning(_built: &Self::Built, _state: &Self::State) -> Option<String> {
        None
    }

    /// A warning about a completed step from `before` to `after`.
    fn step_warning(
        _built: &Self::Built,
        _before: &Self::State,
        _after: &Self::State,
    ) -> Option<String> {
        None
    }

    /// Checks a deserialized state (untrusted bytes); the error names what is invalid.
    fn check_state(_state: &Self::State) -> Result<(), &'static str> {
        Ok(())
    }

    /// Model Exchange (FMI 3.0, `crate::fmi3`): the continuous states, each as (the name of the
    /// table's variable that is the state, the unit of its derivative). Empty: the FMU does not
    /// offer Model Exchange. The number of states must not depend on the parameters.
    const CONTINUOUS_STATES: &'static [(&'static str, &'static str)] = &[];

    /// Model Exchange: the continuous states of `CONTINUOUS_STATES` that are no variable of the
    /// table, each as (name, unit, description). The generators declare each as a local
    /// continuous variable of its own, after the derivatives (value reference: FMI 3.0's
    /// `time`'s + 1 + the number of states + its index in `CONTINUOUS_STATES`), read through
    /// [`FmuModel::continuous_states`]. WHY: a state whose value is not what a table output
    /// reports in every machine (the elastic rod's cage angle is `rod.angle` only for an elastic
    /// rod) must be a variable of its own.
    const STATE_VARIABLES: &'static [(&'static str, &'static str, &'static str)] = &[];

    /// Model Exchange (FMI 3.0) is declared: by default when the model has continuous states; a
    /// model without any (outputs functions of the inputs) may declare it too.
    const MODEL_EXCHANGE: bool = !Self::CONTINUOUS_STATES.is_empty();

    /// Model Exchange: why this built machine cannot run as Model Exchange (e.g. it would need
    /// continuous states the FMU does not declare); None: it can. Checked at
    /// fmi3ExitInitializationMode of a Model Exchange instance.
    fn model_exchange_refusal(_built: &Self::Built) -> Option<String> {
        None
    }

    /// Model Exchange: the continuous states of `state`, in the order of `CONTINUOUS_STATES`.
    fn continuous_states(_state: &Self::State, _x: &mut [f64]) {}

    /// Model Exchange: sets the continuous states of `state` from `x` (the importer's solver).
    fn set_continuous_states(_state: &mut Self::State, _x: &[f64]) {}

    /// Model Exchange: the derivatives of the continuous states at `state` with the inputs in
    /// `values`.
    fn derivatives(
        _built: &Self::Built,
        _values: &[f64],
        _state: &Self::State,
        _dx: &mut [f64],
    ) -> Result<(), ModelError> {
        Ok(())
    }

    /// Directional derivatives (`fmi2GetDirectionalDerivative`, `fmi3GetDirectionalDerivative`)
    /// are provided: `providesDirectionalDerivative(s)="true"` in the model descriptions.
    const DIRECTIONAL_DERIVATIVES: bool = false;

    /// The exact directional derivative at (`values`, `state`) with the state held: with the
    /// inputs changing at `d_values` (indexed by value reference, 0 except for inputs) and the
    /// continuous states at `d_states` (Model Exchange; zeros otherwise), writes the change of
    /// every output into `tangent` (read with [`FmuModel::read`]) and of the state derivatives
    /// into `d_derivatives`. An error fails the call (the FMU's state is unchanged).
    #[allow(clippy::too_many_arguments)]
    fn tangent(
        _built: &Self::Built,
        _values: &[f64],
        _state: &Self::State,
        _d_values: &[f64],
        _d_states: &[f64],
        _tangent: &mut Self::Outputs,
        _d_derivatives: &mut [f64],
    ) -> Result<(), ModelError> {
        Err(ModelError::evaluation("directional derivatives are not provided by this FMU"))
    }

    /// Model Exchange: why this built machine gives no partials with respect to its continuous
    /// states or of their derivatives (a one-line reason naming the states); None: it gives
    /// them exactly through [`FmuModel::tangent`]. A partial not provided is refused, never 0.
    fn state_partials_refusal(_built: &Self::Built) -> Option<&'static str> {
        None
    }

    /// Model Exchange: the continuous states (indices into `CONTINUOUS_STATES`) each output
    /// depends on, by the output's name; an output not named depends on none. With the table's
    /// `depends_on` (inputs) these are the `<ModelStructure>` dependencies.
    const OUTPUT_STATES: &'static [(&'static str, &'static [usize])] = &[];

    /// Model Exchange: for each continuous state, the inputs and the states its derivative
    /// depends on; empty: not declared (an importer then assumes every known).
    const DERIVATIVE_DEPENDENCIES: &'static [(&'static [Self::Input], &'static [usize])] = &[];

    /// The states output `name` depends on ([`FmuModel::OUTPUT_STATES`]).
    fn output_states(name: &str) -> &'static [usize] {
        Self::OUTPUT_STATES.iter().find(|(n, _)| *n == name).map_or(&[], |(_, s)| s)
    }
}
