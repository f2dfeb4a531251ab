//! Mitsuba 3 scene files (XML), read into a [`SceneDesc`].
//!
//! Mitsuba's scene format (documented in its manual, "Scene format") is a
//! tree of plugins — `<shape type="sphere">`, `<bsdf type="diffuse">`, … —
//! whose parameters are typed children (`<float name="radius" value="2"/>`).
//! `<default name="x" value="1"/>` and `-D x=2` on the command line give
//! values to `$x` references in any attribute.
//!
//! Conventions carried over (so that both renderers produce the same
//! image): Mitsuba's camera space has +x to the image's *left*, so its
//! `to_world` is composed with a mirror of x; `fov` is measured along
//! `fov_axis` (default `x`); bitmap textures have v = 0 at the top of the
//! image; OBJ texture coordinates are flipped on load (`flip_tex_coords`,
//! default true); BSDFs are one-sided unless wrapped in `twosided`; area
//! emitters belong to the shape they are attached to; an `instance` places
//! every shape of its `shapegroup` with its to_world after the shape's own,
//! the group's meshes named so that the build step stores each once and
//! instances it. What trazo does not support is reported as a warning
//! naming the element and its line, and documented in docs/formats.md.

use super::desc::*;
use crate::color::spectrum::{SpectrumUse, sampled_to_rgb};
use crate::color::{Encoding, Rgb};
use crate::error::{Error, Result, SourceLoc};
use crate::files::{MAX_XML_BYTES, io_reason, read_limited};
use crate::geometry::TriangleMesh;
use crate::light::SpotProfile;
use crate::sampling::SamplerKind;
use crate::settings::{Filter, IntegratorKind, MAX_DEPTH, MAX_SPP, PathSampling};
use glam::{Mat4, Vec2, Vec3};
use roxmltree::{Document, Node, ParsingOptions};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Deepest chain of `<include>`s.
const MAX_INCLUDE_DEPTH: usize = 32;

/// Reads a Mitsuba 3 scene. `defines` set `$name` parameters and take
/// precedence over the file's `<default>`s.
pub fn load(path: &Path, defines: &[(String, String)]) -> Result<SceneDesc> {
    let mut loader = Loader::new(defines);
    loader.load_file(path, None)?;
    loader.finish()
}

/// Reads Mitsuba XML from a string (`path` names it in messages and
/// resolves relative file names).
pub fn parse(text: &str, path: &Path, defines: &[(String, String)]) -> Result<SceneDesc> {
    let mut loader = Loader::new(defines);
    loader.include_stack.push(path.to_path_buf());
    loader.process_text(text, path)?;
    loader.finish()
}

/// Indices of refraction Mitsuba knows by name (its `ior.h` table).
fn named_ior(name: &str) -> Option<f32> {
    Some(match name.to_ascii_lowercase().as_str() {
        "vacuum" => 1.0,
        "helium" => 1.000036,
        "hydrogen" => 1.000132,
        "air" => 1.000277,
        "carbon dioxide" => 1.00045,
        "water" => 1.3330,
        "acetone" => 1.36,
        "ethanol" => 1.361,
        "carbon tetrachloride" => 1.461,
        "glycerol" => 1.4729,
        "benzene" => 1.501,
        "silicone oil" => 1.52045,
        "bromine" => 1.661,
        "water ice" => 1.31,
        "fused quartz" => 1.458,
        "pyrex" => 1.470,
        "acrylic glass" => 1.49,
        "polypropylene" => 1.49,
        "bk7" => 1.5046,
        "sodium chloride" => 1.544,
        "amber" => 1.55,
        "pet" => 1.5750,
        "diamond" => 2.419,
        _ => return None,
    })
}

/// One XML file being read.
struct FileCtx {
    path: Arc<Path>,
    text: String,
}

impl FileCtx {
    fn loc(&self, offset: usize) -> SourceLoc {
        SourceLoc::from_offset(&self.path, &self.text, offset)
    }
    fn loc_of(&self, node: Node) -> SourceLoc {
        self.loc(node.range().start)
    }
}

/// A BSDF registered under an `id`.
#[derive(Clone)]
struct BsdfDef {
    kind: MaterialKindDesc,
    two_sided: bool,
    /// A `mask`'s opacity.
    opacity: Option<ColorSource>,
    /// A `normalmap`'s texture.
    normal_map: Option<ColorSource>,
    /// A `bumpmap`'s texture and scale.
    bump_map: Option<BumpMapDesc>,
    /// Roughness textures of a rough conductor or dielectric.
    roughness_map: Option<RoughnessMapDesc>,
    /// The desc material already made for it (without emission).
    material: Option<String>,
    loc: SourceLoc,
}

/// The deepest nesting of elements read: real scenes nest a few levels
/// (scene, shape, BSDF, nested BSDFs, texture); the reader recurses once
/// per level.
const MAX_NESTING: usize = 64;

/// The elements that instantiate a plugin by `type` (and may carry an id).
const PLUGIN_TAGS: &[&str] = &[
    "bsdf",
    "emitter",
    "film",
    "integrator",
    "medium",
    "phase",
    "rfilter",
    "sampler",
    "sensor",
    "shape",
    "spectrum",
    "texture",
    "volume",
];

/// Mitsuba 0.6's bidirectional integrators, gone from Mitsuba 3, which
/// trazo reads: `bdpt`, and the Metropolis samplers over it.
const MITSUBA_06_INTEGRATORS: [&str; 3] = ["bdpt", "pssmlt", "mlt"];

/// Every plugin Mitsuba 3.9.1 ships (its `plugins` folder, and the
/// integrators its Python package registers), by name.
const MITSUBA_PLUGINS: &[&str] = &[
    "aov",
    "area",
    "batch",
    "bitmap",
    "blackbody",
    "blendbsdf",
    "blender",
    "blendphase",
    "box",
    "bsplinecurve",
    "bumpmap",
    "catmullrom",
    "checkerboard",
    "circular",
    "conductor",
    "constant",
    "constvolume",
    "cube",
    "cylinder",
    "d65",
    "depth",
    "dielectric",
    "diffuse",
    "direct",
    "direct_projective",
    "directional",
    "directionalarea",
    "disk",
    "distant",
    "ellipsoids",
    "ellipsoidsmesh",
    "envmap",
    "gaussian",
    "gridvolume",
    "hair",
    "hdrfilm",
    "heterogeneous",
    "hg",
    "homogeneous",
    "independent",
    "instance",
    "irradiancemeter",
    "irregular",
    "isotropic",
    "lanczos",
    "ldsampler",
    "linearcurve",
    "mask",
    "measured",
    "measured_polarized",
    "merge",
    "mesh_attribute",
    "mitchell",
    "moment",
    "multijitter",
    "normalmap",
    "null",
    "obj",
    "orthogonal",
    "orthographic",
    "path",
    "perspective",
    "plastic",
    "ply",
    "point",
    "polarizer",
    "pplastic",
    "prb",
    "prb_basic",
    "prb_projective",
    "prbvolpath",
    "principled",
    "principledthin",
    "projector",
    "ptracer",
    "radiancemeter",
    "rawconstant",
    "rayleigh",
    "rectangle",
    "regular",
    "retarder",
    "roughconductor",
    "roughdielectric",
    "roughplastic",
    "sdfgrid",
    "serialized",
    "sggx",
    "shapegroup",
    "specfilm",
    "sphere",
    "spot",
    "srgb",
    "stokes",
    "stratified",
    "sunsky",
    "tabphase",
    "tent",
    "thindielectric",
    "thinlens",
    "timed_sunsky",
    "twosided",
    "uniform",
    "volpath",
    "volpathmis",
    "volprim_rf_basic",
    "volume",
];

struct Loader {
    desc: SceneDesc,
    params: HashMap<String, String>,
    from_cli: HashSet<String>,
    used_cli: HashSet<String>,
    include_stack: Vec<PathBuf>,
    bsdfs: HashMap<String, BsdfDef>,
    textures: HashMap<String, ColorSource>,
    /// Media by id: the names of their descriptions.
    media: HashMap<String, String>,
    counter: usize,
    default_material: Option<String>,
    saw_sensor: bool,
    saw_integrator: bool,
    /// Shape groups by id.
    groups: HashMap<String, GroupDef>,
    /// Instances in the order read, placed by `finish` (Mitsuba resolves
    /// references after reading the whole file, so an instance may come
    /// before its group).
    instances: Vec<InstanceUse>,
    /// The meshes of groups, each file read once: by (type, path,
    /// face_normals, flip_tex_coords), the name of its [`MeshDesc`].
    group_mesh_names: HashMap<(String, PathBuf, u32, bool, bool), String>,
    /// Those meshes; `finish` keeps the ones a placed shape uses.
    group_meshes: Vec<MeshDesc>,
    /// Where relative file names are looked for, first first, as Mitsuba's
    /// file resolver: the main scene's folder, with each `<path>` put in
    /// front of it. Included files resolve names against these too, not
    /// against their own folder.
    search_paths: Vec<PathBuf>,
    /// Whether an emitter's properties are being read (its spectra
    /// convert as emission).
    in_emitter: bool,
    /// Where each object id was defined, in every file read: Mitsuba
    /// refuses a second object with the same id.
    ids: HashMap<String, SourceLoc>,
    /// Top-level area emitters by id, for shapes that refer to them.
    area_emitters: HashMap<String, (ColorSource, SourceLoc)>,
    /// Top-level samplers by id (kind, samples per pixel, seed), for the
    /// sensor that refers to one.
    samplers: HashMap<String, (SamplerKind, u32, u64)>,
}

/// A `<shape type="shapegroup" id="..">`: its shapes, each with its own
/// transform and material, and meshes named, not inline, so that every
/// placement shares one copy of the triangles.
struct GroupDef {
    loc: SourceLoc,
    shapes: Vec<ShapeDesc>,
    placed: bool,
}

/// A `<shape type="instance">`.
struct InstanceUse {
    /// The group's id and where the `<ref>` naming it was written.
    id: String,
    ref_loc: SourceLoc,
    loc: SourceLoc,
    to_world: Mat4,
    /// How many shapes were read before it: its group's shapes go there.
    position: usize,
}

/// Children of a plugin that are values, not nested plugins.
const PROPERTY_TAGS: [&str; 9] = [
    "float",
    "integer",
    "boolean",
    "string",
    "point",
    "vector",
    "rgb",
    "spectrum",
    "transform",
];

/// Parsed value of a colour-like property.
enum ColorProp {
    Constant(Rgb),
    Texture(ColorSource),
}

impl Loader {
    fn new(defines: &[(String, String)]) -> Loader {
        let mut desc = SceneDesc::default();
        // Mitsuba's defaults where they differ from trazo's.
        desc.settings.width = 768;
        desc.settings.height = 576;
        desc.settings.spp = 4;
        desc.settings.max_depth = MAX_DEPTH;
        desc.settings.integrator = IntegratorKind::Path;
        desc.settings.sampling = PathSampling::Mis;
        desc.settings.sampler = SamplerKind::Independent;
        desc.settings.filter = Filter::from_name("gaussian").expect("known filter");
        Loader {
            desc,
            params: defines.iter().cloned().collect(),
            from_cli: defines.iter().map(|(k, _)| k.clone()).collect(),
            used_cli: HashSet::new(),
            include_stack: Vec::new(),
            bsdfs: HashMap::new(),
            textures: HashMap::new(),
            media: HashMap::new(),
            counter: 0,
            default_material: None,
            saw_sensor: false,
            saw_integrator: false,
            groups: HashMap::new(),
            ids: HashMap::new(),
            area_emitters: HashMap::new(),
            samplers: HashMap::new(),
            instances: Vec::new(),
            group_mesh_names: HashMap::new(),
            group_meshes: Vec::new(),
            search_paths: Vec::new(),
            in_emitter: false,
        }
    }

