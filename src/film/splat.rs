//! Splatting: each sample adds to every pixel whose filter covers it, with
//! the filter's weight there (the classic reconstruction of Mitsuba and
//! pbrt-v3), for filters wider than a pixel.
//!
//! Filter importance sampling (see [`super::filter`]) reaches the same
//! expected image with each sample in one pixel; splatting averages about
//! `(2r)²·(filter's efficiency)` samples into each pixel instead, which
//! lowers the per-pixel error at equal samples (measured on the Cornell box
//! in commit 95701ba) at the price of noise correlated between neighbours.
//! Tiles splat into a buffer with a margin of the filter's radius, which
//! the film adds exactly (see [`super::ExactSums`]), so renders stay
//! deterministic on any number of threads.

use super::PixelSum;
use crate::settings::{Filter, PixelFilter};
use glam::{DVec3, Vec4};

/// Sub-pixel phases tabulated: a sample's weights along an axis depend
/// only on where it falls between two pixel centres.
const PHASES: usize = 64;

/// Most pixels one sample touches along an axis.
pub const MAX_TAPS: usize = 16;

/// A separable filter's weights, tabulated for splatting.
#[derive(Clone, Debug)]
pub struct Splat {
    /// Along x and along y.
    axes: [SplatAxis; 2],
    /// Pixels a tile's buffer extends beyond the tile on each side.
    pub margin: u32,
}

/// One axis's profile, tabulated.
#[derive(Clone, Debug)]
struct SplatAxis {
    radius: f32,
    /// Row `j` holds the weights of the pixel centres at x = −radius +
    /// j/PHASES + k (k = 0, 1, …) from a sample, the filter's profile
    /// divided by its integral (zero beyond the radius). A sample's
    /// weights are interpolated between two rows: a few vector
    /// multiply-adds instead of a profile lookup per tap.
    rows: Box<[[f32; MAX_TAPS]; PHASES + 1]>,
}

impl Splat {
    /// Splatting for `filter`, or `None` for the one-pixel box, for which
    /// filter importance sampling is the same estimator.
    pub fn new(filter: &PixelFilter) -> Option<Splat> {
        let margin = filter.splat_margin()?;
        Some(Splat {
            axes: [SplatAxis::new(&filter.x), SplatAxis::new(&filter.y)],
            margin,
        })
    }

    /// [`Splat::new`] with `filter` along both axes.
    pub fn same(filter: &Filter) -> Option<Splat> {
        Splat::new(&PixelFilter::same(*filter))
    }

    /// [`SplatAxis::taps`] along x.
    #[inline(always)]
    pub fn taps_x<'w>(&self, p: f32, lo: u32, hi: u32, weights: &'w mut [f32; MAX_TAPS]) -> (u32, &'w [f32]) {
        self.axes[0].taps(p, lo, hi, weights)
    }

    /// [`SplatAxis::taps`] along y.
    #[inline(always)]
    pub fn taps_y<'w>(&self, p: f32, lo: u32, hi: u32, weights: &'w mut [f32; MAX_TAPS]) -> (u32, &'w [f32]) {
        self.axes[1].taps(p, lo, hi, weights)
    }
}

impl SplatAxis {
    fn new(filter: &Filter) -> SplatAxis {
        let radius = filter.radius();
        // Normalise the profile so that a sample's weights sum to about 1:
        // a pixel's total weight is then about its number of samples.
        let integral = profile_integral(filter);
        let mut rows = Box::new([[0.0; MAX_TAPS]; PHASES + 1]);
        for (j, row) in rows.iter_mut().enumerate() {
            for (k, w) in row.iter_mut().enumerate() {
                let x = -radius + j as f32 / PHASES as f32 + k as f32;
                *w = (filter.eval_1d(x) as f64 / integral) as f32;
            }
        }
        SplatAxis { radius, rows }
    }

