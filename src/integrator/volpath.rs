//! The volumetric path tracer: Kajiya's path tracer extended to the
//! radiative transfer equation, for scenes with participating media
//! ([`crate::media`]).
//!
//! Along each segment inside a medium, tentative collisions are sampled
//! against the medium's majorant σ_maj, and each is an absorption (σa),
//! a real scattering (σs) or a null collision (σn = σ_maj − σt) in
//! proportion to those coefficients: delta tracking, unbiased in a
//! heterogeneous medium. Shadow rays weigh light by the transmittance
//! estimated by ratio tracking (the product of σn/σ_maj over their
//! collisions), and pass through surfaces that are not there (a medium's
//! boundary) or thin sheets, with the sheet's transmission.
//!
//! Distances are sampled in one channel, the path's hero channel, drawn
//! at random; the other channels are weighed by the ratios of their
//! densities to the hero's, averaged over channels as one-sample MIS
//! (the null-scattering path integral of Miller, Georgiev and Jarosz
//! 2019, as pbrt-v4's `VolPathIntegrator`, section 14.2.3). A chromatic
//! medium (σt differing by channel) is then as quiet as a grey one. The
//! rescaled path densities `r_u` (of the path as sampled) and `r_l` (of
//! the same path with its last vertex found by light sampling) carry
//! both that average and the balance heuristic between BSDF or phase
//! sampling and next-event estimation.
//!
//! A null surface or a thin sheet's transmission does not count as a
//! bounce (Mitsuba's `volpath` does the same): `max_depth` counts the
//! segments between scattering events, as in [`super::path`].

use super::{Integrator, RayStats, choose_light, light_choice_pmf, path_bsdf, survival_cap};
use crate::color::Rgb;
use crate::geometry::interaction::SHADOW_EPSILON;
use crate::geometry::{Ray, SurfaceHit};
use crate::light::ShadowTarget;
use crate::material::{Bsdf, MaterialKind, ShadingFrame, TransportMode};
use crate::media::{Phase, sample_majorant};
use crate::sampling::Sampler;
use crate::sampling::rng::{Pcg32, hash_u64s};
use crate::scene::Scene;
use crate::texture::TexCoord;
use glam::Vec3;

/// The volumetric path tracer.
#[derive(Clone, Copy, Debug)]
pub struct VolPathTracer {
    /// Longest path, in segments from the camera.
    pub max_depth: u32,
    /// Segments after which Russian roulette starts.
    pub rr_depth: u32,
    /// `None`: free flights by delta tracking and transmittance by ratio
    /// tracking (unbiased); `Some(step)`: both by fixed-step ray marching
    /// with steps of this length (biased where a medium varies within a
    /// step; converges as the step shrinks).
    pub march_step: Option<f32>,
}

/// The mean of the three channels.
#[inline]
fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) * (1.0 / 3.0)
}

/// Where a light is sampled from.
enum Vertex<'a> {
    /// A surface point with its BSDF.
    Surface {
        hit: &'a SurfaceHit,
        frame: &'a ShadingFrame,
        bsdf: &'a Bsdf<'a>,
        /// Direction toward the previous vertex, local frame.
        wo: Vec3,
    },
    /// A point in a medium with its phase function.
    Medium {
        p: Vec3,
        /// Direction toward the previous vertex.
        wo: Vec3,
        phase: Phase,
        /// The path's time, which its rays keep.
        time: f32,
    },
}

/// The state of one path.
struct PathState {
    /// Radiance found so far.
    l: Rgb,
    /// Throughput.
    beta: Rgb,
    /// Rescaled density of the path as sampled, per channel.
    r_u: Rgb,
    /// Rescaled density of the path with its last vertex light-sampled.
    r_l: Rgb,
    /// Scattering events so far.
    depth: u32,
    /// Whether the last scattering was a delta lobe (or there was none).
    specular: bool,
    /// The last scattering point and the normal its light choice used.
    prev_p: Vec3,
    prev_n: Vec3,
}

