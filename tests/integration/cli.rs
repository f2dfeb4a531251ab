//! The command line as a user meets it: the README's commands, every flag,
//! every kind of bad input (exit status 2 with a one-line message naming
//! the file, place and key), and the files it writes.

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

fn trazo() -> Command {
    Command::cargo_bin("trazo").unwrap()
}

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Runs trazo expecting failure with status 2 and one line on stderr;
/// returns that line.
fn fails(args: &[&str]) -> String {
    let out = trazo().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "args {args:?}, stderr: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line expected, got: {err}");
    assert!(!err.contains("panicked"), "{err}");
    lines[0].to_string()
}

fn write_scene(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    fs::write(&p, text).unwrap();
    p
}

const SPHERE: &str = r#"[render]
width = 16
height = 12
spp = 1

[[light]]
type = "point"
position = [0, 3, 3]
intensity = 10

[[shape]]
type = "sphere"
center = [0, 0, 0]
radius = 1
"#;

#[test]
fn help_explains_every_flag() {
    let out = trazo().arg("--help").output().unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("render"));
    let out = trazo().args(["render", "--help"]).output().unwrap();
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for flag in [
        "--output",
        "--spp",
        "--integrator",
        "--width",
        "--height",
        "--max-depth",
        "--seed",
        "--threads",
        "--quiet",
        "--verbose",
        "--tonemap",
        "--sampler",
        "--exposure",
    ] {
        assert!(help.contains(flag), "render --help lacks {flag}");
    }
}

#[test]
fn renders_the_default_scene() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cornell.png");
    let o = trazo()
        .args(["render", "--width", "32", "--height", "32", "--spp", "2", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = String::from_utf8_lossy(&o.stderr);
    assert!(summary.contains("samples/s") && summary.contains("32×32"), "{summary}");
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (32, 32));
    // The red left wall and the green right wall are where they belong.
    let left = img.get_pixel(3, 16);
    let right = img.get_pixel(28, 16);
    assert!(left[0] > left[1] && right[1] > right[0], "{left:?} {right:?}");
}

/// Every sampler name renders from the command line; `--sampler sobol`
/// (the default) gives the same image as no flag; a wrong name is refused
/// with the list of names.
#[test]
fn every_sampler_renders_and_sobol_is_the_default() {
    let dir = tempfile::tempdir().unwrap();
    let render = |extra: &[&str], name: &str| -> Vec<u8> {
        let out = dir.path().join(name);
        let o = trazo()
            .args(["render", "-q", "--width", "12", "--height", "12", "--spp", "4", "-o"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&o.stderr));
        fs::read(&out).unwrap()
    };
    let default = render(&[], "default.pfm");
    assert_eq!(render(&["--sampler", "sobol"], "sobol.pfm"), default);
    assert_ne!(render(&["--sampler", "stratified"], "stratified.pfm"), default);
    render(&["--sampler", "independent"], "independent.pfm");
    render(&["--sampler", "center"], "center.pfm");
    let halton = render(&["--sampler", "halton"], "halton.pfm");
    assert_ne!(halton, default);
    assert_ne!(render(&["--sampler", "halton-owen"], "halton-owen.pfm"), halton);
    // Unrandomised points are the same for every seed.
    let plain = render(&["--sampler", "halton-plain"], "halton-plain.pfm");
    assert_ne!(plain, halton);
    assert_eq!(
        render(&["--sampler", "halton-plain", "--seed", "7"], "halton-plain-7.pfm"),
        plain
    );
    let o = trazo().args(["render", "--sampler", "pmj02bn"]).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("sobol"));
}

#[test]
fn default_output_name_follows_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "ball.toml", SPHERE);
    let o = trazo()
        .current_dir(dir.path())
        .args(["render", "-q"])
        .arg(&scene)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(o.stderr.is_empty(), "--quiet prints nothing");
    assert!(dir.path().join("ball.png").is_file());
}

