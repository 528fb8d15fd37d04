//! Errors of the pure model, as values. The FMI layer turns each into `fmi2Error` plus one log
//! line, so every message names the variable(s), the value(s) and what is allowed.

use std::fmt;

#[derive(Clone, Debug, PartialEq)]
pub enum ModelError {
    /// A single variable outside its allowed range (includes NaN and ±inf).
    OutOfRange {
        variable: &'static str,
        value: f64,
        allowed: String,
    },
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
                write!(f, "{variable} = {value} is out of range; allowed: {allowed}")
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
