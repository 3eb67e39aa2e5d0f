//! The reconstruction pipeline (thesis §5.2.4): from a scanned point cloud to a triangle mesh.
//!
//! [`Method::Integrated`] (the default) runs, in the unit frame of the points' bounding box:
//!
//! 1. normals by PCA and consistent orientation when the input has none (beyond the thesis);
//! 2. the surface cover (thesis §3.4.1), weighted by a scanner-given confidence if any;
//! 3. the graph cut on the sphere intersection graph (thesis §5.2.4): supports whose label
//!    disagrees with the sign of `f` at their centre are *inconsistent* (outliers and wrong
//!    normals make them) and get a zero local function and confidence 0;
//! 4. the confidence of every sample (eq. 5.39–5.40) and the outlier labels;
//! 5. diffusion of the local functions with confidence-weighted fitting (§5.2.3);
//! 6. polygonisation by surface nets from the confident samples, so a sheet that no
//!    confident sample touches (floating outlier surfaces) is never meshed; components far
//!    smaller than the largest are dropped;
//!
//! and maps the mesh back to input coordinates. [`Method::Diffusion`] skips the cut,
//! [`Method::PartitionOfUnity`] polygonises the cover as built, and [`Method::GraphCut`] is
//! the graph-cut-only path of §5.2.2 (marching tetrahedra on the labels of the dual complex).
//!
//! Lengths in [`ReconParams`] are relative to the longest edge of the input's bounding box
//! (the unit frame), so one parameter set suits any scan's units.

use std::time::{Duration, Instant};

use rayon::prelude::*;
use sphcover_core::{
    Cover, CoverError, DVec3, LocalFunctions, MeshTopology, Normalisation, PointCloud, PointIndex,
    PointIndexError, PuEvaluator, SigError, SphereIntersectionGraph, SupportSamples,
    SurfaceCoverError, SurfaceCoverParams, SurfaceCoverStats, TriMesh,
    build_surface_cover_with_index,
};
use sphcover_ops::{OpsError, PairGeometry};
use thiserror::Error;

use crate::confidence::{
    ConfidenceError, ConfidenceParams, ConfidenceStats, SampleConfidence, blend_over_supports,
    sample_confidence, sample_confidence_indexed,
};
use crate::diffusion::{DiffusionError, DiffusionParams, DiffusionStats, FittingTerms, diffuse};
use crate::graph_cut::{GraphCutError, GraphCutParams, GraphCutStats, graph_cut_sig_alongside};
use crate::graphcut_reconstruction::{
    GraphCutReconstructionError, GraphCutReconstructionParams, reconstruct_graphcut,
};
use crate::normals::{NormalError, NormalParams, estimate_normals};
use crate::polygonise::{
    GridStep, PolygoniseError, PolygoniseParams, PolygoniseStats, polygonise_blending,
};
use crate::scan_statistics::{ScanStatistics, ScanStatisticsParams, scan_statistics};
use crate::small_components::{SmallComponentsError, remove_small_components_of};
use crate::vertex_refinement::{
    RefinementSamples, RefinementScale, VertexRefinementError, VertexRefinementParams,
    VertexRefinementStats, refine_vertices,
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
    /// Shrink factor of the sphere intersection graph (SPEC: 0.7).
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
    /// chooses it from the number of points (module docs of [`default_depth`]).
    pub depth: Option<u32>,
    /// Drop surface far from every sample (users of Poisson tools ask for this on open
    /// scans).
    pub trim: Trim,
    /// Drop components whose area is below this fraction of the largest one's.
    pub min_component_fraction: f64,
    /// Samples at least this confident seed the polygonisation (and count for trimming).
    /// 0: every sample not labelled an outlier, because the thesis confidence separates
    /// surface samples from outliers poorly (module docs of [`mod@crate::scan_statistics`]).
    pub seed_confidence: f64,
    /// Spacing, noise and isolated samples of the scan (beyond the thesis).
    pub scan: ScanStatisticsParams,
    /// The cover tolerance is at least this multiple of the measured noise σ̂ (module docs
    /// of [`mod@crate::scan_statistics`]); `None` keeps ε as given.
    pub noise_tolerance: Option<f64>,
    /// Leave isolated samples out of the cover and label them outliers.
    pub drop_isolated: bool,
    /// Move the vertices onto quadrics fitted to the samples near them (module docs of
    /// [`mod@crate::vertex_refinement`]); `None` keeps the function's zero set.
    pub refine: Option<VertexRefinementParams>,
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
            trim: Trim::Off,
            min_component_fraction: 0.01,
            seed_confidence: 0.0,
            scan: ScanStatisticsParams::default(),
            noise_tolerance: Some(4.0),
            drop_isolated: true,
            refine: Some(VertexRefinementParams::default()),
        }
    }
}

