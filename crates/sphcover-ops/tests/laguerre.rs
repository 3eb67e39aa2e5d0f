//! The power-cell (Laguerre) operators: cells against a sampling oracle, the exact cubes of a
//! regular grid, symmetry, and exactness on constants and (closed cells) linear fields.

use glam::DVec3;
use proptest::prelude::*;
use sphcover_core::{Aabb, SphereIntersectionGraph, synthetic};
use sphcover_ops::{CellBound, DiscreteOperators, LaguerreOperators, PairGeometry};

fn geometry(centres: &[DVec3], radii: &[f64]) -> PairGeometry {
    let graph = SphereIntersectionGraph::build(centres, radii, 1.0).unwrap();
    PairGeometry::build(centres, radii, &graph).unwrap()
}

fn power(c: DVec3, r: f64, x: DVec3) -> f64 {
    (x - c).length_squared() - r * r
}

#[test]
fn regular_grid_cells_are_cubes() {
    let h = 0.125;
    let domain = Aabb {
        min: DVec3::splat(-0.5),
        max: DVec3::splat(0.5),
    };
    let cover = synthetic::regular_grid(domain, h, 1.3).unwrap();
    let g = geometry(&cover.centres, &cover.radii);
    let ops = LaguerreOperators::new(&g, CellBound::CoverBox);
    assert_eq!(ops.stats().empty_cells, 0);
    let sq: Vec<f64> = cover.centres.iter().map(|c| c.length_squared()).collect();
    let lap = ops.lap(&sq);
    let div = ops.div(&cover.centres);
    let mut interior = 0;
    for i in 0..g.len() {
        if ops.bound_areas()[i] > 0.0 {
            continue;
        }
        interior += 1;
        assert!((ops.volumes()[i] - h * h * h).abs() < 1e-12, "support {i}");
        let range = g.offsets()[i] as usize..g.offsets()[i + 1] as usize;
        let faces: Vec<f64> = ops.face_areas()[range]
            .iter()
            .copied()
            .filter(|&a| a > 1e-12)
            .collect();
        assert_eq!(faces.len(), 6, "support {i}");
        assert!(faces.iter().all(|a| (a - h * h).abs() < 1e-12));
        assert!((lap[i] - 6.0).abs() < 1e-9, "support {i}: {}", lap[i]);
        assert!((div[i] - 3.0).abs() < 1e-9);
    }
    assert!(interior > 100);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn cells_match_a_sampling_oracle_and_keep_the_identities(
        balls in prop::collection::vec(
            ((0.0..1.0f64, 0.0..1.0f64, 0.0..1.0f64), 0.15..0.45f64), 2..12),
        a in (-2.0..2.0f64, -2.0..2.0f64, -2.0..2.0f64),
    ) {
        let a = DVec3::new(a.0, a.1, a.2);
        let mut centres: Vec<DVec3> =
            balls.iter().map(|&((x, y, z), _)| DVec3::new(x, y, z)).collect();
        let mut radii: Vec<f64> = balls.iter().map(|&(_, r)| r).collect();
        // A ball with no neighbour: zero operators, not NaN.
        centres.push(DVec3::new(2.0, 0.5, 0.5));
        radii.push(0.2);
        let n = centres.len();
        let g = geometry(&centres, &radii);
        for bound in [CellBound::CoverBox, CellBound::BallCube] {
            let ops = LaguerreOperators::new(&g, bound);
            // Symmetric weights, exact zero on constants.
            let sym = ops.symmetric_face_areas();
            for i in 0..n {
                for (p, &j) in g.neighbours(i).iter().enumerate() {
                    let back = g.neighbours(j as usize).binary_search(&(i as u32)).unwrap();
                    prop_assert_eq!(sym[g.offsets()[i] as usize + p],
                        sym[g.offsets()[j as usize] as usize + back]);
                }
            }
            prop_assert!(ops.lap(&vec![1.7; n]).iter().all(|&v| v == 0.0));
            prop_assert!(ops.div(&vec![a; n]).iter().all(|&v| v == 0.0));
            prop_assert!(ops.curl(&vec![a; n]).iter().all(|&v| v == DVec3::ZERO));
            let linear: Vec<f64> = centres.iter().map(|c| a.dot(*c)).collect();
            let lap = ops.lap(&linear);
            prop_assert!(lap.iter().all(|v| v.is_finite()));
            prop_assert_eq!(lap[n - 1], 0.0);
            for i in 0..n {
                let v = ops.volumes()[i];
                if !(v > 0.0 && ops.bound_areas()[i] == 0.0) {
                    continue;
                }
                // Closed cell: its own faces close, Σ_j A_ij n_ij = 0.
                let range = g.offsets()[i] as usize..g.offsets()[i + 1] as usize;
                let (mut closure, mut total) = (DVec3::ZERO, 0.0);
                for k in range.clone() {
                    let j = g.neighbour_array()[k] as usize;
                    let d = centres[j] - centres[i];
                    if d.length() > 0.0 {
                        closure += ops.face_areas()[k] * d.normalize();
                        total += ops.face_areas()[k];
                    }
                }
                prop_assert!(closure.length() <= 1e-9 * total, "support {i}: {closure}");
                // Where every neighbour's cell agrees on the shared faces (Ā = A), Lap of a
                // linear field is a · Σ_j A_ij n_ij: rounding.
                let agree = range.clone().all(|k| {
                    let (a, b) = (ops.face_areas()[k], sym[k]);
                    (a - b).abs() <= 1e-12 * a.max(b)
                });
                if agree {
                    let scale: f64 = range.clone().map(|k| {
                        let j = g.neighbour_array()[k] as usize;
                        let d = centres[j].distance(centres[i]);
                        ops.face_areas()[k] * (linear[j] - linear[i]).abs() / d.max(1e-300)
                    }).sum::<f64>() / v;
                    prop_assert!(lap[i].abs() <= 1e-9 * scale + 1e-12, "support {i}: {}", lap[i]);
                }
            }
            // Volume of the cell against counting sample points of the bound that are no
            // farther (in power) from c_i than from any graph neighbour.
            let (lo, hi) = centres.iter().zip(&radii).fold(
                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                |(lo, hi), (&c, &r)| (lo.min(c - r), hi.max(c + r)));
            let samples = 48;
            for i in 0..n - 1 {
                let (blo, bhi) = match bound {
                    CellBound::CoverBox => (lo, hi),
                    CellBound::BallCube => (centres[i] - radii[i], centres[i] + radii[i]),
                };
                let step = (bhi - blo) / samples as f64;
                let mut count = 0usize;
                for x in 0..samples {
                    for y in 0..samples {
                        for z in 0..samples {
                            let p = blo + step * DVec3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5);
                            let own = power(centres[i], radii[i], p);
                            if g.neighbours(i).iter().all(|&j| {
                                let j = j as usize;
                                centres[j] == centres[i] || own <= power(centres[j], radii[j], p)
                            }) {
                                count += 1;
                            }
                        }
                    }
                }
                let cell = step.x * step.y * step.z;
                let estimate = count as f64 * cell;
                let box_volume = (bhi - blo).x * (bhi - blo).y * (bhi - blo).z;
                // Sampling error: about one sample layer over the cell's surface.
                let tolerance = 0.05 * ops.volumes()[i] + 6.0 * (box_volume).powf(2.0 / 3.0) * step.x;
                prop_assert!((ops.volumes()[i] - estimate).abs() <= tolerance,
                    "support {i} ({bound:?}): volume {} vs sampled {estimate}", ops.volumes()[i]);
            }
        }
    }
}
