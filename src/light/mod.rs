//! Light sources: point, spot, directional, area lights (emissive shapes)
//! and the environment (the background, seen as light from infinitely far
//! away).
//!
//! ```toml
//! [[light]]
//! type = "point"
//! position = [0, 1.9, 0]
//! intensity = [5, 5, 5]     # W/sr
//! falloff = true            # inverse-square law (false: classic constant light)
//! ```
//!
//! Every light answers, for a shading point: which direction to look in
//! for light, how much arrives and with what density the direction was
//! chosen ([`Light::sample_li`]); and, for multiple importance sampling,
//! with what density it would have chosen a given direction
//! ([`Light::pdf_li`]).

pub mod emission;
pub mod environment;
pub mod portal;
pub mod sampler;

pub use emission::{EmissionSample, sample_scene_emission, scene_bounding_sphere};
pub use environment::{Background, EnvironmentMap};
pub use sampler::{LightBounds, LightSampler};

use crate::accel::aggregate::{EmitterArea, EmitterRef};
use crate::color::{Rgb, luminance};
use crate::geometry::SurfaceHit;
use crate::geometry::shape::Shape;
use crate::geometry::simd::{Floats, Vec3s};
use crate::material::Frame;
use crate::sampling::warp::{orthonormal_basis_lanes, pdf_sphere_uniform, sample_sphere_uniform, sin_cos_turn};
use crate::sampling::{Distribution2D, Sampler};
use crate::scene::Scene;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// A light source.
#[derive(Clone, Debug)]
pub enum Light {
    /// An isotropic point light.
    Point {
        /// Position.
        position: Vec3,
        /// Radiant intensity (W/sr).
        intensity: Rgb,
        /// Inverse-square falloff; without it the light delivers
        /// `intensity` as irradiance at every distance.
        falloff: bool,
    },
    /// A point light restricted to a cone, fading between an inner and an
    /// outer angle, optionally projecting an image.
    Spot {
        /// Position.
        position: Vec3,
        /// Unit axis of the cone (the direction light travels).
        direction: Vec3,
        /// Radiant intensity on the axis (W/sr).
        intensity: Rgb,
        /// Cosine of the angle inside which the intensity is full.
        cos_inner: f32,
        /// Cosine of the angle outside which there is no light.
        cos_outer: f32,
        /// How the intensity falls between the two angles.
        profile: SpotProfile,
        /// An image the light projects, where it has one.
        projection: Option<SpotProjection>,
        /// Inverse-square falloff.
        falloff: bool,
    },
    /// A point light that projects an image through a pinhole, as a
    /// projector does (Mitsuba 3's `projector`): the image fills the frame
    /// of a perspective camera at the light, and a surface facing it at
    /// depth z in that frame receives the image's value as irradiance
    /// scaled by π/z².
    Projector(Box<Projector>),
    /// A point light whose intensity varies with direction as an image
    /// says (pbrt-v4's `goniometric`: a measured luminaire).
    Goniometric(Box<Goniometric>),
    /// Parallel light from infinitely far away, like the sun.
    Directional {
        /// Unit direction in which the light travels.
        direction: Vec3,
        /// Irradiance on a surface facing the light (W/m²).
        irradiance: Rgb,
    },
    /// An emissive shape or mesh.
    Area {
        /// The emitting geometry.
        emitter: EmitterRef,
        /// Emitted radiance from the front side (from both with
        /// `two_sided`).
        radiance: Texture,
        /// Whether the back emits too (pbrt-v4's `twosided` area lights).
        two_sided: bool,
        /// Area data for sampling.
        area: EmitterArea,
        /// Centre and radius when the emitter is a sphere, which is then
        /// sampled by the cone it subtends rather than by area.
        sphere: Option<(Vec3, f32)>,
        /// The emitter itself when it is a rectangle in world space, which
        /// is then sampled here rather than through the aggregate.
        parallelogram: Option<Parallelogram>,
        /// The world-space bounding sphere of an emitter that has no
        /// density over its area (a distance function or an implicit
        /// surface), which is sampled by direction instead: uniformly in
        /// the cone the sphere subtends (over every direction from inside
        /// it), the light's point the emitter's first along the direction.
        /// Its rays of light, and the light points of bidirectional
        /// connections, are drawn through lines across the sphere
        /// ([`sample_on_lines`]).
        cone: Option<(Vec3, f32)>,
    },
    /// The background (see [`Background`]), as light from every direction.
    Environment,
}

/// A rectangle emitter in world space (its transform baked in), kept in the
/// light so that sampling it is a few multiply-adds: the Cornell box's
/// light is one, sampled at every bounce, and the general route (a match on
/// the emitter, then on its shape, then a division by its area) cost about
/// as many instructions again (BENCHMARKS.md). Points, normal, coordinates
/// and density are those [`crate::accel::Aggregate::sample_emitter`] gives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Parallelogram {
    pub(crate) corner: Vec3,
    pub(crate) edge_u: Vec3,
    pub(crate) edge_v: Vec3,
    /// The front side's unit normal.
    pub(crate) normal: Vec3,
    /// Density per unit area: one over the area.
    pub(crate) pdf_area: f32,
}

impl Parallelogram {
    /// The rectangle emitter `emitter` of `geometry` with area data `area`,
    /// or `None` for other emitters.
    pub fn of_emitter(geometry: &crate::accel::Aggregate, emitter: EmitterRef, area: &EmitterArea) -> Option<Self> {
        let ([corner, edge_u, edge_v], normal) = geometry.emitter_parallelogram(emitter)?;
        Some(Parallelogram {
            corner,
            edge_u,
            edge_v,
            normal,
            pdf_area: 1.0 / area.total,
        })
    }
}

/// Where a shadow ray must go to test a light sample's visibility.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShadowTarget {
    /// A point on the light (segment test).
    Point(Vec3),
    /// Infinitely far along the sampled direction.
    Infinity,
}

/// Light arriving at a shading point from one sampled direction.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point toward the light.
    pub wi: Vec3,
    /// Incident radiance along `wi` (for delta lights: the irradiance the
    /// light delivers to a surface facing it, with pdf 1).
    pub li: Rgb,
    /// Density of `wi` per unit solid angle; 1 for delta lights.
    pub pdf: f32,
    /// Whether the light is a delta distribution (point, spot, directional).
    pub is_delta: bool,
    /// What the shadow ray must reach.
    pub target: ShadowTarget,
}

/// How a spot light's intensity falls between its inner angle (full) and
/// its outer angle (none).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpotProfile {
    /// A smoothstep in the cosine of the angle, as pbrt-v4's `SpotLight`.
    #[default]
    SmoothStepInCosine,
    /// Linear in the angle, as Mitsuba 3's `spot` (`falloff_curve`).
    LinearInAngle,
}

impl SpotProfile {
    /// The share of the axis's intensity at `cos_theta` from the axis, for
    /// a cone whose full and zero intensity begin at the angles whose
    /// cosines are `cos_inner` and `cos_outer`.
    #[inline]
    pub fn eval(self, cos_inner: f32, cos_outer: f32, cos_theta: f32) -> f32 {
        match self {
            SpotProfile::SmoothStepInCosine => smoothstep(cos_outer, cos_inner, cos_theta),
            SpotProfile::LinearInAngle => {
                if cos_theta <= cos_outer {
                    0.0
                } else if cos_theta >= cos_inner {
                    1.0
                } else {
                    let (inner, outer) = (cos_inner.acos(), cos_outer.acos());
                    (outer - cos_theta.acos()) / (outer - inner)
                }
            }
        }
    }
}

/// An image a spot light projects (Mitsuba 3's `spot` with a `texture`):
/// a direction `d` from the light, taken into the light's own frame as
/// `l = to_local · d`, reads the image at u = ½ + ½·l.x / (l.z·tan θ_outer),
/// v = ½ + ½·l.y / (l.z·tan θ_outer), so that the image spans the outer
/// cone's square.
#[derive(Clone, Copy, Debug)]
pub struct SpotProjection {
    /// World to the light's frame (the inverse of its `to_world`'s linear
    /// part: the axis is +z).
    pub to_local: glam::Mat3,
    /// tan of the outer angle.
    pub tan_outer: f32,
    /// The image.
    pub texture: Texture,
}

impl SpotProjection {
    /// Where world direction `d` from the light reads the image.
    #[inline]
    pub fn uv(&self, d: Vec3) -> Vec2 {
        let l = self.to_local * d;
        let k = 0.5 / (l.z * self.tan_outer);
        Vec2::new(0.5 + l.x * k, 0.5 + l.y * k)
    }

    /// The image's colour in world direction `d` from the light.
    #[inline]
    pub fn eval(&self, textures: &crate::texture::TextureStore, d: Vec3) -> Rgb {
        let uv = self.uv(d);
        self.texture.eval(textures, &TexCoord::new(uv, Vec3::ZERO))
    }
}

/// A goniometric light (see [`Light::Goniometric`]): the intensity toward
/// a direction is `intensity` times the value of the square image's pixel
/// that pbrt-v4's equal-area octahedral mapping (Clarberg 2008) takes the
/// direction to, in the light's frame, read at the nearest pixel as
/// pbrt-v4's `GoniometricLight` reads it. Every pixel subtends 4π/N
/// steradians, so emitted directions are drawn pixel by pixel in
/// proportion to the values.
#[derive(Clone, Debug)]
pub struct Goniometric {
    /// Position of the light.
    pub position: Vec3,
    /// World directions into the image's frame (its square's centre is
    /// +z there).
    pub to_local: glam::Mat3,
    /// Its inverse.
    pub to_world: glam::Mat3,
    /// Intensity (W/sr) where the image's value is 1.
    pub intensity: Rgb,
    /// The image's side in pixels.
    size: usize,
    /// Its values, row by row from the top.
    values: Vec<f32>,
    distribution: Distribution2D,
    mean: f32,
}

