//! Every sampling routine produces what its density says: chi-square
//! goodness-of-fit tests of BSDF sampling (all models, several incident
//! directions, both sides) and of light sampling (sphere, rectangle, disk,
//! triangle mesh, transformed shape, environment map), plus the
//! consistency of `sample` with `eval` and `pdf`.

use std::f32::consts::PI;
use trazo::color::Rgb;
use trazo::light::{Background, EnvironmentMap, Light};
use trazo::material::blend::BlendBsdf;
use trazo::material::classic::ClassicBsdf;
use trazo::material::conductor::{ConductorBsdf, ConductorFresnel};
use trazo::material::dielectric::DielectricBsdf;
use trazo::material::lambert::LambertBsdf;
use trazo::material::microfacet::{Microfacet, MicrofacetDistribution};
use trazo::material::plastic::{CoatTables, PlasticBsdf, smooth_internal_reflectance};
use trazo::material::{Bsdf, DirectionSampling, TransportMode};
use trazo::sampling::Pcg32;
use trazo::sampling::chi2::{Chi2Test, sidak_alpha};
use trazo::scene::desc::*;
use trazo::texture::ImageTexture;
use trazo::{Vec2, Vec3};

fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn coat_smooth() -> f32 {
    smooth_internal_reflectance(1.5)
}

/// The rough plastics' coats under test: GGX and Beckmann.
fn coat_roughness() -> [Microfacet; 2] {
    [
        Microfacet::isotropic(0.3),
        Microfacet::new(MicrofacetDistribution::Beckmann, 0.3, 0.3),
    ]
}

