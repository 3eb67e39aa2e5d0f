//! Building a cover from oriented surface points (thesis §3.4.1).
//!
//! The method is described on [`build_surface_cover()`].

mod expansion;
mod fit;
mod octree;

use crate::LengthMismatch;
use crate::ParameterError;
use crate::cover::{Cover, CoverError};
use crate::geometry::Normalisation;
use crate::kernel::Kernel;
use crate::local_function::LocalFunctions;
use crate::opposite_faces::FaceSelection;
use crate::point_cloud::PointCloud;
use crate::point_index::{PointIndex, PointIndexError};
use crate::support_samples::SupportSamples;
use fit::Samples;
use glam::DVec3;
use rayon::prelude::*;
use std::borrow::Cow;
use std::time::{Duration, Instant};

pub use octree::MAX_OCTREE_DEPTH;

/// Parameters of [`build_surface_cover`]. Lengths are in the unit frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceCoverParams {
    /// Error tolerance ε of the local fits (thesis tables: 2.5e-3 … 1e-3).
    pub eps: f64,
    /// Fewest points a support's ball must hold; smaller balls grow to reach them (MPU: 15).
    pub n_min: usize,
    /// Deepest octree level (the root is level 0), at most [`MAX_OCTREE_DEPTH`].
    pub max_depth: u32,
    /// Stop refining where the sampling density cannot support ε: a subdivision whose
    /// non-empty children all hold fewer than `n_min` points in their own balls and still
    /// miss ε with their grown balls is undone (the octant keeps its fit, and its error is
    /// reported). Keeps the support count below the point count on sparse scans. Off by
    /// default: the reconstruction's outlier confidence (thesis eq. 5.39) relies on sparse
    /// outlier clouds being covered by many small supports (with the rule, a 300-point cloud
    /// beside a sphere keeps a mean confidence of 0.61 instead of 0.38); `sphcover cover`
    /// turns it on.
    pub sampling_stop: bool,
    /// Weight kernel of the fits and of the cover.
    pub kernel: Kernel,
    /// Seed of the random expansion order.
    pub seed: u64,
    /// Whether to run the expansion and elimination stage.
    pub expansion: bool,
    /// Margin added on every side of the unit cube to make the octree's root cube, in unit
    /// lengths (0.05 makes a root cube of side 1.1). Points must lie inside the root cube.
    pub box_margin: f64,
    /// Largest factor by which expansion may grow a radius (≥ 1). The root cube's diagonal
    /// bounds every grown radius too.
    pub max_growth: f64,
    /// Relative width at which the bisection for a grown radius stops (in `(0, 1]`): unless
    /// the radius reached its cap, a trial at most this factor above the radius found
    /// failed (`E > ε`).
    pub growth_tolerance: f64,
    /// Which samples a support whose ball holds two faces of a thin part fits
    /// ([`crate::face_to_fit`]). The wide face by default; the reconstruction takes the
    /// narrow one on scans nearly free of noise.
    pub faces: FaceSelection,
}

impl Default for SurfaceCoverParams {
    fn default() -> SurfaceCoverParams {
        SurfaceCoverParams {
            eps: 2.5e-3,
            n_min: 15,
            max_depth: 12,
            sampling_stop: false,
            kernel: Kernel::QuadraticBSpline,
            seed: 0,
            expansion: true,
            box_margin: 0.05,
            max_growth: 8.0,
            growth_tolerance: 0.05,
            faces: FaceSelection::Wide,
        }
    }
}