/// A pbrt-v4 scene's Film names the image written without -o (in the
/// current folder, as pbrt-v4 writes it); -o overrides it with a warning,
/// as pbrt-v4's --outfile; a name of an unknown format is an error at the
/// parameter.
#[test]
fn a_pbrt_film_filename_names_the_output() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("scenes")).unwrap();
    let scene = |film: &str| {
        format!(
            "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\"\nSampler \"independent\" \"integer pixelsamples\" 1\n\
             Film \"rgb\" \"integer xresolution\" 8 \"integer yresolution\" 6 {film}\n\
             WorldBegin\nLightSource \"infinite\"\nShape \"sphere\"\n"
        )
    };
    let named = write_scene(
        &dir.path().join("scenes"),
        "ball.pbrt",
        &scene("\"string filename\" \"named.exr\""),
    );
    let o = trazo()
        .current_dir(dir.path())
        .arg("render")
        .arg(&named)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(dir.path().join("named.exr").is_file());
    assert!(!dir.path().join("ball.png").exists());

    let o = trazo()
        .current_dir(dir.path())
        .args(["render", "-o", "other.png"])
        .arg(&named)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(dir.path().join("other.png").is_file());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("ball.pbrt:4:") && err.contains("\"named.exr\" is overridden by -o other.png"),
        "{err}"
    );

    let bad = write_scene(dir.path(), "bad.pbrt", &scene("\"string filename\" \"named.tga\""));
    let line = fails(&["render", bad.to_str().unwrap()]);
    assert!(
        line.contains("bad.pbrt:4:") && line.contains("named.tga") && line.contains("-o"),
        "{line}"
    );

    // Without a filename: the scene's name.
    let plain = write_scene(dir.path(), "plain.pbrt", &scene(""));
    let o = trazo()
        .current_dir(dir.path())
        .arg("render")
        .arg(&plain)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(dir.path().join("plain.png").is_file());
}

/// pbrt-v4's `Integrator "function"` runs a sampler study instead of a
/// render: the text file of `n mse` lines, named by its `filename`, else by
/// -o, else `<function>-mse.txt`; an image of the function where asked; the
/// counts the sampler is designed for; pbrt-v4's errors for an unknown
/// function and for its global `sobol` sampler.
#[test]
fn a_pbrt_function_integrator_runs_a_sampler_study() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |sampler: &str, integrator: &str| {
        format!(
            "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\"\nSampler {sampler}\n\
             Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 8 \"string filename\" \"never.exr\"\n\
             Integrator \"function\" {integrator}\nWorldBegin\nShape \"sphere\"\n"
        )
    };
    let run = |name: &str, text: &str, args: &[&str]| {
        let path = write_scene(dir.path(), name, text);
        let o = trazo()
            .current_dir(dir.path())
            .arg("render")
            .arg(&path)
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        err
    };
    let lines = |file: &str| -> Vec<(u32, f64)> {
        fs::read_to_string(dir.path().join(file))
            .unwrap()
            .lines()
            .map(|l| {
                let (n, e) = l.split_once(' ').unwrap();
                (n.parse().unwrap(), e.parse().unwrap())
            })
            .collect()
    };
    // The default function, the step, with Sobol points: powers of two,
    // exact from two samples on (one point in each half of x).
    let err = run(
        "sobol.pbrt",
        &scene("\"paddedsobol\" \"integer pixelsamples\" 64", ""),
        &[],
    );
    assert!(err.contains("step-mse.txt"), "{err}");
    let sobol = lines("step-mse.txt");
    assert_eq!(sobol.iter().map(|l| l.0).collect::<Vec<_>>(), [1, 2, 4, 8, 16, 32, 64]);
    assert_eq!(sobol[0].1, 1.0);
    assert!(sobol[1..].iter().all(|l| l.1 == 0.0), "{sobol:?}");
    assert!(!dir.path().join("never.exr").exists());

    // Independent samples of the disk, every count, named by the study,
    // with the function's image.
    run(
        "disk.pbrt",
        &scene(
            "\"independent\" \"integer pixelsamples\" 32",
            "\"string function\" \"disk\" \"string filename\" \"disk.txt\" \"string imagefilename\" \"disk.pfm\"",
        ),
        &[],
    );
    let disk = lines("disk.txt");
    assert_eq!(disk.len(), 32);
    // Variance of the disk's estimator: (4/π)²·π/4 − 1 = 4/π − 1 per sample;
    // over 128 pixels the mean squared error at 32 samples is within 50 %.
    let expected = (4.0 / std::f64::consts::PI - 1.0) / 32.0;
    assert!(
        (disk[31].1 / expected - 1.0).abs() < 0.5,
        "{} against {expected}",
        disk[31].1
    );
    let image = fs::read(dir.path().join("disk.pfm")).unwrap();
    assert!(image.starts_with(b"PF\n16 8\n"), "{:?}", &image[..12]);

    // -o names the file; a stratified study reports square counts.
    run(
        "strata.pbrt",
        &scene(
            "\"stratified\" \"integer xsamples\" 5 \"integer ysamples\" 5",
            "\"string function\" \"gaussian\"",
        ),
        &["-o", "strata.txt"],
    );
    let strata = lines("strata.txt");
    assert_eq!(strata.iter().map(|l| l.0).collect::<Vec<_>>(), [1, 4, 9, 16, 25]);
    assert!(strata[4].1 < strata[0].1 / 25.0, "{strata:?}");

    let bad = write_scene(
        dir.path(),
        "bad.pbrt",
        &scene("\"independent\"", "\"string function\" \"sphere\""),
    );
    let line = fails(&["render", bad.to_str().unwrap()]);
    assert!(line.contains("bad.pbrt:5:") && line.contains("\"sphere\""), "{line}");
    // The warning that "sobol" is approximated comes first, as every
    // warning given before a fatal error.
    let global = write_scene(dir.path(), "global.pbrt", &scene("\"sobol\"", ""));
    let o = trazo().args(["render", global.to_str().unwrap()]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    let last = err.lines().last().unwrap();
    assert!(last.contains("global.pbrt:5:") && last.contains("paddedsobol"), "{err}");
}

