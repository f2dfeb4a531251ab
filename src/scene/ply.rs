//! Stanford PLY meshes, read by hand: ASCII, binary little-endian and
//! binary big-endian, following Greg Turk's description of the format
//! ("The PLY Polygon File Format") as the Stanford scans, rply, Blender and
//! MeshLab write it. docs/formats.md lists what is read and what is
//! skipped.
//!
//! The reader never trusts a count before checking it against the bytes
//! that are actually there: every element's smallest possible size times
//! its count is compared with the size of the body before anything is
//! allocated, and every list length in binary data is compared with the
//! bytes that remain. Errors in the header and in ASCII data name
//! `file:line:column`; errors in binary data name the byte offset.

use crate::error::{Error, Result, SourceLoc};
use crate::files::{MAX_PLY_BYTES, read_limited};
use crate::geometry::TriangleMesh;
use glam::{Vec2, Vec3};
use std::fmt;
use std::path::Path;
use std::sync::Arc;

/// A mesh read from a PLY file, with the PLY face each triangle came from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlyMesh {
    /// The triangles: polygons are split into fans around their first vertex.
    pub mesh: TriangleMesh,
    /// For each triangle of `mesh`, the number (from 0) of the `face` entry
    /// of the file it was cut from.
    pub face_of_triangle: Vec<u32>,
    /// What the file contains that trazo skipped or does not support, each
    /// as `file:line:col: … is unsupported: …` (or `file: byte offset N: …`
    /// for binary data).
    pub warnings: Vec<String>,
}

/// Reads a PLY file: see [`parse_ply`]. A missing or unreadable file is an
/// [`Error::File`] naming the path.
pub fn read_ply(path: &Path) -> Result<PlyMesh> {
    let bytes = read_limited(path, MAX_PLY_BYTES).map_err(|e| Error::file(path, format!("cannot read PLY: {e}")))?;
    parse_ply(&bytes, path)
}

/// Reads the triangles of a PLY file. Its warnings are dropped: callers that
/// can report them use [`read_ply`].
pub fn load_ply_mesh(path: &Path) -> Result<TriangleMesh> {
    read_ply(path).map(|p| p.mesh)
}

/// Parses the bytes of a PLY file; `path` is only used in messages.
///
/// Vertices need `x`, `y`, `z`; `nx ny nz` become normals and `u v`,
/// `s t`, `texture_u texture_v` or `texture_s texture_t` texture
/// coordinates. Faces need a `vertex_indices` (or `vertex_index`) list;
/// polygons become fans of triangles. Every other property and element is
/// skipped with a warning.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<PlyMesh> {
    let src = Source {
        bytes,
        path,
        file: Arc::from(path),
    };
    let header = parse_header(&src)?;
    check_sizes(&src, &header)?;
    let mut warnings = Vec::new();
    let plan = plan(&src, &header, &mut warnings)?;
    let mut out = match header.encoding {
        Encoding::Ascii => {
            let mut body = AsciiBody {
                src: &src,
                pos: header.body_start,
                line_end: header.body_start,
            };
            read_body(&mut body, &header, &plan)?
        }
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
            let mut body = BinaryBody {
                src: &src,
                pos: header.body_start,
                big_endian: header.encoding == Encoding::BinaryBigEndian,
            };
            read_body(&mut body, &header, &plan)?
        }
    };
    warnings.append(&mut out.warnings);
    if out.mesh.indices.is_empty() {
        let faces = header.elements.iter().find(|e| e.name == "face").map_or(0, |e| e.count);
        return Err(Error::file(
            path,
            format!("the PLY file has no triangles: none of its {faces} faces has 3 or more vertices"),
        ));
    }
    if let Some((count, first)) = concave_polygons(&out) {
        let face = header
            .elements
            .iter()
            .find(|e| e.name == "face")
            .map_or(0, |e| e.offset);
        warnings.push(format!(
            "{}: concave polygons are approximated: {count} faces, the first `face[{first}]`, are split into fans around their first vertex, which covers a different area",
            src.loc(face)
        ));
    }
    out.warnings = warnings;
    out.mesh
        .validate()
        .map_err(|e| Error::file(path, format!("invalid mesh: {e}")))?;
    Ok(out)
}

/// Counts the polygons (faces cut into more than one triangle) that are not
/// convex, whose fans are therefore wrong; returns the count and the first.
fn concave_polygons(m: &PlyMesh) -> Option<(usize, u32)> {
    let mut count = 0;
    let mut first = None;
    let mut polygon: Vec<Vec3> = Vec::new();
    let mut t = 0;
    while t < m.face_of_triangle.len() {
        let face = m.face_of_triangle[t];
        let run = m.face_of_triangle[t..].iter().take_while(|&&f| f == face).count();
        if run > 1 {
            // The fan [p0 p1 p2], [p0 p2 p3], … gives back p0 p1 p2 p3 ….
            let p = |i: u32| m.mesh.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
            polygon.clear();
            let [a, b, c] = m.mesh.indices[t];
            polygon.extend([p(a), p(b), p(c)]);
            polygon.extend(m.mesh.indices[t + 1..t + run].iter().map(|tri| p(tri[2])));
            if !is_convex(&polygon) {
                count += 1;
                first.get_or_insert(face);
            }
        }
        t += run;
    }
    first.map(|f| (count, f))
}

/// Whether a (nearly planar) polygon turns the same way at every corner, as
/// seen along its Newell normal.
fn is_convex(polygon: &[Vec3]) -> bool {
    let n = polygon.len();
    let corner = |i: usize| (polygon[i % n], polygon[(i + 1) % n], polygon[(i + 2) % n]);
    let normal: Vec3 = (0..n).map(|i| polygon[i].cross(polygon[(i + 1) % n])).sum();
    if normal.length_squared() == 0.0 {
        return true;
    }
    (0..n).all(|i| {
        let (a, b, c) = corner(i);
        let turn = (b - a).cross(c - b);
        turn.dot(normal) >= -1e-5 * turn.length() * normal.length()
    })
}

// ---------------------------------------------------------------------------
// Types of the header.

/// The scalar types of the format ("Property types" in Turk's description),
/// with the sized names that later writers use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }

    /// Bytes in binary data.
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Smallest and largest value of an integer type.
    fn int_range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => (0, u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }
}

const TYPE_NAMES: &str = "char, uchar, short, ushort, int, uint, float, double (or int8, uint8, int16, uint16, int32, uint32, float32, float64)";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: PropKind,
    /// Byte offset of the `property` line in the header.
    offset: usize,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
    /// Byte offsets of the `element` keyword and of the count.
    offset: usize,
    count_offset: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the `end_header` line.
    end_offset: usize,
    /// Byte offset of the first byte after the header.
    body_start: usize,
}

// ---------------------------------------------------------------------------
// Positions and messages.

struct Source<'a> {
    bytes: &'a [u8],
    path: &'a Path,
    file: Arc<Path>,
}

impl Source<'_> {
    /// Line and column of a byte offset. A line ends at `\n`, `\r\n` or a
    /// lone `\r`; columns count characters (UTF-8 lead bytes).
    fn loc(&self, offset: usize) -> SourceLoc {
        let offset = offset.min(self.bytes.len());
        let mut line = 1u32;
        let mut line_start = 0;
        for (i, &b) in self.bytes[..offset].iter().enumerate() {
            let breaks = b == b'\n' || (b == b'\r' && self.bytes.get(i + 1) != Some(&b'\n'));
            if breaks {
                line = line.saturating_add(1);
                line_start = i + 1;
            }
        }
        let column = self.bytes[line_start..offset]
            .iter()
            .filter(|&&b| b & 0xC0 != 0x80)
            .count();
        SourceLoc {
            file: self.file.clone(),
            line,
            column: u32::try_from(column).unwrap_or(u32::MAX - 1) + 1,
        }
    }

    /// An error at a place in the header or in ASCII data.
    fn text_error(&self, offset: usize, key: Option<String>, message: impl Into<String>) -> Error {
        Error::Scene {
            loc: Some(self.loc(offset)),
            key,
            message: message.into(),
        }
    }

    /// An error at a place in binary data.
    fn byte_error(&self, offset: usize, key: &Key, message: impl fmt::Display) -> Error {
        Error::file(self.path, format!("byte offset {offset}: `{key}`: {message}"))
    }
}

/// Names a value in messages: `vertex[3].x`, or `face[7]` for a whole entry.
#[derive(Clone, Copy)]
struct Key<'a> {
    element: &'a str,
    index: u64,
    property: Option<&'a str>,
}

impl<'a> Key<'a> {
    fn with(self, property: &'a str) -> Key<'a> {
        Key {
            property: Some(property),
            ..self
        }
    }
}

impl fmt::Display for Key<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}[{}]", self.element, self.index)?;
        if let Some(p) = self.property {
            write!(f, ".{p}")?;
        }
        Ok(())
    }
}

/// A token for messages: lossy UTF-8, shortened.
fn show(token: &[u8]) -> String {
    let s = String::from_utf8_lossy(&token[..token.len().min(40)]).into_owned();
    if token.len() > 40 { format!("{s}…") } else { s }
}

// ---------------------------------------------------------------------------
// The header.

/// Spaces within a line (not line breaks).
fn is_blank(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | 0x0b | 0x0c)
}

struct Token<'a> {
    text: &'a [u8],
    offset: usize,
}

fn tokens(bytes: &[u8], start: usize, end: usize) -> Vec<Token<'_>> {
    let mut out = Vec::new();
    let mut i = start;
    while i < end {
        if is_blank(bytes[i]) {
            i += 1;
            continue;
        }
        let s = i;
        while i < end && !is_blank(bytes[i]) {
            i += 1;
        }
        out.push(Token {
            text: &bytes[s..i],
            offset: s,
        });
    }
    out
}

