//! The spherical cover and everything below the pipelines of `sphcover`.
//!
//! A *cover* is a set of balls ("supports", thesis §3.2), each carrying a small local
//! function; the partition of unity of their weights blends the local functions into one
//! implicit function `f` (thesis eq. 3.1). This crate holds that model, its analytic
//! evaluation, the sphere intersection graph (thesis Appendix B), spatial queries over balls,
//! point and mesh types, and the scan file formats.
//!
//! ```
//! use sphcover_core::{DVec3, PuEvaluator, SphereIntersectionGraph, SurfaceCoverParams};
//! use sphcover_core::{SurfaceSamples, build_surface_cover};
//!
//! // 1,000 oriented points on a sphere of radius 0.4 (a Fibonacci lattice).
//! let n = 1000;
//! let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
//! let normals: Vec<DVec3> = (0..n)
//!     .map(|i| {
//!         let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
//!         let s = (1.0 - z * z).sqrt();
//!         DVec3::new(s * (golden * i as f64).cos(), s * (golden * i as f64).sin(), z)
//!     })
//!     .collect();
//! let points: Vec<DVec3> = normals.iter().map(|&u| 0.4 * u).collect();
//!
//! // The cover of thesis §3.4.1: balls whose local quadratics fit the points to ε.
//! let params = SurfaceCoverParams { eps: 1e-2, ..SurfaceCoverParams::default() };
//! let (cover, _stats) = build_surface_cover(&SurfaceSamples::new(&points, &normals), &params)?;
//!
//! // Their blend f: positive inside, negative outside, zero on the surface.
//! let f = PuEvaluator::new(&cover, 1.0)?;
//! assert!(f.value(DVec3::ZERO).unwrap() > 0.0);
//! assert!(f.value(DVec3::new(0.0, 0.0, 0.5)).unwrap() < 0.0);
//! assert!(f.value(points[0]).unwrap().abs() <= 2.0 * params.eps);
//!
//! // Which supports overlap (thesis Appendix B): every support meets another.
//! let graph = SphereIntersectionGraph::build(cover.centres(), cover.radii(), 1.0)?;
//! assert!((0..cover.len()).all(|i| graph.degree(i) > 0));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Parameter structs (`SurfaceCoverParams`, `VolumeCoverParams`, …) implement `Default` with
//! the documented defaults; set what you need and take the rest with `..Default::default()`.
#![deny(missing_docs)]

mod ball_index;
mod concat;
mod cover;
mod disjoint_sets;
mod geometry;
pub mod io;
mod kernel;
mod local_function;
mod mesh;
mod mesh_topology;
mod opposite_faces;
mod parameter_error;
mod partition_of_unity;
mod point_cloud;
mod point_index;
mod process_memory;
pub mod random;
mod small_cholesky;
mod spatial_order;
mod sphere_intersection_graph;
mod stages;
mod support_samples;
mod surface_cover;
mod symmetric_eigen;
pub mod synthetic;
pub mod this_process;
mod threads;
mod volume;
mod volume_cover;

pub use ball_index::{BallIndex, BallIndexError};
pub use cover::{Cover, CoverError};
pub use disjoint_sets::DisjointSets;
pub use geometry::{Aabb, Normalisation};
pub use glam::{DMat3, DVec3};
pub use kernel::{GAUSSIAN_KAPPA, Kernel};
pub use local_function::{LinearFunction, LocalFunction, LocalFunctions, QuadraticFunction};
pub use mesh::{
    SmallComponentsError, SmallComponentsStats, TriMesh, VertexTriangles, component_areas,
    remove_components, remove_small_components, remove_unused_vertices, triangle_area,
    vertex_normals,
};
pub use mesh_topology::MeshTopology;
pub use opposite_faces::{
    COHERENT_RESULTANT, FACE_COSINE, Face, FaceSelection, OPPOSED_COSINE, face_to_fit, faces_away,
    may_hold_opposite_faces,
};
pub use parameter_error::{LengthMismatch, ParameterError};
pub use partition_of_unity::{PuEvaluator, SupportLists, ValueGradient, ValueGradientHessian};
pub use point_cloud::PointCloud;
pub use point_index::{PointIndex, PointIndexError};
pub use process_memory::{MemorySource, ProcessMemory, READ_LIMIT_PERCENT, process_memory};
pub use small_cholesky::SmallCholesky;
pub use sphere_intersection_graph::{SigError, SphereIntersectionGraph, balls_nested};
pub use stages::{
    Stage, StageProgress, StageTimes, StopRequest, Stopped, run_stages, run_stages_until,
};
pub use support_samples::SupportSamples;
pub use surface_cover::{
    MAX_OCTREE_DEPTH, SurfaceCoverError, SurfaceCoverParams, SurfaceCoverStats,
    SurfaceCoverTimings, SurfaceSamples, build_surface_cover, build_surface_cover_from_cloud,
    build_surface_cover_with_samples,
};
pub use symmetric_eigen::SymmetricEigen3;
pub use threads::on_threads;
pub use volume::{Volume, VolumeError, VoxelValues};
pub use volume_cover::{
    CentreOrder, Elimination, Threshold, VolumeCoverError, VolumeCoverParams, VolumeCoverStats,
    VolumeCoverVariant, build_scattered_cover, build_volume_cover, median_nearest_distance,
    squared_depth_to_background,
};
