//! Smoothing `∇f` and `∇²f` over the supports before the ridge test (thesis §6.2.3).
//!
//! The method is described on [`smoothed_vertex_derivatives()`].

use glam::{DMat3, DVec3};
use sphcover_core::{PuEvaluator, SphereIntersectionGraph};
use sphcover_ops::{CgParams, MassKind, PairGeometry, implicit_smoothing};

use crate::error::SkeletonError;
use crate::ridge_points::VertexDerivatives;
use crate::slice_stretch::{SliceStretch, ridge_eigen};

/// The nine smoothed components, in this order: `∂x f, ∂y f, ∂z f, H_xx, H_yy, H_zz, H_xy,
/// H_xz, H_yz`.
const FIELDS: usize = 9;

/// `vertex_derivatives` with `∇f` and `∇²f` smoothed over the sphere
/// intersection graph of the balls `(positions[i], radii[i])` by one implicit heat step of
/// time `time` (world units squared; method below). `time = 0` returns the
/// unsmoothed derivatives. Vertices where `f` is undefined stay `None` and do not take part.
/// With `stretch` (a grid resampled from thick slices) the eigenpairs are those of the
/// stretched Hessian ([`SliceStretch`]).
///
/// The thesis names derivative smoothing as the remedy for noise but never formulates it
/// (it proposes "a linear cover and discrete operators", §6.2.3). Here it is formulated with
/// the project's own operators on the sphere intersection graph of the supports that are
/// vertices of the tetrahedral mesh: each of the nine fields — the three components of `∇f`
/// and the six of the symmetric `∇²f`, one value per vertex — takes one implicit
/// (backward-Euler) step of the heat equation,
///
/// ```text
/// (M − t L_W) u = M u₀,    L_W = W − diag(W·1),  W = [φ_ij]   (thesis §4)
/// ```
///
/// with the moment-matched mass (consistent on regular stencils,
/// [`sphcover_ops::MassKind::MomentMatched`]), solved by conjugate gradients
/// ([`sphcover_ops::implicit_smoothing()`]). A step of time `t` damps a Fourier mode of
/// wavelength `λ` by `1 / (1 + t (2π/λ)²)`, so `t = ℓ² / 2` smooths over a length `ℓ` (the
/// standard deviation of the heat kernel of time `t`). The ridge test (eq. 6.1, 6.4, 6.5)
/// then runs on the eigen-decomposition of the smoothed Hessians, with the smoothed
/// gradients; `f` itself is not smoothed (the strength filter and the patches use it only
/// through the derivatives).
///
/// Smoothing is linear and leaves fields that are constant over a connected graph unchanged
/// (`L_W 1 = 0`), so a plate's Hessian, constant across its middle, keeps its eigenvectors;
/// what it removes is the vertex-to-vertex scatter of the second derivatives that noise
/// leaves in the local quadratic fits.
pub fn smoothed_vertex_derivatives(
    evaluator: &PuEvaluator<'_>,
    positions: &[DVec3],
    radii: &[f64],
    time: f64,
    stretch: Option<&SliceStretch>,
) -> Result<Vec<Option<VertexDerivatives>>, SkeletonError> {
    let vgh = evaluator.values_gradients_hessians(positions);
    let raw: Vec<Option<(f64, [f64; FIELDS])>> = vgh
        .iter()
        .map(|d| {
            let d = d.as_ref()?;
            let (g, h) = (d.gradient, d.hessian);
            let fields = [
                g.x,
                g.y,
                g.z,
                h.x_axis.x,
                h.y_axis.y,
                h.z_axis.z,
                0.5 * (h.x_axis.y + h.y_axis.x),
                0.5 * (h.x_axis.z + h.z_axis.x),
                0.5 * (h.y_axis.z + h.z_axis.y),
            ];
            (d.value.is_finite() && fields.iter().all(|v| v.is_finite()))
                .then_some((d.value, fields))
        })
        .collect();
    let smoothed = if time > 0.0 {
        smooth_fields(&raw, positions, radii, time)?
    } else {
        raw.iter().map(|r| r.map(|(_, f)| f)).collect()
    };
    Ok(positions
        .iter()
        .zip(raw.iter().zip(smoothed))
        .map(|(&position, (r, s))| {
            let (value, _) = (*r)?;
            let f = s?;
            let gradient = DVec3::new(f[0], f[1], f[2]);
            let hessian = DMat3::from_cols(
                DVec3::new(f[3], f[6], f[7]),
                DVec3::new(f[6], f[4], f[8]),
                DVec3::new(f[7], f[8], f[5]),
            );
            let eigen = ridge_eigen(&hessian, stretch)?;
            Some(VertexDerivatives {
                position,
                value,
                gradient,
                eigen,
            })
        })
        .collect())
}

