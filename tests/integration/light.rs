//! Light tracing against the path tracer: the same image in expectation
//! through a pinhole, a thin lens and an orthographic camera, and with a
//! filter wider than a pixel; determinism across thread counts.

use trazo::color::luminance;
use trazo::film::Image;
use trazo::render::{RenderOptions, render};
use trazo::scene::builtin::cornell_box;
use trazo::scene::desc::*;
use trazo::settings::{Filter, IntegratorKind};

/// Side of the square blocks of pixels compared.
const BLOCK: u32 = 8;

/// Luminance means of the image's BLOCK×BLOCK blocks.
pub(crate) fn block_means(img: &Image) -> Vec<f64> {
    let (bw, bh) = (img.width / BLOCK, img.height / BLOCK);
    let mut out = vec![0.0; (bw * bh) as usize];
    for y in 0..bh * BLOCK {
        for x in 0..bw * BLOCK {
            out[((y / BLOCK) * bw + x / BLOCK) as usize] += luminance(img.get(x, y)) as f64;
        }
    }
    out.iter().map(|s| s / (BLOCK * BLOCK) as f64).collect()
}

/// Per block, the mean over `seeds` renders of `d` by `integrator` and its
/// standard error (from the spread between seeds).
pub(crate) fn blocks_over_seeds(d: &SceneDesc, integrator: IntegratorKind, seeds: u64) -> Vec<(f64, f64)> {
    let mut runs = Vec::new();
    for seed in 0..seeds {
        let mut d = d.clone();
        d.settings.integrator = integrator;
        d.settings.seed = seed;
        let scene = trazo::scene::build(&d).unwrap();
        let out = render(&scene, &RenderOptions::default()).unwrap();
        assert_eq!(out.stats.spp, d.settings.spp);
        runs.push(block_means(&out.film.to_image()));
    }
    let n = seeds as f64;
    (0..runs[0].len())
        .map(|b| {
            let mean = runs.iter().map(|r| r[b]).sum::<f64>() / n;
            let var = runs.iter().map(|r| (r[b] - mean).powi(2)).sum::<f64>() / (n - 1.0);
            (mean, (var / n).sqrt())
        })
        .collect()
}

pub(crate) fn small_cornell() -> SceneDesc {
    let mut d = cornell_box();
    d.settings.width = 32;
    d.settings.height = 32;
    d.settings.spp = 64;
    d
}

/// The small Cornell box through every camera the splatting integrators
/// connect to: a pinhole, a thin lens focused on the back wall, an
/// orthographic camera, a Gaussian filter (splatted over 5×5 pixels), and
/// a 32×32 crop window of a 48×40 image (the importance is the window's).
pub(crate) fn every_camera() -> Vec<(&'static str, SceneDesc)> {
    let pinhole = small_cornell();
    let mut lens = small_cornell();
    lens.camera.aperture_radius = 0.15;
    let mut ortho = small_cornell();
    ortho.camera.projection = ProjectionDesc::Orthographic { size: 2.2 };
    let mut filtered = small_cornell();
    filtered.settings.filter = Filter::from_name("gaussian").unwrap();
    let mut cropped = small_cornell();
    cropped.settings.crop = Some(trazo::settings::Crop {
        full_width: 48,
        full_height: 40,
        x: 12,
        y: 3,
    });
    vec![
        ("pinhole", pinhole),
        ("thin lens", lens),
        ("orthographic", ortho),
        ("gaussian filter", filtered),
        ("crop window", cropped),
    ]
}

/// Every block of the light-traced Cornell box agrees with the path
/// tracer's within five standard errors of their difference (16 seeds
/// each), through every camera (`every_camera`; filter splats normalised
/// at the border as the camera passes normalise). The
/// blocks' standard errors are 0.2–0.4 % of their values, so a light
/// tracer 2 % too bright or too dark anywhere fails (its importance scaled
/// by 1.05 fails at z = 8.6).
#[test]
fn light_tracing_agrees_with_the_path_tracer_through_every_camera() {
    for (name, d) in every_camera() {
        let light = blocks_over_seeds(&d, IntegratorKind::Light, 16);
        let path = blocks_over_seeds(&d, IntegratorKind::Path, 16);
        let mut worst: f64 = 0.0;
        for (b, ((ml, sl), (mp, sp))) in light.iter().zip(&path).enumerate() {
            let z = (ml - mp) / (sl * sl + sp * sp).sqrt();
            worst = worst.max(z.abs());
            assert!(
                z.abs() < 5.0,
                "{name}, block {b}: light {ml} ± {sl}, path {mp} ± {sp} (z = {z:.2})"
            );
            assert!(
                sl / ml < 0.02 && sp / mp < 0.02,
                "{name}, block {b}: errors too large to judge"
            );
        }
        eprintln!(
            "{name}: largest |z| over {} blocks {worst:.2}; relative errors of a block {:.4} (light), {:.4} (path)",
            light.len(),
            light[5].1 / light[5].0,
            path[5].1 / path[5].0
        );
    }
}

