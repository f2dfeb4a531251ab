//! The film: where samples accumulate into pixels, and how pixels become
//! image files.
//!
//! A pass sums its samples into each pixel in double precision
//! ([`PixelSum`]); the film adds those sums in fixed point
//! ([`ExactSums`]), where addition is exact and so associative: the image
//! does not depend on how the work was split between threads, passes,
//! resumed runs or the shards of a farm, whose films merge bit for bit.
//! Tone mapping happens only when an 8-bit image is written.

pub mod denoise;
pub mod display;
pub mod filter;
pub mod io;
pub mod metrics;
pub mod plot;
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

/// One unit of the film's fixed point is 2⁻⁵⁰ (about 9·10⁻¹⁶); a sum
/// reaches 2⁷⁷ (about 10²³) before it saturates.
const FIXED_SCALE: f64 = (1u64 << 50) as f64;

/// `v` in units of 2⁻⁵⁰, rounded toward zero; NaN becomes 0 and values
/// beyond the range saturate. Pass sums below 2¹³ take the one-instruction
/// conversion through `i64`.
#[inline]
fn to_fixed(v: f64) -> i128 {
    let x = v * FIXED_SCALE;
    if x.abs() < 9.2e18 { x as i64 as i128 } else { x as i128 }
}

/// Sums in fixed point: integers, so that adding them is exact, and the
/// same numbers added in any grouping and order give the same bits. The
/// film's pixels (`N` = 5: [`PixelSum`]'s fields) and auxiliary sums
/// (`N` = 9: [`AovSum`]'s) are kept so.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExactSums<const N: usize>(pub [i128; N]);

impl<const N: usize> Default for ExactSums<N> {
    fn default() -> Self {
        ExactSums([0; N])
    }
}

impl<const N: usize> ExactSums<N> {
    /// Adds `values`, each rounded once to the fixed point.
    #[inline]
    pub fn add(&mut self, values: [f64; N]) {
        for (s, v) in self.0.iter_mut().zip(values) {
            *s = s.saturating_add(to_fixed(v));
        }
    }

    /// Adds other sums, exactly (saturating at the range's ends).
    #[inline]
    pub fn merge(&mut self, other: &ExactSums<N>) {
        for (s, o) in self.0.iter_mut().zip(other.0) {
            *s = s.saturating_add(o);
        }
    }

    /// The sums as floating-point numbers.
    #[inline]
    pub fn to_f64(&self) -> [f64; N] {
        self.0.map(|v| v as f64 / FIXED_SCALE)
    }
}

/// A pixel of the film: [`PixelSum`]'s sums (Σw·L, Σw, Σw·Y²) in fixed point.
pub type FilmPixel = ExactSums<5>;

impl FilmPixel {
    /// Adds what a pass summed into this pixel.
    #[inline]
    pub fn add_sum(&mut self, s: &PixelSum) {
        self.add([s.rgb.x, s.rgb.y, s.rgb.z, s.weight, s.lum_sq]);
    }

    /// This pixel plus `s`.
    #[inline]
    pub fn plus(mut self, s: &PixelSum) -> FilmPixel {
        self.add_sum(s);
        self
    }

    /// The sums in double precision.
    #[inline]
    pub fn sum(&self) -> PixelSum {
        let [r, g, b, weight, lum_sq] = self.to_f64();
        PixelSum {
            rgb: DVec3::new(r, g, b),
            weight,
            lum_sq,
        }
    }

    /// The pixel's estimate (black without samples).
    #[inline]
    pub fn value(&self) -> Rgb {
        self.sum().value()
    }

    /// Σw: the number of samples, where each weighs 1.
    pub fn weight(&self) -> f64 {
        self.sum().weight
    }

    /// See [`PixelSum::variance_of_mean`].
    pub fn variance_of_mean(&self) -> f64 {
        self.sum().variance_of_mean()
    }
}

/// A pixel's auxiliary sums in fixed point ([`AovSum`]'s fields).
pub type FilmAov = ExactSums<9>;

