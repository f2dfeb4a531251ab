//! The photon pass (Jensen 2001, ch. 5): photons leave the lights, chosen
//! in proportion to their power, and bounce through the scene's BSDFs
//! (traced as importance, [`TransportMode::Importance`]), stored wherever
//! they land on a surface with a non-delta lobe.
//!
//! Each photon starts with `Le·cos/(p_A·p_ω) / (p_light·N)`, its share of
//! the emitted power. At every bounce Russian roulette keeps it with
//! probability q = min(1, max(β·f·cos/pdf) / max(β)) and divides the
//! survivor by q (Jensen 2001, §5.3): photon powers stay about constant, and
//! the map is not filled with dim photons.
//!
//! Photons are traced on all cores in chunks; photon i's random numbers
//! come from (seed, pass, i) alone and chunks are concatenated in order, so
//! a pass is identical for any number of threads.

use super::Photon;
use crate::color::Rgb;
use crate::integrator::material_path_bsdf;
use crate::sampling::rng::{Pcg32, hash_u64s};
use crate::scene::Scene;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Which photons a pass stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhotonStore {
    /// Every landing on a surface with a non-delta lobe: Jensen's global map.
    All,
    /// Only light that reached such a surface through one or more specular
    /// (delta) bounces and nothing else, L S+ D: the caustic map. Paths end
    /// at their first non-delta surface.
    Caustic,
    /// Every landing but the first: light that has bounced at least once.
    /// SPPM's map, whose direct light comes from next-event estimation.
    Indirect,
}

/// What a photon pass produced.
#[derive(Clone, Debug, Default)]
pub struct PhotonPass {
    /// The stored photons.
    pub photons: Vec<Photon>,
    /// Photons emitted.
    pub emitted: u64,
    /// Rays traced.
    pub rays: u64,
    /// Wall time in seconds.
    pub seconds: f64,
}

/// Photons per work unit, at most.
const CHUNK: u32 = 2048;

/// Emits `count` photons and traces each for at most `max_depth` segments.
/// `pass` separates the random numbers of successive passes.
pub fn trace_photons(
    scene: &Scene,
    count: u32,
    seed: u64,
    pass: u64,
    max_depth: u32,
    store: PhotonStore,
) -> PhotonPass {
    trace_photons_until(scene, count, seed, pass, max_depth, store, None)
}

/// [`trace_photons`], giving up when `cancel` is set (checked before each
/// chunk of photons): the pass is then incomplete and must not be used;
/// the caller checks the flag.
pub fn trace_photons_until(
    scene: &Scene,
    count: u32,
    seed: u64,
    pass: u64,
    max_depth: u32,
    store: PhotonStore,
    cancel: Option<&AtomicBool>,
) -> PhotonPass {
    let start = Instant::now();
    if scene.lights.is_empty() || count == 0 || scene.light_distribution.is_empty() {
        return PhotonPass {
            emitted: count as u64,
            ..PhotonPass::default()
        };
    }
    let bounds = crate::light::scene_bounding_sphere(scene);
    let chunk = crate::integrator::work_unit_len(count, CHUNK);
    let chunks = count.div_ceil(chunk);
    let parts: Vec<(Vec<Photon>, u64)> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut photons = Vec::new();
            let mut rays = 0u64;
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                return (photons, rays);
            }
            for i in c * chunk..((c + 1) * chunk).min(count) {
                let mut rng = Pcg32::new(hash_u64s(&[seed, pass, i as u64]), 0x9e37);
                trace_one(
                    scene,
                    bounds,
                    count,
                    max_depth,
                    store,
                    &mut rng,
                    &mut photons,
                    &mut rays,
                );
            }
            (photons, rays)
        })
        .collect();
    let total: usize = parts.iter().map(|p| p.0.len()).sum();
    let mut photons = Vec::with_capacity(total);
    let mut rays = 0;
    for (p, r) in parts {
        photons.extend_from_slice(&p);
        rays += r;
    }
    PhotonPass {
        photons,
        emitted: count as u64,
        rays,
        seconds: start.elapsed().as_secs_f64(),
    }
}

#[allow(clippy::too_many_arguments)]
fn trace_one(
    scene: &Scene,
    bounds: (glam::Vec3, f32),
    count: u32,
    max_depth: u32,
    store: PhotonStore,
    rng: &mut Pcg32,
    out: &mut Vec<Photon>,
    rays: &mut u64,
) {
    let Some((emitted, _, pmf)) = crate::light::sample_scene_emission(scene, &scene.light_distribution, bounds, rng)
    else {
        return;
    };
    let mut beta = emitted.weight / (pmf * count as f32);
    // Photons of a moving scene leave at times spread over the shutter.
    let mut ray = emitted.ray.at_time(scene.camera.time_from(|| rng.next_f32()));
    let mut only_specular = true;
    // The photon's wavelength, once it has met a dispersive glass.
    let mut wavelength = None;
    for depth in 0..max_depth {
        *rays += 1;
        let Some(mut hit) = scene.intersect(&ray) else {
            return;
        };
        // One material of a blend per point, as the camera side takes it.
        scene.choose_any_material(&mut hit, ray.dir);
        let m = &scene.materials[hit.material as usize];
        let tc = crate::texture::TexCoord::at(&hit);
        let mut spectral = Rgb::ONE;
        let bsdf = material_path_bsdf(
            scene,
            hit.material,
            &tc,
            &mut wavelength,
            || rng.next_f32(),
            &mut spectral,
        );
        let wo_world = -ray.dir.normalize();
        if !m.two_sided && !bsdf.transmits() && !hit.is_front(wo_world) {
            return; // the back of a one-sided surface absorbs
        }
        if bsdf.has_smooth() {
            let keep = match store {
                PhotonStore::All => true,
                PhotonStore::Caustic => depth > 0 && only_specular,
                PhotonStore::Indirect => depth > 0,
            };
            if keep {
                out.push(Photon::new(hit.p, beta, wo_world, hit.ng));
            }
            if store == PhotonStore::Caustic {
                return;
            }
        }
        if depth + 1 == max_depth {
            return;
        }
        // A normal map turns the frame as the light side sees it and
        // scales the scattering by its factor toward the light (Mitsuba's
        // radiance convention, applied to the photon's own direction).
        let frame = m.shading_frame(&scene.textures, &hit, wo_world);
        let Some((next, next_ray, delta)) =
            crate::integrator::scatter_light(&hit, &bsdf, &frame, wo_world, beta * spectral, rng)
        else {
            return;
        };
        beta = next;
        if !delta {
            only_specular = false;
        }
        ray = next_ray;
    }
}
