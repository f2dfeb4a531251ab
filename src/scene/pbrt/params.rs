//! Parameter lists: `"type name" value` or `"type name" [ values ]`
//! (pbrt-v4 file format documentation, "Parameter lists"), checked for
//! type and count as they are read, and looked up by name and type.

use super::lexer::{Lexer, Tok};
use crate::color::Rgb;
use crate::error::{Error, Result, SourceLoc};
use glam::{Vec2, Vec3};
use std::cell::Cell;

/// The parameter types of pbrt-v4, with the older spellings they replace.
const TYPES: [(&str, &str); 17] = [
    ("integer", "integer"),
    ("float", "float"),
    ("point2", "point2"),
    ("vector2", "vector2"),
    ("point3", "point3"),
    ("point", "point3"),
    ("vector3", "vector3"),
    ("vector", "vector3"),
    ("normal3", "normal3"),
    ("normal", "normal3"),
    ("rgb", "rgb"),
    ("color", "rgb"),
    ("spectrum", "spectrum"),
    ("blackbody", "blackbody"),
    ("bool", "bool"),
    ("string", "string"),
    ("texture", "texture"),
];

/// The values of a parameter.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Values {
    /// Numbers (integers are checked to be whole when read).
    Nums(Vec<f32>),
    /// Strings.
    Strs(Vec<String>),
    /// Booleans.
    Bools(Vec<bool>),
}

/// One parameter as written.
#[derive(Clone, Debug)]
pub(crate) struct Param {
    /// Canonical type (`point` is read as `point3`, `color` as `rgb`).
    pub ty: &'static str,
    /// Name.
    pub name: String,
    /// `"type name"` as written, for messages.
    pub written: String,
    /// Values.
    pub values: Values,
    /// Where the declaration is.
    pub loc: SourceLoc,
    /// Whether a reader looked at it.
    pub used: Cell<bool>,
    /// Whether it came from an `Attribute` directive (and so may go
    /// unused without a warning).
    pub inherited: bool,
}

impl Param {
    /// An error about this parameter.
    pub fn err(&self, message: impl Into<String>) -> Error {
        Error::scene(Some(self.loc.clone()), self.written.clone(), message)
    }

    pub(crate) fn nums(&self) -> &[f32] {
        match &self.values {
            Values::Nums(v) => v,
            _ => &[],
        }
    }

    fn strs(&self) -> &[String] {
        match &self.values {
            Values::Strs(v) => v,
            _ => &[],
        }
    }

    fn count(&self) -> usize {
        match &self.values {
            Values::Nums(v) => v.len(),
            Values::Strs(v) => v.len(),
            Values::Bools(v) => v.len(),
        }
    }

    fn one_value(&self) -> Result<()> {
        match self.count() {
            1 => Ok(()),
            n => Err(self.err(format!("expected one value, found {n}"))),
        }
    }
}

/// A spectral quantity as written: the forms a `spectrum`, `rgb`,
/// `blackbody`, `float` or `texture` parameter can take.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum SpectrumValue {
    /// `"rgb name" [r g b]`.
    Rgb(Rgb),
    /// `"blackbody name" T` (pbrt-v3 files add a scale).
    Blackbody {
        /// Temperature in kelvin.
        kelvin: f32,
        /// Multiplier (pbrt-v3's second value; 1 in pbrt-v4).
        scale: f32,
    },
    /// `"spectrum name" [λ₀ v₀ λ₁ v₁ …]`.
    Sampled(Vec<(f32, f32)>),
    /// `"spectrum name" "metal-Au-eta"` or a file of samples.
    Named(String),
    /// `"texture name" "texname"`.
    Texture(String),
    /// `"float name" v`.
    Float(f32),
}

/// A float that may instead name a float texture.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum FloatValue {
    /// A number.
    Num(f32),
    /// A texture name.
    Texture(String),
}

/// The parameters of one directive, plus those inherited from `Attribute`.
#[derive(Clone, Debug, Default)]
pub(crate) struct ParamList {
    /// In the order written; the directive's own come before inherited ones.
    pub items: Vec<Param>,
}

