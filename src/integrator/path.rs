//! Kajiya's path tracer: a Monte Carlo estimate of the rendering equation
//! (Kajiya 1986),
//!
//! ```text
//! L(x, ωo) = Le(x, ωo) + ∫ f(x, ωo, ωi) L(x', −ωi) |cos θi| dωi,
//! ```
//!
//! followed one random direction per bounce. Six estimators are offered,
//! from the textbook one to the one production renderers use:
//!
//! | `sampling` | direction at each bounce | light collected |
//! |---|---|---|
//! | `uniform` | uniform over the hemisphere, pdf 1/(2π) | only when a path hits an emitter |
//! | `cosine` | cosine-weighted, pdf cos θ/π | only when a path hits an emitter |
//! | `bsdf` | the BSDF's own importance sampling | only when a path hits an emitter |
//! | `nee` | the BSDF's own importance sampling | by next-event estimation (a shadow ray to a light chosen in proportion to power); a hit on a light counts only from the camera or after a delta bounce |
//! | `nee-uniform` | uniform over the hemisphere | as `nee` |
//! | `mis` | the BSDF's own importance sampling | also by next-event estimation: a shadow ray to a light chosen in proportion to power; the two strategies combined by the power heuristic (Veach and Guibas 1995) |
//!
//! Delta lobes (mirrors, smooth glass) are always sampled exactly: a random
//! direction has zero probability of finding them. Delta lights (point,
//! spot, directional) have zero size, so a path never hits them: only the
//! estimators with next-event estimation, which sample them directly, see
//! their light.
//!
//! `max_depth` is the longest path in segments from the camera (1: emitters
//! seen directly, 2: direct lighting, …), as in Mitsuba. After `rr_depth`
//! segments, Russian roulette keeps a path with probability
//! q = min(1, max(β)·η²) and divides the survivors' throughput β by q,
//! which keeps the estimate unbiased (η² undoes the radiance scaling of
//! refraction so that paths inside glass are not killed for it): as in
//! pbrt-v4, a path whose weight is still at least one goes on. Where the
//! depth is unbounded the cap is Mitsuba's 0.95 instead of 1, so that
//! every path ends ([`super::survival_cap`]).

use super::{Integrator, LANES, RayStats, choose_light, light_choice_pmf, path_bsdf, survival_cap};
use crate::color::Rgb;
use crate::geometry::simd::{Floats, Vec3s, lanes};
use crate::geometry::{Ray, SurfaceHit};
use crate::light::ShadowTarget;
use crate::material::{DirectionSampling, LaneBounce, TransportMode};
use crate::sampling::Sampler;
use crate::scene::Scene;
use crate::texture::TexCoord;

pub use crate::settings::PathSampling;

/// How a path gathers the light of emitters, besides the directions it
/// samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Gathering {
    /// Only by hitting them.
    Hits,
    /// By next-event estimation at every vertex; a hit on a light it
    /// samples counts only from the camera or after a delta bounce.
    Nee,
    /// By both, weighted by the power heuristic.
    Mis,
}

impl Gathering {
    /// The weight of emission found by a path's hit after a non-delta
    /// bounce of density `pdf_bsdf`, on a light that next-event estimation
    /// samples with density `pdf_light` (per solid angle).
    #[inline]
    fn hit_weight(self, pdf_bsdf: f32, pdf_light: f32) -> f32 {
        match self {
            Gathering::Mis => power_heuristic(pdf_bsdf, pdf_light),
            // What next-event estimation can reach it finds there.
            Gathering::Nee if pdf_light > 0.0 => 0.0,
            _ => 1.0,
        }
    }
}

/// The power heuristic with β = 2 (Veach 1997, eq. 9.13).
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    power_heuristic_lanes(pdf_a, pdf_b)
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
        self.trace::<f32>(scene, [*camera_ray], std::array::from_mut(sampler), 1, stats)
            .lane(0)
    }

    #[allow(unsafe_code)]
    fn radiance_lanes(
        &self,
        scene: &Scene,
        rays: &[Ray; LANES],
        samplers: &mut [Sampler; LANES],
        live: u32,
        stats: &mut RayStats,
    ) -> [Rgb; LANES] {
        #[cfg(target_arch = "x86_64")]
        if crate::geometry::lanes::avx_available() {
            // SAFETY: the processor has AVX.
            return unsafe { self.trace_avx(scene, rays, samplers, live, stats) };
        }
        super::one_by_one(self, scene, rays, samplers, live, stats)
    }
}

/// What a path did at the previous bounce, which weighs the emission its
/// next ray finds.
#[derive(Clone, Copy)]
struct Previous {
    /// Whether the direction came from a delta lobe (or a cut-out).
    delta: bool,
    /// The direction's density.
    pdf: f32,
    /// The bounce's position.
    p: glam::Vec3,
    /// The normal the light choice used there (zero: none).
    n: glam::Vec3,
}

/// Light a path found at the end of its ray, before its throughput: the
/// radiance and its MIS weight.
#[derive(Clone, Copy)]
struct Found {
    le: Rgb,
    weight: f32,
}

/// Light found by next-event estimation at a bounce, before the path's
/// throughput: the BSDF value, the light's radiance and the factor
/// `|cos θ| · w / pdf`.
#[derive(Clone, Copy)]
struct Direct {
    f: Rgb,
    li: Rgb,
    factor: f32,
}

/// How a path goes on from a surface.
#[derive(Clone, Copy)]
enum Scatter {
    /// It ends.
    End,
    /// Through a mask's cut-out part, unchanged.
    Pass(Ray),
    /// By a sampled direction: the throughput's factor, the factor of
    /// the radiance scale (η² through refraction, else 1), the bounce and
    /// the next ray.
    Bounce {
        factor: Rgb,
        eta2: f32,
        previous: Previous,
        ray: Ray,
    },
}

