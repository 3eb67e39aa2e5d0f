//! Surface-net extraction: one vertex per sheet of every active cell (moved by a Newton step
//! onto `f = 0` when asked), one quad around every crossing grid edge, in ascending cell
//! order.
//!
//! It runs once, on the finished search, and reads only what the search stored; numbering
//! the output here alone is what makes the mesh the same whatever order the search found the
//! cells in.

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{TriMesh, ValueGradient, remove_unused_vertices};

use super::bricks::BrickReader;
use super::cell::{ActiveCell, NO_SHEET, cells_and_edges_around, corner_offset, edge_ends};
use super::grid::{Grid, Index3, KeyMap, unpack};
use super::search::Search;
use super::tubes::{TubeFace, push_polygon_through_tubes, tube_faces};
use super::{PolygoniseParams, PolygoniseStats};

/// Builds the mesh from the active cells, in ascending cell order.
pub(super) fn extract(
    search: &Search,
    grid: &Grid,
    params: &PolygoniseParams,
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
        let fg: Vec<Option<ValueGradient>> = match search.eval.values_gradients_blends(&vertices) {
            Some(fgb) => {
                blended = Some(
                    fgb.par_iter()
                        .map(|r| r.map_or(0.0, |(_, b)| b))
                        .collect::<Vec<f64>>(),
                );
                fgb.into_par_iter().map(|r| r.map(|(vg, _)| vg)).collect()
            }
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
    if blended.is_none() {
        blended = search.eval.blend(&vertices);
    }
    let mut mesh = TriMesh::new(vertices, triangles);
    mesh.normals = if params.normals { normals } else { None };
    mesh.values = blended;
    remove_unused_vertices(&mut mesh);
    mesh
}

/// Where `f` crosses 0 on the cube edge from corner `a` (value `fa`) to corner `b` (value
/// `fb`), by linear interpolation, in cell units from the cell's origin.
pub(super) fn edge_crossing(a: usize, b: usize, fa: f64, fb: f64) -> DVec3 {
    let t = fa / (fa - fb);
    let pa = DVec3::from_array(corner_offset(a).map(|x| x as f64));
    let pb = DVec3::from_array(corner_offset(b).map(|x| x as f64));
    pa + (pb - pa) * t
}

/// Splits a quad into two triangles along its shorter diagonal.
pub(super) fn split_quad(tris: &mut Vec<[u32; 3]>, q: [u32; 4], vertices: &[DVec3]) {
    let x = q.map(|v| vertices[v as usize]);
    if x[0].distance_squared(x[2]) <= x[1].distance_squared(x[3]) {
        tris.extend([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
    } else {
        tris.extend([[q[0], q[1], q[3]], [q[1], q[2], q[3]]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::polygonise::{GridStep, polygonise};
    use sphcover_core::MeshTopology;
    use sphcover_core::{PuEvaluator, SurfaceCoverParams, SurfaceSamples, build_surface_cover};

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
        let (cover, _) =
            build_surface_cover(&SurfaceSamples::new(&points, &normals), &params).unwrap();
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
}
