//! Properties of the normal-coherence measure that gates the diffusion's normal fit.

use proptest::prelude::*;
use sphcover_core::DVec3;
use sphcover_recon::FittingTerms;

fn terms(weights: &[f64], normals: &[DVec3]) -> FittingTerms {
    FittingTerms {
        weight: weights.to_vec(),
        normal_sum: normals.to_vec(),
        offset_sum: vec![DVec3::ZERO; weights.len()],
        kernel_sum: weights.to_vec(),
    }
}

proptest! {
    /// Supports whose samples agree on one unit normal (`‖N_i‖ = W_i`) are fully coherent,
    /// whatever their weights.
    #[test]
    fn agreeing_normals_are_fully_coherent(
        weights in prop::collection::vec(0.01f64..100.0, 1..50),
        direction in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
    ) {
        let d = DVec3::new(direction.0, direction.1, direction.2).normalize_or(DVec3::Z);
        let normals: Vec<DVec3> = weights.iter().map(|&w| -w * d).collect();
        let c = terms(&weights, &normals).median_normal_coherence();
        prop_assert!((c - 1.0).abs() < 1e-12, "{c}");
    }

    /// The coherence is the median of `‖N_i‖ / W_i` over supports with samples: scaling a
    /// support's sums leaves it unchanged, supports without samples do not count, and it
    /// matches a sorted brute force.
    #[test]
    fn coherence_is_the_median_ratio(
        supports in prop::collection::vec((0.01f64..10.0, 0.0f64..1.0, 0.1f64..10.0), 1..40),
        empty in 0usize..5,
    ) {
        let mut weights: Vec<f64> = supports.iter().map(|s| s.0).collect();
        let mut normals: Vec<DVec3> = supports.iter().map(|s| DVec3::X * (s.0 * s.1)).collect();
        weights.extend(std::iter::repeat_n(0.0, empty));
        normals.extend(std::iter::repeat_n(DVec3::ZERO, empty));
        let c = terms(&weights, &normals).median_normal_coherence();
        let mut ratios: Vec<f64> = supports.iter().map(|s| s.1).collect();
        ratios.sort_by(f64::total_cmp);
        prop_assert!((c - ratios[ratios.len() / 2]).abs() < 1e-12);
        let scale = |i: usize| supports.get(i).map_or(1.0, |s| s.2);
        let scaled_w: Vec<f64> = weights.iter().enumerate().map(|(i, w)| w * scale(i)).collect();
        let scaled_n: Vec<DVec3> = normals.iter().enumerate().map(|(i, n)| *n * scale(i)).collect();
        let c2 = terms(&scaled_w, &scaled_n).median_normal_coherence();
        prop_assert!((c - c2).abs() < 1e-12);
    }
}

#[test]
fn no_sample_means_zero_coherence() {
    assert_eq!(
        terms(&[0.0, 0.0], &[DVec3::ZERO; 2]).median_normal_coherence(),
        0.0
    );
    assert_eq!(terms(&[], &[]).median_normal_coherence(), 0.0);
}