impl VolPathTracer {
    /// Radiance from the light sampled at `vertex` in medium `medium`
    /// toward it, weighed by the transmittance on the way and by MIS
    /// against the vertex's own sampling; `r_p` is the path's `r_u`.
    #[allow(clippy::too_many_arguments)]
    fn sample_light(
        &self,
        scene: &Scene,
        vertex: &Vertex,
        medium: Option<u32>,
        beta: Rgb,
        r_p: Rgb,
        channel: usize,
        sampler: &mut Sampler,
        rng: &mut Pcg32,
        stats: &mut RayStats,
    ) -> Rgb {
        let (p, n) = match vertex {
            Vertex::Surface { hit, .. } => (hit.p, hit.ns),
            Vertex::Medium { p, .. } => (*p, Vec3::ZERO),
        };
        let chosen = choose_light(scene, p, n, sampler, true);
        let sample = match chosen {
            Some((light, _)) => scene.lights[light].sample_li_drawing(scene, p, sampler, true),
            None => {
                sampler.skip_1d();
                sampler.skip_2d();
                None
            }
        };
        let Some(ls) = sample else {
            return Rgb::ZERO;
        };
        if ls.li == Rgb::ZERO || ls.pdf <= 0.0 {
            return Rgb::ZERO;
        }
        let pmf = chosen.map_or(0.0, |(_, pmf)| pmf);
        let (f_hat, scatter_pdf, mut shadow, mut medium) = match vertex {
            Vertex::Surface { hit, frame, bsdf, wo } => {
                let wi = frame.to_local(ls.wi);
                let front_o = hit.ng.dot(frame.to_world(*wo)) > 0.0;
                let front_i = hit.ng.dot(ls.wi) > 0.0;
                // The geometric normal decides reflection or transmission.
                if (front_i == front_o) != (wi.z * wo.z > 0.0) {
                    return Rgb::ZERO;
                }
                let f = bsdf.eval(*wo, wi, TransportMode::Radiance) * (wi.z.abs() * frame.factor(ls.wi));
                let shadow = match ls.target {
                    ShadowTarget::Point(q) => hit.spawn_ray_to(q),
                    ShadowTarget::Infinity => hit.spawn_ray(ls.wi),
                };
                let medium = match scene.material_media[hit.material as usize] {
                    Some(interface) => interface.toward(ls.wi, hit.ng),
                    None => medium,
                };
                (f, bsdf.pdf(*wo, wi), shadow, medium)
            }
            Vertex::Medium { p, wo, phase, time } => {
                let f = phase.eval(*wo, ls.wi);
                let shadow = match ls.target {
                    ShadowTarget::Point(q) => Ray::with_interval(*p, q - *p, 0.0, SHADOW_EPSILON),
                    ShadowTarget::Infinity => Ray::new(*p, ls.wi),
                }
                .at_time(*time);
                (Rgb::splat(f), f, shadow, medium)
            }
        };
        if f_hat == Rgb::ZERO {
            return Rgb::ZERO;
        }

        // The transmittance to the light, by ratio tracking through media
        // and past the surfaces light crosses unchanged.
        let mut t_ray = Rgb::ONE;
        let mut r_l = Rgb::ONE;
        let mut r_u = Rgb::ONE;
        loop {
            stats.rays += 1;
            let hit = scene.intersect(&shadow);
            let len = shadow.dir.length();
            let dir = shadow.dir / len;
            if let Some(h) = &hit {
                let m = &scene.materials[h.material as usize];
                let thin = matches!(m.kind, MaterialKind::Thin { .. });
                if !thin && m.opacity.is_none() {
                    return Rgb::ZERO;
                }
                let tc = TexCoord::at(h);
                // Light passes a mask's cut-out part (1 − α) and what the
                // surface itself lets through unchanged.
                let alpha = m.opacity_at(&scene.textures, &tc);
                let sheet = if thin {
                    let frame = m.shading_frame(&scene.textures, h, -dir);
                    m.bsdf(&scene.textures, &tc).pass_through(frame.to_local(-dir))
                } else {
                    Rgb::ZERO
                };
                t_ray *= Rgb::splat(1.0 - alpha) + sheet * alpha;
            }
            if let Some(mi) = medium {
                let t_end = hit.as_ref().map_or(shadow.t_max, |h| h.t);
                let segment = Ray::with_interval(shadow.at(shadow.t_min), dir, 0.0, (t_end - shadow.t_min) * len);
                let medium = &scene.media[mi as usize];
                if !self.shadow_transmittance(medium, &segment, channel, &mut t_ray, &mut r_l, &mut r_u, rng) {
                    return Rgb::ZERO;
                }
            }
            if t_ray == Rgb::ZERO || !t_ray.is_finite() {
                return Rgb::ZERO;
            }
            let Some(h) = hit else { break };
            if let Some(interface) = scene.material_media[h.material as usize] {
                medium = interface.toward(dir, h.ng);
            }
            shadow = match ls.target {
                ShadowTarget::Point(q) => h.spawn_ray_to(q),
                ShadowTarget::Infinity => h.spawn_ray(dir),
            };
        }
        let r_l = r_l * r_p * (ls.pdf * pmf);
        let r_u = r_u * r_p * scatter_pdf;
        let denom = if ls.is_delta { mean(r_l) } else { mean(r_l + r_u) };
        if denom <= 0.0 {
            return Rgb::ZERO;
        }
        beta * f_hat * t_ray * ls.li / denom
    }
}

