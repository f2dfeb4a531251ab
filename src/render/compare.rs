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

impl Budget {
    /// 1/2^k of the budget; `None` where that is less than one sample per
    /// pixel.
    pub fn fraction(self, k: u32) -> Option<Budget> {
        match self {
            Budget::Spp(n) => Some(Budget::Spp(n.checked_shr(k).filter(|&m| m >= 1)?)),
            Budget::Time { limit, max_spp } => Some(Budget::Time {
                limit: limit / 2u32.checked_pow(k)?,
                max_spp,
            }),
        }
    }
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
    /// With a reference: (seconds, relative MSE) of renders at 1/32, 1/16,
    /// …, 1/2 of the budget (those of at least one sample per pixel) and of
    /// the full one, for the convergence plot.
    pub convergence: Vec<(f64, f64)>,
    /// The image.
    pub image: Image,
}

/// Budget fractions 1/2^k of the convergence plot's extra renders: up to
/// five points below the full budget, each render independent.
const CONVERGENCE_HALVINGS: u32 = 5;

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
        let mut scene = crate::scene::build(&d)?;
        let run = run_contestant(&mut scene, c, budget, &opts)?;
        let rel_mse = reference.map(|r| relative_mse(&run.image, r)).transpose()?;
        let mut convergence = Vec::new();
        if let (Some(r), Some(e)) = (reference, rel_mse) {
            // Smaller budgets first, each its own render; quiet, as the
            // full render already showed its progress.
            let quiet = RenderOptions {
                progress: false,
                ..opts.clone()
            };
            for k in (1..=CONVERGENCE_HALVINGS).rev() {
                let Some(part) = budget.fraction(k) else {
                    continue;
                };
                let partial = run_contestant(&mut scene, c, part, &quiet)?;
                convergence.push((partial.seconds, relative_mse(&partial.image, r)?));
            }
            convergence.push((run.seconds, e));
        }
        rows.push(ComparisonRow {
            label: c.label.clone(),
            spp: run.spp,
            seconds: run.seconds,
            msamples_per_second: run.msamples_per_second,
            mrays_per_second: run.mrays_per_second,
            mean_standard_error: run.mean_standard_error,
            rel_mse,
            convergence,
            image: run.image,
        });
    }
    Ok(rows)
}

/// One render of a contestant and what the table reports of it.
struct Run {
    spp: u32,
    seconds: f64,
    msamples_per_second: f64,
    mrays_per_second: f64,
    mean_standard_error: Option<f64>,
    image: Image,
}

/// Renders `scene` (built for contestant `c`) within `budget`, denoising
/// the image if `c` asks for it (its time then counts too).
fn run_contestant(
    scene: &mut crate::scene::Scene,
    c: &Contestant,
    budget: Budget,
    options: &RenderOptions,
) -> Result<Run> {
    let mut opts = options.clone();
    scene.settings.spp = match budget {
        Budget::Spp(n) => n,
        Budget::Time { limit, max_spp } => {
            opts.time_limit = Some(limit);
            max_spp
        }
    };
    let out = render(scene, &opts)?;
    let mut seconds = out.stats.seconds;
    // SPPM's iterations are not independent estimates (each shrinks the
    // radii), nor are MLT's (the chains go on from one to the next): the
    // spread between their iterations says nothing of the error.
    let mut mean_standard_error = match c.integrator {
        IntegratorKind::Sppm | IntegratorKind::Mlt | IntegratorKind::Pssmlt => None,
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
    Ok(Run {
        spp: out.stats.spp,
        seconds,
        msamples_per_second: out.stats.samples_per_second() / 1e6,
        mrays_per_second: out.stats.rays_per_second() / 1e6,
        mean_standard_error,
        image,
    })
}

/// The convergence plot's curves: per contestant, the root of each
/// relative MSE (an RMS relative error, which falls as 1/√t for an
/// unbiased estimator) against seconds.
pub fn convergence_curves(rows: &[ComparisonRow]) -> Vec<crate::film::plot::Curve> {
    rows.iter()
        .filter(|r| !r.convergence.is_empty())
        .map(|r| crate::film::plot::Curve {
            label: r.label.clone(),
            points: r.convergence.iter().map(|&(t, e)| (t, e.sqrt())).collect(),
        })
        .collect()
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
    fn budget_fractions() {
        assert_eq!(Budget::Spp(64).fraction(1), Some(Budget::Spp(32)));
        assert_eq!(Budget::Spp(64).fraction(6), Some(Budget::Spp(1)));
        assert_eq!(Budget::Spp(64).fraction(7), None);
        assert_eq!(Budget::Spp(1).fraction(40), None);
        let t = Budget::Time {
            limit: Duration::from_secs(2),
            max_spp: 9,
        };
        assert_eq!(
            t.fraction(2),
            Some(Budget::Time {
                limit: Duration::from_millis(500),
                max_spp: 9
            })
        );
    }

    /// The convergence points of an unbiased estimator: one per halving of
    /// the budget and the full one, in order of samples, the error falling
    /// as the samples grow (by the 32× between first and last, 1/32 of the
    /// relative MSE in expectation; a factor of 4 is far outside the noise
    /// of 16×16 pixels).
    #[test]
    fn convergence_points_follow_the_budget() {
        let mut desc = crate::scene::builtin::cornell_box();
        desc.settings.width = 16;
        desc.settings.height = 16;
        desc.settings.spp = 1024;
        let options = RenderOptions {
            progress: false,
            ..RenderOptions::default()
        };
        let reference = render(&crate::scene::build(&desc).unwrap(), &options)
            .unwrap()
            .film
            .to_image();
        let c = [Contestant::parse("path:mis").unwrap()];
        let rows = compare(&desc, &c, Budget::Spp(32), Some(&reference), &options).unwrap();
        let points = &rows[0].convergence;
        assert_eq!(points.len(), 6, "{points:?}");
        assert_eq!(points.last().unwrap().1, rows[0].rel_mse.unwrap());
        assert!(points[0].1 > 4.0 * points[5].1, "{points:?}");
        let curves = convergence_curves(&rows);
        assert_eq!(curves[0].points[5].1, points[5].1.sqrt());
        // Without a reference, no extra renders.
        let rows = compare(&desc, &c, Budget::Spp(2), None, &options).unwrap();
        assert!(rows[0].convergence.is_empty() && convergence_curves(&rows).is_empty());
    }

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
        assert_eq!(Contestant::parse("bdpt").unwrap().integrator, IntegratorKind::Bdpt);
        assert_eq!(Contestant::parse("mlt").unwrap().integrator, IntegratorKind::Mlt);
        assert_eq!(Contestant::parse("vcm").unwrap().integrator, IntegratorKind::Vcm);
        assert!(Contestant::parse("upbp").is_err());
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
