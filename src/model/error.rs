//! Errors of the pure model, as values. The FMI layer turns each into `fmi2Error` plus one log
//! line, so every message names the variable(s), the value(s) and what is allowed.

use std::fmt;

#[derive(Clone, Debug, PartialEq)]
pub enum ModelError {
    /// A single variable outside its allowed range (includes NaN and ±inf).
    OutOfRange { variable: &'static str, value: f64, allowed: String },
    /// A combination of parameters that is not a valid machine (the linkage does not assemble,
    /// supports do not hold the link, ...). The message names the condition and the values.
    Invalid { message: String },
    /// The model cannot produce a valid result at the current inputs (self-locking guide,
    /// buckled rod, integrator failure). The FMU's state is left as it was.
    Evaluation { message: String },
}

impl ModelError {
    pub fn out_of_range(variable: &'static str, value: f64, allowed: impl Into<String>) -> Self {
        ModelError::OutOfRange { variable, value, allowed: allowed.into() }
    }
    pub fn invalid(message: impl Into<String>) -> Self {
        ModelError::Invalid { message: message.into() }
    }
    pub fn evaluation(message: impl Into<String>) -> Self {
        ModelError::Evaluation { message: message.into() }
    }
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ModelError::OutOfRange { variable, value, allowed } => {
                write!(f, "{variable} = {} is out of range; allowed: {allowed}", num(*value))
            }
            ModelError::Invalid { message } | ModelError::Evaluation { message } => {
                f.write_str(message)
            }
        }
    }
}

impl std::error::Error for ModelError {}

/// Checks that `value` is finite; the error names the variable.
pub fn require_finite(variable: &'static str, value: f64) -> Result<f64, ModelError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ModelError::out_of_range(variable, value, "a finite number"))
    }
}

/// A number in a message, short: 1e308 as `1e308`, 0.0025 as `0.0025`, 2.5e-7 as `2.5e-7`
/// (never hundreds of digits), NaN and infinities as such.
pub fn num(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || !v.is_finite() || (1e-4..1e15).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod num_tests {
    use super::num;

    #[test]
    fn short_numbers() {
        assert_eq!(num(1e308), "1e308");
        assert_eq!(num(-1e-300), "-1e-300");
        assert_eq!(num(2.5e-7), "2.5e-7");
        assert_eq!(num(0.001), "0.001");
        assert_eq!(num(0.2), "0.2");
        assert_eq!(num(f64::NAN), "NaN");
        assert_eq!(num(f64::INFINITY), "inf");
    }
}
