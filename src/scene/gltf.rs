//! glTF 2.0 scenes: `.gltf` (JSON with external or data-URI buffers and
//! images) and `.glb` (the binary container), read into a [`SceneDesc`].
//!
//! The `gltf` crate parses the JSON into its data model and checks references
//! between elements; everything that touches binary data (the GLB container,
//! buffers, buffer views, accessors, embedded images) is read here, with
//! every length checked against the bytes that are actually there. Errors and
//! warnings name the place in the JSON by line and column (in a `.glb`, of its
//! JSON chunk) and the element by its JSON path, e.g.
//! `meshes[0].primitives[1].indices`. docs/formats.md lists what is
//! supported, approximated and ignored.

use super::builtin;
use super::desc::*;
use crate::color::{Encoding, Rgb};
use crate::error::{Error, Result, SourceLoc};
use crate::files::{MAX_BUFFER_BYTES, MAX_SCENE_BYTES, io_reason, read_limited};
use crate::geometry::{Aabb, Transform, TriangleMesh};
use crate::settings::MAX_IMAGE_SIDE;
use crate::texture::ImageTexture;
use ::gltf::json;
use ::gltf::json::accessor::{ComponentType, Type as AccessorType};
use ::gltf::json::validation::Checked;
use glam::{Mat4, Quat, Vec2, Vec3};
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Extensions whose data trazo reads (fully or approximately); a file that
/// requires any other is refused, one that merely uses another is read
/// with a warning.
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_mesh_quantization",
    "KHR_texture_transform",
];

/// Film width used for glTF scenes (glTF has no render settings); the
/// height follows the camera's aspect ratio, 4:3 when it has none.
pub const FILM_WIDTH: u32 = 640;

/// Largest element count of an accessor that has no buffer view (its data
/// are zeros plus sparse substitutions, so no buffer bounds its count).
const MAX_ZERO_ACCESSOR_VALUES: u64 = 1 << 28;

/// GLB chunk types (glTF 2.0 §4, "Chunks").
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Reads a `.gltf` or `.glb` file (told apart by the GLB magic, not by the
/// extension). glTF has no parameters: each of `defines` gets a warning.
pub fn load(path: &Path, defines: &[(String, String)]) -> Result<SceneDesc> {
    let bytes = read_file(
        path,
        if is_glb_name(path) {
            MAX_BUFFER_BYTES
        } else {
            MAX_SCENE_BYTES
        },
        "scene",
    )?;
    parse_bytes(&bytes, path, defines)
}

/// Reads a glTF scene held in memory: the bytes of a `.gltf` (JSON) or
/// `.glb` file that was read from `path` (which names it in messages and
/// resolves external buffers and images).
pub fn parse_bytes(bytes: &[u8], path: &Path, defines: &[(String, String)]) -> Result<SceneDesc> {
    if bytes.is_empty() {
        return Err(Error::file(path, "the file is empty"));
    }
    // A .glb that holds JSON is read as JSON; anything else must be GLB.
    let looks_like_json = bytes.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{');
    if is_glb_name(path) && !bytes.starts_with(b"glTF") && !looks_like_json {
        return Err(Error::file(
            path,
            "invalid GLB at byte 0: the file does not start with the magic \"glTF\"",
        ));
    }
    let (json_bytes, bin, loc_file) = if bytes.starts_with(b"glTF") {
        let (json, bin) = split_glb(path, bytes)?;
        let name = PathBuf::from(format!("{} (JSON chunk)", path.display()));
        (json, bin, Arc::from(name.as_path()))
    } else {
        (bytes, None, Arc::from(path))
    };
    let text = std::str::from_utf8(json_bytes).map_err(|e| {
        let lossy = String::from_utf8_lossy(json_bytes);
        Error::Scene {
            loc: Some(SourceLoc::from_offset(&loc_file, &lossy, e.valid_up_to())),
            key: None,
            message: "the glTF JSON is not valid UTF-8 text".into(),
        }
    })?;
    // glTF JSON must not start with a byte-order mark, but one is harmless.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut root: json::Root = json::deserialize::from_str(text).map_err(|e| json_syntax_error(&loc_file, &e))?;

    let mut reader = Reader {
        base_dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
        locator: Locator::new(text, loc_file),
        bin,
        buffers: vec![None; root.buffers.len()],
        images: HashMap::new(),
        volumes: HashMap::new(),
        materials: HashMap::new(),
        warnings: Vec::new(),
        warning_index: HashMap::new(),
        any_emission: false,
        desc: SceneDesc {
            source: Some(Arc::from(path)),
            ..SceneDesc::default()
        },
    };
    // §3.12: a loader must refuse a file that requires an extension it does
    // not know. The gltf crate would refuse some that trazo reads itself
    // (KHR_mesh_quantization), so the check is made here and the list
    // cleared before the crate validates.
    for (i, ext) in root.extensions_required.iter().enumerate() {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(reader.err(
                &format!("extensionsRequired[{i}]"),
                format!("the file requires extension \"{ext}\", which trazo does not support"),
            ));
        }
    }
    root.extensions_required.clear();
    // §3.2: the asset's version is "<major>.<minor>"; a loader reads only
    // its own major version, and refuses a file whose minVersion is newer
    // than what it knows.
    let version_ok = |v: &str| {
        let mut parts = v.split('.');
        match (parts.next(), parts.next(), parts.next()) {
            (Some(major), Some(minor), None) => Some((major.parse::<u32>().ok()?, minor.parse::<u32>().ok()?)),
            _ => None,
        }
    };
    match version_ok(&root.asset.version) {
        Some((2, _)) => {}
        Some(_) => {
            return Err(reader.err(
                "asset.version",
                format!("glTF {} is not supported (trazo reads glTF 2.0)", root.asset.version),
            ));
        }
        None => {
            return Err(reader.err(
                "asset.version",
                format!("\"{}\" is not a glTF version (\"<major>.<minor>\")", root.asset.version),
            ));
        }
    }
    if let Some(min) = &root.asset.min_version {
        match version_ok(min) {
            Some((2, 0)) => {}
            _ => {
                return Err(reader.err(
                    "asset.minVersion",
                    format!("the file needs glTF {min} or later; trazo reads glTF 2.0"),
                ));
            }
        }
    }
    // The gltf crate's validation (1.4) indexes the accessors with each
    // primitive's POSITION before checking that it exists: check first.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let position = prim.attributes.get(&Checked::Valid(json::mesh::Semantic::Positions));
            if position.is_some_and(|a| a.value() >= root.accessors.len()) {
                return Err(reader.err(
                    &format!("meshes[{m}].primitives[{p}].attributes.POSITION"),
                    "refers to an element that does not exist",
                ));
            }
        }
    }
    // The gltf crate's checks: references in range, enumerations known,
    // required members present.
    let mut problems = Vec::new();
    json::validation::Validate::validate(&root, &root, json::Path::new, &mut |p, e| {
        let p = p();
        // §3.7.2.1 asks POSITION accessors for min and max, which many
        // exporters omit or get wrong; trazo computes bounds itself. A
        // primitive without POSITION is skipped with a warning (§3.7.2.1:
        // "client implementations SHOULD skip primitive's rendering").
        let tolerated = match e {
            json::validation::Error::Missing | json::validation::Error::Invalid => {
                p.as_str().ends_with("].min") || p.as_str().ends_with("].max")
            }
            _ => false,
        } || (matches!(e, json::validation::Error::Missing) && p.as_str().ends_with("[\"POSITION\"]"));
        if !tolerated {
            problems.push((p, e));
        }
    });
    if !problems.is_empty() {
        return Err(reader.validation_error(&problems));
    }
    reader.read(&root)?;
    for (name, _) in defines {
        reader.desc.warnings.push(format!(
            "-D {name}: glTF scenes have no parameters; the definition is not used"
        ));
    }
    Ok(reader.desc)
}

fn is_glb_name(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb"))
}

/// Reads a whole file after checking its size; errors name the path.
fn read_file(path: &Path, limit: u64, what: &str) -> Result<Vec<u8>> {
    let meta =
        std::fs::metadata(path).map_err(|e| Error::file(path, format!("cannot read {what}: {}", io_reason(&e))))?;
    if meta.is_dir() {
        return Err(Error::file(path, format!("cannot read {what}: this is a folder")));
    }
    if meta.len() > limit {
        return Err(Error::file(
            path,
            format!(
                "{what} file of {} bytes is larger than the limit of {limit} bytes",
                meta.len()
            ),
        ));
    }
    read_limited(path, limit).map_err(|e| Error::file(path, format!("cannot read {what}: {e}")))
}

/// Splits a GLB file into its JSON chunk and optional BIN chunk (glTF 2.0
/// §4, "GLB File Format Specification"): a 12-byte header (magic, version 2, total length), then chunks of
/// (length, type, data); the first is JSON, a BIN chunk may follow, chunks
/// of other types are skipped.
fn split_glb<'b>(path: &Path, bytes: &'b [u8]) -> Result<(&'b [u8], Option<&'b [u8]>)> {
    let bad = |offset: usize, msg: String| Error::file(path, format!("invalid GLB at byte {offset}: {msg}"));
    let u32_at = |offset: usize| -> Option<u32> {
        bytes
            .get(offset..offset + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    if bytes.len() < 12 {
        return Err(bad(
            bytes.len(),
            format!("the file ends after {} bytes, inside the 12-byte header", bytes.len()),
        ));
    }
    let version = u32_at(4).expect("length checked");
    if version != 2 {
        return Err(bad(
            4,
            format!("version {version} is not supported (trazo reads glTF 2.0)"),
        ));
    }
    let length = u32_at(8).expect("length checked") as usize;
    if length > bytes.len() {
        return Err(bad(
            8,
            format!(
                "the header gives a length of {length} bytes but the file has {} (truncated?)",
                bytes.len()
            ),
        ));
    }
    if length < 20 {
        return Err(bad(
            8,
            format!("the header gives a length of {length} bytes, too short for a JSON chunk"),
        ));
    }
    let bytes = &bytes[..length];
    let mut offset = 12;
    let mut json = None;
    let mut bin = None;
    while offset < length {
        let (Some(chunk_len), Some(chunk_type)) = (u32_at(offset), u32_at(offset + 4)) else {
            return Err(bad(offset, "the file ends inside a chunk header".into()));
        };
        let start = offset + 8;
        let end = start
            .checked_add(chunk_len as usize)
            .filter(|&e| e <= length)
            .ok_or_else(|| {
                bad(
                    offset,
                    format!(
                        "a chunk of {chunk_len} bytes starting at byte {start} runs past the end of the file ({length} bytes)"
                    ),
                )
            })?;
        let data = &bytes[start..end];
        match (json.is_none(), chunk_type) {
            (true, CHUNK_JSON) => json = Some(data),
            (true, _) => {
                return Err(bad(
                    offset + 4,
                    format!("the first chunk must be JSON (type 0x{CHUNK_JSON:08X}), got type 0x{chunk_type:08X}"),
                ));
            }
            (false, CHUNK_BIN) if bin.is_none() => bin = Some(data),
            (false, CHUNK_JSON) => return Err(bad(offset + 4, "a second JSON chunk".into())),
            // §4, "Chunks": chunks of unknown types are ignored.
            _ => {}
        }
        offset = end;
    }
    let json = json.expect("length ≥ 20 guarantees one chunk was read");
    // Exporters pad the JSON chunk with spaces (allowed) or, wrongly, NULs.
    let json_end = json.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    Ok((&json[..json_end], bin))
}

/// How an image's pixels are read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum ImageRead {
    /// Colours, decoded from sRGB (base colour, emission).
    Srgb,
    /// Data as stored (metalness and roughness, normals).
    Linear,
    /// The alpha channel as a grey, 1 where there is none (coverage).
    Alpha,
}

/// A JSON syntax or type error from serde_json, at its line and column.
fn json_syntax_error(file: &Arc<Path>, e: &json::Error) -> Error {
    let full = e.to_string();
    let suffix = format!(" at line {} column {}", e.line(), e.column());
    let message = full.strip_suffix(&suffix).unwrap_or(&full);
    Error::Scene {
        loc: (e.line() > 0).then(|| SourceLoc {
            file: file.clone(),
            line: e.line() as u32,
            column: e.column().max(1) as u32,
        }),
        key: None,
        message: format!("invalid glTF JSON: {message}"),
    }
}

/// Finds the line and column of elements named by JSON paths such as
/// `meshes[0].primitives[1].attributes["POSITION"]` (the `gltf` crate's
/// notation; `a.b` and `a["b"]` are the same).
struct Locator<'t> {
    text: &'t str,
    file: Arc<Path>,
    /// Byte offset of each object member (its key) and of each array
    /// element that is an object or array, by normalised path.
    offsets: HashMap<String, usize>,
    line_starts: Vec<usize>,
    ascii: bool,
}

