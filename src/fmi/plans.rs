//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! The value references of the arrays a master passes to fmi2GetReal and fmi2SetReal at every
//! step, resolved once per instance (docs/performance.md "Read and input plans"): the variable
//! table is consulted again only when the array's contents change. Used by the fast paths of
//! `Instance::quick_get_real` and `Instance::quick_set_real`.

use crate::fmi::model::FmuModel;
use crate::fmi::variables::{VarInfo, VarType};

/// The input slots of the value references of one fmi2SetReal of inputs only, resolved once
/// for the array a master passes at every step (as [`ReadPlan`] for fmi2GetReal).
pub(crate) struct InputPlan<M: FmuModel> {
    vrs: [u32; INPUT_PLAN_SIZE],
    len: usize,
    pub(crate) slots: [Option<M::Input>; INPUT_PLAN_SIZE],
}

/// The longest fmi2SetReal an input plan is kept for (the table has a handful of inputs).
const INPUT_PLAN_SIZE: usize = 8;

impl<M: FmuModel> InputPlan<M> {
    /// Whether this plan was resolved for `vrs` (their contents, wherever they are).
    #[inline]
    pub(crate) fn is_for(&self, vrs: &[u32]) -> bool {
        same_refs(&self.vrs, self.len, vrs)
    }

    pub(crate) fn empty() -> Self {
        InputPlan { vrs: [0; INPUT_PLAN_SIZE], len: 0, slots: [None; INPUT_PLAN_SIZE] }
    }

    /// The plan for `vrs`: None unless every one is a Real input of the table (whose index
    /// `values` has) and there are at most [`INPUT_PLAN_SIZE`].
    pub(crate) fn resolve(info: &[VarInfo<M>], values: usize, vrs: &[u32]) -> Option<Self> {
        if vrs.len() > INPUT_PLAN_SIZE {
            return None;
        }
        let mut plan = Self::empty();
        for (k, &vr) in vrs.iter().enumerate() {
            let v = info
                .get(vr as usize)
                .filter(|v| v.ty == VarType::Real && (vr as usize) < values)?;
            plan.slots[k] = Some(v.slot?);
            plan.vrs[k] = vr;
        }
        plan.len = vrs.len();
        Some(plan)
    }
}

/// Where the values of one fmi2GetReal come from, resolved once for the array of value
/// references a master passes at every step: the variable table is consulted when the array
/// changes, not at every call. WHY: checking and resolving each value reference cost more per
/// value than reading it (docs/performance.md).
pub(crate) struct ReadPlan<M: FmuModel> {
    /// The value references, `len` of them (0: no plan).
    vrs: [u32; PLAN_SIZE],
    len: usize,
    /// The groups the outputs among them need ([`FmuModel::needs`]).
    pub(crate) need: u8,
    pub(crate) sources: [Source<M::Output>; PLAN_SIZE],
}

/// Whether the first `len` of a plan's value references are `vrs`: one pass without a branch
/// per value, where `==` of the slices would call memcmp, whose call costs more than comparing
/// a master's handful of value references.
#[inline]
fn same_refs(plan: &[u32], len: usize, vrs: &[u32]) -> bool {
    len == vrs.len() && plan.iter().zip(vrs).fold(true, |same, (a, b)| same & (a == b))
}

/// The longest fmi2GetReal a plan is kept for; longer calls resolve every value each time.
const PLAN_SIZE: usize = 16;

#[derive(Clone, Copy)]
pub(crate) enum Source<O> {
    /// A parameter or input: `core.values[i]`.
    Value(usize),
    Output(O),
}

impl<M: FmuModel> ReadPlan<M> {
    /// Whether this plan was resolved for `vrs` (their contents, wherever they are).
    #[inline]
    pub(crate) fn is_for(&self, vrs: &[u32]) -> bool {
        same_refs(&self.vrs, self.len, vrs)
    }

    pub(crate) fn empty() -> Self {
        ReadPlan { vrs: [0; PLAN_SIZE], len: 0, need: 0, sources: [Source::Value(0); PLAN_SIZE] }
    }

    /// The plan for `vrs`, from the table's `info`: None when a value reference is not a Real
    /// (the general path then names it) or the call is longer than a plan.
    pub(crate) fn resolve(info: &[VarInfo<M>], vrs: &[u32]) -> Option<Self> {
        if vrs.len() > PLAN_SIZE {
            return None;
        }
        let mut plan = Self::empty();
        for (k, &vr) in vrs.iter().enumerate() {
            let v = info.get(vr as usize).filter(|v| v.ty == VarType::Real)?;
            plan.sources[k] = match v.output {
                Some(o) => {
                    plan.need |= M::needs(o);
                    Source::Output(o)
                }
                None => Source::Value(vr as usize),
            };
            plan.vrs[k] = vr;
        }
        plan.len = vrs.len();
        Some(plan)
    }
}
