//! Photon mapping and SPPM against answers known in advance and against
//! long path-traced references (tests/data, made by
//! tests/data/make-references.sh): the density estimate under a sphere
//! light, agreement with the path tracer on the Cornell box, SPPM's error
//! falling with iterations, SPPM beating the path tracer on a caustic at
//! equal time, determinism.

use std::path::Path;
use std::time::Duration;
use trazo::Vec3;
use trazo::color::{Rgb, luminance};
use trazo::film::Image;
use trazo::film::io::read_exr;
use trazo::film::metrics::relative_mse;
use trazo::render::{RenderOptions, RenderOutput, render};
use trazo::sampling::SamplerKind;
use trazo::scene::builtin::cornell_box;
use trazo::scene::desc::*;
use trazo::settings::{IntegratorKind, PhotonKernel};

fn reference(name: &str) -> Image {
    read_exr(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)).unwrap()
}

fn run(d: &SceneDesc, options: &RenderOptions) -> RenderOutput {
    let scene = trazo::scene::build(d).unwrap();
    render(&scene, options).unwrap()
}

fn diffuse(name: &str, albedo: f32) -> MaterialDesc {
    MaterialDesc::with_kind(
        name,
        MaterialKindDesc::Diffuse {
            reflectance: ColorSource::Rgb(Rgb::splat(albedo)),
        },
    )
}

/// Reading the global photon map directly (no final gathering) on a
/// diffuse plane under a sphere light: the density estimate must give the
/// closed-form radiance ρ·Le·(r/d)²·cos θ at every pixel, with each kernel.
#[test]
fn density_estimate_matches_the_irradiance_of_a_sphere_light() {
    let (rho, le, r) = (0.6f32, 5.0f32, 0.5f32);
    let center = Vec3::new(0.0, 2.0, 0.0);
    for kernel in [PhotonKernel::Cone, PhotonKernel::Epanechnikov, PhotonKernel::Box] {
        let mut d = SceneDesc::default();
        d.settings.width = 8;
        d.settings.height = 8;
        d.settings.spp = 2;
        d.settings.max_depth = 2;
        d.settings.integrator = IntegratorKind::Photon;
        d.settings.photon.photons = 1_000_000;
        d.settings.photon.gather = 500;
        d.settings.photon.final_gather = 0;
        d.settings.photon.kernel = kernel;
        // A window 1 unit wide around the light's foot, seen from the side,
        // past the light.
        d.camera = CameraDesc {
            projection: ProjectionDesc::Orthographic { size: 1.0 },
            from: Vec3::new(3.0, 3.0, 0.0),
            to: Vec3::ZERO,
            up: Vec3::Y,
            ..CameraDesc::default()
        };
        d.materials.push(diffuse("floor", rho));
        let mut lamp = diffuse("lamp", 0.0);
        lamp.emission = ColorSource::Rgb(Rgb::splat(le));
        d.materials.push(lamp);
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Plane {
                point: Vec3::ZERO,
                normal: Vec3::Y,
            },
            Some("floor"),
        ));
        d.shapes
            .push(ShapeDesc::new(ShapeKind::Sphere { center, radius: r }, Some("lamp")));
        let scene = trazo::scene::build(&d).unwrap();
        let img = render(&scene, &RenderOptions::default()).unwrap().film.to_image();
        let (mut sum, mut sum_expect) = (0.0f64, 0.0f64);
        for y in 0..8 {
            for x in 0..8 {
                let ray = scene
                    .camera
                    .generate_ray(trazo::Vec2::new(x as f32 + 0.5, y as f32 + 0.5), trazo::Vec2::ZERO);
                let hit = scene.intersect(&ray).expect("the floor fills the view");
                let to_light = center - hit.p;
                let d2 = to_light.length_squared();
                let cos = to_light.y / d2.sqrt();
                let expect = rho * le * r * r / d2 * cos;
                let got = img.get(x, y).x;
                assert!(
                    (got - expect).abs() < 0.2 * expect,
                    "{}: pixel ({x},{y}) = {got}, expected {expect}",
                    kernel.name()
                );
                sum += got as f64;
                sum_expect += expect as f64;
            }
        }
        assert!(
            (sum / sum_expect - 1.0).abs() < 0.03,
            "{}: mean ratio {}",
            kernel.name(),
            sum / sum_expect
        );
    }
}