#[test]
fn every_example_scene_renders() {
    let dir = tempfile::tempdir().unwrap();
    let mut count = 0;
    // scenes/ and its folders: trazo TOML, Mitsuba XML, pbrt-v4 and lone
    // models.
    let mut files = Vec::new();
    let mut folders = vec![repo("scenes")];
    while let Some(folder) = folders.pop() {
        for entry in fs::read_dir(folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                folders.push(path);
            } else if path
                .extension()
                .is_some_and(|e| ["toml", "xml", "pbrt", "ply", "obj"].iter().any(|x| e == *x))
            {
                files.push(path);
            }
        }
    }
    for path in files {
        let out = dir.path().join(format!(
            "{}-{}.png",
            path.file_stem().unwrap().to_string_lossy(),
            path.extension().unwrap().to_string_lossy()
        ));
        let o = trazo()
            .args(["render", "-q", "--width", "24", "--height", "16", "--spp", "1", "-o"])
            .arg(&out)
            .arg(&path)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{}: {}",
            path.display(),
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(out.is_file());
        count += 1;
    }
    assert!(count >= 15, "found {count} scenes");
}

#[test]
fn float_formats_and_verbose_statistics() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "s.toml", SPHERE);
    for ext in ["exr", "hdr", "pfm"] {
        let out = dir.path().join(format!("x.{ext}"));
        let o = trazo()
            .args(["render", "-v", "-o"])
            .arg(&out)
            .arg(&scene)
            .output()
            .unwrap();
        assert!(o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("bvh:") && err.contains("nodes") && err.contains("built in"),
            "{err}"
        );
        let img = trazo::film::io::read_image(&out).unwrap();
        assert_eq!((img.width, img.height), (16, 12));
    }
}

/// An image rendered in another colour space names it in its OpenEXR
/// file; a PNG, which cannot, is written in sRGB, with a warning.
#[test]
fn output_colour_spaces_are_recorded_in_exr_files() {
    use trazo::color::space::ColorSpace;
    let dir = tempfile::tempdir().unwrap();
    let text = SPHERE.replace("spp = 1", "spp = 1\ncolor_space = \"rec2020\"");
    let scene = write_scene(dir.path(), "s.toml", &text);
    let plain = write_scene(dir.path(), "plain.toml", SPHERE);
    let render = |scene: &Path, out: &Path| {
        let o = trazo().args(["render", "-o"]).arg(out).arg(scene).output().unwrap();
        assert!(o.status.success());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let exr = dir.path().join("x.exr");
    let err = render(&scene, &exr);
    assert!(!err.contains("colour space"), "{err}");
    let c = trazo::film::io::exr_chromaticities(&fs::read(&exr).unwrap()).unwrap();
    assert_eq!(ColorSpace::from_primaries_and_white(c), Some(ColorSpace::Rec2020));
    let png = dir.path().join("x.png");
    let err = render(&scene, &png);
    assert!(
        err.contains("x.png: only OpenEXR images record a colour space; the image is written in sRGB, not rec2020"),
        "{err}"
    );
    let srgb = dir.path().join("srgb.png");
    render(&plain, &srgb);
    let (a, b) = (
        trazo::film::io::read_image(&png).unwrap(),
        trazo::film::io::read_image(&srgb).unwrap(),
    );
    let most = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (*p - *q).abs().max_element())
        .fold(0.0, f32::max);
    assert!(
        most <= 1.0 / 255.0 + 1e-6,
        "the PNG differs from the sRGB render by {most}"
    );
}

#[test]
fn threads_do_not_change_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.pfm");
    let b = dir.path().join("b.pfm");
    for (out, threads) in [(&a, "1"), (&b, "2")] {
        let o = trazo()
            .args([
                "render",
                "-q",
                "--width",
                "24",
                "--height",
                "24",
                "--spp",
                "3",
                "--seed",
                "7",
                "--threads",
                threads,
                "-o",
            ])
            .arg(out)
            .output()
            .unwrap();
        assert!(o.status.success());
    }
    assert_eq!(fs::read(&a).unwrap(), fs::read(&b).unwrap());
}

