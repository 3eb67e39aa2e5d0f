//! The skeletal-sheet pipeline (thesis §6.2): intensity cover (quadratic) → dual-complex
//! tetrahedral mesh → ridge points on its edges → patches → repairs, in world coordinates.
//!
//! The pipeline is two lists of stages: the front (`front_stages`: intensity model,
//! object mask, cover), which differs between volumes and scattered samples, and the stages
//! after the cover (`sheet_stages`), common to both, whose repairs [`SheetRepairs`] switches
//! one by one. [`stage_names`] lists them for a parameter set.

mod front_stages;
mod sheet_stages;

use sphcover_core::{
    Kernel, ParameterError, StageProgress, StageTimes, StopRequest, TriMesh, Volume,
    VolumeCoverStats, run_stages_until,
};

use crate::error::SkeletonError;
use crate::intensity_model::IntensityModel;
use crate::material::{MaterialChoice, MaterialReport, windowed_volume};
use crate::object_mask::ObjectMaskStats;
use crate::repair::SheetRepairs;
use crate::repair::cleaning::CleaningStats;
use crate::repair::perforations::VoxelPart;
use crate::repair::slice_centroids::ThickSlices;
use crate::resample::{ResampledGrid, resample_if_anisotropic};
use crate::ridge_points::RidgeFilter;
use crate::voxel_grid::measured_after_resampling;
pub(crate) use front_stages::{CoverStage, intensity_cover_params};
use front_stages::{VolumeFront, volume_front_stages};
pub(crate) use sheet_stages::sheet_stage_list;
use sheet_stages::{SheetContext, built};