/// Every BSDF configuration under test, with a name.
fn bsdfs<'a>(tables: &'a [CoatTables; 2]) -> Vec<(String, Bsdf<'a>)> {
    let complex = ConductorFresnel::Complex {
        eta: Rgb::new(0.2, 0.92, 1.1),
        k: Rgb::new(3.9, 2.45, 2.14),
    };
    let plastic = |microfacet: Microfacet, tables: Option<&'a CoatTables>| PlasticBsdf {
        diffuse: Rgb::new(0.6, 0.3, 0.2),
        eta: 1.5,
        microfacet,
        specular_tint: Rgb::ONE,
        nonlinear: false,
        specular_weight: 0.6,
        smooth_internal_reflectance: coat_smooth(),
        tables,
    };
    let configs: Vec<(String, Bsdf<'a>)> = vec![
        (
            "lambert".into(),
            Bsdf::Lambert(LambertBsdf {
                albedo: Rgb::splat(0.7),
            }),
        ),
        (
            "classic diffuse+phong s=12".into(),
            Bsdf::Classic(ClassicBsdf::new(
                Rgb::splat(0.5),
                Rgb::splat(0.4),
                12.0,
                Rgb::ZERO,
                Rgb::ZERO,
                1.0,
            )),
        ),
        (
            "classic phong s=80 + mirror + glass".into(),
            Bsdf::Classic(ClassicBsdf::new(
                Rgb::splat(0.1),
                Rgb::splat(0.3),
                80.0,
                Rgb::splat(0.2),
                Rgb::splat(0.3),
                1.5,
            )),
        ),
        (
            "rough conductor α=0.15".into(),
            Bsdf::Conductor(ConductorBsdf {
                fresnel: complex,
                tint: Rgb::ONE,
                microfacet: Microfacet::isotropic(0.15),
            }),
        ),
        (
            "rough conductor α=0.6 schlick".into(),
            Bsdf::Conductor(ConductorBsdf {
                fresnel: ConductorFresnel::Schlick(Rgb::new(0.9, 0.6, 0.3)),
                tint: Rgb::ONE,
                microfacet: Microfacet::isotropic(0.6),
            }),
        ),
        (
            "anisotropic conductor α=(0.1, 0.5)".into(),
            Bsdf::Conductor(ConductorBsdf {
                fresnel: complex,
                tint: Rgb::ONE,
                microfacet: Microfacet::new(MicrofacetDistribution::Ggx, 0.1, 0.5),
            }),
        ),
        (
            "rough conductor Beckmann α=0.3".into(),
            Bsdf::Conductor(ConductorBsdf {
                fresnel: complex,
                tint: Rgb::ONE,
                microfacet: Microfacet::new(MicrofacetDistribution::Beckmann, 0.3, 0.3),
            }),
        ),
        (
            "anisotropic conductor Beckmann α=(0.4, 0.08)".into(),
            Bsdf::Conductor(ConductorBsdf {
                fresnel: ConductorFresnel::Schlick(Rgb::new(0.9, 0.6, 0.3)),
                tint: Rgb::ONE,
                microfacet: Microfacet::new(MicrofacetDistribution::Beckmann, 0.4, 0.08),
            }),
        ),
        (
            "rough dielectric Beckmann α=0.25 η=1.5".into(),
            Bsdf::Dielectric(DielectricBsdf {
                eta: 1.5,
                microfacet: Microfacet::new(MicrofacetDistribution::Beckmann, 0.25, 0.25),
                reflect_tint: Rgb::ONE,
                transmit_tint: Rgb::ONE,
            }),
        ),
        (
            "rough dielectric α=0.2 η=1.5".into(),
            Bsdf::Dielectric(DielectricBsdf {
                eta: 1.5,
                microfacet: Microfacet::isotropic(0.2),
                reflect_tint: Rgb::ONE,
                transmit_tint: Rgb::ONE,
            }),
        ),
        (
            "rough dielectric anisotropic α=(0.4, 0.1) η=1.5".into(),
            Bsdf::Dielectric(DielectricBsdf {
                eta: 1.5,
                microfacet: Microfacet::new(MicrofacetDistribution::Ggx, 0.4, 0.1),
                reflect_tint: Rgb::ONE,
                transmit_tint: Rgb::ONE,
            }),
        ),
        (
            "rough dielectric α=0.5 η=1.33".into(),
            Bsdf::Dielectric(DielectricBsdf {
                eta: 1.33,
                microfacet: Microfacet::isotropic(0.5),
                reflect_tint: Rgb::ONE,
                transmit_tint: Rgb::ONE,
            }),
        ),
        (
            "smooth plastic (diffuse part)".into(),
            Bsdf::Plastic(plastic(Microfacet::isotropic(0.0), None)),
        ),
        (
            "rough plastic α=0.3".into(),
            Bsdf::Plastic(plastic(coat_roughness()[0], Some(&tables[0]))),
        ),
        (
            "rough plastic Beckmann α=0.3".into(),
            Bsdf::Plastic(plastic(coat_roughness()[1], Some(&tables[1]))),
        ),
    ];
    // Blends (Mitsuba's blendbsdf) of some of the above: diffuse and
    // glossy, and glossy reflection with delta and glossy transmission.
    let find = |name: &str| configs.iter().find(|(n, _)| n == name).map(|(_, b)| *b).unwrap();
    let blends = [
        ("lambert", "rough conductor α=0.15", 0.3),
        (
            "classic phong s=80 + mirror + glass",
            "rough dielectric α=0.2 η=1.5",
            0.6,
        ),
    ];
    let mut all = configs.clone();
    for (a, b, weight) in blends {
        // The parts live as long as the test: leaked, as the scene's
        // integrators hold them on the stack for one shading point.
        let parts: &'a [Bsdf<'a>; 2] = Box::leak(Box::new([find(a), find(b)]));
        all.push((
            format!("blend of {a} and {b}, w={weight}"),
            Bsdf::Blend(BlendBsdf { weight, parts }),
        ));
    }
    all
}

