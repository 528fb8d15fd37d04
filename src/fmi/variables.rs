//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! The shape of a variable table: each model's table (e.g. `crate::fmus::reciprocating_drive::variables`)
//! is the one source of truth for names, value references, types, causality, variability, units,
//! start values, ranges, descriptions and output dependencies. The runtime (get/set, range checks,
//! building the model's parameters) and the generators of modelDescription.xml and of the HTML
//! documentation all read it, so they cannot drift apart.
//!
//! The value reference of a variable is its index in the table; references are unique across all
//! types, and `fmi2GetReal` etc. check the type of the variable they address.

use std::sync::OnceLock;

use crate::fmi::model::FmuModel;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarType {
    Real,
    Integer,
    Boolean,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    Parameter,
    /// Computed by the FMU at initialization from the parameters (e.g. the balancer stiffness).
    CalculatedParameter,
    Input,
    Output,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variability {
    Fixed,
    Tunable,
    Continuous,
}

/// How a variable is connected to the model. Values of every type are held as f64 in the
/// instance (integers and booleans are exact in f64).
pub enum Binding<M: FmuModel> {
    Param {
        get: fn(&M::Params) -> f64,
        set: fn(&mut M::Params, f64),
    },
    Input {
        slot: M::Input,
        start: f64,
    },
    /// Outputs and calculated parameters: read through [`FmuModel::read`].
    Output {
        get: M::Output,
        depends_on: &'static [M::Input],
    },
}

impl<M: FmuModel> Clone for Binding<M> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<M: FmuModel> Copy for Binding<M> {}

/// Allowed values. XML min/max are inclusive; an open end (e.g. r > 0) is marked so that the
/// runtime check and its message are exact while the XML shows the nearest inclusive bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    pub min: f64,
    pub max: f64,
    pub min_open: bool,
    pub max_open: bool,
}

impl Range {
    pub const ANY: Range =
        Range { min: f64::NEG_INFINITY, max: f64::INFINITY, min_open: true, max_open: true };
    pub const POSITIVE: Range =
        Range { min: 0.0, max: f64::INFINITY, min_open: true, max_open: true };
    pub const NON_NEGATIVE: Range =
        Range { min: 0.0, max: f64::INFINITY, min_open: false, max_open: true };
    pub const fn closed(min: f64, max: f64) -> Range {
        Range { min, max, min_open: false, max_open: false }
    }
    /// An integrator's relative tolerance: [1e-13, 1). Below about 100 machine epsilons
    /// (2.2e-14) the rounding of a step's own error estimate (a sum over the stages of
    /// differences of numbers of the size of the state) exceeds the tolerance, so no step size
    /// meets it and every step fails; 1e-13 (about 450 epsilons) leaves a margin
    /// (docs/hardening.md "Bounded parameters").
    pub const TOLERANCE: Range = Range { min: 1e-13, max: 1.0, min_open: false, max_open: true };
    /// (0, max]: a positive quantity with an upper bound.
    pub const fn positive_to(max: f64) -> Range {
        Range { min: 0.0, max, min_open: true, max_open: false }
    }
    /// [−m, m].
    pub const fn within(m: f64) -> Range {
        Range { min: -m, max: m, min_open: false, max_open: false }
    }

    pub fn contains(&self, v: f64) -> bool {
        if !v.is_finite() {
            return false;
        }
        let above = if self.min_open { v > self.min } else { v >= self.min };
        let below = if self.max_open { v < self.max } else { v <= self.max };
        above && below
    }

    /// Human-readable interval of a Real, e.g. "a finite number in (0, inf) m".
    pub fn describe(&self, unit: &str) -> String {
        self.describe_as(VarType::Real, unit)
    }