impl FilmAov {
    /// Adds what a pass summed into this pixel.
    #[inline]
    pub fn add_aov(&mut self, a: &AovSum) {
        self.add([
            a.albedo.x, a.albedo.y, a.albedo.z, a.normal.x, a.normal.y, a.normal.z, a.depth, a.count, a.steps,
        ]);
    }

    /// These sums plus `a`.
    #[inline]
    pub fn plus(mut self, a: &AovSum) -> FilmAov {
        self.add_aov(a);
        self
    }

    /// The sums in double precision.
    pub fn sum(&self) -> AovSum {
        let [ar, ag, ab, nx, ny, nz, depth, count, steps] = self.to_f64();
        AovSum {
            albedo: DVec3::new(ar, ag, ab),
            normal: DVec3::new(nx, ny, nz),
            depth,
            count,
            steps,
        }
    }
}

/// What pbrt-v4's `GBufferFilm` records of one camera sample: the first
/// surface with a BSDF that the camera ray meets, its positions and
/// normals already in the G-buffer's coordinates.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GBufferSample {
    /// The point.
    pub p: Vec3,
    /// The geometric normal, facing the ray's origin.
    pub n: Vec3,
    /// The shading normal, facing the ray's origin.
    pub ns: Vec3,
    /// The surface's (u, v).
    pub uv: glam::Vec2,
    /// How far the point moves along z for a step of one pixel along x,
    /// and along y, scaled as pbrt-v4 scales its ray differentials.
    pub dzdx: f32,
    /// See `dzdx`.
    pub dzdy: f32,
    /// The BSDF's directional albedo toward the camera.
    pub albedo: Rgb,
}

/// A pixel's G-buffer sums in fixed point, pbrt-v4's `GBufferFilm::Pixel`:
/// Σw over the samples that saw a surface; Σw·p, Σw·n, Σw·ns, Σw·uv,
/// Σw·dz/dx, Σw·dz/dy, Σw·albedo over them; for the variance of the
/// radiance, their count, Σ L and Σ L² per channel (unweighted, as pbrt-v4
/// estimates it, and of the values its default sensor records, CIE XYZ);
/// and Σw over all the pixel's samples.
pub type FilmGBuffer = ExactSums<GBUFFER_SUMS>;

/// The number of sums of a [`FilmGBuffer`].
pub const GBUFFER_SUMS: usize = 25;

/// The channels of a G-buffer image, in pbrt-v4's order.
pub const GBUFFER_CHANNELS: [&str; 25] = [
    "R",
    "G",
    "B",
    "Albedo.R",
    "Albedo.G",
    "Albedo.B",
    "P.X",
    "P.Y",
    "P.Z",
    "dzdx",
    "dzdy",
    "N.X",
    "N.Y",
    "N.Z",
    "Ns.X",
    "Ns.Y",
    "Ns.Z",
    "u",
    "v",
    "Variance.R",
    "Variance.G",
    "Variance.B",
    "RelativeVariance.R",
    "RelativeVariance.G",
    "RelativeVariance.B",
];

impl FilmGBuffer {
    /// Adds a camera sample of filter weight `w` and sensor value `l` (the
    /// radiance's CIE XYZ, as pbrt-v4's default `cie1931` sensor records
    /// it) that saw the surface `s`, or none.
    #[inline]
    pub fn add_sample(&mut self, s: Option<&GBufferSample>, w: f32, l: Rgb) {
        let w = w as f64;
        let Some(s) = s else {
            self.0[24] = self.0[24].saturating_add(to_fixed(w));
            return;
        };
        let wv = |v: f32| w * v as f64;
        let l = l.as_dvec3();
        self.add([
            w,
            wv(s.p.x),
            wv(s.p.y),
            wv(s.p.z),
            wv(s.n.x),
            wv(s.n.y),
            wv(s.n.z),
            wv(s.ns.x),
            wv(s.ns.y),
            wv(s.ns.z),
            wv(s.uv.x),
            wv(s.uv.y),
            wv(s.dzdx),
            wv(s.dzdy),
            wv(s.albedo.x),
            wv(s.albedo.y),
            wv(s.albedo.z),
            1.0,
            l.x,
            l.y,
            l.z,
            l.x * l.x,
            l.y * l.y,
            l.z * l.z,
            w,
        ]);
    }

