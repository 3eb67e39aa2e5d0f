//! Expansion and elimination (thesis §3.4.1, Fig. 3.7): visit the supports in random order,
//! grow each radius as far as the fit error allows, and delete every support whose ball lies
//! entirely inside the grown ball.
//!
//! # Why batches give exactly the sequential algorithm
//!
//! How far a support grows depends only on its centre, its initial radius and the points —
//! never on the other supports. So the seeded random order is cut into batches of
//! [`BATCH`] visits: the supports of a batch still alive when it starts are grown in
//! parallel (with the range queries their deletions need), then one sequential pass walks
//! the batch in order, skips those already deleted, switches each visited support to its
//! grown radius, and deletes every live support `k` with `‖c_k − c_i‖ + r_k ≤ r_i`, where
//! `r_k` is `k`'s radius at that moment (grown when `k` was visited earlier, initial
//! otherwise). That is the one-support-at-a-time procedure of Fig. 3.7, decision for
//! decision; the only extra cost is growing the supports that an earlier support of their
//! own batch deletes. A support deleted in an earlier batch is never grown. The batches are
//! fixed by the order alone, so the result depends on the seed, never on the thread count.
//!
//! # Growth
//!
//! A support whose initial error exceeds ε (a leaf at the maximum depth) keeps its radius,
//! and so does a support whose radius already grew to reach `n_min` points: that radius is
//! set by the distance to the data, not by the error, and such supports sit away from the
//! surface where a larger ball sweeps in a large piece of surface (thousands of points to
//! gather for one trial that fails). They still delete the supports inside their balls.
//! Otherwise the search takes the bracket `[r, 2r]` (capped at `max_growth ×` the initial
//! radius and at the root cube's diagonal) and bisects it on the logarithm of the radius as
//! though `2r` had failed, until the bracket is narrower than the growth tolerance. Only when
//! every trial passed is `2r` itself tested, and when it passes the search goes on with
//! `[2r, 4r]`. (Testing `2r` first, as a doubling search does, costs a fit over the largest
//! ball, and on the 362K-point bunny that trial failed for 97% of the supports that grow.)
//! Where the error rises with the radius this finds what the doubling search finds; where
//! it dips, the two may stop at different radii, each with `E ≤ ε` there and a failed trial
//! within the tolerance above it (or the cap).
//!
//! Each trial radius refits from scratch (the kernel weights depend on the radius). The
//! first trial of a bracket gathers its own ball. Once it passed, the doubled ball is
//! gathered and serves every later trial: the kernel gives the points outside a smaller
//! trial ball weight 0, and the error pass counts them as 0. (Sorting the points by
//! distance, to make each trial ball a prefix, cost more than these extra passes.)

use super::SurfaceCoverParams;
use super::fit::{Candidates, Fit, Samples};
use super::octree::Leaf;
use crate::point_index::{PointIndex, PointIndexError};
use crate::support_samples::SupportSamples;
use glam::DVec3;
use rand_pcg::Pcg64;
use rand_pcg::rand_core::{RngCore, SeedableRng};
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// Visits per batch. On the 362K-point bunny at ε = 2.5e-3 (94,543 supports before
/// expansion, 28,225 deleted), batches of 8,192 skip 76,182 of the 269,904 growth fits that
/// growing every support would cost; batches of 256 would skip 81,460, but the threads would
/// meet 370 times instead of 12, and the supports of a small batch lie too far apart to share
/// cached points (they are grown in index order, which is Morton order).
const BATCH: usize = 8192;

/// A support after growth.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Grown {
    pub radius: f64,
    pub fit: Fit,
    /// Fits computed while growing.
    pub fits: u32,
}

/// The supports after expansion and elimination.
#[derive(Debug)]
pub(crate) struct Expanded {
    /// Which supports survive.
    pub alive: Vec<bool>,
    /// Radius of each survivor (grown); the initial one for the deleted supports.
    pub radius: Vec<f64>,
    /// The fit of each survivor at its radius; the octree's for the deleted supports.
    pub fit: Vec<Fit>,
    /// The slots of the points in each survivor's ball: the row its growth gathered, when
    /// asked for (see [`grow`]), else the one given for it; `None` for the deleted supports.
    pub rows: Vec<Option<Vec<u32>>>,
    /// Fits computed while growing.
    pub fits: u64,
    /// Time spent growing and in the range queries (parallel).
    pub growth: Duration,
    /// Time spent in the sequential passes and building the index of the centres.
    pub elimination: Duration,
}

