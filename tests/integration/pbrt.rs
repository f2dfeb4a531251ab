//! pbrt-v4 scenes end to end: pbrt's camera conventions in rendered
//! images, instancing in the built scene, the Cornell box against the
//! native one, and the command line's errors (exit status 2, file:line:col)
//! and warnings for pbrt files.

use assert_cmd::Command;
use std::f32::consts::PI;
use std::fs;
use std::path::{Path, PathBuf};
use trazo::color::luminance;
use trazo::film::Film;
use trazo::render::{RenderOptions, render};
use trazo::scene::desc::SceneDesc;
use trazo::{Rgb, Vec2, Vec3};

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn parse(text: &str) -> SceneDesc {
    trazo::scene::pbrt::parse(text, Path::new("test.pbrt")).unwrap_or_else(|e| panic!("{e}"))
}

fn render_desc(desc: &SceneDesc) -> Film {
    let scene = trazo::scene::build(desc).unwrap_or_else(|e| panic!("{e}"));
    render(&scene, &RenderOptions::default()).unwrap().film
}

/// Mean colour of the pixels in columns `x0..x1` and rows `y0..y1`.
fn region_mean(film: &Film, (x0, x1): (u32, u32), (y0, y1): (u32, u32)) -> Rgb {
    let mut sum = Rgb::ZERO;
    for y in y0..y1 {
        for x in x0..x1 {
            sum += film.pixels[(y * film.width + x) as usize].value();
        }
    }
    sum / ((x1 - x0) * (y1 - y0)) as f32
}

/// A red sphere at +x and a green one at −x, seen by pbrt's `LookAt` from
/// +z: pbrt puts world +x on the image's left, and so must trazo.
#[test]
fn look_at_puts_world_x_on_the_left_as_pbrt_does() {
    let scene = r#"
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 30
Film "rgb" "integer xresolution" 48 "integer yresolution" 24
Sampler "independent" "integer pixelsamples" 4
Integrator "path" "integer maxdepth" 1
WorldBegin
LightSource "distant" "point3 from" [0 0 5] "point3 to" [0 0 0] "rgb L" [3 3 3]
AttributeBegin
  Material "diffuse" "rgb reflectance" [0.8 0 0]
  Translate 1.2 0 0
  Shape "sphere" "float radius" 0.6
AttributeEnd
AttributeBegin
  Material "diffuse" "rgb reflectance" [0 0.8 0]
  Translate -1.2 0 0
  Shape "sphere" "float radius" 0.6
AttributeEnd
"#;
    let film = render_desc(&parse(scene));
    let left = region_mean(&film, (0, 24), (0, 24));
    let right = region_mean(&film, (24, 48), (0, 24));
    assert!(left.x > 0.05 && left.x > 20.0 * left.y, "left half: {left}");
    assert!(right.y > 0.05 && right.y > 20.0 * right.x, "right half: {right}");

    // `Scale -1 1 1` before LookAt (as scenes converted from right-handed
    // tools do) swaps them back.
    let film = render_desc(&parse(&scene.replace("LookAt", "Scale -1 1 1\nLookAt")));
    let left = region_mean(&film, (0, 24), (0, 24));
    assert!(left.y > 20.0 * left.x, "mirrored: {left}");
}

/// A folder holding singlet.dat: a biconvex singlet (f ≈ 100 mm) and its
/// stop, as a lens description (radius, thickness, index, aperture
/// diameter in millimetres).
fn singlet_lens() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    fs::write(
        dir.path().join("singlet.dat"),
        "# a simple lens\n100 10 1.5 40\n-100 1 1 40\n0 50 0 20\n",
    )
    .unwrap();
    dir
}