    /// Human-readable interval for a variable of type `ty`: an Integer's bounds as integers
    /// ("an integer in [0, 3]"), a Real's with at most 6 significant digits.
    pub fn describe_as(&self, ty: VarType, unit: &str) -> String {
        let lo = if self.min_open { '(' } else { '[' };
        let hi = if self.max_open { ')' } else { ']' };
        let bound = |b: f64| match ty {
            VarType::Real => fmt_bound(b),
            // Integer bounds are whole numbers within i32 (or infinite, printed as such).
            _ if b.is_finite() => format!("{}", b as i64),
            _ => fmt_bound(b),
        };
        let what = if ty == VarType::Real { "a finite number" } else { "an integer" };
        let mut s = format!("{what} in {lo}{}, {}{hi}", bound(self.min), bound(self.max));
        if !unit.is_empty() {
            s.push(' ');
            s.push_str(unit);
        }
        s
    }
}

fn fmt_bound(v: f64) -> String {
    crate::model::error::num(v)
}

pub struct Var<M: FmuModel> {
    pub name: &'static str,
    pub ty: VarType,
    pub causality: Causality,
    pub variability: Variability,
    pub unit: &'static str,
    pub description: &'static str,
    pub range: Range,
    pub binding: Binding<M>,
}

impl<M: FmuModel> Var<M> {
    /// What a refusal of this variable says is allowed: its range, in its type and unit.
    pub fn allowed(&self) -> String {
        self.range.describe_as(self.ty, self.unit)
    }

    /// Start value (parameters: the model's default parameters; inputs: their start).
    pub fn start(&self) -> Option<f64> {
        match self.binding {
            Binding::Param { get, .. } => Some(get(&M::Params::default())),
            Binding::Input { start, .. } => Some(start),
            Binding::Output { .. } => None,
        }
    }
}

/// What get/set need to know about a value reference, packed small so the per-call checks touch
/// one cache line instead of the full [`Var`] records. Derived once from the table.
pub struct VarInfo<M: FmuModel> {
    pub ty: VarType,
    pub causality: Causality,
    /// The input slot, for inputs.
    pub slot: Option<M::Input>,
    /// The output, for outputs and calculated parameters.
    pub output: Option<M::Output>,
}

impl<M: FmuModel> Clone for VarInfo<M> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<M: FmuModel> Copy for VarInfo<M> {}

/// A model's variable table with what the glue derives from it once (in the model's own statics:
/// a `static` inside a generic function would be shared by every model).
pub struct Table<M: FmuModel> {
    /// Every variable, in value-reference order.
    pub variables: &'static [Var<M>],
    /// Units used by the table, with their SI base-unit exponents (kg, m, s, rad) for
    /// `<UnitDefinitions>`.
    pub units: &'static [(&'static str, [i32; 4])],
    info: OnceLock<Vec<VarInfo<M>>>,
    pub(crate) guid: OnceLock<String>,
    /// The FMI 3.0 instantiationToken (written by the FMI 3.0 model-description writer).
    pub(crate) token3: OnceLock<String>,
    pub(crate) fingerprint: OnceLock<u64>,
    /// The value references of the continuous states (Model Exchange), found once by name: the
    /// directional derivatives ask for them at every call (`crate::fmi::directional`).
    state_vrs: OnceLock<Vec<usize>>,
}

