//! The Phong reflection model in radiometric units.
//!
//! Phong's model (1975) sums a diffuse term kd·max(n·l, 0) and a specular
//! term ks·max(r·v, 0)^s, r being l mirrored about n. trazo uses it as the
//! BRDF
//!
//! ```text
//! f(l, v) = kd/π + ks·(s + 2)/(2π)·max(r·v, 0)^s
//! ```
//!
//! so that the reflected radiance is `L = f·E`, with `E = I·max(n·l,0)/d²`
//! for a point light. The factors 1/π and (s + 2)/(2π) normalise the two
//! lobes (Lewis 1994, "Making Shaders More Physically Plausible"): a
//! surface with kd + ks ≤ 1 never reflects more light than it receives,
//! and the Whitted and path tracers agree on how bright it is.

use super::optics::reflect;
use crate::color::Rgb;
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};

/// The normalised Phong BRDF for unit directions `wi` (toward the light)
/// and `wo` (toward the viewer) about unit normal `n`; zero if either
/// direction is below the surface.
#[inline]
pub fn phong_brdf(kd: Rgb, ks: Rgb, shininess: f32, n: Vec3, wi: Vec3, wo: Vec3) -> Rgb {
    if n.dot(wi) <= 0.0 || n.dot(wo) <= 0.0 {
        return Rgb::ZERO;
    }
    let mut f = kd * FRAC_1_PI;
    if ks != Rgb::ZERO {
        let cos_alpha = reflect(wi, n).dot(wo);
        if cos_alpha > 0.0 {
            f += ks * ((shininess + 2.0) / (2.0 * PI) * cos_alpha.powf(shininess));
        }
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diffuse_part_is_albedo_over_pi() {
        let f = phong_brdf(
            Rgb::splat(0.6),
            Rgb::ZERO,
            10.0,
            Vec3::Z,
            Vec3::new(0.3, 0.0, 1.0).normalize(),
            Vec3::Z,
        );
        assert!((f - Rgb::splat(0.6 / PI)).length() < 1e-7);
        let below = phong_brdf(Rgb::ONE, Rgb::ZERO, 1.0, Vec3::Z, -Vec3::Z, Vec3::Z);
        assert_eq!(below, Rgb::ZERO);
    }

    #[test]
    fn specular_lobe_peaks_at_the_mirror_direction() {
        let wi = Vec3::new(1.0, 0.0, 1.0).normalize();
        let mirror = Vec3::new(-1.0, 0.0, 1.0).normalize();
        let s = 20.0;
        let peak = phong_brdf(Rgb::ZERO, Rgb::ONE, s, Vec3::Z, wi, mirror);
        assert!((peak.x - (s + 2.0) / (2.0 * PI)).abs() < 1e-4);
        let off = phong_brdf(Rgb::ZERO, Rgb::ONE, s, Vec3::Z, wi, Vec3::Z);
        let cos_a = mirror.dot(Vec3::Z);
        assert!((off.x - (s + 2.0) / (2.0 * PI) * cos_a.powf(s)).abs() < 1e-5);
    }

    #[test]
    fn normalised_lobe_conserves_energy_at_normal_incidence() {
        // ∫ f cosθ dω over the hemisphere, for wi = n, equals 1 for ks = 1:
        // ∫ (s+2)/(2π) cos^s θ cosθ dω = (s+2)/(2π)·2π/(s+2) = 1.
        let s = 8.0f32;
        let n_theta = 2000;
        let mut sum = 0.0f64;
        for i in 0..n_theta {
            let theta = (i as f32 + 0.5) / n_theta as f32 * PI / 2.0;
            let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
            let f = phong_brdf(Rgb::ZERO, Rgb::ONE, s, Vec3::Z, Vec3::Z, wo).x as f64;
            // dω = 2π sinθ dθ (the lobe is symmetric about n here).
            sum += f
                * theta.cos() as f64
                * 2.0
                * std::f64::consts::PI
                * theta.sin() as f64
                * (PI as f64 / 2.0 / n_theta as f64);
        }
        assert!((sum - 1.0).abs() < 1e-3, "{sum}");
    }
}
