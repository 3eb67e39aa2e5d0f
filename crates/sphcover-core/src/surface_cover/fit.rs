//! The local linear fit of a support to oriented points (thesis eq. 3.2) and its error.
//!
//! With kernel weights `w_j = ψ(‖p_j − c‖ / r)` (times the point's confidence, when given):
//!
//! ```text
//! n̄ = Σ w_j n_j / ‖Σ w_j n_j‖,   p̄ = Σ w_j p_j / Σ w_j,   g(x) = n̄·(p̄ − x)
//! ```
//!
//! so `α = −n̄` and `β = n̄·(p̄ − c)` in the centred form, positive inside for outward
//! normals. Where the ball holds two opposite faces of a thin part, the sums run over one face
//! only ([`crate::face_to_fit`]). The error is `E = max_j |g(p_j)|` over all the points in the
//! open ball (points of zero confidence excluded). Both are single passes over the candidate
//! points (three more for a ball across a thin part), which sum offsets from the centre so the
//! sums stay well conditioned for small balls far from the origin. The candidates are slots of
//! the point index: a ball's points lie in a few runs of consecutive slots, so the passes still
//! read memory nearly sequentially.

use crate::kernel::Kernel;
use crate::local_function::LinearFunction;
use crate::opposite_faces::{FaceSelection, face_to_fit};
use crate::point_index::{PointIndex, keep_inside};
use glam::DVec3;
use std::borrow::Cow;

/// Candidates per check of the error pass's early exit (see [`Candidates::fit`]).
const ERROR_RUN: usize = 16;

/// The oriented points of the build, in the slot order of the point index.
#[derive(Debug)]
pub(crate) struct Samples<'i> {
    /// The point index (holds the positions in slot order): the caller's when it indexes
    /// exactly the points used, else the build's own.
    pub index: Cow<'i, PointIndex>,
    /// Unit normals in slot order.
    pub normals: Vec<DVec3>,
    /// Confidences in slot order, when given.
    pub confidence: Option<Vec<f64>>,
    /// Which samples make the face of a support across a thin part.
    pub faces: FaceSelection,
}

/// The result of a fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Fit {
    /// Unit mean normal `n̄`.
    pub normal: DVec3,
    /// Weighted centroid offset `p̄ − c`.
    pub centroid: DVec3,
    /// `E = max |g(p_j)|`, or a value above the early-exit limit when it was exceeded.
    pub error: f64,
}

impl Fit {
    /// The local function in centred form.
    pub fn linear(&self) -> LinearFunction {
        LinearFunction {
            alpha: -self.normal,
            beta: self.normal.dot(self.centroid),
        }
    }
}

/// Candidate points of one support: the slots of the points in the ball of the last gather
/// (in tree order) and their squared distances from its centre. The fits read positions,
/// normals and confidences through the slots: copying them here wrote 56 bytes per point
/// and gather, against 12, and a support gathers once per doubling of its radius but fits
/// only a few times more.
#[derive(Debug, Default)]
pub(crate) struct Candidates {
    centre: DVec3,
    slots: Vec<u32>,
    dist2: Vec<f64>,
}

impl Candidates {
    /// Number of candidates.
    pub fn len(&self) -> usize {
        self.dist2.len()
    }

    /// Gathers the points with `‖p − c‖² < r²`, in tree order.
    pub fn gather(&mut self, samples: &Samples<'_>, c: DVec3, r: f64) {
        self.centre = c;
        self.slots.clear();
        self.dist2.clear();
        samples
            .index
            .extend_within(c, r, &mut self.slots, Some(&mut self.dist2));
    }

    /// Drops the candidates with `distance² ≥ r²`, keeping the others in order. Exact for
    /// every later fit whose radius `ρ` has `ρ² ≤ r² / (1 + 1e-6)`: the dropped candidates
    /// would get kernel weight exactly 0 there (`s = d²/ρ² > 1`, with a margin far above
    /// rounding) and count as 0 in the error pass, so the sums do not change by a bit, nor
    /// the error of a fit within its limit (one above it stays above).
    pub fn keep_within(&mut self, r: f64) {
        let kept = keep_inside(&mut self.slots, &mut self.dist2, r * r);
        self.slots.truncate(kept);
        self.dist2.truncate(kept);
    }