/// Parameters of [`extract_skeleton`]. `Default` is the one parameter set the phantom
/// tests use; lengths given in voxels are converted with the volume's voxel size.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct SkeletonParams {
    /// Object voxels are those above this value (volume units, e.g. HU); `None`: the
    /// material's on a CT in Hounsfield units (see [`material`](Self::material)), otherwise
    /// the two-class threshold of [`IntensityModel`].
    pub threshold: Option<f64>,
    /// On a CT in Hounsfield units, the material whose mid-surface is wanted (see the
    /// [`Material`](crate::Material) list): chosen automatically as the first thin one, or
    /// given. The volume is then windowed to that material (a given threshold is windowed
    /// too). [`MaterialChoice::Off`] treats every volume as two classes.
    pub material: MaterialChoice,
    /// Fit tolerance ε of the cover (fraction of the value range); `None`: from the noise
    /// and contrast, see [`IntensityModel::tolerance`].
    pub tolerance: Option<f64>,
    /// The model part of the automatic tolerance, as a fraction of the contrast.
    pub model_tolerance: f64,
    /// Connected components of the object mask smaller than this fraction of the largest are
    /// noise specks and are dropped before the cover is built.
    pub min_object_fraction: f64,
    /// Above this noise level (standard deviation over contrast), object voxels must also
    /// exceed the threshold in the volume smoothed by one voxel (see
    /// [`drop_small_object_components`](crate::drop_small_object_components)). On a grid
    /// resampled from thick slices the level is divided by the resampling factor `k` (the
    /// largest over the axes): one slice's noise spans `k` resampled voxels along its axis,
    /// so a speck on a plate's face stands `k` voxels tall and grows a fin of its own. On
    /// the generated phantoms on 5:1 slices (`k` = 3, noise 0.085–0.124 of the contrast at
    /// 10 % noise) the T-junction's base plate came apart in fins at 10 % noise (coverage
    /// 0.50; 0.87 smoothed, seed 1) and the mean coverage of the table rose 0.891–0.914 →
    /// 0.913–0.927 over seeds 1–5; on 3:1 slices (`k` = 2, at most 0.098 at 10 %) nothing
    /// changes, and smoothing there regardless of the noise lost the true χ in three of
    /// five seeds' tables. The small perforations on every second slice (`k` = 2, 0.15 at
    /// 10 %) are smoothed now: the true χ at 10 % in 14 of 16 runs against 12.
    pub smooth_mask_noise: f64,
    /// Smallest support radius (world units); `None`: the voxel diagonal.
    pub r_min: Option<f64>,
    /// Largest support radius (world units); `None`: the object's maximum thickness.
    pub r_max: Option<f64>,
    /// Support expansion σ for the derivatives (thesis §6.2.2: 4).
    pub sigma: f64,
    /// Derivative smoothing (thesis §6.2.3, formulated in
    /// [`smoothed_vertex_derivatives`](crate::smoothed_vertex_derivatives)):
    /// `∇f` and `∇²f` take one implicit heat step over the supports' sphere intersection
    /// graph that smooths over this length (voxels) before the ridge test; `None` takes the
    /// derivatives as they are.
    pub derivative_smoothing_voxels: Option<f64>,
    /// On a grid resampled from slices more than twice as thick as its pixels, the Hessian
    /// is taken with the slice axis compressed ([`SliceStretch`](crate::SliceStretch)) for
    /// this in-plane blur of the derivatives (standard deviation, pixels); `None` takes it
    /// as it is.
    pub slice_blur_pixels: Option<f64>,
    /// Radius shrink σ_t of the tetrahedral mesh. The thesis uses 0.75 (§3.5.2) against
    /// skinny tetrahedra; on volume covers of thin plates (centres one voxel layer apart
    /// across a 3–5 voxel plate) the shrunk balls rarely meet four at a time, and the dual
    /// complex is too sparse to carry the sheet: measured on the reference phantoms, σ_t =
    /// 0.75 covers 11–29 % of the true sheet in 10–25 pieces, σ_t = 1 covers 99–100 %. So the
    /// default is 1.
    pub tet_shrink: f64,
    /// Which tetrahedra of the supports' regular triangulation carry the ridge patches.
    pub tet_complex: TetComplex,
    /// Weight kernel of the cover (C2, since Hessians are taken).
    pub kernel: Kernel,
    /// Filters on the ridge points.
    pub ridge: RidgeFilter,
    /// The repairs of the raw patches, each its own stage (see [`SheetRepairs`](crate::SheetRepairs)).
    pub repairs: SheetRepairs,
    /// Seed of the cover's centre order and the triangulation.
    pub seed: u64,
}

/// Which tetrahedra of the supports' regular triangulation (weights `(σ_t r)²`) form the
/// tetrahedral mesh whose edges carry the ridge points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TetComplex {
    /// [`TetComplex::OverlapInPart`] for a volume, [`TetComplex::Dual`] for scattered
    /// samples.
    #[default]
    Auto,
    /// The thesis's dual complex (§3.5): the four balls share a point.
    Dual,
    /// The four balls overlap pairwise (beyond the thesis;
    /// [`overlap_complex`](sphcover_tetra::overlap_complex())): a superset of the dual
    /// complex. Across a plate two or three voxels thick the supports form a slab whose
    /// tetrahedra are flat, and the dual complex keeps few of them, so the patches around the
    /// ridge edges stay open and the sheet comes apart. Measured on the generated T-junction
    /// (its web is 3 voxels thick) at 10 % noise: on slices 3 voxels thick, 3 components
    /// with the dual complex and 1 with this one; on cubic voxels its coverage goes from
    /// 0.994 to 1.000. Balls that overlap pairwise may still leave a hole between them,
    /// which the dual complex respects: on scattered samples (seven in ten voxels of the
    /// plate with a hole, 10 % noise) the sheet spans part of the hole with this complex
    /// (spurious share 0.030 against 0.003), so `Auto` keeps the dual complex there.
    Overlap,
    /// [`TetComplex::Overlap`] and, besides, the tetrahedra within the part whose balls
    /// overlap pairwise when grown to twice their radii (beyond the thesis;
    /// [`overlap_complex_admitting`](sphcover_tetra::overlap_complex_admitting())): a
    /// tetrahedron is within the part when the cover's function exceeds the part's level at
    /// its centroid. Where the slab of supports across a plate is thinner still (the
    /// T-junction's web on slices 3 voxels thick, resampled to 1.5 voxels), even the
    /// overlap complex leaves holes in the web: at noise 0 it came apart in 3 pieces
    /// (coverage 0.959), at 10 % coverage was 0.985; with these tetrahedra one piece each,
    /// 0.999 and 0.996. Without the test on the centroid the tetrahedra of the grown balls
    /// also span the holes through the plates (on those slices, the plate with a hole at
    /// 0–30 % noise: spurious share 0.09–0.14 against 0.001–0.004).
    OverlapInPart,
}

