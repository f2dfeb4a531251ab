//! trazo's native scene format: TOML, documented key by key in
//! docs/scene-format.md.
//!
//! The reader walks the TOML document with its source spans, so that every
//! error — a syntax error, an unknown key, a wrong type, a value that fails
//! validation — names the file, line, column and key.

use super::desc::*;
use crate::color::space::ColorSpace;
use crate::color::{Encoding, Rgb};
use crate::error::{Error, Result, SourceLoc};
use crate::files::{MAX_SCENE_BYTES, io_reason, read_limited};
use crate::geometry::TriangleMesh;
use crate::geometry::sdf::{self, SdfBuilder};
use crate::material::dispersion::{D_LINE_NM, IorSpectrum};
use crate::sampling::SamplerKind;
use crate::settings::{Filter, IntegratorKind, PathSampling, PhotonKernel, RenderSettings, Tonemap};
use crate::texture::{Mapping2D, NoisePattern, TextureNode};
use glam::{Affine3A, Mat4, Vec2, Vec3, Vec4};
use serde_spanned::Spanned;
use std::cell::RefCell;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use toml::de::{DeTable, DeValue};

/// Reads a scene file.
pub fn load(path: &Path) -> Result<SceneDesc> {
    let meta =
        std::fs::metadata(path).map_err(|e| Error::file(path, format!("cannot read scene: {}", io_reason(&e))))?;
    if meta.is_dir() {
        return Err(Error::file(path, "cannot read scene: this is a folder"));
    }
    if meta.len() > MAX_SCENE_BYTES {
        return Err(Error::file(path, "scene file is larger than 1 GiB"));
    }
    let bytes =
        read_limited(path, MAX_SCENE_BYTES).map_err(|e| Error::file(path, format!("cannot read scene: {e}")))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        let loc = SourceLoc::from_offset(
            &Arc::from(path),
            &String::from_utf8_lossy(e.as_bytes()),
            e.utf8_error().valid_up_to(),
        );
        Error::Scene {
            loc: Some(loc),
            key: None,
            message: "the file is not valid UTF-8 text".into(),
        }
    })?;
    parse(&text, path)
}

/// Parses scene text that was read from `path` (used for messages and to
/// resolve relative file names).
pub fn parse(text: &str, path: &Path) -> Result<SceneDesc> {
    let file: Arc<Path> = Arc::from(path);
    let root = DeTable::parse(text).map_err(|e| {
        let loc = e.span().map(|s| SourceLoc::from_offset(&file, text, s.start));
        Error::Scene {
            loc,
            key: None,
            message: format!("TOML syntax error: {}", e.message().trim()),
        }
    })?;
    let ctx = Ctx { file, text };
    let top = Table::new(&ctx, String::new(), root.get_ref(), root.span());
    let mut desc = SceneDesc {
        source: Some(ctx.file.clone()),
        ..SceneDesc::default()
    };
    if let Some(t) = top.table("render")? {
        read_render(&t, &mut desc.settings)?;
        desc.settings_locs = t.finish()?;
    }
    if let Some(t) = top.table("camera")? {
        desc.camera_medium = t.string("medium")?;
        desc.camera = read_camera(&t)?;
    }
    if let Some(t) = top.table("world")? {
        if let Some(v) = t.value("background") {
            desc.background = match v.get_ref() {
                DeValue::Table(_) => {
                    let g = t.table("background")?.expect("checked above");
                    let bg = if g.value("file").is_some() {
                        let path = g.path("file")?.expect("present");
                        let transform = match g.value("transform") {
                            Some(v) => read_transform(&g, v)?,
                            None => Vec::new(),
                        };
                        BackgroundDesc::Image {
                            path,
                            scale: g.number_or("scale", 1.0)?,
                            transform,
                            layout: EnvironmentLayout::LatLong,
                            illuminance: None,
                        }
                    } else {
                        BackgroundDesc::Gradient {
                            top: g.color("top")?.unwrap_or(Rgb::ONE),
                            bottom: g.color("bottom")?.unwrap_or(Rgb::ZERO),
                        }
                    };
                    g.finish()?;
                    bg
                }
                _ => BackgroundDesc::Constant(t.color("background")?.unwrap_or(Rgb::ZERO)),
            };
        }
        desc.ambient = t.color("ambient")?.unwrap_or(Rgb::ZERO);
        desc.world_locs = t.finish()?;
    }
    for t in top.tables("texture")? {
        desc.textures.extend(read_texture(&t)?);
    }
    for t in top.tables("material")? {
        desc.materials.push(read_material(&t)?);
    }
    for t in top.tables("mesh")? {
        let name = t.required_string("name")?;
        let source = read_mesh_source(&t, true)?.expect("required");
        desc.meshes.push(MeshDesc {
            name,
            source,
            locs: t.finish()?,
        });
    }
    for t in top.tables("light")? {
        desc.lights.push(read_light(&t)?);
    }
    for t in top.tables("shape")? {
        desc.shapes.extend(read_shape(&t)?);
    }
    for t in top.tables("medium")? {
        desc.media.push(read_medium(&t)?);
    }
    top.finish()?;
    desc.validate()?;
    Ok(desc)
}

struct Ctx<'a> {
    file: Arc<Path>,
    text: &'a str,
}

impl Ctx<'_> {
    fn loc(&self, span: &Range<usize>) -> SourceLoc {
        SourceLoc::from_offset(&self.file, self.text, span.start)
    }
}

type Value<'a> = Spanned<DeValue<'a>>;

/// A TOML table being read: remembers which keys were used (the others are
/// errors) and where each was written.
struct Table<'a> {
    ctx: &'a Ctx<'a>,
    path: String,
    table: &'a DeTable<'a>,
    span: Range<usize>,
    used: RefCell<Vec<String>>,
    locs: RefCell<Locs>,
}

fn type_name(v: &DeValue) -> &'static str {
    match v {
        DeValue::String(_) => "a string",
        DeValue::Integer(_) => "an integer",
        DeValue::Float(_) => "a number",
        DeValue::Boolean(_) => "a boolean",
        DeValue::Datetime(_) => "a date",
        DeValue::Array(_) => "an array",
        DeValue::Table(_) => "a table",
    }
}

impl<'a> Table<'a> {
    fn new(ctx: &'a Ctx<'a>, path: String, table: &'a DeTable<'a>, span: Range<usize>) -> Table<'a> {
        let item = Some(ctx.loc(&span));
        Table {
            ctx,
            path,
            table,
            span,
            used: RefCell::new(Vec::new()),
            locs: RefCell::new(Locs::at(item)),
        }
    }

    fn key_path(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_string()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    fn err_at(&self, key: &str, span: &Range<usize>, msg: impl Into<String>) -> Error {
        Error::scene(Some(self.ctx.loc(span)), self.key_path(key), msg)
    }

    /// The raw value of `key`, marking it used.
    fn value(&self, key: &str) -> Option<&'a Value<'a>> {
        self.used.borrow_mut().push(key.to_string());
        let (_, v) = self.table.iter().find(|(k, _)| k.get_ref().as_ref() == key)?;
        self.locs
            .borrow_mut()
            .keys
            .push((key.to_string(), self.ctx.loc(&v.span())));
        Some(v)
    }

    fn expected(&self, key: &str, v: &Value, what: &str) -> Error {
        self.err_at(
            key,
            &v.span(),
            format!("expected {what}, found {}", type_name(v.get_ref())),
        )
    }

    fn number_of(&self, key: &str, v: &Value) -> Result<f32> {
        match v.get_ref() {
            DeValue::Integer(i) => i128::from_str_radix(i.as_str(), i.radix())
                .map(|x| x as f32)
                .map_err(|_| self.err_at(key, &v.span(), "integer out of range")),
            DeValue::Float(f) => f
                .as_str()
                .parse::<f64>()
                .map(|x| x as f32)
                .map_err(|_| self.err_at(key, &v.span(), format!("cannot read number {}", f.as_str()))),
            _ => Err(self.expected(key, v, "a number")),
        }
    }

    fn number(&self, key: &str) -> Result<Option<f32>> {
        self.value(key).map(|v| self.number_of(key, v)).transpose()
    }

    fn number_or(&self, key: &str, default: f32) -> Result<f32> {
        Ok(self.number(key)?.unwrap_or(default))
    }

    /// An index of refraction: a number, the name of a glass that
    /// disperses (`"BK7"`, pbrt-v4's `"glass-BK7"` …) or `[nm, index]`
    /// pairs; with the index at the sodium d line and how it varies.
    fn ior_spectrum(&self, key: &str, default: f32) -> Result<(f32, Option<IorSpectrum>)> {
        let Some(v) = self.value(key) else {
            return Ok((default, None));
        };
        match v.get_ref() {
            DeValue::String(name) => {
                let full = if name.starts_with("glass-") {
                    name.to_string()
                } else {
                    format!("glass-{name}")
                };
                let spectrum = IorSpectrum::named_glass(&full).ok_or_else(|| {
                    self.err_at(
                        key,
                        &v.span(),
                        format!("unknown glass \"{name}\": expected a number, [nm, index] pairs or one of BK7, BAF10, FK51A, LASF9, F5, F10, F11"),
                    )
                })?;
                Ok((spectrum.at(D_LINE_NM), Some(spectrum)))
            }
            DeValue::Array(pairs) => {
                let mut samples = Vec::with_capacity(pairs.len());
                for p in pairs.iter() {
                    let x = self.numbers_of(key, p, 2)?;
                    if samples.last().is_some_and(|&(l, _): &(f32, f32)| x[0] <= l) {
                        return Err(self.err_at(key, &p.span(), "wavelengths must increase"));
                    }
                    samples.push((x[0], x[1]));
                }
                if samples.len() < 2 {
                    return Err(self.err_at(key, &v.span(), "expected at least two [nm, index] pairs"));
                }
                let spectrum = IorSpectrum::sampled(&samples);
                let d = spectrum.as_ref().map_or(samples[0].1, |s| s.at(D_LINE_NM));
                Ok((d, spectrum))
            }
            _ => Ok((self.number_of(key, v)?, None)),
        }
    }

    fn required<T>(&self, key: &str, v: Option<T>) -> Result<T> {
        v.ok_or_else(|| {
            Error::scene(
                Some(self.ctx.loc(&self.span)),
                self.key_path(key),
                format!("missing required key `{key}`"),
            )
        })
    }

    fn unsigned(&self, key: &str, max: u64) -> Result<Option<u64>> {
        let Some(v) = self.value(key) else {
            return Ok(None);
        };
        match v.get_ref() {
            DeValue::Integer(i) => {
                let x = i128::from_str_radix(i.as_str(), i.radix())
                    .map_err(|_| self.err_at(key, &v.span(), "integer out of range"))?;
                if x < 0 || x > max as i128 {
                    return Err(self.err_at(key, &v.span(), format!("must be between 0 and {max}, got {x}")));
                }
                Ok(Some(x as u64))
            }
            _ => Err(self.expected(key, v, "a whole number")),
        }
    }

    fn numbers_of(&self, key: &str, v: &Value, n: usize) -> Result<Vec<f32>> {
        match v.get_ref() {
            DeValue::Array(a) if a.len() == n => a.iter().map(|x| self.number_of(key, x)).collect(),
            DeValue::Array(a) => Err(self.err_at(key, &v.span(), format!("expected {n} numbers, found {}", a.len()))),
            _ => Err(self.expected(key, v, &format!("an array of {n} numbers"))),
        }
    }

    fn vec3_of(&self, key: &str, v: &Value) -> Result<Vec3> {
        let x = self.numbers_of(key, v, 3)?;
        Ok(Vec3::new(x[0], x[1], x[2]))
    }

    fn vec3(&self, key: &str) -> Result<Option<Vec3>> {
        self.value(key).map(|v| self.vec3_of(key, v)).transpose()
    }

    /// A 3-vector, or one number for all three components.
    fn vec3_or_scalar(&self, key: &str) -> Result<Option<Vec3>> {
        let Some(v) = self.value(key) else {
            return Ok(None);
        };
        match v.get_ref() {
            DeValue::Integer(_) | DeValue::Float(_) => Ok(Some(Vec3::splat(self.number_of(key, v)?))),
            _ => self.vec3_of(key, v).map(Some),
        }
    }

    /// Two numbers, or one for both.
    fn vec2(&self, key: &str) -> Result<Option<Vec2>> {
        let Some(v) = self.value(key) else {
            return Ok(None);
        };
        match v.get_ref() {
            DeValue::Integer(_) | DeValue::Float(_) => Ok(Some(Vec2::splat(self.number_of(key, v)?))),
            _ => {
                let x = self.numbers_of(key, v, 2)?;
                Ok(Some(Vec2::new(x[0], x[1])))
            }
        }
    }

    /// A colour: [r, g, b] or one number for grey.
    fn color(&self, key: &str) -> Result<Option<Rgb>> {
        self.vec3_or_scalar(key)
    }

    /// A colour or the name of a texture.
    fn color_source(&self, key: &str) -> Result<Option<ColorSource>> {
        let Some(v) = self.value(key) else {
            return Ok(None);
        };
        match v.get_ref() {
            DeValue::String(s) => Ok(Some(ColorSource::Texture(s.to_string()))),
            DeValue::Integer(_) | DeValue::Float(_) => Ok(Some(ColorSource::Rgb(Rgb::splat(self.number_of(key, v)?)))),
            DeValue::Array(_) => Ok(Some(ColorSource::Rgb(self.vec3_of(key, v)?))),
            _ => Err(self.expected(key, v, "a colour [r, g, b], a number or a texture name")),
        }
    }

    fn string(&self, key: &str) -> Result<Option<String>> {
        let Some(v) = self.value(key) else {
            return Ok(None);
        };
        match v.get_ref() {
            DeValue::String(s) => Ok(Some(s.to_string())),
            _ => Err(self.expected(key, v, "a string")),
        }
    }

    fn required_string(&self, key: &str) -> Result<String> {
        let s = self.string(key)?;
        self.required(key, s)
    }

    /// A string that must be one of `names`.
    fn choice(&self, key: &str, names: &[&str]) -> Result<Option<String>> {
        let Some(s) = self.string(key)? else {
            return Ok(None);
        };
        if names.contains(&s.as_str()) {
            Ok(Some(s))
        } else {
            let span = self.value(key).map(|v| v.span()).unwrap_or(self.span.clone());
            Err(self.err_at(
                key,
                &span,
                format!(
                    "unknown value \"{s}\": expected one of {}{}",
                    quote_list(names),
                    suggest(&s, names.iter().copied())
                ),
            ))
        }
    }

    fn boolean(&self, key: &str) -> Result<Option<bool>> {
        let Some(v) = self.value(key) else {
            return Ok(None);
        };
        match v.get_ref() {
            DeValue::Boolean(b) => Ok(Some(*b)),
            _ => Err(self.expected(key, v, "true or false")),
        }
    }

    fn path(&self, key: &str) -> Result<Option<PathBuf>> {
        Ok(self.string(key)?.map(PathBuf::from))
    }

    fn table(&self, key: &str) -> Result<Option<Table<'a>>> {
        let Some(v) = self.value(key) else {
            return Ok(None);
        };
        match v.get_ref() {
            DeValue::Table(t) => Ok(Some(Table::new(self.ctx, self.key_path(key), t, v.span()))),
            _ => Err(self.expected(key, v, "a table")),
        }
    }

    /// An array of tables (`[[key]]`), each named `key[i]` in messages.
    fn tables(&self, key: &str) -> Result<Vec<Table<'a>>> {
        let Some(v) = self.value(key) else {
            return Ok(Vec::new());
        };
        match v.get_ref() {
            DeValue::Array(a) => a
                .iter()
                .enumerate()
                .map(|(i, item)| match item.get_ref() {
                    DeValue::Table(t) => Ok(Table::new(
                        self.ctx,
                        format!("{}[{i}]", self.key_path(key)),
                        t,
                        item.span(),
                    )),
                    _ => Err(self.expected(&format!("{key}[{i}]"), item, "a table")),
                })
                .collect(),
            _ => Err(self.expected(key, v, &format!("an array of tables ([[{key}]])"))),
        }
    }

    /// Fails on any key that was never asked for; returns the locations.
    fn finish(&self) -> Result<Locs> {
        let used = self.used.borrow();
        for (k, _) in self.table.iter() {
            let name = k.get_ref().as_ref();
            if !used.iter().any(|u| u == name) {
                // Other renderers' names for a key first: spelling is
                // no guide to them ("samples" is nearest "sampler").
                let hint = match KEY_ALIASES.iter().find(|(alias, _)| *alias == name) {
                    Some((_, key)) if used.iter().any(|u| u == key) => format!(" (did you mean \"{key}\"?)"),
                    _ => suggest(name, used.iter().map(String::as_str)),
                };
                return Err(Error::scene(
                    Some(self.ctx.loc(&k.span())),
                    self.key_path(name),
                    format!("unknown key{hint}"),
                ));
            }
        }
        Ok(self.locs.borrow().clone())
    }
}

