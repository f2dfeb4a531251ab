//! From [`SceneDesc`] to the render-time [`Scene`]: resolves names to
//! indices, loads images and meshes, composes transforms, turns emissive
//! shapes into area lights and builds the BVH.

use super::Scene;
use super::desc::*;
use super::memory::{
    BYTES_PER_ENVIRONMENT_TEXEL, BYTES_PER_TEXEL, MemoryEstimate, light_vertex_bytes, mesh_bytes, photon_bytes,
    top_level_bytes,
};
use crate::accel::aggregate::{Aggregate, EmitterRef, MeshInstance, MeshObject, ShapeInstance};
use crate::camera::{Camera, Projection};
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::files::io_reason;
use crate::geometry::motion::MotionTransform;
use crate::geometry::shape::{Cuboid, Cylinder, Disk, Plane, Rectangle, Shape, Sphere};
use crate::geometry::{Aabb, Transform, TriangleMesh};
use crate::light::{Background, EnvironmentMap, Goniometric, Light, Projector, ProjectorLaw, SpotProjection};
use crate::material::conductor::ConductorFresnel;
use crate::material::measured::MeasuredBrdf;
use crate::material::{
    LayerBaseKind, Material, MaterialKind, MaterialMix, Microfacet, MicrofacetDistribution, RoughnessMap,
};
use crate::media::{Field, Medium, MediumInterface, Phase, VoxelGrid};
use crate::sampling::Distribution1D;
use crate::settings::IntegratorKind;
use crate::texture::{ImageColors, ImageTexture, MAX_TEXTURE_DEPTH, TexCoord, Texture, TextureStore};
use glam::Vec3;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Limits checked while a scene is built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BuildLimits {
    /// Largest estimated memory of the render in bytes (see
    /// [`super::memory`]); `None`: no limit.
    pub max_memory: Option<u64>,
    /// Whether the render will record auxiliary images (they count toward
    /// the memory).
    pub aovs: bool,
}

/// Builds a renderable scene. Validates the description first, so that
/// scenes made in code get the same checks as scenes read from files.
pub fn build(desc: &SceneDesc) -> Result<Scene> {
    build_limited(desc, &BuildLimits::default())
}

