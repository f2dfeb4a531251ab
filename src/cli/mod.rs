//! The `trazo` command line: maps flags onto library calls. No rendering
//! logic lives here.

mod bench;
mod farm;
mod job;

use crate::error::{Error, Result};
use crate::film::denoise::{DenoiserKind, denoise_film};
use crate::film::io::{ImageFormat, read_image, write_atomic, write_image, write_image_in};
use crate::film::{Aov, Film, plot};
use crate::render::checkpoint::checkpoint_path;
use crate::render::compare::{Budget, Contestant, compare, convergence_curves, side_by_side, table};
use crate::render::{Control, RenderOptions, RenderStats, Shard, Stop, render_controlled};
use crate::sampling::SamplerKind;
use crate::scene::{self, SceneDesc, builtin};
use crate::settings::{
    IntegratorKind, MAX_DEPTH, MAX_GATHER, MAX_IMAGE_SIDE, MAX_MLT_BOOTSTRAP, MAX_MLT_CHAINS, MAX_PHOTONS, MAX_SPP,
    PathSampling, PhotonKernel, SamplerStudy, Tonemap,
};
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Exit status for bad input: unreadable or invalid scenes, bad options,
/// unwritable outputs.
pub const EXIT_USAGE: u8 = 2;

/// Exit status of a render stopped by Ctrl-C or SIGTERM (128 + SIGINT, as
/// shells report it): the image of the passes completed and a checkpoint
/// were written, unless no pass was complete.
pub const EXIT_INTERRUPTED: u8 = 130;

/// Exit status after a second Ctrl-C or SIGTERM: trazo stopped at once and
/// wrote nothing more (files written earlier are whole).
pub const EXIT_ABORTED: u8 = 131;

#[derive(Parser, Debug)]
#[command(
    name = "trazo",
    version,
    about = "trazo: a physically based renderer (Whitted ray tracing, Monte Carlo path tracing and photon mapping)",
    long_about = None
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene to an image file.
    Render(RenderArgs),
    /// Render one scene with several algorithms and show them side by side,
    /// with a table of time and noise.
    Compare(CompareArgs),
    /// Compare two images (PNG, EXR, HDR, PFM): RMSE, relative MSE and the
    /// mean of each channel; the exit status says whether they agree (0:
    /// relative MSE at most --max-relmse, 1: above it).
    Diff(DiffArgs),
    /// Benchmarks of the renderer's kernels on your own inputs.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// Merge the part files of a sharded render (`trazo render --shard`)
    /// into its image, which is bit for bit the image of the render on one
    /// machine; or, with --status, tell how far the shards are.
    Merge(farm::MergeArgs),
}

#[derive(Args, Debug)]
struct DiffArgs {
    /// The image to judge.
    a: PathBuf,
    /// The reference.
    b: PathBuf,
    /// Write a false-colour image of the per-pixel relative error (black:
    /// none, yellow: at least --error-scale).
    #[arg(long, value_name = "FILE")]
    error_image: Option<PathBuf>,
    /// Relative error shown as full yellow in the error image.
    #[arg(long, value_name = "E", default_value_t = 0.2)]
    error_scale: f64,
    /// The images agree (exit status 0) if their relative MSE is at most
    /// this, and differ (status 1) otherwise.
    #[arg(long, value_name = "X", default_value_t = 0.01)]
    max_relmse: f64,
    /// Where the reference is an integer multiple of the image's size,
    /// average its blocks down to that size first (a box filter), to judge
    /// a small render against a large one.
    #[arg(long)]
    downscale: bool,
}

/// The scene and the settings that override what it says.
#[derive(Args, Debug)]
struct SceneArgs {
    /// Scene file: trazo .toml, Mitsuba 3 .xml, pbrt-v4 .pbrt (or .pbrt.gz),
    /// glTF .gltf/.glb, or a lone .obj/.ply model (framed with a default
    /// camera and lights). Without one, the built-in Cornell box.
    scene: Option<PathBuf>,

    /// Image width in pixels (overrides the scene).
    #[arg(long, value_name = "W", value_parser = clap::value_parser!(u32).range(1..=(MAX_IMAGE_SIDE as i64)))]
    width: Option<u32>,

    /// Image height in pixels (overrides the scene).
    #[arg(long, value_name = "H", value_parser = clap::value_parser!(u32).range(1..=(MAX_IMAGE_SIDE as i64)))]
    height: Option<u32>,

    /// Longest light path in segments from the camera: 1 shows emitters,
    /// 2 adds direct light, each more one more bounce (overrides the scene).
    #[arg(long, value_name = "D", value_parser = clap::value_parser!(u32).range(0..=(MAX_DEPTH as i64)))]
    max_depth: Option<u32>,

    /// Render media by fixed-step ray marching with steps of this length
    /// in scene units (the taught estimator, biased where a medium varies
    /// within a step) instead of delta and ratio tracking (volpath only;
    /// overrides the scene).
    #[arg(long, value_name = "LENGTH", value_parser = parse_length)]
    march_step: Option<f32>,

    /// Seed of the random numbers; the same seed gives the same image.
    #[arg(long, value_name = "S")]
    seed: Option<u64>,

    /// How samples are placed: sobol (Owen-scrambled Sobol points,
    /// stratified in every dimension of a path; the default), halton,
    /// halton-owen and halton-plain (pbrt-v4's Halton sampler, digits
    /// permuted, Owen-scrambled or as they are), stratified (every
    /// dimension in jittered strata, as pbrt-v4's), independent (random)
    /// or center (one ray through each pixel centre: aliasing).
    #[arg(long, value_name = "KIND", value_parser = SamplerKind::NAMES)]
    sampler: Option<String>,

    /// Tone mapping for PNG output.
    #[arg(long, value_name = "OP", value_parser = Tonemap::NAMES)]
    tonemap: Option<String>,

    /// Exposure compensation in stops (+1 doubles the brightness).
    #[arg(long, value_name = "EV", allow_negative_numbers = true)]
    exposure: Option<f32>,

    /// Worker threads (default: all cores). The image does not depend on it.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,

    /// Print nothing but errors and warnings.
    #[arg(short, long, conflicts_with = "verbose")]
    quiet: bool,

    /// Print scene and acceleration-structure statistics.
    #[arg(short, long)]
    verbose: bool,

    /// Photons emitted for photon mapping's global map (overrides the scene).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=(MAX_PHOTONS as i64)))]
    photons: Option<u32>,

    /// Photons per SPPM iteration; 0: one per pixel.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=(MAX_PHOTONS as i64)))]
    sppm_photons: Option<u32>,

