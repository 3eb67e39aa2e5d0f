//! The spherical cover and everything below the pipelines of `sphcover`.
//!
//! A *cover* is a set of balls ("supports", thesis §3.2), each carrying a small local
//! function; the partition of unity of their weights blends the local functions into one
//! implicit function `f` (thesis eq. 3.1). This crate holds that model, its analytic
//! evaluation, the sphere intersection graph (thesis Appendix B), spatial queries over balls,
//! point and mesh types, and the scan file formats.
#![deny(missing_docs)]

pub mod ball_index;
pub mod cover;
pub mod geometry;
pub mod io;
pub mod kernel;
pub mod local_function;
pub mod mesh;
pub mod mesh_topology;
pub mod partition_of_unity;
pub mod point_cloud;
pub mod point_index;
pub mod sphere_intersection_graph;
pub mod surface_cover;
pub mod synthetic;
pub mod volume;
pub mod volume_cover;

pub use ball_index::{BallIndex, BallIndexError};
pub use cover::{Cover, CoverError};
pub use geometry::{Aabb, Normalisation};
pub use glam::{DMat3, DVec3};
pub use kernel::Kernel;
pub use local_function::{LinearFunction, LocalFunction, LocalFunctions, QuadraticFunction};
pub use mesh::TriMesh;
pub use mesh_topology::MeshTopology;
pub use partition_of_unity::{PuEvaluator, ValueGradient, ValueGradientHessian};
pub use point_cloud::PointCloud;
pub use point_index::{PointIndex, PointIndexError};
pub use sphere_intersection_graph::{SigError, SphereIntersectionGraph};
pub use surface_cover::{
    SurfaceCoverError, SurfaceCoverParams, SurfaceCoverStats, SurfaceCoverTimings,
    build_surface_cover, build_surface_cover_from_cloud, build_surface_cover_with_confidence,
};
pub use volume::{Volume, VolumeError, VoxelValues};
pub use volume_cover::{
    CentreOrder, Threshold, VolumeCoverError, VolumeCoverParams, VolumeCoverStats,
    VolumeCoverVariant, build_scattered_cover, build_volume_cover,
};