/// Builds a renderable scene, refusing with an error, before allocating,
/// a render whose estimated memory exceeds `limits.max_memory`: the
/// estimate is checked before anything is loaded, after each image is read
/// and before the BVH is built.
pub fn build_limited(desc: &SceneDesc, limits: &BuildLimits) -> Result<Scene> {
    desc.validate()?;
    let margin = desc.settings.pixel_filter().splat_margin().unwrap_or(0);
    let mut memory = MemoryEstimate::for_filtered_film(desc.settings.width, desc.settings.height, limits.aovs, margin);
    if desc.settings.gbuffer.is_some() {
        let pixels = desc.settings.width as u64 * desc.settings.height as u64;
        memory.aovs += pixels * crate::scene::memory::GBUFFER_BYTES_PER_PIXEL;
    }
    memory.geometry = described_mesh_bytes(desc);
    let (st, ph) = (&desc.settings, &desc.settings.photon);
    memory.photons = match st.integrator {
        IntegratorKind::Photon => photon_bytes(ph.photons as u64 + ph.caustic_photons as u64),
        IntegratorKind::Sppm => photon_bytes(match ph.sppm_photons {
            0 => st.width as u64 * st.height as u64,
            n => n as u64,
        }),
        IntegratorKind::Vcm => light_vertex_bytes(st.width as u64 * st.height as u64, st.max_depth),
        _ => 0,
    };
    memory.check(limits.max_memory)?;
    let base_dir: PathBuf = desc
        .source
        .as_ref()
        .and_then(|p| p.parent())
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let mut warnings = desc.warnings.clone();

    // Textures.
    let mut store = TextureStore::default();
    let mut textures: HashMap<&str, Texture> = HashMap::new();
    let mut attribute_names: Vec<String> = Vec::new();
    for (i, t) in desc.textures.iter().enumerate() {
        let tex = match &t.kind {
            TextureKind::Constant(c) => Texture::Constant(*c),
            TextureKind::MeshAttribute { name } => {
                let k = attribute_names.iter().position(|n| n == name).unwrap_or_else(|| {
                    attribute_names.push(name.clone());
                    attribute_names.len() - 1
                });
                Texture::MeshAttribute(k as u32)
            }
            TextureKind::Checkerboard { even, odd, scale } => Texture::Checkerboard {
                even: *even,
                odd: *odd,
                scale: *scale,
            },
            TextureKind::Checkerboard3d { even, odd, scale } => Texture::Checkerboard3d {
                even: *even,
                odd: *odd,
                scale: *scale,
            },
            TextureKind::Image {
                source,
                scale,
                offset,
                encoding,
                tint,
                wrap,
                filter,
            } => {
                let mut img = match source {
                    ImageSource::File(path) | ImageSource::EmissionFile(path) | ImageSource::DataFile(path) => {
                        let colors = match source {
                            ImageSource::EmissionFile(_) => ImageColors::Emission,
                            ImageSource::DataFile(_) => ImageColors::Data,
                            _ => ImageColors::Reflectance,
                        };
                        let (img, note) =
                            ImageTexture::load_colors(&base_dir.join(path), *encoding, colors).map_err(|e| {
                                Error::scene(t.locs.key("file"), format!("texture[{i}].file"), reason_of(e))
                            })?;
                        if let Some(note) = note {
                            warnings.push(format!(
                                "{}{note}",
                                t.locs.key("file").map(|l| format!("{l}: ")).unwrap_or_default()
                            ));
                        }
                        img
                    }
                    ImageSource::FloatFile(path) => ImageTexture::load_float(&base_dir.join(path), *encoding)
                        .map_err(|e| Error::scene(t.locs.key("file"), format!("texture[{i}].file"), reason_of(e)))?,
                    ImageSource::AlphaFile(path) => ImageTexture::load_alpha(&base_dir.join(path))
                        .map_err(|e| Error::scene(t.locs.key("file"), format!("texture[{i}].file"), reason_of(e)))?,
                    ImageSource::Data(data) => (**data).clone(),
                };
                memory.textures += img.pixels.len() as u64 * BYTES_PER_TEXEL;
                memory.check(limits.max_memory)?;
                let bad = img.sanitize();
                if bad > 0 {
                    warnings.push(format!(
                        "{}texture[{i}]: {bad} texels are NaN, infinite or negative; they are read as black",
                        t.locs.key("file").map(|l| format!("{l}: ")).unwrap_or_default()
                    ));
                }
                store.images.push(img);
                Texture::Image {
                    image: store.images.len() as u32 - 1,
                    scale: *scale,
                    offset: *offset,
                    tint: *tint,
                    wrap: *wrap,
                    filter: *filter,
                }
            }
            TextureKind::Node(node) => {
                // Validation saw that inputs name textures made before.
                let node = node.map(|c| match c {
                    ColorSource::Rgb(rgb) => Texture::Constant(*rgb),
                    ColorSource::Texture(name) => textures[name.as_str()],
                });
                store.push(node).ok_or_else(|| {
                    Error::scene(
                        t.locs.item.clone(),
                        format!("texture[{i}]"),
                        format!("\"{}\" nests textures more than {MAX_TEXTURE_DEPTH} deep", t.name),
                    )
                })?
            }
        };
        textures.insert(t.name.as_str(), tex);
    }
    let heights = Heights {
        textures: &textures,
        store: &store,
    };
    let color = |c: &ColorSource| -> Texture {
        match c {
            ColorSource::Rgb(rgb) => Texture::Constant(*rgb),
            ColorSource::Texture(name) => textures[name.as_str()],
        }
    };

    // Measured BRDFs, each file read once.
    let mut measured: HashMap<&Path, Arc<MeasuredBrdf>> = HashMap::new();
    for (i, m) in desc.materials.iter().enumerate() {
        if let MaterialKindDesc::Measured { file } = &m.kind
            && !measured.contains_key(file.as_path())
        {
            let path = base_dir.join(file);
            let brdf = MeasuredBrdf::load(&path).map_err(|e| {
                Error::scene(
                    m.locs.key("file"),
                    format!("material[{i}].file"),
                    format!("measured BSDF {}: {e}", path.display()),
                )
            })?;
            measured.insert(file.as_path(), Arc::new(brdf));
        }
    }

    // Materials; the default one goes last, used by shapes without one.
    let mut materials: Vec<Material> = desc
        .materials
        .iter()
        .map(|m| to_material(m, &color, &store, &measured))
        .collect();
    let material_index: HashMap<&str, u32> = desc
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| (m.name.as_str(), i as u32))
        .collect();
    let mut material_mixes = resolve_mixes(desc, &mut materials, &material_index, &color, &mut warnings);
    let default_material = materials.len() as u32;
    materials.push(Material::default());
    material_mixes.push(None);

    // Media; a shape that bounds media gets its own copy of its material,
    // which carries the interface ([`Scene::material_media`]).
    let mut media = Vec::with_capacity(desc.media.len());
    for (i, m) in desc.media.iter().enumerate() {
        media.push(to_medium(m, i, &base_dir, &mut memory, limits, &mut warnings)?);
    }
    let medium_index: HashMap<&str, u32> = desc
        .media
        .iter()
        .enumerate()
        .map(|(i, m)| (m.name.as_str(), i as u32))
        .collect();
    let medium_of = |name: &Option<String>| name.as_ref().map(|n| medium_index[n.as_str()]);
    let mut material_media: Vec<Option<MediumInterface>> = vec![None; materials.len()];
    let mut interfaced: HashMap<(u32, MediumInterface), u32> = HashMap::new();

    // Named meshes, loaded once; placed once → baked into world space,
    // placed more often → instanced.
    let mut uses: HashMap<&str, usize> = HashMap::new();
    for s in &desc.shapes {
        if let ShapeKind::Mesh(name) = &s.kind {
            *uses.entry(name.as_str()).or_default() += 1;
        }
    }
    let mut named_meshes: HashMap<&str, TriangleMesh> = HashMap::new();
    for (i, m) in desc.meshes.iter().enumerate() {
        if uses.get(m.name.as_str()).copied().unwrap_or(0) == 0 {
            warnings.push(format!(
                "{}mesh \"{}\" is never placed by a shape",
                m.locs.item.as_ref().map(|l| format!("{l}: ")).unwrap_or_default(),
                m.name
            ));
            continue;
        }
        let mesh = load_mesh_source(
            &m.source,
            &base_dir,
            &m.locs,
            &format!("mesh[{i}]"),
            &mut warnings,
            &Transform::IDENTITY,
            &heights,
        )?;
        named_meshes.insert(m.name.as_str(), mesh);
    }

    let mut meshes: Vec<TriangleMesh> = Vec::new();
    let mut shapes = Vec::new();
    // The description's shape each analytic shape comes from (a box gives
    // six), for messages.
    let mut shape_desc_index = Vec::new();
    let mut mesh_objects = Vec::new();
    let mut instances = Vec::new();
    let mut instanced_mesh_index: HashMap<&str, u32> = HashMap::new();
    for (i, s) in desc.shapes.iter().enumerate() {
        let mut material = s
            .material
            .as_ref()
            .map_or(default_material, |n| material_index[n.as_str()]);
        if let Some(mi) = &s.media {
            let interface = MediumInterface {
                inside: medium_of(&mi.inside),
                outside: medium_of(&mi.outside),
            };
            material = *interfaced.entry((material, interface)).or_insert_with(|| {
                materials.push(materials[material as usize].clone());
                material_media.push(Some(interface));
                materials.len() as u32 - 1
            });
        }
        let transform = compose(&s.transform)
            .map_err(|e| Error::scene(s.locs.key("transform"), format!("shape[{i}].transform"), e))?;
        let motion = match &s.motion {
            None => None,
            // pbrt-v4 cannot sample moving emitters either ("animated area
            // lights are not supported").
            Some(_) if materials[material as usize].is_emissive() => {
                warnings.push(format!(
                    "{}shape[{i}]: an emitting shape cannot move in trazo; it stays where the shutter opens",
                    s.locs
                        .key("transform_end")
                        .map(|l| format!("{l}: "))
                        .unwrap_or_default()
                ));
                None
            }
            Some(m) => {
                let end = compose(&m.end)
                    .map_err(|e| Error::scene(s.locs.key("transform_end"), format!("shape[{i}].transform_end"), e))?;
                if end == transform {
                    None
                } else {
                    let motion = MotionTransform::new(transform, end, m.times.0, m.times.1).ok_or_else(|| {
                        Error::scene(
                            s.locs.key("transform_end"),
                            format!("shape[{i}].transform_end"),
                            "the motion between the two transforms cannot be interpolated (entries too large or too small)",
                        )
                    })?;
                    Some(Box::new(motion))
                }
            }
        };
        let analytic = match &s.kind {
            ShapeKind::Sphere { center, radius } => Some(Shape::Sphere(Sphere::new(*center, *radius))),
            ShapeKind::Plane { point, normal } => Some(Shape::Plane(Plane::new(*point, *normal))),
            ShapeKind::Rectangle { corner, edge_u, edge_v } => {
                Some(Shape::Rectangle(Rectangle::new(*corner, *edge_u, *edge_v)))
            }
            ShapeKind::Disk {
                center,
                normal,
                radius,
                uv,
            } => Some(Shape::Disk(Disk {
                uv: *uv,
                center: *center,
                normal: normal.normalize(),
                radius: *radius,
            })),
            ShapeKind::Cuboid { min, max } => Some(Shape::Cuboid(Cuboid { min: *min, max: *max })),
            ShapeKind::Cylinder { p0, p1, radius } => Some(Shape::Cylinder(Cylinder {
                p0: *p0,
                p1: *p1,
                radius: *radius,
            })),
            ShapeKind::SdfGrid(g) => Some(Shape::SdfGrid(g.clone())),
            ShapeKind::Sdf(f) => Some(Shape::Sdf(f.clone())),
            ShapeKind::Implicit(f) => Some(Shape::Implicit(f.clone())),
            ShapeKind::Quadric(q) => Some(Shape::Quadric(*q)),
            ShapeKind::Bilinear(b) => Some(Shape::Bilinear(*b)),
            ShapeKind::Bezier(b) => Some(Shape::Bezier(b.clone())),
            ShapeKind::Curve(c) => Some(Shape::Curve(*c)),
            ShapeKind::Mesh(_) | ShapeKind::InlineMesh(_) => None,
        };
        if let (Some(shape), Some(motion)) = (&analytic, &motion) {
            shape_desc_index.push(i);
            shapes.push(ShapeInstance {
                shape: shape.clone(),
                transform: Some(transform),
                motion: Some(motion.clone()),
                material,
                light: None,
                flip_normals: s.flip_normals,
            });
            continue;
        }
        if let Some(shape) = analytic {
            // A sphere under a similarity (rotation, uniform scale,
            // translation) is still a sphere: bake the transform in, so it
            // intersects faster and can be sampled by solid angle.
            let (shape, transform) = match (&shape, similarity_scale(&transform)) {
                (&Shape::Sphere(sp), Some(scale)) if !transform.is_identity() => (
                    Shape::Sphere(Sphere {
                        center: transform.point(sp.center),
                        radius: sp.radius * scale,
                        // The rotation (or mirror) turns the surface
                        // coordinates with the sphere.
                        uv_frame: glam::Mat3::from_mat4(transform.m) * (1.0 / scale) * sp.uv_frame,
                    }),
                    Transform::IDENTITY,
                ),
                _ => (shape, transform),
            };
            let transform = (!transform.is_identity()).then_some(transform);
            // A box that does not emit is its six faces: rectangles, which
            // the tree's leaves test in blocks of eight (an emitting box
            // stays one light).
            let faces = match shape {
                Shape::Cuboid(c) if !materials[material as usize].is_emissive() => Some(c.faces()),
                _ => None,
            };
            if let Some(faces) = faces.filter(|f| f.iter().all(|(r, _)| r.is_regular())) {
                for (face, outward_is_front) in faces {
                    shape_desc_index.push(i);
                    shapes.push(ShapeInstance {
                        shape: Shape::Rectangle(face),
                        transform,
                        motion: None,
                        material,
                        light: None,
                        flip_normals: s.flip_normals ^ !outward_is_front,
                    });
                }
                continue;
            }
            shape_desc_index.push(i);
            shapes.push(ShapeInstance {
                shape,
                transform,
                motion: None,
                material,
                light: None,
                flip_normals: s.flip_normals,
            });
            continue;
        }
        let placed_once = match &s.kind {
            ShapeKind::Mesh(name) => uses[name.as_str()] == 1,
            _ => true,
        };
        if placed_once && motion.is_none() {
            let mesh = match &s.kind {
                ShapeKind::Mesh(name) => named_meshes.remove(name.as_str()).expect("loaded"),
                ShapeKind::InlineMesh(src) => load_mesh_source(
                    src,
                    &base_dir,
                    &s.locs,
                    &format!("shape[{i}]"),
                    &mut warnings,
                    &transform,
                    &heights,
                )?,
                _ => unreachable!(),
            };
            let mesh = if transform.is_identity() {
                mesh
            } else {
                mesh.transformed(&transform)
            };
            let mesh = if s.flip_normals { mesh.flipped() } else { mesh };
            let what = format!("shape[{i}]");
            let read = read_attribute(material, &materials, &material_mixes, &store);
            meshes.push(keep_read_attribute(mesh, read, &attribute_names, &what, &mut warnings));
            mesh_objects.push(MeshObject {
                mesh: meshes.len() as u32 - 1,
                material,
                light: None,
            });
        } else {
            // A moving mesh, or one placed many times: an instance (a mesh
            // placed many times is moved, not copied, and held once).
            let what = format!("shape[{i}]");
            let read = read_attribute(material, &materials, &material_mixes, &store);
            let mesh = match &s.kind {
                ShapeKind::Mesh(name) if placed_once => {
                    let mesh = named_meshes.remove(name.as_str()).expect("loaded");
                    meshes.push(keep_read_attribute(mesh, read, &attribute_names, &what, &mut warnings));
                    meshes.len() as u32 - 1
                }
                ShapeKind::Mesh(name) => *instanced_mesh_index.entry(name.as_str()).or_insert_with(|| {
                    let mesh = named_meshes.remove(name.as_str()).expect("loaded");
                    meshes.push(keep_read_attribute(mesh, read, &attribute_names, &what, &mut warnings));
                    meshes.len() as u32 - 1
                }),
                ShapeKind::InlineMesh(src) => {
                    let mesh = load_mesh_source(src, &base_dir, &s.locs, &what, &mut warnings, &transform, &heights)?;
                    meshes.push(keep_read_attribute(mesh, read, &attribute_names, &what, &mut warnings));
                    meshes.len() as u32 - 1
                }
                _ => unreachable!("analytic shapes are placed above"),
            };
            instances.push(MeshInstance {
                mesh,
                transform,
                motion,
                material,
                light: None,
                flip_normals: s.flip_normals,
            });
        }
    }

    memory.geometry = meshes
        .iter()
        .map(|m| mesh_bytes(m.len() as u64, m.positions.len() as u64))
        .sum::<u64>()
        + top_level_bytes((shapes.len() + instances.len()) as u64);
    memory.check(limits.max_memory)?;
    let moving = shapes.iter().any(|s: &ShapeInstance| s.motion.is_some())
        || instances.iter().any(|i: &MeshInstance| i.motion.is_some());
    let mut geometry = Aggregate::build(meshes, shapes, mesh_objects, instances);

    // Lights: the explicit ones, then one per emissive surface.
    let mut lights: Vec<Light> = desc
        .lights
        .iter()
        .enumerate()
        .map(|(i, l)| to_light(i, l, &color, &store))
        .collect::<Result<_>>()?;
    let emissive = |m: u32| materials[m as usize].is_emissive();
    let mut emitters: Vec<(EmitterRef, u32)> = Vec::new();
    for (i, s) in geometry.shapes.iter().enumerate() {
        if emissive(s.material) {
            if s.shape.bounds().is_none() {
                warnings.push(format!(
                    "shape[{}]: an emissive infinite plane is visible but lights nothing directly (it has no finite area to sample)",
                    shape_desc_index[i]
                ));
                continue;
            }
            if matches!(s.shape, Shape::Sdf(_) | Shape::SdfGrid(_) | Shape::Implicit(_)) && s.motion.is_some() {
                // Its light arrives where paths hit it, unweighted by MIS
                // (no other strategy finds it).
                warnings.push(format!(
                    "shape[{}]: a moving emissive distance function or implicit surface is not sampled as a light: its light reaches what paths that hit it see, noisily where it is small",
                    shape_desc_index[i]
                ));
                continue;
            }
            emitters.push((EmitterRef::Shape(i as u32), s.material));
        }
    }
    for (i, o) in geometry.mesh_objects.iter().enumerate() {
        if emissive(o.material) {
            emitters.push((EmitterRef::MeshObject(i as u32), o.material));
        }
    }
    for (i, o) in geometry.instances.iter().enumerate() {
        if emissive(o.material) {
            emitters.push((EmitterRef::Instance(i as u32), o.material));
        }
    }
    for (emitter, material) in emitters {
        let cone = crate::light::implicit_emitter_sphere(&geometry, emitter);
        let area = match cone {
            Some(sphere) => crate::accel::aggregate::EmitterArea {
                total: crate::light::crofton_area(&geometry, emitter, sphere),
                triangles: None,
            },
            None => geometry.emitter_area(emitter),
        };
        if area.total.is_nan() || area.total <= 0.0 {
            warnings.push(format!(
                "{}: an emissive surface has zero area and emits no light",
                match emitter {
                    EmitterRef::Shape(i) => format!("shape[{}]", shape_desc_index[i as usize]),
                    EmitterRef::MeshObject(i) => format!("emissive mesh {i}"),
                    EmitterRef::Instance(i) => format!("emissive mesh instance {i}"),
                }
            ));
            continue;
        }
        let index = lights.len() as u32;
        lights.push(Light::Area {
            emitter,
            radiance: materials[material as usize].emission,
            two_sided: materials[material as usize].emits_both_sides,
            parallelogram: crate::light::Parallelogram::of_emitter(&geometry, emitter, &area),
            area,
            sphere: crate::light::emitter_sphere(&geometry, emitter),
            cone,
        });
        match emitter {
            EmitterRef::Shape(i) => geometry.shapes[i as usize].light = Some(index),
            EmitterRef::MeshObject(i) => geometry.mesh_objects[i as usize].light = Some(index),
            EmitterRef::Instance(i) => geometry.instances[i as usize].light = Some(index),
        }
    }

    let s = &desc.settings;
    let cam = &desc.camera;
    let projection = match cam.projection {
        ProjectionDesc::Perspective { fov } => Projection::Perspective { fov_y: fov },
        ProjectionDesc::Orthographic { size } => Projection::Orthographic { height: size },
        ProjectionDesc::Spherical { mapping } => Projection::Spherical { mapping },
        ProjectionDesc::Realistic { .. } => Projection::Realistic,
    };
    let camera_to_world = match cam.to_world {
        Some(m) => Transform::from_matrix(m)
            .map_err(|e| Error::scene(cam.locs.key("to_world"), "camera.to_world", e.to_string()))?,
        None => Transform::look_at(cam.from, cam.to, cam.up).map_err(|_| {
            Error::scene(
                cam.locs.item.clone(),
                "camera",
                "the camera's `from`, `to` and `up` do not define a view (from = to, or up parallel to the view direction)",
            )
        })?,
    };
    let (full_width, full_height, window) = match s.crop {
        Some(c) => (c.full_width, c.full_height, Some((c.x, c.y, s.width, s.height))),
        None => (s.width, s.height, None),
    };
    let camera = Camera::from_transform_windowed(
        projection,
        camera_to_world,
        full_width,
        full_height,
        window,
        cam.screen_window,
    )
    .map_err(|m| Error::scene(cam.locs.key("screen_window"), "camera", m))?
    .with_thin_lens(
        cam.aperture_radius,
        cam.focus_distance.unwrap_or_else(|| (cam.to - cam.from).length()),
    )
    .with_clipping(cam.near_clip, cam.far_clip);
    let camera_end = match cam.motion {
        Some((end, times)) => {
            let end = Transform::from_matrix(end)
                .map_err(|e| Error::scene(cam.locs.key("to_world"), "camera.to_world", e.to_string()))?;
            (end != camera_to_world).then_some((end, times))
        }
        None => None,
    };
    let camera = match camera_end {
        Some((end, times)) => camera.with_motion(end, times).ok_or_else(|| {
            Error::scene(
                cam.locs.key("to_world"),
                "camera.to_world",
                "the camera's motion cannot be interpolated (entries too large or too small)",
            )
        })?,
        None => camera,
    };
    let camera = if moving || camera_end.is_some() {
        camera.with_shutter(cam.shutter.0, cam.shutter.1)
    } else {
        camera
    };
    let camera = match &cam.projection {
        ProjectionDesc::Realistic {
            lenses,
            aperture_diameter,
            focus_distance,
            film_diagonal,
            stop_mask,
        } => {
            if s.integrator == crate::settings::IntegratorKind::Sppm {
                return Err(Error::scene(
                    cam.locs.item.clone(),
                    "camera",
                    "\"sppm\" cannot trace its camera paths through a realistic camera's lenses (pbrt-v4's cannot either): use the path tracer, Whitted, photon mapping or ambient occlusion",
                ));
            }
            let lenses = crate::camera::LensSystem::new(
                lenses,
                *aperture_diameter,
                *focus_distance,
                *film_diagonal,
                (full_width, full_height),
                stop_mask.clone(),
            )
            .map_err(|m| Error::scene(cam.locs.key("lens"), "camera.lens", m))?;
            camera.with_lens_system(lenses)
        }
        _ => camera,
    };
    if s.integrator.splats_light_paths() && !camera.connects() {
        let why = match projection {
            Projection::Realistic => {
                "a realistic camera (it has no importance to connect to, nor has pbrt-v4's): use the path tracer, Whitted, photon mapping or ambient occlusion"
            }
            Projection::Spherical { .. } => {
                "a spherical camera (it has no importance to connect to, nor has pbrt-v4's): use the path tracer, Whitted, photon mapping or SPPM"
            }
            _ => {
                "an orthographic camera with a lens (its rays focus nowhere): drop the aperture, or use another integrator"
            }
        };
        return Err(Error::scene(
            cam.locs.item.clone(),
            "camera",
            format!("\"{}\" cannot connect light paths to {why}", s.integrator.name()),
        ));
    }
    let background = match &desc.background {
        BackgroundDesc::Sum(terms) => {
            let (mut maps, mut constant) = (Vec::new(), Rgb::ZERO);
            for term in terms {
                match environment(term, &base_dir, desc, limits, &mut memory, &mut warnings)? {
                    Background::Image(map) => maps.push(*map),
                    Background::Constant(c) => constant += c,
                    _ => unreachable!("validation keeps sums to constants and images"),
                }
            }
            match EnvironmentMap::summed(maps, constant) {
                Some(map) => Background::Image(Box::new(map)),
                None => Background::Constant(constant),
            }
        }
        one => environment(one, &base_dir, desc, limits, &mut memory, &mut warnings)?,
    };
    // A portal: the background resampled into the portal's directions,
    // at the map's resolution (pbrt-v4's; a constant needs one pixel).
    let background = match (&desc.portal, background) {
        (None, b) => b,
        (Some(corners), b) => {
            let res = match &b {
                Background::Image(map) => map.image.height.max(1) as usize,
                _ => 1,
            };
            let portal = crate::light::portal::PortalMap::new(|d| b.eval(d), *corners, res).map_err(|e| {
                Error::scene(
                    desc.world_locs.key("portal"),
                    "world.portal",
                    format!("the portal: {e}"),
                )
            })?;
            Background::Portal(Box::new(portal))
        }
    };
    // In the path tracer a background that is not black lights the scene.
    let environment_light = if background.is_black() {
        None
    } else {
        lights.push(Light::Environment);
        Some(lights.len() as u32 - 1)
    };
    if lights.is_empty() && desc.ambient == Rgb::ZERO {
        warnings.push("the scene has no lights, no emissive surfaces, no ambient light and a black background: the image will be black".into());
    }
    let any_transmissive = materials.iter().any(Material::is_transmissive);
    let materials_reading_uv = (0..materials.len() as u32)
        .map(|m| {
            let mut t = Vec::new();
            deciding_textures(m, &materials, &material_mixes, &mut t);
            t.iter().any(Texture::reads_uv)
        })
        .collect();
    let camera_medium = medium_of(&desc.camera_medium);
    let integrator = desc.settings.integrator;
    // BDPT, VCM and the Metropolis samplers over BDPT trace media
    // (bdpt/mod.rs).
    let traces_media = matches!(
        integrator,
        IntegratorKind::VolPath
            | IntegratorKind::Bdpt
            | IntegratorKind::Mlt
            | IntegratorKind::Pssmlt
            | IntegratorKind::Vcm
    );
    let at_medium =
        |m: &crate::scene::desc::MediumDesc| m.locs.item.as_ref().map(|l| format!("{l}: ")).unwrap_or_default();
    if !desc.media.is_empty() && !traces_media {
        warnings.push(format!(
            "{}the scene has participating media, which only the \"volpath\", \"bdpt\", \"vcm\", \"mlt\" and \"pssmlt\" integrators render; \"{}\" renders the surfaces as if the media were not there",
            at_medium(&desc.media[0]),
            integrator.name()
        ));
    }
    if desc.settings.max_component_value.is_finite()
        && (desc.settings.integrator == IntegratorKind::Sppm || desc.settings.integrator.splats_light_paths())
    {
        let at = desc
            .settings_locs
            .keys
            .iter()
            .find(|(k, _)| k == "max_component_value")
            .map(|(_, l)| format!("{l}: "))
            .unwrap_or_default();
        warnings.push(format!(
            "{at}max_component_value is unsupported by \"{}\", whose pixels gather photons or splats rather than samples: ignored",
            desc.settings.integrator.name()
        ));
    }
    let path_tracers = [IntegratorKind::Path, IntegratorKind::VolPath];
    if let Some(m) = desc.materials.iter().find(|m| m.opacity.is_some())
        && !(path_tracers.contains(&desc.settings.integrator) || desc.settings.integrator.splats_light_paths())
    {
        warnings.push(format!(
            "{}material \"{}\" has an opacity mask, which only \"path\", \"volpath\", \"light\", \"bdpt\", \"mlt\" and \"pssmlt\" render; \"{}\" renders it opaque",
            m.locs.item.as_ref().map(|l| format!("{l}: ")).unwrap_or_default(),
            m.name,
            desc.settings.integrator.name()
        ));
    }
    // Empty where nothing mixes, so that a hit looks no mix up.
    if material_mixes.iter().all(Option::is_none) {
        material_mixes.clear();
    } else {
        material_mixes.resize(materials.len(), None);
    }
    let mut lane_bounces: Vec<_> = (0..materials.len())
        .map(|m| {
            let mixed = material_mixes.get(m).is_some_and(Option::is_some);
            materials[m].lane_bounce().filter(|_| !mixed)
        })
        .collect();
    if lane_bounces.iter().all(Option::is_none) {
        lane_bounces.clear();
    }
    let mut scene = Scene {
        lane_bounces,
        any_blend: material_mixes.iter().flatten().any(|m| m.exact),
        any_dispersive: materials.iter().any(|m| m.dispersion().is_some()),
        material_mixes,
        media,
        material_media,
        camera_medium,
        any_transmissive,
        materials_reading_uv,
        camera,
        geometry,
        materials,
        textures: store,
        lights,
        background,
        ambient: desc.ambient,
        settings: desc.settings.clone(),
        warnings,
        light_distribution: Distribution1D::default(),
        light_sampler: Default::default(),
        environment_light,
    };
    // Lights are chosen in proportion to their power.
    let radius = {
        let b = scene.geometry.bounds();
        if b.is_empty() {
            1.0
        } else {
            (b.extent().length() * 0.5).max(1e-3)
        }
    };
    let powers: Vec<f32> = scene.lights.iter().map(|l| l.power(&scene, radius)).collect();
    scene.light_distribution = Distribution1D::new(&powers);
    // For a shading point, by the light tree.
    let bounds: Vec<_> = scene
        .lights
        .iter()
        .zip(&powers)
        .map(|(l, &power)| (l.bounds(&scene, power), power))
        .collect();
    scene.light_sampler = crate::light::LightSampler::new(&bounds);
    let silent: Vec<usize> = (0..scene.lights.len())
        .filter(|&i| !scene.lights[i].samples_when_incomplete(&scene))
        .collect();
    scene.light_sampler.leave_out_when_incomplete(&silent);
    Ok(scene)
}

