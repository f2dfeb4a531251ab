//! Pearson's chi-square goodness-of-fit test for direction samplers: do the
//! directions a sampler produces follow the density it claims? (The method
//! of Mitsuba's `chi2` tests and pbrt's `sampling_test`.)
//!
//! The sphere is cut into cells of equal solid angle (bands of cos θ times
//! sectors of φ). Many directions are drawn and counted per cell; the
//! expected count of a cell is the number of draws times the density
//! integrated over the cell by quadrature. Cells expecting fewer than 5
//! are pooled, and the statistic Σ (observed − expected)²/expected is
//! compared with the chi-square distribution.

use glam::Vec3;
use std::f64::consts::PI;

/// The outcome of a test.
#[derive(Clone, Debug)]
pub struct Chi2Result {
    /// The statistic.
    pub statistic: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Probability of a statistic at least this large if the sampler is right.
    pub p_value: f64,
    /// Draws that produced a direction (others failed or were delta).
    pub counted: u64,
    /// The expected total from the density (should equal `counted` within noise).
    pub expected_total: f64,
}

/// Grid and sample count of a test.
#[derive(Clone, Copy, Debug)]
pub struct Chi2Test {
    /// Bands in cos θ.
    pub theta_bins: usize,
    /// Sectors in φ.
    pub phi_bins: usize,
    /// Draws.
    pub samples: u64,
    /// Quadrature points per cell side.
    pub quadrature: usize,
}

impl Default for Chi2Test {
    fn default() -> Self {
        Chi2Test {
            theta_bins: 20,
            phi_bins: 40,
            samples: 200_000,
            quadrature: 8,
        }
    }
}

fn cell_of(d: Vec3, nt: usize, np: usize) -> usize {
    let z = d.z.clamp(-1.0, 1.0) as f64;
    let t = (((1.0 - z) * 0.5 * nt as f64) as usize).min(nt - 1);
    let phi = (d.y as f64).atan2(d.x as f64).rem_euclid(2.0 * PI);
    let p = ((phi / (2.0 * PI) * np as f64) as usize).min(np - 1);
    t * np + p
}

