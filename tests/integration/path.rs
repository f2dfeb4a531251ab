//! The path tracer against answers known in advance: white furnaces,
//! closed-form irradiance, agreement of its four estimators, determinism.
//! Tolerances come from the per-pixel variance that each render measures,
//! not from a lucky run.

use trazo::color::{Rgb, luminance};
use trazo::film::Film;
use trazo::render::{RenderOptions, render};
use trazo::scene::builtin::cornell_box;
use trazo::scene::desc::*;
use trazo::settings::{IntegratorKind, PathSampling};
use trazo::{Vec2, Vec3};

pub(crate) fn render_film(d: &SceneDesc) -> Film {
    let scene = trazo::scene::build(d).unwrap();
    render(&scene, &RenderOptions::default()).unwrap().film
}

/// Mean luminance of the image and the standard error of that mean.
pub(crate) fn mean_and_error(f: &Film) -> (f64, f64) {
    let n = f.pixels.len() as f64;
    let mean = f.pixels.iter().map(|p| luminance(p.value()) as f64).sum::<f64>() / n;
    let var: f64 = f.pixels.iter().map(|p| p.variance_of_mean()).sum::<f64>() / (n * n);
    (mean, var.sqrt())
}

fn furnace(material: MaterialDesc, sampling: PathSampling) -> SceneDesc {
    let mut d = SceneDesc::default();
    d.settings.width = 16;
    d.settings.height = 16;
    d.settings.spp = 64;
    d.settings.max_depth = 64;
    d.settings.integrator = IntegratorKind::Path;
    d.settings.sampling = sampling;
    d.camera.from = Vec3::new(0.0, 0.0, 4.0);
    d.camera.projection = ProjectionDesc::Perspective { fov: 25.0 };
    d.background = BackgroundDesc::Constant(Rgb::ONE);
    let name = material.name.clone();
    d.materials.push(material);
    d.shapes.push(ShapeDesc::new(
        ShapeKind::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        },
        Some(&name),
    ));
    d
}

fn diffuse(albedo: f32) -> MaterialDesc {
    MaterialDesc::with_kind(
        "diffuse",
        MaterialKindDesc::Diffuse {
            reflectance: ColorSource::Rgb(Rgb::splat(albedo)),
        },
    )
}

/// Smooth glass of index 1.5 in air, named "glass".
fn smooth_glass() -> MaterialDesc {
    MaterialDesc::with_kind(
        "glass",
        MaterialKindDesc::Dielectric {
            ior: 1.5,
            ext_ior: 1.0,
            roughness: (0.0, 0.0),
            distribution: MicrofacetDistribution::Ggx,
            reflect_tint: Rgb::ONE,
            transmit_tint: Rgb::ONE,
            dispersion: None,
        },
    )
}

/// The plane y = 0 of material "diffuse".
fn diffuse_floor() -> ShapeDesc {
    ShapeDesc::new(
        ShapeKind::Plane {
            point: Vec3::ZERO,
            normal: Vec3::Y,
        },
        Some("diffuse"),
    )
}

/// Every pixel is `expect` within 5 of its own standard errors (plus a
/// rounding allowance), and the image mean within 4 standard errors.
fn assert_uniform(f: &Film, expect: f32, what: &str) {
    for (i, p) in f.pixels.iter().enumerate() {
        let v = p.value();
        let sigma = p.variance_of_mean().sqrt() as f32;
        for c in [v.x, v.y, v.z] {
            assert!(
                (c - expect).abs() <= 5.0 * sigma + 1e-4,
                "{what}: pixel {i} = {v}, expected {expect} ± {sigma}"
            );
        }
    }
    let (mean, err) = mean_and_error(f);
    assert!(
        (mean - expect as f64).abs() <= 4.0 * err + 1e-5,
        "{what}: mean {mean} ± {err}, expected {expect}"
    );
}

#[test]
fn white_furnace_lambertian_albedo_one_renders_one() {
    for sampling in [
        PathSampling::Mis,
        PathSampling::Nee,
        PathSampling::NeeUniform,
        PathSampling::Bsdf,
        PathSampling::Cosine,
        PathSampling::Uniform,
    ] {
        let f = render_film(&furnace(diffuse(1.0), sampling));
        assert_uniform(&f, 1.0, &format!("albedo 1, {}", sampling.name()));
    }
}

