//! Scenes that need no file: the default Cornell box, and a studio set-up
//! that frames a lone model.

use super::desc::*;
use super::native;
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::geometry::{Aabb, TriangleMesh};
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

/// A model file's meshes (each with the name of its material, if the file
/// gave one), plus the materials, textures and warnings it brings.
struct Model {
    parts: Vec<(TriangleMesh, Option<String>)>,
    materials: Vec<MaterialDesc>,
    textures: Vec<TextureDesc>,
    warnings: Vec<String>,
}

/// Loads a model file by its extension (`.obj` with its MTL materials, or
/// `.ply`), with the reader's warnings.
fn load_model(path: &Path) -> Result<Model> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("obj") => Ok(obj_model(super::obj::load_obj_scene(path)?)),
        // Through `read_ply` rather than `load_ply_mesh`, to keep its warnings.
        Some("ply") => super::ply::read_ply(path).map(ply_model),
        // Its first mesh, smoothed where it has no normals, as Mitsuba
        // shows it.
        Some("serialized") => super::serialized::read_serialized(path, 0).map(|s| {
            let mut mesh = s.mesh;
            if mesh.normals.is_empty() && !s.face_normals {
                mesh.compute_vertex_normals();
            }
            ply_model(super::ply::PlyMesh {
                mesh,
                ..Default::default()
            })
        }),
        _ => Err(Error::file(
            path,
            "unknown model format: trazo reads .obj, .ply and .serialized models",
        )),
    }
}

fn obj_model(s: super::obj::ObjScene) -> Model {
    let names: Vec<String> = s.materials.iter().map(|m| m.name.clone()).collect();
    Model {
        parts: s
            .parts
            .into_iter()
            .map(|(m, i)| (m, i.map(|i| names[i].clone())))
            .collect(),
        materials: s.materials,
        textures: s.textures,
        warnings: s.warnings,
    }
}

fn ply_model(p: super::ply::PlyMesh) -> Model {
    Model {
        parts: vec![(p.mesh, None)],
        materials: Vec::new(),
        textures: Vec::new(),
        warnings: p.warnings,
    }
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
    d.lights.push(LightDesc::new(LightKind::Directional {
        direction: Vec3::new(-0.5, -1.0, -0.6).normalize(),
        irradiance: Rgb::splat(2.6),
    }));
    d.lights.push(LightDesc::new(LightKind::Directional {
        direction: Vec3::new(0.8, -0.3, -0.5).normalize(),
        irradiance: Rgb::new(0.6, 0.65, 0.8),
    }));
}

/// Sets up a studio around geometry with bounds `bounds`: the
/// [`framing_camera`], the [`add_studio_lights`] and a grey ground plane
/// under it all.
pub fn studio(d: &mut SceneDesc, bounds: Aabb) {
    d.camera = framing_camera(&bounds);
    add_studio_lights(d);
    d.materials.push(MaterialDesc::classic(
        "studio-ground",
        ClassicDesc {
            diffuse: ColorSource::Rgb(Rgb::splat(0.5)),
            ..ClassicDesc::default()
        },
    ));
    d.shapes.push(ShapeDesc::new(
        ShapeKind::Plane {
            point: Vec3::new(0.0, bounds.min.y, 0.0),
            normal: Vec3::Y,
        },
        Some("studio-ground"),
    ));
}

/// A scene showing one model file (`.obj` with its MTL materials, or
/// `.ply`): the model on a ground plane in a studio (see [`studio`]); parts
/// without a material are light grey.
pub fn framed_model(path: &Path) -> Result<SceneDesc> {
    frame(load_model(path)?, path)
}

/// [`framed_model`] for an OBJ file already read from `path`.
pub fn framed_obj(obj: super::obj::ObjScene, path: &Path) -> Result<SceneDesc> {
    frame(obj_model(obj), path)
}

/// [`framed_model`] for a PLY file already read from `path`.
pub fn framed_ply(ply: super::ply::PlyMesh, path: &Path) -> Result<SceneDesc> {
    frame(ply_model(ply), path)
}

fn frame(model: Model, path: &Path) -> Result<SceneDesc> {
    let bounds = model.parts.iter().fold(Aabb::EMPTY, |b, (m, _)| b.union(&m.bounds()));
    let mut d = SceneDesc {
        source: Some(std::sync::Arc::from(path)),
        warnings: model.warnings,
        textures: model.textures,
        materials: model.materials,
        ..SceneDesc::default()
    };
    d.materials.push(MaterialDesc::classic(
        "studio-model",
        ClassicDesc {
            diffuse: ColorSource::Rgb(Rgb::splat(0.7)),
            specular: ColorSource::Rgb(Rgb::splat(0.15)),
            shininess: 40.0,
            ..ClassicDesc::default()
        },
    ));
    studio(&mut d, bounds);
    for (mesh, material) in model.parts {
        let material = material.unwrap_or_else(|| "studio-model".into());
        d.shapes.push(ShapeDesc::new(
            ShapeKind::InlineMesh(MeshSource::Inline(mesh)),
            Some(&material),
        ));
    }
    d.validate()?;
    Ok(d)
}
