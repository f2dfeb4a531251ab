//! `Material`, `MakeNamedMaterial` and `Texture` (pbrt-v4 materials.cpp
//! and textures.cpp): each pbrt material becomes the nearest of trazo's
//! models, each spectrum texture the nearest of trazo's textures.

use super::params::{FloatValue, Param, ParamList, SpectrumValue};
use super::spectrum::{
    blackbody_reflectance_rgb, blackbody_rgb, illuminant_rgb, metal_of, pbrt_only_metal_ior, sampled_factor_rgb,
    sampled_rgb, spectrum_at_rgb_wavelengths,
};
use super::{MatDef, MatKind, Parser};
use crate::color::space::ColorSpace;
use crate::color::spectrum::parse_spd;
use crate::color::{Encoding, Rgb};
use crate::error::{Error, Result, SourceLoc};
use crate::material::conductor::metal_ior;
use crate::material::dispersion::{D_LINE_NM, IorSpectrum};
use crate::scene::desc::*;
use crate::texture::{Mapping2D, NoisePattern, TextureNode};
use glam::{Affine3A, Mat3, Mat4, Vec2, Vec3};
use std::path::Path;

/// pbrt-v4's material types (`Material::Create`).
pub(super) const MATERIAL_TYPES: &[&str] = &[
    "",
    "coatedconductor",
    "coateddiffuse",
    "conductor",
    "dielectric",
    "diffuse",
    "diffusetransmission",
    "hair",
    "interface",
    "measured",
    "mix",
    "none",
    "subsurface",
    "thindielectric",
];

/// pbrt-v4's texture classes (float and spectrum).
pub(super) const TEXTURE_CLASSES: &[&str] = &[
    "bilerp",
    "checkerboard",
    "constant",
    "directionmix",
    "dots",
    "fbm",
    "imagemap",
    "marble",
    "mix",
    "ptex",
    "scale",
    "windy",
    "wrinkled",
];

/// pbrt-v4's names of colour encodings (`ColorEncoding::Get`): `sRGB`,
/// `linear` and `gamma γ` for a positive γ.
fn parse_encoding(name: &str) -> Option<Encoding> {
    match name {
        "sRGB" => Some(Encoding::Srgb),
        "linear" => Some(Encoding::Linear),
        _ => {
            let g: f32 = name.strip_prefix("gamma ")?.trim().parse().ok()?;
            (g.is_finite() && g > 0.0).then_some(Encoding::Gamma(g))
        }
    }
}

/// Whether `name` is of the families of named spectra that pbrt-v4 ships
/// (`GetNamedSpectrum`): metals, glasses, illuminants and camera sensors.
/// Other names are spectrum files.
fn is_pbrt_spectrum_name(name: &str) -> bool {
    ["metal-", "glass-", "stdillum-", "illum-", "canon_", "nikon_", "sony_"]
        .iter()
        .any(|family| name.starts_with(family))
}

/// What a colour parameter means, which decides how spectra become RGB.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum ColorUse {
    /// A reflectance: components at most 1 (pbrt-v4 `SpectrumType::Albedo`).
    Albedo,
    /// Any non-negative colour (texture values, scale factors).
    Unbounded,
    /// Emitted light, normalised as pbrt-v4 normalises emitters.
    Illuminant,
}

impl Parser {
    /// The samples of the spectrum file `name` (a pbrt `.spd` file of
    /// wavelength and value pairs), found from `dir_rel` as textures are.
    fn spectrum_file(&self, name: &str, dir_rel: &Path, prm: &Param) -> Result<Vec<(f32, f32)>> {
        let path = self.top_dir.join(self.resolve(dir_rel, name));
        let text = crate::files::read_limited(&path, crate::files::MAX_SCENE_BYTES).map_err(|e| {
            prm.err(format!(
                "\"{name}\" is neither a named spectrum nor a readable file: {e}"
            ))
        })?;
        parse_spd(&String::from_utf8_lossy(&text)).map_err(|e| prm.err(format!("{}: {e}", path.display())))
    }

    /// A colour parameter as a constant or a texture reference; `None` if
    /// the value cannot be used (after a warning).
    pub(super) fn color_value(&mut self, v: SpectrumValue, prm: &Param, use_: ColorUse) -> Result<Option<ColorSource>> {
        let loc = prm.loc.clone();
        let what = format!("\"{}\"", prm.written);
        Ok(Some(ColorSource::Rgb(match v {
            SpectrumValue::Rgb(c) => {
                if use_ == ColorUse::Albedo && c.max_element() > 1.0 {
                    return Err(prm.err(format!(
                        "a reflectance must not exceed 1 in any component, got [{} {} {}]",
                        c.x, c.y, c.z
                    )));
                }
                self.rgb_in_space(c, use_, &loc, &what)
            }
            // Spectra become the RGB that pbrt-v4's RGB film records of
            // them (`color::spectrum`): emitted ones seen directly,
            // reflectances and other factors lighting a white (D65)
            // illuminant.
            SpectrumValue::Blackbody { kelvin, scale } => match use_ {
                ColorUse::Illuminant => blackbody_rgb(kelvin) * scale,
                _ => blackbody_reflectance_rgb(kelvin),
            },
            SpectrumValue::Sampled(samples) => match use_ {
                ColorUse::Illuminant => sampled_rgb(&samples),
                ColorUse::Albedo | ColorUse::Unbounded => {
                    let (c, clipped) = sampled_factor_rgb(&samples, use_ == ColorUse::Albedo);
                    if clipped {
                        self.approximated(
                            &loc,
                            format!("sampled spectrum {what}"),
                            format!(
                                "its colour leaves the sRGB gamut{}: clipped to [{} {} {}]",
                                if use_ == ColorUse::Albedo { " or exceeds 1" } else { "" },
                                c.x,
                                c.y,
                                c.z
                            ),
                        );
                    }
                    c
                }
            },
            SpectrumValue::Named(name) => match (use_, illuminant_rgb(&name)) {
                (ColorUse::Illuminant, Some((c, exact))) => {
                    if !exact {
                        self.approximated(
                            &loc,
                            format!("{what} \"{name}\""),
                            format!("rendered as the colour [{} {} {}]", c.x, c.y, c.z),
                        );
                    }
                    c
                }
                _ if is_pbrt_spectrum_name(&name) => {
                    self.unsupported(
                        &loc,
                        format!("named spectrum \"{name}\" for {what}"),
                        "the default value is used",
                    );
                    return Ok(None);
                }
                // Not a name pbrt-v4 ships: a file of samples, as there.
                _ => {
                    let dir = self.directive_dir.clone();
                    let samples = self.spectrum_file(&name, &dir, prm)?;
                    return self.color_value(SpectrumValue::Sampled(samples), prm, use_);
                }
            },
            SpectrumValue::Texture(t) => {
                if use_ == ColorUse::Illuminant {
                    return Err(prm.err("an emitted spectrum cannot be a texture"));
                }
                return Ok(Some(ColorSource::Texture(t)));
            }
            SpectrumValue::Float(_) => {
                return Err(prm.err(format!(
                    "`{}` is a colour: give \"rgb\", \"spectrum\", \"blackbody\"{}",
                    prm.name,
                    if use_ == ColorUse::Illuminant {
                        ""
                    } else {
                        " or \"texture\""
                    }
                )));
            }
        })))
    }

