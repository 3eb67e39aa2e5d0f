//! The stages of [`reconstruct`](super::reconstruct) and the context they share.
//!
//! Each stage reads what the earlier ones left in [`ReconContext`] and leaves its own product
//! there; [`stage_list`] says which stages a method runs, in order. The large intermediates
//! (sphere intersection graph, pair geometry, samples of each support, support lists at the
//! centres) are taken out of the context by the last stage that reads them, so each is freed
//! as soon as it is no longer needed, and peak memory stays that of the largest stage.

use rayon::prelude::*;
use sphcover_core::{
    Aabb, Cover, DVec3, FaceSelection, LocalFunctions, MeshTopology, Normalisation, PointCloud,
    PointIndex, PuEvaluator, SphereIntersectionGraph, Stage, SupportLists, SupportSamples,
    SurfaceSamples, TriMesh, build_surface_cover, build_surface_cover_with_samples,
};
use sphcover_ops::{OpsError, PairGeometry};
use std::borrow::Cow;

use super::components::{
    drop_small_components, drop_unsupported_sheets, object_component, sample_votes,
};
use super::tiled::{TileRunner, TiledFunctions, Tiling};
use super::{
    Method, ONE_VIEW_LAYER_GAP, ONE_VIEW_NEAR, ONE_VIEW_REACH, ReconError, ReconParams, ReconStats,
    Trim, UNSEEN_NEAR, UNSEEN_REACH, default_depth,
};
use crate::confidence::{
    SampleConfidence, SupportConfidence, blend_over_supports, sample_confidence,
    sample_confidence_with,
};
use crate::diffusion::{DiffusionParams, FittingTerms, diffuse};
use crate::graph_cut::graph_cut_sig_alongside;
use crate::graphcut_reconstruction::reconstruct_graphcut;
use crate::memory_model::RECON_MEMORY_MODEL;
use crate::normals::estimate_normals;
use crate::polygonise::{
    FieldPiece, GridStep, PiecewiseFunction, PolygoniseParams, UnseenTrim,
    polygonise_piecewise_indexed,
};
use crate::scan_statistics::{ScanStatistics, scan_statistics};
use crate::vertex_colors::nearest_sample_colors;
use crate::vertex_refinement::{RefinementSamples, RefinementScale, refine_vertices};

/// A stage of the reconstruction.
pub(super) type ReconStage<'a> = Stage<ReconContext<'a>, ReconError>;

/// Fewest points with finite coordinates that span a surface.
pub(super) const MIN_POINTS: usize = 4;

/// What the stages of one reconstruction share. Per-sample arrays are indexed by slot: slot
/// `s` is input point `kept[s]`.
pub(super) struct ReconContext<'a> {
    pub cloud: &'a PointCloud,
    pub params: &'a ReconParams,
    /// The input points with finite coordinates.
    pub kept: Vec<usize>,
    /// The unit frame (after `normalise`).
    pub normalisation: Option<Normalisation>,
    /// The samples in the unit frame.
    pub points: Vec<DVec3>,
    /// Outward normals of the samples, given or estimated.
    pub normals: Vec<DVec3>,
    /// The scanner's confidence of each sample, clamped to `[0, 1]`, when the input has one.
    pub scanner: Option<Vec<f64>>,
    /// The k-d tree over `points` (after `scan statistics`).
    pub index: Option<PointIndex>,
    pub scan: ScanStatistics,
    /// Isolated samples are left out of the cover and labelled outliers.
    pub drop_isolated: bool,
    /// The cover (after `cover`); its local functions change in `diffusion`.
    pub cover: Option<Cover>,
    /// The sphere intersection graph, until the stages after it have built the pair geometry.
    pub graph: Option<SphereIntersectionGraph>,
    /// Supports the graph cut found inconsistent: they start the diffusion from zero.
    pub zeroed: Vec<bool>,
    /// The supports at each centre, shared by the graph cut and every diffusion round.
    pub at_centres: Option<SupportLists>,
    pub pairs: Option<PairGeometry>,
    /// The samples inside each support, shared by the confidence and the fitting terms.
    pub incidence: Option<SupportSamples>,
    /// The supports' confidences, when computed beside the graph cut.
    pub support_confidence: Option<SupportConfidence>,
    pub confidence: Option<SampleConfidence>,
    /// The surface, in the unit frame until `topology` maps it back.
    pub mesh: TriMesh,
    /// The topology of `mesh`, when the cleaning left its triangles as they were.
    pub unchanged_topology: Option<MeshTopology>,
    /// How a tiled reconstruction splits the samples.
    pub tiling: Option<Tiling>,
    /// The tiles' functions, between the stage that builds them and the polygonisation.
    pub tiled: Option<TiledFunctions>,
    /// What runs the tiles' functions.
    pub runner: Option<&'a dyn TileRunner>,
    pub stats: ReconStats,
}