impl Goniometric {
    /// A light at `position` whose frame `to_world` takes to the world,
    /// with the `size` × `size` values of its image, row by row from the
    /// top (non-negative and finite).
    pub fn new(position: Vec3, to_world: glam::Mat3, intensity: Rgb, size: usize, values: Vec<f32>) -> Self {
        assert!(size > 0 && values.len() == size * size, "a square image");
        let mean = (values.iter().map(|&v| v as f64).sum::<f64>() / values.len() as f64) as f32;
        Goniometric {
            position,
            to_local: to_world.inverse(),
            to_world,
            intensity,
            size,
            distribution: Distribution2D::new(&values, size, size),
            values,
            mean,
        }
    }

    /// The image's value toward world direction `dir`.
    #[inline]
    fn value(&self, dir: Vec3) -> f32 {
        let local = (self.to_local * dir).normalize_or_zero();
        if local == Vec3::ZERO {
            return 0.0;
        }
        let uv = environment::equal_area_sphere_to_square(local);
        let n = self.size;
        let x = ((uv.x * n as f32) as usize).min(n - 1);
        let y = ((uv.y * n as f32) as usize).min(n - 1);
        self.values[y * n + x]
    }

    /// Intensity (W/sr) toward world direction `dir`.
    #[inline]
    pub fn intensity_toward(&self, dir: Vec3) -> Rgb {
        self.intensity * self.value(dir)
    }

    /// A unit direction of emission drawn in proportion to the intensity's
    /// luminance, and the power it carries (intensity over density); `None`
    /// for an image of no light.
    #[inline]
    pub fn sample_emission(&self, u: Vec2) -> Option<(Rgb, Vec3)> {
        let (uv, pdf_uv) = self.distribution.sample(u);
        if pdf_uv <= 0.0 || self.mean <= 0.0 {
            return None;
        }
        let dir = (self.to_world * environment::equal_area_square_to_sphere(uv)).try_normalize()?;
        // The map is equal-area: dω = 4π du dv.
        Some((self.intensity_toward(dir) * (4.0 * PI / pdf_uv), dir))
    }

    /// The density per steradian with which [`Goniometric::sample_emission`]
    /// draws unit direction `dir`.
    #[inline]
    pub fn pdf_emission(&self, dir: Vec3) -> f32 {
        let local = (self.to_local * dir).normalize_or_zero();
        if local == Vec3::ZERO || self.mean <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(environment::equal_area_sphere_to_square(local)) / (4.0 * PI)
    }

    /// The mean of the image's values.
    pub fn mean_value(&self) -> f32 {
        self.mean
    }

    /// The power, by luminance: 4π × the image's mean × the intensity.
    pub fn power(&self) -> f32 {
        4.0 * PI * self.mean * luminance(self.intensity)
    }
}

/// A projector light's frame and image (see [`Light::Projector`]).
#[derive(Clone, Debug)]
pub struct Projector {
    /// Position of the pinhole.
    pub position: Vec3,
    /// The light's frame to world (linear part of its `to_world`): light
    /// leaves along +z; +x and +y run toward the image's left and top.
    pub to_world: glam::Mat3,
    /// Its inverse.
    pub to_local: glam::Mat3,
    /// tan of half the field of view across and up the image.
    pub tan_half: Vec2,
    /// Multiplier of the image's value: π times the scene's `scale` for
    /// [`ProjectorLaw::PlaneIrradiance`], the scene's `scale` for
    /// [`ProjectorLaw::RadiantIntensity`].
    pub scale: f32,
    /// The image, read at the (u, v) that `Projector::uv` gives a
    /// direction (Mitsuba's: v = 0 at the image's top).
    pub image: Texture,
    /// What the image's value is.
    pub law: ProjectorLaw,
}

/// What the value E of a projector's image is, which decides its
/// intensity I toward a direction at angle θ from its axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ProjectorLaw {
    /// Irradiance over π on the plane at depth 1 (Mitsuba 3's
    /// `projector`): I = π·scale·E/cos³θ, so that a plane facing the light
    /// at depth z receives π·scale·E/z² everywhere in the frame.
    #[default]
    PlaneIrradiance,
    /// Radiant intensity (pbrt-v4's `projection`): I = scale·E, so that
    /// the plane's irradiance falls off as cos³θ/z² away from the axis.
    RadiantIntensity,
}

impl Projector {
    /// Where the point `local` (in the light's frame) falls in the image,
    /// as Mitsuba's perspective projection maps it: u = ½ − ½·x/(z·tan_x),
    /// v = ½ − ½·y/(z·tan_y); `None` behind the light or outside the frame.
    #[inline]
    fn uv(&self, local: Vec3) -> Option<Vec2> {
        if local.z <= 0.0 {
            return None;
        }
        let uv = Vec2::splat(0.5) - 0.5 * Vec2::new(local.x, local.y) / (local.z * self.tan_half);
        (uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0).then_some(uv)
    }

    /// Area of the image on the plane z = 1 of the light's frame.
    #[inline]
    pub fn image_area(&self) -> f32 {
        4.0 * self.tan_half.x * self.tan_half.y
    }

    /// The image's value at `uv`.
    #[inline]
    fn eval(&self, textures: &crate::texture::TextureStore, uv: Vec2) -> Rgb {
        self.image.eval(textures, &TexCoord::new(uv, Vec3::ZERO))
    }

    /// Intensity (W/sr) toward world point `p`, and the direction from the
    /// light to it; zero outside the frame: scale·E(u, v), over cos³θ (cos θ
    /// from the axis) for [`ProjectorLaw::PlaneIrradiance`].
    #[inline]
    pub fn intensity_toward(&self, textures: &crate::texture::TextureStore, p: Vec3) -> Option<(Rgb, Vec3)> {
        let local = self.to_local * (p - self.position);
        let uv = self.uv(local)?;
        let dir = (p - self.position).try_normalize()?;
        let factor = match self.law {
            ProjectorLaw::PlaneIrradiance => {
                let cos = local.z / local.length();
                self.scale / (cos * cos * cos)
            }
            ProjectorLaw::RadiantIntensity => self.scale,
        };
        Some((self.eval(textures, uv) * factor, dir))
    }

    /// The light's power per unit of `scale`, by luminance: the intensity's
    /// integral over the frame's solid angle, dω = cos³θ dA on the plane
    /// z = 1, summed over the image's pixels (pbrt-v4's `power`
    /// normalisation of its `projection` light sums the same way).
    pub fn power_per_scale(&self, textures: &crate::texture::TextureStore) -> f32 {
        let Texture::Image { image, .. } = self.image else {
            // A constant image (or one of no pixels to sum): its mean
            // over the plane, in closed form for the plane-irradiance law,
            // and by quadrature for the other.
            let e = luminance(self.image.average(textures));
            return match self.law {
                ProjectorLaw::PlaneIrradiance => e * self.image_area(),
                ProjectorLaw::RadiantIntensity => e * self.mean_cos3(64, 64) * self.image_area(),
            };
        };
        let img = &textures.images[image as usize];
        let (w, h) = (img.width.max(1), img.height.max(1));
        let mut sum = 0.0f64;
        for y in 0..h {
            for x in 0..w {
                let uv = Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
                let cos3 = match self.law {
                    ProjectorLaw::PlaneIrradiance => 1.0,
                    ProjectorLaw::RadiantIntensity => self.cos3_at(uv),
                };
                sum += (luminance(self.eval(textures, uv)) * cos3) as f64;
            }
        }
        (sum / (w * h) as f64) as f32 * self.image_area()
    }

    /// cos³θ of the direction through point `uv` of the frame.
    fn cos3_at(&self, uv: Vec2) -> f32 {
        let q = (Vec2::ONE - 2.0 * uv) * self.tan_half;
        (1.0 + q.length_squared()).powf(-1.5)
    }

    /// The mean of cos³θ over the frame, at the centres of a grid.
    fn mean_cos3(&self, nx: u32, ny: u32) -> f32 {
        let mut sum = 0.0;
        for y in 0..ny {
            for x in 0..nx {
                sum += self.cos3_at(Vec2::new((x as f32 + 0.5) / nx as f32, (y as f32 + 0.5) / ny as f32));
            }
        }
        sum / (nx * ny) as f32
    }

    /// The density per unit solid angle with which
    /// [`Projector::sample_emission`] draws the unit direction `dir`.
    #[inline]
    pub fn pdf_emission(&self, dir: Vec3) -> f32 {
        let local = self.to_local * dir;
        if self.uv(local).is_none() || local.z <= 0.0 {
            return 0.0;
        }
        let cos = local.z / local.length();
        1.0 / (self.image_area() * cos * cos * cos)
    }

    /// A direction of emission drawn uniformly over the image's area on
    /// the plane z = 1, and the power that carries: the intensity over the
    /// direction's density 1/(area·cos³θ), i.e. scale·E·area, times cos³θ
    /// for [`ProjectorLaw::RadiantIntensity`].
    #[inline]
    pub fn sample_emission(&self, textures: &crate::texture::TextureStore, u: Vec2) -> Option<(Rgb, Vec3)> {
        let local = Vec3::new(
            (1.0 - 2.0 * u.x) * self.tan_half.x,
            (1.0 - 2.0 * u.y) * self.tan_half.y,
            1.0,
        );
        let dir = (self.to_world * local).try_normalize()?;
        let cos3 = match self.law {
            ProjectorLaw::PlaneIrradiance => 1.0,
            ProjectorLaw::RadiantIntensity => self.cos3_at(u),
        };
        Some((self.eval(textures, u) * (self.scale * self.image_area() * cos3), dir))
    }
}