/// A realistic camera (a lens description file, `aperturediameter`,
/// `focusdistance`, the film's `diagonal`) sees the scene as the
/// perspective camera of the same `LookAt` does, upright and unmirrored (the
/// lens inverts the image onto the film; pbrt-v4 reads the film back); the
/// integrators that connect light paths to the camera refuse it, and a
/// missing lens file is an error naming it.
#[test]
fn realistic_cameras_see_the_scene_as_the_perspective_camera_does() {
    let dir = singlet_lens();
    let scene = |camera: &str| {
        let text = format!(
            "LookAt 0 0 5  0 0 0  0 1 0\n{camera}\n\
             Film \"rgb\" \"integer xresolution\" 48 \"integer yresolution\" 24 \"float diagonal\" 100\n\
             Sampler \"independent\" \"integer pixelsamples\" 16\nIntegrator \"path\" \"integer maxdepth\" 1\nWorldBegin\n\
             LightSource \"distant\" \"point3 from\" [0 0 5] \"point3 to\" [0 0 0] \"rgb L\" [3 3 3]\n\
             AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0.8 0 0]\nTranslate 1.2 0.8 0\nShape \"sphere\" \"float radius\" 0.6\nAttributeEnd\n\
             AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0 0.8 0]\nTranslate -1.2 -0.8 0\nShape \"sphere\" \"float radius\" 0.6\nAttributeEnd\n"
        );
        let path = dir.path().join("scene.pbrt");
        fs::write(&path, text).unwrap();
        trazo::scene::load(&path, &[])
    };
    let realistic = scene(
        "Camera \"realistic\" \"string lensfile\" \"singlet.dat\" \"float aperturediameter\" 10 \"float focusdistance\" 5",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(realistic.warnings.is_empty(), "{:?}", realistic.warnings);
    let film = render_desc(&realistic);
    let quadrant = |f: &Film, x0: u32, y0: u32| region_mean(f, (x0, x0 + 24), (y0, y0 + 12));
    // Red at world +x, up: pbrt's LookAt puts +x on the left, so top left.
    let (tl, br) = (quadrant(&film, 0, 0), quadrant(&film, 24, 12));
    assert!(tl.x > 0.0 && tl.x > 10.0 * tl.y, "top left is red: {tl}");
    assert!(br.y > 0.0 && br.y > 10.0 * br.x, "bottom right is green: {br}");
    let (tr, bl) = (quadrant(&film, 24, 0), quadrant(&film, 0, 12));
    assert!(
        tr.max_element() < 0.1 * tl.x && bl.max_element() < 0.1 * br.y,
        "{tr} {bl}"
    );

    let mut bdpt = realistic.clone();
    bdpt.settings.integrator = trazo::settings::IntegratorKind::from_name("bdpt").unwrap();
    let Err(e) = trazo::scene::build(&bdpt) else {
        panic!("BDPT refuses it")
    };
    let e = e.to_string();
    assert!(e.contains("realistic camera"), "{e}");
    let e = scene("Camera \"realistic\" \"string lensfile\" \"missing.dat\"")
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.dat"), "{e}");
}

/// A realistic camera's `aperture` shapes its stop as pbrt-v4's does: a
/// small lamp far out of focus images as the stop's shape (told apart by
/// the blur's fourth moments), as bright in all as through the round stop;
/// an image file is read as a grey mask, top row up; a missing or black
/// one is an error naming it.
#[test]
fn realistic_camera_apertures_shape_the_blur_as_pbrt_v4s_do() {
    let dir = singlet_lens();
    // PFM masks, bottom row first: a white square on black, and all black.
    let pfm = |name: &str, lit: &dyn Fn(usize, usize) -> bool| {
        let n = 16;
        let mut bytes = format!("PF\n{n} {n}\n-1.0\n").into_bytes();
        for row in 0..n {
            for col in 0..n {
                let v: f32 = if lit(row, col) { 1.0 } else { 0.0 };
                for _ in 0..3 {
                    bytes.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        fs::write(dir.path().join(name), bytes).unwrap();
    };
    pfm("square.pfm", &|r, c| (4..12).contains(&r) && (4..12).contains(&c));
    pfm("black.pfm", &|_, _| false);
    let scene = |aperture: &str| {
        let text = format!(
            "LookAt 0 0 5  0 0 0  0 1 0\n\
             Camera \"realistic\" \"string lensfile\" \"singlet.dat\" \"float aperturediameter\" 20 \"float focusdistance\" 0.5 {aperture}\n\
             Film \"rgb\" \"integer xresolution\" 48 \"integer yresolution\" 48 \"float diagonal\" 16\n\
             Sampler \"independent\" \"integer pixelsamples\" 64\nIntegrator \"path\" \"integer maxdepth\" 1\nWorldBegin\n\
             AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [2000 2000 2000]\nShape \"sphere\" \"float radius\" 0.03\nAttributeEnd\n"
        );
        let path = dir.path().join("scene.pbrt");
        fs::write(&path, text).unwrap();
        trazo::scene::load(&path, &[])
    };
    // The blur's shape by its moments about its centre: E[x⁴]/E[x²y²]
    // is 3 for a disc and 9/5 for a square along the axes (both have
    // E[x²] = E[y²]); weighted by every pixel's light, it does not hang on
    // single noisy pixels.
    let blur = |aperture: &str| {
        let desc = scene(aperture).unwrap_or_else(|e| panic!("{e}"));
        assert!(desc.warnings.is_empty(), "{:?}", desc.warnings);
        let film = render_desc(&desc);
        let light: Vec<(f64, f64, f64)> = (0..48 * 48)
            .map(|i| {
                let l = luminance(film.pixels[i].value()) as f64;
                ((i % 48) as f64 + 0.5, (i / 48) as f64 + 0.5, l)
            })
            .collect();
        let total: f64 = light.iter().map(|p| p.2).sum();
        let mean = |f: &dyn Fn(f64, f64) -> f64| light.iter().map(|&(x, y, l)| l * f(x, y)).sum::<f64>() / total;
        let (cx, cy) = (mean(&|x, _| x), mean(&|_, y| y));
        let x4 = mean(&|x, y| ((x - cx).powi(4) + (y - cy).powi(4)) / 2.0);
        let x2y2 = mean(&|x, y| (x - cx).powi(2) * (y - cy).powi(2));
        let width = mean(&|x, _| (x - cx).powi(2)).sqrt();
        (x4 / x2y2, width, total)
    };
    let (round_ratio, round_width, round_total) = blur("");
    assert!(
        round_width > 4.0,
        "the blur's standard deviation is {round_width} pixels"
    );
    assert!((round_ratio - 3.0).abs() < 0.4, "round: E[x⁴]/E[x²y²] = {round_ratio}");
    // The square's blur: its corners rounded by the lamp's own image and
    // the singlet's spherical aberration, between the two; the image file
    // of a square half the width gives the built-in one's.
    let mut ratios = Vec::new();
    for square in ["\"string aperture\" \"square\"", "\"string aperture\" \"square.pfm\""] {
        let (ratio, _, total) = blur(square);
        assert!(ratio > 1.8 && ratio < 2.6, "{square}: E[x⁴]/E[x²y²] = {ratio}");
        assert!(
            (total / round_total - 1.0).abs() < 0.1,
            "{square}: {total} in all, round {round_total}"
        );
        ratios.push(ratio);
    }
    assert!((ratios[0] - ratios[1]).abs() < 0.15, "{ratios:?}");
    let e = scene("\"string aperture\" \"black.pfm\"").unwrap_err().to_string();
    assert!(e.contains("black.pfm") && e.contains("black"), "{e}");
    let e = scene("\"string aperture\" \"missing.png\"").unwrap_err().to_string();
    assert!(e.contains("missing.png"), "{e}");
}

/// pbrt-v4's `screenwindow` frames any part of the screen: the right half
/// of a 2:1 image's window, rendered on a square image, is the right half
/// of the full image, for the path tracer and for BDPT (whose light paths
/// find their pixels through the same window); `frameaspectratio` sets
/// the window's shape.
#[test]
fn screen_windows_frame_the_part_of_the_screen_they_name() {
    let scene = |camera: &str, w: u32, integrator: &str| {
        parse(&format!(
            "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40 {camera}\n\
             Film \"rgb\" \"integer xresolution\" {w} \"integer yresolution\" 16\n\
             Sampler \"independent\" \"integer pixelsamples\" 64\nIntegrator \"{integrator}\" \"integer maxdepth\" 2\nWorldBegin\n\
             LightSource \"point\" \"point3 from\" [0 0 4] \"rgb I\" [10 10 10]\n\
             Material \"diffuse\" \"rgb reflectance\" [0.8 0.8 0.8]\n\
             Shape \"trianglemesh\" \"point3 P\" [-4 -2 0 4 -2 0 4 2 0 -4 2 0] \"integer indices\" [0 1 2 0 2 3]\n\
             AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0.8 0.1 0.1]\nTranslate 0.9 0.2 0.5\nShape \"sphere\" \"float radius\" 0.4\nAttributeEnd\n"
        ))
    };
    let full = render_desc(&scene("", 32, "path"));
    for integrator in ["path", "bdpt"] {
        let half = render_desc(&scene("\"float screenwindow\" [0 2 -1 1]", 16, integrator));
        for (x0, y0) in [(0, 0), (8, 0), (0, 8), (8, 8)] {
            let a = region_mean(&full, (16 + x0, 24 + x0), (y0, y0 + 8));
            let b = region_mean(&half, (x0, x0 + 8), (y0, y0 + 8));
            assert!(
                (a - b).abs().max_element() < 0.05 * a.max_element() + 1e-3,
                "{integrator}, quadrant ({x0}, {y0}): {b} against the full image's {a}"
            );
        }
    }
    // A square frame on the 2:1 image: the window [-1, 1]², stretched.
    let stretched = parse(
        "Camera \"perspective\" \"float frameaspectratio\" 1\nFilm \"rgb\" \"integer xresolution\" 32 \"integer yresolution\" 16\nWorldBegin",
    );
    assert_eq!(stretched.camera.screen_window, Some([-1.0, 1.0, -1.0, 1.0]));
    assert!(stretched.warnings.is_empty(), "{:?}", stretched.warnings);
}

/// pbrt's `fov` spans the shorter image axis: the rays through the middle
/// of the image's edges show it.
#[test]
fn fov_spans_the_shorter_axis_in_portrait_and_landscape() {
    let angle_deg = |d: Vec3| d.angle_between(Vec3::Z).to_degrees();
    let wide = 2.0f32 * 30f32.to_radians().tan();
    for (w, h) in [(40u32, 20u32), (20, 40)] {
        let desc = parse(&format!(
            "Camera \"perspective\" \"float fov\" 60\nFilm \"rgb\" \"integer xresolution\" {w} \"integer yresolution\" {h}\nWorldBegin\nShape \"sphere\""
        ));
        let scene = trazo::scene::build(&desc).unwrap();
        let cam = &scene.camera;
        let side = angle_deg(cam.generate_ray(Vec2::new(0.0, h as f32 / 2.0), Vec2::ZERO).dir);
        let top = angle_deg(cam.generate_ray(Vec2::new(w as f32 / 2.0, 0.0), Vec2::ZERO).dir);
        let (short, long) = if w > h { (top, side) } else { (side, top) };
        assert!(
            (short - 30.0).abs() < 0.01,
            "{w}×{h}: half-angle across the short side {short}"
        );
        assert!(
            (long - wide.atan().to_degrees()).abs() < 0.01,
            "{w}×{h}: half-angle across the long side {long}"
        );
    }
}

#[test]
fn object_instances_become_instances() {
    let desc = parse(
        r#"WorldBegin
LightSource "point" "point3 from" [0 5 5] "rgb I" [10 10 10]
ObjectBegin "tri"
  Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0]
  Shape "sphere" "float radius" 0.25
ObjectEnd
ObjectInstance "tri"
Translate 2 0 0
ObjectInstance "tri"
Translate 2 0 0
ObjectInstance "tri"
"#,
    );
    let scene = trazo::scene::build(&desc).unwrap();
    assert_eq!(scene.geometry.instances.len(), 3);
    // Analytic shapes are copied per instance.
    assert_eq!(scene.geometry.shapes.len(), 3);
}

/// Per region of a 4 × 4 grid: mean luminance and the variance of that mean.
fn regions(film: &Film) -> Vec<(Rgb, f64, f64)> {
    let (w, h) = (film.width, film.height);
    let mut out = Vec::new();
    for ry in 0..4 {
        for rx in 0..4 {
            let (x0, x1, y0, y1) = (rx * w / 4, (rx + 1) * w / 4, ry * h / 4, (ry + 1) * h / 4);
            let n = ((x1 - x0) * (y1 - y0)) as f64;
            let (mut lum, mut var) = (0.0, 0.0);
            for y in y0..y1 {
                for x in x0..x1 {
                    let p = &film.pixels[(y * w + x) as usize];
                    lum += luminance(p.value()) as f64;
                    var += p.variance_of_mean();
                }
            }
            out.push((region_mean(film, (x0, x1), (y0, y1)), lum / n, var / (n * n)));
        }
    }
    out
}

/// scenes/pbrt/cornell-box.pbrt renders the image of scenes/cornell-box.toml:
/// red wall left, green right, and every region's mean luminance within
/// the noise of the two estimates.
#[test]
fn the_pbrt_cornell_box_matches_the_native_one() {
    let mut images = Vec::new();
    for path in ["scenes/cornell-box.toml", "scenes/pbrt/cornell-box.pbrt"] {
        let mut desc = trazo::scene::load(&repo(path), &[]).unwrap();
        assert!(desc.warnings.is_empty(), "{path}: {:?}", desc.warnings);
        desc.settings.width = 32;
        desc.settings.height = 32;
        desc.settings.spp = 64;
        images.push(render_desc(&desc));
    }
    let (native, pbrt) = (regions(&images[0]), regions(&images[1]));
    for (i, ((c0, m0, v0), (c1, m1, v1))) in native.iter().zip(&pbrt).enumerate() {
        let sigma = (v0 + v1).sqrt();
        assert!(
            (m0 - m1).abs() <= 5.0 * sigma + 1e-4,
            "region {i}: native {m0:.4}, pbrt {m1:.4}, σ {sigma:.4}"
        );
        // The walls' colours are on the same sides.
        if i % 4 == 0 && (1..3).contains(&(i / 4)) {
            assert!(c0.x > 2.0 * c0.y && c1.x > 2.0 * c1.y, "left wall red: {c0} {c1}");
        }
        if i % 4 == 3 && (1..3).contains(&(i / 4)) {
            assert!(c0.y > 1.2 * c0.x && c1.y > 1.2 * c1.x, "right wall green: {c0} {c1}");
        }
    }
}

fn trazo() -> Command {
    Command::cargo_bin("trazo").unwrap()
}

/// Runs `trazo render` on `scene` expecting exit status 2 and a single
/// line on stderr; returns it.
fn render_fails(scene: &Path, out: &Path) -> String {
    let o = trazo()
        .args(["render", "-q", "-o"])
        .arg(out)
        .arg(scene)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{}: {err}", scene.display());
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line expected, got: {err}");
    assert!(!err.contains("panicked"), "{err}");
    lines[0].to_string()
}

#[test]
fn malformed_pbrt_files_exit_2_naming_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let cases: &[(&str, &str)] = &[
        ("WorldBegin\nShape \"sphere\n", "s.pbrt:2:7: unterminated string"),
        (
            "WorldBegin\nShape \"sphere\" \"float radius\" 1.5.2\n",
            "s.pbrt:2:31: \"float radius\": expected a number, found `1.5.2`",
        ),
        (
            "WorldBegin\nShape \"sphere\" \"float radius\" [1\n",
            "s.pbrt:2:31: unclosed `[`",
        ),
        ("WorldBegin\nSphere \"x\"\n", "s.pbrt:2:1: `Sphere`: unknown directive"),
        (
            "WorldBegin\nShape \"sphere\" \"rgb radius\" [1 1 1]\n",
            "s.pbrt:2:16: `rgb radius`: `radius` must be of type float",
        ),
        (
            "WorldBegin\nShape \"sphere\" \"float radius\" [1 2]\n",
            "s.pbrt:2:16: `float radius`: expected one value, found 2",
        ),
        (
            "WorldBegin\nShape \"sphere\" \"flaot radius\" 1\n",
            "s.pbrt:2:16: unknown parameter type \"flaot\"",
        ),
        (
            "WorldBegin\nWorldBegin\n",
            "s.pbrt:2:1: `WorldBegin`: appears a second time",
        ),
        (
            "WorldBegin\nAttributeEnd\n",
            "s.pbrt:2:1: `AttributeEnd`: without a matching AttributeBegin",
        ),
        (
            "WorldBegin\n\nObjectInstance \"tree\"\n",
            "s.pbrt:3:16: `ObjectInstance`: no object named \"tree\"",
        ),
        (
            "WorldBegin\nNamedMaterial \"gold\"\nShape \"sphere\"\n",
            "s.pbrt:2:15: `NamedMaterial`: no material named \"gold\"",
        ),
        (
            "WorldBegin\nMaterial \"diffuse\" \"texture reflectance\" \"wood\"\n",
            "s.pbrt:2:20: `texture`: no texture named \"wood\"",
        ),
        (
            "WorldBegin\nInclude \"missing.pbrt\"\n",
            "s.pbrt:2:9: `Include`: cannot read",
        ),
        (
            "WorldBegin\nShape \"sphere\" \"float radius\" -2\n",
            "s.pbrt:2:16: `shape[0].radius`: must be positive",
        ),
        ("Shape \"sphere\"\n", "s.pbrt:1:1: `Shape`: must come after WorldBegin"),
        (
            "Film \"rgb\"\n",
            "s.pbrt:2:1: `WorldBegin`: the file ends before WorldBegin",
        ),
        (
            "WorldBegin\nAttributeBegin\n",
            "s.pbrt:2:1: `AttributeBegin`: is never closed",
        ),
        (
            "WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 5]\n",
            "s.pbrt:2:53: `integer indices`: index 5 is out of range",
        ),
    ];
    for (text, expected) in cases {
        let scene = dir.path().join("s.pbrt");
        fs::write(&scene, text).unwrap();
        let line = render_fails(&scene, &out);
        let at = line
            .find("s.pbrt:")
            .unwrap_or_else(|| panic!("{text:?}: no position in {line}"));
        assert!(
            line[at..].starts_with(expected),
            "{text:?}\n  gave: {line}\n  want: {expected}"
        );
        assert!(!out.exists(), "no image is written on errors");
    }

    // An include loop names the Include directive that closes the loop.
    fs::write(dir.path().join("a.pbrt"), "WorldBegin\nInclude \"b.pbrt\"\n").unwrap();
    fs::write(dir.path().join("b.pbrt"), "# b\nInclude \"a.pbrt\"\n").unwrap();
    let line = render_fails(&dir.path().join("a.pbrt"), &out);
    assert!(
        line.contains("b.pbrt:2:9: `Include`: include loop: a.pbrt → b.pbrt → a.pbrt"),
        "{line}"
    );

    // An error in an included file is at its own line and column.
    fs::write(dir.path().join("c.pbrt"), "WorldBegin\nInclude \"d.pbrt\"\n").unwrap();
    fs::write(dir.path().join("d.pbrt"), "\n\n    Translate 1 x 3\n").unwrap();
    let line = render_fails(&dir.path().join("c.pbrt"), &out);
    assert!(
        line.contains("d.pbrt:3:17: Translate: expected a number, found `x`"),
        "{line}"
    );

    // Text that is not UTF-8.
    fs::write(dir.path().join("e.pbrt"), b"WorldBegin\n# caf\xe9\n").unwrap();
    let line = render_fails(&dir.path().join("e.pbrt"), &out);
    assert!(line.contains("e.pbrt:2:6: the file is not valid UTF-8 text"), "{line}");
}

#[test]
fn unsupported_elements_warn_with_positions_and_still_render() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("w.pbrt");
    fs::write(
        &scene,
        r#"Film "rgb" "integer xresolution" 16 "integer yresolution" 12
Sampler "pmj02bn" "integer pixelsamples" 2
WorldBegin
LightSource "point" "point3 from" [0 3 3] "blackbody I" 5000 "float scale" 20
Material "hair"
Shape "curve" "point3 P" [0 0 0 1 1 1 2 2 2 3 3 3]
Shape "disk" "string emissionfilename" "e.exr"
"#,
    )
    .unwrap();
    let out = dir.path().join("w.png");
    let o = trazo()
        .args(["render", "-q", "-o"])
        .arg(&out)
        .arg(&scene)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(out.is_file());
    for expected in [
        "w.pbrt:2:1: Sampler \"pmj02bn\" is approximated",
        "w.pbrt:7:14: parameter \"string emissionfilename\" of Shape \"disk\" is unsupported: ignored",
    ] {
        assert!(
            err.lines().any(|l| l.starts_with("warning: ") && l.contains(expected)),
            "missing {expected:?} in\n{err}"
        );
    }
}

#[test]
fn the_example_pbrt_scene_renders_without_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cb.png");
    let o = trazo()
        .args(["render", "-q", "--width", "24", "--height", "24", "--spp", "1", "-o"])
        .arg(&out)
        .arg(repo("scenes/pbrt/cornell-box.pbrt"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("warning"), "{err}");
    assert!(out.is_file());
}

#[test]
fn the_extension_picks_the_reader_and_defines_warn() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("x.PBRT");
    fs::write(&scene, "WorldBegin\nShape \"sphere\"\n").unwrap();
    let d = trazo::scene::load(&scene, &[("size".into(), "2".into())]).unwrap();
    assert_eq!(d.shapes.len(), 1);
    assert_eq!(d.warnings.len(), 1, "{:?}", d.warnings);
    assert!(d.warnings[0].contains("-D size"));
    let other = dir.path().join("x.stl");
    fs::write(&other, "").unwrap();
    let e = trazo::scene::load(&other, &[]).unwrap_err().to_string();
    assert!(e.contains(".pbrt"), "{e}");
}

