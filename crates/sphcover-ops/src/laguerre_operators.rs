//! A Laguerre (power-diagram) partition variant with the symmetric finite-volume structure.
//!
//! The method is described on [`LaguerreOperators`].

use glam::DVec3;
use rayon::prelude::*;

use crate::discrete_operators::DiscreteOperators;
use crate::pair_geometry::PairGeometry;

/// The convex polyhedron every power cell is clipped from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CellBound {
    /// The bounding box of the union of all balls: interior cells are the true power cells.
    CoverBox,
    /// The cube circumscribing the support's own ball, `c_i ± r_i` (a polyhedral stand-in
    /// for "the cell restricted to its ball").
    BallCube,
}

/// What building a [`LaguerreOperators`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LaguerreStats {
    /// Cells of zero volume (a support whose power cell is empty, e.g. nested in another).
    pub empty_cells: usize,
    /// Cells with a face on the bound (open: `Σ_j A_ij n_ij ≠ 0`).
    pub bounded_cells: usize,
    /// Largest `|A_ij − A_ji| / max(A_ij, A_ji)` over the pairs.
    pub max_face_mismatch: f64,
    /// Pairs with `A_ij ≠ A_ji` beyond rounding (relative 1e-9).
    pub mismatched_pairs: usize,
}

/// One cell's `(entry, face area)` list, volume and area on the bound.
type CellMeasure = (Vec<(usize, f64)>, f64, f64);

/// One face of a convex polyhedron: its polygon and what made it.
#[derive(Clone, Debug)]
struct Face {
    /// Entry index of the neighbour whose radical plane holds the face; `None` on the bound.
    entry: Option<usize>,
    /// Outward unit normal.
    normal: DVec3,
    /// Vertices in order around the face.
    vertices: Vec<DVec3>,
}

/// The six faces of the box `[lo, hi]`, outward normals, vertices counter-clockwise seen from
/// outside.
fn box_faces(lo: DVec3, hi: DVec3) -> Vec<Face> {
    let corner = |x: bool, y: bool, z: bool| {
        DVec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    let quad = |normal: DVec3, v: [DVec3; 4]| Face {
        entry: None,
        normal,
        vertices: v.to_vec(),
    };
    let (f, t) = (false, true);
    vec![
        quad(
            DVec3::NEG_X,
            [
                corner(f, f, f),
                corner(f, f, t),
                corner(f, t, t),
                corner(f, t, f),
            ],
        ),
        quad(
            DVec3::X,
            [
                corner(t, f, f),
                corner(t, t, f),
                corner(t, t, t),
                corner(t, f, t),
            ],
        ),
        quad(
            DVec3::NEG_Y,
            [
                corner(f, f, f),
                corner(t, f, f),
                corner(t, f, t),
                corner(f, f, t),
            ],
        ),
        quad(
            DVec3::Y,
            [
                corner(f, t, f),
                corner(f, t, t),
                corner(t, t, t),
                corner(t, t, f),
            ],
        ),
        quad(
            DVec3::NEG_Z,
            [
                corner(f, f, f),
                corner(f, t, f),
                corner(t, t, f),
                corner(t, f, f),
            ],
        ),
        quad(
            DVec3::Z,
            [
                corner(f, f, t),
                corner(t, f, t),
                corner(t, t, t),
                corner(f, t, t),
            ],
        ),
    ]
}

/// Clips the convex polyhedron `faces` by `normal · x ≤ offset`, adding the cut face (tagged
/// `entry`); `tolerance` is the distance below which a vertex counts as on the plane.
fn clip(faces: &mut Vec<Face>, normal: DVec3, offset: f64, entry: usize, tolerance: f64) {
    let outside = faces
        .iter()
        .flat_map(|f| &f.vertices)
        .any(|v| normal.dot(*v) - offset > tolerance);
    if !outside {
        return;
    }
    let mut cut: Vec<DVec3> = Vec::new();
    let mut kept = Vec::with_capacity(faces.len() + 1);
    for face in faces.drain(..) {
        let dist: Vec<f64> = face
            .vertices
            .iter()
            .map(|v| {
                let s = normal.dot(*v) - offset;
                if s.abs() <= tolerance { 0.0 } else { s }
            })
            .collect();
        if dist.iter().all(|&s| s <= 0.0) {
            cut.extend(
                face.vertices
                    .iter()
                    .zip(&dist)
                    .filter(|(_, s)| **s == 0.0)
                    .map(|(v, _)| *v),
            );
            kept.push(face);
            continue;
        }
        let n = face.vertices.len();
        let mut out = Vec::with_capacity(n + 1);
        for k in 0..n {
            let (a, b) = (face.vertices[k], face.vertices[(k + 1) % n]);
            let (da, db) = (dist[k], dist[(k + 1) % n]);
            if da <= 0.0 {
                out.push(a);
                if da == 0.0 {
                    cut.push(a);
                }
            }
            if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
                let p = a + (b - a) * (da / (da - db));
                out.push(p);
                cut.push(p);
            }
        }
        if out.len() >= 3 {
            kept.push(Face {
                vertices: out,
                ..face
            });
        }
    }
    *faces = kept;
    if let Some(polygon) = convex_polygon(&cut, normal, tolerance) {
        faces.push(Face {
            entry: Some(entry),
            normal,
            vertices: polygon,
        });
    }
}

