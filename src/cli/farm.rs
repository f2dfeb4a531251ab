//! Render farms from the command line: the part files of `trazo render
//! --shard K/N`, and `trazo merge`, which checks that parts belong
//! together and writes the image of the whole render, or reports how far
//! the shards are (`--status`).
//!
//! A part file is a checkpoint ([`crate::render::checkpoint`]) whose job
//! names its shard: the shard's film of exact sums, the samples per pixel
//! it holds, and the render's settings, scene and file hashes. Parts of the
//! same render agree on all of these but the paths (shards may run on
//! machines that mount the scene elsewhere), the shard and the output.

use super::ImageOutputs;
use crate::error::{Error, Result};
use crate::film::denoise::DenoiserKind;
use crate::film::{Aov, Film};
use crate::render::checkpoint::Checkpoint;
use crate::render::{RenderOutput, RenderStats, Shard, Stop, shard_passes};
use crate::settings::{RenderSettings, Tonemap};
use clap::Args;
use std::path::{Path, PathBuf};

/// The extension of part files.
pub(super) const PART_EXTENSION: &str = "trazo-part";

#[derive(Args, Debug)]
pub(super) struct MergeArgs {
    /// The part files (.trazo-part) of the shards of one render.
    #[arg(required = true, value_name = "PARTS")]
    parts: Vec<PathBuf>,

    /// The image to write (PNG, EXR, HDR or PFM by extension); the
    /// auxiliary images and the denoised image the render asked for are
    /// written beside it, as `trazo render` writes them.
    #[arg(short, long, value_name = "FILE", required_unless_present = "status")]
    output: Option<PathBuf>,

    /// Write the image even if shards are missing or unfinished (it is then
    /// a noisier image of the same scene, with the samples the parts hold).
    #[arg(long)]
    partial: bool,

    /// Only tell which shards are done and how many samples per pixel the
    /// parts hold; write nothing.
    #[arg(long, conflicts_with_all = ["output", "partial"])]
    status: bool,
}

/// `scene.toml` and shard 2/8 → `scene.shard-2-of-8.trazo-part`.
pub(super) fn default_part(scene: Option<&Path>, shard: Shard) -> PathBuf {
    let image = super::default_output(scene);
    let stem = image
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    PathBuf::from(format!(
        "{stem}.shard-{}-of-{}.{PART_EXTENSION}",
        shard.index + 1,
        shard.count
    ))
}

/// A shard writes a part file, never an image: its name says so.
pub(super) fn check_part_name(path: &Path) -> Result<()> {
    if path.extension().is_some_and(|e| e == PART_EXTENSION) {
        Ok(())
    } else {
        Err(Error::file(
            path,
            format!("with --shard the output is a part file for `trazo merge`: name it NAME.{PART_EXTENSION}"),
        ))
    }
}

/// What a shard's command says when it is done.
pub(super) fn report_shard(shard: Shard, part: &Path, s: &RenderSettings, out: &RenderOutput, quiet: bool) {
    let st = &out.stats;
    let share: u32 = shard_passes(s.spp, shard)
        .map(|p| p.iter().map(|p| p.1 - p.0).sum())
        .unwrap_or(0);
    let why = match out.stopped {
        Some(Stop::Interrupted) => "interrupted: ",
        Some(Stop::TimeLimit) => "time limit reached: ",
        None => "",
    };
    if !quiet || out.stopped.is_some() {
        eprintln!(
            "{why}rendered shard {}/{} of {}×{} ({} of its {share} spp, of {} in all) in {:.2} s ({:.2} M samples/s, {} threads) → {}",
            shard.index + 1,
            shard.count,
            s.width,
            s.height,
            st.spp,
            s.spp,
            st.seconds,
            st.samples_per_second() / 1e6,
            st.threads,
            part.display()
        );
        if out.stopped.is_some() {
            eprintln!("continue it with: trazo render --resume {}", part.display());
        }
    }
}

/// A part file read and understood.
struct Part {
    path: PathBuf,
    shard: Shard,
    /// Samples per pixel of the shard's share.
    share: u32,
    checkpoint: Checkpoint,
}

impl Part {
    fn read(path: &Path) -> Result<Part> {
        let checkpoint = Checkpoint::read(path)?;
        let Some(name) = checkpoint.job_value("shard") else {
            return Err(Error::file(
                path,
                "is a checkpoint of a whole render, not a shard's part: continue it with `trazo render --resume`",
            ));
        };
        let shard = super::parse_shard(name).map_err(|e| Error::file(path, format!("invalid part file: {e}")))?;
        let share = shard_passes(checkpoint.target_spp, shard)
            .map_err(|e| Error::file(path, format!("invalid part file: {e}")))?
            .iter()
            .map(|p| p.1 - p.0)
            .sum();
        if checkpoint.stats.spp > share {
            return Err(Error::file(
                path,
                format!(
                    "invalid part file: it holds {} samples per pixel of a share of {share}",
                    checkpoint.stats.spp
                ),
            ));
        }
        Ok(Part {
            path: path.to_path_buf(),
            shard,
            share,
            checkpoint,
        })
    }

