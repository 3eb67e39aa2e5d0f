//! Typed errors of the operator constructors and solvers.

use glam::DVec3;
use sphcover_core::LengthMismatch;
use sphcover_core::ParameterError;
use thiserror::Error;

/// Why operators could not be built on a cover, or a problem on them could not be set up.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum OpsError {
    /// An array does not have one entry per support.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
    /// The graph was built on a different number of supports than the cover has.
    #[error("the graph has {graph} nodes but the cover has {supports} supports")]
    GraphMismatch {
        /// Number of graph nodes.
        graph: usize,
        /// Number of supports given.
        supports: usize,
    },
    /// A graph row names a node out of range.
    #[error("graph row {row} names node {neighbour}, out of range")]
    InvalidGraph {
        /// Row of the bad entry.
        row: usize,
        /// The neighbour index found.
        neighbour: u32,
    },
    /// A centre has a NaN or infinite coordinate.
    #[error("support {index}: centre {centre} is not finite")]
    NonFiniteCentre {
        /// Index of the support.
        index: usize,
        /// The centre given.
        centre: DVec3,
    },
    /// A radius is NaN, infinite or negative.
    #[error("support {index}: radius {radius} is not finite and non-negative")]
    InvalidRadius {
        /// Index of the support.
        index: usize,
        /// The radius given.
        radius: f64,
    },
    /// A value array (field, right-hand side) holds a NaN or infinity.
    #[error("{array}[{index}] is not finite")]
    NonFiniteValue {
        /// Name of the array.
        array: &'static str,
        /// Index of the first bad entry.
        index: usize,
    },
    /// A parameter is out of its documented range.
    #[error(transparent)]
    InvalidParameter(#[from] ParameterError),
    /// A boundary condition names a support out of range.
    #[error("boundary condition names support {support}, but the cover has {len}")]
    BoundarySupportOutOfRange {
        /// The support named.
        support: u32,
        /// Number of supports.
        len: usize,
    },
    /// A connected component of the operator graph (of more than one support) has no fixed
    /// value, so the Poisson problem on it has no unique solution.
    #[error("the component containing support {support} has no anchor or boundary value")]
    UnconstrainedComponent {
        /// One support of the component.
        support: usize,
    },
}

/// Why a problem solved on the operators (smoothing, Poisson) failed.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum SolveError {
    /// The problem is ill-posed or its inputs are invalid.
    #[error(transparent)]
    Setup(#[from] OpsError),
    /// The conjugate-gradient solve failed.
    #[error(transparent)]
    Solver(#[from] crate::conjugate_gradient::CgError),
}