fn parse_header(src: &Source) -> Result<Header> {
    let bytes = src.bytes;
    let mut pos = 0;
    let mut line_no = 0u64;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let key = |k: &str| Some(k.to_string());
    loop {
        if pos >= bytes.len() {
            let message = if line_no == 0 {
                "the file is empty: not a PLY file"
            } else {
                "the header has no `end_header` line (the file ends first)"
            };
            return Err(src.text_error(bytes.len(), None, message));
        }
        // Header lines end at `\n`, `\r\n` or `\r`.
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n' || b == b'\r')
            .map_or(bytes.len(), |i| pos + i);
        let next = match bytes.get(end) {
            Some(b'\r') if bytes.get(end + 1) == Some(&b'\n') => end + 2,
            Some(_) => end + 1,
            None => end,
        };
        let toks = tokens(bytes, pos, end);
        let line_start = pos;
        pos = next;
        line_no += 1;
        if line_no == 1 {
            // The magic number (Turk: "ply" on the first line).
            if toks.len() != 1 || toks[0].text != b"ply" {
                return Err(src.text_error(0, None, "not a PLY file: the first line must be `ply`"));
            }
            continue;
        }
        let Some(first) = toks.first() else { continue };
        let extra = |n: usize, k: &str, what: &str| -> Result<()> {
            match toks.get(n) {
                Some(t) => Err(src.text_error(t.offset, key(k), format!("unexpected `{}` after {what}", show(t.text)))),
                None => Ok(()),
            }
        };
        match first.text {
            b"comment" | b"obj_info" => {}
            b"format" => {
                if encoding.is_some() {
                    return Err(src.text_error(first.offset, key("format"), "a second `format` line"));
                }
                if !elements.is_empty() {
                    return Err(src.text_error(
                        first.offset,
                        key("format"),
                        "`format` must come before the first `element`",
                    ));
                }
                let Some(kind) = toks.get(1) else {
                    return Err(src.text_error(
                        line_start,
                        key("format"),
                        "expected `format ascii|binary_little_endian|binary_big_endian 1.0`",
                    ));
                };
                encoding = Some(match kind.text {
                    b"ascii" => Encoding::Ascii,
                    b"binary_little_endian" => Encoding::BinaryLittleEndian,
                    b"binary_big_endian" => Encoding::BinaryBigEndian,
                    other => {
                        return Err(src.text_error(
                            kind.offset,
                            key("format"),
                            format!(
                                "unknown format `{}`: expected ascii, binary_little_endian or binary_big_endian",
                                show(other)
                            ),
                        ));
                    }
                });
                let Some(version) = toks.get(2) else {
                    return Err(src.text_error(
                        line_start,
                        key("format"),
                        "the format line has no version (expected `1.0`)",
                    ));
                };
                if version.text != b"1.0" && version.text != b"1" {
                    return Err(src.text_error(
                        version.offset,
                        key("format"),
                        format!("unsupported version `{}`: trazo reads PLY 1.0", show(version.text)),
                    ));
                }
                extra(3, "format", "the version")?;
            }
            b"element" => {
                if encoding.is_none() {
                    return Err(src.text_error(first.offset, key("element"), "`element` before the `format` line"));
                }
                let (Some(name), Some(count)) = (toks.get(1), toks.get(2)) else {
                    return Err(src.text_error(line_start, key("element"), "expected `element <name> <count>`"));
                };
                let name = String::from_utf8_lossy(name.text).into_owned();
                let k = format!("element {name}");
                extra(3, &k, "the count")?;
                let n = std::str::from_utf8(count.text)
                    .ok()
                    .and_then(|s| s.parse::<u64>().ok())
                    .ok_or_else(|| {
                        src.text_error(
                            count.offset,
                            Some(k.clone()),
                            format!("the count must be a non-negative integer, found `{}`", show(count.text)),
                        )
                    })?;
                if (name == "vertex" || name == "face") && elements.iter().any(|e| e.name == name) {
                    return Err(src.text_error(first.offset, Some(k), format!("a second `{name}` element")));
                }
                elements.push(Element {
                    name,
                    count: n,
                    props: Vec::new(),
                    offset: first.offset,
                    count_offset: count.offset,
                });
            }
            b"property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(src.text_error(first.offset, key("property"), "`property` before any `element`"));
                };
                let k = format!("element {}", element.name);
                let scalar = |t: &Token| -> Result<Scalar> {
                    Scalar::from_name(t.text).ok_or_else(|| {
                        src.text_error(
                            t.offset,
                            Some(k.clone()),
                            format!("unknown property type `{}`: expected {TYPE_NAMES}", show(t.text)),
                        )
                    })
                };
                let (kind, name_at) = match toks.get(1) {
                    Some(t) if t.text == b"list" => {
                        let (Some(c), Some(i)) = (toks.get(2), toks.get(3)) else {
                            return Err(src.text_error(
                                line_start,
                                Some(k),
                                "expected `property list <count type> <item type> <name>`",
                            ));
                        };
                        let count = scalar(c)?;
                        if !count.is_integer() {
                            return Err(src.text_error(
                                c.offset,
                                Some(k),
                                format!("a list's count type must be an integer type, not `{}`", show(c.text)),
                            ));
                        }
                        (
                            PropKind::List {
                                count,
                                item: scalar(i)?,
                            },
                            4,
                        )
                    }
                    Some(t) => (PropKind::Scalar(scalar(t)?), 2),
                    None => {
                        return Err(src.text_error(line_start, Some(k), "expected `property <type> <name>`"));
                    }
                };
                let Some(name) = toks.get(name_at) else {
                    return Err(src.text_error(line_start, Some(k), "the property has no name"));
                };
                extra(name_at + 1, &k, "the property name")?;
                let name = String::from_utf8_lossy(name.text).into_owned();
                if element.props.iter().any(|p| p.name == name) {
                    return Err(src.text_error(first.offset, Some(k), format!("a second property `{name}`")));
                }
                element.props.push(Property {
                    name,
                    kind,
                    offset: first.offset,
                });
            }
            b"end_header" => {
                extra(1, "end_header", "`end_header`")?;
                let Some(encoding) = encoding else {
                    return Err(src.text_error(first.offset, key("end_header"), "the header has no `format` line"));
                };
                return Ok(Header {
                    encoding,
                    elements,
                    end_offset: first.offset,
                    body_start: pos,
                });
            }
            other => {
                return Err(src.text_error(
                    first.offset,
                    None,
                    format!(
                        "unknown header line `{}`: expected comment, obj_info, format, element, property or end_header",
                        show(other)
                    ),
                ));
            }
        }
    }
}

