//! Photon mapping: light traced forward from the lights and stored where it
//! lands, then read back by density estimation.
//!
//! - [`map`]: the photon map, a kd-tree with k-nearest and radius queries.
//! - [`trace`]: the photon pass shared by both algorithms, multi-threaded
//!   and deterministic.
//! - [`jensen`]: Jensen's two-pass photon mapping (`--integrator photon`):
//!   a global and a caustic map, direct light by next-event estimation,
//!   final gathering for diffuse interreflection.
//! - [`sppm`]: stochastic progressive photon mapping (`--integrator sppm`,
//!   Hachisuka and Jensen 2009): iterations of camera and photon passes
//!   whose radii shrink, so that the image converges to the path tracer's.
//!
//! ```toml
//! [render]
//! integrator = "photon"   # or "sppm"
//! photons = 200000        # photons for the global map
//! caustic_photons = 200000
//! photon_gather = 64      # photons per radiance estimate (k nearest)
//! photon_radius = 0       # largest search radius (SPPM: initial radius); 0: from the scene's size
//! final_gather = 16       # final-gather rays per camera sample (0: read the global map directly)
//! photon_kernel = "cone"  # or "epanechnikov", "box"
//! sppm_photons = 0        # photons per SPPM iteration; 0: one per pixel
//! sppm_alpha = 0.6667     # share of new photons SPPM keeps per iteration
//! ```

pub mod jensen;
pub mod map;
pub mod sppm;
pub mod trace;

pub use jensen::PhotonMapper;
pub use map::{Nearest, Photon, PhotonMap};

use crate::color::Rgb;
use crate::geometry::{Ray, SurfaceHit};
use crate::light::ShadowTarget;
use crate::material::{Bsdf, ShadingFrame, TransportMode};
use crate::sampling::Sampler;
use crate::scene::Scene;
use crate::settings::{PhotonKernel, PhotonSettings};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

impl PhotonKernel {
    /// Weight of a photon at squared distance `d2` in a disk of squared
    /// radius `r2`, divided by the kernel's integral over the disk: the
    /// weights of photons sum to a density estimate per unit area.
    #[inline]
    pub fn weight(&self, d2: f32, r2: f32) -> f32 {
        match self {
            PhotonKernel::Box => 1.0 / (PI * r2),
            PhotonKernel::Cone => (1.0 - (d2 / r2).sqrt()).max(0.0) * 3.0 / (PI * r2),
            PhotonKernel::Epanechnikov => (1.0 - d2 / r2).max(0.0) * 2.0 / (PI * r2),
        }
    }
}

impl PhotonSettings {
    /// The photon radius: the one given, or [`default_radius`].
    pub fn radius_for(&self, scene: &Scene) -> f32 {
        if self.radius > 0.0 {
            self.radius
        } else {
            default_radius(scene)
        }
    }
}

/// Pixel footprints the default photon radius spans.
const RADIUS_FOOTPRINTS: f32 = 2.0;

/// The photon radius where the scene gives none (SPPM's initial radius,
/// photon mapping's largest search radius): two pixel footprints, the
/// median of the footprints at the surfaces the camera sees through a grid
/// of pixel centres, so that it follows the image's resolution and the
/// camera as well as the scene's size (a fixed share of the scene's extent
/// blurs caustics in large scenes and starves small ones; pbrt-v4 leaves it
/// to the user). Two footprints is the middle of the flat optimum measured
/// for SPPM on the suite's caustic (docs/photon-mapping.md). A camera that
/// sees nothing falls back to 2 % of the scene's radius.
pub fn default_radius(scene: &Scene) -> f32 {
    let s = &scene.settings;
    const GRID: u32 = 16;
    let mut footprints = Vec::with_capacity((GRID * GRID) as usize);
    for j in 0..GRID {
        for i in 0..GRID {
            let x = (i as f32 + 0.5) / GRID as f32 * s.width as f32;
            let y = (j as f32 + 0.5) / GRID as f32 * s.height as f32;
            let ray = scene.camera.generate_ray(Vec2::new(x, y), Vec2::ZERO);
            let Some(hit) = scene.intersect(&ray) else {
                continue;
            };
            // The neighbouring pixel's ray, followed as far: the distance
            // between the two points is the footprint, for any projection.
            let next = scene.camera.generate_ray(Vec2::new(x + 1.0, y), Vec2::ZERO);
            let d = (hit.p - ray.origin).length();
            let q = next.origin + next.dir.normalize_or_zero() * d;
            let footprint = (q - hit.p).length();
            if footprint.is_finite() && footprint > 0.0 {
                footprints.push(footprint);
            }
        }
    }
    if footprints.is_empty() {
        return crate::light::scene_bounding_sphere(scene).1 * 0.02;
    }
    footprints.sort_by(f32::total_cmp);
    RADIUS_FOOTPRINTS * footprints[footprints.len() / 2]
}