/// Every pixel entirely on the furnace's sphere (all its samples hit it)
/// is `expect` within 5 of its standard errors: those of a sample's
/// standard deviation `sample_sd` where the estimator's is known, else
/// the pixel's own estimate.
fn assert_sphere_pixels(d: &SceneDesc, expect: f32, sample_sd: Option<f32>, what: &str) {
    let f = render_film(d);
    let scene = trazo::scene::build(d).unwrap();
    let mut on_sphere = 0;
    for y in 0..16 {
        for x in 0..16 {
            let corners_hit = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)]
                .iter()
                .all(|(dx, dy)| {
                    let r = scene
                        .camera
                        .generate_ray(trazo::Vec2::new(x as f32 + dx, y as f32 + dy), trazo::Vec2::ZERO);
                    scene.intersect(&r).is_some()
                });
            if corners_hit {
                on_sphere += 1;
                let p = f.pixels[(y * 16 + x) as usize];
                let sigma = match sample_sd {
                    Some(sd) => sd / (d.settings.spp as f32).sqrt(),
                    None => p.variance_of_mean().sqrt() as f32,
                };
                let v = p.value();
                assert!(
                    (v.x - expect).abs() <= 5.0 * sigma + 1e-4,
                    "{what}: pixel ({x},{y}) = {v} ± {sigma}, expected {expect}"
                );
            }
        }
    }
    assert!(on_sphere > 50, "{on_sphere}");
}

#[test]
fn convex_lambertian_of_albedo_rho_renders_rho() {
    // Pixels that miss the sphere see the background (1); the others ρ.
    assert_sphere_pixels(&furnace(diffuse(0.5), PathSampling::Mis), 0.5, None, "albedo 0.5");
}

/// A mix chooses its second material with the weight's probability: on a
/// convex sphere in a white furnace it renders (1 − w)·ρ₀ + w·ρ₁.
#[test]
fn a_mix_of_two_lambertians_renders_their_weighted_albedo() {
    let mix = MaterialDesc::with_kind(
        "mix",
        MaterialKindDesc::Mix {
            choice: MixChoice::Weight(ColorSource::Rgb(Rgb::splat(0.25))),
            materials: ["dark".into(), "light".into()],
        },
    );
    let mut d = furnace(mix, PathSampling::Mis);
    for (name, albedo) in [("dark", 0.2), ("light", 0.8)] {
        let mut m = diffuse(albedo);
        m.name = name.into();
        d.materials.push(m);
    }
    // Each sample sees one of the two (its light leaves the convex sphere
    // for the furnace): 0.2 with probability 3/4, 0.8 with 1/4, whose
    // variance is 0.0675. (A pixel's own variance from 64 such samples
    // is too unsteady a measure: few bright samples make it small.)
    assert_sphere_pixels(&d, 0.75 * 0.2 + 0.25 * 0.8, Some(0.0675f32.sqrt()), "mix");
}

#[test]
fn white_furnace_smooth_glass_renders_one() {
    let f = render_film(&furnace(smooth_glass(), PathSampling::Mis));
    assert_uniform(&f, 1.0, "smooth dielectric");
}

/// Where the depth bounds the paths, Russian roulette puts no path at risk
/// whose weight (refraction's radiance scaling undone) is still one, as in
/// pbrt-v4: in a white furnace every path through smooth glass then
/// brings back exactly the furnace's radiance, so that every sample of
/// every pixel is one, up to rounding. (Mitsuba's survival probability,
/// capped at 0.95, ends some of those paths and weighs the others above
/// one: a pixel of 64 samples that loses one is off by 1/64.)
#[test]
fn russian_roulette_spares_paths_of_weight_one_where_the_depth_is_bounded() {
    let mut d = furnace(smooth_glass(), PathSampling::Mis);
    d.settings.rr_depth = 1;
    let f = render_film(&d);
    for (i, p) in f.pixels.iter().enumerate() {
        let v = p.value();
        assert!((v - Rgb::ONE).abs().max_element() < 1e-5, "pixel {i} = {v}");
    }
}

/// Where the depth is unbounded (Mitsuba's `max_depth` −1), nothing else
/// ends a path that keeps its weight: Russian roulette's survival
/// probability is then capped at Mitsuba's 0.95, so that paths in a closed
/// room of albedo one (the camera inside the furnace's sphere, grown) end
/// after about 1/0.05 = 20 segments past `rr_depth`, not at the bound of
/// 1024 segments.
#[test]
fn russian_roulette_ends_paths_of_weight_one_where_the_depth_is_unbounded() {
    let mut d = furnace(diffuse(1.0), PathSampling::Mis);
    d.settings.max_depth = trazo::settings::MAX_DEPTH;
    d.settings.spp = 16;
    d.shapes[0].kind = ShapeKind::Sphere {
        center: Vec3::ZERO,
        radius: 10.0,
    };
    let scene = trazo::scene::build(&d).unwrap();
    let out = render(&scene, &RenderOptions::default()).unwrap();
    // No light gets in.
    assert!(out.film.pixels.iter().all(|p| p.value() == Rgb::ZERO));
    // A ray a segment for about rr_depth + 20 segments (a shadow ray
    // only where the light's sample is not black); 1024 without the cap.
    let rays_per_sample = out.stats.rays as f64 / out.stats.samples as f64;
    assert!(rays_per_sample < 100.0, "{rays_per_sample} rays a sample");
}

