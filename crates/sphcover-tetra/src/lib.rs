//! Tetrahedral meshes of a spherical cover (thesis §3.5): exact predicates, the 3D regular
//! triangulation of the support centres weighted by `r²`, the dual complex of the union of
//! balls, [`TetMesh`] with unique edges and ordered edge rings, and marching tetrahedra.
//!
//! ```
//! use sphcover_core::DVec3;
//! use sphcover_tetra::{DualComplexParams, TetMesh, dual_complex, marching_tetrahedra_scalar};
//!
//! // Eight overlapping balls at the corners of a cube, one ball in the middle.
//! let mut centres = Vec::new();
//! for i in 0..8 {
//!     centres.push(DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64));
//! }
//! centres.push(DVec3::splat(0.5));
//! let radii = vec![0.9; centres.len()];
//! let dc = dual_complex(&centres, &radii, &DualComplexParams { shrink: 1.0, ..Default::default() })?;
//! assert!(!dc.tets.is_empty());
//! let mesh = TetMesh::from_dual_complex(&dc);
//! // The union is a ball: the dual complex is contractible.
//! assert_eq!(mesh.euler_characteristic(), 1);
//! // Cut the mesh by a plane through the middle.
//! let pos: Vec<DVec3> = mesh.vertices.iter().map(|&v| centres[v as usize]).collect();
//! let val: Vec<f64> = pos.iter().map(|p| p.z - 0.3).collect();
//! let surface = marching_tetrahedra_scalar(&mesh, &pos, &val, None)?;
//! assert!(surface.triangles.len() >= 2);
//! # Ok::<(), sphcover_tetra::TetraError>(())
//! ```
//!
//! # Architecture
//!
//! Topology is kept apart from geometry and every handle is a `u32` (the spade layout):
//!
//! ```text
//! expansion ──► predicates ──► regular ──► dual_complex ──► tet_mesh ──► marching
//!                  ▲              ▲
//!             (exact signs)  spatial_sort (BRIO + Hilbert order, seeded RNG)
//! ```
//!
//! * `expansion` (private): Shewchuk's exact floating-point expansions, and a `Ring`
//!   trait so a predicate polynomial is written once and evaluated with a running error bound
//!   or exactly.
//! * [`predicates`]: `orient3d`, the lifted power test, the coplanar power-circle test and the
//!   orthocentre-power sign, each exact and adaptive (static float filter, then an `i128`
//!   stage for dyadic inputs such as grids and octrees, then expansions), with CGAL's
//!   lexicographic symbolic perturbation for ties.
//! * `spatial_sort` (private): the insertion order.
//! * [`RegularTriangulation`]: incremental Bowyer–Watson with a remembering
//!   stochastic walk, an infinite vertex, hidden (redundant) points; `u32` handles, per
//!   tetrahedron one 32-byte block of its 4 vertices and 4 neighbours, a free list; large
//!   rounds of the insertion order inserted in parallel, region by region.
//! * [`dual_complex()`]: the tetrahedra whose orthocentre has power ≤ 0, with the radius shrink
//!   `σ_t` of thesis §3.5.2; [`overlap_complex()`]: the tetrahedra whose balls overlap
//!   pairwise, a superset that stays full across thin slabs of supports;
//!   [`overlap_complex_admitting()`]: with it, the tetrahedra a caller admits among those
//!   whose grown balls overlap pairwise.
//! * [`TetMesh`]: plain arrays and CSR offsets, built vertex by vertex in parallel.
//! * [`marching_tetrahedra`]: marching tetrahedra on a [`TetMesh`].
//!
//! Determinism: the same input and seed give the same output, whatever the thread count
//! (large insertion rounds run region by region, with regions that depend on the input
//! alone; the sorts of distinct keys, the renumbering, the per-tetrahedron filter and the
//! mesh's per-vertex edges and rings run in parallel, item by item, and are concatenated in
//! item order).
//!
//! Parameter structs implement `Default` with the documented defaults; set what you need and
//! take the rest with `..Default::default()`, as the example does.
#![deny(missing_docs)]

mod dual_complex;
mod error;
mod expansion;
mod marching;
mod mesh_file;
mod overlap_complex;
pub mod predicates;
mod regular;
mod spatial_sort;
mod tet_mesh;

pub use dual_complex::{DualComplex, DualComplexParams, dual_complex, dual_complex_of};
pub use error::TetraError;
pub use marching::{IsoSurface, marching_tetrahedra, marching_tetrahedra_scalar};
pub use mesh_file::{TetMeshFormat, write_tet_mesh};
pub use overlap_complex::{overlap_complex, overlap_complex_admitting, overlap_complex_of};
pub use regular::{
    INFINITE_VERTEX, NO_TET, RegularTriangulation, TriangulationParams, VertexStatus,
};
pub use tet_mesh::TetMesh;