#[test]
fn flags_override_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "s.toml", SPHERE);
    let out = dir.path().join("x.png");
    let o = trazo()
        .args([
            "render",
            "-q",
            "--width",
            "20",
            "--height",
            "10",
            "--spp",
            "2",
            "--max-depth",
            "1",
            "--seed",
            "3",
            "--integrator",
            "whitted",
            "--sampler",
            "independent",
            "--tonemap",
            "aces",
            "--exposure",
            "-1",
            "-o",
        ])
        .arg(&out)
        .arg(&scene)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(image::open(&out).unwrap().to_rgb8().dimensions(), (20, 10));
}

#[test]
fn renders_a_lone_obj_model() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("knot.png");
    let o = trazo()
        .args(["render", "-q", "--width", "24", "--height", "24", "--spp", "1", "-o"])
        .arg(&out)
        .arg(repo("scenes/models/torus-knot.obj"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The model is framed: the centre pixel shows it, not the background.
    let img = image::open(&out).unwrap().to_rgb8();
    assert_ne!(img.get_pixel(12, 12), img.get_pixel(0, 0));
}

#[test]
fn missing_and_unreadable_scenes() {
    let e = fails(&["render", "no/such/scene.toml"]);
    assert!(e.contains("no/such/scene.toml") && e.contains("not found"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let e = fails(&["render", dir.path().to_str().unwrap()]);
    assert!(e.contains("unknown scene format") || e.contains("folder"), "{e}");
    let bad = write_scene(dir.path(), "s.xyz", "");
    let e = fails(&["render", bad.to_str().unwrap()]);
    assert!(e.contains("unknown scene format"), "{e}");
    let binary = dir.path().join("bin.toml");
    fs::write(&binary, [0xffu8, 0xfe, 0x00, 0x41]).unwrap();
    let e = fails(&["render", binary.to_str().unwrap()]);
    assert!(e.contains("UTF-8"), "{e}");
}

fn scene_error(text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "bad.toml", text);
    let out = dir.path().join("x.png");
    let e = fails(&["render", "-o", out.to_str().unwrap(), scene.to_str().unwrap()]);
    assert!(!out.exists(), "no image is written for a bad scene");
    assert!(e.contains("bad.toml:"), "the message names the file: {e}");
    e
}

#[test]
fn bad_scenes_name_file_line_column_and_key() {
    let e = scene_error(&SPHERE.replace("radius = 1", "radius = -1"));
    assert!(
        e.contains("bad.toml:14:10") && e.contains("`shape[0].radius`") && e.contains("positive"),
        "{e}"
    );
    let e = scene_error(&SPHERE.replace("radius = 1", "radius = nan"));
    assert!(e.contains("`shape[0].radius`") && e.contains("finite"), "{e}");
    let e = scene_error(&SPHERE.replace("radius = 1", "radius = [1]"));
    assert!(
        e.contains("`shape[0].radius`") && e.contains("expected a number"),
        "{e}"
    );
    let e = scene_error(&SPHERE.replace("radius = 1", "radios = 1"));
    assert!(
        e.contains("bad.toml:14:1") && e.contains("unknown key") && e.contains("radius"),
        "{e}"
    );
    let e = scene_error(&SPHERE.replace("width = 16", "width = 0"));
    assert!(e.contains("bad.toml:2:9") && e.contains("`render.width`"), "{e}");
    let e = scene_error(&SPHERE.replace("spp = 1", "spp = 99999999999"));
    assert!(e.contains("`render.spp`"), "{e}");
    let e = scene_error(&format!("{SPHERE}material = \"missing\"\n"));
    assert!(e.contains("no material named \"missing\""), "{e}");
    let e = scene_error("[render\nwidth = 3\n");
    assert!(e.contains("bad.toml:1:") && e.contains("syntax"), "{e}");
    let e = scene_error(&format!(
        "{SPHERE}\n[[shape]]\ntype = \"mesh\"\nfile = \"nowhere/model.obj\"\n"
    ));
    assert!(e.contains("nowhere/model.obj") && e.contains("not found"), "{e}");
    let e = scene_error(&format!(
        "{SPHERE}\n[[texture]]\nname = \"t\"\ntype = \"image\"\nfile = \"missing.png\"\n"
    ));
    assert!(e.contains("missing.png"), "{e}");
    let e = scene_error(&format!("{SPHERE}\n[[material]]\nname = \"g\"\nior = 0\n"));
    assert!(e.contains("`material[0].ior`"), "{e}");
}

#[test]
fn bad_flags_exit_with_status_2() {
    let out = trazo().args(["render", "--width", "0"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = trazo().args(["render", "--spp", "lots"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = trazo().args(["render", "--integrator", "magic"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("whitted"));
    let out = trazo().args(["frobnicate"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let e = fails(&[
        "render",
        "--threads",
        "0",
        "--width",
        "8",
        "--height",
        "8",
        "-o",
        "/tmp/trazo-threads0.png",
    ]);
    assert!(e.contains("threads"), "{e}");
}

#[test]
fn unwritable_outputs_fail_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let e = fails(&["render", "-o", dir.path().join("no/such/dir/x.png").to_str().unwrap()]);
    assert!(e.contains("does not exist"), "{e}");
    let e = fails(&["render", "-o", dir.path().join("x.bmp").to_str().unwrap()]);
    assert!(e.contains("unsupported image format"), "{e}");
    let e = fails(&["render", "-o", dir.path().to_str().unwrap()]);
    assert!(e.contains("folder") || e.contains("extension"), "{e}");
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0, "nothing is left behind");
}

#[test]
fn an_existing_output_is_replaced_whole() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    fs::write(&out, b"an old file").unwrap();
    let o = trazo()
        .args(["render", "-q", "--width", "8", "--height", "8", "--spp", "1", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success());
    assert_eq!(image::open(&out).unwrap().to_rgb8().dimensions(), (8, 8));
    assert_eq!(
        fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no temporary file is left"
    );
}

#[test]
fn auxiliary_images_are_written_next_to_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("box.png");
    let o = trazo()
        .args([
            "render",
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "2",
            "--aov",
            "albedo,normal,depth",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    // The summary names every file written.
    let albedo_path = dir.path().join("box.albedo.exr");
    assert!(
        err.contains(&format!("→ {}, {}", out.display(), albedo_path.display())) && err.contains("box.depth.exr"),
        "{err}"
    );
    let albedo = trazo::film::io::read_image(&dir.path().join("box.albedo.exr")).unwrap();
    let normal = trazo::film::io::read_image(&dir.path().join("box.normal.exr")).unwrap();
    let depth = trazo::film::io::read_image(&dir.path().join("box.depth.exr")).unwrap();
    // The back wall, straight ahead: white-ish albedo, normal +z, depth about 4.9.
    let c = (8, 6);
    let a = albedo.get(c.0, c.1);
    assert!(a.x > 0.8 && a.y > 0.6, "{a}");
    let n = normal.get(c.0, c.1);
    assert!(n.z > 0.95, "{n}");
    let d = depth.get(c.0, c.1).x;
    assert!((d - 4.9).abs() < 0.1, "{d}");
    // The red wall's albedo is red.
    let red = albedo.get(0, 8);
    assert!(red.x > 5.0 * red.y, "{red}");
}

#[test]
fn compare_renders_side_by_side_with_a_table() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cmp.png");
    let o = trazo()
        .args([
            "compare",
            "-q",
            "--width",
            "24",
            "--height",
            "16",
            "--spp",
            "4",
            "--integrators",
            "whitted,path:uniform,path:mis",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = String::from_utf8_lossy(&o.stdout);
    for name in ["whitted", "path:uniform", "path:mis", "mean std. error"] {
        assert!(table.contains(name), "{table}");
    }
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.width(), 3 * 24 + 2 * 4);

    // Equal time, against a reference.
    let reference = dir.path().join("ref.exr");
    let o = trazo()
        .args(["render", "-q", "--width", "24", "--height", "16", "--spp", "32", "-o"])
        .arg(&reference)
        .output()
        .unwrap();
    assert!(o.status.success());
    let o = trazo()
        .args([
            "compare",
            "-q",
            "--width",
            "24",
            "--height",
            "16",
            "--time",
            "0.2",
            "--integrators",
            "path:bsdf,path:mis",
            "-o",
        ])
        .arg(&out)
        .arg("--reference")
        .arg(&reference)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("rel. MSE"));
    // With a reference, a convergence plot beside the image, as SVG and PNG.
    let svg = std::fs::read_to_string(dir.path().join("cmp-convergence.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("path:bsdf") && svg.contains("path:mis"));
    let plot = image::open(dir.path().join("cmp-convergence.png")).unwrap();
    assert!(plot.width() > 100 && plot.height() > 100);
    // --plot names it; without -q the summary names every file written.
    let named = dir.path().join("curves");
    let o = trazo()
        .args([
            "compare",
            "--width",
            "24",
            "--height",
            "16",
            "--spp",
            "8",
            "--integrators",
            "path:mis",
            "-o",
        ])
        .arg(&out)
        .arg("--reference")
        .arg(&reference)
        .arg("--plot")
        .arg(&named)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(said.contains("curves.svg") && said.contains("curves.png"), "{said}");
    assert!(named.with_extension("svg").is_file() && named.with_extension("png").is_file());

    // Without --spp, the scene's samples per pixel, as `trazo render`.
    let scene = write_scene(dir.path(), "three.toml", &SPHERE.replace("spp = 1", "spp = 3"));
    let o = trazo()
        .args(["compare", "-q", "--integrators", "whitted,path:mis", "-o"])
        .arg(&out)
        .arg(&scene)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(
        table.contains("| whitted | 3 |") && table.contains("| path:mis | 3 |"),
        "{table}"
    );

    let e = fails(&["compare", "--integrators", "path:magic", "-o", out.to_str().unwrap()]);
    assert!(e.contains("magic"), "{e}");
    let e = fails(&[
        "compare",
        "--width",
        "8",
        "--reference",
        reference.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(e.contains("reference"), "{e}");
    let e = fails(&["compare", "--time", "0", "-o", out.to_str().unwrap()]);
    assert!(e.contains("--time"), "{e}");
}

/// Writes a black `side`×`side` image to `path`.
fn write_black(path: &std::path::Path, side: u32) {
    let black = trazo::film::Image::new(side, side);
    trazo::film::io::write_image(path, &black, trazo::settings::Tonemap::Clamp, 0.0).unwrap();
}

#[test]
fn diff_reports_errors_and_its_exit_status_says_whether_images_agree() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str, seed: &str, spp: &str| {
        let p = dir.path().join(name);
        let o = trazo()
            .args([
                "render", "-q", "--width", "16", "--height", "16", "--spp", spp, "--seed", seed, "-o",
            ])
            .arg(&p)
            .output()
            .unwrap();
        assert!(o.status.success());
        p
    };
    let a = render("a.exr", "1", "64");
    let b = render("b.exr", "2", "64");
    let o = trazo().args(["diff"]).arg(&a).arg(&a).output().unwrap();
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("relative MSE: 0.000000") && text.contains("mean R G B"),
        "{text}"
    );
    // Two seeds: a small relative MSE, within a loose bound, beyond a tight one.
    let err_img = dir.path().join("err.png");
    let o = trazo()
        .args(["diff", "--max-relmse", "1"])
        .arg(&a)
        .arg(&b)
        .arg("--error-image")
        .arg(&err_img)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stdout));
    assert_eq!(image::open(&err_img).unwrap().to_rgb8().dimensions(), (16, 16));
    let o = trazo()
        .args(["diff", "--max-relmse", "0.000001"])
        .arg(&a)
        .arg(&b)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "images that differ give status 1");
    // Without --max-relmse, images far apart differ: the default bound is
    // 0.01 (a black image against the box).
    let black = dir.path().join("black.pfm");
    write_black(&black, 16);
    let o = trazo().args(["diff"]).arg(&black).arg(&a).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stdout));
    // Other formats, size mismatch, missing file.
    let png = render("c.png", "1", "4");
    let o = trazo()
        .args(["diff", "--max-relmse", "1"])
        .arg(&png)
        .arg(&a)
        .output()
        .unwrap();
    assert!(o.status.success());
    let small = dir.path().join("small.pfm");
    let o = trazo()
        .args(["render", "-q", "--width", "8", "--height", "8", "--spp", "1", "-o"])
        .arg(&small)
        .output()
        .unwrap();
    assert!(o.status.success());
    let e = fails(&["diff", small.to_str().unwrap(), a.to_str().unwrap()]);
    assert!(e.contains("differ in size"), "{e}");
    // --downscale averages the reference's 2×2 blocks: the 8×8 render
    // against the 16×16 one, and not a 16×16 against a 24×24.
    let o = trazo()
        .args(["diff", "--downscale", "--max-relmse", "10"])
        .arg(&small)
        .arg(&a)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && text.contains("B averaged down by 2×2 to 8×8"),
        "{text}"
    );
    let wide = dir.path().join("wide.pfm");
    write_black(&wide, 24);
    let e = fails(&["diff", "--downscale", a.to_str().unwrap(), wide.to_str().unwrap()]);
    assert!(e.contains("not an integer multiple"), "{e}");
    let e = fails(&["diff", "nope.exr", a.to_str().unwrap()]);
    assert!(e.contains("nope.exr"), "{e}");
}

#[test]
fn a_lone_obj_brings_its_mtl_materials() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 0.9 0.05 0.05\n").unwrap();
    let obj = dir.path().join("m.obj");
    // A box-ish quad facing +z, in front of the studio camera.
    std::fs::write(
        &obj,
        "mtllib m.mtl\nv -1 0 0\nv 1 0 0\nv 1 2 0\nv -1 2 0\nusemtl red\nf 1 2 3 4\n",
    )
    .unwrap();
    let out = dir.path().join("m.png");
    let o = trazo()
        .args(["render", "-q", "--width", "24", "--height", "24", "--spp", "4", "-o"])
        .arg(&out)
        .arg(&obj)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&out).unwrap().to_rgb8();
    let c = img.get_pixel(12, 12);
    assert!(
        c[0] > 3 * c[1].max(1) && c[0] > 3 * c[2].max(1),
        "the MTL's red reaches the image: {c:?}"
    );
}

#[test]
fn photon_mapping_sppm_and_denoising_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = trazo().args(["render", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    for flag in [
        "--photons",
        "--caustic-photons",
        "--sppm-photons",
        "--photon-gather",
        "--photon-radius",
        "--final-gather",
        "--photon-kernel",
        "--denoise",
        "sppm",
    ] {
        assert!(help.contains(flag), "render --help lacks {flag}");
    }
    for (integrator, extra) in [("photon", "--final-gather=2"), ("sppm", "--photon-radius=0.05")] {
        let img = dir.path().join(format!("{integrator}.png"));
        let o = trazo()
            .args([
                "render",
                "--width",
                "16",
                "--height",
                "16",
                "--spp",
                "2",
                "--photons",
                "5000",
            ])
            .args(["--integrator", integrator, extra, "-o"])
            .arg(&img)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(err.contains("photons/s") && err.contains(integrator), "{err}");
        assert!(img.is_file());
    }
    // The built-in filter, chosen by name; the noisy image is kept.
    let img = dir.path().join("box.png");
    let o = trazo()
        .args([
            "render",
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "2",
            "--denoise=atrous",
            "-o",
        ])
        .arg(&img)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("à-trous"), "{err}");
    assert!(img.is_file() && dir.path().join("box.noisy.png").is_file());
    // Without the library, auto falls back to it and oidn is an error.
    let o = trazo()
        .env("TRAZO_OIDN", "/nonexistent/libOpenImageDenoise.so.2")
        .args([
            "render",
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "--denoise",
            "-o",
        ])
        .arg(dir.path().join("auto.png"))
        .output()
        .unwrap();
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("à-trous"));
    let bad = dir.path().join("never.png");
    let out = trazo()
        .env("TRAZO_OIDN", "/nonexistent/libOpenImageDenoise.so.2")
        .args(["render", "--width", "8", "--height", "8", "--denoise=oidn", "-o"])
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("tools/oidn/setup") && err.contains("--denoise=atrous"),
        "{err}"
    );
    assert!(!bad.exists(), "nothing is rendered when the denoiser is missing");
    let out = trazo().args(["render", "--denoise=blur"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("atrous"));
    assert!(fails(&["render", "--photon-radius=-1", "-o", "/tmp/trazo-neg.png"]).contains("--photon-radius"));
}

