//! Motion blur: shapes moving while the shutter is open, against the
//! fraction of the shutter interval for which they cover each pixel.

use std::path::Path;
use trazo::film::Film;
use trazo::render::{RenderOptions, render};
use trazo::scene::SceneDesc;

const WIDTH: u32 = 32;
const HEIGHT: u32 = 6;
const SPP: u32 = 256;

/// A black bar 0.5 wide, in front of a white background, seen by an
/// orthographic camera spanning x ∈ [−1, 1]. It moves from x = −0.5 at
/// time 0 to x = 0.5 at time 1; the shutter is open from 0 to 0.5.
fn moving_bar(integrator: &str, shape: &str) -> String {
    format!(
        r#"
[render]
width = {WIDTH}
height = {HEIGHT}
spp = {SPP}
integrator = "{integrator}"
filter = "box"
max_depth = 4

[camera]
type = "orthographic"
size = 0.375
from = [0, 0, 5]
to = [0, 0, 0]
shutter = [0, 0.5]

[world]
background = [1, 1, 1]

[[material]]
name = "black"
type = "diffuse"
reflectance = 0

[[shape]]
material = "black"
{shape}
transform = [{{ translate = [-0.5, 0, 0] }}]
transform_end = [{{ translate = [0.5, 0, 0] }}]
motion_times = [0, 1]
"#
    )
}

const RECTANGLE: &str = r#"type = "rectangle"
corner = [-0.25, -2, 0]
edge_u = [0.5, 0, 0]
edge_v = [0, 4, 0]"#;

const MESH: &str = r#"type = "mesh"
positions = [[-0.25, -2, 0], [0.25, -2, 0], [0.25, 2, 0], [-0.25, 2, 0]]
indices = [0, 1, 2, 0, 2, 3]"#;

fn render_film(text: &str) -> Film {
    let d: SceneDesc = trazo::scene::native::parse(text, Path::new("test.toml")).unwrap();
    let scene = trazo::scene::build(&d).unwrap();
    render(&scene, &RenderOptions::default()).unwrap().film
}

/// The fraction of the shutter interval [0, 0.5] during which the bar
/// (centre −0.5 + u at time u, half-width 0.25) covers x.
fn covered(x: f64) -> f64 {
    let (a, b) = ((x + 0.25).max(0.0), (x + 0.75).min(0.5));
    (b - a).max(0.0) / 0.5
}

/// What column `x` sees: 1 − the bar's mean coverage over the column's
/// span of x (`mirrored`: world +x on the image's left).
fn expected_column(x: u32, mirrored: bool) -> f64 {
    let pixel = 2.0 / WIDTH as f64;
    let column = if mirrored { WIDTH - 1 - x } else { x };
    let x0 = -1.0 + column as f64 * pixel;
    let steps = 1000;
    1.0 - (0..steps)
        .map(|i| covered(x0 + (i as f64 + 0.5) * pixel / steps as f64))
        .sum::<f64>()
        / steps as f64
}

/// Each column's mean against 1 − the bar's mean coverage over the
/// column's span of x, within 5 standard errors: the film's estimate, or
/// where it has none (SPPM's) or is smaller, that of a path tracer's
/// samples, each 0 or 1. `mirrored`: world +x is on the image's left (as
/// pbrt-v4's left-handed camera space puts it).
fn check_profile(f: &Film, mirrored: bool, what: &str) {
    for x in 0..WIDTH {
        let expected = expected_column(x, mirrored);
        let (mut mean, mut var) = (0.0f64, 0.0f64);
        for y in 0..HEIGHT {
            let p = &f.pixels[(y * WIDTH + x) as usize];
            mean += p.value().x as f64;
            var += p.variance_of_mean();
        }
        let n = HEIGHT as f64;
        let bernoulli = (expected * (1.0 - expected) / (SPP as f64 * n)).sqrt();
        let (mean, sigma) = (mean / n, (var.sqrt() / n).max(bernoulli));
        assert!(
            (mean - expected).abs() <= 5.0 * sigma + 2e-3,
            "{what}: column {x} is {mean:.4} ± {sigma:.4}, expected {expected:.4}"
        );
    }
}

