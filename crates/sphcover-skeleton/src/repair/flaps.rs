//! Collapsing flaps that stand across the sheet.
//!
//! The method is described on [`collapse_misaligned_flaps()`].

use glam::DVec3;
use sphcover_core::TriMesh;

use super::collapse::FreeEdgeCollapse;
use super::retain_triangles;

/// `|n · ē|` of each triangle: `n` its normal, `ē` the mean across direction of its corners
/// (signs aligned to the first corner's); 1 without normals.
pub fn triangle_alignment(mesh: &TriMesh) -> Vec<f64> {
    mesh.triangles
        .iter()
        .map(|t| {
            let Some(normals) = &mesh.normals else {
                return 1.0;
            };
            let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
            let n = (b - a).cross(c - a).normalize_or_zero();
            let first = normals[t[0] as usize];
            let mean: DVec3 = t
                .iter()
                .map(|&v| {
                    let e = normals[v as usize];
                    if e.dot(first) < 0.0 { -e } else { e }
                })
                .sum();
            n.dot(mean.normalize_or_zero()).abs()
        })
        .collect()
}

/// Parameters of [`collapse_misaligned_flaps`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct FlapParams {
    /// Triangles whose alignment ([`triangle_alignment`]) is below this are collapsed from
    /// the free edges: `|cos|` of the angle between a triangle's normal and its corners'
    /// across direction.
    pub min_alignment: f64,
}

impl Default for FlapParams {
    fn default() -> FlapParams {
        FlapParams { min_alignment: 0.8 }
    }
}

/// Collapses, from the free edges, the triangles whose alignment ([`triangle_alignment`]) is
/// below [`FlapParams::min_alignment`], as described below.
/// Returns the triangles removed.
///
/// On a thick plate the blurred intensity has a flat top, the Hessian's smallest eigenvalues
/// are close there, and the ridge test of eq. 6.5 also fires along in-plane directions: the
/// sheet grows fins standing across it (on the reference wedge at 10 % noise, 2–3 voxels
/// off the true sheet, 7 voxels from its boundary), whose triangles' normals are nearly
/// perpendicular to the across direction `e` of their corners. A fin has a free edge on
/// top; it is eaten from there by elementary collapses (a triangle through its only free
/// edge, or a tip with the edges and corners only it uses: `super::collapse`), which keep
/// the sheet's topology (components, Euler characteristic) whatever is removed. Only
/// triangles lying across the ridge by less than a bound are collapsed, so the collapse
/// stops where the fin meets the sheet.
pub fn collapse_misaligned_flaps(mesh: &mut TriMesh, params: &FlapParams) -> usize {
    let alignment = triangle_alignment(mesh);
    let mut collapse = FreeEdgeCollapse::new(mesh);
    // Candidates in index order, a neighbour of a removed triangle next (deterministic).
    let mut queue: Vec<u32> = (0..mesh.triangles.len() as u32).rev().collect();
    let mut count = 0;
    while let Some(t) = queue.pop() {
        let t = t as usize;
        if alignment[t] >= params.min_alignment || !collapse.try_remove(t) {
            continue;
        }
        count += 1;
        queue.extend(collapse.neighbours(t));
    }
    let removed = collapse.into_removed();
    retain_triangles(&mut mesh.triangles, |t| !removed[t]);
    count
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use sphcover_core::MeshTopology;

    /// An `n × n` grid in z = 0 and a fin of `height` rows standing on the base edges of
    /// x = `fx`, y ∈ [fy, fy + width]; every across direction is `Z`.
    fn base_with_fin(n: u32, fx: u32, fy: u32, width: u32, height: u32) -> TriMesh {
        let id = |i: u32, j: u32| i * (n + 1) + j;
        let mut vertices: Vec<DVec3> = (0..=n)
            .flat_map(|i| (0..=n).map(move |j| DVec3::new(i as f64, j as f64, 0.0)))
            .collect();
        let mut triangles = Vec::new();
        for i in 0..n {
            for j in 0..n {
                triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        let mut row: Vec<u32> = (fy..=fy + width).map(|j| id(fx, j)).collect();
        for k in 1..=height {
            let above: Vec<u32> = (fy..=fy + width)
                .map(|j| {
                    vertices.push(DVec3::new(fx as f64, j as f64, k as f64));
                    (vertices.len() - 1) as u32
                })
                .collect();
            for s in 0..width as usize {
                triangles.push([row[s], row[s + 1], above[s + 1]]);
                triangles.push([row[s], above[s + 1], above[s]]);
            }
            row = above;
        }
        let count = vertices.len();
        let mut m = TriMesh::new(vertices, triangles);
        m.normals = Some(vec![DVec3::Z; count]);
        m
    }

    proptest! {
        /// A fin across the sheet is eaten whole; the base, its components and its Euler
        /// characteristic stay; with a bound of 0 nothing goes.
        #[test]
        fn a_fin_is_collapsed_to_the_sheet(n in 3u32..8, fx in 1u32..7, width in 1u32..4,
                                           height in 1u32..4) {
            let fx = 1 + fx % (n - 1);
            let width = width.min(n);
            let mut m = base_with_fin(n, fx, 0, width, height);
            let base = 2 * (n * n) as usize;
            let before = MeshTopology::of(&m);
            let mut same = m.clone();
            prop_assert_eq!(collapse_misaligned_flaps(&mut same, &FlapParams { min_alignment: 0.0 }), 0);
            prop_assert_eq!(&same, &m);
            let fin = m.triangles.len() - base;
            prop_assert_eq!(collapse_misaligned_flaps(&mut m, &FlapParams { min_alignment: 0.5 }), fin);
            prop_assert_eq!(m.triangles.len(), base);
            let after = MeshTopology::of(&m);
            prop_assert_eq!(after.euler_characteristic(), before.euler_characteristic());
            prop_assert_eq!(after.components, before.components);
        }

        /// Whatever the bound, collapsing keeps the topology (random across directions).
        #[test]
        fn collapsing_keeps_the_topology(n in 3u32..7, height in 1u32..4, bound in 0.0f64..1.0,
                                         seed in any::<u64>()) {
            let mut m = base_with_fin(n, 1, 0, n.min(3), height);
            let mut rng = sphcover_core::random::XorShift64::new(seed | 1);
            let normals: Vec<DVec3> = (0..m.vertices.len())
                .map(|_| {
                    let mut next = || rng.uniform() - 0.5;
                    DVec3::new(next(), next(), next()).normalize_or(DVec3::Z)
                })
                .collect();
            m.normals = Some(normals);
            let before = MeshTopology::of(&m);
            collapse_misaligned_flaps(&mut m, &FlapParams { min_alignment: bound });
            let after = MeshTopology::of(&m);
            prop_assert_eq!(after.euler_characteristic(), before.euler_characteristic());
            prop_assert_eq!(after.components, before.components);
        }
    }
}