/// pbrt-v4's environment maps are equal-area octahedral squares: a map
/// whose pixels hold max(0, d) of their own central direction d, seen by
/// cameras looking down +x, +y and +z, shows each camera its own axis.
#[test]
fn environment_maps_are_equal_area_octahedral_as_in_pbrt() {
    let dir = tempfile::tempdir().unwrap();
    let n = 32usize;
    // PFM: a header, then rows of little-endian RGB floats, bottom row first.
    let mut pfm = format!("PF\n{n} {n}\n-1.0\n").into_bytes();
    for row in (0..n).rev() {
        for col in 0..n {
            let uv = Vec2::new((col as f32 + 0.5) / n as f32, (row as f32 + 0.5) / n as f32);
            let d = trazo::light::environment::equal_area_square_to_sphere(uv);
            for c in [d.x, d.y, d.z] {
                pfm.extend_from_slice(&c.max(0.0).to_le_bytes());
            }
        }
    }
    fs::write(dir.path().join("sky.pfm"), pfm).unwrap();
    for (look, up, axis) in [("1 0 0", "0 1 0", 0), ("0 1 0", "0 0 1", 1), ("0 0 1", "0 1 0", 2)] {
        let text = format!(
            "LookAt 0 0 0  {look}  {up}\nCamera \"perspective\" \"float fov\" 4\n\
             Film \"rgb\" \"integer xresolution\" 4 \"integer yresolution\" 4\n\
             Sampler \"independent\" \"integer pixelsamples\" 4\n\
             WorldBegin\nLightSource \"infinite\" \"string filename\" \"sky.pfm\"\n"
        );
        let path = dir.path().join("env.pbrt");
        fs::write(&path, text).unwrap();
        let desc = trazo::scene::load(&path, &[]).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            desc.warnings.iter().all(|w| !w.contains("approximated")),
            "{:?}",
            desc.warnings
        );
        let film = render_desc(&desc);
        let m = region_mean(&film, (0, 4), (0, 4));
        let c = [m.x, m.y, m.z];
        for (k, v) in c.into_iter().enumerate() {
            if k == axis {
                assert!(v > 0.9, "looking down axis {axis}: {m}");
            } else {
                assert!(v < 0.2, "looking down axis {axis}: {m}");
            }
        }
    }
}

