//! Metropolis light transport against the path tracer: the same image in
//! expectation through every camera, for both contribution functions
//! (multiplexed strategies and whole bidirectional samples), with
//! independent renders (seeds) giving the error bars, which so include the
//! chains' correlation and the bootstrap's estimate of the brightness.
//! (Determinism across thread counts: light.rs.)

use super::light::{block_means, every_camera, small_cornell};
use trazo::color::luminance;
use trazo::render::{RenderOptions, render};
use trazo::scene::desc::{ColorSource, SceneDesc};
use trazo::settings::IntegratorKind;

/// Renders `d` by `integrator` with seeds 0..16: per seed the image's mean
/// luminance and its blocks' luminance means divided by it.
fn runs(d: &SceneDesc, integrator: IntegratorKind) -> Vec<(f64, Vec<f64>)> {
    (0..16)
        .map(|seed| {
            let mut d = d.clone();
            d.settings.integrator = integrator;
            d.settings.seed = seed;
            let scene = trazo::scene::build(&d).unwrap();
            let image = render(&scene, &RenderOptions::default()).unwrap().film.to_image();
            let mean = luminance(image.mean()) as f64;
            (mean, block_means(&image).iter().map(|b| b / mean).collect())
        })
        .collect()
}

/// The mean over runs of `value` and its standard error.
fn mean_and_error(runs: &[(f64, Vec<f64>)], value: impl Fn(&(f64, Vec<f64>)) -> f64) -> (f64, f64) {
    let n = runs.len() as f64;
    let mean = runs.iter().map(&value).sum::<f64>() / n;
    let var = runs.iter().map(|r| (value(r) - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// `d` rendered by `integrator` agrees with the path tracer (at 64 spp),
/// both judged over 16 independent renders (seeds), whose spread includes
/// the chains' correlation: the image's brightness within five standard
/// errors (it is the bootstrap's estimate, the same in every block), and
/// every 8×8 block's share of it within five standard errors of the
/// difference. The brightness and the median block must be known to
/// `precision` (relative), every block to three times that (the chains
/// spend little time in the darkest), so that a bias of a few times that
/// fails.
fn agrees_with_the_path_tracer(integrator: IntegratorKind, name: &str, d: &SceneDesc, precision: f64) {
    let mlt = runs(d, integrator);
    let mut p = d.clone();
    p.settings.spp = 64;
    let path = runs(&p, IntegratorKind::Path);
    let i = integrator.name();
    let ((mm, sm), (mp, sp)) = (mean_and_error(&mlt, |r| r.0), mean_and_error(&path, |r| r.0));
    let z = (mm - mp) / (sm * sm + sp * sp).sqrt();
    assert!(
        z.abs() < 5.0,
        "{name}: brightness {i} {mm} ± {sm}, path {mp} ± {sp} (z = {z:.2})"
    );
    assert!(
        sm / mm < precision,
        "{name}: brightness {i} {mm} ± {sm}: too uncertain to judge"
    );
    let (mut worst, mut errors) = (0.0f64, Vec::new());
    for b in 0..mlt[0].1.len() {
        let (mb, sb) = mean_and_error(&mlt, |r| r.1[b]);
        let (pb, qb) = mean_and_error(&path, |r| r.1[b]);
        let z = (mb - pb) / (sb * sb + qb * qb).sqrt();
        worst = worst.max(z.abs());
        assert!(
            z.abs() < 5.0,
            "{name}, block {b}: share {i} {mb} ± {sb}, path {pb} ± {qb} (z = {z:.2})"
        );
        assert!(
            sb / mb < 3.0 * precision && qb / pb < precision,
            "{name}, block {b}: share {i} {mb} ± {sb}, path {pb} ± {qb}: too uncertain to judge"
        );
        errors.push(sb / mb);
    }
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    assert!(median < precision, "{name}: a block's share is known to {median} only");
    eprintln!(
        "{name}, {i}: brightness z = {z:.2} (relative error {:.4}); largest |z| of a block's share {worst:.2}, median relative error {median:.4}",
        sm / mm
    );
}

/// Multiplexed MLT (pbrt-v4's `mlt`) on the Cornell box through every
/// camera (`every_camera`), 256 mutations per pixel (the chains spend
/// little time in the dark corners, and need that many to know them to
/// 3 %). A chain started in
/// proportion to a wrong brightness, splats weighted wrongly, a strategy's
/// contribution not multiplied by the number of strategies or a camera's
/// importance wrong shows in some block.
#[test]
fn multiplexed_mlt_agrees_with_the_path_tracer_through_every_camera() {
    for (name, mut d) in every_camera() {
        d.settings.spp = 256;
        d.settings.mlt.bootstrap = 20_000;
        d.settings.mlt.chains = 256;
        agrees_with_the_path_tracer(IntegratorKind::Mlt, name, &d, 0.025);
    }
}

/// Kelemen's MLT over whole bidirectional samples, on the Cornell box
/// through a pinhole and with a Gaussian filter.
#[test]
fn pssmlt_agrees_with_the_path_tracer() {
    for (name, mut d) in every_camera()
        .into_iter()
        .filter(|(n, _)| matches!(*n, "pinhole" | "gaussian filter"))
    {
        d.settings.mlt.bootstrap = 20_000;
        d.settings.mlt.chains = 256;
        agrees_with_the_path_tracer(IntegratorKind::Pssmlt, name, &d, 0.025);
    }
}

/// Each mutation adds luminance one (in expectation over its acceptance,
/// exactly in the splats of proposal and current state) times the
/// brightness: with a box filter the image's mean luminance is the
/// bootstrap's estimate of it, whatever the chains did. So two renders
/// with the same bootstrap and different chains (other mutation counts)
/// have the same mean luminance, to rounding.
#[test]
fn every_mutation_adds_the_same_luminance() {
    let mean = |spp: u32, chains: u32| {
        let mut d = small_cornell();
        d.settings.integrator = IntegratorKind::Mlt;
        d.settings.mlt.bootstrap = 5000;
        d.settings.mlt.chains = chains;
        d.settings.spp = spp;
        let scene = trazo::scene::build(&d).unwrap();
        luminance(
            render(&scene, &RenderOptions::default())
                .unwrap()
                .film
                .to_image()
                .mean(),
        ) as f64
    };
    let (a, b) = (mean(1, 64), mean(3, 200));
    assert!(a > 0.05, "{a}");
    assert!((a - b).abs() < 1e-4 * a, "{a} against {b}");
}

/// A scene with no light, or paths of no segment (max_depth 0): the
/// bootstrap finds nothing, the chains do not start, the image is black.
#[test]
fn a_scene_without_light_renders_black() {
    for integrator in [IntegratorKind::Mlt, IntegratorKind::Pssmlt] {
        for dark in [true, false] {
            let mut d = small_cornell();
            d.settings.integrator = integrator;
            d.settings.mlt.bootstrap = 1000;
            d.settings.spp = 2;
            if dark {
                for m in &mut d.materials {
                    m.emission = ColorSource::Rgb(glam::Vec3::ZERO);
                }
                d.lights.clear();
            } else {
                d.settings.max_depth = 0;
            }
            let scene = trazo::scene::build(&d).unwrap();
            let out = render(&scene, &RenderOptions::default()).unwrap();
            assert_eq!(out.film.to_image().mean(), glam::Vec3::ZERO, "{}", integrator.name());
        }
    }
}
