//! The sampler study of pbrt-v4's `Integrator "function"`: how fast a
//! sampler's error falls with the number of samples, measured on test
//! functions whose integral over [0, 1]² is known to be 1. Every pixel
//! estimates the integral from the positions in the pixel that the sampler
//! gives its samples (the same numbers a render places its camera rays
//! with), and the study reports, per sample count n, the mean over pixels
//! of (estimate − 1)²: for independent samples it falls as 1/n, for
//! stratified and low-discrepancy points faster, and how much faster
//! depends on the function's edges (Pharr, Jakob & Humphreys, *Physically
//! Based Rendering*, 4th ed., ch. 8).

use crate::color::Rgb;
use crate::film::Image;
use crate::sampling::rng::hash_u64s;
use crate::sampling::{Pcg32, Sampler, SamplerKind};
use crate::settings::{RenderSettings, SamplerStudy, TestFunction};
use glam::Vec2;
use rayon::prelude::*;

/// The value of `f` at `p` in [0, 1]², as pbrt-v4 defines it.
pub fn value(f: TestFunction, p: Vec2) -> f64 {
    match f {
        TestFunction::Step => {
            if p.x < 0.5 {
                2.0
            } else {
                0.0
            }
        }
        TestFunction::Diagonal => {
            if p.x + p.y < 1.0 {
                2.0
            } else {
                0.0
            }
        }
        TestFunction::Disk => {
            if p.distance(Vec2::splat(0.5)) < 0.5 {
                4.0 / std::f64::consts::PI
            } else {
                0.0
            }
        }
        TestFunction::Checkerboard => checkerboard(p),
        TestFunction::RotatedCheckerboard => {
            let (sa, ca) = std::f32::consts::FRAC_PI_4.sin_cos();
            // pbrt-v4's normalisation of the turned board, whose cells the
            // square cuts unevenly.
            const INTEGRAL: f64 = 1.000_068_664_550_781_3;
            checkerboard(Vec2::new(10.0 + p.x * ca - p.y * sa, 10.0 + p.x * sa + p.y * ca)) / INTEGRAL
        }
        TestFunction::Gaussian => {
            const MU: f64 = 0.5;
            const SIGMA: f64 = 0.25;
            // The square holds ±2σ of each axis: erf(√2) of its mass.
            const ERF_SQRT_2: f64 = 0.954_499_736_103_641_6;
            let g = |x: f32| {
                (-(x as f64 - MU).powi(2) / (2.0 * SIGMA * SIGMA)).exp()
                    / (2.0 * std::f64::consts::PI * SIGMA * SIGMA).sqrt()
            };
            g(p.x) * g(p.y) / (ERF_SQRT_2 * ERF_SQRT_2)
        }
    }
}

/// 2 on the cells of a 10 × 10 board where the column and row numbers
/// differ in parity, 0 on the others.
fn checkerboard(p: Vec2) -> f64 {
    let (x, y) = ((p.x * 10.0) as i32, (p.y * 10.0) as i32);
    if (x & 1) ^ (y & 1) == 1 { 2.0 } else { 0.0 }
}

/// Whether sample count `n` is reported for `kind`: all counts, or with
/// `skip_bad` those the sampler is designed for, as pbrt-v4 chooses them.
pub fn is_reported(kind: SamplerKind, n: u32, skip_bad: bool) -> bool {
    if !skip_bad {
        return true;
    }
    match kind {
        SamplerKind::Stratified => {
            let r = (n as f64).sqrt().round() as u32;
            r * r == n
        }
        SamplerKind::Sobol => n.is_power_of_two(),
        SamplerKind::Halton | SamplerKind::HaltonOwen | SamplerKind::HaltonPlain => {
            let (mut m, mut twos, mut threes) = (n, 0, 0);
            while m % 2 == 0 {
                m /= 2;
                twos += 1;
            }
            while m % 3 == 0 {
                m /= 3;
                threes += 1;
            }
            m == 1 && twos == threes
        }
        SamplerKind::Independent | SamplerKind::Center => true,
    }
}

/// What a study measured.
#[derive(Clone, Debug, PartialEq)]
pub struct StudyReport {
    /// Each reported sample count with the mean over pixels of the squared
    /// error of the pixels' estimates at that count.
    pub errors: Vec<(u32, f64)>,
    /// The mean over pixels of the estimates at the last count reported,
    /// and its standard error: an unbiased sampler's is 1 within a few.
    pub mean_estimate: (f64, f64),
}

impl StudyReport {
    /// The text pbrt-v4 writes: a line `n mse` for each reported count.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        for &(n, mse) in &self.errors {
            // pbrt-v4 prints its single-precision value at its shortest,
            // with an exponent below 10⁻⁶.
            let v = mse as f32;
            if v != 0.0 && v < 1e-6 {
                out += &format!("{n} {v:e}\n");
            } else {
                out += &format!("{n} {v}\n");
            }
        }
        out
    }

    /// A warning where the estimates' mean is further from 1 than their
    /// noise explains: the sampler is biased.
    pub fn bias_warning(&self) -> Option<String> {
        let (mean, se) = self.mean_estimate;
        ((mean - 1.0).abs() > (5.0 * se).max(1e-3)).then(|| {
            format!(
                "the sampler study's mean estimate is {mean:.6} (± {se:.2e}), far from the function's integral 1: the sampler's points are not uniform"
            )
        })
    }
}