impl<'a> ReconContext<'a> {
    pub fn new(cloud: &'a PointCloud, params: &'a ReconParams) -> ReconContext<'a> {
        ReconContext {
            cloud,
            params,
            kept: Vec::new(),
            normalisation: None,
            points: Vec::new(),
            normals: Vec::new(),
            scanner: None,
            index: None,
            scan: ScanStatistics::default(),
            drop_isolated: false,
            cover: None,
            graph: None,
            zeroed: Vec::new(),
            at_centres: None,
            pairs: None,
            incidence: None,
            support_confidence: None,
            confidence: None,
            mesh: TriMesh::default(),
            unchanged_topology: None,
            tiling: None,
            tiled: None,
            runner: None,
            stats: ReconStats {
                method: params.method,
                points: cloud.len(),
                ..ReconStats::default()
            },
        }
    }

    pub fn normalisation(&self) -> Normalisation {
        built(self.normalisation, "unit frame")
    }

    pub fn index(&self) -> &PointIndex {
        built(self.index.as_ref(), "point index")
    }

    pub fn cover(&self) -> &Cover {
        built(self.cover.as_ref(), "cover")
    }

    pub fn confidence(&self) -> &SampleConfidence {
        built(self.confidence.as_ref(), "sample confidence")
    }
}

/// An intermediate that an earlier stage of the list builds. Every method's list is run by
/// the tests, so a missing one is a bug in [`stage_list`], not something input can cause.
pub(super) fn built<T>(slot: Option<T>, what: &str) -> T {
    slot.unwrap_or_else(|| panic!("the stage list builds the {what} before it is used"))
}

/// The stages `params` asks for, in order. `has_normals`: the input carries normals.
pub(super) fn stage_list<'a>(params: &ReconParams, cloud: &PointCloud) -> Vec<ReconStage<'a>> {
    let mut stages = front_stages(cloud);
    stages.push(Stage::new("cover", build_cover));
    match function_stages(params.method) {
        Some(function) => {
            stages.extend(function);
            stages.push(Stage::new("polygonise", polygonise_cover));
        }
        None => stages.extend([
            Stage::new("graph cut", cut_dual_complex),
            Stage::new("confidence", confidence_of_cover),
        ]),
    }
    stages.extend(back_stages(params, cloud));
    stages
}

/// The stages before the cover: the unit frame, normals when the input has none, the scan
/// statistics.
pub(super) fn front_stages<'a>(cloud: &PointCloud) -> Vec<ReconStage<'a>> {
    let mut stages = vec![Stage::new("normalise", normalise)];
    // The noise estimate reads the normals, given or estimated.
    if cloud.normals.is_none() {
        stages.push(Stage::new("normals", estimate_sample_normals));
    }
    stages.push(Stage::new("scan statistics", measure_scan));
    stages
}

/// The stages from the cover to the function that `method` polygonises, after the cover;
/// `None` for [`Method::GraphCut`], whose surface comes from the dual complex instead.
pub(super) fn function_stages<'a>(method: Method) -> Option<Vec<ReconStage<'a>>> {
    Some(match method {
        Method::Integrated => vec![
            Stage::new("graph", build_graph),
            Stage::new("graph cut", cut_graph),
            Stage::new("confidence", confidence_over_supports),
            Stage::new("diffusion", diffuse_functions),
        ],
        Method::Diffusion => vec![
            Stage::new("graph", build_graph_and_geometry),
            Stage::new("confidence", confidence_over_supports),
            Stage::new("diffusion", diffuse_functions),
        ],
        Method::PartitionOfUnity => vec![Stage::new("confidence", confidence_of_cover)],
        Method::GraphCut => return None,
    })
}

