//! Plastic: a diffuse base under a dielectric coat, smooth or rough, with
//! the formulation of Mitsuba's `plastic` and `roughplastic` (after
//! Weidlich and Wilkie 2007, "Arbitrarily Layered Micro-Facet Surfaces"):
//!
//! ```text
//! smooth:  f = ks·F(θo)·δ(mirror) + ρ'/(π η²)·(1 − F(θi))·(1 − F(θo))
//! rough:   f = ks·F(wo·h)·D(h)·G/(4 cos θo cos θi) + ρ'/(π η²)·T(θi)·T(θo)
//! ρ' = ρ / (1 − R_int)          (or ρ / (1 − ρ·R_int) when `nonlinear`)
//! ```
//!
//! R_int is the fraction of diffuse light the coat reflects back inside
//! (the hemispherical average of the Fresnel reflectance seen from within);
//! T(θ) is the fraction of light the rough coat lets through at incidence
//! θ, tabulated once per material by integrating the coat's microfacet
//! transmission lobe (as Mitsuba 3 does: light that the microfacets shadow
//! on its way through is lost, so T < 1 − R).
//! Two-sided.

use super::bsdf::{BsdfSample, TransportMode, flip_z, reflect_local, same_hemisphere};
use super::microfacet::Microfacet;
use super::optics::{fresnel_dielectric, fresnel_diffuse_reflectance};
use crate::color::Rgb;
use crate::sampling::warp::{pdf_hemisphere_cosine, sample_hemisphere_cosine};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Entries of the transmittance table, from cos θ = 0 to 1.
pub const TABLE_SIZE: usize = 64;

/// Precomputed coat transmittance of a rough plastic.
#[derive(Clone, Debug, PartialEq)]
pub struct CoatTables {
    /// T(μ) = 1 − (albedo of the coat's reflection lobe) at μ = i/63.
    pub external_transmittance: [f32; TABLE_SIZE],
    /// Fraction of diffuse light reflected back by the coat from inside.
    pub internal_reflectance: f32,
}

/// Directional albedo of a rough dielectric interface's reflection lobe,
/// ∫ F·D·G/(4 cos θo) dωi, by quadrature over visible normals: with m drawn
/// from D_wo, the integrand's weight is F(wo·m)·G/G1(wo) = F·G1(wi).
pub fn rough_reflection_albedo(microfacet: &Microfacet, cos_o: f32, eta: f32) -> f32 {
    let cos_o = cos_o.clamp(1e-6, 1.0);
    let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
    let n = 48;
    let mut sum = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            let m = microfacet.sample_visible_normal(wo, u);
            let wi = 2.0 * wo.dot(m) * m - wo;
            if wi.z <= 0.0 {
                continue;
            }
            let weight = fresnel_dielectric(wo.dot(m), eta) * microfacet.g(wo, wi) / microfacet.g1(wo);
            debug_assert!(weight.is_finite());
            sum += weight as f64;
        }
    }
    (sum / (n * n) as f64) as f32
}

/// Directional albedo of a rough dielectric interface's transmission lobe,
/// by quadrature over visible normals: with m drawn from D_wo, the weight of
/// the refracted direction wt is (1 − F(wo·m))·G1(wt).
pub fn rough_transmission_albedo(microfacet: &Microfacet, cos_o: f32, eta: f32) -> f32 {
    let cos_o = cos_o.clamp(1e-6, 1.0);
    let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
    let n = 48;
    let mut sum = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            let m = microfacet.sample_visible_normal(wo, u);
            let Some((wt, _)) = super::optics::refract(wo, m, eta) else {
                continue; // total internal reflection
            };
            if wt.z >= 0.0 {
                continue;
            }
            sum += ((1.0 - fresnel_dielectric(wo.dot(m), eta)) * microfacet.g1(wt)) as f64;
        }
    }
    (sum / (n * n) as f64) as f32
}

impl CoatTables {
    /// Tables for a coat of roughness `microfacet` and relative index `eta`, on the
    /// same grid as Mitsuba's (so that both renderers agree).
    pub fn new(microfacet: &Microfacet, eta: f32) -> CoatTables {
        let mut external_transmittance = [0.0; TABLE_SIZE];
        let mut internal = 0.0f64;
        for (i, t) in external_transmittance.iter_mut().enumerate() {
            let mu = (i as f32 / (TABLE_SIZE - 1) as f32).max(1e-6);
            *t = rough_transmission_albedo(microfacet, mu, eta);
            internal += (rough_reflection_albedo(microfacet, mu, 1.0 / eta) * mu) as f64;
        }
        CoatTables {
            external_transmittance,
            internal_reflectance: (2.0 * internal / TABLE_SIZE as f64) as f32,
        }
    }

    /// T(cos θ), linearly interpolated.
    #[inline]
    pub fn transmittance(&self, cos: f32) -> f32 {
        let x = cos.clamp(0.0, 1.0) * (TABLE_SIZE - 1) as f32;
        let i = (x as usize).min(TABLE_SIZE - 2);
        let w = x - i as f32;
        self.external_transmittance[i] * (1.0 - w) + self.external_transmittance[i + 1] * w
    }
}

/// Fraction of diffuse light a smooth coat of relative index `eta` reflects
/// back inside.
pub fn smooth_internal_reflectance(eta: f32) -> f32 {
    fresnel_diffuse_reflectance(1.0 / eta)
}

