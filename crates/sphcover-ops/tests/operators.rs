//! Identities of the discrete operators on random covers, including near-degenerate ones
//! (coincident radii, nearly nested balls, a ball with one neighbour, an isolated ball).

use glam::DVec3;
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use sphcover_core::SphereIntersectionGraph;
use sphcover_ops::{
    CgParams, DiscreteOperators, FluxKind, MassKind, OpsError, PairGeometry, PairTerms,
    PoissonBoundary, Preconditioner, QuadraticFitOperators, RowKind, SolveError, ThesisOperators,
    implicit_smoothing, solve_poisson,
};

/// A random cover: `n` balls in the unit cube, then the degenerate extras.
fn cover_strategy() -> impl Strategy<Value = (Vec<DVec3>, Vec<f64>)> {
    (
        prop::collection::vec(
            ((0.0..1.0f64, 0.0..1.0f64, 0.0..1.0f64), 0.12..0.45f64),
            2..40,
        ),
        any::<bool>(),
        -12.0..-3.0f64,
        any::<bool>(),
    )
        .prop_map(|(balls, coincident, log_gap, duplicate)| {
            let nest_gap = 10f64.powf(log_gap);
            let mut centres: Vec<DVec3> = balls
                .iter()
                .map(|&((x, y, z), _)| DVec3::new(x, y, z))
                .collect();
            let mut radii: Vec<f64> = balls.iter().map(|&(_, r)| r).collect();
            if coincident {
                // Same radius as ball 0, next to it.
                centres.push(centres[0] + DVec3::new(0.1, 0.05, 0.0));
                radii.push(radii[0]);
            }
            // Nearly nested in ball 1: d just above |r_i − r_j|.
            let r = 0.5 * radii[1];
            centres.push(centres[1] + DVec3::new(radii[1] - r + nest_gap, 0.0, 0.0));
            radii.push(r);
            if duplicate {
                // Same centre and radius as ball 0 (d = 0: no intersection circle), and a ball
                // strictly inside ball 1.
                centres.push(centres[0]);
                radii.push(radii[0]);
                centres.push(centres[1] + DVec3::new(0.1 * radii[1], 0.0, 0.0));
                radii.push(0.5 * radii[1]);
            }
            // A pair far away: each ball has exactly one neighbour.
            centres.push(DVec3::new(10.0, 0.0, 0.0));
            radii.push(0.3);
            centres.push(DVec3::new(10.4, 0.1, 0.0));
            radii.push(0.3);
            // An isolated ball.
            centres.push(DVec3::new(-10.0, 0.0, 0.0));
            radii.push(0.3);
            (centres, radii)
        })
}

fn geometry(centres: &[DVec3], radii: &[f64], shrink: f64) -> PairGeometry {
    let graph = SphereIntersectionGraph::build(centres, radii, shrink).unwrap();
    PairGeometry::build(centres, radii, &graph).unwrap()
}