/// Checks, before anything is allocated, that the body can hold what the
/// header declares: each entry takes at least the sizes of its scalars and
/// list counts in binary, and at least two bytes (a digit and a separator)
/// per property in ASCII.
fn check_sizes(src: &Source, h: &Header) -> Result<()> {
    let body = (src.bytes.len() - h.body_start.min(src.bytes.len())) as u64;
    let ascii = h.encoding == Encoding::Ascii;
    // The last ASCII line needs no line break.
    let limit = if ascii { body + 1 } else { body };
    let mut need: u64 = 0;
    for (i, e) in h.elements.iter().enumerate() {
        let k = Some(format!("element {}", e.name));
        let per_entry: u64 = if ascii {
            2 * e.props.len() as u64
        } else {
            e.props
                .iter()
                .map(|p| match p.kind {
                    PropKind::Scalar(t) => t.size() as u64,
                    PropKind::List { count, .. } => count.size() as u64,
                })
                .sum()
        };
        let total = e.count.checked_mul(per_entry).and_then(|n| n.checked_add(need));
        let before = if i == 0 { "" } else { " with the elements before it" };
        let data = if ascii { "ASCII" } else { "binary" };
        match total {
            None => {
                return Err(src.text_error(
                    e.count_offset,
                    k,
                    format!(
                        "{} entries of at least {per_entry} bytes each{before} are more than any file can hold",
                        e.count
                    ),
                ));
            }
            Some(n) if n > limit => {
                return Err(src.text_error(
                    e.count_offset,
                    k,
                    format!(
                        "{} entries need at least {n} bytes of {data} data{before}, but only {body} bytes follow the header (the count is wrong or the file is truncated)",
                        e.count
                    ),
                ));
            }
            Some(n) => need = n,
        }
        if (e.name == "vertex" || e.name == "face") && e.count > u64::from(u32::MAX) {
            return Err(src.text_error(
                e.count_offset,
                Some(format!("element {}", e.name)),
                format!(
                    "{} entries are more than trazo can index (at most {})",
                    e.count,
                    u32::MAX
                ),
            ));
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// What to do with each element and property.

const X: usize = 0;
const NX: usize = 3;
const U: usize = 6;

/// Names of texture coordinate pairs, in order of preference.
const UV_NAMES: [(&str, &str); 4] = [
    ("u", "v"),
    ("s", "t"),
    ("texture_u", "texture_v"),
    ("texture_s", "texture_t"),
];

#[derive(Debug)]
enum Role {
    Vertices {
        /// For each property, the slot of [x y z nx ny nz u v] it fills.
        slots: Vec<Option<usize>>,
        normals: bool,
        uvs: bool,
        attributes: Vec<AttributePlan>,
    },
    Faces {
        /// The property with the vertex indices.
        list: usize,
        vertices: u64,
        attributes: Vec<AttributePlan>,
    },
    Skip,
}

/// Properties of an element read as one mesh attribute.
#[derive(Debug)]
struct AttributePlan {
    /// Mitsuba's name for it: `vertex_color`, `face_weight`.
    name: String,
    /// Its properties, one per channel, in order.
    props: Vec<usize>,
}

/// The channel suffixes Mitsuba groups, by position: x y z w, r g b a,
/// 0 1 2 3 or 1 2 3 4.
const SUFFIXES: [[&str; 4]; 4] = [
    ["x", "y", "z", "w"],
    ["r", "g", "b", "a"],
    ["0", "1", "2", "3"],
    ["1", "2", "3", "4"],
];

/// The element's other scalar properties (those `used` does not mark)
/// grouped into attributes as Mitsuba 3's PLY reader groups them (its
/// `find_other_fields`): `r g b [a]` or `red green blue [alpha]` make
/// `color`; consecutive `P_x P_y P_z` (or with suffixes r g b, 0 1 2, 1 2 3)
/// make `P` (`P_color` for r g b), a lone `P_x` makes `P` of one channel;
/// the names take the element's prefix `vertex_` or `face_`. Marks what it
/// takes in `used`.
fn attribute_plans(e: &Element, prefix: &str, used: &mut [bool]) -> Vec<AttributePlan> {
    let free = |i: usize, used: &[bool]| !used[i] && matches!(e.props[i].kind, PropKind::Scalar(_));
    let find = |name: &str, used: &[bool]| e.props.iter().position(|p| p.name == name).filter(|&i| free(i, used));
    let mut plans = Vec::new();
    for names in [["r", "g", "b", "a"], ["red", "green", "blue", "alpha"]] {
        let rgb: Option<Vec<usize>> = names[..3].iter().map(|n| find(n, used)).collect();
        if let Some(mut props) = rgb {
            props.extend(find(names[3], used));
            for &i in &props {
                used[i] = true;
            }
            plans.push(AttributePlan {
                name: format!("{prefix}color"),
                props,
            });
            break;
        }
    }
    let mut i = 0;
    while i < e.props.len() {
        let Some((stem, suffix)) = e.props[i].name.rsplit_once('_').filter(|_| free(i, used)) else {
            i += 1;
            continue;
        };
        let Some(scheme) = SUFFIXES.iter().position(|s| s[0] == suffix) else {
            i += 1;
            continue;
        };
        let mut props = vec![i];
        while props.len() < 4 {
            let j = i + props.len();
            let next = format!("{stem}_{}", SUFFIXES[scheme][props.len()]);
            if j < e.props.len() && free(j, used) && e.props[j].name == next {
                props.push(j);
            } else {
                break;
            }
        }
        i += props.len();
        // Mitsuba takes one channel or three.
        if props.len() == 1 || props.len() == 3 {
            for &k in &props {
                used[k] = true;
            }
            let color = if scheme == 1 { "_color" } else { "" };
            plans.push(AttributePlan {
                name: format!("{prefix}{stem}{color}"),
                props,
            });
        }
    }
    plans
}

struct Plan {
    roles: Vec<Role>,
}

fn plan(src: &Source, h: &Header, warnings: &mut Vec<String>) -> Result<Plan> {
    let end_key = Some("end_header".to_string());
    let vertex_count = h
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .map(|e| e.count)
        .ok_or_else(|| src.text_error(h.end_offset, end_key.clone(), "the header declares no `vertex` element"))?;
    if !h.elements.iter().any(|e| e.name == "face") {
        return Err(src.text_error(
            h.end_offset,
            end_key,
            "the header declares no `face` element (point clouds cannot be rendered)",
        ));
    }
    let mut roles = Vec::new();
    for e in &h.elements {
        let k = || Some(format!("element {}", e.name));
        let find = |name: &str| e.props.iter().position(|p| p.name == name);
        let scalar = |name: &str| find(name).filter(|&i| matches!(e.props[i].kind, PropKind::Scalar(_)));
        let mut used = vec![false; e.props.len()];
        let role = match e.name.as_str() {
            "vertex" => {
                let mut slots = vec![None; e.props.len()];
                for (slot, name) in ["x", "y", "z"].into_iter().enumerate() {
                    match find(name) {
                        None => {
                            return Err(src.text_error(
                                e.offset,
                                k(),
                                format!("the vertex element has no property `{name}`"),
                            ));
                        }
                        Some(i) if !matches!(e.props[i].kind, PropKind::Scalar(_)) => {
                            return Err(src.text_error(
                                e.props[i].offset,
                                k(),
                                format!("`{name}` must be a scalar property, not a list"),
                            ));
                        }
                        Some(i) => slots[i] = Some(X + slot),
                    }
                }
                let normal = [scalar("nx"), scalar("ny"), scalar("nz")];
                let normals = normal.iter().all(Option::is_some);
                if normals {
                    for (slot, i) in normal.into_iter().flatten().enumerate() {
                        slots[i] = Some(NX + slot);
                    }
                }
                let uv = UV_NAMES.iter().find_map(|(u, v)| Some((scalar(u)?, scalar(v)?)));
                if let Some((iu, iv)) = uv {
                    slots[iu] = Some(U);
                    slots[iv] = Some(U + 1);
                }
                for (u, s) in used.iter_mut().zip(&slots) {
                    *u = s.is_some();
                }
                let attributes = attribute_plans(e, "vertex_", &mut used);
                Role::Vertices {
                    slots,
                    normals,
                    uvs: uv.is_some(),
                    attributes,
                }
            }
            "face" => {
                let Some(list) = find("vertex_indices").or_else(|| find("vertex_index")) else {
                    return Err(src.text_error(
                        e.offset,
                        k(),
                        "the face element has no `vertex_indices` (or `vertex_index`) list",
                    ));
                };
                let p = &e.props[list];
                match p.kind {
                    PropKind::Scalar(_) => {
                        return Err(src.text_error(p.offset, k(), format!("`{}` must be a list property", p.name)));
                    }
                    PropKind::List { item, .. } if !item.is_integer() => {
                        return Err(src.text_error(
                            p.offset,
                            k(),
                            format!("`{}` must list integers, not `{}`", p.name, item.name()),
                        ));
                    }
                    PropKind::List { .. } => {}
                }
                used[list] = true;
                let attributes = attribute_plans(e, "face_", &mut used);
                Role::Faces {
                    list,
                    vertices: vertex_count,
                    attributes,
                }
            }
            _ => {
                if e.count > 0 {
                    let how = if e.name == "tristrips" {
                        "only `face` polygons are read"
                    } else {
                        "trazo reads only `vertex` and `face`"
                    };
                    warnings.push(format!(
                        "{}: element `{}` is unsupported: its {} entries are skipped ({how})",
                        src.loc(e.offset),
                        e.name,
                        e.count
                    ));
                }
                used.fill(true);
                Role::Skip
            }
        };
        let ignored: Vec<&Property> = e
            .props
            .iter()
            .zip(&used)
            .filter(|(_, u)| !**u)
            .map(|(p, _)| p)
            .collect();
        if let Some(first) = ignored.first() {
            let names: Vec<String> = ignored.iter().map(|p| format!("`{}`", p.name)).collect();
            warnings.push(format!(
                "{}: {} {} {} {} unsupported: ignored (trazo reads positions, normals nx ny nz, texture coordinates, vertex indices, and attributes of 1 or 3 channels named as Mitsuba groups them: r g b, P_x P_y P_z, P_0 P_1 P_2…)",
                src.loc(first.offset),
                e.name,
                if names.len() == 1 { "property" } else { "properties" },
                names.join(", "),
                if names.len() == 1 { "is" } else { "are" },
            ));
        }
        roles.push(role);
    }
    Ok(Plan { roles })
}

// ---------------------------------------------------------------------------
// The body, in either encoding.

#[derive(Clone, Copy, Debug)]
enum Num {
    Int(i64),
    Float(f64),
}

impl Num {
    fn as_f64(self) -> f64 {
        match self {
            Num::Int(i) => i as f64,
            Num::Float(f) => f,
        }
    }
}

/// Reads the values of the body one by one, in the order of the header.
trait Body {
    /// Moves to the first value of an entry; `declared` is the element's count.
    fn begin(&mut self, key: &Key, declared: u64) -> Result<()>;
    /// Reads one value; returns where it starts and what it is.
    fn value(&mut self, ty: Scalar, key: &Key) -> Result<(usize, Num)>;
    /// Reads a list's length and checks that its items can be there.
    fn list_len(&mut self, count: Scalar, item: Scalar, key: &Key) -> Result<usize>;
    /// Passes over `n` values.
    fn skip(&mut self, ty: Scalar, n: usize, key: &Key) -> Result<()>;
    /// Ends an entry (in ASCII, its line must end here).
    fn end(&mut self, key: &Key) -> Result<()>;
    /// Passes over `entries` entries of `size` bytes each if the encoding
    /// allows it (binary); returns whether it did.
    fn skip_fixed(&mut self, entries: u64, size: u64, key: &Key) -> Result<bool>;
    /// Where the next value starts.
    fn offset(&self) -> usize;
    /// An error at a place of the body.
    fn error(&self, offset: usize, key: &Key, message: String) -> Error;
    /// A place of the body for warnings.
    fn place(&self, offset: usize) -> String;
    /// Checks what follows the last element.
    fn finish(&mut self, warnings: &mut Vec<String>) -> Result<()>;
}

struct BinaryBody<'a> {
    src: &'a Source<'a>,
    pos: usize,
    big_endian: bool,
}

impl BinaryBody<'_> {
    fn remaining(&self) -> usize {
        self.src.bytes.len().saturating_sub(self.pos)
    }

    fn take(&mut self, n: usize, key: &Key) -> Result<&[u8]> {
        if self.remaining() < n {
            return Err(self.src.byte_error(
                self.pos,
                key,
                format!(
                    "the file ends in the middle of the data: {n} more bytes needed, {} left",
                    self.remaining()
                ),
            ));
        }
        let s = &self.src.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
}

fn array<const N: usize>(b: &[u8]) -> [u8; N] {
    let mut a = [0u8; N];
    a.copy_from_slice(&b[..N]);
    a
}

impl Body for BinaryBody<'_> {
    fn begin(&mut self, _key: &Key, _declared: u64) -> Result<()> {
        Ok(())
    }

    fn value(&mut self, ty: Scalar, key: &Key) -> Result<(usize, Num)> {
        let at = self.pos;
        let be = self.big_endian;
        let b = self.take(ty.size(), key)?;
        macro_rules! int {
            ($t:ty) => {{
                let a = array(b);
                Num::Int(i64::from(if be {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }))
            }};
        }
        let n = match ty {
            Scalar::I8 => int!(i8),
            Scalar::U8 => int!(u8),
            Scalar::I16 => int!(i16),
            Scalar::U16 => int!(u16),
            Scalar::I32 => int!(i32),
            Scalar::U32 => int!(u32),
            Scalar::F32 => {
                let a = array(b);
                Num::Float(f64::from(if be {
                    f32::from_be_bytes(a)
                } else {
                    f32::from_le_bytes(a)
                }))
            }
            Scalar::F64 => {
                let a = array(b);
                Num::Float(if be {
                    f64::from_be_bytes(a)
                } else {
                    f64::from_le_bytes(a)
                })
            }
        };
        Ok((at, n))
    }

    fn list_len(&mut self, count: Scalar, item: Scalar, key: &Key) -> Result<usize> {
        let (at, n) = self.value(count, key)?;
        let n = match n {
            Num::Int(n) if n >= 0 => n as u64,
            other => {
                return Err(self
                    .src
                    .byte_error(at, key, format!("list count {} is negative", other.as_f64())));
            }
        };
        let need = n.checked_mul(item.size() as u64);
        match need {
            Some(need) if need <= self.remaining() as u64 => Ok(n as usize),
            _ => Err(self.src.byte_error(
                at,
                key,
                format!(
                    "a list of {n} {} items needs more than the {} bytes left in the file",
                    item.name(),
                    self.remaining()
                ),
            )),
        }
    }

    fn skip(&mut self, ty: Scalar, n: usize, key: &Key) -> Result<()> {
        let bytes = n.saturating_mul(ty.size());
        self.take(bytes, key).map(|_| ())
    }

    fn end(&mut self, _key: &Key) -> Result<()> {
        Ok(())
    }

    fn skip_fixed(&mut self, entries: u64, size: u64, key: &Key) -> Result<bool> {
        let bytes = entries
            .checked_mul(size)
            .and_then(|b| usize::try_from(b).ok())
            .unwrap_or(usize::MAX);
        self.take(bytes, key)?;
        Ok(true)
    }

    fn offset(&self) -> usize {
        self.pos
    }

    fn error(&self, offset: usize, key: &Key, message: String) -> Error {
        self.src.byte_error(offset, key, message)
    }

    fn place(&self, offset: usize) -> String {
        format!("{}: byte offset {offset}", self.src.path.display())
    }

    fn finish(&mut self, warnings: &mut Vec<String>) -> Result<()> {
        let left = self.remaining();
        if left > 0 {
            warnings.push(format!(
                "{}: {left} bytes after the last element the header declares are unsupported: ignored",
                self.place(self.pos)
            ));
        }
        Ok(())
    }
}

/// ASCII data: one entry per line (Turk: "each element on its own line"),
/// values separated by spaces; blank lines are passed over.
struct AsciiBody<'a> {
    src: &'a Source<'a>,
    pos: usize,
    /// End of the current entry's line.
    line_end: usize,
}