/// One environment of the description as the scene's background.
fn environment(
    background: &BackgroundDesc,
    base_dir: &Path,
    desc: &SceneDesc,
    limits: &BuildLimits,
    memory: &mut MemoryEstimate,
    warnings: &mut Vec<String>,
) -> Result<Background> {
    Ok(match background {
        BackgroundDesc::Constant(c) => Background::Constant(*c),
        BackgroundDesc::Gradient { top, bottom } => Background::Gradient {
            top: *top,
            bottom: *bottom,
        },
        BackgroundDesc::Image {
            path,
            scale,
            transform,
            layout,
            illuminance,
        } => {
            let full = base_dir.join(path);
            let (mut image, note) = ImageTexture::load_colors(&full, None, ImageColors::Emission)
                .map_err(|e| Error::scene(desc.world_locs.key("background"), "world.background", reason_of(e)))?;
            if let Some(note) = note {
                let at = desc
                    .world_locs
                    .key("background")
                    .map(|l| format!("{l}: "))
                    .unwrap_or_default();
                warnings.push(format!("{at}{note}"));
            }
            memory.textures += image.pixels.len() as u64 * (BYTES_PER_TEXEL + BYTES_PER_ENVIRONMENT_TEXEL);
            memory.check(limits.max_memory)?;
            let bad = image.sanitize();
            if bad > 0 {
                warnings.push(format!(
                    "{}world.background: {bad} texels are NaN, infinite or negative; they are read as black",
                    desc.world_locs
                        .key("background")
                        .map(|l| format!("{l}: "))
                        .unwrap_or_default()
                ));
            }
            let to_world = compose(transform)
                .map_err(|e| Error::scene(desc.world_locs.key("background"), "world.background", e))?;
            if *layout == EnvironmentLayout::EqualAreaOctahedral && image.width != image.height {
                return Err(Error::scene(
                    desc.world_locs.key("background"),
                    "world.background",
                    format!(
                        "{}: an equal-area octahedral environment map must be square; this image is {}×{}",
                        path.display(),
                        image.width,
                        image.height
                    ),
                ));
            }
            let mut scale = *scale;
            if let Some(e) = illuminance {
                let k = pbrt_upper_hemisphere_illuminance(&image);
                if k > 0.0 {
                    scale *= e / k;
                }
            }
            Background::Image(Box::new(EnvironmentMap::with_layout(image, scale, to_world, *layout)))
        }
        BackgroundDesc::Sum(_) => unreachable!("sums are taken apart by the caller"),
    })
}