#[test]
fn bad_photon_settings_name_their_key() {
    let e = scene_error(&SPHERE.replace("spp = 1", "spp = 1\nphoton_gather = 0"));
    assert!(e.contains("`render.photon_gather`") && e.contains("at least 1"), "{e}");
    let e = scene_error(&SPHERE.replace("spp = 1", "spp = 1\nphoton_kernel = \"gauss\""));
    assert!(e.contains("photon_kernel") && e.contains("epanechnikov"), "{e}");
    let e = scene_error(&SPHERE.replace("spp = 1", "spp = 1\nsppm_alpha = 1.5"));
    assert!(e.contains("`render.sppm_alpha`"), "{e}");
    let e = scene_error(&SPHERE.replace("spp = 1", "spp = 1\nphoton_radius = -2"));
    assert!(e.contains("`render.photon_radius`"), "{e}");
}

#[test]
fn compare_accepts_photon_sppm_and_denoised_contestants() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cmp.png");
    let o = trazo()
        .args([
            "compare",
            "-q",
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "2",
            "--photons",
            "5000",
        ])
        .args([
            "--final-gather",
            "2",
            "--integrators",
            "path:mis,path:mis+atrous,photon,sppm",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = String::from_utf8_lossy(&o.stdout);
    for label in ["| path:mis |", "| path:mis+atrous |", "| photon |", "| sppm |"] {
        assert!(table.contains(label), "{table}");
    }
    assert!(out.is_file());
    assert!(fails(&["compare", "--integrators", "path+blur"]).contains("+blur"));
}

/// On a fatal error, the warnings given before it are printed first (each
/// `warning: …`, then `error: …`), so one run tells of every problem; the
/// exit status stays 2. Both when the reader stops and when the scene it
/// read fails to build.
#[test]
fn warnings_before_a_fatal_error_are_printed_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let run = |scene: &Path| {
        let o = trazo().arg("render").arg("-o").arg(&out).arg(scene).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "no image is written for a bad scene");
        err.lines()
            .filter(|l| !l.trim().is_empty())
            .map(str::to_string)
            .collect::<Vec<_>>()
    };

    // The reader stops at an unknown directive after an unsupported shape.
    let scene = write_scene(
        dir.path(),
        "bad.pbrt",
        "WorldBegin\nShape \"disk\" \"string emissionfilename\" \"e.exr\"\nBogus 1 2 3\n",
    );
    let lines = run(&scene);
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert!(
        lines[0].starts_with("warning: ")
            && lines[0]
                .contains("bad.pbrt:2:14: parameter \"string emissionfilename\" of Shape \"disk\" is unsupported"),
        "{lines:?}"
    );
    assert!(
        lines[1].starts_with("error: ") && lines[1].contains("bad.pbrt:3:1: `Bogus`: unknown directive"),
        "{lines:?}"
    );

    // The scene reads, with a warning, but fails to build: its mesh is missing.
    let scene = write_scene(
        dir.path(),
        "no-mesh.pbrt",
        "Accelerator \"kdtree\"\nWorldBegin\nShape \"plymesh\" \"string filename\" \"missing.ply\"\n",
    );
    let lines = run(&scene);
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert!(
        lines[0].starts_with("warning: ")
            && lines[0].contains("no-mesh.pbrt:1:1: Accelerator \"kdtree\" is unsupported"),
        "{lines:?}"
    );
    assert!(
        lines[1].starts_with("error: ") && lines[1].contains("missing.ply") && lines[1].contains("file not found"),
        "{lines:?}"
    );
}

