//! Incremental 3D regular (weighted Delaunay) triangulation.
//!
//! The method is described on [`RegularTriangulation`].

mod cells;
mod check;
mod conflict;
mod domain;
mod insert;
mod parallel;
mod prepare;

use rayon::prelude::*;

use crate::error::TetraError;
use crate::predicates::{Point, scale_pow2};
use crate::spatial_sort::brio_order;
use prepare::{distinct_points, integer_grid};
use sphcover_core::random::SplitMix64;

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
    /// Inputs of at least this many distinct points insert their large rounds in parallel,
    /// region by region (default 131,072); smaller ones are inserted one point after another.
    /// The tetrahedra are the same either way, the slots they take are not (and whatever
    /// follows slot order, such as the dual complex's order, follows them). The thread count
    /// changes neither.
    pub parallel_from: usize,
    /// Points per region of a parallel round (default 32,768): a round of at least an eighth
    /// of this many points is split into its size over this, rounded down to a power of two,
    /// regions (from 2 to 64).
    pub region_points: usize,
}

impl Default for TriangulationParams {
    fn default() -> Self {
        Self {
            seed: 0x5eed_7e7a,
            parallel_from: 1 << 17,
            region_points: 1 << 15,
        }
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
    /// Points of parallel rounds whose region could not insert them (their walk or conflict
    /// zone crossed a region border), inserted after the round one after another.
    pub deferred: u64,
}

/// A 3D regular triangulation of weighted points (weights are squared radii).
///
/// Design (after geogram's `Delaunay_3d`, BSD-3): points are inserted one at a time in BRIO +
/// Hilbert order (module `spatial_sort`); each is located by a remembering stochastic walk
/// from the previous insertion; the *conflict zone* (tetrahedra whose orthosphere the new
/// weighted point has negative power against) is grown by a depth-first search from the
/// located tetrahedron and replaced by the cone from the new point to its boundary
/// (Bowyer–Watson). The convex hull is closed by tetrahedra through one *infinite vertex*.
///
/// Redundant (hidden) points. A weighted point whose lifted image lies above the lower
/// convex hull of the lifted points has no power cell and is not a vertex:
/// * if the tetrahedron containing the new point is not in conflict with it, the point is
///   redundant when it arrives and is not inserted;
/// * a heavier point can make an existing vertex redundant. Then every tetrahedron around
///   that vertex is in conflict (its lifted image is above the new lower hull), so the vertex
///   lies inside the conflict zone and disappears with it: after building the cone we mark
///   as hidden every vertex of the zone that no new tetrahedron uses. A hidden point stays
///   hidden (inserting points only lowers the lower hull), so no vertex ever reappears.
///
/// Ties (co-spherical, co-planar configurations) are broken by the symbolic perturbation of
/// [`crate::predicates`], which is a genuine perturbation of the lifted coordinates: the
/// result is the regular triangulation of a generic point set infinitesimally close to the
/// input, every tetrahedron has positive volume, and no random perturbation is needed.
/// Points with identical centres are resolved before insertion: the heaviest (then the
/// first) stays, the others are hidden.
///
/// Storage uses `u32` handles: per tetrahedron slot one 32-byte aligned block holding its
/// four vertices and the neighbour opposite each (the walk and the conflict search read both
/// for every cell they visit: one cache line instead of two), and a free list of slots. The
/// input-sized arrays (points, ranks, marks) stay separate. While building, vertices are numbered in
/// insertion order (cells near the new point then touch nearby memory) and mapped back to
/// input indices at the end. The cone over the conflict zone is stitched in two passes: each new
/// cell takes its outside neighbour from the old cell it replaces, and the new cells are
/// paired with each other through a small per-insertion table keyed by their boundary edge
/// (open addressing, stamped instead of cleared; no allocation in the steady state). On inputs whose centres lie on
/// one dyadic grid (voxel grids, octrees), integer coordinates are precomputed so that exact
/// tie-breaking, frequent there, skips the per-call bit analysis, and power tests whose five
/// weights are equal go straight to an exact small-integer evaluation (on the octree
/// benchmark cover, counted at 50K spheres, 30% of the power tests are exact ties, nine in
/// ten of them between equal weights).
///
/// Parallelism: the sorts (duplicate detection, the Hilbert rounds) and the final renumbering
/// run on rayon; sorted keys are distinct pairs, so every order is the same whatever the
/// thread count. On inputs of at least [`TriangulationParams::parallel_from`] points, the
/// insertions of a large round run region by region: the round is split
/// by median planes into boxes, each box inserts its points on its own thread and may change
/// only the cells whose vertices all lie in it; a point whose walk or conflict zone reaches
/// across a border is deferred to a second pass with other planes, and what remains after
/// that is inserted one point after another (module `parallel`). The number of regions
/// depends on the round's size alone, so the output is the same for every thread count; the
/// triangulation is unique, so its tetrahedra are those of the one-by-one construction (on
/// the 1M-sphere octree benchmark cover about 1% of the points are left to the one-by-one
/// insertion).
///
/// Input domain: the predicates are exact only while nothing they compute under- or
/// overflows. The construction works on a copy of the input scaled by a power of two (exact,
/// and no decision changes) into the range where they are, and refuses inputs that no such
/// scaling brings there; the queries answer in the caller's units. `domain` derives the bounds.
///
/// Layout: the types, the constructor and the queries are here; `domain` (the exact range and
/// the scaling into it), `prepare` (duplicates, ranks, the dyadic grid), `insert` (the first
/// cell, the walk, the conflict zone, the cone), `cells` (where an insertion reads and writes
/// cells), `parallel` (the rounds by regions), `conflict` (the exact predicates on vertex
/// handles) and `check` (validity checks for tests) hold the phases.
#[derive(Clone, Debug)]
pub struct RegularTriangulation {
    /// The points as the predicates see them (see [`Geometry`]).
    geometry: Geometry,
    /// The power of two the input was scaled by (see `domain`).
    scale_log2: i32,
    /// Tetrahedron slots: vertices and neighbours together (one cache line per cell).
    cells: Vec<Cell>,
    free: Vec<u32>,
    status: Vec<VertexStatus>,
    stats: TriangulationStats,
}

/// The points and what the exact predicates know of them; only read while building, so the
/// insertions of separate regions share it.
#[derive(Clone, Debug)]
struct Geometry {
    /// `[x, y, z, w]` per point (one cache line holds two), scaled into the exact range:
    /// coordinates times `2^scale_log2`, weights times `2^(2·scale_log2)`. While building,
    /// indexed by insertion rank (neighbouring cells then touch neighbouring memory);
    /// afterwards by input index, like every handle the API returns.
    pw: Vec<WeightedPoint>,
    /// While building, when every centre lies on one dyadic grid (grids, octrees): each
    /// centre as integers in units of `2^e`, so exact tie-breaking skips the bit analysis.
    grid: Option<(i32, Vec<[i32; 3]>)>,
    /// While building on such a grid, `2^-e` (one over the grid unit); otherwise 0.
    grid_inverse_unit: f64,
    /// While building on such a grid with `|e| ≤ 300`, `2^16` grid units, the range of the
    /// exact grid orientation ([`orient3d_grid`](crate::predicates::orient3d_grid));
    /// otherwise 0.
    grid_orient_limit: f64,
    /// While building, the lexicographic rank of each point's centre (ties share a rank;
    /// only distinct centres are inserted), the order of the symbolic perturbation; empty
    /// afterwards (the validity checks recompute it).
    rank: Vec<u32>,
}

impl Geometry {
    /// The centre of point `v`, scaled into the exact range.
    #[inline]
    fn point(&self, v: u32) -> &Point {
        &self.pw[v as usize].p
    }
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

/// Per-cell and per-vertex marks of the insertions. One set serves the whole construction:
/// the insertions of separate regions write disjoint entries of it.
struct Marks {
    /// Per tet: [`UNTESTED`], [`IN_CONFLICT`] or [`OUTSIDE`] for the current insertion; reset
    /// before the next one (one byte keeps the array cache-resident).
    mark: Vec<u8>,
    /// Per vertex: the insertion stamp of the last cavity boundary it was on.
    vmark: Vec<u32>,
    /// Per vertex (insertion numbering): hidden on arrival or swallowed later.
    hidden: Vec<bool>,
}

/// Buffers of one inserting thread, reused across insertions (no allocation in the steady
/// state).
struct Scratch {
    /// The current insertion's stamp (see [`Marks::vmark`] and [`Scratch::edge_table`]).
    stamp: u32,
    stack: Vec<u32>,
    cavity: Vec<u32>,
    boundary: Vec<BoundaryFace>,
    /// Open-addressing table pairing the new cells' faces through the inserted point by
    /// their boundary edge; a power of two long, entries valid for the current stamp only.
    edge_table: Vec<EdgeSlot>,
    rng: SplitMix64,
    /// Orientation steps of the walks.
    walk_steps: u64,
    /// Tetrahedra found in conflict.
    conflict_tets: u64,
}

impl Scratch {
    fn new(seed: u64, stamp: u32) -> Self {
        Scratch {
            stamp,
            stack: Vec::new(),
            cavity: Vec::new(),
            boundary: Vec::new(),
            edge_table: Vec::new(),
            rng: SplitMix64::new(seed),
            walk_steps: 0,
            conflict_tets: 0,
        }
    }
}

/// A face of the conflict zone's boundary: face `face` of the zone's cell `old`, and the new
/// cell built on it from the inserted point (once built).
#[derive(Clone, Copy, Debug)]
struct BoundaryFace {
    old: u32,
    face: u8,
    /// The cell across the face is one the insertion may only read (see `cells::CellRead`).
    read_only: bool,
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
    /// The input is triangulated exactly on a copy scaled by a power of two, so the result
    /// does not change when the coordinates are scaled by `2^k` and the weights by `2^(2k)`.
    /// Inputs that no such scaling brings into the exact range are refused: coordinates
    /// spanning more than about 74 orders of magnitude from the largest magnitude down to the
    /// finest binary digit, or weights too large or too small for the coordinates.
    ///
    /// Errors: mismatched lengths, more than `u32::MAX − 2` points, non-finite values, a span
    /// of magnitudes beyond the exact predicates ([`TetraError::CoordinateSpan`],
    /// [`TetraError::RadiusScale`]), or distinct centres that do not span 3D (fewer than four
    /// affinely independent ones).
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
        check_count(points.len())?;
        let k = domain::scale_for_weights(points, weights)?;
        if k == 0 {
            return Self::from_scaled(points, weights, 0, params);
        }
        // Exact: `domain` keeps every scaled value normal and finite.
        let scaled: Vec<Point> = points.iter().map(|p| p.map(|c| scale_pow2(c, k))).collect();
        let scaled_weights: Vec<f64> = weights.iter().map(|&w| scale_pow2(w, 2 * k)).collect();
        Self::from_scaled(&scaled, &scaled_weights, k, params)
    }

