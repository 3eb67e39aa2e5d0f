//! Building a cover from volume data (thesis §3.4.2; the linear bounding-box variant of
//! §6.2.3).
//!
//! # Algorithm
//!
//! Samples are the voxel centres in world coordinates with their values normalised to
//! `[0, 1]` over the volume's finite value range; non-finite voxels are no samples. *Object
//! points* are the voxels with value above the threshold.
//!
//! 1. Candidates ← object points (all voxels for [`VolumeCoverVariant::BoundingBoxLinear`]),
//!    all uncovered, in a random order drawn from the seed.
//! 2. The first uncovered candidate in that order becomes a centre `c` (this picks uniformly
//!    among the uncovered, as the thesis asks). Its radius is the largest `r ∈ [r_min, r_max]`
//!    with `E(r) ≤ ε`, where `E(r)` is the RMS residual of the least-squares local function
//!    (quadratic: 10 coefficients; linear: 4) over all samples within `r`, solved in the
//!    centred, scaled coordinates `(x − c)/r`. The sample set only changes where `r` crosses
//!    a shell of voxel centres at equal distance, so the search runs over shells: it grows
//!    the radius by factors of 1.5 until `E > ε` (or `r_max`), then bisects between the
//!    last good and the first bad shell (the thesis' bisection, assuming like it that `E`
//!    grows with `r`). The final radius lies halfway between the accepted shell and the next
//!    one, so no sample sits on a support's sphere. When even `r_min` misses `ε` (steep
//!    edges), the search bisects below `r_min`, down to the smallest ball holding
//!    `min_samples` samples (default 15, MPU's `N_min`; an isotropic grid then keeps the
//!    19-voxel neighbourhood of radius √2 voxels for the 10 quadratic coefficients). A
//!    centre whose smallest ball still misses `ε` keeps that ball and is counted in
//!    [`VolumeCoverStats::above_tolerance`].
//! 3. Covering check (thesis Fig. 3.12): with `S` the object points (all grid points for the
//!    linear variant) inside the new ball, a point of `S` is marked covered when it is not a
//!    vertex of the convex hull of `S`. Computing a 3D hull per support is replaced by an
//!    exact-where-it-answers test: `p` is not a hull vertex when `p − e` and `p + e` both lie
//!    in `S` for some lattice step `e` (then `p` is their midpoint). The steps tried are the
//!    49 primitive integer directions with coordinates in `{−2, …, 2}`. Points the test
//!    cannot decide stay uncovered, as true hull vertices do, so the test only ever leaves
//!    *more* candidates, never a gap. The centre itself is always marked covered, which
//!    guarantees progress (a centre on a corner of the object is a hull vertex).
//! 4. Repeat until no candidate is uncovered.
//! 5. Elimination (default, object variant only; [`VolumeCoverParams::elimination`],
//!    a departure from the thesis, after its surface builder §3.4.1). A support's *members*
//!    are the object points strictly inside its ball and, for [`Elimination::CellCorners`]
//!    (the default), the corners of object voxels' cells strictly inside it that lie in
//!    some ball of the loop's cover. Supports over ε
//!    first, then by increasing member count (ties by position), a support is removed when
//!    every member lies in at least one other remaining support. With elimination on, a
//!    centre whose fit misses ε in step 2 is set aside (nothing is marked covered) and is
//!    only taken after step 4 if it holds a member that no accepted ball holds by then.
//!
//! # No object point is left outside the cover
//!
//! Every object point ends covered, and is covered only in two ways: as a centre (distance 0
//! from its own centre), or as the midpoint of two points `p ± e` of the ball's closed
//! sample set. In the latter case, with `L` the voxel→world linear map,
//! `‖p − c‖² = (‖p + e − c‖² + ‖p − e − c‖²)/2 − ‖Le‖² ≤ s² − ‖Le‖² < r²` (parallelogram law,
//! `s ≤ r` the accepted shell): the point lies strictly inside the open ball, where every
//! kernel weight is positive. Radii are at least `r_min` (by default the voxel diagonal, so
//! that a ball holds the whole 3×3×3 neighbourhood of its centre) except at steep edges
//! where that ball misses `ε`; the argument above does not depend on the radius.
//!
//! Elimination keeps this: each object point starts in at least one member set (a centre,
//! or a hull-interior point at `‖p − c‖ < s`), and a support goes only when all its members
//! have another one. Every kept support holds a member no other kept ball holds. With
//! [`Elimination::CellCorners`] no cell corner leaves the union of the balls either, so the
//! elimination opens no gap at those points between the voxel centres
//! ([`Elimination::VoxelCentres`] leaves 1–4 % of them in no ball on the phantoms).
//!
//! # Compactness
//!
//! With the thesis' `ε = 5 %`, a quadratic follows the intensity profile across a plate of
//! 4 voxels (blurred by a 0.8-voxel PSF) only within radius ≈ 2 voxels, and the hull rule
//! marks only a ball's hull interior, so the thesis' loop gives such plates about one
//! support per 8 object voxels, most balls overlapping their neighbours far more than
//! needed. Elimination removes that redundancy: 20.7 object voxels per support on the
//! tests' 4-voxel plate, 41.9 on the 6-voxel one (cell corners kept; 34.1 and 69.5 with
//! voxel centres only; measurements in `docs/algorithms.md` and `docs/benchmarks.md`).
//!
//! # Centre order (a departure from the thesis, optional)
//!
//! The thesis picks a random uncovered candidate. A random candidate near a plate's face
//! gets a small ball (a quadratic follows the face's ramp only so far); one on the plate's
//! mid-surface gets a larger one and its ball is symmetric about the profile.
//! [`CentreOrder::DeepestFirst`] takes candidates by decreasing distance to the background
//! (the distance transform of `r_max`), ties in the seeded order. Measured at ε = 0.05 with
//! the tests' tilted plate phantom (40 × 40 × 24 voxels, PSF 0.8 voxel), object voxels per
//! support, random → deepest first: 4-voxel plate 7.7 → 11.3, 6-voxel 14.9 → 21.7, 8-voxel
//! 14.5 → 15.6; the T-junction phantom 6.4 → 8.4; every RMS ≤ ε, no object voxel uncovered.
//! It stays opt-in (the default keeps the thesis' random order, which the skeleton
//! pipeline's figures were measured with). With the default elimination the orders give
//! 20.7 / 29.7 / 42.4 object voxels per support on the 4-voxel plate (random / deepest
//! first / [`CentreOrder::MostUncovered`]), and 41.9 / 62.3 / 105.3 on the 6-voxel one.
//!
//! [`CentreOrder::MostUncovered`] is a greedy set cover: every candidate's support is fitted
//! (one fit per object point, against about one per eight in the thesis' loop), then the
//! support with the most uncovered members is taken next, supports within ε before those
//! over it. Only it reaches every support within ε where some points' smallest ball misses
//! ε but a neighbour's ball around them does not (sharp edges).
//!
//! # Radii
//!
//! `r_max` defaults to the object's maximum thickness, twice the largest distance from an
//! object voxel to a background voxel centre (exact Euclidean distance transform with the
//! voxel edge lengths as spacing; exact for orthogonal voxel axes), capped at
//! [`VolumeCoverParams::max_radius_voxels`] voxel diagonals to bound the work per support.
//! A volume with no background voxel uses half its diagonal before the cap.
//!
//! # Determinism
//!
//! A support's radius and function depend on its centre only, so the fits of the next few
//! uncovered candidates run in parallel ahead of time; the covering check then runs in
//! candidate order and drops the speculative fits whose centre got covered meanwhile. The
//! result is that of the sequential algorithm, bit for bit, whatever the thread count. The
//! greedy order fits every candidate in parallel, then selects sequentially; elimination
//! counts members in parallel (integer sums) and decides sequentially.

