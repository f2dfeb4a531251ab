//! `LightSource` and `AreaLightSource` (pbrt-v4 lights.cpp, each light's
//! `Create`). pbrt-v4 divides every emitted spectrum by its luminance
//! (`SpectrumToPhotometric`), which leaves RGB colours as written (only the
//! colour space's illuminant is divided out) and gives blackbody and
//! sampled spectra luminance 1; `scale` multiplies, and `power` or
//! `illuminance` set the scale where given.

use super::materials::ColorUse;
use super::params::ParamList;
use super::{Emission, Parser};
use crate::color::Rgb;
use crate::error::{Error, Result, SourceLoc};
use crate::scene::desc::*;
use glam::{DMat3, DVec3, Mat4, Vec2, Vec3, Vec4};
use std::f32::consts::PI;
use std::path::Path;

impl Parser {
    /// The spectrum parameter `name` of a light as RGB (white by default,
    /// the colour space's illuminant), with where it was written.
    fn emitted(&mut self, p: &ParamList, name: &str) -> Result<(Rgb, Option<SourceLoc>)> {
        let Some((v, prm)) = p.spectrum(name)? else {
            return Ok((self.gs.color_space.to_srgb(true) * Rgb::ONE, None));
        };
        let loc = prm.loc.clone();
        let c = match self.color_value(v, prm, ColorUse::Illuminant)? {
            Some(ColorSource::Rgb(c)) => c,
            _ => Rgb::ONE,
        };
        Ok((c, Some(loc)))
    }

    /// `LightSource`.
    pub(super) fn light_source(&mut self, kind: &str, p: &ParamList, loc: &SourceLoc, dir_rel: &Path) -> Result<()> {
        let ctm = self.gs.ctm;
        let mut locs = Locs::at(Some(loc.clone()));
        let what = format!("LightSource \"{kind}\"");
        let light = match kind {
            "goniometric" if p.find("filename").is_some() => self.goniometric_light(p, loc, &mut locs, dir_rel)?,
            "point" | "goniometric" => {
                let (i, iloc) = self.emitted(p, "I")?;
                let mut scale = p.float("scale", 1.0)?;
                if let Some((power, _)) = p.float_opt("power")? {
                    if power > 0.0 {
                        if kind == "point" {
                            // Radiant intensity of a point light of this power.
                            scale *= power / (4.0 * PI);
                        } else {
                            self.unsupported(loc, format!("\"power\" of {what}"), "the given I and scale are used");
                        }
                    }
                }
                if let Some(l) = iloc {
                    locs.keys.push(("intensity".into(), l));
                }
                let from = p.point3("from", Vec3::ZERO)?;
                add_key(&mut locs, "position", p.find("from"));
                let position = place(&ctm, from).ok_or_else(|| at_infinity(loc))?;
                if kind == "goniometric" {
                    self.approximated(
                        loc,
                        format!("{what} without a \"filename\""),
                        "rendered as a point light of intensity I × scale (pbrt-v4 warns too, and has no distribution to read)",
                    );
                }
                LightKind::Point {
                    position,
                    intensity: i * scale,
                    falloff: true,
                }
            }
            "spot" => {
                let (i, iloc) = self.emitted(p, "I")?;
                let mut scale = p.float("scale", 1.0)?;
                let cone = p.float("coneangle", 30.0)?;
                let delta = p.float("conedeltaangle", 5.0)?;
                add_key(&mut locs, "outer_angle", p.find("coneangle"));
                add_key(&mut locs, "inner_angle", p.find("conedeltaangle"));
                if let Some((power, _)) = p.float_opt("power")? {
                    if power > 0.0 {
                        // pbrt-v4 SpotLight::Create: the power of the cone
                        // with its smoothstep falloff.
                        let cos_end = cone.to_radians().cos();
                        let cos_start = (cone - delta).to_radians().cos();
                        scale *= power / (2.0 * PI * ((1.0 - cos_start) + (cos_start - cos_end) / 2.0));
                    }
                }
                if let Some(l) = iloc {
                    locs.keys.push(("intensity".into(), l));
                }
                let from = p.point3("from", Vec3::ZERO)?;
                let to = p.point3("to", Vec3::Z)?;
                add_key(&mut locs, "position", p.find("from"));
                add_key(&mut locs, "to", p.find("to"));
                let position = place(&ctm, from).ok_or_else(|| at_infinity(loc))?;
                let (axis, angles_kept) = spot_axis(&ctm, from, to).ok_or_else(|| {
                    Error::scene(
                        Some(loc.clone()),
                        "LightSource",
                        "the current transform is singular, or \"from\" and \"to\" are the same point, so the spotlight has no direction",
                    )
                })?;
                if !angles_kept {
                    self.approximated(
                        loc,
                        "a spotlight under a transform that stretches directions unevenly",
                        "pbrt-v4's cone is distorted by it (its angles change, or it becomes elliptical); trazo's keeps the written angles, around the axis pbrt-v4's has",
                    );
                }
                LightKind::Spot {
                    position,
                    to: position + axis,
                    intensity: i * scale,
                    // cos(−x) = cos(x): a delta larger than the cone gives
                    // pbrt a hard edge at |cone − delta|, capped by the cone.
                    inner_angle: (cone - delta).abs().min(cone),
                    outer_angle: cone,
                    profile: crate::light::SpotProfile::SmoothStepInCosine,
                    projection: None,
                    falloff: true,
                }
            }
            "distant" => {
                let (l, lloc) = self.emitted(p, "L")?;
                let mut scale = p.float("scale", 1.0)?;
                if let Some((e, _)) = p.float_opt("illuminance")? {
                    if e > 0.0 {
                        scale *= e;
                    }
                }
                if let Some(l) = lloc {
                    locs.keys.push(("irradiance".into(), l));
                }
                let from = p.point3("from", Vec3::ZERO)?;
                let to = p.point3("to", Vec3::Z)?;
                add_key(&mut locs, "direction", p.find("to").or(p.find("from")));
                LightKind::Directional {
                    // Light travels from `from` towards `to`. pbrt-v4 turns
                    // the direction by the upper-left 3×3 part of the CTM
                    // (`DistantLight::SampleLi`), ignoring a projective row,
                    // as this does.
                    direction: ctm.transform_vector3(to - from),
                    irradiance: l * scale,
                }
            }
            "infinite" => return self.infinite_light(p, loc, dir_rel),
            "projection" => self.projection_light(p, loc, &mut locs, dir_rel)?,
            _ => {
                Self::use_all(p);
                self.unsupported(loc, &what, "the light is skipped");
                return Ok(());
            }
        };
        self.desc.lights.push(LightDesc { kind: light, locs });
        Ok(())
    }

