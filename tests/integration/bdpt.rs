//! Bidirectional path tracing against the path tracer: the same image in
//! expectation through every camera, under every kind of light and over
//! delta and glossy BSDFs; the strategies' images. (Determinism across
//! thread counts: light.rs.)

use super::light::{blocks_over_seeds, every_camera, small_cornell};
use std::path::Path;
use trazo::color::luminance;
use trazo::render::{RenderOptions, render};
use trazo::scene::desc::*;
use trazo::settings::IntegratorKind;

/// Every block of `d` rendered by BDPT agrees with the path tracer's
/// within five standard errors of their difference (16 seeds each), and
/// both are known to 2 % or better, so a bias of a few per cent anywhere
/// fails.
fn agrees_with_the_path_tracer(name: &str, d: &SceneDesc) {
    same_as_the_path_tracer(name, d, IntegratorKind::Bdpt);
}

/// Every block of `d` rendered by `integrator` agrees with the path
/// tracer's within five standard errors of their difference (16 seeds
/// each), both known to 2 % or better.
fn same_as_the_path_tracer(name: &str, d: &SceneDesc, integrator: IntegratorKind) {
    same_as(name, d, integrator, (IntegratorKind::Path, 1));
}

/// Every block of `d` rendered by `integrator` agrees with `reference`'s
/// (rendered with `spp_scale` times the samples) within five standard
/// errors of their difference (16 seeds each), both known to 2 % or better.
fn same_as(name: &str, d: &SceneDesc, integrator: IntegratorKind, (reference, spp_scale): (IntegratorKind, u32)) {
    let bdpt = blocks_over_seeds(d, integrator, 16);
    let mut more = d.clone();
    more.settings.spp *= spp_scale;
    let path = blocks_over_seeds(&more, reference, 16);
    let mut worst: f64 = 0.0;
    for (b, ((mb, sb), (mp, sp))) in bdpt.iter().zip(&path).enumerate() {
        if *sb == 0.0 && *sp == 0.0 {
            // The sky alone: the same in every sample.
            assert!((mb - mp).abs() <= 1e-6 * mp, "{name}, block {b}: bdpt {mb}, path {mp}");
            continue;
        }
        let z = (mb - mp) / (sb * sb + sp * sp).sqrt();
        worst = worst.max(z.abs());
        assert!(
            z.abs() < 5.0,
            "{name}, block {b}: {integrator:?} {mb} ± {sb}, {reference:?} {mp} ± {sp} (z = {z:.2})"
        );
        assert!(
            sb / mb < 0.02 && sp / mp < 0.02,
            "{name}, block {b}: errors too large to judge: {integrator:?} {mb} ± {sb}, {reference:?} {mp} ± {sp}"
        );
    }
    eprintln!("{name}: largest |z| over {} blocks {worst:.2}", bdpt.len());
}

/// The Cornell box through every camera (`every_camera`).
#[test]
fn bdpt_agrees_with_the_path_tracer_through_every_camera() {
    for (name, d) in every_camera() {
        agrees_with_the_path_tracer(name, &d);
    }
}

/// Vertex connection and merging through every camera. Merging is biased
/// by its radius (light is averaged over a disk, which near a wall's edge
/// reaches past it), and converges as the radius shrinks: at 32² the
/// default radius, two pixel footprints, is 9 % of the box and darkens the
/// blocks along the walls' edges by up to 3 % after 64 iterations, so the
/// test merges within 0.02 (1 % of the box). This checks the weights of
/// connections among merges; `vcm_merges_light_that_no_connection_reaches`
/// checks merging alone.
#[test]
fn vcm_agrees_with_the_path_tracer_through_every_camera() {
    for (name, mut d) in every_camera() {
        d.settings.photon.radius = 0.02;
        same_as_the_path_tracer(name, &d, IntegratorKind::Vcm);
    }
}

