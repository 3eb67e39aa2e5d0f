//! The initial cover (thesis §3.4.1, after MPU): an adaptive, 2:1-balanced octree whose
//! leaves carry the supports.
//!
//! Every octant gets a support at its centre with radius `0.75 ×` its diagonal (which covers
//! the octant with room to spare, so the leaves' balls cover the root box). When that ball
//! holds fewer than `n_min` points the radius grows to reach the `n_min` nearest points (by
//! a factor [`REACH`] past the farthest of them, so it carries weight in the fit): a cell far
//! from the surface still gets a support, whose plane is fitted to the nearest piece of
//! surface. An octant is subdivided while its fit error exceeds ε, up to the maximum depth.
//!
//! Refinement stops where the data cannot support it. The children's balls of an octant lie
//! inside its ball (a child's centre is `√3/4` of the parent's side from the parent's, and
//! `√3/4 + 0.75·√3/2 < 0.75·√3`), so when an octant's own ball holds fewer than `n_min`
//! points, every descendant grows its ball too, to nearly the same nearest points once the
//! grown radius is several times the octant's own: subdividing then multiplies supports
//! without fitting the data any better (around a crease or a tip no plane fits the nearest
//! points, and the subdivision would run to the maximum depth all along it). So a grown
//! octant is subdivided only while its grown radius is at most [`REFINABLE_GROWTH`] times its
//! own radius, and an *empty* octant (own ball without any point) never is. The factor is 1
//! (a grown octant is never subdivided): with 2, the 5,210-point kitten scan at ε = 2.5e-3
//! gets 47,081 supports (9 per point) and a sphere intersection graph of mean degree 265;
//! with 1, 15,370 supports and degree 84, and the same reconstruction.
//!
//! The same holds one level up, where the octant's own ball still holds `n_min` points but
//! its children's balls (half the radius: about a quarter of the points on a surface) do
//! not. On sparse scans with ε below what the sampling supports, every child then grows to
//! its `n_min` nearest points and still misses ε, and the subdivision multiplies supports
//! for nothing (the 2,000-point sphere at ε = 2.5e-3 gets 5,793 supports, 4,681 over ε; the
//! 5,210-point kitten 15,370, 11,295 over). So a subdivision whose non-empty children are
//! all grown and over ε is undone: the octant stays a leaf with its own fit, whose error is
//! reported (the supports over ε, and [`SurfaceCoverStats::sampling_limited_octants`]),
//! not refined. Where grown children do reach ε (the same sphere at ε = 1e-2) the
//! subdivision stays. The rule applies with [`SurfaceCoverParams::sampling_stop`] (off by
//! default, on in `sphcover cover`).
//!
//! When the plane fitted to its nearest points misses them by more than ε, an empty octant
//! keeps the plane but not the grown radius: its support stays the octant's own ball, which
//! touches no sample, so the poor fit cannot spoil `f` on the data while the ball still
//! covers the octant. (Seen from a concave region the nearest points spread over the whole
//! concavity and no plane fits them.)
//!
//! Balance: a leaf at level `l` has no face neighbour coarser than level `l − 1` (the
//! usual 2:1 face balance; balancing across edges and corners as well makes 2.4 times as
//! many balance octants on a scanned bunny, nearly all in empty space, for no gain in the
//! fit). Leaves created to restore the balance are fitted and refined like the others, and
//! balancing repeats until nothing changes.
//!
//! Near the root an octant's ball holds a large part of the scan and its fit always misses
//! ε, yet gathering and fitting its points cost as much as a whole level of leaves. So an
//! octant whose parent held many points is first tried with a bound that needs only the
//! number of points in its ball and a few dozen of them spread over it (the point index
//! counts whole subtrees inside the ball without reading them): when four of them span a
//! tetrahedron wider than `2ε`, no plane passes within ε of all of them, so the fit would
//! miss ε and the octant is subdivided unfitted. On a 362K-point bunny scan this settles
//! 13 of the 20 million point visits of the octree; the tree is the same.
//!
//! Octants are fitted one level (wave) at a time in parallel; every decision is taken
//! sequentially in wave order, and the final leaves are sorted by Morton code, so the result
//! does not depend on the thread count.

