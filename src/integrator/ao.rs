//! Ambient occlusion (Zhukov et al. 1998; pbrt-v4's `AOIntegrator`): the
//! share of the hemisphere above the first surface a camera ray meets that
//! is open to the sky within a distance, weighted by the cosine. Each sample
//! casts one cosine-distributed ray, so a pixel is the mean of 1 (open) and
//! 0 (blocked): white where nothing is near, dark in creases and corners.
//! It needs no lights and no materials, which makes it a first look at a
//! scene's geometry, and a lesson in Monte Carlo visibility.

use crate::color::Rgb;
use crate::geometry::Ray;
use crate::integrator::{Integrator, RayStats};
use crate::material::Frame;
use crate::sampling::Sampler;
use crate::sampling::warp::sample_hemisphere_cosine;
use crate::scene::Scene;

/// Ambient occlusion within `max_distance` (infinite: any surface occludes).
#[derive(Clone, Copy, Debug)]
pub struct AmbientOcclusion {
    /// How far a surface still occludes.
    pub max_distance: f32,
}

impl Integrator for AmbientOcclusion {
    fn radiance(&self, scene: &Scene, camera_ray: &Ray, sampler: &mut Sampler, stats: &mut RayStats) -> Rgb {
        stats.rays += 1;
        let Some(hit) = scene.intersect(camera_ray) else {
            return Rgb::ZERO;
        };
        // The hemisphere on the viewer's side of the shading normal.
        let wo = -camera_ray.dir;
        let n = if hit.ns.dot(wo) < 0.0 { -hit.ns } else { hit.ns };
        let dir = Frame::from_normal(n).to_world(sample_hemisphere_cosine(sampler.next_2d()));
        // A direction below the surface itself is blocked by it.
        if hit.ng.dot(dir) * hit.ng.dot(wo) <= 0.0 {
            return Rgb::ZERO;
        }
        stats.rays += 1;
        let mut ray = hit.spawn_ray(dir);
        ray.t_max = self.max_distance;
        if scene.occluded(&ray) { Rgb::ZERO } else { Rgb::ONE }
    }
}