/// An open scene under a point light, a spot light, a directional light,
/// a spherical area light and a sky (a constant environment), over a
/// diffuse floor with a glass ball, a copper ball and a gold ball: every
/// light kind's emission densities and paths that leave the scene. Rough
/// here: the path tracer cannot see a point light through smooth glass
/// (a caustic, which BDPT renders), so the two would differ.
const LIGHTS_AND_BSDFS: &str = r#"
[render]
width = 32
height = 32
spp = 64
max_depth = 6

[camera]
from = [0, 2.2, 5]
to = [0, 0.5, 0]
fov = 45

[world]
background = [0.25, 0.3, 0.4]

[[material]]
name = "floor"
type = "diffuse"
reflectance = 0.7

[[material]]
name = "glass"
type = "dielectric"
ior = 1.5
roughness = 0.3

[[material]]
name = "copper"
type = "conductor"
metal = "Cu"
roughness = 0.25

[[material]]
name = "gold"
type = "conductor"
metal = "Au"
roughness = 0.15

[[material]]
name = "lamp"
emission = [30, 26, 20]

[[light]]
type = "point"
position = [-2, 3, 2]
intensity = [6, 6, 5]

[[light]]
type = "spot"
position = [2, 3, 1]
to = [0, 0, 0]
intensity = [12, 10, 8]
inner_angle = 15
outer_angle = 30

[[light]]
type = "directional"
direction = [0.3, -1, -0.4]
irradiance = [0.8, 0.8, 0.7]

[[shape]]
type = "rectangle"
corner = [-3, 0, -3]
edge_u = [0, 0, 6]
edge_v = [6, 0, 0]
material = "floor"

[[shape]]
type = "sphere"
center = [-0.9, 0.5, 0]
radius = 0.5
material = "glass"

[[shape]]
type = "sphere"
center = [0.3, 0.45, -0.4]
radius = 0.45
material = "copper"

[[shape]]
type = "sphere"
center = [1.1, 0.35, 0.6]
radius = 0.35
material = "gold"

[[shape]]
type = "sphere"
center = [0.5, 2.5, 1.5]
radius = 0.15
material = "lamp"
"#;

#[test]
fn bdpt_agrees_with_the_path_tracer_under_every_kind_of_light() {
    let d = trazo::scene::native::parse(LIGHTS_AND_BSDFS, Path::new("<lights-and-bsdfs>")).unwrap();
    let scene = trazo::scene::build(&d).unwrap();
    assert_eq!(scene.lights.len(), 5, "point, spot, directional, sphere and sky");
    agrees_with_the_path_tracer("every light, rough BSDFs", &d);
}

/// The same scene lit by the sphere and the sky alone, with smooth glass
/// and a mirror-smooth gold ball: delta lobes, whose zero densities the
/// weights skip, and caustics that both tracers find (the path tracer by
/// hitting the lamp).
#[test]
fn bdpt_agrees_with_the_path_tracer_over_delta_bsdfs() {
    let text = LIGHTS_AND_BSDFS
        .replace("ior = 1.5\nroughness = 0.3", "ior = 1.5")
        .replace("metal = \"Au\"\nroughness = 0.15", "metal = \"Au\"");
    assert!(!text.contains("roughness = 0.3") && !text.contains("roughness = 0.15"));
    let mut d = trazo::scene::native::parse(&text, Path::new("<delta-bsdfs>")).unwrap();
    d.lights.clear();
    let scene = trazo::scene::build(&d).unwrap();
    assert_eq!(scene.lights.len(), 2, "sphere and sky");
    agrees_with_the_path_tracer("sphere and sky, delta BSDFs", &d);
}

/// A room of thin fog (a `null` box, the camera inside) under a sky
/// seen through it, a point light and a small spherical lamp; in it a
/// diffuse floor and ball, a ball of a chromatic scattering medium with no
/// surface, and a rough glass ball filled with a denser one. What the
/// subpaths of bidirectional path tracing go through.
const FOG_ROOM: &str = r#"
[render]
width = 32
height = 32
spp = 16
max_depth = 6

[camera]
from = [0, 1.2, 3.5]
to = [0, 0.6, 0]
fov = 50
medium = "fog"

