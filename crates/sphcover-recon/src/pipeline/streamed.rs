//! The streamed tiled reconstruction: the scan read from its file a block at a time into
//! tile files, and every pass over the samples made one tile at a time, so that the process
//! holds one tile's samples, the tiles' functions and the surface, never the whole scan.
//!
//! The method is described on [`reconstruct_streamed()`](super::reconstruct_streamed).

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use sphcover_core::io::{self, ReadOptions};
use sphcover_core::{
    Aabb, Cover, DVec3, MeshTopology, Normalisation, PointCloud, PointIndex, Stage, StageProgress,
    StopRequest, Stopped, TriMesh, run_stages_until, vertex_normals,
};

use super::spill::{TileDirectory, TileFiles, TileLabels, TileSamples};
use super::stages::{
    MIN_POINTS, built, component_votes, drop_sheets_by_votes, may_hold_sheets, most_voted,
    polygonisation_params_at, record_topology, vertex_components,
};
use super::tiled::{
    SampleLabels, TileFunction, TileInput, TileStats, Tiling, empty_cover, polygonise_pieces,
    split_planes, tile_box, tile_function_and_samples, tile_of, tiles_holding,
};
use super::{
    DEFAULT_NOISE_TOLERANCE, Method, ReconError, ReconParams, ReconStats, Trim, default_depth,
};
use crate::confidence::ConfidenceStats;
use crate::normals::{NormalParams, estimate_normals};
use crate::polygonise::{PolygoniseParams, PolygoniseStats, trim_and_resolve};
use crate::scan_statistics::{
    ScanStatistics, isolated_samples, median, noise_residuals, spacing_values,
};
use crate::vertex_refinement::{
    Outcome, RefinementSamples, RefinementScale, apply_moves, check, refinement_moves,
};

/// A scan that can be read more than once, a block of points at a time, in the same order
/// each time ([`reconstruct_streamed`](super::reconstruct_streamed) reads it twice).
pub trait PointBlocks: Sync {
    /// Hands the scan's points to `visit` in blocks, in order; stops at `visit`'s first
    /// error and returns it.
    fn blocks(
        &self,
        visit: &mut dyn FnMut(PointCloud) -> Result<(), ReconError>,
    ) -> Result<(), ReconError>;

    /// Whether the points carry normals, as the first block says (`true` without points).
    fn has_normals(&self) -> Result<bool, ReconError> {
        const FIRST_BLOCK: &str = "the second block";
        let mut given = true;
        let read = self.blocks(&mut |block| {
            given = block.normals.is_some();
            Err(Stopped {
                before: FIRST_BLOCK,
            }
            .into())
        });
        match read {
            Ok(())
            | Err(ReconError::Stopped(Stopped {
                before: FIRST_BLOCK,
            })) => Ok(given),
            Err(e) => Err(e),
        }
    }
}

/// A scan file read a block at a time ([`io::stream_points`]).
#[derive(Clone, Debug)]
pub struct ScanFile {
    /// The file.
    pub path: PathBuf,
    /// How it is read.
    pub options: ReadOptions,
    /// Points per block.
    pub block: usize,
    /// Leave the file's normals out (they are estimated instead).
    pub ignore_normals: bool,
}

impl ScanFile {
    /// `path`, read with the default options in blocks of 2^18 points.
    pub fn new(path: impl Into<PathBuf>) -> ScanFile {
        ScanFile {
            path: path.into(),
            options: ReadOptions::default(),
            block: 1 << 18,
            ignore_normals: false,
        }
    }
}

impl PointBlocks for ScanFile {
    fn blocks(
        &self,
        visit: &mut dyn FnMut(PointCloud) -> Result<(), ReconError>,
    ) -> Result<(), ReconError> {
        io::stream_points(&self.path, &self.options, self.block, |mut block| {
            if self.ignore_normals {
                block.normals = None;
            }
            visit(block)
        })?;
        Ok(())
    }
}

/// A cloud in memory, in blocks of 2^16 points (for tests and for callers that hold a scan
/// already).
impl PointBlocks for PointCloud {
    fn blocks(
        &self,
        visit: &mut dyn FnMut(PointCloud) -> Result<(), ReconError>,
    ) -> Result<(), ReconError> {
        const BLOCK: usize = 1 << 16;
        for start in (0..self.len()).step_by(BLOCK) {
            let r = start..(start + BLOCK).min(self.len());
            visit(PointCloud {
                positions: self.positions[r.clone()].to_vec(),
                normals: self.normals.as_ref().map(|n| n[r.clone()].to_vec()),
                confidence: self.confidence.as_ref().map(|c| c[r.clone()].to_vec()),
                ..PointCloud::default()
            })?;
        }
        Ok(())
    }
}

