//! `max_memory`: the keyword that bounds what a call may allocate, as the command line's
//! `--max-memory` does. A size is an int of bytes or a string as people write it (`"2G"`,
//! `"500M"`, `"1.5GiB"`).
//!
//! Without it, the readers' limit is the command line's default, a share of the memory this
//! process may use ([`sphcover_core::process_memory`]): a file that declares more data than
//! the machine holds is refused from its header, naming the file, instead of ending the
//! interpreter in a failed allocation.

use pyo3::prelude::*;
use sphcover_core::io::{IoError, ReadOptions, parse_byte_size};
use sphcover_core::{READ_LIMIT_PERCENT, process_memory};

use crate::errors::{bad_input, io_error};

/// The size `value` names, in bytes (`None` for None).
pub fn byte_size(value: Option<&Bound<'_, PyAny>>) -> PyResult<Option<u64>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    if let Ok(text) = value.extract::<String>() {
        return parse_byte_size(&text)
            .map(Some)
            .map_err(|e| bad_input(format!("max_memory: {e}")));
    }
    match value.extract::<i128>() {
        Ok(bytes) if (0..=i128::from(u64::MAX)).contains(&bytes) => Ok(Some(bytes as u64)),
        Ok(bytes) => Err(bad_input(format!(
            "max_memory {bytes} must be a non-negative number of bytes"
        ))),
        Err(_) => Err(bad_input(format!(
            "max_memory must be a number of bytes or a size such as \"2G\", not {}",
            value.get_type().name()?
        ))),
    }
}

/// The readers' limit of a call, and where it came from for messages.
pub struct ReadLimit {
    bytes: Option<u64>,
    origin: String,
}

impl ReadLimit {
    /// `max_memory` when given, else the command line's default.
    pub fn new(max_memory: Option<u64>) -> ReadLimit {
        match (max_memory, process_memory()) {
            (Some(bytes), _) => ReadLimit {
                bytes: Some(bytes),
                origin: "max_memory".to_owned(),
            },
            (None, Some(memory)) => ReadLimit {
                bytes: Some(memory.read_limit()),
                origin: format!(
                    "{READ_LIMIT_PERCENT}% of {}; max_memory sets it",
                    memory.describe()
                ),
            },
            (None, None) => ReadLimit {
                bytes: None,
                origin: "none: the machine's memory is unknown".to_owned(),
            },
        }
    }

    /// `options` with this limit.
    pub fn apply(&self, options: ReadOptions) -> ReadOptions {
        ReadOptions {
            max_bytes: self.bytes,
            ..options
        }
    }

    /// A reader's error, with where the limit came from when it was over the limit and the
    /// keyword that drops non-finite vertices when those were refused.
    pub fn error(&self, e: IoError) -> PyErr {
        match e {
            IoError::OverMemoryLimit { .. } => bad_input(format!("{e} ({})", self.origin)),
            IoError::NonFinite { .. } => bad_input(format!("{e}; drop_non_finite=True drops them")),
            IoError::NonFiniteVoxels { all: false, .. } => {
                bad_input(format!("{e}; drop_non_finite=True makes them background"))
            }
            other => io_error(other),
        }
    }
}
