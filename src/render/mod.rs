//! Scheduling: splits the image into tiles, renders them on all cores in
//! progressive passes, shows progress and gathers statistics. It knows
//! nothing about the algorithm: [`crate::integrator::drive`] prepares the
//! one the scene's settings name and hands it back either as a per-sample
//! estimator ([`crate::integrator::Integrator`]) for the camera passes here
//! or as whole-image iterations ([`crate::integrator::Progressive`], SPPM)
//! that this module runs, stops and times. Threads, passes, interrupts,
//! deadlines, time limits, checkpoints and progress are decided here alone.
//!
//! A pass adds a few samples to every pixel; passes grow (1, 1, 2, 4, …
//! samples) so that the first image is quick. Each sample's random
//! numbers depend only on its pixel, its index and the seed, a pass sums
//! each pixel's samples in index order, and the film adds the passes'
//! sums exactly ([`crate::film::ExactSums`]), so the result is
//! bit-identical whatever the number of threads, the tile order, or how
//! the passes were shared out: a [`Shard`] renders some of them, and the
//! films of all shards merge into the film of one render.
//!
//! Long renders are controlled by a [`Control`]: a cancellation flag (set by
//! the command line's signal handler), a deadline, periodic checkpoints and
//! resuming from one. A pass that is cut short is abandoned, so the film
//! always holds whole passes; and because the pass schedule depends only on
//! the samples per pixel asked for, a render resumed from a checkpoint
//! ends with the same image, bit for bit, as one that never stopped.

pub mod checkpoint;
pub mod compare;

use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::film::splat::{MAX_TAPS, Splat, SplatSum};
use crate::film::{AovSum, Film, FilmAov, FilmGBuffer, FilmPixel, Image, PixelSum};
use crate::geometry::Ray;
use crate::integrator::aov::{camera_aov, camera_gbuffer};
use crate::integrator::{Integrator, LANES, Progressive, RayStats, Work};
use crate::sampling::Sampler;
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
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
    /// Render only this share of the passes (see [`shard_passes`]).
    pub shard: Option<Shard>,
}

/// The `index`-th (from 0) of `count` disjoint shares of a render's passes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which share, from 0.
    pub index: u32,
    /// How many shares.
    pub count: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            threads: None,
            progress: false,
            tile_size: 16,
            aovs: false,
            time_limit: None,
            shard: None,
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
    /// The first few dropped samples, in pass, tile and pixel order (at
    /// most [`MAX_INVALID_EXAMPLES`]), to show where they happen.
    pub invalid_examples: Vec<InvalidSample>,
}

/// Most dropped samples whose place is remembered.
pub const MAX_INVALID_EXAMPLES: usize = 8;

/// A sample whose radiance was NaN or infinite, and was dropped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InvalidSample {
    /// Pixel column.
    pub x: u32,
    /// Pixel row, from the top.
    pub y: u32,
    /// The sample's index within its pixel.
    pub index: u32,
    /// The value the integrator returned.
    pub value: crate::Rgb,
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
    /// Why the render stopped before the samples per pixel asked for, if it
    /// did; the film then holds `stats.spp` samples per pixel.
    pub stopped: Option<Stop>,
    /// Images the algorithm made besides the film, by name
    /// ([`Progressive::extra_images`]).
    pub extra: Vec<(String, Film)>,
    /// A progressive algorithm's state at the end, from which a render
    /// stopped early continues ([`Progressive::state`]); empty for camera
    /// passes, whose state is the film.
    pub state: Vec<u8>,
}

/// Why a render stopped early.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The cancellation flag was set (Ctrl-C, SIGTERM).
    Interrupted,
    /// The deadline passed.
    TimeLimit,
}

/// Shows a render's film after a pass (see [`Control::on_pass`]).
pub type CheckpointFn<'a> = dyn FnMut(&Film, &RenderStats) + Send + 'a;

/// Saves a render's state at a pass boundary: its film, statistics and a
/// progressive algorithm's state (empty for camera passes; see
/// [`Control::on_checkpoint`]).
pub type SaveFn<'a> = dyn FnMut(&Film, &RenderStats, &[u8]) + Send + 'a;

/// What a long render does besides rendering: where it starts, when it
/// stops early, and when it saves its state.
#[derive(Default)]
pub struct Control<'a> {
    /// Start from this film and these statistics (read from a checkpoint)
    /// instead of an empty film. `stats.spp` must be a pass boundary of the
    /// schedule for the scene's samples per pixel ([`pass_schedule`]).
    pub resume: Option<(Film, RenderStats)>,
    /// With `resume`, a progressive algorithm's saved state
    /// ([`Progressive::state`]: SPPM, light tracing, BDPT, MLT).
    pub resume_state: Vec<u8>,
    /// When set (by a signal handler, say), the pass in flight is abandoned
    /// within a tile row and the render returns the film of whole passes.
    pub cancel: Option<&'a AtomicBool>,
    /// At this instant the pass in flight is abandoned, as by `cancel` —
    /// unless no pass is complete yet, so that there is always an image.
    pub deadline: Option<Instant>,
    /// Call `on_checkpoint` after a pass when at least this long has passed
    /// since the last call (or the start).
    pub checkpoint_every: Option<Duration>,
    /// Saves the state at a pass boundary (writes a checkpoint file).
    pub on_checkpoint: Option<&'a mut SaveFn<'a>>,
    /// Called after every pass with the film so far (a live preview).
    pub on_pass: Option<&'a mut CheckpointFn<'a>>,
}