fn row_of(g: &PairGeometry, k: usize) -> usize {
    g.offsets().partition_point(|&o| o as usize <= k) - 1
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn pair_terms_are_consistent(
        ri in 0.05..2.0f64, rj in 0.05..2.0f64, t in 0.0..1.0f64,
        dir in (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64),
    ) {
        let dir = DVec3::new(dir.0, dir.1, dir.2);
        prop_assume!(dir.length() > 1e-3);
        let (lo, hi) = ((ri - rj).abs(), ri + rj);
        let d = lo + t * (hi - lo);
        let cj = dir.normalize() * d;
        let a = PairTerms::new(DVec3::ZERO, ri, cj, rj);
        let b = PairTerms::new(cj, rj, DVec3::ZERO, ri);
        // φ and D are symmetric bit for bit.
        prop_assert_eq!(a.phi, b.phi);
        prop_assert_eq!(a.disk_area, b.disk_area);
        if a.phi > 0.0 {
            prop_assert!((a.plane_offset + b.plane_offset - a.distance).abs() <= 1e-12 * hi);
            let rho2 = ri * ri - a.plane_offset * a.plane_offset;
            prop_assert!((a.disk_radius_sq - rho2).abs() <= 1e-9 * hi * hi);
            prop_assert!(a.cap_area >= 0.0 && a.cap_area <= 4.0 * std::f64::consts::PI * ri * ri);
        }
    }

    #[test]
    fn weights_are_symmetric_and_stiffness_negative((centres, radii) in cover_strategy(),
                                                    x in prop::collection::vec(-1.0..1.0f64, 50)) {
        let g = geometry(&centres, &radii, 1.0);
        for k in 0..g.stored_entries() {
            let i = row_of(&g, k);
            let j = g.neighbour_array()[k] as usize;
            let back = g.neighbours(j).binary_search(&(i as u32)).unwrap();
            prop_assert_eq!(g.phi()[k], g.phi_row(j)[back]);
            prop_assert!(g.phi()[k].is_finite() && g.phi()[k] >= 0.0);
        }
        let x: Vec<f64> = (0..g.len()).map(|i| x[i % x.len()]).collect();
        let mut y = vec![0.0; g.len()];
        g.apply_stiffness(&x, &mut y);
        let quad: f64 = x.iter().zip(&y).map(|(a, b)| a * b).sum();
        let scale: f64 = g.weight_sum().iter().zip(&x).map(|(w, v)| w * v * v).sum();
        prop_assert!(quad <= 1e-12 * scale, "xᵀLx = {quad}");
    }

    #[test]
    fn thesis_identities((centres, radii) in cover_strategy(),
                         a in (-2.0..2.0f64, -2.0..2.0f64, -2.0..2.0f64), b in -1.0..1.0f64) {
        let a = DVec3::new(a.0, a.1, a.2);
        let g = geometry(&centres, &radii, 0.8);
        let n = g.len();
        let isolated = n - 1;
        for mass in [MassKind::Thesis, MassKind::MomentMatched] {
            for flux in [FluxKind::Neighbour, FluxKind::Central] {
                let ops = ThesisOperators::new(&g, mass, flux);
                // Lap(const) = 0 exactly.
                prop_assert!(ops.lap(&vec![2.5; n]).iter().all(|&v| v == 0.0));
                let u: Vec<f64> = centres.iter().map(|c| a.dot(*c) + b).collect();
                let grad = ops.grad(&u);
                let lap = ops.lap(&u);
                let div_grad = ops.div(&grad);
                let m = g.mass(mass);
                for i in 0..n {
                    // Scale of the sum whose cancellation the identity relies on.
                    let scale: f64 = g.neighbours(i).iter().zip(g.phi_row(i))
                        .map(|(&j, &phi)| phi * a.dot(centres[j as usize] - centres[i]).abs())
                        .sum::<f64>() / m[i].max(f64::MIN_POSITIVE);
                    prop_assert!((lap[i] - div_grad[i]).abs() <= 1e-10 * (scale + lap[i].abs()),
                        "support {i}: Lap {} vs Div Grad {} (scale {scale})", lap[i], div_grad[i]);
                    // Every neighbour difference is reproduced, whatever the rank and the
                    // conditioning; with full rank the gradient is `a` up to the conditioning.
                    for (&j, &phi) in g.neighbours(i).iter().zip(g.phi_row(i)) {
                        if phi > 0.0 {
                            let d = centres[j as usize] - centres[i];
                            prop_assert!((grad[i].dot(d) - a.dot(d)).abs()
                                <= 1e-10 * a.length() * d.length(),
                                "support {i}: grad {} vs {a} along {d}", grad[i]);
                        }
                    }
                    if ops.gradient().is_full_rank(i) {
                        // The fit sees differences `u_j − u_i`, each rounded relative to |u|,
                        // over distances `d`: its rounding error is relative to |a| plus
                        // |u| / d, amplified by the fit's conditioning.
                        let cond = ops.gradient().condition(i);
                        let (mut u_max, mut d_min) = (u[i].abs(), f64::INFINITY);
                        for (&j, &phi) in g.neighbours(i).iter().zip(g.phi_row(i)) {
                            if phi > 0.0 {
                                u_max = u_max.max(u[j as usize].abs());
                                d_min = d_min.min((centres[j as usize] - centres[i]).length());
                            }
                        }
                        let scale = a.length() + u_max / d_min;
                        prop_assert!((grad[i] - a).length() <= 1e-12f64.max(1e-15 * cond) * scale,
                            "support {i}: grad {} vs {a} (cond {cond:e}, scale {scale:e})", grad[i]);
                    }
                }
                // The isolated support gets zero operators.
                prop_assert_eq!(lap[isolated], 0.0);
                prop_assert_eq!(grad[isolated], DVec3::ZERO);
                prop_assert_eq!(ops.div(&grad)[isolated], 0.0);
                prop_assert_eq!(ops.curl(&grad)[isolated], DVec3::ZERO);
                prop_assert!(lap.iter().chain(&div_grad).all(|v| v.is_finite()));
            }
        }
    }

    #[test]
    fn quadratic_fit_exactness((centres, radii) in cover_strategy(),
                               h in prop::array::uniform6(-2.0..2.0f64),
                               a in (-2.0..2.0f64, -2.0..2.0f64, -2.0..2.0f64)) {
        let a = DVec3::new(a.0, a.1, a.2);
        let g = geometry(&centres, &radii, 1.0);
        let n = g.len();
        let ops = QuadraticFitOperators::new(&g);
        let isolated = n - 1;
        prop_assert!(ops.lap(&vec![-1.5; n]).iter().all(|&v| v == 0.0));
        prop_assert!(ops.div(&vec![a; n]).iter().all(|&v| v == 0.0));
        prop_assert!(ops.curl(&vec![a; n]).iter().all(|&v| v == DVec3::ZERO));

        // Quadratic u = ½ xᵀHx + a·x with H = [[h0,h3,h4],[h3,h1,h5],[h4,h5,h2]].
        let quad = |c: DVec3| 0.5 * (h[0] * c.x * c.x + h[1] * c.y * c.y + h[2] * c.z * c.z)
            + h[3] * c.x * c.y + h[4] * c.x * c.z + h[5] * c.y * c.z + a.dot(c);
        let trace = h[0] + h[1] + h[2];
        let u: Vec<f64> = centres.iter().map(|&c| quad(c)).collect();
        let linear: Vec<f64> = centres.iter().map(|c| a.dot(*c)).collect();
        let lap_u = ops.lap(&u);
        let lap_linear = ops.lap(&linear);
        let grad_linear = ops.grad(&linear);
        let div_x = ops.div(&centres);
        let coeff = ops.lap_coefficients();
        let linear_gradient = sphcover_ops::LeastSquaresGradient::new(&g);
        for i in 0..n {
            let range = g.offsets()[i] as usize..g.offsets()[i + 1] as usize;
            // Magnitude of the terms that cancel: the fit's own and the fallback's φ/m.
            let m = g.mass(MassKind::MomentMatched)[i].max(f64::MIN_POSITIVE);
            let scale = |f: &[f64]| range.clone()
                .map(|k| (coeff[k].abs() + g.phi()[k] / m)
                    * (f[g.neighbour_array()[k] as usize] - f[i]).abs())
                .sum::<f64>();
            prop_assert!(lap_linear[i].abs() <= 1e-12 * scale(&linear) + 1e-300,
                "support {i}: Lap(linear) = {}", lap_linear[i]);
            prop_assert!(lap_u[i].is_finite());
            if ops.row_kind(i) == RowKind::Quadratic {
                prop_assert!((lap_u[i] - trace).abs() <= 1e-9 * (scale(&u) + trace.abs()),
                    "support {i}: Lap(u) = {} vs {trace}", lap_u[i]);
            }
            if linear_gradient.is_full_rank(i) {
                let tolerance = 1e-10f64.max(1e-15 * linear_gradient.condition(i));
                prop_assert!((grad_linear[i] - a).length() <= tolerance * a.length(),
                    "support {i}: grad {} vs {a}", grad_linear[i]);
                prop_assert!((div_x[i] - 3.0).abs() <= 3.0 * tolerance,
                    "support {i}: Div x = {}", div_x[i]);
            }
        }
        prop_assert_eq!(lap_u[isolated], 0.0);
        prop_assert_eq!(div_x[isolated], 0.0);
    }
}