/// The product of [`reconstruct_streamed`](super::reconstruct_streamed): the surface and
/// what was measured. Per-point labels and the joined cover, which would take memory in
/// proportion to the scan, are not kept.
#[derive(Clone, Debug)]
pub struct StreamedReconstruction {
    /// The surface, in input coordinates.
    pub mesh: TriMesh,
    /// The unit frame the reconstruction worked in.
    pub normalisation: Normalisation,
    /// What was measured. `scan.isolated` is empty (`scan.isolated_count` counts them).
    pub stats: ReconStats,
}

/// What the stages of a streamed reconstruction share.
struct Streamed<'a> {
    source: &'a dyn PointBlocks,
    runner: &'a dyn StreamedTileRunner,
    params: &'a ReconParams,
    tiling: Tiling,
    scratch: &'a Path,
    /// Whether the samples carry a scanner's confidence, and normals.
    scanner: bool,
    normals_given: bool,
    /// Without normals: a subsample of the scan (every k-th finite point, at most
    /// [`COARSE_SAMPLES`]) whose normals, oriented over the whole subsample, orient the
    /// tiles' own.
    coarse: Vec<DVec3>,
    /// The split planes in input coordinates, and the halo in input units.
    input_splits: [Vec<f64>; 3],
    input_halo: f64,
    files: Option<TileFiles>,
    /// The unit frame: the box of the samples that are not isolated.
    frame: Normalisation,
    spacing: f64,
    noise: f64,
    drop_isolated: bool,
    /// The split planes in the unit frame.
    splits: [Vec<f64>; 3],
    pieces: Vec<(Cover, Vec<f64>)>,
    /// Samples the tiles found confident (at the seed threshold), and a few of them as
    /// polygonisation seeds; the same for the threshold 0.
    seeds: [SeedSet; 2],
    poly: PolygoniseParams,
    poly_stats: PolygoniseStats,
    mesh: TriMesh,
    /// The first triangle of the component most samples lie nearest to, when they voted.
    object_triangle: Option<usize>,
    stats: ReconStats,
}

/// Seeds of one threshold: how many samples qualify, and one of them per lattice cell of
/// half a grid step (the polygonisation needs a seed near every piece of surface, not every
/// sample; the trimming reads every sample, tile by tile).
#[derive(Default)]
struct SeedSet {
    qualified: usize,
    cells: HashSet<[i64; 3]>,
    points: Vec<DVec3>,
}

impl SeedSet {
    /// Counts `p` as qualified and keeps it when its cell has no seed yet.
    fn add(&mut self, p: DVec3, cell: f64) {
        self.qualified += 1;
        self.keep(p, cell);
    }

    /// Keeps `p` when its cell has no seed yet (a tile's seeds joined in tile order keep the
    /// seed a single pass over all tiles' samples would).
    fn keep(&mut self, p: DVec3, cell: f64) {
        let key = (p / cell).floor().as_i64vec3().to_array();
        if self.cells.insert(key) {
            self.points.push(p);
        }
    }
}

impl Streamed<'_> {
    fn files(&self) -> &TileFiles {
        built(self.files.as_ref(), "tile files")
    }

    /// The halo in the unit frame.
    fn halo(&self) -> f64 {
        self.input_halo / self.frame.scale
    }

    /// Tile `t`'s samples in the unit frame, and which lie in its own box.
    fn tile_samples(&self, t: usize) -> Result<(TileSamples, Vec<bool>), ReconError> {
        read_tile(self.files().directory(), t, &self.input_splits, &self.frame)
    }

    /// The seeds that qualify: at the seed threshold, or at 0 when none did anywhere.
    fn threshold(&self) -> (usize, f64) {
        if self.seeds[0].qualified > 0 {
            (0, self.params.seed_confidence)
        } else {
            (1, 0.0)
        }
    }

    fn position(&self, t: usize) -> [usize; 3] {
        let [nx, ny, _] = self.tiling.tiles;
        [t % nx, (t / nx) % ny, t / (nx * ny)]
    }
}

/// Tile `t`'s samples from `directory` in the unit frame `frame`, and which lie in its own
/// box (by the split planes in input coordinates).
fn read_tile(
    directory: &TileDirectory,
    t: usize,
    input_splits: &[Vec<f64>; 3],
    frame: &Normalisation,
) -> Result<(TileSamples, Vec<bool>), ReconError> {
    let mut samples = directory.read(t)?;
    let own = samples
        .points
        .iter()
        .map(|&p| tile_of(input_splits, p) == t)
        .collect();
    for p in &mut samples.points {
        *p = frame.to_unit(*p);
    }
    Ok((samples, own))
}

type StreamedStage<'a> = Stage<Streamed<'a>, ReconError>;

/// The stages of a streamed reconstruction with `params`, in order.
fn streamed_stages<'a>(params: &ReconParams, normals_given: bool) -> Vec<StreamedStage<'a>> {
    let mut stages = vec![
        Stage::new("bounds", bounds),
        Stage::new("tile files", write_tile_files),
    ];
    if !normals_given {
        stages.push(Stage::new("normals", estimate_tile_normals));
    }
    stages.extend([
        Stage::new("scan statistics", measure_tiles),
        Stage::new("tiles", build_tile_functions),
        Stage::new("polygonise", polygonise),
    ]);
    if params.trim != Trim::Off {
        stages.push(Stage::new("trim", trim));
    }
    stages.push(Stage::new("clean and refine", clean_and_refine));
    stages.push(Stage::new("topology", topology));
    stages
}

