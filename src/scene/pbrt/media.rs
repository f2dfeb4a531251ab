//! pbrt-v4's participating media: `MakeNamedMedium` (`homogeneous`,
//! `uniformgrid`, `rgbgrid`, `cloud`), `MediumInterface` and the camera's
//! medium.
//!
//! pbrt gives σa and σs (both defaulting to 1, times `scale`); trazo's
//! media hold σt and the albedo, so σt = (σa + σs)·scale·density and the
//! albedo σs/(σa + σs). A `uniformgrid`'s density spans [p0, p1] in the
//! medium's space (the CTM at `MakeNamedMedium`) and fades to zero past its
//! outermost voxel centres, as pbrt-v4's `SampledGrid` reads it. An
//! `rgbgrid` gives σa, σs and Le per voxel (RGB): trazo's grids of σt and
//! of the albedo follow from them voxel by voxel, and its emission grid is
//! Le (the source term σa·Le, as pbrt's). pbrt interpolates σa and σs and
//! divides; trazo interpolates σt and the albedo: the same where a voxel's
//! neighbours share their albedo (an empty voxel takes the grid's mean
//! albedo).

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
    pub(super) fn medium_color(&mut self, p: &ParamList, name: &str, default: Rgb) -> Result<Rgb> {
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
    pub(super) fn make_named_medium(
        &mut self,
        name: &str,
        p: &ParamList,
        loc: &SourceLoc,
        dir_rel: &std::path::Path,
    ) -> Result<()> {
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
        if ty == "rgbgrid" {
            return self.rgb_grid_medium(name, p, loc);
        }
        if ty == "cloud" {
            return self.cloud_medium(name, p, loc);
        }
        if ty == "nanovdb" {
            return self.nanovdb_medium(name, p, loc, dir_rel);
        }
        if !matches!(ty.as_str(), "homogeneous" | "uniformgrid") {
            Self::use_all(p);
            self.unsupported(
                loc,
                format!("{what} of type \"{ty}\""),
                "the medium is not rendered: shapes it fills are empty (trazo reads \"homogeneous\", \"uniformgrid\", \"rgbgrid\", \"cloud\" and \"nanovdb\")",
            );
            self.unsupported_media.insert(name.to_string());
            return Ok(());
        }
        // pbrt-v4's homogeneous medium takes a measured medium's
        // coefficients over sigma_a and sigma_s (mm⁻¹, times scale).
        let mut preset = None;
        if let Some((name, prm)) = p.string("preset")? {
            let l = prm.loc.clone();
            if ty != "homogeneous" {
                self.unsupported(
                    &l,
                    format!("\"string preset\" of a \"{ty}\" medium"),
                    "pbrt-v4 reads presets for homogeneous media only; sigma_a and sigma_s are used",
                );
            } else {
                preset = crate::media::measured::measured_medium(&name);
                if preset.is_none() {
                    // pbrt-v4 warns and goes on.
                    self.unsupported(
                        &l,
                        format!("medium preset \"{name}\""),
                        format!(
                            "no measured medium has that name{}; sigma_a and sigma_s are used",
                            suggest(&name, crate::media::measured::measured_medium_names())
                        ),
                    );
                }
            }
        }
        // With a preset, sigma_a and sigma_s are not read (pbrt-v4 then
        // reports them unused too).
        let (sigma_a, sigma_s) = match preset {
            Some(coefficients) => coefficients,
            None => (
                self.medium_color(p, "sigma_a", Rgb::ONE)?,
                self.medium_color(p, "sigma_s", Rgb::ONE)?,
            ),
        };
        let scale = p.float("scale", 1.0)?;
        let g = Self::phase_g(p)?;
        let le = self.medium_color(p, "Le", Rgb::ZERO)?;
        // A homogeneous medium's `Lescale` is one number, a grid's a grid.
        let le_scale = if ty == "homogeneous" {
            p.float("Lescale", 1.0)?
        } else {
            1.0
        };
        let mut grid_emission = None;
        let sigma_t = sigma_a + sigma_s;
        let albedo = Rgb::select(sigma_t.cmpgt(Rgb::ZERO), sigma_s / sigma_t, Rgb::ZERO);
        let (sigma_t_field, scale) = if ty == "homogeneous" {
            (FieldDesc::Constant(sigma_t), Rgb::splat(scale))
        } else {
            let res = [
                self.grid_dim(p, "nx")?,
                self.grid_dim(p, "ny")?,
                self.grid_dim(p, "nz")?,
            ];
            let Some((density, prm)) = p.floats("density")? else {
                return Err(crate::error::Error::scene(
                    Some(loc.clone()),
                    what,
                    "a \"uniformgrid\" needs \"float density\"",
                ));
            };
            let mut grid = VoxelGrid::new(res, 1, density).map_err(|e| prm.err(e))?;
            grid.edge = GridEdge::Zero;
            let unit_to_world = self.grid_box(p, loc, &what)?;
            grid_emission = self.uniform_grid_emission(p, loc, &what, res, le, &unit_to_world)?;
            (
                FieldDesc::Grid {
                    source: GridSource::Data(Arc::new(grid)),
                    to_world: vec![TransformOp::Matrix(unit_to_world)],
                    use_file_bounds: false,
                },
                sigma_t * scale,
            )
        };
        let emission = if ty == "homogeneous" {
            (le != Rgb::ZERO).then(|| FieldDesc::Constant(le * le_scale))
        } else {
            grid_emission
        };
        Self::use_all(p);
        let medium = MediumDesc {
            name: format!("medium:{name}"),
            sigma_t: sigma_t_field,
            albedo: FieldDesc::Constant(albedo),
            emission,
            scale,
            g,
            locs: Locs::at(Some(loc.clone())),
        };
        self.add_medium(name, medium);
        Ok(())
    }

    /// `MakeNamedMedium "name" "string type" "cloud"`: pbrt-v4's procedural
    /// cloud (`CloudMedium`), σa and σs (each 1 where not given) times its
    /// density in the box [`p0`, `p1`] of the medium's space; pbrt-v4 reads
    /// no `scale` here.
    fn cloud_medium(&mut self, name: &str, p: &ParamList, loc: &SourceLoc) -> Result<()> {
        let sigma_a = self.medium_color(p, "sigma_a", Rgb::ONE)?;
        let sigma_s = self.medium_color(p, "sigma_s", Rgb::ONE)?;
        let g = Self::phase_g(p)?;
        let number = |key: &str, default: f32| -> Result<f32> {
            match p.float_opt(key)? {
                Some((x, prm)) if !x.is_finite() => Err(prm.err(format!("must be a finite number, got {x}"))),
                Some((x, _)) => Ok(x),
                None => Ok(default),
            }
        };
        let (density, wispiness, frequency) = (
            number("density", 1.0)?,
            number("wispiness", 1.0)?,
            number("frequency", 5.0)?,
        );
        // pbrt-v4's Bounds3f(p0, p1) takes the corners in either order.
        let (a, b) = (p.point3("p0", Vec3::ZERO)?, p.point3("p1", Vec3::ONE)?);
        let sigma_t = sigma_a + sigma_s;
        let albedo = Rgb::select(sigma_t.cmpgt(Rgb::ZERO), sigma_s / sigma_t, Rgb::ZERO);
        Self::use_all(p);
        let medium = MediumDesc {
            name: format!("medium:{name}"),
            sigma_t: FieldDesc::Cloud {
                value: sigma_t,
                density,
                wispiness,
                frequency,
                p0: a.min(b),
                p1: a.max(b),
                to_world: vec![TransformOp::Matrix(self.gs.ctm)],
            },
            albedo: FieldDesc::Constant(albedo),
            emission: None,
            scale: Rgb::ONE,
            g,
            locs: Locs::at(Some(loc.clone())),
        };
        self.add_medium(name, medium);
        Ok(())
    }

    /// `MakeNamedMedium "name" "string type" "nanovdb"`: pbrt-v4's
    /// `NanoVDBMedium`, σa and σs (each 1 where not given) times `scale`
    /// times the density grid (`gridname`, "density") of the NanoVDB file
    /// `filename`, inside the grid's world box; and, where the file has a
    /// temperature grid (`temperaturename`, "temperature"), the blackbody
    /// emission Le = `Lescale` × B((T − `temperatureoffset`) ·
    /// `temperaturescale`), none at 100 K or below. Both grids are placed
    /// by their own index-to-world maps and then the CTM.
    fn nanovdb_medium(&mut self, name: &str, p: &ParamList, loc: &SourceLoc, dir_rel: &std::path::Path) -> Result<()> {
        use crate::media::nanovdb::NanoVdbGrid;
        let what = format!("MakeNamedMedium \"{name}\"");
        let Some((file, fprm)) = p.string("filename")? else {
            return Err(crate::error::Error::scene(
                Some(loc.clone()),
                what,
                "a \"nanovdb\" medium needs a \"string filename\"",
            ));
        };
        let floc = fprm.loc.clone();
        let fail = |reason: String| crate::error::Error::scene(Some(floc.clone()), "string filename", reason);
        let path = self.top_dir.join(self.resolve(dir_rel, &file));
        let bytes = crate::files::read_limited(&path, crate::files::MAX_NANOVDB_BYTES)
            .map_err(|e| fail(format!("cannot read {}: {e}", path.display())))?;
        let in_file = |e: String| fail(format!("{}: {e}", path.display()));
        let grid_name = p.string("gridname")?.map_or_else(|| "density".to_string(), |g| g.0);
        let temperature_name = p
            .string("temperaturename")?
            .map_or_else(|| "temperature".to_string(), |g| g.0);
        let density = crate::scene::build::nanovdb_grid(&bytes, &grid_name).map_err(in_file)?;
        if !matches!(density.class, 0 | crate::media::nanovdb::CLASS_FOG_VOLUME) {
            return Err(in_file(format!(
                "grid \"{grid_name}\" is not a fog volume (its class is {}), as pbrt-v4 requires of a medium's density",
                density.class
            )));
        }
        let temperature = NanoVdbGrid::from_file(&bytes, &temperature_name).map_err(in_file)?;
        drop(bytes);
        let ctm = TransformOp::Matrix(self.gs.ctm);
        let Some((density, unit_to_grid)) = density.to_voxel_grid().map_err(in_file)? else {
            // Nothing active: an empty medium, as pbrt-v4's empty box.
            self.unsupported(
                &floc,
                format!("grid \"{grid_name}\" of {}", path.display()),
                "it has no active voxels: the medium is empty",
            );
            self.unsupported_media.insert(name.to_string());
            Self::use_all(p);
            return Ok(());
        };
        let sigma_a = self.medium_color(p, "sigma_a", Rgb::ONE)?;
        let sigma_s = self.medium_color(p, "sigma_s", Rgb::ONE)?;
        let scale = p.float("scale", 1.0)?;
        let le_scale = p.float("Lescale", 1.0)?;
        let offset = match p.float_opt("temperatureoffset")? {
            Some((v, _)) => v,
            None => p.float("temperaturecutoff", 0.0)?,
        };
        let t_scale = p.float("temperaturescale", 1.0)?;
        let g = Self::phase_g(p)?;
        let emission = match temperature {
            Some(t) if le_scale > 0.0 => match t.to_voxel_grid().map_err(in_file)? {
                Some((t_grid, t_unit_to_grid)) => {
                    // Three channels a voxel: bounded as a grid file's values are.
                    if t_grid.data.len() as u64 * 3 > crate::media::grid::MAX_VOXELS {
                        return Err(in_file(format!(
                            "grid \"{temperature_name}\" spans {} voxels, more than the {} colours trazo keeps",
                            t_grid.data.len(),
                            crate::media::grid::MAX_VOXELS / 3
                        )));
                    }
                    self.approximated(
                        &floc,
                        format!("grid \"{temperature_name}\" of {}", path.display()),
                        "the blackbody colour is interpolated between voxels, where pbrt-v4 interpolates the temperature",
                    );
                    let colors: Vec<f32> = t_grid
                        .data
                        .iter()
                        .flat_map(|&kelvin| {
                            let kelvin = (kelvin - offset) * t_scale;
                            let c = if kelvin > 100.0 {
                                super::spectrum::peak_normalized_blackbody_rgb(kelvin) * le_scale
                            } else {
                                Rgb::ZERO
                            };
                            c.to_array()
                        })
                        .collect();
                    let mut grid = VoxelGrid::new(t_grid.res, 3, colors).map_err(in_file)?;
                    (grid.edge, grid.support) = (t_grid.edge, t_grid.support);
                    Some(FieldDesc::Grid {
                        source: GridSource::Data(Arc::new(grid)),
                        to_world: vec![TransformOp::Matrix(t_unit_to_grid), ctm],
                        use_file_bounds: false,
                    })
                }
                None => None,
            },
            _ => None,
        };
        let sigma_t = sigma_a + sigma_s;
        let albedo = Rgb::select(sigma_t.cmpgt(Rgb::ZERO), sigma_s / sigma_t, Rgb::ZERO);
        Self::use_all(p);
        let medium = MediumDesc {
            name: format!("medium:{name}"),
            sigma_t: FieldDesc::Grid {
                source: GridSource::Data(Arc::new(density)),
                to_world: vec![TransformOp::Matrix(unit_to_grid), ctm],
                use_file_bounds: false,
            },
            albedo: FieldDesc::Constant(albedo),
            emission,
            scale: sigma_t * scale,
            g,
            locs: Locs::at(Some(loc.clone())),
        };
        self.add_medium(name, medium);
        Ok(())
    }

    /// `MakeNamedMedium "name" "string type" "rgbgrid"`: RGB grids of
    /// `sigma_a`, `sigma_s` (each 1 where not given) and `Le`, `nx`×`ny`×`nz`
    /// voxels over [`p0`, `p1`], times `scale` and `Lescale`.
    fn rgb_grid_medium(&mut self, name: &str, p: &ParamList, loc: &SourceLoc) -> Result<()> {
        let what = format!("MakeNamedMedium \"{name}\"");
        let res = [
            self.grid_dim(p, "nx")?,
            self.grid_dim(p, "ny")?,
            self.grid_dim(p, "nz")?,
        ];
        let voxels = res[0] * res[1] * res[2];
        let grid_of = |key: &str| -> Result<Option<Vec<Vec3>>> {
            match p.vec3s(key, &["rgb"])? {
                Some((v, prm)) if v.len() != voxels || prm.nums().len() != 3 * voxels => Err(prm.err(format!(
                    "a {}×{}×{} grid needs {voxels} RGB values ({} numbers), got {} numbers",
                    res[0],
                    res[1],
                    res[2],
                    3 * voxels,
                    prm.nums().len()
                ))),
                Some((v, _)) => Ok(Some(v)),
                None => Ok(None),
            }
        };
        let (mut sigma_a, mut sigma_s, mut le) = (grid_of("sigma_a")?, grid_of("sigma_s")?, grid_of("Le")?);
        // Voxels written in another colour space, as `Parser::rgb_in_space`
        // converts single colours.
        let space = self.gs.color_space;
        let mut clipped = false;
        for (grid, emitted) in [(&mut sigma_a, false), (&mut sigma_s, false), (&mut le, true)] {
            let (Some(grid), false) = (grid.as_mut(), space == crate::color::space::ColorSpace::Srgb) else {
                continue;
            };
            let m = space.to_srgb(emitted);
            for v in grid.iter_mut() {
                let c = m * *v;
                clipped |= c.min_element() < 0.0;
                *v = c.max(Vec3::ZERO);
            }
        }
        if clipped {
            self.approximated(
                loc,
                format!("{what}: {} colours", space.pbrt_name()),
                "some are outside the sRGB gamut, which trazo renders in: their negative components are clipped to 0",
            );
        }
        let mut sigma_t = Vec::with_capacity(3 * voxels);
        let (mut sum_s, mut sum_t) = (Vec3::ZERO, Vec3::ZERO);
        for i in 0..voxels {
            let a = sigma_a.as_ref().map_or(Vec3::ONE, |g| g[i]);
            let s = sigma_s.as_ref().map_or(Vec3::ONE, |g| g[i]);
            if !(a.is_finite() && s.is_finite() && a.cmpge(Vec3::ZERO).all() && s.cmpge(Vec3::ZERO).all()) {
                return Err(crate::error::Error::scene(
                    Some(loc.clone()),
                    what,
                    format!("voxel {i}: sigma_a {a} and sigma_s {s} must be finite and non-negative"),
                ));
            }
            sigma_t.extend((a + s).to_array());
            (sum_s, sum_t) = (sum_s + s, sum_t + a + s);
        }
        // An empty voxel's albedo is that of the whole grid, so that
        // interpolating toward it does not darken its neighbours (their σs
        // fades with σt, as pbrt's interpolated σs does).
        let ratio = |s: Vec3, t: Vec3| Vec3::select(t.cmpgt(Vec3::ZERO), s / t, Vec3::ZERO);
        let mean_albedo = ratio(sum_s, sum_t);
        let albedo: Vec<f32> = (0..voxels)
            .flat_map(|i| {
                let t = Vec3::from_slice(&sigma_t[3 * i..3 * i + 3]);
                let s = sigma_s.as_ref().map_or(Vec3::ONE, |g| g[i]);
                Vec3::select(t.cmpgt(Vec3::ZERO), ratio(s, t), mean_albedo).to_array()
            })
            .collect();
        let scale = p.float("scale", 1.0)?;
        let le_scale = p.float("Lescale", 1.0)?;
        let g = Self::phase_g(p)?;
        let to_world = vec![TransformOp::Matrix(self.grid_box(p, loc, &what)?)];
        // σt and Le fade to zero past the outermost voxel centres, as pbrt's
        // grids do; the albedo keeps its edge values (σs fades with σt).
        let field = |data: Vec<f32>, edge: GridEdge| -> Result<FieldDesc> {
            let mut grid = VoxelGrid::new(res, 3, data)
                .map_err(|e| crate::error::Error::scene(Some(loc.clone()), what.clone(), e))?;
            grid.edge = edge;
            Ok(FieldDesc::Grid {
                source: GridSource::Data(Arc::new(grid)),
                to_world: to_world.clone(),
                use_file_bounds: false,
            })
        };
        let emission = match le {
            Some(le) if le.iter().any(|c| *c != Vec3::ZERO) => {
                if le.iter().any(|c| !(c.is_finite() && c.cmpge(Vec3::ZERO).all())) {
                    return Err(crate::error::Error::scene(
                        Some(loc.clone()),
                        what,
                        "\"rgb Le\" must be finite and non-negative",
                    ));
                }
                Some(field(
                    le.iter().flat_map(|c| (*c * le_scale).to_array()).collect(),
                    GridEdge::Zero,
                )?)
            }
            _ => None,
        };
        let medium = MediumDesc {
            name: format!("medium:{name}"),
            sigma_t: field(sigma_t, GridEdge::Zero)?,
            albedo: field(albedo, GridEdge::Clamp)?,
            emission,
            scale: Rgb::splat(scale),
            g,
            locs: Locs::at(Some(loc.clone())),
        };
        Self::use_all(p);
        self.add_medium(name, medium);
        Ok(())
    }

    /// The emission of a `uniformgrid` (pbrt-v4's `GridMedium`), Le(p) =
    /// Lescale(p) × (the spectrum `Le`, or the blackbody of `temperature`(p)
    /// offset by `temperatureoffset` and scaled by `temperaturescale`,
    /// none at 100 K or below), with the source term σa·Le. Without
    /// `Lescale` pbrt-v4 reads a grid of one voxel of 1, which fades toward
    /// the box's edges as every grid does past its outermost voxel centres;
    /// so does this. pbrt-v4 interpolates the temperature and Lescale; trazo
    /// interpolates the colour they give voxel by voxel (approximated, with
    /// a warning, where a temperature grid is given).
    fn uniform_grid_emission(
        &mut self,
        p: &ParamList,
        loc: &SourceLoc,
        what: &str,
        res: [usize; 3],
        le: Rgb,
        unit_to_world: &glam::Mat4,
    ) -> Result<Option<FieldDesc>> {
        let voxels = res[0] * res[1] * res[2];
        let grid_values = |key: &str| -> Result<Option<Vec<f32>>> {
            match p.floats(key)? {
                Some((v, prm)) if v.len() != voxels => Err(prm.err(format!(
                    "a {}×{}×{} grid needs {voxels} values, got {}",
                    res[0],
                    res[1],
                    res[2],
                    v.len()
                ))),
                Some((v, prm)) if v.iter().any(|x| !x.is_finite()) => Err(prm.err("must be finite")),
                Some((v, _)) => Ok(Some(v)),
                None => Ok(None),
            }
        };
        let le_scale = grid_values("Lescale")?;
        let temperature = grid_values("temperature")?;
        if temperature.is_some() && le != Rgb::ZERO {
            return Err(crate::error::Error::scene(
                Some(loc.clone()),
                what,
                "give either \"Le\" or \"temperature\" to a grid medium, not both (as pbrt-v4)",
            ));
        }
        let offset = match p.float_opt("temperatureoffset")? {
            Some((v, _)) => v,
            None => p.float("temperaturecutoff", 0.0)?,
        };
        let t_scale = p.float("temperaturescale", 1.0)?;
        let (values, res) = match (temperature, le_scale) {
            (None, _) if le == Rgb::ZERO => return Ok(None),
            (None, None) => (le.to_array().to_vec(), [1, 1, 1]),
            (None, Some(s)) => (s.iter().flat_map(|&k| (le * k.max(0.0)).to_array()).collect(), res),
            (Some(t), s) => {
                self.approximated(
                    loc,
                    format!("\"temperature\" of {what}"),
                    "the blackbody colour is interpolated between voxels, where pbrt-v4 interpolates the temperature",
                );
                // Lescale at the voxel centres: its grid, or pbrt-v4's
                // single voxel of 1, a tent over the box.
                let tent = |i: usize, n: usize| 1.0 - ((i as f32 + 0.5) / n as f32 - 0.5).abs();
                let scale_at = |i: usize| match &s {
                    Some(s) => s[i].max(0.0),
                    None => {
                        let (x, y, z) = (i % res[0], (i / res[0]) % res[1], i / (res[0] * res[1]));
                        tent(x, res[0]) * tent(y, res[1]) * tent(z, res[2])
                    }
                };
                let values = (0..voxels)
                    .flat_map(|i| {
                        let kelvin = (t[i] - offset) * t_scale;
                        let c = if kelvin > 100.0 {
                            super::spectrum::peak_normalized_blackbody_rgb(kelvin) * scale_at(i)
                        } else {
                            Rgb::ZERO
                        };
                        c.to_array()
                    })
                    .collect();
                (values, res)
            }
        };
        let mut grid =
            VoxelGrid::new(res, 3, values).map_err(|e| crate::error::Error::scene(Some(loc.clone()), what, e))?;
        grid.edge = GridEdge::Zero;
        Ok(Some(FieldDesc::Grid {
            source: GridSource::Data(Arc::new(grid)),
            to_world: vec![TransformOp::Matrix(*unit_to_world)],
            use_file_bounds: false,
        }))
    }

    /// A grid's voxel count along one axis (`nx`, `ny`, `nz`; 1 if not
    /// given).
    fn grid_dim(&self, p: &ParamList, key: &str) -> Result<usize> {
        match p.int_opt(key)? {
            Some((n, prm)) if !(1..=1 << 12).contains(&n) => {
                Err(prm.err(format!("must be between 1 and 4096, got {n}")))
            }
            Some((n, _)) => Ok(n as usize),
            None => Ok(1),
        }
    }

    /// The Henyey–Greenstein `g` (0 if not given), strictly inside (−1, 1).
    fn phase_g(p: &ParamList) -> Result<f32> {
        match p.float_opt("g")? {
            Some((g, prm)) if !(g > -1.0 && g < 1.0) => {
                Err(prm.err(format!("must lie strictly between -1 and 1, got {g}")))
            }
            Some((g, _)) => Ok(g),
            None => Ok(0.0),
        }
    }

    /// A grid medium's box [`p0`, `p1`] in the medium's space (the current
    /// transform): the map from the unit cube to the world.
    fn grid_box(&self, p: &ParamList, loc: &SourceLoc, what: &str) -> Result<Mat4> {
        let p0 = p.point3("p0", Vec3::ZERO)?;
        let p1 = p.point3("p1", Vec3::ONE)?;
        if !(p1 - p0).cmpgt(Vec3::ZERO).all() {
            return Err(crate::error::Error::scene(
                Some(loc.clone()),
                what,
                format!("\"point3 p1\" {p1} must exceed \"point3 p0\" {p0} on every axis"),
            ));
        }
        Ok(self.gs.ctm * Mat4::from_translation(p0) * Mat4::from_scale(p1 - p0))
    }

    /// Defines medium `name` (replacing one of that name).
    fn add_medium(&mut self, name: &str, medium: MediumDesc) {
        let desc_name = medium.name.clone();
        self.desc.media.retain(|m| m.name != desc_name);
        self.desc.media.push(medium);
        self.unsupported_media.remove(name);
        self.media_names.insert(name.to_string(), desc_name);
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