/// The points (on a plane of unit normal `normal`), deduplicated and ordered
/// counter-clockwise seen from the side `normal` points to; `None` below three points.
fn convex_polygon(points: &[DVec3], normal: DVec3, tolerance: f64) -> Option<Vec<DVec3>> {
    let mut unique: Vec<DVec3> = Vec::with_capacity(points.len());
    for p in points {
        if !unique.iter().any(|q| (*q - *p).length() <= tolerance) {
            unique.push(*p);
        }
    }
    if unique.len() < 3 {
        return None;
    }
    let centre = unique.iter().copied().sum::<DVec3>() / unique.len() as f64;
    let (e1, e2) = normal.any_orthonormal_pair();
    let mut angled: Vec<(f64, DVec3)> = unique
        .into_iter()
        .map(|p| {
            let d = p - centre;
            (d.dot(e2).atan2(d.dot(e1)), p)
        })
        .collect();
    angled.sort_by(|a, b| a.0.total_cmp(&b.0));
    Some(angled.into_iter().map(|(_, p)| p).collect())
}

/// Area of a planar polygon.
fn polygon_area(vertices: &[DVec3]) -> f64 {
    let v0 = vertices[0];
    let mut sum = DVec3::ZERO;
    for k in 1..vertices.len() - 1 {
        sum += (vertices[k] - v0).cross(vertices[k + 1] - v0);
    }
    0.5 * sum.length()
}

/// The power-cell operators of a cover (method below).
///
/// The power cell of support `i` is `{x : |x − c_i|² − r_i² ≤ |x − c_j|² − r_j² ∀ j}`; within
/// the union of the balls only intersecting balls can share a face (a face point has equal,
/// non-positive power for both). Here the cell is computed from the graph neighbours only:
/// a convex polyhedron (the bound, [`CellBound`]) clipped by the radical plane
/// `n_ij · (x − c_i) ≤ l_i` of every neighbour (`n_ij = (c_j − c_i)/d_ij`,
/// `l_i = (d² + r_i² − r_j²)/(2d)`, thesis eq. 4.33), which gives the face areas `A_ij`, the
/// cell volume `V_i` and the area of the cell's faces on the bound. Then
///
/// ```text
/// Lap(u)_i  = (1/V_i) Σ_j (Ā_ij / d_ij) (u_j − u_i)          Ā_ij = (A_ij + A_ji)/2, symmetric
/// Grad(u)_i = (1/2V_i) Σ_j A_ij n_ij (u_j − u_i)
/// Div(v)_i  = (1/2V_i) Σ_j A_ij n_ij · (v_j − v_i)
/// Curl(v)_i = (1/2V_i) Σ_j A_ij n_ij × (v_j − v_i)
/// ```
///
/// The difference forms equal the central-flux forms `(1/V)Σ A n·(v_i + v_j)/2` wherever the
/// cell is closed by neighbour faces (`Σ_j A_ij n_ij = 0`), and vanish on constants exactly
/// everywhere. `Lap` is `V⁻¹(W − diag(W·1))` with the symmetric `W = [Ā_ij/d_ij]`: symmetric
/// and negative semi-definite like the thesis form, so it can go into conjugate gradients.
/// For closed cells `Lap` of a linear field is `a · Σ_j A_ij n_ij = 0` to rounding (faces are
/// perpendicular to `c_j − c_i`); it is not exact on quadratics unless the radii are equal
/// (Voronoi) and the face centroids lie on the centre lines; the consistency example measures
/// by how much.
///
/// The cell of `i` uses only `i`'s neighbours, so `A_ij` (from `i`'s cell) and `A_ji` (from
/// `j`'s) agree only when both cells see every plane that cuts them; build the graph with
/// shrink factor 1 (every intersecting pair) for that. [`LaguerreStats`] reports the largest
/// mismatch.
#[derive(Clone, Debug)]
pub struct LaguerreOperators {
    centres: Vec<DVec3>,
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    face_area: Vec<f64>,
    symmetric_area: Vec<f64>,
    volume: Vec<f64>,
    bound_area: Vec<f64>,
    stats: LaguerreStats,
}