    /// Triangulates the centres `points` with weights `(shrink·r)²` (`radii` finite and
    /// non-negative, `shrink` finite and positive), the weights formed after the scaling into
    /// the exact range, so that radii whose squares would under- or overflow in the caller's
    /// units are still triangulated exactly.
    pub(crate) fn from_spheres(
        points: &[Point],
        radii: &[f64],
        shrink: f64,
        params: &TriangulationParams,
    ) -> Result<Self, TetraError> {
        debug_assert_eq!(points.len(), radii.len());
        check_count(points.len())?;
        let k = domain::scale_for_radii(points, radii, shrink)?;
        // Exact: `domain` keeps every scaled value, and `shrink·r·2^k`, normal and finite.
        let weight = |r: f64| {
            let s = scale_pow2(r, k) * shrink;
            s * s
        };
        let weights: Vec<f64> = radii.iter().map(|&r| weight(r)).collect();
        if k == 0 {
            return Self::from_scaled(points, &weights, 0, params);
        }
        let scaled: Vec<Point> = points.iter().map(|p| p.map(|c| scale_pow2(c, k))).collect();
        Self::from_scaled(&scaled, &weights, k, params)
    }

    /// The construction on an input already scaled by `2^scale_log2` into the exact range.
    fn from_scaled(
        points: &[Point],
        weights: &[f64],
        scale_log2: i32,
        params: &TriangulationParams,
    ) -> Result<Self, TetraError> {
        let n = points.len();
        let mut status = vec![VertexStatus::Vertex; n];
        let mut rank = vec![0u32; n];
        let mut order = distinct_points(points, weights, &mut status, &mut rank);
        let distinct = order.len();
        let rounds = brio_order(points, &mut order, params.seed);
        // While building, vertex `i` is the `i`-th point inserted.
        let pw: Vec<WeightedPoint> = order
            .par_iter()
            .with_min_len(4096)
            .map(|&e| WeightedPoint {
                p: points[e as usize],
                w: weights[e as usize],
            })
            .collect();
        let grid = integer_grid(&pw);
        let grid_inverse_unit = match &grid {
            // 2^-e is a normal f64 for e in -1022..=1022.
            Some((e, _)) if (-1022..=1022).contains(e) => f64::from_bits(((1023 - e) as u64) << 52),
            _ => 0.0,
        };
        let grid_orient_limit = match &grid {
            // 2^(e+16), a normal f64 in this range.
            Some((e, _)) if (-300..=300).contains(e) => {
                f64::from_bits(((1023 + 16 + e) as u64) << 52)
            }
            _ => 0.0,
        };
        let mut tri = RegularTriangulation {
            geometry: Geometry {
                pw,
                grid,
                grid_inverse_unit,
                grid_orient_limit,
                rank: order
                    .par_iter()
                    .with_min_len(4096)
                    .map(|&e| rank[e as usize])
                    .collect(),
            },
            scale_log2,
            // Room for the final cells (about 6.9 per point) and the margin of a round by
            // regions (`parallel`); pages never written cost no memory.
            cells: Vec::with_capacity(15 * distinct / 2 + 16),
            free: Vec::new(),
            status: Vec::new(),
            stats: TriangulationStats {
                points: n,
                ..Default::default()
            },
        };
        drop(rank);
        let first =
            tri.initial_simplex(distinct)
                .map_err(|dimension| TetraError::NotFullDimensional {
                    dimension,
                    distinct,
                })?;
        let mut marks = Marks {
            mark: Vec::with_capacity(7 * distinct + 16),
            vmark: vec![0; distinct],
            hidden: vec![false; distinct],
        };
        let mut scratch = Scratch::new(params.seed ^ 0xa5a5_5a5a_dead_beef, 0);
        let mut hint = 0u32;
        let mut start = 0;
        for end in rounds {
            let round = (start as u32, end as u32);
            if distinct >= params.parallel_from && end - start >= parallel::min_round(params) {
                hint = tri.insert_by_regions(round, first, hint, &mut marks, &mut scratch, params);
            } else {
                for v in (round.0..round.1).filter(|v| !first.contains(v)) {
                    hint = tri.insert(v, hint, &mut marks, &mut scratch);
                }
            }
            start = end;
        }
        tri.stats.walk_steps += scratch.walk_steps;
        tri.stats.conflict_tets += scratch.conflict_tets;
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
        for (i, &h) in marks.hidden.iter().enumerate() {
            if h {
                status[order[i] as usize] = VertexStatus::Hidden;
            }
        }
        tri.geometry = Geometry {
            pw: points
                .par_iter()
                .with_min_len(4096)
                .zip(weights)
                .map(|(&p, &w)| WeightedPoint { p, w })
                .collect(),
            grid: None,
            grid_inverse_unit: 0.0,
            grid_orient_limit: 0.0,
            rank: Vec::new(),
        };
        tri.status = status;
        let count = |k: VertexStatus| tri.status.iter().filter(|s| **s == k).count();
        tri.stats.duplicates = count(VertexStatus::Duplicate);
        tri.stats.hidden = count(VertexStatus::Hidden);
        tri.stats.vertices = n - tri.stats.duplicates - tri.stats.hidden;
        tri.stats.tets = tri.cells.len() - tri.free.len();
        tri.stats.finite_tets = tri
            .cells
            .par_iter()
            .with_min_len(4096)
            .filter(|c| c.v[0] != DEAD && !c.v.contains(&INFINITE_VERTEX))
            .count();
        Ok(tri)
    }