/// Keys as other renderers (pbrt-v4, Mitsuba 3, Blender) name them, with
/// trazo's name.
const KEY_ALIASES: &[(&str, &str)] = &[
    ("samples", "spp"),
    ("sample_count", "spp"),
    ("pixelsamples", "spp"),
    ("samples_per_pixel", "spp"),
    ("maxdepth", "max_depth"),
    ("xresolution", "width"),
    ("yresolution", "height"),
];

fn quote_list(names: &[&str]) -> String {
    names.iter().map(|n| format!("\"{n}\"")).collect::<Vec<_>>().join(", ")
}

fn read_render(t: &Table, s: &mut RenderSettings) -> Result<()> {
    if let Some(w) = t.unsigned("width", u32::MAX as u64)? {
        s.width = w as u32;
    }
    if let Some(h) = t.unsigned("height", u32::MAX as u64)? {
        s.height = h as u32;
    }
    if let Some(n) = t.unsigned("spp", u32::MAX as u64)? {
        s.spp = n as u32;
    }
    if let Some(d) = t.unsigned("max_depth", u32::MAX as u64)? {
        s.max_depth = d as u32;
    }
    if let Some(seed) = t.unsigned("seed", u64::MAX)? {
        s.seed = seed;
    }
    if let Some(i) = t.choice("integrator", &IntegratorKind::NAMES)? {
        s.integrator = IntegratorKind::from_name(&i).expect("checked");
    }
    if let Some(k) = t.choice("sampling", &PathSampling::NAMES)? {
        s.sampling = PathSampling::from_name(&k).expect("checked");
    }
    if let Some(step) = t.number("march_step")? {
        s.march_step = Some(step);
    }
    if let Some(d) = t.unsigned("rr_depth", u32::MAX as u64)? {
        s.rr_depth = d as u32;
    }
    if let Some(k) = t.choice("sampler", &SamplerKind::NAMES)? {
        s.sampler = SamplerKind::from_name(&k).expect("checked");
    }
    if let Some(k) = t.choice("tonemap", &Tonemap::NAMES)? {
        s.tonemap = Tonemap::from_name(&k).expect("checked");
    }
    if let Some(e) = t.number("exposure")? {
        s.exposure = e;
    }
    if let Some(m) = t.number("max_component_value")? {
        s.max_component_value = m;
    }
    if let Some(k) = t.number("white_balance")? {
        s.white_balance = k;
    }
    if let Some(c) = t.choice("color_space", ColorSpace::PBRT_NAMES)? {
        s.color_space = ColorSpace::from_pbrt_name(&c).expect("checked");
    }
    if let Some(h) = t.boolean("hide_emitters")? {
        s.hide_emitters = h;
    }
    if let Some(d) = t.number("ao_distance")? {
        s.ao_distance = d;
    }
    if let Some(n) = t.unsigned("mlt_bootstrap", u32::MAX as u64)? {
        s.mlt.bootstrap = n as u32;
    }
    if let Some(n) = t.unsigned("mlt_chains", u32::MAX as u64)? {
        s.mlt.chains = n as u32;
    }
    if let Some(p) = t.number("mlt_large_step")? {
        s.mlt.large_step_probability = p;
    }
    if let Some(sigma) = t.number("mlt_sigma")? {
        s.mlt.sigma = sigma;
    }
    if let Some(v) = t.value("crop") {
        // [x, y, width, height] in pixels of the width × height image.
        let c = t.numbers_of("crop", v, 4)?;
        let (full_w, full_h) = (s.width as f64, s.height as f64);
        let ok = c.iter().all(|x| x.fract() == 0.0 && *x >= 0.0)
            && c[2] >= 1.0
            && c[3] >= 1.0
            && c[0] as f64 + c[2] as f64 <= full_w
            && c[1] as f64 + c[3] as f64 <= full_h;
        if !ok {
            return Err(t.err_at(
                "crop",
                &v.span(),
                format!(
                    "must be [x, y, width, height], whole pixels inside the {}×{} image, got {c:?}",
                    s.width, s.height
                ),
            ));
        }
        s.crop = Some(crate::settings::Crop {
            full_width: s.width,
            full_height: s.height,
            x: c[0] as u32,
            y: c[1] as u32,
        });
        (s.width, s.height) = (c[2] as u32, c[3] as u32);
    }
    if let Some(n) = t.unsigned("photons", u32::MAX as u64)? {
        s.photon.photons = n as u32;
    }
    if let Some(n) = t.unsigned("caustic_photons", u32::MAX as u64)? {
        s.photon.caustic_photons = n as u32;
    }
    if let Some(n) = t.unsigned("sppm_photons", u32::MAX as u64)? {
        s.photon.sppm_photons = n as u32;
    }
    if let Some(n) = t.unsigned("photon_gather", u32::MAX as u64)? {
        s.photon.gather = n as u32;
    }
    if let Some(r) = t.number("photon_radius")? {
        s.photon.radius = r;
    }
    if let Some(n) = t.unsigned("final_gather", u32::MAX as u64)? {
        s.photon.final_gather = n as u32;
    }
    if let Some(k) = t.choice("photon_kernel", &PhotonKernel::NAMES)? {
        s.photon.kernel = PhotonKernel::from_name(&k).expect("checked");
    }
    if let Some(a) = t.number("sppm_alpha")? {
        s.photon.alpha = a;
    }
    if let Some(f) = t.choice("filter", &Filter::NAMES)? {
        s.filter = Filter::from_name(&f).expect("checked");
    }
    // One radius, or [x, y]: one per axis, as pbrt-v4's filters have.
    let radii = t.vec2("filter_radius")?;
    let radius = radii.map(|r| r.x);
    s.filter_y_radius = radii.and_then(|r| (r.y != r.x).then_some(r.y));
    if s.filter_y_radius.is_some() {
        // The y radius's errors point at the pair.
        let mut locs = t.locs.borrow_mut();
        if let Some(loc) = locs.key("filter_radius") {
            locs.keys.push(("filter_y_radius".into(), loc));
        }
    }
    let stddev = t.number("filter_stddev")?;
    let (b, c, tau) = (t.number("filter_b")?, t.number("filter_c")?, t.number("filter_tau")?);
    // A parameter of another filter than the one chosen is an error.
    let foreign = |key: &str, owner: &str| -> Result<()> {
        match t.value(key) {
            Some(v) => Err(t.err_at(key, &v.span(), format!("only the {owner} filter has `{key}`"))),
            None => Ok(()),
        }
    };
    if !matches!(s.filter, Filter::Gaussian { .. }) {
        foreign("filter_stddev", "gaussian")?;
    }
    if !matches!(s.filter, Filter::Mitchell { .. }) {
        foreign("filter_b", "mitchell (or catmullrom)")?;
        foreign("filter_c", "mitchell (or catmullrom)")?;
    }
    if !matches!(s.filter, Filter::Lanczos { .. }) {
        foreign("filter_tau", "lanczos")?;
    }
    match &mut s.filter {
        Filter::Box { radius: r } | Filter::Tent { radius: r } => {
            if let Some(v) = radius {
                *r = v;
            }
        }
        Filter::Gaussian { stddev: sd, radius: r } => {
            if let Some(v) = stddev {
                *sd = v;
                *r = 4.0 * v;
            }
            if let Some(v) = radius {
                *r = v;
            }
        }
        Filter::Mitchell {
            radius: r,
            b: fb,
            c: fc,
        } => {
            if let Some(v) = radius {
                *r = v;
            }
            *fb = b.unwrap_or(*fb);
            *fc = c.unwrap_or(*fc);
        }
        Filter::Lanczos { radius: r, tau: ft } => {
            if let Some(v) = radius {
                *r = v;
            }
            *ft = tau.unwrap_or(*ft);
        }
    }
    Ok(())
}

fn read_camera(t: &Table) -> Result<CameraDesc> {
    let kind = t
        .choice("type", &["perspective", "orthographic", "spherical"])?
        .unwrap_or_else(|| "perspective".into());
    let projection = match kind.as_str() {
        "perspective" => ProjectionDesc::Perspective {
            fov: t.number_or("fov", 40.0)?,
        },
        "orthographic" => ProjectionDesc::Orthographic {
            size: t.number_or("size", 2.0)?,
        },
        _ => ProjectionDesc::Spherical {
            mapping: match t.choice("mapping", &["equal_area", "equirectangular"])?.as_deref() {
                Some("equirectangular") => crate::camera::SphericalMapping::Equirectangular,
                _ => crate::camera::SphericalMapping::EqualArea,
            },
        },
    };
    let d = CameraDesc::default();
    let (from, to, up) = (
        t.vec3("from")?.unwrap_or(d.from),
        t.vec3("to")?.unwrap_or(d.to),
        t.vec3("up")?.unwrap_or(d.up),
    );
    // A moving camera: where it is at the second of `motion_times`.
    let ends = (t.vec3("from_end")?, t.vec3("to_end")?, t.vec3("up_end")?);
    let motion = match ends {
        (None, None, None) => None,
        (from_end, to_end, up_end) => {
            let key = ["from_end", "to_end", "up_end"][if from_end.is_some() {
                0
            } else if to_end.is_some() {
                1
            } else {
                2
            }];
            let span = t.value(key).map(|v| v.span()).unwrap_or(t.span.clone());
            let end = crate::geometry::Transform::look_at(
                from_end.unwrap_or(from),
                to_end.unwrap_or(to),
                up_end.unwrap_or(up),
            )
            .map_err(|_| {
                t.err_at(
                    key,
                    &span,
                    "the camera's `from_end`, `to_end` and `up_end` do not define a view (from = to, or up parallel to the view direction)",
                )
            })?;
            let times = t.vec2("motion_times")?.map_or((0.0, 1.0), |v| (v.x, v.y));
            if !(times.0.is_finite() && times.1.is_finite() && times.0 < times.1) {
                let span = t.value("motion_times").map(|v| v.span()).unwrap_or(t.span.clone());
                return Err(t.err_at(
                    "motion_times",
                    &span,
                    format!("must increase, got {} then {}", times.0, times.1),
                ));
            }
            Some((end.m, times))
        }
    };
    let cam = CameraDesc {
        projection,
        from,
        to,
        up,
        motion,
        aperture_radius: t.number_or("aperture_radius", 0.0)?,
        focus_distance: t.number("focus_distance")?,
        to_world: None,
        shutter: t.vec2("shutter")?.map_or(d.shutter, |v| (v.x, v.y)),
        ..d
    };
    Ok(CameraDesc {
        locs: t.finish()?,
        ..cam
    })
}

