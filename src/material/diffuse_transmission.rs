//! Diffuse transmission (pbrt-v4's `diffusetransmission`, Mitsuba 3's
//! `difftrans`): Lambertian reflection R/π on the side light arrives from
//! and Lambertian transmission T/π to the other side, without bending.
//! Sampled as pbrt-v4 samples it: reflection or transmission with
//! probabilities in proportion to max R and max T, then a cosine-weighted
//! direction on that side.

use super::bsdf::{BsdfSample, TransportMode, flip_z, same_hemisphere};
use crate::color::Rgb;
use crate::sampling::warp::{pdf_hemisphere_cosine, sample_hemisphere_cosine};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Diffuse reflection R and diffuse transmission T.
#[derive(Clone, Copy, Debug)]
pub struct DiffuseTransmissionBsdf {
    /// Reflectance R.
    pub reflectance: Rgb,
    /// Transmittance T.
    pub transmittance: Rgb,
}

impl DiffuseTransmissionBsdf {
    /// The probability of sampling reflection.
    #[inline]
    fn reflect_probability(&self) -> f32 {
        let (pr, pt) = (self.reflectance.max_element(), self.transmittance.max_element());
        if pr + pt > 0.0 { pr / (pr + pt) } else { 0.0 }
    }

    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        if same_hemisphere(wo, wi) {
            self.reflectance * FRAC_1_PI
        } else {
            self.transmittance * FRAC_1_PI
        }
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let pr = self.reflect_probability();
        let side = if same_hemisphere(wo, wi) { pr } else { 1.0 - pr };
        side * pdf_hemisphere_cosine(wi.z.abs())
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 || self.reflectance.max_element() + self.transmittance.max_element() <= 0.0 {
            return None;
        }
        let reflect = u_lobe < self.reflect_probability();
        let mut wi = sample_hemisphere_cosine(u);
        // On wo's side for reflection, the other for transmission.
        if (wo.z < 0.0) == reflect {
            wi = flip_z(wi);
        }
        let pdf = self.pdf(wo, wi);
        if pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.eval(wo, wi, mode),
            pdf,
            delta: false,
            eta: 1.0,
        })
    }

    pub(crate) fn delta_probability(&self, _wo: Vec3) -> f32 {
        0.0
    }

    pub(crate) fn sample_delta(&self, _wo: Vec3, _u: f32, _mode: TransportMode) -> Option<BsdfSample> {
        None
    }

    pub(crate) fn has_smooth(&self) -> bool {
        true
    }

    pub(crate) fn albedo(&self) -> Rgb {
        self.reflectance + self.transmittance
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::chi2::Chi2Test;
    use crate::sampling::rng::Pcg32;

    fn bsdf(r: f32, t: f32) -> DiffuseTransmissionBsdf {
        DiffuseTransmissionBsdf {
            reflectance: Rgb::new(r, 0.5 * r, 0.2 * r),
            transmittance: Rgb::new(t, 0.3 * t, 0.9 * t),
        }
    }

    /// Sampled directions follow the density `pdf` reports, from either
    /// side, for reflection and transmission in any proportion.
    #[test]
    fn samples_follow_the_density() {
        for (r, t) in [(0.25, 0.25), (0.9, 0.05), (0.0, 0.5), (0.7, 0.0)] {
            let b = bsdf(r, t);
            for wo in [
                Vec3::new(0.3, -0.2, 0.9).normalize(),
                Vec3::new(-0.5, 0.1, -0.6).normalize(),
            ] {
                let mut rng = Pcg32::new(5, 7);
                let result = Chi2Test::default().run(
                    |_| {
                        b.sample(
                            wo,
                            rng.next_f32(),
                            Vec2::new(rng.next_f32(), rng.next_f32()),
                            TransportMode::Radiance,
                        )
                        .map(|s| s.wi)
                    },
                    |wi| b.pdf(wo, wi) as f64,
                );
                assert!(result.p_value > 0.001, "R {r} T {t} wo {wo}: {result:?}");
            }
        }
    }

    /// The estimator f·|cos|/pdf of sampled directions averages to the
    /// albedo R + T (the integral of f·|cos| over the sphere), and each
    /// sample's value is f as `eval` gives it.
    #[test]
    fn reflected_and_transmitted_light_add_up_to_r_plus_t() {
        let b = bsdf(0.6, 0.3);
        let wo = Vec3::new(0.2, 0.4, 0.8).normalize();
        let mut rng = Pcg32::new(1, 2);
        let n = 200_000;
        let mut sum = Rgb::ZERO;
        for _ in 0..n {
            let s = b
                .sample(
                    wo,
                    rng.next_f32(),
                    Vec2::new(rng.next_f32(), rng.next_f32()),
                    TransportMode::Radiance,
                )
                .unwrap();
            assert_eq!(s.f, b.eval(wo, s.wi, TransportMode::Radiance));
            assert!((s.pdf - b.pdf(wo, s.wi)).abs() < 1e-6 * s.pdf);
            sum += s.f * s.wi.z.abs() / s.pdf;
        }
        let mean = sum / n as f32;
        let want = b.reflectance + b.transmittance;
        assert!((mean - want).abs().max_element() < 0.01, "{mean} vs {want}");
    }
}