impl TetComplex {
    /// The complex to build, `Auto` resolved for a cover fitted to a voxel grid (`on_grid`)
    /// or to scattered samples.
    pub(crate) fn resolved(self, on_grid: bool) -> TetComplex {
        match self {
            TetComplex::Auto if on_grid => TetComplex::OverlapInPart,
            TetComplex::Auto => TetComplex::Dual,
            chosen => chosen,
        }
    }
}

impl Default for SkeletonParams {
    fn default() -> SkeletonParams {
        SkeletonParams {
            threshold: None,
            material: MaterialChoice::Auto,
            tolerance: None,
            model_tolerance: 0.05,
            min_object_fraction: 0.01,
            smooth_mask_noise: 0.2,
            r_min: None,
            r_max: None,
            sigma: 4.0,
            tet_shrink: 1.0,
            tet_complex: TetComplex::Auto,
            derivative_smoothing_voxels: Some(1.0),
            slice_blur_pixels: Some(1.1),
            kernel: Kernel::WendlandC2,
            ridge: RidgeFilter::default(),
            repairs: SheetRepairs::default(),
            seed: 0,
        }
    }
}

/// What [`extract_skeleton`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct SkeletonStats {
    /// The CT's materials and the one used, when the volume is a CT in Hounsfield units.
    pub material: Option<MaterialReport>,
    /// How the volume was resampled before the stages, its voxels being more than
    /// [`MAX_ANISOTROPY`](crate::MAX_ANISOTROPY) apart; `None` when the stages ran on the
    /// input grid (always for scattered samples). Lengths given in voxels are then in the
    /// resampled voxels.
    pub resampled: Option<ResampledGrid>,
    /// Threshold, levels and noise (of the windowed volume when a material was used).
    pub intensity: IntensityModel,
    /// The fit tolerance ε used (normalised units).
    pub tolerance: f64,
    /// Noise specks dropped from the object mask.
    pub object_mask: ObjectMaskStats,
    /// The volume cover's own statistics (radii bounds, thickness, supports).
    pub cover: VolumeCoverStats,
    /// Vertices of the tetrahedral mesh.
    pub mesh_vertices: usize,
    /// Tetrahedra.
    pub tetrahedra: usize,
    /// Edges of the tetrahedral mesh.
    pub edges: usize,
    /// Edges carrying a ridge point.
    pub ridge_points: usize,
    /// Triangles of the raw patches.
    pub raw_triangles: usize,
    /// What cleaning did (both passes, before and after rim trimming).
    pub cleaning: CleaningStats,
    /// Triangles removed by rim trimming.
    pub rim_triangles: usize,
    /// Large holes filled where the material is continuous.
    pub material_holes: usize,
    /// Holes filled in the sheets meeting at junctions.
    pub junction_holes: usize,
    /// Tunnels through material closed at junctions.
    pub tunnels: usize,
    /// Perforations of the part the sheet was cut open over.
    pub perforations: usize,
    /// Triangles of flaps across the sheet collapsed.
    pub flap_triangles: usize,
    /// Junction vertices folded onto a plate's tangent plane.
    pub junction_folded_vertices: usize,
    /// Vertices of junction bands projected onto a sheet's plane.
    pub junction_snapped_vertices: usize,
    /// Vertices inserted where two sheets' planes meet, splitting the edges from one to the
    /// other.
    pub junction_corner_vertices: usize,
    /// Vertices re-centred between the part's faces.
    pub centred_vertices: usize,
    /// Vertices moved to the centroid of the measured slices (volumes resampled from slices
    /// more than twice as thick as the pixels).
    pub slice_centred_vertices: usize,
    /// The factor by which the Hessian compressed the slice axis for the ridge test
    /// ([`SliceStretch`](crate::SliceStretch)), on volumes resampled from slices more than
    /// twice as thick as the pixels.
    pub hessian_slice_stretch: Option<f64>,
    /// The factor by which the rim test compressed the slice axis
    /// ([`RimTrimParams::slice_exponent`](crate::RimTrimParams::slice_exponent)), on the same
    /// volumes.
    pub rim_slice_stretch: Option<f64>,
    /// Triangles standing off the plates of thick slices collapsed (volumes resampled from
    /// slices more than twice as thick as the pixels).
    pub off_plate_triangles: usize,
    /// Triangles of the output.
    pub triangles: usize,
    /// Vertices of the output.
    pub vertices: usize,
    /// Connected components of the output.
    pub components: usize,
    /// Euler characteristic `V − E + F` of the output.
    pub euler_characteristic: i64,
    /// Wall time of each stage, in order.
    pub stages: StageTimes,
}

