//! The triangulation against a brute-force oracle (every quadruple of points tested for an
//! empty power sphere, ties broken by the same symbolic perturbation), on small random and
//! grid inputs: the fast paths of the construction (float filters, the equal-weight grid
//! stage, the integer stages) must give exactly the oracle's tetrahedra. And the output must
//! not depend on the number of threads.
mod common;
use common::*;
use proptest::prelude::*;
use sphcover_core::random::SplitMix64;
use sphcover_tetra::predicates::{in_power_sphere_sos, orient3d};
use sphcover_tetra::{RegularTriangulation, TriangulationParams, VertexStatus, dual_complex_of};

/// The finite tetrahedra of the regular triangulation by definition: the positively oriented
/// quadruples that no other point conflicts with. `O(n^5)`; distinct centres required.
fn brute_force_tets(p: &[[f64; 3]], w: &[f64]) -> Vec<[u32; 4]> {
    let n = p.len();
    let mut out = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                for d in c + 1..n {
                    let o = orient3d(&p[a], &p[b], &p[c], &p[d]);
                    if o == 0 {
                        continue;
                    }
                    let t = if o > 0 { [a, b, c, d] } else { [b, a, c, d] };
                    let q = t.map(|i| &p[i]);
                    let qw = t.map(|i| w[i]);
                    let empty = (0..n)
                        .filter(|m| !t.contains(m))
                        .all(|m| !in_power_sphere_sos(q, qw, &p[m], w[m]));
                    if empty {
                        out.push([a as u32, b as u32, c as u32, d as u32]);
                    }
                }
            }
        }
    }
    out
}

fn triangulated_tets(p: &[[f64; 3]], w: &[f64], seed: u64) -> Vec<[u32; 4]> {
    let t = RegularTriangulation::new(
        p,
        w,
        &TriangulationParams {
            seed,
            ..Default::default()
        },
    )
    .unwrap();
    let tets: Vec<[u32; 4]> = t.finite_tets().map(|c| t.tet(c)).collect();
    canonical(&tets)
}

fn assert_same_as_oracle(p: &[[f64; 3]], w: &[f64], seed: u64) {
    let ours = triangulated_tets(p, w, seed);
    let oracle = canonical(&brute_force_tets(p, w));
    assert!(!oracle.is_empty());
    assert_eq!(
        ours,
        oracle,
        "{} vs {} tetrahedra",
        ours.len(),
        oracle.len()
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn random_sets_match_the_oracle(n in 5usize..22, wmax in 0.0f64..0.1, seed in 0u64..1000) {
        let (p, w) = random_points(n, wmax, seed);
        assert_same_as_oracle(&p, &w, seed);
    }

    #[test]
    fn grids_with_few_weights_match_the_oracle(k in 0u64..1000) {
        // A 3×3×3 grid with weights of an octree's levels (`w`, `4w`) or zero: exact
        // co-spherical ties everywhere, settled by the equal-weight grid stage or the integer
        // stages, then by the perturbation.
        let (p, _) = grid(3, 0.25, 0.0);
        let mut rng = SplitMix64::new(k);
        let w: Vec<f64> = p
            .iter()
            .map(|_| [0.0, 0.0121, 4.0 * 0.0121][rng.below(3) as usize])
            .collect();
        assert_same_as_oracle(&p, &w, k);
    }
}

#[test]
fn equal_sphere_grid_matches_the_oracle() {
    let (p, w) = grid(3, 1.0, 0.75);
    assert_same_as_oracle(&p, &w, 1);
    // Off the dyadic grid (no integer stages), with the same ties in exact arithmetic.
    let (p, w) = grid(3, 0.1, 0.0);
    assert_same_as_oracle(&p, &w, 2);
}

#[test]
fn output_does_not_depend_on_the_thread_count() {
    // Large enough for the parallel sorts and passes to split the work.
    let (p, _) = grid(24, 0.5, 0.0);
    let mut rng = SplitMix64::new(9);
    let w: Vec<f64> = p
        .iter()
        .map(|_| [0.0, 0.0625, 0.3][rng.below(3) as usize])
        .collect();
    let run = |threads: usize| {
        sphcover_core::on_threads(threads, || {
            let t = RegularTriangulation::new(&p, &w, &TriangulationParams::default()).unwrap();
            let dc = dual_complex_of(&t);
            (
                t.tet_slots().collect::<Vec<_>>(),
                t.vertex_status().to_vec(),
                dc.tets,
                dc.neighbours,
            )
        })
    };
    let one = run(1);
    assert!(one.1.contains(&VertexStatus::Hidden));
    for threads in [2, 3] {
        assert!(run(threads) == one, "{threads} threads differ from one");
    }
}