/// The cosine between an emitter's front normal `n` and the unit
/// direction `w` light leaves in, where the emitter emits that way: from
/// the front only, or with `two_sided` from either side (the absolute
/// cosine); zero or less where it does not.
#[inline(always)]
pub fn emitting_cosine(n: Vec3, w: Vec3, two_sided: bool) -> f32 {
    emitting_cosine_lanes(Vec3s::<f32>::splat(n), Vec3s::splat(w), two_sided)
}

/// [`emitting_cosine`] over lanes (`two_sided`: the lanes whose emitter's
/// back emits too).
#[inline(always)]
fn emitting_cosine_lanes<F: Floats>(n: Vec3s<F>, w: Vec3s<F>, two_sided: F::Mask) -> F {
    let cos = n.dot(w);
    F::select(two_sided, cos.abs(), cos)
}

/// GLSL's smoothstep: 0 below `a`, 1 above `b`, a cubic ramp between.
#[inline]
fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    if a == b {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Samples the cone of directions that a sphere subtends from `p`
/// (pbrt-v4 §6.2.4, with its small-angle care). Returns the point on the
/// sphere, its normal and the density per steradian; `None` if `p` is inside.
#[inline]
fn sample_sphere_cone(center: Vec3, radius: f32, p: Vec3, u: Vec2) -> Option<(Vec3, Vec3, f32)> {
    let (lp, n, pdf, outside) =
        sample_sphere_cone_lanes(Vec3s::<f32>::splat(center), radius, Vec3s::splat(p), u.x, u.y);
    outside.then(|| (lp.lane(0), n.lane(0), pdf))
}

/// [`sample_sphere_cone`] over lanes: the point, its normal, the density
/// and the lanes where `p` is outside the sphere (elsewhere the rest is
/// meaningless).
#[inline(always)]
pub(crate) fn sample_sphere_cone_lanes<F: Floats>(
    center: Vec3s<F>,
    radius: F,
    p: Vec3s<F>,
    ux: F,
    uy: F,
) -> (Vec3s<F>, Vec3s<F>, F, F::Mask) {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let to_center = center - p;
    let dc2 = to_center.dot(to_center);
    let r2 = radius * radius;
    let outside = dc2.gt(r2);
    // This runs at every vertex of every path in a scene lit by a sphere,
    // so its square roots and divisions run side by side where they can
    // rather than one after another.
    let dc = dc2.sqrt();
    let (inv_dc, inv_sin_max) = (one / dc, dc / radius);
    let sin_max = radius * inv_dc;
    let sin2_max = sin_max * sin_max;
    // cos θmax = √(dc² − r²)/dc: its root beside dc's.
    let cos_max = (dc2 - r2).max(zero).sqrt() * inv_dc;
    // A tiny cone is computed through sin², which keeps the precision.
    let tiny = F::splat(0.000_685_23).gt(sin2_max);
    let one_minus_cos_max = F::select(tiny, sin2_max / F::splat(2.0), one - cos_max);
    let cos_t_wide = (cos_max - one) * ux + one;
    let sin2_t = F::select(tiny, sin2_max * ux, one - cos_t_wide * cos_t_wide);
    let cos_t = F::select(tiny, (one - sin2_t).max(zero).sqrt(), cos_t_wide);
    // The angle α at the centre between p and the sampled point, from the
    // triangle of the two and the centre (law of sines): with
    // k = dc/r and s = √(1 − k² sin² θ), cos α = k sin² θ + s cos θ (as
    // pbrt-v4) and sin α = sin θ (k cos θ − s), whose roots are
    // independent (sin α as √(1 − cos² α) would wait for cos α, and loses
    // the small angles).
    let s = (one - sin2_t * inv_sin_max * inv_sin_max).max(zero).sqrt();
    let sin_t = sin2_t.max(zero).sqrt();
    let cos_a = sin2_t * inv_sin_max + cos_t * s;
    let sin_a = (sin_t * (cos_t * inv_sin_max - s)).max(zero);
    let (sin_phi, cos_phi) = sin_cos_turn(uy);
    let axis = to_center.scale(inv_dc);
    let (bs, bt) = orthonormal_basis_lanes(axis);
    // The normal points back toward p's side: −(sin α cos φ, sin α sin φ, cos α).
    let n = (bs.scale(sin_a * cos_phi) + bt.scale(sin_a * sin_phi) + axis.scale(cos_a)).scale(F::splat(-1.0));
    let pdf = one / (F::splat(2.0 * PI) * one_minus_cos_max);
    (center + n.scale(radius), n, pdf, outside)
}

/// The (u, v) of a point on an untransformed sphere with outward normal
/// `n` (the parameterisation of [`crate::geometry::Shape::surface`]).
fn sphere_uv(n: Vec3) -> Vec2 {
    let phi = n.z.atan2(n.x).rem_euclid(2.0 * PI);
    Vec2::new(phi / (2.0 * PI), 0.5 + n.y.clamp(-1.0, 1.0).asin() / PI)
}

/// The light from point `lp` (unit normal `ln`, coordinates `uv`) of an
/// area light with emitted `radiance` arriving at `p`, for a point chosen
/// with density `pdf_solid_angle` per steradian, or else `pdf_area` per
/// unit area.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn area_light_sample(
    scene: &Scene,
    p: Vec3,
    lp: Vec3,
    ln: Vec3,
    two_sided: bool,
    (uv, attribute): (Vec2, Vec3),
    pdf_solid_angle: Option<f32>,
    pdf_area: f32,
    radiance: &Texture,
) -> Option<LightSample> {
    let (wi, dist2, cos_light) = toward_light(Vec3s::<f32>::splat(p), Vec3s::splat(lp), Vec3s::splat(ln), two_sided);
    if dist2 == 0.0 || cos_light <= 0.0 {
        return None;
    }
    let wi = wi.lane(0);
    // Area density to solid-angle density: p_ω = p_A · d² / cos θ_l.
    let pdf = match pdf_solid_angle {
        Some(pdf) => pdf,
        None => pdf_area * dist2 / cos_light,
    };
    if !pdf.is_finite() || pdf <= 0.0 {
        return None;
    }
    Some(LightSample {
        wi,
        li: radiance.eval(&scene.textures, &TexCoord::new(uv, lp).with_attribute(attribute)),
        pdf,
        is_delta: false,
        target: ShadowTarget::Point(lp),
    })
}

/// From `p` toward the point `lp` of an emitter whose unit normal there is
/// `ln`, over lanes: the unit direction, the squared distance and the
/// cosine at the emitter ([`emitting_cosine`]; `two_sided`: the lanes whose
/// emitter's back emits too).
#[inline(always)]
fn toward_light<F: Floats>(p: Vec3s<F>, lp: Vec3s<F>, ln: Vec3s<F>, two_sided: F::Mask) -> (Vec3s<F>, F, F) {
    let d = lp - p;
    let dist2 = d.dot(d);
    let wi = d.over(dist2.sqrt());
    (
        wi,
        dist2,
        emitting_cosine_lanes(ln, wi.scale(F::splat(-1.0)), two_sided),
    )
}

/// A sphere light of constant radiance sampled by the cone it subtends
/// ([`sample_sphere_cone`] and [`area_light_sample`] over lanes), for the
/// path tracer's diffuse bounces in lanes: from `p`, the lanes of the
/// spheres (`center`, `radius`, `two_sided`: the lanes whose back emits)
/// drawing `ux`, `uy`, the direction, the point, the density per
/// steradian, the lanes where the sample is valid and those where `p` is
/// outside the sphere (inside, the light is sampled by area instead).
#[inline(always)]
pub(crate) fn sample_sphere_light_lanes<F: Floats>(
    center: Vec3s<F>,
    radius: F,
    two_sided: F::Mask,
    p: Vec3s<F>,
    ux: F,
    uy: F,
) -> (Vec3s<F>, Vec3s<F>, F, u32, u32) {
    let zero = F::splat(0.0);
    let (lp, ln, pdf, outside) = sample_sphere_cone_lanes(center, radius, p, ux, uy);
    let (wi, dist2, cos_light) = toward_light(p, lp, ln, two_sided);
    let bits = |m: F::Mask| F::mask_bits(m);
    let valid = bits(outside)
        & bits(dist2.gt(zero))
        & bits(cos_light.gt(zero))
        & bits(pdf.gt(zero))
        & bits(F::splat(f32::INFINITY).gt(pdf));
    (wi, lp, pdf, valid, bits(outside))
}

/// Parallelograms in lanes (see [`Parallelogram`]).
#[derive(Clone, Copy)]
pub(crate) struct ParallelogramLanes<F> {
    pub(crate) corner: Vec3s<F>,
    pub(crate) edge_u: Vec3s<F>,
    pub(crate) edge_v: Vec3s<F>,
    pub(crate) normal: Vec3s<F>,
    pub(crate) pdf_area: F,
}

