//! Splatting: each sample adds to every pixel whose filter covers it, with
//! the filter's weight there (the classic reconstruction of Mitsuba and
//! pbrt-v3), for filters wider than a pixel.
//!
//! Filter importance sampling (see [`super::filter`]) reaches the same
//! expected image with each sample in one pixel; splatting averages about
//! `(2r)²·(filter's efficiency)` samples into each pixel instead, which
//! lowers the per-pixel error at equal samples (three times, measured on the
//! Cornell box with Mitsuba's Gaussian, σ = 0.5, r = 2) at the price of
//! noise correlated between neighbours. Tiles splat into a buffer with a
//! margin of the filter's radius, merged into the film in tile order, so
//! renders stay deterministic on any number of threads.

use super::PixelSum;
use super::filter::Filter;
use glam::{DVec3, Vec4};

/// Samples of the filter's profile on [0, radius].
const TABLE: usize = 64;

/// Most pixels one sample touches along an axis.
pub const MAX_TAPS: usize = 16;

/// A separable filter's weights, tabulated for splatting.
#[derive(Clone, Debug)]
pub struct Splat {
    radius: f32,
    /// Table steps per pixel: (TABLE − 1) / radius.
    scale: f32,
    /// Pixels a tile's buffer extends beyond the tile on each side.
    pub margin: u32,
    /// The 1D profile at |x| = i·radius/(TABLE − 1), divided by its integral.
    table: [f32; TABLE],
}

impl Splat {
    /// Splatting for `filter`, or `None` for the one-pixel box, for which
    /// filter importance sampling is the same estimator.
    pub fn new(filter: &Filter) -> Option<Splat> {
        let radius = filter.radius();
        if matches!(filter, Filter::Box { .. }) && radius <= 0.5 || !(radius > 0.0 && radius <= 8.0) {
            return None;
        }
        // Normalise the profile so that a sample's weights sum to about 1:
        // a pixel's total weight is then about its number of samples.
        let steps = 4096;
        let integral: f64 = (0..steps)
            .map(|i| {
                let x = -radius + (2.0 * radius) * (i as f32 + 0.5) / steps as f32;
                filter.eval_1d(x) as f64
            })
            .sum::<f64>()
            * (2.0 * radius as f64 / steps as f64);
        let table =
            std::array::from_fn(|i| (filter.eval_1d(radius * i as f32 / (TABLE - 1) as f32) as f64 / integral) as f32);
        Some(Splat {
            radius,
            scale: (TABLE - 1) as f32 / radius,
            margin: (radius - 0.5).ceil().max(0.0) as u32,
            table,
        })
    }

    /// The weight of a sample at distance `x` (pixels, |x| ≤ radius) from
    /// a pixel centre. The index is clamped rather than tested, so that a
    /// row of taps is computed without a branch.
    #[inline(always)]
    fn weight(&self, x: f32) -> f32 {
        let t = (x.abs() * self.scale).min((TABLE - 1) as f32);
        let i = (t as u32).min(TABLE as u32 - 2) as usize;
        let f = t - i as f32;
        self.table[i] + (self.table[i + 1] - self.table[i]) * f
    }

    /// The pixels in `[lo, hi)` whose centres lie within the radius of
    /// position `p` along one axis, which are consecutive: writes their
    /// weights to `weights` and returns the first pixel and how many.
    #[inline]
    pub fn taps(&self, p: f32, lo: u32, hi: u32, weights: &mut [f32; MAX_TAPS]) -> (u32, usize) {
        let first = ceil_in_film(p - self.radius - 0.5).max(lo as f32);
        let last = floor_in_film(p + self.radius - 0.5).min(hi as f32 - 1.0);
        let n = ((last - first + 1.0).max(0.0) as usize).min(MAX_TAPS);
        let x0 = first + 0.5 - p;
        for (k, w) in weights[..n].iter_mut().enumerate() {
            *w = self.weight(x0 + k as f32);
        }
        (first as u32, n)
    }
}

/// `x.ceil()` for |x| < 2³¹ (film coordinates are far smaller) by a
/// conversion to integer: x86-64 without SSE4.1 has no rounding
/// instruction, and `f32::ceil` is a call into libm, which cost about 45
/// instructions per sample (two calls) on the Cornell box. Signed zeros
/// may differ, which no caller sees.
#[inline(always)]
fn ceil_in_film(x: f32) -> f32 {
    // On integers, so that the comparison is a flag and not a branch: which
    // way it goes is as good as random from sample to sample.
    let i = x as i32;
    (i + ((i as f32) < x) as i32) as f32
}