/// Why a surface cover could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SurfaceCoverError {
    /// The input has no normals; the surface builder fits planes to oriented points.
    #[error(
        "the surface cover builder needs a normal per point (outward); the input has none — estimate and orient normals first"
    )]
    MissingNormals,
    /// A per-point array does not have one entry per point.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
    /// A parameter is out of its range.
    #[error(transparent)]
    InvalidParameter(#[from] ParameterError),
    /// A point has a NaN or infinite coordinate.
    #[error("point {index} ({point}) is not finite")]
    NonFinitePoint {
        /// Index of the point.
        index: usize,
        /// The point.
        point: DVec3,
    },
    /// A point lies outside the root cube: the input is not in the unit frame.
    #[error(
        "point {index} ({point}) lies outside the root cube |x|,|y|,|z| ≤ {half_side}: normalise the input to the unit frame first (build_surface_cover_from_cloud does)"
    )]
    NotNormalised {
        /// Index of the point.
        index: usize,
        /// The point.
        point: DVec3,
        /// Half the side of the root cube.
        half_side: f64,
    },
    /// A confidence is negative or not finite.
    #[error("confidence of point {index} is {value}; expected a finite value ≥ 0")]
    InvalidConfidence {
        /// Index of the point.
        index: usize,
        /// The value given.
        value: f64,
    },
    /// No point with a usable normal (and positive confidence) is left.
    #[error(
        "no usable point: {points} points given, {skipped_normals} with a zero or non-finite normal"
    )]
    NoUsablePoints {
        /// Number of points given.
        points: usize,
        /// Points skipped for their normals.
        skipped_normals: usize,
    },
    /// More points or supports than `u32` indices reach.
    #[error(transparent)]
    TooMany(#[from] PointIndexError),
    /// The cover assembled from the fits was rejected (a bug, reported rather than hidden).
    #[error("internal error assembling the cover: {0}")]
    Cover(#[from] CoverError),
}

/// Wall-clock time of each stage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SurfaceCoverTimings {
    /// Validating the input and building the point index.
    pub index: Duration,
    /// The adaptive, balanced octree with its fits.
    pub octree: Duration,
    /// Growing the supports and finding the ones inside each grown ball (parallel).
    pub growth: Duration,
    /// Indexing the centres and the sequential elimination passes.
    pub elimination: Duration,
    /// Everything.
    pub total: Duration,
}

/// What [`build_surface_cover`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceCoverStats {
    /// Points given.
    pub input_points: usize,
    /// Points used (with a usable normal).
    pub used_points: usize,
    /// Points skipped because their normal is zero or not finite.
    pub skipped_normals: usize,
    /// Octants fitted at each level (index = level), leaves and subdivided ones.
    pub octants_per_level: Vec<usize>,
    /// Leaves at each level (index = level): the supports before expansion.
    pub leaves_per_level: Vec<usize>,
    /// Leaves whose own ball held fewer than `n_min` points, so the radius grew to reach
    /// them.
    pub grown_leaves: usize,
    /// Leaves whose own ball held no point (never subdivided).
    pub empty_leaves: usize,
    /// Octants over ε left unsubdivided because their children were all sampling-limited
    /// and over ε too ([`SurfaceCoverParams::sampling_stop`]).
    pub sampling_limited_octants: usize,
    /// Octants created to restore the 2:1 balance.
    pub balance_octants: usize,
    /// Supports before expansion (octree leaves).
    pub supports_before_expansion: usize,
    /// Supports in the cover.
    pub supports_after_expansion: usize,
    /// Supports whose radius grew in expansion.
    pub grown_supports: usize,
    /// Local fits computed (octants plus expansion trials).
    pub fits: u64,
    /// Octants subdivided on a lower bound of their fit error alone, without a fit (see the
    /// octree's module docs).
    pub bounded_octants: usize,
    /// Supports of the cover whose fit error exceeds ε (leaves at the maximum depth, grown
    /// or sampling-limited octants).
    pub supports_over_eps: usize,
    /// Largest fit error among the cover's supports.
    pub max_error: f64,
    /// Time per stage.
    pub timings: SurfaceCoverTimings,
}

