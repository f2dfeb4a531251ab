//! Directive by directive: what each produces in the description, and the
//! errors and warnings of malformed or unsupported input.

use super::*;
use crate::color::Encoding;
use crate::texture::TextureNode;
use glam::{Vec2, Vec3, Vec4};

fn parse_str(s: &str) -> Result<SceneDesc> {
    parse(s, Path::new("test.pbrt"))
}

/// A scene with `world` after WorldBegin.
fn world(world: &str) -> SceneDesc {
    parse_str(&format!("WorldBegin\n{world}")).unwrap_or_else(|e| panic!("{e}"))
}

fn error_of(s: &str) -> String {
    parse_str(s).unwrap_err().to_string()
}

/// The object-to-world matrix of shape `i`.
fn matrix(d: &SceneDesc, i: usize) -> Mat4 {
    d.shapes[i].transform.iter().fold(Mat4::IDENTITY, |acc, op| match op {
        TransformOp::Matrix(m) => *m * acc,
        _ => panic!("pbrt shapes carry matrices"),
    })
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-5
}

fn material(d: &SceneDesc, shape: usize) -> &MaterialDesc {
    let name = d.shapes[shape]
        .material
        .as_ref()
        .expect("pbrt shapes name their material");
    d.materials.iter().find(|m| &m.name == name).expect("defined")
}

#[test]
fn options_become_settings() {
    let d = parse_str(
        r#"Film "rgb" "integer xresolution" 64 "integer yresolution" [32]
Sampler "independent" "integer pixelsamples" 8
Integrator "volpath" "integer maxdepth" [3]
PixelFilter "triangle" "float xradius" 1.5 "float yradius" 1.5
WorldBegin"#,
    )
    .unwrap();
    let s = &d.settings;
    assert_eq!((s.width, s.height, s.spp, s.max_depth), (64, 32, 8, 4));
    assert_eq!(s.sampler, SamplerKind::Independent);
    assert_eq!(s.integrator, IntegratorKind::Path);
    assert_eq!(s.sampling, PathSampling::Mis);
    assert_eq!(s.filter, Filter::Tent { radius: 1.5 });
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);

    // pbrt-v4's light path integrator is light tracing, with its depth.
    let d = parse_str("Integrator \"lightpath\" \"integer maxdepth\" [2]\nWorldBegin").unwrap();
    assert_eq!(
        (d.settings.integrator, d.settings.max_depth),
        (IntegratorKind::Light, 3)
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);

    // pbrt-v4's teaching integrators are the path tracer's estimators:
    // uniform directions (random walk), BSDF sampling alone, light
    // sampling with BSDF sampling.
    for (kind, sampling) in [
        ("\"randomwalk\"", PathSampling::Uniform),
        ("\"simplepath\"", PathSampling::Nee),
        ("\"simplepath\" \"bool samplebsdf\" false", PathSampling::NeeUniform),
        ("\"simplepath\" \"bool samplelights\" false", PathSampling::Bsdf),
        (
            "\"simplepath\" \"bool samplelights\" false \"bool samplebsdf\" false",
            PathSampling::Uniform,
        ),
    ] {
        let d = parse_str(&format!("Integrator {kind} \"integer maxdepth\" 3\nWorldBegin")).unwrap();
        assert_eq!(
            (d.settings.integrator, d.settings.sampling, d.settings.max_depth),
            (IntegratorKind::Path, sampling, 4),
            "{kind}"
        );
        assert!(d.warnings.is_empty(), "{kind}: {:?}", d.warnings);
    }

    // pbrt-v4's simple volumetric path tracer is the volumetric one where
    // there are media (the same image, with light sampling), the path
    // tracer where there are none, as for `volpath`.
    let fog = "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\"\nMediumInterface \"\" \"fog\"";
    for (media, kind) in [(fog, IntegratorKind::VolPath), ("", IntegratorKind::Path)] {
        let d = parse_str(&format!(
            "Integrator \"simplevolpath\" \"integer maxdepth\" 3\n{media}\nCamera \"perspective\"\nWorldBegin"
        ))
        .unwrap();
        assert_eq!((d.settings.integrator, d.settings.max_depth), (kind, 4), "{media}");
        assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    }
    // pbrt-v4 knows no "aov" integrator (only its warnings name one).
    let e = parse_str("Integrator \"aov\"\nWorldBegin").unwrap_err().to_string();
    assert!(e.contains("unknown Integrator type \"aov\""), "{e}");

    // pbrt-v4's ambient occlusion, with its distance.
    let d = parse_str("Integrator \"ambientocclusion\" \"float maxdistance\" 0.5 \"bool cossample\" false\nWorldBegin")
        .unwrap();
    assert_eq!(
        (d.settings.integrator, d.settings.ao_distance),
        (IntegratorKind::AmbientOcclusion, 0.5)
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);

    // pbrt-v4's SPPM is trazo's, with its photons per iteration, initial
    // radius (default 1) and seed.
    let d = parse_str(
        "Integrator \"sppm\" \"integer maxdepth\" 4 \"integer photonsperiteration\" 5000 \"float radius\" 0.25 \"integer seed\" 7\nWorldBegin",
    )
    .unwrap();
    let s = &d.settings;
    assert_eq!((s.integrator, s.max_depth, s.seed), (IntegratorKind::Sppm, 5, 7));
    assert_eq!((s.photon.sppm_photons, s.photon.radius), (5000, 0.25));
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let d = parse_str("Integrator \"sppm\" \"integer photonsperiteration\" -1\nWorldBegin").unwrap();
    assert_eq!((d.settings.photon.sppm_photons, d.settings.photon.radius), (0, 1.0));
    for bad in ["\"float radius\" 0", "\"integer photonsperiteration\" -5"] {
        let e = parse_str(&format!("Integrator \"sppm\" {bad}\nWorldBegin"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("test.pbrt:1:"), "{e}");
    }

    // pbrt-v4's defaults: 1280×720, 16 spp, maxdepth 5, Gaussian filter.
    let d = world("");
    let s = &d.settings;
    assert_eq!((s.width, s.height, s.spp, s.max_depth), (1280, 720, 16, 6));
    assert_eq!(s.sampler, SamplerKind::Sobol, "pbrt's default sampler is ZSobol");
    assert_eq!(
        s.filter,
        Filter::Gaussian {
            stddev: 0.5,
            radius: 1.5
        }
    );

    // pbrt-v4's stratified sampler: its grid and jitter.
    let d = parse_str(
        "Sampler \"stratified\" \"integer xsamples\" 3 \"integer ysamples\" 2 \"bool jitter\" false\nWorldBegin",
    )
    .unwrap();
    let s = &d.settings;
    assert_eq!(
        (s.sampler, s.spp, s.strata, s.jitter),
        (SamplerKind::Stratified, 6, Some([3, 2]), false)
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);

    let d = parse_str(
        r#"Sampler "stratified" "integer xsamples" 3 "integer ysamples" 5
PixelFilter "gaussian" "float sigma" 0.25 "float xradius" 1 "float yradius" 1
Integrator "bdpt" "integer maxdepth" 2
Sampler "zsobol" "integer pixelsamples" 32
WorldBegin"#,
    )
    .unwrap();
    assert_eq!(d.settings.spp, 32);
    assert_eq!(
        (d.settings.strata, d.settings.jitter),
        (None, true),
        "the last sampler's"
    );
    assert_eq!(d.settings.max_depth, 3);
    assert_eq!(
        d.settings.filter,
        Filter::Gaussian {
            stddev: 0.25,
            radius: 1.0
        }
    );
    // Mitchell's cubic and Lanczos' sinc, pbrt-v4's defaults and given.
    for (text, filter) in [
        (
            "PixelFilter \"mitchell\"",
            Filter::Mitchell {
                radius: 2.0,
                b: 1.0 / 3.0,
                c: 1.0 / 3.0,
            },
        ),
        (
            "PixelFilter \"mitchell\" \"float B\" 0 \"float C\" 0.5 \"float xradius\" 3 \"float yradius\" 3",
            Filter::Mitchell {
                radius: 3.0,
                b: 0.0,
                c: 0.5,
            },
        ),
        ("PixelFilter \"sinc\"", Filter::Lanczos { radius: 4.0, tau: 3.0 }),
        (
            "PixelFilter \"sinc\" \"float tau\" 2 \"float xradius\" 2 \"float yradius\" 2",
            Filter::Lanczos { radius: 2.0, tau: 2.0 },
        ),
    ] {
        let f = parse_str(&format!("{text}\nWorldBegin")).unwrap();
        assert_eq!(f.settings.filter, filter, "{text}");
        assert!(f.warnings.is_empty(), "{text}: {:?}", f.warnings);
    }
    let e = parse_str("PixelFilter \"sinc\" \"float xradius\" 9 \"float yradius\" 9\nWorldBegin")
        .unwrap_err()
        .to_string();
    assert!(e.contains("test.pbrt:1:") && e.contains("negative lobes"), "{e}");
    // A radius per axis, as pbrt-v4's filters have.
    let f = parse_str("PixelFilter \"gaussian\" \"float xradius\" 1 \"float yradius\" 2.5\nWorldBegin").unwrap();
    assert!(f.warnings.is_empty(), "{:?}", f.warnings);
    assert_eq!(
        f.settings.pixel_filter(),
        crate::settings::PixelFilter {
            x: Filter::Gaussian {
                stddev: 0.5,
                radius: 1.0
            },
            y: Filter::Gaussian {
                stddev: 0.5,
                radius: 2.5
            },
        }
    );
    let e = parse_str("PixelFilter \"sinc\" \"float xradius\" 2 \"float yradius\" 9\nWorldBegin")
        .unwrap_err()
        .to_string();
    assert!(e.contains("test.pbrt:1:38") && e.contains("negative lobes"), "{e}");
    let w = d.warnings.join("\n");
    // pbrt-v4's BDPT is trazo's, with its depth.
    assert_eq!(d.settings.integrator, IntegratorKind::Bdpt);
    assert!(!w.contains("Integrator"), "{w}");
    assert!(!d.settings.bdpt_strategies);
    let v = parse_str("Integrator \"bdpt\" \"bool visualizeweights\" true\nWorldBegin").unwrap();
    assert!(v.settings.bdpt_strategies && v.warnings.is_empty(), "{:?}", v.warnings);
    // Its MLT is trazo's multiplexed MLT, its mutations per pixel the
    // samples per pixel wherever the sampler is declared.
    let m = parse_str(
        "Integrator \"mlt\" \"integer maxdepth\" 4 \"integer bootstrapsamples\" 500 \"integer chains\" 20\n\
         \"integer mutationsperpixel\" 7 \"float largestepprobability\" 0.5 \"float sigma\" 0.02\n\
         Sampler \"halton\" \"integer pixelsamples\" 64\nWorldBegin",
    )
    .unwrap();
    assert_eq!((m.settings.integrator, m.settings.max_depth), (IntegratorKind::Mlt, 5));
    assert_eq!(m.settings.spp, 7);
    let mlt = m.settings.mlt;
    assert_eq!(
        (mlt.bootstrap, mlt.chains, mlt.large_step_probability, mlt.sigma),
        (500, 20, 0.5, 0.02)
    );
    assert!(!m.warnings.join("\n").contains("Integrator"), "{:?}", m.warnings);
    let e = parse_str("Integrator \"mlt\" \"float sigma\" -1\nWorldBegin")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("test.pbrt:1:") && e.contains("sigma") && e.contains("positive"),
        "{e}"
    );
    assert_eq!(d.settings.sampler, SamplerKind::Sobol);
    assert!(!w.contains("Sampler"), "ZSobol is read as trazo's Sobol sampler: {w}");

    let d = parse_str("Sampler \"pmj02bn\" \"integer pixelsamples\" 8\nWorldBegin").unwrap();
    assert_eq!((d.settings.sampler, d.settings.spp), (SamplerKind::Sobol, 8));
    let w = d.warnings.join("\n");
    assert!(w.contains("test.pbrt:1:1: Sampler \"pmj02bn\" is approximated"), "{w}");

    // Halton, with its randomizations.
    for (randomize, kind) in [
        ("", SamplerKind::Halton),
        ("\"string randomize\" \"permutedigits\"", SamplerKind::Halton),
        ("\"string randomize\" \"owen\"", SamplerKind::HaltonOwen),
        ("\"string randomize\" \"fastowen\"", SamplerKind::HaltonOwen),
        ("\"string randomize\" \"none\"", SamplerKind::HaltonPlain),
    ] {
        let d = parse_str(&format!(
            "Sampler \"halton\" \"integer pixelsamples\" 32 {randomize}\nWorldBegin"
        ))
        .unwrap();
        assert_eq!((d.settings.sampler, d.settings.spp), (kind, 32), "{randomize}");
        assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    }
    let e = parse_str("Sampler \"halton\" \"string randomize\" \"sobol\"\nWorldBegin")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("test.pbrt:1:18") && e.contains("unknown randomization"),
        "{e}"
    );
}

#[test]
fn film_iso_and_shutter_set_the_exposure() {
    let d = parse_str("Film \"rgb\" \"float iso\" 400\nCamera \"perspective\" \"float shutterclose\" 0.5\nWorldBegin")
        .unwrap();
    // Imaging ratio 0.5 × 400 / 100 = 2: one stop.
    assert!((d.settings.exposure - 1.0).abs() < 1e-6);
}

#[test]
fn film_maxcomponentvalue_limits_samples() {
    let d = parse_str("Film \"rgb\" \"float maxcomponentvalue\" 10\nWorldBegin").unwrap();
    assert_eq!(d.settings.max_component_value, 10.0);
    assert!(
        !d.warnings.iter().any(|w| w.contains("maxcomponentvalue")),
        "{:?}",
        d.warnings
    );
    assert!(
        parse_str("WorldBegin")
            .unwrap()
            .settings
            .max_component_value
            .is_infinite()
    );
}

#[test]
fn perspective_fov_is_for_the_shorter_image_axis() {
    let fov = |w: u32, h: u32| {
        let d = parse_str(&format!(
            "Film \"rgb\" \"integer xresolution\" {w} \"integer yresolution\" {h}\nCamera \"perspective\" \"float fov\" 60\nWorldBegin"
        ))
        .unwrap();
        match d.camera.projection {
            ProjectionDesc::Perspective { fov } => fov,
            p => panic!("{p:?}"),
        }
    };
    // Landscape: the vertical axis is the shorter one.
    assert!((fov(200, 100) - 60.0).abs() < 1e-4);
    // Portrait: 60° across; vertically tan(fov_y/2) = 2·tan(30°).
    let expected = 2.0 * (2.0 * 30f32.to_radians().tan()).atan().to_degrees();
    assert!(
        (fov(100, 200) - expected).abs() < 1e-3,
        "{} vs {expected}",
        fov(100, 200)
    );
    assert!((fov(100, 100) - 60.0).abs() < 1e-4);
    // Film after Camera counts too: pbrt creates the camera at WorldBegin.
    let d = parse_str(
        "Camera \"perspective\" \"float fov\" 60\nFilm \"rgb\" \"integer xresolution\" 100 \"integer yresolution\" 200\nWorldBegin",
    )
    .unwrap();
    assert!(
        matches!(d.camera.projection, ProjectionDesc::Perspective { fov } if (fov - expected).abs() < 1e-3),
        "{:?}",
        d.camera.projection
    );
}

#[test]
fn orthographic_screen_window_and_lens() {
    let size = |w: u32, h: u32, extra: &str| {
        let d = parse_str(&format!(
            "Film \"rgb\" \"integer xresolution\" {w} \"integer yresolution\" {h}\nCamera \"orthographic\" {extra}\nWorldBegin"
        ))
        .unwrap();
        match d.camera.projection {
            ProjectionDesc::Orthographic { size } => (size, d.warnings),
            p => panic!("{p:?}"),
        }
    };
    assert_eq!(size(200, 100, "").0, 2.0);
    assert_eq!(size(100, 200, "").0, 4.0);
    let (s, w) = size(200, 100, "\"float screenwindow\" [-4 4 -2 2]");
    assert_eq!(s, 4.0);
    assert!(w.is_empty(), "a centred window of the image's shape is exact: {w:?}");
    // Any other window is laid over the image as given.
    let d = parse_str("Film \"rgb\" \"integer xresolution\" 200 \"integer yresolution\" 100\nCamera \"orthographic\" \"float screenwindow\" [0 1 0 3]\nWorldBegin").unwrap();
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert_eq!(d.camera.screen_window, Some([0.0, 1.0, 0.0, 3.0]));
    let d = parse_str("Film \"rgb\" \"integer xresolution\" 200 \"integer yresolution\" 100\nCamera \"orthographic\" \"float frameaspectratio\" 1\nWorldBegin").unwrap();
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert_eq!(d.camera.screen_window, Some([-1.0, 1.0, -1.0, 1.0]));
    for bad in ["[0 1 2]", "[1 0 0 1]", "[0 1 1 1]"] {
        let e = parse_str(&format!(
            "Camera \"orthographic\" \"float screenwindow\" {bad}\nWorldBegin"
        ))
        .unwrap_err();
        assert!(e.to_string().contains("screenwindow"), "{e}");
    }

    let d = parse_str("Camera \"perspective\" \"float lensradius\" 0.1 \"float focaldistance\" 4\nWorldBegin").unwrap();
    assert_eq!(d.camera.aperture_radius, 0.1);
    assert_eq!(d.camera.focus_distance, Some(4.0));
}

#[test]
fn look_at_reproduces_pbrts_handedness() {
    let d = parse_str("LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin").unwrap();
    let to_world = d.camera.to_world.expect("pbrt cameras give a matrix");
    assert!(close(to_world.transform_point3(Vec3::ZERO), Vec3::new(0.0, 0.0, 5.0)));
    // Forward is −z, up is +y, and image-right (camera +x) is world −x.
    assert!(close(to_world.transform_vector3(Vec3::Z), -Vec3::Z));
    assert!(close(to_world.transform_vector3(Vec3::Y), Vec3::Y));
    assert!(close(to_world.transform_vector3(Vec3::X), -Vec3::X));
    // Mirroring first gives the conventional view.
    let d = parse_str("Scale -1 1 1\nLookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin").unwrap();
    assert!(close(d.camera.to_world.unwrap().transform_vector3(Vec3::X), Vec3::X));
}

/// The camera matrix of `LookAt` is exactly affine, so no tilt makes it
/// "singular": a thousand random eyes, targets and tilted up vectors (a
/// fixed seed) all give cameras, where a general 4×4 inverse refused about
/// one in five.
#[test]
fn a_thousand_random_tilted_look_at_cameras_are_accepted() {
    let mut rng = crate::sampling::Pcg32::new(31, 1);
    let mut r = move |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f32();
    let mut accepted = 0;
    while accepted < 1000 {
        let eye = Vec3::new(r(-20.0, 20.0), r(-20.0, 20.0), r(-20.0, 20.0));
        let target = Vec3::new(r(-20.0, 20.0), r(-20.0, 20.0), r(-20.0, 20.0));
        let up = Vec3::new(r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0));
        let dir = (target - eye).normalize();
        if (target - eye).length() < 0.1 || up.length() < 0.1 || up.normalize().cross(dir).length() < 0.05 {
            continue;
        }
        let text = format!(
            "LookAt {} {} {}  {} {} {}  {} {} {}\nCamera \"perspective\" \"float fov\" 40\nFilm \"rgb\" \"integer xresolution\" 8 \"integer yresolution\" 6\nWorldBegin\nLightSource \"point\" \"point3 from\" [0 10 0]\nShape \"sphere\"\n",
            eye.x, eye.y, eye.z, target.x, target.y, target.z, up.x, up.y, up.z
        );
        let d = parse_str(&text).unwrap_or_else(|e| panic!("camera {accepted} refused: {e}\n{text}"));
        crate::scene::build(&d).unwrap_or_else(|e| panic!("camera {accepted} refused: {e}\n{text}"));
        // The camera is where LookAt puts it and looks where it says, with
        // its up axis in the plane of the up vector and the view.
        let m = d.camera.to_world.expect("pbrt cameras give a matrix");
        assert_eq!(m.row(3), Vec4::W, "{text}");
        let tol = 1e-5 * (1.0 + eye.length());
        assert!((m.transform_point3(Vec3::ZERO) - eye).length() < tol, "{text}");
        assert!((m.transform_vector3(Vec3::Z) - dir).length() < 1e-5, "{text}");
        assert!(
            m.transform_vector3(Vec3::Y).dot(up.cross(dir).normalize()).abs() < 1e-5,
            "{text}"
        );
        assert!(m.transform_vector3(Vec3::Y).dot(up) > 0.0, "{text}");
        accepted += 1;
    }
}

