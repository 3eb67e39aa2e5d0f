//! The colour bar drawn beside a colour-by-scalar image: the colour map from the lowest value
//! (bottom) to the highest (top), labelled at both ends and the middle in a small bitmap
//! font, so that an image pasted into a report still says what its colours mean.

use super::colour_map::{ColourScale, viridis_srgb};
use super::image::Image;

/// Glyph width and height in font pixels; one more column separates characters.
const GLYPH_W: usize = 5;
const GLYPH_H: usize = 7;

/// 5×7 glyphs of the characters numbers are printed with; each row's bit 4 is the left
/// column.
fn glyph(c: char) -> Option<[u8; GLYPH_H]> {
    Some(match c {
        '0' => [0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e],
        '1' => [0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e],
        '2' => [0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f],
        '3' => [0x1f, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0e],
        '4' => [0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02],
        '5' => [0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e],
        '6' => [0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e],
        '7' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e],
        '9' => [0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c],
        '-' => [0x00, 0x00, 0x00, 0x1f, 0x00, 0x00, 0x00],
        '+' => [0x00, 0x04, 0x04, 0x1f, 0x04, 0x04, 0x00],
        'e' => [0x00, 0x00, 0x0e, 0x11, 0x1f, 0x10, 0x0e],
        _ => return None,
    })
}

/// A value as the colour bar's labels print it: at most 4 significant digits, in exponent
/// form outside [1e-3, 1e5).
pub fn label(value: f64) -> String {
    if value == 0.0 || !value.is_finite() {
        return if value.is_nan() {
            "-".into()
        } else {
            format!("{}", value as i64)
        };
    }
    let magnitude = value.abs();
    if (1e-3..1e5).contains(&magnitude) {
        let decimals = (3 - magnitude.log10().floor() as i32).max(0) as usize;
        let text = format!("{value:.decimals$}");
        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            text
        }
    } else {
        format!("{value:.2e}")
    }
}

/// Where the bar and its labels go, decided before the geometry is fitted into the rest.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ColourBar {
    labels: [String; 3],
    /// Font pixel size in image pixels.
    font: usize,
    bar: [usize; 4],
    /// Width of the strip on the right the bar takes from the image.
    pub strip_width: usize,
}

impl ColourBar {
    /// The layout for an image of `width × height` pixels and a scale's range; `None` when
    /// the image is too small to hold a readable bar beside the geometry.
    pub fn layout(width: usize, height: usize, scale: &ColourScale) -> Option<ColourBar> {
        let middle = 0.5 * (scale.low + scale.high);
        // A midpoint that is zero but for rounding (a symmetric range) reads as 0, not as
        // a long exponent.
        let span = scale.high - scale.low;
        let middle = if middle.abs() < 5e-4 * span {
            0.0
        } else {
            middle
        };
        let labels = [label(scale.high), label(middle), label(scale.low)];
        let font = (height / 450).max(1);
        let chars = labels.iter().map(|l| l.chars().count()).max().unwrap_or(1);
        let pad = (width / 100).max(6);
        let bar_width = (width / 60).max(8);
        let gap = 3 * font;
        let strip_width = pad + bar_width + gap + chars * (GLYPH_W + 1) * font + pad;
        let bar_height = height * 3 / 5;
        if strip_width * 3 > width || bar_height < 3 * GLYPH_H * font {
            return None;
        }
        let left = width - strip_width + pad;
        let top = (height - bar_height) / 2;
        Some(ColourBar {
            labels,
            font,
            bar: [left, top, bar_width, bar_height],
            strip_width,
        })
    }

    /// Draws the bar, its frame and its labels in `ink` (sRGB, opaque).
    pub fn draw(&self, image: &mut Image, ink: [u8; 3]) {
        let [left, top, width, height] = self.bar;
        for row in 0..height {
            let t = 1.0 - row as f64 / (height - 1).max(1) as f64;
            let colour = viridis_srgb(t).map(|c| (c * 255.0).round() as u8);
            for x in left..left + width {
                image.put(x, top + row, colour);
            }
        }
        for x in left.saturating_sub(1)..=left + width {
            image.put(x, top.saturating_sub(1), ink);
            image.put(x, top + height, ink);
        }
        for y in top.saturating_sub(1)..=top + height {
            image.put(left.saturating_sub(1), y, ink);
            image.put(left + width, y, ink);
        }
        let text_left = left + width + 3 * self.font;
        let text_height = GLYPH_H * self.font;
        let rows = [top, top + height / 2, top + height - 1];
        for (text, centre) in self.labels.iter().zip(rows) {
            let y = centre.saturating_sub(text_height / 2);
            self.draw_text(image, text, text_left, y, ink);
        }
    }

    fn draw_text(&self, image: &mut Image, text: &str, left: usize, top: usize, ink: [u8; 3]) {
        let f = self.font;
        for (i, c) in text.chars().enumerate() {
            let Some(rows) = glyph(c) else { continue };
            let x0 = left + i * (GLYPH_W + 1) * f;
            for (gy, bits) in rows.iter().enumerate() {
                for gx in 0..GLYPH_W {
                    if bits & (0x10 >> gx) == 0 {
                        continue;
                    }
                    for dy in 0..f {
                        for dx in 0..f {
                            image.put(x0 + gx * f + dx, top + gy * f + dy, ink);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_are_short_and_use_only_drawable_characters() {
        for (v, want) in [
            (0.0, "0"),
            (1.0, "1"),
            (0.5, "0.5"),
            (-0.25, "-0.25"),
            (123.456, "123.5"),
            (12345.0, "12345"),
            (0.001234, "0.001234"),
            (1.5e-5, "1.50e-5"),
            (2.5e7, "2.50e7"),
        ] {
            let text = label(v);
            assert_eq!(text, want);
            assert!(text.chars().all(|c| glyph(c).is_some()), "{text}");
        }
    }

    #[test]
    fn bar_is_drawn_inside_its_strip() {
        let scale = ColourScale::new(-1.0, 2.0);
        let bar = ColourBar::layout(800, 600, &scale).unwrap();
        let mut image = Image::new(800, 600, [255, 255, 255, 255]);
        bar.draw(&mut image, [0, 0, 0]);
        let touched: Vec<usize> = (0..800)
            .filter(|&x| (0..600).any(|y| image.get(x, y) != [255, 255, 255, 255]))
            .collect();
        assert!(touched[0] >= 800 - bar.strip_width);
        // The top of the bar is the last colour, the bottom the first.
        let [left, top, width, height] = bar.bar;
        let yellow = image.get(left + width / 2, top);
        let purple = image.get(left + width / 2, top + height - 1);
        assert!(yellow[0] > 200 && yellow[2] < 80, "{yellow:?}");
        assert!(purple[2] > purple[1], "{purple:?}");
        assert!(ColourBar::layout(60, 40, &scale).is_none());
    }
}
