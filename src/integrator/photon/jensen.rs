//! Jensen's two-pass photon mapping (Jensen 1996, "Global Illumination
//! Using Photon Maps"; Jensen 2001, ch. 9).
//!
//! **First pass.** Photons are traced from the lights ([`super::trace`])
//! into two maps: the *global* map holds every photon that lands on a
//! surface with a non-delta lobe; the *caustic* map, traced separately with
//! its own photon count, holds only light that reached such a surface
//! through specular (delta) bounces alone, L S+ D.
//!
//! **Second pass.** From the camera, the path follows specular bounces and
//! collects emission seen directly or in mirrors. At the first surface with
//! a non-delta lobe the radiance is split by the last bounces of the light
//! that arrives:
//!
//! | term | light paths | estimated by |
//! |---|---|---|
//! | direct | L D | next-event estimation (a shadow ray to a light chosen by power) |
//! | caustics | L S+ D | the caustic map, read at the point |
//! | diffuse interreflection | L (S\|D)* D D | final gathering: `final_gather` rays sampled from the BSDF, each followed through specular surfaces to a diffuse one, where the global map is read |
//!
//! Emission found by gather rays is ignored (direct light already counts
//! it, and emission seen through glass is a caustic). With
//! `final_gather = 0` the global map is read at the first diffuse surface
//! for all its light instead: a quick, blotchy preview.
//!
//! Each map read is the density estimate over the `photon_gather` nearest
//! photons within `photon_radius` (`ShadingPoint::photon_radiance`).
//! Photon mapping is biased (the estimate blurs light over the disk) but
//! consistent: the error vanishes as photons grow in number and the disks
//! shrink.

use super::trace::{PhotonStore, trace_photons_until};
use super::{Nearest, PhotonMap, PhotonSettings, ShadingPoint, camera_segment};
use crate::color::Rgb;
use crate::geometry::{Ray, SurfaceHit};
use crate::integrator::{Integrator, RayStats};
use crate::material::TransportMode;
use crate::sampling::Sampler;
use crate::scene::Scene;
use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Most specular bounces a final-gather ray follows to a diffuse surface.
const MAX_GATHER_SPECULAR: u32 = 8;

/// Figures from the photon pass.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhotonPassStats {
    /// Photons emitted (both maps).
    pub emitted: u64,
    /// Photons stored in the global map.
    pub global: usize,
    /// Photons stored in the caustic map.
    pub caustic: usize,
    /// Rays traced by photons.
    pub rays: u64,
    /// Seconds spent tracing photons and building the maps.
    pub seconds: f64,
}

/// The photon-mapping integrator: the maps, built once, and the settings
/// that read them.
#[derive(Clone, Debug)]
pub struct PhotonMapper {
    /// Every photon landing on a non-delta surface.
    pub global: PhotonMap,
    /// Photons that arrived through specular bounces only.
    pub caustic: PhotonMap,
    /// Irradiance at every fourth global photon (`power` holds E, the
    /// normal faces the side the light arrived on); for final gathering.
    pub irradiance: PhotonMap,
    settings: PhotonSettings,
    max_depth: u32,
    max_r2: f32,
    /// Figures from building the maps.
    pub stats: PhotonPassStats,
}

thread_local! {
    /// Each thread's k-nearest buffer, so that lookups never allocate.
    static NEAREST: RefCell<Nearest> = RefCell::new(Nearest::default());
}

impl PhotonMapper {
    /// Traces the photons and builds the maps for `scene` with its settings.
    pub fn build(scene: &Scene) -> PhotonMapper {
        Self::build_until(scene, None).expect("nothing cancels the build")
    }

