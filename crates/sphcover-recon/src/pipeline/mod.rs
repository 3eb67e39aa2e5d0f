//! The reconstruction pipeline (thesis §5.2.4): from a scanned point cloud to a triangle mesh.
//!
//! The method is described on [`reconstruct()`].

mod components;
mod error;
mod spill;
mod spread;
mod stages;
mod streamed;
mod tile_bytes;
mod tiled;

use sphcover_core::{
    Cover, Normalisation, ParameterError, PointCloud, StageProgress, StopRequest,
    SurfaceCoverParams, SurfaceCoverStats, TriMesh, run_stages_until,
};
use std::time::Duration;

use crate::confidence::{ConfidenceParams, ConfidenceStats};
use crate::diffusion::{DiffusionParams, DiffusionStats};
use crate::graph_cut::{GraphCutParams, GraphCutStats};
use crate::graphcut_reconstruction::GraphCutReconstructionParams;
use crate::normals::NormalParams;
use crate::polygonise::PolygoniseStats;
use crate::scan_statistics::{ScanStatistics, ScanStatisticsParams};
use crate::vertex_refinement::{VertexRefinementParams, VertexRefinementStats};
pub use error::ReconError;
pub use spill::TILE_DIRECTORY_PREFIX;
use stages::{ReconContext, back_stages, built, front_stages, stage_list};
pub use streamed::{
    PointBlocks, ScanFile, SequentialStreamedTiles, StreamedReconstruction, StreamedTile,
    StreamedTileProduct, StreamedTileRunner, streamed_tile_function,
};
pub use tiled::{
    SequentialTiles, TileFunction, TileInput, TileRunner, TileStats, Tiling, tile_function,
};

/// Which reconstruction to run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Method {
    /// Cover, graph cut on the sphere intersection graph, diffusion, polygonisation
    /// (thesis §5.2.4).
    #[default]
    Integrated,
    /// Cover, diffusion, polygonisation: no graph cut.
    Diffusion,
    /// Cover, polygonisation: the plain partition-of-unity function (multi-level
    /// partition of unity, as MPU).
    PartitionOfUnity,
    /// Cover, dual-complex tetrahedral mesh, graph cut, marching tetrahedra on the labels
    /// (thesis §5.2.2).
    GraphCut,
}

impl Method {
    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Method::Integrated => "integrated",
            Method::Diffusion => "diffusion",
            Method::PartitionOfUnity => "pu",
            Method::GraphCut => "graphcut",
        }
    }
}

/// Parameters of [`reconstruct`]. Lengths are relative to the longest edge of the input's
/// bounding box.
#[derive(Clone, Debug, PartialEq)]
pub struct ReconParams {
    /// The pipeline.
    pub method: Method,
    /// Surface cover: ε, `n_min`, kernel, seed (thesis §3.4.1).
    pub cover: SurfaceCoverParams,
    /// Shrink factor of the sphere intersection graph (thesis Appendix B: 0.7).
    pub graph_shrink: f64,
    /// Graph cut on the sphere intersection graph.
    pub graph_cut: GraphCutParams,
    /// The graph-cut-only path ([`Method::GraphCut`]).
    pub graph_cut_only: GraphCutReconstructionParams,
    /// Outlier threshold of the sample confidence.
    pub confidence: ConfidenceParams,
    /// Diffusion of the local functions.
    pub diffusion: DiffusionParams,
    /// Normal estimation, used when the input has no normals.
    pub normals: NormalParams,
    /// Octree depth of the polygonisation grid (step = longest edge / 2^depth); `None`
    /// chooses it from the number of points (see [`default_depth`]).
    pub depth: Option<u32>,
    /// Drop surface far from every sample (users of Poisson tools ask for this on open
    /// scans).
    pub trim: Trim,
    /// Drop components whose area is below this fraction of the largest one's.
    pub min_component_fraction: f64,
    /// Samples at least this confident seed the polygonisation (and count for trimming).
    /// 0: every sample not labelled an outlier, because the thesis confidence separates
    /// surface samples from outliers poorly (see [`scan_statistics()`](crate::scan_statistics())).
    pub seed_confidence: f64,
    /// Spacing, noise and isolated samples of the scan (beyond the thesis).
    pub scan: ScanStatisticsParams,
    /// The cover tolerance is at least this multiple of the scan's noise σ (see
    /// [`scan_statistics()`](crate::scan_statistics())); `None` keeps ε as given. The floor
    /// is recorded either way ([`ReconStats::noise_floor`], with
    /// [`DEFAULT_NOISE_TOLERANCE`] when `None`), so that a caller can say when a given ε
    /// lies below it.
    pub noise_tolerance: Option<f64>,
    /// The noise σ of the scan, relative to the longest edge of the unit frame, when it is
    /// known; `None` measures it.
    pub noise: Option<f64>,
    /// Leave isolated samples out of the cover and label them outliers.
    pub drop_isolated: bool,
    /// Move the vertices onto quadrics fitted to the samples near them (see
    /// [`refine_vertices`](crate::refine_vertices)); `None` keeps the function's zero set.
    pub refine: Option<VertexRefinementParams>,
    /// Fill the tunnels one or two grid vertices wide that the polygonisation would run
    /// through thin walls ([`PolygoniseParams::fill_pinholes`](crate::PolygoniseParams)).
    pub fill_pinholes: bool,
    /// Once the sphere intersection graph is built, stop with
    /// [`ReconError::OverMemoryBudget`] when the predicted peak of the whole run
    /// ([`crate::ReconMemoryModel::peak_bytes_with_graph`]) exceeds this many bytes: a cover
    /// refined to its sampling (thin walls, sharp edges everywhere) can need several times
    /// what the points and the depth predict. `None` checks nothing; tiles are not checked.
    pub memory_budget: Option<u64>,
}