/// The sampler these fixed-seed tests were tuned with. Their images hold
/// rare legitimate fireflies (the lamp seen through specular chains, at
/// light edges) that dominate a few-spp error; with the Sobol sampler,
/// trazo's default since, the default seed happens to draw one. Over 200
/// seeds of the caustic test's SPPM render, stratified, Sobol and
/// independent sampling give 10, 15 and 9 firefly pixels and the same
/// image mean within its standard error (0.2923, 0.2929, 0.2922 ± 0.0004).
const TUNED_SAMPLER: SamplerKind = SamplerKind::Stratified;

fn small_cornell(integrator: IntegratorKind, spp: u32) -> SceneDesc {
    let mut d = cornell_box();
    d.settings.width = 32;
    d.settings.height = 32;
    d.settings.spp = spp;
    d.settings.integrator = integrator;
    d.settings.sampler = TUNED_SAMPLER;
    d
}

/// Photon mapping with final gathering is biased but close: on the Cornell
/// box its mean is within 3% of the path-traced reference and its error
/// is small.
#[test]
fn photon_mapping_agrees_with_the_path_tracer_on_the_cornell_box() {
    let reference = reference("cornell-32-ref.exr");
    let mut d = small_cornell(IntegratorKind::Photon, 4);
    d.settings.photon.photons = 100_000;
    let img = run(&d, &RenderOptions::default()).film.to_image();
    let (a, b) = (luminance(img.mean()), luminance(reference.mean()));
    assert!((a / b - 1.0).abs() < 0.03, "mean luminance {a} vs {b}");
    let e = relative_mse(&img, &reference).unwrap();
    assert!(e < 0.05, "relative MSE {e}");
}

/// SPPM converges: its error against the path-traced reference falls with
/// the number of iterations (by the rate that bias and noise shrinking
/// together give, about k^(−2/3) to k^(−1) in relative MSE; we ask for a
/// factor 2 per 4× iterations).
#[test]
fn sppm_error_falls_with_iterations_on_the_cornell_box() {
    let reference = reference("cornell-32-ref.exr");
    let mut errors = Vec::new();
    for iterations in [4, 16, 64] {
        let mut d = small_cornell(IntegratorKind::Sppm, iterations);
        d.settings.photon.sppm_photons = 20_000;
        let out = run(&d, &RenderOptions::default());
        assert_eq!(out.stats.spp, iterations);
        assert_eq!(out.stats.photons_emitted, 20_000 * iterations as u64);
        errors.push(relative_mse(&out.film.to_image(), &reference).unwrap());
    }
    for w in errors.windows(2) {
        assert!(w[1] < 0.5 * w[0], "relative MSE by iterations 4, 16, 64: {errors:?}");
    }
    assert!(errors[2] < 0.005, "{errors:?}");
}

/// Relative MSE over the pixels where `mask` holds.
fn masked_rel_mse(a: &Image, b: &Image, mask: &[bool]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ((p, q), &m) in a.pixels.iter().zip(&b.pixels).zip(mask) {
        if m {
            for c in 0..3 {
                let (x, y) = (p[c] as f64, q[c] as f64);
                sum += (x - y) * (x - y) / (y * y + trazo::film::metrics::REL_MSE_EPSILON);
            }
            n += 3;
        }
    }
    sum / n.max(1) as f64
}

