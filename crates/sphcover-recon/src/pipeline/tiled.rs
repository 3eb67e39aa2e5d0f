//! The tiled reconstruction: the cover and its function built tile by tile, each from the
//! samples of its box and a halo around it, and one surface polygonised from the tiles'
//! functions, each used inside its own box.
//!
//! The method is described on [`reconstruct_tiled()`](super::reconstruct_tiled).

use rayon::prelude::*;
use sphcover_core::{
    Aabb, Cover, CoverError, DVec3, LocalFunction, LocalFunctions, PointIndex, PuEvaluator,
    QuadraticFunction, Stage, TriMesh,
};
use std::time::{Duration, Instant};

use super::stages::{
    ReconContext, ReconStage, build_cover, built, function_stages, polygonisation_params,
    polygonisation_seeds,
};
use super::{ReconError, ReconParams, default_depth};
use crate::confidence::{ConfidenceStats, SampleConfidence};
use crate::polygonise::{
    FieldPiece, PiecewiseFunction, PolygoniseParams, PolygoniseStats, polygonise_piecewise,
    polygonise_untrimmed,
};
use crate::scan_statistics::ScanStatistics;

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
    /// `tiles` with the default halo ([`Tiling::default_halo`]).
    pub fn new(tiles: [usize; 3]) -> Tiling {
        Tiling {
            tiles,
            halo: Tiling::default_halo(tiles),
        }
    }

    /// `n × n × n` tiles with the default halo.
    pub fn cubes(n: usize) -> Tiling {
        Tiling::new([n; 3])
    }

    /// The default halo: a fifth of the width of a tile along the longest edge, at most 0.1
    /// (2 tiles: 0.1; 4: 0.05). On the 2M-point bunny in 2×2×2 tiles (clean, and with noise,
    /// outliers and holes) the Hausdorff-99 distance differs from the single run's by
    /// 2.7–2.8% with a halo of 0.05 and by at most 1.2% with 0.1, and 0.2 costs a third more
    /// time for nothing; a halo of a fifth of the tile keeps the samples the tiles read to
    /// 1.4³ ≈ 2.7 times the tile's own at most, whatever the count (2.45 times on the 50M bunny
    /// in 4×4×4 tiles, whose Chamfer and Hausdorff-99 distances came out 5% and 8% below the
    /// single run's).
    pub fn default_halo(tiles: [usize; 3]) -> f64 {
        let most = tiles.iter().copied().max().unwrap_or(1).max(1);
        (0.2 / most as f64).min(0.1)
    }

    /// The number of tiles.
    pub fn count(&self) -> usize {
        self.tiles.iter().product()
    }

    /// Refuses a tiling without tiles along an axis, with more than 4096 tiles, or with a
    /// halo outside [0, 1].
    pub fn check(&self) -> Result<(), ReconError> {
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
    /// Its share of the tiles stage's wall time, in proportion to its samples (a runner may
    /// run the tiles at once, so their own times do not add up to the stage's).
    pub time: Duration,
}

/// The tiles' functions, between the stage that builds them and the polygonisation.
pub(super) struct TiledFunctions {
    /// Split planes along x, y and z, in the unit frame.
    splits: [Vec<f64>; 3],
    /// Each tile's cover (empty where the tile has too few samples) and its support
    /// confidence.
    pieces: Vec<(Cover, Vec<f64>)>,
}

/// The split planes cutting `bbox` into `tiles` equal boxes along each axis.
pub(super) fn split_planes(bbox: &Aabb, tiles: [usize; 3]) -> [Vec<f64>; 3] {
    std::array::from_fn(|a| {
        let (lo, hi) = (bbox.min[a], bbox.max[a]);
        (1..tiles[a])
            .map(|k| lo + (hi - lo) * k as f64 / tiles[a] as f64)
            .collect()
    })
}

