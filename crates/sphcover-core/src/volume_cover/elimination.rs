//! Elimination of redundant supports (step 5 of the algorithm in the notes of the
//! `volume_cover` module, a departure from the thesis): what a support's members are (the
//! object voxels and, by default, the cell corners) and which supports go.
//!
//! It runs on the finished list of either builder and keeps every member in some ball, so
//! it stays apart from the covering that placed the balls; the greedy centre order counts
//! the same members.

use std::sync::atomic::{AtomicU32, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::grid::Grid;
use super::support::Support;

impl<'a> Grid<'a> {
    /// Calls `f` with every object point (every grid point, for the linear variant) strictly
    /// inside the support's ball.
    #[inline]
    fn for_each_member(&self, s: &Support, f: &mut dyn FnMut(usize)) {
        let base = self.base(s.centre as usize);
        for o in &self.offsets[..s.offsets] {
            if let Some(idx) = self.neighbour(base, o.step)
                && (self.bounding_box || self.object[idx])
            {
                f(idx);
            }
        }
    }

    /// Calls `f` with the support's member voxels (`0..n`) and, with `corners`, its member
    /// cell corners (`n..`).
    pub(super) fn for_each_point(
        &self,
        s: &Support,
        corners: Option<&CornerSet>,
        f: &mut dyn FnMut(usize),
    ) {
        self.for_each_member(s, &mut *f);
        if let Some(cs) = corners {
            let n = self.volume.len();
            cs.for_each_member(self, s, |c| f(n + c));
        }
    }

    /// Removes redundant supports (see [`eliminate_redundant_supports`]); members are the
    /// object voxels and, with `corners`, the cell corners.
    pub(super) fn eliminate_redundant(
        &self,
        supports: Vec<Support>,
        corners: Option<&CornerSet>,
    ) -> Vec<Support> {
        let total = self.volume.len() + corners.map_or(0, |cs| cs.object.len());
        eliminate_redundant_supports(supports, self.tolerance, total, |s, f| {
            self.for_each_point(s, corners, f)
        })
    }
}

/// The corners of the voxel cells (the lattice shifted by half a voxel) that touch an object
/// voxel, for [`Elimination::CellCorners`](super::Elimination::CellCorners). Corner
/// `(a, b, c)`, `a ∈ 0..=nx`, sits at voxel coordinates `(a − ½, b − ½, c − ½)`.
pub(super) struct CornerSet {
    dims: [i64; 3],
    pub(super) object: Vec<bool>,
    /// Offsets from a voxel centre to corners within `r_max`: `(step, distance² in frame
    /// d/h)`, by increasing distance; the corner of step `s` from voxel `v` is `v + s + 1`.
    offsets: Vec<([i32; 3], f64)>,
}

impl CornerSet {
    pub(super) fn new(grid: &Grid) -> CornerSet {
        let [nx, ny, nz] = grid.dims;
        let dims = [nx + 1, ny + 1, nz + 1];
        let count = (dims[0] * dims[1] * dims[2]) as usize;
        let object: Vec<bool> = (0..count)
            .into_par_iter()
            .map(|c| {
                let c = c as i64;
                let (a, b, k) = (
                    c % dims[0],
                    (c / dims[0]) % dims[1],
                    c / (dims[0] * dims[1]),
                );
                (0..8).any(|m| {
                    let (i, j, l) = (a - 1 + (m & 1), b - 1 + ((m >> 1) & 1), k - 1 + (m >> 2));
                    (0..nx).contains(&i)
                        && (0..ny).contains(&j)
                        && (0..nz).contains(&l)
                        && grid.object[(i + nx * (j + ny * l)) as usize]
                })
            })
            .collect();
        let reach = grid.r_max / grid.unit;
        let inv = grid.linear.inverse().transpose();
        let ext = [inv.x_axis, inv.y_axis, inv.z_axis]
            .map(|row| (reach * row.length()).ceil() as i32 + 1);
        let mut offsets = Vec::new();
        for k in -ext[2]..ext[2] {
            for j in -ext[1]..ext[1] {
                for i in -ext[0]..ext[0] {
                    let p =
                        grid.linear * DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5);
                    let d2 = p.length_squared();
                    if d2 <= reach * reach {
                        offsets.push(([i, j, k], d2));
                    }
                }
            }
        }
        offsets.sort_by(|a, b| a.1.total_cmp(&b.1).then_with(|| a.0.cmp(&b.0)));
        CornerSet {
            dims,
            object,
            offsets,
        }
    }

    /// Calls `f` with the object corners strictly inside the support's ball.
    fn for_each_member(&self, grid: &Grid, s: &Support, mut f: impl FnMut(usize)) {
        let base = grid.base(s.centre as usize);
        let limit = s.radius / grid.unit * (1.0 - 1e-9);
        let limit2 = limit * limit;
        for &(step, d2) in &self.offsets {
            if d2 >= limit2 {
                break;
            }
            let a = base[0] + i64::from(step[0]) + 1;
            let b = base[1] + i64::from(step[1]) + 1;
            let c = base[2] + i64::from(step[2]) + 1;
            let [dx, dy, dz] = self.dims;
            if a < 0 || b < 0 || c < 0 || a >= dx || b >= dy || c >= dz {
                continue;
            }
            let idx = (a + dx * (b + dy * c)) as usize;
            if self.object[idx] {
                f(idx);
            }
        }
    }
}

/// Removes redundant supports: those over `tolerance` first, then in order of increasing
/// member count (ties by position), a support goes when each of its members (indices below
/// `members`, listed by `for_each_member`) lies in at least one other remaining support.
/// Every member keeps at least one support, so the cover stays gap-free. The removal is
/// sequential and order-defined: the same whatever the thread count.
pub(super) fn eliminate_redundant_supports(
    supports: Vec<Support>,
    tolerance: f64,
    members: usize,
    for_each_member: impl Fn(&Support, &mut dyn FnMut(usize)) + Sync,
) -> Vec<Support> {
    let counts: Vec<AtomicU32> = (0..members).map(|_| AtomicU32::new(0)).collect();
    let sizes: Vec<u32> = supports
        .par_iter()
        .map(|s| {
            let mut size = 0u32;
            for_each_member(s, &mut |idx| {
                counts[idx].fetch_add(1, Ordering::Relaxed);
                size += 1;
            });
            size
        })
        .collect();
    let mut counts: Vec<u32> = counts.into_iter().map(AtomicU32::into_inner).collect();
    let mut by_size: Vec<u32> = (0..supports.len() as u32).collect();
    by_size.sort_by_key(|&i| {
        let s = &supports[i as usize];
        (s.rms <= tolerance, sizes[i as usize], i)
    });
    let mut keep = vec![true; supports.len()];
    for &i in &by_size {
        let s = &supports[i as usize];
        let mut redundant = true;
        for_each_member(s, &mut |idx| redundant &= counts[idx] >= 2);
        if redundant {
            for_each_member(s, &mut |idx| counts[idx] -= 1);
            keep[i as usize] = false;
        }
    }
    supports
        .into_iter()
        .zip(keep)
        .filter_map(|(s, k)| k.then_some(s))
        .collect()
}
