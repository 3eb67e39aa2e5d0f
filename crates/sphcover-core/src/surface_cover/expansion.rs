//! Expansion and elimination (thesis §3.4.1, Fig. 3.7): visit the supports in random order,
//! grow each radius as far as the fit error allows, and delete every support whose ball lies
//! entirely inside the grown ball.
//!
//! # Why two phases give exactly the sequential algorithm
//!
//! How far a support grows depends only on its centre, its initial radius and the points —
//! never on the other supports. So the grown radius (and refitted function) of every support
//! is computed first, in parallel; then one sequential pass walks the supports in the seeded
//! random order, skips those already deleted, switches each visited support to its grown
//! radius, and deletes every live support `k` with `‖c_k − c_i‖ + r_k ≤ r_i`, where `r_k` is
//! `k`'s radius at that moment (grown when `k` was visited earlier, initial otherwise). That
//! is the one-support-at-a-time procedure of Fig. 3.7, decision for decision; the only cost
//! is growing supports that end up deleted. The result depends on the seed, never on the
//! thread count.
//!
//! # Growth
//!
//! A support whose initial error exceeds ε (a leaf at the maximum depth) keeps its radius,
//! and so does a support whose radius already grew to reach `n_min` points: that radius is
//! set by the distance to the data, not by the error, and such supports sit away from the
//! surface where a larger ball sweeps in a large piece of surface (thousands of points to
//! gather for one trial that fails). They still delete the supports inside their balls.
//! Otherwise the radius doubles while the refitted error stays `≤ ε`, up to
//! `max_growth ×` the initial radius and the root cube's diagonal; a failed trial bounds a
//! bisection (on the logarithm of the radius) that stops when the bracket is narrower than
//! the growth tolerance. Each trial radius refits from scratch (the kernel weights depend on
//! the radius) over the points gathered once per doubling: the kernel gives the points
//! outside a smaller trial ball weight 0, and the error pass skips them. (Sorting the points
//! by distance, to make each trial ball a prefix, cost more than these extra passes.)

use super::SurfaceCoverParams;
use super::fit::{Candidates, Fit, Samples};
use super::octree::Leaf;
use crate::point_index::{PointIndex, PointIndexError};
use glam::DVec3;
use rand_pcg::Pcg64;
use rand_pcg::rand_core::{RngCore, SeedableRng};
use rayon::prelude::*;

/// A support after growth.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Grown {
    pub radius: f64,
    pub fit: Fit,
    /// Fits computed while growing.
    pub fits: u32,
}

/// Grows every support (in parallel; see the module docs).
pub(crate) fn grow_all(
    leaves: &[Leaf],
    samples: &Samples<'_>,
    params: &SurfaceCoverParams,
    max_radius: f64,
) -> Vec<Grown> {
    leaves
        .par_iter()
        .with_min_len(64)
        .map_init(Candidates::default, |cand, leaf| {
            grow(cand, leaf, samples, params, max_radius)
        })
        .collect()
}

fn grow(
    cand: &mut Candidates,
    leaf: &Leaf,
    samples: &Samples<'_>,
    params: &SurfaceCoverParams,
    max_radius: f64,
) -> Grown {
    let mut best = Grown {
        radius: leaf.radius,
        fit: leaf.fit,
        fits: 0,
    };
    if leaf.fit.error > params.eps || leaf.grown {
        return best;
    }
    let cap = (leaf.radius * params.max_growth).min(max_radius);
    let eps = params.eps;
    let mut lo = leaf.radius;
    let mut hi = None;
    while lo < cap {
        let trial = (2.0 * lo).min(cap);
        cand.gather(samples, leaf.center, trial);
        best.fits += 1;
        match cand.fit(trial, params.kernel, eps) {
            Some(fit) if fit.error <= eps => {
                lo = trial;
                best.radius = trial;
                best.fit = fit;
            }
            _ => {
                hi = Some(trial);
                break;
            }
        }
    }
    let Some(mut hi) = hi else { return best };
    let ratio = 1.0 + params.growth_tolerance;
    // Every later trial `√(lo·hi)` has a squared radius below `hi² / ratio`, so once `hi`
    // shrinks the candidates outside it can go (exactly; see `Candidates::keep_within`):
    // the bisection passes then read the points of the bracket, not of the failed doubling.
    let compact = ratio >= 1.0 + 1e-6;
    while hi > lo * ratio {
        let mid = (lo * hi).sqrt();
        if !(mid > lo && mid < hi) {
            break;
        }
        best.fits += 1;
        match cand.fit(mid, params.kernel, eps) {
            Some(fit) if fit.error <= eps => {
                lo = mid;
                best.radius = mid;
                best.fit = fit;
            }
            _ => {
                hi = mid;
                if compact && hi > lo * ratio {
                    cand.keep_within(hi);
                }
            }
        }
    }
    best
}

