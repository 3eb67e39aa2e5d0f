//! A thin-walled CAD part of known genus: an open-top housing with walls, ribs, fins, bosses,
//! bores, slots and windows, as a closed triangle mesh for synthetic scans.
//!
//! The part is built from axis-aligned boxes added to and cut from a solid in order
//! ([`BoxSolid`]). Its boundary then lies on the rectilinear grid of every box face, so the
//! mesh is exact: sharp edges stay sharp, each thin wall has its true thickness, and the
//! genus is known by construction (each bore, slot or window through a wall adds one handle).

use sphcover_core::{DVec3, TriMesh};

/// One step of a [`BoxSolid`]: a box added to the solid or cut from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BoxStep {
    /// The box (lower and upper corners) becomes solid.
    Add(DVec3, DVec3),
    /// The box becomes empty.
    Cut(DVec3, DVec3),
}

/// A solid made of axis-aligned boxes, added and cut in order (a later step wins).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BoxSolid {
    /// The steps, applied in order.
    pub steps: Vec<BoxStep>,
}

impl BoxSolid {
    /// Whether `p` is in the solid. Points on a box face count as in the box, so query cell
    /// centres, not grid points.
    pub fn contains(&self, p: DVec3) -> bool {
        let mut inside = false;
        for step in &self.steps {
            let (lo, hi, add) = match *step {
                BoxStep::Add(lo, hi) => (lo, hi, true),
                BoxStep::Cut(lo, hi) => (lo, hi, false),
            };
            if p.cmpge(lo).all() && p.cmple(hi).all() {
                inside = add;
            }
        }
        inside
    }

    /// The boundary of the solid as a closed triangle mesh, counter-clockwise seen from
    /// outside. Every box face lies on a line of one rectilinear grid, so the boundary is a
    /// union of grid-cell faces that share their edges and corners exactly. The mesh is
    /// manifold when no two solid cells meet only along an edge or at a corner.
    pub fn boundary_mesh(&self) -> TriMesh {
        let lines: [Vec<f64>; 3] = std::array::from_fn(|axis| {
            let mut v: Vec<f64> = self
                .steps
                .iter()
                .flat_map(|s| {
                    let (BoxStep::Add(lo, hi) | BoxStep::Cut(lo, hi)) = *s;
                    [lo[axis], hi[axis]]
                })
                .collect();
            v.sort_by(f64::total_cmp);
            v.dedup();
            v
        });
        let cells = [lines[0].len() - 1, lines[1].len() - 1, lines[2].len() - 1];
        let cell_index = |c: [usize; 3]| c[0] + cells[0] * (c[1] + cells[1] * c[2]);
        let mut solid = vec![false; cells[0] * cells[1] * cells[2]];
        for k in 0..cells[2] {
            for j in 0..cells[1] {
                for i in 0..cells[0] {
                    let centre = DVec3::new(
                        0.5 * (lines[0][i] + lines[0][i + 1]),
                        0.5 * (lines[1][j] + lines[1][j + 1]),
                        0.5 * (lines[2][k] + lines[2][k + 1]),
                    );
                    solid[cell_index([i, j, k])] = self.contains(centre);
                }
            }
        }
        let is_solid = |c: [isize; 3]| -> bool {
            (0..3).all(|a| c[a] >= 0 && (c[a] as usize) < cells[a])
                && solid[cell_index(c.map(|x| x as usize))]
        };

        let points = [lines[0].len(), lines[1].len(), lines[2].len()];
        let mut vertex_of = vec![u32::MAX; points[0] * points[1] * points[2]];
        let mut vertices = Vec::new();
        let mut vertex = |g: [usize; 3]| -> u32 {
            let slot = &mut vertex_of[g[0] + points[0] * (g[1] + points[1] * g[2])];
            if *slot == u32::MAX {
                *slot = vertices.len() as u32;
                vertices.push(DVec3::new(lines[0][g[0]], lines[1][g[1]], lines[2][g[2]]));
            }
            *slot
        };
        let mut triangles = Vec::new();
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            // Grid planes across `axis`, between cell `p - 1` and cell `p`.
            for p in 0..points[axis] {
                for a in 0..cells[u] {
                    for b in 0..cells[v] {
                        let mut below = [0isize; 3];
                        below[axis] = p as isize - 1;
                        below[u] = a as isize;
                        below[v] = b as isize;
                        let mut above = below;
                        above[axis] += 1;
                        let (s0, s1) = (is_solid(below), is_solid(above));
                        if s0 == s1 {
                            continue;
                        }
                        let corner = |da: usize, db: usize| {
                            let mut g = [0usize; 3];
                            g[axis] = p;
                            g[u] = a + da;
                            g[v] = b + db;
                            g
                        };
                        let q = [
                            vertex(corner(0, 0)),
                            vertex(corner(1, 0)),
                            vertex(corner(1, 1)),
                            vertex(corner(0, 1)),
                        ];
                        // (u, v, axis) is right-handed: q runs counter-clockwise seen from
                        // +axis, which is outside when the solid cell is below.
                        if s0 {
                            triangles.push([q[0], q[1], q[2]]);
                            triangles.push([q[0], q[2], q[3]]);
                        } else {
                            triangles.push([q[0], q[2], q[1]]);
                            triangles.push([q[0], q[3], q[2]]);
                        }
                    }
                }
            }
        }
        TriMesh::new(vertices, triangles)
    }
}