impl Default for ReconParams {
    fn default() -> Self {
        ReconParams {
            method: Method::Integrated,
            cover: SurfaceCoverParams::default(),
            graph_shrink: 0.7,
            graph_cut: GraphCutParams::sig(),
            graph_cut_only: GraphCutReconstructionParams::default(),
            confidence: ConfidenceParams::default(),
            diffusion: DiffusionParams::default(),
            normals: NormalParams::default(),
            depth: None,
            trim: Trim::Unseen,
            min_component_fraction: 0.01,
            seed_confidence: 0.0,
            scan: ScanStatisticsParams::default(),
            noise_tolerance: Some(DEFAULT_NOISE_TOLERANCE),
            noise: None,
            drop_isolated: true,
            refine: Some(VertexRefinementParams::default()),
            fill_pinholes: true,
            memory_budget: None,
        }
    }
}

/// The polygonisation depth chosen for `points` samples: `log₂(0.7 √n)` rounded, clamped to
/// 6..=8 below a million samples and 9 from there. The grid step follows the sample spacing
/// (`∝ 1/√n` on a surface): 2–5 triangles per sample on the bunny. On the 362K-point bunny
/// depth 9 instead of 8 quadruples the triangles and raises the peak memory by about two
/// thirds (`docs/benchmarks.md`, *Memory*) for hardly any gain in Chamfer distance: the
/// function, not the grid, limits the accuracy.
pub fn default_depth(points: usize) -> u32 {
    let d = (0.7 * (points.max(1) as f64).sqrt()).log2().round();
    let finest = if points >= 1_000_000 { 9.0 } else { 8.0 };
    d.clamp(6.0, finest) as u32
}

/// The distance from every sample, in sample spacings (the median mean distance to 16
/// neighbours, about 2.9 times the median distance to the nearest for random samples), beyond
/// which [`Trim::Unseen`] takes surface for invented. Where the views of a scan stop reaching
/// (grazing angles, occlusion) the surface a few spacings on is a fair completion: cutting at
/// one spacing instead of three made the 12-view scans of the thin-walled housing 14–32%
/// worse in Hausdorff-99 against the truth, and the turntable bunny 4.5% worse in Chamfer.
/// Scans of one view are cut nearer ([`ONE_VIEW_NEAR`]).
pub const UNSEEN_NEAR: f64 = 3.0;

/// [`UNSEEN_NEAR`] for a scan of one view (its normals facing one side, see
/// [`crate::one_view`]): about three nearest-neighbour distances, the most that surface
/// between samples lies from them. A single view's borders are silhouettes and the shadows
/// of depth jumps, which surface continued three spacings on bridges: so the hippo scans
/// kept 25–31% of their area farther than three nearest-neighbour distances from every
/// sample, and with one spacing 0.4–0.5%.
pub const ONE_VIEW_NEAR: f64 = 1.0;

/// The diffusion's layer gate for a scan of one view, in cover tolerances ε
/// ([`crate::diffusion::DiffusionParams::layer_gap`]): supports whose planes lie more than
/// about this far apart are not smoothed together. One view sees surface before surface
/// (plates before a wall, a nose before a cheek) from one side only, and averaging the two
/// layers lost the surface beside the near one: on the 100K single-view scans 0.3–4% of
/// the samples lay farther than two nearest-neighbour distances from the output, 10.7% on
/// plates before a wall; with the gate 0.00–1.9%. At 4ε the femur came out in 4 components
/// instead of 3; at 2ε in 3. Scans of several views keep the thesis's coupling: their
/// tables were measured with it.
pub const ONE_VIEW_LAYER_GAP: f64 = 2.0;

