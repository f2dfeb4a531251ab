//! The volumetric path tracer against answers known in advance: white
//! furnaces of media (albedo 1 inside a uniform environment renders 1),
//! Beer–Lambert transmittance through a slab, single scattering in a thin
//! slab against its closed form. Tolerances come from the spread of the
//! pixels, which are independent estimates of the same value.

use trazo::Vec3;
use trazo::color::Rgb;
use trazo::media::VoxelGrid;
use trazo::render::render_image;
use trazo::scene::desc::*;
use trazo::settings::IntegratorKind;

/// Per channel: the mean of the pixels and the standard error of that mean.
fn mean_and_error(pixels: &[Rgb]) -> (Rgb, Rgb) {
    let n = pixels.len() as f32;
    let mean = pixels.iter().copied().sum::<Rgb>() / n;
    let var = pixels.iter().map(|p| (*p - mean) * (*p - mean)).sum::<Rgb>() / (n - 1.0);
    (mean, (var / n).powf(0.5))
}

fn assert_mean(pixels: &[Rgb], expect: Rgb, what: &str) {
    let (mean, err) = mean_and_error(pixels);
    for c in 0..3 {
        assert!(
            (mean[c] - expect[c]).abs() <= 4.5 * err[c] + 2e-4,
            "{what}: channel {c}: mean {} ± {}, expected {}",
            mean[c],
            err[c],
            expect[c]
        );
    }
}

/// A camera looking at the origin from +z, a null-bounded shape filled
/// with `medium`, and a uniform white environment.
fn medium_scene(shape: ShapeKind, medium: MediumDesc) -> SceneDesc {
    let mut d = SceneDesc::default();
    d.settings.width = 12;
    d.settings.height = 12;
    d.settings.spp = 48;
    d.settings.max_depth = 256;
    d.settings.integrator = IntegratorKind::VolPath;
    d.camera.from = Vec3::new(0.0, 0.0, 4.0);
    d.camera.projection = ProjectionDesc::Perspective { fov: 25.0 };
    d.background = BackgroundDesc::Constant(Rgb::ONE);
    d.materials
        .push(MaterialDesc::with_kind("boundary", MaterialKindDesc::NULL));
    let mut s = ShapeDesc::new(shape, Some("boundary"));
    s.media = Some(MediumInterfaceDesc {
        inside: Some(medium.name.clone()),
        outside: None,
    });
    d.shapes.push(s);
    d.media.push(medium);
    d
}

fn homogeneous(sigma_t: Rgb, albedo: Rgb, g: f32) -> MediumDesc {
    MediumDesc {
        name: "fog".into(),
        sigma_t: FieldDesc::Constant(sigma_t),
        albedo: FieldDesc::Constant(albedo),
        emission: None,
        scale: Rgb::ONE,
        g,
        locs: Locs::default(),
    }
}

fn sphere() -> ShapeKind {
    ShapeKind::Sphere {
        center: Vec3::ZERO,
        radius: 1.0,
    }
}

#[test]
fn white_furnace_of_a_scattering_medium_renders_one() {
    for (sigma_t, g) in [
        (Rgb::splat(2.0), 0.0),
        (Rgb::splat(1.5), 0.6),
        (Rgb::new(0.5, 2.0, 4.0), -0.3),
    ] {
        let d = medium_scene(sphere(), homogeneous(sigma_t, Rgb::ONE, g));
        let image = render_image(&trazo::scene::build(&d).unwrap()).unwrap();
        assert_mean(&image.pixels, Rgb::ONE, &format!("σt {sigma_t}, g {g}"));
    }
}

#[test]
fn white_furnace_of_a_grid_medium_renders_one() {
    // A 4×4×4 grid of densities from 0 to 9: null collisions everywhere
    // but at the densest voxel; chromatic through `scale`d channels.
    let values: Vec<f32> = (0..64 * 3).map(|i| ((i * 7) % 10) as f32).collect();
    let grid = VoxelGrid::new([4, 4, 4], 3, values).unwrap();
    let to_world = vec![
        TransformOp::Translate(Vec3::splat(-0.5)),
        TransformOp::Scale(Vec3::splat(1.6)),
    ];
    let medium = MediumDesc {
        name: "smoke".into(),
        sigma_t: FieldDesc::Grid {
            source: GridSource::Data(std::sync::Arc::new(grid)),
            to_world,
            use_file_bounds: false,
        },
        albedo: FieldDesc::Constant(Rgb::ONE),
        emission: None,
        scale: Rgb::new(0.5, 0.25, 1.0),
        g: 0.0,
        locs: Locs::default(),
    };
    let d = medium_scene(
        ShapeKind::Cuboid {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        },
        medium,
    );
    let image = render_image(&trazo::scene::build(&d).unwrap()).unwrap();
    assert_mean(&image.pixels, Rgb::ONE, "grid furnace");
}