    fn name(&self) -> String {
        format!("{}/{}", self.shard.index + 1, self.shard.count)
    }

    fn finished(&self) -> bool {
        self.checkpoint.stats.spp == self.share
    }

    /// What must agree between the parts of one render, by name: paths
    /// are left out, and so are the shard and the output.
    fn identity(&self) -> Vec<(&'static str, String)> {
        let c = &self.checkpoint;
        let value = |k: &str| c.job_value(k).unwrap_or("").to_string();
        let mut files: Vec<&str> = c
            .job_values("file")
            .map(|v| v.split_once(' ').map_or(v, |(hash, _)| hash))
            .collect();
        files.sort_unstable();
        let flags: Vec<&str> = c
            .job_values("arg")
            .filter(|a| a.starts_with('-') && !a.starts_with("--output=") && !a.starts_with("--shard="))
            .collect();
        // The plainest differences first, to name them.
        vec![
            ("image sizes", format!("{}×{}", c.film.width, c.film.height)),
            ("samples per pixel", c.target_spp.to_string()),
            ("auxiliary images", c.film.aovs.is_some().to_string()),
            ("scene files", value("scene_hash")),
            ("files the scenes read", files.join(" ")),
            ("trazo versions", value("trazo")),
            ("render settings", value("settings")),
            ("command-line settings", flags.join(" ")),
        ]
    }
}

/// Reads the parts and checks that they are shards of one render, no
/// shard twice; sorted by shard.
fn read_parts(paths: &[PathBuf]) -> Result<Vec<Part>> {
    let mut parts = paths.iter().map(|p| Part::read(p)).collect::<Result<Vec<_>>>()?;
    let first = &parts[0];
    let identity = first.identity();
    for p in &parts[1..] {
        if p.shard.count != first.shard.count {
            return Err(Error::file(
                &p.path,
                format!(
                    "is shard {} but {} is shard {}: the parts were split into different numbers of shards",
                    p.name(),
                    first.path.display(),
                    first.name()
                ),
            ));
        }
        if let Some(((what, _), _)) = p.identity().iter().zip(&identity).find(|(a, b)| a != b) {
            return Err(Error::file(
                &p.path,
                format!(
                    "is not a shard of the same render as {}: the {what} differ",
                    first.path.display()
                ),
            ));
        }
    }
    parts.sort_by_key(|p| p.shard.index);
    for w in parts.windows(2) {
        if w[0].shard == w[1].shard {
            let again = if w[0].path == w[1].path {
                "is given twice".to_string()
            } else {
                format!("is shard {} again (so is {})", w[1].name(), w[0].path.display())
            };
            return Err(Error::file(&w[1].path, again));
        }
    }
    Ok(parts)
}

/// The shards missing from `parts`, as `K/N` names.
fn missing(parts: &[Part]) -> Vec<String> {
    let count = parts[0].shard.count;
    (0..count)
        .filter(|k| !parts.iter().any(|p| p.shard.index == *k))
        .map(|k| format!("{}/{count}", k + 1))
        .collect()
}

/// How many of `names` there are, listed (the first few).
fn list(names: &[String]) -> String {
    const SHOWN: usize = 12;
    let mut s = names.iter().take(SHOWN).cloned().collect::<Vec<_>>().join(", ");
    if names.len() > SHOWN {
        s.push_str(&format!(" and {} more", names.len() - SHOWN));
    }
    s
}

