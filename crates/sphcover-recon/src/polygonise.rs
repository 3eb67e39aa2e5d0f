//! Polygonisation of the zero set of a cover's function by surface nets visited only near the
//! surface (thesis §5.2.3, Appendix C).
//!
//! The grid is uniform with step `h`; `f` is sampled at grid vertices. A cell is *active* when
//! `f` is defined at its 8 corners (some support covers each of them) and the corners do not
//! all lie on one side (inside is `f > 0`, the sign convention of the cover). Surface nets put
//! one vertex per surface sheet in every active cell and, for every grid edge whose ends lie
//! on opposite sides, one quad joining the vertices of the four cells around that edge.
//!
//! # Continuation from seeds
//!
//! Only active cells are ever visited: from the cells holding the seed points (samples the
//! caller trusts) and, for seeds not next to the surface (noise), from where Newton steps
//! pull them onto `f = 0`, a breadth-first search crosses
//! from an active cell to the three other cells around each of its crossing edges. So the
//! cost follows the area of the surface, not the volume of the box, and a spurious sheet far
//! from every seed is never meshed. Each round of the search evaluates the new grid vertices
//! of its frontier in one parallel batch ([`PuEvaluator::values`]).
//!
//! # A 2-manifold
//!
//! Plain surface nets give one vertex per cell, which pinches two sheets passing through one
//! cell into a non-manifold vertex. Here the crossing edges of a cell are grouped into the
//! closed polygons marching cubes would build in that cell (on each face the crossings are
//! paired; a face with four crossings is resolved by the asymptotic decider, the sign of the
//! bilinear interpolant at its saddle, which both cells sharing the face compute from the
//! same four values, so they agree), and each polygon gets its own vertex, as in manifold
//! dual contouring. The star of such a vertex is the ring of quads around the polygon's
//! edges, a disc. Where the meshed region ends (undefined `f`, trimming) a vertex can keep
//! two separate fans; it is then split into one vertex per fan. One saddle configuration
//! needs more: when the polygons of both cells sharing a face each use both segments of that
//! face, the surface runs through the face as a tube, and the edge between the two cells'
//! vertices would carry four quads. Such a *tube face* gets one vertex per segment (the mean
//! of its two crossings), inserted between the two cells' vertices in the quads of that
//! segment's edges, so each of those edges is shared by two polygons. It is rare (no real
//! scan measured has one) and leaves every other quad as it was.
//!
//! # Orientation and placement
//!
//! Triangles are wound counter-clockwise seen from outside (from `f < 0`). A vertex sits at
//! the mean of its polygon's edge crossings (linear interpolation of `f` along each edge),
//! optionally moved by one Newton step `x − f ∇f / ‖∇f‖²` onto `f = 0`, kept inside its cell.
//!
//! # Determinism
//!
//! The set of active cells is the union of the surface components reached from the seeds in
//! their given order; values are pure functions of grid positions; the mesh is written in
//! ascending cell order. So the output is bit-identical whatever the thread count.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{Aabb, PointIndex, PointIndexError, PuEvaluator, TriMesh, ValueGradient};

use crate::unused_vertices::remove_unused_vertices;

/// How the grid step is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GridStep {
    /// `step = longest edge of the seeds' bounding box / 2^depth` (as an octree depth of
    /// Poisson reconstruction tools).
    Depth(u32),
    /// This step, in the units of the cover.
    Absolute(f64),
    /// This factor times the smallest support radius of the cover.
    SmallestRadius(f64),
}

/// Parameters of [`polygonise`].
#[derive(Clone, Debug, PartialEq)]
pub struct PolygoniseParams {
    /// Grid step.
    pub step: GridStep,
    /// Move every vertex by one Newton step onto `f = 0` (staying in its cell).
    pub project: bool,
    /// Drop triangles whose centroid is farther than this from every seed, in the units of
    /// the cover (surface invented where there were no samples).
    pub trim: Option<f64>,
    /// Attach per-vertex outward unit normals `−∇f / ‖∇f‖`.
    pub normals: bool,
    /// A seed whose Newton steps towards `f = 0` move it farther than this many grid steps,
    /// or end more than one step from `f = 0`, starts no search: it is off the surface.
    pub seed_reach: f64,
    /// Most grid cells the search may visit; a bound on time and memory for a step far too
    /// fine for the object.
    pub max_cells: usize,
}

impl Default for PolygoniseParams {
    fn default() -> PolygoniseParams {
        PolygoniseParams {
            step: GridStep::Depth(9),
            project: true,
            trim: None,
            normals: true,
            seed_reach: 4.0,
            max_cells: 1 << 25,
        }
    }
}

/// Why the zero set could not be polygonised.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PolygoniseError {
    /// No seed point was given, or none is finite.
    #[error("no seed point: {given} given, none finite; polygonisation starts from samples")]
    NoSeeds {
        /// Number of seeds given.
        given: usize,
    },
    /// A parameter is out of its range.
    #[error("parameter {name} = {value} is invalid: {requirement}")]
    InvalidParameter {
        /// Field name in [`PolygoniseParams`].
        name: &'static str,
        /// The value given.
        value: f64,
        /// What the value must satisfy.
        requirement: &'static str,
    },
    /// The grid step is so small that the box where `f` is defined needs more than
    /// 2²¹ − 2 cells along an axis.
    #[error(
        "grid step {step} is too fine for the cover's extent {extent}: more than 2^21 cells along an axis"
    )]
    GridTooFine {
        /// The step.
        step: f64,
        /// Longest edge of the box where `f` is defined.
        extent: f64,
    },
    /// The cover has no support.
    #[error("the cover has no support, so f is defined nowhere")]
    EmptyCover,
    /// The search visited more cells than [`PolygoniseParams::max_cells`].
    #[error("more than {max_cells} grid cells near the surface at step {step}: use a coarser step")]
    TooManyCells {
        /// The limit.
        max_cells: usize,
        /// The step.
        step: f64,
    },
    /// No seed lies near a sign change of `f` where `f` is defined.
    #[error("no surface (sign change of f) within reach of any of the {seeds} seeds")]
    NoSurfaceNearSeeds {
        /// Finite seeds given.
        seeds: usize,
    },
    /// The seeds could not be indexed for trimming.
    #[error(transparent)]
    TooManySeeds(#[from] PointIndexError),
    /// The values to blend at the vertices are not one per support.
    #[error("{found} values to blend at the vertices for a cover of {expected} supports")]
    BlendLengthMismatch {
        /// Supports in the cover.
        expected: usize,
        /// Values given.
        found: usize,
    },
}

/// What [`polygonise`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PolygoniseStats {
    /// The grid step used.
    pub step: f64,
    /// Seeds pulled onto `f = 0` because they were not next to a cell the surface crosses
    /// (one per brick of 4×4×4 cells).
    pub seeds_projected: usize,
    /// Projected seeds that started a search of their own (their surface was not met yet).
    pub seeds_searched: usize,
    /// Seeds dropped: not finite, `f` undefined there, or off the surface by more than the
    /// seed reach.
    pub seeds_dropped: usize,
    /// Grid cells visited.
    pub cells_visited: usize,
    /// Cells with a surface vertex.
    pub active_cells: usize,
    /// Active cells holding more than one sheet (one vertex each).
    pub multi_sheet_cells: usize,
    /// Evaluations of `f` at grid vertices.
    pub grid_evaluations: usize,
    /// Crossing edges left without a quad because a cell around them is not meshed (`f`
    /// undefined at one of its corners): a boundary of the mesh.
    pub open_quads: usize,
    /// Triangles removed by trimming.
    pub trimmed_triangles: usize,
    /// Faces where both cells' polygons use both crossing segments (a tube through the
    /// face): each segment got a vertex of its own on the face.
    pub tube_faces: usize,
    /// Vertices split because their triangles formed several fans.
    pub split_vertices: usize,
    /// Time spent evaluating `f` at grid vertices (part of the search).
    pub evaluation_time: Duration,
    /// Time of the search over cells, from the seeds.
    pub search_time: Duration,
    /// Time of placing vertices (with their Newton step) and building triangles.
    pub extraction_time: Duration,
    /// Total time.
    pub total_time: Duration,
}

/// Polygonises the zero set of `eval`'s function near `seeds` (see the module notes).
///
/// Returns a mesh in the cover's units, wound counter-clockwise seen from outside, closed
/// wherever the surface is closed and `f` defined around it.
///
/// Seeds should be samples the caller trusts (high confidence, not outliers): every surface
/// component that passes through a seed's cell, or that a seed's Newton steps reach within
/// [`PolygoniseParams::seed_reach`], is meshed, including a small piece of `f = 0` around
/// an outlier that was given as a seed. [`sphcover_core::remove_small_components`] removes such
/// pieces afterwards if needed.
pub fn polygonise(
    eval: &PuEvaluator<'_>,
    seeds: &[DVec3],
    params: &PolygoniseParams,
) -> Result<(TriMesh, PolygoniseStats), PolygoniseError> {
    polygonise_blending(eval, seeds, params, None)
}

/// [`polygonise`], and with `blend` (one value per support) also the partition-of-unity
/// blend `Σ w_i v_i / Σ w_i` of those values at every vertex as the mesh's
/// [`TriMesh::values`] (0 where no weight is positive).
///
/// The blend is taken where each vertex was placed on its cell's edges, before the Newton
/// step of [`PolygoniseParams::project`] (less than a cell away): there it shares the
/// gathering of the supports with `f` and `∇f`, which costs as much as the blend itself. The
/// mesh geometry is the same as without `blend`.
pub fn polygonise_blending(
    eval: &PuEvaluator<'_>,
    seeds: &[DVec3],
    params: &PolygoniseParams,
    blend: Option<&[f64]>,
) -> Result<(TriMesh, PolygoniseStats), PolygoniseError> {
    let start = Instant::now();
    check_params(params)?;
    if let Some(values) = blend
        && values.len() != eval.cover().len()
    {
        return Err(PolygoniseError::BlendLengthMismatch {
            expected: eval.cover().len(),
            found: values.len(),
        });
    }
    let finite_seeds: Vec<DVec3> = seeds.iter().copied().filter(|p| p.is_finite()).collect();
    if finite_seeds.is_empty() {
        return Err(PolygoniseError::NoSeeds { given: seeds.len() });
    }
    let cover = eval.cover();
    if cover.is_empty() {
        return Err(PolygoniseError::EmptyCover);
    }
    let step = grid_step(params.step, &finite_seeds, cover.radii())?;
    let grid = Grid::around(eval, step)?;

    let mut stats = PolygoniseStats {
        step,
        seeds_dropped: seeds.len() - finite_seeds.len(),
        ..PolygoniseStats::default()
    };
    let mut search = Search::new(eval, &grid, params.max_cells);
    let reach = params.seed_reach * step;
    // Clean samples lie in or next to a cell the surface crosses: searching from all their
    // cells at once evaluates `f` in a few large batches, instead of one thin wavefront
    // crawling over the whole surface. Seeds left away from the meshed cells (noise) are
    // pulled onto the surface below.
    let mut seed_cells: Vec<u64> = finite_seeds
        .par_iter()
        .map(|&p| pack_clamped(grid.cell_of(p)))
        .collect();
    seed_cells.par_sort_unstable();
    seed_cells.dedup();
    search.run(seed_cells.into_iter().filter_map(unpack_clamped).collect())?;
    // Noisy seeds that met no surface: one per brick of 4×4×4 cells is pulled onto `f = 0`
    // (more would find the same surface again), all in one batch.
    let away: Vec<bool> = finite_seeds
        .par_iter()
        .map_init(
            || search.reader(),
            |reader, &p| !search.near_active(reader, grid.cell_of(p)),
        )
        .collect();
    let mut bricks_seen = KeyMap::<()>::default();
    let unmet: Vec<DVec3> = finite_seeds
        .iter()
        .zip(away)
        .filter(|&(&p, away)| {
            away && bricks_seen
                .insert(brick_of(grid.cell_of(p)).0, ())
                .is_none()
        })
        .map(|(&p, _)| p)
        .collect();
    stats.seeds_projected = unmet.len();
    for (p, seed) in project_seeds(eval, &unmet).into_iter().zip(&unmet) {
        match p {
            Some((q, residual)) if residual <= step && q.distance(*seed) <= reach => {
                let cell = grid.cell_of(q);
                // The search from an earlier seed may have reached it already, or started
                // from the same place and found nothing.
                if !search.near_active(&mut search.reader(), cell) && !search.visited(cell) {
                    stats.seeds_searched += 1;
                    search.run(grid.block_around(cell).collect())?;
                }
            }
            _ => stats.seeds_dropped += 1,
        }
    }
    if search.cells.is_empty() {
        return Err(PolygoniseError::NoSurfaceNearSeeds {
            seeds: finite_seeds.len(),
        });
    }
    stats.cells_visited = search.visited_cells;
    stats.grid_evaluations = search.evaluations;
    stats.evaluation_time = search.evaluation_time;
    stats.search_time = start.elapsed();

    let extraction_start = Instant::now();
    let mut mesh = extract(&search, &grid, params, blend, &mut stats);
    stats.extraction_time = extraction_start.elapsed();
    if let Some(limit) = params.trim {
        stats.trimmed_triangles = trim(&mut mesh, &finite_seeds, limit)?;
    }
    stats.split_vertices = split_fans(&mut mesh);
    stats.total_time = start.elapsed();
    Ok((mesh, stats))
}

