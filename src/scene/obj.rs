//! Wavefront OBJ meshes (through the tobj crate), with their MTL materials
//! when the model is rendered on its own. Polygons are triangulated.

use super::desc::{ClassicDesc, ColorSource, ImageSource, MaterialDesc, MaterialKindDesc, TextureDesc, TextureKind};
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::geometry::TriangleMesh;
use glam::{Vec2, Vec3};
use std::cell::RefCell;
use std::path::Path;

/// An OBJ file's triangles grouped by material, with the materials and
/// textures its MTL file describes.
#[derive(Clone, Debug, Default)]
pub struct ObjScene {
    /// Meshes and the index of their material in `materials` (if any).
    pub parts: Vec<(TriangleMesh, Option<usize>)>,
    /// Materials translated from the MTL file.
    pub materials: Vec<MaterialDesc>,
    /// Image textures the materials use.
    pub textures: Vec<TextureDesc>,
    /// What could not be translated exactly.
    pub warnings: Vec<String>,
}

fn load_options() -> tobj::LoadOptions {
    tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    }
}

fn to_mesh(m: &tobj::Mesh) -> TriangleMesh {
    let n = m.positions.len() / 3;
    let mut mesh = TriangleMesh {
        positions: m
            .positions
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect(),
        ..TriangleMesh::default()
    };
    if m.normals.len() == 3 * n {
        mesh.normals = m.normals.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
    }
    if m.texcoords.len() == 2 * n {
        mesh.uvs = m.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect();
    }
    mesh.indices = m.indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    mesh
}

/// Reads an OBJ file with its MTL materials, one mesh per object and
/// material. MTL colours map onto trazo's classical material: `Kd` →
/// diffuse (`map_Kd` → an image texture), `Ks` → specular, `Ns` →
/// shininess, `Ke` → emission, and the illumination model decides
/// reflection (`illum` 3, 5, 8: reflectivity `Ks`) and refraction (`illum`
/// 4, 6, 7, 9, or `d` < 1: transmission, index of refraction `Ni`).
pub fn load_obj_scene(path: &Path) -> Result<ObjScene> {
    let bytes = read_obj(path)?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let warnings = RefCell::new(Vec::new());
    let mut scene = parse_obj_scene_with(&bytes, path, |mtl| {
        let full = dir.join(mtl);
        let text = crate::files::read_limited(&full, crate::files::MAX_SCENE_BYTES)
            .map_err(|_| tobj::LoadError::OpenFileFailed)?;
        read_mtl(&text, &full, &mut warnings.borrow_mut())
    })?;
    scene.warnings.splice(0..0, warnings.into_inner());
    Ok(scene)
}

/// Parses the bytes of an OBJ file read from `path` (which names it in
/// messages and resolves texture files); `mtl`, if given, is the text of
/// every MTL library the file names (without it, materials are grey).
pub fn parse_obj_scene(obj: &[u8], mtl: Option<&[u8]>, path: &Path) -> Result<ObjScene> {
    let warnings = RefCell::new(Vec::new());
    let mut scene = parse_obj_scene_with(obj, path, |name| match mtl {
        Some(m) => read_mtl(m, name, &mut warnings.borrow_mut()),
        None => Err(tobj::LoadError::OpenFileFailed),
    })?;
    scene.warnings.splice(0..0, warnings.into_inner());
    Ok(scene)
}

