//! The tiled reconstruction: the cover and its function built tile by tile, each from the
//! samples of its box and a halo around it, and one surface polygonised from the tiles'
//! functions, each used inside its own box.
//!
//! The method is described on [`reconstruct_tiled()`](super::reconstruct_tiled).

use rayon::prelude::*;
use sphcover_core::{
    Aabb, Cover, CoverError, DVec3, LocalFunction, LocalFunctions, PointIndex, PuEvaluator,
    QuadraticFunction, Stage,
};
use std::time::{Duration, Instant};

use super::stages::{
    ReconContext, ReconStage, build_cover, built, function_stages, polygonisation_params,
    polygonisation_seeds,
};
use super::{ReconError, ReconParams, ReconStats, default_depth};
use crate::confidence::{ConfidenceStats, SampleConfidence};
use crate::polygonise::{FieldPiece, PiecewiseFunction, polygonise_piecewise};

/// How a reconstruction is split into tiles (see
/// [`reconstruct_tiled`](super::reconstruct_tiled)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tiling {
    /// Tiles along x, y and z: the samples' bounding box is cut into equal boxes.
    pub tiles: [usize; 3],
    /// How far beyond its box a tile takes samples, relative to the longest edge of the
    /// samples' bounding box. The supports near a tile's faces then see the samples a single
    /// run gives them, and its function there matches its neighbour's.
    pub halo: f64,
}

impl Tiling {
    /// The halo [`Tiling::cubes`] gives: 0.1 of the longest edge. On the 2M-point bunny in
    /// 2×2×2 tiles (clean, and with noise, outliers and holes) the Hausdorff-99 distance
    /// differs from the single run's by 2.7–2.8% with a halo of 0.05, and by at most 1.2%
    /// with 0.1; 0.2 costs a third more time and gains nothing.
    pub const DEFAULT_HALO: f64 = 0.1;

    /// `n × n × n` tiles with the default halo.
    pub fn cubes(n: usize) -> Tiling {
        Tiling {
            tiles: [n; 3],
            halo: Tiling::DEFAULT_HALO,
        }
    }

    /// The number of tiles.
    pub fn count(&self) -> usize {
        self.tiles.iter().product()
    }

    pub(super) fn check(&self) -> Result<(), ReconError> {
        let count = self.tiles.iter().try_fold(1usize, |n, &t| n.checked_mul(t));
        if self.tiles.contains(&0) || count.is_none_or(|n| n > MAX_TILES) {
            return Err(ReconError::InvalidParameter(
                sphcover_core::ParameterError {
                    name: "tiles",
                    value: count.unwrap_or(usize::MAX) as f64,
                    expected: "1..=4096 tiles in all, at least one along each axis",
                },
            ));
        }
        if !(self.halo.is_finite() && self.halo >= 0.0 && self.halo <= 1.0) {
            return Err(ReconError::InvalidParameter(
                sphcover_core::ParameterError {
                    name: "halo",
                    value: self.halo,
                    expected: "[0, 1]",
                },
            ));
        }
        Ok(())
    }
}

/// Most tiles in one run.
const MAX_TILES: usize = 4096;

/// What one tile did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TileStats {
    /// The tile's position along x, y and z.
    pub position: [usize; 3],
    /// Samples in the tile's box.
    pub own_samples: usize,
    /// Samples in the box and its halo: those its cover is built from.
    pub samples: usize,
    /// Supports of its cover.
    pub supports: usize,
    /// Wall time of its stages.
    pub time: Duration,
}

/// The tiles' functions, between the stage that builds them and the polygonisation.
#[derive(Debug, Default)]
pub(super) struct TiledFunctions {
    /// Split planes along x, y and z, in the unit frame.
    splits: [Vec<f64>; 3],
    /// Each tile's cover (empty where the tile has too few samples) and its support
    /// confidence.
    pieces: Vec<(Cover, Vec<f64>)>,
}

/// The split planes cutting `bbox` into `tiles` equal boxes along each axis.
fn split_planes(bbox: &Aabb, tiles: [usize; 3]) -> [Vec<f64>; 3] {
    std::array::from_fn(|a| {
        let (lo, hi) = (bbox.min[a], bbox.max[a]);
        (1..tiles[a])
            .map(|k| lo + (hi - lo) * k as f64 / tiles[a] as f64)
            .collect()
    })
}

