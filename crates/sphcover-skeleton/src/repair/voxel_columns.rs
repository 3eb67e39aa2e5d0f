//! What the voxels under a sheet say: at each vertex, the mean value of the volume along a
//! short column across the sheet, against the level of the part under its piece of sheet.
//!
//! The cover's quadratic fits, over supports several voxels wide, pass over details a few
//! voxels across (a hole of radius 1–1.2 voxels through a plate 3 voxels thick); the
//! voxels do not. The perforation cut ([`crate::cut_perforations`]) reads them to open the
//! sheet over holes, and the rim trimming ([`crate::trim_rims`]) to keep the sheet where
//! they show material.

use glam::{DAffine3, DVec3};
use rayon::prelude::*;
use sphcover_core::{DisjointSets, TriMesh, Volume};

/// How many standard deviations of its noise the air test's mean lies below the part's level
/// at least. With 4 the repair cut a hole into a generated wedge at 30 % noise (`SEED=3`: one
/// vertex read air through the noise); with 4.5 no generated phantom at 10 or 30 % noise,
/// seeds 1–5, has a hole cut that it does not have (isotropic voxels), and the small
/// perforations' spurious area at 30 % stays within 0.043 (seeds 1–16; at most 0.042 with 4).
const NOISE_DEVIATIONS: f64 = 4.5;

/// The air test reads the mean of five columns: the vertex's and four half a voxel from it
/// along the sheet. A hole of radius 1 voxel or more holds all five; noise that puts a
/// single column over air rarely puts their mean there.
const DISK_RADIUS_VOXELS: f64 = 0.5;

/// Independent voxels' worth of noise in the five columns' mean: their 45 trilinear samples
/// weigh the voxels around them so that, for noise independent from voxel to voxel, the
/// mean's variance is that of 10.0 voxels on average over positions and directions and of
/// more than 9.2 in 95% of them (computed from the interpolation weights; a single column:
/// 6.6 and 4.8). With a single column and 4.5 voxels the repair left 1–5 of the small
/// perforations spanned at 30 % noise (spurious area up to 0.056 on seeds 1–16; 3 voxels:
/// up to 0.057 on seeds 1–3; 6: a hole cut into the rough-boundary plate), and on slices
/// twice the pixels apart, where half the voxels are interpolated, it cut holes into three
/// plates that have none (`docs/benchmarks.md`, *Small perforations*).
const DISK_INDEPENDENT_VOXELS: f64 = 9.0;

/// Nine samples a quarter of the column apart: about three voxels' worth of noise.
const COLUMN_SAMPLES: [f64; 9] = [-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0];

/// Directions along the sheet in which [`SheetColumns::flanked`] looks for material.
const FLANK_DIRECTIONS: usize = 12;

/// How many of the [`FLANK_DIRECTIONS`] must meet material for a vertex to be flanked by it.
/// On the small perforations (`small_perforations` example, seeds 1–8, 10 % noise) the air
/// vertices within 2 voxels of a hole's centre met material in 11 or 12 (1,774 vertices);
/// those more than 1.5 voxels off the plate's mid-plane, on folds whose across direction lies
/// along the plate, in 5–7 (123 vertices: the directions that run down to the plate).
const FLANK_MIN_DIRECTIONS: usize = 10;

/// How far (voxels) [`SheetColumns::flanked`] looks along the sheet: across the small
/// perforations' holes (up to 3.2 voxels in radius on the true sheet) from anywhere inside
/// them, and down the 2–2.5 voxels a fold stands off the plate, at slants of up to 60°.
const FLANK_REACH_VOXELS: f64 = 6.0;

/// The voxels a sheet is checked against: the volume its cover was fitted to, as measured,
/// and the part's threshold and noise.
#[derive(Clone, Copy, Debug)]
pub struct VoxelPart<'a> {
    /// The volume as read, or resampled from slices at most twice its pixels apart (from
    /// thicker slices, interpolated voxels are not measurements), and not windowed
    /// (windowing keeps the order of values about the threshold).
    pub volume: &'a Volume,
    /// The part is where the values exceed this.
    pub threshold: f64,
    /// The level of what surrounds the part: the median of the values at or below the
    /// threshold (of the material window on a CT).
    pub background: f64,
    /// Standard deviation of the volume's noise.
    pub noise: f64,
}