/// The stages after the surface: cleaning, refinement, colours, topology.
pub(super) fn back_stages<'a>(params: &ReconParams, cloud: &PointCloud) -> Vec<ReconStage<'a>> {
    let mut stages = vec![Stage::new("clean", clean)];
    if params.refine.is_some() {
        stages.push(Stage::new("refine", refine));
    }
    if cloud.colors.is_some() {
        stages.push(Stage::new("colours", transfer_colors));
    }
    stages.push(Stage::new("topology", topology));
    stages
}

/// The finite input points in the unit frame; non-finite points are left out (and get
/// confidence 0).
fn normalise(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let cloud = ctx.cloud;
    let kept: Vec<usize> = (0..cloud.len())
        .filter(|&i| cloud.positions[i].is_finite())
        .collect();
    ctx.stats.non_finite_points = cloud.len() - kept.len();
    // The scan's spacing is measured over each point's `k` nearest others: with fewer points
    // it is zero, and every length derived from it (cover, trimming, refinement) with it.
    let needed = MIN_POINTS.max(ctx.params.scan.k + 1);
    if kept.len() < needed {
        return Err(ReconError::TooFewPoints {
            found: kept.len(),
            needed,
        });
    }
    let mut points: Vec<DVec3> = kept.iter().map(|&i| cloud.positions[i]).collect();
    let extent = Aabb::from_points(&points).longest_edge();
    if extent.is_nan() || extent <= 0.0 {
        return Err(ReconError::NoExtent(kept.len()));
    }
    let trimmed = ctx.params.trim != Trim::Off;
    super::spread::check_spread(&points, &kept, cloud.normals.is_some(), trimmed)?;
    let normalisation =
        Normalisation::of_points(&points).ok_or(ReconError::NoExtent(kept.len()))?;
    normalisation.points_to_unit(&mut points);
    ctx.scanner = cloud
        .confidence
        .as_ref()
        .map(|c| kept.iter().map(|&i| c[i].clamp(0.0, 1.0)).collect());
    if let Some(n) = &cloud.normals {
        ctx.normals = kept.iter().map(|&i| n[i]).collect();
    }
    ctx.normalisation = Some(normalisation);
    ctx.points = points;
    ctx.kept = kept;
    Ok(())
}

/// Spacing, noise and isolated samples; the frame refitted to the samples that are not
/// isolated; the cover tolerance raised to the noise.
fn measure_scan(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let params = ctx.params;
    let mut index = PointIndex::new(&ctx.points)?;
    let mut scan = scan_statistics(&ctx.points, Some(&ctx.normals), &index, &params.scan);
    ctx.drop_isolated = params.drop_isolated && scan.isolated_count > 0;
    if ctx.drop_isolated {
        // The frame and the cover's octree follow the object, not the outliers' extent:
        // with far outliers in the box, the octree's cells near the object are coarser and
        // data-less regions (scanner shadows) reach much farther.
        let positions = &ctx.cloud.positions[..];
        let inliers: Vec<DVec3> = (0..ctx.points.len())
            .filter(|&s| !scan.isolated[s])
            .map(|s| positions[ctx.kept[s]])
            .collect();
        if let Some(tight) = Normalisation::of_points(&inliers) {
            let ratio = ctx.normalisation().scale / tight.scale;
            scan.spacing *= ratio;
            scan.noise *= ratio;
            ctx.points = ctx
                .kept
                .iter()
                .map(|&i| tight.to_unit(positions[i]))
                .collect();
            ctx.normalisation = Some(tight);
            index = PointIndex::new(&ctx.points)?;
        }
    }
    ctx.stats.noise_floor = params.noise_floor(scan.noise);
    ctx.stats.eps = params.tolerance(ctx.stats.noise_floor);
    ctx.index = Some(index);
    ctx.scan = scan;
    Ok(())
}

/// Normals by PCA and consistent orientation, for input without normals.
fn estimate_sample_normals(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    ctx.stats.normals_estimated = true;
    ctx.normals = estimate_normals(&ctx.points, &ctx.params.normals)?.normals;
    Ok(())
}

