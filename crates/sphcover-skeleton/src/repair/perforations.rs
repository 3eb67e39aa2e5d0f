//! Perforations: cutting the sheet where it spans a hole through the part that its voxels
//! show and the cover's function does not.
//!
//! The method is described on [`cut_perforations`].

use glam::{DAffine3, DVec3};
use rayon::prelude::*;
use sphcover_core::{DisjointSets, PointIndex, TriMesh, Volume, remove_unused_vertices};

use super::sorted_edges;

/// Boundary loops of at most this many edges are holes (the cleaning fills holes of up to 200
/// edges), longer ones the sheet's rims.
const SMALL_HOLE_EDGES: usize = 200;

/// How many standard deviations of a column's noise a column over air lies below the part's
/// level at least.
const NOISE_DEVIATIONS: f64 = 4.0;

/// Independent voxels' worth of noise in a column's mean: the nine trilinear samples along
/// ±1 voxel weigh the voxels around them so that, for noise independent from voxel to voxel,
/// the mean's variance is that of 6.5 voxels on average over positions and directions and of
/// more than 4.7 in 95% of them (computed from the interpolation weights). Taking 3, the
/// repair left half the small perforations spanned at 30% noise (spurious area up to 0.057);
/// with 4.5, 5–7 of 8 open and at most 0.039, and no cut on the other phantoms; with 6, a cut
/// opened a hole in the rough-boundary plate at 30% noise.
const COLUMN_INDEPENDENT_VOXELS: f64 = 4.5;

/// A region of [`cut_perforations`] with a vertex nearer than this (voxels) to a rim or
/// junction vertex reaches it. On the reference T-junction at 10 % noise one vertex beside the
/// rim, 0.14 voxels from it, read a column of 492 HU (air below 528): the cut opened a hole
/// there and χ fell from the true 1 to 0. Within half a voxel the cut cannot tell a hole from
/// the rim's own rounded edge.
const RIM_CLEARANCE_VOXELS: f64 = 0.5;

/// Parameters of [`cut_perforations`]; lengths in voxels.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct PerforationParams {
    /// Half the length of the column of voxels read across the sheet at each vertex, about
    /// the thinnest part's half-thickness (a longer column reads the air on both sides of a
    /// thin part and takes its material for a hole).
    pub column_half_length_voxels: f64,
    /// A vertex is over air when its column's mean value is below the threshold plus this
    /// fraction of the way to the part's level (the median column of its piece of sheet),
    /// and below the midpoint of the background and the part's level plus this fraction of
    /// the way from there to the level (the same point when the threshold is the midpoint).
    pub air_fraction: f64,
    /// A vertex is over little material when its column's mean is below both points of
    /// [`PerforationParams::air_fraction`] taken with this fraction; such vertices joined
    /// through edges form the region cut around a vertex over air.
    pub little_material_fraction: f64,
}