/// The farthest, in sample spacings, that a region of surface far from the samples of a scan
/// of one view may reach and still be kept by [`Trim::Unseen`]: pinholes where the samples
/// are sparse, not shadows. With 1 (no
/// region kept), a streamed and an in-memory run of the same hippo scan differed by three
/// pinholes; at 1.5 and 2 they agree, and the single views of the bunny, housing, fandisk
/// and femur keep 0–0.08% of their area farther than 3 nearest-neighbour distances from
/// every sample at 1.5, 0–0.16% at 2.
pub const ONE_VIEW_REACH: f64 = 1.5;

/// The farthest, relative to the samples' bounding-box diagonal, that a region of surface
/// far from the samples may reach and still be kept by [`Trim::Unseen`]: a hole the samples
/// surround (the benchmarks' holes, of radius 3%, are closed), not a side the scanner never
/// saw (the back of one view reaches 20–50%, the unseen base of a turntable scan 15%).
pub const UNSEEN_REACH: f64 = 0.06;

/// Trimming of surface far from the samples.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Trim {
    /// Keep everything (a closed surface).
    Off,
    /// Cut away the regions of surface farther than [`UNSEEN_NEAR`] sample spacings from
    /// every sample that reach farther than [`UNSEEN_REACH`] of the diagonal (what an open
    /// scan never saw), and keep the others (holes in a closed object, which stays closed).
    /// A scan of one view is cut at [`ONE_VIEW_NEAR`] and keeps only regions within
    /// [`ONE_VIEW_REACH`] spacings (pinholes).
    #[default]
    Unseen,
    /// Drop triangles farther than this many sample spacings (the median distance of a
    /// sample to its neighbours) from every sample.
    SampleSpacings(f64),
    /// Drop triangles farther than this (relative to the longest bounding-box edge) from
    /// every sample.
    Distance(f64),
}

impl Trim {
    /// The number it holds (1 for [`Trim::Off`]).
    fn value(self) -> f64 {
        match self {
            Trim::Off | Trim::Unseen => 1.0,
            Trim::SampleSpacings(v) | Trim::Distance(v) => v,
        }
    }
}

/// The multiple of the noise σ the cover tolerance keeps to by default: with a smaller ε
/// the local functions fit the noise rather than the surface, and the supports shrink to
/// the noise's scale.
pub const DEFAULT_NOISE_TOLERANCE: f64 = 4.0;

impl ReconParams {
    /// The least tolerance a scan asks for ([`ReconStats::noise_floor`]): the noise
    /// tolerance factor times the noise given, or else `measured_noise`.
    pub(crate) fn noise_floor(&self, measured_noise: f64) -> f64 {
        self.noise_tolerance.unwrap_or(DEFAULT_NOISE_TOLERANCE)
            * self.noise.unwrap_or(measured_noise)
    }

    /// The cover's tolerance for a scan whose noise floor is `noise_floor`: ε raised to the
    /// floor, unless a given ε is to be used as given (`noise_tolerance` unset).
    pub(crate) fn tolerance(&self, noise_floor: f64) -> f64 {
        match self.noise_tolerance {
            Some(_) => self.cover.eps.max(noise_floor),
            None => self.cover.eps,
        }
    }
}

/// What a run did with the requested cover tolerance, worth telling the user once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ToleranceNote {
    /// ε was raised to the noise floor.
    Raised {
        /// The ε asked for.
        requested: f64,
        /// The ε used: `factor × noise`.
        used: f64,
        /// The multiple of the noise.
        factor: f64,
        /// The noise σ.
        noise: f64,
        /// Whether σ was measured (else given).
        measured: bool,
    },
    /// The ε asked for lies below the noise floor and was used as asked.
    BelowFloor {
        /// The ε asked for.
        requested: f64,
        /// The floor: [`DEFAULT_NOISE_TOLERANCE`] × the measured noise.
        floor: f64,
    },
}

impl ToleranceNote {
    /// The note for a run with `params` that gave `stats`, if there is one.
    pub fn of(params: &ReconParams, stats: &ReconStats) -> Option<ToleranceNote> {
        let requested = params.cover.eps;
        if stats.eps > requested {
            Some(ToleranceNote::Raised {
                requested,
                used: stats.eps,
                factor: params.noise_tolerance.unwrap_or(DEFAULT_NOISE_TOLERANCE),
                noise: params.noise.unwrap_or(stats.scan.noise),
                measured: params.noise.is_none(),
            })
        } else if stats.noise_floor > requested {
            Some(ToleranceNote::BelowFloor {
                requested,
                floor: stats.noise_floor,
            })
        } else {
            None
        }
    }