[world]
background = [0.3, 0.35, 0.45]

[[medium]]
name = "fog"
type = "homogeneous"
sigma_t = 0.3
albedo = 0.9

[[medium]]
name = "tint"
type = "homogeneous"
sigma_t = [0.6, 1.8, 3.5]
albedo = [0.9, 0.8, 0.7]
g = 0.3

[[medium]]
name = "milk"
type = "homogeneous"
sigma_t = 4
albedo = 0.95
g = -0.2

[[material]]
name = "floor"
type = "diffuse"
reflectance = 0.6

[[material]]
name = "boundary"
type = "null"

[[material]]
name = "glass"
type = "dielectric"
ior = 1.4
roughness = 0.3

[[material]]
name = "lamp"
emission = [20, 18, 15]

[[light]]
type = "point"
position = [-1.5, 2.5, 1]
intensity = [4, 4, 3.5]

[[shape]]
type = "box"
min = [-2.5, -0.5, -2.5]
max = [2.5, 3, 4.5]
material = "boundary"
inside = "fog"

[[shape]]
type = "rectangle"
corner = [-2, 0, -2]
edge_u = [0, 0, 4]
edge_v = [4, 0, 0]
material = "floor"

[[shape]]
type = "sphere"
center = [-0.8, 0.45, -0.2]
radius = 0.45
material = "floor"

[[shape]]
type = "sphere"
center = [0.2, 0.5, 0.5]
radius = 0.5
material = "boundary"
inside = "tint"
outside = "fog"

[[shape]]
type = "sphere"
center = [1.1, 0.4, -0.3]
radius = 0.4
material = "glass"
inside = "milk"
outside = "fog"

[[shape]]
type = "sphere"
center = [0.8, 2.2, 0.6]
radius = 0.12
material = "lamp"
"#;

/// Bidirectional path tracing (and vertex connection and merging)
/// through participating media: medium vertices on both subpaths, connections weighed by the transmittance
/// through media and past surfaces that are not there, light subpaths
/// starting in the medium around their light (the sky's from outside the
/// room). The same image as the volumetric path tracer's, in a room of
/// homogeneous media and with the tinted ball a voxel grid (delta and
/// ratio tracking); and with the fog everywhere (no room), where the sky's
/// light never arrives.
#[test]
fn bdpt_and_vcm_agree_with_the_volumetric_path_tracer_through_media() {
    let d = trazo::scene::native::parse(FOG_ROOM, Path::new("<fog-room>")).unwrap();
    let mut bdpt = d.clone();
    bdpt.settings.integrator = IntegratorKind::Bdpt;
    let warnings = trazo::scene::build(&bdpt).unwrap().warnings;
    assert!(!warnings.iter().any(|w| w.contains("media")), "{warnings:?}");
    same_as("fog room", &d, IntegratorKind::Bdpt, (IntegratorKind::VolPath, 1));
    // Vertex connection and merging: the same connections, and merges on
    // the surfaces (within a small radius, as the Cornell box's test).
    let mut vcm = d.clone();
    vcm.settings.photon.radius = 0.02;
    same_as("fog room, vcm", &vcm, IntegratorKind::Vcm, (IntegratorKind::VolPath, 1));

    let mut grid = d.clone();
    let values: Vec<f32> = (0..64 * 3).map(|i| ((i * 7) % 10) as f32 * 0.4).collect();
    let tint = grid.media.iter_mut().find(|m| m.name == "tint").unwrap();
    tint.sigma_t = FieldDesc::Grid {
        source: GridSource::Data(std::sync::Arc::new(
            trazo::media::VoxelGrid::new([4, 4, 4], 3, values).unwrap(),
        )),
        to_world: vec![
            TransformOp::Translate(trazo::Vec3::splat(-0.5)),
            TransformOp::Scale(trazo::Vec3::splat(1.0)),
            TransformOp::Translate(trazo::Vec3::new(0.2, 0.5, 0.5)),
        ],
        use_file_bounds: false,
    };
    same_as(
        "fog room, grid",
        &grid,
        IntegratorKind::Bdpt,
        (IntegratorKind::VolPath, 1),
    );

    // Without the room, and without the glass ball, whose milk the
    // volumetric path tracer lights only by finding the lamp (through
    // rough glass, light sampling is blocked).
    // The tinted ball glowing: emission that only the camera's flights
    // find.
    let mut glowing = d.clone();
    glowing.media.iter_mut().find(|m| m.name == "tint").unwrap().emission =
        Some(FieldDesc::Constant(trazo::color::Rgb::new(3.0, 1.5, 0.5)));
    same_as(
        "fog room, glowing ball",
        &glowing,
        IntegratorKind::Bdpt,
        (IntegratorKind::VolPath, 1),
    );

    let mut open = d.clone();
    open.shapes.retain(
        |s| !matches!(s.material.as_deref(), Some("boundary") if s.media.as_ref().is_some_and(|m| m.outside.is_none())),
    );
    open.shapes.retain(|s| s.material.as_deref() != Some("glass"));
    assert_eq!(open.shapes.len(), d.shapes.len() - 2);
    let mean_of = |integrator, spp_scale| {
        let mut d = open.clone();
        d.settings.spp *= spp_scale;
        let blocks = blocks_over_seeds(&d, integrator, 16);
        let n = blocks.len() as f64;
        let mean = blocks.iter().map(|(m, _)| m).sum::<f64>() / n;
        let error = blocks.iter().map(|(_, e)| e * e).sum::<f64>().sqrt() / n;
        (mean, error)
    };
    // The whole image: the volumetric path tracer's blocks are noisy here.
    let ((mb, sb), (mv, sv)) = (mean_of(IntegratorKind::Bdpt, 1), mean_of(IntegratorKind::VolPath, 8));
    let z = (mb - mv) / (sb * sb + sv * sv).sqrt();
    assert!(
        z.abs() < 5.0 && sb < 0.01 * mb && sv < 0.01 * mv,
        "fog everywhere: bdpt {mb} ± {sb}, volpath {mv} ± {sv}"
    );
}

