//! Pixel reconstruction filters, applied by filter importance sampling
//! (Ernst et al. 2006; pbrt-v4 §8.8): each sample's position in its pixel
//! is drawn from the filter's own distribution and counts with weight 1 in
//! that pixel alone. The expected pixel value is the same as when samples
//! are splatted with filter weights, and because no sample touches another
//! pixel, tiles stay independent and renders deterministic.

use crate::sampling::erf::{erf, erf_inv};
use crate::settings::{Filter, PixelFilter};
use glam::Vec2;

impl Filter {
    /// The filter's (unnormalised) 1D profile at offset `x` in pixels;
    /// [`Filter::sample`] draws offsets with this density.
    pub fn eval_1d(&self, x: f32) -> f32 {
        let r = self.radius();
        if x.abs() > r {
            return 0.0;
        }
        match *self {
            Filter::Box { .. } => 1.0,
            Filter::Tent { radius } => 1.0 - x.abs() / radius,
            // Less its value at the radius, as pbrt-v4's and Mitsuba 3's
            // Gaussians: it falls to 0 there instead of stopping short.
            Filter::Gaussian { stddev, radius } => (gaussian(x, stddev) - gaussian(radius, stddev)).max(0.0),
            Filter::Mitchell { radius, b, c } => mitchell_1d(2.0 * x / radius, b, c),
            Filter::Lanczos { tau, .. } => sinc(x) * sinc(x / tau),
        }
    }

    /// An offset from the pixel centre distributed like the filter, from
    /// `u` ∈ [0,1)² (stratification of `u` carries over).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Vec2 {
        PixelFilter::same(*self).sample(u)
    }

    /// [`PixelFilter::sample_weight`] of this filter along both axes.
    #[inline]
    pub fn sample_weight(&self, offset: Vec2) -> f32 {
        PixelFilter::same(*self).sample_weight(offset)
    }

    /// The weight along one axis of an offset `x` drawn by
    /// [`Filter::sample_1d`], as a fraction: the filter's profile over the
    /// density the offset was drawn from, and its mean. That is 1 but for
    /// the Gaussian, which is drawn from the whole Gaussian cut off at the
    /// radius and weighs its samples by 1 − g(r)/g(x) so that their
    /// expected pixel is the one the profile, which subtracts g(r), gives
    /// (pbrt-v4 weighs samples by f/p as well, for its tabulated filters).
    #[inline]
    fn sample_weight_1d(&self, x: f32) -> (f32, f32) {
        match *self {
            Filter::Gaussian { stddev, radius } => {
                let s = std::f32::consts::SQRT_2 * stddev;
                // ∫g over [−r, r] and what subtracting g(r) leaves of it.
                let whole = s * std::f32::consts::PI.sqrt() * erf(radius / s);
                let edge = gaussian(radius, stddev);
                let mean = 1.0 - 2.0 * radius * edge / whole;
                if mean > 0.0 {
                    ((1.0 - edge / gaussian(x, stddev)).max(0.0), mean)
                } else {
                    (1.0, 1.0)
                }
            }
            _ => (1.0, 1.0),
        }
    }

    /// The box's inverse CDF is one line and inlined into the render loop;
    /// the others' are not.
    #[inline]
    fn sample_1d(&self, u: f32) -> f32 {
        match *self {
            Filter::Box { radius } => (2.0 * u - 1.0) * radius,
            _ => self.sample_1d_shaped(u),
        }
    }

    #[inline(never)]
    fn sample_1d_shaped(&self, u: f32) -> f32 {
        match *self {
            Filter::Box { .. } => self.sample_1d(u),
            Filter::Tent { radius } => {
                // Inverse CDF of the triangle on [−1, 1].
                let x = if u < 0.5 {
                    (2.0 * u).sqrt() - 1.0
                } else {
                    1.0 - (2.0 - 2.0 * u).max(0.0).sqrt()
                };
                x * radius
            }
            // Splatted (`Filter::splat_margin`): scenes keep them within
            // the splat's reach, and importance sampling could not give
            // their negative lobes their sign.
            Filter::Mitchell { .. } | Filter::Lanczos { .. } => {
                unreachable!("filters with negative lobes are splatted")
            }
            Filter::Gaussian { stddev, radius } => {
                // Inverse CDF of the normal distribution truncated to ±radius,
                // in f32: pixel offsets need no more, and this runs once per
                // camera sample (in f64 with Newton steps it stood out in the
                // path tracer's profile; commit 412cbcc).
                let s = std::f32::consts::SQRT_2 * stddev;
                let x = s * erf_inv((2.0 * u - 1.0) * erf(radius / s));
                x.clamp(-radius, radius)
            }
        }
    }
}