    /// The note for people, with the options spelled `eps_option` and `noise_option`
    /// (`--eps`, `--noise`; `eps`, `noise`). Tolerances are relative to the longest edge of
    /// the bounding box.
    pub fn message(&self, eps_option: &str, noise_option: &str) -> String {
        match *self {
            ToleranceNote::Raised {
                requested,
                used,
                factor,
                noise,
                measured,
            } => format!(
                "cover tolerance raised from {requested:.3e} to {used:.3e}, {factor} × the scan's {} noise {noise:.3e}, so that the local functions fit the surface and not its noise; {noise_option} off keeps {requested:.3e} ({eps_option} sets it)",
                if measured { "measured" } else { "given" }
            ),
            ToleranceNote::BelowFloor { requested, floor } => format!(
                "{eps_option} {requested:.3e} is below {floor:.3e}, {DEFAULT_NOISE_TOLERANCE} × the scan's measured noise: the surface may follow the noise; used as given ({noise_option} auto raises it)"
            ),
        }
    }
}

/// Counts and timings of [`reconstruct`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReconStats {
    /// Method run.
    pub method: Method,
    /// Input points.
    pub points: usize,
    /// Points skipped because a coordinate is not finite.
    pub non_finite_points: usize,
    /// Spacing, noise and isolated samples measured on the scan (unit frame).
    pub scan: ScanStatistics,
    /// The cover tolerance used (ε, or more on a noisy scan).
    pub eps: f64,
    /// The least tolerance the scan's noise asks for: [`ReconParams::noise_tolerance`] (or
    /// [`DEFAULT_NOISE_TOLERANCE`]) times the noise σ, given or measured.
    pub noise_floor: f64,
    /// Normals were estimated (the input had none).
    pub normals_estimated: bool,
    /// Samples labelled outliers.
    pub outliers: usize,
    /// The cover's statistics.
    pub cover: SurfaceCoverStats,
    /// Supports.
    pub supports: usize,
    /// Mean degree of the sphere intersection graph.
    pub graph_mean_degree: f64,
    /// The whole run's peak memory as [`crate::RECON_MEMORY_MODEL`] predicts it once the
    /// sphere intersection graph is built (`None` where no graph of the whole cover is).
    pub predicted_peak_bytes: Option<u64>,
    /// The graph cut's statistics (integrated method).
    pub cut: Option<GraphCutStats>,
    /// Supports whose label disagreed with the sign of `f` (zeroed unless confirmed).
    pub inconsistent_supports: usize,
    /// Inconsistent supports kept because at least `n_min` of their samples lie within ε of
    /// their local function's zero set (thin walls, narrow gaps).
    pub confirmed_supports: usize,
    /// Confidence statistics.
    pub confidence: Option<ConfidenceStats>,
    /// Diffusion statistics.
    pub diffusion: Option<DiffusionStats>,
    /// Polygonisation statistics.
    pub polygonise: Option<PolygoniseStats>,
    /// Octree depth of the polygonisation grid.
    pub depth: u32,
    /// Components dropped as too small.
    pub dropped_components: usize,
    /// What the vertex refinement did, when it ran.
    pub refinement: Option<VertexRefinementStats>,
    /// Triangles of the result.
    pub triangles: usize,
    /// Vertices of the result.
    pub vertices: usize,
    /// Connected components of the result.
    pub components: usize,
    /// Every edge has exactly two triangles.
    pub watertight: bool,
    /// Components with a boundary.
    pub open_components: usize,
    /// Share of the surface's area left out as never seen by the scanner ([`Trim::Unseen`]).
    pub unseen_area_fraction: f64,
    /// Whether the object's component has a boundary: when it has none, the open
    /// components are separate sheets (most often surface around stray samples), not a hole
    /// in the object. With several components, the object's is the one that most samples
    /// lie nearest to (a sheet around a few stray samples can be the larger in area).
    pub object_component_open: bool,
    /// Euler characteristic of the result.
    pub euler_characteristic: i64,
    /// Wall time per stage, in order.
    pub stages: Vec<(&'static str, Duration)>,
    /// What each tile did, in a tiled reconstruction ([`reconstruct_tiled`]).
    pub tiles: Vec<TileStats>,
}

/// The product of [`reconstruct`].
#[derive(Clone, Debug)]
pub struct Reconstruction {
    /// The surface, in input coordinates, with per-vertex outward normals and, as values,
    /// the confidence of the surface (the partition-of-unity blend of the support
    /// confidences).
    pub mesh: TriMesh,
    /// Confidence of every input point (0 for non-finite points).
    pub confidence: Vec<f64>,
    /// Outlier label of every input point.
    pub outliers: Vec<bool>,
    /// The final cover, in the unit frame.
    pub cover: Cover,
    /// The unit frame.
    pub normalisation: Normalisation,
    /// Counts and timings.
    pub stats: ReconStats,
}

