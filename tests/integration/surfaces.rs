//! Implicit and parametric surfaces: signed distance functions (sphere
//! traced), equations (roots found by interval arithmetic) and quadrics cut
//! to heights and angles. White furnaces of non-convex and open ones (a ray
//! that met its own surface again on leaving would darken them), a sphere
//! of each kind against the analytic sphere under every integrator, the
//! `steps` image, and light sampled from cut quadrics against BSDF
//! sampling. Tolerances come from each render's own per-pixel variance or
//! from the spread over seeds.

use std::f32::consts::PI;
use std::path::Path;
use trazo::color::luminance;
use trazo::film::{Aov, Film};
use trazo::render::{RenderOptions, render};
use trazo::scene::SceneDesc;
use trazo::scene::desc::ShapeKind;

fn parse(text: &str) -> SceneDesc {
    trazo::scene::native::parse(text, Path::new("test.toml")).unwrap()
}

fn render_film(d: &SceneDesc, aovs: bool) -> Film {
    let scene = trazo::scene::build(d).unwrap();
    let options = RenderOptions {
        aovs,
        ..RenderOptions::default()
    };
    render(&scene, &options).unwrap().film
}

const FURNACE: &str = r#"
[render]
width = 24
height = 24
spp = 48
max_depth = 128
rr_depth = 128

[camera]
from = [0, 0.5, 5]
to = [0, 0, 0]
fov = 40

[world]
background = [1, 1, 1]

[[material]]
name = "white"
type = "diffuse"
reflectance = 1
"#;

/// Every pixel of a furnace is 1 within 5 of its standard errors, and the
/// image's mean within 4 standard errors of the mean.
fn assert_white(f: &Film, what: &str) {
    for (i, p) in f.pixels.iter().enumerate() {
        let v = p.value();
        let sigma = p.variance_of_mean().sqrt() as f32;
        assert!(
            (v.x - 1.0).abs() <= 5.0 * sigma + 1e-4,
            "{what}: pixel {i} = {v} ± {sigma}"
        );
    }
    let (mean, err) = mean_and_error(f);
    assert!((mean - 1.0).abs() <= 4.0 * err + 1e-5, "{what}: mean {mean} ± {err}");
}

/// The image's mean luminance and its standard error.
fn mean_and_error(f: &Film) -> (f64, f64) {
    let n = f.pixels.len() as f64;
    let mean = f.pixels.iter().map(|p| luminance(p.value()) as f64).sum::<f64>() / n;
    let var: f64 = f.pixels.iter().map(|p| p.variance_of_mean()).sum::<f64>() / (n * n);
    (mean, var.sqrt())
}

#[test]
fn white_furnaces_of_distance_functions_render_one() {
    let shapes = [
        // Concave, sheared and scaled, with a smooth blend.
        r#"sdf = { difference = [{ box = 0.6, round = 0.08 }, { sphere = 0.75 }], smooth = 0.05 }
transform = [{ scale = [1, 1.6, 0.7] }, { shear = { xy = 0.4 } }, { rotate = { axis = [1, 1, 0], angle = 30 } }]"#,
        // Twisted: a value that is only a bound, scaled by the twist.
        r#"sdf = { twist = { box = [0.5, 1.0, 0.5] }, rate = 1.6 }"#,
        // Repeated, with a displaced member.
        r#"sdf = { repeat = { displace = { torus = [0.3, 0.12] }, amplitude = 0.03, frequency = 8 }, period = [1, 1, 1], count = [1, 1, 0] }"#,
    ];
    for (i, shape) in shapes.iter().enumerate() {
        let text = format!("{FURNACE}\n[[shape]]\ntype = \"sdf\"\nmaterial = \"white\"\n{shape}\n");
        assert_white(&render_film(&parse(&text), false), &format!("shape {i}"));
    }
}

#[test]
fn white_furnaces_of_implicit_surfaces_render_one() {
    let shapes = [
        // Taubin's heart: concave, with a cusp.
        r#"equation = "(x^2 + 9/4 y^2 + z^2 - 1)^3 - x^2 z^3 - 9/80 y^2 z^3"
bounds = [[-1.5, -1, -1.5], [1.5, 1, 1.5]]
transform = [{ rotate = { axis = [1, 0, 0], angle = -90 } }]"#,
        // A superellipsoid, sheared.
        r#"equation = "x^4 + y^4 + z^4 = 1"
bounds = [[-1.1, -1.1, -1.1], [1.1, 1.1, 1.1]]
transform = [{ shear = { xy = 0.5 } }, { rotate = { axis = [0, 1, 1], angle = 40 } }]"#,
    ];
    for (i, shape) in shapes.iter().enumerate() {
        let text = format!("{FURNACE}\n[[shape]]\ntype = \"implicit\"\nmaterial = \"white\"\n{shape}\n");
        assert_white(&render_film(&parse(&text), false), &format!("shape {i}"));
    }
}

