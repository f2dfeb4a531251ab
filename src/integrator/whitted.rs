//! Whitted's recursive ray tracer (Whitted 1980, "An Improved Illumination
//! Model for Shaded Display").
//!
//! At each hit: emission (front side only, both for two-sided emitters), an optional ambient term
//! `ambient·kd`, direct light from every light through a shadow ray and the
//! Phong model ([`crate::material::phong`]), then recursion along the
//! mirror direction weighted by the reflectivity kr and, for transmissive
//! materials, along the reflected and refracted directions weighted by
//! `kt·F` and `kt·(1 − F)` (F: the exact dielectric Fresnel reflectance;
//! total internal reflection sends everything to the reflected ray).
//! Rays that leave the scene return the background.
//!
//! `max_depth` counts the segments of a light path from the camera, as in
//! the path tracer (and Mitsuba): 1 shows only what emits, 2 adds direct
//! light (and the ambient term), each further unit allows one more level
//! of reflection or refraction.
//!
//! Physically based materials are rendered through their classical
//! equivalents ([`crate::material::Material::classic`]).
//!
//! Area lights (emissive shapes) are sampled at one random point per light
//! per pixel sample, so supersampling gives them soft shadows.
//!
//! **Dispersion.** Glass whose index varies with wavelength draws one
//! wavelength at the first such glass a ray meets (as the path tracer
//! does, `color::spectrum::sample_visible_wavelength`): both its
//! reflected and refracted rays, and every glass below them, take their
//! index there, and their light is weighted by the wavelength's weight,
//! so that supersampling averages the spectrum.
//!
//! **Shadow rays and transparent occluders.** A shadow ray is not bent by
//! refraction. It passes through transmissive surfaces, attenuated at each
//! crossing by `kt·(1 − F)`, and is blocked by any opaque surface. A glass
//! sphere therefore casts a light, tinted shadow instead of a black one,
//! but no caustic: focused light needs the path tracer or photon mapping.

use super::{Integrator, RayStats};
use crate::color::Rgb;
use crate::color::spectrum::sample_visible_wavelength;
use crate::geometry::Ray;
use crate::geometry::interaction::SurfaceHit;
use crate::light::{Light, LightSample, ShadowTarget};
use crate::material::optics::{fresnel_dielectric, reflect, refract};
use crate::material::phong::phong_brdf;
use crate::sampling::Sampler;
use crate::scene::Scene;
use crate::texture::TexCoord;

/// The Whitted integrator.
#[derive(Clone, Copy, Debug)]
pub struct Whitted {
    /// Longest light path, in segments from the camera.
    pub max_depth: u32,
}

impl Integrator for Whitted {
    fn radiance(&self, scene: &Scene, ray: &Ray, sampler: &mut Sampler, stats: &mut RayStats) -> Rgb {
        if self.max_depth == 0 {
            return Rgb::ZERO;
        }
        self.trace(scene, ray, 1, sampler, stats, None)
    }
}