/// `x.floor()` for |x| < 2³¹; see [`ceil_in_film`].
#[inline(always)]
fn floor_in_film(x: f32) -> f32 {
    let i = x as i32;
    (i - ((i as f32) > x) as i32) as f32
}

/// What one pass splats into one pixel. Single precision suffices: a pass
/// adds at most 16 samples per pixel (and their neighbours' tails) before
/// the sum joins the film's double-precision one; and with colour and
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

impl PixelSum {
    /// Adds what a pass splatted into this pixel.
    #[inline]
    pub fn merge_splat(&mut self, s: &SplatSum) {
        let v = s.rgb_weight.as_dvec4();
        self.rgb += DVec3::new(v.x, v.y, v.z);
        self.weight += v.w;
        self.lum_sq += s.lum_sq as f64;
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
        let mut merged = PixelSum::default();
        merged.merge_splat(&splat);
        assert!((merged.rgb - exact.rgb).abs().max_element() < 1e-6 * exact.rgb.max_element());
        assert!((merged.weight - exact.weight).abs() < 1e-7);
        assert!((merged.lum_sq - exact.lum_sq).abs() < 1e-6 * exact.lum_sq);
    }

    #[test]
    fn film_rounding_matches_floor_and_ceil() {
        let mut rng = crate::sampling::rng::Pcg32::new(3, 9);
        let mut xs = vec![
            0.0f32, -0.0, 0.5, -0.5, 1.0, -1.0, 2.5, -2.5, 8388607.5, 8388608.0, -8388609.0, 1e9, -1e9,
        ];
        xs.extend((0..10_000).map(|_| (rng.next_f32() - 0.5) * 4096.0));
        // Integers and their nearest neighbours.
        for _ in 0..1000 {
            let x = ((rng.next_f32() - 0.5) * 8.0).round();
            xs.extend([x, x + 1e-6, x - 1e-6]);
        }
        for x in xs {
            // Equal as numbers: the sign of a zero may differ.
            assert_eq!(ceil_in_film(x), x.ceil(), "ceil {x}");
            assert_eq!(floor_in_film(x), x.floor(), "floor {x}");
        }
    }

    #[test]
    fn weights_sum_to_one_and_follow_the_filter() {
        let g = Filter::Gaussian {
            stddev: 0.5,
            radius: 2.0,
        };
        let s = Splat::new(&g).unwrap();
        assert_eq!(s.margin, 2);
        let mut weights = [0.0; MAX_TAPS];
        for p in [10.0f32, 10.25, 10.5, 10.9] {
            let (first, n) = s.taps(p, 0, 100, &mut weights);
            assert!((4..=5).contains(&n), "{p}: {n}");
            let sum: f32 = weights[..n].iter().sum();
            assert!((sum - 1.0).abs() < 0.02, "{p}: {sum}");
            for (k, &w) in weights[..n].iter().enumerate() {
                let x = (first + k as u32) as f32 + 0.5 - p;
                assert!(x.abs() <= 2.0);
                let expect = g.eval_1d(x) / g.eval_1d(0.0) * s.table[0];
                assert!((w - expect).abs() < 2e-3 * s.table[0], "{p} {x}: {w} vs {expect}");
            }
        }
        // At the image's edge only pixels inside are touched.
        assert_eq!(s.taps(0.3, 0, 100, &mut weights), (0, 2));
        assert_eq!(s.taps(99.9, 0, 100, &mut weights), (98, 2));
        // The one-pixel box is left to filter importance sampling.
        assert!(Splat::new(&Filter::Box { radius: 0.5 }).is_none());
        let tent = Splat::new(&Filter::Tent { radius: 1.0 }).unwrap();
        assert_eq!(tent.margin, 1);
        let (first, n) = tent.taps(5.5, 0, 10, &mut weights);
        // The unit tent's taps at a pixel centre: that pixel (weight 1) and
        // its neighbours at the tent's edge (weight 0).
        assert_eq!((first, n), (4, 3));
        assert_eq!(weights[..3], [0.0, 1.0, 0.0]);
    }
}
