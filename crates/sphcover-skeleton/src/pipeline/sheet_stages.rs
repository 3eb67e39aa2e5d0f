//! The stages after the intensity cover, common to volumes and scattered samples:
//! tetrahedral mesh, derivatives, ridge points, patches and the repairs of
//! [`crate::repair`], over one [`SheetContext`].

use sphcover_core::{Cover, DVec3, MeshTopology, PuEvaluator, Stage, TriMesh};
use sphcover_tetra::{
    DualComplexParams, TetMesh, TetraError, dual_complex, overlap_complex,
    overlap_complex_admitting,
};

use super::{SkeletonParams, TetComplex};
use crate::derivative_smoothing::smoothed_vertex_derivatives;
use crate::error::SkeletonError;
use crate::patches::ridge_patches;
use crate::repair::cleaning::{CleaningStats, clean_sheet};
use crate::repair::flaps::collapse_misaligned_flaps;
use crate::repair::junction_holes::fill_holes_within_sheets;
use crate::repair::junction_planes::snap_to_junction_planes;
use crate::repair::material_holes::fill_material_holes;
use crate::repair::medial_correction::{centre_between_faces, fold_junction_vertices};
use crate::repair::part_surface::PartSurface;
use crate::repair::perforations::{VoxelPart, cut_perforations, over_little_material};
use crate::repair::rim_trimming::trim_rims;
use crate::repair::sheet_smoothing::smooth_across;
use crate::repair::slice_centroids::{
    ThickSlices, centre_on_slice_centroids, collapse_off_plate_triangles,
};
use crate::repair::tunnels::close_material_tunnels;
use crate::ridge_points::{
    RidgePoint, VertexDerivatives, orient_eigenvectors, ridge_points, vertex_derivatives,
};
use crate::slice_stretch::SliceStretch;

/// A stage after the cover.
pub(crate) type SheetStage<'c> = Stage<SheetContext<'c>, SkeletonError>;

/// What the repairs did, for [`super::SkeletonStats`].
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct RepairCounts {
    pub cleaning: CleaningStats,
    pub rim_triangles: usize,
    pub material_holes: usize,
    pub junction_holes: usize,
    pub tunnels: usize,
    pub perforations: usize,
    pub flap_triangles: usize,
    pub centred_vertices: usize,
    pub slice_centred_vertices: usize,
    pub off_plate_triangles: usize,
    pub junction_folded_vertices: usize,
    pub junction_snapped_vertices: usize,
    pub junction_corner_vertices: usize,
}

/// What the stages after the cover share.
pub(crate) struct SheetContext<'c> {
    pub params: &'c SkeletonParams,
    pub cover: &'c Cover,
    /// The part's surface level in the cover's (normalised) units.
    pub level: f64,
    /// The cover's largest support radius: how far the part's faces are searched.
    pub r_max: f64,
    /// The length unit of the voxel-based parameters (world units).
    pub voxel: f64,
    /// The tetrahedral mesh's complex (resolved: never `Auto`).
    pub complex: TetComplex,
    /// The voxels of the part, for a volume.
    pub voxels: Option<VoxelPart<'c>>,
    /// The slices as measured, for a volume resampled from slices more than twice as thick
    /// as its pixels.
    pub slices: Option<ThickSlices<'c>>,
    pub mesh: Option<TetMesh>,
    pub derivatives: Vec<Option<VertexDerivatives>>,
    pub ridge: Vec<Option<RidgePoint>>,
    pub ridge_count: usize,
    /// The factor by which the Hessian compressed the slice axis of thick slices.
    pub hessian_slice_stretch: Option<f64>,
    /// The factor by which the rim test compressed it.
    pub rim_slice_stretch: Option<f64>,
    pub raw_triangles: usize,
    /// The cover's function with σ = 1, which the repairs probe (from the tetrahedral mesh
    /// of [`TetComplex::OverlapInPart`] or the first repair on).
    pub function: Option<PuEvaluator<'c>>,
    /// The raw patches, then the sheet as each repair leaves it.
    pub sheet: TriMesh,
    pub repairs: RepairCounts,
    /// Cleaning passes run so far.
    pub cleaning_passes: usize,
    pub topology: Option<MeshTopology>,
}

impl<'c> SheetContext<'c> {
    pub fn new(
        params: &'c SkeletonParams,
        cover: &'c Cover,
        level: f64,
        r_max: f64,
        voxel: f64,
        complex: TetComplex,
        voxels: Option<VoxelPart<'c>>,
        slices: Option<ThickSlices<'c>>,
    ) -> SheetContext<'c> {
        SheetContext {
            params,
            cover,
            level,
            r_max,
            voxel,
            complex,
            voxels,
            slices,
            mesh: None,
            derivatives: Vec::new(),
            ridge: Vec::new(),
            ridge_count: 0,
            hessian_slice_stretch: None,
            rim_slice_stretch: None,
            raw_triangles: 0,
            function: None,
            sheet: TriMesh::default(),
            repairs: RepairCounts::default(),
            cleaning_passes: 0,
            topology: None,
        }
    }

    fn mesh(&self) -> &TetMesh {
        built(self.mesh.as_ref(), "tetrahedral mesh")
    }
}