/// The oriented points a surface cover is built from, in the unit frame, with what the
/// caller may add: a confidence per point, and a point index it has built already.
///
/// ```
/// use sphcover_core::{DVec3, SurfaceCoverParams, SurfaceSamples, build_surface_cover};
///
/// // A 20 × 20 patch of the plane z = 0 with upward normals.
/// let points: Vec<DVec3> = (0..400)
///     .map(|i| DVec3::new((i % 20) as f64 / 40.0 - 0.25, (i / 20) as f64 / 40.0 - 0.25, 0.0))
///     .collect();
/// let normals = vec![DVec3::Z; points.len()];
/// let samples = SurfaceSamples::new(&points, &normals);
/// let (cover, stats) = build_surface_cover(&samples, &SurfaceCoverParams::default())?;
/// assert_eq!(stats.used_points, 400);
/// assert!(cover.len() > 0);
/// # Ok::<(), sphcover_core::SurfaceCoverError>(())
/// ```
#[derive(Clone, Copy, Debug)]
pub struct SurfaceSamples<'a> {
    /// Positions in the unit frame.
    pub points: &'a [DVec3],
    /// Outward normals, one per point; they need not be unit length (they are normalised).
    pub normals: &'a [DVec3],
    /// A confidence per point: each fit weight is multiplied by it, and points of zero
    /// confidence neither weigh in nor count in the error (they are left out entirely).
    pub confidence: Option<&'a [f64]>,
    /// A point index over exactly `points` ([`PointIndex::new`]), which the build uses
    /// instead of indexing the points again whenever it uses every point (no zero normal, no
    /// zero confidence). Any other index is ignored; the cover is the same either way.
    pub index: Option<&'a PointIndex>,
}

impl<'a> SurfaceSamples<'a> {
    /// Points and their normals, without confidence or index.
    pub fn new(points: &'a [DVec3], normals: &'a [DVec3]) -> SurfaceSamples<'a> {
        SurfaceSamples {
            points,
            normals,
            confidence: None,
            index: None,
        }
    }

    /// The same samples with a confidence per point.
    pub fn with_confidence(self, confidence: Option<&'a [f64]>) -> SurfaceSamples<'a> {
        SurfaceSamples { confidence, ..self }
    }

    /// The same samples with a point index the caller has built over them.
    pub fn with_index(self, index: &'a PointIndex) -> SurfaceSamples<'a> {
        SurfaceSamples {
            index: Some(index),
            ..self
        }
    }
}

/// Builds the cover of oriented points given in the unit frame (thesis §3.4.1).
///
/// Points whose normal is zero or not finite are skipped and counted in
/// [`SurfaceCoverStats::skipped_normals`].
///
/// Input: points in the unit frame (bounding box centred at the origin, longest edge 1; see
/// [`Normalisation`]) with outward normals and optionally a confidence per point. Output: a
/// [`Cover`] with linear local functions `g_i(x) = n̄_i·(p̄_i − x)` (positive inside) whose
/// partition-of-unity blend approximates the signed distance to the sampled surface.
///
/// Two stages:
///
/// 1. **Initial cover** (`octree.rs`): an adaptive, 2:1-balanced octree over the root cube
///    (the unit cube around the origin enlarged by [`SurfaceCoverParams::box_margin`] on every
///    side); each leaf carries a support at its centre with radius `0.75 ×` its diagonal,
///    grown to reach `n_min` points when it holds fewer; octants are subdivided while the fit
///    error `E_i = max_j |g_i(p_j)|` exceeds ε, up to the maximum depth.
/// 2. **Expansion** (`expansion.rs`, optional): supports in seeded random order grow as far
///    as `E_i ≤ ε` allows, and supports lying entirely inside a grown ball are deleted.
///
/// The local fit (`fit.rs`) is thesis eq. 3.2 with the kernel's weights. Every stage runs in
/// parallel with rayon, and the cover is bit-identical for the same input, parameters and
/// seed whatever the thread count.
///
/// # Example
///
/// ```
/// use sphcover_core::{DVec3, PuEvaluator, SurfaceCoverParams, SurfaceSamples, build_surface_cover};
///
/// // 2000 points on a sphere of radius 0.4 with outward normals (a Fibonacci lattice).
/// let n = 2000;
/// let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
/// let normals: Vec<DVec3> = (0..n)
///     .map(|i| {
///         let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
///         let s = (1.0 - z * z).sqrt();
///         let a = golden * i as f64;
///         DVec3::new(s * a.cos(), s * a.sin(), z)
///     })
///     .collect();
/// let points: Vec<DVec3> = normals.iter().map(|&u| 0.4 * u).collect();
///
/// let params = SurfaceCoverParams { eps: 1e-2, ..SurfaceCoverParams::default() };
/// let (cover, stats) = build_surface_cover(&SurfaceSamples::new(&points, &normals), &params)?;
/// assert_eq!(stats.supports_after_expansion, cover.len());
///
/// // Positive inside, negative outside, near zero on the surface.
/// let f = PuEvaluator::new(&cover, 1.0)?;
/// assert!(f.value(DVec3::ZERO).unwrap() > 0.2);
/// assert!(f.value(DVec3::new(0.45, 0.0, 0.0)).unwrap() < 0.0);
/// assert!(f.value(points[0]).unwrap().abs() <= 2.0 * params.eps);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn build_surface_cover(
    samples: &SurfaceSamples<'_>,
    params: &SurfaceCoverParams,
) -> Result<(Cover, SurfaceCoverStats), SurfaceCoverError> {
    let (cover, stats, _) = build(samples, params, false)?;
    Ok((cover, stats))
}

