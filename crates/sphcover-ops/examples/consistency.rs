//! Consistency of the discrete operators under refinement.
//!
//! For the thesis operator and each variant, prints the RMS error (over supports at least
//! two radii away from the domain boundary, so that one-sided boundary stencils are left out)
//! of `Lap(|x|²) = 6`, `Lap(x²) = 2`, `Lap(x² − y²) = 0`, `Lap(xy) = 0`,
//! `Lap(sin πx sin πy sin πz) = −3π² u` (relative), `Div(x) = 3`, `Div(a) = 0`, `Curl(Grad(ℓ)) = 0` for a
//! linear `ℓ`, on (a) a regular grid cover, (b) a jittered grid cover, (c) an adaptive octree
//! cover around a sphere (the initial covers of thesis §3.4.1), (d) covers built by
//! `build_surface_cover` from points on a sphere (expansion on), each at three refinement
//! levels, with the observed convergence order `log(e_coarse / e_fine) / log(h_coarse / h_fine)`.
//!
//! Run: `cargo run --release -p sphcover-ops --example consistency`

use std::f64::consts::PI;
use std::time::Instant;

use sphcover_core::synthetic::{self, AdaptiveCoverParams, Surface};
use sphcover_core::{
    Aabb, DVec3, SphereIntersectionGraph, SurfaceCoverParams, SurfaceSamples, build_surface_cover,
};
use sphcover_ops::{
    CellBound, DiscreteOperators, FluxKind, LaguerreOperators, MassKind, PairGeometry,
    QuadraticFitOperators, ThesisOperators,
};

const SHRINK: f64 = 0.7;
const QUANTITIES: [&str; 8] = [
    "Lap|x|²",
    "Lap x²",
    "Lap x²−y²",
    "Lap xy",
    "Lap sin",
    "Div x",
    "Div a",
    "Curl∇ℓ",
];

struct Level {
    label: String,
    h: f64,
    centres: Vec<DVec3>,
    radii: Vec<f64>,
}

fn unit_box() -> Aabb {
    Aabb {
        min: DVec3::splat(-0.5),
        max: DVec3::splat(0.5),
    }
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for v in values {
        sum += v * v;
        count += 1;
    }
    if count == 0 {
        0.0
    } else {
        (sum / count as f64).sqrt()
    }
}

fn errors(ops: &dyn DiscreteOperators, centres: &[DVec3], interior: &[usize]) -> [f64; 8] {
    let scalar = |f: &dyn Fn(DVec3) -> f64| centres.iter().map(|&c| f(c)).collect::<Vec<f64>>();
    let sin3 = |c: DVec3| (PI * c.x).sin() * (PI * c.y).sin() * (PI * c.z).sin();
    let lap_err = |f: &dyn Fn(DVec3) -> f64, exact: &dyn Fn(DVec3) -> f64| {
        let lap = ops.lap(&scalar(f));
        rms(interior.iter().map(|&i| lap[i] - exact(centres[i])))
    };
    let a = DVec3::new(0.3, -0.5, 0.8);
    let div_x = ops.div(centres);
    let div_a = ops.div(&vec![a; centres.len()]);
    let grad_linear = ops.grad(&scalar(&|c| a.dot(c) + 0.2));
    let curl = ops.curl(&grad_linear);
    [
        lap_err(&|c| c.length_squared(), &|_| 6.0),
        lap_err(&|c| c.x * c.x, &|_| 2.0),
        lap_err(&|c| c.x * c.x - c.y * c.y, &|_| 0.0),
        lap_err(&|c| c.x * c.y, &|_| 0.0),
        {
            // Relative: the RMS of the exact values over the same supports normalises it.
            let exact = |c: DVec3| -3.0 * PI * PI * sin3(c);
            let scale = rms(interior.iter().map(|&i| exact(centres[i])));
            lap_err(&sin3, &exact) / scale
        },
        rms(interior.iter().map(|&i| div_x[i] - 3.0)),
        rms(interior.iter().map(|&i| div_a[i])),
        rms(interior.iter().map(|&i| curl[i].length())),
    ]
}

fn fmt(e: f64) -> String {
    if e == 0.0 {
        "0".into()
    } else {
        format!("{e:.1e}")
    }
}

