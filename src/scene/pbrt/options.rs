//! The rendering options before `WorldBegin` (pbrt-v4 film.cpp,
//! samplers.cpp, integrators.cpp, filters.cpp, cameras.cpp): `Film`,
//! `Sampler`, `Integrator`, `PixelFilter`, and the `Camera`, which is
//! converted at `WorldBegin` when the film's size is known.

use super::params::ParamList;
use super::{Parser, world_from_camera};
use crate::camera::SphericalMapping;
use crate::error::{Error, Result, SourceLoc};
use crate::sampling::SamplerKind;
use crate::scene::desc::*;
use crate::settings::{
    Crop, Filter, GBufferSpace, IntegratorKind, MAX_DEPTH, MAX_IMAGE_SIDE, MAX_PHOTONS, MAX_SPP, PathSampling,
    SamplerStudy, TestFunction,
};

impl Parser {
    pub(super) fn film(&mut self, kind: &str, p: &ParamList, loc: &SourceLoc) -> Result<()> {
        for (key, param, default) in [("width", "xresolution", 1280), ("height", "yresolution", 720)] {
            let v = match p.int_opt(param)? {
                Some((v, prm)) => {
                    if v < 1 || v > MAX_IMAGE_SIDE as i64 {
                        return Err(prm.err(format!("must be between 1 and {MAX_IMAGE_SIDE} pixels, got {v}")));
                    }
                    self.desc.settings_locs.keys.push((key.into(), prm.loc.clone()));
                    v as u32
                }
                None => default,
            };
            if key == "width" {
                self.desc.settings.width = v;
            } else {
                self.desc.settings.height = v;
            }
        }
        if kind == "spectral" {
            self.approximated(
                loc,
                format!("Film \"{kind}\""),
                "rendered as an RGB film, without its spectral channels",
            );
        }
        if kind == "gbuffer" {
            // pbrt-v4's GBufferFilm: the image with what the camera sees
            // first, in camera coordinates unless asked otherwise.
            let space = match p.string("coordinatesystem")? {
                None => GBufferSpace::Camera,
                Some((name, prm)) => match name.as_str() {
                    "camera" => GBufferSpace::Camera,
                    "world" => GBufferSpace::World,
                    _ => {
                        return Err(prm.err(format!(
                            "unknown coordinate system \"{name}\" for a G-buffer: expected \"camera\" or \"world\""
                        )));
                    }
                },
            };
            self.desc.settings.gbuffer = Some(space);
            self.desc.settings_locs.keys.push(("gbuffer".into(), loc.clone()));
        } else {
            self.desc.settings.gbuffer = None;
        }
        // The image's file, which `trazo render` writes where no `-o` names
        // another (pbrt-v4's `--outfile`); pbrt-v4's default, "pbrt.exr",
        // is left to trazo's (the scene's name).
        if let Some((f, prm)) = p.string("filename")? {
            if !f.is_empty() {
                self.desc.settings_locs.keys.push(("output".into(), prm.loc.clone()));
                self.desc.output = Some(std::path::PathBuf::from(f));
            }
        }
        if let Some((m, prm)) = p.float_opt("maxcomponentvalue")? {
            self.desc
                .settings_locs
                .keys
                .push(("max_component_value".into(), prm.loc.clone()));
            self.desc.settings.max_component_value = m;
        }
        if let Some((d, prm)) = p.float_opt("diagonal")? {
            if !(d > 0.0 && d.is_finite()) {
                return Err(prm.err(format!("must be positive, got {d}")));
            }
            self.film_diagonal_mm = d;
        }
        if let Some((iso, prm)) = p.float_opt("iso")? {
            if iso <= 0.0 {
                return Err(prm.err(format!("must be positive, got {iso}")));
            }
            self.film_iso = iso;
        }
        if let Some((s, prm)) = p.string("sensor")? {
            if s != "cie1931" {
                let l = prm.loc.clone();
                self.approximated(
                    &l,
                    format!("sensor \"{s}\""),
                    "the CIE 1931 observer (plain sRGB) is used",
                );
            }
        }
        if let Some((wb, prm)) = p.float_opt("whitebalance")? {
            self.desc
                .settings_locs
                .keys
                .push(("white_balance".into(), prm.loc.clone()));
            self.desc.settings.white_balance = wb;
        }
        self.crop_window(p)
    }