/// Balls on a lattice plus random jitter: every interior support has many neighbours in
/// general position, so the quadratic fit is exact there.
#[test]
fn quadratic_fit_is_exact_on_quadratics_of_a_jittered_grid() {
    let domain = sphcover_core::Aabb {
        min: DVec3::splat(0.0),
        max: DVec3::splat(1.0),
    };
    let cover = sphcover_core::synthetic::jittered_grid(domain, 0.125, 1.3, 0.3, 3).unwrap();
    let g = geometry(&cover.centres, &cover.radii, 0.7);
    let ops = QuadraticFitOperators::new(&g);
    let stats = ops.stats();
    assert_eq!(stats.isolated_rows, 0);
    assert!(stats.quadratic_rows > 9 * g.len() / 10, "{stats:?}");
    let u: Vec<f64> = cover
        .centres
        .iter()
        .map(|c| 3.0 * c.x * c.x - c.y * c.z + 0.5 * c.z * c.z + c.x)
        .collect();
    let lap = ops.lap(&u);
    let thesis = ThesisOperators::new(&g, MassKind::Thesis, FluxKind::Neighbour).lap(&u);
    let mut exact_rows = 0;
    let mut thesis_max_error = 0.0f64;
    for i in 0..g.len() {
        if ops.row_kind(i) == RowKind::Quadratic && (lap[i] - 7.0).abs() <= 1e-9 {
            exact_rows += 1;
        }
        thesis_max_error = thesis_max_error.max((thesis[i] - 7.0).abs());
    }
    assert_eq!(exact_rows, stats.quadratic_rows);
    assert!(
        thesis_max_error > 1.0,
        "the thesis operator is inconsistent"
    );
}