/// Bytes of the meshes a description holds itself (inline meshes and
/// generated spheres; mesh files are counted once they are read). A named
/// mesh counts once, however often it is placed.
fn described_mesh_bytes(desc: &SceneDesc) -> u64 {
    let source_bytes = |src: &MeshSource| match src {
        MeshSource::Inline(m) => mesh_bytes(m.len() as u64, m.positions.len() as u64),
        MeshSource::UvSphere { segments, rings } => mesh_bytes(
            2 * *segments as u64 * *rings as u64,
            (*segments as u64 + 1) * (*rings as u64 + 1),
        ),
        MeshSource::File(_) | MeshSource::Displaced { .. } => 0,
    };
    let named: u64 = desc.meshes.iter().map(|m| source_bytes(&m.source)).sum();
    let inline: u64 = desc
        .shapes
        .iter()
        .map(|s| match &s.kind {
            ShapeKind::InlineMesh(src) => source_bytes(src),
            _ => 0,
        })
        .sum();
    named + inline
}

/// The scale factor of a transform that is a similarity (rotation and
/// uniform scale, plus translation), or `None`.
fn similarity_scale(t: &Transform) -> Option<f32> {
    let m = glam::Mat3::from_mat4(t.m);
    let mtm = m.transpose() * m;
    let s2 = mtm.x_axis.x;
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * s2.abs().max(1e-30);
    let ok = close(mtm.y_axis.y, s2)
        && close(mtm.z_axis.z, s2)
        && close(mtm.x_axis.y, 0.0)
        && close(mtm.x_axis.z, 0.0)
        && close(mtm.y_axis.z, 0.0);
    ok.then(|| s2.sqrt())
}