impl ParamList {
    /// The parameter called `name`, marked as used.
    pub fn find(&self, name: &str) -> Option<&Param> {
        // As in pbrt-v4's `ParameterDictionary`, the last of repeated
        // parameters wins, and the directive's own win over inherited ones.
        let p = self
            .items
            .iter()
            .rev()
            .find(|p| !p.inherited && p.name == name)
            .or_else(|| self.items.iter().find(|p| p.inherited && p.name == name))?;
        p.used.set(true);
        Some(p)
    }

    /// Whether a parameter called `name` is present (without marking it).
    pub fn has(&self, name: &str) -> bool {
        self.items.iter().any(|p| p.name == name)
    }

    /// The parameter called `name` if it has one of `types`; a parameter of
    /// that name with another type is an error.
    fn typed(&self, name: &str, types: &[&str]) -> Result<Option<&Param>> {
        match self.find(name) {
            Some(p) if types.contains(&p.ty) => Ok(Some(p)),
            Some(p) => Err(p.err(format!("`{name}` must be of type {}, not {}", types.join(" or "), p.ty))),
            None => Ok(None),
        }
    }

    /// One `float`.
    pub fn float_opt(&self, name: &str) -> Result<Option<(f32, &Param)>> {
        let Some(p) = self.typed(name, &["float"])? else {
            return Ok(None);
        };
        p.one_value()?;
        Ok(Some((p.nums()[0], p)))
    }

    /// One `float`, or `default`.
    pub fn float(&self, name: &str, default: f32) -> Result<f32> {
        Ok(self.float_opt(name)?.map_or(default, |(v, _)| v))
    }

    /// One `integer`.
    pub fn int_opt(&self, name: &str) -> Result<Option<(i64, &Param)>> {
        let Some(p) = self.typed(name, &["integer"])? else {
            return Ok(None);
        };
        p.one_value()?;
        Ok(Some((p.nums()[0] as i64, p)))
    }

    /// One `bool`, or `default`.
    pub fn bool(&self, name: &str, default: bool) -> Result<bool> {
        let Some(p) = self.typed(name, &["bool"])? else {
            return Ok(default);
        };
        p.one_value()?;
        match &p.values {
            Values::Bools(b) => Ok(b[0]),
            _ => Ok(default),
        }
    }

    /// One `string`.
    pub fn string(&self, name: &str) -> Result<Option<(String, &Param)>> {
        let Some(p) = self.typed(name, &["string"])? else {
            return Ok(None);
        };
        p.one_value()?;
        Ok(Some((p.strs()[0].clone(), p)))
    }

    /// All values of a `string` parameter.
    pub fn strings(&self, name: &str) -> Result<Option<(Vec<String>, &Param)>> {
        let Some(p) = self.typed(name, &["string"])? else {
            return Ok(None);
        };
        Ok(Some((p.strs().to_vec(), p)))
    }

    /// One `point3`, or `default`.
    pub fn point3(&self, name: &str, default: Vec3) -> Result<Vec3> {
        let Some(p) = self.typed(name, &["point3"])? else {
            return Ok(default);
        };
        let v = p.nums();
        if v.len() != 3 {
            return Err(p.err(format!("expected one point (3 numbers), found {} numbers", v.len())));
        }
        Ok(Vec3::new(v[0], v[1], v[2]))
    }

    /// All numbers of a `float` parameter.
    pub fn floats(&self, name: &str) -> Result<Option<(Vec<f32>, &Param)>> {
        let Some(p) = self.typed(name, &["float"])? else {
            return Ok(None);
        };
        Ok(Some((p.nums().to_vec(), p)))
    }

    /// All values of an `integer` parameter.
    pub fn ints(&self, name: &str) -> Result<Option<(Vec<i64>, &Param)>> {
        let Some(p) = self.typed(name, &["integer"])? else {
            return Ok(None);
        };
        Ok(Some((p.nums().iter().map(|&x| x as i64).collect(), p)))
    }