    /// Linear sRGB of `c`, an RGB value written in the current colour
    /// space (`ColorSpace`) for `use_`. A colour of a wider space that
    /// sRGB cannot hold (a negative component, or a reflectance above 1)
    /// is clipped to it, with a warning.
    pub(super) fn rgb_in_space(&mut self, c: Rgb, use_: ColorUse, loc: &SourceLoc, what: &str) -> Rgb {
        let space = self.gs.color_space;
        if space == ColorSpace::Srgb {
            return c;
        }
        let converted = space.to_srgb(use_ == ColorUse::Illuminant) * c;
        let top = if use_ == ColorUse::Albedo { 1.0 } else { f32::INFINITY };
        let clipped = converted.clamp(Rgb::ZERO, Rgb::splat(top));
        if clipped != converted {
            self.approximated(
                loc,
                format!("{} colour {what}", space.pbrt_name()),
                format!(
                    "[{} {} {}] is [{} {} {}] in linear sRGB, which trazo renders in: clipped to [{} {} {}]",
                    c.x, c.y, c.z, converted.x, converted.y, converted.z, clipped.x, clipped.y, clipped.z
                ),
            );
        }
        clipped
    }

    /// A constant colour where trazo cannot use a texture: a texture stands
    /// for its representative colour, with a warning.
    fn constant_color(&mut self, src: ColorSource, prm: &Param) -> Result<Rgb> {
        match src {
            ColorSource::Rgb(c) => Ok(c),
            ColorSource::Texture(t) => {
                let Some(&c) = self.texture_colors.get(&t) else {
                    return Err(prm.err(format!(
                        "no texture named \"{t}\"{}",
                        suggest(&t, self.texture_colors.keys().map(String::as_str))
                    )));
                };
                let l = prm.loc.clone();
                self.approximated(
                    &l,
                    format!("texture \"{t}\" for \"{}\"", prm.written),
                    format!(
                        "a constant is needed here; the texture's typical colour [{} {} {}] is used",
                        c.x, c.y, c.z
                    ),
                );
                Ok(c)
            }
        }
    }

    /// A reflectance parameter (colour or texture).
    fn albedo(&mut self, p: &ParamList, name: &str, default: f32, key: &str, def: &mut MatDef) -> Result<ColorSource> {
        let Some((v, prm)) = p.spectrum(name)? else {
            return Ok(ColorSource::Rgb(Rgb::splat(default)));
        };
        def.locs.keys.push((key.into(), prm.loc.clone()));
        let src = self.color_value(v, prm, ColorUse::Albedo)?;
        if let Some(ColorSource::Texture(t)) = &src {
            def.tex_refs.push((t.clone(), prm.loc.clone()));
        }
        Ok(src.unwrap_or(ColorSource::Rgb(Rgb::splat(default))))
    }

    /// A float parameter that pbrt allows to be a float texture and trazo
    /// takes as a number: a texture gives `default` with a warning.
    fn float_param(&mut self, p: &ParamList, name: &str, default: f32) -> Result<Option<(f32, SourceLoc)>> {
        match p.float_or_texture(name)? {
            None => Ok(None),
            Some((FloatValue::Num(v), prm)) => Ok(Some((v, prm.loc.clone()))),
            Some((FloatValue::Texture(t), prm)) => {
                let l = prm.loc.clone();
                self.unsupported(
                    &l,
                    format!("float texture \"{t}\" for \"{}\"", prm.written),
                    format!("trazo takes a number here, not a texture; {default} is used"),
                );
                Ok(Some((default, l)))
            }
        }
    }

    /// A roughness parameter: a number, or a float texture trazo reads (its
    /// typical value, where, and the desc texture's name); other float
    /// textures give 0 with a warning.
    fn roughness_param(&mut self, p: &ParamList, name: &str) -> Result<Option<(f32, SourceLoc, Option<String>)>> {
        self.float_or_read_texture(p, name, 0.0)
    }

    /// A float parameter, or a float texture trazo reads (its typical
    /// value, where, and the desc texture's name); other float textures
    /// give `default` with a warning.
    fn float_or_read_texture(
        &mut self,
        p: &ParamList,
        name: &str,
        default: f32,
    ) -> Result<Option<(f32, SourceLoc, Option<String>)>> {
        if let Some((FloatValue::Texture(t), prm)) = p.float_or_texture(name)? {
            if let Some((desc_name, typical)) = self.float_texture_descs.get(&t) {
                return Ok(Some((*typical, prm.loc.clone(), Some(desc_name.clone()))));
            }
        }
        Ok(self.float_param(p, name, default)?.map(|(v, l)| (v, l, None)))
    }

    /// GGX α along u and v from `roughness`/`uroughness`/`vroughness`,
    /// mapped by pbrt-v4's `TrowbridgeReitzDistribution::RoughnessToAlpha`
    /// (α = √roughness) unless `remaproughness` is false.
    ///
    /// A float texture that trazo reads sets `def.roughness_map` (its
    /// typical value gives the constant α); materials that cannot vary
    /// their roughness drop it with a warning (see [`Self::material`]).
    fn roughness(&mut self, p: &ParamList, prefix: &str, def: &mut MatDef) -> Result<(f32, f32)> {
        let both = self.roughness_param(p, &format!("{prefix}roughness"))?;
        let u = self
            .roughness_param(p, &format!("{prefix}uroughness"))?
            .or(both.clone());
        let v = self.roughness_param(p, &format!("{prefix}vroughness"))?.or(both);
        let remap = p.bool("remaproughness", true)?;
        if [&u, &v].iter().any(|r| matches!(r, Some((_, _, Some(_))))) {
            let source = |r: &Option<(f32, SourceLoc, Option<String>)>| match r {
                Some((_, _, Some(t))) => ColorSource::Texture(t.clone()),
                Some((x, _, None)) => ColorSource::Rgb(Rgb::splat(*x)),
                None => ColorSource::Rgb(Rgb::ZERO),
            };
            def.roughness_map = Some(RoughnessMapDesc {
                u: source(&u),
                v: source(&v),
                remap_sqrt: remap,
            });
        }
        let mut alpha = [0.0f32; 2];
        for (slot, r) in alpha.iter_mut().zip([u, v]) {
            let Some((r, loc, _)) = r else { continue };
            if r.is_nan() || r < 0.0 {
                return Err(Error::scene(
                    Some(loc),
                    format!("{prefix}roughness"),
                    format!("must not be negative, got {r}"),
                ));
            }
            def.locs.keys.push(("roughness".into(), loc.clone()));
            let a = if remap { r.sqrt() } else { r };
            *slot = if a > 1.0 {
                self.approximated(
                    &loc,
                    format!("roughness {r} (GGX α {a})"),
                    "trazo's microfacet models take α up to 1; 1 is used",
                );
                1.0
            } else {
                a
            };
        }
        Ok((alpha[0], alpha[1]))
    }

