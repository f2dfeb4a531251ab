//! Phase functions: the angular distribution of light scattered in a
//! medium, the volume's counterpart of a BSDF.
//!
//! Directions follow the BSDF convention: `wo` points back along the
//! incoming path (toward the viewer), `wi` away from the scattering point
//! (toward the light), both unit length.

use crate::sampling::warp::{orthonormal_basis, pdf_sphere_uniform, sample_sphere_uniform};
use glam::{Vec2, Vec3};

/// A phase function.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Phase {
    /// The same in every direction: 1/(4π).
    Isotropic,
    /// Henyey and Greenstein's (1941) one-parameter lobe; `g` in (−1, 1)
    /// is the mean cosine of the scattering angle (g > 0: forward).
    HenyeyGreenstein(f32),
}

/// A sampled direction; the phase functions here are sampled exactly, so
/// the value equals the density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseSample {
    /// The sampled direction (unit length).
    pub wi: Vec3,
    /// The phase function's value, which is also the density per steradian.
    pub pdf: f32,
}

/// The Henyey–Greenstein density for the cosine between the directions of
/// propagation before and after scattering.
#[inline]
fn henyey_greenstein(cos_propagation: f32, g: f32) -> f32 {
    let denom = 1.0 + g * g - 2.0 * g * cos_propagation;
    (1.0 - g * g) / (4.0 * std::f32::consts::PI * denom * denom.max(1e-12).sqrt())
}

impl Phase {
    /// Henyey–Greenstein with `g` kept inside (−1, 1), where it is a
    /// distribution; 0 is isotropic.
    pub fn henyey_greenstein(g: f32) -> Phase {
        if g == 0.0 {
            Phase::Isotropic
        } else {
            Phase::HenyeyGreenstein(g.clamp(-0.999, 0.999))
        }
    }

    /// The value p(wo, wi) (which is also the sampling density).
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            Phase::Isotropic => pdf_sphere_uniform(),
            // The path travels along −wo before and along wi after.
            Phase::HenyeyGreenstein(g) => henyey_greenstein(-wo.dot(wi), g),
        }
    }

    /// Samples `wi` for `wo` (pbrt-v4, section 11.3.1: the inverted CDF of
    /// the cosine, then a uniform azimuth).
    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2) -> PhaseSample {
        match *self {
            Phase::Isotropic => PhaseSample {
                wi: sample_sphere_uniform(u),
                pdf: pdf_sphere_uniform(),
            },
            Phase::HenyeyGreenstein(g) => {
                let cos = if g.abs() < 1e-3 {
                    1.0 - 2.0 * u.x
                } else {
                    let s = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
                    (1.0 + g * g - s * s) / (2.0 * g)
                }
                .clamp(-1.0, 1.0);
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let phi = 2.0 * std::f32::consts::PI * u.y;
                let forward = -wo;
                let (t, b) = orthonormal_basis(forward);
                let wi = (t * (sin * phi.cos()) + b * (sin * phi.sin()) + forward * cos).normalize();
                PhaseSample {
                    wi,
                    pdf: henyey_greenstein(cos, g),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// Both phase functions integrate to one over the sphere, and their
    /// sampling density is their value (estimated by uniform sampling).
    #[test]
    fn phase_functions_are_normalised_and_sampled_by_their_value() {
        let wo = Vec3::new(0.3, -0.5, 0.8).normalize();
        for phase in [
            Phase::Isotropic,
            Phase::henyey_greenstein(0.7),
            Phase::henyey_greenstein(-0.4),
        ] {
            let mut rng = Pcg32::new(7, 0);
            let n = 200_000;
            let mut integral = 0.0f64;
            let mut mean_cos = 0.0f64;
            for _ in 0..n {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let w = sample_sphere_uniform(u);
                integral += (phase.eval(wo, w) / pdf_sphere_uniform()) as f64;
                let s = phase.sample(wo, Vec2::new(rng.next_f32(), rng.next_f32()));
                assert!(
                    (s.pdf - phase.eval(wo, s.wi)).abs() <= 1e-3 * s.pdf.max(1.0),
                    "{phase:?}"
                );
                mean_cos += (-wo).dot(s.wi) as f64;
            }
            integral /= n as f64;
            mean_cos /= n as f64;
            // Uniform estimates of a lobe with g = 0.7: relative standard
            // error about 1/sqrt(n)·4 (the lobe's peak over its mean).
            assert!((integral - 1.0).abs() < 0.05, "{phase:?}: {integral}");
            let g = match phase {
                Phase::Isotropic => 0.0,
                Phase::HenyeyGreenstein(g) => g as f64,
            };
            // The mean cosine of HG is g; its standard error is below 1/sqrt(n).
            assert!((mean_cos - g).abs() < 5.0 / (n as f64).sqrt(), "{phase:?}: {mean_cos}");
        }
    }
}