/// The box of tile `t` (the outermost reaching to infinity) grown by `halo`.
fn tile_box(splits: &[Vec<f64>; 3], t: [usize; 3], halo: f64) -> Aabb {
    let edge = |a: usize, k: usize, low: bool| -> f64 {
        let s = &splits[a];
        match (low, k) {
            (true, 0) => f64::NEG_INFINITY,
            (true, k) => s[k - 1] - halo,
            (false, k) if k == s.len() => f64::INFINITY,
            (false, k) => s[k] + halo,
        }
    };
    Aabb {
        min: DVec3::from_array(std::array::from_fn(|a| edge(a, t[a], true))),
        max: DVec3::from_array(std::array::from_fn(|a| edge(a, t[a], false))),
    }
}

/// The tile (as `ix + nx (iy + ny iz)`) whose box holds `p`; a point on a plane belongs to
/// the box above it, as in [`PiecewiseFunction`].
fn tile_of(splits: &[Vec<f64>; 3], p: DVec3) -> usize {
    let along = |a: usize| splits[a].partition_point(|&plane| plane <= p[a]);
    along(0) + (splits[0].len() + 1) * (along(1) + (splits[1].len() + 1) * along(2))
}

/// The stages of a tiled reconstruction between the scan statistics and the cleaning.
pub(super) fn tiled_stages<'a>() -> [ReconStage<'a>; 2] {
    [
        Stage::new("tiles", build_tiles),
        Stage::new("polygonise", polygonise_tiles),
    ]
}

/// Every tile's cover and function, one tile after the other (each with every thread), and
/// the samples' confidence from the tile whose box holds them.
fn build_tiles(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let tiling = built(ctx.tiling, "tiling");
    // The tiles split the box of the samples the cover takes, not the outliers' extent.
    let inliers: Vec<DVec3> = ctx
        .points
        .iter()
        .enumerate()
        .filter(|&(s, _)| !(ctx.drop_isolated && ctx.scan.isolated[s]))
        .map(|(_, &p)| p)
        .collect();
    let splits = split_planes(&Aabb::from_points(&inliers), tiling.tiles);
    drop(inliers);
    let owner: Vec<u32> = ctx
        .points
        .par_iter()
        .map(|&p| tile_of(&splits, p) as u32)
        .collect();
    // Every tile polygonises at the depth of the whole scan.
    let depth = ctx
        .params
        .depth
        .unwrap_or_else(|| default_depth(ctx.points.len()));
    let tile_params = ReconParams {
        depth: Some(depth),
        ..ctx.params.clone()
    };
    let samples = ctx.points.len();
    let mut confidence = vec![0.0; samples];
    let mut outliers = vec![true; samples];
    let mut pieces = Vec::with_capacity(tiling.count());
    let mut tile_stats = Vec::with_capacity(tiling.count());
    let [nx, ny, nz] = tiling.tiles;
    for iz in 0..nz {
        for iy in 0..ny {
            for ix in 0..nx {
                let start = Instant::now();
                let t = ix + nx * (iy + ny * iz);
                let grown = tile_box(&splits, [ix, iy, iz], tiling.halo);
                let slots: Vec<usize> = (0..samples)
                    .into_par_iter()
                    .filter(|&s| grown.contains(ctx.points[s]))
                    .collect();
                let mut stats = TileStats {
                    position: [ix, iy, iz],
                    own_samples: owner.iter().filter(|&&o| o as usize == t).count(),
                    samples: slots.len(),
                    ..TileStats::default()
                };
                let piece = tile_function(ctx, &tile_params, &slots)?;
                if let Some((cover, mut conf, counts)) = piece {
                    let own_box = tile_box(&splits, [ix, iy, iz], 0.0);
                    let (cover, kept) = supports_reaching(cover, &own_box)?;
                    conf.support_confidence = kept
                        .iter()
                        .map(|&i| conf.support_confidence[i as usize])
                        .collect();
                    ctx.stats.inconsistent_supports += counts.inconsistent_supports;
                    ctx.stats.confirmed_supports += counts.confirmed_supports;
                    for (k, &s) in slots.iter().enumerate() {
                        if owner[s] as usize == t {
                            confidence[s] = conf.confidence[k];
                            outliers[s] = conf.outliers[k];
                        }
                    }
                    stats.supports = cover.len();
                    pieces.push((cover, conf.support_confidence));
                } else {
                    pieces.push((empty_cover(ctx.params)?, Vec::new()));
                }
                stats.time = start.elapsed();
                tile_stats.push(stats);
            }
        }
    }
    ctx.stats.depth = depth;
    ctx.stats.supports = pieces.iter().map(|(c, _)| c.len()).sum();
    ctx.stats.tiles = tile_stats;
    let outlier_count = outliers.iter().filter(|&&o| o).count();
    ctx.confidence = Some(SampleConfidence {
        support_confidence: pieces.iter().flat_map(|(_, s)| s.iter().copied()).collect(),
        confidence,
        outliers,
        stats: ConfidenceStats {
            supports: ctx.stats.supports,
            samples,
            outliers: outlier_count,
            scanner_given: ctx.scanner.is_some(),
            ..ConfidenceStats::default()
        },
    });
    ctx.tiled = Some(TiledFunctions { splits, pieces });
    Ok(())
}

