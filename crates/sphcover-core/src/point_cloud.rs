//! Scanned points with optional per-point attributes.

use glam::DVec3;

use crate::geometry::{Aabb, Normalisation};

/// A set of scanned points stored as parallel arrays (struct of arrays).
///
/// Every present attribute has exactly one entry per point; [`PointCloud::check`] verifies
/// that. Normals point outward (the convention of thesis §3.4.1) when the scanner or exporter got them right;
/// they need not be unit length in files, and readers keep them as written.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    /// Point positions.
    pub positions: Vec<DVec3>,
    /// Per-point normals, if the source has them.
    pub normals: Option<Vec<DVec3>>,
    /// Per-point confidence in `[0, 1]` (scanner-given, or computed by reconstruction).
    pub confidence: Option<Vec<f64>>,
    /// Per-point scalar value (for example a CT intensity sample or a PLY `quality`/`scalar`/`value`).
    pub values: Option<Vec<f64>>,
    /// Per-point colour as 8-bit red, green, blue (PLY `red green blue`, LAS RGB).
    pub colors: Option<Vec<[u8; 3]>>,
}

impl PointCloud {
    /// A cloud of positions only.
    pub fn from_positions(positions: Vec<DVec3>) -> PointCloud {
        PointCloud {
            positions,
            ..PointCloud::default()
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there is no point.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Bounding box of the finite positions.
    pub fn bounding_box(&self) -> Aabb {
        Aabb::from_points(&self.positions)
    }

    /// Checks that every attribute array has one entry per point.
    pub fn check(&self) -> Result<(), String> {
        let n = self.len();
        let lens = [
            ("normals", self.normals.as_ref().map(Vec::len)),
            ("confidence", self.confidence.as_ref().map(Vec::len)),
            ("values", self.values.as_ref().map(Vec::len)),
            ("colors", self.colors.as_ref().map(Vec::len)),
        ];
        for (name, len) in lens {
            if let Some(len) = len
                && len != n
            {
                return Err(format!("{name} has {len} entries for {n} points"));
            }
        }
        Ok(())
    }

    /// Maps the positions into the unit frame of `norm` (normals are unchanged).
    pub fn to_unit(&mut self, norm: &Normalisation) {
        norm.points_to_unit(&mut self.positions);
    }

    /// Maps the positions back to input coordinates.
    pub fn to_input(&mut self, norm: &Normalisation) {
        norm.points_to_input(&mut self.positions);
    }

    /// Keeps the points for which `keep(i)` is true, in order, with their attributes.
    pub fn retain_indices(&mut self, mut keep: impl FnMut(usize) -> bool) {
        let mask: Vec<bool> = (0..self.len()).map(&mut keep).collect();
        fn filter<T: Copy>(v: &mut Vec<T>, mask: &[bool]) {
            let mut i = 0;
            v.retain(|_| {
                let k = mask[i];
                i += 1;
                k
            });
        }
        filter(&mut self.positions, &mask);
        if let Some(v) = self.normals.as_mut() {
            filter(v, &mask);
        }
        if let Some(v) = self.confidence.as_mut() {
            filter(v, &mask);
        }
        if let Some(v) = self.values.as_mut() {
            filter(v, &mask);
        }
        if let Some(v) = self.colors.as_mut() {
            filter(v, &mask);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retain_keeps_attributes_aligned() {
        let mut pc = PointCloud::from_positions((0..5).map(|i| DVec3::splat(i as f64)).collect());
        pc.values = Some((0..5).map(|i| i as f64).collect());
        pc.colors = Some((0..5).map(|i| [i, 0, 0]).collect());
        pc.retain_indices(|i| i % 2 == 0);
        assert_eq!(pc.len(), 3);
        assert_eq!(pc.values.as_deref(), Some(&[0.0, 2.0, 4.0][..]));
        assert_eq!(
            pc.colors.as_deref(),
            Some(&[[0, 0, 0], [2, 0, 0], [4, 0, 0]][..])
        );
        assert!(pc.check().is_ok());
        pc.values.as_mut().unwrap().pop();
        assert!(pc.check().is_err());
    }
}
