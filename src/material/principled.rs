//! Disney's principled BSDF (Burley 2012, "Physically-Based Shading at
//! Disney"; Burley 2015, "Extending the Disney BRDF to a BSDF with
//! Integrated Subsurface Scattering"), term for term as Mitsuba 3's
//! `principled` evaluates it, so that scenes written for Mitsuba look the
//! same:
//!
//! - a GGX specular lobe (anisotropic: α = roughness² stretched by
//!   √(1 − 0.9·anisotropic)) whose Fresnel term blends the dielectric one,
//!   a tint toward the base colour and the metal's Schlick term;
//! - GGX specular transmission of weight (1 − metallic)·spec_trans, tinted
//!   by √base_color;
//! - Disney's diffuse with retro-reflection, flattened toward Hanrahan and
//!   Krueger's subsurface approximation by `flatness`, and a sheen lobe,
//!   all of weight (1 − metallic)·(1 − spec_trans);
//! - a clearcoat of GTR1 normals (α from 0.1 to 0.001 as clearcoat_gloss
//!   goes from 0 to 1), Schlick's Fresnel from 0.04 and Smith masking of
//!   α = 0.25, written as Mitsuba writes it (0.25·clearcoat·F·D·G, without
//!   the 1/(4 cos θi cos θo) of a microfacet lobe).
//!
//! The back side scatters only by the specular lobes, with the plain
//! dielectric Fresnel term (Mitsuba's convention). Directions are sampled
//! by lobe (cosine for the diffuse lobes, visible GGX normals for the
//! specular ones, GTR1 normals for the clearcoat), with lobe probabilities
//! that depend only on `wo` (the dielectric Fresnel at the macro normal
//! stands for the microfacet's), and weighed by the density of the whole
//! mixture.

use super::bsdf::{BsdfSample, TransportMode};
use super::microfacet::{Microfacet, MicrofacetDistribution};
use super::optics::{fresnel_dielectric, reflect, refract};
use crate::color::{Rgb, luminance};
use crate::sampling::warp::{pdf_hemisphere_cosine, sample_hemisphere_cosine};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// The principled BSDF at one point, its parameters already read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrincipledBsdf {
    /// Base colour: diffuse albedo, metal reflectance at normal incidence.
    pub base_color: Rgb,
    /// Perceptual roughness (α = roughness²).
    pub roughness: f32,
    /// Anisotropy of the specular lobes, 0 to 1.
    pub anisotropic: f32,
    /// Metal (1) or dielectric (0).
    pub metallic: f32,
    /// Share of the dielectric that transmits specularly.
    pub spec_trans: f32,
    /// Tint of the dielectric's specular reflection toward the base colour.
    pub spec_tint: f32,
    /// Weight of the sheen lobe.
    pub sheen: f32,
    /// Tint of the sheen toward the base colour.
    pub sheen_tint: f32,
    /// Blend of the diffuse lobe toward the subsurface approximation.
    pub flatness: f32,
    /// Weight of the clearcoat.
    pub clearcoat: f32,
    /// Glossiness of the clearcoat.
    pub clearcoat_gloss: f32,
    /// Share of the thin form's diffuse light that is transmitted.
    pub diff_trans: f32,
    /// Index of refraction inside, relative to the outside (of the sheet,
    /// for the thin form).
    pub eta: f32,
    /// The thin form (Mitsuba's `principledthin`): a sheet seen the same
    /// from both sides, without metal or clearcoat.
    pub thin: bool,
}

/// The principled BSDF's parameters, as textures (`T = Texture`) or as a
/// scene description's colour sources: the base colour, and the rest read
/// by their first channel.
#[derive(Clone, Debug, PartialEq)]
pub struct PrincipledParams<T> {
    /// Base colour.
    pub base_color: T,
    /// Perceptual roughness.
    pub roughness: T,
    /// Anisotropy.
    pub anisotropic: T,
    /// Metal or dielectric.
    pub metallic: T,
    /// Specular transmission.
    pub spec_trans: T,
    /// Specular tint.
    pub spec_tint: T,
    /// Sheen.
    pub sheen: T,
    /// Sheen tint.
    pub sheen_tint: T,
    /// Flatness (the subsurface approximation).
    pub flatness: T,
    /// Clearcoat.
    pub clearcoat: T,
    /// Clearcoat glossiness.
    pub clearcoat_gloss: T,
    /// Diffuse transmission of the thin form, 0 to 2 as Mitsuba's
    /// `principledthin` takes it (half of it is the transmitted share).
    pub diff_trans: T,
}