impl PathTracer {
    /// The path tracer that render settings `s` describe.
    pub fn with_settings(s: &crate::settings::RenderSettings) -> PathTracer {
        PathTracer {
            max_depth: s.max_depth,
            rr_depth: s.rr_depth,
            sampling: s.sampling,
        }
    }

    /// [`PathTracer::trace`] over eight lanes.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn trace_avx(
        &self,
        scene: &Scene,
        rays: &[Ray; LANES],
        samplers: &mut [Sampler; LANES],
        live: u32,
        stats: &mut RayStats,
    ) -> [Rgb; LANES] {
        use crate::geometry::lanes::F8;
        let l = self.trace::<F8>(scene, *rays, samplers, live, stats);
        std::array::from_fn(|i| l.lane(i))
    }

    /// Traces `F::N` paths at once from the camera rays `rays`, those of
    /// the lanes set in `live`, lane `i` drawing its numbers from
    /// `samplers[i]`: their estimates, each the one the path would give
    /// traced alone. The paths move in lockstep, one segment each per
    /// step; what depends on one path's surface (its intersection, BSDF
    /// and light sample) is computed lane by lane, and the throughput and
    /// estimate in lanes, except the bounces off plain smooth glass and
    /// Lambertian surfaces, which are made together
    /// ([`smooth_glass_bounces`], [`diffuse_bounces`]).
    #[inline(always)]
    fn trace<F: Floats>(
        &self,
        scene: &Scene,
        mut rays: F::Each<Ray>,
        samplers: &mut [Sampler],
        mut live: u32,
        stats: &mut RayStats,
    ) -> Vec3s<F> {
        let strategy = match self.sampling {
            PathSampling::Uniform | PathSampling::NeeUniform => DirectionSampling::Uniform,
            PathSampling::Cosine => DirectionSampling::Cosine,
            PathSampling::Bsdf | PathSampling::Nee | PathSampling::Mis => DirectionSampling::Bsdf,
        };
        let nee = match self.sampling {
            PathSampling::Uniform | PathSampling::Cosine | PathSampling::Bsdf => Gathering::Hits,
            PathSampling::Nee | PathSampling::NeeUniform => Gathering::Nee,
            PathSampling::Mis => Gathering::Mis,
        };
        debug_assert_eq!(samplers.len(), F::N, "a sampler a lane");

        let mut l = Vec3s::<F>::splat(Rgb::ZERO);
        let mut beta = Vec3s::<F>::splat(Rgb::ONE);
        let mut eta_scale = F::splat(1.0);
        let mut previous = F::each(|i| Previous {
            delta: true,
            pdf: 0.0,
            p: rays.as_ref()[i].origin,
            n: glam::Vec3::ZERO,
        });
        let mut depth = 1u32; // segments in the paths once `rays` are traced
        // Per-lane results of each step, valid in the lanes its masks name.
        let mut hits = F::each(|_| None);
        let mut found = F::each(|_| Found {
            le: Rgb::ZERO,
            weight: 0.0,
        });
        let mut direct = F::each(|_| Direct {
            f: Rgb::ZERO,
            li: Rgb::ZERO,
            factor: 0.0,
        });
        let mut factor = F::each(|_| Rgb::ONE);
        let mut eta2 = F::each(|_| 1.0f32);
        // Diffuse bounces are made in lanes where directions are drawn by
        // the BSDF (the other strategies are the textbook ones).
        let diffuse_in_lanes = strategy == DirectionSampling::Bsdf;
        // Each path's wavelength, once it has met a dispersive glass.
        let mut wavelengths = F::each(|_| None::<f32>);

        while depth <= self.max_depth && live != 0 {
            // Where the rays end, and the light they find there.
            let mut lit = 0u32;
            let together = scene.intersect_together(rays.as_ref(), live, hits.as_mut());
            for i in lanes(live) {
                stats.rays += 1;
                if !together {
                    scene.intersect_into(&rays.as_ref()[i], &mut hits.as_mut()[i]);
                }
                let hit = &hits.as_ref()[i];
                let light = self.arrive(scene, &rays.as_ref()[i], &previous.as_ref()[i], depth, nee, hit);
                if hit.is_none() {
                    live &= !(1 << i);
                }
                if let Some(light) = light {
                    found.as_mut()[i] = light;
                    lit |= 1 << i;
                }
            }
            if lit != 0 {
                let le = Vec3s::gather(&F::each(|i| found.as_ref()[i].le));
                let w = F::gather(&F::each(|i| found.as_ref()[i].weight));
                l = Vec3s::select(F::mask_from_bits(lit), l + (beta * le).scale(w), l);
            }
            if depth == self.max_depth || live == 0 {
                break;
            }

            // How the paths go on: those on smooth glass or diffuse
            // surfaces together, the others one by one.
            let (mut on_glass, mut on_diffuse) = (0u32, 0u32);
            if !scene.lane_bounces.is_empty() {
                for i in lanes(live) {
                    let Some(hit) = &hits.as_ref()[i] else { continue };
                    match scene.lane_bounces[hit.material as usize] {
                        Some(LaneBounce::SmoothGlass { .. }) => on_glass |= 1 << i,
                        Some(LaneBounce::Diffuse) if diffuse_in_lanes => on_diffuse |= 1 << i,
                        _ => {}
                    }
                }
            }
            let mut lanes_bounced = 0;
            if on_glass != 0 {
                let (factor, eta2, bounced) =
                    smooth_glass_bounces::<F>(scene, &hits, on_glass, &mut rays, samplers, &mut previous);
                live &= !(on_glass & !bounced);
                let mask = F::mask_from_bits(bounced);
                beta = Vec3s::select(mask, beta * factor, beta);
                eta_scale = F::select(mask, eta_scale * eta2, eta_scale);
                lanes_bounced |= bounced;
            }
            if on_diffuse != 0 {
                let d = diffuse_bounces::<F>(scene, &hits, on_diffuse, &mut rays, samplers, &mut previous, nee, stats);
                if d.lit != 0 {
                    l = Vec3s::select(F::mask_from_bits(d.lit), l + (beta * d.f * d.li).scale(d.s), l);
                }
                live &= !(on_diffuse & !d.bounced);
                beta = Vec3s::select(F::mask_from_bits(d.bounced), beta * d.factor, beta);
                lanes_bounced |= d.bounced;
            }
            let mut lit = 0u32;
            let mut bounced = 0u32;
            for i in lanes(live & !on_glass & !on_diffuse) {
                let Some(hit) = &hits.as_ref()[i] else { continue };
                let ray = &mut rays.as_mut()[i];
                let wavelength = &mut wavelengths.as_mut()[i];
                let (light, scatter) =
                    self.scatter(scene, hit, ray.dir, &mut samplers[i], wavelength, stats, strategy, nee);
                if let Some(light) = light {
                    direct.as_mut()[i] = light;
                    lit |= 1 << i;
                }
                match scatter {
                    Scatter::End => live &= !(1 << i),
                    Scatter::Pass(next) => {
                        previous.as_mut()[i].delta = true;
                        *ray = next;
                    }
                    Scatter::Bounce {
                        factor: f,
                        eta2: e,
                        previous: p,
                        ray: next,
                    } => {
                        factor.as_mut()[i] = f;
                        eta2.as_mut()[i] = e;
                        previous.as_mut()[i] = p;
                        *ray = next;
                        bounced |= 1 << i;
                    }
                }
            }
            if lit != 0 {
                let f = Vec3s::gather(&F::each(|i| direct.as_ref()[i].f));
                let li = Vec3s::gather(&F::each(|i| direct.as_ref()[i].li));
                let s = F::gather(&F::each(|i| direct.as_ref()[i].factor));
                l = Vec3s::select(F::mask_from_bits(lit), l + (beta * f * li).scale(s), l);
            }
            if bounced != 0 {
                let mask = F::mask_from_bits(bounced);
                beta = Vec3s::select(mask, beta * Vec3s::gather(&factor), beta);
                eta_scale = F::select(mask, eta_scale * F::gather(&eta2), eta_scale);
            }
            bounced |= lanes_bounced;
            depth += 1;

            // Russian roulette, for the paths that bounced.
            if depth > self.rr_depth && bounced != 0 {
                let mut u = F::repeat(0.0f32);
                for i in lanes(bounced) {
                    u.as_mut()[i] = samplers[i].next_1d();
                }
                let q = (beta.max_magnitude() * eta_scale).min(F::splat(survival_cap(self.max_depth)));
                let ended = F::mask_bits(F::gather(&u).ge(q)) & bounced;
                live &= !ended;
                beta = Vec3s::select(F::mask_from_bits(bounced & !ended), beta.over(q), beta);
            }
        }
        l
    }

    /// The light one path's `ray` finds where it ends, at `hit` (`None`:
    /// it leaves the scene), weighed against next-event estimation from
    /// `previous`, the bounce that sent it.
    #[inline(always)]
    fn arrive(
        &self,
        scene: &Scene,
        ray: &Ray,
        previous: &Previous,
        depth: u32,
        nee: Gathering,
        hit: &Option<SurfaceHit>,
    ) -> Option<Found> {
        let shows_emission = scene.settings.shows_emission(depth);
        let Some(hit) = hit else {
            let (Some(env), true) = (scene.environment_light, shows_emission) else {
                return None;
            };
            let dir = ray.dir.normalize();
            // (A portal lets in what the ray's origin sees through it.)
            let found = if nee != Gathering::Hits && !previous.delta {
                let (le, pdf_dir) = scene.background.eval_pdf_from(previous.p, dir, true);
                let pdf_light = light_choice_pmf(scene, previous.p, previous.n, env as usize, true) * pdf_dir;
                Found {
                    le,
                    weight: nee.hit_weight(previous.pdf, pdf_light),
                }
            } else {
                Found {
                    le: scene.background.eval_from(ray.origin, dir),
                    weight: 1.0,
                }
            };
            return Some(found);
        };
        let m = &scene.materials[hit.material as usize];
        let wo_world = -ray.dir.normalize();
        let mut found = None;
        if m.is_emissive() && shows_emission && m.emits_toward(hit, wo_world) {
            let weight = match hit.light {
                Some(li) if nee != Gathering::Hits && !previous.delta => {
                    let pdf_light = light_choice_pmf(scene, previous.p, previous.n, li as usize, true)
                        * scene.lights[li as usize].pdf_li(scene, previous.p, hit);
                    nee.hit_weight(previous.pdf, pdf_light)
                }
                _ => 1.0,
            };
            found = Some(Found {
                le: m.emission_at(&scene.textures, &TexCoord::at(hit)),
                weight,
            });
        }
        found
    }

    /// One path's bounce at `hit`, which its ray reached along `dir`: the
    /// light next-event estimation finds there, and how the path goes on.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn scatter(
        &self,
        scene: &Scene,
        hit: &SurfaceHit,
        dir: glam::Vec3,
        sampler: &mut Sampler,
        wavelength: &mut Option<f32>,
        stats: &mut RayStats,
        strategy: DirectionSampling,
        nee: Gathering,
    ) -> (Option<Direct>, Scatter) {
        let mode = TransportMode::Radiance;
        let m = &scene.materials[hit.material as usize];
        let wo_world = -dir.normalize();
        let tc = TexCoord::at(hit);
        // A mask's cut-out part, chosen with probability 1 − α: the path
        // goes on unchanged (a bounce, as Mitsuba's path counts it).
        // Shadow rays do not see through masks (nor do Mitsuba's), so
        // only this way finds the light behind them: weight 1.
        if m.cut_out(&scene.textures, &tc, || sampler.next_1d()) {
            return (None, Scatter::Pass(hit.spawn_ray(dir)));
        }
        let mut parts = None;
        let mut spectral = Rgb::ONE;
        let bsdf = path_bsdf(
            scene,
            hit.material,
            &tc,
            &mut parts,
            wavelength,
            || sampler.next_1d(),
            &mut spectral,
        );
        let frame = m.shading_frame(&scene.textures, hit, wo_world);
        let wo = frame.to_local(wo_world);
        if !m.two_sided && !bsdf.transmits() && !hit.is_front(wo_world) {
            return (None, Scatter::End); // the back of a one-sided surface is black
        }
        let front_o = hit.ng.dot(wo_world) > 0.0;

        // Next-event estimation.
        let mut direct = None;
        if nee != Gathering::Hits && bsdf.has_smooth() && !scene.lights.is_empty() {
            let chosen = choose_light(scene, hit.p, hit.ns, sampler, true);
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
                        let w = if ls.is_delta || nee != Gathering::Mis {
                            1.0
                        } else {
                            power_heuristic(pdf_light, bsdf.pdf(wo, wi))
                        };
                        direct = Some(Direct {
                            f: f * spectral,
                            li: ls.li,
                            factor: wi.z.abs() * w / pdf_light,
                        });
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
            return (direct, Scatter::End);
        };
        if bs.pdf <= 0.0 || bs.f == Rgb::ZERO || bs.wi.z == 0.0 {
            return (direct, Scatter::End);
        }
        let wi_world = frame.to_world(bs.wi);
        let reflection = bs.wi.z * wo.z > 0.0;
        if (hit.ng.dot(wi_world) > 0.0) != (front_o == reflection) {
            return (direct, Scatter::End); // the shading normal sent the path through the surface
        }
        let mapped = frame.factor(wi_world);
        if mapped == 0.0 {
            return (direct, Scatter::End);
        }
        let scatter = Scatter::Bounce {
            factor: bs.f * spectral * (mapped * bs.wi.z.abs() / bs.pdf),
            eta2: if reflection { 1.0 } else { bs.eta * bs.eta },
            previous: Previous {
                delta: bs.delta,
                pdf: bs.pdf,
                p: hit.p,
                n: hit.ns,
            },
            ray: hit.spawn_ray(wi_world),
        };
        (direct, scatter)
    }
}