#[test]
fn bsdf_sampling_matches_the_density() {
    let tables = coat_roughness().map(|m| CoatTables::new(&m, 1.5));
    let configs = bsdfs(&tables);
    let incident = [dir(20.0, 30.0), dir(65.0, 200.0), dir(150.0, 80.0)];
    let strategies = [
        DirectionSampling::Bsdf,
        DirectionSampling::Uniform,
        DirectionSampling::Cosine,
    ];
    let tests = configs.len() * incident.len() * strategies.len();
    let alpha = sidak_alpha(0.01, tests);
    let mode = TransportMode::Radiance;
    let mut seed = 0;
    for (name, bsdf) in &configs {
        for &wo in &incident {
            for strategy in strategies {
                seed += 1;
                let mut r = Pcg32::new(seed, 0);
                let mut deltas = 0u64;
                let sample_pdf = |wi: Vec3| -> f64 {
                    match strategy {
                        DirectionSampling::Bsdf => bsdf.pdf(wo, wi) as f64,
                        _ => {
                            // The strategies' densities, for the non-delta share.
                            let p_smooth = 1.0 - bsdf.delta_probability(wo);
                            let base = if bsdf.has_smooth_transmission() {
                                match strategy {
                                    DirectionSampling::Uniform => 1.0 / (4.0 * PI),
                                    _ => 0.5 * wi.z.abs() / PI,
                                }
                            } else if wi.z * wo.z > 0.0 {
                                match strategy {
                                    DirectionSampling::Uniform => 1.0 / (2.0 * PI),
                                    _ => wi.z.abs() / PI,
                                }
                            } else {
                                0.0
                            };
                            (p_smooth * base) as f64
                        }
                    }
                };
                let result = Chi2Test::default().run(
                    |_| {
                        let s =
                            bsdf.sample_with(strategy, wo, r.next_f32(), Vec2::new(r.next_f32(), r.next_f32()), mode)?;
                        if s.delta {
                            deltas += 1;
                            return None;
                        }
                        // The sample agrees with eval and pdf.
                        let f = bsdf.eval(wo, s.wi, mode);
                        assert!(
                            (s.f - f).abs().max_element() <= 1e-3 * f.max_element().max(1e-3),
                            "{name}: f {} vs eval {f}",
                            s.f
                        );
                        let p = sample_pdf(s.wi) as f32;
                        assert!(
                            (s.pdf - p).abs() <= 1e-3 * p.max(1e-3),
                            "{name} {strategy:?}: pdf {} vs {p}",
                            s.pdf
                        );
                        Some(s.wi)
                    },
                    sample_pdf,
                );
                assert!(
                    result.p_value > alpha,
                    "{name}, wo = {wo}, {strategy:?}: χ² = {:.1} with {} dof, p = {:.2e}",
                    result.statistic,
                    result.dof,
                    result.p_value
                );
                // The density accounts for all non-delta samples: it
                // integrates to 1 minus the delta lobes' share (up to what
                // a lobe loses below the horizon, which is never sampled).
                let n = Chi2Test::default().samples as f64;
                let smooth_share = 1.0 - deltas as f64 / n;
                assert!(
                    result.expected_total / n <= smooth_share + 0.01,
                    "{name}: ∫pdf = {} > {smooth_share}",
                    result.expected_total / n
                );
                assert!(
                    (result.expected_total - result.counted as f64).abs() <= 0.01 * n,
                    "{name}, {strategy:?}: ∫pdf·N = {:.0} but {} samples",
                    result.expected_total,
                    result.counted
                );
            }
        }
    }
}