/// The names of [`streamed_stages`].
pub(super) fn streamed_stage_names(params: &ReconParams, normals_given: bool) -> Vec<&'static str> {
    streamed_stages(params, normals_given)
        .iter()
        .map(|s| s.name)
        .collect()
}

/// Runs a streamed reconstruction (see [`reconstruct_streamed`](super::reconstruct_streamed)).
pub(super) fn run_streamed(
    source: &dyn PointBlocks,
    runner: &dyn StreamedTileRunner,
    params: &ReconParams,
    tiling: &Tiling,
    scratch: &Path,
    progress: &(dyn Fn(StageProgress) + Sync),
    stop: &StopRequest,
) -> Result<StreamedReconstruction, ReconError> {
    if params.method == Method::GraphCut {
        return Err(ReconError::NotTileable(params.method.name()));
    }
    let mut ctx = Streamed {
        source,
        runner,
        params,
        tiling: *tiling,
        scratch,
        scanner: false,
        normals_given: true,
        coarse: Vec::new(),
        input_splits: Default::default(),
        input_halo: 0.0,
        files: None,
        frame: Normalisation::IDENTITY,
        spacing: 0.0,
        noise: 0.0,
        drop_isolated: false,
        splits: Default::default(),
        pieces: Vec::new(),
        seeds: Default::default(),
        poly: PolygoniseParams::default(),
        poly_stats: PolygoniseStats::default(),
        mesh: TriMesh::default(),
        object_triangle: None,
        stats: ReconStats {
            method: params.method,
            ..ReconStats::default()
        },
    };
    ctx.normals_given = source.has_normals()?;
    let stages = streamed_stages(params, ctx.normals_given);
    let times = run_stages_until(&mut ctx, &stages, progress, stop)?;
    ctx.stats.stages = times;
    Ok(StreamedReconstruction {
        mesh: ctx.mesh,
        normalisation: ctx.frame,
        stats: ctx.stats,
    })
}

/// First pass over the scan: the box of its finite points, how many there are, and whether
/// they have what the reconstruction needs (normals).
fn bounds(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let (mut bbox, mut total, mut finite) = (Aabb::EMPTY, 0usize, 0usize);
    let mut scanner = None;
    let (mut coarse, mut stride) = (Vec::new(), 1usize);
    let subsample = !ctx.normals_given;
    ctx.source.blocks(&mut |block| {
        scanner.get_or_insert(block.confidence.is_some());
        total += block.len();
        for &p in block.positions.iter().filter(|p| p.is_finite()) {
            bbox.add(p);
            if subsample && finite.is_multiple_of(stride) {
                coarse.push(p);
                // Twice the limit: keep every other one, and take every other from now on.
                if coarse.len() == 2 * COARSE_SAMPLES {
                    coarse = coarse.iter().copied().step_by(2).collect();
                    stride *= 2;
                }
            }
            finite += 1;
        }
        Ok(())
    })?;
    ctx.coarse = coarse;
    ctx.stats.points = total;
    ctx.stats.non_finite_points = total - finite;
    let needed = MIN_POINTS.max(ctx.params.scan.k + 1);
    if finite < needed {
        return Err(ReconError::TooFewPoints {
            found: finite,
            needed,
        });
    }
    let edge = bbox.longest_edge();
    if edge.is_nan() || edge <= 0.0 {
        return Err(ReconError::NoExtent(finite));
    }
    ctx.scanner = scanner.unwrap_or(false);
    ctx.input_splits = split_planes(&bbox, ctx.tiling.tiles);
    ctx.input_halo = ctx.tiling.halo * edge;
    ctx.frame = Normalisation::of_box(&bbox).ok_or(ReconError::NoExtent(finite))?;
    Ok(())
}

/// Second pass: every finite sample written to the file of each tile whose box, grown by the
/// halo, holds it.
fn write_tile_files(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let mut files = TileFiles::create(ctx.scratch, ctx.tiling.count(), ctx.scanner)?;
    let (splits, halo) = (&ctx.input_splits, ctx.input_halo);
    ctx.source.blocks(&mut |block| {
        for (i, &p) in block.positions.iter().enumerate() {
            if !p.is_finite() {
                continue;
            }
            // Without normals, the next stage writes them.
            let normal = block.normals.as_ref().map_or(DVec3::ZERO, |n| n[i]);
            let scanner = block.confidence.as_ref().map(|c| c[i].clamp(0.0, 1.0));
            let mut result = Ok(());
            tiles_holding(splits, halo, p, |t| {
                if result.is_ok() {
                    result = files.push(t, p, normal, scanner);
                }
            });
            result?;
        }
        Ok(())
    })?;
    files.finish()?;
    ctx.files = Some(files);
    Ok(())
}

