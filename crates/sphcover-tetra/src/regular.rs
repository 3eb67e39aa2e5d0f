//! Incremental 3D regular (weighted Delaunay) triangulation.
//!
//! Design (after geogram's `Delaunay_3d`, BSD-3): points are inserted one at a time in BRIO +
//! Hilbert order ([`crate::spatial_sort`]); each is located by a remembering stochastic walk
//! from the previous insertion; the *conflict zone* (tetrahedra whose orthosphere the new
//! weighted point has negative power against) is grown by a depth-first search from the
//! located tetrahedron and replaced by the cone from the new point to its boundary
//! (Bowyer–Watson). The convex hull is closed by tetrahedra through one *infinite vertex*.
//!
//! Redundant (hidden) points. A weighted point whose lifted image lies above the lower
//! convex hull of the lifted points has no power cell and is not a vertex:
//! * if the tetrahedron containing the new point is not in conflict with it, the point is
//!   redundant when it arrives and is not inserted;
//! * a heavier point can make an existing vertex redundant. Then every tetrahedron around
//!   that vertex is in conflict (its lifted image is above the new lower hull), so the vertex
//!   lies inside the conflict zone and disappears with it: after building the cone we mark
//!   as hidden every vertex of the zone that no new tetrahedron uses. A hidden point stays
//!   hidden (inserting points only lowers the lower hull), so no vertex ever reappears.
//!
//! Ties (co-spherical, co-planar configurations) are broken by the symbolic perturbation of
//! [`crate::predicates`], which is a genuine perturbation of the lifted coordinates: the
//! result is the regular triangulation of a generic point set infinitesimally close to the
//! input, every tetrahedron has positive volume, and no random perturbation is needed.
//! Points with identical centres are resolved before insertion: the heaviest (then the
//! first) stays, the others are hidden.
//!
//! Storage uses `u32` handles: per tetrahedron slot one 32-byte aligned block holding its
//! four vertices and the neighbour opposite each (the walk and the conflict search read both
//! for every cell they visit: one cache line instead of two), and a free list of slots. The
//! input-sized arrays (points, ranks, marks) stay separate. While building, vertices are numbered in
//! insertion order (cells near the new point then touch nearby memory) and mapped back to
//! input indices at the end. The cone over the conflict zone is stitched in two passes: each new
//! cell takes its outside neighbour from the old cell it replaces, and the new cells are
//! paired with each other through a small per-insertion table keyed by their boundary edge
//! (open addressing, stamped instead of cleared; no allocation in the steady state). On inputs whose centres lie on
//! one dyadic grid (voxel grids, octrees), integer coordinates are precomputed so that exact
//! tie-breaking, frequent there, skips the per-call bit analysis, and power tests whose five
//! weights are equal go straight to an exact small-integer evaluation (on the octree
//! benchmark cover, counted at 50K spheres, 30% of the power tests are exact ties, nine in
//! ten of them between equal weights).
//!
//! Parallelism: the sorts (duplicate detection, the Hilbert rounds) and the final renumbering
//! run on rayon; the insertions are sequential. Sorted keys are distinct pairs, so every order
//! is the same whatever the thread count.

use rayon::prelude::*;

use crate::error::TetraError;
use crate::predicates::{
    MAX_COORDINATE, MAX_WEIGHT, Point, collinear, grid_lifted_sign, lifted_sign_fixed, orient3d,
    orient3d_filter, orient3d_grid, power_test_exact, power_test_filter,
};
use crate::spatial_sort::{SplitMix64, brio_order};

/// The infinite vertex, closing the hull.
pub const INFINITE_VERTEX: u32 = u32::MAX;
/// A missing handle (no tetrahedron / no neighbour).
pub const NO_TET: u32 = u32::MAX;
/// Vertex-slot marker of a freed tetrahedron.
const DEAD: u32 = u32::MAX - 1;

/// What became of an input point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VertexStatus {
    /// A vertex of the triangulation.
    Vertex,
    /// Redundant: its power cell is empty (a heavier neighbour swallows it).
    Hidden,
    /// Same centre as another point that is kept (the heavier one, or the first of equals).
    Duplicate,
}

/// Options of [`RegularTriangulation::new`].
#[derive(Clone, Debug)]
pub struct TriangulationParams {
    /// Seed of the insertion order and of the walk (same seed → same triangulation).
    pub seed: u64,
}

impl Default for TriangulationParams {
    fn default() -> Self {
        Self { seed: 0x5eed_7e7a }
    }
}