    /// An index of refraction given as a float or a named or sampled
    /// spectrum (glasses, thin sheets, coats): its value at 587.6 nm (for
    /// an RGB value, the mean) and how it varies with wavelength, where it
    /// does.
    fn eta_spectrum(
        &mut self,
        p: &ParamList,
        name: &str,
        default: f32,
        def: &mut MatDef,
        dir_rel: &Path,
    ) -> Result<(f32, Option<IorSpectrum>)> {
        let Some((v, prm)) = p.spectrum(name)? else {
            return Ok((default, None));
        };
        // A name that is not a glass's: a file of samples, found as
        // textures are.
        let v = match v {
            SpectrumValue::Named(n) if IorSpectrum::named_glass(&n).is_none() => {
                SpectrumValue::Sampled(self.spectrum_file(&n, dir_rel, prm)?)
            }
            v => v,
        };
        def.locs.keys.push(("ior".into(), prm.loc.clone()));
        let loc = prm.loc.clone();
        let what = format!("\"{}\"", prm.written);
        let mut spectrum = None;
        let eta = match v {
            SpectrumValue::Float(e) => e,
            SpectrumValue::Named(n) => {
                let glass = IorSpectrum::named_glass(&n).expect("other names were read as files");
                let e = glass.at(D_LINE_NM);
                spectrum = Some(glass);
                e
            }
            SpectrumValue::Sampled(s) => match IorSpectrum::sampled(&s) {
                Some(varying) => {
                    let e = varying.at(D_LINE_NM);
                    spectrum = Some(varying);
                    e
                }
                // The same index at every wavelength.
                None => s[0].1,
            },
            SpectrumValue::Rgb(c) => {
                let rgb = [c.x, c.y, c.z];
                if !rgb.iter().all(|&c| c > 0.0 && c.is_finite()) {
                    return Err(prm.err(format!(
                        "every channel of an index of refraction must be positive, got {} {} {}",
                        c.x, c.y, c.z
                    )));
                }
                match IorSpectrum::from_rgb(rgb) {
                    Some(smooth) => {
                        let e = smooth.at(D_LINE_NM);
                        spectrum = Some(smooth);
                        e
                    }
                    // Grey: the same index at every wavelength.
                    None if c.x == c.y && c.y == c.z => c.x,
                    None => {
                        let mean = (c.x + c.y + c.z) / 3.0;
                        self.approximated(
                            &loc,
                            format!("RGB {what}"),
                            format!("no smooth spectrum has this colour; the mean index {mean} is used"),
                        );
                        mean
                    }
                }
            }
            SpectrumValue::Blackbody { .. } | SpectrumValue::Texture(_) => {
                self.unsupported(
                    &loc,
                    what,
                    format!("an index of refraction must be a number here; {default} is used"),
                );
                default
            }
        };
        if !(eta > 0.0 && eta.is_finite()) {
            return Err(prm.err(format!("an index of refraction must be positive, got {eta}")));
        }
        if let Some((lo, hi)) = spectrum.as_ref().map(IorSpectrum::visible_range) {
            if !(lo > 0.0 && hi.is_finite()) {
                return Err(prm.err(format!(
                    "an index of refraction must be positive over 360-830 nm, got {lo} to {hi}"
                )));
            }
        }
        Ok((eta, spectrum))
    }

    /// η or k of a conductor: RGB, a named metal spectrum such as
    /// `"metal-Au-eta"`, or a sampled spectrum. pbrt-v4's default is copper.
    fn metal_part(&mut self, v: Option<(SpectrumValue, &Param)>, is_eta: bool, dir_rel: &Path) -> Result<Rgb> {
        let (cu_eta, cu_k) = metal_ior("Cu").expect("copper is tabulated");
        let default = if is_eta { cu_eta } else { cu_k };
        let Some((v, prm)) = v else {
            return Ok(default);
        };
        let loc = prm.loc.clone();
        let what = format!("\"{}\"", prm.written);
        Ok(match v {
            SpectrumValue::Rgb(c) => self.rgb_in_space(c, ColorUse::Unbounded, &loc, &what),
            SpectrumValue::Float(x) => Rgb::splat(x),
            SpectrumValue::Named(n) => match metal_of(&n) {
                Some((metal, part_eta)) => {
                    let known = metal_ior(metal)
                        .filter(|_| crate::material::conductor::METAL_NAMES.contains(&metal))
                        .or_else(|| pbrt_only_metal_ior(metal));
                    match known {
                        Some((eta, k)) => {
                            if part_eta {
                                eta
                            } else {
                                k
                            }
                        }
                        None => {
                            self.approximated(
                                &loc,
                                format!("{what} \"{n}\""),
                                "pbrt-v4 names the spectra of Au, Ag, Cu, Al, CuZn, MgO and TiO2 only; copper is used",
                            );
                            if part_eta { cu_eta } else { cu_k }
                        }
                    }
                }
                // Not a named spectrum: a file of samples, found as
                // textures are.
                None => spectrum_at_rgb_wavelengths(&self.spectrum_file(&n, dir_rel, prm)?),
            },
            // As trazo's metals are tabulated: at one wavelength per channel.
            SpectrumValue::Sampled(s) => spectrum_at_rgb_wavelengths(&s),
            SpectrumValue::Blackbody { .. } | SpectrumValue::Texture(_) => {
                self.unsupported(&loc, what, "trazo's conductors take constant η and k; copper's is used");
                default
            }
        })
    }

    /// A conductor from `eta`/`k` or `reflectance` (with `prefix`
    /// `"conductor."` for coatedconductor).
    fn conductor(&mut self, p: &ParamList, prefix: &str, def: &mut MatDef, dir_rel: &Path) -> Result<MaterialKindDesc> {
        let eta = p.spectrum(&format!("{prefix}eta"))?;
        let k = p.spectrum(&format!("{prefix}k"))?;
        let roughness = self.roughness(p, prefix, def)?;
        let fresnel = match p.spectrum("reflectance")? {
            Some((v, prm)) => {
                if eta.is_some() || k.is_some() {
                    return Err(prm.err(format!(
                        "give either \"reflectance\" or \"{prefix}eta\" and \"{prefix}k\", not both"
                    )));
                }
                def.locs.keys.push(("reflectance".into(), prm.loc.clone()));
                let c = match self.color_value(v, prm, ColorUse::Albedo)? {
                    Some(src) => self.constant_color(src, prm)?,
                    None => Rgb::ONE,
                };
                ConductorDesc::Reflectance(c)
            }
            None => {
                for (key, v) in [("eta", &eta), ("k", &k)] {
                    if let Some((_, prm)) = v {
                        def.locs.keys.push((key.into(), prm.loc.clone()));
                    }
                }
                ConductorDesc::Complex {
                    eta: self.metal_part(eta, true, dir_rel)?,
                    k: self.metal_part(k, false, dir_rel)?,
                }
            }
        };
        Ok(MaterialKindDesc::Conductor {
            fresnel,
            tint: Rgb::ONE,
            roughness,
            distribution: MicrofacetDistribution::Ggx,
        })
    }