#[test]
fn isolated_supports_get_zero_not_nan() {
    let centres = vec![
        DVec3::ZERO,
        DVec3::new(5.0, 0.0, 0.0),
        DVec3::new(5.0, 0.0, 0.0),
    ];
    // Support 2 duplicates support 1 (d = 0): weight 0, so every support is isolated.
    let radii = vec![1.0, 1.0, 1.0];
    let g = geometry(&centres, &radii, 1.0);
    assert_eq!(g.usable_entries(), 0);
    let u = vec![1.0, 2.0, 3.0];
    let v = vec![DVec3::X, DVec3::Y, DVec3::Z];
    let thesis = ThesisOperators::new(&g, MassKind::Thesis, FluxKind::Neighbour);
    let quad = QuadraticFitOperators::new(&g);
    let ops: [&dyn DiscreteOperators; 2] = [&thesis, &quad];
    for op in ops {
        assert_eq!(op.lap(&u), vec![0.0; 3]);
        assert_eq!(op.div(&v), vec![0.0; 3]);
        assert_eq!(op.grad(&u), vec![DVec3::ZERO; 3]);
        assert_eq!(op.curl(&v), vec![DVec3::ZERO; 3]);
        assert_eq!(op.lap_vector(&v), vec![DVec3::ZERO; 3]);
    }
    // Smoothing keeps them; Poisson gives them 0.
    let (s, _) = implicit_smoothing(&g, MassKind::Thesis, 1.0, &u, &CgParams::default()).unwrap();
    assert_eq!(s, u);
}