/// A centre and its weight, stored together (32 bytes: two per cache line).
#[derive(Clone, Copy, Debug)]
struct WeightedPoint {
    p: Point,
    w: f64,
}

/// Counters of one construction.
#[derive(Clone, Debug, Default)]
pub struct TriangulationStats {
    /// Points given.
    pub points: usize,
    /// Points that ended as vertices.
    pub vertices: usize,
    /// Points hidden on arrival or later.
    pub hidden: usize,
    /// Points dropped as duplicated centres.
    pub duplicates: usize,
    /// Live tetrahedra, finite and infinite.
    pub tets: usize,
    /// Live finite tetrahedra.
    pub finite_tets: usize,
    /// Orientation steps of the point-location walks.
    pub walk_steps: u64,
    /// Tetrahedra found in conflict over all insertions.
    pub conflict_tets: u64,
}

/// A 3D regular triangulation of weighted points (weights are squared radii).
#[derive(Clone, Debug)]
pub struct RegularTriangulation {
    /// `[x, y, z, w]` per point (one cache line holds two). While building, indexed by
    /// insertion rank (neighbouring cells then touch neighbouring memory); afterwards by input
    /// index, like every handle the API returns.
    pw: Vec<WeightedPoint>,
    /// Tetrahedron slots: vertices and neighbours together (one cache line per cell).
    cells: Vec<Cell>,
    free: Vec<u32>,
    status: Vec<VertexStatus>,
    /// While building, when every centre lies on one dyadic grid (grids, octrees): each
    /// centre as integers in units of `2^e`, so exact tie-breaking skips the bit analysis.
    grid: Option<(i32, Vec<[i32; 3]>)>,
    /// While building on such a grid, `2^-e` (one over the grid unit); otherwise 0.
    grid_inverse_unit: f64,
    /// While building on such a grid with `|e| ≤ 300`, `2^16` grid units, the range of the
    /// exact grid orientation ([`orient3d_grid`]); otherwise 0.
    grid_orient_limit: f64,
    /// Lexicographic rank of each point's centre (ties share a rank; only distinct centres
    /// are inserted), the order of the symbolic perturbation.
    rank: Vec<u32>,
    stats: TriangulationStats,
}

/// One tetrahedron slot: its vertices and, in slot `i` of `n`, the neighbour across the face
/// opposite vertex `i`. Together in one 32-byte aligned block, so visiting a cell during the
/// walk or the conflict search touches a single cache line.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Cell {
    v: [u32; 4],
    n: [u32; 4],
}

/// Scratch buffers reused across insertions (no allocation in the steady state).
struct Scratch {
    /// Per tet: [`UNTESTED`], [`IN_CONFLICT`] or [`OUTSIDE`] for the current insertion; reset
    /// before the next one (one byte keeps the array cache-resident).
    mark: Vec<u8>,
    stamp: u32,
    stack: Vec<u32>,
    cavity: Vec<u32>,
    boundary: Vec<BoundaryFace>,
    /// Open-addressing table pairing the new cells' faces through the inserted point by
    /// their boundary edge; a power of two long, entries valid for the current stamp only.
    edge_table: Vec<EdgeSlot>,
    rng: SplitMix64,
    /// Per vertex: the insertion stamp of the last cavity boundary it was on.
    vmark: Vec<u32>,
    /// Per vertex (insertion numbering): hidden on arrival or swallowed later.
    hidden: Vec<bool>,
}

/// A face of the conflict zone's boundary: face `face` of the zone's cell `old`, and the new
/// cell built on it from the inserted point (once built).
#[derive(Clone, Copy, Debug)]
struct BoundaryFace {
    old: u32,
    face: u8,
    new: u32,
}

/// An entry of [`Scratch::edge_table`]: the edge (its two vertices, smaller one high) and the
/// new cell face through it waiting for its partner.
#[derive(Clone, Copy, Debug, Default)]
struct EdgeSlot {
    key: u64,
    cell: u32,
    face: u32,
    stamp: u32,
}

const UNTESTED: u8 = 0;
const IN_CONFLICT: u8 = 1;
const OUTSIDE: u8 = 2;

