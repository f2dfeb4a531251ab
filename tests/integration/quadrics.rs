//! Quadrics cut to heights and angles (pbrt's partial spheres, cylinders,
//! disks with holes, and pbrt-v3's cones, paraboloids and hyperboloids):
//! white furnaces of the open surfaces render 1, and light sampled from
//! cut spheres, cylinders and annuli (next-event estimation by their area
//! samples) agrees with light found by BSDF sampling alone. Tolerances come
//! from each render's own per-pixel variance.

use std::path::Path;
use trazo::color::luminance;
use trazo::film::Film;
use trazo::render::{RenderOptions, render};

fn render_toml(text: &str) -> Film {
    let d = trazo::scene::native::parse(text, Path::new("test.toml")).unwrap();
    let scene = trazo::scene::build(&d).unwrap();
    render(&scene, &RenderOptions::default()).unwrap().film
}

/// The image's mean luminance and its standard error.
fn mean_and_error(f: &Film) -> (f64, f64) {
    let n = f.pixels.len() as f64;
    let mean = f.pixels.iter().map(|p| luminance(p.value()) as f64).sum::<f64>() / n;
    let var: f64 = f.pixels.iter().map(|p| p.variance_of_mean()).sum::<f64>() / (n * n);
    (mean, var.sqrt())
}

#[test]
fn white_furnaces_of_cut_quadrics_render_one() {
    // Open surfaces, seen from both sides (materials are two-sided).
    let shapes = r#"
[[shape]]
type = "sphere"
radius = 0.6
zmin = -0.3
phimax = 270
material = "white"
transform = [{ rotate = { axis = [1, 0, 0], angle = -60 } }, { translate = [-1.2, 0.6, 0] }]

[[shape]]
type = "cone"
radius = 0.5
height = 1
phimax = 300
material = "white"
transform = [{ rotate = { axis = [1, 0, 0], angle = -90 } }, { translate = [0, -0.8, 0] }]

[[shape]]
type = "paraboloid"
radius = 0.5
zmin = 0.1
zmax = 0.8
material = "white"
transform = [{ rotate = { axis = [1, 1, 0], angle = 50 } }, { translate = [1.2, 0.6, 0] }]

[[shape]]
type = "hyperboloid"
p1 = [0.5, 0, -0.5]
p2 = [0, 0.5, 0.5]
phimax = 200
material = "white"
transform = [{ translate = [1.2, -0.7, 0] }]
"#;
    let text = format!(
        r#"
[render]
width = 24
height = 24
spp = 48
max_depth = 128
rr_depth = 128

[camera]
from = [0, 0, 5]
to = [0, 0, 0]
fov = 45

[world]
background = [1, 1, 1]

[[material]]
name = "white"
type = "diffuse"
reflectance = 1
{shapes}"#
    );
    let f = render_toml(&text);
    for (i, p) in f.pixels.iter().enumerate() {
        let v = p.value();
        let sigma = p.variance_of_mean().sqrt() as f32;
        assert!((v.x - 1.0).abs() <= 5.0 * sigma + 1e-4, "pixel {i} = {v} ± {sigma}");
    }
    let (mean, err) = mean_and_error(&f);
    assert!((mean - 1.0).abs() <= 4.0 * err + 1e-5, "mean {mean} ± {err}");
}

/// A floor lit only by `emitter` (a cut quadric of emission 4), rendered
/// with `sampling`.
fn lit_by(emitter: &str, sampling: &str) -> Film {
    render_toml(&format!(
        r#"
[render]
width = 20
height = 20
spp = 256
max_depth = 2
sampling = "{sampling}"

[camera]
from = [0, 3, 4]
to = [0, 0, 0]
fov = 50

[[material]]
name = "floor"
type = "diffuse"
reflectance = 0.8

[[material]]
name = "lamp"
type = "diffuse"
reflectance = 0
emission = 4

[[shape]]
type = "plane"
material = "floor"

{emitter}
material = "lamp"
"#
    ))
}

#[test]
fn cut_quadric_lights_are_sampled_by_their_area() {
    // A dome open towards the floor, cut by phimax, emitting from its
    // inside.
    let sphere = "[[shape]]\ntype = \"sphere\"\nradius = 0.8\nzmin = 0\nphimax = 300\nflip_normals = true\ntransform = [{ rotate = { axis = [1, 0, 0], angle = -90 } }, { translate = [0, 1.2, 0] }]";
    // pbrt's cylinder and disk with a hole, cut by phimax.
    let pbrt_lamps = [
        r#"Shape "cylinder" "float radius" 0.4 "float zmin" -0.5 "float zmax" 0.5 "float phimax" 240"#,
        r#"Shape "disk" "float radius" 0.8 "float innerradius" 0.3 "float phimax" 270 "float height" 0"#,
    ];
    let check = |mis: &Film, bsdf: &Film, what: &str| {
        let (a, ea) = mean_and_error(mis);
        let (b, eb) = mean_and_error(bsdf);
        assert!(a > 0.01, "{what}: the floor is lit ({a})");
        let allowed = 4.5 * (ea * ea + eb * eb).sqrt();
        assert!(
            (a - b).abs() <= allowed,
            "{what}: MIS {a} ± {ea}, BSDF sampling {b} ± {eb}"
        );
    };
    check(&lit_by(sphere, "mis"), &lit_by(sphere, "bsdf"), "cut sphere");
    for (i, shape) in pbrt_lamps.iter().enumerate() {
        let scene = || {
            format!(
                r#"Integrator "path" "integer maxdepth" 2 "bool regularize" false
Sampler "independent" "integer pixelsamples" 256
Film "rgb" "integer xresolution" 20 "integer yresolution" 20 "string filename" "x.exr"
LookAt 0 -4 3  0 0 0  0 0 1
Camera "perspective" "float fov" 50
WorldBegin
Material "diffuse" "rgb reflectance" [0.8 0.8 0.8]
Shape "trianglemesh" "point3 P" [-20 -20 0 20 -20 0 20 20 0 -20 20 0] "integer indices" [0 1 2 0 2 3]
AttributeBegin
AreaLightSource "diffuse" "rgb L" [4 4 4] "bool twosided" true
Translate 0 0 1.2
Rotate 150 1 0 0
{shape}
AttributeEnd
"#
            )
        };
        let film = |sampling: &str| {
            let mut d = trazo::scene::pbrt::parse(&scene(), Path::new("test.pbrt")).unwrap();
            d.settings.sampling = trazo::settings::PathSampling::from_name(sampling).unwrap();
            let s = trazo::scene::build(&d).unwrap();
            render(&s, &RenderOptions::default()).unwrap().film
        };
        check(&film("mis"), &film("bsdf"), &format!("pbrt lamp {i}"));
    }
}