/// Expands the octree's supports `leaves` (see the module docs), whose centres, radii and
/// fits are `centres`, `initial` and `fit`; with `keep_rows`, keeps the points of the
/// supports' balls that their growth gathered, and otherwise the octree's `rows`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn expand(
    leaves: &[Leaf],
    centres: &[DVec3],
    initial: &[f64],
    fit: Vec<Fit>,
    rows: Vec<Option<Vec<u32>>>,
    samples: &Samples<'_>,
    params: &SurfaceCoverParams,
    max_radius: f64,
    keep_rows: bool,
) -> Result<Expanded, PointIndexError> {
    expand_with(
        centres,
        initial,
        fit,
        rows,
        params.seed,
        BATCH,
        |cand, i| grow(cand, &leaves[i], samples, params, max_radius, keep_rows),
    )
}

/// The pass in batches of `batch` visits over the supports with centres `centres` and radii
/// `initial`, whose octree fits are `fit` and rows `rows` (empty: none); `grow(candidates, i)`
/// grows support `i` and may give its row. A deleted support's row is dropped at once, so its
/// memory serves the rows grown after it.
fn expand_with(
    centres: &[DVec3],
    initial: &[f64],
    mut fit: Vec<Fit>,
    mut rows: Vec<Option<Vec<u32>>>,
    seed: u64,
    batch: usize,
    grow: impl Fn(&mut Candidates, usize) -> (Grown, Option<Vec<u32>>) + Sync,
) -> Result<Expanded, PointIndexError> {
    let start = Instant::now();
    let n = centres.len();
    let index = PointIndex::new(centres)?;
    let mut radius = initial.to_vec();
    let mut alive = vec![true; n];
    rows.resize(n, None);
    let mut fits = 0u64;
    let mut growth = Duration::ZERO;
    let mut live = Vec::with_capacity(batch);
    // A support `k` inside the grown ball has `‖c_k − c_i‖ ≤ r_i − r_k ≤ r_i − r_min`, so the
    // range query reaches that far (plus a relative 1e-9 for the rounding of both tests),
    // not over the whole grown ball; the deletions are the same.
    let r_min = initial.iter().copied().fold(f64::INFINITY, f64::min);
    for visits in shuffled(n, seed).chunks(batch) {
        // Grown in index (Morton) order, so that neighbouring supports gather from the same
        // points while they are in cache; visited below in the random order.
        live.clear();
        live.extend(visits.iter().copied().filter(|&i| alive[i as usize]));
        live.sort_unstable();
        let t_batch = Instant::now();
        // A support `k` can only ever be deleted by `i` when `‖c_k − c_i‖ + r_k ≤ r_i` holds
        // for its initial radius (its radius at deletion time is the initial or the larger
        // grown one), so each grown support keeps those candidates, with their distance, and
        // the sequential pass re-checks them against the radius of the moment (bitwise the
        // same test).
        let mut grown: Vec<_> = live
            .par_iter()
            .with_min_len(64)
            .map_init(Candidates::default, |cand, &i| {
                let i = i as usize;
                let (g, row) = grow(cand, i);
                let mut near = Vec::new();
                let ci = centres[i];
                let reach = (g.radius - r_min).max(0.0) + 1e-9 * g.radius;
                index.for_each_within(ci, reach, |k, ck| {
                    let d = ck.distance(ci);
                    if k as usize != i && d + initial[k as usize] <= g.radius {
                        near.push((k, d));
                    }
                });
                (g, row, near)
            })
            .collect();
        growth += t_batch.elapsed();
        fits += grown.iter().map(|(g, _, _)| u64::from(g.fits)).sum::<u64>();
        for &i in visits {
            let Ok(at) = live.binary_search(&i) else {
                continue;
            };
            let i = i as usize;
            if !alive[i] {
                continue;
            }
            let (g, row, near) = &mut grown[at];
            radius[i] = g.radius;
            fit[i] = g.fit;
            if let Some(row) = row.take() {
                rows[i] = Some(row);
            }
            for &(k, d) in near.iter() {
                let k = k as usize;
                if alive[k] && d + radius[k] <= g.radius {
                    alive[k] = false;
                    rows[k] = None;
                }
            }
        }
    }
    Ok(Expanded {
        alive,
        radius,
        fit,
        rows,
        fits,
        growth,
        elimination: start.elapsed().saturating_sub(growth),
    })
}