/// Cells along an axis stay below this so that three indices pack into a `u64`.
const GRID_LIMIT: i64 = 1 << 21;

/// Newton steps that pull a seed onto `f = 0`.
const SEED_NEWTON_STEPS: usize = 2;

fn check_params(params: &PolygoniseParams) -> Result<(), PolygoniseError> {
    let invalid = |name, value, requirement| {
        Err(PolygoniseError::InvalidParameter {
            name,
            value,
            requirement,
        })
    };
    match params.step {
        GridStep::Depth(d) if d > 20 => return invalid("step", f64::from(d), "depth ≤ 20"),
        GridStep::Absolute(s) | GridStep::SmallestRadius(s) if !(s.is_finite() && s > 0.0) => {
            return invalid("step", s, "finite and > 0");
        }
        _ => {}
    }
    if let Some(t) = params.trim
        && (t.is_nan() || t <= 0.0)
    {
        return invalid("trim", t, "> 0 (or None)");
    }
    if !(params.seed_reach.is_finite() && params.seed_reach >= 0.0) {
        return invalid("seed_reach", params.seed_reach, "finite and ≥ 0");
    }
    Ok(())
}

fn grid_step(step: GridStep, seeds: &[DVec3], radii: &[f64]) -> Result<f64, PolygoniseError> {
    let h = match step {
        GridStep::Depth(d) => Aabb::from_points(seeds).longest_edge() / f64::from(1u32 << d),
        GridStep::Absolute(s) => s,
        GridStep::SmallestRadius(k) => k * radii.iter().copied().fold(f64::INFINITY, f64::min),
    };
    if h.is_finite() && h > 0.0 {
        Ok(h)
    } else {
        // A single seed (or coincident seeds) has a bounding box without extent.
        Err(PolygoniseError::InvalidParameter {
            name: "step",
            value: h,
            requirement: "a positive step: give an absolute step when the seeds span no box",
        })
    }
}

/// Pulls each seed onto `f = 0` with Newton steps; `(projected point, |f| / ‖∇f‖ there)`, or
/// `None` where `f` is undefined or flat.
fn project_seeds(eval: &PuEvaluator<'_>, seeds: &[DVec3]) -> Vec<Option<(DVec3, f64)>> {
    let mut points: Vec<Option<(DVec3, f64)>> =
        seeds.iter().map(|&p| Some((p, f64::INFINITY))).collect();
    // The last round only measures the distance at the final point.
    for round in 0..=SEED_NEWTON_STEPS {
        let live: Vec<DVec3> = points.iter().flatten().map(|&(p, _)| p).collect();
        let mut results = eval.values_gradients(&live).into_iter();
        for slot in points.iter_mut().filter(|s| s.is_some()) {
            let Some((x, _)) = *slot else { continue };
            *slot = results.next().flatten().and_then(|vg| {
                let g2 = vg.gradient.length_squared();
                if !(g2 > 0.0 && g2.is_finite()) {
                    return None;
                }
                let distance = vg.value.abs() / g2.sqrt();
                let next = if round < SEED_NEWTON_STEPS {
                    x - vg.gradient * (vg.value / g2)
                } else {
                    x
                };
                next.is_finite().then_some((next, distance))
            });
        }
    }
    points
}

/// The uniform grid: vertex `(i, j, k)` is at `origin + step (i, j, k)`; cell `(i, j, k)` has
/// that vertex as its lowest corner.
#[derive(Debug)]
struct Grid {
    origin: DVec3,
    step: f64,
    /// Grid vertices along each axis; indices outside `0..dims` are outside every support.
    dims: [i64; 3],
}

type Index3 = [i64; 3];

impl Grid {
    /// The grid of step `step` over the box where `eval`'s function can be defined (the
    /// expanded balls), with one spare cell on every side.
    fn around(eval: &PuEvaluator<'_>, step: f64) -> Result<Grid, PolygoniseError> {
        let cover = eval.cover();
        let mut defined = Aabb::EMPTY;
        for (&c, &r) in cover.centers().iter().zip(cover.radii()) {
            let r = r * eval.sigma();
            defined.add(c - DVec3::splat(r));
            defined.add(c + DVec3::splat(r));
        }
        let extent = defined.longest_edge();
        let cells_per_axis = (extent / step).ceil() + 3.0;
        if cells_per_axis.is_nan() || cells_per_axis >= GRID_LIMIT as f64 {
            return Err(PolygoniseError::GridTooFine { step, extent });
        }
        Ok(Grid {
            origin: defined.min - DVec3::splat(step),
            step,
            dims: (defined.extent() / step)
                .ceil()
                .as_ivec3()
                .to_array()
                .map(|d| d as i64 + 3),
        })
    }

    fn position(&self, v: Index3) -> DVec3 {
        self.origin + DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) * self.step
    }

    fn cell_of(&self, p: DVec3) -> Index3 {
        let q = ((p - self.origin) / self.step).floor();
        [q.x, q.y, q.z].map(|c| c.clamp(-1.0, GRID_LIMIT as f64) as i64)
    }

    fn in_range(&self, v: Index3) -> bool {
        (0..3).all(|a| v[a] >= 0 && v[a] < self.dims[a])
    }

    /// The cell and its 26 neighbours.
    fn block_around(&self, c: Index3) -> impl Iterator<Item = Index3> + '_ {
        (0..27).map(move |n| [c[0] + n % 3 - 1, c[1] + (n / 3) % 3 - 1, c[2] + n / 9 - 1])
    }
}

/// A cell index packed when in range, else a key no cell has.
fn pack_clamped(v: Index3) -> u64 {
    if v.iter().all(|&c| (0..GRID_LIMIT).contains(&c)) {
        pack(v)
    } else {
        u64::MAX
    }
}

fn unpack_clamped(key: u64) -> Option<Index3> {
    (key != u64::MAX).then(|| unpack(key))
}

fn pack(v: Index3) -> u64 {
    (v[0] as u64) | ((v[1] as u64) << 21) | ((v[2] as u64) << 42)
}

fn unpack(key: u64) -> Index3 {
    let mask = (1u64 << 21) - 1;
    [key & mask, (key >> 21) & mask, key >> 42].map(|c| c as i64)
}

/// A multiplicative hash of packed grid keys: std's SipHash costs more than the work per
/// key here.
#[derive(Default)]
struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        }
    }
    fn write_u64(&mut self, key: u64) {
        let x = (key ^ (key >> 29)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        self.0 = x ^ (x >> 32);
    }
}

type KeyMap<V> = HashMap<u64, V, BuildHasherDefault<KeyHasher>>;

/// Corner `c` of a cube (bit 0: +x, bit 1: +y, bit 2: +z).
fn corner_offset(c: usize) -> Index3 {
    [(c & 1) as i64, ((c >> 1) & 1) as i64, ((c >> 2) & 1) as i64]
}

/// Cube edge `4d + bu + 2bw` runs along axis `d` from the corner with bit `bu` on axis
/// `(d + 1) % 3` and bit `bw` on axis `(d + 2) % 3` (zero on `d`).
const fn edge_ends(e: usize) -> (usize, usize) {
    let d = e / 4;
    let (u, w) = ((d + 1) % 3, (d + 2) % 3);
    let a = ((e & 1) << u) | (((e >> 1) & 1) << w);
    (a, a | (1 << d))
}

const fn edge_between(a: usize, b: usize) -> usize {
    let d = (a ^ b).trailing_zeros() as usize;
    let lo = if a < b { a } else { b };
    let (u, w) = ((d + 1) % 3, (d + 2) % 3);
    4 * d + ((lo >> u) & 1) + 2 * ((lo >> w) & 1)
}

/// The corners of face `2a + s` (normal axis `a`, side `s`) in cyclic order, with the bits of
/// axes `(a + 1) % 3`, `(a + 2) % 3` going (0,0), (1,0), (1,1), (0,1). Both cells sharing a
/// face list its grid vertices in the same order.
const FACE_CORNERS: [[usize; 4]; 6] = {
    let mut t = [[0; 4]; 6];
    let mut f = 0;
    while f < 6 {
        let (a, s) = (f / 2, f % 2);
        let (u, w) = ((a + 1) % 3, (a + 2) % 3);
        let base = s << a;
        t[f] = [
            base,
            base | (1 << u),
            base | (1 << u) | (1 << w),
            base | (1 << w),
        ];
        f += 1;
    }
    t
};

/// Edge `k` of face `f` joins its corners `k` and `k + 1`.
const FACE_EDGES: [[usize; 4]; 6] = {
    let mut t = [[0; 4]; 6];
    let mut f = 0;
    while f < 6 {
        let mut k = 0;
        while k < 4 {
            t[f][k] = edge_between(FACE_CORNERS[f][k], FACE_CORNERS[f][(k + 1) % 4]);
            k += 1;
        }
        f += 1;
    }
    t
};

/// No sheet crosses this cube edge.
const NO_SHEET: u8 = u8::MAX;

fn inside(v: f64) -> bool {
    v > 0.0
}

/// Asymptotic decider on a face with four crossings and corner values `q` (in the order of
/// [`FACE_CORNERS`]): whether corners 0 and 2 are joined through the face, i.e. the sign of
/// the bilinear interpolant at its saddle is theirs. Its segments then cut off corners 1 and
/// 3. The denominator cannot vanish: the corner pairs lie strictly on opposite sides of 0.
fn joins_corners_0_and_2(q: [f64; 4]) -> bool {
    let saddle = (q[0] * q[2] - q[1] * q[3]) / (q[0] + q[2] - q[1] - q[3]);
    inside(saddle) == inside(q[0])
}

/// The segment (0 or 1) of face edge `k` on a face with four crossings: segments join face
/// edges 0–1 and 2–3 when corners 0 and 2 are joined, 3–0 and 1–2 otherwise.
fn face_segment(joins_0_and_2: bool, k: usize) -> usize {
    if joins_0_and_2 {
        k / 2
    } else {
        ((k + 1) % 4) / 2
    }
}