use super::fit::{Candidates, Fit, Samples, error_lower_bound};
use super::{SurfaceCoverParams, SurfaceCoverStats};
use crate::support_samples::SupportSamples;
use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashSet;
use std::hash::{BuildHasherDefault, Hasher};

/// Deepest octree level [`super::SurfaceCoverParams::max_depth`] may ask for (the cell keys
/// hold 21 bits per axis).
pub const MAX_OCTREE_DEPTH: u32 = 20;

/// A grown support reaches this factor past its `n_min`-th nearest point, so that point has
/// a small positive weight (the kernels vanish on the sphere).
pub(crate) const REACH: f64 = 1.0625;

/// A grown octant is subdivided only while its grown radius is at most this factor times its
/// own radius (see the module docs).
pub(crate) const REFINABLE_GROWTH: f64 = 1.0;

/// A subdivision is undone, when a child misses ε, if the octant's own ball held fewer than
/// this factor times `n_min` points: its children's balls (half the radius) then hold about
/// a quarter as many on a surface, fewer than `n_min` (see the module docs).
pub(crate) const SPLIT_FACTOR: usize = 4;

/// Cells whose parent's own ball held at least this many points are first tried with
/// [`Octree::bound_cell`]: a cell's ball holds about a quarter of its parent's points on a
/// surface, and below a few hundred the plain fit costs about as much as the bound.
const BOUND_FIRST_POINTS: usize = 1024;

/// The sample for [`Octree::bound_cell`] takes one point per subtree of the index whose box
/// diagonal is at most this fraction of the ball's radius.
const BOUND_GRAIN: f64 = 0.25;

/// One octree leaf: its support and fit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Leaf {
    pub level: u8,
    pub key: u64,
    pub centre: DVec3,
    pub radius: f64,
    pub fit: Fit,
    /// The octant's own ball (radius `0.75 ×` diagonal) held fewer than `n_min` points, and
    /// the radius grew to reach them.
    pub grown: bool,
    /// The octant's own ball held no point.
    pub empty: bool,
    /// Subdividing the octant can fit the data better (see the module docs).
    pub refinable: bool,
    /// Points in the octant's own ball.
    pub own_points: usize,
}

impl Leaf {
    /// Settled by [`Octree::bound_cell`], without a fit (whose normal it marks NaN).
    fn bounded(&self) -> bool {
        self.fit.normal.is_nan()
    }
}

/// The root cube and its subdivision.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Geometry {
    /// Minimum corner of the root cube.
    pub min: f64,
    /// Side of the root cube.
    pub side: f64,
}

impl Geometry {
    fn cell(&self, level: u8, key: u64) -> (DVec3, f64) {
        let h = self.side / f64::from(1u32 << level);
        let (x, y, z) = unpack(key);
        let centre = DVec3::new(
            self.min + (f64::from(x) + 0.5) * h,
            self.min + (f64::from(y) + 0.5) * h,
            self.min + (f64::from(z) + 0.5) * h,
        );
        (centre, 0.75 * 3f64.sqrt() * h)
    }
}

const AXIS_BITS: u32 = 21;
const AXIS_MASK: u64 = (1 << AXIS_BITS) - 1;

fn pack(x: u32, y: u32, z: u32) -> u64 {
    u64::from(x) | u64::from(y) << AXIS_BITS | u64::from(z) << (2 * AXIS_BITS)
}

fn unpack(key: u64) -> (u32, u32, u32) {
    (
        (key & AXIS_MASK) as u32,
        (key >> AXIS_BITS & AXIS_MASK) as u32,
        (key >> (2 * AXIS_BITS) & AXIS_MASK) as u32,
    )
}

fn parent(key: u64) -> u64 {
    let (x, y, z) = unpack(key);
    pack(x >> 1, y >> 1, z >> 1)
}

fn children(key: u64) -> impl Iterator<Item = u64> {
    let (x, y, z) = unpack(key);
    (0..8u32).map(move |c| pack(2 * x + (c & 1), 2 * y + (c >> 1 & 1), 2 * z + (c >> 2)))
}

/// Interleaves the bits of a cell's minimum corner at the finest level: sorting leaves by it
/// puts neighbouring supports next to each other in memory.
fn morton(level: u8, key: u64) -> u64 {
    let shift = MAX_OCTREE_DEPTH - u32::from(level);
    let (x, y, z) = unpack(key);
    spread(x << shift) | spread(y << shift) << 1 | spread(z << shift) << 2
}

