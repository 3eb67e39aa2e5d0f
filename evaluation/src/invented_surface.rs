//! Surface a reconstruction makes up far from its input points, measured without a ground
//! truth: what matters for raw scans, whose unseen parts no reconstruction can know.
//!
//! * The input's *sample spacing* is the median, over the input points, of the distance from a
//!   point to its nearest other point (0 for a point with a duplicate).
//! * The reconstruction is sampled by area ([`SurfaceSampler`], seeded); a sample is
//!   *invented* when its nearest input point is farther than `K` spacings (strictly), and the
//!   *invented fraction* is the share of samples that are: the share of the surface's area
//!   farther than `K` spacings from every input point.
//! * The other direction, how far the input lies from the reconstruction, is the median and
//!   the 95th percentile of the exact point-to-triangle distance from a random subset of the
//!   input points (all of them when there are few).
//!
//! These are the definitions of the `invented` command of the scan-metrics script the
//! benchmark notes were made with (`scan_metrics.py invented REC POINTS`: K = 3, a million
//! area samples, 50,000 input points), so numbers from either agree up to sampling noise.
//! On an exact surface sampled at random (a Poisson process), the chance that a point of the
//! surface is farther than `K` median spacings from every sample is `2^(−K²)`: 0.2% for
//! K = 3. A square grid of samples on a plane scores 0 (no point of the plane is farther than
//! 0.71 spacings from the grid).
//!
//! Lengths are in the input's units. Every query is per point and the samples come from one
//! seeded generator, so the scores do not depend on the thread count.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use sphcover_core::{DVec3, PointIndex, TriMesh};

use crate::recon_metrics::{percentile, surface_triangles};
use crate::surface_sampling::SurfaceSampler;
use crate::triangle_bvh::TriangleBvh;

/// Why invented surface could not be measured.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InventedSurfaceError {
    /// Fewer than two finite input points: no spacing to measure.
    #[error("the input has {points} finite points: a spacing needs at least 2")]
    TooFewPoints {
        /// Finite input points.
        points: usize,
    },
    /// The reconstruction has no triangle of positive area.
    #[error("the reconstruction has no surface ({triangles} triangles, none of positive area)")]
    EmptyReconstruction {
        /// Triangles in the reconstruction.
        triangles: usize,
    },
    /// A parameter is out of range.
    #[error("{0}")]
    InvalidParameter(&'static str),
}

/// What to measure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InventedSurfaceParams {
    /// Area samples drawn on the reconstruction.
    pub samples: usize,
    /// Seed of the area samples and of the subset of input points.
    pub seed: u64,
    /// `K`: samples farther than this many spacings from every input point are invented.
    pub spacings: f64,
    /// Input points (at most) whose distance to the reconstruction is measured.
    pub input_samples: usize,
    /// Input points farther than this many spacings from the reconstruction are left out
    /// by it (surface the scanner saw and the reconstruction dropped).
    pub uncovered_spacings: f64,
}

impl Default for InventedSurfaceParams {
    fn default() -> InventedSurfaceParams {
        InventedSurfaceParams {
            samples: 1_000_000,
            seed: 0,
            spacings: 3.0,
            input_samples: 50_000,
            uncovered_spacings: 2.0,
        }
    }
}

/// The scores of one reconstruction against its input points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InventedSurface {
    /// The input's sample spacing: the median distance from a point to its nearest other.
    pub spacing: f64,
    /// `K` spacings: the distance beyond which surface is invented.
    pub threshold: f64,
    /// Share of the reconstruction's area farther than `threshold` from every input point
    /// (0 to 1).
    pub invented_fraction: f64,
    /// Median distance from an input point to the reconstruction.
    pub input_to_rec_median: f64,
    /// 95th percentile of the distances from the input points to the reconstruction.
    pub input_to_rec_p95: f64,
    /// Share of the measured input points farther than `uncovered_spacings` spacings from
    /// the reconstruction (0 to 1).
    pub uncovered_fraction: f64,
    /// Area samples drawn.
    pub samples: usize,
    /// Input points whose distance to the reconstruction was measured.
    pub input_samples: usize,
}

/// The input points of a reconstruction, indexed once, with their sample spacing: one scan
/// scores every reconstruction made from it.
#[derive(Clone, Debug)]
pub struct InputPoints {
    index: PointIndex,
    spacing: f64,
}

impl InputPoints {
    /// Indexes `points` (non-finite ones are left out) and measures their spacing.
    pub fn new(points: &[DVec3]) -> Result<InputPoints, InventedSurfaceError> {
        let too_few = |points| InventedSurfaceError::TooFewPoints { points };
        let index = PointIndex::new(points).map_err(|_| too_few(points.len()))?;
        if index.len() < 2 {
            return Err(too_few(index.len()));
        }
        // From a point itself, the second nearest is the nearest other point.
        let nearest_other: Vec<f64> = index
            .slot_points()
            .par_iter()
            .map_init(Vec::new, |found, &p| {
                index.nearest_k_with_distances(p, 2, found);
                found[1].0.sqrt()
            })
            .collect();
        let spacing = percentile(&nearest_other, 50.0);
        Ok(InputPoints { index, spacing })
    }

