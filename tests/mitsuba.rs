//! Mitsuba 3 XML through the whole pipeline: the repository's Mitsuba
//! Cornell box renders like trazo's native one, `-D` sets parameters, bad
//! files exit with status 2 naming file, line and column.

use assert_cmd::Command;
use std::path::{Path, PathBuf};
use trazo::color::luminance;
use trazo::render::{RenderOptions, render};

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// The Mitsuba XML Cornell box and the native TOML one are the same
/// scene: their images agree region by region within the noise.
#[test]
fn mitsuba_cornell_box_matches_the_native_one() {
    let defines = [
        ("res".to_string(), "24".to_string()),
        ("spp".to_string(), "256".to_string()),
    ];
    let xml = trazo::scene::load(&repo("tools/crosscheck/scenes/cornell-box.xml"), &defines).unwrap();
    let mut native = trazo::scene::builtin::cornell_box();
    native.settings.width = 24;
    native.settings.height = 24;
    native.settings.spp = 256;
    native.settings.filter = xml.settings.filter;
    let render_film = |d: &trazo::scene::SceneDesc| {
        render(&trazo::scene::build(d).unwrap(), &RenderOptions::default())
            .unwrap()
            .film
    };
    let (a, b) = (render_film(&xml), render_film(&native));
    // Compare 4×4-pixel blocks: mean luminance within 5 standard errors.
    for by in 0..6 {
        for bx in 0..6 {
            let (mut ma, mut mb, mut va, mut vb) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for y in by * 4..by * 4 + 4 {
                for x in bx * 4..bx * 4 + 4 {
                    let (pa, pb) = (a.pixels[y * 24 + x], b.pixels[y * 24 + x]);
                    ma += luminance(pa.value()) as f64 / 16.0;
                    mb += luminance(pb.value()) as f64 / 16.0;
                    va += pa.variance_of_mean() / 256.0;
                    vb += pb.variance_of_mean() / 256.0;
                }
            }
            let tol = 5.0 * (va + vb).sqrt() + 1e-4;
            assert!((ma - mb).abs() <= tol, "block ({bx},{by}): {ma} vs {mb} ± {tol}");
        }
    }
}

#[test]
fn every_crosscheck_scene_loads_and_renders() {
    for name in [
        "cornell-box",
        "conductors",
        "glass",
        "plastic",
        "environment",
        "textured",
    ] {
        let defines = [
            ("res".to_string(), "8".to_string()),
            ("spp".to_string(), "1".to_string()),
        ];
        let d = trazo::scene::load(&repo(&format!("tools/crosscheck/scenes/{name}.xml")), &defines).unwrap();
        assert_eq!(
            (d.settings.width, d.settings.spp),
            (8, 1),
            "{name}: -D must set $res and $spp"
        );
        let scene = trazo::scene::build(&d).unwrap();
        let img = trazo::render::render_image(&scene).unwrap();
        assert!(img.mean().x > 0.0, "{name} renders black");
    }
}

fn trazo() -> Command {
    Command::cargo_bin("trazo").unwrap()
}

#[test]
fn cli_reads_xml_with_defines_and_reports_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    let o = trazo()
        .args(["render", "-q", "-D", "res=16", "-D", "spp=2", "-o"])
        .arg(&out)
        .arg(repo("tools/crosscheck/scenes/conductors.xml"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(image::open(&out).unwrap().to_rgb8().dimensions(), (16, 16));

    let bad = dir.path().join("bad.xml");
    std::fs::write(
        &bad,
        "<scene>\n  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"-2\"/>\n  </shape>\n</scene>\n",
    )
    .unwrap();
    let o = trazo()
        .args(["render", "-q", "-o"])
        .arg(&out)
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.xml:3:") && err.contains("radius"), "{err}");

    std::fs::write(
        &bad,
        "<scene>\n  <shape type=\"obj\"><string name=\"filename\" value=\"missing.obj\"/></shape>\n</scene>\n",
    )
    .unwrap();
    let o = trazo()
        .args(["render", "-q", "-o"])
        .arg(&out)
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.xml:2:") && err.contains("missing.obj"), "{err}");

    std::fs::write(&bad, "<scene><include filename=\"bad.xml\"/></scene>").unwrap();
    let o = trazo()
        .args(["render", "-q", "-o"])
        .arg(&out)
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("include loop"));

    std::fs::write(
        &bad,
        "<scene><shape type=\"sphere\"><float name=\"radius\" value=\"$r\"/></shape></scene>",
    )
    .unwrap();
    let o = trazo()
        .args(["render", "-q", "-o"])
        .arg(&out)
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("undefined parameter $r"));
    let o = trazo()
        .args(["render", "-q", "-D", "r=0.5", "-o"])
        .arg(&out)
        .arg(&bad)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
