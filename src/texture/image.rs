//! Image textures: images decoded by `film::io` (8- and 16-bit images from
//! sRGB, float images as linear) and their filtered lookup.

use crate::color::space::ColorSpace;
use crate::color::{Encoding, Rgb};
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

/// What an image's colours are, which decides how they convert from
/// another colour space (see [`crate::color::space`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageColors {
    /// Reflectances and other factors: the space's white stays white.
    Reflectance,
    /// Emitted light: its XYZ is kept.
    Emission,
    /// Not colours (a normal map's vectors): read as they are.
    Data,
}

/// Largest texture accepted, in pixels (a 16k × 16k image).
pub const MAX_TEXTURE_PIXELS: u64 = crate::film::io::MAX_IMAGE_PIXELS;

impl ImageTexture {
    /// Reads a PNG, JPEG, BMP, TGA, PPM (PGM, PBM), Radiance HDR, OpenEXR
    /// or PFM file, decoded by `encoding`; where it is `None`, integer
    /// images from sRGB and float images as linear.
    pub fn load(path: &Path, encoding: Option<Encoding>) -> Result<ImageTexture> {
        let bytes = crate::files::read_limited(path, crate::files::MAX_IMAGE_FILE_BYTES)
            .map_err(|e| Error::file(path, format!("cannot open image: {e}")))?;
        let ext = path.extension().and_then(|e| e.to_str());
        let image = crate::film::io::decode_any_named(&bytes, encoding, ext).map_err(|e| Error::file(path, e))?;
        Self::from_image(image).map_err(|e| Error::file(path, e))
    }

    /// [`ImageTexture::load`] with the colours converted to linear sRGB
    /// from the colour space an OpenEXR file's `chromaticities` name
    /// (Rec. 2020, DCI-P3, ACES2065-1), as `colors` says the image is used
    /// (`color::space`). Chromaticities of another space leave the colours
    /// as they are, read as sRGB (as pbrt-v4 does): the second value then
    /// says so, for a warning.
    pub fn load_colors(
        path: &Path,
        encoding: Option<Encoding>,
        colors: ImageColors,
    ) -> Result<(ImageTexture, Option<String>)> {
        let bytes = crate::files::read_limited(path, crate::files::MAX_IMAGE_FILE_BYTES)
            .map_err(|e| Error::file(path, format!("cannot open image: {e}")))?;
        let ext = path.extension().and_then(|e| e.to_str());
        let image = crate::film::io::decode_any_named(&bytes, encoding, ext).map_err(|e| Error::file(path, e))?;
        let mut texture = Self::from_image(image).map_err(|e| Error::file(path, e))?;
        let chromaticities = crate::film::io::exr_chromaticities(&bytes).filter(|_| colors != ImageColors::Data);
        let Some(c) = chromaticities else {
            return Ok((texture, None));
        };
        match ColorSpace::from_primaries_and_white(c) {
            Some(space) => {
                if space != ColorSpace::Srgb {
                    let m = space.to_srgb(colors == ImageColors::Emission);
                    for p in &mut texture.pixels {
                        *p = m * *p;
                    }
                }
                Ok((texture, None))
            }
            None => {
                let [r, g, b, w] = c;
                Ok((
                    texture,
                    Some(format!(
                        "{}: the colour space of chromaticities r {r:?} g {g:?} b {b:?} white {w:?} is unsupported: its colours are read as sRGB",
                        path.display()
                    )),
                ))
            }
        }
    }

    /// Reads an image as pbrt-v4 reads a float image texture (its
    /// `MIPMap::Bilerp<Float>`): one value a texel, in all three channels:
    /// the image's alpha where it has one that is not 1 everywhere, else
    /// the mean of its red, green and blue (for a grey image, its value).
    pub fn load_float(path: &Path, encoding: Option<Encoding>) -> Result<ImageTexture> {
        let bytes = crate::files::read_limited(path, crate::files::MAX_IMAGE_FILE_BYTES)
            .map_err(|e| Error::file(path, format!("cannot open image: {e}")))?;
        let ext = path.extension().and_then(|e| e.to_str());
        let (mut image, alpha) =
            crate::film::io::decode_any_with_alpha(&bytes, encoding, ext).map_err(|e| Error::file(path, e))?;
        match alpha.filter(|a| a.iter().any(|&x| x != 1.0)) {
            Some(alpha) => {
                for (p, a) in image.pixels.iter_mut().zip(alpha) {
                    *p = Rgb::splat(a);
                }
            }
            None => {
                for p in &mut image.pixels {
                    *p = Rgb::splat((p.x + p.y + p.z) / 3.0);
                }
            }
        }
        Self::from_image(image).map_err(|e| Error::file(path, e))
    }

