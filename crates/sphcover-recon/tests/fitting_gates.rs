//! Properties of the normal-coherence measure that gates the diffusion's normal fit, and of the
//! fitting terms over both faces of a thin wall.

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

/// The fitting terms of supports over both faces of a wall of `thickness` (`z = 0` facing
/// down, `z = thickness` facing up, jittered grids of spacing 0.01), against a brute force
/// over every sample that sums the face `face_to_fit` picks where the normals cancel, and
/// all samples otherwise.
mod thin_wall {
    use super::*;
    use sphcover_core::{
        Cover, FaceSelection, Kernel, LocalFunctions, PointIndex, SupportSamples, face_to_fit,
    };

    /// `(W, N, P, K)` of one support by brute force over every sample.
    fn brute_force(
        c: DVec3,
        r: f64,
        points: &[DVec3],
        normals: &[DVec3],
        confidence: &[f64],
    ) -> (f64, DVec3, DVec3, f64) {
        let kernel = Kernel::WendlandC2;
        let inside: Vec<usize> = (0..points.len())
            .filter(|&k| (points[k] - c).length_squared() < r * r)
            .collect();
        let sums = |keep: &dyn Fn(usize) -> bool| {
            inside.iter().filter(|&&k| keep(k)).fold(
                (0.0, DVec3::ZERO, DVec3::ZERO, 0.0),
                |s, &k| {
                    let kw = kernel.weight(points[k], c, r);
                    let w = confidence[k] * kw;
                    (
                        s.0 + w,
                        s.1 - w * normals[k],
                        s.2 + w * (points[k] - c),
                        s.3 + kw,
                    )
                },
            )
        };
        let all = sums(&|_| true);
        let face = face_to_fit(all.0, all.1, FaceSelection::Narrow, |visit| {
            for &k in &inside {
                let d2 = (points[k] - c).length_squared();
                visit(
                    normals[k],
                    d2,
                    confidence[k] * kernel.weight(points[k], c, r),
                );
            }
        });
        match face {
            Some(face) => sums(&|k| face.holds(normals[k])),
            None => all,
        }
    }

    proptest! {
        #[test]
        fn a_support_across_the_wall_sums_its_nearer_face(
            thickness in 0.02..0.05f64,
            supports in prop::collection::vec(
                ((-0.1..0.1f64, -0.1..0.1f64, -0.5..1.5f64), 0.5..4.0f64), 1..12),
            dimmed in 0usize..50,
        ) {
            let (points, normals) = sphcover_core::synthetic::thin_wall(thickness);
            // Some samples of zero confidence (outliers), which never pick the face.
            let confidence: Vec<f64> =
                (0..points.len()).map(|k| if k % 50 == dimmed { 0.0 } else { 1.0 }).collect();
            let centres: Vec<DVec3> = supports
                .iter()
                .map(|((x, y, z), _)| DVec3::new(*x, *y, z * thickness))
                .collect();
            let radii: Vec<f64> = supports.iter().map(|(_, r)| r * thickness).collect();
            let n = centres.len();
            let cover = Cover::new(
                centres.clone(),
                radii.clone(),
                LocalFunctions::Linear { alpha: vec![DVec3::ZERO; n], beta: vec![0.0; n] },
                Kernel::WendlandC2,
            ).unwrap();
            let index = PointIndex::new(&points).unwrap();
            let incidence = SupportSamples::gather(&cover, &index);
            let terms =
                FittingTerms::gather(
                    &cover, &index, &incidence, &points, &normals, &confidence, FaceSelection::Narrow,
                )
                    .unwrap();
            for i in 0..n {
                let (w, nsum, p, k) = brute_force(centres[i], radii[i], &points, &normals, &confidence);
                let tol = 1e-9 * (1.0 + k);
                prop_assert!((terms.weight[i] - w).abs() < tol, "W {} {}", terms.weight[i], w);
                prop_assert!((terms.normal_sum[i] - nsum).length() < tol);
                prop_assert!((terms.offset_sum[i] - p).length() < tol);
                prop_assert!((terms.kernel_sum[i] - k).abs() < tol);
            }
        }
    }
}
