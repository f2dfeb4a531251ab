//! The MIS path tracer on eight paths at once, for diffuse scenes lit by
//! one rectangle light (a Cornell box, a lit room).
//!
//! The eight paths advance in lockstep, one bounce of all of them at a
//! time. Their rays go to the scene eight at a time
//! ([`Aggregate::intersect_rays`](crate::accel::Aggregate::intersect_rays)),
//! which in a room of rectangles tests them together, one rectangle
//! against eight rays, and elsewhere one by one; the surface records come
//! back in lanes too ([`Aggregate::surfaces`](crate::accel::Aggregate::surfaces),
//! computed in lanes in a room of rectangles). What differs from path to
//! path in control flow stays per path: the materials' lookups and the
//! sampler's draws. The shading between them (the light sample's
//! geometry, the diffuse BSDF, the MIS weights, the cosine-weighted
//! direction, the throughput and Russian roulette) is written over arrays
//! of eight lanes, structure of arrays, which the compiler turns into
//! vector instructions (eight-wide where the processor has AVX). This is
//! how Mitsuba's LLVM variants and other wavefront renderers use SIMD
//! across paths, here in its smallest form: the lanes of one tile, in the
//! tile's own order.
//!
//! Each lane is the path [`PathTracer::radiance`] traces with the same
//! sampler: the same numbers drawn in the same order, the same decisions
//! and the same arithmetic in the same order, so the two give the same
//! bits (a test compares whole films). Scenes with other materials or
//! lights, or options this loop does not cover, are traced one path at a
//! time.

use super::RayStats;
use super::path::{PathSampling, PathTracer, power_heuristic};
use crate::color::Rgb;
use crate::geometry::Ray;
use crate::geometry::interaction::SurfaceLanes;
use crate::light::{Light, Parallelogram};
use crate::material::MaterialKind;
use crate::sampling::Sampler;
use crate::scene::Scene;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_4};

/// Paths traced together.
pub const LANES: usize = 8;

/// One ray per lane.
pub type Rays = [Ray; LANES];

/// One sampler per lane.
pub type Samplers = [Sampler; LANES];

/// One colour per lane.
pub type Radiances = [Rgb; LANES];

/// One `f32` per lane.
type F32Lanes = [f32; LANES];

/// A vector per lane, as three arrays of coordinates.
#[derive(Clone, Copy, Default)]
struct Vec3Lanes {
    x: F32Lanes,
    y: F32Lanes,
    z: F32Lanes,
}

impl From<[[f32; LANES]; 3]> for Vec3Lanes {
    #[inline(always)]
    fn from([x, y, z]: [[f32; LANES]; 3]) -> Vec3Lanes {
        Vec3Lanes { x, y, z }
    }
}

impl Vec3Lanes {
    #[inline(always)]
    fn set(&mut self, i: usize, v: Vec3) {
        self.x[i] = v.x;
        self.y[i] = v.y;
        self.z[i] = v.z;
    }

    #[inline(always)]
    fn get(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }
}

/// The path tracer on a scene the lockstep loop can trace, with what the
/// loop needs of the scene: its one light.
#[derive(Clone, Copy, Debug)]
pub struct LockstepScene<'a> {
    integrator: &'a PathTracer,
    scene: &'a Scene,
    light: &'a Parallelogram,
    radiance: Rgb,
    /// Whether the processor runs AVX instructions.
    avx: bool,
}

