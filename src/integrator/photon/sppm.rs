//! Stochastic progressive photon mapping (Hachisuka and Jensen 2009,
//! "Stochastic Progressive Photon Mapping"; Hachisuka, Ogaki and Jensen
//! 2008, "Progressive Photon Mapping").
//!
//! Photon mapping's bias comes from the disk over which it averages
//! photons; SPPM makes the disk of every pixel shrink as photons arrive, so
//! that bias and noise both vanish and the image converges to the path
//! tracer's. Each iteration:
//!
//! 1. **Camera pass.** Every pixel traces one camera ray (a new random
//!    position in the pixel each time: the "stochastic" of SPPM, which
//!    anti-aliases and integrates depth of field and glossy chains) through
//!    specular bounces to its *visible point*, the first surface with a
//!    non-delta lobe. Emission seen on the way and direct light at the
//!    visible point (next-event estimation) go to the pixel's direct sum.
//! 2. **Photon pass.** `sppm_photons` photons (by default one per pixel)
//!    are traced from the lights; those
//!    that have bounced at least once are stored (direct light is already
//!    counted) in a kd-tree.
//! 3. **Update** (Hachisuka et al. 2008, eqs. 5–7). The M photons within
//!    the pixel's radius R add flux Φ = Σ β·f·Φp. With N the pixel's photon
//!    count so far and α ∈ (0, 1):
//!
//!    ```text
//!    N' = N + α·M      R'² = R²·(N + α·M)/(N + M)      τ' = (τ + Φ)·R'²/R²
//!    ```
//!
//! After k iterations the pixel is `direct/k + τ/(k·π·R²)` (photon powers
//! are per iteration). α = 2/3 is the usual choice; Knaus and Zwicker 2011
//! show any α in (0, 1) converges.
//!
//! A surface with both delta and non-delta lobes (a smooth coat over a
//! diffuse base) is treated by choosing: with the delta lobes' probability
//! the path continues specularly, otherwise the visible point is here; the
//! choice's probability divides the throughput.
//!
//! The visible point is found and updated by its own pixel's thread (a
//! radius query of the photon kd-tree), so no two threads touch one
//! pixel's statistics: the image is identical for any number of threads.

use super::jensen::specular_bounce;
use super::trace::{PhotonStore, trace_photons_until};
use super::{PhotonMap, camera_segment, same_surface};
use crate::color::Rgb;
use crate::film::{AovSum, Film, FilmAov, FilmPixel, PixelSum};
use crate::integrator::aov::camera_aov;
use crate::integrator::state::{StateReader, StateWriter};
use crate::integrator::{Progressive, Work};
use crate::sampling::Sampler;
use crate::scene::Scene;
use glam::{DVec3, Vec2};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// One pixel's progressive statistics.
#[derive(Clone, Copy, Debug, Default)]
struct PixelState {
    /// Squared radius R².
    r2: f32,
    /// Accumulated photon count N.
    n: f64,
    /// Accumulated, radius-scaled flux τ.
    tau: DVec3,
    /// Sum over iterations of directly estimated light.
    direct: DVec3,
    /// Auxiliary values, when requested.
    aov: AovSum,
}

/// SPPM's state between iterations: every pixel's statistics. The
/// renderer runs `spp` iterations (or as many as its time limit or
/// deadline allow, at most `spp`), each of one camera sample per pixel and
/// `sppm_photons` photons; the image is always that of whole iterations.
pub struct Sppm {
    width: u32,
    height: u32,
    /// Row by row from the top.
    pixels: Vec<PixelState>,
    /// Photons per iteration.
    photons: u32,
    /// Iterations done.
    iterations: u32,
    /// Whether the auxiliary sums are recorded.
    aovs: bool,
}

impl Sppm {
    /// The state before the first iteration: every pixel's radius the
    /// initial one, nothing gathered.
    pub fn new(scene: &Scene, aovs: bool) -> Sppm {
        let s = &scene.settings;
        let p = s.photon;
        let (w, h) = (s.width as usize, s.height as usize);
        let r0 = p.radius_for(scene);
        Sppm {
            width: s.width,
            height: s.height,
            pixels: vec![
                PixelState {
                    r2: r0 * r0,
                    ..PixelState::default()
                };
                w * h
            ],
            photons: p.sppm_photons_for((w * h) as u64),
            iterations: 0,
            aovs,
        }
    }
}

impl Progressive for Sppm {
    /// One iteration: the photon pass (given up soon after `cancel` is
    /// set, and then the whole iteration), then every pixel's camera sample
    /// and update.
    fn iterate(&mut self, scene: &Scene, cancel: Option<&AtomicBool>) -> Option<Work> {
        let s = &scene.settings;
        let w = s.width as usize;
        let photon_start = Instant::now();
        let pass = trace_photons_until(
            scene,
            self.photons,
            s.seed,
            2 + self.iterations as u64,
            s.max_depth,
            PhotonStore::Indirect,
            cancel,
        );
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            // The photon pass may be incomplete; the iteration is dropped.
            return None;
        }
        let map = PhotonMap::build(pass.photons);
        let photon_seconds = photon_start.elapsed().as_secs_f64();