fn order(coarse: (f64, f64), fine: (f64, f64)) -> String {
    let (h0, e0) = coarse;
    let (h1, e1) = fine;
    // Below this an error is rounding, and no order can be read from it.
    if e0 < 1e-9 || e1 < 1e-9 {
        "exact".into()
    } else {
        format!("{:.2}", (e0 / e1).ln() / (h0 / h1).ln())
    }
}

fn run(name: &str, levels: &[Level]) {
    println!("\n### ({name}\n");
    let families = [
        "thesis",
        "thesis, central flux",
        "moment-matched",
        "quadratic fit",
        "Laguerre, cover box",
        "Laguerre, ball cube",
    ];
    let mut table: Vec<Vec<(f64, [f64; 8])>> = vec![Vec::new(); families.len()];
    for level in levels {
        let start = Instant::now();
        let graph = SphereIntersectionGraph::build(&level.centres, &level.radii, SHRINK)
            .expect("valid cover");
        let geometry =
            PairGeometry::build(&level.centres, &level.radii, &graph).expect("valid cover");
        let interior: Vec<usize> = (0..level.centres.len())
            .filter(|&i| {
                let c = level.centres[i];
                let gap = (DVec3::splat(0.5) - c.abs()).min_element();
                gap > 2.0 * level.radii[i]
            })
            .collect();
        let thesis = ThesisOperators::new(&geometry, MassKind::Thesis, FluxKind::Neighbour);
        let central = ThesisOperators::new(&geometry, MassKind::Thesis, FluxKind::Central);
        let moment = ThesisOperators::new(&geometry, MassKind::MomentMatched, FluxKind::Central);
        let quad = QuadraticFitOperators::new(&geometry);
        let stats = quad.stats();
        // The power cells need every intersecting pair: their own graph, shrink 1.
        let full_graph =
            SphereIntersectionGraph::build(&level.centres, &level.radii, 1.0).expect("valid cover");
        let full_geometry =
            PairGeometry::build(&level.centres, &level.radii, &full_graph).expect("valid cover");
        let laguerre_box = LaguerreOperators::new(&full_geometry, CellBound::CoverBox);
        let laguerre_ball = LaguerreOperators::new(&full_geometry, CellBound::BallCube);
        let ops: [&dyn DiscreteOperators; 6] = [
            &thesis,
            &central,
            &moment,
            &quad,
            &laguerre_box,
            &laguerre_ball,
        ];
        for (f, op) in ops.iter().enumerate() {
            table[f].push((level.h, errors(*op, &level.centres, &interior)));
        }
        println!(
            "- {}: {} supports, {} interior, mean degree {:.1}, quadratic-fit rows {} \
             (fallback {}, isolated {}), {:.2} s",
            level.label,
            level.centres.len(),
            interior.len(),
            graph.mean_degree(),
            stats.quadratic_rows,
            stats.fallback_rows,
            stats.isolated_rows,
            start.elapsed().as_secs_f64()
        );
        // Power cells need not contain their centre: c_i is outside when r_j² − r_i² > d² for
        // some neighbour, and the two-point flux then has no consistency to lean on.
        let outside = interior
            .iter()
            .filter(|&&i| {
                full_geometry.neighbours(i).iter().any(|&j| {
                    let j = j as usize;
                    let d2 = level.centres[j].distance_squared(level.centres[i]);
                    level.radii[j].powi(2) - level.radii[i].powi(2) > d2
                })
            })
            .count();
        let small = interior
            .iter()
            .filter(|&&i| laguerre_box.volumes()[i] < 0.1 * level.h.powi(3))
            .count();
        println!(
            "  - power cells: {outside} interior centres outside their own cell, {small} interior \
             cells below 0.1 h³ (of {})",
            interior.len()
        );
        for (name, l) in [("cover box", &laguerre_box), ("ball cube", &laguerre_ball)] {
            let s = l.stats();
            let interior_bounded = interior
                .iter()
                .filter(|&&i| l.bound_areas()[i] > 0.0)
                .count();
            println!(
                "  - Laguerre, {name} (shrink-1 graph, mean degree {:.1}): {} empty cells, \
                 {} cells touching the bound ({} of them interior), face mismatch \
                 |A_ij − A_ji|/A: max {:.1e}, {} pairs above 1e-9",
                full_graph.mean_degree(),
                s.empty_cells,
                s.bounded_cells,
                interior_bounded,
                s.max_face_mismatch,
                s.mismatched_pairs
            );
        }
    }
    println!();
    println!("| operator | level | {} |", QUANTITIES.join(" | "));
    println!("|---|---|{}", "---|".repeat(QUANTITIES.len()));
    for (f, rows) in table.iter().enumerate() {
        for (level, (_, e)) in levels.iter().zip(rows) {
            let cells: Vec<String> = e.iter().map(|&v| fmt(v)).collect();
            println!(
                "| {} | {} | {} |",
                families[f],
                level.label,
                cells.join(" | ")
            );
        }
        let first = rows.first().expect("levels");
        let last = rows.last().expect("levels");
        let orders: Vec<String> = (0..8)
            .map(|q| order((first.0, first.1[q]), (last.0, last.1[q])))
            .collect();
        println!("| {} | order | {} |", families[f], orders.join(" | "));
    }
}