impl Integrator for VolPathTracer {
    fn radiance(&self, scene: &Scene, camera_ray: &Ray, sampler: &mut Sampler, stats: &mut RayStats) -> Rgb {
        let channel = ((sampler.next_1d() * 3.0) as usize).min(2);
        let seed = hash_u64s(&[
            sampler.next_1d().to_bits() as u64,
            sampler.next_1d().to_bits() as u64,
            camera_ray.dir.x.to_bits() as u64 | (camera_ray.dir.y.to_bits() as u64) << 32,
        ]);
        let mut rng = Pcg32::new(seed, 0);
        let mut s = PathState {
            l: Rgb::ZERO,
            beta: Rgb::ONE,
            r_u: Rgb::ONE,
            r_l: Rgb::ONE,
            depth: 0,
            specular: true,
            prev_p: camera_ray.origin,
            prev_n: Vec3::ZERO,
        };
        let mut eta_scale = 1.0f32;
        // The path's wavelength, once it has met a dispersive glass.
        let mut wavelength = None;
        let mut medium = scene.camera_medium;
        let mut ray = *camera_ray;

        loop {
            stats.rays += 1;
            let hit = scene.intersect(&ray);
            let len = ray.dir.length();
            let dir = ray.dir / len;

            if let Some(mi) = medium {
                let t_end = hit.as_ref().map_or(ray.t_max, |h| h.t);
                let segment = Ray::with_interval(ray.at(ray.t_min), dir, 0.0, (t_end - ray.t_min) * len);
                let walk = Walk {
                    scene,
                    medium: mi,
                    channel,
                    time: ray.time,
                };
                let outcome = match self.march_step {
                    None => self.track(&walk, &segment, &mut s, sampler, &mut rng, stats),
                    Some(step) => self.march(&walk, &segment, step, &mut s, sampler, &mut rng, stats),
                };
                match outcome {
                    Segment::Ended => return s.l,
                    Segment::Scattered(next) => {
                        ray = next;
                        if !self.roulette(&mut s, eta_scale, sampler) {
                            return s.l;
                        }
                        continue;
                    }
                    Segment::Crossed => {}
                }
            }

            // Scattering events so far, plus the camera ray: the segment
            // that met what it meets.
            let shows_emission = scene.settings.shows_emission(s.depth + 1);
            let Some(hit) = hit else {
                if let (Some(env), true) = (scene.environment_light, shows_emission) {
                    let (prev_p, prev_n) = (s.prev_p, s.prev_n);
                    let (le, pdf_dir) = if s.specular {
                        (scene.background.eval_from(prev_p, dir), 0.0)
                    } else {
                        scene.background.eval_pdf_from(prev_p, dir, true)
                    };
                    self.add_emission(&mut s, le, || {
                        light_choice_pmf(scene, prev_p, prev_n, env as usize, true) * pdf_dir
                    });
                }
                return s.l;
            };
            let m = &scene.materials[hit.material as usize];
            let wo_world = -dir;
            if m.is_emissive() && shows_emission && m.emits_toward(&hit, wo_world) {
                let le = m.emission_at(&scene.textures, &TexCoord::at(&hit));
                let (prev_p, prev_n) = (s.prev_p, s.prev_n);
                self.add_emission(&mut s, le, || match hit.light {
                    Some(li) => {
                        light_choice_pmf(scene, prev_p, prev_n, li as usize, true)
                            * scene.lights[li as usize].pdf_li(scene, prev_p, &hit)
                    }
                    None => 0.0,
                });
            }
            let interface = scene.material_media[hit.material as usize];
            let cross = |medium: Option<u32>, w: Vec3| match interface {
                Some(i) => i.toward(w, hit.ng),
                None => medium,
            };
            // A surface that is not there, or a mask's cut-out part
            // (chosen with probability 1 − α): the path goes on unchanged,
            // no bounce.
            let cut_out = m.cut_out(&scene.textures, &TexCoord::at(&hit), || sampler.next_1d());
            if cut_out || matches!(m.kind, MaterialKind::Thin { eta, .. } if eta == 1.0) {
                medium = cross(medium, dir);
                ray = hit.spawn_ray(dir);
                continue;
            }

            let tc = TexCoord::at(&hit);
            let mut parts = None;
            let mut spectral = Rgb::ONE;
            let bsdf = path_bsdf(
                scene,
                hit.material,
                &tc,
                &mut parts,
                &mut wavelength,
                || sampler.next_1d(),
                &mut spectral,
            );
            s.beta *= spectral;
            let frame = m.shading_frame(&scene.textures, &hit, wo_world);
            let wo = frame.to_local(wo_world);
            if !m.two_sided && !bsdf.transmits() && !hit.is_front(wo_world) {
                return s.l; // the back of a one-sided surface is black
            }
            let front_o = hit.ng.dot(wo_world) > 0.0;
            let u_lobe = sampler.next_1d();
            let u_dir = sampler.next_2d();

            // A thin sheet lets the path through without a bounce, or
            // reflects it (a bounce).
            if bsdf.pass_through(wo) != Rgb::ZERO {
                let Some(bs) = bsdf.sample(wo, u_lobe, u_dir, TransportMode::Radiance) else {
                    return s.l;
                };
                if bsdf.passed_through(wo, &bs) {
                    s.beta *= bs.weight();
                    medium = cross(medium, dir);
                    ray = hit.spawn_ray(dir);
                    continue;
                }
            }

            s.depth += 1;
            if s.depth >= self.max_depth {
                return s.l;
            }
            if bsdf.has_smooth() && !scene.lights.is_empty() {
                let vertex = Vertex::Surface {
                    hit: &hit,
                    frame: &frame,
                    bsdf: &bsdf,
                    wo,
                };
                s.l += self.sample_light(scene, &vertex, medium, s.beta, s.r_u, channel, sampler, &mut rng, stats);
            }
            let Some(bs) = bsdf.sample(wo, u_lobe, u_dir, TransportMode::Radiance) else {
                return s.l;
            };
            if bs.pdf <= 0.0 || bs.f == Rgb::ZERO || bs.wi.z == 0.0 {
                return s.l;
            }
            let wi_world = frame.to_world(bs.wi);
            let reflection = bs.wi.z * wo.z > 0.0;
            if (hit.ng.dot(wi_world) > 0.0) != (front_o == reflection) {
                return s.l; // the shading normal sent the path through the surface
            }
            let mapped = frame.factor(wi_world);
            if mapped == 0.0 {
                return s.l;
            }
            s.beta *= bs.weight() * mapped;
            s.r_l = s.r_u / bs.pdf;
            s.specular = bs.delta;
            if !reflection {
                eta_scale *= bs.eta * bs.eta;
            }
            s.prev_p = hit.p;
            s.prev_n = hit.ns;
            medium = cross(medium, wi_world);
            ray = hit.spawn_ray(wi_world);
            if !self.roulette(&mut s, eta_scale, sampler) {
                return s.l;
            }
        }
    }
}

