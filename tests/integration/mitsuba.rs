//! Mitsuba 3 XML through the whole pipeline: the repository's Mitsuba
//! Cornell box renders like trazo's native one, a shapegroup placed by
//! instances renders like its shapes written out, `-D` sets parameters, bad
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
    assert_blocks_agree(&a, &b);
}

/// Mean luminance of each 4×4-pixel block of two square films of the same
/// size agrees within 5 standard errors.
fn assert_blocks_agree(a: &trazo::film::Film, b: &trazo::film::Film) {
    let side = a.width as usize;
    for by in 0..side / 4 {
        for bx in 0..side / 4 {
            let (mut ma, mut mb, mut va, mut vb) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for y in by * 4..by * 4 + 4 {
                for x in bx * 4..bx * 4 + 4 {
                    let (pa, pb) = (a.pixels[y * side + x], b.pixels[y * side + x]);
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
    // Writes `text` to bad.xml, renders it, expects exit status 2 and
    // returns what was printed.
    let render_text = |text: &str| {
        std::fs::write(&bad, text).unwrap();
        trazo()
            .args(["render", "-q", "-o"])
            .arg(&out)
            .arg(&bad)
            .output()
            .unwrap()
    };
    let fails_with = |text: &str| {
        let o = render_text(text);
        assert_eq!(o.status.code(), Some(2));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let err = fails_with(
        "<scene>\n  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"-2\"/>\n  </shape>\n</scene>\n",
    );
    assert!(err.contains("bad.xml:3:") && err.contains("radius"), "{err}");
    let err = fails_with(
        "<scene>\n  <shape type=\"obj\"><string name=\"filename\" value=\"missing.obj\"/></shape>\n</scene>\n",
    );
    assert!(err.contains("bad.xml:2:") && err.contains("missing.obj"), "{err}");
    let err = fails_with("<scene><include filename=\"bad.xml\"/></scene>");
    assert!(err.contains("include loop"), "{err}");
    let err = fails_with("<scene>\n  <shape type=\"instance\">\n    <ref id=\"trees\"/>\n  </shape>\n</scene>\n");
    assert!(
        err.contains("bad.xml:3:5") && err.contains("no shapegroup with id \"trees\""),
        "{err}"
    );

    // Deep nesting is refused before the recursive reading could overflow
    // its stack (Mitsuba itself crashes on 20,000 levels); 64 levels are read.
    let nested = |depth: usize| {
        format!(
            "<scene>\n<shape type=\"sphere\">{}<bsdf type=\"diffuse\"/>{}</shape></scene>",
            "<bsdf type=\"twosided\">".repeat(depth),
            "</bsdf>".repeat(depth)
        )
    };
    let err = fails_with(&nested(20_000));
    assert!(
        err.contains("bad.xml:2:") && err.contains("nested more than 64 deep"),
        "{err}"
    );
    let o = render_text(&nested(61));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = fails_with(&nested(62));
    assert!(err.contains("nested more than 64 deep"), "{err}");
    // A plugin type Mitsuba does not know is an error, as in Mitsuba; so is
    // a second object with an id already taken.
    let err = fails_with("<scene>\n  <shape type=\"spherez\"/>\n</scene>");
    assert!(
        err.contains("bad.xml:2:3") && err.contains("unknown plugin type \"spherez\"") && err.contains("\"sphere\"?"),
        "{err}"
    );
    let err =
        fails_with("<scene>\n  <bsdf type=\"diffuse\" id=\"a\"/>\n  <texture type=\"bitmap\" id=\"a\"/>\n</scene>");
    assert!(
        err.contains("bad.xml:3:3") && err.contains("duplicate id \"a\"") && err.contains("bad.xml:2:3"),
        "{err}"
    );

    let err = fails_with("<scene><shape type=\"sphere\"><float name=\"radius\" value=\"$r\"/></shape></scene>");
    assert!(err.contains("undefined parameter $r"), "{err}");
    let o = trazo()
        .args(["render", "-q", "-D", "r=0.5", "-o"])
        .arg(&out)
        .arg(&bad)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A shapegroup of a mesh, a sphere and a cube (each with its own
/// to_world and BSDF) placed by three instances, one of them mirrored,
/// renders as the same nine shapes written out with the composed
/// transforms. Not bit for bit: the instanced mesh is traced in its own
/// space and the written-out ones in world space, and the two transforms
/// are composed in another order of rounding. But every pixel draws the
/// same random numbers, so the images differ far less than the noise that
/// the tolerances allow.
#[test]
fn shapegroup_instances_render_as_the_shapes_written_out() {
    // (type and parameters, the shape's own transform steps, its BSDF).
    let shapes = [
        (
            r#"shape type="obj"><string name="filename" value="models/torus-knot.obj"/"#,
            r#"<scale value="0.3"/><translate y="0.6"/>"#,
            r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.5, 0.3"/></bsdf>"#,
        ),
        (
            r#"shape type="sphere"><point name="center" x="0.8" y="0.25" z="0.3"/><float name="radius" value="0.25"/"#,
            "",
            r#"<bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/></bsdf>"#,
        ),
        (
            r#"shape type="cube""#,
            r#"<scale value="0.2"/><rotate y="1" angle="30"/><translate x="-0.8" y="0.2" z="0.4"/>"#,
            r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.6, 0.3"/></bsdf>"#,
        ),
    ];
    let instances = [
        r#"<translate x="-1.8" z="-0.5"/>"#,
        r#"<rotate y="1" angle="120"/><scale value="0.8"/>"#,
        r#"<scale x="-1.2" y="1.2" z="1.2"/><rotate y="1" angle="200"/><translate x="1.8" z="-0.8"/>"#,
    ];
    let scene = |body: &str| {
        format!(
            r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="4"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <transform name="to_world"><lookat origin="0, 2.5, 5" target="0, 0.3, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="64"/></sampler>
        <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/>
            <rfilter type="box"/></film>
    </sensor>
    <shape type="rectangle">
        <transform name="to_world"><scale value="5"/><rotate x="1" angle="-90"/></transform>
        <bsdf type="diffuse"/>
    </shape>
    <shape type="sphere">
        <point name="center" x="-1" y="4" z="2"/><float name="radius" value="0.5"/>
        <emitter type="area"><rgb name="radiance" value="8"/></emitter>
    </shape>
    <emitter type="constant"><rgb name="radiance" value="0.3"/></emitter>
{body}
</scene>"#
        )
    };
    let mut group = String::from("<shape type=\"shapegroup\" id=\"things\">\n");
    for (kind, steps, bsdf) in shapes {
        group += &format!("<{kind}><transform name=\"to_world\">{steps}</transform>{bsdf}</shape>\n");
    }
    group += "</shape>\n";
    for steps in instances {
        group += &format!(
            "<shape type=\"instance\"><ref id=\"things\"/><transform name=\"to_world\">{steps}</transform></shape>\n"
        );
    }
    let mut explicit = String::new();
    for inst in instances {
        for (kind, steps, bsdf) in shapes {
            explicit += &format!("<{kind}><transform name=\"to_world\">{steps}{inst}</transform>{bsdf}</shape>\n");
        }
    }
    let path = repo("scenes/instancing-test.xml");
    let read = |text: &str| trazo::scene::mitsuba::parse(text, &path, &[]).unwrap();
    let (instanced, written) = (read(&scene(&group)), read(&scene(&explicit)));
    assert!(instanced.warnings.is_empty(), "{:?}", instanced.warnings);
    assert!(written.warnings.is_empty(), "{:?}", written.warnings);
    let (a, b) = (
        trazo::scene::build(&instanced).unwrap(),
        trazo::scene::build(&written).unwrap(),
    );
    // The mesh is held once and placed three times, not copied.
    assert_eq!((a.geometry.meshes.len(), a.geometry.instances.len()), (1, 3));
    assert_eq!((b.geometry.meshes.len(), b.geometry.mesh_objects.len()), (3, 3));
    let (a, b) = (
        render(&a, &RenderOptions::default()).unwrap().film,
        render(&b, &RenderOptions::default()).unwrap().film,
    );
    // The whole image: mean luminance within 4 standard errors of the
    // difference (as if the two were independent, which overstates it).
    let n = a.pixels.len() as f64;
    let mean = |f: &trazo::film::Film| f.pixels.iter().map(|p| luminance(p.value()) as f64).sum::<f64>() / n;
    let var = |f: &trazo::film::Film| f.pixels.iter().map(|p| p.variance_of_mean()).sum::<f64>() / (n * n);
    let (ma, mb) = (mean(&a), mean(&b));
    let tol = 4.0 * (var(&a) + var(&b)).sqrt();
    assert!(ma > 0.05, "the scene renders dark: {ma}");
    assert!((ma - mb).abs() <= tol, "mean luminance {ma} vs {mb} ± {tol}");
    // 4×4-pixel blocks, which see a shape misplaced even where the whole
    // image's mean would not.
    assert_blocks_agree(&a, &b);
}

/// Mitsuba's clipping planes: a camera outside a wall sees through it where
/// `near_clip` lies beyond the wall (as smallpt-style scenes place their
/// camera), and sees nothing beyond `far_clip`.
#[test]
fn near_and_far_clip_cut_the_view_as_in_mitsuba() {
    let scene = |clip: &str| {
        format!(
            r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="1"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="30"/>{clip}
        <transform name="to_world"><lookat origin="0, 0, 10" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>
            <rfilter type="box"/></film>
    </sensor>
    <shape type="rectangle">
        <transform name="to_world"><scale value="20"/><translate z="5"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="20"/></transform>
        <emitter type="area"><rgb name="radiance" value="2"/></emitter>
    </shape>
</scene>"#
        )
    };
    let path = repo("scenes/clip-test.xml");
    let mean = |clip: &str| {
        let d = trazo::scene::mitsuba::parse(&scene(clip), &path, &[]).unwrap();
        assert!(d.warnings.iter().all(|w| !w.contains("clip")), "{:?}", d.warnings);
        let film = render(&trazo::scene::build(&d).unwrap(), &RenderOptions::default())
            .unwrap()
            .film;
        film.pixels.iter().map(|p| luminance(p.value())).sum::<f32>() / film.pixels.len() as f32
    };
    // The black wall 5 in front of the camera hides the light behind it.
    assert_eq!(mean(""), 0.0);
    assert_eq!(mean(r#"<float name="near_clip" value="4"/>"#), 0.0);
    // Past the wall: the light, everywhere in the image.
    assert!((mean(r#"<float name="near_clip" value="6"/>"#) - 2.0).abs() < 1e-4);
    // The far plane before the light: nothing (no background).
    assert_eq!(
        mean(r#"<float name="near_clip" value="6"/><float name="far_clip" value="9"/>"#),
        0.0
    );
    let e = trazo::scene::mitsuba::parse(&scene(r#"<float name="far_clip" value="0.001"/>"#), &path, &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("clip-test.xml:3:") && e.contains("near_clip"), "{e}");
}