/// The mesh with only the attribute its material reads, first, where the
/// surface record looks for it (a mesh placed many times keeps the one of
/// its first placement's material); a material reading one the mesh does
/// not have gets a warning and reads 0.
fn keep_read_attribute(
    mut mesh: TriangleMesh,
    read: Option<u32>,
    names: &[String],
    what: &str,
    warnings: &mut Vec<String>,
) -> TriangleMesh {
    let read = read.map(|k| names[k as usize].as_str());
    let kept = read.and_then(|name| mesh.attributes.iter().position(|a| a.name == name));
    match (read, kept) {
        (_, Some(k)) => {
            let a = mesh.attributes.swap_remove(k);
            mesh.attributes = vec![a];
        }
        (Some(name), None) => {
            let has: Vec<&str> = mesh.attributes.iter().map(|a| a.name.as_str()).collect();
            warnings.push(format!(
                "{what}: its material reads the mesh attribute \"{name}\", which the mesh does not have (it has {}); it reads 0",
                if has.is_empty() { "none".to_string() } else { has.join(", ") }
            ));
            mesh.attributes.clear();
        }
        (None, None) => mesh.attributes.clear(),
    }
    mesh
}

/// The mixes among the materials (`None` for the others), and each mix's
/// place taken by a copy of its first material (what light sampling and
/// the checks of every material read: a mix's emission is its own). Where
/// a mix has its own emission, sides, opacity or normal map, its two
/// materials are copied with them (appended to `materials`); a mix inside
/// such a mix does not take them (warning).
fn resolve_mixes(
    desc: &SceneDesc,
    materials: &mut Vec<Material>,
    index: &HashMap<&str, u32>,
    color: &dyn Fn(&ColorSource) -> Texture,
    warnings: &mut Vec<String>,
) -> Vec<Option<MaterialMix>> {
    let mut mixes: Vec<Option<MaterialMix>> = vec![None; materials.len()];
    for (i, m) in desc.materials.iter().enumerate() {
        let MaterialKindDesc::Mix {
            choice,
            materials: names,
        } = &m.kind
        else {
            continue;
        };
        let own = materials[i].clone();
        let overrides = own.emission != Texture::Constant(Rgb::ZERO)
            || own.two_sided
            || own.opacity.is_some()
            || own.normal_map.is_some()
            || own.bump_map.is_some();
        let mut parts = [index[names[0].as_str()], index[names[1].as_str()]];
        if overrides {
            for (k, part) in parts.iter_mut().enumerate() {
                if matches!(
                    desc.materials.get(*part as usize).map(|d| &d.kind),
                    Some(MaterialKindDesc::Mix { .. })
                ) {
                    warnings.push(format!(
                        "material \"{}\": its mix \"{}\" does not take its emission, sides, opacity, normal map or bump map",
                        m.name, names[k]
                    ));
                    continue;
                }
                let mut copy = materials[*part as usize].clone();
                if own.emission != Texture::Constant(Rgb::ZERO) {
                    copy.emission = own.emission;
                }
                copy.two_sided |= own.two_sided;
                copy.opacity = own.opacity.or(copy.opacity);
                copy.normal_map = own.normal_map.clone().or(copy.normal_map);
                copy.bump_map = own.bump_map.clone().or(copy.bump_map);
                materials.push(copy);
                mixes.push(None);
                *part = materials.len() as u32 - 1;
            }
        }
        // Blended as one BSDF where the two differ in their BSDFs alone: the
        // stand-in below then answers for everything but the BSDF.
        let plain = |k: u32| {
            let m = &materials[k as usize];
            !matches!(
                desc.materials.get(k as usize).map(|d| &d.kind),
                Some(MaterialKindDesc::Mix { .. })
            ) && m.normal_map.is_none()
                && m.bump_map.is_none()
                && m.opacity.is_none()
                && !m.is_emissive()
                && !matches!(m.kind, MaterialKind::Thin { .. })
        };
        let by_side = *choice == MixChoice::Side;
        let exact = !overrides
            && !by_side
            && parts.iter().all(|&k| plain(k))
            && materials[parts[0] as usize].two_sided == materials[parts[1] as usize].two_sided;
        let mut stand_in = materials[parts[0] as usize].clone();
        stand_in.emission = own.emission;
        materials[i] = stand_in;
        mixes[i] = Some(MaterialMix {
            weight: match choice {
                MixChoice::Weight(weight) => color(weight),
                MixChoice::Side => Texture::Constant(Rgb::ZERO),
            },
            by_side,
            materials: parts,
            exact,
        });
    }
    mixes
}

/// The textures that decide a surface's look with material `m`: a mix's
/// weight and, through it, those of the materials it chooses among.
fn deciding_textures<'a>(m: u32, materials: &'a [Material], mixes: &'a [Option<MaterialMix>], out: &mut Vec<Texture>) {
    match mixes.get(m as usize).and_then(Option::as_ref) {
        Some(mix) if out.len() < 64 * MAX_MIX_DEPTH => {
            out.push(mix.weight);
            for p in mix.materials {
                deciding_textures(p, materials, mixes, out);
            }
        }
        _ => out.extend(materials[m as usize].textures().into_iter().copied()),
    }
}

/// The mesh attribute (by number) a surface with material `m` reads, the
/// first if several, also as the input of a texture node (a light's image
/// scaled per triangle, say).
fn read_attribute(m: u32, materials: &[Material], mixes: &[Option<MaterialMix>], store: &TextureStore) -> Option<u32> {
    fn within(t: &Texture, store: &TextureStore, depth: usize) -> Option<u32> {
        match t {
            Texture::MeshAttribute(k) => Some(*k),
            Texture::Node(i) if depth < MAX_TEXTURE_DEPTH => store.nodes[*i as usize]
                .inputs()
                .into_iter()
                .find_map(|(_, input)| within(input, store, depth + 1)),
            _ => None,
        }
    }
    let mut t = Vec::new();
    deciding_textures(m, materials, mixes, &mut t);
    t.iter().find_map(|t| within(t, store, 0))
}

