//! The film: where samples accumulate into pixels, and how pixels become
//! image files.
//!
//! Pixels hold sums of weighted linear radiance in double precision, added
//! in sample order, so that the image does not depend on how the work was
//! split between threads or passes. Tone mapping happens only when an
//! 8-bit image is written.

pub mod denoise;
pub mod filter;
pub mod io;
pub mod metrics;
pub mod splat;
pub mod text;
pub mod tonemap;

use crate::color::{Rgb, luminance};
use glam::{DVec3, Vec3};

/// A linear RGB image in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels row by row, top row first.
    pub pixels: Vec<Rgb>,
}

impl Image {
    /// A black image.
    pub fn new(width: u32, height: u32) -> Image {
        Image {
            width,
            height,
            pixels: vec![Rgb::ZERO; width as usize * height as usize],
        }
    }

    /// The pixel at column `x`, row `y` (from the top).
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Rgb {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// The image `k` times smaller in each direction, each pixel the mean
    /// of a k×k block (a box filter). `None` unless `k` divides both sides.
    pub fn downscaled(&self, k: u32) -> Option<Image> {
        if k == 0 || self.width % k != 0 || self.height % k != 0 {
            return None;
        }
        let mut out = Image::new(self.width / k, self.height / k);
        for y in 0..out.height {
            for x in 0..out.width {
                let mut sum = DVec3::ZERO;
                for dy in 0..k {
                    for dx in 0..k {
                        sum += self.get(x * k + dx, y * k + dy).as_dvec3();
                    }
                }
                out.pixels[(y * out.width + x) as usize] = (sum / (k * k) as f64).as_vec3();
            }
        }
        Some(out)
    }

    /// Mean of each channel.
    pub fn mean(&self) -> Rgb {
        let s = self.pixels.iter().fold(DVec3::ZERO, |a, p| a + p.as_dvec3());
        (s / self.pixels.len().max(1) as f64).as_vec3()
    }
}

/// Accumulated samples of one pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelSum {
    /// Σ wᵢ·Lᵢ.
    pub rgb: DVec3,
    /// Σ wᵢ.
    pub weight: f64,
    /// Σ wᵢ·Yᵢ² (luminance squared), for the variance estimate.
    pub lum_sq: f64,
}

impl PixelSum {
    /// Adds one sample.
    #[inline]
    pub fn add(&mut self, l: Rgb, w: f32) {
        let w = w as f64;
        self.rgb += l.as_dvec3() * w;
        self.weight += w;
        let y = luminance(l) as f64;
        self.lum_sq += w * y * y;
    }

    /// Adds one sample whose luminance is already known.
    #[inline]
    pub fn add_with_luminance(&mut self, l: Rgb, y: f32, w: f32) {
        let w = w as f64;
        self.rgb += l.as_dvec3() * w;
        self.weight += w;
        self.lum_sq += w * (y as f64) * (y as f64);
    }

    /// Adds another sum's samples.
    #[inline]
    pub fn merge(&mut self, o: &PixelSum) {
        self.rgb += o.rgb;
        self.weight += o.weight;
        self.lum_sq += o.lum_sq;
    }

    /// The pixel's estimate (black without samples).
    #[inline]
    pub fn value(&self) -> Rgb {
        if self.weight > 0.0 {
            (self.rgb / self.weight).as_vec3()
        } else {
            Rgb::ZERO
        }
    }

    /// Estimated variance of the pixel's mean luminance (sample variance
    /// over the number of samples), for error reports.
    pub fn variance_of_mean(&self) -> f64 {
        if self.weight <= 1.0 {
            return 0.0;
        }
        let n = self.weight;
        let mean = luminance(self.value()) as f64;
        let var = (self.lum_sq / n - mean * mean).max(0.0) * n / (n - 1.0);
        var / n
    }
}

/// The auxiliary channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aov {
    /// Surface colour (reflectance) at the first non-specular hit.
    Albedo,
    /// World-space shading normal at the first non-specular hit, facing the
    /// camera; components in [−1, 1].
    Normal,
    /// Distance along the camera ray to the first hit (0 where nothing is hit).
    Depth,
}

