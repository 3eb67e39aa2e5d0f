//! Repairs of the raw ridge patches (future work in thesis §6.4): what turns the fans of
//! thesis Fig. 6.11 into one clean sheet.
//!
//! The method is described on [`SheetRepairs`].

pub(crate) mod cleaning;
pub(crate) mod collapse;
pub(crate) mod flaps;
pub(crate) mod junction_holes;
pub(crate) mod junction_planes;
pub(crate) mod material_holes;
pub(crate) mod medial_correction;
pub(crate) mod part_surface;
pub(crate) mod perforations;
pub(crate) mod rim_trimming;
pub(crate) mod sheet_smoothing;
pub(crate) mod slice_centroids;
pub(crate) mod tunnels;
pub(crate) mod voxel_columns;

use std::cmp::Ordering;

use cleaning::CleaningParams;
use flaps::FlapParams;
use junction_holes::SheetHoleParams;
use junction_planes::JunctionPlaneParams;
use material_holes::MaterialHoleParams;
use medial_correction::{CentringParams, JunctionFoldParams};
use perforations::PerforationParams;
use rim_trimming::RimTrimParams;
use sheet_smoothing::SmoothingParams;
use slice_centroids::SliceCentroidParams;
use tunnels::TunnelParams;

/// Which repairs run on the raw ridge patches, and their parameters (method below). `Default`
/// is the set the phantom tests use: every repair but the smoothing.
///
/// Each repair is a stage of the pipeline with its own parameters, all lengths in voxels
/// (the geometric mean of the voxel edges, or the sample spacing of scattered samples), and
/// each but the cleaning can be switched off by leaving its entry of [`SheetRepairs`] `None`.
/// They run in this order:
///
/// | stage | function | what it does |
/// |---|---|---|
/// | cleaning | [`clean_sheet`](crate::clean_sheet) | weld, undo pinches, fill small holes over material, drop fragments |
/// | rim trimming | [`trim_rims`](crate::trim_rims) | trim the sheet back from the part's rounded rims (medial-axis test; keeping its topology where the voxels show material, with the perforation check on), then clean again |
/// | material holes | [`fill_material_holes`](crate::fill_material_holes) | fill large holes where the material is continuous, on the part's mid-surface |
/// | junction holes | [`fill_holes_within_sheets`](crate::fill_holes_within_sheets) | fill holes of the sheets meeting at a junction |
/// | tunnels | [`close_material_tunnels`](crate::close_material_tunnels) | open closed pockets, close loops that go around material only |
/// | perforations | [`cut_perforations`](crate::cut_perforations) | cut the sheet open where its voxels show a hole through the part (volumes only; folds off the part are collapsed, not cut), then clean again without filling holes |
/// | flaps | [`collapse_misaligned_flaps`](crate::collapse_misaligned_flaps) | collapse fins standing across the sheet |
/// | centring | [`centre_between_faces`](crate::centre_between_faces) | re-centre vertices between the part's two faces |
/// | junction fold | [`fold_junction_vertices`](crate::fold_junction_vertices) | fold junction fillets onto the plates (needs centring) |
/// | junction planes | [`snap_to_junction_planes`](crate::snap_to_junction_planes) | snap the band where sheets meet onto their planes, and split its edges across their corner |
/// | slice centroids | [`centre_on_slice_centroids`](crate::centre_on_slice_centroids) | collapse pieces off the plates, move the rest to the measured slices' centroid (slices over 2:1) |
/// | smoothing | [`smooth_across`](crate::smooth_across) | smooth across the sheet (off by default) |
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct SheetRepairs {
    /// Welding, pinches, small holes and fragments: always runs (first, and again after rim
    /// trimming), since the later repairs need one shared-vertex sheet.
    pub cleaning: CleaningParams,
    /// Trimming back from the rims.
    pub rim_trimming: Option<RimTrimParams>,
    /// Large holes where the material is continuous.
    pub material_holes: Option<MaterialHoleParams>,
    /// Holes of the sheets meeting at a junction.
    pub junction_holes: Option<SheetHoleParams>,
    /// Closed pockets and tunnels through material.
    pub tunnels: Option<TunnelParams>,
    /// Holes through the part that the sheet spans (volumes only).
    pub perforations: Option<PerforationParams>,
    /// Flaps standing across the sheet.
    pub flaps: Option<FlapParams>,
    /// Re-centring between the part's faces.
    pub centring: Option<CentringParams>,
    /// Folding junction fillets onto the plates; runs only after the centring, so it needs
    /// [`SheetRepairs::centring`].
    pub junction_fold: Option<JunctionFoldParams>,
    /// Snapping junction bands onto the sheets' planes.
    pub junction_planes: Option<JunctionPlaneParams>,
    /// Collapsing the pieces of sheet off the plates and moving the rest to the centroid of
    /// the measured slices, on slices more than twice as thick as the pixels (volumes
    /// only).
    pub slice_centroids: Option<SliceCentroidParams>,
    /// Smoothing across the sheet. Off by default: on the 10 % phantoms three rounds lower
    /// the 95th-percentile distance of flat plates (0.23 → 0.19 voxel) but raise it at the
    /// T-junction (0.45 → 0.52) and on the spherical cap (0.32 → 0.37), where the umbrella
    /// step pulls towards chords.
    pub smoothing: Option<SmoothingParams>,
}