/// The cover and sample confidence of one tile, from the samples at `slots`, by the
/// method's stages; `None` when too few of them are left for a cover.
fn tile_function(
    ctx: &ReconContext<'_>,
    params: &ReconParams,
    slots: &[usize],
) -> Result<Option<(Cover, SampleConfidence, ReconStats)>, ReconError> {
    let in_cover = slots
        .iter()
        .filter(|&&s| !(ctx.drop_isolated && ctx.scan.isolated[s]))
        .count();
    // A tile holding a few stray samples alone (far outliers) measures no surface.
    if in_cover < super::stages::MIN_POINTS.max(params.scan.k + 1) {
        return Ok(None);
    }
    let pick = |v: &[DVec3]| -> Vec<DVec3> { slots.iter().map(|&s| v[s]).collect() };
    let mut tile = ReconContext::new(ctx.cloud, params);
    tile.points = pick(&ctx.points);
    tile.normals = pick(&ctx.normals);
    tile.scanner = ctx
        .scanner
        .as_ref()
        .map(|c| slots.iter().map(|&s| c[s]).collect());
    tile.index = Some(PointIndex::new(&tile.points)?);
    tile.scan = ctx.scan.clone();
    tile.scan.isolated = slots.iter().map(|&s| ctx.scan.isolated[s]).collect();
    tile.scan.isolated_count = tile.scan.isolated.iter().filter(|&&i| i).count();
    tile.drop_isolated = ctx.drop_isolated && tile.scan.isolated_count > 0;
    tile.stats.eps = ctx.stats.eps;
    tile.stats.noise_floor = ctx.stats.noise_floor;
    let function =
        function_stages(params.method).ok_or(ReconError::NotTileable(params.method.name()))?;
    build_cover(&mut tile)?;
    for stage in &function {
        (stage.run)(&mut tile)?;
    }
    let cover = built(tile.cover.take(), "cover");
    let confidence = built(tile.confidence.take(), "sample confidence");
    Ok(Some((cover, confidence, tile.stats)))
}

/// The supports of `cover` whose ball reaches into `own` (the only ones the tile's function
/// answers with), as a cover, and their indices in `cover`. The halo's other supports
/// served the cut and the diffusion and are not needed any more.
fn supports_reaching(cover: Cover, own: &Aabb) -> Result<(Cover, Vec<u32>), ReconError> {
    let kept: Vec<u32> = (0..cover.len() as u32)
        .filter(|&i| {
            let c = cover.centres()[i as usize];
            let nearest = c.clamp(own.min, own.max);
            c.distance(nearest) < cover.radii()[i as usize]
        })
        .collect();
    if kept.len() == cover.len() {
        return Ok((cover, kept));
    }
    let pick = |v: &[DVec3]| -> Vec<DVec3> { kept.iter().map(|&i| v[i as usize]).collect() };
    let funcs = match cover.funcs() {
        LocalFunctions::Linear { alpha, beta } => LocalFunctions::Linear {
            alpha: pick(alpha),
            beta: kept.iter().map(|&i| beta[i as usize]).collect(),
        },
        LocalFunctions::Quadratic { a, b, k } => LocalFunctions::Quadratic {
            a: kept.iter().map(|&i| a[i as usize]).collect(),
            b: pick(b),
            k: kept.iter().map(|&i| k[i as usize]).collect(),
        },
    };
    let radii = kept.iter().map(|&i| cover.radii()[i as usize]).collect();
    let pruned = Cover::new(pick(cover.centres()), radii, funcs, cover.kernel())?;
    Ok((pruned, kept))
}

/// A cover without supports, for a tile with too few samples.
fn empty_cover(params: &ReconParams) -> Result<Cover, ReconError> {
    Ok(Cover::new(
        Vec::new(),
        Vec::new(),
        LocalFunctions::Linear {
            alpha: Vec::new(),
            beta: Vec::new(),
        },
        params.cover.kernel,
    )?)
}