impl<M: FmuModel> Table<M> {
    pub const fn new(
        variables: &'static [Var<M>],
        units: &'static [(&'static str, [i32; 4])],
    ) -> Table<M> {
        Table {
            variables,
            units,
            info: OnceLock::new(),
            guid: OnceLock::new(),
            token3: OnceLock::new(),
            fingerprint: OnceLock::new(),
            state_vrs: OnceLock::new(),
        }
    }

    /// The value reference of each continuous state, in the order of
    /// [`FmuModel::CONTINUOUS_STATES`] (`crate::fmi::structure::state_vr`, derived once:
    /// it looks the names up in the table).
    #[inline]
    pub fn state_vrs(&self) -> &[usize] {
        self.state_vrs.get_or_init(|| {
            (0..M::CONTINUOUS_STATES.len()).map(crate::fmi::structure::state_vr::<M>).collect()
        })
    }

    /// [`Self::info`] once it has been derived (the first instance derives it), without the
    /// code that derives it: for the paths that must not panic.
    #[inline]
    pub fn info_ready(&self) -> Option<&[VarInfo<M>]> {
        self.info.get().map(Vec::as_slice)
    }

    #[inline]
    pub fn info(&self) -> &[VarInfo<M>] {
        self.info.get_or_init(|| {
            self.variables
                .iter()
                .map(|v| VarInfo {
                    ty: v.ty,
                    causality: v.causality,
                    slot: match v.binding {
                        Binding::Input { slot, .. } => Some(slot),
                        _ => None,
                    },
                    output: match v.binding {
                        Binding::Output { get, .. } => Some(get),
                        _ => None,
                    },
                })
                .collect()
        })
    }

    /// Value reference of a variable by name (used by tests, the generator and set-up code, never
    /// in the hot path).
    pub fn value_reference(&self, name: &str) -> Option<usize> {
        self.variables.iter().position(|v| v.name == name)
    }

    /// Value reference of the input bound to `slot` (a scan: not for the hot path).
    pub fn input_vr(&self, slot: M::Input) -> Option<usize> {
        self.variables
            .iter()
            .position(|v| matches!(v.binding, Binding::Input { slot: s, .. } if s == slot))
    }
}

/// Value reference of a variable of model `M` by name.
pub fn value_reference<M: FmuModel>(name: &str) -> Option<usize> {
    M::table().value_reference(name)
}

/// Consistency checks every table must pass (each model's unit tests call it): unique names,
/// declared units, start values inside their ranges, inputs that can be found, and parameter
/// setters and getters that address the same field and no other.
pub fn check_table<M: FmuModel>() {
    let t = M::table();
    for (i, v) in t.variables.iter().enumerate() {
        assert_eq!(t.value_reference(v.name), Some(i), "duplicate name {}", v.name);
        assert!(v.unit.is_empty() || t.units.iter().any(|u| u.0 == v.unit), "unit {}", v.unit);
        if let Some(s) = v.start() {
            assert!(v.range.contains(s), "start of {} outside its range", v.name);
        }
        if let Binding::Input { slot, .. } = v.binding {
            assert_eq!(t.input_vr(slot), Some(i), "input slot of {} bound twice", v.name);
        }
        if let Binding::Output { depends_on, .. } = v.binding {
            for d in depends_on {
                assert!(
                    t.input_vr(*d).is_some(),
                    "{} depends on an input that is not in the table",
                    v.name
                );
            }
        }
    }
    for v in t.variables {
        if let Binding::Param { get, set } = v.binding {
            let mut p = M::Params::default();
            let x = match v.ty {
                VarType::Real => 0.123,
                VarType::Integer => 2.0,
                VarType::Boolean => 1.0,
            };
            set(&mut p, x);
            assert_eq!(get(&p), x, "{}", v.name);
            for w in t.variables {
                if let Binding::Param { get: g2, .. } = w.binding {
                    if w.name != v.name {
                        assert_eq!(
                            g2(&p),
                            g2(&M::Params::default()),
                            "{} changed {}",
                            v.name,
                            w.name
                        );
                    }
                }
            }
        }
    }
}

/// A parameter bound to a field (or field path, e.g. `supports[1].z`) of the model's parameters.
macro_rules! param {
    ($name:literal, $ty:ident, $field:ident $([$i:literal].$sub:ident)?, $var:ident, $unit:literal, $range:expr, $desc:literal) => {
        $crate::fmi::variables::Var {
            name: $name,
            ty: $crate::fmi::variables::VarType::$ty,
            causality: $crate::fmi::variables::Causality::Parameter,
            variability: $crate::fmi::variables::Variability::$var,
            unit: $unit,
            description: $desc,
            range: $range,
            binding: $crate::fmi::variables::Binding::Param {
                get: |p| p.$field $([$i].$sub)? as f64,
                set: |p, v| p.$field $([$i].$sub)? = v as _,
            },
        }
    };
}

