//! Integrators: the algorithms that estimate the radiance arriving along a
//! camera ray. This is the only place that knows the algorithm; scheduling,
//! films and files are elsewhere.
//!
//! The renderer runs every algorithm through one interface, [`drive`]: the
//! algorithm the scene's settings name is prepared here (photon mapping
//! traces its maps) and handed to a [`Driver`] (the renderer's scheduling)
//! in one of two shapes: a per-sample estimator ([`Integrator`]) for the
//! driver's camera passes, or an algorithm of whole-image iterations
//! ([`Progressive`], SPPM) for the driver to iterate. Nothing here calls
//! back into the renderer: cancellation arrives as a plain flag, and the
//! driver chooses the threads (whatever runs inside its rayon pool uses
//! it), the passes, the deadline, checkpoints and progress.

pub mod ao;
pub mod aov;
pub mod bdpt;
pub mod function;
pub mod light;
pub mod mlt;
pub mod path;
pub mod photon;
pub(crate) mod state;
pub mod volpath;
pub mod whitted;

pub use ao::AmbientOcclusion;
pub use bdpt::Bdpt;
pub use bdpt::vcm::Vcm;
pub use light::LightTracer;
pub use mlt::Metropolis;
pub use path::PathTracer;
pub use photon::PhotonMapper;
pub use volpath::VolPathTracer;
pub use whitted::Whitted;

use crate::color::Rgb;
use crate::film::Film;
use crate::geometry::Ray;
use crate::sampling::Sampler;
use crate::scene::Scene;
use crate::settings::IntegratorKind;
use std::sync::atomic::AtomicBool;

/// Counters that an integrator updates while it works; each thread owns
/// one, and they are summed at the end.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayStats {
    /// Rays traced (camera, shadow and secondary).
    pub rays: u64,
}

impl std::ops::AddAssign for RayStats {
    fn add_assign(&mut self, o: RayStats) {
        self.rays += o.rays;
    }
}

/// Camera samples [`Integrator::radiance_lanes`] takes at once.
pub const LANES: usize = 8;

/// A per-sample radiance estimator.
pub trait Integrator: Sync {
    /// An estimate of the radiance arriving at the camera along `ray`.
    fn radiance(&self, scene: &Scene, ray: &Ray, sampler: &mut Sampler, stats: &mut RayStats) -> Rgb;

    /// The estimates of [`Integrator::radiance`] for the `rays` whose bits
    /// are set in `live`, ray `i` drawing from `samplers[i]` (zero for the
    /// others): the same numbers, which an estimator that traces paths
    /// many at a time computes together.
    fn radiance_lanes(
        &self,
        scene: &Scene,
        rays: &[Ray; LANES],
        samplers: &mut [Sampler; LANES],
        live: u32,
        stats: &mut RayStats,
    ) -> [Rgb; LANES] {
        one_by_one(self, scene, rays, samplers, live, stats)
    }
}

/// The largest probability with which Russian roulette keeps a path of
/// the path tracers, whose paths are at most `max_depth` segments long.
/// A path goes on with probability min(cap, max(β)·η²), η² undoing the
/// radiance scaling of refraction. Where the depth bounds the paths, the
/// cap is 1, as in pbrt-v4's path tracers: a path whose weight is still
/// at least one is not put at risk, which would add the noise of its
/// weight 1/q and save few segments (glass keeps β·η² at one: inside a
/// glass ball the risk was most of the noise). Where the depth is
/// unbounded (Mitsuba's −1, kept as [`MAX_DEPTH`]) nothing else ends a
/// path that keeps its weight (light trapped by total internal
/// reflection, a white furnace), so the cap is Mitsuba's 0.95.
///
/// [`MAX_DEPTH`]: crate::settings::MAX_DEPTH
pub(crate) fn survival_cap(max_depth: u32) -> f32 {
    if max_depth >= crate::settings::MAX_DEPTH {
        0.95
    } else {
        1.0
    }
}