/// A `LookAt` with no viewing direction, or with an up vector along it, is
/// refused at the `LookAt`, saying which, also when the parallel vectors
/// were written in decimals that single precision rounds a hair apart.
#[test]
fn singular_look_at_is_refused_with_its_reason() {
    for (text, expected) in [
        (
            "LookAt 1 2 3  1 2 3  0 1 0",
            "test.pbrt:1:1: `LookAt`: the eye and the point looked at are the same point (1 2 3)",
        ),
        (
            "LookAt 0 0 0  1 1 1  2 2 2",
            "test.pbrt:1:1: `LookAt`: the up vector (2 2 2) is parallel to the viewing direction",
        ),
        (
            "LookAt 0 0 0  0 0 -3  0 0 1",
            "test.pbrt:1:1: `LookAt`: the up vector (0 0 1) is parallel to the viewing direction",
        ),
        (
            "LookAt 0.1 0.2 0.3  0.4 0.8 1.2  0.3 0.6 0.9",
            "`LookAt`: the up vector (0.3 0.6 0.9) is parallel to the viewing direction",
        ),
        (
            "LookAt 0 0 0  0 0 1  0 0 0",
            "`LookAt`: the up vector must not be the zero vector",
        ),
    ] {
        let e = error_of(&format!("{text}\nCamera \"perspective\"\nWorldBegin"));
        assert!(e.contains(expected), "{text}: {e}");
    }
}

/// A camera transform whose bottom row is not 0 0 0 1 is used as pbrt-v4
/// uses it (the inverse moves the eye as a point and directions by its
/// 3×3 part): a multiple of a matrix is the same camera, and rounding
/// noise in the bottom row changes nothing visible.
#[test]
fn projective_camera_transforms_move_rays_as_in_pbrt() {
    let plain = parse_str("LookAt 1 2 5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin").unwrap();
    let plain = plain.camera.to_world.unwrap();
    let doubled = parse_str(
        "ConcatTransform [2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 2]\nLookAt 1 2 5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin",
    )
    .unwrap();
    assert!(doubled.warnings.is_empty(), "{:?}", doubled.warnings);
    let doubled = doubled.camera.to_world.unwrap();
    assert!(close(
        doubled.transform_point3(Vec3::ZERO),
        plain.transform_point3(Vec3::ZERO)
    ));
    for v in [Vec3::X, Vec3::Y, Vec3::Z] {
        assert!(close(
            doubled.transform_vector3(v).normalize(),
            plain.transform_vector3(v)
        ));
    }
    let noisy = parse_str(
        "LookAt 1 2 5  0 0 0  0 1 0\nConcatTransform [1 0 0 1e-9  0 1 0 -2e-9  0 0 1 0  0 0 0 0.99999994]\nCamera \"perspective\"\nWorldBegin",
    )
    .unwrap()
    .camera
    .to_world
    .unwrap();
    assert!(close(
        noisy.transform_point3(Vec3::ZERO),
        plain.transform_point3(Vec3::ZERO)
    ));
    assert!(close(
        noisy.transform_vector3(Vec3::Z),
        plain.transform_vector3(Vec3::Z)
    ));
    // A thin lens is moved by the affine part only: approximated.
    let d = parse_str(
        "ConcatTransform [1 0 0 0.1  0 1 0 0  0 0 1 0  0 0 0 1]\nCamera \"perspective\" \"float lensradius\" 0.1\nWorldBegin",
    )
    .unwrap();
    assert!(
        d.warnings[0].starts_with(
            "test.pbrt:2:1: a projective camera transform (a bottom row other than 0 0 0 1) is approximated"
        ),
        "{:?}",
        d.warnings
    );
    // An eye at infinity has no view.
    let e = error_of("Transform [1 0 0 0  0 1 0 0  0 0 0 1  0 0 1 0]\nCamera \"perspective\"\nWorldBegin");
    assert!(
        e.contains("`Camera`: the current transform is projective and puts the eye at infinity"),
        "{e}"
    );
}

#[test]
fn transforms_post_multiply() {
    let d = world(
        "Translate 1 0 0\nScale 2 2 2\nShape \"sphere\"\nIdentity\nRotate 90 0 0 1\nTranslate 1 0 0\nShape \"sphere\"",
    );
    // CTM = T · S: the scale applies to the object first.
    let m = matrix(&d, 0);
    assert!(close(m.transform_point3(Vec3::ZERO), Vec3::X));
    assert!(close(m.transform_point3(Vec3::X), Vec3::new(3.0, 0.0, 0.0)));
    // CTM = R · T: the translation is rotated.
    let m = matrix(&d, 1);
    assert!(close(m.transform_point3(Vec3::ZERO), Vec3::Y));
}

#[test]
fn transform_numbers_are_column_major_and_concat_multiplies() {
    // pbrt reads the 16 numbers as rows and transposes them, so the
    // translation is the 13th to 15th number.
    let d = world(
        "Translate 9 9 9\nTransform [1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1]\nShape \"sphere\"\n\
         Identity\nTranslate 1 0 0\nConcatTransform [0 1 0 0  -1 0 0 0  0 0 1 0  0 0 0 1]\nShape \"sphere\"",
    );
    // Transform replaces the CTM.
    assert!(close(
        matrix(&d, 0).transform_point3(Vec3::ZERO),
        Vec3::new(5.0, 6.0, 7.0)
    ));
    // ConcatTransform post-multiplies: x → y (first column is (0 1 0)),
    // then the earlier translation.
    let m = matrix(&d, 1);
    assert!(close(m.transform_point3(Vec3::X), Vec3::new(1.0, 1.0, 0.0)));
    assert_eq!(m.col(0), Vec4::new(0.0, 1.0, 0.0, 0.0));
}

#[test]
fn attribute_blocks_restore_the_graphics_state() {
    let d = world(
        r#"Material "diffuse" "rgb reflectance" [0.1 0.2 0.3]
AttributeBegin
  Translate 0 5 0
  Material "conductor"
  ReverseOrientation
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Shape "sphere"
AttributeEnd
Shape "sphere"
TransformBegin
  Translate 1 0 0
TransformEnd
Shape "disk""#,
    );
    assert!(close(
        matrix(&d, 0).transform_point3(Vec3::ZERO),
        Vec3::new(0.0, 5.0, 0.0)
    ));
    assert!(d.shapes[0].flip_normals);
    assert!(matches!(material(&d, 0).kind, MaterialKindDesc::Conductor { .. }));
    assert_eq!(material(&d, 0).emission, ColorSource::Rgb(Rgb::ONE));
    for i in [1, 2] {
        assert_eq!(matrix(&d, i), Mat4::IDENTITY);
        assert!(!d.shapes[i].flip_normals);
        let m = material(&d, i);
        assert_eq!(
            m.kind,
            MaterialKindDesc::Diffuse {
                reflectance: ColorSource::Rgb(Rgb::new(0.1, 0.2, 0.3))
            }
        );
        assert_eq!(m.emission, ColorSource::Rgb(Rgb::ZERO));
    }
}

#[test]
fn mirrored_quadrics_flip_like_pbrt_but_triangles_keep_their_side() {
    let d = world(
        "Scale -1 1 1\nShape \"sphere\"\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n\
         ReverseOrientation\nShape \"sphere\"\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]",
    );
    let flips: Vec<bool> = d.shapes.iter().map(|s| s.flip_normals).collect();
    assert_eq!(flips, vec![true, false, false, true]);
}

#[test]
fn coordinate_systems_and_the_camera_space() {
    let d = parse_str(
        r#"LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective"
WorldBegin
Translate 3 0 0
CoordinateSystem "shifted"
Identity
CoordSysTransform "shifted"
Shape "sphere"
CoordSysTransform "camera"
Translate 0 0 1
Shape "sphere"
CoordSysTransform "world"
Shape "sphere""#,
    )
    .unwrap();
    assert!(close(
        matrix(&d, 0).transform_point3(Vec3::ZERO),
        Vec3::new(3.0, 0.0, 0.0)
    ));
    // One unit in front of the camera at z = 5 looking down −z.
    assert!(close(
        matrix(&d, 1).transform_point3(Vec3::ZERO),
        Vec3::new(0.0, 0.0, 4.0)
    ));
    assert_eq!(matrix(&d, 2), Mat4::IDENTITY);

    let d = world("CoordSysTransform \"nowhere\"");
    assert!(d.warnings[0].starts_with("test.pbrt:2:1: CoordSysTransform \"nowhere\" is unsupported"));
}

#[test]
fn loop_subdivision_surfaces_become_their_refined_limit_meshes() {
    // A tetrahedron: 4 faces, 3 levels by default (pbrt-v4's).
    let tetrahedron = r#""point3 P" [1 1 1  1 -1 -1  -1 1 -1  -1 -1 1]
        "integer indices" [0 1 2  0 3 1  0 2 3  1 3 2]"#;
    for (levels, faces) in [
        ("", 4 * 64),
        ("\"integer levels\" 1", 4 * 4),
        ("\"integer levels\" 0", 4),
    ] {
        let d = world(&format!("Shape \"loopsubdiv\" {levels} {tetrahedron}"));
        assert!(d.warnings.is_empty(), "{:?}", d.warnings);
        let ShapeKind::InlineMesh(MeshSource::Inline(m)) = &d.shapes[0].kind else {
            panic!("{:?}", d.shapes[0].kind)
        };
        assert_eq!(m.indices.len(), faces);
        assert_eq!(m.normals.len(), m.positions.len());
        // The limit surface lies inside the control hull, and its triangles
        // face the side of pbrt-v4's limit normals: inward, against the
        // control faces' counter-clockwise side.
        let centre: Vec3 = m.positions.iter().sum::<Vec3>() / m.positions.len() as f32;
        assert!(centre.length() < 1e-4);
        for t in &m.indices {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let n = (b - a).cross(c - a);
            assert!(n.dot(a + b + c) < 0.0);
            assert!(m.normals[t[0] as usize].dot(n) > 0.0);
        }
    }
    for (shape, message) in [
        (
            format!("Shape \"loopsubdiv\" \"integer levels\" 99 {tetrahedron}"),
            "test.pbrt:2:20: `integer levels`: 99 is not a number of subdivision levels",
        ),
        (
            "Shape \"loopsubdiv\" \"integer indices\" [0 1 2]".to_string(),
            "test.pbrt:2:1: `P`: loopsubdiv needs vertex positions",
        ),
    ] {
        let e = parse_str(&format!("WorldBegin\n{shape}")).unwrap_err().to_string();
        assert!(e.starts_with(message), "{e}");
    }
}

#[test]
fn analytic_shapes() {
    let d = world(
        r#"Shape "sphere" "float radius" 2
Shape "disk" "float height" 0.5 "float radius" 3
Shape "cylinder" "float radius" 0.5 "float zmin" -2 "float zmax" 3
Shape "sphere" "float zmax" 0.5
Shape "disk" "float innerradius" 0.5
Shape "cylinder" "float phimax" 90
Shape "cone" "float radius" 2 "float height" 3
Shape "paraboloid" "float zmax" 2
Shape "hyperboloid" "point3 p1" [1 0 -1] "point3 p2" [0 1 1] "float phimax" 180"#,
    );
    assert_eq!(
        d.shapes[0].kind,
        ShapeKind::Sphere {
            center: Vec3::ZERO,
            radius: 2.0
        }
    );
    assert_eq!(
        d.shapes[1].kind,
        ShapeKind::Disk {
            center: Vec3::new(0.0, 0.0, 0.5),
            normal: Vec3::Z,
            radius: 3.0,
            uv: crate::geometry::DiskUv::AngleRadius,
        }
    );
    assert_eq!(
        d.shapes[2].kind,
        ShapeKind::Cylinder {
            p0: Vec3::new(0.0, 0.0, -2.0),
            p1: Vec3::new(0.0, 0.0, 3.0),
            radius: 0.5
        }
    );
    use crate::geometry::quadric::Quadric;
    assert_eq!(d.shapes.len(), 9);
    // Cut quadrics, pbrt-v4's and pbrt-v3's, are quadrics with their cuts.
    let expected = [
        Quadric::sphere(1.0, -1.0, 0.5, 360.0),
        Quadric::annulus(0.0, 0.5, 1.0, 360.0),
        Quadric::cylinder(1.0, -1.0, 1.0, 90.0),
        Quadric::cone(2.0, 3.0, 360.0),
        Quadric::paraboloid(1.0, 0.0, 2.0, 360.0),
        Quadric::hyperboloid(Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, 1.0), 180.0),
    ];
    for (shape, q) in d.shapes[3..].iter().zip(expected) {
        assert_eq!(shape.kind, ShapeKind::Quadric(q.unwrap()));
    }
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    // The default material is pbrt's: diffuse 0.5.
    assert_eq!(
        material(&d, 0).kind,
        MaterialKindDesc::Diffuse {
            reflectance: ColorSource::Rgb(Rgb::splat(0.5))
        }
    );
}

#[test]
fn meshes() {
    let d = world(
        r#"Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0  1 1 0] "integer indices" [0 1 2  2 1 3]
  "normal N" [0 0 1 0 0 1 0 0 1 0 0 1] "point2 uv" [0 0 1 0 0 1 1 1]
Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0]
Shape "bilinearmesh" "point3 P" [0 0 0  1 0 0  0 1 0  1 1 0]
Shape "bilinearmesh" "point3 P" [0 0 0  1 0 0  0 1 0  1 1 1  2 0 0  2 1 0] "integer indices" [0 1 2 3  1 4 3 5]
  "point2 uv" [0 0  1 0  0 1  1 1  2 0  2 1]
Shape "plymesh" "string filename" "models/bunny.ply""#,
    );
    let mesh = |i: usize| match &d.shapes[i].kind {
        ShapeKind::InlineMesh(MeshSource::Inline(m)) => m.clone(),
        k => panic!("{k:?}"),
    };
    let m = mesh(0);
    assert_eq!(m.indices, vec![[0, 1, 2], [2, 1, 3]]);
    assert_eq!((m.normals.len(), m.uvs.len()), (4, 4));
    assert_eq!(m.uvs[3], Vec2::ONE);
    // Three points need no indices.
    assert_eq!(mesh(1).indices, vec![[0, 1, 2]]);
    // A patch v00 v10 v01 v11 is two triangles with its normal (+z).
    let q = mesh(2);
    assert_eq!(q.indices, vec![[0, 1, 3], [0, 3, 2]]);
    for i in 0..2 {
        let [a, b, c] = q.vertices(i);
        assert!((b - a).cross(c - a).z > 0.0);
    }
    // A mesh with a bent patch is a bilinear patch per patch, with the
    // corners and texture coordinates in pbrt-v4's order.
    let patch = |i: usize| match &d.shapes[i].kind {
        ShapeKind::Bilinear(b) => *b,
        k => panic!("{k:?}"),
    };
    let (first, second) = (patch(3), patch(4));
    assert_eq!(first.p.map(|p| p.as_vec3()), [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE]);
    assert_eq!(second.p[3].as_vec3(), Vec3::new(2.0, 1.0, 0.0));
    assert_eq!(
        second.uvs,
        [Vec2::X, Vec2::new(2.0, 0.0), Vec2::ONE, Vec2::new(2.0, 1.0)]
    );
    assert_eq!(
        d.shapes[5].kind,
        ShapeKind::InlineMesh(MeshSource::File(PathBuf::from("models/bunny.ply")))
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
}

#[test]
fn bad_meshes_are_errors_at_the_parameter() {
    let e = error_of("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 3]");
    assert!(
        e.starts_with("test.pbrt:2:53: `integer indices`: index 3 is out of range"),
        "{e}"
    );
    let e =
        error_of("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 -1]");
    assert!(e.contains("index -1 is out of range"), "{e}");
    let e =
        error_of("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 1] \"integer indices\" [0 1]");
    assert!(e.contains("needs 3 indices per triangle, found 2"), "{e}");
    let e = error_of("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 1]");
    assert!(e.starts_with("test.pbrt:2:22: `indices`: trianglemesh needs"), "{e}");
    let e = error_of("WorldBegin\nShape \"trianglemesh\" \"integer indices\" [0 1 2]");
    assert!(e.starts_with("test.pbrt:2:1: `P`"), "{e}");
    let e = error_of("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"normal N\" [0 0 1]");
    assert!(e.contains("1 normals given for 3 points"), "{e}");
    let e = error_of("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"point2 uv\" [0 0]");
    assert!(e.contains("1 texture coordinates given for 3 points"), "{e}");
    let e = error_of(
        "WorldBegin\nShape \"bilinearmesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 1 2 2 2] \"integer indices\" [0 1 2]",
    );
    assert!(e.contains("needs 4 indices per patch"), "{e}");
    let e = error_of("WorldBegin\nShape \"plymesh\"");
    assert!(e.starts_with("test.pbrt:2:1: `filename`: plymesh needs"), "{e}");
    let e = error_of("WorldBegin\nShape \"sphere\" \"float radius\" -1");
    assert!(
        e.starts_with("test.pbrt:2:16: `shape[0].radius`: must be positive"),
        "{e}"
    );
}

/// pbrt-v4's brass, magnesium oxide and titanium dioxide: their spectra
/// at trazo's three wavelengths, without a warning; brass is yellow (its
/// reflectance at normal incidence largest in red, smallest in blue).
#[test]
fn pbrt_named_metal_spectra_beyond_the_four_metals() {
    let d = world(
        r#"Material "conductor" "spectrum eta" "metal-CuZn-eta" "spectrum k" "metal-CuZn-k"
Shape "sphere"
Material "conductor" "spectrum eta" "metal-TiO2-eta" "spectrum k" "metal-TiO2-k"
Shape "sphere"
Material "conductor" "spectrum eta" "metal-Xx-eta"
Shape "sphere""#,
    );
    let complex = |i: usize| match material(&d, i).kind {
        MaterialKindDesc::Conductor {
            fresnel: ConductorDesc::Complex { eta, k },
            ..
        } => (eta, k),
        ref other => panic!("{other:?}"),
    };
    let (eta, k) = complex(0);
    let r0 = |e: f32, k: f32| ((e - 1.0).powi(2) + k * k) / ((e + 1.0).powi(2) + k * k);
    let (r, g, b) = (r0(eta.x, k.x), r0(eta.y, k.y), r0(eta.z, k.z));
    assert!(r > g && g > b && b > 0.3, "brass at normal incidence: {r} {g} {b}");
    let (eta, k) = complex(1);
    assert!((eta.y - 2.955).abs() < 1e-3 && k == Rgb::ZERO, "{eta} {k}");
    assert_eq!(d.warnings.len(), 1, "{:?}", d.warnings);
    assert!(d.warnings[0].contains("metal-Xx-eta"), "{:?}", d.warnings);
}

