//! The skeletal-sheet pipeline (thesis §6.2): intensity cover (quadratic) → dual-complex
//! tetrahedral mesh → ridge points on its edges → patches → cleaning, in world coordinates.

use std::time::{Duration, Instant};

use sphcover_core::mesh_topology::MeshTopology;
use sphcover_core::{
    Cover, DVec3, Kernel, PuEvaluator, Threshold, TriMesh, Volume, VolumeCoverParams,
    VolumeCoverStats, build_volume_cover,
};
use sphcover_tetra::{DualComplexParams, TetMesh, TetraError, dual_complex};

use crate::cleaning::{CleaningParams, CleaningStats, clean_sheet};
use crate::derivative_smoothing::smoothed_vertex_derivatives;
use crate::error::SkeletonError;
use crate::flaps::collapse_misaligned_flaps;
use crate::gaussian_filter::smoothed_values;
use crate::intensity_model::{IntensityModel, estimate_intensity_model};
use crate::junction_holes::{SheetHoleParams, fill_holes_within_sheets};
use crate::junction_planes::{JunctionPlaneParams, snap_to_junction_planes};
use crate::medial_correction::{centre_between_faces, fold_junction_vertices};
use crate::object_mask::{ObjectMaskStats, drop_small_object_components};
use crate::patches::ridge_patches;
use crate::ridge_points::{RidgeFilter, orient_eigenvectors, ridge_points, vertex_derivatives};
use crate::rim_trimming::{RimTrimParams, trim_rims};
use crate::sheet_smoothing::smooth_across;
use crate::tunnels::{TunnelParams, close_material_tunnels};

/// Parameters of [`extract_skeleton`]. `Default` is the one parameter set the phantom
/// tests use; lengths given in voxels are converted with the volume's voxel size.
#[derive(Clone, Debug, PartialEq)]
pub struct SkeletonParams {
    /// Object voxels are those above this value (volume units, e.g. HU); `None`: Otsu.
    pub threshold: Option<f64>,
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
    /// [`crate::object_mask`]).
    pub smooth_mask_noise: f64,
    /// Smallest support radius (world units); `None`: the voxel diagonal.
    pub r_min: Option<f64>,
    /// Largest support radius (world units); `None`: the object's maximum thickness.
    pub r_max: Option<f64>,
    /// Support expansion σ for the derivatives (thesis §6.2.2: 4).
    pub sigma: f64,
    /// Derivative smoothing (thesis §6.2.3, formulated in [`crate::derivative_smoothing`]):
    /// `∇f` and `∇²f` take one implicit heat step over the supports' sphere intersection
    /// graph that smooths over this length (voxels) before the ridge test; 0 disables it.
    pub derivative_smoothing_voxels: f64,
    /// Radius shrink σ_t of the tetrahedral mesh. The thesis uses 0.75 (§3.5.2) against
    /// skinny tetrahedra; on volume covers of thin plates (centres one voxel layer apart
    /// across a 3–5 voxel plate) the shrunk balls rarely meet four at a time, and the dual
    /// complex is too sparse to carry the sheet: measured on the reference phantoms, σ_t =
    /// 0.75 covers 11–29 % of the true sheet in 10–25 pieces, σ_t = 1 covers 99–100 %. So the
    /// default is 1.
    pub tet_shrink: f64,
    /// Weight kernel of the cover (C2, since Hessians are taken).
    pub kernel: Kernel,
    /// Filters on the ridge points.
    pub ridge: RidgeFilter,
    /// Components whose strength-weighted area is below this fraction of the largest one's
    /// are dropped.
    pub min_component_fraction: f64,
    /// Components smaller than this many voxel areas are dropped.
    pub min_component_area_voxels: f64,
    /// Rim trimming: a sheet vertex is in the rim when the object's surface lies closer than
    /// this factor times the local half-thickness along the sheet; `0` disables trimming.
    pub rim_trim_factor: f64,
    /// Pieces of the sheet of at least this area (voxel²) that rim trimming would cut off
    /// stay joined to the rest (see [`trim_rims`]); infinity disables this.
    pub min_rim_piece_voxels: f64,
    /// Largest shift (voxels) of a vertex re-centred between the part's two faces (see
    /// [`crate::medial_correction`]); 0 disables re-centring.
    pub max_centring_shift_voxels: f64,
    /// Rounds of smoothing across the sheet (see [`crate::sheet_smoothing`]); 0 disables it.
    /// Off by default: on the 10 % phantoms three rounds lower the 95th-percentile distance
    /// of flat plates (0.23 → 0.19 voxel) but raise it at the T-junction (0.45 → 0.52) and on
    /// the spherical cap (0.32 → 0.37), where the umbrella step pulls towards chords.
    pub smoothing_rounds: usize,
    /// Filling holes of the sheets meeting at a junction (see [`crate::junction_holes`]):
    /// triangles whose planes meet at less than this angle (degrees) belong to one sheet; 0
    /// disables the step.
    pub junction_angle_degrees: f64,
    /// Vertices where the part's faces are not both found along `±e` (junctions) are
    /// projected onto the tangent plane of the nearest re-centred vertex within this
    /// distance (voxels; see [`fold_junction_vertices`]); 0 disables it. Measured
    /// (`phantom_table`, seed 1): T-junction p95 away from the rim 0.41 → 0.40, 0.46 → 0.43,
    /// 0.40 → 0.36 at 0, 10, 30 % noise, no other phantom worse.
    pub junction_fold_reach_voxels: f64,
    /// Vertices in the band where two sheets meet are projected onto the nearest of the
    /// planes fitted to the sheets' plate vertices within this distance (voxels; see
    /// [`crate::junction_planes`]); 0 disables the step.
    pub junction_plane_reach_voxels: f64,
    /// Largest move (voxels) of a vertex onto a junction plane.
    pub junction_plane_max_shift_voxels: f64,
    /// Loops of the sheet through its junctions that bound nothing but go around material
    /// only, up to this perimeter (voxels), are closed (see [`crate::tunnels`]); 0 disables
    /// the step.
    pub max_tunnel_perimeter_voxels: f64,
    /// Flaps whose triangles' normals make `|cos|` below this with their corners' across
    /// directions are collapsed from their free edges (see [`crate::flaps`]); 0 disables it.
    pub min_flap_alignment: f64,
    /// Closed pockets of the sheet are opened before tunnels are closed (see
    /// [`crate::tunnels::remove_closed_pockets`]).
    pub remove_pockets: bool,
    /// Holes with at most this many edges…
    pub max_hole_edges: usize,
    /// …and at most this perimeter (voxels) are filled.
    pub max_hole_perimeter_voxels: f64,
    /// Seed of the cover's centre order and the triangulation.
    pub seed: u64,
}

