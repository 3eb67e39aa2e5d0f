//! Which samples of a support its linear local function fits where one ball holds two faces
//! of a thin part (beyond the thesis).
//!
//! The linear local function of a support (thesis eq. 3.2) takes the weighted mean normal and
//! centroid of its samples. When the ball holds both faces of a wall thinner than itself, or
//! two surfaces facing each other across a narrow gap, the normals cancel and the plane lands
//! between the faces: the blend then puts the zero set inside the wall from both sides, so the
//! wall thins until it breaks (holes through fins, extra handles) or surface grows into the
//! gap. On a generated housing with 0.7 mm fins, sampled noise-free with 200K points, the
//! output had genus 63 instead of 11.
//!
//! As MPU does for thin structures (Ohtake et al. 2003), such a support fits only the face of
//! the sample nearest its centre, unless the samples turned away from that sample's normal by
//! more than 120° ([`faces_away`]) weigh more ([`face_to_fit`]). The test applies only where
//! the normals disagree at all ([`may_hold_opposite_faces`]), so a smooth or merely curved
//! patch is fitted as before, and a crease or a corner (normals 90° apart, none turned away)
//! keeps all its samples.
//!
//! Which samples make the face ([`Face::holds`]): with [`FaceSelection::Narrow`], those within
//! 60° of its normal ([`FACE_COSINE`]) where the ball does hold samples turned away. Within
//! 120°, the face would keep the faces at right angles to it: a ball in the gap beside a rib
//! fits the rib's side and its top together, a plane tilted towards the gap whose inside
//! reaches into the gap below the top (on the housing's 1.3 mm gaps the tops of neighbouring
//! ribs grew towards each other and met). [`FaceSelection::Wide`] keeps the 120° bound everywhere; the
//! reconstruction uses it unless the scan is nearly free of noise: on a noisy building scan
//! the narrow cone left more of the seen surface out (`docs/algorithms.md`, *Surface
//! reconstruction*, has the figures).

use glam::DVec3;

/// A support's unit normals whose weighted resultant is at least this fraction of their
/// weight agree well enough that no two of them are opposite faces worth separating.
pub const COHERENT_RESULTANT: f64 = 0.9;

/// `cos` of the smallest angle between two normals of opposite faces (120°).
pub const OPPOSED_COSINE: f64 = -0.5;

/// Where a support's ball holds samples facing away from its face, the samples whose normal
/// is within `acos(FACE_COSINE)` = 60° of the face's make the face
/// ([`FaceSelection::Narrow`]).
pub const FACE_COSINE: f64 = 0.5;

/// Which samples make the face a support fits ([`face_to_fit`], [`Face::holds`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FaceSelection {
    /// Where the ball holds samples facing away from the face, those within 60° of its
    /// normal; elsewhere those not facing away (all of them).
    Narrow,
    /// Those not facing away from the face (within 120° of its normal).
    #[default]
    Wide,
}

/// The face a support fits: its normal, and which samples belong to it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Face {
    normal: DVec3,
    /// A sample belongs when the cosine of its angle to `normal` is not below this.
    cosine: f64,
}

impl Face {
    /// The normal of the sample that chose the face.
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// Whether a sample with `normal` (of any length) belongs to the face. A zero or
    /// non-finite normal faces nowhere and belongs.
    pub fn holds(&self, normal: DVec3) -> bool {
        !turned_beyond(self.normal, normal, self.cosine)
    }
}

/// Whether a support whose samples' normals (unit, or of any length in `normal_sum` as long
/// as `weight` sums the same weights times their lengths) sum to `normal_sum` with total
/// `weight` may hold opposite faces, and so should be fitted to one face only
/// ([`face_to_fit`]).
///
/// ```
/// use sphcover_core::{DVec3, may_hold_opposite_faces};
///
/// // Both faces of a wall, 60% of the weight on one: the normals nearly cancel.
/// assert!(may_hold_opposite_faces(1.0, DVec3::Z * 0.6 - DVec3::Z * 0.4));
/// // One flat face.
/// assert!(!may_hold_opposite_faces(1.0, DVec3::Z));
/// ```
pub fn may_hold_opposite_faces(weight: f64, normal_sum: DVec3) -> bool {
    weight > 0.0 && normal_sum.length() < COHERENT_RESULTANT * weight
}

