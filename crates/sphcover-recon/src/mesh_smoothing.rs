//! Two-step Laplacian smoothing of a triangle mesh (thesis §5.2.2, eq. 5.3–5.5).
//!
//! The method is described on [`smooth_two_step()`].

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::TriMesh;

#[cfg(doc)]
use crate::GraphCutReconstructionParams;

/// The λ of the thesis (eq. 5.3–5.5).
pub(crate) const DEFAULT_LAMBDA: f64 = 0.5;

/// The round count of the thesis for the graph-cut surface (§5.2.2).
pub(crate) const DEFAULT_ROUNDS: usize = 30;

/// Vertices per rayon task at least: one umbrella costs tens of nanoseconds.
const MIN_VERTICES_PER_TASK: usize = 1024;

/// Why a mesh could not be smoothed. The mesh is left unchanged.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SmoothingError {
    /// The movable mask does not have one entry per vertex.
    #[error("movable mask has {found} entries, expected one per vertex ({expected})")]
    MaskLength {
        /// Number of vertices.
        expected: usize,
        /// Length of the mask.
        found: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {vertex} but there are {vertices} vertices")]
    IndexOutOfRange {
        /// Index of the triangle.
        triangle: usize,
        /// The vertex index given.
        vertex: u32,
        /// Number of vertices.
        vertices: usize,
    },
    /// λ is not finite.
    #[error("lambda = {lambda} is not finite")]
    InvalidLambda {
        /// The value given.
        lambda: f64,
    },
    /// A vertex position is NaN or infinite; it would spread to its neighbours.
    #[error("vertex {index} ({position}) is not finite")]
    NonFiniteVertex {
        /// Index of the vertex.
        index: usize,
        /// The position.
        position: DVec3,
    },
}

/// The 1-rings of a mesh's vertices in compressed form: the neighbours of vertex `v` are
/// `neighbours[offsets[v]..offsets[v + 1]]`, ascending and without repetition. Two vertices
/// are neighbours when some triangle holds both.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VertexRings {
    /// `vertices + 1` offsets into `neighbours`.
    pub offsets: Vec<u32>,
    /// Neighbour indices, grouped per vertex.
    pub neighbours: Vec<u32>,
}

impl VertexRings {
    /// The 1-rings of the vertices `0..vertex_count` of `triangles`.
    ///
    /// Degenerate triangles (a repeated index) contribute only their distinct pairs, and a
    /// vertex is never its own neighbour.
    pub fn new(vertex_count: usize, triangles: &[[u32; 3]]) -> Result<VertexRings, SmoothingError> {
        for (t, tri) in triangles.iter().enumerate() {
            if let Some(&vertex) = tri.iter().find(|&&v| v as usize >= vertex_count) {
                return Err(SmoothingError::IndexOutOfRange {
                    triangle: t,
                    vertex,
                    vertices: vertex_count,
                });
            }
        }
        // Directed half-edges (a, b) for every ordered pair of distinct corners, sorted, then
        // deduplicated: a counting sort by `a` followed by a per-vertex sort by `b`.
        let mut counts = vec![0u32; vertex_count + 1];
        for tri in triangles {
            for k in 0..3 {
                let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                counts[a as usize + 1] += u32::from(a != b) + u32::from(a != c);
            }
        }
        for v in 0..vertex_count {
            counts[v + 1] += counts[v];
        }
        let mut fill = counts.clone();
        let mut raw = vec![0u32; counts[vertex_count] as usize];
        for tri in triangles {
            for k in 0..3 {
                let a = tri[k];
                for b in [tri[(k + 1) % 3], tri[(k + 2) % 3]] {
                    if a != b {
                        raw[fill[a as usize] as usize] = b;
                        fill[a as usize] += 1;
                    }
                }
            }
        }
        let mut offsets = Vec::with_capacity(vertex_count + 1);
        let mut neighbours = Vec::with_capacity(raw.len() / 2);
        offsets.push(0u32);
        for v in 0..vertex_count {
            let ring = &mut raw[counts[v] as usize..counts[v + 1] as usize];
            ring.sort_unstable();
            let mut last = None;
            for &b in ring.iter() {
                if last != Some(b) {
                    neighbours.push(b);
                    last = Some(b);
                }
            }
            offsets.push(neighbours.len() as u32);
        }
        Ok(VertexRings {
            offsets,
            neighbours,
        })
    }