/// The support `leaf` as the octree left it, and the largest radius it may grow to; `None`
/// for a support that keeps its radius (see the module docs).
fn growth_start(leaf: &Leaf, params: &SurfaceCoverParams, max_radius: f64) -> (Grown, Option<f64>) {
    let unchanged = Grown {
        radius: leaf.radius,
        fit: leaf.fit,
        fits: 0,
    };
    let growable = !(leaf.fit.error > params.eps || leaf.grown);
    let cap = growable.then(|| (leaf.radius * params.max_growth).min(max_radius));
    (unchanged, cap)
}

/// Grows one support (see the module docs). With `keep_row`, also its row of
/// [`SupportSamples`] (the slots of the points in its ball, grown or not) when its trials
/// gathered them: a gather at the final radius would visit the index in the same order, set
/// by the centre alone, so the row is the candidates inside that ball. A support that grew
/// gets its row in any case, gathered once more when its candidates fall short of the ball.
fn grow(
    cand: &mut Candidates,
    leaf: &Leaf,
    samples: &Samples<'_>,
    params: &SurfaceCoverParams,
    max_radius: f64,
    keep_row: bool,
) -> (Grown, Option<Vec<u32>>) {
    let (mut best, cap) = growth_start(leaf, params, max_radius);
    let Some(cap) = cap else { return (best, None) };
    let eps = params.eps;
    let ratio = 1.0 + params.growth_tolerance;
    // Every later trial below a failed radius `hi` has a squared radius below `hi² / ratio`,
    // so the candidates outside `hi` can go (exactly; see `Candidates::keep_within`) when the
    // tolerance leaves that margin.
    let compact = ratio >= 1.0 + 1e-6;
    // Radius of the candidates held (0: none yet).
    let mut held = 0.0;
    // The fit at `r` if it passes, gathering the ball of radius `reach ≥ r` first when the
    // candidates held do not reach `r`.
    let passes = |cand: &mut Candidates, held: &mut f64, r: f64, reach: f64| {
        if r > *held {
            cand.gather(samples, leaf.centre, reach);
            *held = reach;
        }
        cand.fit(samples, r, params.kernel, eps)
            .filter(|fit| fit.error <= eps)
    };
    let mut lo = leaf.radius;
    while lo < cap {
        let top = (2.0 * lo).min(cap);
        let mut hi = top;
        let mut first = true;
        let mut failed = false;
        while hi > lo * ratio {
            let mid = (lo * hi).sqrt();
            if !(mid > lo && mid < hi) {
                break;
            }
            best.fits += 1;
            // The first trial of a bracket gathers its own ball: when it fails, every later
            // trial is smaller and needs no other point. Once it passed, the doubled ball
            // serves every later trial.
            let reach = if first { mid } else { top };
            first = false;
            match passes(cand, &mut held, mid, reach) {
                Some(fit) => {
                    lo = mid;
                    best.radius = mid;
                    best.fit = fit;
                }
                None => {
                    hi = mid;
                    failed = true;
                    if compact && hi > lo * ratio && hi < held {
                        cand.keep_within(hi);
                        held = hi;
                    }
                }
            }
        }
        if failed {
            break;
        }
        // Every trial below `top` passed: only now is `top` itself tested.
        best.fits += 1;
        match passes(cand, &mut held, top, top) {
            Some(fit) => {
                lo = top;
                best.radius = top;
                best.fit = fit;
            }
            None => break,
        }
    }
    if !keep_row {
        return (best, None);
    }
    let reach = SupportSamples::ball_radius(best.radius);
    if held >= reach {
        cand.keep_within(reach);
    } else if best.radius > leaf.radius {
        cand.gather(samples, leaf.centre, reach);
    } else {
        // Nothing gathered reaches the ball the octree left: the gather of all the rows
        // finds it as cheaply.
        return (best, None);
    }
    (best, Some(cand.slots().to_vec()))
}