    /// Triples of a parameter of one of `types` (`point3`, `normal3`, …).
    pub fn vec3s(&self, name: &str, types: &[&str]) -> Result<Option<(Vec<Vec3>, &Param)>> {
        let Some(p) = self.typed(name, types)? else {
            return Ok(None);
        };
        let v = p.nums();
        Ok(Some((
            v.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect(),
            p,
        )))
    }

    /// Pairs from a `point2` parameter, or from a flat `float` list (the
    /// older way of writing texture coordinates).
    pub fn vec2s(&self, name: &str) -> Result<Option<(Vec<Vec2>, &Param)>> {
        let Some(p) = self.typed(name, &["point2", "vector2", "float"])? else {
            return Ok(None);
        };
        let v = p.nums();
        if v.len() % 2 != 0 {
            return Err(p.err(format!("needs pairs of numbers, found {} numbers", v.len())));
        }
        Ok(Some((v.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect(), p)))
    }

    /// A spectral quantity in any of its forms; which forms make sense is
    /// the caller's business.
    pub fn spectrum(&self, name: &str) -> Result<Option<(SpectrumValue, &Param)>> {
        let Some(p) = self.typed(name, &["rgb", "blackbody", "spectrum", "texture", "float"])? else {
            return Ok(None);
        };
        let value = match (p.ty, &p.values) {
            ("rgb", Values::Nums(v)) => {
                if v.len() != 3 {
                    return Err(p.err(format!("expected one colour (3 numbers), found {} numbers", v.len())));
                }
                if v.iter().any(|&x| x < 0.0) {
                    return Err(p.err(format!(
                        "RGB components must not be negative, got [{} {} {}]",
                        v[0], v[1], v[2]
                    )));
                }
                SpectrumValue::Rgb(Rgb::new(v[0], v[1], v[2]))
            }
            ("blackbody", Values::Nums(v)) => {
                if v.len() > 2 {
                    return Err(p.err(format!("expected a temperature, found {} numbers", v.len())));
                }
                if v[0] <= 0.0 {
                    return Err(p.err(format!("the temperature must be positive, got {}", v[0])));
                }
                SpectrumValue::Blackbody {
                    kelvin: v[0],
                    scale: v.get(1).copied().unwrap_or(1.0),
                }
            }
            ("spectrum", Values::Nums(v)) => {
                if v.len() < 4 {
                    return Err(p.err(format!(
                        "a sampled spectrum needs at least two pairs of wavelength and value, found {} numbers",
                        v.len()
                    )));
                }
                let pairs: Vec<(f32, f32)> = v.chunks_exact(2).map(|c| (c[0], c[1])).collect();
                if let Some(w) = pairs.windows(2).find(|w| w[1].0 <= w[0].0) {
                    return Err(p.err(format!("wavelengths must increase, but {} follows {}", w[1].0, w[0].0)));
                }
                SpectrumValue::Sampled(pairs)
            }
            ("spectrum", Values::Strs(_)) | ("texture", _) => {
                p.one_value()?;
                let s = p.strs()[0].clone();
                if p.ty == "texture" {
                    SpectrumValue::Texture(s)
                } else {
                    SpectrumValue::Named(s)
                }
            }
            _ => {
                p.one_value()?;
                SpectrumValue::Float(p.nums()[0])
            }
        };
        Ok(Some((value, p)))
    }

    /// A `float` or the name of a float texture.
    pub fn float_or_texture(&self, name: &str) -> Result<Option<(FloatValue, &Param)>> {
        let Some(p) = self.typed(name, &["float", "texture"])? else {
            return Ok(None);
        };
        p.one_value()?;
        Ok(Some(match &p.values {
            Values::Strs(s) => (FloatValue::Texture(s[0].clone()), p),
            _ => (FloatValue::Num(p.nums()[0]), p),
        }))
    }