    /// The pixels in `[lo, hi)` whose centres lie within the radius of
    /// position `p` along the axis, which are consecutive: writes their
    /// weights to `weights` and returns the first pixel and the weights.
    /// Always inlined: a plain `inline` was not taken, which left two calls
    /// a sample in the tile loop (commit fa0cc16).
    #[inline(always)]
    fn taps<'w>(&self, p: f32, lo: u32, hi: u32, weights: &'w mut [f32; MAX_TAPS]) -> (u32, &'w [f32]) {
        // The first and last centres within the radius, before clipping.
        let first = ceil_in_film(p - self.radius - 0.5);
        let last = floor_in_film(p + self.radius - 0.5);
        // The first centre lies at x = −radius + s from p, s in [0, 1).
        let phase = ((first as f32 + 0.5 - p + self.radius) * PHASES as f32).clamp(0.0, PHASES as f32);
        let j = floor_in_film(phase).clamp(0, PHASES as i32 - 1) as usize;
        let f = phase - j as f32;
        let (a, b) = (&self.rows[j], &self.rows[j + 1]);
        for k in 0..MAX_TAPS {
            weights[k] = a[k] + (b[k] - a[k]) * f;
        }
        let start = (lo as i32 - first).max(0);
        let end = ((last.min(hi as i32 - 1) - first + 1).max(start)).min(MAX_TAPS as i32);
        let start = start.min(end);
        (
            (first + start).max(lo as i32) as u32,
            &weights[start as usize..end as usize],
        )
    }
}

/// ∫ of the filter's 1D profile over [−radius, radius] (midpoint rule).
fn profile_integral(filter: &Filter) -> f64 {
    let radius = filter.radius();
    let steps = 4096;
    (0..steps)
        .map(|i| {
            let x = -radius + (2.0 * radius) * (i as f32 + 0.5) / steps as f32;
            filter.eval_1d(x) as f64
        })
        .sum::<f64>()
        * (2.0 * radius as f64 / steps as f64)
}

/// `x` rounded to the nearest integer (ties to even) for |x| < 2²², by
/// adding 1.5·2²³, which leaves the integer in the low bits of the sum.
/// Baseline x86-64 has no rounding instruction (SSE4.1): `f32::ceil` and
/// `floor` are calls into libm, and `as i32` checks every conversion for
/// NaN and overflow. Film coordinates are far inside the range (images are
/// at most 65 536 pixels a side).
#[inline(always)]
fn round_in_film(x: f32) -> i32 {
    const MAGIC: f32 = 12_582_912.0;
    ((x + MAGIC).to_bits() as i32).wrapping_sub(MAGIC.to_bits() as i32)
}

/// `x.ceil()` as an integer for |x| < 2²² (see [`round_in_film`]). The
/// correction is a flag, not a branch: which way it goes is as good as
/// random from sample to sample.
#[inline(always)]
fn ceil_in_film(x: f32) -> i32 {
    let r = round_in_film(x);
    r + ((r as f32) < x) as i32
}

/// `x.floor()` as an integer for |x| < 2²²; see [`ceil_in_film`].
#[inline(always)]
fn floor_in_film(x: f32) -> i32 {
    let r = round_in_film(x);
    r - ((r as f32) > x) as i32
}

/// What one pass splats into one pixel. Single precision suffices: a pass
/// adds at most 16 samples per pixel (and their neighbours' tails) before
/// the sum joins the film's fixed-point one; and with colour and
/// weight in one vector, a splat's inner loop is one multiply-add per pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SplatSum {
    /// (Σ w·r, Σ w·g, Σ w·b, Σ w).
    rgb_weight: Vec4,
    /// Σ w·Y² (luminance squared).
    lum_sq: f32,
}

impl SplatSum {
    /// Adds a sample with weight `w`; `rgb_one` is its colour with a fourth
    /// component of 1, `lum_sq` its luminance squared.
    #[inline(always)]
    pub fn add(&mut self, rgb_one: Vec4, lum_sq: f32, w: f32) {
        self.rgb_weight += rgb_one * w;
        self.lum_sq += lum_sq * w;
    }
}

