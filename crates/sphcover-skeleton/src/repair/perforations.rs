//! Perforations: cutting the sheet where it spans a hole through the part that its voxels
//! show and the cover's function does not.
//!
//! The method is described on [`cut_perforations`].

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{DisjointSets, PointIndex, TriMesh, remove_unused_vertices};

use super::collapse::collapse_in_order;
use super::sorted_edges;
use super::voxel_columns::SheetColumns;
pub use super::voxel_columns::VoxelPart;

/// Boundary loops of at most this many edges are holes (the cleaning fills holes of up to 200
/// edges), longer ones the sheet's rims.
const SMALL_HOLE_EDGES: usize = 200;

/// Boundary loops longer than this (voxels) are rims whatever their edge count: on slices
/// twice the pixels apart the generated wedge's rim at 30 % noise had 183 edges over 256
/// voxels, and the cut, taking it for a hole, bit into the plate's thin end from it (coverage
/// 0.912; 0.985 with this bound). The holes of the generated phantoms' sheets are at most 117
/// voxels around, their rims at least 248.
const SMALL_HOLE_PERIMETER_VOXELS: f64 = 200.0;

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
    /// A vertex is over air when the mean of its column and of four columns half a voxel from
    /// it along the sheet is below the threshold plus this fraction of the way to the part's
    /// level (the median column of its piece of sheet), and below the midpoint of the
    /// background and the part's level plus this fraction of the way from there to the level
    /// (the same point when the threshold is the midpoint), and lies 4.5 deviations of its
    /// noise below the level.
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

/// The vertices on a sheet's rims and junctions, given its `edges` once per triangle they
/// bound (sorted): rims are boundary loops of more than `SMALL_HOLE_EDGES` edges or longer
/// than `SMALL_HOLE_PERIMETER_VOXELS` (shorter loops are holes the ridge test already
/// opened, partly, over a perforation), junctions edges of three or more triangles (where
/// the across direction is the ridge's of one sheet only).
fn rims_and_junctions(mesh: &TriMesh, edges: &[(u32, u32)], voxel: f64) -> Vec<bool> {
    let n = mesh.vertices.len();
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
    let mut loop_length = vec![0.0; n];
    for &(a, b) in &boundary_edges {
        let root = loops.find(a) as usize;
        loop_edges[root] += 1;
        loop_length[root] += mesh.vertices[a as usize].distance(mesh.vertices[b as usize]);
    }
    let rim_length = SMALL_HOLE_PERIMETER_VOXELS * voxel;
    for &(a, b) in &boundary_edges {
        let root = loops.find(a) as usize;
        if loop_edges[root] > SMALL_HOLE_EDGES || loop_length[root] > rim_length {
            excluded[a as usize] = true;
            excluded[b as usize] = true;
        }
    }
    excluded
}