/// The thin-walled housing and what is known about it.
#[derive(Clone, Debug, PartialEq)]
pub struct ThinWalledPart {
    /// The solid.
    pub solid: BoxSolid,
    /// The genus of its surface, by construction.
    pub genus: u32,
    /// The thinnest wall (fins), in the part's units (millimetres).
    pub thinnest_wall: f64,
    /// The narrowest gap between walls (between ribs), in millimetres.
    pub narrowest_gap: f64,
}

/// An open-top housing of 100 × 70 × 40 mm with 6 mm of fins on one side (bounding-box
/// diagonal 133.2 mm): side walls 1.6 mm, floor 2.4 mm, nine internal ribs 1.0 mm thick with
/// gaps of 1.3 mm, a cross rib, four square bosses with bores through the floor, five vent
/// slots in the floor, a window in each of two walls, and fourteen fins 0.7 mm thick with gaps
/// of 1.5 mm. Walls are 0.5–1.8% of the diagonal, gaps 1.0–1.1%. Genus 11: four bores, five
/// slots, two windows.
pub fn thin_walled_housing() -> ThinWalledPart {
    let b = |lo: [f64; 3], hi: [f64; 3]| (DVec3::from(lo), DVec3::from(hi));
    let add = |(lo, hi)| BoxStep::Add(lo, hi);
    let cut = |(lo, hi)| BoxStep::Cut(lo, hi);
    let (wall, floor, top) = (1.6, 2.4, 40.0);
    let mut steps = vec![
        add(b([0.0, 0.0, 0.0], [100.0, 70.0, top])),
        cut(b(
            [wall, wall, floor],
            [100.0 - wall, 70.0 - wall, top + 1.0],
        )),
    ];
    // Internal ribs across the housing, wall to wall.
    let (rib, rib_gap) = (1.0, 1.3);
    for i in 0..9 {
        let x = 10.0 + i as f64 * (rib + rib_gap);
        steps.push(add(b([x, wall, floor], [x + rib, 70.0 - wall, 17.0])));
    }
    // A lower cross rib from the far wall.
    steps.push(add(b([40.0, 34.5, floor], [100.0 - wall, 35.5, 12.0])));
    // Bosses, then their bores through boss and floor.
    let bosses = [[55.0, 15.0], [85.0, 15.0], [55.0, 55.0], [85.0, 55.0]];
    for [x, y] in bosses {
        steps.push(add(b([x - 3.0, y - 3.0, floor], [x + 3.0, y + 3.0, 20.0])));
    }
    for [x, y] in bosses {
        steps.push(cut(b([x - 1.2, y - 1.2, -1.0], [x + 1.2, y + 1.2, 21.0])));
    }
    // Vent slots through the floor.
    for i in 0..5 {
        let x = 63.0 + i as f64 * 3.2;
        steps.push(cut(b([x, 45.0, -1.0], [x + 1.6, 62.0, floor + 1.0])));
    }
    // Windows through two side walls.
    steps.push(cut(b([30.0, -1.0, 20.0], [45.0, wall + 1.0, 30.0])));
    steps.push(cut(b([-1.0, 20.0, 25.0], [wall + 1.0, 50.0, 32.0])));
    // Cooling fins outside the wall at x = 100.
    let (fin, fin_gap) = (0.7, 1.5);
    for i in 0..14 {
        let z = 6.0 + i as f64 * (fin + fin_gap);
        steps.push(add(b([100.0, 10.0, z], [106.0, 60.0, z + fin])));
    }
    ThinWalledPart {
        solid: BoxSolid { steps },
        genus: 11,
        thinnest_wall: fin,
        narrowest_gap: rib_gap,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use sphcover_core::MeshTopology;

    #[test]
    fn the_housing_is_a_closed_manifold_of_its_stated_genus() {
        let part = thin_walled_housing();
        let mesh = part.solid.boundary_mesh();
        let topology = MeshTopology::of(&mesh);
        assert!(topology.is_closed_oriented_manifold());
        assert_eq!(topology.component_sizes().len(), 1);
        assert_eq!(topology.euler_characteristic(), 2 - 2 * part.genus as i64);
        let diagonal = sphcover_core::Aabb::from_points(&mesh.vertices).diagonal();
        assert!((diagonal - 133.2).abs() < 0.1, "{diagonal}");
        assert!(part.thinnest_wall / diagonal > 0.005);
    }

    #[test]
    fn the_mesh_encloses_the_solid_with_outward_triangles() {
        // The signed volume of the mesh is the solid's volume, which random points measure.
        let part = thin_walled_housing();
        let volume = crate::ground_truth_meshes::signed_volume(&part.solid.boundary_mesh());
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let (lo, hi) = (DVec3::ZERO, DVec3::new(106.0, 70.0, 40.0));
        let n = 400_000;
        let inside = (0..n)
            .filter(|_| {
                let t = DVec3::new(rng.random(), rng.random(), rng.random());
                part.solid.contains(lo + t * (hi - lo))
            })
            .count();
        let sampled = inside as f64 / n as f64 * (hi - lo).element_product();
        assert!(
            (volume - sampled).abs() < 0.02 * volume,
            "{volume} {sampled}"
        );
    }

    #[test]
    fn later_steps_win() {
        let solid = BoxSolid {
            steps: vec![
                BoxStep::Add(DVec3::ZERO, DVec3::ONE),
                BoxStep::Cut(DVec3::splat(0.25), DVec3::splat(0.75)),
                BoxStep::Add(DVec3::splat(0.4), DVec3::splat(0.6)),
            ],
        };
        assert!(solid.contains(DVec3::splat(0.1)));
        assert!(!solid.contains(DVec3::splat(0.3)));
        assert!(solid.contains(DVec3::splat(0.5)));
        assert!(!solid.contains(DVec3::splat(2.0)));
    }
}
