//! Dispersion: glass whose index varies with wavelength, in every
//! integrator that draws a wavelength for its paths (camera paths, light
//! paths, photons). Checked against Snell's law per channel and against
//! a white furnace. Tolerances come from the spread the renders show.

use trazo::Vec3;
use trazo::color::Rgb;
use trazo::film::Film;
use trazo::material::dispersion::{D_LINE_NM, IorSpectrum};
use trazo::render::{RenderOptions, render};
use trazo::scene::desc::*;
use trazo::settings::IntegratorKind;

fn render_film(d: &SceneDesc) -> Film {
    let scene = trazo::scene::build(d).unwrap();
    assert!(
        !scene.warnings.iter().any(|w| w.contains("disperses")),
        "{:?}",
        scene.warnings
    );
    render(&scene, &RenderOptions::default()).unwrap().film
}

fn sf11() -> IorSpectrum {
    IorSpectrum::named_glass("glass-F11").unwrap()
}

/// SF11 (pbrt-v4's `glass-F11`), a strongly dispersive glass.
pub(crate) fn dispersive_glass(name: &str) -> MaterialDesc {
    MaterialDesc::with_kind(
        name,
        MaterialKindDesc::Dielectric {
            ior: sf11().at(D_LINE_NM),
            ext_ior: 1.0,
            roughness: (0.0, 0.0),
            distribution: MicrofacetDistribution::Ggx,
            reflect_tint: Rgb::ONE,
            transmit_tint: Rgb::ONE,
            dispersion: Some(sf11()),
        },
    )
}

/// Per channel, the mean over the image's pixels and its standard error
/// from their spread. (A pixel's own variance is kept for its luminance
/// only, and a wavelength's weights move the channels more than that.)
fn channel_means(f: &Film) -> [(f64, f64); 3] {
    let n = f.pixels.len() as f64;
    std::array::from_fn(|k| {
        let values: Vec<f64> = f.pixels.iter().map(|p| p.value()[k] as f64).collect();
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, (var / n).sqrt())
    })
}

/// A dispersive glass sphere in a white furnace vanishes in every channel:
/// each wavelength's path is lossless, and the wavelengths' weights
/// average to white. Every integrator whose camera paths draw a
/// wavelength is checked.
#[test]
fn white_furnace_dispersive_glass_renders_one_in_every_channel() {
    for integrator in [
        IntegratorKind::Path,
        IntegratorKind::VolPath,
        IntegratorKind::Photon,
        IntegratorKind::Sppm,
        IntegratorKind::Vcm,
    ] {
        let mut d = SceneDesc::default();
        d.settings.width = 16;
        d.settings.height = 16;
        d.settings.spp = 256;
        d.settings.max_depth = 64;
        d.settings.integrator = integrator;
        d.camera.from = Vec3::new(0.0, 0.0, 4.0);
        d.camera.projection = ProjectionDesc::Perspective { fov: 15.0 };
        d.background = BackgroundDesc::Constant(Rgb::ONE);
        d.materials.push(dispersive_glass("glass"));
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            },
            Some("glass"),
        ));
        let f = render_film(&d);
        for (k, (mean, err)) in channel_means(&f).into_iter().enumerate() {
            assert!(
                (mean - 1.0).abs() <= 5.0 * err + 1e-4,
                "{}: channel {k}: {mean} ± {err}",
                integrator.name()
            );
        }
        // The channels differ pixel by pixel (they are equal without
        // dispersion, to the bit): the glass dispersed them.
        let spread = f
            .pixels
            .iter()
            .map(|p| (p.value().x - p.value().z).abs())
            .fold(0.0f32, f32::max);
        assert!(
            spread > 1e-3,
            "{}: no pixel shows dispersion ({spread})",
            integrator.name()
        );
    }
}

/// Light crossing a flat SF11 interface at θ = 60° from the normal is
/// refracted by φ(λ) = asin(sin θ / n(λ)), and after a depth D below the
/// interface it is displaced along the surface by D·tan φ(λ): by
/// D·(tan φ(λ) − tan φ_d) from where light of the d line goes. A channel
/// gathers its wavelengths in proportion to their weights (the channel's
/// response) times the Fresnel transmittance T(λ) of the crossing; the
/// centre of its image of a thin strip is the mean of those displacements
/// under those weights. Returns it per channel.
fn snell_offsets(theta: f32, depth: f32) -> [f64; 3] {
    let spectrum = sf11();
    let tan_phi = |n: f32| (theta.sin() / n).asin().tan();
    let offset = |n: f32| depth * (tan_phi(n) - tan_phi(spectrum.at(D_LINE_NM)));
    // Fresnel transmittance of unpolarised light crossing at θ.
    let transmittance = |n: f32| {
        let (ci, ct) = (theta.cos(), (theta.sin() / n).asin().cos());
        let rs = ((ci - n * ct) / (ci + n * ct)).powi(2);
        let rp = ((n * ci - ct) / (n * ci + ct)).powi(2);
        1.0 - 0.5 * (rs + rp)
    };
    let (mut sum, mut norm) = ([0.0f64; 3], [0.0f64; 3]);
    let steps = 200_000;
    for i in 0..steps {
        let s = trazo::color::spectrum::sample_visible_wavelength((i as f32 + 0.5) / steps as f32);
        let n = spectrum.at(s.nm);
        for k in 0..3 {
            let w = (s.weight[k] * transmittance(n)) as f64;
            sum[k] += w * offset(n) as f64;
            norm[k] += w;
        }
    }
    std::array::from_fn(|k| sum[k] / norm[k])
}