/// Reconstructs the surface sampled by `cloud` (method below). `progress` is told of each
/// stage as it starts (for progress display); the stages are those of [`stage_names`].
///
/// [`Method::Integrated`] (the default) runs, in the unit frame of the points' bounding box:
///
/// 1. normals by PCA and consistent orientation when the input has none (beyond the thesis);
/// 2. the surface cover (thesis §3.4.1), weighted by a scanner-given confidence if any;
/// 3. the graph cut on the sphere intersection graph (thesis §5.2.4): supports whose label
///    disagrees with the sign of `f` at their centre are *inconsistent* (outliers and wrong
///    normals make them) and get a zero local function and confidence 0, unless at least
///    `n_min` of their samples lie within ε of their zero set (beyond the thesis: the cut
///    also relabels thin walls);
/// 4. the confidence of every sample (eq. 5.39–5.40) and the outlier labels;
/// 5. diffusion of the local functions with confidence-weighted fitting (§5.2.3);
/// 6. polygonisation by surface nets from the confident samples, so a sheet that no
///    confident sample touches (floating outlier surfaces) is never meshed; components far
///    smaller than the largest are dropped, and open ones that fewer than 1% of the samples
///    lie nearest to;
/// 7. when the points have colours, the colour of the nearest inlier sample at every vertex
///    ([`nearest_sample_colors`](crate::nearest_sample_colors));
///
/// and maps the mesh back to input coordinates. [`Method::Diffusion`] skips the cut,
/// [`Method::PartitionOfUnity`] polygonises the cover as built, and [`Method::GraphCut`] is
/// the graph-cut-only path of §5.2.2 (marching tetrahedra on the labels of the dual complex).
///
/// Lengths in [`ReconParams`] are relative to the longest edge of the input's bounding box
/// (the unit frame), so one parameter set suits any scan's units.
pub fn reconstruct(
    cloud: &PointCloud,
    params: &ReconParams,
    progress: &(dyn Fn(StageProgress) + Sync),
) -> Result<Reconstruction, ReconError> {
    reconstruct_until(cloud, params, progress, &StopRequest::new())
}

/// [`reconstruct`], ending with [`ReconError::Stopped`] before the first stage that starts
/// after `stop` was requested (for callers that cancel a run from another thread).
pub fn reconstruct_until(
    cloud: &PointCloud,
    params: &ReconParams,
    progress: &(dyn Fn(StageProgress) + Sync),
    stop: &StopRequest,
) -> Result<Reconstruction, ReconError> {
    check_params(params)?;
    let stages = stage_list(params, cloud);
    run_pipeline(ReconContext::new(cloud, params), &stages, progress, stop)
}

/// [`reconstruct`] in tiles, for scans whose cover, graph and diffusion would not fit in
/// memory at once.
///
/// The frame, the normals (when the input has none) and the scan statistics are those of
/// the whole scan, so every tile works at the same tolerance, depth and orientation. The
/// samples' bounding box is then cut into [`Tiling::tiles`] equal boxes; one tile after the
/// other, the cover, the graph cut, the confidence and the diffusion are built from the
/// samples of the tile's box and a halo of [`Tiling::halo`] around it (the outermost boxes
/// reach to infinity), and only the tile's function is kept. A sample's confidence and
/// outlier label are those of the tile whose box holds it.
///
/// The surface is then polygonised once, from the function that each tile's function
/// defines inside its own box ([`polygonise_piecewise`](crate::polygonise_piecewise)):
/// every grid vertex takes its value from one tile, so the cells on the two sides of a seam
/// agree on their shared corners and the mesh has no crack, duplicate face or seam boundary.
/// Within the halo the tiles' functions nearly agree, so the surface steps by far less than
/// a grid cell at a seam. The cleaning, refinement and topology stages run on the whole
/// mesh as in [`reconstruct`]. The result's cover holds the supports of every tile.
///
/// ```
/// use sphcover_core::{DVec3, MeshTopology, PointCloud};
/// use sphcover_recon::{ReconParams, Tiling, reconstruct_tiled};
///
/// // 6,000 points on a sphere of radius 2, in 2 × 2 × 2 tiles.
/// let positions = sphcover_core::synthetic::fibonacci_sphere(6000);
/// let mut cloud = PointCloud::from_positions(positions.iter().map(|p| 2.0 * *p).collect());
/// cloud.normals = Some(positions);
/// let result = reconstruct_tiled(&cloud, &ReconParams::default(), &Tiling::cubes(2), &|_| {})?;
/// assert_eq!(result.stats.tiles.len(), 8);
/// let topology = MeshTopology::of(&result.mesh);
/// assert!(topology.is_closed_oriented_manifold());
/// assert_eq!((topology.components, topology.euler_characteristic()), (1, 2));
/// assert!(result.mesh.vertices.iter().all(|v| (v.length() - 2.0).abs() < 0.05));
/// # Ok::<(), sphcover_recon::ReconError>(())
/// ```
pub fn reconstruct_tiled(
    cloud: &PointCloud,
    params: &ReconParams,
    tiling: &Tiling,
    progress: &(dyn Fn(StageProgress) + Sync),
) -> Result<Reconstruction, ReconError> {
    reconstruct_tiled_with(
        cloud,
        params,
        tiling,
        &SequentialTiles,
        progress,
        &StopRequest::new(),
    )
}