    /// The film's `pixelbounds` (pixels x0 x1 y0 y1) or `cropwindow`
    /// (fractions of the image, x0 x1 y0 y1, their pixels rounded up), as
    /// pbrt-v4's `FilmBaseParameters` reads them: the image rendered is
    /// that window of the full resolution.
    fn crop_window(&mut self, p: &ParamList) -> Result<()> {
        let (full_w, full_h) = (self.desc.settings.width, self.desc.settings.height);
        let bounds = if let Some((b, prm)) = p.ints("pixelbounds")? {
            let [x0, x1, y0, y1] = b[..] else {
                return Err(prm.err(format!("needs 4 values (x0 x1 y0 y1), got {}", b.len())));
            };
            // Clamped to the image, as pbrt-v4 does (with a warning).
            let clamp = |v: i64, n: u32| v.clamp(0, n as i64) as u32;
            let b = (
                clamp(x0, full_w),
                clamp(x1, full_w),
                clamp(y0, full_h),
                clamp(y1, full_h),
            );
            if (b.0 as i64, b.1 as i64, b.2 as i64, b.3 as i64) != (x0, x1, y0, y1) {
                let l = prm.loc.clone();
                self.approximated(&l, "\"integer pixelbounds\" beyond the image", "clamped to the image");
            }
            if let Some((_, c)) = p.floats("cropwindow")? {
                let l = c.loc.clone();
                self.unsupported(
                    &l,
                    "\"float cropwindow\" with \"pixelbounds\"",
                    "pixelbounds is used, as in pbrt-v4",
                );
            }
            Some((b, prm.loc.clone()))
        } else if let Some((c, prm)) = p.floats("cropwindow")? {
            let [a, b, c0, c1] = c[..] else {
                return Err(prm.err(format!("needs 4 values (x0 x1 y0 y1), got {}", c.len())));
            };
            if [a, b, c0, c1].iter().any(|v| !v.is_finite()) {
                return Err(prm.err("values must be finite numbers"));
            }
            let frac = |v: f32| v.clamp(0.0, 1.0);
            let px = |f: f32, n: u32| (n as f64 * frac(f) as f64).ceil() as u32;
            Some((
                (
                    px(a.min(b), full_w),
                    px(a.max(b), full_w),
                    px(c0.min(c1), full_h),
                    px(c0.max(c1), full_h),
                ),
                prm.loc.clone(),
            ))
        } else {
            None
        };
        let Some(((x0, x1, y0, y1), loc)) = bounds else {
            return Ok(());
        };
        if x1 <= x0 || y1 <= y0 {
            return Err(Error::scene(
                Some(loc),
                "Film",
                format!("the crop window is empty: pixels x {x0}..{x1}, y {y0}..{y1}"),
            ));
        }
        if (x0, x1, y0, y1) == (0, full_w, 0, full_h) {
            return Ok(());
        }
        let s = &mut self.desc.settings;
        s.crop = Some(Crop {
            full_width: full_w,
            full_height: full_h,
            x: x0,
            y: y0,
        });
        (s.width, s.height) = (x1 - x0, y1 - y0);
        Ok(())
    }