/// Per row of `f`, the centre along the film (in units of `pixel`, the
/// width a column covers, 0 at the film's middle) of each channel; then
/// their mean over the rows and its standard error.
fn centroids(f: &Film, pixel: f64) -> [(f64, f64); 3] {
    let (w, h) = (f.width as usize, f.height as usize);
    std::array::from_fn(|k| {
        let rows: Vec<f64> = (0..h)
            .map(|y| {
                let (mut sum, mut moment) = (0.0f64, 0.0f64);
                for x in 0..w {
                    let v = f.pixels[y * w + x].value()[k] as f64;
                    sum += v;
                    moment += v * ((x as f64 + 0.5) - w as f64 / 2.0) * pixel;
                }
                moment / sum
            })
            .collect();
        let n = rows.len() as f64;
        let mean = rows.iter().sum::<f64>() / n;
        let var = rows.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, (var / n).sqrt())
    })
}

/// Each channel's centre within 5 standard errors (plus `slack`) of
/// Snell's law's; red and blue pixels apart.
fn assert_centred(what: &str, found: [(f64, f64); 3], predicted: [f64; 3], slack: f64) {
    for k in 0..3 {
        let (c, err) = found[k];
        assert!(
            (c - predicted[k]).abs() <= 5.0 * err + slack,
            "{what}: channel {k} centred at {c} ± {err}, Snell's law predicts {} (all: {found:?} against {predicted:?})",
            predicted[k]
        );
    }
}

/// Camera paths: an orthographic camera looks at θ = 60° into a block of
/// SF11 and sees, one refraction down, a thin emitting strip at depth D.
/// A wavelength refracted less (red) reaches the strip from farther back
/// along the film, so each channel's image of the strip is centred where
/// [`snell_offsets`] puts it (the film runs against the displacement).
/// Without dispersion every channel sees it where the d line does.
#[test]
fn camera_paths_through_a_dispersive_interface_follow_snell() {
    let (theta, depth, strip): (f32, f32, f32) = (60f32.to_radians(), 4.0, 0.02);
    let (width, height, pixel) = (160u32, 16u32, 0.0025f32);
    let tan_d = (theta.sin() / sf11().at(D_LINE_NM)).asin().tan();
    let predicted = snell_offsets(theta, depth).map(|o| -o * theta.cos() as f64);
    let scene = |glass: MaterialDesc, integrator: IntegratorKind| {
        let mut d = SceneDesc::default();
        d.settings.width = width;
        d.settings.height = height;
        d.settings.spp = 256;
        d.settings.max_depth = 2; // one refraction, then the strip
        d.settings.integrator = integrator;
        d.settings.filter = trazo::settings::Filter::Box { radius: 0.5 };
        d.background = BackgroundDesc::Constant(Rgb::ZERO);
        let dir = Vec3::new(theta.sin(), 0.0, -theta.cos());
        // The film's centre looks at the entry point from which light of
        // the d line reaches the strip's centre.
        let entry = Vec3::new(strip / 2.0 - depth * tan_d, 0.0, 0.0);
        d.camera.from = entry - 5.0 * dir;
        d.camera.to = entry;
        d.camera.up = Vec3::Y;
        d.camera.projection = ProjectionDesc::Orthographic {
            size: height as f32 * pixel,
        };
        d.materials.push(glass);
        let mut light = MaterialDesc::with_kind(
            "strip",
            MaterialKindDesc::Diffuse {
                reflectance: ColorSource::Rgb(Rgb::ZERO),
            },
        );
        light.emission = ColorSource::Rgb(Rgb::ONE);
        d.materials.push(light);
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Cuboid {
                min: Vec3::new(-50.0, -50.0, -50.0),
                max: Vec3::new(50.0, 50.0, 0.0),
            },
            Some("glass"),
        ));
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Rectangle {
                corner: Vec3::new(0.0, -1.0, -depth),
                edge_u: Vec3::new(strip, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 2.0, 0.0),
            },
            Some("strip"),
        ));
        render_film(&d)
    };
    let mut plain = dispersive_glass("glass");
    if let MaterialKindDesc::Dielectric { dispersion, .. } = &mut plain.kind {
        *dispersion = None;
    }
    let flat = centroids(&scene(plain, IntegratorKind::Path), pixel as f64);
    assert_centred("no dispersion", flat, [0.0; 3], 0.05 * pixel as f64);
    // The channels are pixels apart.
    assert!(predicted[2] - predicted[0] > 3.0 * pixel as f64, "{predicted:?}");
    for integrator in [
        IntegratorKind::Path,
        IntegratorKind::VolPath,
        IntegratorKind::Photon,
        IntegratorKind::Sppm,
        IntegratorKind::Bdpt,
        IntegratorKind::Vcm,
        IntegratorKind::Mlt,
        IntegratorKind::Pssmlt,
        IntegratorKind::Whitted,
    ] {
        let found = centroids(&scene(dispersive_glass("glass"), integrator), pixel as f64);
        assert_centred(integrator.name(), found, predicted, 0.05 * pixel as f64);
    }
}