/// The narrow face (`sphcover_core::FaceSelection::Narrow`) applies while the scan's noise
/// floor is under this share of the cover's tolerance.
///
/// Measured (`docs/algorithms.md`, *Surface reconstruction*): it helped where the floor was
/// 0–0.23 of the tolerance (the generated housing, noise-free and from 12 views; the bunny
/// scans without noise) and cost seen surface on CGAL's building scan (0.50: 1.52 → 1.82% of
/// its samples farther than two spacings from the output) and on the bunny with noise 0.5%
/// of the diagonal (where the noise sets the tolerance: Chamfer +3%).
const NARROW_FACE_NOISE: f64 = 0.25;

/// Which samples a support across a thin part fits (`sphcover_core::face_to_fit`): the narrow
/// face on scans nearly free of noise ([`NARROW_FACE_NOISE`]), the wide one otherwise. A
/// tile decides from the whole scan's noise and tolerance, which it is given, so every tile
/// decides alike.
fn face_selection(ctx: &ReconContext<'_>) -> FaceSelection {
    if ctx.params.noise_floor(ctx.scan.noise) < NARROW_FACE_NOISE * ctx.stats.eps {
        FaceSelection::Narrow
    } else {
        FaceSelection::Wide
    }
}

/// The surface cover of the samples that are not isolated (thesis §3.4.1).
pub(super) fn build_cover(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let mut cover_params = ctx.params.cover.clone();
    cover_params.eps = ctx.stats.eps;
    cover_params.faces = face_selection(ctx);
    // Isolated samples are left out of the cover (copied only when there are some).
    let picked: (Vec<DVec3>, Vec<DVec3>, Option<Vec<f64>>);
    let (points, normals, trust) = if ctx.drop_isolated {
        let in_cover: Vec<usize> = (0..ctx.points.len())
            .filter(|&s| !ctx.scan.isolated[s])
            .collect();
        let pick = |v: &[DVec3]| -> Vec<DVec3> { in_cover.iter().map(|&s| v[s]).collect() };
        picked = (
            pick(&ctx.points),
            pick(&ctx.normals),
            ctx.scanner
                .as_ref()
                .map(|c| in_cover.iter().map(|&s| c[s]).collect()),
        );
        (&picked.0[..], &picked.1[..], picked.2.as_deref())
    } else {
        (&ctx.points[..], &ctx.normals[..], ctx.scanner.as_deref())
    };
    // The scan statistics' index serves the cover too when every sample is in it.
    let samples = SurfaceSamples::new(points, normals)
        .with_confidence(trust)
        .with_index(ctx.index());
    // The methods that diffuse read every support's samples: the build gives them.
    let (cover, cover_stats, incidence) = match ctx.params.method {
        Method::Integrated | Method::Diffusion => {
            build_surface_cover_with_samples(&samples, &cover_params)?
        }
        Method::PartitionOfUnity | Method::GraphCut => {
            let (cover, stats) = build_surface_cover(&samples, &cover_params)?;
            (cover, stats, None)
        }
    };
    ctx.stats.cover = cover_stats;
    ctx.stats.supports = cover.len();
    ctx.stats.depth = ctx
        .params
        .depth
        .unwrap_or_else(|| default_depth(ctx.points.len()));
    ctx.zeroed = vec![false; cover.len()];
    ctx.cover = Some(cover);
    ctx.incidence = incidence;
    Ok(())
}

/// The sphere intersection graph of the supports (thesis Appendix B).
fn build_graph(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let cover = ctx.cover();
    let graph =
        SphereIntersectionGraph::build(cover.centres(), cover.radii(), ctx.params.graph_shrink)?;
    let supports = cover.len();
    ctx.stats.graph_mean_degree = graph.mean_degree();
    let graph_entries = graph.neighbour_array().len() as u64;
    let estimate =
        RECON_MEMORY_MODEL.peak_bytes_with_graph(ctx.points.len(), ctx.stats.depth, graph_entries);
    ctx.stats.predicted_peak_bytes = Some(estimate);
    if let Some(budget) = ctx.params.memory_budget
        && estimate > budget
    {
        return Err(ReconError::OverMemoryBudget {
            supports,
            graph_entries,
            estimate,
            budget,
        });
    }
    ctx.graph = Some(graph);
    Ok(())
}