/// [`reconstruct_tiled`] with the tiles' functions run by `runner` (a distributed engine's
/// tasks, for instance: each is [`tile_function`] of one [`TileInput`]), ending with
/// [`ReconError::Stopped`] before the first stage that starts after `stop` was requested.
/// The surface is the same whichever runner ran the tiles.
pub fn reconstruct_tiled_with(
    cloud: &PointCloud,
    params: &ReconParams,
    tiling: &Tiling,
    runner: &dyn TileRunner,
    progress: &(dyn Fn(StageProgress) + Sync),
    stop: &StopRequest,
) -> Result<Reconstruction, ReconError> {
    check_params(params)?;
    tiling.check()?;
    if params.method == Method::GraphCut {
        return Err(ReconError::NotTileable(params.method.name()));
    }
    let stages = tiled_stage_list(params, cloud);
    let mut ctx = ReconContext::new(cloud, params);
    ctx.tiling = Some(*tiling);
    ctx.runner = Some(runner);
    run_pipeline(ctx, &stages, progress, stop)
}

/// [`reconstruct_tiled`] for scans larger than memory: the scan is read from `source` (a
/// file, [`ScanFile`]) a block at a time, twice, and never held whole.
///
/// The first pass finds the box of the finite points; the second writes each sample into a
/// file of every tile whose box, grown by the halo, holds it, in a directory made inside
/// `scratch` and removed afterwards. Every later pass reads one tile file at a time:
///
/// 0. **Normals**, for a scan without them: PCA normals of each tile's samples (the halo
///    gives every sample its neighbours), each given the sign of the nearest normals of a
///    subsample of the whole scan (at most 2^20 points, kept from the first pass), which
///    are estimated and oriented as [`reconstruct`] orients a scan's
///    ([`estimate_normals`](crate::estimate_normals)); written into the tile files.
/// 1. **Scan statistics.** Each tile measures the mean neighbour distances and the noise
///    residuals of its share of the subsamples a single run takes (from the samples of its
///    own box, with the halo's as neighbours); the spacing and the noise are the medians
///    over all tiles' shares. Isolated samples are found at the scan's spacing, and the unit
///    frame is fitted to the rest, as in a single run.
/// 2. **Tiles.** Each tile's function ([`tile_function`]), as in [`reconstruct_tiled`]; the
///    confidence and outlier label of its samples are stored beside its file. `runner` runs
///    these tasks ([`streamed_tile_function`]): [`SequentialStreamedTiles`] in this process,
///    or a distributed engine whose workers read `scratch` (a shared file system).
/// 3. **Polygonisation** of the tiles' functions, seeded from one confident sample per
///    lattice cell of half a grid step.
/// 4. **Trimming**: each triangle's distance to the nearest confident sample, measured by
///    the tile whose box holds its centroid.
/// 5. **Cleaning and refinement**: the samples' votes for the components they lie nearest
///    to, and each vertex's move onto a quadric fitted to the samples near it, by the tile
///    whose box holds it.
///
/// The process holds one tile's samples, the tiles' functions (their supports) and the
/// surface. The spread checks of [`reconstruct`] (points on a plane or a line, a far point)
/// are not made, and colours are not carried to the surface.
///
/// ```
/// use sphcover_core::{MeshTopology, PointCloud, StopRequest};
/// use sphcover_recon::{ReconParams, SequentialStreamedTiles, Tiling, reconstruct_streamed};
///
/// // 6,000 points on a sphere of radius 2, in 2 × 2 × 2 tiles, from memory (a `ScanFile`
/// // reads them from disk instead).
/// let positions = sphcover_core::synthetic::fibonacci_sphere(6000);
/// let mut cloud = PointCloud::from_positions(positions.iter().map(|p| 2.0 * *p).collect());
/// cloud.normals = Some(positions);
/// let scratch = std::env::temp_dir();
/// let result = reconstruct_streamed(
///     &cloud,
///     &SequentialStreamedTiles,
///     &ReconParams::default(),
///     &Tiling::cubes(2),
///     &scratch,
///     &|_| {},
///     &StopRequest::new(),
/// )?;
/// let topology = MeshTopology::of(&result.mesh);
/// assert!(topology.is_closed_oriented_manifold());
/// assert_eq!((topology.components, topology.euler_characteristic()), (1, 2));
/// assert!(result.mesh.vertices.iter().all(|v| (v.length() - 2.0).abs() < 0.05));
/// # Ok::<(), sphcover_recon::ReconError>(())
/// ```
pub fn reconstruct_streamed(
    source: &dyn PointBlocks,
    runner: &dyn StreamedTileRunner,
    params: &ReconParams,
    tiling: &Tiling,
    scratch: &std::path::Path,
    progress: &(dyn Fn(StageProgress) + Sync),
    stop: &StopRequest,
) -> Result<StreamedReconstruction, ReconError> {
    check_params(params)?;
    tiling.check()?;
    streamed::run_streamed(source, runner, params, tiling, scratch, progress, stop)
}

