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
    /// Build the tetrahedral mesh of a cover: the dual complex of its union of balls.
    Tetra(TetraArgs),
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

/// Arguments of `sphcover tetra`.
#[derive(Debug, Args)]
pub struct TetraArgs {
    /// A sphere set (`x y z r` text, or PLY with a `radius` vertex property).
    #[arg(value_name = "SPHERES")]
    pub input: PathBuf,
    /// Output: `.vtk` (VTK legacy unstructured grid, opens in ParaView) or `.txt`/`.tets`
    /// (one tetrahedron per line as four ascending support indices, rows sorted).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Radius factor σ_t applied before triangulating (thesis §3.5.2): below 1 it avoids
    /// skinny tetrahedra near the boundary and hides fewer small spheres.
    #[arg(long, default_value_t = 0.75, value_name = "S")]
    pub shrink: f64,
    /// Seed of the insertion order and point-location walks (the mesh does not depend on it).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// Arguments of a subcommand whose pipeline is not built yet: accepted so that the command
/// can say plainly what is missing instead of failing on the first option.
#[derive(Debug, Args)]
pub struct PendingArgs {
    /// Whatever was given.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    pub rest: Vec<String>,
}