impl<F: Floats> ParallelogramLanes<F> {
    /// `r` in every lane.
    #[inline(always)]
    pub(crate) fn of(r: &Parallelogram) -> Self {
        ParallelogramLanes {
            corner: Vec3s::splat(r.corner),
            edge_u: Vec3s::splat(r.edge_u),
            edge_v: Vec3s::splat(r.edge_v),
            normal: Vec3s::splat(r.normal),
            pdf_area: F::splat(r.pdf_area),
        }
    }

    /// Lanes from plain parallelograms.
    #[inline(always)]
    pub(crate) fn gather(r: &F::Each<Parallelogram>) -> Self {
        let r = r.as_ref();
        let v = |f: fn(&Parallelogram) -> Vec3| Vec3s::<F>::gather(&F::each(|i| f(&r[i])));
        ParallelogramLanes {
            corner: v(|r| r.corner),
            edge_u: v(|r| r.edge_u),
            edge_v: v(|r| r.edge_v),
            normal: v(|r| r.normal),
            pdf_area: F::gather(&F::each(|i| r[i].pdf_area)),
        }
    }
}

/// A parallelogram light sampled by area, uniformly (the sample of
/// [`Light::sample_li`], over lanes): from `p`, the parallelograms `r`
/// (`two_sided`: the lanes whose back emits) drawing `ux`, `uy`, the
/// direction, the point, the density per steradian and the lanes where the
/// sample is valid (the point is not `p` itself, `p` is on the emitting
/// side, the density is positive and finite).
#[inline(always)]
pub(crate) fn sample_parallelogram_light_lanes<F: Floats>(
    r: ParallelogramLanes<F>,
    two_sided: F::Mask,
    p: Vec3s<F>,
    ux: F,
    uy: F,
) -> (Vec3s<F>, Vec3s<F>, F, u32) {
    let zero = F::splat(0.0);
    let lp = r.corner + r.edge_u.scale(ux) + r.edge_v.scale(uy);
    let (wi, dist2, cos_light) = toward_light(p, lp, r.normal, two_sided);
    // Area density to solid-angle density: p_ω = p_A · d² / cos θ_l.
    let pdf = r.pdf_area * dist2 / cos_light;
    let bits = |m: F::Mask| F::mask_bits(m);
    let valid =
        bits(dist2.gt(zero)) & bits(cos_light.gt(zero)) & bits(pdf.gt(zero)) & bits(F::splat(f32::INFINITY).gt(pdf));
    (wi, lp, pdf, valid)
}

/// 1 − cos θ_max of the cone whose half-angle has sin²θ_max = `sin2_max`,
/// through sin² for a tiny cone, where 1 − cos would round away.
fn one_minus_cos_max(sin2_max: f32) -> f32 {
    if sin2_max < 0.000_685_23 {
        sin2_max / 2.0
    } else {
        1.0 - (1.0 - sin2_max).max(0.0).sqrt()
    }
}

/// Density per steradian of [`sample_sphere_cone`] (0 if `p` is inside).
fn sphere_cone_pdf(center: Vec3, radius: f32, p: Vec3) -> f32 {
    let dc2 = (center - p).length_squared();
    if dc2 <= radius * radius {
        return 0.0;
    }
    1.0 / (2.0 * PI * one_minus_cos_max(radius * radius / dc2))
}

/// A direction from `p` drawn uniformly in the cone that the sphere of
/// `center` and `radius` subtends, or over the whole sphere of directions
/// from inside it, and its density per steradian
/// ([`toward_sphere_pdf`]).
fn sample_toward_sphere(center: Vec3, radius: f32, p: Vec3, u: Vec2) -> (Vec3, f32) {
    let to_center = center - p;
    let dc2 = to_center.length_squared();
    if dc2 <= radius * radius {
        return (sample_sphere_uniform(u), pdf_sphere_uniform());
    }
    let omc = one_minus_cos_max(radius * radius / dc2);
    let z = 1.0 - u.x * omc;
    // sin² θ = (1 − z)(1 + z), exact for the tiny cones.
    let sin_t = ((u.x * omc) * (1.0 + z)).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    let frame = Frame::from_normal(to_center / dc2.sqrt());
    (
        frame.to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), z)),
        1.0 / (2.0 * PI * omc),
    )
}

/// Density per steradian of [`sample_toward_sphere`].
fn toward_sphere_pdf(center: Vec3, radius: f32, p: Vec3) -> f32 {
    let pdf = sphere_cone_pdf(center, radius, p);
    if pdf > 0.0 { pdf } else { pdf_sphere_uniform() }
}

/// Where a ray drawn toward a bounding sphere of radius `radius` starts,
/// in units of that radius: past the shading point itself, which may lie
/// on the emitter.
const TOWARD_SPHERE_START: f32 = 1e-4;

impl Light {
    /// Samples light arriving at point `p`; `u_pick` and `u` are uniform
    /// numbers (the first picks a triangle of a mesh emitter). Returns
    /// `None` when no light can arrive (behind a spot, on the back of an
    /// emitter, or at the emitter itself). `incomplete` (pbrt-v4's
    /// `allowIncompletePDF`) lets the environment draw from a density that
    /// leaves out part of its light, which only estimators that also
    /// sample the BSDF and weigh the two by MIS may ask for (see
    /// [`Background::sample_radiance_from`]).
    #[inline(always)]
    pub fn sample_li(&self, scene: &Scene, p: Vec3, u_pick: f32, u: Vec2, incomplete: bool) -> Option<LightSample> {
        // A rectangle light, a room's usual light, is sampled in the
        // caller's code; the other kinds behind a call. (Inlining the
        // whole match into the path loop was measured slower.)
        // `inline(always)`: with a plain `inline`, LLVM's choice flipped
        // with unrelated changes elsewhere, putting the call back.
        if let Light::Area {
            radiance,
            parallelogram: Some(r),
            two_sided,
            ..
        } = self
        {
            let (wi, lp, pdf, valid) = sample_parallelogram_light_lanes(
                ParallelogramLanes::<f32>::of(r),
                *two_sided,
                Vec3s::splat(p),
                u.x,
                u.y,
            );
            let lp = lp.lane(0);
            return (valid != 0).then(|| LightSample {
                wi: wi.lane(0),
                li: radiance.eval(&scene.textures, &TexCoord::new(u, lp)),
                pdf,
                is_delta: false,
                target: ShadowTarget::Point(lp),
            });
        }
        self.sample_li_other(scene, p, u_pick, u, incomplete)
    }

    /// [`Light::sample_li`] with its numbers drawn from `sampler`: first
    /// `u_pick` (passed over where this light does not read it), then
    /// `u`.
    #[inline(always)]
    pub fn sample_li_drawing(
        &self,
        scene: &Scene,
        p: Vec3,
        sampler: &mut Sampler,
        incomplete: bool,
    ) -> Option<LightSample> {
        let u_pick = if self.reads_pick() {
            sampler.next_1d()
        } else {
            sampler.skip_1d();
            0.0
        };
        let u = sampler.next_2d();
        self.sample_li(scene, p, u_pick, u, incomplete)
    }

    /// Whether [`Light::sample_li`] reads its `u_pick`: only an area
    /// light that is not a parallelogram can sample its emitter's parts
    /// (a mesh's triangles; a sphere when the point is inside it).
    #[inline]
    pub fn reads_pick(&self) -> bool {
        matches!(
            self,
            Light::Area {
                parallelogram: None,
                ..
            }
        )
    }