    /// The slots of the candidates, in order.
    pub fn slots(&self) -> &[u32] {
        &self.slots
    }

    /// Fits the candidates inside the ball of radius `r` (at most the gather radius) with
    /// kernel radius `r`, reading them from `samples` (those of the gather). Candidates
    /// outside get weight 0 from the kernel and count as 0 in the error pass, so one gather
    /// at the largest radius serves every smaller trial. The error pass stops once `E`
    /// exceeds `limit`, tested every [`ERROR_RUN`] candidates, and then returns a value
    /// above `limit` rather than `E` (pass `f64::INFINITY` for the exact error). `None` when
    /// no candidate lies inside.
    pub fn fit(&self, samples: &Samples<'_>, r: f64, kernel: Kernel, limit: f64) -> Option<Fit> {
        let len = self.len();
        let r2 = r * r;
        let c = self.centre;
        let points = samples.index.slot_points();
        let normals = &samples.normals[..];
        let slots = &self.slots[..len];
        let dist2 = &self.dist2[..len];
        let (mut sum_w, mut sum_p, mut sum_n) = self.weighted_sums(samples, r, kernel, |_| true);
        // Across a thin part, fit one face. The error below still counts the other, so a
        // ball across a thin wall is refined as before.
        let inv_r2 = 1.0 / r2;
        let face = face_to_fit(sum_w, sum_n, samples.faces, |visit| {
            for j in (0..len).filter(|&j| dist2[j] < r2) {
                let s = slots[j] as usize;
                let confidence = samples.confidence.as_ref().map_or(1.0, |w| w[s]);
                visit(
                    normals[s],
                    dist2[j],
                    kernel.value_sq_clamped(dist2[j] * inv_r2) * confidence,
                );
            }
        });
        if let Some(face) = face {
            let sums = self.weighted_sums(samples, r, kernel, |s| face.holds(normals[s]));
            // The face's samples have weight unless their kernel weights underflow; keep
            // the plain sums if they have none.
            if sums.0 > 0.0 && sums.2.length() > 0.0 {
                (sum_w, sum_p, sum_n) = sums;
            }
        }
        let length = sum_n.length();
        let (normal, centroid) = if sum_w > 0.0 && length > 0.0 && length.is_finite() {
            (sum_n / length, sum_p / sum_w)
        } else {
            // The weighted normals cancel (two sheets facing each other with equal weight)
            // or no point carries weight: take the nearest point's plane. Its error decides
            // whether the support is refined.
            let j = (0..len)
                .filter(|&j| dist2[j] < r2)
                .min_by(|&a, &b| dist2[a].total_cmp(&dist2[b]).then(a.cmp(&b)))?;
            let s = slots[j] as usize;
            (normals[s], points[s] - c)
        };
        let level = normal.dot(centroid);
        // The candidates outside the ball (and of zero confidence) count as 0 rather than
        // being skipped by a branch, which no predictor could guess for a trial smaller
        // than its gather; the limit is checked once per run of `ERROR_RUN`, so a passing
        // fit's error is the same maximum, and a failing one's is still above the limit.
        let deviation = |j: usize| {
            let s = slots[j] as usize;
            let e = (level - normal.dot(points[s] - c)).abs();
            let counted = dist2[j] < r2 && samples.confidence.as_ref().is_none_or(|w| w[s] > 0.0);
            if counted { e } else { 0.0 }
        };
        let mut error: f64 = 0.0;
        for start in (0..len).step_by(ERROR_RUN) {
            let run = (start..len.min(start + ERROR_RUN)).map(deviation);
            error = run.fold(error, f64::max);
            if error > limit {
                break;
            }
        }
        Some(Fit {
            normal,
            centroid,
            error,
        })
    }