    /// The directive's own parameters that nothing looked at.
    pub fn unused(&self) -> impl Iterator<Item = &Param> {
        self.items.iter().filter(|p| !p.used.get() && !p.inherited)
    }
}

/// Reads the parameter list that follows a directive: every quoted string
/// that comes next starts a parameter.
pub(crate) fn parse_params(lx: &mut Lexer) -> Result<ParamList> {
    let mut items = Vec::new();
    loop {
        match lx.peek()? {
            Some(t) if matches!(t.tok, Tok::Str(_)) => {}
            _ => break,
        }
        let decl_tok = lx.next()?.expect("peeked");
        let Tok::Str(decl) = &decl_tok.tok else { unreachable!() };
        let decl = decl.to_string();
        let loc = lx.loc(decl_tok.offset);
        let mut words = decl.split_whitespace();
        let (Some(ty_written), Some(name), None) = (words.next(), words.next(), words.next()) else {
            return Err(lx.error(
                decl_tok.offset,
                format!("\"{decl}\" is not a parameter declaration: write \"type name\", e.g. \"float radius\""),
            ));
        };
        let Some(&(_, ty)) = TYPES.iter().find(|(w, _)| *w == ty_written) else {
            let known: Vec<&str> = TYPES.iter().map(|(w, _)| *w).collect();
            return Err(lx.error(
                decl_tok.offset,
                format!(
                    "unknown parameter type \"{ty_written}\" in \"{decl}\"{}",
                    crate::scene::desc::suggest(ty_written, known.into_iter())
                ),
            ));
        };
        let written = format!("{ty_written} {name}");
        let values = parse_values(lx, ty, &written, decl_tok.offset)?;
        let p = Param {
            ty,
            name: name.to_string(),
            written,
            values,
            loc,
            used: Cell::new(false),
            inherited: false,
        };
        check_count(&p)?;
        items.push(p);
    }
    Ok(ParamList { items })
}

/// Reads one value, or a bracketed list, converting as the type requires.
fn parse_values(lx: &mut Lexer, ty: &'static str, written: &str, decl_offset: usize) -> Result<Values> {
    let Some(first) = lx.next()? else {
        return Err(lx.error(decl_offset, format!("\"{written}\" has no value: the file ends")));
    };
    let bracketed = first.tok == Tok::Open;
    let mut nums = Vec::new();
    let mut strs = Vec::new();
    let mut bools = Vec::new();
    let mut pending = if bracketed { None } else { Some(first.clone()) };
    loop {
        let t = match pending.take() {
            Some(t) => t,
            None => match lx.next()? {
                Some(t) => t,
                None => {
                    return Err(lx.error(first.offset, format!("unclosed `[` in the value of \"{written}\"")));
                }
            },
        };
        match &t.tok {
            Tok::Close if bracketed => break,
            Tok::Open | Tok::Close => {
                return Err(lx.error(
                    t.offset,
                    format!("unexpected {} in the value of \"{written}\"", t.describe()),
                ));
            }
            Tok::Word(w) => match ty {
                "bool" => match &**w {
                    "true" => bools.push(true),
                    "false" => bools.push(false),
                    _ => return Err(lx.error(t.offset, format!("\"{written}\": expected true or false, found `{w}`"))),
                },
                "string" | "texture" => {
                    return Err(lx.error(
                        t.offset,
                        format!("\"{written}\": expected a quoted string, found `{w}`"),
                    ));
                }
                "spectrum" if !strs.is_empty() => {
                    return Err(lx.error(
                        t.offset,
                        format!("\"{written}\": expected a quoted string, found `{w}`"),
                    ));
                }
                "integer" => nums.push(parse_integer(lx, t.offset, w, written)?),
                _ => nums.push(parse_number(lx, t.offset, w, &format!("\"{written}\""))?),
            },
            Tok::Str(s) => match ty {
                "string" | "texture" => strs.push(s.to_string()),
                "spectrum" if nums.is_empty() => strs.push(s.to_string()),
                "bool" if s == "true" || s == "false" => bools.push(s == "true"),
                _ => {
                    let what = if ty == "bool" { "true or false" } else { "a number" };
                    return Err(lx.error(t.offset, format!("\"{written}\": expected {what}, found \"{s}\"")));
                }
            },
        }
        if !bracketed {
            break;
        }
    }
    Ok(match ty {
        "bool" => Values::Bools(bools),
        "string" | "texture" => Values::Strs(strs),
        "spectrum" if !strs.is_empty() => Values::Strs(strs),
        _ => Values::Nums(nums),
    })
}