    /// Photons emitted for photon mapping's caustic map.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=(MAX_PHOTONS as i64)))]
    caustic_photons: Option<u32>,

    /// Photons in each radiance estimate (the k nearest).
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..=(MAX_GATHER as i64)))]
    photon_gather: Option<u32>,

    /// Largest photon search radius (SPPM: the initial radius), in scene
    /// units; 0 chooses two pixel footprints at the surfaces the camera
    /// sees.
    #[arg(long, value_name = "R")]
    photon_radius: Option<f32>,

    /// Final-gather rays per camera sample for photon mapping; 0 reads the
    /// global map directly.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=(MAX_GATHER as i64)))]
    final_gather: Option<u32>,

    /// Density estimation kernel for photon mapping.
    #[arg(long, value_name = "NAME", value_parser = PhotonKernel::NAMES)]
    photon_kernel: Option<String>,

    /// Metropolis light transport: bootstrap paths that estimate the
    /// image's brightness and start the chains (per path length for mlt).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=(MAX_MLT_BOOTSTRAP as i64)))]
    mlt_bootstrap: Option<u32>,

    /// Metropolis light transport: Markov chains (at most one per pixel).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=(MAX_MLT_CHAINS as i64)))]
    mlt_chains: Option<u32>,

    /// Metropolis light transport: probability that a mutation draws a new
    /// path independently of the current one (0–1).
    #[arg(long, value_name = "P")]
    mlt_large_step: Option<f32>,

    /// Metropolis light transport: deviation of a small step's
    /// perturbation of each random number.
    #[arg(long, value_name = "S")]
    mlt_sigma: Option<f32>,

    /// Set a scene parameter: a Mitsuba `$name` default (may be repeated).
    #[arg(short = 'D', value_name = "NAME=VALUE", value_parser = parse_define)]
    defines: Vec<(String, String)>,
}

fn parse_define(s: &str) -> std::result::Result<(String, String), String> {
    let (name, value) = s
        .split_once('=')
        .ok_or_else(|| format!("expected NAME=VALUE, got \"{s}\""))?;
    if name.is_empty() {
        return Err(format!("empty parameter name in \"{s}\""));
    }
    Ok((name.to_string(), value.to_string()))
}

#[derive(Args, Debug)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,

    /// Output image; the format follows the extension: .png (8-bit sRGB,
    /// tone-mapped), .exr, .hdr or .pfm (linear float). Default: the file
    /// a pbrt-v4 scene's Film names ("filename"), else the scene's name
    /// with .png, in the current folder. With --shard, the
    /// part file (NAME.trazo-part; default: the scene's name with
    /// .shard-K-of-N.trazo-part).
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,

    /// Render the K-th of N shares of the samples (K from 1 to N), for a
    /// render farm: every pixel gets its share, and the output is a part
    /// file that `trazo merge` combines with the other shards' into the
    /// image of the whole render, bit for bit. Not with --time-limit.
    #[arg(long, value_name = "K/N", value_parser = parse_shard, conflicts_with = "time_limit")]
    shard: Option<Shard>,

    /// Samples per pixel (overrides the scene).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=(MAX_SPP as i64)))]
    spp: Option<u32>,

    /// Rendering algorithm (overrides the scene): whitted, path, photon
    /// (Jensen's photon mapping), sppm (stochastic progressive photon
    /// mapping; --spp is then the number of iterations), volpath (media),
    /// light (light tracing: paths from the lights connected to the
    /// camera; --spp is the number of light paths per pixel), bdpt
    /// (bidirectional path tracing; --spp camera and light subpaths per
    /// pixel), mlt (multiplexed Metropolis light transport over BDPT's
    /// strategies, as pbrt-v4's mlt; --spp mutations per pixel), pssmlt
    /// (primary-sample-space Metropolis over whole BDPT samples) or ao
    /// (ambient occlusion).
    #[arg(long, value_name = "NAME", value_parser = IntegratorKind::NAMES)]
    integrator: Option<String>,

    /// The path tracer's estimator: uniform or cosine hemisphere sampling,
    /// BSDF importance sampling, next-event estimation without MIS and
    /// BSDF sampling (nee) or uniform directions (nee-uniform) onward, or
    /// next-event estimation with multiple importance sampling (mis).
    #[arg(long, value_name = "NAME", value_parser = PathSampling::NAMES)]
    sampling: Option<String>,

    /// Denoise the image, guided by the albedo and normal images: with
    /// Intel Open Image Denoise if its library is found (see
    /// tools/oidn/setup), else with the built-in à-trous filter;
    /// --denoise=oidn or --denoise=atrous to choose. The noisy image is
    /// kept as OUTPUT-NAME.noisy.<ext>.
    #[arg(long, value_name = "KIND", num_args = 0..=1, require_equals = true, default_missing_value = "auto", value_parser = DenoiserKind::NAMES)]
    denoise: Option<String>,

    /// Also write auxiliary images (comma-separated: albedo, normal,
    /// depth, steps) as OUTPUT-NAME.<aov>.exr next to the output (steps:
    /// sphere-tracing steps per camera ray, also as a heat map
    /// OUTPUT-NAME.steps.png).
    #[arg(long, value_name = "LIST", value_delimiter = ',', value_parser = Aov::NAMES)]
    aov: Vec<String>,

    /// With --integrator bdpt, also write each strategy's image for paths
    /// of up to 5 segments, as pbrt-v4 does: OUTPUT-NAME.bdpt_dBB_sSS_tTT.exr
    /// (weighted by multiple importance: they sum to the image) and
    /// …_unweighted.exr (the strategy alone), BB the bounces.
    #[arg(long)]
    bdpt_strategies: bool,

    /// Stop after this many seconds (from the start of the command) and
    /// write the image of the passes completed; without --spp, render the
    /// scene file's samples per pixel if it states them, else as many as
    /// the time allows. A checkpoint is kept so that the render can be
    /// continued with --resume (a render without --spp continues for the
    /// same time again, unless --time-limit is given with --resume).
    #[arg(long, value_name = "SECS", value_parser = parse_seconds)]
    time_limit: Option<f64>,

    /// Start afresh where OUTPUT.trazo-checkpoint holds an unfinished
    /// render, deleting it (without this, such a render is refused: continue
    /// it with --resume).
    #[arg(long)]
    restart: bool,

    /// Write a checkpoint (OUTPUT.trazo-checkpoint) at the end of a pass
    /// whenever this many seconds have passed since the last one, so that a
    /// crash or power loss loses at most that much work.
    #[arg(long, value_name = "SECS", value_parser = parse_seconds)]
    checkpoint_every: Option<f64>,

    /// Continue an interrupted render from its checkpoint, which holds the
    /// scene, the output and every setting; the image is the same, bit for
    /// bit, as if it had never stopped. Only --threads, --time-limit,
    /// --checkpoint-every, --max-memory, --display-server, --quiet and
    /// --verbose may be given with it.
    #[arg(long, value_name = "CHECKPOINT", conflicts_with_all = [
        "scene", "width", "height", "max_depth", "march_step", "seed", "sampler", "tonemap", "exposure", "defines",
        "output", "spp", "integrator", "sampling", "aov", "denoise", "photons", "caustic_photons",
        "sppm_photons", "photon_gather", "photon_radius", "final_gather", "photon_kernel", "restart", "shard",
        "mlt_bootstrap", "mlt_chains", "mlt_large_step", "mlt_sigma",
    ])]
    resume: Option<PathBuf>,

    /// Show the render as it progresses in the tev image viewer listening
    /// at HOST:PORT (tev's default is 127.0.0.1:14158): the image after
    /// each pass, the auxiliary images as channel groups, and at the end
    /// the image written. A viewer that is not there or goes away does not
    /// stop the render (a warning; trazo tries again after each pass).
    #[arg(long, value_name = "HOST:PORT", value_parser = parse_host_port)]
    display_server: Option<String>,

    /// Refuse to start a render whose estimated memory (film, auxiliary
    /// images, geometry and BVH, textures) exceeds this size: a number of
    /// bytes with K, M, G or T (e.g. 512M, 16G). Default: 90% of the
    /// machine's memory.
    #[arg(long, value_name = "SIZE", value_parser = scene::memory::parse_size)]
    max_memory: Option<u64>,
}

