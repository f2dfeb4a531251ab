//! The error function and its inverse in single precision, for sampling
//! Gaussian profiles: pixel filters and Beckmann microfacet slopes.

/// The error function (Abramowitz and Stegun 7.1.26: one exponential,
/// absolute error below 1.5e-7, ample for pixel offsets).
pub fn erf(x: f32) -> f32 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * z);
    let poly = t * (0.254_829_6 + t * (-0.284_496_74 + t * (1.421_413_8 + t * (-1.453_152_1 + t * 1.061_405_4))));
    let r = 1.0 - poly * (-z * z).exp();
    r.copysign(x)
}

/// The inverse error function on (−1, 1): Giles' single-precision
/// approximation (Giles 2012, "Approximating the erfinv function"), one
/// logarithm and a polynomial, relative error about 4e-7.
pub fn erf_inv(y: f32) -> f32 {
    let y = y.clamp(-1.0 + 1e-7, 1.0 - 1e-7);
    let w = -((1.0 - y) * (1.0 + y)).ln();
    if w < 5.0 {
        let w = w - 2.5;
        let mut p = 2.810_226_4e-8;
        p = 3.432_739_4e-7 + p * w;
        p = -3.523_387_7e-6 + p * w;
        p = -4.391_506_5e-6 + p * w;
        p = 0.000_218_580_87 + p * w;
        p = -0.001_253_725 + p * w;
        p = -0.004_177_681_6 + p * w;
        p = 0.246_640_73 + p * w;
        p = 1.501_409_4 + p * w;
        p * y
    } else {
        let w = w.sqrt() - 3.0;
        let mut p = -0.000_200_214_26;
        p = 0.000_100_950_56 + p * w;
        p = 0.001_349_343_2 + p * w;
        p = -0.003_673_428_4 + p * w;
        p = 0.005_739_507_7 + p * w;
        p = -0.007_622_461 + p * w;
        p = 0.009_438_870_5 + p * w;
        p = 1.001_674 + p * w;
        p = 2.832_976_8 + p * w;
        p * y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erf_and_its_inverse() {
        assert!((erf(0.5) as f64 - 0.520_499_877_8).abs() < 2e-7);
        assert!((erf(-1.0) as f64 + 0.842_700_792_9).abs() < 2e-7);
        for y in [-0.99, -0.5, 0.0, 0.3, 0.9, 0.999] {
            assert!((erf(erf_inv(y)) - y).abs() < 1e-6, "{y}");
        }
        // Against the series erf(x) = 2/√π Σ (−1)ⁿ x^(2n+1) / (n! (2n+1)).
        for x in [0.1f64, 0.7, 1.3, 2.0] {
            let mut term = x;
            let mut sum = 0.0;
            for n in 0..60 {
                sum += term / (2 * n + 1) as f64;
                term *= -x * x / (n + 1) as f64;
            }
            let exact = 2.0 / std::f64::consts::PI.sqrt() * sum;
            assert!((erf(x as f32) as f64 - exact).abs() < 3e-7, "{x}");
            assert!((erf_inv(exact as f32) as f64 - x).abs() < 2e-6 * x.max(1.0), "{x}");
        }
    }
}
