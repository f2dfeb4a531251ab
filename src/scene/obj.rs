//! Wavefront OBJ meshes (through the tobj crate). Polygons are triangulated
//! and all objects of the file are merged into one mesh.

use crate::error::{Error, Result};
use crate::geometry::TriangleMesh;
use glam::{Vec2, Vec3};
use std::path::Path;

/// Loads the triangles of an OBJ file, with its normals and texture
/// coordinates where every vertex has them.
pub fn load_obj_mesh(path: &Path) -> Result<TriangleMesh> {
    if !path.is_file() {
        return Err(Error::file(path, "mesh file not found"));
    }
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    // Materials (MTL) are not used by the native format; a missing MTL file
    // is not an error here.
    let (models, _materials) =
        tobj::load_obj(path, &options).map_err(|e| Error::file(path, format!("cannot read OBJ: {e}")))?;
    let mut mesh = TriangleMesh::default();
    let mut all_normals = true;
    let mut all_uvs = true;
    for m in &models {
        let n = m.mesh.positions.len() / 3;
        all_normals &= m.mesh.normals.len() == 3 * n;
        all_uvs &= m.mesh.texcoords.len() == 2 * n;
    }
    for m in &models {
        let base = mesh.positions.len() as u32;
        let mm = &m.mesh;
        mesh.positions
            .extend(mm.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])));
        if all_normals {
            mesh.normals
                .extend(mm.normals.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])));
        }
        if all_uvs {
            mesh.uvs
                .extend(mm.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])));
        }
        mesh.indices.extend(
            mm.indices
                .chunks_exact(3)
                .map(|c| [c[0] + base, c[1] + base, c[2] + base]),
        );
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