fn grid(n: usize, h: f64, rho: f64) -> (Vec<DVec3>, Vec<f64>) {
    let mut c = Vec::new();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                c.push(DVec3::new(x as f64, y as f64, z as f64) * h);
            }
        }
    }
    let r = vec![rho * h; c.len()];
    (c, r)
}

/// Brute-force oracle: the dense system `(M − tL_W) u = M u₀` solved by LU.
#[test]
fn implicit_smoothing_matches_a_dense_solve() {
    let (mut centres, mut radii) = grid(5, 0.2, 1.1);
    for (k, c) in centres.iter_mut().enumerate() {
        *c += 0.03
            * DVec3::new(
                (k as f64 * 1.7).sin(),
                (k as f64 * 2.3).cos(),
                (k as f64).sin(),
            );
    }
    radii
        .iter_mut()
        .enumerate()
        .for_each(|(k, r)| *r *= 1.0 + 0.1 * (k as f64).cos());
    let g = geometry(&centres, &radii, 0.8);
    let n = g.len();
    let u0: Vec<f64> = centres
        .iter()
        .map(|c| (3.0 * c.x).sin() + c.y * c.z)
        .collect();
    for (mass, preconditioner) in [
        (MassKind::Thesis, Preconditioner::Jacobi),
        (MassKind::MomentMatched, Preconditioner::Jacobi),
        (MassKind::Thesis, Preconditioner::SymmetricGaussSeidel),
        (MassKind::MomentMatched, Preconditioner::Identity),
        (MassKind::MomentMatched, Preconditioner::TwoLevel),
    ] {
        let t = 0.05;
        let params = CgParams {
            relative_tolerance: 1e-12,
            preconditioner,
            ..CgParams::default()
        };
        let (u, info) = implicit_smoothing(&g, mass, t, &u0, &params).unwrap();
        assert!(info.relative_residual <= 1e-12 && info.iterations > 0);
        let m = g.mass(mass);
        let mut a = DMatrix::<f64>::zeros(n, n);
        for i in 0..n {
            a[(i, i)] = m[i] + t * g.weight_sum()[i];
            for (&j, &phi) in g.neighbours(i).iter().zip(g.phi_row(i)) {
                a[(i, j as usize)] -= t * phi;
            }
        }
        let b = DVector::from_iterator(n, (0..n).map(|i| m[i] * u0[i]));
        let exact = a.lu().solve(&b).unwrap();
        for i in 0..n {
            assert!((u[i] - exact[i]).abs() <= 1e-9 * (1.0 + exact[i].abs()));
        }
    }
}

#[test]
fn poisson_with_dirichlet_boundary_reproduces_a_linear_field_on_a_grid() {
    let n = 7;
    let (centres, radii) = grid(n, 0.1, 1.3);
    let g = geometry(&centres, &radii, 0.7);
    let linear = |c: DVec3| 2.0 * c.x - c.y + 0.5 * c.z + 1.0;
    // Boundary: every support within two layers of a face (the stencil reaches two layers).
    let boundary: Vec<(u32, f64)> = centres
        .iter()
        .enumerate()
        .filter(|(_, c)| {
            let k = (**c / 0.1).round();
            k.min_element() < 2.0 || k.max_element() > (n - 3) as f64
        })
        .map(|(i, &c)| (i as u32, linear(c)))
        .collect();
    let f = vec![0.0; g.len()];
    let (u, info) = solve_poisson(
        &g,
        MassKind::Thesis,
        &f,
        &PoissonBoundary::Dirichlet(boundary),
        &CgParams::default(),
    )
    .unwrap();
    assert!(info.relative_residual <= 1e-8);
    for (i, c) in centres.iter().enumerate() {
        assert!((u[i] - linear(*c)).abs() < 1e-6, "support {i}");
    }
    // An anchor fixes one component only.
    let mut two = centres.clone();
    two.push(DVec3::splat(50.0));
    two.push(DVec3::splat(50.05));
    let mut r2 = radii.clone();
    r2.push(0.1);
    r2.push(0.1);
    let g2 = geometry(&two, &r2, 0.7);
    let err = solve_poisson(
        &g2,
        MassKind::Thesis,
        &vec![0.0; g2.len()],
        &PoissonBoundary::Anchor {
            support: 0,
            value: 1.0,
        },
        &CgParams::default(),
    )
    .unwrap_err();
    assert_eq!(
        err,
        SolveError::Setup(OpsError::UnconstrainedComponent { support: g.len() })
    );
}