#[test]
fn materials_map_to_the_nearest_model() {
    let d = world(
        r#"Material "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0.04
Shape "sphere"
Material "conductor" "rgb reflectance" [0.9 0.8 0.7] "float uroughness" 0.01 "float vroughness" 0.09 "bool remaproughness" false
Shape "sphere"
Material "dielectric" "float eta" 1.33
Shape "sphere"
Material "dielectric" "spectrum eta" "glass-BK7" "float roughness" 0.25
Shape "sphere"
Material "coateddiffuse" "rgb reflectance" [0.2 0.3 0.4] "float roughness" 0
Shape "sphere"
Material "conductor"
Shape "sphere"
Material "coateddiffuse" "spectrum eta" "glass-F11"
Shape "sphere"
Material "dielectric" "spectrum eta" [400 1.6 700 1.5]
Shape "sphere"
Material "dielectric" "spectrum eta" [400 1.45 700 1.45]
Shape "sphere""#,
    );
    let (au_eta, au_k) = crate::material::conductor::metal_ior("Au").unwrap();
    assert_eq!(
        material(&d, 0).kind,
        MaterialKindDesc::Conductor {
            fresnel: ConductorDesc::Complex { eta: au_eta, k: au_k },
            tint: Rgb::ONE,
            // remaproughness: α = √roughness.
            roughness: (0.2, 0.2),
            distribution: MicrofacetDistribution::Ggx,
        }
    );
    assert_eq!(
        material(&d, 1).kind,
        MaterialKindDesc::Conductor {
            fresnel: ConductorDesc::Reflectance(Rgb::new(0.9, 0.8, 0.7)),
            tint: Rgb::ONE,
            roughness: (0.01, 0.09),
            distribution: MicrofacetDistribution::Ggx,
        }
    );
    assert!(
        matches!(material(&d, 2).kind, MaterialKindDesc::Dielectric { ior, roughness, .. } if ior == 1.33 && roughness == (0.0, 0.0))
    );
    // Named glasses and varying sampled indices disperse; the index at
    // the d line stands for them where one index is needed.
    let bk7 = crate::material::dispersion::IorSpectrum::named_glass("glass-BK7");
    assert!(
        matches!(&material(&d, 3).kind, MaterialKindDesc::Dielectric { ior, roughness, dispersion, .. }
            if (ior - 1.5168).abs() < 1e-4 && *roughness == (0.5, 0.5) && *dispersion == bk7)
    );
    assert!(
        matches!(&material(&d, 7).kind, MaterialKindDesc::Dielectric { ior, dispersion: Some(s), .. }
        if (ior - s.at(587.56)).abs() < 1e-6 && s.at(400.0) == 1.6)
    );
    assert!(matches!(
        &material(&d, 8).kind,
        MaterialKindDesc::Dielectric {
            ior: 1.45,
            dispersion: None,
            ..
        }
    ));
    assert_eq!(
        material(&d, 4).kind,
        MaterialKindDesc::Layered {
            base: LayeredBaseDesc::Diffuse(ColorSource::Rgb(Rgb::new(0.2, 0.3, 0.4))),
            coat_ior: 1.5,
            coat_roughness: (0.0, 0.0),
            thickness: 0.01,
            albedo: Rgb::ZERO,
            g: 0.0,
            max_depth: 10,
            samples: 1,
            coat_dispersion: None,
        }
    );
    // pbrt-v4's default conductor is copper.
    let (cu_eta, cu_k) = crate::material::conductor::metal_ior("Cu").unwrap();
    assert!(matches!(
        material(&d, 5).kind,
        MaterialKindDesc::Conductor { fresnel: ConductorDesc::Complex { eta, k }, .. } if eta == cu_eta && k == cu_k
    ));
    let w = d.warnings.join("\n");
    // Coats disperse too.
    assert!(
        matches!(&material(&d, 6).kind, MaterialKindDesc::Layered { coat_ior, coat_dispersion: Some(f11), .. }
        if (coat_ior - 1.7847).abs() < 1e-4 && f11.at(450.0) > f11.at(650.0))
    );
    assert!(!w.contains("glass-") && !w.contains("[400"), "{w}");
}