/// The texture types of the native format.
pub const TEXTURE_TYPES: [&str; 14] = [
    "constant",
    "checkerboard",
    "checkerboard3d",
    "image",
    "scale",
    "mix",
    "direction_mix",
    "dots",
    "bilerp",
    "invert",
    "fbm",
    "wrinkled",
    "windy",
    "marble",
];

/// A `[[texture]]`: one texture, or two where an image is placed by a
/// mapping other than (u, v) (the image itself, under the texture's name
/// after a "\0" that no scene can write, and the texture reading it).
fn read_texture(t: &Table) -> Result<Vec<TextureDesc>> {
    let name = t.required_string("name")?;
    let kind = t.choice("type", &TEXTURE_TYPES)?;
    let kind = t.required("type", kind)?;
    let input = |key: &str, default: f32| -> Result<ColorSource> {
        Ok(t.color_source(key)?.unwrap_or(ColorSource::Rgb(Rgb::splat(default))))
    };
    let kind = match kind.as_str() {
        "constant" => TextureKind::Constant(t.color("color")?.unwrap_or(Rgb::splat(0.5))),
        "checkerboard" => {
            let (even, odd) = (input("even", 1.0)?, input("odd", 0.0)?);
            match (even, odd, read_mapping(t, Vec2::splat(8.0))?) {
                (ColorSource::Rgb(even), ColorSource::Rgb(odd), Mapping2D::Uv { scale, offset })
                    if offset == Vec2::ZERO =>
                {
                    TextureKind::Checkerboard { even, odd, scale }
                }
                (even, odd, mapping) => TextureKind::Node(TextureNode::Checkerboard { even, odd, mapping }),
            }
        }
        "checkerboard3d" => {
            let (even, odd) = (input("even", 1.0)?, input("odd", 0.0)?);
            let scale = t.number_or("scale", 1.0)?;
            match (even, odd) {
                (ColorSource::Rgb(even), ColorSource::Rgb(odd)) if t.value("transform").is_none() => {
                    TextureKind::Checkerboard3d { even, odd, scale }
                }
                (even, odd) => TextureKind::Node(TextureNode::SolidCheckerboard {
                    even,
                    odd,
                    to_texture: Affine3A::from_scale(Vec3::splat(scale)) * texture_space(t)?,
                }),
            }
        }
        "image" => {
            let path = t.path("file")?;
            let mapping = read_mapping(t, Vec2::ONE)?;
            let (scale, offset) = match mapping {
                Mapping2D::Uv { scale, offset } => (scale, offset),
                _ => (Vec2::ONE, Vec2::ZERO),
            };
            let wrap = match t.choice("wrap", &["repeat", "mirror", "clamp"])?.as_deref() {
                Some("mirror") => crate::texture::WrapMode::Mirror,
                Some("clamp") => crate::texture::WrapMode::Clamp,
                _ => crate::texture::WrapMode::Repeat,
            };
            let filter = match t.choice("filter", &["bilinear", "nearest"])?.as_deref() {
                Some("nearest") => crate::texture::ImageFilter::Nearest,
                _ => crate::texture::ImageFilter::Bilinear,
            };
            let image = TextureKind::Image {
                source: ImageSource::File(t.required("file", path)?),
                scale,
                offset,
                encoding: t
                    .boolean("srgb")?
                    .map(|srgb| if srgb { Encoding::Srgb } else { Encoding::Linear }),
                tint: t.color("tint")?.unwrap_or(Rgb::ONE),
                wrap: [wrap; 2],
                filter,
            };
            if !matches!(mapping, Mapping2D::Uv { .. }) {
                let locs = t.finish()?;
                let image_name = format!("\u{0}{name} image");
                return Ok(vec![
                    TextureDesc {
                        name: image_name.clone(),
                        kind: image,
                        locs: locs.clone(),
                    },
                    TextureDesc {
                        name,
                        kind: TextureKind::Node(TextureNode::Mapped {
                            tex: ColorSource::Texture(image_name),
                            mapping,
                        }),
                        locs,
                    },
                ]);
            }
            image
        }
        "scale" => TextureKind::Node(TextureNode::Scale {
            tex: t.required("texture", t.color_source("texture")?)?,
            scale: input("scale", 1.0)?,
        }),
        "mix" => TextureKind::Node(TextureNode::Mix {
            first: input("first", 0.0)?,
            second: input("second", 1.0)?,
            amount: input("amount", 0.5)?,
        }),
        "direction_mix" => TextureKind::Node(TextureNode::DirectionMix {
            first: input("first", 0.0)?,
            second: input("second", 1.0)?,
            dir: t.vec3("direction")?.unwrap_or(Vec3::Y),
        }),
        "dots" => TextureKind::Node(TextureNode::Dots {
            inside: input("inside", 1.0)?,
            outside: input("outside", 0.0)?,
            mapping: read_mapping(t, Vec2::ONE)?,
        }),
        "bilerp" => TextureKind::Node(TextureNode::Bilerp {
            corners: [
                t.color("v00")?.unwrap_or(Rgb::ZERO),
                t.color("v10")?.unwrap_or(Rgb::ZERO),
                t.color("v01")?.unwrap_or(Rgb::ONE),
                t.color("v11")?.unwrap_or(Rgb::ONE),
            ],
            mapping: read_mapping(t, Vec2::ONE)?,
        }),
        "invert" => TextureKind::Node(TextureNode::Invert(t.required("texture", t.color_source("texture")?)?)),
        noise => {
            let octaves = t.unsigned("octaves", MAX_NOISE_OCTAVES as u64)?.unwrap_or(8) as u32;
            let omega = t.number_or("roughness", 0.5)?;
            let pattern = NoisePattern::named(noise, octaves, omega, || {
                Ok::<_, Error>((t.number_or("scale", 1.0)?, t.number_or("variation", 0.2)?))
            })?
            .expect("a noise type");
            TextureKind::Node(TextureNode::Noise {
                pattern,
                to_texture: texture_space(t)?,
            })
        }
    };
    Ok(vec![TextureDesc {
        name,
        kind,
        locs: t.finish()?,
    }])
}

/// `mapping = ""uv" | "spherical" | "cylindrical" | "planar"` (pbrt-v4's
/// 2-D mappings): (u, v) scaled by `scale` and moved by `offset`, or read
/// from the point in the texture space that `transform` places (`s_axis`,
/// `t_axis` and `offset` for planar).
fn read_mapping(t: &Table, default_scale: Vec2) -> Result<Mapping2D> {
    Ok(
        match t
            .choice("mapping", &["uv", "spherical", "cylindrical", "planar"])?
            .as_deref()
        {
            Some("spherical") => Mapping2D::Spherical {
                to_texture: texture_space(t)?,
            },
            Some("cylindrical") => Mapping2D::Cylindrical {
                to_texture: texture_space(t)?,
            },
            Some("planar") => Mapping2D::Planar {
                to_texture: texture_space(t)?,
                s_axis: t.vec3("s_axis")?.unwrap_or(Vec3::X),
                t_axis: t.vec3("t_axis")?.unwrap_or(Vec3::Y),
                offset: t.vec2("offset")?.unwrap_or(Vec2::ZERO),
            },
            _ => Mapping2D::Uv {
                scale: t.vec2("scale")?.unwrap_or(default_scale),
                offset: t.vec2("offset")?.unwrap_or(Vec2::ZERO),
            },
        },
    )
}

/// World to a texture's own space: the inverse of its `transform` (which
/// places the texture in the world), the identity without one.
fn texture_space(t: &Table) -> Result<Affine3A> {
    let Some(v) = t.value("transform") else {
        return Ok(Affine3A::IDENTITY);
    };
    let mut placed = crate::geometry::Transform::IDENTITY;
    for op in read_transform(t, v)? {
        let step = op
            .to_transform()
            .map_err(|e| t.err_at("transform", &v.span(), format!("{}: {e}", op.name())))?;
        placed = placed.then(&step);
    }
    Ok(Affine3A::from_mat4(placed.inv))
}

/// The material types of the native format.
pub const MATERIAL_TYPES: [&str; 13] = [
    "classic",
    "diffuse",
    "diffusetransmission",
    "mirror",
    "conductor",
    "dielectric",
    "plastic",
    "thin",
    "null",
    "mix",
    "principled",
    "measured",
    "hair",
];

