//! The built-in denoiser: an edge-avoiding à-trous wavelet filter
//! (Dammertz, Sewtz, Hanika and Lensch 2010, "Edge-Avoiding À-Trous Wavelet
//! Transform for fast Global Illumination Filtering"), with the
//! variance-guided luminance weight and the albedo demodulation of
//! spatiotemporal variance-guided filtering (Schied et al. 2017, §4).
//!
//! 1. **Demodulation.** The image is divided by the albedo image, so that
//!    the filter blurs only illumination and texture detail survives; it is
//!    multiplied back at the end.
//! 2. **Five passes** of the 5×5 B3-spline kernel (1/16, 1/4, 3/8, 1/4,
//!    1/16) with holes: pass i reads pixels 2^i apart, so the footprint
//!    grows to 125 pixels at the cost of 25 taps per pass.
//! 3. **Edge-stopping weights** between the centre p and a tap q:
//!    - normal: max(0, n_p·n_q)^128;
//!    - albedo: exp(−|a_p − a_q|² / σ_a²), σ_a = 0.1;
//!    - luminance: exp(−|l_p − l_q| / (σ_l·√var_p + ε)), σ_l = 4, where
//!      var_p is the variance of the pixel's mean (the film measures it)
//!      blurred over 3×3 and carried through the passes as the variance of
//!      a weighted mean (Σ w² var / (Σ w)²): where the render is noisy the
//!      filter averages across luminance differences that noise explains,
//!      and where it has converged it stops.

use super::DenoiseInput;
use crate::color::{Rgb, luminance};
use crate::film::Image;
use glam::Vec3;
use rayon::prelude::*;

/// Passes of the filter.
const PASSES: u32 = 5;
/// B3-spline taps.
const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];
/// Exponent of the normal weight.
const SIGMA_NORMAL: i32 = 128;
/// Albedo difference that halves (about) the weight.
const SIGMA_ALBEDO: f32 = 0.1;
/// Luminance differences tolerated, in standard deviations of the noise.
const SIGMA_LUMINANCE: f32 = 4.0;
/// Albedo below which a pixel is not demodulated (black surfaces,
/// background).
const MIN_ALBEDO: f32 = 0.01;

/// Denoises with the à-trous filter.
pub fn denoise(input: &DenoiseInput) -> Image {
    let (w, h) = (input.color.width as usize, input.color.height as usize);
    let n = w * h;
    // Demodulate: illumination = colour / albedo.
    let factors: Vec<Rgb> = input
        .albedo
        .pixels
        .iter()
        .map(|&a| {
            if luminance(a) < MIN_ALBEDO {
                Rgb::ONE
            } else {
                a.max(Rgb::splat(MIN_ALBEDO))
            }
        })
        .collect();
    let mut illum: Vec<Rgb> = input.color.pixels.iter().zip(&factors).map(|(&c, &f)| c / f).collect();
    let raw_var: Vec<f32> = (0..n)
        .map(|i| {
            let f = luminance(factors[i]).max(MIN_ALBEDO);
            input.variance.get(i).copied().unwrap_or(0.0).max(0.0) / (f * f)
        })
        .collect();
    let normals: Vec<Vec3> = input.normal.pixels.iter().map(|v| v.normalize_or_zero()).collect();
    let albedo = &input.albedo.pixels;
    let mut var = blur3(&raw_var, w, h);

    for pass in 0..PASSES {
        let step = 1usize << pass;
        let (illum_ref, var_ref) = (&illum, &var);
        let out: Vec<(Rgb, f32)> = (0..n)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let (lp, np, ap) = (luminance(illum_ref[i]), normals[i], albedo[i]);
                let sigma = SIGMA_LUMINANCE * var_ref[i].sqrt() + 1e-6;
                let (mut sum, mut wsum, mut vsum) = (Rgb::ZERO, 0.0f32, 0.0f32);
                for (dy, ky) in KERNEL.iter().enumerate() {
                    let qy = y as isize + (dy as isize - 2) * step as isize;
                    if qy < 0 || qy >= h as isize {
                        continue;
                    }
                    for (dx, kx) in KERNEL.iter().enumerate() {
                        let qx = x as isize + (dx as isize - 2) * step as isize;
                        if qx < 0 || qx >= w as isize {
                            continue;
                        }
                        let q = qy as usize * w + qx as usize;
                        let wn = normal_weight(np, normals[q]);
                        let da = ap - albedo[q];
                        let wa = (-da.length_squared() / (SIGMA_ALBEDO * SIGMA_ALBEDO)).exp();
                        let wl = (-(lp - luminance(illum_ref[q])).abs() / sigma).exp();
                        let wt = kx * ky * wn * wa * wl;
                        sum += illum_ref[q] * wt;
                        wsum += wt;
                        vsum += wt * wt * var_ref[q];
                    }
                }
                if wsum > 0.0 {
                    (sum / wsum, vsum / (wsum * wsum))
                } else {
                    (illum_ref[i], var_ref[i])
                }
            })
            .collect();
        for (i, (c, v)) in out.into_iter().enumerate() {
            illum[i] = c;
            var[i] = v;
        }
    }
    Image {
        width: input.color.width,
        height: input.color.height,
        pixels: illum.iter().zip(&factors).map(|(&c, &f)| c * f).collect(),
    }
}