#[test]
fn rgb_indices_disperse_as_pbrt_v4s_unbounded_rgb_spectra() {
    let d = world(
        r#"Material "dielectric" "rgb eta" [1.45 1.5 1.6]
Shape "sphere"
Material "dielectric" "rgb eta" [1.5 1.5 1.5]
Shape "sphere"
Material "thindielectric" "rgb eta" [1.6 1.5 1.45]
Shape "sphere""#,
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    // Twice the largest channel times the smooth spectrum whose colour is
    // the rest: the colour of the index's spectrum (as a reflectance, the
    // fit's measure) is the colour given, and blue light bends more.
    let MaterialKindDesc::Dielectric {
        ior,
        dispersion: Some(s),
        ..
    } = &material(&d, 0).kind
    else {
        panic!("{:?}", material(&d, 0).kind);
    };
    assert!((ior - s.at(587.56)).abs() < 1e-6);
    assert!(s.at(450.0) > s.at(550.0) && s.at(550.0) > s.at(650.0), "{s:?}");
    let rgb = crate::color::spectrum::xyz_to_linear_srgb(crate::color::spectrum::spectrum_xyz(
        |nm| s.at(nm as f32) as f64 / 3.2,
        true,
    ));
    for (k, want) in [1.45, 1.5, 1.6].into_iter().enumerate() {
        assert!((rgb[k] * 3.2 - want).abs() < 1e-4, "{rgb:?}");
    }
    // Grey is one index; a thin sheet disperses the other way round.
    assert!(matches!(
        &material(&d, 1).kind,
        MaterialKindDesc::Dielectric {
            ior: 1.5,
            dispersion: None,
            ..
        }
    ));
    assert!(matches!(
        &material(&d, 2).kind,
        MaterialKindDesc::Thin { dispersion: Some(s), .. } if s.at(650.0) > s.at(450.0)
    ));
    // A channel that is not positive is an error at its place.
    let e = error_of("WorldBegin\nMaterial \"dielectric\" \"rgb eta\" [1.5 0 1.5]\nShape \"sphere\"\n");
    assert!(e.contains("2:") && e.contains("must be positive"), "{e}");
}

#[test]
fn coated_materials_are_pbrt_v4s_layered_bsdf() {
    let d = world(
        r#"Material "coatedconductor" "spectrum conductor.eta" [400 0.2 700 0.2] "spectrum conductor.k" [400 3 700 3]
    "float conductor.roughness" 0.04 "float interface.roughness" 0.09 "float interface.eta" 1.4
    "float thickness" 0.2 "rgb albedo" [0.5 0.4 0.3] "float g" -0.3 "integer maxdepth" 20 "integer nsamples" 4
Shape "sphere"
Material "coatedconductor"
Shape "sphere""#,
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert_eq!(
        material(&d, 0).kind,
        MaterialKindDesc::Layered {
            base: LayeredBaseDesc::Conductor {
                fresnel: ConductorDesc::Complex {
                    eta: Rgb::splat(0.2),
                    k: Rgb::splat(3.0)
                },
                roughness: (0.2, 0.2),
                roughness_map: None,
            },
            coat_ior: 1.4,
            coat_roughness: (0.3, 0.3),
            thickness: 0.2,
            albedo: Rgb::new(0.5, 0.4, 0.3),
            g: -0.3,
            max_depth: 20,
            samples: 4,
            coat_dispersion: None,
        }
    );
    let (cu_eta, cu_k) = crate::material::conductor::metal_ior("Cu").unwrap();
    assert!(matches!(
        material(&d, 1).kind,
        MaterialKindDesc::Layered {
            base: LayeredBaseDesc::Conductor { fresnel: ConductorDesc::Complex { eta, k }, roughness: (0.0, 0.0), .. },
            coat_ior: 1.5,
            ..
        } if eta == cu_eta && k == cu_k
    ));
    for (bad, message) in [
        (
            "\"float thickness\" 0",
            "test.pbrt:2:26: `float thickness`: must be positive, got 0",
        ),
        ("\"float g\" 2", "test.pbrt:2:26: `float g`: must be in [-1, 1], got 2"),
        (
            "\"integer maxdepth\" 0",
            "test.pbrt:2:26: `integer maxdepth`: must be 1 to 4096, got 0",
        ),
        (
            "\"rgb albedo\" [2 0 0]",
            "test.pbrt:2:26: `rgb albedo`: an albedo must be at most 1",
        ),
    ] {
        let e = error_of(&format!(
            "WorldBegin\nMaterial \"coateddiffuse\" {bad}\nShape \"sphere\""
        ));
        assert!(e.starts_with(message), "{e}");
    }
}

#[test]
fn other_materials_are_approximated_with_warnings() {
    // diffusetransmission is read as it is, with pbrt-v4's defaults.
    let d = world("Material \"diffusetransmission\"\nShape \"sphere\"");
    assert_eq!(
        material(&d, 0).kind,
        MaterialKindDesc::DiffuseTransmission {
            reflectance: ColorSource::Rgb(Rgb::splat(0.25)),
            transmittance: ColorSource::Rgb(Rgb::splat(0.25)),
        }
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    // Its scale multiplies constants (clamped to 1) and textures (a scale
    // node; the BSDF clamps).
    let d = world(
        "Texture \"grid\" \"spectrum\" \"checkerboard\"\nMaterial \"diffusetransmission\" \"texture reflectance\" \"grid\" \"rgb transmittance\" [0.2 0.4 0.8] \"float scale\" 2\nShape \"sphere\"",
    );
    let MaterialKindDesc::DiffuseTransmission {
        reflectance: ColorSource::Texture(scaled),
        transmittance,
    } = &material(&d, 0).kind
    else {
        panic!("{:?}", material(&d, 0).kind)
    };
    assert_eq!(*transmittance, ColorSource::Rgb(Rgb::new(0.4, 0.8, 1.0)));
    let node = d.textures.iter().find(|t| &t.name == scaled).unwrap();
    assert_eq!(
        node.kind,
        TextureKind::Node(TextureNode::Scale {
            tex: ColorSource::Texture("grid".into()),
            scale: ColorSource::Rgb(Rgb::splat(2.0)),
        })
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    // subsurface is a dielectric over a medium, with a warning.
    let d = world("Material \"subsurface\"\nShape \"sphere\"");
    assert!(matches!(material(&d, 0).kind, MaterialKindDesc::Dielectric { .. }));
    assert!(
        d.warnings
            .iter()
            .any(|w| w.starts_with("test.pbrt:2:1: material \"subsurface\" is approximated")),
        "{:?}",
        d.warnings
    );
}

#[test]
fn named_and_mixed_materials() {
    let d = world(
        r#"NamedMaterial "later"
Shape "sphere"
MakeNamedMaterial "later" "string type" "diffuse" "rgb reflectance" [0.1 0.1 0.1]
MakeNamedMaterial "metal" "string type" "conductor"
MakeNamedMaterial "blend" "string type" "mix" "string materials" ["later" "metal"] "float amount" 0.8
NamedMaterial "blend"
Shape "sphere""#,
    );
    // Named materials are resolved when the file has been read, as pbrt does.
    assert_eq!(d.shapes[0].material.as_deref(), Some("later"));
    // mix takes the second material with probability `amount`.
    assert_eq!(
        material(&d, 1).kind,
        MaterialKindDesc::Mix {
            choice: MixChoice::Weight(ColorSource::Rgb(Rgb::splat(0.8))),
            materials: ["later".to_string(), "metal".to_string()],
        }
    );
    assert!(!d.warnings.iter().any(|w| w.contains("mix")), "{:?}", d.warnings);
    crate::scene::build(&d).expect("builds");
    let e = error_of(
        "WorldBegin\nMakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [\"m\" \"m\"]\nNamedMaterial \"m\"\nShape \"sphere\"",
    );
    assert!(e.contains("m"), "{e}");
    let e = error_of(
        "WorldBegin\nMakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [\"x\" \"y\"]\nNamedMaterial \"m\"\nShape \"sphere\"",
    );
    assert!(e.contains("no material named \"x\""), "{e}");

    let e = error_of(
        "WorldBegin\nNamedMaterial \"nope\"\nShape \"sphere\"\nMakeNamedMaterial \"nop\" \"string type\" \"diffuse\"",
    );
    assert!(
        e.starts_with("test.pbrt:2:15: `NamedMaterial`: no material named \"nope\" (did you mean \"nop\"?)"),
        "{e}"
    );
    let e = error_of(
        "WorldBegin\nMakeNamedMaterial \"a\" \"string type\" \"diffuse\"\nMakeNamedMaterial \"a\" \"string type\" \"diffuse\"",
    );
    assert!(
        e.starts_with("test.pbrt:3:19: the named material \"a\" is already defined (at test.pbrt:2:1)"),
        "{e}"
    );
    let e = error_of("WorldBegin\nMakeNamedMaterial \"a\" \"rgb reflectance\" [1 1 1]");
    assert!(e.contains("needs a \"string type\""), "{e}");
    let e = error_of("WorldBegin\nMaterial \"difuse\"");
    assert!(
        e.contains("unknown Material type \"difuse\" (did you mean \"diffuse\"?)"),
        "{e}"
    );
    let e = error_of("WorldBegin\nMaterial \"diffuse\" \"rgb reflectance\" [1.5 0 0]");
    assert!(e.contains("must not exceed 1"), "{e}");
}

/// An imagemap's `encoding` decodes PNG files, as pbrt-v4's `Image::Read`
/// applies it: `sRGB`, `linear` and `gamma γ`; other integer formats stay
/// sRGB and float formats linear whatever it says (`None`: by the file's
/// type); an unknown encoding is an error at its place.
#[test]
fn imagemap_encodings_decode_png_files_as_pbrt_v4_reads_them() {
    let encoding_of = |file: &str, encoding: &str| {
        let d = world(&format!(
            "Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"{file}\" \"string encoding\" \"{encoding}\""
        ));
        match &d.textures[0].kind {
            TextureKind::Image { encoding, .. } => *encoding,
            k => panic!("{k:?}"),
        }
    };
    assert_eq!(encoding_of("a.png", "sRGB"), Some(Encoding::Srgb));
    assert_eq!(encoding_of("a.PNG", "linear"), Some(Encoding::Linear));
    assert_eq!(encoding_of("a.png", "gamma 2.2"), Some(Encoding::Gamma(2.2)));
    for other in ["a.jpg", "a.tga", "a.exr", "a.pfm"] {
        assert_eq!(encoding_of(other, "gamma 2.2"), None, "{other}");
        assert_eq!(encoding_of(other, "linear"), None, "{other}");
    }
    for bad in ["gamma", "gamma -1", "srgb", "gamma x"] {
        let e = error_of(&format!(
            "WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"a.png\" \"string encoding\" \"{bad}\""
        ));
        assert!(
            e.contains("test.pbrt:2:") && e.contains(&format!("unknown encoding \"{bad}\"")),
            "{e}"
        );
    }
}

#[test]
fn textures() {
    let d = world(
        r#"Texture "img" "spectrum" "imagemap" "string filename" "textures/wood.png" "float uscale" 2 "float vscale" 3 "float udelta" 0.5 "float scale" 0.8 "string encoding" "linear"
Texture "checks" "spectrum" "checkerboard" "rgb tex1" [1 0 0] "rgb tex2" [0 0 1] "float uscale" 4 "float vscale" 4
Scale 0.5 0.5 0.5
Texture "solid" "spectrum" "checkerboard" "integer dimension" 3 "rgb tex1" [1 1 1] "rgb tex2" [0 0 0]
Texture "bump" "float" "imagemap" "string filename" "bump.png"
Texture "gray" "spectrum" "constant" "rgb value" [0.3 0.3 0.3]
Material "diffuse" "texture reflectance" "checks"
Shape "sphere""#,
    );
    assert_eq!(
        d.textures[0].kind,
        TextureKind::Image {
            source: ImageSource::File(PathBuf::from("textures/wood.png")),
            scale: Vec2::new(2.0, 3.0),
            offset: Vec2::new(0.5, 0.0),
            encoding: Some(Encoding::Linear),
            tint: Rgb::splat(0.8),
            wrap: [crate::texture::WrapMode::Repeat; 2],
            filter: crate::texture::ImageFilter::Bilinear,
        }
    );
    assert_eq!(
        d.textures[1].kind,
        TextureKind::Checkerboard {
            even: Rgb::X,
            odd: Rgb::Z,
            scale: Vec2::splat(4.0)
        }
    );
    // pbrt looks solid textures up in texture space: the inverse of the CTM.
    assert_eq!(
        d.textures[2].kind,
        TextureKind::Checkerboard3d {
            even: Rgb::ONE,
            odd: Rgb::ZERO,
            scale: 2.0
        }
    );
    assert_eq!(d.textures[3].kind, TextureKind::Constant(Rgb::splat(0.3)));
    assert_eq!(d.textures.len(), 4, "float textures no roughness reads are dropped");
    assert_eq!(
        material(&d, 0).kind,
        MaterialKindDesc::Diffuse {
            reflectance: ColorSource::Texture("checks".into())
        }
    );
    assert!(!d.warnings.iter().any(|w| w.contains("bump")), "{:?}", d.warnings);

    let e = error_of("WorldBegin\nMaterial \"diffuse\" \"texture reflectance\" \"nothing\"\nShape \"sphere\"");
    assert!(
        e.starts_with("test.pbrt:2:20: `texture`: no texture named \"nothing\""),
        "{e}"
    );
    let e = error_of(
        "WorldBegin\nTexture \"b\" \"float\" \"constant\"\nMaterial \"diffuse\" \"texture reflectance\" \"b\"",
    );
    assert!(e.contains("a float texture of that name exists"), "{e}");
    let e = error_of("WorldBegin\nTexture \"t\" \"color3\" \"constant\"");
    assert!(
        e.starts_with("test.pbrt:2:13: texture type \"color3\" is unknown"),
        "{e}"
    );
    let e = error_of("WorldBegin\nTexture \"t\" \"spectrum\" \"checkerboard\" \"integer dimension\" 4");
    assert!(e.contains("must be 2 or 3, got 4"), "{e}");
    let e = error_of("WorldBegin\nTexture \"t\" \"spectrum\" \"constant\"\nTexture \"t\" \"spectrum\" \"constant\"");
    assert!(
        e.starts_with("test.pbrt:3:9: `Texture`: the texture \"t\" is already defined"),
        "{e}"
    );
}

#[test]
fn lights() {
    let d = world(
        r#"Translate 0 1 0
LightSource "point" "rgb I" [1 2 3] "float scale" 2 "point3 from" [1 0 0]
LightSource "spot" "point3 from" [0 0 0] "point3 to" [0 -1 0] "float coneangle" 40 "float conedeltaangle" 10 "blackbody I" 3000
LightSource "distant" "point3 from" [0 10 0] "point3 to" [0 0 0] "rgb L" [4 4 4]
Identity
LightSource "infinite" "rgb L" [0.1 0.2 0.3] "float scale" 2
LightSource "point" "float power" 100"#,
    );
    assert_eq!(
        d.lights[0].kind,
        LightKind::Point {
            position: Vec3::new(1.0, 1.0, 0.0),
            intensity: Rgb::new(2.0, 4.0, 6.0),
            falloff: true
        }
    );
    match &d.lights[1].kind {
        LightKind::Spot {
            position,
            to,
            intensity,
            inner_angle,
            outer_angle,
            ..
        } => {
            assert_eq!((*position, *to), (Vec3::Y, Vec3::ZERO));
            assert_eq!((*inner_angle, *outer_angle), (30.0, 40.0));
            assert_eq!(*intensity, blackbody_rgb(3000.0));
        }
        k => panic!("{k:?}"),
    }
    assert_eq!(
        d.lights[2].kind,
        LightKind::Directional {
            direction: Vec3::new(0.0, -10.0, 0.0),
            irradiance: Rgb::splat(4.0)
        }
    );
    assert_eq!(d.background, BackgroundDesc::Constant(Rgb::new(0.2, 0.4, 0.6)));
    // power = 4π·I for a point light.
    match d.lights[3].kind {
        LightKind::Point { intensity, .. } => assert!((intensity.x - 100.0 / (4.0 * PI_F32)).abs() < 1e-4),
        ref k => panic!("{k:?}"),
    }
    // A blackbody is the colour an RGB film records of it: nothing to warn of.
    assert!(d.warnings.iter().all(|w| !w.contains("blackbody")), "{:?}", d.warnings);
}

const PI_F32: f32 = std::f32::consts::PI;

#[test]
fn environment_maps_are_read_as_equal_area_octahedral() {
    let d = world("Rotate -90 1 0 0\nLightSource \"infinite\" \"string filename\" \"sky.exr\" \"float scale\" 3");
    let BackgroundDesc::Image {
        path,
        scale,
        transform,
        layout,
        illuminance,
    } = &d.background
    else {
        panic!("{:?}", d.background)
    };
    assert_eq!(
        (path.as_path(), *scale, *illuminance),
        (Path::new("sky.exr"), 3.0, None)
    );
    assert_eq!(*layout, EnvironmentLayout::EqualAreaOctahedral);
    let m = transform.iter().fold(Mat4::IDENTITY, |acc, op| match op {
        TransformOp::Matrix(m) => *m * acc,
        _ => acc,
    });
    // The centre of the map is the light's +z, which Rotate -90 about x
    // turns to world +y.
    assert!(close(m.transform_vector3(Vec3::Z), Vec3::Y));
    assert!(
        d.warnings.iter().all(|w| !w.contains("approximated")),
        "{:?}",
        d.warnings
    );
    let e = error_of("WorldBegin\nLightSource \"infinite\" \"string filename\" \"sky.exr\" \"rgb L\" [1 1 1]");
    assert!(e.contains("give either \"L\" or \"filename\""), "{e}");
}

/// A light's `ConcatTransform` may have a projective bottom row (the
/// environment of pbrt-v4-scenes' sssdragon does); pbrt-v4 uses the matrix
/// as it is: points divided by w, directions through 3×3 parts.
#[test]
fn projective_light_transforms_are_used_as_pbrt_uses_them() {
    // sssdragon's environment: the first matrix's bottom row is 0 0 8.87 1.
    let d = world(
        "AttributeBegin\n  ConcatTransform [ -0.224951 0 -0.97437 0 -0.97437 0 0.224951 0 0 1 0 8.87 0 0 0 1  ]\n  ConcatTransform [ 0 0 -1 0 1 0 0 0 0 1 0 0 0 0 0 1  ]\n  LightSource \"infinite\" \"float scale\" .3 \"string filename\" \"textures/envmap.exr\"\nAttributeEnd",
    );
    let BackgroundDesc::Image { transform, .. } = &d.background else {
        panic!("{:?}", d.background)
    };
    let [TransformOp::Matrix(map)] = transform[..] else {
        panic!("{transform:?}")
    };
    assert_eq!(map.row(3), Vec4::W);
    // pbrt-v4 looks the map up in the direction normalize(3×3 of CTM⁻¹ · d).
    let ctm = Mat4::from_cols_array(&[
        -0.224951, 0.0, -0.97437, 0.0, -0.97437, 0.0, 0.224951, 0.0, 0.0, 1.0, 0.0, 8.87, 0.0, 0.0, 0.0, 1.0,
    ]) * Mat4::from_cols_array(&[
        0.0, 0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ]);
    let pbrt_lookup = Mat3::from_mat4(ctm.inverse());
    let trazo_lookup = Mat3::from_mat4(map.inverse());
    for d in [Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(0.3, -0.5, 0.8).normalize()] {
        assert!(
            close((pbrt_lookup * d).normalize(), (trazo_lookup * d).normalize()),
            "{d}"
        );
    }
    assert!(d.warnings.iter().all(|w| !w.contains("projective")), "{:?}", d.warnings);

    // Point lights are placed with the division by w: the bottom row
    // 0 0 0.5 1 sends (0 0 2) to (0 0 2)/2.
    let projective = "ConcatTransform [1 0 0 0  0 1 0 0  0 0 1 0.5  0 0 0 1]";
    let d = world(&format!(
        "{projective}\nLightSource \"point\" \"point3 from\" [0 0 2]\nLightSource \"spot\" \"point3 from\" [0 0 2] \"point3 to\" [0 0 3]\nLightSource \"distant\" \"point3 from\" [0 0 0] \"point3 to\" [1 0 0]"
    ));
    assert!(matches!(d.lights[0].kind, LightKind::Point { position, .. } if close(position, Vec3::new(0.0, 0.0, 1.0))));
    // The spotlight: pbrt-v4 measures angles to its axis through the 3×3
    // part of (CTM · Translate(from))⁻¹, here diag(1, 1, 2). The written
    // axis +z stays +z, but the cone's angles widen (tan θ doubles), which
    // trazo's spotlight cannot do: it says it approximates.
    let LightKind::Spot { position, to, .. } = d.lights[1].kind else {
        panic!("{:?}", d.lights[1].kind)
    };
    assert!(close(position, Vec3::new(0.0, 0.0, 1.0)));
    assert!(close((to - position).normalize(), Vec3::Z));
    assert!(
        d.warnings[0].starts_with(
            "test.pbrt:4:1: a spotlight under a transform that stretches directions unevenly is approximated"
        ),
        "{:?}",
        d.warnings
    );
    // Distant lights turn by the 3×3 part, which the row does not touch.
    assert!(
        matches!(d.lights[2].kind, LightKind::Directional { direction, .. } if close(direction.normalize(), Vec3::X))
    );

    // A homogeneous multiple of a matrix is the same transform.
    let plain =
        world("Translate 1 2 3\nRotate 30 0 1 0\nLightSource \"spot\" \"point3 from\" [1 0 0] \"point3 to\" [0 -1 0]");
    let doubled = world(
        "ConcatTransform [2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 2]\nTranslate 1 2 3\nRotate 30 0 1 0\nLightSource \"spot\" \"point3 from\" [1 0 0] \"point3 to\" [0 -1 0]",
    );
    let (
        LightKind::Spot {
            position: p0, to: t0, ..
        },
        LightKind::Spot {
            position: p1, to: t1, ..
        },
    ) = (&plain.lights[0].kind, &doubled.lights[0].kind)
    else {
        panic!()
    };
    assert!(close(*p0, *p1));
    assert!(close((*t0 - *p0).normalize(), (*t1 - *p1).normalize()));
    assert!(doubled.warnings.is_empty(), "{:?}", doubled.warnings);

    // Shapes do not take projective transforms (pbrt-v4's projective
    // geometry is not reproduced): an error naming the shape.
    let e = error_of("WorldBegin\nConcatTransform [1 0 0 0  0 1 0 0  0 0 1 0.5  0 0 0 1]\nShape \"sphere\"");
    assert!(
        e.contains("test.pbrt:3:1: `shape[0].transform`: matrix: the bottom row must be 0 0 0 1"),
        "{e}"
    );

    // A light sent to infinity is an error at its directive.
    let e = error_of(
        "WorldBegin\nConcatTransform [1 0 0 0  0 1 0 0  0 0 1 -1  0 0 0 1]\nLightSource \"point\" \"point3 from\" [0 0 1]",
    );
    assert!(
        e.contains("test.pbrt:3:1: `LightSource`: the current transform is projective and puts the light at infinity"),
        "{e}"
    );
}

#[test]
fn area_lights_make_emissive_materials_per_combination() {
    let d = world(
        r#"NamedMaterial "m"
MakeNamedMaterial "m" "string type" "diffuse"
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [5 5 5] "float scale" 2
  Shape "sphere"
  Shape "sphere"
  AreaLightSource "diffuse" "rgb L" [1 0 0] "bool twosided" true
  Shape "sphere"
AttributeEnd
Shape "sphere""#,
    );
    let names: Vec<&str> = d.shapes.iter().map(|s| s.material.as_deref().unwrap()).collect();
    assert_eq!(names[0], names[1]);
    assert_ne!(names[0], names[2]);
    assert_eq!(names[3], "m");
    assert_eq!(material(&d, 0).emission, ColorSource::Rgb(Rgb::splat(10.0)));
    assert_eq!(material(&d, 2).emission, ColorSource::Rgb(Rgb::X));
    assert_eq!(material(&d, 3).emission, ColorSource::Rgb(Rgb::ZERO));
    assert!(material(&d, 2).emits_both_sides && !material(&d, 0).emits_both_sides);
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
}

#[test]
fn object_instances() {
    let d = world(
        r#"ObjectBegin "thing"
  Material "conductor"
  Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0]
  Translate 0 0 1
  Shape "sphere" "float radius" 0.5
ObjectEnd
Translate 10 0 0
ObjectInstance "thing"
Identity
Scale -1 1 1
ObjectInstance "thing"
ObjectBegin "unused"
ObjectEnd
Shape "disk""#,
    );
    assert_eq!(d.meshes.len(), 1);
    let mesh = &d.meshes[0].name;
    let placed: Vec<&ShapeDesc> = d
        .shapes
        .iter()
        .filter(|s| s.kind == ShapeKind::Mesh(mesh.clone()))
        .collect();
    assert_eq!(placed.len(), 2);
    let spheres: Vec<usize> = (0..d.shapes.len())
        .filter(|&i| matches!(d.shapes[i].kind, ShapeKind::Sphere { .. }))
        .collect();
    assert_eq!(spheres.len(), 2);
    // World = instance CTM × the shape's CTM inside the object.
    assert!(close(
        matrix(&d, spheres[0]).transform_point3(Vec3::ZERO),
        Vec3::new(10.0, 0.0, 1.0)
    ));
    assert!(close(
        matrix(&d, spheres[1]).transform_point3(Vec3::X),
        Vec3::new(-1.0, 0.0, 1.0)
    ));
    assert!(d.shapes[spheres[1]].flip_normals, "mirrored quadric");
    assert!(matches!(
        material(&d, spheres[0]).kind,
        MaterialKindDesc::Conductor { .. }
    ));
    assert!(
        d.warnings
            .iter()
            .any(|w| w.starts_with("test.pbrt:13:1: object \"unused\" is unsupported"))
    );

    let e = error_of("WorldBegin\nObjectInstance \"nothing\"");
    assert!(
        e.starts_with("test.pbrt:2:16: `ObjectInstance`: no object named \"nothing\""),
        "{e}"
    );
    let e = error_of("WorldBegin\nObjectBegin \"a\"\nObjectBegin \"b\"");
    assert!(e.contains("inside the definition of object \"a\""), "{e}");
    let e = error_of("WorldBegin\nObjectBegin \"a\"\nObjectEnd\nObjectBegin \"a\"");
    assert!(e.contains("already defined (at test.pbrt:2:1)"), "{e}");
    let e = error_of("WorldBegin\nObjectBegin \"a\"\nAttributeEnd");
    assert!(e.contains("closes the ObjectBegin at test.pbrt:2:1"), "{e}");
    let e = error_of("WorldBegin\nAttributeBegin\nObjectEnd");
    assert!(e.contains("the AttributeBegin at test.pbrt:2:1 is still open"), "{e}");
}

#[test]
fn attribute_directive_sets_defaults() {
    let d = world("Attribute \"shape\" \"float radius\" 3\nShape \"sphere\"\nShape \"sphere\" \"float radius\" 1");
    assert!(matches!(d.shapes[0].kind, ShapeKind::Sphere { radius, .. } if radius == 3.0));
    assert!(matches!(d.shapes[1].kind, ShapeKind::Sphere { radius, .. } if radius == 1.0));
    let e = error_of("WorldBegin\nAttribute \"camera\" \"float fov\" 3");
    assert!(
        e.starts_with("test.pbrt:2:11: unknown Attribute target \"camera\""),
        "{e}"
    );
}

#[test]
fn structural_errors_name_the_place() {
    let cases: &[(&str, &str)] = &[
        (
            "WorldBegin\nShpe \"sphere\"",
            "test.pbrt:2:1: `Shpe`: unknown directive (did you mean \"Shape\"?)",
        ),
        (
            "WorldBegin\nWorldBegin",
            "test.pbrt:2:1: `WorldBegin`: appears a second time (the first is at test.pbrt:1:1)",
        ),
        (
            "WorldBegin\nAttributeEnd",
            "test.pbrt:2:1: `AttributeEnd`: without a matching AttributeBegin",
        ),
        (
            "WorldBegin\nTransformEnd",
            "test.pbrt:2:1: `TransformEnd`: without a matching TransformBegin",
        ),
        (
            "Shape \"sphere\"\nWorldBegin",
            "test.pbrt:1:1: `Shape`: must come after WorldBegin",
        ),
        (
            "WorldBegin\nCamera \"perspective\"",
            "test.pbrt:2:1: `Camera`: is a rendering option and must come before WorldBegin",
        ),
        (
            "Camera \"perspective\"\n",
            "test.pbrt:2:1: `WorldBegin`: the file ends before WorldBegin",
        ),
        (
            "WorldBegin\n  AttributeBegin\nShape \"sphere\"",
            "test.pbrt:2:3: `AttributeBegin`: is never closed",
        ),
        (
            "WorldBegin\nObjectBegin \"x\"",
            "test.pbrt:2:1: `ObjectBegin`: is never closed",
        ),
        (
            "WorldBegin\nTranslate 1 2",
            "test.pbrt:2:1: Translate needs 3 numbers; the file ends after 2",
        ),
        (
            "WorldBegin\nTranslate 1 2 Shape",
            "test.pbrt:2:15: Translate: expected a number, found `Shape`",
        ),
        (
            "WorldBegin\nRotate 10 0 0 0",
            "test.pbrt:2:1: `Rotate`: the rotation axis must not be the zero vector",
        ),
        (
            "LookAt 0 0 0 0 0 0 0 1 0\nWorldBegin",
            "test.pbrt:1:1: `LookAt`: the eye and the point looked at are the same point",
        ),
        (
            "LookAt 0 0 1 0 0 0 0 0 1\nWorldBegin",
            "test.pbrt:1:1: `LookAt`: the up vector (0 0 1) is parallel",
        ),
        (
            "Transform 1 0 0 0\nWorldBegin",
            "test.pbrt:1:11: Transform needs [ and 16 numbers ], found `1`",
        ),
        (
            "ConcatTransform [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1 0]",
            "test.pbrt:1:50: ConcatTransform needs exactly 16 numbers, then ]",
        ),
        (
            "WorldBegin\n\"sphere\"",
            "test.pbrt:2:1: expected a directive, found the string \"sphere\"",
        ),
        (
            "WorldBegin\nShape sphere",
            "test.pbrt:2:7: Shape needs a quoted string, found `sphere`",
        ),
        (
            "WorldBegin\nShape \"sphear\"",
            "test.pbrt:2:7: unknown Shape type \"sphear\" (did you mean \"sphere\"?)",
        ),
        (
            "WorldBegin\nShape \"sphere\" \"float radius\" \"big\"",
            "test.pbrt:2:31: \"float radius\": expected a number, found \"big\"",
        ),
        (
            "WorldBegin\nShape \"sphere\" \"integer radius\" 2",
            "test.pbrt:2:16: `integer radius`: `radius` must be of type float, not integer",
        ),
        (
            "WorldBegin\nShape \"sphere\" \"float radius\" [1 2]",
            "test.pbrt:2:16: `float radius`: expected one value, found 2",
        ),
        (
            "Film \"rgb\" \"integer xresolution\" 0\nWorldBegin",
            "test.pbrt:1:12: `integer xresolution`: must be between 1 and 65536 pixels, got 0",
        ),
        (
            "Camera \"perspective\" \"float fov\" 180\nWorldBegin",
            "test.pbrt:1:22: `float fov`: must be between 0 and 180 degrees",
        ),
        (
            "Scale 0 1 1\nCamera \"perspective\"\nWorldBegin",
            "test.pbrt:2:1: `Camera`: the current transform is singular",
        ),
        (
            "WorldBegin\nScale 0 1 1\nShape \"sphere\"",
            "test.pbrt:3:1: `shape[0].transform`: matrix: the matrix is singular",
        ),
        (
            "WorldBegin\nImport",
            "test.pbrt:2:1: Import needs a quoted string; the file ends",
        ),
        (
            "Import \"x.pbrt\"\nWorldBegin",
            "test.pbrt:1:1: `Import`: must come after WorldBegin",
        ),
        (
            "WorldBegin\nInclude \"does-not-exist.pbrt\"",
            "test.pbrt:2:9: `Include`: cannot read does-not-exist.pbrt: file not found",
        ),
        (
            "WorldBegin\nLightSource \"spot\" \"float coneangle\" 200",
            "test.pbrt:2:20: `light[0].outer_angle`: must be at most 180 degrees",
        ),
        (
            "WorldBegin\nLightSource \"point\" \"rgb I\" [1 1]",
            "test.pbrt:2:21: `rgb I`: needs groups of 3 numbers, found 2 numbers",
        ),
        (
            "WorldBegin\nAreaLightSource \"diffuse\" \"float scale\" -1",
            "test.pbrt:2:1: `L`: the emitted radiance must not be negative",
        ),
        (
            "WorldBegin\nActiveTransform Sometimes",
            "test.pbrt:2:17: ActiveTransform needs All, StartTime or EndTime, found `Sometimes`",
        ),
    ];
    for (text, expected) in cases {
        let e = error_of(text);
        assert!(e.starts_with(expected), "{text:?}\n  gave: {e}\n  want: {expected}");
        assert!(!e.contains('\n'), "{e}");
    }
}

#[test]
fn unsupported_parameters_and_directives_warn_with_positions() {
    let d = parse_str(
        r#"Film "rgb" "string filename" "out.exr" "bool savefp16" true
Accelerator "kdtree"
Option "disablepixeljitter" true
WorldBegin
MakeNamedMedium "fog" "string type" "homogeneous"
MediumInterface "fog" ""
Shape "sphere" "string emissionfilename" "e.exr"
WorldEnd"#,
    )
    .unwrap();
    let w = d.warnings.join("\n");
    for expected in [
        "test.pbrt:1:40: parameter \"bool savefp16\" of Film \"rgb\" is unsupported: ignored",
        "test.pbrt:2:1: Accelerator \"kdtree\" is unsupported",
        "test.pbrt:3:1: Option \"disablepixeljitter\" is unsupported",
        "test.pbrt:7:16: parameter \"string emissionfilename\" of Shape \"sphere\" is unsupported: ignored",
        "test.pbrt:8:1: WorldEnd (pbrt-v3 syntax) is unsupported",
    ] {
        assert!(w.contains(expected), "missing {expected:?} in\n{w}");
    }
    // The Film's file is the render's output, where it was written.
    assert_eq!(d.output.as_deref(), Some(std::path::Path::new("out.exr")));
    assert_eq!(d.settings_locs.key("output").unwrap().to_string(), "test.pbrt:1:12");
    assert!(!w.contains("out.exr"), "{w}");
}

#[test]
fn repeated_warnings_are_counted_after_ten() {
    let d = world(&"Shape \"sphere\" \"string emissionfilename\" \"e.exr\"\n".repeat(25));
    assert_eq!(d.warnings.len(), 11, "{:?}", d.warnings);
    assert_eq!(
        d.warnings[10],
        "test.pbrt:2:16: parameter \"string emissionfilename\" of Shape \"sphere\" is unsupported: ignored (15 more times, not listed)"
    );
}

#[test]
fn imported_files_keep_their_blocks_to_themselves() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::write(
        root.join("main.pbrt"),
        "WorldBegin\nAttributeBegin\nImport \"i.pbrt\"\nAttributeEnd\n",
    )
    .unwrap();
    std::fs::write(root.join("i.pbrt"), "Shape \"sphere\"\nAttributeEnd\n").unwrap();
    let e = load(&root.join("main.pbrt"), &[]).unwrap_err().to_string();
    assert!(
        e.contains("i.pbrt:2:1: `AttributeEnd`: without a matching AttributeBegin"),
        "{e}"
    );
    std::fs::write(root.join("i.pbrt"), "AttributeBegin\nShape \"sphere\"\n").unwrap();
    let e = load(&root.join("main.pbrt"), &[]).unwrap_err().to_string();
    assert!(
        e.contains("i.pbrt:1:1: `AttributeBegin`: is not closed before the end of the imported file"),
        "{e}"
    );
}

#[test]
fn repeated_parameters_take_the_last_value() {
    let d = world("Shape \"sphere\" \"float radius\" 1 \"float radius\" 2");
    assert!(matches!(d.shapes[0].kind, ShapeKind::Sphere { radius, .. } if radius == 2.0));
    assert!(
        d.warnings[0].starts_with("test.pbrt:2:16: parameter \"float radius\""),
        "{:?}",
        d.warnings
    );
}

#[test]
fn defines_only_warn() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("s.pbrt");
    std::fs::write(&f, "WorldBegin\n").unwrap();
    let d = load(&f, &[("x".into(), "1".into())]).unwrap();
    assert_eq!(
        d.warnings,
        vec!["-D x: pbrt scenes have no parameters; the definition is not used"]
    );
}

#[test]
fn includes_resolve_relative_to_the_including_file_and_detect_loops() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::create_dir_all(root.join("parts/more")).unwrap();
    std::fs::write(
        root.join("main.pbrt"),
        "WorldBegin\nInclude \"parts/geometry.pbrt\"\nShape \"disk\"\n",
    )
    .unwrap();
    std::fs::write(
        root.join("parts/geometry.pbrt"),
        "Translate 0 2 0\nInclude \"more/deeper.pbrt\"\nShape \"plymesh\" \"string filename\" \"mesh.ply\"\n",
    )
    .unwrap();
    std::fs::write(root.join("parts/mesh.ply"), "").unwrap();
    std::fs::write(root.join("parts/more/deeper.pbrt"), "Shape \"sphere\"\n").unwrap();
    let d = load(&root.join("main.pbrt"), &[]).unwrap();
    assert_eq!(d.shapes.len(), 3);
    // Include is textual: the CTM set in the included file stays in force.
    for i in 0..3 {
        assert!(close(
            matrix(&d, i).transform_point3(Vec3::ZERO),
            Vec3::new(0.0, 2.0, 0.0)
        ));
    }
    assert_eq!(
        d.shapes[1].kind,
        ShapeKind::InlineMesh(MeshSource::File(PathBuf::from("parts/mesh.ply")))
    );
    // Positions inside included files are their own.
    assert!(
        d.shapes[0]
            .locs
            .item
            .as_ref()
            .unwrap()
            .to_string()
            .ends_with("deeper.pbrt:1:1")
    );

    // Import keeps its graphics state to itself.
    std::fs::write(
        root.join("imp.pbrt"),
        "WorldBegin\nImport \"parts/geometry.pbrt\"\nShape \"disk\"\n",
    )
    .unwrap();
    let d = load(&root.join("imp.pbrt"), &[]).unwrap();
    assert_eq!(matrix(&d, 2), Mat4::IDENTITY);

    // A loop: a → b → a.
    std::fs::write(root.join("a.pbrt"), "WorldBegin\nInclude \"parts/b.pbrt\"\n").unwrap();
    std::fs::write(root.join("parts/b.pbrt"), "\n  Include \"../a.pbrt\"\n").unwrap();
    let e = load(&root.join("a.pbrt"), &[]).unwrap_err().to_string();
    assert!(
        e.contains("b.pbrt:2:11: `Include`: include loop: a.pbrt → b.pbrt → a.pbrt"),
        "{e}"
    );

    // Errors inside an included file point into it.
    std::fs::write(root.join("c.pbrt"), "WorldBegin\nInclude \"parts/bad.pbrt\"\n").unwrap();
    std::fs::write(root.join("parts/bad.pbrt"), "Shape \"sphere\"\n  Bogus\n").unwrap();
    let e = load(&root.join("c.pbrt"), &[]).unwrap_err().to_string();
    assert!(e.contains("bad.pbrt:2:3: `Bogus`: unknown directive"), "{e}");
}