impl SplatSum {
    /// What a pass splatted into this pixel, as a pixel's sums.
    #[inline]
    pub fn sum(&self) -> PixelSum {
        let v = self.rgb_weight.as_dvec4();
        PixelSum {
            rgb: DVec3::new(v.x, v.y, v.z),
            weight: v.w,
            lum_sq: self.lum_sq as f64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splat_sums_agree_with_pixel_sums() {
        let mut exact = PixelSum::default();
        let mut splat = SplatSum::default();
        for (k, w) in [0.25f32, 0.5, 0.0625, 1.0].into_iter().enumerate() {
            let l = crate::color::Rgb::new(0.5, 2.0, 0.125) * (k as f32 + 1.0);
            let y = crate::color::luminance(l);
            exact.add_with_luminance(l, y, w);
            splat.add(l.extend(1.0), y * y, w);
        }
        let merged = splat.sum();
        assert!((merged.rgb - exact.rgb).abs().max_element() < 1e-6 * exact.rgb.max_element());
        assert!((merged.weight - exact.weight).abs() < 1e-7);
        assert!((merged.lum_sq - exact.lum_sq).abs() < 1e-6 * exact.lum_sq);
    }

    #[test]
    fn film_rounding_matches_floor_and_ceil() {
        let mut rng = crate::sampling::rng::Pcg32::new(3, 9);
        // The ends of the range, halves (ties), and random values.
        let mut xs = vec![
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            1.5,
            -1.5,
            2.5,
            -2.5,
            4_194_303.5,
            -4_194_303.5,
            4_194_303.0,
            -4_194_304.0,
            65_544.25,
        ];
        xs.extend((0..10_000).map(|_| (rng.next_f32() - 0.5) * 4096.0));
        xs.extend((0..10_000).map(|_| (rng.next_f32() - 0.5) * 8_388_000.0));
        // Integers and their nearest neighbours.
        for _ in 0..1000 {
            let x = ((rng.next_f32() - 0.5) * 8.0).round();
            xs.extend([x, x + 1e-6, x - 1e-6]);
        }
        for x in xs {
            assert_eq!(ceil_in_film(x) as f32, x.ceil(), "ceil {x}");
            assert_eq!(floor_in_film(x) as f32, x.floor(), "floor {x}");
            assert_eq!(round_in_film(x) as f32, x.round_ties_even(), "round {x}");
        }
    }

    #[test]
    fn weights_sum_to_one_and_follow_the_filter() {
        let g = Filter::Gaussian {
            stddev: 0.5,
            radius: 2.0,
        };
        let s = Splat::same(&g).unwrap();
        assert_eq!(s.margin, 2);
        let integral = profile_integral(&g) as f32;
        let mut weights = [0.0; MAX_TAPS];
        let mut rng = crate::sampling::rng::Pcg32::new(1, 2);
        let positions = [10.0f32, 10.25, 10.5, 10.9, 10.5 + 1e-6, 11.0 - 1e-6];
        for p in positions
            .into_iter()
            .chain((0..2000).map(|_| 10.0 + 5.0 * rng.next_f32()))
        {
            let (first, w) = s.taps_x(p, 0, 100, &mut weights);
            assert!((4..=5).contains(&w.len()), "{p}: {}", w.len());
            let sum: f32 = w.iter().sum();
            assert!((sum - 1.0).abs() < 0.02, "{p}: {sum}");
            for (k, &w) in w.iter().enumerate() {
                let x = (first + k as u32) as f32 + 0.5 - p;
                assert!(x.abs() <= 2.0);
                // Linear interpolation over 1/64 of a pixel: the error is
                // at most h²/8 · max|g''| ≈ 1.3e-4 of the peak.
                let expect = g.eval_1d(x) / integral;
                assert!((w - expect).abs() < 3e-4 / integral, "{p} {x}: {w} vs {expect}");
            }
        }
        // At the image's edge only pixels inside are touched.
        let (first, w) = s.taps_x(0.3, 0, 100, &mut weights);
        assert_eq!((first, w.len()), (0, 2));
        let (first, w) = s.taps_x(99.9, 0, 100, &mut weights);
        assert_eq!((first, w.len()), (98, 2));
        // A one-pixel image, and a position outside every pixel's reach.
        assert_eq!(s.taps_x(0.5, 0, 1, &mut weights).1.len(), 1);
        assert!(s.taps_x(150.0, 0, 100, &mut weights).1.is_empty());
        // The one-pixel box is left to filter importance sampling.
        assert!(Splat::same(&Filter::Box { radius: 0.5 }).is_none());
        let tent = Splat::same(&Filter::Tent { radius: 1.0 }).unwrap();
        assert_eq!(tent.margin, 1);
        let (first, w) = tent.taps_x(5.5, 0, 10, &mut weights);
        // The unit tent's taps at a pixel centre: that pixel (weight 1) and
        // its neighbours at the tent's edge (weight 0).
        assert_eq!((first, w), (4, &[0.0, 1.0, 0.0][..]));
        // The widest filter: sixteen taps.
        let wide = Splat::same(&Filter::Box { radius: 8.0 }).unwrap();
        let (_, w) = wide.taps_x(50.3, 0, 100, &mut weights);
        assert_eq!(w.len(), 16);
        assert!(w.iter().all(|&w| (w - 1.0 / 16.0).abs() < 1e-6), "{w:?}");
    }
}