#[test]
fn white_furnace_rough_glass_and_mirror_conserve_energy() {
    // A perfect mirror reflects all light.
    let mirror = MaterialDesc::with_kind(
        "mirror",
        MaterialKindDesc::Conductor {
            fresnel: ConductorDesc::Mirror(Rgb::ONE),
            tint: Rgb::ONE,
            roughness: (0.0, 0.0),
            distribution: MicrofacetDistribution::Ggx,
        },
    );
    assert_uniform(&render_film(&furnace(mirror, PathSampling::Mis)), 1.0, "mirror");
    // Rough glass never creates energy, and loses only what single-
    // scattering microfacet models lose (light that a microfacet sends
    // back through the surface, most of all after total internal
    // reflection inside): almost nothing when nearly smooth, more as the
    // roughness grows.
    let rough = |alpha: f32| {
        let m = MaterialDesc::with_kind(
            "rough",
            MaterialKindDesc::Dielectric {
                ior: 1.5,
                ext_ior: 1.0,
                roughness: (alpha, alpha),
                distribution: MicrofacetDistribution::Ggx,
                reflect_tint: Rgb::ONE,
                transmit_tint: Rgb::ONE,
                dispersion: None,
            },
        );
        mean_and_error(&render_film(&furnace(m, PathSampling::Mis)))
    };
    let (nearly_smooth, e1) = rough(0.01);
    let (medium, e2) = rough(0.1);
    let (very, e3) = rough(0.4);
    assert!(
        nearly_smooth <= 1.0 + 4.0 * e1 && nearly_smooth > 0.99,
        "α = 0.01: {nearly_smooth} ± {e1}"
    );
    assert!(
        medium <= 1.0 + 4.0 * e2 && medium < nearly_smooth + 4.0 * e1,
        "α = 0.1: {medium} ± {e2}"
    );
    assert!(
        very < medium,
        "α = 0.4: {very} ± {e3} should lose more than α = 0.1: {medium}"
    );
}

/// A diffuse plane of albedo ρ under a sphere light of radiance Le and
/// radius r at height h: straight below it the irradiance is
/// E = π·Le·(r/h)², so the plane's radiance is ρ·Le·(r/h)².
#[test]
fn sphere_light_over_a_plane_matches_the_closed_form() {
    let (rho, le, r, h) = (0.6f32, 5.0f32, 0.5f32, 2.0f32);
    let expect = rho * le * (r / h) * (r / h);
    for (sampling, spp) in [
        (PathSampling::Mis, 64),
        (PathSampling::Nee, 64),
        (PathSampling::NeeUniform, 64),
        (PathSampling::Bsdf, 1024),
        (PathSampling::Cosine, 1024),
        (PathSampling::Uniform, 2048),
    ] {
        let mut d = SceneDesc::default();
        d.settings.width = 4;
        d.settings.height = 4;
        d.settings.spp = spp;
        d.settings.max_depth = 2;
        d.settings.integrator = IntegratorKind::Path;
        d.settings.sampling = sampling;
        // Look at the point below the light from the side, through a tiny
        // orthographic window, past the light.
        d.camera = CameraDesc {
            projection: ProjectionDesc::Orthographic { size: 1e-4 },
            from: Vec3::new(3.0, 3.0, 0.0),
            to: Vec3::ZERO,
            up: Vec3::Y,
            ..CameraDesc::default()
        };
        d.materials.push(diffuse(rho));
        let mut lamp = diffuse(0.0);
        lamp.name = "lamp".into();
        lamp.emission = ColorSource::Rgb(Rgb::splat(le));
        d.materials.push(lamp);
        d.shapes.push(diffuse_floor());
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Sphere {
                center: Vec3::new(0.0, h, 0.0),
                radius: r,
            },
            Some("lamp"),
        ));
        let f = render_film(&d);
        let (mean, err) = mean_and_error(&f);
        assert!(
            (mean - expect as f64).abs() <= 4.0 * err + 1e-5,
            "{}: {mean} ± {err}, expected {expect}",
            sampling.name()
        );
    }
}

/// A diffuse plane under a uniform sky of radiance L receives E = π·L and
/// reflects ρ·L (found by BSDF sampling alone: a constant sky's compensated
/// density is zero, so next-event estimation draws nothing from it).
#[test]
fn plane_under_a_uniform_sky() {
    let mut d = SceneDesc::default();
    d.settings.width = 4;
    d.settings.height = 4;
    d.settings.spp = 256;
    d.settings.max_depth = 2;
    d.settings.integrator = IntegratorKind::Path;
    d.camera = CameraDesc {
        projection: ProjectionDesc::Orthographic { size: 1.0 },
        from: Vec3::new(0.0, 5.0, 0.0),
        to: Vec3::ZERO,
        up: Vec3::Z,
        ..CameraDesc::default()
    };
    d.background = BackgroundDesc::Constant(Rgb::splat(2.0));
    d.materials.push(diffuse(0.3));
    d.shapes.push(diffuse_floor());
    let f = render_film(&d);
    let (mean, err) = mean_and_error(&f);
    assert!((mean - 0.6).abs() <= 4.0 * err + 1e-5, "{mean} ± {err}");
}