    /// [`PhotonMapper::build`], giving up (`None`) soon after `cancel` is
    /// set (within a chunk of photons). This is photon mapping's
    /// preparation: [`crate::integrator::drive`] hands the mapper to the
    /// renderer's camera passes, which obey interrupts, time limits and
    /// checkpoints as the path tracer's do. The maps depend only on the
    /// scene's settings and seed, so a render resumed from a checkpoint (a
    /// film of whole camera passes) traces the same maps again and ends
    /// with the same image as one that never stopped.
    pub fn build_until(scene: &Scene, cancel: Option<&AtomicBool>) -> Option<PhotonMapper> {
        let start = Instant::now();
        let cancelled = || cancel.is_some_and(|c| c.load(Ordering::Relaxed));
        let s = scene.settings.photon;
        let (seed, max_depth) = (scene.settings.seed, scene.settings.max_depth);
        let global = trace_photons_until(scene, s.photons, seed, 0, max_depth, PhotonStore::All, cancel);
        let caustic = if s.final_gather > 0 && scene_has_specular(scene) && !cancelled() {
            trace_photons_until(
                scene,
                s.caustic_photons,
                seed,
                1,
                max_depth,
                PhotonStore::Caustic,
                cancel,
            )
        } else {
            Default::default()
        };
        if cancelled() {
            return None;
        }
        let stats = PhotonPassStats {
            emitted: global.emitted + caustic.emitted,
            global: global.photons.len(),
            caustic: caustic.photons.len(),
            rays: global.rays + caustic.rays,
            seconds: 0.0,
        };
        let (global, caustic) = rayon::join(
            || PhotonMap::build(global.photons),
            || PhotonMap::build(caustic.photons),
        );
        let r = s.radius_for(scene);
        let irradiance = if s.final_gather > 0 {
            precompute_irradiance(&global, s.gather as usize, r * r, s.kernel)
        } else {
            PhotonMap::default()
        };
        Some(PhotonMapper {
            global,
            caustic,
            irradiance,
            settings: s,
            max_depth,
            max_r2: r * r,
            stats: PhotonPassStats {
                seconds: start.elapsed().as_secs_f64(),
                ..stats
            },
        })
    }

    /// Radiance arriving at the camera along `ray`.
    fn trace(
        &self,
        scene: &Scene,
        camera_ray: &Ray,
        sampler: &mut Sampler,
        stats: &mut RayStats,
        found: &mut Nearest,
    ) -> Rgb {
        let mut l = Rgb::ZERO;
        let mut beta = Rgb::ONE;
        let mut ray = *camera_ray;
        let mut wavelength = None;
        for depth in 1..=self.max_depth {
            let draw = || sampler.next_1d();
            let Some((hit, sp)) =
                camera_segment(scene, &ray, beta, depth, &mut l, &mut stats.rays, &mut wavelength, draw)
            else {
                break;
            };
            beta *= sp.spectral;
            if sp.bsdf.has_smooth() {
                let k = self.settings.gather as usize;
                let kernel = self.settings.kernel;
                if self.settings.final_gather == 0 {
                    l += beta * sp.photon_radiance(&hit, &self.global, k, self.max_r2, kernel, found);
                } else {
                    let direct = sp.direct_light(scene, &hit, sampler, &mut stats.rays);
                    let caustic = sp.photon_radiance(&hit, &self.caustic, k, self.max_r2, kernel, found);
                    let indirect = self.final_gather(scene, &hit, &sp, wavelength, sampler, stats, found);
                    l += beta * (direct + caustic + indirect);
                }
            }
            // Specular bounces continue the camera path.
            match specular_bounce(&hit, &sp, sampler.next_1d()) {
                Some((weight, next)) => {
                    beta *= weight;
                    ray = next;
                }
                None => break,
            }
        }
        l
    }

    /// Indirect diffuse light at `hit` by final gathering (Jensen 2001,
    /// §9.3.4): the mean over gather rays of f·cos/pdf times the global
    /// map's radiance where each ray lands.
    #[allow(clippy::too_many_arguments)]
    fn final_gather(
        &self,
        scene: &Scene,
        hit: &SurfaceHit,
        sp: &ShadingPoint,
        path_wavelength: Option<f32>,
        sampler: &mut Sampler,
        stats: &mut RayStats,
        found: &mut Nearest,
    ) -> Rgb {
        let n = self.settings.final_gather;
        let mut sum = Rgb::ZERO;
        for _ in 0..n {
            let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
            // Delta samples carry no diffuse light: they count as zero, and
            // the smooth samples keep the mixture's density (unbiased).
            let Some(bs) = sp.bsdf.sample(sp.wo, u_lobe, u, TransportMode::Radiance) else {
                continue;
            };
            if bs.delta || bs.pdf <= 0.0 || bs.f == Rgb::ZERO || bs.wi.z == 0.0 {
                continue;
            }
            let wi_world = sp.frame.to_world(bs.wi);
            if (hit.ng.dot(wi_world) > 0.0) != (sp.front_o == (bs.wi.z * sp.wo.z > 0.0)) {
                continue;
            }
            let mut weight = bs.f * (bs.wi.z.abs() / bs.pdf);
            let mut ray = hit.spawn_ray(wi_world);
            // Each gather ray continues the camera path on its own.
            let mut wavelength = path_wavelength;
            for _ in 0..MAX_GATHER_SPECULAR {
                stats.rays += 1;
                let Some(mut h) = scene.intersect(&ray) else {
                    break;
                };
                scene.choose_any_material(&mut h, ray.dir);
                let Some(sp2) =
                    ShadingPoint::new(scene, &h, -ray.dir.normalize(), &mut wavelength, || sampler.next_1d())
                else {
                    break;
                };
                weight *= sp2.spectral;
                if sp2.bsdf.has_smooth() {
                    sum += weight * self.irradiance_radiance(&h, &sp2, found);
                }
                match specular_bounce(&h, &sp2, sampler.next_1d()) {
                    Some((w, next)) => {
                        weight *= w;
                        ray = next;
                    }
                    None => break,
                }
            }
        }
        sum / n as f32
    }
}