mod distance_transform;
mod fit;
mod scattered;

pub use scattered::{build_scattered_cover, median_nearest_distance};

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use glam::{DMat3, DVec3};
use rand::RngCore;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use crate::cover::{Cover, CoverError};
use crate::kernel::Kernel;
use crate::local_function::{LinearFunction, LocalFunctions, QuadraticFunction};
use crate::volume::Volume;
use fit::{LINEAR, NormalEquations, QUADRATIC};

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
    /// (the linear variant has no background); see the module docs for the measurements.
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
    /// transform (see the module documentation).
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

/// The elimination pass after covering (a departure from the thesis; module docs, step 5).
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
    #[error("parameter {name} = {value} is invalid: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        reason: &'static str,
    },
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
    let depth = (params.r_max.is_none() || deepest).then(|| depth_to_background(volume, &object));
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
    let centers: Vec<DVec3> = supports
        .iter()
        .map(|s| volume.voxel_center(volume.ijk(s.center as usize)))
        .collect();
    let cover = supports_to_cover(&supports, centers, params, &mut stats)?;
    stats.time_cover = start.elapsed();
    Ok((cover, stats))
}

/// Assembles the cover of the accepted supports (centres given) and fills the statistics.
fn supports_to_cover(
    supports: &[Support],
    centers: Vec<DVec3>,
    params: &VolumeCoverParams,
    stats: &mut VolumeCoverStats,
) -> Result<Cover, VolumeCoverError> {
    stats.supports = supports.len();
    let radii: Vec<f64> = supports.iter().map(|s| s.radius).collect();
    stats.radius_min = radii.iter().copied().fold(f64::INFINITY, f64::min);
    stats.radius_max = radii.iter().copied().fold(0.0, f64::max);
    stats.radius_mean = radii.iter().sum::<f64>() / radii.len().max(1) as f64;
    stats.max_rms = supports.iter().map(|s| s.rms).fold(0.0, f64::max);
    stats.above_tolerance = supports.iter().filter(|s| s.rms > params.tolerance).count();
    let funcs = match params.variant {
        VolumeCoverVariant::ObjectQuadratic => {
            LocalFunctions::from_quadratic(supports.iter().map(|s| s.quadratic()))
        }
        VolumeCoverVariant::BoundingBoxLinear => {
            LocalFunctions::from_linear(supports.iter().map(|s| s.linear()))
        }
    };
    Ok(Cover::new(centers, radii, funcs, params.kernel)?)
}

