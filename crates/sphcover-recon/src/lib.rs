//! Surface reconstruction from scanned points (thesis §5).
//!
//! This crate will hold the reconstruction pipeline: confidence of samples (eq. 5.39–5.40),
//! a Boykov–Kolmogorov max-flow graph cut on the sphere intersection graph and on the
//! tetrahedral mesh, diffusion of local functions with fitting terms, normal estimation for
//! unoriented input, and polygonisation by surface nets visited only near the zero set.
//!
//! It builds on `sphcover-core`, `sphcover-ops` and `sphcover-tetra`.
#![deny(missing_docs)]

pub mod confidence;
pub mod diffusion;
pub mod graph_cut;
pub mod graphcut_reconstruction;
pub mod maxflow;
pub mod normals;
mod pca;
pub mod pipeline;

pub use confidence::{
    ConfidenceError, ConfidenceParams, ConfidenceStats, SampleConfidence, blend_over_supports,
    sample_confidence, sample_confidence_with, support_confidence,
};
pub use diffusion::{
    DiffusionError, DiffusionParams, DiffusionStats, FittingScale, FittingTerms, PoissonStep,
    diffuse,
};
pub use graph_cut::{
    GraphCut, GraphCutError, GraphCutParams, GraphCutStats, graph_cut, graph_cut_csr,
    graph_cut_sig, graph_cut_tet,
};
pub use graphcut_reconstruction::{
    GraphCutReconstructionError, GraphCutReconstructionParams, GraphCutReconstructionStats,
    reconstruct_graphcut,
};
pub use maxflow::{FlowEdge, FlowGraph, MaxFlowError, MaxFlowInfo};
pub use normals::{EstimatedNormals, NormalError, NormalParams, NormalStats, estimate_normals};
pub mod mesh_smoothing;

pub use mesh_smoothing::{SmoothingError, VertexRings, smooth_two_step};
pub mod polygonise;

pub use pipeline::{
    Method, ReconError, ReconParams, ReconStats, Reconstruction, default_depth, reconstruct,
};
pub use polygonise::{GridStep, PolygoniseError, PolygoniseParams, PolygoniseStats, polygonise};