    fn finish(mut self) -> Result<SceneDesc> {
        self.place_instances()?;
        for name in &self.from_cli {
            if !self.used_cli.contains(name) {
                self.desc.warnings.push(format!(
                    "-D {name}: the scene has no parameter ${name}; the definition is not used"
                ));
            }
        }
        if !self.saw_sensor {
            self.desc.warnings.push(
                "the scene has no <sensor>: using Mitsuba's default (perspective, fov 39.6° along x, at the origin looking down +z)"
                    .into(),
            );
            self.desc.camera.to_world = Some(Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)));
            self.desc.camera.projection = ProjectionDesc::Perspective {
                fov: vertical_fov(
                    39.597_755,
                    FovAxis::X,
                    self.desc.settings.width,
                    self.desc.settings.height,
                ),
            };
            (self.desc.camera.near_clip, self.desc.camera.far_clip) = (1e-2, 1e4);
        }
        if !self.saw_integrator {
            self.desc
                .warnings
                .push("the scene has no <integrator>: using trazo's path tracer (Mitsuba's default)".into());
        }
        self.desc.validate()?;
        Ok(self.desc)
    }

    fn fresh_name(&mut self, stem: &str) -> String {
        self.counter += 1;
        format!("{stem}-{}", self.counter)
    }

    fn warn(&mut self, f: &FileCtx, node: Node, msg: impl AsRef<str>) {
        let what = describe(node);
        self.desc
            .warnings
            .push(format!("{}: {what}: {}", f.loc_of(node), msg.as_ref()));
    }

    fn err(&self, f: &FileCtx, node: Node, msg: impl Into<String>) -> Error {
        Error::Scene {
            loc: Some(f.loc_of(node)),
            key: None,
            message: format!("{}: {}", describe(node), msg.into()),
        }
    }

    /// A file name as Mitsuba's file resolver finds it: as it is if
    /// absolute, else in the first search path that holds it, else in the
    /// main scene's folder (where it is then reported missing).
    fn resolve(&self, name: &str) -> PathBuf {
        let name = Path::new(name);
        if name.is_absolute() {
            return name.to_path_buf();
        }
        self.search_paths
            .iter()
            .map(|dir| dir.join(name))
            .find(|p| p.exists())
            .unwrap_or_else(|| {
                self.search_paths
                    .last()
                    .map_or_else(|| name.to_path_buf(), |d| d.join(name))
            })
    }

    fn load_file(&mut self, path: &Path, from: Option<(&FileCtx, Node)>) -> Result<()> {
        let canonical = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
        if self.include_stack.contains(&canonical) {
            let (f, node) = from.expect("the first file cannot loop");
            return Err(self.err(
                f,
                node,
                format!("include loop: {} is already being read", path.display()),
            ));
        }
        if self.include_stack.len() >= MAX_INCLUDE_DEPTH {
            let (f, node) = from.expect("depth > 0 means an include");
            return Err(self.err(f, node, "includes nested more than 32 deep"));
        }
        let meta = std::fs::metadata(path).map_err(|e| match from {
            Some((f, node)) => self.err(f, node, format!("cannot read {}: {}", path.display(), io_reason(&e))),
            None => Error::file(path, format!("cannot read scene: {}", io_reason(&e))),
        })?;
        if meta.is_dir() {
            return Err(Error::file(path, "cannot read scene: this is a folder"));
        }
        if meta.len() > MAX_XML_BYTES {
            return Err(Error::file(path, "scene file is larger than 256 MiB"));
        }
        let bytes = read_limited(path, MAX_XML_BYTES).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
        let text = String::from_utf8(bytes)
            .map_err(|e| Error::file(path, format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to())))?;
        self.include_stack.push(canonical);
        self.process_text(&text, path)?;
        self.include_stack.pop();
        Ok(())
    }

    fn process_text(&mut self, text: &str, path: &Path) -> Result<()> {
        if self.search_paths.is_empty() {
            self.search_paths
                .push(path.parent().map(Path::to_path_buf).unwrap_or_default());
        }
        let f = FileCtx {
            path: Arc::from(path),
            text: text.to_string(),
        };
        let options = ParsingOptions {
            allow_dtd: false,
            nodes_limit: 10_000_000,
            ..ParsingOptions::default()
        };
        let doc = Document::parse_with_options(&f.text, options).map_err(|e| {
            let pos = e.pos();
            Error::Scene {
                loc: Some(SourceLoc {
                    file: f.path.clone(),
                    line: pos.row,
                    column: pos.col,
                }),
                key: None,
                message: format!("XML syntax error: {e}"),
            }
        })?;
        let root = doc.root_element();
        if root.tag_name().name() != "scene" {
            return Err(self.err(&f, root, "the root element must be <scene>"));
        }
        self.check_structure(&f, root)?;
        for child in root.children().filter(Node::is_element) {
            self.scene_child(&f, child)?;
        }
        Ok(())
    }

    /// Checks the whole document before reading it, without recursion:
    /// elements nested deeper than [`MAX_NESTING`] (which the recursive
    /// reading below could not follow without overflowing its stack) and
    /// a second object with an id already defined (an error in Mitsuba,
    /// also across included files). Ids made of `$` parameters are not
    /// known yet and are not checked.
    fn check_structure(&mut self, f: &FileCtx, root: Node) -> Result<()> {
        // Elements in document order, each with its depth (the scene's is 1).
        let mut stack = vec![(root, 1usize)];
        // The line and column (in characters) of byte `counted`.
        let (mut counted, mut line, mut column) = (0usize, 1u32, 1u32);
        while let Some((node, depth)) = stack.pop() {
            if depth > MAX_NESTING {
                return Err(self.err(
                    f,
                    node,
                    format!("elements are nested more than {MAX_NESTING} deep; trazo refuses such a scene"),
                ));
            }
            // Pushed last to first, so that the first child is checked next.
            stack.extend(node.children().rev().filter(Node::is_element).map(|c| (c, depth + 1)));
            let tag = node.tag_name().name();
            let Some(id) = node.attribute("id") else {
                continue;
            };
            if !PLUGIN_TAGS.contains(&tag) || id.contains('$') {
                continue;
            }
            // Lines counted on from the last id's, as the elements come in
            // the order of the text: locating each from the start would
            // make a scene of many ids quadratic.
            let offset = node.range().start;
            for c in f.text[counted..offset].chars() {
                if c == '\n' {
                    (line, column) = (line + 1, 1);
                } else {
                    column += 1;
                }
            }
            counted = offset;
            let loc = SourceLoc {
                file: f.path.clone(),
                line,
                column,
            };
            if let Some(first) = self.ids.get(id) {
                return Err(self.err(
                    f,
                    node,
                    format!(
                        "duplicate id \"{id}\" (first defined at {}:{}:{})",
                        first.file.display(),
                        first.line,
                        first.column
                    ),
                ));
            }
            self.ids.insert(id.to_string(), loc);
        }
        Ok(())
    }

    /// Substitutes `$name` parameters in an attribute's value.
    fn attr(&mut self, f: &FileCtx, node: Node, name: &str) -> Result<Option<String>> {
        let Some(raw) = node.attribute(name) else {
            return Ok(None);
        };
        if !raw.contains('$') {
            return Ok(Some(raw.to_string()));
        }
        let mut out = String::new();
        let mut rest = raw;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let after = &rest[i + 1..];
            let len = after
                .char_indices()
                .find(|(_, c)| !(c.is_ascii_alphanumeric() || *c == '_'))
                .map_or(after.len(), |(k, _)| k);
            let key = &after[..len];
            if key.is_empty() {
                out.push('$');
                rest = after;
                continue;
            }
            match self.params.get(key) {
                Some(v) => {
                    out.push_str(v);
                    if self.from_cli.contains(key) {
                        self.used_cli.insert(key.to_string());
                    }
                }
                None => {
                    return Err(self.err(
                        f,
                        node,
                        format!("undefined parameter ${key} (give it a <default> or -D {key}=VALUE)"),
                    ));
                }
            }
            rest = &after[len..];
        }
        out.push_str(rest);
        Ok(Some(out))
    }

    /// An attribute that must be there. A plugin's `type` must also be one
    /// that Mitsuba 3 knows (a type Mitsuba knows and trazo does not is
    /// warned about where it is read; one Mitsuba does not know is an
    /// error in Mitsuba too), or one of Mitsuba 0.6's bidirectional
    /// integrators, which trazo renders.
    fn required_attr(&mut self, f: &FileCtx, node: Node, name: &str) -> Result<String> {
        let value = self
            .attr(f, node, name)?
            .ok_or_else(|| self.err(f, node, format!("missing attribute `{name}`")))?;
        let legacy = node.tag_name().name() == "integrator" && MITSUBA_06_INTEGRATORS.contains(&value.as_str());
        if name == "type"
            && PLUGIN_TAGS.contains(&node.tag_name().name())
            && !MITSUBA_PLUGINS.contains(&value.as_str())
            && !legacy
        {
            return Err(self.err(
                f,
                node,
                format!(
                    "unknown plugin type \"{value}\": Mitsuba 3 has no such plugin{}",
                    crate::scene::desc::suggest(&value, MITSUBA_PLUGINS.iter().copied())
                ),
            ));
        }
        Ok(value)
    }

    fn scene_child(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        match node.tag_name().name() {
            "default" => {
                let name = self.required_attr(f, node, "name")?;
                let value = self.required_attr(f, node, "value")?;
                self.params.entry(name).or_insert(value);
            }
            "include" => {
                let file = self.required_attr(f, node, "filename")?;
                let path = self.resolve(&file);
                self.load_file(&path, Some((f, node)))?;
            }
            "path" => {
                let value = self.required_attr(f, node, "value")?;
                let dir = self.resolve(&value);
                if !dir.is_dir() {
                    return Err(self.err(f, node, format!("search path is not a folder: {}", dir.display())));
                }
                self.search_paths.insert(0, dir);
            }
            "integrator" => self.integrator(f, node)?,
            "sensor" => self.sensor(f, node)?,
            "emitter" => self.emitter(f, node)?,
            "bsdf" => {
                let id = self.attr(f, node, "id")?;
                let def = self.bsdf(f, node)?;
                match id {
                    Some(id) => {
                        self.bsdfs.insert(id, def);
                    }
                    None => self.warn(f, node, "a top-level BSDF without an id is never used"),
                }
            }
            "texture" => {
                let id = self.attr(f, node, "id")?;
                let tex = self.texture(f, node)?;
                match id {
                    Some(id) => {
                        self.textures.insert(id, tex);
                    }
                    None => self.warn(f, node, "a top-level texture without an id is never used"),
                }
            }
            "shape" => self.shape(f, node)?,
            "medium" => {
                if self.attr(f, node, "id")?.is_none() {
                    self.warn(f, node, "a top-level medium without an id is never used");
                }
                self.medium(f, node)?;
            }
            "phase" | "volume" => self.warn(f, node, "a top-level phase function or volume is never used; ignored"),
            "sampler" => match self.attr(f, node, "id")? {
                // Read as a sensor's would be, kept for the sensor that
                // refers to it.
                Some(id) => {
                    let s = &self.desc.settings;
                    let saved = (s.sampler, s.spp, s.seed);
                    self.sampler(f, node)?;
                    let s = &mut self.desc.settings;
                    let read = (s.sampler, s.spp, s.seed);
                    (s.sampler, s.spp, s.seed) = saved;
                    self.samplers.insert(id, read);
                }
                None => self.warn(f, node, "a top-level sampler without an id is never used; ignored"),
            },
            _ => self.warn(f, node, "unsupported element; ignored"),
        }
        Ok(())
    }

    // ---------------------------------------------------------------
    // Properties

    /// The property children of `node` (those with a `name`).
    fn props<'a, 'i>(node: Node<'a, 'i>) -> Vec<Node<'a, 'i>> {
        node.children()
            .filter(|c| c.is_element() && c.has_attribute("name"))
            .collect()
    }

    fn find<'a, 'i>(props: &[Node<'a, 'i>], name: &str, used: &mut Vec<String>) -> Option<Node<'a, 'i>> {
        used.push(name.to_string());
        props.iter().copied().find(|p| p.attribute("name") == Some(name))
    }

    /// Warns about every property that was not asked for.
    fn unused(&mut self, f: &FileCtx, node: Node, props: &[Node], used: &[String]) {
        for p in props {
            let name = p.attribute("name").unwrap_or("");
            if !used.iter().any(|u| u == name) {
                let msg = format!("parameter \"{name}\" of {} is unsupported; ignored", describe(node));
                self.desc.warnings.push(format!("{}: {msg}", f.loc_of(*p)));
            }
        }
    }

    fn numbers(&mut self, f: &FileCtx, node: Node, text: &str) -> Result<Vec<f32>> {
        text.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| {
                s.parse::<f32>()
                    .map_err(|_| self.err(f, node, format!("\"{s}\" is not a number")))
            })
            .collect()
    }

    fn float(&mut self, f: &FileCtx, props: &[Node], name: &str, used: &mut Vec<String>) -> Result<Option<f32>> {
        let Some(p) = Self::find(props, name, used) else {
            return Ok(None);
        };
        match p.tag_name().name() {
            "float" | "integer" => {
                let v = self.required_attr(f, p, "value")?;
                let n = self.numbers(f, p, &v)?;
                if n.len() != 1 {
                    return Err(self.err(f, p, "expected one number"));
                }
                Ok(Some(n[0]))
            }
            other => Err(self.err(f, p, format!("expected <float>, found <{other}>"))),
        }
    }

    fn integer(&mut self, f: &FileCtx, props: &[Node], name: &str, used: &mut Vec<String>) -> Result<Option<i64>> {
        let Some(p) = Self::find(props, name, used) else {
            return Ok(None);
        };
        match p.tag_name().name() {
            "integer" => {
                let v = self.required_attr(f, p, "value")?;
                v.trim()
                    .parse::<i64>()
                    .map(Some)
                    .map_err(|_| self.err(f, p, format!("\"{v}\" is not an integer")))
            }
            other => Err(self.err(f, p, format!("expected <integer>, found <{other}>"))),
        }
    }

    fn boolean(&mut self, f: &FileCtx, props: &[Node], name: &str, used: &mut Vec<String>) -> Result<Option<bool>> {
        let Some(p) = Self::find(props, name, used) else {
            return Ok(None);
        };
        if p.tag_name().name() != "boolean" {
            return Err(self.err(f, p, format!("expected <boolean>, found <{}>", p.tag_name().name())));
        }
        match self.required_attr(f, p, "value")?.as_str() {
            "true" => Ok(Some(true)),
            "false" => Ok(Some(false)),
            v => Err(self.err(f, p, format!("\"{v}\" is not true or false"))),
        }
    }

    fn string(&mut self, f: &FileCtx, props: &[Node], name: &str, used: &mut Vec<String>) -> Result<Option<String>> {
        let Some(p) = Self::find(props, name, used) else {
            return Ok(None);
        };
        if p.tag_name().name() != "string" {
            return Err(self.err(f, p, format!("expected <string>, found <{}>", p.tag_name().name())));
        }
        self.attr(f, p, "value")
    }

    /// `value="x, y, z"` or `x=".." y=".." z=".."` (missing ones: `default`).
    fn triple(&mut self, f: &FileCtx, node: Node, default: f32) -> Result<Vec3> {
        if let Some(v) = self.attr(f, node, "value")? {
            let n = self.numbers(f, node, &v)?;
            return match n.len() {
                1 => Ok(Vec3::splat(n[0])),
                3 => Ok(Vec3::new(n[0], n[1], n[2])),
                k => Err(self.err(f, node, format!("expected 1 or 3 numbers, found {k}"))),
            };
        }
        let mut out = Vec3::splat(default);
        for (i, axis) in ["x", "y", "z"].iter().enumerate() {
            if let Some(v) = self.attr(f, node, axis)? {
                let n = self.numbers(f, node, &v)?;
                if n.len() != 1 {
                    return Err(self.err(f, node, format!("attribute `{axis}` must be one number")));
                }
                out[i] = n[0];
            }
        }
        Ok(out)
    }

    fn point(&mut self, f: &FileCtx, props: &[Node], name: &str, used: &mut Vec<String>) -> Result<Option<Vec3>> {
        let Some(p) = Self::find(props, name, used) else {
            return Ok(None);
        };
        match p.tag_name().name() {
            "point" | "vector" => Ok(Some(self.triple(f, p, 0.0)?)),
            other => Err(self.err(f, p, format!("expected <point> or <vector>, found <{other}>"))),
        }
    }

    /// An RGB colour from `<rgb>`, `<spectrum>` or `<float>`.
    fn rgb_of(&mut self, f: &FileCtx, p: Node) -> Result<Rgb> {
        match p.tag_name().name() {
            "rgb" => {
                let v = self.required_attr(f, p, "value")?;
                let n = self.numbers(f, p, &v)?;
                match n.len() {
                    1 => Ok(Rgb::splat(n[0])),
                    3 => Ok(Rgb::new(n[0], n[1], n[2])),
                    k => Err(self.err(f, p, format!("expected 3 numbers, found {k}"))),
                }
            }
            "float" => {
                let v = self.required_attr(f, p, "value")?;
                let n = self.numbers(f, p, &v)?;
                if n.len() != 1 {
                    return Err(self.err(f, p, "expected one number"));
                }
                Ok(Rgb::splat(n[0]))
            }
            "spectrum" => {
                if let Some(file) = self.attr(f, p, "filename")? {
                    // Mitsuba's spectrum files: wavelength and value pairs.
                    let path = self.resolve(&file);
                    let text = read_limited(&path, MAX_XML_BYTES)
                        .map_err(|e| self.err(f, p, format!("cannot read spectrum file {}: {e}", path.display())))?;
                    let pairs = crate::color::spectrum::parse_spd(&String::from_utf8_lossy(&text))
                        .map_err(|e| self.err(f, p, format!("spectrum file {}: {e}", path.display())))?;
                    return Ok(self.sampled_spectrum_rgb(f, p, &pairs));
                }
                let v = self.required_attr(f, p, "value")?;
                if !v.contains(':') {
                    let n = self.numbers(f, p, &v)?;
                    if n.len() != 1 {
                        return Err(self.err(f, p, "expected one number or wavelength:value pairs"));
                    }
                    // In an emitter, Mitsuba's RGB variants read a flat
                    // spectrum as that much of illuminant E, whose sRGB
                    // colour is XYZ (1, 1, 1)'s.
                    return Ok(if self.in_emitter {
                        Rgb::new(1.204794, 0.948315, 0.908903) * n[0]
                    } else {
                        Rgb::splat(n[0])
                    });
                }
                let mut pairs = Vec::new();
                for item in v.split(',').map(str::trim).filter(|s| !s.is_empty()) {
                    let (w, x) = item
                        .split_once(':')
                        .ok_or_else(|| self.err(f, p, format!("\"{item}\" is not wavelength:value")))?;
                    let w: f32 = w
                        .trim()
                        .parse()
                        .map_err(|_| self.err(f, p, format!("bad wavelength \"{w}\"")))?;
                    let x: f32 = x
                        .trim()
                        .parse()
                        .map_err(|_| self.err(f, p, format!("bad value \"{x}\"")))?;
                    pairs.push((w, x));
                }
                pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
                if pairs.len() < 2 {
                    return Err(self.err(f, p, "a sampled spectrum needs at least two wavelength:value pairs"));
                }
                Ok(self.sampled_spectrum_rgb(f, p, &pairs))
            }
            other => Err(self.err(f, p, format!("expected a colour, found <{other}>"))),
        }
    }

    /// The RGB of a sampled spectrum given at `p`, as Mitsuba's RGB
    /// variants take it there: an emitter's light, an index or coefficient
    /// (unbounded), or a reflectance (clipped to the gamut, with a
    /// warning).
    fn sampled_spectrum_rgb(&mut self, f: &FileCtx, p: Node, pairs: &[(f32, f32)]) -> Rgb {
        let usage = if self.in_emitter {
            SpectrumUse::Emission
        } else if matches!(
            p.attribute("name"),
            Some("eta" | "k" | "int_ior" | "ext_ior" | "sigma_t" | "sigma_a" | "sigma_s" | "value")
        ) {
            SpectrumUse::Unbounded
        } else {
            SpectrumUse::Bounded
        };
        let (rgb, clamped) = sampled_to_rgb(pairs, usage);
        if clamped {
            self.warn(f, p, format!("the spectrum's colour is out of gamut; clamped to {rgb}"));
        }
        rgb
    }

    /// A colour or a texture (nested or `<ref>`).
    fn color(&mut self, f: &FileCtx, props: &[Node], name: &str, used: &mut Vec<String>) -> Result<Option<ColorProp>> {
        let Some(p) = Self::find(props, name, used) else {
            return Ok(None);
        };
        match p.tag_name().name() {
            "texture" => Ok(Some(ColorProp::Texture(self.texture(f, p)?))),
            "ref" => {
                let id = self.required_attr(f, p, "id")?;
                match self.textures.get(&id) {
                    Some(t) => Ok(Some(ColorProp::Texture(t.clone()))),
                    None => Err(self.err(f, p, format!("no texture with id \"{id}\""))),
                }
            }
            _ => Ok(Some(ColorProp::Constant(self.rgb_of(f, p)?))),
        }
    }

    fn color_source(
        &mut self,
        f: &FileCtx,
        props: &[Node],
        name: &str,
        used: &mut Vec<String>,
    ) -> Result<Option<ColorSource>> {
        Ok(self.color(f, props, name, used)?.map(|c| match c {
            ColorProp::Constant(c) => ColorSource::Rgb(c),
            ColorProp::Texture(t) => t,
        }))
    }

    /// A colour where trazo takes no texture: a texture is replaced by a
    /// constant, with a warning.
    fn constant_color(
        &mut self,
        f: &FileCtx,
        node: Node,
        props: &[Node],
        name: &str,
        used: &mut Vec<String>,
    ) -> Result<Option<Rgb>> {
        match self.color(f, props, name, used)? {
            None => Ok(None),
            Some(ColorProp::Constant(c)) => Ok(Some(c)),
            Some(ColorProp::Texture(_)) => {
                self.warn(
                    f,
                    node,
                    format!("a texture for \"{name}\" is unsupported here; using 1"),
                );
                Ok(Some(Rgb::ONE))
            }
        }
    }

    /// A `<transform name=..>` as one matrix: later steps apply after
    /// earlier ones.
    fn transform(&mut self, f: &FileCtx, props: &[Node], name: &str, used: &mut Vec<String>) -> Result<Option<Mat4>> {
        let Some(p) = Self::find(props, name, used) else {
            return Ok(None);
        };
        if p.tag_name().name() != "transform" {
            return Err(self.err(f, p, format!("expected <transform>, found <{}>", p.tag_name().name())));
        }
        let mut m = Mat4::IDENTITY;
        for step in p.children().filter(Node::is_element) {
            let s = match step.tag_name().name() {
                "translate" => Mat4::from_translation(self.triple(f, step, 0.0)?),
                "scale" => Mat4::from_scale(self.triple(f, step, 1.0)?),
                "rotate" => {
                    let axis = self.triple(f, step, 0.0)?;
                    let angle = self.required_attr(f, step, "angle")?;
                    let angle = self.numbers(f, step, &angle)?;
                    if angle.len() != 1 {
                        return Err(self.err(f, step, "`angle` must be one number"));
                    }
                    let axis = axis
                        .try_normalize()
                        .ok_or_else(|| self.err(f, step, "the rotation axis is zero"))?;
                    Mat4::from_axis_angle(axis, angle[0].to_radians())
                }
                "matrix" => {
                    let v = self.required_attr(f, step, "value")?;
                    let n = self.numbers(f, step, &v)?;
                    match n.len() {
                        // Row by row.
                        16 => Mat4::from_cols_array(&n.try_into().expect("16 numbers")).transpose(),
                        9 => {
                            Mat4::from_mat3(glam::Mat3::from_cols_array(&n.try_into().expect("9 numbers")).transpose())
                        }
                        k => return Err(self.err(f, step, format!("a matrix needs 16 (or 9) numbers, found {k}"))),
                    }
                }
                "lookat" => {
                    let origin = self.vec_attr(f, step, "origin")?;
                    let target = self.vec_attr(f, step, "target")?;
                    let up = match self.attr(f, step, "up")? {
                        Some(_) => self.vec_attr(f, step, "up")?,
                        None => Vec3::Y,
                    };
                    mitsuba_look_at(origin, target, up)
                        .ok_or_else(|| self.err(f, step, "origin, target and up do not define a view"))?
                }
                other => return Err(self.err(f, step, format!("unknown transform step <{other}>"))),
            };
            m = s * m;
        }
        if !m.is_finite() {
            return Err(self.err(f, p, "the transform has NaN or infinite entries"));
        }
        Ok(Some(m))
    }

    fn vec_attr(&mut self, f: &FileCtx, node: Node, name: &str) -> Result<Vec3> {
        let v = self.required_attr(f, node, name)?;
        let n = self.numbers(f, node, &v)?;
        if n.len() != 3 {
            return Err(self.err(f, node, format!("`{name}` needs 3 numbers")));
        }
        Ok(Vec3::new(n[0], n[1], n[2]))
    }

    fn child<'a, 'i>(node: Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
        node.children().find(|c| c.is_element() && c.tag_name().name() == tag)
    }

    // ---------------------------------------------------------------
    // Plugins

    fn integrator(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        self.saw_integrator = true;
        let ty = self.required_attr(f, node, "type")?;
        if ty == "moment" {
            // Mitsuba's moment integrator renders its nested integrator's
            // image and adds the moments as extra channels.
            let nested: Vec<Node> = node
                .children()
                .filter(|c| c.is_element() && c.tag_name().name() == "integrator")
                .collect();
            let [inner] = nested[..] else {
                return Err(self.err(f, node, "a moment integrator needs exactly one nested integrator"));
            };
            self.warn(
                f,
                node,
                "the moment channels are not written; the nested integrator renders the image",
            );
            return self.integrator(f, inner);
        }
        let props = Self::props(node);
        let mut used = Vec::new();
        let s = &mut self.desc.settings;
        s.integrator = IntegratorKind::Path;
        s.sampling = PathSampling::Mis;
        match ty.as_str() {
            "path" | "direct" => {}
            "volpath" | "volpathmis" => s.integrator = IntegratorKind::VolPath,
            "ptracer" => s.integrator = IntegratorKind::Light,
            // Mitsuba 0.6's bidirectional integrators: BDPT itself, and its
            // Metropolis samplers over it.
            "bdpt" => s.integrator = IntegratorKind::Bdpt,
            "pssmlt" => s.integrator = IntegratorKind::Pssmlt,
            "mlt" => {
                // Veach's MLT mutates whole paths of any length, as PSSMLT's
                // chains over whole bidirectional samples move.
                s.integrator = IntegratorKind::Pssmlt;
                self.warn(
                    f,
                    node,
                    "integrator \"mlt\" (Veach's path-space mutations) is rendered by trazo's \"pssmlt\", Metropolis sampling in primary sample space over whole bidirectional samples, which converges to the same image",
                );
            }
            other => self.warn(
                f,
                node,
                format!("integrator \"{other}\" is unsupported: rendered as \"path\""),
            ),
        }
        let max_depth = self.integer(f, &props, "max_depth", &mut used)?;
        let rr_depth = self.integer(f, &props, "rr_depth", &mut used)?;
        if matches!(ty.as_str(), "pssmlt" | "mlt") {
            self.read_metropolis(f, node, &props, &mut used)?;
        }
        let s = &mut self.desc.settings;
        if ty == "direct" {
            s.max_depth = 2;
        } else if let Some(d) = max_depth {
            s.max_depth = if d < 0 {
                MAX_DEPTH
            } else {
                (d as u64).min(MAX_DEPTH as u64) as u32
            };
        }
        if let Some(d) = rr_depth {
            s.rr_depth = d.clamp(0, u32::MAX as i64) as u32;
            if s.integrator.splats_light_paths() && s.integrator != IntegratorKind::Light {
                self.warn(
                    f,
                    node,
                    "\"rr_depth\" is ignored: trazo's bidirectional subpaths end at the depth, without Russian roulette (as pbrt-v4's)",
                );
            }
        }
        if let Some(hide) = self.boolean(f, &props, "hide_emitters", &mut used)? {
            self.desc.settings.hide_emitters = hide;
        }
        if self.integer(f, &props, "samples_per_pass", &mut used)?.is_some() {
            self.warn(
                f,
                node,
                "\"samples_per_pass\" is ignored (each iteration traces one light path per pixel)",
            );
        }
        // The direct integrator's sample counts only change its noise.
        for ignored in ["emitter_samples", "bsdf_samples"] {
            if self.integer(f, &props, ignored, &mut used)?.is_some() {
                self.warn(
                    f,
                    node,
                    format!("\"{ignored}\" is ignored (one light and one BSDF sample per bounce)"),
                );
            }
        }
        self.unused(f, node, &props, &used);
        Ok(())
    }

    /// Mitsuba 0.6's Metropolis parameters, in its spelling or Mitsuba
    /// 3's: `luminanceSamples` (the bootstrap paths) and `pLarge` (the
    /// large-step probability). The others (`bidirectional`, `twoStage`,
    /// `directSamples`, the path-space mutations) are left to the warning
    /// on unused properties: trazo's chains always run over the
    /// bidirectional sampler.
    fn read_metropolis(&mut self, f: &FileCtx, node: Node, props: &[Node], used: &mut Vec<String>) -> Result<()> {
        let at = |name: &str| Self::find(props, name, &mut Vec::new()).unwrap_or(node);
        for name in ["luminanceSamples", "luminance_samples"] {
            if let Some(v) = self.integer(f, props, name, used)? {
                if !(1..=MAX_SPP as i64).contains(&v) {
                    return Err(self.err(f, at(name), format!("must be between 1 and {MAX_SPP}, got {v}")));
                }
                self.desc.settings.mlt.bootstrap = v as u32;
            }
        }
        for name in ["pLarge", "p_large"] {
            if let Some(v) = self.float(f, props, name, used)? {
                if !(0.0..=1.0).contains(&v) {
                    return Err(self.err(f, at(name), format!("must be a probability between 0 and 1, got {v}")));
                }
                self.desc.settings.mlt.large_step_probability = v;
            }
        }
        Ok(())
    }

    fn sensor(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        if self.saw_sensor {
            self.warn(f, node, "only the first sensor is used");
            return Ok(());
        }
        self.saw_sensor = true;
        let ty = self.required_attr(f, node, "type")?;
        // Film and sampler first: the field of view depends on the aspect.
        if let Some(film) = Self::child(node, "film") {
            self.film(f, film)?;
        }
        if let Some(sampler) = Self::child(node, "sampler") {
            self.sampler(f, sampler)?;
        }
        for c in node.children().filter(Node::is_element) {
            if c.tag_name().name() == "ref" && !c.has_attribute("name") {
                let id = self.required_attr(f, c, "id")?;
                match self.samplers.get(&id) {
                    Some(&read) => {
                        let s = &mut self.desc.settings;
                        (s.sampler, s.spp, s.seed) = read;
                    }
                    None if self.ids.contains_key(&id) => self.warn(
                        f,
                        c,
                        format!("a sensor's reference to \"{id}\" is unsupported (only a sampler's is read); ignored"),
                    ),
                    None => return Err(self.err(f, c, format!("no object with id \"{id}\""))),
                }
            } else if !matches!(c.tag_name().name(), "film" | "sampler") && !c.has_attribute("name") {
                self.warn(f, c, "unsupported inside a sensor; ignored");
            }
        }
        let props = Self::props(node);
        let mut used = Vec::new();
        let (w, h) = self.desc.settings.full_size();
        let to_world = self
            .transform(f, &props, "to_world", &mut used)?
            .unwrap_or(Mat4::IDENTITY);
        // Mitsuba's camera x points to the image's left; trazo's to its right.
        let cam = &mut self.desc.camera;
        cam.to_world = Some(to_world * Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)));
        cam.locs = Locs::at(Some(f.loc_of(node)));
        match ty.as_str() {
            "perspective" | "thinlens" => {
                let (fov, fov_axis) = self.field_of_view(f, node, &props, &mut used)?;
                let fov_y = vertical_fov(fov, fov_axis, w, h);
                self.desc.camera.projection = ProjectionDesc::Perspective { fov: fov_y };
                if ty == "thinlens" {
                    let r = self.float(f, &props, "aperture_radius", &mut used)?.unwrap_or(0.0);
                    let d = self.float(f, &props, "focus_distance", &mut used)?.unwrap_or(1.0);
                    self.desc.camera.aperture_radius = r;
                    self.desc.camera.focus_distance = Some(d);
                } else {
                    // A pinhole: Mitsuba's perspective camera ignores it too.
                    let _ = self.float(f, &props, "focus_distance", &mut used)?;
                }
            }
            "orthographic" => {
                // Mitsuba's orthographic view spans [−1, 1] in x; y follows the aspect.
                self.desc.camera.projection = ProjectionDesc::Orthographic {
                    size: 2.0 * h as f32 / w as f32,
                };
            }
            other => {
                self.warn(
                    f,
                    node,
                    format!("sensor \"{other}\" is unsupported: using a perspective camera"),
                );
            }
        }
        if let Some(m) = Self::find(&props, "medium", &mut used) {
            self.desc.camera_medium = Some(self.medium_ref(f, m)?);
        }
        // Mitsuba's defaults: 1e-2 and 1e4.
        let near = self.float(f, &props, "near_clip", &mut used)?.unwrap_or(1e-2);
        let far = self.float(f, &props, "far_clip", &mut used)?.unwrap_or(1e4);
        if !(near >= 0.0 && far > near && near.is_finite()) {
            return Err(self.err(
                f,
                node,
                format!("near_clip ({near}) and far_clip ({far}) must satisfy 0 ≤ near_clip < far_clip"),
            ));
        }
        self.desc.camera.near_clip = near;
        self.desc.camera.far_clip = far;
        for shutter in ["shutter_open", "shutter_close"] {
            if self.float(f, &props, shutter, &mut used)?.is_some() {
                self.warn(f, node, format!("\"{shutter}\" is unsupported (no motion blur)"));
            }
        }
        self.unused(f, node, &props, &used);
        Ok(())
    }

    fn film(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        let ty = self.required_attr(f, node, "type")?;
        if ty != "hdrfilm" {
            self.warn(f, node, format!("film \"{ty}\" is read as \"hdrfilm\""));
        }
        let props = Self::props(node);
        let mut used = Vec::new();
        let mut locs = Locs::at(Some(f.loc_of(node)));
        for (key, dim) in [("width", 0usize), ("height", 1)] {
            if let Some(v) = self.integer(f, &props, key, &mut used)? {
                let p = props.iter().find(|p| p.attribute("name") == Some(key)).expect("found");
                locs.keys.push((key.to_string(), f.loc_of(*p)));
                let v = v.clamp(0, u32::MAX as i64) as u32;
                if dim == 0 {
                    self.desc.settings.width = v;
                } else {
                    self.desc.settings.height = v;
                }
            }
        }
        // The sampler (read before the film where the sensor lists it
        // first) records its keys here too.
        locs.keys.append(&mut self.desc.settings_locs.keys);
        self.desc.settings_locs = locs;
        for key in ["pixel_format", "component_format", "file_format"] {
            let _ = self.string(f, &props, key, &mut used)?;
        }
        // A crop window: the image rendered is that part of the full one.
        let (full_w, full_h) = (self.desc.settings.width, self.desc.settings.height);
        let mut crop = [0i64, 0, full_w as i64, full_h as i64];
        for (k, key) in ["crop_offset_x", "crop_offset_y", "crop_width", "crop_height"]
            .iter()
            .enumerate()
        {
            if let Some(v) = self.integer(f, &props, key, &mut used)? {
                crop[k] = v;
            }
        }
        let [x, y, cw, ch] = crop;
        if x < 0 || y < 0 || cw < 1 || ch < 1 || x + cw > full_w as i64 || y + ch > full_h as i64 {
            return Err(self.err(
                f,
                node,
                format!("the crop window ({x}, {y}) + {cw}×{ch} does not lie within the {full_w}×{full_h} film"),
            ));
        }
        if [x, y, cw, ch] != [0, 0, full_w as i64, full_h as i64] {
            let s = &mut self.desc.settings;
            s.crop = Some(crate::settings::Crop {
                full_width: full_w,
                full_height: full_h,
                x: x as u32,
                y: y as u32,
            });
            (s.width, s.height) = (cw as u32, ch as u32);
        }
        if let Some(b) = self.boolean(f, &props, "sample_border", &mut used)? {
            if b {
                self.warn(f, node, "sample_border is unsupported");
            }
        }
        if let Some(rf) = Self::child(node, "rfilter") {
            let ty = self.required_attr(f, rf, "type")?;
            let rprops = Self::props(rf);
            let mut rused = Vec::new();
            let filter = match ty.as_str() {
                "box" => Filter::Box {
                    radius: self.float(f, &rprops, "radius", &mut rused)?.unwrap_or(0.5),
                },
                "tent" => Filter::Tent {
                    radius: self.float(f, &rprops, "radius", &mut rused)?.unwrap_or(1.0),
                },
                "gaussian" => {
                    let sd = self.float(f, &rprops, "stddev", &mut rused)?.unwrap_or(0.5);
                    Filter::Gaussian {
                        stddev: sd,
                        radius: 4.0 * sd,
                    }
                }
                // Mitsuba's cubics are supported on [−2, 2] pixels.
                "mitchell" => Filter::Mitchell {
                    radius: 2.0,
                    b: self.float(f, &rprops, "B", &mut rused)?.unwrap_or(1.0 / 3.0),
                    c: self.float(f, &rprops, "C", &mut rused)?.unwrap_or(1.0 / 3.0),
                },
                "catmullrom" => Filter::from_name("catmullrom").expect("known"),
                // Its radius is its number of lobes.
                "lanczos" => {
                    let lobes = self.integer(f, &rprops, "lobes", &mut rused)?.unwrap_or(3);
                    if !(1..=7).contains(&lobes) {
                        return Err(self.err(f, rf, format!("lanczos \"lobes\" must be between 1 and 7, got {lobes}")));
                    }
                    Filter::Lanczos {
                        radius: lobes as f32,
                        tau: lobes as f32,
                    }
                }
                other => {
                    self.warn(
                        f,
                        rf,
                        format!("filter \"{other}\" is approximated by a Gaussian of σ = 0.5"),
                    );
                    Filter::from_name("gaussian").expect("known")
                }
            };
            self.unused(f, rf, &rprops, &rused);
            self.desc.settings.filter = filter;
        }
        self.unused(f, node, &props, &used);
        Ok(())
    }

    fn sampler(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        let ty = self.required_attr(f, node, "type")?;
        self.desc.settings.sampler = match ty.as_str() {
            "independent" => SamplerKind::Independent,
            "stratified" => SamplerKind::Stratified,
            // Mitsuba's ldsampler pads randomised (0,2)-sequences per
            // dimension pair (Kollig and Keller 2002), as trazo's Sobol
            // sampler does.
            "ldsampler" | "sobol" => SamplerKind::Sobol,
            other => {
                self.warn(
                    f,
                    node,
                    format!("sampler \"{other}\" is approximated by stratified sampling"),
                );
                SamplerKind::Stratified
            }
        };
        let props = Self::props(node);
        let mut used = Vec::new();
        if let Some(n) = self.integer(f, &props, "sample_count", &mut used)? {
            let p = props
                .iter()
                .find(|p| p.attribute("name") == Some("sample_count"))
                .expect("found");
            if !(1..=MAX_SPP as i64).contains(&n) {
                return Err(self.err(
                    f,
                    *p,
                    format!("`sample_count` must be between 1 and {MAX_SPP}, got {n}"),
                ));
            }
            self.desc.settings_locs.keys.push(("spp".into(), f.loc_of(*p)));
            self.desc.settings.spp = n as u32;
        }
        if let Some(seed) = self.integer(f, &props, "seed", &mut used)? {
            self.desc.settings.seed = seed.max(0) as u64;
        }
        // The stratified samplers' jitter inside strata (Mitsuba's default:
        // on); false puts samples at the strata's centres.
        if let Some(jitter) = self.boolean(f, &props, "jitter", &mut used)? {
            self.desc.settings.jitter = jitter;
        }
        for ignored in ["scramble_seed", "dimension"] {
            let _ = Self::find(&props, ignored, &mut used);
        }
        self.unused(f, node, &props, &used);
        Ok(())
    }

    /// A perspective sensor's (or projector's) `fov` and `fov_axis`, or
    /// without `fov` its `focal_length`.
    fn field_of_view(
        &mut self,
        f: &FileCtx,
        node: Node,
        props: &[Node],
        used: &mut Vec<String>,
    ) -> Result<(f32, FovAxis)> {
        let name = self.string(f, props, "fov_axis", used)?.unwrap_or_else(|| "x".into());
        let axis =
            FovAxis::from_name(&name).ok_or_else(|| self.err(f, node, format!("unknown fov_axis \"{name}\"")))?;
        Ok(match self.float(f, props, "fov", used)? {
            Some(v) => (v, axis),
            None => {
                // As Mitsuba: a focal length (default 50 mm) on a 36 × 24 mm
                // film, measured along its diagonal whatever fov_axis says
                // (34.02° across a square film at 50 mm).
                let focal = self
                    .string(f, props, "focal_length", used)?
                    .unwrap_or_else(|| "50mm".into());
                let mm: f32 = focal
                    .trim_end_matches("mm")
                    .trim()
                    .parse()
                    .map_err(|_| self.err(f, node, format!("bad focal_length \"{focal}\"")))?;
                (
                    (2.0 * (36.0f32.hypot(24.0) / (2.0 * mm)).atan()).to_degrees(),
                    FovAxis::Diagonal,
                )
            }
        })
    }

    fn emitter(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        self.in_emitter = true;
        let result = self.emitter_properties(f, node);
        self.in_emitter = false;
        result
    }

    /// An area emitter's radiance (1 by default), read as emission.
    fn area_radiance(&mut self, f: &FileCtx, node: Node) -> Result<ColorSource> {
        let props = Self::props(node);
        let mut used = Vec::new();
        let was = std::mem::replace(&mut self.in_emitter, true);
        let radiance = self.color_source(f, &props, "radiance", &mut used);
        self.in_emitter = was;
        let radiance = radiance?.unwrap_or(ColorSource::Rgb(Rgb::ONE));
        self.unused(f, node, &props, &used);
        Ok(radiance)
    }

    fn emitter_properties(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        let ty = self.required_attr(f, node, "type")?;
        let props = Self::props(node);
        let mut used = Vec::new();
        let to_world = self
            .transform(f, &props, "to_world", &mut used)?
            .unwrap_or(Mat4::IDENTITY);
        let locs = Locs::at(Some(f.loc_of(node)));
        match ty.as_str() {
            "point" => {
                let position = match self.point(f, &props, "position", &mut used)? {
                    Some(p) => to_world.transform_point3(p),
                    None => to_world.transform_point3(Vec3::ZERO),
                };
                let intensity = self
                    .constant_color(f, node, &props, "intensity", &mut used)?
                    .unwrap_or(Rgb::ONE);
                self.desc.lights.push(LightDesc {
                    kind: LightKind::Point {
                        position,
                        intensity,
                        falloff: true,
                    },
                    locs,
                });
            }
            "spot" => {
                let position = to_world.transform_point3(Vec3::ZERO);
                let dir = to_world.transform_vector3(Vec3::Z);
                let intensity = self
                    .constant_color(f, node, &props, "intensity", &mut used)?
                    .unwrap_or(Rgb::ONE);
                let cutoff = self.float(f, &props, "cutoff_angle", &mut used)?.unwrap_or(20.0);
                let beam = self.float(f, &props, "beam_width", &mut used)?.unwrap_or(cutoff * 0.75);
                let projection = match self.color_source(f, &props, "texture", &mut used)? {
                    None => None,
                    Some(ColorSource::Texture(texture)) => Some(SpotProjectionDesc {
                        texture,
                        to_world: glam::Mat3::from_mat4(to_world),
                    }),
                    Some(ColorSource::Rgb(_)) => {
                        return Err(self.err(
                            f,
                            node,
                            "the spot light's \"texture\" must vary over the image (a bitmap, say), as in Mitsuba",
                        ));
                    }
                };
                self.desc.lights.push(LightDesc {
                    kind: LightKind::Spot {
                        position,
                        to: position + dir,
                        intensity,
                        inner_angle: beam.min(cutoff),
                        outer_angle: cutoff,
                        profile: SpotProfile::LinearInAngle,
                        projection,
                        falloff: true,
                    },
                    locs,
                });
            }
            "projector" => {
                let (fov, fov_axis) = self.field_of_view(f, node, &props, &mut used)?;
                let irradiance = self
                    .color_source(f, &props, "irradiance", &mut used)?
                    .ok_or_else(|| self.err(f, node, "a projector needs an \"irradiance\" (a colour or a texture)"))?;
                let scale = self.float(f, &props, "scale", &mut used)?.unwrap_or(1.0);
                self.desc.lights.push(LightDesc {
                    kind: LightKind::Projector {
                        position: to_world.transform_point3(Vec3::ZERO),
                        to_world: glam::Mat3::from_mat4(to_world),
                        fov,
                        fov_axis,
                        irradiance,
                        scale,
                        law: crate::light::ProjectorLaw::PlaneIrradiance,
                        power: None,
                    },
                    locs,
                });
            }
            "directional" => {
                let direction = match self.point(f, &props, "direction", &mut used)? {
                    Some(d) => d,
                    None => to_world.transform_vector3(Vec3::Z),
                };
                let irradiance = self
                    .constant_color(f, node, &props, "irradiance", &mut used)?
                    .unwrap_or(Rgb::ONE);
                self.desc.lights.push(LightDesc {
                    kind: LightKind::Directional { direction, irradiance },
                    locs,
                });
            }
            "constant" => {
                let radiance = self
                    .constant_color(f, node, &props, "radiance", &mut used)?
                    .unwrap_or(Rgb::ONE);
                self.set_background(f, node, BackgroundDesc::Constant(radiance));
            }
            "envmap" => {
                let file = self
                    .string(f, &props, "filename", &mut used)?
                    .ok_or_else(|| self.err(f, node, "an envmap needs a \"filename\""))?;
                let scale = self.float(f, &props, "scale", &mut used)?.unwrap_or(1.0);
                let path = self.resolve(&file);
                if !path.is_file() {
                    return Err(self.err(f, node, format!("environment image not found: {}", path.display())));
                }
                let _ = self.string(f, &props, "filter_type", &mut used)?;
                self.set_background(
                    f,
                    node,
                    BackgroundDesc::Image {
                        path,
                        scale,
                        transform: vec![TransformOp::Matrix(to_world)],
                        layout: EnvironmentLayout::LatLong,
                        illuminance: None,
                    },
                );
            }
            "area" => match self.attr(f, node, "id")? {
                // Defined here, placed by the shapes that refer to it.
                Some(id) => {
                    let radiance = self.area_radiance(f, node)?;
                    self.area_emitters.insert(id, (radiance, f.loc_of(node)));
                    return Ok(());
                }
                None => self.warn(f, node, "an area emitter must be attached to a shape; ignored"),
            },
            other => self.warn(f, node, format!("emitter \"{other}\" is unsupported; ignored")),
        }
        self.unused(f, node, &props, &used);
        Ok(())
    }

    fn set_background(&mut self, f: &FileCtx, node: Node, bg: BackgroundDesc) {
        if !matches!(self.desc.background, BackgroundDesc::Constant(c) if c == Rgb::ZERO) {
            self.warn(
                f,
                node,
                "only one environment emitter is supported; this one replaces the earlier",
            );
        }
        self.desc.background = bg;
        self.desc.world_locs = Locs::at(Some(f.loc_of(node)));
    }

    /// Parses a `<texture>` into a desc texture, returning its reference.
    fn texture(&mut self, f: &FileCtx, node: Node) -> Result<ColorSource> {
        let ty = self.required_attr(f, node, "type")?;
        let props = Self::props(node);
        let mut used = Vec::new();
        let to_uv = self.transform(f, &props, "to_uv", &mut used)?.unwrap_or(Mat4::IDENTITY);
        // Mitsuba maps (u, v) by the transform's 2D part: the upper-left
        // 2 × 2 block and the translation.
        let scale = Vec2::new(to_uv.x_axis.x, to_uv.y_axis.y);
        let offset = Vec2::new(to_uv.w_axis.x, to_uv.w_axis.y);
        let turned = to_uv.x_axis.y != 0.0 || to_uv.y_axis.x != 0.0;
        let affine = |k: f32| crate::texture::Mapping2D::UvAffine {
            u_axis: k * to_uv.x_axis.truncate().truncate(),
            v_axis: k * to_uv.y_axis.truncate().truncate(),
            offset: k * offset,
        };
        if turned && !matches!(ty.as_str(), "bitmap" | "checkerboard") {
            self.warn(
                f,
                node,
                format!("a rotated or sheared to_uv on a \"{ty}\" texture is unsupported; only its scale and offset are used"),
            );
        }
        let kind = match ty.as_str() {
            "bitmap" => {
                let file = self
                    .string(f, &props, "filename", &mut used)?
                    .ok_or_else(|| self.err(f, node, "a bitmap needs a \"filename\""))?;
                let path = self.resolve(&file);
                if !path.is_file() {
                    return Err(self.err(f, node, format!("image not found: {}", path.display())));
                }
                let raw = self.boolean(f, &props, "raw", &mut used)?.unwrap_or(false);
                let wrap = match self.string(f, &props, "wrap_mode", &mut used)?.as_deref() {
                    None | Some("repeat") => WrapMode::Repeat,
                    Some("mirror") => WrapMode::Mirror,
                    Some("clamp") => WrapMode::Clamp,
                    Some(other) => {
                        return Err(self.err(
                            f,
                            node,
                            format!("unknown wrap_mode \"{other}\" (repeat, mirror or clamp)"),
                        ));
                    }
                };
                let filter = match self.string(f, &props, "filter_type", &mut used)?.as_deref() {
                    None | Some("bilinear") => ImageFilter::Bilinear,
                    Some("nearest") => ImageFilter::Nearest,
                    Some(other) => {
                        return Err(self.err(
                            f,
                            node,
                            format!("unknown filter_type \"{other}\" (bilinear or nearest)"),
                        ));
                    }
                };
                // Mitsuba looks images up with v = 0 at the top row, trazo
                // at the bottom: flip v after Mitsuba's to_uv.
                let image = |scale: Vec2, offset: Vec2| TextureKind::Image {
                    // `raw` images hold numbers, which no colour space converts.
                    source: if raw {
                        ImageSource::DataFile(path.clone())
                    } else {
                        ImageSource::File(path.clone())
                    },
                    scale: Vec2::new(scale.x, -scale.y),
                    offset: Vec2::new(offset.x, 1.0 - offset.y),
                    encoding: raw.then_some(Encoding::Linear),
                    tint: Rgb::ONE,
                    wrap: [wrap; 2],
                    filter,
                };
                if turned {
                    // The image read at the turned (u, v): a mapped node.
                    let name = self.fresh_name("mitsuba-texture");
                    self.desc.textures.push(TextureDesc {
                        name: name.clone(),
                        kind: image(Vec2::ONE, Vec2::ZERO),
                        locs: Locs::at(Some(f.loc_of(node))),
                    });
                    TextureKind::Node(crate::texture::TextureNode::Mapped {
                        tex: ColorSource::Texture(name),
                        mapping: affine(1.0),
                    })
                } else {
                    image(scale, offset)
                }
            }
            "checkerboard" => {
                let c0 = self
                    .color_source(f, &props, "color0", &mut used)?
                    .unwrap_or(ColorSource::Rgb(Rgb::splat(0.4)));
                let c1 = self
                    .color_source(f, &props, "color1", &mut used)?
                    .unwrap_or(ColorSource::Rgb(Rgb::splat(0.2)));
                // Mitsuba's checks are half a unit of its transformed
                // (u, v) wide; color0 is where both fractions are below ½
                // (as a colour; see `float_texture`).
                match (&c0, &c1) {
                    (ColorSource::Rgb(even), ColorSource::Rgb(odd)) if offset == Vec2::ZERO && !turned => {
                        TextureKind::Checkerboard {
                            even: *even,
                            odd: *odd,
                            scale: 2.0 * scale,
                        }
                    }
                    // Nested textures or a to_uv offset: the node, which
                    // takes both.
                    _ => TextureKind::Node(crate::texture::TextureNode::Checkerboard {
                        even: c0,
                        odd: c1,
                        mapping: if turned {
                            affine(2.0)
                        } else {
                            crate::texture::Mapping2D::Uv {
                                scale: 2.0 * scale,
                                offset: 2.0 * offset,
                            }
                        },
                    }),
                }
            }
            "mesh_attribute" => {
                let name = self.string(f, &props, "name", &mut used)?.ok_or_else(|| {
                    self.err(
                        f,
                        node,
                        "a mesh_attribute texture needs a \"name\" (vertex_… or face_…)",
                    )
                })?;
                if !(name.starts_with("vertex_") || name.starts_with("face_")) {
                    return Err(self.err(
                        f,
                        node,
                        format!("mesh attribute \"{name}\": Mitsuba's names start with vertex_ or face_"),
                    ));
                }
                if let Some(s) = self.float(f, &props, "scale", &mut used)?.filter(|&s| s != 1.0) {
                    self.warn(
                        f,
                        node,
                        format!("a mesh_attribute's scale ({s}) is unsupported; ignored"),
                    );
                }
                TextureKind::MeshAttribute { name }
            }
            other => {
                self.warn(f, node, format!("texture \"{other}\" is unsupported: using grey 0.5"));
                TextureKind::Constant(Rgb::splat(0.5))
            }
        };
        self.unused(f, node, &props, &used);
        let name = self.fresh_name("mitsuba-texture");
        self.desc.textures.push(TextureDesc {
            name: name.clone(),
            kind,
            locs: Locs::at(Some(f.loc_of(node))),
        });
        Ok(ColorSource::Texture(name))
    }

    /// `src` as Mitsuba reads a texture where it wants a float
    /// (`Texture::eval_1`). Its checkerboard's `eval_1` puts color0 on the
    /// other checks than its `eval` does (`neq` against `eq` of the two
    /// halves, Mitsuba 3.9's checkerboard.cpp), and its render tests are
    /// rendered so: a checkerboard read as a float has its colours swapped.
    fn float_texture(&mut self, src: ColorSource) -> ColorSource {
        let ColorSource::Texture(name) = &src else {
            return src;
        };
        let Some(t) = self.desc.textures.iter().find(|t| &t.name == name) else {
            return src;
        };
        let kind = match &t.kind {
            TextureKind::Checkerboard { even, odd, scale } => TextureKind::Checkerboard {
                even: *odd,
                odd: *even,
                scale: *scale,
            },
            TextureKind::Node(crate::texture::TextureNode::Checkerboard { even, odd, mapping }) => {
                TextureKind::Node(crate::texture::TextureNode::Checkerboard {
                    even: odd.clone(),
                    odd: even.clone(),
                    mapping: *mapping,
                })
            }
            _ => return src,
        };
        let locs = t.locs.clone();
        let swapped = TextureDesc {
            name: self.fresh_name("mitsuba-texture"),
            kind,
            locs,
        };
        let name = swapped.name.clone();
        self.desc.textures.push(swapped);
        ColorSource::Texture(name)
    }

    /// A rough BSDF's microfacet distribution and its α along u and v
    /// (Mitsuba's default: Beckmann, α = 0.1); where `alpha`, `alpha_u` or
    /// `alpha_v` is a texture, the textures too (the constants are then
    /// replaced at build time).
    fn alpha(
        &mut self,
        f: &FileCtx,
        node: Node,
        props: &[Node],
        used: &mut Vec<String>,
    ) -> Result<(MicrofacetDistribution, f32, f32, Option<RoughnessMapDesc>)> {
        let distribution = match self.string(f, props, "distribution", used)? {
            Some(d) => MicrofacetDistribution::from_name(&d).ok_or_else(|| {
                self.err(
                    f,
                    node,
                    format!("unknown distribution \"{d}\": expected \"beckmann\" or \"ggx\""),
                )
            })?,
            None => MicrofacetDistribution::Beckmann,
        };
        // Mitsuba draws all microfacet normals instead of the visible ones
        // when this is false: the same image, with more noise.
        let _ = self.boolean(f, props, "sample_visible", used)?;
        let a = self.color_source(f, props, "alpha", used)?;
        let au = self.color_source(f, props, "alpha_u", used)?;
        let av = self.color_source(f, props, "alpha_v", used)?;
        let (u, v) = match (a, au, av) {
            (_, Some(u), Some(v)) => (self.float_texture(u), self.float_texture(v)),
            (Some(a), _, _) => {
                let a = self.float_texture(a);
                (a.clone(), a)
            }
            _ => (ColorSource::Rgb(Rgb::splat(0.1)), ColorSource::Rgb(Rgb::splat(0.1))),
        };
        Ok(match (u, v) {
            (ColorSource::Rgb(u), ColorSource::Rgb(v)) => (distribution, u.x, v.x, None),
            (u, v) => (
                distribution,
                0.1,
                0.1,
                Some(RoughnessMapDesc {
                    u,
                    v,
                    remap_sqrt: false,
                }),
            ),
        })
    }

    fn ior(
        &mut self,
        f: &FileCtx,
        node: Node,
        props: &[Node],
        name: &str,
        default: f32,
        used: &mut Vec<String>,
    ) -> Result<f32> {
        let Some(p) = Self::find(props, name, used) else {
            return Ok(default);
        };
        match p.tag_name().name() {
            "float" => {
                let v = self.required_attr(f, p, "value")?;
                let n = self.numbers(f, p, &v)?;
                n.first().copied().ok_or_else(|| self.err(f, p, "expected a number"))
            }
            "string" => {
                let v = self.required_attr(f, p, "value")?;
                named_ior(&v).ok_or_else(|| self.err(f, p, format!("unknown index of refraction \"{v}\"")))
            }
            other => Err(self.err(
                f,
                node,
                format!("\"{name}\" must be a <float> or <string>, found <{other}>"),
            )),
        }
    }

    /// Parses a `<bsdf>` (or a `<ref>` to one).
    fn bsdf(&mut self, f: &FileCtx, node: Node) -> Result<BsdfDef> {
        if node.tag_name().name() == "ref" {
            let id = self.required_attr(f, node, "id")?;
            return self
                .bsdfs
                .get(&id)
                .cloned()
                .ok_or_else(|| self.err(f, node, format!("no BSDF with id \"{id}\"")));
        }
        let ty = self.required_attr(f, node, "type")?;
        let props = Self::props(node);
        let mut used = Vec::new();
        let nested = || {
            node.children()
                .find(|c| c.is_element() && matches!(c.tag_name().name(), "bsdf" | "ref") && !c.has_attribute("name"))
        };
        let loc = f.loc_of(node);
        let mut roughness_map = None;
        let kind = match ty.as_str() {
            "twosided" => {
                let inner: Vec<Node> = node
                    .children()
                    .filter(|c| {
                        c.is_element() && matches!(c.tag_name().name(), "bsdf" | "ref") && !c.has_attribute("name")
                    })
                    .collect();
                match inner.as_slice() {
                    [one] => {
                        let mut def = self.bsdf(f, *one)?;
                        def.two_sided = true;
                        def.material = None;
                        def.loc = loc;
                        return Ok(def);
                    }
                    // The front's BSDF and the back's, each seeing its side
                    // as its front, as Mitsuba flips the directions for
                    // the back's.
                    [front, back] => {
                        let [mut front, mut back] = [self.bsdf(f, *front)?, self.bsdf(f, *back)?];
                        for def in [&mut front, &mut back] {
                            def.two_sided = true;
                            def.material = None;
                        }
                        let materials = [
                            self.material_for(Some((front, None)), None),
                            self.material_for(Some((back, None)), None),
                        ];
                        MaterialKindDesc::Mix {
                            choice: MixChoice::Side,
                            materials,
                        }
                    }
                    _ => {
                        return Err(self.err(
                            f,
                            node,
                            format!("twosided takes one or two nested BSDFs, not {}", inner.len()),
                        ));
                    }
                }
            }
            "principled" | "principledthin" => {
                let thin = ty == "principledthin";
                let base_color = self
                    .color_source(f, &props, "base_color", &mut used)?
                    .unwrap_or(ColorSource::Rgb(Rgb::splat(0.5)));
                // The rest are floats (`eval_1`), 0 by default but roughness;
                // the thin form has no metal or clearcoat.
                let mut float = |me: &mut Self, name: &str, default: f32| -> Result<ColorSource> {
                    let takes = !(thin && matches!(name, "metallic" | "clearcoat" | "clearcoat_gloss"))
                        && (thin || name != "diff_trans");
                    if !takes {
                        return Ok(ColorSource::Rgb(Rgb::splat(default)));
                    }
                    Ok(match me.color_source(f, &props, name, &mut used)? {
                        Some(c) => me.float_texture(c),
                        None => ColorSource::Rgb(Rgb::splat(default)),
                    })
                };
                let params = crate::material::principled::PrincipledParams {
                    base_color,
                    roughness: float(self, "roughness", 0.5)?,
                    anisotropic: float(self, "anisotropic", 0.0)?,
                    metallic: float(self, "metallic", 0.0)?,
                    spec_trans: float(self, "spec_trans", 0.0)?,
                    spec_tint: float(self, "spec_tint", 0.0)?,
                    sheen: float(self, "sheen", 0.0)?,
                    sheen_tint: float(self, "sheen_tint", 0.0)?,
                    flatness: float(self, "flatness", 0.0)?,
                    clearcoat: float(self, "clearcoat", 0.0)?,
                    clearcoat_gloss: float(self, "clearcoat_gloss", 0.0)?,
                    diff_trans: float(self, "diff_trans", 0.0)?,
                };
                // Mitsuba's sampling rates change the noise, not the image.
                let rates: &[&str] = if thin {
                    &[
                        "specular_reflectance_sampling_rate",
                        "specular_transmittance_sampling_rate",
                        "diffuse_transmittance_sampling_rate",
                        "diffuse_reflectance_sampling_rate",
                    ]
                } else {
                    &[
                        "main_specular_sampling_rate",
                        "clearcoat_sampling_rate",
                        "diffuse_reflectance_sampling_rate",
                    ]
                };
                for rate in rates {
                    self.float(f, &props, rate, &mut used)?;
                }
                let eta = if thin {
                    match self.color_source(f, &props, "eta", &mut used)? {
                        None => 1.5,
                        Some(ColorSource::Rgb(c)) => c.x,
                        Some(ColorSource::Texture(_)) => {
                            self.warn(
                                f,
                                node,
                                "a textured \"eta\" is unsupported: Mitsuba's default 1.5 is used",
                            );
                            1.5
                        }
                    }
                } else {
                    // A present spec_trans (unless the number 0) turns the
                    // transmission on, and with it Mitsuba's guards on η.
                    let transmits = !matches!(params.spec_trans, ColorSource::Rgb(c) if c == Rgb::ZERO);
                    match (
                        self.float(f, &props, "eta", &mut used)?,
                        self.float(f, &props, "specular", &mut used)?,
                    ) {
                        (Some(_), Some(_)) => {
                            return Err(self.err(f, node, "principled takes \"eta\" or \"specular\", not both"));
                        }
                        (Some(eta), None) if transmits && eta == 1.0 => 1.001,
                        (Some(eta), None) => eta,
                        (None, specular) => {
                            let specular = specular.unwrap_or(0.5);
                            let specular = if transmits && specular == 0.0 { 1e-3 } else { specular };
                            if !(0.0..12.5).contains(&specular) {
                                return Err(self.err(
                                    f,
                                    node,
                                    format!("principled \"specular\" must lie in [0, 12.5), got {specular}"),
                                ));
                            }
                            crate::material::principled::eta_from_specular(specular)
                        }
                    }
                };
                MaterialKindDesc::Principled {
                    params: Box::new(params),
                    eta,
                    thin,
                }
            }
            "diffuse" => MaterialKindDesc::Diffuse {
                reflectance: self
                    .color_source(f, &props, "reflectance", &mut used)?
                    .unwrap_or(ColorSource::Rgb(Rgb::splat(0.5))),
            },
            "conductor" | "roughconductor" => {
                let (distribution, roughness) = if ty == "roughconductor" {
                    let (d, a, b, map) = self.alpha(f, node, &props, &mut used)?;
                    roughness_map = map;
                    (d, (a, b))
                } else {
                    (MicrofacetDistribution::Ggx, (0.0, 0.0))
                };
                let material = self.string(f, &props, "material", &mut used)?;
                let eta = self.constant_color(f, node, &props, "eta", &mut used)?;
                let k = self.constant_color(f, node, &props, "k", &mut used)?;
                let tint = self
                    .constant_color(f, node, &props, "specular_reflectance", &mut used)?
                    .unwrap_or(Rgb::ONE);
                let fresnel = match (eta, k, material.as_deref()) {
                    (Some(eta), Some(k), _) => ConductorDesc::Complex { eta, k },
                    (Some(_), None, _) | (None, Some(_), _) => {
                        return Err(self.err(f, node, "give both \"eta\" and \"k\""));
                    }
                    (None, None, None) | (None, None, Some("none")) => ConductorDesc::Mirror(Rgb::ONE),
                    (None, None, Some(m)) => {
                        // Mitsuba's own RGB projections of its spectra.
                        match crate::material::conductor::metal_ior(m) {
                            Some((eta, k)) => ConductorDesc::Complex { eta, k },
                            None => {
                                self.warn(
                                    f,
                                    node,
                                    format!("material \"{m}\" is unknown to trazo: using a perfect mirror"),
                                );
                                ConductorDesc::Mirror(Rgb::ONE)
                            }
                        }
                    }
                };
                MaterialKindDesc::Conductor {
                    fresnel,
                    tint,
                    roughness,
                    distribution,
                }
            }
            "null" => {
                let def = BsdfDef {
                    opacity: None,
                    normal_map: None,
                    bump_map: None,
                    roughness_map: None,
                    kind: MaterialKindDesc::NULL,
                    two_sided: true,
                    material: None,
                    loc,
                };
                self.unused(f, node, &props, &used);
                return Ok(def);
            }
            "dielectric" | "roughdielectric" | "thindielectric" => {
                let (distribution, roughness) = if ty == "roughdielectric" {
                    let (d, a, b, map) = self.alpha(f, node, &props, &mut used)?;
                    roughness_map = map;
                    (d, (a, b))
                } else {
                    (MicrofacetDistribution::Ggx, (0.0, 0.0))
                };
                let ior = self.ior(f, node, &props, "int_ior", 1.5046, &mut used)?;
                let ext_ior = self.ior(f, node, &props, "ext_ior", 1.000277, &mut used)?;
                let reflect_tint = self
                    .constant_color(f, node, &props, "specular_reflectance", &mut used)?
                    .unwrap_or(Rgb::ONE);
                let transmit_tint = self
                    .constant_color(f, node, &props, "specular_transmittance", &mut used)?
                    .unwrap_or(Rgb::ONE);
                if ty == "thindielectric" {
                    self.unused(f, node, &props, &used);
                    return Ok(BsdfDef {
                        opacity: None,
                        normal_map: None,
                        bump_map: None,
                        roughness_map: None,
                        kind: MaterialKindDesc::Thin {
                            ior,
                            ext_ior,
                            reflect_tint,
                            transmit_tint,
                            dispersion: None,
                        },
                        two_sided: true,
                        material: None,
                        loc,
                    });
                }
                MaterialKindDesc::Dielectric {
                    dispersion: None,
                    ior,
                    ext_ior,
                    roughness,
                    distribution,
                    reflect_tint,
                    transmit_tint,
                }
            }
            "plastic" | "roughplastic" => {
                let (distribution, roughness) = if ty == "roughplastic" {
                    let (d, a, _, map) = self.alpha(f, node, &props, &mut used)?;
                    if map.is_some() {
                        self.warn(
                            f,
                            node,
                            "a roughness texture on a rough plastic is unsupported: its coat has α = 0.1",
                        );
                    }
                    (d, a)
                } else {
                    (MicrofacetDistribution::Ggx, 0.0)
                };
                MaterialKindDesc::Plastic {
                    diffuse: self
                        .color_source(f, &props, "diffuse_reflectance", &mut used)?
                        .unwrap_or(ColorSource::Rgb(Rgb::splat(0.5))),
                    ior: self.ior(f, node, &props, "int_ior", 1.49, &mut used)?,
                    ext_ior: self.ior(f, node, &props, "ext_ior", 1.000277, &mut used)?,
                    roughness,
                    distribution,
                    specular_tint: self
                        .constant_color(f, node, &props, "specular_reflectance", &mut used)?
                        .unwrap_or(Rgb::ONE),
                    nonlinear: self.boolean(f, &props, "nonlinear", &mut used)?.unwrap_or(false),
                }
            }
            "mask" => {
                let inner = nested().ok_or_else(|| self.err(f, node, "mask needs a nested BSDF"))?;
                // Mitsuba reads the opacity as a float (`eval_1`).
                let opacity = match self.color_source(f, &props, "opacity", &mut used)? {
                    Some(o) => self.float_texture(o),
                    None => ColorSource::Rgb(Rgb::splat(0.5)),
                };
                self.unused(f, node, &props, &used);
                let def = self.bsdf(f, inner)?;
                return Ok(BsdfDef {
                    loc,
                    opacity: Some(opacity),
                    material: None,
                    ..def
                });
            }
            "bumpmap" => {
                // Mitsuba takes the nested texture and BSDF by their kinds,
                // whatever their names.
                let is_texture = |c: &Node| {
                    c.tag_name().name() == "texture"
                        || (c.tag_name().name() == "ref"
                            && c.attribute("id").is_some_and(|id| self.textures.contains_key(id)))
                };
                let inner = node
                    .children()
                    .find(|c| c.is_element() && matches!(c.tag_name().name(), "bsdf" | "ref") && !is_texture(c))
                    .ok_or_else(|| self.err(f, node, "bumpmap needs a nested BSDF"))?;
                let tex_node = node.children().find(|c| c.is_element() && is_texture(c));
                let Some(tex_node) = tex_node else {
                    return Err(self.err(f, node, "bumpmap needs a nested texture of heights"));
                };
                if let Some(name) = tex_node.attribute("name") {
                    used.push(name.to_string());
                }
                let height = match tex_node.tag_name().name() {
                    "texture" => self.texture(f, tex_node)?,
                    _ => self.textures[tex_node.attribute("id").unwrap_or_default()].clone(),
                };
                let scale = self.float(f, &props, "scale", &mut used)?.unwrap_or(1.0);
                self.unused(f, node, &props, &used);
                let def = self.bsdf(f, inner)?;
                if def.normal_map.is_some() || def.bump_map.is_some() {
                    self.warn(
                        f,
                        node,
                        "a bumpmap over a normalmap or another bumpmap is unsupported: only the outer one is applied",
                    );
                }
                return Ok(BsdfDef {
                    loc,
                    normal_map: None,
                    bump_map: Some(BumpMapDesc { height, scale }),
                    material: None,
                    ..def
                });
            }
            "normalmap" => {
                let inner = nested().ok_or_else(|| self.err(f, node, "normalmap needs a nested BSDF"))?;
                let map = self
                    .color_source(f, &props, "normalmap", &mut used)?
                    .ok_or_else(|| self.err(f, node, "normalmap needs a texture named \"normalmap\""))?;
                self.unused(f, node, &props, &used);
                let def = self.bsdf(f, inner)?;
                if def.normal_map.is_some() || def.bump_map.is_some() {
                    self.warn(
                        f,
                        node,
                        "a normalmap over a bumpmap or another normalmap is unsupported: only the outer one is applied",
                    );
                }
                return Ok(BsdfDef {
                    loc,
                    normal_map: Some(map),
                    bump_map: None,
                    material: None,
                    ..def
                });
            }
            "measured" => {
                let file = self
                    .string(f, &props, "filename", &mut used)?
                    .ok_or_else(|| self.err(f, node, "a measured BSDF needs a \"filename\" (an RGL .bsdf file)"))?;
                let path = self.resolve(&file);
                if !path.is_file() {
                    return Err(self.err(f, node, format!("measured BSDF file not found: {}", path.display())));
                }
                MaterialKindDesc::Measured { file: path }
            }
            "blendbsdf" => {
                // Mitsuba reads the weight as a float (`eval_1`).
                let weight = match self.color_source(f, &props, "weight", &mut used)? {
                    Some(w) => self.float_texture(w),
                    None => ColorSource::Rgb(Rgb::splat(0.5)),
                };
                let inner: Vec<Node> = node
                    .children()
                    .filter(|c| {
                        c.is_element() && matches!(c.tag_name().name(), "bsdf" | "ref") && !c.has_attribute("name")
                    })
                    .collect();
                let [first, second] = inner.as_slice() else {
                    return Err(self.err(
                        f,
                        node,
                        format!("blendbsdf blends two nested BSDFs, not {}", inner.len()),
                    ));
                };
                let (first, second) = (self.bsdf(f, *first)?, self.bsdf(f, *second)?);
                let materials = [
                    self.material_for(Some((first, None)), None),
                    self.material_for(Some((second, None)), None),
                ];
                MaterialKindDesc::Mix {
                    choice: MixChoice::Weight(weight),
                    materials,
                }
            }
            other => {
                self.warn(
                    f,
                    node,
                    format!("BSDF \"{other}\" is unsupported: using a grey diffuse one"),
                );
                for p in &props {
                    used.push(p.attribute("name").unwrap_or("").to_string());
                }
                MaterialKindDesc::Diffuse {
                    reflectance: ColorSource::Rgb(Rgb::splat(0.5)),
                }
            }
        };
        self.unused(f, node, &props, &used);
        // Mitsuba's BSDFs are one-sided, but for its thin sheet and
        // `twosided`.
        let two_sided = matches!(
            kind,
            MaterialKindDesc::Principled { thin: true, .. }
                | MaterialKindDesc::Mix {
                    choice: MixChoice::Side,
                    ..
                }
        );
        Ok(BsdfDef {
            opacity: None,
            normal_map: None,
            bump_map: None,
            roughness_map,
            kind,
            two_sided,
            material: None,
            loc,
        })
    }

    /// A `<medium>` or a `<ref>` to one: the name of its description.
    fn medium_ref(&mut self, f: &FileCtx, node: Node) -> Result<String> {
        if node.tag_name().name() == "ref" {
            let id = self.required_attr(f, node, "id")?;
            return self
                .media
                .get(&id)
                .cloned()
                .ok_or_else(|| self.err(f, node, format!("no medium with id \"{id}\"")));
        }
        if node.tag_name().name() != "medium" {
            return Err(self.err(
                f,
                node,
                format!("expected <medium>, found <{}>", node.tag_name().name()),
            ));
        }
        self.medium(f, node)
    }

    /// A `<medium type="homogeneous|heterogeneous">`, added to the
    /// description; returns its name.
    fn medium(&mut self, f: &FileCtx, node: Node) -> Result<String> {
        let ty = self.required_attr(f, node, "type")?;
        let id = self.attr(f, node, "id")?;
        if !matches!(ty.as_str(), "homogeneous" | "heterogeneous") {
            return Err(self.err(
                f,
                node,
                format!("medium \"{ty}\" is unsupported (trazo reads \"homogeneous\" and \"heterogeneous\")"),
            ));
        }
        let props = Self::props(node);
        let mut used = Vec::new();
        let bounded = ty == "heterogeneous";
        let sigma_t = self.medium_field(f, &props, "sigma_t", bounded, &mut used)?;
        let albedo = self.medium_field(f, &props, "albedo", bounded, &mut used)?;
        let scale = self.float(f, &props, "scale", &mut used)?.unwrap_or(1.0);
        if self.boolean(f, &props, "sample_emitters", &mut used)? == Some(false) {
            self.warn(
                f,
                node,
                "\"sample_emitters\" = false is unsupported: lights are sampled in the medium",
            );
        }
        // Mitsuba's RGB variants treat every medium as chromatic; trazo
        // finds out from the values.
        self.boolean(f, &props, "has_spectral_extinction", &mut used)?;
        let mut g = 0.0;
        for c in node
            .children()
            .filter(|c| c.is_element() && c.tag_name().name() == "phase")
        {
            let pty = self.required_attr(f, c, "type")?;
            let pprops = Self::props(c);
            let mut pused = Vec::new();
            match pty.as_str() {
                "isotropic" => {}
                "hg" => {
                    g = self.float(f, &pprops, "g", &mut pused)?.unwrap_or(0.8);
                    if !(g > -1.0 && g < 1.0) {
                        return Err(self.err(f, c, format!("g must lie strictly between -1 and 1, not {g}")));
                    }
                }
                other => self.warn(
                    f,
                    c,
                    format!("phase function \"{other}\" is unsupported: using an isotropic one"),
                ),
            }
            self.unused(f, c, &pprops, &pused);
        }
        for c in node.children().filter(|c| c.is_element() && !c.has_attribute("name")) {
            if c.tag_name().name() != "phase" {
                self.warn(f, c, "unsupported inside a medium; ignored");
            }
        }
        self.unused(f, node, &props, &used);
        let name = match &id {
            Some(id) => format!("medium:{id}"),
            None => self.fresh_name("medium"),
        };
        let mut locs = Locs::at(Some(f.loc_of(node)));
        for key in ["sigma_t", "albedo", "scale", "g"] {
            if let Some(p) = props.iter().find(|p| p.attribute("name") == Some(key)) {
                locs.keys.push((key.into(), f.loc_of(*p)));
            }
        }
        self.desc.media.push(MediumDesc {
            name: name.clone(),
            sigma_t: sigma_t.unwrap_or(FieldDesc::Constant(Rgb::ONE)),
            albedo: albedo.unwrap_or(FieldDesc::Constant(Rgb::splat(0.75))),
            emission: None,
            scale: Rgb::splat(scale),
            g,
            locs,
        });
        if let Some(id) = id {
            self.media.insert(id, name.clone());
        }
        Ok(name)
    }

    /// A medium's property: a colour, or a `<volume>` (`constvolume`,
    /// `gridvolume`). A homogeneous medium (`bounded` false) takes only
    /// constants, as Mitsuba's does.
    fn medium_field(
        &mut self,
        f: &FileCtx,
        props: &[Node],
        name: &str,
        bounded: bool,
        used: &mut Vec<String>,
    ) -> Result<Option<FieldDesc>> {
        let Some(p) = props.iter().copied().find(|p| p.attribute("name") == Some(name)) else {
            used.push(name.to_string());
            return Ok(None);
        };
        used.push(name.to_string());
        if p.tag_name().name() != "volume" {
            return Ok(Some(FieldDesc::Constant(self.rgb_of(f, p)?)));
        }
        let vty = self.required_attr(f, p, "type")?;
        let vprops = Self::props(p);
        let mut vused = Vec::new();
        let to_world = self.transform(f, &vprops, "to_world", &mut vused)?;
        let to_world: Vec<TransformOp> = to_world.map(TransformOp::Matrix).into_iter().collect();
        let field = match vty.as_str() {
            "constvolume" => {
                let value = match vprops.iter().copied().find(|v| v.attribute("name") == Some("value")) {
                    Some(v) => self.rgb_of(f, v)?,
                    None => Rgb::ONE,
                };
                vused.push("value".into());
                if bounded {
                    FieldDesc::Boxed { value, to_world }
                } else {
                    FieldDesc::Constant(value)
                }
            }
            "gridvolume" => {
                if !bounded {
                    return Err(self.err(
                        f,
                        p,
                        "a homogeneous medium takes constant values; use a \"heterogeneous\" medium for a grid",
                    ));
                }
                let file = self
                    .string(f, &vprops, "filename", &mut vused)?
                    .ok_or_else(|| self.err(f, p, "a gridvolume needs a \"filename\""))?;
                let use_file_bounds = self.boolean(f, &vprops, "use_grid_bbox", &mut vused)?.unwrap_or(false);
                if let Some(filter) = self.string(f, &vprops, "filter_type", &mut vused)? {
                    if filter != "trilinear" {
                        self.warn(
                            f,
                            p,
                            format!("filter_type \"{filter}\" is unsupported: the grid is read trilinearly"),
                        );
                    }
                }
                if let Some(wrap) = self.string(f, &vprops, "wrap_mode", &mut vused)? {
                    if wrap != "clamp" {
                        self.warn(
                            f,
                            p,
                            format!("wrap_mode \"{wrap}\" is unsupported: the grid is clamped"),
                        );
                    }
                }
                self.boolean(f, &vprops, "raw", &mut vused)?;
                FieldDesc::Grid {
                    source: GridSource::MitsubaVol(self.resolve(&file)),
                    to_world,
                    use_file_bounds,
                }
            }
            other => {
                return Err(self.err(
                    f,
                    p,
                    format!("volume \"{other}\" is unsupported (trazo reads \"constvolume\" and \"gridvolume\")"),
                ));
            }
        };
        self.unused(f, p, &vprops, &vused);
        Ok(Some(field))
    }

    /// The name of a desc material for a BSDF (made on first use) and an
    /// optional emission.
    fn material_for(
        &mut self,
        def: Option<(BsdfDef, Option<String>)>,
        emission: Option<(ColorSource, SourceLoc)>,
    ) -> String {
        let (def, id) = match def {
            Some(d) => d,
            None => {
                // Mitsuba's default: a one-sided diffuse BSDF of albedo 0.5.
                (
                    BsdfDef {
                        opacity: None,
                        normal_map: None,
                        bump_map: None,
                        roughness_map: None,
                        kind: MaterialKindDesc::Diffuse {
                            reflectance: ColorSource::Rgb(Rgb::splat(0.5)),
                        },
                        two_sided: false,
                        material: None,
                        loc: SourceLoc {
                            file: Arc::from(Path::new("<mitsuba default>")),
                            line: 0,
                            column: 0,
                        },
                    },
                    Some("\u{0}default".to_string()),
                )
            }
        };
        if emission.is_none() {
            if let Some(id) = &id {
                if id == "\u{0}default" {
                    if let Some(m) = &self.default_material {
                        return m.clone();
                    }
                } else if let Some(m) = self.bsdfs.get(id).and_then(|b| b.material.clone()) {
                    return m;
                }
            }
        }
        let name = self.fresh_name(if emission.is_some() {
            "mitsuba-emitter"
        } else {
            "mitsuba-bsdf"
        });
        let mut m = MaterialDesc::with_kind(name.clone(), def.kind.clone());
        m.two_sided = def.two_sided;
        m.opacity = def.opacity.clone();
        m.normal_map = def.normal_map.clone().map(NormalMapDesc::new);
        m.bump_map = def.bump_map.clone();
        m.roughness_map = def.roughness_map.clone();
        m.locs = Locs::at(if def.loc.line > 0 { Some(def.loc.clone()) } else { None });
        if let Some((e, loc)) = emission {
            m.emission = e;
            m.locs.keys.push(("emission".into(), loc));
        }
        self.desc.materials.push(m);
        // Only a plain (non-emitting) material stands for its BSDF's id.
        if let (Some(id), true) = (id, self.desc.materials.last().is_some_and(|m| !emitting(m))) {
            if id == "\u{0}default" {
                if self.default_material.is_none() {
                    self.default_material = Some(name.clone());
                }
            } else if let Some(b) = self.bsdfs.get_mut(&id) {
                if b.material.is_none() {
                    b.material = Some(name.clone());
                }
            }
        }
        name
    }

    fn shape(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        match self.required_attr(f, node, "type")?.as_str() {
            "shapegroup" => self.shapegroup(f, node),
            "instance" => self.instance(f, node),
            _ => {
                let shapes = self.shape_descs(f, node, false)?;
                self.desc.shapes.extend(shapes);
                Ok(())
            }
        }
    }

    /// A `<shape type="shapegroup">`: its shapes are read (materials made,
    /// meshes named) but placed only by instances.
    fn shapegroup(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        let id = self.attr(f, node, "id")?;
        if let Some(id) = &id {
            let earlier = match (self.groups.get(id), self.bsdfs.get(id)) {
                (Some(g), _) => Some(format!("the shapegroup at {}", g.loc)),
                (None, Some(b)) => Some(format!("the BSDF at {}", b.loc)),
                (None, None) => self.textures.contains_key(id).then(|| "a texture".to_string()),
            };
            if let Some(earlier) = earlier {
                return Err(self.err(f, node, format!("duplicate id \"{id}\": {earlier} has it")));
            }
        }
        // Mitsuba reads a group's own to_world and never applies it.
        let props: Vec<Node> = Self::props(node)
            .into_iter()
            .filter(|p| p.tag_name().name() != "shape")
            .collect();
        let mut used = Vec::new();
        if self.transform(f, &props, "to_world", &mut used)?.is_some() {
            self.warn(
                f,
                node,
                "a shapegroup's to_world is ignored (as by Mitsuba); transform its shapes or its instances",
            );
        }
        let mut shapes = Vec::new();
        for c in node.children().filter(Node::is_element) {
            let tag = c.tag_name().name();
            if tag == "shape" {
                match self.required_attr(f, c, "type")?.as_str() {
                    "shapegroup" => {
                        return Err(self.err(
                            f,
                            c,
                            "a shapegroup cannot hold another shapegroup (Mitsuba: \"Nested ShapeGroup is not permitted\")",
                        ));
                    }
                    "instance" => {
                        return Err(self.err(
                            f,
                            c,
                            "a shapegroup cannot hold an instance (Mitsuba: \"Nested instancing is not permitted\")",
                        ));
                    }
                    _ => shapes.extend(self.shape_descs(f, c, true)?),
                }
            } else if !PROPERTY_TAGS.contains(&tag) {
                return Err(self.err(
                    f,
                    c,
                    format!("a shapegroup holds only shapes, not <{tag}> (Mitsuba rejects it too); give the BSDF to each shape"),
                ));
            }
        }
        self.unused(f, node, &props, &used);
        if shapes.is_empty() {
            self.warn(f, node, "the shapegroup holds no shapes");
        }
        match id {
            Some(id) => {
                self.groups.insert(
                    id,
                    GroupDef {
                        loc: f.loc_of(node),
                        shapes,
                        placed: false,
                    },
                );
            }
            None => self.warn(
                f,
                node,
                "a shapegroup without an id cannot be placed by an instance; nothing of it is rendered",
            ),
        }
        Ok(())
    }

    /// A `<shape type="instance">`: a `<ref>` to a shapegroup and a
    /// `to_world`, placed by `place_instances` once the whole file is read.
    fn instance(&mut self, f: &FileCtx, node: Node) -> Result<()> {
        let mut group: Option<(String, SourceLoc)> = None;
        for c in node.children().filter(Node::is_element) {
            let tag = c.tag_name().name();
            if tag == "ref" {
                if group.is_some() {
                    return Err(self.err(
                        f,
                        c,
                        "an instance places one shapegroup (Mitsuba: \"Only a single shapegroup can be specified per instance\")",
                    ));
                }
                group = Some((self.required_attr(f, c, "id")?, f.loc_of(c)));
            } else if tag == "shape" && c.attribute("type") == Some("shapegroup") {
                return Err(self.err(
                    f,
                    c,
                    "a shapegroup cannot be written inside an instance (nor in Mitsuba); give it an id and place it with <ref id=\"..\"/>",
                ));
            } else if !PROPERTY_TAGS.contains(&tag) {
                return Err(self.err(
                    f,
                    c,
                    format!(
                        "an instance takes a <ref> to a shapegroup and a to_world, not <{tag}> (Mitsuba: \"Only a shapegroup can be specified in an instance\"); the group's shapes keep their own BSDFs"
                    ),
                ));
            }
        }
        let Some((id, ref_loc)) = group else {
            return Err(self.err(f, node, "an instance needs a <ref id=\"..\"/> to a shapegroup"));
        };
        let props: Vec<Node> = Self::props(node)
            .into_iter()
            .filter(|p| p.tag_name().name() != "ref")
            .collect();
        let mut used = Vec::new();
        let to_world = self
            .transform(f, &props, "to_world", &mut used)?
            .unwrap_or(Mat4::IDENTITY);
        if let Err(e) = TransformOp::Matrix(to_world).to_transform() {
            return Err(self.err(f, node, format!("to_world: {e}")));
        }
        self.unused(f, node, &props, &used);
        self.instances.push(InstanceUse {
            id,
            ref_loc,
            loc: f.loc_of(node),
            to_world,
            position: self.desc.shapes.len(),
        });
        Ok(())
    }

    /// Places every instance's group, in the order the instances were read,
    /// and keeps the group meshes that are placed.
    fn place_instances(&mut self) -> Result<()> {
        let uses = std::mem::take(&mut self.instances);
        let read = std::mem::take(&mut self.desc.shapes);
        let mut shapes = Vec::with_capacity(read.len());
        let mut read = read.into_iter();
        let mut taken = 0;
        for u in uses {
            let Some(group) = self.groups.get_mut(&u.id) else {
                let id = &u.id;
                let hint = if self.bsdfs.contains_key(id) {
                    " (a BSDF has that id; an instance places a shapegroup)".to_string()
                } else if self.textures.contains_key(id) {
                    " (a texture has that id; an instance places a shapegroup)".to_string()
                } else {
                    suggest(id, self.groups.keys().map(String::as_str))
                };
                return Err(Error::Scene {
                    loc: Some(u.ref_loc),
                    key: None,
                    message: format!("<ref>: no shapegroup with id \"{id}\"{hint}"),
                });
            };
            group.placed = true;
            shapes.extend(read.by_ref().take(u.position - taken));
            taken = u.position;
            for s in &group.shapes {
                // The instance's to_world after the shape's own: Mitsuba
                // carries rays into the group's space, where each shape
                // lies by its own to_world.
                let mut s = s.clone();
                if u.to_world != Mat4::IDENTITY {
                    s.transform.push(TransformOp::Matrix(u.to_world));
                    if !s.locs.keys.iter().any(|(k, _)| k == "transform") {
                        s.locs.keys.push(("transform".into(), u.loc.clone()));
                    }
                }
                shapes.push(s);
            }
        }
        shapes.extend(read);
        self.desc.shapes = shapes;

        let mut unplaced: Vec<(&String, &GroupDef)> = self.groups.iter().filter(|(_, g)| !g.placed).collect();
        unplaced.sort_by_key(|(_, g)| (g.loc.file.clone(), g.loc.line, g.loc.column));
        for (id, g) in unplaced {
            self.desc.warnings.push(format!(
                "{}: shapegroup \"{id}\" is never placed by an instance; nothing of it is rendered",
                g.loc
            ));
        }
        let placed: HashSet<&str> = self
            .desc
            .shapes
            .iter()
            .filter_map(|s| match &s.kind {
                ShapeKind::Mesh(name) => Some(name.as_str()),
                _ => None,
            })
            .collect();
        let meshes: Vec<MeshDesc> = std::mem::take(&mut self.group_meshes)
            .into_iter()
            .filter(|m| placed.contains(m.name.as_str()))
            .collect();
        self.desc.meshes.extend(meshes);
        Ok(())
    }

    /// The shapes one `<shape>` element makes (a cube makes six
    /// rectangles; an unsupported shape none). In a group (`in_group`), a
    /// mesh is named rather than inline, one name per file, and an emitter
    /// is an error, as in Mitsuba.
    fn shape_descs(&mut self, f: &FileCtx, node: Node, in_group: bool) -> Result<Vec<ShapeDesc>> {
        let ty = self.required_attr(f, node, "type")?;
        if in_group {
            for c in node.children().filter(Node::is_element) {
                let what = match c.tag_name().name() {
                    "emitter" => "emitters",
                    "sensor" => "sensors",
                    _ => continue,
                };
                return Err(self.err(
                    f,
                    c,
                    format!(
                        "{what} cannot be instanced: Mitsuba rejects a shape with one in a shapegroup (\"Instancing of {what} is not supported\"); place that shape on its own, outside the group"
                    ),
                ));
            }
        }
        let props = Self::props(node);
        let mut used = Vec::new();
        let to_world = self.transform(f, &props, "to_world", &mut used)?;
        let flip_normals = self.boolean(f, &props, "flip_normals", &mut used)?.unwrap_or(false);
        let mut locs = Locs::at(Some(f.loc_of(node)));
        // A rotation of a sphere about its centre that aligns trazo's
        // surface coordinates with Mitsuba's.
        let mut sphere_uv = None;

        let kind = match ty.as_str() {
            "sphere" => {
                let center = self.point(f, &props, "center", &mut used)?.unwrap_or(Vec3::ZERO);
                // Mitsuba's (u, v) are longitude around its object space's
                // +z from +x towards +y, and latitude from +z (v = 0) to −z;
                // trazo's run around +y from +x towards +z, v = 0 at −y.
                // Mitsuba's space seen from trazo's: x stays, trazo's y is
                // Mitsuba's −z, trazo's z Mitsuba's y.
                let mitsuba_from_trazo = Mat4::from_mat3(glam::Mat3::from_cols(Vec3::X, -Vec3::Z, Vec3::Y));
                sphere_uv = Some(Mat4::from_translation(center) * mitsuba_from_trazo * Mat4::from_translation(-center));
                let radius = self.float(f, &props, "radius", &mut used)?.unwrap_or(1.0);
                if let Some(p) = props.iter().find(|p| p.attribute("name") == Some("radius")) {
                    locs.keys.push(("radius".into(), f.loc_of(*p)));
                }
                ShapeKind::Sphere { center, radius }
            }
            "rectangle" => ShapeKind::Rectangle {
                corner: Vec3::new(-1.0, -1.0, 0.0),
                edge_u: Vec3::new(2.0, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 2.0, 0.0),
            },
            "disk" => ShapeKind::Disk {
                center: Vec3::ZERO,
                normal: Vec3::Z,
                radius: 1.0,
                uv: crate::geometry::DiskUv::RadiusAngle,
            },
            // Mitsuba's cube is a triangle mesh whose faces each map onto
            // [0,1]² in (u, v); reproduce it so that textures line up.
            "cube" => ShapeKind::InlineMesh(MeshSource::Inline(mitsuba_cube())),
            "cylinder" => {
                let p0 = self.point(f, &props, "p0", &mut used)?.unwrap_or(Vec3::ZERO);
                let p1 = self.point(f, &props, "p1", &mut used)?.unwrap_or(Vec3::Z);
                let radius = self.float(f, &props, "radius", &mut used)?.unwrap_or(1.0);
                ShapeKind::Cylinder { p0, p1, radius }
            }
            "sdfgrid" => {
                let file = self
                    .string(f, &props, "filename", &mut used)?
                    .ok_or_else(|| self.err(f, node, "an sdfgrid needs a \"filename\" (a .vol grid of one channel)"))?;
                let path = self.resolve(&file);
                let smooth = match self.string(f, &props, "normals", &mut used)?.as_deref() {
                    None | Some("smooth") => true,
                    Some("analytic") => false,
                    Some(other) => {
                        return Err(self.err(
                            f,
                            node,
                            format!(
                                "normals \"{other}\" is unknown: Mitsuba's sdfgrid takes \"smooth\" or \"analytic\""
                            ),
                        ));
                    }
                };
                let grid = crate::media::grid::VoxelGrid::load_mitsuba_vol(&path)
                    .map_err(|e| self.err(f, node, e.to_string()))?;
                if grid.channels != 1 {
                    return Err(self.err(
                        f,
                        node,
                        format!(
                            "{}: an sdfgrid's grid has one channel, not {}",
                            path.display(),
                            grid.channels
                        ),
                    ));
                }
                let sdf = crate::geometry::sdf_grid::SdfGrid::new(grid.res, grid.data, smooth)
                    .map_err(|e| self.err(f, node, format!("{}: {e}", path.display())))?;
                ShapeKind::SdfGrid(Arc::new(sdf))
            }
            "obj" | "ply" | "serialized" => {
                let file = self
                    .string(f, &props, "filename", &mut used)?
                    .ok_or_else(|| self.err(f, node, "a mesh needs a \"filename\""))?;
                let path = self.resolve(&file);
                if !path.is_file() {
                    return Err(self.err(f, node, format!("mesh file not found: {}", path.display())));
                }
                let face_normals = self.boolean(f, &props, "face_normals", &mut used)?.unwrap_or(false);
                let flip_tex = self
                    .boolean(f, &props, "flip_tex_coords", &mut used)?
                    .unwrap_or(ty == "obj");
                if ty != "obj" && flip_tex {
                    self.warn(
                        f,
                        node,
                        format!("flip_tex_coords is unsupported for {ty} files; ignored"),
                    );
                }
                let shape_index = match self.integer(f, &props, "shape_index", &mut used)? {
                    Some(i) if ty != "serialized" => {
                        self.warn(
                            f,
                            node,
                            format!("shape_index {i} applies to serialized files only; ignored"),
                        );
                        0
                    }
                    Some(i) => u32::try_from(i).map_err(|_| {
                        self.err(
                            f,
                            node,
                            format!("shape_index {i} is out of range: it counts meshes from 0"),
                        )
                    })?,
                    None => 0,
                };
                // A file that groups use again is read once and named.
                let key = in_group.then(|| {
                    let canonical = path.canonicalize().unwrap_or_else(|_| path.clone());
                    (
                        ty.clone(),
                        canonical,
                        shape_index,
                        face_normals,
                        flip_tex && ty == "obj",
                    )
                });
                match key.as_ref().and_then(|k| self.group_mesh_names.get(k)) {
                    Some(name) => ShapeKind::Mesh(name.clone()),
                    None => {
                        let mesh = self.mesh_file(f, node, &ty, &path, shape_index, face_normals, flip_tex)?;
                        let source = MeshSource::Inline(mesh);
                        match key {
                            Some(key) => {
                                let name = self.group_mesh(f, node, source);
                                self.group_mesh_names.insert(key, name.clone());
                                ShapeKind::Mesh(name)
                            }
                            None => ShapeKind::InlineMesh(source),
                        }
                    }
                }
            }
            other => {
                self.warn(f, node, format!("shape \"{other}\" is unsupported; ignored"));
                return Ok(Vec::new());
            }
        };

        // The BSDF: nested, by reference, or Mitsuba's default.
        let mut bsdf: Option<(BsdfDef, Option<String>)> = None;
        let mut emission: Option<(ColorSource, SourceLoc)> = None;
        let mut media: Option<MediumInterfaceDesc> = None;
        for c in node.children().filter(Node::is_element) {
            match c.tag_name().name() {
                "bsdf" => {
                    if bsdf.is_some() {
                        self.warn(f, c, "a shape has one BSDF; this one is ignored");
                        continue;
                    }
                    let def = self.bsdf(f, c)?;
                    bsdf = Some((def, None));
                }
                "ref" if !c.has_attribute("name") || c.attribute("name") == Some("bsdf") => {
                    let id = self.required_attr(f, c, "id")?;
                    if let (None, Some(e)) = (c.attribute("name"), self.area_emitters.get(&id)) {
                        emission = Some(e.clone());
                        continue;
                    }
                    let def = self
                        .bsdfs
                        .get(&id)
                        .cloned()
                        .ok_or_else(|| self.err(f, c, format!("no BSDF with id \"{id}\"")))?;
                    bsdf = Some((def, Some(id)));
                }
                "emitter" => {
                    let ety = self.required_attr(f, c, "type")?;
                    if ety != "area" {
                        self.warn(
                            f,
                            c,
                            format!("a shape can only carry an \"area\" emitter, not \"{ety}\"; ignored"),
                        );
                        continue;
                    }
                    emission = Some((self.area_radiance(f, c)?, f.loc_of(c)));
                }
                "transform" | "float" | "integer" | "boolean" | "string" | "point" | "vector" | "rgb" | "spectrum" => {}
                "medium" | "ref" => {
                    let side = c.attribute("name").unwrap_or("");
                    if !matches!(side, "interior" | "exterior") {
                        self.warn(f, c, "a shape's medium is its \"interior\" or \"exterior\"; ignored");
                        continue;
                    }
                    used.push(side.to_string());
                    let name = self.medium_ref(f, c)?;
                    let mi = media.get_or_insert_with(MediumInterfaceDesc::default);
                    if side == "interior" {
                        mi.inside = Some(name);
                    } else {
                        mi.outside = Some(name);
                    }
                }
                _ => self.warn(f, c, "unsupported inside a shape; ignored"),
            }
        }
        // A cube's faces stay parallelograms under the affine maps a shape's
        // transform may be. As six rectangles they are six primitives
        // instead of twelve triangles, each met by the rectangle test
        // (cheaper than the watertight triangle test), in half as many
        // blocks of the tree's leaves (commit 69b9d1a). An emitting cube
        // stays one mesh, one light sampled by area.
        let cube_faces = ty == "cube" && emission.is_none();
        let material = self.material_for(bsdf, emission);
        self.unused(f, node, &props, &used);
        let mut shape = ShapeDesc::new(kind, Some(&material));
        shape.flip_normals = flip_normals;
        shape.media = media;
        if let Some(m) = sphere_uv {
            shape.transform.push(TransformOp::Matrix(m));
        }
        if let Some(m) = to_world {
            shape.transform.push(TransformOp::Matrix(m));
            locs.keys.push(("transform".into(), f.loc_of(node)));
        }
        shape.locs = locs;
        if cube_faces {
            return Ok(mitsuba_cube_faces()
                .into_iter()
                .map(|[corner, edge_u, edge_v]| {
                    let mut face = shape.clone();
                    face.kind = ShapeKind::Rectangle { corner, edge_u, edge_v };
                    // The faces' (u, v) run clockwise seen from outside, so
                    // edge_u × edge_v, a rectangle's front, points in.
                    face.flip_normals = !flip_normals;
                    face
                })
                .collect());
        }
        if in_group {
            if let ShapeKind::InlineMesh(source) = &shape.kind {
                let name = self.group_mesh(f, node, source.clone());
                shape.kind = ShapeKind::Mesh(name);
            }
        }
        Ok(vec![shape])
    }

    /// The triangles of an `obj`, `ply` or `serialized` shape's file, as
    /// Mitsuba loads them: with `face_normals` the file's normals are
    /// dropped (the mesh is faceted), and a mesh without normals gets
    /// smooth ones otherwise; an OBJ's v is flipped unless
    /// `flip_tex_coords` is false.
    #[allow(clippy::too_many_arguments)]
    fn mesh_file(
        &mut self,
        f: &FileCtx,
        node: Node,
        ty: &str,
        path: &Path,
        shape_index: u32,
        face_normals: bool,
        flip_tex: bool,
    ) -> Result<TriangleMesh> {
        let (mut mesh, file_face_normals) = match ty {
            "obj" => {
                let mut mesh = super::obj::load_obj_mesh(path).map_err(|e| self.err(f, node, e.to_string()))?;
                if flip_tex {
                    for uv in &mut mesh.uvs {
                        uv.y = 1.0 - uv.y;
                    }
                }
                (mesh, false)
            }
            "ply" => {
                let ply = super::ply::read_ply(path).map_err(|e| self.err(f, node, e.to_string()))?;
                self.desc.warnings.extend(ply.warnings);
                (ply.mesh, false)
            }
            _ => {
                let s = super::serialized::read_serialized(path, shape_index)
                    .map_err(|e| self.err(f, node, e.to_string()))?;
                (s.mesh, s.face_normals)
            }
        };
        if face_normals || file_face_normals {
            mesh.normals.clear();
        } else if mesh.normals.is_empty() {
            mesh.compute_vertex_normals();
        }
        Ok(mesh)
    }

    /// Names a mesh of a group; `finish` keeps it if a placed shape uses it.
    fn group_mesh(&mut self, f: &FileCtx, node: Node, source: MeshSource) -> String {
        let name = self.fresh_name("mitsuba-mesh");
        self.group_meshes.push(MeshDesc {
            name: name.clone(),
            source,
            locs: Locs::at(Some(f.loc_of(node))),
        });
        name
    }
}