/// [`build_surface_cover`], and the samples of every support over the index that came with
/// `samples` ([`SurfaceSamples::with_index`]): what [`SupportSamples::gather`] of the cover
/// and that index gives, bit for bit. Most supports take their rows from the points their
/// fits gathered (those the expansion grew, and the octants grown to their `n_min` nearest
/// points), so only the others are gathered again.
/// `None` when the build could not use that index as it is (no index given, or points left
/// out for a zero normal or confidence); [`SupportSamples::gather`] serves then.
///
/// ```
/// use sphcover_core::{
///     DVec3, PointIndex, SupportSamples, SurfaceCoverParams, SurfaceSamples,
///     build_surface_cover_with_samples,
/// };
///
/// // Points on a sphere of radius 0.3, with outward normals.
/// let n = 2000;
/// let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
/// let normals: Vec<DVec3> = (0..n)
///     .map(|i| {
///         let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
///         let (s, a) = ((1.0 - z * z).sqrt(), golden * i as f64);
///         DVec3::new(s * a.cos(), s * a.sin(), z)
///     })
///     .collect();
/// let points: Vec<DVec3> = normals.iter().map(|&u| 0.3 * u).collect();
/// let index = PointIndex::new(&points)?;
/// let samples = SurfaceSamples::new(&points, &normals).with_index(&index);
/// let (cover, _stats, incidence) =
///     build_surface_cover_with_samples(&samples, &SurfaceCoverParams::default())?;
/// assert_eq!(incidence, Some(SupportSamples::gather(&cover, &index)));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn build_surface_cover_with_samples(
    samples: &SurfaceSamples<'_>,
    params: &SurfaceCoverParams,
) -> Result<(Cover, SurfaceCoverStats, Option<SupportSamples>), SurfaceCoverError> {
    build(samples, params, true)
}

