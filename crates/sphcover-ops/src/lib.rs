//! Discrete differential operators on a spherical cover (thesis §4), made consistent.
//!
//! A cover's supports are balls `(c_i, r_i)`; neighbouring balls meet in a disk on their radical
//! plane. [`PairGeometry`] computes, once per [`sphcover_core::SphereIntersectionGraph`], the
//! geometry of every pair (thesis eq. 4.33–4.36) and the symmetric edge weight
//! `φ_ij = D_ij / d_ij`, stored in compressed sparse rows aligned with the graph's neighbour
//! array, and the masses `m_i`. The thesis Laplacian is `Lap = M⁻¹ (W − diag(W·1))` with
//! `W = [φ_ij]`: self-adjoint in the `M` inner product, negative semi-definite, so implicit
//! smoothing and Poisson problems are solved by [`conjugate_gradient()`] (Jacobi, block
//! symmetric Gauss–Seidel or two-level preconditioning, [`Preconditioner`]).
//!
//! Operator families behind [`DiscreteOperators`]: the thesis form ([`ThesisOperators`]), the
//! consistent second-order least-squares fit ([`QuadraticFitOperators`], exact on quadratics),
//! and power-cell finite volumes ([`LaguerreOperators`], symmetric and closed, consistent only
//! where the radii vary slowly; see `docs/algorithms.md`, *Discrete differential operators*, for the measured trade-offs).
//! Least-squares fits are solved by pivoted Householder QR, never by normal equations.
//!
//! ```
//! use sphcover_core::{synthetic, Aabb, DVec3, SphereIntersectionGraph};
//! use sphcover_ops::{implicit_smoothing, CgParams, MassKind, PairGeometry};
//!
//! // A 9×9×9 lattice of spacing 0.125 with radius 1.3·h, and its intersection graph.
//! let domain = Aabb { min: DVec3::splat(-0.5), max: DVec3::splat(0.5) };
//! let cover = synthetic::regular_grid(domain, 0.125, 1.3)?;
//! let graph = SphereIntersectionGraph::build(&cover.centres, &cover.radii, 1.0)?;
//! let geometry = PairGeometry::build(&cover.centres, &cover.radii, &graph)?;
//!
//! // The Laplacian of a constant vanishes exactly, that of |x|² is 6 at interior centres once
//! // the moment-matched mass replaces the thesis mass.
//! let ones = vec![1.0; geometry.len()];
//! let mut lap = vec![0.0; geometry.len()];
//! geometry.apply_laplacian(MassKind::Thesis, &ones, &mut lap);
//! assert!(lap.iter().all(|&v| v == 0.0));
//! let sq: Vec<f64> = cover.centres.iter().map(|c| c.length_squared()).collect();
//! geometry.apply_laplacian(MassKind::MomentMatched, &sq, &mut lap);
//! let centre = cover.centres.iter().position(|c| c.length() < 1e-12).unwrap();
//! assert!((lap[centre] - 6.0).abs() < 1e-9);
//!
//! // One implicit smoothing step (M − tW_L) u = M u₀ by preconditioned CG.
//! let (smooth, info) =
//!     implicit_smoothing(&geometry, MassKind::MomentMatched, 1e-3, &sq, &CgParams::default())?;
//! assert!(info.relative_residual <= 1e-8);
//! assert_eq!(smooth.len(), sq.len());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Parameter structs implement `Default` with the documented defaults; set what you need and
//! take the rest with `..Default::default()`.
#![deny(missing_docs)]

mod conjugate_gradient;
mod discrete_operators;
mod error;
mod gauss_seidel;
mod implicit_smoothing;
mod laguerre_operators;
mod least_squares_gradient;
mod operator_matrices;
mod pair_geometry;
mod poisson;
mod quadratic_fit_operators;
mod thesis_operators;
mod two_level;
mod weighted_fit;

pub use conjugate_gradient::{
    CgError, CgInfo, CgParams, CgScratch, Preconditioner, SymmetricOperator, conjugate_gradient,
    dot,
};
pub use discrete_operators::DiscreteOperators;
pub use error::{OpsError, SolveError};
pub use gauss_seidel::{SparseRows, SymmetricGaussSeidel};
pub use implicit_smoothing::{ShiftedStiffness, implicit_smoothing};
pub use laguerre_operators::{CellBound, LaguerreOperators, LaguerreStats};
pub use least_squares_gradient::LeastSquaresGradient;
pub use operator_matrices::{CsrMatrix, OperatorMatrices};
pub use pair_geometry::{MassKind, PairGeometry, PairTerms};
pub use poisson::{PoissonBoundary, solve_poisson};
pub use quadratic_fit_operators::{QuadraticFitOperators, QuadraticFitStats, RowKind};
pub use thesis_operators::{FluxKind, ThesisOperators};
pub use two_level::TwoLevel;