/// The strategies' images (pbrt-v4's `visualizeweights` and
/// `visualizestrategies`): the weighted ones sum to the image, and the
/// unweighted images of one path length estimate the same light, each by
/// one strategy alone: direct light by next-event estimation (1, 2) and by
/// light tracing (2, 1) agree over 8 seeds within five standard errors.
#[test]
fn the_strategies_images_sum_to_the_image_and_each_estimates_its_paths() {
    let mut d = small_cornell();
    d.settings.integrator = IntegratorKind::Bdpt;
    d.settings.bdpt_strategies = true;
    d.settings.max_depth = 4;
    d.settings.spp = 16;
    let (mut direct_nee, mut direct_light) = (Vec::new(), Vec::new());
    for seed in 0..8 {
        d.settings.seed = seed;
        let out = render(&trazo::scene::build(&d).unwrap(), &RenderOptions::default()).unwrap();
        // Up to 4 segments: 1 + 3 + 4 + 5 strategies, two images each.
        assert_eq!(out.extra.len(), 26);
        let image = out.film.to_image();
        let images: Vec<_> = out
            .extra
            .iter()
            .map(|(name, f)| (name.as_str(), f.to_image()))
            .collect();
        for i in 0..image.pixels.len() {
            let sum = images
                .iter()
                .filter(|(n, _)| !n.ends_with("_unweighted"))
                .fold(trazo::Rgb::ZERO, |acc, (_, im)| acc + im.pixels[i]);
            let p = image.pixels[i];
            assert!(
                (sum - p).abs().max_element() <= 1e-4 * (1.0 + p.max_element()),
                "pixel {i}: strategies sum to {sum}, the image is {p}"
            );
        }
        let mean_of = |name: &str| {
            let (_, im) = images.iter().find(|(n, _)| *n == name).unwrap();
            luminance(im.mean()) as f64
        };
        direct_nee.push(mean_of("bdpt_d01_s01_t02_unweighted"));
        direct_light.push(mean_of("bdpt_d01_s02_t01_unweighted"));
        if seed == 0 {
            let has = |name: &str| images.iter().any(|(n, _)| *n == name);
            assert!(has("bdpt_d00_s00_t02") && has("bdpt_d03_s04_t01_unweighted") && has("bdpt_d03_s00_t05"));
            assert!(!has("bdpt_d00_s01_t01") && !images.iter().any(|(n, _)| n.starts_with("bdpt_d04")));
        }
    }
    let stats = |v: &[f64]| {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        (
            m,
            (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt(),
        )
    };
    let ((a, sa), (b, sb)) = (stats(&direct_nee), stats(&direct_light));
    let z = (a - b) / (sa * sa + sb * sb).sqrt();
    assert!(
        a > 0.01 && z.abs() < 5.0,
        "direct light: NEE {a} ± {sa}, light tracing {b} ± {sb} (z = {z:.2})"
    );
}

/// A diffuse floor under a point light, seen from above, with a clear
/// sheet (a smooth dielectric of index 1: every ray passes it unbent) between
/// the floor and both the light and the camera. Shadow rays stop at the
/// sheet, the point light cannot be hit and the floor cannot be joined
/// to the lens through it: every path is light → sheet → floor → sheet →
/// camera, which only merging can make. So vertex connection and merging
/// must render the floor as the path tracer renders it without the
/// sheet, while bidirectional path tracing renders it black.
#[test]
fn vcm_merges_light_that_no_connection_reaches() {
    let scene = |sheet: bool| {
        let text = format!(
            r#"
[render]
width = 32
height = 32
spp = 64
max_depth = 4

[camera]
from = [0, 3, 0.01]
to = [0, 0, 0]
fov = 30

[[material]]
name = "floor"
type = "diffuse"
reflectance = 0.7

[[material]]
name = "clear"
type = "dielectric"
ior = 1.0

[[light]]
type = "point"
position = [0.5, 2.5, 0.3]
intensity = [5, 5, 5]

[[shape]]
type = "rectangle"
corner = [-4, 0, -4]
edge_u = [0, 0, 8]
edge_v = [8, 0, 0]
material = "floor"
{}
"#,
            if sheet {
                "[[shape]]\ntype = \"rectangle\"\ncorner = [-4, 1.5, -4]\nedge_u = [0, 0, 8]\nedge_v = [8, 0, 0]\nmaterial = \"clear\""
            } else {
                ""
            }
        );
        trazo::scene::native::parse(&text, Path::new("<clear-sheet>")).unwrap()
    };
    let with_sheet = scene(true);
    let mut bdpt = with_sheet.clone();
    bdpt.settings.integrator = IntegratorKind::Bdpt;
    bdpt.settings.spp = 4;
    let image = render(&trazo::scene::build(&bdpt).unwrap(), &RenderOptions::default())
        .unwrap()
        .film
        .to_image();
    let brightest = image.pixels.iter().map(|p| p.max_element()).fold(0.0f32, f32::max);
    assert!(brightest == 0.0, "BDPT found a path through the sheet: {brightest}");
    // Merging alone, of 32² light paths an iteration: many iterations.
    let mut many = with_sheet.clone();
    many.settings.spp = 512;
    let vcm = blocks_over_seeds(&many, IntegratorKind::Vcm, 16);
    let path = blocks_over_seeds(&scene(false), IntegratorKind::Path, 16);
    let mut worst: f64 = 0.0;
    for (b, ((mv, sv), (mp, sp))) in vcm.iter().zip(&path).enumerate() {
        let z = (mv - mp) / (sv * sv + sp * sp).sqrt();
        worst = worst.max(z.abs());
        assert!(
            z.abs() < 5.0,
            "block {b}: vcm {mv} ± {sv}, path {mp} ± {sp} (z = {z:.2})"
        );
        assert!(sv / mv < 0.02, "block {b}: vcm {mv} ± {sv}, too noisy to judge");
    }
    eprintln!("clear sheet: largest |z| over {} blocks {worst:.2}", vcm.len());
}