/// Runs `study` with the sampler, samples per pixel, seed and image size
/// of `settings`. Each pixel's numbers depend on the pixel alone, so the
/// report is the same for any number of threads.
pub fn run(study: &SamplerStudy, settings: &RenderSettings) -> StudyReport {
    let (width, height) = (settings.width.max(1), settings.height.max(1));
    let (full_w, full_h) = settings.full_size();
    let (x0, y0) = settings.crop.map_or((0, 0), |c| (c.x, c.y));
    let spp = settings.spp.max(1);
    let kind = settings.sampler;
    let counts: Vec<u32> = (1..=spp).filter(|&n| is_reported(kind, n, study.skip_bad)).collect();
    let f = study.function;
    // Per row: Σ over its pixels of the squared error at each count, and
    // of the final estimate and its square.
    let rows: Vec<(Vec<f64>, f64, f64)> = (0..height)
        .into_par_iter()
        .map(|y| {
            let mut squared = vec![0.0; counts.len()];
            let (mut sum, mut sum_sq) = (0.0, 0.0);
            let mut last = 0.0;
            for x in 0..width {
                let (px, py) = (x0 + x, y0 + y);
                if kind == SamplerKind::Stratified {
                    // A stratified sampler's strata depend on its sample
                    // count: each count is a pattern of its own, with its
                    // own jitter, as pbrt-v4's study draws it.
                    for (i, &n) in counts.iter().enumerate() {
                        let grid = crate::sampling::sampler::strata_grid(n);
                        let mut sampler = Sampler::new(kind, n, hash_u64s(&[settings.seed, n as u64]))
                            .with_strata(Some([grid[1], grid[0]]), true);
                        let mut total = 0.0;
                        for s in 0..n {
                            sampler.start_pixel_sample(px, py, s);
                            total += value(f, sampler.pixel_2d());
                        }
                        last = total / n as f64;
                        squared[i] += (last - 1.0).powi(2);
                    }
                } else {
                    let mut sampler = Sampler::new(kind, spp, settings.seed).for_image(full_w, full_h);
                    let mut total = 0.0;
                    let mut next = 0;
                    for s in 0..spp {
                        sampler.start_pixel_sample(px, py, s);
                        total += value(f, sampler.pixel_2d());
                        if counts.get(next) == Some(&(s + 1)) {
                            last = total / (s + 1) as f64;
                            squared[next] += (last - 1.0).powi(2);
                            next += 1;
                        }
                    }
                }
                sum += last;
                sum_sq += last * last;
            }
            (squared, sum, sum_sq)
        })
        .collect();
    let pixels = (width as f64) * (height as f64);
    let mut squared = vec![0.0; counts.len()];
    let (mut sum, mut sum_sq) = (0.0, 0.0);
    for (row, s, s2) in &rows {
        for (total, v) in squared.iter_mut().zip(row) {
            *total += v;
        }
        sum += s;
        sum_sq += s2;
    }
    let mean = sum / pixels;
    let variance = if pixels > 1.0 {
        ((sum_sq - sum * mean) / (pixels - 1.0)).max(0.0)
    } else {
        0.0
    };
    StudyReport {
        errors: counts.iter().zip(&squared).map(|(&n, &s)| (n, s / pixels)).collect(),
        mean_estimate: (mean, (variance / pixels).sqrt()),
    }
}