/// pbrt's numbers: optional sign, digits, optional fraction and exponent
/// (no `inf` or `nan`), within the range of 32-bit floats.
pub(crate) fn parse_number(lx: &Lexer, offset: usize, w: &str, what: &str) -> Result<f32> {
    let looks_numeric = w
        .bytes()
        .all(|b| b.is_ascii_digit() || matches!(b, b'+' | b'-' | b'.' | b'e' | b'E'))
        && w.bytes().any(|b| b.is_ascii_digit());
    let v = if looks_numeric { w.parse::<f64>().ok() } else { None };
    match v {
        Some(v) if v.is_finite() && v.abs() <= f32::MAX as f64 => Ok(v as f32),
        Some(_) => Err(lx.error(offset, format!("{what}: the number {w} is out of range"))),
        None => Err(lx.error(offset, format!("{what}: expected a number, found `{w}`"))),
    }
}

fn parse_integer(lx: &Lexer, offset: usize, w: &str, what: &str) -> Result<f32> {
    let digits = w.strip_prefix(['+', '-']).unwrap_or(w);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(lx.error(offset, format!("\"{what}\": expected a whole number, found `{w}`")));
    }
    match w.parse::<i64>() {
        Ok(v) if v >= i32::MIN as i64 && v <= i32::MAX as i64 => Ok(v as f32),
        _ => Err(lx.error(offset, format!("\"{what}\": {w} does not fit in a 32-bit integer"))),
    }
}