    /// The texture of a light's image file, read at the nearest pixel and
    /// clamped at its edges as pbrt-v4's lights read their images, under a
    /// name no scene can write; `top_at_v0` reads v = 0 at its top row.
    fn light_image(
        &mut self,
        kind: &str,
        file: &str,
        file_loc: SourceLoc,
        loc: &SourceLoc,
        dir_rel: &Path,
        top_at_v0: bool,
    ) -> Result<String> {
        let name = format!("\u{0}{kind} {}", self.desc.textures.len());
        let (scale, offset) = if top_at_v0 {
            (glam::Vec2::new(1.0, -1.0), glam::Vec2::new(0.0, 1.0))
        } else {
            (glam::Vec2::ONE, glam::Vec2::ZERO)
        };
        let kind = TextureKind::Image {
            source: ImageSource::EmissionFile(self.resolve(dir_rel, file)),
            scale,
            offset,
            encoding: None,
            tint: Rgb::ONE,
            wrap: [crate::texture::WrapMode::Clamp; 2],
            filter: crate::texture::ImageFilter::Nearest,
        };
        let locs = Locs {
            item: Some(loc.clone()),
            keys: vec![("file".into(), file_loc)],
        };
        self.push_texture(&name, loc, locs, (kind, Rgb::ONE))?;
        Ok(name)
    }

    /// `LightSource "goniometric"` with an image: pbrt-v4's
    /// `GoniometricLight`, at the origin of the light's space (it reads no
    /// `from`), its square equal-area image's centre toward the light
    /// space's +y (pbrt-v4 swaps y and z).
    fn goniometric_light(
        &mut self,
        p: &ParamList,
        loc: &SourceLoc,
        locs: &mut Locs,
        dir_rel: &Path,
    ) -> Result<LightKind> {
        let (i, iloc) = self.emitted(p, "I")?;
        if let Some(l) = iloc {
            locs.keys.push(("intensity".into(), l));
        }
        let (scale, power) = scale_and_power(p)?;
        let (file, file_prm) = p.string("filename")?.expect("the caller checked");
        let file_loc = file_prm.loc.clone();
        let ctm = self.gs.ctm;
        let position = place(&ctm, Vec3::ZERO).ok_or_else(|| at_infinity(loc))?;
        let swap_yz = glam::Mat3::from_cols(Vec3::X, Vec3::Z, Vec3::Y);
        locs.keys.push(("image".into(), file_loc.clone()));
        let texture = self.light_image("goniometric", &file, file_loc, loc, dir_rel, false)?;
        Ok(LightKind::Goniometric {
            position,
            to_world: glam::Mat3::from_mat4(ctm) * swap_yz,
            intensity: i * scale,
            image: texture,
            power,
        })
    }

