//! Kajiya's path tracer: a Monte Carlo estimate of the rendering equation
//! (Kajiya 1986),
//!
//! ```text
//! L(x, ωo) = Le(x, ωo) + ∫ f(x, ωo, ωi) L(x', −ωi) |cos θi| dωi,
//! ```
//!
//! followed one random direction per bounce. Four estimators are offered,
//! from the textbook one to the one production renderers use:
//!
//! | `sampling` | direction at each bounce | light collected |
//! |---|---|---|
//! | `uniform` | uniform over the hemisphere, pdf 1/(2π) | only when a path hits an emitter |
//! | `cosine` | cosine-weighted, pdf cos θ/π | only when a path hits an emitter |
//! | `bsdf` | the BSDF's own importance sampling | only when a path hits an emitter |
//! | `mis` | the BSDF's own importance sampling | also by next-event estimation: a shadow ray to a light chosen in proportion to power; the two strategies combined by the power heuristic (Veach and Guibas 1995) |
//!
//! Delta lobes (mirrors, smooth glass) are always sampled exactly: a random
//! direction has zero probability of finding them. Delta lights (point,
//! spot, directional) have zero size, so a path never hits them: only `mis`,
//! which samples them directly, sees their light.
//!
//! `max_depth` is the longest path in segments from the camera (1: emitters
//! seen directly, 2: direct lighting, …), as in Mitsuba. After `rr_depth`
//! segments, Russian roulette ends a path with probability
//! 1 − min(0.95, max(β)·η²) and divides the survivors' throughput β by the
//! survival probability, which keeps the estimate unbiased (η² undoes the
//! radiance scaling of refraction so that paths inside glass are not
//! killed for it).

use super::{Integrator, RayStats, choose_light, light_choice_pmf};
use crate::color::Rgb;
use crate::geometry::Ray;
use crate::light::ShadowTarget;
use crate::material::{DirectionSampling, TransportMode};
use crate::sampling::Sampler;
use crate::scene::Scene;
use crate::texture::TexCoord;

pub use crate::settings::PathSampling;

/// The power heuristic with β = 2 (Veach 1997, eq. 9.13).
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let (a, b) = (pdf_a * pdf_a, pdf_b * pdf_b);
    if a.is_infinite() {
        return 1.0;
    }
    if a + b == 0.0 { 0.0 } else { a / (a + b) }
}

/// The path tracer.
#[derive(Clone, Copy, Debug)]
pub struct PathTracer {
    /// Longest path, in segments from the camera.
    pub max_depth: u32,
    /// Segments after which Russian roulette starts.
    pub rr_depth: u32,
    /// The estimator.
    pub sampling: PathSampling,
}