/// The unit sphere at (0, 1, 0) written three ways.
#[derive(Clone, Copy, Debug, PartialEq)]
enum SphereAs {
    Analytic,
    DistanceFunction,
    Equation,
}

/// A diffuse sphere on a floor lit by a point light and a uniform sky,
/// with `integrator`.
fn lit_sphere(integrator: &str, kind: SphereAs) -> SceneDesc {
    let shape = match kind {
        SphereAs::DistanceFunction => "type = \"sdf\"\nsdf = { sphere = 1 }\ntransform = [{ translate = [0, 1, 0] }]",
        SphereAs::Equation => {
            "type = \"implicit\"\nequation = \"x^2 + (y - 1)^2 + z^2 = 1\"\nbounds = [[-1.1, -0.1, -1.1], [1.1, 2.1, 1.1]]"
        }
        SphereAs::Analytic => "type = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1",
    };
    parse(&format!(
        r#"
[render]
width = 24
height = 24
spp = 64
max_depth = 6
integrator = "{integrator}"
photons = 20000

[camera]
from = [0, 2, 5]
to = [0, 0.8, 0]
fov = 45

[world]
background = [0.2, 0.25, 0.3]

[[material]]
name = "grey"
type = "diffuse"
reflectance = 0.6

[[light]]
type = "point"
position = [2, 4, 3]
intensity = 20

[[shape]]
{shape}
material = "grey"

[[shape]]
type = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]
material = "grey"
"#
    ))
}

/// Under every integrator, the image's mean agrees between the three within
/// 4.5 standard errors of the difference, estimated from renders of six
/// seeds each (photon mapping's and SPPM's noise is not in their films'
/// variances), plus 0.5 % for the marcher's ε.
#[test]
fn spheres_as_distance_functions_and_equations_render_as_the_sphere_under_every_integrator() {
    const SEEDS: u64 = 6;
    let mean_and_var = |integrator: &str, kind: SphereAs| {
        let mut d = lit_sphere(integrator, kind);
        let means: Vec<f64> = (0..SEEDS)
            .map(|seed| {
                d.settings.seed = seed;
                let f = render_film(&d, false);
                f.pixels.iter().map(|p| luminance(p.value()) as f64).sum::<f64>() / f.pixels.len() as f64
            })
            .collect();
        let m = means.iter().sum::<f64>() / SEEDS as f64;
        let var = means.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (SEEDS - 1) as f64;
        (m, var / SEEDS as f64)
    };
    for integrator in ["path", "whitted", "photon", "sppm", "volpath"] {
        let (ma, va) = mean_and_var(integrator, SphereAs::Analytic);
        assert!(ma > 0.05);
        for kind in [SphereAs::DistanceFunction, SphereAs::Equation] {
            let (mb, vb) = mean_and_var(integrator, kind);
            let allowed = 4.5 * (va + vb).sqrt() + 0.005 * ma;
            assert!(
                (ma - mb).abs() <= allowed,
                "{integrator}: mean {ma} (sphere) and {mb} ({kind:?}), allowed difference {allowed}"
            );
        }
    }
}

#[test]
fn the_steps_image_counts_the_marchers_work_where_it_marched() {
    let d = lit_sphere("path", SphereAs::DistanceFunction);
    let f = render_film(&d, true);
    let steps = f.aov_image(Aov::Steps).unwrap();
    let scene = trazo::scene::build(&d).unwrap();
    let (mut on, mut off) = (0, 0);
    for y in 0..24 {
        for x in 0..24 {
            let centre = trazo::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let ray = scene.camera.generate_ray(centre, trazo::Vec2::ZERO);
            let s = steps.get(x, y).x;
            let hits_sdf = scene
                .intersect(&ray)
                .is_some_and(|h| (h.p - trazo::Vec3::new(0.0, 1.0, 0.0)).length() < 1.01);
            if hits_sdf {
                on += 1;
                assert!(s >= 2.0, "pixel ({x}, {y}) on the sphere took {s} steps");
            }
            // Rays that miss the distance function's bounds take no step.
            if s == 0.0 {
                off += 1;
            }
        }
    }
    assert!(on > 30 && off > 30, "{on} pixels on the sphere, {off} without steps");
    // Without distance functions the image is zero.
    let plain = render_film(&lit_sphere("path", SphereAs::Analytic), true);
    assert!(plain.aov_image(Aov::Steps).unwrap().pixels.iter().all(|p| p.x == 0.0));
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
    let text = format!("{FURNACE}{shapes}");
    assert_white(&render_film(&parse(&text), false), "cut quadrics");
}

