//! The glTF 2.0 reader: small .gltf and .glb files built here from JSON and
//! binary buffers, read through `scene::load`, checked in the description,
//! in the built scene, in rendered pixels and through the command line.

use assert_cmd::Command;
use std::path::{Path, PathBuf};
use trazo::geometry::Transform;
use trazo::render::render_image;
use trazo::sampling::SamplerKind;
use trazo::scene::desc::*;
use trazo::scene::{build, load};
use trazo::{Rgb, Vec3};

/// Binary data, buffer views and accessors of a glTF asset under
/// construction; everything lives in buffer 0.
#[derive(Default)]
struct Asset {
    bin: Vec<u8>,
    views: Vec<String>,
    accessors: Vec<String>,
}

impl Asset {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.views.push(format!(
            r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{}}}"#,
            bytes.len()
        ));
        self.views.len() - 1
    }

    fn floats(&mut self, values: &[f32], ty: &str) -> usize {
        let comps = match ty {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            _ => 4,
        };
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessors.push(format!(
            r#"{{"bufferView":{view},"componentType":5126,"count":{},"type":"{ty}"}}"#,
            values.len() / comps
        ));
        self.accessors.len() - 1
    }

    fn indices(&mut self, values: &[u16]) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessors.push(format!(
            r#"{{"bufferView":{view},"componentType":5123,"count":{},"type":"SCALAR"}}"#,
            values.len()
        ));
        self.accessors.len() - 1
    }

    /// A unit square in the xy plane facing +z, with glTF texture
    /// coordinates ((0, 0) at its top-left corner); returns the JSON of a
    /// primitive's `attributes` and `indices`.
    fn square(&mut self) -> String {
        self.square_with_uv(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    }

    /// [`Asset::square`] with the texture coordinates `uv` at its corners
    /// (bottom-left, bottom-right, top-right, top-left).
    fn square_with_uv(&mut self, uv: &[f32; 8]) -> String {
        let p = self.floats(
            &[-0.5, -0.5, 0.0, 0.5, -0.5, 0.0, 0.5, 0.5, 0.0, -0.5, 0.5, 0.0],
            "VEC3",
        );
        let n = self.floats(&[0.0, 0.0, 1.0].repeat(4), "VEC3");
        let t = self.floats(uv, "VEC2");
        let i = self.indices(&[0, 1, 2, 0, 2, 3]);
        format!(r#""attributes":{{"POSITION":{p},"NORMAL":{n},"TEXCOORD_0":{t}}},"indices":{i}"#)
    }

    /// A 2 × 2 square in the xz plane facing +y.
    fn floor(&mut self) -> String {
        let p = self.floats(
            &[-1.0, 0.0, -1.0, -1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0, -1.0],
            "VEC3",
        );
        let i = self.indices(&[0, 1, 2, 0, 2, 3]);
        format!(r#""attributes":{{"POSITION":{p}}},"indices":{i}"#)
    }

    /// The whole JSON: buffer 0 (with `uri` if given), views, accessors and
    /// the other top-level members in `body`.
    fn json(&self, uri: Option<&str>, body: &str) -> String {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{{}"byteLength":{}}}],"bufferViews":[{}],"accessors":[{}],{body}}}"#,
            uri.map(|u| format!(r#""uri":"{u}","#)).unwrap_or_default(),
            self.bin.len(),
            self.views.join(","),
            self.accessors.join(",")
        )
    }

    fn write_glb(&self, path: &Path, body: &str) {
        std::fs::write(path, glb(&self.json(None, body), &self.bin)).unwrap();
    }

    fn write_embedded(&self, path: &Path, body: &str) {
        let uri = format!("data:application/octet-stream;base64,{}", base64(&self.bin));
        std::fs::write(path, self.json(Some(&uri), body)).unwrap();
    }

    fn write_with_bin(&self, path: &Path, bin_name: &str, body: &str) {
        std::fs::write(path.with_file_name(bin_name), &self.bin).unwrap();
        std::fs::write(path, self.json(Some(bin_name), body)).unwrap();
    }
}

/// A GLB container (glTF 2.0 §4.4) of a JSON chunk and a BIN chunk.
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while b.len() % 4 != 0 {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + if b.is_empty() { 0 } else { 8 + b.len() };
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    if !b.is_empty() {
        out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&b);
    }
    out
}