fn parse_host_port(s: &str) -> std::result::Result<String, String> {
    match s.rsplit_once(':') {
        Some((host, port)) if !host.is_empty() && port.parse::<u16>().is_ok_and(|p| p > 0) => Ok(s.to_string()),
        _ => Err(format!(
            "expected HOST:PORT (tev listens on 127.0.0.1:14158), got \"{s}\""
        )),
    }
}

fn parse_shard(s: &str) -> std::result::Result<Shard, String> {
    let bad = || format!("expected K/N with 1 ≤ K ≤ N (the K-th of N shards), got \"{s}\"");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (k, n): (u32, u32) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if k == 0 || k > n {
        return Err(bad());
    }
    Ok(Shard { index: k - 1, count: n })
}

fn parse_length(s: &str) -> std::result::Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("expected a length > 0, got \"{s}\"")),
    }
}

fn parse_seconds(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("expected a number of seconds ≥ 0, got \"{s}\"")),
    }
}

#[derive(Args, Debug)]
struct CompareArgs {
    #[command(flatten)]
    scene: SceneArgs,

    /// The contestants, comma-separated: whitted, path, path:uniform,
    /// path:cosine, path:bsdf, path:mis, photon, sppm, volpath (media by
    /// tracking), volpath:march=STEP (by ray marching), light, bdpt, mlt,
    /// pssmlt, ao; a suffix +denoise,
    /// +atrous or +oidn denoises a contestant's image (e.g. path:mis+denoise).
    #[arg(long, value_name = "LIST", default_value = "whitted,path:uniform,path:mis")]
    integrators: String,

    /// Samples per pixel for every contestant (equal samples); default: the
    /// scene's, as `trazo render` renders it. With --time, the most samples
    /// per pixel.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=(MAX_SPP as i64)))]
    spp: Option<u32>,

    /// Seconds of rendering for every contestant (equal time).
    #[arg(long, value_name = "SECONDS")]
    time: Option<f64>,

    /// A converged image of the same scene: the table then reports each
    /// contestant's relative MSE against it, and a convergence plot (error
    /// against time, log–log) is written beside the image. The plot's
    /// points are extra renders at 1/2, 1/4, … 1/32 of the budget, so the
    /// comparison takes about twice as long.
    #[arg(long, value_name = "FILE")]
    reference: Option<PathBuf>,

    /// The side-by-side image.
    #[arg(short, long, value_name = "FILE", default_value = "compare.png")]
    output: PathBuf,

    /// The convergence plot (with --reference), written as FILE.svg and
    /// FILE.png [default: the image's name with "-convergence"].
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
}

/// Runs the command line; the exit status is 0 on success and 2 on any
/// error caused by the input.
pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { EXIT_USAGE } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    let result = match cli.command {
        Command::Render(args) => run_render(args),
        Command::Compare(args) => run_compare(args).map(|()| ExitCode::SUCCESS),
        Command::Diff(args) => return run_diff(args),
        Command::Bench(command) => bench::run(command).map(|()| ExitCode::SUCCESS),
        Command::Merge(args) => farm::run_merge(args).map(|()| ExitCode::SUCCESS),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            print_error(&e);
            ExitCode::from(EXIT_USAGE)
        }
    }
}

/// Prints an error on stderr, after the warnings given before it: a run
/// that fails still reports every problem it found.
fn print_error(e: &Error) {
    for w in e.warnings() {
        eprintln!("warning: {w}");
    }
    eprintln!("error: {e}");
}

/// `e` with the warnings of the scene description loaded before it, unless
/// it carries warnings already (a stage that gives its own includes the
/// description's).
fn after_loading(e: Error, desc: &SceneDesc) -> Error {
    if e.warnings().is_empty() {
        e.with_warnings(desc.warnings.clone())
    } else {
        e
    }
}

