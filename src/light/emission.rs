//! Emission sampling: rays leaving the lights, for algorithms that trace
//! light forward (photon mapping). Each light picks a point on itself and a
//! direction of emission, and reports the weight
//!
//! ```text
//! Le(x, ω) · |cos θ| / (p_A(x) · p_ω(ω))
//! ```
//!
//! so that the mean of the weights over many samples is the light's total
//! flux Φ (Veach 1997, §10.2; pbrt-v4 §12.6 `SampleLe`). A photon that
//! carries `weight / (p_light · N)` of N photons therefore carries its share
//! of the scene's power.
//!
//! | light | point | direction |
//! |---|---|---|
//! | point | its position | uniform over the sphere |
//! | projector | its position | uniform over the image's frame on the plane at depth 1 |
//! | goniometric | its position | pixel by pixel of its equal-area image, in proportion to the values |
//! | spot | its position | uniform inside the outer cone, weighted by the smooth falloff |
//! | directional | uniform on a disk of the scene's bounding radius, before the scene | the light's direction |
//! | area | uniform on the emitter (by area) | cosine-weighted about the front normal (for a two-sided emitter about either side's, each with probability ½) |
//! | area without an area density (distance functions, implicit surfaces) | one of the crossings of a line drawn uniformly through its bounding sphere (weighted by their number) | the line's, turned to the emitting side: cosine-weighted (Crofton) |
//! | environment | uniform on a disk facing the sampled direction, beyond the scene | importance-sampled from the background |
//!
//! A point or spot light with `falloff = false` (the classical constant
//! light) has no physical flux; it is emitted as the physical light of the
//! same intensity.

use super::Light;
use crate::color::Rgb;
use crate::geometry::Ray;
use crate::material::Frame;
use crate::sampling::Uniforms;
use crate::sampling::warp::{
    pdf_cone_uniform, pdf_sphere_uniform, sample_cone_uniform, sample_disk_concentric, sample_hemisphere_cosine,
    sample_sphere_uniform,
};
use crate::scene::Scene;
use crate::texture::TexCoord;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// A ray of light leaving a light source.
#[derive(Clone, Copy, Debug)]
pub struct EmissionSample {
    /// Starts on the light (or on a disk before the scene, for lights at
    /// infinity) and points where the light travels; unit direction.
    pub ray: Ray,
    /// `Le·|cos θ| / (p_A·p_ω)`: its mean over samples is the light's flux.
    pub weight: Rgb,
    /// For an area light, the point the ray leaves from, which a camera
    /// may see directly (light tracing's first connection).
    pub surface: Option<EmitterPoint>,
}

/// A point sampled on an area light.
#[derive(Clone, Copy, Debug)]
pub struct EmitterPoint {
    /// The point (before the push off the surface).
    pub p: Vec3,
    /// The emitting side's unit normal (the front's; see `two_sided`).
    pub n: Vec3,
    /// Whether the back emits too.
    pub two_sided: bool,
    /// Radiance leaving the emitting side (each, when two-sided), the same
    /// in every direction.
    pub le: Rgb,
    /// Density of the point, per unit area.
    pub pdf_area: f32,
}

impl EmitterPoint {
    /// The point pushed off the emitter to the side that unit direction
    /// `w` leaves on, where a ray toward `w` starts: a two-sided
    /// emitter's photon may have left from the other side.
    pub fn origin_toward(&self, w: Vec3) -> Vec3 {
        let side = if self.n.dot(w) >= 0.0 { self.n } else { -self.n };
        self.p + side * (EMITTER_OFFSET * self.p.abs().max_element().max(1.0))
    }
}

/// The sphere that bounds the scene's geometry: centre and radius (a unit
/// sphere at the origin for a scene without bounded geometry).
pub fn scene_bounding_sphere(scene: &Scene) -> (Vec3, f32) {
    let b = scene.geometry.bounds();
    if b.is_empty() {
        (Vec3::ZERO, 1.0)
    } else {
        (b.centroid(), (b.extent().length() * 0.5).max(1e-3))
    }
}