/// `-D` on the built-in scene, which has no parameters, is named in a
/// warning rather than ignored.
#[test]
fn defines_on_the_built_in_scene_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let o = trazo()
        .args([
            "render", "-D", "spp=8", "--width", "8", "--height", "8", "--spp", "1", "-o",
        ])
        .arg(dir.path().join("d.png"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning: -D spp: the built-in scene has no parameters"),
        "{err}"
    );
}

/// `--bdpt-strategies` writes each strategy's image beside the output,
/// named as pbrt-v4 names them; without the bdpt integrator it is an error
/// (exit 2) that says what to add.
#[test]
fn bdpt_strategies_write_one_image_per_strategy() {
    let e = fails(&[
        "render",
        "--bdpt-strategies",
        "--spp",
        "1",
        "--width",
        "8",
        "--height",
        "8",
        "-o",
        "x.png",
    ]);
    assert!(e.contains("--integrator bdpt"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("box.exr");
    trazo()
        .args([
            "render",
            "--integrator",
            "bdpt",
            "--bdpt-strategies",
            "--max-depth",
            "3",
        ])
        .args(["--spp", "2", "--width", "16", "--height", "16", "-o"])
        .arg(&out)
        .assert()
        .success();
    // Up to 3 segments: (0, 2); (0, 3), (1, 2), (2, 1); (0, 4) … (3, 1).
    let mut names: Vec<String> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".bdpt_"))
        .collect();
    names.sort();
    assert_eq!(names.len(), 16, "{names:?}");
    assert!(
        names.contains(&"box.bdpt_d02_s03_t01_unweighted.exr".to_string()),
        "{names:?}"
    );
}