    /// This pixel's G-buffer channels after R, G, B (pbrt-v4's
    /// `GBufferFilm::GetImage`): albedo over the pixel's whole filter
    /// weight, positions, uv and depth slopes (as magnitudes) over the
    /// weight of the samples that saw a surface, normals normalised, and
    /// the radiance's variance per channel with its relative variance
    /// (over the mean, 0 where the mean is).
    pub fn channels(&self) -> [f32; 22] {
        let v = self.to_f64();
        let (w, pixel_weight) = (v[0], v[24]);
        let over = |x: f64, by: f64| if by != 0.0 { x / by } else { x };
        let unit = |x: f64, y: f64, z: f64| {
            let len = (x * x + y * y + z * z).sqrt();
            if len > 0.0 {
                [x / len, y / len, z / len]
            } else {
                [0.0; 3]
            }
        };
        let n = unit(v[4], v[5], v[6]);
        let ns = unit(v[7], v[8], v[9]);
        let count = v[17];
        let mut variance = [0.0; 3];
        let mut relative = [0.0; 3];
        for c in 0..3 {
            let (sum, sum_sq) = (v[18 + c], v[21 + c]);
            let mean = if count > 0.0 { sum / count } else { 0.0 };
            variance[c] = if count > 1.0 {
                ((sum_sq - sum * mean) / (count - 1.0)).max(0.0)
            } else {
                0.0
            };
            relative[c] = if count >= 1.0 && mean != 0.0 {
                variance[c] / mean
            } else {
                0.0
            };
        }
        [
            over(v[14], pixel_weight),
            over(v[15], pixel_weight),
            over(v[16], pixel_weight),
            over(v[1], w),
            over(v[2], w),
            over(v[3], w),
            over(v[12], w).abs(),
            over(v[13], w).abs(),
            n[0],
            n[1],
            n[2],
            ns[0],
            ns[1],
            ns[2],
            over(v[10], w),
            over(v[11], w),
            variance[0],
            variance[1],
            variance[2],
            relative[0],
            relative[1],
            relative[2],
        ]
        .map(|x| x as f32)
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
    /// Evaluations along the camera ray of distance functions (sphere
    /// tracing steps) and of implicit surfaces' equations on intervals (0
    /// where it meets neither): where the root finders work hard.
    Steps,
}

impl Aov {
    /// The names accepted on the command line.
    pub const NAMES: [&'static str; 4] = ["albedo", "normal", "depth", "steps"];

    /// Parses one of [`Aov::NAMES`].
    pub fn from_name(s: &str) -> Option<Aov> {
        match s {
            "albedo" => Some(Aov::Albedo),
            "normal" => Some(Aov::Normal),
            "depth" => Some(Aov::Depth),
            "steps" => Some(Aov::Steps),
            _ => None,
        }
    }

    /// This channel's name.
    pub fn name(&self) -> &'static str {
        match self {
            Aov::Albedo => "albedo",
            Aov::Normal => "normal",
            Aov::Depth => "depth",
            Aov::Steps => "steps",
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
    /// Sphere-tracing steps.
    pub steps: f32,
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
    /// Σ sphere-tracing steps.
    pub steps: f64,
}

impl AovSum {
    /// Adds one sample.
    #[inline]
    pub fn add(&mut self, s: &AovSample) {
        self.albedo += s.albedo.as_dvec3();
        self.normal += s.normal.as_dvec3();
        self.depth += s.depth as f64;
        self.count += 1.0;
        self.steps += s.steps as f64;
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
    pub pixels: Vec<FilmPixel>,
    /// Auxiliary sums, when requested.
    pub aovs: Option<Vec<FilmAov>>,
    /// G-buffer sums, when the scene asks for a G-buffer film.
    pub gbuffer: Option<Vec<FilmGBuffer>>,
    /// The colour matrix applied to the pixels' estimates when they are
    /// read ([`Film::to_image`]), after all sums (white balance); the sums
    /// themselves, which checkpoints and shards hold and merge, stay as
    /// rendered.
    pub output_transform: Option<glam::Mat3>,
}

impl Film {
    /// An empty film.
    pub fn new(width: u32, height: u32) -> Film {
        Film {
            width,
            height,
            pixels: vec![FilmPixel::default(); width as usize * height as usize],
            aovs: None,
            gbuffer: None,
            output_transform: None,
        }
    }

    /// The G-buffer's channels after R, G, B, channel by channel, each
    /// row by row from the top, if it was recorded.
    pub fn gbuffer_channels(&self) -> Option<Vec<Vec<f32>>> {
        let sums = self.gbuffer.as_ref()?;
        let mut out = vec![Vec::with_capacity(sums.len()); GBUFFER_CHANNELS.len() - 3];
        for g in sums {
            for (channel, v) in out.iter_mut().zip(g.channels()) {
                channel.push(v);
            }
        }
        Some(out)
    }

    /// The image of one auxiliary channel, if they were recorded. Normals
    /// are averaged (not renormalised), so edge pixels show the mix.
    pub fn aov_image(&self, aov: Aov) -> Option<Image> {
        let sums = self.aovs.as_ref()?;
        let pixels = sums
            .iter()
            .map(|a| {
                let a = a.sum();
                let n = a.count.max(1.0);
                match aov {
                    Aov::Albedo => (a.albedo / n).as_vec3(),
                    Aov::Normal => (a.normal / n).as_vec3(),
                    Aov::Depth => Rgb::splat((a.depth / n) as f32),
                    Aov::Steps => Rgb::splat((a.steps / n) as f32),
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
            pixels: match self.output_transform {
                None => self.pixels.iter().map(FilmPixel::value).collect(),
                Some(m) => self.pixels.iter().map(|p| m * p.value()).collect(),
            },
        }
    }

    /// Adds `other`'s sums (other samples of the same image, such as
    /// another shard's), exactly: films merged in any order are the same.
    /// An error if the sizes or the auxiliary channels differ.
    pub fn merge(&mut self, other: &Film) -> Result<(), String> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(format!(
                "a film of {}×{} pixels cannot merge one of {}×{}",
                self.width, self.height, other.width, other.height
            ));
        }
        match (&mut self.aovs, &other.aovs) {
            (Some(a), Some(b)) => a.iter_mut().zip(b).for_each(|(a, b)| a.merge(b)),
            (None, None) => {}
            _ => return Err("one film has auxiliary images and the other not".into()),
        }
        match (&mut self.gbuffer, &other.gbuffer) {
            (Some(a), Some(b)) => a.iter_mut().zip(b).for_each(|(a, b)| a.merge(b)),
            (None, None) => {}
            _ => return Err("one film has a G-buffer and the other not".into()),
        }
        for (a, b) in self.pixels.iter_mut().zip(&other.pixels) {
            a.merge(b);
        }
        Ok(())
    }

    /// Mean over pixels of the standard error of each pixel's luminance.
    pub fn mean_standard_error(&self) -> f64 {
        let s: f64 = self.pixels.iter().map(|p| p.sum().variance_of_mean().sqrt()).sum();
        s / self.pixels.len().max(1) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// pbrt-v4's G-buffer pixel: geometry over the weight of the samples
    /// that saw a surface, albedo over every sample's, normals normalised,
    /// depth slopes as magnitudes, the radiance's sample variance per
    /// channel and its ratio to the mean.
    #[test]
    fn gbuffer_channels_are_pbrt_v4s() {
        let surface = |p: Vec3, l| {
            let s = GBufferSample {
                p,
                n: Vec3::new(0.0, 0.0, -2.0),
                ns: Vec3::new(0.0, 1.0, -1.0),
                uv: glam::Vec2::new(0.5, 0.25),
                dzdx: -0.25,
                dzdy: 0.5,
                albedo: Rgb::splat(0.8),
            };
            (s, l)
        };
        let mut g = FilmGBuffer::default();
        let (a, la) = surface(Vec3::new(1.0, 0.0, 4.0), Rgb::new(1.0, 2.0, 0.0));
        let (b, lb) = surface(Vec3::new(3.0, 0.0, 6.0), Rgb::new(3.0, 2.0, 0.0));
        g.add_sample(Some(&a), 1.0, la);
        g.add_sample(Some(&b), 1.0, lb);
        g.add_sample(None, 2.0, Rgb::splat(100.0));
        let c = g.channels();
        let close = |x: f32, y: f32| (x - y).abs() < 1e-6;
        // Albedo: Σw·albedo / Σw over all four weights.
        assert!(c[..3].iter().all(|&v| close(v, 0.4)), "{c:?}");
        assert!(close(c[3], 2.0) && close(c[4], 0.0) && close(c[5], 5.0), "{c:?}");
        assert!(close(c[6], 0.25) && close(c[7], 0.5), "{c:?}");
        assert_eq!(c[8..11], [0.0, 0.0, -1.0]);
        let h = std::f32::consts::FRAC_1_SQRT_2;
        assert!(close(c[11], 0.0) && close(c[12], h) && close(c[13], -h), "{c:?}");
        assert!(close(c[14], 0.5) && close(c[15], 0.25), "{c:?}");
        // Radiance 1 and 3 in red: mean 2, sample variance 2; green is
        // constant; blue's mean is 0, so its relative variance is 0.
        assert_eq!(c[16..22], [2.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        // A pixel no sample saw a surface in: zeros.
        let mut empty = FilmGBuffer::default();
        empty.add_sample(None, 1.0, Rgb::ONE);
        assert_eq!(empty.channels(), [0.0; 22]);
    }

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
            std::mem::size_of::<FilmPixel>() as u64,
            crate::scene::memory::PIXEL_SUM_BYTES
        );
    }

    /// The same samples summed in passes of any grouping and in any order
    /// give the same film, bit for bit, which floating-point sums do not.
    #[test]
    fn exact_sums_do_not_depend_on_grouping_or_order() {
        let mut rng = crate::sampling::rng::Pcg32::new(7, 1);
        // Values of very different sizes, where float sums would differ.
        let samples: Vec<Rgb> = (0..300)
            .map(|i| Rgb::splat(rng.next_f32() * 10f32.powi(i % 9 - 4)))
            .collect();
        let film_of = |groups: &[std::ops::Range<usize>]| {
            let mut px = FilmPixel::default();
            for g in groups {
                let mut pass = PixelSum::default();
                for l in &samples[g.clone()] {
                    pass.add(*l, 1.0);
                }
                px.add_sum(&pass);
            }
            px
        };
        let one = film_of(std::slice::from_ref(&(0..300)));
        let a = film_of(&[0..1, 1..2, 2..4, 4..300]);
        let b = film_of(&[150..300, 0..150]);
        // Each pass rounds once, so passes of one sample are the reference.
        let singles: Vec<_> = (0..300).map(|i| i..i + 1).collect();
        let mut reversed = singles.clone();
        reversed.reverse();
        assert_eq!(film_of(&singles), film_of(&reversed));
        let mut parts = [film_of(&singles[..100]), film_of(&singles[100..])];
        parts.swap(0, 1);
        let mut merged = parts[0];
        merged.merge(&parts[1]);
        assert_eq!(merged, film_of(&singles));
        // Grouped passes sum in double precision first, so they differ,
        // but only by the rounding of those sums.
        for p in [a, b] {
            let d = (p.sum().rgb - one.sum().rgb).abs().max_element();
            assert!(d < 1e-15 * one.sum().rgb.x * 300.0, "{d}");
        }
        assert!((one.sum().weight - 300.0).abs() == 0.0);
        // Saturation instead of wrap-around, and NaN counts as nothing.
        let mut big = FilmPixel::default();
        for _ in 0..4 {
            big.add([1e30, -1e30, f64::NAN, 1.0, 0.0]);
        }
        assert_eq!(big.0[0], i128::MAX);
        assert_eq!(big.0[1], i128::MIN);
        assert_eq!(big.0[2], 0);
        assert_eq!(big.sum().weight, 4.0);
    }
}