fn spread(v: u32) -> u64 {
    let mut x = u64::from(v) & AXIS_MASK;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// The six face neighbours' offsets, in the order the balance visits them.
const FACE_STEPS: [(i64, i64, i64); 6] = [
    (0, 0, -1),
    (0, -1, 0),
    (-1, 0, 0),
    (1, 0, 0),
    (0, 1, 0),
    (0, 0, 1),
];

/// A multiplicative hasher for the `u64` cell keys (SipHash costs more than the lookups).
#[derive(Default)]
struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        let mut x = self.0;
        x ^= x >> 33;
        x = x.wrapping_mul(0xff51_afd7_ed55_8ccd);
        x ^= x >> 33;
        x
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        }
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = v;
    }
}

type KeySet = HashSet<u64, BuildHasherDefault<KeyHasher>>;

struct Octree<'a> {
    samples: &'a Samples<'a>,
    params: &'a SurfaceCoverParams,
    geometry: Geometry,
    /// Subdivided cells, per level.
    internal: Vec<KeySet>,
    /// Fitted cells that became leaves, in the order fitted. A cell that the balance
    /// subdivided later stays here; it is dropped at the end, where `internal` holds it. (A
    /// list, not a map per level: inserting 112-byte leaves into maps, and reading them back
    /// out, holds one thread alone between the parallel waves.)
    leaves: Vec<Leaf>,
    /// With `keep_rows`, the row of [`SupportSamples`] of each of `leaves` that grew to its
    /// `n_min` nearest points (see [`Octree::fit_cell`]).
    rows: Vec<Option<Vec<u32>>>,
    keep_rows: bool,
}

/// Builds the balanced adaptive octree and returns its leaves in Morton order; with
/// `keep_rows`, also the row of [`SupportSamples`] of each leaf that grew to its `n_min`
/// nearest points (the others' rows are `None`).
pub(crate) fn build(
    samples: &Samples<'_>,
    params: &SurfaceCoverParams,
    geometry: Geometry,
    stats: &mut SurfaceCoverStats,
    keep_rows: bool,
) -> (Vec<Leaf>, Vec<Option<Vec<u32>>>) {
    let levels = params.max_depth as usize + 1;
    let mut tree = Octree {
        samples,
        params,
        geometry,
        internal: vec![KeySet::default(); levels],
        leaves: Vec::new(),
        rows: Vec::new(),
        keep_rows,
    };
    stats.octants_per_level = vec![0; levels];
    let mut frontier = vec![(0u8, 0u64)];
    loop {
        let new_leaves = tree.refine(frontier, stats);
        frontier = tree.balance(new_leaves);
        stats.balance_octants += frontier.len();
        if frontier.is_empty() {
            break;
        }
    }
    let internal = &tree.internal;
    let (unordered, mut unordered_rows): (Vec<Leaf>, Vec<Option<Vec<u32>>>) = tree
        .leaves
        .into_par_iter()
        .zip(tree.rows)
        .filter(|(l, _)| !internal[l.level as usize].contains(&l.key))
        .unzip();
    // Sorting the keys alone, each computed once: `(Morton code, level)` names a cell, so
    // the order is total and independent of the order the waves fitted the leaves in.
    let mut order: Vec<(u64, u8, u32)> = unordered
        .par_iter()
        .enumerate()
        .map(|(i, l)| (morton(l.level, l.key), l.level, i as u32))
        .collect();
    order.par_sort_unstable();
    debug_assert!(
        order
            .windows(2)
            .all(|w| (w[0].0, w[0].1) != (w[1].0, w[1].1)),
        "a cell became a leaf twice"
    );
    let leaves: Vec<Leaf> = order
        .par_iter()
        .map(|&(_, _, i)| unordered[i as usize])
        .collect();
    let rows = order
        .iter()
        .map(|&(_, _, i)| unordered_rows[i as usize].take())
        .collect();
    stats.leaves_per_level = vec![0; levels];
    for l in &leaves {
        stats.leaves_per_level[l.level as usize] += 1;
    }
    (leaves, rows)
}