/// A floor lit only by `emitter` (a cut quadric of emission 4), rendered
/// with `sampling`.
fn lit_by(emitter: &str, sampling: &str) -> Film {
    render_film(
        &parse(&format!(
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
        )),
        false,
    )
}

/// A floor lit only by `lamp` (pbrt-v4 shape lines, emitting 4 from both
/// sides, after `transform` lines), read by the pbrt-v4 reader and rendered
/// with `sampling`; no warning may name the lamp's shape `kind`.
fn pbrt_lit_by(transform: &str, lamp: &str, kind: &str, sampling: &str) -> Film {
    let scene = format!(
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
{transform}
{lamp}
AttributeEnd
"#
    );
    let mut d = trazo::scene::pbrt::parse(&scene, Path::new("test.pbrt")).unwrap();
    assert!(!d.warnings.iter().any(|w| w.contains(kind)), "{:?}", d.warnings);
    d.settings.sampling = trazo::settings::PathSampling::from_name(sampling).unwrap();
    let s = trazo::scene::build(&d).unwrap();
    render(&s, &RenderOptions::default()).unwrap().film
}

/// The floor's mean under MIS and under BSDF sampling alone agree within
/// 4.5 standard errors of their difference (and the floor is lit).
/// The mean over pixels of the squared difference in luminance between
/// two renders with seeds 1 and 2 (`render(seed)`): twice the variance of
/// a pixel, splats included.
fn seed_noise(render: impl Fn(u32) -> Film) -> f64 {
    let [a, b] = [1, 2].map(render);
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (luminance(p.value()) as f64 - luminance(q.value()) as f64).powi(2))
        .sum::<f64>()
        / a.pixels.len() as f64
}

fn check_mis_agrees(mis: &Film, bsdf: &Film, what: &str) {
    let (a, ea) = mean_and_error(mis);
    let (b, eb) = mean_and_error(bsdf);
    assert!(a > 0.01, "{what}: the floor is lit ({a})");
    assert!(
        (a - b).abs() <= 4.5 * (ea * ea + eb * eb).sqrt(),
        "{what}: MIS {a} ± {ea}, BSDF sampling {b} ± {eb}"
    );
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
    check_mis_agrees(&lit_by(sphere, "mis"), &lit_by(sphere, "bsdf"), "cut sphere");
    // A cone, a paraboloid and a hyperboloid, cut by phimax, tilted above
    // the floor, emitting from their outsides.
    let tilted = "transform = [{ rotate = { axis = [1, 0, 0], angle = 120 } }, { translate = [0, 1.4, 0] }]";
    for (what, shape) in [
        ("cone", "type = \"cone\"\nradius = 0.6\nheight = 0.8\nphimax = 280"),
        (
            "paraboloid",
            "type = \"paraboloid\"\nradius = 0.6\nzmin = 0.1\nzmax = 0.7\nphimax = 300",
        ),
        (
            "hyperboloid",
            "type = \"hyperboloid\"\np1 = [0.5, 0, -0.4]\np2 = [0.2, 0.4, 0.4]\nphimax = 250",
        ),
    ] {
        let lamp = format!("[[shape]]\n{shape}\n{tilted}");
        check_mis_agrees(&lit_by(&lamp, "mis"), &lit_by(&lamp, "bsdf"), what);
    }
    let tilt = "Translate 0 0 1.2\nRotate 150 1 0 0";
    for (i, (kind, shape)) in [("cylinder", pbrt_lamps[0]), ("disk", pbrt_lamps[1])]
        .into_iter()
        .enumerate()
    {
        check_mis_agrees(
            &pbrt_lit_by(tilt, shape, kind, "mis"),
            &pbrt_lit_by(tilt, shape, kind, "bsdf"),
            &format!("pbrt lamp {i}"),
        );
    }
}