    /// `LightSource "projection"`: pbrt-v4's `ProjectionLight`, an image
    /// of radiant intensity projected from the origin of the light's space
    /// along its +z, the image's shorter side spanning `fov` (default 90°),
    /// read at the nearest pixel, its top toward the light's +y and its
    /// left toward −x.
    fn projection_light(
        &mut self,
        p: &ParamList,
        loc: &SourceLoc,
        locs: &mut Locs,
        dir_rel: &Path,
    ) -> Result<LightKind> {
        let Some((file, file_prm)) = p.string("filename")? else {
            return Err(Error::scene(
                Some(loc.clone()),
                "filename",
                "a projection light needs a \"string filename\" (its image)",
            ));
        };
        let file_loc = file_prm.loc.clone();
        let (scale, power) = scale_and_power(p)?;
        let fov = p.float("fov", 90.0)?;
        if !(fov > 0.0 && fov < 180.0) {
            return Err(p
                .find("fov")
                .expect("read")
                .err(format!("must lie between 0 and 180 degrees, got {fov}")));
        }
        add_key(locs, "fov", p.find("fov"));
        let ctm = self.gs.ctm;
        let position = place(&ctm, Vec3::ZERO).ok_or_else(|| at_infinity(loc))?;
        // trazo's projector frame has +x toward the image's left, pbrt-v4's
        // light space toward its right.
        let to_world = glam::Mat3::from_mat4(ctm) * glam::Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0));
        locs.keys.push(("irradiance".into(), file_loc.clone()));
        // The projector reads v = 0 at the image's top.
        let texture = self.light_image("projection", &file, file_loc, loc, dir_rel, true)?;
        Ok(LightKind::Projector {
            position,
            to_world,
            fov,
            fov_axis: FovAxis::Smaller,
            irradiance: ColorSource::Texture(texture),
            scale,
            law: crate::light::ProjectorLaw::RadiantIntensity,
            power,
        })
    }

    /// `LightSource "infinite"`: a constant colour or an environment image.
    fn infinite_light(&mut self, p: &ParamList, loc: &SourceLoc, dir_rel: &Path) -> Result<()> {
        let file = p.string("filename")?;
        if let (Some(_), Some(prm)) = (&file, p.find("L")) {
            return Err(prm.err("give either \"L\" or \"filename\" to an infinite light, not both"));
        }
        let mut scale = p.float("scale", 1.0)?;
        // A portal: four corners in world space (pbrt-v4 does not move
        // them by the CTM).
        if let Some((corners, prm)) = p.vec3s("portal", &["point3", "point"])? {
            let [a, b, c, d] = corners[..] else {
                return Err(prm.err(format!("a portal has 4 corners, got {}", corners.len())));
            };
            if !corners.iter().all(|v| v.is_finite()) {
                return Err(prm.err("the portal's corners must be finite"));
            }
            self.desc.portal = Some([a, b, c, d]);
            self.desc.world_locs.keys.push(("portal".into(), prm.loc.clone()));
        }
        let illuminance = p.float_opt("illuminance")?.map(|(e, _)| e).filter(|&e| e > 0.0);
        let (background, at) = match file {
            Some((name, prm)) => {
                let at = prm.loc.clone();
                // pbrt-v4 stores environment maps in its equal-area
                // octahedral layout, +z at the centre of the square in the
                // light's space (which the CTM places in the world).
                let to_world = self.environment_transform(loc)?;
                (
                    BackgroundDesc::Image {
                        path: self.resolve(dir_rel, &name),
                        scale,
                        transform: vec![TransformOp::Matrix(to_world)],
                        layout: EnvironmentLayout::EqualAreaOctahedral,
                        illuminance,
                    },
                    at,
                )
            }
            None => {
                let (c, lloc) = self.emitted(p, "L")?;
                if let Some(e) = illuminance {
                    // Illuminance of uniform radiance on an upward-facing
                    // patch is π·L.
                    scale *= e / PI;
                }
                (BackgroundDesc::Constant(c * scale), lloc.unwrap_or_else(|| loc.clone()))
            }
        };
        // pbrt-v4 takes any number of infinite lights; trazo sums them
        // into one environment (`EnvironmentMap::summed`).
        let previous = std::mem::replace(&mut self.desc.background, BackgroundDesc::Constant(Rgb::ZERO));
        self.desc.background = match (previous, background, self.infinite_light.is_some()) {
            (_, b, false) => b,
            (BackgroundDesc::Constant(a), BackgroundDesc::Constant(b), true) => BackgroundDesc::Constant(a + b),
            (BackgroundDesc::Sum(mut terms), b, true) => {
                terms.push(b);
                BackgroundDesc::Sum(terms)
            }
            (a, b, true) => BackgroundDesc::Sum(vec![a, b]),
        };
        if let BackgroundDesc::Sum(terms) = &self.desc.background {
            let images = terms
                .iter()
                .filter(|t| matches!(t, BackgroundDesc::Image { .. }))
                .count();
            if images > 1 && matches!(terms.last(), Some(BackgroundDesc::Image { .. })) {
                self.approximated(
                    loc,
                    "a second image infinite light",
                    "the maps are summed into the largest one, the others resampled at its pixels (exact for maps of one size and frame)",
                );
            }
        }
        self.infinite_light = Some(loc.clone());
        self.desc.world_locs.item = Some(loc.clone());
        self.desc.world_locs.keys.push(("background".into(), at));
        Ok(())
    }

    /// The map-to-world matrix of an environment image under the CTM.
    /// pbrt-v4 looks an infinite light up in the direction that the
    /// upper-left 3×3 part of the inverse of the CTM gives (`Le`:
    /// `renderFromLight.ApplyInverse(ray.d)`), normalised; for an affine
    /// CTM that is the inverse of the CTM's own 3×3 part, for a projective
    /// one (a bottom row other than 0 0 0 1: pbrt-v4-scenes' sssdragon) it
    /// need not be, and the affine matrix of its inverse is the one that
    /// looks the map up the same way.
    fn environment_transform(&mut self, loc: &SourceLoc) -> Result<Mat4> {
        let ctm = self.gs.ctm;
        if ctm.row(3) == Vec4::W || !ctm.is_finite() {
            return Ok(ctm);
        }
        let singular = || {
            Error::scene(
                Some(loc.clone()),
                "LightSource",
                "the current transform is singular, so the environment map has no orientation",
            )
        };
        let m = ctm.as_dmat4();
        if m.determinant() == 0.0 {
            return Err(singular());
        }
        let lookup = DMat3::from_mat4(m.inverse());
        if lookup.determinant() == 0.0 || !lookup.is_finite() {
            return Err(singular());
        }
        let linear = lookup.inverse();
        // pbrt-v4 samples the light through the CTM's own 3×3 part; where
        // that differs from the lookup's, its two strategies disagree.
        let own = DMat3::from_mat4(m);
        let scale = |a: &DMat3| a.x_axis.length() + a.y_axis.length() + a.z_axis.length();
        let (a, b) = (own * (1.0 / scale(&own)), linear * (1.0 / scale(&linear)));
        let differ = (a.x_axis - b.x_axis).length() + (a.y_axis - b.y_axis).length() + (a.z_axis - b.z_axis).length();
        if differ > 1e-4 {
            self.approximated(
                loc,
                "an environment map under a projective transform that also translates",
                "pbrt-v4 looks the map up through the inverse's 3×3 part but samples it through the matrix's own, which differ here; trazo uses the lookup's for both",
            );
        }
        Ok(super::affine(linear, DVec3::ZERO).as_mat4())
    }

    /// `AreaLightSource "diffuse"`: shapes that follow in the block emit.
    pub(super) fn area_light_source(&mut self, p: &ParamList, loc: &SourceLoc, dir_rel: &Path) -> Result<()> {
        let (l, _) = self.emitted(p, "L")?;
        let scale = p.float("scale", 1.0)?;
        let two_sided = p.bool("twosided", false)?;
        // pbrt-v4's image emission: L = scale × the image at the surface's
        // (u, v) (v = 0 at the image's bottom), clamped at its edges.
        let image = match p.string("filename")? {
            None => None,
            Some((file, prm)) => {
                if p.find("L").is_some() {
                    return Err(prm.err("give \"L\" or \"filename\", not both (as pbrt-v4 requires)"));
                }
                if !scale.is_finite() || scale < 0.0 {
                    return Err(Error::scene(
                        Some(loc.clone()),
                        "scale",
                        format!("must not be negative, got {scale}"),
                    ));
                }
                let name = format!("\u{0}area light image {}", self.desc.textures.len());
                let mut locs = Locs::at(Some(loc.clone()));
                locs.keys.push(("file".into(), prm.loc.clone()));
                let kind = TextureKind::Image {
                    source: ImageSource::EmissionFile(self.resolve(dir_rel, &file)),
                    scale: Vec2::ONE,
                    offset: Vec2::ZERO,
                    encoding: None,
                    tint: Rgb::splat(scale),
                    wrap: [crate::texture::WrapMode::Clamp; 2],
                    filter: crate::texture::ImageFilter::Bilinear,
                };
                self.push_texture(&name, loc, locs, (kind, Rgb::splat(0.5 * scale)))?;
                Some(name)
            }
        };
        // pbrt-v4 reads a power of 0 or less as none.
        let power = match p.float_opt("power")? {
            Some((w, prm)) if w > 0.0 && w.is_finite() => Some((w, prm.loc.clone())),
            _ => None,
        };
        let radiance = l * scale;
        if !radiance.is_finite() || radiance.min_element() < 0.0 {
            return Err(Error::scene(
                Some(loc.clone()),
                "L",
                format!(
                    "the emitted radiance must not be negative, got [{} {} {}]",
                    radiance.x, radiance.y, radiance.z
                ),
            ));
        }
        self.gs.area_light = Some(Emission {
            radiance,
            image,
            two_sided,
            power,
            loc: loc.clone(),
        });
        Ok(())
    }
}