/// `0..n` in the seeded random order: Fisher–Yates driven by PCG-64, with the multiply-shift
/// range reduction written out so the order never changes with a `rand` release.
pub(crate) fn shuffled(n: usize, seed: u64) -> Vec<u32> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut order: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        let j = ((u128::from(rng.next_u64()) * (i as u128 + 1)) >> 64) as usize;
        order.swap(i, j);
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::Kernel;
    use crate::surface_cover::fit::tests::bumpy_sphere;
    use proptest::prelude::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Fig. 3.7 one support at a time, every pair tested: the oracle of [`expand_with`].
    /// Returns which supports survive, the radius of each and how many were visited alive.
    fn expand_one_at_a_time(
        centres: &[DVec3],
        initial: &[f64],
        grown: &[Grown],
        seed: u64,
    ) -> (Vec<bool>, Vec<f64>, usize) {
        let mut radius = initial.to_vec();
        let mut alive = vec![true; centres.len()];
        let mut visited = 0;
        for i in shuffled(centres.len(), seed) {
            let i = i as usize;
            if !alive[i] {
                continue;
            }
            visited += 1;
            let ri = grown[i].radius;
            radius[i] = ri;
            for k in 0..centres.len() {
                let inside = (centres[k] - centres[i]).length_squared() < ri * ri;
                if k != i && alive[k] && inside && centres[k].distance(centres[i]) + radius[k] <= ri
                {
                    alive[k] = false;
                }
            }
        }
        (alive, radius, visited)
    }

    /// [`grow`] without its economies: every trial fitted over one gather at the cap, never
    /// compacted. Its oracle: the gathers and the compaction must not change a bit.
    fn grow_over_one_gather(
        leaf: &Leaf,
        samples: &Samples<'_>,
        params: &SurfaceCoverParams,
        max_radius: f64,
    ) -> Grown {
        let (mut best, cap) = growth_start(leaf, params, max_radius);
        let Some(cap) = cap else { return best };
        let mut cand = Candidates::default();
        cand.gather(samples, leaf.centre, cap);
        let passes = |r: f64, best: &mut Grown| {
            best.fits += 1;
            let fit = cand.fit(samples, r, params.kernel, f64::INFINITY);
            match fit {
                Some(fit) if fit.error <= params.eps => {
                    best.radius = r;
                    best.fit = fit;
                    true
                }
                _ => false,
            }
        };
        let ratio = 1.0 + params.growth_tolerance;
        let mut lo = leaf.radius;
        while lo < cap {
            let top = (2.0 * lo).min(cap);
            let mut hi = top;
            while hi > lo * ratio {
                let mid = (lo * hi).sqrt();
                if !(mid > lo && mid < hi) {
                    break;
                }
                if passes(mid, &mut best) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            if hi < top || !passes(top, &mut best) {
                break;
            }
            lo = top;
        }
        best
    }

    proptest! {
        #[test]
        fn growth_matches_the_search_over_one_gather(
            bump in 0.0f64..0.03,
            (theta, phi) in (0.0f64..std::f64::consts::PI, 0.0f64..std::f64::consts::TAU),
            height in -0.02f64..0.02,
            radius in 0.01f64..0.06,
            eps in 1e-4f64..5e-3,
            tolerance in prop::sample::select(vec![1e-7, 0.05, 0.3, 1.0]),
            max_growth in 1.0f64..8.0,
        ) {
            let samples = bumpy_sphere(3000, bump);
            let u = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            let centre = (0.3 + height) * u;
            let mut cand = Candidates::default();
            cand.gather(&samples, centre, radius);
            let Some(fit) = cand.fit(&samples, radius, Kernel::QuadraticBSpline, f64::INFINITY) else {
                return Ok(());
            };
            let leaf = Leaf {
                level: 0,
                key: 0,
                centre,
                radius,
                fit,
                grown: false,
                empty: false,
                refinable: true,
                own_points: cand.len(),
            };
            let params = SurfaceCoverParams {
                eps,
                growth_tolerance: tolerance,
                max_growth,
                ..SurfaceCoverParams::default()
            };
            let max_radius = 0.2;
            let (fast, row) =
                grow(&mut Candidates::default(), &leaf, &samples, &params, max_radius, true);
            let plain = grow_over_one_gather(&leaf, &samples, &params, max_radius);
            // A row is the gather of the support's ball, slot for slot, and every grown
            // support has one.
            prop_assert!(row.is_some() || fast.radius == radius);
            if let Some(row) = row {
                let reach = SupportSamples::ball_radius(fast.radius);
                let mut direct = Vec::new();
                samples.index.extend_within(centre, reach, &mut direct, None);
                prop_assert_eq!(row, direct);
            }
            prop_assert_eq!(fast.radius, plain.radius);
            prop_assert_eq!(fast.fit, plain.fit);
            prop_assert_eq!(fast.fits, plain.fits);
            // The radius found fits within ε, refitted over its own ball alone.
            if fast.fits > 0 && fast.radius > radius {
                cand.gather(&samples, centre, fast.radius);
                let own = cand.fit(&samples, fast.radius, params.kernel, f64::INFINITY);
                prop_assert_eq!(own, Some(fast.fit));
                prop_assert!(fast.fit.error <= eps);
            }
        }

        #[test]
        fn expansion_matches_the_one_at_a_time_pass(
            balls in prop::collection::vec(
                ((-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0), 0.01f64..0.3, 1.0f64..4.0),
                1..120,
            ),
            seed in any::<u64>(),
            batch in 1usize..40,
        ) {
            let centres: Vec<DVec3> = balls.iter().map(|&((x, y, z), _, _)| DVec3::new(x, y, z)).collect();
            let initial: Vec<f64> = balls.iter().map(|&(_, r, _)| r).collect();
            let octree_fit = Fit { normal: DVec3::Z, centroid: DVec3::ZERO, error: 0.0 };
            // Each grown fit is told apart by its error.
            let grown: Vec<Grown> = balls
                .iter()
                .enumerate()
                .map(|(i, &(_, r, g))| Grown {
                    radius: r * g,
                    fit: Fit { error: i as f64 + 1.0, ..octree_fit },
                    fits: 1,
                })
                .collect();
            let calls = AtomicUsize::new(0);
            let octree_fits = vec![octree_fit; centres.len()];
            // Every other support's growth gives a row; the others keep the one given.
            let given = (0..centres.len()).map(|i| Some(vec![u32::MAX, i as u32])).collect();
            let grown_row = |i: usize| i.is_multiple_of(2).then(|| vec![i as u32]);
            let fast = expand_with(&centres, &initial, octree_fits, given, seed, batch, |_, i| {
                calls.fetch_add(1, Ordering::Relaxed);
                (grown[i], grown_row(i))
            })
            .unwrap();
            let (alive, radius, visited) = expand_one_at_a_time(&centres, &initial, &grown, seed);
            prop_assert_eq!(&fast.alive, &alive);
            for i in (0..centres.len()).filter(|&i| alive[i]) {
                prop_assert_eq!(fast.radius[i], radius[i]);
                prop_assert_eq!(fast.fit[i], grown[i].fit);
                let row = grown_row(i).unwrap_or_else(|| vec![u32::MAX, i as u32]);
                prop_assert_eq!(fast.rows[i].as_ref(), Some(&row));
            }
            for i in (0..centres.len()).filter(|&i| !alive[i]) {
                prop_assert!(fast.rows[i].is_none());
            }
            // Every support visited alive was grown, no support twice, and with one visit
            // per batch no other.
            let calls = calls.into_inner();
            prop_assert!(calls >= visited && calls <= centres.len());
            if batch == 1 {
                prop_assert_eq!(calls, visited);
            }
            prop_assert_eq!(fast.fits, calls as u64);
        }
    }
}