#[test]
fn poisson_with_an_anchor_solves_the_thesis_laplacian() {
    let (centres, radii) = grid(6, 0.2, 1.3);
    let g = geometry(&centres, &radii, 0.7);
    // A right-hand side in the range of Lap: Lap of a known field.
    let target: Vec<f64> = centres.iter().map(|c| (2.0 * c.x).sin() * c.y).collect();
    let ops = ThesisOperators::new(&g, MassKind::MomentMatched, FluxKind::Central);
    let f = ops.lap(&target);
    let params = CgParams {
        relative_tolerance: 1e-12,
        ..CgParams::default()
    };
    let anchor = PoissonBoundary::Anchor {
        support: 3,
        value: target[3],
    };
    let (u, jacobi) = solve_poisson(&g, MassKind::MomentMatched, &f, &anchor, &params).unwrap();
    for i in 0..g.len() {
        assert!((u[i] - target[i]).abs() < 1e-8, "support {i}");
    }
    let sgs = CgParams {
        preconditioner: Preconditioner::SymmetricGaussSeidel,
        ..params
    };
    let (u, info) = solve_poisson(&g, MassKind::MomentMatched, &f, &anchor, &sgs).unwrap();
    for i in 0..g.len() {
        assert!((u[i] - target[i]).abs() < 1e-8, "support {i}");
    }
    assert!(
        info.iterations < jacobi.iterations,
        "{info:?} vs {jacobi:?}"
    );
}

/// Bit-identical results with one thread and with two.
#[test]
fn results_do_not_depend_on_the_thread_count() {
    let domain = sphcover_core::Aabb {
        min: DVec3::splat(0.0),
        max: DVec3::splat(1.0),
    };
    let cover = sphcover_core::synthetic::jittered_grid(domain, 1.0 / 24.0, 1.3, 0.3, 9).unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let g = geometry(&cover.centres, &cover.radii, 0.7);
            let u: Vec<f64> = cover
                .centres
                .iter()
                .map(|c| (5.0 * c.x).sin() + c.y)
                .collect();
            let mut lap = vec![0.0; g.len()];
            g.apply_laplacian(MassKind::Thesis, &u, &mut lap);
            let quad = QuadraticFitOperators::new(&g).lap(&u);
            let (smooth, info) =
                implicit_smoothing(&g, MassKind::MomentMatched, 1e-3, &u, &CgParams::default())
                    .unwrap();
            let sgs = CgParams {
                preconditioner: Preconditioner::SymmetricGaussSeidel,
                ..CgParams::default()
            };
            let (smooth_sgs, _) = implicit_smoothing(&g, MassKind::Thesis, 1e-2, &u, &sgs).unwrap();
            let mut all = smooth;
            all.extend(smooth_sgs);
            (g.phi().to_vec(), lap, quad, all, info.iterations)
        })
    };
    let one = run(1);
    let two = run(2);
    assert!(one.0.len() > 10_000);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
    assert_eq!(bits(&one.0), bits(&two.0));
    assert_eq!(bits(&one.1), bits(&two.1));
    assert_eq!(bits(&one.2), bits(&two.2));
    assert_eq!(bits(&one.3), bits(&two.3));
    assert_eq!(one.4, two.4);
}