    /// `Σ w_j`, `Σ w_j (p_j − c)` and `Σ w_j n_j` over the candidates whose slot `keep`
    /// accepts, with the kernel of radius `r` times the confidence as `w_j`.
    fn weighted_sums(
        &self,
        samples: &Samples<'_>,
        r: f64,
        kernel: Kernel,
        keep: impl Fn(usize) -> bool,
    ) -> (f64, DVec3, DVec3) {
        let len = self.len();
        let inv_r2 = 1.0 / (r * r);
        let c = self.centre;
        let points = samples.index.slot_points();
        let normals = &samples.normals[..];
        let slots = &self.slots[..len];
        let dist2 = &self.dist2[..len];
        let mut sum_w = 0.0;
        let mut sum_p = DVec3::ZERO;
        let mut sum_n = DVec3::ZERO;
        match &samples.confidence {
            None => {
                for j in 0..len {
                    let s = slots[j] as usize;
                    if keep(s) {
                        let w = kernel.value_sq_clamped(dist2[j] * inv_r2);
                        sum_w += w;
                        sum_p += w * (points[s] - c);
                        sum_n += w * normals[s];
                    }
                }
            }
            Some(conf) => {
                for j in 0..len {
                    let s = slots[j] as usize;
                    if keep(s) {
                        let w = kernel.value_sq_clamped(dist2[j] * inv_r2) * conf[s];
                        sum_w += w;
                        sum_p += w * (points[s] - c);
                        sum_n += w * normals[s];
                    }
                }
            }
        }
        (sum_w, sum_p, sum_n)
    }
}

/// A lower bound on the error `E` of every fit whose ball holds all of `sample` (points of
/// positive confidence): half the minimum width of a tetrahedron of four of them, spread
/// far apart (each the farthest from what the earlier ones span). Any plane through a point
/// of their convex hull — the weighted centroid, or a sample point in the fallback of
/// [`Candidates::fit`] — lies farther than half the width in its normal's direction from one
/// of them, so `E` is at least this. 0 for fewer than four points or a flat tetrahedron.
pub(crate) fn error_lower_bound(sample: &[DVec3]) -> f64 {
    let Some(&a) = sample.first() else {
        return 0.0;
    };
    let farthest = |key: &dyn Fn(DVec3) -> f64| {
        sample
            .iter()
            .map(|&p| (key(p - a), p))
            .fold((f64::NEG_INFINITY, a), |best, cand| {
                if cand.0 > best.0 { cand } else { best }
            })
            .1
    };
    let b = farthest(&|v| v.length_squared());
    let ab = b - a;
    let c = farthest(&|v| v.cross(ab).length_squared());
    let normal = ab.cross(c - a);
    let d = farthest(&|v| v.dot(normal).abs());
    tetrahedron_width(a, b, c, d) * 0.5
}