/// The support lists at the centres, gathered once: the graph cut and every diffusion round
/// evaluate there, and the supports stay the same.
fn centre_supports(cover: &Cover) -> Result<SupportLists, ReconError> {
    Ok(PuEvaluator::new(cover, 1.0)?.support_lists(cover.centres()))
}

/// The diffusion's pair geometry and the samples of each support, with the supports'
/// confidences when the cover's build gave the samples (else they are gathered here): none
/// of them depends on the cut.
fn geometry_and_samples(
    cover: &Cover,
    graph: &SphereIntersectionGraph,
    index: &PointIndex,
    known: Option<SupportSamples>,
) -> (
    Result<PairGeometry, OpsError>,
    SupportSamples,
    Option<SupportConfidence>,
) {
    let pairs = || PairGeometry::build(cover.centres(), cover.radii(), graph);
    match known {
        Some(incidence) => {
            let (pairs, support) =
                rayon::join(pairs, || SupportConfidence::of(cover, index, &incidence));
            (pairs, incidence, Some(support))
        }
        None => {
            let (pairs, incidence) = rayon::join(pairs, || SupportSamples::gather(cover, index));
            (pairs, incidence, None)
        }
    }
}

/// The graph, and what the diffusion needs of it, without a cut.
fn build_graph_and_geometry(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    build_graph(ctx)?;
    let graph = built(ctx.graph.take(), "sphere intersection graph");
    let known = ctx.incidence.take();
    let cover = ctx.cover();
    let at_centres = centre_supports(cover)?;
    let (pairs, incidence, support) = geometry_and_samples(cover, &graph, ctx.index(), known);
    ctx.pairs = Some(pairs?);
    ctx.at_centres = Some(at_centres);
    ctx.incidence = Some(incidence);
    ctx.support_confidence = support;
    Ok(())
}

/// The graph cut on the sphere intersection graph (thesis §5.2.4): supports whose label
/// disagrees with the sign of `f` at their centre are inconsistent (outliers and wrong
/// normals make them) and get a zero local function and confidence 0, unless their own
/// samples confirm them: at least `n_min` lie within ε of the local function's zero set.
fn cut_graph(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let graph = built(ctx.graph.take(), "sphere intersection graph");
    let known = ctx.incidence.take();
    let (cover, index) = (ctx.cover(), ctx.index());
    let at_centres = centre_supports(cover)?;
    // The pair geometry and the support samples are built while the max-flow solve, which
    // is sequential, holds one thread: they keep the others busy.
    let (cut, (pairs, incidence, support)) =
        graph_cut_sig_alongside(cover, &graph, &at_centres, &ctx.params.graph_cut, || {
            geometry_and_samples(cover, &graph, index, known)
        })?;
    let fitted = fitted_samples(
        cover,
        index,
        &incidence,
        &cut.inconsistent,
        ctx.stats.eps,
        &ctx.scan.isolated,
    );
    ctx.stats.inconsistent_supports = cut.inconsistent.len();
    // The cut's smoothing also flips supports on thin walls and across narrow gaps, where a
    // thin region of one sign is cheaper to relabel than to cut around; there the samples
    // confirm the local function, and zeroing it leaves bumps of a wall's thickness.
    let n_min = ctx.params.cover.n_min;
    for (&i, &f) in cut.inconsistent.iter().zip(&fitted) {
        ctx.zeroed[i as usize] = f < n_min;
    }
    ctx.stats.confirmed_supports = fitted.iter().filter(|&&f| f >= n_min).count();
    ctx.stats.cut = Some(cut.stats);
    ctx.pairs = Some(pairs?);
    ctx.at_centres = Some(at_centres);
    ctx.incidence = Some(incidence);
    ctx.support_confidence = support;
    Ok(())
}

/// For each of `supports`, how many of its samples (isolated ones left out) lie within
/// `eps` of the zero set of its local function.
fn fitted_samples(
    cover: &Cover,
    index: &PointIndex,
    incidence: &SupportSamples,
    supports: &[u32],
    eps: f64,
    isolated: &[bool],
) -> Vec<usize> {
    let LocalFunctions::Linear { alpha, beta } = cover.funcs() else {
        return vec![0; supports.len()];
    };
    let (points, order) = (index.slot_points(), index.order());
    supports
        .par_iter()
        .map(|&i| {
            let i = i as usize;
            let c = cover.centres()[i];
            let mut count = 0;
            incidence.for_each_slot_within(cover, index, i, |slot, _| {
                let value = alpha[i].dot(points[slot] - c) + beta[i];
                if value.abs() <= eps && !isolated[order[slot] as usize] {
                    count += 1;
                }
            });
            count
        })
        .collect()
}

