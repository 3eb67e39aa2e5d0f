//! Command-line arguments.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// Processing of scanned geometry with spherically supported functions.
#[derive(Debug, Parser)]
#[command(name = "sphcover", version, about, long_about = None)]
pub struct Cli {
    #[command(flatten)]
    pub global: GlobalArgs,
    #[command(subcommand)]
    pub command: Command,
}

/// Options every subcommand takes.
#[derive(Debug, Args)]
pub struct GlobalArgs {
    /// Worker threads (default: one per core). Output does not depend on it.
    #[arg(long, global = true, value_name = "N")]
    pub threads: Option<usize>,
    /// Print per-stage timings and counts to stderr.
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
    /// Print nothing but errors; no progress bars.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub quiet: bool,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Report what a geometry file holds: counts, bounding box, attributes, normals, non-finite values.
    Info(InfoArgs),
    /// Reconstruct a surface mesh from scanned points (not available yet).
    Recon(PendingArgs),
    /// Extract the skeletal sheet of a thin part from a CT volume (not available yet).
    Skeleton(PendingArgs),
    /// Build a spherical cover of points or a volume (not available yet).
    Cover(PendingArgs),
    /// Build the tetrahedral mesh (dual complex) of a cover (not available yet).
    Tetra(PendingArgs),
}

/// Arguments of `sphcover info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Files to inspect (PLY, OBJ, OFF, STL, XYZ/PWN, sphere sets).
    #[arg(required = true, value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// Print the report as JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of a subcommand whose pipeline is not built yet: accepted so that the command
/// can say plainly what is missing instead of failing on the first option.
#[derive(Debug, Args)]
pub struct PendingArgs {
    /// Whatever was given.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    pub rest: Vec<String>,
}
