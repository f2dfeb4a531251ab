//! Auxiliary images (AOVs): what the camera sees first, for denoisers and
//! debugging. Computed from the camera ray alone, independent of the
//! integrator, following perfectly specular bounces (mirrors, smooth
//! glass) to the first surface with a non-specular lobe, as denoisers such
//! as Intel Open Image Denoise expect.

use crate::color::Rgb;
use crate::film::AovSample;
use crate::geometry::Ray;
use crate::material::TransportMode;
use crate::scene::Scene;
use crate::texture::TexCoord;

/// Most specular bounces followed before giving up.
const MAX_SPECULAR_CHAIN: u32 = 8;

/// The auxiliary values seen along a camera ray.
pub fn camera_aov(scene: &Scene, camera_ray: &Ray) -> AovSample {
    let mut ray = *camera_ray;
    let mut out = AovSample::default();
    let mut throughput = Rgb::ONE;
    for bounce in 0..=MAX_SPECULAR_CHAIN {
        let steps_before = crate::geometry::sdf::steps_on_this_thread();
        let found = scene.intersect(&ray);
        if bounce == 0 {
            out.steps = (crate::geometry::sdf::steps_on_this_thread() - steps_before) as f32;
        }
        let Some(hit) = found else {
            // Seen through a specular chain, the background is the colour.
            if bounce > 0 {
                out.albedo = (throughput * scene.background.eval_from(ray.origin, ray.dir)).min(Rgb::ONE);
            }
            return out;
        };
        let wo_world = -ray.dir.normalize();
        if bounce == 0 {
            out.depth = hit.t * ray.dir.length();
        }
        let m = &scene.materials[hit.material as usize];
        let mut parts = None;
        let bsdf = scene.bsdf(hit.material, &TexCoord::at(&hit), &mut parts);
        let frame = m.shading_frame(&scene.textures, &hit, wo_world);
        let facing = if frame.n.dot(wo_world) < 0.0 { -frame.n } else { frame.n };
        if bsdf.has_smooth() || bounce == MAX_SPECULAR_CHAIN {
            out.albedo = throughput * bsdf.albedo();
            out.normal = facing;
            return out;
        }
        // Follow the most likely specular lobe, deterministically.
        let wo = frame.to_local(wo_world);
        let Some(s) = bsdf.sample_delta(wo, 0.5, TransportMode::Radiance) else {
            out.normal = facing;
            return out;
        };
        throughput *= s.f * (s.wi.z.abs() / s.pdf.max(1e-6));
        ray = hit.spawn_ray(frame.to_world(s.wi));
    }
    out
}