/// The sequential elimination pass: returns which supports survive and the radius of each
/// (grown for survivors).
pub(crate) fn eliminate(
    centers: &[DVec3],
    initial: &[f64],
    grown: &[Grown],
    seed: u64,
) -> Result<(Vec<bool>, Vec<f64>), PointIndexError> {
    let n = centers.len();
    let index = PointIndex::new(centers)?;
    // The range queries do not depend on the pass, so they run first, in parallel: a support
    // `k` can only ever be deleted by `i` when `‖c_k − c_i‖ + r_k ≤ r_i` holds for its
    // initial radius (its radius at deletion time is the initial or the larger grown one), so
    // each visited support keeps those candidates, with their distance, and the sequential
    // pass re-checks them against the radius of the moment (bitwise the same test).
    let candidates: Vec<Vec<(u32, f64)>> = (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            let mut near = Vec::new();
            let ri = grown[i].radius;
            let ci = centers[i];
            index.for_each_within(ci, ri, |k, ck| {
                let d = ck.distance(ci);
                if k as usize != i && d + initial[k as usize] <= ri {
                    near.push((k, d));
                }
            });
            near
        })
        .collect();
    let order = shuffled(n, seed);
    let mut radius = initial.to_vec();
    let mut alive = vec![true; n];
    for i in order {
        let i = i as usize;
        if !alive[i] {
            continue;
        }
        let ri = grown[i].radius;
        radius[i] = ri;
        for &(k, d) in &candidates[i] {
            let k = k as usize;
            if alive[k] && d + radius[k] <= ri {
                alive[k] = false;
            }
        }
    }
    Ok((alive, radius))
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
    use proptest::prelude::*;

    /// Fig. 3.7 one support at a time, every pair tested: the oracle of [`eliminate`].
    fn eliminate_brute_force(
        centers: &[DVec3],
        initial: &[f64],
        grown: &[Grown],
        seed: u64,
    ) -> (Vec<bool>, Vec<f64>) {
        let mut radius = initial.to_vec();
        let mut alive = vec![true; centers.len()];
        for i in shuffled(centers.len(), seed) {
            let i = i as usize;
            if !alive[i] {
                continue;
            }
            let ri = grown[i].radius;
            radius[i] = ri;
            for k in 0..centers.len() {
                let inside = (centers[k] - centers[i]).length_squared() < ri * ri;
                if k != i && alive[k] && inside && centers[k].distance(centers[i]) + radius[k] <= ri
                {
                    alive[k] = false;
                }
            }
        }
        (alive, radius)
    }

    proptest! {
        #[test]
        fn elimination_matches_the_one_at_a_time_pass(
            balls in prop::collection::vec(
                ((-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0), 0.01f64..0.3, 1.0f64..4.0),
                1..120,
            ),
            seed in any::<u64>(),
        ) {
            let centers: Vec<DVec3> = balls.iter().map(|&((x, y, z), _, _)| DVec3::new(x, y, z)).collect();
            let initial: Vec<f64> = balls.iter().map(|&(_, r, _)| r).collect();
            let fit = Fit { normal: DVec3::Z, centroid: DVec3::ZERO, error: 0.0 };
            let grown: Vec<Grown> = balls
                .iter()
                .map(|&(_, r, g)| Grown { radius: r * g, fit, fits: 0 })
                .collect();
            let fast = eliminate(&centers, &initial, &grown, seed).unwrap();
            prop_assert_eq!(fast, eliminate_brute_force(&centers, &initial, &grown, seed));
        }
    }
}
