//! The exceptions: the two kinds of failure the command line tells apart by its exit code.
//!
//! [`BadInputError`] (a `ValueError`) is what `sphcover` exits with 2 for: a malformed or
//! unreadable file, an option out of range, input the method cannot treat. [`SphcoverError`]
//! (a `RuntimeError`) is a failure of the run itself (exit 1). The message is the library's,
//! as the command line prints it after the file name.

use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use sphcover_core::io::IoError;
use sphcover_recon::{OptionError, ReconError, cover_over_budget_message};
use sphcover_skeleton::SkeletonError;
use sphcover_tetra::TetraError;

create_exception!(
    sphcover,
    BadInputError,
    PyValueError,
    "The input or an option is unusable (the command line exits with 2)."
);
create_exception!(
    sphcover,
    SphcoverError,
    PyRuntimeError,
    "A run failed for a reason other than its input (the command line exits with 1)."
);

/// A bad-input exception with `message`.
pub fn bad_input(message: impl Into<String>) -> PyErr {
    BadInputError::new_err(message.into())
}

/// Emits `message` as a Python `UserWarning` (an error when the warnings filter says so).
pub fn warn(py: Python<'_>, message: &str) -> PyResult<()> {
    let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
    PyErr::warn(py, &category, &std::ffi::CString::new(message)?, 1)
}

/// A runtime-failure exception with `message`.
pub fn failure(message: impl Into<String>) -> PyErr {
    SphcoverError::new_err(message.into())
}

/// A reader's or writer's error, of the kind [`IoError::is_bad_input`] says.
pub fn io_error(e: IoError) -> PyErr {
    if e.is_bad_input() {
        bad_input(e.to_string())
    } else {
        failure(e.to_string())
    }
}

/// An option out of range, named by its keyword.
pub fn option_error(e: OptionError) -> PyErr {
    bad_input(e.to_string())
}

/// A reconstruction's error, split as `sphcover recon` splits it.
pub fn recon_error(e: ReconError) -> PyErr {
    if let Some(message) = cover_over_budget_message(&e, "max_memory", "tiles", "eps") {
        return bad_input(message);
    }
    if e.is_bad_input() {
        bad_input(e.to_string())
    } else {
        failure(e.to_string())
    }
}

/// A skeleton's error, split as `sphcover skeleton` splits it: the lower layers' failures are
/// the run's, every other is the input's.
pub fn skeleton_error(e: SkeletonError) -> PyErr {
    match e {
        SkeletonError::Tetra(_) | SkeletonError::Evaluator(_) | SkeletonError::Stopped(_) => {
            failure(e.to_string())
        }
        e => bad_input(e.to_string()),
    }
}

/// A triangulation's error: `sphcover tetra` treats each as bad input.
pub fn tetra_error(e: TetraError) -> PyErr {
    bad_input(e.to_string())
}
