//! A reader for pbrt-v4 scene files (`.pbrt`), documented in
//! docs/formats.md with the support of every directive and parameter.
//!
//! The reader follows pbrt-v4's own parser and scene builder (parser.cpp,
//! scene.cpp) for the graphics state: the current transformation matrix
//! (CTM) is post-multiplied by each transform directive; `AttributeBegin`
//! saves the CTM, material, area light and orientation, `AttributeEnd`
//! restores them; a shape's object-to-world transform is the CTM when it is
//! declared; the camera's CTM is camera-from-world, so the camera's
//! camera-to-world matrix is its inverse. pbrt's camera space (+x right in
//! the image, +y up, +z forward) is trazo's, so no axis is flipped: a scene
//! renders as pbrt renders it, including pbrt's habit of showing world +x
//! on the left of an image made by `LookAt 0 0 5  0 0 0  0 1 0`.
//!
//! Errors name the file, line and column (of the included file, for
//! `Include`d text); elements that trazo approximates or cannot render add
//! warnings of the form `file:line:col: <what> is unsupported/approximated:
//! <how>` to [`SceneDesc::warnings`].

mod lexer;
mod lights;
mod materials;
mod media;
mod options;
mod params;
mod shapes;
mod spectrum;

pub use spectrum::blackbody_rgb;

use self::lexer::{Lexer, Tok};
use self::params::{Param, ParamList, parse_number, parse_params};
use super::desc::*;
use crate::color::Rgb;
use crate::color::space::ColorSpace;
use crate::error::{Error, Result, SourceLoc};
use crate::files::{MAX_SCENE_BYTES, io_reason};
use crate::sampling::SamplerKind;
use crate::settings::{Filter, IntegratorKind, PathSampling};
use glam::{DMat3, DMat4, DVec3, Mat3, Mat4, Vec3, Vec4};
use std::collections::{HashMap, HashSet};
use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// How many times one warning is listed before the rest are only counted.
const MAX_SAME_WARNING: usize = 10;

/// Deepest nesting of `Include` and `Import`.
const MAX_INCLUDE_DEPTH: usize = 64;

/// Every directive of pbrt-v4 (and pbrt-v3's `WorldEnd`), for suggestions.
const DIRECTIVES: [&str; 41] = [
    "Accelerator",
    "ActiveTransform",
    "AreaLightSource",
    "Attribute",
    "AttributeBegin",
    "AttributeEnd",
    "Camera",
    "ColorSpace",
    "ConcatTransform",
    "CoordinateSystem",
    "CoordSysTransform",
    "Film",
    "Identity",
    "Import",
    "Include",
    "Integrator",
    "LightSource",
    "LookAt",
    "MakeNamedMaterial",
    "MakeNamedMedium",
    "Material",
    "MediumInterface",
    "NamedMaterial",
    "ObjectBegin",
    "ObjectEnd",
    "ObjectInstance",
    "Option",
    "PixelFilter",
    "ReverseOrientation",
    "Rotate",
    "Sampler",
    "Scale",
    "Shape",
    "Texture",
    "Transform",
    "TransformBegin",
    "TransformEnd",
    "TransformTimes",
    "Translate",
    "WorldBegin",
    "WorldEnd",
];

/// Reads a pbrt-v4 scene file and the files it includes. pbrt scenes have
/// no parameters, so each `-D` definition only adds a warning.
pub fn load(path: &Path, defines: &[(String, String)]) -> Result<SceneDesc> {
    let unused = defines
        .iter()
        .map(|(name, _)| format!("-D {name}: pbrt scenes have no parameters; the definition is not used"));
    let text = read_text(path, None).map_err(|e| e.with_warnings(unused.clone().collect()))?;
    match parse(&text, path) {
        Ok(mut desc) => {
            desc.warnings.extend(unused);
            Ok(desc)
        }
        Err(e) => {
            let (e, mut warnings) = e.into_parts();
            warnings.extend(unused);
            Err(e.with_warnings(warnings))
        }
    }
}

/// Parses pbrt scene text that was read from `path` (used for messages and
/// to resolve `Include`d and referenced files). An error carries the
/// warnings given before it ([`Error::warnings`]).
pub fn parse(text: &str, path: &Path) -> Result<SceneDesc> {
    let file: Arc<Path> = Arc::from(path);
    let mut p = Parser::new(file.clone());
    p.open_files
        .push(std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()));
    let mut lx = Lexer::new(file, text, Arc::from(Path::new("")));
    let read = p.parse_file(&mut lx).and_then(|()| p.finish(lx.end_loc()));
    match read {
        Ok(()) => Ok(p.desc),
        Err(e) => {
            p.summarise_repeats();
            Err(e.with_warnings(std::mem::take(&mut p.desc.warnings)))
        }
    }
}

/// Reads a scene file as UTF-8 text, decompressing it if its name ends in
/// `.gz` (as pbrt-v4 does for the main file, `Include` and `Import`).
/// `included_from` is the `Include` directive that names it, which errors
/// then point at.
fn read_text(path: &Path, included_from: Option<&SourceLoc>) -> Result<String> {
    read_text_limited(path, included_from, MAX_SCENE_BYTES)
}

/// [`read_text`] with a limit on the bytes read (before and after
/// decompression).
fn read_text_limited(path: &Path, included_from: Option<&SourceLoc>, limit: u64) -> Result<String> {
    let fail = |message: String| match included_from {
        Some(loc) => Error::scene(Some(loc.clone()), "Include", format!("{}: {message}", path.display())),
        None => Error::file(path, message),
    };
    let meta = std::fs::metadata(path).map_err(|e| fail(format!("cannot read scene: {}", io_reason(&e))))?;
    if meta.is_dir() {
        return Err(fail("cannot read scene: this is a folder".into()));
    }
    if meta.len() > limit {
        return Err(fail(format!("scene file is larger than the limit of {limit} bytes")));
    }
    let bytes = crate::files::read_limited_gz(path, limit).map_err(|e| fail(format!("cannot read scene: {e}")))?;
    String::from_utf8(bytes).map_err(|e| {
        let lossy = String::from_utf8_lossy(e.as_bytes());
        Error::Scene {
            loc: Some(SourceLoc::from_offset(
                &Arc::from(path),
                &lossy,
                e.utf8_error().valid_up_to(),
            )),
            key: None,
            message: "the file is not valid UTF-8 text".into(),
        }
    })
}

/// Which material a shape uses.
#[derive(Clone, Debug, PartialEq)]
enum MatRef {
    /// pbrt's default: diffuse, reflectance 0.5.
    Default,
    /// A material made by `Material` or `MakeNamedMaterial` (index into
    /// `Parser::materials`).
    Index(usize),
    /// `NamedMaterial "name"`, resolved when the whole scene has been read.
    Named(String, SourceLoc),
}

/// The area light that shapes declared after `AreaLightSource` carry.
#[derive(Clone, Debug, PartialEq)]
struct Emission {
    radiance: Rgb,
    /// The texture of its image (`"string filename"`), which replaces
    /// `radiance`.
    image: Option<String>,
    /// `"bool twosided"`: the back emits too.
    two_sided: bool,
    /// `"float power"` where positive, and where it was written: each
    /// shape's radiance is scaled so that it emits this much.
    power: Option<(f32, SourceLoc)>,
    loc: SourceLoc,
}

impl Emission {
    /// What the emitting material's emission is.
    fn source(&self) -> ColorSource {
        match &self.image {
            Some(name) => ColorSource::Texture(name.clone()),
            None => ColorSource::Rgb(self.radiance),
        }
    }
}

/// The graphics state that `AttributeBegin`/`AttributeEnd` save and
/// restore (pbrt-v4 `BasicSceneBuilder::GraphicsState`).
#[derive(Clone, Debug)]
struct GraphicsState {
    /// The current transform at the first of the `TransformTimes`.
    ctm: Mat4,
    /// The current transform at the second (pbrt-v4 keeps the pair as a
    /// `TransformSet`); it differs from `ctm` where things move.
    ctm_end: Mat4,
    /// Which of the two transform directives change (`ActiveTransform`):
    /// the start's, the end's.
    active: [bool; 2],
    reverse_orientation: bool,
    material: MatRef,
    area_light: Option<Emission>,
    /// The media inside and outside the shapes now made (description
    /// names; `None`: vacuum), from `MediumInterface`.
    media: (Option<String>, Option<String>),
    /// Default parameters from `Attribute "shape"|"light"|"material"|"medium"|"texture"`.
    attributes: HashMap<&'static str, Vec<Param>>,
    /// The space of the RGB values given from here on (`ColorSpace`).
    color_space: ColorSpace,
}