/// What a path segment through a medium ended in.
enum Segment {
    /// The path ended there (absorbed, too long, or nothing left to carry).
    Ended,
    /// It scattered: the next ray.
    Scattered(Ray),
    /// It crossed the medium to the segment's end (a surface or nowhere).
    Crossed,
}

/// The medium a segment runs in, with what every collision needs.
struct Walk<'a> {
    scene: &'a Scene,
    medium: u32,
    channel: usize,
    /// The path's time.
    time: f32,
}

/// exp(−τ) per channel.
#[inline]
fn exp_neg(tau: Rgb) -> Rgb {
    Rgb::new((-tau.x).exp(), (-tau.y).exp(), (-tau.z).exp())
}

/// The steps of fixed-step ray marching over `segment` (unit direction, t
/// in [0, t_max]) inside `medium`: the first step jittered by `jitter`
/// in [0, 1) so that the quadrature's error is noise, not a pattern. Each
/// step [a, b] is passed to `visit` with the medium's coefficients at its
/// middle; `visit` returns whether to go on.
fn march_steps(
    medium: &crate::media::Medium,
    segment: &Ray,
    step: f32,
    jitter: f32,
    mut visit: impl FnMut(f32, f32, &crate::media::MediumPoint) -> bool,
) {
    let Some((t0, t1)) = medium.segment(segment.origin, segment.dir, segment.t_max) else {
        return;
    };
    if !(t1 - t0).is_finite() {
        // An unbounded segment (the camera in fog, looking at the sky):
        // marched until the transmittance is negligible, at most 2^20 steps.
        let sigma = medium.majorant().max_element();
        let reach = if sigma > 0.0 { 40.0 / sigma } else { 0.0 };
        return march_steps(
            medium,
            &Ray::with_interval(segment.origin, segment.dir, 0.0, t0 + reach),
            step,
            jitter,
            visit,
        );
    }
    let step = step.max((t1 - t0) / (1 << 20) as f32);
    let mut a = t0;
    let mut b = (t0 + step * jitter.max(1e-3)).min(t1);
    while a < t1 {
        let mp = medium.point(segment.at(0.5 * (a + b)));
        if !visit(a, b, &mp) {
            return;
        }
        a = b;
        b = (b + step).min(t1);
    }
}