    /// Number of indexed (finite) points.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// True when no point is indexed (never, for a built set).
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// The median distance from a point to its nearest other point.
    pub fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Scores `rec` against these points (see the module docs).
    pub fn score(
        &self,
        rec: &TriMesh,
        params: &InventedSurfaceParams,
    ) -> Result<InventedSurface, InventedSurfaceError> {
        if params.samples == 0 {
            return Err(InventedSurfaceError::InvalidParameter(
                "at least one area sample is needed",
            ));
        }
        if !(params.spacings.is_finite()
            && params.spacings >= 0.0
            && params.uncovered_spacings.is_finite()
            && params.uncovered_spacings >= 0.0)
        {
            return Err(InventedSurfaceError::InvalidParameter(
                "the threshold in spacings must be finite and at least 0",
            ));
        }
        let surface = surface_triangles(rec);
        let empty = || InventedSurfaceError::EmptyReconstruction {
            triangles: rec.triangles.len(),
        };
        let sampler = SurfaceSampler::new(&surface).map_err(|_| empty())?;
        let bvh = TriangleBvh::new(&surface).map_err(|_| empty())?;
        let threshold = params.spacings * self.spacing;

        let mut rng = Pcg64::seed_from_u64(params.seed);
        let positions: Vec<DVec3> = (0..params.samples)
            .map(|_| sampler.sample(&mut rng).position)
            .collect();
        let invented = positions
            .par_iter()
            .map_init(Vec::new, |found, &p| {
                self.index.nearest_k_with_distances(p, 1, found);
                found.first().is_none_or(|&(d2, _)| d2.sqrt() > threshold)
            })
            .filter(|&far| far)
            .count();

        // A random subset of the input points (partial Fisher–Yates over the slots), or all.
        let n = self.index.len();
        let take = params.input_samples.min(n);
        let mut slots: Vec<u32> = (0..n as u32).collect();
        if take < n {
            let mut rng = Pcg64::seed_from_u64(params.seed);
            for i in 0..take {
                let j = rng.random_range(i..n);
                slots.swap(i, j);
            }
            slots.truncate(take);
        }
        let points = self.index.slot_points();
        let to_rec: Vec<f64> = slots
            .par_iter()
            .map(|&s| {
                bvh.closest_point(points[s as usize])
                    .map_or(f64::INFINITY, |c| c.distance_squared.sqrt())
            })
            .collect();

        Ok(InventedSurface {
            spacing: self.spacing,
            threshold,
            invented_fraction: invented as f64 / params.samples as f64,
            input_to_rec_median: percentile(&to_rec, 50.0),
            input_to_rec_p95: percentile(&to_rec, 95.0),
            uncovered_fraction: to_rec
                .iter()
                .filter(|&&d| d > params.uncovered_spacings * self.spacing)
                .count() as f64
                / to_rec.len().max(1) as f64,
            samples: params.samples,
            input_samples: to_rec.len(),
        })
    }
}