/// The density integrates, over the whole sphere, to the share of draws
/// that the sampler returns as non-delta directions: 1 for Lambert, less
/// by the delta lobes' share, and less by whatever a lobe would send below
/// the horizon (such draws are discarded, never returned with a wrong
/// density). No probability is lost or invented.
#[test]
fn densities_integrate_to_the_share_of_returned_samples() {
    let tables = coat_roughness().map(|m| CoatTables::new(&m, 1.5));
    let mode = TransportMode::Radiance;
    for (name, bsdf) in bsdfs(&tables) {
        for wo in [dir(35.0, 10.0), dir(70.0, 100.0), dir(120.0, 250.0)] {
            let (nt, np) = (600, 300);
            let mut sum = 0.0f64;
            for i in 0..nt {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / nt as f64;
                let r = (1.0 - z * z).sqrt();
                for j in 0..np {
                    let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / np as f64;
                    let wi = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                    sum += bsdf.pdf(wo, wi) as f64;
                }
            }
            let integral = sum * 4.0 * std::f64::consts::PI / (nt * np) as f64;
            let mut rng = Pcg32::new(99, 1);
            let n = 400_000;
            let returned = (0..n)
                .filter(|_| {
                    bsdf.sample(wo, rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()), mode)
                        .is_some_and(|s| !s.delta)
                })
                .count() as f64
                / n as f64;
            // Binomial noise (4σ) plus the quadrature's error on peaked lobes.
            let tol = 4.0 * (returned * (1.0 - returned) / n as f64).sqrt() + 0.01;
            assert!(integral <= 1.0 + 0.01, "{name}: ∫pdf = {integral}");
            assert!(
                (integral - returned).abs() < tol,
                "{name}, wo {wo}: ∫pdf = {integral}, returned {returned}"
            );
            if name == "lambert" {
                assert!((integral - 1.0).abs() < 0.002, "{integral}");
            }
        }
    }
}

/// A scene whose only geometry is one emitter, and that emitter's light.
fn light_scene(shape: ShapeDesc) -> trazo::scene::Scene {
    let mut d = SceneDesc::default();
    let mut m = MaterialDesc::new("glow");
    m.emission = ColorSource::Rgb(Rgb::splat(2.0));
    d.materials.push(m);
    let mut shape = shape;
    shape.material = Some("glow".into());
    d.shapes.push(shape);
    trazo::scene::build(&d).unwrap()
}

fn check_light(name: &str, scene: &trazo::scene::Scene, p: Vec3, alpha: f64) {
    check_light_density(name, scene, p, alpha, false);
}

/// [`check_light`], with the environment's compensated density if
/// `incomplete`.
fn check_light_density(name: &str, scene: &trazo::scene::Scene, p: Vec3, alpha: f64, incomplete: bool) {
    let light = &scene.lights[0];
    let mut r = Pcg32::new(name.len() as u64, 3);
    let result = Chi2Test {
        samples: 100_000,
        ..Chi2Test::default()
    }
    .run(
        |_| {
            let s = light.sample_li(
                scene,
                p,
                r.next_f32(),
                Vec2::new(r.next_f32(), r.next_f32()),
                incomplete,
            )?;
            Some(s.wi)
        },
        |d| {
            if let Light::Environment = light {
                return light.pdf_environment(scene, p, d, incomplete) as f64;
            }
            let ray = trazo::geometry::Ray::new(p, d);
            match scene.intersect(&ray) {
                Some(hit) if hit.is_front(-d) => light.pdf_li(scene, p, &hit) as f64,
                _ => 0.0,
            }
        },
    );
    assert!(
        result.p_value > alpha,
        "{name}: χ² = {:.1}, dof {}, p = {:.2e}",
        result.statistic,
        result.dof,
        result.p_value
    );
    assert!(
        (result.expected_total - result.counted as f64).abs() < 0.02 * result.counted as f64 + 50.0,
        "{name}: ∫pdf·N = {:.0}, samples {}",
        result.expected_total,
        result.counted
    );
}

