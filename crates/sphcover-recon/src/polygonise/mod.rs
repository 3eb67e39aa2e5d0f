//! Polygonisation of the zero set of a cover's function by surface nets visited only near the
//! surface (thesis §5.2.3, Appendix C).
//!
//! The method is described on [`polygonise()`].

mod bricks;
mod cell;
mod extract;
mod fans;
mod field;
mod grid;
mod pinholes;
mod search;
mod trim;
mod tubes;

use sphcover_core::{ParameterError, PointIndex, PointIndexError, PuEvaluator, TriMesh};
use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;

use bricks::brick_of;
use extract::extract;
use fans::resolve_fans;
pub use field::{FieldPiece, PiecewiseFunction};
use grid::{Grid, KeyMap, grid_step, pack_clamped, unpack_clamped};
use search::{Search, project_seeds};
pub use trim::UnseenTrim;
pub(crate) use trim::trimming_points;
use trim::{trim, trim_unseen};

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
    /// Without `trim`: drop the regions of surface that the scanner did not see, keep those
    /// that close holes (see [`UnseenTrim`]).
    pub unseen: Option<UnseenTrim>,
    /// Attach per-vertex outward unit normals `−∇f / ‖∇f‖`.
    pub normals: bool,
    /// Fill the tunnels through the inside that are one or two grid vertices wide (see
    /// [`polygonise`], *Pinholes*).
    pub fill_pinholes: bool,
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
            unseen: None,
            normals: true,
            fill_pinholes: true,
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
    #[error(transparent)]
    InvalidParameter(#[from] ParameterError),
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
    /// The pieces of a [`PiecewiseFunction`] are not one per box of its split planes, or
    /// the planes are not finite and in ascending order.
    #[error(
        "{pieces} pieces for {boxes} boxes, or split planes that are not finite and in ascending order"
    )]
    PieceLayout {
        /// Pieces given.
        pieces: usize,
        /// Boxes the split planes make.
        boxes: usize,
    },
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
    /// Share of the surface's area that [`PolygoniseParams::unseen`] removed.
    pub unseen_area_fraction: f64,
    /// Tunnels one or two grid vertices wide filled ([`PolygoniseParams::fill_pinholes`]).
    pub pinholes_filled: usize,
    /// Faces where both cells' polygons use both crossing segments (a tube through the
    /// face): each segment got a vertex of its own on the face.
    pub tube_faces: usize,
    /// Vertices split because their triangles formed several closed fans.
    pub split_vertices: usize,
    /// Triangles removed at vertices where a boundary pinched them (open fans beside
    /// another fan), so that boundaries share their vertices.
    pub pinch_triangles: usize,
    /// Time spent evaluating `f` at grid vertices (part of the search).
    pub evaluation_time: Duration,
    /// Time of the search over cells, from the seeds.
    pub search_time: Duration,
    /// Time of placing vertices (with their Newton step) and building triangles.
    pub extraction_time: Duration,
    /// Total time.
    pub total_time: Duration,
}