/// The build; with `want_rows`, also the samples of every support when the given index
/// served as it is.
fn build(
    given: &SurfaceSamples<'_>,
    params: &SurfaceCoverParams,
    want_rows: bool,
) -> Result<(Cover, SurfaceCoverStats, Option<SupportSamples>), SurfaceCoverError> {
    let SurfaceSamples {
        points,
        normals,
        confidence,
        index: given_index,
    } = *given;
    let start = Instant::now();
    check_params(params)?;
    let n = points.len();
    if normals.len() != n {
        return Err(SurfaceCoverError::LengthMismatch(LengthMismatch {
            array: "normals",
            expected: n,
            found: normals.len(),
        }));
    }
    if let Some(c) = confidence {
        if c.len() != n {
            return Err(SurfaceCoverError::LengthMismatch(LengthMismatch {
                array: "confidence",
                expected: n,
                found: c.len(),
            }));
        }
        if let Some(index) = c.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(SurfaceCoverError::InvalidConfidence {
                index,
                value: c[index],
            });
        }
    }
    let half_side = 0.5 + params.box_margin;
    let outside = |point: &DVec3| !point.is_finite() || point.abs().max_element() > half_side;
    if let Some(index) = points.par_iter().position_first(outside) {
        let point = points[index];
        return Err(if point.is_finite() {
            SurfaceCoverError::NotNormalised {
                index,
                point,
                half_side,
            }
        } else {
            SurfaceCoverError::NonFinitePoint { index, point }
        });
    }

    let normal_ok = |normal: &DVec3| {
        let length = normal.length();
        length > 0.0 && length.is_finite()
    };
    let mut stats = SurfaceCoverStats {
        input_points: n,
        skipped_normals: normals.par_iter().filter(|m| !normal_ok(m)).count(),
        ..SurfaceCoverStats::default()
    };
    // Usually every point is kept: then nothing is copied (at 362K points the copies held
    // one thread for tens of milliseconds, much of it faulting in fresh pages).
    let every_point_kept =
        stats.skipped_normals == 0 && confidence.is_none_or(|c| !c.contains(&0.0));
    type Kept<'a, T> = Cow<'a, [T]>;
    let (kept_points, kept_normals, kept_conf): (Kept<DVec3>, Kept<DVec3>, Option<Kept<f64>>) =
        if every_point_kept {
            (
                Cow::Borrowed(points),
                Cow::Borrowed(normals),
                confidence.map(Cow::Borrowed),
            )
        } else {
            let keep = |i: usize| normal_ok(&normals[i]) && confidence.is_none_or(|c| c[i] != 0.0);
            let kept: Vec<usize> = (0..n).filter(|&i| keep(i)).collect();
            (
                kept.iter().map(|&i| points[i]).collect(),
                kept.iter().map(|&i| normals[i]).collect(),
                confidence.map(|c| kept.iter().map(|&i| c[i]).collect()),
            )
        };
    stats.used_points = kept_points.len();
    if kept_points.is_empty() {
        return Err(SurfaceCoverError::NoUsablePoints {
            points: n,
            skipped_normals: stats.skipped_normals,
        });
    }
    // An index over exactly the points kept (checked slot by slot, far cheaper than building
    // one; an index over all the input fails the check when any was left out) serves as it is.
    let indexes_kept = |index: &PointIndex| {
        index.input_len() == kept_points.len()
            && index.len() == kept_points.len()
            && index
                .order()
                .par_iter()
                .zip(index.slot_points())
                .all(|(&i, &p)| kept_points[i as usize] == p)
    };
    let index = match given_index {
        Some(index) if indexes_kept(index) => Cow::Borrowed(index),
        _ => Cow::Owned(PointIndex::new(&kept_points)?),
    };
    let samples = Samples {
        normals: index
            .order()
            .par_iter()
            .map(|&i| {
                let normal = kept_normals[i as usize];
                normal / normal.length()
            })
            .collect(),
        confidence: kept_conf.map(|c| index.order().par_iter().map(|&i| c[i as usize]).collect()),
        index,
        faces: params.faces,
    };
    drop(kept_points);
    drop(kept_normals);
    let t_index = Instant::now();
    stats.timings.index = t_index - start;

    let geometry = octree::Geometry {
        min: -half_side,
        side: 2.0 * half_side,
    };
    let keep_rows = want_rows && matches!(samples.index, Cow::Borrowed(_));
    let (leaves, octree_rows) = octree::build(&samples, params, geometry, &mut stats, keep_rows);
    stats.supports_before_expansion = leaves.len();
    stats.grown_leaves = leaves.iter().filter(|l| l.grown).count();
    stats.empty_leaves = leaves.iter().filter(|l| l.empty).count();
    let t_octree = Instant::now();
    stats.timings.octree = t_octree - t_index;

    let mut centres: Vec<DVec3> = leaves.iter().map(|l| l.centre).collect();
    let mut radii: Vec<f64> = leaves.iter().map(|l| l.radius).collect();
    let mut fits: Vec<fit::Fit> = leaves.iter().map(|l| l.fit).collect();
    let mut rows = octree_rows;
    if params.expansion {
        let max_radius = 2.0 * half_side * 3f64.sqrt();
        let expanded = expansion::expand(
            &leaves, &centres, &radii, fits, rows, &samples, params, max_radius, keep_rows,
        )?;
        fits = expanded.fit;
        rows = expanded.rows;
        stats.fits += expanded.fits;
        stats.timings.growth = expanded.growth;
        stats.timings.elimination = expanded.elimination;
        let mut kept = 0;
        for i in 0..leaves.len() {
            if expanded.alive[i] {
                if expanded.radius[i] > radii[i] {
                    stats.grown_supports += 1;
                }
                centres[kept] = centres[i];
                radii[kept] = expanded.radius[i];
                fits[kept] = fits[i];
                rows.swap(kept, i);
                kept += 1;
            }
        }
        centres.truncate(kept);
        radii.truncate(kept);
        fits.truncate(kept);
        rows.truncate(kept);
    }
    stats.supports_after_expansion = centres.len();
    stats.supports_over_eps = fits.iter().filter(|f| f.error > params.eps).count();
    stats.max_error = fits.iter().map(|f| f.error).fold(0.0, f64::max);
    let funcs = LocalFunctions::from_linear(fits.iter().map(fit::Fit::linear));
    let cover = Cover::new(centres, radii, funcs, params.kernel)?;
    let incidence = keep_rows.then(|| SupportSamples::from_rows(&cover, &samples.index, rows));
    stats.timings.total = start.elapsed();
    Ok((cover, stats, incidence))
}

