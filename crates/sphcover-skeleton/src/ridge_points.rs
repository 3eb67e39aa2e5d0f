//! Ridge points on the edges of the tetrahedral mesh (thesis §6.2.1, eq. 6.1, 6.4, 6.5).
//!
//! The method is described on [`ridge_points()`].

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::PuEvaluator;
use sphcover_tetra::TetMesh;

use crate::slice_stretch::{SliceStretch, ridge_eigen};
use crate::symmetric_eigen::SmallestEigen;

/// `f`, `∇f` and the Hessian's smallest eigenpair at one vertex of the tetrahedral mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexDerivatives {
    /// Position (the support centre).
    pub position: DVec3,
    /// `f` there.
    pub value: f64,
    /// `∇f` there.
    pub gradient: DVec3,
    /// Eigenvalues and the smallest eigenvector of `∇²f` there.
    pub eigen: SmallestEigen,
}

/// Evaluates [`VertexDerivatives`] at `positions` (in parallel, per point: deterministic);
/// `None` where `f` is undefined or its Hessian not finite.
pub(crate) fn vertex_derivatives(
    evaluator: &PuEvaluator<'_>,
    positions: &[DVec3],
    stretch: Option<&SliceStretch>,
) -> Vec<Option<VertexDerivatives>> {
    let vgh = evaluator.values_gradients_hessians(positions);
    positions
        .par_iter()
        .zip(vgh)
        .map(|(&position, d)| {
            let d = d?;
            let eigen = ridge_eigen(&d.hessian, stretch)?;
            Some(VertexDerivatives {
                position,
                value: d.value,
                gradient: d.gradient,
                eigen,
            })
        })
        .collect()
}

/// Filters of [`ridge_points`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RidgeFilter {
    /// Smallest `−λ1` of a ridge point, as a fraction of the largest `−λ1` over the vertices.
    pub min_relative_strength: f64,
    /// Largest `λ2 / λ1` of a ridge point (only tested when `λ2 < 0`); `1` disables it.
    pub max_eigen_ratio: f64,
}

impl Default for RidgeFilter {
    fn default() -> RidgeFilter {
        RidgeFilter {
            min_relative_strength: 0.05,
            max_eigen_ratio: 1.0,
        }
    }
}

/// A ridge point on a mesh edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RidgePoint {
    /// Position.
    pub position: DVec3,
    /// Parameter along the edge from its first vertex (`0..1`).
    pub t: f64,
    /// `−λ1` interpolated: how sharp the ridge is.
    pub strength: f64,
    /// `λ2 / λ1` interpolated (only meaningful when both are negative).
    pub eigen_ratio: f64,
    /// `f` interpolated.
    pub value: f64,
    /// The ridge's across direction `e` (unit, interpolated between the aligned ends): the
    /// sheet's unoriented normal.
    pub direction: DVec3,
}

/// The ridge point on the edge from `a` to `b`, if the ridge crosses it (eq. 6.4, 6.5).
/// Filters are not applied.
pub(crate) fn ridge_point_on_edge(
    a: &VertexDerivatives,
    b: &VertexDerivatives,
) -> Option<RidgePoint> {
    let e1 = a.eigen.vector;
    let e2 = if e1.dot(b.eigen.vector) < 0.0 {
        -b.eigen.vector
    } else {
        b.eigen.vector
    };
    let s1 = e1.dot(a.gradient);
    let s2 = e2.dot(b.gradient);
    let product = s1 * s2;
    if product.is_nan() || product >= 0.0 {
        return None;
    }
    let d = b.position - a.position;
    let concave = a.eigen.values[0] < 0.0 && b.eigen.values[0] < 0.0;
    if !(concave || s1 * d.dot(e1) > 0.0 || s2 * (-d).dot(e2) > 0.0) {
        return None;
    }
    let t = s1 / (s1 - s2);
    let lerp = |x: f64, y: f64| x + t * (y - x);
    let l1 = lerp(a.eigen.values[0], b.eigen.values[0]);
    if l1.is_nan() || l1 >= 0.0 {
        return None;
    }
    let l2 = lerp(a.eigen.values[1], b.eigen.values[1]);
    Some(RidgePoint {
        position: a.position + t * d,
        t,
        strength: -l1,
        eigen_ratio: l2 / l1,
        value: lerp(a.value, b.value),
        direction: (e1 + t * (e2 - e1)).normalize_or(e1),
    })
}