/// The stages of [`reconstruct_streamed`] for `params`, in order, for a scan with normals
/// or without (`normals_given`).
pub fn streamed_stage_names(params: &ReconParams, normals_given: bool) -> Vec<&'static str> {
    streamed::streamed_stage_names(params, normals_given)
}

/// The stages of [`reconstruct_tiled`] for `params` on `cloud`, in order.
pub fn tiled_stage_names(params: &ReconParams, cloud: &PointCloud) -> Vec<&'static str> {
    tiled_stage_list(params, cloud)
        .iter()
        .map(|s| s.name)
        .collect()
}

fn tiled_stage_list<'a>(params: &ReconParams, cloud: &PointCloud) -> Vec<stages::ReconStage<'a>> {
    let mut stages = front_stages(cloud);
    stages.extend(tiled::tiled_stages());
    stages.extend(back_stages(params, cloud));
    stages
}

/// Runs `stages` over `ctx` and gathers the product.
fn run_pipeline<'a>(
    mut ctx: ReconContext<'a>,
    stages: &[stages::ReconStage<'a>],
    progress: &(dyn Fn(StageProgress) + Sync),
    stop: &StopRequest,
) -> Result<Reconstruction, ReconError> {
    let cloud = ctx.cloud;
    let times = run_stages_until(&mut ctx, stages, progress, stop)?;
    let conf = built(ctx.confidence.take(), "sample confidence");

    // Per input point, in input order.
    let mut point_confidence = vec![0.0; cloud.len()];
    let mut point_outlier = vec![true; cloud.len()];
    for (slot, &i) in ctx.kept.iter().enumerate() {
        point_confidence[i] = conf.confidence[slot];
        point_outlier[i] = conf.outliers[slot];
    }
    let mut stats = ctx.stats;
    stats.confidence = Some(conf.stats);
    stats.scan = ctx.scan;
    stats.outliers = point_outlier.iter().filter(|&&o| o).count();
    stats.stages = times;
    Ok(Reconstruction {
        mesh: ctx.mesh,
        confidence: point_confidence,
        outliers: point_outlier,
        cover: built(ctx.cover, "cover"),
        normalisation: built(ctx.normalisation, "unit frame"),
        stats,
    })
}

/// The names of the stages [`reconstruct`] runs for `params` on `cloud`, in order (normals
/// are estimated when the cloud has none; colours are carried to the surface when it has
/// them).
pub fn stage_names(params: &ReconParams, cloud: &PointCloud) -> Vec<&'static str> {
    stage_list(params, cloud).iter().map(|s| s.name).collect()
}