impl PhotonMapper {
    /// Radiance leaving `hit` toward `sp.wo` from the nearest precomputed
    /// irradiance on the same side of the same surface: albedo/π·E.
    fn irradiance_radiance(&self, hit: &SurfaceHit, sp: &ShadingPoint, found: &mut Nearest) -> Rgb {
        let side = if sp.front_o { hit.ng } else { -hit.ng };
        if self
            .irradiance
            .nearest(hit.p, IRRADIANCE_CANDIDATES, self.max_r2, found)
            .is_none()
        {
            return Rgb::ZERO;
        }
        let mut best: Option<(f32, u32)> = None;
        for (d2, index) in found.iter() {
            if super::same_surface(self.irradiance.photon(index).normal(), side) && best.is_none_or(|(b, _)| d2 < b) {
                best = Some((d2, index));
            }
        }
        match best {
            Some((_, index)) => sp.bsdf.albedo() * (self.irradiance.photon(index).power / std::f32::consts::PI),
            None => Rgb::ZERO,
        }
    }
}

/// Nearest precomputed-irradiance points examined for one on the right
/// side of the right surface.
const IRRADIANCE_CANDIDATES: usize = 8;
/// Irradiance is precomputed at one global photon in this many.
const IRRADIANCE_STRIDE: usize = 4;

/// The irradiance at every [`IRRADIANCE_STRIDE`]-th photon of `global`,
/// from the photons that arrived on its side of its surface.
fn precompute_irradiance(global: &PhotonMap, k: usize, max_r2: f32, kernel: super::PhotonKernel) -> PhotonMap {
    use rayon::prelude::*;
    let photons = global.photons();
    let points: Vec<super::Photon> = (0..photons.len())
        .into_par_iter()
        .step_by(IRRADIANCE_STRIDE)
        .map_init(Nearest::default, |found, i| {
            let ph = &photons[i];
            let n = ph.normal();
            let side = if ph.wi().dot(n) >= 0.0 { n } else { -n };
            let mut e = Rgb::ZERO;
            if let Some(far) = global.nearest(ph.p, k, max_r2, found) {
                let r2 = if found.len() < k { max_r2 } else { far };
                for (d2, index) in found.iter() {
                    let q = global.photon(index);
                    if super::same_surface(q.normal(), n) && q.wi().dot(side) > 0.0 {
                        e += q.power * kernel.weight(d2, r2);
                    }
                }
            }
            super::Photon::new(ph.p, e, ph.wi(), side)
        })
        .collect();
    PhotonMap::build(points)
}

impl Integrator for PhotonMapper {
    fn radiance(&self, scene: &Scene, ray: &Ray, sampler: &mut Sampler, stats: &mut RayStats) -> Rgb {
        NEAREST.with(|found| self.trace(scene, ray, sampler, stats, &mut found.borrow_mut()))
    }
}

/// Continues a path through the delta lobes of the surface (mirror, glass,
/// a smooth coat), one lobe picked by `u`: the weight f·|cos|/pdf and the
/// next ray; `None` when the surface has no delta lobe.
pub(crate) fn specular_bounce(hit: &SurfaceHit, sp: &ShadingPoint, u: f32) -> Option<(Rgb, Ray)> {
    if sp.bsdf.delta_probability(sp.wo) <= 0.0 {
        return None;
    }
    let s = sp.bsdf.sample_delta(sp.wo, u, TransportMode::Radiance)?;
    if s.pdf <= 0.0 || s.f == Rgb::ZERO || s.wi.z == 0.0 {
        return None;
    }
    let wi_world = sp.frame.to_world(s.wi);
    if (hit.ng.dot(wi_world) > 0.0) != (sp.front_o == (s.wi.z * sp.wo.z > 0.0)) {
        return None;
    }
    Some((s.f * (s.wi.z.abs() / s.pdf), hit.spawn_ray(wi_world)))
}

/// Whether any material has a delta lobe (otherwise there are no caustics).
fn scene_has_specular(scene: &Scene) -> bool {
    let tc = crate::texture::TexCoord::new(glam::Vec2::splat(0.5), glam::Vec3::ZERO);
    scene.materials.iter().any(|m| {
        let b = m.bsdf(&scene.textures, &tc);
        b.delta_probability(glam::Vec3::Z) > 0.0 || !b.has_smooth()
    })
}