    /// Reads an image's alpha channel as a grey texture, 1 where the image
    /// has none: glTF's coverage, which its base colour image carries.
    pub fn load_alpha(path: &Path) -> Result<ImageTexture> {
        let bytes = crate::files::read_limited(path, crate::files::MAX_IMAGE_FILE_BYTES)
            .map_err(|e| Error::file(path, format!("cannot open image: {e}")))?;
        let ext = path.extension().and_then(|e| e.to_str());
        Self::alpha_of(&bytes, ext).map_err(|e| Error::file(path, e))
    }

    /// [`ImageTexture::load_alpha`] of an image held in memory (a PNG or
    /// JPEG embedded in a glTF file). Errors are plain reasons.
    pub fn alpha_from_encoded(bytes: &[u8]) -> Result<ImageTexture, String> {
        let format = ::image::guess_format(bytes).map_err(|e| format!("cannot read image: {e}"))?;
        if !matches!(format, ::image::ImageFormat::Png | ::image::ImageFormat::Jpeg) {
            return Err("not a PNG or JPEG image".into());
        }
        Self::alpha_of(bytes, None)
    }

    fn alpha_of(bytes: &[u8], ext: Option<&str>) -> Result<ImageTexture, String> {
        // Alpha is coverage, not a colour: read linear.
        let (mut image, alpha) = crate::film::io::decode_any_with_alpha(bytes, Some(Encoding::Linear), ext)?;
        match alpha {
            Some(alpha) => {
                for (p, a) in image.pixels.iter_mut().zip(alpha) {
                    *p = Rgb::splat(a);
                }
            }
            None => image.pixels.fill(Rgb::ONE),
        }
        Self::from_image(image)
    }

    /// Decodes a PNG, JPEG, BMP, Radiance HDR, OpenEXR or PFM image held in
    /// memory (told apart by their first bytes), as [`ImageTexture::load`] does.
    /// The size in the header is checked before any pixel is allocated.
    /// Errors are plain reasons, for the caller to place.
    pub fn decode(bytes: &[u8], encoding: Option<Encoding>) -> Result<ImageTexture, String> {
        Self::from_image(crate::film::io::decode_any(bytes, encoding)?)
    }

    /// A decoded image as a texture, which must have pixels.
    fn from_image(image: crate::film::Image) -> Result<ImageTexture, String> {
        if image.pixels.is_empty() || image.pixels.len() != image.width as usize * image.height as usize {
            return Err(format!(
                "an image of {}×{} pixels cannot be a texture",
                image.width, image.height
            ));
        }
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
        Self::decode(bytes, Some(if srgb { Encoding::Srgb } else { Encoding::Linear }))
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

    /// The texel at integer coordinates, brought into the image by `wrap`
    /// (along x, along y).
    #[inline]
    fn texel(&self, x: i64, y: i64, wrap: [WrapMode; 2]) -> Rgb {
        let x = wrap[0].apply(x, self.width as i64) as usize;
        let y = wrap[1].apply(y, self.height as i64) as usize;
        self.pixels[y * self.width as usize + x]
    }

    /// Bilinearly filtered colour at `uv`, repeating outside [0, 1]²;
    /// v = 0 is the bottom row of the image.
    #[inline]
    pub fn lookup_bilinear(&self, uv: Vec2) -> Rgb {
        self.lookup(uv, [WrapMode::Repeat; 2], ImageFilter::Bilinear)
    }

    /// The colour at `uv` (v = 0 is the bottom row of the image), filtered
    /// by `filter`, the image extended beyond [0, 1]² by `wrap` (along u,
    /// along v: glTF's wrapS and wrapT, pbrt-v4's `WrapMode2D`). Texel
    /// centres lie at half-integer pixel coordinates, as in Mitsuba's
    /// `bitmap` and pbrt-v4's `Image`.
    #[inline]
    pub fn lookup(&self, uv: Vec2, wrap: [WrapMode; 2], filter: ImageFilter) -> Rgb {
        let x = uv.x * self.width as f32;
        let y = (1.0 - uv.y) * self.height as f32;
        if !x.is_finite() || !y.is_finite() {
            return self.pixels[0];
        }
        match filter {
            ImageFilter::Nearest => self.texel(crate::math::floor(x) as i64, crate::math::floor(y) as i64, wrap),
            ImageFilter::Bilinear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (crate::math::floor(x), crate::math::floor(y));
                let (fx, fy) = (x - x0, y - y0);
                let (xi, yi) = (x0 as i64, y0 as i64);
                let top = self.texel(xi, yi, wrap) * (1.0 - fx) + self.texel(xi + 1, yi, wrap) * fx;
                let bottom = self.texel(xi, yi + 1, wrap) * (1.0 - fx) + self.texel(xi + 1, yi + 1, wrap) * fx;
                top * (1.0 - fy) + bottom * fy
            }
        }
    }