/// Scores `rec` against the input `points` it was made from (see the module docs); to score
/// several reconstructions of one input, build [`InputPoints`] once.
pub fn score_invented_surface(
    rec: &TriMesh,
    points: &[DVec3],
    params: &InventedSurfaceParams,
) -> Result<InventedSurface, InventedSurfaceError> {
    InputPoints::new(points)?.score(rec, params)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ground_truth_meshes::icosphere;

    /// The square `[x0, x0 + side] × [0, side]` at height `z`, as two triangles.
    fn square(x0: f64, side: f64, z: f64) -> TriMesh {
        TriMesh::new(
            vec![
                DVec3::new(x0, 0.0, z),
                DVec3::new(x0 + side, 0.0, z),
                DVec3::new(x0 + side, side, z),
                DVec3::new(x0, side, z),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    /// A regular `n × n` grid of points over the unit square at height `z`.
    fn grid(n: usize, z: f64) -> Vec<DVec3> {
        let h = 1.0 / (n - 1) as f64;
        (0..n * n)
            .map(|k| DVec3::new((k % n) as f64 * h, (k / n) as f64 * h, z))
            .collect()
    }

    fn params(samples: usize) -> InventedSurfaceParams {
        InventedSurfaceParams {
            samples,
            ..InventedSurfaceParams::default()
        }
    }

    #[test]
    fn the_sampled_surface_itself_invents_nothing() {
        let points = grid(101, 0.0);
        let s = score_invented_surface(&square(0.0, 1.0, 0.0), &points, &params(100_000)).unwrap();
        assert!((s.spacing - 0.01).abs() < 1e-12, "{s:?}");
        assert!((s.threshold - 0.03).abs() < 1e-12);
        assert_eq!(s.invented_fraction, 0.0);
        // Up to rounding.
        assert!(s.input_to_rec_median < 1e-12 && s.input_to_rec_p95 < 1e-12);
        assert_eq!(s.input_samples, 10_201);
        assert_eq!(s.uncovered_fraction, 0.0);
    }

    #[test]
    fn input_the_reconstruction_leaves_out_is_uncovered() {
        // The output holds the quarter [0, 0.5]² of the sampled unit square: within 2.5
        // spacings (0.025) of it lie the 53 × 53 points up to 0.52 but the corner (0.52,
        // 0.52), 0.028 away.
        let points = grid(101, 0.0);
        let p = InventedSurfaceParams {
            uncovered_spacings: 2.5,
            ..params(10_000)
        };
        let s = score_invented_surface(&square(0.0, 0.5, 0.0), &points, &p).unwrap();
        let covered = 53.0 * 53.0 - 1.0;
        assert!(
            (s.uncovered_fraction - (1.0 - covered / 10_201.0)).abs() < 1e-12,
            "{s:?}"
        );
    }

    #[test]
    fn a_far_patch_scores_its_share_of_the_area() {
        // The unit square, sampled, and a square of side 0.5 five units away: 0.25 of 1.25
        // of the area is invented.
        let points = grid(101, 0.0);
        let mut rec = square(0.0, 1.0, 0.0);
        let far = square(3.0, 0.5, 5.0);
        rec.vertices.extend(&far.vertices);
        rec.triangles.extend([[4, 5, 6], [4, 6, 7]]);
        // A triangle without area adds nothing.
        rec.triangles.push([4, 4, 5]);
        let s = score_invented_surface(&rec, &points, &params(200_000)).unwrap();
        // Binomial standard deviation: about 0.0009.
        assert!((s.invented_fraction - 0.2).abs() < 0.005, "{s:?}");
    }

    #[test]
    fn the_input_distance_is_measured_to_the_triangles() {
        // Points 0.01 above the square; the subset of 500 of 10,201 points sees the same.
        let points = grid(101, 0.01);
        let p = InventedSurfaceParams {
            input_samples: 500,
            ..params(10_000)
        };
        let s = score_invented_surface(&square(0.0, 1.0, 0.0), &points, &p).unwrap();
        assert_eq!(s.input_samples, 500);
        assert!((s.input_to_rec_median - 0.01).abs() < 1e-12);
        assert!((s.input_to_rec_p95 - 0.01).abs() < 1e-12);
        // 0.01 is far below 3 spacings: the surface is still all near the input.
        assert_eq!(s.invented_fraction, 0.0);
    }

    #[test]
    fn random_samples_of_the_surface_leave_two_to_the_minus_k_squared() {
        // Area-uniform points on a sphere: the chance of an empty disc of radius K median
        // spacings is 2^(−K²) (0.00195 for K = 3, 0.0625 for K = 2) on a Poisson process.
        let mesh = icosphere(DVec3::ZERO, 1.0, 5);
        let mut rng = Pcg64::seed_from_u64(3);
        let points: Vec<DVec3> = SurfaceSampler::new(&mesh)
            .unwrap()
            .samples(40_000, &mut rng)
            .iter()
            .map(|s| s.position)
            .collect();
        let input = InputPoints::new(&points).unwrap();
        let three = input.score(&mesh, &params(400_000)).unwrap();
        assert!(
            (0.0012..0.003).contains(&three.invented_fraction),
            "{three:?}"
        );
        let two = InventedSurfaceParams {
            spacings: 2.0,
            ..params(400_000)
        };
        let two = input.score(&mesh, &two).unwrap();
        assert!((two.invented_fraction - 0.0625).abs() < 0.006, "{two:?}");
        // The points lie on the mesh: the input → mesh distances are rounding only.
        assert!(three.input_to_rec_p95 < 1e-12);
    }

    #[test]
    fn scores_do_not_depend_on_the_thread_count() {
        let mesh = icosphere(DVec3::ZERO, 1.0, 3);
        let points: Vec<DVec3> = crate::sphere(DVec3::ZERO, 1.0, 3000).positions;
        let run = |threads| {
            sphcover_core::on_threads(threads, || {
                score_invented_surface(&mesh, &points, &params(20_000)).unwrap()
            })
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let rec = square(0.0, 1.0, 0.0);
        assert_eq!(
            score_invented_surface(&rec, &[DVec3::ZERO], &params(10)).unwrap_err(),
            InventedSurfaceError::TooFewPoints { points: 1 }
        );
        assert_eq!(
            score_invented_surface(&rec, &[DVec3::ZERO, DVec3::NAN], &params(10)).unwrap_err(),
            InventedSurfaceError::TooFewPoints { points: 1 }
        );
        let points = grid(5, 0.0);
        assert!(matches!(
            score_invented_surface(&TriMesh::default(), &points, &params(10)),
            Err(InventedSurfaceError::EmptyReconstruction { triangles: 0 })
        ));
        assert!(score_invented_surface(&rec, &points, &params(0)).is_err());
        let negative = InventedSurfaceParams {
            spacings: -1.0,
            ..params(10)
        };
        assert!(score_invented_surface(&rec, &points, &negative).is_err());
    }
}