#[test]
fn an_absorbing_slab_transmits_by_beer_lambert() {
    // An orthographic camera looks through a slab 2 thick: exp(−2σt).
    let sigma_t = Rgb::new(0.2, 0.7, 1.5);
    let mut d = medium_scene(
        ShapeKind::Cuboid {
            min: Vec3::new(-5.0, -5.0, -1.0),
            max: Vec3::new(5.0, 5.0, 1.0),
        },
        homogeneous(sigma_t, Rgb::ZERO, 0.0),
    );
    d.camera.projection = ProjectionDesc::Orthographic { size: 2.0 };
    let image = render_image(&trazo::scene::build(&d).unwrap()).unwrap();
    let expect = Rgb::new((-0.4f32).exp(), (-1.4f32).exp(), (-3.0f32).exp());
    assert_mean(&image.pixels, expect, "Beer–Lambert");
}

#[test]
fn a_thin_slab_scatters_once_as_its_closed_form() {
    // Light of irradiance E falls straight down (−z) on a slab z ∈ [−d, 0];
    // the camera looks straight down at it. Single scattering (max_depth
    // 2) by an isotropic medium: L = σs·E/(4π)·(1 − e^(−2σt·d))/(2σt).
    let (sigma_t, albedo, depth, e) = (1.2f32, 0.6f32, 0.5f32, 3.0f32);
    let mut d = medium_scene(
        ShapeKind::Cuboid {
            min: Vec3::new(-5.0, -5.0, -depth),
            max: Vec3::new(5.0, 5.0, 0.0),
        },
        homogeneous(Rgb::splat(sigma_t), Rgb::splat(albedo), 0.0),
    );
    d.background = BackgroundDesc::Constant(Rgb::ZERO);
    d.settings.max_depth = 2;
    d.camera.projection = ProjectionDesc::Orthographic { size: 2.0 };
    d.lights.push(LightDesc {
        kind: LightKind::Directional {
            direction: -Vec3::Z,
            irradiance: Rgb::splat(e),
        },
        locs: Locs::default(),
    });
    let image = render_image(&trazo::scene::build(&d).unwrap()).unwrap();
    let sigma_s = sigma_t * albedo;
    let expect = sigma_s * e / (4.0 * std::f32::consts::PI) * (1.0 - (-2.0 * sigma_t * depth).exp()) / (2.0 * sigma_t);
    assert_mean(&image.pixels, Rgb::splat(expect), "single scattering");
}

#[test]
fn a_null_surface_is_invisible_to_both_path_tracers() {
    for integrator in [IntegratorKind::Path, IntegratorKind::VolPath] {
        let mut d = medium_scene(sphere(), homogeneous(Rgb::ZERO, Rgb::ONE, 0.0));
        d.shapes[0].media = None;
        d.media.clear();
        d.settings.integrator = integrator;
        d.settings.spp = 4;
        let image = render_image(&trazo::scene::build(&d).unwrap()).unwrap();
        let worst = image
            .pixels
            .iter()
            .map(|p| (*p - Rgb::ONE).abs().max_element())
            .fold(0.0, f32::max);
        assert!(worst < 1e-5, "{integrator:?}: {worst}");
    }
}