    /// [`Light::sample_li`] for every light but a rectangle.
    #[inline(never)]
    fn sample_li_other(&self, scene: &Scene, p: Vec3, u_pick: f32, u: Vec2, incomplete: bool) -> Option<LightSample> {
        match self {
            Light::Point {
                position,
                intensity,
                falloff,
            } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                if dist2 == 0.0 {
                    return None;
                }
                let scale = if *falloff { 1.0 / dist2 } else { 1.0 };
                Some(LightSample {
                    wi: d / dist2.sqrt(),
                    li: *intensity * scale,
                    pdf: 1.0,
                    is_delta: true,
                    target: ShadowTarget::Point(*position),
                })
            }
            Light::Spot {
                position,
                direction,
                intensity,
                cos_inner,
                cos_outer,
                profile,
                projection,
                falloff,
            } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                if dist2 == 0.0 {
                    return None;
                }
                let wi = d / dist2.sqrt();
                let cone = profile.eval(*cos_inner, *cos_outer, direction.dot(-wi));
                if cone <= 0.0 {
                    return None;
                }
                let scale = if *falloff { 1.0 / dist2 } else { 1.0 };
                let intensity = match projection {
                    Some(image) => *intensity * image.eval(&scene.textures, -wi),
                    None => *intensity,
                };
                Some(LightSample {
                    wi,
                    li: intensity * (cone * scale),
                    pdf: 1.0,
                    is_delta: true,
                    target: ShadowTarget::Point(*position),
                })
            }
            Light::Projector(proj) => {
                let (intensity, dir) = proj.intensity_toward(&scene.textures, p)?;
                let dist2 = (proj.position - p).length_squared();
                Some(LightSample {
                    wi: -dir,
                    li: intensity / dist2,
                    pdf: 1.0,
                    is_delta: true,
                    target: ShadowTarget::Point(proj.position),
                })
            }
            Light::Goniometric(g) => {
                let d = g.position - p;
                let dist2 = d.length_squared();
                if dist2 == 0.0 {
                    return None;
                }
                let wi = d / dist2.sqrt();
                let li = g.intensity_toward(-wi) / dist2;
                if li == Rgb::ZERO {
                    return None;
                }
                Some(LightSample {
                    wi,
                    li,
                    pdf: 1.0,
                    is_delta: true,
                    target: ShadowTarget::Point(g.position),
                })
            }
            Light::Directional { direction, irradiance } => Some(LightSample {
                wi: -*direction,
                li: *irradiance,
                pdf: 1.0,
                is_delta: true,
                target: ShadowTarget::Infinity,
            }),
            Light::Area {
                emitter,
                radiance,
                two_sided,
                cone: Some((center, radius)),
                ..
            } => {
                let EmitterRef::Shape(i) = *emitter else {
                    return None;
                };
                let (wi, pdf) = sample_toward_sphere(*center, *radius, p, u);
                let start = TOWARD_SPHERE_START * radius;
                let mut ray = crate::geometry::Ray::with_interval(p, wi, start, f32::MAX);
                let mut hit = scene.geometry.shape_hit(i, &ray, radiance.reads_uv())?;
                // A crossing at the first step lies on the surface the
                // point is on (a path bouncing off the emitter): the point
                // a ray leaving that surface meets is the next one.
                for _ in 0..2 {
                    if (hit.p - p).length() > 2.0 * start {
                        break;
                    }
                    ray = hit.spawn_ray(wi);
                    hit = scene.geometry.shape_hit(i, &ray, radiance.reads_uv())?;
                }
                area_light_sample(
                    scene,
                    p,
                    hit.p,
                    hit.ng,
                    *two_sided,
                    (hit.uv, hit.attribute),
                    Some(pdf),
                    0.0,
                    radiance,
                )
            }
            Light::Area {
                emitter,
                radiance,
                two_sided,
                area,
                sphere,
                parallelogram,
                cone: None,
            } => {
                // The point's density: per steradian from cone sampling of
                // a sphere, per unit area otherwise.
                let (lp, ln, uv, pdf_solid_angle, pdf_area) = if let Some(r) = parallelogram {
                    // What `Shape::sample_area` does for a rectangle.
                    (
                        r.corner + u.x * r.edge_u + u.y * r.edge_v,
                        r.normal,
                        (u, Vec3::ZERO),
                        None,
                        r.pdf_area,
                    )
                } else {
                    match sphere.and_then(|(c, r)| sample_sphere_cone(c, r, p, u)) {
                        Some((lp, ln, pdf)) => {
                            let uv = if radiance.reads_uv() { sphere_uv(ln) } else { Vec2::ZERO };
                            (lp, ln, (uv, Vec3::ZERO), Some(pdf), 0.0)
                        }
                        None => {
                            let s = scene
                                .geometry
                                .sample_emitter(*emitter, area, u_pick, u, radiance.reads_uv())?;
                            if s.pdf_area.is_nan() || s.pdf_area <= 0.0 {
                                return None;
                            }
                            (s.p, s.n, (s.uv, s.attribute), None, s.pdf_area)
                        }
                    }
                };
                area_light_sample(scene, p, lp, ln, *two_sided, uv, pdf_solid_angle, pdf_area, radiance)
            }
            Light::Environment => {
                let (wi, pdf, li) = scene.background.sample_radiance_from(p, u, incomplete)?;
                if pdf <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    li,
                    pdf,
                    is_delta: false,
                    target: ShadowTarget::Infinity,
                })
            }
        }
    }

    /// The centre, radius, sidedness and radiance of a sphere light of
    /// constant radiance, which [`Light::sample_li`] samples by the cone it
    /// subtends: what [`sample_sphere_light_lanes`] needs.
    pub(crate) fn constant_sphere(&self) -> Option<(Vec3, f32, bool, Rgb)> {
        match self {
            Light::Area {
                radiance: Texture::Constant(radiance),
                two_sided,
                sphere: Some((center, radius)),
                parallelogram: None,
                cone: None,
                ..
            } => Some((*center, *radius, *two_sided, *radiance)),
            _ => None,
        }
    }

    /// The parallelogram, sidedness and radiance of a parallelogram light
    /// of constant radiance, which [`Light::sample_li`] samples by area:
    /// what [`sample_parallelogram_light_lanes`] needs.
    pub(crate) fn constant_parallelogram(&self) -> Option<(Parallelogram, bool, Rgb)> {
        match self {
            Light::Area {
                radiance: Texture::Constant(radiance),
                two_sided,
                parallelogram: Some(r),
                ..
            } => Some((*r, *two_sided, *radiance)),
            _ => None,
        }
    }

    /// Whether [`Light::sample_li`] with `incomplete` can draw anything: not
    /// for a constant environment, whose compensated density (its radiance
    /// less its mean) is zero everywhere, so that BSDF sampling alone finds
    /// its light, as pbrt-v4's `UniformInfiniteLight` does.
    pub fn samples_when_incomplete(&self, scene: &Scene) -> bool {
        match self {
            Light::Environment => scene.background.samples_when_incomplete(),
            _ => true,
        }
    }

    /// The density per steradian with which [`Light::sample_li`] at `p`
    /// would pick the direction toward `hit`, a point on this (area) light.
    pub fn pdf_li(&self, scene: &Scene, p: Vec3, hit: &SurfaceHit) -> f32 {
        match self {
            Light::Area { cone: Some((c, r)), .. } => toward_sphere_pdf(*c, *r, p),
            Light::Area {
                emitter,
                area,
                sphere,
                two_sided,
                ..
            } => {
                if let Some((c, r)) = sphere {
                    let pdf = sphere_cone_pdf(*c, *r, p);
                    if pdf > 0.0 {
                        return pdf;
                    }
                }
                let d = hit.p - p;
                let cos_light = emitting_cosine(hit.ng, -d.normalize_or_zero(), *two_sided);
                if cos_light <= 0.0 {
                    return 0.0;
                }
                scene.geometry.emitter_pdf_area(*emitter, area, hit.p, hit.ng) * d.length_squared() / cos_light
            }
            _ => 0.0,
        }
    }

    /// The density per steradian with which the environment light samples
    /// direction `dir` from `p` (by [`Light::sample_li`] with the same
    /// `incomplete`).
    pub fn pdf_environment(&self, scene: &Scene, p: Vec3, dir: Vec3, incomplete: bool) -> f32 {
        match self {
            Light::Environment => scene.background.eval_pdf_from(p, dir, incomplete).1,
            _ => 0.0,
        }
    }

    /// Whether the light is a delta distribution.
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Light::Point { .. }
                | Light::Spot { .. }
                | Light::Projector(_)
                | Light::Goniometric(_)
                | Light::Directional { .. }
        )
    }

    /// Emitted power (luminance), for choosing lights in proportion to it;
    /// `scene_radius` bounds the scene, for lights at infinity.
    pub fn power(&self, scene: &Scene, scene_radius: f32) -> f32 {
        let disk = PI * scene_radius * scene_radius;
        match self {
            Light::Point { intensity, .. } => 4.0 * PI * luminance(*intensity),
            Light::Spot {
                intensity,
                cos_inner,
                cos_outer,
                ..
            } => 2.0 * PI * luminance(*intensity) * (1.0 - 0.5 * (cos_inner + cos_outer)),
            Light::Projector(p) => match p.law {
                ProjectorLaw::PlaneIrradiance => p.scale * p.image_area() * luminance(p.image.average(&scene.textures)),
                ProjectorLaw::RadiantIntensity => p.scale * p.power_per_scale(&scene.textures),
            },
            Light::Goniometric(g) => g.power(),
            Light::Directional { irradiance, .. } => disk * luminance(*irradiance),
            Light::Area {
                emitter,
                radiance,
                area,
                two_sided,
                cone,
                ..
            } => {
                // World-space area: exact for meshes, estimated in world
                // space for emitters sampled by direction, scaled by the
                // transform's average area factor for other shapes.
                let world_area = match emitter {
                    _ if cone.is_some() => area.total,
                    EmitterRef::Shape(i) => match &scene.geometry.shapes[*i as usize].transform {
                        Some(t) => {
                            let det = glam::Mat3::from_mat4(t.m).determinant().abs();
                            area.total * det.powf(2.0 / 3.0)
                        }
                        None => area.total,
                    },
                    _ => area.total,
                };
                let sides = if *two_sided { 2.0 } else { 1.0 };
                // A radiance per triangle or vertex (a mesh attribute) is
                // known from the mesh: its mean over the area, each
                // triangle's the value at its centroid (exact for values
                // interpolated linearly).
                let g = &scene.geometry;
                let mesh = match *emitter {
                    EmitterRef::MeshObject(o) => Some(&g.meshes[g.mesh_objects[o as usize].mesh as usize]),
                    EmitterRef::Instance(i) => Some(&g.meshes[g.instances[i as usize].mesh as usize]),
                    EmitterRef::Shape(_) => None,
                };
                let mean_radiance = match (radiance, mesh) {
                    (Texture::MeshAttribute(_), Some(m)) => {
                        let (mut sum, mut total) = (Rgb::ZERO, 0.0f32);
                        for i in 0..m.indices.len() {
                            let a = m.triangle_area(i);
                            sum += a * m.attribute(i, [1.0 / 3.0; 3]);
                            total += a;
                        }
                        if total > 0.0 { sum / total } else { Rgb::ZERO }
                    }
                    _ => radiance.average(&scene.textures),
                };
                sides * PI * world_area * luminance(mean_radiance)
            }
            Light::Environment => disk * luminance(scene.background.average()) * 4.0,
        }
    }
}