/// A plastic BSDF.
#[derive(Clone, Copy, Debug)]
pub struct PlasticBsdf<'a> {
    /// Diffuse reflectance ρ of the base.
    pub diffuse: Rgb,
    /// Relative index of refraction of the coat.
    pub eta: f32,
    /// Coat roughness; smooth below [`super::microfacet::SMOOTH_ALPHA`].
    pub microfacet: Microfacet,
    /// Multiplier of the coat's reflection.
    pub specular_tint: Rgb,
    /// Whether the base's colour saturates with internal scattering.
    pub nonlinear: bool,
    /// Share of samples steered to the coat: s̄/(s̄ + d̄) of the mean colours.
    pub specular_weight: f32,
    /// R_int for the smooth coat.
    pub smooth_internal_reflectance: f32,
    /// Tables of the rough coat (required when rough).
    pub tables: Option<&'a CoatTables>,
}

impl PlasticBsdf<'_> {
    fn rough(&self) -> Option<&CoatTables> {
        if self.microfacet.is_smooth() { None } else { self.tables }
    }

    /// ρ' = ρ/(1 − R_int), or ρ/(1 − ρ·R_int) when nonlinear.
    fn base(&self, r_int: f32) -> Rgb {
        let d = self.diffuse;
        if self.nonlinear {
            d / (Rgb::ONE - d * r_int)
        } else {
            d / (1.0 - r_int)
        }
    }

    /// Probability of sampling the coat for `wo` (upper hemisphere).
    fn specular_probability(&self, cos_o: f32) -> f32 {
        let sw = self.specular_weight;
        let (ps, pd) = match self.rough() {
            Some(t) => {
                let t_o = t.transmittance(cos_o);
                ((1.0 - t_o) * sw, t_o * (1.0 - sw))
            }
            None => {
                let f_o = fresnel_dielectric(cos_o, self.eta);
                (f_o * sw, (1.0 - f_o) * (1.0 - sw))
            }
        };
        if ps + pd > 0.0 { ps / (ps + pd) } else { 0.0 }
    }

    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        if !same_hemisphere(wo, wi) {
            return Rgb::ZERO;
        }
        let (wo, wi) = if wo.z < 0.0 { (flip_z(wo), flip_z(wi)) } else { (wo, wi) };
        let inv_eta2 = 1.0 / (self.eta * self.eta);
        match self.rough() {
            Some(t) => {
                let h = (wo + wi).normalize();
                let spec = fresnel_dielectric(wo.dot(h), self.eta) * self.microfacet.d(h) * self.microfacet.g(wo, wi)
                    / (4.0 * wo.z * wi.z);
                let diff = self.base(t.internal_reflectance)
                    * (FRAC_1_PI * inv_eta2 * t.transmittance(wi.z) * t.transmittance(wo.z));
                self.specular_tint * spec + diff
            }
            None => {
                let f_o = fresnel_dielectric(wo.z, self.eta);
                let f_i = fresnel_dielectric(wi.z, self.eta);
                self.base(self.smooth_internal_reflectance) * (FRAC_1_PI * inv_eta2 * (1.0 - f_o) * (1.0 - f_i))
            }
        }
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !same_hemisphere(wo, wi) {
            return 0.0;
        }
        let (wo, wi) = if wo.z < 0.0 { (flip_z(wo), flip_z(wi)) } else { (wo, wi) };
        let ps = self.specular_probability(wo.z);
        let mut pdf = (1.0 - ps) * pdf_hemisphere_cosine(wi.z);
        if self.rough().is_some() {
            let h = (wo + wi).normalize();
            pdf += ps * self.microfacet.pdf_visible_normal(wo, h) / (4.0 * wo.dot(h).abs());
        }
        pdf
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let flip = wo.z < 0.0;
        let wo_up = if flip { flip_z(wo) } else { wo };
        let ps = self.specular_probability(wo_up.z);
        if u_lobe < ps && self.rough().is_none() {
            let mut s = self.sample_delta(wo, 0.0, mode)?;
            s.pdf = ps;
            return Some(s);
        }
        let wi_up = if u_lobe < ps {
            let h = self.microfacet.sample_visible_normal(wo_up, u);
            2.0 * wo_up.dot(h) * h - wo_up
        } else {
            sample_hemisphere_cosine(u)
        };
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

    pub(crate) fn delta_probability(&self, wo: Vec3) -> f32 {
        if self.rough().is_some() {
            0.0
        } else {
            self.specular_probability(wo.z.abs())
        }
    }

    pub(crate) fn sample_delta(&self, wo: Vec3, _u: f32, _mode: TransportMode) -> Option<BsdfSample> {
        if self.rough().is_some() || wo.z == 0.0 {
            return None;
        }
        let wi = reflect_local(wo);
        let f_o = fresnel_dielectric(wo.z.abs(), self.eta);
        Some(BsdfSample {
            wi,
            f: self.specular_tint * (f_o / wi.z.abs()),
            pdf: 1.0,
            delta: true,
            eta: 1.0,
        })
    }

    pub(crate) fn has_smooth(&self) -> bool {
        true
    }

    pub(crate) fn albedo(&self) -> Rgb {
        self.diffuse
    }
}