impl Chi2Test {
    /// Runs the test. `sample(i)` returns the i-th drawn direction (unit
    /// length), or `None` when the draw produced none (or a delta lobe);
    /// `pdf(d)` is the claimed density per steradian of the non-delta part.
    pub fn run(&self, mut sample: impl FnMut(u64) -> Option<Vec3>, pdf: impl Fn(Vec3) -> f64) -> Chi2Result {
        let (nt, np) = (self.theta_bins, self.phi_bins);
        let cells = nt * np;
        let mut observed = vec![0f64; cells];
        let mut counted = 0u64;
        for i in 0..self.samples {
            if let Some(d) = sample(i) {
                if d.is_finite() {
                    observed[cell_of(d, nt, np)] += 1.0;
                    counted += 1;
                }
            }
        }
        // Expected counts: midpoint quadrature in (cos θ, φ), where the
        // solid-angle element is d(cos θ)·dφ. Cells where the density
        // varies a lot (an edge of its support, a narrow peak) are
        // integrated again on a grid eight times finer.
        let dz = 2.0 / nt as f64;
        let dphi = 2.0 * PI / np as f64;
        let integrate = |t: usize, p: usize, q: usize| -> (f64, f64, f64) {
            let (mut sum, mut lo, mut hi) = (0.0, f64::INFINITY, 0.0f64);
            for a in 0..q {
                let z = 1.0 - dz * (t as f64 + (a as f64 + 0.5) / q as f64);
                let r = (1.0 - z * z).max(0.0).sqrt();
                for b in 0..q {
                    let phi = dphi * (p as f64 + (b as f64 + 0.5) / q as f64);
                    let d = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                    let v = pdf(d);
                    sum += v;
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            (sum / (q * q) as f64, lo, hi)
        };
        let mut expected = vec![0f64; cells];
        for t in 0..nt {
            for p in 0..np {
                let (mut mean, lo, hi) = integrate(t, p, self.quadrature);
                if hi > 0.0 && (hi - lo) > 0.1 * hi {
                    mean = integrate(t, p, self.quadrature * 8).0;
                }
                expected[t * np + p] = mean * dz * dphi * self.samples as f64;
            }
        }
        let expected_total = expected.iter().sum();

        // Pool cells expecting fewer than 5 draws, smallest first.
        let mut order: Vec<usize> = (0..cells).collect();
        order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
        let mut statistic = 0.0;
        let mut dof = 0usize;
        let (mut pool_obs, mut pool_exp) = (0.0, 0.0);
        for &c in &order {
            if expected[c] < 5.0 || pool_exp > 0.0 && pool_exp < 5.0 {
                pool_obs += observed[c];
                pool_exp += expected[c];
                if pool_exp >= 5.0 {
                    statistic += (pool_obs - pool_exp).powi(2) / pool_exp;
                    dof += 1;
                    pool_obs = 0.0;
                    pool_exp = 0.0;
                }
                continue;
            }
            statistic += (observed[c] - expected[c]).powi(2) / expected[c];
            dof += 1;
        }
        if pool_exp > 0.0 {
            // A remainder too small to stand alone: any sample there is a failure.
            statistic += (pool_obs - pool_exp).powi(2) / pool_exp.max(1e-3);
            dof += 1;
        }
        let dof = dof.saturating_sub(1).max(1);
        Chi2Result {
            statistic,
            dof,
            p_value: chi2_survival(statistic, dof as f64),
            counted,
            expected_total,
        }
    }
}

/// P(X ≥ x) for X chi-square distributed with `k` degrees of freedom:
/// the regularised upper incomplete gamma function Q(k/2, x/2).
pub fn chi2_survival(x: f64, k: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    upper_regularized_gamma(k / 2.0, x / 2.0)
}

fn ln_gamma(x: f64) -> f64 {
    // Lanczos approximation (g = 7, n = 9), accurate to about 1e-15.
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return (PI / (PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Q(a, x) by its series (x < a + 1) or continued fraction (otherwise).
fn upper_regularized_gamma(a: f64, x: f64) -> f64 {
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        let mut sum = 1.0 / a;
        let mut del = sum;
        let mut ap = a;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        let p = sum * (-x + a * x.ln() - gln).exp();
        (1.0 - p).max(0.0)
    } else {
        // Lentz's method for the continued fraction.
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

/// The significance level for one of `tests` tests so that all of them
/// together reject a correct sampler with probability `alpha` (Šidák).
pub fn sidak_alpha(alpha: f64, tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / tests.max(1) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;
    use crate::sampling::warp::*;
    use glam::Vec2;

    #[test]
    fn survival_function_known_values() {
        // Tabulated 0.95 and 0.99 quantiles of chi-square.
        assert!((chi2_survival(3.841, 1.0) - 0.05).abs() < 1e-3);
        assert!((chi2_survival(18.307, 10.0) - 0.05).abs() < 1e-3);
        assert!((chi2_survival(135.807, 100.0) - 0.01).abs() < 1e-3);
        assert!((chi2_survival(2.0, 2.0) - (-1.0f64).exp()).abs() < 1e-9);
        assert_eq!(chi2_survival(0.0, 5.0), 1.0);
    }

    fn run(f: impl Fn(Vec2) -> Vec3, pdf: impl Fn(Vec3) -> f64) -> Chi2Result {
        let mut r = Pcg32::new(77, 0);
        Chi2Test::default().run(|_| Some(f(Vec2::new(r.next_f32(), r.next_f32()))), pdf)
    }

    #[test]
    fn warps_pass_and_a_wrong_pdf_fails() {
        let alpha = sidak_alpha(0.01, 5);
        let cases: Vec<(&str, Chi2Result)> = vec![
            (
                "uniform sphere",
                run(sample_sphere_uniform, |_| pdf_sphere_uniform() as f64),
            ),
            (
                "uniform hemisphere",
                run(sample_hemisphere_uniform, |d| {
                    if d.z > 0.0 {
                        pdf_hemisphere_uniform() as f64
                    } else {
                        0.0
                    }
                }),
            ),
            (
                "cosine hemisphere",
                run(sample_hemisphere_cosine, |d| pdf_hemisphere_cosine(d.z) as f64),
            ),
            (
                "cone",
                run(
                    |u| sample_cone_uniform(u, 0.7),
                    |d| if d.z >= 0.7 { pdf_cone_uniform(0.7) as f64 } else { 0.0 },
                ),
            ),
        ];
        for (name, r) in &cases {
            assert!(
                r.p_value > alpha,
                "{name}: p = {} (χ² = {}, dof {})",
                r.p_value,
                r.statistic,
                r.dof
            );
            assert!(
                (r.expected_total - r.counted as f64).abs() < 0.01 * r.counted as f64,
                "{name}: pdf does not integrate to 1"
            );
        }
        // Cosine samples judged against the uniform pdf must fail.
        let wrong = run(sample_hemisphere_cosine, |d| {
            if d.z > 0.0 {
                pdf_hemisphere_uniform() as f64
            } else {
                0.0
            }
        });
        assert!(
            wrong.p_value < 1e-6,
            "the test must be able to fail (p = {})",
            wrong.p_value
        );
    }
}