fn read_material(t: &Table) -> Result<MaterialDesc> {
    let name = t.required_string("name")?;
    let kind = t.choice("type", &MATERIAL_TYPES)?.unwrap_or_else(|| "classic".into());
    let kind = match kind.as_str() {
        "classic" => {
            let d = ClassicDesc::default();
            MaterialKindDesc::Classic(ClassicDesc {
                diffuse: t.color_source("diffuse")?.unwrap_or(d.diffuse),
                specular: t.color_source("specular")?.unwrap_or(d.specular),
                shininess: t.number_or("shininess", d.shininess)?,
                reflectivity: t.color("reflectivity")?.unwrap_or(d.reflectivity),
                transmission: t.color("transmission")?.unwrap_or(d.transmission),
                ior: t.number_or("ior", d.ior)?,
            })
        }
        "diffuse" => MaterialKindDesc::Diffuse {
            reflectance: t
                .color_source("reflectance")?
                .unwrap_or(ColorSource::Rgb(Rgb::splat(0.5))),
        },
        "diffusetransmission" => MaterialKindDesc::DiffuseTransmission {
            reflectance: t
                .color_source("reflectance")?
                .unwrap_or(ColorSource::Rgb(Rgb::splat(0.25))),
            transmittance: t
                .color_source("transmittance")?
                .unwrap_or(ColorSource::Rgb(Rgb::splat(0.25))),
        },
        "mirror" => MaterialKindDesc::Conductor {
            fresnel: ConductorDesc::Mirror(t.color("reflectance")?.unwrap_or(Rgb::ONE)),
            tint: Rgb::ONE,
            roughness: (0.0, 0.0),
            distribution: MicrofacetDistribution::Ggx,
        },
        "conductor" => {
            let metal = t.choice("metal", &crate::material::conductor::METAL_NAMES)?;
            let eta = t.color("eta")?;
            let k = t.color("k")?;
            let reflectance = t.color("reflectance")?;
            let given = [metal.is_some(), eta.is_some() || k.is_some(), reflectance.is_some()];
            if given.iter().filter(|&&g| g).count() > 1 {
                return Err(Error::scene(
                    Some(t.ctx.loc(&t.span)),
                    t.key_path("metal"),
                    "give one of `metal`, `eta` with `k`, or `reflectance`",
                ));
            }
            let fresnel = if let Some(m) = metal {
                let (eta, k) = crate::material::conductor::metal_ior(&m).expect("checked name");
                ConductorDesc::Complex { eta, k }
            } else if eta.is_some() || k.is_some() {
                ConductorDesc::Complex {
                    eta: t.required("eta", eta)?,
                    k: t.required("k", k)?,
                }
            } else if let Some(r) = reflectance {
                ConductorDesc::Reflectance(r)
            } else {
                ConductorDesc::Mirror(Rgb::ONE)
            };
            let roughness = match t.vec2("roughness")? {
                Some(v) => (v.x, v.y),
                None => (0.0, 0.0),
            };
            MaterialKindDesc::Conductor {
                fresnel,
                tint: t.color("tint")?.unwrap_or(Rgb::ONE),
                roughness,
                distribution: distribution(t)?,
            }
        }
        "dielectric" => {
            let (ior, dispersion) = t.ior_spectrum("ior", 1.5)?;
            MaterialKindDesc::Dielectric {
                ior,
                dispersion,
                ext_ior: t.number_or("ext_ior", 1.0)?,
                roughness: match t.vec2("roughness")? {
                    Some(v) => (v.x, v.y),
                    None => (0.0, 0.0),
                },
                distribution: distribution(t)?,
                reflect_tint: t.color("reflect_tint")?.unwrap_or(Rgb::ONE),
                transmit_tint: t.color("transmit_tint")?.unwrap_or(Rgb::ONE),
            }
        }
        "thin" => {
            let (ior, dispersion) = t.ior_spectrum("ior", 1.5)?;
            MaterialKindDesc::Thin {
                ior,
                ext_ior: t.number_or("ext_ior", 1.0)?,
                reflect_tint: t.color("reflect_tint")?.unwrap_or(Rgb::ONE),
                transmit_tint: t.color("transmit_tint")?.unwrap_or(Rgb::ONE),
                dispersion,
            }
        }
        "null" => MaterialKindDesc::NULL,
        "hair" => {
            let beta_n = t.number_or("beta_n", 0.3)?;
            let sigma_a = if let Some(s) = t.color("sigma_a")? {
                s
            } else if let Some(c) = t.color("reflectance")? {
                crate::material::hair::HairBsdf::sigma_a_from_reflectance(c, beta_n)
            } else {
                crate::material::hair::HairBsdf::sigma_a_from_concentration(
                    t.number_or("eumelanin", 1.3)?,
                    t.number_or("pheomelanin", 0.0)?,
                )
            };
            MaterialKindDesc::Hair(crate::material::hair::HairParams {
                sigma_a,
                eta: t.number_or("eta", 1.55)?,
                beta_m: t.number_or("beta_m", 0.3)?,
                beta_n,
                alpha: t.number_or("alpha", 2.0)?,
            })
        }
        "measured" => MaterialKindDesc::Measured {
            file: t.required("file", t.path("file")?)?,
        },
        "principled" => {
            let thin = t.boolean("thin")?.unwrap_or(false);
            let param = |key: &str, default: f32| -> Result<ColorSource> {
                Ok(t.color_source(key)?.unwrap_or(ColorSource::Rgb(Rgb::splat(default))))
            };
            let zero = ColorSource::Rgb(Rgb::ZERO);
            // The thin sheet has no metal or clearcoat; only it transmits diffusely.
            let (metallic, clearcoat, clearcoat_gloss, diff_trans) = if thin {
                (zero.clone(), zero.clone(), zero.clone(), param("diff_trans", 0.0)?)
            } else {
                (
                    param("metallic", 0.0)?,
                    param("clearcoat", 0.0)?,
                    param("clearcoat_gloss", 0.0)?,
                    zero,
                )
            };
            MaterialKindDesc::Principled {
                params: Box::new(crate::material::principled::PrincipledParams {
                    base_color: param("base_color", 0.5)?,
                    roughness: param("roughness", 0.5)?,
                    anisotropic: param("anisotropic", 0.0)?,
                    metallic,
                    spec_trans: param("spec_trans", 0.0)?,
                    spec_tint: param("spec_tint", 0.0)?,
                    sheen: param("sheen", 0.0)?,
                    sheen_tint: param("sheen_tint", 0.0)?,
                    flatness: param("flatness", 0.0)?,
                    clearcoat,
                    clearcoat_gloss,
                    diff_trans,
                }),
                eta: t.number_or("ior", 1.5)?,
                thin,
            }
        }
        "mix" => {
            let names = t.value("materials").and_then(|v| match v.get_ref() {
                DeValue::Array(a) => {
                    let names: Option<Vec<String>> =
                        a.iter().map(|x| x.get_ref().as_str().map(str::to_string)).collect();
                    names.and_then(|n| <[String; 2]>::try_from(n).ok())
                }
                _ => None,
            });
            let Some(materials) = names else {
                let span = t.value("materials").map(|v| v.span()).unwrap_or(t.span.clone());
                return Err(t.err_at(
                    "materials",
                    &span,
                    "a mix needs `materials`: the names of two materials, [\"a\", \"b\"]".to_string(),
                ));
            };
            MaterialKindDesc::Mix {
                choice: MixChoice::Weight(t.color_source("weight")?.unwrap_or(ColorSource::Rgb(Rgb::splat(0.5)))),
                materials,
            }
        }
        _ => MaterialKindDesc::Plastic {
            diffuse: t.color_source("diffuse")?.unwrap_or(ColorSource::Rgb(Rgb::splat(0.5))),
            ior: t.number_or("ior", 1.49)?,
            ext_ior: t.number_or("ext_ior", 1.0)?,
            roughness: t.number_or("roughness", 0.0)?,
            distribution: distribution(t)?,
            specular_tint: t.color("specular_tint")?.unwrap_or(Rgb::ONE),
            nonlinear: t.boolean("nonlinear")?.unwrap_or(false),
        },
    };
    let mut m = MaterialDesc::with_kind(name, kind);
    m.emission = t.color_source("emission")?.unwrap_or(ColorSource::Rgb(Rgb::ZERO));
    m.emits_both_sides = t.boolean("two_sided_emission")?.unwrap_or(false);
    m.two_sided = t.boolean("two_sided")?.unwrap_or(true);
    m.opacity = t.color_source("opacity")?;
    m.normal_map = t.color_source("normal_map")?.map(NormalMapDesc::new);
    if let Some(height) = t.color_source("bump_map")? {
        m.bump_map = Some(BumpMapDesc {
            height,
            scale: t.number_or("bump_scale", 1.0)?,
        });
    }
    if let Some(u) = t.string("roughness_texture")? {
        let v = t.string("roughness_texture_v")?.unwrap_or_else(|| u.clone());
        m.roughness_map = Some(RoughnessMapDesc {
            u: ColorSource::Texture(u),
            v: ColorSource::Texture(v),
            remap_sqrt: false,
        });
    }
    m.locs = t.finish()?;
    Ok(m)
}

/// A rough material's `distribution = "ggx" | "beckmann"` (GGX when absent).
fn distribution(t: &Table) -> Result<MicrofacetDistribution> {
    Ok(t.choice("distribution", &["ggx", "beckmann"])?
        .and_then(|d| MicrofacetDistribution::from_name(&d))
        .unwrap_or_default())
}

/// `[[medium]]`: `type = "homogeneous"` (σt and albedo everywhere the
/// shapes that bound it say), `"grid"` (σt from a Mitsuba `.vol` file
/// over the unit cube placed by `transform`, empty outside it; or from the
/// grid `grid` of a NanoVDB `.nvdb` file, placed by its own map and then
/// `transform`, empty outside its active voxels) or
/// `"cloud"` (σt times pbrt-v4's procedural cloud density over the unit
/// cube placed by `transform`, with its `density`, `wispiness` and
/// `frequency`).
fn read_medium(t: &Table) -> Result<MediumDesc> {
    let name = t.required_string("name")?;
    let kind = t
        .choice("type", &["homogeneous", "grid", "cloud"])?
        .unwrap_or_else(|| "homogeneous".into());
    let to_world = match t.value("transform") {
        Some(v) => read_transform(t, v)?,
        None => Vec::new(),
    };
    let sigma_t = match kind.as_str() {
        // σt comes from the file (times `scale`); a `sigma_t` key is
        // reported as unknown by `finish`.
        "grid" => {
            let file = t.required("file", t.path("file")?)?;
            let nanovdb = file.extension().is_some_and(|e| e.eq_ignore_ascii_case("nvdb"));
            let source = match t.string("grid")? {
                Some(grid) if nanovdb => GridSource::NanoVdb { path: file, grid },
                None if nanovdb => GridSource::NanoVdb {
                    path: file,
                    grid: "density".into(),
                },
                Some(_) => {
                    let span = t.value("grid").map(|v| v.span()).unwrap_or_default();
                    return Err(t.err_at(
                        "grid",
                        &span,
                        "names a grid of a NanoVDB (.nvdb) file; a .vol file has one",
                    ));
                }
                None => GridSource::MitsubaVol(file),
            };
            FieldDesc::Grid {
                source,
                to_world,
                use_file_bounds: false,
            }
        }
        "cloud" => FieldDesc::Cloud {
            value: t.color("sigma_t")?.unwrap_or(Rgb::ONE),
            density: finite_number(t, "density", 1.0)?,
            wispiness: finite_number(t, "wispiness", 1.0)?,
            frequency: finite_number(t, "frequency", 5.0)?,
            p0: glam::Vec3::ZERO,
            p1: glam::Vec3::ONE,
            to_world,
        },
        _ => FieldDesc::Constant(t.color("sigma_t")?.unwrap_or(Rgb::ONE)),
    };
    Ok(MediumDesc {
        name,
        sigma_t,
        albedo: FieldDesc::Constant(t.color("albedo")?.unwrap_or(Rgb::ONE)),
        emission: t.color("emission")?.map(FieldDesc::Constant),
        scale: t.color("scale")?.unwrap_or(Rgb::ONE),
        g: t.number_or("g", 0.0)?,
        locs: t.finish()?,
    })
}

/// The level set `name` of a NanoVDB file (where no name is given, its
/// one level set), its signed distances on the lattice of its active box,
/// and the map from the lattice's unit cube to the grid's space.
fn read_level_set(
    path: &Path,
    name: Option<&str>,
) -> std::result::Result<(crate::media::nanovdb::Lattice, glam::Mat4), String> {
    use crate::media::nanovdb::{CLASS_LEVEL_SET, NanoVdbGrid, grid_names};
    let in_file = |e: String| format!("{}: {e}", path.display());
    let bytes = crate::files::read_limited(path, crate::files::MAX_NANOVDB_BYTES).map_err(in_file)?;
    let names = grid_names(&bytes).map_err(in_file)?;
    let name = match name {
        Some(n) => n.to_string(),
        None => {
            let level_sets: Vec<&String> = names
                .iter()
                .filter(|n| {
                    NanoVdbGrid::from_file(&bytes, n).is_ok_and(|g| g.is_some_and(|g| g.class == CLASS_LEVEL_SET))
                })
                .collect();
            match level_sets[..] {
                [one] => one.clone(),
                _ => {
                    return Err(in_file(format!(
                        "it has {} level sets among its grids ({}): name one with `grid`",
                        level_sets.len(),
                        names.join(", ")
                    )));
                }
            }
        }
    };
    let grid = crate::scene::build::nanovdb_grid(&bytes, &name).map_err(in_file)?;
    if grid.class != CLASS_LEVEL_SET {
        return Err(in_file(format!(
            "grid \"{name}\" is not a level set (its class is {}): an SDF grid holds signed distances",
            grid.class
        )));
    }
    let lattice = grid
        .dense()
        .map_err(in_file)?
        .ok_or_else(|| in_file(format!("grid \"{name}\" has no active voxels")))?;
    let to_space = grid.lattice_to_space(&lattice);
    Ok((lattice, to_space))
}

/// Number `key` of `t`, or `default`; an error at the key where it is
/// not finite.
fn finite_number(t: &Table, key: &str, default: f32) -> Result<f32> {
    let Some(v) = t.value(key) else {
        return Ok(default);
    };
    let x = t.number_of(key, v)?;
    if !x.is_finite() {
        return Err(t.err_at(key, &v.span(), format!("must be a finite number, got {x}")));
    }
    Ok(x)
}

fn read_light(t: &Table) -> Result<LightDesc> {
    let kind = t.choice("type", &["point", "spot", "directional"])?;
    let kind = match t.required("type", kind)?.as_str() {
        "point" => LightKind::Point {
            position: t.required("position", t.vec3("position")?)?,
            intensity: t.color("intensity")?.unwrap_or(Rgb::ONE),
            falloff: t.boolean("falloff")?.unwrap_or(true),
        },
        "spot" => LightKind::Spot {
            position: t.required("position", t.vec3("position")?)?,
            to: t.required("to", t.vec3("to")?)?,
            intensity: t.color("intensity")?.unwrap_or(Rgb::ONE),
            inner_angle: t.number_or("inner_angle", 20.0)?,
            outer_angle: t.number_or("outer_angle", 30.0)?,
            profile: crate::light::SpotProfile::SmoothStepInCosine,
            projection: None,
            falloff: t.boolean("falloff")?.unwrap_or(true),
        },
        _ => LightKind::Directional {
            direction: t.required("direction", t.vec3("direction")?)?,
            irradiance: t.color("irradiance")?.unwrap_or(Rgb::ONE),
        },
    };
    Ok(LightDesc {
        kind,
        locs: t.finish()?,
    })
}

/// Reads a mesh given by `file`, inline arrays or `generate`. With
/// `required`, one of them must be present.
fn read_mesh_source(t: &Table, required: bool) -> Result<Option<MeshSource>> {
    let file = t.path("file")?;
    let generate = t.choice("generate", &["uv_sphere"])?;
    let positions = t.value("positions");
    let given = [file.is_some(), generate.is_some(), positions.is_some()]
        .iter()
        .filter(|&&b| b)
        .count();
    if given > 1 {
        return Err(Error::scene(
            Some(t.ctx.loc(&t.span)),
            t.key_path("file"),
            "give only one of `file`, `generate` and `positions`",
        ));
    }
    if let Some(f) = file {
        return Ok(Some(MeshSource::File(f)));
    }
    if generate.is_some() {
        let segments = t.unsigned("segments", u32::MAX as u64)?.unwrap_or(64) as u32;
        let rings = t.unsigned("rings", u32::MAX as u64)?.unwrap_or(32) as u32;
        return Ok(Some(MeshSource::UvSphere { segments, rings }));
    }
    let Some(pv) = positions else {
        if required {
            return Err(Error::scene(
                Some(t.ctx.loc(&t.span)),
                t.key_path("file"),
                "a mesh needs `file`, `generate` or `positions` (with `indices`)",
            ));
        }
        return Ok(None);
    };
    let mut mesh = TriangleMesh {
        positions: vec3_list(t, "positions", pv)?,
        ..TriangleMesh::default()
    };
    if let Some(v) = t.value("normals") {
        mesh.normals = vec3_list(t, "normals", v)?;
    }
    if let Some(v) = t.value("uvs") {
        let flat = flat_numbers(t, "uvs", v, 2)?;
        mesh.uvs = flat.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect();
    }
    let iv = t.value("indices").ok_or_else(|| {
        Error::scene(
            Some(t.ctx.loc(&pv.span())),
            t.key_path("indices"),
            "inline meshes need `indices`",
        )
    })?;
    let flat = flat_numbers(t, "indices", iv, 3)?;
    for &x in &flat {
        if x < 0.0 || x.fract() != 0.0 || x > u32::MAX as f32 {
            return Err(t.err_at(
                "indices",
                &iv.span(),
                format!("indices must be non-negative whole numbers, got {x}"),
            ));
        }
    }
    mesh.indices = flat
        .chunks_exact(3)
        .map(|c| [c[0] as u32, c[1] as u32, c[2] as u32])
        .collect();
    Ok(Some(MeshSource::Inline(mesh)))
}