/// Bent bilinear patches (pbrt-v4's `bilinearmesh`), intersected exactly:
/// a saddle and a twisted strip, seen from both sides, vanish in a white
/// furnace.
#[test]
fn white_furnaces_of_bilinear_patches_render_one() {
    let shapes = r#"
[[shape]]
type = "bilinear"
p00 = [-1.5, -0.5, 0.5]
p10 = [-0.5, -0.5, -0.5]
p01 = [-1.5, 0.5, -0.5]
p11 = [-0.5, 0.5, 0.5]
material = "white"

[[shape]]
type = "bilinear"
p00 = [0.2, -1, 0]
p10 = [1.2, -1, 0]
p01 = [0.2, 1, 0.8]
p11 = [1.2, 1, -0.8]
material = "white"
transform = [{ rotate = { axis = [0, 1, 0], angle = 30 } }]
"#;
    let text = format!("{FURNACE}{shapes}");
    assert_white(&render_film(&parse(&text), false), "bilinear patches");
}

/// A bent bilinear patch emitting: its points are drawn with pbrt-v4's
/// bilinear density, not uniformly by area, so the light's density must be
/// the one reported at each point for MIS to agree with BSDF sampling.
/// From TOML, and from a pbrt-v4 `bilinearmesh` of two bent patches with an
/// `AreaLightSource`.
#[test]
fn bent_bilinear_patch_lights_are_sampled_by_their_density() {
    // A steep saddle y = 1 + 2.5·x·z over [−0.6, 0.6]², facing down
    // (∂S/∂u × ∂S/∂v points to −y), two corners 0.1 above the floor, whose
    // area factor at the centre is 0.35 of that at its corners. (A uniform
    // density reported for pbrt-v4's draw makes MIS 2 % bright here, within
    // this test's noise; accel::aggregate's unit test
    // `bilinear_emitters_report_the_density_they_draw_with` sees it.)
    let lamp = "[[shape]]\ntype = \"bilinear\"\np00 = [-0.6, 1.9, -0.6]\np10 = [0.6, 0.1, -0.6]\np01 = [-0.6, 0.1, 0.6]\np11 = [0.6, 1.9, 0.6]";
    check_mis_agrees(&lit_by(lamp, "mis"), &lit_by(lamp, "bsdf"), "TOML patch");
    let mesh = r#"Shape "bilinearmesh" "point3 P" [-1 -0.5 1.4  0 -0.5 1  -1 0.5 1  0 0.5 1.6  1 -0.5 1.5  1 0.5 0.9]
  "integer indices" [0 1 2 3  1 4 3 5]"#;
    check_mis_agrees(
        &pbrt_lit_by("", mesh, "bilinearmesh", "mis"),
        &pbrt_lit_by("", mesh, "bilinearmesh", "bsdf"),
        "pbrt bilinearmesh",
    );
}

/// `shape` (a `[[shape]]` entry, which may use the material "white") on a
/// white floor at height `floor`, lit by a point light and a grey sky,
/// rendered with the `[render]` `settings` (and a depth of 3) through
/// `camera`.
fn on_lit_floor(settings: &str, camera: &str, floor: f32, shape: &str) -> Film {
    render_film(
        &parse(&format!(
            r#"
[render]
{settings}
max_depth = 3

[camera]
{camera}

[world]
background = [0.3, 0.35, 0.4]

[[material]]
name = "white"
type = "diffuse"
reflectance = 0.7

[[light]]
type = "point"
position = [1.5, 3, 2]
intensity = 6

[[shape]]
type = "plane"
point = [0, {floor}, 0]
material = "white"

{shape}
"#
        )),
        false,
    )
}

/// A bent bicubic Bézier patch (a saddle with two bulges) in TOML, row by
/// row.
const BEZIER_POINTS: &str = "points = [[-1.5, -1.5, 0.9], [-0.5, -1.5, 0.3], [0.5, -1.5, -0.3], [1.5, -1.5, -0.9],
  [-1.5, -0.5, 0.3], [-0.5, -0.5, 0.1], [0.5, -0.5, -1.0], [1.5, -0.5, -0.3],
  [-1.5, 0.5, -0.3], [-0.5, 0.5, 1.3], [0.5, 0.5, 0.1], [1.5, 0.5, 0.3],
  [-1.5, 1.5, -0.9], [-0.5, 1.5, -0.3], [0.5, 1.5, 0.3], [1.5, 1.5, 0.9]]";

