//! Discrete distributions for picking one of many items in proportion to a
//! weight (triangles by area, lights by power).

/// A discrete distribution over `0..n` proportional to non-negative weights,
/// sampled by binary search in its cumulative sum.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Distribution1D {
    /// Normalised cumulative sum: `cdf[0] = 0`, `cdf[n] = 1`.
    cdf: Vec<f64>,
    total: f64,
    /// A guide table (the cutpoint method of Chen and Asau, 1974): with
    /// m = n buckets of u, `guide[j]` counts the cdf values below
    /// (j − ½)/m, so the search for a u of bucket k is confined to
    /// `cdf[guide[k]..guide[k + 2]]`, a few entries, and finds what a
    /// search of the whole table finds: a few loads instead of log₂ n
    /// dependent ones (the rows of an environment map, a mesh's triangles).
    guide: Vec<u32>,
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
        let guide = guide_table(&cdf, n);
        Distribution1D { cdf, total, guide }
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
        // The last i with cdf[i] <= u, skipping zero-probability items: the
        // count of cdf values <= u, less one. Bucket k = ⌊u·m⌋ holds u in
        // [k/m, (k + 1)/m) (u·m is exact: a 24-bit u times a 32-bit m), so
        // every value below (k − ½)/m counts and none from (k + 3/2)/m
        // (half-bucket margins outweigh any rounding of the bounds); a u
        // outside [0, 1) or NaN lands in the first or last bucket, whose
        // bounds take it too.
        let m = self.guide.len() - 2;
        let k = ((u64 * m as f64) as usize).min(m - 1);
        let (lo, hi) = (self.guide[k] as usize, self.guide[k + 2] as usize);
        let count = lo + self.cdf[lo..hi].partition_point(|&c| c <= u64);
        let i = count.saturating_sub(1).min(n - 1);
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