impl VoxelPart<'_> {
    /// Trilinear interpolation of the volume at `x` (world units); `None` farther than half a
    /// voxel outside the grid (within it, the edge voxels extend).
    pub(crate) fn value(&self, to_voxel: &DAffine3, x: DVec3) -> Option<f64> {
        let dims = self.volume.dims();
        let g = to_voxel.transform_point3(x).to_array();
        let mut lower = [0usize; 3];
        let mut upper = [0usize; 3];
        let mut frac = [0.0; 3];
        for axis in 0..3 {
            let last = dims[axis] as f64 - 1.0;
            if !(g[axis] >= -0.5 && g[axis] <= last + 0.5) {
                return None;
            }
            let c = g[axis].clamp(0.0, last);
            lower[axis] = c.floor() as usize;
            upper[axis] = (lower[axis] + 1).min(dims[axis] - 1);
            frac[axis] = c - c.floor();
        }
        let values = self.volume.values();
        let mut sum = 0.0;
        for corner in 0..8 {
            let mut ijk = [0usize; 3];
            let mut weight = 1.0;
            for axis in 0..3 {
                let high = (corner >> axis) & 1 == 1;
                ijk[axis] = if high { upper[axis] } else { lower[axis] };
                weight *= if high { frac[axis] } else { 1.0 - frac[axis] };
            }
            sum += weight * values.get(self.volume.index(ijk[0], ijk[1], ijk[2]));
        }
        Some(sum)
    }
}

/// The columns read at a sheet's vertices, with the part's level under each vertex's piece.
pub(crate) struct SheetColumns<'a> {
    part: VoxelPart<'a>,
    to_voxel: DAffine3,
    /// Half a column's length, world units.
    half: f64,
    /// Each vertex's column mean; `None` without an across direction or off the grid.
    mean: Vec<Option<f64>>,
    /// The part's level under each vertex: the median column of its piece of sheet (a head
    /// holder of 500 HU is a part as much as bone of 1,500 HU is), at least the threshold.
    top: Vec<f64>,
}

