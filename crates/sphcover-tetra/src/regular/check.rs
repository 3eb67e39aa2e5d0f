//! Validity checks for tests: the structure (symmetric adjacency, shared faces, positive
//! orientation, exactly the vertices in use), local regularity across every face, and the
//! brute-force empty power sphere test.
//!
//! They never run during a construction, and they ask the construction's own conflict
//! test, so a fault in the stitching shows without a second implementation of the
//! predicates.

use super::conflict::conflict;
use super::prepare::distinct_points;
use super::{Geometry, INFINITE_VERTEX, NO_TET, RegularTriangulation, VertexStatus, face_key};
use crate::predicates::{Point, orient3d};

impl RegularTriangulation {
    /// Brute-force validity check, `O(T · n)` (for tests): the structure is sound (see
    /// [`Self::check_local_regularity`]) and no point other than a dropped duplicate is in
    /// conflict with any tetrahedron, finite or infinite: vertices satisfy the empty power
    /// sphere condition, hidden points are truly redundant, and the hull is convex.
    /// Returns the first violation found.
    pub fn check_validity(&self) -> Result<(), String> {
        self.check_structure()?;
        let in_conflict = self.conflict_test();
        for t in 0..self.cells.len() as u32 {
            if !self.is_live(t) {
                continue;
            }
            for v in 0..self.num_points() as u32 {
                if self.status[v as usize] == VertexStatus::Duplicate
                    || self.cells[t as usize].v.contains(&v)
                {
                    continue;
                }
                if in_conflict(t, v) {
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
        let in_conflict = self.conflict_test();
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
                if v != INFINITE_VERTEX && in_conflict(t, v) {
                    return Err(format!(
                        "vertex {v} of tet {n} conflicts with its neighbour {t}"
                    ));
                }
            }
        }
        Ok(())
    }

    /// The construction's conflict test on this triangulation, with the ranks of the
    /// symbolic perturbation recomputed (the construction drops them when it is done).
    fn conflict_test(&self) -> impl Fn(u32, u32) -> bool + '_ {
        let points: Vec<Point> = self.geometry.pw.iter().map(|q| q.p).collect();
        let weights: Vec<f64> = self.geometry.pw.iter().map(|q| q.w).collect();
        let mut status = vec![VertexStatus::Vertex; points.len()];
        let mut rank = vec![0u32; points.len()];
        distinct_points(&points, &weights, &mut status, &mut rank);
        let geometry = Geometry {
            pw: self.geometry.pw.clone(),
            grid: None,
            grid_inverse_unit: 0.0,
            grid_orient_limit: 0.0,
            rank,
        };
        move |t, v| conflict(&self.cells[..], &geometry, t, v) == Some(true)
    }

    fn check_structure(&self) -> Result<(), String> {
        let mut used = vec![false; self.num_points()];
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