/// Bézier patches intersected directly: they vanish in a white furnace
/// (no light leaks through or between the pieces the intersection splits
/// them into), render as a fine tessellation of themselves (`tessellate`),
/// and as lights their points' density is the one reported, so MIS agrees
/// with BSDF sampling.
#[test]
fn bezier_patches_vanish_in_a_furnace_match_their_tessellation_and_emit() {
    let patch = format!("[[shape]]\ntype = \"bezier\"\n{BEZIER_POINTS}\nmaterial = \"white\"\n");
    let tilted = "transform = [{ scale = 0.6 }, { rotate = { axis = [1, 0, 0], angle = 35 } }]";
    assert_white(
        &render_film(&parse(&format!("{FURNACE}{patch}{tilted}\n")), false),
        "Bézier patch",
    );

    // On a lit floor, against 64 × 64 quads of the same patch.
    let lit = |shape: &str| {
        let placed = format!(
            "{shape}\ntransform = [{{ scale = 0.5 }}, {{ rotate = {{ axis = [1, 0, 0], angle = -60 }} }}, {{ translate = [0, 0.9, 0] }}]"
        );
        let camera = "from = [0, 2.5, 4]\nto = [0, 0.5, 0]\nfov = 45";
        mean_and_error(&on_lit_floor(
            "width = 24\nheight = 24\nspp = 128",
            camera,
            0.0,
            &placed,
        ))
    };
    let (a, ea) = lit(&patch);
    let (b, eb) = lit(&format!("{patch}tessellate = 64\n"));
    assert!(
        (a - b).abs() <= 4.5 * (ea * ea + eb * eb).sqrt() + 1e-3 * b,
        "patch {a} ± {ea}, tessellation {b} ± {eb}"
    );

    let lamp = format!(
        "[[shape]]\ntype = \"bezier\"\n{BEZIER_POINTS}\ntransform = [{{ scale = 0.4 }}, {{ rotate = {{ axis = [1, 0, 0], angle = 90 }} }}, {{ translate = [0, 1.2, 0] }}]"
    );
    check_mis_agrees(&lit_by(&lamp, "mis"), &lit_by(&lamp, "bsdf"), "Bézier lamp");
}

/// Light subpaths start on emitting distance functions and implicit
/// surfaces (drawn through lines across them, weighed by MIS as uniform by
/// area): a floor lit only by way of a mirror, the lamp above a screen, is
/// a caustic that BDPT and VCM find from the lamp, and the path tracer only
/// where its paths hit the small lamp (as BDPT did before its light
/// subpaths started there): 24–50 times as noisy. Against the analytic
/// sphere's light subpaths, which draw its points by area, the lines
/// waste those that miss the lamp inside its bounding sphere: 2.3–7.7
/// times the noise, the equation's loose bounds the most. The images agree.
#[test]
fn light_subpaths_start_on_emitting_distance_functions_and_equations() {
    let scene = |lamp: &str, integrator: &str, seed: u32| {
        render_film(
            &parse(&format!(
                r#"
[render]
width = 24
height = 16
spp = 64
max_depth = 4
integrator = "{integrator}"
seed = {seed}

[camera]
from = [2, 1, 5]
to = [2, 0, 0]
fov = 40

[[material]]
name = "floor"
type = "diffuse"
reflectance = 0.8

[[material]]
name = "screen"
type = "diffuse"
reflectance = 0

[[material]]
name = "mirror"
type = "mirror"

[[material]]
name = "lamp"
type = "diffuse"
reflectance = 0
emission = 400

[[shape]]
type = "plane"
material = "floor"

# Below the lamp: no light reaches the floor in view directly.
[[shape]]
type = "rectangle"
corner = [-1, 1.5, 1]
edge_u = [2, 0, 0]
edge_v = [0, 0, -2]
material = "screen"

[[shape]]
type = "rectangle"
corner = [3.5, 0, 3]
edge_u = [0, 3, 0]
edge_v = [0, 0, -6]
material = "mirror"

{lamp}
material = "lamp"
"#
            )),
            false,
        )
    };
    let sphere = "[[shape]]\ntype = \"sphere\"\ncenter = [0, 2, 0]\nradius = 0.1";
    let sdf = "[[shape]]\ntype = \"sdf\"\nsdf = { sphere = 0.1 }\ntransform = [{ translate = [0, 2, 0] }]";
    let implicit = "[[shape]]\ntype = \"implicit\"\nequation = \"x^2 + (y - 2)^2 + z^2 - 0.01\"\nbounds = [[-0.15, 1.85, -0.15], [0.15, 2.15, 0.15]]";
    for integrator in ["bdpt", "vcm"] {
        let reference = seed_noise(|seed| scene(sphere, integrator, seed));
        for (what, lamp) in [("distance function", sdf), ("equation", implicit)] {
            let noise = seed_noise(|seed| scene(lamp, integrator, seed));
            let path = seed_noise(|seed| scene(lamp, "path", seed));
            assert!(
                noise < 0.1 * path && noise < 12.0 * reference,
                "{what}, {integrator}: mean squared difference of two seeds' images {noise}, {reference} for the analytic sphere, {path} by the path tracer"
            );
            check_mis_agrees(
                &scene(sphere, integrator, 3),
                &scene(lamp, integrator, 4),
                &format!("{what}, {integrator}"),
            );
        }
    }
}