/// Which vertices of `mesh` (whose normals must hold the across directions) stand over
/// little material ([`PerforationParams::little_material_fraction`]); `None` without normals.
pub(crate) fn over_little_material(
    mesh: &TriMesh,
    part: &VoxelPart<'_>,
    params: &PerforationParams,
    voxel: f64,
) -> Option<Vec<bool>> {
    let mut edges = sorted_edges(mesh);
    edges.dedup();
    let columns = SheetColumns::read(mesh, &edges, part, params.column_half_length_voxels, voxel)?;
    Some(columns.below(params.little_material_fraction))
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
/// vertex over a hole's middle is enough, and noise of 30% of the contrast puts no mean of
/// five columns over material that low) is a perforation, and the triangles touching it are removed,
/// unless the region reaches a junction (where the column follows one sheet only: at 30%
/// noise a cut opened the T-junction) or a rim of the sheet, or passes within
/// `RIM_CLEARANCE_VOXELS` of one. Rims (boundary loops longer than a hole's) run out to the
/// part's rounded edges, whose columns hold little material: cutting there cost the
/// T-junction and the wedge's 2-voxel end 2–3% of their coverage.
///
/// A hole lies in the part, which surrounds it along the sheet; the raw sheet also holds
/// folds standing 2–2.5 voxels off a plate into the air beside it, whose across direction
/// lies along the plate, and their columns read air too. Cutting into a fold opens a hole
/// the part does not have (on the small perforations at 10 % noise, isotropic seed 1 and 2×
/// seed 8 of 1–8 ended with χ one too low). So a region is cut only when one of its air
/// vertices is flanked by material along the sheet (`SheetColumns::flanked`); a region over
/// air that is not is a fold, taken back as far as elementary collapses from its free edges
/// go (`super::collapse`: a fin goes whole, a blister attached all round stays), which
/// keeps the sheet's topology. The count returned is of the regions cut.
pub fn cut_perforations(
    mesh: &mut TriMesh,
    part: &VoxelPart<'_>,
    params: &PerforationParams,
    voxel: f64,
) -> usize {
    let n = mesh.vertices.len();
    let mut edges = sorted_edges(mesh);
    let excluded = rims_and_junctions(mesh, &edges, voxel);
    edges.dedup();
    let Some(columns) =
        SheetColumns::read(mesh, &edges, part, params.column_half_length_voxels, voxel)
    else {
        return 0;
    };
    // Hysteresis: a region of vertices over little material is a perforation when some of
    // its vertices are over air.
    let little = columns.below(params.little_material_fraction);
    // Only a vertex over little material belongs to a region: the others' air is not read.
    let air = columns.over_air(mesh, &little, params.air_fraction, voxel);
    let mut regions = DisjointSets::new(n);
    for &(a, b) in &edges {
        if little[a as usize] && little[b as usize] {
            regions.union(a, b);
        }
    }
    let root: Vec<u32> = (0..n as u32).map(|v| regions.find(v)).collect();
    // An air vertex with material around it along the sheet lies over a hole; one without
    // lies on a fold standing off the part (see `SheetColumns::flanked`).
    let normals = mesh.normals.as_deref().unwrap_or_default();
    let over_hole: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|v| {
            air[v]
                && columns.flanked(
                    mesh.vertices[v],
                    normals[v],
                    v,
                    params.little_material_fraction,
                    voxel,
                )
        })
        .collect();
    let mut over_air = vec![false; n];
    let mut hole = vec![false; n];
    let mut reaches_boundary = vec![false; n];
    for v in (0..n).filter(|&v| little[v]) {
        over_air[root[v] as usize] |= air[v];
        hole[root[v] as usize] |= over_hole[v];
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
    let in_region = |v: usize, over: &[bool]| {
        let r = root[v] as usize;
        little[v] && over[r] && !reaches_boundary[r]
    };
    let cut: Vec<bool> = (0..n).map(|v| in_region(v, &hole)).collect();
    // A fold is taken back as far as collapses from its free edges go: cutting into it would
    // open a hole the part does not have.
    let on_fold: Vec<bool> = (0..n).map(|v| !cut[v] && in_region(v, &over_air)).collect();
    let fold_triangles: Vec<bool> = mesh
        .triangles
        .iter()
        .map(|t| t.iter().any(|&v| on_fold[v as usize]))
        .collect();
    let collapsed = if fold_triangles.contains(&true) {
        collapse_in_order(mesh, &fold_triangles, &vec![0.0; mesh.triangles.len()])
    } else {
        vec![false; mesh.triangles.len()]
    };
    let mut perforations: Vec<u32> = (0..n).filter(|&v| cut[v]).map(|v| root[v]).collect();
    perforations.sort_unstable();
    perforations.dedup();
    if perforations.is_empty() && !collapsed.contains(&true) {
        return 0;
    }
    let mut t = 0;
    mesh.triangles.retain(|tri| {
        t += 1;
        !collapsed[t - 1] && !tri.iter().any(|&v| cut[v as usize])
    });
    remove_unused_vertices(mesh);
    perforations.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use sphcover_core::{Volume, VoxelValues};

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

    /// `volume` as a part of level 1 over a background of 0, thresholded at 0.5, without noise.
    fn noiseless(volume: &Volume) -> VoxelPart<'_> {
        VoxelPart {
            volume,
            threshold: 0.5,
            background: 0.0,
            noise: 0.0,
        }
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
        // Noise that reaches from the part's level to the hole's columns (4.5 deviations of
        // five columns' mean, 4.5 · 0.7 / √9, exceed the contrast): nothing is taken for air.
        let noisy = VoxelPart {
            noise: 0.7,
            ..part(&holed)
        };
        let mut unsure = sheet();
        assert_eq!(cut_perforations(&mut unsure, &noisy, &params, 1.0), 0);
    }

    /// A line of voxels at half the part's value through the slab: the column along it reads
    /// 0.5, under the air limit (0.625, a quarter of the way from the threshold to the level),
    /// but the air test reads the mean of five columns half a voxel apart, 0.7. A hole of
    /// radius 1 voxel or more holds all five (the 1.2-voxel hole above is cut).
    #[test]
    fn a_dip_narrower_than_the_air_test_is_not_cut() {
        let params = PerforationParams::default();
        let dip = slab(|i, j| if i == 12.0 && j == 12.0 { 0.5 } else { 1.0 });
        let mut mesh = sheet();
        assert_eq!(
            cut_perforations(&mut mesh, &noiseless(&dip), &params, 1.0),
            0
        );
        assert_eq!(mesh, sheet());
    }

    /// A loop of few long edges is a rim: a square sheet 60 voxels wide of triangles 6
    /// voxels across has a boundary of 40 edges over 240 voxels, all of whose 40 vertices are
    /// on a rim; the same sheet 20 voxels wide (80 voxels around) has none.
    #[test]
    fn long_loops_of_few_edges_are_rims() {
        let rim_vertices = |mesh: &TriMesh| {
            rims_and_junctions(mesh, &sorted_edges(mesh), 1.0)
                .iter()
                .filter(|&&r| r)
                .count()
        };
        let small = sheet_from(0.0, 2.0);
        assert_eq!(rim_vertices(&small), 0);
        let mut large = small;
        for p in &mut large.vertices {
            *p *= 3.0;
        }
        assert_eq!(rim_vertices(&large), 40);
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

    /// A fold of the sheet standing off a plate without holes, into the air beside it (its
    /// across direction along the plate, as the ridge's is there): its columns read air, but
    /// no hole is cut into it, and the sheet keeps its Euler characteristic.
    #[test]
    fn a_fold_off_the_plate_is_not_cut() {
        let params = PerforationParams::default();
        let solid = plate(-1.0);
        let part = noiseless(&solid);
        let mut mesh = sheet();
        let normals = mesh.normals.as_mut().unwrap();
        for (p, n) in mesh.vertices.iter_mut().zip(normals.iter_mut()) {
            let r = (p.x - 12.0).hypot(p.y - 12.0);
            if r < 2.0 {
                p.z += 2.5 * (1.0 - 0.2 * r);
                *n = DVec3::X;
            }
        }
        let before = sphcover_core::MeshTopology::of(&mesh);
        assert_eq!(cut_perforations(&mut mesh, &part, &params, 1.0), 0);
        let after = sphcover_core::MeshTopology::of(&mesh);
        assert_eq!(after.euler_characteristic(), before.euler_characteristic());
    }

    proptest! {
        /// Over a hole through the plate a column is flanked by material along the sheet; two
        /// to three voxels off the plate, across along it, it is not.
        #[test]
        fn holes_are_flanked_and_folds_are_not(hole in 1.0f64..4.0, angle in 0.0f64..6.3,
                                               offset in 0.0f64..0.5, height in 2.0f64..3.0,
                                               side in 0.0f64..6.3) {
            let volume = plate(hole);
            let part = noiseless(&volume);
            let mesh = sheet();
            let mut edges = sorted_edges(&mesh);
            edges.dedup();
            let columns = SheetColumns::read(&mesh, &edges, &part, 1.0, 1.0).unwrap();
            let fraction = PerforationParams::default().little_material_fraction;
            let r = offset * hole;
            let in_hole = DVec3::new(12.0 + r * angle.cos(), 12.0 + r * angle.sin(), 6.0);
            prop_assert!(columns.flanked(in_hole, DVec3::Z, 0, fraction, 1.0));
            let off = DVec3::new(6.0, 18.0, 6.0 + height);
            let along = DVec3::new(side.cos(), side.sin(), 0.0);
            prop_assert!(!columns.flanked(off, along, 0, fraction, 1.0));
        }
    }
}