    pub(super) fn sampler(&mut self, kind: &str, p: &ParamList, loc: &SourceLoc) -> Result<()> {
        self.sobol_sampler = kind == "sobol";
        let s = &mut self.desc.settings;
        (s.strata, s.jitter) = (None, true);
        match kind {
            "stratified" => {
                // pbrt-v4: xsamples × ysamples strata (default 4 × 4).
                let x = p.int_opt("xsamples")?;
                let y = p.int_opt("ysamples")?;
                let nx = x.as_ref().map_or(4, |(v, _)| *v);
                let ny = y.as_ref().map_or(4, |(v, _)| *v);
                for (v, prm) in [x, y].into_iter().flatten() {
                    if !(1..=1 << 12).contains(&v) {
                        return Err(prm.err(format!("must be between 1 and 4096, got {v}")));
                    }
                    self.desc.settings_locs.keys.push(("spp".into(), prm.loc.clone()));
                }
                s.spp = (nx * ny) as u32;
                s.sampler = SamplerKind::Stratified;
                s.strata = Some([nx as u32, ny as u32]);
                s.jitter = p.bool("jitter", true)?;
            }
            _ => {
                let default = if kind == "independent" { 4 } else { 16 };
                s.spp = match p.int_opt("pixelsamples")? {
                    Some((v, prm)) => {
                        if v < 1 || v > MAX_SPP as i64 {
                            return Err(prm.err(format!("must be between 1 and {MAX_SPP}, got {v}")));
                        }
                        self.desc.settings_locs.keys.push(("spp".into(), prm.loc.clone()));
                        v as u32
                    }
                    None => default,
                };
                match kind {
                    "independent" => self.desc.settings.sampler = SamplerKind::Independent,
                    // pbrt's padded and Z-order Sobol samplers with Owen
                    // scrambling (their default) pad per-pixel scrambled
                    // Sobol dimension pairs, as trazo's Sobol sampler does;
                    // ZSobol's Morton-ordered indices only change which
                    // scramble a pixel gets.
                    "zsobol" | "paddedsobol" => self.desc.settings.sampler = SamplerKind::Sobol,
                    "halton" => {
                        let randomize = p.string("randomize")?;
                        self.desc.settings.sampler = match randomize
                            .as_ref()
                            .map_or("permutedigits", |(r, _)| r.as_str())
                        {
                            "permutedigits" => SamplerKind::Halton,
                            // pbrt-v4's fast variant hashes the digits
                            // otherwise; both are Owen scrambling.
                            "owen" | "fastowen" => SamplerKind::HaltonOwen,
                            "none" => SamplerKind::HaltonPlain,
                            other => {
                                let prm = randomize.as_ref().map(|(_, prm)| *prm).expect("given");
                                return Err(prm.err(format!(
                                    "unknown randomization \"{other}\": expected \"permutedigits\", \"owen\", \"fastowen\" or \"none\""
                                )));
                            }
                        };
                    }
                    _ => {
                        self.desc.settings.sampler = SamplerKind::Sobol;
                        self.approximated(
                            loc,
                            format!("Sampler \"{kind}\""),
                            "its low-discrepancy points are replaced by per-pixel Owen-scrambled Sobol points (same count)",
                        );
                    }
                }
            }
        }
        if let Some((seed, _)) = p.int_opt("seed")? {
            self.desc.settings.seed = seed as u64;
        }
        Ok(())
    }