    /// Converts a material of type `kind`; `name` is the name trazo gives it.
    pub(super) fn material(
        &mut self,
        kind: &str,
        p: &ParamList,
        loc: &SourceLoc,
        name: String,
        dir_rel: &Path,
    ) -> Result<MatDef> {
        let mut def = MatDef {
            name,
            kind: MatKind::Desc(MaterialKindDesc::Diffuse {
                reflectance: ColorSource::Rgb(Rgb::splat(0.5)),
            }),
            locs: Locs::at(Some(loc.clone())),
            tex_refs: Vec::new(),
            normal_map: None,
            bump_map: None,
            roughness_map: None,
            subsurface: None,
        };
        let what = format!("material \"{kind}\"");
        // pbrt-v4's normal map: an image read linearly, looked up at
        // (u, 1 − v) as its image textures are, the normal 2c − 1 in the
        // frame of ∂p/∂u and the shading normal.
        if let Some((file, prm)) = p.string("normalmap")? {
            let texture = format!("{}: normalmap", def.name);
            self.desc.textures.push(TextureDesc {
                name: texture.clone(),
                kind: TextureKind::Image {
                    source: ImageSource::DataFile(self.resolve(dir_rel, &file)),
                    scale: Vec2::ONE,
                    offset: Vec2::ZERO,
                    encoding: Some(Encoding::Linear),
                    tint: Rgb::ONE,
                    wrap: [crate::texture::WrapMode::Repeat; 2],
                    filter: crate::texture::ImageFilter::Bilinear,
                },
                locs: Locs::at(Some(prm.loc.clone())),
            });
            def.normal_map = Some(ColorSource::Texture(texture));
        }
        // pbrt-v4's bump map: a float texture of heights along the shading
        // normal; a normal map, where there is one, takes precedence.
        if let Some((FloatValue::Texture(t), prm)) = p.float_or_texture("displacement")? {
            let loc = prm.loc.clone();
            match self.float_texture_descs.get(&t) {
                Some(_) if def.normal_map.is_some() => {}
                Some((desc_name, _)) => {
                    def.bump_map = Some(BumpMapDesc {
                        height: ColorSource::Texture(desc_name.clone()),
                        scale: 1.0,
                    });
                }
                None => self.unsupported(
                    &loc,
                    format!("\"displacement\" texture \"{t}\""),
                    "trazo bumps only with the float textures it reads; the surface is left smooth",
                ),
            }
        }
        let desc = match kind {
            "diffuse" => MaterialKindDesc::Diffuse {
                reflectance: self.albedo(p, "reflectance", 0.5, "reflectance", &mut def)?,
            },
            "conductor" => self.conductor(p, "", &mut def, dir_rel)?,
            "coatedconductor" => {
                let MaterialKindDesc::Conductor { fresnel, roughness, .. } =
                    self.conductor(p, "conductor.", &mut def, dir_rel)?
                else {
                    unreachable!("conductor() makes conductors")
                };
                // The conductor's roughness texture, apart from the coat's.
                let roughness_map = def.roughness_map.take();
                let coat_ior = self.eta_spectrum(p, "interface.eta", 1.5, &mut def, dir_rel)?;
                let coat_roughness = self.roughness(p, "interface.", &mut def)?;
                self.layered(
                    p,
                    LayeredBaseDesc::Conductor {
                        fresnel,
                        roughness,
                        roughness_map,
                    },
                    coat_ior,
                    coat_roughness,
                )?
            }
            "thindielectric" => {
                let (ior, dispersion) = self.eta_spectrum(p, "eta", 1.5, &mut def, dir_rel)?;
                MaterialKindDesc::Thin {
                    ior,
                    ext_ior: 1.0,
                    reflect_tint: Rgb::ONE,
                    transmit_tint: Rgb::ONE,
                    dispersion,
                }
            }
            "dielectric" => {
                let (ior, dispersion) = self.eta_spectrum(p, "eta", 1.5, &mut def, dir_rel)?;
                let roughness = self.roughness(p, "", &mut def)?;
                let mut d = dielectric(ior, roughness);
                if let MaterialKindDesc::Dielectric { dispersion: slot, .. } = &mut d {
                    *slot = dispersion;
                }
                d
            }
            "coateddiffuse" => {
                let diffuse = self.albedo(p, "reflectance", 0.5, "diffuse", &mut def)?;
                let coat_roughness = self.roughness(p, "", &mut def)?;
                let coat_ior = self.eta_spectrum(p, "eta", 1.5, &mut def, dir_rel)?;
                self.layered(p, LayeredBaseDesc::Diffuse(diffuse), coat_ior, coat_roughness)?
            }
            "diffusetransmission" => {
                let reflectance = self.albedo(p, "reflectance", 0.25, "reflectance", &mut def)?;
                let transmittance = self.albedo(p, "transmittance", 0.25, "transmittance", &mut def)?;
                // pbrt-v4 multiplies both by `scale` and clamps them to [0, 1].
                let scale = match self.float_param(p, "scale", 1.0)? {
                    Some((s, _)) if s.is_finite() && s >= 0.0 => s,
                    Some((s, l)) => {
                        return Err(Error::scene(
                            Some(l),
                            "scale",
                            format!("must be a non-negative number, got {s}"),
                        ));
                    }
                    None => 1.0,
                };
                // Over a texture: a scale node, clamped where the BSDF is
                // made (`MaterialKind::DiffuseTransmission`).
                let scaled = |this: &mut Self, c: ColorSource| -> Result<ColorSource> {
                    Ok(match c {
                        ColorSource::Rgb(rgb) => ColorSource::Rgb((rgb * scale).clamp(Rgb::ZERO, Rgb::ONE)),
                        other if scale == 1.0 => other,
                        ColorSource::Texture(tex) => {
                            let typical = this.texture_colors.get(&tex).copied().unwrap_or(Rgb::ONE) * scale;
                            let name = format!("{tex} scaled by {scale} ({})", this.desc.textures.len());
                            let kind = TextureKind::Node(TextureNode::Scale {
                                tex: ColorSource::Texture(tex),
                                scale: ColorSource::Rgb(Rgb::splat(scale)),
                            });
                            this.push_texture(&name, loc, Locs::at(Some(loc.clone())), (kind, typical))?;
                            ColorSource::Texture(name)
                        }
                    })
                };
                let reflectance = scaled(self, reflectance)?;
                let transmittance = scaled(self, transmittance)?;
                MaterialKindDesc::DiffuseTransmission {
                    reflectance,
                    transmittance,
                }
            }
            "subsurface" => {
                let ior = p.float("eta", 1.33)?;
                let roughness = self.roughness(p, "", &mut def)?;
                def.subsurface = Some(self.subsurface_medium(p, loc)?);
                self.approximated(
                    loc,
                    &what,
                    "a dielectric surface over a homogeneous medium that the volumetric path tracer walks through (pbrt-v4 integrates the same medium with its tabulated photon-beam-diffusion BSSRDF); as in pbrt-v4, only \"volpath\" scatters below the surface",
                );
                dielectric(ior, roughness)
            }
            "measured" => {
                let Some((file, prm)) = p.string("filename")? else {
                    return Err(Error::scene(
                        Some(loc.clone()),
                        "filename",
                        "measured needs a \"string filename\" (an RGL .bsdf file)",
                    ));
                };
                def.locs.keys.push(("file".into(), prm.loc.clone()));
                MaterialKindDesc::Measured {
                    file: self.resolve(dir_rel, &file),
                }
            }
            "hair" => {
                // pbrt-v4's HairMaterial: σa, else a colour, else pigment
                // concentrations, else eumelanin 1.3 (brown).
                let beta_m = p.float("beta_m", 0.3)?;
                let beta_n = p.float("beta_n", 0.3)?;
                let eta = p.float("eta", 1.55)?;
                let alpha = p.float("alpha", 2.0)?;
                let colour_key = ["reflectance", "color"].into_iter().find(|k| p.has(k));
                let sigma_a = if p.has("sigma_a") {
                    self.medium_color(p, "sigma_a", Rgb::ZERO)?
                } else if let Some(key) = colour_key {
                    let c = self.medium_color(p, key, Rgb::splat(0.5))?;
                    crate::material::hair::HairBsdf::sigma_a_from_reflectance(c, beta_n)
                } else if p.has("eumelanin") || p.has("pheomelanin") {
                    crate::material::hair::HairBsdf::sigma_a_from_concentration(
                        p.float("eumelanin", 0.0)?.max(0.0),
                        p.float("pheomelanin", 0.0)?.max(0.0),
                    )
                } else {
                    crate::material::hair::HairBsdf::sigma_a_from_concentration(1.3, 0.0)
                };
                // Whichever of the others were given, pbrt-v4 ignores too.
                Self::use_all(p);
                for (key, bad) in [("beta_m", beta_m), ("beta_n", beta_n)] {
                    if !(0.0..=1.0).contains(&bad) {
                        return Err(p.find(key).expect("read").err(format!("must be in [0, 1], got {bad}")));
                    }
                }
                if !(eta > 0.0 && eta.is_finite()) {
                    return Err(p.find("eta").expect("read").err(format!("must be positive, got {eta}")));
                }
                MaterialKindDesc::Hair(crate::material::hair::HairParams {
                    sigma_a,
                    eta,
                    beta_m,
                    beta_n,
                    alpha,
                })
            }
            "mix" => {
                let Some((names, prm)) = p.strings("materials")? else {
                    return Err(Error::scene(
                        Some(loc.clone()),
                        "materials",
                        "mix needs \"string materials\" with the names of two materials",
                    ));
                };
                if names.len() != 2 {
                    return Err(prm.err(format!("needs two material names, found {}", names.len())));
                }
                let mloc = prm.loc.clone();
                // pbrt-v4's `MixMaterial::ChooseMaterial` takes the second
                // with probability `amount`, by a hash of the point and the
                // direction: trazo's mix.
                let amount = match self.float_or_read_texture(p, "amount", 0.5)? {
                    Some((_, _, Some(texture))) => ColorSource::Texture(texture),
                    Some((a, _, None)) => ColorSource::Rgb(Rgb::splat(a)),
                    None => ColorSource::Rgb(Rgb::splat(0.5)),
                };
                def.kind = MatKind::Mix {
                    names: [names[0].clone(), names[1].clone()],
                    amount,
                    loc: mloc,
                };
                return Ok(def);
            }
            // interface, none and "": the shape only bounds a medium.
            _ => MaterialKindDesc::NULL,
        };
        if def.roughness_map.is_some() {
            match &desc {
                // A layered material's map is its coat's.
                MaterialKindDesc::Conductor { .. }
                | MaterialKindDesc::Layered { .. }
                | MaterialKindDesc::Dielectric { .. } => {}
                _ => {
                    def.roughness_map = None;
                    self.approximated(
                        loc,
                        format!("{what} with a float texture for its roughness"),
                        "the texture's typical value is used",
                    );
                }
            }
        }
        def.kind = MatKind::Desc(desc);
        Ok(def)
    }