/// Numbers from `[[a, b, c], …]` or a flat `[a, b, c, …]`, in groups of `n`.
fn flat_numbers(t: &Table, key: &str, v: &Value, n: usize) -> Result<Vec<f32>> {
    let DeValue::Array(items) = v.get_ref() else {
        return Err(t.expected(key, v, "an array"));
    };
    let mut out = Vec::with_capacity(items.len() * n);
    for item in items.iter() {
        match item.get_ref() {
            DeValue::Array(_) => out.extend(t.numbers_of(key, item, n)?),
            _ => out.push(t.number_of(key, item)?),
        }
    }
    if out.len() % n != 0 {
        return Err(t.err_at(
            key,
            &v.span(),
            format!("needs a multiple of {n} numbers, found {}", out.len()),
        ));
    }
    Ok(out)
}

fn vec3_list(t: &Table, key: &str, v: &Value) -> Result<Vec<Vec3>> {
    let flat = flat_numbers(t, key, v, 3)?;
    Ok(flat.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
}

/// One shape, or for a curve one shape per piece.
fn read_shape(t: &Table) -> Result<Vec<ShapeDesc>> {
    let mut more_pieces = Vec::new();
    let types = [
        "sphere",
        "plane",
        "rectangle",
        "disk",
        "box",
        "cylinder",
        "cone",
        "paraboloid",
        "hyperboloid",
        "bilinear",
        "bezier",
        "subdivision",
        "curve",
        "sdf",
        "sdfgrid",
        "implicit",
        "mesh",
    ];
    let kind = t.choice("type", &types)?;
    // A cut sphere is a quadric about its centre: this moves it there.
    let mut placed_at = None;
    // A NanoVDB level set's unit cube goes to the grid's space first.
    let mut placed_by = None;
    let quadric = |q: std::result::Result<crate::geometry::quadric::Quadric, String>| {
        q.map(ShapeKind::Quadric).map_err(|e| t.err_at("type", &t.span, e))
    };
    let kind = match t.required("type", kind)?.as_str() {
        "sphere" => {
            let center = t.vec3("center")?.unwrap_or(Vec3::ZERO);
            let radius = t.number_or("radius", 1.0)?;
            let (zmin, zmax, phimax) = (t.number("zmin")?, t.number("zmax")?, t.number("phimax")?);
            if zmin.is_some() || zmax.is_some() || phimax.is_some() {
                placed_at = Some(center);
                quadric(crate::geometry::quadric::Quadric::sphere(
                    radius,
                    zmin.unwrap_or(-radius),
                    zmax.unwrap_or(radius),
                    phimax.unwrap_or(360.0),
                ))?
            } else {
                ShapeKind::Sphere { center, radius }
            }
        }
        "cone" => quadric(crate::geometry::quadric::Quadric::cone(
            t.number_or("radius", 1.0)?,
            t.number_or("height", 1.0)?,
            t.number_or("phimax", 360.0)?,
        ))?,
        "paraboloid" => quadric(crate::geometry::quadric::Quadric::paraboloid(
            t.number_or("radius", 1.0)?,
            t.number_or("zmin", 0.0)?,
            t.number_or("zmax", 1.0)?,
            t.number_or("phimax", 360.0)?,
        ))?,
        "hyperboloid" => quadric(crate::geometry::quadric::Quadric::hyperboloid(
            t.vec3("p1")?.unwrap_or(Vec3::ZERO),
            t.vec3("p2")?.unwrap_or(Vec3::ONE),
            t.number_or("phimax", 360.0)?,
        ))?,
        "bilinear" => {
            let mut corners = [Vec3::ZERO; 4];
            for (corner, key) in corners.iter_mut().zip(["p00", "p10", "p01", "p11"]) {
                *corner = t.required(key, t.vec3(key)?)?;
            }
            let [p00, p10, p01, p11] = corners;
            ShapeKind::Bilinear(crate::geometry::bilinear::BilinearPatch::new(p00, p10, p01, p11))
        }
        "curve" => {
            use crate::geometry::curve::{Curve, CurveKind, bezier_segments};
            let points = match t.value("points") {
                Some(v) => vec3_list(t, "points", v)?,
                None => return Err(t.err_at("points", &t.span, "a curve needs its control `points`")),
            };
            let degree = t.number_or("degree", 3.0)?;
            let bspline = match t.string("basis")?.as_deref() {
                None | Some("bezier") => false,
                Some("bspline") => true,
                Some(other) => {
                    return Err(t.err_at("basis", &t.span, format!("\"{other}\": \"bezier\" or \"bspline\"")));
                }
            };
            let segments = bezier_segments(
                &points,
                bspline,
                if degree == 2.0 {
                    2
                } else if degree == 3.0 {
                    3
                } else {
                    0
                },
            )
            .map_err(|e| t.err_at("points", &t.span, e))?;
            let width = t.number_or("width", 0.1)?;
            let (w0, w1) = (t.number_or("width0", width)?, t.number_or("width1", width)?);
            if !(w0 >= 0.0 && w1 >= 0.0 && w0.is_finite() && w1.is_finite() && w0.max(w1) > 0.0) {
                return Err(t.err_at(
                    "width",
                    &t.span,
                    "widths must be finite, not negative and not both zero",
                ));
            }
            let kind = match t.string("curve_type")? {
                None => CurveKind::Cylinder,
                Some(k) => CurveKind::named(&k).ok_or_else(|| {
                    t.err_at(
                        "curve_type",
                        &t.span,
                        format!("\"{k}\": \"flat\", \"cylinder\" or \"ribbon\""),
                    )
                })?,
            };
            let normals = match t.value("normals") {
                Some(v) => Some(vec3_list(t, "normals", v)?),
                None => None,
            };
            if kind == CurveKind::Ribbon && normals.as_ref().is_none_or(|n| n.len() != segments.len() + 1) {
                return Err(t.err_at(
                    "normals",
                    &t.span,
                    format!(
                        "a ribbon of {} segments needs {} `normals`",
                        segments.len(),
                        segments.len() + 1
                    ),
                ));
            }
            let split = t.number_or("split_depth", 3.0)?.clamp(0.0, 10.0) as u32;
            let n = segments.len() as f32;
            let mut pieces = segments.iter().enumerate().flat_map(|(i, cp)| {
                let lerp = |x: f32| w0 + (w1 - w0) * x;
                let ends = normals
                    .as_ref()
                    .filter(|_| kind == CurveKind::Ribbon)
                    .map(|n| [n[i], n[i + 1]]);
                Curve::pieces(*cp, lerp(i as f32 / n), lerp((i + 1) as f32 / n), kind, ends, split)
            });
            let first = pieces.next().expect("a curve has a segment");
            more_pieces = pieces.map(ShapeKind::Curve).collect();
            ShapeKind::Curve(first)
        }
        "subdivision" => read_subdivision(t)?,
        "bezier" => {
            let mut kinds = read_bezier(t)?.into_iter();
            let first = kinds.next().expect("a Bézier shape has a patch");
            more_pieces = kinds.collect();
            first
        }
        "plane" => ShapeKind::Plane {
            point: t.vec3("point")?.unwrap_or(Vec3::ZERO),
            normal: t.vec3("normal")?.unwrap_or(Vec3::Y),
        },
        "rectangle" => ShapeKind::Rectangle {
            corner: t.vec3("corner")?.unwrap_or(Vec3::new(-1.0, 0.0, 1.0)),
            edge_u: t.vec3("edge_u")?.unwrap_or(Vec3::new(2.0, 0.0, 0.0)),
            edge_v: t.vec3("edge_v")?.unwrap_or(Vec3::new(0.0, 0.0, -2.0)),
        },
        "disk" => ShapeKind::Disk {
            center: t.vec3("center")?.unwrap_or(Vec3::ZERO),
            normal: t.vec3("normal")?.unwrap_or(Vec3::Y),
            radius: t.number_or("radius", 1.0)?,
            uv: crate::geometry::DiskUv::AngleRadius,
        },
        "box" => ShapeKind::Cuboid {
            min: t.vec3("min")?.unwrap_or(Vec3::splat(-1.0)),
            max: t.vec3("max")?.unwrap_or(Vec3::ONE),
        },
        "cylinder" => ShapeKind::Cylinder {
            p0: t.vec3("p0")?.unwrap_or(Vec3::ZERO),
            p1: t.vec3("p1")?.unwrap_or(Vec3::Y),
            radius: t.number_or("radius", 1.0)?,
        },
        "sdf" => {
            let node = t.required("sdf", t.table("sdf")?)?;
            let mut builder = SdfBuilder::new();
            let root = read_sdf_node(&node, &mut builder, 0)?;
            let epsilon = t.number("epsilon")?;
            let max_steps = t
                .unsigned("max_steps", sdf::MAX_MAX_STEPS as u64)?
                .map_or(sdf::DEFAULT_MAX_STEPS, |n| n as u32);
            let shape = builder
                .build(root, epsilon, max_steps)
                .map_err(|e| t.err_at("sdf", &node.span, e))?;
            ShapeKind::Sdf(Arc::new(shape.with_origin(t.ctx.loc(&t.span).to_string())))
        }
        "sdfgrid" => {
            // Mitsuba's `sdfgrid`: a one-channel `.vol` grid of signed
            // distances over the object's unit cube; or a level set of a
            // NanoVDB file, placed by the grid's own map. Read here
            // (relative to the scene file) so that errors name this key.
            let file = t.required("file", t.path("file")?)?;
            let at = t.value("file").map(|v| v.span()).unwrap_or(t.span.clone());
            let path = t.ctx.file.parent().unwrap_or(Path::new("")).join(&file);
            let smooth = t.choice("normals", &["smooth", "analytic"])?.as_deref() != Some("analytic");
            let grid_name = t.string("grid")?;
            let (res, values) = if file.extension().is_some_and(|e| e.eq_ignore_ascii_case("nvdb")) {
                let (lattice, to_space) =
                    read_level_set(&path, grid_name.as_deref()).map_err(|e| t.err_at("file", &at, e))?;
                placed_by = Some(to_space);
                (lattice.res, lattice.values)
            } else {
                if grid_name.is_some() {
                    let span = t.value("grid").map(|v| v.span()).unwrap_or_default();
                    return Err(t.err_at(
                        "grid",
                        &span,
                        "names a grid of a NanoVDB (.nvdb) file; a .vol file has one",
                    ));
                }
                let grid = crate::media::grid::VoxelGrid::load_mitsuba_vol(&path)
                    .map_err(|e| t.err_at("file", &at, e.to_string()))?;
                if grid.channels != 1 {
                    return Err(t.err_at(
                        "file",
                        &at,
                        format!("{}: an SDF grid has one channel, not {}", path.display(), grid.channels),
                    ));
                }
                (grid.res, grid.data)
            };
            let sdf = crate::geometry::sdf_grid::SdfGrid::new(res, values, smooth)
                .map_err(|e| t.err_at("file", &at, format!("{}: {e}", path.display())))?;
            ShapeKind::SdfGrid(Arc::new(sdf))
        }
        "implicit" => {
            let text = t.required_string("equation")?;
            let at = t.value("equation").map(|v| v.span()).unwrap_or(t.span.clone());
            let equation = crate::geometry::implicit::Equation::parse(&text).map_err(|e| {
                // The column inside a one-line string written with quotes.
                let mut span = at.clone();
                span.start += e.column;
                t.err_at("equation", &span, e.message)
            })?;
            let bounds_value = t.required("bounds", t.value("bounds"))?;
            let corners = flat_numbers(t, "bounds", bounds_value, 3)?;
            if corners.len() != 6 {
                return Err(t.err_at(
                    "bounds",
                    &bounds_value.span(),
                    "bounds are two corners, [[xmin, ymin, zmin], [xmax, ymax, zmax]]",
                ));
            }
            let bounds = crate::geometry::Aabb {
                min: Vec3::new(corners[0], corners[1], corners[2]),
                max: Vec3::new(corners[3], corners[4], corners[5]),
            };
            let max_evaluations = t
                .unsigned("max_evaluations", 1 << 20)?
                .map_or(crate::geometry::implicit::DEFAULT_MAX_EVALUATIONS, |n| n as u32);
            let surface = crate::geometry::implicit::ImplicitSurface::new(equation, bounds, max_evaluations)
                .map_err(|e| t.err_at("bounds", &bounds_value.span(), e))?;
            ShapeKind::Implicit(Arc::new(surface.with_origin(t.ctx.loc(&t.span).to_string())))
        }
        _ => match t.string("mesh")? {
            Some(name) => {
                if read_mesh_source(t, false)?.is_some() {
                    return Err(Error::scene(
                        Some(t.ctx.loc(&t.span)),
                        t.key_path("mesh"),
                        "give either `mesh` (a named mesh) or the mesh data, not both",
                    ));
                }
                ShapeKind::Mesh(name)
            }
            None => ShapeKind::InlineMesh(read_mesh_source(t, true)?.expect("required")),
        },
    };
    let mut transform = match t.value("transform") {
        Some(v) => read_transform(t, v)?,
        None => Vec::new(),
    };
    if let Some(center) = placed_at {
        transform.insert(0, TransformOp::Translate(center));
    }
    if let Some(m) = placed_by {
        transform.insert(0, TransformOp::Matrix(m));
    }
    let material = t.string("material")?;
    let flip_normals = t.boolean("flip_normals")?.unwrap_or(false);
    let inside = t.string("inside")?;
    let outside = t.string("outside")?;
    let media = (inside.is_some() || outside.is_some()).then_some(MediumInterfaceDesc { inside, outside });
    let motion = match t.value("transform_end") {
        Some(v) => {
            let mut end = read_transform(t, v)?;
            if let Some(center) = placed_at {
                end.insert(0, TransformOp::Translate(center));
            }
            if let Some(m) = placed_by {
                end.insert(0, TransformOp::Matrix(m));
            }
            let times = t.vec2("motion_times")?.map_or((0.0, 1.0), |v| (v.x, v.y));
            Some(MotionDesc { end, times })
        }
        None => {
            if t.value("motion_times").is_some() {
                let span = t.value("motion_times").map(|v| v.span()).unwrap_or(t.span.clone());
                return Err(t.err_at(
                    "motion_times",
                    &span,
                    "needs `transform_end`, the transform at the second time",
                ));
            }
            None
        }
    };
    let first = ShapeDesc {
        kind,
        transform,
        material,
        flip_normals,
        media,
        motion,
        locs: t.finish()?,
    };
    let rest: Vec<ShapeDesc> = more_pieces
        .into_iter()
        .map(|kind| ShapeDesc { kind, ..first.clone() })
        .collect();
    Ok(std::iter::once(first).chain(rest).collect())
}

/// `type = "subdivision"`: a subdivision surface of the control mesh
/// `positions` and polygon `faces` (lists of indices), `levels` rounds
/// (3) of Catmull–Clark (`scheme = "catmull-clark"`, the default) or Loop
/// (`"loop"`, triangles only) refinement, its vertices on the limit
/// surface.
fn read_subdivision(t: &Table) -> Result<ShapeKind> {
    let positions = match t.value("positions") {
        Some(v) => vec3_list(t, "positions", v)?,
        None => {
            return Err(t.err_at(
                "positions",
                &t.span,
                "a subdivision surface needs its control `positions`",
            ));
        }
    };
    if !positions.iter().all(|p| p.is_finite()) {
        return Err(t.err_at("positions", &t.span, "control points must be finite"));
    }
    let Some(fv) = t.value("faces") else {
        return Err(t.err_at(
            "faces",
            &t.span,
            "a subdivision surface needs its `faces`, lists of indices",
        ));
    };
    let DeValue::Array(items) = fv.get_ref() else {
        return Err(t.expected("faces", fv, "an array of faces"));
    };
    let mut faces = Vec::with_capacity(items.len());
    for item in items.iter() {
        let DeValue::Array(corners) = item.get_ref() else {
            return Err(t.expected("faces", item, "a face: an array of indices"));
        };
        let mut face = Vec::with_capacity(corners.len());
        for c in corners.iter() {
            let x = t.number_of("faces", c)?;
            if x < 0.0 || x.fract() != 0.0 || x > u32::MAX as f32 {
                return Err(t.err_at(
                    "faces",
                    &c.span(),
                    format!("indices must be non-negative whole numbers, got {x}"),
                ));
            }
            face.push(x as u32);
        }
        faces.push(face);
    }
    let levels = t.number_or("levels", 3.0)?;
    if !(0.0..=64.0).contains(&levels) || levels.fract() != 0.0 {
        return Err(t.err_at("levels", &t.span, format!("{levels} is not a number of levels")));
    }
    let scheme = t.choice("scheme", &["catmull-clark", "loop"])?;
    let mesh = match scheme.as_deref() {
        Some("loop") => {
            let triangles: Vec<[u32; 3]> = faces
                .iter()
                .map(|f| <[u32; 3]>::try_from(f.as_slice()))
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| {
                    t.err_at(
                        "faces",
                        &fv.span(),
                        "Loop subdivision needs triangles (faces of 3 indices)",
                    )
                })?;
            crate::geometry::subdivision::loop_subdivide(&positions, &triangles, levels as u32)
        }
        _ => crate::geometry::catmull_clark::catmull_clark(&positions, &faces, levels as u32),
    }
    .map_err(|e| t.err_at("faces", &fv.span(), e))?;
    Ok(ShapeKind::InlineMesh(MeshSource::Inline(mesh)))
}

