//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! Display units: the engineering units a person reads (deg, rpm, kN, kN.m, MPa, mm), declared in
//! `<UnitDefinitions>` so that importers with a GUI (Dymola, OMEdit, Simulink's FMU block) show
//! and accept values in them. The FMU itself always exchanges SI values; FMI 2.0 defines
//! `display = factor·value + offset`.
//!
//! One convention for every FMU of the crate, keyed by the SI unit of the variable table: each
//! unit may offer several display units, and the first marked `default` becomes the
//! `displayUnit` of every Real variable with that unit.

use std::f64::consts::PI;

pub struct DisplayUnit {
    /// The SI unit (as used in the variable tables) it converts from.
    pub unit: &'static str,
    pub name: &'static str,
    pub factor: f64,
    /// Used as the `displayUnit` of the unit's variables.
    pub default: bool,
}

pub const DISPLAY_UNITS: &[DisplayUnit] = &[
    DisplayUnit { unit: "rad", name: "deg", factor: 180.0 / PI, default: true },
    // Crank speeds read as revolutions (strokes) per minute.
    DisplayUnit { unit: "rad/s", name: "rpm", factor: 30.0 / PI, default: true },
    DisplayUnit { unit: "rad/s", name: "deg/s", factor: 180.0 / PI, default: false },
    DisplayUnit { unit: "rad/s2", name: "deg/s2", factor: 180.0 / PI, default: false },
    DisplayUnit { unit: "N", name: "kN", factor: 1e-3, default: true },
    DisplayUnit { unit: "N.m", name: "kN.m", factor: 1e-3, default: true },
    DisplayUnit { unit: "Pa", name: "MPa", factor: 1e-6, default: true },
    // Lengths stay in m by default (strokes are metres); mm is offered for small parts.
    DisplayUnit { unit: "m", name: "mm", factor: 1e3, default: false },
    DisplayUnit { unit: "N/m", name: "N/mm", factor: 1e-3, default: false },
];

/// The display units offered for `unit`.
pub fn for_unit(unit: &str) -> impl Iterator<Item = &'static DisplayUnit> + '_ {
    DISPLAY_UNITS.iter().filter(move |d| d.unit == unit)
}

/// The `displayUnit` of a Real variable with SI unit `unit`, if any.
pub fn default_for(unit: &str) -> Option<&'static str> {
    for_unit(unit).find(|d| d.default).map(|d| d.name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_most_one_default_per_unit_and_unique_names() {
        for d in DISPLAY_UNITS {
            assert!(for_unit(d.unit).filter(|x| x.default).count() <= 1, "{}", d.unit);
            assert_eq!(
                DISPLAY_UNITS.iter().filter(|x| x.unit == d.unit && x.name == d.name).count(),
                1
            );
            assert!(d.factor.is_finite() && d.factor > 0.0);
        }
    }
}