impl LaguerreOperators {
    /// Computes every support's cell over the graph of `geometry`, in parallel (the result does
    /// not depend on the thread count).
    pub fn new(geometry: &PairGeometry, bound: CellBound) -> LaguerreOperators {
        let c = geometry.centres();
        let r = geometry.radii();
        let n = geometry.len();
        let (lo, hi) = c.iter().zip(r).fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), (&ci, &ri)| (lo.min(ci - ri), hi.max(ci + ri)),
        );
        let offsets = geometry.offsets();
        let neighbours = geometry.neighbour_array();
        let cells: Vec<CellMeasure> = (0..n)
            .into_par_iter()
            .map(|i| {
                let (ci, ri) = (c[i], r[i]);
                let mut faces = match bound {
                    CellBound::CoverBox => box_faces(lo, hi),
                    CellBound::BallCube => box_faces(ci - ri, ci + ri),
                };
                let tolerance = 1e-12 * ri.max(f64::MIN_POSITIVE);
                // Nearest planes first: the cell shrinks fastest, later clips are cheap.
                let mut planes: Vec<(f64, usize, DVec3)> = (offsets[i] as usize
                    ..offsets[i + 1] as usize)
                    .filter_map(|k| {
                        let j = neighbours[k] as usize;
                        let delta = c[j] - ci;
                        let d = delta.length();
                        (d > 0.0).then(|| {
                            let l = (d * d + ri * ri - r[j] * r[j]) / (2.0 * d);
                            (l, k, delta / d)
                        })
                    })
                    .collect();
                planes.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                for (l, k, normal) in planes {
                    if faces.len() < 4 {
                        faces.clear();
                        break;
                    }
                    clip(&mut faces, normal, normal.dot(ci) + l, k, tolerance);
                }
                let mut areas = Vec::new();
                let (mut volume, mut bound_area) = (0.0, 0.0);
                if faces.len() >= 4 {
                    for face in &faces {
                        let area = polygon_area(&face.vertices);
                        volume += area * face.normal.dot(face.vertices[0] - ci) / 3.0;
                        match face.entry {
                            Some(k) => areas.push((k, area)),
                            None => bound_area += area,
                        }
                    }
                }
                if volume <= 0.0 || !volume.is_finite() {
                    return (Vec::new(), 0.0, 0.0);
                }
                (areas, volume, bound_area)
            })
            .collect();
        let mut face_area = vec![0.0; neighbours.len()];
        let mut volume = vec![0.0; n];
        let mut bound_area = vec![0.0; n];
        for (i, (areas, v, b)) in cells.into_iter().enumerate() {
            for (k, a) in areas {
                face_area[k] += a;
            }
            volume[i] = v;
            bound_area[i] = b;
        }
        let mut stats = LaguerreStats {
            empty_cells: volume.iter().filter(|&&v| v == 0.0).count(),
            bounded_cells: bound_area.iter().filter(|&&b| b > 0.0).count(),
            ..LaguerreStats::default()
        };
        let mut symmetric_area = vec![0.0; neighbours.len()];
        for i in 0..n {
            for k in offsets[i] as usize..offsets[i + 1] as usize {
                let j = neighbours[k] as usize;
                let row = &neighbours[offsets[j] as usize..offsets[j + 1] as usize];
                let back = row
                    .binary_search(&(i as u32))
                    .ok()
                    .map(|p| face_area[offsets[j] as usize + p])
                    .unwrap_or(0.0);
                let (a, b) = (face_area[k], back);
                symmetric_area[k] = 0.5 * (a + b);
                let big = a.max(b);
                if big > 0.0 {
                    let mismatch = (a - b).abs() / big;
                    stats.max_face_mismatch = stats.max_face_mismatch.max(mismatch);
                    stats.mismatched_pairs += usize::from(mismatch > 1e-9);
                }
            }
        }
        stats.mismatched_pairs /= 2;
        LaguerreOperators {
            centres: c.to_vec(),
            offsets: offsets.to_vec(),
            neighbours: neighbours.to_vec(),
            face_area,
            symmetric_area,
            volume,
            bound_area,
            stats,
        }
    }

    /// What the build found.
    pub fn stats(&self) -> LaguerreStats {
        self.stats
    }

    /// `A_ij` of every stored entry, from the cell of the entry's row.
    pub fn face_areas(&self) -> &[f64] {
        &self.face_area
    }

    /// `Ā_ij = (A_ij + A_ji)/2` of every stored entry (symmetric).
    pub fn symmetric_face_areas(&self) -> &[f64] {
        &self.symmetric_area
    }

    /// `V_i` per support (0 for an empty cell).
    pub fn volumes(&self) -> &[f64] {
        &self.volume
    }

    /// Area of each cell's faces on the bound (0 for a cell closed by neighbour faces).
    pub fn bound_areas(&self) -> &[f64] {
        &self.bound_area
    }

    /// `y = (W − diag(W·1)) x` with `W = [Ā_ij / d_ij]`: symmetric, negative semi-definite.
    pub fn apply_stiffness(&self, x: &[f64], y: &mut [f64]) {
        assert_eq!(x.len(), self.len(), "x has the wrong length");
        assert_eq!(y.len(), self.len(), "y has the wrong length");
        y.par_iter_mut().enumerate().for_each(|(i, yi)| {
            let mut acc = 0.0;
            for k in self.offsets[i] as usize..self.offsets[i + 1] as usize {
                let j = self.neighbours[k] as usize;
                let d = (self.centres[j] - self.centres[i]).length();
                if d > 0.0 {
                    acc += self.symmetric_area[k] / d * (x[j] - x[i]);
                }
            }
            *yi = acc;
        });
    }

    /// `(1/2V_i) Σ_j A_ij n_ij ⊗ (difference)` per support, zero for empty cells.
    fn flux<T, F>(&self, combine: F) -> Vec<T>
    where
        T: Default + Send + std::ops::AddAssign + std::ops::Mul<f64, Output = T>,
        F: Fn(usize, usize, DVec3) -> T + Sync,
    {
        (0..self.len())
            .into_par_iter()
            .map(|i| {
                let v = self.volume[i];
                if v <= 0.0 {
                    return T::default();
                }
                let mut acc = T::default();
                for k in self.offsets[i] as usize..self.offsets[i + 1] as usize {
                    let j = self.neighbours[k] as usize;
                    let delta = self.centres[j] - self.centres[i];
                    let d = delta.length();
                    if d > 0.0 && self.face_area[k] > 0.0 {
                        acc += combine(i, j, delta * (self.face_area[k] / d));
                    }
                }
                acc * (0.5 / v)
            })
            .collect()
    }
}

impl DiscreteOperators for LaguerreOperators {
    fn len(&self) -> usize {
        self.centres.len()
    }

    fn grad(&self, u: &[f64]) -> Vec<DVec3> {
        assert_eq!(u.len(), self.len(), "u has the wrong length");
        self.flux(|i, j, area_normal| area_normal * (u[j] - u[i]))
    }

    fn div(&self, v: &[DVec3]) -> Vec<f64> {
        assert_eq!(v.len(), self.len(), "v has the wrong length");
        self.flux(|i, j, area_normal| area_normal.dot(v[j] - v[i]))
    }

    fn lap(&self, u: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; u.len()];
        self.apply_stiffness(u, &mut out);
        for (o, &v) in out.iter_mut().zip(&self.volume) {
            *o = if v > 0.0 { *o / v } else { 0.0 };
        }
        out
    }

    fn curl(&self, v: &[DVec3]) -> Vec<DVec3> {
        assert_eq!(v.len(), self.len(), "v has the wrong length");
        self.flux(|i, j, area_normal| area_normal.cross(v[j] - v[i]))
    }
}
