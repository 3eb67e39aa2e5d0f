//! Tetrahedral meshes of a spherical cover (thesis §3.5).
//!
//! This crate will hold exact adaptive predicates (orient3d and the lifted power test with
//! symbolic perturbation), an incremental 3D regular triangulation of support centres weighted
//! by `r²`, the dual complex of the union of balls (tetrahedra whose orthocentre has negative
//! power), the `TetMesh` type with unique edges and cyclic edge rings, and marching tetrahedra.
//!
//! It depends only on `sphcover-core`. Nothing is implemented yet, so it exposes no API.
#![deny(missing_docs)]