impl<'t> Locator<'t> {
    fn new(text: &'t str, file: Arc<Path>) -> Locator<'t> {
        let mut scanner = JsonScanner {
            b: text.as_bytes(),
            pos: 0,
            offsets: HashMap::new(),
        };
        scanner.value(&mut String::new(), 0);
        let mut line_starts = vec![0];
        line_starts.extend(
            text.bytes()
                .enumerate()
                .filter(|&(_, b)| b == b'\n')
                .map(|(i, _)| i + 1),
        );
        Locator {
            text,
            file,
            offsets: scanner.offsets,
            line_starts,
            ascii: text.is_ascii(),
        }
    }

    /// Where `path` is written; for an element that is not written (a
    /// missing key, say), where its nearest written ancestor is.
    fn loc(&self, path: &str) -> SourceLoc {
        let mut segments = path_segments(path);
        let offset = loop {
            if segments.is_empty() {
                break 0;
            }
            if let Some(&o) = self.offsets.get(&segments.join("\0")) {
                break o;
            }
            segments.pop();
        };
        let line = self.line_starts.partition_point(|&s| s <= offset);
        let start = self.line_starts[line - 1];
        let column = if self.ascii {
            offset - start
        } else {
            self.text
                .get(start..offset)
                .map_or(offset - start, |s| s.chars().count())
        };
        SourceLoc {
            file: self.file.clone(),
            line: line as u32,
            column: column as u32 + 1,
        }
    }
}

/// Splits `a.b[2]["c"] = "v"` into `a`, `b`, `2`, `c`.
fn path_segments(path: &str) -> Vec<String> {
    let path = path.split(" = ").next().unwrap_or(path);
    let mut out = Vec::new();
    let mut current = String::new();
    let mut chars = path.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '.' => {
                if !current.is_empty() {
                    out.push(std::mem::take(&mut current));
                }
            }
            '[' => {
                if !current.is_empty() {
                    out.push(std::mem::take(&mut current));
                }
                let quoted = chars.peek() == Some(&'"');
                if quoted {
                    chars.next();
                }
                for c in chars.by_ref() {
                    if (quoted && c == '"') || (!quoted && c == ']') {
                        break;
                    }
                    current.push(c);
                }
                if quoted {
                    chars.next(); // the closing ']'
                }
                out.push(std::mem::take(&mut current));
            }
            _ => current.push(c),
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// Records where members and container elements of a JSON text start. It
/// runs on text that serde_json has accepted, but never indexes out of
/// bounds or loops on text that is not JSON.
struct JsonScanner<'t> {
    b: &'t [u8],
    pos: usize,
    offsets: HashMap<String, usize>,
}

impl JsonScanner<'_> {
    /// Deeper containers are skipped without being indexed (serde_json
    /// already refuses nesting deeper than 128).
    const MAX_DEPTH: usize = 200;

    fn peek(&self) -> Option<u8> {
        self.b.get(self.pos).copied()
    }

    fn skip_ws(&mut self) {
        while matches!(self.peek(), Some(b' ' | b'\t' | b'\r' | b'\n')) {
            self.pos += 1;
        }
    }

    /// Skips a string starting at the opening quote; returns its raw
    /// content.
    fn string(&mut self) -> &str {
        let start = self.pos + 1;
        self.pos += 1;
        while let Some(c) = self.peek() {
            self.pos += 1;
            match c {
                b'\\' => self.pos += 1,
                b'"' => break,
                _ => {}
            }
        }
        let end = self.pos.saturating_sub(1).max(start).min(self.b.len());
        std::str::from_utf8(&self.b[start.min(end)..end]).unwrap_or("")
    }

    fn push(path: &mut String, segment: &str) -> usize {
        let len = path.len();
        if !path.is_empty() {
            path.push('\0');
        }
        path.push_str(segment);
        len
    }

    fn value(&mut self, path: &mut String, depth: usize) {
        self.skip_ws();
        match self.peek() {
            Some(b'{') => {
                self.pos += 1;
                loop {
                    self.skip_ws();
                    match self.peek() {
                        None => return,
                        Some(b'}') => {
                            self.pos += 1;
                            return;
                        }
                        Some(b',') => self.pos += 1,
                        Some(b'"') => {
                            let key_start = self.pos;
                            let key = self.string().to_string();
                            self.skip_ws();
                            if self.peek() == Some(b':') {
                                self.pos += 1;
                            }
                            let len = Self::push(path, &key);
                            if depth < Self::MAX_DEPTH {
                                self.offsets.insert(path.clone(), key_start);
                            }
                            self.value(path, depth + 1);
                            path.truncate(len);
                        }
                        Some(_) => self.pos += 1,
                    }
                }
            }
            Some(b'[') => {
                self.pos += 1;
                let mut index = 0usize;
                loop {
                    self.skip_ws();
                    match self.peek() {
                        None => return,
                        Some(b']') => {
                            self.pos += 1;
                            return;
                        }
                        Some(b',') => self.pos += 1,
                        Some(c) => {
                            let len = Self::push(path, &index.to_string());
                            if matches!(c, b'{' | b'[') && depth < Self::MAX_DEPTH {
                                self.offsets.insert(path.clone(), self.pos);
                            }
                            let before = self.pos;
                            self.value(path, depth + 1);
                            path.truncate(len);
                            if self.pos == before {
                                self.pos += 1;
                            }
                            index += 1;
                        }
                    }
                }
            }
            Some(b'"') => {
                self.string();
            }
            Some(_) => {
                while !matches!(
                    self.peek(),
                    None | Some(b',' | b']' | b'}' | b' ' | b'\t' | b'\r' | b'\n')
                ) {
                    self.pos += 1;
                }
            }
            None => {}
        }
    }
}

/// Reader state: the JSON's locations, the binary data loaded so far and
/// the description being built.
struct Reader<'a> {
    base_dir: PathBuf,
    locator: Locator<'a>,
    /// The GLB's BIN chunk.
    bin: Option<&'a [u8]>,
    /// Buffer contents, loaded when first needed.
    buffers: Vec<Option<Cow<'a, [u8]>>>,
    /// Decoded embedded images, by image index and how they were read.
    images: HashMap<(usize, ImageRead), Arc<ImageTexture>>,
    /// Names of the materials converted so far (`None`: glTF's default).
    materials: HashMap<Option<usize>, String>,
    /// The absorbing medium inside each material's shapes that has one
    /// (KHR_materials_volume), by material name.
    volumes: HashMap<String, String>,
    /// Warnings without repeats: (message, how many more times it came).
    warnings: Vec<(String, usize)>,
    warning_index: HashMap<String, usize>,
    any_emission: bool,
    desc: SceneDesc,
}

/// A primitive ready to place: its triangles (taken by the first
/// placement), material name and local bounds.
struct Primitive {
    mesh: TriangleMesh,
    material: String,
    bounds: Aabb,
}

/// A node reached from the scene's roots, with its world transform.
struct Placed {
    node: usize,
    world: Mat4,
}

impl<'a> Reader<'a> {
    fn loc(&self, path: &str) -> SourceLoc {
        self.locator.loc(path)
    }

    fn err(&self, path: &str, message: impl Into<String>) -> Error {
        Error::scene(Some(self.loc(path)), path, message)
    }

    /// A warning at `path`; the same message at other places is counted
    /// rather than repeated.
    fn warn(&mut self, path: &str, message: impl Into<String>) {
        let message = message.into();
        if let Some(&i) = self.warning_index.get(&message) {
            self.warnings[i].1 += 1;
            return;
        }
        let text = format!("{}: {message}", self.loc(path));
        self.warning_index.insert(message, self.warnings.len());
        self.warnings.push((text, 0));
    }

    fn validation_error(&self, list: &[(json::Path, json::validation::Error)]) -> Error {
        let (json_path, kind) = &list[0];
        use json::validation::Error as V;
        let what = match kind {
            V::IndexOutOfBounds => "refers to an element that does not exist",
            V::Invalid => "has an invalid value",
            V::Missing => "is required but missing",
            V::Oversize => "is too large",
            V::Unsupported => "is not supported",
        };
        let more = match list.len() {
            1 => String::new(),
            n => format!(" (and {} more problems)", n - 1),
        };
        let key = json_path.as_str().split(" = ").next().unwrap_or_default();
        Error::scene(Some(self.loc(json_path.as_str())), key, format!("{what}{more}"))
    }

    fn read(&mut self, root: &json::Root) -> Result<()> {
        for (i, ext) in root.extensions_used.iter().enumerate() {
            if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
                self.warn(
                    &format!("extensionsUsed[{i}]"),
                    format!("extension {ext} is unsupported: its data are ignored"),
                );
            }
        }
        if !root.animations.is_empty() {
            self.warn(
                "animations",
                "animations are unsupported: the scene is rendered in its static pose",
            );
        }

        let placed = self.walk_scene(root)?;
        let mut bounds = Aabb::EMPTY;
        self.place_meshes(root, &placed, &mut bounds)?;
        if self.desc.shapes.is_empty() {
            return Err(Error::Scene {
                loc: Some(self.loc("scenes")),
                key: None,
                message: "the scene has no triangles to render (points and lines are not rendered)".into(),
            });
        }
        self.read_lights(root, &placed)?;
        let has_camera = self.read_camera(root, &placed, &bounds)?;
        if !has_camera {
            self.desc.camera = builtin::framing_camera(&bounds);
            self.desc.settings.width = FILM_WIDTH;
            self.desc.settings.height = FILM_WIDTH * 3 / 4;
        }
        if self.desc.lights.is_empty() && !self.any_emission {
            builtin::add_studio_lights(&mut self.desc);
            self.warn(
                "",
                "a scene without lights is approximated: it has no KHR_lights_punctual lights and no emissive \
                 materials, so studio lights and a gradient background were added",
            );
        }

