//! The course's comparison: one scene rendered by several algorithms at
//! equal sample count or equal time, side by side, with a table of time
//! and noise (or error against a reference image).

use super::{RenderOptions, render};
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::film::Image;
use crate::film::denoise::{DenoiserKind, denoise_film};
use crate::film::metrics::relative_mse;
use crate::film::text::{GLYPH_H, draw_text, text_width};
use crate::scene::SceneDesc;
use crate::settings::{IntegratorKind, PathSampling};
use std::time::{Duration, Instant};

/// One contestant: an integrator, for the path tracer its estimator, and
/// optionally a denoiser applied to its image.
#[derive(Clone, Debug, PartialEq)]
pub struct Contestant {
    /// As the user wrote it (`whitted`, `path:mis`, `path:mis+denoise`, …).
    pub label: String,
    /// Algorithm.
    pub integrator: IntegratorKind,
    /// Estimator (path tracer only).
    pub sampling: PathSampling,
    /// Fixed-step ray marching with this step (volumetric path tracer
    /// only); `None`: tracking.
    pub march_step: Option<f32>,
    /// Denoiser run on the result.
    pub denoise: Option<DenoiserKind>,
}

impl Contestant {
    /// Parses `whitted`, `path`, `path:uniform|cosine|bsdf|mis`, `photon`,
    /// `sppm`, `volpath` or `volpath:march=STEP`, optionally followed by `+denoise` (Open Image Denoise if
    /// available, else the built-in filter), `+atrous` or `+oidn`.
    pub fn parse(spec: &str) -> Result<Contestant> {
        let spec = spec.trim();
        let (spec, denoise) = match spec.split_once('+') {
            None => (spec, None),
            Some((base, suffix)) => {
                let kind = match suffix {
                    "denoise" => DenoiserKind::Auto,
                    other => DenoiserKind::from_name(other)
                        .filter(|k| *k != DenoiserKind::Auto)
                        .ok_or_else(|| {
                            Error::Invalid(format!(
                                "unknown denoiser \"+{other}\" in --integrators (expected +denoise, +atrous or +oidn)"
                            ))
                        })?,
                };
                (base, Some((suffix, kind)))
            }
        };
        let (name, variant) = match spec.split_once(':') {
            Some((n, v)) => (n, Some(v)),
            None => (spec, None),
        };
        let integrator = IntegratorKind::from_name(name).ok_or_else(|| {
            Error::Invalid(format!(
                "unknown integrator \"{name}\" in --integrators (expected one of {})",
                IntegratorKind::NAMES.join(", ")
            ))
        })?;
        let mut march_step = None;
        let sampling = match (integrator, variant) {
            (_, None) => PathSampling::default(),
            (IntegratorKind::VolPath, Some(v)) => {
                let step = v
                    .strip_prefix("march=")
                    .and_then(|x| x.parse::<f32>().ok())
                    .filter(|x| x.is_finite() && *x > 0.0)
                    .ok_or_else(|| {
                        Error::Invalid(format!(
                            "unknown volpath variant \"{v}\" in --integrators (expected march=STEP, a positive length)"
                        ))
                    })?;
                march_step = Some(step);
                PathSampling::default()
            }
            (IntegratorKind::Path, Some(v)) => PathSampling::from_name(v).ok_or_else(|| {
                Error::Invalid(format!(
                    "unknown path sampling \"{v}\" in --integrators (expected one of {})",
                    PathSampling::NAMES.join(", ")
                ))
            })?,
            (_, Some(v)) => {
                return Err(Error::Invalid(format!(
                    "\"{name}\" takes no variant (got \"{name}:{v}\")"
                )));
            }
        };
        let mut label = match (integrator, march_step) {
            (IntegratorKind::Path, _) => format!("path:{}", sampling.name()),
            (IntegratorKind::VolPath, Some(step)) => format!("volpath:march={step}"),
            _ => name.to_string(),
        };
        if let Some((suffix, _)) = denoise {
            label = format!("{label}+{suffix}");
        }
        Ok(Contestant {
            label,
            integrator,
            sampling,
            march_step,
            denoise: denoise.map(|d| d.1),
        })
    }
}

/// How much work each contestant gets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// The same number of samples per pixel.
    Spp(u32),
    /// The same wall time (at most `max_spp` samples per pixel).
    Time {
        /// Time per contestant.
        limit: Duration,
        /// Upper bound on samples per pixel.
        max_spp: u32,
    },
}

/// The result for one contestant.
#[derive(Clone, Debug)]
pub struct ComparisonRow {
    /// Which contestant.
    pub label: String,
    /// Samples per pixel rendered.
    pub spp: u32,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Millions of samples per second.
    pub msamples_per_second: f64,
    /// Millions of rays per second.
    pub mrays_per_second: f64,
    /// Mean over pixels of the standard error of the pixel's luminance
    /// (`None` where it does not apply: SPPM, denoised images).
    pub mean_standard_error: Option<f64>,
    /// Relative MSE against the reference, when one is given.
    pub rel_mse: Option<f64>,
    /// The image.
    pub image: Image,
}

