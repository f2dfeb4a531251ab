//! The `trazo` command line: maps flags onto library calls. No rendering
//! logic lives here.

use crate::error::{Error, Result};
use crate::film::Tonemap;
use crate::film::io::{ImageFormat, write_image};
use crate::integrator::IntegratorKind;
use crate::render::{RenderOptions, render};
use crate::sampling::SamplerKind;
use crate::scene::{self, SceneDesc, builtin};
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Exit status for bad input: unreadable or invalid scenes, bad options,
/// unwritable outputs.
pub const EXIT_USAGE: u8 = 2;

#[derive(Parser, Debug)]
#[command(
    name = "trazo",
    version,
    about = "trazo: a physically based renderer (Whitted ray tracing; path tracing and photon mapping to come)",
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
}

#[derive(Args, Debug)]
struct RenderArgs {
    /// Scene file: a trazo .toml scene or a lone .obj model (framed with a
    /// default camera and lights). Without one, the built-in Cornell box.
    scene: Option<PathBuf>,

    /// Output image; the format follows the extension: .png (8-bit sRGB,
    /// tone-mapped), .exr, .hdr or .pfm (linear float). Default: the
    /// scene's name with .png, in the current folder.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,

    /// Samples per pixel (overrides the scene).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=(crate::scene::desc::MAX_SPP as i64)))]
    spp: Option<u32>,

    /// Rendering algorithm (overrides the scene).
    #[arg(long, value_name = "NAME", value_parser = IntegratorKind::NAMES)]
    integrator: Option<String>,

    /// The path tracer's estimator: uniform or cosine hemisphere sampling,
    /// BSDF importance sampling, or next-event estimation with multiple
    /// importance sampling (mis).
    #[arg(long, value_name = "NAME", value_parser = crate::integrator::PathSampling::NAMES)]
    sampling: Option<String>,

    /// Image width in pixels (overrides the scene).
    #[arg(long, value_name = "W", value_parser = clap::value_parser!(u32).range(1..=(crate::scene::desc::MAX_IMAGE_SIDE as i64)))]
    width: Option<u32>,

    /// Image height in pixels (overrides the scene).
    #[arg(long, value_name = "H", value_parser = clap::value_parser!(u32).range(1..=(crate::scene::desc::MAX_IMAGE_SIDE as i64)))]
    height: Option<u32>,

    /// Longest light path in segments from the camera: 1 shows emitters,
    /// 2 adds direct light, each more one more bounce (overrides the scene).
    #[arg(long, value_name = "D", value_parser = clap::value_parser!(u32).range(0..=(crate::scene::desc::MAX_DEPTH as i64)))]
    max_depth: Option<u32>,

    /// Seed of the random numbers; the same seed gives the same image.
    #[arg(long, value_name = "S")]
    seed: Option<u64>,

    /// Placement of samples inside pixels: center (one ray through the
    /// centre: aliasing), independent (random jitter) or stratified
    /// (jittered grid).
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
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(EXIT_USAGE)
        }
    }
}

/// Applies command-line overrides to a scene's settings.
fn apply_overrides(desc: &mut SceneDesc, a: &RenderArgs) {
    let s = &mut desc.settings;
    if let Some(v) = a.spp {
        s.spp = v;
    }
    if let Some(v) = a.width {
        s.width = v;
    }
    if let Some(v) = a.height {
        s.height = v;
    }
    if let Some(v) = a.max_depth {
        s.max_depth = v;
    }
    if let Some(v) = a.seed {
        s.seed = v;
    }
    if let Some(v) = &a.integrator {
        s.integrator = IntegratorKind::from_name(v).expect("clap checked the value");
    }
    if let Some(v) = &a.sampling {
        s.sampling = crate::integrator::PathSampling::from_name(v).expect("clap checked the value");
    }
    if let Some(v) = &a.sampler {
        s.sampler = SamplerKind::from_name(v).expect("clap checked the value");
    }
    if let Some(v) = &a.tonemap {
        s.tonemap = Tonemap::from_name(v).expect("clap checked the value");
    }
    if let Some(v) = a.exposure {
        s.exposure = v;
    }
}

fn default_output(scene: Option<&Path>) -> PathBuf {
    let stem = scene
        .and_then(|p| p.file_stem())
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "cornell-box".into());
    PathBuf::from(format!("{stem}.png"))
}

/// Fails early, before a long render, if the output cannot be written.
fn check_output(path: &Path) -> Result<()> {
    ImageFormat::from_path(path)?;
    if path.is_dir() {
        return Err(Error::file(path, "cannot write the image: this is a folder"));
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

fn run_render(args: RenderArgs) -> Result<()> {
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| default_output(args.scene.as_deref()));
    check_output(&output)?;

    let load_start = Instant::now();
    let mut desc = match &args.scene {
        Some(path) => scene::load(path)?,
        None => builtin::cornell_box(),
    };
    apply_overrides(&mut desc, &args);
    let scene = scene::build(&desc)?;
    let load_seconds = load_start.elapsed().as_secs_f64();
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    if args.verbose {
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
            "bvh: {} primitives, {} nodes, {:.1} MiB (meshes {:.1} MiB), built in {:.3} s",
            g.primitives,
            g.nodes,
            g.bvh_bytes as f64 / (1 << 20) as f64,
            g.mesh_bytes as f64 / (1 << 20) as f64,
            g.seconds
        );
        eprintln!("load and build: {load_seconds:.3} s");
    }

    let s = scene.settings.clone();
    let options = RenderOptions {
        threads: args.threads,
        progress: !args.quiet,
        ..RenderOptions::default()
    };
    let out = render(&scene, &options)?;
    write_image(&output, &out.film.to_image(), s.tonemap, s.exposure)?;
    let st = &out.stats;
    if st.invalid_samples > 0 {
        eprintln!(
            "warning: {} samples were NaN or infinite and were dropped",
            st.invalid_samples
        );
    }
    if !args.quiet {
        eprintln!(
            "rendered {}×{} at {} spp with {} in {:.2} s ({:.2} M samples/s, {:.2} M rays/s, {} threads) → {}",
            s.width,
            s.height,
            s.spp,
            s.integrator.name(),
            st.seconds,
            st.samples_per_second() / 1e6,
            st.rays_per_second() / 1e6,
            st.threads,
            output.display()
        );
    }
    Ok(())
}
