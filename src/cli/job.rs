//! A render as its checkpoint records it: the command-line settings that
//! decide the image, written so that `trazo render --resume` can parse them
//! again; and the interrupt handler.

use super::{Cli, Command, RenderArgs};
use crate::error::{Error, Result};
use crate::files::FileRead;
use crate::film::Film;
use crate::render::RenderStats;
use crate::render::checkpoint::{Checkpoint, fnv1a};
use crate::scene::{Scene, SceneDesc};
use clap::Parser;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// This program's version, recorded in checkpoints.
const VERSION: &str = env!("CARGO_PKG_VERSION");

/// Makes Ctrl-C (SIGINT) and SIGTERM set the returned flag; a second one
/// ends the process at once with [`super::EXIT_ABORTED`], writing nothing
/// and removing the temporary files of writes in flight.
pub(super) fn install_interrupt_handler() -> Result<Arc<AtomicBool>> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let flag = Arc::new(AtomicBool::new(false));
    let fail = |e: std::io::Error| Error::Invalid(format!("cannot install the interrupt handler: {e}"));
    // The flag is set in the signal handler itself; the second signal is
    // handled on a thread of its own, where removing files is safe.
    for signal in [SIGINT, SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&flag)).map_err(fail)?;
    }
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]).map_err(fail)?;
    std::thread::Builder::new()
        .name("trazo-signals".into())
        .spawn(move || {
            let mut seen = 0;
            for _ in signals.forever() {
                seen += 1;
                if seen >= 2 {
                    crate::film::io::remove_unfinished_temp_files();
                    // End the progress bar's line, which nothing else will.
                    if std::io::stderr().is_terminal() {
                        eprintln!();
                    }
                    std::process::exit(super::EXIT_ABORTED as i32);
                }
            }
        })
        .map_err(fail)?;
    Ok(flag)
}

/// Most bytes of file records a checkpoint names one by one (well within
/// what a checkpoint's reader accepts).
const MAX_LISTED_FILE_BYTES: usize = 16 << 20;

/// The settings of a render that a checkpoint records.
pub(super) struct Job {
    entries: Vec<(String, String)>,
    target_spp: u32,
}

fn absolute(p: &Path) -> PathBuf {
    std::fs::canonicalize(p)
        .or_else(|_| std::path::absolute(p))
        .unwrap_or_else(|_| p.to_path_buf())
}

/// A hash of the scene file's bytes, to notice a scene edited between an
/// interruption and its resumption.
fn scene_hash(path: &Path) -> Result<String> {
    let bytes = crate::files::read_limited(path, crate::files::MAX_SCENE_BYTES << 2)
        .map_err(|e| Error::file(path, format!("cannot read scene: {e}")))?;
    Ok(format!("{:016x}", fnv1a(&bytes)))
}

impl Job {
    /// The job of `args` as loaded into `desc` and built into `scene`.
    pub(super) fn new(
        args: &RenderArgs,
        output: &Path,
        desc: &SceneDesc,
        scene: &Scene,
        files: &[FileRead],
    ) -> Result<Job> {
        let mut arg = Vec::new();
        let a = &args.scene;
        if let Some(p) = &a.scene {
            arg.push(absolute(p).to_string_lossy().into_owned());
        }
        for (name, value) in &a.defines {
            arg.push(format!("-D{name}={value}"));
        }
        arg.push(format!("--output={}", absolute(output).to_string_lossy()));
        if let Some(shard) = args.shard {
            arg.push(format!("--shard={}/{}", shard.index + 1, shard.count));
        }
        // The samples per pixel in effect (a time limit alone sets the
        // largest), which fix the pass schedule and the stratification.
        arg.push(format!("--spp={}", desc.settings.spp));
        let optional = [
            ("width", a.width.map(|v| v.to_string())),
            ("height", a.height.map(|v| v.to_string())),
            ("max-depth", a.max_depth.map(|v| v.to_string())),
            ("seed", a.seed.map(|v| v.to_string())),
            ("sampler", a.sampler.clone()),
            ("tonemap", a.tonemap.clone()),
            ("exposure", a.exposure.map(|v| v.to_string())),
            ("march-step", a.march_step.map(|v| v.to_string())),
            ("integrator", args.integrator.clone()),
            ("sampling", args.sampling.clone()),
            ("aov", (!args.aov.is_empty()).then(|| args.aov.join(","))),
            ("denoise", args.denoise.clone()),
            ("photons", a.photons.map(|v| v.to_string())),
            ("caustic-photons", a.caustic_photons.map(|v| v.to_string())),
            ("sppm-photons", a.sppm_photons.map(|v| v.to_string())),
            ("photon-gather", a.photon_gather.map(|v| v.to_string())),
            ("photon-radius", a.photon_radius.map(|v| v.to_string())),
            ("final-gather", a.final_gather.map(|v| v.to_string())),
            ("photon-kernel", a.photon_kernel.clone()),
            // A render that only time ends (no samples per pixel asked
            // for) keeps its limit, so that its resumption ends too: it gets
            // the same time again unless the resuming command gives its own.
            (
                "time-limit",
                args.time_limit
                    .filter(|_| desc.settings.spp == crate::settings::MAX_SPP)
                    .map(|v| v.to_string()),
            ),
        ];
        for (flag, value) in optional {
            if let Some(v) = value {
                arg.push(format!("--{flag}={v}"));
            }
        }
        let mut entries = vec![("trazo".to_string(), VERSION.to_string())];
        entries.extend(arg.into_iter().map(|v| ("arg".to_string(), v)));
        if let Some(p) = &a.scene {
            entries.push(("scene_hash".into(), scene_hash(p)?));
        }
        entries.push(("settings".into(), format!("{:?}", scene.settings)));
        // What `trazo merge` needs to write a shard's image.
        if let Some(shard) = args.shard {
            entries.push(("shard".into(), format!("{}/{}", shard.index + 1, shard.count)));
            entries.push(("tonemap".into(), scene.settings.tonemap.name().into()));
            entries.push(("exposure".into(), scene.settings.exposure.to_string()));
            entries.push(("white_balance".into(), scene.settings.white_balance.to_string()));
            entries.push(("color_space".into(), scene.settings.color_space.pbrt_name().into()));
        }
        // The hash first: a path may hold spaces.
        let mut listed: Vec<(String, String)> = files
            .iter()
            .map(|f| ("file".to_string(), format!("{:016x} {}", f.hash, f.path.display())))
            .collect();
        if listed.iter().map(|(_, v)| v.len() + 16).sum::<usize>() > MAX_LISTED_FILE_BYTES {
            // Too many to name one by one and still read back: one hash.
            let all: String = listed.iter().map(|(_, v)| format!("{v}\n")).collect();
            let summary = format!("(the {} files the scene reads)", files.len());
            listed = vec![("file".into(), format!("{:016x} {summary}", fnv1a(all.as_bytes())))];
        }
        entries.extend(listed);
        Ok(Job {
            entries,
            target_spp: scene.settings.spp,
        })
    }