    pub(super) fn integrator(&mut self, kind: &str, p: &ParamList, loc: &SourceLoc) -> Result<()> {
        // pbrt's maxdepth counts bounces; trazo's max_depth counts path
        // segments from the camera, one more.
        let depth = match p.int_opt("maxdepth")? {
            Some((v, prm)) => {
                if v < 0 || v >= MAX_DEPTH as i64 {
                    return Err(prm.err(format!("must be between 0 and {}, got {v}", MAX_DEPTH - 1)));
                }
                self.desc.settings_locs.keys.push(("max_depth".into(), prm.loc.clone()));
                v as u32
            }
            None => 5,
        };
        let s = &mut self.desc.settings;
        s.max_depth = depth + 1;
        s.integrator = IntegratorKind::Path;
        s.sampling = PathSampling::Mis;
        // Media are known only once the world is read (`finish`).
        self.volpath = matches!(kind, "volpath" | "simplevolpath");
        if kind == "lightpath" {
            // pbrt-v4's LightPathIntegrator: light tracing, with the same
            // depth.
            s.integrator = IntegratorKind::Light;
        } else if kind == "mlt" {
            // pbrt-v4's MLTIntegrator: multiplexed Metropolis light
            // transport over the bidirectional strategies, its samples per
            // pixel the mutations per pixel.
            s.integrator = IntegratorKind::Mlt;
            let counts = [
                ("bootstrapsamples", 100_000i64),
                ("chains", 1000),
                ("mutationsperpixel", 100),
            ];
            let mut values = [0u32; 3];
            for ((name, default), value) in counts.into_iter().zip(&mut values) {
                *value = match p.int_opt(name)? {
                    Some((v, prm)) if !(1..=MAX_SPP as i64).contains(&v) => {
                        return Err(prm.err(format!("must be between 1 and {MAX_SPP}, got {v}")));
                    }
                    Some((v, _)) => v as u32,
                    None => default as u32,
                };
            }
            let large_step = match p.float_opt("largestepprobability")? {
                Some((v, prm)) if !(0.0..=1.0).contains(&v) => {
                    return Err(prm.err(format!("must be a probability between 0 and 1, got {v}")));
                }
                Some((v, _)) => v,
                None => 0.3,
            };
            let sigma = match p.float_opt("sigma")? {
                Some((v, prm)) if !(v > 0.0 && v.is_finite()) => {
                    return Err(prm.err(format!("must be a positive number, got {v}")));
                }
                Some((v, _)) => v,
                None => 0.01,
            };
            let s = &mut self.desc.settings;
            s.mlt = crate::settings::MltSettings {
                bootstrap: values[0],
                chains: values[1],
                large_step_probability: large_step,
                sigma,
            };
            self.mlt_mutations = Some(values[2]);
        } else if kind == "bdpt" {
            // pbrt-v4's BDPTIntegrator, with the same depth.
            s.integrator = IntegratorKind::Bdpt;
            // Either asks for the strategies' images; trazo writes both
            // kinds (`trazo render --bdpt-strategies` names them).
            for name in ["visualizestrategies", "visualizeweights"] {
                if p.bool(name, false)? {
                    self.desc.settings.bdpt_strategies = true;
                }
            }
            Self::use_all(p);
        } else if kind == "ambientocclusion" {
            // pbrt-v4's AOIntegrator. Its `cossample` false samples the
            // hemisphere uniformly: the same image, noisier; trazo samples
            // by the cosine either way.
            s.integrator = IntegratorKind::AmbientOcclusion;
            if let Some((d, prm)) = p.float_opt("maxdistance")? {
                if d.is_nan() || d <= 0.0 {
                    return Err(prm.err(format!("must be a positive distance, got {d}")));
                }
                self.desc.settings.ao_distance = d;
            }
            p.bool("cossample", true)?;
        } else if kind == "sppm" {
            // pbrt-v4's SPPMIntegrator: one iteration per pixel sample,
            // `photonsperiteration` photons (−1: one per pixel) and an
            // initial search radius of `radius` scene units (default 1).
            s.integrator = IntegratorKind::Sppm;
            let photons = match p.int_opt("photonsperiteration")? {
                Some((v, _)) if v == -1 || v == 0 => 0,
                Some((v, prm)) => {
                    if !(1..=MAX_PHOTONS as i64).contains(&v) {
                        return Err(prm.err(format!(
                            "must be −1 (one per pixel) or between 1 and {MAX_PHOTONS}, got {v}"
                        )));
                    }
                    v as u32
                }
                None => 0,
            };
            let radius = match p.float_opt("radius")? {
                Some((v, prm)) => {
                    if !(v > 0.0 && v.is_finite()) {
                        return Err(prm.err(format!("must be a positive number, got {v}")));
                    }
                    v
                }
                None => 1.0,
            };
            let seed = p.int_opt("seed")?.map(|(v, _)| v as u64);
            let s = &mut self.desc.settings;
            s.photon.sppm_photons = photons;
            s.photon.radius = radius;
            if let Some(seed) = seed {
                s.seed = seed;
            }
        } else if kind == "randomwalk" {
            // pbrt-v4's RandomWalkIntegrator: uniformly sampled directions,
            // emission found by hitting it: trazo's uniform estimator.
            s.sampling = PathSampling::Uniform;
        } else if kind == "simplepath" {
            // pbrt-v4's SimplePathIntegrator: light sampling for direct
            // light without MIS, BSDF sampling or uniform directions
            // onward.
            let lights = p.bool("samplelights", true)?;
            let bsdf = p.bool("samplebsdf", true)?;
            self.desc.settings.sampling = match (lights, bsdf) {
                (true, true) => PathSampling::Nee,
                (true, false) => PathSampling::NeeUniform,
                (false, true) => PathSampling::Bsdf,
                (false, false) => PathSampling::Uniform,
            };
        } else if kind == "simplevolpath" {
            // pbrt-v4's SimpleVolPathIntegrator: delta tracking through
            // media, emission found by hitting it, no light sampling, and
            // surfaces that scatter refused (it stops with an error at
            // the first BSDF sample). trazo's volumetric path tracer
            // estimates the same image with next-event estimation: less
            // noise, and it renders scattering surfaces too.
        } else if kind == "function" {
            // pbrt-v4's FunctionIntegrator: a sampler study, not a render.
            let function = match p.string("function")? {
                Some((name, prm)) => TestFunction::from_name(&name).ok_or_else(|| {
                    prm.err(format!(
                        "unknown function \"{name}\": expected one of {}",
                        TestFunction::NAMES.map(|n| format!("\"{n}\"")).join(", ")
                    ))
                })?,
                None => TestFunction::Step,
            };
            let path = |v: Option<(String, _)>| v.map(|(f, _)| std::path::PathBuf::from(f));
            let output = path(p.string("filename")?);
            let image = path(p.string("imagefilename")?);
            let skip_bad = p.bool("skipbad", true)?;
            self.desc.settings_locs.keys.push(("integrator".into(), loc.clone()));
            self.desc.sampler_study = Some(SamplerStudy {
                function,
                skip_bad,
                output,
                image,
            });
        } else if !matches!(kind, "path" | "volpath" | "bdpt" | "mlt") {
            self.approximated(
                loc,
                format!("Integrator \"{kind}\""),
                "rendered by trazo's path tracer (next-event estimation with MIS) with the same depth",
            );
            Self::use_all(p);
        }
        if matches!(kind, "path" | "volpath" | "bdpt" | "mlt") {
            // Light sampling and regularisation change noise, not the
            // expected image.
            for (name, how) in [
                ("lightsampler", "trazo picks lights in proportion to their power"),
                ("regularize", "paths are not regularised"),
            ] {
                if let Some(prm) = p.find(name) {
                    let l = prm.loc.clone();
                    self.unsupported(&l, format!("\"{}\"", prm.written), how);
                }
            }
        }
        Ok(())
    }