/// [`Integrator::radiance_lanes`] by [`Integrator::radiance`], one ray
/// after the other.
pub(crate) fn one_by_one<I: Integrator + ?Sized>(
    integrator: &I,
    scene: &Scene,
    rays: &[Ray; LANES],
    samplers: &mut [Sampler; LANES],
    live: u32,
    stats: &mut RayStats,
) -> [Rgb; LANES] {
    std::array::from_fn(|i| {
        if live & (1 << i) != 0 {
            integrator.radiance(scene, &rays[i], &mut samplers[i], stats)
        } else {
            Rgb::ZERO
        }
    })
}

/// Work an algorithm did besides the camera samples' own paths (photon
/// passes), which the driver adds to the render's statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Work {
    /// Rays traced (photon mapping: by photons; SPPM: by the iteration's
    /// photons and camera paths).
    pub rays: u64,
    /// Photons emitted.
    pub photons_emitted: u64,
    /// Seconds spent tracing photons and building photon maps.
    pub photon_seconds: f64,
}

/// Why a progressive algorithm's render cannot be split into shards.
pub const NOT_SHARDABLE: &str = "progressive algorithms (sppm, light, bdpt, mlt, pssmlt, vcm) cannot be sharded (each iteration renders the whole image): drop --shard, or use --integrator path";

/// An algorithm that renders in iterations over the whole image, whose
/// state is not a film of samples (SPPM: every pixel's radius, photon count
/// and flux). The driver decides when to iterate and when to stop.
pub trait Progressive {
    /// Runs one more iteration. `None` when `cancel` was set during it: the
    /// iteration is dropped and the state is that of the iterations before.
    fn iterate(&mut self, scene: &Scene, cancel: Option<&AtomicBool>) -> Option<Work>;

    /// The image of the iterations so far (with the auxiliary sums, when
    /// they are recorded).
    fn film(&self) -> Film;

    /// Images the algorithm makes besides its film, by name (BDPT's
    /// per-strategy images, when asked for).
    fn extra_images(&self) -> Vec<(String, Film)> {
        Vec::new()
    }

    /// The state after the iterations so far (for checkpoints), from
    /// which [`Progressive::restore`] continues exactly as if the render
    /// had not stopped.
    fn state(&self) -> Vec<u8>;

    /// Continues from a state [`Progressive::state`] wrote for this scene
    /// (a reason where it does not fit).
    fn restore(&mut self, scene: &Scene, state: &[u8]) -> Result<(), String>;
}

/// What runs an algorithm: the renderer's scheduling, which [`drive`] hands
/// the prepared algorithm in one of its two shapes.
pub trait Driver {
    /// What driving produces.
    type Output;

    /// Camera passes over the image with a per-sample estimator, after
    /// `prepared`, the work that made it (photon maps; nothing for the
    /// others).
    fn camera_passes<I: Integrator>(self, integrator: &I, prepared: Work) -> Self::Output;

    /// Iterations of a progressive algorithm.
    fn iterations<P: Progressive>(self, algorithm: P) -> Self::Output;
}

/// Items per parallel work unit when `items` are split into units of at
/// most `most` (at least 64): small enough that a small count still gives
/// every thread work (a 40×30 image's paths, or its SPPM photons, were
/// one unit, so one thread), large enough that a unit's overhead stays
/// small. It depends on the count alone, not on the threads, and the
/// callers gather the units' results in order: the result is the same
/// for any unit length.
pub(crate) fn work_unit_len(items: u32, most: u32) -> u32 {
    (items / 64).clamp(64, most.max(64))
}