/// max(0, n_p·n_q)^128; pixels without a surface (zero normal) match only
/// each other.
#[inline]
fn normal_weight(a: Vec3, b: Vec3) -> f32 {
    match (a == Vec3::ZERO, b == Vec3::ZERO) {
        (true, true) => 1.0,
        (false, false) => a.dot(b).max(0.0).powi(SIGMA_NORMAL),
        _ => 0.0,
    }
}

/// A 3×3 box blur (edges clamped).
fn blur3(v: &[f32], w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            let (mut s, mut c) = (0.0f32, 0.0f32);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (qx, qy) = (x + dx, y + dy);
                    if qx >= 0 && qy >= 0 && (qx as usize) < w && (qy as usize) < h {
                        s += v[qy as usize * w + qx as usize];
                        c += 1.0;
                    }
                }
            }
            s / c
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> Rgb) -> Image {
        Image {
            width: w,
            height: h,
            pixels: (0..w * h).map(|i| f(i % w, i / w)).collect(),
        }
    }

    #[test]
    fn flat_noise_is_smoothed_and_albedo_edges_kept() {
        let (w, h) = (48u32, 32u32);
        // Albedo 0.8 on the left half, 0.1 on the right, illumination 1
        // plus noise of standard deviation 0.3.
        let albedo = image(w, h, |x, _| Rgb::splat(if x < w / 2 { 0.8 } else { 0.1 }));
        let normal = image(w, h, |_, _| Vec3::Z);
        let mut r = Pcg32::new(1, 0);
        let color = image(w, h, |x, y| {
            let _ = (x, y);
            Rgb::splat(1.0)
        });
        let noisy = Image {
            pixels: color
                .pixels
                .iter()
                .zip(&albedo.pixels)
                .map(|(&c, &a)| (c + Rgb::splat((r.next_f32() - 0.5) * 0.3 * 12f32.sqrt())) * a)
                .collect(),
            ..color.clone()
        };
        let variance: Vec<f32> = albedo.pixels.iter().map(|a| 0.09 * a.x * a.x).collect();
        let out = denoise(&DenoiseInput {
            color: &noisy,
            albedo: &albedo,
            normal: &normal,
            variance: &variance,
        });
        let truth = Image {
            pixels: albedo.pixels.clone(),
            ..albedo.clone()
        };
        let before = crate::film::metrics::rmse(&noisy, &truth).unwrap();
        let after = crate::film::metrics::rmse(&out, &truth).unwrap();
        assert!(after < 0.25 * before, "rmse {before} → {after}");
        // The columns either side of the edge keep their own albedo.
        for y in 0..h {
            let l = out.get(w / 2 - 1, y).x;
            let rr = out.get(w / 2, y).x;
            assert!((l - 0.8).abs() < 0.1, "row {y}: left of the edge {l}");
            assert!((rr - 0.1).abs() < 0.02, "row {y}: right of the edge {rr}");
        }
    }

    #[test]
    fn converged_images_pass_through() {
        let (w, h) = (16u32, 16u32);
        let color = image(w, h, |x, y| Rgb::new(x as f32 / 16.0, y as f32 / 16.0, 0.5));
        let albedo = image(w, h, |_, _| Rgb::splat(0.5));
        let normal = image(w, h, |_, _| Vec3::Y);
        let out = denoise(&DenoiseInput {
            color: &color,
            albedo: &albedo,
            normal: &normal,
            variance: &vec![0.0; (w * h) as usize],
        });
        for (a, b) in out.pixels.iter().zip(&color.pixels) {
            assert!((*a - *b).abs().max_element() < 1e-5, "{a} vs {b}");
        }
    }
}
