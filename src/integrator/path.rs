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
use crate::geometry::interaction::SurfaceHit;
use crate::light::ShadowTarget;
use crate::material::{DirectionSampling, Frame, TransportMode};
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

/// One path between bounces: what it has gathered, its throughput, the
/// ray it traces next and what the bounce that sent it was (for the MIS
/// weight of emission that ray finds).
#[derive(Clone, Copy, Debug)]
pub struct PathState {
    l: Rgb,
    beta: Rgb,
    ray: Ray,
    prev_delta: bool,
    prev_pdf: f32,
    prev_p: glam::Vec3,
    /// The normal the light choice used at `prev_p` (zero: none).
    prev_n: glam::Vec3,
    eta_scale: f32,
    /// Segments in the path once `ray` is traced.
    depth: u32,
}

/// A bounce's shadow ray and what it adds to the path if nothing blocks it.
#[derive(Clone, Copy, Debug)]
pub struct ShadowQuery {
    /// The ray towards the light.
    pub ray: Ray,
    /// Throughput × BSDF × light × cosine × MIS weight / density.
    pub contribution: Rgb,
}

impl PathState {
    /// The ray the path traces next.
    #[inline]
    pub fn ray(&self) -> &Ray {
        &self.ray
    }

    /// The radiance gathered so far.
    #[inline]
    pub fn radiance(&self) -> Rgb {
        self.l
    }

    /// Adds an unblocked shadow ray's contribution.
    #[inline]
    pub fn add_unblocked(&mut self, shadow: &ShadowQuery) {
        self.l += shadow.contribution;
    }
}

impl PathTracer {
    /// A path that starts along `camera_ray`, or `None` where no segment is
    /// traced at all (`max_depth` 0).
    #[inline]
    pub fn start(&self, camera_ray: &Ray) -> Option<PathState> {
        (self.max_depth >= 1).then_some(PathState {
            l: Rgb::ZERO,
            beta: Rgb::ONE,
            ray: *camera_ray,
            prev_delta: true,
            prev_pdf: 0.0,
            prev_p: camera_ray.origin,
            prev_n: glam::Vec3::ZERO,
            eta_scale: 1.0,
            depth: 1,
        })
    }