impl SceneArgs {
    /// Loads the scene (or the built-in one) and applies the overrides.
    fn load(&self) -> Result<SceneDesc> {
        let mut desc = match &self.scene {
            Some(path) => scene::load(path, &self.defines)?,
            None => {
                let mut desc = builtin::cornell_box();
                for (name, _) in &self.defines {
                    desc.warnings.push(format!(
                        "-D {name}: the built-in scene has no parameters; the definition is not used"
                    ));
                }
                desc
            }
        };
        if desc.settings.crop.is_some() && (self.width.is_some() || self.height.is_some()) {
            desc.settings.crop = None;
            desc.warnings
                .push("--width/--height set the size of the whole image: the scene's crop window is not used".into());
        }
        let s = &mut desc.settings;
        if let Some(v) = self.width {
            s.width = v;
        }
        if let Some(v) = self.height {
            s.height = v;
        }
        if let Some(v) = self.march_step {
            s.march_step = Some(v);
        }
        if let Some(v) = self.max_depth {
            s.max_depth = v;
        }
        if let Some(v) = self.seed {
            s.seed = v;
        }
        if let Some(v) = &self.sampler {
            s.sampler = SamplerKind::from_name(v).expect("clap checked the value");
        }
        if let Some(v) = &self.tonemap {
            s.tonemap = Tonemap::from_name(v).expect("clap checked the value");
        }
        if let Some(v) = self.exposure {
            s.exposure = v;
        }
        if let Some(v) = self.photons {
            s.photon.photons = v;
        }
        if let Some(v) = self.sppm_photons {
            s.photon.sppm_photons = v;
        }
        if let Some(v) = self.caustic_photons {
            s.photon.caustic_photons = v;
        }
        if let Some(v) = self.photon_gather {
            s.photon.gather = v;
        }
        if let Some(v) = self.photon_radius {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Invalid(format!(
                    "--photon-radius must be 0 (automatic) or a positive number, got {v}"
                )));
            }
            s.photon.radius = v;
        }
        if let Some(v) = self.final_gather {
            s.photon.final_gather = v;
        }
        if let Some(v) = &self.photon_kernel {
            s.photon.kernel = PhotonKernel::from_name(v).expect("clap checked the value");
        }
        if let Some(v) = self.mlt_bootstrap {
            s.mlt.bootstrap = v;
        }
        if let Some(v) = self.mlt_chains {
            s.mlt.chains = v;
        }
        if let Some(v) = self.mlt_large_step {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::Invalid(format!(
                    "--mlt-large-step must be a probability between 0 and 1, got {v}"
                )));
            }
            s.mlt.large_step_probability = v;
        }
        if let Some(v) = self.mlt_sigma {
            if !(v > 0.0 && v.is_finite()) {
                return Err(Error::Invalid(format!(
                    "--mlt-sigma must be a positive number, got {v}"
                )));
            }
            s.mlt.sigma = v;
        }
        Ok(desc)
    }

    fn options(&self) -> RenderOptions {
        RenderOptions {
            threads: self.threads,
            progress: !self.quiet,
            ..RenderOptions::default()
        }
    }
}

fn default_output(scene: Option<&Path>) -> PathBuf {
    // `scene.pbrt.gz` → `scene.png`.
    let stem = scene
        .map(|p| {
            if crate::files::is_gzip_name(p) {
                p.with_extension("")
            } else {
                p.to_path_buf()
            }
        })
        .as_deref()
        .and_then(Path::file_stem)
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "cornell-box".into());
    PathBuf::from(format!("{stem}.png"))
}

/// Fails early, before a long render, if the output cannot be written.
fn check_output(path: &Path) -> Result<()> {
    ImageFormat::from_path(path)?;
    check_writable(path)
}

/// Fails early if a file cannot be created at `path`.
fn check_writable(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::file(path, "cannot write: this is a folder"));
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(Error::file(
            path,
            format!("cannot write: the folder {} does not exist", dir.display()),
        ));
    }
    // Probe with a temporary file, so that permissions are checked too.
    let probe = dir.join(format!(".trazo-write-test-{}", std::process::id()));
    match std::fs::File::create(&probe) {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => Err(Error::file(path, format!("cannot write in {}: {e}", dir.display()))),
    }
}

/// `out.png` → `out.noisy.png`.
fn sibling_path(output: &Path, tag: &str) -> PathBuf {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = output
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    output.with_file_name(format!("{stem}.{tag}{ext}"))
}

/// `out.png` → `out.NAME.exr`, for an image an algorithm makes besides
/// the film ([`crate::render::RenderOutput::extra`]).
fn extra_path(output: &Path, name: &str) -> PathBuf {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    output.with_file_name(format!("{stem}.{name}.exr"))
}

/// `out.png` → `out.albedo.exr`.
fn aov_path(output: &Path, aov: Aov) -> PathBuf {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    output.with_file_name(format!("{stem}.{}.exr", aov.name()))
}

fn print_scene_stats(scene: &scene::Scene, load_seconds: f64) {
    let g = scene.geometry.stats();
    eprintln!(
        "scene: {} shapes, {} mesh objects, {} instances, {} triangles, {} lights, {} materials",
        scene.geometry.shapes.len(),
        scene.geometry.mesh_objects.len(),
        scene.geometry.instances.len(),
        g.triangles,
        scene.lights.len(),
        scene.materials.len() - 1,
    );
    eprintln!(
        "bvh: {} top-level primitives, {} nodes, {} leaf blocks, {:.1} MiB (meshes {:.1} MiB), built in {:.3} s",
        g.primitives,
        g.nodes,
        g.leaf_blocks,
        g.bvh_bytes as f64 / (1 << 20) as f64,
        g.mesh_bytes as f64 / (1 << 20) as f64,
        g.seconds,
    );
    eprintln!("load and build: {load_seconds:.3} s");
}

/// The output `output` and its checkpoint file, checked before anything is
/// written: the output can be written, and no unfinished render of it is
/// there unless this render resumes or restarts it (`--restart` replaces
/// it). Temporary files that an earlier render to them left are removed.
fn prepare_output(args: &RenderArgs, output: PathBuf, resuming: bool) -> Result<(PathBuf, PathBuf)> {
    // A shard's part file is its checkpoint too: unfinished, it is resumed.
    let checkpoint_file = match args.shard {
        None => {
            check_output(&output)?;
            checkpoint_path(&output)
        }
        Some(_) => {
            farm::check_part_name(&output)?;
            check_writable(&output)?;
            output.clone()
        }
    };
    if !resuming && checkpoint_file.is_file() {
        if !args.restart {
            // Refused before anything is written: the checkpoint may hold
            // hours of work.
            let what = match args.shard {
                None => format!("an unfinished render of {}", output.display()),
                Some(_) => "a shard's part of a render".to_string(),
            };
            return Err(Error::file(
                &checkpoint_file,
                format!(
                    "holds {what}: continue it with `trazo render --resume {}`, or start afresh with --restart (which deletes it)",
                    checkpoint_file.display()
                ),
            ));
        }
        eprintln!(
            "warning: --restart: the unfinished render in {} is replaced by this one",
            checkpoint_file.display()
        );
    }
    // Temporary files of an earlier render to this output killed outright.
    crate::film::io::remove_stale_temp_files(&output);
    crate::film::io::remove_stale_temp_files(&checkpoint_file);
    Ok((output, checkpoint_file))
}

/// "file:line:col: " where the scene set the setting `key`, or nothing: the
/// start of a warning about it.
fn place_of(desc: &SceneDesc, key: &str) -> String {
    desc.settings_locs.key(key).map_or(String::new(), |l| format!("{l}: "))
}