/// The graph-cut-only path (thesis §5.2.2): marching tetrahedra on the labels of the dual
/// complex.
fn cut_dual_complex(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let (mut mesh, stats) =
        reconstruct_graphcut(ctx.cover(), &ctx.points, &ctx.params.graph_cut_only)?;
    // The clean stage blends the support confidence at these vertices.
    mesh.values = None;
    ctx.stats.inconsistent_supports = stats.cut.inconsistent;
    ctx.stats.cut = Some(stats.cut);
    ctx.mesh = mesh;
    Ok(())
}

/// The confidence of every sample (eq. 5.39–5.40) over the samples of each support gathered
/// beside the graph cut; the inconsistent supports count as τ = 0.
fn confidence_over_supports(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let computed = ctx.support_confidence.take();
    let incidence = built(ctx.incidence.as_ref(), "support samples");
    let (cover, index) = (ctx.cover(), ctx.index());
    let mut support = computed.unwrap_or_else(|| SupportConfidence::of(cover, index, incidence));
    let zeroed = &ctx.zeroed;
    support.distrust(|i| zeroed[i]);
    let confidence = sample_confidence_with(
        cover,
        index,
        incidence,
        &ctx.points,
        ctx.scanner.as_deref(),
        &ctx.params.confidence,
        support,
    )?;
    ctx.confidence = Some(without_isolated(confidence, ctx));
    Ok(())
}

/// The confidence of every sample (eq. 5.39–5.40) from the cover alone.
fn confidence_of_cover(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let confidence = sample_confidence(
        ctx.cover(),
        &ctx.points,
        ctx.scanner.as_deref(),
        &ctx.params.confidence,
    )?;
    ctx.confidence = Some(without_isolated(confidence, ctx));
    Ok(())
}

/// `conf` with the isolated samples (when they are dropped) at confidence 0 and labelled
/// outliers.
fn without_isolated(mut conf: SampleConfidence, ctx: &ReconContext<'_>) -> SampleConfidence {
    if ctx.params.drop_isolated {
        for (i, _) in ctx.scan.isolated.iter().enumerate().filter(|(_, o)| **o) {
            conf.confidence[i] = 0.0;
            conf.outliers[i] = true;
        }
        conf.stats.outliers = conf.outliers.iter().filter(|&&o| o).count();
    }
    conf
}