/// Gives the eigenvectors of `derivatives` one consistent sign over each connected part of
/// `mesh`, by propagation along a maximum spanning tree of `|⟨e_i, e_j⟩|` over the mesh
/// edges (Prim's algorithm from the lowest vertex of each part; ties by edge order).
///
/// An eigenvector has no sign, and eq. 6.4 aligns the two ends of each edge separately; but
/// pairwise alignment is not transitive, so around a tetrahedron whose eigenvectors turn, the
/// signs of `s = ⟨e, ∇f⟩` can disagree from edge to edge and cross it on one, two or five
/// edges, which no surface does. With one sign per vertex, `s` is a function on the vertices
/// and every tetrahedron is crossed on 0, 3 or 4 edges, except across the rare edges where the
/// propagated signs still disagree (`⟨e_i, e_j⟩ < 0`), which eq. 6.4's alignment then fixes
/// locally.
pub fn orient_eigenvectors(mesh: &TetMesh, derivatives: &mut [Option<VertexDerivatives>]) {
    use std::cmp::Ordering;
    use std::collections::BinaryHeap;

    #[derive(PartialEq)]
    struct Candidate {
        weight: f64,
        edge: u32,
        to: u32,
    }
    impl Eq for Candidate {}
    impl PartialOrd for Candidate {
        fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
            Some(self.cmp(other))
        }
    }
    impl Ord for Candidate {
        fn cmp(&self, other: &Self) -> Ordering {
            self.weight
                .total_cmp(&other.weight)
                .then_with(|| other.edge.cmp(&self.edge))
        }
    }

    let n = mesh.vertices.len();
    let mut done = vec![false; n];
    let mut heap = BinaryHeap::new();
    let vector = |d: &[Option<VertexDerivatives>], v: u32| d[v as usize].map(|d| d.eigen.vector);
    for root in 0..n as u32 {
        if done[root as usize] || derivatives[root as usize].is_none() {
            continue;
        }
        done[root as usize] = true;
        let push = |heap: &mut BinaryHeap<Candidate>, d: &[Option<VertexDerivatives>], v: u32| {
            let ev = vector(d, v).unwrap_or_default();
            for &e in mesh.edges_of_vertex(v) {
                let [a, b] = mesh.edges[e as usize];
                let to = if a == v { b } else { a };
                if let Some(et) = vector(d, to) {
                    heap.push(Candidate {
                        weight: ev.dot(et).abs(),
                        edge: e,
                        to,
                    });
                }
            }
        };
        push(&mut heap, derivatives, root);
        while let Some(c) = heap.pop() {
            if done[c.to as usize] {
                continue;
            }
            done[c.to as usize] = true;
            let [a, b] = mesh.edges[c.edge as usize];
            let from = if a == c.to { b } else { a };
            let reference = vector(derivatives, from).unwrap_or_default();
            if let Some(d) = &mut derivatives[c.to as usize]
                && d.eigen.vector.dot(reference) < 0.0
            {
                d.eigen.vector = -d.eigen.vector;
            }
            push(&mut heap, derivatives, c.to);
        }
    }
}