/// The render-time material of a description.
fn to_material(
    m: &MaterialDesc,
    color: &dyn Fn(&ColorSource) -> Texture,
    textures: &TextureStore,
    measured: &HashMap<&Path, Arc<MeasuredBrdf>>,
) -> Material {
    let mut mat = match &m.kind {
        MaterialKindDesc::Classic(c) => Material::new_classic(
            color(&c.diffuse),
            color(&c.specular),
            c.shininess,
            c.reflectivity,
            c.transmission,
            c.ior,
        ),
        MaterialKindDesc::Diffuse { reflectance } => Material::plain(MaterialKind::Diffuse {
            reflectance: color(reflectance),
        }),
        MaterialKindDesc::DiffuseTransmission {
            reflectance,
            transmittance,
        } => Material::plain(MaterialKind::DiffuseTransmission {
            reflectance: color(reflectance),
            transmittance: color(transmittance),
        }),
        MaterialKindDesc::Conductor {
            fresnel,
            tint,
            roughness,
            distribution,
        } => Material::plain(MaterialKind::Conductor {
            fresnel: match fresnel {
                ConductorDesc::Complex { eta, k } => ConductorFresnel::Complex { eta: *eta, k: *k },
                ConductorDesc::Reflectance(r) => ConductorFresnel::Schlick(*r),
                ConductorDesc::Mirror(r) => ConductorFresnel::Constant(*r),
            },
            tint: *tint,
            microfacet: Microfacet::new(*distribution, roughness.0, roughness.1),
        }),
        MaterialKindDesc::Dielectric {
            ior,
            ext_ior,
            roughness,
            distribution,
            reflect_tint,
            transmit_tint,
            dispersion,
        } => Material::plain(MaterialKind::Dielectric {
            eta: ior / ext_ior,
            microfacet: Microfacet::new(*distribution, roughness.0, roughness.1),
            reflect_tint: *reflect_tint,
            transmit_tint: *transmit_tint,
            dispersion: dispersion.as_ref().map(|inside| {
                Box::new(crate::material::dispersion::Dispersion {
                    inside: inside.clone(),
                    outside: *ext_ior,
                })
            }),
        }),
        MaterialKindDesc::Plastic {
            diffuse,
            ior,
            ext_ior,
            roughness,
            distribution,
            specular_tint,
            nonlinear,
        } => Material::plastic(
            color(diffuse),
            ior / ext_ior,
            Microfacet::new(*distribution, *roughness, *roughness),
            *specular_tint,
            *nonlinear,
            textures,
        ),
        MaterialKindDesc::Layered {
            base,
            coat_ior,
            coat_roughness,
            thickness,
            albedo,
            g,
            max_depth,
            samples,
            coat_dispersion,
        } => Material::plain(MaterialKind::Layered {
            base: match base {
                LayeredBaseDesc::Diffuse(r) => LayerBaseKind::Diffuse(color(r)),
                LayeredBaseDesc::Conductor {
                    fresnel,
                    roughness,
                    roughness_map,
                } => {
                    // The conductor lies in the coat: its indices are
                    // relative to the coat's (pbrt-v4's
                    // CoatedConductorMaterial). A reflectance becomes
                    // the index η = 1, k = 2√r/√(1 − r) that reflects it
                    // at normal incidence, as pbrt-v4 converts it.
                    let (eta, k) = match fresnel {
                        ConductorDesc::Complex { eta, k } => (*eta, *k),
                        ConductorDesc::Reflectance(r) | ConductorDesc::Mirror(r) => {
                            let r = r.min(Rgb::splat(0.9999));
                            let k = |x: f32| 2.0 * x.sqrt() / (1.0 - x).max(0.0).sqrt();
                            (Rgb::ONE, Rgb::new(k(r.x), k(r.y), k(r.z)))
                        }
                    };
                    // A roughness texture: the constant α becomes its
                    // average, as for a material's own map.
                    let base_map = roughness_map.as_ref().map(|r| RoughnessMap {
                        u: color(&r.u),
                        v: color(&r.v),
                        remap_sqrt: r.remap_sqrt,
                    });
                    let base_alpha = base_map.as_ref().map_or(*roughness, |m| m.average_alpha(textures));
                    LayerBaseKind::Conductor {
                        fresnel: ConductorFresnel::Complex {
                            eta: eta / *coat_ior,
                            k: k / *coat_ior,
                        },
                        microfacet: Microfacet::new(MicrofacetDistribution::Ggx, base_alpha.0, base_alpha.1),
                        roughness_map: base_map,
                    }
                }
            },
            coat_eta: *coat_ior,
            coat: Microfacet::new(MicrofacetDistribution::Ggx, coat_roughness.0, coat_roughness.1),
            thickness: *thickness,
            albedo: *albedo,
            phase: Phase::henyey_greenstein(*g),
            max_depth: *max_depth,
            samples: *samples,
            coat_dispersion: coat_dispersion.as_ref().map(|inside| {
                Box::new(crate::material::dispersion::Dispersion {
                    inside: inside.clone(),
                    outside: 1.0,
                })
            }),
        }),
        MaterialKindDesc::Thin {
            ior,
            ext_ior,
            reflect_tint,
            transmit_tint,
            dispersion,
        } => Material::plain(MaterialKind::Thin {
            eta: ior / ext_ior,
            reflect_tint: *reflect_tint,
            transmit_tint: *transmit_tint,
            dispersion: dispersion.as_ref().map(|inside| {
                Box::new(crate::material::dispersion::Dispersion {
                    inside: inside.clone(),
                    outside: *ext_ior,
                })
            }),
        }),
        MaterialKindDesc::Hair(h) => Material::plain(MaterialKind::Hair(*h)),
        MaterialKindDesc::Measured { file } => Material::plain(MaterialKind::Measured {
            brdf: measured[file.as_path()].clone(),
        }),
        MaterialKindDesc::Principled { params, eta, thin } => Material {
            two_sided: *thin,
            ..Material::plain(MaterialKind::Principled {
                params: Box::new(params.map(color)),
                eta: *eta,
                thin: *thin,
            })
        },
        // Replaced by `resolve_mixes` once every material is made.
        MaterialKindDesc::Mix { .. } => Material::default(),
    };
    mat.emission = color(&m.emission);
    mat.emits_both_sides = m.emits_both_sides;
    mat.two_sided = m.two_sided;
    mat.opacity = m.opacity.as_ref().map(color);
    mat.normal_map = m.normal_map.as_ref().map(|n| crate::material::NormalMap {
        texture: color(&n.texture),
        scale: n.scale,
        bitangent_along_v: n.bitangent_along_v,
    });
    mat.bump_map = m.bump_map.as_ref().map(|b| crate::material::BumpMap {
        height: color(&b.height),
        scale: b.scale,
    });
    if let Some(r) = &m.roughness_map {
        let map = RoughnessMap {
            u: color(&r.u),
            v: color(&r.v),
            remap_sqrt: r.remap_sqrt,
        };
        // The constant α the kind was built with becomes the textures'
        // average: the material is rough unless every texel is 0.
        let (au, av) = map.average_alpha(textures);
        // (Validation admits a map on conductors, dielectrics and the
        // coats of layered materials only.)
        if let MaterialKind::Conductor { microfacet, .. }
        | MaterialKind::Dielectric { microfacet, .. }
        | MaterialKind::Layered { coat: microfacet, .. } = &mut mat.kind
        {
            *microfacet = Microfacet::new(microfacet.distribution, au, av);
            mat.roughness_map = Some(map);
        }
    }
    mat
}

/// The world box of the unit cube under `to_world`.
fn unit_cube_in(to_world: &Transform) -> Aabb {
    to_world.aabb(&Aabb::new(Vec3::ZERO, Vec3::ONE))
}