impl<'a> AsciiBody<'a> {
    /// The next token on the current line, or an error naming `key`.
    fn token(&mut self, key: &Key) -> Result<(usize, &'a [u8])> {
        let bytes = self.src.bytes;
        while self.pos < self.line_end && is_blank(bytes[self.pos]) {
            self.pos += 1;
        }
        if self.pos >= self.line_end {
            return Err(self.error(self.pos, key, "the line ends before this value".into()));
        }
        let start = self.pos;
        while self.pos < self.line_end && !is_blank(bytes[self.pos]) {
            self.pos += 1;
        }
        Ok((start, &bytes[start..self.pos]))
    }
}

impl Body for AsciiBody<'_> {
    fn begin(&mut self, key: &Key, declared: u64) -> Result<()> {
        let bytes = self.src.bytes;
        while self.pos < bytes.len() && (is_blank(bytes[self.pos]) || matches!(bytes[self.pos], b'\n' | b'\r')) {
            self.pos += 1;
        }
        if self.pos >= bytes.len() {
            return Err(self.error(
                self.pos,
                key,
                format!(
                    "the file ends before this entry (the header declares {declared} `{}` entries)",
                    key.element
                ),
            ));
        }
        self.line_end = bytes[self.pos..]
            .iter()
            .position(|&b| b == b'\n' || b == b'\r')
            .map_or(bytes.len(), |i| self.pos + i);
        Ok(())
    }

    fn value(&mut self, ty: Scalar, key: &Key) -> Result<(usize, Num)> {
        let (at, tok) = self.token(key)?;
        let text = std::str::from_utf8(tok).ok();
        let n = if ty.is_integer() {
            let Some(i) = text.and_then(|s| s.parse::<i64>().ok()) else {
                return Err(self.error(
                    at,
                    key,
                    format!("expected an integer ({}), found `{}`", ty.name(), show(tok)),
                ));
            };
            let (lo, hi) = ty.int_range();
            if i < lo || i > hi {
                return Err(self.error(at, key, format!("{i} is out of range for {} ({lo} to {hi})", ty.name())));
            }
            Num::Int(i)
        } else {
            let Some(f) = text.and_then(|s| s.parse::<f64>().ok()) else {
                return Err(self.error(
                    at,
                    key,
                    format!("expected a number ({}), found `{}`", ty.name(), show(tok)),
                ));
            };
            Num::Float(f)
        };
        Ok((at, n))
    }

    fn list_len(&mut self, count: Scalar, _item: Scalar, key: &Key) -> Result<usize> {
        let (at, n) = self.value(count, key)?;
        match n {
            Num::Int(n) if n < 0 => Err(self.error(at, key, format!("list count {n} is negative"))),
            // Each item takes a separator and a digit at least.
            Num::Int(n) if n as u64 <= (self.line_end - self.pos) as u64 / 2 => Ok(n as usize),
            n => Err(self.error(
                at,
                key,
                format!("the list count {} is larger than the values on the line", n.as_f64()),
            )),
        }
    }

    fn skip(&mut self, ty: Scalar, n: usize, key: &Key) -> Result<()> {
        for _ in 0..n {
            self.value(ty, key)?;
        }
        Ok(())
    }

    fn end(&mut self, key: &Key) -> Result<()> {
        let bytes = self.src.bytes;
        while self.pos < self.line_end && is_blank(bytes[self.pos]) {
            self.pos += 1;
        }
        if self.pos < self.line_end {
            let at = self.pos;
            let (_, tok) = self.token(key)?;
            return Err(self.error(
                at,
                key,
                format!(
                    "unexpected `{}` after the last property of the entry (the line has more values than the header declares)",
                    show(tok)
                ),
            ));
        }
        Ok(())
    }

    fn skip_fixed(&mut self, _entries: u64, _size: u64, _key: &Key) -> Result<bool> {
        Ok(false)
    }

    fn offset(&self) -> usize {
        self.pos
    }

    fn error(&self, offset: usize, key: &Key, message: String) -> Error {
        self.src.text_error(offset, Some(key.to_string()), message)
    }

    fn place(&self, offset: usize) -> String {
        self.src.loc(offset).to_string()
    }

    fn finish(&mut self, _warnings: &mut Vec<String>) -> Result<()> {
        let bytes = self.src.bytes;
        let rest = bytes[self.pos.min(bytes.len())..]
            .iter()
            .position(|&b| !(is_blank(b) || b == b'\n' || b == b'\r'));
        if let Some(i) = rest {
            let at = self.pos + i;
            let end = bytes[at..]
                .iter()
                .position(|&b| is_blank(b) || b == b'\n' || b == b'\r')
                .map_or(bytes.len(), |j| at + j);
            return Err(self.src.text_error(
                at,
                None,
                format!(
                    "unexpected `{}` after the last element: the file has more data than the header declares",
                    show(&bytes[at..end])
                ),
            ));
        }
        Ok(())
    }
}

fn read_body<B: Body>(b: &mut B, h: &Header, plan: &Plan) -> Result<PlyMesh> {
    let mut out = PlyMesh::default();
    for (e, role) in h.elements.iter().zip(&plan.roles) {
        let entry = |index| Key {
            element: &e.name,
            index,
            property: None,
        };
        match role {
            Role::Vertices {
                slots,
                normals,
                uvs,
                attributes,
            } => read_vertices(b, e, slots, *normals, *uvs, attributes, &mut out.mesh)?,
            Role::Faces {
                list,
                vertices,
                attributes,
            } => read_faces(b, e, *list, *vertices, attributes, &mut out)?,
            Role::Skip => {
                // An entry without properties has nothing in the body.
                if e.props.is_empty() {
                    continue;
                }
                let fixed: Option<u64> = e
                    .props
                    .iter()
                    .map(|p| match p.kind {
                        PropKind::Scalar(t) => Some(t.size() as u64),
                        PropKind::List { .. } => None,
                    })
                    .sum();
                if let Some(size) = fixed {
                    if b.skip_fixed(e.count, size, &entry(0))? {
                        continue;
                    }
                }
                for i in 0..e.count {
                    let key = entry(i);
                    b.begin(&key, e.count)?;
                    for p in &e.props {
                        skip_property(b, p, &key.with(&p.name))?;
                    }
                    b.end(&key)?;
                }
            }
        }
    }
    b.finish(&mut out.warnings)?;
    Ok(out)
}

fn skip_property<B: Body>(b: &mut B, p: &Property, key: &Key) -> Result<()> {
    match p.kind {
        PropKind::Scalar(t) => b.value(t, key).map(|_| ()),
        PropKind::List { count, item } => {
            let n = b.list_len(count, item, key)?;
            b.skip(item, n, key)
        }
    }
}

/// For each property of an element, the attribute and channel it fills,
/// and the attributes' empty value arrays.
fn attribute_targets(
    e: &Element,
    plans: &[AttributePlan],
    per_face: bool,
) -> (Vec<Option<(usize, usize)>>, Vec<crate::geometry::mesh::MeshAttribute>) {
    let mut target = vec![None; e.props.len()];
    let mut attributes = Vec::new();
    for (a, plan) in plans.iter().enumerate() {
        for (channel, &p) in plan.props.iter().enumerate() {
            target[p] = Some((a, channel));
        }
        attributes.push(crate::geometry::mesh::MeshAttribute {
            name: plan.name.clone(),
            per_face,
            channels: plan.props.len(),
            values: Vec::new(),
        });
    }
    (target, attributes)
}