/// The Metropolis parameters on the command line: they change the render
/// (a different bootstrap, a different image) and are checked, an absurd
/// value being an error (exit 2) that names the flag.
#[test]
fn metropolis_flags_are_read_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str, flags: &[&str]| {
        let out = dir.path().join(name);
        trazo()
            .args([
                "render",
                "--integrator",
                "mlt",
                "--spp",
                "2",
                "--width",
                "8",
                "--height",
                "8",
                "-q",
            ])
            .args(flags)
            .arg("-o")
            .arg(&out)
            .assert()
            .success();
        fs::read(out).unwrap()
    };
    let a = render("a.pfm", &["--mlt-bootstrap", "500", "--mlt-chains", "8"]);
    let b = render("b.pfm", &["--mlt-bootstrap", "500", "--mlt-chains", "8"]);
    let c = render(
        "c.pfm",
        &["--mlt-bootstrap", "700", "--mlt-chains", "8", "--mlt-large-step", "0.5"],
    );
    assert!(a == b && a != c);
    for (flags, word) in [
        (["--mlt-large-step", "1.5"], "--mlt-large-step"),
        (["--mlt-sigma", "0"], "--mlt-sigma"),
    ] {
        let e = fails(&[&["render", "--integrator", "mlt", "-o", "x.pfm"][..], &flags[..]].concat());
        assert!(e.contains(word), "{e}");
    }
    // Out of the flag's range: clap's error (status 2) names it.
    let o = trazo()
        .args(["render", "--integrator", "mlt", "--mlt-chains", "0", "-o", "x.pfm"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.code() == Some(2) && err.contains("--mlt-chains"), "{err}");
}