/// Parses an MTL library with tobj, after rewriting the colour statements
/// that tobj cannot read (it panics on fewer than three numbers): by the
/// MTL specification `Kd 0.5` means `Kd 0.5 0.5 0.5`; statements without
/// numbers (`Kd spectral f.rfl`, `Kd xyz …`) are dropped with a warning.
fn read_mtl(bytes: &[u8], path: &Path, warnings: &mut Vec<String>) -> tobj::MTLLoadResult {
    let text = String::from_utf8_lossy(bytes);
    let mut fixed = String::with_capacity(text.len());
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let key = words.next();
        if matches!(key, Some("Ka" | "Kd" | "Ks" | "Ke")) {
            let numbers: Vec<&str> = words.take_while(|w| w.parse::<f32>().is_ok()).take(3).collect();
            match numbers.as_slice() {
                [] => {
                    warnings.push(format!(
                        "{}:{}: `{}` without numbers is unsupported and ignored",
                        path.display(),
                        n + 1,
                        line.trim()
                    ));
                    fixed.push('\n');
                    continue;
                }
                [v] => fixed.push_str(&format!("{} {v} {v} {v}", key.unwrap_or_default())),
                [r, g] => fixed.push_str(&format!("{} {r} {g} {g}", key.unwrap_or_default())),
                _ => fixed.push_str(line),
            }
        } else {
            fixed.push_str(line);
        }
        fixed.push('\n');
    }
    tobj::load_mtl_buf(&mut std::io::Cursor::new(fixed.as_bytes()))
}

/// Reads an OBJ file whole, refusing folders, missing files and files larger
/// than scene files may be.
fn read_obj(path: &Path) -> Result<Vec<u8>> {
    let meta = std::fs::metadata(path).map_err(|_| Error::file(path, "mesh file not found"))?;
    if !meta.is_file() {
        return Err(Error::file(path, "mesh file not found"));
    }
    crate::files::read_limited(path, crate::files::MAX_SCENE_BYTES)
        .map_err(|e| Error::file(path, format!("cannot read OBJ: {e}")))
}

fn parse_obj_scene_with(
    bytes: &[u8],
    path: &Path,
    mtl_loader: impl Fn(&Path) -> tobj::MTLLoadResult,
) -> Result<ObjScene> {
    let (models, materials) = tobj::load_obj_buf(&mut std::io::Cursor::new(bytes), &load_options(), mtl_loader)
        .map_err(|e| Error::file(path, format!("cannot read OBJ: {e}")))?;
    let mut out = ObjScene::default();
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let materials = match materials {
        Ok(m) => m,
        Err(e) => {
            out.warnings.push(format!(
                "{}: materials (MTL) unreadable ({e}); using grey",
                path.display()
            ));
            Vec::new()
        }
    };
    for (i, m) in materials.iter().enumerate() {
        let (desc, textures, warnings) = mtl_material(m, &format!("{stem}-mtl-{i}"), &dir, path);
        out.materials.push(desc);
        out.textures.extend(textures);
        out.warnings.extend(warnings);
    }
    for model in &models {
        let mesh = to_mesh(&model.mesh);
        if mesh.indices.is_empty() {
            continue;
        }
        mesh.validate()
            .map_err(|e| Error::file(path, format!("object \"{}\": invalid mesh: {e}", model.name)))?;
        let material = model.mesh.material_id.filter(|&id| id < out.materials.len());
        out.parts.push((mesh, material));
    }
    if out.parts.is_empty() {
        return Err(Error::file(path, "the OBJ file has no faces"));
    }
    Ok(out)
}