/// Diffusion of the local functions with confidence-weighted fitting (thesis §5.2.3).
fn diffuse_functions(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let incidence = built(ctx.incidence.take(), "support samples");
    let terms = FittingTerms::gather(
        ctx.cover(),
        ctx.index(),
        &incidence,
        &ctx.points,
        &ctx.normals,
        &ctx.confidence().confidence,
        face_selection(ctx),
    )?;
    drop(incidence);
    let pairs = built(ctx.pairs.take(), "pair geometry");
    let at_centres = built(ctx.at_centres.take(), "support lists at the centres");
    let cover = built(ctx.cover.as_mut(), "cover");
    // The supports the cut found inconsistent start the diffusion from zero; no stage before
    // this one reads the local functions after the cut.
    zero_functions(cover, &ctx.zeroed)?;
    // A single view's layers (surface before surface, seen from one side) are kept apart
    // unless the parameters set the gate themselves.
    let one_view_gap = ONE_VIEW_LAYER_GAP * ctx.stats.eps;
    let params = DiffusionParams {
        layer_gap: ctx
            .params
            .diffusion
            .layer_gap
            .or(ctx.scan.one_view.then_some(one_view_gap)),
        ..ctx.params.diffusion
    };
    ctx.stats.diffusion = Some(diffuse(cover, &pairs, &terms, &at_centres, &params)?);
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

/// Surface nets from the confident, non-outlier samples, so a sheet that no confident sample
/// touches (floating outlier surfaces) is never meshed.
fn polygonise_cover(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let seeds = polygonisation_seeds(ctx)?;
    let poly = polygonisation_params(ctx, &seeds);
    let eval = PuEvaluator::new(ctx.cover(), 1.0)?;
    let blend = Some(&ctx.confidence().support_confidence[..]);
    let field = PiecewiseFunction::single(FieldPiece { eval: &eval, blend })?;
    // Seeds that are all the samples have their index: the scan's.
    let seed_index = matches!(seeds, Cow::Borrowed(_)).then(|| ctx.index());
    let (mesh, stats) = polygonise_piecewise_indexed(&field, &seeds, seed_index, &poly)?;
    ctx.stats.unseen_area_fraction = stats.unseen_area_fraction;
    ctx.stats.polygonise = Some(stats);
    ctx.mesh = mesh;
    Ok(())
}

/// The confident samples that are not outliers (every sample that is not an outlier when
/// none reaches [`ReconParams::seed_confidence`]); the samples themselves, not a copy, when
/// every one qualifies (a clean scan: a copy would be the polygonisation's largest array).
pub(super) fn polygonisation_seeds<'c>(
    ctx: &'c ReconContext<'_>,
) -> Result<Cow<'c, [DVec3]>, ReconError> {
    let (params, conf) = (ctx.params, ctx.confidence());
    let qualifies = |threshold: f64| move |(c, o): (&f64, &bool)| !*o && *c >= threshold;
    let confident = |threshold: f64| -> Cow<'c, [DVec3]> {
        let all = conf
            .confidence
            .par_iter()
            .zip(conf.outliers.par_iter())
            .all(qualifies(threshold));
        if all {
            return Cow::Borrowed(&ctx.points[..]);
        }
        Cow::Owned(
            ctx.points
                .par_iter()
                .zip(conf.confidence.par_iter().zip(conf.outliers.par_iter()))
                .filter(|(_, co)| qualifies(threshold)(*co))
                .map(|(&p, _)| p)
                .collect(),
        )
    };
    let mut seeds = confident(params.seed_confidence);
    if seeds.is_empty() {
        seeds = confident(0.0);
    }
    if seeds.is_empty() {
        return Err(ReconError::Empty("every sample is an outlier"));
    }
    Ok(seeds)
}

/// The grid step of the depth, and the trimming `params` ask for at the scan's spacing.
pub(super) fn polygonisation_params(ctx: &ReconContext<'_>, seeds: &[DVec3]) -> PolygoniseParams {
    polygonisation_params_at(
        ctx.params,
        ctx.stats.depth,
        &ctx.scan,
        Aabb::from_points(seeds).diagonal(),
    )
}

/// [`polygonisation_params`] at `depth` for a scan measured as `scan`, with seeds whose
/// bounding box has the diagonal `seeds_diagonal`. A scan of one view is cut nearer its
/// samples ([`ONE_VIEW_NEAR`]) and keeps only pinholes ([`ONE_VIEW_REACH`]): it never saw a
/// closed object, so surface far from its samples is a shadow or what lies out of its
/// sight, not a hole.
pub(super) fn polygonisation_params_at(
    params: &ReconParams,
    depth: u32,
    scan: &ScanStatistics,
    seeds_diagonal: f64,
) -> PolygoniseParams {
    let spacing = scan.spacing;
    let near = if scan.one_view {
        ONE_VIEW_NEAR
    } else {
        UNSEEN_NEAR
    } * spacing;
    PolygoniseParams {
        step: GridStep::Absolute(1.0 / f64::from(1u32 << depth)),
        trim: match params.trim {
            Trim::Off | Trim::Unseen => None,
            Trim::SampleSpacings(m) => Some(m * spacing),
            Trim::Distance(d) => Some(d),
        },
        unseen: (params.trim == Trim::Unseen).then(|| UnseenTrim {
            near,
            reach: if scan.one_view {
                ONE_VIEW_REACH * spacing
            } else {
                (UNSEEN_REACH * seeds_diagonal).max(3.0 * spacing)
            },
        }),
        fill_pinholes: params.fill_pinholes,
        ..PolygoniseParams::default()
    }
}

