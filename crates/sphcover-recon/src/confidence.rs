//! Confidence of samples (thesis §5.2.3, eq. 5.39–5.40) and outlier labels (§5.2.4).
//!
//! The method is described on [`sample_confidence()`].

use std::time::{Duration, Instant};

use rayon::prelude::*;
use sphcover_core::{
    Cover, CoverError, DVec3, PointIndex, PointIndexError, PuEvaluator, SupportSamples,
};
use thiserror::Error;

use crate::pca::{Pca, RANK_TOLERANCE};

/// Why sample confidences could not be computed.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum ConfidenceError {
    /// The outlier threshold is not finite and non-negative.
    #[error("outlier threshold {0} is not finite and non-negative")]
    InvalidThreshold(f64),
    /// The scanner confidence does not have one entry per sample.
    #[error("scanner confidence has {found} entries for {expected} samples")]
    LengthMismatch {
        /// Expected length (samples, or supports for per-support values).
        expected: usize,
        /// Length given.
        found: usize,
    },
    /// The point index given was not built over the samples given.
    #[error("point index over {found} points given for {expected} samples")]
    IndexMismatch {
        /// Number of samples.
        expected: usize,
        /// Points the index was built over.
        found: usize,
    },
    /// A scanner confidence is NaN or outside `[0, 1]`.
    #[error("scanner confidence of sample {index} is {value}, not in [0, 1]")]
    InvalidScannerConfidence {
        /// Index of the sample.
        index: usize,
        /// The value given.
        value: f64,
    },
    /// The samples could not be indexed.
    #[error("sample index: {0}")]
    Samples(#[from] PointIndexError),
    /// The cover's evaluator could not be built.
    #[error("cover: {0}")]
    Cover(#[from] CoverError),
}

/// Parameters of [`sample_confidence`].
#[derive(Clone, Debug, PartialEq)]
pub struct ConfidenceParams {
    /// Samples whose confidence is below this are outliers (thesis §5.2.4: 0.007).
    pub outlier_threshold: f64,
}

impl Default for ConfidenceParams {
    fn default() -> Self {
        ConfidenceParams {
            outlier_threshold: 0.007,
        }
    }
}

/// Counters of [`sample_confidence`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ConfidenceStats {
    /// Supports of the cover.
    pub supports: usize,
    /// Supports with fewer than 3 samples or all samples at one point (`τ = 0`).
    pub degenerate_supports: usize,
    /// Samples.
    pub samples: usize,
    /// Samples inside no support, or not finite (confidence 0).
    pub uncovered_samples: usize,
    /// Samples labelled outliers.
    pub outliers: usize,
    /// True when the confidence came from the scanner.
    pub scanner_given: bool,
    /// Time for the per-support PCA.
    pub support_time: Duration,
    /// Time for the per-sample blend.
    pub sample_time: Duration,
}

/// Confidences of supports and samples.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleConfidence {
    /// Per support: `τ_i`.
    pub support_confidence: Vec<f64>,
    /// Per sample: `σ_k` (or the scanner's value).
    pub confidence: Vec<f64>,
    /// Per sample: `σ_k` below the outlier threshold.
    pub outliers: Vec<bool>,
    /// Counters.
    pub stats: ConfidenceStats,
}

/// The confidence `τ_i` of every support of `cover` from the samples inside it, and the count
/// of degenerate supports.
pub fn support_confidence(
    cover: &Cover,
    samples: &[DVec3],
) -> Result<(Vec<f64>, usize), ConfidenceError> {
    let index = PointIndex::new(samples)?;
    let incidence = SupportSamples::gather(cover, &index);
    Ok(support_confidence_in(cover, &index, &incidence))
}

/// As [`support_confidence`], over the samples of `incidence` (gathered from `cover` and
/// `index`).
fn support_confidence_in(
    cover: &Cover,
    index: &PointIndex,
    incidence: &SupportSamples,
) -> (Vec<f64>, usize) {
    let points = index.slot_points();
    let tau: Vec<(f64, bool)> = (0..cover.len())
        .into_par_iter()
        .with_min_len(256)
        .map_init(Vec::new, |buf, i| {
            buf.clear();
            incidence.for_each_slot_within(cover, index, i, |s, _| buf.push(points[s]));
            tau_of(cover.centres()[i], cover.radii()[i], buf)
        })
        .collect();
    let degenerate = tau.iter().filter(|t| t.1).count();
    (tau.into_iter().map(|t| t.0).collect(), degenerate)
}

