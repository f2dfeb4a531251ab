//! Image textures: images decoded by `film::io` (8- and 16-bit images from
//! sRGB, float images as linear) and their filtered lookup.

use crate::color::Rgb;
use crate::error::{Error, Result};
use glam::Vec2;
use std::path::Path;

/// A linear RGB image used as a texture.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageTexture {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels, row by row from the top.
    pub pixels: Vec<Rgb>,
}

/// Largest texture accepted, in pixels (a 16k × 16k image).
pub const MAX_TEXTURE_PIXELS: u64 = crate::film::io::MAX_IMAGE_PIXELS;

impl ImageTexture {
    /// Reads a PNG, JPEG, BMP, Radiance HDR, OpenEXR or PFM file. Integer images are
    /// decoded from sRGB unless `srgb` is `Some(false)`; float images are
    /// taken as linear unless `srgb` is `Some(true)`.
    pub fn load(path: &Path, srgb: Option<bool>) -> Result<ImageTexture> {
        let bytes = crate::files::read_limited(path, crate::files::MAX_IMAGE_FILE_BYTES)
            .map_err(|e| Error::file(path, format!("cannot open image: {e}")))?;
        Self::decode(&bytes, srgb).map_err(|e| Error::file(path, e))
    }

    /// Decodes a PNG, JPEG, BMP, Radiance HDR, OpenEXR or PFM image held in
    /// memory (told apart by their first bytes), as [`ImageTexture::load`] does.
    /// The size in the header is checked before any pixel is allocated.
    /// Errors are plain reasons, for the caller to place.
    pub fn decode(bytes: &[u8], srgb: Option<bool>) -> Result<ImageTexture, String> {
        let t = Self::decode_any_size(bytes, srgb)?;
        if t.pixels.is_empty() || t.pixels.len() != t.width as usize * t.height as usize {
            return Err(format!(
                "an image of {}×{} pixels cannot be a texture",
                t.width, t.height
            ));
        }
        Ok(t)
    }

    fn decode_any_size(bytes: &[u8], srgb: Option<bool>) -> Result<ImageTexture, String> {
        let image = crate::film::io::decode_any(bytes, srgb)?;
        Ok(ImageTexture {
            width: image.width,
            height: image.height,
            pixels: image.pixels,
        })
    }

    /// Decodes a PNG or JPEG image held in memory (an image embedded in a
    /// glTF file, say); 8- and 16-bit images are decoded from sRGB when
    /// `srgb` is true. Errors are plain reasons, for the caller to place.
    pub fn from_encoded(bytes: &[u8], srgb: bool) -> Result<ImageTexture, String> {
        let format = ::image::guess_format(bytes).map_err(|e| format!("cannot read image: {e}"))?;
        if !matches!(format, ::image::ImageFormat::Png | ::image::ImageFormat::Jpeg) {
            return Err("not a PNG or JPEG image".into());
        }
        Self::decode(bytes, Some(srgb))
    }

    /// Replaces texels that are not finite (NaN or infinite, as float
    /// images may hold) or negative by black, so that they cannot poison
    /// the samples or the light-sampling tables; returns how many were
    /// replaced.
    pub fn sanitize(&mut self) -> usize {
        let mut replaced = 0;
        for p in &mut self.pixels {
            if !p.is_finite() || p.min_element() < 0.0 {
                *p = if p.is_finite() { p.max(Rgb::ZERO) } else { Rgb::ZERO };
                replaced += 1;
            }
        }
        replaced
    }

    /// The texel at integer coordinates, wrapping around the edges.
    #[inline]
    fn texel(&self, x: i64, y: i64) -> Rgb {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        self.pixels[y * self.width as usize + x]
    }

