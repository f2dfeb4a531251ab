//! Error metrics between images.

use super::Image;
use crate::error::{Error, Result};

/// ε in the relative MSE's denominator, which keeps black pixels from
/// dominating (the convention of Rousselle et al. 2011 and of denoising
/// papers).
pub const REL_MSE_EPSILON: f64 = 1e-2;

fn check_sizes(a: &Image, b: &Image) -> Result<()> {
    if a.width != b.width || a.height != b.height {
        return Err(Error::Invalid(format!(
            "the images differ in size: {}×{} and {}×{}",
            a.width, a.height, b.width, b.height
        )));
    }
    Ok(())
}

/// Mean over pixels and channels of (a − b)² / (b² + ε): the error of
/// `a` relative to the reference `b`.
pub fn relative_mse(a: &Image, b: &Image) -> Result<f64> {
    check_sizes(a, b)?;
    let mut sum = 0.0f64;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let (x, y) = (p[c] as f64, q[c] as f64);
            sum += (x - y) * (x - y) / (y * y + REL_MSE_EPSILON);
        }
    }
    Ok(sum / (3 * a.pixels.len().max(1)) as f64)
}

/// Root of the mean over pixels and channels of (a − b)².
pub fn rmse(a: &Image, b: &Image) -> Result<f64> {
    check_sizes(a, b)?;
    let mut sum = 0.0f64;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let d = p[c] as f64 - q[c] as f64;
            sum += d * d;
        }
    }
    Ok((sum / (3 * a.pixels.len().max(1)) as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::Rgb;

    #[test]
    fn metrics_of_known_images() {
        let mut a = Image::new(2, 1);
        let mut b = Image::new(2, 1);
        a.pixels = vec![Rgb::splat(1.0), Rgb::splat(0.0)];
        b.pixels = vec![Rgb::splat(1.0), Rgb::splat(2.0)];
        assert!((rmse(&a, &b).unwrap() - 2f64.sqrt()).abs() < 1e-9);
        let rel = relative_mse(&a, &b).unwrap();
        assert!((rel - 0.5 * 4.0 / (4.0 + REL_MSE_EPSILON)).abs() < 1e-9);
        assert_eq!(relative_mse(&b, &b).unwrap(), 0.0);
        assert!(rmse(&a, &Image::new(3, 1)).is_err());
    }
}