/// The part's surface from the context's fields, for the repairs that probe it (a method
/// would borrow the whole context, beside the sheet the repairs change).
fn part<'a>(function: &'a Option<PuEvaluator<'a>>, level: f64, r_max: f64) -> PartSurface<'a> {
    PartSurface {
        function: built(function.as_ref(), "cover function"),
        level,
        max_half_thickness: r_max,
    }
}

/// An intermediate that an earlier stage of the list builds. Every stage list is run by the
/// tests, so a missing one is a bug in [`sheet_stage_list`], not something input can cause.
pub(super) fn built<T>(slot: Option<T>, what: &str) -> T {
    slot.unwrap_or_else(|| panic!("the stage list builds the {what} before it is used"))
}

/// The stages after the cover that `params` asks for, in order.
pub(crate) fn sheet_stage_list<'c>(params: &SkeletonParams) -> Vec<SheetStage<'c>> {
    let repairs = &params.repairs;
    let mut stages = vec![
        Stage::new("tetrahedral mesh", tetrahedral_mesh),
        Stage::new("derivatives", derivatives),
        Stage::new("ridge points", find_ridge_points),
        Stage::new("patches", patches),
        Stage::new("cleaning", cleaning),
    ];
    let optional: [(bool, SheetStage<'c>); 12] = [
        (
            repairs.rim_trimming.is_some(),
            Stage::new("rim trimming", rim_trimming),
        ),
        (
            repairs.rim_trimming.is_some(),
            Stage::new("cleaning again", cleaning),
        ),
        (
            repairs.material_holes.is_some(),
            Stage::new("material holes", material_holes),
        ),
        (
            repairs.junction_holes.is_some(),
            Stage::new("junction holes", junction_holes),
        ),
        (repairs.tunnels.is_some(), Stage::new("tunnels", tunnels)),
        (
            repairs.perforations.is_some(),
            Stage::new("perforations", perforations),
        ),
        (repairs.flaps.is_some(), Stage::new("flaps", flaps)),
        (repairs.centring.is_some(), Stage::new("centring", centring)),
        (
            repairs.junction_fold.is_some(),
            Stage::new("junction fold", junction_fold),
        ),
        (
            repairs.junction_planes.is_some(),
            Stage::new("junction planes", junction_planes),
        ),
        (
            repairs.slice_centroids.is_some(),
            Stage::new("slice centroids", slice_centroids),
        ),
        (
            repairs.smoothing.is_some(),
            Stage::new("smoothing", smoothing),
        ),
    ];
    stages.extend(optional.into_iter().filter(|s| s.0).map(|s| s.1));
    stages.push(Stage::new("topology", topology));
    stages
}

/// How much [`TetComplex::OverlapInPart`] grows the balls of the tetrahedra it adds to the
/// overlap complex: twice their radii (a power of two keeps the overlap test exact). On the
/// generated T-junction on slices 3 voxels thick the web's missing tetrahedra have balls
/// that overlap pairwise when grown by 1.35 (coverage 0.992 at noise 0, 0.991 at 10 %);
/// grown twice, 0.999 and 0.996; grown without limit, the same as twice.
const PART_BALL_GROWTH: f64 = 2.0;

/// Builds the cover's function with σ = 1 that the repairs probe, once.
fn build_function(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    if ctx.function.is_none() {
        ctx.function = Some(PuEvaluator::new(ctx.cover, 1.0)?);
    }
    Ok(())
}

/// The chosen complex of the cover (radius shrink σ_t, [`SheetContext::complex`]) and its
/// tetrahedral mesh with edges and ordered edge rings.
fn tetrahedral_mesh(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    let cover = ctx.cover;
    let (centres, radii) = (cover.centres(), cover.radii());
    let params = DualComplexParams {
        shrink: ctx.params.tet_shrink,
        seed: ctx.params.seed,
    };
    let complex = match ctx.complex {
        TetComplex::Dual | TetComplex::Auto => dual_complex(centres, radii, &params),
        TetComplex::Overlap => overlap_complex(centres, radii, &params),
        TetComplex::OverlapInPart => {
            build_function(ctx)?;
            let part = part(&ctx.function, ctx.level, ctx.r_max);
            overlap_complex_admitting(centres, radii, &params, PART_BALL_GROWTH, |cell| {
                part.is_material(cell.iter().map(|&i| centres[i as usize]).sum::<DVec3>() / 4.0)
            })
        }
    }
    .map_err(|e| match e {
        TetraError::NotFullDimensional { .. } => SkeletonError::EmptyResult {
            stage: "the tetrahedral mesh",
            hint: "the object's supports do not span 3D: it is a speck or a single layer of voxels; check the threshold",
        },
        e => SkeletonError::Tetra(e),
    })?;
    let mesh = TetMesh::from_dual_complex(&complex);
    if mesh.tets.is_empty() {
        return Err(SkeletonError::EmptyResult {
            stage: "the tetrahedral mesh",
            hint: "the object is too small or too thin for the cover; check the threshold",
        });
    }
    ctx.mesh = Some(mesh);
    Ok(())
}

/// `∇f` and `∇²f` at the mesh vertices with support expansion σ, smoothed over the supports'
/// sphere intersection graph when asked, with eigenvectors oriented over the mesh.
fn derivatives(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    let (cover, mesh) = (ctx.cover, built(ctx.mesh.as_ref(), "tetrahedral mesh"));
    let evaluator = PuEvaluator::new(cover, ctx.params.sigma)?;
    let positions: Vec<DVec3> = mesh
        .vertices
        .iter()
        .map(|&s| cover.centres()[s as usize])
        .collect();
    let stretch = slice_stretch(ctx);
    ctx.hessian_slice_stretch = stretch.map(|s| s.factor());
    let stretch = stretch.as_ref();
    let mut derivatives = match ctx.params.derivative_smoothing_voxels {
        Some(voxels) => {
            let radii: Vec<f64> = mesh
                .vertices
                .iter()
                .map(|&s| cover.radii()[s as usize])
                .collect();
            let length = voxels * ctx.voxel;
            let time = 0.5 * length * length;
            smoothed_vertex_derivatives(&evaluator, &positions, &radii, time, stretch)?
        }
        None => vertex_derivatives(&evaluator, &positions, stretch),
    };
    drop(evaluator);
    orient_eigenvectors(mesh, &mut derivatives);
    ctx.derivatives = derivatives;
    Ok(())
}

/// How the Hessian compresses the slice axis of thick slices ([`SliceStretch`]); `None`
/// without thick slices or the parameter.
fn slice_stretch(ctx: &SheetContext<'_>) -> Option<SliceStretch> {
    let (slices, blur) = (ctx.slices.as_ref()?, ctx.params.slice_blur_pixels?);
    SliceStretch::new(slices.axis_direction(), slices.slice_pixels(), blur)
}

/// Ridge points on the mesh edges (thesis eq. 6.1, 6.4, 6.5).
fn find_ridge_points(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    ctx.ridge = ridge_points(ctx.mesh(), &ctx.derivatives, &ctx.params.ridge);
    ctx.ridge_count = ctx.ridge.iter().flatten().count();
    if ctx.ridge_count == 0 {
        return Err(SkeletonError::EmptyResult {
            stage: "the ridge detection",
            hint: "no intensity ridge inside the object; is the object brighter than the background?",
        });
    }
    Ok(())
}

/// The fans around ridge edges (thesis Fig. 6.11), open at the mesh boundary.
fn patches(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    ctx.sheet = ridge_patches(ctx.mesh(), &ctx.ridge);
    ctx.raw_triangles = ctx.sheet.triangles.len();
    Ok(())
}

/// Welding, pinches, small holes over material and fragments; the first repair also builds
/// the function the repairs probe, unless the tetrahedral mesh did.
fn cleaning(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    build_function(ctx)?;
    let part = part(&ctx.function, ctx.level, ctx.r_max);
    let (sheet, stats) = clean_sheet(&ctx.sheet, &ctx.params.repairs.cleaning, ctx.voxel, |x| {
        part.is_material(x)
    });
    if ctx.cleaning_passes == 0 {
        ctx.repairs.cleaning = stats;
    } else {
        ctx.repairs.cleaning.add_later_pass(&stats);
    }
    ctx.cleaning_passes += 1;
    ctx.sheet = sheet;
    Ok(())
}

/// Trimming back from the part's rounded rims.
fn rim_trimming(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    let Some(params) = &ctx.params.repairs.rim_trimming else {
        return Ok(());
    };
    let part = part(&ctx.function, ctx.level, ctx.r_max);
    // With the voxels at hand the trimming keeps the sheet's topology but where they show
    // little material (`trim_rims`).
    let little = match (&ctx.voxels, &ctx.params.repairs.perforations) {
        (Some(voxels), Some(params)) => over_little_material(&ctx.sheet, voxels, params, ctx.voxel),
        _ => None,
    };
    let stretch = slice_stretch(ctx).map(|s| s.powered(params.slice_exponent));
    ctx.rim_slice_stretch = stretch.map(|s| s.factor());
    let (trimmed, removed) = trim_rims(
        &ctx.sheet,
        &part,
        params,
        ctx.voxel,
        little.as_deref(),
        stretch.as_ref(),
    );
    ctx.repairs.rim_triangles = removed;
    ctx.sheet = trimmed;
    Ok(())
}

/// Large holes where the material is continuous.
fn material_holes(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    let Some(params) = &ctx.params.repairs.material_holes else {
        return Ok(());
    };
    let part = part(&ctx.function, ctx.level, ctx.r_max);
    ctx.repairs.material_holes = fill_material_holes(&mut ctx.sheet, &part, params, ctx.voxel);
    Ok(())
}

/// Holes of the sheets meeting at a junction.
fn junction_holes(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    let Some(params) = &ctx.params.repairs.junction_holes else {
        return Ok(());
    };
    let part = part(&ctx.function, ctx.level, ctx.r_max);
    ctx.repairs.junction_holes =
        fill_holes_within_sheets(&mut ctx.sheet, params, ctx.voxel, |x| part.is_material(x));
    Ok(())
}

/// Closed pockets opened, and loops that go around material only closed.
fn tunnels(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    let Some(params) = &ctx.params.repairs.tunnels else {
        return Ok(());
    };
    let part = part(&ctx.function, ctx.level, ctx.r_max);
    ctx.repairs.tunnels =
        close_material_tunnels(&mut ctx.sheet, params, ctx.voxel, |x| part.is_material(x));
    Ok(())
}

/// The sheet cut open over holes through the part, then cleaned without filling holes.
fn perforations(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    let (Some(params), Some(voxels)) = (&ctx.params.repairs.perforations, &ctx.voxels) else {
        return Ok(());
    };
    ctx.repairs.perforations = cut_perforations(&mut ctx.sheet, voxels, params, ctx.voxel);
    if ctx.repairs.perforations > 0 {
        let (sheet, stats) =
            clean_sheet(&ctx.sheet, &ctx.params.repairs.cleaning, ctx.voxel, |_| {
                false
            });
        ctx.repairs.cleaning.add_later_pass(&stats);
        ctx.sheet = sheet;
    }
    Ok(())
}

/// Flaps standing across the sheet collapsed.
fn flaps(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    if let Some(params) = &ctx.params.repairs.flaps {
        ctx.repairs.flap_triangles = collapse_misaligned_flaps(&mut ctx.sheet, params);
    }
    Ok(())
}

/// Vertices re-centred between the part's faces.
fn centring(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    let Some(params) = &ctx.params.repairs.centring else {
        return Ok(());
    };
    let part = part(&ctx.function, ctx.level, ctx.r_max);
    ctx.repairs.centred_vertices = centre_between_faces(&mut ctx.sheet, &part, params, ctx.voxel);
    Ok(())
}

/// Junction fillets folded onto the plates.
fn junction_fold(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    let Some(params) = &ctx.params.repairs.junction_fold else {
        return Ok(());
    };
    let part = part(&ctx.function, ctx.level, ctx.r_max);
    ctx.repairs.junction_folded_vertices =
        fold_junction_vertices(&mut ctx.sheet, &part, params, ctx.voxel);
    Ok(())
}

/// Junction bands snapped onto the sheets' planes, and their edges across a corner split.
fn junction_planes(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    if let Some(params) = &ctx.params.repairs.junction_planes {
        let snap = snap_to_junction_planes(&mut ctx.sheet, params, ctx.voxel);
        ctx.repairs.junction_snapped_vertices = snap.moved;
        ctx.repairs.junction_corner_vertices = snap.corner_vertices;
    }
    Ok(())
}

/// Pieces off the plates of thick slices collapsed, the sheet across them moved to the
/// centroid of the measured slices.
fn slice_centroids(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    if let (Some(params), Some(slices)) = (&ctx.params.repairs.slice_centroids, &ctx.slices) {
        ctx.repairs.off_plate_triangles =
            collapse_off_plate_triangles(&mut ctx.sheet, slices, params);
        ctx.repairs.slice_centred_vertices =
            centre_on_slice_centroids(&mut ctx.sheet, slices, params);
    }
    Ok(())
}

/// Smoothing across the sheet.
fn smoothing(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    if let Some(params) = &ctx.params.repairs.smoothing {
        smooth_across(&mut ctx.sheet, params);
    }
    Ok(())
}

/// The sheet's topology; an empty sheet is an error.
fn topology(ctx: &mut SheetContext<'_>) -> Result<(), SkeletonError> {
    if ctx.sheet.triangles.is_empty() {
        return Err(SkeletonError::EmptyResult {
            stage: "patching and cleaning",
            hint: "the ridge points form no surface",
        });
    }
    ctx.topology = Some(MeshTopology::of(&ctx.sheet));
    Ok(())
}