impl Aov {
    /// The names accepted on the command line.
    pub const NAMES: [&'static str; 3] = ["albedo", "normal", "depth"];

    /// Parses one of [`Aov::NAMES`].
    pub fn from_name(s: &str) -> Option<Aov> {
        match s {
            "albedo" => Some(Aov::Albedo),
            "normal" => Some(Aov::Normal),
            "depth" => Some(Aov::Depth),
            _ => None,
        }
    }

    /// This channel's name.
    pub fn name(&self) -> &'static str {
        match self {
            Aov::Albedo => "albedo",
            Aov::Normal => "normal",
            Aov::Depth => "depth",
        }
    }
}

/// The auxiliary values of one camera sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AovSample {
    /// Albedo.
    pub albedo: Rgb,
    /// Normal.
    pub normal: Vec3,
    /// Depth.
    pub depth: f32,
}

/// Accumulated auxiliary values of one pixel (computed by [`crate::integrator::aov`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AovSum {
    /// Σ albedo.
    pub albedo: DVec3,
    /// Σ normal.
    pub normal: DVec3,
    /// Σ depth.
    pub depth: f64,
    /// Number of samples.
    pub count: f64,
}

impl AovSum {
    /// Adds one sample.
    #[inline]
    pub fn add(&mut self, s: &AovSample) {
        self.albedo += s.albedo.as_dvec3();
        self.normal += s.normal.as_dvec3();
        self.depth += s.depth as f64;
        self.count += 1.0;
    }
}

/// The accumulation buffer of a render.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel sums, row by row from the top.
    pub pixels: Vec<PixelSum>,
    /// Auxiliary sums, when requested.
    pub aovs: Option<Vec<AovSum>>,
}

impl Film {
    /// An empty film.
    pub fn new(width: u32, height: u32) -> Film {
        Film {
            width,
            height,
            pixels: vec![PixelSum::default(); width as usize * height as usize],
            aovs: None,
        }
    }

    /// The image of one auxiliary channel, if they were recorded. Normals
    /// are averaged (not renormalised), so edge pixels show the mix.
    pub fn aov_image(&self, aov: Aov) -> Option<Image> {
        let sums = self.aovs.as_ref()?;
        let pixels = sums
            .iter()
            .map(|a| {
                let n = a.count.max(1.0);
                match aov {
                    Aov::Albedo => (a.albedo / n).as_vec3(),
                    Aov::Normal => (a.normal / n).as_vec3(),
                    Aov::Depth => Rgb::splat((a.depth / n) as f32),
                }
            })
            .collect();
        Some(Image {
            width: self.width,
            height: self.height,
            pixels,
        })
    }

    /// The current estimate of every pixel.
    pub fn to_image(&self) -> Image {
        Image {
            width: self.width,
            height: self.height,
            pixels: self.pixels.iter().map(PixelSum::value).collect(),
        }
    }

    /// Mean over pixels of the standard error of each pixel's luminance.
    pub fn mean_standard_error(&self) -> f64 {
        let s: f64 = self.pixels.iter().map(|p| p.variance_of_mean().sqrt()).sum();
        s / self.pixels.len().max(1) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_mean_and_variance() {
        let mut p = PixelSum::default();
        for v in [1.0f32, 3.0] {
            p.add(Rgb::splat(v), 1.0);
        }
        assert_eq!(p.value(), Rgb::splat(2.0));
        // Sample variance of {1, 3} is 2; of the mean, 1.
        assert!((p.variance_of_mean() - 1.0).abs() < 1e-9);
        assert_eq!(PixelSum::default().value(), Rgb::ZERO);
    }

    /// The memory estimate (`scene::memory`) counts this size per pixel.
    #[test]
    fn pixel_sums_are_the_size_the_memory_estimate_counts() {
        assert_eq!(
            std::mem::size_of::<PixelSum>() as u64,
            crate::scene::memory::PIXEL_SUM_BYTES
        );
    }
}