/// Under an environment image with a sun, MIS, whose light samples come
/// from the image's compensated density (only what is brighter than its
/// mean, pbrt-v4's `allowIncompletePDF`), converges to what BSDF sampling
/// alone does, and with less variance: the part the light samples leave
/// out is found by BSDF samples at full weight. So does the volumetric
/// path tracer's MIS. (Weighing BSDF samples that meet the sky by the
/// full density instead makes the image 7 % dark, z ≈ −10.)
#[test]
fn mis_with_a_compensated_sky_agrees_with_bsdf_sampling() {
    let dir = tempfile::tempdir().unwrap();
    let sky = dir.path().join("sky.pfm");
    // 32 × 16, latitude–longitude: brighter toward the zenith, a sun of
    // 2 × 2 pixels at 20 on row 4 (about 50° from the zenith).
    crate::pbrt::write_pfm(&sky, 32, 16, |col, row| {
        if (4..6).contains(&row) && (10..12).contains(&col) {
            [20.0, 18.0, 15.0]
        } else {
            let t = 1.0 - row as f32 / 15.0;
            [0.2 + 0.6 * t, 0.3 + 0.6 * t, 0.5 + 0.5 * t]
        }
    });
    let scene = |integrator: IntegratorKind, sampling: PathSampling, spp: u32| {
        let mut d = sky_test_scene(integrator, sampling, spp);
        d.background = BackgroundDesc::Image {
            path: sky.clone(),
            scale: 1.0,
            transform: Vec::new(),
            layout: EnvironmentLayout::LatLong,
            illuminance: None,
        };
        d.materials.push(diffuse(0.5));
        d.shapes.push(diffuse_floor());
        // A ball that shades the plane and reflects the sky onto it.
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Sphere {
                center: Vec3::new(0.3, 0.6, -0.2),
                radius: 0.6,
            },
            Some("diffuse"),
        ));
        d
    };
    let bsdf = render_film(&scene(IntegratorKind::Path, PathSampling::Bsdf, 2048));
    for integrator in [IntegratorKind::Path, IntegratorKind::VolPath] {
        let mis = render_film(&scene(integrator, PathSampling::Mis, 256));
        assert_mis_agrees_with_bsdf_sampling(&mis, &bsdf, &format!("{integrator:?}"));
    }
}

/// The two sky tests' 6 × 6 image, three segments deep, seen from above by
/// an orthographic camera; each adds its sky, materials and shapes.
fn sky_test_scene(integrator: IntegratorKind, sampling: PathSampling, spp: u32) -> SceneDesc {
    let mut d = SceneDesc::default();
    d.settings.width = 6;
    d.settings.height = 6;
    d.settings.spp = spp;
    d.settings.max_depth = 3;
    d.settings.integrator = integrator;
    d.settings.sampling = sampling;
    d.camera = CameraDesc {
        projection: ProjectionDesc::Orthographic { size: 3.0 },
        from: Vec3::new(0.0, 5.0, 0.0),
        to: Vec3::ZERO,
        up: Vec3::Z,
        ..CameraDesc::default()
    };
    d
}

/// `mis` agrees with `bsdf` (BSDF sampling alone) in the image mean within
/// 5 standard errors and pixel by pixel (mean squared z below 2), and is
/// less noisy per sample.
fn assert_mis_agrees_with_bsdf_sampling(mis: &Film, bsdf: &Film, what: &str) {
    let ((a, ea), (b, eb)) = (mean_and_error(mis), mean_and_error(bsdf));
    assert!(
        (a - b).abs() <= 5.0 * (ea * ea + eb * eb).sqrt(),
        "{what}: MIS {a} ± {ea}, BSDF sampling {b} ± {eb}"
    );
    let z2 = mis
        .pixels
        .iter()
        .zip(&bsdf.pixels)
        .map(|(p, q)| {
            let d = luminance(p.value()) as f64 - luminance(q.value()) as f64;
            // (Pixels that see only an emitter have no variance.)
            d * d / (p.variance_of_mean() + q.variance_of_mean()).max(1e-12)
        })
        .sum::<f64>()
        / mis.pixels.len() as f64;
    assert!(z2 < 2.0, "{what}: mean z² {z2}");
    assert!(
        per_sample_variance(mis) < per_sample_variance(bsdf),
        "{what}: MIS no less noisy than BSDF sampling"
    );
}

