//! Pixel reconstruction filters, applied by filter importance sampling
//! (Ernst et al. 2006; pbrt-v4 §8.8): each sample's position in its pixel
//! is drawn from the filter's own distribution and counts with weight 1 in
//! that pixel alone. The expected pixel value is the same as when samples
//! are splatted with filter weights, and because no sample touches another
//! pixel, tiles stay independent and renders deterministic.

use glam::Vec2;

/// A separable reconstruction filter, centred on the pixel centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    /// Uniform weight within `radius` pixels (0.5: exactly the pixel).
    Box {
        /// Half-width in pixels.
        radius: f32,
    },
    /// Weight falling linearly to 0 at `radius`.
    Tent {
        /// Half-width in pixels.
        radius: f32,
    },
    /// A Gaussian of standard deviation `stddev`, cut off at `radius`.
    Gaussian {
        /// Standard deviation in pixels.
        stddev: f32,
        /// Cut-off in pixels.
        radius: f32,
    },
}

impl Default for Filter {
    fn default() -> Self {
        Filter::Box { radius: 0.5 }
    }
}

impl Filter {
    /// The names accepted in scene files.
    pub const NAMES: [&'static str; 3] = ["box", "tent", "gaussian"];

    /// The filter called `name` with its default size (box 0.5, tent 1,
    /// Gaussian σ = 0.5 cut off at 4σ, as Mitsuba's).
    pub fn from_name(name: &str) -> Option<Filter> {
        match name {
            "box" => Some(Filter::Box { radius: 0.5 }),
            "tent" => Some(Filter::Tent { radius: 1.0 }),
            "gaussian" => Some(Filter::Gaussian {
                stddev: 0.5,
                radius: 2.0,
            }),
            _ => None,
        }
    }

    /// Half-width in pixels.
    pub fn radius(&self) -> f32 {
        match *self {
            Filter::Box { radius } | Filter::Tent { radius } | Filter::Gaussian { radius, .. } => radius,
        }
    }

    /// An offset from the pixel centre distributed like the filter, from
    /// `u` ∈ [0,1)² (stratification of `u` carries over).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Vec2 {
        Vec2::new(self.sample_1d(u.x), self.sample_1d(u.y))
    }

    fn sample_1d(&self, u: f32) -> f32 {
        match *self {
            Filter::Box { radius } => (2.0 * u - 1.0) * radius,
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
                // Inverse CDF of the normal distribution truncated to ±radius.
                let s = std::f64::consts::SQRT_2 * stddev as f64;
                let lo = erf(-radius as f64 / s);
                let hi = erf(radius as f64 / s);
                let x = s * erf_inv(lo + u as f64 * (hi - lo));
                (x as f32).clamp(-radius, radius)
            }
        }
    }
}

/// The error function, by the Chebyshev fit of erfc in Numerical Recipes
/// (§6.2; absolute error below 1.2e-7, ample for pixel offsets).
pub fn erf(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 { 1.0 - r } else { r - 1.0 }
}

/// The inverse error function on (−1, 1) (Giles 2012, "Approximating the
/// erfinv function", refined by two Newton steps on [`erf`]).
pub fn erf_inv(y: f64) -> f64 {
    let y = y.clamp(-1.0 + 1e-15, 1.0 - 1e-15);
    let w = -((1.0 - y) * (1.0 + y)).ln();
    let mut x = if w < 5.0 {
        let w = w - 2.5;
        let mut p = 2.810_226_36e-08;
        p = 3.432_739_39e-07 + p * w;
        p = -3.523_387_7e-06 + p * w;
        p = -4.391_506_54e-06 + p * w;
        p = 0.000_218_580_87 + p * w;
        p = -0.001_253_725_03 + p * w;
        p = -0.004_177_681_64 + p * w;
        p = 0.246_640_727 + p * w;
        p = 1.501_409_41 + p * w;
        p * y
    } else {
        let w = w.sqrt() - 3.0;
        let mut p = -0.000_200_214_257;
        p = 0.000_100_950_558 + p * w;
        p = 0.001_349_343_22 + p * w;
        p = -0.003_673_428_44 + p * w;
        p = 0.005_739_507_73 + p * w;
        p = -0.007_622_461_3 + p * w;
        p = 0.009_438_870_47 + p * w;
        p = 1.001_674_06 + p * w;
        p = 2.832_976_82 + p * w;
        p * y
    };
    for _ in 0..2 {
        let err = erf(x) - y;
        x -= err / (2.0 / std::f64::consts::PI.sqrt() * (-x * x).exp());
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    #[test]
    fn erf_and_its_inverse() {
        assert!((erf(0.5) - 0.520_499_877_8).abs() < 2e-7);
        assert!((erf(-1.0) + 0.842_700_792_9).abs() < 2e-7);
        for y in [-0.99, -0.5, 0.0, 0.3, 0.9, 0.999] {
            assert!((erf(erf_inv(y)) - y).abs() < 1e-6, "{y}");
        }
    }

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