pub(super) fn run_merge(args: MergeArgs) -> Result<()> {
    let parts = read_parts(&args.parts)?;
    let target = parts[0].checkpoint.target_spp;
    let count = parts[0].shard.count;
    let held: u32 = parts.iter().map(|p| p.checkpoint.stats.spp).sum();
    let missing = missing(&parts);
    let unfinished: Vec<String> = parts
        .iter()
        .filter(|p| !p.finished())
        .map(|p| format!("{} ({} of {} spp)", p.name(), p.checkpoint.stats.spp, p.share))
        .collect();
    if args.status {
        for p in &parts {
            let st = &p.checkpoint.stats;
            println!(
                "shard {:>7}  {:>6} of {:>6} spp  {:>9}  {:>9.1} s  {}",
                p.name(),
                st.spp,
                p.share,
                if p.finished() { "done" } else { "unfinished" },
                st.seconds,
                p.path.display()
            );
        }
        let done = parts.iter().filter(|p| p.finished()).count();
        println!(
            "{done} of {count} shards done; the parts hold {held} of {target} samples per pixel ({:.1} %){}",
            100.0 * held as f64 / target as f64,
            if missing.is_empty() {
                String::new()
            } else {
                format!("; no part of {}", list(&missing))
            }
        );
        return Ok(());
    }
    let output = args.output.expect("clap requires --output without --status");
    if (!missing.is_empty() || !unfinished.is_empty()) && !args.partial {
        let mut why = Vec::new();
        if !missing.is_empty() {
            why.push(format!("no part of shard {}", list(&missing)));
        }
        if !unfinished.is_empty() {
            why.push(format!("shard {} unfinished", list(&unfinished)));
        }
        return Err(Error::Invalid(format!(
            "{}: the parts hold {held} of {target} samples per pixel (merge them anyway with --partial, for a noisier image)",
            why.join(", ")
        )));
    }
    super::check_output(&output)?;

    let first = &parts[0].checkpoint;
    let mut film = Film::new(first.film.width, first.film.height);
    if first.film.aovs.is_some() {
        film.aovs = Some(vec![Default::default(); film.pixels.len()]);
    }
    let mut stats = RenderStats::default();
    for p in &parts {
        film.merge(&p.checkpoint.film).map_err(|e| Error::file(&p.path, e))?;
        let s = &p.checkpoint.stats;
        stats.samples += s.samples;
        stats.rays += s.rays;
        stats.invalid_samples += s.invalid_samples;
        stats.seconds += s.seconds;
        stats.spp += s.spp;
    }
    let (tonemap, exposure) = image_settings(&parts[0])?;
    // Part files from before white balance existed have none.
    let white_balance = match first.job_value("white_balance") {
        None => 0.0,
        Some(v) => v
            .parse::<f32>()
            .ok()
            .filter(|k| *k == 0.0 || crate::color::white_balance::WHITE_BALANCE_RANGE.contains(k))
            .ok_or_else(|| Error::file(&parts[0].path, format!("invalid part file: white balance {v}")))?,
    };
    // Part files from before output colour spaces existed are sRGB.
    let color_space = match first.job_value("color_space") {
        None => crate::color::space::ColorSpace::Srgb,
        Some(v) => crate::color::space::ColorSpace::from_pbrt_name(v)
            .ok_or_else(|| Error::file(&parts[0].path, format!("invalid part file: colour space {v}")))?,
    };
    film.output_transform = crate::color::white_balance::output_transform(color_space, white_balance);
    let flag = |name: &str| {
        first
            .job_values("arg")
            .find_map(|a| a.strip_prefix(&format!("--{name}=")).map(str::to_string))
    };
    let denoiser = flag("denoise").map(|d| {
        DenoiserKind::from_name(&d).ok_or_else(|| Error::file(&parts[0].path, format!("unknown denoiser {d}")))
    });
    let denoiser = denoiser.transpose()?;
    let aovs: Vec<Aov> = match flag("aov") {
        None => Vec::new(),
        Some(list) => list
            .split(',')
            .map(|a| Aov::from_name(a).ok_or_else(|| Error::file(&parts[0].path, format!("unknown image {a}"))))
            .collect::<Result<_>>()?,
    };
    if let Some(w) = super::color_space_warning(color_space, &output) {
        eprintln!("warning: {w}");
    }
    let images = ImageOutputs {
        output: &output,
        tonemap,
        exposure,
        color_space,
        denoiser,
        aovs: &aovs,
    };
    let (_, note) = images.write(&film)?;
    if !missing.is_empty() || !unfinished.is_empty() {
        eprintln!(
            "warning: --partial: the image holds {held} of {target} samples per pixel ({} shards of {count} present)",
            parts.len()
        );
    }
    eprintln!(
        "merged {} shards of {}×{} ({held} of {target} spp; {:.2} s of rendering in all) → {}",
        parts.len(),
        film.width,
        film.height,
        stats.seconds,
        images.names()
    );
    if stats.invalid_samples > 0 {
        eprintln!(
            "warning: {} samples were NaN or infinite and were dropped",
            stats.invalid_samples
        );
    }
    if let Some(note) = note {
        eprintln!("{note}");
    }
    Ok(())
}

/// The tone mapping and exposure a part's render writes its image with.
fn image_settings(part: &Part) -> Result<(Tonemap, f32)> {
    let c = &part.checkpoint;
    let tonemap = c.job_value("tonemap").and_then(Tonemap::from_name);
    let exposure = c.job_value("exposure").and_then(|v| v.parse::<f32>().ok());
    match (tonemap, exposure) {
        (Some(t), Some(e)) if e.is_finite() => Ok((t, e)),
        _ => Err(Error::file(
            &part.path,
            "invalid part file: it does not say how its image is tone-mapped",
        )),
    }
}
