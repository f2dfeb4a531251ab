//! Scheduling: splits the image into tiles, renders them on all cores in
//! progressive passes, shows progress and gathers statistics. It knows
//! nothing about the algorithm, which it reaches through
//! [`crate::integrator::Integrator`].
//!
//! A pass adds a few samples to every pixel; passes grow (1, 1, 2, 4, …
//! samples) so that the first image is quick. Each sample's random
//! numbers depend only on its pixel, its index and the seed, and each
//! pixel's samples are added in index order, so the result is bit-identical
//! whatever the number of threads or the tile order.

pub mod compare;

use crate::error::{Error, Result};
use crate::film::{AovSum, Film, Image, PixelSum};
use crate::integrator::aov::camera_aov;
use crate::integrator::{Integrator, IntegratorKind, PathTracer, RayStats, Whitted};
use crate::sampling::Sampler;
use crate::scene::Scene;
use glam::Vec2;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// How to render (as opposed to what: that is the scene's settings).
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Worker threads; `None` uses every core.
    pub threads: Option<usize>,
    /// Show a progress bar on stderr (only if stderr is a terminal).
    pub progress: bool,
    /// Side of the square tiles in pixels.
    pub tile_size: u32,
    /// Record the auxiliary images (albedo, normal, depth).
    pub aovs: bool,
    /// Stop after the pass during which this much time has passed; the
    /// scene's `spp` is then the most samples per pixel. Passes are one
    /// sample per pixel, so the overshoot is at most one pass.
    pub time_limit: Option<Duration>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            threads: None,
            progress: false,
            tile_size: 16,
            aovs: false,
            time_limit: None,
        }
    }
}

/// Figures about a finished render.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderStats {
    /// Wall time of the rendering itself, in seconds.
    pub seconds: f64,
    /// Samples computed (pixels × samples per pixel).
    pub samples: u64,
    /// Rays traced.
    pub rays: u64,
    /// Samples dropped because they were NaN or infinite.
    pub invalid_samples: u64,
    /// Threads used.
    pub threads: usize,
    /// Samples per pixel completed (SPPM: iterations).
    pub spp: u32,
    /// Photons emitted (photon mapping).
    pub photons_emitted: u64,
    /// Seconds spent tracing photons and building photon maps (included
    /// in `seconds`).
    pub photon_seconds: f64,
}

impl RenderStats {
    /// Samples per second.
    pub fn samples_per_second(&self) -> f64 {
        self.samples as f64 / self.seconds.max(1e-9)
    }

    /// Rays per second.
    pub fn rays_per_second(&self) -> f64 {
        self.rays as f64 / self.seconds.max(1e-9)
    }
}

/// A finished render: the accumulated film and its statistics.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// Accumulated samples.
    pub film: Film,
    /// Figures.
    pub stats: RenderStats,
}

/// Renders `scene` with its own settings into an in-memory image, using
/// every core and no progress output. The simplest entry point for
/// library users.
pub fn render_image(scene: &Scene) -> Result<Image> {
    Ok(render(scene, &RenderOptions::default())?.film.to_image())
}

/// Renders `scene` with its settings.
pub fn render(scene: &Scene, options: &RenderOptions) -> Result<RenderOutput> {
    let s = &scene.settings;
    match s.integrator {
        IntegratorKind::Whitted => render_with(scene, &Whitted { max_depth: s.max_depth }, options),
        IntegratorKind::Path => render_with(
            scene,
            &PathTracer {
                max_depth: s.max_depth,
                rr_depth: s.rr_depth,
                sampling: s.sampling,
            },
            options,
        ),
        IntegratorKind::Photon => crate::integrator::photon::jensen::render(scene, options),
        IntegratorKind::Sppm => crate::integrator::photon::sppm::render(scene, options),
    }
}

/// Renders `scene` with a given integrator.
pub fn render_with<I: Integrator>(scene: &Scene, integrator: &I, options: &RenderOptions) -> Result<RenderOutput> {
    in_thread_pool(options, || render_passes(scene, integrator, options))
}

/// Runs `work` on `options.threads` threads (every core when `None`):
/// whatever it starts with rayon runs there.
pub fn in_thread_pool<T: Send>(options: &RenderOptions, work: impl FnOnce() -> T + Send) -> Result<T> {
    let pool = match options.threads {
        Some(0) => return Err(Error::Invalid("--threads must be at least 1".into())),
        Some(n) => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| Error::Invalid(format!("cannot start {n} threads: {e}")))?,
        ),
        None => None,
    };
    Ok(match pool {
        Some(p) => p.install(work),
        None => work(),
    })
}

/// A rectangle of pixels.
#[derive(Clone, Copy, Debug)]
struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

fn tiles(width: u32, height: u32, size: u32) -> Vec<Tile> {
    let size = size.max(1);
    let mut v = Vec::new();
    for y0 in (0..height).step_by(size as usize) {
        for x0 in (0..width).step_by(size as usize) {
            v.push(Tile {
                x0,
                y0,
                x1: (x0 + size).min(width),
                y1: (y0 + size).min(height),
            });
        }
    }
    v
}