impl<T> PrincipledParams<T> {
    /// The parameters with their names, in a fixed order.
    pub fn named(&self) -> [(&'static str, &T); 12] {
        [
            ("base_color", &self.base_color),
            ("roughness", &self.roughness),
            ("anisotropic", &self.anisotropic),
            ("metallic", &self.metallic),
            ("spec_trans", &self.spec_trans),
            ("spec_tint", &self.spec_tint),
            ("sheen", &self.sheen),
            ("sheen_tint", &self.sheen_tint),
            ("flatness", &self.flatness),
            ("clearcoat", &self.clearcoat),
            ("clearcoat_gloss", &self.clearcoat_gloss),
            ("diff_trans", &self.diff_trans),
        ]
    }

    /// Each parameter mapped by `f`.
    pub fn map<U>(&self, mut f: impl FnMut(&T) -> U) -> PrincipledParams<U> {
        PrincipledParams {
            base_color: f(&self.base_color),
            roughness: f(&self.roughness),
            anisotropic: f(&self.anisotropic),
            metallic: f(&self.metallic),
            spec_trans: f(&self.spec_trans),
            spec_tint: f(&self.spec_tint),
            sheen: f(&self.sheen),
            sheen_tint: f(&self.sheen_tint),
            flatness: f(&self.flatness),
            clearcoat: f(&self.clearcoat),
            clearcoat_gloss: f(&self.clearcoat_gloss),
            diff_trans: f(&self.diff_trans),
        }
    }
}

impl PrincipledParams<crate::texture::Texture> {
    /// The BSDF at `tc`: the base colour as it is, the others' first
    /// channels clamped to [0, 1] as Disney's parameters are.
    #[inline]
    pub fn bsdf_at(
        &self,
        textures: &crate::texture::TextureStore,
        tc: &crate::texture::TexCoord,
        eta: f32,
        thin: bool,
    ) -> PrincipledBsdf {
        let x = |t: &crate::texture::Texture| t.eval(textures, tc).x.clamp(0.0, 1.0);
        PrincipledBsdf {
            base_color: self.base_color.eval(textures, tc).max(Rgb::ZERO),
            roughness: x(&self.roughness),
            anisotropic: x(&self.anisotropic),
            metallic: x(&self.metallic),
            spec_trans: x(&self.spec_trans),
            spec_tint: x(&self.spec_tint),
            sheen: x(&self.sheen),
            sheen_tint: x(&self.sheen_tint),
            flatness: x(&self.flatness),
            clearcoat: x(&self.clearcoat),
            clearcoat_gloss: x(&self.clearcoat_gloss),
            diff_trans: 0.5 * self.diff_trans.eval(textures, tc).x.clamp(0.0, 2.0),
            eta,
            thin,
        }
    }
}

/// Mitsuba's default index, from its default `specular` of 0.5.
pub fn eta_from_specular(specular: f32) -> f32 {
    2.0 / (1.0 - (0.08 * specular).sqrt()) - 1.0
}

/// (1 − cos)⁵, clamped: Schlick's weight.
#[inline]
fn schlick_weight(cos: f32) -> f32 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// The weight of Schlick's approximation F = R0 + (1 − R0)·w at an
/// interface of index `eta` met with cosine `cos_i` (negative: from
/// inside): w from the incident cosine when entering the denser side,
/// from the transmitted one otherwise (Mitsuba's `calc_schlick`).
#[inline]
fn schlick_blend(cos_i: f32, eta: f32) -> f32 {
    let eta_it = if cos_i >= 0.0 { eta } else { 1.0 / eta };
    if eta_it > 1.0 {
        schlick_weight(cos_i.abs())
    } else {
        let cos_t2 = 1.0 - (1.0 - cos_i * cos_i) / (eta_it * eta_it);
        schlick_weight(cos_t2.max(0.0).sqrt())
    }
}

/// ((η − 1)/(η + 1))²: the reflectance at normal incidence.
#[inline]
fn r0_of(eta: f32) -> f32 {
    ((eta - 1.0) / (eta + 1.0)).powi(2)
}

/// Smith's masking of `v` for GGX of roughness `alpha_x`, `alpha_y`,
/// zero where the microfacet `m` faces away from `v` (Mitsuba's
/// `smith_g1`).
#[inline]
fn masking(mf: &Microfacet, v: Vec3, m: Vec3) -> f32 {
    if v.dot(m) * v.z <= 0.0 { 0.0 } else { mf.g1(v) }
}

/// Berry's distribution (GTR1, Burley 2012, eq. 4) of roughness `alpha`,
/// at the microfacet cosine `cos`.
#[inline]
fn gtr1(cos: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let d = (a2 - 1.0) / (PI * a2.ln() * (1.0 + (a2 - 1.0) * cos * cos));
    if d * cos > 1e-20 { d } else { 0.0 }
}

/// A GTR1 normal, distributed as D(m)·cos θm.
#[inline]
fn sample_gtr1(u: Vec2, alpha: f32) -> Vec3 {
    let a2 = alpha * alpha;
    let (sin_phi, cos_phi) = (2.0 * PI * u.x).sin_cos();
    let cos2 = (1.0 - a2.powf(1.0 - u.y)) / (1.0 - a2);
    let sin_theta = (1.0 - cos2).max(0.0).sqrt();
    Vec3::new(cos_phi * sin_theta, sin_phi * sin_theta, cos2.max(0.0).sqrt())
}

/// What (wo, wi) share in eval and pdf: the generalised half vector,
/// pointing outside, and how the pair meets it.
struct Pair {
    wh: Vec3,
    reflect: bool,
    refract: bool,
    front: bool,
    /// Index along the path (η from the outside, 1/η from the inside).
    eta_path: f32,
    /// Both directions see the microfacet's side that a reflection (or a
    /// refraction) needs.
    reflect_ok: bool,
    refract_ok: bool,
}

impl PrincipledBsdf {
    /// The GGX distribution of the specular lobes.
    #[inline]
    fn specular(&self) -> Microfacet {
        let r2 = self.roughness * self.roughness;
        let aspect = (1.0 - 0.9 * self.anisotropic.clamp(0.0, 1.0)).sqrt();
        Microfacet::new(
            MicrofacetDistribution::Ggx,
            (r2 / aspect).max(0.001),
            (r2 * aspect).max(0.001),
        )
    }

