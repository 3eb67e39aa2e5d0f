//! Typed errors of the crate.

/// Why a triangulation, dual complex or mesh could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TetraError {
    /// The point and weight (or centre and radius) slices differ in length.
    #[error("{points} points but {weights} weights")]
    LengthMismatch {
        /// Number of points.
        points: usize,
        /// Number of weights.
        weights: usize,
    },
    /// A coordinate is not finite or exceeds the proven range of the exact predicates.
    #[error(
        "point {index} has a non-finite coordinate or one beyond ±1e20 (the exact predicates' range)"
    )]
    InvalidPoint {
        /// Index of the offending point.
        index: usize,
    },
    /// A weight (or radius) is not finite or exceeds the proven range.
    #[error("weight or radius {index} is not finite, negative, or too large")]
    InvalidWeight {
        /// Index of the offending weight.
        index: usize,
    },
    /// More points than `u32` handles can address.
    #[error("{count} points exceed the u32 index range")]
    TooManyPoints {
        /// Number of points given.
        count: usize,
    },
    /// The distinct centres do not span 3D space, so there is no tetrahedron.
    #[error(
        "the {distinct} distinct centres span only {dimension} dimension(s); a tetrahedral mesh needs four affinely independent centres"
    )]
    NotFullDimensional {
        /// Dimension of the affine hull of the distinct centres (0, 1 or 2; 0 also for no points).
        dimension: u8,
        /// Number of distinct centres.
        distinct: usize,
    },
    /// The radius shrink factor is not in `(0, ∞)`.
    #[error("radius shrink factor {0} is not a positive finite number")]
    InvalidShrink(f64),
    /// Per-vertex arrays given to a mesh routine have the wrong length.
    #[error("expected {expected} per-vertex values, got {got}")]
    VertexArrayLength {
        /// Number of mesh vertices.
        expected: usize,
        /// Length of the array given.
        got: usize,
    },
}