/// The ridge point of every edge of `mesh` that has one and passes `filter`, indexed like
/// `mesh.edges`. `derivatives` is indexed by mesh vertex, best with eigenvectors oriented
/// by [`orient_eigenvectors`].
///
/// A point of a skeletal sheet is a ridge of the intensity `f`: with `λ1` the smallest
/// eigenvalue of the Hessian `∇²f` and `e` its unit eigenvector, `⟨e, ∇f⟩ = 0` and `λ1 < 0`
/// (eq. 6.1): `f` has a maximum along `e`. On an edge `(x1, x2)` the eigenvectors at both
/// ends are first aligned (`e2 ← −e2` when `⟨e1, e2⟩ < 0`: an eigenvector has no sign).
/// With `s_k = ⟨e_k, ∇f(x_k)⟩`, the edge crosses the zero set of `s` when `s1 s2 < 0`
/// (eq. 6.4); the crossing is a maximum, not a minimum, when `s_i ⟨x_j − x_i, e_i⟩ > 0` for
/// `(i, j) = (1, 2)` or `(2, 1)` (eq. 6.5: the slope at one end points towards the other).
/// The point is placed by linear interpolation of `s`, and its eigenvalues likewise.
///
/// Eq. 6.5 decides by the sign of `⟨x_j − x_i, e_i⟩`, which is noise for an edge running
/// nearly along the sheet (perpendicular to `e`). When `λ1 < 0` at both ends, `f` is concave
/// along `e` over the edge, so any zero of `s` on it is a maximum: the crossing is accepted
/// without eq. 6.5. On the phantoms this removes most tetrahedra crossed on exactly two
/// edges (an impossible pattern for a surface, which leaves a hole in the patches).
///
/// Two filters go beyond the thesis, both on the interpolated eigenvalues:
/// * strength: `−λ1` must exceed a fraction of the largest strength found at any vertex,
///   which drops the faint ridges of noise;
/// * sheetness: `λ2 / λ1` (both negative near a rim) must stay below a limit. Inside a plate
///   `f` is flat along the sheet (`λ2 ≈ 0`); at a plate's rounded rim it falls off in the
///   in-plane direction too (`λ2 → λ1`), and the rim's ridge points would stick out beyond
///   the true sheet's boundary.
pub fn ridge_points(
    mesh: &TetMesh,
    derivatives: &[Option<VertexDerivatives>],
    filter: &RidgeFilter,
) -> Vec<Option<RidgePoint>> {
    let max_strength = derivatives
        .iter()
        .flatten()
        .map(|d| -d.eigen.values[0])
        .fold(0.0, f64::max);
    let min_strength = filter.min_relative_strength * max_strength;
    mesh.edges
        .par_iter()
        .with_min_len(1024)
        .map(|&[a, b]| {
            let (a, b) = (
                derivatives[a as usize].as_ref()?,
                derivatives[b as usize].as_ref()?,
            );
            let p = ridge_point_on_edge(a, b)?;
            let sheet = p.eigen_ratio <= filter.max_eigen_ratio;
            (p.strength >= min_strength && sheet).then_some(p)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The derivatives of `f(x) = −(n·x − h)²` (a ridge on the plane `n·x = h`) at `p`.
    fn plane_ridge(p: DVec3, n: DVec3, h: f64) -> VertexDerivatives {
        let s = n.dot(p) - h;
        VertexDerivatives {
            position: p,
            value: -s * s,
            gradient: -2.0 * s * n,
            eigen: SmallestEigen {
                values: [-2.0, 0.0, 0.0],
                vector: n,
            },
        }
    }

    proptest! {
        /// On `f = −(n·x − h)²`, an edge whose ends lie on opposite sides of the plane gets
        /// its ridge point exactly on the plane, whatever the eigenvectors' signs.
        #[test]
        fn ridge_point_lies_on_the_ridge_plane(
            ax in -3.0..3.0f64, ay in -3.0..3.0f64, az in -3.0..3.0f64,
            bx in -3.0..3.0f64, by in -3.0..3.0f64, bz in -3.0..3.0f64,
            theta in 0.0..3.1f64, phi in 0.0..6.2f64, h in -1.0..1.0f64, flip in any::<bool>(),
        ) {
            let n = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            let (a, b) = (DVec3::new(ax, ay, az), DVec3::new(bx, by, bz));
            let (sa, sb) = (n.dot(a) - h, n.dot(b) - h);
            prop_assume!(sa.abs() > 1e-3 && sb.abs() > 1e-3);
            let da = plane_ridge(a, n, h);
            let mut db = plane_ridge(b, n, h);
            if flip {
                db.eigen.vector = -db.eigen.vector;
            }
            let p = ridge_point_on_edge(&da, &db);
            if sa * sb < 0.0 {
                let p = p.unwrap();
                prop_assert!((n.dot(p.position) - h).abs() < 1e-9);
                prop_assert!(p.strength == 2.0);
            } else {
                prop_assert!(p.is_none());
            }
        }
    }

    #[test]
    fn a_valley_is_no_ridge() {
        let n = DVec3::Z;
        let valley = |p: DVec3| {
            let mut d = plane_ridge(p, n, 0.0);
            d.gradient = -d.gradient;
            d.eigen.values = [0.0, 0.0, 2.0];
            d.eigen.vector = DVec3::X;
            d
        };
        assert!(ridge_point_on_edge(&valley(-DVec3::Z), &valley(DVec3::Z)).is_none());
    }
}