/// Most points of the subsample whose oriented normals orient the tiles' (it holds between
/// this and twice this many): it is oriented in one process, so its size is bounded, not
/// the scan's.
const COARSE_SAMPLES: usize = 1 << 19;

/// Nearest subsample normals that vote on the sign of a tile's normal.
const ORIENTING_NEIGHBOURS: usize = 4;

/// Normals for a scan without them: PCA normals of each tile's samples (the halo gives every
/// sample its neighbours), each given the sign that agrees with the nearest normals of a
/// subsample of the whole scan, estimated and oriented consistently as a single run orients
/// them (`estimate_normals`); written into the tile files.
fn estimate_tile_normals(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let coarse: Vec<DVec3> = std::mem::take(&mut ctx.coarse)
        .into_iter()
        .map(|p| ctx.frame.to_unit(p))
        .collect();
    let reference = estimate_normals(&coarse, &ctx.params.normals)?.normals;
    let index = PointIndex::new(&coarse)?;
    let unoriented = NormalParams {
        orient: false,
        ..ctx.params.normals
    };
    for t in 0..ctx.tiling.count() {
        let (samples, _) = ctx.tile_samples(t)?;
        if samples.points.is_empty() {
            continue;
        }
        let mut normals = estimate_normals(&samples.points, &unoriented)?.normals;
        normals
            .par_iter_mut()
            .zip(&samples.points)
            .for_each_init(Vec::new, |near, (n, &p)| {
                index.nearest_k(p, ORIENTING_NEIGHBOURS, near);
                let agreement: f64 = near.iter().map(|&c| n.dot(reference[c as usize])).sum();
                if agreement < 0.0 {
                    *n = -*n;
                }
            });
        ctx.files().directory().replace_normals(t, &normals)?;
    }
    ctx.stats.normals_estimated = true;
    Ok(())
}

/// The spacing and noise of the whole scan from every tile's share of the subsamples, the
/// isolated samples, and the unit frame fitted to the samples that are not isolated.
fn measure_tiles(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let population = ctx.stats.points - ctx.stats.non_finite_points;
    let scan = &ctx.params.scan;
    let (mut spacings, mut residuals) = (Vec::new(), Vec::new());
    let mut inliers = Aabb::EMPTY;
    let mut isolated_count = 0;
    for t in 0..ctx.tiling.count() {
        let (samples, own) = ctx.tile_samples(t)?;
        if samples.points.len() <= scan.k.max(3) {
            // Too few to measure, even with the halo: samples far from all others.
            isolated_count += own.iter().filter(|&&o| o).count();
            continue;
        }
        let index = PointIndex::new(&samples.points)?;
        spacings.extend(spacing_values(&index, scan, population, Some(&own)));
        // Isolation at the tile's own spacing: the scan's is not known yet.
        let local = median(spacing_values(&index, scan, samples.points.len(), None));
        let (isolated, _) = isolated_samples(&index, scan, local);
        residuals.extend(noise_residuals(
            &samples.points,
            Some(&samples.normals),
            &index,
            scan,
            population,
            &isolated,
            Some(&own),
        ));
        for (s, &p) in samples.points.iter().enumerate() {
            if own[s] {
                if isolated[s] {
                    isolated_count += 1;
                } else {
                    inliers.add(ctx.frame.to_input(p));
                }
            }
        }
    }
    let (mut spacing, mut noise) = (median(spacings), median(residuals));
    ctx.drop_isolated = ctx.params.drop_isolated && isolated_count > 0;
    if ctx.drop_isolated
        && let Some(tight) = Normalisation::of_box(&inliers)
    {
        let ratio = ctx.frame.scale / tight.scale;
        spacing *= ratio;
        noise *= ratio;
        ctx.frame = tight;
    }
    ctx.spacing = spacing;
    ctx.noise = noise;
    ctx.stats.scan = ScanStatistics {
        spacing,
        noise,
        isolated: Vec::new(),
        isolated_count,
    };
    let noise = ctx.params.noise.unwrap_or(noise);
    let factor = ctx
        .params
        .noise_tolerance
        .unwrap_or(DEFAULT_NOISE_TOLERANCE);
    ctx.stats.noise_floor = factor * noise;
    ctx.stats.eps = match ctx.params.noise_tolerance {
        Some(_) => ctx.params.cover.eps.max(ctx.stats.noise_floor),
        None => ctx.params.cover.eps,
    };
    ctx.stats.depth = ctx
        .params
        .depth
        .unwrap_or_else(|| default_depth(population));
    let frame = ctx.frame;
    ctx.splits = std::array::from_fn(|a| {
        ctx.input_splits[a]
            .iter()
            .map(|&s| frame.to_unit(DVec3::splat(s))[a])
            .collect()
    });
    Ok(())
}