#[test]
fn a_moving_bar_is_blurred_over_the_shutter_interval() {
    for integrator in ["path", "volpath", "bdpt", "sppm", "whitted", "photon", "vcm"] {
        for (shape, name) in [(RECTANGLE, "rectangle"), (MESH, "mesh")] {
            let f = render_film(&moving_bar(integrator, shape));
            check_profile(&f, false, &format!("{integrator}, {name}"));
        }
    }
}

/// A camera moving past a still bar (`from_end`, `to_end`) sees what a
/// still camera sees of the bar moving the other way.
#[test]
fn a_moving_camera_blurs_what_it_passes() {
    let text = moving_bar("path", MESH)
        .replace(
            "from = [0, 0, 5]\nto = [0, 0, 0]",
            "from = [0.5, 0, 5]\nto = [0.5, 0, 0]\nfrom_end = [-0.5, 0, 5]\nto_end = [-0.5, 0, 0]",
        )
        .replace("transform = [{ translate = [-0.5, 0, 0] }]\n", "")
        .replace(
            "transform_end = [{ translate = [0.5, 0, 0] }]\nmotion_times = [0, 1]\n",
            "",
        );
    assert!(text.contains("from_end") && !text.contains("transform_end"), "{text}");
    check_profile(&render_film(&text), false, "moving camera");
}

/// Without a shutter interval (it opens and closes at once) the bar stands
/// where it is at that time: a sharp image of it.
#[test]
fn a_closed_shutter_freezes_the_motion() {
    let text = moving_bar("path", RECTANGLE).replace("shutter = [0, 0.5]", "shutter = [0.25, 0.25]");
    let f = render_film(&text);
    // At time 0.25 the bar spans x ∈ [−0.5, 0]: columns 8 to 15.
    for x in 0..WIDTH {
        let v = f.pixels[x as usize].value().x;
        let expected = if (8..16).contains(&x) { 0.0 } else { 1.0 };
        assert_eq!(v, expected, "column {x}");
    }
}

/// An emitter cannot move (as in pbrt-v4): it stays where the shutter
/// opens, and the user is told.
#[test]
fn a_moving_emitter_stays_put_with_a_warning() {
    let text = moving_bar("path", RECTANGLE).replace("reflectance = 0", "reflectance = 0\nemission = [1, 1, 1]");
    let d: SceneDesc = trazo::scene::native::parse(&text, Path::new("test.toml")).unwrap();
    let scene = trazo::scene::build(&d).unwrap();
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("an emitting shape cannot move")),
        "{:?}",
        scene.warnings
    );
}

/// A pbrt-v4 scene of the bar: `camera` before `LookAt`, `bar` the
/// transform directives before the bar's mesh, `light` what is seen behind
/// it (radiance 1).
fn pbrt_bar_scene(camera: &str, bar: &str, light: &str) -> SceneDesc {
    let text = format!(
        r#"
{camera}
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [-1 1 -0.1875 0.1875]
    "float shutteropen" 0 "float shutterclose" 0.5
Film "rgb" "integer xresolution" 32 "integer yresolution" 6 "float iso" 200
PixelFilter "box"
Sampler "independent" "integer pixelsamples" 256
Integrator "path" "integer maxdepth" 4
TransformTimes 0 1
WorldBegin
{light}
Material "diffuse" "rgb reflectance" [0 0 0]
AttributeBegin
  {bar}
  Shape "trianglemesh" "point3 P" [-0.25 -2 0  0.25 -2 0  0.25 2 0  -0.25 2 0]
      "integer indices" [0 1 2 0 2 3]
AttributeEnd
"#
    );
    let d = trazo::scene::pbrt::parse(&text, Path::new("test.pbrt")).unwrap();
    assert_eq!(d.camera.shutter, (0.0, 0.5));
    d
}