    /// One warning for a layered material; its layer parameters count as read.
    /// The slab of a `coateddiffuse` or `coatedconductor` (pbrt-v4's
    /// defaults: thickness 0.01, no medium, `g` 0, 10 scattering events, 1
    /// walk per evaluation).
    fn layered(
        &mut self,
        p: &ParamList,
        base: LayeredBaseDesc,
        (coat_ior, coat_dispersion): (f32, Option<IorSpectrum>),
        coat_roughness: (f32, f32),
    ) -> Result<MaterialKindDesc> {
        let thickness = self.float_param(p, "thickness", 0.01)?.map_or(0.01, |(v, _)| v);
        if let Some(prm) = p
            .find("thickness")
            .filter(|_| !(thickness.is_finite() && thickness > 0.0))
        {
            return Err(prm.err(format!("must be positive, got {thickness}")));
        }
        let g = self.float_param(p, "g", 0.0)?.map_or(0.0, |(v, _)| v);
        if let Some(prm) = p.find("g").filter(|_| !(-1.0..=1.0).contains(&g)) {
            return Err(prm.err(format!("must be in [-1, 1], got {g}")));
        }
        let albedo = self.texture_color(p, "albedo", Rgb::ZERO)?;
        if let Some(prm) = p.find("albedo").filter(|_| albedo.max_element() > 1.0) {
            return Err(prm.err("an albedo must be at most 1"));
        }
        let count = |name: &str, default: u32| -> Result<u32> {
            match p.int_opt(name)? {
                None => Ok(default),
                Some((n, _)) if (1..=4096).contains(&n) => Ok(n as u32),
                Some((n, prm)) => Err(prm.err(format!("must be 1 to 4096, got {n}"))),
            }
        };
        let max_depth = count("maxdepth", 10)?;
        let samples = count("nsamples", 1)?;
        Ok(MaterialKindDesc::Layered {
            base,
            coat_ior,
            coat_roughness,
            thickness,
            albedo,
            g,
            max_depth,
            samples,
            coat_dispersion,
        })
    }

