//! Building a cover from volume data (thesis §3.4.2; the linear bounding-box variant of
//! §6.2.3).
//!
//! The method is described on [`build_volume_cover()`].

mod covering;
mod distance_transform;
mod elimination;
mod fit;
mod grid;
mod radii;
mod radius_search;
mod scattered;
mod support;

pub use scattered::{build_scattered_cover, median_nearest_distance};

use crate::ParameterError;
use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;

use crate::cover::{Cover, CoverError};
use crate::kernel::Kernel;
use crate::volume::Volume;
use fit::{LINEAR, QUADRATIC};
use grid::Grid;
pub use radii::squared_depth_to_background;
use radii::{grid_diagonal, max_thickness, radius_cap};
use support::supports_to_cover;

/// The threshold that selects the object points `v > T`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Threshold {
    /// In the volume's own units (e.g. Hounsfield units after `scl_slope`/`scl_inter`).
    Raw(f64),
    /// As a fraction of the value range: `T = min + t·(max − min)`, `t ∈ [0, 1)`. `0`
    /// selects every voxel above the minimum (the thesis' "T = 0 covers everything").
    Normalised(f64),
}

impl Default for Threshold {
    fn default() -> Threshold {
        Threshold::Normalised(0.5)
    }
}

/// Which cover to build.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VolumeCoverVariant {
    /// Quadratic local functions centred at object points (thesis §3.4.2).
    #[default]
    ObjectQuadratic,
    /// Linear local functions centred anywhere in the grid's bounding box, covering checked
    /// with every grid point of the ball (thesis §6.2.3, the input of derivative smoothing).
    BoundingBoxLinear,
}

/// The order in which uncovered candidates become centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CentreOrder {
    /// Uniformly random among the uncovered (thesis §3.4.2), drawn from the seed.
    #[default]
    Random,
    /// Deepest first: by decreasing distance to the nearest background sample (the distance
    /// transform that gives `r_max`), ties in the seeded random order. Object variant only
    /// (the linear variant has no background); see [`build_volume_cover`] for the measurements.
    DeepestFirst,
    /// Greedy set cover: every candidate's support is fitted, then the support holding the
    /// most still-uncovered members (object points strictly inside it, and cell corners
    /// under [`Elimination::CellCorners`]) is taken next, supports within ε first, ties in
    /// the seeded order. Costs one fit per candidate.
    MostUncovered,
}

/// Parameters of [`build_volume_cover`]. `Default` gives the thesis defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeCoverParams {
    /// Object points are the voxels with a value above this.
    pub threshold: Threshold,
    /// Error tolerance ε as a fraction of the value range (the RMS residual on normalised
    /// values); thesis default 5 %.
    pub tolerance: f64,
    /// Smallest radius in world units; `None`: the voxel diagonal.
    pub r_min: Option<f64>,
    /// Largest radius in world units; `None`: the object's maximum thickness from a distance
    /// transform (see [`build_volume_cover`]).
    pub r_max: Option<f64>,
    /// Cap on the default `r_max`, in voxel diagonals (bounds the work per support on thick
    /// objects; an explicit `r_max` is not capped).
    pub max_radius_voxels: f64,
    /// Fewest samples a fit uses; the radius grows beyond `r_min` until it has them.
    pub min_samples: usize,
    /// Which cover to build.
    pub variant: VolumeCoverVariant,
    /// The weight kernel stored in the cover (thesis default: truncated Gaussian).
    pub kernel: Kernel,
    /// Seed of the order in which candidates become centres.
    pub seed: u64,
    /// Which uncovered candidate becomes the next centre.
    pub centre_order: CentreOrder,
    /// Which redundant supports are removed after covering (see [`Elimination`]). Object
    /// variant only: the linear variant keeps the thesis' cover (elimination raised its
    /// largest error at the skull's object voxels from 0.12 to 0.45).
    pub elimination: Elimination,
}

/// The elimination pass after covering (a departure from the thesis; [`build_volume_cover`], step 5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Elimination {
    /// Keep every support of the covering loop (the thesis' cover).
    Off,
    /// Remove a support when each object voxel strictly inside it lies strictly inside
    /// another remaining support.
    VoxelCentres,
    /// As `VoxelCentres`, and each corner of an object voxel's cell strictly inside it also
    /// lies in another remaining support (a corner in no ball of the thesis' cover does not
    /// count): no gap opens at the sampled corners. The scattered builder has no cells and
    /// treats this as `VoxelCentres`.
    #[default]
    CellCorners,
}