        let (iteration, aovs) = (self.iterations, self.aovs);
        let rays: u64 = self
            .pixels
            .par_chunks_mut(w)
            .enumerate()
            .map(|(y, row)| {
                let mut sampler = Sampler::new(s.sampler, s.spp, s.seed)
                    .for_image(s.width, s.height)
                    .with_strata(s.strata, s.jitter);
                let mut rays = 0u64;
                for (x, px) in row.iter_mut().enumerate() {
                    camera_sample(
                        scene,
                        aovs,
                        &map,
                        x as u32,
                        y as u32,
                        iteration,
                        px,
                        &mut sampler,
                        &mut rays,
                    );
                }
                rays
            })
            .sum();
        self.iterations += 1;
        Some(Work {
            rays: pass.rays + rays,
            photons_emitted: pass.emitted,
            photon_seconds,
        })
    }

    /// Each pixel is `direct/k + τ/(k·π·R²)` after k iterations.
    fn film(&self) -> Film {
        let mut film = Film::new(self.width, self.height);
        let k = self.iterations.max(1) as f64;
        for (sum, px) in film.pixels.iter_mut().zip(&self.pixels) {
            let indirect = px.tau / (k * PI * px.r2 as f64);
            let l = px.direct / k + indirect;
            *sum = FilmPixel::default().plus(&PixelSum {
                rgb: l,
                weight: 1.0,
                lum_sq: crate::color::luminance(l.as_vec3()) as f64 * crate::color::luminance(l.as_vec3()) as f64,
            });
        }
        if self.aovs {
            film.aovs = Some(self.pixels.iter().map(|px| FilmAov::default().plus(&px.aov)).collect());
        }
        film
    }

    /// The iterations done, the photons per iteration, and every pixel's
    /// radius, photon count, flux and direct light (and auxiliary sums).
    fn state(&self) -> Vec<u8> {
        let mut w = StateWriter::default();
        w.u32(self.iterations);
        w.u32(self.photons);
        w.u32(u32::from(self.aovs));
        w.u64(self.pixels.len() as u64);
        for px in &self.pixels {
            w.f32(px.r2);
            w.f64(px.n);
            for v in [px.tau, px.direct] {
                for c in v.to_array() {
                    w.f64(c);
                }
            }
            if self.aovs {
                w.aov(&px.aov);
            }
        }
        w.0
    }

    fn restore(&mut self, _scene: &Scene, state: &[u8]) -> Result<(), String> {
        let mut r = StateReader::new(state);
        let iterations = r.u32()?;
        if r.u32()? != self.photons || (r.u32()? == 1) != self.aovs {
            return Err("the saved state is of another number of photons or auxiliary images".into());
        }
        let per_pixel = 4 + 8 * 7 + if self.aovs { 9 * 8 } else { 0 };
        if r.count(per_pixel)? != self.pixels.len() {
            return Err("the saved state is of another image size".into());
        }
        for px in &mut self.pixels {
            px.r2 = r.f32()?;
            px.n = r.f64()?;
            px.tau = DVec3::new(r.f64()?, r.f64()?, r.f64()?);
            px.direct = DVec3::new(r.f64()?, r.f64()?, r.f64()?);
            if self.aovs {
                px.aov = r.aov()?;
            }
            let finite = px.r2.is_finite() && px.n.is_finite() && px.tau.is_finite() && px.direct.is_finite();
            if !finite || px.r2 < 0.0 {
                return Err("a saved pixel's statistics are not finite".into());
            }
        }
        self.iterations = iterations;
        r.finish()
    }
}

/// One iteration's camera sample of pixel (x, y): its direct light, its
/// visible point and the update of its statistics from `map`.
#[allow(clippy::too_many_arguments)]
fn camera_sample(
    scene: &Scene,
    aovs: bool,
    map: &PhotonMap,
    x: u32,
    y: u32,
    iteration: u32,
    px: &mut PixelState,
    sampler: &mut Sampler,
    rays: &mut u64,
) {
    let s = &scene.settings;
    sampler.start_pixel_sample(x, y, iteration);
    let filter = s.pixel_filter();
    let offset = filter.sample(sampler.pixel_2d());
    let lens = scene.camera.draw_lens(sampler);
    let time = scene.camera.draw_time(sampler);
    let camera_ray = scene.camera.moved(
        scene
            .camera
            .generate_ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5) + offset, lens)
            .at_time(time),
    );
    if aovs {
        px.aov.add(&camera_aov(scene, &camera_ray));
    }
    let mut l = Rgb::ZERO;
    let mut beta = Rgb::splat(filter.sample_weight(offset));
    let mut ray = camera_ray;
    let mut wavelength = None;
    for depth in 1..=s.max_depth {
        let draw = || sampler.next_1d();
        let Some((hit, sp)) = camera_segment(scene, &ray, beta, depth, &mut l, rays, &mut wavelength, draw) else {
            break;
        };
        beta *= sp.spectral;
        if sp.bsdf.has_smooth() {
            let p_delta = sp.bsdf.delta_probability(sp.wo).clamp(0.0, 1.0);
            let u = if p_delta > 0.0 { sampler.next_1d() } else { 1.0 };
            if u >= p_delta {
                // The visible point.
                let beta_vp = beta / (1.0 - p_delta);
                l += beta_vp * sp.direct_light(scene, &hit, sampler, rays);
                let (mut m_count, mut phi) = (0u64, Rgb::ZERO);
                map.for_each_within(hit.p, px.r2, |ph, _| {
                    if same_surface(ph.normal(), hit.ng) {
                        m_count += 1;
                        phi += sp.eval(&hit, ph.wi()) * ph.power;
                    }
                });
                if m_count > 0 {
                    let alpha = s.photon.alpha as f64;
                    let m = m_count as f64;
                    let n_new = px.n + alpha * m;
                    let ratio = n_new / (px.n + m);
                    px.tau = (px.tau + (beta_vp * phi).as_dvec3()) * ratio;
                    px.r2 = (px.r2 as f64 * ratio) as f32;
                    px.n = n_new;
                }
                break;
            }
            beta /= p_delta;
        }
        match specular_bounce(&hit, &sp, sampler.next_1d()) {
            Some((weight, next)) => {
                beta *= weight;
                ray = next;
            }
            None => break,
        }
    }
    if l.is_finite() {
        px.direct += l.as_dvec3();
    }
}
