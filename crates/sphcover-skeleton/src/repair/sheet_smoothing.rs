//! Smoothing of the sheet across itself: Jacobi rounds of the umbrella (1-ring mean) step,
//! restricted to each vertex's across direction `e`.
//!
//! The method is described on [`smooth_across()`].

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::TriMesh;

/// Parameters of [`smooth_across`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct SmoothingParams {
    /// Jacobi rounds.
    pub rounds: usize,
    /// `λ`: the fraction of the step to the neighbours' plane taken per round.
    pub lambda: f64,
}

impl Default for SmoothingParams {
    fn default() -> SmoothingParams {
        SmoothingParams {
            rounds: 3,
            lambda: 0.5,
        }
    }
}

/// Runs [`SmoothingParams::rounds`] Jacobi rounds of `v ← v + λ ⟨m − v, e⟩ e` with `m` the
/// mean of the 1-ring neighbours of `v` and `e` its normal. Needs per-vertex normals (does
/// nothing without them); vertices without a neighbour stay.
///
/// The patch vertices carry the noise of the ridge points and of the tetrahedron centroids
/// between them, which zig-zag across the sheet by a fraction of a voxel. Moving each
/// vertex only along its across direction `e`, towards the plane through the mean of its
/// neighbours, removes that zig-zag without shrinking the sheet along itself or pulling its
/// boundary inwards (the tangential part of the umbrella step is dropped).
pub fn smooth_across(mesh: &mut TriMesh, params: &SmoothingParams) {
    let SmoothingParams { rounds, lambda } = *params;
    let Some(normals) = mesh.normals.clone() else {
        return;
    };
    let n = mesh.vertices.len();
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            neighbours[a as usize].push(b);
            neighbours[b as usize].push(a);
        }
    }
    for list in &mut neighbours {
        list.sort_unstable();
        list.dedup();
    }
    for _ in 0..rounds {
        let current = mesh.vertices.clone();
        mesh.vertices = (0..n)
            .into_par_iter()
            .with_min_len(1024)
            .map(|v| {
                let ring = &neighbours[v];
                if ring.is_empty() {
                    return current[v];
                }
                let mean =
                    ring.iter().map(|&w| current[w as usize]).sum::<DVec3>() / ring.len() as f64;
                let e = normals[v];
                current[v] + lambda * (mean - current[v]).dot(e) * e
            })
            .collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn zigzag_grid(amplitude: f64) -> TriMesh {
        let n = 8u32;
        let mut v = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let z = if (i + j) % 2 == 0 {
                    amplitude
                } else {
                    -amplitude
                };
                v.push(DVec3::new(i as f64, j as f64, z));
            }
        }
        let id = |i: u32, j: u32| j * (n + 1) + i;
        let mut t = Vec::new();
        for j in 0..n {
            for i in 0..n {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        let mut m = TriMesh::new(v, t);
        m.normals = Some(vec![DVec3::Z; m.vertices.len()]);
        m
    }

    proptest! {
        /// Vertices move only along their normal: in-plane coordinates are unchanged, and a
        /// flat sheet stays exactly where it is.
        #[test]
        fn moves_only_across(amplitude in 0.0..0.5f64, rounds in 1usize..5) {
            let mut m = zigzag_grid(amplitude);
            let before = m.vertices.clone();
            smooth_across(&mut m, &SmoothingParams { rounds, lambda: 0.5 });
            for (a, b) in before.iter().zip(&m.vertices) {
                prop_assert!(a.x == b.x && a.y == b.y);
                prop_assert!(b.z.abs() <= amplitude + 1e-12);
            }
            if amplitude == 0.0 {
                prop_assert!(m.vertices == before);
            }
        }
    }

    #[test]
    fn zigzag_is_flattened() {
        let mut m = zigzag_grid(0.3);
        smooth_across(&mut m, &SmoothingParams::default());
        let interior_max = m
            .vertices
            .iter()
            .filter(|p| p.x > 0.5 && p.x < 7.5 && p.y > 0.5 && p.y < 7.5)
            .fold(0.0f64, |a, p| a.max(p.z.abs()));
        assert!(interior_max < 0.1, "{interior_max}");
    }
}
