//! Mitsuba's `.serialized` meshes: one or more triangle meshes, each a
//! small header (the identifier 0x041C and a version, 3 or 4) followed by a
//! zlib stream of flags, (version 4) a name, the vertex and triangle
//! counts, positions, optional normals, texture coordinates and colours,
//! and the triangles' indices; a file of several meshes ends with a table
//! of their byte offsets and their number (Mitsuba 3's documentation of its
//! `serialized` shape). Everything is little-endian.
//!
//! The counts in a file are not trusted: the arrays are read as the zlib
//! stream delivers them, so a header that claims more than the stream holds
//! is an error once the data runs out, not an allocation of that size.

use std::io::Read;
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{Error, Result};
use crate::files::{MAX_PLY_BYTES, read_limited};
use crate::geometry::TriangleMesh;

/// The identifier every mesh's header starts with.
const FORMAT_ID: u16 = 0x041C;
/// The mesh has a normal per vertex.
const HAS_NORMALS: u32 = 0x0001;
/// The mesh has texture coordinates per vertex.
const HAS_TEXCOORDS: u32 = 0x0002;
/// The mesh has a colour per vertex.
const HAS_COLORS: u32 = 0x0008;
/// The mesh is to be shaded with face normals.
const FACE_NORMALS: u32 = 0x0010;
/// The arrays hold doubles instead of floats.
const DOUBLE_PRECISION: u32 = 0x2000;

/// One mesh of a `.serialized` file.
#[derive(Clone, Debug, PartialEq)]
pub struct SerializedMesh {
    /// Its triangles, normals (unless it asks for face normals) and texture
    /// coordinates.
    pub mesh: TriangleMesh,
    /// Its colour per vertex (empty where it has none).
    pub colors: Vec<Vec3>,
    /// Whether its flags ask for face normals (its normals, if any, are
    /// then dropped).
    pub face_normals: bool,
    /// Its name (version 4 files; empty otherwise).
    pub name: String,
}

/// Reads mesh number `index` (from 0) of a `.serialized` file.
pub fn read_serialized(path: &Path, index: u32) -> Result<SerializedMesh> {
    let bytes = read_limited(path, MAX_PLY_BYTES)
        .map_err(|e| Error::file(path, format!("cannot read serialized mesh: {e}")))?;
    parse_serialized(&bytes, index).map_err(|e| Error::file(path, format!("cannot read serialized mesh: {e}")))
}

/// Parses mesh number `index` of a `.serialized` file's bytes; errors are
/// short reasons.
pub fn parse_serialized(bytes: &[u8], index: u32) -> std::result::Result<SerializedMesh, String> {
    let (_, version) = header(bytes, 0)?;
    let start = if index == 0 {
        0
    } else {
        mesh_offset(bytes, version, index)?
    };
    let (_, version) = header(bytes, start)?;
    let mut z = flate2::read::ZlibDecoder::new(&bytes[start + 4..]);
    let flags = u32::from_le_bytes(read_array(&mut z, "the flags")?);
    let mut name = Vec::new();
    if version == 4 {
        loop {
            let [c] = read_array(&mut z, "the mesh's name")?;
            if c == 0 {
                break;
            }
            if name.len() >= 1 << 16 {
                return Err("the mesh's name has no end".into());
            }
            name.push(c);
        }
    }
    let vertex_count = u64::from_le_bytes(read_array(&mut z, "the vertex count")?);
    let triangle_count = u64::from_le_bytes(read_array(&mut z, "the triangle count")?);
    if vertex_count > u32::MAX as u64 {
        return Err(format!("{vertex_count} vertices: trazo's meshes hold at most 2^32"));
    }
    let double = flags & DOUBLE_PRECISION != 0;
    let mut reals = |count: u64, what: &str| -> std::result::Result<Vec<f32>, String> {
        let width = if double { 8 } else { 4 };
        let data = read_exactly(&mut z, count, width, what)?;
        Ok(if double {
            data.chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()) as f32)
                .collect()
        } else {
            data.chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect()
        })
    };
    let triples = |v: Vec<f32>| -> Vec<Vec3> { v.chunks_exact(3).map(Vec3::from_slice).collect() };
    let positions = triples(reals(3 * vertex_count, "the positions")?);
    let normals = if flags & HAS_NORMALS != 0 {
        triples(reals(3 * vertex_count, "the normals")?)
    } else {
        Vec::new()
    };
    let uvs = if flags & HAS_TEXCOORDS != 0 {
        reals(2 * vertex_count, "the texture coordinates")?
            .chunks_exact(2)
            .map(Vec2::from_slice)
            .collect()
    } else {
        Vec::new()
    };
    let colors = if flags & HAS_COLORS != 0 {
        triples(reals(3 * vertex_count, "the vertex colours")?)
    } else {
        Vec::new()
    };
    let indices: Vec<[u32; 3]> = read_exactly(&mut z, 3 * triangle_count, 4, "the triangles")?
        .chunks_exact(12)
        .map(|c| std::array::from_fn(|k| u32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap())))
        .collect();
    let face_normals = flags & FACE_NORMALS != 0;
    let mesh = TriangleMesh {
        positions,
        normals: if face_normals { Vec::new() } else { normals },
        uvs,
        indices,
        attributes: Vec::new(),
    };
    mesh.validate().map_err(|e| e.to_string())?;
    Ok(SerializedMesh {
        mesh,
        colors,
        face_normals,
        name: String::from_utf8_lossy(&name).into_owned(),
    })
}

