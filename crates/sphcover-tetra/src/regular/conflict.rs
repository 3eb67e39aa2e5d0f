//! The geometric questions of the construction, on vertex handles: whether a point is in
//! conflict with a tetrahedron (the perturbed power test) and the orientation of four
//! vertices, each exact, with shortcuts for centres on one dyadic grid.
//!
//! The walk, the conflict search and the validity checks all ask them; the float filters,
//! the grid stages and the exact fallbacks stay together here, where the hottest calls of
//! the construction can be read in one place.

use super::cells::CellRead;
use super::{Geometry, INFINITE_VERTEX};
use crate::predicates::{
    Point, grid_lifted_sign, lifted_sign_fixed, orient3d, orient3d_filter, orient3d_grid,
    power_test_exact, power_test_filter,
};

/// Whether point `v` conflicts with cell `t` of `cells` (perturbed power test; for an
/// infinite cell: beyond its hull facet, or on its plane and inside the facet's power
/// circle). `None` when that last case needs the neighbours of a cell the caller may only
/// read (they can be stale there).
#[inline]
pub(super) fn conflict<C: CellRead + ?Sized>(
    cells: &C,
    geometry: &Geometry,
    t: u32,
    v: u32,
) -> Option<bool> {
    let cell = cells.cell(t).v;
    if let Some(k) = cell.iter().position(|&x| x == INFINITE_VERTEX) {
        let mut ids = cell;
        ids[k] = v;
        let o = geometry.orient(ids);
        if o != 0 {
            return Some(o > 0);
        }
        // On the hull facet's plane: conflict with the facet's power circle. For a
        // coplanar query that equals conflict with the orthosphere of the finite cell on
        // the facet (both are the lifted plane through the facet's lifted vertices), and
        // the perturbation agrees too (the apex's term is the flat orient(a, b, c, q)).
        if !cells.owns(t) {
            return None;
        }
        let finite = cells.cell(t).n[k];
        return Some(geometry.finite_conflict(&cells.cell(finite).v, v));
    }
    Some(geometry.finite_conflict(&cell, v))
}

impl Geometry {
    /// Whether point `v` conflicts with the finite tetrahedron `cell` (perturbed power test).
    #[inline]
    pub(super) fn finite_conflict(&self, cell: &[u32; 4], v: u32) -> bool {
        let q = &self.pw[v as usize].p;
        let wq = self.pw[v as usize].w;
        // Plain indexing (an array `map` here is not always inlined, and this is the hottest
        // call of the construction).
        let (a, b, c, d) = (
            &self.pw[cell[0] as usize],
            &self.pw[cell[1] as usize],
            &self.pw[cell[2] as usize],
            &self.pw[cell[3] as usize],
        );
        let p = [&a.p, &b.p, &c.p, &d.p];
        let w = [a.w, b.w, c.w, d.w];
        let equal_grid =
            if self.grid_inverse_unit != 0.0 && a.w == wq && b.w == wq && c.w == wq && d.w == wq {
                grid_lifted_sign(p, w, q, wq, self.grid_inverse_unit)
            } else {
                None
            };
        let s = match equal_grid.or_else(|| power_test_filter(p, w, q, wq)) {
            Some(s) => s,
            None => self.exact_power_test(cell, v, p, w, q, wq),
        };
        if s != 0 {
            return s < 0;
        }
        // A tie: the symbolic perturbation decides (see `predicates::power_sphere_perturbed`,
        // here with orientations through `orient`).
        let r = |x: u32| self.rank[x as usize];
        let mut rank = [r(cell[0]), r(cell[1]), r(cell[2]), r(cell[3]), r(v)];
        let mut left = 5;
        while left > 0 {
            let mut i = 5;
            for j in 0..5 {
                if rank[j] != u32::MAX && (i == 5 || rank[j] > rank[i]) {
                    i = j;
                }
            }
            if i == 4 {
                return false;
            }
            rank[i] = u32::MAX;
            left -= 1;
            let mut ids = *cell;
            ids[i] = v;
            let o = self.orient(ids);
            if o != 0 {
                return o > 0;
            }
        }
        // Unreachable: the cell is not flat, so some replacement is not flat either.
        false
    }

    /// Exact orientation of four vertices (no infinite one): the float filter, then `i128`
    /// arithmetic on the precomputed grid when there is one, else the exact stages of
    /// [`orient3d`].
    #[inline]
    pub(super) fn orient(&self, ids: [u32; 4]) -> i32 {
        let (pa, pb, pc, pd) = (
            self.point(ids[0]),
            self.point(ids[1]),
            self.point(ids[2]),
            self.point(ids[3]),
        );
        match orient3d_filter(pa, pb, pc, pd) {
            Some(s) => s,
            None => {
                // Near-zero orientations, mostly exact zeros on grids: plain f64 settles them
                // when the grid is fine enough, before the out-of-line exact stages.
                if self.grid_orient_limit != 0.0
                    && let Some(s) = orient3d_grid(pa, pb, pc, pd, self.grid_orient_limit)
                {
                    return s;
                }
                self.orient_exact(ids)
            }
        }
    }

    /// The exact stages of [`Self::orient`].
    #[cold]
    fn orient_exact(&self, ids: [u32; 4]) -> i32 {
        if let Some((_, ic)) = &self.grid {
            let a = ic[ids[0] as usize];
            let d = |x: u32| {
                let b = ic[x as usize];
                [
                    (b[0] as i64 - a[0] as i64) as i128,
                    (b[1] as i64 - a[1] as i64) as i128,
                    (b[2] as i64 - a[2] as i64) as i128,
                ]
            };
            let (b, c, e) = (d(ids[1]), d(ids[2]), d(ids[3]));
            // Differences below 2^31: each product of three below 2^93.
            let det = b[0] * (c[1] * e[2] - c[2] * e[1]) - b[1] * (c[0] * e[2] - c[2] * e[0])
                + b[2] * (c[0] * e[1] - c[1] * e[0]);
            return det.signum() as i32;
        }
        orient3d(
            self.point(ids[0]),
            self.point(ids[1]),
            self.point(ids[2]),
            self.point(ids[3]),
        )
    }

    /// [`power_test`](crate::predicates::power_test)'s exact stages, through the precomputed
    /// grid when there is one.
    #[cold]
    fn exact_power_test(
        &self,
        cell: &[u32; 4],
        v: u32,
        p: [&Point; 4],
        w: [f64; 4],
        q: &Point,
        wq: f64,
    ) -> i32 {
        if self.grid_inverse_unit != 0.0
            && let Some(s) = grid_lifted_sign(p, w, q, wq, self.grid_inverse_unit)
        {
            return s;
        }
        if let Some((e, ic)) = &self.grid {
            let iq = ic[v as usize];
            let mut ints = [0i64; 12];
            let mut range = 0i64;
            for i in 0..4 {
                let ip = ic[cell[i] as usize];
                for k in 0..3 {
                    let d = ip[k] as i64 - iq[k] as i64;
                    ints[3 * i + k] = d;
                    range |= d.abs();
                }
            }
            if range < 1 << 22
                && let Some(s) = lifted_sign_fixed(&ints, *e, w, wq)
            {
                return s;
            }
        }
        power_test_exact(p, w, q, wq)
    }
}