impl Integrator for PathTracer {
    fn radiance(&self, scene: &Scene, camera_ray: &Ray, sampler: &mut Sampler, stats: &mut RayStats) -> Rgb {
        let strategy = match self.sampling {
            PathSampling::Uniform => DirectionSampling::Uniform,
            PathSampling::Cosine => DirectionSampling::Cosine,
            PathSampling::Bsdf | PathSampling::Mis => DirectionSampling::Bsdf,
        };
        let nee = self.sampling == PathSampling::Mis;
        let mode = TransportMode::Radiance;

        let mut l = Rgb::ZERO;
        let mut beta = Rgb::ONE;
        let mut ray = *camera_ray;
        // What the previous bounce was, for weighting emission found by it.
        let mut prev_delta = true;
        let mut prev_pdf = 0.0f32;
        let mut prev_p = ray.origin;
        // The normal the light choice used there (zero: none).
        let mut prev_n = glam::Vec3::ZERO;
        let mut eta_scale = 1.0f32;
        let mut depth = 1u32; // segments in the path once `ray` is traced

        while depth <= self.max_depth {
            stats.rays += 1;
            let shows_emission = scene.settings.shows_emission(depth);
            let Some(hit) = scene.intersect(&ray) else {
                if let (Some(env), true) = (scene.environment_light, shows_emission) {
                    let dir = ray.dir.normalize();
                    // (A portal lets in what the ray's origin sees through it.)
                    if nee && !prev_delta {
                        let (le, pdf_dir) = scene.background.eval_pdf_from(prev_p, dir, true);
                        let pdf_light = light_choice_pmf(scene, prev_p, prev_n, env as usize) * pdf_dir;
                        l += beta * le * power_heuristic(prev_pdf, pdf_light);
                    } else {
                        l += beta * scene.background.eval_from(ray.origin, dir);
                    }
                }
                break;
            };
            let m = &scene.materials[hit.material as usize];
            let wo_world = -ray.dir.normalize();

            if m.is_emissive() && shows_emission && m.emits_toward(&hit, wo_world) {
                let w = match hit.light {
                    Some(li) if nee && !prev_delta => {
                        let pdf_light = light_choice_pmf(scene, prev_p, prev_n, li as usize)
                            * scene.lights[li as usize].pdf_li(scene, prev_p, &hit);
                        power_heuristic(prev_pdf, pdf_light)
                    }
                    _ => 1.0,
                };
                l += beta * m.emission_at(&scene.textures, &TexCoord::at(&hit)) * w;
            }
            if depth == self.max_depth {
                break;
            }

            let tc = TexCoord::at(&hit);
            // A mask's cut-out part, chosen with probability 1 − α: the path
            // goes on unchanged (a bounce, as Mitsuba's path counts it).
            // Shadow rays do not see through masks (nor do Mitsuba's), so
            // only this way finds the light behind them: weight 1.
            if m.cut_out(&scene.textures, &tc, || sampler.next_1d()) {
                prev_delta = true;
                ray = hit.spawn_ray(ray.dir);
                depth += 1;
                continue;
            }
            let mut parts = None;
            let bsdf = scene.bsdf(hit.material, &tc, &mut parts);
            let frame = m.shading_frame(&scene.textures, &hit, wo_world);
            let wo = frame.to_local(wo_world);
            if !m.two_sided && !bsdf.transmits() && !hit.is_front(wo_world) {
                break; // the back of a one-sided surface is black
            }
            let front_o = hit.ng.dot(wo_world) > 0.0;

            // Next-event estimation.
            if nee && bsdf.has_smooth() && !scene.lights.is_empty() {
                let chosen = choose_light(scene, hit.p, hit.ns, sampler);
                let sample = match chosen {
                    Some((light_index, _)) => scene.lights[light_index].sample_li_drawing(scene, hit.p, sampler, true),
                    None => {
                        // No light reaches the point: its numbers are passed over.
                        sampler.skip_1d();
                        sampler.skip_2d();
                        None
                    }
                };
                let pmf = chosen.map_or(0.0, |(_, pmf)| pmf);
                if let Some(ls) = sample {
                    let wi = frame.to_local(ls.wi);
                    let f = bsdf.eval(wo, wi, mode) * frame.factor(ls.wi);
                    // The geometric normal decides reflection or transmission.
                    let front_i = hit.ng.dot(ls.wi) > 0.0;
                    let consistent = (front_i == front_o) == (wi.z * wo.z > 0.0);
                    if f != Rgb::ZERO && ls.li != Rgb::ZERO && consistent {
                        stats.rays += 1;
                        let shadow = match ls.target {
                            ShadowTarget::Point(p) => hit.spawn_ray_to(p),
                            ShadowTarget::Infinity => hit.spawn_ray(ls.wi),
                        };
                        if !scene.occluded(&shadow) {
                            let pdf_light = ls.pdf * pmf;
                            let w = if ls.is_delta {
                                1.0
                            } else {
                                power_heuristic(pdf_light, bsdf.pdf(wo, wi))
                            };
                            l += beta * f * ls.li * (wi.z.abs() * w / pdf_light);
                        }
                    }
                }
            }

            // Continue the path.
            // The lobe choice, passed over where there is one lobe.
            let u_lobe = if bsdf.reads_lobe_choice() {
                sampler.next_1d()
            } else {
                sampler.skip_1d();
                0.0
            };
            let Some(bs) = bsdf.sample_with(strategy, wo, u_lobe, sampler.next_2d(), mode) else {
                break;
            };
            if bs.pdf <= 0.0 || bs.f == Rgb::ZERO || bs.wi.z == 0.0 {
                break;
            }
            let wi_world = frame.to_world(bs.wi);
            let reflection = bs.wi.z * wo.z > 0.0;
            if (hit.ng.dot(wi_world) > 0.0) != (front_o == reflection) {
                break; // the shading normal sent the path through the surface
            }
            let mapped = frame.factor(wi_world);
            if mapped == 0.0 {
                break;
            }
            beta *= bs.f * (mapped * bs.wi.z.abs() / bs.pdf);
            if !reflection {
                eta_scale *= bs.eta * bs.eta;
            }
            prev_delta = bs.delta;
            prev_pdf = bs.pdf;
            prev_p = hit.p;
            prev_n = hit.ns;
            ray = hit.spawn_ray(wi_world);
            depth += 1;

            if depth > self.rr_depth {
                let q = (beta.max_element() * eta_scale).min(0.95);
                if sampler.next_1d() >= q {
                    break;
                }
                beta /= q;
            }
        }
        l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_heuristic_weights_sum_to_one() {
        for (a, b) in [(1.0f32, 1.0f32), (0.3, 7.0), (5.0, 0.0)] {
            assert!((power_heuristic(a, b) + power_heuristic(b, a) - 1.0).abs() < 1e-6);
        }
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
    }

    #[test]
    fn names_round_trip() {
        for n in PathSampling::NAMES {
            assert_eq!(PathSampling::from_name(n).unwrap().name(), n);
        }
    }
}