    /// The checkpoint of this job at the end of a pass.
    pub(super) fn checkpoint(&self, film: &Film, stats: &RenderStats, state: &[u8]) -> Checkpoint {
        Checkpoint {
            job: self.entries.clone(),
            target_spp: self.target_spp,
            film: film.clone(),
            stats: stats.clone(),
            state: state.to_vec(),
        }
    }

    fn value(&self, key: &str) -> Option<&str> {
        self.entries.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// Checks that `checkpoint` (read from `path`) belongs to this job: the
    /// settings are the same and so is every file the scene was loaded from
    /// (the scene file itself was checked by [`resume_args`]).
    pub(super) fn check_resume(&self, path: &Path, checkpoint: &Checkpoint) -> Result<()> {
        if self.value("settings") != checkpoint.job_value("settings") || self.target_spp != checkpoint.target_spp {
            return Err(Error::file(
                path,
                "cannot resume: the scene's render settings are not those of the checkpoint",
            ));
        }
        // Checkpoints written before files were recorded name none.
        let then: Vec<(&str, &str)> = checkpoint.job_values("file").filter_map(hash_and_path).collect();
        if then.is_empty() {
            return Ok(());
        }
        let now: Vec<(&str, &str)> = self
            .entries
            .iter()
            .filter(|(k, _)| k == "file")
            .filter_map(|(_, v)| hash_and_path(v))
            .collect();
        let hash_now = |p: &str| now.iter().find(|(_, q)| *q == p).map(|(h, _)| *h);
        if let Some((_, changed)) = then.iter().find(|(h, p)| hash_now(p) != Some(*h)) {
            let how = if hash_now(changed).is_some() {
                "has changed since the checkpoint was written"
            } else {
                "was read when the checkpoint was written and is not now"
            };
            return Err(Error::file(path, format!("cannot resume: {changed} {how}")));
        }
        if let Some((_, new)) = now.iter().find(|(_, p)| !then.iter().any(|(_, q)| q == p)) {
            return Err(Error::file(
                path,
                format!("cannot resume: the scene now reads {new}, which it did not when the checkpoint was written"),
            ));
        }
        Ok(())
    }
}

/// A `file` entry's hash and path.
fn hash_and_path(entry: &str) -> Option<(&str, &str)> {
    entry.split_once(' ')
}

/// The render arguments a checkpoint holds, with the run-control flags
/// (threads, output verbosity, time limit, checkpoint interval, memory
/// limit, display server) of the command that resumes it (where it gives no time limit, a
/// render that only its time limit ends gets that limit afresh); and the
/// checkpoint.
pub(super) fn resume_args(path: &Path, current: &RenderArgs) -> Result<(RenderArgs, Checkpoint)> {
    let checkpoint = Checkpoint::read(path)?;
    let stored: Vec<&str> = checkpoint.job_values("arg").collect();
    if stored.is_empty() {
        return Err(Error::file(path, "invalid checkpoint: it records no render settings"));
    }
    let cli = Cli::try_parse_from(["trazo", "render"].into_iter().chain(stored.iter().copied())).map_err(|e| {
        let first = e.to_string().lines().next().unwrap_or_default().to_string();
        Error::file(path, format!("invalid checkpoint: its settings do not parse: {first}"))
    })?;
    let Command::Render(mut args) = cli.command else {
        unreachable!("parsed as a render command")
    };
    // Before loading anything: an edited scene would mix two images.
    let stored_hash = checkpoint.job_value("scene_hash");
    let current_hash = args.scene.scene.as_deref().map(scene_hash).transpose()?;
    if stored_hash != current_hash.as_deref() {
        return Err(Error::file(
            path,
            format!(
                "cannot resume: the scene file {} has changed since the checkpoint was written",
                args.scene.scene.as_deref().unwrap_or(Path::new("?")).display()
            ),
        ));
    }
    if let Some(v) = checkpoint.job_value("trazo").filter(|v| *v != VERSION) {
        eprintln!(
            "warning: {}: written by trazo {v}, resumed by trazo {VERSION}: the image may differ from an uninterrupted render",
            path.display()
        );
    }
    args.scene.threads = current.scene.threads;
    args.scene.quiet = current.scene.quiet;
    args.scene.verbose = current.scene.verbose;
    args.time_limit = current.time_limit.or(args.time_limit);
    args.checkpoint_every = current.checkpoint_every;
    args.max_memory = current.max_memory;
    args.display_server = current.display_server.clone();
    Ok((args, checkpoint))
}