    /// Bilinearly filtered colour at `uv`, repeating outside [0, 1]²;
    /// v = 0 is the bottom row of the image.
    #[inline]
    pub fn lookup_bilinear(&self, uv: Vec2) -> Rgb {
        let x = uv.x * self.width as f32 - 0.5;
        let y = (1.0 - uv.y) * self.height as f32 - 0.5;
        if !x.is_finite() || !y.is_finite() {
            return self.pixels[0];
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (xi, yi) = (x0 as i64, y0 as i64);
        let top = self.texel(xi, yi) * (1.0 - fx) + self.texel(xi + 1, yi) * fx;
        let bottom = self.texel(xi, yi + 1) * (1.0 - fx) + self.texel(xi + 1, yi + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Mean colour.
    pub fn average(&self) -> Rgb {
        let sum = self.pixels.iter().fold(glam::DVec3::ZERO, |a, p| a + p.as_dvec3());
        (sum / self.pixels.len().max(1) as f64).as_vec3()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::srgb_to_linear;

    #[test]
    fn bilinear_interpolates_and_wraps() {
        let t = ImageTexture {
            width: 2,
            height: 1,
            pixels: vec![Rgb::ZERO, Rgb::ONE],
        };
        // Texel centres.
        assert_eq!(t.lookup_bilinear(Vec2::new(0.25, 0.5)), Rgb::ZERO);
        assert_eq!(t.lookup_bilinear(Vec2::new(0.75, 0.5)), Rgb::ONE);
        // Halfway between them.
        assert!((t.lookup_bilinear(Vec2::new(0.5, 0.5)) - Rgb::splat(0.5)).length() < 1e-6);
        // Wrapping: u = 0 lies halfway between the last and first texel.
        assert!((t.lookup_bilinear(Vec2::new(0.0, 0.5)) - Rgb::splat(0.5)).length() < 1e-6);
        assert_eq!(t.lookup_bilinear(Vec2::new(1.25, 0.5)), Rgb::ZERO);
    }

    #[test]
    fn png_is_decoded_from_srgb() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.png");
        let img = ::image::RgbImage::from_pixel(2, 2, ::image::Rgb([128, 255, 0]));
        img.save(&path).unwrap();
        let t = ImageTexture::load(&path, None).unwrap();
        assert_eq!((t.width, t.height), (2, 2));
        assert!((t.pixels[0].x - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
        assert_eq!(t.pixels[0].y, 1.0);
        let lin = ImageTexture::load(&path, Some(false)).unwrap();
        assert!((lin.pixels[0].x - 128.0 / 255.0).abs() < 1e-6);
    }

    #[test]
    fn bmp_is_decoded_from_srgb() {
        let img = ::image::RgbImage::from_pixel(2, 3, ::image::Rgb([128, 255, 0]));
        let mut bmp = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut bmp), ::image::ImageFormat::Bmp)
            .unwrap();
        let t = ImageTexture::decode(&bmp, None).unwrap();
        assert_eq!((t.width, t.height), (2, 3));
        assert!((t.pixels[0].x - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
        assert_eq!((t.pixels[5].y, t.pixels[5].z), (1.0, 0.0));
    }

    #[test]
    fn encoded_png_in_memory_is_decoded() {
        let img = ::image::RgbImage::from_pixel(3, 1, ::image::Rgb([128, 255, 0]));
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), ::image::ImageFormat::Png)
            .unwrap();
        let t = ImageTexture::from_encoded(&png, true).unwrap();
        assert_eq!((t.width, t.height), (3, 1));
        assert!((t.pixels[2].x - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
        let lin = ImageTexture::from_encoded(&png, false).unwrap();
        assert!((lin.pixels[0].x - 128.0 / 255.0).abs() < 1e-6);
        assert!(ImageTexture::from_encoded(b"garbage", true).is_err());
        assert!(ImageTexture::from_encoded(&png[..png.len() / 2], true).is_err());
    }

    #[test]
    fn missing_and_garbage_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let e = ImageTexture::load(&dir.path().join("nope.png"), None).unwrap_err();
        assert!(e.to_string().contains("nope.png"));
        let bad = dir.path().join("bad.png");
        std::fs::write(&bad, b"not a png at all").unwrap();
        assert!(ImageTexture::load(&bad, None).is_err());
    }
}