#[allow(clippy::too_many_arguments)]
fn read_vertices<B: Body>(
    b: &mut B,
    e: &Element,
    slots: &[Option<usize>],
    normals: bool,
    uvs: bool,
    plans: &[AttributePlan],
    mesh: &mut TriangleMesh,
) -> Result<()> {
    let (target, mut attributes) = attribute_targets(e, plans, false);
    let mut vertex_values: Vec<Vec<f32>> = attributes.iter().map(|a| vec![0.0; a.channels]).collect();
    // The count was checked against the size of the body.
    let n = e.count as usize;
    mesh.positions.reserve(n);
    if normals {
        mesh.normals.reserve(n);
    }
    if uvs {
        mesh.uvs.reserve(n);
    }
    for i in 0..e.count {
        let key = Key {
            element: &e.name,
            index: i,
            property: None,
        };
        b.begin(&key, e.count)?;
        let start = b.offset();
        let mut v = [0.0f64; 8];
        for ((p, slot), to) in e.props.iter().zip(slots).zip(&target) {
            match (p.kind, slot, to) {
                (PropKind::Scalar(t), Some(s), _) => v[*s] = b.value(t, &key.with(&p.name))?.1.as_f64(),
                (PropKind::Scalar(t), None, Some((a, channel))) => {
                    vertex_values[*a][*channel] = b.value(t, &key.with(&p.name))?.1.as_f64() as f32;
                }
                _ => skip_property(b, p, &key.with(&p.name))?,
            }
        }
        b.end(&key)?;
        for (a, values) in attributes.iter_mut().zip(&vertex_values) {
            a.values.extend_from_slice(values);
        }
        let f = |s: usize| v[s] as f32;
        let position = Vec3::new(f(X), f(X + 1), f(X + 2));
        if !position.is_finite() {
            return Err(b.error(
                start,
                &key,
                format!(
                    "position ({}, {}, {}) is not finite (NaN, infinite or beyond 32-bit floats)",
                    v[X],
                    v[X + 1],
                    v[X + 2]
                ),
            ));
        }
        mesh.positions.push(position);
        if normals {
            let normal = Vec3::new(f(NX), f(NX + 1), f(NX + 2));
            if !normal.is_finite() {
                return Err(b.error(start, &key, "the normal is NaN or infinite".into()));
            }
            mesh.normals.push(normal);
        }
        if uvs {
            let uv = Vec2::new(f(U), f(U + 1));
            if !uv.is_finite() {
                return Err(b.error(start, &key, "the texture coordinates are NaN or infinite".into()));
            }
            mesh.uvs.push(uv);
        }
    }
    mesh.attributes.extend(attributes);
    Ok(())
}