/// The caustic scene: light focused by a glass sphere reaches the floor
/// only through two refractions, which the path tracer finds by chance.
/// SPPM, given a fixed number of iterations, is measured; the path tracer
/// then gets as long, and SPPM must still have under half its error over
/// the caustic (the pixels brighter than twice the median in the
/// reference). Over the whole image the path tracer's error is dominated by
/// a few fireflies whose number varies from run to run: it is printed, not
/// tested.
#[test]
fn sppm_beats_the_path_tracer_on_a_caustic_at_equal_time() {
    let reference = reference("caustic-64-ref.exr");
    let mut d = trazo::scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/caustic.toml"), &[]).unwrap();
    d.settings.width = 64;
    d.settings.height = 48;
    d.settings.integrator = IntegratorKind::Sppm;
    d.settings.spp = 24;
    d.settings.photon.sppm_photons = 30_000;
    d.settings.sampler = TUNED_SAMPLER;
    let sppm = run(&d, &RenderOptions::default());
    let mut pt = d.clone();
    pt.settings.integrator = IntegratorKind::Path;
    pt.settings.spp = 1 << 20;
    let path = run(
        &pt,
        &RenderOptions {
            time_limit: Some(Duration::from_secs_f64(sppm.stats.seconds)),
            ..RenderOptions::default()
        },
    );
    assert!(path.stats.seconds >= sppm.stats.seconds, "the path tracer got its time");
    let (a, b) = (sppm.film.to_image(), path.film.to_image());
    let mut lum: Vec<f32> = reference.pixels.iter().map(|&p| luminance(p)).collect();
    lum.sort_by(f32::total_cmp);
    let median = lum[lum.len() / 2];
    let caustic: Vec<bool> = reference.pixels.iter().map(|&p| luminance(p) > 2.0 * median).collect();
    let n_caustic = caustic.iter().filter(|&&m| m).count();
    assert!((10..300).contains(&n_caustic), "{n_caustic} caustic pixels");
    let (e_sppm, e_path) = (
        masked_rel_mse(&a, &reference, &caustic),
        masked_rel_mse(&b, &reference, &caustic),
    );
    eprintln!(
        "caustic: SPPM {e_sppm} ({} iterations) vs path tracing {e_path} ({} spp) in {:.2} s; whole image {} vs {}",
        sppm.stats.spp,
        path.stats.spp,
        sppm.stats.seconds,
        relative_mse(&a, &reference).unwrap(),
        relative_mse(&b, &reference).unwrap()
    );
    assert!(
        e_sppm < 0.5 * e_path,
        "SPPM {e_sppm} vs path tracing {e_path} on the caustic"
    );
}

/// The photon pass and SPPM's updates are deterministic: one thread or
/// two, the same image to the bit.
#[test]
fn photon_images_do_not_depend_on_the_thread_count() {
    for integrator in [IntegratorKind::Photon, IntegratorKind::Sppm] {
        let mut d = small_cornell(integrator, 3);
        d.settings.width = 16;
        d.settings.height = 16;
        d.settings.photon.photons = 10_000;
        d.settings.photon.sppm_photons = 2_000;
        d.settings.photon.final_gather = 4;
        let films: Vec<_> = [1usize, 2]
            .iter()
            .map(|&t| {
                run(
                    &d,
                    &RenderOptions {
                        threads: Some(t),
                        aovs: true,
                        ..RenderOptions::default()
                    },
                )
                .film
            })
            .collect();
        assert_eq!(films[0], films[1], "{}", integrator.name());
        assert!(films[0].aovs.is_some());
    }
}

/// A time limit stops SPPM between iterations.
#[test]
fn sppm_respects_a_time_limit() {
    let mut d = small_cornell(IntegratorKind::Sppm, 1_000_000);
    d.settings.photon.sppm_photons = 5_000;
    let out = run(
        &d,
        &RenderOptions {
            time_limit: Some(Duration::from_millis(200)),
            ..RenderOptions::default()
        },
    );
    assert!(out.stats.spp >= 1 && out.stats.spp < 1_000_000);
    assert!(out.stats.seconds < 5.0, "{}", out.stats.seconds);
}

/// The default photon radius (SPPM's initial radius, photon mapping's
/// largest search radius) follows the image: two pixel footprints, so a
/// render of twice the resolution has half the radius.
#[test]
fn the_default_photon_radius_follows_the_pixel_footprint() {
    let radius = |side: u32| {
        let mut d = small_cornell(IntegratorKind::Sppm, 1);
        d.settings.width = side;
        d.settings.height = side;
        trazo::integrator::photon::default_radius(&trazo::scene::build(&d).unwrap())
    };
    let (r64, r128) = (radius(64), radius(128));
    assert!((r64 / r128 - 2.0).abs() < 0.05, "{r64} at 64 px, {r128} at 128 px");
    // The box is about 2 units wide and fills most of the picture: two
    // footprints at 64 pixels are a few hundredths.
    assert!((0.02..0.2).contains(&r64), "{r64}");
}