/// `(τ, degenerate)` of the support `(c, r)` holding `points`.
fn tau_of(c: DVec3, r: f64, points: &[DVec3]) -> (f64, bool) {
    if points.len() < 3 {
        return (0.0, true);
    }
    let Some(pca) = Pca::of(points) else {
        return (0.0, true);
    };
    let [l0, l1, l2] = pca.eigenvalues;
    if l2 <= 0.0 {
        return (0.0, true);
    }
    let d = c - pca.centroid;
    let len = d.length();
    if len <= 1e-9 * r {
        return (1.0, false);
    }
    let d = d / len;
    // cos ω: the length of d's projection on the normal line, or on the normal plane when
    // the samples are collinear.
    let cos = if l1 - l0 <= RANK_TOLERANCE * l2 {
        (1.0 - d.dot(pca.axes[2]).powi(2)).max(0.0).sqrt()
    } else {
        d.dot(pca.axes[0]).abs()
    };
    let omega = cos.clamp(0.0, 1.0).acos();
    ((-2.0 * omega * omega).exp(), false)
}

/// Confidence of every sample (thesis eq. 5.39–5.40) and outlier labels, from the supports
/// of `cover` holding it, or from `scanner` (one value in `[0, 1]` per sample) when given.
/// `samples` are in the cover's frame.
///
/// For each support `s_i`: the PCA of the samples inside it gives the centroid `G_i` and the
/// direction of least variance `N_i`; `ω_i ∈ [0, π/2]` is the angle between the lines of
/// `N_i` and `c_i − G_i`, and the support's confidence is
///
/// ```text
/// τ_i = exp(−2 ω_i²)
/// ```
///
/// Why it works: where the samples lie on a smooth sheet, the centroid of the part of the
/// sheet inside a ball is (nearly) the foot of the perpendicular from the centre, so
/// `c_i − G_i` is along the sheet's normal and `τ_i ≈ 1`; a ball over scattered outliers has
/// no such structure. Each sample's confidence blends the confidences of the supports holding
/// it with the cover's kernel weights:
///
/// ```text
/// σ_k = Σ_i w_i(p_k) τ_i / Σ_i w_i(p_k)
/// ```
///
/// Samples with `σ_k` below 0.007 (≈ `exp(−2 (π/2)²)`, the value of a support whose offset is
/// perpendicular to its normal) are outliers. A scanner-given confidence replaces `σ_k`.
///
/// Degenerate supports: fewer than 3 samples, or all samples at one point, carry no plane and
/// get `τ_i = 0`. Collinear samples determine only a line, so the normal is any direction
/// perpendicular to it and `ω_i` is the angle between `c_i − G_i` and that perpendicular
/// plane. A centre at the centroid itself (`‖c_i − G_i‖ ≤ 1e-9 r_i`) gets `τ_i = 1`.
///
/// Both stages run in parallel, one support or one sample per task, and each sum runs in an
/// order fixed by the input (the point index's tree order; ascending support index): the
/// result is bit-identical whatever the thread count.
pub fn sample_confidence(
    cover: &Cover,
    samples: &[DVec3],
    scanner: Option<&[f64]>,
    params: &ConfidenceParams,
) -> Result<SampleConfidence, ConfidenceError> {
    let index = PointIndex::new(samples)?;
    let incidence = SupportSamples::gather(cover, &index);
    let support = SupportConfidence::of(cover, &index, &incidence);
    sample_confidence_with(cover, &index, &incidence, samples, scanner, params, support)
}

/// The supports' confidences `τ_i` over their samples, apart from the samples' (so that a
/// pipeline can compute them beside other work), with the count of degenerate supports and
/// the time they took.
pub(crate) struct SupportConfidence {
    tau: Vec<f64>,
    degenerate: usize,
    time: Duration,
}

impl SupportConfidence {
    /// The confidences of the supports of `cover` over `incidence` (gathered from `cover`
    /// and `index`).
    pub(crate) fn of(cover: &Cover, index: &PointIndex, incidence: &SupportSamples) -> Self {
        let start = Instant::now();
        let (tau, degenerate) = support_confidence_in(cover, index, incidence);
        SupportConfidence {
            tau,
            degenerate,
            time: start.elapsed(),
        }
    }

    /// Sets `τ_i = 0` for the supports that `distrusted(i)` names.
    pub(crate) fn distrust(&mut self, distrusted: impl Fn(usize) -> bool) {
        for (i, t) in self.tau.iter_mut().enumerate() {
            if distrusted(i) {
                *t = 0.0;
            }
        }
    }
}