        self.desc.warnings = std::mem::take(&mut self.warnings)
            .into_iter()
            .map(|(w, more)| match more {
                0 => w,
                n => format!("{w} (and {n} more places like this)"),
            })
            .collect();
        self.desc.validate()
    }

    /// The nodes of the default scene (or the first, or, without scenes, of
    /// every root node) in depth-first order, with world transforms.
    fn walk_scene(&mut self, root: &json::Root) -> Result<Vec<Placed>> {
        let roots: Vec<usize> = match root.scene.map(|s| s.value()).or((!root.scenes.is_empty()).then_some(0)) {
            Some(s) => {
                if root.scenes.len() > 1 {
                    self.warn(
                        "scenes",
                        format!(
                            "more than one scene is unsupported: only scene {s} (the {}) is rendered",
                            if root.scene.is_some() { "default scene" } else { "first" }
                        ),
                    );
                }
                root.scenes[s].nodes.iter().map(|n| n.value()).collect()
            }
            None => {
                let mut is_child = vec![false; root.nodes.len()];
                for n in &root.nodes {
                    for c in n.children.iter().flatten() {
                        is_child[c.value()] = true;
                    }
                }
                (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
            }
        };
        let mut visited = vec![false; root.nodes.len()];
        let mut placed = Vec::new();
        // (node, parent's world transform, parent index for messages)
        let mut stack: Vec<(usize, Mat4, Option<usize>)> =
            roots.iter().rev().map(|&n| (n, Mat4::IDENTITY, None)).collect();
        while let Some((n, parent_world, parent)) = stack.pop() {
            if visited[n] {
                // §3.5.2: nodes form disjoint strict trees; a second parent
                // (or a cycle) would place the node twice or forever.
                let at = match parent {
                    Some(p) => format!("nodes[{p}].children"),
                    None => "scenes".to_string(),
                };
                return Err(self.err(
                    &at,
                    format!("node {n} is reached twice: glTF nodes must form disjoint trees (no node with two parents, no cycles)"),
                ));
            }
            visited[n] = true;
            let world = parent_world * self.local_transform(root, n)?;
            if !world.is_finite() {
                return Err(self.err(
                    &format!("nodes[{n}]"),
                    "the node's world transform (its own composed with its ancestors') overflows to infinity",
                ));
            }
            let node = &root.nodes[n];
            if node.skin.is_some() {
                self.warn(
                    &format!("nodes[{n}].skin"),
                    "skinning is unsupported: the mesh is rendered unskinned, placed by its node",
                );
            }
            for c in node.children.iter().flatten().rev() {
                stack.push((c.value(), world, Some(n)));
            }
            placed.push(Placed { node: n, world });
        }
        Ok(placed)
    }

    /// A node's transform (§3.5.3): its matrix (column-major) or
    /// translation × rotation × scale.
    fn local_transform(&mut self, root: &json::Root, n: usize) -> Result<Mat4> {
        let node = &root.nodes[n];
        let at = format!("nodes[{n}]");
        let has_trs = node.translation.is_some() || node.rotation.is_some() || node.scale.is_some();
        if let Some(m) = node.matrix {
            if has_trs {
                self.warn(
                    &at,
                    "a node with both matrix and translation/rotation/scale is approximated: the matrix is used",
                );
            }
            let m = Mat4::from_cols_array(&m);
            if !m.is_finite() {
                return Err(self.err(&format!("{at}.matrix"), "has a NaN or infinite element"));
            }
            if m.row(3) != glam::Vec4::W {
                return Err(self.err(
                    &format!("{at}.matrix"),
                    "is not an affine transform: its last row must be 0, 0, 0, 1 (elements 3, 7, 11, 15)",
                ));
            }
            return Ok(m);
        }
        let t = Vec3::from(node.translation.unwrap_or([0.0; 3]));
        let s = Vec3::from(node.scale.unwrap_or([1.0; 3]));
        let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
        if !t.is_finite() {
            return Err(self.err(&format!("{at}.translation"), "has a NaN or infinite element"));
        }
        if !s.is_finite() {
            return Err(self.err(&format!("{at}.scale"), "has a NaN or infinite element"));
        }
        let q = Quat::from_array(r);
        if !q.is_finite() || q.length() == 0.0 {
            return Err(self.err(
                &format!("{at}.rotation"),
                "must be a unit quaternion [x, y, z, w], got a zero or non-finite one",
            ));
        }
        if (q.length() - 1.0).abs() > 1e-3 {
            self.warn(
                &format!("{at}.rotation"),
                "a rotation quaternion that is not of unit length is approximated: it is normalised",
            );
        }
        Ok(Mat4::from_scale_rotation_translation(s, q.normalize(), t))
    }

    /// Turns the meshes of placed nodes into shapes: a mesh placed once
    /// becomes inline meshes in world space, one placed more often named
    /// meshes that the build step instances.
    fn place_meshes(&mut self, root: &json::Root, placed: &[Placed], bounds: &mut Aabb) -> Result<()> {
        let mut uses: HashMap<usize, usize> = HashMap::new();
        for p in placed {
            if let Some(m) = root.nodes[p.node].mesh {
                if Transform::from_matrix(p.world).is_ok() {
                    *uses.entry(m.value()).or_default() += 1;
                }
            }
        }
        // Primitives per mesh (`None`: skipped).
        let mut converted: HashMap<usize, Vec<Option<Primitive>>> = HashMap::new();
        let mut named: HashMap<(usize, usize), String> = HashMap::new();
        for p in placed {
            let Some(m) = root.nodes[p.node].mesh.map(|m| m.value()) else {
                continue;
            };
            // A zero scale hides a subtree (often used by animations); the
            // result is the same as not placing it.
            if Transform::from_matrix(p.world).is_err() {
                continue;
            }
            if let std::collections::hash_map::Entry::Vacant(e) = converted.entry(m) {
                e.insert(self.convert_mesh(root, m)?);
            }
            let node_at = format!("nodes[{}]", p.node);
            let transform = if p.world == Mat4::IDENTITY {
                Vec::new()
            } else {
                vec![TransformOp::Matrix(p.world)]
            };
            let placed_once = uses[&m] == 1;
            let prims = converted.get_mut(&m).expect("converted above");
            for (pi, prim) in prims.iter_mut().enumerate() {
                let Some(Primitive {
                    mesh,
                    material,
                    bounds: local,
                }) = prim
                else {
                    continue;
                };
                let prim_at = format!("meshes[{m}].primitives[{pi}]");
                for corner in 0..8 {
                    let c = Vec3::new(
                        if corner & 1 == 0 { local.min.x } else { local.max.x },
                        if corner & 2 == 0 { local.min.y } else { local.max.y },
                        if corner & 4 == 0 { local.min.z } else { local.max.z },
                    );
                    *bounds = bounds.union_point(p.world.transform_point3(c));
                }
                let locs = Locs {
                    item: Some(self.loc(&node_at)),
                    keys: vec![
                        ("transform".into(), self.loc(&node_at)),
                        ("indices".into(), self.loc(&prim_at)),
                        ("material".into(), self.loc(&format!("{prim_at}.material"))),
                    ],
                };
                let kind = if placed_once {
                    ShapeKind::InlineMesh(MeshSource::Inline(std::mem::take(mesh)))
                } else {
                    let name = match named.get(&(m, pi)) {
                        Some(name) => name.clone(),
                        None => {
                            let name = prim_at.clone();
                            self.desc.meshes.push(MeshDesc {
                                name: name.clone(),
                                source: MeshSource::Inline(std::mem::take(mesh)),
                                locs: Locs::at(Some(self.loc(&prim_at))),
                            });
                            named.insert((m, pi), name.clone());
                            name
                        }
                    };
                    ShapeKind::Mesh(name)
                };
                self.desc.shapes.push(ShapeDesc {
                    kind,
                    transform: transform.clone(),
                    media: self.volumes.get(material.as_str()).map(|inside| MediumInterfaceDesc {
                        inside: Some(inside.clone()),
                        outside: None,
                    }),
                    material: Some(material.clone()),
                    flip_normals: false,
                    motion: None,
                    locs,
                });
            }
        }
        Ok(())
    }

    /// The triangles and material of each primitive of mesh `m`; `None`
    /// for primitives that are skipped (with a warning).
    fn convert_mesh(&mut self, root: &json::Root, m: usize) -> Result<Vec<Option<Primitive>>> {
        let mesh = &root.meshes[m];
        if mesh.weights.is_some() || mesh.primitives.iter().any(|p| p.targets.is_some()) {
            self.warn(
                &format!("meshes[{m}]"),
                "morph targets are unsupported: the base shape is rendered",
            );
        }
        let mut out = Vec::with_capacity(mesh.primitives.len());
        for p in 0..mesh.primitives.len() {
            let tri = self.convert_primitive(root, m, p)?;
            let item = match tri {
                Some(t) => {
                    let material = self.material(
                        root,
                        mesh.primitives[p].material.map(|i| i.value()),
                        &format!("meshes[{m}].primitives[{p}]"),
                    )?;
                    let bounds = t.bounds();
                    Some(Primitive {
                        mesh: t,
                        material,
                        bounds,
                    })
                }
                None => None,
            };
            out.push(item);
        }
        Ok(out)
    }

    fn convert_primitive(&mut self, root: &json::Root, m: usize, p: usize) -> Result<Option<TriangleMesh>> {
        use json::mesh::{Mode, Semantic};
        let prim = &root.meshes[m].primitives[p];
        let at = format!("meshes[{m}].primitives[{p}]");
        let mode = match prim.mode {
            Checked::Valid(mode) => mode,
            Checked::Invalid => return Err(self.err(&format!("{at}.mode"), "has an invalid value")),
        };
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.warn(
                &format!("{at}.mode"),
                format!(
                    "{} primitives are unsupported: skipped (trazo renders surfaces only)",
                    mode_name(mode)
                ),
            );
            return Ok(None);
        }
        let normal_mapped = prim
            .material
            .is_some_and(|i| root.materials[i.value()].normal_texture.is_some());
        let mut position = None;
        let mut normal = None;
        let mut uv = None;
        for (semantic, accessor) in &prim.attributes {
            let attr_at = |name: &str| format!("{at}.attributes.{name}");
            match semantic {
                Checked::Valid(Semantic::Positions) => position = Some(accessor.value()),
                Checked::Valid(Semantic::Normals) => normal = Some(accessor.value()),
                Checked::Valid(Semantic::TexCoords(0)) => uv = Some(accessor.value()),
                Checked::Valid(Semantic::TexCoords(n)) => self.warn(
                    &attr_at(&format!("TEXCOORD_{n}")),
                    format!("TEXCOORD_{n} is unsupported: only TEXCOORD_0 is read"),
                ),
                // Tangents serve normal maps alone.
                Checked::Valid(Semantic::Tangents) if normal_mapped => self.warn(
                    &attr_at("TANGENT"),
                    "TANGENT is approximated: normal maps take each triangle's tangent along its texture coordinates' u",
                ),
                Checked::Valid(Semantic::Tangents) => {}
                Checked::Valid(Semantic::Colors(n)) => self.warn(
                    &attr_at(&format!("COLOR_{n}")),
                    format!("vertex colours (COLOR_{n}) are unsupported: ignored"),
                ),
                Checked::Valid(Semantic::Joints(_) | Semantic::Weights(_)) => self.warn(
                    &attr_at("JOINTS_0"),
                    "skinning attributes (JOINTS_n, WEIGHTS_n) are unsupported: ignored",
                ),
                // §3.7.2.1: names starting with '_' are application-specific.
                Checked::Valid(Semantic::Extras(name)) => self.warn(
                    &attr_at(&format!("_{name}")),
                    format!("application-specific attribute _{name} is unsupported: ignored"),
                ),
                Checked::Invalid => self.warn(
                    &format!("{at}.attributes"),
                    "an attribute with an unknown name is unsupported: ignored",
                ),
            }
        }
        let Some(position) = position else {
            // §3.7.2.1: without POSITION a client should skip the primitive.
            self.warn(&at, "a primitive without POSITION is unsupported: skipped");
            return Ok(None);
        };
        let mut mesh = TriangleMesh::default();
        let pos_at = format!("{at}.attributes.POSITION");
        let values = self.read_floats(root, position, AccessorType::Vec3, "POSITION")?;
        mesh.positions = values.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let n = mesh.positions.len();
        if n > u32::MAX as usize {
            return Err(self.err(&pos_at, format!("{n} vertices are more than trazo's limit of 2³² − 1")));
        }
        if let Some(a) = normal {
            let values = self.read_floats(root, a, AccessorType::Vec3, "NORMAL")?;
            mesh.normals = values.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
            let normal_at = format!("{at}.attributes.NORMAL");
            if mesh.normals.len() != n {
                return Err(self.err(
                    &normal_at,
                    format!("has {} elements but POSITION has {n}", mesh.normals.len()),
                ));
            }
            if let Some(v) = mesh.normals.iter().position(|n| !n.is_finite()) {
                return Err(self.err(&normal_at, format!("vertex {v} has a NaN or infinite normal")));
            }
            if mesh.normals.iter().any(|n| n.length_squared() == 0.0) {
                self.warn(
                    &normal_at,
                    "zero-length vertex normals are approximated: the primitive is shaded with its face normals",
                );
                mesh.normals.clear();
            }
        }
        if let Some(a) = uv {
            let values = self.read_floats(root, a, AccessorType::Vec2, "TEXCOORD_0")?;
            // glTF's (0, 0) is the image's top-left corner (§3.8.1);
            // trazo's v runs up from the bottom row.
            mesh.uvs = values.chunks_exact(2).map(|c| Vec2::new(c[0], 1.0 - c[1])).collect();
            let uv_at = format!("{at}.attributes.TEXCOORD_0");
            if mesh.uvs.len() != n {
                return Err(self.err(&uv_at, format!("has {} elements but POSITION has {n}", mesh.uvs.len())));
            }
            if let Some(v) = mesh.uvs.iter().position(|t| !t.is_finite()) {
                return Err(self.err(&uv_at, format!("vertex {v} has a NaN or infinite texture coordinate")));
            }
        }
        let indices: Vec<u32> = match prim.indices {
            Some(a) => self.read_indices(root, a.value())?,
            None => (0..n as u32).collect(),
        };
        let (triangles, leftover) = match mode {
            Mode::Triangles => (indices.len() / 3, indices.len() % 3),
            _ => (indices.len().saturating_sub(2), 0),
        };
        if leftover != 0 {
            self.warn(
                &format!("{at}.indices"),
                "a triangle list whose length is not a multiple of 3 is approximated: the incomplete last triangle is dropped",
            );
        }
        // §3.7.2.1: strips p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2−i%2)}}, fans
        // p_i = {v_{i+1}, v_{i+2}, v_0}; both keep the list's winding.
        mesh.indices = (0..triangles)
            .map(|i| match mode {
                Mode::TriangleStrip => [indices[i], indices[i + 1 + i % 2], indices[i + 2 - i % 2]],
                Mode::TriangleFan => [indices[i + 1], indices[i + 2], indices[0]],
                _ => [indices[3 * i], indices[3 * i + 1], indices[3 * i + 2]],
            })
            .collect();
        if mesh.indices.is_empty() {
            self.warn(&at, "a primitive without triangles is unsupported: skipped");
            return Ok(None);
        }
        if let Err(e) = mesh.validate() {
            let key = match e {
                crate::geometry::mesh::MeshError::NonFinite { .. } => pos_at,
                _ if prim.indices.is_some() => format!("{at}.indices"),
                _ => at,
            };
            return Err(self.err(&key, e.to_string()));
        }
        Ok(Some(mesh))
    }

    /// Loads buffer `b` if it is not loaded yet: the GLB's BIN chunk, a
    /// data URI or a file next to the glTF file.
    fn ensure_buffer(&mut self, root: &json::Root, b: usize) -> Result<()> {
        if self.buffers[b].is_some() {
            return Ok(());
        }
        let buffer = &root.buffers[b];
        let at = format!("buffers[{b}]");
        let (data, source): (Cow<'a, [u8]>, String) = match &buffer.uri {
            None => match self.bin {
                // §4, "Binary buffer": buffer 0 without a uri is the BIN chunk.
                Some(bin) if b == 0 => (Cow::Borrowed(bin), "the GLB binary chunk".into()),
                Some(_) => {
                    return Err(self.err(&at, "has no uri; only buffer 0 can refer to the GLB binary chunk"));
                }
                None => return Err(self.err(&at, "has no uri, and the file has no GLB binary chunk")),
            },
            Some(uri) if uri.starts_with("data:") => {
                let (_, data) = decode_data_uri(uri).map_err(|m| self.err(&format!("{at}.uri"), m))?;
                (Cow::Owned(data), "its data URI".into())
            }
            Some(uri) => {
                let rel = uri_to_path(uri).map_err(|m| self.err(&format!("{at}.uri"), m))?;
                let full = self.base_dir.join(&rel);
                let data = read_file(&full, MAX_BUFFER_BYTES, "buffer").map_err(|e| {
                    let reason = match e {
                        Error::File { message, .. } => message,
                        other => other.to_string(),
                    };
                    self.err(&format!("{at}.uri"), format!("{}: {reason}", full.display()))
                })?;
                (Cow::Owned(data), full.display().to_string())
            }
        };
        let len = buffer.byte_length.0;
        if (data.len() as u64) < len {
            return Err(self.err(
                &format!("{at}.byteLength"),
                format!("is {len} bytes but {source} holds only {}", data.len()),
            ));
        }
        self.buffers[b] = Some(data);
        Ok(())
    }

    /// The bytes of buffer view `v`, whose buffer must be loaded.
    fn view_bytes(&self, root: &json::Root, v: usize) -> Result<&[u8]> {
        let view = &root.buffer_views[v];
        let b = view.buffer.value();
        let data = self.buffers[b].as_deref().expect("ensure_buffer was called");
        let buffer_len = root.buffers[b].byte_length.0;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let len = view.byte_length.0;
        match start.checked_add(len) {
            Some(end) if end <= buffer_len => Ok(&data[start as usize..end as usize]),
            _ => Err(self.err(
                &format!("bufferViews[{v}]"),
                format!("bytes {start} to {start}+{len} lie outside buffers[{b}], which has {buffer_len} bytes"),
            )),
        }
    }

    fn read_floats(&mut self, root: &json::Root, a: usize, ty: AccessorType, what: &str) -> Result<Vec<f32>> {
        self.check_attribute_components(root, a, what)?;
        self.read_accessor(root, a, ty, what, &[], decode_f32)
    }

    /// §3.7.2.1: the component types a vertex attribute may have: floats
    /// for POSITION and NORMAL, floats or normalized unsigned bytes and
    /// shorts for TEXCOORD_n, and, where the file uses
    /// KHR_mesh_quantization, the integer types that extension adds.
    fn check_attribute_components(&self, root: &json::Root, a: usize, what: &str) -> Result<()> {
        use ComponentType::*;
        let acc = &root.accessors[a];
        let Checked::Valid(ct) = acc.component_type else {
            return Ok(()); // read_accessor names an invalid value
        };
        let (ct, normalized) = (ct.0, acc.normalized);
        let quantized = root.extensions_used.iter().any(|e| e == "KHR_mesh_quantization");
        let allowed = match (what, quantized) {
            (_, _) if ct == F32 => true,
            ("POSITION", false) | ("NORMAL", false) => false,
            ("POSITION", true) => matches!(ct, I8 | U8 | I16 | U16),
            ("NORMAL", true) => normalized && matches!(ct, I8 | I16),
            (_, false) => normalized && matches!(ct, U8 | U16),
            (_, true) => matches!(ct, I8 | U8 | I16 | U16),
        };
        if allowed {
            return Ok(());
        }
        let kind = format!("{}{}", if normalized { "normalized " } else { "" }, component_name(ct));
        Err(self.err(
            &format!("accessors[{a}].componentType"),
            format!(
                "{what} cannot have components of type {kind} in glTF 2.0{}",
                if quantized {
                    ", even with KHR_mesh_quantization"
                } else {
                    " (only KHR_mesh_quantization allows more, and the file does not use it)"
                }
            ),
        ))
    }

    fn read_indices(&mut self, root: &json::Root, a: usize) -> Result<Vec<u32>> {
        use ComponentType::*;
        if root.accessors[a].normalized {
            return Err(self.err(&format!("accessors[{a}].normalized"), "indices must not be normalized"));
        }
        self.read_accessor(
            root,
            a,
            AccessorType::Scalar,
            "indices",
            &[U8, U16, U32],
            |ct, _, b| match ct {
                U8 => b[0] as u32,
                U16 => u16::from_le_bytes([b[0], b[1]]) as u32,
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            },
        )
    }

    /// Reads accessor `a` (§3.6.2): `count` elements of type `ty` from its
    /// buffer view (or zeros), then its sparse substitutions, every range
    /// checked against the data before anything is allocated.
    /// `component_types` lists those allowed (empty: any).
    fn read_accessor<T: Copy + Default>(
        &mut self,
        root: &json::Root,
        a: usize,
        ty: AccessorType,
        what: &str,
        component_types: &[ComponentType],
        decode: impl Fn(ComponentType, bool, &[u8]) -> T,
    ) -> Result<Vec<T>> {
        let acc = &root.accessors[a];
        let at = format!("accessors[{a}]");
        let Checked::Valid(acc_ty) = acc.type_ else {
            return Err(self.err(&format!("{at}.type"), "has an invalid value"));
        };
        if acc_ty != ty {
            return Err(self.err(
                &format!("{at}.type"),
                format!("{what} needs {} elements, got {}", type_name(ty), type_name(acc_ty)),
            ));
        }
        let Checked::Valid(ct) = acc.component_type else {
            return Err(self.err(&format!("{at}.componentType"), "has an invalid value"));
        };
        let ct = ct.0;
        if !component_types.is_empty() && !component_types.contains(&ct) {
            return Err(self.err(
                &format!("{at}.componentType"),
                format!("{what} cannot have components of type {}", component_name(ct)),
            ));
        }
        let comps = ty.multiplicity();
        let csize = ct.size();
        let esize = comps * csize;
        let count = acc.count.0;
        let mut out: Vec<T>;
        if let Some(v) = acc.buffer_view {
            let v = v.value();
            let view = &root.buffer_views[v];
            self.ensure_buffer(root, view.buffer.value())?;
            let data = self.view_bytes(root, v)?;
            let stride = view.byte_stride.map_or(esize, |s| s.0);
            if stride < esize {
                return Err(self.err(
                    &format!("bufferViews[{v}].byteStride"),
                    format!("{stride} is smaller than the {esize}-byte elements of {at}"),
                ));
            }
            let offset = acc.byte_offset.map_or(0, |o| o.0);
            if count > 0 {
                let need = (count - 1)
                    .checked_mul(stride as u64)
                    .and_then(|x| x.checked_add(esize as u64))
                    .and_then(|x| x.checked_add(offset));
                if need.is_none_or(|n| n > data.len() as u64) {
                    return Err(self.err(
                        &at,
                        format!(
                            "{count} elements of {esize} bytes every {stride} bytes from byte {offset} do not fit in bufferViews[{v}], which has {} bytes",
                            data.len()
                        ),
                    ));
                }
            }
            // count ≤ data.len() now, so the allocation is bounded by data.
            let (count, offset) = (count as usize, offset as usize);
            out = Vec::with_capacity(count * comps);
            for i in 0..count {
                let base = offset + i * stride;
                for c in 0..comps {
                    out.push(decode(ct, acc.normalized, &data[base + c * csize..]));
                }
            }
        } else {
            if count.saturating_mul(comps as u64) > MAX_ZERO_ACCESSOR_VALUES {
                return Err(self.err(
                    &format!("{at}.count"),
                    format!(
                        "{count} elements without a bufferView are more than trazo accepts ({MAX_ZERO_ACCESSOR_VALUES} values)"
                    ),
                ));
            }
            out = vec![T::default(); count as usize * comps];
        }
        if let Some(sparse) = &acc.sparse {
            let sat = format!("{at}.sparse");
            let n = sparse.count.0;
            if n > count {
                return Err(self.err(
                    &format!("{sat}.count"),
                    format!("{n} substitutions are more than the accessor's {count} elements"),
                ));
            }
            let iv = sparse.indices.buffer_view.value();
            let vv = sparse.values.buffer_view.value();
            let Checked::Valid(ict) = sparse.indices.component_type else {
                return Err(self.err(&format!("{sat}.indices.componentType"), "has an invalid value"));
            };
            let ict = ict.0;
            if !matches!(ict, ComponentType::U8 | ComponentType::U16 | ComponentType::U32) {
                return Err(self.err(
                    &format!("{sat}.indices.componentType"),
                    "must be an unsigned integer type",
                ));
            }
            self.ensure_buffer(root, root.buffer_views[iv].buffer.value())?;
            self.ensure_buffer(root, root.buffer_views[vv].buffer.value())?;
            let idata = self.view_bytes(root, iv)?;
            let vdata = self.view_bytes(root, vv)?;
            let ioff = sparse.indices.byte_offset.0;
            let voff = sparse.values.byte_offset.0;
            let fits = |off: u64, size: usize, len: usize| {
                n.checked_mul(size as u64)
                    .and_then(|x| x.checked_add(off))
                    .is_some_and(|end| end <= len as u64)
            };
            if !fits(ioff, ict.size(), idata.len()) {
                return Err(self.err(
                    &format!("{sat}.indices"),
                    format!("{n} indices from byte {ioff} do not fit in bufferViews[{iv}]"),
                ));
            }
            if !fits(voff, esize, vdata.len()) {
                return Err(self.err(
                    &format!("{sat}.values"),
                    format!("{n} values from byte {voff} do not fit in bufferViews[{vv}]"),
                ));
            }
            let (ioff, voff) = (ioff as usize, voff as usize);
            for k in 0..n as usize {
                let b = &idata[ioff + k * ict.size()..];
                let index = match ict {
                    ComponentType::U8 => b[0] as u64,
                    ComponentType::U16 => u16::from_le_bytes([b[0], b[1]]) as u64,
                    _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64,
                };
                if index >= count {
                    return Err(self.err(
                        &format!("{sat}.indices"),
                        format!("substitution {k} is for element {index}, but the accessor has {count}"),
                    ));
                }
                for c in 0..comps {
                    out[index as usize * comps + c] =
                        decode(ct, acc.normalized, &vdata[voff + k * esize + c * csize..]);
                }
            }
        }
        Ok(out)
    }

    /// The pixels of image `i`: a file name for the build step to load, or
    /// decoded pixels for embedded images, sRGB-decoded where `srgb` (colour
    /// textures, §3.9.2) and read as they are otherwise (data such as
    /// metalness and roughness). Missing files are reported here, where the
    /// image's place in the JSON is known.
    fn image_source(&mut self, root: &json::Root, i: usize, read: ImageRead) -> Result<ImageSource> {
        if let Some(img) = self.images.get(&(i, read)) {
            return Ok(ImageSource::Data(img.clone()));
        }
        let image = &root.images[i];
        let at = format!("images[{i}]");
        let bytes: Cow<[u8]> = match (&image.uri, image.buffer_view) {
            (Some(uri), _) if uri.starts_with("data:") => {
                let (_, data) = decode_data_uri(uri).map_err(|m| self.err(&format!("{at}.uri"), m))?;
                Cow::Owned(data)
            }
            (Some(uri), _) => {
                let rel = uri_to_path(uri).map_err(|m| self.err(&format!("{at}.uri"), m))?;
                let full = self.base_dir.join(&rel);
                match std::fs::metadata(&full) {
                    Ok(meta) if meta.is_file() => {
                        return Ok(match read {
                            ImageRead::Alpha => ImageSource::AlphaFile(rel),
                            ImageRead::Srgb | ImageRead::Linear => ImageSource::File(rel),
                        });
                    }
                    Ok(_) => {
                        return Err(self.err(
                            &format!("{at}.uri"),
                            format!("cannot read image {}: not a file", full.display()),
                        ));
                    }
                    Err(e) => {
                        return Err(self.err(
                            &format!("{at}.uri"),
                            format!("cannot read image {}: {}", full.display(), io_reason(&e)),
                        ));
                    }
                }
            }
            (None, Some(v)) => {
                let v = v.value();
                self.ensure_buffer(root, root.buffer_views[v].buffer.value())?;
                Cow::Borrowed(self.view_bytes(root, v)?)
            }
            (None, None) => return Err(self.err(&at, "has neither a uri nor a bufferView")),
        };
        let img = match read {
            ImageRead::Alpha => ImageTexture::alpha_from_encoded(&bytes),
            _ => ImageTexture::from_encoded(&bytes, read == ImageRead::Srgb),
        }
        .map_err(|m| self.err(&at, format!("cannot decode the embedded image: {m}")))?;
        let img = Arc::new(img);
        self.images.insert((i, read), img.clone());
        Ok(ImageSource::Data(img))
    }

    /// Adds a texture for the texture reference at `at` multiplied by
    /// `tint`, and returns its name. Colours are sRGB-encoded, as glTF
    /// stores them.
    fn texture(&mut self, root: &json::Root, info: &json::texture::Info, at: &str, tint: Rgb) -> Result<String> {
        self.texture_encoded(root, info, at, tint, ImageRead::Srgb)
    }

    /// [`Reader::texture`] for an image read as `read` (linear for data
    /// such as metalness and roughness, alpha for coverage).
    fn texture_encoded(
        &mut self,
        root: &json::Root,
        info: &json::texture::Info,
        at: &str,
        tint: Rgb,
        read: ImageRead,
    ) -> Result<String> {
        self.texture_named(root, info, at, at, tint, read)
    }

    /// [`Reader::texture_encoded`] of the reference at `at` under the
    /// texture name `name` (a second reading of one reference: the base
    /// colour image's alpha).
    fn texture_named(
        &mut self,
        root: &json::Root,
        info: &json::texture::Info,
        at: &str,
        name: &str,
        tint: Rgb,
        read: ImageRead,
    ) -> Result<String> {
        let t = info.index.value();
        let texture = &root.textures[t];
        let mut tex_coord = info.tex_coord;
        let mut scale = Vec2::ONE;
        let mut offset = Vec2::ZERO;
        let mut turned = None;
        if let Some(tt) = info.extensions.as_ref().and_then(|e| e.texture_transform.as_ref()) {
            let tt_at = format!("{at}.extensions.KHR_texture_transform");
            let (s, o, r) = (Vec2::from(tt.scale.0), Vec2::from(tt.offset.0), tt.rotation.0);
            if !s.is_finite() || !o.is_finite() || !r.is_finite() {
                return Err(self.err(&tt_at, "has a NaN or infinite value"));
            }
            // glTF samples at o + R·(s·(u, v)) with v down, R turning
            // (1, 0) to (cos r, sin r) (the extension's matrix); trazo's
            // mesh holds v' = 1 − v and samples with v up, so the same texel
            // is at (o.x − sin r·s.y, 1 − o.y − cos r·s.y) + u·(cos r·s.x,
            // −sin r·s.x) + v'·(sin r·s.y, cos r·s.y): without a rotation,
            // (o.x + s.x·u, (1 − o.y − s.y) + s.y·v').
            scale = s;
            offset = Vec2::new(o.x, 1.0 - o.y - s.y);
            if r != 0.0 {
                let (sin, cos) = r.sin_cos();
                turned = Some(crate::texture::Mapping2D::UvAffine {
                    u_axis: Vec2::new(cos * s.x, -sin * s.x),
                    v_axis: Vec2::new(sin * s.y, cos * s.y),
                    offset: Vec2::new(o.x - sin * s.y, 1.0 - o.y - cos * s.y),
                });
            }
            if let Some(tc) = tt.tex_coord {
                tex_coord = tc;
            }
        }
        if tex_coord != 0 {
            self.warn(
                &format!("{at}.texCoord"),
                format!("texture coordinate set {tex_coord} is approximated: TEXCOORD_0 is used"),
            );
        }
        let mut wrap = [crate::texture::WrapMode::Repeat; 2];
        let mut filter = crate::texture::ImageFilter::Bilinear;
        if let Some(s) = texture.sampler {
            use crate::texture::WrapMode;
            use json::texture::{MagFilter, WrappingMode};
            let sampler = &root.samplers[s.value()];
            let mode = |w: Checked<WrappingMode>| match w {
                Checked::Valid(WrappingMode::ClampToEdge) => WrapMode::Clamp,
                Checked::Valid(WrappingMode::MirroredRepeat) => WrapMode::Mirror,
                _ => WrapMode::Repeat,
            };
            wrap = [mode(sampler.wrap_s), mode(sampler.wrap_t)];
            // Images are not minified through mipmaps, so the
            // magnification filter is the one that applies.
            if let Some(Checked::Valid(MagFilter::Nearest)) = sampler.mag_filter {
                filter = crate::texture::ImageFilter::Nearest;
            }
        }
        let image = texture.source.value();
        let source = self.image_source(root, image, read)?;
        let encoding = if read == ImageRead::Srgb {
            Encoding::Srgb
        } else {
            Encoding::Linear
        };
        let name = name.to_string();
        let image_at = format!("images[{image}]");
        let locs = Locs {
            item: Some(self.loc(at)),
            keys: vec![("file".into(), self.loc(&format!("{image_at}.uri")))],
        };
        // A rotated transform reads the image through a mapped node.
        let image_name = if turned.is_some() {
            format!("{name} image")
        } else {
            name.clone()
        };
        if turned.is_some() {
            (scale, offset) = (Vec2::ONE, Vec2::ZERO);
        }
        self.desc.textures.push(TextureDesc {
            name: image_name.clone(),
            kind: TextureKind::Image {
                source,
                scale,
                offset,
                encoding: Some(encoding),
                tint,
                wrap,
                filter,
            },
            locs: locs.clone(),
        });
        if let Some(mapping) = turned {
            self.desc.textures.push(TextureDesc {
                name: name.clone(),
                kind: TextureKind::Node(crate::texture::TextureNode::Mapped {
                    tex: ColorSource::Texture(image_name),
                    mapping,
                }),
                locs,
            });
        }
        Ok(name)
    }

    /// The mean colour of the image a texture reference shows (for
    /// materials that cannot vary over a surface).
    fn texture_average(&mut self, root: &json::Root, info: &json::texture::Info) -> Result<Rgb> {
        let image = root.textures[info.index.value()].source.value();
        match self.image_source(root, image, ImageRead::Srgb)? {
            ImageSource::Data(img) => Ok(img.average()),
            // glTF images are colours.
            ImageSource::File(rel)
            | ImageSource::FloatFile(rel)
            | ImageSource::AlphaFile(rel)
            | ImageSource::EmissionFile(rel)
            | ImageSource::DataFile(rel) => {
                let full = self.base_dir.join(rel);
                let img = ImageTexture::load(&full, Some(Encoding::Srgb)).map_err(|e| {
                    let reason = match e {
                        Error::File { message, .. } => message,
                        other => other.to_string(),
                    };
                    self.err(&format!("images[{image}].uri"), format!("{}: {reason}", full.display()))
                })?;
                Ok(img.average())
            }
        }
    }

    /// The name of the material for glTF material `m` (`None`: the
    /// default material of §3.9.6, reported at `user`, the first primitive
    /// that uses it), converting it on first use.
    fn material(&mut self, root: &json::Root, m: Option<usize>, user: &str) -> Result<String> {
        if let Some(name) = self.materials.get(&m) {
            return Ok(name.clone());
        }
        let default = json::Material::default();
        let (mat, at, name) = match m {
            Some(i) => (&root.materials[i], format!("materials[{i}]"), format!("materials[{i}]")),
            None => (&default, user.to_string(), "glTF default material".to_string()),
        };
        let desc = self.convert_material(root, mat, &at, &name)?;
        self.desc.materials.push(desc);
        self.materials.insert(m, name.clone());
        Ok(name)
    }

    /// The medium inside a transmissive material's shapes from its
    /// KHR_materials_volume: white light turns into `attenuationColor`
    /// over `attenuationDistance` (world units), so the medium absorbs
    /// with σa = −ln(colour)/distance per channel and scatters nothing
    /// (Beer–Lambert). A zero thickness (thin-walled) or an infinite
    /// distance has none. `thickness`, which a rasteriser needs, is not
    /// read: paths measure the distances in the mesh itself.
    fn volume(&mut self, volume: Option<&json::extensions::material::Volume>, at: &str, name: &str) -> Result<()> {
        let Some(v) = volume else { return Ok(()) };
        let v_at = format!("{at}.extensions.KHR_materials_volume");
        let thickness = v.thickness_factor.0;
        if !thickness.is_finite() || thickness < 0.0 {
            return Err(self.err(
                &format!("{v_at}.thicknessFactor"),
                format!("must be a number of at least 0, got {thickness}"),
            ));
        }
        let distance = v.attenuation_distance.0;
        if distance.is_nan() || distance <= 0.0 {
            return Err(self.err(
                &format!("{v_at}.attenuationDistance"),
                format!("must be above 0, got {distance}"),
            ));
        }
        let c_at = format!("{v_at}.attenuationColor");
        let [r, g, b] = v.attenuation_color.0;
        let color = Rgb::new(self.unit(&c_at, r)?, self.unit(&c_at, g)?, self.unit(&c_at, b)?);
        if thickness == 0.0 || distance.is_infinite() || color == Rgb::ONE {
            return Ok(());
        }
        // A black channel would absorb everything it meets (an infinite
        // coefficient): a transmittance of 10⁻³ per attenuation distance
        // stands for it.
        let sigma_a = color.max(Rgb::splat(1e-3)).map(|c| -c.ln() / distance);
        let medium = format!("{name} volume");
        self.desc.media.push(MediumDesc {
            name: medium.clone(),
            sigma_t: FieldDesc::Constant(sigma_a),
            albedo: FieldDesc::Constant(Rgb::ZERO),
            emission: None,
            scale: Rgb::ONE,
            g: 0.0,
            locs: Locs::at(Some(self.loc(&v_at))),
        });
        self.volumes.insert(name.to_string(), medium);
        // Media need the volumetric path tracer, which renders the same
        // surfaces as the path tracer elsewhere.
        self.desc.settings.integrator = crate::settings::IntegratorKind::VolPath;
        Ok(())
    }

    /// A factor in [0, 1] (the schema's range for colours and strengths).
    fn unit(&self, at: &str, v: f32) -> Result<f32> {
        if (0.0..=1.0).contains(&v) {
            Ok(v)
        } else {
            Err(self.err(at, format!("must be between 0 and 1, got {v}")))
        }
    }

    fn convert_material(
        &mut self,
        root: &json::Root,
        mat: &json::Material,
        at: &str,
        name: &str,
    ) -> Result<MaterialDesc> {
        use json::material::AlphaMode;
        let pbr = &mat.pbr_metallic_roughness;
        let pbr_at = format!("{at}.pbrMetallicRoughness");
        let base_at = format!("{pbr_at}.baseColorFactor");
        let f = pbr.base_color_factor.0;
        for c in f {
            self.unit(&base_at, c)?;
        }
        let base = Rgb::new(f[0], f[1], f[2]);
        let metallic = self.unit(&format!("{pbr_at}.metallicFactor"), pbr.metallic_factor.0)?;
        let roughness = self.unit(&format!("{pbr_at}.roughnessFactor"), pbr.roughness_factor.0)?;
        // Perceptual roughness squared is the GGX α (glTF 2.0 Appendix B).
        let alpha = roughness * roughness;
        let ext = mat.extensions.as_ref();
        let ior_at = format!("{at}.extensions.KHR_materials_ior.ior");
        let ior = match ext.and_then(|e| e.ior.as_ref()).map(|i| i.ior.0) {
            None => 1.5,
            Some(v) if v.is_finite() && v >= 1.0 => v,
            Some(v) => {
                self.warn(
                    &ior_at,
                    format!("index of refraction {v} is unsupported: 1.5 is used (trazo needs a finite ior ≥ 1)"),
                );
                1.5
            }
        };
        let transmission = ext.and_then(|e| e.transmission.as_ref());
        let transmission_factor = match transmission {
            Some(t) => self.unit(
                &format!("{at}.extensions.KHR_materials_transmission.transmissionFactor"),
                t.transmission_factor.0,
            )?,
            None => 0.0,
        };

        // Coverage from the base colour's alpha (§3.9.4): MASK cuts the
        // surface out below the cutoff, BLEND lets light through the rest
        // (trazo's cut-out masks, which pass light with probability 1 − α).
        // The alpha is the factor's times the base colour image's (§3.9.2),
        // read through the same sampler and transform.
        let coverage = f[3];
        let mut opacity = None;
        let mask = matches!(mat.alpha_mode, Checked::Valid(AlphaMode::Mask));
        let blend = matches!(mat.alpha_mode, Checked::Valid(AlphaMode::Blend));
        let cutoff = mat.alpha_cutoff.map_or(0.5, |c| c.0);
        if mask && !cutoff.is_finite() {
            return Err(self.err(&format!("{at}.alphaCutoff"), format!("must be a number, got {cutoff}")));
        }
        match &pbr.base_color_texture {
            Some(info) if mask || blend => {
                let base_at = format!("{pbr_at}.baseColorTexture");
                let alpha = format!("{base_at} alpha");
                self.texture_named(root, info, &base_at, &alpha, Rgb::splat(coverage), ImageRead::Alpha)?;
                opacity = Some(ColorSource::Texture(alpha.clone()));
                if mask {
                    let cut = format!("{base_at} mask");
                    self.desc.textures.push(TextureDesc {
                        name: cut.clone(),
                        kind: TextureKind::Node(crate::texture::TextureNode::Cutoff {
                            tex: ColorSource::Texture(alpha),
                            cutoff,
                        }),
                        locs: Locs::at(Some(self.loc(&format!("{at}.alphaCutoff")))),
                    });
                    opacity = Some(ColorSource::Texture(cut));
                }
            }
            _ if mask && coverage < cutoff => opacity = Some(ColorSource::Rgb(Rgb::ZERO)),
            _ if blend && coverage < 1.0 => opacity = Some(ColorSource::Rgb(Rgb::splat(coverage))),
            _ => {}
        }
        // The metallic-roughness image (linear): roughness in green, times
        // its factor and squared for α; metalness in blue, times its factor
        // (§3.9.2).
        let mut metal_map = None;
        let mut roughness_map = None;
        if let Some(info) = &pbr.metallic_roughness_texture {
            let mr_at = format!("{pbr_at}.metallicRoughnessTexture");
            let image = self.texture_encoded(root, info, &mr_at, Rgb::ONE, ImageRead::Linear)?;
            let node = |this: &mut Self, suffix: &str, node: crate::texture::TextureNode<ColorSource>| {
                let name = format!("{mr_at} {suffix}");
                this.desc.textures.push(TextureDesc {
                    name: name.clone(),
                    kind: TextureKind::Node(node),
                    locs: Locs::at(Some(this.loc(&mr_at))),
                });
                ColorSource::Texture(name)
            };
            use crate::texture::TextureNode::{Channel, Scale};
            let green = node(
                self,
                "green",
                Channel {
                    tex: ColorSource::Texture(image.clone()),
                    channel: 1,
                },
            );
            let r = node(
                self,
                "roughness",
                Scale {
                    tex: green,
                    scale: ColorSource::Rgb(Rgb::splat(roughness)),
                },
            );
            let alpha = node(
                self,
                "alpha",
                Scale {
                    tex: r.clone(),
                    scale: r,
                },
            );
            roughness_map = Some(RoughnessMapDesc {
                u: alpha.clone(),
                v: alpha,
                remap_sqrt: false,
            });
            let blue = node(
                self,
                "blue",
                Channel {
                    tex: ColorSource::Texture(image),
                    channel: 2,
                },
            );
            metal_map = Some(node(
                self,
                "metalness",
                Scale {
                    tex: blue,
                    scale: ColorSource::Rgb(Rgb::splat(metallic)),
                },
            ));
        }
        // The normal texture (linear), in glTF's tangent space: its
        // bitangent follows increasing v (§3.9.3; the tangents themselves
        // come from the texture coordinates, see the TANGENT warning).
        let mut normal_map = None;
        if let Some(n) = &mat.normal_texture {
            let n_at = format!("{at}.normalTexture");
            if !n.scale.is_finite() {
                return Err(self.err(&format!("{n_at}.scale"), format!("must be a number, got {}", n.scale)));
            }
            // The gltf crate keeps a normal texture's extensions unparsed:
            // its KHR_texture_transform is read here, and then applies as
            // on every other texture.
            let tt_at = format!("{n_at}.extensions.KHR_texture_transform");
            let texture_transform = match n
                .extensions
                .as_ref()
                .and_then(|e| e.others.get("KHR_texture_transform"))
            {
                Some(value) => Some(
                    json::deserialize::from_value::<json::extensions::texture::TextureTransform>(value.clone())
                        .map_err(|e| self.err(&tt_at, format!("is malformed: {e}")))?,
                ),
                None => None,
            };
            let info = json::texture::Info {
                index: n.index,
                tex_coord: n.tex_coord,
                extensions: texture_transform.map(|tt| json::extensions::texture::Info {
                    texture_transform: Some(tt),
                    others: Default::default(),
                }),
                extras: Default::default(),
            };
            let image = self.texture_encoded(root, &info, &n_at, Rgb::ONE, ImageRead::Linear)?;
            normal_map = Some(NormalMapDesc {
                texture: ColorSource::Texture(image),
                scale: n.scale,
                bitangent_along_v: true,
            });
        }
        if mat.occlusion_texture.is_some() {
            self.warn(
                &format!("{at}.occlusionTexture"),
                "occlusionTexture is unsupported: ignored (the renderer computes occlusion itself)",
            );
        }

        let mut locs = Locs {
            item: Some(self.loc(at)),
            keys: vec![
                ("roughness".into(), self.loc(&format!("{pbr_at}.roughnessFactor"))),
                ("ior".into(), self.loc(&ior_at)),
                ("emission".into(), self.loc(&format!("{at}.emissiveFactor"))),
            ],
        };
        let base_texture_at = format!("{pbr_at}.baseColorTexture");
        // glTF's BRDF is the blend (1 − m)·dielectric + m·metal (§B.3.5):
        // one of the two for m = 0 or 1, else a mix of both.
        let metal = if metallic > 0.0 {
            let reflectance = match &pbr.base_color_texture {
                Some(info) => {
                    self.warn(
                        &base_texture_at,
                        "baseColorTexture on a metal is approximated: the reflectance is the base colour factor times the texture's average colour",
                    );
                    base * self.texture_average(root, info)?
                }
                None => base,
            };
            locs.keys.push(("reflectance".into(), self.loc(&base_at)));
            MaterialKindDesc::Conductor {
                fresnel: ConductorDesc::Reflectance(reflectance),
                tint: Rgb::ONE,
                roughness: (alpha, alpha),
                distribution: MicrofacetDistribution::Ggx,
            }
        } else {
            MaterialKindDesc::Diffuse {
                reflectance: ColorSource::Rgb(Rgb::ZERO),
            }
        };
        // With a metalness image, the dielectric shows where it is below 1.
        let dielectric = if metallic < 1.0 || metal_map.is_some() {
            if transmission_factor > 0.0 && transmission_factor < 1.0 {
                self.warn(
                    &format!("{at}.extensions.KHR_materials_transmission.transmissionFactor"),
                    "partial transmission is approximated: > 0.5 is taken as clear glass, ≤ 0.5 as opaque",
                );
            }
            if transmission.is_some_and(|t| t.transmission_texture.is_some()) {
                self.warn(
                    &format!("{at}.extensions.KHR_materials_transmission.transmissionTexture"),
                    "transmissionTexture is approximated: the transmission factor is used alone",
                );
            }
            if transmission_factor > 0.5 {
                self.volume(ext.and_then(|e| e.volume.as_ref()), at, name)?;
                let transmit_tint = match &pbr.base_color_texture {
                    Some(info) => {
                        self.warn(
                            &base_texture_at,
                            "baseColorTexture on a transmissive material is approximated: the transmission is tinted by the base colour factor times the texture's average colour",
                        );
                        base * self.texture_average(root, info)?
                    }
                    None => base,
                };
                locs.keys.push(("transmit_tint".into(), self.loc(&base_at)));
                MaterialKindDesc::Dielectric {
                    dispersion: None,
                    ior,
                    ext_ior: 1.0,
                    roughness: (alpha, alpha),
                    distribution: MicrofacetDistribution::Ggx,
                    reflect_tint: Rgb::ONE,
                    transmit_tint,
                }
            } else {
                let diffuse = match &pbr.base_color_texture {
                    Some(info) => ColorSource::Texture(self.texture(root, info, &base_texture_at, base)?),
                    None => ColorSource::Rgb(base),
                };
                locs.keys.push(("diffuse".into(), self.loc(&base_at)));
                if ior == 1.0 {
                    // A coat of the surrounding medium's index reflects
                    // nothing: only the diffuse base is left.
                    MaterialKindDesc::Diffuse { reflectance: diffuse }
                } else {
                    MaterialKindDesc::Plastic {
                        diffuse,
                        ior,
                        ext_ior: 1.0,
                        roughness: alpha,
                        distribution: MicrofacetDistribution::Ggx,
                        specular_tint: Rgb::ONE,
                        nonlinear: false,
                    }
                }
            }
        } else {
            MaterialKindDesc::Diffuse {
                reflectance: ColorSource::Rgb(Rgb::ZERO),
            }
        };
        // Glass takes the roughness image as the metal does; the plastic
        // coat and the diffuse base take none.
        let glass = matches!(dielectric, MaterialKindDesc::Dielectric { .. });
        if roughness_map.is_some() && metallic < 1.0 && !glass {
            self.warn(
                &format!("{pbr_at}.metallicRoughnessTexture"),
                "the roughness of metallicRoughnessTexture is approximated on the dielectric: its coat takes the roughness factor (it varies on the metal)",
            );
        }
        let dielectric_roughness = if glass { roughness_map.clone() } else { None };
        let mut own_roughness_map = None;
        let kind = if metallic >= 1.0 && metal_map.is_none() {
            own_roughness_map = roughness_map;
            metal
        } else if metallic <= 0.0 {
            own_roughness_map = dielectric_roughness;
            dielectric
        } else {
            let weight = metal_map.unwrap_or(ColorSource::Rgb(Rgb::splat(metallic)));
            let mut part = |kind: MaterialKindDesc, which: &str, roughness_map: Option<RoughnessMapDesc>| {
                let part_name = format!("{name} ({which})");
                self.desc.materials.push(MaterialDesc {
                    two_sided: mat.double_sided,
                    locs: locs.clone(),
                    roughness_map,
                    ..MaterialDesc::with_kind(part_name.clone(), kind)
                });
                part_name
            };
            let materials = [
                part(dielectric, "dielectric part", dielectric_roughness),
                part(metal, "metal part", roughness_map),
            ];
            MaterialKindDesc::Mix {
                choice: MixChoice::Weight(weight),
                materials,
            }
        };

        // Emission: factor × texture × strength (§3.9.3 and
        // KHR_materials_emissive_strength).
        let ef = mat.emissive_factor.0;
        for c in ef {
            self.unit(&format!("{at}.emissiveFactor"), c)?;
        }
        let strength = match ext.and_then(|e| e.emissive_strength.as_ref()) {
            Some(s) => {
                let v = s.emissive_strength.0;
                if !(v.is_finite() && v >= 0.0) {
                    return Err(self.err(
                        &format!("{at}.extensions.KHR_materials_emissive_strength.emissiveStrength"),
                        format!("must be a finite number ≥ 0, got {v}"),
                    ));
                }
                v
            }
            None => 1.0,
        };
        let radiance = Rgb::new(ef[0], ef[1], ef[2]) * strength;
        let emission = if radiance == Rgb::ZERO {
            ColorSource::Rgb(Rgb::ZERO)
        } else {
            self.any_emission = true;
            if mat.double_sided {
                self.warn(
                    &format!("{at}.doubleSided"),
                    "emission from a double-sided material is approximated: only the front faces emit",
                );
            }
            match &mat.emissive_texture {
                Some(info) => {
                    ColorSource::Texture(self.texture(root, info, &format!("{at}.emissiveTexture"), radiance)?)
                }
                None => ColorSource::Rgb(radiance),
            }
        };
        if !mat.double_sided {
            self.warn(
                &format!("{at}.doubleSided"),
                "single-sided materials are approximated: back faces are not culled but scatter no light",
            );
        }
        Ok(MaterialDesc {
            name: name.to_string(),
            kind,
            emission,
            // glTF 2.0: a double-sided material is lit, and so emits, on
            // both sides.
            emits_both_sides: mat.double_sided,
            two_sided: mat.double_sided,
            opacity,
            normal_map,
            bump_map: None,
            roughness_map: own_roughness_map,
            locs,
        })
    }

    /// KHR_lights_punctual lights of placed nodes. Lights shine along the
    /// node's −Z (extension spec, "Adding Light Instances to Nodes").
    fn read_lights(&mut self, root: &json::Root, placed: &[Placed]) -> Result<()> {
        use json::extensions::scene::khr_lights_punctual::Type;
        let lights = root
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .map_or(&[][..], |l| &l.lights[..]);
        for p in placed {
            let Some(l) = root.nodes[p.node]
                .extensions
                .as_ref()
                .and_then(|e| e.khr_lights_punctual.as_ref())
                .map(|l| l.light.value())
            else {
                continue;
            };
            let light = &lights[l];
            let at = format!("extensions.KHR_lights_punctual.lights[{l}]");
            let color = Vec3::from(light.color);
            if !color.is_finite() || color.min_element() < 0.0 {
                return Err(self.err(&format!("{at}.color"), "must be finite and not negative"));
            }
            if !(light.intensity.is_finite() && light.intensity >= 0.0) {
                return Err(self.err(
                    &format!("{at}.intensity"),
                    format!("must be a finite number ≥ 0, got {}", light.intensity),
                ));
            }
            self.warn(
                &at,
                "KHR_lights_punctual intensities are approximated: candela are taken as W/sr and lux as W/m², times the light's colour",
            );
            if light.range.is_some() {
                self.warn(
                    &format!("{at}.range"),
                    "a light's range is unsupported: the light falls off with the inverse square of distance and no cut-off",
                );
            }
            let power = color * light.intensity;
            let position = p.world.transform_point3(Vec3::ZERO);
            let direction = p.world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
            let ty = match light.type_ {
                Checked::Valid(t) => t,
                Checked::Invalid => return Err(self.err(&format!("{at}.type"), "has an invalid value")),
            };
            if ty != Type::Point && direction == Vec3::ZERO {
                self.warn(
                    &format!("nodes[{}]", p.node),
                    "a light under a singular transform has no direction: skipped",
                );
                continue;
            }
            let kind = match ty {
                Type::Point => LightKind::Point {
                    position,
                    intensity: power,
                    falloff: true,
                },
                Type::Directional => LightKind::Directional {
                    direction,
                    irradiance: power,
                },
                Type::Spot => {
                    let spot = light.spot.clone().unwrap_or_default();
                    let (inner, outer) = (spot.inner_cone_angle, spot.outer_cone_angle);
                    // Extension schema: 0 ≤ inner < outer ≤ π/2.
                    if !(inner.is_finite()
                        && outer.is_finite()
                        && inner >= 0.0
                        && inner < outer
                        && outer <= std::f32::consts::FRAC_PI_2 + 1e-6)
                    {
                        return Err(self.err(
                            &format!("{at}.spot"),
                            format!("cone angles must satisfy 0 ≤ innerConeAngle < outerConeAngle ≤ π/2, got {inner} and {outer}"),
                        ));
                    }
                    LightKind::Spot {
                        position,
                        to: position + direction,
                        intensity: power,
                        inner_angle: inner.to_degrees(),
                        outer_angle: outer.to_degrees(),
                        profile: crate::light::SpotProfile::SmoothStepInCosine,
                        projection: None,
                        falloff: true,
                    }
                }
            };
            self.desc.lights.push(LightDesc {
                kind,
                locs: Locs::at(Some(self.loc(&at))),
            });
        }
        Ok(())
    }

    /// The first camera in the node hierarchy (depth first), if any.
    fn read_camera(&mut self, root: &json::Root, placed: &[Placed], bounds: &Aabb) -> Result<bool> {
        use json::camera::Type;
        let mut with_camera = placed
            .iter()
            .filter_map(|p| root.nodes[p.node].camera.map(|c| (p, c.value())));
        let Some((p, c)) = with_camera.next() else {
            return Ok(false);
        };
        for (other, _) in with_camera {
            self.warn(
                &format!("nodes[{}].camera", other.node),
                "more than one camera is unsupported: the first in the node hierarchy is used",
            );
        }
        let cam = &root.cameras[c];
        let at = format!("cameras[{c}]");
        let node_at = format!("nodes[{}]", p.node);
        let ty = match cam.type_ {
            Checked::Valid(t) => t,
            Checked::Invalid => return Err(self.err(&format!("{at}.type"), "has an invalid value")),
        };
        let positive = |key: &str, v: f32| -> Result<f32> {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(self.err(&format!("{at}.{key}"), format!("must be a positive number, got {v}")))
            }
        };
        let (projection, aspect) = match ty {
            Type::Perspective => {
                let Some(per) = &cam.perspective else {
                    return Err(self.err(&format!("{at}.perspective"), "is missing for a perspective camera"));
                };
                let yfov = positive("perspective.yfov", per.yfov)?;
                if yfov >= std::f32::consts::PI {
                    return Err(self.err(
                        &format!("{at}.perspective.yfov"),
                        format!("must be less than π radians, got {yfov}"),
                    ));
                }
                let aspect = per
                    .aspect_ratio
                    .map(|a| positive("perspective.aspectRatio", a))
                    .transpose()?;
                if per.zfar.is_some() || per.znear > 1e-3 * bounds.extent().length() {
                    self.warn(
                        &format!("{at}.perspective"),
                        "camera clipping planes (znear, zfar) are unsupported: everything in front of the camera is visible",
                    );
                }
                (ProjectionDesc::Perspective { fov: yfov.to_degrees() }, aspect)
            }
            Type::Orthographic => {
                let Some(ortho) = &cam.orthographic else {
                    return Err(self.err(&format!("{at}.orthographic"), "is missing for an orthographic camera"));
                };
                let xmag = positive("orthographic.xmag", ortho.xmag)?;
                let ymag = positive("orthographic.ymag", ortho.ymag)?;
                self.warn(
                    &format!("{at}.orthographic"),
                    "camera clipping planes (znear, zfar) are unsupported: everything in front of the camera is visible",
                );
                // xmag and ymag are half the width and height of the view.
                (ProjectionDesc::Orthographic { size: 2.0 * ymag }, Some(xmag / ymag))
            }
        };
        if Transform::from_matrix(p.world).is_err() {
            return Err(self.err(
                &node_at,
                "the camera's node has a singular world transform (a zero scale)",
            ));
        }
        let aspect = aspect.unwrap_or(4.0 / 3.0);
        self.desc.settings.width = FILM_WIDTH;
        self.desc.settings.height = (FILM_WIDTH as f32 / aspect).round().clamp(1.0, MAX_IMAGE_SIDE as f32) as u32;
        // glTF cameras look along −Z with +Y up and +X right (§3.10.1);
        // trazo's look along +Z: mirror z into the node's frame.
        let to_world = p.world * Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0));
        self.desc.camera = CameraDesc {
            projection,
            to_world: Some(to_world),
            locs: Locs {
                item: Some(self.loc(&at)),
                keys: vec![("to_world".into(), self.loc(&node_at))],
            },
            ..CameraDesc::default()
        };
        Ok(true)
    }
}