impl Default for SheetRepairs {
    fn default() -> SheetRepairs {
        SheetRepairs {
            cleaning: CleaningParams::default(),
            rim_trimming: Some(RimTrimParams::default()),
            material_holes: Some(MaterialHoleParams::default()),
            junction_holes: Some(SheetHoleParams::default()),
            tunnels: Some(TunnelParams::default()),
            perforations: Some(PerforationParams::default()),
            flaps: Some(FlapParams::default()),
            centring: Some(CentringParams::default()),
            junction_fold: Some(JunctionFoldParams::default()),
            junction_planes: Some(JunctionPlaneParams::default()),
            slice_centroids: Some(SliceCentroidParams::default()),
            smoothing: None,
        }
    }
}

impl SheetRepairs {
    /// No repair but the cleaning: the sheet as the ridge patches give it, welded.
    pub fn cleaning_only() -> SheetRepairs {
        SheetRepairs {
            cleaning: CleaningParams::default(),
            rim_trimming: None,
            material_holes: None,
            junction_holes: None,
            tunnels: None,
            perforations: None,
            flaps: None,
            centring: None,
            junction_fold: None,
            junction_planes: None,
            slice_centroids: None,
            smoothing: None,
        }
    }
}

/// Keeps the triangles whose index `keep` accepts, in their order: how a repair drops the
/// triangles it marked.
pub(crate) fn retain_triangles(triangles: &mut Vec<[u32; 3]>, keep: impl Fn(usize) -> bool) {
    let mut t = 0;
    triangles.retain(|_| {
        t += 1;
        keep(t - 1)
    });
}

/// A key and an index ordered for a min-heap in [`std::collections::BinaryHeap`]: the lowest
/// key first, ties by the lowest index (shortest paths, collapse orders).
#[derive(PartialEq)]
pub(crate) struct MinFirst(pub(crate) f64, pub(crate) u32);

impl Eq for MinFirst {}

impl PartialOrd for MinFirst {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for MinFirst {
    /// Reversed: the max-heap pops the lowest key.
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

/// Every triangle's edges as (lower, higher) vertex pairs, sorted: an edge appears once per
/// triangle it bounds, so runs of one are boundary edges and runs of three or more junctions.
pub(crate) fn sorted_edges(mesh: &sphcover_core::TriMesh) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32)> = mesh
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
        .collect();
    edges.sort_unstable();
    edges
}

/// `mesh` with only the triangles `keep` marks, for the repairs' tests.
#[cfg(test)]
pub(crate) fn kept_triangles_of(
    mesh: &sphcover_core::TriMesh,
    keep: &[bool],
) -> sphcover_core::TriMesh {
    let mut out = mesh.clone();
    retain_triangles(&mut out.triangles, |t| keep[t]);
    out
}

/// An `n × m` grid of unit squares in z = 0, two triangles each (square `(i, j)` holds
/// triangles `2(i + n j)` and `2(i + n j) + 1`), for the repairs' tests.
#[cfg(test)]
pub(crate) fn grid(n: u32, m: u32) -> sphcover_core::TriMesh {
    let mut v = Vec::new();
    for j in 0..=m {
        for i in 0..=n {
            v.push(glam::DVec3::new(i as f64, j as f64, 0.0));
        }
    }
    let mut t = Vec::new();
    for j in 0..m {
        for i in 0..n {
            let a = i + (n + 1) * j;
            t.push([a, a + 1, a + n + 2]);
            t.push([a, a + n + 2, a + n + 1]);
        }
    }
    sphcover_core::TriMesh::new(v, t)
}