/// An image of `f` at `width` × `height` pixels, each the mean of 256
/// uniform samples in it, the top row at y = 0 (pbrt-v4's `imagefilename`).
pub fn function_image(f: TestFunction, width: u32, height: u32, seed: u64) -> Image {
    const SAMPLES: u32 = 256;
    let pixels = (0..height)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..width).map(move |x| {
                let mut rng = Pcg32::new(hash_u64s(&[seed, x as u64, y as u64]), 0);
                let total: f64 = (0..SAMPLES)
                    .map(|_| {
                        let u = Vec2::new(rng.next_f32(), rng.next_f32());
                        let p = (Vec2::new(x as f32, y as f32) + u) / Vec2::new(width as f32, height as f32);
                        value(f, p)
                    })
                    .sum();
                Rgb::splat((total / SAMPLES as f64) as f32)
            })
        })
        .collect();
    Image { width, height, pixels }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn study(function: TestFunction, kind: SamplerKind, spp: u32, size: u32, skip_bad: bool) -> StudyReport {
        let settings = RenderSettings {
            width: size,
            height: size,
            spp,
            sampler: kind,
            seed: 7,
            ..RenderSettings::default()
        };
        let s = SamplerStudy {
            function,
            skip_bad,
            output: None,
            image: None,
        };
        run(&s, &settings)
    }

    /// Every test function integrates to 1 over the square (a midpoint
    /// sum over 2000² cells, whose error at the functions' edges is a few
    /// 10⁻⁴).
    #[test]
    fn each_test_function_integrates_to_one() {
        let n = 2000;
        for name in TestFunction::NAMES {
            let f = TestFunction::from_name(name).unwrap();
            assert_eq!(f.name(), name);
            let mut total = 0.0;
            for j in 0..n {
                for i in 0..n {
                    let p = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    total += value(f, p);
                }
            }
            let integral = total / (n * n) as f64;
            assert!((integral - 1.0).abs() < 2e-3, "{name}: {integral}");
        }
        assert_eq!(TestFunction::from_name("sphere"), None);
    }

    #[test]
    fn the_counts_reported_are_those_each_sampler_is_designed_for() {
        let reported = |kind, skip| (1..=300).filter(|&n| is_reported(kind, n, skip)).collect::<Vec<_>>();
        assert_eq!(
            reported(SamplerKind::Sobol, true),
            vec![1, 2, 4, 8, 16, 32, 64, 128, 256]
        );
        assert_eq!(reported(SamplerKind::Halton, true), vec![1, 6, 36, 216]);
        assert_eq!(reported(SamplerKind::Stratified, true)[..5], [1, 4, 9, 16, 25]);
        assert_eq!(reported(SamplerKind::Independent, true).len(), 300);
        assert_eq!(reported(SamplerKind::Sobol, false).len(), 300);
    }

    /// Independent samples of the step function (values 2 and 0 with
    /// probability ½ each: variance 1) give each pixel's estimate at n
    /// samples a variance of 1/n, so the study's mean squared error over
    /// P pixels is 1/n with a relative standard deviation of about
    /// √(2/P) (2.2 % for 64² pixels; the bound is 5 of them).
    #[test]
    fn independent_samples_have_the_error_of_their_variance() {
        let r = study(TestFunction::Step, SamplerKind::Independent, 64, 64, true);
        assert_eq!(r.errors.len(), 64);
        let tolerance = 5.0 * (2.0f64 / (64.0 * 64.0)).sqrt();
        for &(n, mse) in &r.errors {
            let expected = 1.0 / n as f64;
            // At one sample each squared error is exactly 1.
            assert!(
                (mse / expected - 1.0).abs() < tolerance,
                "n = {n}: {mse} against {expected}"
            );
        }
        assert!(r.bias_warning().is_none(), "{:?}", r.mean_estimate);
        let text = r.to_text();
        assert!(text.starts_with("1 1\n2 "), "{text}");
        assert_eq!(text.lines().count(), 64);
    }

    /// The step's edge at x = ½ lies on a stratum boundary of every even
    /// grid and of the first 2ᵏ Sobol points (the (0, 2)-sequence puts one
    /// point in each of 2ᵏ intervals of x): those estimates are exact. The
    /// diagonal edge crosses strata, and stratified error falls faster than
    /// 1/n there (n^(−3/2) for an edge).
    #[test]
    fn strata_aligned_with_an_edge_integrate_it_exactly() {
        let sobol = study(TestFunction::Step, SamplerKind::Sobol, 64, 16, true);
        for &(n, mse) in &sobol.errors[1..] {
            assert!(mse < 1e-12, "sobol, n = {n}: {mse}");
        }
        let stratified = study(TestFunction::Step, SamplerKind::Stratified, 64, 16, true);
        assert_eq!(
            stratified.errors.iter().map(|e| e.0).collect::<Vec<_>>(),
            [1, 4, 9, 16, 25, 36, 49, 64]
        );
        for &(n, mse) in &stratified.errors {
            if n % 2 == 0 {
                assert!(mse < 1e-12, "stratified, n = {n}: {mse}");
            } else {
                assert!(mse > 1e-4, "stratified, n = {n}: an odd grid splits the edge's column");
            }
        }
        let diagonal = study(TestFunction::Diagonal, SamplerKind::Stratified, 256, 32, true);
        let independent = study(TestFunction::Diagonal, SamplerKind::Independent, 256, 32, true);
        let at = |r: &StudyReport, n| r.errors.iter().find(|e| e.0 == n).unwrap().1;
        assert!(at(&diagonal, 256) < 0.1 * at(&independent, 256));
        assert!(diagonal.bias_warning().is_none() && independent.bias_warning().is_none());
    }

    /// Every sampler's estimates are unbiased: their mean over pixels is 1
    /// within its standard error.
    #[test]
    fn every_sampler_is_unbiased_on_every_function() {
        for kind in ["independent", "stratified", "sobol", "halton", "halton-owen"] {
            for name in TestFunction::NAMES {
                let f = TestFunction::from_name(name).unwrap();
                let r = study(f, SamplerKind::from_name(kind).unwrap(), 16, 32, false);
                let (mean, se) = r.mean_estimate;
                assert!((mean - 1.0).abs() < 5.0 * se + 1e-9, "{kind}, {name}: {mean} ± {se}");
            }
        }
    }

    #[test]
    fn the_function_image_shows_the_function() {
        let img = function_image(TestFunction::Step, 4, 2, 1);
        let v: Vec<f32> = img.pixels.iter().map(|p| p.x).collect();
        assert_eq!(v, [2.0, 2.0, 0.0, 0.0, 2.0, 2.0, 0.0, 0.0]);
    }
}