    /// One bounce of `path`, whose ray found `hit` (`None`: it left the
    /// scene): emission found there, next-event estimation, the next
    /// direction and Russian roulette. Returns the shadow ray to trace (its
    /// contribution counts when nothing blocks it, see
    /// [`PathState::add_unblocked`]) and whether the path goes on along
    /// [`PathState::ray`]. The numbers are drawn in one order whatever the
    /// shadow ray finds, so that paths traced together draw and compute
    /// exactly what a path traced alone does.
    #[inline]
    pub fn bounce(
        &self,
        scene: &Scene,
        path: &mut PathState,
        hit: Option<&SurfaceHit>,
        sampler: &mut Sampler,
        stats: &mut RayStats,
    ) -> (Option<ShadowQuery>, bool) {
        let strategy = match self.sampling {
            PathSampling::Uniform => DirectionSampling::Uniform,
            PathSampling::Cosine => DirectionSampling::Cosine,
            PathSampling::Bsdf | PathSampling::Mis => DirectionSampling::Bsdf,
        };
        let nee = self.sampling == PathSampling::Mis;
        let mode = TransportMode::Radiance;
        let ray = &path.ray;

        let Some(hit) = hit else {
            if let Some(env) = scene.environment_light {
                let dir = ray.dir.normalize();
                let le = scene.background.eval(dir);
                let w = if nee && !path.prev_delta {
                    let pdf_light =
                        light_choice_pmf(scene, path.prev_p, path.prev_n, env as usize) * scene.background.pdf(dir);
                    power_heuristic(path.prev_pdf, pdf_light)
                } else {
                    1.0
                };
                path.l += path.beta * le * w;
            }
            return (None, false);
        };
        let m = &scene.materials[hit.material as usize];
        let wo_world = -ray.dir.normalize();

        if m.is_emissive() && hit.is_front(wo_world) {
            let w = match hit.light {
                Some(li) if nee && !path.prev_delta => {
                    let pdf_light = light_choice_pmf(scene, path.prev_p, path.prev_n, li as usize)
                        * scene.lights[li as usize].pdf_li(scene, path.prev_p, hit);
                    power_heuristic(path.prev_pdf, pdf_light)
                }
                _ => 1.0,
            };
            path.l += path.beta * m.emission_at(&scene.images, &TexCoord { uv: hit.uv, p: hit.p }) * w;
        }
        if path.depth == self.max_depth {
            return (None, false);
        }

        let tc = TexCoord { uv: hit.uv, p: hit.p };
        let bsdf = m.bsdf(&scene.images, &tc);
        let frame = Frame::from_orthonormal(hit.ns, hit.tangent);
        let wo = frame.to_local(wo_world);
        if !m.two_sided && !bsdf.transmits() && !hit.is_front(wo_world) {
            return (None, false); // the back of a one-sided surface is black
        }
        let front_o = hit.ng.dot(wo_world) > 0.0;

        // Next-event estimation.
        let mut shadow = None;
        if nee && bsdf.has_smooth() && !scene.lights.is_empty() {
            let chosen = choose_light(scene, hit.p, hit.ns, sampler);
            let sample = match chosen {
                Some((light_index, _)) => scene.lights[light_index].sample_li_drawing(scene, hit.p, sampler),
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
                let f = bsdf.eval(wo, wi, mode);
                // The geometric normal decides reflection or transmission.
                let front_i = hit.ng.dot(ls.wi) > 0.0;
                let consistent = (front_i == front_o) == (wi.z * wo.z > 0.0);
                if f != Rgb::ZERO && ls.li != Rgb::ZERO && consistent {
                    stats.rays += 1;
                    let ray = match ls.target {
                        ShadowTarget::Point(p) => hit.spawn_ray_to(p),
                        ShadowTarget::Infinity => hit.spawn_ray(ls.wi),
                    };
                    let pdf_light = ls.pdf * pmf;
                    let w = if ls.is_delta {
                        1.0
                    } else {
                        power_heuristic(pdf_light, bsdf.pdf(wo, wi))
                    };
                    let contribution = path.beta * f * ls.li * (wi.z.abs() * w / pdf_light);
                    shadow = Some(ShadowQuery { ray, contribution });
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
            return (shadow, false);
        };
        if bs.pdf <= 0.0 || bs.f == Rgb::ZERO || bs.wi.z == 0.0 {
            return (shadow, false);
        }
        let wi_world = frame.to_world(bs.wi);
        let reflection = bs.wi.z * wo.z > 0.0;
        if (hit.ng.dot(wi_world) > 0.0) != (front_o == reflection) {
            return (shadow, false); // the shading normal sent the path through the surface
        }
        path.beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
        if !reflection {
            path.eta_scale *= bs.eta * bs.eta;
        }
        path.prev_delta = bs.delta;
        path.prev_pdf = bs.pdf;
        path.prev_p = hit.p;
        path.prev_n = hit.ns;
        path.ray = hit.spawn_ray(wi_world);
        path.depth += 1;

        if path.depth > self.rr_depth {
            let q = (path.beta.max_element() * path.eta_scale).min(0.95);
            if sampler.next_1d() >= q {
                return (shadow, false);
            }
            path.beta /= q;
        }
        (shadow, path.depth <= self.max_depth)
    }
}

impl Integrator for PathTracer {
    fn radiance(&self, scene: &Scene, camera_ray: &Ray, sampler: &mut Sampler, stats: &mut RayStats) -> Rgb {
        let Some(mut path) = self.start(camera_ray) else {
            return Rgb::ZERO;
        };
        loop {
            stats.rays += 1;
            let hit = scene.intersect(&path.ray);
            let (shadow, goes_on) = self.bounce(scene, &mut path, hit.as_ref(), sampler, stats);
            if let Some(shadow) = shadow {
                if !scene.occluded(&shadow.ray) {
                    path.add_unblocked(&shadow);
                }
            }
            if !goes_on {
                return path.l;
            }
        }
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