fn read_faces<B: Body>(
    b: &mut B,
    e: &Element,
    list: usize,
    vertices: u64,
    plans: &[AttributePlan],
    out: &mut PlyMesh,
) -> Result<()> {
    let (target, mut attributes) = attribute_targets(e, plans, true);
    // The face's values, then one copy per triangle it makes.
    let mut face_values: Vec<Vec<f32>> = attributes.iter().map(|a| vec![0.0; a.channels]).collect();
    // The count was checked against the size of the body; most faces give
    // one triangle at least.
    out.mesh.indices.reserve(e.count as usize);
    out.face_of_triangle.reserve(e.count as usize);
    let mut polygon: Vec<u32> = Vec::new();
    let mut degenerate = 0u64;
    let mut first_degenerate = None;
    for i in 0..e.count {
        let key = Key {
            element: &e.name,
            index: i,
            property: None,
        };
        b.begin(&key, e.count)?;
        let start = b.offset();
        polygon.clear();
        for (pi, p) in e.props.iter().enumerate() {
            let pkey = key.with(&p.name);
            let PropKind::List { count, item } = p.kind else {
                match (p.kind, target[pi]) {
                    (PropKind::Scalar(t), Some((a, channel))) => {
                        face_values[a][channel] = b.value(t, &pkey)?.1.as_f64() as f32;
                    }
                    _ => skip_property(b, p, &pkey)?,
                }
                continue;
            };
            if pi != list {
                skip_property(b, p, &pkey)?;
                continue;
            }
            let n = b.list_len(count, item, &pkey)?;
            for _ in 0..n {
                let (at, v) = b.value(item, &pkey)?;
                let index = match v {
                    Num::Int(v) if v >= 0 && (v as u64) < vertices => v as u32,
                    Num::Int(v) if v < 0 => {
                        return Err(b.error(at, &pkey, format!("vertex index {v} is negative")));
                    }
                    v => {
                        return Err(b.error(
                            at,
                            &pkey,
                            format!(
                                "vertex index {} is out of range: the file has {vertices} vertices",
                                v.as_f64()
                            ),
                        ));
                    }
                };
                polygon.push(index);
            }
        }
        b.end(&key)?;
        if polygon.len() < 3 {
            degenerate += 1;
            first_degenerate.get_or_insert((i, start));
            continue;
        }
        // A convex polygon as a fan around its first vertex (the usual
        // reading of PLY faces; concave polygons are not split correctly).
        let face = i as u32;
        for k in 1..polygon.len() - 1 {
            out.mesh.indices.push([polygon[0], polygon[k], polygon[k + 1]]);
            out.face_of_triangle.push(face);
            for (a, values) in attributes.iter_mut().zip(&face_values) {
                a.values.extend_from_slice(values);
            }
        }
    }
    out.mesh.attributes.extend(attributes);
    if let Some((i, at)) = first_degenerate {
        out.warnings.push(format!(
            "{}: faces with fewer than 3 vertices are unsupported: {degenerate} skipped, the first is `{}[{i}]`",
            b.place(at),
            e.name
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A property for the test writer: (type, name) or (count type, item type, name).
    #[derive(Clone, Copy)]
    enum P {
        S(&'static str, &'static str),
        L(&'static str, &'static str, &'static str),
    }

    struct El {
        name: &'static str,
        props: Vec<P>,
        /// Per entry, per property: one value for a scalar, the items of a list.
        rows: Vec<Vec<Vec<f64>>>,
    }

    fn ty(name: &str) -> Scalar {
        Scalar::from_name(name.as_bytes()).unwrap()
    }

    fn put(out: &mut Vec<u8>, t: Scalar, v: f64, enc: &str) {
        let be = enc == "binary_big_endian";
        macro_rules! w {
            ($x:expr) => {{
                let x = $x;
                out.extend_from_slice(&if be { x.to_be_bytes() } else { x.to_le_bytes() });
            }};
        }
        if enc == "ascii" {
            let s = if t.is_integer() {
                format!("{}", v as i64)
            } else {
                format!("{v}")
            };
            out.extend_from_slice(s.as_bytes());
            out.push(b' ');
            return;
        }
        match t {
            Scalar::I8 => w!(v as i8),
            Scalar::U8 => w!(v as u8),
            Scalar::I16 => w!(v as i16),
            Scalar::U16 => w!(v as u16),
            Scalar::I32 => w!(v as i32),
            Scalar::U32 => w!(v as u32),
            Scalar::F32 => w!(v as f32),
            Scalar::F64 => w!(v),
        }
    }

    /// Writes a PLY file in encoding `enc` ("ascii", "binary_little_endian",
    /// "binary_big_endian").
    fn write(enc: &str, elements: &[El]) -> Vec<u8> {
        let mut out = format!("ply\nformat {enc} 1.0\ncomment written by the test writer\n").into_bytes();
        for e in elements {
            out.extend_from_slice(format!("element {} {}\n", e.name, e.rows.len()).as_bytes());
            for p in &e.props {
                let line = match p {
                    P::S(t, n) => format!("property {t} {n}\n"),
                    P::L(c, i, n) => format!("property list {c} {i} {n}\n"),
                };
                out.extend_from_slice(line.as_bytes());
            }
        }
        out.extend_from_slice(b"end_header\n");
        for e in elements {
            for row in &e.rows {
                for (p, vals) in e.props.iter().zip(row) {
                    match p {
                        P::S(t, _) => put(&mut out, ty(t), vals[0], enc),
                        P::L(c, i, _) => {
                            put(&mut out, ty(c), vals.len() as f64, enc);
                            for &v in vals {
                                put(&mut out, ty(i), v, enc);
                            }
                        }
                    }
                }
                if enc == "ascii" {
                    out.pop();
                    out.push(b'\n');
                }
            }
        }
        out
    }

    const ENCODINGS: [&str; 3] = ["ascii", "binary_little_endian", "binary_big_endian"];

    fn parse(bytes: &[u8]) -> Result<PlyMesh> {
        parse_ply(bytes, Path::new("dir/model.ply"))
    }

    fn err(bytes: &[u8]) -> String {
        match parse(bytes) {
            Ok(m) => panic!("expected an error, got {m:?}"),
            Err(e) => e.to_string(),
        }
    }

    fn text_err(text: &str) -> String {
        err(text.as_bytes())
    }

    /// Five vertices of a pentagon in the z = 1 plane.
    fn pentagon() -> Vec<[f64; 3]> {
        (0..5)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 5.0;
                [a.cos(), a.sin(), 1.0]
            })
            .collect()
    }

    fn vertex_rows(extra: impl Fn(usize) -> Vec<Vec<f64>>) -> Vec<Vec<Vec<f64>>> {
        pentagon()
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut row = vec![vec![p[0]], vec![p[1]], vec![p[2]]];
                row.extend(extra(i));
                row
            })
            .collect()
    }

    /// A quad, a triangle, a pentagon.
    fn face_rows() -> Vec<Vec<Vec<f64>>> {
        vec![
            vec![vec![0.0, 1.0, 2.0, 3.0]],
            vec![vec![4.0, 0.0, 2.0]],
            vec![vec![0.0, 1.0, 2.0, 3.0, 4.0]],
        ]
    }

    fn simple(enc: &str) -> Vec<u8> {
        write(
            enc,
            &[
                El {
                    name: "vertex",
                    props: vec![P::S("float", "x"), P::S("float", "y"), P::S("float", "z")],
                    rows: vertex_rows(|_| vec![]),
                },
                El {
                    name: "face",
                    props: vec![P::L("uchar", "int", "vertex_indices")],
                    rows: face_rows(),
                },
            ],
        )
    }

    #[test]
    fn polygons_become_fans_that_remember_their_face() {
        for enc in ENCODINGS {
            let m = parse(&simple(enc)).unwrap();
            assert_eq!(m.mesh.positions.len(), 5, "{enc}");
            for (p, q) in m.mesh.positions.iter().zip(pentagon()) {
                assert!((*p - Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32)).length() < 1e-6);
            }
            assert_eq!(
                m.mesh.indices,
                vec![[0, 1, 2], [0, 2, 3], [4, 0, 2], [0, 1, 2], [0, 2, 3], [0, 3, 4]],
                "{enc}"
            );
            assert_eq!(m.face_of_triangle, vec![0, 0, 1, 2, 2, 2], "{enc}");
            assert!(m.mesh.normals.is_empty() && m.mesh.uvs.is_empty());
            assert!(m.warnings.is_empty(), "{:?}", m.warnings);
        }
    }

    /// Vertices with normals, texture coordinates, colours and a list; faces
    /// with flags and per-face texture coordinates; `edge`, `material` and
    /// `tristrips` elements between and after them.
    fn busy(enc: &str, uv: (&'static str, &'static str)) -> Vec<u8> {
        write(
            enc,
            &[
                El {
                    name: "material",
                    props: vec![P::S("uchar", "ambient_red"), P::S("float", "shininess")],
                    rows: vec![vec![vec![200.0], vec![0.5]]],
                },
                El {
                    name: "vertex",
                    props: vec![
                        P::S("double", "x"),
                        P::S("uchar", "red"),
                        P::S("double", "y"),
                        P::L("uchar", "float", "weights"),
                        P::S("double", "z"),
                        P::S("float", "nx"),
                        P::S("float", "ny"),
                        P::S("float", "nz"),
                        P::S("float", uv.0),
                        P::S("short", "confidence"),
                        P::S("float", uv.1),
                        P::L("int", "ushort", "neighbours"),
                    ],
                    rows: vertex_rows(|i| {
                        vec![
                            vec![(i * 40) as f64],
                            vec![0.25; i],
                            vec![0.0],
                            vec![0.6],
                            vec![0.8],
                            vec![i as f64 * 0.25],
                            vec![-7.0],
                            vec![1.0 - i as f64 * 0.125],
                            vec![1.0, 2.0],
                        ]
                    })
                    .into_iter()
                    .map(|mut r| {
                        // Put the values in the order of the properties.
                        let (x, y, z) = (r.remove(0), r.remove(0), r.remove(0));
                        let red = r.remove(0);
                        let weights = r.remove(0);
                        let mut row = vec![x, red, y, weights, z];
                        row.extend(r);
                        row
                    })
                    .collect(),
                },
                El {
                    name: "edge",
                    props: vec![P::S("int", "vertex1"), P::S("int", "vertex2"), P::S("uchar", "crease")],
                    rows: vec![vec![vec![0.0], vec![1.0], vec![3.0]]; 4],
                },
                El {
                    name: "face",
                    props: vec![
                        P::S("uchar", "flags"),
                        P::L("uint8", "uint32", "vertex_indices"),
                        P::L("uchar", "float", "texcoord"),
                    ],
                    rows: face_rows()
                        .into_iter()
                        .map(|r| vec![vec![9.0], r[0].clone(), vec![0.5; 6]])
                        .collect(),
                },
                El {
                    name: "tristrips",
                    props: vec![P::L("int", "int", "vertex_indices")],
                    rows: vec![vec![vec![0.0, 1.0, 2.0, -1.0, 3.0, 4.0, 0.0]]],
                },
            ],
        )
    }

    /// Other properties become attributes named as Mitsuba names them;
    /// polygons give each of their triangles the face's values.
    #[test]
    fn attributes_are_grouped_as_mitsuba_groups_them() {
        let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
                    property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float n_x\nproperty float n_y\n\
                    property float temp_1\nelement face 1\nproperty list uchar int vertex_indices\nproperty float tint_r\n\
                    property float tint_g\nproperty float tint_b\nend_header\n\
                    0 0 0 1 2 3 0 0 10\n1 0 0 4 5 6 0 0 20\n1 1 0 7 8 9 0 0 30\n0 1 0 0 0 0 0 0 40\n4 0 1 2 3 0.1 0.2 0.3\n";
        let m = parse_ply(text.as_bytes(), Path::new("a.ply")).unwrap();
        let got: Vec<(&str, bool, usize, &[f32])> = m
            .mesh
            .attributes
            .iter()
            .map(|a| (a.name.as_str(), a.per_face, a.channels, a.values.as_slice()))
            .collect();
        let colours = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 0.0, 0.0, 0.0];
        let tint = [0.1, 0.2, 0.3, 0.1, 0.2, 0.3];
        assert_eq!(
            got,
            [
                ("vertex_color", false, 3, &colours[..]),
                ("vertex_temp", false, 1, &[10.0, 20.0, 30.0, 40.0][..]),
                ("face_tint_color", true, 3, &tint[..]),
            ]
        );
        m.mesh.validate().unwrap();
        // Two channels are not an attribute in Mitsuba: skipped, named.
        let w = m.warnings.join("\n");
        assert!(w.contains("vertex properties `n_x`, `n_y` are unsupported"), "{w}");
    }

    #[test]
    fn extra_properties_and_elements_are_skipped_in_every_encoding() {
        let meshes: Vec<PlyMesh> = ENCODINGS.iter().map(|e| parse(&busy(e, ("u", "v"))).unwrap()).collect();
        let m = &meshes[0];
        let plain = parse(&simple("ascii")).unwrap();
        assert_eq!(m.mesh.indices, plain.mesh.indices);
        assert_eq!(m.face_of_triangle, plain.face_of_triangle);
        for (p, q) in m.mesh.positions.iter().zip(&plain.mesh.positions) {
            assert!((*p - *q).length() < 1e-6);
        }
        assert_eq!(m.mesh.normals, vec![Vec3::new(0.0, 0.6, 0.8); 5]);
        assert_eq!(m.mesh.uvs[2], Vec2::new(0.5, 0.75));
        assert_eq!(m.mesh.uvs.len(), 5);
        // The binary files give the same mesh as the ASCII one (up to the
        // decimal printing of doubles), and big-endian equals little-endian.
        assert_eq!(meshes[1], meshes[2]);
        assert_eq!(meshes[1].mesh.indices, m.mesh.indices);
        for (p, q) in meshes[1].mesh.positions.iter().zip(&m.mesh.positions) {
            assert!((*p - *q).length() < 1e-6);
        }
        // Nothing skipped goes unmentioned.
        let w = m.warnings.join("\n");
        for what in [
            "element `material` is unsupported",
            "element `edge` is unsupported",
            "element `tristrips` is unsupported",
            "vertex properties `red`, `weights`, `confidence`, `neighbours` are unsupported",
            "face properties `flags`, `texcoord` are unsupported",
        ] {
            assert!(w.contains(what), "no warning about {what}: {w}");
        }
        assert!(w.contains("dir/model.ply:4:1: element `material`"), "{w}");
    }

    #[test]
    fn every_texture_coordinate_naming_is_read() {
        for names in UV_NAMES {
            for enc in ENCODINGS {
                let m = parse(&busy(enc, names)).unwrap();
                assert_eq!(m.mesh.uvs.len(), 5, "{names:?} {enc}");
                assert_eq!(m.mesh.uvs[4], Vec2::new(1.0, 0.5), "{names:?} {enc}");
            }
        }
    }

    #[test]
    fn every_scalar_type_is_read_in_every_encoding() {
        let types = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double"];
        let sized = [
            "int8", "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64",
        ];
        for enc in ENCODINGS {
            for (i, (&t, &s)) in types.iter().zip(&sized).enumerate() {
                let z = types[(i + 3) % 8];
                let count = ["uchar", "char", "ushort", "short", "uint", "int", "uint8", "int32"][i];
                let index = ["int", "uint", "short", "ushort", "char", "uchar", "int16", "uint32"][i];
                let bytes = write(
                    enc,
                    &[
                        El {
                            name: "vertex",
                            props: vec![P::S(t, "x"), P::S(s, "y"), P::S(z, "z")],
                            rows: vec![
                                vec![vec![1.0], vec![2.0], vec![3.0]],
                                vec![vec![100.0], vec![0.0], vec![0.0]],
                                vec![vec![0.0], vec![120.0], vec![0.0]],
                            ],
                        },
                        El {
                            name: "face",
                            props: vec![P::L(count, index, "vertex_index")],
                            rows: vec![vec![vec![2.0, 1.0, 0.0]]],
                        },
                    ],
                );
                let m = parse(&bytes).unwrap_or_else(|e| panic!("{enc} {t} {s} {z}: {e}"));
                assert_eq!(
                    m.mesh.positions,
                    vec![
                        Vec3::new(1.0, 2.0, 3.0),
                        Vec3::new(100.0, 0.0, 0.0),
                        Vec3::new(0.0, 120.0, 0.0)
                    ],
                    "{enc} {t} {s} {z}"
                );
                assert_eq!(m.mesh.indices, vec![[2, 1, 0]]);
            }
        }
    }

    #[test]
    fn negative_values_of_signed_types_and_large_unsigned_ones() {
        for enc in ENCODINGS {
            let bytes = write(
                enc,
                &[
                    El {
                        name: "vertex",
                        props: vec![P::S("char", "x"), P::S("short", "y"), P::S("int", "z")],
                        rows: vec![
                            vec![vec![-128.0], vec![-32768.0], vec![-2147483648.0]],
                            vec![vec![127.0], vec![32767.0], vec![2147483647.0]],
                            vec![vec![0.0], vec![0.0], vec![0.0]],
                        ],
                    },
                    El {
                        name: "face",
                        props: vec![P::L("uint", "uint", "vertex_indices")],
                        rows: vec![vec![vec![0.0, 1.0, 2.0]]],
                    },
                ],
            );
            let m = parse(&bytes).unwrap();
            assert_eq!(m.mesh.positions[0], Vec3::new(-128.0, -32768.0, -2147483648.0), "{enc}");
            assert_eq!(m.mesh.positions[1], Vec3::new(127.0, 32767.0, 2147483647.0), "{enc}");
        }
    }

    #[test]
    fn normals_and_uvs_need_both_or_all_three_properties() {
        for enc in ENCODINGS {
            let bytes = write(
                enc,
                &[
                    El {
                        name: "vertex",
                        props: vec![
                            P::S("float", "x"),
                            P::S("float", "y"),
                            P::S("float", "z"),
                            P::S("float", "nx"),
                            P::S("float", "ny"),
                            P::S("float", "u"),
                        ],
                        rows: vertex_rows(|_| vec![vec![1.0], vec![0.0], vec![0.5]]),
                    },
                    El {
                        name: "face",
                        props: vec![P::L("uchar", "int", "vertex_indices")],
                        rows: face_rows(),
                    },
                ],
            );
            let m = parse(&bytes).unwrap();
            assert!(m.mesh.normals.is_empty() && m.mesh.uvs.is_empty(), "{enc}");
            assert!(
                m.warnings[0].contains("dir/model.ply:8:1: vertex properties `nx`, `ny`, `u` are unsupported"),
                "{:?}",
                m.warnings
            );
        }
    }

    #[test]
    fn faces_with_fewer_than_three_vertices_are_skipped_with_a_warning() {
        for enc in ENCODINGS {
            let bytes = write(
                enc,
                &[
                    El {
                        name: "vertex",
                        props: vec![P::S("float", "x"), P::S("float", "y"), P::S("float", "z")],
                        rows: vertex_rows(|_| vec![]),
                    },
                    El {
                        name: "face",
                        props: vec![P::L("uchar", "int", "vertex_indices")],
                        rows: vec![
                            vec![vec![0.0, 1.0]],
                            vec![vec![0.0, 1.0, 2.0, 3.0]],
                            vec![vec![]],
                            vec![vec![2.0, 3.0, 4.0]],
                        ],
                    },
                ],
            );
            let m = parse(&bytes).unwrap();
            assert_eq!(m.face_of_triangle, vec![1, 1, 3], "{enc}");
            assert_eq!(m.mesh.indices, vec![[0, 1, 2], [0, 2, 3], [2, 3, 4]]);
            assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
            let w = &m.warnings[0];
            assert!(
                w.contains("fewer than 3 vertices") && w.contains("2 skipped") && w.contains("`face[0]`"),
                "{w}"
            );
            let place = if enc == "ascii" {
                "dir/model.ply:16:1:"
            } else {
                "dir/model.ply: byte offset "
            };
            assert!(w.starts_with(place), "{w}");
        }
    }

    #[test]
    fn concave_polygons_are_fanned_with_a_warning() {
        // A dart: the corner at (0.5, 0.5) points inwards. Counted in either
        // winding; the convex square that follows is not.
        let text = "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n\
                    element face 3\nproperty list uchar int vertex_indices\nend_header\n\
                    0 0 0\n2 0 0\n0.5 0.5 0\n0 2 0\n5 0 0\n6 0 0\n6 1 0\n5 1 0\n\
                    4 0 1 2 3\n4 3 2 1 0\n4 4 5 6 7\n";
        let m = parse(text.as_bytes()).unwrap();
        assert_eq!(m.face_of_triangle, vec![0, 0, 1, 1, 2, 2]);
        assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
        assert!(
            m.warnings[0]
                .starts_with("dir/model.ply:7:1: concave polygons are approximated: 2 faces, the first `face[0]`"),
            "{:?}",
            m.warnings
        );
        assert!(is_convex(&[Vec3::ZERO, Vec3::X, Vec3::X + Vec3::Y, Vec3::Y]));
        assert!(!is_convex(&[
            Vec3::ZERO,
            Vec3::X * 2.0,
            Vec3::new(0.5, 0.5, 0.0),
            Vec3::Y * 2.0
        ]));
    }

    #[test]
    fn line_endings_and_blank_lines() {
        let text = "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty float x\r\nproperty float y\r\n\
                    property float z\r\nelement face 1\r\nproperty list uchar int vertex_indices\r\nend_header\r\n\
                    0 0 0\r\n\r\n1 0 0  \r\n\t0 1 0\r\n3 0 1 2";
        let m = parse(text.as_bytes()).unwrap();
        assert_eq!(m.mesh.positions[2], Vec3::Y);
        assert_eq!(m.mesh.indices, vec![[0, 1, 2]]);
        // Binary data right after a CRLF header.
        let bin = simple("binary_little_endian");
        let at = bin.windows(11).position(|w| w == b"end_header\n").unwrap();
        let mut crlf = Vec::new();
        for &b in &bin[..at + 10] {
            if b == b'\n' {
                crlf.push(b'\r');
            }
            crlf.push(b);
        }
        crlf.extend_from_slice(b"\r\n");
        crlf.extend_from_slice(&bin[at + 11..]);
        assert_eq!(parse(&crlf).unwrap(), parse(&bin).unwrap());
    }

    const HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                        element face 1\nproperty list uchar int vertex_indices\nend_header\n";

    #[test]
    fn header_errors_name_line_and_column() {
        let cases: &[(&str, &str)] = &[
            ("", "empty"),
            ("PLY\nformat ascii 1.0\n", "dir/model.ply:1:1: not a PLY file"),
            ("ply\nformat ascii 1.0\nelement vertex 3\n", "no `end_header`"),
            (
                "ply\nformat utf8 1.0\nend_header\n",
                "dir/model.ply:2:8: `format`: unknown format `utf8`",
            ),
            (
                "ply\nformat ascii 2.0\nend_header\n",
                "dir/model.ply:2:14: `format`: unsupported version",
            ),
            ("ply\nformat ascii\nend_header\n", "no version"),
            (
                "ply\nelement vertex 3\n",
                "dir/model.ply:2:1: `element`: `element` before the `format` line",
            ),
            (
                "ply\nformat ascii 1.0\nformat ascii 1.0\n",
                "dir/model.ply:3:1: `format`: a second",
            ),
            (
                "ply\nformat ascii 1.0\nproperty float x\n",
                "dir/model.ply:3:1: `property`: `property` before any",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty real x\n",
                "dir/model.ply:4:10: `element vertex`: unknown property type `real`",
            ),
            (
                "ply\nformat ascii 1.0\nelement face 3\nproperty list float int vertex_indices\n",
                "dir/model.ply:4:15: `element face`: a list's count type must be an integer type, not `float`",
            ),
            (
                "ply\nformat ascii 1.0\nelement face 3\nproperty list double int vertex_indices\n",
                "count type must be an integer",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex -3\n",
                "dir/model.ply:3:16: `element vertex`: the count must be a non-negative integer, found `-3`",
            ),
            ("ply\nformat ascii 1.0\nelement vertex 2.5\n", "non-negative integer"),
            (
                "ply\nformat ascii 1.0\nelement vertex\n",
                "expected `element <name> <count>`",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 1 2\n",
                "dir/model.ply:3:18: `element vertex`: unexpected `2`",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x y\n",
                "unexpected `y` after the property name",
            ),
            ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float\n", "no name"),
            (
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty list uchar\n",
                "expected `property list",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\n",
                "dir/model.ply:5:1: `element vertex`: a second property `x`",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 1\nelement vertex 1\n",
                "a second `vertex` element",
            ),
            (
                "ply\nformat ascii 1.0\nvertices 3\n",
                "dir/model.ply:3:1: unknown header line `vertices`",
            ),
            ("ply\nformat ascii 1.0\nend_header now\n", "unexpected `now`"),
            ("ply\nend_header\n", "no `format` line"),
            (
                "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
                "dir/model.ply:5:1: `end_header`: the header declares no `vertex` element",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
                "no `face` element",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
                "dir/model.ply:3:1: `element vertex`: the vertex element has no property `y`",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty list uchar float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
                "dir/model.ply:5:1: `element vertex`: `y` must be a scalar property",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertices\nend_header\n",
                "dir/model.ply:7:1: `element face`: the face element has no `vertex_indices`",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty int vertex_indices\nend_header\n",
                "dir/model.ply:8:1: `element face`: `vertex_indices` must be a list",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar float vertex_indices\nend_header\n",
                "must list integers, not `float`",
            ),
            (
                "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
                "no triangles",
            ),
        ];
        for (text, expected) in cases {
            let e = text_err(text);
            assert!(e.contains(expected), "{text:?}:\n  got      {e}\n  expected {expected}");
            assert!(e.contains("dir/model.ply"), "{e}");
        }
    }

    #[test]
    fn ascii_errors_name_line_column_and_value() {
        let cases: &[(&str, &str)] = &[
            (
                "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 7\n",
                "dir/model.ply:13:9: `face[0]`: unexpected `7` after the last property",
            ),
            (
                "0 0 0 5\n1 0 0\n0 1 0\n3 0 1 2\n",
                "dir/model.ply:10:7: `vertex[0]`: unexpected `5`",
            ),
            (
                "0 0 0\n1 0\n0 1 0\n3 0 1 2\n",
                "dir/model.ply:11:4: `vertex[1].z`: the line ends before this value",
            ),
            (
                "0 0 0        \n1 0 0\n0 1 0\n",
                "dir/model.ply:13:1: `face[0]`: the file ends before this entry (the header declares 1 `face` entries)",
            ),
            (
                "0 0 0\n1 0 0\n0 1 0\n3 0 1\n",
                "dir/model.ply:13:1: `face[0].vertex_indices`: the list count 3 is larger than the values on the line",
            ),
            (
                "0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n",
                "dir/model.ply:13:1: `face[0].vertex_indices`: -3 is out of range for uchar",
            ),
            (
                "0 0 0\n1 0 0\n0 1 0\n3.0 0 1 2\n",
                "dir/model.ply:13:1: `face[0].vertex_indices`: expected an integer (uchar), found `3.0`",
            ),
            (
                "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
                "dir/model.ply:13:7: `face[0].vertex_indices`: vertex index 3 is out of range: the file has 3 vertices",
            ),
            (
                "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
                "dir/model.ply:13:5: `face[0].vertex_indices`: vertex index -1 is negative",
            ),
            (
                "0 0 zero\n1 0 0\n0 1 0\n3 0 1 2\n",
                "dir/model.ply:10:5: `vertex[0].z`: expected a number (float), found `zero`",
            ),
            (
                "0 0 nan\n1 0 0\n0 1 0\n3 0 1 2\n",
                "dir/model.ply:10:1: `vertex[0]`: position (0, 0, NaN) is not finite",
            ),
            (
                "0 0 1e39\n1 0 0\n0 1 0\n3 0 1 2\n",
                "`vertex[0]`: position (0, 0, 1000000000000000000000000000000000000000) is not finite",
            ),
            (
                "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n4 0 1 2 0\n",
                "dir/model.ply:14:1: unexpected `4` after the last element",
            ),
            (
                "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n\u{e9}",
                "dir/model.ply:14:1: unexpected `\u{e9}`",
            ),
        ];
        for (body, expected) in cases {
            let e = text_err(&format!("{HEAD}{body}"));
            assert!(e.contains(expected), "{body:?}:\n  got      {e}\n  expected {expected}");
        }
        let e = text_err(
            &HEAD
                .replace("uchar int", "char int")
                .replace("end_header\n", "end_header\n0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n"),
        );
        assert!(
            e.contains("dir/model.ply:13:1: `face[0].vertex_indices`: list count -3 is negative"),
            "{e}"
        );
        let e = text_err(
            &HEAD
                .replace("float z", "uchar z")
                .replace("end_header\n", "end_header\n0 0 256\n1 0 0\n0 1 0\n3 0 1 2\n"),
        );
        assert!(
            e.contains("dir/model.ply:10:5: `vertex[0].z`: 256 is out of range for uchar (0 to 255)"),
            "{e}"
        );
    }

    #[test]
    fn binary_errors_name_the_byte_offset() {
        for enc in ["binary_little_endian", "binary_big_endian"] {
            let good = simple(enc);
            let body = good.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
            // Truncated: by the header's counts, by a list's length, and
            // in the middle of a value. 5 × 12 bytes of vertices, then faces
            // of 17, 13 and 21 bytes.
            let e = err(&good[..body + 30]);
            assert!(
                e.contains("dir/model.ply:4:16: `element vertex`: 5 entries need at least 60 bytes of binary data, but only 30 bytes follow the header"),
                "{enc}: {e}"
            );
            let last = body + 60 + 17 + 13;
            let e = err(&good[..good.len() - 3]);
            assert!(
                e.contains(&format!(
                    "dir/model.ply: byte offset {last}: `face[2].vertex_indices`: a list of 5 int items needs more than the 17 bytes left"
                )),
                "{enc}: {e}"
            );
            let busy_file = busy(enc, ("u", "v"));
            let cut = busy_file.len() - 79;
            let e = err(&busy_file[..cut]);
            assert!(
                e.contains(&format!(
                    "dir/model.ply: byte offset {cut}: `face[2].flags`: the file ends in the middle of the data"
                )),
                "{enc}: {e}"
            );
            // A list count of 200 where 5 were written.
            let mut bad = good.clone();
            bad[last] = 200;
            let e = err(&bad);
            assert!(
                e.contains(&format!("byte offset {last}: `face[2].vertex_indices`: a list of 200 int items needs more than the 20 bytes left")),
                "{enc}: {e}"
            );
            // An index out of range, and a negative one.
            let mut bad = good.clone();
            let at = last + 1 + 4;
            let i = if enc == "binary_big_endian" { at + 3 } else { at };
            bad[i] = 9;
            let e = err(&bad);
            assert!(
                e.contains(&format!(
                    "byte offset {at}: `face[2].vertex_indices`: vertex index 9 is out of range"
                )),
                "{enc}: {e}"
            );
            bad[at..at + 4].fill(0xff);
            let e = err(&bad);
            assert!(
                e.contains(&format!(
                    "byte offset {at}: `face[2].vertex_indices`: vertex index -1 is negative"
                )),
                "{enc}: {e}"
            );
            // A NaN coordinate.
            let mut bad = good.clone();
            let nan = if enc == "binary_big_endian" {
                f32::NAN.to_be_bytes()
            } else {
                f32::NAN.to_le_bytes()
            };
            bad[body + 12..body + 16].copy_from_slice(&nan);
            let e = err(&bad);
            assert!(
                e.contains(&format!("byte offset {}: `vertex[1]`: position", body + 12)),
                "{enc}: {e}"
            );
            // Trailing bytes are reported.
            let mut more = good.clone();
            more.extend_from_slice(b"\n\n");
            let m = parse(&more).unwrap();
            assert!(
                m.warnings[0].contains(&format!("byte offset {}: 2 bytes after the last element", good.len())),
                "{:?}",
                m.warnings
            );
        }
        // A negative list count in a signed count type.
        let bytes = write(
            "binary_little_endian",
            &[
                El {
                    name: "vertex",
                    props: vec![P::S("float", "x"), P::S("float", "y"), P::S("float", "z")],
                    rows: vertex_rows(|_| vec![]),
                },
                El {
                    name: "face",
                    props: vec![P::L("int", "int", "vertex_indices")],
                    rows: vec![vec![vec![0.0, 1.0, 2.0]]],
                },
            ],
        );
        let body = bytes.len() - 16 - 60;
        let mut bad = bytes.clone();
        bad[body + 60..body + 64].copy_from_slice(&(-2i32).to_le_bytes());
        let e = err(&bad);
        assert!(
            e.contains(&format!(
                "byte offset {}: `face[0].vertex_indices`: list count -2 is negative",
                body + 60
            )),
            "{e}"
        );
        // A list count of 2^32 - 1 in a skipped element fails on its size, not by allocating.
        let mut bad = busy("binary_little_endian", ("u", "v"));
        let at = bad.windows(11).position(|w| w == b"end_header\n").unwrap() + 11 + 1 + 4 + 8 + 1 + 8;
        assert_eq!(bad[at], 0, "the `weights` count of vertex 0");
        bad[at] = 255;
        let e = err(&bad);
        assert!(
            e.contains(&format!(
                "byte offset {at}: `vertex[0].weights`: a list of 255 float items"
            )),
            "{e}"
        );
    }

    #[test]
    fn absurd_counts_fail_before_anything_is_allocated() {
        for enc in ENCODINGS {
            let head = format!(
                "ply\nformat {enc} 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\nproperty float z\n\
                 element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            );
            let mut bytes = head.into_bytes();
            bytes.extend_from_slice(&[0u8; 64]);
            let e = err(&bytes);
            assert!(
                e.contains("dir/model.ply:3:16: `element vertex`: 1000000000000 entries need at least"),
                "{e}"
            );
            assert!(e.contains("only 64 bytes follow the header"), "{e}");
        }
        // Counts whose sizes overflow 64 bits.
        let e = text_err(
            "ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\nproperty double x\nend_header\n",
        );
        assert!(
            e.contains("dir/model.ply:3:16") && e.contains("more than any file can hold"),
            "{e}"
        );
        // Many faces of an element that is skipped.
        let e = text_err(&format!(
            "{}element edge 99999999999\nproperty int a\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
            &HEAD[..HEAD.len() - 11]
        ));
        assert!(
            e.contains("`element edge`") && e.contains("with the elements before it"),
            "{e}"
        );
        // Elements without properties take no room and are not looped over.
        let text = format!(
            "{}element nothing 18446744073709551615\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
            &HEAD[..HEAD.len() - 11]
        );
        let m = parse(text.as_bytes()).unwrap();
        assert!(
            m.warnings[0].contains("element `nothing` is unsupported"),
            "{:?}",
            m.warnings
        );
    }

    #[test]
    fn mangled_files_give_errors_not_panics() {
        let mut files: Vec<Vec<u8>> = ENCODINGS.iter().map(|e| busy(e, ("s", "t"))).collect();
        files.extend(ENCODINGS.iter().map(|e| simple(e)));
        for file in &files {
            for len in 0..file.len() {
                let _ = parse(&file[..len]);
            }
            for i in 0..file.len() {
                for b in [0u8, 0xff, b' ', b'\n', b'9', b'-', 0x80] {
                    let mut bad = file.clone();
                    bad[i] = b;
                    let _ = parse(&bad);
                }
            }
        }
    }

    #[test]
    fn files_are_read_from_disk_and_missing_ones_name_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.ply");
        std::fs::write(&p, simple("binary_big_endian")).unwrap();
        assert_eq!(read_ply(&p).unwrap(), parse(&simple("ascii")).unwrap());
        assert_eq!(load_ply_mesh(&p).unwrap().len(), 6);
        let missing = dir.path().join("none.ply");
        let e = read_ply(&missing).unwrap_err();
        assert!(matches!(e, Error::File { .. }));
        let e = e.to_string();
        assert!(
            e.contains(&missing.display().to_string()) && e.contains("not found"),
            "{e}"
        );
        let e = load_ply_mesh(dir.path()).unwrap_err().to_string();
        assert!(e.contains(&dir.path().display().to_string()), "{e}");
    }
}