/// The Utah teapot from its 32 patches (scenes/models/teapot.bpt, with
/// poles at the lid's top and the bottom's centre, where a patch's first
/// row is one point): it vanishes in a white furnace, and lit on a floor
/// it renders as a fine tessellation of the same patches, pixel by pixel:
/// the mean of the squared differences over their estimated variances is
/// at most about 1 for equal images (0.3 here: the stratified sampler's
/// error is below the variance its samples' spread suggests), and 3.5
/// against 3 × 3 quads a patch, whose facets show.
#[test]
fn the_teapot_from_its_patches_matches_their_tessellation() {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/models/teapot.bpt");
    let teapot = format!(
        "[[shape]]\ntype = \"bezier\"\nfile = \"{file}\"\nmaterial = \"white\"\n\
         transform = [{{ rotate = {{ axis = [1, 0, 0], angle = -70 }} }}, {{ scale = 0.55 }}, {{ translate = [0.1, -0.7, 0] }}]\n"
    );
    // Light that enters the pot by the gap between lid and rim bounces
    // hundreds of times before it leaves: paths must not be cut first.
    let deep = FURNACE.replace("max_depth = 128\nrr_depth = 128", "max_depth = 1024\nrr_depth = 1024");
    assert_ne!(deep, FURNACE);
    assert_white(&render_film(&parse(&format!("{deep}{teapot}")), false), "teapot");

    // Independent seeds: equal images then differ by their noise alone.
    let lit = |shape: &str, seed: u32| {
        let settings = format!("width = 32\nheight = 24\nspp = 256\nseed = {seed}");
        on_lit_floor(
            &settings,
            "from = [0, 1.5, 5]\nto = [0, -0.1, 0]\nfov = 40",
            -0.7,
            shape,
        )
    };
    let patches = lit(&teapot, 1);
    let mesh = lit(&format!("{teapot}tessellate = 48\n"), 2);
    // Over the pixels with noise (the background's have none).
    let z2: Vec<f64> = patches
        .pixels
        .iter()
        .zip(&mesh.pixels)
        .map(|(a, b)| {
            (
                luminance(a.value()) - luminance(b.value()),
                a.variance_of_mean() + b.variance_of_mean(),
            )
        })
        .filter(|&(_, v)| v > 0.0)
        .map(|(d, v)| (d as f64).powi(2) / v)
        .collect();
    let z2 = z2.iter().sum::<f64>() / z2.len() as f64;
    let ((a, ea), (b, eb)) = (mean_and_error(&patches), mean_and_error(&mesh));
    assert!(z2 < 1.0, "mean squared difference over variance {z2}");
    assert!(
        (a - b).abs() <= 4.5 * (ea * ea + eb * eb).sqrt(),
        "patches {a} ± {ea}, tessellation {b} ± {eb}"
    );
}

/// Newell's `.bpt` format: a file of two patches read as two shapes; a
/// malformed one is an error naming the file and the line.
#[test]
fn bpt_files_are_read_as_patches() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("2\n");
    for k in 0..2 {
        text += "3 3\n";
        for p in 0..16 {
            text += &format!(
                "{} {} {}\n",
                (p % 4) as f32 + 4.0 * k as f32,
                (p / 4) as f32,
                0.1 * (p % 3) as f32
            );
        }
    }
    std::fs::write(dir.path().join("two.bpt"), &text).unwrap();
    let scene = "[[shape]]\ntype = \"bezier\"\nfile = \"two.bpt\"\n";
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    let d = trazo::scene::load(&dir.path().join("scene.toml"), &[]).unwrap();
    assert_eq!(d.shapes.len(), 2);
    assert!(d.shapes.iter().all(|s| matches!(s.kind, ShapeKind::Bezier(_))));
    std::fs::write(dir.path().join("two.bpt"), text.replace("0.1", "x")).unwrap();
    let e = trazo::scene::load(&dir.path().join("scene.toml"), &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("scene.toml:3:8") && e.contains("two.bpt: line 4"), "{e}");
}