/// Whether a sample with `normal` lies on the face opposite the one whose normal is
/// `reference` (neither needs unit length; a zero normal faces nowhere and is kept).
///
/// ```
/// use sphcover_core::{DVec3, faces_away};
///
/// assert!(faces_away(DVec3::Z, -DVec3::Z));
/// // A crease (90°) is one surface, not two faces.
/// assert!(!faces_away(DVec3::Z, DVec3::X));
/// ```
pub fn faces_away(reference: DVec3, normal: DVec3) -> bool {
    turned_beyond(reference, normal, OPPOSED_COSINE)
}

/// Whether the angle between `reference` and `normal` has a cosine below `cosine` (false
/// when either is zero or not finite).
fn turned_beyond(reference: DVec3, normal: DVec3, cosine: f64) -> bool {
    reference.dot(normal) < cosine * (reference.length() * normal.length())
}

/// The face a support should fit, or `None` when its samples' normals agree
/// ([`may_hold_opposite_faces`] of `weight` and `normal_sum`, their sums).
///
/// `samples` calls its argument with the normal, squared distance from the centre and
/// weight of every sample of the support, in a fixed order (it is called twice). The face is
/// the nearest sample's, unless the samples facing away from that one weigh more: then it is
/// the face of the nearest of those. So a stray sample nearest the centre (an outlier whose
/// normal says nothing) does not choose the face, while across a thin wall the nearer face,
/// which the kernel weighs more, does. `selection` says which samples belong to the face
/// ([`Face::holds`]).
///
/// ```
/// use sphcover_core::{DVec3, FaceSelection, face_to_fit};
///
/// // Two faces of a wall, the upper (normal +z) nearer the centre, one stray sample nearer
/// // still with a normal that faces down, and the wall's end face (normal +x).
/// let samples = [
///     (DVec3::Z, 0.04, 1.0), (DVec3::Z, 0.05, 1.0), (DVec3::Z, 0.06, 1.0),
///     (-DVec3::Z, 0.09, 0.8), (-DVec3::Z, 0.10, 0.8),
///     (-DVec3::Z, 0.01, 0.3),
///     (DVec3::X, 0.08, 0.5),
/// ];
/// let (weight, normal_sum) = samples
///     .iter()
///     .fold((0.0, DVec3::ZERO), |(w, n), s| (w + s.2, n + s.2 * s.0));
/// let face = |selection| {
///     face_to_fit(weight, normal_sum, selection, |visit| {
///         for &(n, d2, w) in &samples {
///             visit(n, d2, w);
///         }
///     })
///     .unwrap()
/// };
/// let narrow = face(FaceSelection::Narrow);
/// assert_eq!(narrow.normal(), DVec3::Z);
/// assert!(narrow.holds(DVec3::Z) && !narrow.holds(-DVec3::Z) && !narrow.holds(DVec3::X));
/// // The wide selection keeps the end face, at right angles to the chosen one.
/// let wide = face(FaceSelection::Wide);
/// assert!(wide.holds(DVec3::Z) && !wide.holds(-DVec3::Z) && wide.holds(DVec3::X));
/// ```
pub fn face_to_fit(
    weight: f64,
    normal_sum: DVec3,
    selection: FaceSelection,
    samples: impl Fn(&mut dyn FnMut(DVec3, f64, f64)),
) -> Option<Face> {
    if !may_hold_opposite_faces(weight, normal_sum) {
        return None;
    }
    let nearest_where = |keep: &dyn Fn(DVec3) -> bool| {
        let mut nearest: Option<(f64, DVec3)> = None;
        let mut weight = 0.0;
        samples(&mut |n, d2, w| {
            if w > 0.0 && keep(n) {
                weight += w;
                if nearest.is_none_or(|(best, _)| d2 < best) {
                    nearest = Some((d2, n));
                }
            }
        });
        nearest.map(|(_, n)| (n, weight))
    };
    let (first, total) = nearest_where(&|_| true)?;
    let away = nearest_where(&|n| faces_away(first, n));
    let cosine = match (selection, away) {
        (FaceSelection::Narrow, Some(_)) => FACE_COSINE,
        _ => OPPOSED_COSINE,
    };
    let normal = match away {
        Some((other, away)) if away > total - away => other,
        _ => first,
    };
    Some(Face { normal, cosine })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn direction(theta: f64, phi: f64) -> DVec3 {
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    proptest! {
        /// Opposition depends on the angle alone: symmetric, blind to the normals' lengths,
        /// and exactly the normals more than `acos(OPPOSED_COSINE)` apart.
        #[test]
        fn faces_away_is_the_angle_test(
            t1 in 0.0..std::f64::consts::PI, p1 in 0.0..std::f64::consts::TAU,
            t2 in 0.0..std::f64::consts::PI, p2 in 0.0..std::f64::consts::TAU,
            l1 in 0.01f64..100.0, l2 in 0.01f64..100.0,
        ) {
            let (a, b) = (direction(t1, p1), direction(t2, p2));
            let away = faces_away(a, b);
            prop_assert_eq!(away, faces_away(l2 * b, l1 * a));
            let angle = a.dot(b).clamp(-1.0, 1.0).acos();
            let bound = OPPOSED_COSINE.acos();
            if (angle - bound).abs() > 1e-9 {
                prop_assert_eq!(away, angle > bound);
            }
        }

        /// Samples of one face never look like two, whatever their weights; those of two
        /// opposite faces do unless one face carries nearly all the weight.
        #[test]
        fn one_face_is_coherent_and_two_are_not(
            weights in proptest::collection::vec(0.01f64..1.0, 1..20),
            t in 0.0..std::f64::consts::PI, p in 0.0..std::f64::consts::TAU,
            share in 0.0f64..1.0,
        ) {
            let n = direction(t, p);
            let w: f64 = weights.iter().sum();
            let sum = weights.iter().fold(DVec3::ZERO, |s, &k| s + k * n);
            prop_assert!(!may_hold_opposite_faces(w, sum));
            // Two faces, `share` of the weight on the second.
            let two = (1.0 - share) * w * n - share * w * n;
            let resultant = (1.0 - 2.0 * share).abs();
            if (resultant - COHERENT_RESULTANT).abs() > 1e-9 {
                prop_assert_eq!(may_hold_opposite_faces(w, two), resultant < COHERENT_RESULTANT);
            }
        }
    }

    /// Samples as `(normal, squared distance, weight)`.
    fn face_with(samples: &[(DVec3, f64, f64)], selection: FaceSelection) -> Option<Face> {
        let (w, n) = samples
            .iter()
            .fold((0.0, DVec3::ZERO), |(w, n), s| (w + s.2, n + s.2 * s.0));
        face_to_fit(w, n, selection, |visit| {
            for &(n, d2, w) in samples {
                visit(n, d2, w);
            }
        })
    }

    fn face_of(samples: &[(DVec3, f64, f64)]) -> Option<DVec3> {
        face_with(samples, FaceSelection::Narrow).map(|f| f.normal())
    }

    /// The angle between two directions, in degrees.
    fn degrees(a: DVec3, b: DVec3) -> f64 {
        (a.dot(b) / (a.length() * b.length()))
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    proptest! {
        /// Where the ball holds samples facing away from the face, the narrow selection
        /// keeps exactly the normals within 60° of the face's, the wide one those within
        /// 120°. Where it holds none (a crease: faces at right angles), both keep the same.
        #[test]
        fn the_face_holds_the_normals_within_its_cone(
            near in proptest::collection::vec((0.0f64..1.0, 0.01f64..1.0), 1..8),
            away in proptest::collection::vec((0.0f64..1.0, 0.01f64..1.0), 1..8),
            opposite in proptest::bool::ANY,
            t in 0.0..std::f64::consts::PI, p in 0.0..std::f64::consts::TAU,
            length in 0.01f64..10.0,
        ) {
            // The second face is opposite (−z) or at right angles (+x) to the first.
            let second = if opposite { -DVec3::Z } else { DVec3::X };
            let samples: Vec<(DVec3, f64, f64)> = near
                .iter()
                .map(|&(d2, w)| (DVec3::Z, d2, w))
                .chain(away.iter().map(|&(d2, w)| (second, d2, w)))
                .collect();
            let probe = length * direction(t, p);
            match (face_with(&samples, FaceSelection::Narrow), face_with(&samples, FaceSelection::Wide)) {
                (Some(narrow), Some(wide)) => {
                    prop_assert_eq!(narrow.normal(), wide.normal());
                    let angle = degrees(wide.normal(), probe);
                    if (angle - 120.0).abs() > 1e-6 {
                        prop_assert_eq!(wide.holds(probe), angle < 120.0);
                    }
                    if !opposite {
                        prop_assert_eq!(narrow.holds(probe), wide.holds(probe));
                    } else if (angle - 60.0).abs() > 1e-6 {
                        prop_assert_eq!(narrow.holds(probe), angle < 60.0);
                    }
                    prop_assert!(narrow.holds(DVec3::ZERO) && wide.holds(DVec3::ZERO));
                }
                (narrow, wide) => {
                    prop_assert!(narrow.is_none() && wide.is_none());
                    // Only samples that agree have no face to choose.
                    let (w, n) = samples
                        .iter()
                        .fold((0.0, DVec3::ZERO), |(w, n), s| (w + s.2, n + s.2 * s.0));
                    prop_assert!(!may_hold_opposite_faces(w, n));
                }
            }
        }
    }

    proptest! {
        /// Across a wall (faces `+z` and `−z`, each sample with its own distance and
        /// weight), the face fitted is the nearest sample's, or the other one where that
        /// weighs more; samples without weight never choose. The order of the samples does
        /// not matter (distances are distinct).
        #[test]
        fn the_face_is_the_nearest_sample_s_unless_outweighed(
            up in proptest::collection::vec((0.0f64..1.0, 0.01f64..1.0), 1..12),
            down in proptest::collection::vec((0.0f64..1.0, 0.01f64..1.0), 1..12),
            weightless in 0.0f64..1.0,
            rotation in 0usize..24,
        ) {
            let mut samples: Vec<(DVec3, f64, f64)> = up
                .iter()
                .map(|&(d2, w)| (DVec3::Z, d2, w))
                .chain(down.iter().map(|&(d2, w)| (-DVec3::Z, d2, w)))
                .collect();
            samples.push((DVec3::X, weightless * 1e-3, 0.0));
            let (w_up, w_down): (f64, f64) =
                (up.iter().map(|s| s.1).sum(), down.iter().map(|s| s.1).sum());
            let face = face_of(&samples);
            let nearest = samples
                .iter()
                .filter(|s| s.2 > 0.0)
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap()
                .0;
            let (own, other) = if nearest == DVec3::Z { (w_up, w_down) } else { (w_down, w_up) };
            if (w_up - w_down).abs() >= COHERENT_RESULTANT * (w_up + w_down) {
                prop_assert_eq!(face, None);
            } else if other > own {
                prop_assert_eq!(face, Some(-nearest));
            } else {
                prop_assert_eq!(face, Some(nearest));
            }
            let len = samples.len();
            samples.rotate_left(rotation % len);
            prop_assert_eq!(face_of(&samples), face);
        }
    }

    #[test]
    fn no_weight_is_no_face() {
        assert!(!may_hold_opposite_faces(0.0, DVec3::ZERO));
        assert!(!faces_away(DVec3::Z, DVec3::ZERO));
    }
}