impl Default for VolumeCoverParams {
    fn default() -> VolumeCoverParams {
        VolumeCoverParams {
            threshold: Threshold::default(),
            tolerance: 0.05,
            r_min: None,
            r_max: None,
            max_radius_voxels: 16.0,
            min_samples: 15,
            variant: VolumeCoverVariant::default(),
            kernel: Kernel::TruncatedGaussian,
            seed: 0,
            centre_order: CentreOrder::default(),
            elimination: Elimination::default(),
        }
    }
}

/// What [`build_volume_cover`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VolumeCoverStats {
    /// Smallest and largest finite voxel value (the normalisation: the cover's functions
    /// approximate `(v − min)/(max − min)`).
    pub value_range: (f64, f64),
    /// The threshold in normalised units.
    pub threshold_normalised: f64,
    /// Voxels above the threshold.
    pub object_points: usize,
    /// Voxels that were candidates (object points, or every voxel for the linear variant).
    pub candidates: usize,
    /// Supports in the cover.
    pub supports: usize,
    /// Radius bounds used (world units).
    pub r_min: f64,
    /// See `r_min`.
    pub r_max: f64,
    /// Maximum thickness from the distance transform, when it was computed (world units).
    pub thickness: Option<f64>,
    /// Scattered samples only ([`build_scattered_cover`]): the spacing `h`, `√3 ×` the
    /// median nearest-neighbour distance (the voxel diagonal of a cubic grid); 0 for volumes.
    pub sample_spacing: f64,
    /// Smallest, mean and largest support radius.
    pub radius_min: f64,
    /// See `radius_min`.
    pub radius_mean: f64,
    /// See `radius_min`.
    pub radius_max: f64,
    /// Largest RMS residual of a support on normalised values (summed directly).
    pub max_rms: f64,
    /// Supports whose smallest admissible ball already exceeds ε.
    pub above_tolerance: usize,
    /// Fits computed, including speculative ones dropped because their centre got covered.
    pub fits: usize,
    /// Time spent in the distance transform.
    pub time_distance_transform: Duration,
    /// Time spent fitting and covering.
    pub time_cover: Duration,
}