/// Sample counts of successive passes: 1, 1, 2, 4, … up to 16 per pass.
pub fn pass_schedule(spp: u32) -> Vec<(u32, u32)> {
    let mut passes = Vec::new();
    let mut start = 0;
    let mut len = 1;
    while start < spp {
        let n = len.min(spp - start);
        passes.push((start, start + n));
        start += n;
        if passes.len() > 1 {
            len = (len * 2).min(16);
        }
    }
    passes
}

/// What one tile of one pass produced.
struct TileResult {
    tile: Tile,
    sums: Vec<PixelSum>,
    aovs: Vec<AovSum>,
    rays: RayStats,
    invalid: u64,
}

fn render_passes<I: Integrator>(scene: &Scene, integrator: &I, options: &RenderOptions) -> RenderOutput {
    let s = &scene.settings;
    let (w, h) = (s.width, s.height);
    let mut film = Film::new(w, h);
    if options.aovs {
        film.aovs = Some(vec![AovSum::default(); (w * h) as usize]);
    }
    let tiles = tiles(w, h, options.tile_size);
    let bar = match options.time_limit {
        Some(limit) => progress_bar(options.progress, limit.as_millis().max(1) as u64),
        None => progress_bar(options.progress, w as u64 * h as u64 * s.spp as u64),
    };
    let start = Instant::now();
    let mut stats = RenderStats {
        threads: rayon::current_num_threads(),
        ..RenderStats::default()
    };
    let passes = match options.time_limit {
        Some(_) => (0..s.spp).map(|i| (i, i + 1)).collect(),
        None => pass_schedule(s.spp),
    };

    for (first, end) in passes {
        let results: Vec<TileResult> = tiles
            .par_iter()
            .map(|&tile| {
                let mut sampler = Sampler::new(s.sampler, s.spp, s.seed);
                let mut rays = RayStats::default();
                let mut invalid = 0u64;
                let n = ((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize;
                let mut sums = Vec::with_capacity(n);
                let mut aovs = Vec::with_capacity(if options.aovs { n } else { 0 });
                for y in tile.y0..tile.y1 {
                    for x in tile.x0..tile.x1 {
                        let i = (y * w + x) as usize;
                        let mut sum = film.pixels[i];
                        let mut aov = film.aovs.as_ref().map(|a| a[i]).unwrap_or_default();
                        for index in first..end {
                            sampler.start_pixel_sample(x, y, index);
                            let offset = s.filter.sample(sampler.pixel_2d());
                            let lens = sampler.next_2d();
                            let ray = scene
                                .camera
                                .generate_ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5) + offset, lens);
                            let l = integrator.radiance(scene, &ray, &mut sampler, &mut rays);
                            if l.is_finite() {
                                sum.add(l, 1.0);
                            } else {
                                invalid += 1;
                            }
                            if options.aovs {
                                aov.add(&camera_aov(scene, &ray));
                            }
                        }
                        sums.push(sum);
                        if options.aovs {
                            aovs.push(aov);
                        }
                    }
                }
                if let Some(b) = &bar {
                    match options.time_limit {
                        Some(_) => b.set_position(start.elapsed().as_millis() as u64),
                        None => b.inc(n as u64 * (end - first) as u64),
                    }
                }
                TileResult {
                    tile,
                    sums,
                    aovs,
                    rays,
                    invalid,
                }
            })
            .collect();
        for r in results {
            let mut k = 0;
            for y in r.tile.y0..r.tile.y1 {
                for x in r.tile.x0..r.tile.x1 {
                    let i = (y * w + x) as usize;
                    film.pixels[i] = r.sums[k];
                    if let Some(a) = film.aovs.as_mut() {
                        a[i] = r.aovs[k];
                    }
                    k += 1;
                }
            }
            stats.rays += r.rays.rays;
            stats.invalid_samples += r.invalid;
        }
        stats.samples += w as u64 * h as u64 * (end - first) as u64;
        stats.spp = end;
        if options.time_limit.is_some_and(|limit| start.elapsed() >= limit) {
            break;
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    stats.seconds = start.elapsed().as_secs_f64();
    RenderOutput { film, stats }
}

fn progress_bar(enabled: bool, total: u64) -> Option<ProgressBar> {
    if !enabled || !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr_with_hz(4));
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{wide_bar}] {percent:>3}%  ETA {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.enable_steady_tick(Duration::from_millis(250));
    Some(bar)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_cover_every_sample_once() {
        for spp in [1u32, 2, 3, 16, 17, 100, 1000] {
            let p = pass_schedule(spp);
            assert_eq!(p[0], (0, 1));
            assert_eq!(p.last().unwrap().1, spp);
            for w in p.windows(2) {
                assert_eq!(w[0].1, w[1].0);
                assert!(w[1].1 - w[1].0 <= 16);
            }
        }
    }

    #[test]
    fn tiles_cover_the_image() {
        let t = tiles(37, 20, 16);
        let covered: u32 = t.iter().map(|t| (t.x1 - t.x0) * (t.y1 - t.y0)).sum();
        assert_eq!(covered, 37 * 20);
    }
}