/// The render-time medium of a description: its grids read, and its
/// bounds (the box of its σt grid) found.
fn to_medium(
    m: &MediumDesc,
    i: usize,
    base_dir: &Path,
    memory: &mut MemoryEstimate,
    limits: &BuildLimits,
    warnings: &mut Vec<String>,
) -> Result<Medium> {
    let mut field = |key: &str, f: &FieldDesc| -> Result<(Field, Option<Aabb>)> {
        let place = |ops: &[TransformOp]| {
            compose(ops).map_err(|e| Error::scene(m.locs.key(key), format!("medium[{i}].{key}"), e))
        };
        Ok(match f {
            FieldDesc::Constant(v) => (Field::Constant(*v), None),
            FieldDesc::Boxed { value, to_world } => (Field::Constant(*value), Some(unit_cube_in(&place(to_world)?))),
            FieldDesc::Grid {
                source,
                to_world,
                use_file_bounds,
            } => {
                let fail = |e: String| Error::scene(m.locs.key(key), format!("medium[{i}].{key}"), e);
                // A NanoVDB grid's unit cube is placed in the grid's space
                // first.
                let mut grid_to_space = None;
                let mut grid = match source {
                    GridSource::MitsubaVol(path) => {
                        VoxelGrid::load_mitsuba_vol(&base_dir.join(path)).map_err(|e| fail(reason_of(e)))?
                    }
                    GridSource::NanoVdb { path, grid } => {
                        let (g, to_space) = load_nanovdb(&base_dir.join(path), grid).map_err(fail)?;
                        grid_to_space = Some(to_space);
                        g
                    }
                    GridSource::Data(g) => (**g).clone(),
                };
                memory.textures += grid.data.len() as u64 * 4;
                memory.check(limits.max_memory)?;
                let bad = grid.sanitize();
                if bad > 0 {
                    warnings.push(format!(
                        "{}medium[{i}].{key}: {bad} values are NaN, infinite or negative; they are read as 0",
                        m.locs.key(key).map(|l| format!("{l}: ")).unwrap_or_default()
                    ));
                }
                let mut unit_to_world = place(to_world)?;
                if let Some(m) = grid_to_space {
                    unit_to_world = Transform::from_matrix(m)
                        .map_err(|e| fail(e.to_string()))?
                        .then(&unit_to_world);
                }
                if *use_file_bounds {
                    let (lo, hi) = grid.file_bounds;
                    let file_box = Transform::scale(hi - lo)
                        .map_err(|e| Error::scene(m.locs.key(key), format!("medium[{i}].{key}"), e.to_string()))?
                        .then(&Transform::translate(lo));
                    unit_to_world = file_box.then(&unit_to_world);
                }
                // A grid that reads 0 outside part of its cube bounds the
                // medium by that part.
                let bounds = match grid.support {
                    Some((lo, hi)) => unit_to_world.aabb(&Aabb::new(lo, hi)),
                    None => unit_cube_in(&unit_to_world),
                };
                (Field::Grid(Arc::new(grid), unit_to_world.inverse()), Some(bounds))
            }
            FieldDesc::Cloud {
                value,
                density,
                wispiness,
                frequency,
                p0,
                p1,
                to_world,
            } => {
                let to_world = place(to_world)?;
                let bounds = Aabb::new(*p0, *p1);
                let cloud = crate::media::CloudField {
                    value: *value,
                    density: *density,
                    wispiness: *wispiness,
                    frequency: *frequency,
                    bounds,
                    to_local: to_world.inverse(),
                };
                (Field::Cloud(Box::new(cloud)), Some(to_world.aabb(&bounds)))
            }
        })
    };
    let (sigma_t, bounds) = field("sigma_t", &m.sigma_t)?;
    let (albedo, _) = field("albedo", &m.albedo)?;
    let emission = match &m.emission {
        Some(e) => Some(field("emission", e)?.0),
        None => None,
    };
    Ok(Medium::new(
        bounds,
        sigma_t,
        albedo,
        emission,
        m.scale,
        Phase::henyey_greenstein(m.g),
    ))
}

/// The grid named `name` of NanoVDB file `path`, dense, and the map from
/// its unit cube to the grid's space; a grid with nothing active is one
/// empty voxel.
fn load_nanovdb(path: &Path, name: &str) -> std::result::Result<(VoxelGrid, glam::Mat4), String> {
    let in_file = |e: String| format!("{}: {e}", path.display());
    let bytes = crate::files::read_limited(path, crate::files::MAX_NANOVDB_BYTES).map_err(in_file)?;
    let grid = nanovdb_grid(&bytes, name).map_err(in_file)?;
    drop(bytes);
    Ok(match grid.to_voxel_grid().map_err(in_file)? {
        Some(dense) => dense,
        None => (VoxelGrid::new([1, 1, 1], 1, vec![0.0])?, glam::Mat4::IDENTITY),
    })
}

/// The grid `name` of a NanoVDB file's contents `bytes`, or an error that
/// names the grids the file has (the one meant, where it is a near miss).
pub(crate) fn nanovdb_grid(
    bytes: &[u8],
    name: &str,
) -> std::result::Result<crate::media::nanovdb::NanoVdbGrid, String> {
    use crate::media::nanovdb::{NanoVdbGrid, grid_names};
    match NanoVdbGrid::from_file(bytes, name)? {
        Some(grid) => Ok(grid),
        None => {
            let names = grid_names(bytes)?;
            Err(format!(
                "no grid named \"{name}\"{}",
                crate::scene::desc::suggest(name, names.iter().map(String::as_str))
            ))
        }
    }
}

/// The message of an error without the file name it already carries.
pub(crate) fn reason_of(e: Error) -> String {
    match e {
        Error::File { path, message } => format!("{}: {message}", path.display()),
        other => other.to_string(),
    }
}

/// Composes transform steps: the first listed is applied first.
pub fn compose(ops: &[TransformOp]) -> Result<Transform, String> {
    let mut t = Transform::IDENTITY;
    for op in ops {
        let step = op.to_transform().map_err(|e| format!("{}: {e}", op.name()))?;
        t = t.then(&step);
    }
    Ok(t)
}

/// Loads a mesh; a mesh file's warnings go to `warnings`.
/// What displacing a mesh reads: the textures built, by name.
struct Heights<'a> {
    textures: &'a HashMap<&'a str, Texture>,
    store: &'a TextureStore,
}

/// Most triangles a displaced mesh may be cut into.
const MAX_DISPLACED_TRIANGLES: usize = 1 << 25;

fn load_mesh_source(
    src: &MeshSource,
    base_dir: &Path,
    locs: &Locs,
    what: &str,
    warnings: &mut Vec<String>,
    to_world: &Transform,
    heights: &Heights,
) -> Result<TriangleMesh> {
    let mesh = match src {
        MeshSource::Displaced {
            mesh,
            height,
            edge_length,
            power,
        } => {
            let base = read_mesh_source(mesh, base_dir, locs, what, warnings)?;
            let texture = heights.textures[height.as_str()];
            // As pbrt-v4: edges measured after the shape's transform, the
            // texture read at the object-space point and its (u, v).
            let displaced = crate::geometry::displacement::displace(
                &base,
                |a, b| to_world.point(a).distance(to_world.point(b)),
                *edge_length,
                |p, uv| {
                    let c = texture.eval(heights.store, &TexCoord::new(uv, p));
                    (c.x + c.y + c.z) / 3.0
                },
                MAX_DISPLACED_TRIANGLES,
            )
            .map_err(|e| Error::scene(locs.key("edge_length").or(locs.item.clone()), what, e.to_string()))?;
            match power {
                None => displaced,
                Some(p) => with_triangle_power(displaced, p, to_world),
            }
        }
        _ => read_mesh_source(src, base_dir, locs, what, warnings)?,
    };
    let degenerate = (0..mesh.len())
        .filter(|&i| {
            let [a, b, c] = mesh.vertices(i);
            (b - a).cross(c - a).length_squared() == 0.0
        })
        .count();
    if degenerate > 0 {
        warnings.push(format!(
            "{}{what}: {degenerate} of {} triangles have zero area; they are never hit and emit no light",
            locs.item.as_ref().map(|l| format!("{l}: ")).unwrap_or_default(),
            mesh.len()
        ));
    }
    Ok(mesh)
}

/// `mesh` with the per-face attribute of [`TrianglePower`]: each
/// triangle's radiance from its area after `to_world` (zero for a
/// degenerate one, which is never hit).
fn with_triangle_power(mut mesh: TriangleMesh, p: &TrianglePower, to_world: &Transform) -> TriangleMesh {
    let values = (0..mesh.len())
        .flat_map(|i| {
            let [a, b, c] = mesh.vertices(i).map(|v| to_world.point(v));
            let k_e = p.per_area * 0.5 * (b - a).cross(c - a).length();
            let l = if k_e > 0.0 && k_e.is_finite() {
                p.radiance * (p.power / k_e)
            } else {
                Rgb::ZERO
            };
            l.to_array()
        })
        .collect();
    mesh.attributes.push(crate::geometry::mesh::MeshAttribute {
        name: p.attribute.clone(),
        per_face: true,
        channels: 3,
        values,
    });
    mesh
}

fn read_mesh_source(
    src: &MeshSource,
    base_dir: &Path,
    locs: &Locs,
    what: &str,
    warnings: &mut Vec<String>,
) -> Result<TriangleMesh> {
    match src {
        MeshSource::Inline(m) => Ok(m.clone()),
        MeshSource::Displaced { .. } => unreachable!("validation refuses a displaced mesh inside another"),
        MeshSource::UvSphere { segments, rings } => {
            Ok(TriangleMesh::uv_sphere(glam::Vec3::ZERO, 1.0, *segments, *rings))
        }
        MeshSource::File(path) => {
            let full = base_dir.join(path);
            let ext = full.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
            if !matches!(ext.as_deref(), Some("obj" | "ply")) {
                return Err(Error::scene(
                    locs.key("file"),
                    format!("{what}.file"),
                    format!(
                        "{}: unsupported mesh format (the native format reads .obj and .ply files)",
                        full.display()
                    ),
                ));
            }
            if let Err(e) = std::fs::metadata(&full) {
                return Err(Error::scene(
                    locs.key("file"),
                    format!("{what}.file"),
                    format!("cannot read mesh {}: {}", full.display(), io_reason(&e)),
                ));
            }
            let in_file = |e| Error::scene(locs.key("file"), format!("{what}.file"), reason_of(e));
            if ext.as_deref() == Some("ply") {
                let ply = super::ply::read_ply(&full).map_err(in_file)?;
                warnings.extend(ply.warnings);
                Ok(ply.mesh)
            } else {
                super::obj::load_obj_mesh(&full).map_err(in_file)
            }
        }
    }
}

