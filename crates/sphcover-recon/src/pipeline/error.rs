//! Why a reconstruction fails: the error type of every stage of the pipeline, and which of
//! its cases lie with the input.

use sphcover_core::{
    CoverError, DVec3, ParameterError, PointIndexError, SigError, SmallComponentsError, Stopped,
    SurfaceCoverError,
};
use sphcover_ops::OpsError;
use thiserror::Error;

use crate::confidence::ConfidenceError;
use crate::diffusion::DiffusionError;
use crate::graph_cut::GraphCutError;
use crate::graphcut_reconstruction::GraphCutReconstructionError;
use crate::normals::NormalError;
use crate::polygonise::PolygoniseError;
use crate::vertex_refinement::VertexRefinementError;

/// Why reconstruction failed.
#[derive(Debug, Error)]
pub enum ReconError {
    /// Too few usable points.
    #[error("{found} usable points; reconstruction needs at least {needed}")]
    TooFewPoints {
        /// Points with finite coordinates.
        found: usize,
        /// The minimum.
        needed: usize,
    },
    /// All points coincide (no extent to reconstruct).
    #[error("all {0} points coincide: there is no surface to reconstruct")]
    NoExtent(usize),
    /// The points lie on a line, to rounding, and have no normals: every plane through the
    /// line fits them, so no surface is determined.
    #[error(
        "the points lie on a line, to rounding, and have no normals: no surface is determined (give normals, which choose the plane through the line, or points spread in more dimensions)"
    )]
    Collinear,
    /// The points lie on a plane (or on a line, with normals) and the surface is not trimmed.
    #[error(
        "the points lie on a plane, to rounding: they enclose nothing, and the untrimmed surface would be their plane extrapolated over the whole bounding box; trim the surface to the samples for the flat sheet they cover"
    )]
    Flat,
    /// One point lies so far from the rest that, in the frame of its bounding box, the rest
    /// of the scan cannot be resolved.
    #[error(
        "point {index} at ({:?}, {:?}, {:?}) lies {ratio:.1e} times the scan's median radius from its centre: remove such far outliers first (more than 10^9 radii away, the rest of the scan cannot be resolved in the frame of the bounding box)",
        position.x,
        position.y,
        position.z
    )]
    FarPoint {
        /// Its index in the input.
        index: usize,
        /// Its position.
        position: DVec3,
        /// Its distance from the coordinate-wise median, in median distances to it.
        ratio: f64,
    },
    /// A parameter is out of range.
    #[error(transparent)]
    InvalidParameter(#[from] ParameterError),
    /// Normal estimation failed.
    #[error("normal estimation: {0}")]
    Normals(#[from] NormalError),
    /// The cover could not be built.
    #[error("surface cover: {0}")]
    Cover(#[from] SurfaceCoverError),
    /// A cover operation failed.
    #[error("cover: {0}")]
    CoverUpdate(#[from] CoverError),
    /// The sphere intersection graph could not be built.
    #[error("sphere intersection graph: {0}")]
    Graph(#[from] SigError),
    /// The graph cut failed.
    #[error("graph cut: {0}")]
    GraphCut(#[from] GraphCutError),
    /// The graph-cut-only reconstruction failed.
    #[error("graph-cut reconstruction: {0}")]
    GraphCutReconstruction(#[from] GraphCutReconstructionError),
    /// Confidence could not be computed.
    #[error("confidence: {0}")]
    Confidence(#[from] ConfidenceError),
    /// The pair geometry could not be built.
    #[error("operators: {0}")]
    Operators(#[from] OpsError),
    /// Diffusion failed.
    #[error("diffusion: {0}")]
    Diffusion(#[from] DiffusionError),
    /// Polygonisation failed.
    #[error("polygonisation: {0}")]
    Polygonise(#[from] PolygoniseError),
    /// The samples could not be indexed.
    #[error("sample index: {0}")]
    Index(#[from] PointIndexError),
    /// Small components could not be removed.
    #[error(transparent)]
    SmallComponents(#[from] SmallComponentsError),
    /// Vertex refinement failed.
    #[error("vertex refinement: {0}")]
    Refinement(#[from] VertexRefinementError),
    /// Nothing was left to mesh.
    #[error("the reconstruction is empty: {0}")]
    Empty(&'static str),
    /// The method builds no function that tiles can share ([`reconstruct_tiled`](super::reconstruct_tiled)).
    #[error(
        "the {0} method cannot be tiled: its surface comes from the dual complex of the whole cover, not from a function each tile can build"
    )]
    NotTileable(&'static str),
    /// A [`TileRunner`](super::TileRunner) failed or returned something other than the tiles' functions.
    #[error("tiles: {0}")]
    TileRunner(String),
    /// The scan could not be read ([`reconstruct_streamed`](super::reconstruct_streamed)).
    #[error(transparent)]
    Read(#[from] sphcover_core::io::IoError),
    /// The tile files of a streamed reconstruction could not be written or read back.
    #[error("tile files: {0}")]
    Scratch(String),
    /// The cover needs more memory than [`ReconParams::memory_budget`](super::ReconParams::memory_budget) allows.
    #[error(
        "{}, over the budget of {}",
        crate::memory_budget::cover_needs(*.supports, *.graph_entries, *.estimate),
        sphcover_core::io::format_byte_size(*.budget)
    )]
    OverMemoryBudget {
        /// Supports of the cover.
        supports: usize,
        /// Directed entries of its sphere intersection graph.
        graph_entries: u64,
        /// The predicted peak, in bytes.
        estimate: u64,
        /// The budget, in bytes.
        budget: u64,
    },
    /// The caller asked the pipeline to stop ([`reconstruct_until`](super::reconstruct_until)).
    #[error(transparent)]
    Stopped(#[from] Stopped),
}

impl ReconError {
    /// True when the error lies with the input (too few or degenerate points, nothing left
    /// after outlier removal, flat points without trimming) rather than with the run: a
    /// command line exits with its bad-input code for these.
    pub fn is_bad_input(&self) -> bool {
        matches!(
            self,
            ReconError::TooFewPoints { .. }
                | ReconError::NoExtent(_)
                | ReconError::Collinear
                | ReconError::Flat
                | ReconError::FarPoint { .. }
                | ReconError::Empty(_)
                | ReconError::Read(_)
                | ReconError::Cover(SurfaceCoverError::NoUsablePoints { .. })
                | ReconError::OverMemoryBudget { .. }
        )
    }
}
