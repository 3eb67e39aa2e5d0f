//! Separable Gaussian smoothing of a volume on its grid.

use rayon::prelude::*;
use sphcover_core::Volume;

/// The values of `volume` smoothed by a Gaussian of standard deviation `sigma` voxels along
/// each grid axis, non-finite values replaced by `fill` first. `sigma = 0` copies.
pub(crate) fn smoothed_values(volume: &Volume, sigma: f64, fill: f64) -> Vec<f64> {
    let mut data: Vec<f64> = (0..volume.len())
        .map(|i| {
            let v = volume.value(i);
            if v.is_finite() { v } else { fill }
        })
        .collect();
    if sigma > 0.0 {
        for axis in 0..3 {
            data = gaussian_along(&data, volume.dims(), axis, sigma);
        }
    }
    data
}

/// Convolves `data` (grid `dims`, x fastest) along `axis` with a Gaussian of standard
/// deviation `sigma` (truncated at 3σ, renormalised at the borders).
pub(crate) fn gaussian_along(data: &[f64], dims: [usize; 3], axis: usize, sigma: f64) -> Vec<f64> {
    let radius = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f64> = (-radius..=radius)
        .map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let stride = [1, dims[0], dims[0] * dims[1]][axis];
    let n = dims[axis] as i64;
    (0..data.len())
        .into_par_iter()
        .with_min_len(4096)
        .map(|idx| {
            let pos = ((idx / stride) % dims[axis]) as i64;
            let (mut sum, mut weight) = (0.0, 0.0);
            for (o, w) in (-radius..=radius).zip(&kernel) {
                let p = pos + o;
                if (0..n).contains(&p) {
                    sum += w * data[(idx as i64 + o * stride as i64) as usize];
                    weight += w;
                }
            }
            sum / weight
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Smoothing keeps constants and, away from the borders, the mean of a signal.
        #[test]
        fn constants_are_kept(c in -1e3..1e3f64, sigma in 0.3..3.0f64) {
            let data = vec![c; 6 * 5 * 4];
            for axis in 0..3 {
                let out = gaussian_along(&data, [6, 5, 4], axis, sigma);
                prop_assert!(out.iter().all(|v| (v - c).abs() <= 1e-9 * (1.0 + c.abs())));
            }
        }
    }

    #[test]
    fn an_impulse_spreads_symmetrically() {
        let mut data = vec![0.0; 15];
        data[7] = 1.0;
        let out = gaussian_along(&data, [15, 1, 1], 0, 1.0);
        assert!((out[6] - out[8]).abs() < 1e-15 && out[7] > out[6] && out[6] > out[5]);
        assert!((out.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
}