impl SkeletonStats {
    /// True when the automatic `r_max` was capped below the object's thickness, so thick
    /// parts may have been covered by balls too small to see their middle.
    pub fn thickness_exceeds_r_max(&self) -> bool {
        self.cover.thickness.is_some_and(|t| t > self.cover.r_max)
    }
}

/// Extracts the skeletal sheet of the thin object in `volume` as one shared-vertex
/// triangle mesh in world coordinates. Per-vertex values are the ridge strengths `−λ1`.
/// `progress` is told of each stage as it starts ([`stage_names`]).
///
/// A volume whose voxels are more than [`MAX_ANISOTROPY`](crate::MAX_ANISOTROPY) apart, up
/// to [`MAX_RESAMPLED_ANISOTROPY`](crate::MAX_RESAMPLED_ANISOTROPY), is first resampled along
/// its coarse axes ([`Resampling`](crate::Resampling), [`SkeletonStats::resampled`]). No grid
/// is refused here: [`check_voxel_grid`](crate::check_voxel_grid) says from the header which
/// grids the pipeline treats correctly (the others run as they are).
pub fn extract_skeleton(
    volume: &Volume,
    params: &SkeletonParams,
    progress: &(dyn Fn(StageProgress) + Sync),
) -> Result<(TriMesh, SkeletonStats), SkeletonError> {
    extract_skeleton_until(volume, params, progress, &StopRequest::new())
}

