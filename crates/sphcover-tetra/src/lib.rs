//! Tetrahedral meshes of a spherical cover (thesis §3.5).
#![deny(missing_docs)]

pub mod error;
pub mod expansion;
pub mod predicates;
pub mod regular;
pub mod spatial_sort;

pub use error::TetraError;
pub use regular::{RegularTriangulation, TriangulationParams, VertexStatus};
