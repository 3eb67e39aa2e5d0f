//! The streamed tiled reconstruction: the scan read from its file a block at a time into
//! tile files, and every pass over the samples made one tile at a time, so that the process
//! holds one tile's samples, the tiles' functions and the surface, never the whole scan.
//!
//! The method is described on [`reconstruct_streamed()`](super::reconstruct_streamed).

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use sphcover_core::io::{self, ReadOptions};
use sphcover_core::{
    Aabb, Cover, DVec3, Normalisation, PointCloud, PointIndex, Stage, StageProgress, StopRequest,
    Stopped, TriMesh, run_stages_until,
};

mod surface;
mod tile;

use surface::{clean_and_refine, polygonise, topology, trim};
use tile::{SeedSet, build_tile_functions, read_tile};
pub use tile::{
    SequentialStreamedTiles, StreamedTile, StreamedTileProduct, StreamedTileRunner,
    streamed_tile_function,
};

use super::spill::{TileFiles, TileSamples};
use super::stages::{MIN_POINTS, built};
use super::tiled::{Tiling, split_planes, tiles_holding};
use super::{Method, ReconError, ReconParams, ReconStats, Trim, default_depth};
use crate::normals::{NormalParams, estimate_normals};
use crate::polygonise::PolygoniseParams;
use crate::scan_statistics::{
    ScanStatistics, isolated_samples, median, noise_residuals, one_view, spacing_values,
    view_normals,
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
    mesh: TriMesh,
    /// The first triangle of the component most samples lie nearest to, when they voted.
    object_triangle: Option<usize>,
    stats: ReconStats,
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
    let (mut spacings, mut residuals, mut normals) = (Vec::new(), Vec::new(), Vec::new());
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
        normals.extend(view_normals(
            &samples.normals,
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
        one_view: one_view(&normals),
    };
    ctx.stats.noise_floor = ctx.params.noise_floor(noise);
    ctx.stats.eps = ctx.params.tolerance(ctx.stats.noise_floor);
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

#[cfg(test)]
mod tests;