    /// Weights of the two major lobes: the dielectric's reflection
    /// (diffuse, sheen) and its transmission.
    #[inline]
    fn lobe_weights(&self) -> (f32, f32) {
        let dielectric = 1.0 - self.metallic;
        (dielectric * (1.0 - self.spec_trans), dielectric * self.spec_trans)
    }

    #[inline]
    fn pair(&self, wo: Vec3, wi: Vec3) -> Option<Pair> {
        let (ci, co) = (wo.z, wi.z);
        if ci == 0.0 {
            return None;
        }
        let reflect = ci * co > 0.0;
        let refract = ci * co < 0.0;
        let front = ci > 0.0;
        let eta_path = if front { self.eta } else { 1.0 / self.eta };
        let wh = (wo + wi * if reflect { 1.0 } else { eta_path }).try_normalize()?;
        let wh = if wh.z < 0.0 { -wh } else { wh };
        let side = wh * ci.signum();
        let (a, b) = (wo.dot(side) > 0.0, wi.dot(side));
        Some(Pair {
            wh,
            reflect,
            refract,
            front,
            eta_path,
            reflect_ok: a && b > 0.0,
            refract_ok: a && b < 0.0,
        })
    }

    /// The specular Fresnel term: on the front, the dielectric's, tinted
    /// and blended with the metal's; on the back, the dielectric's alone,
    /// weighted as the transmitting lobe.
    #[inline]
    fn specular_fresnel(&self, f_dielectric: f32, cos_h: f32, front: bool) -> Rgb {
        let (_, transmit) = self.lobe_weights();
        if !front {
            return Rgb::splat(transmit * f_dielectric);
        }
        let blend = schlick_blend(cos_h, self.eta);
        let schlick = |r0: Rgb| r0 + (Rgb::ONE - r0) * blend;
        let metal = self.metallic * schlick(self.base_color);
        let lum = luminance(self.base_color);
        let tint = if lum > 0.0 { self.base_color / lum } else { Rgb::ONE };
        let eta_it = if cos_h >= 0.0 { self.eta } else { 1.0 / self.eta };
        let tinted = (1.0 - self.metallic) * self.spec_tint * schlick(tint * r0_of(eta_it));
        Rgb::splat((1.0 - self.metallic) * (1.0 - self.spec_tint) * f_dielectric) + metal + tinted
    }

    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        if self.thin {
            return self.thin_eval(wo, wi);
        }
        let Some(p) = self.pair(wo, wi) else {
            return Rgb::ZERO;
        };
        let (ci, co) = (wo.z, wi.z);
        if co == 0.0 {
            return Rgb::ZERO;
        }
        let (reflection, transmission) = self.lobe_weights();
        let mf = self.specular();
        let cos_h = wo.dot(p.wh);
        let f_dielectric = fresnel_dielectric(cos_h, self.eta);
        let d = mf.d(p.wh);
        let g = masking(&mf, wo, p.wh) * masking(&mf, wi, p.wh);
        // Mitsuba's value is f·|cos θi|; it is divided out at the end.
        let mut value = Rgb::ZERO;
        if p.reflect && p.reflect_ok && f_dielectric > 0.0 {
            value += self.specular_fresnel(f_dielectric, cos_h, p.front) * (d * g / (4.0 * ci.abs()));
        }
        if transmission > 0.0 && p.refract && p.refract_ok && f_dielectric < 1.0 {
            let scale = if mode == TransportMode::Radiance {
                1.0 / (p.eta_path * p.eta_path)
            } else {
                1.0
            };
            let (oh, ih) = (cos_h, wi.dot(p.wh));
            let t = scale * (1.0 - f_dielectric) * d * g * p.eta_path * p.eta_path * oh * ih
                / (ci * (oh + p.eta_path * ih).powi(2));
            value += self.base_color.max(Rgb::ZERO).powf(0.5) * (transmission * t.abs());
        }
        if self.clearcoat > 0.0 && p.reflect && p.reflect_ok && p.front {
            let f_cc = 0.04 + 0.96 * schlick_blend(cos_h, self.eta);
            let d_cc = gtr1(p.wh.z, lerp(0.1, 0.001, self.clearcoat_gloss));
            let coat = Microfacet::isotropic(0.25);
            let g_cc = masking(&coat, wo, p.wh) * masking(&coat, wi, p.wh);
            value += Rgb::splat(0.25 * self.clearcoat * f_cc * d_cc * g_cc * co.abs());
        }
        if reflection > 0.0 && p.reflect && p.front {
            let (f_o, f_i) = (schlick_weight(co.abs()), schlick_weight(ci.abs()));
            let diffuse = (1.0 - 0.5 * f_i) * (1.0 - 0.5 * f_o);
            let cos_d = p.wh.dot(wi);
            let rr = 2.0 * self.roughness * cos_d * cos_d;
            let retro = rr * (f_o + f_i + f_o * f_i * (rr - 1.0));
            let fss90 = 0.5 * rr;
            let fss = lerp(1.0, fss90, f_o) * lerp(1.0, fss90, f_i);
            let subsurface = 1.25 * (fss * (1.0 / (co.abs() + ci.abs()) - 0.5) + 0.5);
            let shape = lerp(diffuse + retro, subsurface, self.flatness);
            value += self.base_color * (reflection * co.abs() * shape / PI);
            if self.sheen > 0.0 && 1.0 - self.metallic > 0.0 {
                let lum = luminance(self.base_color);
                let tint = if lum > 0.0 { self.base_color / lum } else { Rgb::ONE };
                let color = Rgb::ONE + (tint - Rgb::ONE) * self.sheen_tint;
                value += color * (self.sheen * (1.0 - self.metallic) * schlick_weight(cos_d.abs()) * co.abs());
            }
        }
        value / co.abs()
    }

