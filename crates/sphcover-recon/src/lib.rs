//! Surface reconstruction from scanned points (thesis §5).
//!
//! This crate will hold the reconstruction pipeline: confidence of samples (eq. 5.39–5.40),
//! a Boykov–Kolmogorov max-flow graph cut on the sphere intersection graph and on the
//! tetrahedral mesh, diffusion of local functions with fitting terms, normal estimation for
//! unoriented input, and polygonisation by surface nets visited only near the zero set.
//!
//! It builds on `sphcover-core`, `sphcover-ops` and `sphcover-tetra`. Nothing is implemented
//! yet, so it exposes no API.
#![deny(missing_docs)]

pub mod mesh_smoothing;
pub mod polygonise;
pub mod small_components;
pub mod unused_vertices;

pub use mesh_smoothing::{SmoothingError, VertexRings, smooth_two_step};
pub use polygonise::{GridStep, PolygoniseError, PolygoniseParams, PolygoniseStats, polygonise};
pub use small_components::{SmallComponentsError, SmallComponentsStats, remove_small_components};
pub use unused_vertices::remove_unused_vertices;