/// An element of an array field of the parameters (e.g. `link_lengths[2]`).
macro_rules! param_at {
    ($name:literal, $field:ident[$i:literal], $unit:literal, $range:expr, $desc:literal) => {
        $crate::fmi::variables::Var {
            name: $name,
            ty: $crate::fmi::variables::VarType::Real,
            causality: $crate::fmi::variables::Causality::Parameter,
            variability: $crate::fmi::variables::Variability::Fixed,
            unit: $unit,
            description: $desc,
            range: $range,
            binding: $crate::fmi::variables::Binding::Param {
                get: |p| p.$field[$i],
                set: |p, v| p.$field[$i] = v,
            },
        }
    };
}

macro_rules! param_bool {
    ($name:literal, $field:ident, $var:ident, $desc:literal) => {
        $crate::fmi::variables::Var {
            name: $name,
            ty: $crate::fmi::variables::VarType::Boolean,
            causality: $crate::fmi::variables::Causality::Parameter,
            variability: $crate::fmi::variables::Variability::$var,
            unit: "",
            description: $desc,
            range: $crate::fmi::variables::Range::closed(0.0, 1.0),
            binding: $crate::fmi::variables::Binding::Param {
                get: |p| p.$field as i32 as f64,
                set: |p, v| p.$field = v != 0.0,
            },
        }
    };
}

/// A continuous Real input bound to the model's input slot `$slot`.
macro_rules! input {
    ($name:literal, $slot:ident, $start:expr, $unit:literal, $desc:literal) => {
        $crate::fmi::variables::Var {
            name: $name,
            ty: $crate::fmi::variables::VarType::Real,
            causality: $crate::fmi::variables::Causality::Input,
            variability: $crate::fmi::variables::Variability::Continuous,
            unit: $unit,
            description: $desc,
            range: $crate::fmi::variables::Range::ANY,
            binding: $crate::fmi::variables::Binding::Input { slot: $slot, start: $start },
        }
    };
}

/// A Real output read from a field (path) of the model's outputs struct: `output!(...)` for an
/// eagerly evaluated struct (the model's `Output` type is then `fn(&Outputs) -> f64`), or
/// `output!(GROUP => ...)` for a model that evaluates its outputs on demand by groups (`Output`
/// is then `GroupedOutput<Outputs>`).
macro_rules! output {
    ($name:literal, $($field:ident).+, $unit:literal, [$($dep:ident),*], $desc:literal) => {
        output!(Output, Continuous, $name, $($field).+, $unit, [$($dep),*], $desc)
    };
    ($causality:ident, $variability:ident, $name:literal, $($field:ident).+, $unit:literal, [$($dep:ident),*], $desc:literal) => {
        output!(@var $causality, $variability, $name, |o| o.$($field).+, $unit, [$($dep),*], $desc)
    };
    ($group:path => $name:literal, $($field:ident).+, $unit:literal, [$($dep:ident),*], $desc:literal) => {
        output!($group => Output, Continuous, $name, $($field).+, $unit, [$($dep),*], $desc)
    };
    ($group:path => $causality:ident, $variability:ident, $name:literal, $($field:ident).+, $unit:literal, [$($dep:ident),*], $desc:literal) => {
        output!(@var $causality, $variability, $name,
            $crate::fmi::model::GroupedOutput { group: $group, get: |o| o.$($field).+ }, $unit, [$($dep),*], $desc)
    };
    (@var $causality:ident, $variability:ident, $name:literal, $get:expr, $unit:literal, [$($dep:ident),*], $desc:literal) => {
        $crate::fmi::variables::Var {
            name: $name,
            ty: $crate::fmi::variables::VarType::Real,
            causality: $crate::fmi::variables::Causality::$causality,
            variability: $crate::fmi::variables::Variability::$variability,
            unit: $unit,
            description: $desc,
            range: $crate::fmi::variables::Range::ANY,
            binding: $crate::fmi::variables::Binding::Output { get: $get, depends_on: &[$($dep),*] },
        }
    };
}

pub(crate) use {input, output, param, param_at, param_bool};