/// Why a volume cover could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VolumeCoverError {
    /// The volume has a single voxel: nothing to fit.
    #[error("the volume has a single voxel")]
    SingleVoxel,
    /// No voxel value is finite.
    #[error("no voxel value is finite")]
    NoFiniteValue,
    /// Every finite voxel has the same value: the normalisation is undefined.
    #[error("the volume is constant (every voxel is {value})")]
    ConstantVolume {
        /// The value.
        value: f64,
    },
    /// The threshold selects no voxel.
    #[error("threshold {threshold} selects no voxel (values range over [{min}, {max}])")]
    NoObjectPoint {
        /// The threshold in the volume's units.
        threshold: f64,
        /// Smallest finite value.
        min: f64,
        /// Largest finite value.
        max: f64,
    },
    /// A parameter is out of its domain.
    #[error(transparent)]
    InvalidParameter(#[from] ParameterError),
    /// The volume has more voxels than `u32` indices reach.
    #[error("{voxels} voxels exceed the u32 index range")]
    TooManyVoxels {
        /// Number of voxels.
        voxels: usize,
    },
    /// Scattered samples: not as many values as positions.
    #[error("{positions} sample positions but {values} values")]
    SampleCountMismatch {
        /// Number of positions.
        positions: usize,
        /// Number of values.
        values: usize,
    },
    /// Scattered samples: fewer than two.
    #[error("{count} sample(s): a cover needs at least two")]
    TooFewSamples {
        /// Number of samples.
        count: usize,
    },
    /// Scattered samples: a position or a value is not finite.
    #[error("sample {index} has a non-finite {what}")]
    NonFiniteSample {
        /// Index of the first such sample.
        index: usize,
        /// `"position"` or `"value"`.
        what: &'static str,
    },
    /// Scattered samples: more than half of them coincide with another sample, so no
    /// sample spacing can be estimated.
    #[error("most samples coincide with another one: no sample spacing")]
    CoincidentSamples,
    /// The cover could not be assembled (a non-finite fit: not expected).
    #[error(transparent)]
    Cover(#[from] CoverError),
}

/// Builds a cover of the object in `volume` (or of the whole grid, for the linear variant)
/// by balls carrying local least-squares fits of the normalised intensities. See the module
/// documentation for the algorithm and its guarantees.
///
/// # Algorithm
///
/// Samples are the voxel centres in world coordinates with their values normalised to
/// `[0, 1]` over the volume's finite value range; non-finite voxels are no samples. *Object
/// points* are the voxels with value above the threshold.
///
/// 1. Candidates ← object points (all voxels for [`VolumeCoverVariant::BoundingBoxLinear`]),
///    all uncovered, in a random order drawn from the seed.
/// 2. The first uncovered candidate in that order becomes a centre `c` (this picks uniformly
///    among the uncovered, as the thesis asks). Its radius is the largest `r ∈ [r_min, r_max]`
///    with `E(r) ≤ ε`, where `E(r)` is the RMS residual of the least-squares local function
///    (quadratic: 10 coefficients; linear: 4) over all samples within `r`, solved in the
///    centred, scaled coordinates `(x − c)/r`. The sample set only changes where `r` crosses
///    a shell of voxel centres at equal distance, so the search runs over shells: it grows
///    the radius by factors of 1.5 until `E > ε` (or `r_max`), then bisects between the
///    last good and the first bad shell (the thesis' bisection, assuming like it that `E`
///    grows with `r`). The final radius lies halfway between the accepted shell and the next
///    one, so no sample sits on a support's sphere. When even `r_min` misses `ε` (steep
///    edges), the search bisects below `r_min`, down to the smallest ball holding
///    `min_samples` samples (default 15, MPU's `N_min`; an isotropic grid then keeps the
///    19-voxel neighbourhood of radius √2 voxels for the 10 quadratic coefficients). A
///    centre whose smallest ball still misses `ε` keeps that ball and is counted in
///    [`VolumeCoverStats::above_tolerance`].
/// 3. Covering check (thesis Fig. 3.12): with `S` the object points (all grid points for the
///    linear variant) inside the new ball, a point of `S` is marked covered when it is not a
///    vertex of the convex hull of `S`. Computing a 3D hull per support is replaced by an
///    exact-where-it-answers test: `p` is not a hull vertex when `p − e` and `p + e` both lie
///    in `S` for some lattice step `e` (then `p` is their midpoint). The steps tried are the
///    49 primitive integer directions with coordinates in `{−2, …, 2}`. Points the test
///    cannot decide stay uncovered, as true hull vertices do, so the test only ever leaves
///    *more* candidates, never a gap. The centre itself is always marked covered, which
///    guarantees progress (a centre on a corner of the object is a hull vertex).
/// 4. Repeat until no candidate is uncovered.
/// 5. Elimination (default, object variant only; [`VolumeCoverParams::elimination`],
///    a departure from the thesis, after its surface builder §3.4.1). A support's *members*
///    are the object points strictly inside its ball and, for [`Elimination::CellCorners`]
///    (the default), the corners of object voxels' cells strictly inside it that lie in
///    some ball of the loop's cover. Supports over ε
///    first, then by increasing member count (ties by position), a support is removed when
///    every member lies in at least one other remaining support. With elimination on, a
///    centre whose fit misses ε in step 2 is set aside (nothing is marked covered) and is
///    only taken after step 4 if it holds a member that no accepted ball holds by then.
///
/// # No object point is left outside the cover
///
/// Every object point ends covered, and is covered only in two ways: as a centre (distance 0
/// from its own centre), or as the midpoint of two points `p ± e` of the ball's closed
/// sample set. In the latter case, with `L` the voxel→world linear map,
/// `‖p − c‖² = (‖p + e − c‖² + ‖p − e − c‖²)/2 − ‖Le‖² ≤ s² − ‖Le‖² < r²` (parallelogram law,
/// `s ≤ r` the accepted shell): the point lies strictly inside the open ball, where every
/// kernel weight is positive. Radii are at least `r_min` (by default the voxel diagonal, so
/// that a ball holds the whole 3×3×3 neighbourhood of its centre) except at steep edges
/// where that ball misses `ε`; the argument above does not depend on the radius.
///
/// Elimination keeps this: each object point starts in at least one member set (a centre,
/// or a hull-interior point at `‖p − c‖ < s`), and a support goes only when all its members
/// have another one. Every kept support holds a member no other kept ball holds. With
/// [`Elimination::CellCorners`] no cell corner leaves the union of the balls either, so the
/// elimination opens no gap at those points between the voxel centres
/// ([`Elimination::VoxelCentres`] leaves 1–4 % of them in no ball on the phantoms).
///
/// # Compactness
///
/// With the thesis' `ε = 5 %`, a quadratic follows the intensity profile across a plate of
/// 4 voxels (blurred by a 0.8-voxel PSF) only within radius ≈ 2 voxels, and the hull rule
/// marks only a ball's hull interior, so the thesis' loop gives such plates about one
/// support per 8 object voxels, most balls overlapping their neighbours far more than
/// needed. Elimination removes that redundancy: 20.7 object voxels per support on the
/// tests' 4-voxel plate, 41.9 on the 6-voxel one (cell corners kept; 34.1 and 69.5 with
/// voxel centres only; measurements in `docs/algorithms.md` and `docs/benchmarks.md`).
///
/// # Centre order (a departure from the thesis, optional)
///
/// The thesis picks a random uncovered candidate. A random candidate near a plate's face
/// gets a small ball (a quadratic follows the face's ramp only so far); one on the plate's
/// mid-surface gets a larger one and its ball is symmetric about the profile.
/// [`CentreOrder::DeepestFirst`] takes candidates by decreasing distance to the background
/// (the distance transform of `r_max`), ties in the seeded order. Measured at ε = 0.05 with
/// the tests' tilted plate phantom (40 × 40 × 24 voxels, PSF 0.8 voxel), object voxels per
/// support, random → deepest first: 4-voxel plate 7.7 → 11.3, 6-voxel 14.9 → 21.7, 8-voxel
/// 14.5 → 15.6; the T-junction phantom 6.4 → 8.4; every RMS ≤ ε, no object voxel uncovered.
/// It stays opt-in (the default keeps the thesis' random order, which the skeleton
/// pipeline's figures were measured with). With the default elimination the orders give
/// 20.7 / 29.7 / 42.4 object voxels per support on the 4-voxel plate (random / deepest
/// first / [`CentreOrder::MostUncovered`]), and 41.9 / 62.3 / 105.3 on the 6-voxel one.
///
/// [`CentreOrder::MostUncovered`] is a greedy set cover: every candidate's support is fitted
/// (one fit per object point, against about one per eight in the thesis' loop), then the
/// support with the most uncovered members is taken next, supports within ε before those
/// over it. Only it reaches every support within ε where some points' smallest ball misses
/// ε but a neighbour's ball around them does not (sharp edges).
///
/// # Radii
///
/// `r_max` defaults to the object's maximum thickness, twice the largest distance from an
/// object voxel to a background voxel centre (exact Euclidean distance transform with the
/// voxel edge lengths as spacing; exact for orthogonal voxel axes), capped at
/// [`VolumeCoverParams::max_radius_voxels`] voxel diagonals to bound the work per support.
/// A volume with no background voxel uses half its diagonal before the cap.
///
/// # Determinism
///
/// A support's radius and function depend on its centre only, so the fits of the next few
/// uncovered candidates run in parallel ahead of time; the covering check then runs in
/// candidate order and drops the speculative fits whose centre got covered meanwhile. The
/// result is that of the sequential algorithm, bit for bit, whatever the thread count. The
/// greedy order fits every candidate in parallel, then selects sequentially; elimination
/// counts members in parallel (integer sums) and decides sequentially.
///
/// # Layout
///
/// One file per phase: `radii` (the radius range, by the distance transform of
/// `distance_transform`), `grid` (the lattice of offsets and shells), `radius_search` (one
/// support's fit, on the normal equations of `fit`), `covering` (the loop and the centre
/// orders), `elimination`, and `support` (the accepted supports as a [`Cover`]). `scattered`
/// runs the same algorithm on samples off any grid.
pub fn build_volume_cover(
    volume: &Volume,
    params: &VolumeCoverParams,
) -> Result<(Cover, VolumeCoverStats), VolumeCoverError> {
    let n = volume.len();
    if n == 1 {
        return Err(VolumeCoverError::SingleVoxel);
    }
    if u32::try_from(n).is_err() {
        return Err(VolumeCoverError::TooManyVoxels { voxels: n });
    }
    check_params(params)?;
    let (lo, hi) = volume
        .value_range()
        .ok_or(VolumeCoverError::NoFiniteValue)?;
    if lo == hi {
        return Err(VolumeCoverError::ConstantVolume { value: lo });
    }
    let threshold = match params.threshold {
        Threshold::Raw(t) => t,
        Threshold::Normalised(t) => lo + t * (hi - lo),
    };
    let is_object = |idx: usize| volume.value(idx) > threshold;
    let object: Vec<bool> = (0..n).into_par_iter().map(is_object).collect();
    let object_points = object.iter().filter(|&&o| o).count();
    if object_points == 0 {
        return Err(VolumeCoverError::NoObjectPoint {
            threshold,
            min: lo,
            max: hi,
        });
    }

    let diagonal = volume.voxel_diagonal();
    let r_min = params.r_min.unwrap_or(diagonal);
    let start = Instant::now();
    let deepest = params.centre_order == CentreOrder::DeepestFirst
        && params.variant == VolumeCoverVariant::ObjectQuadratic;
    let depth =
        (params.r_max.is_none() || deepest).then(|| squared_depth_to_background(volume, &object));
    let (r_max, thickness) = radius_cap(
        params,
        r_min,
        diagonal,
        || max_thickness(depth.as_deref().expect("computed without r_max"), &object),
        || grid_diagonal(volume),
    )?;
    let time_distance_transform = start.elapsed();

    let start = Instant::now();
    let grid = Grid::new(volume, lo, hi, r_min, r_max, &object, params);
    let mut stats = VolumeCoverStats {
        value_range: (lo, hi),
        threshold_normalised: (threshold - lo) / (hi - lo),
        object_points,
        r_min,
        r_max,
        thickness,
        time_distance_transform,
        ..VolumeCoverStats::default()
    };
    let depth = if deepest { depth.as_deref() } else { None };
    let supports = match params.variant {
        VolumeCoverVariant::ObjectQuadratic => grid.cover::<QUADRATIC>(params, depth, &mut stats),
        VolumeCoverVariant::BoundingBoxLinear => grid.cover::<LINEAR>(params, None, &mut stats),
    };
    let centres: Vec<DVec3> = supports
        .iter()
        .map(|s| volume.voxel_centre(volume.ijk(s.centre as usize)))
        .collect();
    let cover = supports_to_cover(&supports, centres, params, &mut stats)?;
    stats.time_cover = start.elapsed();
    Ok((cover, stats))
}

pub(super) fn check_params(p: &VolumeCoverParams) -> Result<(), VolumeCoverError> {
    let bad = |name, value, reason| {
        Err(VolumeCoverError::InvalidParameter(ParameterError {
            name,
            value,
            expected: reason,
        }))
    };
    if !(p.tolerance.is_finite() && p.tolerance > 0.0) {
        return bad("tolerance", p.tolerance, "must be finite and positive");
    }
    for (name, r) in [("r_min", p.r_min), ("r_max", p.r_max)] {
        if let Some(r) = r
            && !(r.is_finite() && r > 0.0)
        {
            return bad(name, r, "must be finite and positive");
        }
    }
    if !(p.max_radius_voxels.is_finite() && p.max_radius_voxels >= 1.0) {
        return bad(
            "max_radius_voxels",
            p.max_radius_voxels,
            "must be at least 1",
        );
    }
    match p.threshold {
        Threshold::Raw(t) if t.is_nan() => bad("threshold", t, "must not be NaN"),
        Threshold::Normalised(t) if !(0.0..1.0).contains(&t) => {
            bad("threshold", t, "a normalised threshold lies in [0, 1)")
        }
        _ => Ok(()),
    }
}