/// pbrt-v4's `Include` is token-level: the included file's tokens are
/// followed by those after the `Include`, so a statement begun in the
/// included file goes on after it (pbrt-v4-scenes' smoke-plume/plume.pbrt).
/// A `uniformgrid`'s emission as pbrt-v4's `GridMedium` gives it: `Le`
/// without `Lescale` over pbrt-v4's one-voxel grid of 1; a temperature
/// grid as peak-normalised blackbodies (approximated: interpolated by
/// colour), none at 100 K or below after the offset and scale; `Le` and
/// `temperature` together, or a grid of the wrong size, are errors.
#[test]
fn uniform_grids_emit_as_pbrt_v4s_grid_medium() {
    let medium = |extra: &str| {
        world(&format!(
            "MakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \"float density\" [1 1] {extra}\n\
             MediumInterface \"m\" \"\"\nMaterial \"interface\"\nShape \"sphere\""
        ))
    };
    let grid = |d: &SceneDesc| match &d.media[0].emission {
        Some(FieldDesc::Grid {
            source: GridSource::Data(g),
            ..
        }) => (g.res, g.data.clone()),
        other => panic!("{other:?}"),
    };
    let d = medium("\"rgb Le\" [2 1 0.5]");
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert_eq!(grid(&d), ([1, 1, 1], vec![2.0, 1.0, 0.5]));

    let d = medium(
        "\"float temperature\" [50 1600] \"float temperatureoffset\" 100 \"float temperaturescale\" 2 \"float Lescale\" [1 3]",
    );
    assert!(
        d.warnings
            .iter()
            .any(|w| w.contains("\"temperature\"") && w.contains("approximated")),
        "{:?}",
        d.warnings
    );
    let (res, data) = grid(&d);
    assert_eq!(res, [2, 1, 1]);
    assert_eq!(&data[..3], &[0.0; 3], "(50 − 100)·2 K emits nothing");
    let expected = super::spectrum::peak_normalized_blackbody_rgb(3000.0) * 3.0;
    assert_eq!(&data[3..], &expected.to_array(), "(1600 − 100)·2 = 3000 K, × 3");
    assert!(
        expected.x > expected.y && expected.y > expected.z,
        "3000 K is red: {expected}"
    );

    let e = crate::scene::pbrt::parse(
        "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \"float density\" [1 1] \"rgb Le\" [1 1 1] \"float temperature\" [2000 2000]\n",
        Path::new("test.pbrt"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("test.pbrt:2:1") && e.contains("not both"), "{e}");
    let e = crate::scene::pbrt::parse(
        "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \"float density\" [1 1] \"rgb Le\" [1 1 1] \"float Lescale\" [1 2 3]\n",
        Path::new("test.pbrt"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("Lescale") && e.contains("needs 2 values"), "{e}");
}

/// The peak-normalised blackbody (pbrt-v4's `BlackbodySpectrum`) has the
/// hue of the luminance-normalised one and the luminance ∫B̂ȳ/∫ȳ < 1,
/// which grows with the temperature across the visible range.
#[test]
fn peak_normalized_blackbodies_are_dimmer_where_the_peak_leaves_the_visible() {
    use super::spectrum::{blackbody_rgb, peak_normalized_blackbody_rgb};
    let lum = |t: f32| crate::color::luminance(peak_normalized_blackbody_rgb(t));
    for t in [1500.0, 3000.0, 6500.0] {
        let (a, b) = (peak_normalized_blackbody_rgb(t), blackbody_rgb(t));
        // blackbody_rgb has luminance 1: a is b times a's luminance.
        assert!((a - b * lum(t)).abs().max_element() < 1e-5, "{t} K: {a} vs {b}");
        assert!(lum(t) > 0.0 && lum(t) < 1.0, "{t} K: {}", lum(t));
    }
    assert!(lum(1500.0) < lum(3000.0) && lum(3000.0) < lum(6500.0));
}

#[test]
fn include_is_token_level_so_statements_continue_after_it() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::create_dir_all(root.join("geometry")).unwrap();
    let write = |name: &str, text: &str| std::fs::write(root.join(name), text).unwrap();

    // As smoke-plume: the medium's grid in the included file, its other
    // parameters after the Include, then more directives.
    write(
        "geometry/density.pbrt",
        "MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\"\n  \"integer nx\" 2 \"integer ny\" 1 \"integer nz\" 1\n  \"float density\" [0 1]\n",
    );
    write(
        "plume.pbrt",
        "WorldBegin\nAttributeBegin\nInclude \"geometry/density.pbrt\"\n\t\"spectrum sigma_a\" [300 20 830 20]\n\t\"spectrum sigma_s\" [300 160 830 160]\n  MediumInterface \"smoke\" \"\"\n  Shape \"sphere\" \"float radius\" 3\nAttributeEnd\n",
    );
    let d = load(&root.join("plume.pbrt"), &[]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.shapes.len(), 1);
    assert!(matches!(d.shapes[0].kind, ShapeKind::Sphere { radius, .. } if radius == 3.0));
    // The grid and the σ that follow the Include are one medium, filling the sphere.
    assert_eq!(d.media.len(), 1, "{:?}", d.warnings);
    let m = &d.media[0];
    assert!(matches!(&m.sigma_t, FieldDesc::Grid { source: GridSource::Data(g), .. } if g.res == [2, 1, 1]));
    assert_eq!(m.scale, Rgb::splat(180.0));
    assert_eq!(m.albedo, FieldDesc::Constant(Rgb::splat(160.0 / 180.0)));
    let mi = d.shapes[0].media.as_ref().unwrap();
    assert_eq!(
        (mi.inside.as_deref(), mi.outside.as_deref()),
        (Some("medium:smoke"), None)
    );

    // On the same line as the Include, and after it, in the main file.
    write("sphere.pbrt", "Shape \"sphere\"");
    write(
        "same-line.pbrt",
        "WorldBegin\nInclude \"sphere.pbrt\" \"float radius\" 2.5\nShape \"disk\"\n",
    );
    let d = load(&root.join("same-line.pbrt"), &[]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.shapes.len(), 2);
    assert!(matches!(d.shapes[0].kind, ShapeKind::Sphere { radius, .. } if radius == 2.5));
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);

    // A list of values that the included file leaves open is closed after
    // the Include; each shape keeps the position of its own directive.
    write(
        "geometry/open.pbrt",
        "Shape \"trianglemesh\" \"point3 P\" [0 0 0  1 0 0\n",
    );
    write(
        "open-list.pbrt",
        "WorldBegin\nInclude \"geometry/open.pbrt\" 0 1 0 ] \"integer indices\" [0 1 2]\nShape \"sphere\"\n",
    );
    let d = load(&root.join("open-list.pbrt"), &[]).unwrap_or_else(|e| panic!("{e}"));
    let ShapeKind::InlineMesh(MeshSource::Inline(mesh)) = &d.shapes[0].kind else {
        panic!("{:?}", d.shapes[0].kind)
    };
    assert_eq!(mesh.vertices(0), [Vec3::ZERO, Vec3::X, Vec3::Y]);
    let loc = |i: usize| d.shapes[i].locs.item.as_ref().unwrap().to_string();
    assert!(loc(0).ends_with("open.pbrt:1:1"), "{}", loc(0));
    assert!(loc(1).ends_with("open-list.pbrt:3:1"), "{}", loc(1));

    // Errors name the file each token came from, on both sides.
    write("bad-kind.pbrt", "Shape \"sphear\"");
    write(
        "bad-kind-main.pbrt",
        "WorldBegin\nInclude \"bad-kind.pbrt\" \"float radius\" 1\n",
    );
    let e = load(&root.join("bad-kind-main.pbrt"), &[]).unwrap_err().to_string();
    assert!(e.contains("bad-kind.pbrt:1:7: unknown Shape type \"sphear\""), "{e}");
    write(
        "bad-value.pbrt",
        "WorldBegin\nInclude \"sphere.pbrt\"\n  \"float radius\" \"big\"\n",
    );
    let e = load(&root.join("bad-value.pbrt"), &[]).unwrap_err().to_string();
    assert!(
        e.contains("bad-value.pbrt:3:18: \"float radius\": expected a number"),
        "{e}"
    );

    // A file included twice in a row is no loop; the same file inside
    // itself still is, reached through the continued statement or not.
    write(
        "twice.pbrt",
        "WorldBegin\nInclude \"sphere.pbrt\"\nInclude \"sphere.pbrt\" \"float radius\" 2\n",
    );
    let d = load(&root.join("twice.pbrt"), &[]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.shapes.len(), 2);
    write("self.pbrt", "Shape \"sphere\"\nInclude \"self.pbrt\"\n");
    write("self-main.pbrt", "WorldBegin\nInclude \"self.pbrt\"\n");
    let e = load(&root.join("self-main.pbrt"), &[]).unwrap_err().to_string();
    assert!(e.contains("include loop: self.pbrt → self.pbrt"), "{e}");
}

fn write_gzip(path: &Path, text: &str) {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(text.as_bytes()).unwrap();
    std::fs::write(path, e.finish().unwrap()).unwrap();
}

const TRIANGLE_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

/// pbrt-v4 reads gzip-compressed files wherever it reads scene text (the
/// main file, `Include`, `Import`) and PLY meshes; so does trazo, by name
/// (`.gz`), through the same limits as other files.
#[test]
fn gzip_compressed_scenes_includes_imports_and_meshes_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::create_dir_all(root.join("parts")).unwrap();
    write_gzip(
        &root.join("scene.pbrt.gz"),
        "WorldBegin\nInclude \"parts/sphere.pbrt.gz\" \"float radius\" 2\nImport \"parts/lights.pbrt.gz\"\nShape \"plymesh\" \"string filename\" \"parts/mesh.ply.gz\"\n",
    );
    write_gzip(&root.join("parts/sphere.pbrt.gz"), "Translate 0 1 0\nShape \"sphere\"");
    write_gzip(
        &root.join("parts/lights.pbrt.gz"),
        "LightSource \"point\" \"point3 from\" [0 5 0]\n",
    );
    write_gzip(&root.join("parts/mesh.ply.gz"), TRIANGLE_PLY);
    let d = crate::scene::load(&root.join("scene.pbrt.gz"), &[]).unwrap_or_else(|e| panic!("{e}"));
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert!(matches!(d.shapes[0].kind, ShapeKind::Sphere { radius, .. } if radius == 2.0));
    let sphere_at = d.shapes[0].locs.item.as_ref().unwrap().to_string();
    assert!(sphere_at.ends_with("sphere.pbrt.gz:2:1"), "{sphere_at}");
    assert_eq!(d.lights.len(), 1);
    let ShapeKind::InlineMesh(MeshSource::Inline(mesh)) = &d.shapes[1].kind else {
        panic!("{:?}", d.shapes[1].kind)
    };
    assert_eq!(mesh.vertices(0), [Vec3::ZERO, Vec3::X, Vec3::Y]);
    // The Include's Translate holds for the mesh too.
    assert!(close(matrix(&d, 1).transform_point3(Vec3::ZERO), Vec3::Y));

    // A damaged file is an error naming the file and the directive.
    std::fs::write(root.join("parts/bad.pbrt.gz"), "not gzip").unwrap();
    std::fs::write(root.join("bad.pbrt"), "WorldBegin\nInclude \"parts/bad.pbrt.gz\"\n").unwrap();
    let e = load(&root.join("bad.pbrt"), &[]).unwrap_err().to_string();
    assert!(
        e.contains("bad.pbrt:2:9: `Include`: ")
            && e.contains("bad.pbrt.gz: cannot read scene: the file is not valid gzip data"),
        "{e}"
    );
    std::fs::write(root.join("parts/bad.ply.gz"), "not gzip either").unwrap();
    std::fs::write(
        root.join("bad-mesh.pbrt"),
        "WorldBegin\nShape \"plymesh\" \"string filename\" \"parts/bad.ply.gz\"\n",
    )
    .unwrap();
    let e = load(&root.join("bad-mesh.pbrt"), &[]).unwrap_err().to_string();
    assert!(
        e.contains("bad-mesh.pbrt:2:17: `string filename`: cannot read mesh")
            && e.contains("bad.ply.gz: the file is not valid gzip data"),
        "{e}"
    );
    // Errors inside a compressed mesh give positions in its text.
    write_gzip(
        &root.join("parts/broken.ply.gz"),
        &TRIANGLE_PLY.replace("0 1 0\n", "0 x 0\n"),
    );
    std::fs::write(
        root.join("broken-mesh.pbrt"),
        "WorldBegin\nShape \"plymesh\" \"string filename\" \"parts/broken.ply.gz\"\n",
    )
    .unwrap();
    let e = load(&root.join("broken-mesh.pbrt"), &[]).unwrap_err().to_string();
    assert!(e.contains("broken.ply.gz:12:"), "{e}");
    // Text that is not UTF-8 once decompressed names its place.
    let mut raw = Vec::new();
    {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(&mut raw, flate2::Compression::default());
        e.write_all(b"WorldBegin\n# caf\xe9\n").unwrap();
        e.finish().unwrap();
    }
    std::fs::write(root.join("latin1.pbrt.gz"), raw).unwrap();
    let e = crate::scene::load(&root.join("latin1.pbrt.gz"), &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("latin1.pbrt.gz:2:6: the file is not valid UTF-8 text"),
        "{e}"
    );
}

/// A gzip bomb (a small file that inflates to far more than the limit)
/// stops at the limit of the file it stands for, with an error, whether it
/// is scene text or a mesh. (The limits are 1 GiB of text and 16 GiB of
/// PLY; the test uses 1 MiB, as the functions take the limit.)
#[test]
fn gzip_bombs_stop_at_the_read_limit() {
    let dir = tempfile::tempdir().unwrap();
    let bomb = {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        for _ in 0..64 {
            e.write_all(&[b' '; 1 << 16]).unwrap();
        }
        e.finish().unwrap()
    };
    assert!(bomb.len() < 64 << 10);
    let scene = dir.path().join("bomb.pbrt.gz");
    std::fs::write(&scene, &bomb).unwrap();
    let e = read_text_limited(&scene, None, 1 << 20).unwrap_err().to_string();
    assert!(
        e.contains("bomb.pbrt.gz: cannot read scene: the file decompresses to more than the limit of 1048576 bytes"),
        "{e}"
    );
    let mesh = dir.path().join("bomb.ply.gz");
    std::fs::write(&mesh, &bomb).unwrap();
    let mut p = Parser::new(Arc::from(Path::new("test.pbrt")));
    let at = SourceLoc {
        file: Arc::from(Path::new("test.pbrt")),
        line: 2,
        column: 16,
    };
    let e = p.gzip_ply(&mesh, &at, 1 << 20).unwrap_err().to_string();
    assert!(
        e.contains("test.pbrt:2:16: `string filename`: cannot read mesh")
            && e.contains("the file decompresses to more than the limit of 1048576 bytes"),
        "{e}"
    );
}

#[test]
fn media_fill_shapes_and_the_camera_and_select_volpath() {
    let d = parse_str(
        r#"MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [0.1 0.2 0.3] "rgb sigma_s" [0.9 0.8 0.7] "float scale" 2 "float g" 0.4
MediumInterface "" "fog"
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective"
WorldBegin
MakeNamedMedium "cloud" "string type" "spectralgrid" "string filename" "cloud.vdb"
AttributeBegin
  MediumInterface "fog" ""
  Material "interface"
  Shape "sphere"
AttributeEnd
Material "thindielectric" "float eta" 1.33
Shape "sphere" "float radius" 2
MediumInterface "cloud" "fog"
Shape "sphere" "float radius" 3"#,
    )
    .unwrap();
    assert_eq!(d.settings.integrator, IntegratorKind::VolPath);
    assert_eq!(d.camera_medium.as_deref(), Some("medium:fog"));
    assert_eq!(d.media.len(), 1);
    let fog = &d.media[0];
    assert_eq!(fog.sigma_t, FieldDesc::Constant(Rgb::ONE));
    assert_eq!(fog.scale, Rgb::splat(2.0));
    assert_eq!(fog.g, 0.4);
    let mi = d.shapes[0].media.as_ref().unwrap();
    assert_eq!(
        (mi.inside.as_deref(), mi.outside.as_deref()),
        (Some("medium:fog"), None)
    );
    assert_eq!(material(&d, 0).kind, MaterialKindDesc::NULL);
    // The glass sphere has the interface set before WorldBegin (pbrt-v4
    // keeps it): vacuum inside, fog outside.
    let mi = d.shapes[1].media.as_ref().unwrap();
    assert_eq!(
        (mi.inside.as_deref(), mi.outside.as_deref()),
        (None, Some("medium:fog"))
    );
    assert!(matches!(material(&d, 1).kind, MaterialKindDesc::Thin { ior, .. } if ior == 1.33));
    // An unknown kind of medium is vacuum, with a warning.
    let mi = d.shapes[2].media.as_ref().unwrap();
    assert_eq!(
        (mi.inside.as_deref(), mi.outside.as_deref()),
        (None, Some("medium:fog"))
    );
    assert!(
        d.warnings
            .iter()
            .any(|w| w.contains("test.pbrt:6:1: MakeNamedMedium \"cloud\" of type \"spectralgrid\" is unsupported")),
        "{:?}",
        d.warnings
    );
    let e = parse_str("WorldBegin\nMediumInterface \"smoke\" \"\"\nShape \"sphere\"")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("test.pbrt:2:1") && e.contains("no medium named \"smoke\""),
        "{e}"
    );
    // Without media, volpath is the path tracer.
    let d = parse_str("WorldBegin\nShape \"sphere\"").unwrap();
    assert_eq!(d.settings.integrator, IntegratorKind::Path);
    // The same medium on both sides is no transition.
    let d = parse_str("MakeNamedMedium \"fog\" \"string type\" \"homogeneous\"\nWorldBegin\nMediumInterface \"fog\"\nShape \"sphere\"").unwrap();
    assert!(d.shapes[0].media.is_none());
}

/// A float texture for a conductor's or dielectric's roughness becomes a
/// roughness map (remapped α = √r unless `remaproughness` is false); on a
/// material that cannot vary its roughness it gives its typical value with
/// a warning; float textures nothing reads are not kept.
#[test]
fn float_textures_give_roughness_maps() {
    let d = world(
        r#"Texture "rough" "float" "checkerboard" "float tex1" 0.01 "float tex2" 0.25 "float uscale" 8 "float vscale" 8
Texture "unused" "float" "imagemap" "string filename" "missing.png"
Material "conductor" "texture roughness" "rough"
Shape "sphere"
Material "dielectric" "texture uroughness" "rough" "float vroughness" 0.5 "bool remaproughness" false
Shape "sphere"
Material "coateddiffuse" "texture roughness" "rough"
Shape "sphere""#,
    );
    assert_eq!(d.textures.len(), 1, "{:?}", d.textures);
    let t = &d.textures[0];
    assert_eq!(
        t.kind,
        TextureKind::Checkerboard {
            even: Rgb::splat(0.01),
            odd: Rgb::splat(0.25),
            scale: Vec2::splat(8.0)
        }
    );
    let conductor = material(&d, 0);
    let map = conductor.roughness_map.as_ref().expect("a roughness map");
    assert_eq!(map.u, ColorSource::Texture(t.name.clone()));
    assert_eq!(map.v, map.u);
    assert!(map.remap_sqrt);
    // The constant α is the remapped typical roughness, the checks' mean.
    assert!(
        matches!(conductor.kind, MaterialKindDesc::Conductor { roughness: (a, _), .. } if (a - 0.13f32.sqrt()).abs() < 1e-6),
        "{:?}",
        conductor.kind
    );
    let dielectric = material(&d, 1).roughness_map.as_ref().expect("a roughness map");
    assert!(!dielectric.remap_sqrt);
    // Its u is the texture, its v the constant 0.5.
    assert_eq!(dielectric.u, ColorSource::Texture(t.name.clone()));
    assert_eq!(dielectric.v, ColorSource::Rgb(Rgb::splat(0.5)));
    // A coated material's is its coat's.
    assert!(material(&d, 2).roughness_map.is_some());
    assert!(
        !d.warnings
            .iter()
            .any(|w| w.contains("coateddiffuse") && w.contains("float texture")),
        "{:?}",
        d.warnings
    );
    crate::scene::build(&d).expect("builds");
}

