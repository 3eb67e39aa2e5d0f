//! Normals for unoriented points (beyond the thesis, which needs oriented input).
//!
//! The method is described on [`estimate_normals()`].

use std::time::{Duration, Instant};

use rayon::prelude::*;
use sphcover_core::{DVec3, PointIndex, PointIndexError};
use thiserror::Error;

use crate::pca::Pca;

/// Why normals could not be estimated.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum NormalError {
    /// The neighbourhood size is below 3 (a plane needs three points).
    #[error("neighbourhood size k = {0} is below 3")]
    InvalidK(usize),
    /// The points could not be indexed.
    #[error("point index: {0}")]
    Points(#[from] PointIndexError),
}

/// Parameters of [`estimate_normals`].
#[derive(Clone, Debug, PartialEq)]
pub struct NormalParams {
    /// Neighbours per point, the point included (default 12; 10–15 suits scans).
    pub k: usize,
    /// Orient the normals consistently and outward; `false` leaves PCA's arbitrary signs.
    pub orient: bool,
}

impl Default for NormalParams {
    fn default() -> Self {
        NormalParams {
            k: 12,
            orient: true,
        }
    }
}

/// Counters and timings of [`estimate_normals`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NormalStats {
    /// Points given.
    pub points: usize,
    /// Points left with a zero normal (no plane in their neighbourhood, or not finite).
    pub undetermined: usize,
    /// Connected components of the orientation graph.
    pub components: usize,
    /// Normals flipped while propagating along the spanning tree.
    pub propagation_flips: usize,
    /// Components flipped as a whole to point outward.
    pub flipped_components: usize,
    /// Time for the neighbours and the PCA.
    pub estimation_time: Duration,
    /// Time for the orientation.
    pub orientation_time: Duration,
}

/// Estimated normals.
#[derive(Clone, Debug, PartialEq)]
pub struct EstimatedNormals {
    /// Unit normals, or zero where undetermined.
    pub normals: Vec<DVec3>,
    /// Counters.
    pub stats: NormalStats,
}

/// Estimates unit normals of `points` by PCA over `k` nearest neighbours and, with
/// `params.orient`, orients them consistently and outward (method below).
///
/// 1. **Estimation.** The normal of each point is the direction of least variance of its `k`
///    nearest neighbours (itself included) — the PCA plane fit of Hoppe et al., "Surface
///    reconstruction from unorganized points", SIGGRAPH 1992.
/// 2. **Consistent orientation.** PCA gives each normal up to sign. Following Hoppe et al.,
///    the signs are propagated along a minimum spanning tree of the symmetrised kNN graph with
///    edge cost `1 − |n_i·n_j|`, so that propagation crosses nearly parallel planes first and
///    postpones the ambiguous places (thin parts, sharp edges) to the end, where a wrong flip
///    affects few points. A child is flipped when `n_child·n_parent < 0`.
/// 3. **Outward.** Each connected component of the graph is oriented as a whole: at the six
///    points extreme along ±x, ±y, ±z the outward normal points away from the rest of the
///    component (at a point of largest `x`, an outward normal has `n_x ≥ 0`). Hoppe uses the
///    single point of largest `z`; summing the six votes `±n_axis` makes one noisy extreme
///    point unable to flip a component.
///
/// Points whose neighbourhood spans no plane (duplicates, collinear sets, fewer than 3
/// points) get a zero normal, are left out of the orientation, and are counted; the surface
/// cover skips zero normals.
///
/// Determinism: estimation runs per point in parallel; the tree is built sequentially with
/// ties broken by index. The result does not depend on the thread count.
pub fn estimate_normals(
    points: &[DVec3],
    params: &NormalParams,
) -> Result<EstimatedNormals, NormalError> {
    if params.k < 3 {
        return Err(NormalError::InvalidK(params.k));
    }
    let k = params.k;
    let n = points.len();
    let start = Instant::now();
    let index = PointIndex::new(points)?;
    // Neighbour lists, `k` slots per point, `u32::MAX` for a missing neighbour.
    // Queries run in the index's slot order, where consecutive points are neighbours in
    // space (the tree's buckets), so the tree nodes they visit stay in cache; the results
    // are scattered back to the caller's order afterwards. Non-finite points are not in the
    // index and keep a zero normal.
    let order = index.order();
    let mut by_slot_neighbours = vec![u32::MAX; order.len() * k];
    let mut by_slot_normals = vec![DVec3::ZERO; order.len()];
    by_slot_neighbours
        .par_chunks_mut(k)
        .zip(by_slot_normals.par_iter_mut())
        .zip(index.slot_points().par_iter())
        .with_min_len(512)
        .for_each_init(
            || (Vec::with_capacity(k), Vec::with_capacity(k)),
            |(ids, pts), ((slots, normal), &p)| {
                index.nearest_k(p, k, ids);
                pts.clear();
                pts.extend(ids.iter().map(|&j| points[j as usize]));
                if let Some(nv) = Pca::of(pts).and_then(|pca| pca.normal()) {
                    *normal = nv;
                }
                slots[..ids.len()].copy_from_slice(ids);
            },
        );
    let mut neighbours = vec![u32::MAX; n * k];
    let mut normals = vec![DVec3::ZERO; n];
    for (slot, &i) in order.iter().enumerate() {
        let i = i as usize;
        normals[i] = by_slot_normals[slot];
        neighbours[i * k..(i + 1) * k]
            .copy_from_slice(&by_slot_neighbours[slot * k..(slot + 1) * k]);
    }
    drop((by_slot_neighbours, by_slot_normals));
    let mut stats = NormalStats {
        points: n,
        undetermined: normals.iter().filter(|v| **v == DVec3::ZERO).count(),
        estimation_time: start.elapsed(),
        ..Default::default()
    };
    if params.orient {
        let start = Instant::now();
        orient(points, &mut normals, &neighbours, k, &mut stats);
        stats.orientation_time = start.elapsed();
    }
    Ok(EstimatedNormals { normals, stats })
}