/// Every integrator that splats light paths onto the image.
const SPLATTING: [IntegratorKind; 5] = [
    IntegratorKind::Light,
    IntegratorKind::Bdpt,
    IntegratorKind::Mlt,
    IntegratorKind::Pssmlt,
    IntegratorKind::Vcm,
];

/// Light paths (BDPT's pairs of subpaths, Metropolis chains) are traced in
/// fixed chunks and their splats added in order: one thread or two, the
/// same film to the bit (auxiliary sums included).
#[test]
fn splatting_integrators_do_not_depend_on_the_thread_count() {
    for integrator in SPLATTING {
        let mut d = small_cornell();
        d.settings.width = 24;
        d.settings.height = 20;
        d.settings.spp = 2;
        d.settings.integrator = integrator;
        d.settings.filter = Filter::from_name("tent").unwrap();
        d.settings.mlt.bootstrap = 2000;
        d.settings.mlt.chains = 50;
        let scene = trazo::scene::build(&d).unwrap();
        let films: Vec<_> = [1usize, 2]
            .iter()
            .map(|&t| {
                let options = RenderOptions {
                    threads: Some(t),
                    aovs: true,
                    ..RenderOptions::default()
                };
                render(&scene, &options).unwrap().film
            })
            .collect();
        assert_eq!(films[0], films[1], "{}", integrator.name());
        assert!(films[0].aovs.is_some());
        assert!(luminance(films[0].to_image().mean()) > 0.01);
    }
}

/// A thin lens over an orthographic projection focuses nowhere, so light
/// cannot be connected to it: the scene is refused, naming the camera and
/// the integrator.
#[test]
fn splatting_integrators_refuse_an_orthographic_camera_with_a_lens() {
    for integrator in SPLATTING {
        let mut d = small_cornell();
        d.settings.integrator = integrator;
        d.camera.projection = ProjectionDesc::Orthographic { size: 2.0 };
        d.camera.aperture_radius = 0.1;
        let Err(e) = trazo::scene::build(&d) else {
            panic!("an orthographic camera with a lens was accepted");
        };
        let e = e.to_string();
        assert!(
            e.contains("camera") && e.contains("orthographic") && e.contains(integrator.name()),
            "{e}"
        );
    }
}

/// A progressive render interrupted after an iteration, its state saved
/// in a checkpoint's bytes and resumed on another number of threads, ends
/// with the same film (auxiliary sums and BDPT's strategies' images
/// included), bit for bit, as one that never stopped: the sums, MLT's
/// brightness and chains (their states in primary sample space, their
/// generators, their current paths), SPPM's per-pixel statistics are all
/// saved.
#[test]
fn progressive_renders_resume_exactly() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use trazo::render::checkpoint::Checkpoint;
    use trazo::render::{Control, Stop, render_controlled};
    // VCM once more with a dispersive glass ball, whose light subpaths,
    // traced again on resuming, draw their wavelengths anew.
    let runs = SPLATTING
        .into_iter()
        .chain([IntegratorKind::Sppm])
        .map(|k| (k, false))
        .chain([(IntegratorKind::Vcm, true)]);
    for (integrator, dispersive) in runs {
        let mut d = small_cornell();
        (d.settings.width, d.settings.height, d.settings.spp) = (20, 16, 5);
        d.settings.integrator = integrator;
        if dispersive {
            d.materials.push(crate::dispersion::dispersive_glass("sf11"));
            d.shapes.push(ShapeDesc::new(
                ShapeKind::Sphere {
                    center: trazo::Vec3::new(0.3, 0.2, 0.4),
                    radius: 0.15,
                },
                Some("sf11"),
            ));
        }
        d.settings.bdpt_strategies = integrator == IntegratorKind::Bdpt;
        d.settings.mlt.bootstrap = 2000;
        d.settings.mlt.chains = 40;
        let scene = trazo::scene::build(&d).unwrap();
        let options = |threads| RenderOptions {
            aovs: true,
            threads: Some(threads),
            ..RenderOptions::default()
        };
        let whole = render(&scene, &options(2)).unwrap();
        let cancel = AtomicBool::new(false);
        let mut saved = None;
        let mut save = |f: &trazo::film::Film, st: &trazo::render::RenderStats, state: &[u8]| {
            if st.spp == 2 {
                saved = Some((f.clone(), st.clone(), state.to_vec()));
                cancel.store(true, Ordering::Relaxed);
            }
        };
        let mut control = Control {
            cancel: Some(&cancel),
            checkpoint_every: Some(std::time::Duration::ZERO),
            on_checkpoint: Some(&mut save),
            ..Control::default()
        };
        let partial = render_controlled(&scene, &options(2), &mut control).unwrap();
        drop(control);
        let name = format!("{}{}", integrator.name(), if dispersive { ", dispersive" } else { "" });
        assert_eq!(
            (partial.stopped, partial.stats.spp),
            (Some(Stop::Interrupted), 2),
            "{name}"
        );
        let (film, stats, state) = saved.expect("a checkpoint after the second iteration");
        assert!(!state.is_empty(), "{name}");
        // The state the render ended with is the one saved after its last
        // iteration (what the command line writes on an interrupt).
        assert!(partial.state == state, "{name}");
        let checkpoint = Checkpoint {
            job: Vec::new(),
            target_spp: 5,
            film,
            stats,
            state,
        };
        let back = Checkpoint::from_bytes(&checkpoint.to_bytes()).unwrap();
        let mut control = Control {
            resume: Some((back.film, back.stats)),
            resume_state: back.state.clone(),
            ..Control::default()
        };
        let resumed = render_controlled(&scene, &options(1), &mut control).unwrap();
        assert_eq!((resumed.stopped, resumed.stats.spp), (None, 5), "{name}");
        assert!(resumed.film == whole.film, "{name}: the resumed film differs");
        assert_eq!(resumed.extra.len(), whole.extra.len());
        for ((a, fa), (b, fb)) in resumed.extra.iter().zip(&whole.extra) {
            assert!(a == b && fa == fb, "{name}: {a} differs");
        }
        // A state cut short is refused with a reason, not trusted.
        let mut control = Control {
            resume: Some((checkpoint.film.clone(), checkpoint.stats.clone())),
            resume_state: back.state[..back.state.len() - 1].to_vec(),
            ..Control::default()
        };
        let e = render_controlled(&scene, &options(1), &mut control)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot resume") && e.contains("state"), "{name}: {e}");
    }
}

