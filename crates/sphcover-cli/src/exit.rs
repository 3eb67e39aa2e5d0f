//! Exit codes: 0 success, 1 runtime failure, 2 bad usage or bad input.

use sphcover_core::io::IoError;

/// The run succeeded.
pub const SUCCESS: u8 = 0;
/// The run failed for a reason other than its input (an unwritable output, a missing feature).
pub const FAILURE: u8 = 1;
/// The command line or an input file is wrong.
pub const USAGE: u8 = 2;

/// Marks an error as caused by the command line or the input, so it exits with [`USAGE`].
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// The exit code for an error that ended the run.
pub fn code_for(err: &anyhow::Error) -> u8 {
    for cause in err.chain() {
        if cause.downcast_ref::<BadInput>().is_some() {
            return USAGE;
        }
        if let Some(io) = cause.downcast_ref::<IoError>() {
            return if io.is_bad_input() { USAGE } else { FAILURE };
        }
    }
    FAILURE
}