/// [`ConfidenceError::IndexMismatch`] unless `index` is over exactly `samples` and
/// `incidence` was gathered from `cover` and `index`.
fn check_index(
    cover: &Cover,
    index: &PointIndex,
    incidence: &SupportSamples,
    samples: &[DVec3],
) -> Result<(), ConfidenceError> {
    let found = index.input_len();
    if found != samples.len() || !incidence.fits(cover, index) {
        return Err(ConfidenceError::IndexMismatch {
            expected: samples.len(),
            found,
        });
    }
    Ok(())
}

/// As [`sample_confidence`], over `incidence`: the samples of the cover's supports, gathered
/// from `index`, a point index over exactly `samples` (built by [`PointIndex::new`]), so a
/// caller that needs the incidences again (the diffusion's fitting terms) gathers them once;
/// and with the supports' confidences `support` computed already, where the supports the
/// graph cut found inconsistent have `τ_i = 0` (thesis §5.2.4,
/// [`SupportConfidence::distrust`]).
pub(crate) fn sample_confidence_with(
    cover: &Cover,
    index: &PointIndex,
    incidence: &SupportSamples,
    samples: &[DVec3],
    scanner: Option<&[f64]>,
    params: &ConfidenceParams,
    support: SupportConfidence,
) -> Result<SampleConfidence, ConfidenceError> {
    check_index(cover, index, incidence, samples)?;
    let t = params.outlier_threshold;
    if !(t.is_finite() && t >= 0.0) {
        return Err(ConfidenceError::InvalidThreshold(t));
    }
    if let Some(s) = scanner {
        if s.len() != samples.len() {
            return Err(ConfidenceError::LengthMismatch {
                expected: samples.len(),
                found: s.len(),
            });
        }
        if let Some(index) = s.iter().position(|v| !(0.0..=1.0).contains(v)) {
            return Err(ConfidenceError::InvalidScannerConfidence {
                index,
                value: s[index],
            });
        }
    }
    let mut stats = ConfidenceStats {
        supports: cover.len(),
        samples: samples.len(),
        scanner_given: scanner.is_some(),
        degenerate_supports: support.degenerate,
        support_time: support.time,
        ..Default::default()
    };
    let tau = support.tau;

    let start = Instant::now();
    let confidence: Vec<f64> = match scanner {
        Some(s) => {
            stats.uncovered_samples = samples.iter().filter(|p| !p.is_finite()).count();
            s.to_vec()
        }
        None => {
            let blended = incidence.blend(cover, index, &tau)?;
            stats.uncovered_samples = blended.iter().filter(|v| v.is_none()).count();
            blended.into_iter().map(|v| v.unwrap_or(0.0)).collect()
        }
    };
    let outliers: Vec<bool> = confidence
        .iter()
        .zip(samples)
        .map(|(&s, p)| s < t || !p.is_finite())
        .collect();
    stats.outliers = outliers.iter().filter(|&&o| o).count();
    stats.sample_time = start.elapsed();
    Ok(SampleConfidence {
        support_confidence: tau,
        confidence,
        outliers,
        stats,
    })
}