impl RegularTriangulation {
    /// Triangulates `points` with `weights` (squared radii).
    ///
    /// Errors: mismatched lengths, non-finite or out-of-range values (coordinates beyond
    /// ±1e20, weights beyond 1e40), more than `u32::MAX − 2` points, or distinct centres that
    /// do not span 3D (fewer than four affinely independent ones).
    pub fn new(
        points: &[Point],
        weights: &[f64],
        params: &TriangulationParams,
    ) -> Result<Self, TetraError> {
        if points.len() != weights.len() {
            return Err(TetraError::LengthMismatch {
                points: points.len(),
                weights: weights.len(),
            });
        }
        if points.len() >= (u32::MAX - 2) as usize {
            return Err(TetraError::TooManyPoints {
                count: points.len(),
            });
        }
        for (i, p) in points.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite() && c.abs() <= MAX_COORDINATE) {
                return Err(TetraError::InvalidPoint { index: i });
            }
        }
        for (i, w) in weights.iter().enumerate() {
            if !(w.is_finite() && w.abs() <= MAX_WEIGHT) {
                return Err(TetraError::InvalidWeight { index: i });
            }
        }
        let n = points.len();
        let mut status = vec![VertexStatus::Vertex; n];
        let mut rank = vec![0u32; n];
        let mut order = distinct_points(points, weights, &mut status, &mut rank);
        let distinct = order.len();
        brio_order(points, &mut order, params.seed);
        // While building, vertex `i` is the `i`-th point inserted.
        let mut tri = RegularTriangulation {
            pw: order
                .iter()
                .map(|&e| WeightedPoint {
                    p: points[e as usize],
                    w: weights[e as usize],
                })
                .collect(),
            rank: order.iter().map(|&e| rank[e as usize]).collect(),
            cells: Vec::with_capacity(7 * distinct + 16),
            free: Vec::new(),
            status: Vec::new(),
            grid: None,
            grid_inverse_unit: 0.0,
            grid_orient_limit: 0.0,
            stats: TriangulationStats {
                points: n,
                ..Default::default()
            },
        };
        tri.grid = integer_grid(&tri.pw);
        tri.grid_inverse_unit = match &tri.grid {
            // 2^-e is a normal f64 for e in -1022..=1022.
            Some((e, _)) if (-1022..=1022).contains(e) => f64::from_bits(((1023 - e) as u64) << 52),
            _ => 0.0,
        };
        tri.grid_orient_limit = match &tri.grid {
            // 2^(e+16), a normal f64 in this range.
            Some((e, _)) if (-300..=300).contains(e) => {
                f64::from_bits(((1023 + 16 + e) as u64) << 52)
            }
            _ => 0.0,
        };
        let first =
            tri.initial_simplex(distinct)
                .map_err(|dimension| TetraError::NotFullDimensional {
                    dimension,
                    distinct,
                })?;
        let mut scratch = Scratch {
            mark: Vec::with_capacity(7 * distinct + 16),
            stamp: 0,
            stack: Vec::new(),
            cavity: Vec::new(),
            boundary: Vec::new(),
            edge_table: Vec::new(),
            rng: SplitMix64::new(params.seed ^ 0xa5a5_5a5a_dead_beef),
            vmark: vec![0; distinct],
            hidden: vec![false; distinct],
        };
        let mut hint = 0u32;
        for v in 0..distinct as u32 {
            if first.contains(&v) {
                continue;
            }
            hint = tri.insert(v, hint, &mut scratch);
        }
        // Back to input numbering.
        tri.cells
            .par_iter_mut()
            .with_min_len(4096)
            .for_each(|cell| {
                if cell.v[0] != DEAD {
                    for x in cell.v.iter_mut() {
                        if *x != INFINITE_VERTEX {
                            *x = order[*x as usize];
                        }
                    }
                }
            });
        for (i, &h) in scratch.hidden.iter().enumerate() {
            if h {
                status[order[i] as usize] = VertexStatus::Hidden;
            }
        }
        tri.grid = None;
        tri.grid_inverse_unit = 0.0;
        tri.grid_orient_limit = 0.0;
        tri.pw = points
            .iter()
            .zip(weights)
            .map(|(&p, &w)| WeightedPoint { p, w })
            .collect();
        tri.rank = rank;
        tri.status = status;
        let count = |k: VertexStatus| tri.status.iter().filter(|s| **s == k).count();
        tri.stats.duplicates = count(VertexStatus::Duplicate);
        tri.stats.hidden = count(VertexStatus::Hidden);
        tri.stats.vertices = n - tri.stats.duplicates - tri.stats.hidden;
        tri.stats.tets = tri.cells.len() - tri.free.len();
        tri.stats.finite_tets = tri.finite_tets().count();
        Ok(tri)
    }

    /// Builds the first tetrahedron and its four infinite neighbours from the first four
    /// affinely independent points of `order`; returns them, or the dimension reached.
    fn initial_simplex(&mut self, count: usize) -> Result<[u32; 4], u8> {
        let order: Vec<u32> = (0..count as u32).collect();
        let order = &order[..];
        let p = |v: u32| self.point(v);
        let Some(&a) = order.first() else {
            return Err(0);
        };
        let Some(&b) = order.get(1) else {
            return Err(0);
        };
        // b differs from a (centres are distinct).
        let collinear = |c: u32| collinear(p(a), p(b), p(c));
        let Some(&c) = order[2..].iter().find(|&&c| !collinear(c)) else {
            return Err(1);
        };
        let Some(&d) = order[2..]
            .iter()
            .find(|&&d| d != c && orient3d(p(a), p(b), p(c), p(d)) != 0)
        else {
            return Err(2);
        };
        let (a, b) = if orient3d(p(a), p(b), p(c), p(d)) > 0 {
            (a, b)
        } else {
            (b, a)
        };
        let finite = [a, b, c, d];
        let mut cells = vec![finite];
        for i in 0..4 {
            // Face i of the finite cell with the infinite vertex in place of vertex i, made
            // positive by swapping two finite vertices.
            let mut t = finite;
            t[i] = INFINITE_VERTEX;
            let (j, k) = match i {
                0 => (1, 2),
                _ => (0, if i == 1 { 2 } else { 1 }),
            };
            t.swap(j, k);
            cells.push(t);
        }
        for cell in &cells {
            self.alloc(*cell);
        }
        // Link the five cells by matching faces.
        for t in 0..5u32 {
            for i in 0..4 {
                let face = face_key(&self.cells[t as usize].v, i);
                for u in 0..5u32 {
                    if u == t {
                        continue;
                    }
                    for j in 0..4 {
                        if face_key(&self.cells[u as usize].v, j) == face {
                            self.cells[t as usize].n[i] = u;
                        }
                    }
                }
            }
        }
        Ok(finite)
    }

    #[inline]
    fn alloc(&mut self, cell: [u32; 4]) -> u32 {
        if let Some(t) = self.free.pop() {
            self.cells[t as usize].v = cell;
            self.cells[t as usize].n = [NO_TET; 4];
            t
        } else {
            self.cells.push(Cell {
                v: cell,
                n: [NO_TET; 4],
            });
            (self.cells.len() - 1) as u32
        }
    }

    #[inline]
    fn point(&self, v: u32) -> &Point {
        &self.pw[v as usize].p
    }

    /// Inserts point `v`, walking from `hint`; returns a live tetrahedron near `v`.
    fn insert(&mut self, v: u32, hint: u32, s: &mut Scratch) -> u32 {
        let start = self.locate(v, hint, s);
        if !self.in_conflict(start, v) {
            s.hidden[v as usize] = true;
            return start;
        }
        if s.mark.len() < self.cells.len() {
            s.mark.resize(self.cells.len(), 0);
        }
        s.stamp += 1;
        let (conflict, outside) = (IN_CONFLICT, OUTSIDE);
        // The search's vectors as locals (their lengths can then live in registers across the
        // out-of-line predicate calls); put back below.
        let mut stack = std::mem::take(&mut s.stack);
        let mut cavity = std::mem::take(&mut s.cavity);
        let mut boundary = std::mem::take(&mut s.boundary);
        let mark = &mut s.mark;
        stack.clear();
        cavity.clear();
        boundary.clear();
        stack.push(start);
        mark[start as usize] = conflict;
        while let Some(t) = stack.pop() {
            cavity.push(t);
            let neighbours = self.cells[t as usize].n;
            for (i, n) in (0..4u8).zip(neighbours) {
                let m = mark[n as usize];
                if m == conflict {
                    continue;
                }
                if m != outside && self.in_conflict(n, v) {
                    mark[n as usize] = conflict;
                    stack.push(n);
                } else {
                    mark[n as usize] = outside;
                    boundary.push(BoundaryFace {
                        old: t,
                        face: i,
                        new: NO_TET,
                    });
                }
            }
        }
        s.stack = stack;
        s.cavity = cavity;
        s.boundary = boundary;
        self.stats.conflict_tets += s.cavity.len() as u64;
        // Every new cell's slot, reused or appended, gets a mark entry.
        let needed = self.cells.len() + s.boundary.len();
        if s.mark.len() < needed {
            s.mark.resize(needed, UNTESTED);
        }
        // Cone from v over the zone's boundary. The old cell keeps, in the slot of the
        // boundary face, the handle of the new cell built on that face: the second pass
        // finds the new cells' mutual neighbours through it.
        // New cells take the free slots in the order `pop` would (last freed first), then
        // append; a reused slot's mark was cleared when it was freed and an appended one is
        // fresh, so every new cell is UNTESTED.
        let stamp = s.stamp;
        let (mark, vmark) = (&mut s.mark, &mut s.vmark);
        let free_len = self.free.len();
        let reused = free_len.min(s.boundary.len());
        for (j, f) in s.boundary.iter_mut().enumerate() {
            let (t, i) = (f.old, f.face as usize);
            let old = self.cells[t as usize];
            let mut fresh = Cell {
                v: old.v,
                n: [NO_TET; 4],
            };
            fresh.v[i] = v;
            let outer = old.n[i];
            fresh.n[i] = outer;
            let nt = if j < reused {
                let nt = self.free[free_len - 1 - j];
                self.cells[nt as usize] = fresh;
                nt
            } else {
                self.cells.push(fresh);
                (self.cells.len() - 1) as u32
            };
            // The search is over: clear the tested-outside mark for the next insertion.
            mark[outer as usize] = UNTESTED;
            let back = self.cells[outer as usize]
                .n
                .iter()
                .position(|&x| x == t)
                .expect("adjacency is symmetric");
            self.cells[outer as usize].n[back] = nt;
            self.cells[t as usize].n[i] = nt;
            // The boundary facet's vertices stay; `v` is new.
            for (k, &u) in old.v.iter().enumerate() {
                if k != i && u != INFINITE_VERTEX {
                    vmark[u as usize] = stamp;
                }
            }
            f.new = nt;
        }
        self.free.truncate(free_len - reused);
        // Each face of a new cell through v contains an edge ab of the zone's boundary (a
        // closed surface: every edge is on exactly two boundary faces), and the neighbour
        // across it is the new cell on the other face through ab. They are paired by a
        // small open-addressing table keyed by the edge, stamped per insertion (no clearing).
        let edges = 3 * s.boundary.len() / 2;
        if s.edge_table.len() < 4 * edges {
            let size = (4 * edges).next_power_of_two();
            s.edge_table.clear();
            s.edge_table.resize(size, EdgeSlot::default());
        }
        let mask = s.edge_table.len() - 1;
        let shift = 64 - s.edge_table.len().trailing_zeros();
        for f in &s.boundary {
            let (i, nt) = (f.face as usize, f.new);
            let cell = self.cells[nt as usize].v;
            for k in 0..4usize {
                if k == i {
                    continue;
                }
                let (x, y) = other_two(i, k);
                let (a, b) = (cell[x], cell[y]);
                let key = if a < b {
                    ((a as u64) << 32) | b as u64
                } else {
                    ((b as u64) << 32) | a as u64
                };
                let mut h = (key.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> shift) as usize;
                loop {
                    let slot = &mut s.edge_table[h];
                    if slot.stamp != stamp {
                        *slot = EdgeSlot {
                            key,
                            cell: nt,
                            face: k as u32,
                            stamp,
                        };
                        break;
                    }
                    if slot.key == key {
                        self.cells[nt as usize].n[k] = slot.cell;
                        self.cells[slot.cell as usize].n[slot.face as usize] = nt;
                        break;
                    }
                    h = (h + 1) & mask;
                }
            }
        }
        // A vertex of the zone on no boundary facet has been swallowed.
        for &t in &s.cavity {
            for &u in &self.cells[t as usize].v {
                if u != INFINITE_VERTEX && s.vmark[u as usize] != s.stamp {
                    s.hidden[u as usize] = true;
                }
            }
            self.cells[t as usize].v = [DEAD; 4];
            s.mark[t as usize] = UNTESTED;
        }
        self.free.extend_from_slice(&s.cavity);

        s.boundary[0].new
    }

    /// Remembering stochastic walk to a tetrahedron containing point `v` (closed), or to an
    /// infinite tetrahedron whose hull facet `v` lies strictly beyond.
    fn locate(&mut self, v: u32, hint: u32, s: &mut Scratch) -> u32 {
        let mut t = hint;
        if self.cells[t as usize].v[0] == DEAD {
            t = (0..self.cells.len() as u32)
                .find(|&x| self.cells[x as usize].v[0] != DEAD)
                .unwrap_or(0);
        }
        if let Some(k) = self.cells[t as usize]
            .v
            .iter()
            .position(|&x| x == INFINITE_VERTEX)
        {
            t = self.cells[t as usize].n[k];
        }
        let mut previous = NO_TET;
        let mut steps = 0u64;
        'walk: loop {
            let cell = self.cells[t as usize].v;
            let first = (s.rng.next_u64() >> 62) as usize;
            for j in 0..4 {
                let i = (first + j) & 3;
                let n = self.cells[t as usize].n[i];
                if n == previous {
                    continue;
                }
                let mut ids = cell;
                ids[i] = v;
                steps += 1;
                if self.orient(ids) < 0 {
                    previous = t;
                    t = n;
                    if self.cells[t as usize].v.contains(&INFINITE_VERTEX) {
                        self.stats.walk_steps += steps;
                        return t;
                    }
                    continue 'walk;
                }
            }
            self.stats.walk_steps += steps;
            return t;
        }
    }

    /// Whether point `v` conflicts with tetrahedron `t` (perturbed power test; for an
    /// infinite tetrahedron: beyond its hull facet, or on its plane and inside the facet's
    /// power circle).
    #[inline]
    fn in_conflict(&self, t: u32, v: u32) -> bool {
        let cell = self.cells[t as usize].v;
        let q = self.point(v);
        let wq = self.pw[v as usize].w;
        if let Some(k) = cell.iter().position(|&x| x == INFINITE_VERTEX) {
            let mut ids = cell;
            ids[k] = v;
            let o = self.orient(ids);
            if o != 0 {
                return o > 0;
            }
            // On the hull facet's plane: conflict with the facet's power circle. For a
            // coplanar query that equals conflict with the orthosphere of the finite cell on
            // the facet (both are the lifted plane through the facet's lifted vertices), and
            // the perturbation agrees too (the apex's term is the flat orient(a, b, c, q)).
            let finite = self.cells[t as usize].n[k];
            return self.in_conflict(finite, v);
        }
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
            None => self.exact_power_test(&cell, v, p, w, q, wq),
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
            let mut ids = cell;
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
    fn orient(&self, ids: [u32; 4]) -> i32 {
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
                if self.grid_orient_limit != 0.0 {
                    if let Some(s) = orient3d_grid(pa, pb, pc, pd, self.grid_orient_limit) {
                        return s;
                    }
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

    /// [`power_test`]'s exact stages, through the precomputed grid when there is one.
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
        if self.grid_inverse_unit != 0.0 {
            if let Some(s) = grid_lifted_sign(p, w, q, wq, self.grid_inverse_unit) {
                return s;
            }
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
            if range < 1 << 22 {
                if let Some(s) = lifted_sign_fixed(&ints, *e, w, wq) {
                    return s;
                }
            }
        }
        power_test_exact(p, w, q, wq)
    }

    /// Number of input points (vertices, hidden points and duplicates).
    pub fn num_points(&self) -> usize {
        self.pw.len()
    }

    /// Centre of input point `v`.
    pub fn point_of(&self, v: u32) -> Point {
        *self.point(v)
    }

    /// Weight of input point `v`.
    pub fn weight(&self, v: u32) -> f64 {
        self.pw[v as usize].w
    }

    /// What became of each input point.
    pub fn vertex_status(&self) -> &[VertexStatus] {
        &self.status
    }

    /// Construction counters.
    pub fn stats(&self) -> &TriangulationStats {
        &self.stats
    }

    /// Number of tetrahedron slots, live or freed (handles are `0..num_slots()`).
    pub fn num_slots(&self) -> usize {
        self.cells.len()
    }

    /// Vertex handles of slot `t` ([`INFINITE_VERTEX`] for the hull vertex); a freed slot is
    /// not live (see [`Self::is_live`]).
    #[inline]
    pub fn tet(&self, t: u32) -> [u32; 4] {
        self.cells[t as usize].v
    }

    /// Neighbour handles of slot `t`: entry `i` is across the face opposite vertex `i`.
    #[inline]
    pub fn neighbors(&self, t: u32) -> [u32; 4] {
        self.cells[t as usize].n
    }

    /// Vertex handles of every slot, in slot order (see [`Self::tet`]).
    pub fn tet_slots(&self) -> impl ExactSizeIterator<Item = [u32; 4]> + '_ {
        self.cells.iter().map(|c| c.v)
    }

    /// Whether slot `t` holds a live tetrahedron.
    pub fn is_live(&self, t: u32) -> bool {
        self.cells[t as usize].v[0] != DEAD
    }

    /// Whether slot `t` is live and has no infinite vertex.
    pub fn is_finite(&self, t: u32) -> bool {
        let c = &self.cells[t as usize].v;
        c[0] != DEAD && !c.contains(&INFINITE_VERTEX)
    }

    /// Handles of the live finite tetrahedra, in slot order.
    pub fn finite_tets(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.cells.len() as u32).filter(|&t| self.is_finite(t))
    }

    /// Brute-force validity check, `O(T · n)` (for tests): the structure is sound (see
    /// [`Self::check_local_regularity`]) and no point other than a dropped duplicate is in
    /// conflict with any tetrahedron, finite or infinite: vertices satisfy the empty power
    /// sphere condition, hidden points are truly redundant, and the hull is convex.
    /// Returns the first violation found.
    pub fn check_validity(&self) -> Result<(), String> {
        self.check_structure()?;
        for t in 0..self.cells.len() as u32 {
            if !self.is_live(t) {
                continue;
            }
            for v in 0..self.pw.len() as u32 {
                if self.status[v as usize] == VertexStatus::Duplicate
                    || self.cells[t as usize].v.contains(&v)
                {
                    continue;
                }
                if self.in_conflict(t, v) {
                    return Err(format!(
                        "point {v} ({:?}) conflicts with tet {t}",
                        self.status[v as usize]
                    ));
                }
            }
        }
        Ok(())
    }

    /// Local validity check, `O(T)` (for tests on large inputs): adjacency is symmetric and
    /// neighbours share exactly the opposite face, finite tetrahedra are positively oriented,
    /// the points used by cells are exactly those of status [`VertexStatus::Vertex`], and
    /// across every face the opposite vertex is not in conflict (local regularity, which
    /// implies global regularity). Does not test hidden points.
    pub fn check_local_regularity(&self) -> Result<(), String> {
        self.check_structure()?;
        for t in 0..self.cells.len() as u32 {
            if !self.is_live(t) {
                continue;
            }
            for i in 0..4 {
                let n = self.cells[t as usize].n[i];
                let j = self.cells[n as usize]
                    .n
                    .iter()
                    .position(|&x| x == t)
                    .unwrap_or(0);
                let v = self.cells[n as usize].v[j];
                if v != INFINITE_VERTEX && self.in_conflict(t, v) {
                    return Err(format!(
                        "vertex {v} of tet {n} conflicts with its neighbour {t}"
                    ));
                }
            }
        }
        Ok(())
    }

    fn check_structure(&self) -> Result<(), String> {
        let mut used = vec![false; self.pw.len()];
        for t in 0..self.cells.len() as u32 {
            if !self.is_live(t) {
                continue;
            }
            let cell = self.cells[t as usize].v;
            for i in 0..4 {
                let n = self.cells[t as usize].n[i];
                if n == NO_TET || !self.is_live(n) {
                    return Err(format!("tet {t} has a missing neighbour {i}"));
                }
                let back = self.cells[n as usize].n.iter().filter(|&&x| x == t).count();
                if back != 1 {
                    return Err(format!("tet {t} and {n}: adjacency not symmetric"));
                }
                let j = self.cells[n as usize]
                    .n
                    .iter()
                    .position(|&x| x == t)
                    .unwrap_or(0);
                if face_key(&cell, i) != face_key(&self.cells[n as usize].v, j) {
                    return Err(format!("tet {t} and {n} do not share the face"));
                }
                if self.cells[n as usize].v[j] == cell[i] {
                    return Err(format!("tet {t} and {n} are the same cell"));
                }
            }
            for &v in &cell {
                if v != INFINITE_VERTEX {
                    used[v as usize] = true;
                }
            }
            if self.is_finite(t) {
                let p = cell.map(|v| self.point(v));
                if orient3d(p[0], p[1], p[2], p[3]) <= 0 {
                    return Err(format!("tet {t} is not positively oriented"));
                }
            }
        }
        for (v, &u) in used.iter().enumerate() {
            let is_vertex = self.status[v] == VertexStatus::Vertex;
            if u != is_vertex {
                return Err(format!(
                    "point {v}: status {:?} but used by a cell: {u}",
                    self.status[v]
                ));
            }
        }
        Ok(())
    }
}

