//! The overlap complex of a cover: the tetrahedra of the regular triangulation of the support
//! centres (weights `r²`) whose four balls overlap pairwise.
//!
//! The method is described on [`overlap_complex()`].

use sphcover_core::DVec3;

use crate::dual_complex::{DualComplex, DualComplexParams, complex_of, cover_triangulation};
use crate::error::TetraError;
use crate::expansion::{Bounded, Expansion, Ring};
use crate::predicates::Point;
use crate::regular::RegularTriangulation;

/// Builds the overlap complex of the cover `(centres, radii)` with the radius shrink and seed
/// of `params`: the finite tetrahedra of the regular triangulation (weights `(σ_t r)²`, as
/// for [`dual_complex()`](crate::dual_complex())) whose four balls of radii `σ_t r` overlap
/// pairwise.
///
/// The dual complex asks more: that the four balls share a point (the orthocentre has power
/// ≤ 0), so its tetrahedra are all here, and both complexes agree where the balls overlap
/// deeply. They part where the supports lie in a thin slab, as across a plate two or three
/// voxels thick: there the triangulation's tetrahedra are flat, their orthocentres lie far
/// outside the slab, and the dual complex keeps few of them, while the balls of those
/// tetrahedra still overlap pairwise. A sheet drawn through the tetrahedra (ridge patches)
/// then has the tetrahedra it needs on both sides of every ridge edge.
///
/// Overlap is strict, `‖c_i − c_j‖ < σ_t (r_i + r_j)`, decided exactly on the
/// triangulation's scaled copy of its input (balls that only touch do not overlap). Errors:
/// those of [`dual_complex()`](crate::dual_complex()).
///
/// ```
/// use sphcover_core::DVec3;
/// use sphcover_tetra::{DualComplexParams, dual_complex, overlap_complex};
///
/// // Four balls of radius 0.52 at the corners of a regular tetrahedron of edge 1: each pair
/// // overlaps (1 < 2 × 0.52), but the centre lies √6/4 ≈ 0.61 from every corner, so no point
/// // is in all four.
/// let centres = [
///     DVec3::new(0.0, 0.0, 0.0),
///     DVec3::new(1.0, 0.0, 0.0),
///     DVec3::new(0.5, 3f64.sqrt() / 2.0, 0.0),
///     DVec3::new(0.5, 3f64.sqrt() / 6.0, (2.0f64 / 3.0).sqrt()),
/// ];
/// let radii = [0.52; 4];
/// let params = DualComplexParams { shrink: 1.0, ..Default::default() };
/// assert!(dual_complex(&centres, &radii, &params)?.tets.is_empty());
/// assert_eq!(overlap_complex(&centres, &radii, &params)?.tets.len(), 1);
/// # Ok::<(), sphcover_tetra::TetraError>(())
/// ```
pub fn overlap_complex(
    centres: &[DVec3],
    radii: &[f64],
    params: &DualComplexParams,
) -> Result<DualComplex, TetraError> {
    Ok(overlap_complex_of(&cover_triangulation(
        centres, radii, params,
    )?))
}

/// The overlap complex of an existing triangulation: its finite tetrahedra whose balls
/// (radius² = the triangulation's weights) overlap pairwise (see [`overlap_complex()`]).
pub fn overlap_complex_of(tri: &RegularTriangulation) -> DualComplex {
    complex_of(tri, |cell| overlap_pairwise(tri, cell, 1.0))
}

/// [`overlap_complex()`] and, besides, the tetrahedra whose balls grown by the factor
/// `growth` (radii `growth · σ_t r`) overlap pairwise and that `admit` accepts; `admit` is
/// given the tetrahedron's four input indices and is asked only about those tetrahedra.
///
/// A caller that knows where its sheet may lie can so add the flat tetrahedra of a slab
/// thinner than its balls reach across without adding the large ones elsewhere. A growth
/// that is a power of two keeps the test exact (the grown weights `growth² · (σ_t r)²` are
/// then exact); any other growth rounds each grown weight once. Errors: those of
/// [`dual_complex()`](crate::dual_complex()), and [`TetraError::InvalidGrowth`] for a
/// growth below 1 or not finite.
///
/// ```
/// use sphcover_core::DVec3;
/// use sphcover_tetra::{DualComplexParams, overlap_complex, overlap_complex_admitting};
///
/// // Radius 0.4 at the corners of a regular tetrahedron of edge 1: no two balls overlap,
/// // while the balls grown twice (radius 0.8) overlap pairwise.
/// let centres = [
///     DVec3::new(0.0, 0.0, 0.0),
///     DVec3::new(1.0, 0.0, 0.0),
///     DVec3::new(0.5, 3f64.sqrt() / 2.0, 0.0),
///     DVec3::new(0.5, 3f64.sqrt() / 6.0, (2.0f64 / 3.0).sqrt()),
/// ];
/// let radii = [0.4; 4];
/// let params = DualComplexParams { shrink: 1.0, ..Default::default() };
/// assert!(overlap_complex(&centres, &radii, &params)?.tets.is_empty());
/// let admitted = overlap_complex_admitting(&centres, &radii, &params, 2.0, |_| true)?;
/// assert_eq!(admitted.tets.len(), 1);
/// let refused = overlap_complex_admitting(&centres, &radii, &params, 2.0, |_| false)?;
/// assert!(refused.tets.is_empty());
/// # Ok::<(), sphcover_tetra::TetraError>(())
/// ```
pub fn overlap_complex_admitting(
    centres: &[DVec3],
    radii: &[f64],
    params: &DualComplexParams,
    growth: f64,
    admit: impl Fn([u32; 4]) -> bool + Sync,
) -> Result<DualComplex, TetraError> {
    if !(growth.is_finite() && growth >= 1.0) {
        return Err(TetraError::InvalidGrowth(growth));
    }
    let tri = cover_triangulation(centres, radii, params)?;
    let grown = growth * growth;
    Ok(complex_of(&tri, |cell| {
        overlap_pairwise(&tri, cell, 1.0)
            || (grown > 1.0 && overlap_pairwise(&tri, cell, grown) && admit(cell))
    }))
}