/// Distance functions and implicit surfaces may emit. They have no density
/// over their area, so lights sample them by direction (uniformly in the
/// cone of their bounding sphere, the point their first along it), and
/// light subpaths start on lines drawn through them. A floor lit by an
/// emitting sphere of either kind is lit as by the analytic sphere, by the
/// path tracer with MIS, volpath, BDPT, VCM, photon mapping, SPPM and
/// light tracing (the photons' power is checked closely in
/// `light::emission`'s tests); and next-event
/// estimation finds the lamp: with MIS the image is about as noisy as the
/// analytic sphere's, and less than with BSDF sampling alone.
#[test]
fn emitting_distance_functions_and_equations_are_sampled_by_direction() {
    let sphere = "[[shape]]\ntype = \"sphere\"\ncenter = [0, 1.2, 0]\nradius = 0.25";
    let sdf = "[[shape]]\ntype = \"sdf\"\nsdf = { sphere = 0.25 }\ntransform = [{ translate = [0, 1.2, 0] }]";
    let implicit = "[[shape]]\ntype = \"implicit\"\nequation = \"x^2 + (y - 1.2)^2 + z^2 - 0.0625\"\nbounds = [[-0.3, 0.9, -0.3], [0.3, 1.5, 0.3]]";
    let reference = lit_by(sphere, "mis");
    for (what, lamp) in [("distance function", sdf), ("equation", implicit)] {
        let d = parse(&format!(
            "{lamp}\nmaterial = \"lamp\"\n[[material]]\nname = \"lamp\"\nemission = 4\n"
        ));
        let scene = trazo::scene::build(&d).unwrap();
        assert!(scene.warnings.is_empty(), "{what}: {:?}", scene.warnings);
        assert_eq!(scene.lights.len(), 1, "{what}: the lamp is a light");
        // Its area, for its power, estimated by Crofton's formula: 4π/16.
        let trazo::light::Light::Area { area, .. } = &scene.lights[0] else {
            panic!("{what}: an area light")
        };
        assert!(
            (area.total / (PI / 4.0) - 1.0).abs() < 0.2,
            "{what}: area {} for π/4",
            area.total
        );
        let mis = lit_by(lamp, "mis");
        check_mis_agrees(&reference, &mis, what);
        let bsdf = lit_by(lamp, "bsdf");
        check_mis_agrees(&mis, &bsdf, what);
        let (e_mis, e_bsdf) = (mean_and_error(&mis).1, mean_and_error(&bsdf).1);
        // The pixels on the lamp's outline keep part of the noise (the
        // analytic sphere's MIS image has 0.62 of its BSDF image's), and
        // the bounding sphere's cone is wider than the lamp's.
        let e_reference = mean_and_error(&reference).1;
        assert!(
            e_mis < 0.75 * e_bsdf && e_mis < 1.2 * e_reference,
            "{what}: light samples find the lamp: standard error {e_mis} with MIS, {e_bsdf} with BSDF sampling, {e_reference} for the analytic sphere"
        );
        for integrator in ["volpath", "bdpt", "vcm", "photon", "sppm", "light"] {
            let film = lit_by(lamp, &format!("mis\"\nintegrator = \"{integrator}"));
            check_mis_agrees(&reference, &film, &format!("{what}, {integrator}"));
        }
    }
}