#[test]
fn normal_maps_are_linear_images_on_the_material() {
    let d = world(
        r#"Material "coateddiffuse" "string normalmap" "textures/bumps.png"
Shape "sphere""#,
    );
    let m = &d.materials[0];
    let Some(NormalMapDesc {
        texture: ColorSource::Texture(name),
        scale: 1.0,
        bitangent_along_v: false,
    }) = &m.normal_map
    else {
        panic!("no normal map: {:?}", m.normal_map)
    };
    let t = d.textures.iter().find(|t| &t.name == name).expect("its texture");
    assert_eq!(
        t.kind,
        TextureKind::Image {
            source: ImageSource::DataFile(PathBuf::from("textures/bumps.png")),
            scale: Vec2::ONE,
            offset: Vec2::ZERO,
            encoding: Some(Encoding::Linear),
            tint: Rgb::ONE,
            wrap: [crate::texture::WrapMode::Repeat; 2],
            filter: crate::texture::ImageFilter::Bilinear,
        }
    );
    assert!(!d.warnings.iter().any(|w| w.contains("normalmap")), "{:?}", d.warnings);
}

#[test]
fn displacement_textures_are_bump_maps() {
    let d = world(
        r#"Texture "bumps" "float" "imagemap" "string filename" "textures/bumps.png"
Texture "noise" "float" "fbm"
Material "diffuse" "texture displacement" "bumps"
Shape "sphere"
Material "diffuse" "texture displacement" "noise"
Shape "sphere"
Material "diffuse" "texture displacement" "bumps" "string normalmap" "textures/n.png"
Shape "sphere""#,
    );
    let material = |i: usize| {
        let name = d.shapes[i].material.as_ref().expect("a material");
        d.materials.iter().find(|m| &m.name == name).expect("its material")
    };
    let b = material(0).bump_map.as_ref().expect("a bump map");
    assert_eq!(b.scale, 1.0);
    let ColorSource::Texture(name) = &b.height else {
        panic!("{:?}", b.height)
    };
    // A float image is read as pbrt-v4 reads one.
    let t = d.textures.iter().find(|t| &t.name == name).expect("its texture");
    assert!(
        matches!(&t.kind, TextureKind::Image { source: ImageSource::FloatFile(f), .. } if f.ends_with("textures/bumps.png")),
        "{:?}",
        t.kind
    );
    // Procedural float textures bump too.
    let b = material(1).bump_map.as_ref().expect("a bump map of noise");
    let ColorSource::Texture(name) = &b.height else {
        panic!("{:?}", b.height)
    };
    let t = d.textures.iter().find(|t| &t.name == name).expect("its texture");
    assert!(
        matches!(
            t.kind,
            TextureKind::Node(TextureNode::Noise {
                pattern: crate::texture::NoisePattern::Fbm { octaves: 8, omega: 0.5 },
                ..
            })
        ),
        "{:?}",
        t.kind
    );
    // As in pbrt-v4, a normal map wins.
    let both = material(2);
    assert!(both.normal_map.is_some() && both.bump_map.is_none());
    assert!(
        !d.warnings.iter().any(|w| w.contains("\"displacement\" is")),
        "{:?}",
        d.warnings
    );
}

/// Writes `text` to `root`/main.pbrt and loads it.
fn load_main(root: &Path, text: &str) -> Result<SceneDesc> {
    std::fs::write(root.join("main.pbrt"), text).unwrap();
    load(&root.join("main.pbrt"), &[])
}

#[test]
fn conductor_spectra_from_spd_files_and_samples_are_read_at_the_rgb_wavelengths() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::create_dir_all(root.join("spds")).unwrap();
    std::fs::write(root.join("spds/eta.spd"), "# eta\n400 1\n500 2\n600 3\n700 4\n").unwrap();
    std::fs::write(root.join("spds/bad.spd"), "400 1\n300 2\n").unwrap();
    let scene = |eta: &str| {
        load_main(
            root,
            &format!(
                "WorldBegin\nMaterial \"conductor\" \"spectrum eta\" {eta} \"spectrum k\" [400 5 700 5]\nShape \"sphere\"\n"
            ),
        )
    };
    let d = scene("\"spds/eta.spd\"").unwrap();
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let MaterialKindDesc::Conductor {
        fresnel: ConductorDesc::Complex { eta, k },
        ..
    } = &material(&d, 0).kind
    else {
        panic!("{:?}", material(&d, 0).kind)
    };
    // 650, 550 and 450 nm.
    assert!((*eta - Rgb::new(3.5, 2.5, 1.5)).abs().max_element() < 1e-6, "{eta:?}");
    assert_eq!(*k, Rgb::splat(5.0));
    let e = scene("\"spds/bad.spd\"").unwrap_err().to_string();
    assert!(
        e.contains("bad.spd: wavelengths must increase, but 300 follows 400"),
        "{e}"
    );
    let e = scene("\"spds/none.spd\"").unwrap_err().to_string();
    assert!(
        e.contains("\"spds/none.spd\" is neither a named spectrum nor a readable file"),
        "{e}"
    );
}

/// A reflectance given as a spectrum (inline or from an `.spd` file) is the
/// colour it gives D65 white, as an RGB film records it, channel by channel
/// relative to a flat spectrum's: flat spectra keep their value exactly, a
/// tinted one takes Mitsuba's conversion of it (checked against Mitsuba in
/// `color::spectrum`) up to that white, and out-of-gamut or brighter-than-1
/// reflectances are clipped with a warning.
#[test]
fn reflectance_spectra_are_the_colours_an_rgb_film_records() {
    use crate::color::spectrum::{SpectrumUse, sampled_to_rgb};
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::create_dir_all(root.join("spds")).unwrap();
    std::fs::write(root.join("spds/tint.spd"), "400 0.1\n500 0.5\n600 0.9\n700 0.3\n").unwrap();
    let scene = |kd: &str| {
        load_main(
            root,
            &format!("WorldBegin\nMaterial \"diffuse\" \"spectrum reflectance\" {kd}\nShape \"sphere\"\n"),
        )
    };
    let reflectance = |d: &SceneDesc| match &material(d, 0).kind {
        MaterialKindDesc::Diffuse {
            reflectance: ColorSource::Rgb(c),
        } => *c,
        k => panic!("{k:?}"),
    };
    let d = scene("[300 0.5 900 0.5]").unwrap();
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert!(
        (reflectance(&d) - Rgb::splat(0.5)).abs().max_element() < 1e-6,
        "{}",
        reflectance(&d)
    );

    let white = sampled_to_rgb(&[(360.0, 1.0), (830.0, 1.0)], SpectrumUse::Bounded).0;
    let tint = [(400.0, 0.1), (500.0, 0.5), (600.0, 0.9), (700.0, 0.3)];
    let expected = sampled_to_rgb(&tint, SpectrumUse::Bounded).0 / white;
    for kd in ["[400 0.1 500 0.5 600 0.9 700 0.3]", "\"spds/tint.spd\""] {
        let d = scene(kd).unwrap();
        assert!(d.warnings.is_empty(), "{kd}: {:?}", d.warnings);
        let c = reflectance(&d);
        assert!((c - expected).abs().max_element() < 1e-5, "{kd}: {c} vs {expected}");
        // Orange: mostly red, little blue; not the grey of its mean.
        assert!(c.x > 0.8 && c.z < 0.3, "{kd}: {c}");
    }

    let d = scene("[400 1.5 700 1.5]").unwrap();
    assert_eq!(reflectance(&d).max_element(), 1.0);
    assert!(
        d.warnings
            .iter()
            .any(|w| w.contains("main.pbrt:2:") && w.contains("clipped")),
        "{:?}",
        d.warnings
    );
    let e = scene("[400 0.5 700]").unwrap_err().to_string();
    assert!(
        e.contains("main.pbrt:2:") && e.contains("pairs, found 3 numbers"),
        "{e}"
    );
    let e = scene("[400 0.5]").unwrap_err().to_string();
    assert!(e.contains("main.pbrt:2:") && e.contains("at least two pairs"), "{e}");
    let e = scene("\"spds/none.spd\"").unwrap_err().to_string();
    assert!(
        e.contains("\"spds/none.spd\" is neither a named spectrum nor a readable file"),
        "{e}"
    );
    // Names of pbrt-v4's own families that trazo does not tabulate for
    // reflectances keep the default, with a warning.
    let d = scene("\"canon_eos_100d_r\"").unwrap();
    assert!(
        d.warnings
            .iter()
            .any(|w| w.contains("canon_eos_100d_r") && w.contains("unsupported")),
        "{:?}",
        d.warnings
    );
}

/// `plymesh` `displacement`: the mesh is cut until its edges, measured in
/// world space, are shorter than `edgelength`, then moved along its
/// normals by the float texture (pbrt-v4's `TriQuadMesh::Displace`): a
/// unit square lifted by 0.25 and scaled by 2 ends at z = 0.5, with more
/// triangles than unscaled. Bad values are errors at their place; a mesh
/// without (u, v) is an error when the scene is built.
#[test]
fn plymesh_displacement_cuts_and_lifts_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let square = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float u\nproperty float v\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 1\n4 0 1 2 3\n";
    std::fs::write(root.join("square.ply"), square).unwrap();
    std::fs::write(root.join("plain.ply"), TRIANGLE_PLY).unwrap();
    let scene = |transform: &str, shape: &str| {
        load_main(
            root,
            &format!(
                "WorldBegin\nTexture \"h\" \"float\" \"constant\" \"float value\" 0.25\n{transform}\nShape \"plymesh\" {shape}\n"
            ),
        )
    };
    let displaced = "\"string filename\" \"square.ply\" \"texture displacement\" \"h\" \"float edgelength\" 0.25";
    let d = scene("", displaced).unwrap();
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert!(matches!(
        &d.shapes[0].kind,
        ShapeKind::InlineMesh(MeshSource::Displaced { height, edge_length, .. }) if edge_length == &0.25 && !height.is_empty()
    ));
    let built = crate::scene::build::build(&d).unwrap();
    let b = built.geometry.bounds();
    assert!((b.min.z - 0.25).abs() < 1e-6 && (b.max.z - 0.25).abs() < 1e-6, "{b:?}");
    let near = built.geometry.stats().triangles;
    assert!(
        near >= 2 * 16,
        "{near}: every edge below 0.25 takes at least 32 triangles"
    );

    let far = crate::scene::build::build(&scene("Scale 2 2 2", displaced).unwrap()).unwrap();
    let b = far.geometry.bounds();
    assert!((b.min.z - 0.5).abs() < 1e-6 && (b.max.z - 0.5).abs() < 1e-6, "{b:?}");
    assert!(
        far.geometry.stats().triangles >= 3 * near,
        "{} vs {near}",
        far.geometry.stats().triangles
    );

    // Without a displacement, edgelength is read and nothing changes.
    let d = scene("", "\"string filename\" \"square.ply\" \"float edgelength\" 0.1").unwrap();
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert!(matches!(&d.shapes[0].kind, ShapeKind::InlineMesh(MeshSource::File(_))));

    for (shape, why) in [
        (
            "\"string filename\" \"square.ply\" \"texture displacement\" \"h\" \"float edgelength\" 0",
            "must be a positive length, got 0",
        ),
        (
            "\"string filename\" \"square.ply\" \"texture displacement\" \"nope\"",
            "no float texture named \"nope\"",
        ),
        (
            "\"string filename\" \"square.ply\" \"float displacement\" 1",
            "must be a float texture",
        ),
    ] {
        let e = scene("", shape).unwrap_err().to_string();
        assert!(e.contains("main.pbrt:4:") && e.contains(why), "{shape}: {e}");
    }
    let d = scene("", "\"string filename\" \"plain.ply\" \"texture displacement\" \"h\"").unwrap();
    let e = crate::scene::build::build(&d).unwrap_err().to_string();
    assert!(
        e.contains("main.pbrt:4:") && e.contains("needs texture coordinates"),
        "{e}"
    );
    let d = scene(
        "",
        "\"string filename\" \"square.ply\" \"texture displacement\" \"h\" \"float edgelength\" 1e-5",
    )
    .unwrap();
    let e = crate::scene::build::build(&d).unwrap_err().to_string();
    assert!(
        e.contains("main.pbrt:4:") && e.contains("more than 33554432 triangles"),
        "{e}"
    );
}