fn base64(data: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for chunk in data.chunks(3) {
        let n = chunk
            .iter()
            .enumerate()
            .fold(0u32, |acc, (i, &b)| acc | (b as u32) << (16 - 8 * i));
        for i in 0..4 {
            if i <= chunk.len() {
                s.push(A[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// An emissive, black (so that only the emission shows) material.
const GLOW: &str =
    r#"{"pbrMetallicRoughness":{"baseColorFactor":[0,0,0,1],"metallicFactor":0},"emissiveFactor":[1,1,1]}"#;

/// The index of the first shape's material, in the description and in
/// the scene built from it.
fn first_shape_material(d: &SceneDesc) -> usize {
    d.materials
        .iter()
        .position(|m| Some(&m.name) == d.shapes[0].material.as_ref())
        .expect("the first shape's material")
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// Where `shape` puts the local point `p`.
fn world_point(shape: &ShapeDesc, p: Vec3) -> Vec3 {
    let mut t = Transform::IDENTITY;
    for op in &shape.transform {
        t = t.then(&op.to_transform().unwrap());
    }
    t.point(p)
}

fn inline_mesh(shape: &ShapeDesc) -> &trazo::geometry::TriangleMesh {
    match &shape.kind {
        ShapeKind::InlineMesh(MeshSource::Inline(m)) => m,
        other => panic!("expected an inline mesh, got {other:?}"),
    }
}

#[test]
fn child_nodes_compose_parent_transforms() {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    // Parent: translate (10, 0, 0), rotate 90° about +z, scale 2; the
    // child sits at (1, 0, 0) in the parent's frame → 2·Rz(90°)·(1, 0, 0)
    // + (10, 0, 0) = (10, 2, 0).
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let body = format!(
        r#""scenes":[{{"nodes":[0]}}],"nodes":[
            {{"translation":[10,0,0],"rotation":[0,0,{s},{s}],"scale":[2,2,2],"children":[1]}},
            {{"matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0, 1,0,0,1],"mesh":0}}],
            "meshes":[{{"primitives":[{{{prim}}}]}}]"#
    );
    let path = dir.path().join("tree.gltf");
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    assert_eq!(d.shapes.len(), 1);
    let origin = world_point(&d.shapes[0], Vec3::ZERO);
    assert!((origin - Vec3::new(10.0, 2.0, 0.0)).length() < 1e-5, "{origin}");
    // The child's local +x runs along world +y, twice as long.
    let x = world_point(&d.shapes[0], Vec3::X) - origin;
    assert!((x - Vec3::new(0.0, 2.0, 0.0)).length() < 1e-5, "{x}");
    assert_eq!(inline_mesh(&d.shapes[0]).len(), 2);
}

#[test]
fn a_mesh_placed_by_two_nodes_is_instanced() {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    let body = format!(
        r#""scene":0,"scenes":[{{"nodes":[0,1]}}],"nodes":[
            {{"mesh":0,"translation":[-2,0,0]}},{{"mesh":0,"translation":[2,0,0]}}],
            "meshes":[{{"primitives":[{{{prim}}}]}}]"#
    );
    let path = dir.path().join("two.glb");
    a.write_glb(&path, &body);
    let d = load(&path, &[]).unwrap();
    assert_eq!(d.meshes.len(), 1, "one named mesh for the shared primitive");
    assert!(d.shapes.iter().all(|s| matches!(s.kind, ShapeKind::Mesh(_))));
    let scene = build(&d).unwrap();
    assert_eq!(scene.geometry.instances.len(), 2);
    assert!(scene.geometry.mesh_objects.is_empty());
}

/// Renders a scene with a camera at +z looking down −z (glTF's
/// convention) at a glowing square placed at `at`; returns the image.
fn render_glowing_square(at: [f32; 3]) -> trazo::film::Image {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.square();
    let body = format!(
        r#""scenes":[{{"nodes":[0,1]}}],"nodes":[
            {{"camera":0,"translation":[0,0,4]}},
            {{"mesh":0,"translation":[{},{},{}],"scale":[0.6,0.6,0.6]}}],
            "cameras":[{{"type":"perspective","perspective":{{"yfov":0.8,"aspectRatio":1.0,"znear":0.01}}}}],
            "materials":[{GLOW}],
            "meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#,
        at[0], at[1], at[2]
    );
    let path = dir.path().join("cam.gltf");
    a.write_embedded(&path, &body);
    let mut d = load(&path, &[]).unwrap();
    assert_eq!((d.settings.width, d.settings.height), (640, 640), "aspectRatio 1");
    d.settings.width = 16;
    d.settings.height = 16;
    d.settings.spp = 4;
    render_image(&build(&d).unwrap()).unwrap()
}

fn quadrant_sums(img: &trazo::film::Image) -> [[f32; 2]; 2] {
    let mut s = [[0.0; 2]; 2];
    for y in 0..img.height {
        for x in 0..img.width {
            let row = (y >= img.height / 2) as usize;
            let col = (x >= img.width / 2) as usize;
            s[row][col] += img.get(x, y).element_sum();
        }
    }
    s
}

#[test]
fn gltf_camera_x_is_image_right_and_y_is_image_up() {
    // At +x: the right half of the image.
    let s = quadrant_sums(&render_glowing_square([0.9, 0.0, 0.0]));
    let (left, right) = (s[0][0] + s[1][0], s[0][1] + s[1][1]);
    assert!(right > 10.0 && left < 0.05 * right, "left {left}, right {right}");
    // At +y: the top half (rows from the top).
    let s = quadrant_sums(&render_glowing_square([0.0, 0.9, 0.0]));
    let (top, bottom) = (s[0][0] + s[0][1], s[1][0] + s[1][1]);
    assert!(top > 10.0 && bottom < 0.05 * top, "top {top}, bottom {bottom}");
    // Behind the camera (+z beyond it): nothing is seen.
    let s = quadrant_sums(&render_glowing_square([0.0, 0.0, 6.0]));
    assert_eq!(s.iter().flatten().sum::<f32>(), 0.0);
}

#[test]
fn perspective_and_orthographic_cameras() {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    let body = |camera: &str| {
        format!(
            r#""scenes":[{{"nodes":[0,1]}}],"nodes":[{{"camera":0,"translation":[0,1,5]}},{{"mesh":0}}],
            "cameras":[{camera}],"meshes":[{{"primitives":[{{{prim}}}]}}]"#
        )
    };
    let path = dir.path().join("p.gltf");
    a.write_embedded(
        &path,
        &body(r#"{"type":"perspective","perspective":{"yfov":0.5,"aspectRatio":2.0,"znear":0.1}}"#),
    );
    let d = load(&path, &[]).unwrap();
    let ProjectionDesc::Perspective { fov } = d.camera.projection else {
        panic!("{:?}", d.camera.projection)
    };
    assert!((fov - 0.5f32.to_degrees()).abs() < 1e-4, "{fov}");
    assert_eq!((d.settings.width, d.settings.height), (640, 320));
    // Camera-space +z (forward) maps to world −z; the eye sits at the node.
    let m = d.camera.to_world.unwrap();
    assert!((m.transform_vector3(Vec3::Z) - Vec3::NEG_Z).length() < 1e-6);
    assert!((m.transform_point3(Vec3::ZERO) - Vec3::new(0.0, 1.0, 5.0)).length() < 1e-6);

    // No aspect ratio: 4:3.
    a.write_embedded(
        &path,
        &body(r#"{"type":"perspective","perspective":{"yfov":0.5,"znear":0.1}}"#),
    );
    let d = load(&path, &[]).unwrap();
    assert_eq!((d.settings.width, d.settings.height), (640, 480));

    a.write_embedded(
        &path,
        &body(r#"{"type":"orthographic","orthographic":{"xmag":2,"ymag":1,"znear":0,"zfar":10}}"#),
    );
    let d = load(&path, &[]).unwrap();
    assert_eq!(d.camera.projection, ProjectionDesc::Orthographic { size: 2.0 });
    assert_eq!((d.settings.width, d.settings.height), (640, 320));
    assert!(
        d.warnings.iter().any(|w| w.contains("clipping planes")),
        "{:?}",
        d.warnings
    );

    // Without a camera the scene is framed from the front and above.
    let body = format!(r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{{prim}}}]}}]"#);
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    assert!(d.camera.to_world.is_none());
    assert!(d.camera.from.y > 0.0 && d.camera.from.z > 0.0 && d.camera.to.length() < 1e-6);
}

#[test]
fn materials_map_to_conductor_plastic_dielectric_and_diffuse() {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    let materials = r#"[
        {"pbrMetallicRoughness":{"baseColorFactor":[0.9,0.6,0.2,1],"metallicFactor":1,"roughnessFactor":0.5}},
        {"pbrMetallicRoughness":{"baseColorFactor":[0.2,0.3,0.4,1],"metallicFactor":0,"roughnessFactor":0.6},"doubleSided":true},
        {"pbrMetallicRoughness":{"metallicFactor":0,"roughnessFactor":0},"extensions":{"KHR_materials_ior":{"ior":1.33}},"doubleSided":true},
        {"pbrMetallicRoughness":{"baseColorFactor":[0.9,1,0.9,1],"metallicFactor":0,"roughnessFactor":0.1},
         "extensions":{"KHR_materials_transmission":{"transmissionFactor":1},"KHR_materials_ior":{"ior":1.6}},"doubleSided":true},
        {"pbrMetallicRoughness":{"metallicFactor":0},"extensions":{"KHR_materials_ior":{"ior":1.0}},"doubleSided":true}
    ]"#;
    let nodes: Vec<String> = (0..6).map(|i| format!(r#"{{"mesh":{i}}}"#)).collect();
    let meshes: Vec<String> = (0..5)
        .map(|i| format!(r#"{{"primitives":[{{{prim},"material":{i}}}]}}"#))
        .chain([format!(r#"{{"primitives":[{{{prim}}}]}}"#)])
        .collect();
    let body = format!(
        r#""scenes":[{{"nodes":[0,1,2,3,4,5]}}],"nodes":[{}],"materials":{materials},"meshes":[{}]"#,
        nodes.join(","),
        meshes.join(",")
    );
    let path = dir.path().join("m.gltf");
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    let kind = |name: &str| &d.materials.iter().find(|m| m.name == name).unwrap().kind;
    assert_eq!(
        kind("materials[0]"),
        &MaterialKindDesc::Conductor {
            fresnel: ConductorDesc::Reflectance(Rgb::new(0.9, 0.6, 0.2)),
            tint: Rgb::ONE,
            roughness: (0.25, 0.25),
            distribution: MicrofacetDistribution::Ggx,
        }
    );
    let MaterialKindDesc::Plastic {
        diffuse,
        ior,
        ext_ior,
        roughness,
        ..
    } = kind("materials[1]")
    else {
        panic!("{:?}", kind("materials[1]"))
    };
    assert_eq!(diffuse, &ColorSource::Rgb(Rgb::new(0.2, 0.3, 0.4)));
    assert_eq!((*ior, *ext_ior), (1.5, 1.0));
    assert!((roughness - 0.36).abs() < 1e-6, "α = roughness²");
    assert!(
        matches!(kind("materials[2]"), MaterialKindDesc::Plastic { ior, roughness, .. } if *ior == 1.33 && *roughness == 0.0)
    );
    assert_eq!(
        kind("materials[3]"),
        &MaterialKindDesc::Dielectric {
            ior: 1.6,
            ext_ior: 1.0,
            roughness: (0.1f32 * 0.1, 0.1f32 * 0.1),
            distribution: MicrofacetDistribution::Ggx,
            reflect_tint: Rgb::ONE,
            transmit_tint: Rgb::new(0.9, 1.0, 0.9),
            dispersion: None,
        }
    );
    assert!(matches!(kind("materials[4]"), MaterialKindDesc::Diffuse { .. }));
    // §3.9.6: the default material is a rough white metal.
    assert!(matches!(
        kind("glTF default material"),
        MaterialKindDesc::Conductor {
            roughness: (1.0, 1.0),
            ..
        }
    ));
    // doubleSided false (the default) → one-sided, with a warning.
    let m0 = d.materials.iter().find(|m| m.name == "materials[0]").unwrap();
    assert!(!m0.two_sided);
    assert!(d.materials.iter().find(|m| m.name == "materials[1]").unwrap().two_sided);
    assert!(d.warnings.iter().any(|w| w.contains("single-sided")));
    assert!(build(&d).is_ok());
}

/// An image encoded as PNG.
fn png_bytes(img: impl Into<image::DynamicImage>) -> Vec<u8> {
    let mut png = Vec::new();
    img.into()
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png
}

/// A 2 × 2 PNG: red, green / blue, white (top row first).
fn png_2x2() -> Vec<u8> {
    let mut img = image::RgbImage::new(2, 2);
    img.put_pixel(0, 0, image::Rgb([255, 0, 0]));
    img.put_pixel(1, 0, image::Rgb([0, 255, 0]));
    img.put_pixel(0, 1, image::Rgb([0, 0, 255]));
    img.put_pixel(1, 1, image::Rgb([255, 255, 255]));
    png_bytes(img)
}

/// The glowing square seen face-on by an orthographic camera that frames
/// it exactly; the emission comes from texture 0 (`images` is the JSON
/// of the images array, `tex` extra keys of the texture reference).
fn textured_square_body(a: &mut Asset, images: &str, tex: &str, strength: f32) -> String {
    let prim = a.square();
    format!(
        r#""scenes":[{{"nodes":[0,1]}}],"nodes":[{{"camera":0,"translation":[0,0,3]}},{{"mesh":0}}],
        "cameras":[{{"type":"orthographic","orthographic":{{"xmag":0.5,"ymag":0.5,"znear":0,"zfar":10}}}}],
        "images":{images},"textures":[{{"source":0}}],
        "materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0,0,0,1],"metallicFactor":0}},
          "emissiveFactor":[1,1,1],"emissiveTexture":{{"index":0{tex}}},
          "extensions":{{"KHR_materials_emissive_strength":{{"emissiveStrength":{strength}}}}}}}],
        "meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#
    )
}

fn render_2x2(mut d: SceneDesc) -> trazo::film::Image {
    d.settings.width = 2;
    d.settings.height = 2;
    d.settings.spp = 1;
    d.settings.sampler = SamplerKind::Center;
    render_image(&build(&d).unwrap()).unwrap()
}

fn close(a: Rgb, b: Rgb) -> bool {
    (a - b).abs().max_element() < 1e-3
}

#[test]
fn png_embedded_in_a_glb_reaches_the_image_with_gltf_texture_orientation() {
    let dir = tmp();
    let mut a = Asset::default();
    let png = a.view(&png_2x2());
    let body = textured_square_body(
        &mut a,
        &format!(r#"[{{"bufferView":{png},"mimeType":"image/png"}}]"#),
        "",
        1.0,
    );
    let path = dir.path().join("tex.glb");
    a.write_glb(&path, &body);
    let d = load(&path, &[]).unwrap();
    assert!(matches!(
        &d.textures[0].kind,
        TextureKind::Image {
            source: ImageSource::Data(_),
            ..
        }
    ));
    assert!(matches!(&d.materials[0].emission, ColorSource::Texture(_)));
    let img = render_2x2(d);
    // The image's top-left texel shows at the top left of the square.
    assert!(close(img.get(0, 0), Rgb::new(1.0, 0.0, 0.0)), "{}", img.get(0, 0));
    assert!(close(img.get(1, 0), Rgb::new(0.0, 1.0, 0.0)), "{}", img.get(1, 0));
    assert!(close(img.get(0, 1), Rgb::new(0.0, 0.0, 1.0)), "{}", img.get(0, 1));
    assert!(close(img.get(1, 1), Rgb::ONE), "{}", img.get(1, 1));
}

#[test]
fn emission_is_factor_times_texture_times_strength_and_texture_transforms_apply() {
    let dir = tmp();
    // An external PNG file, a data-URI buffer; strength 3.
    std::fs::write(dir.path().join("my tex.png"), png_2x2()).unwrap();
    let mut a = Asset::default();
    let body = textured_square_body(&mut a, r#"[{"uri":"my%20tex.png"}]"#, "", 3.0);
    let path = dir.path().join("e.gltf");
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    let TextureKind::Image { source, tint, .. } = &d.textures[0].kind else {
        panic!()
    };
    assert_eq!(source, &ImageSource::File(PathBuf::from("my tex.png")));
    assert_eq!(*tint, Rgb::splat(3.0));
    let img = render_2x2(d);
    assert!(close(img.get(0, 0), Rgb::new(3.0, 0.0, 0.0)), "{}", img.get(0, 0));

    // KHR_texture_transform: offset by half the texture in u → the
    // columns swap.
    let transformed = |transform: &str| {
        let mut a = Asset::default();
        let extension = format!(r#","extensions":{{"KHR_texture_transform":{transform}}}"#);
        let body = textured_square_body(&mut a, r#"[{"uri":"my%20tex.png"}]"#, &extension, 1.0);
        a.write_embedded(&path, &body);
        load(&path, &[]).unwrap()
    };
    let img = render_2x2(transformed(r#"{"offset":[0.5,0]}"#));
    assert!(close(img.get(0, 0), Rgb::new(0.0, 1.0, 0.0)), "{}", img.get(0, 0));
    assert!(close(img.get(0, 1), Rgb::ONE), "{}", img.get(0, 1));

    // Turned a quarter: the extension's R takes (u, v) to (−v, u), so the
    // pixel at glTF (u, v) shows the texel at (1 − v, u) (repeating):
    // green, white over red, blue.
    let d = transformed(r#"{"rotation":1.5707963267948966}"#);
    assert!(!d.warnings.iter().any(|w| w.contains("rotation")), "{:?}", d.warnings);
    let img = render_2x2(d);
    for ((x, y), texel) in [
        ((0, 0), Rgb::new(0.0, 1.0, 0.0)),
        ((1, 0), Rgb::ONE),
        ((0, 1), Rgb::new(1.0, 0.0, 0.0)),
        ((1, 1), Rgb::new(0.0, 0.0, 1.0)),
    ] {
        assert!(close(img.get(x, y), texel), "({x}, {y}): {}", img.get(x, y));
    }

    // A plain emissive factor.
    let mut a = Asset::default();
    let prim = a.floor();
    let body = format!(
        r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "materials":[{{"emissiveFactor":[1,0.5,0.25],"extensions":{{"KHR_materials_emissive_strength":{{"emissiveStrength":4}}}}}}],
        "meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#
    );
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    assert_eq!(d.materials[0].emission, ColorSource::Rgb(Rgb::new(4.0, 2.0, 1.0)));
    assert!(d.lights.is_empty(), "emissive scenes get no studio lights");
    assert!(
        build(&d)
            .unwrap()
            .lights
            .iter()
            .any(|l| matches!(l, trazo::light::Light::Area { .. }))
    );
}

/// A sampler's wrap modes and nearest-texel filter reach the image: the
/// 2 × 2 texture shifted by half its width repeats, or clamps to its right
/// column, and shifted by half its height follows the mode along t; halved, a bilinear look-up between texels blends them, a
/// nearest one does not.
#[test]
fn sampler_wrap_modes_and_nearest_filtering_apply() {
    let dir = tmp();
    std::fs::write(dir.path().join("t.png"), png_2x2()).unwrap();
    let path = dir.path().join("s.gltf");
    let render = |sampler: &str, transform: &str| {
        let mut a = Asset::default();
        let body = textured_square_body(
            &mut a,
            r#"[{"uri":"t.png"}]"#,
            &format!(r#","extensions":{{"KHR_texture_transform":{transform}}}"#),
            1.0,
        )
        .replace(
            r#""textures":[{"source":0}]"#,
            &format!(r#""samplers":[{sampler}],"textures":[{{"source":0,"sampler":0}}]"#),
        );
        a.write_embedded(&path, &body);
        let d = load(&path, &[]).unwrap();
        assert!(!d.warnings.iter().any(|w| w.contains("samplers")), "{:?}", d.warnings);
        render_2x2(d)
    };
    let (red, green) = (Rgb::new(1.0, 0.0, 0.0), Rgb::new(0.0, 1.0, 0.0));
    let shifted = r#"{"offset":[0.5,0]}"#;
    let img = render(r#"{"wrapS":10497,"wrapT":10497}"#, shifted);
    assert!(close(img.get(1, 0), red), "repeat: {}", img.get(1, 0));
    let img = render(r#"{"wrapS":33071,"wrapT":33071}"#, shifted);
    assert!(close(img.get(1, 0), green), "clamp: {}", img.get(1, 0));
    // Each axis has its own mode: shifted by half its height, the bottom
    // left texel repeats to the top row's red along t, or clamps to the
    // bottom row's blue, whatever the mode along s.
    let lowered = r#"{"offset":[0,0.5]}"#;
    let blue = Rgb::new(0.0, 0.0, 1.0);
    let img = render(r#"{"wrapS":33071,"wrapT":10497}"#, lowered);
    assert!(close(img.get(0, 1), red), "repeat along t: {}", img.get(0, 1));
    let img = render(r#"{"wrapS":10497,"wrapT":33071}"#, lowered);
    assert!(close(img.get(0, 1), blue), "clamp along t: {}", img.get(0, 1));
    let halved = r#"{"scale":[0.5,0.5]}"#;
    let img = render(r#"{"magFilter":9728}"#, halved);
    assert!(close(img.get(1, 0), red), "nearest: {}", img.get(1, 0));
    let img = render(r#"{"magFilter":9729}"#, halved);
    assert!(!close(img.get(1, 0), red), "bilinear: {}", img.get(1, 0));
}

/// glTF's BRDF blends the dielectric and the metal by the metallic factor:
/// between 0 and 1 it is a mix of the two weighted by it, so a floor's
/// image at 0.5 is the mean of its images at 0 and 1, within the renders'
/// standard errors.
#[test]
fn metallic_factors_between_0_and_1_blend_the_dielectric_and_the_metal() {
    let dir = tmp();
    let path = dir.path().join("m.gltf");
    let load_with = |metallic: f32| {
        let mut a = Asset::default();
        let prim = a.floor();
        let body = format!(
            r#""extensionsUsed":["KHR_lights_punctual"],
            "extensions":{{"KHR_lights_punctual":{{"lights":[{{"type":"point","intensity":2}}]}}}},
            "scenes":[{{"nodes":[0,1]}}],
            "nodes":[{{"mesh":0}},{{"translation":[0.2,1,0],"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}}],
            "materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0.8,0.6,0.3,1],"metallicFactor":{metallic},"roughnessFactor":0.6}}}}],
            "meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#
        );
        a.write_embedded(&path, &body);
        let mut d = load(&path, &[]).unwrap();
        (d.settings.width, d.settings.height, d.settings.spp) = (16, 12, 2048);
        d
    };
    let d = load_with(0.3);
    assert!(!d.warnings.iter().any(|w| w.contains("metallic")), "{:?}", d.warnings);
    let kind = |name: &str| &d.materials.iter().find(|m| m.name == name).unwrap().kind;
    let MaterialKindDesc::Mix {
        choice: MixChoice::Weight(ColorSource::Rgb(w)),
        materials: [dielectric, metal],
    } = kind(d.shapes[0].material.as_deref().unwrap())
    else {
        panic!("{:?}", d.materials)
    };
    assert_eq!(*w, Rgb::splat(0.3));
    assert!(
        matches!(kind(dielectric), MaterialKindDesc::Plastic { .. }),
        "{:?}",
        kind(dielectric)
    );
    assert!(
        matches!(kind(metal), MaterialKindDesc::Conductor { .. }),
        "{:?}",
        kind(metal)
    );

    let [(m0, e0), (m1, e1), (half, e_half)] =
        [0.0, 1.0, 0.5].map(|m| crate::path::mean_and_error(&crate::path::render_film(&load_with(m))));
    let expected = 0.5 * (m0 + m1);
    let tol = 4.0 * (e_half * e_half + 0.25 * (e0 * e0 + e1 * e1)).sqrt();
    assert!(
        (half - expected).abs() <= tol,
        "metallic 0.5: {half} ± {e_half}, expected {expected} ± {tol} (0: {m0}, 1: {m1})"
    );
    // Rounding the factor to either end would miss by half the gap.
    assert!(
        0.5 * (m0 - m1).abs() > 3.0 * tol,
        "the two ends differ: {m0} against {m1}, ± {tol}"
    );
}

/// A metallic-roughness image (linear) drives the blend and the metal's
/// roughness: its blue channel times the metallic factor weighs the metal,
/// its green channel times the roughness factor, squared, is the metal's α.
#[test]
fn metallic_roughness_textures_weigh_the_metal_and_roughen_it() {
    let dir = tmp();
    // Left column: metal (blue 255), green 128; right: dielectric, green 255.
    let mut img = image::RgbImage::new(2, 1);
    img.put_pixel(0, 0, image::Rgb([0, 128, 255]));
    img.put_pixel(1, 0, image::Rgb([0, 255, 0]));
    let png = png_bytes(img);
    std::fs::write(dir.path().join("mr.png"), &png).unwrap();
    // A file beside the glTF, and embedded (decoded by the reader), read
    // linear alike.
    let embedded = format!("data:image/png;base64,{}", base64(&png));
    for uri in ["mr.png", embedded.as_str()] {
        metallic_roughness_image_case(&dir, uri);
    }
}

fn metallic_roughness_image_case(dir: &tempfile::TempDir, uri: &str) {
    let mut a = Asset::default();
    let prim = a.square();
    let body = format!(
        r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "images":[{{"uri":"{uri}"}}],"textures":[{{"source":0}}],
        "materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0.9,0.7,0.2,1],"metallicFactor":0.8,"roughnessFactor":0.5,
          "metallicRoughnessTexture":{{"index":0}}}},"doubleSided":true}}],
        "meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#
    );
    let path = dir.path().join("mr.gltf");
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    // Only the plastic coat's roughness stays the factor, with a warning.
    let mr: Vec<_> = d
        .warnings
        .iter()
        .filter(|w| w.contains("metallicRoughnessTexture"))
        .collect();
    assert!(mr.len() == 1 && mr[0].contains("on the dielectric"), "{:?}", d.warnings);
    let scene = build(&d).unwrap();
    let m = first_shape_material(&d);
    let mix = scene.material_mixes[m].as_ref().expect("a mix of dielectric and metal");
    // The square's (u, v) runs over the image; texel centres at u = ¼, ¾.
    let at = |u: f32| trazo::texture::TexCoord::new(trazo::Vec2::new(u, 0.5), Vec3::ZERO);
    let weight = |u: f32| mix.weight.eval(&scene.textures, &at(u));
    assert!(
        (weight(0.25) - Rgb::splat(0.8)).abs().max_element() < 1e-3,
        "{}",
        weight(0.25)
    );
    assert!(weight(0.75).abs().max_element() < 1e-3, "{}", weight(0.75));
    let metal = &scene.materials[mix.materials[1] as usize];
    let map = metal.roughness_map.as_ref().expect("the metal's roughness varies");
    let r = 0.5 * 128.0 / 255.0;
    assert!((map.u.eval(&scene.textures, &at(0.25)).x - r * r).abs() < 1e-3);
    assert!((map.u.eval(&scene.textures, &at(0.75)).x - 0.25).abs() < 1e-3);
    assert!(
        scene.materials[mix.materials[0] as usize].roughness_map.is_none(),
        "the plastic's is the factor"
    );
}

/// The scene of `path`, read without a warning about a normal texture.
fn normal_mapped_scene(path: &Path) -> trazo::scene::Scene {
    let d = load(path, &[]).unwrap();
    assert!(
        !d.warnings.iter().any(|w| w.contains("normalTexture")),
        "{:?}",
        d.warnings
    );
    build(&d).unwrap()
}

/// The shading normal a ray down −z through (x, 0.1) finds.
fn shading_normal_at(scene: &trazo::scene::Scene, x: f32) -> Vec3 {
    let ray = trazo::geometry::Ray::new(Vec3::new(x, 0.1, 3.0), Vec3::NEG_Z);
    let hit = scene.intersect(&ray).expect("the square");
    let m = &scene.materials[hit.material as usize];
    m.shading_frame(&scene.textures, &hit, Vec3::Z).n
}

#[test]
fn normal_textures_tilt_the_normal_in_gltf_tangent_space() {
    // One texel: the tangent-space normal (0.004, 0.506, 1) (green up the
    // image), read linear.
    let dir = tmp();
    let mut img = image::RgbImage::new(1, 1);
    img.put_pixel(0, 0, image::Rgb([128, 192, 255]));
    img.save(dir.path().join("n.png")).unwrap();
    let mut a = Asset::default();
    // The same square twice: up the image is up the square (+y), then,
    // with v mirrored, down it.
    let upright = a.square();
    let mirrored = a.square_with_uv(&[0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0]);
    for (scale, tilt) in [(None, 0.506f32.atan()), (Some(2.0), (2.0f32 * 0.506).atan())] {
        let scale_json = scale.map(|s| format!(r#","scale":{s}"#)).unwrap_or_default();
        let body = format!(
            r#""scenes":[{{"nodes":[0,1]}}],"nodes":[{{"mesh":0,"translation":[-1,0,0]}},{{"mesh":1,"translation":[1,0,0]}}],
            "images":[{{"uri":"n.png"}}],"textures":[{{"source":0}}],
            "materials":[{{"normalTexture":{{"index":0{scale_json}}},"doubleSided":true}}],
            "meshes":[{{"primitives":[{{{upright},"material":0}}]}},{{"primitives":[{{{mirrored},"material":0}}]}}]"#
        );
        let path = dir.path().join("normals.gltf");
        a.write_embedded(&path, &body);
        let scene = normal_mapped_scene(&path);
        for (x, up) in [(-1.0f32, 1.0f32), (1.0, -1.0)] {
            let n = shading_normal_at(&scene, x);
            let expected = Vec3::new(0.0, up * tilt.sin(), tilt.cos());
            assert!(
                (n - expected).length() < 0.01,
                "scale {scale:?}, square at x = {x}: {n} against {expected}"
            );
        }
    }
    // A texture transform on it applies: two texels, the left tilted up
    // the image and the right down it; shifted by half the image in u,
    // the square's left half reads the right texel.
    let mut img = image::RgbImage::new(2, 1);
    img.put_pixel(0, 0, image::Rgb([128, 192, 255]));
    img.put_pixel(1, 0, image::Rgb([128, 64, 255]));
    img.save(dir.path().join("n2.png")).unwrap();
    let turned = |transform: &str| {
        format!(
            r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
            "images":[{{"uri":"n2.png"}}],"textures":[{{"source":0}}],
            "materials":[{{"normalTexture":{{"index":0,"extensions":{{"KHR_texture_transform":{transform}}}}},"doubleSided":true}}],
            "meshes":[{{"primitives":[{{{upright},"material":0}}]}}]"#
        )
    };
    let path = dir.path().join("turned.gltf");
    for (offset, left_up) in [(0.0, true), (0.5, false)] {
        a.write_embedded(&path, &turned(&format!(r#"{{"offset":[{offset},0]}}"#)));
        let scene = normal_mapped_scene(&path);
        for (x, up) in [(-0.25f32, left_up), (0.25, !left_up)] {
            let n = shading_normal_at(&scene, x);
            assert!(n.y.abs() > 0.4 && (n.y > 0.0) == up, "offset {offset}, x = {x}: {n}");
        }
    }
    // A malformed one is an error naming it.
    a.write_embedded(&path, &turned(r#"{"offset":"left"}"#));
    let e = load(&path, &[]).unwrap_err().to_string();
    assert!(
        e.contains("normalTexture.extensions.KHR_texture_transform") && e.contains("turned.gltf"),
        "{e}"
    );
}

#[test]
fn volumes_absorb_as_beer_lambert_inside_transmissive_meshes() {
    let dir = tmp();
    let mut a = Asset::default();
    // A unit cube (outward winding), and a glowing square behind it.
    let h = 0.5f32;
    let corners: Vec<f32> = [
        [-h, -h, -h],
        [h, -h, -h],
        [h, h, -h],
        [-h, h, -h],
        [-h, -h, h],
        [h, -h, h],
        [h, h, h],
        [-h, h, h],
    ]
    .concat();
    let p = a.floats(&corners, "VEC3");
    let i = a.indices(&[
        0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5,
    ]);
    let square = a.square();
    // Index-matched (no refraction, no reflection), so a ray straight
    // through crosses one attenuation distance of the medium.
    let body = format!(
        r#""extensionsUsed":["KHR_materials_volume","KHR_materials_transmission","KHR_materials_ior"],
        "scenes":[{{"nodes":[0,1,2]}}],"nodes":[{{"camera":0,"translation":[0,0,3]}},{{"mesh":0}},
          {{"mesh":1,"translation":[0,0,-2],"scale":[3,3,3]}}],
        "cameras":[{{"type":"orthographic","orthographic":{{"xmag":0.3,"ymag":0.3,"znear":0,"zfar":10}}}}],
        "materials":[{{"pbrMetallicRoughness":{{"metallicFactor":0,"roughnessFactor":0}},
            "extensions":{{"KHR_materials_transmission":{{"transmissionFactor":1}},"KHR_materials_ior":{{"ior":1}},
              "KHR_materials_volume":{{"thicknessFactor":1,"attenuationDistance":1,"attenuationColor":[0.5,0.25,0.8]}}}}}},
          {GLOW}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":{p}}},"indices":{i},"material":0}}]}},
          {{"primitives":[{{{square},"material":1}}]}}]"#
    );
    let path = dir.path().join("glass.gltf");
    a.write_embedded(&path, &body);
    let mut d = load(&path, &[]).unwrap();
    assert!(!d.warnings.iter().any(|w| w.contains("volume")), "{:?}", d.warnings);
    assert_eq!(d.settings.integrator, trazo::settings::IntegratorKind::VolPath);
    assert_eq!(d.media.len(), 1);
    let FieldDesc::Constant(sigma) = d.media[0].sigma_t else {
        panic!("{:?}", d.media[0].sigma_t)
    };
    assert!(
        (sigma - Rgb::new(0.5f32.ln(), 0.25f32.ln(), 0.8f32.ln()) * -1.0)
            .abs()
            .max_element()
            < 1e-6
    );
    let inside: Vec<_> = d
        .shapes
        .iter()
        .map(|s| s.media.as_ref().and_then(|m| m.inside.clone()))
        .collect();
    assert_eq!(inside.iter().filter(|m| m.is_some()).count(), 1, "{inside:?}");
    // The light through the cube: the glow times the attenuation colour.
    // Each sample passes or is absorbed, so the image's mean over its
    // 8 × 8 × 256 samples has a standard deviation below
    // √(0.25/16384) ≈ 0.004 per channel.
    d.settings.width = 8;
    d.settings.height = 8;
    d.settings.spp = 256;
    let img = render_image(&build(&d).unwrap()).unwrap();
    let mean = img.pixels.iter().sum::<Rgb>() / img.pixels.len() as f32;
    assert!((mean - Rgb::new(0.5, 0.25, 0.8)).abs().max_element() < 0.02, "{mean}");

    // A thin-walled volume (thickness 0) and an infinite distance have no
    // medium.
    for volume in [
        r#"{"thicknessFactor":0,"attenuationDistance":1,"attenuationColor":[0.5,0.5,0.5]}"#,
        r#"{"thicknessFactor":1,"attenuationColor":[0.5,0.5,0.5]}"#,
    ] {
        let thin = body.replace(
            r#"{"thicknessFactor":1,"attenuationDistance":1,"attenuationColor":[0.5,0.25,0.8]}"#,
            volume,
        );
        a.write_embedded(&path, &thin);
        let d = load(&path, &[]).unwrap();
        assert!(
            d.media.is_empty() && d.shapes.iter().all(|s| s.media.is_none()),
            "{volume}"
        );
    }
    // A distance of 0 is an error naming it.
    let bad = body.replace(r#""attenuationDistance":1,"#, r#""attenuationDistance":0,"#);
    a.write_embedded(&path, &bad);
    let e = load(&path, &[]).unwrap_err().to_string();
    assert!(e.contains("attenuationDistance") && e.contains("above 0"), "{e}");
}

/// A floor under a point light 1 unit above it, seen by the framing camera.
fn lit_floor(intensity: f32) -> (SceneDesc, trazo::film::Image) {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    let body = format!(
        r#""extensionsUsed":["KHR_lights_punctual"],
        "extensions":{{"KHR_lights_punctual":{{"lights":[{{"type":"point","intensity":{intensity},"color":[1,0.5,1]}}]}}}},
        "scenes":[{{"nodes":[0,1]}}],
        "nodes":[{{"mesh":0}},{{"translation":[0.2,1,0],"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}}],
        "materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0.8,0.8,0.8,1],"metallicFactor":0}}}}],
        "meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#
    );
    let path = dir.path().join("lit.gltf");
    a.write_embedded(&path, &body);
    let mut d = load(&path, &[]).unwrap();
    d.settings.width = 16;
    d.settings.height = 12;
    d.settings.spp = 4;
    let img = render_image(&build(&d).unwrap()).unwrap();
    (d, img)
}

#[test]
fn a_punctual_point_light_lights_a_floor() {
    let (d, img) = lit_floor(5.0);
    assert_eq!(d.lights.len(), 1);
    assert_eq!(
        d.lights[0].kind,
        LightKind::Point {
            position: Vec3::new(0.2, 1.0, 0.0),
            intensity: Rgb::new(5.0, 2.5, 5.0),
            falloff: true,
        }
    );
    assert!(d.warnings.iter().any(|w| w.contains("candela")), "{:?}", d.warnings);
    let lit: f32 = img.pixels.iter().map(|p| p.element_sum()).sum();
    assert!(lit > 1.0, "{lit}");
    // The same scene with the light switched off is black: the light is
    // what lit it (no studio lights were added).
    let (_, dark) = lit_floor(0.0);
    assert_eq!(dark.pixels.iter().map(|p| p.element_sum()).sum::<f32>(), 0.0);
}

#[test]
fn spot_and_directional_lights_point_along_the_node_minus_z() {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    // Rotation −90° about x turns −z into −y (down).
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let body = format!(
        r#""extensions":{{"KHR_lights_punctual":{{"lights":[
            {{"type":"spot","intensity":2,"spot":{{"innerConeAngle":0.2,"outerConeAngle":0.5}}}},
            {{"type":"directional","intensity":3}}]}}}},
        "scenes":[{{"nodes":[0,1,2]}}],
        "nodes":[{{"mesh":0}},
          {{"translation":[0,2,0],"rotation":[-{s},0,0,{s}],"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}},
          {{"rotation":[-{s},0,0,{s}],"extensions":{{"KHR_lights_punctual":{{"light":1}}}}}}],
        "meshes":[{{"primitives":[{{{prim}}}]}}]"#
    );
    let path = dir.path().join("spot.gltf");
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    let LightKind::Spot {
        position,
        to,
        inner_angle,
        outer_angle,
        ..
    } = d.lights[0].kind
    else {
        panic!("{:?}", d.lights[0])
    };
    assert!((position - Vec3::new(0.0, 2.0, 0.0)).length() < 1e-5);
    assert!(((to - position).normalize() - Vec3::NEG_Y).length() < 1e-5);
    assert!((inner_angle - 0.2f32.to_degrees()).abs() < 1e-4 && (outer_angle - 0.5f32.to_degrees()).abs() < 1e-4);
    let LightKind::Directional { direction, irradiance } = d.lights[1].kind else {
        panic!()
    };
    assert!((direction - Vec3::NEG_Y).length() < 1e-5);
    assert_eq!(irradiance, Rgb::splat(3.0));
}

#[test]
fn scenes_without_lights_get_studio_lights_and_a_warning() {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    let body = format!(r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{{prim}}}]}}]"#);
    let path = dir.path().join("dark.gltf");
    a.write_embedded(&path, &body);
    let d = load(&path, &[("x".into(), "1".into())]).unwrap();
    assert_eq!(d.lights.len(), 2);
    assert!(matches!(d.background, BackgroundDesc::Gradient { .. }));
    assert!(
        d.warnings.iter().any(|w| w.contains("studio lights")),
        "{:?}",
        d.warnings
    );
    assert!(d.warnings.iter().any(|w| w.contains("-D x")), "{:?}", d.warnings);
}

/// The base colour's alpha as coverage (§3.9.4): MASK cuts the surface
/// out below the cutoff (0.5 by default), BLEND makes it that opaque; an
/// alpha a texture varies is approximated by an opaque surface, with a
/// warning.
#[test]
fn alpha_modes_make_cut_outs_and_partial_coverage() {
    let dir = tmp();
    std::fs::write(dir.path().join("t.png"), png_2x2()).unwrap();
    let path = dir.path().join("alpha.gltf");
    let opacity = |material: &str| {
        let mut a = Asset::default();
        let prim = a.floor();
        let body = format!(
            r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"images":[{{"uri":"t.png"}}],"textures":[{{"source":0}}],
            "materials":[{material}],"meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#
        );
        a.write_embedded(&path, &body);
        let d = load(&path, &[]).unwrap();
        let m = &d.materials[first_shape_material(&d)];
        m.opacity.clone()
    };
    let factor = |a: f32| format!(r#""pbrMetallicRoughness":{{"baseColorFactor":[1,1,1,{a}],"metallicFactor":0}}"#);
    let cut = Some(ColorSource::Rgb(Rgb::ZERO));
    for (material, expected) in [
        (format!(r#"{{{},"alphaMode":"MASK"}}"#, factor(0.3)), cut.clone()),
        (format!(r#"{{{},"alphaMode":"MASK"}}"#, factor(0.7)), None),
        (
            format!(r#"{{{},"alphaMode":"MASK","alphaCutoff":0.8}}"#, factor(0.7)),
            cut,
        ),
        (
            format!(r#"{{{},"alphaMode":"BLEND"}}"#, factor(0.4)),
            Some(ColorSource::Rgb(Rgb::splat(0.4))),
        ),
        (format!(r#"{{{}}}"#, factor(0.4)), None),
    ] {
        assert_eq!(opacity(&material), expected, "{material}");
    }
}

#[test]
fn alpha_from_the_base_colour_image_masks_and_blends() {
    let dir = tmp();
    // Alpha 1 on the left texel, 64/255 on the right.
    let mut img = image::RgbaImage::new(2, 1);
    img.put_pixel(0, 0, image::Rgba([200, 10, 10, 255]));
    img.put_pixel(1, 0, image::Rgba([10, 200, 10, 64]));
    let png = png_bytes(img);
    std::fs::write(dir.path().join("rgba.png"), &png).unwrap();
    std::fs::write(dir.path().join("rgb.png"), png_2x2()).unwrap();
    let embedded = format!("data:image/png;base64,{}", base64(&png));
    let path = dir.path().join("alpha.gltf");
    // The opacity at the left and right texel centres.
    let opacity = |uri: &str, mode: &str| {
        let mut a = Asset::default();
        let prim = a.square();
        let body = format!(
            r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"images":[{{"uri":"{uri}"}}],"textures":[{{"source":0}}],
            "materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[1,1,1,0.8],"baseColorTexture":{{"index":0}},"metallicFactor":0}},{mode}}}],
            "meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#
        );
        a.write_embedded(&path, &body);
        let d = load(&path, &[]).unwrap();
        assert!(!d.warnings.iter().any(|w| w.contains("alphaMode")), "{:?}", d.warnings);
        let scene = build(&d).unwrap();
        let m = first_shape_material(&d);
        let at = |u: f32| trazo::texture::TexCoord::new(trazo::Vec2::new(u, 0.5), Vec3::ZERO);
        let m = &scene.materials[m];
        [
            m.opacity_at(&scene.textures, &at(0.25)),
            m.opacity_at(&scene.textures, &at(0.75)),
        ]
    };
    let near = |a: [f32; 2], b: [f32; 2]| (a[0] - b[0]).abs() < 1e-3 && (a[1] - b[1]).abs() < 1e-3;
    let quarter = 64.0 / 255.0;
    for uri in ["rgba.png", embedded.as_str()] {
        // BLEND: the factor's alpha times the image's.
        let blend = opacity(uri, r#""alphaMode":"BLEND""#);
        assert!(near(blend, [0.8, 0.8 * quarter]), "{blend:?}");
        // MASK: cut where that product is below the cutoff (0.5 by default).
        let mask = opacity(uri, r#""alphaMode":"MASK""#);
        assert!(near(mask, [1.0, 0.0]), "{mask:?}");
        let mask = opacity(uri, r#""alphaMode":"MASK","alphaCutoff":0.9"#);
        assert!(near(mask, [0.0, 0.0]), "{mask:?}");
        // OPAQUE ignores alpha.
        assert!(near(opacity(uri, r#""alphaMode":"OPAQUE""#), [1.0, 1.0]));
    }
    // An image without alpha covers everywhere: the factor alone.
    assert!(near(opacity("rgb.png", r#""alphaMode":"BLEND""#), [0.8, 0.8]));
}

#[test]
fn unsupported_features_warn_with_their_place() {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    let body = format!(
        "\"extensionsUsed\":[\"KHR_materials_clearcoat\"],\n\"scenes\":[{{\"nodes\":[0]}}],\"nodes\":[{{\"mesh\":0}}],\n\
         \"materials\":[{{\"occlusionTexture\":{{\"index\":0}},\"alphaMode\":\"MASK\"}}],\n\
         \"textures\":[{{\"source\":0}}],\"images\":[{{\"uri\":\"n.png\"}}],\n\
         \"meshes\":[{{\"primitives\":[{{{prim},\"material\":0}},{{{prim},\"mode\":1}}]}}]"
    );
    let path = dir.path().join("warn.gltf");
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    let has = |s: &str| {
        d.warnings
            .iter()
            .find(|w| w.contains(s))
            .unwrap_or_else(|| panic!("{s}: {:?}", d.warnings))
    };
    let w = has("occlusionTexture is unsupported");
    assert!(w.starts_with(&format!("{}:3:", path.display())), "{w}");
    assert!(has("KHR_materials_clearcoat is unsupported").contains(":1:"));
    assert!(has("LINES primitives are unsupported").contains(":5:"));

    // A primitive without POSITION is skipped (§3.7.2.1), the rest drawn.
    let body = format!(
        r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{{prim}}},{{"attributes":{{}}}}]}}]"#
    );
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    assert_eq!(d.shapes.len(), 1);
    has_warning(&d, "without POSITION");
}

fn has_warning(d: &SceneDesc, s: &str) {
    assert!(d.warnings.iter().any(|w| w.contains(s)), "{s}: {:?}", d.warnings);
}

#[test]
fn strips_fans_and_sparse_accessors() {
    let dir = tmp();
    let mut a = Asset::default();
    // Strip 0 1 2 3 over a square → (0 1 2), (1 3 2): both face +z.
    let p = a.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0], "VEC3");
    // Fan 0 1 3 2 around vertex 0 → (1 3 0), (3 2 0).
    let fan_indices = a.indices(&[0, 1, 3, 2]);
    // Sparse: element 3 of a copy of the positions moves to z = 5.
    let base = a.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0], "VEC3");
    let idx_view = a.view(&[3u8]);
    let val_view = a.view(
        &[1.0f32, 1.0, 5.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect::<Vec<u8>>(),
    );
    let base_view = a.accessors[base]
        .split("\"bufferView\":")
        .nth(1)
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .to_string();
    a.accessors.push(format!(
        r#"{{"bufferView":{base_view},"componentType":5126,"count":4,"type":"VEC3",
            "sparse":{{"count":1,"indices":{{"bufferView":{idx_view},"componentType":5121}},"values":{{"bufferView":{val_view}}}}}}}"#
    ));
    let sparse = a.accessors.len() - 1;
    let body = format!(
        r#""scenes":[{{"nodes":[0,1]}}],"nodes":[{{"mesh":0}},{{"mesh":1}}],"meshes":[
            {{"primitives":[{{"attributes":{{"POSITION":{p}}},"mode":5}},{{"attributes":{{"POSITION":{p}}},"indices":{fan_indices},"mode":6}}]}},
            {{"primitives":[{{"attributes":{{"POSITION":{sparse}}},"mode":5}}]}}]"#
    );
    let path = dir.path().join("strip.gltf");
    a.write_embedded(&path, &body);
    let d = load(&path, &[]).unwrap();
    let strip = inline_mesh(&d.shapes[0]);
    assert_eq!(strip.indices, [[0, 1, 2], [1, 3, 2]]);
    let fan = inline_mesh(&d.shapes[1]);
    assert_eq!(fan.indices, [[1, 3, 0], [3, 2, 0]]);
    for m in [strip, fan] {
        for t in 0..m.len() {
            let [a, b, c] = m.vertices(t);
            assert!((b - a).cross(c - a).z > 0.0, "triangle {t} faces +z");
        }
    }
    let moved = inline_mesh(&d.shapes[2]);
    assert_eq!(moved.positions[3], Vec3::new(1.0, 1.0, 5.0));
    assert_eq!(moved.positions[2], Vec3::new(0.0, 1.0, 0.0));
}

/// Loads `json` (with the floor's buffer as a data URI) as a .gltf file
/// and returns the error message.
fn load_error(dir: &Path, a: &Asset, body: &str) -> String {
    let path = dir.join("bad.gltf");
    a.write_embedded(&path, body);
    load(&path, &[]).unwrap_err().to_string()
}

#[test]
fn bad_data_is_an_error_naming_the_element() {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    let scene = r#""scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}]"#;

    // Index 9 of 4 vertices.
    let mut b = Asset::default();
    let p = b.floats(&[0.0; 12], "VEC3");
    let i = b.indices(&[0, 1, 9]);
    let e = load_error(
        dir.path(),
        &b,
        &format!(r#"{scene},"meshes":[{{"primitives":[{{"attributes":{{"POSITION":{p}}},"indices":{i}}}]}}]"#),
    );
    assert!(
        e.contains("meshes[0].primitives[0].indices") && e.contains("vertex 9"),
        "{e}"
    );

    // An accessor larger than its buffer view.
    let mut b = Asset::default();
    let p = b.floats(&[0.0; 9], "VEC3");
    b.accessors[p] = b.accessors[p].replace("\"count\":3", "\"count\":300");
    let e = load_error(
        dir.path(),
        &b,
        &format!(r#"{scene},"meshes":[{{"primitives":[{{"attributes":{{"POSITION":{p}}}}}]}}]"#),
    );
    assert!(e.contains("`accessors[0]`") && e.contains("300 elements"), "{e}");

    // POSITION as VEC2.
    let mut b = Asset::default();
    let p = b.floats(&[0.0; 6], "VEC2");
    let e = load_error(
        dir.path(),
        &b,
        &format!(r#"{scene},"meshes":[{{"primitives":[{{"attributes":{{"POSITION":{p}}}}}]}}]"#),
    );
    assert!(e.contains("accessors[0].type") && e.contains("VEC3"), "{e}");

    // A reference to a mesh that does not exist (the gltf crate's check),
    // reported at its line and column.
    let e = load_error(
        dir.path(),
        &a,
        &format!(
            "\"scenes\":[{{\"nodes\":[0]}}],\n\"nodes\":[{{\"mesh\":7}}],\"meshes\":[{{\"primitives\":[{{{prim}}}]}}]"
        ),
    );
    assert!(
        e.contains(":2:") && e.contains("nodes[0].mesh") && e.contains("does not exist"),
        "{e}"
    );

    // A POSITION accessor that does not exist (the gltf crate 1.4 would
    // panic validating it).
    let e = load_error(
        dir.path(),
        &a,
        &format!(r#"{scene},"meshes":[{{"primitives":[{{"attributes":{{"POSITION":99}}}}]}}]"#),
    );
    assert!(
        e.contains("meshes[0].primitives[0].attributes.POSITION") && e.contains("does not exist"),
        "{e}"
    );

    // A cycle in the node hierarchy.
    let e = load_error(
        dir.path(),
        &a,
        &format!(
            r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0,"children":[1]}},{{"children":[0]}}],"meshes":[{{"primitives":[{{{prim}}}]}}]"#
        ),
    );
    assert!(e.contains("reached twice"), "{e}");

    // A required extension trazo does not know.
    let e = load_error(
        dir.path(),
        &a,
        &format!(
            r#""extensionsRequired":["KHR_draco_mesh_compression"],{scene},"meshes":[{{"primitives":[{{{prim}}}]}}]"#
        ),
    );
    assert!(e.contains("KHR_draco_mesh_compression"), "{e}");

    // Out-of-range factors and a perspective camera without its object.
    let e = load_error(
        dir.path(),
        &a,
        &format!(
            r#"{scene},"materials":[{{"pbrMetallicRoughness":{{"roughnessFactor":2}}}}],"meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#
        ),
    );
    assert!(e.contains("roughnessFactor") && e.contains("between 0 and 1"), "{e}");
    let e = load_error(
        dir.path(),
        &a,
        &format!(
            r#""scenes":[{{"nodes":[0,1]}}],"nodes":[{{"mesh":0}},{{"camera":0}}],"cameras":[{{"type":"perspective","orthographic":{{"xmag":1,"ymag":1,"znear":0,"zfar":1}}}}],"meshes":[{{"primitives":[{{{prim}}}]}}]"#
        ),
    );
    assert!(e.contains("cameras[0].perspective") && e.contains("missing"), "{e}");

    // An embedded image that is not an image.
    let e = load_error(
        dir.path(),
        &a,
        &format!(
            r#"{scene},"images":[{{"uri":"data:image/png;base64,AAAA"}}],"textures":[{{"source":0}}],"materials":[{{"pbrMetallicRoughness":{{"metallicFactor":0,"baseColorTexture":{{"index":0}}}}}}],"meshes":[{{"primitives":[{{{prim},"material":0}}]}}]"#
        ),
    );
    assert!(e.contains("images[0]") && e.contains("decode"), "{e}");

    // A data URI that is not base64.
    let path = dir.path().join("bad64.gltf");
    std::fs::write(&path, a.json(Some("data:application/octet-stream;base64,AA*A"), scene).replace("\"nodes\":[{\"mesh\":0}]", "\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}]")).unwrap();
    let e = load(&path, &[]).unwrap_err().to_string();
    assert!(e.contains("buffers[0].uri") && e.contains("base64"), "{e}");
}

#[test]
fn missing_buffer_and_image_files_are_named_with_their_full_path() {
    let dir = tmp();
    let mut a = Asset::default();
    let prim = a.floor();
    let body = format!(r#""scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{{prim}}}]}}]"#);
    let path = dir.path().join("ext.gltf");
    a.write_with_bin(&path, "ext.bin", &body);
    assert!(load(&path, &[]).is_ok());
    std::fs::remove_file(dir.path().join("ext.bin")).unwrap();
    let e = load(&path, &[]).unwrap_err().to_string();
    let full = dir.path().join("ext.bin");
    assert!(
        e.contains(&full.display().to_string()) && e.contains("not found") && e.contains("buffers[0].uri"),
        "{e}"
    );

    let mut a = Asset::default();
    let body = textured_square_body(&mut a, r#"[{"uri":"gone.png"}]"#, "", 1.0);
    a.write_embedded(&path, &body);
    let e = load(&path, &[]).unwrap_err().to_string();
    let full = dir.path().join("gone.png");
    assert!(
        e.contains(&full.display().to_string()) && e.contains("images[0].uri"),
        "{e}"
    );
}

/// A complete small .glb: the lit floor.
fn small_glb() -> Vec<u8> {
    let mut a = Asset::default();
    let prim = a.floor();
    let body = format!(
        r#""extensions":{{"KHR_lights_punctual":{{"lights":[{{"type":"point","intensity":5}}]}}}},
        "scenes":[{{"nodes":[0,1]}}],
        "nodes":[{{"mesh":0}},{{"translation":[0,1,0],"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}}],
        "meshes":[{{"primitives":[{{{prim}}}]}}]"#
    );
    glb(&a.json(None, &body), &a.bin)
}

#[test]
fn truncated_or_corrupted_glb_files_are_errors_never_panics() {
    let dir = tmp();
    let bytes = small_glb();
    let path = dir.path().join("t.glb");
    std::fs::write(&path, &bytes).unwrap();
    assert!(load(&path, &[]).is_ok());
    for cut in (0..bytes.len()).step_by(3) {
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let e = load(&path, &[]).unwrap_err().to_string();
        assert!(!e.is_empty());
    }
    // Deterministic byte corruption anywhere: Ok or Err, no panic.
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    for _ in 0..400 {
        let mut b = bytes.clone();
        for _ in 0..3 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let i = (state % b.len() as u64) as usize;
            b[i] = (state >> 32) as u8;
        }
        std::fs::write(&path, &b).unwrap();
        let _ = load(&path, &[]);
    }
}

fn trazo() -> Command {
    Command::cargo_bin("trazo").unwrap()
}

/// Runs trazo expecting exit status 2 with one line on stderr.
fn fails(args: &[&str]) -> String {
    let out = trazo().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "args {args:?}, stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{err}");
    lines[0].to_string()
}

#[test]
fn command_line_renders_glb_and_reports_bad_files_with_status_2() {
    let dir = tmp();
    let model = dir.path().join("model.glb");
    std::fs::write(&model, small_glb()).unwrap();
    let out = dir.path().join("x.png");
    let m = model.to_str().unwrap();
    let o = out.to_str().unwrap();
    let status = trazo()
        .args([
            "render", m, "-o", o, "--width", "32", "--height", "32", "--spp", "1", "-q",
        ])
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (32, 32));

    // Missing file.
    let missing = dir.path().join("nothing.gltf");
    let e = fails(&["render", missing.to_str().unwrap(), "-o", o, "-q"]);
    assert!(e.contains("nothing.gltf"), "{e}");

    // Malformed JSON: line and column.
    let bad = dir.path().join("bad.gltf");
    std::fs::write(
        &bad,
        "{\n  \"asset\": {\"version\": \"2.0\"},\n  \"nodes\": [ {\"mesh\": 0,, } ]\n}\n",
    )
    .unwrap();
    let e = fails(&["render", bad.to_str().unwrap(), "-o", o, "-q"]);
    assert!(e.contains("bad.gltf:3:"), "{e}");

    // Empty files and files that are not GLB despite the name.
    let empty = dir.path().join("empty.gltf");
    std::fs::write(&empty, "").unwrap();
    let e = fails(&["render", empty.to_str().unwrap(), "-o", o, "-q"]);
    assert!(e.contains("empty.gltf") && e.contains("empty"), "{e}");
    let not_glb = dir.path().join("not.glb");
    std::fs::write(&not_glb, b"PK\x03\x04 zip").unwrap();
    let e = fails(&["render", not_glb.to_str().unwrap(), "-o", o, "-q"]);
    assert!(
        e.contains("not.glb") && e.contains("byte 0") && e.contains("magic"),
        "{e}"
    );

    // Truncated glb: the byte offset of the problem.
    let cut = dir.path().join("cut.glb");
    let bytes = small_glb();
    std::fs::write(&cut, &bytes[..bytes.len() - 10]).unwrap();
    let e = fails(&["render", cut.to_str().unwrap(), "-o", o, "-q"]);
    assert!(
        e.contains("cut.glb") && e.contains("byte 8") && e.contains("truncated"),
        "{e}"
    );

    // A wrong type in the JSON chunk of a glb: positions in the chunk.
    let typed = dir.path().join("typed.glb");
    std::fs::write(
        &typed,
        glb(r#"{"asset":{"version":"2.0"},"nodes":[{"mesh":"zero"}]}"#, &[]),
    )
    .unwrap();
    let e = fails(&["render", typed.to_str().unwrap(), "-o", o, "-q"]);
    assert!(e.contains("typed.glb (JSON chunk):1:"), "{e}");
}