impl Whitted {
    /// Radiance along `ray`, the `depth`-th segment of its path, at
    /// wavelength `nm` where a dispersive glass above chose one.
    fn trace(
        &self,
        scene: &Scene,
        ray: &Ray,
        depth: u32,
        sampler: &mut Sampler,
        stats: &mut RayStats,
        nm: Option<f32>,
    ) -> Rgb {
        stats.rays += 1;
        let shows_emission = scene.settings.shows_emission(depth);
        let Some(mut hit) = scene.intersect(ray) else {
            return if shows_emission {
                scene.background.eval_from(ray.origin, ray.dir)
            } else {
                Rgb::ZERO
            };
        };
        // A blend's classical parameters are those of one of its materials.
        scene.choose_any_material(&mut hit, ray.dir);
        let m = &scene.materials[hit.material as usize];
        let wo = -ray.dir.normalize();
        let tc = TexCoord::at(&hit);
        let mut l = if m.emits_toward(&hit, wo) && shows_emission {
            m.emission_at(&scene.textures, &tc)
        } else {
            Rgb::ZERO
        };
        if depth >= self.max_depth {
            return l;
        }

        // Surfaces shade on both sides: the shading normal (a normal map's,
        // where the material has one) faces the viewer.
        let ns = m.shading_frame(&scene.textures, &hit, wo).n;
        let n = if ns.dot(wo) < 0.0 { -ns } else { ns };
        let c = m.classic(&scene.textures, &tc);
        let (kd, ks) = (c.kd, c.ks);

        l += scene.ambient * kd;
        if kd != Rgb::ZERO || ks != Rgb::ZERO {
            for light in &scene.lights {
                // Whitted's background is seen, not a light.
                if matches!(light, Light::Environment) {
                    continue;
                }
                let Some(ls) = light.sample_li_drawing(scene, hit.p, sampler, false) else {
                    continue;
                };
                let cos = n.dot(ls.wi);
                // The light must be on the viewer's side of the surface
                // itself, not only of the (interpolated) shading normal.
                if cos <= 0.0 || hit.ng.dot(ls.wi) * hit.ng.dot(wo) <= 0.0 {
                    continue;
                }
                let f = phong_brdf(kd, ks, c.shininess, n, ls.wi, wo);
                if f == Rgb::ZERO || ls.li == Rgb::ZERO {
                    continue;
                }
                let vis = shadow_transmittance(scene, &hit, &ls, stats, nm);
                l += f * ls.li * vis * (cos / ls.pdf);
            }
        }

        if c.kr != Rgb::ZERO {
            let r = hit.spawn_ray(reflect(wo, n));
            l += c.kr * self.trace(scene, &r, depth + 1, sampler, stats, nm);
        }
        if c.kt != Rgb::ZERO {
            // A dispersive glass: its index at the wavelength, drawn here
            // if no glass above drew one.
            let (ior, nm, weight) = match (m.dispersion().filter(|_| scene.disperses(hit.material)), nm) {
                (Some(d), Some(nm)) => (d.eta(nm), Some(nm), Rgb::ONE),
                (Some(d), None) => {
                    let w = sample_visible_wavelength(sampler.next_1d());
                    (d.eta(w.nm), Some(w.nm), w.weight)
                }
                (None, nm) => (c.ior, nm, Rgb::ONE),
            };
            // Fresnel with the outward normal: cosθ < 0 means leaving the inside.
            let cos_i = ns.dot(wo);
            let fresnel = fresnel_dielectric(cos_i, ior);
            let reflected = hit.spawn_ray(reflect(wo, n));
            let mut through = Rgb::ZERO;
            if let Some((wt, _)) = refract(wo, ns, ior) {
                if fresnel < 1.0 {
                    through = (1.0 - fresnel) * self.trace(scene, &hit.spawn_ray(wt), depth + 1, sampler, stats, nm);
                }
            }
            let back = fresnel * self.trace(scene, &reflected, depth + 1, sampler, stats, nm);
            l += c.kt * (back + through) * weight;
        }
        l
    }
}

/// Most transmissive surfaces a shadow ray passes through before it
/// counts as blocked.
const MAX_SHADOW_CROSSINGS: u32 = 64;

/// Fraction of a light sample's light that reaches `hit`: 0 behind an
/// opaque surface, `Π kt·(1 − F)` over the transmissive ones crossed
/// (F of a dispersive glass at wavelength `nm` where one was drawn).
fn shadow_transmittance(
    scene: &Scene,
    hit: &SurfaceHit,
    ls: &LightSample,
    stats: &mut RayStats,
    nm: Option<f32>,
) -> Rgb {
    stats.rays += 1;
    let mut ray = match ls.target {
        ShadowTarget::Point(p) => hit.spawn_ray_to(p),
        ShadowTarget::Infinity => hit.spawn_ray(ls.wi),
    };
    if !scene.has_transmissive_materials() {
        return if scene.occluded(&ray) { Rgb::ZERO } else { Rgb::ONE };
    }
    // Walk from surface to surface: each query starts strictly after the
    // last hit, so both faces of a glass object are crossed.
    let mut transmittance = Rgb::ONE;
    for _ in 0..MAX_SHADOW_CROSSINGS {
        let Some(h) = scene.geometry.intersect(&ray) else {
            return transmittance;
        };
        let mut s = scene.geometry.surface(&ray, &h);
        scene.choose_any_material(&mut s, ray.dir);
        let m = &scene.materials[s.material as usize];
        if !m.is_transmissive() {
            return Rgb::ZERO;
        }
        let c = m.classic(&scene.textures, &TexCoord::at(&s));
        let cos = s.ns.dot(-ray.dir.normalize());
        let ior = match (m.dispersion().filter(|_| scene.disperses(s.material)), nm) {
            (Some(d), Some(nm)) => d.eta(nm),
            _ => c.ior,
        };
        transmittance *= c.kt * (1.0 - fresnel_dielectric(cos, ior));
        if transmittance == Rgb::ZERO {
            return Rgb::ZERO;
        }
        ray.t_min = h.t;
        stats.rays += 1;
    }
    Rgb::ZERO
}