    /// A filter's float parameter `name` (`default` where absent), its
    /// place recorded under the settings key `key` for validation errors.
    fn filter_parameter(&mut self, p: &ParamList, name: &str, default: f32, key: &str) -> Result<f32> {
        let value = p.float(name, default)?;
        if let Some((_, prm)) = p.float_opt(name)? {
            self.desc.settings_locs.keys.push((key.into(), prm.loc.clone()));
        }
        Ok(value)
    }

    pub(super) fn pixel_filter(&mut self, kind: &str, p: &ParamList, loc: &SourceLoc) -> Result<()> {
        let default = match kind {
            "box" => 0.5,
            "gaussian" => 1.5,
            "sinc" => 4.0,
            _ => 2.0,
        };
        let x = p.float_opt("xradius")?;
        let y = p.float_opt("yradius")?;
        let radius = x.as_ref().map_or(default, |(v, _)| *v);
        let y_radius = y.as_ref().map_or(default, |(v, _)| *v);
        for (given, key) in [(&x, "filter_radius"), (&y, "filter_y_radius")] {
            if let Some((_, prm)) = given {
                self.desc.settings_locs.keys.push((key.into(), prm.loc.clone()));
            }
        }
        // pbrt-v4's filters have a radius per axis.
        self.desc.settings.filter_y_radius = (y_radius != radius).then_some(y_radius);
        self.desc.settings.filter = match kind {
            "box" => Filter::Box { radius },
            "triangle" => Filter::Tent { radius },
            "gaussian" => {
                let sigma = self.filter_parameter(p, "sigma", 0.5, "filter_stddev")?;
                Filter::Gaussian { stddev: sigma, radius }
            }
            // pbrt-v4's `MitchellFilter`: Mitchell1D(2x/radius), B and C
            // 1/3.
            "mitchell" => {
                let b = self.filter_parameter(p, "B", 1.0 / 3.0, "filter_b")?;
                let c = self.filter_parameter(p, "C", 1.0 / 3.0, "filter_c")?;
                Filter::Mitchell { radius, b, c }
            }
            // pbrt-v4's `LanczosSincFilter`: sinc(x)·sinc(x/τ), τ 3.
            "sinc" => {
                let tau = self.filter_parameter(p, "tau", 3.0, "filter_tau")?;
                Filter::Lanczos { radius, tau }
            }
            _ => {
                Self::use_all(p);
                self.approximated(
                    loc,
                    format!("PixelFilter \"{kind}\""),
                    format!("replaced by a Gaussian filter (σ = 0.5 pixels) of the same radius {radius}"),
                );
                Filter::Gaussian { stddev: 0.5, radius }
            }
        };
        Ok(())
    }