fn check_params(p: &VolumeCoverParams) -> Result<(), VolumeCoverError> {
    let bad = |name, value, reason| {
        Err(VolumeCoverError::InvalidParameter {
            name,
            value,
            reason,
        })
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

/// Squared distance from every voxel centre to the nearest background voxel centre.
fn depth_to_background(volume: &Volume, object: &[bool]) -> Vec<f64> {
    let size = volume.voxel_size();
    distance_transform::squared_distance_to_background(
        volume.dims(),
        [size.x, size.y, size.z],
        |i| !object[i],
    )
}

/// Twice the largest distance from an object voxel to a background voxel centre (`d2` from
/// [`depth_to_background`]); `+∞` with no background voxel.
fn max_thickness(d2: &[f64], object: &[bool]) -> f64 {
    let max = d2
        .par_iter()
        .zip(object)
        .filter(|&(_, &o)| o)
        .map(|(&d, _)| d)
        .reduce(|| 0.0, f64::max);
    2.0 * max.sqrt()
}

/// `r_max` and the object thickness it came from: the given `r_max`, or else the largest
/// thickness (half the sample extent `diagonal` when no background sample bounds the object),
/// capped at `max_radius_voxels` sample spacings and raised to `r_min`. Both builders use it.
fn radius_cap(
    params: &VolumeCoverParams,
    r_min: f64,
    spacing: f64,
    thickness: impl FnOnce() -> f64,
    diagonal: impl FnOnce() -> f64,
) -> Result<(f64, Option<f64>), VolumeCoverError> {
    let (r_max, thickness) = match params.r_max {
        Some(r) => (r, None),
        None => {
            let t = thickness();
            let r = if t.is_finite() { t } else { 0.5 * diagonal() };
            let cap = params.max_radius_voxels * spacing;
            (r.min(cap).max(r_min), t.is_finite().then_some(t))
        }
    };
    if r_max < r_min {
        return Err(VolumeCoverError::InvalidParameter {
            name: "r_max",
            value: r_max,
            reason: "must be at least r_min",
        });
    }
    Ok((r_max, thickness))
}

fn grid_diagonal(volume: &Volume) -> f64 {
    let [nx, ny, nz] = volume.dims();
    let far = DVec3::new(nx as f64 - 1.0, ny as f64 - 1.0, nz as f64 - 1.0);
    (volume.affine().matrix3 * far).length()
}

/// A lattice offset from a centre voxel with its position in the frame `d/h`.
#[derive(Clone, Copy, Debug)]
struct Offset {
    step: [i32; 3],
    p: [f64; 3],
}

/// One accepted support (or a speculative fit).
#[derive(Clone, Copy, Debug)]
struct Support {
    center: u32,
    radius: f64,
    /// Squared distance (frame `d/h`) of the outermost shell inside the ball.
    shell_d2: f64,
    /// Number of offsets (in table order) inside the ball.
    offsets: usize,
    /// Coefficients in the frame `u = (x − c)/r`, constant term relative to `shift`.
    coef: [f64; QUADRATIC],
    shift: f64,
    rms: f64,
}

impl Support {
    fn quadratic(&self) -> QuadraticFunction {
        let c = &self.coef;
        let (s1, s2) = (1.0 / self.radius, 1.0 / (self.radius * self.radius));
        let (xy, yz, xz) = (0.5 * c[7] * s2, 0.5 * c[8] * s2, 0.5 * c[9] * s2);
        QuadraticFunction {
            a: DMat3::from_cols(
                DVec3::new(c[4] * s2, xy, xz),
                DVec3::new(xy, c[5] * s2, yz),
                DVec3::new(xz, yz, c[6] * s2),
            ),
            b: DVec3::new(c[1], c[2], c[3]) * s1,
            k: c[0] + self.shift,
        }
    }

    fn linear(&self) -> LinearFunction {
        let c = &self.coef;
        LinearFunction {
            alpha: DVec3::new(c[1], c[2], c[3]) / self.radius,
            beta: c[0] + self.shift,
        }
    }
}

/// The sampling grid and everything shared by the fits.
struct Grid<'a> {
    volume: &'a Volume,
    dims: [i64; 3],
    lo: f64,
    inv_range: f64,
    object: &'a [bool],
    /// `h`: the unit of the fixed frame (the voxel diagonal).
    unit: f64,
    /// The voxel→world linear map divided by `h`.
    linear: DMat3,
    /// Lattice offsets within `r_max`, by increasing distance.
    offsets: Vec<Offset>,
    /// Shells: `(squared distance in frame d/h, end index in offsets)`, increasing.
    shells: Vec<(f64, usize)>,
    r_min: f64,
    r_max: f64,
    /// Index of the last shell within `r_min`.
    first_shell: usize,
    tolerance: f64,
    min_samples: usize,
    /// Lattice steps for the hull test, shortest first.
    steps: Vec<([i32; 3], DVec3)>,
    bounding_box: bool,
}

impl<'a> Grid<'a> {
    fn new(
        volume: &'a Volume,
        lo: f64,
        hi: f64,
        r_min: f64,
        r_max: f64,
        object: &'a [bool],
        params: &VolumeCoverParams,
    ) -> Grid<'a> {
        let dims = volume.dims().map(|d| d as i64);
        let unit = volume.voxel_diagonal();
        let linear = volume.affine().matrix3 * (1.0 / unit);
        // The box of lattice offsets that can reach r_max: |step_a| ≤ R·‖row a of L⁻¹‖.
        let inv = linear.inverse();
        let reach = r_max / unit;
        let rows = inv.transpose();
        let ext =
            [rows.x_axis, rows.y_axis, rows.z_axis].map(|row| (reach * row.length()).ceil() as i32);
        // A ball's support is open (its weight vanishes on the sphere), so offsets on the
        // sphere of radius r_max, up to rounding, are outside every ball: neither fitted nor
        // covered. r_max is often a voxel distance (the thickness), so they occur.
        let mut offsets = Vec::new();
        let r2 = reach * reach * (1.0 - 1e-9);
        for k in -ext[2]..=ext[2] {
            for j in -ext[1]..=ext[1] {
                for i in -ext[0]..=ext[0] {
                    let p = linear * DVec3::new(i as f64, j as f64, k as f64);
                    if p.length_squared() < r2 {
                        offsets.push(Offset {
                            step: [i, j, k],
                            p: p.to_array(),
                        });
                    }
                }
            }
        }
        let d2 = |o: &Offset| o.p[0] * o.p[0] + o.p[1] * o.p[1] + o.p[2] * o.p[2];
        offsets.sort_by(|a, b| {
            d2(a)
                .total_cmp(&d2(b))
                .then_with(|| a.step[2].cmp(&b.step[2]))
                .then_with(|| a.step[1].cmp(&b.step[1]))
                .then_with(|| a.step[0].cmp(&b.step[0]))
        });
        // Offsets at the same true distance can differ in the last bits of their computed
        // distance (summation order): a shell gathers every offset within a relative 1e-9
        // of its first one, and keeps the largest computed distance.
        let mut shells: Vec<(f64, usize)> = Vec::new();
        let mut shell_start = f64::NEG_INFINITY;
        for (idx, o) in offsets.iter().enumerate() {
            let d = d2(o);
            match shells.last_mut() {
                Some(last) if d <= shell_start * (1.0 + 1e-9) => *last = (d, idx + 1),
                _ => {
                    shell_start = d;
                    shells.push((d, idx + 1));
                }
            }
        }
        let rmin2 = (r_min / unit) * (r_min / unit);
        let first_shell = shells.iter().rposition(|&(d, _)| d <= rmin2).unwrap_or(0);
        let mut steps: Vec<([i32; 3], DVec3)> = Vec::new();
        for k in -2i32..=2 {
            for j in -2i32..=2 {
                for i in -2i32..=2 {
                    let s = [i, j, k];
                    let first_nonzero = s.iter().copied().find(|&c| c != 0);
                    let primitive = gcd(gcd(i.abs(), j.abs()), k.abs()) == 1;
                    if first_nonzero.is_some_and(|c| c > 0) && primitive {
                        steps.push((s, linear * DVec3::new(i as f64, j as f64, k as f64)));
                    }
                }
            }
        }
        steps.sort_by(|a, b| {
            a.1.length_squared()
                .total_cmp(&b.1.length_squared())
                .then_with(|| a.0.cmp(&b.0))
        });
        Grid {
            volume,
            dims,
            lo,
            inv_range: 1.0 / (hi - lo),
            object,
            unit,
            linear,
            offsets,
            shells,
            r_min,
            r_max,
            first_shell,
            tolerance: params.tolerance,
            min_samples: params.min_samples,
            steps,
            bounding_box: params.variant == VolumeCoverVariant::BoundingBoxLinear,
        }
    }

    /// The voxel at `base + step`, if inside the grid.
    #[inline]
    fn neighbour(&self, base: [i64; 3], step: [i32; 3]) -> Option<usize> {
        let i = base[0] + i64::from(step[0]);
        let j = base[1] + i64::from(step[1]);
        let k = base[2] + i64::from(step[2]);
        let [nx, ny, nz] = self.dims;
        if i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz {
            return None;
        }
        Some((i + nx * (j + ny * k)) as usize)
    }

    /// The normalised value of a voxel, `None` when not finite.
    #[inline]
    fn sample(&self, idx: usize) -> Option<f64> {
        let v = (self.volume.value(idx) - self.lo) * self.inv_range;
        v.is_finite().then_some(v)
    }

    fn base(&self, idx: usize) -> [i64; 3] {
        self.volume.ijk(idx).map(|c| c as i64)
    }

    /// The ball radius for shell `s`: halfway to the next shell, within `[r_min, r_max]`.
    fn radius_of_shell(&self, s: usize) -> f64 {
        let here = self.shells[s].0.sqrt() * self.unit;
        let r = match self.shells.get(s + 1) {
            Some(&(next, _)) => 0.5 * (here + next.sqrt() * self.unit),
            None => self.r_max,
        };
        let r = if s >= self.first_shell {
            r.max(self.r_min)
        } else {
            r
        };
        r.min(self.r_max).max(here)
    }

    /// Fits the support centred at voxel `center` (a pure function of `center`).
    fn fit<const N: usize>(&self, center: usize) -> Support {
        let base = self.base(center);
        let shift = self.sample(center).unwrap_or(0.0);
        let mut acc = NormalEquations::<N>::new();
        let mut next_offset = 0;
        // Accumulates shells up to `s` into `acc` (which holds shells below `next_offset`).
        let extend = |acc: &mut NormalEquations<N>, next_offset: &mut usize, s: usize| {
            let end = self.shells[s].1;
            for o in &self.offsets[*next_offset..end] {
                if let Some(idx) = self.neighbour(base, o.step)
                    && let Some(v) = self.sample(idx)
                {
                    acc.add(o.p, v - shift);
                }
            }
            *next_offset = end;
        };
        let last = self.shells.len() - 1;
        // The smallest ball with min_samples samples, and the start: r_min or that ball.
        let mut floor = 0;
        extend(&mut acc, &mut next_offset, floor);
        while acc.count() < self.min_samples && floor < last {
            floor += 1;
            extend(&mut acc, &mut next_offset, floor);
        }
        let floor_acc = acc;
        let s = floor.max(self.first_shell);
        extend(&mut acc, &mut next_offset, s);
        let solve = |acc: &NormalEquations<N>, s: usize| {
            let r = self.radius_of_shell(s);
            acc.solve(self.unit / r)
                .map(|(c, e)| (c, e, r))
                .unwrap_or(([0.0; N], 0.0, r))
        };
        // The largest good shell between a good `good.0` and a bad `hi` (E assumed to grow
        // with r).
        let bisect = |mut good: (usize, ([f64; N], f64, f64), NormalEquations<N>),
                      mut hi: usize| {
            while hi - good.0 > 1 {
                let mid = good.0 + (hi - good.0) / 2;
                let mut trial = good.2;
                let mut trial_next = self.shells[good.0].1;
                extend(&mut trial, &mut trial_next, mid);
                let res = solve(&trial, mid);
                if res.1 <= self.tolerance {
                    good = (mid, res, trial);
                } else {
                    hi = mid;
                }
            }
            good
        };
        let mut good = (s, solve(&acc, s), acc);
        if good.1.1 > self.tolerance && s > floor {
            // Even r_min misses ε: bisect below it, down to the smallest ball with
            // min_samples samples (kept, over ε, when that misses too).
            good = (floor, solve(&floor_acc, floor), floor_acc);
            if good.1.1 <= self.tolerance {
                good = bisect(good, s);
            }
        } else if good.1.1 <= self.tolerance {
            // Gallop outward by radius factors of 1.5 until the error exceeds ε.
            let mut bad = None;
            while good.0 < last {
                let target = self.radius_of_shell(good.0) * 1.5 / self.unit;
                let t2 = target * target;
                let mut probe = good.0 + 1;
                while probe < last && self.shells[probe + 1].0 <= t2 {
                    probe += 1;
                }
                extend(&mut acc, &mut next_offset, probe);
                let res = solve(&acc, probe);
                if res.1 <= self.tolerance {
                    good = (probe, res, acc);
                } else {
                    bad = Some(probe);
                    break;
                }
            }
            // Bisect between the last good and the first bad shell.
            if let Some(hi) = bad {
                good = bisect(good, hi);
            }
        }
        let (shell, (c, _, radius), _) = good;
        let mut coef = [0.0; QUADRATIC];
        coef[..N].copy_from_slice(&c);
        let end = self.shells[shell].1;
        let rms = self.direct_rms::<N>(base, end, &c, radius, shift);
        Support {
            center: center as u32,
            radius,
            shell_d2: self.shells[shell].0,
            offsets: end,
            coef,
            shift,
            rms,
        }
    }

    /// RMS residual summed sample by sample (what the statistics report).
    fn direct_rms<const N: usize>(
        &self,
        base: [i64; 3],
        end: usize,
        c: &[f64; N],
        radius: f64,
        shift: f64,
    ) -> f64 {
        let scale = self.unit / radius;
        let (mut sum, mut count) = (0.0, 0usize);
        for o in &self.offsets[..end] {
            if let Some(idx) = self.neighbour(base, o.step)
                && let Some(v) = self.sample(idx)
            {
                let u = [o.p[0] * scale, o.p[1] * scale, o.p[2] * scale];
                let r = fit::evaluate(c, u) - (v - shift);
                sum += r * r;
                count += 1;
            }
        }
        (sum / count.max(1) as f64).sqrt()
    }

    /// Marks the points of the new support's `S` that are midpoints of two other points of
    /// `S`, and the centre, as covered.
    fn mark_covered(&self, s: &Support, covered: &mut [bool]) {
        let base = self.base(s.center as usize);
        covered[s.center as usize] = true;
        let in_set = |o: [i32; 3]| -> bool {
            let Some(idx) = self.neighbour(base, o) else {
                return false;
            };
            if !(self.bounding_box || self.object[idx]) {
                return false;
            }
            let p = self.linear * DVec3::new(o[0] as f64, o[1] as f64, o[2] as f64);
            p.length_squared() <= s.shell_d2
        };
        for o in &self.offsets[..s.offsets] {
            let Some(idx) = self.neighbour(base, o.step) else {
                continue;
            };
            if covered[idx] || !(self.bounding_box || self.object[idx]) {
                continue;
            }
            let interior = self.steps.iter().any(|(e, _)| {
                let plus = [o.step[0] + e[0], o.step[1] + e[1], o.step[2] + e[2]];
                let minus = [o.step[0] - e[0], o.step[1] - e[1], o.step[2] - e[2]];
                in_set(plus) && in_set(minus)
            });
            if interior {
                covered[idx] = true;
            }
        }
    }

    /// The covering loop; returns the accepted supports in order.
    /// `depth`: when given, candidates go deepest first (ties in the seeded order).
    fn cover<const N: usize>(
        &self,
        params: &VolumeCoverParams,
        depth: Option<&[f64]>,
        stats: &mut VolumeCoverStats,
    ) -> Vec<Support> {
        let n = self.volume.len();
        let mut order: Vec<u32> = if self.bounding_box {
            (0..n as u32).collect()
        } else {
            (0..n as u32).filter(|&i| self.object[i as usize]).collect()
        };
        stats.candidates = order.len();
        shuffle(&mut order, params.seed);
        if let Some(d) = depth {
            order.sort_by(|&a, &b| d[b as usize].total_cmp(&d[a as usize]));
        }
        // The linear variant (smoothing input, §6.2.3) keeps the thesis' cover.
        let eliminate = params.elimination != Elimination::Off && !self.bounding_box;
        let corners = (eliminate && params.elimination == Elimination::CellCorners)
            .then(|| CornerSet::new(self));
        let corners = corners.as_ref();
        let supports = if params.centre_order == CentreOrder::MostUncovered {
            self.cover_greedy::<N>(&order, corners, stats)
        } else {
            self.cover_in_order::<N>(&order, eliminate, corners, stats)
        };
        if eliminate {
            self.eliminate_redundant(supports, corners)
        } else {
            supports
        }
    }

    /// Calls `f` with every object point (every grid point, for the linear variant) strictly
    /// inside the support's ball.
    #[inline]
    fn for_each_member(&self, s: &Support, f: &mut dyn FnMut(usize)) {
        let base = self.base(s.center as usize);
        for o in &self.offsets[..s.offsets] {
            if let Some(idx) = self.neighbour(base, o.step)
                && (self.bounding_box || self.object[idx])
            {
                f(idx);
            }
        }
    }

    /// Calls `f` with the support's member voxels (`0..n`) and, with `corners`, its member
    /// cell corners (`n..`).
    fn for_each_point(&self, s: &Support, corners: Option<&CornerSet>, f: &mut dyn FnMut(usize)) {
        self.for_each_member(s, &mut *f);
        if let Some(cs) = corners {
            let n = self.volume.len();
            cs.for_each_member(self, s, |c| f(n + c));
        }
    }

    /// Removes redundant supports (see [`eliminate_redundant_supports`]); members are the
    /// object voxels and, with `corners`, the cell corners.
    fn eliminate_redundant(
        &self,
        supports: Vec<Support>,
        corners: Option<&CornerSet>,
    ) -> Vec<Support> {
        let total = self.volume.len() + corners.map_or(0, |cs| cs.object.len());
        eliminate_redundant_supports(supports, self.tolerance, total, |s, f| {
            self.for_each_point(s, corners, f)
        })
    }

    /// Greedy set cover over the supports of every candidate (in `order`, the seeded
    /// order): the support with the most uncovered members next, supports within ε before
    /// those over it (lazy re-evaluation; ties to the earlier candidate).
    fn cover_greedy<const N: usize>(
        &self,
        order: &[u32],
        corners: Option<&CornerSet>,
        stats: &mut VolumeCoverStats,
    ) -> Vec<Support> {
        let fits: Vec<Support> = order
            .par_iter()
            .map(|&c| self.fit::<N>(c as usize))
            .collect();
        stats.fits += fits.len();
        let gains: Vec<u32> = fits
            .par_iter()
            .map(|s| {
                let mut g = 0u32;
                self.for_each_point(s, corners, &mut |_| g += 1);
                g
            })
            .collect();
        let tolerance = self.tolerance;
        let within = |s: &Support| s.rms <= tolerance;
        let mut heap: BinaryHeap<(bool, u32, Reverse<u32>)> = gains
            .iter()
            .zip(&fits)
            .enumerate()
            .map(|(rank, (&g, s))| (within(s), g, Reverse(rank as u32)))
            .collect();
        let total = self.volume.len() + corners.map_or(0, |cs| cs.object.len());
        let mut covered = vec![false; total];
        let mut supports = Vec::new();
        while let Some((ok, stale, Reverse(rank))) = heap.pop() {
            let s = &fits[rank as usize];
            let mut gain = 0u32;
            self.for_each_point(s, corners, &mut |idx| gain += u32::from(!covered[idx]));
            if gain == 0 {
                continue;
            }
            if gain < stale && heap.peek().is_some_and(|&(o, g, _)| (o, g) > (ok, gain)) {
                heap.push((ok, gain, Reverse(rank)));
                continue;
            }
            self.for_each_point(s, corners, &mut |idx| covered[idx] = true);
            supports.push(*s);
        }
        supports
    }

    /// The covering loop of the thesis over candidates in `order`; returns the accepted
    /// supports in order. With `defer`, a centre whose fit misses ε is set aside and taken
    /// at the end only if it holds a member that no accepted ball holds by then (with
    /// `corners`, cell corners count as members).
    fn cover_in_order<const N: usize>(
        &self,
        order: &[u32],
        defer: bool,
        corners: Option<&CornerSet>,
        stats: &mut VolumeCoverStats,
    ) -> Vec<Support> {
        let n = self.volume.len();
        let mut supports = Vec::new();
        let mut deferred = Vec::new();
        covering_loop(
            order,
            n,
            |c| self.fit::<N>(c),
            stats,
            |s, covered| {
                if defer && s.rms > self.tolerance {
                    deferred.push(s);
                } else {
                    self.mark_covered(&s, covered);
                    supports.push(s);
                }
            },
        );
        if !deferred.is_empty() {
            let total = n + corners.map_or(0, |cs| cs.object.len());
            let mut in_ball = vec![false; total];
            for s in &supports {
                self.for_each_point(s, corners, &mut |idx| in_ball[idx] = true);
            }
            for s in deferred {
                // Taken when it holds a member (its centre, or with `corners` a cell corner)
                // that no accepted ball holds.
                let mut needed = false;
                self.for_each_point(&s, corners, &mut |idx| needed |= !in_ball[idx]);
                if needed {
                    self.for_each_point(&s, corners, &mut |idx| in_ball[idx] = true);
                    supports.push(s);
                }
            }
        }
        supports
    }
}

