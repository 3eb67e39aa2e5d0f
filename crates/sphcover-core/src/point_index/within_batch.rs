//! Fixed-radius neighbourhoods of many query points at once ([`PointIndex::map_within`]).
//!
//! The queries are visited in Morton order and cut into blocks of neighbouring points (see
//! [`BatchPlan`]). The tree is asked once per block, for the points within `r` plus the
//! block's bounding radius of its centre, and every query of the block keeps those within
//! `r` of itself. Keeping is a distance test without a branch, where each query of its own
//! meets a branch per point of the tree's leaves that no predictor can guess, and the walk
//! down the tree is shared by the block.

use super::PointIndex;
use crate::spatial_order::{BatchPlan, bounding_sphere, in_input_order};
use glam::DVec3;
use rayon::prelude::*;

/// Queries per block at most.
const BLOCK_LEN: usize = 32;

/// A block's bounding box has a diagonal of at most this many times the query radius, so
/// its candidates reach at most 1.5 radii from its centre.
const BLOCK_SPAN_PER_RADIUS: f64 = 1.0;

/// Queries per rayon task at least.
const MIN_TASK_LEN: usize = 64;

impl PointIndex {
    /// `visit(scratch, q, near)` for every query point `queries[q]`, in parallel, with the
    /// results in query order; `scratch` is the task's own, made by `init`. `near` holds `(slot, ‖p − x‖²)` for exactly the indexed points that
    /// [`PointIndex::for_each_slot_within`] reports for `x = queries[q]` and radius `r`, with
    /// the same squared distances, in ascending slot order: the same for every thread count.
    /// Nothing is reported for a non-finite query or a radius that is not positive.
    ///
    /// Much faster than one query per point when the queries lie close together (the vertices
    /// of a mesh, say): see the module docs.
    ///
    /// ```
    /// use sphcover_core::{DVec3, PointIndex};
    ///
    /// let points: Vec<DVec3> = (0..1000).map(|i| DVec3::new(i as f64 * 0.001, 0.0, 0.0)).collect();
    /// let index = PointIndex::new(&points)?;
    /// let queries = [DVec3::new(0.5, 0.0, 0.0), DVec3::new(2.0, 0.0, 0.0)];
    /// let counts = index.map_within(&queries, 0.0105, || (), |_, _, near| near.len());
    /// assert_eq!(counts, vec![21, 0]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn map_within<S, R: Copy + Send + Sync>(
        &self,
        queries: &[DVec3],
        r: f64,
        init: impl Fn() -> S + Sync + Send,
        visit: impl Fn(&mut S, usize, &[(u32, f64)]) -> R + Sync,
    ) -> Vec<R> {
        if u32::try_from(queries.len()).is_err() {
            // Beyond the plan's u32 positions: one query at a time.
            return queries
                .par_iter()
                .enumerate()
                .map_init(
                    || (init(), Vec::new()),
                    |(scratch, near), (q, &x)| {
                        near.clear();
                        self.for_each_slot_within(x, r, |s, d2| near.push((s as u32, d2)));
                        near.sort_unstable_by_key(|&(s, _)| s);
                        visit(scratch, q, near)
                    },
                )
                .collect();
        }
        let plan = BatchPlan::new(queries, BLOCK_LEN, BLOCK_SPAN_PER_RADIUS * r);
        let by_position: Vec<R> = (0..plan.order.len())
            .into_par_iter()
            .with_min_len(MIN_TASK_LEN)
            .map_init(
                || (init(), WithinState::default()),
                |(scratch, state), k| {
                    let q = plan.order[k] as usize;
                    visit(scratch, q, state.near(self, queries, &plan, k, r))
                },
            )
            .collect();
        in_input_order(&plan.rank(), &by_position)
    }
}

/// What a task of [`PointIndex::map_within`] keeps between neighbouring queries: the block
/// of its last query and the block's candidate slots.
#[derive(Default)]
struct WithinState {
    block: Option<usize>,
    candidates: Vec<u32>,
    near: Vec<(u32, f64)>,
}