/// Whether a photon that landed on a surface of normal `photon_n` may be
/// counted at a point of normal `n`: both on one side of the same surface
/// (Jensen 2001, §7.2, discarding photons of nearby surfaces in corners).
#[inline]
pub(crate) fn same_surface(photon_n: Vec3, n: Vec3) -> bool {
    photon_n.dot(n) > 0.7
}

/// The `depth`-th segment of a camera path as both photon integrators
/// follow it: traces `ray`, adds to `l` the light seen along it (the
/// environment on a miss, emission from the front of an emitter, unless
/// the settings hide them from the camera) weighted by `beta`, and returns
/// the surface to go on from; `None` where the path ends (a miss, the last
/// segment, the back of a one-sided surface). The path carries
/// `wavelength` past dispersive glass (drawn from `draw` at the first);
/// the shading point's `spectral` weight then multiplies its throughput.
#[allow(clippy::too_many_arguments)]
pub(crate) fn camera_segment<'a>(
    scene: &'a Scene,
    ray: &Ray,
    beta: Rgb,
    depth: u32,
    l: &mut Rgb,
    rays: &mut u64,
    wavelength: &mut Option<f32>,
    draw: impl FnOnce() -> f32,
) -> Option<(SurfaceHit, ShadingPoint<'a>)> {
    *rays += 1;
    let last = depth >= scene.settings.max_depth;
    let shows_emission = scene.settings.shows_emission(depth);
    let Some(mut hit) = scene.intersect(ray) else {
        if scene.environment_light.is_some() && shows_emission {
            *l += beta * scene.background.eval_from(ray.origin, ray.dir);
        }
        return None;
    };
    // Photon mapping takes one material of a blend per shading point (the
    // blend on average): its shading points outlive a blend's parts.
    scene.choose_any_material(&mut hit, ray.dir);
    let wo_world = -ray.dir.normalize();
    let m = &scene.materials[hit.material as usize];
    if m.is_emissive() && shows_emission && m.emits_toward(&hit, wo_world) {
        *l += beta * m.emission_at(&scene.textures, &crate::texture::TexCoord::at(&hit));
    }
    if last {
        return None;
    }
    let sp = ShadingPoint::new(scene, &hit, wo_world, wavelength, draw)?;
    Some((hit, sp))
}

/// The BSDF at a surface as the camera-side passes see it.
pub(crate) struct ShadingPoint<'a> {
    pub(crate) bsdf: Bsdf<'a>,
    pub(crate) frame: ShadingFrame,
    /// Outgoing direction in the local frame.
    pub(crate) wo: Vec3,
    /// Whether `wo` is on the geometric front.
    pub(crate) front_o: bool,
    /// What the path's throughput is multiplied by from here on: the
    /// weight of the wavelength drawn here, at the path's first
    /// dispersive glass (see [`crate::integrator::path_wavelength`]); 1
    /// elsewhere.
    pub(crate) spectral: Rgb,
}