/// The corners of the voxel cells (the lattice shifted by half a voxel) that touch an object
/// voxel, for [`Elimination::CellCorners`]. Corner `(a, b, c)`, `a ∈ 0..=nx`, sits at voxel
/// coordinates `(a − ½, b − ½, c − ½)`.
struct CornerSet {
    dims: [i64; 3],
    object: Vec<bool>,
    /// Offsets from a voxel centre to corners within `r_max`: `(step, distance² in frame
    /// d/h)`, by increasing distance; the corner of step `s` from voxel `v` is `v + s + 1`.
    offsets: Vec<([i32; 3], f64)>,
}

impl CornerSet {
    fn new(grid: &Grid) -> CornerSet {
        let [nx, ny, nz] = grid.dims;
        let dims = [nx + 1, ny + 1, nz + 1];
        let count = (dims[0] * dims[1] * dims[2]) as usize;
        let object: Vec<bool> = (0..count)
            .into_par_iter()
            .map(|c| {
                let c = c as i64;
                let (a, b, k) = (
                    c % dims[0],
                    (c / dims[0]) % dims[1],
                    c / (dims[0] * dims[1]),
                );
                (0..8).any(|m| {
                    let (i, j, l) = (a - 1 + (m & 1), b - 1 + ((m >> 1) & 1), k - 1 + (m >> 2));
                    (0..nx).contains(&i)
                        && (0..ny).contains(&j)
                        && (0..nz).contains(&l)
                        && grid.object[(i + nx * (j + ny * l)) as usize]
                })
            })
            .collect();
        let reach = grid.r_max / grid.unit;
        let inv = grid.linear.inverse().transpose();
        let ext = [inv.x_axis, inv.y_axis, inv.z_axis]
            .map(|row| (reach * row.length()).ceil() as i32 + 1);
        let mut offsets = Vec::new();
        for k in -ext[2]..ext[2] {
            for j in -ext[1]..ext[1] {
                for i in -ext[0]..ext[0] {
                    let p =
                        grid.linear * DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5);
                    let d2 = p.length_squared();
                    if d2 <= reach * reach {
                        offsets.push(([i, j, k], d2));
                    }
                }
            }
        }
        offsets.sort_by(|a, b| a.1.total_cmp(&b.1).then_with(|| a.0.cmp(&b.0)));
        CornerSet {
            dims,
            object,
            offsets,
        }
    }

    /// Calls `f` with the object corners strictly inside the support's ball.
    fn for_each_member(&self, grid: &Grid, s: &Support, mut f: impl FnMut(usize)) {
        let base = grid.base(s.center as usize);
        let limit = s.radius / grid.unit * (1.0 - 1e-9);
        let limit2 = limit * limit;
        for &(step, d2) in &self.offsets {
            if d2 >= limit2 {
                break;
            }
            let a = base[0] + i64::from(step[0]) + 1;
            let b = base[1] + i64::from(step[1]) + 1;
            let c = base[2] + i64::from(step[2]) + 1;
            let [dx, dy, dz] = self.dims;
            if a < 0 || b < 0 || c < 0 || a >= dx || b >= dy || c >= dz {
                continue;
            }
            let idx = (a + dx * (b + dy * c)) as usize;
            if self.object[idx] {
                f(idx);
            }
        }
    }
}