/// Under a constant sky and a small lamp, next-event estimation draws no
/// light from the sky (its compensated density is zero, as pbrt-v4's
/// uniform infinite light with `allowIncompletePDF`) and gives the sky's
/// share of light choices to the lamp; BSDF samples that reach the sky
/// count at full weight. path:mis and volpath agree with BSDF sampling
/// alone, pixel by pixel, and are less noisy. (Weighing sky hits against
/// the sky's full density, or the lamp's samples by the choice that still
/// included the sky, biases the image by several per cent.)
#[test]
fn a_constant_sky_is_left_to_bsdf_sampling_and_its_light_choices_to_the_lamp() {
    let scene = |integrator: IntegratorKind, sampling: PathSampling, spp: u32| {
        let mut d = sky_test_scene(integrator, sampling, spp);
        d.background = BackgroundDesc::Constant(Rgb::new(0.1, 0.12, 0.15));
        d.materials.push(diffuse(0.5));
        let mut lamp = diffuse(0.0);
        lamp.name = "lamp".into();
        lamp.emission = ColorSource::Rgb(Rgb::splat(4.0));
        d.materials.push(lamp);
        d.shapes.push(diffuse_floor());
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Sphere {
                center: Vec3::new(0.3, 0.6, -0.2),
                radius: 0.6,
            },
            Some("diffuse"),
        ));
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Sphere {
                center: Vec3::new(-2.5, 1.2, 0.0),
                radius: 0.9,
            },
            Some("lamp"),
        ));
        d
    };
    let bsdf = render_film(&scene(IntegratorKind::Path, PathSampling::Bsdf, 16384));
    for integrator in [IntegratorKind::Path, IntegratorKind::VolPath] {
        let mis = render_film(&scene(integrator, PathSampling::Mis, 2048));
        assert_mis_agrees_with_bsdf_sampling(&mis, &bsdf, &format!("{integrator:?}"));
    }
}

fn small_cornell(sampling: PathSampling, spp: u32) -> Film {
    let mut d = cornell_box();
    d.settings.width = 20;
    d.settings.height = 20;
    d.settings.spp = spp;
    d.settings.integrator = IntegratorKind::Path;
    d.settings.sampling = sampling;
    render_film(&d)
}

/// Mean per-pixel variance of a single sample's luminance.
fn per_sample_variance(f: &Film) -> f64 {
    f.pixels.iter().map(|p| p.variance_of_mean() * p.weight()).sum::<f64>() / f.pixels.len() as f64
}

/// All six estimators converge to the same image; MIS has the lowest
/// variance of the first four, the textbook uniform estimator the highest,
/// and next-event estimation, with or without MIS, beats hits alone.
#[test]
fn estimators_agree_on_the_cornell_box_and_mis_is_best() {
    let runs: Vec<(PathSampling, Film)> = [
        (PathSampling::Mis, 64),
        (PathSampling::Bsdf, 512),
        (PathSampling::Cosine, 512),
        (PathSampling::Uniform, 512),
        (PathSampling::Nee, 64),
        (PathSampling::NeeUniform, 128),
    ]
    .into_iter()
    .map(|(s, spp)| (s, small_cornell(s, spp)))
    .collect();
    let (m0, e0) = mean_and_error(&runs[0].1);
    for (s, f) in &runs[1..] {
        let (m, e) = mean_and_error(f);
        let tol = 4.0 * (e0 * e0 + e * e).sqrt();
        assert!((m - m0).abs() <= tol, "{} mean {m} ± {e} vs mis {m0} ± {e0}", s.name());
    }
    let v: Vec<f64> = runs.iter().map(|(_, f)| per_sample_variance(f)).collect();
    assert!(
        v[0] < v[1] && v[0] < v[2] && v[0] < v[3],
        "variances mis/bsdf/cosine/uniform/nee/nee-uniform: {v:?}"
    );
    assert!(v[2] < v[3], "cosine beats uniform on diffuse walls: {v:?}");
    assert!(v[4] < v[1] && v[5] < v[3], "light sampling beats hits alone: {v:?}");
}

#[test]
fn path_tracing_is_deterministic_across_thread_counts() {
    let mut d = cornell_box();
    d.settings.width = 24;
    d.settings.height = 24;
    d.settings.spp = 4;
    d.settings.integrator = IntegratorKind::Path;
    let scene = trazo::scene::build(&d).unwrap();
    let run = |threads| {
        render(
            &scene,
            &RenderOptions {
                threads: Some(threads),
                ..RenderOptions::default()
            },
        )
        .unwrap()
        .film
    };
    assert_eq!(run(1), run(2));
    assert_eq!(run(1), run(3));
}

