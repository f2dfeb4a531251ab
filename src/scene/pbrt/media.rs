//! pbrt-v4's participating media: `MakeNamedMedium` (`homogeneous`,
//! `uniformgrid`), `MediumInterface` and the camera's medium.
//!
//! pbrt gives σa and σs (both defaulting to 1, times `scale`); trazo's
//! media hold σt and the albedo, so σt = (σa + σs)·scale·density and the
//! albedo σs/(σa + σs). A `uniformgrid`'s density spans [p0, p1] in the
//! medium's space (the CTM at `MakeNamedMedium`) and fades to zero past its
//! outermost voxel centres, as pbrt-v4's `SampledGrid` reads it.

use super::Parser;
use super::materials::ColorUse;
use super::params::ParamList;
use crate::color::Rgb;
use crate::error::{Result, SourceLoc};
use crate::media::{GridEdge, VoxelGrid};
use crate::scene::desc::*;
use glam::{Mat4, Vec3};
use std::sync::Arc;

impl Parser {
    /// A colour parameter of a medium (unbounded), or `default`.
    fn medium_color(&mut self, p: &ParamList, name: &str, default: Rgb) -> Result<Rgb> {
        let Some((v, prm)) = p.spectrum(name)? else {
            return Ok(default);
        };
        let prm = prm.clone();
        Ok(match self.color_value(v, &prm, ColorUse::Unbounded)? {
            Some(ColorSource::Rgb(c)) => c,
            _ => {
                self.unsupported(
                    &prm.loc,
                    format!("\"{}\"", prm.written),
                    "a texture here is unsupported; using 1",
                );
                Rgb::ONE
            }
        })
    }

    /// `MakeNamedMedium "name" "string type" …`.
    pub(super) fn make_named_medium(&mut self, name: &str, p: &ParamList, loc: &SourceLoc) -> Result<()> {
        let what = format!("MakeNamedMedium \"{name}\"");
        let ty = match p.string("type")? {
            Some((t, _)) => t,
            None => {
                return Err(crate::error::Error::scene(
                    Some(loc.clone()),
                    what,
                    "needs a \"string type\"",
                ));
            }
        };
        if !matches!(ty.as_str(), "homogeneous" | "uniformgrid") {
            Self::use_all(p);
            self.unsupported(
                loc,
                format!("{what} of type \"{ty}\""),
                "the medium is not rendered: shapes it fills are empty (trazo reads \"homogeneous\" and \"uniformgrid\")",
            );
            self.unsupported_media.insert(name.to_string());
            return Ok(());
        }
        if let Some((preset, prm)) = p.string("preset")? {
            let l = prm.loc.clone();
            self.unsupported(
                &l,
                format!("\"string preset\" \"{preset}\""),
                "measured scattering presets are not built in; sigma_a and sigma_s are used",
            );
        }
        let sigma_a = self.medium_color(p, "sigma_a", Rgb::ONE)?;
        let sigma_s = self.medium_color(p, "sigma_s", Rgb::ONE)?;
        let scale = p.float("scale", 1.0)?;
        let g = match p.float_opt("g")? {
            Some((g, prm)) if !(g > -1.0 && g < 1.0) => {
                return Err(prm.err(format!("must lie strictly between -1 and 1, got {g}")));
            }
            Some((g, _)) => g,
            None => 0.0,
        };
        let le = self.medium_color(p, "Le", Rgb::ZERO)?;
        let le_scale = p.float("Lescale", 1.0)?;
        let sigma_t = sigma_a + sigma_s;
        let albedo = Rgb::select(sigma_t.cmpgt(Rgb::ZERO), sigma_s / sigma_t, Rgb::ZERO);
        let (sigma_t_field, scale) = if ty == "homogeneous" {
            (FieldDesc::Constant(sigma_t), Rgb::splat(scale))
        } else {
            let dim = |k: &str| -> Result<usize> {
                match p.int_opt(k)? {
                    Some((n, prm)) if !(1..=1 << 12).contains(&n) => {
                        Err(prm.err(format!("must be between 1 and 4096, got {n}")))
                    }
                    Some((n, _)) => Ok(n as usize),
                    None => Ok(1),
                }
            };
            let res = [dim("nx")?, dim("ny")?, dim("nz")?];
            let Some((density, prm)) = p.floats("density")? else {
                return Err(crate::error::Error::scene(
                    Some(loc.clone()),
                    what,
                    "a \"uniformgrid\" needs \"float density\"",
                ));
            };
            let mut grid = VoxelGrid::new(res, 1, density).map_err(|e| prm.err(e))?;
            grid.edge = GridEdge::Zero;
            for key in ["temperature", "temperaturecutoff", "temperaturescale", "Lescale"] {
                if let Some(prm) = p.find(key).filter(|_| key != "Lescale" || le != Rgb::ZERO) {
                    let l = prm.loc.clone();
                    let written = prm.written.clone();
                    self.unsupported(&l, format!("\"{written}\""), "a grid medium's emission is not rendered");
                }
            }
            let p0 = p.point3("p0", Vec3::ZERO)?;
            let p1 = p.point3("p1", Vec3::ONE)?;
            if !(p1 - p0).cmpgt(Vec3::ZERO).all() {
                return Err(crate::error::Error::scene(
                    Some(loc.clone()),
                    what,
                    format!("\"point3 p1\" {p1} must exceed \"point3 p0\" {p0} on every axis"),
                ));
            }
            let unit_to_world = self.gs.ctm * Mat4::from_translation(p0) * Mat4::from_scale(p1 - p0);
            (
                FieldDesc::Grid {
                    source: GridSource::Data(Arc::new(grid)),
                    to_world: vec![TransformOp::Matrix(unit_to_world)],
                    use_file_bounds: false,
                },
                sigma_t * scale,
            )
        };
        let emission = (ty == "homogeneous" && le != Rgb::ZERO).then(|| FieldDesc::Constant(le * le_scale));
        if ty == "uniformgrid" && le != Rgb::ZERO {
            self.unsupported(
                loc,
                format!("\"Le\" of {what}"),
                "a grid medium's emission is not rendered",
            );
        }
        Self::use_all(p);
        let desc_name = format!("medium:{name}");
        self.desc.media.retain(|m| m.name != desc_name);
        self.desc.media.push(MediumDesc {
            name: desc_name.clone(),
            sigma_t: sigma_t_field,
            albedo: FieldDesc::Constant(albedo),
            emission,
            scale,
            g,
            locs: Locs::at(Some(loc.clone())),
        });
        self.unsupported_media.remove(name);
        self.media_names.insert(name.to_string(), desc_name);
        Ok(())
    }

    /// A medium name of `MediumInterface` as a description's name (`None`:
    /// vacuum, or a medium trazo does not render).
    pub(super) fn medium_name(&mut self, name: &str, loc: &SourceLoc) -> Result<Option<String>> {
        if name.is_empty() || self.unsupported_media.contains(name) {
            return Ok(None);
        }
        match self.media_names.get(name) {
            Some(n) => Ok(Some(n.clone())),
            None => Err(crate::error::Error::scene(
                Some(loc.clone()),
                "MediumInterface",
                format!("no medium named \"{name}\" (define it with MakeNamedMedium first)"),
            )),
        }
    }

    /// The medium interface shapes now get: `None` where the two sides are
    /// the same medium (not a transition; the ray keeps its medium).
    pub(super) fn current_media(&self) -> Option<MediumInterfaceDesc> {
        let (inside, outside) = &self.gs.media;
        (inside != outside).then(|| MediumInterfaceDesc {
            inside: inside.clone(),
            outside: outside.clone(),
        })
    }
}