impl VolPathTracer {
    /// A segment by delta tracking against the majorant (unbiased).
    fn track(
        &self,
        walk: &Walk,
        segment: &Ray,
        s: &mut PathState,
        sampler: &mut Sampler,
        rng: &mut Pcg32,
        stats: &mut RayStats,
    ) -> Segment {
        let channel = walk.channel;
        let medium = &walk.scene.media[walk.medium as usize];
        let mut outcome = Segment::Crossed;
        let u = sampler.next_1d();
        let mut u_mode = sampler.next_1d();
        let t_maj = sample_majorant(medium, segment, channel, u, rng, |p, mp, sigma_maj, t_maj, rng| {
            // Emission along the way.
            if s.depth < self.max_depth && mp.le != Rgb::ZERO {
                let pdf = sigma_maj[channel] * t_maj[channel];
                let r_e = s.r_u * sigma_maj * t_maj / pdf;
                if r_e != Rgb::ZERO {
                    s.l += s.beta * t_maj / pdf * mp.sigma_a * mp.le / mean(r_e);
                }
            }
            // Scattering or a null collision, chosen in proportion to the
            // throughput they would carry (averaged over channels, so the
            // choice is the same for every channel and cancels from their
            // density ratios). Absorption is not an event: the scattering
            // weight σs < σ_maj − σn accounts for it, as in Mitsuba's
            // volpath, which keeps paths through dark or chromatic albedo
            // from ending at random.
            let sigma_n = (sigma_maj - mp.sigma_a - mp.sigma_s).max(Rgb::ZERO);
            let (w_scatter, w_null) = (mean(s.beta * mp.sigma_s), mean(s.beta * sigma_n));
            if w_scatter + w_null <= 0.0 {
                outcome = Segment::Ended;
                return false;
            }
            let p_scatter = w_scatter / (w_scatter + w_null);
            let choice = u_mode;
            u_mode = rng.next_f32();
            let hero = t_maj[channel] * sigma_maj[channel];
            let density_ratio = t_maj * sigma_maj / hero;
            if choice < p_scatter {
                outcome = self.scatter(
                    walk,
                    p,
                    segment.dir,
                    t_maj * mp.sigma_s / (hero * p_scatter),
                    density_ratio,
                    s,
                    sampler,
                    rng,
                    stats,
                );
                return false;
            }
            // A null collision: light sampling would have crossed it by
            // ratio tracking, with density T_maj·σ_maj and no choice.
            let p_null = 1.0 - p_scatter;
            s.beta *= t_maj * sigma_n / (hero * p_null);
            s.r_u *= density_ratio;
            s.r_l *= density_ratio / p_null;
            s.beta != Rgb::ZERO && s.r_u != Rgb::ZERO
        });
        if s.beta == Rgb::ZERO || s.r_u == Rgb::ZERO || !s.beta.is_finite() {
            return Segment::Ended;
        }
        if !matches!(outcome, Segment::Crossed) {
            return outcome;
        }
        let hero = t_maj[channel];
        if hero <= 0.0 {
            return Segment::Ended;
        }
        s.beta *= t_maj / hero;
        s.r_u *= t_maj / hero;
        s.r_l *= t_maj / hero;
        Segment::Crossed
    }