/// One MTL material as a trazo material, its textures and its warnings.
fn mtl_material(
    m: &tobj::Material,
    name: &str,
    dir: &Path,
    obj: &Path,
) -> (MaterialDesc, Vec<TextureDesc>, Vec<String>) {
    let mut warnings = Vec::new();
    let mut textures = Vec::new();
    let rgb = |c: Option<[f32; 3]>| c.map(|c| Rgb::new(c[0], c[1], c[2]).max(Rgb::ZERO));
    let kd = rgb(m.diffuse).unwrap_or(Rgb::splat(0.8));
    let ks = rgb(m.specular).unwrap_or(Rgb::ZERO);
    let illum = m.illumination_model.unwrap_or(2);
    let dissolve = m.dissolve.unwrap_or(1.0).clamp(0.0, 1.0);
    let ior = m.optical_density.filter(|n| n.is_finite() && *n > 0.0).unwrap_or(1.0);
    let mut diffuse = ColorSource::Rgb(kd);
    if let Some(file) = &m.diffuse_texture {
        let tex_path = dir.join(file.replace('\\', "/"));
        if tex_path.is_file() {
            let tex_name = format!("{name}-map_Kd");
            textures.push(TextureDesc {
                name: tex_name.clone(),
                kind: TextureKind::Image {
                    source: ImageSource::File(tex_path),
                    scale: Vec2::ONE,
                    offset: Vec2::ZERO,
                    encoding: None,
                    tint: if m.diffuse.is_some() { kd } else { Rgb::ONE },
                    wrap: [crate::texture::WrapMode::Repeat; 2],
                    filter: crate::texture::ImageFilter::Bilinear,
                },
                locs: Default::default(),
            });
            diffuse = ColorSource::Texture(tex_name);
        } else {
            warnings.push(format!(
                "{}: material \"{}\": texture {} not found; using Kd",
                obj.display(),
                m.name,
                tex_path.display()
            ));
        }
    }
    let transmissive = matches!(illum, 4 | 6 | 7 | 9) || dissolve < 1.0;
    let reflective = matches!(illum, 3 | 5 | 8);
    let classic = ClassicDesc {
        diffuse,
        specular: ColorSource::Rgb(ks),
        shininess: m.shininess.unwrap_or(0.0).clamp(0.0, 10_000.0),
        reflectivity: if reflective { ks } else { Rgb::ZERO },
        // Partly dissolved surfaces let 1 − d through; glass models all of it.
        transmission: match (transmissive, dissolve < 1.0) {
            (false, _) => Rgb::ZERO,
            (true, true) => Rgb::splat(1.0 - dissolve),
            (true, false) => Rgb::ONE,
        },
        ior: if transmissive { ior } else { 1.0 },
    };
    let mut desc = MaterialDesc::with_kind(name, MaterialKindDesc::Classic(classic));
    desc.two_sided = true;
    if let Some(ke) = rgb(m.emissive).or_else(|| m.unknown_param.get("Ke").and_then(|v| parse_rgb(v))) {
        if ke != Rgb::ZERO {
            desc.emission = ColorSource::Rgb(ke);
        }
    }
    for (key, what) in [
        ("map_Ks", "specular maps"),
        ("map_Bump", "bump maps"),
        ("bump", "bump maps"),
        ("map_d", "opacity maps"),
        ("Pr", "PBR roughness"),
        ("Pm", "PBR metallic"),
        ("map_Ke", "emission maps"),
    ] {
        if m.unknown_param.contains_key(key) {
            warnings.push(format!(
                "{}: material \"{}\": {what} ({key}) are unsupported; ignored",
                obj.display(),
                m.name
            ));
        }
    }
    if m.normal_texture.is_some()
        || m.specular_texture.is_some()
        || m.shininess_texture.is_some()
        || m.dissolve_texture.is_some()
    {
        warnings.push(format!(
            "{}: material \"{}\": only the diffuse map (map_Kd) is used; other maps are ignored",
            obj.display(),
            m.name
        ));
    }
    (desc, textures, warnings)
}

fn parse_rgb(v: &str) -> Option<Rgb> {
    let n: Vec<f32> = v.split_whitespace().filter_map(|x| x.parse().ok()).collect();
    match n.as_slice() {
        [x] => Some(Rgb::splat(*x)),
        [r, g, b, ..] => Some(Rgb::new(*r, *g, *b)),
        _ => None,
    }
    .filter(|c: &Rgb| c.is_finite() && c.min_element() >= 0.0)
}

/// Loads the triangles of an OBJ file merged into one mesh, with normals
/// and texture coordinates where every vertex has them (materials are the
/// scene's business).
pub fn load_obj_mesh(path: &Path) -> Result<TriangleMesh> {
    parse_obj_mesh(&read_obj(path)?, path)
}