impl Default for SkeletonParams {
    fn default() -> SkeletonParams {
        SkeletonParams {
            threshold: None,
            tolerance: None,
            model_tolerance: 0.05,
            min_object_fraction: 0.01,
            smooth_mask_noise: 0.2,
            r_min: None,
            r_max: None,
            sigma: 4.0,
            tet_shrink: 1.0,
            derivative_smoothing_voxels: 1.0,
            kernel: Kernel::WendlandC2,
            ridge: RidgeFilter::default(),
            min_component_fraction: 0.05,
            min_component_area_voxels: 4.0,
            rim_trim_factor: 0.9,
            min_rim_piece_voxels: 16.0,
            max_centring_shift_voxels: 2.0,
            smoothing_rounds: 0,
            junction_angle_degrees: 45.0,
            junction_fold_reach_voxels: 4.0,
            junction_plane_reach_voxels: 9.0,
            junction_plane_max_shift_voxels: 2.0,
            max_tunnel_perimeter_voxels: 24.0,
            min_flap_alignment: 0.8,
            remove_pockets: true,
            max_hole_edges: 200,
            max_hole_perimeter_voxels: 60.0,
            seed: 0,
        }
    }
}

/// Time spent in each stage.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkeletonTimings {
    /// Histogram, threshold and noise estimate.
    pub intensity_model: Duration,
    /// Dropping noise specks from the object mask.
    pub object_mask: Duration,
    /// The volume cover (including its distance transform).
    pub cover: Duration,
    /// Regular triangulation, dual complex, edges and rings.
    pub tetrahedral_mesh: Duration,
    /// `∇f` and `∇²f` at the mesh vertices, with their eigen-decomposition.
    pub derivatives: Duration,
    /// Ridge points on the edges.
    pub ridge_points: Duration,
    /// Patches.
    pub patches: Duration,
    /// Cleaning.
    pub cleaning: Duration,
}

