//! Scalar → colour: the viridis colour map (perceptually uniform, readable in greyscale and by
//! most colour-blind readers) over a value range.

/// Entries of the lookup table the shader uses.
const TABLE_LEN: usize = 1024;

/// Colour of values that are not finite (NaN labels, missing confidences): neutral grey.
pub(crate) const NOT_FINITE_SRGB: [f64; 3] = [0.5, 0.5, 0.5];

/// Viridis as sRGB components in [0, 1] for `t` in [0, 1] (clamped).
///
/// A degree-6 polynomial fit of matplotlib's table (Matt Zucker's public-domain fit); it
/// stays within about 1/255 of the table, below what 8-bit output resolves reliably.
pub(crate) fn viridis_srgb(t: f64) -> [f64; 3] {
    const C: [[f64; 3]; 7] = [
        [
            0.277_727_327_223_417_7,
            0.005_407_344_544_966_578,
            0.334_099_805_335_306_1,
        ],
        [
            0.105_093_043_108_577_4,
            1.404_613_529_898_575,
            1.384_590_162_594_685,
        ],
        [
            -0.330_861_828_725_556_3,
            0.214_847_559_468_213,
            0.095_095_163_028_236_59,
        ],
        [
            -4.634_230_498_983_486,
            -5.799_100_973_351_585,
            -19.332_440_956_279_87,
        ],
        [
            6.228_269_936_347_081,
            14.179_933_366_805_09,
            56.690_552_600_681_05,
        ],
        [
            4.776_384_997_670_288,
            -13.745_145_377_746_01,
            -65.353_032_633_372_34,
        ],
        [
            -5.435_455_855_934_631,
            4.645_852_612_178_535,
            26.312_435_249_583_2,
        ],
    ];
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut v = C[6][k];
        for c in C[..6].iter().rev() {
            v = v * t + c[k];
        }
        *o = v.clamp(0.0, 1.0);
    }
    out
}

/// The sRGB transfer function, inverted: an encoded component to linear light.
pub(crate) fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light to an encoded sRGB component.
pub(crate) fn linear_to_srgb(c: f64) -> f64 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// A value range mapped onto the colour map, with the colours in linear light.
#[derive(Clone, Debug)]
pub(crate) struct ColourScale {
    /// The value drawn in the first colour.
    pub low: f64,
    /// The value drawn in the last colour.
    pub high: f64,
    table: Vec<[f32; 3]>,
    not_finite: [f32; 3],
}

impl ColourScale {
    /// A scale over `[low, high]`; a zero-width range maps every finite value to the middle
    /// colour.
    pub fn new(low: f64, high: f64) -> ColourScale {
        let linear = |c: [f64; 3]| c.map(|v| srgb_to_linear(v) as f32);
        let table = (0..TABLE_LEN)
            .map(|i| linear(viridis_srgb(i as f64 / (TABLE_LEN - 1) as f64)))
            .collect();
        ColourScale {
            low,
            high,
            table,
            not_finite: linear(NOT_FINITE_SRGB),
        }
    }

    /// The range of the finite values, or `None` when no value is finite.
    pub fn range_of(values: &[f64]) -> Option<(f64, f64)> {
        values
            .iter()
            .filter(|v| v.is_finite())
            .fold(None, |acc, &v| match acc {
                None => Some((v, v)),
                Some((lo, hi)) => Some((v.min(lo), v.max(hi))),
            })
    }

    /// Position of `value` along the colour map, in [0, 1] (NaN for non-finite values).
    pub fn position(&self, value: f64) -> f64 {
        if !value.is_finite() {
            return f64::NAN;
        }
        let width = self.high - self.low;
        if width > 0.0 {
            ((value - self.low) / width).clamp(0.0, 1.0)
        } else {
            0.5
        }
    }

    /// The linear-light colour of a value.
    #[inline]
    pub fn linear(&self, value: f64) -> [f32; 3] {
        let t = self.position(value);
        if t.is_nan() {
            return self.not_finite;
        }
        self.table[(t * (TABLE_LEN - 1) as f64).round() as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Relative luminance of an sRGB colour.
    fn luminance(c: [f64; 3]) -> f64 {
        let [r, g, b] = c.map(srgb_to_linear);
        0.2126 * r + 0.7152 * g + 0.0722 * b
    }

    #[test]
    fn endpoints_match_matplotlib() {
        // matplotlib's viridis: #440154 at 0, #21918c at 0.5, #fde725 at 1.
        for (t, hex) in [
            (0.0, [0x44, 0x01, 0x54]),
            (0.5, [0x21, 0x91, 0x8c]),
            (1.0, [0xfd, 0xe7, 0x25]),
        ] {
            let c = viridis_srgb(t);
            for k in 0..3 {
                assert!(
                    (c[k] * 255.0 - hex[k] as f64).abs() < 4.0,
                    "t {t}: {c:?} vs {hex:?}"
                );
            }
        }
    }

    proptest! {
        /// Viridis is perceptually ordered: luminance grows with the value.
        #[test]
        fn luminance_increases(a in 0.0..1.0f64, d in 0.01..1.0f64) {
            let b = (a + d).min(1.0);
            prop_assume!(b > a + 0.005);
            prop_assert!(luminance(viridis_srgb(b)) > luminance(viridis_srgb(a)));
        }

        /// The transfer functions are inverse to each other.
        #[test]
        fn srgb_round_trip(c in 0.0..=1.0f64) {
            prop_assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-12);
        }

        /// Positions are monotone in the value and clamp outside the range.
        #[test]
        fn positions_are_monotone(lo in -1e6..1e6f64, w in 0.0..1e6f64, a in -2e6..2e6f64, b in -2e6..2e6f64) {
            let scale = ColourScale::new(lo, lo + w);
            let (a, b) = (a.min(b), a.max(b));
            let (pa, pb) = (scale.position(a), scale.position(b));
            prop_assert!((0.0..=1.0).contains(&pa) && (0.0..=1.0).contains(&pb));
            if w > 0.0 {
                prop_assert!(pa <= pb);
            }
        }
    }

    #[test]
    fn ranges_skip_non_finite_values() {
        assert_eq!(
            ColourScale::range_of(&[f64::NAN, 2.0, -1.0, f64::INFINITY]),
            Some((-1.0, 2.0))
        );
        assert_eq!(ColourScale::range_of(&[f64::NAN]), None);
        let scale = ColourScale::new(0.0, 1.0);
        assert_eq!(scale.linear(f64::NAN), scale.not_finite);
    }
}