fn decode_f32(ct: ComponentType, normalized: bool, b: &[u8]) -> f32 {
    // §3.11, "normalized integers" (used by KHR_mesh_quantization and
    // by core texture coordinates):
    // normalized integers map to [0, 1] or [−1, 1].
    match ct {
        ComponentType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        ComponentType::U8 => {
            let v = b[0] as f32;
            if normalized { v / 255.0 } else { v }
        }
        ComponentType::I8 => {
            let v = b[0] as i8 as f32;
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        ComponentType::U16 => {
            let v = u16::from_le_bytes([b[0], b[1]]) as f32;
            if normalized { v / 65535.0 } else { v }
        }
        ComponentType::I16 => {
            let v = i16::from_le_bytes([b[0], b[1]]) as f32;
            if normalized { (v / 32767.0).max(-1.0) } else { v }
        }
        ComponentType::U32 => {
            let v = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            if normalized {
                (v as f64 / u32::MAX as f64) as f32
            } else {
                v as f32
            }
        }
    }
}

fn mode_name(m: json::mesh::Mode) -> &'static str {
    use json::mesh::Mode::*;
    match m {
        Points => "POINTS",
        Lines => "LINES",
        LineLoop => "LINE_LOOP",
        LineStrip => "LINE_STRIP",
        Triangles => "TRIANGLES",
        TriangleStrip => "TRIANGLE_STRIP",
        TriangleFan => "TRIANGLE_FAN",
    }
}