/// Renders `scene` with its own settings into an in-memory image, using
/// every core and no progress output. The simplest entry point for
/// library users.
pub fn render_image(scene: &Scene) -> Result<Image> {
    Ok(render(scene, &RenderOptions::default())?.film.to_image())
}

/// Renders `scene` with its settings.
pub fn render(scene: &Scene, options: &RenderOptions) -> Result<RenderOutput> {
    render_controlled(scene, options, &mut Control::default())
}

/// Renders `scene` with its settings under `control` (resume, cancel,
/// deadline, checkpoints): in a pool of `options.threads` threads, the
/// algorithm the settings name is prepared and handed back to this
/// module's camera passes or progressive iterations
/// ([`crate::integrator::drive`]).
pub fn render_controlled(scene: &Scene, options: &RenderOptions, control: &mut Control) -> Result<RenderOutput> {
    let cancel = control.cancel;
    let mut out = in_thread_pool(options, || {
        let driver = RenderDriver {
            scene,
            options,
            control,
        };
        crate::integrator::drive(scene, options.aovs, cancel, driver).unwrap_or_else(|| {
            // Interrupted while preparing (tracing photons): no image.
            Ok(RenderOutput {
                film: Film::new(scene.settings.width, scene.settings.height),
                stats: RenderStats::default(),
                stopped: Some(Stop::Interrupted),
                extra: Vec::new(),
                state: Vec::new(),
            })
        })
    })??;
    // White balance and the output's colour space apply to the finished
    // estimates, as pbrt-v4's film applies them when a pixel is read.
    let balance =
        crate::color::white_balance::output_transform(scene.settings.color_space, scene.settings.white_balance);
    out.film.output_transform = balance;
    for (_, film) in &mut out.extra {
        film.output_transform = balance;
    }
    Ok(out)
}

/// Renders `scene` with a given integrator.
pub fn render_with<I: Integrator>(scene: &Scene, integrator: &I, options: &RenderOptions) -> Result<RenderOutput> {
    render_with_control(scene, integrator, options, &mut Control::default())
}

/// Renders `scene` with a given integrator under `control`.
pub fn render_with_control<I: Integrator>(
    scene: &Scene,
    integrator: &I,
    options: &RenderOptions,
    control: &mut Control,
) -> Result<RenderOutput> {
    check_resume(scene, options, control)?;
    in_thread_pool(options, || render_passes(scene, integrator, options, control))
}

/// Refuses to resume from a film that is not a state of this render.
fn check_resume(scene: &Scene, options: &RenderOptions, control: &Control) -> Result<()> {
    let s = &scene.settings;
    if let Some((film, stats)) = &control.resume {
        if (film.width, film.height) != (s.width, s.height) {
            return Err(Error::Invalid(format!(
                "cannot resume: the saved film is {}×{} but the scene renders {}×{}",
                film.width, film.height, s.width, s.height
            )));
        }
        if film.aovs.is_some() != options.aovs {
            return Err(Error::Invalid(
                "cannot resume: the saved film and the render disagree on auxiliary images".into(),
            ));
        }
        if film.gbuffer.is_some() != s.gbuffer.is_some() {
            return Err(Error::Invalid(
                "cannot resume: the saved film and the render disagree on a G-buffer".into(),
            ));
        }
        if options.time_limit.is_some() || !done_passes(&render_schedule(s.spp, options)?, stats.spp).0 {
            return Err(Error::Invalid(format!(
                "cannot resume: {} samples per pixel is not the end of a pass of a {}-spp render",
                stats.spp, s.spp
            )));
        }
    } else {
        render_schedule(s.spp, options)?;
    }
    Ok(())
}

/// Whether the first passes of `passes` hold exactly `spp` samples per
/// pixel, and how many passes they are: a render resumed with `spp` done
/// goes on from there.
fn done_passes(passes: &[(u32, u32)], spp: u32) -> (bool, usize) {
    let mut sum = 0;
    for (k, p) in passes.iter().enumerate() {
        if sum >= spp {
            return (sum == spp, k);
        }
        sum += p.1 - p.0;
    }
    (sum == spp, passes.len())
}