/// One tile's task in a streamed run: where its file is and what was measured on the whole
/// scan. Plain data, so that a task on another machine that reads the same directory (a
/// shared file system) can be handed one ([`StreamedTileRunner`]).
#[derive(Clone, Debug, PartialEq)]
pub struct StreamedTile {
    /// The tile's index (`ix + nx (iy + ny iz)`).
    pub tile: usize,
    /// Its position along x, y and z.
    pub position: [usize; 3],
    /// The directory of the run's tile files.
    pub directory: PathBuf,
    /// Whether the records carry a scanner's confidence.
    pub scanner: bool,
    /// The split planes in input coordinates: a sample is the tile's own when its box holds
    /// it.
    pub input_splits: [Vec<f64>; 3],
    /// The unit frame of the whole scan.
    pub frame: Normalisation,
    /// The tile's own box in the unit frame.
    pub own_box: Aabb,
    /// The whole scan's sample spacing, noise σ and cover tolerance (unit frame).
    pub spacing: f64,
    /// See [`StreamedTile::spacing`].
    pub noise: f64,
    /// See [`StreamedTile::spacing`].
    pub eps: f64,
    /// Whether isolated samples are left out of the cover.
    pub drop_isolated: bool,
    /// The polygonisation depth of the whole scan.
    pub depth: u32,
}

/// What one tile's task gives back ([`streamed_tile_function`]); the labels of its samples
/// are stored beside its file.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamedTileProduct {
    /// The tile's function: its pruned cover and support confidence (an empty cover for a
    /// tile with too few samples), without per-sample labels.
    pub function: TileFunction,
    /// The seeds of the surface among the tile's own samples, one per lattice cell of half a
    /// grid step: at the seed threshold, and at 0.
    pub seeds: [Vec<DVec3>; 2],
    /// How many own samples qualified as seeds at each threshold.
    pub qualified: [usize; 2],
    /// Samples in the tile's box, and with its halo.
    pub own_samples: usize,
    /// See [`StreamedTileProduct::own_samples`].
    pub samples: usize,
    /// Own samples that are isolated, and that are outliers.
    pub isolated: usize,
    /// See [`StreamedTileProduct::isolated`].
    pub outliers: usize,
}

/// Runs the tasks of a streamed run's tiles: one after the other in this process
/// ([`SequentialStreamedTiles`]), or as tasks of a distributed engine whose workers read the
/// tile files' directory. A runner must return, in order, exactly what
/// [`streamed_tile_function`] returns for each task.
pub trait StreamedTileRunner: Sync {
    /// The product of each task.
    fn run(
        &self,
        tasks: &[StreamedTile],
        params: &ReconParams,
    ) -> Result<Vec<StreamedTileProduct>, ReconError>;
}

/// Runs a streamed run's tiles one after the other in this process, each with every thread.
#[derive(Clone, Copy, Debug, Default)]
pub struct SequentialStreamedTiles;

impl StreamedTileRunner for SequentialStreamedTiles {
    fn run(
        &self,
        tasks: &[StreamedTile],
        params: &ReconParams,
    ) -> Result<Vec<StreamedTileProduct>, ReconError> {
        tasks
            .iter()
            .map(|task| streamed_tile_function(task, params))
            .collect()
    }
}

/// One tile of a streamed run: its samples read from its file, those isolated at the scan's
/// spacing found, its function built ([`tile_function`](super::tile_function)), the labels
/// of all its samples stored beside its file, and the seeds among its own samples. Depends
/// on nothing but its arguments and the tile's file, so any worker gives the same product.
pub fn streamed_tile_function(
    task: &StreamedTile,
    params: &ReconParams,
) -> Result<StreamedTileProduct, ReconError> {
    let directory = TileDirectory {
        dir: task.directory.clone(),
        scanner: task.scanner,
    };
    let (samples, own) = read_tile(&directory, task.tile, &task.input_splits, &task.frame)?;
    let n = samples.points.len();
    let isolated = if !task.drop_isolated {
        vec![false; n]
    } else if n > params.scan.k.max(3) {
        let index = PointIndex::new(&samples.points)?;
        isolated_samples(&index, &params.scan, task.spacing).0
    } else {
        // Too few to measure, even with the halo (as the statistics judged them).
        vec![true; n]
    };
    let input = TileInput {
        position: task.position,
        own_box: task.own_box,
        points: samples.points,
        normals: samples.normals,
        scanner: samples.scanner,
        isolated,
        own,
        spacing: task.spacing,
        noise: task.noise,
        eps: task.eps,
        drop_isolated: task.drop_isolated,
        depth: task.depth,
    };
    let (product, input) = tile_function_and_samples(input, params)?;
    let (mut function, labels) = match product {
        Some(p) => p,
        None => (
            TileFunction {
                cover: empty_cover(params)?,
                support_confidence: Vec::new(),
                confidence: Vec::new(),
                outliers: Vec::new(),
                inconsistent_supports: 0,
                confirmed_supports: 0,
            },
            SampleLabels {
                confidence: vec![0.0; n],
                outliers: vec![true; n],
            },
        ),
    };
    // The labels of the own samples are stored with the others, not sent.
    function.confidence = Vec::new();
    function.outliers = Vec::new();
    directory.write_labels(
        task.tile,
        &labels.confidence,
        &labels.outliers,
        &input.isolated,
    )?;
    let cell = 0.5 / f64::from(1u32 << task.depth);
    let mut seeds: [SeedSet; 2] = Default::default();
    let mut product = StreamedTileProduct {
        function,
        seeds: Default::default(),
        qualified: [0; 2],
        own_samples: 0,
        samples: n,
        isolated: 0,
        outliers: 0,
    };
    for s in (0..n).filter(|&s| input.own[s]) {
        product.own_samples += 1;
        product.isolated += usize::from(input.isolated[s]);
        if labels.outliers[s] {
            product.outliers += 1;
            continue;
        }
        let p = input.points[s];
        if labels.confidence[s] >= params.seed_confidence {
            seeds[0].add(p, cell);
        }
        seeds[1].add(p, cell);
    }
    for (k, set) in seeds.into_iter().enumerate() {
        product.qualified[k] = set.qualified;
        product.seeds[k] = set.points;
    }
    Ok(product)
}