/// The bounces of the paths in lanes `on_glass`, whose `hits` are on
/// plain smooth dielectrics ([`LaneBounce::SmoothGlass`]), made in lanes: what
/// [`PathTracer::scatter`] does there (with the same numbers drawn: the
/// lobe choice, then a pair that a delta lobe passes over), in world
/// space. Sets the rays and bounces of the lanes that go on and returns
/// their throughput factors, their radiance scales (η² through
/// refraction, else 1) and the bits of the lanes that go on; the other
/// lanes of `on_glass` end, for what `scatter` ends a path for: a grazing
/// direction, a black tint, or a shading normal that sent the path
/// through the surface.
#[inline(always)]
fn smooth_glass_bounces<F: Floats>(
    scene: &Scene,
    hits: &F::Each<Option<SurfaceHit>>,
    on_glass: u32,
    rays: &mut F::Each<Ray>,
    samplers: &mut [Sampler],
    previous: &mut F::Each<Previous>,
) -> (Vec3s<F>, F, u32) {
    use crate::material::dielectric::smooth_bounce;
    let hit = |i: usize| hits.as_ref()[i].as_ref().filter(|_| on_glass & (1 << i) != 0);
    // The lanes' bits, not a test of each lane (as for every per-lane
    // loop here): which lanes bounce is as good as random from step to
    // step.
    let mut u = F::repeat(0.0f32);
    for i in lanes(on_glass) {
        if hit(i).is_some() {
            u.as_mut()[i] = samplers[i].next_1d();
            samplers[i].skip_2d();
        }
    }
    let u = F::gather(&u);
    // Lanes outside `on_glass` keep a harmless direction, normal and index.
    let (mut d, mut ns, mut ng) = (
        F::repeat(glam::Vec3::Z),
        F::repeat(glam::Vec3::Z),
        F::repeat(glam::Vec3::Z),
    );
    let (mut eta, mut reflect_tint, mut transmit_tint) =
        (F::repeat(1.0f32), F::repeat(Rgb::ZERO), F::repeat(Rgb::ZERO));
    for i in lanes(on_glass) {
        let Some(h) = &hits.as_ref()[i] else { continue };
        d.as_mut()[i] = rays.as_ref()[i].dir;
        (ns.as_mut()[i], ng.as_mut()[i]) = (h.ns, h.ng);
        if let Some(LaneBounce::SmoothGlass {
            eta: e,
            reflect_tint: r,
            transmit_tint: t,
        }) = scene.lane_bounces[h.material as usize]
        {
            (eta.as_mut()[i], reflect_tint.as_mut()[i], transmit_tint.as_mut()[i]) = (e, r, t);
        }
    }
    let (d, ns, ng) = (Vec3s::<F>::gather(&d), Vec3s::<F>::gather(&ns), Vec3s::<F>::gather(&ng));
    let eta = F::gather(&eta);
    let (reflect_tint, transmit_tint) = (Vec3s::<F>::gather(&reflect_tint), Vec3s::<F>::gather(&transmit_tint));

    let zero = F::splat(0.0);
    // wo = −d/|d|, as `glam::Vec3::normalize` rounds it.
    let wo = d.scale(zero - F::splat(1.0) / d.dot(d).sqrt());
    let cos_o = wo.dot(ns);
    let (c, wi, factor) = smooth_bounce(wo, ns, eta, u, reflect_tint, transmit_tint);
    let cos_i = wi.dot(ns);
    // The geometric normal decides reflection or transmission.
    let reflection = F::mask_bits((cos_i * cos_o).gt(zero));
    let front_o = F::mask_bits(ng.dot(wo).gt(zero));
    let front_i = F::mask_bits(ng.dot(wi).gt(zero));
    let grazing = !F::mask_bits(cos_o.abs().gt(zero)) | !F::mask_bits(cos_i.abs().gt(zero));
    let through = front_i ^ !(front_o ^ reflection);
    let black = !F::mask_bits(factor.abs().max_element().gt(zero)) | !F::mask_bits(c.pdf.gt(zero));
    let eta2 = F::select(F::mask_from_bits(reflection), F::splat(1.0), c.etap * c.etap);
    let goes_on = on_glass & !grazing & !through & !black;
    let (wx, wy, wz, pdf) = (wi.x.each_lane(), wi.y.each_lane(), wi.z.each_lane(), c.pdf.each_lane());
    for i in lanes(goes_on) {
        let Some(hit) = hit(i) else { continue };
        previous.as_mut()[i] = Previous {
            delta: true,
            pdf: pdf.as_ref()[i],
            p: hit.p,
            n: hit.ns,
        };
        let wi = glam::Vec3::new(wx.as_ref()[i], wy.as_ref()[i], wz.as_ref()[i]);
        rays.as_mut()[i] = hit.spawn_ray(wi);
    }
    (factor, eta2, goes_on)
}