impl Octree<'_> {
    /// Fits the cells of `frontier` and subdivides those whose error exceeds ε, wave by wave,
    /// until no cell is left; returns the cells that became leaves. A subdivision whose
    /// children are all sampling-limited and over ε is undone (see the module docs).
    fn refine(
        &mut self,
        mut frontier: Vec<(u8, u64)>,
        stats: &mut SurfaceCoverStats,
    ) -> Vec<(u8, u64)> {
        let mut new_leaves = Vec::new();
        // The parent of each run of 8 cells of the frontier, when it came from a subdivision
        // in this call (the first frontier has none).
        let mut parents: Vec<(u8, u64, usize)> = Vec::new();
        while !frontier.is_empty() {
            let (fitted, mut rows): (Vec<Option<Leaf>>, Vec<Option<Vec<u32>>>) = frontier
                .par_iter()
                .enumerate()
                .map_init(
                    || (Candidates::default(), Vec::new()),
                    |(cand, sample), (idx, &(level, key))| {
                        // The parent's points, or all of them for the root.
                        let parent_points = match parents.get(idx / 8) {
                            Some(parent) => parent.2,
                            None if level == 0 => self.samples.index.len(),
                            None => 0,
                        };
                        if parent_points >= BOUND_FIRST_POINTS
                            && let Some(leaf) = self.bound_cell(sample, level, key)
                        {
                            return (Some(leaf), None);
                        }
                        self.fit_cell(cand, level, key, false)
                            .map_or((None, None), |(leaf, row)| (Some(leaf), row))
                    },
                )
                .unzip();
            let bounded = fitted.iter().flatten().filter(|l| l.bounded()).count();
            stats.bounded_octants += bounded;
            stats.fits += (frontier.len() - bounded) as u64;
            let eps = self.params.eps;
            let mut undone = vec![false; parents.len()];
            if self.params.sampling_stop {
                for (g, slot) in undone.iter_mut().enumerate() {
                    let group = &fitted[8 * g..8 * g + 8];
                    let sparse = parents[g].2 < SPLIT_FACTOR * self.params.n_min;
                    let limited = |l: &Option<Leaf>| l.as_ref().is_some_and(|l| l.empty || l.grown);
                    let over = group
                        .iter()
                        .flatten()
                        .any(|l| !l.empty && l.fit.error > eps);
                    *slot = over && (sparse || group.iter().all(limited));
                }
            }
            let restored: Vec<Option<(Leaf, Option<Vec<u32>>)>> = parents
                .par_iter()
                .zip(&undone)
                .map_init(Candidates::default, |cand, (&(level, key, _), &u)| {
                    if u {
                        self.fit_cell(cand, level, key, true)
                    } else {
                        None
                    }
                })
                .collect();
            for ((&(level, key, _), fitted), &u) in parents.iter().zip(restored).zip(&undone) {
                if let (true, Some((leaf, row))) = (u, fitted) {
                    self.internal[level as usize].remove(&key);
                    self.leaves.push(leaf);
                    self.rows.push(row);
                    new_leaves.push((level, key));
                    stats.sampling_limited_octants += 1;
                }
            }
            let mut next = Vec::new();
            let mut next_parents = Vec::new();
            for (idx, (&(level, key), leaf)) in frontier.iter().zip(fitted).enumerate() {
                stats.octants_per_level[level as usize] += 1;
                if undone.get(idx / 8).copied().unwrap_or(false) {
                    continue;
                }
                let Some(leaf) = leaf else { continue };
                if leaf.fit.error > eps
                    && u32::from(level) < self.params.max_depth
                    && leaf.refinable
                {
                    self.internal[level as usize].insert(key);
                    next.extend(children(key).map(|c| (level + 1, c)));
                    next_parents.push((level, key, leaf.own_points));
                } else {
                    debug_assert!(!leaf.bounded(), "a bounded cell is refined");
                    self.leaves.push(leaf);
                    self.rows.push(rows[idx].take());
                    new_leaves.push((level, key));
                }
            }
            frontier = next;
            parents = next_parents;
        }
        new_leaves
    }

    /// A cell whose fit would miss ε for certain, without fitting it: its own ball holds at
    /// least `n_min` points (so it is refinable, not grown), and four of them span a
    /// tetrahedron too thick for any plane to pass within ε of all four (see
    /// [`error_lower_bound`]). Such a cell is always subdivided, so only its error and its
    /// number of points are needed: the fit's normal and centroid are NaN. `None` where the
    /// cell must be fitted.
    fn bound_cell(&self, sample: &mut Vec<DVec3>, level: u8, key: u64) -> Option<Leaf> {
        if u32::from(level) >= self.params.max_depth {
            return None;
        }
        let (centre, natural) = self.geometry.cell(level, key);
        let samples = self.samples;
        let points = samples.index.slot_points();
        let conf = samples.confidence.as_deref();
        sample.clear();
        let own_points =
            samples
                .index
                .count_within_sampled(centre, natural, BOUND_GRAIN * natural, |s| {
                    if conf.is_none_or(|conf| conf[s] > 0.0) {
                        sample.push(points[s]);
                    }
                });
        if own_points < self.params.n_min {
            return None;
        }
        let bound = error_lower_bound(sample);
        // A margin far above the rounding of the bound and of the fit's error.
        if bound.is_nan() || bound <= self.params.eps * (1.0 + 1e-9) + 1e-12 * natural {
            return None;
        }
        Some(Leaf {
            level,
            key,
            centre,
            radius: natural,
            fit: Fit {
                normal: DVec3::NAN,
                centroid: DVec3::NAN,
                error: bound,
            },
            grown: false,
            empty: false,
            refinable: true,
            own_points,
        })
    }

    /// The support of a cell, and with `keep_rows` its row of [`SupportSamples`] when it grew
    /// to its `n_min` nearest points. `None` only when no point is indexed at all.
    /// `exact`: compute the exact error even where the cell would be refined (a cell whose
    /// subdivision was undone).
    fn fit_cell(
        &self,
        cand: &mut Candidates,
        level: u8,
        key: u64,
        exact: bool,
    ) -> Option<(Leaf, Option<Vec<u32>>)> {
        let (centre, natural) = self.geometry.cell(level, key);
        let samples = self.samples;
        cand.gather(samples, centre, natural);
        let mut radius = natural;
        let own_points = cand.len();
        let empty = own_points == 0;
        let mut grown = false;
        if cand.len() < self.params.n_min {
            let farthest = samples
                .index
                .kth_nearest_distance2(centre, self.params.n_min)?
                .sqrt();
            radius = natural.max(farthest * REACH);
            grown = radius > natural;
            // A hair wider than the ball, as its row is: the fit gives the points outside
            // the ball weight 0 and leaves them out of the error.
            cand.gather(samples, centre, SupportSamples::ball_radius(radius));
        }
        let limit = if u32::from(level) < self.params.max_depth && !empty && !exact {
            self.params.eps
        } else {
            // No refinement will follow: keep the exact error.
            f64::INFINITY
        };
        let refinable = !empty && radius <= REFINABLE_GROWTH * natural;
        let limit = if refinable { limit } else { f64::INFINITY };
        let mut fit = cand.fit(samples, radius, self.params.kernel, limit)?;
        if empty && fit.error > self.params.eps {
            radius = natural;
            grown = false;
            // No sample lies in the support's ball.
            fit.error = 0.0;
        }
        // A grown octant is never refined (see the module docs) nor grown further in the
        // expansion, so its gather is its row.
        let row = (self.keep_rows && grown).then(|| cand.slots().to_vec());
        let leaf = Leaf {
            level,
            key,
            centre,
            radius,
            fit,
            grown,
            empty,
            refinable,
            own_points,
        };
        Some((leaf, row))
    }

    /// Restores the 2:1 balance around the leaves `seeds` (and around every leaf it creates)
    /// and returns the created leaves, still to be fitted.
    fn balance(&mut self, seeds: Vec<(u8, u64)>) -> Vec<(u8, u64)> {
        let levels = self.internal.len();
        let mut buckets: Vec<Vec<u64>> = vec![Vec::new(); levels];
        for (level, key) in seeds {
            buckets[level as usize].push(key);
        }
        let mut created = Vec::new();
        // Deepest first: fixing level l only creates cells at levels below l, which are
        // checked afterwards.
        for level in (2..levels).rev() {
            let bucket = std::mem::take(&mut buckets[level]);
            let cells = 1i64 << level;
            // Each face neighbour's parent must exist: its grandparent subdivided. The
            // grandparents missing now are found in parallel, in the order of the sequential
            // walk; subdividing only adds internal cells (and none at this level), so a
            // grandparent present now stays present, and checking the others again in that
            // order makes the same subdivisions as the walk.
            let internal = &self.internal;
            let missing: Vec<u64> = bucket
                .par_iter()
                .with_min_len(1024)
                .filter(|&key| !internal[level].contains(key))
                .flat_map_iter(|&key| {
                    let (x, y, z) = unpack(key);
                    FACE_STEPS
                        .iter()
                        .filter_map(move |&(dx, dy, dz)| {
                            let (nx, ny, nz) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                            let inside = |c: i64| (0..cells).contains(&c);
                            (inside(nx) && inside(ny) && inside(nz))
                                .then(|| pack((nx >> 2) as u32, (ny >> 2) as u32, (nz >> 2) as u32))
                        })
                        .filter(|grand| !internal[level - 2].contains(grand))
                })
                .collect();
            for grand in missing {
                if !self.internal[level - 2].contains(&grand) {
                    self.subdivide_up(level - 2, grand, &mut buckets, &mut created);
                }
            }
        }
        created.retain(|&(level, key)| !self.internal[level as usize].contains(&key));
        created
    }

    /// Subdivides cell `(level, key)` and every ancestor not yet subdivided; the new cells
    /// that are not themselves subdivided are new leaves.
    fn subdivide_up(
        &mut self,
        mut level: usize,
        mut key: u64,
        buckets: &mut [Vec<u64>],
        created: &mut Vec<(u8, u64)>,
    ) {
        let mut chain = Vec::new();
        while !self.internal[level].contains(&key) {
            self.internal[level].insert(key);
            chain.push((level, key));
            if level == 0 {
                break;
            }
            level -= 1;
            key = parent(key);
        }
        for (level, key) in chain {
            for child in children(key) {
                if !self.internal[level + 1].contains(&child) {
                    created.push(((level + 1) as u8, child));
                    buckets[level + 1].push(child);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface_cover::fit::tests::bumpy_sphere;
    use proptest::prelude::*;

    /// For every cell of `level` that [`Octree::bound_cell`] settles, the exact fit must
    /// agree that the cell is refined: over ε, not grown, not empty, refinable, with the
    /// same radius and points, its error at least the bound. Returns how many were settled.
    fn check_bounded_cells(samples: &Samples<'_>, eps: f64, level: u8) -> usize {
        let params = SurfaceCoverParams {
            eps,
            ..SurfaceCoverParams::default()
        };
        let tree = Octree {
            samples,
            params: &params,
            geometry: Geometry {
                min: -0.5,
                side: 1.0,
            },
            internal: Vec::new(),
            leaves: Vec::new(),
            rows: Vec::new(),
            keep_rows: false,
        };
        let (mut cand, mut sample) = (Candidates::default(), Vec::new());
        let cells = 1u32 << level;
        let mut settled = 0;
        for x in 0..cells {
            for y in 0..cells {
                for z in 0..cells {
                    let key = pack(x, y, z);
                    let Some(bounded) = tree.bound_cell(&mut sample, level, key) else {
                        continue;
                    };
                    settled += 1;
                    let (fitted, _) = tree.fit_cell(&mut cand, level, key, true).unwrap();
                    assert!(fitted.fit.error > eps, "cell {x} {y} {z}");
                    assert!(bounded.fit.error <= fitted.fit.error * (1.0 + 1e-9));
                    assert!(fitted.refinable && !fitted.grown && !fitted.empty);
                    assert_eq!(
                        (bounded.radius, bounded.own_points),
                        (fitted.radius, fitted.own_points)
                    );
                }
            }
        }
        settled
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn a_bounded_cell_is_one_the_fit_refines(
            bump in 0.0..0.05f64,
            eps in 1e-4..2e-2f64,
            level in 1u8..5,
        ) {
            check_bounded_cells(&bumpy_sphere(3000, bump), eps, level);
        }
    }

    #[test]
    fn the_bound_settles_the_bent_cells() {
        // A cell of side 1/8 holds a cap of the sphere of radius 0.3 whose sag is far
        // above ε = 1e-3 wherever the cell holds a sizeable patch.
        let settled = check_bounded_cells(&bumpy_sphere(3000, 0.0), 1e-3, 3);
        assert!(settled >= 20, "{settled}");
    }
}