    /// A segment by fixed-step ray marching (the taught estimator, biased
    /// where the medium varies within a step): the optical depth is summed
    /// step by step, each step at the coefficients of its middle, and the
    /// free-flight distance found where it reaches −ln(1 − u); volume
    /// emission is summed along the way.
    #[allow(clippy::too_many_arguments)]
    fn march(
        &self,
        walk: &Walk,
        segment: &Ray,
        step: f32,
        s: &mut PathState,
        sampler: &mut Sampler,
        rng: &mut Pcg32,
        stats: &mut RayStats,
    ) -> Segment {
        let channel = walk.channel;
        let medium = &walk.scene.media[walk.medium as usize];
        let target = -(1.0 - sampler.next_1d()).ln();
        let jitter = sampler.next_1d();
        let mut tau = Rgb::ZERO;
        let mut emitted = Rgb::ZERO;
        let mut scatter_at: Option<(f32, crate::media::MediumPoint)> = None;
        march_steps(medium, segment, step, jitter, |a, b, mp| {
            let sigma_t = mp.sigma_a + mp.sigma_s;
            if mp.le != Rgb::ZERO {
                emitted += exp_neg(tau + sigma_t * (0.5 * (b - a))) * mp.sigma_a * mp.le * (b - a);
            }
            let reach = tau[channel] + sigma_t[channel] * (b - a);
            if reach >= target && sigma_t[channel] > 0.0 {
                let t = a + (target - tau[channel]) / sigma_t[channel];
                tau += sigma_t * (t - a);
                scatter_at = Some((t, *mp));
                return false;
            }
            tau += sigma_t * (b - a);
            true
        });
        if s.depth < self.max_depth && emitted != Rgb::ZERO {
            s.l += s.beta * emitted / mean(s.r_u);
        }
        let transmitted = exp_neg(tau);
        let hero = transmitted[channel];
        match scatter_at {
            Some((t, mp)) => {
                // The density of stopping here in channel c: T̂c·σt,c.
                let sigma_t = mp.sigma_a + mp.sigma_s;
                let pdf_hero = hero * sigma_t[channel];
                self.scatter(
                    walk,
                    segment.at(t),
                    segment.dir,
                    transmitted * mp.sigma_s / pdf_hero,
                    transmitted * sigma_t / pdf_hero,
                    s,
                    sampler,
                    rng,
                    stats,
                )
            }
            None if hero > 0.0 => {
                s.beta *= transmitted / hero;
                s.r_u *= transmitted / hero;
                // Light sampling crosses the segment by the same sum, with
                // no choice (density 1 in every channel).
                s.r_l /= hero;
                Segment::Crossed
            }
            None => Segment::Ended,
        }
    }

    /// A real scattering event at `p` in the walk's medium, for a path
    /// travelling along `dir`: the throughput is multiplied by `weight`
    /// and the channels' density ratios by `density_ratio`; then the
    /// light is sampled and the phase function chooses the next direction.
    #[allow(clippy::too_many_arguments)]
    fn scatter(
        &self,
        walk: &Walk,
        p: Vec3,
        dir: Vec3,
        weight: Rgb,
        density_ratio: Rgb,
        s: &mut PathState,
        sampler: &mut Sampler,
        rng: &mut Pcg32,
        stats: &mut RayStats,
    ) -> Segment {
        s.depth += 1;
        if s.depth >= self.max_depth {
            return Segment::Ended;
        }
        s.beta *= weight;
        s.r_u *= density_ratio;
        if s.beta == Rgb::ZERO || s.r_u == Rgb::ZERO {
            return Segment::Ended;
        }
        let phase = walk.scene.media[walk.medium as usize].phase;
        let wo = -dir;
        let vertex = Vertex::Medium {
            p,
            wo,
            phase,
            time: walk.time,
        };
        s.l += self.sample_light(
            walk.scene,
            &vertex,
            Some(walk.medium),
            s.beta,
            s.r_u,
            walk.channel,
            sampler,
            rng,
            stats,
        );
        let ps = phase.sample(wo, sampler.next_2d());
        if ps.pdf <= 0.0 {
            return Segment::Ended;
        }
        // The phase functions are sampled exactly: p/pdf = 1.
        s.r_l = s.r_u / ps.pdf;
        s.prev_p = p;
        s.prev_n = Vec3::ZERO;
        s.specular = false;
        Segment::Scattered(Ray::new(p, ps.wi).at_time(walk.time))
    }