impl Light {
    /// Where the light's points lie, its power and the cone it emits into,
    /// for the light tree ([`LightSampler`]); `None` for lights without
    /// bounds (directional, environment, an emissive infinite plane).
    /// `power` is [`Light::power`].
    pub fn bounds(&self, scene: &Scene, power: f32) -> Option<LightBounds> {
        match self {
            Light::Point { position, .. } => Some(LightBounds::point(*position, power)),
            // Bounded as an isotropic point light, as pbrt-v4 bounds it.
            Light::Goniometric(g) => Some(LightBounds::point(g.position, power)),
            Light::Spot {
                position,
                direction,
                cos_inner,
                cos_outer,
                ..
            } => {
                // Full intensity inside θ_inner; none beyond θ_outer.
                let spread = (cos_outer.clamp(-1.0, 1.0).acos() - cos_inner.clamp(-1.0, 1.0).acos()).max(0.0);
                Some(LightBounds {
                    w: *direction,
                    cos_theta_o: *cos_inner,
                    cos_theta_e: spread.cos(),
                    ..LightBounds::point(*position, power)
                })
            }
            Light::Area { emitter, two_sided, .. } => {
                let g = &scene.geometry;
                let bounds = match *emitter {
                    EmitterRef::Shape(i) => {
                        let s = &g.shapes[i as usize];
                        let b = s.shape.bounds()?;
                        s.transform.as_ref().map_or(b, |t| t.aabb(&b))
                    }
                    EmitterRef::MeshObject(o) => g.meshes[g.mesh_objects[o as usize].mesh as usize].bounds(),
                    EmitterRef::Instance(i) => {
                        let inst = &g.instances[i as usize];
                        inst.transform.aabb(&g.meshes[inst.mesh as usize].bounds())
                    }
                };
                // A rectangle emits into the half-space its front faces;
                // other emitters are bounded by the whole sphere of normals.
                let (w, cos_theta_o) = match g.emitter_parallelogram(*emitter) {
                    Some((_, n)) => (n, 1.0),
                    None => (Vec3::Z, -1.0),
                };
                Some(LightBounds {
                    bounds,
                    phi: power,
                    w,
                    cos_theta_o,
                    cos_theta_e: 0.0,
                    two_sided: *two_sided,
                })
            }
            Light::Projector(proj) => {
                // Every direction of the frame lies within the half-diagonal
                // of the axis; the spread beyond it is a generous bound
                // (an importance must not vanish where light arrives).
                let axis = proj.to_world * Vec3::Z;
                let half_diagonal = 1.0 / (1.0 + proj.tan_half.length_squared()).sqrt();
                Some(LightBounds {
                    w: axis.try_normalize()?,
                    cos_theta_o: half_diagonal,
                    cos_theta_e: 0.0,
                    ..LightBounds::point(proj.position, power)
                })
            }
            Light::Directional { .. } | Light::Environment => None,
        }
    }
}

/// Whether a light's emitter is an untransformed sphere (or one whose
/// transform keeps it a sphere), and if so its world centre and radius.
pub fn emitter_sphere(scene_geometry: &crate::accel::Aggregate, emitter: EmitterRef) -> Option<(Vec3, f32)> {
    let EmitterRef::Shape(i) = emitter else {
        return None;
    };
    let s = &scene_geometry.shapes[i as usize];
    match (&s.shape, &s.transform) {
        (Shape::Sphere(sp), None) => Some((sp.center, sp.radius)),
        _ => None,
    }
}

/// The world-space bounding sphere of an emitter that has no density over
/// its area (a distance function, a grid of distances or an implicit
/// surface), which lights then sample by direction
/// ([`Light::Area`]'s `cone`); `None` for other emitters, and for a moving
/// one (light samples are drawn at time 0).
pub fn implicit_emitter_sphere(scene_geometry: &crate::accel::Aggregate, emitter: EmitterRef) -> Option<(Vec3, f32)> {
    let EmitterRef::Shape(i) = emitter else {
        return None;
    };
    let s = &scene_geometry.shapes[i as usize];
    if !matches!(s.shape, Shape::Sdf(_) | Shape::SdfGrid(_) | Shape::Implicit(_)) || s.motion.is_some() {
        return None;
    }
    let b = s.shape.bounds()?;
    let b = s.transform.as_ref().map_or(b, |t| t.aabb(&b));
    let radius = 0.5 * b.extent().length();
    (radius.is_finite() && radius > 0.0).then(|| (b.centroid(), radius))
}

/// Most crossings of one line with an emitter that [`line_crossings`]
/// finds; those beyond are left out.
pub const MAX_LINE_CROSSINGS: usize = 32;

/// The measure of the oriented lines that meet a sphere of radius
/// `radius`: 4π directions times the πr² of its shadow.
pub fn line_measure(radius: f32) -> f32 {
    4.0 * PI * PI * radius * radius
}

/// The oriented line drawn uniformly among those meeting the sphere of
/// `center` and `radius` (a direction uniform over the sphere from `u_dir`,
/// a point uniform over the disk of the sphere's shadow from `u_pos`):
/// where it enters the sphere's bounding cube of side 3r and its direction.
fn uniform_line(center: Vec3, radius: f32, u_pos: Vec2, u_dir: Vec2) -> (Vec3, Vec3) {
    let w = sample_sphere_uniform(u_dir);
    let q = crate::sampling::warp::sample_disk_concentric(u_pos) * radius;
    let through = center + Frame::from_normal(w).to_world(Vec3::new(q.x, q.y, 0.0));
    (through - 1.5 * radius * w, w)
}

/// Where the segment from `start` along unit `w` over 3·`radius` (a line
/// through an emitter's bounding sphere, from [`uniform_line`]) crosses
/// shape `i`, in order (at most [`MAX_LINE_CROSSINGS`]), with the surface
/// there (coordinates if `uv`). Each search after the first starts from
/// the last crossing as a path's ray leaves a surface.
pub fn line_crossings(
    scene_geometry: &crate::accel::Aggregate,
    i: u32,
    (start, w): (Vec3, Vec3),
    radius: f32,
    uv: bool,
) -> arrayvec::ArrayVec<SurfaceHit, MAX_LINE_CROSSINGS> {
    let end = start + 3.0 * radius * w;
    let mut hits = arrayvec::ArrayVec::new();
    let mut ray = crate::geometry::Ray::with_interval(start, w, 0.0, 3.0 * radius);
    while !hits.is_full() {
        let Some(hit) = scene_geometry.shape_hit(i, &ray, uv) else {
            break;
        };
        let next = hit.spawn_ray(w);
        let remaining = (end - next.origin).dot(w);
        hits.push(hit);
        if remaining <= 0.0 {
            break;
        }
        ray = crate::geometry::Ray::with_interval(next.origin, w, 0.0, remaining);
    }
    hits
}

/// A point of emitter shape `i` drawn through its bounding sphere
/// (`center`, `radius`): one of the k crossings, chosen by `u_pick`, of a
/// line drawn uniformly among those meeting the sphere ([`uniform_line`]
/// from `u_pos` and `u_dir`). Returns the crossing, its density per unit
/// area 2π/(M·k) for lines of measure M ([`line_measure`]), and the
/// line's unit direction. That density is the line's, not the point's
/// (no function of the point gives it), but dividing by it is unbiased:
/// by Crofton's formula E[k·g(x, ω)] = (1/M)·∫∫ g |cos θ| dω dA, so the
/// point is drawn uniformly by area on average and the direction as
/// |cos θ| about its normal.
pub(crate) fn sample_on_lines(
    scene_geometry: &crate::accel::Aggregate,
    i: u32,
    (center, radius): (Vec3, f32),
    u_pick: f32,
    (u_pos, u_dir): (Vec2, Vec2),
    uv: bool,
) -> Option<(SurfaceHit, f32, Vec3)> {
    let line = uniform_line(center, radius, u_pos, u_dir);
    let mut hits = line_crossings(scene_geometry, i, line, radius, uv);
    let k = hits.len();
    let pick = ((u_pick * k as f32) as usize).min(k.checked_sub(1)?);
    let pdf_area = 2.0 * PI / (line_measure(radius) * k as f32);
    Some((hits.swap_remove(pick), pdf_area, line.1))
}