impl<'a> SheetColumns<'a> {
    /// Reads the columns of `mesh` (whose normals must hold the across directions), each
    /// `2 · column_half_length_voxels` long; `edges` are the mesh's edges, each once (its
    /// pieces are the components they join). `None` without normals.
    pub(crate) fn read(
        mesh: &TriMesh,
        edges: &[(u32, u32)],
        part: &VoxelPart<'a>,
        column_half_length_voxels: f64,
        voxel: f64,
    ) -> Option<SheetColumns<'a>> {
        let n = mesh.vertices.len();
        let normals = mesh.normals.as_ref().filter(|m| m.len() == n)?;
        let mut columns = SheetColumns {
            part: *part,
            to_voxel: part.volume.affine().inverse(),
            half: column_half_length_voxels * voxel,
            mean: Vec::new(),
            top: Vec::new(),
        };
        columns.mean = mesh
            .vertices
            .par_iter()
            .zip(normals)
            .map(|(&p, &d)| columns.column_at(p, d.try_normalize()?))
            .collect();
        let mut pieces = DisjointSets::new(n);
        for &(a, b) in edges {
            pieces.union(a, b);
        }
        let piece: Vec<u32> = (0..n as u32).map(|v| pieces.find(v)).collect();
        let mut columns_of: Vec<Vec<f64>> = vec![Vec::new(); n];
        for v in 0..n {
            if let Some(m) = columns.mean[v] {
                columns_of[piece[v] as usize].push(m);
            }
        }
        let piece_level: Vec<f64> = columns_of
            .into_iter()
            .map(|mut c| {
                if c.is_empty() {
                    return f64::NAN;
                }
                let mid = c.len() / 2;
                *c.select_nth_unstable_by(mid, f64::total_cmp).1
            })
            .collect();
        columns.top = piece
            .iter()
            .map(|&p| piece_level[p as usize].max(part.threshold))
            .collect();
        Some(columns)
    }

    /// The mean value along the column through `p` in direction `d` (unit).
    fn column_at(&self, p: DVec3, d: DVec3) -> Option<f64> {
        let sum = COLUMN_SAMPLES
            .iter()
            .map(|&t| self.part.value(&self.to_voxel, p + d * (t * self.half)))
            .sum::<Option<f64>>()?;
        Some(sum / COLUMN_SAMPLES.len() as f64)
    }

    /// The value under which vertex `v`'s column holds less than `fraction` of the part: the
    /// lower of `fraction` of the way from the threshold to the part's level and `fraction`
    /// of the way from the midpoint of the background and the level to it.
    fn limit(&self, v: usize, fraction: f64) -> f64 {
        let top = self.top[v];
        let part = &self.part;
        // Both bounds are `from + fraction · (top − from)`, which grows with `from`: the
        // lower one counts from the lower of the two starting points. The second matters
        // where the threshold lies near the part's level: on the head CT the holder arc
        // (+500 HU, its columns' median 337 HU) stands above a bone threshold of 223 HU over
        // a background of 33 HU, and columns of 229–280 HU across the arc, where it runs
        // along the grid's planes, passed for air under the first bound alone: the repair
        // cut a strip of holes across it.
        let mid = 0.5 * (part.background.min(part.threshold) + top);
        let from = part.threshold.min(mid);
        from + fraction * (top - from)
    }

    /// Which vertices' columns hold less than `fraction` of the part ([`Self::limit`]).
    pub(crate) fn below(&self, fraction: f64) -> Vec<bool> {
        (0..self.mean.len())
            .map(|v| self.mean[v].is_some_and(|m| m < self.limit(v, fraction)))
            .collect()
    }

    /// Which of the vertices `among` of `mesh` (the mesh the columns were read on; the others
    /// are not read) stand over air: the mean
    /// of their column and of the four columns [`DISK_RADIUS_VOXELS`] from it along the sheet
    /// holds less than `fraction` of the part ([`Self::limit`]) and lies at least
    /// [`NOISE_DEVIATIONS`] of that mean's noise below the part's level (at 30 % of the
    /// contrast a quarter of the way to the level is within 2.4 deviations of a single
    /// column's noise, and a cut opened the T-junction's web).
    pub(crate) fn over_air(
        &self,
        mesh: &TriMesh,
        among: &[bool],
        fraction: f64,
        voxel: f64,
    ) -> Vec<bool> {
        let normals = mesh.normals.as_deref().unwrap_or_default();
        let disk_noise = NOISE_DEVIATIONS * self.part.noise / DISK_INDEPENDENT_VOXELS.sqrt();
        let r = DISK_RADIUS_VOXELS * voxel;
        (0..self.mean.len())
            .into_par_iter()
            .map(|v| {
                if !among[v] {
                    return false;
                }
                let (Some(centre), Some(d)) = (self.mean[v], normals[v].try_normalize()) else {
                    return false;
                };
                let p = mesh.vertices[v];
                let u = d.any_orthonormal_vector();
                let w = d.cross(u);
                let around = [u, -u, w, -w].map(|t| self.column_at(p + t * r, d));
                let Some(around) = around.into_iter().sum::<Option<f64>>() else {
                    return false;
                };
                let mean = (centre + around) / 5.0;
                mean < self.limit(v, fraction).min(self.top[v] - disk_noise)
            })
            .collect()
    }

    /// Whether material surrounds vertex `v` along the sheet: in at least
    /// [`FLANK_MIN_DIRECTIONS`] of [`FLANK_DIRECTIONS`] directions perpendicular to its across
    /// direction `d`, a column parallel to `d` within [`FLANK_REACH_VOXELS`] holds at least
    /// `fraction` of the part. A sheet spanning a hole through a plate lies in the plate, which
    /// surrounds the hole; a fold standing off the plate into the air beside it has the plate
    /// on one side only.
    pub(crate) fn flanked(&self, p: DVec3, d: DVec3, v: usize, fraction: f64, voxel: f64) -> bool {
        let Some(d) = d.try_normalize() else {
            return false;
        };
        let limit = self.limit(v, fraction);
        let u = d.any_orthonormal_vector();
        let w = d.cross(u);
        // Half a voxel apart.
        let steps = (2.0 * FLANK_REACH_VOXELS).round() as usize;
        (0..FLANK_DIRECTIONS)
            .filter(|&k| {
                let angle = std::f64::consts::TAU * k as f64 / FLANK_DIRECTIONS as f64;
                let along = angle.cos() * u + angle.sin() * w;
                (1..=steps).any(|i| {
                    let x = p + along * (0.5 * i as f64 * voxel);
                    self.column_at(x, d).is_some_and(|m| m >= limit)
                })
            })
            .count()
            >= FLANK_MIN_DIRECTIONS
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use sphcover_core::VoxelValues;

    proptest! {
        #[test]
        fn trilinear_values_reproduce_a_linear_field(
            gradient in (-3.0f64..3.0, -3.0f64..3.0, -3.0f64..3.0),
            offset in -5.0f64..5.0,
            p in (0.0f64..5.0, 0.0f64..4.0, 0.0f64..3.0),
        ) {
            let g = DVec3::new(gradient.0, gradient.1, gradient.2);
            let (dims, size, origin) = ([6, 5, 4], DVec3::new(0.5, 1.0, 2.0), DVec3::new(1.0, -2.0, 3.0));
            let mut values = Vec::new();
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        let x = origin + size * DVec3::new(i as f64, j as f64, k as f64);
                        values.push(g.dot(x) + offset);
                    }
                }
            }
            let volume = Volume::axis_aligned(dims, VoxelValues::F64(values), size, origin).unwrap();
            let part = VoxelPart { volume: &volume, threshold: 0.0, background: 0.0, noise: 0.0 };
            let x = origin + size * DVec3::new(p.0, p.1, p.2);
            let value = part.value(&volume.affine().inverse(), x).unwrap();
            prop_assert!((value - (g.dot(x) + offset)).abs() < 1e-9);
            // Beyond half a voxel outside the grid there is no value.
            let outside = origin - size * 0.6;
            prop_assert!(part.value(&volume.affine().inverse(), outside).is_none());
        }
    }
}