/// Parses the bytes of an OBJ file read from `path` (named in messages)
/// into one mesh, as [`load_obj_mesh`] does.
pub fn parse_obj_mesh(bytes: &[u8], path: &Path) -> Result<TriangleMesh> {
    // MTL files are not read: materials come from the scene.
    let (models, _materials) = tobj::load_obj_buf(&mut std::io::Cursor::new(bytes), &load_options(), |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| Error::file(path, format!("cannot read OBJ: {e}")))?;
    let parts: Vec<TriangleMesh> = models.iter().map(|m| to_mesh(&m.mesh)).collect();
    let all_normals = parts.iter().all(|m| !m.normals.is_empty() || m.positions.is_empty());
    let all_uvs = parts.iter().all(|m| !m.uvs.is_empty() || m.positions.is_empty());
    let mut mesh = TriangleMesh::default();
    for part in parts {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(&part.positions);
        if all_normals {
            mesh.normals.extend(&part.normals);
        }
        if all_uvs {
            mesh.uvs.extend(&part.uvs);
        }
        mesh.indices.extend(part.indices.iter().map(|t| t.map(|k| k + base)));
    }
    if mesh.indices.is_empty() {
        return Err(Error::file(path, "the OBJ file has no faces"));
    }
    mesh.validate()
        .map_err(|e| Error::file(path, format!("invalid mesh: {e}")))?;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loads_and_triangulates_a_quad() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("q.obj");
        std::fs::write(
            &p,
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n",
        )
        .unwrap();
        let m = load_obj_mesh(&p).unwrap();
        assert_eq!(m.len(), 2);
        assert_eq!(m.uvs.len(), m.positions.len());
        assert!(m.normals.is_empty());
    }

    #[test]
    fn mtl_materials_become_trazo_materials() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("m.mtl"),
            "newmtl red\nKd 0.8 0.1 0.1\nKs 0.2 0.2 0.2\nNs 50\nillum 2\n\
             newmtl glass\nKd 0 0 0\nNi 1.5\nillum 7\n\
             newmtl lamp\nKd 0.5 0.5 0.5\nKe 4 4 3\n",
        )
        .unwrap();
        let p = dir.path().join("m.obj");
        std::fs::write(
            &p,
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
             usemtl red\nf 1 2 3\nusemtl glass\nf 2 4 3\nusemtl lamp\nf 1 3 4\n",
        )
        .unwrap();
        let s = load_obj_scene(&p).unwrap();
        assert_eq!(s.parts.len(), 3);
        let mat = |k: usize| &s.materials[s.parts[k].1.unwrap()];
        let MaterialKindDesc::Classic(c) = &mat(0).kind else {
            panic!()
        };
        assert_eq!(c.diffuse, ColorSource::Rgb(Rgb::new(0.8, 0.1, 0.1)));
        assert_eq!(c.shininess, 50.0);
        let MaterialKindDesc::Classic(g) = &mat(1).kind else {
            panic!()
        };
        assert_eq!((g.transmission, g.ior), (Rgb::ONE, 1.5));
        assert_eq!(mat(2).emission, ColorSource::Rgb(Rgb::new(4.0, 4.0, 3.0)));
    }

    #[test]
    fn a_missing_mtl_or_texture_is_a_warning_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("t.mtl"), "newmtl tex\nmap_Kd nowhere/wood.png\n").unwrap();
        let p = dir.path().join("t.obj");
        std::fs::write(&p, "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl tex\nf 1 2 3\n").unwrap();
        let s = load_obj_scene(&p).unwrap();
        assert!(
            s.warnings
                .iter()
                .any(|w| w.contains("wood.png") && w.contains("not found")),
            "{:?}",
            s.warnings
        );
        let p2 = dir.path().join("u.obj");
        std::fs::write(
            &p2,
            "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n",
        )
        .unwrap();
        let s = load_obj_scene(&p2).unwrap();
        assert!(s.warnings.iter().any(|w| w.contains("MTL")), "{:?}", s.warnings);
    }

    #[test]
    fn bad_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let e = load_obj_mesh(&dir.path().join("none.obj")).unwrap_err().to_string();
        assert!(e.contains("none.obj") && e.contains("not found"), "{e}");
        let p = dir.path().join("bad.obj");
        std::fs::write(&p, "v 0 0 0\nf 1 2 3\n").unwrap();
        assert!(load_obj_mesh(&p).is_err());
        let p = dir.path().join("empty.obj");
        std::fs::write(&p, "# nothing\n").unwrap();
        assert!(load_obj_mesh(&p).is_err());
    }
}