/// Marks points with a repeated centre as duplicates (the heaviest stays, then the first),
/// writes every point's lexicographic rank (equal centres share one), and returns the kept
/// points.
fn distinct_points(
    pts: &[Point],
    weights: &[f64],
    status: &mut [VertexStatus],
    rank: &mut [u32],
) -> Vec<u32> {
    let n = pts.len();
    // Order-preserving integer keys (−0 and +0 are one value): an integer sort is much
    // faster than comparing float tuples.
    let key = |x: f64| {
        let b = (x + 0.0).to_bits();
        if b >> 63 == 1 { !b } else { b | (1 << 63) }
    };
    // The pairs are distinct (by index): the parallel sort's order is thread-count independent.
    let mut keyed: Vec<([u64; 3], u32)> = pts
        .par_iter()
        .with_min_len(4096)
        .enumerate()
        .map(|(i, p)| ([key(p[0]), key(p[1]), key(p[2])], i as u32))
        .collect();
    keyed.par_sort_unstable();
    let idx: Vec<u32> = keyed.par_iter().map(|k| k.1).collect();
    drop(keyed);
    let mut kept = Vec::with_capacity(n);
    let mut i = 0;
    while i < n {
        let mut j = i + 1;
        let p = pts[idx[i] as usize];
        while j < n && pts[idx[j] as usize] == p {
            j += 1;
        }
        // Heaviest wins; among equals the lowest index (the group is index-sorted).
        let mut best = idx[i];
        for &k in &idx[i + 1..j] {
            if weights[k as usize] > weights[best as usize] {
                best = k;
            }
        }
        for &k in &idx[i..j] {
            rank[k as usize] = kept.len() as u32;
            if k != best {
                status[k as usize] = VertexStatus::Duplicate;
            }
        }
        kept.push(best);
        i = j;
    }
    kept
}