/// Runs the sampler study a scene asks for instead of a render (pbrt-v4's
/// `Integrator "function"`) and writes its text file: the study's
/// `filename`, else -o, else `<function>-mse.txt`, as pbrt-v4 names it.
fn run_sampler_study(args: &RenderArgs, desc: SceneDesc, study: SamplerStudy, resuming: bool) -> Result<ExitCode> {
    use std::io::Write;
    let at = desc.settings_locs.key("integrator");
    let refuse = |what: &str| {
        let e = Error::scene(
            at.clone(),
            "Integrator \"function\"",
            format!("is a sampler study: {what}"),
        );
        after_loading(e, &desc)
    };
    if resuming {
        return Err(refuse("it writes no checkpoint to resume"));
    }
    if args.shard.is_some() {
        return Err(refuse(
            "it is one quick computation, not split among machines (leave out --shard)",
        ));
    }
    if !args.aov.is_empty() || args.denoise.is_some() || args.bdpt_strategies {
        return Err(refuse(
            "it renders no image for auxiliary images or a denoiser (--integrator path renders the scene)",
        ));
    }
    for w in &desc.warnings {
        eprintln!("warning: {w}");
    }
    let output = match (&study.output, &args.output) {
        (Some(named), Some(o)) => {
            eprintln!(
                "warning: {}the study's \"string filename\" \"{}\" is overridden by -o {}",
                place_of(&desc, "integrator"),
                named.display(),
                o.display()
            );
            o.clone()
        }
        (_, Some(o)) => o.clone(),
        (Some(named), None) => named.clone(),
        (None, None) => PathBuf::from(format!("{}-mse.txt", study.function.name())),
    };
    check_writable(&output)?;
    if let Some(image) = &study.image {
        check_output(image).map_err(|e| refuse(&format!("its \"imagefilename\": {e}")))?;
    }
    let mut settings = desc.settings.clone();
    if let Some(v) = args.spp {
        settings.spp = v;
    }
    let report = crate::integrator::function::run(&study, &settings);
    let text = report.to_text();
    write_atomic(&output, |f| f.write_all(text.as_bytes()).map_err(|e| e.to_string()))?;
    if let Some(image) = &study.image {
        let img =
            crate::integrator::function::function_image(study.function, settings.width, settings.height, settings.seed);
        write_image(image, &img, Tonemap::Clamp, 0.0)?;
    }
    if let Some(w) = report.bias_warning() {
        eprintln!("warning: {w}");
    }
    if !args.scene.quiet {
        eprintln!(
            "sampler study of \"{}\" with the {} sampler, {}×{} pixels, up to {} spp: {} sample counts written to {}",
            study.function.name(),
            settings.sampler.name(),
            settings.width,
            settings.height,
            settings.spp,
            report.errors.len(),
            output.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn run_render(args: RenderArgs) -> Result<ExitCode> {
    let started = Instant::now();
    // Ctrl-C and SIGTERM set this flag (the render then stops after the
    // work in flight); a second one ends the process at once.
    let interrupt = job::install_interrupt_handler()?;
    let (args, resume) = match &args.resume {
        Some(path) => {
            let (stored, checkpoint) = job::resume_args(path, &args)?;
            (stored, Some((path.clone(), checkpoint)))
        }
        None => (args, None),
    };
    // A pbrt-v4 scene names its image (`Film` "filename"), or asks for a
    // sampler study that writes text instead: its output is known, and
    // checked, once the scene is read.
    let scene_names_output =
        args.shard.is_none() && args.scene.scene.as_deref().is_some_and(scene::may_name_its_output);
    let prepared = if scene_names_output {
        None
    } else {
        let output = match (&args.output, args.shard) {
            (Some(o), _) => o.clone(),
            (None, None) => default_output(args.scene.scene.as_deref()),
            (None, Some(shard)) => farm::default_part(args.scene.scene.as_deref(), shard),
        };
        Some(prepare_output(&args, output, resume.is_some())?)
    };
    let aovs: Vec<Aov> = args
        .aov
        .iter()
        .map(|a| Aov::from_name(a).expect("clap checked the value"))
        .collect();

    let load_start = Instant::now();
    // Every file read while loading goes into the checkpoint, so that a
    // resume notices an edited mesh or texture, not only the scene file.
    let (desc, mut files) = crate::files::record_file_reads(|| args.scene.load());
    let mut desc = desc?;
    if let Some(study) = desc.sampler_study.take() {
        // The command line's integrator renders the scene instead.
        if args.integrator.is_none() {
            return run_sampler_study(&args, desc, study, resume.is_some());
        }
    }
    let (output, checkpoint_file) = match prepared {
        Some(p) => p,
        None => {
            let output = match (&args.output, &desc.output) {
                (Some(o), _) => o.clone(),
                (None, Some(named)) => {
                    // A file the scene names that trazo cannot write is
                    // the scene's error, at its parameter.
                    check_output(named).map_err(|e| {
                        let e = Error::scene(
                            desc.settings_locs.key("output"),
                            "filename",
                            format!("{e} (the Film's file; name another with -o)"),
                        );
                        after_loading(e, &desc)
                    })?;
                    named.clone()
                }
                // A G-buffer is written to OpenEXR (pbrt-v4's default name
                // is "pbrt.exr").
                (None, None) if desc.settings.gbuffer.is_some() => {
                    default_output(args.scene.scene.as_deref()).with_extension("exr")
                }
                (None, None) => default_output(args.scene.scene.as_deref()),
            };
            if desc.settings.gbuffer.is_some() && ImageFormat::from_path(&output).ok() != Some(ImageFormat::Exr) {
                // As pbrt-v4 refuses it.
                let e = Error::scene(
                    desc.settings_locs.key("gbuffer"),
                    "Film \"gbuffer\"",
                    format!("writes OpenEXR files only, not {}: name an .exr file", output.display()),
                );
                return Err(after_loading(e, &desc));
            }
            prepare_output(&args, output, resume.is_some()).map_err(|e| after_loading(e, &desc))?
        }
    };
    if let (Some(named), Some(o)) = (&desc.output, &args.output) {
        // As pbrt-v4 warns when --outfile overrides the scene's.
        let at = place_of(&desc, "output");
        desc.warnings.push(format!(
            "{at}the Film's \"string filename\" \"{}\" is overridden by -o {}",
            named.display(),
            o.display()
        ));
    }
    match (args.spp, args.time_limit) {
        (Some(v), _) => desc.settings.spp = v,
        // A time limit alone: as many samples as the time allows, or as the
        // scene file asks for if it says (the built-in scene does not ask).
        (None, Some(_)) if args.scene.scene.is_none() || !desc.sets_spp() => desc.settings.spp = MAX_SPP,
        _ => {}
    }
    if let Some(v) = &args.integrator {
        desc.settings.integrator = IntegratorKind::from_name(v).expect("clap checked the value");
    }
    if let Some(v) = &args.sampling {
        desc.settings.sampling = PathSampling::from_name(v).expect("clap checked the value");
    }
    if args.bdpt_strategies {
        if desc.settings.integrator != IntegratorKind::Bdpt {
            return Err(after_loading(
                Error::Invalid(format!(
                    "--bdpt-strategies needs the bdpt integrator (the scene's is {}): add --integrator bdpt",
                    desc.settings.integrator.name()
                )),
                &desc,
            ));
        }
        desc.settings.bdpt_strategies = true;
    }
    // The progressive algorithms' states are checkpointed (SPPM's
    // per-pixel statistics, the splat sums, MLT's chains), but each of
    // their iterations renders the whole image: none is sharded.
    let progressive = desc.settings.integrator == IntegratorKind::Sppm || desc.settings.integrator.splats_light_paths();
    if progressive && desc.settings.gbuffer.is_some() {
        // pbrt-v4's integrators of this kind give its G-buffer no surfaces
        // either, and it writes those channels as zeros.
        let at = place_of(&desc, "gbuffer");
        desc.warnings.push(format!(
            "{at}Film \"gbuffer\" is unsupported with the {} integrator, which records no G-buffer: the image alone is written",
            desc.settings.integrator.name()
        ));
        desc.settings.gbuffer = None;
    }
    if progressive && args.shard.is_some() {
        return Err(after_loading(
            Error::Invalid(crate::integrator::NOT_SHARDABLE.into()),
            &desc,
        ));
    }
    let limits = scene::BuildLimits {
        max_memory: Some(args.max_memory.unwrap_or_else(scene::memory::default_limit)),
        aovs: !aovs.is_empty(),
    };
    let (scene, built_from) = crate::files::record_file_reads(|| scene::build_limited(&desc, &limits));
    let scene = scene.map_err(|e| after_loading(e, &desc))?;
    files.extend(built_from);
    files.sort();
    files.dedup();
    let load_seconds = load_start.elapsed().as_secs_f64();
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(w) = color_space_warning(scene.settings.color_space, &output) {
        eprintln!("warning: {w}");
    }
    if args.scene.verbose {
        print_scene_stats(&scene, load_seconds);
    }
    let job = job::Job::new(&args, &output, &desc, &scene, &files)?;
    if let Some((path, checkpoint)) = &resume {
        job.check_resume(path, checkpoint)?;
    }

    let denoiser = args
        .denoise
        .as_deref()
        .map(|d| DenoiserKind::from_name(d).expect("clap checked the value"));
    if denoiser == Some(DenoiserKind::Oidn) {
        // Fail before rendering, not after.
        crate::film::denoise::oidn::Library::find()?;
    }
    let s = scene.settings.clone();
    let options = RenderOptions {
        aovs: !aovs.is_empty() || denoiser.is_some(),
        shard: args.shard,
        ..args.scene.options()
    };
    let mut save = |film: &Film, stats: &RenderStats, state: &[u8]| {
        if let Err(e) = job.checkpoint(film, stats, state).write(&checkpoint_file) {
            eprintln!("warning: {e}");
        }
    };
    let display = args.display_server.as_deref().map(|address| {
        let name = output
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        crate::film::display::Display::start(address, &name)
    });
    // At most a few frames a second, and none while one is being sent.
    let mut last_frame: Option<Instant> = None;
    let mut show = |film: &Film, _: &RenderStats| {
        let Some(d) = &display else { return };
        if d.ready() && last_frame.is_none_or(|t| t.elapsed() >= Duration::from_millis(250)) {
            d.offer(display_frame(film, &film.to_image(), s.exposure, &aovs));
            last_frame = Some(Instant::now());
        }
    };
    let (resume, resume_state) = match resume {
        Some((_, c)) => (Some((c.film, c.stats)), c.state),
        None => (None, Vec::new()),
    };
    let mut control = Control {
        resume,
        resume_state,
        cancel: Some(interrupt.as_ref()),
        deadline: args.time_limit.map(|t| started + Duration::from_secs_f64(t)),
        checkpoint_every: args.checkpoint_every.map(Duration::from_secs_f64),
        on_checkpoint: Some(&mut save),
        on_pass: Some(&mut show),
    };
    let out = render_controlled(&scene, &options, &mut control);
    drop(control);
    let out = out?;
    let st = &out.stats;
    if st.spp == 0 {
        eprintln!("interrupted before the first pass was complete: nothing was written");
        return Ok(ExitCode::from(EXIT_INTERRUPTED));
    }
    if let Some(shard) = args.shard {
        job.checkpoint(&out.film, st, &[]).write(&output)?;
        if let Some(d) = display {
            d.finish(display_frame(&out.film, &out.film.to_image(), s.exposure, &aovs));
        }
        farm::report_shard(shard, &output, &s, &out, args.scene.quiet);
        return Ok(match out.stopped {
            Some(Stop::Interrupted) => ExitCode::from(EXIT_INTERRUPTED),
            _ => ExitCode::SUCCESS,
        });
    }
    let images = ImageOutputs {
        output: &output,
        tonemap: s.tonemap,
        exposure: s.exposure,
        color_space: s.color_space,
        denoiser,
        aovs: &aovs,
    };
    let (image, denoise_note) = images.write(&out.film)?;
    for (name, film) in &out.extra {
        write_image(&extra_path(&output, name), &film.to_image(), s.tonemap, 0.0)?;
    }
    if let Some(d) = display {
        // The viewer ends with the image written (denoised, if it was).
        d.finish(display_frame(&out.film, &image, s.exposure, &aovs));
    }
    match out.stopped {
        Some(_) => job.checkpoint(&out.film, st, &out.state).write(&checkpoint_file)?,
        _ => {
            // The render is complete (or cannot be continued): a
            // checkpoint of an earlier render to this output is stale.
            if checkpoint_file.is_file() {
                std::fs::remove_file(&checkpoint_file)
                    .map_err(|e| Error::file(&checkpoint_file, format!("cannot remove the stale checkpoint: {e}")))?;
            }
        }
    }
    for s in &scene.geometry.shapes {
        if let crate::geometry::Shape::Implicit(f) = &s.shape {
            let n = f.give_ups();
            if n > 0 {
                eprintln!(
                    "warning: {}: the root search gave up on {n} rays after {} interval evaluations each ({:.1e} of the rays traced; they pass through the shape there); raise the shape's max_evaluations",
                    f.origin().unwrap_or("an implicit surface"),
                    f.max_evaluations(),
                    n as f64 / st.rays.max(1) as f64
                );
            }
        }
        if let crate::geometry::Shape::Sdf(f) = &s.shape {
            let n = f.step_cap_hits();
            if n > 0 {
                eprintln!(
                    "warning: {}: sphere tracing gave up on {n} rays after {} steps each ({:.1e} of the rays traced; they pass through the shape there); raise the shape's max_steps or epsilon",
                    f.origin().unwrap_or("a distance-function shape"),
                    f.max_steps(),
                    n as f64 / st.rays.max(1) as f64
                );
            }
        }
    }
    if st.invalid_samples > 0 {
        eprintln!(
            "warning: {} samples were NaN or infinite and were dropped{}",
            st.invalid_samples,
            if args.scene.verbose {
                ":"
            } else {
                " (--verbose shows where)"
            }
        );
        if args.scene.verbose {
            for e in &st.invalid_examples {
                eprintln!(
                    "  pixel ({}, {}) sample {}: ({}, {}, {})",
                    e.x, e.y, e.index, e.value.x, e.value.y, e.value.z
                );
            }
            if st.invalid_samples > st.invalid_examples.len() as u64 {
                eprintln!("  … and {} more", st.invalid_samples - st.invalid_examples.len() as u64);
            }
        }
    }
    let spp = if st.spp == s.spp {
        format!("{} spp", s.spp)
    } else if s.spp == MAX_SPP {
        format!("{} spp", st.spp)
    } else {
        format!("{} of {} spp", st.spp, s.spp)
    };
    if !args.scene.quiet || out.stopped == Some(Stop::Interrupted) {
        let integrator = match s.integrator {
            IntegratorKind::Path => format!("path:{}", s.sampling.name()),
            other => other.name().to_string(),
        };
        let why = match out.stopped {
            Some(Stop::Interrupted) => "interrupted: ",
            Some(Stop::TimeLimit) => "time limit reached: ",
            None => "",
        };
        eprintln!(
            "{why}rendered {}×{} at {spp} with {integrator} in {:.2} s ({:.2} M samples/s, {:.2} M rays/s, {} threads) → {}",
            s.width,
            s.height,
            st.seconds,
            st.samples_per_second() / 1e6,
            st.rays_per_second() / 1e6,
            st.threads,
            images.names()
        );
        if let Some(note) = denoise_note {
            eprintln!("{note}");
        }
        if let (Some((first, _)), Some((last, _))) = (out.extra.first(), out.extra.last()) {
            eprintln!(
                "{} images of the strategies: {} … {}",
                out.extra.len(),
                extra_path(&output, first).display(),
                extra_path(&output, last).display()
            );
        }
        if out.stopped.is_some() {
            eprintln!(
                "checkpoint → {} (continue with: trazo render --resume {})",
                checkpoint_file.display(),
                checkpoint_file.display()
            );
        }
        if st.photons_emitted > 0 {
            eprintln!(
                "photons: {} emitted in {:.2} s ({:.2} M photons/s, tracing and map building)",
                st.photons_emitted,
                st.photon_seconds,
                st.photons_emitted as f64 / st.photon_seconds.max(1e-9) / 1e6
            );
        }
    }
    Ok(match out.stopped {
        Some(Stop::Interrupted) => ExitCode::from(EXIT_INTERRUPTED),
        _ => ExitCode::SUCCESS,
    })
}

/// What the live preview shows: `image`, and the auxiliary images asked
/// for as channel groups named after them.
fn display_frame(film: &Film, image: &crate::film::Image, exposure: f32, aovs: &[Aov]) -> crate::film::display::Frame {
    // The exposure, as the float image files get it.
    let scale = crate::film::io::exposure_scale(exposure);
    let scaled;
    let image = if scale == 1.0 {
        image
    } else {
        scaled = crate::film::Image {
            pixels: image.pixels.iter().map(|p| *p * scale).collect(),
            ..image.clone()
        };
        &scaled
    };
    let extra: Vec<(Aov, crate::film::Image)> = aovs
        .iter()
        .filter_map(|a| film.aov_image(*a).map(|img| (*a, img)))
        .collect();
    let mut layers: Vec<(&str, &[crate::Rgb], usize)> = vec![("", &image.pixels, 3)];
    for (aov, img) in &extra {
        let n = if matches!(aov, Aov::Depth | Aov::Steps) { 1 } else { 3 };
        layers.push((aov.name(), &img.pixels, n));
    }
    crate::film::display::Frame::new(image.width, image.height, &layers)
}

/// The images a render writes from its film: the image (denoised, with
/// the noisy one beside it, if asked) and the auxiliary images.
/// What to tell the user whose image in `space` goes to `output`, a
/// format that cannot record a colour space.
pub(crate) fn color_space_warning(space: crate::color::space::ColorSpace, output: &Path) -> Option<String> {
    (space != crate::color::space::ColorSpace::Srgb && !crate::film::io::records_color_space(output)).then(|| {
        format!(
            "{}: only OpenEXR images record a colour space; the image is written in sRGB, not {}",
            output.display(),
            space.pbrt_name()
        )
    })
}

struct ImageOutputs<'a> {
    output: &'a Path,
    tonemap: Tonemap,
    exposure: f32,
    /// The colour space the film's image is in (its output transform's).
    color_space: crate::color::space::ColorSpace,
    denoiser: Option<DenoiserKind>,
    aovs: &'a [Aov],
}

impl ImageOutputs<'_> {
    /// The files [`ImageOutputs::write`] writes, for the summary line.
    fn names(&self) -> String {
        std::iter::once(self.output.to_path_buf())
            .chain(self.aovs.iter().map(|a| aov_path(self.output, *a)))
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Writes them; returns the image (denoised, if it was) and what to
    /// say about the denoising, if any.
    fn write(&self, film: &Film) -> Result<(crate::film::Image, Option<String>)> {
        let (output, tonemap, exposure) = (self.output, self.tonemap, self.exposure);
        let mut note = None;
        let mut image = film.to_image();
        let space = self.color_space;
        // A G-buffer film writes its channels beside the image's.
        let write_main = |path: &Path, image: &crate::film::Image| match film.gbuffer {
            Some(_) => crate::film::io::write_gbuffer_exr(path, image, film, exposure, space),
            None => write_image_in(path, image, tonemap, exposure, space),
        };
        match self.denoiser {
            None => write_main(output, &image)?,
            Some(kind) => {
                let noisy = sibling_path(output, "noisy");
                write_main(&noisy, &film.to_image())?;
                let start = Instant::now();
                let d = denoise_film(film, kind)?;
                write_main(output, &d.image)?;
                image = d.image;
                note = Some(format!(
                    "denoised with {} in {:.2} s (the noisy image: {})",
                    d.denoiser,
                    start.elapsed().as_secs_f64(),
                    noisy.display()
                ));
            }
        }
        for aov in self.aovs {
            let img = film
                .aov_image(*aov)
                .ok_or_else(|| Error::Invalid("the auxiliary images were not recorded".into()))?;
            write_image(&aov_path(output, *aov), &img, tonemap, 0.0)?;
            if *aov == Aov::Steps {
                // The counts are in the EXR; a heat map shows them, from
                // black (none) to yellow (the most in any pixel).
                let most = img.pixels.iter().map(|p| p.x).fold(0.0f32, f32::max).ceil().max(1.0);
                let path = output.with_file_name(format!(
                    "{}.steps.png",
                    output.file_stem().map(|s| s.to_string_lossy()).unwrap_or_default()
                ));
                write_image(&path, &crate::film::metrics::heat_map(&img, most), Tonemap::Clamp, 0.0)?;
                let line = format!(
                    "steps per camera ray (sphere tracing, interval evaluations): heat map {} (black 0, yellow {most})",
                    path.display()
                );
                note = Some(match note {
                    Some(n) => format!("{n}; {line}"),
                    None => line,
                });
            }
        }
        Ok((image, note))
    }
}

/// Exit status of `trazo diff` when the images differ by more than allowed.
pub const EXIT_DIFFERENT: u8 = 1;

fn run_diff(args: DiffArgs) -> ExitCode {
    match diff(&args) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(EXIT_DIFFERENT),
        Err(e) => {
            print_error(&e);
            ExitCode::from(EXIT_USAGE)
        }
    }
}

/// Prints the comparison; returns whether the images agree.
fn diff(args: &DiffArgs) -> Result<bool> {
    let x = args.max_relmse;
    if !(x.is_finite() && x >= 0.0) {
        return Err(Error::Invalid(format!("--max-relmse must be a number ≥ 0, got {x}")));
    }
    if !(args.error_scale.is_finite() && args.error_scale > 0.0) {
        return Err(Error::Invalid(format!(
            "--error-scale must be positive, got {}",
            args.error_scale
        )));
    }
    if let Some(p) = &args.error_image {
        check_output(p)?;
    }
    let a = read_image(&args.a)?;
    let mut b = read_image(&args.b)?;
    if args.downscale && (b.width, b.height) != (a.width, a.height) {
        let k = b.width / a.width.max(1);
        b = b
            .downscaled(k)
            .filter(|d| (d.width, d.height) == (a.width, a.height))
            .ok_or_else(|| {
                Error::Invalid(format!(
                    "--downscale: {} is {}×{}, not an integer multiple of {}'s {}×{}",
                    args.b.display(),
                    b.width,
                    b.height,
                    args.a.display(),
                    a.width,
                    a.height
                ))
            })?;
        println!("B averaged down by {k}×{k} to {}×{}", a.width, a.height);
    }
    let rel = crate::film::metrics::relative_mse(&a, &b)
        .map_err(|e| Error::Invalid(format!("{} and {}: {e}", args.a.display(), args.b.display())))?;
    let rmse = crate::film::metrics::rmse(&a, &b)?;
    let (ma, mb) = (a.mean(), b.mean());
    println!(
        "A: {} ({}×{}), mean R G B: {:.6} {:.6} {:.6}",
        args.a.display(),
        a.width,
        a.height,
        ma.x,
        ma.y,
        ma.z
    );
    println!(
        "B: {} ({}×{}), mean R G B: {:.6} {:.6} {:.6}",
        args.b.display(),
        b.width,
        b.height,
        mb.x,
        mb.y,
        mb.z
    );
    println!("rmse: {rmse:.6}");
    println!("relative MSE: {rel:.6}");
    if let Some(p) = &args.error_image {
        let img = crate::film::metrics::error_image(&a, &b, args.error_scale)?;
        write_image(p, &img, Tonemap::Clamp, 0.0)?;
    }
    if rel > x {
        println!("the images differ: relative MSE {rel:.6} > {x}");
        Ok(false)
    } else {
        Ok(true)
    }
}

fn run_compare(args: CompareArgs) -> Result<()> {
    check_output(&args.output)?;
    let contestants = args
        .integrators
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(Contestant::parse)
        .collect::<Result<Vec<_>>>()?;
    if contestants.is_empty() {
        return Err(Error::Invalid("--integrators lists no integrator".into()));
    }
    if let Some(t) = args.time.filter(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(Error::Invalid(format!(
            "--time must be a positive number of seconds, got {t}"
        )));
    }
    let desc = args.scene.load()?;
    let budget = match args.time {
        Some(t) => Budget::Time {
            limit: Duration::from_secs_f64(t),
            max_spp: args.spp.unwrap_or(MAX_SPP),
        },
        // Equal samples: the scene's own, as `trazo render` renders it.
        None => Budget::Spp(args.spp.unwrap_or(desc.settings.spp)),
    };
    let reference = args
        .reference
        .as_deref()
        .map(read_image)
        .transpose()
        .map_err(|e| after_loading(e, &desc))?;
    if let Some(r) = &reference {
        if (r.width, r.height) != (desc.settings.width, desc.settings.height) {
            let e = Error::Invalid(format!(
                "the reference is {}×{} but the render is {}×{} (set --width and --height)",
                r.width, r.height, desc.settings.width, desc.settings.height
            ));
            return Err(after_loading(e, &desc));
        }
    }
    let rows = compare(&desc, &contestants, budget, reference.as_ref(), &args.scene.options())
        .map_err(|e| after_loading(e, &desc))?;
    write_image(
        &args.output,
        &side_by_side(&rows),
        desc.settings.tonemap,
        desc.settings.exposure,
    )?;
    print!("{}", table(&rows));
    let curves = convergence_curves(&rows);
    let mut written = vec![args.output.clone()];
    if !curves.is_empty() {
        let base = args.plot.clone().unwrap_or_else(|| {
            let stem = args
                .output
                .file_stem()
                .map_or("compare".into(), |s| s.to_string_lossy().into_owned());
            args.output.with_file_name(format!("{stem}-convergence"))
        });
        let y_label = "RMS relative error";
        for (ext, bytes) in [
            ("svg", plot::convergence_svg(&curves, y_label)?.into_bytes()),
            ("png", plot::convergence_png(&curves, y_label)?),
        ] {
            let path = base.with_extension(ext);
            write_atomic(&path, |f| {
                std::io::Write::write_all(f, &bytes).map_err(|e| e.to_string())
            })?;
            written.push(path);
        }
    }
    if !args.scene.quiet {
        let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
        eprintln!("→ {}", names.join(", "));
    }
    Ok(())
}