/// pbrt-v4's spherical camera: its equirectangular image looks along the
/// `LookAt` view a quarter of the way across, up along its top row, and
/// toward camera +x (world −x here: pbrt's `LookAt` frame is left-handed)
/// at its left edge; the equal-area one looks up at its centre. Light
/// paths cannot connect to it.
#[test]
fn spherical_cameras_map_directions_as_pbrt_v4() {
    let scene = |mapping: &str| {
        parse(&format!(
            "LookAt 0 0 0  0 0 -1  0 1 0\nCamera \"spherical\" {mapping}\n\
             Film \"rgb\" \"integer xresolution\" 40 \"integer yresolution\" 20\nWorldBegin\nShape \"sphere\""
        ))
    };
    let desc = scene("\"string mapping\" \"equirectangular\"");
    assert!(desc.warnings.is_empty(), "{:?}", desc.warnings);
    let built = trazo::scene::build(&desc).unwrap();
    let dir = |x: f32, y: f32| built.camera.generate_ray(Vec2::new(x, y), Vec2::ZERO).dir;
    let near = |a: Vec3, b: Vec3| (a - b).length() < 1e-4;
    assert!(near(dir(10.0, 10.0), Vec3::NEG_Z), "{}", dir(10.0, 10.0));
    assert!(near(dir(17.0, 0.0), Vec3::Y));
    assert!(near(dir(0.0, 10.0), Vec3::NEG_X), "{}", dir(0.0, 10.0));
    assert!(near(dir(20.0, 10.0), Vec3::X));

    let mut desc = scene("");
    assert!(
        desc.warnings.iter().any(|w| w.contains("not square")),
        "equal-area over a 2:1 film: {:?}",
        desc.warnings
    );
    let built = trazo::scene::build(&desc).unwrap();
    let centre = built.camera.generate_ray(Vec2::new(20.0, 10.0), Vec2::ZERO).dir;
    assert!(near(centre, Vec3::Y), "{centre}");
    desc.settings.integrator = trazo::settings::IntegratorKind::from_name("bdpt").unwrap();
    let Err(e) = trazo::scene::build(&desc) else {
        panic!("BDPT cannot use a spherical camera")
    };
    let e = e.to_string();
    assert!(e.contains("spherical camera"), "{e}");

    let e = trazo::scene::pbrt::parse(
        "Camera \"spherical\" \"string mapping\" \"fisheye\"\nWorldBegin\n",
        Path::new("test.pbrt"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("test.pbrt:1:") && e.contains("fisheye"), "{e}");
}

/// Writes a PFM image (rows of little-endian RGB floats, bottom row
/// first) of `w` × `h` pixels, the colour of each given by its column and
/// its row counted from the top.
pub(crate) fn write_pfm(path: &Path, w: usize, h: usize, color: impl Fn(usize, usize) -> [f32; 3]) {
    let mut pfm = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
    for row in (0..h).rev() {
        for col in 0..w {
            for c in color(col, row) {
                pfm.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    fs::write(path, pfm).unwrap();
}

/// A projection light at the camera, with the camera's frame and field of
/// view, casts its image onto a wall facing both: the image appears as it
/// is (its top up, its left on the left), each pixel with the intensity
/// scale × value (pbrt-v4's `ProjectionLight`), or with `power` the
/// intensity that spreads that power over the frame's solid angle.
#[test]
fn projection_lights_cast_their_image_upright_with_pbrt_v4s_intensity() {
    let dir = tempfile::tempdir().unwrap();
    let quadrants = |col: usize, row: usize| match (col < 4, row < 4) {
        (true, true) => [1.0, 0.0, 0.0],
        (false, true) => [0.0, 1.0, 0.0],
        (true, false) => [0.0, 0.0, 1.0],
        (false, false) => [1.0, 1.0, 1.0],
    };
    write_pfm(&dir.path().join("quadrants.pfm"), 8, 8, quadrants);
    write_pfm(&dir.path().join("white.pfm"), 8, 8, |_, _| [1.0, 1.0, 1.0]);
    let render_with = |light: &str| {
        let text = format!(
            "Camera \"perspective\" \"float fov\" 40\n\
             Film \"rgb\" \"integer xresolution\" 32 \"integer yresolution\" 32\n\
             Sampler \"independent\" \"integer pixelsamples\" 16\n\
             Integrator \"path\" \"integer maxdepth\" 1\n\
             WorldBegin\n{light}\n\
             Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n\
             Shape \"trianglemesh\" \"point3 P\" [-20 -20 5  20 -20 5  20 20 5  -20 20 5] \"integer indices\" [0 1 2 0 2 3]\n"
        );
        let path = dir.path().join("projection.pbrt");
        fs::write(&path, text).unwrap();
        let desc = trazo::scene::load(&path, &[]).unwrap_or_else(|e| panic!("{e}"));
        assert!(desc.warnings.is_empty(), "{:?}", desc.warnings);
        render_desc(&desc)
    };
    let film = render_with("LightSource \"projection\" \"string filename\" \"quadrants.pfm\" \"float fov\" 40");
    let quadrant = |x0: u32, y0: u32| region_mean(&film, (x0 + 3, x0 + 13), (y0 + 3, y0 + 13));
    let (tl, tr, bl, br) = (quadrant(0, 0), quadrant(16, 0), quadrant(0, 16), quadrant(16, 16));
    assert!(tl.x > 0.005 && tl.x > 50.0 * (tl.y + tl.z), "top left is red: {tl}");
    assert!(tr.y > 0.005 && tr.y > 50.0 * (tr.x + tr.z), "top right is green: {tr}");
    assert!(bl.z > 0.005 && bl.z > 50.0 * (bl.x + bl.y), "bottom left is blue: {bl}");
    assert!(br.min_element() > 0.005, "bottom right is white: {br}");

    // On the axis the wall receives I/d² and reflects ρ/π of it.
    let centre = |film: &Film| luminance(region_mean(film, (15, 17), (15, 17)));
    let expected = 0.5 / PI * 2.0 / 25.0;
    let film =
        render_with("LightSource \"projection\" \"string filename\" \"white.pfm\" \"float fov\" 40 \"float scale\" 2");
    let got = centre(&film);
    assert!((got - expected).abs() < 0.02 * expected, "scale 2: {got} vs {expected}");
    // A power of 3 over the solid angle 4·asin(sin² 20°) of the frame,
    // times the scale, which multiplies it as in pbrt-v4.
    let solid_angle = 4.0 * (20f32.to_radians().sin().powi(2)).asin();
    let expected = 0.5 / PI * (2.0 * 3.0 / solid_angle) / 25.0;
    let film = render_with(
        "LightSource \"projection\" \"string filename\" \"white.pfm\" \"float fov\" 40 \"float scale\" 2 \"float power\" 3",
    );
    let got = centre(&film);
    assert!((got - expected).abs() < 0.02 * expected, "power 3: {got} vs {expected}");
}

/// A goniometric light reads its square image in pbrt-v4's equal-area
/// layout, the square's centre toward +y of the light's space (pbrt-v4
/// swaps y and z), a pixel's value the mean of its RGB; `power` sets the
/// intensity that emits it over the sphere.
#[test]
fn goniometric_lights_shine_as_their_equal_area_image_says() {
    let dir = tempfile::tempdir().unwrap();
    let n = 64;
    // Bright toward the image's +z, dark below its equator; grey values
    // given as unequal RGB of the same mean.
    write_pfm(&dir.path().join("lamp.pfm"), n, n, |col, row| {
        let uv = Vec2::new((col as f32 + 0.5) / n as f32, (row as f32 + 0.5) / n as f32);
        let v = trazo::light::environment::equal_area_square_to_sphere(uv).z.max(0.0);
        [2.0 * v, v, 0.0]
    });
    let light_at = |light: &str, p: Vec3| {
        let text = format!(
            "Camera \"perspective\"\nFilm \"rgb\" \"integer xresolution\" 4 \"integer yresolution\" 4\n\
             WorldBegin\nAttributeBegin\nTranslate 0 1 0\n{light}\nAttributeEnd\nShape \"sphere\" \"float radius\" 0.1\n"
        );
        let path = dir.path().join("lamp.pbrt");
        fs::write(&path, text).unwrap();
        let desc = trazo::scene::load(&path, &[]).unwrap_or_else(|e| panic!("{e}"));
        assert!(desc.warnings.is_empty(), "{:?}", desc.warnings);
        let scene = trazo::scene::build(&desc).unwrap_or_else(|e| panic!("{e}"));
        let s = scene.lights[0].sample_li(&scene, p, 0.5, Vec2::splat(0.5), false);
        s.map_or(Rgb::ZERO, |s| s.li)
    };
    let lamp = "LightSource \"goniometric\" \"string filename\" \"lamp.pfm\" \"rgb I\" [2 2 2]";
    // Straight above the light (at y = 1), 2 away: I·v/d² with v ≈ 1.
    let above = light_at(lamp, Vec3::new(0.0, 3.0, 0.0));
    assert!((above.x - 2.0 / 4.0).abs() < 0.02, "above: {above}");
    assert!(
        above.x == above.y && above.y == above.z,
        "the mean of RGB is grey: {above}"
    );
    // At 45° up: v = cos 45°, within the change of v over a pixel (the
    // nearest pixel is read); below: nothing.
    let slanted = light_at(lamp, Vec3::new(2.0, 3.0, 0.0));
    let expected = 2.0 * std::f32::consts::FRAC_1_SQRT_2 / 8.0;
    assert!(
        (slanted.x - expected).abs() < 0.04 * expected,
        "45°: {slanted} vs {expected}"
    );
    assert_eq!(light_at(lamp, Vec3::new(0.0, -1.0, 0.0)), Rgb::ZERO, "below");
    // With power P the intensity is I × P / (4π × the image's mean).
    let powered = light_at(&format!("{lamp} \"float power\" 10"), Vec3::new(0.0, 3.0, 0.0));
    let ratio = powered.x / above.x;
    // The mean of the image's values: ∫ max(z, 0) dω / 4π = 1/4.
    let expected = 10.0 / (4.0 * PI * 0.25);
    assert!(
        (ratio - expected).abs() < 0.02 * expected,
        "power: ×{ratio} vs ×{expected}"
    );
    // Without a filename pbrt-v4 warns; trazo renders a point light.
    let text = "Camera \"perspective\"\nWorldBegin\nLightSource \"goniometric\" \"rgb I\" [2 2 2]\n";
    assert!(
        parse(text)
            .warnings
            .iter()
            .any(|w| w.contains("without a \"filename\""))
    );
}

/// An image infinite light with `illuminance` E is scaled as pbrt-v4
/// scales it: by E over Σ luminance·cos θ of the pixels above the map's
/// horizon × 2π/N, which for a uniform map is π/2 (pbrt-v4 counts each
/// pixel as 2π/N steradians, so the radiance comes out as 2E/π).
#[test]
fn image_infinite_lights_take_pbrt_v4s_illuminance_scaling() {
    let dir = tempfile::tempdir().unwrap();
    write_pfm(&dir.path().join("sky.pfm"), 32, 32, |_, _| [0.5, 0.5, 0.5]);
    let text = "Camera \"perspective\"\nWorldBegin\n\
                LightSource \"infinite\" \"string filename\" \"sky.pfm\" \"float illuminance\" 3\n";
    let path = dir.path().join("sky.pbrt");
    fs::write(&path, text).unwrap();
    let desc = trazo::scene::load(&path, &[]).unwrap_or_else(|e| panic!("{e}"));
    assert!(desc.warnings.is_empty(), "{:?}", desc.warnings);
    let scene = trazo::scene::build(&desc).unwrap();
    let mut sum = 0.0f64;
    for y in 0..32 {
        for x in 0..32 {
            let uv = Vec2::new((x as f32 + 0.5) / 32.0, (y as f32 + 0.5) / 32.0);
            let z = trazo::light::environment::equal_area_square_to_sphere(uv).z;
            if z > 0.0 {
                sum += 0.5 * z as f64;
            }
        }
    }
    let k = sum * 2.0 * std::f64::consts::PI / 1024.0;
    let expected = (0.5 * 3.0 / k) as f32;
    let got = scene.background.eval(Vec3::new(0.3, 0.4, 0.5).normalize()).x;
    assert!((got - expected).abs() < 1e-4 * expected, "{got} vs {expected}");
    assert!((got - 6.0 / PI).abs() < 0.01 * got, "about 2E/π: {got}");
}

/// pbrt-v4 takes any number of infinite lights, and they add up: a map
/// and a constant light exactly (the map's radiance plus the constant in
/// every direction, without a warning), two maps of one size and frame
/// exactly at the pixels (with a warning: maps of other sizes are
/// resampled).
#[test]
fn infinite_lights_add_up_as_pbrt_v4s_do() {
    let dir = tempfile::tempdir().unwrap();
    write_pfm(&dir.path().join("a.pfm"), 16, 16, |x, y| {
        [x as f32 / 16.0, y as f32 / 16.0, 0.25]
    });
    write_pfm(&dir.path().join("b.pfm"), 16, 16, |x, _| [0.5, 0.0, x as f32 / 8.0]);
    let scene_of = |lights: &str| {
        let path = dir.path().join("sky.pbrt");
        fs::write(&path, format!("Camera \"perspective\"\nWorldBegin\n{lights}")).unwrap();
        let desc = trazo::scene::load(&path, &[]).unwrap_or_else(|e| panic!("{e}"));
        let scene = trazo::scene::build(&desc).unwrap_or_else(|e| panic!("{e}"));
        (desc.warnings, scene)
    };
    let image_a = "LightSource \"infinite\" \"string filename\" \"a.pfm\" \"float scale\" 2\n";
    let image_b =
        "AttributeBegin\nRotate 90 0 0 1\nLightSource \"infinite\" \"string filename\" \"b.pfm\"\nAttributeEnd\n";
    let constant = "LightSource \"infinite\" \"rgb L\" [0.1 0.2 0.3]\n";
    let (_, a) = scene_of(image_a);
    let (_, b) = scene_of(image_b);
    let (warnings, with_constant) = scene_of(&format!("{constant}{image_a}"));
    assert!(warnings.is_empty(), "{warnings:?}");
    let (warnings, both) = scene_of(&format!("{image_a}{constant}{image_b}"));
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("sky.pbrt:7:1") && w.contains("second image infinite light is approximated")),
        "{warnings:?}"
    );
    let c = Vec3::new(0.1, 0.2, 0.3);
    for y in 0..16 {
        for x in 0..16 {
            let uv = Vec2::new((x as f32 + 0.5) / 16.0, (y as f32 + 0.5) / 16.0);
            let d = trazo::light::environment::equal_area_square_to_sphere(uv);
            let (one, many) = (a.background.eval(d), with_constant.background.eval(d));
            assert!(
                (many - (one + c)).abs().max_element() < 1e-5,
                "{d}: {many} vs {one} + {c}"
            );
            // b is turned about z: its pixels are not a's, and it is
            // resampled at a's pixel centres (the nearest of its pixels).
            let sum = both.background.eval(d);
            let expected = one + c + b.background.eval(d);
            assert!((sum - expected).abs().max_element() < 1e-4, "{d}: {sum} vs {expected}");
        }
    }
    // Lit by all of them: a light sample's radiance is the sum's.
    assert!(both.environment_light.is_some());
}

fn write_gzip(path: &Path, text: &str) {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    e.write_all(text.as_bytes()).unwrap();
    fs::write(path, e.finish().unwrap()).unwrap();
}

/// A scene compressed with gzip — the main file, an included file and a
/// PLY mesh, as pbrt-v4-scenes ships them — renders from the command line
/// exactly as its plain copy, and the default output drops `.pbrt.gz`.
#[test]
fn gzip_compressed_scenes_render_as_their_plain_copies() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let main = r#"LookAt 0 1 4  0 0.3 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 24 "integer yresolution" 16
Sampler "independent" "integer pixelsamples" 4
WorldBegin
LightSource "point" "point3 from" [1 3 3] "rgb I" [20 20 20]
Include "geometry.pbrt{ext}" "float radius" 0.5
Material "diffuse" "rgb reflectance" [0.2 0.6 0.3]
Shape "plymesh" "string filename" "floor.ply{ext}"
"#;
    let geometry =
        "Material \"diffuse\" \"rgb reflectance\" [0.7 0.2 0.2]\nAttributeBegin\nTranslate 0 0.5 0\nShape \"sphere\"";
    let floor = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n-3 0 -3\n3 0 -3\n3 0 3\n-3 0 3\n4 3 2 1 0\n";
    // The AttributeBegin of the included file is closed after it.
    let main = main.replace(
        "Material \"diffuse\" \"rgb reflectance\" [0.2",
        "AttributeEnd\nMaterial \"diffuse\" \"rgb reflectance\" [0.2",
    );
    fs::write(root.join("plain.pbrt"), main.replace("{ext}", "")).unwrap();
    fs::write(root.join("geometry.pbrt"), geometry).unwrap();
    fs::write(root.join("floor.ply"), floor).unwrap();
    write_gzip(&root.join("packed.pbrt.gz"), &main.replace("{ext}", ".gz"));
    write_gzip(&root.join("geometry.pbrt.gz"), geometry);
    write_gzip(&root.join("floor.ply.gz"), floor);

    let render = |scene: &str, out: Option<&str>| {
        let mut cmd = trazo();
        cmd.current_dir(root).args(["render", "-q", "--threads", "1"]);
        if let Some(out) = out {
            cmd.args(["-o", out]);
        }
        let o = cmd.arg(scene).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{scene}: {err}");
        assert!(!err.contains("warning"), "{scene}: {err}");
    };
    render("plain.pbrt", Some("plain.exr"));
    render("packed.pbrt.gz", Some("packed.exr"));
    let a = trazo::film::io::read_image(&root.join("plain.exr")).unwrap();
    let b = trazo::film::io::read_image(&root.join("packed.exr")).unwrap();
    assert_eq!((a.width, a.height), (24, 16));
    assert_eq!(a.pixels, b.pixels);
    assert!(a.pixels.iter().any(|p| p.x > 0.0), "the image is lit");
    render("packed.pbrt.gz", None);
    assert!(root.join("packed.png").is_file());
}

/// An `rgbgrid` whose σa and σs are a `uniformgrid`'s density times its
/// σa and σs renders the same image (the same random numbers, σt equal up
/// to rounding), empty voxels included: a wrong albedo at the empty voxels'
/// edges, or σa and σs swapped, shows in the mean.
#[test]
fn an_rgb_grid_renders_as_the_uniform_grid_it_equals() {
    let density = [0.0f32, 2.0, 0.5, 0.0, 1.5, 3.0, 0.0, 1.0];
    let times = |k: f32| {
        density
            .iter()
            .map(|d| format!("{0} {0} {0}", d * k))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let scene = |medium: String| {
        format!(
            "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 30\nFilm \"rgb\" \"integer xresolution\" 24 \"integer yresolution\" 24\n\
             Sampler \"independent\" \"integer pixelsamples\" 64\nIntegrator \"volpath\" \"integer maxdepth\" 6\nWorldBegin\n{medium}\n\
             LightSource \"point\" \"point3 from\" [2 3 4] \"float scale\" 40\n\
             AttributeBegin\nMediumInterface \"smoke\" \"\"\nMaterial \"interface\"\nShape \"sphere\"\nAttributeEnd\n"
        )
    };
    let common = "\"integer nx\" 2 \"integer ny\" 2 \"integer nz\" 2 \"point3 p0\" [-1 -1 -1] \"point3 p1\" [1 1 1]";
    let uniform = scene(format!(
        "MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" {common} \"float density\" [{}] \"rgb sigma_a\" [0.5 0.5 0.5] \"rgb sigma_s\" [1.5 1.5 1.5]",
        density.map(|d| d.to_string()).join(" ")
    ));
    let rgb = scene(format!(
        "MakeNamedMedium \"smoke\" \"string type\" \"rgbgrid\" {common} \"rgb sigma_a\" [{}] \"rgb sigma_s\" [{}]",
        times(0.5),
        times(1.5)
    ));
    let (a, b) = (render_desc(&parse(&uniform)), render_desc(&parse(&rgb)));
    let mean = |f: &Film| luminance(region_mean(f, (0, 24), (0, 24)));
    let (ma, mb) = (mean(&a), mean(&b));
    assert!(ma > 0.01, "{ma}");
    assert!((ma - mb).abs() < 0.002 * ma, "uniformgrid {ma}, rgbgrid {mb}");

    // Emission: a uniformgrid's Le × its Lescale grid is the rgbgrid whose
    // Le is their product voxel by voxel (pbrt-v4's GridMedium and
    // RGBGridMedium), without a light.
    let le_scale = [1.0f32, 0.0, 2.0, 0.5, 0.0, 1.0, 3.0, 0.25];
    let le = [2.0f32, 1.0, 0.5];
    let unlit = |s: String| s.replace("LightSource \"point\" \"point3 from\" [2 3 4] \"float scale\" 40\n", "");
    let uniform = unlit(uniform.replace(
        "\"rgb sigma_s\" [1.5 1.5 1.5]",
        &format!(
            "\"rgb sigma_s\" [1.5 1.5 1.5] \"rgb Le\" [{} {} {}] \"float Lescale\" [{}]",
            le[0],
            le[1],
            le[2],
            le_scale.map(|k| k.to_string()).join(" ")
        ),
    ));
    let products = le_scale
        .iter()
        .map(|k| format!("{} {} {}", k * le[0], k * le[1], k * le[2]))
        .collect::<Vec<_>>()
        .join(" ");
    let rgb = unlit(rgb.replace(
        &format!("\"rgb sigma_s\" [{}]", times(1.5)),
        &format!("\"rgb sigma_s\" [{}] \"rgb Le\" [{products}]", times(1.5)),
    ));
    let (da, db) = (parse(&uniform), parse(&rgb));
    assert!(
        da.warnings.is_empty() && db.warnings.is_empty(),
        "{:?} {:?}",
        da.warnings,
        db.warnings
    );
    let (a, b) = (render_desc(&da), render_desc(&db));
    let (ma, mb) = (mean(&a), mean(&b));
    assert!(ma > 0.01, "the medium glows: {ma}");
    assert!((ma - mb).abs() < 0.002 * ma, "emitting uniformgrid {ma}, rgbgrid {mb}");
}

/// A texture graph renders exactly as its closed form: a `mix` of two
/// colours by a float checkerboard of two amounts is a checkerboard of the
/// two blends, and a `scale` of it by a float constant the blends scaled.
#[test]
fn texture_graphs_render_as_their_closed_forms() {
    let frame = r#"
LookAt 0 3 3  0 0 0  0 1 0
Camera "perspective" "float fov" 50
Film "rgb" "integer xresolution" 32 "integer yresolution" 24
Sampler "independent" "integer pixelsamples" 4
Integrator "path" "integer maxdepth" 2
WorldBegin
LightSource "distant" "point3 from" [1 4 2] "point3 to" [0 0 0] "rgb L" [2 2 2]
"#;
    let floor = r#"
Shape "bilinearmesh" "point3 P" [-2 0 -2  2 0 -2  -2 0 2  2 0 2] "point2 uv" [0 0 1 0 0 1 1 1]
"#;
    let (a, b) = (Rgb::new(0.9, 0.2, 0.1), Rgb::new(0.1, 0.3, 0.8));
    let graph = format!(
        r#"{frame}
Texture "amount" "float" "checkerboard" "float tex1" 0.2 "float tex2" 0.9 "float uscale" 4 "float vscale" 4
Texture "blend" "spectrum" "mix" "rgb tex1" [0.9 0.2 0.1] "rgb tex2" [0.1 0.3 0.8] "texture amount" "amount"
Texture "dim" "spectrum" "scale" "texture tex" "blend" "float scale" 0.5
Material "diffuse" "texture reflectance" "dim"
{floor}"#
    );
    let blend = |t: f32| 0.5 * ((1.0 - t) * a + t * b);
    let (even, odd) = (blend(0.2), blend(0.9));
    let closed = format!(
        r#"{frame}
Texture "checks" "spectrum" "checkerboard" "rgb tex1" [{} {} {}] "rgb tex2" [{} {} {}] "float uscale" 4 "float vscale" 4
Material "diffuse" "texture reflectance" "checks"
{floor}"#,
        even.x, even.y, even.z, odd.x, odd.y, odd.z
    );
    let mean = 0.5 * (even + odd);
    let flat = format!(
        r#"{frame}
Material "diffuse" "rgb reflectance" [{} {} {}]
{floor}"#,
        mean.x, mean.y, mean.z
    );
    let (g, c) = (parse(&graph), parse(&closed));
    assert!(g.warnings.is_empty(), "{:?}", g.warnings);
    let (g, c, f) = (render_desc(&g), render_desc(&c), render_desc(&parse(&flat)));
    let largest_difference = |a: &Film, b: &Film| {
        a.pixels
            .iter()
            .zip(&b.pixels)
            .map(|(p, q)| (p.value() - q.value()).abs().max_element())
            .fold(0.0f32, f32::max)
    };
    // The same albedos to the last bits (the printed colours round).
    let worst = largest_difference(&g, &c);
    assert!(worst < 1e-5, "{worst}");
    // And the checks are there: not their mean colour.
    let checks = largest_difference(&g, &f);
    assert!(checks > 0.04, "{checks}");
}

/// pbrt-v4's `alpha` cuts a shape out for every ray, shadow rays too: a
/// sheet of alpha 0.25 between a floor and the light lets 0.75 of the
/// light through, as a number and as a float texture.
#[test]
fn alpha_cut_outs_let_shadow_rays_through() {
    let scene = |sheet: &str| {
        format!(
            r#"
LookAt 0 0.5 0  0 0 0  0 0 1
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 16 "integer yresolution" 16
Sampler "independent" "integer pixelsamples" 4
Integrator "path" "integer maxdepth" 1
WorldBegin
LightSource "distant" "point3 from" [0 1 0] "point3 to" [0 0 0] "rgb L" [3 3 3]
Texture "quarter" "float" "constant" "float value" 0.25
Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
Shape "bilinearmesh" "point3 P" [-5 0 -5  5 0 -5  -5 0 5  5 0 5]
{sheet}
"#
        )
    };
    let sheet = |alpha: &str| format!(r#"Shape "bilinearmesh" "point3 P" [-5 1 -5  5 1 -5  -5 1 5  5 1 5] {alpha}"#);
    let open = render_desc(&parse(&scene("")));
    let mean = |f: &Film| region_mean(f, (0, 16), (0, 16));
    let lit = mean(&open);
    assert!(lit.x > 0.1, "{lit}");
    for alpha in [r#""float alpha" 0.25"#, r#""texture alpha" "quarter""#] {
        let d = parse(&scene(&sheet(alpha)));
        assert!(d.warnings.is_empty(), "{:?}", d.warnings);
        let ratio = mean(&render_desc(&d)).x / lit.x;
        assert!((ratio - 0.75).abs() < 0.01, "{alpha}: {ratio}");
    }
    // An opaque sheet casts its full shadow.
    let ratio = mean(&render_desc(&parse(&scene(&sheet(""))))).x / lit.x;
    assert!(ratio < 0.01, "{ratio}");
}

/// A white furnace of pbrt-v4's `subsurface`: a sphere of a medium that
/// absorbs nothing, under a glass-like surface, in light of radiance 1
/// everywhere, is invisible (every pixel 1) once light can scatter below
/// its surface; so is a coloured one's absorbed light missing from it.
#[test]
fn subsurface_spheres_conserve_energy_in_a_white_furnace() {
    let scene = |medium: &str| {
        format!(
            r#"
LookAt 0 0 4  0 0 0  0 1 0
Camera "perspective" "float fov" 30
Film "rgb" "integer xresolution" 12 "integer yresolution" 12
Sampler "independent" "integer pixelsamples" 64
Integrator "volpath" "integer maxdepth" 400
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Material "subsurface" "float eta" 1.33 {medium}
Shape "sphere"
"#
        )
    };
    let white = parse(&scene(r#""rgb sigma_a" [0 0 0] "rgb sigma_s" [2 2 2]"#));
    assert!(
        white.warnings.iter().all(|w| w.contains("subsurface")),
        "{:?}",
        white.warnings
    );
    let film = render_desc(&white);
    let mean = region_mean(&film, (0, 12), (0, 12));
    assert!((mean - Rgb::ONE).abs().max_element() < 0.02, "{mean}");
    // Absorption in the red: the sphere shows, red darkest.
    let film = render_desc(&parse(&scene(r#""rgb sigma_a" [0.5 0 0] "rgb sigma_s" [2 2 2]"#)));
    let centre = region_mean(&film, (4, 8), (4, 8));
    assert!(centre.x < 0.8 && (centre.y - 1.0).abs() < 0.03, "{centre}");
}

/// An area light's image (`"string filename"`) emits scale × the image at
/// the surface's (u, v), v = 0 at the image's bottom, as pbrt-v4's
/// `DiffuseAreaLight`: seen straight on, a two-pixel image's red and blue
/// halves are where (u, v) puts them (pbrt's `LookAt` shows world +x on the
/// image's left).
#[test]
fn area_lights_emit_their_image() {
    let dir = tempfile::tempdir().unwrap();
    write_pfm(&dir.path().join("split.pfm"), 2, 1, |col, _| {
        if col == 0 { [1.0, 0.0, 0.0] } else { [0.0, 0.0, 1.0] }
    });
    let text = r#"LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 20
Film "rgb" "integer xresolution" 16 "integer yresolution" 16
Sampler "independent" "integer pixelsamples" 4
Integrator "path" "integer maxdepth" 1
WorldBegin
AreaLightSource "diffuse" "string filename" "split.pfm" "float scale" 3
Shape "bilinearmesh" "point3 P" [-1 -1 0  1 -1 0  -1 1 0  1 1 0] "point2 uv" [0 0 1 0 0 1 1 1]
"#;
    let path = dir.path().join("image-light.pbrt");
    fs::write(&path, text).unwrap();
    let desc = trazo::scene::load(&path, &[]).unwrap_or_else(|e| panic!("{e}"));
    assert!(desc.warnings.is_empty(), "{:?}", desc.warnings);
    let film = render_desc(&desc);
    // u < 1/4 (world x < −1/2: the render's right) is the red texel's.
    let right = region_mean(&film, (13, 16), (4, 12));
    let left = region_mean(&film, (0, 3), (4, 12));
    assert!((right - Rgb::new(3.0, 0.0, 0.0)).abs().max_element() < 1e-3, "{right}");
    assert!((left - Rgb::new(0.0, 0.0, 3.0)).abs().max_element() < 1e-3, "{left}");
    // Both L and an image is pbrt-v4's error.
    fs::write(&path, text.replace("\"float scale\" 3", "\"rgb L\" [1 1 1]")).unwrap();
    let Err(e) = trazo::scene::load(&path, &[]) else {
        panic!("L and filename together were accepted")
    };
    assert!(e.to_string().contains("not both"), "{e}");
}

/// A float texture for a coated material's roughness (its coat's, or the
/// conductor's under the coat) varies it at each hit: a constant texture
/// renders as the number, checks of roughness differ.
#[test]
fn coated_materials_take_roughness_textures() {
    let scene = |material: &str| {
        format!(
            r#"
LookAt 0 0 4  0 0 0  0 1 0
Camera "perspective" "float fov" 30
Film "rgb" "integer xresolution" 16 "integer yresolution" 16
Sampler "independent" "integer pixelsamples" 4
Integrator "path" "integer maxdepth" 3
WorldBegin
LightSource "distant" "point3 from" [1 1 2] "point3 to" [0 0 0] "rgb L" [3 3 3]
Texture "rough" "float" "constant" "float value" 0.3
Texture "checks" "float" "checkerboard" "float tex1" 0.01 "float tex2" 0.6 "float uscale" 8 "float vscale" 8
Material {material}
Shape "sphere"
"#
        )
    };
    for (material, key) in [
        (r#""coateddiffuse" "rgb reflectance" [0.6 0.3 0.2]"#, "roughness"),
        (
            r#""coatedconductor" "float interface.roughness" 0.05"#,
            "conductor.roughness",
        ),
    ] {
        let textured = parse(&scene(&format!(r#"{material} "texture {key}" "rough""#)));
        assert!(textured.warnings.is_empty(), "{:?}", textured.warnings);
        let (a, b) = (
            render_desc(&textured),
            render_desc(&parse(&scene(&format!(r#"{material} "float {key}" 0.3"#)))),
        );
        let worst = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(p, q)| (p.value() - q.value()).abs().max_element())
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "{material}: {worst}");
        let c = render_desc(&parse(&scene(&format!(r#"{material} "texture {key}" "checks""#))));
        let differs = a
            .pixels
            .iter()
            .zip(&c.pixels)
            .any(|(p, q)| (p.value() - q.value()).abs().max_element() > 0.01);
        assert!(differs, "{material}");
    }
}

/// An infinite light's portal: a closed room lit through a hole in its
/// ceiling by a uniform sky renders the same with and without the portal
/// on the hole (the sky reaches the room through it alone), and with less
/// noise: its samples all go through the hole.
#[test]
fn a_portal_over_the_only_opening_changes_the_noise_not_the_image() {
    let scene = |portal: bool, seed: u64| {
        let portal = if portal {
            r#""point3 portal" [-0.5 2 -0.5  0.5 2 -0.5  0.5 2 0.5  -0.5 2 0.5]"#
        } else {
            ""
        };
        let mut d = parse(&format!(
            r#"LookAt 0 1 1.9  0 0 -1  0 1 0
Camera "perspective" "float fov" 70
Film "rgb" "integer xresolution" 24 "integer yresolution" 24
Sampler "independent" "integer pixelsamples" 16
Integrator "path" "integer maxdepth" 3
WorldBegin
LightSource "infinite" "rgb L" [1 1 1] {portal}
Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
# Floor, walls and a ceiling with a 1 × 1 hole, a room 4 wide, 2 high.
Shape "bilinearmesh" "point3 P" [-2 0 -2  2 0 -2  -2 0 2  2 0 2]
Shape "bilinearmesh" "point3 P" [-2 0 -2  -2 2 -2  2 0 -2  2 2 -2]
Shape "bilinearmesh" "point3 P" [-2 0 2  2 0 2  -2 2 2  2 2 2]
Shape "bilinearmesh" "point3 P" [-2 0 -2  -2 0 2  -2 2 -2  -2 2 2]
Shape "bilinearmesh" "point3 P" [2 0 -2  2 2 -2  2 0 2  2 2 2]
Shape "bilinearmesh" "point3 P" [-2 2 -2  -0.5 2 -2  -2 2 2  -0.5 2 2]
Shape "bilinearmesh" "point3 P" [0.5 2 -2  2 2 -2  0.5 2 2  2 2 2]
Shape "bilinearmesh" "point3 P" [-0.5 2 -2  0.5 2 -2  -0.5 2 -0.5  0.5 2 -0.5]
Shape "bilinearmesh" "point3 P" [-0.5 2 0.5  0.5 2 0.5  -0.5 2 2  0.5 2 2]
"#
        ));
        d.settings.seed = seed;
        let film = render_desc(&d);
        film.pixels.iter().map(|p| p.value().y as f64).collect::<Vec<_>>()
    };
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    // Squared difference between two renders of other seeds: twice the
    // per-pixel variance.
    let spread = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64;
    let (p1, p2) = (scene(true, 1), scene(true, 2));
    let (n1, n2) = (scene(false, 1), scene(false, 2));
    let (mp, mn) = (mean(&p1) + mean(&p2), mean(&n1) + mean(&n2));
    // Standard error of the difference of the two means, from the spreads.
    let sigma = ((spread(&p1, &p2) + spread(&n1, &n2)) / p1.len() as f64).sqrt();
    assert!(mn > 0.01, "the room is lit: {mn}");
    assert!((mp - mn).abs() < 4.0 * sigma, "{mp} against {mn} (σ {sigma})");
    // (Measured: a four-hundredth.)
    assert!(
        spread(&p1, &p2) < 0.1 * spread(&n1, &n2),
        "{} against {}",
        spread(&p1, &p2),
        spread(&n1, &n2)
    );
}

/// pbrt-v4's `power` on a mesh of unequal triangles makes each triangle a
/// light of that power: seen directly, the small triangle (area 0.5) is 10
/// times as bright as the large one (area 5), L·power/(π·2·A) each, and
/// the light tree takes the mesh to emit twice the power.
#[test]
fn power_on_unequal_triangles_gives_each_its_own_radiance() {
    let d = parse(
        "LookAt 2 2 5  2 2 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-3 3 -3 3]\n\
         Film \"rgb\" \"integer xresolution\" 60 \"integer yresolution\" 60\n\
         Sampler \"independent\" \"integer pixelsamples\" 4\nPixelFilter \"box\"\nWorldBegin\n\
         AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"float power\" 10 \"bool twosided\" true\n\
         Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0  2 0 0 4.5 0 0 2 4 0] \"integer indices\" [0 1 2 3 4 5]\n",
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    // The light tree weighs the mesh by its power, each triangle's 10 W.
    let scene = trazo::scene::build(&d).unwrap();
    let power = scene.lights[0].power(&scene, 1.0);
    assert!((power - 20.0).abs() < 1e-3 * 20.0, "{power}");
    let film = render_desc(&d);
    let near = |v: f32, want: f32| (v - want).abs() < 0.01 * want;
    let (small, large) = (10.0 / (PI * 2.0 * 0.5), 10.0 / (PI * 2.0 * 5.0));
    let count = |want: f32| film.pixels.iter().filter(|p| near(p.value().x, want)).count();
    // 50 and 500 pixels of area, less their edges.
    assert!(count(small) >= 25, "{} pixels at {small}", count(small));
    assert!(count(large) >= 350, "{} pixels at {large}", count(large));
}

/// With an image as well, each triangle's light is the image scaled by
/// power/(k·π·sides·A), k the image's mean luminance: a constant image of
/// colour c (luminance k) shows c·10/(k·2π·A) on each triangle.
#[test]
fn power_on_unequal_triangles_with_an_image_scales_the_image_per_triangle() {
    let dir = tempfile::tempdir().unwrap();
    let c = [0.5f32, 0.25, 1.0];
    let mut pfm = b"PF\n2 1\n-1.0\n".to_vec();
    for _ in 0..2 {
        for v in c {
            pfm.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(dir.path().join("glow.pfm"), pfm).unwrap();
    std::fs::write(
        dir.path().join("scene.pbrt"),
        "LookAt 2 2 5  2 2 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-3 3 -3 3]\n\
         Film \"rgb\" \"integer xresolution\" 60 \"integer yresolution\" 60\n\
         Sampler \"independent\" \"integer pixelsamples\" 4\nPixelFilter \"box\"\nWorldBegin\n\
         AreaLightSource \"diffuse\" \"string filename\" \"glow.pfm\" \"float power\" 10 \"bool twosided\" true\n\
         Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0  2 0 0 4.5 0 0 2 4 0] \"integer indices\" [0 1 2 3 4 5]\n",
    )
    .unwrap();
    let d = trazo::scene::load(&dir.path().join("scene.pbrt"), &[]).unwrap_or_else(|e| panic!("{e}"));
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let film = render_desc(&d);
    let k = luminance(Rgb::new(c[0], c[1], c[2]));
    let near = |v: Rgb, scale: f32| (0..3).all(|i| (v[i] - c[i] * scale).abs() < 0.01 * c[i] * scale);
    let (small, large) = (10.0 / (k * PI * 2.0 * 0.5), 10.0 / (k * PI * 2.0 * 5.0));
    let count = |scale: f32| film.pixels.iter().filter(|p| near(p.value(), scale)).count();
    assert!(count(small) >= 25, "{} pixels at {small}", count(small));
    assert!(count(large) >= 350, "{} pixels at {large}", count(large));
}

/// On a displaced mesh, whose triangles exist only once the build has cut
/// and moved them, each of them is a light of that power too: a unit
/// square cut into N triangles emits N times the power, each triangle's
/// radiance from its area after displacement (and its transform).
#[test]
fn power_on_a_displaced_mesh_is_each_displaced_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let square = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
                  property float u\nproperty float v\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
                  0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 1\n4 0 1 2 3\n";
    std::fs::write(dir.path().join("square.ply"), square).unwrap();
    std::fs::write(
        dir.path().join("scene.pbrt"),
        "LookAt 1 1 5  1 1 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1.5 1.5 -1.5 1.5]\n\
         Film \"rgb\" \"integer xresolution\" 40 \"integer yresolution\" 40\n\
         Sampler \"independent\" \"integer pixelsamples\" 4\nPixelFilter \"box\"\nWorldBegin\n\
         Texture \"h\" \"float\" \"constant\" \"float value\" 0.25\n\
         AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"float power\" 10 \"bool twosided\" true\n\
         Scale 2 2 2\n\
         Shape \"plymesh\" \"string filename\" \"square.ply\" \"texture displacement\" \"h\" \"float edgelength\" 0.6\n",
    )
    .unwrap();
    let d = trazo::scene::load(&dir.path().join("scene.pbrt"), &[]).unwrap_or_else(|e| panic!("{e}"));
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let scene = trazo::scene::build(&d).unwrap();
    let n = scene.geometry.stats().triangles as f32;
    assert!(n >= 8.0, "{n} triangles");
    let power = scene.lights[0].power(&scene, 1.0);
    assert!((power - 10.0 * n).abs() < 1e-3 * 10.0 * n, "{power} for {n} triangles");
    // Seen directly, the square (area 4 after the scale) shows radiances
    // whose mean over its area is N·10/(2π·4).
    let film = render_desc(&d);
    let inside: Vec<f32> = film
        .pixels
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            let (x, y) = ((i % 40) as f32 + 0.5, (i / 40) as f32 + 0.5);
            let (wx, wy) = (-0.5 + x * 3.0 / 40.0, -0.5 + y * 3.0 / 40.0);
            (0.1..1.9).contains(&wx) && (0.1..1.9).contains(&wy)
        })
        .map(|(_, p)| p.value().x)
        .collect();
    let mean = inside.iter().sum::<f32>() / inside.len() as f32;
    let want = n * 10.0 / (2.0 * PI * 4.0);
    assert!((mean - want).abs() < 0.1 * want, "{mean} against {want}");
}

/// Lit by such a mesh, a floor gets the same light from next-event
/// estimation (which reads each sampled triangle's radiance) as from BSDF
/// sampling alone: the image means of `mis` and `bsdf` agree within five
/// standard errors over eight seeds each.
#[test]
fn lights_with_per_triangle_radiance_are_sampled_with_it() {
    let scene = |sampling: &str, seed: u64| {
        let mut d = parse(
            "LookAt 2 -5 4  2 1 0  0 0 1\nCamera \"perspective\" \"float fov\" 50\n\
             Film \"rgb\" \"integer xresolution\" 32 \"integer yresolution\" 32\n\
             Sampler \"independent\" \"integer pixelsamples\" 16\nPixelFilter \"box\"\n\
             Integrator \"path\" \"integer maxdepth\" 1\nWorldBegin\n\
             AttributeBegin\nTranslate 0 0 1.5\n\
             AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"float power\" 10 \"bool twosided\" true\n\
             Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0  2 0 0 4.5 0 0 2 4 0] \"integer indices\" [0 1 2 3 4 5]\n\
             AttributeEnd\n\
             Shape \"trianglemesh\" \"point3 P\" [-10 -10 0 10 -10 0 -10 10 0 10 10 0] \"integer indices\" [0 1 2 2 1 3]\n",
        );
        d.settings.sampling = trazo::settings::PathSampling::from_name(sampling).unwrap();
        d.settings.seed = seed;
        let film = render_desc(&d);
        film.pixels.iter().map(|p| luminance(p.value()) as f64).sum::<f64>() / film.pixels.len() as f64
    };
    let stats = |sampling: &str| {
        let means: Vec<f64> = (0..8).map(|seed| scene(sampling, seed)).collect();
        let mean = means.iter().sum::<f64>() / 8.0;
        let var = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / 7.0;
        (mean, var / 8.0)
    };
    let ((mis, se2_mis), (bsdf, se2_bsdf)) = (stats("mis"), stats("bsdf"));
    let se = (se2_mis + se2_bsdf).sqrt();
    assert!(mis > 0.01, "{mis}");
    assert!(
        (mis - bsdf).abs() < 5.0 * se,
        "mis {mis}, bsdf {bsdf}, standard error {se}"
    );
}

/// A filter with a radius per axis blurs along each axis by its own: a
/// vertical edge stays sharp under a box of x radius 0.5 and y radius 3,
/// and spreads over about six columns with the radii swapped.
#[test]
fn pixel_filters_have_a_radius_per_axis() {
    let columns_between = |xr: f32, yr: f32| {
        let d = parse(&format!(
            "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-10 10 -10 10]\n\
             Film \"rgb\" \"integer xresolution\" 20 \"integer yresolution\" 20\n\
             Sampler \"independent\" \"integer pixelsamples\" 16\n\
             PixelFilter \"box\" \"float xradius\" {xr} \"float yradius\" {yr}\nWorldBegin\n\
             AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n\
             Shape \"trianglemesh\" \"point3 P\" [0 -20 0 20 -20 0 0 20 0 20 20 0] \"integer indices\" [0 1 2 2 1 3]\n"
        ));
        assert!(d.warnings.is_empty(), "{:?}", d.warnings);
        let film = render_desc(&d);
        let row = 10 * film.width;
        (0..film.width)
            .filter(|&x| {
                let v = film.pixels[(row + x) as usize].value().x;
                v > 0.01 && v < 0.99
            })
            .count()
    };
    assert_eq!(columns_between(0.5, 3.0), 0);
    let blurred = columns_between(3.0, 0.5);
    assert!((4..=6).contains(&blurred), "{blurred} columns between");
}

/// The channels of an OpenEXR file by name, each row by row from the top.
fn exr_channels(path: &Path) -> std::collections::HashMap<String, Vec<f32>> {
    let image = exr::prelude::read_all_flat_layers_from_file(path).unwrap_or_else(|e| panic!("{e}"));
    let layer = &image.layer_data[0];
    layer
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect()
}

/// pbrt-v4's `Film "gbuffer"`: one OpenEXR file with its 25 channels. A
/// square lying in the plane z = x, seen from z = −5 along +z: in camera
/// coordinates the depth is 5 + x, the normals face the camera along
/// (1, 0, −1)/√2, the depth changes by as much as x does along a row
/// (dz/dx is |dp/dx|'s x for a step of one pixel scaled by pbrt-v4's
/// differential scale 1/√spp) and not at all along a column; in world
/// coordinates the depth is x itself. The albedo of a Lambertian surface is
/// its reflectance; the variance channels are the radiance's per sample
/// (in CIE XYZ, as pbrt-v4's default sensor records it).
#[test]
fn a_gbuffer_film_writes_pbrt_v4s_channels() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |space: &str, name: &str| {
        format!(
            "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 30\n\
             Sampler \"stratified\" \"integer xsamples\" 8 \"integer ysamples\" 8\nPixelFilter \"box\"\n\
             Film \"gbuffer\" \"integer xresolution\" 12 \"integer yresolution\" 10 \"string filename\" \"{name}\" {space}\n\
             WorldBegin\nLightSource \"point\" \"point3 from\" [0 3 -4] \"rgb I\" [20 20 20]\n\
             Material \"diffuse\" \"rgb reflectance\" [0.5 0.25 0.125]\n\
             Shape \"trianglemesh\" \"point3 P\" [-4 -4 -4  4 -4 4  4 4 4  -4 4 -4] \"integer indices\" [0 1 2 0 2 3]\n\
             \"point2 uv\" [0 0 1 0 1 1 0 1]\n"
        )
    };
    let run = |space: &str, name: &str| {
        let path = dir.path().join(format!("{name}.pbrt"));
        fs::write(&path, scene(space, name)).unwrap();
        let o = trazo()
            .current_dir(dir.path())
            .args(["render", "-q"])
            .arg(&path)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        exr_channels(&dir.path().join(name))
    };
    let c = run("", "camera.exr");
    let mut names: Vec<&str> = c.keys().map(String::as_str).collect();
    names.sort();
    let mut expected = trazo::film::GBUFFER_CHANNELS.to_vec();
    expected.sort();
    assert_eq!(names, expected);
    let (w, h) = (12usize, 10usize);
    let at = |name: &str, x: usize, y: usize| c[name][y * w + x];
    let close = |a: f32, b: f32, tol: f32| (a - b).abs() <= tol;
    let h2 = std::f32::consts::FRAC_1_SQRT_2;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let (px, pz) = (at("P.X", x, y), at("P.Z", x, y));
            assert!(close(pz, 5.0 + px, 1e-4), "({x}, {y}): P {px} {pz}");
            for n in ["N", "Ns"] {
                let v = [
                    at(&format!("{n}.X"), x, y),
                    at(&format!("{n}.Y"), x, y),
                    at(&format!("{n}.Z"), x, y),
                ];
                assert!(
                    close(v[0], h2, 1e-4) && close(v[1], 0.0, 1e-4) && close(v[2], -h2, 1e-4),
                    "{n}: {v:?}"
                );
            }
            // The slope at the pixel's centre: the ray one pixel over,
            // its direction's step scaled by 1/√64 as pbrt-v4 scales it, met
            // on the plane (x = 5·dx/(dz − dx) along direction d). The
            // stratified samples' mean slope is within 0.2 % of it.
            let step = 2.0 * 15f32.to_radians().tan() / 10.0;
            let (a, b) = ((x as f32 - 5.5) * step, (4.5 - y as f32) * step);
            let d = Vec3::new(a, b, 1.0).normalize();
            let over = d + (Vec3::new(a + step, b, 1.0).normalize() - d) / 8.0;
            let plane_x = |d: Vec3| 5.0 * d.x / (d.z - d.x);
            let expected = (plane_x(over) - plane_x(d)).abs();
            let dzdx = at("dzdx", x, y);
            assert!(
                close(dzdx, expected, 0.01 * expected),
                "({x}, {y}): dzdx {dzdx}, expected {expected}"
            );
            assert!(at("dzdy", x, y).abs() < 1e-4 * dzdx, "dzdy {}", at("dzdy", x, y));
            for (channel, value) in [("Albedo.R", 0.5), ("Albedo.G", 0.25), ("Albedo.B", 0.125)] {
                assert!(
                    close(at(channel, x, y), value, 1e-5),
                    "{channel}: {}",
                    at(channel, x, y)
                );
            }
            let (u, v) = (at("u", x, y), at("v", x, y));
            assert!((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v), "uv {u} {v}");
            // The radiance varies with the sample's place in the pixel
            // and the Lambertian bounce's direction: its variance is
            // positive. The variances are of what pbrt-v4's default sensor
            // records, CIE XYZ, and the relative variance is over the mean,
            // which the box filter makes the pixel's X.
            let (var, rel) = (at("Variance.R", x, y), at("RelativeVariance.R", x, y));
            let mean_x = 0.412_456 * at("R", x, y) + 0.357_576 * at("G", x, y) + 0.180_438 * at("B", x, y);
            assert!(
                var > 0.0 && close(rel * mean_x, var, 1e-3 * var),
                "variance {var}, relative {rel}, X {mean_x}"
            );
        }
    }
    let world = run("\"string coordinatesystem\" \"world\"", "world.exr");
    for (pz, px) in world["P.Z"].iter().zip(&world["P.X"]) {
        assert!(close(*pz, *px, 1e-4), "world P {px} {pz}");
    }
    assert!(close(world["N.X"][w * 5 + 6], h2, 1e-4), "{}", world["N.X"][w * 5 + 6]);

    // Only OpenEXR, as pbrt-v4; an unknown coordinate system is an error.
    let path = dir.path().join("png.pbrt");
    fs::write(&path, scene("", "g.png")).unwrap();
    let line = render_fails(&path, &dir.path().join("o.png"));
    assert!(line.contains("png.pbrt:5:") && line.contains("OpenEXR"), "{line}");
    fs::write(&path, scene("\"string coordinatesystem\" \"screen\"", "g.exr")).unwrap();
    let line = render_fails(&path, &dir.path().join("o.exr"));
    assert!(line.contains("png.pbrt:5:") && line.contains("\"screen\""), "{line}");
}