/// Renders the scene once per contestant.
pub fn compare(
    desc: &SceneDesc,
    contestants: &[Contestant],
    budget: Budget,
    reference: Option<&Image>,
    options: &RenderOptions,
) -> Result<Vec<ComparisonRow>> {
    let mut rows = Vec::new();
    for c in contestants {
        let mut d = desc.clone();
        d.settings.integrator = c.integrator;
        d.settings.sampling = c.sampling;
        d.settings.march_step = c.march_step;
        let mut opts = options.clone();
        opts.aovs |= c.denoise.is_some();
        match budget {
            Budget::Spp(n) => d.settings.spp = n,
            Budget::Time { limit, max_spp } => {
                d.settings.spp = max_spp;
                opts.time_limit = Some(limit);
            }
        }
        let scene = crate::scene::build(&d)?;
        let out = render(&scene, &opts)?;
        let mut seconds = out.stats.seconds;
        let mut mean_standard_error = match c.integrator {
            IntegratorKind::Sppm => None,
            _ => Some(out.film.mean_standard_error()),
        };
        let image = match c.denoise {
            Some(kind) => {
                let start = Instant::now();
                let d = denoise_film(&out.film, kind)?;
                seconds += start.elapsed().as_secs_f64();
                mean_standard_error = None;
                d.image
            }
            None => out.film.to_image(),
        };
        let rel_mse = reference.map(|r| relative_mse(&image, r)).transpose()?;
        rows.push(ComparisonRow {
            label: c.label.clone(),
            spp: out.stats.spp,
            seconds,
            msamples_per_second: out.stats.samples_per_second() / 1e6,
            mrays_per_second: out.stats.rays_per_second() / 1e6,
            mean_standard_error,
            rel_mse,
            image,
        });
    }
    Ok(rows)
}

/// The comparison as a Markdown table.
pub fn table(rows: &[ComparisonRow]) -> String {
    let with_ref = rows.iter().any(|r| r.rel_mse.is_some());
    let mut s = String::from("| integrator | spp | time (s) | M samples/s | M rays/s | mean std. error |");
    s.push_str(if with_ref { " rel. MSE |\n" } else { "\n" });
    s.push_str("|---|---|---|---|---|---|");
    s.push_str(if with_ref { "---|\n" } else { "\n" });
    for r in rows {
        let error = r.mean_standard_error.map_or("—".to_string(), |e| format!("{e:.5}"));
        s.push_str(&format!(
            "| {} | {} | {:.2} | {:.2} | {:.2} | {} |",
            r.label, r.spp, r.seconds, r.msamples_per_second, r.mrays_per_second, error
        ));
        if let Some(e) = r.rel_mse {
            s.push_str(&format!(" {e:.5} |"));
        }
        s.push('\n');
    }
    s
}

/// Height of the label bar above each image.
const BAR: u32 = 2 * GLYPH_H + 8;

/// The images side by side, each under a bar with its label, sample count
/// and time. Labels are drawn very bright so that any tone mapping shows
/// them white.
pub fn side_by_side(rows: &[ComparisonRow]) -> Image {
    let (w, h) = rows.first().map_or((1, 1), |r| (r.image.width, r.image.height));
    let gap = 4;
    let total_w = rows.len() as u32 * w + gap * rows.len().saturating_sub(1) as u32;
    let mut out = Image::new(total_w.max(1), h + BAR);
    for (k, r) in rows.iter().enumerate() {
        let x0 = k as u32 * (w + gap);
        for y in 0..h {
            for x in 0..w {
                out.pixels[((y + BAR) * out.width + x0 + x) as usize] = r.image.get(x, y);
            }
        }
        let mut label = format!("{} {}SPP {:.1}S", r.label, r.spp, r.seconds);
        let mut scale = 2;
        if text_width(&label, scale) + 8 > w {
            scale = 1;
        }
        while text_width(&label, scale) + 8 > w && label.len() > 1 {
            label.pop();
        }
        draw_text(&mut out, x0 + 4, 4, &label, scale, Rgb::splat(1000.0));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contestant_specs() {
        let c = Contestant::parse("path:uniform").unwrap();
        assert_eq!(
            (c.integrator, c.sampling),
            (IntegratorKind::Path, PathSampling::Uniform)
        );
        assert_eq!(Contestant::parse("whitted").unwrap().label, "whitted");
        assert_eq!(Contestant::parse("path").unwrap().label, "path:mis");
        assert!(Contestant::parse("path:magic").is_err());
        assert!(Contestant::parse("whitted:mis").is_err());
        assert_eq!(Contestant::parse("photon").unwrap().integrator, IntegratorKind::Photon);
        assert_eq!(Contestant::parse("sppm").unwrap().label, "sppm");
        assert!(Contestant::parse("photon:mis").is_err());
        assert!(Contestant::parse("bdpt").is_err());
        let d = Contestant::parse("path:mis+denoise").unwrap();
        assert_eq!(
            (d.label.as_str(), d.denoise),
            ("path:mis+denoise", Some(DenoiserKind::Auto))
        );
        assert_eq!(
            Contestant::parse("path+atrous").unwrap().denoise,
            Some(DenoiserKind::Atrous)
        );
        assert_eq!(Contestant::parse("sppm+oidn").unwrap().label, "sppm+oidn");
        assert!(Contestant::parse("path+auto").is_err());
        assert!(Contestant::parse("path+blur").is_err());
        let m = Contestant::parse("volpath:march=0.05").unwrap();
        assert_eq!((m.label.as_str(), m.march_step), ("volpath:march=0.05", Some(0.05)));
        assert_eq!(Contestant::parse("volpath").unwrap().march_step, None);
        assert!(Contestant::parse("volpath:march=-1").is_err());
        assert!(Contestant::parse("volpath:fast").is_err());
    }
}