impl Default for PerforationParams {
    /// Column ±1 voxel, over air below a quarter of the way to the part's level, region
    /// grown to half of it. On the small perforations (radius 1.0–1.7 voxels through a
    /// 3-voxel plate, `small_perforations` example), 10% noise: with the threshold itself
    /// for air, the holes of radius 1.0–1.2 stay spanned (their vertices lie at their rims,
    /// never over the middle); with a quarter, all eight open on isotropic voxels and on
    /// every second slice (resampled to 1:1).
    fn default() -> PerforationParams {
        PerforationParams {
            column_half_length_voxels: 1.0,
            air_fraction: 0.25,
            little_material_fraction: 0.5,
        }
    }
}

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
    fn value(&self, to_voxel: &DAffine3, x: DVec3) -> Option<f64> {
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

/// Cuts the sheet open where it spans a perforation of the part; returns how many
/// perforations were cut.
///
/// The cover's quadratic fits, over supports several voxels wide, pass over a hole of radius
/// 1–1.2 voxels through a plate 3 voxels thick, so the ridge test finds a ridge across it
/// and the sheet spans it, while the voxels there are air; the cleaning's fans and the
/// material-hole webs, which ask the same function, close larger ones. At each vertex the
/// mean value of the volume along a short column across the sheet (`mesh.normals`, the
/// ridge's across directions) says how much material lies under it. Vertices over little
/// material ([`PerforationParams::little_material_fraction`]) joined through edges form
/// regions; a region holding a vertex over air ([`PerforationParams::air_fraction`]: one
/// vertex over a hole's middle is enough, and noise of 30% of the contrast puts no column
/// over material that low) is a perforation, and the triangles touching it are removed,
/// unless the region reaches a junction (where the column follows one sheet only: at 30%
/// noise a cut opened the T-junction) or a rim of the sheet, or passes within
/// `RIM_CLEARANCE_VOXELS` of one. Rims (boundary loops longer than a hole's) run out to the
/// part's rounded edges, whose columns hold little material: cutting there cost the
/// T-junction and the wedge's 2-voxel end 2–3% of their coverage.
pub fn cut_perforations(
    mesh: &mut TriMesh,
    part: &VoxelPart<'_>,
    params: &PerforationParams,
    voxel: f64,
) -> usize {
    let n = mesh.vertices.len();
    let Some(normals) = mesh.normals.as_ref().filter(|m| m.len() == n) else {
        return 0;
    };
    let to_voxel = part.volume.affine().inverse();
    let half = params.column_half_length_voxels * voxel;
    let column_mean: Vec<Option<f64>> = mesh
        .vertices
        .par_iter()
        .zip(normals)
        .map(|(&p, &d)| {
            let d = d.try_normalize()?;
            // Nine samples a quarter of the column apart: about three voxels' worth of noise.
            let samples = [-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0];
            let sum = samples
                .iter()
                .map(|&t| part.value(&to_voxel, p + d * (t * half)))
                .sum::<Option<f64>>()?;
            Some(sum / samples.len() as f64)
        })
        .collect();
    let mut edges = sorted_edges(mesh);
    // Vertices on the sheet's long boundaries (its rims: boundary edges joined into runs of
    // more than `SMALL_HOLE_EDGES`; shorter runs are holes the ridge test already opened,
    // partly, over a perforation) and on junctions (edges of three or more triangles, where
    // the across direction is the ridge's of one sheet only).
    let mut loops = DisjointSets::new(n);
    let mut boundary_edges = Vec::new();
    let mut excluded = vec![false; n];
    for run in edges.chunk_by(|a, b| a == b) {
        let (a, b) = run[0];
        match run.len() {
            1 => {
                loops.union(a, b);
                boundary_edges.push((a, b));
            }
            2 => {}
            _ => {
                excluded[a as usize] = true;
                excluded[b as usize] = true;
            }
        }
    }
    let mut loop_edges = vec![0usize; n];
    for &(a, _) in &boundary_edges {
        loop_edges[loops.find(a) as usize] += 1;
    }
    for &(a, b) in &boundary_edges {
        if loop_edges[loops.find(a) as usize] > SMALL_HOLE_EDGES {
            excluded[a as usize] = true;
            excluded[b as usize] = true;
        }
    }
    edges.dedup();
    // The part's level under each piece of the sheet: the median column over its vertices
    // (a head holder of 500 HU is a part as much as bone of 1,500 HU is).
    let mut pieces = DisjointSets::new(n);
    for &(a, b) in &edges {
        pieces.union(a, b);
    }
    let piece: Vec<u32> = (0..n as u32).map(|v| pieces.find(v)).collect();
    let mut columns_of: Vec<Vec<f64>> = vec![Vec::new(); n];
    for v in 0..n {
        if let Some(m) = column_mean[v] {
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
    // Hysteresis: a region of vertices over little material is a perforation when some of
    // its vertices are over air.
    // A vertex is over air only where its material is also out of reach of the column's
    // noise (at 30% of the contrast a quarter of the way to the part's level is within 2.4
    // deviations of it, and a cut opened the T-junction's web).
    let column_noise = NOISE_DEVIATIONS * part.noise / COLUMN_INDEPENDENT_VOXELS.sqrt();
    // The second bound matters where the threshold lies near the part's level: on the head
    // CT the holder arc (+500 HU, its columns' median 337 HU) stands above a bone threshold
    // of 223 HU over a background of 33 HU, and columns of 229–280 HU across the arc, where
    // it runs along the grid's planes, passed for air under the first bound alone: the
    // repair cut a strip of holes across it.
    let below = |fraction: f64, noisy: bool| -> Vec<bool> {
        (0..n)
            .map(|v| {
                let top = piece_level[piece[v] as usize].max(part.threshold);
                // Both bounds are `from + fraction · (top − from)`, which grows with `from`:
                // the lower one counts from the lower of the two starting points.
                let mid = 0.5 * (part.background.min(part.threshold) + top);
                let from = part.threshold.min(mid);
                let mut limit = from + fraction * (top - from);
                if noisy {
                    limit = limit.min(top - column_noise);
                }
                column_mean[v].is_some_and(|m| m < limit)
            })
            .collect()
    };
    let little = below(params.little_material_fraction, false);
    let air = below(params.air_fraction, true);
    let mut regions = DisjointSets::new(n);
    for &(a, b) in &edges {
        if little[a as usize] && little[b as usize] {
            regions.union(a, b);
        }
    }
    let root: Vec<u32> = (0..n as u32).map(|v| regions.find(v)).collect();
    let mut over_air = vec![false; n];
    let mut reaches_boundary = vec![false; n];
    for v in (0..n).filter(|&v| little[v]) {
        over_air[root[v] as usize] |= air[v];
        reaches_boundary[root[v] as usize] |= excluded[v];
    }
    // Regions that pass so far reach a rim or junction also when one of their vertices lies
    // beside one (see `RIM_CLEARANCE_VOXELS`).
    let beside: Vec<DVec3> = (0..n)
        .filter(|&v| excluded[v])
        .map(|v| mesh.vertices[v])
        .collect();
    if let Ok(index) = PointIndex::new(&beside) {
        let clearance = RIM_CLEARANCE_VOXELS * voxel;
        for v in 0..n {
            let r = root[v] as usize;
            if little[v] && over_air[r] && !reaches_boundary[r] {
                index.for_each_slot_within(mesh.vertices[v], clearance, |_, _| {
                    reaches_boundary[r] = true;
                });
            }
        }
    }
    let cut: Vec<bool> = (0..n)
        .map(|v| {
            let r = root[v] as usize;
            little[v] && over_air[r] && !reaches_boundary[r]
        })
        .collect();
    let mut perforations: Vec<u32> = (0..n).filter(|&v| cut[v]).map(|v| root[v]).collect();
    perforations.sort_unstable();
    perforations.dedup();
    if perforations.is_empty() {
        return 0;
    }
    mesh.triangles
        .retain(|t| !t.iter().any(|&v| cut[v as usize]));
    remove_unused_vertices(mesh);
    perforations.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use sphcover_core::VoxelValues;

    /// A 24 × 24 × 12 volume of unit voxels: value 1 in the slab 4.5 < z < 7.5 (3 voxels
    /// thick) but inside a hole of radius `hole` about (12, 12), 0 elsewhere.
    fn plate(hole: f64) -> Volume {
        plate_with_hole_at(12.0, hole)
    }

    /// [`plate`] with the hole about `(x, 12)`.
    fn plate_with_hole_at(x: f64, hole: f64) -> Volume {
        slab(|i, j| {
            if (i - x).hypot(j - 12.0) > hole {
                1.0
            } else {
                0.0
            }
        })
    }

    /// A 24 × 24 × 12 volume of unit voxels: `value(i, j)` in the slab 4.5 < z < 7.5, 0
    /// elsewhere.
    fn slab(value: impl Fn(f64, f64) -> f32) -> Volume {
        let mut values = Vec::new();
        for k in 0..12 {
            for j in 0..24 {
                for i in 0..24 {
                    let in_slab = (4.5..7.5).contains(&f64::from(k));
                    values.push(if in_slab {
                        value(f64::from(i), f64::from(j))
                    } else {
                        0.0
                    });
                }
            }
        }
        Volume::axis_aligned(
            [24, 24, 12],
            VoxelValues::F32(values),
            DVec3::ONE,
            DVec3::ZERO,
        )
        .unwrap()
    }

    /// A sheet on the slab's mid-plane z = 6 over 2 ≤ x, y ≤ 22, half a voxel between
    /// vertices, with normals +z.
    fn sheet() -> TriMesh {
        sheet_from(2.0, 0.5)
    }

    /// A sheet on the slab's mid-plane z = 6 over `x0 ≤ x ≤ x0 + 20`, 2 ≤ y ≤ 22, `step`
    /// voxels between vertices, with normals +z.
    fn sheet_from(x0: f64, step: f64) -> TriMesh {
        let n = (20.0 / step).round() as u32 + 1;
        let vertices = (0..n)
            .flat_map(|j| {
                (0..n).map(move |i| {
                    DVec3::new(x0 + step * f64::from(i), 2.0 + step * f64::from(j), 6.0)
                })
            })
            .collect();
        let v = |i: u32, j: u32| j * n + i;
        let triangles = (0..n - 1)
            .flat_map(|j| {
                (0..n - 1).flat_map(move |i| {
                    [
                        [v(i, j), v(i + 1, j), v(i + 1, j + 1)],
                        [v(i, j), v(i + 1, j + 1), v(i, j + 1)],
                    ]
                })
            })
            .collect();
        let mut mesh = TriMesh::new(vertices, triangles);
        mesh.normals = Some(vec![DVec3::Z; mesh.vertices.len()]);
        mesh
    }

    fn over_the_hole(mesh: &TriMesh) -> bool {
        mesh.vertices
            .iter()
            .any(|p| (p.x - 12.0).hypot(p.y - 12.0) < 0.9)
    }

    /// A part whose level lies just above the threshold (a head holder of 500 HU over a bone
    /// threshold): a band of its slab reads 0.76 against 1 elsewhere, above the threshold 0.7
    /// and under a quarter of the way from it to the level, over a background of 0. That
    /// band is material, not a hole; a hole through the same slab is one.
    #[test]
    fn material_just_above_the_threshold_is_not_a_hole() {
        let params = PerforationParams::default();
        let band = |hole: f64| {
            slab(|i, j| {
                if (i - 12.0).hypot(j - 12.0) <= hole {
                    0.0
                } else if (10.0..=14.0).contains(&i) {
                    0.76
                } else {
                    1.0
                }
            })
        };
        let part = |volume, background| VoxelPart {
            volume,
            threshold: 0.7,
            background,
            noise: 0.0,
        };
        let solid = band(-1.0);
        let mut whole = sheet();
        assert_eq!(
            cut_perforations(&mut whole, &part(&solid, 0.0), &params, 1.0),
            0
        );
        assert_eq!(whole, sheet());
        // Measured from the threshold alone (a background at the threshold), the band passes
        // for air.
        let mut cut = sheet();
        assert!(cut_perforations(&mut cut, &part(&solid, 0.7), &params, 1.0) > 0);
        let holed = band(1.2);
        let mut mesh = sheet();
        assert_eq!(
            cut_perforations(&mut mesh, &part(&holed, 0.0), &params, 1.0),
            1
        );
        assert!(!over_the_hole(&mesh));
    }

    #[test]
    fn a_hole_through_the_part_is_cut_and_nothing_else() {
        let params = PerforationParams::default();
        let part = |volume| VoxelPart {
            volume,
            threshold: 0.5,
            background: 0.0,
            noise: 0.0,
        };
        let holed = plate(1.2);
        let mut mesh = sheet();
        assert_eq!(cut_perforations(&mut mesh, &part(&holed), &params, 1.0), 1);
        assert!(!over_the_hole(&mesh));
        // Only around the hole: the sheet's rim, over the slab's edge, stays.
        let kept = mesh.vertices.len();
        assert!(kept > sheet().vertices.len() - 60, "{kept}");
        for corner in [DVec3::new(2.0, 2.0, 6.0), DVec3::new(22.0, 22.0, 6.0)] {
            assert!(mesh.vertices.contains(&corner));
        }
        // Without a hole nothing is cut.
        let solid = plate(-1.0);
        let mut whole = sheet();
        assert_eq!(cut_perforations(&mut whole, &part(&solid), &params, 1.0), 0);
        assert_eq!(whole, sheet());
        // Noise that reaches from the part's level to the hole's columns (4 deviations of a
        // column's mean, 4 · 0.6 / √4.5, exceed the contrast): nothing is taken for air.
        let noisy = VoxelPart {
            noise: 0.6,
            ..part(&holed)
        };
        let mut unsure = sheet();
        assert_eq!(cut_perforations(&mut unsure, &noisy, &params, 1.0), 0);
    }

    /// A hole whose columns read air a quarter of a voxel from a rim vertex (which itself
    /// stands over material) is the rim's own edge to the cut: nothing is cut. The same hole
    /// two voxels farther in is. The sheet has a quarter of a voxel between vertices, so its
    /// outer boundary (320 edges) is a rim, not a hole.
    #[test]
    fn a_hole_beside_the_rim_is_left_to_the_rim() {
        let params = PerforationParams::default();
        let cut = |x: f64| {
            let volume = plate_with_hole_at(x, 1.2);
            let part = VoxelPart {
                volume: &volume,
                threshold: 0.5,
                background: 0.0,
                noise: 0.0,
            };
            // The rim at x = 2.2 reads 0.8 of the part; the next vertex, at 2.45, 0.55: air.
            let mut mesh = sheet_from(2.2, 0.25);
            cut_perforations(&mut mesh, &part, &params, 1.0)
        };
        assert_eq!(cut(3.8), 0);
        assert_eq!(cut(5.8), 1);
    }

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