    /// The derivatives along u and v of the luminance of
    /// [`ImageTexture::lookup`] at `uv` times `tint`: those of the bilinear interpolant
    /// (zero for nearest-texel reads, constant between texels), as
    /// Mitsuba's `bitmap` gives them to bump maps (`eval_1_grad`).
    pub fn luminance_gradient(&self, uv: Vec2, wrap: [WrapMode; 2], filter: ImageFilter, tint: Rgb) -> Vec2 {
        let (w, h) = (self.width as f32, self.height as f32);
        let (x, y) = (uv.x * w - 0.5, (1.0 - uv.y) * h - 0.5);
        if filter == ImageFilter::Nearest || !x.is_finite() || !y.is_finite() {
            return Vec2::ZERO;
        }
        let (x0, y0) = (crate::math::floor(x), crate::math::floor(y));
        let (fx, fy) = (x - x0, y - y0);
        let (xi, yi) = (x0 as i64, y0 as i64);
        let f = |dx: i64, dy: i64| crate::color::luminance(self.texel(xi + dx, yi + dy, wrap) * tint);
        let (f00, f10, f01, f11) = (f(0, 0), f(1, 0), f(0, 1), f(1, 1));
        let d_dx = (1.0 - fy) * (f10 - f00) + fy * (f11 - f01);
        let d_dy = (1.0 - fx) * (f01 - f00) + fx * (f11 - f10);
        // x = u·w − 1/2 and y = (1 − v)·h − 1/2.
        Vec2::new(d_dx * w, -d_dy * h)
    }

    /// Mean colour.
    pub fn average(&self) -> Rgb {
        let sum = self.pixels.iter().fold(glam::DVec3::ZERO, |a, p| a + p.as_dvec3());
        (sum / self.pixels.len().max(1) as f64).as_vec3()
    }
}

/// How an image continues beyond [0, 1]² of (u, v).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WrapMode {
    /// Tiled.
    #[default]
    Repeat,
    /// Tiled, every other tile mirrored, so that the edges meet.
    Mirror,
    /// The edge texels extended.
    Clamp,
}

impl WrapMode {
    /// Texel coordinate `i` brought into `0..n` (Mitsuba's `bitmap` wrap).
    #[inline]
    pub(crate) fn apply(self, i: i64, n: i64) -> i64 {
        match self {
            WrapMode::Repeat => repeat(i, n),
            WrapMode::Clamp => i.clamp(0, n - 1),
            WrapMode::Mirror => {
                let k = repeat(i, 2 * n);
                if k < n { k } else { 2 * n - 1 - k }
            }
        }
    }
}

/// `i` modulo `n` (> 0) in `0..n`. The texels of a lookup in [0, 1] lie
/// within one period of it, where a comparison does what the remainder, an
/// integer division of tens of cycles, would.
#[inline]
fn repeat(i: i64, n: i64) -> i64 {
    if (0..n).contains(&i) {
        i
    } else if (-n..0).contains(&i) {
        i + n
    } else {
        i.rem_euclid(n)
    }
}