/// Point, spot and directional lights light a diffuse plane as the
/// formulas say: E = I cos θ / d² for a point light, E for a directional one.
#[test]
fn delta_lights_in_the_path_tracer() {
    let plane = |light: LightKind| {
        let mut d = SceneDesc::default();
        d.settings.width = 2;
        d.settings.height = 2;
        d.settings.spp = 16;
        d.settings.max_depth = 2;
        d.settings.integrator = IntegratorKind::Path;
        d.camera = CameraDesc {
            projection: ProjectionDesc::Orthographic { size: 1e-4 },
            from: Vec3::new(0.0, 5.0, 0.001),
            to: Vec3::ZERO,
            up: Vec3::Z,
            ..CameraDesc::default()
        };
        d.materials.push(diffuse(0.5));
        d.lights.push(LightDesc::new(light));
        d.shapes.push(diffuse_floor());
        let (mean, _) = mean_and_error(&render_film(&d));
        mean as f32
    };
    let pi = std::f32::consts::PI;
    let point = plane(LightKind::Point {
        position: Vec3::new(1.0, 2.0, 0.0),
        intensity: Rgb::splat(10.0),
        falloff: true,
    });
    let cos = 2.0 / 5f32.sqrt();
    assert!((point - 0.5 / pi * 10.0 * cos / 5.0).abs() < 1e-4, "{point}");
    let sun = plane(LightKind::Directional {
        direction: Vec3::new(0.0, -1.0, -1.0),
        irradiance: Rgb::splat(3.0),
    });
    assert!(
        (sun - 0.5 / pi * 3.0 * std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-4,
        "{sun}"
    );
    let spot = plane(LightKind::Spot {
        position: Vec3::new(0.0, 2.0, 0.0),
        to: Vec3::ZERO,
        intensity: Rgb::splat(8.0),
        inner_angle: 10.0,
        outer_angle: 20.0,
        profile: trazo::light::SpotProfile::SmoothStepInCosine,
        projection: None,
        falloff: true,
    });
    assert!((spot - 0.5 / pi * 8.0 / 4.0).abs() < 1e-4, "{spot}");
}

/// The Cornell box with its light replaced by a 6 × 6 grid of small lights
/// of different colours and powers just below the ceiling, and a dim sky
/// seen through nothing (it lights only the camera's misses; it makes the
/// light choice split between the tree and the unbounded lights).
fn many_lights_cornell(sampling: PathSampling, spp: u32) -> Film {
    let mut d = cornell_box();
    d.settings.width = 16;
    d.settings.height = 16;
    d.settings.spp = spp;
    d.settings.integrator = IntegratorKind::Path;
    d.settings.sampling = sampling;
    d.shapes.retain(|s| s.material.as_deref() != Some("light"));
    for k in 0..36 {
        let (i, j) = ((k % 6) as f32, (k / 6) as f32);
        let name = format!("lamp{k}");
        let mut m = diffuse(0.0);
        m.name = name.clone();
        let power = 20.0 + 60.0 * ((k * 7) % 5) as f32;
        m.emission = ColorSource::Rgb(Rgb::new(power, power * (0.5 + 0.1 * (k % 5) as f32), power * 0.6));
        d.materials.push(m);
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Rectangle {
                corner: Vec3::new(-0.85 + 0.3 * i, 0.99, -0.85 + 0.3 * j),
                edge_u: Vec3::new(0.08, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, 0.08),
            },
            Some(&name),
        ));
    }
    d.background = BackgroundDesc::Constant(Rgb::splat(0.05));
    render_film(&d)
}

/// Next-event estimation through the light tree converges to what BSDF
/// sampling alone (which never consults the tree) converges to, so the
/// tree's choice probabilities and the MIS weights built from them are
/// right; and it has far lower variance.
#[test]
fn many_lights_nee_through_the_light_tree_agrees_with_bsdf_sampling() {
    let mis = many_lights_cornell(PathSampling::Mis, 256);
    let bsdf = many_lights_cornell(PathSampling::Bsdf, 2048);
    let (m0, e0) = mean_and_error(&mis);
    let (m1, e1) = mean_and_error(&bsdf);
    let tol = 4.0 * (e0 * e0 + e1 * e1).sqrt();
    assert!((m0 - m1).abs() <= tol, "mis {m0} ± {e0} vs bsdf {m1} ± {e1}");
    // Over the pixels that see walls, not lamps: a camera ray's chance of
    // hitting a lamp is the same noise for both estimators.
    let wall_variance = |f: &Film| {
        let walls: Vec<_> = f.pixels.iter().filter(|p| luminance(p.value()) < 2.0).collect();
        walls.iter().map(|p| p.variance_of_mean() * p.weight()).sum::<f64>() / walls.len() as f64
    };
    let (v0, v1) = (wall_variance(&mis), wall_variance(&bsdf));
    assert!(
        v0 * 10.0 < v1,
        "per-sample variance on the walls: mis {v0} vs bsdf {v1}"
    );
}

/// An ASCII PLY sphere of radius 0.5 at the origin, of `rings` × `segments`
/// quads split into triangles.
fn uv_sphere_ply(rings: u32, segments: u32) -> String {
    let mut vertices = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            let p = 0.5 * Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            vertices.push(format!("{} {} {}", p.x, p.y, p.z));
        }
    }
    let mut faces = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let (a, b) = (i * segments + j, i * segments + (j + 1) % segments);
            let (c, d) = (a + segments, b + segments);
            faces.push(format!("3 {a} {c} {b}"));
            faces.push(format!("3 {b} {c} {d}"));
        }
    }
    format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n{}\n{}\n",
        vertices.len(),
        faces.len(),
        vertices.join("\n"),
        faces.join("\n")
    )
}