/// Counts that the type implies (pbrt-v4 `ParameterDictionary::checkParameterTypes`
/// and the per-type value sizes).
fn check_count(p: &Param) -> Result<()> {
    let n = p.count();
    if n == 0 {
        return Err(p.err("the parameter has no values"));
    }
    let per = match p.ty {
        "point2" | "vector2" => 2,
        "point3" | "vector3" | "normal3" | "rgb" => 3,
        "spectrum" if matches!(p.values, Values::Nums(_)) => 2,
        _ => 1,
    };
    if n % per != 0 {
        let what = if p.ty == "spectrum" {
            "(wavelength, value) pairs".to_string()
        } else {
            format!("groups of {per} numbers")
        };
        return Err(p.err(format!("needs {what}, found {n} numbers")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;
    use std::sync::Arc;

    fn params(text: &str) -> Result<ParamList> {
        let mut lx = Lexer::new(Arc::from(Path::new("p.pbrt")), text, Arc::from(Path::new("")));
        parse_params(&mut lx)
    }

    #[test]
    fn reads_every_type() {
        let p = params(
            r#""integer n" 3 "float f" [ 1.5 ] "point3 p" [1 2 3 4 5 6] "point P" [0 0 1]
               "rgb c" [0.1 0.2 0.3] "color k" [1 1 1] "bool b" "true" "bool b2" false "string s" "x"
               "spectrum named" "metal-Au-eta" "spectrum sampled" [400 1 500 2] "blackbody T" 3000
               "texture t" "checks" "point2 uv" [0 0 1 1] "normal N" [0 0 1]"#,
        )
        .unwrap();
        assert_eq!(p.int_opt("n").unwrap().unwrap().0, 3);
        assert_eq!(p.float("f", 0.0).unwrap(), 1.5);
        assert_eq!(p.vec3s("p", &["point3"]).unwrap().unwrap().0.len(), 2);
        assert_eq!(p.point3("P", Vec3::ZERO).unwrap(), Vec3::Z);
        assert_eq!(
            p.spectrum("c").unwrap().unwrap().0,
            SpectrumValue::Rgb(Rgb::new(0.1, 0.2, 0.3))
        );
        assert_eq!(p.spectrum("k").unwrap().unwrap().0, SpectrumValue::Rgb(Rgb::ONE));
        assert!(p.bool("b", false).unwrap());
        assert!(!p.bool("b2", true).unwrap());
        assert_eq!(p.string("s").unwrap().unwrap().0, "x");
        assert_eq!(
            p.spectrum("named").unwrap().unwrap().0,
            SpectrumValue::Named("metal-Au-eta".into())
        );
        assert_eq!(
            p.spectrum("sampled").unwrap().unwrap().0,
            SpectrumValue::Sampled(vec![(400.0, 1.0), (500.0, 2.0)])
        );
        assert_eq!(
            p.spectrum("T").unwrap().unwrap().0,
            SpectrumValue::Blackbody {
                kelvin: 3000.0,
                scale: 1.0
            }
        );
        assert_eq!(
            p.spectrum("t").unwrap().unwrap().0,
            SpectrumValue::Texture("checks".into())
        );
        assert_eq!(p.vec2s("uv").unwrap().unwrap().0, vec![Vec2::ZERO, Vec2::ONE]);
        assert_eq!(p.vec3s("N", &["normal3"]).unwrap().unwrap().0, vec![Vec3::Z]);
        assert_eq!(p.unused().count(), 0);
    }

    #[test]
    fn malformed_lists_are_errors_with_positions() {
        let e = |t: &str| params(t).unwrap_err().to_string();
        assert!(
            e(r#""float r" [1 2"#).starts_with("p.pbrt:1:11: unclosed `[`"),
            "{}",
            e(r#""float r" [1 2"#)
        );
        assert!(e(r#""float r" abc"#).contains("expected a number, found `abc`"));
        assert!(e(r#""float r" 1.2.3"#).contains("expected a number"));
        assert!(e(r#""float r" nan"#).contains("expected a number"));
        assert!(e(r#""float r" 1e99"#).contains("out of range"));
        assert!(e(r#""integer n" 1.5"#).contains("whole number"));
        assert!(e(r#""integer n" 99999999999"#).contains("32-bit"));
        assert!(e(r#""point3 p" [1 2]"#).starts_with("p.pbrt:1:1: `point3 p`: needs groups of 3"));
        assert!(e(r#""rgb c" [1 2 3 4 5]"#).contains("groups of 3"));
        assert!(
            e(r#""floot r" 1"#).contains("unknown parameter type \"floot\" in \"floot r\" (did you mean \"float\"?)")
        );
        assert!(e(r#""radius" 1"#).contains("not a parameter declaration"));
        assert!(e(r#""bool b" "yes""#).contains("expected true or false"));
        assert!(e(r#""string s" 3"#).contains("expected a quoted string"));
        assert!(e(r#""float r" []"#).contains("no values"));
        assert!(e(r#""spectrum s" [400 1 500]"#).contains("pairs"));
    }

    #[test]
    fn lookups_check_type_and_count() {
        let p =
            params(r#""rgb radius" [1 2 3] "float two" [1 2] "spectrum s" [500 1 400 2] "rgb neg" [1 -1 0]"#).unwrap();
        let e = p.float("radius", 1.0).unwrap_err().to_string();
        assert!(
            e.contains("`rgb radius`: `radius` must be of type float, not rgb"),
            "{e}"
        );
        let e = p.float("two", 1.0).unwrap_err().to_string();
        assert!(e.contains("expected one value, found 2"), "{e}");
        let e = p.spectrum("s").unwrap_err().to_string();
        assert!(e.contains("wavelengths must increase"), "{e}");
        let e = p.spectrum("neg").unwrap_err().to_string();
        assert!(e.contains("must not be negative"), "{e}");
        assert_eq!(p.float("absent", 7.0).unwrap(), 7.0);
    }
}