/// Orients `normals` along a minimum spanning tree of the kNN graph, then each component
/// outward.
///
/// The tree is built by Kruskal's algorithm over the edges sorted by `(cost, i, j)`: a strict
/// total order, so the tree is unique and the same as Prim's would be, and the parallel sort
/// cannot make it depend on the thread count. Signs then propagate by breadth-first search
/// from the lowest index of each component; the sign of a node relative to the root is the
/// product along its tree path, whatever the visiting order.
fn orient(
    points: &[DVec3],
    normals: &mut [DVec3],
    neighbours: &[u32],
    k: usize,
    stats: &mut NormalStats,
) {
    let n = points.len();
    let determined = |i: usize| normals[i] != DVec3::ZERO;
    // Each kNN pair once as (cost bits, low, high); non-negative floats order like their
    // bits.
    let normals_ro: &[DVec3] = normals;
    let mut edges: Vec<(u64, u32, u32)> = neighbours
        .par_chunks(k)
        .enumerate()
        .with_min_len(512)
        .flat_map_iter(|(i, row)| {
            row.iter().filter_map(move |&j| {
                let ju = j as usize;
                if j == u32::MAX || ju == i || !determined(i) || !determined(ju) {
                    return None;
                }
                let (a, b) = if i < ju { (i, ju) } else { (ju, i) };
                let cost = (1.0 - normals_ro[a].dot(normals_ro[b]).abs()).max(0.0);
                Some((cost.to_bits(), a as u32, b as u32))
            })
        })
        .collect();
    edges.par_sort_unstable();
    edges.dedup();

    // Kruskal with a union-find (path halving, union by size).
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut size = vec![1u32; n];
    let find = |parent: &mut [u32], mut x: u32| {
        while parent[x as usize] != x {
            let gp = parent[parent[x as usize] as usize];
            parent[x as usize] = gp;
            x = gp;
        }
        x
    };
    let mut tree: Vec<(u32, u32)> = Vec::with_capacity(n);
    for &(_, a, b) in &edges {
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra == rb {
            continue;
        }
        let (big, small) = if size[ra as usize] >= size[rb as usize] {
            (ra, rb)
        } else {
            (rb, ra)
        };
        parent[small as usize] = big;
        size[big as usize] += size[small as usize];
        tree.push((a, b));
    }
    drop(edges);

    // Tree adjacency in CSR.
    let mut offsets = vec![0u32; n + 1];
    for &(a, b) in &tree {
        offsets[a as usize + 1] += 1;
        offsets[b as usize + 1] += 1;
    }
    for v in 0..n {
        offsets[v + 1] += offsets[v];
    }
    let mut fill = offsets.clone();
    let mut adjacent = vec![0u32; offsets[n] as usize];
    for &(a, b) in &tree {
        adjacent[fill[a as usize] as usize] = b;
        fill[a as usize] += 1;
        adjacent[fill[b as usize] as usize] = a;
        fill[b as usize] += 1;
    }

    let mut visited = vec![false; n];
    let mut component: Vec<u32> = Vec::new();
    for root in 0..n {
        if visited[root] || normals[root] == DVec3::ZERO {
            continue;
        }
        stats.components += 1;
        component.clear();
        visited[root] = true;
        component.push(root as u32);
        let mut head = 0;
        while head < component.len() {
            let v = component[head] as usize;
            head += 1;
            for &j in &adjacent[offsets[v] as usize..offsets[v + 1] as usize] {
                let j = j as usize;
                if visited[j] {
                    continue;
                }
                visited[j] = true;
                if normals[j].dot(normals[v]) < 0.0 {
                    normals[j] = -normals[j];
                    stats.propagation_flips += 1;
                }
                component.push(j as u32);
            }
        }
        if outward_vote(points, normals, &component) < 0.0 {
            stats.flipped_components += 1;
            for &v in &component {
                normals[v as usize] = -normals[v as usize];
            }
        }
    }
}