/// A dielectric's `uroughness` and `vroughness` stay apart (GGX α along u
/// and v, as pbrt-v4's), with no warning; so do a texture's.
#[test]
fn dielectrics_keep_anisotropic_roughness() {
    let d = world(
        "Material \"dielectric\" \"float uroughness\" 0.4 \"float vroughness\" 0.1 \"bool remaproughness\" false\nShape \"sphere\"",
    );
    assert!(
        matches!(material(&d, 0).kind, MaterialKindDesc::Dielectric { roughness, .. } if roughness == (0.4, 0.1)),
        "{:?}",
        material(&d, 0).kind
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let d = world(
        "Texture \"ru\" \"float\" \"constant\" \"float value\" 0.3\nTexture \"rv\" \"float\" \"constant\" \"float value\" 0.05\nMaterial \"dielectric\" \"texture uroughness\" \"ru\" \"texture vroughness\" \"rv\"\nShape \"sphere\"",
    );
    let map = material(&d, 0).roughness_map.clone().expect("a roughness map");
    assert_ne!(map.u, map.v, "{map:?}");
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
}

#[test]
fn a_scaled_texture_stays_a_texture() {
    let d = world(
        r#"Texture "grid" "spectrum" "imagemap" "string filename" "lines.png" "float uscale" 2
Texture "half" "spectrum" "scale" "float scale" 0.5 "texture tex" "grid"
Texture "checks" "float" "checkerboard" "float tex1" 1 "float tex2" 0
Texture "tinted" "spectrum" "scale" "texture scale" "checks" "rgb tex" [1 0.5 0.25]
Material "diffuse" "texture reflectance" "tinted"
Shape "sphere"
Material "diffuse" "texture reflectance" "half"
Shape "sphere""#,
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let TextureKind::Image { tint, scale, .. } = &d.textures[1].kind else {
        panic!("{:?}", d.textures[1].kind)
    };
    assert_eq!((*tint, *scale), (Rgb::splat(0.5), Vec2::new(2.0, 1.0)));
    // A colour times a float texture: a product node.
    assert_eq!(
        d.textures[3].kind,
        TextureKind::Node(TextureNode::Scale {
            tex: ColorSource::Rgb(Rgb::new(1.0, 0.5, 0.25)),
            scale: ColorSource::Texture("\u{0}float texture checks".into()),
        })
    );
    assert_eq!(
        d.textures[2].kind,
        TextureKind::Checkerboard {
            even: Rgb::ONE,
            odd: Rgb::ZERO,
            scale: Vec2::ONE
        }
    );
}

/// pbrt-v4's `cropwindow` (fractions, pixels rounded up) and `pixelbounds`
/// cut a window from the full resolution, which the camera still frames.
#[test]
fn film_crop_windows() {
    let d = parse_str(
        "Film \"rgb\" \"integer xresolution\" 100 \"integer yresolution\" 50 \"float cropwindow\" [0.25 0.755 0 0.5]\nWorldBegin",
    )
    .unwrap();
    let s = &d.settings;
    assert_eq!((s.width, s.height), (51, 25));
    assert_eq!(
        s.crop,
        Some(crate::settings::Crop {
            full_width: 100,
            full_height: 50,
            x: 25,
            y: 0
        })
    );
    let d = parse_str(
        "Film \"rgb\" \"integer xresolution\" 100 \"integer yresolution\" 50 \"integer pixelbounds\" [10 30 5 45]\nWorldBegin",
    )
    .unwrap();
    assert_eq!(
        (d.settings.width, d.settings.height, d.settings.crop.unwrap().x),
        (20, 40, 10)
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let e = parse_str("Film \"rgb\" \"float cropwindow\" [0.5 0.5 0 1]\nWorldBegin")
        .unwrap_err()
        .to_string();
    assert!(e.contains("test.pbrt:1:") && e.contains("empty"), "{e}");
}

/// `nanovdb` media: σt is (σa + σs)·scale times the density grid of the
/// file, placed by the grid's map and the CTM, and 0 outside the grid's
/// world box; a temperature grid gives blackbody emission. The values are
/// those NVIDIA Warp's NanoVDB sampler reads (tests/data/nanovdb).
#[test]
fn nanovdb_media_read_their_grids_where_pbrt_v4_places_them() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/nanovdb");
    let d = parse_str(&format!(
        r#"WorldBegin
AttributeBegin
  Translate 1 -2 0.5
  MakeNamedMedium "smoke" "string type" "nanovdb" "string filename" "{dir}/smoke.nvdb"
    "rgb sigma_a" [0.5 0.5 0.5] "rgb sigma_s" [1 2 3] "float scale" 2 "float Lescale" 3
    "float temperatureoffset" 200
AttributeEnd
MediumInterface "smoke" ""
Material "interface"
Shape "sphere" "float radius" 10"#
    ))
    .unwrap();
    assert_eq!(d.media.len(), 1);
    let m = &d.media[0];
    assert_eq!(m.scale, Rgb::new(1.5, 2.5, 3.5) * 2.0);
    assert!(m.emission.is_some());
    assert!(
        d.warnings
            .iter()
            .any(|w| w.contains("\"temperature\"") && w.contains("approximated")),
        "{:?}",
        d.warnings
    );
    let scene = crate::scene::build::build(&d).unwrap();
    let medium = &scene.media[0];
    let shift = Vec3::new(1.0, -2.0, 0.5);
    let text = std::fs::read_to_string(format!("{dir}/smoke-density.txt")).unwrap();
    for line in text.lines().filter(|l| !l.starts_with('#')).take(100) {
        let v: Vec<f32> = line.split_whitespace().map(|x| x.parse().unwrap()).collect();
        if v[0] == -1.25 || v[1] == 0.5 || v[2] == 2.0 {
            continue; // on the box's near faces, in or out by rounding
        }
        let p = Vec3::new(v[0], v[1], v[2]) + shift;
        let sigma_t = medium.sigma_t.at(p) * medium.scale;
        let expected = m.scale * v[3];
        assert!(
            (sigma_t - expected).abs().max_element() < 1e-4 * (1.0 + expected.max_element()),
            "{p}: {sigma_t} against {expected}"
        );
    }
    // The medium ends at the grid's world box: index [0, 23+1] × … at
    // 0.125 per voxel from (−1.25, 0.5, 2), then the translation.
    let bounds = medium.bounds.unwrap();
    assert!(close(bounds.min, Vec3::new(-1.25, 0.5, 2.0) + shift), "{bounds:?}");
    assert!(
        close(bounds.max, Vec3::new(-1.25 + 3.0, 0.5 + 2.0, 2.0 + 2.0) + shift),
        "{bounds:?}"
    );
    assert_eq!(medium.sigma_t.at(bounds.min - 0.01), Rgb::ZERO);
    // Le: the blackbody of T − 200 K, times 3, interpolated as colours.
    let le = medium
        .emission
        .as_ref()
        .unwrap()
        .at(Vec3::new(-1.25, 0.5, 2.0) + shift + 0.125 * Vec3::new(3.0, 4.0, 5.0));
    assert!(le.max_element() > 0.0);

    // Errors name the file and the key.
    let e = error_of(&format!(
        "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"nanovdb\" \"string filename\" \"{dir}/smoke.nvdb\" \"string gridname\" \"densty\""
    ));
    assert!(
        e.contains("test.pbrt:2:") && e.contains("no grid named \"densty\"") && e.contains("density"),
        "{e}"
    );
    let e =
        error_of("WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"nanovdb\" \"string filename\" \"missing.nvdb\"");
    assert!(
        e.contains("test.pbrt:2:") && e.contains("cannot read") && e.contains("missing.nvdb"),
        "{e}"
    );
    let e = error_of(&format!(
        "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"nanovdb\" \"string filename\" \"{dir}/smoke-density.txt\""
    ));
    assert!(e.contains("not a NanoVDB file"), "{e}");
}

/// A scattering (albedo 1) NanoVDB medium vanishes in a white furnace, and
/// an absorbing one darkens it.
#[test]
fn nanovdb_medium_vanishes_in_a_furnace() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/nanovdb");
    let scene = |sigma: &str| {
        format!(
            "LookAt 0.25 1.5 9  0.25 1.5 3  0 1 0\nCamera \"perspective\" \"float fov\" 30\n\
             Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
             Sampler \"independent\" \"integer pixelsamples\" 64\nIntegrator \"volpath\" \"integer maxdepth\" 256\nWorldBegin\n\
             LightSource \"infinite\" \"rgb L\" [1 1 1]\n\
             MakeNamedMedium \"s\" \"string type\" \"nanovdb\" \"string filename\" \"{dir}/smoke.nvdb\" {sigma} \"float Lescale\" 0\n\
             AttributeBegin\nMediumInterface \"s\" \"\"\nMaterial \"interface\"\nTranslate 0.25 1.5 3\nShape \"sphere\" \"float radius\" 2.5\nAttributeEnd\n"
        )
    };
    let mean = |text: &str| {
        let d = parse_str(text).unwrap();
        assert!(d.media[0].emission.is_none(), "Lescale 0 turns the emission off");
        let image = crate::render::render_image(&crate::scene::build(&d).unwrap()).unwrap();
        let n = image.pixels.len() as f64;
        let m = image.pixels.iter().map(|p| p.y as f64).sum::<f64>() / n;
        let var = image.pixels.iter().map(|p| (p.y as f64 - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, (var / n).sqrt())
    };
    let (m, e) = mean(&scene("\"rgb sigma_a\" [0 0 0] \"rgb sigma_s\" [4 4 4]"));
    assert!((m - 1.0).abs() < 4.5 * e + 2e-4, "furnace {m} ± {e}");
    let (dark, _) = mean(&scene("\"rgb sigma_a\" [4 4 4] \"rgb sigma_s\" [0 0 0]"));
    assert!(dark < 0.9, "an absorbing grid darkens the furnace: {dark}");
}

/// `rgbgrid` media: σt and the albedo per voxel from σa and σs (1 where not
/// given), an empty voxel taking the grid's mean albedo, Le times Lescale
/// as the emission grid; a grid of the wrong size is an error naming the
/// parameter.
#[test]
fn rgb_grid_media_are_read() {
    let d = parse_str(
        r#"MakeNamedMedium "smoke" "string type" "rgbgrid" "integer nx" 2 "integer ny" 1 "integer nz" 1
  "rgb sigma_a" [0 0 0 1 2 3] "rgb sigma_s" [0 0 0 1 1 1] "rgb Le" [0 0 0 0.5 0.5 0.25]
  "float Lescale" 2 "float scale" 3 "float g" 0.5 "point3 p0" [-1 -1 -1] "point3 p1" [1 1 1]
WorldBegin
MediumInterface "smoke" ""
Shape "sphere"
"#,
    )
    .unwrap();
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let m = &d.media[0];
    let data = |f: &FieldDesc| match f {
        FieldDesc::Grid {
            source: GridSource::Data(g),
            ..
        } => (g.channels, g.data.clone()),
        other => panic!("{other:?}"),
    };
    assert_eq!(data(&m.sigma_t), (3, vec![0.0, 0.0, 0.0, 2.0, 3.0, 4.0]));
    let (_, albedo) = data(&m.albedo);
    let expected = [0.5, 1.0 / 3.0, 0.25, 0.5, 1.0 / 3.0, 0.25];
    assert!(
        albedo.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-6),
        "{albedo:?}"
    );
    assert_eq!(
        data(m.emission.as_ref().unwrap()),
        (3, vec![0.0, 0.0, 0.0, 1.0, 1.0, 0.5])
    );
    assert_eq!((m.scale, m.g), (Rgb::splat(3.0), 0.5));
    let e = parse_str(
        "MakeNamedMedium \"m\" \"string type\" \"rgbgrid\" \"integer nx\" 2\n  \"rgb sigma_s\" [1 1 1]\nWorldBegin",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("test.pbrt:2:") && e.contains("sigma_s") && e.contains("2 RGB values"),
        "{e}"
    );
}

/// Every texture class of pbrt-v4 becomes a texture of trazo's, float and
/// spectrum alike, without a warning (ptex aside).
#[test]
fn every_texture_class_is_read() {
    let d = world(
        r#"Texture "f" "float" "fbm" "integer octaves" 5 "float roughness" 0.6
Texture "w" "float" "wrinkled"
Texture "wind" "float" "windy"
Texture "marb" "spectrum" "marble" "float scale" 2 "float variation" 0.4
Texture "bl" "spectrum" "bilerp" "rgb v00" [1 0 0] "rgb v11" [0 0 1]
Texture "fbl" "float" "bilerp" "float v10" 0.5
Texture "dots" "spectrum" "dots" "texture inside" "marb" "rgb outside" [0.1 0.1 0.1] "float uscale" 8
Texture "fdots" "float" "dots" "texture inside" "f"
Texture "dm" "spectrum" "directionmix" "texture tex1" "bl" "rgb tex2" [0 1 0] "vector3 dir" [0 0 1]
Texture "fmix" "float" "mix" "texture tex1" "w" "float tex2" 0.25 "texture amount" "wind"
Texture "sph" "spectrum" "checkerboard" "string mapping" "spherical" "texture tex1" "dots"
Texture "pl" "spectrum" "bilerp" "string mapping" "planar" "vector3 v1" [0 0 1] "vector3 v2" [1 0 0] "float udelta" 0.5
Texture "cyl" "spectrum" "checkerboard" "string mapping" "cylindrical"
AttributeBegin
  Translate 1 2 3
  Texture "solid" "spectrum" "checkerboard" "integer dimension" 3 "texture tex1" "dm"
AttributeEnd
Texture "fscaled" "float" "scale" "texture tex" "fmix" "texture scale" "fdots"
Texture "all" "spectrum" "scale" "texture tex" "solid" "texture scale" "fscaled"
Material "diffuse" "texture reflectance" "all" "texture displacement" "f"
Shape "sphere"
Material "conductor" "texture roughness" "fbl"
Shape "sphere""#,
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let kind = |name: &str| {
        let n = if d.textures.iter().any(|t| t.name == name) {
            name.to_string()
        } else {
            format!("\u{0}float texture {name}")
        };
        &d.textures
            .iter()
            .find(|t| t.name == n)
            .unwrap_or_else(|| panic!("{name}"))
            .kind
    };
    use crate::texture::{Mapping2D, NoisePattern};
    assert!(matches!(
        kind("f"),
        TextureKind::Node(TextureNode::Noise {
            pattern: NoisePattern::Fbm { octaves: 5, omega },
            ..
        }) if (*omega - 0.6).abs() < 1e-6
    ));
    assert!(matches!(
        kind("marb"),
        TextureKind::Node(TextureNode::Noise {
            pattern: NoisePattern::Marble { .. },
            ..
        })
    ));
    let TextureKind::Node(TextureNode::Bilerp { corners, .. }) = kind("bl") else {
        panic!()
    };
    // v00, v10, v01, v11 (pbrt's defaults 0, 0, 1, 1).
    assert_eq!(
        *corners,
        [Rgb::new(1.0, 0.0, 0.0), Rgb::ZERO, Rgb::ONE, Rgb::new(0.0, 0.0, 1.0)]
    );
    assert!(
        matches!(kind("dots"), TextureKind::Node(TextureNode::Dots { mapping: Mapping2D::Uv { scale, .. }, .. }) if scale.x == 8.0)
    );
    assert!(matches!(kind("dm"), TextureKind::Node(TextureNode::DirectionMix { dir, .. }) if *dir == Vec3::Z));
    assert!(matches!(
        kind("sph"),
        TextureKind::Node(TextureNode::Checkerboard {
            mapping: Mapping2D::Spherical { .. },
            ..
        })
    ));
    assert!(matches!(
        kind("cyl"),
        TextureKind::Node(TextureNode::Checkerboard {
            mapping: Mapping2D::Cylindrical { .. },
            ..
        })
    ));
    let TextureKind::Node(TextureNode::Bilerp {
        mapping: Mapping2D::Planar { s_axis, offset, .. },
        ..
    }) = kind("pl")
    else {
        panic!("{:?}", kind("pl"))
    };
    assert_eq!((*s_axis, *offset), (Vec3::Z, Vec2::new(0.5, 0.0)));
    // Solid checks of texture space: the inverse of the CTM.
    let TextureKind::Node(TextureNode::SolidCheckerboard { to_texture, .. }) = kind("solid") else {
        panic!("{:?}", kind("solid"))
    };
    assert!(
        to_texture
            .transform_point3(Vec3::new(1.0, 2.0, 3.0))
            .abs()
            .max_element()
            < 1e-6
    );
    assert!(matches!(kind("all"), TextureKind::Node(TextureNode::Scale { .. })));
    // The scene builds, and every texture is evaluated on the way.
    crate::scene::build(&d).unwrap_or_else(|e| panic!("{e}"));
}

/// pbrt-v4's classes are of one kind only, and inputs name textures made
/// before them.
#[test]
fn texture_inputs_are_checked() {
    assert!(error_of("WorldBegin\nTexture \"m\" \"float\" \"marble\"").contains("spectrum texture in pbrt-v4"));
    assert!(error_of("WorldBegin\nTexture \"m\" \"spectrum\" \"fbm\"").contains("float texture in pbrt-v4"));
    let e = error_of("WorldBegin\nTexture \"m\" \"spectrum\" \"mix\" \"texture tex1\" \"later\"");
    assert!(e.contains("no texture named \"later\""), "{e}");
    let e = error_of("WorldBegin\nTexture \"m\" \"float\" \"mix\" \"texture amount\" \"nope\"");
    assert!(e.contains("no float texture named \"nope\""), "{e}");
    let e = error_of("WorldBegin\nTexture \"m\" \"float\" \"fbm\" \"integer octaves\" 1000");
    assert!(e.contains("between 0 and 64"), "{e}");
    let e = error_of("WorldBegin\nScale 0 1 1\nTexture \"m\" \"float\" \"fbm\"");
    assert!(e.contains("singular"), "{e}");
}

/// pbrt-v4's `subsurface`: a dielectric over a homogeneous medium, in each
/// of its ways of giving the coefficients; only `volpath` gets the medium.
#[test]
fn subsurface_materials_are_dielectrics_over_a_medium() {
    let d = world(
        r#"Material "subsurface" "float eta" 1.4 "rgb sigma_a" [0.1 0.2 0.3] "rgb sigma_s" [1 2 3] "float scale" 2 "float g" 0.5
Shape "sphere"
Material "subsurface" "rgb reflectance" [0.5 0.5 0.5] "rgb mfp" [0.25 0.25 0.25]
Shape "sphere"
Material "subsurface"
Shape "sphere""#,
    );
    assert_eq!(d.settings.integrator, crate::settings::IntegratorKind::VolPath);
    assert_eq!(d.media.len(), 3);
    let medium_of = |i: usize| {
        let name = d.shapes[i].media.as_ref().unwrap().inside.as_ref().unwrap();
        d.media.iter().find(|m| &m.name == name).unwrap()
    };
    let constant = |f: &FieldDesc| match f {
        FieldDesc::Constant(c) => *c,
        other => panic!("{other:?}"),
    };
    let m = medium_of(0);
    assert!((constant(&m.sigma_t) - Rgb::new(2.2, 4.4, 6.6)).abs().max_element() < 1e-5);
    assert!(
        (constant(&m.albedo) - Rgb::new(1.0 / 1.1, 2.0 / 2.2, 3.0 / 3.3))
            .abs()
            .max_element()
            < 1e-5
    );
    assert_eq!(m.g, 0.5);
    let material = d
        .materials
        .iter()
        .find(|x| Some(&x.name) == d.shapes[0].material.as_ref())
        .unwrap();
    assert!(matches!(material.kind, MaterialKindDesc::Dielectric { ior, .. } if ior == 1.4));
    // From a reflectance: σt = 1/mfp, and an albedo below 1 that reflects it.
    let m = medium_of(1);
    assert!((constant(&m.sigma_t) - Rgb::splat(4.0)).abs().max_element() < 1e-4);
    let albedo = constant(&m.albedo).x;
    assert!(albedo > 0.9 && albedo < 1.0, "{albedo}");
    // pbrt-v4's defaults.
    let m = medium_of(2);
    assert!(
        (constant(&m.sigma_t) - Rgb::new(2.5511, 3.2124, 3.784))
            .abs()
            .max_element()
            < 1e-4
    );
    // pbrt's path tracer does not scatter below the surface.
    let d = parse_str("Integrator \"path\"\nWorldBegin\nMaterial \"subsurface\"\nShape \"sphere\"").unwrap();
    assert!(d.media.is_empty() && d.shapes[0].media.is_none());
    assert_eq!(d.settings.integrator, crate::settings::IntegratorKind::Path);
}

#[test]
fn the_single_scattering_albedo_inverts_the_reflectance_monotonically() {
    use super::materials::single_scattering_albedo;
    assert!(single_scattering_albedo(0.0).abs() < 1e-5);
    assert!((single_scattering_albedo(1.0) - 1.0).abs() < 1e-4);
    let mut last = 0.0;
    for k in 1..=20 {
        let a = single_scattering_albedo(k as f32 / 20.0);
        assert!(a > last, "{k}: {a}");
        last = a;
    }
}

/// Measured media by name: a homogeneous medium's `preset` and a
/// subsurface material's `name` take Jensen et al.'s and Narasimhan et
/// al.'s coefficients (mm⁻¹), times `scale`.
#[test]
fn measured_media_by_name() {
    let d = world(
        r#"MakeNamedMedium "milk" "string type" "homogeneous" "string preset" "Wholemilk" "float scale" 10
MakeNamedMedium "odd" "string type" "homogeneous" "string preset" "Mik"
MediumInterface "milk" ""
Material "interface"
Shape "sphere"
MediumInterface "" ""
Material "subsurface" "string name" "Ketchup"
Shape "sphere""#,
    );
    let medium = |name: &str| d.media.iter().find(|m| m.name == name).unwrap();
    let milk = medium(d.shapes[0].media.as_ref().unwrap().inside.as_ref().unwrap());
    let FieldDesc::Constant(sigma_t) = &milk.sigma_t else {
        panic!()
    };
    assert!(
        (*sigma_t * milk.scale - 10.0 * Rgb::new(2.5511, 3.2124, 3.784))
            .abs()
            .max_element()
            < 1e-3
    );
    assert!(
        d.warnings.iter().any(|w| w.contains("medium preset \"Mik\"")),
        "{:?}",
        d.warnings
    );
    let inside = d.shapes[1].media.as_ref().unwrap().inside.clone().unwrap();
    let FieldDesc::Constant(sigma_t) = &medium(&inside).sigma_t else {
        panic!()
    };
    assert!(
        (*sigma_t - Rgb::new(0.241, 1.04, 1.48)).abs().max_element() < 1e-4,
        "{sigma_t}"
    );
    let e = error_of("WorldBegin\nMaterial \"subsurface\" \"string name\" \"Skin9\"");
    assert!(e.contains("no measured medium named \"Skin9\""), "{e}");
}

#[test]
fn measured_materials_read_their_file_and_render_as_the_surface_it_measured() {
    use crate::material::measured::fixture::{ggx_file, thetas};
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("bsdfs")).unwrap();
    std::fs::write(dir.path().join("bsdfs/ggx.bsdf"), ggx_file(0.3, 0.8, 33, &thetas())).unwrap();
    let scene = |file: &str| {
        format!(
            "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 30\n\
             Film \"rgb\" \"integer xresolution\" 24 \"integer yresolution\" 24\n\
             Sampler \"independent\" \"integer pixelsamples\" 256\nWorldBegin\n\
             LightSource \"infinite\" \"rgb L\" [1 1 1]\n\
             Material \"measured\" \"string filename\" \"{file}\"\nShape \"sphere\"\n"
        )
    };
    let main = dir.path().join("main.pbrt");
    std::fs::write(&main, scene("bsdfs/ggx.bsdf")).unwrap();
    let d = load(&main, &[]).unwrap();
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    assert_eq!(
        material(&d, 0).kind,
        MaterialKindDesc::Measured {
            file: "bsdfs/ggx.bsdf".into()
        }
    );
    // Under a uniform sky each pixel of the sphere shows the surface's
    // albedo toward the camera: the tables render as the GGX conductor
    // they were made from (same Fresnel colour, as converted).
    let mean = |d: &SceneDesc| {
        let image = crate::render::render_image(&crate::scene::build::build(d).unwrap()).unwrap();
        image.pixels.iter().map(|p| p.y as f64).sum::<f64>() / image.pixels.len() as f64
    };
    let measured = mean(&d);
    let w = crate::color::spectrum::sample_weights(&[360.0, 830.0], crate::color::spectrum::SpectrumUse::Unbounded);
    let mut conductor = d.clone();
    let m = conductor
        .materials
        .iter_mut()
        .find(|m| m.name == material(&d, 0).name)
        .unwrap();
    m.kind = MaterialKindDesc::Conductor {
        fresnel: ConductorDesc::Mirror((w[0] + w[1]) * 0.8),
        tint: Rgb::ONE,
        roughness: (0.3, 0.3),
        distribution: crate::material::microfacet::MicrofacetDistribution::Ggx,
    };
    let model = mean(&conductor);
    // The sphere covers about half the image and its pixels average
    // about 0.67: 0.004 is 1.3 % of its share (measured: 0.1 %).
    assert!((measured - model).abs() < 0.004, "{measured} against {model}");

    // A missing file is an error that names it and the line that named it.
    std::fs::write(&main, scene("bsdfs/missing.bsdf")).unwrap();
    let e = crate::scene::build::build(&load(&main, &[]).unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("main.pbrt:7") && e.contains("missing.bsdf"), "{e}");
    // So is a file that is not a measured BSDF.
    std::fs::write(dir.path().join("bsdfs/missing.bsdf"), "Shape \"sphere\"").unwrap();
    let e = crate::scene::build::build(&load(&main, &[]).unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a tensor file"), "{e}");
}

#[test]
fn curves_and_hair() {
    // A degree-3 Bézier of 7 points is 2 segments, a quadratic b-spline
    // of 3 points 1; each is split into 2^splitdepth pieces (default 3).
    let d = world(
        r#"Shape "curve" "point3 P" [0 0 0 1 1 0 2 -1 0 3 0 0 4 1 0 5 -1 0 6 0 0] "float width0" 0.2 "float width1" 0.1 "integer splitdepth" 1
Shape "curve" "point3 P" [0 0 0 1 0 0 2 0 0] "integer degree" 2 "string basis" "bspline" "string type" "cylinder""#,
    );
    assert_eq!(d.shapes.len(), 4 + 8);
    assert!(d.shapes.iter().all(|s| matches!(s.kind, ShapeKind::Curve(_))));
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    for (bad, message) in [
        (
            r#"Shape "curve" "point3 P" [0 0 0 1 1 1 2 2 2]"#,
            "a degree-3 Bézier curve takes 4 + n·3",
        ),
        (
            r#"Shape "curve" "point3 P" [0 0 0 1 1 1 2 2 2 3 3 3] "string type" "tube""#,
            "unknown curve type \"tube\"",
        ),
        (
            r#"Shape "curve" "point3 P" [0 0 0 1 1 1 2 2 2 3 3 3] "string type" "ribbon""#,
            "needs normals",
        ),
        (
            r#"Shape "curve" "point3 P" [0 0 0 1 1 1 2 2 2 3 3 3] "float width" -1"#,
            "widths must be finite",
        ),
        (r#"Shape "curve""#, "control points"),
        (r#"Material "hair" "float beta_m" 2"#, "must be in [0, 1]"),
    ] {
        let e = error_of(&format!("WorldBegin\n{bad}"));
        assert!(e.contains(message), "{bad}: {e}");
    }
    let e = error_of("WorldBegin\nAreaLightSource \"diffuse\"\nShape \"curve\" \"point3 P\" [0 0 0 1 1 1 2 2 2 3 3 3]");
    assert!(
        e.contains("test.pbrt:3:1") && e.contains("a curve cannot emit light"),
        "{e}"
    );

    // Hair's absorption: σa, a colour, pigments or pbrt-v4's brown.
    let hair = |params: &str| match material(&world(&format!("Material \"hair\" {params}\nShape \"sphere\"")), 0).kind {
        MaterialKindDesc::Hair(h) => h.sigma_a,
        ref k => panic!("{k:?}"),
    };
    use crate::material::hair::HairBsdf;
    assert_eq!(hair(r#""rgb sigma_a" [0.1 0.2 0.3]"#), Rgb::new(0.1, 0.2, 0.3));
    assert_eq!(
        hair(r#""float eumelanin" 0.5"#),
        HairBsdf::sigma_a_from_concentration(0.5, 0.0)
    );
    assert_eq!(hair(""), HairBsdf::sigma_a_from_concentration(1.3, 0.0));
    assert_eq!(
        hair(r#""rgb reflectance" [0.5 0.4 0.3] "float beta_n" 0.5"#),
        HairBsdf::sigma_a_from_reflectance(Rgb::new(0.5, 0.4, 0.3), 0.5)
    );
}

/// Rendered: a flat curve covers the pixels a black one darkens, at the
/// albedo of its material (so rays leaving it do not meet it again), and
/// a fibre without absorption vanishes in a white furnace.
#[test]
fn curves_render_at_their_albedo_and_clear_hair_vanishes_in_a_furnace() {
    let render = |material: &str, kind: &str| {
        let text = format!(
            "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 30\n\
             Film \"rgb\" \"integer xresolution\" 32 \"integer yresolution\" 32\n\
             Sampler \"independent\" \"integer pixelsamples\" 128\nIntegrator \"path\" \"integer maxdepth\" 64\nWorldBegin\n\
             LightSource \"infinite\" \"rgb L\" [1 1 1]\n{material}\n\
             Shape \"curve\" \"point3 P\" [-1.2 -0.5 0  -0.4 0.8 0.3  0.4 -0.8 -0.3  1.2 0.5 0] \"float width\" 0.25 \"string type\" \"{kind}\"\n"
        );
        let d = parse_str(&text).unwrap();
        let image = crate::render::render_image(&crate::scene::build::build(&d).unwrap()).unwrap();
        image.pixels.iter().map(|p| p.y as f64).sum::<f64>() / image.pixels.len() as f64
    };
    let black = render("Material \"diffuse\" \"rgb reflectance\" [0 0 0]", "flat");
    let coverage = 1.0 - black;
    assert!(coverage > 0.05, "the curve covers {coverage} of the image");
    let grey = render("Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]", "flat");
    let expected = 1.0 - 0.5 * coverage;
    assert!(
        (grey - expected).abs() < 0.02 * coverage,
        "{grey} against {expected} (coverage {coverage})"
    );
    for kind in ["flat", "cylinder"] {
        let clear = render("Material \"hair\" \"rgb sigma_a\" [0 0 0] \"float beta_m\" 0.3", kind);
        assert!(
            (clear - 1.0).abs() < 0.02 * coverage,
            "{kind}: {clear} (coverage {coverage})"
        );
        let brown = render("Material \"hair\"", kind);
        assert!(brown < 1.0 - 0.3 * coverage, "{kind}: brown hair {brown}");
    }
}

/// pbrt-v4's area light `power`: radiance × power / (π · sides · area),
/// with each shape's area as pbrt-v4 reports it.
#[test]
fn area_light_power_sets_each_shapes_radiance() {
    use std::f32::consts::PI;
    let emission = |light: &str, shape: &str| {
        let d = world(&format!(
            "AttributeBegin\nAreaLightSource \"diffuse\" {light}\n{shape}\nAttributeEnd"
        ));
        match &material(&d, 0).emission {
            ColorSource::Rgb(c) => (c.x, d.warnings.clone()),
            e => panic!("{e:?}"),
        }
    };
    let quad = "Shape \"trianglemesh\" \"point3 P\" [0 0 0 2 0 0 0 1 0 2 1 0] \"integer indices\" [0 1 2 2 1 3]";
    let cases = [
        // A disk of radius 2: area 4π.
        ("Shape \"disk\" \"float radius\" 2", "", 4.0 * PI),
        // A sphere of radius 0.5 scaled by 2: pbrt-v4 takes its object-space area, π.
        ("Scale 2 2 2 Shape \"sphere\" \"float radius\" 0.5", "", PI),
        // Two triangles of area 1, two-sided: each emits the power.
        (quad, "\"bool twosided\" true", 2.0),
        // The same quad twice as wide in world space.
        (&format!("Scale 2 1 1 {quad}"), "", 2.0),
    ];
    for (shape, extra, area_sides) in cases {
        let (plain, _) = emission(&format!("\"rgb L\" [1 1 1] {extra}"), shape);
        let (powered, warnings) = emission(&format!("\"rgb L\" [1 1 1] \"float power\" 10 {extra}"), shape);
        let expected = plain * 10.0 / (PI * area_sides);
        assert!(
            (powered - expected).abs() < 1e-4 * expected,
            "{shape}: {powered} against {expected}"
        );
        assert!(warnings.is_empty(), "{shape}: {warnings:?}");
    }
    // Unequal triangles (areas 0.5 and 8): each its own radiance, as pbrt-v4
    // makes each a light of that power, held per triangle in a mesh
    // attribute that the emission reads.
    let d = world(
        "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 0.5 1] \"float power\" 10\n\
         Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 2 0 0 6 0 0 2 4 0] \"integer indices\" [0 1 2 3 4 5]\nAttributeEnd",
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let ColorSource::Texture(name) = &material(&d, 0).emission else {
        panic!("{:?}", material(&d, 0).emission)
    };
    let texture = d.textures.iter().find(|t| &t.name == name).unwrap();
    let TextureKind::MeshAttribute { name: attribute } = &texture.kind else {
        panic!("{:?}", texture.kind)
    };
    let ShapeKind::InlineMesh(MeshSource::Inline(mesh)) = &d.shapes[0].kind else {
        panic!("{:?}", d.shapes[0].kind)
    };
    let a = mesh.attributes.iter().find(|a| &a.name == attribute).unwrap();
    assert!(a.per_face && a.channels == 3);
    for (face, area) in [0.5f32, 8.0].into_iter().enumerate() {
        let l = 10.0 / (PI * area);
        let want = [l, 0.5 * l, l];
        let got = &a.values[3 * face..3 * face + 3];
        assert!(
            got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-5 * w),
            "{got:?} vs {want:?}"
        );
    }
    // Zero or negative: none, as in pbrt-v4.
    let (plain, _) = emission("\"rgb L\" [1 1 1]", "Shape \"disk\"");
    assert_eq!(
        emission("\"rgb L\" [1 1 1] \"float power\" 0", "Shape \"disk\"").0,
        plain
    );
}

/// `power` of an area light with an image divides by the image's mean
/// luminance too (pbrt-v4's k_e), each shape by its own area; a PLY
/// mesh's triangles are read for theirs.
#[test]
fn area_light_power_reads_the_image_and_the_ply_mesh() {
    use std::f32::consts::PI;
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    // A 2 × 1 PFM image of greys 1 and 3: mean luminance 2.
    let mut pfm = b"PF\n2 1\n-1.0\n".to_vec();
    for v in [1.0f32, 1.0, 1.0, 3.0, 3.0, 3.0] {
        pfm.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(root.join("glow.pfm"), pfm).unwrap();
    std::fs::write(root.join("tri.ply"), TRIANGLE_PLY).unwrap();
    std::fs::write(
        root.join("scene.pbrt"),
        "WorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\" \"string filename\" \"glow.pfm\" \"float power\" 10\n\
         Shape \"disk\"\nShape \"disk\" \"float radius\" 2\nAttributeEnd\n\
         AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"float power\" 10\n\
         Shape \"plymesh\" \"string filename\" \"tri.ply\"\nAttributeEnd\n",
    )
    .unwrap();
    let d = crate::scene::load(&root.join("scene.pbrt"), &[]).unwrap_or_else(|e| panic!("{e}"));
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    for (shape, area) in [(0, PI), (1, 4.0 * PI)] {
        let ColorSource::Texture(name) = &material(&d, shape).emission else {
            panic!("{:?}", material(&d, shape).emission)
        };
        let t = d.textures.iter().find(|t| &t.name == name).unwrap();
        let TextureKind::Image { source, tint, .. } = &t.kind else {
            panic!("{:?}", t.kind)
        };
        let expected = 10.0 / (2.0 * PI * area);
        assert!(
            (tint.x - expected).abs() < 1e-5 * expected,
            "shape {shape}: {tint} against {expected}"
        );
        // Read once, while parsing, and kept.
        assert!(matches!(source, ImageSource::Data(_)), "{source:?}");
    }
    let ColorSource::Rgb(c) = material(&d, 2).emission else {
        panic!("{:?}", material(&d, 2).emission)
    };
    assert!(matches!(d.shapes[2].kind, ShapeKind::InlineMesh(MeshSource::Inline(_))));
    let (plain, expected) = (1.0, 10.0 / (PI * 0.5));
    assert!(
        (c.x - plain * expected).abs() < 1e-4 * expected,
        "{c} against {expected}"
    );
    // A missing image is an error at its file key, as at the build.
    std::fs::remove_file(root.join("glow.pfm")).unwrap();
    let e = crate::scene::load(&root.join("scene.pbrt"), &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("scene.pbrt:3:") && e.contains("glow.pfm: cannot open image"),
        "{e}"
    );
}

/// pbrt-v4's `cloud` medium: its parameters, a density that is 1 at the
/// bottom of its box, thins to nothing at the top and is 0 outside it;
/// with albedo 1 inside a white furnace it vanishes under the volumetric
/// path tracer and BDPT alike, and absorbing it darkens what is behind.
#[test]
fn cloud_medium_thins_with_height_and_vanishes_in_a_furnace() {
    let scene = |sigma: &str, integrator: &str| {
        format!(
            "LookAt 0 0.5 4  0 0.5 0  0 1 0\nCamera \"perspective\" \"float fov\" 30\n\
             Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
             Sampler \"independent\" \"integer pixelsamples\" 64\nIntegrator \"{integrator}\" \"integer maxdepth\" 256\nWorldBegin\n\
             LightSource \"infinite\" \"rgb L\" [1 1 1]\n\
             MakeNamedMedium \"c\" \"string type\" \"cloud\" {sigma} \"point3 p0\" [1 1 1] \"point3 p1\" [-1 0 -1] \"float frequency\" 3\n\
             AttributeBegin\nMediumInterface \"c\" \"\"\nMaterial \"interface\"\nTranslate 0 0.5 0\nShape \"sphere\" \"float radius\" 1.6\nAttributeEnd\n"
        )
    };
    let d = parse_str(&scene("\"rgb sigma_a\" [0 0 0] \"rgb sigma_s\" [6 6 6]", "volpath")).unwrap();
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let FieldDesc::Cloud {
        value,
        frequency,
        p0,
        p1,
        ..
    } = &d.media[0].sigma_t
    else {
        panic!("{:?}", d.media[0].sigma_t)
    };
    assert_eq!((*value, *frequency), (Rgb::splat(6.0), 3.0));
    assert_eq!((*p0, *p1), (Vec3::new(-1.0, 0.0, -1.0), Vec3::ONE));
    let built = crate::scene::build::build(&d).unwrap();
    let medium = &built.media[0];
    let mut rng = crate::sampling::rng::Pcg32::new(5, 0);
    let mut upper = 0.0;
    for _ in 0..2000 {
        let (x, y, z) = (2.0 * rng.next_f32() - 1.0, rng.next_f32(), 2.0 * rng.next_f32() - 1.0);
        let sigma_t = medium.point(Vec3::new(x, y, z)).sigma_s.x;
        assert!((0.0..=6.0).contains(&sigma_t), "{sigma_t}");
        if y < 0.25 {
            assert!(sigma_t >= 6.0 * (1.0 - 2.0 * y) - 1e-4, "at height {y}: {sigma_t}");
        }
        if y > 0.999 {
            assert!(sigma_t < 0.03, "at height {y}: {sigma_t}");
        }
        if y > 0.5 {
            upper += sigma_t as f64 / 6.0;
        }
        // Outside the box: nothing.
        assert_eq!(medium.point(Vec3::new(x, y + 1.001, z)).sigma_s, Rgb::ZERO);
    }
    let upper = upper / 1000.0;
    assert!(
        upper > 0.02 && upper < 0.8,
        "mean density of the upper half about {upper}"
    );
    let mean = |text: &str| {
        let image = crate::render::render_image(&crate::scene::build(&parse_str(text).unwrap()).unwrap()).unwrap();
        let n = image.pixels.len() as f64;
        let m = image.pixels.iter().map(|p| p.y as f64).sum::<f64>() / n;
        let var = image.pixels.iter().map(|p| (p.y as f64 - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, (var / n).sqrt())
    };
    for integrator in ["volpath", "bdpt"] {
        let (m, e) = mean(&scene("\"rgb sigma_a\" [0 0 0] \"rgb sigma_s\" [6 6 6]", integrator));
        assert!((m - 1.0).abs() < 4.5 * e + 2e-4, "{integrator}: furnace {m} ± {e}");
    }
    let (dark, _) = mean(&scene("\"rgb sigma_a\" [6 6 6] \"rgb sigma_s\" [0 0 0]", "volpath"));
    assert!(dark < 0.8, "an absorbing cloud lets {dark} through");
}

/// `ActiveTransform` chooses which of the two transforms the transform
/// directives change, `AttributeBegin` saves the choice with the
/// transforms, and shapes and object instances made where the two differ
/// move between the `TransformTimes`; a light made there stays, with a
/// warning.
#[test]
fn active_transform_gives_shapes_and_instances_their_motion() {
    let d = parse_str(
        "TransformTimes 0 2\nWorldBegin\n\
         AttributeBegin\nActiveTransform EndTime\nTranslate 1 0 0\n\
         AttributeBegin\nActiveTransform All\nShape \"sphere\"\nAttributeEnd\n\
         Shape \"sphere\"\nAttributeEnd\n\
         Shape \"sphere\"\n\
         ObjectBegin \"o\"\nShape \"sphere\"\nObjectEnd\n\
         ActiveTransform StartTime\nTranslate 0 1 0\nActiveTransform All\n\
         ObjectInstance \"o\"\nLightSource \"point\"\n",
    )
    .unwrap();
    let moved = Mat4::from_translation(Vec3::X);
    for s in &d.shapes[..2] {
        let m = s.motion.as_ref().expect("moves");
        assert_eq!(m.times, (0.0, 2.0));
        assert_eq!(m.end, vec![TransformOp::Matrix(moved)]);
        assert_eq!(s.transform, vec![TransformOp::Matrix(Mat4::IDENTITY)]);
    }
    assert!(d.shapes[2].motion.is_none());
    let instanced = d.shapes.last().unwrap();
    let m = instanced.motion.as_ref().expect("the instance moves");
    assert_eq!(m.end.last(), Some(&TransformOp::Matrix(Mat4::IDENTITY)));
    assert_eq!(
        instanced.transform.last(),
        Some(&TransformOp::Matrix(Mat4::from_translation(Vec3::Y)))
    );
    assert!(
        d.warnings.iter().any(|w| w.contains("motion of a light")),
        "{:?}",
        d.warnings
    );
}

/// `ColorSpace` as pbrt-v4's: RGB values after it are in that space until
/// `AttributeEnd` restores the enclosing one; emitted colours keep their
/// XYZ (ACES white is warmer than D65), reflectances keep white white;
/// lights without a colour emit the space's white; colours sRGB cannot
/// hold are clipped with a warning; the film writes in the space of its
/// directive; an unknown space is an error at its name.
#[test]
fn colour_spaces_convert_rgb_values_as_pbrt_v4_reads_them() {
    use crate::color::space::ColorSpace;
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let d = load_main(
        root,
        "ColorSpace \"rec2020\"\nFilm \"rgb\"\nColorSpace \"srgb\"\nWorldBegin\n\
         ColorSpace \"aces2065-1\"\n\
         AttributeBegin\nColorSpace \"rec2020\"\nMaterial \"diffuse\" \"rgb reflectance\" [0.5 0.2 0.1]\nShape \"sphere\"\nAttributeEnd\n\
         Material \"diffuse\" \"rgb reflectance\" [0.7 0.7 0.7]\nShape \"sphere\"\n\
         LightSource \"point\" \"rgb I\" [1 1 1]\nLightSource \"point\"\n\
         Material \"diffuse\" \"rgb reflectance\" [0 1 0]\nShape \"sphere\"\n",
    )
    .unwrap();
    assert_eq!(d.settings.color_space, ColorSpace::Rec2020);
    let reflectance = |i: usize| match &material(&d, i).kind {
        MaterialKindDesc::Diffuse {
            reflectance: ColorSource::Rgb(c),
        } => *c,
        k => panic!("{k:?}"),
    };
    let rec2020 = ColorSpace::Rec2020.to_srgb(false) * Vec3::new(0.5, 0.2, 0.1);
    assert!((reflectance(0) - rec2020).abs().max_element() < 1e-6);
    // Rec. 2020's red is redder than sRGB's: more red, less green and blue.
    assert!(rec2020.x > 0.5 && rec2020.y < 0.2 && rec2020.z < 0.1, "{rec2020}");
    // ACES after AttributeEnd: a grey stays grey.
    assert!(
        (reflectance(1) - Vec3::splat(0.7)).abs().max_element() < 1e-5,
        "{}",
        reflectance(1)
    );
    let aces_white = ColorSpace::Aces2065_1.to_srgb(true) * Vec3::ONE;
    for light in &d.lights {
        let LightKind::Point { intensity, .. } = light.kind else {
            panic!("{:?}", light.kind)
        };
        assert!((intensity - aces_white).abs().max_element() < 1e-6, "{intensity}");
    }
    assert!(aces_white.x > 1.0 && aces_white.z < 0.95, "{aces_white}");
    // ACES green has no sRGB: clipped to 0 and 1, named in a warning.
    let green = reflectance(2);
    assert!(
        green.min_element() >= 0.0 && green.max_element() <= 1.0 && green.y == 1.0,
        "{green}"
    );
    let w = d.warnings.join("\n");
    assert!(
        w.contains("main.pbrt:15:20: aces2065-1 colour \"rgb reflectance\" is approximated"),
        "{w}"
    );
    assert_eq!(d.warnings.len(), 1, "{w}");

    let err = load_main(root, "ColorSpace \"p3\"\nWorldBegin\n")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("main.pbrt:1:12") && err.contains("unknown colour space \"p3\""),
        "{err}"
    );
}

/// Thin sheets and coats of a glass that disperses take their index at the
/// path's wavelength, as glass does; a coated conductor's base keeps its
/// indices relative to the coat's index at that wavelength.
#[test]
fn thin_sheets_and_coats_disperse() {
    use crate::material::Bsdf;
    use crate::material::conductor::ConductorFresnel;
    use crate::material::layered::LayerBase;
    let d = world(
        r#"Material "thindielectric" "spectrum eta" "glass-F11"
Shape "sphere"
Material "coatedconductor" "spectrum interface.eta" "glass-F11" "rgb conductor.eta" [0.2 0.3 0.4] "rgb conductor.k" [3 3 3]
Shape "sphere""#,
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let scene = crate::scene::build(&d).unwrap();
    let f11 = crate::material::dispersion::IorSpectrum::named_glass("glass-F11").unwrap();
    let tc = crate::texture::TexCoord::new(glam::Vec2::ZERO, glam::Vec3::ZERO);
    let material_of = |s: usize| {
        scene
            .materials
            .iter()
            .position(|m| {
                m.dispersion().is_some() && {
                    matches!(
                        (s, &m.kind),
                        (0, crate::material::MaterialKind::Thin { .. })
                            | (1, crate::material::MaterialKind::Layered { .. })
                    )
                }
            })
            .unwrap() as u32
    };
    for nm in [450.0, 650.0] {
        let Bsdf::Thin(sheet) = scene.material_bsdf_at(material_of(0), &tc, nm) else {
            panic!()
        };
        assert_eq!(sheet.eta, f11.at(nm));
        let Bsdf::Layered(coated) = scene.material_bsdf_at(material_of(1), &tc, nm) else {
            panic!()
        };
        assert_eq!(coated.coat.eta, f11.at(nm));
        let LayerBase::Conductor(base) = coated.base else {
            panic!()
        };
        let ConductorFresnel::Complex { eta, k } = base.fresnel else {
            panic!()
        };
        let want = glam::Vec3::new(0.2, 0.3, 0.4) / f11.at(nm);
        assert!(
            (eta - want).abs().max_element() < 1e-5 && (k.x - 3.0 / f11.at(nm)).abs() < 1e-5,
            "{eta} {k}"
        );
    }
}