/// The minimum width of the tetrahedron `abcd`: the smallest distance between two parallel
/// planes enclosing it. For a convex polytope it is attained with a face in one plane and a
/// vertex in the other, or with an edge in each; a tetrahedron has four of the first kind
/// and three (its pairs of opposite edges) of the second. 0 when the tetrahedron is flat.
pub(crate) fn tetrahedron_width(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    // The width in direction `w` of two sets of vertices each level in it: `|w·v| / |w|` for
    // `v` from one set to the other.
    let across = |w: DVec3, v: DVec3| {
        let length = w.length();
        if length > 0.0 {
            w.dot(v).abs() / length
        } else {
            0.0
        }
    };
    let (ab, ac, ad) = (b - a, c - a, d - a);
    let (bc, bd) = (c - b, d - b);
    [
        across(ab.cross(ac), ad),
        across(ab.cross(ad), ac),
        across(ac.cross(ad), ab),
        across(bc.cross(bd), -ab),
        across(ab.cross(d - c), ac),
        across(ac.cross(bd), ab),
        across(ad.cross(bc), ab),
    ]
    .into_iter()
    .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    /// `points` with their `normals`, as the build's samples.
    fn samples_of(points: &[DVec3], normals: &[DVec3]) -> Samples<'static> {
        let index = PointIndex::new(points).unwrap();
        let normals = index.order().iter().map(|&i| normals[i as usize]).collect();
        Samples {
            index: Cow::Owned(index),
            normals,
            confidence: None,
            faces: FaceSelection::Narrow,
        }
    }

    /// Points on a bumpy sphere (so the fit error is not monotone in the radius), with
    /// radial normals, as the build's samples.
    pub(crate) fn bumpy_sphere(n: usize, bump: f64) -> Samples<'static> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let (points, normals): (Vec<DVec3>, Vec<DVec3>) = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let a = golden * i as f64;
                let u = DVec3::new(
                    (1.0 - z * z).sqrt() * a.cos(),
                    (1.0 - z * z).sqrt() * a.sin(),
                    z,
                );
                let r = 0.3 + bump * (7.0 * u.x).sin() * (5.0 * u.y).cos();
                (r * u, u)
            })
            .unzip();
        samples_of(&points, &normals)
    }

    fn vec3() -> impl Strategy<Value = DVec3> {
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    /// The extent of `points` along unit direction `u`.
    fn width_along(points: &[DVec3], u: DVec3) -> f64 {
        let (lo, hi) = points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.dot(u)), hi.max(p.dot(u)))
            });
        hi - lo
    }

    proptest! {
        /// The minimum width is a minimum: no direction finds the tetrahedron thinner (so
        /// the seven candidate directions include the minimising one), and it is attained.
        #[test]
        fn tetrahedron_width_is_the_minimum_over_directions(
            (a, b, c, d) in (vec3(), vec3(), vec3(), vec3()),
            directions in prop::collection::vec(vec3(), 1..64),
        ) {
            let width = tetrahedron_width(a, b, c, d);
            let vertices = [a, b, c, d];
            for u in directions {
                let Some(u) = u.try_normalize() else { continue };
                prop_assert!(width_along(&vertices, u) >= width * (1.0 - 1e-9) - 1e-12);
            }
            // Directions near the minimising one find nearly the same width: a random
            // search from the face normals and edge cross products gets within a hair.
            let (ab, ac, ad, bc, bd, cd) = (b - a, c - a, d - a, c - b, d - b, d - c);
            let candidates = [
                ab.cross(ac), ab.cross(ad), ac.cross(ad), bc.cross(bd),
                ab.cross(cd), ac.cross(bd), ad.cross(bc),
            ];
            let attained = candidates
                .iter()
                .filter_map(|w| w.try_normalize())
                .map(|u| width_along(&vertices, u))
                .fold(f64::INFINITY, f64::min);
            prop_assert!((attained - width).abs() <= 1e-9 * (1.0 + attained));
        }

        /// The bound never exceeds the error of a fit over any ball holding its sample: on
        /// the bumpy sphere, the points of a ball, a sample of them, the fit's exact error.
        #[test]
        fn the_error_bound_is_below_every_fit(
            bump in 0.0..0.05f64,
            centre in vec3(),
            radius in 0.02..0.6f64,
            stride in 1usize..40,
            kernel in prop::sample::select(vec![
                Kernel::QuadraticBSpline, Kernel::WendlandC2, Kernel::TruncatedGaussian,
            ]),
        ) {
            let samples = bumpy_sphere(2000, bump);
            let centre = centre * 0.4;
            let mut cand = Candidates::default();
            cand.gather(&samples, centre, radius);
            let points = samples.index.slot_points();
            let sample: Vec<DVec3> =
                cand.slots.iter().step_by(stride).map(|&s| points[s as usize]).collect();
            let bound = error_lower_bound(&sample);
            if let Some(fit) = cand.fit(&samples, radius, kernel, f64::INFINITY) {
                prop_assert!(bound <= fit.error * (1.0 + 1e-9) + 1e-15, "{bound} > {}", fit.error);
            } else {
                prop_assert_eq!(bound, 0.0);
            }
        }
    }

    proptest! {
        /// A ball across both faces of a thin wall fits the face nearer its centre: the plane
        /// through that face with its normal (averaging both put it between the faces, and
        /// the wall thinned from both sides). Its error still counts the other face.
        #[test]
        fn a_ball_across_a_thin_wall_fits_its_nearer_face(
            thickness in 0.02..0.05f64,
            depth in 0.1..0.3f64,
            (x, y) in (-0.05..0.05f64, -0.05..0.05f64),
            radius_over_thickness in 2.5..4.0f64,
        ) {
            let (points, normals) = crate::synthetic::thin_wall(thickness);
            let samples = samples_of(&points, &normals);
            // The centre within the wall, `depth` of the way up from the lower face.
            let centre = DVec3::new(x, y, depth * thickness);
            let radius = radius_over_thickness * thickness;
            let mut cand = Candidates::default();
            cand.gather(&samples, centre, radius);
            let fit = cand.fit(&samples, radius, Kernel::WendlandC2, f64::INFINITY).unwrap();
            let plane = fit.linear();
            // Positive inside (between the faces), zero on the lower face.
            prop_assert!((fit.normal + DVec3::Z).length() < 1e-9, "normal {}", fit.normal);
            prop_assert!(plane.beta > 0.0);
            prop_assert!((plane.beta - depth * thickness).abs() < 1e-9 * thickness);
            prop_assert!(fit.error >= thickness * (1.0 - 1e-9));
        }
    }

    /// Two ribs across a gap, sampled on a grid of spacing `h`: rib A is `x ≤ 0, z ≤ 0` (its
    /// side faces `+x`, its top `+z`), rib B's side faces `−x` at `x = gap`.
    fn ribs_across_a_gap(gap: f64, h: f64) -> (Vec<DVec3>, Vec<DVec3>) {
        let steps = |from: f64, to: f64| {
            let n = ((to - from) / h).round() as i32;
            (0..=n).map(move |i| from + f64::from(i) * h)
        };
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for y in steps(-1.0, 1.0) {
            for z in steps(-2.0, -h) {
                points.extend([DVec3::new(0.0, y, z), DVec3::new(gap, y, z)]);
                normals.extend([DVec3::X, -DVec3::X]);
            }
            for x in steps(-1.0, 0.0) {
                points.push(DVec3::new(x, y, 0.0));
                normals.push(DVec3::Z);
            }
        }
        (points, normals)
    }

    proptest! {
        /// A ball in the gap beside a rib's top holds the rib's side, its top (at right angles)
        /// and the other rib's side (opposite). The narrow face fits the nearer side alone;
        /// the wide one takes the top too, and its plane tilts towards the gap.
        #[test]
        fn a_ball_beside_a_rib_top_fits_the_rib_s_side(
            gap in 1.0..1.6f64,
            (x, z) in (0.15..0.3f64, -0.55..-0.35f64),
            past in 0.3..0.5f64,
        ) {
            let (points, normals) = ribs_across_a_gap(gap, 0.05);
            let centre = DVec3::new(x, 0.0, z);
            // The ball reaches `past` beyond the other rib's side: enough of both other faces
            // that the normals disagree (their resultant is under 0.8 of their weight).
            let radius = gap - x + past;
            let fit_with = |faces| {
                let samples = Samples { faces, ..samples_of(&points, &normals) };
                let mut cand = Candidates::default();
                cand.gather(&samples, centre, radius);
                cand.fit(&samples, radius, Kernel::QuadraticBSpline, f64::INFINITY).unwrap()
            };
            let narrow = fit_with(FaceSelection::Narrow);
            prop_assert!((narrow.normal - DVec3::X).length() < 1e-9, "normal {}", narrow.normal);
            // The plane is the side's, `x = 0`.
            let on_side = DVec3::new(0.0, 0.0, z) - centre;
            prop_assert!(narrow.linear().value(on_side).abs() < 1e-9);
            let wide = fit_with(FaceSelection::Wide);
            prop_assert!(wide.normal.z > 0.01, "normal {}", wide.normal);
            // Mid-gap, a quarter of the gap below the top: air.
            let air = DVec3::new(0.5 * gap, 0.0, -0.25 * gap) - centre;
            prop_assert!(narrow.linear().value(air) < 0.0);
        }
    }

    #[test]
    fn a_flat_or_short_sample_bounds_nothing() {
        assert_eq!(error_lower_bound(&[]), 0.0);
        let three = [DVec3::ZERO, DVec3::X, DVec3::Y];
        assert_eq!(error_lower_bound(&three), 0.0);
        let square = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)];
        assert_eq!(error_lower_bound(&square), 0.0);
        // The unit cube's corners: width 1, so every plane misses one by at least 1/2.
        let cube: Vec<DVec3> = (0..8)
            .map(|i| DVec3::new((i & 1) as f64, (i >> 1 & 1) as f64, (i >> 2) as f64))
            .collect();
        let bound = error_lower_bound(&cube);
        assert!(bound > 0.0 && bound <= 0.5 + 1e-12, "{bound}");
    }
}