/// The sum over the six axis-extreme points of `component` of the normal's component along
/// the outward axis: positive when the component's normals point outward.
fn outward_vote(points: &[DVec3], normals: &[DVec3], component: &[u32]) -> f64 {
    let Some(&first) = component.first() else {
        return 0.0;
    };
    let mut vote = 0.0;
    for axis in 0..3 {
        // Ties in the coordinate go to the lower index.
        let (mut hi, mut lo) = (first as usize, first as usize);
        for &v in component {
            let v = v as usize;
            let x = points[v][axis];
            let (xh, xl) = (points[hi][axis], points[lo][axis]);
            if x > xh || (x == xh && v < hi) {
                hi = v;
            }
            if x < xl || (x == xl && v < lo) {
                lo = v;
            }
        }
        vote += normals[hi][axis] - normals[lo][axis];
    }
    vote
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::PointCloud;

    /// Fraction of points whose estimated normal agrees in sign with the true one.
    fn correct_fraction(cloud: &PointCloud, est: &EstimatedNormals) -> f64 {
        let truth = cloud.normals.as_ref().unwrap();
        let good = est
            .normals
            .iter()
            .zip(truth)
            .filter(|(a, b)| a.dot(**b) > 0.0)
            .count();
        good as f64 / truth.len() as f64
    }

    #[test]
    fn sphere_torus_and_noisy_sphere_are_oriented_outward() {
        let sphere = sphcover_evaluation::sphere(DVec3::new(0.3, -0.2, 0.1), 0.5, 2000);
        let torus = sphcover_evaluation::torus(0.35, 0.15, 3000);
        let mut noisy = sphcover_evaluation::sphere(DVec3::ZERO, 0.5, 2000);
        sphcover_evaluation::add_position_noise(&mut noisy, 0.0025, 1);
        for (name, cloud) in [
            ("sphere", &sphere),
            ("torus", &torus),
            ("noisy sphere", &noisy),
        ] {
            let est = estimate_normals(&cloud.positions, &NormalParams::default()).unwrap();
            let frac = correct_fraction(cloud, &est);
            println!("{name}: {frac:.4} correctly oriented, {:?}", est.stats);
            assert!(frac >= 0.99, "{name}: {frac}");
            assert_eq!(est.stats.components, 1, "{name}");
            assert_eq!(est.stats.undetermined, 0, "{name}");
            // Unit length, and accurate up to sign on the clean shapes.
            for (a, b) in est.normals.iter().zip(cloud.normals.as_ref().unwrap()) {
                assert!((a.length() - 1.0).abs() < 1e-9);
                if name != "noisy sphere" {
                    assert!(a.dot(*b).abs() > 0.98, "{name}: {a} vs {b}");
                }
            }
        }
    }

    #[test]
    fn two_separate_spheres_are_each_outward() {
        let mut a = sphcover_evaluation::sphere(DVec3::ZERO, 0.3, 800);
        let b = sphcover_evaluation::sphere(DVec3::new(2.0, 0.0, 0.0), 0.2, 500);
        a.positions.extend(&b.positions);
        a.normals
            .as_mut()
            .unwrap()
            .extend(b.normals.as_ref().unwrap());
        let est = estimate_normals(&a.positions, &NormalParams::default()).unwrap();
        assert_eq!(est.stats.components, 2);
        assert_eq!(correct_fraction(&a, &est), 1.0);
    }

    #[test]
    fn thread_count_does_not_change_the_result() {
        let cloud = sphcover_evaluation::torus(0.35, 0.15, 3000);
        let on = |threads| {
            sphcover_core::on_threads(threads, || {
                estimate_normals(&cloud.positions, &NormalParams::default()).unwrap()
            })
        };
        assert_eq!(on(1).normals, on(2).normals);
    }

    #[test]
    fn degenerate_input() {
        assert!(matches!(
            estimate_normals(&[DVec3::ZERO], &NormalParams { k: 2, orient: true }),
            Err(NormalError::InvalidK(2))
        ));
        let empty = estimate_normals(&[], &NormalParams::default()).unwrap();
        assert!(empty.normals.is_empty());
        let one = estimate_normals(&[DVec3::ONE], &NormalParams::default()).unwrap();
        assert_eq!(one.normals, vec![DVec3::ZERO]);
        assert_eq!(one.stats.undetermined, 1);
        // Collinear points and duplicates: no plane anywhere.
        let line: Vec<DVec3> = (0..50)
            .map(|i| DVec3::new(i as f64, 2.0 * i as f64, 0.0))
            .collect();
        let est = estimate_normals(&line, &NormalParams::default()).unwrap();
        assert_eq!(est.stats.undetermined, 50);
        let dups = vec![DVec3::new(1.0, 2.0, 3.0); 30];
        let est = estimate_normals(&dups, &NormalParams::default()).unwrap();
        assert!(est.normals.iter().all(|n| *n == DVec3::ZERO));
        // A plane: one normal direction, all on one side; non-finite points get zero.
        let mut plane: Vec<DVec3> = (0..400)
            .map(|i| DVec3::new((i % 20) as f64, (i / 20) as f64, 1.0))
            .collect();
        plane.push(DVec3::NAN);
        let est = estimate_normals(&plane, &NormalParams::default()).unwrap();
        assert_eq!(est.normals[400], DVec3::ZERO);
        let z = est.normals[0].z.signum();
        assert!(est.normals[..400].iter().all(|n| (n.z - z).abs() < 1e-9));
        assert_eq!(est.stats.undetermined, 1);
    }

    /// Speed on 362K points (the thesis's bunny size).
    /// `cargo test --release -p sphcover-recon normals_speed -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn normals_speed() {
        let mut cloud = sphcover_evaluation::torus(0.35, 0.15, 362_000);
        sphcover_evaluation::add_position_noise(&mut cloud, 0.0005, 5);
        let t = Instant::now();
        let est = estimate_normals(&cloud.positions, &NormalParams::default()).unwrap();
        println!(
            "normals_speed: {} points in {:.2} s, {:.4} correctly oriented, {:?}",
            cloud.len(),
            t.elapsed().as_secs_f64(),
            correct_fraction(&cloud, &est),
            est.stats
        );
    }
}