/// Light paths and photons: a spot light far off shines at θ = 60°
/// through a slit in a black sheet onto a block of SF11; a diffuse floor
/// at depth D inside the block catches the light, and a camera inside the
/// block looks straight down at it. Each channel's image of the lit strip
/// is centred where [`snell_offsets`] puts it (the camera's film runs
/// with the displacement, a column covering `pixel` of the floor).
/// Photon mapping's density estimates blur the strip symmetrically, by a
/// radius that shrinks over SPPM's iterations: a fifth of a column of
/// slack for them.
#[test]
fn light_paths_through_a_dispersive_interface_follow_snell() {
    let (theta, depth, slit): (f32, f32, f32) = (60f32.to_radians(), 4.0, 0.02);
    let (width, height, pixel) = (160u32, 16u32, 0.0025f32);
    let tan_d = (theta.sin() / sf11().at(D_LINE_NM)).asin().tan();
    let predicted = snell_offsets(theta, depth);
    // The sheet lies 0.01 above the glass; the strip of the d line is
    // centred below the slit's centre by the path through both.
    let centre = slit / 2.0 + 0.01 * theta.tan() + depth * tan_d;
    let dir = [theta.sin(), 0.0, -theta.cos()];
    let aim = [slit / 2.0, 0.0, 0.01];
    let lamp: Vec<f32> = (0..3).map(|i| aim[i] - 10.0 * dir[i]).collect();
    let camera_height = depth - 0.5;
    let fov = 2.0 * (height as f32 * pixel / 2.0 / camera_height).atan().to_degrees();
    let text = format!(
        r#"[render]
width = {width}
height = {height}
spp = 256
max_depth = 3
photons = 200000

[camera]
type = "perspective"
from = [{centre}, 0, -0.5]
to = [{centre}, 0, -{depth}]
up = [0, 1, 0]
fov = {fov}

[[material]]
name = "glass"
type = "dielectric"
ior = "F11"

[[material]]
name = "floor"
diffuse = [1, 1, 1]

[[material]]
name = "black"
diffuse = [0, 0, 0]

[[light]]
type = "spot"
position = [{}, {}, {}]
to = [{}, {}, {}]
intensity = [100, 100, 100]
inner_angle = 1.5
outer_angle = 2

[[shape]]
type = "box"
min = [-50, -50, -50]
max = [50, 50, 0]
material = "glass"

[[shape]]
type = "rectangle"
corner = [-20, -1, -{depth}]
edge_u = [40, 0, 0]
edge_v = [0, 2, 0]
material = "floor"

[[shape]]
type = "rectangle"
corner = [-20, -20, 0.01]
edge_u = [20, 0, 0]
edge_v = [0, 40, 0]
material = "black"

[[shape]]
type = "rectangle"
corner = [{slit}, -20, 0.01]
edge_u = [20, 0, 0]
edge_v = [0, 40, 0]
material = "black"
"#,
        lamp[0], lamp[1], lamp[2], aim[0], aim[1], aim[2]
    );
    let desc = trazo::scene::native::parse(&text, std::path::Path::new("slit.toml")).unwrap();
    assert!(predicted[0] - predicted[2] > 3.0 * pixel as f64, "{predicted:?}");
    // (Jensen's photon mapper gathers finally at every pixel: fewer
    // samples.)
    for (integrator, spp, slack) in [
        (IntegratorKind::Light, 256, 0.05),
        (IntegratorKind::Bdpt, 64, 0.05),
        (IntegratorKind::Vcm, 64, 0.2),
        (IntegratorKind::Sppm, 256, 0.2),
        (IntegratorKind::Photon, 16, 0.2),
    ] {
        let mut d = desc.clone();
        d.settings.integrator = integrator;
        d.settings.spp = spp;
        let found = centroids(&render_film(&d), pixel as f64);
        assert_centred(integrator.name(), found, predicted, slack * pixel as f64);
    }
}
