//! What the reconstruction refuses before it starts: points on a line without normals (no
//! surface is determined: every plane through the line fits), flat sets (on a plane, or on a
//! line with normals) without trimming, and scans whose bounding box a far point blows up so
//! much that the rest of the scan cannot be resolved in it. These used to fail inside a later
//! stage or return a mesh of the bounding box's size.
//!
//! A flat set is a legitimate open sheet (a scanned flat part), but it encloses nothing: the
//! untrimmed surface is the sheet's plane extrapolated over the whole bounding cube (91K
//! triangles for 2,000 points in a unit square, reaching 1.4 units past it). With `Trim` the
//! pipeline reconstructs the flat sheet the samples cover.

use sphcover_core::{DMat3, DVec3, SymmetricEigen3};

use super::ReconError;

/// A set whose spread (standard deviation) across its best line is below this fraction of its
/// spread along it lies on that line: no scanner resolves a millionth of its field.
const FLAT_RATIO: f64 = 1e-6;

/// A point farther than this many median radii from the scan's median centre is refused: in
/// the frame of a bounding box stretched to it, the rest of the scan's coordinates keep fewer
/// than about 20 of their 52 bits, too few to measure its spacing before isolated points are
/// dropped and the frame follows the rest. Nearer outliers are dropped as isolated.
const FAR_RATIO: f64 = 1e9;

/// Checks the finite input `points` (`oriented`: they come with normals; `trimmed`: the
/// surface is trimmed to them); `index` maps a point back to its input index (for the
/// message).
pub(super) fn check_spread(
    points: &[DVec3],
    index: &[usize],
    oriented: bool,
    trimmed: bool,
) -> Result<(), ReconError> {
    if let Some((far, ratio)) = farthest_beyond(points, FAR_RATIO) {
        return Err(ReconError::FarPoint {
            index: index[far],
            position: points[far],
            ratio,
        });
    }
    let [thickness, across, along] = principal_spreads(points);
    if !oriented && across <= FLAT_RATIO * along {
        return Err(ReconError::Collinear);
    }
    if !trimmed && thickness <= FLAT_RATIO * along {
        return Err(ReconError::Flat);
    }
    Ok(())
}

/// The point farthest from the coordinate-wise median centre and its distance in median
/// distances, when that exceeds `ratio`. `None` when the median distance is zero (more than
/// half the points coincide: the coincidence checks speak to that).
fn farthest_beyond(points: &[DVec3], ratio: f64) -> Option<(usize, f64)> {
    let median = |mut v: Vec<f64>| -> f64 {
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let centre = DVec3::new(
        median(points.iter().map(|p| p.x).collect()),
        median(points.iter().map(|p| p.y).collect()),
        median(points.iter().map(|p| p.z).collect()),
    );
    let distances: Vec<f64> = points.iter().map(|&p| distance(p, centre)).collect();
    let typical = median(distances.clone());
    if typical <= 0.0 {
        return None;
    }
    let (far, &distance) = distances
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))?;
    let r = distance / typical;
    (r > ratio).then_some((far, r))
}

/// `‖a − b‖` without overflow for coordinates up to `f64::MAX / 2` (a point at 1e300 is
/// what this check is for).
fn distance(a: DVec3, b: DVec3) -> f64 {
    let d = a - b;
    let largest = d.abs().max_element();
    if largest > 0.0 {
        largest * (d / largest).length()
    } else {
        0.0
    }
}

/// Standard deviations of `points` along their principal axes, ascending.
fn principal_spreads(points: &[DVec3]) -> [f64; 3] {
    let n = points.len() as f64;
    let mean = points.iter().copied().sum::<DVec3>() / n;
    let mut covariance = DMat3::ZERO;
    for p in points {
        let d = *p - mean;
        covariance += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    covariance *= 1.0 / n;
    SymmetricEigen3::of(&covariance).map_or([0.0; 3], |e| e.values.map(|v| v.max(0.0).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sphere(n: usize) -> Vec<DVec3> {
        sphcover_core::synthetic::fibonacci_sphere(n)
    }

    proptest! {
        /// Points on any line through any point, at any scale, are refused without normals
        /// and kept with them when trimmed (the normals choose the plane); lifting one point
        /// off the line by a visible amount makes a plane, kept when trimmed; lifting another
        /// off that plane makes a solid set, kept either way.
        #[test]
        fn lines_and_planes_are_refused_at_any_orientation_and_scale(
            direction in proptest::array::uniform3(-1.0f64..1.0),
            origin in proptest::array::uniform3(-1e3f64..1e3),
            scale in 1e-3f64..1e3,
        ) {
            let direction = DVec3::from(direction);
            prop_assume!(direction.length() > 0.1);
            let direction = direction.normalize();
            let mut points: Vec<DVec3> = (0..200)
                .map(|i| DVec3::from(origin) + scale * i as f64 * direction)
                .collect();
            let index: Vec<usize> = (0..points.len()).collect();
            let check = |points: &[DVec3], oriented, trimmed| {
                check_spread(points, &index, oriented, trimmed)
            };
            for trimmed in [false, true] {
                prop_assert!(matches!(check(&points, false, trimmed), Err(ReconError::Collinear)));
            }
            prop_assert!(matches!(check(&points, true, false), Err(ReconError::Flat)));
            prop_assert!(check(&points, true, true).is_ok());
            let (u, v) = direction.any_orthonormal_pair();
            points[0] += 10.0 * scale * u;
            for oriented in [false, true] {
                prop_assert!(matches!(check(&points, oriented, false), Err(ReconError::Flat)));
                prop_assert!(check(&points, oriented, true).is_ok());
            }
            points[1] += 10.0 * scale * v;
            for (oriented, trimmed) in [(false, false), (true, false), (false, true), (true, true)] {
                prop_assert!(check(&points, oriented, trimmed).is_ok());
            }
        }
    }

    #[test]
    fn one_far_point_is_named_and_outliers_within_reach_are_kept() {
        let mut points = sphere(500);
        let index: Vec<usize> = (10..510).collect();
        // Outliers 10^6 radii away are dropped as isolated, not refused.
        points[7] = DVec3::new(1e6, 0.0, 0.0);
        assert!(check_spread(&points, &index, false, false).is_ok());
        points[3] = DVec3::new(1e300, 0.0, 0.0);
        match check_spread(&points, &index, false, false) {
            Err(ReconError::FarPoint { index, ratio, .. }) => {
                assert_eq!(index, 13);
                assert!(ratio > 1e299 && ratio.is_finite(), "{ratio}");
            }
            other => panic!("{other:?}"),
        }
    }
}