/// Transmittance through a slab whose density zig-zags along the view:
/// tracking is exact; ray marching is biased for long steps (the
/// transmittance of a jittered sum of the optical depth is not the
/// transmittance of the depth) and converges as the step shrinks.
#[test]
fn ray_marching_converges_to_the_tracked_transmittance() {
    let grid = VoxelGrid::new([1, 1, 8], 1, vec![0.0, 3.0, 0.0, 3.0, 0.0, 3.0, 0.0, 3.0]).unwrap();
    // Exact optical depth along z: the slab is 2 thick, the grid is read
    // trilinearly (clamped) between voxel centres.
    let n = 100_000;
    let tau: f64 = (0..n)
        .map(|i| grid.lookup(Vec3::new(0.5, 0.5, (i as f32 + 0.5) / n as f32)).x as f64)
        .sum::<f64>()
        * 2.0
        / n as f64;
    let exact = (-tau).exp() as f32;
    let medium = MediumDesc {
        name: "zigzag".into(),
        sigma_t: FieldDesc::Grid {
            source: GridSource::Data(std::sync::Arc::new(grid)),
            to_world: vec![
                TransformOp::Scale(Vec3::splat(2.0)),
                TransformOp::Translate(Vec3::splat(-1.0)),
            ],
            use_file_bounds: false,
        },
        albedo: FieldDesc::Constant(Rgb::ZERO),
        emission: None,
        scale: Rgb::ONE,
        g: 0.0,
        locs: Locs::default(),
    };
    let mut d = medium_scene(
        ShapeKind::Cuboid {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        },
        medium,
    );
    d.camera.projection = ProjectionDesc::Orthographic { size: 1.0 };
    d.settings.spp = 256;
    let error = |step: Option<f32>| {
        let mut d = d.clone();
        d.settings.march_step = step;
        let image = render_image(&trazo::scene::build(&d).unwrap()).unwrap();
        let (mean, err) = mean_and_error(&image.pixels);
        ((mean.x - exact).abs(), err.x)
    };
    let (tracked, se) = error(None);
    assert!(
        tracked <= 4.5 * se + 1e-4,
        "tracking: off by {tracked} ± {se} from {exact}"
    );
    let (coarse, se_coarse) = error(Some(1.0));
    let (fine, se_fine) = error(Some(0.01));
    assert!(
        coarse > 6.0 * se_coarse,
        "a step of 1 is biased: off by {coarse} ± {se_coarse}"
    );
    assert!(
        fine <= 4.5 * se_fine + 1e-4,
        "a step of 0.01 converges: off by {fine} ± {se_fine}"
    );
}

/// A black surface of opacity α in front of a white background shows
/// 1 − α (a cut-out mask, Mitsuba's `mask` BSDF), in both path tracers;
/// the volumetric one's shadow rays also pass it with weight 1 − α.
#[test]
fn a_mask_lets_through_what_it_cuts_out() {
    let alpha = 0.3f32;
    for integrator in [IntegratorKind::Path, IntegratorKind::VolPath] {
        let mut d = medium_scene(sphere(), homogeneous(Rgb::ZERO, Rgb::ONE, 0.0));
        d.shapes[0].media = None;
        d.media.clear();
        d.settings.integrator = integrator;
        d.settings.spp = 64;
        let mut m = MaterialDesc::with_kind(
            "leaf",
            MaterialKindDesc::Diffuse {
                reflectance: ColorSource::Rgb(Rgb::ZERO),
            },
        );
        m.opacity = Some(ColorSource::Rgb(Rgb::splat(alpha)));
        d.materials.push(m);
        d.shapes[0].material = Some("leaf".into());
        let image = render_image(&trazo::scene::build(&d).unwrap()).unwrap();
        // The camera's 25° view is filled by the sphere: two crossings.
        let expect = (1.0 - alpha) * (1.0 - alpha);
        let centre: Vec<Rgb> = (4..8)
            .flat_map(|y| (4..8).map(move |x| (x, y)))
            .map(|(x, y)| image.get(x, y))
            .collect();
        assert_mean(&centre, Rgb::splat(expect), &format!("{integrator:?}"));
    }
}

#[test]
fn integrators_without_masks_or_media_say_so() {
    let mut d = medium_scene(sphere(), homogeneous(Rgb::ONE, Rgb::ONE, 0.0));
    d.materials[0].opacity = Some(ColorSource::Rgb(Rgb::splat(0.5)));
    d.settings.integrator = IntegratorKind::Whitted;
    let scene = trazo::scene::build(&d).unwrap();
    assert!(
        scene.warnings.iter().any(|w| w.contains("opacity mask")),
        "{:?}",
        scene.warnings
    );
    assert!(
        scene.warnings.iter().any(|w| w.contains("participating media")),
        "{:?}",
        scene.warnings
    );
    d.settings.integrator = IntegratorKind::VolPath;
    let scene = trazo::scene::build(&d).unwrap();
    assert!(
        !scene
            .warnings
            .iter()
            .any(|w| w.contains("opacity mask") || w.contains("participating media"))
    );
}