/// Every tile's task by the context's runner; the tiles' seeds joined, one per lattice cell.
fn build_tile_functions(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let params = ReconParams {
        depth: Some(ctx.stats.depth),
        ..ctx.params.clone()
    };
    let tasks: Vec<StreamedTile> = (0..ctx.tiling.count())
        .map(|t| StreamedTile {
            tile: t,
            position: ctx.position(t),
            directory: ctx.files().directory().dir.clone(),
            scanner: ctx.scanner,
            input_splits: ctx.input_splits.clone(),
            frame: ctx.frame,
            own_box: tile_box(&ctx.splits, ctx.position(t), 0.0),
            spacing: ctx.spacing,
            noise: ctx.noise,
            eps: ctx.stats.eps,
            drop_isolated: ctx.drop_isolated,
            depth: ctx.stats.depth,
        })
        .collect();
    let start = Instant::now();
    let products = ctx.runner.run(&tasks, &params)?;
    let elapsed = start.elapsed();
    if products.len() != tasks.len() {
        return Err(ReconError::TileRunner(format!(
            "{} tile products returned for {} tiles",
            products.len(),
            tasks.len()
        )));
    }
    let cell = 0.5 / f64::from(1u32 << ctx.stats.depth);
    let mut confidence_stats = ConfidenceStats {
        scanner_given: ctx.scanner,
        ..ConfidenceStats::default()
    };
    // Counted again at the scan's spacing (the statistics stage judged at each tile's own).
    let mut isolated_count = 0;
    let total = products.iter().map(|p| p.samples).sum::<usize>().max(1);
    for (t, product) in products.into_iter().enumerate() {
        let f = product.function;
        if f.support_confidence.len() != f.cover.len() {
            return Err(ReconError::TileRunner(format!(
                "tile {t}: {} support confidences for {} supports",
                f.support_confidence.len(),
                f.cover.len()
            )));
        }
        ctx.stats.tiles.push(TileStats {
            position: ctx.position(t),
            own_samples: product.own_samples,
            samples: product.samples,
            supports: f.cover.len(),
            time: elapsed.mul_f64(product.samples as f64 / total as f64),
        });
        ctx.stats.inconsistent_supports += f.inconsistent_supports;
        ctx.stats.confirmed_supports += f.confirmed_supports;
        ctx.pieces.push((f.cover, f.support_confidence));
        confidence_stats.samples += product.own_samples;
        confidence_stats.outliers += product.outliers;
        isolated_count += product.isolated;
        for (k, seeds) in product.seeds.into_iter().enumerate() {
            ctx.seeds[k].qualified += product.qualified[k];
            for p in seeds {
                ctx.seeds[k].keep(p, cell);
            }
        }
    }
    if ctx.drop_isolated {
        ctx.stats.scan.isolated_count = isolated_count;
    }
    ctx.stats.supports = ctx.pieces.iter().map(|(c, _)| c.len()).sum();
    confidence_stats.supports = ctx.stats.supports;
    ctx.stats.outliers = confidence_stats.outliers;
    ctx.stats.confidence = Some(confidence_stats);
    Ok(())
}