/// The common dyadic grid of all centres, if their coordinates are integer multiples of one
/// power of two `2^e` below `2^30` of them: `(e, integer coordinates)`.
fn integer_grid(pw: &[WeightedPoint]) -> Option<(i32, Vec<[i32; 3]>)> {
    let mut low = i32::MAX;
    let mut high = i32::MIN;
    for c in pw.iter().flat_map(|x| x.p) {
        let raw = c.to_bits();
        let biased = ((raw >> 52) & 0x7ff) as i32;
        if raw << 1 == 0 {
            continue;
        }
        if biased == 0 || biased == 0x7ff {
            return None;
        }
        let mantissa = (raw & ((1u64 << 52) - 1)) | (1u64 << 52);
        let exponent = biased - 1075;
        low = low.min(exponent + mantissa.trailing_zeros() as i32);
        high = high.max(exponent + 53);
        if high - low > 30 {
            return None;
        }
    }
    if low == i32::MAX {
        low = 0;
    }
    let to_int = |c: f64| -> i32 {
        let raw = c.to_bits();
        if raw << 1 == 0 {
            return 0;
        }
        let mantissa = (raw & ((1u64 << 52) - 1)) | (1u64 << 52);
        let shift = ((raw >> 52) & 0x7ff) as i32 - 1075 - low;
        let m = if shift >= 0 {
            (mantissa << shift) as i64
        } else {
            (mantissa >> -shift) as i64
        };
        (if raw >> 63 == 1 { -m } else { m }) as i32
    };
    Some((low, pw.iter().map(|x| x.p.map(to_int)).collect()))
}

/// The three vertices of face `i` of `cell`, sorted.
fn face_key(cell: &[u32; 4], i: usize) -> [u32; 3] {
    let mut f = [0u32; 3];
    let mut k = 0;
    for (j, &v) in cell.iter().enumerate() {
        if j != i {
            f[k] = v;
            k += 1;
        }
    }
    f.sort_unstable();
    f
}

/// The two positions of `0..4` other than `i` and `k` (`i ≠ k`), by table.
#[inline]
fn other_two(i: usize, k: usize) -> (usize, usize) {
    const OTHER: [[(u8, u8); 4]; 4] = [
        [(0, 0), (2, 3), (1, 3), (1, 2)],
        [(2, 3), (0, 0), (0, 3), (0, 2)],
        [(1, 3), (0, 3), (0, 0), (0, 1)],
        [(1, 2), (0, 2), (0, 1), (0, 0)],
    ];
    let (x, y) = OTHER[i & 3][k & 3];
    (x as usize, y as usize)
}
