//! Conductors (metals): a perfect mirror when smooth, a GGX microfacet
//! surface (Walter et al. 2007) sampled by visible normals (Heitz 2018)
//! when rough. The Fresnel term comes from a complex index of refraction
//! η + ik per colour channel, from Schlick's approximation of a colour at
//! normal incidence, or is a constant reflectance (an ideal mirror).
//! Two-sided.

use super::bsdf::{BsdfSample, TransportMode, flip_z, reflect_local, same_hemisphere};
use super::microfacet::Microfacet;
use super::optics::{fresnel_conductor, fresnel_schlick};
use crate::color::Rgb;
use glam::{Vec2, Vec3};

/// How a conductor's reflectance depends on the angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConductorFresnel {
    /// Complex index of refraction per channel, relative to the outside.
    Complex {
        /// Real part η.
        eta: Rgb,
        /// Imaginary part k (absorption).
        k: Rgb,
    },
    /// Schlick's approximation from the reflectance at normal incidence.
    Schlick(Rgb),
    /// The same reflectance at every angle (an ideal mirror).
    Constant(Rgb),
}

impl ConductorFresnel {
    /// Reflectance for incidence cosine `cos`.
    #[inline]
    pub fn eval(&self, cos: f32) -> Rgb {
        match *self {
            ConductorFresnel::Complex { eta, k } => Rgb::new(
                fresnel_conductor(cos, eta.x, k.x),
                fresnel_conductor(cos, eta.y, k.y),
                fresnel_conductor(cos, eta.z, k.z),
            ),
            ConductorFresnel::Schlick(f0) => Rgb::new(
                fresnel_schlick(cos, f0.x),
                fresnel_schlick(cos, f0.y),
                fresnel_schlick(cos, f0.z),
            ),
            ConductorFresnel::Constant(r) => r,
        }
    }
}

/// A smooth or rough conductor.
#[derive(Clone, Copy, Debug)]
pub struct ConductorBsdf {
    /// Reflectance model.
    pub fresnel: ConductorFresnel,
    /// Colour multiplier (Mitsuba's `specular_reflectance`).
    pub tint: Rgb,
    /// Microfacet roughness; smooth below [`super::microfacet::SMOOTH_ALPHA`].
    pub microfacet: Microfacet,
}

impl ConductorBsdf {
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        if self.microfacet.is_smooth() || !same_hemisphere(wo, wi) {
            return Rgb::ZERO;
        }
        let (wo, wi) = if wo.z < 0.0 { (flip_z(wo), flip_z(wi)) } else { (wo, wi) };
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return Rgb::ZERO;
        }
        let h = h.normalize();
        let d = self.microfacet.d(h);
        let g = self.microfacet.g(wo, wi);
        self.tint * self.fresnel.eval(wo.dot(h)) * (d * g / (4.0 * wo.z * wi.z))
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.microfacet.is_smooth() || !same_hemisphere(wo, wi) {
            return 0.0;
        }
        let (wo, wi) = if wo.z < 0.0 { (flip_z(wo), flip_z(wi)) } else { (wo, wi) };
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return 0.0;
        }
        let h = h.normalize();
        // Reflection maps normals to directions with Jacobian 1/(4 |wo·h|).
        self.microfacet.pdf_visible_normal(wo, h) / (4.0 * wo.dot(h).abs())
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if self.microfacet.is_smooth() {
            return self.sample_delta(wo, u_lobe, mode);
        }
        if wo.z == 0.0 {
            return None;
        }
        let flip = wo.z < 0.0;
        let wo_up = if flip { flip_z(wo) } else { wo };
        let h = self.microfacet.sample_visible_normal(wo_up, u);
        let wi_up = 2.0 * wo_up.dot(h) * h - wo_up;
        if wi_up.z <= 0.0 {
            return None;
        }
        let wi = if flip { flip_z(wi_up) } else { wi_up };
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
        if self.microfacet.is_smooth() { 1.0 } else { 0.0 }
    }

    pub(crate) fn sample_delta(&self, wo: Vec3, _u: f32, _mode: TransportMode) -> Option<BsdfSample> {
        if !self.microfacet.is_smooth() || wo.z == 0.0 {
            return None;
        }
        let wi = reflect_local(wo);
        Some(BsdfSample {
            wi,
            f: self.tint * self.fresnel.eval(wo.z.abs()) / wi.z.abs(),
            pdf: 1.0,
            delta: true,
            eta: 1.0,
        })
    }

    pub(crate) fn has_smooth(&self) -> bool {
        !self.microfacet.is_smooth()
    }

    pub(crate) fn albedo(&self) -> Rgb {
        (self.tint * self.fresnel.eval(1.0)).min(Rgb::ONE)
    }
}

/// Complex indices of refraction (η, k) of common metals at the red,
/// green and blue primaries (about 650, 550 and 450 nm), as commonly
/// tabulated from Palik's handbook; used by `material = "Au"` and friends.
pub fn metal_ior(name: &str) -> Option<(Rgb, Rgb)> {
    Some(match name {
        "Au" | "gold" => (Rgb::new(0.143, 0.374, 1.442), Rgb::new(3.983, 2.385, 1.603)),
        "Ag" | "silver" => (Rgb::new(0.155, 0.117, 0.138), Rgb::new(4.828, 3.122, 2.147)),
        "Cu" | "copper" => (Rgb::new(0.200, 0.924, 1.102), Rgb::new(3.912, 2.452, 2.142)),
        "Al" | "aluminium" | "aluminum" => (Rgb::new(1.657, 0.880, 0.521), Rgb::new(9.224, 6.270, 4.837)),
        _ => return None,
    })
}

/// The names [`metal_ior`] knows.
pub const METAL_NAMES: [&str; 4] = ["Au", "Ag", "Cu", "Al"];