/// The illuminance pbrt-v4 computes for an equal-area environment map's
/// upper hemisphere (+z of its frame) to honour an `illuminance`
/// (`Light::Create`, "infinite"): Σ luminance · cos θ over the pixels
/// whose centres lie above the horizon, × 2π/N for N pixels. (Each pixel
/// subtends 4π/N steradians, so this is half the map's illuminance; a
/// scene that asks for E gets twice that, in pbrt-v4 and so here.)
fn pbrt_upper_hemisphere_illuminance(image: &ImageTexture) -> f32 {
    let (w, h) = (image.width as usize, image.height as usize);
    let mut sum = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let uv = glam::Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let d = crate::sampling::warp::equal_area_square_to_sphere(uv);
            if d.z > 0.0 {
                sum += (crate::color::luminance(image.pixels[y * w + x]) * d.z) as f64;
            }
        }
    }
    (sum * 2.0 * std::f64::consts::PI / (w * h).max(1) as f64) as f32
}

fn to_light(
    index: usize,
    light: &LightDesc,
    color: &dyn Fn(&ColorSource) -> Texture,
    textures: &TextureStore,
) -> Result<Light> {
    let texture = |name: &str| color(&ColorSource::Texture(name.to_string()));
    Ok(match light.kind {
        LightKind::Point {
            position,
            intensity,
            falloff,
        } => Light::Point {
            position,
            intensity,
            falloff,
        },
        LightKind::Spot {
            position,
            to,
            intensity,
            inner_angle,
            outer_angle,
            profile,
            ref projection,
            falloff,
        } => Light::Spot {
            position,
            direction: (to - position).normalize(),
            intensity,
            cos_inner: inner_angle.to_radians().cos(),
            cos_outer: outer_angle.to_radians().cos(),
            profile,
            projection: projection.as_ref().map(|p| SpotProjection {
                to_local: p.to_world.inverse(),
                tan_outer: outer_angle.to_radians().tan(),
                texture: texture(&p.texture),
            }),
            falloff,
        },
        LightKind::Projector {
            position,
            to_world,
            fov,
            fov_axis,
            ref irradiance,
            scale,
            law,
            power,
        } => {
            let image = color(irradiance);
            // The frame has the image's proportions (a constant: square).
            let (w, h) = match image {
                Texture::Image { image, .. } => {
                    let i = &textures.images[image as usize];
                    (i.width, i.height)
                }
                _ => (1, 1),
            };
            let mut projector = Projector {
                position,
                to_world,
                to_local: to_world.inverse(),
                tan_half: fov_axis.tan_half(fov, w, h),
                scale: match law {
                    ProjectorLaw::PlaneIrradiance => std::f32::consts::PI * scale,
                    ProjectorLaw::RadiantIntensity => scale,
                },
                image,
                law,
            };
            if let Some(power) = power {
                // As pbrt-v4: the scale then multiplies what makes the
                // power this. An image of no light keeps its scale: it
                // emits nothing whatever the scale.
                let per_scale = projector.power_per_scale(textures);
                if per_scale > 0.0 {
                    projector.scale *= power / per_scale;
                }
            }
            Light::Projector(Box::new(projector))
        }
        LightKind::Goniometric {
            position,
            to_world,
            intensity,
            ref image,
            power,
        } => {
            let Texture::Image { image: i, .. } = texture(image) else {
                unreachable!("a goniometric light's image is an image texture")
            };
            let img = &textures.images[i as usize];
            if img.width != img.height {
                return Err(Error::scene(
                    light.locs.key("image"),
                    format!("light[{index}].image"),
                    format!(
                        "a goniometric light's image must be square (pbrt-v4's equal-area layout); this one is {}×{}",
                        img.width, img.height
                    ),
                ));
            }
            let values: Vec<f32> = img.pixels.iter().map(|c| ((c.x + c.y + c.z) / 3.0).max(0.0)).collect();
            let mut g = Goniometric::new(position, to_world, intensity, img.width as usize, values);
            if let Some(power) = power {
                // pbrt-v4 multiplies the intensity by power over 4π × the
                // image's mean (as for a point light, the colour's own
                // brightness stays); an image of no light stays dark.
                if g.mean_value() > 0.0 {
                    g.intensity *= power / (4.0 * std::f32::consts::PI * g.mean_value());
                }
            }
            Light::Goniometric(Box::new(g))
        }
        LightKind::Directional { direction, irradiance } => Light::Directional {
            direction: direction.normalize(),
            irradiance,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;
    use glam::Vec3;

    /// Mitsuba's and the native format's `measured` read the same file as
    /// pbrt-v4's (whose reader test renders it), one copy a file.
    #[test]
    fn measured_materials_of_every_format_share_their_tables() {
        use crate::material::measured::fixture::{ggx_file, thetas};
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("ggx.bsdf"), ggx_file(0.3, 0.8, 9, &thetas())).unwrap();
        let xml = dir.path().join("s.xml");
        std::fs::write(
            &xml,
            r#"<scene version="3.0.0">
                <bsdf type="measured" id="a"><string name="filename" value="ggx.bsdf"/></bsdf>
                <shape type="sphere"><ref id="a"/></shape>
                <shape type="sphere"><bsdf type="measured"><string name="filename" value="ggx.bsdf"/></bsdf></shape>
            </scene>"#,
        )
        .unwrap();
        let scene = build(&crate::scene::load(&xml, &[]).unwrap()).unwrap();
        let tables: Vec<_> = scene
            .materials
            .iter()
            .filter_map(|m| match &m.kind {
                MaterialKind::Measured { brdf } => Some(brdf.clone()),
                _ => None,
            })
            .collect();
        assert_eq!(tables.len(), 2);
        assert!(Arc::ptr_eq(&tables[0], &tables[1]), "one copy of the file");
        assert!(!scene.materials[0].two_sided, "Mitsuba's is one-sided");
        std::fs::write(
            &xml,
            r#"<scene version="3.0.0"><shape type="sphere"><bsdf type="measured"><string name="filename" value="gone.bsdf"/></bsdf></shape></scene>"#,
        )
        .unwrap();
        let e = crate::scene::load(&xml, &[]).unwrap_err().to_string();
        assert!(
            e.contains("measured BSDF file not found") && e.contains("gone.bsdf"),
            "{e}"
        );

        let toml = dir.path().join("s.toml");
        std::fs::write(
            &toml,
            "[[material]]\nname = \"m\"\ntype = \"measured\"\nfile = \"ggx.bsdf\"\n\n\
             [[shape]]\ntype = \"sphere\"\nmaterial = \"m\"\n",
        )
        .unwrap();
        let scene = build(&crate::scene::load(&toml, &[]).unwrap()).unwrap();
        assert!(matches!(scene.materials[0].kind, MaterialKind::Measured { .. }) && scene.materials[0].two_sided);
        std::fs::write(&toml, "[[material]]\nname = \"m\"\ntype = \"measured\"\n").unwrap();
        let e = crate::scene::load(&toml, &[]).unwrap_err().to_string();
        assert!(e.contains("file"), "{e}");
    }

    /// Surface records carry (u, v) where the material reads them, and a
    /// sphere whose material reads none skips them (they are zero).
    #[test]
    fn surface_coordinates_where_the_material_reads_them() {
        let text = r#"
[[texture]]
name = "checks"
type = "checkerboard"

[[material]]
name = "checked"
type = "diffuse"
reflectance = "checks"

[[material]]
name = "plain"
type = "diffuse"
reflectance = 0.5

[[shape]]
type = "sphere"
center = [-2, 0, 0]
radius = 1
material = "checked"

[[shape]]
type = "sphere"
center = [2, 0, 0]
radius = 1
material = "plain"
"#;
        let desc = crate::scene::native::parse(text, std::path::Path::new("uv.toml")).unwrap();
        let scene = build(&desc).unwrap();
        // (The last material is the default one that the build adds.)
        assert_eq!(scene.materials_reading_uv[..2], [true, false]);
        let toward = |x: f32| scene.intersect(&Ray::new(Vec3::new(x, 0.3, 5.0), Vec3::new(0.0, 0.0, -1.0)));
        let checked = toward(-2.0).unwrap();
        let expected = crate::geometry::Shape::Sphere(crate::geometry::Sphere::new(Vec3::new(-2.0, 0.0, 0.0), 1.0))
            .surface(checked.p)
            .uv;
        assert!((checked.uv - expected).length() < 1e-6 && checked.uv != glam::Vec2::ZERO);
        assert_eq!(toward(2.0).unwrap().uv, glam::Vec2::ZERO);
    }
}