fn type_name(t: AccessorType) -> &'static str {
    match t {
        AccessorType::Scalar => "SCALAR",
        AccessorType::Vec2 => "VEC2",
        AccessorType::Vec3 => "VEC3",
        AccessorType::Vec4 => "VEC4",
        AccessorType::Mat2 => "MAT2",
        AccessorType::Mat3 => "MAT3",
        AccessorType::Mat4 => "MAT4",
    }
}

fn component_name(c: ComponentType) -> &'static str {
    match c {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

/// A relative URI reference (RFC 3986) as a file path: percent-escapes
/// decoded; absolute URLs (`http:`, `file:` …) are refused.
fn uri_to_path(uri: &str) -> std::result::Result<PathBuf, String> {
    if let Some(colon) = uri.find(':') {
        let scheme = &uri[..colon];
        if colon > 1 && scheme.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c)) {
            return Err(format!(
                "URI \"{uri}\" is unsupported: trazo reads files by relative path and data: URIs only"
            ));
        }
    }
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        match (
            bytes[i],
            bytes.get(i + 1).copied().and_then(hex),
            bytes.get(i + 2).copied().and_then(hex),
        ) {
            (b'%', Some(h), Some(l)) => {
                out.push((h * 16 + l) as u8);
                i += 3;
            }
            (c, _, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    let path = String::from_utf8(out).map_err(|_| format!("URI \"{uri}\" does not decode to UTF-8 text"))?;
    Ok(PathBuf::from(path))
}

/// Decodes `data:[<media type>];base64,<data>` (RFC 2397) into its media
/// type and bytes.
fn decode_data_uri(uri: &str) -> std::result::Result<(String, Vec<u8>), String> {
    let rest = &uri["data:".len()..];
    let Some((meta, data)) = rest.split_once(',') else {
        return Err("the data URI has no ',' before its data".into());
    };
    let Some(media_type) = meta.strip_suffix(";base64") else {
        return Err("data URIs that are not base64-encoded are unsupported".into());
    };
    let bytes = base64_decode(data).map_err(|e| format!("the data URI's base64 data is invalid: {e}"))?;
    Ok((media_type.to_string(), bytes))
}

/// Standard base64 (RFC 4648 §4; the URL-safe alphabet of §5 is accepted
/// too), with or without padding.
fn base64_decode(s: &str) -> std::result::Result<Vec<u8>, String> {
    let data = s.trim_end_matches('=');
    if s.len() - data.len() > 2 {
        return Err("more than two '=' at the end".into());
    }
    if data.len() % 4 == 1 {
        return Err(format!("{} characters cannot be base64 (truncated?)", data.len()));
    }
    let mut out = Vec::with_capacity(data.len() / 4 * 3 + 2);
    let mut acc = 0u32;
    let mut bits = 0;
    for (i, c) in data.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => {
                return Err(format!(
                    "character {:?} at offset {i} is not base64",
                    data[i..].chars().next().unwrap_or('?')
                ));
            }
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_and_rejects_garbage() {
        assert_eq!(base64_decode("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(base64_decode("aGVsbG8").unwrap(), b"hello");
        assert_eq!(base64_decode("AAEC").unwrap(), [0, 1, 2]);
        assert_eq!(base64_decode("").unwrap(), b"");
        assert!(base64_decode("aGV$bG8=").unwrap_err().contains("offset 3"));
        assert!(base64_decode("a").is_err());
        assert!(base64_decode("aGVsbG8====").is_err());
    }

    #[test]
    fn data_uris_and_relative_uris() {
        let (mime, data) = decode_data_uri("data:application/octet-stream;base64,AAEC").unwrap();
        assert_eq!((mime.as_str(), data), ("application/octet-stream", vec![0, 1, 2]));
        assert!(decode_data_uri("data:text/plain,hello").is_err());
        assert!(decode_data_uri("data:nocomma").is_err());
        assert_eq!(uri_to_path("my%20tex.png").unwrap(), PathBuf::from("my tex.png"));
        assert_eq!(uri_to_path("sub/a.bin").unwrap(), PathBuf::from("sub/a.bin"));
        assert!(uri_to_path("https://example.com/a.bin").is_err());
    }

    #[test]
    fn json_paths_are_located() {
        let text =
            "{\n  \"meshes\": [\n    {\"primitives\": [{\"attributes\": {\"POSITION\": 0}}]}\n  ],\n  \"x\": [1, 2]\n}";
        let loc = Locator::new(text, Arc::from(Path::new("m.gltf")));
        let l = loc.loc("meshes[0].primitives[0].attributes[\"POSITION\"]");
        assert_eq!((l.line, l.column), (3, 37));
        let l = loc.loc("meshes[0].primitives[0].indices");
        assert_eq!((l.line, l.column), (3, 21));
        let l = loc.loc("x[1]");
        assert_eq!((l.line, l.column), (5, 3));
        let l = loc.loc("extensionsRequired[0] = \"FOO\"");
        assert_eq!((l.line, l.column), (1, 1));
        assert_eq!(path_segments("a.b[2][\"c.d\"] = \"v\""), ["a", "b", "2", "c.d"]);
    }

    #[test]
    fn glb_headers_are_checked() {
        let p = Path::new("t.glb");
        let json = b"{\"asset\":{\"version\":\"2.0\"}}";
        let mut glb = Vec::new();
        glb.extend_from_slice(b"glTF");
        glb.extend_from_slice(&2u32.to_le_bytes());
        glb.extend_from_slice(&((20 + json.len()) as u32).to_le_bytes());
        glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
        glb.extend_from_slice(&CHUNK_JSON.to_le_bytes());
        glb.extend_from_slice(json);
        let (j, bin) = split_glb(p, &glb).unwrap();
        assert_eq!(j, json);
        assert!(bin.is_none());
        for cut in 0..glb.len() {
            assert!(split_glb(p, &glb[..cut]).is_err(), "cut at {cut}");
        }
        let mut v1 = glb.clone();
        v1[4] = 1;
        assert!(split_glb(p, &v1).unwrap_err().to_string().contains("version 1"));
    }
}