/// Mitsuba's `cube` shape ([−1, 1]³) face by face: four corners each, in
/// the order whose (u, v) are (0,1), (1,1), (1,0), (0,0).
const CUBE_FACES: [[[f32; 3]; 4]; 6] = [
    [
        [1.0, -1.0, -1.0],
        [1.0, -1.0, 1.0],
        [-1.0, -1.0, 1.0],
        [-1.0, -1.0, -1.0],
    ],
    [[1.0, 1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, 1.0, 1.0], [1.0, 1.0, 1.0]],
    [[1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [1.0, 1.0, 1.0], [1.0, -1.0, 1.0]],
    [[1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0], [-1.0, -1.0, 1.0]],
    [
        [-1.0, -1.0, 1.0],
        [-1.0, 1.0, 1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, -1.0],
    ],
    [
        [1.0, 1.0, -1.0],
        [1.0, -1.0, -1.0],
        [-1.0, -1.0, -1.0],
        [-1.0, 1.0, -1.0],
    ],
];

/// The 24 vertices and 12 triangles of Mitsuba's `cube` shape,
/// counter-clockwise outside, each face's (u, v) spanning [0, 1]².
fn mitsuba_cube() -> crate::geometry::TriangleMesh {
    let corners_uv = [
        Vec2::new(0.0, 1.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(0.0, 0.0),
    ];
    let mut m = crate::geometry::TriangleMesh::default();
    for (f, face) in CUBE_FACES.iter().enumerate() {
        let base = 4 * f as u32;
        for (corner, uv) in face.iter().zip(corners_uv) {
            m.positions.push(Vec3::from_array(*corner));
            m.uvs.push(uv);
        }
        // Triangles (0,1,2) and (3,0,2): counter-clockwise outside.
        m.indices.push([base, base + 1, base + 2]);
        m.indices.push([base + 3, base, base + 2]);
    }
    m
}

/// Mitsuba's cube as six parallelograms `[corner, edge_u, edge_v]` with
/// the mesh's (u, v): the corner at (0, 0), the edges to (1, 0) and (0, 1).
/// Each edge_u × edge_v points into the cube.
fn mitsuba_cube_faces() -> [[Vec3; 3]; 6] {
    CUBE_FACES.map(|[uv01, _, uv10, uv00]| {
        let corner = Vec3::from_array(uv00);
        [corner, Vec3::from_array(uv10) - corner, Vec3::from_array(uv01) - corner]
    })
}

fn emitting(m: &MaterialDesc) -> bool {
    m.emission != ColorSource::Rgb(Rgb::ZERO)
}

/// "<shape type=\"sphere\">" and the like, for messages.
fn describe(node: Node) -> String {
    let tag = node.tag_name().name();
    match (node.attribute("type"), node.attribute("name")) {
        (Some(t), _) => format!("<{tag} type=\"{t}\">"),
        (None, Some(n)) => format!("<{tag} name=\"{n}\">"),
        _ => format!("<{tag}>"),
    }
}

/// Mitsuba's look-at matrix: columns (left, up, forward, origin) with
/// left = up × forward.
pub fn mitsuba_look_at(origin: Vec3, target: Vec3, up: Vec3) -> Option<Mat4> {
    let dir = (target - origin).try_normalize()?;
    let left = up.normalize_or_zero().cross(dir).try_normalize()?;
    let new_up = dir.cross(left);
    Some(Mat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        origin.extend(1.0),
    ))
}

/// The vertical field of view of a camera whose `fov` is measured along
/// `axis`, for a `w`×`h` image.
pub fn vertical_fov(fov: f32, axis: FovAxis, w: u32, h: u32) -> f32 {
    (2.0 * axis.tan_half(fov, w, h).y.atan()).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(xml: &str) -> Result<SceneDesc> {
        parse(xml, Path::new("test.xml"), &[])
    }

    /// The material of shape `i`.
    fn material_of(d: &SceneDesc, i: usize) -> &MaterialDesc {
        d.materials
            .iter()
            .find(|m| Some(&m.name) == d.shapes[i].material.as_ref())
            .unwrap()
    }

    /// The (u, v) where a ray from `origin` towards `target` meets the
    /// scene's surface.
    fn uv_at(d: &SceneDesc, origin: Vec3, target: Vec3) -> Vec2 {
        let scene = crate::scene::build(d).unwrap();
        let ray = crate::geometry::Ray::new(origin, (target - origin).normalize());
        let hit = scene.geometry.intersect(&ray).expect("the ray meets the surface");
        scene.geometry.surface(&ray, &hit).uv
    }

    #[test]
    fn spheres_and_disks_have_mitsubas_surface_coordinates() {
        let near = |a: Vec2, b: Vec2| (a - b).length() < 1e-4;
        let sphere = |to_world: &str| {
            parse_str(&format!(
                r#"<scene version="3.0.0"><shape type="sphere"><point name="center" value="1, 2, 3"/><float name="radius" value="2"/>{to_world}</shape></scene>"#
            ))
            .unwrap()
        };
        let c = Vec3::new(1.0, 2.0, 3.0);
        let d = sphere("");
        // u = φ/2π around +z from +x, v = θ/π from +z.
        for (dir, uv) in [
            (Vec3::Y, Vec2::new(0.25, 0.5)),
            (-Vec3::X, Vec2::new(0.5, 0.5)),
            (Vec3::new(0.0, -1.0, 0.0), Vec2::new(0.75, 0.5)),
            (Vec3::new(1.0, 0.0, 1.0).normalize(), Vec2::new(0.0, 0.25)),
        ] {
            let got = uv_at(&d, c + dir * 10.0, c);
            assert!(near(got, uv), "{dir}: {got}, expected {uv}");
        }
        // A rotation turns the coordinates with the sphere: +x to +y.
        let d = sphere(r#"<transform name="to_world"><rotate z="1" angle="90"/></transform>"#);
        let c_rot = Vec3::new(-2.0, 1.0, 3.0);
        let got = uv_at(&d, c_rot + Vec3::Y * 10.0, c_rot);
        let u = got.x.rem_euclid(1.0);
        assert!(!(1e-4..=1.0 - 1e-4).contains(&u) && (got.y - 0.5).abs() < 1e-4, "{got}");
        // A disk: u = r, v = φ/2π.
        let d = parse_str(r#"<scene version="3.0.0"><shape type="disk"/></scene>"#).unwrap();
        let got = uv_at(&d, Vec3::new(0.0, 0.5, 5.0), Vec3::new(0.0, 0.5, 0.0));
        assert!(near(got, Vec2::new(0.5, 0.25)), "{got}");
    }

    /// A `.serialized` file of `meshes` (positions, triangles), version 4,
    /// without normals or texture coordinates.
    fn serialized_file(meshes: &[(&[Vec3], &[[u32; 3]])]) -> Vec<u8> {
        use std::io::Write;
        let mut file = Vec::new();
        let mut offsets = Vec::new();
        for (positions, triangles) in meshes {
            offsets.push(file.len() as u64);
            let mut body = 0x1000u32.to_le_bytes().to_vec();
            body.push(0);
            body.extend((positions.len() as u64).to_le_bytes());
            body.extend((triangles.len() as u64).to_le_bytes());
            for p in *positions {
                for x in p.to_array() {
                    body.extend(x.to_le_bytes());
                }
            }
            for t in *triangles {
                for i in t {
                    body.extend(i.to_le_bytes());
                }
            }
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(&body).unwrap();
            file.extend(0x041Cu16.to_le_bytes());
            file.extend(4u16.to_le_bytes());
            file.extend(z.finish().unwrap());
        }
        for o in offsets {
            file.extend(o.to_le_bytes());
        }
        file.extend((meshes.len() as u32).to_le_bytes());
        file
    }

    #[test]
    fn serialized_meshes_sdf_grids_and_mesh_attributes_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let quad = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.5), Vec3::Y];
        let file = serialized_file(&[(&tri, &[[0, 1, 2]]), (&quad, &[[0, 1, 2], [0, 2, 3]])]);
        std::fs::write(dir.path().join("two.serialized"), file).unwrap();
        // A sphere of radius 0.3 in an 11³ grid.
        let mut vol = b"VOL".to_vec();
        vol.push(3);
        for v in [1i32, 11, 11, 11, 1] {
            vol.extend(v.to_le_bytes());
        }
        for v in [0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
            vol.extend(v.to_le_bytes());
        }
        for z in 0..11 {
            for y in 0..11 {
                for x in 0..11 {
                    let p = Vec3::new(x as f32, y as f32, z as f32) / 10.0;
                    vol.extend(((p - Vec3::splat(0.5)).length() - 0.3).to_le_bytes());
                }
            }
        }
        std::fs::write(dir.path().join("ball.vol"), vol).unwrap();
        let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                   property float color_0\nproperty float color_1\nproperty float color_2\n\
                   element face 1\nproperty list uchar int vertex_indices\nproperty float weight_0\nend_header\n\
                   0 0 0 1 0 0\n1 0 0 0 1 0\n0 1 0 0 0 1\n3 0 1 2 0.25\n";
        std::fs::write(dir.path().join("tri.ply"), ply).unwrap();
        let main = dir.path().join("main.xml");
        std::fs::write(
            &main,
            r#"<scene version="3.0.0">
    <texture type="mesh_attribute" id="w"><string name="name" value="face_weight"/></texture>
    <shape type="serialized"><string name="filename" value="two.serialized"/><integer name="shape_index" value="1"/></shape>
    <shape type="serialized"><string name="filename" value="two.serialized"/><boolean name="face_normals" value="true"/></shape>
    <shape type="sdfgrid"><string name="filename" value="ball.vol"/></shape>
    <shape type="ply"><string name="filename" value="tri.ply"/>
        <bsdf type="blendbsdf"><ref name="weight" id="w"/><bsdf type="diffuse"/><bsdf type="conductor"/></bsdf>
    </shape>
</scene>"#,
        )
        .unwrap();
        let d = load(&main, &[]).unwrap();
        let mesh = |i: usize| match &d.shapes[i].kind {
            ShapeKind::InlineMesh(MeshSource::Inline(m)) => m.clone(),
            other => panic!("{other:?}"),
        };
        // The second mesh, smoothed (its normals lean between its faces);
        // the first, faceted as asked.
        let second = mesh(0);
        assert_eq!(second.positions, quad);
        assert_eq!(second.normals.len(), 4);
        assert!(
            second.normals[0].z > 0.9 && second.normals[0].y < 0.0,
            "{}",
            second.normals[0]
        );
        let first = mesh(1);
        assert_eq!(first.positions, tri);
        assert!(first.normals.is_empty());
        assert!(matches!(&d.shapes[2].kind, ShapeKind::SdfGrid(_)));
        // The PLY's attributes, named as Mitsuba names them.
        let attributes: Vec<(String, bool, usize)> = mesh(3)
            .attributes
            .iter()
            .map(|a| (a.name.clone(), a.per_face, a.channels))
            .collect();
        assert_eq!(
            attributes,
            [
                ("vertex_color".to_string(), false, 3),
                ("face_weight".to_string(), true, 1)
            ]
        );
        let MaterialKindDesc::Mix {
            choice: MixChoice::Weight(weight),
            materials,
        } = &material_of(&d, 3).kind
        else {
            panic!("{:?}", material_of(&d, 3).kind)
        };
        let ColorSource::Texture(w) = weight else {
            panic!("{weight:?}")
        };
        let texture = d.textures.iter().find(|t| &t.name == w).unwrap();
        assert_eq!(
            texture.kind,
            TextureKind::MeshAttribute {
                name: "face_weight".into()
            }
        );
        let kinds: Vec<bool> = materials
            .iter()
            .map(|n| {
                matches!(
                    d.materials.iter().find(|m| &m.name == n).unwrap().kind,
                    MaterialKindDesc::Diffuse { .. }
                )
            })
            .collect();
        assert_eq!(kinds, [true, false]);
        // The grid's surface is where its values say, 0.3 from the centre.
        let scene = crate::scene::build(&d).unwrap();
        let hit = scene
            .intersect(&crate::geometry::Ray::new(Vec3::new(0.5, 0.5, 3.0), -Vec3::Z))
            .unwrap();
        assert!((hit.p.z - 0.8).abs() < 0.02, "{}", hit.p);
        // Errors name the place.
        std::fs::write(
            &main,
            r#"<scene version="3.0.0"><shape type="sdfgrid"><string name="filename" value="ball.vol"/><string name="normals" value="flat"/></shape></scene>"#,
        )
        .unwrap();
        let e = load(&main, &[]).unwrap_err().to_string();
        assert!(e.contains("main.xml:1:") && e.contains("\"flat\" is unknown"), "{e}");
        std::fs::write(
            &main,
            r#"<scene version="3.0.0"><shape type="serialized"><string name="filename" value="two.serialized"/><integer name="shape_index" value="2"/></shape></scene>"#,
        )
        .unwrap();
        let e = load(&main, &[]).unwrap_err().to_string();
        assert!(
            e.contains("shape_index 2 is out of range: the file holds 2 meshes"),
            "{e}"
        );
    }

    const SPHERE: &str = r#"<scene version="3.0.0">
    <default name="spp" value="8"/>
    <integrator type="path"><integer name="max_depth" value="5"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="32"/>
            <rfilter type="box"/></film>
    </sensor>
    <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
    <shape type="sphere">
        <float name="radius" value="1"/>
        <ref id="red"/>
    </shape>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
</scene>"#;

    /// Mitsuba's cubic and Lanczos filters, with their parameters; a
    /// Lanczos of too many lobes is an error.
    #[test]
    fn reads_mitchell_catmull_rom_and_lanczos_filters() {
        for (rfilter, filter) in [
            (
                r#"<rfilter type="mitchell"/>"#,
                Filter::Mitchell {
                    radius: 2.0,
                    b: 1.0 / 3.0,
                    c: 1.0 / 3.0,
                },
            ),
            (
                r#"<rfilter type="mitchell"><float name="B" value="0.5"/><float name="C" value="0.25"/></rfilter>"#,
                Filter::Mitchell {
                    radius: 2.0,
                    b: 0.5,
                    c: 0.25,
                },
            ),
            (
                r#"<rfilter type="catmullrom"/>"#,
                Filter::Mitchell {
                    radius: 2.0,
                    b: 0.0,
                    c: 0.5,
                },
            ),
            (
                r#"<rfilter type="lanczos"/>"#,
                Filter::Lanczos { radius: 3.0, tau: 3.0 },
            ),
            (
                r#"<rfilter type="lanczos"><integer name="lobes" value="2"/></rfilter>"#,
                Filter::Lanczos { radius: 2.0, tau: 2.0 },
            ),
        ] {
            let d = parse_str(&SPHERE.replace(r#"<rfilter type="box"/>"#, rfilter)).unwrap();
            assert_eq!(d.settings.filter, filter, "{rfilter}");
            assert!(d.warnings.is_empty(), "{rfilter}: {:?}", d.warnings);
        }
        let e = parse_str(&SPHERE.replace(
            r#"<rfilter type="box"/>"#,
            r#"<rfilter type="lanczos"><integer name="lobes" value="9"/></rfilter>"#,
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("lobes") && e.contains("between 1 and 7"), "{e}");
    }

    #[test]
    fn reads_settings_camera_and_shapes() {
        let d = parse_str(SPHERE).unwrap();
        assert_eq!(
            (
                d.settings.width,
                d.settings.height,
                d.settings.spp,
                d.settings.max_depth
            ),
            (64, 32, 8, 5)
        );
        // The sampler, read before the film, states the samples per pixel
        // (a time limit then only caps them); without one, Mitsuba's 4 are
        // a default.
        assert!(d.sets_spp());
        let without = SPHERE.replace(
            r#"<sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>"#,
            "",
        );
        let w = parse_str(&without).unwrap();
        assert!(!w.sets_spp() && w.settings.spp == 4);
        assert_eq!(d.settings.filter, Filter::Box { radius: 0.5 });
        // fov 45° along x on a 2:1 image.
        let ProjectionDesc::Perspective { fov } = d.camera.projection else {
            panic!()
        };
        let expect = (2.0 * ((22.5f32).to_radians().tan() * 0.5).atan()).to_degrees();
        assert!((fov - expect).abs() < 1e-4);
        // The camera sits at z = 5; its +x (after the mirror) points to world +x.
        let m = d.camera.to_world.unwrap();
        assert!((m.transform_point3(Vec3::ZERO) - Vec3::new(0.0, 0.0, 5.0)).length() < 1e-5);
        assert!((m.transform_vector3(Vec3::X) - Vec3::X).length() < 1e-5);
        assert!((m.transform_vector3(Vec3::Z) - -Vec3::Z).length() < 1e-5);
        assert_eq!(d.shapes.len(), 1);
        assert!(matches!(d.background, BackgroundDesc::Constant(c) if c == Rgb::ONE));
        let m = &d.materials[0];
        assert!(!m.two_sided, "Mitsuba BSDFs are one-sided");
    }

    /// `twosided` with two BSDFs: a mix chosen by the side a ray arrives
    /// from, each part two-sided; a ray from the front meets the first, one
    /// from the back the second.
    #[test]
    fn twosided_with_two_bsdfs_chooses_by_side() {
        let d = parse_str(
            r#"<scene version="3.0.0"><shape type="rectangle"><bsdf type="twosided">
              <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.1, 0.1"/></bsdf>
              <bsdf type="roughconductor"><float name="alpha" value="0.3"/></bsdf></bsdf></shape></scene>"#,
        )
        .unwrap();
        let m = material_of(&d, 0);
        let MaterialKindDesc::Mix {
            choice: MixChoice::Side,
            materials,
        } = &m.kind
        else {
            panic!("{:?}", m.kind)
        };
        let part = |i: usize| d.materials.iter().find(|m| m.name == materials[i]).unwrap();
        assert!(matches!(part(0).kind, MaterialKindDesc::Diffuse { .. }) && part(0).two_sided);
        assert!(matches!(part(1).kind, MaterialKindDesc::Conductor { .. }) && part(1).two_sided);
        assert!(!d.warnings.iter().any(|w| w.contains("BSDF")), "{:?}", d.warnings);
        // The rectangle faces +z.
        let scene = crate::scene::build(&d).unwrap();
        let kind_of = |name: &str| {
            let index = d.materials.iter().position(|m| m.name == name).unwrap();
            std::mem::discriminant(&scene.materials[index].kind)
        };
        for (origin, expected) in [(Vec3::Z, 0), (-Vec3::Z, 1)] {
            let ray = crate::geometry::Ray::new(origin, -origin);
            let mut hit = scene.intersect(&ray).expect("the ray meets the rectangle");
            scene.choose_any_material(&mut hit, ray.dir);
            let chosen = &scene.materials[hit.material as usize];
            assert_eq!(
                std::mem::discriminant(&chosen.kind),
                kind_of(&materials[expected]),
                "from {origin}"
            );
            assert!(chosen.two_sided, "from {origin}");
        }
        let e = parse_str(
            r#"<scene version="3.0.0"><bsdf type="twosided" id="t"><bsdf type="diffuse"/><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf></scene>"#,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("twosided takes one or two nested BSDFs, not 3"), "{e}");
    }

    #[test]
    fn sampler_types_map_to_trazo_samplers() {
        for (ty, kind, warns) in [
            ("independent", SamplerKind::Independent, false),
            ("stratified", SamplerKind::Stratified, false),
            ("ldsampler", SamplerKind::Sobol, false),
            ("multijitter", SamplerKind::Stratified, true),
        ] {
            let d =
                parse_str(&SPHERE.replace("sampler type=\"independent\"", &format!("sampler type=\"{ty}\""))).unwrap();
            assert_eq!(d.settings.sampler, kind, "{ty}");
            assert_eq!(
                d.warnings.iter().any(|w| w.contains("approximated by stratified")),
                warns,
                "{ty}"
            );
            assert!(d.settings.jitter, "{ty}");
        }
        // Stratified samples at the strata's centres.
        let d = parse_str(&SPHERE.replace(
            "<sampler type=\"independent\">",
            "<sampler type=\"stratified\"><boolean name=\"jitter\" value=\"false\"/>",
        ))
        .unwrap();
        assert_eq!(
            (d.settings.sampler, d.settings.jitter),
            (SamplerKind::Stratified, false)
        );
    }

    #[test]
    fn defines_override_defaults_and_unknown_parameters_fail() {
        let d = parse(SPHERE, Path::new("t.xml"), &[("spp".into(), "32".into())]).unwrap();
        assert_eq!(d.settings.spp, 32);
        let e = parse_str(&SPHERE.replace("$spp", "$samples")).unwrap_err().to_string();
        assert!(e.contains("undefined parameter $samples"), "{e}");
        let d = parse(SPHERE, Path::new("t.xml"), &[("nothing".into(), "1".into())]).unwrap();
        assert!(d.warnings.iter().any(|w| w.contains("-D nothing")));
    }

    #[test]
    fn transforms_compose_in_order() {
        let xml = r#"<scene version="3.0.0"><shape type="cube"><transform name="to_world">
            <scale value="2"/><rotate y="1" angle="90"/><translate x="1"/>
        </transform></shape></scene>"#;
        let d = parse_str(xml).unwrap();
        let TransformOp::Matrix(m) = d.shapes[0].transform[0] else {
            panic!()
        };
        // (1,0,0) → scale (2,0,0) → rotate about y by 90° → (0,0,−2) → translate (1,0,−2).
        assert!((m.transform_point3(Vec3::X) - Vec3::new(1.0, 0.0, -2.0)).length() < 1e-5);
    }

    #[test]
    fn errors_name_place_and_element() {
        let e = parse_str("<scene><shape type=\"sphere\"><float name=\"radius\" value=\"-1\"/></shape></scene>")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("test.xml:1:"), "{e}");
        assert!(e.contains("radius") && e.contains("positive"), "{e}");
        let e = parse_str("<scene><shape type=\"sphere\"><float name=\"radius\" value=\"big\"/></shape></scene>")
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"big\" is not a number"), "{e}");
        let e = parse_str("<scene><shape type=\"sphere\">").unwrap_err().to_string();
        assert!(e.contains("XML syntax error"), "{e}");
        let e = parse_str("<scene><shape type=\"sphere\"><ref id=\"nope\"/></shape></scene>")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no BSDF with id \"nope\""), "{e}");
        let e = parse_str("<notscene/>").unwrap_err().to_string();
        assert!(e.contains("<scene>"), "{e}");
    }

    #[test]
    fn media_attach_to_shapes_and_the_sensor() {
        let xml = r#"<scene>
            <medium id="fog" type="homogeneous">
                <rgb name="sigma_t" value="1, 2, 3"/>
                <float name="albedo" value="0.5"/>
                <float name="scale" value="2"/>
                <phase type="hg"><float name="g" value="0.3"/></phase>
            </medium>
            <sensor type="perspective"><ref id="fog" name="medium"/></sensor>
            <shape type="sphere">
                <bsdf type="null"/>
                <ref id="fog" name="interior"/>
                <medium type="heterogeneous" name="exterior">
                    <volume type="constvolume" name="sigma_t">
                        <float name="value" value="4"/>
                        <transform name="to_world"><translate x="1"/></transform>
                    </volume>
                </medium>
            </shape>
            <shape type="sphere"><bsdf type="thindielectric"/></shape>
        </scene>"#;
        let d = parse_str(xml).unwrap();
        assert_eq!(d.media.len(), 2);
        let fog = &d.media[0];
        assert_eq!(fog.name, "medium:fog");
        assert_eq!(fog.sigma_t, FieldDesc::Constant(Rgb::new(1.0, 2.0, 3.0)));
        assert_eq!(fog.albedo, FieldDesc::Constant(Rgb::splat(0.5)));
        assert_eq!((fog.scale, fog.g), (Rgb::splat(2.0), 0.3));
        assert!(matches!(&d.media[1].sigma_t, FieldDesc::Boxed { value, .. } if *value == Rgb::splat(4.0)));
        assert_eq!(d.camera_medium.as_deref(), Some("medium:fog"));
        let mi = d.shapes[0].media.as_ref().unwrap();
        assert_eq!(mi.inside.as_deref(), Some("medium:fog"));
        assert_eq!(mi.outside.as_deref(), Some(d.media[1].name.as_str()));
        let material = |s: &ShapeDesc| {
            d.materials
                .iter()
                .find(|m| Some(&m.name) == s.material.as_ref())
                .unwrap()
        };
        assert_eq!(material(&d.shapes[0]).kind, MaterialKindDesc::NULL);
        assert!(
            matches!(material(&d.shapes[1]).kind, MaterialKindDesc::Thin { ior, .. } if (ior - 1.5046).abs() < 1e-4)
        );
        assert!(d.shapes[1].media.is_none());
        let e = parse_str(r#"<scene><shape type="sphere"><ref id="smoke" name="interior"/></shape></scene>"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no medium with id \"smoke\""), "{e}");
        let e = parse_str(r#"<scene><medium id="m" type="homogeneous"><volume name="sigma_t" type="gridvolume"><string name="filename" value="a.vol"/></volume></medium></scene>"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("heterogeneous"), "{e}");
    }

    #[test]
    fn unsupported_things_warn_with_lines() {
        let xml = "<scene>\n<volume type=\"gridvolume\"/>\n<shape type=\"sphere\"><float name=\"wobble\" value=\"1\"/></shape>\n</scene>";
        let d = parse_str(xml).unwrap();
        assert!(
            d.warnings
                .iter()
                .any(|w| w.starts_with("test.xml:2:") && w.contains("never used")),
            "{:?}",
            d.warnings
        );
        assert!(
            d.warnings
                .iter()
                .any(|w| w.starts_with("test.xml:3:") && w.contains("wobble")),
            "{:?}",
            d.warnings
        );
    }

    /// An area emitter defined at the top with an id lights every shape
    /// that refers to it (with or without a BSDF of its own); one without
    /// an id is placed nowhere.
    #[test]
    fn area_emitters_by_reference() {
        let xml = r#"<scene>
          <emitter type="area" id="lamp"><rgb name="radiance" value="5"/></emitter>
          <bsdf type="diffuse" id="white"/>
          <shape type="rectangle"><ref id="lamp"/></shape>
          <shape type="sphere"><ref id="white"/><ref id="lamp"/></shape>
          <shape type="sphere"><ref id="white"/></shape>
        </scene>"#;
        let d = parse_str(xml).unwrap();
        for i in 0..2 {
            assert_eq!(
                material_of(&d, i).emission,
                ColorSource::Rgb(Rgb::splat(5.0)),
                "shape {i}"
            );
        }
        assert_eq!(material_of(&d, 2).emission, ColorSource::Rgb(Rgb::ZERO));
        let e = parse_str(
            r#"<scene><emitter type="area" id="lamp"/>
            <shape type="sphere"><ref name="bsdf" id="lamp"/></shape></scene>"#,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("no BSDF with id \"lamp\""), "{e}");
    }

    /// A sampler defined at the top with an id is the sensor's when the
    /// sensor refers to it, and nobody's before.
    #[test]
    fn samplers_by_reference() {
        let sampler = r#"<sampler type="stratified" id="s"><integer name="sample_count" value="9"/>
            <integer name="seed" value="3"/></sampler>"#;
        let d = parse_str(&format!(
            r#"<scene>{sampler}<sensor type="perspective"><ref id="s"/></sensor></scene>"#
        ))
        .unwrap();
        assert_eq!(
            (d.settings.sampler, d.settings.spp, d.settings.seed),
            (SamplerKind::Stratified, 9, 3)
        );
        let d = parse_str(&format!(r#"<scene>{sampler}<sensor type="perspective"/></scene>"#)).unwrap();
        assert_eq!(d.settings.spp, 4, "Mitsuba's default, not the unused sampler's");
        let e = parse_str(r#"<scene><sensor type="perspective"><ref id="t"/></sensor></scene>"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no object with id \"t\""), "{e}");
    }

    #[test]
    fn materials_map_to_trazo_models() {
        let xml = r#"<scene>
          <bsdf type="twosided" id="a"><bsdf type="roughconductor">
              <string name="distribution" value="ggx"/><float name="alpha" value="0.2"/>
              <rgb name="eta" value="0.2, 0.9, 1.1"/><rgb name="k" value="3.9, 2.4, 2.1"/></bsdf></bsdf>
          <bsdf type="dielectric" id="b"><string name="int_ior" value="water"/></bsdf>
          <bsdf type="roughplastic" id="c"><string name="distribution" value="ggx"/>
              <rgb name="diffuse_reflectance" value="0.1, 0.2, 0.3"/></bsdf>
          <bsdf type="roughdielectric" id="e"><float name="alpha" value="0.3"/></bsdf>
          <bsdf type="normalmap" id="f"><rgb name="normalmap" value="0.6, 0.5, 0.9"/><bsdf type="diffuse"/></bsdf>
          <shape type="sphere"><ref id="a"/></shape>
          <shape type="sphere"><ref id="b"/></shape>
          <shape type="sphere"><ref id="c"/></shape>
          <shape type="sphere"><ref id="c"/><emitter type="area"><rgb name="radiance" value="4"/></emitter></shape>
          <shape type="sphere"><ref id="e"/></shape>
          <shape type="sphere"><ref id="f"/></shape>
        </scene>"#;
        let d = parse_str(xml).unwrap();
        let by = |i: usize| material_of(&d, i);
        assert!(by(0).two_sided);
        assert!(matches!(by(0).kind, MaterialKindDesc::Conductor { roughness: (a, _), .. } if a == 0.2));
        assert!(matches!(by(1).kind, MaterialKindDesc::Dielectric { ior, .. } if (ior - 1.333).abs() < 1e-3));
        assert!(
            matches!(by(2).kind, MaterialKindDesc::Plastic { roughness, ior, distribution, .. }
                if roughness == 0.1 && ior == 1.49 && distribution == MicrofacetDistribution::Ggx)
        );
        // Mitsuba's default distribution is Beckmann's.
        assert!(matches!(
            by(4).kind,
            MaterialKindDesc::Dielectric { roughness, distribution: MicrofacetDistribution::Beckmann, .. } if roughness == (0.3, 0.3)
        ));
        assert!(
            !d.warnings.iter().any(|w| w.contains("distribution")),
            "{:?}",
            d.warnings
        );
        // A normal map keeps its nested BSDF and adds its texture.
        assert!(matches!(by(5).kind, MaterialKindDesc::Diffuse { .. }));
        assert_eq!(
            by(5).normal_map,
            Some(NormalMapDesc::new(ColorSource::Rgb(Rgb::new(0.6, 0.5, 0.9))))
        );
        assert!(by(0).normal_map.is_none());
        assert!(!d.warnings.iter().any(|w| w.contains("normalmap")), "{:?}", d.warnings);
        // The emitting shape gets its own material; the plain one is shared.
        assert_ne!(d.shapes[2].material, d.shapes[3].material);
        assert_eq!(by(3).emission, ColorSource::Rgb(Rgb::splat(4.0)));
    }

    /// Mitsuba's checkerboard with textures for its colours and a to_uv
    /// offset: checks half a unit of the transformed (u, v) wide, color0
    /// where both fractions are below ½ (checkerboard.cpp), evaluated here
    /// against that formula at many points.
    #[test]
    fn checkerboards_nest_and_take_offsets() {
        let xml = r#"<scene version="3.0.0">
          <shape type="sphere">
            <bsdf type="diffuse">
              <texture name="reflectance" type="checkerboard">
                <transform name="to_uv"><scale x="3" y="2"/><translate x="0.25" y="0.1"/></transform>
                <texture name="color0" type="checkerboard">
                  <rgb name="color0" value="0.9, 0.1, 0.1"/><rgb name="color1" value="0.1, 0.9, 0.1"/>
                  <transform name="to_uv"><scale x="5" y="5"/></transform>
                </texture>
                <rgb name="color1" value="0.1, 0.1, 0.9"/>
              </texture>
            </bsdf>
          </shape>
        </scene>"#;
        let d = parse_str(xml).unwrap();
        assert!(
            !d.warnings
                .iter()
                .any(|w| w.contains("checkerboard") || w.contains("to_uv")),
            "{:?}",
            d.warnings
        );
        let scene = crate::scene::build::build(&d).unwrap();
        let crate::material::MaterialKind::Diffuse { reflectance } = &scene.materials[0].kind else {
            panic!("{:?}", scene.materials[0].kind)
        };
        let checks = |uv: Vec2, even: Rgb, odd: Rgb| {
            let f = uv - uv.floor();
            if (f.x > 0.5) == (f.y > 0.5) { even } else { odd }
        };
        let mut rng = crate::sampling::rng::Pcg32::new(9, 0);
        for _ in 0..500 {
            let uv = Vec2::new(rng.next_f32(), rng.next_f32());
            let inner = checks(uv * 5.0, Rgb::new(0.9, 0.1, 0.1), Rgb::new(0.1, 0.9, 0.1));
            let expected = checks(
                uv * Vec2::new(3.0, 2.0) + Vec2::new(0.25, 0.1),
                inner,
                Rgb::new(0.1, 0.1, 0.9),
            );
            let tc = crate::texture::TexCoord::new(uv, Vec3::ZERO);
            let got = reflectance.eval(&scene.textures, &tc);
            // Points within float error of a check's edge may go either way.
            let near_edge = [uv * 5.0, uv * Vec2::new(3.0, 2.0) + Vec2::new(0.25, 0.1)]
                .iter()
                .any(|q| ((2.0 * *q) - (2.0 * *q).round()).abs().min_element() < 1e-4);
            assert!(near_edge || got == expected, "at {uv}: {got} against {expected}");
        }
    }

    /// A bump map keeps its nested BSDF and takes its texture whatever the
    /// texture's name, with its scale; one over a normal map is named.
    #[test]
    fn bump_maps_take_their_texture_and_scale() {
        let xml = r#"<scene version="3.0.0">
          <texture type="checkerboard" id="checks"/>
          <bsdf type="bumpmap" id="a">
            <float name="scale" value="0.02"/>
            <texture name="anything" type="checkerboard"><float name="color0" value="0.2"/></texture>
            <bsdf type="roughconductor"/>
          </bsdf>
          <bsdf type="bumpmap" id="b"><ref id="checks"/><bsdf type="diffuse"/></bsdf>
          <bsdf type="bumpmap" id="c">
            <ref name="heights" id="checks"/>
            <bsdf type="normalmap"><rgb name="normalmap" value="0.5, 0.5, 1"/><bsdf type="diffuse"/></bsdf>
          </bsdf>
          <shape type="sphere"><ref id="a"/></shape>
          <shape type="sphere"><ref id="b"/></shape>
          <shape type="sphere"><ref id="c"/></shape>
        </scene>"#;
        let d = parse_str(xml).unwrap();
        let by = |i: usize| material_of(&d, i);
        assert!(matches!(by(0).kind, MaterialKindDesc::Conductor { .. }));
        let a = by(0).bump_map.clone().expect("a bump map");
        assert_eq!(a.scale, 0.02);
        let ColorSource::Texture(name) = &a.height else {
            panic!("{:?}", a.height)
        };
        assert!(
            d.textures
                .iter()
                .any(|t| &t.name == name && matches!(t.kind, TextureKind::Checkerboard { .. }))
        );
        let b = by(1).bump_map.clone().expect("a bump map");
        assert_eq!(b.scale, 1.0);
        assert!(matches!(by(1).kind, MaterialKindDesc::Diffuse { .. }));
        // The outer map wins, and the inner one is named.
        assert!(by(2).bump_map.is_some() && by(2).normal_map.is_none());
        assert_eq!(
            d.warnings
                .iter()
                .filter(|w| w.contains("a bumpmap over a normalmap"))
                .count(),
            1,
            "{:?}",
            d.warnings
        );
        assert!(
            !d.warnings
                .iter()
                .any(|w| !w.contains("a bumpmap over") && (w.contains("unsupported") || w.contains("ignored"))),
            "{:?}",
            d.warnings
        );
        // Without a texture there are no heights.
        let err = parse_str(
            r#"<scene version="3.0.0"><bsdf type="bumpmap" id="x"><bsdf type="diffuse"/></bsdf>
               <shape type="sphere"><ref id="x"/></shape></scene>"#,
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("bumpmap needs a nested texture"), "{err}");
    }

    /// `principled` takes Mitsuba's defaults, its index from `specular`
    /// (or `eta`, not both) and floats as float textures; `principledthin`
    /// is two-sided and takes `diff_trans`.
    #[test]
    fn principled_bsdfs_take_mitsubas_parameters() {
        let xml = r#"<scene version="3.0.0">
          <bsdf type="principled" id="a"/>
          <bsdf type="principled" id="b">
            <rgb name="base_color" value="0.2, 0.8, 0.1"/>
            <float name="roughness" value="0.15"/>
            <texture name="metallic" type="checkerboard">
              <float name="color0" value="0.7"/><float name="color1" value="0.1"/>
            </texture>
            <float name="spec_trans" value="0.5"/>
            <float name="eta" value="1"/>
            <float name="main_specular_sampling_rate" value="2"/>
          </bsdf>
          <bsdf type="principledthin" id="c">
            <float name="diff_trans" value="1.4"/>
            <float name="eta" value="1.33"/>
          </bsdf>
          <shape type="sphere"><ref id="a"/></shape>
          <shape type="sphere"><ref id="b"/></shape>
          <shape type="rectangle"><ref id="c"/></shape>
        </scene>"#;
        let d = parse_str(xml).unwrap();
        assert!(
            d.warnings
                .iter()
                .all(|w| !w.contains("principled") && !w.contains("ignored")),
            "{:?}",
            d.warnings
        );
        let by = |i: usize| material_of(&d, i);
        let MaterialKindDesc::Principled { params, eta, thin } = &by(0).kind else {
            panic!("{:?}", by(0).kind)
        };
        assert!(!thin && !by(0).two_sided);
        assert!((eta - 1.5).abs() < 1e-3, "{eta}"); // specular 0.5
        assert_eq!(params.base_color, ColorSource::Rgb(Rgb::splat(0.5)));
        assert_eq!(params.roughness, ColorSource::Rgb(Rgb::splat(0.5)));
        assert_eq!(params.clearcoat, ColorSource::Rgb(Rgb::ZERO));
        let MaterialKindDesc::Principled { params, eta, .. } = &by(1).kind else {
            panic!("{:?}", by(1).kind)
        };
        // With transmission on, η = 1 becomes 1.001, as in Mitsuba.
        assert_eq!(*eta, 1.001);
        assert_eq!(params.roughness, ColorSource::Rgb(Rgb::splat(0.15)));
        // A float read from checks: Mitsuba's eval_1 swaps color0 and color1.
        let ColorSource::Texture(name) = &params.metallic else {
            panic!("{:?}", params.metallic)
        };
        let t = d.textures.iter().find(|t| &t.name == name).unwrap();
        assert!(
            matches!(t.kind, TextureKind::Checkerboard { even, .. } if even == Rgb::splat(0.1)),
            "{:?}",
            t.kind
        );
        let MaterialKindDesc::Principled { params, eta, thin } = &by(2).kind else {
            panic!("{:?}", by(2).kind)
        };
        assert!(*thin && by(2).two_sided);
        assert_eq!((*eta, &params.diff_trans), (1.33, &ColorSource::Rgb(Rgb::splat(1.4))));
        let e = parse_str(
            r#"<scene version="3.0.0"><bsdf type="principled" id="x"><float name="eta" value="1.4"/>
               <float name="specular" value="0.3"/></bsdf><shape type="sphere"><ref id="x"/></shape></scene>"#,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("\"eta\" or \"specular\", not both"), "{e}");
    }

    /// Roughness given as textures (Mitsuba's float textures for `alpha_u`
    /// and `alpha_v`) becomes a roughness map; a constant stays constant.
    #[test]
    fn rough_bsdfs_take_roughness_textures() {
        let xml = r#"<scene>
          <bsdf type="roughconductor" id="a">
            <texture name="alpha_u" type="checkerboard">
              <float name="color0" value="0.05"/><float name="color1" value="0.3"/></texture>
            <float name="alpha_v" value="0.2"/>
          </bsdf>
          <bsdf type="roughdielectric" id="b">
            <texture name="alpha" type="checkerboard"/>
          </bsdf>
          <shape type="sphere"><ref id="a"/></shape>
          <shape type="sphere"><ref id="b"/></shape>
        </scene>"#;
        let d = parse_str(xml).unwrap();
        let by = |i: usize| material_of(&d, i);
        let a = by(0).roughness_map.as_ref().expect("a roughness map");
        let ColorSource::Texture(t) = &a.u else {
            panic!("alpha_u is not a texture: {:?}", a.u)
        };
        let tex = d.textures.iter().find(|x| &x.name == t).unwrap();
        // Read as a float, Mitsuba's checkerboard swaps its colours.
        assert!(matches!(tex.kind, TextureKind::Checkerboard { even, odd, .. }
            if even == Rgb::splat(0.3) && odd == Rgb::splat(0.05)));
        assert_eq!(a.v, ColorSource::Rgb(Rgb::splat(0.2)));
        assert!(!a.remap_sqrt);
        let b = by(1).roughness_map.as_ref().expect("a roughness map");
        assert_eq!(b.u, b.v);
        assert!(
            !d.warnings.iter().any(|w| w.contains("alpha") || w.contains("texture")),
            "{:?}",
            d.warnings
        );
        let built = crate::scene::build(&d).unwrap();
        assert_eq!(built.materials.iter().filter(|m| m.roughness_map.is_some()).count(), 2);
    }

    /// A projector keeps its frame, field of view and image; without an
    /// irradiance it is an error, as in Mitsuba.
    #[test]
    fn projectors_are_read() {
        let xml = r#"<scene>
          <emitter type="projector">
            <float name="fov" value="60"/><string name="fov_axis" value="y"/>
            <float name="scale" value="3"/>
            <rgb name="irradiance" value="0.5"/>
            <transform name="to_world"><translate value="1, 2, 3"/></transform>
          </emitter>
        </scene>"#;
        let d = parse_str(xml).unwrap();
        let LightKind::Projector {
            position,
            fov,
            fov_axis,
            ref irradiance,
            scale,
            ..
        } = d.lights[0].kind
        else {
            panic!("not a projector: {:?}", d.lights[0].kind)
        };
        assert_eq!(
            (position, fov, fov_axis, scale),
            (Vec3::new(1.0, 2.0, 3.0), 60.0, FovAxis::Y, 3.0)
        );
        assert_eq!(*irradiance, ColorSource::Rgb(Rgb::splat(0.5)));
        assert!(!d.warnings.iter().any(|w| w.contains("projector")), "{:?}", d.warnings);
        let e = parse_str(r#"<scene><emitter type="projector"/></scene>"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("needs an \"irradiance\""), "{e}");
    }

    #[test]
    fn an_emitter_does_not_lend_its_emission_to_other_users_of_its_bsdf() {
        let xml = r#"<scene>
          <bsdf type="diffuse" id="white"/>
          <shape type="sphere"><ref id="white"/><emitter type="area"><rgb name="radiance" value="9"/></emitter></shape>
          <shape type="sphere"><ref id="white"/></shape>
          <shape type="sphere"><ref id="white"/></shape>
        </scene>"#;
        let d = parse_str(xml).unwrap();
        let m = |i: usize| {
            d.materials
                .iter()
                .find(|m| Some(&m.name) == d.shapes[i].material.as_ref())
                .unwrap()
        };
        assert_eq!(m(0).emission, ColorSource::Rgb(Rgb::splat(9.0)));
        assert_eq!(m(1).emission, ColorSource::Rgb(Rgb::ZERO));
        assert_eq!(
            d.shapes[1].material, d.shapes[2].material,
            "plain users share one material"
        );
    }

    #[test]
    fn mitsuba_cube_faces_point_outward() {
        let m = mitsuba_cube();
        assert!(m.validate().is_ok());
        for i in 0..m.len() {
            let s = m.surface(i, [1.0 / 3.0; 3]);
            // Outward: the normal points away from the centre.
            assert!(s.n.dot(s.p) > 0.9, "face {i}");
        }
    }

    #[test]
    fn cube_faces_are_the_mesh_faces() {
        use crate::geometry::shape::{Rectangle, Shape};
        let mesh = mitsuba_cube();
        let faces = mitsuba_cube_faces();
        for (f, [corner, edge_u, edge_v]) in faces.into_iter().enumerate() {
            let face = Shape::Rectangle(Rectangle::new(corner, edge_u, edge_v));
            for tri in [2 * f, 2 * f + 1] {
                for b in [[0.2, 0.3, 0.5], [0.7, 0.1, 0.2], [1.0 / 3.0; 3]] {
                    let m = mesh.surface(tri, b);
                    let r = face.surface(m.p);
                    // Same point, the mesh's (u, v) and dp/du, and the
                    // normal opposite (the reader flips the rectangles).
                    assert!((r.p - m.p).length() < 1e-6, "face {f}");
                    assert!((r.uv - m.uv).length() < 1e-6, "face {f}: {} {}", r.uv, m.uv);
                    assert!((r.dpdu - m.dpdu).length() < 1e-6, "face {f}: {} {}", r.dpdu, m.dpdu);
                    assert!((r.n + m.n).length() < 1e-6, "face {f}: {} {}", r.n, m.n);
                }
            }
        }
    }

    #[test]
    fn cubes_become_rectangles_unless_emitting() {
        let d = parse_str(
            r#"<scene version="3.0.0">
            <shape type="cube"><transform name="to_world"><scale value="2"/></transform></shape>
            <shape type="cube"><boolean name="flip_normals" value="true"/></shape>
            <shape type="cube"><emitter type="area"/></shape>
            </scene>"#,
        )
        .unwrap();
        let kinds: Vec<&str> = d
            .shapes
            .iter()
            .map(|s| match s.kind {
                ShapeKind::Rectangle { .. } => "rectangle",
                ShapeKind::InlineMesh(_) => "mesh",
                _ => "other",
            })
            .collect();
        assert_eq!(kinds, [["rectangle"; 12].as_slice(), &["mesh"; 1]].concat());
        // Faces keep the cube's transform and material; flip_normals turns
        // them back out.
        assert!(
            d.shapes[..6]
                .iter()
                .all(|s| s.transform == d.shapes[0].transform && s.flip_normals)
        );
        assert!(d.shapes[6..12].iter().all(|s| !s.flip_normals));
        assert!(d.shapes[..12].iter().all(|s| s.material == d.shapes[0].material));
        assert_eq!(d.shapes[0].transform.len(), 1);
    }

    /// A group of a mesh (OBJ), a sphere and a cube, each with its own
    /// to_world and BSDF; a second group with the same OBJ file.
    /// Without `fov`, Mitsuba's field of view is a focal length (50 mm by
    /// default) on a 36 × 24 mm film along its diagonal: 34.02° across a
    /// square film.
    #[test]
    fn default_field_of_view_is_fifty_millimetres_along_the_diagonal() {
        let fov_of = |sensor_props: &str, w: u32, h: u32| {
            let text = format!(
                r#"<scene version="3.0.0"><sensor type="perspective">{sensor_props}
    <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/></film>
</sensor></scene>"#
            );
            match parse(&text, Path::new("s.xml"), &[]).unwrap().camera.projection {
                ProjectionDesc::Perspective { fov } => fov,
                other => panic!("{other:?}"),
            }
        };
        assert!((fov_of("", 48, 48) - 34.02).abs() < 0.01, "{}", fov_of("", 48, 48));
        // fov_axis does not change how a focal length is measured.
        assert_eq!(
            fov_of(r#"<string name="fov_axis" value="y"/>"#, 48, 48),
            fov_of("", 48, 48)
        );
        // 35 mm on a 3:2 film: the diagonal is the film's, so the vertical
        // field of view is that of 24 mm at 35 mm, 37.85°.
        let fov = fov_of(r#"<string name="focal_length" value="35mm"/>"#, 300, 200);
        assert!((fov - 37.85).abs() < 0.01, "{fov}");
        // An explicit fov keeps its axis.
        assert!((fov_of(r#"<float name="fov" value="40"/>"#, 48, 48) - 40.0).abs() < 1e-4);
    }

    /// Sampled spectra convert as in Mitsuba's RGB variants: emission
    /// without D65, reflectances with it; a flat emitted spectrum is
    /// illuminant E.
    #[test]
    fn spectra_convert_as_in_mitsubas_rgb_variants() {
        let d = parse_str(
            r#"<scene version="3.0.0">
    <emitter type="constant"><spectrum name="radiance" value="2"/></emitter>
    <shape type="sphere">
        <bsdf type="diffuse"><spectrum name="reflectance" value="400:0.1, 500:0.5, 600:0.9, 700:0.3"/></bsdf>
        <emitter type="area"><spectrum name="radiance" value="400:0, 500:8, 600:15.6, 700:18.4"/></emitter>
    </shape>
</scene>"#,
        )
        .unwrap();
        let text = format!("{d:?}");
        for expected in ["2.409588", "20.71", "0.8547", "0.6875"] {
            assert!(text.contains(expected), "{expected} not in {text}");
        }
        let e = parse_str(r#"<scene><shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="500:0.5"/></bsdf></shape></scene>"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("test.xml:1:") && e.contains("at least two"), "{e}");
    }

    /// A spectrum file (wavelength and value pairs) gives the colour its
    /// samples give inline; an unreadable or malformed one is an error
    /// naming the file.
    #[test]
    fn spectra_from_files_convert_as_their_samples() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("paint.spd"),
            "# a red paint\n400 0.1\n500 0.5\n600 0.9\n700 0.3\n",
        )
        .unwrap();
        std::fs::write(dir.path().join("bad.spd"), "400 0.1 500").unwrap();
        let scene = |spectrum: &str| {
            let main = dir.path().join("s.xml");
            std::fs::write(
                &main,
                format!(r#"<scene version="3.0.0"><shape type="sphere"><bsdf type="diffuse">{spectrum}</bsdf></shape></scene>"#),
            )
            .unwrap();
            load(&main, &[]).map(|d| material_of(&d, 0).kind.clone())
        };
        let from_file = scene(r#"<spectrum name="reflectance" filename="paint.spd"/>"#).unwrap();
        let inline = scene(r#"<spectrum name="reflectance" value="400:0.1, 500:0.5, 600:0.9, 700:0.3"/>"#).unwrap();
        assert_eq!(from_file, inline);
        assert!(matches!(from_file, MaterialKindDesc::Diffuse { reflectance: ColorSource::Rgb(c) } if c != Rgb::ONE));
        for (file, why) in [
            ("missing.spd", "cannot read spectrum file"),
            ("bad.spd", "found 3 numbers"),
        ] {
            let e = scene(&format!(r#"<spectrum name="reflectance" filename="{file}"/>"#))
                .unwrap_err()
                .to_string();
            assert!(e.contains("s.xml:1:") && e.contains(why) && e.contains(file), "{e}");
        }
    }

    /// A moment integrator renders with its nested integrator's settings.
    #[test]
    fn moment_integrator_renders_its_nested_integrator() {
        let text = r#"<scene version="3.0.0">
    <integrator type="moment">
        <integrator type="path"><integer name="max_depth" value="3"/><integer name="rr_depth" value="2"/></integrator>
    </integrator>
</scene>"#;
        let d = parse(text, Path::new("m.xml"), &[]).unwrap();
        assert_eq!((d.settings.max_depth, d.settings.rr_depth), (3, 2));
        assert!(
            d.warnings
                .iter()
                .any(|w| w.starts_with("m.xml:2:") && w.contains("moment channels"))
        );
        let direct = text.replace("type=\"path\"", "type=\"direct\"");
        assert_eq!(parse(&direct, Path::new("m.xml"), &[]).unwrap().settings.max_depth, 2);
        let e = parse(r#"<scene><integrator type="moment"/></scene>"#, Path::new("m.xml"), &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.xml:1:") && e.contains("exactly one nested integrator"),
            "{e}"
        );
    }

    /// Mitsuba's particle tracer is trazo's light tracer, with its depth;
    /// its pass size only changes scheduling and is named as ignored.
    #[test]
    fn particle_tracer_is_light_tracing() {
        let text = r#"<scene version="3.0.0">
    <integrator type="ptracer">
        <integer name="max_depth" value="4"/>
        <integer name="samples_per_pass" value="8"/>
    </integrator>
</scene>"#;
        let d = parse(text, Path::new("p.xml"), &[]).unwrap();
        assert_eq!(d.settings.integrator, IntegratorKind::Light);
        assert_eq!(d.settings.max_depth, 4);
        // The other warning is about the missing sensor.
        assert_eq!(d.warnings.len(), 2, "{:?}", d.warnings);
        assert!(d.warnings[0].starts_with("p.xml:2:") && d.warnings[0].contains("samples_per_pass"));
        assert!(!d.settings.hide_emitters);
        let hidden = text.replace(
            "<integer name=\"max_depth\" value=\"4\"/>",
            "<boolean name=\"hide_emitters\" value=\"true\"/>",
        );
        assert!(parse(&hidden, Path::new("p.xml"), &[]).unwrap().settings.hide_emitters);
    }

    /// The film's crop window: the image is that part of the full one, and
    /// a window outside the film is an error at the film.
    #[test]
    fn film_crop_window() {
        let text = |x: i32| {
            format!(
                "<scene version=\"3.0.0\">\n<sensor type=\"perspective\">\n<film type=\"hdrfilm\">\n<integer name=\"width\" value=\"64\"/><integer name=\"height\" value=\"48\"/>\n<integer name=\"crop_offset_x\" value=\"{x}\"/><integer name=\"crop_offset_y\" value=\"8\"/><integer name=\"crop_width\" value=\"32\"/><integer name=\"crop_height\" value=\"16\"/>\n</film>\n</sensor>\n</scene>"
            )
        };
        let d = parse(&text(16), Path::new("c.xml"), &[]).unwrap();
        assert_eq!((d.settings.width, d.settings.height), (32, 16));
        assert_eq!(d.settings.full_size(), (64, 48));
        assert_eq!(d.settings.crop.map(|c| (c.x, c.y)), Some((16, 8)));
        let e = parse(&text(40), Path::new("c.xml"), &[]).unwrap_err().to_string();
        assert!(e.starts_with("c.xml:3:") && e.contains("crop window"), "{e}");
    }

    /// Mitsuba 0.6's `bdpt` and `pssmlt` are trazo's; its path-space
    /// `mlt` is rendered by trazo's PSSMLT, with a warning. The
    /// Metropolis parameters carry over, and out of range they are errors.
    #[test]
    fn bidirectional_integrators_are_read() {
        for (ty, kind, warned) in [
            ("bdpt", IntegratorKind::Bdpt, false),
            ("pssmlt", IntegratorKind::Pssmlt, false),
            ("mlt", IntegratorKind::Pssmlt, true),
        ] {
            let text = format!(
                "<scene version=\"3.0.0\">\n    <integrator type=\"{ty}\">\n        <integer name=\"max_depth\" value=\"5\"/>\n    </integrator>\n</scene>"
            );
            let d = parse(&text, Path::new("b.xml"), &[]).unwrap();
            assert_eq!((d.settings.integrator, d.settings.max_depth), (kind, 5));
            let w = d.warnings.join("\n");
            assert_eq!(w.contains("b.xml:2:") && w.contains("path-space"), warned, "{w}");
        }
        let text = |p: &str| {
            format!(
                "<scene version=\"0.6.0\">\n<integrator type=\"pssmlt\">\n<integer name=\"luminanceSamples\" value=\"5000\"/>\n<float name=\"pLarge\" value=\"{p}\"/>\n</integrator>\n</scene>"
            )
        };
        let d = parse(&text("0.5"), Path::new("b.xml"), &[]).unwrap();
        assert_eq!(
            (d.settings.mlt.bootstrap, d.settings.mlt.large_step_probability),
            (5000, 0.5)
        );
        let e = parse(&text("1.5"), Path::new("b.xml"), &[]).unwrap_err().to_string();
        assert!(e.starts_with("b.xml:4:") && e.contains("probability"), "{e}");
    }

    /// File names resolve as in Mitsuba: against the main scene's folder
    /// and the `<path>`s in front of it, also inside an included file,
    /// whose own folder is not searched.
    #[test]
    fn file_names_resolve_against_search_paths_and_the_main_folder() {
        let root = tempfile::tempdir().unwrap();
        let scene_dir = root.path().join("scenes");
        std::fs::create_dir_all(scene_dir.join("parts")).unwrap();
        std::fs::create_dir_all(root.path().join("common/meshes")).unwrap();
        // One triangle each, told apart by its first vertex's x.
        let ply = |x: f32| {
            format!(
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                 element face 1\nproperty list uchar int vertex_indices\nend_header\n{x} 0 0\n{x} 1 0\n{x} 0 1\n3 0 1 2\n"
            )
        };
        std::fs::write(root.path().join("common/meshes/shared.ply"), ply(1.0)).unwrap();
        std::fs::write(scene_dir.join("local.ply"), ply(2.0)).unwrap();
        // A decoy beside the included file, which Mitsuba does not search.
        std::fs::write(scene_dir.join("parts/local.ply"), ply(3.0)).unwrap();
        std::fs::write(
            scene_dir.join("parts/sub.xml"),
            r#"<scene version="3.0.0">
    <shape type="ply"><string name="filename" value="meshes/shared.ply"/></shape>
    <shape type="ply"><string name="filename" value="local.ply"/></shape>
</scene>"#,
        )
        .unwrap();
        let main = scene_dir.join("main.xml");
        let text = r#"<scene version="3.0.0">
    <path value="../common"/>
    <include filename="parts/sub.xml"/>
</scene>"#;
        std::fs::write(&main, text).unwrap();
        let d = load(&main, &[]).unwrap();
        let files: Vec<f32> = d
            .shapes
            .iter()
            .filter_map(|s| match &s.kind {
                ShapeKind::InlineMesh(MeshSource::Inline(m)) => Some(m.positions[0].x),
                _ => None,
            })
            .collect();
        assert_eq!(files, vec![1.0, 2.0]);
        // Without the search path the shared mesh is missing, reported in
        // the main folder, where Mitsuba looks last.
        std::fs::write(&main, text.replace("<path value=\"../common\"/>", "")).unwrap();
        let e = load(&main, &[]).unwrap_err().to_string();
        assert!(
            e.contains("sub.xml:2:") && e.contains("scenes/meshes/shared.ply"),
            "{e}"
        );
        // A search path that is not a folder is an error at its element.
        std::fs::write(&main, text.replace("../common", "../nowhere")).unwrap();
        let e = load(&main, &[]).unwrap_err().to_string();
        assert!(e.contains("main.xml:2:") && e.contains("not a folder"), "{e}");
    }

    fn instancing_scene(dir: &Path) -> String {
        std::fs::write(
            dir.join("quad.obj"),
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n",
        )
        .unwrap();
        r#"<scene version="3.0.0">
    <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
    <shape type="instance">
        <ref id="g"/>
        <transform name="to_world"><rotate y="1" angle="90"/><translate x="10"/></transform>
    </shape>
    <shape type="shapegroup" id="g">
        <shape type="obj">
            <string name="filename" value="quad.obj"/>
            <transform name="to_world"><scale value="2"/></transform>
            <ref id="red"/>
        </shape>
        <shape type="sphere">
            <point name="center" x="0" y="3" z="0"/>
            <float name="radius" value="0.5"/>
            <bsdf type="roughconductor"><string name="distribution" value="ggx"/></bsdf>
        </shape>
        <shape type="cube"><transform name="to_world"><translate z="-4"/></transform></shape>
    </shape>
    <shape type="shapegroup" id="h">
        <shape type="obj"><string name="filename" value="quad.obj"/></shape>
    </shape>
    <shape type="sphere"><float name="radius" value="7"/></shape>
    <shape type="instance"><ref id="g"/></shape>
    <shape type="instance">
        <ref id="h"/>
        <transform name="to_world"><translate y="-5"/></transform>
    </shape>
</scene>"#
            .to_string()
    }

    fn matrix_of(s: &ShapeDesc) -> Mat4 {
        super::super::build::compose(&s.transform).unwrap().m
    }

    /// A spot light keeps Mitsuba's falloff (linear in angle) and projects
    /// its `texture` in its own frame; bitmaps keep their wrap mode and
    /// filter; unknown modes and a constant spot texture are errors.
    #[test]
    fn spot_projections_and_bitmap_wrap_modes() {
        let dir = tempfile::tempdir().unwrap();
        ::image::RgbImage::from_pixel(4, 2, ::image::Rgb([200, 100, 50]))
            .save(dir.path().join("t.png"))
            .unwrap();
        let path = dir.path().join("scene.xml");
        let scene = |spot_texture: &str, wrap: &str| {
            format!(
                r#"<scene version="3.0.0">
    <emitter type="spot">
        <float name="cutoff_angle" value="30"/><float name="beam_width" value="10"/>
        {spot_texture}
        <transform name="to_world"><rotate z="1" angle="90"/><translate x="1"/></transform>
    </emitter>
    <shape type="rectangle"><bsdf type="diffuse">
        <texture type="bitmap" name="reflectance"><string name="filename" value="t.png"/>
            <string name="wrap_mode" value="{wrap}"/><string name="filter_type" value="nearest"/></texture>
    </bsdf></shape>
</scene>"#
            )
        };
        let bitmap = r#"<texture type="bitmap" name="texture"><string name="filename" value="t.png"/></texture>"#;
        let d = parse(&scene(bitmap, "mirror"), &path, &[]).unwrap();
        assert!(
            d.warnings
                .iter()
                .all(|w| !w.contains("unsupported") && !w.contains("approximated")),
            "{:?}",
            d.warnings
        );
        let LightKind::Spot {
            inner_angle,
            outer_angle,
            profile,
            projection: Some(image),
            position,
            ..
        } = &d.lights[0].kind
        else {
            panic!("{:?}", d.lights[0].kind)
        };
        assert_eq!(
            (*inner_angle, *outer_angle, *profile),
            (10.0, 30.0, SpotProfile::LinearInAngle)
        );
        assert!((*position - Vec3::X).length() < 1e-6);
        // The light's x axis, turned a quarter about z, is world y.
        assert!((image.to_world * Vec3::X - Vec3::Y).length() < 1e-6);
        let texture = |name: &str| d.textures.iter().find(|t| t.name == name).unwrap();
        assert!(matches!(texture(&image.texture).kind, TextureKind::Image { .. }));
        let wraps: Vec<([WrapMode; 2], ImageFilter)> = d
            .textures
            .iter()
            .filter_map(|t| match t.kind {
                TextureKind::Image { wrap, filter, .. } => Some((wrap, filter)),
                _ => None,
            })
            .collect();
        assert!(
            wraps.contains(&([WrapMode::Mirror; 2], ImageFilter::Nearest)),
            "{wraps:?}"
        );
        assert!(
            wraps.contains(&([WrapMode::Repeat; 2], ImageFilter::Bilinear)),
            "{wraps:?}"
        );
        let e = parse(&scene("", "sideways"), &path, &[]).unwrap_err().to_string();
        assert!(
            e.contains("scene.xml:8:") && e.contains("unknown wrap_mode \"sideways\""),
            "{e}"
        );
        let e = parse(&scene(r#"<rgb name="texture" value="0.5"/>"#, "clamp"), &path, &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("scene.xml:2:") && e.contains("must vary over the image"),
            "{e}"
        );
    }

    #[test]
    fn instances_place_their_groups_shapes_with_composed_transforms() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scene.xml");
        let d = parse(&instancing_scene(dir.path()), &path, &[]).unwrap();
        assert!(
            d.warnings.iter().all(|w| !w.contains("unsupported")),
            "{:?}",
            d.warnings
        );
        // Group g is a mesh, a sphere and six cube faces; placed twice, with
        // the big sphere (read between) in its place, then group h once.
        let kinds: Vec<&str> = d
            .shapes
            .iter()
            .map(|s| match &s.kind {
                ShapeKind::Mesh(_) => "mesh",
                ShapeKind::Sphere { radius, .. } if *radius == 7.0 => "big sphere",
                ShapeKind::Sphere { .. } => "sphere",
                ShapeKind::Rectangle { .. } => "face",
                _ => "other",
            })
            .collect();
        let g = [["mesh", "sphere"].as_slice(), &["face"; 6]].concat();
        assert_eq!(kinds, [g.as_slice(), &["big sphere"], &g, &["mesh"]].concat());

        // The instance's to_world applies after the shape's own.
        let inst = Mat4::from_translation(Vec3::new(10.0, 0.0, 0.0)) * Mat4::from_rotation_y(90f32.to_radians());
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
        let p = Vec3::new(1.0, 1.0, 0.0);
        // The quad scaled by 2, then rotated and moved: (2,2,0) → (10,2,−2).
        assert!(close(
            matrix_of(&d.shapes[0]).transform_point3(p),
            Vec3::new(10.0, 2.0, -2.0)
        ));
        assert!(close(
            matrix_of(&d.shapes[0]).transform_point3(p),
            inst.transform_point3(2.0 * p)
        ));
        // The sphere has no to_world of its own: the instance's alone.
        let ShapeKind::Sphere { center, radius } = d.shapes[1].kind else {
            panic!()
        };
        assert_eq!((center, radius), (Vec3::new(0.0, 3.0, 0.0), 0.5));
        assert!(close(
            matrix_of(&d.shapes[1]).transform_point3(center),
            Vec3::new(10.0, 3.0, 0.0)
        ));
        // A cube face: translated by z = −4, then the instance.
        let q = Vec3::new(0.0, 0.0, 1.0);
        assert!(close(
            matrix_of(&d.shapes[2]).transform_point3(q),
            Vec3::new(7.0, 0.0, 0.0)
        ));
        // The second placement of g has no to_world: the shapes' own.
        assert_eq!(d.shapes[9].transform, d.shapes[0].transform[..1].to_vec());
        assert!(close(matrix_of(&d.shapes[9]).transform_point3(p), 2.0 * p));
        assert!(close(
            matrix_of(&d.shapes[17]).transform_point3(p),
            Vec3::new(1.0, -4.0, 0.0)
        ));

        // Each shape keeps its own BSDF in every placement.
        let material = |i: usize| {
            let name = d.shapes[i].material.as_ref().unwrap();
            &d.materials.iter().find(|m| &m.name == name).unwrap().kind
        };
        for base in [0, 9] {
            assert!(
                matches!(material(base), MaterialKindDesc::Diffuse { reflectance: ColorSource::Rgb(c) } if *c == Rgb::new(0.8, 0.1, 0.1))
            );
            assert!(matches!(material(base + 1), MaterialKindDesc::Conductor { .. }));
            assert!(
                matches!(material(base + 2), MaterialKindDesc::Diffuse { reflectance: ColorSource::Rgb(c) } if *c == Rgb::splat(0.5))
            );
        }
        assert_eq!(d.shapes[0].material, d.shapes[9].material);
    }

    #[test]
    fn a_mesh_file_in_groups_is_one_mesh_stored_once() {
        let dir = tempfile::tempdir().unwrap();
        let d = parse(&instancing_scene(dir.path()), &dir.path().join("scene.xml"), &[]).unwrap();
        // Both groups name the same file: one named mesh, placed three times.
        assert_eq!(d.meshes.len(), 1, "{:?}", d.meshes);
        let name = &d.meshes[0].name;
        let uses = d
            .shapes
            .iter()
            .filter(|s| s.kind == ShapeKind::Mesh(name.clone()))
            .count();
        assert_eq!(uses, 3);
        let scene = crate::scene::build(&d).unwrap();
        assert_eq!(scene.geometry.meshes.len(), 1, "the triangles are held once");
        assert_eq!(scene.geometry.instances.len(), 3);
        assert!(scene.geometry.mesh_objects.is_empty());
    }

    #[test]
    fn instance_and_shapegroup_errors_name_the_place() {
        let group = "<shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\"/></shape>";
        let err = |body: &str| {
            parse_str(&format!("<scene version=\"3.0.0\">\n{body}\n</scene>"))
                .unwrap_err()
                .to_string()
        };
        // An unknown id: the <ref>'s line and column, and a close name.
        let e = err(&format!(
            "{group}\n<shape type=\"instance\">\n  <ref id=\"gg\"/></shape>"
        ));
        assert!(e.starts_with("test.xml:4:3:"), "{e}");
        assert!(e.contains("no shapegroup with id \"gg\"") && e.contains("\"g\""), "{e}");
        let e = err("<bsdf type=\"diffuse\" id=\"red\"/>\n<shape type=\"instance\"><ref id=\"red\"/></shape>");
        assert!(
            e.contains("no shapegroup with id \"red\"") && e.contains("a BSDF has that id"),
            "{e}"
        );
        // What Mitsuba rejects.
        for (body, line, what) in [
            (
                "<shape type=\"shapegroup\" id=\"a\">\n<shape type=\"shapegroup\" id=\"b\"/></shape>",
                "test.xml:3:",
                "Nested ShapeGroup",
            ),
            (
                &format!(
                    "{group}\n<shape type=\"shapegroup\" id=\"b\">\n<shape type=\"instance\"><ref id=\"g\"/></shape></shape>"
                ),
                "test.xml:4:",
                "Nested instancing",
            ),
            (
                "<shape type=\"shapegroup\" id=\"a\"><shape type=\"sphere\">\n<emitter type=\"area\"/></shape></shape>",
                "test.xml:3:",
                "Instancing of emitters",
            ),
            ("<shape type=\"instance\"/>", "test.xml:2:", "needs a <ref"),
            (
                &format!("{group}\n<shape type=\"instance\"><ref id=\"g\"/>\n<ref id=\"g\"/></shape>"),
                "test.xml:4:",
                "one shapegroup",
            ),
            (
                &format!("{group}\n<shape type=\"instance\"><ref id=\"g\"/>\n<bsdf type=\"diffuse\"/></shape>"),
                "test.xml:4:",
                "keep their own BSDFs",
            ),
            (
                "<shape type=\"shapegroup\" id=\"a\">\n<bsdf type=\"diffuse\"/></shape>",
                "test.xml:3:",
                "holds only shapes",
            ),
            (&format!("{group}\n{group}"), "test.xml:3:", "duplicate id \"g\""),
            (
                "<shape type=\"instance\"><ref id=\"g\"/>\n<transform name=\"to_world\"><scale value=\"0\"/></transform></shape>",
                "test.xml:2:",
                "to_world",
            ),
        ] {
            let e = err(body);
            assert!(e.starts_with(line) && e.contains(what), "{body}: {e}");
        }
    }

    #[test]
    fn shapegroups_warn_only_where_nothing_is_placed() {
        let d = parse_str(
            "<scene version=\"3.0.0\">
            <shape type=\"shapegroup\" id=\"used\"><shape type=\"disk\"/><shape type=\"rectangle\"/></shape>
            <shape type=\"shapegroup\" id=\"unused\"><shape type=\"sphere\"/></shape>
            <shape type=\"shapegroup\" id=\"moved\">
                <transform name=\"to_world\"><translate x=\"1\"/></transform><shape type=\"sphere\"/>
            </shape>
            <shape type=\"instance\"><ref id=\"used\"/></shape>
            <shape type=\"instance\"><ref name=\"group\" id=\"moved\"/></shape>
            </scene>",
        )
        .unwrap();
        assert_eq!(d.shapes.len(), 3);
        // Read first, then placed: the group's to_world, then the unplaced group.
        let warnings: Vec<&String> = d.warnings.iter().filter(|w| !w.contains("the scene has no")).collect();
        let [a, b] = warnings.as_slice() else {
            panic!("{:?}", d.warnings)
        };
        assert!(a.starts_with("test.xml:4:") && a.contains("to_world is ignored"), "{a}");
        assert!(
            b.starts_with("test.xml:3:") && b.contains("\"unused\" is never placed"),
            "{b}"
        );
        // As in Mitsuba, the group's own to_world does not move its shapes:
        // the sphere's one transform turns its surface coordinates about
        // its centre.
        let ShapeKind::Sphere { center, .. } = d.shapes[2].kind else {
            panic!("{:?}", d.shapes[2].kind)
        };
        let [TransformOp::Matrix(m)] = d.shapes[2].transform.as_slice() else {
            panic!("{:?}", d.shapes[2].transform)
        };
        assert_eq!(m.transform_point3(center), center);
    }

    #[test]
    fn fov_axes() {
        assert!((vertical_fov(60.0, FovAxis::Y, 200, 100) - 60.0).abs() < 1e-4);
        let x = vertical_fov(60.0, FovAxis::X, 200, 100);
        assert!(((x / 2.0).to_radians().tan() - (30f32).to_radians().tan() / 2.0).abs() < 1e-5);
        assert_eq!(
            vertical_fov(60.0, FovAxis::Smaller, 200, 100),
            vertical_fov(60.0, FovAxis::Y, 200, 100)
        );
        assert_eq!(
            vertical_fov(60.0, FovAxis::Larger, 200, 100),
            vertical_fov(60.0, FovAxis::X, 200, 100)
        );
    }
}