/// A point moved by `m` as pbrt-v4 moves points: with the division by w
/// of a projective matrix. `None` if it goes to infinity.
fn place(m: &Mat4, p: Vec3) -> Option<Vec3> {
    let h = m.as_dmat4() * p.as_dvec3().extend(1.0);
    if h.w == 0.0 {
        return None;
    }
    Some((h.truncate() / h.w).as_vec3()).filter(|v| v.is_finite())
}

/// A light's `scale` (1; non-negative) and its `power` where positive
/// (pbrt-v4 reads 0 or less as none).
fn scale_and_power(p: &ParamList) -> Result<(f32, Option<f32>)> {
    let scale = p.float("scale", 1.0)?;
    if !(scale.is_finite() && scale >= 0.0) {
        return Err(p
            .find("scale")
            .expect("read")
            .err(format!("must be a non-negative number, got {scale}")));
    }
    let power = p.float_opt("power")?.map(|(w, _)| w).filter(|&w| w > 0.0);
    Ok((scale, power))
}

fn at_infinity(loc: &SourceLoc) -> Error {
    Error::scene(
        Some(loc.clone()),
        "LightSource",
        "the current transform is projective and puts the light at infinity (its w is 0)",
    )
}

/// The world direction of a spotlight's axis from `from` towards `to`
/// under the CTM `m`, and whether the cone keeps its angles. pbrt-v4 finds
/// a direction v's angle to the axis from the light-space direction that
/// the upper-left 3×3 part K of the inverse of m · Translate(from) gives
/// (`SpotLight::SampleLi`: `renderFromLight.ApplyInverse(-wi)`): the angle
/// between K·v and the written axis. The world axis is then K⁻¹ applied to
/// the written one; unless K is a rotation times a scale, the angles of the
/// world cone differ from the written ones (and it may be elliptical). For
/// an affine m, K is the inverse of m's 3×3 part.
fn spot_axis(m: &Mat4, from: Vec3, to: Vec3) -> Option<(Vec3, bool)> {
    let written = (to - from).as_dvec3().try_normalize()?;
    let inv = m.as_dmat4().inverse();
    if !inv.is_finite() || m.as_dmat4().determinant() == 0.0 {
        return None;
    }
    // The inverse of Translate(from) subtracts `from` times the bottom row
    // of m⁻¹ from its 3×3 part.
    let f = from.as_dvec3();
    let b = DMat3::from_mat4(inv);
    let k = DMat3::from_cols(
        b.x_axis - f * inv.x_axis.w,
        b.y_axis - f * inv.y_axis.w,
        b.z_axis - f * inv.z_axis.w,
    );
    if k.determinant() == 0.0 {
        return None;
    }
    let axis = (k.inverse() * written).try_normalize()?.as_vec3();
    // Kᵀ·K is a multiple of the identity for a rotation times a scale.
    let g = k.transpose() * k;
    let s2 = (g.x_axis.x + g.y_axis.y + g.z_axis.z) / 3.0;
    let off = (g - DMat3::from_diagonal(DVec3::splat(s2))).to_cols_array();
    let conformal = off.iter().all(|x| x.abs() <= 1e-4 * s2);
    Some((axis, conformal))
}

/// Records where the value of `key` was written.
fn add_key(locs: &mut Locs, key: &str, prm: Option<&super::params::Param>) {
    if let Some(prm) = prm {
        locs.keys.push((key.into(), prm.loc.clone()));
    }
}