#[test]
fn light_sampling_matches_the_density() {
    let alpha = sidak_alpha(0.01, 7);
    let p = Vec3::new(0.1, -0.2, 0.05);
    let sphere = ShapeKind::Sphere {
        center: Vec3::new(0.3, 0.2, 1.5),
        radius: 0.6,
    };
    check_light(
        "sphere (cone sampling)",
        &light_scene(ShapeDesc::new(sphere, None)),
        p,
        alpha,
    );
    // A disk sheared and unevenly scaled into a tilted ellipse: area
    // sampling through the transform's area scaling. (A curved shape under
    // such a transform is sampled the same way, but its solid-angle density
    // diverges at the silhouette, which no fixed quadrature integrates well.)
    check_light(
        "sheared, scaled disk (area sampling under a transform)",
        &light_scene(
            ShapeDesc::new(
                ShapeKind::Disk {
                    center: Vec3::ZERO,
                    normal: -Vec3::Z,
                    radius: 0.7,
                    uv: trazo::geometry::DiskUv::AngleRadius,
                },
                None,
            )
            .with(TransformOp::Scale(Vec3::new(1.6, 0.6, 1.0)))
            .with(TransformOp::Shear {
                xy: 0.0,
                xz: 0.0,
                yx: 0.4,
                yz: 0.0,
                zx: 0.3,
                zy: 0.0,
            })
            .with(TransformOp::Translate(Vec3::new(0.2, 0.0, 1.3))),
        ),
        p,
        alpha,
    );
    check_light(
        "rectangle",
        &light_scene(ShapeDesc::new(
            ShapeKind::Rectangle {
                corner: Vec3::new(-1.0, -0.5, 1.0),
                edge_u: Vec3::new(2.0, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 1.0, 0.3),
            },
            None,
        )),
        p,
        alpha,
    );
    check_light(
        "disk",
        &light_scene(ShapeDesc::new(
            ShapeKind::Disk {
                center: Vec3::new(0.0, 0.0, 1.0),
                normal: Vec3::new(0.2, 0.1, -1.0),
                radius: 0.8,
                uv: trazo::geometry::DiskUv::AngleRadius,
            },
            None,
        )),
        p,
        alpha,
    );
    // A bumpy 4×4 grid of triangles of unequal areas, facing p (a curved
    // mesh seen edge-on has the silhouette problem described above).
    let mut mesh = trazo::geometry::TriangleMesh::default();
    for j in 0..5 {
        for i in 0..5 {
            let (x, y) = (i as f32 * 0.4 - 0.8, j as f32 * 0.3 - 0.6);
            mesh.positions.push(Vec3::new(
                x + 0.1 * (j as f32).sin(),
                y,
                1.2 + 0.15 * ((i * j) % 3) as f32,
            ));
        }
    }
    for j in 0..4u32 {
        for i in 0..4u32 {
            let a = j * 5 + i;
            mesh.indices.push([a, a + 6, a + 1]);
            mesh.indices.push([a, a + 5, a + 6]);
        }
    }
    check_light(
        "triangle mesh",
        &light_scene(ShapeDesc::new(ShapeKind::InlineMesh(MeshSource::Inline(mesh)), None)),
        p,
        alpha,
    );
    check_light(
        "box (area sampling, faces of different size)",
        &light_scene(ShapeDesc::new(
            ShapeKind::Cuboid {
                min: Vec3::new(-0.3, -0.6, 1.0),
                max: Vec3::new(0.5, 0.1, 1.4),
            },
            None,
        )),
        p,
        alpha,
    );
    // An environment map with a bright spot.
    let mut scene = light_scene(ShapeDesc::new(
        ShapeKind::Sphere {
            center: Vec3::new(0.0, 0.0, 100.0),
            radius: 0.01,
        },
        None,
    ));
    let (w, h) = (32u32, 16u32);
    let mut pixels = vec![Rgb::splat(0.2); (w * h) as usize];
    for (i, px) in pixels.iter_mut().enumerate() {
        if i % 37 == 3 {
            *px = Rgb::new(30.0, 20.0, 10.0);
        }
    }
    scene.background = Background::Image(Box::new(EnvironmentMap::new(
        ImageTexture {
            width: w,
            height: h,
            pixels,
        },
        1.0,
        trazo::geometry::Transform::rotate(Vec3::X, 25.0).unwrap(),
    )));
    scene.lights = vec![Light::Environment];
    check_light("environment map", &scene, p, alpha);
    // Its compensated density (for MIS): the spots alone.
    check_light_density("environment map, compensated", &scene, p, alpha, true);
}
