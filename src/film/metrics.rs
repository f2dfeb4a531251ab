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

/// A false-colour image of the per-pixel relative error of `a` against
/// `b`: √(mean over channels of (a − b)²/(b² + ε)), mapped from black
/// (no error) through purple and orange to yellow (≥ `full_scale`).
pub fn error_image(a: &Image, b: &Image, full_scale: f64) -> Result<Image> {
    check_sizes(a, b)?;
    let pixels = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| {
            let mut e = 0.0f64;
            for c in 0..3 {
                let (x, y) = (p[c] as f64, q[c] as f64);
                e += (x - y) * (x - y) / (y * y + REL_MSE_EPSILON);
            }
            heat_ramp(((e / 3.0).sqrt() / full_scale.max(1e-12)) as f32)
        })
        .collect();
    Ok(Image {
        width: a.width,
        height: a.height,
        pixels,
    })
}

/// An inferno-like ramp from black (t = 0) through purple and orange to
/// yellow (t ≥ 1), given in sRGB and converted to linear so that a written
/// PNG shows these colours.
pub fn heat_ramp(t: f32) -> crate::color::Rgb {
    const STOPS: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.02],
        [0.34, 0.06, 0.43],
        [0.73, 0.21, 0.33],
        [0.98, 0.55, 0.04],
        [0.99, 1.0, 0.64],
    ];
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) } * (STOPS.len() - 1) as f32;
    let i = (t as usize).min(STOPS.len() - 2);
    let f = t - i as f32;
    let c = |k: usize| crate::color::srgb_to_linear(STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f);
    crate::color::Rgb::new(c(0), c(1), c(2))
}

/// A false-colour image of `img`'s first channel, from black at 0 to
/// yellow at `full_scale` and above.
pub fn heat_map(img: &Image, full_scale: f32) -> Image {
    Image {
        width: img.width,
        height: img.height,
        pixels: img
            .pixels
            .iter()
            .map(|p| heat_ramp(p.x / full_scale.max(1e-12)))
            .collect(),
    }
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