/// How an image is read between its texels' centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ImageFilter {
    /// Bilinear interpolation of the four nearest texels.
    #[default]
    Bilinear,
    /// The texel the point lies in.
    Nearest,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::srgb_to_linear;

    /// An OpenEXR image names its colour space by its chromaticities:
    /// written in one, it is read back into linear sRGB as its use asks;
    /// a space trazo does not know is read as sRGB, with a note; other
    /// formats cannot name a space and are written in sRGB.
    #[test]
    fn exr_chromaticities_convert_images_to_srgb() {
        use crate::film::io::{exr_chromaticities, read_image, write_image, write_image_in};
        use crate::settings::Tonemap;
        let dir = tempfile::tempdir().unwrap();
        let colours = vec![Rgb::new(0.5, 0.25, 0.125), Rgb::new(0.1, 0.7, 0.2), Rgb::ONE];
        let image = crate::film::Image {
            width: 3,
            height: 1,
            pixels: colours.clone(),
        };
        for space in [ColorSpace::Aces2065_1, ColorSpace::Rec2020, ColorSpace::DciP3] {
            let path = dir.path().join(format!("{}.exr", space.pbrt_name()));
            write_image_in(&path, &image, Tonemap::Clamp, 0.0, space).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            let c = exr_chromaticities(&bytes).unwrap();
            assert_eq!(ColorSpace::from_primaries_and_white(c), Some(space));
            for (colors, emitted) in [(ImageColors::Reflectance, false), (ImageColors::Emission, true)] {
                let (t, note) = ImageTexture::load_colors(&path, None, colors).unwrap();
                assert!(note.is_none());
                for (got, c) in t.pixels.iter().zip(&colours) {
                    let want = space.to_srgb(emitted) * *c;
                    assert!(
                        (*got - want).abs().max_element() < 1e-6,
                        "{space:?} {colors:?}: {got} against {want}"
                    );
                }
            }
            // A reflectance of 1 stays white in every space.
            let (t, _) = ImageTexture::load_colors(&path, None, ImageColors::Reflectance).unwrap();
            assert!(
                (t.pixels[2] - Rgb::ONE).abs().max_element() < 1e-4,
                "{space:?}: {}",
                t.pixels[2]
            );
            let (t, _) = ImageTexture::load_colors(&path, None, ImageColors::Data).unwrap();
            assert_eq!(t.pixels, colours);
            // A PNG cannot say it is in another space: its pixels are
            // converted back to sRGB, as the same light written in sRGB.
            let png = dir.path().join("out.png");
            let srgb_png = dir.path().join("srgb.png");
            write_image_in(&png, &image, Tonemap::Clamp, 0.0, space).unwrap();
            let to_srgb = space.to_srgb(true);
            let back = crate::film::Image {
                width: 3,
                height: 1,
                pixels: colours.iter().map(|c| to_srgb * *c).collect(),
            };
            write_image(&srgb_png, &back, Tonemap::Clamp, 0.0).unwrap();
            assert_eq!(read_image(&png).unwrap().pixels, read_image(&srgb_png).unwrap().pixels);
        }
        // sRGB files carry no attribute.
        let path = dir.path().join("srgb.exr");
        write_image(&path, &image, Tonemap::Clamp, 0.0).unwrap();
        assert_eq!(exr_chromaticities(&std::fs::read(&path).unwrap()), None);
        // Adobe RGB: unknown, read as sRGB, with a note naming the file.
        let adobe = dir.path().join("adobe.exr");
        {
            use exr::prelude::{Encoding, Image as ExrImage, SpecificChannels, WritableImage};
            let channels = SpecificChannels::rgb(|exr::math::Vec2(x, _y): exr::math::Vec2<usize>| {
                let c = colours[x];
                (c.x, c.y, c.z)
            });
            let mut exr = ExrImage::from_encoded_channels((3, 1), Encoding::FAST_LOSSLESS, channels);
            let v = |x: f32, y: f32| exr::math::Vec2(x, y);
            exr.attributes.chromaticities = Some(exr::meta::attribute::Chromaticities {
                red: v(0.64, 0.33),
                green: v(0.21, 0.71),
                blue: v(0.15, 0.06),
                white: v(0.3127, 0.329),
            });
            exr.write().to_file(&adobe).unwrap();
        }
        let (t, note) = ImageTexture::load_colors(&adobe, None, ImageColors::Emission).unwrap();
        assert_eq!(t.pixels, colours);
        let note = note.unwrap();
        assert!(note.contains("adobe.exr") && note.contains("read as sRGB"), "{note}");
    }

    #[test]
    fn float_images_are_their_alpha_or_the_mean_of_their_colours() {
        let dir = tempfile::tempdir().unwrap();
        let rgba = |alpha: [u8; 2]| {
            ::image::RgbaImage::from_raw(2, 1, vec![255, 0, 0, alpha[0], 0, 255, 255, alpha[1]]).unwrap()
        };
        let cut = dir.path().join("cut.png");
        rgba([0, 128]).save(&cut).unwrap();
        let t = ImageTexture::load_float(&cut, None).unwrap();
        // The alpha, decoded by the image's (sRGB) encoding as pbrt-v4 does.
        assert_eq!(t.pixels, vec![Rgb::ZERO, Rgb::splat(srgb_to_linear(128.0 / 255.0))]);
        // Opaque everywhere: the mean of the colours.
        let opaque = dir.path().join("opaque.png");
        rgba([255, 255]).save(&opaque).unwrap();
        let t = ImageTexture::load_float(&opaque, None).unwrap();
        assert_eq!(t.pixels, vec![Rgb::splat(1.0 / 3.0), Rgb::splat(2.0 / 3.0)]);
        let plain = dir.path().join("plain.png");
        ::image::RgbImage::from_raw(1, 1, vec![255, 255, 0])
            .unwrap()
            .save(&plain)
            .unwrap();
        let t = ImageTexture::load_float(&plain, Some(Encoding::Linear)).unwrap();
        assert_eq!(t.pixels, vec![Rgb::splat(2.0 / 3.0)]);
    }

    #[test]
    fn repeat_is_the_euclidean_remainder() {
        for n in [1i64, 2, 5, 256] {
            for i in -3 * n - 2..3 * n + 2 {
                assert_eq!(repeat(i, n), i.rem_euclid(n), "{i} mod {n}");
            }
            for i in [i64::MIN, i64::MIN + 1, i64::MAX] {
                assert_eq!(repeat(i, n), i.rem_euclid(n));
            }
        }
    }

    #[test]
    fn luminance_gradients_are_the_interpolants_derivatives() {
        // A 5 × 4 image of unrelated colours, every wrap, against central
        // differences of the looked-up luminance inside texel cells.
        let mut rng = crate::sampling::rng::Pcg32::new(11, 3);
        let pixels = (0..20)
            .map(|_| Rgb::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))
            .collect();
        let t = ImageTexture {
            width: 5,
            height: 4,
            pixels,
        };
        let tint = Rgb::new(0.5, 2.0, 1.0);
        let lum =
            |uv: Vec2, wrap: [WrapMode; 2]| crate::color::luminance(t.lookup(uv, wrap, ImageFilter::Bilinear) * tint);
        let h = 1e-3;
        use WrapMode::{Clamp, Mirror, Repeat};
        for wrap in [[Repeat; 2], [Clamp; 2], [Mirror; 2], [Repeat, Clamp], [Mirror, Repeat]] {
            for _ in 0..200 {
                let uv = Vec2::new(rng.next_f32() * 3.0 - 1.0, rng.next_f32() * 3.0 - 1.0);
                // Central differences straddle no texel centre.
                let (x, y) = (uv.x * 5.0 - 0.5, (1.0 - uv.y) * 4.0 - 0.5);
                if (x - x.round()).abs() < 0.01 || (y - y.round()).abs() < 0.01 {
                    continue;
                }
                let g = t.luminance_gradient(uv, wrap, ImageFilter::Bilinear, tint);
                let du = (lum(uv + Vec2::new(h, 0.0), wrap) - lum(uv - Vec2::new(h, 0.0), wrap)) / (2.0 * h);
                let dv = (lum(uv + Vec2::new(0.0, h), wrap) - lum(uv - Vec2::new(0.0, h), wrap)) / (2.0 * h);
                assert!(
                    (g.x - du).abs() < 0.02 * (1.0 + du.abs()),
                    "{wrap:?} {uv}: {} against {du}",
                    g.x
                );
                assert!(
                    (g.y - dv).abs() < 0.02 * (1.0 + dv.abs()),
                    "{wrap:?} {uv}: {} against {dv}",
                    g.y
                );
            }
        }
        // Nearest-texel reads are flat.
        assert_eq!(
            t.luminance_gradient(Vec2::splat(0.3), [WrapMode::Repeat; 2], ImageFilter::Nearest, tint),
            Vec2::ZERO
        );
    }

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

    /// Beyond [0, 1]² an image repeats, mirrors (its edges meeting) or
    /// extends its edge texels; nearest filtering reads the texel a point
    /// lies in.
    #[test]
    fn wrap_modes_and_nearest_filtering() {
        let t = ImageTexture {
            width: 3,
            height: 1,
            pixels: vec![Rgb::splat(0.0), Rgb::splat(1.0), Rgb::splat(2.0)],
        };
        let at = |u: f32, wrap: WrapMode, filter: ImageFilter| t.lookup(Vec2::new(u, 0.5), [wrap; 2], filter).x;
        let near = ImageFilter::Nearest;
        // Texel k covers u in [k/3, (k+1)/3).
        for (u, repeat, mirror, clamp) in [
            (0.5, 1.0, 1.0, 1.0),
            (1.1, 0.0, 2.0, 2.0),
            (1.5, 1.0, 1.0, 2.0),
            (1.9, 2.0, 0.0, 2.0),
            (-0.1, 2.0, 0.0, 0.0),
            (2.1, 0.0, 0.0, 2.0),
        ] {
            assert_eq!(at(u, WrapMode::Repeat, near), repeat, "repeat at {u}");
            assert_eq!(at(u, WrapMode::Mirror, near), mirror, "mirror at {u}");
            assert_eq!(at(u, WrapMode::Clamp, near), clamp, "clamp at {u}");
        }
        // Bilinear at the right edge (u = 1, between the last texel and
        // the next): the first texel when repeating, the last itself when
        // mirrored or clamped.
        let bi = ImageFilter::Bilinear;
        assert!((at(1.0, WrapMode::Repeat, bi) - 1.0).abs() < 1e-6);
        assert!((at(1.0, WrapMode::Mirror, bi) - 2.0).abs() < 1e-6);
        assert!((at(1.0, WrapMode::Clamp, bi) - 2.0).abs() < 1e-6);
        assert_eq!(
            t.lookup_bilinear(Vec2::new(0.3, 0.5)),
            t.lookup(Vec2::new(0.3, 0.5), [WrapMode::Repeat; 2], bi)
        );
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
        let lin = ImageTexture::load(&path, Some(Encoding::Linear)).unwrap();
        assert!((lin.pixels[0].x - 128.0 / 255.0).abs() < 1e-6);
        // A power law: (128/255)^2.2, 1 stays 1 and 0 stays 0.
        let gamma = ImageTexture::load(&path, Some(Encoding::Gamma(2.2))).unwrap();
        assert!((gamma.pixels[0].x - (128.0f32 / 255.0).powf(2.2)).abs() < 1e-6);
        assert_eq!((gamma.pixels[0].y, gamma.pixels[0].z), (1.0, 0.0));
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

    /// TGA (which has no signature: its extension names it) and binary PPM
    /// files, as Mitsuba reads them: 8-bit sRGB, rows from the top.
    #[test]
    fn tga_and_ppm_files_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = ::image::RgbImage::from_pixel(2, 3, ::image::Rgb([128, 255, 0]));
        img.put_pixel(1, 2, ::image::Rgb([0, 0, 255]));
        for name in ["t.tga", "t.ppm"] {
            let path = dir.path().join(name);
            img.save(&path).unwrap();
            let t = ImageTexture::load(&path, None).unwrap();
            assert_eq!((t.width, t.height), (2, 3), "{name}");
            assert!((t.pixels[0].x - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6, "{name}");
            assert_eq!(t.pixels[5], Rgb::new(0.0, 0.0, 1.0), "{name}");
        }
        // A TGA's bytes alone name no format; a truncated one is an error.
        let tga = std::fs::read(dir.path().join("t.tga")).unwrap();
        assert!(ImageTexture::decode(&tga, None).is_err());
        let cut = dir.path().join("cut.tga");
        std::fs::write(&cut, &tga[..20]).unwrap();
        let e = ImageTexture::load(&cut, None).unwrap_err().to_string();
        assert!(e.contains("cut.tga"), "{e}");
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