/// A floor under two lamps that face up, away from it (a rectangle, which
/// the light samples inline, and a disk, sampled through the aggregate):
/// with `two_sided_emission` their backs light the floor, the same in
/// expectation under every estimator: the path tracer with MIS and with
/// BSDF sampling alone, light tracing, BDPT and VCM, each over seeds
/// (their means within 4.5 standard errors of the path tracer's). Without
/// it the floor is black.
#[test]
fn two_sided_area_lights_light_both_sides_under_every_estimator() {
    let scene = |two_sided: bool| {
        let text = format!(
            r#"[render]
width = 24
height = 24
spp = 64
max_depth = 3
sampler = "independent"

[camera]
from = [0, 3, 4]
to = [0, 0, 0]
fov = 50

[[material]]
name = "floor"
diffuse = [0.6, 0.6, 0.6]

[[material]]
name = "lamp"
diffuse = [0, 0, 0]
emission = [3, 3, 3]
two_sided_emission = {two_sided}

[[shape]]
type = "rectangle"
corner = [-3, 0, 3]
edge_u = [6, 0, 0]
edge_v = [0, 0, -6]
material = "floor"

[[shape]]
type = "rectangle"
corner = [-1.5, 0.8, -0.5]
edge_u = [0, 0, 1]
edge_v = [1, 0, 0]
material = "lamp"

[[shape]]
type = "disk"
center = [1, 0.6, 0]
normal = [0, 1, 0]
radius = 0.4
material = "lamp"
"#
        );
        trazo::scene::native::parse(&text, std::path::Path::new("lamps.toml")).unwrap()
    };
    let mean_over_seeds = |d: &SceneDesc, integrator: &str, sampling: &str| {
        let mut d = d.clone();
        d.settings.integrator = IntegratorKind::from_name(integrator).unwrap();
        d.settings.sampling = trazo::settings::PathSampling::from_name(sampling).unwrap();
        let blocks = blocks_over_seeds(&d, d.settings.integrator, 6);
        let n = blocks.len() as f64;
        let mean = blocks.iter().map(|b| b.0).sum::<f64>() / n;
        let err = blocks.iter().map(|b| b.1 * b.1).sum::<f64>().sqrt() / n;
        (mean, err)
    };
    let two = scene(true);
    let (reference, ref_err) = mean_over_seeds(&two, "path", "mis");
    let (one_sided, _) = mean_over_seeds(&scene(false), "path", "mis");
    // One-sided, only the lamps' fronts are seen, from above.
    assert!(
        reference > 1.5 * one_sided,
        "two-sided {reference}, one-sided {one_sided}"
    );
    for (integrator, sampling) in [("path", "bsdf"), ("light", "mis"), ("bdpt", "mis"), ("vcm", "mis")] {
        let (m, e) = mean_over_seeds(&two, integrator, sampling);
        assert!(
            (m - reference).abs() <= 4.5 * (e * e + ref_err * ref_err).sqrt(),
            "{integrator} ({sampling}): {m} ± {e}, path with MIS {reference} ± {ref_err}"
        );
    }
}