fn pbrt_bar(camera: &str, bar: &str) -> Film {
    let scene = trazo::scene::build(&pbrt_bar_scene(camera, bar, SKY)).unwrap();
    render(&scene, &RenderOptions::default()).unwrap().film
}

const SKY: &str = r#"LightSource "infinite" "rgb L" [1 1 1]"#;

/// An emitting wall behind the bar, which light paths reach (the sky they
/// cannot).
const WALL: &str = r#"AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1] "bool twosided" true
  Shape "trianglemesh" "point3 P" [-5 -5 -1  5 -5 -1  5 5 -1  -5 5 -1] "integer indices" [0 1 2 0 2 3]
AttributeEnd"#;

const MOVING_CAMERA: &str =
    "ActiveTransform StartTime\nTranslate 0.5 0 0\nActiveTransform EndTime\nTranslate -0.5 0 0\nActiveTransform All";

/// pbrt-v4's `ActiveTransform` and `TransformTimes` give the shape its two
/// transforms, and the camera's `shutteropen` and `shutterclose` its
/// interval; the render is the same blur.
#[test]
fn pbrt_motion_renders_the_same_blur() {
    let f = pbrt_bar(
        "",
        "ActiveTransform StartTime\n  Translate -0.5 0 0\n  ActiveTransform EndTime\n  Translate 0.5 0 0\n  ActiveTransform All",
    );
    check_profile(&f, true, "pbrt, moving bar");
}

/// A camera moving the other way past a still bar sees the same: its
/// transform before `Camera` given at both times. (pbrt-v4's camera space
/// has +x toward world −x here, so a camera-space shift of +0.5 puts the
/// bar where the moving bar starts.)
#[test]
fn a_moving_pbrt_camera_blurs_what_it_passes() {
    let f = pbrt_bar(MOVING_CAMERA, "");
    check_profile(&f, true, "pbrt, moving camera");
}

/// Light paths connect to a moving camera where it is at their time:
/// under `bdpt` and `vcm` too the moving camera sees the blur (the light
/// tracer below).
#[test]
fn light_paths_meet_a_moving_camera_where_it_is() {
    for integrator in ["bdpt", "vcm"] {
        let mut d = pbrt_bar_scene(MOVING_CAMERA, "", WALL);
        assert!(d.camera.motion.is_some());
        d.settings.integrator = trazo::settings::IntegratorKind::from_name(integrator).unwrap();
        let scene = trazo::scene::build(&d).unwrap();
        let f = render(&scene, &RenderOptions::default()).unwrap().film;
        check_profile(&f, true, &format!("{integrator}, moving camera"));
    }
}

/// The light tracer's splats reach a moving camera where it is at their
/// path's time. Its pixels are noisier than a path tracer's and the film
/// keeps no variance of splats, so each column's error is estimated from
/// the spread of its 48 rows, which see the same coverage.
#[test]
fn the_light_tracer_meets_a_moving_camera_where_it_is() {
    let rows = 48u32;
    let mut d = pbrt_bar_scene(MOVING_CAMERA, "", WALL);
    d.settings.integrator = trazo::settings::IntegratorKind::Light;
    d.settings.height = rows;
    d.settings.spp = 1024;
    // Square pixels again: the view's height grows with the rows (x
    // still spans [−1, 1]), and the bar still spans every row.
    d.camera.projection = trazo::scene::desc::ProjectionDesc::Orthographic {
        size: 2.0 * rows as f32 / WIDTH as f32,
    };
    let scene = trazo::scene::build(&d).unwrap();
    let f = render(&scene, &RenderOptions::default()).unwrap().film;
    for x in 0..WIDTH {
        let expected = expected_column(x, true);
        let values: Vec<f64> = (0..rows)
            .map(|y| f.pixels[(y * WIDTH + x) as usize].value().x as f64)
            .collect();
        let n = rows as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
        let sigma = (var / n).sqrt();
        assert!(
            (mean - expected).abs() <= 5.0 * sigma + 2e-3,
            "column {x} is {mean:.4} ± {sigma:.4}, expected {expected:.4}"
        );
    }
}
