//! The Hessian's ridge direction on a grid resampled from thick slices.
//!
//! A scanner's slice `k` pixels thick holds the mean of the part over its extent, so across
//! the slices the part is blurred by a box `k` pixels wide on top of the point-spread
//! function: a variance `(k² − 1) / 12` pixels² larger than within a slice (whose pixels are
//! one wide). A profile blurred more is flatter, and its second derivative smaller, so the
//! Hessian of the resampled grid understates the curvature along the slice axis against
//! the curvature across the pixels. Where one direction clearly dominates (the middle of a
//! plate) that changes nothing, but where two compete it turns the ridge direction: a strip
//! of plate between a hole and the plate's edge, about as wide as the plate is thick, or a
//! plate's end, where its faces meet its rim.
//!
//! Taking the Hessian in coordinates where the slice axis `a` is compressed by `s`, so that
//! the blur is the same along every axis, undoes that: `y = S⁻¹ x` with
//! `S = I + (s − 1) a aᵀ` turns the Hessian into `S H S`. Its smallest eigenvector `e'` is
//! the normal of the sheet in those coordinates; back in the grid's, the normal is
//! `S⁻¹ e'` (a plane `n·x = c` has the normal `S n` in `y`). For a plate alone, whose
//! Hessian is `−c n nᵀ`, this gives `n` back whatever `s` is. With an in-plane blur of `b`
//! pixels,
//!
//! ```text
//! s² = (b² + (k² − 1) / 12) / b²
//! ```

use glam::{DMat3, DVec3};

use crate::symmetric_eigen::{SmallestEigen, smallest_eigen};

/// The slice axis and how much the Hessian compresses it (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliceStretch {
    /// Unit vector along the slice axis (world coordinates).
    axis: DVec3,
    /// `s ≥ 1`.
    factor: f64,
}

impl SliceStretch {
    /// The stretch for slices `slice_pixels` pixels thick along `axis` (any length), seen
    /// with an in-plane blur of `blur_pixels` (standard deviation, pixels). `None` when the
    /// axis has no direction or the sizes are not positive and finite.
    ///
    /// ```
    /// use sphcover_skeleton::SliceStretch;
    /// use glam::DVec3;
    ///
    /// // Slices 5 pixels thick seen through a blur of 1.28 pixels: s² = 1 + 2 / 1.64.
    /// let stretch = SliceStretch::new(DVec3::Z, 5.0, 1.28).unwrap();
    /// assert!((stretch.factor() - 1.49).abs() < 0.01);
    /// // Slices one pixel thick need none.
    /// assert_eq!(SliceStretch::new(DVec3::Z, 1.0, 1.28).unwrap().factor(), 1.0);
    /// ```
    pub fn new(axis: DVec3, slice_pixels: f64, blur_pixels: f64) -> Option<SliceStretch> {
        let axis = axis.try_normalize()?;
        let valid = |v: f64| v.is_finite() && v > 0.0;
        if !(valid(slice_pixels) && valid(blur_pixels)) {
            return None;
        }
        let extra = (slice_pixels * slice_pixels - 1.0).max(0.0) / 12.0;
        let factor = (1.0 + extra / (blur_pixels * blur_pixels)).sqrt();
        Some(SliceStretch { axis, factor })
    }

    /// `s`.
    pub fn factor(&self) -> f64 {
        self.factor
    }

    /// The same axis with the factor `s^exponent`.
    pub(crate) fn powered(&self, exponent: f64) -> SliceStretch {
        SliceStretch {
            axis: self.axis,
            factor: self.factor.powf(exponent),
        }
    }

    /// `‖S⁻¹ v‖`: the length of `v` in the coordinates where the slice axis is compressed,
    /// in which the blur is the same along every axis.
    pub(crate) fn compressed_length(&self, v: DVec3) -> f64 {
        self.scaled(v, 1.0 / self.factor).length()
    }

    /// `M v` with `M = I + (m − 1) a aᵀ`.
    fn scaled(&self, v: DVec3, m: f64) -> DVec3 {
        v + (m - 1.0) * v.dot(self.axis) * self.axis
    }

    /// The smallest eigenpair of `S H S`, its vector mapped back to the grid's coordinates
    /// (`S⁻¹ e'`, normalised); the eigenvalues are those of `S H S`. `None` as for
    /// [`smallest_eigen`].
    pub(crate) fn smallest_eigen(&self, hessian: &DMat3) -> Option<SmallestEigen> {
        let s = |v: DVec3| self.scaled(v, self.factor);
        let s_matrix = DMat3::from_cols(s(DVec3::X), s(DVec3::Y), s(DVec3::Z));
        let mut eigen = smallest_eigen(&(s_matrix * *hessian * s_matrix))?;
        eigen.vector = self
            .scaled(eigen.vector, 1.0 / self.factor)
            .try_normalize()?;
        Some(eigen)
    }
}