impl PixelFilter {
    /// An offset from the pixel centre distributed like the filter, from
    /// `u` ∈ [0,1)² (stratification of `u` carries over).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Vec2 {
        Vec2::new(self.x.sample_1d(u.x), self.y.sample_1d(u.y))
    }

    /// The weight of a sample at `offset` drawn by [`PixelFilter::sample`]
    /// (the product of the axes' weights, see `Filter::sample_weight_1d`):
    /// 1 but for Gaussians.
    #[inline]
    pub fn sample_weight(&self, offset: Vec2) -> f32 {
        if matches!(self.x, Filter::Gaussian { .. }) || matches!(self.y, Filter::Gaussian { .. }) {
            self.weight_of_gaussians(offset)
        } else {
            1.0
        }
    }

    /// [`PixelFilter::sample_weight`] where an axis is Gaussian, out of
    /// line (the render loop inlines the rest).
    #[inline(never)]
    fn weight_of_gaussians(&self, offset: Vec2) -> f32 {
        let ((wx, mx), (wy, my)) = (self.x.sample_weight_1d(offset.x), self.y.sample_weight_1d(offset.y));
        wx * wy / (mx * my)
    }
}

/// exp(−x²/2σ²): the Gaussian of standard deviation `stddev`, 1 at 0.
#[inline]
fn gaussian(x: f32, stddev: f32) -> f32 {
    (-x * x / (2.0 * stddev * stddev)).exp()
}

/// Mitchell and Netravali's cubic ("Reconstruction Filters in Computer
/// Graphics", 1988, eq. 8) at `x`, supported on [−2, 2].
fn mitchell_1d(x: f32, b: f32, c: f32) -> f32 {
    let x = x.abs();
    let (x2, x3) = (x * x, x * x * x);
    if x <= 1.0 {
        ((12.0 - 9.0 * b - 6.0 * c) * x3 + (-18.0 + 12.0 * b + 6.0 * c) * x2 + (6.0 - 2.0 * b)) / 6.0
    } else if x <= 2.0 {
        ((-b - 6.0 * c) * x3 + (6.0 * b + 30.0 * c) * x2 + (-12.0 * b - 48.0 * c) * x + (8.0 * b + 24.0 * c)) / 6.0
    } else {
        0.0
    }
}