    /// The transmittance along a shadow `segment` (unit direction) in
    /// `medium`, multiplied into `t_ray`, with the channels' density
    /// ratios of the two strategies: by ratio tracking, or by marching.
    /// Returns false where the estimate is zero.
    #[allow(clippy::too_many_arguments)]
    fn shadow_transmittance(
        &self,
        medium: &crate::media::Medium,
        segment: &Ray,
        channel: usize,
        t_ray: &mut Rgb,
        r_l: &mut Rgb,
        r_u: &mut Rgb,
        rng: &mut Pcg32,
    ) -> bool {
        // Where σt is constant the transmittance is known exactly, and is
        // what ratio tracking gives on average (it is 0 or T/T_hero, at
        // random): the exact value, with the density ratios ratio tracking
        // would have given when it passes (the ones the path's own free
        // flights use, so that the MIS weights still sum to one).
        if let (None, Some(sigma_t)) = (self.march_step, medium.constant_extinction()) {
            let length = medium
                .segment(segment.origin, segment.dir, segment.t_max)
                .map_or(0.0, |(a, b)| b - a);
            let t = crate::media::transmittance(length, sigma_t);
            let hero = t[channel];
            if hero <= 0.0 {
                return false;
            }
            *t_ray *= t;
            *r_l *= t / hero;
            *r_u *= t / hero;
            return *t_ray != Rgb::ZERO;
        }
        if let Some(step) = self.march_step {
            let mut tau = Rgb::ZERO;
            march_steps(medium, segment, step, rng.next_f32(), |a, b, mp| {
                tau += (mp.sigma_a + mp.sigma_s) * (b - a);
                true
            });
            let t = exp_neg(tau);
            *t_ray *= t;
            // The path would have crossed with probability T̂c in channel c.
            *r_u *= t;
            return *t_ray != Rgb::ZERO;
        }
        let u = rng.next_f32();
        let t_maj = sample_majorant(medium, segment, channel, u, rng, |_, mp, sigma_maj, t_maj, rng| {
            let sigma_n = (sigma_maj - mp.sigma_a - mp.sigma_s).max(Rgb::ZERO);
            let pdf = t_maj[channel] * sigma_maj[channel];
            *t_ray *= t_maj * sigma_n / pdf;
            *r_l *= t_maj * sigma_maj / pdf;
            *r_u *= t_maj * sigma_n / pdf;
            // Russian roulette on a faint estimate (pbrt-v4).
            let tr = *t_ray / mean(*r_l + *r_u);
            if tr.max_element() < 0.05 {
                if rng.next_f32() < 0.75 {
                    *t_ray = Rgb::ZERO;
                } else {
                    *t_ray /= 0.25;
                }
            }
            *t_ray != Rgb::ZERO && t_ray.is_finite()
        });
        let hero = t_maj[channel];
        if hero <= 0.0 {
            return false;
        }
        *t_ray *= t_maj / hero;
        *r_l *= t_maj / hero;
        *r_u *= t_maj / hero;
        true
    }

    /// Adds emitted radiance `le` found by the path, weighed against light
    /// sampling (whose density for it `light_pdf` gives) unless the last
    /// scattering was a delta lobe, which light sampling cannot find.
    #[inline]
    fn add_emission(&self, s: &mut PathState, le: Rgb, light_pdf: impl FnOnce() -> f32) {
        if le == Rgb::ZERO {
            return;
        }
        if s.specular {
            s.l += s.beta * le / mean(s.r_u);
        } else {
            let r_l = s.r_l * light_pdf();
            s.l += s.beta * le / mean(s.r_u + r_l);
        }
    }

    /// Russian roulette after `rr_depth` segments, as the path tracer's
    /// ([`survival_cap`]): whether the path goes on (its throughput then
    /// divided by the survival probability).
    #[inline]
    fn roulette(&self, s: &mut PathState, eta_scale: f32, sampler: &mut Sampler) -> bool {
        let u = sampler.next_1d();
        if s.depth < self.rr_depth {
            return true;
        }
        let q = (s.beta * eta_scale / mean(s.r_u))
            .abs()
            .max_element()
            .min(survival_cap(self.max_depth));
        if u >= q {
            return false;
        }
        s.beta /= q;
        true
    }
}