/// The guide table of [`Distribution1D`] for a cdf of n + 1 values:
/// entry j, for j in 0..=n + 1, counts the values below (j − ½)/n.
fn guide_table(cdf: &[f64], n: usize) -> Vec<u32> {
    let m = n.max(1);
    let mut below = 0usize;
    (0..=m + 1)
        .map(|j| {
            let bound = (j as f64 - 0.5) / m as f64;
            while below < cdf.len() && cdf[below] < bound {
                below += 1;
            }
            u32::try_from(below).expect("a distribution of at most 2³² − 2 items")
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// What the guided search must find: the search of the whole table.
    fn searched(d: &Distribution1D, u: f32) -> usize {
        let u = u as f64;
        d.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(d.len() - 1)
    }

    #[test]
    fn the_guide_table_finds_what_a_full_search_finds() {
        let mut r = Pcg32::new(7, 3);
        // Smooth, spiky (a sun: one item of almost all the weight), runs of
        // zero weights, one item, and weights spanning 30 orders.
        let mut cases: Vec<Vec<f32>> = vec![
            (0..257).map(|i| 1.0 + (i as f32 * 0.1).sin()).collect(),
            (0..300).map(|i| if i == 123 { 1e9 } else { 1e-3 }).collect(),
            (0..100).map(|i| if i % 10 < 7 { 0.0 } else { 1.0 }).collect(),
            vec![0.0, 0.0, 5.0, 0.0, 0.0],
            (0..64).map(|i| 10f32.powi(i % 31 - 15)).collect(),
        ];
        cases.push((0..1000).map(|_| r.next_f32().powi(8)).collect());
        for weights in &cases {
            let d = Distribution1D::new(weights);
            let cdf_values = d.cdf.iter().map(|&c| c as f32);
            let mut us: Vec<f32> = (0..20_000).map(|_| r.next_f32()).collect();
            // Every cdf value exactly and its neighbours, where rounding bites.
            for c in cdf_values {
                us.extend([c, c.next_down(), c.next_up()]);
            }
            us.extend([0.0, 1.0 - f32::EPSILON / 2.0, 1.0, -0.5, 2.0, f32::NAN]);
            for u in us {
                assert_eq!(d.sample(u).0, searched(&d, u), "u = {u} of {} items", weights.len());
            }
        }
    }

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

/// Draws x ∈ [0, 1) with density proportional to the linear function
/// that is `a` at 0 and `b` at 1 (both ≥ 0, not both 0), by inverting its
/// cumulative distribution in the form that stays accurate when one end is
/// near 0 (pbrt-v4 `SampleLinear`).
#[inline]
pub fn sample_linear(u: f32, a: f32, b: f32) -> f32 {
    if u == 0.0 && a == 0.0 {
        return 0.0;
    }
    let x = u * (a + b) / (a + ((1.0 - u) * a * a + u * b * b).sqrt());
    x.min(1.0 - f32::EPSILON / 2.0)
}

/// A density over [0, 1]² proportional to the bilinear interpolation of
/// non-negative values at the nodes of a regular grid (`nodes_x` × `nodes_y`
/// nodes, so one fewer cells each way). A cell is chosen in proportion to
/// the integral of its bilinear patch (the mean of its four corners), then
/// the point inside it by the patch's marginal and conditional densities,
/// both linear (pbrt-v4 `SampleBilinear`): the density is exactly the
/// interpolant, not a step function beside it, so an image lookup that
/// interpolates bilinearly is sampled without the variance a piecewise
/// constant density leaves at the edges of bright pixels.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BilinearDistribution2D {
    nodes_x: usize,
    nodes_y: usize,
    nodes: Vec<f32>,
    cells: Distribution2D,
    /// Cells divided by the sum of the cell weights: turns an interpolated
    /// value into a density over [0, 1]².
    norm: f32,
}

impl BilinearDistribution2D {
    /// A distribution from row-major node values (negative or non-finite
    /// ones count as 0); needs at least two nodes each way.
    pub fn new(nodes: &[f32], nodes_x: usize, nodes_y: usize) -> Self {
        assert!(nodes_x >= 2 && nodes_y >= 2 && nodes.len() == nodes_x * nodes_y);
        let nodes: Vec<f32> = nodes
            .iter()
            .map(|&v| if v.is_finite() && v > 0.0 { v } else { 0.0 })
            .collect();
        let (cx, cy) = (nodes_x - 1, nodes_y - 1);
        let mut weights = Vec::with_capacity(cx * cy);
        let mut sum = 0.0f64;
        for y in 0..cy {
            for x in 0..cx {
                let n = |dx: usize, dy: usize| nodes[(y + dy) * nodes_x + x + dx] as f64;
                let w = 0.25 * (n(0, 0) + n(1, 0) + n(0, 1) + n(1, 1));
                weights.push(w as f32);
                sum += w;
            }
        }
        let norm = if sum > 0.0 {
            ((cx * cy) as f64 / sum) as f32
        } else {
            0.0
        };
        BilinearDistribution2D {
            nodes_x,
            nodes_y,
            nodes,
            cells: Distribution2D::new(&weights, cx, cy),
            norm,
        }
    }

    /// The four corner values of cell (x, y): (x0 y0, x1 y0, x0 y1, x1 y1).
    #[inline]
    fn corners(&self, x: usize, y: usize) -> [f32; 4] {
        let i = y * self.nodes_x + x;
        let j = i + self.nodes_x;
        [self.nodes[i], self.nodes[i + 1], self.nodes[j], self.nodes[j + 1]]
    }

    #[inline]
    fn cell_of(&self, t: f32, cells: usize) -> (usize, f32) {
        let s = t.clamp(0.0, 1.0) * cells as f32;
        let i = (s as usize).min(cells - 1);
        (i, s - i as f32)
    }

    /// A point of [0, 1]² and its density there (0 where every node is 0).
    #[inline]
    pub fn sample(&self, u: glam::Vec2) -> (glam::Vec2, f32) {
        let (x, y, f, pdf) = self.sample_in_cell(u);
        let (cx, cy) = (self.nodes_x - 1, self.nodes_y - 1);
        (
            glam::Vec2::new((x as f32 + f.x) / cx as f32, (y as f32 + f.y) / cy as f32),
            pdf,
        )
    }

    /// [`BilinearDistribution2D::sample`] as the cell drawn (its column
    /// and row), the point's fractions within it and its density: what a
    /// caller needs to interpolate values stored at the same nodes.
    #[inline]
    pub fn sample_in_cell(&self, u: glam::Vec2) -> (usize, usize, glam::Vec2, f32) {
        // The cell, then the two numbers rescaled to within it.
        let (y, _, ry) = self.cells.marginal.sample(u.y);
        let (x, _, rx) = self.cells.rows[y].sample(u.x);
        let [a, b, c, d] = self.corners(x, y);
        let fy = sample_linear(ry, a + b, c + d);
        let fx = sample_linear(rx, a + (c - a) * fy, b + (d - b) * fy);
        let value = bilerp([a, b, c, d], fx, fy);
        (x, y, glam::Vec2::new(fx, fy), value * self.norm)
    }

    /// The node values, row-major, as the density interpolates them
    /// (negative and non-finite ones as 0).
    pub fn nodes(&self) -> &[f32] {
        &self.nodes
    }

    /// The factor that turns an interpolated node value into the density.
    pub fn norm(&self) -> f32 {
        self.norm
    }

    /// The density at a point of [0, 1]².
    #[inline]
    pub fn pdf(&self, p: glam::Vec2) -> f32 {
        let (x, fx) = self.cell_of(p.x, self.nodes_x - 1);
        let (y, fy) = self.cell_of(p.y, self.nodes_y - 1);
        bilerp(self.corners(x, y), fx, fy) * self.norm
    }
}

/// The bilinear interpolation of corners (x0 y0, x1 y0, x0 y1, x1 y1).
#[inline]
fn bilerp([a, b, c, d]: [f32; 4], fx: f32, fy: f32) -> f32 {
    (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy
}

#[cfg(test)]
mod tests_bilinear {
    use super::*;
    use crate::sampling::rng::Pcg32;

    #[test]
    fn linear_samples_follow_the_line() {
        // The empirical distribution against the exact CDF of density ∝ a + (b − a)x.
        let mut r = Pcg32::new(3, 1);
        for (a, b) in [(1.0f32, 1.0f32), (0.0, 2.0), (3.0, 0.0), (1e-6, 5.0)] {
            let n = 20_000;
            let mut xs: Vec<f32> = (0..n).map(|_| sample_linear(r.next_f32(), a, b)).collect();
            xs.sort_by(f32::total_cmp);
            let cdf = |x: f32| (a * x + 0.5 * (b - a) * x * x) / (0.5 * (a + b));
            let ks = xs
                .iter()
                .enumerate()
                .map(|(i, &x)| ((i as f32 + 0.5) / n as f32 - cdf(x)).abs())
                .fold(0.0f32, f32::max);
            // Kolmogorov–Smirnov at α = 0.001: 1.95/√n.
            assert!(ks < 1.95 / (n as f32).sqrt(), "a {a} b {b}: KS {ks}");
            assert!(xs.iter().all(|x| (0.0..1.0).contains(x)));
        }
        assert_eq!(sample_linear(0.0, 0.0, 1.0), 0.0);
    }

    #[test]
    fn bilinear_density_matches_samples_and_integrates_to_one() {
        // 4 × 3 nodes with zeros, a spike and a flat part.
        #[rustfmt::skip]
        let nodes = [
            0.0, 0.0, 1.0, 1.0,
            0.0, 9.0, 1.0, 1.0,
            0.0, 0.0, 1.0, 0.5,
        ];
        let d = BilinearDistribution2D::new(&nodes, 4, 3);
        // ∫ pdf = 1 by the midpoint rule on a fine grid.
        let m = 600;
        let mut integral = 0.0f64;
        for j in 0..m {
            for i in 0..m {
                let p = glam::Vec2::new((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32);
                integral += d.pdf(p) as f64;
            }
        }
        integral /= (m * m) as f64;
        assert!((integral - 1.0).abs() < 1e-3, "∫ pdf = {integral}");
        // Chi-square of samples over an 12 × 12 grid against the pdf integrated per cell.
        let g = 12;
        let mut counts = vec![0f64; g * g];
        let mut r = Pcg32::new(5, 2);
        let n = 200_000;
        let mut on_zero_edges = 0;
        for _ in 0..n {
            let (p, pdf) = d.sample(glam::Vec2::new(r.next_f32(), r.next_f32()));
            assert!((pdf - d.pdf(p)).abs() <= 1e-3 * pdf, "{p} {pdf} {}", d.pdf(p));
            if pdf == 0.0 {
                // A draw of exactly 0 lands on a corner whose value is 0:
                // callers drop such a sample.
                on_zero_edges += 1;
            }
            let cell = ((p.y * g as f32) as usize).min(g - 1) * g + ((p.x * g as f32) as usize).min(g - 1);
            counts[cell] += 1.0;
        }
        let (mut chi2, mut dof) = (0.0, 0);
        for (cell, &count) in counts.iter().enumerate() {
            let (cx, cy) = (cell % g, cell / g);
            let k = 20;
            let mut expected = 0.0f64;
            for j in 0..k {
                for i in 0..k {
                    let p = glam::Vec2::new(
                        (cx as f32 + (i as f32 + 0.5) / k as f32) / g as f32,
                        (cy as f32 + (j as f32 + 0.5) / k as f32) / g as f32,
                    );
                    expected += d.pdf(p) as f64;
                }
            }
            expected *= n as f64 / (k * k * g * g) as f64;
            if expected < 1e-9 {
                assert_eq!(count, 0.0, "a sample where the density is 0");
            } else if expected > 5.0 {
                chi2 += (count - expected).powi(2) / expected;
                dof += 1;
            }
        }
        assert!(on_zero_edges < 10, "{on_zero_edges} samples of density 0");
        let p_value = crate::sampling::chi2::chi2_survival(chi2, (dof - 1) as f64);
        assert!(p_value > 0.001, "χ² {chi2} over {dof} cells: p = {p_value}");
    }
}
