//! Pixel reconstruction filters, applied by filter importance sampling
//! (Ernst et al. 2006; pbrt-v4 §8.8): each sample's position in its pixel
//! is drawn from the filter's own distribution and counts with weight 1 in
//! that pixel alone. The expected pixel value is the same as when samples
//! are splatted with filter weights, and because no sample touches another
//! pixel, tiles stay independent and renders deterministic.

use crate::sampling::erf::{erf, erf_inv};
use crate::settings::Filter;
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
            Filter::Gaussian { stddev, .. } => (-x * x / (2.0 * stddev * stddev)).exp(),
        }
    }

    /// An offset from the pixel centre distributed like the filter, from
    /// `u` ∈ [0,1)² (stratification of `u` carries over).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Vec2 {
        Vec2::new(self.sample_1d(u.x), self.sample_1d(u.y))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// Offsets stay within the radius, and their histogram follows the
    /// filter's shape (chi-square over 20 bins per axis).
    /// A filter and its unnormalised profile.
    type Profile = (Filter, fn(f32) -> f32);

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
}