/// [`extract_skeleton`], ending with [`SkeletonError::Stopped`] before the first stage that
/// starts after `stop` was requested (for callers that cancel a run from another thread).
pub fn extract_skeleton_until(
    volume: &Volume,
    params: &SkeletonParams,
    progress: &(dyn Fn(StageProgress) + Sync),
    stop: &StopRequest,
) -> Result<(TriMesh, SkeletonStats), SkeletonError> {
    check_params(params)?;
    let resampled = resample_if_anisotropic(volume)?;
    let grid = resampled.as_ref().map_or(volume, |(grid, _)| grid);
    let front = volume_front_stages();
    let count = front.len() + sheet_stage_list(params).len();
    let factor = resampled.as_ref().map_or(1, |(_, record)| {
        record.resampling.factors.into_iter().max().unwrap_or(1)
    });
    let mut ctx = VolumeFront::new(grid, params, factor);
    let times = run_stages_until(&mut ctx, &front, &offset(progress, 0, count), stop)?;
    // Resampled voxels are interpolated between slices, not measured: a column across bone
    // that runs along 2.9 mm slices reads values that pass for air, and the perforation
    // repair opened two vault holes of 28 and 37 mm on the head CT's 3:1 grid.
    let measured = resampled
        .as_ref()
        .is_none_or(|(_, record)| measured_after_resampling(record.resampling.size))
        .then_some(grid);
    let front = ctx.finish()?;
    // The slice centroids read the slices as measured, on the threshold's scale.
    let slice_axis = resampled
        .as_ref()
        .filter(|_| measured.is_none())
        .and_then(|(_, record)| single_resampled_axis(record.resampling.factors));
    let window = front.material.as_ref().and_then(|m| m.window);
    let windowed = slice_axis.and(window).map(|w| windowed_volume(volume, w));
    let thick_slices = slice_axis.map(|axis| (windowed.as_ref().unwrap_or(volume), axis));
    let (sheet, mut stats) = sheet_from_cover(
        front,
        measured,
        thick_slices,
        true,
        times,
        params,
        progress,
        stop,
    )?;
    stats.resampled = resampled.map(|(_, record)| record);
    Ok((sheet, stats))
}

/// The voxel axis of a grid resampled along that axis alone.
fn single_resampled_axis(factors: [usize; 3]) -> Option<usize> {
    let mut axes = (0..3).filter(|&a| factors[a] > 1);
    axes.next().filter(|_| axes.next().is_none())
}

/// The names of the stages [`extract_skeleton`] (and
/// [`crate::extract_skeleton_from_samples`]) runs for `params`, in order.
pub fn stage_names(params: &SkeletonParams) -> Vec<&'static str> {
    let front = volume_front_stages().into_iter().map(|s| s.name);
    front
        .chain(sheet_stage_list(params).iter().map(|s| s.name))
        .collect()
}

/// `progress` for a list of stages that starts at position `first` of `count` in all.
pub(crate) fn offset<'p>(
    progress: &'p (dyn Fn(StageProgress) + Sync),
    first: usize,
    count: usize,
) -> impl Fn(StageProgress) + Sync + 'p {
    move |stage| {
        progress(StageProgress {
            index: first + stage.index,
            count,
            ..stage
        })
    }
}