/// The box of tile `t` (the outermost reaching to infinity) grown by `halo`.
pub(super) fn tile_box(splits: &[Vec<f64>; 3], t: [usize; 3], halo: f64) -> Aabb {
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

/// The samples of each tile's box grown by the halo, in compressed rows: tile `t`'s are
/// `slots[start[t]..start[t + 1]]`, ascending.
struct TileMembers {
    start: Vec<usize>,
    slots: Vec<u32>,
}

/// [`TileMembers`] in one pass over the samples ([`tiles_holding`]), instead of one pass per
/// tile.
fn tile_members(
    points: &[DVec3],
    splits: &[Vec<f64>; 3],
    tiles: [usize; 3],
    halo: f64,
) -> TileMembers {
    let mut rows: Vec<Vec<u32>> = vec![Vec::new(); tiles.iter().product()];
    for (slot, &p) in points.iter().enumerate() {
        tiles_holding(splits, halo, p, |t| rows[t].push(slot as u32));
    }
    let mut start = Vec::with_capacity(rows.len() + 1);
    start.push(0);
    for row in &rows {
        start.push(start.last().copied().unwrap_or(0) + row.len());
    }
    TileMembers {
        start,
        slots: rows.concat(),
    }
}

/// Calls `visit` with every tile (as `ix + nx (iy + ny iz)`, ascending) whose box grown by
/// `halo` holds `p`: a few along each axis (two at most while the halo is less than a tile
/// wide), found by binary search on the split planes. The boxes are closed, as in
/// [`Aabb::contains`].
pub(super) fn tiles_holding(
    splits: &[Vec<f64>; 3],
    halo: f64,
    p: DVec3,
    mut visit: impl FnMut(usize),
) {
    // The tiles along axis `a` whose grown interval holds `x`: tile k reaches from
    // splits[k − 1] − halo to splits[k] + halo (the outermost to infinity).
    let along = |a: usize| -> std::ops::RangeInclusive<usize> {
        let s = &splits[a];
        let first = s.partition_point(|&plane| plane + halo < p[a]);
        let last = s.partition_point(|&plane| plane - halo <= p[a]);
        first..=last
    };
    let (nx, ny) = (splits[0].len() + 1, splits[1].len() + 1);
    for iz in along(2) {
        for iy in along(1) {
            for ix in along(0) {
                visit(ix + nx * (iy + ny * iz));
            }
        }
    }
}

/// The tile (as `ix + nx (iy + ny iz)`) whose box holds `p`; a point on a plane belongs to
/// the box above it, as in [`PiecewiseFunction`].
pub(super) fn tile_of(splits: &[Vec<f64>; 3], p: DVec3) -> usize {
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

/// What one tile's function is built from: the samples of its box and halo, in the unit frame
/// of the whole scan, and what was measured on the whole scan. Plain arrays, so that a task
/// on another machine can be handed one ([`TileRunner`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TileInput {
    /// The tile's position along x, y and z.
    pub position: [usize; 3],
    /// The tile's own box (unbounded on the outer sides); the function answers inside it.
    pub own_box: Aabb,
    /// The samples of the box and the halo, in the unit frame.
    pub points: Vec<DVec3>,
    /// Their outward normals, given or estimated on the whole scan.
    pub normals: Vec<DVec3>,
    /// Their scanner confidence, when the input has one.
    pub scanner: Option<Vec<f64>>,
    /// Which of them are isolated (left out of the cover, outliers).
    pub isolated: Vec<bool>,
    /// Which of them lie in the tile's own box: the tile gives those their confidence.
    pub own: Vec<bool>,
    /// The whole scan's sample spacing (unit frame).
    pub spacing: f64,
    /// The whole scan's noise σ (unit frame).
    pub noise: f64,
    /// The cover tolerance of the whole scan.
    pub eps: f64,
    /// Whether isolated samples are left out of the cover.
    pub drop_isolated: bool,
    /// Whether the whole scan is one view (its diffusion keeps layers apart).
    pub one_view: bool,
    /// The polygonisation depth of the whole scan.
    pub depth: u32,
}

/// One tile's product ([`tile_function`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TileFunction {
    /// The tile's cover after diffusion, keeping the supports that reach into its box.
    pub cover: Cover,
    /// The confidence of each of those supports, blended at the vertices.
    pub support_confidence: Vec<f64>,
    /// The confidence of each sample of the tile's own box, in the order of
    /// [`TileInput::points`].
    pub confidence: Vec<f64>,
    /// The outlier label of each sample of the tile's own box, in the same order.
    pub outliers: Vec<bool>,
    /// Supports the graph cut found inconsistent.
    pub inconsistent_supports: usize,
    /// Inconsistent supports kept because their samples fit them.
    pub confirmed_supports: usize,
}