    /// The centre of point `v` as the predicates see it: scaled into the exact range.
    #[inline]
    pub(crate) fn point(&self, v: u32) -> &Point {
        self.geometry.point(v)
    }

    /// The weight of point `v` as the predicates see it: scaled into the exact range.
    #[inline]
    pub(crate) fn scaled_weight(&self, v: u32) -> f64 {
        self.geometry.pw[v as usize].w
    }

    /// Number of input points (vertices, hidden points and duplicates).
    pub fn num_points(&self) -> usize {
        self.geometry.pw.len()
    }

    /// Centre of input point `v`, in the caller's units (exactly as given).
    pub fn point_of(&self, v: u32) -> Point {
        // Exact: undoes an exact scaling.
        self.point(v).map(|c| scale_pow2(c, -self.scale_log2))
    }

    /// Weight of input point `v`, in the caller's units: as given to [`Self::new`]; for a
    /// triangulation built by [`crate::dual_complex()`], `(σ_t·r)²` rounded to `f64` in those
    /// units (zero or subnormal when it is that small there; the construction used it exactly).
    pub fn weight(&self, v: u32) -> f64 {
        scale_pow2(self.scaled_weight(v), -2 * self.scale_log2)
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
    pub fn neighbours(&self, t: u32) -> [u32; 4] {
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
}

/// More points than `u32` handles (minus the two markers) can address, as the typed error.
fn check_count(n: usize) -> Result<(), TetraError> {
    if n >= (u32::MAX - 2) as usize {
        return Err(TetraError::TooManyPoints { count: n });
    }
    Ok(())
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