fn grid_levels(jitter: f64) -> Vec<Level> {
    [8usize, 16, 32]
        .iter()
        .map(|&cells| {
            let h = 1.0 / cells as f64;
            // 1.3 h is the thesis octree radius (0.75 × the cell diagonal).
            let cover = if jitter == 0.0 {
                synthetic::regular_grid(unit_box(), h, 1.3)
            } else {
                synthetic::jittered_grid(unit_box(), h, 1.3, jitter, 7)
            }
            .expect("valid grid");
            Level {
                label: format!("h=1/{cells}"),
                h,
                centres: cover.centres,
                radii: cover.radii,
            }
        })
        .collect()
}

fn adaptive_levels() -> Vec<Level> {
    [5u32, 6, 7]
        .iter()
        .map(|&depth| {
            let cover = synthetic::adaptive_surface_cover(&AdaptiveCoverParams {
                min_depth: depth - 2,
                max_depth: depth,
                surface: Surface::Sphere {
                    centre: DVec3::ZERO,
                    radius: 0.3,
                },
                ..AdaptiveCoverParams::default()
            })
            .expect("valid octree");
            Level {
                label: format!("depth {}–{depth}", depth - 2),
                h: 1.0 / (1u64 << depth) as f64,
                centres: cover.centres,
                radii: cover.radii,
            }
        })
        .collect()
}

fn surface_cover_levels() -> Vec<Level> {
    // Points on a sphere of radius 0.35 (Fibonacci lattice) with outward normals.
    let normals = synthetic::fibonacci_sphere(40_000);
    let points: Vec<DVec3> = normals.iter().map(|&n| 0.35 * n).collect();
    [5u32, 6, 7]
        .iter()
        .map(|&depth| {
            let params = SurfaceCoverParams {
                eps: 1e-5,
                max_depth: depth,
                ..SurfaceCoverParams::default()
            };
            let (cover, _) = build_surface_cover(&SurfaceSamples::new(&points, &normals), &params)
                .expect("cover");
            Level {
                label: format!("max depth {depth}"),
                h: 1.0 / (1u64 << depth) as f64,
                centres: cover.centres().to_vec(),
                radii: cover.radii().to_vec(),
            }
        })
        .collect()
}

fn main() {
    println!("## Consistency of the discrete operators (SIG shrink {SHRINK})");
    println!(
        "\nRMS errors over interior supports (centre at least 2 r_i inside the unit box). \
         `a` = (0.3, −0.5, 0.8), `ℓ(x) = a·x + 0.2`; `Lap sin` is relative (divided by the RMS of the exact `−3π² u` over the same supports); the others are absolute."
    );
    run("a) regular grid, r = 1.3 h", &grid_levels(0.0));
    run(
        "b) jittered grid, r = 1.3 h (1 ± 0.25), centres ± 0.25 h",
        &grid_levels(0.25),
    );
    run(
        "c) adaptive octree around a sphere, r = 0.75 × cell diagonal",
        &adaptive_levels(),
    );
    run(
        "d) build_surface_cover of 40K points on a sphere",
        &surface_cover_levels(),
    );
}
