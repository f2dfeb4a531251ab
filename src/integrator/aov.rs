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

/// What pbrt-v4's `GBufferFilm` records of a camera ray (its
/// `VisibleSurface`): the first surface with a BSDF that the ray meets
/// (surfaces that only bound a medium are passed), or `None`. Positions,
/// normals (facing the ray's origin) and the depth slopes are in `space`;
/// the slopes come from the rays one pixel over along x and along y, met
/// on the surface's tangent plane, their offsets scaled by
/// `differential_scale` as pbrt-v4 scales camera ray differentials
/// (max(1/8, 1/√spp)). The albedo is the BSDF's directional albedo
/// toward the camera, estimated as pbrt-v4's `BSDF::rho` with 16 fixed
/// stratified samples.
pub fn camera_gbuffer(
    scene: &Scene,
    camera_ray: &Ray,
    film: glam::Vec2,
    lens: glam::Vec2,
    space: crate::settings::GBufferSpace,
    differential_scale: f32,
) -> Option<crate::film::GBufferSample> {
    use crate::settings::GBufferSpace;
    use glam::{Vec2, Vec3};
    let mut ray = *camera_ray;
    let mut first = None;
    // At most as many boundaries passed as specular bounces followed above.
    for _ in 0..=MAX_SPECULAR_CHAIN {
        let hit = scene.intersect(&ray)?;
        let wo_world = -ray.dir.normalize();
        let mut parts = None;
        let bsdf = scene.bsdf(hit.material, &TexCoord::at(&hit), &mut parts);
        if bsdf.pass_through(wo_world) == Rgb::ONE {
            // A medium's boundary: pbrt-v4 skips it.
            ray = hit.spawn_ray(ray.dir);
            continue;
        }
        let m = &scene.materials[hit.material as usize];
        let frame = m.shading_frame(&scene.textures, &hit, wo_world);
        let wo = frame.to_local(wo_world);
        let mut albedo = Rgb::ZERO;
        for i in 0..RHO_SAMPLES {
            let (u_lobe, u) = rho_sample(i);
            if let Some(s) = bsdf.sample(wo, u_lobe, u, TransportMode::Radiance)
                && s.pdf > 0.0
            {
                albedo += s.f * (s.wi.z.abs() / s.pdf);
            }
        }
        albedo /= RHO_SAMPLES as f32;
        let face = |n: Vec3| if n.dot(wo_world) < 0.0 { -n } else { n };
        first = Some((hit, face(hit.ng), face(frame.n), albedo));
        break;
    }
    let (hit, n, ns, albedo) = first?;
    // The offset rays on the tangent plane (pbrt-v4's
    // `SurfaceInteraction::ComputeDifferentials`).
    let camera = &scene.camera;
    let (o, d) = (camera_ray.origin, camera_ray.dir.normalize());
    let offset_point = |step: Vec2| {
        let r = camera.generate_ray(film + step, lens);
        let ro = o + (r.origin - o) * differential_scale;
        let rd = d + (r.dir.normalize() - d) * differential_scale;
        let t = (hit.ng.dot(hit.p) - hit.ng.dot(ro)) / hit.ng.dot(rd);
        if t.is_finite() { ro + rd * t } else { hit.p }
    };
    let (px, py) = (offset_point(Vec2::X), offset_point(Vec2::Y));
    let (p, n, ns, dpdx, dpdy) = match space {
        GBufferSpace::World => (hit.p, n, ns, px - hit.p, py - hit.p),
        GBufferSpace::Camera => {
            let to_camera = camera.camera_to_world().inverse();
            (
                to_camera.point(hit.p),
                to_camera.normal(n).normalize_or_zero(),
                to_camera.normal(ns).normalize_or_zero(),
                to_camera.vector(px - hit.p),
                to_camera.vector(py - hit.p),
            )
        }
    };
    Some(crate::film::GBufferSample {
        p,
        n,
        ns,
        uv: hit.uv,
        dzdx: dpdx.z,
        dzdy: dpdy.z,
        albedo,
    })
}

/// The samples of a G-buffer's albedo estimate.
const RHO_SAMPLES: u32 = 16;

/// Sample `i` of [`RHO_SAMPLES`]: the lobe number from the van der Corput
/// sequence, the direction's point stratified in a 4 × 4 grid with its
/// offset from the next two Halton dimensions; the same for every pixel,
/// as pbrt-v4's fixed table.
fn rho_sample(i: u32) -> (f32, glam::Vec2) {
    use crate::sampling::halton::radical_inverse;
    let index = i as u64 + 1;
    let cell = glam::Vec2::new((i % 4) as f32, (i / 4) as f32);
    let jitter = glam::Vec2::new(radical_inverse(1, index), radical_inverse(2, index));
    (radical_inverse(0, index), (cell + jitter) / 4.0)
}