/// Runs the stages after the cover, common to volumes and scattered samples, on the
/// product of the front stages (`front`, whose stages took `times`) and, for a volume read
/// as measured or resampled from slices at most 2:1, the grid the cover was fitted to; for
/// one resampled from thicker slices along one axis, the slices as measured (on the
/// threshold's scale) and that axis; `on_grid` when the cover was fitted to a voxel grid at
/// all.
pub(crate) fn sheet_from_cover(
    front: CoverStage,
    grid: Option<&Volume>,
    thick_slices: Option<(&Volume, usize)>,
    on_grid: bool,
    mut times: StageTimes,
    params: &SkeletonParams,
    progress: &(dyn Fn(StageProgress) + Sync),
    stop: &StopRequest,
) -> Result<(TriMesh, SkeletonStats), SkeletonError> {
    let CoverStage {
        material,
        intensity,
        tolerance,
        object_mask,
        cover_stats,
        voxel,
        cover,
    } = front;
    let stages = sheet_stage_list(params);
    let count = times.len() + stages.len();
    let mut ctx = SheetContext::new(
        params,
        &cover,
        cover_stats.threshold_normalised,
        cover_stats.r_max,
        voxel,
        params.tet_complex.resolved(on_grid),
        grid.map(|volume| VoxelPart {
            volume,
            threshold: intensity.threshold,
            background: intensity.background_level,
            noise: intensity.noise_std,
        }),
        thick_slices.map(|(volume, axis)| ThickSlices {
            volume,
            axis,
            threshold: intensity.threshold,
            background: intensity.background_level,
        }),
    );
    times.extend(run_stages_until(
        &mut ctx,
        &stages,
        &offset(progress, times.len(), count),
        stop,
    )?);
    let mesh = built(ctx.mesh.as_ref(), "tetrahedral mesh");
    let topology = built(ctx.topology.as_ref(), "topology");
    let repairs = &ctx.repairs;
    let stats = SkeletonStats {
        material,
        resampled: None,
        intensity,
        tolerance,
        object_mask,
        cover: cover_stats,
        mesh_vertices: mesh.vertices.len(),
        tetrahedra: mesh.tets.len(),
        edges: mesh.edges.len(),
        ridge_points: ctx.ridge_count,
        raw_triangles: ctx.raw_triangles,
        cleaning: repairs.cleaning,
        rim_triangles: repairs.rim_triangles,
        material_holes: repairs.material_holes,
        junction_holes: repairs.junction_holes,
        tunnels: repairs.tunnels,
        perforations: repairs.perforations,
        flap_triangles: repairs.flap_triangles,
        junction_folded_vertices: repairs.junction_folded_vertices,
        junction_snapped_vertices: repairs.junction_snapped_vertices,
        junction_corner_vertices: repairs.junction_corner_vertices,
        centred_vertices: repairs.centred_vertices,
        slice_centred_vertices: repairs.slice_centred_vertices,
        hessian_slice_stretch: ctx.hessian_slice_stretch,
        rim_slice_stretch: ctx.rim_slice_stretch,
        off_plate_triangles: repairs.off_plate_triangles,
        triangles: ctx.sheet.triangles.len(),
        vertices: ctx.sheet.vertices.len(),
        components: topology.components,
        euler_characteristic: topology.euler_characteristic(),
        stages: times,
    };
    Ok((ctx.sheet, stats))
}

/// The geometric mean of the voxel edge lengths: the length unit of the voxel-based
/// parameters.
pub(crate) fn voxel_length(volume: &Volume) -> f64 {
    let s = volume.voxel_size();
    (s.x * s.y * s.z).cbrt()
}

pub(crate) fn check_params(p: &SkeletonParams) -> Result<(), SkeletonError> {
    let bad = |name, value, reason| {
        Err(SkeletonError::InvalidParameter(ParameterError {
            name,
            value,
            expected: reason,
        }))
    };
    if !(p.sigma.is_finite() && p.sigma >= 1.0) {
        return bad("sigma", p.sigma, "must be at least 1");
    }
    if !(p.tet_shrink.is_finite() && p.tet_shrink > 0.0 && p.tet_shrink <= 1.0) {
        return bad("tet_shrink", p.tet_shrink, "must lie in (0, 1]");
    }
    if let Some(t) = p.tolerance
        && !(t.is_finite() && t > 0.0)
    {
        return bad("tolerance", t, "must be finite and positive");
    }
    if !(p.model_tolerance.is_finite() && p.model_tolerance > 0.0) {
        return bad("model_tolerance", p.model_tolerance, "must be positive");
    }
    for (name, value) in [
        ("min_relative_strength", p.ridge.min_relative_strength),
        ("max_eigen_ratio", p.ridge.max_eigen_ratio),
        ("min_object_fraction", p.min_object_fraction),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return bad(name, value, "must be finite and non-negative");
        }
    }
    if let Some(v) = p.derivative_smoothing_voxels
        && !(v.is_finite() && v > 0.0)
    {
        return bad(
            "derivative_smoothing_voxels",
            v,
            "must be finite and positive",
        );
    }
    check_repairs(&p.repairs)?;
    Ok(())
}

