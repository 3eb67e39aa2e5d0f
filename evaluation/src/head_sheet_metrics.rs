//! Scores of a skeletal sheet extracted from the head-CT phantom ([`crate::head_ct_phantom`]),
//! as clinical use judges it: does the sheet stay on bone, does it cover the vault where the
//! vault is thin, is the vault one piece without holes where the bone is continuous, and is
//! the head holder kept as a sheet of its own. Lengths are in world millimetres; "voxels"
//! are in-plane voxels, whatever the slice spacing, so that anisotropic grids are judged
//! against the same anatomy.

use std::collections::HashMap;

use rand::SeedableRng;
use rand_pcg::Pcg64;
use rayon::prelude::*;
use sphcover_core::{DVec3, DisjointSets, MeshTopology, PointIndex, TriMesh};

use crate::head_ct_phantom::{HeadCt, Tissue};
use crate::surface_sampling::SurfaceSampler;
use crate::triangle_bvh::TriangleBvh;

/// A sheet point this close to bone (or holder) voxels is on bone (voxels).
pub const ON_BONE: f64 = 2.0;
/// A vault voxel this close to the sheet is covered (voxels).
pub const COVERED: f64 = 3.0;
/// Vault voxels where the bone is at most this thick are the ones coverage counts (voxels).
pub const THIN_VAULT: f64 = 6.0;
/// Sheet samples of the area score.
const AREA_SAMPLES: usize = 200_000;

/// The scores of a sheet on the head phantom (all zero for an empty sheet).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HeadSheetMetrics {
    /// Sheet area (mm²).
    pub area: f64,
    /// Fraction of the sheet's area within [`ON_BONE`] voxels of a bone or holder voxel.
    pub on_bone: f64,
    /// Fraction of the vault voxels with bone at most [`THIN_VAULT`] voxels thick that lie
    /// within [`COVERED`] voxels of the sheet.
    pub vault_covered: f64,
    /// Components of the sheet that hold at least 1 % of the sheet's area near the vault.
    pub vault_components: usize,
    /// Perimeters (mm) of the holes of the vault's sheet where the bone is continuous
    /// (boundary loops away from the skull base and from other bone), largest first.
    pub vault_holes: Vec<f64>,
    /// Fraction of the holder's mid-surface within [`ON_BONE`] voxels of the sheet.
    pub holder_covered: f64,
    /// The holder's sheet shares no component with the vault's.
    pub holder_separate: bool,
    /// Perimeters (mm) of the holes of the holder's sheet (the boundary loops of the
    /// components its mid-surface lies on, but each component's longest, its outline),
    /// largest first. The holder is one continuous plate: any hole is a defect, which
    /// [`HeadSheetMetrics::holder_covered`] does not see when it is narrower than
    /// 2 · [`ON_BONE`] voxels.
    pub holder_holes: Vec<f64>,
    /// Components of the whole sheet.
    pub components: usize,
    /// Fraction of triangles that share no edge with another (confetti).
    pub isolated_triangles: f64,
}

impl HeadSheetMetrics {
    /// The largest hole's perimeter, 0 without holes.
    pub fn largest_hole(&self) -> f64 {
        self.vault_holes.first().copied().unwrap_or(0.0)
    }
}

/// Centres of the phantom's truth grid whose tissue passes `keep`.
fn voxel_centres(ct: &HeadCt, keep: impl Fn(usize, Tissue) -> bool) -> Vec<DVec3> {
    ct.tissue
        .iter()
        .enumerate()
        .filter(|&(idx, &t)| keep(idx, t))
        .map(|(idx, _)| ct.truth_centre(idx))
        .collect()
}

/// Distance from `x` to the nearest point of `index`.
fn nearest(index: &PointIndex, points: &[DVec3], x: DVec3) -> f64 {
    let mut out = Vec::with_capacity(1);
    index.nearest_k(x, 1, &mut out);
    out.first()
        .map_or(f64::INFINITY, |&i| points[i as usize].distance(x))
}