/// Prepares the algorithm that the scene's settings name and runs it with
/// `driver`; `aovs` asks for the auxiliary sums. Call it on the threads
/// that should do the work (inside a rayon pool, that pool's). `None` when
/// `cancel` was set while preparing (photon mapping gives up its photon
/// pass within a chunk of photons): nothing was rendered.
pub fn drive<D: Driver>(scene: &Scene, aovs: bool, cancel: Option<&AtomicBool>, driver: D) -> Option<D::Output> {
    let s = &scene.settings;
    Some(match s.integrator {
        IntegratorKind::Whitted => driver.camera_passes(&Whitted { max_depth: s.max_depth }, Work::default()),
        IntegratorKind::Path => driver.camera_passes(&PathTracer::with_settings(s), Work::default()),
        IntegratorKind::Photon => {
            let mapper = PhotonMapper::build_until(scene, cancel)?;
            let prepared = Work {
                rays: mapper.stats.rays,
                photons_emitted: mapper.stats.emitted,
                photon_seconds: mapper.stats.seconds,
            };
            driver.camera_passes(&mapper, prepared)
        }
        IntegratorKind::Sppm => driver.iterations(photon::sppm::Sppm::new(scene, aovs)),
        IntegratorKind::Light => driver.iterations(LightTracer::new(scene, aovs)),
        IntegratorKind::Bdpt => driver.iterations(Bdpt::new(scene, aovs)),
        IntegratorKind::Mlt => driver.iterations(Metropolis::new(scene, true, aovs)),
        IntegratorKind::Pssmlt => driver.iterations(Metropolis::new(scene, false, aovs)),
        IntegratorKind::Vcm => driver.iterations(Vcm::new(scene, aovs)),
        IntegratorKind::AmbientOcclusion => driver.camera_passes(
            &AmbientOcclusion {
                max_distance: s.ao_distance,
            },
            Work::default(),
        ),
        IntegratorKind::VolPath => driver.camera_passes(
            &VolPathTracer {
                max_depth: s.max_depth,
                rr_depth: s.rr_depth,
                march_step: s.march_step,
            },
            Work::default(),
        ),
    })
}

/// Chooses one of the scene's lights for the point `p` with surface
/// normal `n` (zero for a point in no surface) by the light tree
/// ([`crate::light::LightSampler`]): the light's index and the probability
/// of choosing it, or `None` where no light can reach the point. The
/// choice is drawn from `sampler`, or passed over where the scene has a
/// single light, which leaves the numbers after it unchanged.
/// `incomplete` is the estimator's choice for [`crate::light::Light::sample_li`]:
/// with it, lights that would draw nothing (a constant environment) are
/// not chosen.
#[inline(always)]
pub(crate) fn choose_light(
    scene: &Scene,
    p: glam::Vec3,
    n: glam::Vec3,
    sampler: &mut Sampler,
    incomplete: bool,
) -> Option<(usize, f32)> {
    if scene.lights.len() == 1 {
        sampler.skip_1d();
        return (!incomplete || scene.lights[0].samples_when_incomplete(scene)).then_some((0, 1.0));
    }
    scene.light_sampler.sample(p, n, sampler.next_1d(), incomplete)
}

/// The wavelength of a path that meets a dispersive glass: the one it
/// carries (`wavelength`), or, at its first such glass, one drawn from the
/// number `draw` gives (pbrt-v4 terminates the secondary wavelengths
/// there), which the path keeps and whose weight goes to `spectral`: the
/// path's throughput is multiplied by it from this vertex on.
#[inline(never)]
pub(crate) fn path_wavelength(wavelength: &mut Option<f32>, draw: impl FnOnce() -> f32, spectral: &mut Rgb) -> f32 {
    match *wavelength {
        Some(nm) => nm,
        None => {
            let s = crate::color::spectrum::sample_visible_wavelength(draw());
            *wavelength = Some(s.nm);
            *spectral = s.weight;
            s.nm
        }
    }
}

/// The BSDF of material `m` at a hit, for a path that carries the
/// wavelength `wavelength` once it has met a dispersive glass (`None`
/// before): see [`path_wavelength`], whose weight goes to `spectral` (left
/// as it is where the material does not disperse). (The BSDF alone is
/// returned: returned with the weight, it was copied, and the copy waited
/// on its stores.)
#[inline(always)]
pub(crate) fn path_bsdf<'s>(
    scene: &'s Scene,
    m: u32,
    tc: &crate::texture::TexCoord,
    parts: &'s mut Option<[crate::material::Bsdf<'s>; 2]>,
    wavelength: &mut Option<f32>,
    draw: impl FnOnce() -> f32,
    spectral: &mut Rgb,
) -> crate::material::Bsdf<'s> {
    if !scene.disperses(m) {
        return scene.bsdf(m, tc, parts);
    }
    let nm = path_wavelength(wavelength, draw, spectral);
    scene.bsdf_at_wavelength(m, tc, parts, nm)
}