/// `type = "bezier"`: bicubic Bézier patches, from 16 control `points`
/// (row by row) or a `.bpt` `file` of Newell's format (the teapot's),
/// intersected directly, or with `tessellate = N` as one mesh of N × N
/// quads per patch.
fn read_bezier(t: &Table) -> Result<Vec<ShapeKind>> {
    use crate::geometry::bezier::{BezierPatch, parse_bpt, tessellate};
    let patches = match (t.value("points"), t.path("file")?) {
        (Some(v), None) => {
            let points = vec3_list(t, "points", v)?;
            let points: [Vec3; 16] = points.try_into().map_err(|p: Vec<Vec3>| {
                t.err_at(
                    "points",
                    &v.span(),
                    format!("a bicubic patch has 16 control points, got {}", p.len()),
                )
            })?;
            if !points.iter().all(|p| p.is_finite()) {
                return Err(t.err_at("points", &v.span(), "control points must be finite"));
            }
            vec![BezierPatch::new(points)]
        }
        (None, Some(file)) => {
            let full = t.ctx.file.parent().unwrap_or(Path::new("")).join(&file);
            let at = &t.value("file").expect("read").span();
            let bytes = crate::files::read_limited(&full, crate::files::MAX_SCENE_BYTES)
                .map_err(|e| t.err_at("file", at, format!("cannot read {}: {e}", full.display())))?;
            let text =
                String::from_utf8(bytes).map_err(|_| t.err_at("file", at, format!("{}: not text", full.display())))?;
            parse_bpt(&text).map_err(|e| t.err_at("file", at, format!("{}: {e}", full.display())))?
        }
        _ => {
            return Err(t.err_at(
                "points",
                &t.span,
                "a Bézier patch needs its 16 control `points` or a `.bpt` `file`, one of the two",
            ));
        }
    };
    let Some(n) = t.number("tessellate")? else {
        return Ok(patches
            .into_iter()
            .map(|p| ShapeKind::Bezier(std::sync::Arc::new(p)))
            .collect());
    };
    if !(1.0..=1024.0).contains(&n) || n.fract() != 0.0 {
        return Err(t.err_at(
            "tessellate",
            &t.span,
            format!("{n} is not a number of quads a side (1 to 1024)"),
        ));
    }
    let mut mesh = TriangleMesh::default();
    for patch in &patches {
        let (positions, normals, uvs, indices) = tessellate(patch, n as u32);
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(positions);
        mesh.normals.extend(normals);
        mesh.uvs.extend(uvs);
        mesh.indices.extend(indices.into_iter().map(|i| i.map(|k| k + base)));
    }
    Ok(vec![ShapeKind::InlineMesh(MeshSource::Inline(mesh))])
}

/// The kinds of node of a distance function, each written as the key that
/// holds its main parameter.
const SDF_KINDS: [&str; 15] = [
    "sphere",
    "box",
    "torus",
    "capsule",
    "cylinder",
    "cone",
    "plane",
    "mandelbulb",
    "union",
    "intersection",
    "difference",
    "repeat",
    "twist",
    "bend",
    "displace",
];

/// One node of a distance function (`{ sphere = 1 }`, `{ union = [..],
/// smooth = 0.1 }`, …), with its children, its optional `round` and
/// `transform`; returns its index in `b`.
fn read_sdf_node(t: &Table, b: &mut SdfBuilder, depth: usize) -> Result<u32> {
    if depth >= sdf::MAX_SDF_DEPTH {
        return Err(node_error(
            t,
            format!("a distance function may nest at most {} deep", sdf::MAX_SDF_DEPTH),
        ));
    }
    let present: Vec<&str> = SDF_KINDS
        .iter()
        .copied()
        .filter(|k| t.table.iter().any(|(key, _)| key.get_ref().as_ref() == *k))
        .collect();
    let kind = match present.as_slice() {
        [k] => *k,
        [] => {
            return Err(node_error(
                t,
                format!("a distance function node needs one of {}", SDF_KINDS.join(", ")),
            ));
        }
        more => {
            return Err(node_error(
                t,
                format!("a node is one kind, found {}", more.join(" and ")),
            ));
        }
    };
    let v = t.value(kind).expect("present");
    let built = match kind {
        "sphere" => b.sphere(t.number_of(kind, v)?),
        "box" => match v.get_ref() {
            DeValue::Array(_) => b.cuboid(t.vec3_of(kind, v)?),
            _ => b.cuboid(Vec3::splat(t.number_of(kind, v)?)),
        },
        "torus" => {
            let r = t.numbers_of(kind, v, 2)?;
            b.torus(r[0], r[1])
        }
        "capsule" => {
            let DeValue::Array(ends) = v.get_ref() else {
                return Err(t.expected(kind, v, "an array of two points"));
            };
            if ends.len() != 2 {
                return Err(t.err_at(kind, &v.span(), "a capsule is an array of its two end points"));
            }
            let (a, c) = (t.vec3_of(kind, &ends[0])?, t.vec3_of(kind, &ends[1])?);
            let radius = t.required("radius", t.number("radius")?)?;
            b.capsule(a, c, radius)
        }
        "cylinder" | "cone" => {
            let r = t.numbers_of(kind, v, 2)?;
            if kind == "cone" {
                b.cone(r[0], r[1])
            } else {
                b.cylinder(r[0], r[1])
            }
        }
        "plane" => b.plane(t.vec3_of(kind, v)?, t.number_or("offset", 0.0)?),
        "mandelbulb" => {
            let iterations = t
                .unsigned("iterations", sdf::MAX_MANDELBULB_ITERATIONS as u64)?
                .unwrap_or(12);
            b.mandelbulb(t.number_of(kind, v)?, iterations as u32)
        }
        "union" | "intersection" | "difference" => {
            let DeValue::Array(items) = v.get_ref() else {
                return Err(t.expected(kind, v, "an array of nodes"));
            };
            if items.len() < 2 {
                return Err(t.err_at(kind, &v.span(), format!("a {kind} needs at least two nodes")));
            }
            let smooth = t.number_or("smooth", 0.0)?;
            let mut acc = None;
            for (i, item) in items.iter().enumerate() {
                let key = format!("{kind}[{i}]");
                let n = read_sdf_node(&sdf_child(t, &key, item)?, b, depth + 1)?;
                acc = Some(match acc {
                    None => n,
                    Some(a) => {
                        let r = match kind {
                            "union" => b.union(a, n, smooth),
                            "intersection" => b.intersection(a, n, smooth),
                            _ => b.difference(a, n, smooth),
                        };
                        r.map_err(|e| t.err_at(kind, &item.span(), e))?
                    }
                });
            }
            Ok(acc.expect("two or more"))
        }
        _ => {
            let inner = read_sdf_node(&sdf_child(t, kind, v)?, b, depth + 1)?;
            match kind {
                "repeat" => {
                    let period = t.required("period", t.vec3_or_scalar("period")?)?;
                    let count = t.required("count", t.vec3_or_scalar("count")?)?;
                    if count.cmplt(Vec3::ZERO).any()
                        || count.fract() != Vec3::ZERO
                        || count.cmpgt(Vec3::splat(1e4)).any()
                    {
                        return Err(t.err_at(
                            "count",
                            &t.span,
                            "counts are whole numbers of copies on each side, 0 to 10000",
                        ));
                    }
                    b.repeat(inner, period, [count.x as u32, count.y as u32, count.z as u32])
                }
                "twist" => b.twist(inner, t.required("rate", t.number("rate")?)?),
                "bend" => b.bend(inner, t.required("rate", t.number("rate")?)?),
                _ => b.displace(
                    inner,
                    t.required("amplitude", t.number("amplitude")?)?,
                    t.number_or("frequency", 1.0)?,
                    t.unsigned("seed", u32::MAX as u64)?.unwrap_or(0) as u32,
                ),
            }
        }
    };
    let mut node = built.map_err(|e| t.err_at(kind, &v.span(), e))?;
    if let Some(r) = t.number("round")? {
        node = b.round(node, r).map_err(|e| t.err_at("round", &t.span, e))?;
    }
    if let Some(tv) = t.value("transform") {
        let mut to_parent = crate::geometry::Transform::IDENTITY;
        for op in read_transform(t, tv)? {
            let step = op
                .to_transform()
                .map_err(|e| t.err_at("transform", &tv.span(), format!("{}: {e}", op.name())))?;
            to_parent = to_parent.then(&step);
        }
        node = b
            .transform(node, &to_parent)
            .map_err(|e| t.err_at("transform", &tv.span(), e))?;
    }
    t.finish()?;
    Ok(node)
}

/// An error about node `t` as a whole.
fn node_error(t: &Table, msg: String) -> Error {
    Error::scene(Some(t.ctx.loc(&t.span)), t.path.clone(), msg)
}

/// The node that `v`, the value of `key` in `t`, holds.
fn sdf_child<'a>(t: &Table<'a>, key: &str, v: &'a Value<'a>) -> Result<Table<'a>> {
    match v.get_ref() {
        DeValue::Table(inner) => Ok(Table::new(t.ctx, t.key_path(key), inner, v.span())),
        _ => Err(t.expected(key, v, "a table (a node such as { sphere = 1 })")),
    }
}