/// Subdivision surfaces from TOML: a Catmull–Clark cube of quads and a
/// Loop octahedron of triangles are closed, so they vanish in a white
/// furnace; the cube's corners reach (±½, ±½, ±½). Their smooth normals
/// lose the light of the cosine samples they send below the geometric
/// surface (pbrt-v4 loses it too): 0.13 % at levels 3 and 2, which BSDF
/// sampling alone, the furnace's only strategy, resolves; at levels 4 and
/// 3 it is 0.04 %, within the test's 4 standard errors.
#[test]
fn subdivision_surfaces_are_closed_and_vanish_in_a_furnace() {
    let cube = r#"
[[shape]]
type = "subdivision"
positions = [[-1, -1, -1], [1, -1, -1], [-1, 1, -1], [1, 1, -1], [-1, -1, 1], [1, -1, 1], [-1, 1, 1], [1, 1, 1]]
faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
levels = 4
material = "white"
transform = [{ rotate = { axis = [1, 1, 0], angle = 30 } }, { translate = [-0.9, 0, 0] }]
"#;
    let octahedron = r#"
[[shape]]
type = "subdivision"
scheme = "loop"
positions = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
levels = 3
material = "white"
transform = [{ translate = [0.9, 0, 0] }]
"#;
    let d = parse(&format!("{FURNACE}{cube}{octahedron}"));
    let ShapeKind::InlineMesh(trazo::scene::desc::MeshSource::Inline(mesh)) = &d.shapes[0].kind else {
        panic!("{:?}", d.shapes[0].kind)
    };
    assert_eq!(mesh.indices.len(), 6 * 256 * 2);
    assert!(
        (mesh.positions[7] - trazo::Vec3::splat(0.5)).length() < 1e-5,
        "{}",
        mesh.positions[7]
    );
    assert_white(&render_film(&d, false), "subdivision surfaces");
}

/// A NanoVDB level set (tests/data/nanovdb/torus.nvdb: a torus of radii
/// 0.6 and 0.25 about the y axis, centred at (0.3, −0.2, 0.1), sampled
/// every 0.05 in a narrow band, written with NVIDIA Warp) as an `sdfgrid`:
/// placed by the grid's own map and then `transform`, its surface lies
/// where the torus is, to a fraction of a voxel; rays through the hole
/// miss; it vanishes in a furnace; a fog volume is refused as an SDF.
#[test]
fn nanovdb_level_sets_are_sdf_grids_where_their_map_places_them() {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/nanovdb/torus.nvdb");
    let shape = format!(
        "[[shape]]\ntype = \"sdfgrid\"\nfile = \"{file}\"\nmaterial = \"white\"\ntransform = [{{ translate = [0, 1, 0] }}]\n"
    );
    let d = parse(&format!("{FURNACE}\n{shape}"));
    assert!(matches!(d.shapes[0].kind, ShapeKind::SdfGrid(_)));
    let scene = trazo::scene::build(&d).unwrap();
    let centre = trazo::Vec3::new(0.3, 0.8, 0.1);
    let torus = |p: trazo::Vec3| {
        let q = p - centre;
        let ring = (q.x * q.x + q.z * q.z).sqrt() - 0.6;
        (ring * ring + q.y * q.y).sqrt() - 0.25
    };
    let mut hits = 0;
    for k in 0..200 {
        // Rays from above, aimed at points of the tube's centre circle.
        let a = k as f32 * 0.0314159;
        let target = centre + 0.6 * trazo::Vec3::new(a.cos(), 0.0, a.sin());
        let origin = target + trazo::Vec3::new(0.3 * (k as f32).sin(), 2.0, 0.3 * (k as f32).cos());
        let ray = trazo::geometry::Ray::new(origin, (target - origin).normalize());
        let hit = scene.intersect(&ray).expect("a ray aimed at the tube hits it");
        assert!(
            torus(hit.p).abs() < 0.01,
            "hit at {} is {} off the torus",
            hit.p,
            torus(hit.p)
        );
        // The normal points out of the tube.
        let tube_centre = centre + 0.6 * (hit.p - centre).with_y(0.0).normalize();
        assert!(hit.ng.dot((hit.p - tube_centre).normalize()) > 0.95);
        hits += 1;
        // Straight down through the hole: nothing.
        let hole = trazo::geometry::Ray::new(
            centre + trazo::Vec3::new(0.1 * a.cos(), 2.0, 0.1 * a.sin()),
            -trazo::Vec3::Y,
        );
        assert!(scene.intersect(&hole).is_none());
    }
    assert_eq!(hits, 200);
    assert_white(&render_film(&d, false), "NanoVDB torus");

    // A fog volume is not a signed distance grid; a missing grid names the others.
    let smoke = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/nanovdb/smoke.nvdb");
    let text = format!("{FURNACE}\n[[shape]]\ntype = \"sdfgrid\"\nfile = \"{smoke}\"\ngrid = \"density\"\n");
    let e = trazo::scene::native::parse(&text, Path::new("test.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("test.toml:") && e.contains("not a level set"), "{e}");
    let text = format!("{FURNACE}\n[[shape]]\ntype = \"sdfgrid\"\nfile = \"{smoke}\"\n");
    let e = trazo::scene::native::parse(&text, Path::new("test.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("0 level sets") && e.contains("density, temperature"), "{e}");
}