fn check_params(params: &ReconParams) -> Result<(), ReconError> {
    let checks = [
        (
            "graph_shrink",
            params.graph_shrink,
            params.graph_shrink > 0.0 && params.graph_shrink <= 1.0,
            "(0, 1]",
        ),
        (
            "min_component_fraction",
            params.min_component_fraction,
            (0.0..=1.0).contains(&params.min_component_fraction),
            "[0, 1]",
        ),
        (
            "seed_confidence",
            params.seed_confidence,
            (0.0..=1.0).contains(&params.seed_confidence),
            "[0, 1]",
        ),
        (
            "trim",
            params.trim.value(),
            params.trim.value() > 0.0 && params.trim.value().is_finite(),
            "> 0",
        ),
        (
            "depth",
            f64::from(params.depth.unwrap_or(8)),
            params.depth.is_none_or(|d| (1..=14).contains(&d)),
            "1..=14",
        ),
    ];
    for (name, value, ok, expected) in checks {
        if !ok {
            return Err(ReconError::InvalidParameter(ParameterError {
                name,
                value,
                expected,
            }));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::DVec3;

    #[test]
    fn default_depth_follows_the_sample_count() {
        let depths: Vec<u32> = [1, 5_210, 100_000, 362_000, 999_999, 1_000_000, 10_000_000]
            .map(default_depth)
            .to_vec();
        assert_eq!(depths, [6, 6, 8, 8, 8, 9, 9]);
    }

    #[test]
    fn each_method_runs_its_own_stages() {
        let oriented = PointCloud {
            normals: Some(Vec::new()),
            ..PointCloud::default()
        };
        let names = |method, refine: bool, cloud: &PointCloud| {
            let params = ReconParams {
                method,
                refine: refine.then(VertexRefinementParams::default),
                ..ReconParams::default()
            };
            stage_names(&params, cloud)
        };
        let front = ["normalise", "scan statistics", "cover"];
        let back = ["clean", "refine", "topology"];
        let with = |middle: &[&'static str]| -> Vec<&'static str> {
            front.iter().chain(middle).chain(&back).copied().collect()
        };
        assert_eq!(
            names(Method::Integrated, true, &oriented),
            with(&[
                "graph",
                "graph cut",
                "confidence",
                "diffusion",
                "polygonise"
            ])
        );
        assert_eq!(
            names(Method::Diffusion, true, &oriented),
            with(&["graph", "confidence", "diffusion", "polygonise"])
        );
        assert_eq!(
            names(Method::PartitionOfUnity, true, &oriented),
            with(&["confidence", "polygonise"])
        );
        assert_eq!(
            names(Method::GraphCut, true, &oriented),
            with(&["graph cut", "confidence"])
        );
        let unoriented = names(Method::Integrated, false, &PointCloud::default());
        assert_eq!(unoriented[1], "normals");
        assert!(!unoriented.contains(&"refine"));
        let coloured = PointCloud {
            colors: Some(Vec::new()),
            ..oriented.clone()
        };
        let back = ["clean", "refine", "colours", "topology"];
        assert!(names(Method::GraphCut, true, &coloured).ends_with(&back));
    }

    #[test]
    fn every_method_runs_to_a_mesh_reporting_each_stage() {
        // Points on a sphere of radius 1.5 with outward normals.
        let n = 1500;
        let positions = sphcover_core::synthetic::fibonacci_sphere(n);
        let mut cloud = PointCloud::from_positions(positions.iter().map(|p| 1.5 * *p).collect());
        cloud.normals = Some(positions);
        for method in [
            Method::Integrated,
            Method::Diffusion,
            Method::PartitionOfUnity,
            Method::GraphCut,
        ] {
            let params = ReconParams {
                method,
                ..ReconParams::default()
            };
            let seen = std::sync::Mutex::new(Vec::new());
            let result = reconstruct(&cloud, &params, &|stage| {
                seen.lock()
                    .unwrap()
                    .push((stage.name, stage.index, stage.count));
            })
            .unwrap_or_else(|e| panic!("{}: {e}", method.name()));
            let names = stage_names(&params, &cloud);
            let expected: Vec<_> = names
                .iter()
                .enumerate()
                .map(|(i, &s)| (s, i, names.len()))
                .collect();
            assert_eq!(seen.into_inner().unwrap(), expected, "{}", method.name());
            let timed: Vec<_> = result.stats.stages.iter().map(|s| s.0).collect();
            assert_eq!(timed, names);
            assert!(result.stats.triangles > 0, "{}", method.name());
            assert_eq!(result.confidence.len(), n);
        }
    }

    #[test]
    fn bad_parameters_are_refused_before_any_work() {
        let cloud = PointCloud::from_positions(vec![DVec3::ZERO; 20]);
        for params in [
            ReconParams {
                graph_shrink: 0.0,
                ..ReconParams::default()
            },
            ReconParams {
                min_component_fraction: 2.0,
                ..ReconParams::default()
            },
            ReconParams {
                trim: Trim::Distance(-1.0),
                ..ReconParams::default()
            },
            ReconParams {
                depth: Some(0),
                ..ReconParams::default()
            },
        ] {
            assert!(matches!(
                reconstruct(&cloud, &params, &|_| {}),
                Err(ReconError::InvalidParameter(_))
            ));
        }
        assert!(matches!(
            reconstruct(&cloud, &ReconParams::default(), &|_| {}),
            Err(ReconError::NoExtent(20))
        ));
    }
}