    /// A `Camera "realistic"`: its lens description (`lensfile`, found as
    /// textures are: numbers in millimetres, four per interface, `#`
    /// comments), `aperturediameter` (1 mm) and `focusdistance` (10), over
    /// the film's `diagonal`.
    fn realistic_camera(
        &mut self,
        p: &ParamList,
        dir_rel: &std::path::Path,
        locs: &mut Locs,
    ) -> Result<ProjectionDesc> {
        let Some((file, prm)) = p.string("lensfile")? else {
            let l = self.camera.loc.clone().unwrap_or_else(|| self.desc_loc());
            return Err(Error::scene(
                Some(l),
                "lensfile",
                "a realistic camera needs a \"string lensfile\" (its lens description)",
            ));
        };
        locs.keys.push(("lens".into(), prm.loc.clone()));
        let path = self.top_dir.join(self.resolve(dir_rel, &file));
        let text = crate::files::read_limited(&path, crate::files::MAX_SCENE_BYTES)
            .map_err(|e| prm.err(format!("cannot read the lens description {}: {e}", path.display())))?;
        let mut lenses = Vec::new();
        for (n, line) in String::from_utf8_lossy(&text).lines().enumerate() {
            for word in line.split('#').next().unwrap_or("").split_whitespace() {
                let x: f32 = word
                    .parse()
                    .map_err(|_| prm.err(format!("{}:{}: \"{word}\" is not a number", path.display(), n + 1)))?;
                lenses.push(x);
            }
        }
        let aperture_diameter = p.float("aperturediameter", 1.0)?;
        let focus_distance = p.float("focusdistance", 10.0)?;
        // A shaped stop: one of pbrt-v4's built-in shapes, or an image
        // (found as textures are; colours averaged to grey).
        let stop_mask = match p.string("aperture")? {
            None => None,
            Some((name, _)) if name.is_empty() => None,
            Some((name, prm)) => Some(match crate::camera::ApertureMask::built_in(&name) {
                Some(mask) => mask,
                None => {
                    let path = self.top_dir.join(self.resolve(dir_rel, &name));
                    let image = crate::texture::ImageTexture::load(&path, None)
                        .map_err(|e| prm.err(format!("cannot read the aperture image: {e}")))?;
                    let grey = image.pixels.iter().map(|c| (c.x + c.y + c.z) / 3.0).collect();
                    crate::camera::ApertureMask::from_image(image.width as usize, image.height as usize, grey)
                        .map_err(|e| prm.err(format!("{}: {e}", path.display())))?
                }
            }),
        };
        Ok(ProjectionDesc::Realistic {
            lenses,
            aperture_diameter,
            focus_distance,
            film_diagonal: self.film_diagonal_mm / 1000.0,
            stop_mask,
        })
    }