/// Whether the balls of `cell`'s four vertices, their weights times `weight_factor`, overlap
/// pairwise.
fn overlap_pairwise(tri: &RegularTriangulation, cell: [u32; 4], weight_factor: f64) -> bool {
    (0..4).all(|a| {
        (a + 1..4).all(|b| {
            let (u, v) = (cell[a], cell[b]);
            balls_overlap(
                tri.point(u),
                tri.point(v),
                weight_factor * tri.scaled_weight(u),
                weight_factor * tri.scaled_weight(v),
            )
        })
    })
}

/// Whether the open balls of centres `p`, `q` and squared radii `wp`, `wq` (non-negative)
/// overlap, `‖p − q‖ < √wp + √wq`, decided exactly: with `s = ‖p − q‖² − wp − wq`, they
/// overlap when `s < 0`, or when `s ≥ 0` and `s² < 4 wp wq`. A floating-point evaluation with
/// a running error bound decides nearly every pair; expansions decide the rest. Needs inputs
/// whose products stay in range, as the triangulation's scaled copy guarantees.
pub(crate) fn balls_overlap(p: &Point, q: &Point, wp: f64, wq: f64) -> bool {
    let (s, t) = overlap_polynomials::<Bounded>(p, q, wp, wq);
    match s.certain_sign() {
        Some(-1) => return true,
        Some(_) => {
            if let Some(sign) = t.certain_sign() {
                return sign < 0;
            }
        }
        None => {}
    }
    let (s, t) = overlap_polynomials::<Expansion>(p, q, wp, wq);
    s.sign() < 0 || t.sign() < 0
}

/// `(s, s² − 4 wp wq)` with `s = ‖p − q‖² − wp − wq`.
fn overlap_polynomials<R: Ring>(p: &Point, q: &Point, wp: f64, wq: f64) -> (R, R) {
    let d: [R; 3] = std::array::from_fn(|k| R::input_diff(p[k], q[k]));
    let d2 = d[0].mul(&d[0]).add(&d[1].mul(&d[1])).add(&d[2].mul(&d[2]));
    let s = d2.sub(&R::input(wp)).sub(&R::input(wq));
    // `4 wp` is exact: a power-of-two scaling of a weight in the exact range.
    let t = s.mul(&s).sub(&R::input(4.0 * wp).mul(&R::input(wq)));
    (s, t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The overlap of integer balls in exact integer arithmetic: `d² < (rp + rq)²` with
    /// `wp = rp²`, `wq = rq²` perfect squares.
    fn overlap_oracle(p: [i64; 3], q: [i64; 3], rp: i64, rq: i64) -> bool {
        let d2: i128 = (0..3).map(|k| ((p[k] - q[k]) as i128).pow(2)).sum();
        d2 < ((rp + rq) as i128).pow(2)
    }

    #[test]
    fn a_growth_below_one_or_not_finite_is_refused() {
        let centres = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        let params = DualComplexParams::default();
        for growth in [0.5, f64::NAN, f64::INFINITY] {
            let got = overlap_complex_admitting(&centres, &[1.0; 4], &params, growth, |_| true);
            assert!(
                matches!(got, Err(TetraError::InvalidGrowth(g)) if g.to_bits() == growth.to_bits()),
                "{growth}"
            );
        }
    }

    proptest! {
        /// On integer centres and radii (ties included, at every power-of-two scale) the
        /// predicate is the exact integer comparison.
        #[test]
        fn the_overlap_test_is_exact(
            p in prop::array::uniform3(-40i64..40),
            q in prop::array::uniform3(-40i64..40),
            (rp, rq) in (0i64..40, 0i64..40),
            scale in -60i32..60,
        ) {
            let f = |x: i64| x as f64 * 2f64.powi(scale);
            let (pf, qf) = (p.map(f), q.map(f));
            let (wp, wq) = (f(rp) * f(rp), f(rq) * f(rq));
            prop_assert_eq!(balls_overlap(&pf, &qf, wp, wq), overlap_oracle(p, q, rp, rq));
            prop_assert_eq!(balls_overlap(&qf, &pf, wq, wp), overlap_oracle(p, q, rp, rq));
        }

        /// Balls placed to touch (up to the rounding of the centre): the filtered test agrees
        /// with the exact one, and moving a hair nearer or farther decides.
        #[test]
        fn near_touching_balls_are_decided_exactly(
            rp in 0.1..10.0f64,
            rq in 0.1..10.0f64,
            direction in prop::array::uniform3(-1.0..1.0f64),
        ) {
            let u = DVec3::from_array(direction);
            prop_assume!(u.length() > 0.1);
            let u = u / u.length();
            let q = u * (rp + rq);
            let (wp, wq) = (rp * rp, rq * rq);
            let exact = overlap_polynomials::<Expansion>(&[0.0; 3], &q.to_array(), wp, wq);
            let expected = exact.0.sign() < 0 || exact.1.sign() < 0;
            prop_assert_eq!(balls_overlap(&[0.0; 3], &q.to_array(), wp, wq), expected);
            let nearer = q * (1.0 - 1e-9);
            prop_assert!(balls_overlap(&[0.0; 3], &nearer.to_array(), wp, wq));
            let farther = q * (1.0 + 1e-9);
            prop_assert!(!balls_overlap(&[0.0; 3], &farther.to_array(), wp, wq));
        }
    }
}