/// pbrt-v4's procedural cloud from trazo's TOML: with albedo 1 it vanishes
/// in a white furnace; absorbing, it darkens the sky behind it.
#[test]
fn a_toml_cloud_vanishes_in_a_furnace_and_absorbs_when_dark() {
    let scene = |albedo: f32| {
        format!(
            r#"
[render]
width = 12
height = 12
spp = 48
max_depth = 256
integrator = "volpath"

[camera]
from = [0, 0, 4]
to = [0, 0, 0]
fov = 30

[world]
background = [1, 1, 1]

[[medium]]
name = "cloud"
type = "cloud"
sigma_t = 8
albedo = {albedo}
frequency = 3
transform = [{{ scale = 2 }}, {{ translate = [-1, -1, -1] }}]

[[material]]
name = "boundary"
type = "null"

[[shape]]
type = "box"
min = [-1, -1, -1]
max = [1, 1, 1]
material = "boundary"
inside = "cloud"
"#
        )
    };
    let render = |text: &str| {
        let d = trazo::scene::native::parse(text, std::path::Path::new("<cloud>")).unwrap();
        assert!(matches!(d.media[0].sigma_t, FieldDesc::Cloud { frequency, .. } if frequency == 3.0));
        render_image(&trazo::scene::build(&d).unwrap()).unwrap()
    };
    assert_mean(&render(&scene(1.0)).pixels, Rgb::ONE, "white cloud");
    let dark = render(&scene(0.0));
    let (mean, _) = mean_and_error(&dark.pixels);
    assert!(mean.y < 0.8, "a black cloud lets {} through", mean.y);
}

/// A NanoVDB grid from trazo's TOML (`type = "grid"` with an `.nvdb`
/// file): placed by its own map, then `transform`; with albedo 1 it
/// vanishes in a white furnace, absorbing it darkens the sky; a misspelt
/// grid name is an error that names the file and the grids it has.
#[test]
fn a_toml_nanovdb_grid_vanishes_in_a_furnace_and_absorbs_when_dark() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/nanovdb");
    let scene = |albedo: f32, grid: &str| {
        format!(
            r#"
[render]
width = 12
height = 12
spp = 48
max_depth = 256
integrator = "volpath"

[camera]
from = [0.25, 0, 6]
to = [0.25, 0, 0]
fov = 30

[world]
background = [1, 1, 1]

[[medium]]
name = "smoke"
type = "grid"
file = "{dir}/smoke.nvdb"
grid = "{grid}"
scale = 3
albedo = {albedo}
transform = [{{ translate = [0, -1.5, -3] }}]

[[material]]
name = "boundary"
type = "null"

[[shape]]
type = "sphere"
center = [0.25, 0, 0]
radius = 2.5
material = "boundary"
inside = "smoke"
"#
        )
    };
    let render = |text: &str| {
        let d = trazo::scene::native::parse(text, std::path::Path::new("<smoke>")).unwrap();
        let scene = trazo::scene::build(&d).unwrap();
        // The grid's world box, [0, 24] × [0, 16] × [0, 16] voxels of
        // 0.125 from (−1.25, 0.5, 2), moved by the transform.
        let bounds = scene.media[0].bounds.unwrap();
        assert!(
            (bounds.min - Vec3::new(-1.25, -1.0, -1.0)).length() < 1e-4,
            "{bounds:?}"
        );
        assert!((bounds.max - Vec3::new(1.75, 1.0, 1.0)).length() < 1e-4, "{bounds:?}");
        render_image(&scene).unwrap()
    };
    assert_mean(&render(&scene(1.0, "density")).pixels, Rgb::ONE, "white smoke");
    let (dark, _) = mean_and_error(&render(&scene(0.0, "density")).pixels);
    assert!(dark.y < 0.9, "black smoke lets {} through", dark.y);
    let d = trazo::scene::native::parse(&scene(1.0, "densty"), std::path::Path::new("<smoke>")).unwrap();
    let e = trazo::scene::build(&d).err().unwrap().to_string();
    assert!(
        e.contains("medium[0]")
            && e.contains("smoke.nvdb")
            && e.contains("no grid named \"densty\"")
            && e.contains("\"density\""),
        "{e}"
    );
}