    /// Converts the camera once the film size is known (pbrt-v4 creates it
    /// at WorldBegin too).
    pub(super) fn finish_options(&mut self) -> Result<()> {
        let cam = self.camera.clone();
        let p = &cam.params;
        let at = cam.loc.clone();
        let (w, h) = self.desc.settings.full_size();
        let (w, h) = (w as f32, h as f32);
        let mut locs = Locs::at(at.clone());
        locs.keys
            .push(("to_world".into(), at.clone().unwrap_or_else(|| self.desc_loc())));
        // A moving camera's transform at the end time (checked first: the
        // name is taken below).
        let world_from_camera_end = match world_from_camera(&cam.ctm_end) {
            _ if cam.ctm_end == cam.ctm => None,
            Ok((m, _)) => Some(m),
            Err(why) => {
                return Err(Error::scene(
                    at,
                    "Camera",
                    format!("the current transform at the end time {why}, so the moving camera has no view"),
                ));
            }
        };
        let (world_from_camera, projective) = match world_from_camera(&cam.ctm) {
            Ok(m) => m,
            Err(why) => {
                return Err(Error::scene(
                    at,
                    "Camera",
                    format!("the current transform {why}, so the camera has no view"),
                ));
            }
        };
        // The screen window spans [-1, 1] along the shorter side of the
        // frame, whose aspect ratio is the image's unless
        // `frameaspectratio` says otherwise, or is given by `screenwindow`
        // (pbrt-v4 `CameraBase`/`PerspectiveCamera::Create`).
        let mut frame = w / h;
        if let Some((f, prm)) = p.float_opt("frameaspectratio")? {
            if f <= 0.0 {
                return Err(prm.err(format!("must be positive, got {f}")));
            }
            frame = f;
        }
        let mut window = if frame > 1.0 {
            [-frame, frame, -1.0, 1.0]
        } else {
            [-1.0, 1.0, -1.0 / frame, 1.0 / frame]
        };
        if let Some((sw, prm)) = p.floats("screenwindow")? {
            if sw.len() != 4 {
                return Err(prm.err(format!("needs 4 values (xmin xmax ymin ymax), found {}", sw.len())));
            }
            if !(sw[0] < sw[1] && sw[2] < sw[3]) || sw.iter().any(|v| !v.is_finite()) {
                return Err(prm.err("needs finite values with xmin < xmax and ymin < ymax"));
            }
            locs.keys.push(("screen_window".into(), prm.loc.clone()));
            window = [sw[0], sw[1], sw[2], sw[3]];
        }
        // The window the image's own aspect gives, centred, is trazo's
        // default framing (and the field of view below is converted to
        // it); any other is laid over the image as given.
        let image_window = if w > h {
            [-w / h, w / h, -1.0, 1.0]
        } else {
            [-1.0, 1.0, -h / w, h / w]
        };
        let screen_window = (window != image_window).then_some(window);
        let half_h = window[3];
        let projection = match cam.kind.as_str() {
            "orthographic" => ProjectionDesc::Orthographic { size: 2.0 * half_h },
            "realistic" => self.realistic_camera(p, &cam.dir_rel, &mut locs)?,
            "spherical" => {
                let mapping = match p.string("mapping")? {
                    None => SphericalMapping::EqualArea,
                    Some((m, prm)) => match m.as_str() {
                        "equalarea" => SphericalMapping::EqualArea,
                        "equirectangular" => SphericalMapping::Equirectangular,
                        _ => {
                            return Err(prm.err(format!(
                                "unknown mapping \"{m}\" (pbrt-v4's are \"equalarea\" and \"equirectangular\")"
                            )));
                        }
                    },
                };
                if mapping == SphericalMapping::EqualArea && w != h {
                    let l = at.clone().unwrap_or_else(|| self.desc_loc());
                    self.approximated(
                        &l,
                        "an equal-area spherical camera with a film that is not square",
                        "the square mapping is stretched over the image, as pbrt-v4 does; every pixel no longer sees the same solid angle",
                    );
                }
                // pbrt-v4 reads `lensradius` and `focaldistance` (below)
                // and ignores them: the camera has no lens.
                ProjectionDesc::Spherical { mapping }
            }
            kind => {
                let fov = match p.float_opt("fov")? {
                    Some((fov, prm)) => {
                        if !(fov > 0.0 && fov < 180.0) {
                            return Err(prm.err(format!("must be between 0 and 180 degrees (exclusive), got {fov}")));
                        }
                        locs.keys.push(("fov".into(), prm.loc.clone()));
                        fov
                    }
                    None => 90.0,
                };
                if kind != "perspective" {
                    Self::use_all(p);
                    let l = at.clone().unwrap_or_else(|| self.desc_loc());
                    self.approximated(
                        &l,
                        format!("Camera \"{kind}\""),
                        format!(
                            "rendered by a perspective camera with a {fov}° field of view on the shorter image axis"
                        ),
                    );
                }
                // pbrt's fov spans the screen window's shorter side; trazo's
                // is vertical, over its default window. A window of its own
                // is in units of tan(fov/2), which the fov then gives as is.
                let vertical = if screen_window.is_some() {
                    fov
                } else {
                    (2.0 * ((fov.to_radians() * 0.5).tan() * half_h).atan()).to_degrees()
                };
                ProjectionDesc::Perspective { fov: vertical }
            }
        };
        let lens = p.float_opt("lensradius")?;
        let mut aperture_radius = 0.0;
        if let Some((r, prm)) = lens {
            if r.is_nan() || r < 0.0 {
                return Err(prm.err(format!("must not be negative, got {r}")));
            }
            locs.keys.push(("aperture_radius".into(), prm.loc.clone()));
            aperture_radius = r;
        }
        let mut focus_distance = 1e6;
        if let Some((d, prm)) = p.float_opt("focaldistance")? {
            if d.is_nan() || d <= 0.0 {
                return Err(prm.err(format!("must be positive, got {d}")));
            }
            locs.keys.push(("focus_distance".into(), prm.loc.clone()));
            focus_distance = d;
        }
        let open = p.float("shutteropen", 0.0)?;
        let close = p.float("shutterclose", 1.0)?;
        if close <= open {
            let l = at.clone().unwrap_or_else(|| self.desc_loc());
            return Err(Error::scene(
                Some(l),
                "Camera",
                format!("shutterclose ({close}) must be after shutteropen ({open}): the shutter never opens"),
            ));
        }
        // pbrt-v4's imaging ratio: exposure time × ISO / 100.
        let ratio = (close - open) * self.film_iso / 100.0;
        if ratio != 1.0 {
            self.desc.settings.exposure = ratio.log2();
        }
        if projective && (cam.kind == "orthographic" || aperture_radius > 0.0) {
            let l = at.clone().unwrap_or_else(|| self.desc_loc());
            self.approximated(
                &l,
                "a projective camera transform (a bottom row other than 0 0 0 1)",
                "rays from the eye follow it as in pbrt-v4, but rays from other points of the lens or of an orthographic camera's film are moved by its affine part only",
            );
        }
        // Only projective cameras have a screen window (pbrt-v4's
        // realistic and spherical cameras do not read one).
        let screen_window = match projection {
            ProjectionDesc::Perspective { .. } | ProjectionDesc::Orthographic { .. } => screen_window,
            _ => {
                if let (Some(prm), Some(_)) = (p.find("screenwindow"), screen_window) {
                    let l = prm.loc.clone();
                    self.unsupported(&l, "\"float screenwindow\" on this camera", "it has no screen window");
                }
                None
            }
        };
        self.desc.camera = CameraDesc {
            projection,
            screen_window,
            aperture_radius,
            focus_distance: Some(focus_distance),
            to_world: Some(world_from_camera),
            shutter: (open, close),
            motion: world_from_camera_end.map(|m| (m, self.transform_times)),
            locs,
            ..CameraDesc::default()
        };
        self.report_unused(p, &format!("Camera \"{}\"", cam.kind));
        Ok(())
    }
}