fn gcd(a: i32, b: i32) -> i32 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// Fisher–Yates with Lemire's unbiased bounded integers on PCG-64: portable across `rand`
/// versions, unlike `SliceRandom::shuffle`.
fn shuffle(items: &mut [u32], seed: u64) {
    let mut rng = Pcg64::new(
        0xcafe_f00d_d15e_a5e5 ^ u128::from(seed),
        0x0a02_bdbf_7bb3_c0a7_ac28_fa16_a64a_bf96,
    );
    for i in (1..items.len()).rev() {
        let bound = i as u64 + 1;
        let j = loop {
            let m = u128::from(rng.next_u64()) * u128::from(bound);
            let low = m as u64;
            if low >= bound.wrapping_neg() % bound {
                break (m >> 64) as usize;
            }
        };
        items.swap(i, j);
    }
}

/// The thesis' covering loop (§3.4.2): the candidates of `order` (indices below `n`) not yet
/// covered are fitted in parallel batches, then handed in order to `take`, which marks what
/// the support covers; a candidate covered by an earlier support of its batch is skipped.
/// The result depends on the order only, not on the thread count.
fn covering_loop(
    order: &[u32],
    n: usize,
    fit: impl Fn(usize) -> Support + Sync,
    stats: &mut VolumeCoverStats,
    mut take: impl FnMut(Support, &mut [bool]),
) {
    let mut covered = vec![false; n];
    let batch_size = (rayon::current_num_threads() * 4).clamp(1, 256);
    let mut pos = 0;
    let mut batch = Vec::with_capacity(batch_size);
    while pos < order.len() {
        batch.clear();
        while pos < order.len() && batch.len() < batch_size {
            let c = order[pos] as usize;
            pos += 1;
            if !covered[c] {
                batch.push(c);
            }
        }
        let fits: Vec<Support> = batch.par_iter().map(|&c| fit(c)).collect();
        stats.fits += fits.len();
        for s in fits {
            if !covered[s.center as usize] {
                take(s, &mut covered);
            }
        }
    }
}