/// Polygonises the zero set of `eval`'s function near `seeds` (method below).
///
/// Returns a mesh in the cover's units, wound counter-clockwise seen from outside, closed
/// wherever the surface is closed and `f` defined around it.
///
/// Seeds should be samples the caller trusts (high confidence, not outliers): every surface
/// component that passes through a seed's cell, or that a seed's Newton steps reach within
/// [`PolygoniseParams::seed_reach`], is meshed, including a small piece of `f = 0` around
/// an outlier that was given as a seed. [`sphcover_core::remove_small_components`] removes such
/// pieces afterwards if needed.
///
/// The grid is uniform with step `h`; `f` is sampled at grid vertices. A cell is *active* when
/// `f` is defined at its 8 corners (some support covers each of them) and the corners do not
/// all lie on one side (inside is `f > 0`, the sign convention of the cover). Surface nets put
/// one vertex per surface sheet in every active cell and, for every grid edge whose ends lie
/// on opposite sides, one quad joining the vertices of the four cells around that edge.
///
/// # Continuation from seeds
///
/// Only active cells are ever visited: from the cells holding the seed points (samples the
/// caller trusts) and, for seeds not next to the surface (noise), from where Newton steps
/// pull them onto `f = 0`, a breadth-first search crosses
/// from an active cell to the three other cells around each of its crossing edges. So the
/// cost follows the area of the surface, not the volume of the box, and a spurious sheet far
/// from every seed is never meshed. Each round of the search evaluates the new grid vertices
/// of its frontier in one parallel batch ([`PuEvaluator::values`]).
///
/// # A 2-manifold
///
/// Plain surface nets give one vertex per cell, which pinches two sheets passing through one
/// cell into a non-manifold vertex. Here the crossing edges of a cell are grouped into the
/// closed polygons marching cubes would build in that cell (on each face the crossings are
/// paired; a face with four crossings is resolved by the asymptotic decider, the sign of the
/// bilinear interpolant at its saddle, which both cells sharing the face compute from the
/// same four values, so they agree), and each polygon gets its own vertex, as in manifold
/// dual contouring. The star of such a vertex is the ring of quads around the polygon's
/// edges, a disc. Where the meshed region ends (undefined `f`, trimming) a vertex can keep
/// two separate fans; it is then split into one vertex per fan. One saddle configuration
/// needs more: when the polygons of both cells sharing a face each use both segments of that
/// face, the surface runs through the face as a tube, and the edge between the two cells'
/// vertices would carry four quads. Such a *tube face* gets one vertex per segment (the mean
/// of its two crossings), inserted between the two cells' vertices in the quads of that
/// segment's edges, so each of those edges is shared by two polygons. It is rare (no real
/// scan measured has one) and leaves every other quad as it was.
///
/// # Pinholes
///
/// A wall about one cell thick is held by a single layer of inside grid vertices; where `f`
/// dips below zero at one vertex of that layer, or at two beside each other, the mesh would
/// get a tunnel through the wall a cell or two wide, a handle finer than the grid can show.
/// With [`PolygoniseParams::fill_pinholes`] such vertices are set inside before extraction
/// when, under the connectivity the extraction itself gives the two sides, filling them
/// joins one ring of the inside around them and parts the outside around them into pieces
/// that are joined to each other, around them, within a few dozen grid steps: the fill
/// then closes a small handle, and never bridges a gap or seals off a cavity.
///
/// # Orientation and placement
///
/// Triangles are wound counter-clockwise seen from outside (from `f < 0`). A vertex sits at
/// the mean of its polygon's edge crossings (linear interpolation of `f` along each edge),
/// optionally moved by one Newton step `x − f ∇f / ‖∇f‖²` onto `f = 0`, kept inside its cell.
///
/// # Determinism
///
/// The set of active cells is the union of the surface components reached from the seeds in
/// their given order; values are pure functions of grid positions; the mesh is written in
/// ascending cell order. So the output is bit-identical whatever the thread count.
///
/// # Layout
///
/// One file per phase, in the order they run: `grid` (the grid and its keys), `search` (the
/// cells visited from the seeds) over `bricks` (the values of `f`, evaluated in batches) and
/// `cell` (one cube's sheets), `pinholes` (tunnels one or two vertices wide), `extract`
/// (vertices and quads) with `tubes` (tube faces), then `trim` and `fans` on the finished
/// mesh.
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
    check_params(params)?;
    let field = PiecewiseFunction::single(FieldPiece { eval, blend })?;
    polygonise_piecewise(&field, seeds, params)
}

/// [`polygonise_blending`] of a function given piecewise (the tiles of a tiled
/// reconstruction): every point, grid vertex or mesh vertex, is answered by the one piece
/// whose box holds it, so the cells on both sides of a seam read the same values at their
/// shared corners and the mesh is as closed across seams as anywhere else. The blend is
/// attached when every piece carries values to blend.
pub fn polygonise_piecewise(
    field: &PiecewiseFunction<'_>,
    seeds: &[DVec3],
    params: &PolygoniseParams,
) -> Result<(TriMesh, PolygoniseStats), PolygoniseError> {
    polygonise_piecewise_indexed(field, seeds, None, params)
}

/// [`polygonise_piecewise`] given a point index over `seeds` (built by [`PointIndex::new`]
/// from exactly those points), which the trim then asks for its distances instead of
/// indexing the seeds again: a reconstruction whose seeds are all its samples has that index
/// already.
pub(crate) fn polygonise_piecewise_indexed(
    field: &PiecewiseFunction<'_>,
    seeds: &[DVec3],
    seed_index: Option<&PointIndex>,
    params: &PolygoniseParams,
) -> Result<(TriMesh, PolygoniseStats), PolygoniseError> {
    debug_assert!(seed_index.is_none_or(|index| index.input_len() == seeds.len()));
    let start = Instant::now();
    let (mut mesh, mut stats) = polygonise_untrimmed(field, seeds, params)?;
    let distance2 = match trimming_points(&mesh, params) {
        Some(points) => {
            let built;
            let index = match seed_index {
                Some(index) => index,
                None => {
                    built = PointIndex::new(&finite(seeds))?;
                    &built
                }
            };
            Some(match (params.trim, &params.unseen) {
                (None, Some(unseen)) => trim::unseen_distances_squared(&mesh, index, unseen.near),
                _ => trim::distances_squared(&points, index),
            })
        }
        None => None,
    };
    trim_and_resolve(&mut mesh, distance2.as_deref(), params, &mut stats);
    stats.total_time = start.elapsed();
    Ok((mesh, stats))
}

