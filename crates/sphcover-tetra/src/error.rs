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
    /// A coordinate is not finite.
    #[error("point {index} has a non-finite coordinate")]
    InvalidPoint {
        /// Index of the offending point.
        index: usize,
    },
    /// A weight is not finite, or a radius is not finite or negative.
    #[error("weight or radius {index} is not finite, or is a negative radius")]
    InvalidWeight {
        /// Index of the offending weight.
        index: usize,
    },
    /// The coordinates span more orders of magnitude, from the largest magnitude down to the
    /// finest binary digit any coordinate carries, than the exact predicates support after
    /// any power-of-two scaling: products of up to eight coordinate differences would
    /// underflow or overflow `f64` (the domain is derived in `src/regular/domain.rs`).
    #[error(
        "coordinates span {orders} orders of magnitude, from {largest:.3e} (point {largest_point}) down to the finest binary digit {finest_digit:.1e} (point {finest_point}); the exact predicates support at most {max_orders}"
    )]
    CoordinateSpan {
        /// Orders of magnitude spanned (rounded).
        orders: u32,
        /// The most the exact predicates support.
        max_orders: u32,
        /// The largest coordinate magnitude.
        largest: f64,
        /// The point holding it.
        largest_point: usize,
        /// The finest binary digit set in any coordinate (a power of two).
        finest_digit: f64,
        /// The point holding it.
        finest_point: usize,
    },
    /// The coordinates fit the exact predicates, but a weight (a squared radius, which the
    /// predicates multiply with products of coordinate differences) is too large or too
    /// small for them: no power-of-two scaling keeps those products within the `f64` range.
    #[error(
        "radius {index} ({radius:.3e}; weights are squared radii) is too {} for coordinates from {largest_coordinate:.3e} down to the finest binary digit {finest_coordinate_digit:.1e}: the exact predicates multiply squared radii with products of coordinate differences, and no power-of-two scaling keeps those products within the f64 range",
        if *too_large { "large" } else { "small" }
    )]
    RadiusScale {
        /// Index of the radius (or weight).
        index: usize,
        /// That radius (for a weight `w`: `√|w|`).
        radius: f64,
        /// Whether it is too large; otherwise too small (its finest digit too fine).
        too_large: bool,
        /// The largest coordinate magnitude.
        largest_coordinate: f64,
        /// The finest binary digit set in any coordinate (a power of two).
        finest_coordinate_digit: f64,
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
    /// The growth of [`overlap_complex_admitting`](crate::overlap_complex_admitting) is not
    /// in `[1, ∞)`.
    #[error("ball growth factor {0} is not a finite number of at least 1")]
    InvalidGrowth(f64),
    /// Per-vertex arrays given to a mesh routine have the wrong length.
    #[error("expected {expected} per-vertex values, got {got}")]
    VertexArrayLength {
        /// Number of mesh vertices.
        expected: usize,
        /// Length of the array given.
        got: usize,
    },
}