/// The format identifier and version of the mesh header at `at`.
fn header(bytes: &[u8], at: usize) -> std::result::Result<(u16, u16), String> {
    let h = bytes
        .get(at..at + 4)
        .ok_or_else(|| format!("the file ends before the mesh header at byte {at}"))?;
    let id = u16::from_le_bytes([h[0], h[1]]);
    let version = u16::from_le_bytes([h[2], h[3]]);
    if id != FORMAT_ID {
        return Err(format!(
            "byte {at}: not a Mitsuba serialized mesh (identifier {id:#06x}, expected {FORMAT_ID:#06x})"
        ));
    }
    if version != 3 && version != 4 {
        return Err(format!(
            "byte {at}: version {version} is unsupported (Mitsuba writes 3 and 4)"
        ));
    }
    Ok((id, version))
}

/// Where mesh `index` starts, from the table at the end of the file: the
/// meshes' offsets (64-bit in version 4, 32-bit in version 3) and then
/// their number (32-bit).
fn mesh_offset(bytes: &[u8], version: u16, index: u32) -> std::result::Result<usize, String> {
    let n = bytes.len();
    let count_at = n
        .checked_sub(4)
        .ok_or("the file is too short for its table of meshes")?;
    let count = u32::from_le_bytes(bytes[count_at..].try_into().unwrap());
    if index >= count {
        return Err(format!(
            "shape_index {index} is out of range: the file holds {count} mesh{}",
            if count == 1 { "" } else { "es" }
        ));
    }
    let width = if version == 4 { 8 } else { 4 };
    let at = (count - index) as usize * width;
    let entry = count_at
        .checked_sub(at)
        .ok_or("the file is too short for its table of meshes")?;
    let offset = if width == 8 {
        u64::from_le_bytes(bytes[entry..entry + 8].try_into().unwrap())
    } else {
        u32::from_le_bytes(bytes[entry..entry + 4].try_into().unwrap()) as u64
    };
    if offset >= n as u64 {
        return Err(format!(
            "mesh {index} starts at byte {offset}, past the end of the file"
        ));
    }
    Ok(offset as usize)
}

/// `N` bytes of the stream.
fn read_array<const N: usize>(z: &mut impl Read, what: &str) -> std::result::Result<[u8; N], String> {
    let mut b = [0; N];
    z.read_exact(&mut b).map_err(|e| stream_error(e, what))?;
    Ok(b)
}

/// `count` values of `width` bytes of the stream, read as it delivers them.
fn read_exactly(z: &mut impl Read, count: u64, width: u64, what: &str) -> std::result::Result<Vec<u8>, String> {
    let len = count
        .checked_mul(width)
        .filter(|&l| l <= MAX_PLY_BYTES)
        .ok_or_else(|| format!("{what} would take more than {MAX_PLY_BYTES} bytes"))?;
    let mut data = Vec::new();
    z.take(len).read_to_end(&mut data).map_err(|e| stream_error(e, what))?;
    if (data.len() as u64) < len {
        return Err(format!(
            "the data ends in {what} ({} of {len} bytes): the file is truncated or its counts are wrong",
            data.len()
        ));
    }
    Ok(data)
}