impl<'a> ShadingPoint<'a> {
    /// The shading point of `hit` seen along `-wo_world` by a path of
    /// `wavelength` (drawn from `draw` at its first dispersive glass);
    /// `None` for the back of a one-sided opaque surface, which is black.
    pub(crate) fn new(
        scene: &'a Scene,
        hit: &SurfaceHit,
        wo_world: Vec3,
        wavelength: &mut Option<f32>,
        draw: impl FnOnce() -> f32,
    ) -> Option<ShadingPoint<'a>> {
        let m = &scene.materials[hit.material as usize];
        let tc = crate::texture::TexCoord::at(hit);
        let mut spectral = Rgb::ONE;
        let bsdf = crate::integrator::material_path_bsdf(scene, hit.material, &tc, wavelength, draw, &mut spectral);
        if !m.two_sided && !bsdf.transmits() && !hit.is_front(wo_world) {
            return None;
        }
        let frame = m.shading_frame(&scene.textures, hit, wo_world);
        Some(ShadingPoint {
            bsdf,
            frame,
            wo: frame.to_local(wo_world),
            front_o: hit.ng.dot(wo_world) > 0.0,
            spectral,
        })
    }

    /// f(wo, wi) for a world direction `wi` (toward the light), zero when
    /// the geometric and shading normals disagree about the side.
    #[inline]
    pub(crate) fn eval(&self, hit: &SurfaceHit, wi_world: Vec3) -> Rgb {
        let wi = self.frame.to_local(wi_world);
        let front_i = hit.ng.dot(wi_world) > 0.0;
        if (front_i == self.front_o) != (wi.z * self.wo.z > 0.0) {
            return Rgb::ZERO;
        }
        self.bsdf.eval(self.wo, wi, TransportMode::Radiance) * self.frame.factor(wi_world)
    }

    /// Reflected radiance from the photons of `map` near `hit`: the density
    /// estimate Σ f·Φ·w(d) (Jensen 2001, eq. 7.6) over the `k` nearest within
    /// √`max_r2`. When fewer than `k` are found, the disk is the whole
    /// search disk.
    pub(crate) fn photon_radiance(
        &self,
        hit: &SurfaceHit,
        map: &PhotonMap,
        k: usize,
        max_r2: f32,
        kernel: PhotonKernel,
        found: &mut Nearest,
    ) -> Rgb {
        let Some(far) = map.nearest(hit.p, k, max_r2, found) else {
            return Rgb::ZERO;
        };
        let r2 = if found.len() < k { max_r2 } else { far };
        if r2 <= 0.0 {
            return Rgb::ZERO;
        }
        let mut sum = Rgb::ZERO;
        for (d2, index) in found.iter() {
            let ph = map.photon(index);
            if !same_surface(ph.normal(), hit.ng) {
                continue;
            }
            let f = self.eval(hit, ph.wi());
            sum += f * ph.power * kernel.weight(d2, r2);
        }
        sum
    }

    /// Direct light by next-event estimation: one light chosen by power,
    /// one point on it, one shadow ray. Light found by hitting emitters is
    /// never added after a non-specular bounce, so this is the only
    /// estimate of direct light and needs no MIS weight.
    pub(crate) fn direct_light(&self, scene: &Scene, hit: &SurfaceHit, sampler: &mut Sampler, rays: &mut u64) -> Rgb {
        if scene.lights.is_empty() {
            return Rgb::ZERO;
        }
        let Some((light_index, pmf)) = crate::integrator::choose_light(scene, hit.p, hit.ns, sampler, false) else {
            // No light reaches the point: its numbers are passed over.
            sampler.skip_1d();
            sampler.skip_2d();
            return Rgb::ZERO;
        };
        let Some(ls) = scene.lights[light_index].sample_li_drawing(scene, hit.p, sampler, false) else {
            return Rgb::ZERO;
        };
        if ls.li == Rgb::ZERO || pmf <= 0.0 {
            return Rgb::ZERO;
        }
        let f = self.eval(hit, ls.wi);
        if f == Rgb::ZERO {
            return Rgb::ZERO;
        }
        *rays += 1;
        let shadow = match ls.target {
            ShadowTarget::Point(p) => hit.spawn_ray_to(p),
            ShadowTarget::Infinity => hit.spawn_ray(ls.wi),
        };
        if scene.occluded(&shadow) {
            return Rgb::ZERO;
        }
        let cos = self.frame.to_local(ls.wi).z.abs();
        f * ls.li * (cos / (ls.pdf * pmf))
    }
}