    /// The neighbours of vertex `v`, ascending.
    pub fn ring(&self, v: usize) -> &[u32] {
        &self.neighbours[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// True when there is no vertex.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The umbrella vector `U(v) = (1/n) Σ_j (v_j − v)` of vertex `v` over its 1-ring; zero for
/// an isolated vertex.
#[inline]
fn umbrella(positions: &[DVec3], ring: &[u32], v: DVec3) -> DVec3 {
    if ring.is_empty() {
        return DVec3::ZERO;
    }
    let mut sum = DVec3::ZERO;
    for &j in ring {
        sum += positions[j as usize] - v;
    }
    sum / ring.len() as f64
}

/// Smooths `mesh` in place with `rounds` rounds of the two-step Laplacian
/// `v' = v + λU(v)`, `v'' = v' − λU'(v')` (thesis eq. 5.3–5.5; λ = 0.5 and 30 rounds there, the defaults of [`GraphCutReconstructionParams`]).
///
/// Only vertices with `movable[v] == true` move (all of them when `movable` is `None`); the
/// others stay put but still pull on their neighbours. Vertices in no triangle never move.
/// The connectivity is unchanged. Per-vertex normals, if present, no longer match the moved
/// positions and are dropped (`mesh.normals = None`) unless no vertex was allowed to move;
/// per-vertex values are kept.
///
/// Bit-identical whatever the thread count. On error the mesh is unchanged.
///
/// One round moves every movable vertex twice, with the umbrella operator over its 1-ring
/// `U(v) = (1/n) Σ_j (v_j − v)`:
///
/// ```text
/// v'  = v  + λ U(v)        (shrinking step)
/// v'' = v' − λ U'(v')      (inflating step, U' taken on the positions v')
/// ```
///
/// The second step undoes most of the shrinkage of the first (Taubin's λ|μ idea with μ = −λ),
/// so high-frequency noise goes while the volume stays roughly where it was. The thesis uses
/// λ = 0.5 and 30 rounds on the vertices placed at an end of an inconsistent cut edge.
///
/// Each step is a Jacobi update: every vertex reads the positions of the previous step only,
/// and its sum runs over its neighbours in ascending index. So the result is bit-identical
/// whatever the thread count.
pub fn smooth_two_step(
    mesh: &mut TriMesh,
    movable: Option<&[bool]>,
    rounds: usize,
    lambda: f64,
) -> Result<(), SmoothingError> {
    let n = mesh.vertices.len();
    if let Some(mask) = movable
        && mask.len() != n
    {
        return Err(SmoothingError::MaskLength {
            expected: n,
            found: mask.len(),
        });
    }
    if !lambda.is_finite() {
        return Err(SmoothingError::InvalidLambda { lambda });
    }
    if let Some(index) = mesh.vertices.iter().position(|p| !p.is_finite()) {
        return Err(SmoothingError::NonFiniteVertex {
            index,
            position: mesh.vertices[index],
        });
    }
    let rings = VertexRings::new(n, &mesh.triangles)?;
    let any_movable = movable.is_none_or(|mask| mask.iter().any(|&m| m));
    if rounds == 0 || !any_movable {
        return Ok(());
    }
    let mut current = std::mem::take(&mut mesh.vertices);
    let mut next = current.clone();
    let step = |from: &[DVec3], to: &mut [DVec3], factor: f64| {
        to.par_iter_mut()
            .with_min_len(MIN_VERTICES_PER_TASK)
            .enumerate()
            .for_each(|(v, out)| {
                let p = from[v];
                *out = if movable.is_none_or(|mask| mask[v]) {
                    p + umbrella(from, rings.ring(v), p) * factor
                } else {
                    p
                };
            });
    };
    for _ in 0..rounds {
        step(&current, &mut next, lambda);
        step(&next, &mut current, -lambda);
    }
    mesh.vertices = current;
    mesh.normals = None;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeSet;

    /// An icosahedron subdivided `levels` times on the unit sphere.
    pub(crate) fn icosphere(levels: usize) -> TriMesh {
        sphcover_evaluation::ground_truth_meshes::icosphere(DVec3::ZERO, 1.0, levels as u32)
    }

    /// A deterministic pseudo-random value in [−1, 1) from an integer (splitmix64).
    fn hash_unit(i: u64) -> f64 {
        let mut z = i.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn noisy_sphere(levels: usize, amplitude: f64) -> TriMesh {
        let mut mesh = icosphere(levels);
        for (i, v) in mesh.vertices.iter_mut().enumerate() {
            *v *= 1.0 + amplitude * hash_unit(i as u64);
        }
        mesh
    }

    /// The definition, written the slow and obvious way.
    fn smooth_oracle(
        mesh: &TriMesh,
        movable: Option<&[bool]>,
        rounds: usize,
        lambda: f64,
    ) -> Vec<DVec3> {
        let n = mesh.vertices.len();
        let mut rings = vec![BTreeSet::new(); n];
        for tri in &mesh.triangles {
            for &a in tri {
                for &b in tri {
                    if a != b {
                        rings[a as usize].insert(b);
                    }
                }
            }
        }
        let umbrella_at = |pos: &[DVec3], v: usize| -> DVec3 {
            let ring = &rings[v];
            if ring.is_empty() {
                return DVec3::ZERO;
            }
            let mut sum = DVec3::ZERO;
            for &j in ring {
                sum += pos[j as usize] - pos[v];
            }
            sum / ring.len() as f64
        };
        let may_move = |v: usize| movable.is_none_or(|m| m[v]);
        let mut pos = mesh.vertices.clone();
        for _ in 0..rounds {
            let first: Vec<DVec3> = (0..n)
                .map(|v| {
                    if may_move(v) {
                        pos[v] + umbrella_at(&pos, v) * lambda
                    } else {
                        pos[v]
                    }
                })
                .collect();
            pos = (0..n)
                .map(|v| {
                    if may_move(v) {
                        first[v] + umbrella_at(&first, v) * -lambda
                    } else {
                        first[v]
                    }
                })
                .collect();
        }
        pos
    }

    fn radius_spread(mesh: &TriMesh) -> f64 {
        let r: Vec<f64> = mesh.vertices.iter().map(|v| v.length()).collect();
        let mean = r.iter().sum::<f64>() / r.len() as f64;
        (r.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / r.len() as f64).sqrt()
    }

    #[test]
    fn matches_the_definition_bitwise() {
        let mesh = noisy_sphere(3, 0.05);
        let mask: Vec<bool> = (0..mesh.vertices.len()).map(|i| i % 3 != 0).collect();
        for movable in [None, Some(mask.as_slice())] {
            let mut smoothed = mesh.clone();
            smooth_two_step(&mut smoothed, movable, 7, 0.5).unwrap();
            assert_eq!(smoothed.vertices, smooth_oracle(&mesh, movable, 7, 0.5));
        }
    }

    #[test]
    fn removes_noise_and_keeps_the_size() {
        let mut mesh = noisy_sphere(4, 0.05);
        let before = radius_spread(&mesh);
        smooth_two_step(&mut mesh, None, DEFAULT_ROUNDS, DEFAULT_LAMBDA).unwrap();
        let after = radius_spread(&mesh);
        assert!(after < 0.35 * before, "spread {before} -> {after}");
        let mean_radius =
            mesh.vertices.iter().map(|v| v.length()).sum::<f64>() / mesh.vertices.len() as f64;
        // Plain Laplacian smoothing with the same total step shrinks the sphere by several
        // percent; the inflating step keeps it within one percent here.
        assert!(
            (mean_radius - 1.0).abs() < 0.01,
            "mean radius {mean_radius}"
        );
    }

    #[test]
    fn fixed_vertices_stay_exactly_in_place() {
        let mut mesh = noisy_sphere(3, 0.05);
        let original = mesh.vertices.clone();
        let mask: Vec<bool> = (0..mesh.vertices.len()).map(|i| i % 2 == 0).collect();
        smooth_two_step(&mut mesh, Some(&mask), 5, 0.5).unwrap();
        let mut moved = 0;
        for (v, (&a, &b)) in original.iter().zip(&mesh.vertices).enumerate() {
            if mask[v] {
                moved += usize::from(a != b);
            } else {
                assert_eq!(a, b);
            }
        }
        assert!(moved > 0);
    }

    #[test]
    fn nothing_movable_leaves_mesh_and_normals_unchanged() {
        let mut mesh = noisy_sphere(2, 0.05);
        mesh.normals = Some(mesh.vertices.clone());
        let original = mesh.clone();
        let mask = vec![false; mesh.vertices.len()];
        smooth_two_step(&mut mesh, Some(&mask), 5, 0.5).unwrap();
        assert_eq!(mesh, original);
        smooth_two_step(&mut mesh, None, 0, 0.5).unwrap();
        assert_eq!(mesh, original);
    }

    #[test]
    fn bit_identical_whatever_the_thread_count() {
        let mesh = noisy_sphere(5, 0.05);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut m = mesh.clone();
            pool.install(|| smooth_two_step(&mut m, None, 3, 0.5))
                .unwrap();
            m.vertices
        };
        assert_eq!(run(1), run(4));
    }

    #[test]
    fn bad_input_is_refused_and_leaves_the_mesh_unchanged() {
        let mesh = icosphere(1);
        let mut m = mesh.clone();
        assert!(matches!(
            smooth_two_step(&mut m, Some(&[true; 3]), 1, 0.5),
            Err(SmoothingError::MaskLength { found: 3, .. })
        ));
        assert!(matches!(
            smooth_two_step(&mut m, None, 1, f64::NAN),
            Err(SmoothingError::InvalidLambda { .. })
        ));
        assert_eq!(m, mesh);
        m.triangles.push([0, 1, 999]);
        assert!(matches!(
            smooth_two_step(&mut m, None, 1, 0.5),
            Err(SmoothingError::IndexOutOfRange { vertex: 999, .. })
        ));
        let mut m = mesh.clone();
        m.vertices[4].y = f64::INFINITY;
        assert!(matches!(
            smooth_two_step(&mut m, None, 1, 0.5),
            Err(SmoothingError::NonFiniteVertex { index: 4, .. })
        ));
    }

    #[test]
    fn empty_and_degenerate_meshes() {
        let mut empty = TriMesh::default();
        smooth_two_step(&mut empty, None, 3, 0.5).unwrap();
        assert!(empty.vertices.is_empty());
        // A repeated index and an isolated vertex.
        let mut m = TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::splat(7.0)],
            vec![[0, 1, 1], [0, 1, 2]],
        );
        smooth_two_step(&mut m, None, 2, 0.5).unwrap();
        assert_eq!(m.vertices[3], DVec3::splat(7.0));
        assert!(m.vertices.iter().all(|v| v.is_finite()));
        let rings = VertexRings::new(4, &m.triangles).unwrap();
        assert_eq!(rings.ring(0), &[1, 2]);
        assert_eq!(rings.ring(3), &[] as &[u32]);
    }

    #[test]
    fn a_plane_stays_a_plane() {
        // A triangulated 6×6 grid in z = 0 with jittered x, y: U has no z component.
        let n = 6;
        let vertices: Vec<DVec3> = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f64, (i / n) as f64);
                DVec3::new(
                    x + 0.3 * hash_unit(i as u64),
                    y + 0.3 * hash_unit(1000 + i as u64),
                    0.0,
                )
            })
            .collect();
        let mut triangles = Vec::new();
        for y in 0..n - 1 {
            for x in 0..n - 1 {
                let v = (y * n + x) as u32;
                let n = n as u32;
                triangles.push([v, v + 1, v + n + 1]);
                triangles.push([v, v + n + 1, v + n]);
            }
        }
        let mut mesh = TriMesh::new(vertices, triangles);
        smooth_two_step(&mut mesh, None, 10, 0.5).unwrap();
        assert!(mesh.vertices.iter().all(|v| v.z == 0.0));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        /// U commutes with translations and linear maps, so smoothing does too (up to
        /// rounding).
        #[test]
        fn commutes_with_affine_maps(
            shift in prop::array::uniform3(-10.0f64..10.0),
            scale in 0.1f64..10.0,
            angle in 0.0f64..std::f64::consts::TAU,
            rounds in 1usize..6,
            lambda in 0.05f64..0.9,
        ) {
            let shift = DVec3::from_array(shift);
            let rotation = glam::DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), angle);
            let map = |p: DVec3| rotation * p * scale + shift;
            let mesh = noisy_sphere(2, 0.1);
            let mut a = mesh.clone();
            smooth_two_step(&mut a, None, rounds, lambda).unwrap();
            let mut b = mesh.clone();
            b.vertices.iter_mut().for_each(|p| *p = map(*p));
            smooth_two_step(&mut b, None, rounds, lambda).unwrap();
            for (p, q) in a.vertices.iter().zip(&b.vertices) {
                let tol = 1e-12 * (scale + shift.length() + 1.0) * 16.0;
                prop_assert!((map(*p) - *q).length() < tol, "{} vs {}", map(*p), q);
            }
        }

        /// The rings are symmetric, sorted and free of self-loops for any triangle soup.
        #[test]
        fn rings_are_symmetric(tris in prop::collection::vec(prop::array::uniform3(0u32..12), 0..40)) {
            let rings = VertexRings::new(12, &tris).unwrap();
            for v in 0..12 {
                let ring = rings.ring(v);
                prop_assert!(ring.windows(2).all(|w| w[0] < w[1]));
                for &j in ring {
                    prop_assert!(j as usize != v);
                    prop_assert!(rings.ring(j as usize).contains(&(v as u32)));
                    prop_assert!(tris.iter().any(|t| t.contains(&(v as u32)) && t.contains(&j)));
                }
            }
        }
    }
}
