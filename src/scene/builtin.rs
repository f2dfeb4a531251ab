//! Scenes that need no file: the default Cornell box, and a studio set-up
//! that frames a lone model.

use super::desc::*;
use super::native;
use crate::color::Rgb;
use crate::error::Result;
use crate::geometry::Aabb;
use glam::Vec3;
use std::path::Path;

/// The text of scenes/cornell-box.toml, compiled in.
pub const CORNELL_BOX_TOML: &str = include_str!("../../scenes/cornell-box.toml");

/// The Cornell box of Mitsuba 3's `cornell_box()`: trazo's default scene.
pub fn cornell_box() -> SceneDesc {
    let mut d =
        native::parse(CORNELL_BOX_TOML, Path::new("<built-in cornell-box.toml>")).expect("the built-in scene is valid");
    // Built in: there is no folder to resolve paths against.
    d.source = None;
    d
}

/// A scene showing one model file: the model in a light grey material on
/// a ground plane, lit by a key and a fill light, seen from the front and
/// a little above so that its bounding sphere fills the view.
pub fn framed_model(path: &Path) -> Result<SceneDesc> {
    let mesh = super::obj::load_obj_mesh(path)?;
    let bounds = mesh.bounds();

    let mut d = SceneDesc {
        source: Some(std::sync::Arc::from(path)),
        ..SceneDesc::default()
    };
    d.camera = framing_camera(&bounds);
    add_studio_lights(&mut d);
    d.materials.push(MaterialDesc::classic(
        "model",
        ClassicDesc {
            diffuse: ColorSource::Rgb(Rgb::splat(0.7)),
            specular: ColorSource::Rgb(Rgb::splat(0.15)),
            shininess: 40.0,
            ..ClassicDesc::default()
        },
    ));
    d.materials.push(MaterialDesc::classic(
        "ground",
        ClassicDesc {
            diffuse: ColorSource::Rgb(Rgb::splat(0.5)),
            ..ClassicDesc::default()
        },
    ));
    d.shapes.push(ShapeDesc::new(
        ShapeKind::InlineMesh(MeshSource::Inline(mesh)),
        Some("model"),
    ));
    d.shapes.push(ShapeDesc::new(
        ShapeKind::Plane {
            point: Vec3::new(0.0, bounds.min.y, 0.0),
            normal: Vec3::Y,
        },
        Some("ground"),
    ));
    d.validate()?;
    Ok(d)
}

/// A perspective camera (40° vertical field of view, +y up) that looks at
/// `bounds` from the front, a little above and to the right, far enough
/// away that their bounding sphere fits the view.
pub fn framing_camera(bounds: &Aabb) -> CameraDesc {
    let center = bounds.centroid();
    let radius = (bounds.extent().length() * 0.5).max(1e-6);
    let fov = 40.0f32;
    let distance = radius / (fov.to_radians() * 0.5).sin() * 1.05;
    let view_dir = Vec3::new(0.35, 0.3, 1.0).normalize();
    CameraDesc {
        projection: ProjectionDesc::Perspective { fov },
        from: center + view_dir * distance,
        to: center,
        up: Vec3::Y,
        ..CameraDesc::default()
    }
}

/// Studio lighting for a scene that brings none: a key and a fill
/// directional light, a blue-grey gradient background (which also lights
/// the path tracer's scenes) and a little ambient light for Whitted.
pub fn add_studio_lights(d: &mut SceneDesc) {
    d.background = BackgroundDesc::Gradient {
        top: Rgb::new(0.55, 0.6, 0.7),
        bottom: Rgb::splat(0.15),
    };
    d.ambient = Rgb::splat(0.08);
    d.lights.push(LightDesc {
        kind: LightKind::Directional {
            direction: Vec3::new(-0.5, -1.0, -0.6).normalize(),
            irradiance: Rgb::splat(2.6),
        },
        locs: Locs::default(),
    });
    d.lights.push(LightDesc {
        kind: LightKind::Directional {
            direction: Vec3::new(0.8, -0.3, -0.5).normalize(),
            irradiance: Rgb::new(0.6, 0.65, 0.8),
        },
        locs: Locs::default(),
    });
}
