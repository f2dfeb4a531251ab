//! The denoisers on real renders: they lower the error against a converged
//! reference (tests/data/cornell-64-ref.exr, from
//! tests/data/make-references.sh) and keep edges of the albedo sharp.
//!
//! Intel Open Image Denoise is tested when its library is found
//! (`tools/oidn/setup`); CI sets `TRAZO_REQUIRE_OIDN=1`, which turns a
//! missing library into a failure instead of a skipped check.

use std::path::Path;
use trazo::Vec3;
use trazo::color::Rgb;
use trazo::film::Film;
use trazo::film::denoise::{DenoiserKind, denoise_film, oidn};
use trazo::film::io::read_exr;
use trazo::film::metrics::relative_mse;
use trazo::render::{RenderOptions, render};
use trazo::scene::builtin::cornell_box;
use trazo::scene::desc::*;

fn render_with_aovs(d: &SceneDesc) -> Film {
    let scene = trazo::scene::build(d).unwrap();
    render(
        &scene,
        &RenderOptions {
            aovs: true,
            ..RenderOptions::default()
        },
    )
    .unwrap()
    .film
}

fn noisy_cornell() -> Film {
    let mut d = cornell_box();
    d.settings.width = 64;
    d.settings.height = 64;
    d.settings.spp = 16;
    render_with_aovs(&d)
}

fn cornell_reference() -> trazo::film::Image {
    read_exr(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cornell-64-ref.exr")).unwrap()
}

#[test]
fn atrous_filter_lowers_the_error_of_a_noisy_render() {
    let film = noisy_cornell();
    let reference = cornell_reference();
    let before = relative_mse(&film.to_image(), &reference).unwrap();
    let d = denoise_film(&film, DenoiserKind::Atrous).unwrap();
    assert!(d.denoiser.contains("à-trous"), "{}", d.denoiser);
    let after = relative_mse(&d.image, &reference).unwrap();
    assert!(after < 0.5 * before, "relative MSE {before} → {after}");
}

#[test]
fn open_image_denoise_lowers_the_error_when_installed() {
    if let Err(e) = oidn::Library::find() {
        assert!(
            std::env::var_os("TRAZO_REQUIRE_OIDN").is_none(),
            "TRAZO_REQUIRE_OIDN is set but: {e}"
        );
        eprintln!("skipped: {e}");
        return;
    }
    let film = noisy_cornell();
    let reference = cornell_reference();
    let before = relative_mse(&film.to_image(), &reference).unwrap();
    let d = denoise_film(&film, DenoiserKind::Oidn).unwrap();
    assert!(d.denoiser.contains("Open Image Denoise"), "{}", d.denoiser);
    let after = relative_mse(&d.image, &reference).unwrap();
    assert!(after < 0.5 * before, "relative MSE {before} → {after}");
    // Auto picks it.
    let auto = denoise_film(&film, DenoiserKind::Auto).unwrap();
    assert_eq!(auto.denoiser, d.denoiser);
}

/// Two diffuse panels, albedo 0.8 and 0.1, meet at a pixel boundary under
/// a uniform sky of radiance 1, so each renders exactly its albedo. After
/// denoising a noisy render, the columns on either side of the edge still
/// show their own albedo: the built-in filter does not blur across it.
#[test]
fn denoising_keeps_a_sharp_albedo_edge() {
    let mut d = SceneDesc::default();
    d.settings.width = 64;
    d.settings.height = 32;
    d.settings.spp = 4;
    d.settings.max_depth = 4;
    d.camera = CameraDesc {
        projection: ProjectionDesc::Orthographic { size: 1.0 },
        from: Vec3::new(0.0, 0.0, 3.0),
        to: Vec3::ZERO,
        up: Vec3::Y,
        ..CameraDesc::default()
    };
    d.background = BackgroundDesc::Constant(Rgb::ONE);
    for (name, albedo, x0) in [("light", 0.8f32, -1.0f32), ("dark", 0.1, 0.0)] {
        d.materials.push(MaterialDesc::with_kind(
            name,
            MaterialKindDesc::Diffuse {
                reflectance: ColorSource::Rgb(Rgb::splat(albedo)),
            },
        ));
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Rectangle {
                corner: Vec3::new(x0, -1.0, 0.0),
                edge_u: Vec3::new(1.0, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 2.0, 0.0),
            },
            Some(name),
        ));
    }
    d.settings.sampling = trazo::settings::PathSampling::Uniform;
    let film = render_with_aovs(&d);
    let noisy = film.to_image();
    // The render is noisy (uniform sampling of the sky), or the test would
    // prove nothing.
    let spread = (0..32).map(|y| (noisy.get(4, y).x - 0.8).abs()).fold(0.0f32, f32::max);
    assert!(spread > 0.02, "noise {spread}");
    let mut kinds = vec![DenoiserKind::Atrous];
    if oidn::Library::find().is_ok() {
        kinds.push(DenoiserKind::Oidn);
    }
    for kind in kinds {
        let out = denoise_film(&film, kind).unwrap().image;
        for y in 2..30 {
            let (l, r) = (out.get(31, y).x, out.get(32, y).x);
            assert!((l - 0.8).abs() < 0.08, "{}: row {y}, left of the edge {l}", kind.name());
            if kind == DenoiserKind::Atrous {
                assert!(
                    (r - 0.1).abs() < 0.02,
                    "{}: row {y}, right of the edge {r}",
                    kind.name()
                );
            } else {
                // OIDN leaves a faint halo (about +0.04 on the dark side,
                // measured), but the edge stays sharp: a contrast of 8
                // does not fall below 4.
                assert!(l / r > 4.0, "{}: row {y}, contrast {l} / {r}", kind.name());
            }
        }
    }
}

#[test]
fn denoising_needs_the_guides() {
    let mut d = cornell_box();
    d.settings.width = 8;
    d.settings.height = 8;
    d.settings.spp = 1;
    let scene = trazo::scene::build(&d).unwrap();
    let film = render(&scene, &RenderOptions::default()).unwrap().film;
    assert!(denoise_film(&film, DenoiserKind::Atrous).is_err());
}