/// What [`diffuse_bounces`] found: the light of next-event estimation in
/// lanes `lit` (BSDF value, radiance and the factor `|cos θ| · w / pdf`,
/// as [`Direct`]), and in lanes `bounced` the throughput factors of the
/// paths that go on.
struct DiffuseBounces<F: Floats> {
    lit: u32,
    f: Vec3s<F>,
    li: Vec3s<F>,
    s: F,
    factor: Vec3s<F>,
    bounced: u32,
}

/// The bounces of the paths in lanes `on_diffuse`, whose `hits` are on
/// plain Lambertian surfaces ([`LaneBounce::Diffuse`]), made in lanes:
/// what [`PathTracer::scatter`] does there with the BSDF's own sampling,
/// drawing the same numbers (the light's choice and sample, then the lobe
/// choice that one lobe passes over, then the direction's pair). The
/// reflectance, the light's choice and the shadow ray are made lane by
/// lane through the one-path functions, and so is the light sample except
/// from spheres and parallelograms of constant radiance, which are sampled
/// in lanes (in every lane at once where the lanes chose one light); the
/// shading frame, the BSDF's value, density and sample, the MIS weight and
/// the checks in lanes. Sets the
/// rays and bounces of the lanes that go on; the other lanes of
/// `on_diffuse` end, for what `scatter` ends a path for (the back of a
/// one-sided surface, a black reflectance, a grazing direction, a shading
/// normal that sent the path through the surface).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn diffuse_bounces<F: Floats>(
    scene: &Scene,
    hits: &F::Each<Option<SurfaceHit>>,
    on_diffuse: u32,
    rays: &mut F::Each<Ray>,
    samplers: &mut [Sampler],
    previous: &mut F::Each<Previous>,
    nee: Gathering,
    stats: &mut RayStats,
) -> DiffuseBounces<F> {
    use crate::light::{ParallelogramLanes, sample_parallelogram_light_lanes, sample_sphere_light_lanes};
    use crate::material::lambert::{lambert_eval, lambert_pdf, lambert_sample};
    let hit = |i: usize| hits.as_ref()[i].as_ref().filter(|_| on_diffuse & (1 << i) != 0);
    let zero = F::splat(0.0);
    let bits = |m: F::Mask| F::mask_bits(m);
    // Lanes outside `on_diffuse` keep a harmless direction and frame.
    let (mut d, mut ns, mut ng, mut tangent) = (
        F::repeat(glam::Vec3::Z),
        F::repeat(glam::Vec3::Z),
        F::repeat(glam::Vec3::Z),
        F::repeat(glam::Vec3::X),
    );
    let mut one_sided = 0u32;
    for i in lanes(on_diffuse) {
        let Some(h) = &hits.as_ref()[i] else { continue };
        d.as_mut()[i] = rays.as_ref()[i].dir;
        (ns.as_mut()[i], ng.as_mut()[i], tangent.as_mut()[i]) = (h.ns, h.ng, h.tangent);
        one_sided |= (!scene.materials[h.material as usize].two_sided as u32) << i;
    }
    let (d, ns, ng, tangent) = (
        Vec3s::<F>::gather(&d),
        Vec3s::<F>::gather(&ns),
        Vec3s::<F>::gather(&ng),
        Vec3s::<F>::gather(&tangent),
    );
    // wo = −d/|d|, as `glam::Vec3::normalize` rounds it; its cosine is
    // its z in the shading frame.
    let wo = d.scale(zero - F::splat(1.0) / d.dot(d).sqrt());
    let cos_o = wo.dot(ns);
    let front_o = bits(ng.dot(wo).gt(zero));
    // The back of a one-sided surface is black, and draws nothing.
    let active = on_diffuse & !(one_sided & !front_o);

    // Lane by lane: the reflectance, the light sample, the direction's numbers.
    let sampling_lights = nee != Gathering::Hits && !scene.lights.is_empty();
    let mut samples = F::repeat(None::<crate::light::LightSample>);
    let mut pdf_light = F::repeat(0.0f32);
    let mut u = F::repeat(glam::Vec2::ZERO);
    let mut albedo = F::repeat(Rgb::ZERO);
    // The lanes whose chosen light is sampled below, in lanes: a sphere
    // (by its cone) or a parallelogram (by area) of constant radiance; the
    // light, its probability and radiance, and the numbers drawn for it
    // (those `Light::sample_li_drawing` draws: a pick, read by a sphere
    // alone, then a pair).
    let (mut on_sphere, mut on_quad) = (0u32, 0u32);
    let mut chosen_light = F::repeat(0u32);
    let mut pmf = F::repeat(0.0f32);
    let mut radiance = F::repeat(Rgb::ZERO);
    let mut light_u = F::repeat((0.0f32, glam::Vec2::ZERO));
    for i in lanes(active) {
        let Some(h) = hit(i) else { continue };
        let sampler = &mut samplers[i];
        if let crate::material::MaterialKind::Diffuse { reflectance } = &scene.materials[h.material as usize].kind {
            albedo.as_mut()[i] = reflectance.eval(&scene.textures, &TexCoord::at(h));
        }
        if sampling_lights {
            let chosen = choose_light(scene, h.p, h.ns, sampler, true);
            let sample = match chosen {
                Some((light, p)) => {
                    let l = &scene.lights[light];
                    let lane_light = l
                        .constant_sphere()
                        .map(|s| (true, s.3))
                        .or_else(|| l.constant_parallelogram().map(|q| (false, q.2)));
                    match lane_light {
                        Some((sphere, rgb)) => {
                            if sphere {
                                on_sphere |= 1 << i;
                                light_u.as_mut()[i] = (sampler.next_1d(), sampler.next_2d());
                            } else {
                                on_quad |= 1 << i;
                                sampler.skip_1d();
                                light_u.as_mut()[i] = (0.0, sampler.next_2d());
                            }
                            (chosen_light.as_mut()[i], pmf.as_mut()[i], radiance.as_mut()[i]) = (light as u32, p, rgb);
                            None
                        }
                        None => l.sample_li_drawing(scene, h.p, sampler, true),
                    }
                }
                None => {
                    // No light reaches the point: its numbers are passed over.
                    sampler.skip_1d();
                    sampler.skip_2d();
                    None
                }
            };
            pdf_light.as_mut()[i] = sample.map_or(0.0, |ls| ls.pdf) * chosen.map_or(0.0, |(_, pmf)| pmf);
            samples.as_mut()[i] = sample;
        }
        // The lobe choice, which one lobe passes over.
        sampler.skip_1d();
        u.as_mut()[i] = sampler.next_2d();
    }
    // The samples made in lanes, in the lanes `in_lanes` (the others' are
    // in `samples`): direction, radiance, point and density.
    let mut in_lanes = 0u32;
    let (mut lane_wi, mut lane_li, mut lane_lp) = (
        Vec3s::<F>::splat(glam::Vec3::Z),
        Vec3s::<F>::splat(glam::Vec3::ZERO),
        Vec3s::<F>::splat(glam::Vec3::ZERO),
    );
    let mut lane_pdf = zero;
    if on_sphere | on_quad != 0 {
        let p = Vec3s::<F>::gather(&F::each(|i| hit(i).map_or(glam::Vec3::ZERO, |h| h.p)));
        let ux = F::gather(&F::each(|i| light_u.as_ref()[i].1.x));
        let uy = F::gather(&F::each(|i| light_u.as_ref()[i].1.y));
        let first = |group: u32| chosen_light.as_ref()[group.trailing_zeros() as usize];
        // The light of lane `i`, one of `group`'s, or the group's first.
        let light_of = |group: u32, i: usize| {
            let l = if group & (1 << i) != 0 {
                chosen_light.as_ref()[i]
            } else {
                first(group)
            };
            &scene.lights[l as usize]
        };
        // Lanes that all chose one light take it in every lane.
        let one_light = |group: u32| lanes(group).all(|i| chosen_light.as_ref()[i] == first(group));
        // The group's valid samples, taken into the lanes' (a function, not
        // a closure: a closure is not built for the vector extensions that
        // its enclosing function is, and its lane operations became calls).
        #[inline(always)]
        fn take<F: Floats>(
            group: u32,
            (wi, lp, pdf, valid): (Vec3s<F>, Vec3s<F>, F, u32),
            (lane_wi, lane_lp, lane_pdf, in_lanes): (&mut Vec3s<F>, &mut Vec3s<F>, &mut F, &mut u32),
        ) {
            let took = group & valid;
            let mask = F::mask_from_bits(took);
            *lane_wi = Vec3s::select(mask, wi, *lane_wi);
            *lane_lp = Vec3s::select(mask, lp, *lane_lp);
            *lane_pdf = F::select(mask, pdf, *lane_pdf);
            *in_lanes |= took;
        }
        if on_sphere != 0 {
            // Sphere lights of constant radiance, sampled by their cones.
            let sphere = |i: usize| light_of(on_sphere, i).constant_sphere().expect("a sphere light");
            let (center, radius) = if one_light(on_sphere) {
                let (c, r, _, _) = sphere(on_sphere.trailing_zeros() as usize);
                (Vec3s::splat(c), F::splat(r))
            } else {
                (
                    Vec3s::<F>::gather(&F::each(|i| sphere(i).0)),
                    F::gather(&F::each(|i| sphere(i).1)),
                )
            };
            let two_sided = lanes(on_sphere).fold(0u32, |b, i| b | ((sphere(i).2 as u32) << i));
            let (wi, lp, pdf, valid, outside) =
                sample_sphere_light_lanes(center, radius, F::mask_from_bits(two_sided), p, ux, uy);
            take(
                on_sphere,
                (wi, lp, pdf, valid),
                (&mut lane_wi, &mut lane_lp, &mut lane_pdf, &mut in_lanes),
            );
            for i in lanes(on_sphere & !valid & !outside) {
                // From inside the sphere, by area, lane by lane.
                let (Some(h), (u_pick, u)) = (hit(i), light_u.as_ref()[i]) else {
                    continue;
                };
                let sample = light_of(on_sphere, i).sample_li(scene, h.p, u_pick, u, true);
                pdf_light.as_mut()[i] = sample.map_or(0.0, |ls| ls.pdf) * pmf.as_ref()[i];
                samples.as_mut()[i] = sample;
            }
        }
        if on_quad != 0 {
            // Parallelogram lights of constant radiance, sampled by area.
            let quad = |i: usize| {
                light_of(on_quad, i)
                    .constant_parallelogram()
                    .expect("a parallelogram light")
            };
            let r = if one_light(on_quad) {
                ParallelogramLanes::<F>::of(&quad(on_quad.trailing_zeros() as usize).0)
            } else {
                ParallelogramLanes::<F>::gather(&F::each(|i| quad(i).0))
            };
            let two_sided = lanes(on_quad).fold(0u32, |b, i| b | ((quad(i).1 as u32) << i));
            take(
                on_quad,
                sample_parallelogram_light_lanes(r, F::mask_from_bits(two_sided), p, ux, uy),
                (&mut lane_wi, &mut lane_lp, &mut lane_pdf, &mut in_lanes),
            );
        }
        if in_lanes != 0 {
            lane_li = if one_light(on_sphere | on_quad) {
                Vec3s::splat(radiance.as_ref()[in_lanes.trailing_zeros() as usize])
            } else {
                Vec3s::<F>::gather(&radiance)
            };
            // As `ls.pdf * pmf` lane by lane.
            lane_pdf = lane_pdf * F::gather(&pmf);
        }
    }
    let albedo = Vec3s::<F>::gather(&albedo);
    let black = !bits(albedo.abs().max_element().gt(zero));

    // Next-event estimation: the BSDF's value and the checks in lanes, the
    // shadow rays lane by lane.
    let mut lit = 0u32;
    let (mut f, mut li, mut s) = (Vec3s::splat(Rgb::ZERO), Vec3s::splat(Rgb::ZERO), zero);
    if sampling_lights {
        // The lanes whose samples were made one by one.
        let one_by_one = lanes(active & !in_lanes).fold(0u32, |b, i| b | ((samples.as_ref()[i].is_some() as u32) << i));
        let has = in_lanes | one_by_one;
        let sample = |i: usize| samples.as_ref()[i].filter(|_| one_by_one & (1 << i) != 0);
        let (wi, pdf_light) = if one_by_one == 0 {
            (lane_wi, lane_pdf)
        } else {
            let mask = F::mask_from_bits(in_lanes);
            let wi = Vec3s::<F>::gather(&F::each(|i| sample(i).map_or(glam::Vec3::Z, |ls| ls.wi)));
            li = Vec3s::<F>::gather(&F::each(|i| sample(i).map_or(Rgb::ZERO, |ls| ls.li)));
            (
                Vec3s::select(mask, lane_wi, wi),
                F::select(mask, lane_pdf, F::gather(&pdf_light)),
            )
        };
        li = Vec3s::select(F::mask_from_bits(in_lanes), lane_li, li);
        let cos_i = wi.dot(ns);
        f = lambert_eval(albedo, cos_o, cos_i);
        let same = bits((cos_i * cos_o).gt(zero));
        // The geometric normal decides reflection or transmission.
        let front_i = bits(ng.dot(wi).gt(zero));
        let consistent = !((front_i ^ front_o) ^ !same);
        let dark = !bits(li.abs().max_element().gt(zero));
        let tested = has & same & !black & !dark & consistent;
        let (lx, ly, lz) = (lane_lp.x.each_lane(), lane_lp.y.each_lane(), lane_lp.z.each_lane());
        for i in lanes(tested) {
            let Some(h) = hit(i) else { continue };
            let target = match sample(i) {
                Some(ls) => ls.target,
                None => ShadowTarget::Point(glam::Vec3::new(lx.as_ref()[i], ly.as_ref()[i], lz.as_ref()[i])),
            };
            stats.rays += 1;
            let shadow = match target {
                ShadowTarget::Point(p) => h.spawn_ray_to(p),
                ShadowTarget::Infinity => h.spawn_ray(wi.lane(i)),
            };
            if !scene.occluded(&shadow) {
                lit |= 1 << i;
            }
        }
        if lit != 0 {
            let w = if nee == Gathering::Mis {
                let delta = lanes(lit).fold(0u32, |b, i| b | ((sample(i).is_some_and(|ls| ls.is_delta) as u32) << i));
                let pdf_bsdf = lambert_pdf(cos_o, cos_i);
                F::select(
                    F::mask_from_bits(delta),
                    F::splat(1.0),
                    power_heuristic_lanes(pdf_light, pdf_bsdf),
                )
            } else {
                F::splat(1.0)
            };
            s = cos_i.abs() * w / pdf_light;
        }
    }

    // The BSDF's sample (cosine-weighted, on wo's side), in lanes.
    let u = (
        F::gather(&F::each(|i| u.as_ref()[i].x)),
        F::gather(&F::each(|i| u.as_ref()[i].y)),
    );
    let local = lambert_sample(cos_o, u.0, u.1);
    let same = bits((local.z * cos_o).gt(zero));
    let pdf = lambert_pdf(cos_o, local.z);
    let f_bounce = lambert_eval(albedo, cos_o, local.z);
    // The frame (n, tangent, n × tangent) to world space.
    let bitangent = Vec3s {
        x: ns.y * tangent.z - tangent.y * ns.z,
        y: ns.z * tangent.x - tangent.z * ns.x,
        z: ns.x * tangent.y - tangent.x * ns.y,
    };
    let wi = tangent.scale(local.x) + bitangent.scale(local.y) + ns.scale(local.z);
    let front_i = bits(ng.dot(wi).gt(zero));
    let through = front_i ^ !(front_o ^ same);
    let ends = !same | black | !bits(pdf.gt(zero)) | !bits(local.z.abs().gt(zero)) | through;
    let bounced = active & !ends;
    let factor = f_bounce.scale(local.z.abs() / pdf);
    let (wx, wy, wz, pdfs) = (wi.x.each_lane(), wi.y.each_lane(), wi.z.each_lane(), pdf.each_lane());
    for i in lanes(bounced) {
        let Some(h) = hit(i) else { continue };
        previous.as_mut()[i] = Previous {
            delta: false,
            pdf: pdfs.as_ref()[i],
            p: h.p,
            n: h.ns,
        };
        rays.as_mut()[i] = h.spawn_ray(glam::Vec3::new(wx.as_ref()[i], wy.as_ref()[i], wz.as_ref()[i]));
    }
    DiffuseBounces {
        lit,
        f,
        li,
        s,
        factor,
        bounced,
    }
}