/// The Hessian's smallest eigenpair for the ridge test: that of
/// [`SliceStretch::smallest_eigen`] on thick slices, else the plain one.
pub(crate) fn ridge_eigen(
    hessian: &DMat3,
    stretch: Option<&SliceStretch>,
) -> Option<SmallestEigen> {
    match stretch {
        Some(stretch) => stretch.smallest_eigen(hessian),
        None => smallest_eigen(hessian),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn unit() -> impl Strategy<Value = DVec3> {
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_filter_map("a direction", |(x, y, z)| {
            DVec3::new(x, y, z).try_normalize()
        })
    }

    proptest! {
        /// A plate alone (`H = −c n nᵀ`) keeps its normal whatever the axis and the stretch:
        /// the stretch only settles directions that compete.
        #[test]
        fn a_plate_keeps_its_normal(n in unit(), axis in unit(), c in 0.1..10.0f64,
                                    slices in 1.0..8.0f64, blur in 0.3..3.0f64) {
            let hessian = DMat3::from_cols(-c * n.x * n, -c * n.y * n, -c * n.z * n);
            let stretch = SliceStretch::new(axis, slices, blur).unwrap();
            let e = stretch.smallest_eigen(&hessian).unwrap();
            prop_assert!(e.vector.dot(n).abs() > 1.0 - 1e-9, "{:?} against {n:?}", e.vector);
            prop_assert!((e.vector.length() - 1.0).abs() < 1e-12);
        }

        /// Lengths along the axis shrink by `s^γ`, lengths across it stay, and `γ = 0` is
        /// the plain length.
        #[test]
        fn compressed_lengths_shrink_along_the_axis_only(
            v in unit(), axis in unit(), slices in 1.0..8.0f64, blur in 0.3..3.0f64,
            gamma in 0.0..1.0f64, length in 0.01..10.0f64,
        ) {
            let stretch = SliceStretch::new(axis, slices, blur).unwrap();
            let powered = stretch.powered(gamma);
            let s = powered.factor();
            prop_assert!((s - stretch.factor().powf(gamma)).abs() < 1e-12);
            let along = v.dot(axis) * axis;
            let across = v - along;
            let expected = (across + along / s).length() * length;
            prop_assert!((powered.compressed_length(length * v) - expected).abs() < 1e-9 * length);
            prop_assert!((powered.compressed_length(length * axis) - length / s).abs() < 1e-9 * length);
            prop_assert!(powered.compressed_length(v) <= 1.0 + 1e-12);
            let plain = stretch.powered(0.0).compressed_length(length * v);
            prop_assert!((plain - length).abs() < 1e-9 * length);
        }

        /// The factor follows `s² = 1 + (k² − 1) / (12 b²)`, is 1 for slices one pixel
        /// thick, and grows with the slices.
        #[test]
        fn the_factor_follows_the_blur(k in 1.0..10.0f64, blur in 0.3..3.0f64) {
            let s = SliceStretch::new(DVec3::Z, k, blur).unwrap().factor();
            prop_assert!((s * s - 1.0 - (k * k - 1.0) / (12.0 * blur * blur)).abs() < 1e-9);
            let thicker = SliceStretch::new(DVec3::Z, k + 1.0, blur).unwrap().factor();
            prop_assert!(thicker > s);
        }
    }

    /// A strip as wide as it is thick, its thickness across the slices: the slices' blur
    /// leaves the curvature across them (−0.6) below the one across the strip's width
    /// (−1), so the plain ridge direction lies in the slices; stretched by 1.5 the curvature
    /// across the slices reads −1.35 and the direction turns back to the slice axis.
    #[test]
    fn a_strip_damped_across_the_slices_turns_back_to_the_slice_axis() {
        let hessian = DMat3::from_diagonal(DVec3::new(-1.0, 0.0, -0.6));
        let plain = smallest_eigen(&hessian).unwrap();
        assert!(plain.vector.x.abs() > 0.999, "{plain:?}");
        // s = 1.5: s² − 1 = 1.25 = (k² − 1) / (12 b²) with k = 4, b = 1.
        let stretch = SliceStretch::new(DVec3::Z, 4.0, 1.0).unwrap();
        assert!((stretch.factor() - 1.5).abs() < 1e-12);
        let stretched = stretch.smallest_eigen(&hessian).unwrap();
        assert!(stretched.vector.z.abs() > 0.999, "{stretched:?}");
        assert!((stretched.values[0] + 1.35).abs() < 1e-12, "{stretched:?}");
        assert!(ridge_eigen(&hessian, None) == Some(plain));
    }

    #[test]
    fn sizes_that_are_not_lengths_give_no_stretch() {
        assert!(SliceStretch::new(DVec3::ZERO, 3.0, 1.0).is_none());
        assert!(SliceStretch::new(DVec3::Z, 0.0, 1.0).is_none());
        assert!(SliceStretch::new(DVec3::Z, 3.0, f64::NAN).is_none());
        assert!(SliceStretch::new(DVec3::Z, f64::INFINITY, 1.0).is_none());
    }
}