/// The polygonisation depth chosen for `points` samples: `log₂(0.7 √n)` rounded, clamped to
/// 6..=8 below a million samples and 9 from there. The grid step follows the sample spacing
/// (`∝ 1/√n` on a surface): 2–5 triangles per sample on the bunny. On the 362K-point bunny
/// depth 9 gave 1.79M triangles, 446 MB and Chamfer 0.0107% of the diagonal; depth 8 gives
/// 447K triangles, 255 MB and 0.0111%: the function, not the grid, limits the accuracy.
pub fn default_depth(points: usize) -> u32 {
    let d = (0.7 * (points.max(1) as f64).sqrt()).log2().round();
    let finest = if points >= 1_000_000 { 9.0 } else { 8.0 };
    d.clamp(6.0, finest) as u32
}

/// Trimming of surface far from the samples.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Trim {
    /// Keep everything (a closed surface).
    #[default]
    Off,
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
            Trim::Off => 1.0,
            Trim::SampleSpacings(v) | Trim::Distance(v) => v,
        }
    }
}

/// Why reconstruction failed.
#[derive(Debug, Error)]
pub enum ReconError {
    /// Too few usable points.
    #[error("{found} usable points; reconstruction needs at least {needed}")]
    TooFewPoints {
        /// Points with finite coordinates.
        found: usize,
        /// The minimum.
        needed: usize,
    },
    /// All points coincide (no extent to reconstruct).
    #[error("all {0} points coincide: there is no surface to reconstruct")]
    NoExtent(usize),
    /// A parameter is out of range.
    #[error("parameter `{name}` = {value} is out of range ({expected})")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The accepted range.
        expected: &'static str,
    },
    /// Normal estimation failed.
    #[error("normal estimation: {0}")]
    Normals(#[from] NormalError),
    /// The cover could not be built.
    #[error("surface cover: {0}")]
    Cover(#[from] SurfaceCoverError),
    /// A cover operation failed.
    #[error("cover: {0}")]
    CoverUpdate(#[from] CoverError),
    /// The sphere intersection graph could not be built.
    #[error("sphere intersection graph: {0}")]
    Graph(#[from] SigError),
    /// The graph cut failed.
    #[error("graph cut: {0}")]
    GraphCut(#[from] GraphCutError),
    /// The graph-cut-only reconstruction failed.
    #[error("graph-cut reconstruction: {0}")]
    GraphCutReconstruction(#[from] GraphCutReconstructionError),
    /// Confidence could not be computed.
    #[error("confidence: {0}")]
    Confidence(#[from] ConfidenceError),
    /// The pair geometry could not be built.
    #[error("operators: {0}")]
    Operators(#[from] OpsError),
    /// Diffusion failed.
    #[error("diffusion: {0}")]
    Diffusion(#[from] DiffusionError),
    /// Polygonisation failed.
    #[error("polygonisation: {0}")]
    Polygonise(#[from] PolygoniseError),
    /// The samples could not be indexed.
    #[error("sample index: {0}")]
    Index(#[from] PointIndexError),
    /// Small components could not be removed.
    #[error(transparent)]
    SmallComponents(#[from] SmallComponentsError),
    /// Vertex refinement failed.
    #[error("vertex refinement: {0}")]
    Refinement(#[from] VertexRefinementError),
    /// Nothing was left to mesh.
    #[error("the reconstruction is empty: {0}")]
    Empty(&'static str),
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
    /// The graph cut's statistics (integrated method).
    pub cut: Option<GraphCutStats>,
    /// Supports whose label disagreed with the sign of `f` (zeroed).
    pub inconsistent_supports: usize,
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
    /// Euler characteristic of the result.
    pub euler_characteristic: i64,
    /// Wall time per stage, in order.
    pub stages: Vec<(&'static str, Duration)>,
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

/// Reconstructs the surface sampled by `cloud` (module docs). `on_stage` is told the name of
/// each stage as it starts (for progress display).
pub fn reconstruct(
    cloud: &PointCloud,
    params: &ReconParams,
    on_stage: &(dyn Fn(&'static str) + Sync),
) -> Result<Reconstruction, ReconError> {
    check_params(params)?;
    let mut stats = ReconStats {
        method: params.method,
        points: cloud.len(),
        ..ReconStats::default()
    };
    let mut clock = StageClock::new(on_stage);

    // Input in the unit frame; non-finite points are left out (and get confidence 0).
    clock.start("normalise");
    let kept: Vec<usize> = (0..cloud.len())
        .filter(|&i| cloud.positions[i].is_finite())
        .collect();
    stats.non_finite_points = cloud.len() - kept.len();
    const MIN_POINTS: usize = 4;
    if kept.len() < MIN_POINTS {
        return Err(ReconError::TooFewPoints {
            found: kept.len(),
            needed: MIN_POINTS,
        });
    }
    let input_points: Vec<DVec3> = kept.iter().map(|&i| cloud.positions[i]).collect();
    let extent = sphcover_core::Aabb::from_points(&input_points).longest_edge();
    if extent.is_nan() || extent <= 0.0 {
        return Err(ReconError::NoExtent(kept.len()));
    }
    let mut normalisation =
        Normalisation::of_points(&input_points).ok_or(ReconError::NoExtent(kept.len()))?;
    let mut points = input_points;
    normalisation.points_to_unit(&mut points);
    let scanner: Option<Vec<f64>> = cloud
        .confidence
        .as_ref()
        .map(|c| kept.iter().map(|&i| c[i].clamp(0.0, 1.0)).collect());

    clock.start("scan statistics");
    let mut index = PointIndex::new(&points)?;
    let mut scan = scan_statistics(&points, &index, &params.scan);
    let drop_isolated = params.drop_isolated && scan.isolated_count > 0;
    if drop_isolated {
        // The frame and the cover's octree follow the object, not the outliers' extent:
        // with far outliers in the box, the octree's cells near the object are coarser and
        // data-less regions (scanner shadows) reach much farther.
        let inliers: Vec<DVec3> = (0..points.len())
            .filter(|&s| !scan.isolated[s])
            .map(|s| cloud.positions[kept[s]])
            .collect();
        if let Some(tight) = Normalisation::of_points(&inliers) {
            let ratio = normalisation.scale / tight.scale;
            scan.spacing *= ratio;
            scan.noise *= ratio;
            normalisation = tight;
            points = kept
                .iter()
                .map(|&i| normalisation.to_unit(cloud.positions[i]))
                .collect();
            index = PointIndex::new(&points)?;
        }
    }
    let mut cover_params = params.cover.clone();
    if let Some(factor) = params.noise_tolerance {
        cover_params.eps = cover_params.eps.max(factor * scan.noise);
    }
    stats.eps = cover_params.eps;

    let normals: Vec<DVec3> = match &cloud.normals {
        Some(n) => kept.iter().map(|&i| n[i]).collect(),
        None => {
            clock.start("normals");
            stats.normals_estimated = true;
            estimate_normals(&points, &params.normals)?.normals
        }
    };

    clock.start("cover");
    // Isolated samples are left out of the cover (copied only when there are some).
    let picked: (Vec<DVec3>, Vec<DVec3>, Option<Vec<f64>>);
    let (cover_points, cover_normals, cover_trust) = if drop_isolated {
        let in_cover: Vec<usize> = (0..points.len()).filter(|&s| !scan.isolated[s]).collect();
        let pick = |v: &[DVec3]| -> Vec<DVec3> { in_cover.iter().map(|&s| v[s]).collect() };
        picked = (
            pick(&points),
            pick(&normals),
            scanner
                .as_ref()
                .map(|c| in_cover.iter().map(|&s| c[s]).collect()),
        );
        (&picked.0[..], &picked.1[..], picked.2.as_deref())
    } else {
        (&points[..], &normals[..], scanner.as_deref())
    };
    // The scan statistics' index serves the cover too when every sample is in it.
    let (mut cover, cover_stats) = build_surface_cover_with_index(
        cover_points,
        cover_normals,
        cover_trust,
        &index,
        &cover_params,
    )?;
    stats.cover = cover_stats;
    stats.supports = cover.len();

    let depth = params.depth.unwrap_or_else(|| default_depth(points.len()));
    stats.depth = depth;

    let (unit_mesh, conf) = if params.method == Method::GraphCut {
        clock.start("graph cut");
        let (mut mesh, gc_stats) = reconstruct_graphcut(&cover, &points, &params.graph_cut_only)?;
        // The clean stage blends the support confidence at these vertices.
        mesh.values = None;
        stats.cut = Some(gc_stats.cut.clone());
        stats.inconsistent_supports = gc_stats.cut.inconsistent;
        clock.start("confidence");
        let conf = sample_confidence(&cover, &points, scanner.as_deref(), &params.confidence)?;
        (mesh, without_isolated(conf, &scan, params))
    } else {
        let mut zeroed = vec![false; cover.len()];
        if matches!(params.method, Method::Integrated | Method::Diffusion) {
            clock.start("graph");
            let graph = SphereIntersectionGraph::build(
                cover.centers(),
                cover.radii(),
                params.graph_shrink,
            )?;
            stats.graph_mean_degree = graph.mean_degree();
            // Neither the diffusion's pair geometry nor the samples of each support (which
            // the confidence and the fitting terms visit) depend on the cut: built while the
            // max-flow solve holds one thread, they keep the others busy.
            let geometry = || {
                rayon::join(
                    || PairGeometry::build(cover.centers(), cover.radii(), &graph),
                    || SupportSamples::gather(&cover, &index),
                )
            };
            // The graph cut and every diffusion round evaluate at the centres, whose
            // supports stay the same: gathered once.
            let centre_supports =
                || PuEvaluator::new(&cover, 1.0).map(|eval| eval.support_lists(cover.centers()));
            let (at_centers, (pairs, incidence)) = if params.method == Method::Integrated {
                clock.start("graph cut");
                let at_centers = centre_supports()?;
                let (cut, beside) = graph_cut_sig_alongside(
                    &cover,
                    &graph,
                    &at_centers,
                    &params.graph_cut,
                    geometry,
                )?;
                stats.inconsistent_supports = cut.inconsistent.len();
                for &i in &cut.inconsistent {
                    zeroed[i as usize] = true;
                }
                stats.cut = Some(cut.stats);
                (at_centers, beside)
            } else {
                (centre_supports()?, geometry())
            };
            let pairs = pairs?;
            drop(graph);
            clock.start("confidence");
            let conf = sample_confidence_indexed(
                &incidence,
                &points,
                scanner.as_deref(),
                &params.confidence,
                |i| zeroed[i],
            )?;

            clock.start("diffusion");
            let conf = without_isolated(conf, &scan, params);
            let terms = FittingTerms::gather(&incidence, &points, &normals, &conf.confidence)?;
            drop(incidence);
            // The supports the cut found inconsistent start the diffusion from zero; nothing
            // above reads the local functions.
            zero_functions(&mut cover, &zeroed)?;
            stats.diffusion = Some(diffuse(
                &mut cover,
                &pairs,
                &terms,
                &at_centers,
                &params.diffusion,
            )?);
            drop((pairs, terms, at_centers));
            clock.start("polygonise");
            let mesh = polygonise_confident(
                &cover,
                &points,
                &conf,
                depth,
                scan.spacing,
                params,
                &mut stats,
            )?;
            (mesh, conf)
        } else {
            clock.start("confidence");
            let conf = sample_confidence(&cover, &points, scanner.as_deref(), &params.confidence)?;
            let conf = without_isolated(conf, &scan, params);
            clock.start("polygonise");
            let mesh = polygonise_confident(
                &cover,
                &points,
                &conf,
                depth,
                scan.spacing,
                params,
                &mut stats,
            )?;
            (mesh, conf)
        }
    };

    clock.start("clean");
    let mut mesh = unit_mesh;
    // Polygonisation blended the support confidence at the vertices already.
    if mesh.values.as_ref().map(Vec::len) != Some(mesh.vertices.len()) {
        let surface_confidence =
            blend_over_supports(&cover, &mesh.vertices, &conf.support_confidence)?;
        mesh.values = Some(
            surface_confidence
                .into_iter()
                .map(|v| v.unwrap_or(0.0))
                .collect(),
        );
    }
    let topology = MeshTopology::of(&mesh);
    let removal = remove_small_components_of(&mut mesh, &topology, params.min_component_fraction)?;
    stats.dropped_components = removal.components_removed;
    // Neither the refinement nor the change of frame below touches the triangles, so the
    // topology stays valid unless triangles or vertices went here.
    let unchanged_topology =
        (removal.triangles_removed == 0 && removal.vertices_removed == 0).then_some(topology);
    if mesh.triangles.is_empty() {
        return Err(ReconError::Empty(
            "no surface was found near the confident samples",
        ));
    }
    if let Some(refine) = &params.refine {
        clock.start("refine");
        let weights: Vec<f64> = conf
            .confidence
            .iter()
            .zip(&conf.outliers)
            .map(|(&c, &o)| if o { 0.0 } else { c })
            .collect();
        let samples = RefinementSamples {
            points: &points,
            normals: &normals,
            weights: &weights,
            index: &index,
        };
        let scale = RefinementScale {
            spacing: scan.spacing,
            step: 1.0 / f64::from(1u32 << depth),
            noise_ratio: stats.eps / params.cover.eps,
        };
        stats.refinement = Some(refine_vertices(&mut mesh, &samples, &scale, refine)?);
    }
    clock.start("topology");
    mesh.to_input(&normalisation);
    let topology = unchanged_topology.unwrap_or_else(|| MeshTopology::of(&mesh));
    stats.triangles = mesh.triangles.len();
    stats.vertices = mesh.vertices.len();
    stats.components = topology.components;
    stats.watertight = topology.is_watertight();
    stats.euler_characteristic = topology.euler_characteristic();

    // Per input point, in input order.
    let mut point_confidence = vec![0.0; cloud.len()];
    let mut point_outlier = vec![true; cloud.len()];
    for (slot, &i) in kept.iter().enumerate() {
        point_confidence[i] = conf.confidence[slot];
        point_outlier[i] = conf.outliers[slot];
    }
    stats.confidence = Some(conf.stats);
    stats.scan = scan;
    stats.outliers = point_outlier.iter().filter(|&&o| o).count();
    stats.stages = clock.finish();
    Ok(Reconstruction {
        mesh,
        confidence: point_confidence,
        outliers: point_outlier,
        cover,
        normalisation,
        stats,
    })
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
            return Err(ReconError::InvalidParameter {
                name,
                value,
                expected,
            });
        }
    }
    Ok(())
}

/// Sets the local functions of the `zeroed` supports to zero.
fn zero_functions(cover: &mut Cover, zeroed: &[bool]) -> Result<(), ReconError> {
    if !zeroed.contains(&true) {
        return Ok(());
    }
    if let LocalFunctions::Linear { alpha, beta } = cover.funcs() {
        let (mut alpha, mut beta) = (alpha.clone(), beta.clone());
        for (i, _) in zeroed.iter().enumerate().filter(|(_, z)| **z) {
            alpha[i] = DVec3::ZERO;
            beta[i] = 0.0;
        }
        cover.set_funcs(LocalFunctions::Linear { alpha, beta })?;
    }
    Ok(())
}

/// `conf` with the isolated samples (when they are dropped) at confidence 0 and labelled
/// outliers.
fn without_isolated(
    mut conf: SampleConfidence,
    scan: &ScanStatistics,
    params: &ReconParams,
) -> SampleConfidence {
    if params.drop_isolated {
        for (i, _) in scan.isolated.iter().enumerate().filter(|(_, o)| **o) {
            conf.confidence[i] = 0.0;
            conf.outliers[i] = true;
        }
        conf.stats.outliers = conf.outliers.iter().filter(|&&o| o).count();
    }
    conf
}

/// Polygonises the cover from the confident, non-outlier samples.
fn polygonise_confident(
    cover: &Cover,
    points: &[DVec3],
    conf: &SampleConfidence,
    depth: u32,
    spacing: f64,
    params: &ReconParams,
    stats: &mut ReconStats,
) -> Result<TriMesh, ReconError> {
    let confident = |threshold: f64| -> Vec<DVec3> {
        points
            .par_iter()
            .zip(conf.confidence.par_iter().zip(conf.outliers.par_iter()))
            .filter(|(_, (c, o))| !**o && **c >= threshold)
            .map(|(&p, _)| p)
            .collect()
    };
    let mut seeds = confident(params.seed_confidence);
    if seeds.is_empty() {
        seeds = confident(0.0);
    }
    if seeds.is_empty() {
        return Err(ReconError::Empty("every sample is an outlier"));
    }
    let eval = PuEvaluator::new(cover, 1.0)?;
    let poly = PolygoniseParams {
        step: GridStep::Absolute(1.0 / f64::from(1u32 << depth)),
        trim: match params.trim {
            Trim::Off => None,
            Trim::SampleSpacings(m) => Some(m * spacing),
            Trim::Distance(d) => Some(d),
        },
        ..PolygoniseParams::default()
    };
    let (mesh, poly_stats) =
        polygonise_blending(&eval, &seeds, &poly, Some(&conf.support_confidence))?;
    stats.polygonise = Some(poly_stats);
    Ok(mesh)
}

/// Times the stages and reports each start.
struct StageClock<'a> {
    on_stage: &'a (dyn Fn(&'static str) + Sync),
    current: Option<(&'static str, Instant)>,
    done: Vec<(&'static str, Duration)>,
}

impl<'a> StageClock<'a> {
    fn new(on_stage: &'a (dyn Fn(&'static str) + Sync)) -> StageClock<'a> {
        StageClock {
            on_stage,
            current: None,
            done: Vec::new(),
        }
    }

    fn start(&mut self, name: &'static str) {
        if let Some((prev, t)) = self.current.take() {
            self.done.push((prev, t.elapsed()));
        }
        (self.on_stage)(name);
        self.current = Some((name, Instant::now()));
    }

    fn finish(mut self) -> Vec<(&'static str, Duration)> {
        if let Some((prev, t)) = self.current.take() {
            self.done.push((prev, t.elapsed()));
        }
        self.done
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_depth_follows_the_sample_count() {
        let depths: Vec<u32> = [1, 5_210, 100_000, 362_000, 999_999, 1_000_000, 10_000_000]
            .map(default_depth)
            .to_vec();
        assert_eq!(depths, [6, 6, 8, 8, 8, 9, 9]);
    }

    #[test]
    fn bad_parameters_are_refused_before_any_work() {
        let cloud = PointCloud::from_positions(vec![DVec3::ZERO; 10]);
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
                Err(ReconError::InvalidParameter { .. })
            ));
        }
        assert!(matches!(
            reconstruct(&cloud, &ReconParams::default(), &|_| {}),
            Err(ReconError::NoExtent(10))
        ));
    }
}