impl SkeletonTimings {
    /// The stages with their names, in pipeline order.
    pub fn stages(&self) -> [(&'static str, Duration); 8] {
        [
            ("intensity model", self.intensity_model),
            ("object mask", self.object_mask),
            ("volume cover", self.cover),
            ("tetrahedral mesh", self.tetrahedral_mesh),
            ("derivatives", self.derivatives),
            ("ridge points", self.ridge_points),
            ("patches", self.patches),
            ("cleaning", self.cleaning),
        ]
    }

    /// Sum of the stages.
    pub fn total(&self) -> Duration {
        self.stages().iter().map(|(_, d)| *d).sum()
    }
}

/// What [`extract_skeleton`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct SkeletonStats {
    /// Threshold, levels and noise.
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
    /// Holes filled in the sheets meeting at junctions.
    pub junction_holes: usize,
    /// Tunnels through material closed at junctions.
    pub tunnels: usize,
    /// Triangles of flaps across the sheet collapsed.
    pub flap_triangles: usize,
    /// Junction vertices folded onto a plate's tangent plane.
    pub junction_folded_vertices: usize,
    /// Vertices of junction bands projected onto a sheet's plane.
    pub junction_snapped_vertices: usize,
    /// Vertices re-centred between the part's faces.
    pub centred_vertices: usize,
    /// Triangles of the output.
    pub triangles: usize,
    /// Vertices of the output.
    pub vertices: usize,
    /// Connected components of the output.
    pub components: usize,
    /// Euler characteristic `V − E + F` of the output.
    pub euler_characteristic: i64,
    /// Stage timings.
    pub timings: SkeletonTimings,
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
pub fn extract_skeleton(
    volume: &Volume,
    params: &SkeletonParams,
) -> Result<(TriMesh, SkeletonStats), SkeletonError> {
    check_params(params)?;
    let mut timings = SkeletonTimings::default();

    let start = Instant::now();
    let intensity = estimate_intensity_model(volume, params.threshold)?;
    let tolerance = params
        .tolerance
        .unwrap_or_else(|| intensity.tolerance(params.model_tolerance));
    timings.intensity_model = start.elapsed();

    let start = Instant::now();
    let smooth = (intensity.noise_std > params.smooth_mask_noise * intensity.contrast().abs())
        .then(|| smoothed_values(volume, 1.0, intensity.value_range.0));
    let (cleaned, mask) = drop_small_object_components(
        volume,
        intensity.threshold,
        params.min_object_fraction,
        smooth.as_deref(),
    );
    drop(smooth);
    let volume = cleaned.as_ref().unwrap_or(volume);
    timings.object_mask = start.elapsed();

    let start = Instant::now();
    let cover_params = intensity_cover_params(params, &intensity, tolerance);
    let (cover, cover_stats) = build_volume_cover(volume, &cover_params)?;
    timings.cover = start.elapsed();
    let front = CoverStage {
        intensity,
        tolerance,
        object_mask: mask,
        cover: cover_stats,
        voxel: voxel_length(volume),
        timings,
    };
    sheet_from_cover(cover, front, params)
}

/// The intensity cover's parameters: the model's threshold, the tolerance ε, and the
/// caller's radii, kernel and seed.
pub(crate) fn intensity_cover_params(
    params: &SkeletonParams,
    intensity: &IntensityModel,
    tolerance: f64,
) -> VolumeCoverParams {
    VolumeCoverParams {
        threshold: Threshold::Raw(intensity.threshold),
        tolerance,
        r_min: params.r_min,
        r_max: params.r_max,
        kernel: params.kernel,
        seed: params.seed,
        // The sheet needs the dense thesis cover: without its redundant supports the dual
        // complex is too sparse (measured on the phantoms: coverage 0.64–0.81, 8–36 pieces).
        elimination: sphcover_core::Elimination::Off,
        ..VolumeCoverParams::default()
    }
}

/// What the stages up to the cover produced, for [`sheet_from_cover`].
pub(crate) struct CoverStage {
    pub intensity: IntensityModel,
    pub tolerance: f64,
    pub object_mask: ObjectMaskStats,
    pub cover: VolumeCoverStats,
    /// The length unit of the voxel-based parameters (world units).
    pub voxel: f64,
    pub timings: SkeletonTimings,
}

/// The stages after the intensity cover, common to volumes and scattered samples:
/// tetrahedral mesh, ridge points, patches and cleaning.
pub(crate) fn sheet_from_cover(
    cover: Cover,
    front: CoverStage,
    params: &SkeletonParams,
) -> Result<(TriMesh, SkeletonStats), SkeletonError> {
    let CoverStage {
        intensity,
        tolerance,
        object_mask: mask,
        cover: cover_stats,
        voxel,
        mut timings,
    } = front;
    let start = Instant::now();
    let complex = dual_complex(
        cover.centers(),
        cover.radii(),
        &DualComplexParams {
            shrink: params.tet_shrink,
            seed: params.seed,
        },
    )
    .map_err(|e| match e {
        TetraError::NotFullDimensional { .. } => SkeletonError::EmptyResult {
            stage: "the tetrahedral mesh",
            hint: "the object's supports do not span 3D: it is a speck or a single layer of voxels; check the threshold",
        },
        e => SkeletonError::Tetra(e),
    })?;
    let mesh = TetMesh::from_dual_complex(&complex);
    drop(complex);
    timings.tetrahedral_mesh = start.elapsed();
    if mesh.tets.is_empty() {
        return Err(SkeletonError::EmptyResult {
            stage: "the tetrahedral mesh",
            hint: "the object is too small or too thin for the cover; check the threshold",
        });
    }

    let start = Instant::now();
    let evaluator = PuEvaluator::new(&cover, params.sigma)?;
    let positions: Vec<DVec3> = mesh
        .vertices
        .iter()
        .map(|&s| cover.centers()[s as usize])
        .collect();
    let mut derivatives = if params.derivative_smoothing_voxels > 0.0 {
        let radii: Vec<f64> = mesh
            .vertices
            .iter()
            .map(|&s| cover.radii()[s as usize])
            .collect();
        let length = params.derivative_smoothing_voxels * voxel;
        smoothed_vertex_derivatives(&evaluator, &positions, &radii, 0.5 * length * length)?
    } else {
        vertex_derivatives(&evaluator, &positions)
    };
    drop(evaluator);
    orient_eigenvectors(&mesh, &mut derivatives);
    timings.derivatives = start.elapsed();

    let start = Instant::now();
    let ridge = ridge_points(&mesh, &derivatives, &params.ridge);
    let ridge_count = ridge.iter().flatten().count();
    timings.ridge_points = start.elapsed();
    if ridge_count == 0 {
        return Err(SkeletonError::EmptyResult {
            stage: "the ridge detection",
            hint: "no intensity ridge inside the object; is the object brighter than the background?",
        });
    }

    let start = Instant::now();
    let raw = ridge_patches(&mesh, &ridge);
    timings.patches = start.elapsed();

    let start = Instant::now();
    let cleaning_params = CleaningParams {
        min_component_fraction: params.min_component_fraction,
        min_component_area: params.min_component_area_voxels * voxel * voxel,
        max_hole_edges: params.max_hole_edges,
        max_hole_perimeter: params.max_hole_perimeter_voxels * voxel,
    };
    let plain = PuEvaluator::new(&cover, 1.0)?;
    let level = cover_stats.threshold_normalised;
    let is_material = |x: DVec3| plain.value(x).is_some_and(|v| v > level);
    let (mut sheet, mut cleaning) = clean_sheet(&raw, &cleaning_params, is_material);
    let mut rim_triangles = 0;
    if params.rim_trim_factor > 0.0 {
        let trim = RimTrimParams {
            surface_level: level,
            step: 0.25 * voxel,
            max_half_thickness: cover_stats.r_max,
            factor: params.rim_trim_factor,
        };
        let (trimmed, removed) = trim_rims(
            &sheet,
            &plain,
            &trim,
            params.min_rim_piece_voxels * voxel * voxel,
        );
        rim_triangles = removed;
        let (again, second) = clean_sheet(&trimmed, &cleaning_params, is_material);
        cleaning.welded_vertices += second.welded_vertices;
        cleaning.degenerate_triangles += second.degenerate_triangles;
        cleaning.dropped_components += second.dropped_components;
        cleaning.dropped_triangles += second.dropped_triangles;
        cleaning.holes_filled += second.holes_filled;
        cleaning.pinch_triangles += second.pinch_triangles;
        sheet = again;
    }
    let mut junction_holes = 0;
    if params.junction_angle_degrees > 0.0 {
        let holes = SheetHoleParams {
            min_angle: params.junction_angle_degrees.to_radians(),
            max_perimeter: params.max_hole_perimeter_voxels * voxel,
        };
        junction_holes = fill_holes_within_sheets(&mut sheet, &holes, is_material);
    }
    let mut tunnels = 0;
    if params.max_tunnel_perimeter_voxels > 0.0 {
        let tunnel_params = TunnelParams {
            max_perimeter: params.max_tunnel_perimeter_voxels * voxel,
            max_tunnels: 10_000,
            remove_pockets: params.remove_pockets,
        };
        tunnels = close_material_tunnels(&mut sheet, &tunnel_params, is_material);
    }
    let mut flap_triangles = 0;
    if params.min_flap_alignment > 0.0 {
        flap_triangles = collapse_misaligned_flaps(&mut sheet, params.min_flap_alignment);
    }
    let mut centred = 0;
    let mut folded = 0;
    if params.max_centring_shift_voxels > 0.0 {
        let trim = RimTrimParams {
            surface_level: level,
            step: 0.25 * voxel,
            max_half_thickness: cover_stats.r_max,
            factor: params.rim_trim_factor,
        };
        centred = centre_between_faces(
            &mut sheet,
            &plain,
            &trim,
            params.max_centring_shift_voxels * voxel,
        );
        if params.junction_fold_reach_voxels > 0.0 {
            folded = fold_junction_vertices(
                &mut sheet,
                &plain,
                &trim,
                params.junction_fold_reach_voxels * voxel,
            );
        }
    }
    let mut snapped = 0;
    if params.junction_plane_reach_voxels > 0.0 {
        let planes = JunctionPlaneParams {
            reach: params.junction_plane_reach_voxels * voxel,
            min_angle: 60f64.to_radians(),
            max_ring_angle: 20f64.to_radians(),
            max_fit_angle: 10f64.to_radians(),
            min_group: 6,
            max_shift: params.junction_plane_max_shift_voxels * voxel,
        };
        snapped = snap_to_junction_planes(&mut sheet, &planes);
    }
    smooth_across(&mut sheet, params.smoothing_rounds, 0.5);
    let topology = MeshTopology::of(&sheet);
    timings.cleaning = start.elapsed();
    if sheet.triangles.is_empty() {
        return Err(SkeletonError::EmptyResult {
            stage: "patching and cleaning",
            hint: "the ridge points form no surface",
        });
    }

    let stats = SkeletonStats {
        intensity,
        tolerance,
        object_mask: mask,
        cover: cover_stats,
        mesh_vertices: mesh.vertices.len(),
        tetrahedra: mesh.tets.len(),
        edges: mesh.edges.len(),
        ridge_points: ridge_count,
        raw_triangles: raw.triangles.len(),
        cleaning,
        rim_triangles,
        junction_holes,
        tunnels,
        flap_triangles,
        junction_folded_vertices: folded,
        junction_snapped_vertices: snapped,
        centred_vertices: centred,
        triangles: sheet.triangles.len(),
        vertices: sheet.vertices.len(),
        components: topology.components,
        euler_characteristic: topology.euler_characteristic(),
        timings,
    };
    Ok((sheet, stats))
}

/// The geometric mean of the voxel edge lengths: the length unit of the voxel-based
/// parameters.
pub fn voxel_length(volume: &Volume) -> f64 {
    let s = volume.voxel_size();
    (s.x * s.y * s.z).cbrt()
}

pub(crate) fn check_params(p: &SkeletonParams) -> Result<(), SkeletonError> {
    let bad = |name, value, reason| {
        Err(SkeletonError::InvalidParameter {
            name,
            value,
            reason,
        })
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
    if p.min_rim_piece_voxels.is_nan() || p.min_rim_piece_voxels < 0.0 {
        return bad(
            "min_rim_piece_voxels",
            p.min_rim_piece_voxels,
            "must be non-negative (infinite disables)",
        );
    }
    if !(p.model_tolerance.is_finite() && p.model_tolerance > 0.0) {
        return bad("model_tolerance", p.model_tolerance, "must be positive");
    }
    for (name, value) in [
        ("min_relative_strength", p.ridge.min_relative_strength),
        ("max_eigen_ratio", p.ridge.max_eigen_ratio),
        ("min_component_fraction", p.min_component_fraction),
        ("min_object_fraction", p.min_object_fraction),
        ("rim_trim_factor", p.rim_trim_factor),
        ("derivative_smoothing_voxels", p.derivative_smoothing_voxels),
        ("min_component_area_voxels", p.min_component_area_voxels),
        ("max_hole_perimeter_voxels", p.max_hole_perimeter_voxels),
        ("max_centring_shift_voxels", p.max_centring_shift_voxels),
        ("junction_angle_degrees", p.junction_angle_degrees),
        ("junction_fold_reach_voxels", p.junction_fold_reach_voxels),
        ("junction_plane_reach_voxels", p.junction_plane_reach_voxels),
        (
            "junction_plane_max_shift_voxels",
            p.junction_plane_max_shift_voxels,
        ),
        ("max_tunnel_perimeter_voxels", p.max_tunnel_perimeter_voxels),
        ("min_flap_alignment", p.min_flap_alignment),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return bad(name, value, "must be finite and non-negative");
        }
    }
    Ok(())
}