/// One implicit heat step of each field over the sphere intersection graph of the defined
/// vertices; undefined vertices get `None`.
fn smooth_fields(
    raw: &[Option<(f64, [f64; FIELDS])>],
    positions: &[DVec3],
    radii: &[f64],
    time: f64,
) -> Result<Vec<Option<[f64; FIELDS]>>, SkeletonError> {
    let defined: Vec<usize> = (0..raw.len()).filter(|&i| raw[i].is_some()).collect();
    let mut out: Vec<Option<[f64; FIELDS]>> = vec![None; raw.len()];
    if defined.is_empty() {
        return Ok(out);
    }
    let centres: Vec<DVec3> = defined.iter().map(|&i| positions[i]).collect();
    let balls: Vec<f64> = defined.iter().map(|&i| radii[i]).collect();
    let graph = SphereIntersectionGraph::build(&centres, &balls, 1.0)
        .map_err(|e| SkeletonError::Smoothing(e.to_string()))?;
    let geometry = PairGeometry::build(&centres, &balls, &graph)
        .map_err(|e| SkeletonError::Smoothing(e.to_string()))?;
    let params = CgParams {
        relative_tolerance: 1e-10,
        ..CgParams::default()
    };
    let mut columns: Vec<Vec<f64>> = Vec::with_capacity(FIELDS);
    for k in 0..FIELDS {
        let u0: Vec<f64> = defined
            .iter()
            .map(|&i| raw[i].expect("defined").1[k])
            .collect();
        let (u, _) = implicit_smoothing(&geometry, MassKind::MomentMatched, time, &u0, &params)
            .map_err(|e| SkeletonError::Smoothing(e.to_string()))?;
        columns.push(u);
    }
    for (row, &i) in defined.iter().enumerate() {
        let mut f = [0.0; FIELDS];
        for (k, column) in columns.iter().enumerate() {
            f[k] = column[row];
        }
        out[i] = Some(f);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use sphcover_core::{Cover, Kernel, LocalFunctions, QuadraticFunction};

    /// One large support whose function is the quadratic `q`, and a jittered grid of
    /// vertices inside it with radii that make them overlap.
    fn setup(q: QuadraticFunction) -> (Cover, Vec<DVec3>, Vec<f64>) {
        let cover = Cover::new(
            vec![DVec3::ZERO],
            vec![100.0],
            LocalFunctions::from_quadratic([q]),
            Kernel::WendlandC2,
        )
        .unwrap();
        let mut positions = Vec::new();
        for k in 0..5 {
            for j in 0..5 {
                for i in 0..5 {
                    let jitter = 0.1 * (((i * 7 + j * 3 + k * 5) % 11) as f64 / 11.0 - 0.5);
                    positions.push(DVec3::new(i as f64, j as f64 + jitter, k as f64));
                }
            }
        }
        let radii = vec![1.3; positions.len()];
        (cover, positions, radii)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// A quadratic `f` has a constant Hessian; smoothing, which keeps constant fields,
        /// leaves the eigenvalues and the ridge direction as they were (to the solver's
        /// tolerance), whatever the time.
        #[test]
        fn constant_hessians_are_kept(a in -3.0..-0.5f64, b in -0.4..0.4f64, c in -0.4..0.4f64,
                                      time in 0.0..4.0f64) {
            let q = QuadraticFunction {
                a: DMat3::from_diagonal(DVec3::new(b, c, a)),
                b: DVec3::ZERO,
                k: 1.0,
            };
            let (cover, positions, radii) = setup(q);
            let eval = PuEvaluator::new(&cover, 1.0).unwrap();
            let plain = smoothed_vertex_derivatives(&eval, &positions, &radii, 0.0, None).unwrap();
            let smooth = smoothed_vertex_derivatives(&eval, &positions, &radii, time, None).unwrap();
            for (p, s) in plain.iter().zip(&smooth) {
                let (p, s) = (p.unwrap(), s.unwrap());
                for k in 0..3 {
                    prop_assert!((p.eigen.values[k] - s.eigen.values[k]).abs() < 1e-6 * a.abs());
                }
                prop_assert!(p.eigen.vector.dot(s.eigen.vector).abs() > 1.0 - 1e-9);
                prop_assert_eq!(p.value, s.value);
            }
        }
    }

    /// Smoothing damps the scatter of a field: a Hessian that alternates between two values
    /// from vertex to vertex moves towards their mean, and more so for a longer time.
    #[test]
    fn alternating_fields_are_damped() {
        let (_, positions, radii) = setup(QuadraticFunction {
            a: DMat3::ZERO,
            b: DVec3::ZERO,
            k: 1.0,
        });
        let raw: Vec<Option<(f64, [f64; FIELDS])>> = (0..positions.len())
            .map(|i| {
                let mut f = [0.0; FIELDS];
                f[5] = if i % 2 == 0 { -1.0 } else { -3.0 };
                Some((1.0, f))
            })
            .collect();
        let spread = |time: f64| {
            let out = smooth_fields(&raw, &positions, &radii, time).unwrap();
            let v: Vec<f64> = out.iter().map(|f| f.unwrap()[5]).collect();
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            assert!((mean + 2.0).abs() < 0.2, "{mean}");
            v.iter().map(|x| (x - mean).abs()).fold(0.0, f64::max)
        };
        let (short, long) = (spread(0.2), spread(2.0));
        assert!(short < 1.0, "{short}");
        assert!(long < short, "{long} vs {short}");
    }

    #[test]
    fn undefined_vertices_stay_undefined() {
        let (_, positions, radii) = setup(QuadraticFunction {
            a: DMat3::ZERO,
            b: DVec3::ZERO,
            k: 1.0,
        });
        let mut raw: Vec<Option<(f64, [f64; FIELDS])>> =
            vec![Some((1.0, [0.5; FIELDS])); positions.len()];
        raw[3] = None;
        let out = smooth_fields(&raw, &positions, &radii, 1.0).unwrap();
        assert!(out[3].is_none());
        assert!(out.iter().enumerate().all(|(i, f)| i == 3 || f.is_some()));
    }
}