    /// Lobe probabilities (specular reflection, transmission, clearcoat,
    /// diffuse) for `wo`, summing to 1, or `None` where nothing scatters.
    #[inline]
    fn lobe_probabilities(&self, wo: Vec3) -> Option<[f32; 4]> {
        let (reflection, transmission) = self.lobe_weights();
        let f = fresnel_dielectric(wo.z, self.eta);
        let p = if wo.z > 0.0 {
            [
                1.0 - transmission * (1.0 - f),
                transmission * (1.0 - f),
                0.25 * self.clearcoat.max(0.0),
                reflection.max(0.0),
            ]
        } else if transmission > 0.0 {
            [f, 1.0 - f, 0.0, 0.0]
        } else {
            return None; // the back of an opaque principled surface is black
        };
        let total: f32 = p.iter().sum();
        (total > 0.0 && total.is_finite()).then(|| p.map(|x| x.max(0.0) / total))
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.thin {
            return self.thin_pdf(wo, wi);
        }
        let (Some(p), Some(prob)) = (self.pair(wo, wi), self.lobe_probabilities(wo)) else {
            return 0.0;
        };
        let mf = self.specular();
        let wo_up = if wo.z < 0.0 { -wo } else { wo };
        let mut pdf = 0.0;
        if p.reflect && p.reflect_ok {
            let jacobian = 1.0 / (4.0 * wi.dot(p.wh).abs());
            pdf += prob[0] * mf.pdf_visible_normal(wo_up, p.wh) * jacobian;
            if p.front {
                let alpha = lerp(0.1, 0.001, self.clearcoat_gloss);
                pdf += prob[2] * gtr1(p.wh.z, alpha) * p.wh.z * jacobian;
            }
        }
        if p.reflect && wi.z > 0.0 {
            pdf += prob[3] * pdf_hemisphere_cosine(wi.z);
        }
        if p.refract && p.refract_ok {
            let (oh, ih) = (wo.dot(p.wh), wi.dot(p.wh));
            let jacobian = (p.eta_path * p.eta_path * ih / (oh + p.eta_path * ih).powi(2)).abs();
            pdf += prob[1] * mf.pdf_visible_normal(wo_up, p.wh) * jacobian;
        }
        pdf
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if self.thin {
            return self.thin_sample(wo, u_lobe, u);
        }
        let prob = self.lobe_probabilities(wo)?;
        let wo_up = if wo.z < 0.0 { -wo } else { wo };
        let (diffuse, coat, transmit) = (prob[3], prob[3] + prob[2], prob[3] + prob[2] + prob[1]);
        let mut eta = 1.0;
        let wi = if u_lobe < diffuse {
            sample_hemisphere_cosine(u)
        } else if u_lobe < coat {
            reflect(wo, sample_gtr1(u, lerp(0.1, 0.001, self.clearcoat_gloss)))
        } else {
            let m = self.specular().sample_visible_normal(wo_up, u);
            if u_lobe < transmit {
                let (wi, etap) = refract(wo, m, self.eta)?;
                if wi.z * wo.z >= 0.0 {
                    return None;
                }
                eta = etap;
                wi
            } else {
                reflect(wo, m)
            }
        };
        if wi.z == 0.0 || !wi.is_finite() {
            return None;
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
            eta: if wi.z * wo.z < 0.0 { eta } else { 1.0 },
        })
    }

    /// Whether some lobe transmits.
    #[inline]
    pub(crate) fn transmits(&self) -> bool {
        if self.thin {
            self.spec_trans > 0.0 || self.diff_trans > 0.0
        } else {
            self.spec_trans > 0.0 && self.metallic < 1.0
        }
    }

    // The thin form. Both sides scatter alike: directions are mirrored to
    // the viewer's side first. Its specular transmission is a reflection
    // off a distribution whose roughness is scaled by (0.65·η − 0.35)
    // (Burley 2015, fig. 15), mirrored through the sheet.

    /// `wo` on the upper side and `wi` with it, and their half vector
    /// (with `wi` mirrored up where it is transmitted).
    #[inline]
    fn thin_pair(wo: Vec3, wi: Vec3) -> Option<(Vec3, Vec3, Vec3)> {
        if wo.z == 0.0 {
            return None;
        }
        let s = wo.z.signum();
        let (v, l) = (wo * s, wi * s);
        let l_up = Vec3::new(l.x, l.y, l.z.abs());
        Some((v, l, (v + l_up).try_normalize()?))
    }

    /// The thin form's distributions: of reflection, of transmission.
    #[inline]
    fn thin_distributions(&self) -> (Microfacet, Microfacet) {
        let scaled = PrincipledBsdf {
            roughness: (0.65 * self.eta - 0.35) * self.roughness,
            ..*self
        };
        (self.specular(), scaled.specular())
    }

    /// Lobe probabilities of the thin form: specular reflection and
    /// transmission, diffuse reflection and transmission.
    #[inline]
    fn thin_probabilities(&self) -> Option<[f32; 4]> {
        let p = [
            0.5 * self.spec_trans,
            0.5 * self.spec_trans,
            (1.0 - self.spec_trans) * (1.0 - self.diff_trans),
            (1.0 - self.spec_trans) * self.diff_trans,
        ];
        let total: f32 = p.iter().sum();
        (total > 0.0 && total.is_finite()).then(|| p.map(|x| x.max(0.0) / total))
    }

    fn thin_eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let Some((v, l, wh)) = Self::thin_pair(wo, wi) else {
            return Rgb::ZERO;
        };
        let (ci, co) = (v.z, l.z);
        if co == 0.0 {
            return Rgb::ZERO;
        }
        let (reflect, refract) = (co > 0.0, co < 0.0);
        let (spec_trans, diff_trans) = (self.spec_trans, self.diff_trans);
        // Mitsuba's value is f·|cos θi|; it is divided out at the end.
        let mut value = Rgb::ZERO;
        if spec_trans > 0.0 {
            let f_dielectric = fresnel_dielectric(v.dot(wh), self.eta);
            let (reflection, transmission) = self.thin_distributions();
            if reflect && v.dot(wh) > 0.0 && l.dot(wh) > 0.0 {
                let blend = schlick_blend(v.dot(wh), self.eta);
                let lum = luminance(self.base_color);
                let tint = if lum > 0.0 { self.base_color / lum } else { Rgb::ONE };
                let r0 = tint * r0_of(self.eta);
                let tinted = r0 + (Rgb::ONE - r0) * blend;
                let fresnel = Rgb::splat(f_dielectric) + (tinted - Rgb::splat(f_dielectric)) * self.spec_tint;
                let g = masking(&reflection, v, wh) * masking(&reflection, l, wh);
                value += fresnel * (spec_trans * reflection.d(wh) * g / (4.0 * ci));
            }
            if refract && v.dot(wh) > 0.0 && l.dot(wh) < 0.0 {
                let g = masking(&transmission, v, wh) * masking(&transmission, l, wh);
                value += self.base_color * (spec_trans * (1.0 - f_dielectric) * transmission.d(wh) * g / (4.0 * ci));
            }
        }
        if reflect && spec_trans < 1.0 && diff_trans < 1.0 {
            let (f_o, f_i) = (schlick_weight(co.abs()), schlick_weight(ci));
            let diffuse = (1.0 - 0.5 * f_i) * (1.0 - 0.5 * f_o);
            let cos_d = wh.dot(l);
            let rr = 2.0 * self.roughness * cos_d * cos_d;
            let retro = rr * (f_o + f_i + f_o * f_i * (rr - 1.0));
            let fss90 = 0.5 * rr;
            let fss = lerp(1.0, fss90, f_o) * lerp(1.0, fss90, f_i);
            let subsurface = 1.25 * (fss * (1.0 / (co.abs() + ci) - 0.5) + 0.5);
            let shape = lerp(diffuse + retro, subsurface, self.flatness);
            let kept = (1.0 - spec_trans) * (1.0 - diff_trans);
            value += self.base_color * (kept * co * shape / PI);
            if self.sheen > 0.0 {
                let lum = luminance(self.base_color);
                let tint = if lum > 0.0 { self.base_color / lum } else { Rgb::ONE };
                let color = Rgb::ONE + (tint - Rgb::ONE) * self.sheen_tint;
                value += color * (self.sheen * kept * schlick_weight(cos_d.abs()) * co.abs());
            }
        }
        if refract && spec_trans < 1.0 && diff_trans > 0.0 {
            value += self.base_color * ((1.0 - spec_trans) * diff_trans * co.abs() / PI);
        }
        value / co.abs()
    }

    fn thin_pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (Some((v, l, wh)), Some(prob)) = (Self::thin_pair(wo, wi), self.thin_probabilities()) else {
            return 0.0;
        };
        let mut pdf = 0.0;
        if self.spec_trans > 0.0 && v.dot(wh) > 0.0 {
            let (reflection, transmission) = self.thin_distributions();
            let l_up = Vec3::new(l.x, l.y, l.z.abs());
            let jacobian = 1.0 / (4.0 * l_up.dot(wh)).abs();
            if l.z > 0.0 && l.dot(wh) > 0.0 {
                pdf += prob[0] * visible_pdf(&reflection, v, wh) * jacobian;
            }
            if l.z < 0.0 && l.dot(wh) < 0.0 {
                pdf += prob[1] * visible_pdf(&transmission, v, wh) * jacobian;
            }
        }
        pdf + prob[2] * pdf_hemisphere_cosine(l.z) + prob[3] * pdf_hemisphere_cosine(-l.z)
    }

    fn thin_sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let prob = self.thin_probabilities()?;
        if wo.z == 0.0 {
            return None;
        }
        let s = wo.z.signum();
        let v = wo * s;
        let (reflection, transmission) = self.thin_distributions();
        let l = if u_lobe < prob[0] {
            reflect(v, reflection.sample_visible_normal(v, u))
        } else if u_lobe < prob[0] + prob[1] {
            let r = reflect(v, transmission.sample_visible_normal(v, u));
            Vec3::new(r.x, r.y, -r.z)
        } else if u_lobe < prob[0] + prob[1] + prob[2] {
            sample_hemisphere_cosine(u)
        } else {
            -sample_hemisphere_cosine(u)
        };
        let wi = l * s;
        if wi.z == 0.0 || !wi.is_finite() {
            return None;
        }
        let pdf = self.thin_pdf(wo, wi);
        (pdf > 0.0).then(|| BsdfSample {
            wi,
            f: self.thin_eval(wo, wi),
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
        self.base_color.clamp(Rgb::ZERO, Rgb::ONE)
    }
}