/// Groups the crossing edges of a cell with corner values `f` into the closed polygons of
/// marching cubes (see the module notes): the sheet of each cube edge (or [`NO_SHEET`]) and
/// the number of sheets.
fn cell_sheets(f: &[f64; 8]) -> ([u8; 12], u8) {
    const NONE: u8 = u8::MAX;
    let mut partners = [[NONE; 2]; 12];
    let mut link = |a: usize, b: usize| {
        for (x, y) in [(a, b), (b, a)] {
            let slot = if partners[x][0] == NONE { 0 } else { 1 };
            partners[x][slot] = y as u8;
        }
    };
    for face in 0..6 {
        let q = FACE_CORNERS[face].map(|c| f[c]);
        let crosses: [bool; 4] = std::array::from_fn(|k| inside(q[k]) != inside(q[(k + 1) % 4]));
        let edges = FACE_EDGES[face];
        match crosses.iter().filter(|&&c| c).count() {
            2 => {
                let mut it = (0..4).filter(|&k| crosses[k]);
                let (a, b) = (it.next().unwrap_or(0), it.next().unwrap_or(0));
                link(edges[a], edges[b]);
            }
            4 => {
                if joins_corners_0_and_2(q) {
                    // Cut off corners 1 and 3.
                    link(edges[0], edges[1]);
                    link(edges[2], edges[3]);
                } else {
                    // Cut off corners 0 and 2.
                    link(edges[3], edges[0]);
                    link(edges[1], edges[2]);
                }
            }
            _ => {}
        }
    }
    let mut sheet = [NO_SHEET; 12];
    let mut sheets = 0u8;
    for e in 0..12 {
        if partners[e][0] == NONE || sheet[e] != NO_SHEET {
            continue;
        }
        let (mut prev, mut cur) = (usize::MAX, e);
        while sheet[cur] == NO_SHEET {
            sheet[cur] = sheets;
            let [p, q] = partners[cur].map(usize::from);
            let next = if p != prev { p } else { q };
            prev = cur;
            cur = next;
            if cur >= 12 {
                break;
            }
        }
        sheets += 1;
    }
    (sheet, sheets)
}

/// An active cell: which corners are inside and the sheet of each crossing cube edge. (The
/// corner values stay in the bricks: a copy here would double the search's memory.)
#[derive(Clone, Copy, Debug)]
struct ActiveCell {
    /// Bit `k` is set when corner `k` is inside.
    inside: u8,
    sheet: [u8; 12],
    sheets: u8,
}

/// Side of a brick in grid vertices (and cells).
const BRICK_SHIFT: u32 = 2;
const BRICK_MASK: i64 = (1 << BRICK_SHIFT) - 1;
const BRICK_LEN: usize = 1 << (3 * BRICK_SHIFT);

/// The state of a 4×4×4 block of grid vertices, and of the cells whose lowest corner they
/// are. Storing the grid sparsely by bricks keeps one hash lookup per brick rather than per
/// vertex, and neighbouring vertices mostly share a brick.
#[derive(Clone, Debug)]
struct Brick {
    /// `f` at each vertex (NaN where undefined), once its bit in `evaluated` is set.
    values: [f64; BRICK_LEN],
    evaluated: u64,
    /// Cells queued or examined by the search.
    visited: u64,
    /// Slot in [`Search::cells`] of each active cell, or `u32::MAX`.
    active: [u32; BRICK_LEN],
}

impl Brick {
    const EMPTY: Brick = Brick {
        values: [f64::NAN; BRICK_LEN],
        evaluated: 0,
        visited: 0,
        active: [u32::MAX; BRICK_LEN],
    };
}

/// The brick key of a grid index and its position in the brick.
fn brick_of(v: Index3) -> (u64, usize) {
    let key = pack(v.map(|c| c >> BRICK_SHIFT));
    let local = (v[0] & BRICK_MASK)
        | ((v[1] & BRICK_MASK) << BRICK_SHIFT)
        | ((v[2] & BRICK_MASK) << (2 * BRICK_SHIFT));
    (key, local as usize)
}

/// The parities of the brick coordinates of grid index `v`. The bricks holding one cell's
/// corners, or the cells around one of its edges, all differ in class, so a cache with one
/// entry per class holds all of them at once (one remembering only the last brick went back
/// to the hash map at every step across a brick boundary).
fn brick_class(v: Index3) -> usize {
    let bit = |a: usize| ((v[a] >> BRICK_SHIFT) & 1) as usize;
    bit(0) | bit(1) << 1 | bit(2) << 2
}

/// The last brick key met in each [`brick_class`] and what it maps to. No brick key is
/// `u64::MAX` (the keys of in-range indices use 63 bits).
type BrickCache<T> = [(u64, T); 8];

/// Read access to bricks that remembers the last brick found in each class, since queries
/// come in neighbourhoods.
struct BrickReader<'s> {
    index: &'s KeyMap<u32>,
    bricks: &'s [Brick],
    cache: BrickCache<Option<&'s Brick>>,
}

impl<'s> BrickReader<'s> {
    fn get(&mut self, v: Index3) -> Option<(&'s Brick, usize)> {
        let (key, local) = brick_of(v);
        let entry = &mut self.cache[brick_class(v)];
        if entry.0 != key {
            *entry = (key, self.index.get(&key).map(|&i| &self.bricks[i as usize]));
        }
        entry.1.map(|b| (b, local))
    }

    fn value(&mut self, v: Index3) -> Option<f64> {
        self.get(v)
            .and_then(|(b, l)| (b.evaluated >> l & 1 == 1).then_some(b.values[l]))
    }

    fn active_slot(&mut self, c: Index3) -> Option<u32> {
        self.get(c)
            .map(|(b, l)| b.active[l])
            .filter(|&s| s != u32::MAX)
    }
}

/// The breadth-first search over active cells.
struct Search<'e, 'c> {
    eval: &'e PuEvaluator<'c>,
    grid: &'e Grid,
    max_cells: usize,
    /// Slot in `bricks` of each brick key.
    brick_index: KeyMap<u32>,
    bricks: Vec<Brick>,
    /// Active cells with their keys, in the order found.
    cells: Vec<(u64, ActiveCell)>,
    visited_cells: usize,
    evaluations: usize,
    evaluation_time: Duration,
}

impl<'e, 'c> Search<'e, 'c> {
    fn new(eval: &'e PuEvaluator<'c>, grid: &'e Grid, max_cells: usize) -> Self {
        Search {
            eval,
            grid,
            max_cells,
            brick_index: KeyMap::default(),
            bricks: Vec::new(),
            cells: Vec::new(),
            visited_cells: 0,
            evaluations: 0,
            evaluation_time: Duration::ZERO,
        }
    }

    fn reader(&self) -> BrickReader<'_> {
        BrickReader {
            index: &self.brick_index,
            bricks: &self.bricks,
            cache: [(u64::MAX, None); 8],
        }
    }

    /// The brick holding `v` (created if needed) and `v`'s position in it; `cache` holds the
    /// slots of the last brick keys met.
    fn brick_mut(&mut self, v: Index3, cache: &mut BrickCache<u32>) -> (&mut Brick, usize) {
        let (key, local) = brick_of(v);
        let entry = &mut cache[brick_class(v)];
        if entry.0 != key {
            let next = self.bricks.len() as u32;
            let slot = *self.brick_index.entry(key).or_insert(next);
            if slot == next {
                self.bricks.push(Brick::EMPTY);
            }
            *entry = (key, slot);
        }
        (&mut self.bricks[entry.1 as usize], local)
    }

    /// Marks cell `c` visited; true when it was not before.
    fn visit(&mut self, c: Index3, cache: &mut BrickCache<u32>) -> bool {
        let (brick, l) = self.brick_mut(c, cache);
        let fresh = brick.visited >> l & 1 == 0;
        brick.visited |= 1 << l;
        self.visited_cells += usize::from(fresh);
        fresh
    }

    /// Whether the search has queued or examined cell `c`.
    fn visited(&self, c: Index3) -> bool {
        self.grid.in_range(c)
            && self
                .reader()
                .get(c)
                .is_some_and(|(b, l)| b.visited >> l & 1 == 1)
    }

    /// Whether the cell or one of its 26 neighbours is active.
    fn near_active(&self, reader: &mut BrickReader<'_>, c: Index3) -> bool {
        let mut active = |n: Index3| self.grid.in_range(n) && reader.active_slot(n).is_some();
        // A seed's own cell is nearly always active: ask it first.
        active(c) || self.grid.block_around(c).any(active)
    }

    /// A cell needs its far corner in range too.
    fn cell_in_range(&self, c: Index3) -> bool {
        self.grid.in_range(c) && self.grid.in_range(c.map(|x| x + 1))
    }

    /// Visits the cells `starts` not yet visited and everything reachable from them.
    fn run(&mut self, starts: Vec<Index3>) -> Result<(), PolygoniseError> {
        let mut cache = [(u64::MAX, 0); 8];
        let mut frontier: Vec<Index3> = Vec::new();
        for c in starts {
            if self.cell_in_range(c) && self.visit(c, &mut cache) {
                frontier.push(c);
            }
        }
        while !frontier.is_empty() {
            if self.visited_cells > self.max_cells {
                return Err(PolygoniseError::TooManyCells {
                    max_cells: self.max_cells,
                    step: self.grid.step,
                });
            }
            self.evaluate_corners(&frontier);
            // Classified in parallel, each run with the neighbours its active cells reach
            // that were not visited before this wave: the sequential pass below would
            // reject the others, so it only walks these, in the same order.
            let classified: Vec<(Vec<Option<ActiveCell>>, Vec<Index3>)> = frontier
                .par_chunks(256)
                .map(|chunk| {
                    let mut reader = self.reader();
                    let cells: Vec<Option<ActiveCell>> =
                        chunk.iter().map(|&c| classify(&mut reader, c)).collect();
                    let mut reached = Vec::new();
                    for (&c, cell) in chunk.iter().zip(&cells) {
                        let Some(cell) = cell else { continue };
                        for e in (0..12).filter(|&e| cell.sheet[e] != NO_SHEET) {
                            reached.extend(cells_around_edge(c, e).into_iter().filter(|&n| {
                                n != c
                                    && self.cell_in_range(n)
                                    && reader.get(n).is_none_or(|(b, l)| b.visited >> l & 1 == 0)
                            }));
                        }
                    }
                    (cells, reached)
                })
                .collect();
            let mut next = Vec::new();
            for (chunk, (cells, reached)) in frontier.chunks(256).zip(classified) {
                for n in reached {
                    if self.visit(n, &mut cache) {
                        next.push(n);
                    }
                }
                for (&c, cell) in chunk.iter().zip(cells) {
                    let Some(cell) = cell else { continue };
                    let slot = self.cells.len() as u32;
                    let (brick, l) = self.brick_mut(c, &mut cache);
                    brick.active[l] = slot;
                    self.cells.push((pack(c), cell));
                }
            }
            frontier = next;
        }
        Ok(())
    }

    /// Evaluates `f` at the corners of `cells` not evaluated before. The corners of each
    /// run of [`CORNER_RUN`] cells are collected (a sequential walk over the bricks) while
    /// those of the previous run are evaluated in parallel: on the 362K-point bunny the walk
    /// over the first wave's 1.2M corners otherwise holds one thread for about 20 ms (the
    /// search took 0.339 s instead of 0.350, means of 8 alternating runs).
    fn evaluate_corners(&mut self, cells: &[Index3]) {
        let mut cache = [(u64::MAX, 0); 8];
        let eval = self.eval;
        let mut runs = cells.chunks(CORNER_RUN);
        let mut pending = runs.next().map(|run| self.new_corners(run, &mut cache));
        while let Some((targets, points)) = pending.take() {
            let next_run = runs.next();
            let ((values, took), next) = rayon::join(
                || {
                    let start = Instant::now();
                    (eval.values(&points), start.elapsed())
                },
                || next_run.map(|run| self.new_corners(run, &mut cache)),
            );
            self.evaluations += points.len();
            self.evaluation_time += took;
            for ((brick, l), v) in targets.into_iter().zip(values) {
                self.bricks[brick as usize].values[l] = v.unwrap_or(f64::NAN);
            }
            pending = next;
        }
    }

    /// The corners of `cells` not evaluated before, as (brick slot, position in the brick)
    /// and grid position, marked evaluated.
    fn new_corners(
        &mut self,
        cells: &[Index3],
        cache: &mut BrickCache<u32>,
    ) -> (Vec<(u32, usize)>, Vec<DVec3>) {
        let mut targets = Vec::new();
        let mut points = Vec::new();
        for &c in cells {
            for k in 0..8 {
                let o = corner_offset(k);
                let v = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
                let (brick, l) = self.brick_mut(v, cache);
                if brick.evaluated >> l & 1 == 0 {
                    brick.evaluated |= 1 << l;
                    targets.push((cache[brick_class(v)].1, l));
                    points.push(self.grid.position(v));
                }
            }
        }
        (targets, points)
    }
}

