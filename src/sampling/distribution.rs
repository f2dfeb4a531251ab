//! Discrete distributions for picking one of many items in proportion to a
//! weight (triangles by area, lights by power).

/// A discrete distribution over `0..n` proportional to non-negative weights,
/// sampled by binary search in its cumulative sum.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Distribution1D {
    /// Normalised cumulative sum: `cdf[0] = 0`, `cdf[n] = 1`.
    cdf: Vec<f64>,
    total: f64,
}

impl Distribution1D {
    /// A distribution from weights; negative or non-finite weights count as
    /// 0. If all weights are 0, every item is equally likely.
    pub fn new(weights: &[f32]) -> Self {
        let n = weights.len();
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut acc = 0.0f64;
        for &w in weights {
            let w = if w.is_finite() && w > 0.0 { w as f64 } else { 0.0 };
            acc += w;
            cdf.push(acc);
        }
        let total = acc;
        if total > 0.0 {
            for c in &mut cdf {
                *c /= total;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f64 / n.max(1) as f64;
            }
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Distribution1D { cdf, total }
    }

    /// Number of items.
    pub fn len(&self) -> usize {
        self.cdf.len().saturating_sub(1)
    }

    /// Whether there are no items.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sum of the weights.
    pub fn total(&self) -> f64 {
        self.total
    }

    /// Probability of item `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        (self.cdf[i + 1] - self.cdf[i]) as f32
    }

    /// Picks an item with `u` ∈ [0, 1): returns (index, probability, `u`
    /// rescaled to [0, 1) within the item, for reuse).
    #[inline]
    pub fn sample(&self, u: f32) -> (usize, f32, f32) {
        let n = self.len();
        debug_assert!(n > 0);
        if n == 1 {
            // One item (a scene's only light): no search, no division.
            return (0, 1.0, u);
        }
        let u64 = u as f64;
        // The last i with cdf[i] <= u, skipping zero-probability items.
        let i = self.cdf.partition_point(|&c| c <= u64).saturating_sub(1).min(n - 1);
        let lo = self.cdf[i];
        let p = self.cdf[i + 1] - lo;
        let rest = if p > 0.0 {
            ((u64 - lo) / p).clamp(0.0, 1.0 - f64::EPSILON)
        } else {
            0.0
        };
        (i, p as f32, rest as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    #[test]
    fn frequencies_match_weights() {
        let w = [1.0, 0.0, 3.0, 6.0];
        let d = Distribution1D::new(&w);
        assert_eq!(d.len(), 4);
        assert!((d.pmf(2) - 0.3).abs() < 1e-6 && d.pmf(1) == 0.0);
        let mut r = Pcg32::new(1, 0);
        let mut counts = [0f64; 4];
        let n = 100_000;
        for _ in 0..n {
            let (i, p, rest) = d.sample(r.next_f32());
            assert!((p - d.pmf(i)).abs() < 1e-6 && (0.0..1.0).contains(&rest));
            counts[i] += 1.0;
        }
        assert_eq!(counts[1], 0.0);
        let mut chi2 = 0.0;
        for i in [0, 2, 3] {
            let e = n as f64 * w[i] as f64 / 10.0;
            chi2 += (counts[i] - e).powi(2) / e;
        }
        // 2 degrees of freedom; 13.8 is the 0.999 quantile.
        assert!(chi2 < 13.8, "{counts:?}");
    }

    #[test]
    fn all_zero_weights_are_uniform() {
        let d = Distribution1D::new(&[0.0, 0.0]);
        assert_eq!(d.pmf(0), 0.5);
        assert_eq!(d.sample(0.7).0, 1);
    }
}

/// A piecewise-constant density over [0,1)² from a grid of weights
/// (`width` columns × `height` rows), sampled by picking a row from the
/// marginal distribution, then a column within it (Pharr et al., pbrt-v4
/// §A.5.6).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Distribution2D {
    width: usize,
    height: usize,
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// A distribution from row-major weights.
    pub fn new(weights: &[f32], width: usize, height: usize) -> Self {
        assert_eq!(weights.len(), width * height);
        let rows: Vec<Distribution1D> = (0..height)
            .map(|y| Distribution1D::new(&weights[y * width..(y + 1) * width]))
            .collect();
        let row_sums: Vec<f32> = rows.iter().map(|r| r.total() as f32).collect();
        Distribution2D {
            width,
            height,
            rows,
            marginal: Distribution1D::new(&row_sums),
        }
    }

    /// A point in [0,1)² and its density there.
    #[inline]
    pub fn sample(&self, u: glam::Vec2) -> (glam::Vec2, f32) {
        let (y, py, ry) = self.marginal.sample(u.y);
        let (x, px, rx) = self.rows[y].sample(u.x);
        let p = glam::Vec2::new(
            (x as f32 + rx) / self.width as f32,
            (y as f32 + ry) / self.height as f32,
        );
        (p, py * px * (self.width * self.height) as f32)
    }

    /// Density at a point of [0,1)².
    #[inline]
    pub fn pdf(&self, p: glam::Vec2) -> f32 {
        let x = ((p.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((p.y * self.height as f32) as usize).min(self.height - 1);
        self.marginal.pmf(y) * self.rows[y].pmf(x) * (self.width * self.height) as f32
    }
}

#[cfg(test)]
mod tests_2d {
    use super::*;
    use crate::sampling::rng::Pcg32;

    #[test]
    fn samples_follow_the_weights_and_pdf_matches() {
        let w = [1.0, 2.0, 0.0, 5.0, 1.0, 1.0];
        let d = Distribution2D::new(&w, 3, 2);
        let mut r = Pcg32::new(4, 0);
        let mut counts = [0f64; 6];
        let n = 100_000;
        for _ in 0..n {
            let (p, pdf) = d.sample(glam::Vec2::new(r.next_f32(), r.next_f32()));
            assert!((pdf - d.pdf(p)).abs() < 1e-4 * pdf);
            let cell = (p.y * 2.0) as usize * 3 + (p.x * 3.0) as usize;
            counts[cell] += 1.0;
        }
        let total: f32 = w.iter().sum();
        let mut chi2 = 0.0;
        for i in 0..6 {
            if w[i] == 0.0 {
                assert_eq!(counts[i], 0.0);
                continue;
            }
            let e = n as f64 * (w[i] / total) as f64;
            chi2 += (counts[i] - e).powi(2) / e;
            // The density integrates to the cell's share.
            assert!(
                (d.pdf(glam::Vec2::new((i % 3) as f32 / 3.0 + 0.1, (i / 3) as f32 / 2.0 + 0.1)) / 6.0 - w[i] / total)
                    .abs()
                    < 1e-5
            );
        }
        assert!(chi2 < 20.5, "chi2 {chi2}"); // 4 d.o.f., p = 0.0004
    }
}
