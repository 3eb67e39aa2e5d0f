//! Tetrahedral meshes of a spherical cover (thesis §3.5).
#![deny(missing_docs)]

pub mod dual_complex;
pub mod error;
pub mod expansion;
pub mod predicates;
pub mod regular;
pub mod spatial_sort;

pub use dual_complex::{DualComplex, DualComplexParams, dual_complex, dual_complex_of};
pub use error::TetraError;
pub use regular::{RegularTriangulation, TriangulationParams, VertexStatus};