/// Relative size of the push that moves a ray's origin off the emitter it
/// starts on: about 250 ulps, above the rounding error of sampled points.
const EMITTER_OFFSET: f32 = 3e-5;

/// A ray of light from the whole scene: a light chosen by `lights` (one
/// of the scene's distributions over its lights, by power), then a point
/// and direction on it ([`Light::sample_le`]), with the light's index and
/// the probability of that choice; `None` when the sample carries no
/// light. Draws six numbers from `rng`, in that order.
pub fn sample_scene_emission<R: Uniforms>(
    scene: &Scene,
    lights: &crate::sampling::Distribution1D,
    bounds: (Vec3, f32),
    rng: &mut R,
) -> Option<(EmissionSample, usize, f32)> {
    let (light_index, pmf, _) = lights.sample(rng.next_f32());
    if pmf <= 0.0 {
        return None;
    }
    let u_pick = rng.next_f32();
    let u_pos = Vec2::new(rng.next_f32(), rng.next_f32());
    let u_dir = Vec2::new(rng.next_f32(), rng.next_f32());
    let emitted = scene.lights[light_index].sample_le(scene, bounds, u_pick, u_pos, u_dir)?;
    Some((emitted, light_index, pmf))
}

impl Light {
    /// Samples a ray of emitted light. `u_pick` chooses a triangle of a mesh
    /// emitter, `u_pos` the point and `u_dir` the direction; `bounds` is the
    /// scene's bounding sphere ([`scene_bounding_sphere`]), from which lights
    /// at infinity shine. `None` when the sample carries no light.
    pub fn sample_le(
        &self,
        scene: &Scene,
        bounds: (Vec3, f32),
        u_pick: f32,
        u_pos: Vec2,
        u_dir: Vec2,
    ) -> Option<EmissionSample> {
        let mut surface = None;
        let (weight, ray) = match self {
            Light::Point {
                position, intensity, ..
            } => {
                let dir = sample_sphere_uniform(u_dir);
                (*intensity / pdf_sphere_uniform(), Ray::new(*position, dir))
            }
            Light::Spot {
                position,
                direction,
                intensity,
                cos_inner,
                cos_outer,
                profile,
                projection,
                ..
            } => {
                let local = sample_cone_uniform(u_dir, *cos_outer);
                let cone = profile.eval(*cos_inner, *cos_outer, local.z);
                let dir = Frame::from_normal(*direction).to_world(local);
                let intensity = match projection {
                    Some(image) => *intensity * image.eval(&scene.textures, dir),
                    None => *intensity,
                };
                (
                    intensity * (cone / pdf_cone_uniform(*cos_outer)),
                    Ray::new(*position, dir),
                )
            }
            Light::Projector(proj) => {
                let (power, dir) = proj.sample_emission(&scene.textures, u_dir)?;
                (power, Ray::new(proj.position, dir))
            }
            Light::Goniometric(g) => {
                let (power, dir) = g.sample_emission(u_dir)?;
                (power, Ray::new(g.position, dir))
            }
            Light::Directional { direction, irradiance } => {
                let (center, radius) = bounds;
                let frame = Frame::from_normal(*direction);
                let d = sample_disk_concentric(u_pos) * radius;
                let origin = center - *direction * radius + frame.to_world(Vec3::new(d.x, d.y, 0.0));
                (*irradiance * (PI * radius * radius), Ray::new(origin, *direction))
            }
            Light::Area {
                emitter: super::EmitterRef::Shape(i),
                radiance,
                two_sided,
                cone: Some((center, radius)),
                ..
            } => {
                // Drawn through lines across its bounding sphere
                // ([`super::sample_on_lines`]): of a line's k crossings one
                // is taken (k times as much light), at density 2π/(M·k) on
                // average uniform by area, and the line's direction, turned
                // to the emitting side, is the ray's, distributed as |cos θ|
                // about the normal: E[k·f(x, ω)] = (2/M)·∫∫ f cos θ dω dA
                // over the emitting hemisphere, so the ray is weighed as an
                // area light's with a cosine-weighted direction.
                let (hit, pdf_area, w) = super::sample_on_lines(
                    &scene.geometry,
                    *i,
                    (*center, *radius),
                    u_pick,
                    (u_pos, u_dir),
                    radiance.reads_uv(),
                )?;
                let (dir, sides) = match (*two_sided, w.dot(hit.ng) >= 0.0) {
                    (true, _) => (w, 2.0),
                    (false, true) => (w, 1.0),
                    (false, false) => (-w, 1.0),
                };
                let le = radiance.eval(&scene.textures, &TexCoord::at(&hit));
                surface = Some(EmitterPoint {
                    p: hit.p,
                    n: hit.ng,
                    two_sided: *two_sided,
                    le,
                    pdf_area,
                });
                (le * (sides * PI / pdf_area), hit.spawn_ray(dir))
            }
            Light::Area {
                emitter,
                radiance,
                area,
                two_sided,
                ..
            } => {
                let s = scene
                    .geometry
                    .sample_emitter(*emitter, area, u_pick, u_pos, radiance.reads_uv())?;
                if !(s.pdf_area.is_finite() && s.pdf_area > 0.0) {
                    return None;
                }
                // A two-sided emitter picks its side with probability ½
                // (pbrt-v4 `DiffuseAreaLight::SampleLe`), reusing u_dir.x.
                let (side, u_dir, sides) = match (*two_sided, u_dir.x < 0.5) {
                    (false, _) => (s.n, u_dir, 1.0),
                    (true, true) => (s.n, Vec2::new(2.0 * u_dir.x, u_dir.y), 2.0),
                    (true, false) => (-s.n, Vec2::new(2.0 * u_dir.x - 1.0, u_dir.y), 2.0),
                };
                let local = sample_hemisphere_cosine(u_dir);
                if local.z <= 0.0 {
                    return None;
                }
                let dir = Frame::from_normal(side).to_world(local);
                let le = radiance.eval(&scene.textures, &TexCoord::new(s.uv, s.p).with_attribute(s.attribute));
                let point = EmitterPoint {
                    p: s.p,
                    n: s.n,
                    two_sided: *two_sided,
                    le,
                    pdf_area: s.pdf_area,
                };
                surface = Some(point);
                // Le·cos θ / (p_A · cos θ/(π·sides)) = sides·π·Le / p_A.
                (le * (sides * PI / s.pdf_area), Ray::new(point.origin_toward(dir), dir))
            }
            Light::Environment => {
                let (wi, pdf_dir) = scene.background.sample(u_dir)?;
                if !(pdf_dir.is_finite() && pdf_dir > 0.0) {
                    return None;
                }
                let (center, radius) = bounds;
                let frame = Frame::from_normal(wi);
                let d = sample_disk_concentric(u_pos) * radius;
                let origin = center + wi * radius + frame.to_world(Vec3::new(d.x, d.y, 0.0));
                let le = scene.background.eval(wi);
                (le * (PI * radius * radius / pdf_dir), Ray::new(origin, -wi))
            }
        };
        if weight == Rgb::ZERO || !weight.is_finite() {
            return None;
        }
        Some(EmissionSample { ray, weight, surface })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;
    use crate::scene::desc::*;

    /// Mean and standard error of the flux estimate, per channel, from `n`
    /// photons of the whole scene (lights chosen by power).
    fn scene_flux(scene: &Scene, n: u32, seed: u64) -> (glam::DVec3, glam::DVec3) {
        let bounds = scene_bounding_sphere(scene);
        let mut rng = Pcg32::new(seed, 3);
        let (mut sum, mut sum_sq) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
        for _ in 0..n {
            let (li, pmf, _) = scene.light_distribution.sample(rng.next_f32());
            let u_pick = rng.next_f32();
            let u_pos = Vec2::new(rng.next_f32(), rng.next_f32());
            let u_dir = Vec2::new(rng.next_f32(), rng.next_f32());
            let v = match scene.lights[li].sample_le(scene, bounds, u_pick, u_pos, u_dir) {
                Some(s) => {
                    assert!((s.ray.dir.length() - 1.0).abs() < 1e-4);
                    (s.weight / pmf).as_dvec3()
                }
                None => glam::DVec3::ZERO,
            };
            sum += v;
            sum_sq += v * v;
        }
        let mean = sum / n as f64;
        let var = (sum_sq / n as f64 - mean * mean) / n as f64;
        (mean, glam::DVec3::new(var.x.sqrt(), var.y.sqrt(), var.z.sqrt()))
    }

    fn emissive(name: &str, le: Rgb) -> MaterialDesc {
        let mut m = MaterialDesc::new(name);
        m.emission = ColorSource::Rgb(le);
        m
    }

    #[test]
    fn photons_carry_the_power_of_every_kind_of_light() {
        let mut d = SceneDesc::default();
        d.materials.push(emissive("sphere-light", Rgb::new(2.0, 3.0, 4.0)));
        d.materials.push(emissive("quad-light", Rgb::new(5.0, 1.0, 0.5)));
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Sphere {
                center: Vec3::new(0.0, 2.0, 0.0),
                radius: 0.25,
            },
            Some("sphere-light"),
        ));
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Rectangle {
                corner: Vec3::new(-1.0, 3.0, -0.5),
                edge_u: Vec3::new(0.5, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, 1.5),
            },
            Some("quad-light"),
        ));
        // A receiver, so that the scene has bounds.
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            },
            None,
        ));
        let (i_point, i_spot, e_dir) = (
            Rgb::new(3.0, 2.0, 1.0),
            Rgb::new(10.0, 10.0, 4.0),
            Rgb::new(0.5, 0.7, 0.9),
        );
        d.lights.push(LightDesc::new(LightKind::Point {
            position: Vec3::new(1.0, 3.0, 1.0),
            intensity: i_point,
            falloff: true,
        }));
        let (inner, outer) = (20.0f32, 35.0f32);
        d.lights.push(LightDesc::new(LightKind::Spot {
            position: Vec3::new(0.0, 4.0, 0.0),
            to: Vec3::ZERO,
            intensity: i_spot,
            inner_angle: inner,
            outer_angle: outer,
            profile: crate::light::SpotProfile::SmoothStepInCosine,
            projection: None,
            falloff: true,
        }));
        d.lights.push(LightDesc::new(LightKind::Directional {
            direction: Vec3::new(0.2, -1.0, 0.1),
            irradiance: e_dir,
        }));
        let bg = Rgb::new(0.1, 0.2, 0.05);
        d.background = BackgroundDesc::Constant(bg);
        let scene = crate::scene::build(&d).unwrap();
        let (_, radius) = scene_bounding_sphere(&scene);

        // Spot: 2π·I·∫ smoothstep(cos_o, cos_i, c) dc over [cos_o, 1].
        let (ci, co) = (inner.to_radians().cos(), outer.to_radians().cos());
        let steps = 100_000;
        let mut cone = 0.0f64;
        for k in 0..steps {
            let c = co + (1.0 - co) * (k as f32 + 0.5) / steps as f32;
            cone += super::super::smoothstep(co, ci, c) as f64;
        }
        cone *= (1.0 - co) as f64 / steps as f64;
        let area_sphere = 4.0 * PI * 0.25 * 0.25;
        let expected = (Rgb::new(2.0, 3.0, 4.0) * (PI * area_sphere)
            + Rgb::new(5.0, 1.0, 0.5) * (PI * 0.75)
            + i_point * (4.0 * PI)
            + e_dir * (PI * radius * radius)
            + bg * (4.0 * PI * PI * radius * radius))
            .as_dvec3()
            + i_spot.as_dvec3() * (2.0 * std::f64::consts::PI * cone);
        let (mean, err) = scene_flux(&scene, 400_000, 1);
        for c in 0..3 {
            assert!(
                (mean[c] - expected[c]).abs() <= 4.0 * err[c] + 1e-4 * expected[c],
                "channel {c}: {} ± {} vs {}",
                mean[c],
                err[c],
                expected[c]
            );
        }
    }

    /// Emitters without an area density emit from the crossings of lines
    /// through their bounding spheres: the photons of a distance-function
    /// torus (up to four crossings a line), a two-sided one, a scaled
    /// sphere and an equation sphere carry π·A·Le (twice that two-sided),
    /// A their areas, and their powers for choosing lights are near it.
    #[test]
    fn photons_of_distance_functions_and_equations_carry_their_power() {
        let cases = [
            (
                "type = \"sdf\"\nsdf = { torus = [0.6, 0.2] }\ntransform = [{ rotate = { axis = [1, 0, 0], angle = 30 } }]",
                4.0 * PI * PI * 0.6 * 0.2,
                false,
            ),
            (
                "type = \"sdf\"\nsdf = { torus = [0.6, 0.2] }",
                4.0 * PI * PI * 0.6 * 0.2,
                true,
            ),
            (
                "type = \"sdf\"\nsdf = { sphere = 0.3 }\ntransform = [{ scale = [2, 2, 2] }]",
                4.0 * PI * 0.36,
                false,
            ),
            (
                "type = \"implicit\"\nequation = \"x^2 + y^2 + z^2 - 0.49\"\nbounds = [[-0.8, -0.8, -0.8], [0.8, 0.8, 0.8]]",
                4.0 * PI * 0.49,
                false,
            ),
        ];
        for (shape, area, two_sided) in cases {
            let text = format!(
                "[[material]]\nname = \"l\"\nemission = [1, 2, 3]\ntwo_sided_emission = {two_sided}\n[[shape]]\n{shape}\nmaterial = \"l\"\n"
            );
            let d = crate::scene::native::parse(&text, std::path::Path::new("t.toml")).unwrap();
            let scene = crate::scene::build(&d).unwrap();
            let (mean, err) = scene_flux(&scene, 200_000, 4);
            let sides = if two_sided { 2.0 } else { 1.0 };
            let expected = (Rgb::new(1.0, 2.0, 3.0) * (sides * PI * area)).as_dvec3();
            // Its power, by which lights are chosen, from its area in the
            // world (estimated by Crofton's formula).
            let power = scene.lights[0].power(&scene, 1.0);
            let exact = sides * PI * area * crate::color::luminance(Rgb::new(1.0, 2.0, 3.0));
            assert!((power / exact - 1.0).abs() < 0.2, "{shape}: power {power} for {exact}");
            for c in 0..3 {
                assert!(
                    (mean[c] - expected[c]).abs() <= 4.0 * err[c] + 2e-3 * expected[c],
                    "{shape}, channel {c}: {} ± {} vs {}",
                    mean[c],
                    err[c],
                    expected[c]
                );
            }
        }
    }

    #[test]
    fn area_photons_leave_the_front_side_cosine_weighted() {
        let mut d = SceneDesc::default();
        d.materials.push(emissive("l", Rgb::ONE));
        // Facing down (edge_u × edge_v = −y).
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Rectangle {
                corner: Vec3::new(-0.5, 1.0, -0.5),
                edge_u: Vec3::new(1.0, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, 1.0),
            },
            Some("l"),
        ));
        let scene = crate::scene::build(&d).unwrap();
        let bounds = scene_bounding_sphere(&scene);
        let mut rng = Pcg32::new(9, 0);
        let n = 50_000;
        let mut mean_cos = 0.0f64;
        for _ in 0..n {
            let u = [rng.next_f32(), rng.next_f32(), rng.next_f32(), rng.next_f32()];
            let s = scene.lights[0]
                .sample_le(&scene, bounds, 0.5, Vec2::new(u[0], u[1]), Vec2::new(u[2], u[3]))
                .unwrap();
            let cos = -s.ray.dir.y;
            assert!(cos > 0.0, "emitted through the back");
            assert!(s.ray.origin.y < 1.0 && s.ray.origin.y > 0.999);
            // π·Le / p_A with p_A = 1/area = 1.
            assert!((s.weight.x - PI).abs() < 1e-4);
            mean_cos += cos as f64;
        }
        // E[cos θ] under the cosine density is 2/3.
        assert!((mean_cos / n as f64 - 2.0 / 3.0).abs() < 4.0 * (1.0f64 / 18.0 / n as f64).sqrt());
    }
}
