//! The errors every crate shares: a parameter outside its domain, an array of the wrong
//! length. One type each, so that a user sees the same message whichever stage refused the
//! input.

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

/// An array that should have one entry per item (point, support, node) and has another
/// number.
///
/// ```
/// use sphcover_core::LengthMismatch;
///
/// let e = LengthMismatch::new("normals", 4, 3);
/// assert_eq!(e.to_string(), "normals has 3 entries, expected 4");
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{array} has {found} entries, expected {expected}")]
pub struct LengthMismatch {
    /// Which array.
    pub array: &'static str,
    /// The length it should have.
    pub expected: usize,
    /// The length it has.
    pub found: usize,
}

impl LengthMismatch {
    /// The error for `array`, which has `found` entries instead of `expected`.
    pub fn new(array: &'static str, expected: usize, found: usize) -> LengthMismatch {
        LengthMismatch {
            array,
            expected,
            found,
        }
    }
}