/// The renderer's side of [`crate::integrator::drive`]: runs what the
/// integrator module prepared, on the threads of the pool it is called in.
struct RenderDriver<'r, 'c> {
    scene: &'r Scene,
    options: &'r RenderOptions,
    control: &'r mut Control<'c>,
}

impl crate::integrator::Driver for RenderDriver<'_, '_> {
    type Output = Result<RenderOutput>;

    /// The camera passes; the preparation's time counts against a time
    /// limit and in the statistics.
    fn camera_passes<I: Integrator>(self, integrator: &I, prepared: Work) -> Result<RenderOutput> {
        check_resume(self.scene, self.options, self.control)?;
        let mut options = self.options.clone();
        if let Some(limit) = options.time_limit {
            options.time_limit = Some(limit.saturating_sub(Duration::from_secs_f64(prepared.photon_seconds)));
        }
        let mut out = render_passes(self.scene, integrator, &options, self.control);
        out.stats.seconds += prepared.photon_seconds;
        out.stats.rays += prepared.rays;
        out.stats.photons_emitted += prepared.photons_emitted;
        out.stats.photon_seconds += prepared.photon_seconds;
        Ok(out)
    }

    /// The iterations: checkpointed and resumed by the algorithm's state,
    /// never shared out.
    fn iterations<P: Progressive>(self, algorithm: P) -> Result<RenderOutput> {
        if self.options.shard.is_some() {
            return Err(Error::Invalid(crate::integrator::NOT_SHARDABLE.into()));
        }
        render_iterations(self.scene, algorithm, self.options, self.control)
    }
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

/// The passes of `shard` of a `spp`-sample render, in schedule order: the
/// schedule's passes ([`pass_schedule`]) dealt out so that the shards'
/// samples per pixel differ as little as the passes allow (largest pass
/// first, each to the shard with the fewest samples so far, the lowest
/// index on a tie). Every shard's passes cover every pixel, so the shards
/// finished so far make a whole, noisier image. An error if there are
/// more shards than passes.
pub fn shard_passes(spp: u32, shard: Shard) -> Result<Vec<(u32, u32)>> {
    let passes = pass_schedule(spp);
    if shard.count == 0 || shard.index >= shard.count {
        return Err(Error::Invalid(format!(
            "shard {}/{}: the index must be from 1 to the number of shards",
            shard.index + 1,
            shard.count
        )));
    }
    if shard.count as usize > passes.len() {
        return Err(Error::Invalid(format!(
            "{} shards: a render of {spp} samples per pixel has {} passes, so at most {} shards (more samples per pixel allow more)",
            shard.count,
            passes.len(),
            passes.len()
        )));
    }
    let mut order: Vec<usize> = (0..passes.len()).collect();
    // Stable: equal passes keep schedule order.
    order.sort_by_key(|&i| std::cmp::Reverse(passes[i].1 - passes[i].0));
    // The least-loaded shard, lowest index first: a min-heap of (load, shard).
    let mut shards: std::collections::BinaryHeap<std::cmp::Reverse<(u32, u32)>> =
        (0..shard.count).map(|k| std::cmp::Reverse((0, k))).collect();
    let mut owner = vec![0u32; passes.len()];
    for i in order {
        let std::cmp::Reverse((load, k)) = shards.pop().expect("at least one shard");
        shards.push(std::cmp::Reverse((load + passes[i].1 - passes[i].0, k)));
        owner[i] = k;
    }
    Ok(passes
        .into_iter()
        .zip(owner)
        .filter(|(_, k)| *k == shard.index)
        .map(|(p, _)| p)
        .collect())
}

/// The passes a render goes through: its shard's, one sample per pass
/// under a time limit, else the whole schedule.
fn render_schedule(spp: u32, options: &RenderOptions) -> Result<Vec<(u32, u32)>> {
    match (options.shard, options.time_limit) {
        (Some(_), Some(_)) => Err(Error::Invalid(
            "a shard cannot have a time limit: every shard renders its whole share".into(),
        )),
        (Some(shard), None) => shard_passes(spp, shard),
        (None, Some(_)) => Ok((0..spp).map(|i| (i, i + 1)).collect()),
        (None, None) => Ok(pass_schedule(spp)),
    }
}

/// The samples of a tile whose radiance was not finite: how many, and the
/// first few.
#[derive(Default)]
struct InvalidSamples {
    count: u64,
    examples: Vec<InvalidSample>,
}

impl InvalidSamples {
    fn record(&mut self, sample: InvalidSample) {
        self.count += 1;
        if self.examples.len() < MAX_INVALID_EXAMPLES {
            self.examples.push(sample);
        }
    }
}

/// `l` scaled down so that its largest component is at most `max`
/// (pbrt-v4's `RGBFilm::AddSample`); `max` infinite leaves it as it is.
#[inline]
fn limit_component(l: Rgb, max: f32) -> Rgb {
    let m = l.max_element();
    if m > max { l * (max / m) } else { l }
}

/// Starts sample `index` of pixel `(x, y)` in `sampler` and draws the
/// numbers of its camera ray: the film position (anywhere in the pixel
/// when splatting, else by the importance of `filter`), the lens point and
/// the time. The render loop then makes the rays of several samples at
/// once ([`Camera::generate_weighted_rays_into`]) and [`timed`] them.
///
/// [`Camera::generate_weighted_rays_into`]: crate::camera::Camera::generate_weighted_rays_into
#[inline(always)]
fn camera_draws(
    scene: &Scene,
    filter: &crate::settings::PixelFilter,
    splatting: bool,
    sampler: &mut Sampler,
    (x, y, index): (u32, u32, u32),
) -> (Vec2, Vec2, f32, f32) {
    // A crop window's pixels draw the numbers of the full image's pixels
    // and find their positions there (the window's are those less its
    // corner, exactly, and the camera adds it back, exactly): they come
    // out as in the full image.
    let (cx, cy) = scene.settings.crop.map_or((0, 0), |c| (c.x, c.y));
    let (x, y) = (x + cx, y + cy);
    sampler.start_pixel_sample(x, y, index);
    let u = sampler.pixel_2d();
    let (position, filter_weight) = if splatting {
        (Vec2::new(x as f32, y as f32) + u, 1.0)
    } else {
        let offset = filter.sample(u);
        (
            Vec2::new(x as f32 + 0.5, y as f32 + 0.5) + offset,
            filter.sample_weight(offset),
        )
    };
    let position = position - Vec2::new(cx as f32, cy as f32);
    let lens = scene.camera.draw_lens(sampler);
    let time = scene.camera.draw_time(sampler);
    (position, lens, time, filter_weight)
}

/// The camera ray `ray` made by the still camera, at `time`.
#[inline(always)]
fn timed(scene: &Scene, ray: &mut Ray, time: f32) {
    ray.time = time;
    if scene.camera.moves() {
        *ray = scene.camera.moved(*ray);
    }
}

/// A tile's splats in this pass: the sums over its pixels and margin, and
/// room for one sample's filter weights.
struct SplatBuffer {
    rect: Tile,
    sums: Vec<SplatSum>,
    weights_x: [f32; MAX_TAPS],
    weights_y: [f32; MAX_TAPS],
}

/// Adds radiance `l`, sampled at film position `position`, to the pixels
/// of `buffer` that the filter of `splat` covers there.
#[inline(always)]
fn splat_sample(splat: &Splat, buffer: &mut SplatBuffer, position: Vec2, l: Rgb) {
    let rect = buffer.rect;
    let width = (rect.x1 - rect.x0) as usize;
    let y_l = crate::color::luminance(l);
    let (rgb_one, y_sq) = (l.extend(1.0), y_l * y_l);
    let (x0, wxs) = splat.taps_x(position.x, rect.x0, rect.x1, &mut buffer.weights_x);
    let (y0, wys) = splat.taps_y(position.y, rect.y0, rect.y1, &mut buffer.weights_y);
    // A sample's pixels are a block: one row slice at a time.
    let mut start = (y0 - rect.y0) as usize * width + (x0 - rect.x0) as usize;
    for &wy in wys {
        let (row_rgb, row_y_sq) = (rgb_one * wy, y_sq * wy);
        let row = &mut buffer.sums[start..start + wxs.len()];
        for (s, &wx) in row.iter_mut().zip(wxs) {
            s.add(row_rgb, row_y_sq, wx);
        }
        start += width;
    }
}

/// What one tile of one pass produced.
struct TileResult {
    tile: Tile,
    /// The tile's pixels after this pass (filter importance sampling), or
    /// empty when splatting.
    sums: Vec<FilmPixel>,
    /// Splatting: what this pass adds to the pixels of `splat_rect` (the
    /// tile and its margin, within the image).
    splats: Vec<SplatSum>,
    splat_rect: Tile,
    aovs: Vec<FilmAov>,
    gbuffer: Vec<FilmGBuffer>,
    rays: RayStats,
    invalid: u64,
    invalid_examples: Vec<InvalidSample>,
}

fn render_passes<I: Integrator>(
    scene: &Scene,
    integrator: &I,
    options: &RenderOptions,
    control: &mut Control,
) -> RenderOutput {
    let s = &scene.settings;
    let (w, h) = (s.width, s.height);
    let start = Instant::now();
    // Checked by `check_resume` before the render starts.
    let passes = render_schedule(s.spp, options).expect("a valid schedule");
    let (mut film, mut stats) = match control.resume.take() {
        Some((film, stats)) => (film, stats),
        None => {
            let mut film = Film::new(w, h);
            if options.aovs {
                film.aovs = Some(vec![FilmAov::default(); (w * h) as usize]);
            }
            if s.gbuffer.is_some() {
                film.gbuffer = Some(vec![FilmGBuffer::default(); (w * h) as usize]);
            }
            (film, RenderStats::default())
        }
    };
    stats.threads = rayon::current_num_threads();
    let earlier_seconds = stats.seconds;
    let tiles = tiles(w, h, options.tile_size);
    let pixel_filter = s.pixel_filter();
    // pbrt-v4 scales camera ray differentials by this before a G-buffer
    // records the surfaces' depth slopes.
    let differential_scale = (1.0 / (s.spp as f32).sqrt()).max(0.125);
    // A G-buffer's variances are of what pbrt-v4's default sensor records.
    let xyz_from_srgb = crate::color::space::ColorSpace::Srgb.xyz_from_rgb().as_mat3();
    let splat = Splat::new(&pixel_filter);
    let time_budget = options
        .time_limit
        .or_else(|| control.deadline.map(|d| d.saturating_duration_since(start)));
    let share: u32 = passes.iter().map(|p| p.1 - p.0).sum();
    let progress = Progress::new(
        options.progress,
        w as u64 * h as u64 * share as u64,
        w as u64 * h as u64 * stats.spp as u64,
        time_budget.map(|budget| (start, budget)),
    );
    let cancel = control.cancel;
    let deadline = control.deadline;
    let mut last_checkpoint = Instant::now();
    let mut stopped = None;

    let done = done_passes(&passes, stats.spp).1;
    let last_pass = passes.len().saturating_sub(1);
    for (pass, &(first, end)) in passes.iter().enumerate().skip(done) {
        // The deadline never stops the first pass: there is always an image.
        let deadline_now = deadline.filter(|_| stats.spp > 0);
        let stop_now = || -> Option<Stop> {
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                Some(Stop::Interrupted)
            } else if deadline_now.is_some_and(|d| Instant::now() >= d) {
                Some(Stop::TimeLimit)
            } else {
                None
            }
        };
        let film_ref = &film;
        // The limit applies to exposed values, as pbrt-v4's film applies it
        // to sensor values.
        let max_component = s.max_component_value / crate::film::io::exposure_scale(s.exposure);
        let results: Vec<Option<TileResult>> = tiles
            .par_iter()
            .map(|&tile| {
                let mut samplers: [Sampler; LANES] = std::array::from_fn(|_| {
                    Sampler::new(s.sampler, s.spp, s.seed)
                        .for_image(s.width, s.height)
                        .with_strata(s.strata, s.jitter)
                });
                let mut camera_rays = [Ray::new(Vec3::ZERO, Vec3::Z); LANES];
                let mut positions = [Vec2::ZERO; LANES];
                let (mut lenses, mut times) = ([Vec2::ZERO; LANES], [0.0f32; LANES]);
                let mut weights = [0.0f32; LANES];
                let mut filter_weights = [1.0f32; LANES];
                let mut rays = RayStats::default();
                let mut invalid = InvalidSamples::default();
                let n = ((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize;
                let mut sums = Vec::with_capacity(if splat.is_some() { 0 } else { n });
                let splat_rect = match &splat {
                    Some(sp) => Tile {
                        x0: tile.x0.saturating_sub(sp.margin),
                        y0: tile.y0.saturating_sub(sp.margin),
                        x1: (tile.x1 + sp.margin).min(w),
                        y1: (tile.y1 + sp.margin).min(h),
                    },
                    None => tile,
                };
                let splat_width = splat_rect.x1 - splat_rect.x0;
                let splats = match &splat {
                    Some(_) => vec![SplatSum::default(); (splat_width * (splat_rect.y1 - splat_rect.y0)) as usize],
                    None => Vec::new(),
                };
                let mut splat_buffer = SplatBuffer {
                    rect: splat_rect,
                    sums: splats,
                    weights_x: [0.0; MAX_TAPS],
                    weights_y: [0.0; MAX_TAPS],
                };
                let mut aovs = Vec::with_capacity(if options.aovs { n } else { 0 });
                let mut gbuffer = Vec::with_capacity(if s.gbuffer.is_some() { n } else { 0 });
                let mut gbuffer_sum = FilmGBuffer::default();
                // The tile's samples in order, pixel by pixel (a pixel's
                // samples in order), LANES at a time, so that the
                // integrator's lanes stay full when a pass has fewer
                // samples a pixel than lanes (the schedule's first); each
                // lane's estimate is the one its sample gives alone, and
                // they are recorded in order.
                let total = n as u64 * (end - first) as u64;
                // The next sample: its pixel and index.
                let mut next = (tile.x0, tile.y0, first);
                let mut samples = [next; LANES];
                let (mut sum, mut aov) = (PixelSum::default(), AovSum::default());
                let mut row_checked = None;
                for group in (0..total).step_by(LANES) {
                    let count = (total - group).min(LANES as u64) as usize;
                    // Checked once a row, so that an interrupt is obeyed
                    // within a row of a tile.
                    if row_checked != Some(next.1) {
                        if stop_now().is_some() {
                            return None;
                        }
                        row_checked = Some(next.1);
                    }
                    let mut live = 0u32;
                    for k in 0..count {
                        samples[k] = next;
                        let (x, y, index) = next;
                        next = if index + 1 < end {
                            (x, y, index + 1)
                        } else if x + 1 < tile.x1 {
                            (x + 1, y, first)
                        } else {
                            (tile.x0, y + 1, first)
                        };
                        let (position, lens, time, filter_weight) =
                            camera_draws(scene, &pixel_filter, splat.is_some(), &mut samplers[k], samples[k]);
                        (positions[k], lenses[k], times[k]) = (position, lens, time);
                        filter_weights[k] = filter_weight;
                    }
                    // The rays are written where the loop keeps them (see
                    // `Camera::generate_weighted_ray_into`).
                    scene.camera.generate_weighted_rays_into(
                        &positions,
                        &lenses,
                        count,
                        &mut camera_rays,
                        &mut weights,
                    );
                    for k in 0..count {
                        timed(scene, &mut camera_rays[k], times[k]);
                        if weights[k] > 0.0 {
                            live |= 1 << k;
                        }
                    }
                    let ls = integrator.radiance_lanes(scene, &camera_rays, &mut samplers, live, &mut rays);
                    for k in 0..count {
                        let (x, y, index) = samples[k];
                        let (position, ray) = (positions[k], camera_rays[k]);
                        let l = if live & (1 << k) != 0 {
                            ls[k] * weights[k]
                        } else {
                            Rgb::ZERO
                        };
                        if l.is_finite() {
                            let l = limit_component(l, max_component);
                            if let Some(space) = s.gbuffer {
                                // A ray the lens blocks sees nothing (pbrt-v4
                                // adds its weight alone).
                                let surface = (live & (1 << k) != 0)
                                    .then(|| {
                                        camera_gbuffer(scene, &ray, position, lenses[k], space, differential_scale)
                                    })
                                    .flatten();
                                gbuffer_sum.add_sample(surface.as_ref(), filter_weights[k], xyz_from_srgb * l);
                            }
                            match &splat {
                                // Weighted as pbrt-v4's film weighs
                                // samples: Σ w·L / Σ w.
                                None => sum.add(l, filter_weights[k]),
                                Some(sp) => splat_sample(sp, &mut splat_buffer, position, l),
                            }
                        } else {
                            invalid.record(InvalidSample { x, y, index, value: l });
                        }
                        if options.aovs {
                            let a = camera_aov(scene, &ray);
                            if a.albedo.is_finite()
                                && a.normal.is_finite()
                                && a.depth.is_finite()
                                && a.steps.is_finite()
                            {
                                aov.add(&a);
                            }
                        }
                        // The pixel's last sample.
                        if index + 1 == end {
                            let i = (y * w + x) as usize;
                            if splat.is_none() {
                                sums.push(film_ref.pixels[i].plus(&std::mem::take(&mut sum)));
                            }
                            if let Some(a) = &film_ref.aovs {
                                aovs.push(a[i].plus(&std::mem::take(&mut aov)));
                            }
                            if let Some(g) = &film_ref.gbuffer {
                                let mut sums = g[i];
                                sums.merge(&std::mem::take(&mut gbuffer_sum));
                                gbuffer.push(sums);
                            }
                        }
                    }
                }
                progress.add(n as u64 * (end - first) as u64);
                Some(TileResult {
                    tile,
                    sums,
                    splats: splat_buffer.sums,
                    splat_rect,
                    aovs,
                    gbuffer,
                    rays,
                    invalid: invalid.count,
                    invalid_examples: invalid.examples,
                })
            })
            .collect();
        if results.iter().any(Option::is_none) {
            // A pass cut short is abandoned: the film keeps whole passes.
            stopped = Some(stop_now().unwrap_or(Stop::Interrupted));
            break;
        }
        for r in results.into_iter().flatten() {
            let mut k = 0;
            for y in r.tile.y0..r.tile.y1 {
                for x in r.tile.x0..r.tile.x1 {
                    let i = (y * w + x) as usize;
                    if !r.sums.is_empty() {
                        film.pixels[i] = r.sums[k];
                    }
                    if let Some(a) = film.aovs.as_mut() {
                        a[i] = r.aovs[k];
                    }
                    if let Some(g) = film.gbuffer.as_mut() {
                        g[i] = r.gbuffer[k];
                    }
                    k += 1;
                }
            }
            // Adding splats is exact, so the tiles' overlaps do not depend
            // on the order tiles finish in.
            let rect = r.splat_rect;
            let mut k = 0;
            for y in rect.y0..rect.y1 {
                if r.splats.is_empty() {
                    break;
                }
                for x in rect.x0..rect.x1 {
                    film.pixels[(y * w + x) as usize].add_sum(&r.splats[k].sum());
                    k += 1;
                }
            }
            stats.rays += r.rays.rays;
            stats.invalid_samples += r.invalid;
            let room = MAX_INVALID_EXAMPLES - stats.invalid_examples.len();
            stats.invalid_examples.extend(r.invalid_examples.into_iter().take(room));
        }
        stats.samples += w as u64 * h as u64 * (end - first) as u64;
        stats.spp += end - first;
        stats.seconds = earlier_seconds + start.elapsed().as_secs_f64();
        if let Some(show) = control.on_pass.as_mut() {
            show(&film, &stats);
        }
        if options.time_limit.is_some_and(|limit| start.elapsed() >= limit) {
            break;
        }
        if pass < last_pass {
            if let Some(why) = stop_now() {
                stopped = Some(why);
                break;
            }
            if let (Some(every), Some(save)) = (control.checkpoint_every, control.on_checkpoint.as_mut()) {
                if last_checkpoint.elapsed() >= every {
                    save(&film, &stats, &[]);
                    last_checkpoint = Instant::now();
                }
            }
        }
    }
    progress.finish();
    stats.seconds = earlier_seconds + start.elapsed().as_secs_f64();
    RenderOutput {
        film,
        stats,
        stopped,
        extra: Vec::new(),
        state: Vec::new(),
    }
}

/// Runs `algorithm`'s iterations: the scene's `spp` of them, or as many as
/// the time limit or `deadline` allow, at most `spp`. `cancel` and
/// `deadline` are obeyed between iterations (an iteration cut short by
/// `cancel` is dropped), so the image is always that of whole iterations;
/// the deadline never stops the first.
fn render_iterations<P: Progressive>(
    scene: &Scene,
    mut algorithm: P,
    options: &RenderOptions,
    control: &mut Control,
) -> Result<RenderOutput> {
    let s = &scene.settings;
    let (cancel, deadline) = (control.cancel, control.deadline);
    let start = Instant::now();
    let mut stats = RenderStats::default();
    if let Some((film, saved)) = &control.resume {
        if (film.width, film.height) != (s.width, s.height) || saved.spp > s.spp || options.time_limit.is_some() {
            return Err(Error::Invalid(format!(
                "cannot resume: the saved render ({}×{}, {} of {} iterations) does not continue this one{}",
                film.width,
                film.height,
                saved.spp,
                s.spp,
                if options.time_limit.is_some() {
                    " under a time limit"
                } else {
                    ""
                }
            )));
        }
        algorithm
            .restore(scene, &control.resume_state)
            .map_err(|e| Error::Invalid(format!("cannot resume: {e}")))?;
        stats = saved.clone();
    }
    stats.threads = rayon::current_num_threads();
    let earlier_seconds = stats.seconds;
    let mut iterations = stats.spp;
    let time_budget = options
        .time_limit
        .or_else(|| deadline.map(|d| d.saturating_duration_since(start)));
    let progress = Progress::new(
        options.progress,
        s.spp as u64,
        iterations as u64,
        time_budget.map(|b| (start, b)),
    );
    let cancelled = || cancel.is_some_and(|c| c.load(Ordering::Relaxed));
    let mut stopped = None;
    let mut last_checkpoint = Instant::now();
    let first = iterations;
    let finish = |stats: &mut RenderStats, iterations: u32| {
        stats.samples = s.width as u64 * s.height as u64 * iterations as u64;
        stats.spp = iterations;
        stats.seconds = earlier_seconds + start.elapsed().as_secs_f64();
    };
    while iterations < s.spp {
        if cancelled() {
            stopped = Some(Stop::Interrupted);
            break;
        }
        // The deadline never stops the first iteration: there is always an image.
        if iterations > first && deadline.is_some_and(|d| Instant::now() >= d) {
            stopped = Some(Stop::TimeLimit);
            break;
        }
        let Some(work) = algorithm.iterate(scene, cancel) else {
            stopped = Some(Stop::Interrupted);
            break;
        };
        stats.rays += work.rays;
        stats.photons_emitted += work.photons_emitted;
        stats.photon_seconds += work.photon_seconds;
        iterations += 1;
        progress.add(1);
        if options.time_limit.is_some_and(|limit| start.elapsed() >= limit) {
            break;
        }
        if iterations < s.spp {
            if let (Some(every), Some(save)) = (control.checkpoint_every, control.on_checkpoint.as_mut()) {
                if last_checkpoint.elapsed() >= every {
                    finish(&mut stats, iterations);
                    save(&algorithm.film(), &stats, &algorithm.state());
                    last_checkpoint = Instant::now();
                }
            }
        }
    }
    progress.finish();
    finish(&mut stats, iterations);
    Ok(RenderOutput {
        film: algorithm.film(),
        extra: algorithm.extra_images(),
        state: if stopped.is_some() {
            algorithm.state()
        } else {
            Vec::new()
        },
        stats,
        stopped,
    })
}

/// The steps of a progress bar that counts time.
const PROGRESS_STEPS: u64 = 10_000;

/// A progress bar on stderr (only if stderr is a terminal). It counts work
/// (samples, iterations), or, where a time budget may end the render first,
/// whichever of work and time is further along.
struct Progress {
    bar: Option<ProgressBar>,
    total: u64,
    done: AtomicU64,
    /// When the budget started, and how long it is.
    time: Option<(Instant, Duration)>,
}

impl Progress {
    fn new(enabled: bool, total: u64, done: u64, time: Option<(Instant, Duration)>) -> Progress {
        let bar = (enabled && std::io::stderr().is_terminal()).then(|| {
            let steps = if time.is_some() { PROGRESS_STEPS } else { total };
            let bar = ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::stderr_with_hz(4));
            bar.set_style(
                ProgressStyle::with_template("{elapsed_precise} [{wide_bar}] {percent:>3}%  ETA {eta}")
                    .expect("valid template")
                    .progress_chars("=> "),
            );
            bar.enable_steady_tick(Duration::from_millis(250));
            bar
        });
        let progress = Progress {
            bar,
            total,
            done: AtomicU64::new(done),
            time,
        };
        progress.show();
        if let Some(b) = &progress.bar {
            // Work of a resumed render was not done at this rate.
            b.reset_eta();
        }
        progress
    }

    /// `n` more units of work are done.
    fn add(&self, n: u64) {
        // Without a bar nothing is counted: no shared counter for threads.
        if self.bar.is_none() {
            return;
        }
        self.done.fetch_add(n, Ordering::Relaxed);
        self.show();
    }

    fn show(&self) {
        let Some(b) = &self.bar else { return };
        let done = self.done.load(Ordering::Relaxed);
        match self.time {
            None => b.set_position(done),
            Some((from, budget)) => {
                let by_time = from.elapsed().as_secs_f64() / budget.as_secs_f64().max(1e-3);
                let by_work = done as f64 / self.total.max(1) as f64;
                b.set_position((by_time.max(by_work).min(1.0) * PROGRESS_STEPS as f64) as u64);
            }
        }
    }

    fn finish(self) {
        if let Some(b) = self.bar {
            b.finish_and_clear();
        }
    }
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
    fn shards_share_out_every_pass_once_and_evenly() {
        for spp in [8u32, 64, 100, 1000, 4096] {
            let all = pass_schedule(spp);
            for count in 1..=all.len().min(40) as u32 {
                let shares: Vec<Vec<(u32, u32)>> = (0..count)
                    .map(|index| shard_passes(spp, Shard { index, count }).unwrap())
                    .collect();
                let mut union: Vec<(u32, u32)> = shares.concat();
                union.sort();
                assert_eq!(union, all, "{spp} spp, {count} shards");
                let loads: Vec<u32> = shares.iter().map(|s| s.iter().map(|p| p.1 - p.0).sum()).collect();
                let (lo, hi) = (*loads.iter().min().unwrap(), *loads.iter().max().unwrap());
                // Greedy dealing, largest first: the shards differ by at most
                // one of the largest passes.
                assert!(hi - lo <= 16, "{spp} spp, {count} shards: {loads:?}");
                assert!(
                    shares
                        .iter()
                        .all(|s| !s.is_empty() && s.windows(2).all(|w| w[0].0 < w[1].0))
                );
            }
        }
        // 64 spp: passes 1, 1, 2, 4, 8, 16, 16, 16 in four shares of 16.
        let loads: Vec<u32> = (0..4)
            .map(|index| {
                let s = shard_passes(64, Shard { index, count: 4 }).unwrap();
                s.iter().map(|p| p.1 - p.0).sum()
            })
            .collect();
        assert_eq!(loads, [16, 16, 16, 16]);
        let e = shard_passes(64, Shard { index: 0, count: 9 }).unwrap_err().to_string();
        assert!(e.contains("at most 8 shards"), "{e}");
        assert!(shard_passes(64, Shard { index: 4, count: 4 }).is_err());
    }

    #[test]
    fn resumed_renders_go_on_after_the_passes_done() {
        let passes = pass_schedule(64);
        assert_eq!(done_passes(&passes, 0), (true, 0));
        assert_eq!(done_passes(&passes, 2), (true, 2));
        assert_eq!(done_passes(&passes, 3), (false, 3));
        assert_eq!(done_passes(&passes, 64), (true, passes.len()));
        assert!(!done_passes(&passes, 65).0);
    }

    #[test]
    fn tiles_cover_the_image() {
        let t = tiles(37, 20, 16);
        let covered: u32 = t.iter().map(|t| (t.x1 - t.x0) * (t.y1 - t.y0)).sum();
        assert_eq!(covered, 37 * 20);
    }
}