/// [`polygonise_piecewise`] up to the mesh as extracted: neither trimmed nor with its fans
/// resolved ([`trim_and_resolve`] does both).
pub(crate) fn polygonise_untrimmed(
    field: &PiecewiseFunction<'_>,
    seeds: &[DVec3],
    params: &PolygoniseParams,
) -> Result<(TriMesh, PolygoniseStats), PolygoniseError> {
    let start = Instant::now();
    check_params(params)?;
    let finite_seeds = finite(seeds);
    if finite_seeds.is_empty() {
        return Err(PolygoniseError::NoSeeds { given: seeds.len() });
    }
    let step = grid_step(params.step, &finite_seeds, field)?;
    let grid = Grid::around(field, step)?;

    let mut stats = PolygoniseStats {
        step,
        seeds_dropped: seeds.len() - finite_seeds.len(),
        ..PolygoniseStats::default()
    };
    let mut search = Search::new(field, &grid, params.max_cells);
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
    for (p, seed) in project_seeds(field, &unmet).into_iter().zip(&unmet) {
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

    if params.fill_pinholes {
        stats.pinholes_filled = pinholes::fill_pinholes(&mut search);
    }
    let extraction_start = Instant::now();
    let mesh = extract(&search, &grid, params, &mut stats);
    stats.extraction_time = extraction_start.elapsed();
    stats.total_time = start.elapsed();
    Ok((mesh, stats))
}

/// The trimming `params` ask for, given the squared distance to the nearest seed of each of
/// [`trimming_points`] (`None` when they ask for none), then the fans the extraction or the
/// trimming left resolved.
pub(crate) fn trim_and_resolve(
    mesh: &mut TriMesh,
    distance2: Option<&[f64]>,
    params: &PolygoniseParams,
    stats: &mut PolygoniseStats,
) {
    if let (Some(limit), Some(d2)) = (params.trim, distance2) {
        stats.trimmed_triangles = trim(mesh, d2, limit);
    } else if let (Some(unseen), Some(d2)) = (&params.unseen, distance2) {
        let removed = trim_unseen(mesh, d2, unseen);
        stats.trimmed_triangles = removed.triangles;
        stats.unseen_area_fraction = removed.area_fraction;
    }
    let fans = resolve_fans(mesh);
    stats.split_vertices = fans.split_vertices;
    stats.pinch_triangles = fans.removed_triangles;
}

/// The finite seeds. Seeds are most of a scan's samples: copied only when some must be left
/// out.
fn finite(seeds: &[DVec3]) -> std::borrow::Cow<'_, [DVec3]> {
    if seeds.par_iter().all(|p| p.is_finite()) {
        std::borrow::Cow::Borrowed(seeds)
    } else {
        seeds.iter().copied().filter(|p| p.is_finite()).collect()
    }
}

fn check_params(params: &PolygoniseParams) -> Result<(), PolygoniseError> {
    let invalid = |name, value, requirement| {
        Err(PolygoniseError::InvalidParameter(ParameterError {
            name,
            value,
            expected: requirement,
        }))
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
    if let Some(u) = &params.unseen {
        if !(u.near.is_finite() && u.near > 0.0) {
            return invalid("unseen.near", u.near, "finite and > 0");
        }
        if u.reach.is_nan() || u.reach < u.near {
            return invalid("unseen.reach", u.reach, "≥ unseen.near");
        }
    }
    if !(params.seed_reach.is_finite() && params.seed_reach >= 0.0) {
        return invalid("seed_reach", params.seed_reach, "finite and ≥ 0");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::MeshTopology;
    use sphcover_core::{Aabb, Cover, SurfaceCoverParams, SurfaceSamples, build_surface_cover};
    use sphcover_evaluation::{sphere, sphere_signed_distance, torus, torus_signed_distance};

    pub(super) fn cover_of(cloud: &sphcover_core::PointCloud) -> Cover {
        let normals = cloud.normals.as_ref().expect("fixtures carry normals");
        // A coarser tolerance than the default keeps the cover (and the test) small.
        let params = SurfaceCoverParams {
            eps: 5e-3,
            ..SurfaceCoverParams::default()
        };
        build_surface_cover(&SurfaceSamples::new(&cloud.positions, normals), &params)
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

    pub(super) fn params(depth: u32) -> PolygoniseParams {
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
        let values: Vec<f64> = cover.centres().iter().map(|c| c.x + 2.0 * c.z).collect();
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
        let (cover, _) = build_surface_cover(
            &SurfaceSamples::new(&points, &normals),
            &SurfaceCoverParams::default(),
        )
        .unwrap();
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
            Err(PolygoniseError::InvalidParameter(ParameterError {
                name: "step",
                ..
            }))
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
                Err(PolygoniseError::InvalidParameter(_))
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
}