fn stream_error(e: std::io::Error, what: &str) -> String {
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        format!("the data ends in {what}: the file is truncated")
    } else {
        format!("{what} are not valid zlib data ({e})")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    /// One mesh in Mitsuba's layout: header, then its zlib stream.
    fn mesh_bytes(version: u16, flags: u32, name: &str, mesh: &TriangleMesh, colors: &[Vec3]) -> Vec<u8> {
        let mut body = Vec::new();
        body.extend(flags.to_le_bytes());
        if version == 4 {
            body.extend(name.as_bytes());
            body.push(0);
        }
        body.extend((mesh.positions.len() as u64).to_le_bytes());
        body.extend((mesh.indices.len() as u64).to_le_bytes());
        let reals = mesh.positions.iter().chain(&mesh.normals).flat_map(|v| v.to_array());
        let reals = reals.chain(mesh.uvs.iter().flat_map(|v| v.to_array()));
        for x in reals.chain(colors.iter().flat_map(|v| v.to_array())) {
            if flags & DOUBLE_PRECISION != 0 {
                body.extend((x as f64).to_le_bytes())
            } else {
                body.extend(x.to_le_bytes())
            }
        }
        for t in &mesh.indices {
            for i in t {
                body.extend(i.to_le_bytes());
            }
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&body).unwrap();
        let mut out = FORMAT_ID.to_le_bytes().to_vec();
        out.extend(version.to_le_bytes());
        out.extend(z.finish().unwrap());
        out
    }

    fn triangle(z: f32) -> TriangleMesh {
        TriangleMesh {
            positions: vec![Vec3::new(0.0, 0.0, z), Vec3::new(1.0, 0.0, z), Vec3::new(0.0, 1.0, z)],
            normals: vec![Vec3::Z; 3],
            uvs: vec![Vec2::ZERO, Vec2::X, Vec2::Y],
            indices: vec![[0, 1, 2]],
            attributes: Vec::new(),
        }
    }

    #[test]
    fn reads_single_and_double_precision_meshes_with_their_attributes() {
        let m = triangle(0.5);
        let colors = [Vec3::X, Vec3::Y, Vec3::Z];
        for flags in [
            HAS_NORMALS | HAS_TEXCOORDS | HAS_COLORS | 0x1000,
            HAS_NORMALS | HAS_TEXCOORDS | HAS_COLORS | DOUBLE_PRECISION,
        ] {
            let read = parse_serialized(&mesh_bytes(4, flags, "tri", &m, &colors), 0).unwrap();
            assert_eq!(read.mesh, m);
            assert_eq!(read.colors, colors);
            assert_eq!(read.name, "tri");
            assert!(!read.face_normals);
        }
        // Version 3 has no name; face normals drop the normals.
        let read = parse_serialized(
            &mesh_bytes(
                3,
                HAS_NORMALS | FACE_NORMALS,
                "",
                &TriangleMesh {
                    uvs: vec![],
                    ..m.clone()
                },
                &[],
            ),
            0,
        )
        .unwrap();
        assert!(read.face_normals && read.mesh.normals.is_empty() && read.mesh.uvs.is_empty());
        assert_eq!(read.mesh.positions, m.positions);
    }

    #[test]
    fn finds_each_mesh_of_a_file_by_its_offset() {
        for version in [3u16, 4] {
            let mut file = Vec::new();
            let mut offsets = Vec::new();
            for k in 0..3 {
                offsets.push(file.len() as u64);
                file.extend(mesh_bytes(
                    version,
                    HAS_NORMALS | HAS_TEXCOORDS,
                    "m",
                    &triangle(k as f32),
                    &[],
                ));
            }
            for o in &offsets {
                if version == 4 {
                    file.extend(o.to_le_bytes());
                } else {
                    file.extend((*o as u32).to_le_bytes());
                }
            }
            file.extend(3u32.to_le_bytes());
            for k in 0..3 {
                assert_eq!(
                    parse_serialized(&file, k).unwrap().mesh,
                    triangle(k as f32),
                    "version {version}"
                );
            }
            let e = parse_serialized(&file, 3).unwrap_err();
            assert!(
                e.contains("shape_index 3 is out of range: the file holds 3 meshes"),
                "{e}"
            );
        }
    }

    #[test]
    fn bad_files_are_errors_not_allocations() {
        let good = mesh_bytes(
            4,
            HAS_NORMALS,
            "",
            &TriangleMesh {
                uvs: vec![],
                ..triangle(0.0)
            },
            &[],
        );
        let e = parse_serialized(&good[..3], 0).unwrap_err();
        assert!(e.contains("ends before the mesh header"), "{e}");
        let mut wrong_id = good.clone();
        wrong_id[0] = 0;
        assert!(
            parse_serialized(&wrong_id, 0)
                .unwrap_err()
                .contains("not a Mitsuba serialized mesh")
        );
        let mut wrong_version = good.clone();
        wrong_version[2] = 9;
        assert!(parse_serialized(&wrong_version, 0).unwrap_err().contains("version 9"));
        let e = parse_serialized(&good[..good.len() - 8], 0).unwrap_err();
        assert!(e.contains("truncated") || e.contains("zlib"), "{e}");
        // A header that claims 2^28 vertices in a few bytes of data.
        let mut liar = TriangleMesh {
            uvs: vec![],
            normals: vec![],
            ..triangle(0.0)
        };
        liar.indices.clear();
        let mut bytes = mesh_bytes(4, 0, "", &liar, &[]);
        let mut z = flate2::read::ZlibDecoder::new(&bytes[4..]);
        let mut body = Vec::new();
        z.read_to_end(&mut body).unwrap();
        body[5..13].copy_from_slice(&(1u64 << 28).to_le_bytes());
        let mut enc = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(&body).unwrap();
        bytes.truncate(4);
        bytes.extend(enc.finish().unwrap());
        let e = parse_serialized(&bytes, 0).unwrap_err();
        assert!(e.contains("the data ends in the positions"), "{e}");
        // An index past the vertices.
        let mut bad = triangle(0.0);
        bad.indices = vec![[0, 1, 7]];
        let e = parse_serialized(&mesh_bytes(4, HAS_NORMALS | HAS_TEXCOORDS, "", &bad, &[]), 0).unwrap_err();
        assert!(e.contains("face 0 uses vertex 7"), "{e}");
    }
}