/// The BSDF of material `m` (not a blend) at a hit, for a path of
/// `wavelength` as [`path_bsdf`] takes it: for the light paths and the
/// photon mappers, which choose one material of a blend per point.
#[inline]
pub(crate) fn material_path_bsdf<'s>(
    scene: &'s Scene,
    m: u32,
    tc: &crate::texture::TexCoord,
    wavelength: &mut Option<f32>,
    draw: impl FnOnce() -> f32,
    spectral: &mut Rgb,
) -> crate::material::Bsdf<'s> {
    let material = &scene.materials[m as usize];
    if material.dispersion().is_none() {
        return material.bsdf(&scene.textures, tc);
    }
    let nm = path_wavelength(wavelength, draw, spectral);
    scene.material_bsdf_at(m, tc, nm)
}

/// The probability with which [`choose_light`] at (`p`, `n`) with the same
/// `incomplete` chooses light `light`.
#[inline]
pub(crate) fn light_choice_pmf(scene: &Scene, p: glam::Vec3, n: glam::Vec3, light: usize, incomplete: bool) -> f32 {
    if scene.lights.len() == 1 {
        return if !incomplete || scene.lights[0].samples_when_incomplete(scene) {
            1.0
        } else {
            0.0
        };
    }
    scene.light_sampler.pmf(p, n, light, incomplete)
}

/// The adjoint BSDF's factor for shading normals (Veach 1997, eq. 5.21),
/// `|wo·ns|·|wi·ng| / (|wo·ng|·|wi·ns|)`, for light arriving from `wo` and
/// leaving along `wi` (world directions, `ns` the shading frame's normal,
/// which the local z components give).
#[inline]
pub(crate) fn adjoint_shading_factor(
    ng: glam::Vec3,
    wo: glam::Vec3,
    wo_local_z: f32,
    wi: glam::Vec3,
    wi_local_z: f32,
) -> f32 {
    wo_local_z.abs() * ng.dot(wi).abs() / (ng.dot(wo).abs() * wi_local_z.abs())
}

/// The next segment of a path that carries light from the lights (a
/// photon, a light-tracing path) at `hit`, where it arrived from `wo_world`
/// with throughput `beta`: the BSDF sampled as importance in `frame` (a
/// normal map's factor toward the light applied, Mitsuba's convention),
/// the adjoint correction for shading normals, then Russian roulette on
/// the throughput's change (Jensen 2001, §5.3), so that a path keeps about
/// its share of the power. Draws four numbers from `rng`. The new
/// throughput, the ray and whether the bounce was delta; `None` where the
/// path ends.
pub(crate) fn scatter_light(
    hit: &crate::geometry::SurfaceHit,
    bsdf: &crate::material::Bsdf,
    frame: &crate::material::ShadingFrame,
    wo_world: glam::Vec3,
    beta: Rgb,
    rng: &mut crate::sampling::rng::Pcg32,
) -> Option<(Rgb, Ray, bool)> {
    let wo = frame.to_local(wo_world);
    let (u_lobe, u) = (rng.next_f32(), glam::Vec2::new(rng.next_f32(), rng.next_f32()));
    let bs = bsdf.sample(wo, u_lobe, u, crate::material::TransportMode::Importance)?;
    if bs.pdf <= 0.0 || bs.f == Rgb::ZERO || bs.wi.z == 0.0 || wo.z == 0.0 {
        return None;
    }
    let wi_world = frame.to_world(bs.wi);
    let reflection = bs.wi.z * wo.z > 0.0;
    let front_o = hit.ng.dot(wo_world) > 0.0;
    if (hit.ng.dot(wi_world) > 0.0) != (front_o == reflection) {
        return None; // the shading normal sent the path through the surface
    }
    if hit.ng.dot(wo_world) == 0.0 {
        return None;
    }
    let correction = adjoint_shading_factor(hit.ng, wo_world, wo.z, wi_world, bs.wi.z);
    let next = beta * bs.f * (frame.factor(wo_world) * bs.wi.z.abs() * correction / bs.pdf);
    // By magnitude: a wavelength's weight may make a channel negative.
    let q = (next.abs().max_element() / beta.abs().max_element()).min(1.0);
    if q.is_nan() || q <= 0.0 || rng.next_f32() >= q {
        return None;
    }
    Some((next / q, hit.spawn_ray(wi_world), bs.delta))
}