/// The path tracer traces a pixel's samples eight at a time, in lanes
/// (`Integrator::radiance_lanes`, which the renderer calls): on every
/// scene of the benchmark suite, each lane's estimate has the bits of the
/// same path traced alone (`Integrator::radiance`), lanes left out
/// included.
#[test]
fn paths_traced_in_lanes_give_the_bits_of_paths_traced_alone() {
    let suite = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("bench/suite");
    let mut scenes: Vec<_> = std::fs::read_dir(&suite)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "xml"))
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 10, "the suite has its scenes");
    let defines = [
        ("res".to_string(), "12".to_string()),
        ("spp".to_string(), "8".to_string()),
    ];
    // The suite's large generated mesh (bench/suite_assets.py) is replaced
    // by a small sphere of the same role.
    let generated = "../.cache/suite/knotted-blob-v1.ply";
    let dir = tempfile::tempdir().unwrap();
    let small_mesh = dir.path().join("blob.ply");
    std::fs::write(&small_mesh, uv_sphere_ply(12, 24)).unwrap();
    for path in &scenes {
        let text = std::fs::read_to_string(path).unwrap();
        let path = &if text.contains(generated) {
            let copy = dir.path().join(path.file_name().unwrap());
            std::fs::write(&copy, text.replace(generated, small_mesh.to_str().unwrap())).unwrap();
            copy
        } else {
            path.clone()
        };
        lanes_match_alone(path, &defines);
    }
}

/// What [`paths_traced_in_lanes_give_the_bits_of_paths_traced_alone`]
/// checks, on the scene at `path`.
fn lanes_match_alone(path: &std::path::Path, defines: &[(String, String)]) {
    use trazo::integrator::{Integrator, LANES, PathTracer, RayStats};
    use trazo::sampling::Sampler;
    let d = trazo::scene::load(path, defines).unwrap();
    let scene = trazo::scene::build(&d).unwrap();
    let s = &scene.settings;
    let tracer = PathTracer::with_settings(s);
    let fresh = || Sampler::new(s.sampler, s.spp, s.seed);
    let mut stats = RayStats::default();
    let (mut lanes_rays, mut alone_rays) = (0, 0);
    for y in 0..s.height {
        for x in 0..s.width {
            // Every lane, then some left out (a lens that blocks a ray).
            for live in [0xff_u32, 0b1011_0110] {
                let mut samplers: [Sampler; LANES] = std::array::from_fn(|_| fresh());
                let rays: [trazo::geometry::Ray; LANES] = std::array::from_fn(|k| {
                    samplers[k].start_pixel_sample(x, y, k as u32);
                    let u = samplers[k].next_2d();
                    let film = Vec2::new(x as f32 + u.x, y as f32 + u.y);
                    scene.camera.generate_ray(film, Vec2::splat(0.5))
                });
                let mut alone = samplers.clone();
                let together = tracer.radiance_lanes(&scene, &rays, &mut samplers, live, &mut stats);
                lanes_rays += std::mem::take(&mut stats.rays);
                for k in 0..LANES {
                    let expect = if live & (1 << k) != 0 {
                        tracer.radiance(&scene, &rays[k], &mut alone[k], &mut stats)
                    } else {
                        Rgb::ZERO
                    };
                    assert_eq!(
                        together[k].to_array().map(f32::to_bits),
                        expect.to_array().map(f32::to_bits),
                        "{}: pixel ({x}, {y}), lane {k} of {live:#b}",
                        path.display()
                    );
                }
                alone_rays += std::mem::take(&mut stats.rays);
            }
        }
    }
    assert_eq!(lanes_rays, alone_rays, "{}: rays counted", path.display());
    assert!(alone_rays > 0);
}