/// Cells whose new corners are collected while the previous run's are evaluated (see
/// [`Search::evaluate_corners`]).
const CORNER_RUN: usize = 16_384;

/// The active-cell data of cell `c`, or `None` when it is not active or `f` is undefined at
/// a corner.
fn classify(reader: &mut BrickReader<'_>, c: Index3) -> Option<ActiveCell> {
    let mut values = [0.0; 8];
    let mut inside_count = 0;
    for (k, value) in values.iter_mut().enumerate() {
        let o = corner_offset(k);
        let v = reader.value([c[0] + o[0], c[1] + o[1], c[2] + o[2]])?;
        if v.is_nan() {
            return None;
        }
        inside_count += usize::from(inside(v));
        *value = v;
    }
    if inside_count == 0 || inside_count == 8 {
        return None;
    }
    let (sheet, sheets) = cell_sheets(&values);
    Some(ActiveCell {
        inside: (0..8).fold(0, |m, k| m | (u8::from(inside(values[k])) << k)),
        sheet,
        sheets,
    })
}

/// The four cells around cube edge `e` of cell `c`, counter-clockwise seen from the edge's
/// positive direction, each with the index the edge has in it.
fn cells_around_edge(c: Index3, e: usize) -> [Index3; 4] {
    cells_and_edges_around(c, e).map(|(n, _)| n)
}

fn cells_and_edges_around(c: Index3, e: usize) -> [(Index3, usize); 4] {
    let d = e / 4;
    let (u, w) = ((d + 1) % 3, (d + 2) % 3);
    // The grid vertex where the edge starts.
    let mut g = c;
    g[u] += (e & 1) as i64;
    g[w] += ((e >> 1) & 1) as i64;
    // Relative to the edge, cell g lies at (+u, +w); going (+,+), (−,+), (−,−), (+,−) is
    // counter-clockwise seen from +d since (u, w, d) is right-handed.
    let shifted = |du: i64, dw: i64| {
        let mut n = g;
        n[u] -= du;
        n[w] -= dw;
        (n, 4 * d + du as usize + 2 * dw as usize)
    };
    [shifted(0, 0), shifted(1, 0), shifted(1, 1), shifted(0, 1)]
}

/// Builds the mesh from the active cells, in ascending cell order.
fn extract(
    search: &Search,
    grid: &Grid,
    params: &PolygoniseParams,
    blend: Option<&[f64]>,
    stats: &mut PolygoniseStats,
) -> TriMesh {
    // Ascending cell order, whatever order the search found them in.
    let mut order: Vec<u32> = (0..search.cells.len() as u32).collect();
    order.par_sort_unstable_by_key(|&i| search.cells[i as usize].0);
    let mut rank = vec![0u32; order.len()];
    for (r, &i) in order.iter().enumerate() {
        rank[i as usize] = r as u32;
    }
    let keys: Vec<u64> = order.iter().map(|&i| search.cells[i as usize].0).collect();
    let cells: Vec<&ActiveCell> = order.iter().map(|&i| &search.cells[i as usize].1).collect();
    let mut first_vertex = Vec::with_capacity(keys.len() + 1);
    let mut total = 0u32;
    for cell in &cells {
        first_vertex.push(total);
        total += u32::from(cell.sheets);
    }
    first_vertex.push(total);
    stats.active_cells = cells.len();
    stats.multi_sheet_cells = cells.iter().filter(|c| c.sheets > 1).count();

    // Vertices: the mean of each sheet's edge crossings.
    let mut vertices: Vec<DVec3> = keys
        .par_iter()
        .zip(&cells)
        .map_init(
            || search.reader(),
            |reader, (&key, cell)| {
                let c = unpack(key);
                let base = grid.position(c);
                let value = |reader: &mut BrickReader<'_>, k: usize| {
                    let o = corner_offset(k);
                    reader
                        .value([c[0] + o[0], c[1] + o[1], c[2] + o[2]])
                        .unwrap_or(f64::NAN)
                };
                // A sheet crosses at least three of the twelve cube edges.
                let mut sums = [(DVec3::ZERO, 0u32); 4];
                for e in 0..12 {
                    let s = cell.sheet[e];
                    if s == NO_SHEET {
                        continue;
                    }
                    let (a, b) = edge_ends(e);
                    let slot = &mut sums[usize::from(s)];
                    slot.0 += edge_crossing(a, b, value(reader, a), value(reader, b));
                    slot.1 += 1;
                }
                let step = grid.step;
                sums.into_iter()
                    .take(usize::from(cell.sheets))
                    .map(move |(sum, n)| base + sum / f64::from(n) * step)
            },
        )
        .flatten_iter()
        .collect();
    let tube_list = tube_faces(search, grid, &keys, &cells, total);
    stats.tube_faces = tube_list.len();
    let mut owner: Vec<Index3> = Vec::new();
    if params.project || params.normals {
        owner = keys
            .iter()
            .zip(&cells)
            .flat_map(|(&k, cell)| std::iter::repeat_n(unpack(k), usize::from(cell.sheets)))
            .collect();
    }
    // Each tube face's two vertices follow the cells' (numbered so by `tube_faces`).
    let mut tubes: KeyMap<[Option<TubeFace>; 3]> = KeyMap::default();
    for &(key, axis, t) in &tube_list {
        let c = unpack(key);
        vertices.extend(t.positions.map(|p| grid.position(c) + p * grid.step));
        if !owner.is_empty() {
            owner.extend([c; 2]);
        }
        tubes.entry(key).or_default()[axis] = Some(t);
    }

    let mut normals = None;
    let mut blended = None;
    if params.project || params.normals {
        let fg: Vec<Option<ValueGradient>> = match blend {
            // Lengths were checked on entry.
            Some(values) => match search.eval.values_gradients_blends(&vertices, values) {
                Ok(fgb) => {
                    blended = Some(
                        fgb.par_iter()
                            .map(|r| r.map_or(0.0, |(_, b)| b))
                            .collect::<Vec<f64>>(),
                    );
                    fgb.into_par_iter().map(|r| r.map(|(vg, _)| vg)).collect()
                }
                Err(_) => search.eval.values_gradients(&vertices),
            },
            None => search.eval.values_gradients(&vertices),
        };
        // The gradient before the Newton step serves as the normal: the step is shorter than
        // a cell, and another evaluation would cost as much as the whole projection.
        normals = Some(
            fg.par_iter()
                .map(|vg| vg.map_or(DVec3::ZERO, |vg| (-vg.gradient).normalize_or_zero()))
                .collect::<Vec<DVec3>>(),
        );
        if params.project {
            vertices
                .par_iter_mut()
                .zip(fg)
                .zip(owner)
                .for_each(|((x, vg), c)| {
                    let Some(vg) = vg else { return };
                    let g2 = vg.gradient.length_squared();
                    if !(g2 > 0.0 && g2.is_finite()) {
                        return;
                    }
                    let lo = grid.position(c);
                    let hi = lo + DVec3::splat(grid.step);
                    let moved = (*x - vg.gradient * (vg.value / g2)).clamp(lo, hi);
                    if moved.is_finite() {
                        *x = moved;
                    }
                });
        }
    }

    // Quads: each crossing grid edge is emitted by the cell where it is cube edge 0, 4 or 8.
    // In runs of cells, one triangle list per run rather than per cell.
    const RUN: usize = 256;
    let per_run: Vec<(Vec<[u32; 3]>, usize)> = keys
        .par_chunks(RUN)
        .zip(cells.par_chunks(RUN))
        .map_init(
            || search.reader(),
            |reader, (run_keys, run_cells)| {
                let mut tris = Vec::with_capacity(4 * run_keys.len());
                let mut open = 0;
                for (&key, cell) in run_keys.iter().zip(run_cells) {
                    let c = unpack(key);
                    for d in 0..3 {
                        let e = 4 * d;
                        if cell.sheet[e] == NO_SHEET {
                            continue;
                        }
                        let around = cells_and_edges_around(c, e);
                        let mut quad = [0u32; 4];
                        let mut complete = true;
                        for (slot, (n, ne)) in quad.iter_mut().zip(around) {
                            let found = grid
                                .in_range(n)
                                .then(|| reader.active_slot(n))
                                .flatten()
                                .map(|slot| {
                                    let i = rank[slot as usize];
                                    (i, cells[i as usize].sheet[ne])
                                });
                            match found {
                                Some((i, s)) if s != NO_SHEET => {
                                    *slot = first_vertex[i as usize] + u32::from(s)
                                }
                                _ => complete = false,
                            }
                        }
                        if !complete {
                            open += 1;
                            continue;
                        }
                        let (a, _) = edge_ends(e);
                        let outward = cell.inside >> a & 1 == 1;
                        if tubes.is_empty() {
                            if !outward {
                                quad.reverse();
                            }
                            split_quad(&mut tris, quad, &vertices);
                        } else {
                            push_polygon_through_tubes(
                                &mut tris, quad, around, outward, &tubes, &vertices,
                            );
                        }
                    }
                }
                (tris, open)
            },
        )
        .collect();
    let mut triangles = Vec::with_capacity(per_run.iter().map(|(t, _)| t.len()).sum());
    for (tris, open) in per_run {
        triangles.extend(tris);
        stats.open_quads += open;
    }
    if blended.is_none()
        && let Some(values) = blend
    {
        blended = search.eval.blend(&vertices, values).ok().map(|b| {
            b.into_iter()
                .map(|v| v.unwrap_or(0.0))
                .collect::<Vec<f64>>()
        });
    }
    let mut mesh = TriMesh::new(vertices, triangles);
    mesh.normals = if params.normals { normals } else { None };
    mesh.values = blended;
    remove_unused_vertices(&mut mesh);
    mesh
}

/// Where `f` crosses 0 on the cube edge from corner `a` (value `fa`) to corner `b` (value
/// `fb`), by linear interpolation, in cell units from the cell's origin.
fn edge_crossing(a: usize, b: usize, fa: f64, fb: f64) -> DVec3 {
    let t = fa / (fa - fb);
    let pa = DVec3::from_array(corner_offset(a).map(|x| x as f64));
    let pb = DVec3::from_array(corner_offset(b).map(|x| x as f64));
    pa + (pb - pa) * t
}