/// Surface nets of the tiles' functions, each inside its own box, from the confident
/// samples of every tile; the tiles' covers are joined into the result's cover afterwards.
fn polygonise_tiles(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let tiled = built(ctx.tiled.take(), "tiles' functions");
    let seeds = polygonisation_seeds(ctx)?;
    let poly = polygonisation_params(ctx, &seeds);
    let evals = tiled
        .pieces
        .iter()
        .map(|(cover, _)| PuEvaluator::new(cover, 1.0))
        .collect::<Result<Vec<_>, CoverError>>()?;
    let pieces = evals
        .iter()
        .zip(&tiled.pieces)
        .map(|(eval, (cover, blend))| FieldPiece {
            eval,
            // An empty tile blends nothing; its (empty) cover answers nowhere.
            blend: Some(if cover.is_empty() {
                &[][..]
            } else {
                &blend[..]
            }),
        })
        .collect();
    let field = PiecewiseFunction::new(pieces, tiled.splits.clone())?;
    let (mesh, stats) = polygonise_piecewise(&field, &seeds, &poly)?;
    drop(field);
    drop(evals);
    ctx.stats.unseen_area_fraction = stats.unseen_area_fraction;
    ctx.stats.polygonise = Some(stats);
    ctx.mesh = mesh;
    ctx.cover = Some(join_covers(
        tiled.pieces.into_iter().map(|(c, _)| c).collect(),
    )?);
    Ok(())
}