/// An estimate of the area of emitter `emitter` (shape `i`) inside its
/// bounding `sphere`, for choosing lights by power: by Crofton's formula,
/// an oriented line drawn uniformly among those meeting a sphere (of
/// measure M, [`line_measure`]) crosses a surface of area A inside it
/// 2πA/M times on average. Deterministic (a fixed seed).
pub fn crofton_area(
    scene_geometry: &crate::accel::Aggregate,
    emitter: EmitterRef,
    (center, radius): (Vec3, f32),
) -> f32 {
    const LINES: u32 = 512;
    let EmitterRef::Shape(i) = emitter else {
        return 0.0;
    };
    let mut rng = crate::sampling::rng::Pcg32::new(0x5eed_c0f7, i as u64);
    let mut crossings = 0usize;
    for _ in 0..LINES {
        let u_pos = Vec2::new(rng.next_f32(), rng.next_f32());
        let u_dir = Vec2::new(rng.next_f32(), rng.next_f32());
        let line = uniform_line(center, radius, u_pos, u_dir);
        crossings += line_crossings(scene_geometry, i, line, radius, false).len();
    }
    // Nothing met: as if one line in all had crossed it (it is small).
    let mean = crossings.max(1) as f32 / LINES as f32;
    line_measure(radius) * mean / (2.0 * PI)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    #[test]
    fn directions_toward_a_sphere_stay_in_its_cone_with_its_density() {
        let (c, r) = (Vec3::new(0.3, 2.0, -0.5), 0.4);
        let mut rng = Pcg32::new(8, 1);
        // Outside, far (a tiny cone) and near; inside.
        for p in [Vec3::ZERO, Vec3::new(0.0, -3000.0, 0.0), Vec3::new(0.3, 2.5, -0.5)] {
            let to_c = c - p;
            let cos_max = (1.0 - r * r / to_c.length_squared()).sqrt();
            for _ in 0..2000 {
                let (w, pdf) = sample_toward_sphere(c, r, p, Vec2::new(rng.next_f32(), rng.next_f32()));
                assert!((w.length() - 1.0).abs() < 1e-5, "{w}");
                assert_eq!(pdf, toward_sphere_pdf(c, r, p));
                assert!(w.dot(to_c.normalize()) >= cos_max - 1e-6, "{p}: {w} leaves the cone");
            }
        }
        let inside = c + Vec3::new(0.1, 0.0, 0.0);
        assert_eq!(toward_sphere_pdf(c, r, inside), pdf_sphere_uniform());
        // A tiny cone's density is its solid angle's inverse, πθ² ≈ πr²/d².
        let far = Vec3::new(0.3, -3000.0, -0.5);
        let expected = (c - far).length_squared() / (PI * r * r);
        assert!((toward_sphere_pdf(c, r, far) / expected - 1.0).abs() < 1e-3);
    }

    #[test]
    fn sphere_cone_samples_hit_the_sphere_with_the_right_density() {
        let (c, r) = (Vec3::new(0.0, 3.0, 0.0), 0.5);
        let p = Vec3::ZERO;
        let mut rng = Pcg32::new(5, 0);
        let mut inv_pdf = 0.0f64;
        let n = 20_000;
        for _ in 0..n {
            let (lp, ln, pdf) = sample_sphere_cone(c, r, p, Vec2::new(rng.next_f32(), rng.next_f32())).unwrap();
            assert!(((lp - c).length() - r).abs() < 1e-4);
            assert!(ln.dot(p - lp) >= -1e-4, "the sampled point faces p");
            assert!((pdf - sphere_cone_pdf(c, r, p)).abs() < 1e-3 * pdf);
            inv_pdf += 1.0 / pdf as f64;
        }
        // E[1/pdf] = the cone's solid angle 2π(1 − cos θmax).
        let cos_max = (1.0f64 - 0.25 / 9.0).sqrt();
        let omega = 2.0 * std::f64::consts::PI * (1.0 - cos_max);
        assert!((inv_pdf / n as f64 - omega).abs() < 1e-6 * omega.max(1.0) + 1e-9);
        assert!(sample_sphere_cone(c, r, c, Vec2::ZERO).is_none());
        // A far, tiny sphere takes the small-angle path.
        let (_, _, pdf) = sample_sphere_cone(Vec3::new(0.0, 1e4, 0.0), 1.0, p, Vec2::new(0.3, 0.6)).unwrap();
        assert!((pdf - sphere_cone_pdf(Vec3::new(0.0, 1e4, 0.0), 1.0, p)).abs() < 1e-3 * pdf);
    }

    /// An emissive material and a rectangle light made of it.
    const LAMP_AND_RECTANGLE: &str = r#"
[[material]]
name = "lamp"
emission = [3, 2, 1]

[[shape]]
type = "rectangle"
corner = [-0.5, 2, -0.5]
edge_u = [1, 0, 0]
edge_v = [0, 0, 1]
material = "lamp"
"#;

    /// A rectangle light sampled on its own gives what sampling it through
    /// the aggregate gives, bit for bit: plain, transformed (baked) and
    /// with its normal flipped.
    #[test]
    fn rectangle_lights_sample_as_the_aggregate_does() {
        let text = LAMP_AND_RECTANGLE.to_string()
            + r#"
[[shape]]
type = "rectangle"
corner = [0, 0, 0]
edge_u = [1, 0, 0]
edge_v = [0, 1, 0]
material = "lamp"
flip_normals = true
transform = [{ scale = [2, 3, 1] }, { rotate = { axis = [1, 1, 0], angle = 30 } }, { translate = [0.5, 1, -3] }]
"#;
        let desc = crate::scene::native::parse(&text, std::path::Path::new("lights.toml")).unwrap();
        let scene = crate::scene::build(&desc).unwrap();
        assert_eq!(scene.lights.len(), 2);
        let mut rng = Pcg32::new(11, 3);
        for light in &scene.lights {
            let Light::Area {
                parallelogram: Some(r), ..
            } = light
            else {
                panic!("each rectangle light gets the fast path")
            };
            let mut general = light.clone();
            if let Light::Area { parallelogram, .. } = &mut general {
                *parallelogram = None;
            }
            let mut hits = 0;
            for _ in 0..2000 {
                let p = r.corner + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let (a, b) = (
                    light.sample_li(&scene, p, 0.5, u, false),
                    general.sample_li(&scene, p, 0.5, u, false),
                );
                match (a, b) {
                    (Some(a), Some(b)) => {
                        hits += 1;
                        assert_eq!((a.wi, a.li, a.pdf, a.target), (b.wi, b.li, b.pdf, b.target));
                    }
                    (None, None) => {}
                    _ => panic!("{p}: one route samples the light, the other does not"),
                }
            }
            assert!(hits > 500, "{hits} samples reached the light");
        }
    }

    /// Lights that say they do not read `u_pick` give the same sample
    /// whatever it is, so integrators may pass over drawing it; a mesh
    /// emitter reads it to pick a triangle. (A sphere or a box emitter
    /// says it reads it, which only costs the number.)
    #[test]
    fn only_lights_that_read_the_pick_number_depend_on_it() {
        let text = LAMP_AND_RECTANGLE.to_string()
            + r#"
[world]
background = [0.2, 0.3, 0.4]

[[light]]
type = "point"
position = [0, 3, 0]

[[light]]
type = "spot"
position = [0, 3, 0]
to = [0, 0, 0]

[[light]]
type = "directional"
direction = [0, -1, 0.2]

[[shape]]
type = "sphere"
center = [2, 2, 0]
radius = 0.5
material = "lamp"

[[shape]]
type = "box"
min = [-3, 1, -1]
max = [-2, 2, 0]
material = "lamp"

[[shape]]
type = "mesh"
positions = [[0, 4, 0], [1, 4, 0], [1, 4, 1], [0, 4, 1], [3, 5, 3]]
indices = [[0, 1, 2], [0, 2, 3], [1, 4, 2]]
material = "lamp"
"#;
        let desc = crate::scene::native::parse(&text, std::path::Path::new("lights.toml")).unwrap();
        let scene = crate::scene::build(&desc).unwrap();
        let kinds = |f: fn(&Light) -> bool| scene.lights.iter().filter(|l| f(l)).count();
        assert_eq!(kinds(|l| matches!(l, Light::Point { .. } | Light::Spot { .. })), 2);
        assert_eq!(
            kinds(|l| matches!(l, Light::Directional { .. } | Light::Environment)),
            2
        );
        assert_eq!(kinds(|l| matches!(l, Light::Area { .. })), 4);
        let mut rng = Pcg32::new(3, 9);
        let mut pick_changed_a_sample = false;
        for light in &scene.lights {
            for _ in 0..500 {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::new(1.0, 1.0, 1.0);
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let (a, b) = (
                    light.sample_li(&scene, p, 0.05, u, false),
                    light.sample_li(&scene, p, 0.95, u, false),
                );
                let same = match (&a, &b) {
                    (Some(a), Some(b)) => (a.wi, a.li, a.pdf, a.target) == (b.wi, b.li, b.pdf, b.target),
                    (None, None) => true,
                    _ => false,
                };
                if !light.reads_pick() {
                    assert!(same, "{light:?} at {p}: the sample depends on u_pick");
                }
                pick_changed_a_sample |= !same;
            }
        }
        assert!(
            pick_changed_a_sample,
            "the mesh emitter picks its triangles with u_pick"
        );
        // Drawing through the sampler takes the pick number (or passes
        // over it) and the point, and leaves the sampler where taking both
        // would have.
        use crate::sampling::{Sampler, SamplerKind};
        for kind in [SamplerKind::Independent, SamplerKind::Sobol] {
            for light in &scene.lights {
                let (mut drawing, mut plain) = (Sampler::new(kind, 16, 5), Sampler::new(kind, 16, 5));
                drawing.start_pixel_sample(3, 4, 2);
                plain.start_pixel_sample(3, 4, 2);
                let p = Vec3::new(0.1, 0.2, 0.3);
                let a = light.sample_li_drawing(&scene, p, &mut drawing, false);
                let (u_pick, u) = (plain.next_1d(), plain.next_2d());
                let b = light.sample_li(&scene, p, u_pick, u, false);
                assert_eq!(a.map(|s| (s.wi, s.pdf)), b.map(|s| (s.wi, s.pdf)), "{light:?}");
                assert_eq!(drawing.next_1d(), plain.next_1d(), "{light:?}");
            }
        }
    }

    #[test]
    fn spot_cone_fades_between_the_angles() {
        assert_eq!(smoothstep(0.5, 0.8, 0.4), 0.0);
        assert_eq!(smoothstep(0.5, 0.8, 0.9), 1.0);
        let mid = smoothstep(0.5, 0.8, 0.65);
        assert!((mid - 0.5).abs() < 1e-6);
    }

    /// Mitsuba's profile is linear in the angle: full inside the beam
    /// width, none at and beyond the cutoff, half halfway between.
    #[test]
    fn mitsuba_spot_profile_is_linear_in_angle() {
        let (inner, outer) = (15f32.to_radians(), 20f32.to_radians());
        let eval = |deg: f32| SpotProfile::LinearInAngle.eval(inner.cos(), outer.cos(), deg.to_radians().cos());
        assert_eq!(eval(0.0), 1.0);
        assert_eq!(eval(14.0), 1.0);
        assert_eq!(eval(20.0), 0.0);
        assert_eq!(eval(25.0), 0.0);
        for (deg, expected) in [(17.5, 0.5), (16.0, 0.8), (19.0, 0.2)] {
            assert!((eval(deg) - expected).abs() < 1e-4, "{deg}°: {}", eval(deg));
        }
        // Equal angles: a hard edge.
        let hard = |deg: f32| SpotProfile::LinearInAngle.eval(outer.cos(), outer.cos(), deg.to_radians().cos());
        assert_eq!((hard(19.9), hard(20.1)), (1.0, 0.0));
    }

    /// A projected image spans the outer cone's square: the axis reads its
    /// centre, the cone's edge along the light's x and y axes the middle of
    /// its right and top edges, and the light's frame turns it.
    fn projector(tan_half: Vec2, e: f32) -> Projector {
        // Looking down −z from (0, 0, 1), as Mitsuba's lookat from there to
        // the origin with +y up: local x = up × axis.
        let axis = Vec3::NEG_Z;
        let x = Vec3::Y.cross(axis);
        let to_world = glam::Mat3::from_cols(x, axis.cross(x), axis);
        Projector {
            position: Vec3::Z,
            to_world,
            to_local: to_world.inverse(),
            tan_half,
            scale: PI * 2.0,
            image: Texture::Constant(Rgb::splat(e)),
            law: ProjectorLaw::PlaneIrradiance,
        }
    }

    /// A goniometric light's photons carry its power on average, each
    /// with the weight intensity/density of its direction, and the density
    /// is the one `pdf_emission` reports.
    #[test]
    fn goniometric_emission_carries_the_power_by_the_density_it_reports() {
        let n = 16;
        // Brighter toward +z of the image's frame, dark below its equator.
        let values: Vec<f32> = (0..n * n)
            .map(|i| {
                let uv = Vec2::new(((i % n) as f32 + 0.5) / n as f32, ((i / n) as f32 + 0.5) / n as f32);
                environment::equal_area_square_to_sphere(uv).z.max(0.0) * 2.0
            })
            .collect();
        let to_world = glam::Mat3::from_cols(Vec3::X, Vec3::Z, Vec3::Y);
        let g = Goniometric::new(Vec3::ONE, to_world, Rgb::new(1.0, 0.5, 0.25), n, values);
        // Up in the world is +z of the image: twice the intensity's colour
        // at the top, none below.
        let up = g.intensity_toward(Vec3::Y);
        assert!((up.x - 2.0 * 0.99).abs() < 0.05, "{up}");
        assert_eq!(g.intensity_toward(Vec3::NEG_Y), Rgb::ZERO);
        let mut rng = Pcg32::new(9, 1);
        let count = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..count {
            let (w, dir) = g.sample_emission(Vec2::new(rng.next_f32(), rng.next_f32())).unwrap();
            assert!(dir.y > -1e-3, "no photon leaves where the image is dark: {dir}");
            let pdf = g.pdf_emission(dir);
            let expected = g.intensity_toward(dir) / pdf;
            assert!((w.x - expected.x).abs() <= 1e-3 * expected.x, "{w} vs {expected}");
            sum += luminance(w) as f64;
        }
        let mean = sum / count as f64;
        assert!(
            (mean - g.power() as f64).abs() < 0.01 * g.power() as f64,
            "{mean} vs {}",
            g.power()
        );
    }

    /// pbrt-v4's law: the intensity is scale·E in every direction of the
    /// frame, so the power is scale·E times the frame's solid angle,
    /// 4·asin(sin α·sin β) for half-angles α and β; photon emission
    /// carries the same power, and on the plane the irradiance falls off
    /// as cos³θ.
    #[test]
    fn radiant_intensity_projectors_emit_scale_times_the_frames_solid_angle() {
        let mut p = projector(Vec2::new(1.0, 0.5), 0.3);
        p.law = ProjectorLaw::RadiantIntensity;
        p.scale = 2.0;
        let (a, b) = (1f32.atan(), 0.5f32.atan());
        let solid_angle = 4.0 * (a.sin() * b.sin()).asin();
        let power = 2.0 * 0.3 * solid_angle;
        let by_pixels = p.scale * p.power_per_scale(&crate::texture::TextureStore::default());
        assert!((by_pixels - power).abs() < 1e-3 * power, "{by_pixels} vs {power}");
        let q = Vec3::new(0.6, 0.2, 0.0);
        let (i, dir) = p
            .intensity_toward(&crate::texture::TextureStore::default(), q)
            .expect("inside the frame");
        assert!((i.x - 0.6).abs() < 1e-6);
        let irradiance = i.x * dir.dot(Vec3::NEG_Z) / (q - p.position).length_squared();
        let cos = dir.dot(Vec3::NEG_Z);
        assert!((irradiance - 0.6 * cos.powi(3)).abs() < 1e-5);
        // Emission: the mean weight of uniform points of the frame.
        let mut rng = Pcg32::new(8, 0);
        let n = 200_000;
        let mean = (0..n)
            .map(|_| {
                p.sample_emission(
                    &crate::texture::TextureStore::default(),
                    Vec2::new(rng.next_f32(), rng.next_f32()),
                )
                .unwrap()
                .0
                .x as f64
            })
            .sum::<f64>()
            / n as f64;
        assert!((mean - power as f64).abs() < 5e-3 * power as f64, "{mean} vs {power}");
    }

    /// A plane facing a projector at depth z receives π·scale·E/z² inside
    /// the frame and nothing outside, and the intensity integrated over
    /// the sphere is the power the photon emission carries.
    #[test]
    fn projector_irradiance_and_power_agree() {
        let p = projector(Vec2::new(1.0, 0.5), 0.3);
        let expected = 0.3 * PI * 2.0;
        for q in [Vec3::ZERO, Vec3::new(0.6, 0.2, 0.0), Vec3::new(-0.9, -0.45, 0.0)] {
            let (i, dir) = p
                .intensity_toward(&crate::texture::TextureStore::default(), q)
                .expect("inside the frame");
            let d2 = (q - p.position).length_squared();
            // Irradiance on the plane z = 0: I·cos/d².
            let irradiance = i.x * dir.dot(Vec3::NEG_Z) / d2;
            assert!(
                (irradiance - expected).abs() < 1e-4 * expected,
                "{q}: {irradiance} vs {expected}"
            );
        }
        assert!(
            p.intensity_toward(&crate::texture::TextureStore::default(), Vec3::new(1.1, 0.0, 0.0))
                .is_none()
        );
        assert!(
            p.intensity_toward(&crate::texture::TextureStore::default(), Vec3::new(0.0, 0.6, 0.0))
                .is_none()
        );
        assert!(
            p.intensity_toward(&crate::texture::TextureStore::default(), Vec3::new(0.0, 0.0, 2.0))
                .is_none(),
            "behind the light"
        );
        // ∫ I dω by uniform directions on the sphere: 4π · mean.
        let mut rng = Pcg32::new(7, 0);
        let n = 400_000;
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let d = crate::sampling::warp::sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
            let x = p
                .intensity_toward(&crate::texture::TextureStore::default(), p.position + d)
                .map_or(0.0, |(i, _)| 4.0 * PI as f64 * i.x as f64);
            sum += x;
            sum2 += x * x;
        }
        let mean = sum / n as f64;
        let sigma = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
        let power = (p.scale * p.image_area() * 0.3) as f64;
        assert!(
            (mean - power).abs() < 4.0 * sigma,
            "∫ I dω = {mean} ± {sigma}, emission {power}"
        );
        let (w, dir) = p
            .sample_emission(&crate::texture::TextureStore::default(), Vec2::new(0.25, 0.5))
            .unwrap();
        assert!((w.x as f64 - power).abs() < 1e-4 * power);
        // u = 0.25 lies left of centre: +x of the frame (Mitsuba's left).
        assert!(dir.dot(p.to_world * Vec3::X) > 0.0 && dir.z < 0.0);
    }

    #[test]
    fn spot_projection_spans_the_outer_cone() {
        let outer = 20f32.to_radians();
        let uv_of = |to_world: glam::Mat3, d: Vec3| {
            let p = SpotProjection {
                to_local: to_world.inverse(),
                tan_outer: outer.tan(),
                texture: Texture::Constant(Rgb::ONE),
            };
            let uv = p.uv(d);
            (uv.x, uv.y)
        };
        let close = |a: (f32, f32), b: (f32, f32)| (a.0 - b.0).abs() < 1e-5 && (a.1 - b.1).abs() < 1e-5;
        let id = glam::Mat3::IDENTITY;
        assert!(close(uv_of(id, Vec3::Z), (0.5, 0.5)));
        let edge_x = Vec3::new(outer.sin(), 0.0, outer.cos());
        assert!(close(uv_of(id, edge_x), (1.0, 0.5)));
        assert!(close(uv_of(id, Vec3::new(0.0, outer.sin(), outer.cos())), (0.5, 1.0)));
        // The light turned a quarter about its axis: its x axis is world y.
        let turned = glam::Mat3::from_cols(Vec3::Y, -Vec3::X, Vec3::Z);
        assert!(close(
            uv_of(turned, Vec3::new(0.0, outer.sin(), outer.cos())),
            (1.0, 0.5)
        ));
    }
}