/// The partition-of-unity blend `Σ_i w_i(x) v_i / Σ_i w_i(x)` of one value per support at
/// each of `points` (σ = 1); `None` where no support covers the point.
pub fn blend_over_supports(
    cover: &Cover,
    points: &[DVec3],
    values: &[f64],
) -> Result<Vec<Option<f64>>, ConfidenceError> {
    if values.len() != cover.len() {
        return Err(ConfidenceError::LengthMismatch {
            expected: cover.len(),
            found: values.len(),
        });
    }
    let eval = PuEvaluator::new(cover, 1.0)?;
    Ok(eval.blend(points, values)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use sphcover_core::{
        Kernel, LocalFunctions, SurfaceCoverParams, build_surface_cover_from_cloud,
    };

    fn grid_plane(m: usize, h: f64) -> Vec<DVec3> {
        (0..m * m)
            .map(|i| {
                DVec3::new((i % m) as f64 * h, (i / m) as f64 * h, 0.0)
                    - DVec3::splat(0.5) * DVec3::new(1.0, 1.0, 0.0)
            })
            .collect()
    }

    fn cover_of(centres: Vec<DVec3>, radii: Vec<f64>) -> Cover {
        let n = centres.len();
        Cover::new(
            centres,
            radii,
            LocalFunctions::zero_linear(n),
            Kernel::QuadraticBSpline,
        )
        .unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// A ball cutting a densely sampled plane away from its edges: the centroid of the
        /// disk is the foot of the centre, so ω ≈ 0 and τ ≈ 1, at any clear height.
        #[test]
        fn support_over_a_plane_is_confident(
            x in -0.2f64..0.2, y in -0.2f64..0.2, height in 0.2f64..0.8, below: bool,
            r in 0.12f64..0.2,
        ) {
            // A centre on the plane itself is the measure's blind spot (see
            // `scattered_cloud_is_less_confident_than_the_surface`).
            let height = if below { -height * r } else { height * r };
            let samples = grid_plane(101, 0.01);
            let cover = cover_of(vec![DVec3::new(x, y, height)], vec![r]);
            let (tau, degenerate) = support_confidence(&cover, &samples).unwrap();
            prop_assert_eq!(degenerate, 0);
            prop_assert!(tau[0] > 0.9, "τ = {}", tau[0]);
        }

        /// A centre displaced along the plane from the samples' centroid (the samples fill
        /// only half the ball): ω = π/2, τ = exp(−π²/2), just above the outlier threshold.
        #[test]
        fn offset_along_the_plane_is_not_confident(r in 0.1f64..0.3) {
            let samples: Vec<DVec3> = grid_plane(101, 0.01)
                .into_iter()
                .filter(|p| p.x > 0.0)
                .collect();
            let cover = cover_of(vec![DVec3::ZERO], vec![r]);
            let (tau, _) = support_confidence(&cover, &samples).unwrap();
            let expected = (-2.0 * std::f64::consts::FRAC_PI_2.powi(2)).exp();
            prop_assert!((tau[0] - expected).abs() < 1e-6, "τ = {}", tau[0]);
        }
    }

    /// A sphere with a cloud of scattered points beside it: the cloud's samples get a much
    /// lower confidence than the surface's. Measured (literal thesis measure): mean σ 0.82 on
    /// the surface, 0.38 in the cloud; with 0.5% noise and no cloud the surface's mean is
    /// 0.60, because supports centred on the surface have an offset `c − G` of random
    /// direction. No sample here falls below the thesis's outlier threshold 0.007, which only
    /// a sample whose every support has ω ≈ π/2 reaches.
    #[test]
    fn scattered_cloud_is_less_confident_than_the_surface() {
        let n = 3000;
        let mut cloud = sphcover_evaluation::sphere(DVec3::ZERO, 0.5, n);
        sphcover_evaluation::add_uniform_outliers(
            &mut cloud,
            300,
            DVec3::new(0.55, -0.15, -0.15),
            DVec3::new(0.85, 0.15, 0.15),
            2,
        );
        let params = SurfaceCoverParams {
            eps: 4e-3,
            ..Default::default()
        };
        let (cover, norm, _) = build_surface_cover_from_cloud(&cloud, &params).unwrap();
        let mut samples = cloud.positions.clone();
        norm.points_to_unit(&mut samples);
        let conf = sample_confidence(&cover, &samples, None, &ConfidenceParams::default()).unwrap();
        let mean = |r: std::ops::Range<usize>| {
            let len = r.len() as f64;
            r.map(|k| conf.confidence[k]).sum::<f64>() / len
        };
        let (surface, scattered) = (mean(0..n), mean(n..samples.len()));
        assert!(surface > 0.75, "surface {surface}");
        assert!(
            scattered < 0.55 * surface,
            "cloud {scattered}, surface {surface}"
        );
        assert_eq!(
            conf.stats.outliers,
            conf.outliers.iter().filter(|&&o| o).count()
        );
        assert!(conf.confidence.iter().all(|s| (0.0..=1.0).contains(s)));
        assert_eq!(conf.stats.uncovered_samples, 0);

        // The same bits on one thread and on two.
        let on = |threads| {
            sphcover_core::on_threads(threads, || {
                sample_confidence(&cover, &samples, None, &ConfidenceParams::default()).unwrap()
            })
        };
        let (a, b) = (on(1), on(2));
        assert_eq!(a.confidence, b.confidence);
        assert_eq!(a.support_confidence, b.support_confidence);

        // A caller's index over the same samples gives the same bits; distrusted supports
        // get τ = 0; an index over other samples is refused.
        let index = PointIndex::new(&samples).unwrap();
        let params = ConfidenceParams::default();
        let incidence = SupportSamples::gather(&cover, &index);
        let indexed = |distrusted: fn(usize) -> bool| {
            let mut support = SupportConfidence::of(&cover, &index, &incidence);
            support.distrust(distrusted);
            sample_confidence_with(&cover, &index, &incidence, &samples, None, &params, support)
                .unwrap()
        };
        let trusted = indexed(|_| false);
        assert_eq!(trusted.confidence, a.confidence);
        assert_eq!(trusted.support_confidence, a.support_confidence);
        assert_eq!(trusted.outliers, a.outliers);
        let distrusted = indexed(|i| i % 3 == 0);
        for (i, (&t, &d)) in a
            .support_confidence
            .iter()
            .zip(&distrusted.support_confidence)
            .enumerate()
        {
            assert_eq!(d, if i % 3 == 0 { 0.0 } else { t }, "support {i}");
        }
        let short_index = PointIndex::new(&samples[1..]).unwrap();
        let short = SupportSamples::gather(&cover, &short_index);
        let support = SupportConfidence::of(&cover, &short_index, &short);
        assert_eq!(
            sample_confidence_with(
                &cover,
                &short_index,
                &short,
                &samples,
                None,
                &params,
                support
            )
            .unwrap_err(),
            ConfidenceError::IndexMismatch {
                expected: samples.len(),
                found: samples.len() - 1
            }
        );

        // A scanner confidence replaces σ.
        let scanner: Vec<f64> = (0..samples.len())
            .map(|k| if k % 2 == 0 { 1.0 } else { 0.0 })
            .collect();
        let s = sample_confidence(
            &cover,
            &samples,
            Some(&scanner),
            &ConfidenceParams::default(),
        )
        .unwrap();
        assert_eq!(s.confidence, scanner);
        assert_eq!(s.stats.outliers, samples.len() / 2);
        assert!(s.stats.scanner_given);
    }

    #[test]
    fn degenerate_input() {
        let cover = cover_of(
            vec![DVec3::ZERO, DVec3::X * 5.0, DVec3::Y * 9.0],
            vec![1.0, 1.0, 1.0],
        );
        // No samples at all.
        let c = sample_confidence(&cover, &[], None, &ConfidenceParams::default()).unwrap();
        assert_eq!(c.support_confidence, vec![0.0; 3]);
        assert_eq!(c.stats.degenerate_supports, 3);
        // Duplicates, a line, a sample outside every support, a non-finite sample.
        let mut samples = vec![DVec3::new(0.1, 0.0, 0.0); 5];
        samples.extend((0..5).map(|i| DVec3::new(5.0, -0.4 + 0.2 * i as f64, 0.0)));
        samples.push(DVec3::splat(50.0));
        samples.push(DVec3::NAN);
        let c = sample_confidence(&cover, &samples, None, &ConfidenceParams::default()).unwrap();
        assert_eq!(c.support_confidence[0], 0.0, "all samples at one point");
        // The line x = 5 through the centre (5, 0, 0): the offset is zero.
        assert_eq!(c.support_confidence[1], 1.0);
        assert_eq!(c.stats.uncovered_samples, 2);
        assert!(c.outliers[10] && c.outliers[11]);
        // A line beside the centre: the offset is perpendicular to the line, so it lies in
        // the plane of normals: ω = 0.
        let line: Vec<DVec3> = (0..5)
            .map(|i| DVec3::new(0.5, -0.4 + 0.2 * i as f64, 0.0))
            .collect();
        let c = sample_confidence(&cover, &line, None, &ConfidenceParams::default()).unwrap();
        assert!((c.support_confidence[0] - 1.0).abs() < 1e-12);
        // Errors.
        let bad = ConfidenceParams {
            outlier_threshold: f64::NAN,
        };
        assert!(matches!(
            sample_confidence(&cover, &line, None, &bad),
            Err(ConfidenceError::InvalidThreshold(_))
        ));
        assert!(matches!(
            sample_confidence(&cover, &line, Some(&[0.5]), &ConfidenceParams::default()),
            Err(ConfidenceError::LengthMismatch { .. })
        ));
        assert!(matches!(
            sample_confidence(
                &cover,
                &line,
                Some(&[0.5, 0.5, 1.5, 0.5, 0.5]),
                &ConfidenceParams::default()
            ),
            Err(ConfidenceError::InvalidScannerConfidence { index: 2, .. })
        ));
    }
}