impl Default for GraphicsState {
    fn default() -> Self {
        GraphicsState {
            ctm: Mat4::IDENTITY,
            ctm_end: Mat4::IDENTITY,
            active: [true, true],
            reverse_orientation: false,
            material: MatRef::Default,
            area_light: None,
            media: (None, None),
            attributes: HashMap::new(),
            color_space: ColorSpace::Srgb,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Block {
    Attribute,
    Object,
}

impl Block {
    /// The directive that opens the block.
    fn opener(&self) -> &'static str {
        match self {
            Block::Attribute => "AttributeBegin",
            Block::Object => "ObjectBegin",
        }
    }
}

/// A material as read, before names are resolved.
#[derive(Clone, Debug)]
struct MatDef {
    /// The name given to trazo.
    name: String,
    kind: MatKind,
    locs: Locs,
    /// Texture names it uses, with where they were written.
    tex_refs: Vec<(String, SourceLoc)>,
    /// Its `"string normalmap"` image, as a texture.
    normal_map: Option<ColorSource>,
    /// Its `"texture displacement"`, as a bump map.
    bump_map: Option<BumpMapDesc>,
    /// Roughness from float textures (conductors and dielectrics).
    roughness_map: Option<RoughnessMapDesc>,
    /// A `subsurface` material's medium below its dielectric surface.
    subsurface: Option<SubsurfaceMedium>,
}

/// The homogeneous medium of a pbrt `subsurface` material, its
/// coefficients already multiplied by its `scale`.
#[derive(Clone, Debug)]
struct SubsurfaceMedium {
    sigma_a: Rgb,
    sigma_s: Rgb,
    g: f32,
    loc: SourceLoc,
}

#[derive(Clone, Debug)]
enum MatKind {
    Desc(MaterialKindDesc),
    /// pbrt's `mix` of two named materials: the second with probability
    /// `amount` at each point.
    Mix {
        names: [String; 2],
        amount: ColorSource,
        loc: SourceLoc,
    },
}

/// A shape waiting for its material to be resolved.
#[derive(Clone, Debug)]
struct PendingShape {
    desc: ShapeDesc,
    /// Analytic shapes (sphere, disk, cylinder) flip their normal under a
    /// mirroring transform in pbrt; triangles keep theirs.
    analytic: bool,
    reverse: bool,
    mat: MatRef,
    emission: Option<Emission>,
    /// pbrt-v4's `alpha` (a number below 1 or a float texture): trazo's
    /// opacity mask on the shape's material.
    alpha: Option<ColorSource>,
}

/// An `ObjectBegin` … `ObjectEnd` definition.
#[derive(Clone, Debug)]
struct ObjectDef {
    loc: SourceLoc,
    shapes: Vec<PendingShape>,
    meshes: Vec<MeshDesc>,
}

/// The camera as declared, converted when the film is known (at `WorldBegin`).
#[derive(Clone, Debug)]
struct CameraDef {
    kind: String,
    params: ParamList,
    /// The CTM at `Camera`: camera-from-world.
    ctm: Mat4,
    /// The same at the second of the `TransformTimes` (a moving camera).
    ctm_end: Mat4,
    loc: Option<SourceLoc>,
    /// The folder of the file it is in, relative to the top file's
    /// (a realistic camera's lens file is found from it).
    dir_rel: PathBuf,
}

/// The reader's state while it walks the files.
struct Parser {
    desc: SceneDesc,
    top_dir: PathBuf,
    /// Canonical paths of the files being read, outermost first.
    open_files: Vec<PathBuf>,
    /// The folder, relative to the top file's, of the file that holds the
    /// directive being read: spectrum files that its parameters name are
    /// found from it.
    directive_dir: Arc<Path>,
    /// Where `WorldBegin` was.
    world: Option<SourceLoc>,
    gs: GraphicsState,
    pushed: Vec<(GraphicsState, Block, SourceLoc)>,
    /// Named coordinate systems: the transforms at both times.
    named_coords: HashMap<String, (Mat4, Mat4)>,
    camera: CameraDef,
    /// ISO of the film: exposure multiplies by ISO/100 (pbrt-v4 `PixelSensor`).
    film_iso: f32,
    /// The film's diagonal in millimetres (`Film` `diagonal`, 35), which a
    /// realistic camera's image spans.
    film_diagonal_mm: f32,
    materials: Vec<MatDef>,
    named_materials: HashMap<String, usize>,
    spectrum_textures: HashMap<String, SourceLoc>,
    float_textures: HashSet<String>,
    /// Float textures trazo reads: pbrt's name → (the desc texture's name,
    /// its typical value).
    float_texture_descs: HashMap<String, (String, f32)>,
    /// A colour that stands for each spectrum texture where only a constant
    /// can be used.
    texture_colors: HashMap<String, Rgb>,
    shapes: Vec<PendingShape>,
    current_object: Option<(String, ObjectDef)>,
    objects: HashMap<String, ObjectDef>,
    /// Each `ObjectInstance`: the object's name, the transforms at both
    /// times, where it was.
    instance_uses: Vec<(String, (Mat4, Mat4), SourceLoc)>,
    /// Where the infinite light that set the background was declared.
    infinite_light: Option<SourceLoc>,
    /// `TransformTimes`: the times of the two transforms (pbrt-v4's
    /// default 0 and 1).
    transform_times: (f32, f32),
    /// `pushed` may not shrink below this inside an `Import`ed file.
    import_floor: usize,
    /// How often each warning text (without its position) was given, and
    /// where first.
    warning_counts: HashMap<String, (usize, SourceLoc)>,
    /// Media by pbrt name: their descriptions' names.
    media_names: HashMap<String, String>,
    /// Media declared with a type trazo does not render.
    unsupported_media: HashSet<String>,
    /// Whether the integrator asked for is `volpath` (pbrt's default),
    /// which renders media if the scene has any.
    volpath: bool,
    /// `Integrator "mlt"`'s mutations per pixel, which stand for the
    /// sampler's samples per pixel wherever the sampler is declared.
    mlt_mutations: Option<u32>,
    /// Whether the sampler is pbrt-v4's `sobol`, which its `function`
    /// integrator refuses.
    sobol_sampler: bool,
}

fn det3(m: &Mat4) -> f32 {
    Mat3::from_mat4(*m).determinant()
}

impl Parser {
    fn new(file: Arc<Path>) -> Parser {
        let top_dir = file.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut desc = SceneDesc {
            source: Some(file),
            ..SceneDesc::default()
        };
        // pbrt-v4's defaults (scene.cpp, film.cpp, samplers.cpp, filters.cpp):
        // 1280×720, 16 samples per pixel of the Owen-scrambled ZSobol
        // sampler, volpath with maxdepth 5, Gaussian filter of radius 1.5
        // and σ 0.5.
        desc.settings.width = 1280;
        desc.settings.height = 720;
        desc.settings.spp = 16;
        desc.settings.max_depth = 6;
        desc.settings.integrator = IntegratorKind::Path;
        desc.settings.sampling = PathSampling::Mis;
        desc.settings.sampler = SamplerKind::Sobol;
        desc.settings.filter = Filter::Gaussian {
            stddev: 0.5,
            radius: 1.5,
        };
        Parser {
            desc,
            top_dir,
            open_files: Vec::new(),
            directive_dir: Arc::from(Path::new("")),
            world: None,
            gs: GraphicsState::default(),
            pushed: Vec::new(),
            named_coords: HashMap::new(),
            camera: CameraDef {
                kind: "perspective".into(),
                params: ParamList::default(),
                ctm: Mat4::IDENTITY,
                ctm_end: Mat4::IDENTITY,
                loc: None,
                dir_rel: PathBuf::new(),
            },
            film_iso: 100.0,
            film_diagonal_mm: 35.0,
            materials: Vec::new(),
            named_materials: HashMap::new(),
            spectrum_textures: HashMap::new(),
            float_textures: HashSet::new(),
            float_texture_descs: HashMap::new(),
            texture_colors: HashMap::new(),
            shapes: Vec::new(),
            current_object: None,
            objects: HashMap::new(),
            instance_uses: Vec::new(),
            infinite_light: None,
            transform_times: (0.0, 1.0),
            import_floor: 0,
            warning_counts: HashMap::new(),
            media_names: HashMap::new(),
            unsupported_media: HashSet::new(),
            volpath: true,
            mlt_mutations: None,
            sobol_sampler: false,
        }
    }

    /// Adds a warning `loc: what is status: how`.
    fn warn(&mut self, loc: &SourceLoc, what: impl Display, status: &str, how: impl Display) {
        let message = format!("{what} is {status}: {how}");
        let count = self.warning_counts.entry(message.clone()).or_insert((0, loc.clone()));
        count.0 += 1;
        // Large scenes repeat the same thing thousands of times; the
        // repeats are counted in one summary line instead.
        if count.0 <= MAX_SAME_WARNING {
            self.desc.warnings.push(format!("{loc}: {message}"));
        }
    }

    fn unsupported(&mut self, loc: &SourceLoc, what: impl Display, how: impl Display) {
        self.warn(loc, what, "unsupported", how);
    }

    fn approximated(&mut self, loc: &SourceLoc, what: impl Display, how: impl Display) {
        self.warn(loc, what, "approximated", how);
    }

    /// Warns about every parameter of `directive` that nothing read.
    fn report_unused(&mut self, params: &ParamList, directive: &str) {
        let unused: Vec<(SourceLoc, String)> = params.unused().map(|p| (p.loc.clone(), p.written.clone())).collect();
        for (loc, written) in unused {
            self.unsupported(&loc, format!("parameter \"{written}\" of {directive}"), "ignored");
        }
    }

    /// Marks every parameter as read (after one warning about the whole
    /// directive).
    fn use_all(params: &ParamList) {
        for p in &params.items {
            p.used.set(true);
        }
    }

    /// The directive's parameters followed by the `Attribute` defaults for
    /// `target`.
    fn with_attributes(&self, mut params: ParamList, target: &str) -> ParamList {
        if let Some(extra) = self.gs.attributes.get(target) {
            params.items.extend(extra.iter().cloned());
        }
        params
    }

    fn concat(&mut self, m: Mat4) {
        if self.gs.active[0] {
            self.gs.ctm *= m;
        }
        if self.gs.active[1] {
            self.gs.ctm_end *= m;
        }
    }

    fn set_ctm(&mut self, (start, end): (Mat4, Mat4)) {
        if self.gs.active[0] {
            self.gs.ctm = start;
        }
        if self.gs.active[1] {
            self.gs.ctm_end = end;
        }
    }

    /// Whether the current transform differs between the two times.
    fn ctm_moves(&self) -> bool {
        self.gs.ctm != self.gs.ctm_end
    }

    /// The current transform's motion for a shape made now, if it moves.
    fn motion(&self) -> Option<MotionDesc> {
        self.ctm_moves().then(|| MotionDesc {
            end: vec![TransformOp::Matrix(self.gs.ctm_end)],
            times: self.transform_times,
        })
    }

    /// Warns that `what`, made while the transform moves, stays where it is
    /// at the start (pbrt-v4 does the same for lights and media).
    fn warn_if_moving(&mut self, loc: &SourceLoc, what: &str) {
        if self.ctm_moves() {
            self.unsupported(
                loc,
                format!("motion of a {what}"),
                "it does not move; it stays where the transform puts it at the start time",
            );
        }
    }

    fn in_world(&self, lx: &Lexer, offset: usize, directive: &str) -> Result<()> {
        if self.world.is_none() {
            return Err(Error::scene(
                Some(lx.loc(offset)),
                directive,
                "must come after WorldBegin (the scene description is inside the world block)",
            ));
        }
        Ok(())
    }

    fn in_options(&self, lx: &Lexer, offset: usize, directive: &str) -> Result<()> {
        if let Some(w) = &self.world {
            return Err(Error::scene(
                Some(lx.loc(offset)),
                directive,
                format!("is a rendering option and must come before WorldBegin (at {w})"),
            ));
        }
        Ok(())
    }

    /// A path written in the file being read (whose folder is `dir_rel`,
    /// relative to the main file's folder), relative to the main file's
    /// folder. Relative names are looked up next to the file that names
    /// them, then (as pbrt-v4's `ResolveFilename` does) next to the main file.
    /// The float textures that displace meshes (`plymesh` `displacement`),
    /// placed or in objects.
    fn displacement_heights(&self) -> Vec<String> {
        let shapes = self.shapes.iter().filter_map(|s| match &s.desc.kind {
            ShapeKind::InlineMesh(src) => Some(src),
            _ => None,
        });
        shapes
            .chain(self.desc.meshes.iter().map(|m| &m.source))
            .filter_map(|src| match src {
                MeshSource::Displaced { height, .. } => Some(height.clone()),
                _ => None,
            })
            .collect()
    }

    fn resolve(&self, dir_rel: &Path, name: &str) -> PathBuf {
        let p = Path::new(name);
        if p.is_absolute() || dir_rel.as_os_str().is_empty() {
            return p.to_path_buf();
        }
        let local = dir_rel.join(p);
        if !self.top_dir.join(&local).exists() && self.top_dir.join(p).exists() {
            return p.to_path_buf();
        }
        local
    }

    /// Reads the directives of one file and of the files it includes.
    fn parse_file(&mut self, lx: &mut Lexer) -> Result<()> {
        while let Some(t) = lx.next()? {
            // The directives before this one are done with: the included
            // files they finished can go.
            lx.release();
            let Tok::Word(name) = &t.tok else {
                return Err(lx.error(t.offset, format!("expected a directive, found {}", t.describe())));
            };
            // Names are resolved from the folder of the file that holds the
            // directive.
            let dir_rel = lx.dir_of(t.offset);
            self.directive_dir = dir_rel.clone();
            self.directive(lx, name, t.offset, &dir_rel)?;
        }
        Ok(())
    }

    fn directive(&mut self, lx: &mut Lexer, name: &str, offset: usize, dir_rel: &Path) -> Result<()> {
        let loc = lx.loc(offset);
        match name {
            "AttributeBegin" | "TransformBegin" => {
                // pbrt-v4 treats TransformBegin as AttributeBegin; pbrt-v3
                // files use it before WorldBegin too, which is accepted.
                if name == "AttributeBegin" {
                    self.in_world(lx, offset, name)?;
                }
                self.pushed.push((self.gs.clone(), Block::Attribute, loc));
            }
            "AttributeEnd" | "TransformEnd" => {
                if name == "AttributeEnd" {
                    self.in_world(lx, offset, name)?;
                }
                let popped = if self.pushed.len() > self.import_floor {
                    self.pushed.pop()
                } else {
                    None
                };
                match popped {
                    Some((state, Block::Attribute, _)) => self.gs = state,
                    Some((_, Block::Object, open)) => {
                        return Err(Error::scene(
                            Some(loc),
                            name,
                            format!("closes the ObjectBegin at {open}; use ObjectEnd"),
                        ));
                    }
                    None => {
                        return Err(Error::scene(
                            Some(loc),
                            name,
                            format!("without a matching {}", name.replace("End", "Begin")),
                        ));
                    }
                }
            }
            "Attribute" => {
                let (target, toff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                let key = match target.as_str() {
                    "shape" => "shape",
                    "light" => "light",
                    "material" => "material",
                    "medium" => "medium",
                    "texture" => "texture",
                    _ => {
                        return Err(lx.error(
                            toff,
                            format!(
                                "unknown Attribute target \"{target}\": expected \"shape\", \"light\", \"material\", \"medium\" or \"texture\""
                            ),
                        ));
                    }
                };
                let list = self.gs.attributes.entry(key).or_default();
                for mut p in params.items {
                    p.inherited = true;
                    list.insert(0, p);
                }
            }
            "Identity" => self.set_ctm((Mat4::IDENTITY, Mat4::IDENTITY)),
            "Translate" => {
                let v = numbers::<3>(lx, name, offset)?;
                self.concat(Mat4::from_translation(Vec3::from(v)));
            }
            "Scale" => {
                let v = numbers::<3>(lx, name, offset)?;
                self.concat(Mat4::from_scale(Vec3::from(v)));
            }
            "Rotate" => {
                let v = numbers::<4>(lx, name, offset)?;
                let axis = Vec3::new(v[1], v[2], v[3]);
                let Some(axis) = axis.try_normalize() else {
                    return Err(Error::scene(
                        Some(loc),
                        name,
                        "the rotation axis must not be the zero vector",
                    ));
                };
                self.concat(Mat4::from_axis_angle(axis, v[0].to_radians()));
            }
            "LookAt" => {
                let v = numbers::<9>(lx, name, offset)?;
                let m = look_at(
                    Vec3::new(v[0], v[1], v[2]),
                    Vec3::new(v[3], v[4], v[5]),
                    Vec3::new(v[6], v[7], v[8]),
                )
                .map_err(|m| Error::scene(Some(loc), name, m))?;
                self.concat(m);
            }
            "Transform" | "ConcatTransform" => {
                // pbrt-v4 builds a matrix from the 16 numbers row by row and
                // transposes it (scene.cpp): the numbers are the matrix
                // column by column, translation in the 13th to 15th.
                let m = Mat4::from_cols_array(&bracketed_16(lx, name, offset)?);
                if name == "Transform" {
                    self.set_ctm((m, m));
                } else {
                    self.concat(m);
                }
            }
            "CoordinateSystem" => {
                let (n, _) = quoted(lx, name, offset)?;
                self.named_coords.insert(n, (self.gs.ctm, self.gs.ctm_end));
            }
            "CoordSysTransform" => {
                let (n, _) = quoted(lx, name, offset)?;
                match self.named_coords.get(&n) {
                    Some(m) => {
                        let m = *m;
                        self.set_ctm(m);
                    }
                    None => self.unsupported(
                        &loc,
                        format!("CoordSysTransform \"{n}\""),
                        "no coordinate system of that name was defined; the transform is unchanged",
                    ),
                }
            }
            "ActiveTransform" => {
                let Some(t) = lx.next()? else {
                    return Err(Error::scene(
                        Some(loc),
                        name,
                        "needs All, StartTime or EndTime; the file ends",
                    ));
                };
                match t.tok.word() {
                    Some("All") => self.gs.active = [true, true],
                    Some("StartTime") => self.gs.active = [true, false],
                    Some("EndTime") => self.gs.active = [false, true],
                    _ => {
                        return Err(lx.error(
                            t.offset,
                            format!(
                                "ActiveTransform needs All, StartTime or EndTime, found {}",
                                t.describe()
                            ),
                        ));
                    }
                }
            }
            "TransformTimes" => {
                self.in_options(lx, offset, name)?;
                let [start, end] = numbers::<2>(lx, name, offset)?;
                if !(start.is_finite() && end.is_finite() && start < end) {
                    return Err(Error::scene(
                        Some(loc),
                        name,
                        format!("needs a start time before the end time, got {start} and {end}"),
                    ));
                }
                self.transform_times = (start, end);
            }
            "ReverseOrientation" => {
                self.in_world(lx, offset, name)?;
                self.gs.reverse_orientation = !self.gs.reverse_orientation;
            }
            "Camera" => {
                self.in_options(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(
                    lx,
                    koff,
                    "Camera",
                    &kind,
                    &["perspective", "orthographic", "realistic", "spherical"],
                )?;
                // pbrt-v4 names the camera's space "camera" (scene.cpp).
                if let Ok((inv, _)) = world_from_camera(&self.gs.ctm) {
                    let inv_end = world_from_camera(&self.gs.ctm_end).map_or(inv, |(m, _)| m);
                    self.named_coords.insert("camera".into(), (inv, inv_end));
                }
                self.camera = CameraDef {
                    kind,
                    params,
                    ctm: self.gs.ctm,
                    ctm_end: self.gs.ctm_end,
                    loc: Some(loc),
                    dir_rel: dir_rel.to_path_buf(),
                };
                // pbrt-v4: the camera is in the outside medium current here.
                self.desc.camera_medium = self.gs.media.1.clone();
            }
            "Film" => {
                self.in_options(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(lx, koff, "Film", &kind, &["rgb", "gbuffer", "spectral"])?;
                // The film writes in the colour space of its directive.
                self.desc.settings.color_space = self.gs.color_space;
                self.film(&kind, &params, &loc)?;
                self.report_unused(&params, &format!("Film \"{kind}\""));
            }
            "Sampler" => {
                self.in_options(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(
                    lx,
                    koff,
                    "Sampler",
                    &kind,
                    &[
                        "halton",
                        "independent",
                        "paddedsobol",
                        "pmj02bn",
                        "sobol",
                        "stratified",
                        "zsobol",
                    ],
                )?;
                self.sampler(&kind, &params, &loc)?;
                self.report_unused(&params, &format!("Sampler \"{kind}\""));
            }
            "Integrator" => {
                self.in_options(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(
                    lx,
                    koff,
                    "Integrator",
                    &kind,
                    &[
                        "ambientocclusion",
                        "bdpt",
                        "function",
                        "lightpath",
                        "mlt",
                        "path",
                        "randomwalk",
                        "simplepath",
                        "simplevolpath",
                        "sppm",
                        "volpath",
                    ],
                )?;
                self.integrator(&kind, &params, &loc)?;
                self.report_unused(&params, &format!("Integrator \"{kind}\""));
            }
            "PixelFilter" => {
                self.in_options(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(
                    lx,
                    koff,
                    "PixelFilter",
                    &kind,
                    &["box", "gaussian", "mitchell", "sinc", "triangle"],
                )?;
                self.pixel_filter(&kind, &params, &loc)?;
                self.report_unused(&params, &format!("PixelFilter \"{kind}\""));
            }
            "Accelerator" => {
                self.in_options(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(lx, koff, "Accelerator", &kind, &["bvh", "kdtree"])?;
                Self::use_all(&params);
                self.unsupported(
                    &loc,
                    format!("Accelerator \"{kind}\""),
                    "ignored (trazo always builds its own SAH BVH)",
                );
            }
            "ColorSpace" => {
                let (n, noff) = quoted(lx, name, offset)?;
                let Some(space) = ColorSpace::from_pbrt_name(&n) else {
                    return Err(lx.error(
                        noff,
                        format!(
                            "unknown colour space \"{n}\"{}",
                            suggest(&n, ColorSpace::PBRT_NAMES.iter().copied())
                        ),
                    ));
                };
                self.gs.color_space = space;
            }
            "Option" => {
                let (n, _) = quoted(lx, name, offset)?;
                let Some(v) = lx.next()? else {
                    return Err(Error::scene(Some(loc), name, "needs a value; the file ends"));
                };
                let value = match &v.tok {
                    Tok::Word(w) => w.to_string(),
                    Tok::Str(s) => s.to_string(),
                    _ => return Err(lx.error(v.offset, format!("Option needs a value, found {}", v.describe()))),
                };
                match (n.as_str(), value.parse::<u64>()) {
                    ("seed", Ok(seed)) => self.desc.settings.seed = seed,
                    _ => self.unsupported(&loc, format!("Option \"{n}\""), "ignored"),
                }
            }
            "WorldBegin" => {
                if let Some(first) = &self.world {
                    return Err(Error::scene(
                        Some(loc),
                        name,
                        format!("appears a second time (the first is at {first})"),
                    ));
                }
                self.world = Some(loc);
                self.gs.ctm = Mat4::IDENTITY;
                self.gs.ctm_end = Mat4::IDENTITY;
                self.gs.active = [true, true];
                self.named_coords
                    .insert("world".into(), (Mat4::IDENTITY, Mat4::IDENTITY));
                self.finish_options()?;
            }
            "WorldEnd" => {
                self.unsupported(
                    &loc,
                    "WorldEnd (pbrt-v3 syntax)",
                    "ignored; pbrt-v4 ends the world at the end of the file",
                );
            }
            "Include" | "Import" => {
                let (file, foff) = quoted(lx, name, offset)?;
                if name == "Import" {
                    self.in_world(lx, offset, name)?;
                }
                let floc = lx.loc(foff);
                self.include(lx, &file, &floc, dir_rel, name == "Import")?;
            }
            "Shape" => {
                self.in_world(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(
                    lx,
                    koff,
                    "Shape",
                    &kind,
                    &[
                        "bilinearmesh",
                        "cone",
                        "curve",
                        "cylinder",
                        "disk",
                        "hyperboloid",
                        "loopsubdiv",
                        "paraboloid",
                        "plymesh",
                        "sphere",
                        "trianglemesh",
                    ],
                )?;
                let params = self.with_attributes(params, "shape");
                self.shape(&kind, &params, loc, dir_rel)?;
                self.report_unused(&params, &format!("Shape \"{kind}\""));
            }
            "Material" => {
                self.in_world(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(lx, koff, "Material", &kind, materials::MATERIAL_TYPES)?;
                let params = self.with_attributes(params, "material");
                let n = self.materials.len();
                let def = self.material(&kind, &params, &loc, format!("{kind}#{n}"), dir_rel)?;
                self.report_unused(&params, &format!("Material \"{kind}\""));
                self.materials.push(def);
                self.gs.material = MatRef::Index(n);
            }
            "MakeNamedMaterial" => {
                self.in_world(lx, offset, name)?;
                let (mname, moff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                let params = self.with_attributes(params, "material");
                if let Some(&i) = self.named_materials.get(&mname) {
                    let first = self.materials[i]
                        .locs
                        .item
                        .clone()
                        .map(|l| l.to_string())
                        .unwrap_or_default();
                    return Err(lx.error(
                        moff,
                        format!("the named material \"{mname}\" is already defined (at {first})"),
                    ));
                }
                let Some((kind, kp)) = params.string("type")? else {
                    return Err(lx.error(
                        moff,
                        format!("MakeNamedMaterial \"{mname}\" needs a \"string type\" parameter"),
                    ));
                };
                if !materials::MATERIAL_TYPES.contains(&kind.as_str()) {
                    return Err(kp.err(format!(
                        "unknown material type \"{kind}\"{}",
                        suggest(&kind, materials::MATERIAL_TYPES.iter().copied())
                    )));
                }
                let def = self.material(&kind, &params, &loc, mname.clone(), dir_rel)?;
                self.report_unused(&params, &format!("MakeNamedMaterial \"{mname}\""));
                self.named_materials.insert(mname, self.materials.len());
                self.materials.push(def);
            }
            "NamedMaterial" => {
                self.in_world(lx, offset, name)?;
                let (mname, moff) = quoted(lx, name, offset)?;
                self.gs.material = MatRef::Named(mname, lx.loc(moff));
            }
            "Texture" => {
                self.in_world(lx, offset, name)?;
                let (tname, noff) = quoted(lx, name, offset)?;
                let (ttype, toff) = quoted(lx, name, offset)?;
                let (class, coff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                if !matches!(ttype.as_str(), "spectrum" | "float" | "color") {
                    return Err(lx.error(
                        toff,
                        format!("texture type \"{ttype}\" is unknown: it must be \"float\" or \"spectrum\""),
                    ));
                }
                check_kind(lx, coff, "Texture", &class, materials::TEXTURE_CLASSES)?;
                let params = self.with_attributes(params, "texture");
                let nloc = lx.loc(noff);
                self.texture(&tname, &ttype, &class, &params, &loc, &nloc, dir_rel)?;
                self.report_unused(&params, &format!("Texture \"{tname}\""));
            }
            "LightSource" => {
                self.in_world(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(
                    lx,
                    koff,
                    "LightSource",
                    &kind,
                    &["distant", "goniometric", "infinite", "point", "projection", "spot"],
                )?;
                let params = self.with_attributes(params, "light");
                self.warn_if_moving(&loc, "light");
                self.light_source(&kind, &params, &loc, dir_rel)?;
                self.report_unused(&params, &format!("LightSource \"{kind}\""));
            }
            "AreaLightSource" => {
                self.in_world(lx, offset, name)?;
                let (kind, koff) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                check_kind(lx, koff, "AreaLightSource", &kind, &["diffuse"])?;
                let params = self.with_attributes(params, "light");
                self.area_light_source(&params, &loc, dir_rel)?;
                self.report_unused(&params, &format!("AreaLightSource \"{kind}\""));
            }
            "MakeNamedMedium" => {
                let (mname, _) = quoted(lx, name, offset)?;
                let params = parse_params(lx)?;
                let params = self.with_attributes(params, "medium");
                self.warn_if_moving(&loc, "medium");
                self.make_named_medium(&mname, &params, &loc, dir_rel)?;
                self.report_unused(&params, &format!("MakeNamedMedium \"{mname}\""));
            }
            "MediumInterface" => {
                // One name: the same medium on both sides.
                let (inside, _) = quoted(lx, name, offset)?;
                let mut outside = inside.clone();
                if let Some(t) = lx.peek()? {
                    if let Tok::Str(s) = &t.tok {
                        outside = s.to_string();
                        lx.next()?;
                    }
                }
                let inside = self.medium_name(&inside, &loc)?;
                let outside = self.medium_name(&outside, &loc)?;
                self.gs.media = (inside, outside);
            }
            "ObjectBegin" => {
                self.in_world(lx, offset, name)?;
                let (oname, ooff) = quoted(lx, name, offset)?;
                if let Some((open, _)) = &self.current_object {
                    return Err(lx.error(
                        offset,
                        format!("ObjectBegin \"{oname}\" inside the definition of object \"{open}\""),
                    ));
                }
                if let Some(def) = self.objects.get(&oname) {
                    return Err(lx.error(
                        ooff,
                        format!("the object \"{oname}\" is already defined (at {})", def.loc),
                    ));
                }
                self.pushed.push((self.gs.clone(), Block::Object, loc.clone()));
                self.current_object = Some((
                    oname,
                    ObjectDef {
                        loc,
                        shapes: Vec::new(),
                        meshes: Vec::new(),
                    },
                ));
            }
            "ObjectEnd" => {
                self.in_world(lx, offset, name)?;
                let open = self.pushed.last().filter(|_| self.pushed.len() > self.import_floor);
                match open {
                    Some((_, Block::Object, _)) => {
                        let (state, _, _) = self.pushed.pop().expect("checked");
                        self.gs = state;
                        let (oname, def) = self.current_object.take().expect("an object is open");
                        self.objects.insert(oname, def);
                    }
                    Some((_, Block::Attribute, open)) => {
                        return Err(Error::scene(
                            Some(loc),
                            name,
                            format!("the AttributeBegin at {open} is still open"),
                        ));
                    }
                    None => return Err(Error::scene(Some(loc), name, "without a matching ObjectBegin")),
                }
            }
            "ObjectInstance" => {
                self.in_world(lx, offset, name)?;
                let (oname, ooff) = quoted(lx, name, offset)?;
                if let Some((open, _)) = &self.current_object {
                    return Err(lx.error(
                        offset,
                        format!("ObjectInstance inside the definition of object \"{open}\""),
                    ));
                }
                self.instance_uses
                    .push((oname, (self.gs.ctm, self.gs.ctm_end), lx.loc(ooff)));
            }
            _ => {
                return Err(Error::scene(
                    Some(loc),
                    name,
                    format!("unknown directive{}", suggest(name, DIRECTIVES.iter().copied())),
                ));
            }
        }
        Ok(())
    }

    /// `Include` (token-level inclusion, pbrt-v4 parser.cpp: the included
    /// file's tokens take the place of the directive, so a statement may
    /// continue after it) or `Import` (a file read on its own, whose
    /// graphics state does not leak out of it).
    fn include(&mut self, lx: &mut Lexer, name: &str, loc: &SourceLoc, dir_rel: &Path, import: bool) -> Result<()> {
        let what = if import { "Import" } else { "Include" };
        let rel = self.resolve(dir_rel, name);
        let full = self.top_dir.join(&rel);
        let canon = std::fs::canonicalize(&full).map_err(|e| {
            Error::scene(
                Some(loc.clone()),
                what,
                format!("cannot read {}: {}", full.display(), io_reason(&e)),
            )
        })?;
        // The files being read: those of the imports around this lexer, then
        // the files this lexer is inside.
        let open: Vec<PathBuf> = self.open_files.iter().chain(lx.open_includes()).cloned().collect();
        if let Some(i) = open.iter().position(|f| *f == canon) {
            let chain: Vec<String> = open[i..]
                .iter()
                .chain(std::iter::once(&canon))
                .map(|p| {
                    p.file_name()
                        .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
                })
                .collect();
            return Err(Error::scene(
                Some(loc.clone()),
                what,
                format!("include loop: {}", chain.join(" → ")),
            ));
        }
        if open.len() >= MAX_INCLUDE_DEPTH {
            return Err(Error::scene(
                Some(loc.clone()),
                what,
                format!("files are included more than {MAX_INCLUDE_DEPTH} levels deep"),
            ));
        }
        let text = read_text(&full, Some(loc))?;
        let sub_dir: Arc<Path> = Arc::from(rel.parent().unwrap_or(Path::new("")));
        let file: Arc<Path> = Arc::from(full.as_path());
        if !import {
            lx.include(file, text, sub_dir, canon);
            return Ok(());
        }
        let outer_files = self.open_files.len();
        self.open_files = open;
        self.open_files.push(canon);
        let (gs, depth, floor) = (self.gs.clone(), self.pushed.len(), self.import_floor);
        self.import_floor = self.pushed.len();
        let mut sub = Lexer::new(file, &text, sub_dir);
        self.parse_file(&mut sub)?;
        if let Some((_, block, open)) = self.pushed.get(depth) {
            let what = block.opener();
            return Err(Error::scene(
                Some(open.clone()),
                what,
                "is not closed before the end of the imported file",
            ));
        }
        self.gs = gs;
        self.import_floor = floor;
        self.open_files.truncate(outer_files);
        Ok(())
    }

    /// The location of the main file's start (for defaults that no
    /// directive wrote).
    fn desc_loc(&self) -> SourceLoc {
        SourceLoc {
            file: self.desc.source.clone().unwrap_or_else(|| Arc::from(Path::new(""))),
            line: 1,
            column: 1,
        }
    }

    /// Adds a shape to the world or to the object being defined.
    fn add_shape(&mut self, mut shape: PendingShape) {
        if let Some((oname, def)) = &mut self.current_object {
            if let ShapeKind::InlineMesh(src) = &shape.desc.kind {
                let name = format!("{oname}/{}", def.meshes.len());
                def.meshes.push(MeshDesc {
                    name: name.clone(),
                    source: src.clone(),
                    locs: shape.desc.locs.clone(),
                });
                shape.desc.kind = ShapeKind::Mesh(name);
            }
            def.shapes.push(shape);
        } else {
            self.shapes.push(shape);
        }
    }

    /// Resolves names, places instances and validates.
    fn finish(&mut self, end: SourceLoc) -> Result<()> {
        if self.world.is_none() {
            return Err(Error::scene(
                Some(end),
                "WorldBegin",
                "the file ends before WorldBegin: a pbrt scene needs a world block",
            ));
        }
        if let Some((_, block, open)) = self.pushed.last() {
            let what = block.opener();
            return Err(Error::scene(
                Some(open.clone()),
                what,
                format!(
                    "is never closed (the file ends first); add {}",
                    what.replace("Begin", "End")
                ),
            ));
        }

        // Instances: each shape of the object, placed by the CTM of the
        // instance (pbrt-v4: render-from-instance × the shape's own CTM).
        let uses = std::mem::take(&mut self.instance_uses);
        let mut used_objects: HashSet<String> = HashSet::new();
        for (oname, (ctm, ctm_end), loc) in uses {
            let Some(def) = self.objects.get(&oname) else {
                return Err(Error::scene(
                    Some(loc),
                    "ObjectInstance",
                    format!(
                        "no object named \"{oname}\"{}",
                        suggest(&oname, self.objects.keys().map(String::as_str))
                    ),
                ));
            };
            for s in &def.shapes {
                let mut s = s.clone();
                // A moving instance moves its shapes; a shape that moves
                // inside the object moves by its own motion, then the
                // instance's.
                if ctm != ctm_end || s.desc.motion.is_some() {
                    let motion = s.desc.motion.get_or_insert_with(|| MotionDesc {
                        end: s.desc.transform.clone(),
                        times: self.transform_times,
                    });
                    motion.end.push(TransformOp::Matrix(ctm_end));
                }
                s.desc.transform.push(TransformOp::Matrix(ctm));
                self.shapes.push(s);
            }
            used_objects.insert(oname);
        }
        let mut objects: Vec<(String, ObjectDef)> = std::mem::take(&mut self.objects).into_iter().collect();
        objects.sort_by_key(|a| (a.1.loc.file.clone(), a.1.loc.line, a.1.loc.column));
        for (oname, def) in objects {
            if used_objects.contains(&oname) {
                self.desc.meshes.extend(def.meshes);
            } else {
                self.unsupported(
                    &def.loc,
                    format!("object \"{oname}\""),
                    "it is never placed by ObjectInstance, so nothing is rendered",
                );
            }
        }

        // Float textures that no roughness, bump map or mix reads are not
        // loaded.
        let read_floats: HashSet<String> = self
            .materials
            .iter()
            .flat_map(|m| {
                // A coated conductor's own map sits in its base.
                let base_map = match &m.kind {
                    MatKind::Desc(MaterialKindDesc::Layered {
                        base: LayeredBaseDesc::Conductor { roughness_map, .. },
                        ..
                    }) => roughness_map.as_ref(),
                    _ => None,
                };
                let roughness = m.roughness_map.iter().chain(base_map).flat_map(|r| [&r.u, &r.v]);
                let amount = match &m.kind {
                    MatKind::Mix { amount, .. } => Some(amount),
                    MatKind::Desc(_) => None,
                };
                roughness.chain(m.bump_map.iter().map(|b| &b.height)).chain(amount)
            })
            .chain(self.shapes.iter().filter_map(|s| s.alpha.as_ref()))
            .filter_map(|c| match c {
                ColorSource::Texture(t) => Some(t.clone()),
                ColorSource::Rgb(_) => None,
            })
            .chain(self.displacement_heights())
            .collect();
        // Float textures (and their parts) that nothing reads are not
        // loaded; a texture kept keeps its inputs, which are made before it.
        let float_names: HashSet<&String> = self.float_texture_descs.values().map(|(n, _)| n).collect();
        let droppable = |name: &String| float_names.contains(name) || name.starts_with("\0\0float texture ");
        let mut read_floats = read_floats;
        for t in self.desc.textures.iter().rev() {
            if let (TextureKind::Node(node), true) = (&t.kind, !droppable(&t.name) || read_floats.contains(&t.name)) {
                for (_, input) in node.inputs() {
                    if let ColorSource::Texture(n) = input {
                        read_floats.insert(n.clone());
                    }
                }
            }
        }
        self.desc
            .textures
            .retain(|t| !droppable(&t.name) || read_floats.contains(&t.name));

        // Texture references of materials.
        for m in &self.materials {
            for (t, loc) in &m.tex_refs {
                if !self.spectrum_textures.contains_key(t) {
                    let hint = if self.float_textures.contains(t) {
                        " (a float texture of that name exists, but a colour needs a spectrum texture)".to_string()
                    } else {
                        suggest(t, self.spectrum_textures.keys().map(String::as_str))
                    };
                    return Err(Error::scene(
                        Some(loc.clone()),
                        "texture",
                        format!("no texture named \"{t}\"{hint}"),
                    ));
                }
            }
        }

        // Materials: each used (material, emission) pair becomes one of
        // trazo's materials; named materials are all kept.
        let mut names: HashSet<String> = HashSet::new();
        // (material, emitted radiance's bits, whether both sides emit and
        // its image, the alpha's bits or texture).
        type Made = (Option<usize>, Option<([u32; 3], bool, Option<String>)>, Option<String>);
        let mut made: HashMap<Made, String> = HashMap::new();
        let mut named: Vec<(usize, String)> = self.named_materials.iter().map(|(n, &i)| (i, n.clone())).collect();
        named.sort();
        for (i, n) in named {
            let base = self.resolve_material(i)?;
            let name = unique_name(&mut names, n);
            let m = self.material_desc(base, None, name.clone());
            self.desc.materials.push(m);
            if base == i {
                made.insert((Some(i), None, None), name);
            }
        }
        let shapes = std::mem::take(&mut self.shapes);
        let mut subsurface_media: HashMap<usize, String> = HashMap::new();
        for mut s in shapes {
            let index = match &s.mat {
                MatRef::Default => None,
                MatRef::Index(i) => Some(*i),
                MatRef::Named(n, loc) => match self.named_materials.get(n) {
                    Some(&i) => Some(i),
                    None => {
                        return Err(Error::scene(
                            Some(loc.clone()),
                            "NamedMaterial",
                            format!(
                                "no material named \"{n}\"{}",
                                suggest(n, self.named_materials.keys().map(String::as_str))
                            ),
                        ));
                    }
                },
            };
            let index = match index {
                Some(i) => Some(self.resolve_material(i)?),
                None => None,
            };
            // A subsurface material's shapes hold its medium, which
            // pbrt-v4's volpath (alone) scatters light in.
            let subsurface = index.and_then(|i| self.materials[i].subsurface.clone().map(|m| (i, m)));
            if let (Some((i, medium)), true) = (subsurface, self.volpath) {
                let name = match subsurface_media.get(&i) {
                    Some(n) => n.clone(),
                    None => {
                        let n = format!("\u{0}subsurface {}", self.materials[i].name);
                        let sigma_t = medium.sigma_a + medium.sigma_s;
                        let albedo = Rgb::select(sigma_t.cmpgt(Rgb::ZERO), medium.sigma_s / sigma_t, Rgb::ZERO);
                        self.desc.media.push(MediumDesc {
                            name: n.clone(),
                            sigma_t: FieldDesc::Constant(sigma_t),
                            albedo: FieldDesc::Constant(albedo),
                            emission: None,
                            scale: Rgb::ONE,
                            g: medium.g,
                            locs: Locs::at(Some(medium.loc.clone())),
                        });
                        subsurface_media.insert(i, n.clone());
                        n
                    }
                };
                let outside = s.desc.media.as_ref().and_then(|m| m.outside.clone());
                s.desc.media = Some(MediumInterfaceDesc {
                    inside: Some(name),
                    outside,
                });
            }
            let key = (
                index,
                s.emission
                    .as_ref()
                    .map(|e| (e.radiance.to_array().map(f32::to_bits), e.two_sided, e.image.clone())),
                s.alpha.as_ref().map(|a| match a {
                    ColorSource::Rgb(c) => format!("{}", c.x.to_bits()),
                    ColorSource::Texture(t) => format!("texture {t}"),
                }),
            );
            let name = match made.get(&key) {
                Some(n) => n.clone(),
                None => {
                    let base_name =
                        index.map_or("diffuse (pbrt default)".to_string(), |i| self.materials[i].name.clone());
                    let base_name = match &s.emission {
                        Some(_) => format!("{base_name} + area light"),
                        None => base_name,
                    };
                    let name = match &s.alpha {
                        Some(_) => unique_name(&mut names, format!("{base_name} + alpha")),
                        None => unique_name(&mut names, base_name),
                    };
                    let m = match index {
                        Some(i) => self.material_desc(i, s.emission.as_ref(), name.clone()),
                        None => {
                            let mut m = MaterialDesc::with_kind(
                                name.clone(),
                                MaterialKindDesc::Diffuse {
                                    reflectance: ColorSource::Rgb(Rgb::splat(0.5)),
                                },
                            );
                            if let Some(e) = &s.emission {
                                m.emission = e.source();
                                m.emits_both_sides = e.two_sided;
                                m.locs = Locs::at(Some(e.loc.clone()));
                            }
                            m
                        }
                    };
                    let mut m = m;
                    m.opacity = s.alpha.clone();
                    self.desc.materials.push(m);
                    made.insert(key, name.clone());
                    name
                }
            };
            let mut desc = s.desc;
            desc.material = Some(name);
            let total = desc.transform.iter().fold(Mat4::IDENTITY, |acc, op| match op {
                TransformOp::Matrix(m) => *m * acc,
                _ => acc,
            });
            // pbrt-v4 flips the normal of quadrics when the transform
            // mirrors (shapes.h: reverseOrientation ^ transformSwapsHandedness);
            // triangles, whose normal comes from the transformed vertices,
            // keep the side they face in object space.
            desc.flip_normals = s.reverse ^ (s.analytic && det3(&total) < 0.0);
            self.desc.shapes.push(desc);
        }
        // pbrt's volpath is its path tracer where there are no media. Its
        // alpha cut-outs are geometry that shadow rays pass too (with
        // probability 1 − α), which trazo's volumetric path tracer does
        // with masks (in expectation, by the transmittance 1 − α), and its
        // path tracer does not.
        let any_alpha = self.desc.materials.iter().any(|m| m.opacity.is_some());
        let path = self.desc.settings.integrator == IntegratorKind::Path;
        if path && ((self.volpath && !self.desc.media.is_empty()) || any_alpha) {
            self.desc.settings.integrator = IntegratorKind::VolPath;
        }
        if let Some(m) = self.mlt_mutations {
            self.desc.settings.spp = m;
        }
        if self.desc.sampler_study.is_some() && self.sobol_sampler {
            // As pbrt-v4: the global Sobol sequence spreads a pixel's
            // samples over the image, which the study does not measure.
            return Err(Error::scene(
                self.desc.settings_locs.key("integrator"),
                "Integrator \"function\"",
                "the \"sobol\" sampler should be replaced with \"paddedsobol\" for the \"function\" integrator",
            ));
        }
        self.summarise_repeats();
        self.desc.validate()
    }

    /// Adds one line for each warning given more than [`MAX_SAME_WARNING`]
    /// times, counting the repeats not listed (once: the counts are then
    /// cleared).
    fn summarise_repeats(&mut self) {
        let mut repeated: Vec<(String, (usize, SourceLoc))> = std::mem::take(&mut self.warning_counts)
            .into_iter()
            .filter(|(_, (n, _))| *n > MAX_SAME_WARNING)
            .collect();
        repeated.sort_by(|a, b| a.0.cmp(&b.0));
        for (message, (n, first)) in repeated {
            self.desc.warnings.push(format!(
                "{first}: {message} ({} more times, not listed)",
                n - MAX_SAME_WARNING
            ));
        }
    }

    /// Follows `mix` materials to the one chosen.
    /// Material `i`, once the materials a mix names are known to exist (a
    /// mix stays a mix; loops are refused when the scene is checked).
    fn resolve_material(&self, i: usize) -> Result<usize> {
        if let MatKind::Mix { names, loc, .. } = &self.materials[i].kind {
            for name in names {
                if !self.named_materials.contains_key(name) {
                    return Err(Error::scene(
                        Some(loc.clone()),
                        "materials",
                        format!(
                            "no material named \"{name}\"{}",
                            suggest(name, self.named_materials.keys().map(String::as_str))
                        ),
                    ));
                }
            }
        }
        Ok(i)
    }

    fn material_desc(&self, i: usize, emission: Option<&Emission>, name: String) -> MaterialDesc {
        let def = &self.materials[i];
        let kind = match &def.kind {
            MatKind::Desc(k) => k.clone(),
            // Named materials keep their names in the description.
            MatKind::Mix { names, amount, .. } => MaterialKindDesc::Mix {
                choice: MixChoice::Weight(amount.clone()),
                materials: names.clone(),
            },
        };
        let mut m = MaterialDesc::with_kind(name, kind);
        m.locs = def.locs.clone();
        m.normal_map = def.normal_map.clone().map(NormalMapDesc::new);
        m.bump_map = def.bump_map.clone();
        m.roughness_map = def.roughness_map.clone();
        if let Some(e) = emission {
            m.emission = e.source();
            m.emits_both_sides = e.two_sided;
            m.locs.keys.push(("emission".into(), e.loc.clone()));
        }
        m
    }
}

/// `base`, or `base (2)`, `base (3)`, … if taken; the name is then taken.
fn unique_name(names: &mut HashSet<String>, base: String) -> String {
    let mut name = base.clone();
    let mut k = 2;
    while !names.insert(name.clone()) {
        name = format!("{base} ({k})");
        k += 1;
    }
    name
}

/// The smallest sine of the angle between `LookAt`'s up vector and its
/// viewing direction. pbrt-v4 refuses only an exactly parallel pair; but
/// rounding in the numbers as written (single precision: a relative 6·10⁻⁸)
/// can turn a parallel pair into one a hair apart, whose cross product —
/// the image's horizontal axis — would then point anywhere. Below this
/// angle (0.2 arc seconds, ten times the rounding) the pair is parallel.
const LOOK_AT_MIN_SINE: f64 = 1e-6;

/// pbrt-v4's `LookAt`: camera-from-world for an eye at `eye` looking at
/// `target`, with camera +x = up × direction (so world +x is on the left
/// of an image looking down −z with +y up). It is computed in double
/// precision as the inverse of a rigid motion (the transposed rotation and
/// the rotated, negated eye), so its bottom row is exactly 0 0 0 1 and it
/// stays affine.
fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> std::result::Result<Mat4, String> {
    let (e, t, u) = (eye.as_dvec3(), target.as_dvec3(), up.as_dvec3());
    let Some(dir) = (t - e).try_normalize() else {
        return Err(format!(
            "the eye and the point looked at are the same point ({} {} {}), so there is no viewing direction",
            eye.x, eye.y, eye.z
        ));
    };
    let Some(u) = u.try_normalize() else {
        return Err("the up vector must not be the zero vector".into());
    };
    let cross = u.cross(dir);
    // (Numbers read are finite, so the length is.)
    if cross.length() < LOOK_AT_MIN_SINE {
        let d = (target - eye).normalize();
        return Err(format!(
            "the up vector ({} {} {}) is parallel to the viewing direction ({} {} {}), so the image has no horizontal axis",
            up.x, up.y, up.z, d.x, d.y, d.z
        ));
    }
    let right = cross.normalize();
    let new_up = dir.cross(right);
    let rotation = DMat3::from_cols(right, new_up, dir).transpose();
    let translation = -(rotation * e);
    Ok(affine(rotation, translation).as_mat4())
}

/// The matrix of `linear` followed by a translation by `translation`.
fn affine(linear: DMat3, translation: DVec3) -> DMat4 {
    DMat4::from_cols(
        linear.x_axis.extend(0.0),
        linear.y_axis.extend(0.0),
        linear.z_axis.extend(0.0),
        translation.extend(1.0),
    )
}

/// The inverse of an affine matrix (bottom row exactly 0 0 0 1, as every
/// transform directive but a `Transform` or `ConcatTransform` with a
/// projective row makes), inverted as affine: the 3×3 part's inverse and
/// the translation, in double precision, so that the inverse is exactly
/// affine as well (a general 4×4 inverse leaves rounding errors in its
/// bottom row). The error says why there is none.
fn invert(m: &Mat4) -> std::result::Result<Mat4, &'static str> {
    if !m.is_finite() {
        return Err("has numbers that are not finite");
    }
    if m.row(3) != Vec4::W {
        return Err("is projective (its bottom row is not 0 0 0 1)");
    }
    let m = m.as_dmat4();
    let linear = DMat3::from_mat4(m);
    // The relative test of `Transform::from_matrix`: singular if the
    // determinant is tiny next to the product of the column lengths.
    let det = linear.determinant();
    let scale = linear.x_axis.length() * linear.y_axis.length() * linear.z_axis.length();
    if det.abs() <= 1e-12 * scale || !det.is_finite() {
        return Err("is singular");
    }
    let inv = linear.inverse();
    let out = affine(inv, -(inv * m.w_axis.truncate())).as_mat4();
    if !out.is_finite() {
        return Err("is singular");
    }
    Ok(out)
}

/// The world-from-camera matrix of a camera whose CTM (camera-from-world)
/// is `ctm`, and whether the CTM was projective. An affine CTM is inverted
/// as affine. A projective one is used as pbrt-v4 uses it: it inverts the
/// 4×4 matrix and moves camera rays by the inverse, the eye (the origin) as
/// a point, with the division by w, and directions by its upper-left 3×3
/// part; the affine matrix of that 3×3 part and that eye moves a pinhole
/// camera's rays the same way.
fn world_from_camera(ctm: &Mat4) -> std::result::Result<(Mat4, bool), &'static str> {
    if !ctm.is_finite() || ctm.row(3) == Vec4::W {
        return invert(ctm).map(|m| (m, false));
    }
    let inv = ctm.as_dmat4().inverse();
    let w = inv.w_axis.w;
    if !inv.is_finite() || ctm.as_dmat4().determinant() == 0.0 {
        return Err("is singular");
    }
    if w == 0.0 {
        return Err("is projective and puts the eye at infinity (the inverse's w of the origin is 0)");
    }
    let eye = inv.w_axis.truncate() / w;
    let linear = DMat3::from_mat4(inv);
    let m = affine(linear, eye).as_mat4();
    // The affine result passes the same test as any other.
    invert(&m)?;
    Ok((m, true))
}

/// `N` numbers after a directive.
fn numbers<const N: usize>(lx: &mut Lexer, directive: &str, offset: usize) -> Result<[f32; N]> {
    let mut out = [0.0; N];
    for (i, slot) in out.iter_mut().enumerate() {
        let Some(t) = lx.next()? else {
            return Err(lx.error(
                offset,
                format!("{directive} needs {N} numbers; the file ends after {i}"),
            ));
        };
        *slot = match &t.tok {
            Tok::Word(w) => parse_number(lx, t.offset, w, directive)?,
            _ => {
                return Err(lx.error(
                    t.offset,
                    format!("{directive} needs {N} numbers, found {} after {i}", t.describe()),
                ));
            }
        };
    }
    Ok(out)
}

/// `[ m00 … m33 ]` after `Transform` or `ConcatTransform`.
fn bracketed_16(lx: &mut Lexer, directive: &str, offset: usize) -> Result<[f32; 16]> {
    match lx.next()? {
        Some(t) if t.tok == Tok::Open => {}
        Some(t) => {
            return Err(lx.error(
                t.offset,
                format!("{directive} needs [ and 16 numbers ], found {}", t.describe()),
            ));
        }
        None => return Err(lx.error(offset, format!("{directive} needs [ and 16 numbers ]; the file ends"))),
    }
    let m = numbers::<16>(lx, directive, offset)?;
    match lx.next()? {
        Some(t) if t.tok == Tok::Close => Ok(m),
        Some(t) => Err(lx.error(
            t.offset,
            format!("{directive} needs exactly 16 numbers, then ], found {}", t.describe()),
        )),
        None => Err(lx.error(offset, format!("{directive}: the file ends before ]"))),
    }
}

/// A quoted string after a directive.
fn quoted(lx: &mut Lexer, directive: &str, offset: usize) -> Result<(String, usize)> {
    match lx.next()? {
        Some(t) => match t.tok {
            Tok::Str(s) => Ok((s, t.offset)),
            _ => Err(lx.error(
                t.offset,
                format!("{directive} needs a quoted string, found {}", t.describe()),
            )),
        },
        None => Err(lx.error(offset, format!("{directive} needs a quoted string; the file ends"))),
    }
}

/// Checks that `kind` is one of pbrt-v4's types for `directive`.
fn check_kind(lx: &Lexer, offset: usize, directive: &str, kind: &str, known: &[&str]) -> Result<()> {
    if known.contains(&kind) {
        return Ok(());
    }
    Err(lx.error(
        offset,
        format!(
            "unknown {directive} type \"{kind}\"{}",
            suggest(kind, known.iter().copied())
        ),
    ))
}

#[cfg(test)]
mod tests;
