//! The spherical cover and everything below the pipelines of `sphcover`.
//!
//! A *cover* is a set of balls ("supports", thesis §3.2), each carrying a small local
//! function; the partition of unity of their weights blends the local functions into one
//! implicit function `f` (thesis eq. 3.1). This crate holds that model, its analytic
//! evaluation, the sphere intersection graph (thesis Appendix B), spatial queries over balls,
//! point and mesh types, and the scan file formats.
#![deny(missing_docs)]

pub mod ball_index;
pub mod geometry;
pub mod mesh;
pub mod point_cloud;
pub mod sphere_intersection_graph;
pub mod synthetic;

pub use ball_index::{BallIndex, BallIndexError};
pub use geometry::{Aabb, Normalisation};
pub use glam::{DMat3, DVec3};
pub use mesh::TriMesh;
pub use point_cloud::PointCloud;
pub use sphere_intersection_graph::{SigError, SphereIntersectionGraph};