/// The repairs' parameters: lengths and fractions finite and non-negative, and the junction
/// fold only with the centring it builds on.
fn check_repairs(r: &SheetRepairs) -> Result<(), SkeletonError> {
    let c = &r.cleaning;
    let mut values = vec![
        ("cleaning.min_component_fraction", c.min_component_fraction),
        (
            "cleaning.min_component_area_voxels",
            c.min_component_area_voxels,
        ),
        (
            "cleaning.max_hole_perimeter_voxels",
            c.max_hole_perimeter_voxels,
        ),
    ];
    if let Some(t) = &r.rim_trimming {
        values.push(("rim_trimming.factor", t.factor));
        values.push(("rim_trimming.step_voxels", t.step_voxels));
        if let Some(a) = t.keep_pieces_voxels {
            values.push(("rim_trimming.keep_pieces_voxels", a));
        }
    }
    if let Some(h) = &r.material_holes {
        values.push((
            "material_holes.max_perimeter_voxels",
            h.max_perimeter_voxels,
        ));
        values.push(("material_holes.step_voxels", h.step_voxels));
        values.push(("material_holes.on_sheet_voxels", h.on_sheet_voxels));
    }
    if let Some(h) = &r.junction_holes {
        values.push(("junction_holes.min_angle_degrees", h.min_angle_degrees));
        values.push((
            "junction_holes.max_perimeter_voxels",
            h.max_perimeter_voxels,
        ));
    }
    if let Some(t) = &r.tunnels {
        values.push(("tunnels.max_perimeter_voxels", t.max_perimeter_voxels));
    }
    if let Some(f) = &r.flaps {
        values.push(("flaps.min_alignment", f.min_alignment));
    }
    if let Some(c) = &r.centring {
        values.push(("centring.max_shift_voxels", c.max_shift_voxels));
        values.push(("centring.step_voxels", c.step_voxels));
    }
    if let Some(f) = &r.junction_fold {
        values.push(("junction_fold.reach_voxels", f.reach_voxels));
        values.push(("junction_fold.step_voxels", f.step_voxels));
    }
    if let Some(j) = &r.junction_planes {
        values.push(("junction_planes.reach_voxels", j.reach_voxels));
        values.push(("junction_planes.max_shift_voxels", j.max_shift_voxels));
        values.push(("junction_planes.min_angle_degrees", j.min_angle_degrees));
        values.push((
            "junction_planes.max_ring_angle_degrees",
            j.max_ring_angle_degrees,
        ));
        values.push((
            "junction_planes.max_fit_angle_degrees",
            j.max_fit_angle_degrees,
        ));
    }
    if let Some(s) = &r.slice_centroids {
        values.push(("slice_centroids.min_axis_cosine", s.min_axis_cosine));
        values.push(("slice_centroids.max_shift_slices", s.max_shift_slices));
        values.push((
            "slice_centroids.max_off_plate_pixels",
            s.max_off_plate_pixels,
        ));
    }
    if let Some(s) = &r.smoothing {
        values.push(("smoothing.lambda", s.lambda));
    }
    for (name, value) in values {
        if !(value.is_finite() && value >= 0.0) {
            return Err(SkeletonError::InvalidParameter(ParameterError {
                name,
                value,
                expected: "must be finite and non-negative",
            }));
        }
    }
    // A march that never advances would not end.
    let steps = [
        r.rim_trimming
            .map(|t| ("rim_trimming.step_voxels", t.step_voxels)),
        r.centring.map(|c| ("centring.step_voxels", c.step_voxels)),
        r.junction_fold
            .map(|f| ("junction_fold.step_voxels", f.step_voxels)),
    ];
    for (name, step) in steps.into_iter().flatten() {
        if step <= 0.0 {
            return Err(SkeletonError::InvalidParameter(ParameterError {
                name,
                value: step,
                expected: "must be positive",
            }));
        }
    }
    if r.junction_fold.is_some() && r.centring.is_none() {
        return Err(SkeletonError::InvalidParameter(ParameterError {
            name: "junction_fold",
            value: 1.0,
            expected: "folds junction vertices onto re-centred ones: it needs the centring",
        }));
    }
    Ok(())
}