/// Runs the tiles' [`tile_function`]s: one after the other in this process
/// ([`SequentialTiles`]), or as tasks of a distributed engine. A runner must return, in tile
/// order, exactly what [`tile_function`] returns for each input, so that the surface is the
/// same whichever ran it.
pub trait TileRunner: Sync {
    /// The function of each of `count` tiles; `input(t)` builds tile `t`'s input.
    fn run(
        &self,
        count: usize,
        input: &(dyn Fn(usize) -> TileInput + Sync),
        params: &ReconParams,
    ) -> Result<Vec<Option<TileFunction>>, ReconError>;
}

/// Runs the tiles one after the other in this process, each with every thread, building
/// each tile's input only when its turn comes.
#[derive(Clone, Copy, Debug, Default)]
pub struct SequentialTiles;

impl TileRunner for SequentialTiles {
    fn run(
        &self,
        count: usize,
        input: &(dyn Fn(usize) -> TileInput + Sync),
        params: &ReconParams,
    ) -> Result<Vec<Option<TileFunction>>, ReconError> {
        (0..count)
            .map(|t| tile_function(&input(t), params))
            .collect()
    }
}

/// Every tile's cover and function by the context's runner, and the samples' confidence from
/// the tile whose box holds them.
fn build_tiles(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let tiling = built(ctx.tiling, "tiling");
    let runner = built(ctx.runner, "tile runner");
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
    let [nx, ny, _] = tiling.tiles;
    let position = |t: usize| [t % nx, (t / nx) % ny, t / (nx * ny)];
    let members = tile_members(&ctx.points, &splits, tiling.tiles, tiling.halo);
    let slots_of = |t: usize| -> &[u32] { &members.slots[members.start[t]..members.start[t + 1]] };
    let input = |t: usize| -> TileInput {
        let slots = slots_of(t);
        let pick = |v: &[DVec3]| -> Vec<DVec3> { slots.iter().map(|&s| v[s as usize]).collect() };
        TileInput {
            position: position(t),
            own_box: tile_box(&splits, position(t), 0.0),
            points: pick(&ctx.points),
            normals: pick(&ctx.normals),
            scanner: ctx
                .scanner
                .as_ref()
                .map(|c| slots.iter().map(|&s| c[s as usize]).collect()),
            isolated: slots
                .iter()
                .map(|&s| ctx.scan.isolated[s as usize])
                .collect(),
            own: slots
                .iter()
                .map(|&s| owner[s as usize] as usize == t)
                .collect(),
            spacing: ctx.scan.spacing,
            noise: ctx.scan.noise,
            eps: ctx.stats.eps,
            drop_isolated: ctx.drop_isolated,
            one_view: ctx.scan.one_view,
            depth,
        }
    };
    let start = Instant::now();
    let tile_params = ReconParams {
        depth: Some(depth),
        ..ctx.params.clone()
    };
    let functions = runner.run(tiling.count(), &input, &tile_params)?;
    let elapsed = start.elapsed();
    if functions.len() != tiling.count() {
        return Err(ReconError::TileRunner(format!(
            "{} tile functions returned for {} tiles",
            functions.len(),
            tiling.count()
        )));
    }

    let samples = ctx.points.len();
    let mut confidence = vec![0.0; samples];
    let mut outliers = vec![true; samples];
    let mut pieces = Vec::with_capacity(functions.len());
    let mut tile_stats = Vec::with_capacity(functions.len());
    for (t, function) in functions.into_iter().enumerate() {
        let slots = slots_of(t);
        let own: Vec<usize> = slots
            .iter()
            .map(|&s| s as usize)
            .filter(|&s| owner[s] as usize == t)
            .collect();
        let mut stats = TileStats {
            position: position(t),
            own_samples: own.len(),
            samples: slots.len(),
            ..TileStats::default()
        };
        match function {
            Some(f) => {
                if f.confidence.len() != own.len()
                    || f.outliers.len() != own.len()
                    || f.support_confidence.len() != f.cover.len()
                {
                    return Err(ReconError::TileRunner(format!(
                        "tile {:?}: {} confidences and {} outlier labels for {} samples, {} support confidences for {} supports",
                        stats.position,
                        f.confidence.len(),
                        f.outliers.len(),
                        own.len(),
                        f.support_confidence.len(),
                        f.cover.len()
                    )));
                }
                for (k, &s) in own.iter().enumerate() {
                    confidence[s] = f.confidence[k];
                    outliers[s] = f.outliers[k];
                }
                ctx.stats.inconsistent_supports += f.inconsistent_supports;
                ctx.stats.confirmed_supports += f.confirmed_supports;
                stats.supports = f.cover.len();
                pieces.push((f.cover, f.support_confidence));
            }
            None => pieces.push((empty_cover(ctx.params)?, Vec::new())),
        }
        tile_stats.push(stats);
    }
    // The runner may run the tiles at once: the stage's time is shared out by samples.
    let total: usize = tile_stats.iter().map(|s| s.samples).sum::<usize>().max(1);
    for s in &mut tile_stats {
        s.time = elapsed.mul_f64(s.samples as f64 / total as f64);
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

/// One tile's function: the cover, graph cut, confidence and diffusion of
/// [`ReconParams::method`] on the tile's samples, keeping the supports that reach into its
/// box; `None` when too few samples are left for a cover (a tile holding a few far outliers
/// alone measures no surface). Depends on nothing but its arguments, so any worker gives
/// the same result.
pub fn tile_function(
    input: &TileInput,
    params: &ReconParams,
) -> Result<Option<TileFunction>, ReconError> {
    let (product, _) = tile_function_and_samples(input.clone(), None, params)?;
    Ok(product.map(|(function, _)| function))
}

/// [`tile_function`] of an input it may take apart (its samples are the tile's context's
/// while the stages run, not a copy of them) and gives back, and the confidence and outlier
/// label the tile gave every one of its samples, the halo's included. `index`, when given,
/// indexes `input.points` already.
pub(super) fn tile_function_and_samples(
    mut input: TileInput,
    index: Option<PointIndex>,
    params: &ReconParams,
) -> Result<(Option<(TileFunction, SampleLabels)>, TileInput), ReconError> {
    let n = input.points.len();
    let lengths = [
        input.normals.len(),
        input.isolated.len(),
        input.own.len(),
        input.scanner.as_ref().map_or(n, Vec::len),
    ];
    if lengths.iter().any(|&l| l != n) {
        return Err(ReconError::TileRunner(format!(
            "tile {:?}: {n} points with {lengths:?} normals, isolated flags, own flags and scanner confidences",
            input.position
        )));
    }
    let in_cover = (0..n)
        .filter(|&s| !(input.drop_isolated && input.isolated[s]))
        .count();
    if in_cover < super::stages::MIN_POINTS.max(params.scan.k + 1) {
        return Ok((None, input));
    }
    // A tile's cover is a part of the whole, and the budget's check is for the whole.
    let params = ReconParams {
        depth: Some(input.depth),
        memory_budget: None,
        ..params.clone()
    };
    let nothing = sphcover_core::PointCloud::default();
    let mut tile = ReconContext::new(&nothing, &params);
    tile.points = std::mem::take(&mut input.points);
    tile.normals = std::mem::take(&mut input.normals);
    tile.scanner = input.scanner.take();
    tile.index = Some(match index {
        Some(index) => index,
        None => PointIndex::new(&tile.points)?,
    });
    let isolated_count = input.isolated.iter().filter(|&&i| i).count();
    tile.scan = ScanStatistics {
        spacing: input.spacing,
        noise: input.noise,
        isolated: std::mem::take(&mut input.isolated),
        isolated_count,
        one_view: input.one_view,
    };
    tile.drop_isolated = input.drop_isolated && tile.scan.isolated_count > 0;
    tile.stats.eps = input.eps;
    let function =
        function_stages(params.method).ok_or(ReconError::NotTileable(params.method.name()))?;
    build_cover(&mut tile)?;
    for stage in &function {
        (stage.run)(&mut tile)?;
    }
    let cover = built(tile.cover.take(), "cover");
    let conf = built(tile.confidence.take(), "sample confidence");
    let (cover, kept) = supports_reaching(cover, &input.own_box)?;
    let own = |s: &usize| input.own[*s];
    let function = TileFunction {
        support_confidence: kept
            .iter()
            .map(|&i| conf.support_confidence[i as usize])
            .collect(),
        confidence: (0..n).filter(own).map(|s| conf.confidence[s]).collect(),
        outliers: (0..n).filter(own).map(|s| conf.outliers[s]).collect(),
        cover,
        inconsistent_supports: tile.stats.inconsistent_supports,
        confirmed_supports: tile.stats.confirmed_supports,
    };
    let labels = SampleLabels {
        confidence: conf.confidence,
        outliers: conf.outliers,
    };
    input.points = std::mem::take(&mut tile.points);
    input.normals = std::mem::take(&mut tile.normals);
    input.scanner = tile.scanner.take();
    input.isolated = std::mem::take(&mut tile.scan.isolated);
    Ok((Some((function, labels)), input))
}

/// The confidence and outlier label of each sample of a tile, in its order.
pub(super) struct SampleLabels {
    pub confidence: Vec<f64>,
    pub outliers: Vec<bool>,
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
    let centres = kept.iter().map(|&i| cover.centres()[i as usize]).collect();
    let funcs = gather_functions(
        kept.iter()
            .filter_map(|&i| cover.func(i as usize))
            .collect(),
    );
    let radii = kept.iter().map(|&i| cover.radii()[i as usize]).collect();
    let pruned = Cover::new(centres, radii, funcs, cover.kernel())?;
    Ok((pruned, kept))
}

/// A cover without supports, for a tile with too few samples.
pub(super) fn empty_cover(params: &ReconParams) -> Result<Cover, ReconError> {
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
    let (mesh, stats) = polygonise_pieces(&tiled.pieces, &tiled.splits, &seeds, &poly, true)?;
    ctx.stats.unseen_area_fraction = stats.unseen_area_fraction;
    ctx.stats.polygonise = Some(stats);
    ctx.mesh = mesh;
    ctx.cover = Some(join_covers(
        tiled.pieces.into_iter().map(|(c, _)| c).collect(),
    )?);
    Ok(())
}

/// Surface nets of the function whose piece inside each tile's box (cut by `splits`) is that
/// tile's cover in `pieces`, blending its support confidence; trimmed as `poly` asks when
/// `trimmed`, else as extracted ([`crate::polygonise::trim_and_resolve`] does the rest).
pub(super) fn polygonise_pieces(
    pieces: &[(Cover, Vec<f64>)],
    splits: &[Vec<f64>; 3],
    seeds: &[DVec3],
    poly: &PolygoniseParams,
    trimmed: bool,
) -> Result<(TriMesh, PolygoniseStats), ReconError> {
    let evals = pieces
        .iter()
        .map(|(cover, _)| PuEvaluator::new(cover, 1.0))
        .collect::<Result<Vec<_>, CoverError>>()?;
    let field_pieces = evals
        .iter()
        .zip(pieces)
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
    let field = PiecewiseFunction::new(field_pieces, splits.clone())?;
    Ok(if trimmed {
        polygonise_piecewise(&field, seeds, poly)?
    } else {
        polygonise_untrimmed(&field, seeds, poly)?
    })
}

/// `funcs` in one storage: linear when every one is, else quadratic.
fn gather_functions(funcs: Vec<LocalFunction>) -> LocalFunctions {
    if funcs.iter().all(|f| matches!(f, LocalFunction::Linear(_))) {
        LocalFunctions::from_linear(funcs.into_iter().filter_map(|f| match f {
            LocalFunction::Linear(g) => Some(g),
            LocalFunction::Quadratic(_) => None,
        }))
    } else {
        LocalFunctions::from_quadratic(funcs.into_iter().map(|f| match f {
            LocalFunction::Linear(g) => QuadraticFunction::from_linear(g),
            LocalFunction::Quadratic(q) => q,
        }))
    }
}

/// The supports of every cover, in order, as one cover (the kernel of the first).
fn join_covers(covers: Vec<Cover>) -> Result<Cover, ReconError> {
    let kernel = covers.first().map(Cover::kernel).unwrap_or_default();
    let funcs = gather_functions(
        covers
            .iter()
            .flat_map(|c| (0..c.len()).filter_map(|i| c.func(i)))
            .collect(),
    );
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

    /// Tiles run in reverse order, each through bytes as another process would get and
    /// return them.
    struct ThroughBytes;

    impl TileRunner for ThroughBytes {
        fn run(
            &self,
            count: usize,
            input: &(dyn Fn(usize) -> TileInput + Sync),
            params: &ReconParams,
        ) -> Result<Vec<Option<TileFunction>>, ReconError> {
            let mut out: Vec<Option<TileFunction>> = vec![None; count];
            for t in (0..count).rev() {
                let sent = TileInput::from_bytes(&input(t).to_bytes())?;
                out[t] = tile_function(&sent, params)?
                    .map(|f| TileFunction::from_bytes(&f.to_bytes()))
                    .transpose()?;
            }
            Ok(out)
        }
    }

    #[test]
    fn any_runner_gives_the_sequential_runs_surface() {
        let cloud = torus(0.3, 0.12, 5000);
        let params = ReconParams::default();
        let tiling = Tiling {
            tiles: [2, 1, 3],
            halo: 0.1,
        };
        let stop = sphcover_core::StopRequest::new();
        let here = reconstruct_tiled(&cloud, &params, &tiling, &|_| {}).unwrap();
        let there = super::super::reconstruct_tiled_with(
            &cloud,
            &params,
            &tiling,
            &ThroughBytes,
            &|_| {},
            &stop,
        )
        .unwrap();
        assert_eq!(here.mesh, there.mesh);
        assert_eq!(here.confidence, there.confidence);
        assert_eq!(here.cover, there.cover);
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
    fn a_flat_scan_tiles_across_its_missing_extent() {
        // No extent along z: the planes along z coincide and the boxes between them are
        // empty.
        let n = 60;
        let positions: Vec<DVec3> = (0..n * n)
            .map(|i| DVec3::new((i % n) as f64 / n as f64, (i / n) as f64 / n as f64, 0.0))
            .collect();
        let mut cloud = PointCloud::from_positions(positions);
        cloud.normals = Some(vec![DVec3::Z; n * n]);
        let tiling = Tiling::new([2, 2, 3]);
        let result = reconstruct_tiled(&cloud, &ReconParams::default(), &tiling, &|_| {}).unwrap();
        assert!(result.stats.triangles > 0);
        assert!(result.mesh.vertices.iter().all(|v| v.z.abs() < 1e-6));
        assert!(MeshTopology::of(&result.mesh).is_manifold());
    }

    #[test]
    fn the_default_halo_is_a_fifth_of_a_tile_at_most_a_tenth() {
        let halos = [[1, 1, 1], [2, 2, 2], [4, 1, 1], [3, 8, 2]].map(Tiling::default_halo);
        assert_eq!(halos, [0.1, 0.1, 0.05, 0.025]);
        assert_eq!(Tiling::cubes(4), Tiling::new([4; 3]));
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
        /// The members found by binary search on the planes are those of a test of every
        /// point against every grown box.
        #[test]
        fn tile_members_are_the_points_in_each_grown_box(
            tiles in prop::array::uniform3(1usize..4),
            halo in 0.0f64..0.6,
            points in prop::collection::vec(prop::array::uniform3(-0.7f64..0.7), 0..60),
        ) {
            let bbox = Aabb { min: DVec3::splat(-0.5), max: DVec3::new(0.5, 0.3, 0.2) };
            let splits = split_planes(&bbox, tiles);
            // Points on the planes and at a halo from them, where the bounds are decided.
            let mut points: Vec<DVec3> = points.into_iter().map(DVec3::from_array).collect();
            if let (Some(&plane), Some(&p)) = (splits[0].first(), points.first()) {
                points.push(DVec3::new(plane, p.y, p.z));
                points.push(DVec3::new(plane + halo, p.y, p.z));
                points.push(DVec3::new(plane - halo, p.y, p.z));
            }
            let members = tile_members(&points, &splits, tiles, halo);
            for t in 0..tiles.iter().product() {
                let position = [t % tiles[0], (t / tiles[0]) % tiles[1], t / (tiles[0] * tiles[1])];
                let grown = tile_box(&splits, position, halo);
                let brute: Vec<u32> = (0..points.len() as u32)
                    .filter(|&s| grown.contains(points[s as usize]))
                    .collect();
                prop_assert_eq!(&members.slots[members.start[t]..members.start[t + 1]], &brute[..]);
            }
        }

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