/// Surface nets of the tiles' functions, from a seed in every lattice cell that holds
/// confident samples; trimmed by the next stage (which reads the samples), or only its fans
/// resolved when nothing is trimmed.
fn polygonise(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let (which, _) = ctx.threshold();
    let seeds = &ctx.seeds[which].points;
    if seeds.is_empty() {
        return Err(ReconError::Empty("every sample is an outlier"));
    }
    ctx.poly = polygonisation_params_at(
        ctx.params,
        ctx.stats.depth,
        ctx.spacing,
        Aabb::from_points(seeds).diagonal(),
    );
    let (mesh, stats) = polygonise_pieces(&ctx.pieces, &ctx.splits, seeds, &ctx.poly, false)?;
    ctx.mesh = mesh;
    ctx.poly_stats = stats;
    if ctx.params.trim == Trim::Off {
        trim_and_resolve(&mut ctx.mesh, None, &ctx.poly, &mut ctx.poly_stats);
        finish_polygonisation(ctx);
    }
    // The functions are not needed any more.
    ctx.pieces = Vec::new();
    Ok(())
}

fn finish_polygonisation(ctx: &mut Streamed<'_>) {
    ctx.stats.unseen_area_fraction = ctx.poly_stats.unseen_area_fraction;
    ctx.stats.polygonise = Some(ctx.poly_stats.clone());
}

/// The elements (`centroids` or vertices) each tile owns, by [`tile_of`] in the unit frame.
fn owned_by_tile(splits: &[Vec<f64>; 3], tiles: usize, points: &[DVec3]) -> Vec<Vec<u32>> {
    let mut owned = vec![Vec::new(); tiles];
    for (i, &p) in points.iter().enumerate() {
        owned[tile_of(splits, p)].push(i as u32);
    }
    owned
}

/// The trimming `params` ask for: each triangle's distance to the nearest qualifying sample,
/// measured by the tile whose box holds its centroid from the samples of its box and halo.
/// Where that is farther than the halo (a sample outside the halo could be nearer), the
/// nearest seed of the whole scan is taken when nearer: the distance is then right to
/// within the seeds' lattice, which only the reach of far regions reads.
fn trim(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let centroids: Vec<DVec3> = ctx
        .mesh
        .triangles
        .par_iter()
        .map(|t| {
            t.iter()
                .map(|&v| ctx.mesh.vertices[v as usize])
                .sum::<DVec3>()
                / 3.0
        })
        .collect();
    let owned = owned_by_tile(&ctx.splits, ctx.tiling.count(), &centroids);
    let (which, threshold) = ctx.threshold();
    let mut distance2 = vec![f64::INFINITY; centroids.len()];
    for (t, triangles) in owned.iter().enumerate() {
        if triangles.is_empty() {
            continue;
        }
        let (samples, _) = ctx.tile_samples(t)?;
        let Some(labels) = ctx.files().directory().read_labels(t)? else {
            continue;
        };
        let seeds: Vec<DVec3> = qualifying(&samples.points, &labels, threshold).collect();
        if seeds.is_empty() {
            continue;
        }
        let index = PointIndex::new(&seeds)?;
        let found: Vec<f64> = triangles
            .par_iter()
            .map_init(Vec::new, |near, &tri| {
                index.nearest_k_with_distances(centroids[tri as usize], 1, near);
                near.first().map_or(f64::INFINITY, |&(d2, _)| d2)
            })
            .collect();
        for (&tri, d2) in triangles.iter().zip(found) {
            distance2[tri as usize] = d2;
        }
    }
    let halo2 = ctx.halo() * ctx.halo();
    let far: Vec<usize> = (0..centroids.len())
        .filter(|&i| distance2[i] > halo2)
        .collect();
    if !far.is_empty() {
        let index = PointIndex::new(&ctx.seeds[which].points)?;
        let mut near = Vec::new();
        for i in far {
            index.nearest_k_with_distances(centroids[i], 1, &mut near);
            if let Some(&(d2, _)) = near.first() {
                distance2[i] = distance2[i].min(d2);
            }
        }
    }
    trim_and_resolve(
        &mut ctx.mesh,
        Some(&distance2),
        &ctx.poly,
        &mut ctx.poly_stats,
    );
    finish_polygonisation(ctx);
    Ok(())
}

/// The samples of a tile that seed the surface at `threshold`.
fn qualifying<'a>(
    points: &'a [DVec3],
    labels: &'a TileLabels,
    threshold: f64,
) -> impl Iterator<Item = DVec3> + 'a {
    points
        .iter()
        .zip(labels.confidence.iter().zip(&labels.outliers))
        .filter(move |&(_, (&c, &o))| !o && c >= threshold)
        .map(|(&p, _)| p)
}