/// The surface confidence at the vertices, and components far smaller than the largest
/// dropped.
fn clean(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    // Polygonisation blended the support confidence at the vertices already.
    if ctx.mesh.values.as_ref().map(Vec::len) != Some(ctx.mesh.vertices.len()) {
        let surface_confidence = blend_over_supports(
            ctx.cover(),
            &ctx.mesh.vertices,
            &ctx.confidence().support_confidence,
        )?;
        ctx.mesh.values = Some(
            surface_confidence
                .into_iter()
                .map(|v| v.unwrap_or(0.0))
                .collect(),
        );
    }
    let (small, topology) = drop_small_components(&mut ctx.mesh, ctx.params, |mesh, topology| {
        sample_votes(mesh, topology, &ctx.points, &ctx.scan.isolated)
    })?;
    let sheets =
        drop_unsupported_sheets(&mut ctx.mesh, &topology, &ctx.points, &ctx.scan.isolated)?;
    ctx.stats.dropped_components = small + sheets;
    // Neither the refinement nor the change of frame touches the triangles, so the topology
    // stays valid.
    ctx.unchanged_topology = Some(if sheets > 0 {
        MeshTopology::of(&ctx.mesh)
    } else {
        topology
    });
    if ctx.mesh.triangles.is_empty() {
        return Err(ReconError::Empty(
            "no surface was found near the confident samples",
        ));
    }
    Ok(())
}

/// The vertices moved onto quadrics fitted to the samples near them.
fn refine(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let Some(refine) = &ctx.params.refine else {
        return Ok(());
    };
    let conf = built(ctx.confidence.as_ref(), "sample confidence");
    let weights: Vec<f64> = conf
        .confidence
        .iter()
        .zip(&conf.outliers)
        .map(|(&c, &o)| if o { 0.0 } else { c })
        .collect();
    let samples = RefinementSamples {
        points: &ctx.points,
        normals: &ctx.normals,
        weights: &weights,
        index: built(ctx.index.as_ref(), "point index"),
    };
    let scale = RefinementScale {
        spacing: ctx.scan.spacing,
        step: 1.0 / f64::from(1u32 << ctx.stats.depth),
        noise_ratio: ctx.stats.eps / ctx.params.cover.eps,
    };
    ctx.stats.refinement = Some(refine_vertices(&mut ctx.mesh, &samples, &scale, refine)?);
    Ok(())
}

/// The colour of the nearest inlier sample at every vertex.
fn transfer_colors(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let Some(colors) = &ctx.cloud.colors else {
        return Ok(());
    };
    let sample_colors: Vec<[u8; 3]> = ctx.kept.iter().map(|&i| colors[i]).collect();
    let outliers = &built(ctx.confidence.as_ref(), "sample confidence").outliers;
    ctx.mesh.colors = Some(nearest_sample_colors(
        &ctx.mesh.vertices,
        ctx.index(),
        &sample_colors,
        outliers,
    ));
    Ok(())
}

/// The mesh in input coordinates, and its topology.
fn topology(ctx: &mut ReconContext<'_>) -> Result<(), ReconError> {
    let topology = ctx
        .unchanged_topology
        .take()
        .unwrap_or_else(|| MeshTopology::of(&ctx.mesh));
    let open_components = topology.open_component.iter().filter(|&&o| o).count();
    let object = if topology.components > 1 && open_components > 0 {
        object_component(&ctx.mesh, &topology, &ctx.points, &ctx.scan.isolated)?
    } else {
        Some(0).filter(|_| topology.components > 0)
    };
    ctx.mesh.to_input(&ctx.normalisation());
    record_topology(&mut ctx.stats, &ctx.mesh, &topology, object);
    Ok(())
}

/// The counts and topology of the finished `mesh` in `stats`; `object` is the component
/// the samples lie nearest to.
pub(super) fn record_topology(
    stats: &mut ReconStats,
    mesh: &TriMesh,
    topology: &MeshTopology,
    object: Option<usize>,
) {
    stats.triangles = mesh.triangles.len();
    stats.vertices = mesh.vertices.len();
    stats.components = topology.components;
    stats.watertight = topology.is_watertight();
    stats.open_components = topology.open_component.iter().filter(|&&o| o).count();
    stats.object_component_open = object.is_some_and(|c| topology.open_component[c]);
    stats.euler_characteristic = topology.euler_characteristic();
}
