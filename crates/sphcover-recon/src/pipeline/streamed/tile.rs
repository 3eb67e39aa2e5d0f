//! The tiles stage of a streamed run: each tile a task that reads its own file, builds its
//! function, stores its samples' labels and gives back its seeds, run by a
//! [`StreamedTileRunner`].

use std::collections::HashSet;
use std::path::PathBuf;
use std::time::Instant;

use sphcover_core::{Aabb, DVec3, Normalisation, PointIndex};

use super::Streamed;
use crate::confidence::ConfidenceStats;
use crate::pipeline::spill::{TileDirectory, TileSamples};
use crate::pipeline::tiled::{
    SampleLabels, TileFunction, TileInput, TileStats, empty_cover, tile_box,
    tile_function_and_samples, tile_of,
};
use crate::pipeline::{ReconError, ReconParams};
use crate::scan_statistics::isolated_samples;

/// Seeds of one threshold: how many samples qualify, and one of them per lattice cell of
/// half a grid step (the polygonisation needs a seed near every piece of surface, not every
/// sample; the trimming reads every sample, tile by tile).
#[derive(Default)]
pub(super) struct SeedSet {
    pub qualified: usize,
    cells: HashSet<[i64; 3]>,
    pub points: Vec<DVec3>,
}

impl SeedSet {
    /// Counts `p` as qualified and keeps it when its cell has no seed yet.
    pub fn add(&mut self, p: DVec3, cell: f64) {
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

/// Tile `t`'s samples from `directory` in the unit frame `frame`, and which lie in its own
/// box (by the split planes in input coordinates).
pub(super) fn read_tile(
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
    /// Whether the whole scan is one view (its diffusion keeps layers apart).
    pub one_view: bool,
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
/// spacing found, its function built ([`tile_function`](crate::tile_function)), the labels
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
    // Built once: the isolation test and the tile's stages both search it.
    let index = PointIndex::new(&samples.points)?;
    let isolated = if !task.drop_isolated {
        vec![false; n]
    } else if n > params.scan.k.max(3) {
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
        one_view: task.one_view,
        depth: task.depth,
    };
    let (product, input) = tile_function_and_samples(input, Some(index), params)?;
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
pub(super) fn build_tile_functions(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
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
            one_view: ctx.stats.scan.one_view,
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
