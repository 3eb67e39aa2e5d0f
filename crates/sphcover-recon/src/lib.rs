//! Surface reconstruction from scanned points (thesis §5), robust to noise, outliers and
//! wrong normals.
//!
//! [`reconstruct`] runs the whole pipeline: scan statistics (spacing,
//! noise, isolated samples), normals when the input has none, the surface cover, the graph
//! cut on the sphere intersection graph ([`graph_cut()`], in-house Boykov–Kolmogorov
//! [`FlowGraph`]), the confidence of samples (eq. 5.39–5.40), diffusion of the local functions
//! ([`diffuse`], over the operators of `sphcover-ops`), and polygonisation by surface nets
//! visited only near the zero set ([`polygonise()`]). Every stage is public so a caller can run
//! one alone.
//!
//! ```
//! use sphcover_core::{DVec3, MeshTopology, PointCloud};
//! use sphcover_recon::{ReconParams, reconstruct};
//!
//! // 3,000 points on a sphere of radius 2 (a Fibonacci lattice), without normals.
//! let n = 3000;
//! let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
//! let positions: Vec<DVec3> = (0..n)
//!     .map(|i| {
//!         let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
//!         let s = (1.0 - z * z).sqrt();
//!         let a = golden * i as f64;
//!         2.0 * DVec3::new(s * a.cos(), s * a.sin(), z)
//!     })
//!     .collect();
//! let cloud = PointCloud::from_positions(positions);
//!
//! let result = reconstruct(&cloud, &ReconParams::default(), &|_stage| {})?;
//! assert!(result.stats.normals_estimated);
//! let topology = MeshTopology::of(&result.mesh);
//! assert!(topology.is_closed_oriented_manifold());
//! assert_eq!((topology.components, topology.euler_characteristic()), (1, 2));
//! // Vertices lie on the sphere, in the input's units.
//! assert!(result.mesh.vertices.iter().all(|v| (v.length() - 2.0).abs() < 0.05));
//! # Ok::<(), sphcover_recon::ReconError>(())
//! ```
//!
//! [`ReconParams`] and the stages' parameter structs implement `Default` with the documented
//! defaults; set what you need and take the rest with `..ReconParams::default()`.
#![deny(missing_docs)]

mod allocator;
mod angle;
mod confidence;
mod csr;
mod diffusion;
mod graph_cut;
mod graphcut_reconstruction;
mod maxflow;
mod memory_budget;
mod memory_model;
mod mesh_smoothing;
mod normals;
mod options;
mod pca;
mod pipeline;
mod polygonise;
mod scan_statistics;
mod vertex_colors;
mod vertex_refinement;

pub use allocator::keep_freed_memory;
pub use confidence::{
    ConfidenceError, ConfidenceParams, ConfidenceStats, SampleConfidence, blend_over_supports,
    sample_confidence, support_confidence,
};
pub use diffusion::{
    DiffusionError, DiffusionParams, DiffusionStats, FittingScale, FittingTerms, PoissonStep,
    diffuse,
};
pub use graph_cut::{
    GraphCut, GraphCutError, GraphCutParams, GraphCutStats, graph_cut, graph_cut_sig,
};
pub use graphcut_reconstruction::{
    GraphCutReconstructionError, GraphCutReconstructionParams, GraphCutReconstructionStats,
    reconstruct_graphcut,
};
pub use maxflow::{FlowEdge, FlowGraph, MaxFlowError, MaxFlowInfo};
pub use memory_budget::{BudgetError, BudgetFit, cover_over_budget_message, fit_memory_budget};
pub use memory_model::{
    COARSEST_BUDGET_DEPTH, RECON_MEMORY_MODEL, ReconMemoryModel, TYPICAL_GRAPH_ENTRIES,
};
pub use mesh_smoothing::{SmoothingError, VertexRings, smooth_two_step};
pub use normals::{EstimatedNormals, NormalError, NormalParams, NormalStats, estimate_normals};
pub use options::{
    MAX_DEPTH, MAX_NORMAL_NEIGHBOURS, NoiseOption, OptionError, ReconOptions, TrimOption,
};
pub use pipeline::{
    DEFAULT_NOISE_TOLERANCE, Method, ONE_VIEW_LAYER_GAP, ONE_VIEW_NEAR, ONE_VIEW_REACH,
    PointBlocks, ReconError, ReconParams, ReconStats, Reconstruction, ScanFile,
    SequentialStreamedTiles, SequentialTiles, StreamedReconstruction, StreamedTile,
    StreamedTileProduct, StreamedTileRunner, TILE_DIRECTORY_PREFIX, TileFunction, TileInput,
    TileRunner, TileStats, Tiling, ToleranceNote, Trim, UNSEEN_NEAR, UNSEEN_REACH, default_depth,
    reconstruct, reconstruct_streamed, reconstruct_tiled, reconstruct_tiled_with,
    reconstruct_until, stage_names, streamed_stage_names, streamed_tile_function, tile_function,
    tiled_stage_names,
};
pub use polygonise::{
    FieldPiece, GridStep, PiecewiseFunction, PolygoniseError, PolygoniseParams, PolygoniseStats,
    UnseenTrim, polygonise, polygonise_blending, polygonise_piecewise,
};
pub use scan_statistics::{
    ONE_VIEW_SHARE, ScanStatistics, ScanStatisticsParams, one_view, scan_statistics,
};
pub use vertex_colors::nearest_sample_colors;
pub use vertex_refinement::{
    RefinementSamples, RefinementScale, VertexRefinementError, VertexRefinementParams,
    VertexRefinementStats, refine_vertices,
};