/// The lanes' light samples where the lanes chose different lights of
/// the kinds sampled in lanes (two parallelograms, one facing each way,
/// and a sphere) and of a kind sampled one by one (a disk): each lane
/// still has the bits of its path traced alone.
#[test]
fn paths_in_lanes_that_chose_different_lights_give_the_bits_of_paths_traced_alone() {
    let scene = r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="6"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="50"/>
        <transform name="to_world"><lookat origin="0, 1, 3.5" target="0, 1, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="8"/></sampler>
        <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/></film>
    </sensor>
    <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.7, 0.7, 0.7"/></bsdf>
    <shape type="rectangle">
        <transform name="to_world"><scale value="2, 2, 1"/><rotate x="1" angle="-90"/></transform>
        <ref id="white"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="2, 2, 1"/><translate value="0, 1, -1.5"/></transform>
        <ref id="white"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="0.3, 0.2, 1"/><rotate x="1" angle="90"/><translate value="-0.6, 2, 0"/></transform>
        <emitter type="area"><rgb name="radiance" value="6, 5, 4"/></emitter>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="0.2, 0.3, 1"/><rotate y="1" angle="-90"/><translate value="1.4, 0.8, -0.5"/></transform>
        <emitter type="area"><rgb name="radiance" value="2, 3, 5"/></emitter>
    </shape>
    <shape type="sphere">
        <point name="center" value="0.5, 1.6, -0.8"/><float name="radius" value="0.15"/>
        <emitter type="area"><rgb name="radiance" value="8, 8, 8"/></emitter>
    </shape>
    <shape type="disk">
        <transform name="to_world"><scale value="0.2"/><rotate x="1" angle="90"/><translate value="-1, 2.2, -1"/></transform>
        <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter>
    </shape>
    <shape type="sphere">
        <point name="center" value="0, 0.4, -0.4"/><float name="radius" value="0.4"/>
        <ref id="white"/>
    </shape>
</scene>"#;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lights.xml");
    std::fs::write(&path, scene).unwrap();
    lanes_match_alone(&path, &[]);
}

/// Light that enters a smooth glass sphere meets its inside always at the
/// angle it was refracted to (every chord of a sphere meets it at equal
/// angles at both ends), so it leaves at each inner hit with the same
/// Fresnel transmittance. With Russian roulette off, the share of a white
/// furnace that a path-length limit of d segments loses is then, per
/// camera ray, (1 − R_entry)·R_inside^(d − 2) (d − 2 inner reflections
/// in a row), whose mean over the film is computed here in f64 from the
/// camera's rays and the sphere's equation. Rays entering near grazing
/// meet the inside just short of the critical angle, where R_inside is
/// close to 1: long chains, which numerical error (origins pushed off the
/// wrong side, angles drifting past the critical one) shortens or traps.
/// At d = 12 and these samples, a loss a third off the closed form is
/// four standard deviations. (Mitsuba 3.9.1, scalar and LLVM variants,
/// loses 25 % less than the closed form at d = 8 and 6× less at d = 16 on
/// bench/suite/furnace-glass.xml.)
#[test]
fn glass_sphere_loses_to_the_depth_limit_what_fresnel_predicts() {
    fn fresnel(cos_i: f64, eta: f64) -> f64 {
        let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
        if sin2_t >= 1.0 {
            return 1.0;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        let parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
        let perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
        0.5 * (parallel * parallel + perpendicular * perpendicular)
    }
    let depth = 12;
    let mut d = furnace(smooth_glass(), PathSampling::Mis);
    (d.settings.width, d.settings.height, d.settings.spp) = (32, 32, 4096);
    d.settings.max_depth = depth;
    d.settings.rr_depth = 1000;
    let scene = trazo::scene::build(&d).unwrap();

    // The expected loss: the mean over the film of the closed form, on a
    // 16 × 16 grid in each pixel.
    let (mut expected, mut points) = (0.0f64, 0.0f64);
    for py in 0..32 {
        for px in 0..32 {
            for k in 0..256 {
                let film = Vec2::new(
                    px as f32 + ((k % 16) as f32 + 0.5) / 16.0,
                    py as f32 + ((k / 16) as f32 + 0.5) / 16.0,
                );
                let ray = scene.camera.generate_ray(film, Vec2::splat(0.5));
                let o = ray.origin.as_dvec3();
                let dir = ray.dir.as_dvec3().normalize();
                points += 1.0;
                // The unit sphere at the origin: t² + 2(o·d)t + |o|² − 1 = 0.
                let (b, c) = (o.dot(dir), o.dot(o) - 1.0);
                let disc = b * b - c;
                if disc <= 0.0 {
                    continue;
                }
                let p = o + dir * (-b - disc.sqrt());
                let cos_entry = -dir.dot(p.normalize());
                let sin_inside = (1.0 - cos_entry * cos_entry).max(0.0).sqrt() / 1.5;
                let cos_inside = (1.0 - sin_inside * sin_inside).sqrt();
                let r_inside = fresnel(cos_inside, 1.0 / 1.5);
                expected += (1.0 - fresnel(cos_entry, 1.5)) * r_inside.powi(depth as i32 - 2);
            }
        }
    }
    expected /= points;

    let film = render(&scene, &RenderOptions::default()).unwrap().film;
    let (mean, _) = mean_and_error(&film);
    let lost = 1.0 - mean;
    // Each sample is 1 (its path left the sphere in time) or 0, so the
    // loss is a binomial share of the film's samples.
    let samples = (32 * 32 * 4096) as f64;
    let sigma = (expected * (1.0 - expected) / samples).sqrt();
    assert!(
        (lost - expected).abs() < 4.0 * sigma,
        "lost {lost:.4e} of the furnace at depth {depth}, the closed form says {expected:.4e} (σ {sigma:.1e})"
    );
}