/// sin(πx)/(πx), 1 at 0.
fn sinc(x: f32) -> f32 {
    let px = std::f32::consts::PI * x;
    if px.abs() < 1e-5 { 1.0 } else { px.sin() / px }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// Offsets stay within the radius, and their histogram follows the
    /// filter's shape (chi-square over 20 bins per axis).
    /// A filter and its unnormalised profile.
    type Profile = (Filter, fn(f32) -> f32);

    /// Mitchell and Netravali's cubics and Lanczos' sinc against their
    /// defining properties: the cubic is (6 − 2B)/6 at 0, continuous, and
    /// its integer translates sum to 1 for every B and C (their paper's
    /// design condition, which keeps a constant image constant); the sinc
    /// is 1 at 0 and 0 at the other integers, and negative in its second
    /// lobe. Stretched to a radius, the cubic's profile scales with it.
    #[test]
    fn mitchell_and_lanczos_profiles_keep_their_defining_properties() {
        for (b, c) in [(1.0 / 3.0, 1.0 / 3.0), (0.0, 0.5), (1.0, 0.0), (0.2, 0.7)] {
            assert!((mitchell_1d(0.0, b, c) - (6.0 - 2.0 * b) / 6.0).abs() < 1e-6);
            for k in 0..=100 {
                let x = k as f32 / 100.0;
                let sum: f32 = (-3..=3).map(|n| mitchell_1d(x + n as f32, b, c)).sum();
                assert!((sum - 1.0).abs() < 1e-5, "B {b} C {c}: translates sum to {sum} at {x}");
            }
            for edge in [1.0f32, 2.0] {
                let (below, above) = (mitchell_1d(edge - 1e-4, b, c), mitchell_1d(edge + 1e-4, b, c));
                assert!((below - above).abs() < 1e-3, "B {b} C {c}: jumps at {edge}");
            }
            let stretched = Filter::Mitchell { radius: 3.0, b, c };
            assert_eq!(stretched.eval_1d(1.5), mitchell_1d(1.0, b, c));
            assert_eq!(stretched.eval_1d(3.1), 0.0);
        }
        // Catmull–Rom interpolates: 1 at 0, 0 at ±1 and ±2.
        let catmull_rom = Filter::from_name("catmullrom").unwrap();
        assert!((catmull_rom.eval_1d(0.0) - 1.0).abs() < 1e-6);
        assert!(catmull_rom.eval_1d(1.0).abs() < 1e-6 && catmull_rom.eval_1d(1.5) < 0.0);
        let lanczos = Filter::from_name("lanczos").unwrap();
        assert_eq!(lanczos.eval_1d(0.0), 1.0);
        for k in 1..=3 {
            assert!(lanczos.eval_1d(k as f32).abs() < 1e-6, "{k}");
        }
        assert!(lanczos.eval_1d(1.5) < -0.1 && lanczos.eval_1d(2.5) > 0.0);
        assert_eq!(lanczos.eval_1d(3.01), 0.0);
    }

    #[test]
    fn offsets_follow_the_filter() {
        let shapes: [Profile; 3] = [
            (Filter::Box { radius: 0.5 }, |_| 1.0),
            (Filter::Tent { radius: 1.0 }, |x| 1.0 - x.abs()),
            (
                Filter::Gaussian {
                    stddev: 0.5,
                    radius: 2.0,
                },
                |x| (-x * x / (2.0 * 0.25)).exp(),
            ),
        ];
        for (f, shape) in shapes {
            let r = f.radius();
            let bins = 20;
            let mut counts = vec![0f64; bins];
            let mut rng = Pcg32::new(5, 0);
            let n = 200_000;
            for _ in 0..n {
                let o = f.sample(Vec2::new(rng.next_f32(), rng.next_f32()));
                assert!(o.x.abs() <= r && o.y.abs() <= r);
                counts[(((o.x + r) / (2.0 * r) * bins as f32) as usize).min(bins - 1)] += 1.0;
            }
            // Expected: the filter integrated over each bin (fine midpoint rule).
            let mut expected: Vec<f64> = (0..bins)
                .map(|b| {
                    (0..100)
                        .map(|k| {
                            let x = -r + 2.0 * r * (b as f32 + (k as f32 + 0.5) / 100.0) / bins as f32;
                            shape(x) as f64
                        })
                        .sum()
                })
                .collect();
            let total: f64 = expected.iter().sum();
            for e in &mut expected {
                *e *= n as f64 / total;
            }
            let chi2: f64 = counts
                .iter()
                .zip(&expected)
                .filter(|(_, e)| **e >= 5.0)
                .map(|(c, e)| (c - e).powi(2) / e)
                .sum();
            assert!(chi2 < 45.0, "{f:?}: χ² = {chi2}"); // ≤ 19 dof, p ≈ 0.001
        }
    }

    /// The Gaussian's profile falls to 0 at its radius (pbrt-v4's default,
    /// σ = 0.5 cut at 1.5, and Mitsuba's, cut at 4σ); samples drawn from
    /// the whole Gaussian and weighted by [`Filter::sample_weight`] have a
    /// mean weight of 1 and a weighted histogram that follows the profile,
    /// per bin within 5 standard errors of the weighted sum (Σw² its
    /// variance); every other filter weighs 1.
    #[test]
    fn weighted_gaussian_samples_follow_the_profile() {
        for (stddev, radius) in [(0.5f32, 1.5f32), (0.5, 2.0), (0.3, 0.6)] {
            let f = Filter::Gaussian { stddev, radius };
            assert_eq!(f.eval_1d(radius), 0.0);
            let edge = (-radius * radius / (2.0 * stddev * stddev)).exp();
            assert!((f.eval_1d(0.0) - (1.0 - edge)).abs() < 1e-6);
            let bins = 12;
            let (mut sums, mut squares) = (vec![0f64; bins], vec![0f64; bins]);
            let (mut total, mut total_sq) = (0f64, 0f64);
            let mut rng = Pcg32::new(11, 2);
            let n = 400_000;
            for _ in 0..n {
                let o = f.sample(Vec2::new(rng.next_f32(), rng.next_f32()));
                let w = f.sample_weight(o) as f64;
                let b = (((o.x + radius) / (2.0 * radius) * bins as f32) as usize).min(bins - 1);
                sums[b] += w;
                squares[b] += w * w;
                total += w;
                total_sq += w * w;
            }
            let mean = total / n as f64;
            let mean_error = ((total_sq / n as f64 - mean * mean) / n as f64).sqrt();
            assert!(
                (mean - 1.0).abs() < 5.0 * mean_error,
                "σ {stddev} r {radius}: mean weight {mean}"
            );
            let profile: Vec<f64> = (0..bins)
                .map(|b| {
                    (0..200)
                        .map(|k| {
                            let x = -radius + 2.0 * radius * (b as f32 + (k as f32 + 0.5) / 200.0) / bins as f32;
                            f.eval_1d(x) as f64
                        })
                        .sum()
                })
                .collect();
            let all: f64 = profile.iter().sum();
            for b in 0..bins {
                let expected = n as f64 * profile[b] / all;
                if expected < 50.0 {
                    continue;
                }
                let error = squares[b].sqrt();
                assert!(
                    (sums[b] - expected).abs() < 5.0 * error,
                    "σ {stddev} r {radius} bin {b}: {} vs {expected} ± {error}",
                    sums[b]
                );
            }
        }
        for f in [Filter::Box { radius: 0.5 }, Filter::Tent { radius: 1.0 }] {
            assert_eq!(f.sample_weight(Vec2::new(0.3, -0.2)), 1.0);
        }
    }
}
