//! Subcommands whose pipelines are not built yet say so plainly and exit non-zero.

use crate::args::PendingArgs;
use crate::report::Reporter;

/// What each pending subcommand will do and which crate it waits for.
fn what(name: &str) -> &'static str {
    match name {
        "recon" => "surface reconstruction (crate sphcover-recon)",
        "skeleton" => "skeletal-sheet extraction (crate sphcover-skeleton)",
        _ => "this subcommand",
    }
}

/// Fails with a message naming what is missing.
pub fn run(name: &str, _args: &PendingArgs, _reporter: &Reporter) -> anyhow::Result<()> {
    anyhow::bail!(
        "`sphcover {name}` is not available in this version: {} is not implemented yet",
        what(name)
    )
}
