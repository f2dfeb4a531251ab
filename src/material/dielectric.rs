//! Dielectrics (glass, water): a smooth interface reflects and refracts by
//! the exact Fresnel equations and Snell's law; a rough one is a GGX
//! microfacet interface (Walter et al. 2007) sampled by visible normals.
//!
//! `eta` is the relative index of refraction inside/outside; the side is
//! told by the sign of cos θ (the normal points outside).
//!
//! **Radiance scaling.** Radiance crossing into a denser medium is
//! compressed into a smaller solid angle: L_t = (η_t/η_i)²·(1−F)·L_i
//! (Veach 1997, §5.2). In [`TransportMode::Radiance`] the transmitted
//! BSDF value is divided by η'² (η' = η_t/η_i of the crossing, as the
//! path is traced backwards from the camera); paths traced from the lights
//! ([`TransportMode::Importance`]) are not scaled.

use super::bsdf::{BsdfSample, TransportMode};
use super::layered::Lobes;
use super::microfacet::Microfacet;
use super::optics::{fresnel_dielectric, fresnel_of_cosines, refracted, snell};
use crate::color::Rgb;
use glam::{Vec2, Vec3};

/// A smooth or rough dielectric interface.
#[derive(Clone, Copy, Debug)]
pub struct DielectricBsdf {
    /// Relative index of refraction, inside over outside.
    pub eta: f32,
    /// Roughness; smooth below [`super::microfacet::SMOOTH_ALPHA`].
    pub microfacet: Microfacet,
    /// Multiplier of reflected light (Mitsuba's `specular_reflectance`).
    pub reflect_tint: Rgb,
    /// Multiplier of transmitted light (Mitsuba's `specular_transmittance`).
    pub transmit_tint: Rgb,
}

impl DielectricBsdf {
    /// The generalised half vector of (wo, wi) and the relative index of
    /// the crossing, or `None` if degenerate or back-facing.
    pub(super) fn half_vector(&self, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, bool)> {
        let (cos_o, cos_i) = (wo.z, wi.z);
        if cos_o == 0.0 || cos_i == 0.0 {
            return None;
        }
        let reflect = cos_o * cos_i > 0.0;
        let etap = if reflect {
            1.0
        } else if cos_o > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let wm = wi * etap + wo;
        if wm.length_squared() == 0.0 {
            return None;
        }
        let mut wm = wm.normalize();
        if wm.z < 0.0 {
            wm = -wm;
        }
        // Microfacets seen from behind contribute nothing.
        if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
            return None;
        }
        Some((wm, etap, reflect))
    }

    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        if self.eta == 1.0 || self.microfacet.is_smooth() {
            return Rgb::ZERO;
        }
        let Some((wm, etap, reflect)) = self.half_vector(wo, wi) else {
            return Rgb::ZERO;
        };
        let f = fresnel_dielectric(wo.dot(wm), self.eta);
        let (d, g) = (self.microfacet.d(wm), self.microfacet.g(wo, wi));
        if reflect {
            return self.reflect_tint * (d * g * f / (4.0 * wi.z * wo.z).abs());
        }
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2) * wi.z * wo.z;
        let mut ft = d * (1.0 - f) * g * (wi.dot(wm) * wo.dot(wm) / denom).abs();
        if mode == TransportMode::Radiance {
            ft /= etap * etap;
        }
        self.transmit_tint * ft
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.eta == 1.0 || self.microfacet.is_smooth() {
            return 0.0;
        }
        let Some((wm, etap, reflect)) = self.half_vector(wo, wi) else {
            return 0.0;
        };
        let r = fresnel_dielectric(wo.dot(wm), self.eta);
        let t = 1.0 - r;
        let pdf_m = self.microfacet.pdf_visible_normal(wo, wm);
        if reflect {
            pdf_m / (4.0 * wo.dot(wm).abs()) * r
        } else {
            let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
            pdf_m * wi.dot(wm).abs() / denom * t
        }
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if self.eta == 1.0 || self.microfacet.is_smooth() {
            return self.sample_delta(wo, u_lobe, mode);
        }
        self.sample_lobes(wo, u_lobe, u, mode, Lobes::Both)
    }

    pub(crate) fn delta_probability(&self, _wo: Vec3) -> f32 {
        if self.eta == 1.0 || self.microfacet.is_smooth() {
            1.0
        } else {
            0.0
        }
    }

    pub(crate) fn sample_delta(&self, wo: Vec3, u: f32, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 || !(self.eta == 1.0 || self.microfacet.is_smooth()) {
            return None;
        }
        // Snell's law once for the Fresnel reflectance and the refracted
        // direction (`fresnel_dielectric` and `refract` apart would each
        // solve it).
        let (cos_i, etap, cos_t) = snell(wo.z.clamp(-1.0, 1.0), self.eta);
        let r = cos_t.map_or(1.0, |cos_t| fresnel_of_cosines(cos_i, etap, cos_t));
        if u < r {
            return Some(BsdfSample::mirror(wo, r, self.reflect_tint));
        }
        let n = if wo.z < 0.0 { -Vec3::Z } else { Vec3::Z };
        let wi = refracted(wo, n, cos_i, etap, cos_t?);
        let mut f = self.transmit_tint * ((1.0 - r) / wi.z.abs());
        if mode == TransportMode::Radiance {
            // (A factor known ahead of `f`, not a division after it.)
            f *= 1.0 / (etap * etap);
        }
        Some(BsdfSample {
            wi,
            f,
            pdf: 1.0 - r,
            delta: true,
            eta: etap,
        })
    }

    pub(crate) fn has_smooth(&self) -> bool {
        !(self.eta == 1.0 || self.microfacet.is_smooth())
    }

    pub(crate) fn albedo(&self) -> Rgb {
        self.transmit_tint.max(self.reflect_tint).min(Rgb::ONE)
    }
}
