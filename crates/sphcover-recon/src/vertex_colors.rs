//! The scan's colours carried to the reconstructed surface (beyond the thesis: scanners that
//! photograph the object give each sample a colour, and a viewer shows the surface in them).

use rayon::prelude::*;
use sphcover_core::{DVec3, PointIndex};

/// Samples looked at around a vertex for one that is not an outlier.
const NEAREST: usize = 8;

/// The colour of each vertex: that of the nearest sample not labelled an outlier among its
/// 8 nearest samples, or of the nearest sample when all of those are outliers.
///
/// The nearest sample, not a blend: a blend of neighbours would smear the edges of printed
/// text and texture over the spacing of the samples. Ties in distance go to the lower sample
/// index, so the result does not depend on the threads.
///
/// `index` is over the samples; `colors` and `outliers` are per sample, in the index's caller
/// order.
pub fn nearest_sample_colors(
    vertices: &[DVec3],
    index: &PointIndex,
    colors: &[[u8; 3]],
    outliers: &[bool],
) -> Vec<[u8; 3]> {
    vertices
        .par_iter()
        .map_init(Vec::new, |near, &v| {
            index.nearest_k(v, NEAREST, near);
            let chosen = near
                .iter()
                .find(|&&s| !outliers[s as usize])
                .or(near.first());
            chosen.map_or([0; 3], |&s| colors[s as usize])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_inlier_gives_the_colour() {
        let samples = [
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(0.1, 0.0, 0.0),
            DVec3::new(5.0, 0.0, 0.0),
        ];
        let index = PointIndex::new(&samples).unwrap();
        let colors = [[10, 0, 0], [20, 0, 0], [30, 0, 0], [40, 0, 0]];
        let outliers = [false, false, true, false];
        let vertices = [
            DVec3::new(0.09, 0.0, 0.0),
            DVec3::new(0.9, 0.1, 0.0),
            DVec3::new(4.0, 0.0, 0.0),
        ];
        let got = nearest_sample_colors(&vertices, &index, &colors, &outliers);
        // The first vertex is nearest the outlier at 0.1: the inlier at 0 colours it.
        assert_eq!(got, vec![[10, 0, 0], [20, 0, 0], [40, 0, 0]]);
        let all_outliers = nearest_sample_colors(&vertices[..1], &index, &colors, &[true; 4]);
        assert_eq!(all_outliers, vec![[30, 0, 0]]);
    }
}