/// Mitsuba's density of the normals visible from `v`: zero where `m`
/// faces away from `v`.
#[inline]
fn visible_pdf(mf: &Microfacet, v: Vec3, m: Vec3) -> f32 {
    if v.dot(m) * v.z <= 0.0 {
        0.0
    } else {
        mf.pdf_visible_normal(v, m)
    }
}

#[inline]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;
    use crate::sampling::warp::sample_sphere_uniform;

    fn every_lobe() -> PrincipledBsdf {
        PrincipledBsdf {
            base_color: Rgb::new(0.3, 0.6, 0.8),
            roughness: 0.4,
            anisotropic: 0.5,
            metallic: 0.3,
            spec_trans: 0.4,
            spec_tint: 0.5,
            sheen: 0.6,
            sheen_tint: 0.5,
            flatness: 0.3,
            clearcoat: 0.7,
            clearcoat_gloss: 0.4,
            diff_trans: 0.0,
            eta: 1.45,
            thin: false,
        }
    }

    fn thin() -> PrincipledBsdf {
        PrincipledBsdf {
            base_color: Rgb::new(0.7, 0.1, 0.1),
            roughness: 0.5,
            anisotropic: 0.4,
            metallic: 0.0,
            spec_trans: 0.5,
            spec_tint: 0.3,
            sheen: 0.4,
            sheen_tint: 0.2,
            flatness: 0.2,
            clearcoat: 0.0,
            clearcoat_gloss: 0.0,
            diff_trans: 0.35,
            eta: 1.33,
            thin: true,
        }
    }

    /// The thin form is the same from both sides.
    #[test]
    fn the_thin_form_scatters_alike_from_both_sides() {
        let b = thin();
        let flip = |w: Vec3| -w;
        let mut rng = Pcg32::new(3, 3);
        for _ in 0..1000 {
            let wo = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
            let wi = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
            let (a, c) = (
                b.eval(wo, wi, TransportMode::Radiance),
                b.eval(flip(wo), flip(wi), TransportMode::Radiance),
            );
            assert!(
                (a - c).abs().max_element() <= 1e-5 * (1.0 + a.max_element()),
                "{a} against {c}"
            );
            assert!((b.pdf(wo, wi) - b.pdf(flip(wo), flip(wi))).abs() <= 1e-4 * (1.0 + b.pdf(wo, wi)));
        }
    }

    /// The sampler's reported densities are the densities it samples by:
    /// the mean of f·cos/pdf over its samples equals the integral of f·cos
    /// estimated by uniform directions (fixed seeds; the tolerance is four
    /// standard errors of the two estimates).
    #[test]
    fn samples_weigh_as_uniform_estimates_of_the_same_integral() {
        let mut rng = Pcg32::new(5, 9);
        for (bsdf, wo) in [
            (every_lobe(), Vec3::new(0.3, -0.2, 0.93).normalize()),
            (every_lobe(), Vec3::new(0.8, 0.1, 0.2).normalize()),
            (every_lobe(), Vec3::new(0.2, 0.1, -0.9).normalize()),
            (
                PrincipledBsdf {
                    spec_trans: 0.0,
                    roughness: 0.15,
                    ..every_lobe()
                },
                Vec3::new(-0.4, 0.3, 0.8).normalize(),
            ),
            (thin(), Vec3::new(0.3, -0.2, 0.93).normalize()),
            (thin(), Vec3::new(-0.5, 0.4, -0.6).normalize()),
        ] {
            let n = 400_000;
            let (mut sampled, mut sampled2) = (0.0f64, 0.0f64);
            let (mut uniform, mut uniform2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                if let Some(s) = bsdf.sample(wo, rng.next_f32(), u, TransportMode::Radiance) {
                    let w = (luminance(s.f) * s.wi.z.abs() / s.pdf) as f64;
                    sampled += w;
                    sampled2 += w * w;
                }
                let wi = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
                let w = (luminance(bsdf.eval(wo, wi, TransportMode::Radiance)) * wi.z.abs() * 4.0 * PI) as f64;
                uniform += w;
                uniform2 += w * w;
            }
            let nf = n as f64;
            let (ms, mu) = (sampled / nf, uniform / nf);
            let var = (sampled2 / nf - ms * ms) / nf + (uniform2 / nf - mu * mu) / nf;
            assert!(
                (ms - mu).abs() < 4.0 * var.sqrt(),
                "{wo}: sampled {ms}, uniform {mu} ± {}",
                var.sqrt()
            );
            assert!(mu > 0.05, "{mu}");
        }
    }

    /// With η = 1 (no specular reflection) and roughness 0 (no
    /// retro-reflection), a white surface seen along its normal scatters
    /// Disney's diffuse alone: albedo ∫(1 − ½(1 − cos θ)⁵) cos θ/π dω =
    /// 1 − 1/42. Fixed seed; four standard errors.
    #[test]
    fn disneys_diffuse_lobe_has_its_closed_form_albedo() {
        let bsdf = PrincipledBsdf {
            base_color: Rgb::ONE,
            roughness: 0.0,
            anisotropic: 0.0,
            metallic: 0.0,
            spec_trans: 0.0,
            spec_tint: 0.0,
            sheen: 0.0,
            sheen_tint: 0.0,
            flatness: 0.0,
            clearcoat: 0.0,
            clearcoat_gloss: 0.0,
            diff_trans: 0.0,
            eta: 1.0,
            thin: false,
        };
        let mut rng = Pcg32::new(1, 2);
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        let n = 200_000;
        for _ in 0..n {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            if let Some(s) = bsdf.sample(Vec3::Z, rng.next_f32(), u, TransportMode::Radiance) {
                let w = luminance(s.weight()) as f64;
                sum += w;
                sum2 += w * w;
            }
        }
        let nf = n as f64;
        let mean = sum / nf;
        let se = ((sum2 / nf - mean * mean) / nf).sqrt();
        let expected = 1.0 - 1.0 / 42.0;
        assert!(
            (mean - expected).abs() < 4.0 * se + 1e-4,
            "{mean} against {expected} ± {se}"
        );
    }

    #[test]
    fn mitsubas_default_specular_is_an_index_of_about_1_5() {
        assert!(
            (eta_from_specular(0.5) - 1.5).abs() < 0.01,
            "{}",
            eta_from_specular(0.5)
        );
    }
}