/// `transform = [{ translate = [..] }, { rotate = { axis = [..], angle = .. } }, ...]`
fn read_transform(t: &Table, v: &Value) -> Result<Vec<TransformOp>> {
    let DeValue::Array(steps) = v.get_ref() else {
        return Err(t.expected("transform", v, "an array of steps like { translate = [x, y, z] }"));
    };
    let mut ops = Vec::new();
    for (i, step) in steps.iter().enumerate() {
        let DeValue::Table(st) = step.get_ref() else {
            return Err(t.expected(&format!("transform[{i}]"), step, "a table like { scale = 2 }"));
        };
        let s = Table::new(t.ctx, t.key_path(&format!("transform[{i}]")), st, step.span());
        if st.len() != 1 {
            return Err(s.err_at(
                "",
                &step.span(),
                "each step must have exactly one of translate, rotate, scale, shear, matrix",
            ));
        }
        let op = if let Some(x) = s.vec3("translate").transpose() {
            TransformOp::Translate(x?)
        } else if let Some(x) = s.vec3_or_scalar("scale").transpose() {
            TransformOp::Scale(x?)
        } else if let Some(r) = s.table("rotate")? {
            let axis = r.required("axis", r.vec3("axis")?)?;
            let degrees = r.required("angle", r.number("angle")?)?;
            r.finish()?;
            TransformOp::Rotate { axis, degrees }
        } else if let Some(sh) = s.table("shear")? {
            let op = TransformOp::Shear {
                xy: sh.number_or("xy", 0.0)?,
                xz: sh.number_or("xz", 0.0)?,
                yx: sh.number_or("yx", 0.0)?,
                yz: sh.number_or("yz", 0.0)?,
                zx: sh.number_or("zx", 0.0)?,
                zy: sh.number_or("zy", 0.0)?,
            };
            sh.finish()?;
            op
        } else if let Some(mv) = s.value("matrix") {
            let m = s.numbers_of("matrix", mv, 16)?;
            // Written row by row, as on paper.
            TransformOp::Matrix(Mat4::from_cols(
                Vec4::new(m[0], m[4], m[8], m[12]),
                Vec4::new(m[1], m[5], m[9], m[13]),
                Vec4::new(m[2], m[6], m[10], m[14]),
                Vec4::new(m[3], m[7], m[11], m[15]),
            ))
        } else {
            return Err(s
                .finish()
                .err()
                .unwrap_or_else(|| s.err_at("", &step.span(), "empty transform step")));
        };
        ops.push(op);
    }
    Ok(ops)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(s: &str) -> Result<SceneDesc> {
        parse(s, Path::new("test.toml"))
    }

    /// A curve is a shape per piece, all with the table's material and
    /// transform; hair reads its absorption three ways.
    #[test]
    fn curves_and_hair() {
        let d = parse_str(
            r#"
[[material]]
name = "fur"
type = "hair"
reflectance = [0.6, 0.4, 0.2]

[[shape]]
type = "curve"
points = [[0, 0, 0], [1, 1, 0], [2, -1, 0], [3, 0, 0], [4, 1, 0], [5, 0, 0], [6, 0, 0]]
width0 = 0.1
width1 = 0.02
split_depth = 2
material = "fur"
transform = [{ translate = [0, 1, 0] }]
"#,
        )
        .unwrap();
        assert_eq!(d.shapes.len(), 2 * 4);
        assert!(d.shapes.iter().all(|s| matches!(s.kind, ShapeKind::Curve(_))
            && s.material.as_deref() == Some("fur")
            && s.transform.len() == 1));
        assert!(matches!(d.materials[0].kind, MaterialKindDesc::Hair(h)
            if h.sigma_a == crate::material::hair::HairBsdf::sigma_a_from_reflectance(Rgb::new(0.6, 0.4, 0.2), 0.3)));
        let e = parse_str("[[shape]]\ntype = \"curve\"\npoints = [[0, 0, 0], [1, 1, 0], [2, 0, 0], [3, 0, 0]]\ncurve_type = \"ribbon\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("needs 2 `normals`"), "{e}");
        let e = parse_str("[[shape]]\ntype = \"curve\"\npoints = [[0, 0, 0], [1, 1, 0]]\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("4 + n·3"), "{e}");
    }

    const MINIMAL: &str = r#"
[render]
width = 64
height = 48
spp = 4

[camera]
from = [0, 1, 5]
to = [0, 1, 0]

[[material]]
name = "red"
diffuse = [0.8, 0.1, 0.1]

[[shape]]
type = "sphere"
center = [0, 1, 0]
radius = 1
material = "red"
"#;

    #[test]
    fn reads_a_minimal_scene() {
        let d = parse_str(MINIMAL).unwrap();
        assert_eq!((d.settings.width, d.settings.height, d.settings.spp), (64, 48, 4));
        let MaterialKindDesc::Classic(c) = &d.materials[0].kind else {
            panic!("classic by default")
        };
        assert_eq!(c.diffuse, ColorSource::Rgb(Rgb::new(0.8, 0.1, 0.1)));
        assert_eq!(
            d.shapes[0].kind,
            ShapeKind::Sphere {
                center: Vec3::Y,
                radius: 1.0
            }
        );
        assert_eq!(d.shapes[0].locs.item.as_ref().unwrap().line, 15);
    }

    fn error_of(s: &str) -> String {
        parse_str(s).unwrap_err().to_string()
    }

    /// An `sdfgrid` reads its `.vol` file relative to the scene file and
    /// spans the unit cube, placed by its transform: a ray down the middle
    /// meets the grid's sphere (radius 0.3 about the cube's centre) where
    /// the sphere is. A missing file, a grid of three channels and an
    /// unknown normals mode are errors naming the key and line.
    #[test]
    fn sdf_grids_are_read_relative_to_the_scene_file() {
        let dir = tempfile::tempdir().unwrap();
        let vol = |channels: i32| {
            let mut vol = b"VOL".to_vec();
            vol.push(3);
            for v in [1i32, 11, 11, 11, channels] {
                vol.extend(v.to_le_bytes());
            }
            for v in [0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
                vol.extend(v.to_le_bytes());
            }
            for i in 0..11 * 11 * 11 {
                let (x, y, z) = (i % 11, i / 11 % 11, i / 121);
                let p = Vec3::new(x as f32, y as f32, z as f32) / 10.0;
                for _ in 0..channels {
                    vol.extend(((p - Vec3::splat(0.5)).length() - 0.3).to_le_bytes());
                }
            }
            vol
        };
        std::fs::write(dir.path().join("ball.vol"), vol(1)).unwrap();
        std::fs::write(dir.path().join("rgb.vol"), vol(3)).unwrap();
        let scene = |extra: &str| {
            MINIMAL.replace(
                "type = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1",
                &format!("type = \"sdfgrid\"\n{extra}\ntransform = [{{ translate = [-0.5, 0.5, -0.5] }}]"),
            )
        };
        let path = dir.path().join("grid.toml");
        let d = parse(&scene("file = \"ball.vol\"\nnormals = \"analytic\""), &path).unwrap();
        assert!(matches!(d.shapes[0].kind, ShapeKind::SdfGrid(_)));
        let built = crate::scene::build(&d).unwrap();
        let hit = built
            .intersect(&crate::geometry::Ray::new(Vec3::new(0.0, 1.0, 3.0), Vec3::NEG_Z))
            .expect("the ray meets the grid's sphere");
        assert!((hit.p.z - 0.3).abs() < 0.01, "{:?}", hit.p);
        for (extra, words) in [
            ("file = \"missing.vol\"", ["shape[0].file", "missing.vol"]),
            ("file = \"rgb.vol\"", ["rgb.vol", "one channel"]),
            ("file = \"ball.vol\"\nnormals = \"flat\"", ["normals", "smooth"]),
        ] {
            let e = parse(&scene(extra), &path).unwrap_err().to_string();
            assert!(e.contains("grid.toml:17:") || e.contains("grid.toml:18:"), "{e}");
            assert!(words.iter().all(|w| e.contains(w)), "{extra}: {e}");
        }
    }

    #[test]
    fn hide_emitters_is_read_and_off_by_default() {
        assert!(!parse_str(MINIMAL).unwrap().settings.hide_emitters);
        let d = parse_str(&MINIMAL.replace("spp = 4", "spp = 4\nhide_emitters = true")).unwrap();
        assert!(d.settings.hide_emitters);
        let e = error_of(&MINIMAL.replace("spp = 4", "spp = 4\nhide_emitters = 1"));
        assert!(e.starts_with("test.toml:6:") && e.contains("hide_emitters"), "{e}");
    }

    #[test]
    fn ao_distance_is_read_and_must_be_positive() {
        assert_eq!(parse_str(MINIMAL).unwrap().settings.ao_distance, f32::INFINITY);
        let d = parse_str(&MINIMAL.replace("spp = 4", "spp = 4\nintegrator = \"ao\"\nao_distance = 0.5")).unwrap();
        assert_eq!(d.settings.ao_distance, 0.5);
        let e = error_of(&MINIMAL.replace("spp = 4", "spp = 4\nao_distance = 0"));
        assert!(
            e.starts_with("test.toml:6:") && e.contains("ao_distance") && e.contains("positive"),
            "{e}"
        );
    }

    /// The Metropolis parameters are read, and out of range name their key
    /// and line (a bootstrap too large for the path lengths included: its
    /// weights would be a giant allocation).
    #[test]
    fn metropolis_parameters_are_read_and_checked() {
        let with = |keys: &str| MINIMAL.replace("spp = 4", &format!("spp = 4\nintegrator = \"mlt\"\n{keys}"));
        let d = parse_str(&with(
            "mlt_bootstrap = 500\nmlt_chains = 7\nmlt_large_step = 0.5\nmlt_sigma = 0.02",
        ))
        .unwrap();
        let m = d.settings.mlt;
        assert_eq!(
            (m.bootstrap, m.chains, m.large_step_probability, m.sigma),
            (500, 7, 0.5, 0.02)
        );
        for (keys, key, line) in [
            ("mlt_bootstrap = 0", "mlt_bootstrap", 7),
            ("max_depth = 64\nmlt_bootstrap = 2000000", "mlt_bootstrap", 8),
            ("mlt_chains = 0", "mlt_chains", 7),
            ("mlt_large_step = 1.5", "mlt_large_step", 7),
            ("mlt_sigma = 0", "mlt_sigma", 7),
        ] {
            let e = error_of(&with(keys));
            assert!(
                e.starts_with(&format!("test.toml:{line}:")) && e.contains(key),
                "{keys}: {e}"
            );
        }
    }

    #[test]
    fn every_sampler_name_is_read_and_sobol_is_the_default() {
        assert_eq!(parse_str(MINIMAL).unwrap().settings.sampler, SamplerKind::Sobol);
        for name in SamplerKind::NAMES {
            let d = parse_str(&MINIMAL.replace("spp = 4", &format!("spp = 4\nsampler = \"{name}\""))).unwrap();
            assert_eq!(d.settings.sampler.name(), name);
        }
        let e = error_of(&MINIMAL.replace("spp = 4", "spp = 4\nsampler = \"pmj02bn\""));
        assert!(e.starts_with("test.toml:6:") && e.contains("sobol"), "{e}");
    }

    /// `filter_radius` is one radius or one per axis.
    #[test]
    fn filter_radii_per_axis() {
        let with = |radius: &str| {
            parse_str(&MINIMAL.replace(
                "spp = 4",
                &format!("spp = 4\nfilter = \"tent\"\nfilter_radius = {radius}"),
            ))
            .unwrap()
            .settings
            .pixel_filter()
        };
        assert_eq!(
            with("1.5"),
            crate::settings::PixelFilter::same(Filter::Tent { radius: 1.5 })
        );
        assert_eq!(with("[1.5, 1.5]"), with("1.5"));
        let two = with("[1, 2.5]");
        assert_eq!(
            (two.x, two.y),
            (Filter::Tent { radius: 1.0 }, Filter::Tent { radius: 2.5 })
        );
    }

    #[test]
    fn rough_materials_name_their_microfacet_distribution() {
        let with = |kind: &str, extra: &str| {
            MINIMAL.replace(
                "diffuse = [0.8, 0.1, 0.1]",
                &format!("type = \"{kind}\"\nroughness = 0.2\n{extra}"),
            )
        };
        for kind in ["conductor", "dielectric", "plastic"] {
            let d = parse_str(&with(kind, "distribution = \"beckmann\"")).unwrap();
            let distribution = match d.materials[0].kind {
                MaterialKindDesc::Conductor { distribution, .. }
                | MaterialKindDesc::Dielectric { distribution, .. }
                | MaterialKindDesc::Plastic { distribution, .. } => distribution,
                _ => panic!("{kind}"),
            };
            assert_eq!(distribution, MicrofacetDistribution::Beckmann, "{kind}");
            let d = parse_str(&with(kind, "")).unwrap();
            assert!(matches!(
                d.materials[0].kind,
                MaterialKindDesc::Conductor {
                    distribution: MicrofacetDistribution::Ggx,
                    ..
                } | MaterialKindDesc::Dielectric {
                    distribution: MicrofacetDistribution::Ggx,
                    ..
                } | MaterialKindDesc::Plastic {
                    distribution: MicrofacetDistribution::Ggx,
                    ..
                }
            ));
        }
        let d = parse_str(&with("plastic", "bump_map = [0.5, 0.5, 0.5]\nbump_scale = 0.25")).unwrap();
        assert_eq!(
            d.materials[0].bump_map,
            Some(BumpMapDesc {
                height: ColorSource::Rgb(Rgb::splat(0.5)),
                scale: 0.25
            })
        );
        let e = error_of(&with(
            "plastic",
            "bump_map = [0.5, 0.5, 0.5]\nnormal_map = [0.5, 0.5, 1.0]",
        ));
        assert!(e.contains("bump_map") && e.contains("not both"), "{e}");
        let d = parse_str(&MINIMAL.replace(
            "diffuse = [0.8, 0.1, 0.1]",
            "type = \"principled\"\nbase_color = [0.2, 0.8, 0.1]\nmetallic = 0.3\nior = 1.4",
        ))
        .unwrap();
        let MaterialKindDesc::Principled { params, eta, thin } = &d.materials[0].kind else {
            panic!("{:?}", d.materials[0].kind)
        };
        assert_eq!((*eta, *thin), (1.4, false));
        assert_eq!(params.base_color, ColorSource::Rgb(Rgb::new(0.2, 0.8, 0.1)));
        assert_eq!(params.metallic, ColorSource::Rgb(Rgb::splat(0.3)));
        assert_eq!(params.roughness, ColorSource::Rgb(Rgb::splat(0.5)));
        // A thin sheet has no metal.
        let e = error_of(&MINIMAL.replace(
            "diffuse = [0.8, 0.1, 0.1]",
            "type = \"principled\"\nthin = true\nmetallic = 0.3",
        ));
        assert!(e.contains("metallic"), "{e}");
        let d = parse_str(&with("plastic", "normal_map = [0.5, 0.6, 0.9]")).unwrap();
        assert_eq!(
            d.materials[0].normal_map,
            Some(NormalMapDesc::new(ColorSource::Rgb(Rgb::new(0.5, 0.6, 0.9))))
        );
        let e = error_of(&with("conductor", "distribution = \"phong\""));
        assert!(e.starts_with("test.toml:") && e.contains("beckmann"), "{e}");
    }

    #[test]
    fn syntax_errors_have_positions() {
        let e = error_of("[render]\nwidth = = 3\n");
        assert!(e.starts_with("test.toml:2:"), "{e}");
        assert!(e.contains("TOML syntax error"), "{e}");
    }

    #[test]
    fn unknown_keys_are_named_with_suggestions() {
        let e = error_of(&MINIMAL.replace("radius = 1", "radus = 1"));
        assert!(
            e.starts_with("test.toml:18:1: `shape[0].radus`: unknown key (did you mean \"radius\"?)"),
            "{e}"
        );
        let e = error_of("[render]\nsamples = 16\n");
        assert!(
            e.contains("`render.samples`: unknown key (did you mean \"spp\"?)"),
            "{e}"
        );
        let e = error_of("[rendr]\nwidth = 3\n");
        assert!(e.contains("`rendr`: unknown key") && e.contains("render"), "{e}");
    }

    #[test]
    fn wrong_types_name_the_key_and_place() {
        let e = error_of(&MINIMAL.replace("radius = 1", "radius = \"big\""));
        assert!(
            e.starts_with("test.toml:18:10: `shape[0].radius`: expected a number, found a string"),
            "{e}"
        );
        let e = error_of(&MINIMAL.replace("center = [0, 1, 0]", "center = [0, 1]"));
        assert!(e.contains("`shape[0].center`: expected 3 numbers, found 2"), "{e}");
        let e = error_of(&MINIMAL.replace("width = 64", "width = -5"));
        assert!(e.contains("`render.width`: must be between 0 and"), "{e}");
    }

    #[test]
    fn invalid_values_point_at_the_value() {
        for bad in ["-1", "0", "nan", "inf"] {
            let e = error_of(&MINIMAL.replace("radius = 1", &format!("radius = {bad}")));
            assert!(
                e.starts_with("test.toml:18:10: `shape[0].radius`: must be"),
                "{bad}: {e}"
            );
        }
        let e = error_of(&MINIMAL.replace("width = 64", "width = 0"));
        assert!(e.starts_with("test.toml:3:9: `render.width`"), "{e}");
    }

    /// `ior` of a dielectric: a number, a glass's name or [nm, index]
    /// pairs, the last two dispersing; and what `path` alone renders.
    #[test]
    fn dielectric_indices_disperse_by_name_or_samples() {
        let glass = |ior: &str| {
            MINIMAL.replace(
                "name = \"red\"\ndiffuse = [0.8, 0.1, 0.1]",
                &format!("name = \"red\"\ntype = \"dielectric\"\nior = {ior}"),
            )
        };
        let kind = |ior: &str| parse_str(&glass(ior)).unwrap().materials[0].kind.clone();
        let MaterialKindDesc::Dielectric { ior, dispersion, .. } = kind("\"BK7\"") else {
            panic!()
        };
        assert!((ior - 1.5168).abs() < 1e-4 && dispersion == IorSpectrum::named_glass("glass-BK7"));
        let MaterialKindDesc::Dielectric {
            dispersion: by_pbrt_name,
            ..
        } = kind("\"glass-F11\"")
        else {
            panic!()
        };
        assert_eq!(by_pbrt_name, IorSpectrum::named_glass("glass-F11"));
        let MaterialKindDesc::Dielectric {
            ior,
            dispersion: Some(s),
            ..
        } = kind("[[400, 1.6], [700, 1.5]]")
        else {
            panic!()
        };
        assert!((ior - s.at(D_LINE_NM)).abs() < 1e-6 && s.at(550.0) == 1.55);
        assert!(matches!(
            kind("1.4"),
            MaterialKindDesc::Dielectric {
                ior: 1.4,
                dispersion: None,
                ..
            }
        ));
        for (bad, what) in [
            ("\"BK8\"", "unknown glass \"BK8\""),
            ("[[400, 1.6], [400, 1.5]]", "wavelengths must increase"),
            ("[[400, 1.6]]", "at least two"),
            ("[[400, 1.6, 2], [500, 1.5]]", "expected 2 numbers"),
        ] {
            let e = error_of(&glass(bad));
            assert!(
                e.starts_with("test.toml:14:") && e.contains("material[0].ior") && e.contains(what),
                "{bad}: {e}"
            );
        }
        let e = error_of(&glass("[[400, 1.6], [700, 1.5], [800, -1]]"));
        assert!(
            e.starts_with(
                "test.toml:14:7: `material[0].ior`: index of refraction must be positive and finite over 360-830 nm"
            ),
            "{e}"
        );
        // Every integrator disperses: none warns.
        let mut d = parse_str(&glass("\"F5\"")).unwrap();
        for kind in IntegratorKind::NAMES
            .iter()
            .map(|n| IntegratorKind::from_name(n).unwrap())
        {
            d.settings.integrator = kind;
            let w = crate::scene::build(&d).unwrap().warnings.join("\n");
            assert!(!w.contains("disperses"), "{}: {w}", kind.name());
        }
    }

    #[test]
    fn bad_choices_list_the_options() {
        let e = error_of(&MINIMAL.replace("type = \"sphere\"", "type = \"sphear\""));
        assert!(
            e.contains("unknown value \"sphear\"") && e.contains("did you mean \"sphere\""),
            "{e}"
        );
    }

    #[test]
    fn missing_required_keys() {
        let e = error_of("[[material]]\ndiffuse = 0.5\n");
        assert!(e.contains("`material[0].name`: missing required key `name`"), "{e}");
    }

    #[test]
    fn textures_of_textures_and_procedural_ones() {
        let s = r#"
[[texture]]
name = "grain"
type = "fbm"
octaves = 5
transform = [{ scale = 0.5 }]

[[texture]]
name = "stone"
type = "marble"
variation = 0.5

[[texture]]
name = "blend"
type = "mix"
first = "stone"
second = [0.1, 0.2, 0.3]
amount = "grain"

[[texture]]
name = "dots"
type = "dots"
inside = "blend"
scale = 10

[[texture]]
name = "dim"
type = "scale"
texture = "dots"
scale = 0.5

[[texture]]
name = "solid"
type = "checkerboard3d"
even = "dim"
scale = 2

[[texture]]
name = "globe"
type = "image"
file = "earth.png"
mapping = "spherical"

[[texture]]
name = "flipped"
type = "invert"
texture = "globe"

[[texture]]
name = "sky"
type = "direction_mix"
first = "flipped"
direction = [0, 0, 2]

[[texture]]
name = "ramp"
type = "bilerp"
v11 = [1, 0, 0]
mapping = "planar"
s_axis = [0, 0, 1]
"#;
        let d = parse_str(s).unwrap_or_else(|e| panic!("{e}"));
        d.validate().unwrap_or_else(|e| panic!("{e}"));
        let kind = |name: &str| &d.textures.iter().find(|t| t.name == name).unwrap().kind;
        let TextureKind::Node(TextureNode::Noise {
            pattern: NoisePattern::Fbm { octaves: 5, .. },
            to_texture,
        }) = kind("grain")
        else {
            panic!("{:?}", kind("grain"))
        };
        // Texture space is the transform's inverse: twice the world's.
        assert_eq!(to_texture.transform_point3(Vec3::ONE), Vec3::splat(2.0));
        assert!(
            matches!(kind("stone"), TextureKind::Node(TextureNode::Noise { pattern: NoisePattern::Marble { variation, .. }, .. }) if *variation == 0.5)
        );
        assert_eq!(
            kind("blend"),
            &TextureKind::Node(TextureNode::Mix {
                first: ColorSource::Texture("stone".into()),
                second: ColorSource::Rgb(Rgb::new(0.1, 0.2, 0.3)),
                amount: ColorSource::Texture("grain".into()),
            })
        );
        assert!(
            matches!(kind("dots"), TextureKind::Node(TextureNode::Dots { mapping: Mapping2D::Uv { scale, .. }, .. }) if *scale == Vec2::splat(10.0))
        );
        assert!(matches!(kind("dim"), TextureKind::Node(TextureNode::Scale { .. })));
        let TextureKind::Node(TextureNode::SolidCheckerboard { to_texture, .. }) = kind("solid") else {
            panic!("{:?}", kind("solid"))
        };
        assert_eq!(to_texture.transform_point3(Vec3::ONE), Vec3::splat(2.0));
        // An image by another mapping: the image, and the texture placing it.
        let TextureKind::Node(TextureNode::Mapped {
            tex: ColorSource::Texture(image),
            mapping,
        }) = kind("globe")
        else {
            panic!("{:?}", kind("globe"))
        };
        assert!(matches!(mapping, Mapping2D::Spherical { .. }));
        assert!(matches!(kind(image), TextureKind::Image { .. }));
        assert!(matches!(kind("flipped"), TextureKind::Node(TextureNode::Invert(_))));
        assert!(
            matches!(kind("sky"), TextureKind::Node(TextureNode::DirectionMix { dir, .. }) if *dir == Vec3::new(0.0, 0.0, 2.0))
        );
        assert!(
            matches!(kind("ramp"), TextureKind::Node(TextureNode::Bilerp { mapping: Mapping2D::Planar { s_axis, .. }, .. }) if *s_axis == Vec3::Z)
        );
        // A texture may only be made of textures defined before it.
        let later = "[[texture]]\nname = \"a\"\ntype = \"invert\"\ntexture = \"b\"\n\n[[texture]]\nname = \"b\"\ntype = \"constant\"\n";
        let e = parse_str(later).unwrap_err().to_string();
        assert!(
            e.contains("`texture[0].texture`: no texture named \"b\" before this one"),
            "{e}"
        );
        let e = parse_str("[[texture]]\nname = \"n\"\ntype = \"fbm\"\noctaves = 100\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("octaves"), "{e}");
    }

    #[test]
    fn transforms_meshes_lights_and_textures() {
        let s = r#"
[[texture]]
name = "checks"
type = "checkerboard"
even = 1
odd = [0, 0, 0]
scale = 4

[[material]]
name = "m"
diffuse = "checks"

[[mesh]]
name = "tri"
positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
indices = [0, 1, 2]

[[light]]
type = "spot"
position = [0, 5, 0]
to = [0, 0, 0]

[[shape]]
type = "mesh"
mesh = "tri"
material = "m"
transform = [
  { scale = 2 },
  { rotate = { axis = [0, 1, 0], angle = 90 } },
  { shear = { xy = 0.5 } },
  { translate = [1, 2, 3] },
  { matrix = [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1] },
]
"#;
        let d = parse_str(s).unwrap();
        assert_eq!(d.shapes[0].transform.len(), 5);
        assert_eq!(d.shapes[0].transform[0], TransformOp::Scale(Vec3::splat(2.0)));
        assert!(matches!(d.meshes[0].source, MeshSource::Inline(ref m) if m.indices == vec![[0, 1, 2]]));
        assert!(
            matches!(&d.materials[0].kind, MaterialKindDesc::Classic(c) if c.diffuse == ColorSource::Texture("checks".into()))
        );
        let e = error_of(&s.replace("{ scale = 2 }", "{ scale = 0 }"));
        assert!(e.contains("`shape[0].transform`") && e.contains("singular"), "{e}");
        let e = error_of(&s.replace("{ scale = 2 }", "{ scale = 2, translate = [1, 1, 1] }"));
        assert!(e.contains("exactly one"), "{e}");
        let e = error_of(&s.replace("indices = [0, 1, 2]", "indices = [0, 1, 7]"));
        assert!(e.contains("`mesh[0].indices`") && e.contains("vertex 7"), "{e}");
    }
}