    /// `Texture "name" "spectrum"|"float" "class" …`: pbrt-v4's texture
    /// classes as trazo's textures and texture nodes. A float texture is a
    /// grey texture under a name no scene can write (pbrt's float and
    /// spectrum namespaces are apart), read by its first channel.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn texture(
        &mut self,
        name: &str,
        ttype: &str,
        class: &str,
        p: &ParamList,
        loc: &SourceLoc,
        name_loc: &SourceLoc,
        dir_rel: &Path,
    ) -> Result<()> {
        let float = ttype == "float";
        if float {
            if !self.float_textures.insert(name.to_string()) {
                return Err(Error::scene(
                    Some(name_loc.clone()),
                    "Texture",
                    format!("the float texture \"{name}\" is already defined"),
                ));
            }
        } else if let Some(first) = self.spectrum_textures.get(name) {
            return Err(Error::scene(
                Some(name_loc.clone()),
                "Texture",
                format!("the texture \"{name}\" is already defined (at {first})"),
            ));
        }
        let desc_name = if float {
            format!("\u{0}float texture {name}")
        } else {
            name.to_string()
        };
        // pbrt-v4 knows these classes for one kind of texture only.
        let only = match class {
            "fbm" | "wrinkled" | "windy" => Some("float"),
            "marble" => Some("spectrum"),
            _ => None,
        };
        if let Some(kind) = only.filter(|k| *k != ttype) {
            return Err(Error::scene(
                Some(loc.clone()),
                "Texture",
                format!("\"{class}\" is a {kind} texture in pbrt-v4, not a {ttype} one"),
            ));
        }
        let mut locs = Locs::at(Some(loc.clone()));
        let what = format!("Texture \"{name}\" \"{class}\"");
        let input = |r: &mut Self, key: &str, default: f32| r.texture_input(p, key, default, float);
        let kind = match class {
            "imagemap" => self.image_texture(p, loc, &desc_name, &mut locs, dir_rel, float)?,
            "checkerboard" => {
                let even = input(self, "tex1", 1.0)?;
                let odd = input(self, "tex2", 0.0)?;
                match p.int_opt("dimension")? {
                    None | Some((2, _)) => {
                        let mapping = self.mapping_2d(p, loc)?;
                        if let Some(prm) = p.find("uscale").or(p.find("vscale")) {
                            locs.keys.push(("scale".into(), prm.loc.clone()));
                        }
                        match (even, odd, mapping) {
                            (ColorSource::Rgb(even), ColorSource::Rgb(odd), Mapping2D::Uv { scale, offset })
                                if offset == Vec2::ZERO =>
                            {
                                TextureKind::Checkerboard { even, odd, scale }
                            }
                            (even, odd, mapping) => TextureKind::Node(TextureNode::Checkerboard { even, odd, mapping }),
                        }
                    }
                    Some((3, _)) => {
                        let m = self.gs.ctm;
                        let s = Mat3::from_mat4(m).determinant().abs().cbrt();
                        let uniform = s > 0.0 && m.abs_diff_eq(Mat4::from_scale(Vec3::splat(s)), 1e-6 * s.max(1.0));
                        match (even, odd) {
                            (ColorSource::Rgb(even), ColorSource::Rgb(odd)) if uniform => TextureKind::Checkerboard3d {
                                even,
                                odd,
                                scale: 1.0 / s,
                            },
                            (even, odd) => TextureKind::Node(TextureNode::SolidCheckerboard {
                                even,
                                odd,
                                to_texture: self.texture_from_world(loc)?,
                            }),
                        }
                    }
                    Some((d, prm)) => return Err(prm.err(format!("must be 2 or 3, got {d}"))),
                }
            }
            "constant" => {
                let c = if float {
                    Rgb::splat(p.float("value", 1.0)?)
                } else {
                    self.texture_color(p, "value", Rgb::ONE)?
                };
                TextureKind::Constant(c)
            }
            "scale" => {
                let tex = input(self, "tex", 1.0)?;
                let scale = self.float_input(p, "scale", 1.0)?;
                match (tex, scale) {
                    (ColorSource::Rgb(t), ColorSource::Rgb(s)) => TextureKind::Constant(t * s),
                    // An image times a number: the image with its colours
                    // multiplied, as pbrt-v4 makes it.
                    (ColorSource::Texture(t), ColorSource::Rgb(s)) if self.image_desc(&t).is_some() => {
                        let mut kind = self.image_desc(&t).expect("checked").clone();
                        if let TextureKind::Image { tint, .. } = &mut kind {
                            *tint *= s;
                        }
                        kind
                    }
                    (tex, scale) => TextureKind::Node(TextureNode::Scale { tex, scale }),
                }
            }
            "mix" => {
                let first = input(self, "tex1", 0.0)?;
                let second = input(self, "tex2", 1.0)?;
                let amount = self.float_input(p, "amount", 0.5)?;
                match (first, second, amount) {
                    (ColorSource::Rgb(a), ColorSource::Rgb(b), ColorSource::Rgb(t)) => {
                        TextureKind::Constant(a * (1.0 - t.x) + b * t.x)
                    }
                    (first, second, amount) => TextureKind::Node(TextureNode::Mix { first, second, amount }),
                }
            }
            "directionmix" => {
                let first = input(self, "tex1", 0.0)?;
                let second = input(self, "tex2", 1.0)?;
                let (dir, prm) = match p.vec3s("dir", &["vector3", "vector"])? {
                    Some((v, prm)) => (v[0], Some(prm)),
                    None => (Vec3::Y, None),
                };
                // A direction of texture space, as the CTM turns it.
                let dir = self.gs.ctm.transform_vector3(dir);
                if !dir.is_finite() || dir.length_squared() == 0.0 {
                    let at = prm.map_or(loc.clone(), |prm| prm.loc.clone());
                    return Err(Error::scene(Some(at), "dir", "must be a non-zero direction"));
                }
                TextureKind::Node(TextureNode::DirectionMix { first, second, dir })
            }
            "bilerp" => {
                let mut corners = [Rgb::ZERO; 4];
                for (k, (key, d)) in [("v00", 0.0), ("v10", 0.0), ("v01", 1.0), ("v11", 1.0)]
                    .into_iter()
                    .enumerate()
                {
                    corners[k] = if float {
                        Rgb::splat(p.float(key, d)?)
                    } else {
                        self.texture_color(p, key, Rgb::splat(d))?
                    };
                }
                TextureKind::Node(TextureNode::Bilerp {
                    corners,
                    mapping: self.mapping_2d(p, loc)?,
                })
            }
            "dots" => TextureKind::Node(TextureNode::Dots {
                inside: input(self, "inside", 1.0)?,
                outside: input(self, "outside", 0.0)?,
                mapping: self.mapping_2d(p, loc)?,
            }),
            "fbm" | "wrinkled" | "windy" | "marble" => {
                let octaves = match p.int_opt("octaves")? {
                    None => 8,
                    Some((o, prm)) => {
                        if !(0..=MAX_NOISE_OCTAVES as i64).contains(&o) {
                            return Err(prm.err(format!("must be between 0 and {MAX_NOISE_OCTAVES}, got {o}")));
                        }
                        o as u32
                    }
                };
                let omega = p.float("roughness", 0.5)?;
                let pattern = NoisePattern::named(class, octaves, omega, || {
                    Ok::<_, Error>((p.float("scale", 1.0)?, p.float("variation", 0.2)?))
                })?
                .expect("a noise class");
                TextureKind::Node(TextureNode::Noise {
                    pattern,
                    to_texture: self.texture_from_world(loc)?,
                })
            }
            _ => {
                Self::use_all(p);
                self.unsupported(loc, &what, "replaced by a constant grey of 0.5");
                TextureKind::Constant(Rgb::splat(0.5))
            }
        };
        let typical = self.typical_color(&kind);
        if float {
            self.float_texture_descs
                .insert(name.to_string(), (desc_name.clone(), typical.x));
            self.texture_colors.insert(desc_name.clone(), typical);
            self.desc.textures.push(TextureDesc {
                name: desc_name,
                kind,
                locs,
            });
            return Ok(());
        }
        self.push_texture(name, loc, locs, (kind, typical))
    }

    /// An `imagemap`: the image with pbrt-v4's (u, v) mapping, or placed
    /// by another mapping; `invert`ed where asked; a float texture's image
    /// read as pbrt-v4 reads one (its alpha, or the mean of its colours).
    #[allow(clippy::too_many_arguments)]
    fn image_texture(
        &mut self,
        p: &ParamList,
        loc: &SourceLoc,
        desc_name: &str,
        locs: &mut Locs,
        dir_rel: &Path,
        float: bool,
    ) -> Result<TextureKind> {
        let Some((file, prm)) = p.string("filename")? else {
            return Err(Error::scene(
                Some(loc.clone()),
                "filename",
                "imagemap needs a \"string filename\"",
            ));
        };
        locs.keys.push(("file".into(), prm.loc.clone()));
        let mapping = self.mapping_2d(p, loc)?;
        let tint = p.float("scale", 1.0)?;
        if tint < 0.0 {
            return Err(p
                .find("scale")
                .expect("read")
                .err(format!("must not be negative, got {tint}")));
        }
        // As pbrt-v4's `Image::Read`: the encoding decodes PNG files (8 or
        // 16 bits); other integer formats are always sRGB, float formats
        // linear, whatever it says.
        let encoding = match p.string("encoding")? {
            None => None,
            Some((e, prm)) => {
                let encoding = parse_encoding(&e).ok_or_else(|| {
                    prm.err(format!(
                        "unknown encoding \"{e}\": expected \"sRGB\", \"linear\" or \"gamma <value>\""
                    ))
                })?;
                let png = Path::new(&file)
                    .extension()
                    .is_some_and(|x| x.eq_ignore_ascii_case("png"));
                png.then_some(encoding)
            }
        };
        let wrap = match p.string("wrap")? {
            None => crate::texture::WrapMode::Repeat,
            Some((w, prm)) => match w.as_str() {
                "repeat" => crate::texture::WrapMode::Repeat,
                "clamp" => crate::texture::WrapMode::Clamp,
                _ => {
                    let l = prm.loc.clone();
                    self.approximated(&l, format!("wrap \"{w}\""), "the image repeats");
                    crate::texture::WrapMode::Repeat
                }
            },
        };
        let filter = match p.string("filter")? {
            None => crate::texture::ImageFilter::Bilinear,
            Some((f, prm)) => match f.as_str() {
                "point" => crate::texture::ImageFilter::Nearest,
                "bilinear" => crate::texture::ImageFilter::Bilinear,
                _ => {
                    let l = prm.loc.clone();
                    self.approximated(
                        &l,
                        format!("filter \"{f}\""),
                        "read bilinearly at the point (trazo filters by supersampling)",
                    );
                    crate::texture::ImageFilter::Bilinear
                }
            },
        };
        let (scale, offset) = match mapping {
            Mapping2D::Uv { scale, offset } => (scale, offset),
            _ => (Vec2::ONE, Vec2::ZERO),
        };
        let path = self.resolve(dir_rel, &file);
        let mut kind = TextureKind::Image {
            source: if float {
                ImageSource::FloatFile(path)
            } else {
                ImageSource::File(path)
            },
            scale,
            offset,
            encoding,
            tint: Rgb::splat(tint),
            wrap: [wrap; 2],
            filter,
        };
        if !matches!(mapping, Mapping2D::Uv { .. }) {
            let image = self.hidden_texture(desc_name, "image", kind, locs.clone());
            kind = TextureKind::Node(TextureNode::Mapped { tex: image, mapping });
        }
        if p.bool("invert", false)? {
            let t = self.hidden_texture(desc_name, "uninverted", kind, locs.clone());
            kind = TextureKind::Node(TextureNode::Invert(t));
        }
        Ok(kind)
    }

    /// Records a texture that another is made of, under a name derived from
    /// that one's that no scene can write; what names it.
    fn hidden_texture(&mut self, owner: &str, part: &str, kind: TextureKind, locs: Locs) -> ColorSource {
        let name = format!("\u{0}{owner} {part}");
        let typical = self.typical_color(&kind);
        self.texture_colors.insert(name.clone(), typical);
        self.desc.textures.push(TextureDesc {
            name: name.clone(),
            kind,
            locs,
        });
        ColorSource::Texture(name)
    }

    /// The image texture a name stands for, if it is one.
    fn image_desc(&self, name: &str) -> Option<&TextureKind> {
        self.desc
            .textures
            .iter()
            .rev()
            .find(|t| t.name == name)
            .map(|t| &t.kind)
            .filter(|k| matches!(k, TextureKind::Image { .. }))
    }

    /// A texture's typical colour, for where trazo needs a constant.
    fn typical_color(&self, kind: &TextureKind) -> Rgb {
        let of = |c: &ColorSource| match c {
            ColorSource::Rgb(c) => *c,
            ColorSource::Texture(t) => self.texture_colors.get(t).copied().unwrap_or(Rgb::splat(0.5)),
        };
        match kind {
            TextureKind::Constant(c) => *c,
            TextureKind::Checkerboard { even, odd, .. } | TextureKind::Checkerboard3d { even, odd, .. } => {
                0.5 * (*even + *odd)
            }
            TextureKind::Image { tint, .. } => 0.5 * *tint,
            TextureKind::MeshAttribute { .. } => Rgb::splat(0.5),
            TextureKind::Node(node) => node.average_by(of),
        }
    }

    /// An input of a texture: a number or float texture in a float
    /// texture, a colour or spectrum texture in a spectrum one.
    fn texture_input(&mut self, p: &ParamList, key: &str, default: f32, float: bool) -> Result<ColorSource> {
        if float {
            return self.float_input(p, key, default);
        }
        let Some((v, prm)) = p.spectrum(key)? else {
            return Ok(ColorSource::Rgb(Rgb::splat(default)));
        };
        if let SpectrumValue::Float(x) = v {
            return Ok(ColorSource::Rgb(Rgb::splat(x.max(0.0))));
        }
        match self.color_value(v, prm, ColorUse::Unbounded)? {
            Some(ColorSource::Texture(t)) => {
                if !self.spectrum_textures.contains_key(&t) {
                    let hint = if self.float_textures.contains(&t) {
                        " (a float texture of that name exists, but a colour needs a spectrum texture)".to_string()
                    } else {
                        suggest(&t, self.spectrum_textures.keys().map(String::as_str))
                    };
                    return Err(prm.err(format!("no texture named \"{t}\" before this one{hint}")));
                }
                Ok(ColorSource::Texture(t))
            }
            Some(src) => Ok(src),
            None => Ok(ColorSource::Rgb(Rgb::splat(default))),
        }
    }

    /// A float input of a texture: a number, or a float texture made
    /// before.
    fn float_input(&mut self, p: &ParamList, key: &str, default: f32) -> Result<ColorSource> {
        match p.float_or_texture(key)? {
            None => Ok(ColorSource::Rgb(Rgb::splat(default))),
            Some((FloatValue::Num(v), _)) => Ok(ColorSource::Rgb(Rgb::splat(v))),
            Some((FloatValue::Texture(t), prm)) => match self.float_texture_descs.get(&t) {
                Some((desc_name, _)) => Ok(ColorSource::Texture(desc_name.clone())),
                None => Err(prm.err(format!(
                    "no float texture named \"{t}\" before this one{}",
                    suggest(&t, self.float_textures.iter().map(String::as_str))
                ))),
            },
        }
    }

    /// pbrt-v4's `TextureMapping2D`: `uv` (s = su·u + du, t = sv·v + dv),
    /// or `spherical`, `cylindrical` and `planar` about the texture space
    /// that the CTM places.
    fn mapping_2d(&mut self, p: &ParamList, loc: &SourceLoc) -> Result<Mapping2D> {
        let kind = p.string("mapping")?;
        let kind = kind.as_ref().map_or("uv", |(m, _)| m.as_str());
        Ok(match kind {
            "spherical" => Mapping2D::Spherical {
                to_texture: self.texture_from_world(loc)?,
            },
            "cylindrical" => Mapping2D::Cylindrical {
                to_texture: self.texture_from_world(loc)?,
            },
            "planar" => {
                let axis = |name: &str, default: Vec3| -> Result<Vec3> {
                    Ok(p.vec3s(name, &["vector3", "vector"])?.map_or(default, |(v, _)| v[0]))
                };
                Mapping2D::Planar {
                    to_texture: self.texture_from_world(loc)?,
                    s_axis: axis("v1", Vec3::X)?,
                    t_axis: axis("v2", Vec3::Y)?,
                    offset: Vec2::new(p.float("udelta", 0.0)?, p.float("vdelta", 0.0)?),
                }
            }
            other => {
                if other != "uv" {
                    // pbrt-v4 reports it and goes on with (u, v).
                    self.approximated(
                        loc,
                        format!("texture mapping \"{other}\""),
                        "the (u, v) mapping is used",
                    );
                }
                Mapping2D::Uv {
                    scale: Vec2::new(p.float("uscale", 1.0)?, p.float("vscale", 1.0)?),
                    offset: Vec2::new(p.float("udelta", 0.0)?, p.float("vdelta", 0.0)?),
                }
            }
        })
    }

    /// World to texture space: the inverse of the CTM at the `Texture`
    /// directive (pbrt-v4's textureFromRender).
    fn texture_from_world(&self, loc: &SourceLoc) -> Result<Affine3A> {
        let m = self.gs.ctm;
        let det = m.determinant();
        if !det.is_finite() || det.abs() < 1e-12 {
            return Err(Error::scene(
                Some(loc.clone()),
                "Texture",
                "the texture's transform (the CTM) is singular",
            ));
        }
        Ok(Affine3A::from_mat4(m.inverse()))
    }

    /// The medium of a `subsurface` material, by pbrt-v4's four ways:
    /// `sigma_a` and `sigma_s`; a `reflectance` and mean free path `mfp`
    /// (σt = 1/mfp, the single-scattering albedo whose multiple scattering
    /// reflects that much, by Chiang et al.'s (2016) inversion where pbrt-v4
    /// inverts its photon-beam-diffusion table); pbrt-v4's defaults (in
    /// mm⁻¹); a measured medium by `name` (g then 0). All times `scale`.
    fn subsurface_medium(&mut self, p: &ParamList, loc: &SourceLoc) -> Result<super::SubsurfaceMedium> {
        let mut g = p.float("g", 0.0)?;
        if !(g > -1.0 && g < 1.0) {
            return Err(p.find("g").expect("read").err(format!("must be in (-1, 1), got {g}")));
        }
        let defaults = (Rgb::new(0.0011, 0.0024, 0.014), Rgb::new(2.55, 3.21, 3.77));
        let (sigma_a, sigma_s) = if let Some((name, prm)) = p.string("name")? {
            let Some(coefficients) = crate::media::measured::measured_medium(&name) else {
                return Err(prm.err(format!(
                    "no measured medium named \"{name}\"{}",
                    suggest(&name, crate::media::measured::measured_medium_names())
                )));
            };
            if g != 0.0 {
                let l = prm.loc.clone();
                self.approximated(
                    &l,
                    format!("\"g\" {g} with the measured medium \"{name}\""),
                    "g = 0: the measured coefficients are reduced ones, for isotropic scattering (as pbrt-v4)",
                );
            }
            g = 0.0;
            coefficients
        } else if p.find("sigma_a").is_some() || p.find("sigma_s").is_some() {
            let (Some(_), Some(_)) = (p.find("sigma_a"), p.find("sigma_s")) else {
                return Err(Error::scene(
                    Some(loc.clone()),
                    "sigma_a",
                    "give both \"sigma_a\" and \"sigma_s\", or neither",
                ));
            };
            (
                self.medium_color(p, "sigma_a", Rgb::ONE)?,
                self.medium_color(p, "sigma_s", Rgb::ONE)?,
            )
        } else if let Some((v, prm)) = p.spectrum("reflectance")? {
            let src = self.color_value(v, prm, ColorUse::Albedo)?;
            let reflectance = match src {
                Some(src) => self.constant_color(src, prm)?,
                None => Rgb::splat(0.5),
            };
            let mfp = self.medium_color(p, "mfp", Rgb::ONE)?;
            if mfp.min_element() <= 0.0 || !mfp.is_finite() {
                return Err(p
                    .find("mfp")
                    .expect("read")
                    .err("the mean free path must be positive and finite"));
            }
            let rho = reflectance.to_array().map(single_scattering_albedo);
            let rho = Rgb::from(rho);
            ((Rgb::ONE - rho) / mfp, rho / mfp)
        } else {
            defaults
        };
        let scale = p.float("scale", 1.0)?;
        let (sigma_a, sigma_s) = (sigma_a * scale, sigma_s * scale);
        if !(sigma_a.is_finite() && sigma_s.is_finite()) || sigma_a.min_element() < 0.0 || sigma_s.min_element() < 0.0 {
            return Err(Error::scene(
                Some(loc.clone()),
                "sigma_a",
                "the scattering coefficients (times scale) must be finite and not negative",
            ));
        }
        Ok(super::SubsurfaceMedium {
            sigma_a,
            sigma_s,
            g,
            loc: loc.clone(),
        })
    }

    /// Records a spectrum texture and its typical colour.
    pub(super) fn push_texture(
        &mut self,
        name: &str,
        loc: &SourceLoc,
        locs: Locs,
        (kind, typical): (TextureKind, Rgb),
    ) -> Result<()> {
        self.spectrum_textures.insert(name.to_string(), loc.clone());
        self.texture_colors.insert(name.to_string(), typical);
        self.desc.textures.push(TextureDesc {
            name: name.to_string(),
            kind,
            locs,
        });
        Ok(())
    }

    /// A constant colour parameter of a texture (another texture stands
    /// for its typical colour).
    fn texture_color(&mut self, p: &ParamList, name: &str, default: Rgb) -> Result<Rgb> {
        let Some((v, prm)) = p.spectrum(name)? else {
            return Ok(default);
        };
        if let SpectrumValue::Float(x) = v {
            return Ok(Rgb::splat(x.max(0.0)));
        }
        match self.color_value(v, prm, ColorUse::Unbounded)? {
            Some(src) => self.constant_color(src, prm),
            None => Ok(default),
        }
    }
}

/// The single-scattering albedo of a medium whose multiple scattering
/// reflects `a` of the light: Chiang et al.'s (2016) fit, "Practical and
/// controllable subsurface scattering for production path tracing",
/// 1 − (4.09712 + 4.20863·a − √(9.59217 + 41.6808·a + 17.7126·a²))².
pub(super) fn single_scattering_albedo(a: f32) -> f32 {
    let a = a.clamp(0.0, 1.0);
    let s = 4.09712 + 4.20863 * a - (9.59217 + 41.6808 * a + 17.7126 * a * a).sqrt();
    (1.0 - s * s).clamp(0.0, 1.0)
}

/// pbrt-v4's dielectric surface (of `dielectric` and `subsurface`): GGX of
/// α along u and v, in vacuum.
fn dielectric(ior: f32, roughness: (f32, f32)) -> MaterialKindDesc {
    MaterialKindDesc::Dielectric {
        ior,
        ext_ior: 1.0,
        roughness,
        distribution: MicrofacetDistribution::Ggx,
        reflect_tint: Rgb::ONE,
        transmit_tint: Rgb::ONE,
        dispersion: None,
    }
}