/// [`power_heuristic`] over lanes: 1 where `pdf_a` is infinite, 0 where
/// both densities are 0.
#[inline(always)]
fn power_heuristic_lanes<F: Floats>(pdf_a: F, pdf_b: F) -> F {
    let (a, b) = (pdf_a * pdf_a, pdf_b * pdf_b);
    let zero = F::splat(0.0);
    let sum = a + b;
    let w = F::select(sum.gt(zero), a / sum, zero);
    F::select(a.ge(F::splat(f32::INFINITY)), F::splat(1.0), w)
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

    /// On the suite's scenes with diffuse surfaces, the bounces made in
    /// lanes (`diffuse_bounces`, one lane) are those `PathTracer::scatter`
    /// makes, bit for bit: the next ray, the bounce, the throughput factor,
    /// the light found by next-event estimation, and the numbers drawn,
    /// for every way of gathering light; the hits include the backs of
    /// one-sided surfaces.
    #[test]
    fn diffuse_bounces_in_lanes_are_those_made_one_by_one() {
        use crate::sampling::rng::Pcg32;
        let suite = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("bench/suite");
        let defines = [
            ("res".to_string(), "8".to_string()),
            ("spp".to_string(), "4".to_string()),
        ];
        let mut rng = Pcg32::new(5, 0);
        let mut ends = 0;
        for name in ["cornell-box", "caustic", "smallpt-explicit", "many-lights"] {
            let d = crate::scene::load(&suite.join(format!("{name}.xml")), &defines).unwrap();
            let scene = crate::scene::build(&d).unwrap();
            let s = &scene.settings;
            let tracer = PathTracer::with_settings(s);
            let (mut bounced, mut lit, mut ended) = (0, 0, 0);
            let mut stats = RayStats::default();
            for k in 0..1500u32 {
                let film = glam::Vec2::new(rng.next_f32() * s.width as f32, rng.next_f32() * s.height as f32);
                let camera_ray = scene.camera.generate_ray(film, glam::Vec2::splat(0.5));
                let Some(first) = scene.intersect(&camera_ray) else {
                    continue;
                };
                // Every other ray leaves the first hit in a random direction,
                // which finds backs too.
                let ray = if k % 2 == 0 {
                    camera_ray
                } else {
                    let u = glam::Vec2::new(rng.next_f32(), rng.next_f32());
                    first.spawn_ray(crate::sampling::warp::sample_sphere_uniform(u))
                };
                let Some(hit) = scene.intersect(&ray) else { continue };
                if scene.lane_bounces.get(hit.material as usize) != Some(&Some(LaneBounce::Diffuse)) {
                    continue;
                }
                for nee in [Gathering::Hits, Gathering::Nee, Gathering::Mis] {
                    let mut alone = Sampler::new(s.sampler, s.spp, s.seed);
                    alone.start_pixel_sample(k % s.width, k / s.width % s.height, k % s.spp);
                    let mut lane = alone.clone();
                    let (direct, scatter) = tracer.scatter(
                        &scene,
                        &hit,
                        ray.dir,
                        &mut alone,
                        &mut None,
                        &mut stats,
                        DirectionSampling::Bsdf,
                        nee,
                    );
                    let mut rays = [ray];
                    let mut previous = [Previous {
                        delta: true,
                        pdf: 0.0,
                        p: glam::Vec3::ZERO,
                        n: glam::Vec3::ZERO,
                    }];
                    let made = diffuse_bounces::<f32>(
                        &scene,
                        &[Some(hit)],
                        1,
                        &mut rays,
                        std::slice::from_mut(&mut lane),
                        &mut previous,
                        nee,
                        &mut stats,
                    );
                    let bits = |v: glam::Vec3| v.to_array().map(f32::to_bits);
                    match direct {
                        Some(l) => {
                            assert_eq!(made.lit, 1, "{name}: light found one by one only");
                            assert_eq!(bits(l.f), bits(made.f.lane(0)), "{name}");
                            assert_eq!(bits(l.li), bits(made.li.lane(0)), "{name}");
                            assert_eq!(l.factor.to_bits(), made.s.lane(0).to_bits(), "{name}");
                            lit += 1;
                        }
                        None => assert_eq!(made.lit, 0, "{name}: light found in lanes only"),
                    }
                    match scatter {
                        Scatter::Bounce {
                            factor,
                            eta2,
                            previous: p,
                            ray: next,
                        } => {
                            assert_eq!(made.bounced, 1, "{name}: a bounce one by one only");
                            assert_eq!(bits(factor), bits(made.factor.lane(0)), "{name}");
                            assert_eq!(eta2, 1.0);
                            assert_eq!(next, rays[0], "{name}");
                            assert_eq!(
                                (p.delta, p.pdf.to_bits(), bits(p.p), bits(p.n)),
                                (
                                    previous[0].delta,
                                    previous[0].pdf.to_bits(),
                                    bits(previous[0].p),
                                    bits(previous[0].n)
                                ),
                                "{name}"
                            );
                            bounced += 1;
                        }
                        Scatter::End => {
                            assert_eq!(made.bounced, 0, "{name}: a bounce in lanes only");
                            ended += 1;
                        }
                        Scatter::Pass(_) => panic!("{name}: a diffuse surface has no cut-out"),
                    }
                    assert_eq!(
                        alone.next_1d().to_bits(),
                        lane.next_1d().to_bits(),
                        "{name}: the same numbers drawn"
                    );
                }
            }
            assert!(bounced > 500 && lit > 100, "{name}: {bounced} bounces, {lit} lit");
            ends += ended;
        }
        assert!(ends > 0, "some paths end");
    }

    #[test]
    fn names_round_trip() {
        for n in PathSampling::NAMES {
            assert_eq!(PathSampling::from_name(n).unwrap().name(), n);
        }
    }
}