/// What the cleaning and the refinement of a single run need from the samples, tile by tile:
/// the samples' votes for the components they lie nearest to (every 4th of a tile's own, not
/// isolated, against the vertices of its box and halo), and the move of each vertex onto
/// the samples (by the tile whose box holds it). Small components go first, unsupported
/// sheets after the moves.
fn clean_and_refine(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    if ctx.mesh.values.as_ref().map(Vec::len) != Some(ctx.mesh.vertices.len()) {
        ctx.mesh.values = None;
    }
    let topology = MeshTopology::of(&ctx.mesh);
    let removal = sphcover_core::remove_small_components(
        &mut ctx.mesh,
        &topology,
        ctx.params.min_component_fraction,
    )?;
    let topology = if removal.triangles_removed > 0 || removal.vertices_removed > 0 {
        MeshTopology::of(&ctx.mesh)
    } else {
        topology
    };
    let voting = may_hold_sheets(&topology);
    let (positions, components) = if voting {
        vertex_components(&ctx.mesh, &topology)
    } else {
        (Vec::new(), Vec::new())
    };
    let normals = vertex_normals(&ctx.mesh.vertices, &ctx.mesh.triangles);
    let refine = ctx.params.refine;
    let scale = RefinementScale {
        spacing: ctx.spacing,
        step: 1.0 / f64::from(1u32 << ctx.stats.depth),
        noise_ratio: ctx.stats.eps / ctx.params.cover.eps,
    };
    let tiles = ctx.tiling.count();
    let owned = owned_by_tile(&ctx.splits, tiles, &ctx.mesh.vertices);
    let mut near_vertices = vec![Vec::new(); tiles];
    for (v, &p) in positions.iter().enumerate() {
        tiles_holding(&ctx.splits, ctx.halo(), p, |t| {
            near_vertices[t].push(v as u32)
        });
    }
    let mut votes = vec![0usize; topology.components];
    let mut moves = vec![Outcome::Unfitted; ctx.mesh.vertices.len()];
    for t in 0..tiles {
        if owned[t].is_empty() && near_vertices[t].is_empty() {
            continue;
        }
        let (samples, own) = ctx.tile_samples(t)?;
        let Some(labels) = ctx.files().directory().read_labels(t)? else {
            continue;
        };
        if !near_vertices[t].is_empty() {
            let voters: Vec<usize> = (0..own.len())
                .filter(|&s| own[s])
                .step_by(4)
                .filter(|&s| !labels.isolated[s])
                .collect();
            let (tile_positions, tile_components): (Vec<DVec3>, Vec<u32>) = near_vertices[t]
                .iter()
                .map(|&v| (positions[v as usize], components[v as usize]))
                .unzip();
            let tile_votes = component_votes(
                &tile_positions,
                &tile_components,
                topology.components,
                &samples.points,
                &voters,
            )?;
            for (all, v) in votes.iter_mut().zip(tile_votes) {
                *all += v;
            }
        }
        if let Some(refine) = &refine
            && !owned[t].is_empty()
        {
            let weights: Vec<f64> = labels
                .confidence
                .iter()
                .zip(&labels.outliers)
                .map(|(&c, &o)| if o { 0.0 } else { c })
                .collect();
            let index = PointIndex::new(&samples.points)?;
            let samples = RefinementSamples {
                points: &samples.points,
                normals: &samples.normals,
                weights: &weights,
                index: &index,
            };
            check(&samples, &scale, refine)?;
            let (vertices, vertex_normals): (Vec<DVec3>, Vec<DVec3>) = owned[t]
                .iter()
                .map(|&v| (ctx.mesh.vertices[v as usize], normals[v as usize]))
                .unzip();
            let found = refinement_moves(&vertices, &vertex_normals, &samples, &scale, refine);
            for (&v, m) in owned[t].iter().zip(found) {
                moves[v as usize] = m;
            }
        }
    }
    if refine.is_some() {
        ctx.stats.refinement = Some(apply_moves(&mut ctx.mesh.vertices, &normals, &moves));
    }
    // The object's first triangle: the sheets dropped below keep the others' order.
    let object_first = most_voted(&votes).and_then(|c| {
        topology
            .triangle_component
            .iter()
            .position(|&tc| tc as usize == c)
    });
    let dropped = if voting {
        drop_sheets_by_votes(&mut ctx.mesh, &topology, &votes)
    } else {
        Vec::new()
    };
    let gone = |c: u32| dropped.get(c as usize).copied().unwrap_or(false);
    ctx.object_triangle = object_first.map(|first| {
        topology.triangle_component[..first]
            .iter()
            .filter(|&&c| !gone(c))
            .count()
    });
    ctx.stats.dropped_components =
        removal.components_removed + dropped.iter().filter(|&&d| d).count();
    if ctx.mesh.triangles.is_empty() {
        return Err(ReconError::Empty(
            "no surface was found near the confident samples",
        ));
    }
    Ok(())
}

/// The surface in input coordinates, and its topology.
fn topology(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let topology = MeshTopology::of(&ctx.mesh);
    let open_components = topology.open_component.iter().filter(|&&o| o).count();
    let object = if topology.components > 1 && open_components > 0 {
        ctx.object_triangle
            .and_then(|t| topology.triangle_component.get(t))
            .map(|&c| c as usize)
    } else {
        Some(0).filter(|_| topology.components > 0)
    };
    ctx.mesh.to_input(&ctx.frame);
    record_topology(&mut ctx.stats, &ctx.mesh, &topology, object);
    Ok(())
}

#[cfg(test)]
#[path = "streamed_tests.rs"]
mod tests;