/// Removes redundant supports: those over `tolerance` first, then in order of increasing
/// member count (ties by position), a support goes when each of its members (indices below
/// `members`, listed by `for_each_member`) lies in at least one other remaining support.
/// Every member keeps at least one support, so the cover stays gap-free. The removal is
/// sequential and order-defined: the same whatever the thread count.
fn eliminate_redundant_supports(
    supports: Vec<Support>,
    tolerance: f64,
    members: usize,
    for_each_member: impl Fn(&Support, &mut dyn FnMut(usize)) + Sync,
) -> Vec<Support> {
    let counts: Vec<AtomicU32> = (0..members).map(|_| AtomicU32::new(0)).collect();
    let sizes: Vec<u32> = supports
        .par_iter()
        .map(|s| {
            let mut size = 0u32;
            for_each_member(s, &mut |idx| {
                counts[idx].fetch_add(1, Ordering::Relaxed);
                size += 1;
            });
            size
        })
        .collect();
    let mut counts: Vec<u32> = counts.into_iter().map(AtomicU32::into_inner).collect();
    let mut by_size: Vec<u32> = (0..supports.len() as u32).collect();
    by_size.sort_by_key(|&i| {
        let s = &supports[i as usize];
        (s.rms <= tolerance, sizes[i as usize], i)
    });
    let mut keep = vec![true; supports.len()];
    for &i in &by_size {
        let s = &supports[i as usize];
        let mut redundant = true;
        for_each_member(s, &mut |idx| redundant &= counts[idx] >= 2);
        if redundant {
            for_each_member(s, &mut |idx| counts[idx] -= 1);
            keep[i as usize] = false;
        }
    }
    supports
        .into_iter()
        .zip(keep)
        .filter_map(|(s, k)| k.then_some(s))
        .collect()
}
