//! Integrators: the algorithms that estimate the radiance arriving along a
//! camera ray. This is the only place that knows the algorithm; scheduling,
//! films and files are elsewhere.

pub mod aov;
pub mod path;
pub mod path_lanes;
pub mod photon;
pub mod whitted;

pub use path::PathTracer;
pub use photon::PhotonMapper;
pub use whitted::Whitted;

use crate::color::Rgb;
use crate::geometry::Ray;
use crate::sampling::Sampler;
use crate::scene::Scene;

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

/// A per-sample radiance estimator.
pub trait Integrator: Sync {
    /// An estimate of the radiance arriving at the camera along `ray`.
    fn radiance(&self, scene: &Scene, ray: &Ray, sampler: &mut Sampler, stats: &mut RayStats) -> Rgb;
    /// This integrator as the path tracer, which the renderer may run on
    /// eight paths at once ([`path_lanes`]); `None` for the others.
    fn as_path_tracer(&self) -> Option<&PathTracer> {
        None
    }
}

/// Chooses one of the scene's lights for the point `p` with surface
/// normal `n` (zero for a point in no surface) by the light tree
/// ([`crate::light::LightSampler`]): the light's index and the probability
/// of choosing it, or `None` where no light can reach the point. The
/// choice is drawn from `sampler`, or passed over where the scene has a
/// single light, which leaves the numbers after it unchanged.
#[inline(always)]
pub(crate) fn choose_light(scene: &Scene, p: glam::Vec3, n: glam::Vec3, sampler: &mut Sampler) -> Option<(usize, f32)> {
    if scene.lights.len() == 1 {
        sampler.skip_1d();
        return Some((0, 1.0));
    }
    scene.light_sampler.sample(p, n, sampler.next_1d())
}

/// The probability with which [`choose_light`] at (`p`, `n`) chooses
/// light `light`.
#[inline]
pub(crate) fn light_choice_pmf(scene: &Scene, p: glam::Vec3, n: glam::Vec3, light: usize) -> f32 {
    if scene.lights.len() == 1 {
        return 1.0;
    }
    scene.light_sampler.pmf(p, n, light)
}