/// The supports of every cover, in order, as one cover (the kernel of the first).
fn join_covers(covers: Vec<Cover>) -> Result<Cover, ReconError> {
    let kernel = covers.first().map(Cover::kernel).unwrap_or_default();
    let funcs: Vec<LocalFunction> = covers
        .iter()
        .flat_map(|c| (0..c.len()).filter_map(|i| c.func(i)))
        .collect();
    let all_linear = funcs.iter().all(|f| matches!(f, LocalFunction::Linear(_)));
    let funcs = if all_linear {
        LocalFunctions::from_linear(funcs.into_iter().filter_map(|f| match f {
            LocalFunction::Linear(g) => Some(g),
            LocalFunction::Quadratic(_) => None,
        }))
    } else {
        LocalFunctions::from_quadratic(funcs.into_iter().map(|f| match f {
            LocalFunction::Linear(g) => QuadraticFunction::from_linear(g),
            LocalFunction::Quadratic(q) => q,
        }))
    };
    let mut centres = Vec::new();
    let mut radii = Vec::new();
    for c in &covers {
        centres.extend_from_slice(c.centres());
        radii.extend_from_slice(c.radii());
    }
    Ok(Cover::new(centres, radii, funcs, kernel)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{Method, reconstruct, reconstruct_tiled};
    use proptest::prelude::*;
    use sphcover_core::{MeshTopology, PointCloud, TriMesh};
    use sphcover_evaluation::{torus, torus_signed_distance};

    fn worst_distance(mesh: &TriMesh, truth: impl Fn(DVec3) -> f64) -> f64 {
        mesh.vertices
            .iter()
            .map(|&v| truth(v).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn tiles_join_into_one_closed_surface_as_accurate_as_the_single_run() {
        // A torus tilted so that every seam plane cuts it obliquely.
        let tilt = glam::DMat3::from_rotation_x(0.4) * glam::DMat3::from_rotation_y(0.3);
        let mut cloud = torus(0.3, 0.12, 12_000);
        for p in &mut cloud.positions {
            *p = tilt * *p;
        }
        if let Some(normals) = cloud.normals.as_mut() {
            for n in normals {
                *n = tilt * *n;
            }
        }
        let truth = |p: DVec3| torus_signed_distance(0.3, 0.12, tilt.transpose() * p);
        let params = ReconParams::default();
        let single = reconstruct(&cloud, &params, &|_| {}).unwrap();
        let single_error = worst_distance(&single.mesh, truth);
        for tiles in [[2, 2, 2], [3, 1, 2], [1, 4, 1]] {
            let tiling = Tiling { tiles, halo: 0.1 };
            let tiled = reconstruct_tiled(&cloud, &params, &tiling, &|_| {}).unwrap();
            let topology = MeshTopology::of(&tiled.mesh);
            assert!(
                topology.is_closed_oriented_manifold(),
                "{tiles:?}: {topology:?}"
            );
            assert_eq!(
                (topology.components, topology.euler_characteristic()),
                (1, 0),
                "{tiles:?}"
            );
            assert_eq!(tiled.stats.tiles.len(), tiling.count());
            assert_eq!(
                tiled
                    .stats
                    .tiles
                    .iter()
                    .map(|t| t.own_samples)
                    .sum::<usize>(),
                cloud.len()
            );
            let error = worst_distance(&tiled.mesh, truth);
            assert!(
                error < 1.5 * single_error + 1e-3,
                "{tiles:?}: worst vertex {error:.2e} against the single run's {single_error:.2e}"
            );
            let area = |m: &TriMesh| -> f64 {
                m.triangles
                    .iter()
                    .map(|t| sphcover_core::triangle_area(m, t))
                    .sum()
            };
            let ratio = area(&tiled.mesh) / area(&single.mesh);
            assert!((ratio - 1.0).abs() < 0.01, "{tiles:?}: area ratio {ratio}");
            assert_eq!(tiled.cover.len(), tiled.stats.supports);
            assert_eq!(tiled.confidence.len(), cloud.len());
        }
    }

    #[test]
    fn tiled_output_is_the_same_whatever_the_thread_count() {
        let cloud = torus(0.3, 0.12, 5000);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                reconstruct_tiled(&cloud, &ReconParams::default(), &Tiling::cubes(2), &|_| {})
                    .unwrap()
            })
        };
        let (one, three) = (run(1), run(3));
        assert_eq!(one.mesh, three.mesh);
        assert_eq!(one.confidence, three.confidence);
        assert_eq!(one.outliers, three.outliers);
    }

    #[test]
    fn a_tile_holding_only_far_outliers_is_empty_and_its_samples_are_outliers() {
        // Two stray samples far out along +x: the bounding box, and so the tiles, follow the
        // samples the cover takes, and the strays land alone in outermost tiles.
        let mut cloud = torus(0.3, 0.12, 5000);
        let far = [DVec3::new(5.0, 0.1, 0.0), DVec3::new(5.2, -0.1, 0.1)];
        cloud.positions.extend(far);
        if let Some(normals) = cloud.normals.as_mut() {
            normals.extend([DVec3::X; 2]);
        }
        let result =
            reconstruct_tiled(&cloud, &ReconParams::default(), &Tiling::cubes(2), &|_| {}).unwrap();
        let topology = MeshTopology::of(&result.mesh);
        assert!(topology.is_closed_oriented_manifold(), "{topology:?}");
        assert_eq!(topology.components, 1);
        let n = cloud.len();
        assert!(result.outliers[n - 2] && result.outliers[n - 1]);
        assert!(result.mesh.vertices.iter().all(|v| v.x < 1.0));
    }

    #[test]
    fn methods_without_a_function_and_bad_tilings_are_refused() {
        let cloud = torus(0.3, 0.12, 2000);
        let graphcut = ReconParams {
            method: Method::GraphCut,
            ..ReconParams::default()
        };
        assert!(matches!(
            reconstruct_tiled(&cloud, &graphcut, &Tiling::cubes(2), &|_| {}),
            Err(ReconError::NotTileable("graphcut"))
        ));
        for tiling in [
            Tiling {
                tiles: [0, 1, 1],
                halo: 0.1,
            },
            Tiling {
                tiles: [100, 100, 1],
                halo: 0.1,
            },
            Tiling {
                tiles: [2, 2, 2],
                halo: f64::NAN,
            },
            Tiling {
                tiles: [2, 2, 2],
                halo: -0.1,
            },
        ] {
            assert!(matches!(
                reconstruct_tiled(&cloud, &ReconParams::default(), &tiling, &|_| {}),
                Err(ReconError::InvalidParameter(_))
            ));
        }
        let empty = PointCloud::default();
        assert!(matches!(
            reconstruct_tiled(&empty, &ReconParams::default(), &Tiling::cubes(2), &|_| {}),
            Err(ReconError::TooFewPoints { .. })
        ));
    }

    proptest! {
        /// Every point lies in the box of the tile it is assigned to, and in no other tile's
        /// box without halo.
        #[test]
        fn each_point_lies_in_the_box_of_exactly_its_tile(
            tiles in prop::array::uniform3(1usize..5),
            p in prop::array::uniform3(-1.0f64..1.0),
        ) {
            let bbox = Aabb { min: DVec3::splat(-0.5), max: DVec3::new(0.5, 0.3, 0.2) };
            let splits = split_planes(&bbox, tiles);
            let p = DVec3::from_array(p);
            let t = tile_of(&splits, p);
            let mut holders = 0;
            for iz in 0..tiles[2] {
                for iy in 0..tiles[1] {
                    for ix in 0..tiles[0] {
                        let b = tile_box(&splits, [ix, iy, iz], 0.0);
                        let inside = (0..3).all(|a| p[a] >= b.min[a] && p[a] < b.max[a]);
                        if inside {
                            holders += 1;
                            prop_assert_eq!(t, ix + tiles[0] * (iy + tiles[1] * iz));
                        }
                        prop_assert!(tile_box(&splits, [ix, iy, iz], 0.05).min[0] <= b.min[0]);
                    }
                }
            }
            prop_assert_eq!(holders, 1);
        }
    }
}