impl WithinState {
    /// The points within `r` of the query at position `k` of `plan`.
    fn near(
        &mut self,
        index: &PointIndex,
        queries: &[DVec3],
        plan: &BatchPlan,
        k: usize,
        r: f64,
    ) -> &[(u32, f64)] {
        let x = queries[plan.order[k] as usize];
        if r.is_nan() || r <= 0.0 || !x.is_finite() {
            return &[];
        }
        let b = plan.block_of[k] as usize;
        if self.block != Some(b) {
            self.block = Some(b);
            self.candidates.clear();
            // A point within `r` of a point of the box lies within `r + t` of its centre; the
            // relative margin covers the rounding of both distances.
            if let Some((centre, t)) = bounding_sphere(&plan.blocks[b].1) {
                let reach = (r + t) * (1.0 + 1e-9);
                index.extend_within_ascending(centre, reach, &mut self.candidates);
            }
            self.near.resize(self.candidates.len(), (0, 0.0));
        }
        // Every candidate is written and kept when inside, computed as the tree's own query
        // computes it.
        let r2 = r * r;
        let mut len = 0;
        for &s in &self.candidates {
            let d2 = (index.points[s as usize] - x).length_squared();
            self.near[len] = (s, d2);
            len += usize::from(d2 < r2);
        }
        &self.near[..len]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn coordinate() -> impl Strategy<Value = f64> {
        prop_oneof![-1.0f64..1.0, (-4i32..4).prop_map(|i| f64::from(i) * 0.25)]
    }

    fn point() -> impl Strategy<Value = DVec3> {
        (coordinate(), coordinate(), coordinate()).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    /// The single-point query's answer, sorted by slot.
    fn one_by_one(index: &PointIndex, x: DVec3, r: f64) -> Vec<(u32, f64)> {
        let mut near = Vec::new();
        index.for_each_slot_within(x, r, |s, d2| near.push((s as u32, d2)));
        near.sort_unstable_by_key(|&(s, _)| s);
        near
    }

    proptest! {
        /// Each query gets exactly the single-point query's points and distances, in slot
        /// order, in query order, at any thread count; points on a grid put queries and
        /// points on the spheres, where the test is decided by rounding.
        #[test]
        fn batch_matches_single_queries(
            points in prop::collection::vec(point(), 0..400),
            mut queries in prop::collection::vec(point(), 0..300),
            r in prop_oneof![0.01f64..1.0, Just(0.25), Just(0.0), Just(-1.0), Just(f64::INFINITY), Just(f64::NAN)],
            bad in prop::option::of(0usize..300),
            threads in 1usize..4,
        ) {
            if let Some(i) = bad.filter(|&i| i < queries.len()) {
                queries[i] = DVec3::new(f64::NAN, 0.0, 0.0);
            }
            let index = PointIndex::new(&points).unwrap();
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let batch: Vec<Vec<(u32, f64)>> = pool.install(|| {
                let mut lists = vec![Vec::new(); queries.len()];
                let counts = index.map_within(&queries, r, || (), |_, q, near| (q, near.len()));
                for (q, (seen, _)) in counts.iter().enumerate() {
                    prop_assert_eq!(*seen, q);
                }
                let slots = std::sync::Mutex::new(&mut lists);
                index.map_within(&queries, r, || (), |_, q, near| {
                    slots.lock().unwrap()[q] = near.to_vec();
                });
                Ok(lists)
            })?;
            for (q, &x) in queries.iter().enumerate() {
                let expected = one_by_one(&index, x, r);
                prop_assert_eq!(batch[q].len(), expected.len(), "query {}", q);
                for (a, b) in batch[q].iter().zip(&expected) {
                    prop_assert_eq!(a.0, b.0);
                    prop_assert_eq!(a.1.to_bits(), b.1.to_bits());
                }
            }
        }
    }

    #[test]
    fn long_batches_match_single_queries() {
        // Enough queries for many blocks, spread over a sphere as mesh vertices are.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let sphere = |n: usize, radius: f64| -> Vec<DVec3> {
            (0..n)
                .map(|i| {
                    let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                    let s = (1.0 - z * z).sqrt();
                    let a = golden * i as f64;
                    radius * DVec3::new(s * a.cos(), s * a.sin(), z)
                })
                .collect()
        };
        let points = sphere(20_000, 0.5);
        let queries = sphere(7_000, 0.502);
        let index = PointIndex::new(&points).unwrap();
        let r = 0.03;
        let sums = index.map_within(
            &queries,
            r,
            || (),
            |_, q, near| {
                let expected = one_by_one(&index, queries[q], r);
                near == expected.as_slice()
            },
        );
        assert!(sums.iter().all(|&same| same));
        let counts = index.map_within(&queries, r, || (), |_, _, near| near.len());
        assert!(counts.iter().all(|&c| c > 5), "{:?}", counts.iter().min());
    }
}