/// Triangle components (triangles sharing a vertex are connected) and the number of them.
fn triangle_components(mesh: &TriMesh) -> (Vec<u32>, usize) {
    let mut sets = DisjointSets::new(mesh.vertices.len());
    for t in &mesh.triangles {
        sets.union(t[0], t[1]);
        sets.union(t[1], t[2]);
    }
    let mut label = HashMap::new();
    let ids: Vec<u32> = mesh
        .triangles
        .iter()
        .map(|t| {
            let root = sets.find(t[0]);
            let next = label.len() as u32;
            *label.entry(root).or_insert(next)
        })
        .collect();
    (ids, label.len())
}

/// Undirected edge key.
fn edge(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// Scores `sheet` (world mm) against the phantom.
pub fn score_head_sheet(sheet: &TriMesh, ct: &HeadCt) -> HeadSheetMetrics {
    let voxel = ct.pixel;
    let bone = voxel_centres(ct, |_, t| t.is_bone() || t == Tissue::Holder);
    let bone_index = PointIndex::new(&bone).expect("the phantom has bone");
    let vault = voxel_centres(ct, |_, t| t.is_vault());
    let vault_index = PointIndex::new(&vault).expect("the phantom has a vault");
    let other_bone = voxel_centres(ct, |_, t| t == Tissue::OtherBone);
    let other_index = PointIndex::new(&other_bone).expect("the phantom has other bone");
    let thin_vault = thin_vault_voxels(ct);

    let (Ok(sampler), Ok(bvh)) = (SurfaceSampler::new(sheet), TriangleBvh::new(sheet)) else {
        return HeadSheetMetrics::default();
    };
    let mut rng = Pcg64::seed_from_u64(0);
    let samples = sampler.samples(AREA_SAMPLES, &mut rng);
    let on_bone = samples
        .par_iter()
        .filter(|s| nearest(&bone_index, &bone, s.position) <= ON_BONE * voxel)
        .count() as f64
        / samples.len() as f64;

    let distance_to_sheet = |x: DVec3| {
        bvh.closest_point(x)
            .map_or(f64::INFINITY, |c| c.distance_squared.sqrt())
    };
    let covered = thin_vault
        .par_iter()
        .filter(|&&x| distance_to_sheet(x) <= COVERED * voxel)
        .count() as f64
        / thin_vault.len().max(1) as f64;

    let (component, components) = triangle_components(sheet);
    let corners = |t: &[u32; 3]| t.map(|v| sheet.vertices[v as usize]);
    let area_of = |t: &[u32; 3]| {
        let [a, b, c] = corners(t);
        0.5 * (b - a).cross(c - a).length()
    };
    let centroid = |t: &[u32; 3]| {
        let [a, b, c] = corners(t);
        (a + b + c) / 3.0
    };
    let near_vault: Vec<bool> = sheet
        .triangles
        .par_iter()
        .map(|t| nearest(&vault_index, &vault, centroid(t)) <= COVERED * voxel)
        .collect();
    let mut vault_area = vec![0.0; components];
    for (t, (&c, &near)) in sheet
        .triangles
        .iter()
        .zip(component.iter().zip(&near_vault))
    {
        if near {
            vault_area[c as usize] += area_of(t);
        }
    }
    let total_vault_area: f64 = vault_area.iter().sum();
    let vault_components = vault_area
        .iter()
        .filter(|&&a| a > 0.01 * total_vault_area)
        .count();
    let vault_component = (0..components)
        .max_by(|&a, &b| vault_area[a].total_cmp(&vault_area[b]))
        .unwrap_or(0) as u32;

    let base = ct.skull_base_z + COVERED * ct.pixel;
    let mut vault_holes: Vec<f64> = boundary_loops(
        sheet,
        |t| near_vault[t] && component[t] == vault_component,
        |a, b| {
            a.z.min(b.z) < base
                || nearest(&other_index, &other_bone, 0.5 * (a + b)) <= COVERED * voxel
        },
    )
    .into_iter()
    .filter(|l| !l.rim)
    .map(|l| l.perimeter)
    .collect();
    vault_holes.sort_by(|a, b| b.total_cmp(a));

    let holder: Vec<(f64, u32)> = ct
        .holder_mid_surface
        .par_iter()
        .map(|&x| {
            bvh.closest_point(x).map_or((f64::INFINITY, u32::MAX), |c| {
                (c.distance_squared.sqrt(), component[c.triangle as usize])
            })
        })
        .collect();
    let holder_hits: Vec<u32> = holder
        .iter()
        .filter(|(d, _)| *d <= ON_BONE * voxel)
        .map(|&(_, c)| c)
        .collect();
    let holder_covered = holder_hits.len() as f64 / holder.len().max(1) as f64;
    let holder_separate = !holder_hits.is_empty()
        && holder_hits
            .iter()
            .all(|&c| vault_area[c as usize] <= 0.01 * total_vault_area);
    let holder_holes = holder_holes(sheet, &component, &holder_hits);

    let mut edge_use: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &sheet.triangles {
        for k in 0..3 {
            *edge_use.entry(edge(t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    let isolated = sheet
        .triangles
        .iter()
        .filter(|t| (0..3).all(|k| edge_use[&edge(t[k], t[(k + 1) % 3])] == 1))
        .count();
    HeadSheetMetrics {
        area: sampler.area(),
        on_bone,
        vault_covered: covered,
        vault_components,
        vault_holes,
        holder_covered,
        holder_separate,
        holder_holes,
        components: MeshTopology::of(sheet).components,
        isolated_triangles: isolated as f64 / sheet.triangles.len().max(1) as f64,
    }
}

/// Scores of a point set (the non-maximum-suppression baseline's output): the fraction of
/// points on bone, and the vault and holder coverage by the points; the mesh-only scores
/// (components, holes) are left at zero.
pub fn score_head_points(points: &[DVec3], ct: &HeadCt) -> HeadSheetMetrics {
    let voxel = ct.pixel;
    let mut scores = HeadSheetMetrics::default();
    let Ok(index) = PointIndex::new(points) else {
        return scores;
    };
    let bone = voxel_centres(ct, |_, t| t.is_bone() || t == Tissue::Holder);
    let bone_index = PointIndex::new(&bone).expect("the phantom has bone");
    let fraction_within = |queries: &[DVec3], index: &PointIndex, of: &[DVec3], reach: f64| {
        queries
            .par_iter()
            .filter(|&&x| nearest(index, of, x) <= reach * voxel)
            .count() as f64
            / queries.len().max(1) as f64
    };
    scores.on_bone = fraction_within(points, &bone_index, &bone, ON_BONE);
    scores.vault_covered = fraction_within(&thin_vault_voxels(ct), &index, points, COVERED);
    scores.holder_covered = fraction_within(&ct.holder_mid_surface, &index, points, ON_BONE);
    scores
}

/// Centres of the vault voxels where the bone is at most [`THIN_VAULT`] voxels thick.
fn thin_vault_voxels(ct: &HeadCt) -> Vec<DVec3> {
    voxel_centres(ct, |idx, t| {
        t.is_vault() && f64::from(ct.vault_thickness[idx]) <= THIN_VAULT * ct.pixel
    })
}

/// A boundary loop of part of a sheet.
struct BoundaryLoop {
    /// Length (world units).
    perimeter: f64,
    /// Some edge of the loop passes the caller's rim test.
    rim: bool,
    /// A triangle along the loop.
    triangle: usize,
}

/// The boundary loops (edges used once, joined at shared vertices) of the triangles of
/// `sheet` that `keep` admits (by index), each with whether `rim` holds on one of its edges
/// (given the edge's ends).
fn boundary_loops(
    sheet: &TriMesh,
    keep: impl Fn(usize) -> bool,
    rim: impl Fn(DVec3, DVec3) -> bool,
) -> Vec<BoundaryLoop> {
    let mut edge_use: HashMap<(u32, u32), (u32, usize)> = HashMap::new();
    for (i, t) in sheet.triangles.iter().enumerate().filter(|&(i, _)| keep(i)) {
        for k in 0..3 {
            edge_use
                .entry(edge(t[k], t[(k + 1) % 3]))
                .or_insert((0, i))
                .0 += 1;
        }
    }
    let mut boundary: Vec<((u32, u32), usize)> = edge_use
        .into_iter()
        .filter(|&(_, (n, _))| n == 1)
        .map(|(e, (_, t))| (e, t))
        .collect();
    boundary.sort_unstable();
    let mut chains = DisjointSets::new(sheet.vertices.len());
    for &((a, b), _) in &boundary {
        chains.union(a, b);
    }
    let mut loops: HashMap<u32, BoundaryLoop> = HashMap::new();
    for &((a, b), t) in &boundary {
        let (pa, pb) = (sheet.vertices[a as usize], sheet.vertices[b as usize]);
        let entry = loops.entry(chains.find(a)).or_insert(BoundaryLoop {
            perimeter: 0.0,
            rim: false,
            triangle: t,
        });
        entry.perimeter += pa.distance(pb);
        entry.rim |= rim(pa, pb);
    }
    loops.into_values().collect()
}

/// Perimeters of the holes of the components `hits` (the holder's), largest first: every
/// boundary loop of those components but each one's longest.
fn holder_holes(sheet: &TriMesh, component: &[u32], hits: &[u32]) -> Vec<f64> {
    let holder: std::collections::BTreeSet<u32> = hits.iter().copied().collect();
    let mut by_component: HashMap<u32, Vec<f64>> = HashMap::new();
    for l in boundary_loops(sheet, |t| holder.contains(&component[t]), |_, _| false) {
        by_component
            .entry(component[l.triangle])
            .or_default()
            .push(l.perimeter);
    }
    let mut holes: Vec<f64> = by_component
        .into_values()
        .flat_map(|mut loops| {
            loops.sort_by(|a, b| b.total_cmp(a));
            loops.into_iter().skip(1)
        })
        .collect();
    holes.sort_by(|a, b| b.total_cmp(a));
    holes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::head_ct_phantom::{HeadCtParams, head_ct_phantom};

    /// The vault's true mid-surface on a latitude–longitude grid closed by a fan at the top,
    /// with a patch of quads left out at mid-height when `hole` is set.
    fn mid_surface(ct: &HeadCt, hole: bool) -> TriMesh {
        let (rows, cols) = (60usize, 180usize);
        let mut vertices = Vec::new();
        let mut present = Vec::new();
        for i in 0..rows {
            let lat = -0.6 + (i as f64 / rows as f64) * (std::f64::consts::FRAC_PI_2 + 0.6);
            for j in 0..cols {
                let lon = j as f64 / cols as f64 * std::f64::consts::TAU;
                let u = DVec3::new(lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin());
                let p = ct.vault_mid_point(u);
                present.push(p.is_some());
                vertices.push(p.unwrap_or(ct.head_centre()));
            }
        }
        let apex = vertices.len() as u32;
        vertices.push(ct.vault_mid_point(DVec3::Z).unwrap());
        let mut triangles = Vec::new();
        for i in 0..rows {
            for j in 0..cols {
                if hole && (rows / 2..rows / 2 + 4).contains(&i) && j < 10 {
                    continue;
                }
                let a = (i * cols + j) as u32;
                let b = (i * cols + (j + 1) % cols) as u32;
                let quad = if i + 1 == rows {
                    vec![[a, b, apex]]
                } else {
                    let (c, d) = (a + cols as u32, b + cols as u32);
                    vec![[a, b, d], [a, d, c]]
                };
                for t in quad {
                    if t.iter().all(|&v| v == apex || present[v as usize]) {
                        triangles.push(t);
                    }
                }
            }
        }
        TriMesh::new(vertices, triangles)
    }

    #[test]
    fn a_mid_surface_scores_as_covered_and_a_cut_as_a_hole() {
        let ct = head_ct_phantom(&HeadCtParams::small());
        let whole = score_head_sheet(&mid_surface(&ct, false), &ct);
        assert!(whole.on_bone > 0.99, "{whole:?}");
        assert!(whole.vault_covered > 0.99, "{whole:?}");
        assert_eq!(whole.vault_components, 1);
        assert!(whole.vault_holes.is_empty(), "{whole:?}");
        assert_eq!(whole.holder_covered, 0.0);
        assert!(!whole.holder_separate);
        let holed = score_head_sheet(&mid_surface(&ct, true), &ct);
        assert_eq!(holed.vault_holes.len(), 1, "{holed:?}");
        // 10 quads of about 0.93 mm by 4 rows of about 1.6 mm.
        assert!((holed.largest_hole() - 31.0).abs() < 4.0, "{holed:?}");
    }

    /// The holder's true mid-surface (its samples are a grid, row by row) appended to
    /// `mesh`, with a patch of 6 × 6 quads left out at its middle when `hole` is set.
    fn with_holder(ct: &HeadCt, mut mesh: TriMesh, hole: bool) -> TriMesh {
        let samples = &ct.holder_mid_surface;
        let cols = samples.iter().take_while(|p| p.z == samples[0].z).count();
        let rows = samples.len() / cols;
        let first = mesh.vertices.len() as u32;
        mesh.vertices.extend_from_slice(samples);
        let (mid_row, mid_col) = (rows / 2, cols / 2);
        for i in 0..rows - 1 {
            for j in 0..cols - 1 {
                if hole
                    && (mid_row..mid_row + 6).contains(&i)
                    && (mid_col..mid_col + 6).contains(&j)
                {
                    continue;
                }
                let a = first + (i * cols + j) as u32;
                let (b, c, d) = (a + 1, a + cols as u32, a + cols as u32 + 1);
                mesh.triangles.extend([[a, b, d], [a, d, c]]);
            }
        }
        mesh
    }

    #[test]
    fn a_hole_in_the_holder_is_counted_and_its_outline_is_not() {
        let ct = head_ct_phantom(&HeadCtParams::small());
        let whole = score_head_sheet(&with_holder(&ct, mid_surface(&ct, false), false), &ct);
        assert!(whole.holder_covered > 0.99, "{whole:?}");
        assert!(whole.holder_separate);
        assert!(whole.holder_holes.is_empty(), "{:?}", whole.holder_holes);
        assert!(whole.vault_holes.is_empty(), "{:?}", whole.vault_holes);
        let holed = score_head_sheet(&with_holder(&ct, mid_surface(&ct, false), true), &ct);
        // 6 × 6 quads of about half a millimetre: a loop of about 12 mm. Too narrow for the
        // coverage to see.
        assert_eq!(holed.holder_holes.len(), 1, "{:?}", holed.holder_holes);
        assert!(
            (holed.holder_holes[0] - 12.0).abs() < 1.5,
            "{:?}",
            holed.holder_holes
        );
        assert!(holed.holder_covered > 0.99, "{holed:?}");
    }

    #[test]
    fn nothing_scores_zero() {
        let ct = head_ct_phantom(&HeadCtParams::small());
        let m = score_head_sheet(&TriMesh::new(Vec::new(), Vec::new()), &ct);
        assert_eq!((m.area, m.vault_covered, m.components), (0.0, 0.0, 0));
    }
}
