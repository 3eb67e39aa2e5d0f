//! The one error every crate gives for a parameter outside its domain, so that a user sees
//! the same message whichever stage refused the value.

/// A parameter outside its domain: its name, the value given, and what it must be.
///
/// ```
/// use sphcover_core::ParameterError;
///
/// let e = ParameterError::new("eps", -1.0, "a finite positive number");
/// assert_eq!(e.to_string(), "parameter `eps` = -1 is invalid: expected a finite positive number");
/// ```
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("parameter `{name}` = {value} is invalid: expected {expected}")]
pub struct ParameterError {
    /// The parameter's name, as in its params struct.
    pub name: &'static str,
    /// The value given.
    pub value: f64,
    /// What the value must be.
    pub expected: &'static str,
}

impl ParameterError {
    /// The error for `name` = `value`, which must be `expected`.
    pub fn new(name: &'static str, value: f64, expected: &'static str) -> ParameterError {
        ParameterError {
            name,
            value,
            expected,
        }
    }
}