/// Normalises a copy of `cloud` to the unit frame (thesis §3.4.1) and builds its cover; uses
/// the cloud's confidence when it has one. Returns the cover (in the unit frame), the
/// normalisation that maps it back to input coordinates, and the statistics.
pub fn build_surface_cover_from_cloud(
    cloud: &PointCloud,
    params: &SurfaceCoverParams,
) -> Result<(Cover, Normalisation, SurfaceCoverStats), SurfaceCoverError> {
    let normals = cloud
        .normals
        .as_deref()
        .ok_or(SurfaceCoverError::MissingNormals)?;
    if let Some(index) = cloud.positions.iter().position(|p| !p.is_finite()) {
        return Err(SurfaceCoverError::NonFinitePoint {
            index,
            point: cloud.positions[index],
        });
    }
    let normalisation =
        Normalisation::of_points(&cloud.positions).ok_or(SurfaceCoverError::NoUsablePoints {
            points: cloud.len(),
            skipped_normals: 0,
        })?;
    let mut unit = cloud.positions.clone();
    normalisation.points_to_unit(&mut unit);
    // Rounding may put a coordinate a hair past ±0.5; the root cube's margin absorbs it.
    let samples = SurfaceSamples::new(&unit, normals).with_confidence(cloud.confidence.as_deref());
    let (cover, stats) = build_surface_cover(&samples, params)?;
    Ok((cover, normalisation, stats))
}

fn check_params(p: &SurfaceCoverParams) -> Result<(), SurfaceCoverError> {
    let invalid = |name, value, requirement| {
        Err(SurfaceCoverError::InvalidParameter(ParameterError {
            name,
            value,
            expected: requirement,
        }))
    };
    if !(p.eps.is_finite() && p.eps > 0.0) {
        return invalid("eps", p.eps, "a finite positive number");
    }
    if p.n_min == 0 {
        return invalid("n_min", 0.0, "at least 1");
    }
    if p.max_depth > MAX_OCTREE_DEPTH {
        return invalid("max_depth", f64::from(p.max_depth), "at most 20");
    }
    if !(p.box_margin.is_finite() && p.box_margin >= 0.0) {
        return invalid("box_margin", p.box_margin, "a finite number ≥ 0");
    }
    if !(p.max_growth.is_finite() && p.max_growth >= 1.0) {
        return invalid("max_growth", p.max_growth, "a finite number ≥ 1");
    }
    if !(p.growth_tolerance > 0.0 && p.growth_tolerance <= 1.0) {
        return invalid("growth_tolerance", p.growth_tolerance, "a number in (0, 1]");
    }
    Ok(())
}