impl<'a> LockstepScene<'a> {
    /// `integrator` on `scene` where that is what the lockstep loop
    /// traces: the MIS path tracer, every material diffuse, one light, a
    /// parallelogram of constant radiance, and no environment.
    pub fn new(integrator: &'a PathTracer, scene: &'a Scene) -> Option<LockstepScene<'a>> {
        if integrator.sampling != PathSampling::Mis
            || scene.lights.len() != 1
            || scene.light_distribution.len() != 1
            || scene.environment_light.is_some()
        {
            return None;
        }
        let Light::Area {
            parallelogram: Some(light),
            radiance: Texture::Constant(radiance),
            ..
        } = &scene.lights[0]
        else {
            return None;
        };
        // Textured colours are fine: each lane looks its own up.
        let diffuse = scene
            .materials
            .iter()
            .all(|m| matches!(m.kind, MaterialKind::Diffuse { .. }));
        #[cfg(target_arch = "x86_64")]
        let avx = crate::geometry::lanes::avx_available();
        #[cfg(not(target_arch = "x86_64"))]
        let avx = false;
        diffuse.then_some(LockstepScene {
            integrator,
            scene,
            light,
            radiance: *radiance,
            avx,
        })
    }

    /// The radiance along the first `count` of `rays`, lane `i` drawing
    /// its numbers from `samplers[i]` as [`PathTracer::radiance`] would;
    /// lanes from `count` on are not traced and return zero.
    pub fn radiance(&self, rays: &Rays, count: usize, samplers: &mut Samplers, stats: &mut RayStats) -> Radiances {
        #[cfg(target_arch = "x86_64")]
        if self.avx {
            // SAFETY: `avx` is set only where the processor has AVX.
            #[allow(unsafe_code)]
            return unsafe { self.radiance_avx(rays, count, samplers, stats) };
        }
        self.trace(rays, count, samplers, stats)
    }

    /// [`LockstepScene::radiance`] built for AVX: the lane loops become
    /// eight-wide vector code instead of two halves of four (SSE), and the
    /// flat scene's AVX query inlines into the loop (9.5% fewer
    /// instructions per sample, 3–4% less time on the Cornell box, the
    /// same bits; BENCHMARKS.md).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn radiance_avx(&self, rays: &Rays, count: usize, samplers: &mut Samplers, stats: &mut RayStats) -> Radiances {
        self.trace(rays, count, samplers, stats)
    }

    /// The body of [`LockstepScene::radiance`], inlined into each build of
    /// it.
    #[inline(always)]
    fn trace(&self, rays: &Rays, count: usize, samplers: &mut Samplers, stats: &mut RayStats) -> Radiances {
        let (integrator, scene) = (self.integrator, self.scene);
        let light = self.light;
        let mut l = Vec3Lanes::default();
        let mut beta = Vec3Lanes {
            x: [1.0; LANES],
            y: [1.0; LANES],
            z: [1.0; LANES],
        };
        let mut ray = *rays;
        let mut alive: [bool; LANES] = std::array::from_fn(|i| i < count);
        // The previous bounce, for weighting emission found by it. Diffuse
        // bounces are never delta: only the camera ray's end is unweighted.
        let mut first_segment = true;
        let mut prev_pdf = [0.0f32; LANES];
        let mut prev_p = Vec3Lanes::default();
        for (i, r) in rays.iter().enumerate() {
            prev_p.set(i, r.origin);
        }
        // Each lane's hit: its surface record, in lanes. What lanes that
        // are no longer alive hold is never read.
        let mut surfaces = SurfaceLanes::default();
        let mut albedo = Vec3Lanes::default();
        let mut wo = Vec3Lanes::default();
        let mut depth = 1u32;
        while depth <= integrator.max_depth {
            // The segments' queries and surface records, and emission found.
            let mut any_alive = false;
            let hits = scene.geometry.intersect_rays(&ray, lane_bits(&alive));
            scene.geometry.surfaces(&ray, &hits, &mut surfaces);
            let (p, ng) = (Vec3Lanes::from(surfaces.p), Vec3Lanes::from(surfaces.ng));
            // `-dir.normalize()` and `SurfaceHit::is_front` in lanes.
            let mut front = [false; LANES];
            for i in 0..LANES {
                let d = ray[i].dir;
                let recip = 1.0 / ((d.x * d.x) + (d.y * d.y) + (d.z * d.z)).sqrt();
                (wo.x[i], wo.y[i], wo.z[i]) = (-(d.x * recip), -(d.y * recip), -(d.z * recip));
                front[i] = (ng.x[i] * wo.x[i]) + (ng.y[i] * wo.y[i]) + (ng.z[i] * wo.z[i]) > 0.0;
            }
            for i in 0..LANES {
                if !alive[i] {
                    continue;
                }
                stats.rays += 1;
                if hits[i].is_none() {
                    alive[i] = false;
                    continue;
                }
                let m = &scene.materials[surfaces.material[i] as usize];
                let tex = TexCoord {
                    uv: Vec2::new(surfaces.uv[0][i], surfaces.uv[1][i]),
                    p: p.get(i),
                };
                if m.is_emissive() && front[i] {
                    let w = match surfaces.light[i] {
                        Some(li) if !first_segment => {
                            let pdf_light = scene.light_distribution.pmf(li as usize)
                                * scene.lights[li as usize].pdf_li(scene, prev_p.get(i), &surfaces.get(i));
                            power_heuristic(prev_pdf[i], pdf_light)
                        }
                        _ => 1.0,
                    };
                    let le = m.emission_at(&scene.images, &tex);
                    l.set(i, l.get(i) + beta.get(i) * le * w);
                }
                if depth == integrator.max_depth || !m.two_sided && !front[i] {
                    // The end of the path, or the black back of a one-sided
                    // surface.
                    alive[i] = false;
                    continue;
                }
                // The diffuse BSDF's albedo (`Material::bsdf`'s, read
                // without building the BSDF).
                let MaterialKind::Diffuse { reflectance } = &m.kind else {
                    unreachable!("LockstepScene::new admits diffuse materials only")
                };
                albedo.set(i, reflectance.eval(&scene.images, &tex));
                any_alive = true;
            }
            if !any_alive {
                break;
            }
            let (ns, tangent) = (Vec3Lanes::from(surfaces.ns), Vec3Lanes::from(surfaces.tangent));

            // The numbers of the bounce, in the path tracer's order: the light
            // choice and the pick within the light (both passed over: one
            // light, a parallelogram), the point on the light, the lobe choice
            // (passed over: one lobe), the direction.
            let mut u_light = [[0.0f32; LANES]; 2];
            let mut u_bsdf = [[0.0f32; LANES]; 2];
            for i in 0..LANES {
                if !alive[i] {
                    continue;
                }
                let s = &mut samplers[i];
                s.skip_1d();
                s.skip_1d();
                let u = s.next_2d();
                (u_light[0][i], u_light[1][i]) = (u.x, u.y);
                s.skip_1d();
                let u = s.next_2d();
                (u_bsdf[0][i], u_bsdf[1][i]) = (u.x, u.y);
            }

            // Next-event estimation (`Light::sample_li` for a parallelogram,
            // the diffuse BSDF's value and density, the power heuristic), in
            // lanes.
            let mut cast_shadow = [false; LANES];
            // Black lanes cast no shadow ray and end here, as in the path
            // tracer (its BSDF value is zero).
            let mut black = [false; LANES];
            let mut unoccluded = Vec3Lanes::default();
            let mut light_point = Vec3Lanes::default();
            let mut wo_z = [0.0f32; LANES];
            let mut front_o = [false; LANES];
            let (corner, edge_u, edge_v, ln) = (light.corner, light.edge_u, light.edge_v, light.normal);
            let le = self.radiance;
            for i in 0..LANES {
                let (nx, ny, nz) = (ns.x[i], ns.y[i], ns.z[i]);
                wo_z[i] = wo.x[i] * nx + wo.y[i] * ny + wo.z[i] * nz;
                front_o[i] = ng.x[i] * wo.x[i] + ng.y[i] * wo.y[i] + ng.z[i] * wo.z[i] > 0.0;
                let (ua, ub) = (u_light[0][i], u_light[1][i]);
                let lx = corner.x + ua * edge_u.x + ub * edge_v.x;
                let ly = corner.y + ua * edge_u.y + ub * edge_v.y;
                let lz = corner.z + ua * edge_u.z + ub * edge_v.z;
                (light_point.x[i], light_point.y[i], light_point.z[i]) = (lx, ly, lz);
                let (dx, dy, dz) = (lx - p.x[i], ly - p.y[i], lz - p.z[i]);
                let dist2 = dx * dx + dy * dy + dz * dz;
                let dist = dist2.sqrt();
                let (wx, wy, wz) = (dx / dist, dy / dist, dz / dist);
                // Emission leaves the light's front only.
                let cos_light = -(ln.x * wx + ln.y * wy + ln.z * wz);
                let pdf_light = light.pdf_area * dist2 / cos_light;
                let wi_z = wx * nx + wy * ny + wz * nz;
                let same_side = wi_z * wo_z[i] > 0.0;
                // The geometric normal decides reflection or transmission.
                let front_i = ng.x[i] * wx + ng.y[i] * wy + ng.z[i] * wz > 0.0;
                let consistent = (front_i == front_o[i]) == same_side;
                let pdf_bsdf = wi_z.abs() * FRAC_1_PI;
                let w = power_heuristic(pdf_light, pdf_bsdf);
                // f·Li·|cos θ|·w / p with f = albedo/π.
                let k = wi_z.abs() * w / pdf_light;
                unoccluded.x[i] = beta.x[i] * (albedo.x[i] * FRAC_1_PI) * le.x * k;
                unoccluded.y[i] = beta.y[i] * (albedo.y[i] * FRAC_1_PI) * le.y * k;
                unoccluded.z[i] = beta.z[i] * (albedo.z[i] * FRAC_1_PI) * le.z * k;
                black[i] = albedo.x[i] == 0.0 && albedo.y[i] == 0.0 && albedo.z[i] == 0.0;
                cast_shadow[i] = alive[i]
                    && dist2 != 0.0
                    && cos_light > 0.0
                    && pdf_light.is_finite()
                    && pdf_light > 0.0
                    && same_side
                    && consistent
                    && !black[i];
            }
            if le != Rgb::ZERO {
                let mut shadow_rays = ray;
                for i in 0..LANES {
                    if cast_shadow[i] {
                        stats.rays += 1;
                        shadow_rays[i] = surfaces.spawn_point(i).spawn_ray_to(light_point.get(i));
                    }
                }
                let shadow_bits = lane_bits(&cast_shadow);
                let occluded = scene.geometry.occluded_rays(&shadow_rays, shadow_bits);
                for i in 0..LANES {
                    if shadow_bits & !occluded & (1 << i) != 0 {
                        l.set(i, l.get(i) + unoccluded.get(i));
                    }
                }
            }

            // The diffuse BSDF's sample (`sample_hemisphere_cosine` on the side
            // of `wo`), the throughput and the next direction, in lanes.
            let mut wi_world = Vec3Lanes::default();
            let mut continues = [false; LANES];
            for i in 0..LANES {
                let (x, y, z) = sample_hemisphere_cosine_lane(u_bsdf[0][i], u_bsdf[1][i]);
                let z = if wo_z[i] < 0.0 { -z } else { z };
                let pdf = if z * wo_z[i] > 0.0 { z.abs() * FRAC_1_PI } else { 0.0 };
                let (nx, ny, nz) = (ns.x[i], ns.y[i], ns.z[i]);
                let (sx, sy, sz) = (tangent.x[i], tangent.y[i], tangent.z[i]);
                // The frame's second axis, n × s (`Frame::from_orthonormal`).
                let (tx, ty, tz) = (ny * sz - nz * sy, nz * sx - nx * sz, nx * sy - ny * sx);
                let wx = sx * x + tx * y + nx * z;
                let wy = sy * x + ty * y + ny * z;
                let wz = sz * x + tz * y + nz * z;
                (wi_world.x[i], wi_world.y[i], wi_world.z[i]) = (wx, wy, wz);
                let reflection = z * wo_z[i] > 0.0;
                // A shading normal that sends the path through the surface
                // ends it.
                let side_agrees = (ng.x[i] * wx + ng.y[i] * wy + ng.z[i] * wz > 0.0) == (front_o[i] == reflection);
                continues[i] = alive[i] && pdf > 0.0 && z != 0.0 && side_agrees && !black[i];
                let k = z.abs() / pdf;
                beta.x[i] *= (albedo.x[i] * FRAC_1_PI) * k;
                beta.y[i] *= (albedo.y[i] * FRAC_1_PI) * k;
                beta.z[i] *= (albedo.z[i] * FRAC_1_PI) * k;
                prev_pdf[i] = pdf;
                (prev_p.x[i], prev_p.y[i], prev_p.z[i]) = (p.x[i], p.y[i], p.z[i]);
            }
            first_segment = false;
            depth += 1;

            // The next rays, and Russian roulette, per lane.
            for i in 0..LANES {
                alive[i] = continues[i];
                if !alive[i] {
                    continue;
                }
                ray[i] = surfaces.spawn_point(i).spawn_ray(wi_world.get(i));
                if depth > integrator.rr_depth {
                    let q = beta.get(i).max_element().min(0.95);
                    if samplers[i].next_1d() >= q {
                        alive[i] = false;
                        continue;
                    }
                    beta.x[i] /= q;
                    beta.y[i] /= q;
                    beta.z[i] /= q;
                }
            }
        }
        std::array::from_fn(|i| l.get(i))
    }
}

/// A bit per lane that is set.
#[inline(always)]
fn lane_bits(lanes: &[bool; LANES]) -> u32 {
    (0..LANES).filter(|&i| lanes[i]).fold(0, |bits, i| bits | 1 << i)
}

/// [`crate::sampling::warp::sample_hemisphere_cosine`] as (x, y, z), its
/// two cases selected rather than branched on, so that a loop over lanes
/// becomes vector code.
#[inline(always)]
fn sample_hemisphere_cosine_lane(u0: f32, u1: f32) -> (f32, f32, f32) {
    let (ox, oy) = (2.0 * u0 - 1.0, 2.0 * u1 - 1.0);
    let x_major = ox.abs() > oy.abs();
    let (r, other) = if x_major { (ox, oy) } else { (oy, ox) };
    let (sin, cos) = crate::sampling::warp::sin_cos_quarter_pi(FRAC_PI_4 * (other / r));
    let (x, y) = if x_major {
        (r * cos, r * sin)
    } else {
        (r * sin, r * cos)
    };
    let (x, y) = if ox == 0.0 && oy == 0.0 { (0.0, 0.0) } else { (x, y) };
    (x, y, (1.0 - (x * x + y * y)).max(0.0).sqrt())
}