/// Splits a quad into two triangles along its shorter diagonal.
fn split_quad(tris: &mut Vec<[u32; 3]>, q: [u32; 4], vertices: &[DVec3]) {
    let x = q.map(|v| vertices[v as usize]);
    if x[0].distance_squared(x[2]) <= x[1].distance_squared(x[3]) {
        tris.extend([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
    } else {
        tris.extend([[q[0], q[1], q[3]], [q[1], q[2], q[3]]]);
    }
}

/// A face where the polygons of both cells sharing it use both of its crossing segments: a
/// tube of surface through the face, which one vertex per cell sheet would pinch into an
/// edge of four quads. Each segment gets a vertex of its own on the face.
#[derive(Clone, Copy, Debug)]
struct TubeFace {
    /// The vertex of segment 0; segment 1's follows it.
    first_vertex: u32,
    /// The decider's pairing on the face, as the lower cell sees it (its face `2a + 1`).
    joins_0_and_2: bool,
    /// Mean of each segment's two edge crossings, in cell units from the lower cell's origin.
    positions: [DVec3; 2],
}

/// The tube faces among the active cells (sorted by `keys`): the key of the lower cell, the
/// face's normal axis, and the face, numbered in that order from vertex `first`.
fn tube_faces(
    search: &Search,
    grid: &Grid,
    keys: &[u64],
    cells: &[&ActiveCell],
    first: u32,
) -> Vec<(u64, usize, TubeFace)> {
    // One sheet through all four edges of a face (a four-crossing face pairs them into two
    // segments, so the sheet uses both).
    let one_sheet = |cell: &ActiveCell, face: usize| {
        let s = FACE_EDGES[face].map(|e| cell.sheet[e]);
        s[0] != NO_SHEET && s.iter().all(|&x| x == s[0])
    };
    let found: Vec<(u64, usize, TubeFace)> = keys
        .par_iter()
        .zip(cells)
        .map_init(
            || search.reader(),
            |reader, (&key, cell)| {
                let c = unpack(key);
                let mut out = Vec::new();
                for axis in 0..3 {
                    let face = 2 * axis + 1;
                    if !one_sheet(cell, face) {
                        continue;
                    }
                    let mut n = c;
                    n[axis] += 1;
                    let neighbour_one_sheet = grid.in_range(n)
                        && reader.active_slot(n).is_some_and(|slot| {
                            one_sheet(&search.cells[slot as usize].1, 2 * axis)
                        });
                    if !neighbour_one_sheet {
                        continue;
                    }
                    let mut q = [0.0; 4];
                    for (v, &k) in q.iter_mut().zip(&FACE_CORNERS[face]) {
                        let o = corner_offset(k);
                        *v = reader
                            .value([c[0] + o[0], c[1] + o[1], c[2] + o[2]])
                            .unwrap_or(f64::NAN);
                    }
                    let joins_0_and_2 = joins_corners_0_and_2(q);
                    let mut sums = [DVec3::ZERO; 2];
                    for (k, &e) in FACE_EDGES[face].iter().enumerate() {
                        let (a, b) = edge_ends(e);
                        let (fa, fb) = (q[corner_slot(face, a)], q[corner_slot(face, b)]);
                        sums[face_segment(joins_0_and_2, k)] += 0.5 * edge_crossing(a, b, fa, fb);
                    }
                    out.push((
                        key,
                        axis,
                        TubeFace {
                            first_vertex: 0,
                            joins_0_and_2,
                            positions: sums,
                        },
                    ));
                }
                out
            },
        )
        .flatten_iter()
        .collect();
    found
        .into_iter()
        .enumerate()
        .map(|(i, (key, axis, t))| {
            let first_vertex = first + 2 * i as u32;
            (key, axis, TubeFace { first_vertex, ..t })
        })
        .collect()
}

/// Position of cube corner `corner` in the corner list of `face`.
fn corner_slot(face: usize, corner: usize) -> usize {
    FACE_CORNERS[face]
        .iter()
        .position(|&k| k == corner)
        .expect("an edge of the face joins two of its corners")
}

/// Emits the triangles of the quad `quad` around a crossing edge (cells and their edge
/// indices `around`, counter-clockwise), with the segment vertex of every tube face between
/// two consecutive cells inserted between their vertices; wound outward when `outward`,
/// else reversed.
fn push_polygon_through_tubes(
    tris: &mut Vec<[u32; 3]>,
    quad: [u32; 4],
    around: [(Index3, usize); 4],
    outward: bool,
    tubes: &KeyMap<[Option<TubeFace>; 3]>,
    vertices: &[DVec3],
) {
    // Four cell vertices and at most one segment vertex between each consecutive two.
    let mut polygon = [0u32; 8];
    let mut len = 0;
    let mut apex = None;
    for k in 0..4 {
        polygon[len] = quad[k];
        len += 1;
        let (c0, e0) = around[k];
        let (c1, e1) = around[(k + 1) % 4];
        let axis = (0..3)
            .find(|&d| c0[d] != c1[d])
            .expect("neighbouring cells");
        let (lower, lower_edge) = if c0[axis] < c1[axis] {
            (c0, e0)
        } else {
            (c1, e1)
        };
        if let Some(t) = tubes.get(&pack(lower)).and_then(|faces| faces[axis]) {
            let k_face = FACE_EDGES[2 * axis + 1]
                .iter()
                .position(|&e| e == lower_edge)
                .expect("the crossing edge lies on the face");
            let v = t.first_vertex + face_segment(t.joins_0_and_2, k_face) as u32;
            apex.get_or_insert(v);
            polygon[len] = v;
            len += 1;
        }
    }
    let polygon = &mut polygon[..len];
    if !outward {
        polygon.reverse();
    }
    let Some(apex) = apex else {
        split_quad(
            tris,
            [polygon[0], polygon[1], polygon[2], polygon[3]],
            vertices,
        );
        return;
    };
    // A fan from a segment vertex: it belongs to this polygon and one other only, so its
    // diagonals are edges of no other triangle.
    let at = polygon.iter().position(|&v| v == apex).unwrap_or(0);
    polygon.rotate_left(at);
    for i in 1..len - 1 {
        tris.push([polygon[0], polygon[i], polygon[i + 1]]);
    }
}

/// Drops triangles whose centroid is farther than `limit` from every seed; returns how many.
fn trim(mesh: &mut TriMesh, seeds: &[DVec3], limit: f64) -> Result<usize, PolygoniseError> {
    let index = PointIndex::new(seeds)?;
    let keep: Vec<bool> = mesh
        .triangles
        .par_iter()
        .map_init(Vec::new, |found, t| {
            let centroid = t.iter().map(|&v| mesh.vertices[v as usize]).sum::<DVec3>() / 3.0;
            index.nearest_k_with_distances(centroid, 1, found);
            found.first().is_some_and(|&(d2, _)| d2 <= limit * limit)
        })
        .collect();
    let before = mesh.triangles.len();
    let mut k = keep.iter();
    mesh.triangles.retain(|_| *k.next().unwrap_or(&false));
    remove_unused_vertices(mesh);
    Ok(before - mesh.triangles.len())
}

/// Splits every vertex whose triangles form several fans (joined through edges shared by
/// exactly two of them) into one vertex per fan; returns how many new vertices were made.
fn split_fans(mesh: &mut TriMesh) -> usize {
    let n = mesh.vertices.len();
    let mut offsets = vec![0u32; n + 1];
    for t in &mesh.triangles {
        for &v in t {
            offsets[v as usize + 1] += 1;
        }
    }
    for v in 0..n {
        offsets[v + 1] += offsets[v];
    }
    let mut fill = offsets.clone();
    let mut incident = vec![0u32; offsets[n] as usize];
    for (i, t) in mesh.triangles.iter().enumerate() {
        for &v in t {
            incident[fill[v as usize] as usize] = i as u32;
            fill[v as usize] += 1;
        }
    }
    // The vertices of several fans (few), ascending, with the fan of each incident triangle.
    let split: Vec<(usize, Vec<u32>)> = (0..n)
        .into_par_iter()
        .with_min_len(1024)
        .filter_map(|v| {
            let tris = &incident[offsets[v] as usize..offsets[v + 1] as usize];
            if is_single_fan(v as u32, tris, &mesh.triangles) == Some(true) {
                return None;
            }
            fans_of(v as u32, tris, &mesh.triangles).map(|fan| (v, fan))
        })
        .collect();
    let mut added = 0;
    for (v, fan) in split {
        let count = fan.iter().copied().max().unwrap_or(0) as usize + 1;
        let copies: Vec<u32> = std::iter::once(v as u32)
            .chain((1..count).map(|k| (n + added + k - 1) as u32))
            .collect();
        for _ in 1..count {
            mesh.vertices.push(mesh.vertices[v]);
            if let Some(normals) = &mut mesh.normals {
                normals.push(normals[v]);
            }
            if let Some(values) = &mut mesh.values {
                values.push(values[v]);
            }
        }
        added += count - 1;
        let tris = &incident[offsets[v] as usize..offsets[v + 1] as usize];
        for (&t, &f) in tris.iter().zip(&fan) {
            for corner in &mut mesh.triangles[t as usize] {
                if *corner == v as u32 {
                    *corner = copies[f as usize];
                }
            }
        }
    }
    added
}

/// Most incident triangles a vertex may have for [`is_single_fan`] to decide.
const QUICK_FAN_MAX: usize = 32;

/// Whether the triangles `tris` (all holding `v` once) form a single fan, joined as in
/// [`fans_of`]; `None` when it cannot tell quickly (more than [`QUICK_FAN_MAX`] triangles, a
/// degenerate triangle). Nearly every vertex of a surface net is one fan of about six
/// triangles: walking around it on the stack, without the sorting and the lists of
/// [`fans_of`], the splitting pass over the 362K-point bunny's 224K vertices took 9–17 ms
/// instead of 21–29 ms.
fn is_single_fan(v: u32, tris: &[u32], triangles: &[[u32; 3]]) -> Option<bool> {
    let k = tris.len();
    if k <= 1 {
        return Some(true);
    }
    if k > QUICK_FAN_MAX {
        return None;
    }
    // The two other corners of each triangle: the ends of its two edges at `v`.
    let mut ends = [[0u32; 2]; QUICK_FAN_MAX];
    for (pair, &t) in ends.iter_mut().zip(tris) {
        let [x, y, z] = triangles[t as usize];
        *pair = if x == v {
            [y, z]
        } else if y == v {
            [z, x]
        } else {
            [x, y]
        };
        if pair[0] == pair[1] || pair.contains(&v) {
            return None;
        }
    }
    let ends = &ends[..k];
    // The triangle across the edge (v, w) from triangle `from`: the edge joins two triangles
    // only when exactly two hold it.
    let across = |from: usize, w: u32| -> Option<usize> {
        let mut found = None;
        for (j, pair) in ends.iter().enumerate() {
            if j != from && pair.contains(&w) {
                if found.is_some() {
                    return None;
                }
                found = Some(j);
            }
        }
        found
    };
    // Each triangle meets at most two others, so triangle 0's fan is a cycle or a path: walk
    // it one way, and when that ends (a boundary) the other way.
    let mut seen = 1;
    for start in [1, 0] {
        let (mut at, mut w) = (0, ends[0][start]);
        while let Some(next) = across(at, w) {
            if next == 0 {
                return (start == 1).then_some(seen == k);
            }
            seen += 1;
            if seen > k {
                return None;
            }
            w = if ends[next][0] == w {
                ends[next][1]
            } else {
                ends[next][0]
            };
            at = next;
        }
    }
    Some(seen == k)
}

/// The fan of each triangle in `tris` (all holding `v`), numbered from 0 in order of first
/// appearance, or `None` when they form a single fan.
fn fans_of(v: u32, tris: &[u32], triangles: &[[u32; 3]]) -> Option<Vec<u32>> {
    if tris.len() <= 1 {
        return None;
    }
    let mut parent: Vec<usize> = (0..tris.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    // Each other corner w of an incident triangle names the edge (v, w).
    let mut by_other: Vec<(u32, usize)> = Vec::with_capacity(2 * tris.len());
    for (i, &t) in tris.iter().enumerate() {
        for &w in &triangles[t as usize] {
            if w != v {
                by_other.push((w, i));
            }
        }
    }
    by_other.sort_unstable();
    for group in by_other.chunk_by(|a, b| a.0 == b.0) {
        if let [(_, a), (_, b)] = group {
            let (ra, rb) = (root(&mut parent, *a), root(&mut parent, *b));
            parent[ra.max(rb)] = ra.min(rb);
        }
    }
    let mut label = vec![u32::MAX; tris.len()];
    let mut next = 0;
    let mut fan = Vec::with_capacity(tris.len());
    for i in 0..tris.len() {
        let r = root(&mut parent, i);
        if label[r] == u32::MAX {
            label[r] = next;
            next += 1;
        }
        fan.push(label[r]);
    }
    (next > 1).then_some(fan)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use sphcover_core::mesh_topology::MeshTopology;
    use sphcover_core::{
        Cover, Kernel, LinearFunction, LocalFunctions, SurfaceCoverParams, build_surface_cover,
    };
    use sphcover_fixtures::{sphere, sphere_signed_distance, torus, torus_signed_distance};

    fn cover_of(cloud: &sphcover_core::PointCloud) -> Cover {
        let normals = cloud.normals.as_ref().expect("fixtures carry normals");
        // A coarser tolerance than the default keeps the cover (and the test) small.
        let params = SurfaceCoverParams {
            eps: 5e-3,
            ..SurfaceCoverParams::default()
        };
        build_surface_cover(&cloud.positions, normals, &params)
            .expect("cover of a fixture")
            .0
    }

    /// `Σ (a × b)·c / 6`: positive for a closed mesh wound counter-clockwise from outside.
    fn signed_volume(mesh: &TriMesh) -> f64 {
        mesh.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
                a.cross(b).dot(c) / 6.0
            })
            .sum()
    }

    fn params(depth: u32) -> PolygoniseParams {
        PolygoniseParams {
            step: GridStep::Depth(depth),
            ..PolygoniseParams::default()
        }
    }

    #[test]
    fn blending_keeps_the_geometry_and_blends_at_the_unprojected_vertices() {
        let cloud = sphere(DVec3::ZERO, 0.4, 4000);
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let values: Vec<f64> = cover.centers().iter().map(|c| c.x + 2.0 * c.z).collect();
        for (project, normals) in [(true, true), (false, true), (false, false)] {
            let p = PolygoniseParams {
                project,
                normals,
                ..params(6)
            };
            let (plain, _) = polygonise(&eval, &cloud.positions, &p).unwrap();
            let (mesh, _) =
                polygonise_blending(&eval, &cloud.positions, &p, Some(&values)).unwrap();
            assert_eq!(plain.vertices, mesh.vertices);
            assert_eq!(plain.triangles, mesh.triangles);
            assert_eq!(plain.normals, mesh.normals);
            assert_eq!(plain.values, None);
            let blended = mesh.values.as_ref().unwrap();
            assert_eq!(blended.len(), mesh.vertices.len());
            let (lo, hi) = values
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            assert!(blended.iter().all(|&b| (lo..=hi).contains(&b)));
            if !project {
                // Unprojected vertices are where the blend was taken.
                let direct: Vec<f64> = eval
                    .blend(&mesh.vertices, &values)
                    .unwrap()
                    .into_iter()
                    .map(|v| v.unwrap_or(0.0))
                    .collect();
                assert_eq!(*blended, direct, "project {project}, normals {normals}");
            }
        }
        assert_eq!(
            polygonise_blending(&eval, &cloud.positions, &params(6), Some(&[1.0])).unwrap_err(),
            PolygoniseError::BlendLengthMismatch {
                expected: cover.len(),
                found: 1
            }
        );
    }

    #[test]
    fn sphere_is_a_closed_oriented_sphere_near_the_truth() {
        let cloud = sphere(DVec3::ZERO, 0.4, 4000);
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let (mesh, stats) = polygonise(&eval, &cloud.positions, &params(6)).unwrap();
        let topo = MeshTopology::of(&mesh);
        assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
        assert_eq!((topo.components, topo.euler_characteristic()), (1, 2));
        let volume = signed_volume(&mesh);
        let truth = 4.0 / 3.0 * std::f64::consts::PI * 0.4f64.powi(3);
        assert!(
            (volume / truth - 1.0).abs() < 0.02,
            "volume {volume} vs {truth}"
        );
        let worst = mesh
            .vertices
            .iter()
            .map(|&v| sphere_signed_distance(DVec3::ZERO, 0.4, v).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < 0.25 * stats.step,
            "worst {worst}, step {}",
            stats.step
        );
        let normals = mesh.normals.as_ref().unwrap();
        assert!(
            mesh.vertices
                .iter()
                .zip(normals)
                .all(|(v, n)| v.normalize().dot(*n) > 0.9)
        );
        assert_eq!(stats.open_quads, 0);
        // Clean samples sit next to the surface: none needs pulling onto it.
        assert_eq!(stats.seeds_searched, 0);
    }

    #[test]
    fn torus_is_closed_with_euler_characteristic_zero() {
        let cloud = torus(0.3, 0.12, 6000);
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        for project in [false, true] {
            let p = PolygoniseParams {
                project,
                ..params(6)
            };
            let (mesh, stats) = polygonise(&eval, &cloud.positions, &p).unwrap();
            let topo = MeshTopology::of(&mesh);
            assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
            assert_eq!((topo.components, topo.euler_characteristic()), (1, 0));
            assert!(signed_volume(&mesh) > 0.0);
            let worst = mesh
                .vertices
                .iter()
                .map(|&v| torus_signed_distance(0.3, 0.12, v).abs())
                .fold(0.0, f64::max);
            let bound = if project { 0.25 } else { 0.5 } * stats.step;
            assert!(
                worst < bound,
                "project {project}: worst {worst}, step {}",
                stats.step
            );
        }
    }

    #[test]
    fn plane_patch_gives_an_open_manifold_sheet() {
        let n = 40;
        let points: Vec<DVec3> = (0..n * n)
            .map(|i| {
                DVec3::new(
                    (i % n) as f64 / n as f64 - 0.5,
                    (i / n) as f64 / n as f64 - 0.5,
                    0.0,
                )
            })
            .collect();
        let normals = vec![DVec3::Z; points.len()];
        let (cover, _) =
            build_surface_cover(&points, &normals, &SurfaceCoverParams::default()).unwrap();
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let (mesh, stats) = polygonise(&eval, &points, &params(5)).unwrap();
        let topo = MeshTopology::of(&mesh);
        assert!(
            topo.is_manifold() && topo.inconsistent_edges == 0,
            "{topo:?}"
        );
        assert!(topo.boundary_edges > 0 && stats.open_quads > 0);
        assert_eq!(topo.components, 1);
        // Outside is +z: normals point up.
        assert!(mesh.normals.unwrap().iter().all(|n| n.z > 0.9));
        assert!(mesh.vertices.iter().all(|v| v.z.abs() < 1e-6));
        // Trimming keeps what lies near the samples.
        let trimmed = PolygoniseParams {
            trim: Some(0.05),
            ..params(5)
        };
        let (cut, stats) = polygonise(&eval, &points, &trimmed).unwrap();
        assert!(stats.trimmed_triangles > 0);
        assert!(
            cut.vertices
                .iter()
                .all(|v| v.x.abs() < 0.56 && v.y.abs() < 0.56)
        );
        assert!(MeshTopology::of(&cut).is_manifold());
    }

    #[test]
    fn trimming_a_sphere_seeded_on_one_half_opens_it() {
        let cloud = sphere(DVec3::ZERO, 0.4, 4000);
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let upper: Vec<DVec3> = cloud
            .positions
            .iter()
            .copied()
            .filter(|p| p.z > 0.0)
            .collect();
        let p = PolygoniseParams {
            trim: Some(0.03),
            ..params(6)
        };
        let (mesh, stats) = polygonise(&eval, &upper, &p).unwrap();
        assert!(stats.trimmed_triangles > 0);
        assert!(mesh.vertices.iter().all(|v| v.z > -0.06));
        let topo = MeshTopology::of(&mesh);
        assert!(topo.is_manifold() && topo.boundary_edges > 0, "{topo:?}");
        assert_eq!(topo.components, 1);
    }

    #[test]
    fn seeds_off_the_surface_are_pulled_onto_it_or_dropped() {
        let cloud = sphere(DVec3::ZERO, 0.4, 2000);
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let p = params(6);
        // Three steps outside: too far to touch a meshed cell, close enough to pull in.
        let step = Aabb::from_points(&cloud.positions).longest_edge() / 64.0;
        let near: Vec<DVec3> = cloud
            .positions
            .iter()
            .map(|&q| q * (1.0 + 3.0 * step / 0.4))
            .collect();
        let (mesh, stats) = polygonise(&eval, &near, &p).unwrap();
        assert!(stats.seeds_searched >= 1);
        let topo = MeshTopology::of(&mesh);
        assert!(topo.is_closed_oriented_manifold());
        assert_eq!((topo.components, topo.euler_characteristic()), (1, 2));
        // Eight steps away is beyond the default reach of four.
        let far: Vec<DVec3> = cloud
            .positions
            .iter()
            .map(|&q| q * (1.0 + 8.0 * step / 0.4))
            .collect();
        assert!(matches!(
            polygonise(&eval, &far, &p),
            Err(PolygoniseError::NoSurfaceNearSeeds { .. })
        ));
    }

    #[test]
    fn only_the_surface_reached_from_the_seeds_is_meshed() {
        let mut left = sphere(DVec3::new(-0.25, 0.0, 0.0), 0.15, 1500);
        let right = sphere(DVec3::new(0.25, 0.0, 0.0), 0.15, 1500);
        let left_seeds = left.positions.clone();
        left.positions.extend(&right.positions);
        if let (Some(a), Some(b)) = (left.normals.as_mut(), right.normals.as_ref()) {
            a.extend(b);
        }
        let cover = cover_of(&left);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let p = PolygoniseParams {
            step: GridStep::Absolute(0.01),
            ..PolygoniseParams::default()
        };
        let (one, _) = polygonise(&eval, &left_seeds, &p).unwrap();
        assert_eq!(MeshTopology::of(&one).components, 1);
        assert!(one.vertices.iter().all(|v| v.x < 0.0));
        let (both, _) = polygonise(&eval, &left.positions, &p).unwrap();
        let topo = MeshTopology::of(&both);
        assert!(topo.is_closed_oriented_manifold());
        assert_eq!((topo.components, topo.euler_characteristic()), (2, 4));
    }

    #[test]
    fn a_plate_thinner_than_a_cell_keeps_its_two_sides_apart() {
        // Both faces of a plate of thickness 0.008 pass through the same cells at step 0.02:
        // one vertex per cell would glue them; one per sheet keeps a manifold.
        // Tilted, so that grid vertices fall inside the plate all over it.
        let tilt = glam::DMat3::from_rotation_x(0.5) * glam::DMat3::from_rotation_y(0.3);
        let n = 40;
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for i in 0..n * n {
            let (x, y) = (
                (i % n) as f64 / n as f64 - 0.5,
                (i / n) as f64 / n as f64 - 0.5,
            );
            for side in [-1.0, 1.0] {
                points.push(tilt * DVec3::new(0.6 * x, 0.6 * y, 0.004 * side));
                normals.push(tilt * DVec3::Z * side);
            }
        }
        let params = SurfaceCoverParams {
            eps: 2e-3,
            ..SurfaceCoverParams::default()
        };
        let (cover, _) = build_surface_cover(&points, &normals, &params).unwrap();
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let p = PolygoniseParams {
            step: GridStep::Absolute(0.02),
            project: false,
            ..PolygoniseParams::default()
        };
        let (mesh, stats) = polygonise(&eval, &points, &p).unwrap();
        assert!(stats.multi_sheet_cells > 100, "{stats:?}");
        let topo = MeshTopology::of(&mesh);
        assert!(
            topo.is_manifold() && topo.inconsistent_edges == 0,
            "{topo:?}"
        );
        // The two faces are separate sheets: normals up on top, down below.
        // Both faces are there, wound outwards: as much area faces up as down.
        let up = tilt * DVec3::Z;
        let (mut top, mut bottom) = (0.0, 0.0);
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
            let along = (b - a).cross(c - a).dot(up);
            if along > 0.0 {
                top += along;
            } else {
                bottom -= along;
            }
        }
        assert!(
            top > 0.0 && (top / bottom - 1.0).abs() < 0.2,
            "{top} {bottom}"
        );
    }

    /// The search from seeds on every component finds exactly the active cells (with the
    /// same sheets) that classifying every cell of the grid finds.
    #[test]
    fn search_finds_what_a_scan_of_the_whole_grid_finds() {
        let mut cloud = sphere(DVec3::new(-0.2, 0.0, 0.0), 0.15, 1200);
        let other = torus(0.15, 0.06, 2000);
        let shifted: Vec<DVec3> = other
            .positions
            .iter()
            .map(|&p| p + DVec3::X * 0.2)
            .collect();
        cloud.positions.extend(&shifted);
        if let (Some(a), Some(b)) = (cloud.normals.as_mut(), other.normals.as_ref()) {
            a.extend(b);
        }
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let grid = Grid::around(&eval, 0.025).unwrap();
        let mut search = Search::new(&eval, &grid, usize::MAX);
        // One seed per component is enough.
        let seeds = [cloud.positions[0], shifted[0]];
        search
            .run(
                seeds
                    .iter()
                    .flat_map(|&p| grid.block_around(grid.cell_of(p)))
                    .collect(),
            )
            .unwrap();
        let mut found: Vec<(u64, [u8; 12])> =
            search.cells.iter().map(|(k, c)| (*k, c.sheet)).collect();
        found.sort_unstable();

        let [nx, ny, nz] = grid.dims;
        let index = |v: Index3| ((v[2] * ny + v[1]) * nx + v[0]) as usize;
        let vertices: Vec<DVec3> = (0..nx * ny * nz)
            .map(|i| grid.position([i % nx, (i / nx) % ny, i / (nx * ny)]))
            .collect();
        let values = eval.values(&vertices);
        let mut scanned = Vec::new();
        for i in 0..(nx - 1) * (ny - 1) * (nz - 1) {
            let c = [
                i % (nx - 1),
                (i / (nx - 1)) % (ny - 1),
                i / ((nx - 1) * (ny - 1)),
            ];
            let corners: Option<Vec<f64>> = (0..8)
                .map(|k| {
                    let o = corner_offset(k);
                    values[index([c[0] + o[0], c[1] + o[1], c[2] + o[2]])]
                })
                .collect();
            let Some(corners) = corners else { continue };
            let f: [f64; 8] = std::array::from_fn(|k| corners[k]);
            let inside_count = f.iter().filter(|&&v| inside(v)).count();
            if inside_count != 0 && inside_count != 8 {
                scanned.push((pack(c), cell_sheets(&f).0));
            }
        }
        scanned.sort_unstable();
        assert!(found.len() > 1000);
        assert_eq!(found, scanned);
    }

    #[test]
    fn bad_seeds_and_parameters_are_clear_errors() {
        let cloud = sphere(DVec3::ZERO, 0.4, 2000);
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let p = params(5);
        assert_eq!(
            polygonise(&eval, &[], &p).unwrap_err(),
            PolygoniseError::NoSeeds { given: 0 }
        );
        assert_eq!(
            polygonise(&eval, &[DVec3::NAN], &p).unwrap_err(),
            PolygoniseError::NoSeeds { given: 1 }
        );
        let far = [DVec3::splat(5.0), DVec3::splat(6.0)];
        assert_eq!(
            polygonise(&eval, &far, &p).unwrap_err(),
            PolygoniseError::NoSurfaceNearSeeds { seeds: 2 }
        );
        // One seed spans no box, so a depth gives no step.
        assert!(matches!(
            polygonise(&eval, &cloud.positions[..1], &p),
            Err(PolygoniseError::InvalidParameter { name: "step", .. })
        ));
        let absolute = PolygoniseParams {
            step: GridStep::Absolute(0.02),
            ..p.clone()
        };
        assert!(polygonise(&eval, &cloud.positions[..1], &absolute).is_ok());
        for bad in [
            PolygoniseParams {
                step: GridStep::Absolute(-1.0),
                ..p.clone()
            },
            PolygoniseParams {
                step: GridStep::SmallestRadius(f64::NAN),
                ..p.clone()
            },
            PolygoniseParams {
                trim: Some(0.0),
                ..p.clone()
            },
            PolygoniseParams {
                seed_reach: f64::INFINITY,
                ..p.clone()
            },
        ] {
            assert!(matches!(
                polygonise(&eval, &cloud.positions, &bad),
                Err(PolygoniseError::InvalidParameter { .. })
            ));
        }
        let too_fine = PolygoniseParams {
            step: GridStep::Absolute(1e-9),
            ..p.clone()
        };
        assert!(matches!(
            polygonise(&eval, &cloud.positions, &too_fine),
            Err(PolygoniseError::GridTooFine { .. })
        ));
        let capped = PolygoniseParams {
            max_cells: 100,
            ..p
        };
        assert!(matches!(
            polygonise(&eval, &cloud.positions, &capped),
            Err(PolygoniseError::TooManyCells { .. })
        ));
    }

    #[test]
    fn bit_identical_whatever_the_thread_count() {
        let cloud = torus(0.3, 0.12, 4000);
        let cover = cover_of(&cloud);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| polygonise(&eval, &cloud.positions, &params(6)).unwrap().0)
        };
        assert_eq!(run(1), run(3));
    }

    /// A cover of `[-1, 1]³` by a 5×5×5 lattice of supports carrying the given linear
    /// functions: its zero set is an arbitrary smooth surface, with sheets close together.
    fn random_cover(funcs: &[(DVec3, f64)]) -> Cover {
        let centers: Vec<DVec3> = (0..125)
            .map(|i| DVec3::new((i % 5) as f64, ((i / 5) % 5) as f64, (i / 25) as f64) * 0.5 - 1.0)
            .collect();
        let lin = centers
            .iter()
            .zip(funcs)
            .map(|(&c, &(a, b))| LinearFunction::from_global(a, b, c))
            .collect::<Vec<_>>();
        Cover::new(
            centers,
            vec![0.8; 125],
            LocalFunctions::from_linear(lin),
            Kernel::QuadraticBSpline,
        )
        .unwrap()
    }

    /// The tangled zero set of [`one_sheet_cells_sharing_an_ambiguous_face`]: per lattice
    /// support of [`random_cover`], the gradient and value of its linear function.
    #[rustfmt::skip]
    const TANGLE: [[f64; 4]; 125] = [
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [-0.41982259876301475, -0.41930644080097335, -0.12415545344774259, 0.29713409985764305],
        [0.08672647693349031, -0.8670027665545098, 0.8751838256226313, 0.08364593779986189],
        [0.43300329406906496, 0.7924972436759223, -0.4798176873774507, -0.2639194332354065],
        [0.39945199747239, 0.4347175205448123, 0.6586574548697688, -0.26401297045661376],
        [0.6664013987953484, -0.35882170440308025, -0.6416378965353599, -0.21939095160254207],
        [0.062328806725064904, -0.11184064455765566, -0.3619181881131223, -0.06101172802245994],
        [-0.6525869338740323, 0.1730135124928657, 0.4261129906158749, -0.26205094587674577],
        [-0.7617830311534295, -0.928267963669217, 0.12629733494910178, -0.07355376030244591],
        [-0.6524946623500568, 0.5579786751253042, 0.4740149136562575, 0.06836385424322902],
        [0.266473394104045, 0.32476766784145794, 0.9150136267816606, -0.09735563772512229],
        [0.21463240613344858, 0.40483598828470924, 0.5843198102664908, -0.06464103266589753],
        [0.29468962556762696, -0.7007997046674711, 0.09368426330334721, -0.03675018436508287],
        [-0.24020509959378142, 0.400138552812982, -0.16884229209484855, 0.1510076160821013],
        [0.04121824614019798, -0.755470232016485, -0.5187436759994221, 0.18870819880179773],
        [-0.4781174300541111, 0.3026877244701685, 0.68030839425557, -0.10911544525706732],
        [-0.4613295157974558, -0.7565052518251741, -0.14667323126634488, -0.07825022978114363],
        [-0.6054715189010496, 0.518893729379657, -0.6694651308138115, 0.2651691461754521],
        [-0.30826568090044854, -0.10692141142123283, 0.10509224826711527, 0.06103253505382191],
        [-0.5234764818527851, -0.9809567805830021, -0.6863386111043457, 0.08939396924321172],
        [0.024371586534484273, 0.6099698479900579, -0.6649759112595608, -0.039688159241344986],
        [-0.1382244583681864, 0.5164151971197252, -0.8818105904591502, -0.007646610497832949],
        [0.18122552247167298, 0.3950296555851851, -0.41772932314843697, -0.1033256331916075],
        [0.06254282210968924, -0.36212280548560993, 0.40421609876276027, -0.12382828075226991],
        [0.7734306406254547, 0.8868361784362352, 0.6990722272689701, 0.17844364749138136],
        [-0.09349927146496591, 0.3471414998544411, -0.29614532312769754, -0.22038475631601545],
        [0.9671708231936642, -0.5177632051864702, -0.18201910290387002, -0.05049255443389762],
        [-0.5882510727061399, 0.8996747544219706, 0.5892776630083811, -0.14347523921630678],
        [0.6387423630484272, -0.15495882743414263, 0.3486214943801931, 0.058609812967869365],
        [-0.09758382150187245, -0.7248149265543182, 0.8149307841657802, -0.26933760079387015],
        [-0.18520936846641053, -0.1204003104636337, 0.28992589693349735, 0.09628867821966247],
        [-0.7196921577329464, -0.9103868700536737, -0.6059552807879097, -0.14945882042239275],
        [0.028818379707087272, 0.7717199693831751, -0.5092216455440868, 0.010206547224891015],
        [0.20215458057005742, -0.6488671343158515, -0.36734201882480755, 0.17507115117324445],
        [0.5164852216947137, 0.34935428105229466, 0.520311669138156, 0.2802580512049048],
        [-0.1825102265449309, 0.08911359101977943, -0.9918760557454027, -0.23132320545757043],
        [-0.5425855249202213, 0.13933026566155388, -0.32000532428692763, 0.07454987128239816],
        [-0.086100776287785, 0.6425751054120065, 0.7346174020756451, -0.04012343677339384],
        [0.4161431967015538, 0.6067284283596202, 0.6863203362807264, 0.0943971576540243],
        [0.27996521668048924, 0.32298120837076594, 0.11892531715405161, 0.17096099795550498],
        [-0.20938033289267308, -0.5284594293992516, 0.655249156786148, 0.15121699000214636],
        [0.4088984877342852, -0.6870236144701543, 0.9614230050178888, 0.2038909042559704],
        [0.6896316067075737, 0.7897722802182432, 0.5253055715349618, 0.21722719664807785],
        [0.7294593557131853, 0.8271205945366071, -0.43274914652535973, -0.03934545267200615],
        [-0.5989384630904628, 0.1275471633003839, 0.8156017179593809, 0.2646612125811976],
        [0.724244373933628, -0.7891732872760474, -0.7361018721246491, 0.26833652843038697],
        [0.06749059442053379, -0.5287190802101289, 0.6389715194169482, 0.18311942469765122],
        [0.037288371157633005, 0.83357501427039, -0.7878143374278831, -0.020359472128635727],
        [0.7880137306785694, -0.6703074583582223, 0.3741301622541844, 0.07328169231404806],
        [0.4784264816921216, 0.11923380677012191, -0.8117769267348336, -0.26342624970827166],
        [-0.6779659417268847, -0.5528618173206579, -0.7344437939503923, 0.2945450596151548],
        [-0.5586089055407927, -0.15800250117024697, -0.039025729745865045, -0.10621307099549572],
        [-0.8581629375468501, -0.4344416105495339, -0.05749993898482427, -0.20641718386701904],
        [-0.9781691683809882, 0.6954812523190261, 0.5531343530804052, -0.07836607252483017],
        [0.32868670702073294, 0.43242127321929735, 0.054000918625460664, 0.05033686945503222],
        [0.1039124737703395, -0.047833734448616855, -0.1244210009935379, 0.21204957476061992],
        [0.5693481378774364, -0.3144114999548221, -0.3580947029650622, 0.2510480627300423],
        [0.7100030501415147, 0.6111591813117493, -0.500560868611132, 0.2130862408027498],
        [0.12812476361167596, -0.6906204838330546, -0.6472173101214785, 0.15432506167482365],
        [0.9487196867503896, 0.9004570024641225, 0.07183036251735159, -0.28379482569800324],
        [0.8793078319440006, 0.770835496084664, 0.014769574931220504, 0.08681469054554587],
        [0.6583694484599676, -0.5412540297960784, 0.34950393696646387, 0.18224866930129538],
        [0.9423804638302165, 0.4616347934368144, -0.13547472485721782, 0.09248853552551946],
        [-0.3687109078131071, -0.631784740957235, -0.9640574490883863, -0.020318825044062506],
        [0.039609092301912306, -0.5356177759543922, -0.8910346407663657, 0.2141700255287884],
        [-0.517077988823126, -0.3701136950255429, -0.08050165142533235, 0.24496161558425875],
        [0.5545141281583904, -0.8571595492736278, 0.8068047475416293, 0.04044631090917908],
        [0.11408714880587839, 0.8234740717822208, -0.179922822157974, 0.22445538105224214],
        [0.2516976789810286, -0.10404619058876897, 0.8003244211276999, 0.22815988058555683],
        [0.7371225618740209, -0.8315189675793447, -0.45181551688112936, 0.2597418193616428],
        [0.6174959286437384, -0.7612282731733558, 0.03677261403701954, 0.007143666501242768],
        [-0.003312360779225404, 0.6999662493499381, 0.5231424780098065, 0.1833432873772398],
        [0.7547478550748599, -0.12341124889781659, -0.33691482517118765, 0.22401387599966205],
        [0.804866681948485, -0.5670777587155295, -0.6779365015676904, 0.27497555783540617],
        [0.5116330569311823, -0.7824427328138326, -0.29124791999650285, 0.039969459864516985],
        [-0.6234864898272009, 0.23215764572125344, -0.8170336671486699, -0.2771481326693482],
        [0.9378608881943311, 0.7937761984679808, -0.8633665619428565, -0.08973805302417012],
        [-0.5364337970065567, 0.30578518877085875, -0.40648907579143906, -0.157476092904447],
        [0.6729776990193369, -0.723252390264528, 0.1713061499976043, 0.27266814045908333],
        [-0.9390378828151718, 0.1089349794390745, -0.8676095229736036, 0.10905615568145242],
        [0.8717144833494774, -0.18930679408304962, -0.05425815056870974, 0.12908557816626096],
        [0.6302587971619559, 0.3873720205655489, 0.5756877496804972, -0.2152563382343802],
        [0.35454203441820525, 0.6947837682626457, 0.004263724853661036, -0.07140624431739317],
        [-0.46773440370690555, 0.297541316180282, -0.1951261013286621, 0.026996164988130105],
        [-0.8620234426227993, 0.966195294455819, 0.1294487580870281, -0.14651012920634757],
        [0.5050072933752143, 0.15155836208249257, 0.7993783441862594, -0.14435656392934293],
        [0.17663417746393492, -0.9408492234876646, 0.5504353167286666, 0.2146880471339888],
        [0.1583407215638676, 0.4827367614389574, 0.06664154884577264, -0.08805774425094004],
        [-0.42022141315313405, -0.6308003463263521, -0.5520184204960841, 0.1310331966841414],
        [-0.48250573548792386, -0.10147437167315407, 0.15872695004972023, -0.19101281902246606],
        [-0.11389250037687422, -0.4811238732174069, -0.42367924512738087, 0.06760380858424822],
        [-0.6262634304550695, 0.029992130892995718, 0.5459545183646529, -0.193823951145756],
        [-0.10613884972502036, 0.2583887111152424, 0.5130868269253231, 0.034266560467362414],
        [0.6786211386874593, 0.46540624039795464, 0.9056125651016096, 0.19654042276417114],
        [-0.7061431935623701, -0.27978799872510435, -0.39484720017733327, -0.2549295705711641],
        [0.5104033236825612, -0.6114132153528034, 0.35125869678110794, 0.14008731722836537],
        [0.9086673932388186, -0.33552134258581645, -0.9006893289973608, -0.25100737479375423],
        [0.38950065660247823, 0.23379032149716425, -0.17777348981970012, -0.23604094923213997],
        [0.9872980959039045, 0.7286064550298299, 0.9192457002824033, 0.1470104175775096],
        [0.9936295655353043, 0.3022375255560035, 0.882603868646094, 0.2594531327103684],
        [0.7380060206756249, -0.6610934316861969, 0.4026677108115341, 0.2933751587386393],
        [0.7790935438731792, 0.2053563396325006, 0.263605619836894, -0.13087787705149384],
    ];

    /// Polygonises the zero set of [`random_cover`] with `funcs` from every support centre;
    /// `None` when no surface is near them.
    fn zero_set_topology(
        funcs: &[(DVec3, f64)],
        step: f64,
        project: bool,
    ) -> Option<(MeshTopology, PolygoniseStats)> {
        let cover = random_cover(funcs);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let p = PolygoniseParams {
            step: GridStep::Absolute(step),
            project,
            seed_reach: 100.0,
            ..PolygoniseParams::default()
        };
        match polygonise(&eval, cover.centers(), &p) {
            Ok((mesh, stats)) => Some((MeshTopology::of(&mesh), stats)),
            Err(PolygoniseError::NoSurfaceNearSeeds { .. }) => None,
            Err(e) => panic!("{e}"),
        }
    }

    /// Found by `arbitrary_zero_sets_give_oriented_manifolds` on 2026-12-01: two
    /// neighbouring cells ([17, 12, 9] and [18, 12, 9]) each hold a single sheet through all
    /// four crossings of their shared, ambiguous face, a tube through it. With one vertex
    /// per cell sheet the dual edge between them carried four quads and one edge ended up
    /// traversed twice in the same direction; each segment of the face now has a vertex.
    #[test]
    fn one_sheet_cells_sharing_an_ambiguous_face() {
        let funcs: Vec<(DVec3, f64)> = TANGLE
            .iter()
            .map(|&[x, y, z, b]| (DVec3::new(x, y, z), b))
            .collect();
        let (topo, stats) =
            zero_set_topology(&funcs, 0.1972754302209973, false).expect("a surface");
        assert!(stats.tube_faces > 0);
        assert!(topo.is_manifold(), "{topo:?}");
        assert_eq!(topo.inconsistent_edges, 0);
        assert_eq!(topo.invalid_triangles, 0);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// Any zero set, however tangled, is meshed as an oriented 2-manifold: multi-sheet
        /// cells get one vertex per sheet, and fans are split where the mesh stops.
        #[test]
        fn arbitrary_zero_sets_give_oriented_manifolds(
            funcs in prop::collection::vec(
                (prop::array::uniform3(-1.0f64..1.0), -0.3f64..0.3), 125),
            step in 0.07f64..0.2,
            project in any::<bool>(),
        ) {
            let funcs: Vec<(DVec3, f64)> =
                funcs.into_iter().map(|(a, b)| (DVec3::from_array(a), b)).collect();
            if let Some((topo, _)) = zero_set_topology(&funcs, step, project) {
                prop_assert!(topo.is_manifold(), "{:?}", topo);
                prop_assert_eq!(topo.inconsistent_edges, 0);
                prop_assert_eq!(topo.invalid_triangles, 0);
            }
        }

        /// The sheets of a cell: every crossing edge on one, the others on none, each sheet a
        /// polygon of at least three edges, and the same sheets for `−f` (the decider treats
        /// both sides alike).
        #[test]
        fn cell_sheets_are_polygons(values in prop::array::uniform8(-1.0f64..1.0)) {
            let values = values.map(|v| if v == 0.0 { 0.5 } else { v });
            let (sheet, count) = cell_sheets(&values);
            let mut sizes = vec![0; usize::from(count)];
            for e in 0..12 {
                let (a, b) = edge_ends(e);
                let crossing = inside(values[a]) != inside(values[b]);
                prop_assert_eq!(crossing, sheet[e] != NO_SHEET);
                if crossing {
                    sizes[usize::from(sheet[e])] += 1;
                }
            }
            prop_assert!(sizes.iter().all(|&s| s >= 3), "{:?}", sizes);
            prop_assert_eq!(cell_sheets(&values.map(|v| -v)), (sheet, count));
        }
    }

    /// Two closed tetrahedra glued at a vertex (a bow tie) or along an edge (four triangles
    /// on it) come apart into two closed oriented manifolds.
    #[test]
    fn split_fans_separates_pinched_sheets() {
        let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let tet = |v: [u32; 4]| faces.map(|f: [u32; 3]| f.map(|k| v[k as usize]));
        let mut vertices = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        vertices.extend([-DVec3::X, -DVec3::Y, -DVec3::Z]);
        // Sharing vertex 0.
        let mut pinched = TriMesh::new(
            vertices.clone(),
            [tet([0, 1, 2, 3]), tet([0, 4, 5, 6])].concat(),
        );
        pinched.normals = Some(vertices.clone());
        pinched.values = Some((0..7).map(f64::from).collect());
        assert_eq!(MeshTopology::of(&pinched).non_manifold_vertices, 1);
        assert_eq!(split_fans(&mut pinched), 1);
        let topo = MeshTopology::of(&pinched);
        assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
        assert_eq!((topo.components, topo.euler_characteristic()), (2, 4));
        assert_eq!(pinched.normals.as_ref().map(Vec::len), Some(8));
        assert_eq!(pinched.vertices[7], DVec3::ZERO);
        assert_eq!(
            pinched.values.as_ref().map(|v| (v.len(), v[7])),
            Some((8, 0.0))
        );
        // Sharing the edge 0–1: the second tetrahedron is the first turned half a turn about
        // the x axis, so it is wound outwards too.
        let mut glued = TriMesh::new(vertices, [tet([0, 1, 2, 3]), tet([0, 1, 5, 6])].concat());
        assert_eq!(MeshTopology::of(&glued).non_manifold_edges, 1);
        assert_eq!(split_fans(&mut glued), 2);
        let topo = MeshTopology::of(&glued);
        assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
        assert_eq!((topo.components, topo.euler_characteristic()), (2, 4));
    }

    proptest! {
        /// The quick fan test agrees with the union–find of `fans_of` wherever it decides: on
        /// random triangles around vertex 0 over a few other vertices (closed and open fans,
        /// several fans, edges held by three or more triangles, repeated triangles).
        #[test]
        fn quick_fan_test_agrees_with_fans_of(
            others in prop::collection::vec((1u32..9, 1u32..9), 1..14),
            degenerate in prop::option::of(0usize..14),
        ) {
            let mut triangles: Vec<[u32; 3]> =
                others.iter().map(|&(a, b)| [0, a, b]).collect();
            if let Some(d) = degenerate.filter(|&d| d < triangles.len()) {
                triangles[d] = [0, 0, 3];
            }
            let tris: Vec<u32> = (0..triangles.len() as u32).collect();
            if let Some(single) = is_single_fan(0, &tris, &triangles) {
                prop_assert_eq!(single, fans_of(0, &tris, &triangles).is_none());
            }
        }
    }

    #[test]
    fn quick_fan_test_decides_closed_and_pinched_fans() {
        // A closed fan of six triangles around 0, then the same with a second closed fan.
        let ring = |base: u32| -> Vec<[u32; 3]> {
            (0..6).map(|i| [0, base + i, base + (i + 1) % 6]).collect()
        };
        let one = ring(1);
        let tris: Vec<u32> = (0..6).collect();
        assert_eq!(is_single_fan(0, &tris, &one), Some(true));
        let two = [ring(1), ring(11)].concat();
        let tris: Vec<u32> = (0..12).collect();
        assert_eq!(is_single_fan(0, &tris, &two), Some(false));
        // An open fan (a boundary vertex) listed from its middle.
        let open: Vec<[u32; 3]> = [3, 4, 1, 2].iter().map(|&i| [0, i, i + 1]).collect();
        assert_eq!(is_single_fan(0, &[0, 1, 2, 3], &open), Some(true));
    }

    #[test]
    fn edge_tables_are_consistent() {
        for e in 0..12 {
            let (a, b) = edge_ends(e);
            assert_eq!(edge_between(a, b), e);
            assert_eq!(edge_between(b, a), e);
        }
        for f in 0..6 {
            // Each face edge joins consecutive face corners.
            for k in 0..4 {
                let (a, b) = edge_ends(FACE_EDGES[f][k]);
                let ends = [FACE_CORNERS[f][k], FACE_CORNERS[f][(k + 1) % 4]];
                assert!(ends.contains(&a) && ends.contains(&b));
            }
        }
        // Every cube edge lies on exactly two faces.
        for e in 0..12 {
            assert_eq!(FACE_EDGES.iter().filter(|f| f.contains(&e)).count(), 2);
        }
    }
}
