//! An 8-bit sRGBA image and its PNG encoding.

use std::io::Write;

/// Pixels in rows from the top, 4 bytes each (sRGB, straight alpha).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width × height × 4` bytes.
    pub rgba: Vec<u8>,
}

impl Image {
    /// An image filled with one colour.
    pub fn new(width: usize, height: usize, fill: [u8; 4]) -> Image {
        Image {
            width,
            height,
            rgba: fill.repeat(width * height),
        }
    }

    /// The pixel at column `x`, row `y`, as sRGBA bytes. Panics outside the image.
    pub fn get(&self, x: usize, y: usize) -> [u8; 4] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside a {}x{} image",
            self.width,
            self.height
        );
        let i = 4 * (y * self.width + x);
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Paints an opaque pixel; positions outside the image are ignored.
    pub fn put(&mut self, x: usize, y: usize, rgb: [u8; 3]) {
        if x < self.width && y < self.height {
            let i = 4 * (y * self.width + x);
            self.rgba[i..i + 4].copy_from_slice(&[rgb[0], rgb[1], rgb[2], 255]);
        }
    }

    /// True when every pixel is opaque (the PNG then stores RGB only).
    pub fn is_opaque(&self) -> bool {
        self.rgba.chunks_exact(4).all(|p| p[3] == 255)
    }

    /// Writes the image as a PNG: RGB when opaque, RGBA otherwise, 8 bits per channel, with
    /// no time stamp, so the same pixels always give the same bytes.
    pub fn write_png(&self, out: &mut dyn Write) -> std::io::Result<()> {
        let too_large =
            |_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "image too large for PNG");
        let width = u32::try_from(self.width).map_err(too_large)?;
        let height = u32::try_from(self.height).map_err(too_large)?;
        let mut encoder = png::Encoder::new(out, width, height);
        let opaque = self.is_opaque();
        encoder.set_color(if opaque {
            png::ColorType::Rgb
        } else {
            png::ColorType::Rgba
        });
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Fast);
        encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        encoder
            .add_text_chunk("Software".into(), "sphcover render".into())
            .map_err(std::io::Error::other)?;
        let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
        if opaque {
            let rgb: Vec<u8> = self
                .rgba
                .chunks_exact(4)
                .flat_map(|p| [p[0], p[1], p[2]])
                .collect();
            writer.write_image_data(&rgb)
        } else {
            writer.write_image_data(&self.rgba)
        }
        .map_err(std::io::Error::other)?;
        writer.finish().map_err(std::io::Error::other)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(bytes: &[u8]) -> (png::OutputInfo, Vec<u8>) {
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        (info, buf)
    }

    #[test]
    fn png_round_trips_opaque_and_transparent_images() {
        let mut image = Image::new(7, 5, [10, 20, 30, 255]);
        image.put(3, 2, [200, 100, 50]);
        let mut bytes = Vec::new();
        image.write_png(&mut bytes).unwrap();
        let (info, data) = decode(&bytes);
        assert_eq!((info.width, info.height), (7, 5));
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(&data[3 * (2 * 7 + 3)..3 * (2 * 7 + 4)], &[200, 100, 50]);

        image.rgba[3] = 0;
        let mut bytes = Vec::new();
        image.write_png(&mut bytes).unwrap();
        let (info, data) = decode(&bytes);
        assert_eq!(info.color_type, png::ColorType::Rgba);
        assert_eq!(data, image.rgba);
    }
}
