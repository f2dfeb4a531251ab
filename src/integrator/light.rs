//! Light tracing (particle tracing): paths leave the lights, and every
//! vertex they reach is connected to the camera's lens, which splats its
//! contribution into the pixel it lands in (Arvo and Kirk 1990; Veach 1997
//! §10.3, the t = 1 strategies of bidirectional path tracing; pbrt-v4's
//! `LightPathIntegrator`, Mitsuba 3's `ptracer`).
//!
//! A path starts like a photon ([`Light::sample_le`](crate::light::Light::sample_le)):
//! a light chosen in proportion to its power, a point and a direction, with
//! throughput `β = Le·|cos|/(p_light·p_A·p_ω)`. At every surface vertex with
//! a non-delta lobe the camera is sampled ([`Camera::sample_wi`]) and, if
//! nothing is in the way, the vertex adds
//!
//! ```text
//! β · f(wo → wi_camera) · |cos| · We / p_camera
//! ```
//!
//! to the pixel it is seen in (the BSDF is the adjoint one, with Veach's
//! shading-normal correction, eq. 5.21). The area lights' own points are
//! connected too, so that lights seen directly appear. An iteration traces
//! one path per pixel; the image after k iterations is the sum of the
//! splats divided by k, which estimates what the path tracer's camera rays
//! measure. Lights at infinity and point lights cannot be seen this way
//! (as in pbrt), so a background seen directly stays black; delta BSDFs
//! (mirrors, smooth glass) are bounced through but never connected, so
//! what is seen only through them is black too: the light tracer is for
//! caustics on diffuse surfaces seen directly, and for teaching.
//!
//! Paths are traced in fixed chunks whose random numbers come from (seed,
//! iteration, path) alone, and the chunks' splats are added in order, so
//! the image is the same for any number of threads.

use crate::color::{Rgb, luminance};
use crate::film::splat::{MAX_TAPS, Splat};
use crate::film::{AovSum, Film, FilmAov, FilmPixel, PixelSum};
use crate::geometry::Ray;
use crate::geometry::interaction::SHADOW_EPSILON;
use crate::integrator::aov::camera_aov;
use crate::integrator::state::{StateReader, StateWriter};
use crate::integrator::{Progressive, Work, adjoint_shading_factor, material_path_bsdf};
use crate::material::TransportMode;
use crate::sampling::rng::{Pcg32, hash_u64s};
use crate::scene::Scene;
use crate::texture::TexCoord;
use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Paths per work unit for an iteration of `paths` paths (see
/// [`super::work_unit_len`]; the units' splats are added in path order
/// whatever their length, so the image does not depend on it).
pub(crate) fn chunk_len(paths: u32) -> u32 {
    super::work_unit_len(paths, 4096)
}

/// Work units traced before their splats are added to the image.
const BATCH: u32 = 64;

/// Separates light tracing's random numbers from the photon passes'.
const STREAM: u64 = 0x6c69_6768_7420;

/// Light tracing's state between iterations: the image of its splats.
pub struct LightTracer {
    /// Longest path, in segments from the light to the camera.
    max_depth: u32,
    image: SplatImage,
}

/// An image made of splats, iteration by iteration (light tracing and
/// bidirectional path tracing): per pixel the sum of its splats over the
/// iterations, and the iterations' count.
pub(crate) struct SplatImage {
    /// Where splats land.
    target: SplatTarget,
    /// Per pixel, row by row from the top: Σ over iterations of the
    /// iteration's splats, and of their luminance squared.
    sums: Vec<DVec3>,
    lum_sq: Vec<f64>,
    /// Auxiliary sums from one camera ray per pixel and iteration.
    aovs: Option<Vec<AovSum>>,
    /// Per column and per row, the share of the filter about the pixel's
    /// centre that lies inside the image: the camera passes normalise
    /// each pixel by the weights its samples brought, which near the
    /// border are that share of the rest, so the splats are divided by it.
    inside: (Vec<f64>, Vec<f64>),
    iterations: u32,
}

/// The share of `filter`'s 1D profile about each of `n` pixel centres
/// that lies within [0, n] (midpoint rule).
fn share_inside(filter: &crate::settings::Filter, n: u32) -> Vec<f64> {
    let r = filter.radius();
    let steps = 256;
    let at = |c: f32, lo: f32, hi: f32| -> f64 {
        (0..steps)
            .map(|i| {
                let x = -r + 2.0 * r * (i as f32 + 0.5) / steps as f32;
                if (lo..hi).contains(&(c + x)) {
                    filter.eval_1d(x) as f64
                } else {
                    0.0
                }
            })
            .sum()
    };
    (0..n)
        .map(|j| {
            let c = j as f32 + 0.5;
            at(c, 0.0, n as f32) / at(c, f32::NEG_INFINITY, f32::INFINITY)
        })
        .collect()
}

impl LightTracer {
    /// Nothing traced yet; `aovs` asks for the auxiliary sums. A camera
    /// that light cannot reach (an orthographic one with a lens) is
    /// refused when the scene is built, and sees nothing here.
    pub fn new(scene: &Scene, aovs: bool) -> LightTracer {
        LightTracer {
            max_depth: scene.settings.max_depth,
            image: SplatImage::new(scene, aovs),
        }
    }
}

impl SplatImage {
    /// An image of no iterations; `aovs` asks for the auxiliary sums.
    pub(crate) fn new(scene: &Scene, aovs: bool) -> SplatImage {
        let s = &scene.settings;
        let n = s.width as usize * s.height as usize;
        SplatImage {
            target: SplatTarget {
                width: s.width,
                height: s.height,
                splat: Splat::new(&s.pixel_filter()),
            },
            sums: vec![DVec3::ZERO; n],
            lum_sq: vec![0.0; n],
            aovs: aovs.then(|| vec![AovSum::default(); n]),
            inside: match Splat::new(&s.pixel_filter()) {
                Some(_) => (
                    share_inside(&s.pixel_filter().x, s.width),
                    share_inside(&s.pixel_filter().y, s.height),
                ),
                None => (vec![1.0; s.width as usize], vec![1.0; s.height as usize]),
            },
            iterations: 0,
        }
    }

    /// One more iteration: `trace(i, rng, target, scratch, splats, rays)`
    /// for every pixel index `i` (`scratch`: the chunk's working memory,
    /// reused from path to path), with random numbers from (seed, `stream`, iteration, i)
    /// alone, in fixed chunks whose splats are added in chunk order, so
    /// that the image is the same for any number of threads; given up
    /// (`None`) soon after `cancel` is set. Splats to other images than
    /// this one (`splats.extra`: image, pixel, value) go to `extra`, in
    /// the same order. Returns the rays traced.
    pub(crate) fn iterate<S, F>(
        &mut self,
        scene: &Scene,
        stream: u64,
        cancel: Option<&AtomicBool>,
        trace: F,
        extra: &mut dyn FnMut(u32, u32, Rgb),
    ) -> Option<u64>
    where
        S: Default,
        F: Fn(u32, &mut Pcg32, &SplatTarget, &mut S, &mut Splats, &mut u64) + Sync,
    {
        let target = &self.target;
        let paths = target.width * target.height;
        let (seed, iteration) = (scene.settings.seed, self.iterations as u64);
        let mut this = self.blank();
        let mut rays = 0;
        // Chunks in batches, each batch's splats added in chunk order
        // before the next is traced: the splats held at once stay bounded
        // however large the image.
        let chunk = chunk_len(paths);
        let chunks = paths.div_ceil(chunk);
        for batch in (0..chunks).step_by(BATCH as usize) {
            let parts: Vec<(Splats, u64)> = (batch..(batch + BATCH).min(chunks))
                .into_par_iter()
                .map(|c| {
                    let (mut splats, mut rays) = (Splats::default(), 0u64);
                    if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                        return (splats, rays);
                    }
                    let mut scratch = S::default();
                    for i in c * chunk..((c + 1) * chunk).min(paths) {
                        let mut rng = Pcg32::new(hash_u64s(&[seed, stream, iteration, i as u64]), 0x5bd1);
                        trace(i, &mut rng, target, &mut scratch, &mut splats, &mut rays);
                    }
                    (splats, rays)
                })
                .collect();
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                return None;
            }
            for (splats, r) in parts {
                rays += r;
                gather(&mut this, splats, extra);
            }
        }
        Some(rays + self.end_iteration(scene, stream, &this))
    }

    /// Writes the sums and the number of iterations (for checkpoints).
    pub(crate) fn write_state(&self, w: &mut StateWriter) {
        w.u32(self.iterations);
        w.dvec3s(&self.sums);
        w.f64s(&self.lum_sq);
        match &self.aovs {
            None => w.u32(0),
            Some(aovs) => {
                w.u32(1);
                w.u64(aovs.len() as u64);
                for a in aovs {
                    w.aov(a);
                }
            }
        }
    }

    /// Reads what [`SplatImage::write_state`] wrote, for an image of this
    /// size and the same auxiliary sums.
    pub(crate) fn read_state(&mut self, r: &mut StateReader) -> Result<(), String> {
        let n = self.sums.len();
        self.iterations = r.u32()?;
        self.sums = r.dvec3s(n)?;
        self.lum_sq = r.f64s(n)?;
        let has_aovs = r.u32()? == 1;
        if has_aovs != self.aovs.is_some() {
            return Err("the saved state and the render disagree on auxiliary images".into());
        }
        if let Some(aovs) = &mut self.aovs {
            if r.count(9 * 8)? != n {
                return Err("the saved auxiliary images are of another size".into());
            }
            for a in aovs.iter_mut() {
                *a = r.aov()?;
            }
        }
        let finite = self.sums.iter().all(|s| s.is_finite()) && self.lum_sq.iter().all(|s| s.is_finite());
        if !finite {
            return Err("a saved sum is not a finite number".into());
        }
        Ok(())
    }

    /// The sums alone as a saved state (for an algorithm whose state is
    /// its image).
    pub(crate) fn state(&self) -> Vec<u8> {
        let mut w = StateWriter::default();
        self.write_state(&mut w);
        w.0
    }

    /// Reads what [`SplatImage::state`] wrote.
    pub(crate) fn restore(&mut self, state: &[u8]) -> Result<(), String> {
        let mut r = StateReader::new(state);
        self.read_state(&mut r)?;
        r.finish()
    }

    /// The iterations added so far.
    pub(crate) fn iterations(&self) -> u32 {
        self.iterations
    }

    /// Where splats land.
    pub(crate) fn target(&self) -> &SplatTarget {
        &self.target
    }

    /// A zero image to gather one iteration's splats in.
    pub(crate) fn blank(&self) -> Vec<DVec3> {
        vec![DVec3::ZERO; self.sums.len()]
    }

    /// Adds iteration image `this` (an estimate of the image by itself) to
    /// the sums, with the auxiliary images' camera rays (random numbers
    /// from seed, `stream` + 1, iteration and pixel); returns those rays.
    pub(crate) fn end_iteration(&mut self, scene: &Scene, stream: u64, this: &[DVec3]) -> u64 {
        let (seed, iteration) = (scene.settings.seed, self.iterations as u64);
        let mut rays = 0;
        for ((sum, sq), l) in self.sums.iter_mut().zip(&mut self.lum_sq).zip(this) {
            *sum += *l;
            let y = luminance(l.as_vec3()) as f64;
            *sq += y * y;
        }
        if let Some(aovs) = &mut self.aovs {
            let w = self.target.width as usize;
            aovs.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                for (x, sum) in row.iter_mut().enumerate() {
                    let mut rng = Pcg32::new(hash_u64s(&[seed, stream + 1, iteration, (y * w + x) as u64]), 0x5bd1);
                    let film = Vec2::new(x as f32 + rng.next_f32(), y as f32 + rng.next_f32());
                    let lens = Vec2::new(rng.next_f32(), rng.next_f32());
                    let time = scene.camera.time_from(|| rng.next_f32());
                    sum.add(&camera_aov(scene, &scene.camera.generate_ray(film, lens).at_time(time)));
                }
            });
            rays += (self.target.width * self.target.height) as u64;
        }
        self.iterations += 1;
        rays
    }

    /// The film of per-pixel sums `sums` of splats over the iterations
    /// (an image other than this one, of the same size), normalised as
    /// this one's: the mean over iterations, divided by the share of the
    /// filter inside the image.
    pub(crate) fn film_of(&self, sums: &[DVec3]) -> Film {
        let mut film = Film::new(self.target.width, self.target.height);
        let k = self.iterations as f64;
        let w = self.target.width as usize;
        for (i, (pixel, sum)) in film.pixels.iter_mut().zip(sums).enumerate() {
            let share = self.inside.0[i % w] * self.inside.1[i / w];
            *pixel = FilmPixel::default().plus(&PixelSum {
                rgb: *sum,
                weight: k * share,
                lum_sq: 0.0,
            });
        }
        film
    }

    /// Each pixel is the mean over iterations of its splats.
    pub(crate) fn film(&self) -> Film {
        let mut film = Film::new(self.target.width, self.target.height);
        let k = self.iterations as f64;
        let w = self.target.width as usize;
        for (i, ((pixel, sum), sq)) in film.pixels.iter_mut().zip(&self.sums).zip(&self.lum_sq).enumerate() {
            let share = self.inside.0[i % w] * self.inside.1[i / w];
            *pixel = FilmPixel::default().plus(&PixelSum {
                rgb: *sum,
                weight: k * share,
                lum_sq: *sq,
            });
        }
        if let Some(aovs) = &self.aovs {
            film.aovs = Some(aovs.iter().map(|a| FilmAov::default().plus(a)).collect());
        }
        film
    }
}

/// Adds `splats` to iteration image `this` in their order, and hands
/// those to other images to `extra`.
pub(crate) fn gather(this: &mut [DVec3], splats: Splats, extra: &mut dyn FnMut(u32, u32, Rgb)) {
    for (px, l) in splats.image {
        this[px as usize] += l.as_dvec3();
    }
    for (image, px, l) in splats.extra {
        extra(image, px, l);
    }
}

/// What a chunk of paths splats: onto the image, and onto other images
/// (image, pixel, value).
#[derive(Default)]
pub(crate) struct Splats {
    pub image: Vec<(u32, Rgb)>,
    pub extra: Vec<(u32, u32, Rgb)>,
}

/// The image's pixels as splats reach them: its size and the filter.
pub(crate) struct SplatTarget {
    width: u32,
    height: u32,
    /// Filter weights for filters wider than a pixel.
    splat: Option<Splat>,
}

impl SplatTarget {
    /// Adds contribution `l` at raster position `raster`: into its pixel,
    /// or spread by the filter's weights over the pixels it covers.
    pub(crate) fn add_splat(&self, raster: Vec2, l: Rgb, out: &mut Vec<(u32, Rgb)>) {
        self.splat_with(raster, l, |px, v| out.push((px, v)));
    }

    /// [`SplatTarget::add_splat`], giving each (pixel, value) to `emit`.
    pub(crate) fn splat_with(&self, raster: Vec2, l: Rgb, mut emit: impl FnMut(u32, Rgb)) {
        let (w, h) = (self.width, self.height);
        match &self.splat {
            None => {
                let (x, y) = ((raster.x as u32).min(w - 1), (raster.y as u32).min(h - 1));
                emit(y * w + x, l);
            }
            Some(splat) => {
                let (mut wx, mut wy) = ([0.0; MAX_TAPS], [0.0; MAX_TAPS]);
                let (x0, xs) = splat.taps_x(raster.x, 0, w, &mut wx);
                let (y0, ys) = splat.taps_y(raster.y, 0, h, &mut wy);
                for (dy, fy) in ys.iter().enumerate() {
                    for (dx, fx) in xs.iter().enumerate() {
                        if fx * fy != 0.0 {
                            emit((y0 + dy as u32) * w + x0 + dx as u32, l * (fx * fy));
                        }
                    }
                }
            }
        }
    }
}

impl Progressive for LightTracer {
    /// One path per pixel, given up (and the whole iteration with it) soon
    /// after `cancel` is set.
    fn iterate(&mut self, scene: &Scene, cancel: Option<&AtomicBool>) -> Option<Work> {
        let bounds = crate::light::scene_bounding_sphere(scene);
        let max_depth = self.max_depth;
        let result = self.image.iterate(
            scene,
            STREAM,
            cancel,
            |_, rng, target, _: &mut (), splats, rays| {
                trace_path(scene, max_depth, target, bounds, rng, &mut splats.image, rays)
            },
            &mut |_, _, _| {},
        );
        result.map(|rays| Work {
            rays,
            ..Work::default()
        })
    }

    fn film(&self) -> Film {
        self.image.film()
    }

    fn state(&self) -> Vec<u8> {
        self.image.state()
    }

    fn restore(&mut self, _scene: &Scene, state: &[u8]) -> Result<(), String> {
        self.image.restore(state)
    }
}

/// Traces one light path, adding its splats (pixel, contribution) to
/// `out`. The importance is normalised over the whole image, so a path
/// estimates the image times its number of pixels; with one path per
/// pixel in an iteration, the splats are the iteration's image.
fn trace_path(
    scene: &Scene,
    max_depth: u32,
    target: &SplatTarget,
    bounds: (Vec3, f32),
    rng: &mut Pcg32,
    out: &mut Vec<(u32, Rgb)>,
    rays: &mut u64,
) {
    if scene.lights.is_empty() || scene.light_distribution.is_empty() {
        return;
    }
    let Some((emitted, _, pmf)) = crate::light::sample_scene_emission(scene, &scene.light_distribution, bounds, rng)
    else {
        return;
    };
    // The light's own point, seen directly (one segment).
    let u_lens = Vec2::new(rng.next_f32(), rng.next_f32());
    let time = scene.camera.time_from(|| rng.next_f32());
    if let (Some(point), true) = (emitted.surface, scene.settings.shows_emission(1)) {
        if let Some(c) = scene.camera.sample_wi_at(point.p, u_lens, time) {
            let cos = crate::light::emitting_cosine(point.n, c.wi, point.two_sided);
            if cos > 0.0 {
                *rays += 1;
                let end = point.p + c.wi * c.dist;
                let origin = point.origin_toward(c.wi);
                let shadow = Ray::with_interval(origin, end - origin, 0.0, SHADOW_EPSILON).at_time(time);
                if !scene.occluded(&shadow) {
                    let l = point.le * (cos * c.weight / (point.pdf_area * pmf));
                    target.add_splat(c.raster, l, out);
                }
            }
        }
    }

    let mut beta = emitted.weight / pmf;
    let mut ray = emitted.ray.at_time(time);
    // Segments of the path once it reaches the camera from the next
    // vertex: light → vertex → camera.
    let mut segments = 2u32;
    // The path's wavelength, once it has met a dispersive glass.
    let mut wavelength = None;
    while segments <= max_depth {
        *rays += 1;
        let Some(mut hit) = scene.intersect(&ray) else {
            return;
        };
        scene.choose_any_material(&mut hit, ray.dir);
        let m = &scene.materials[hit.material as usize];
        let tc = TexCoord::at(&hit);
        // A mask's cut-out part lets the light through unchanged, as
        // the path tracer's camera paths pass it.
        if m.cut_out(&scene.textures, &tc, || rng.next_f32()) {
            ray = hit.spawn_ray(ray.dir);
            segments += 1;
            continue;
        }
        let mut spectral = Rgb::ONE;
        let bsdf = material_path_bsdf(
            scene,
            hit.material,
            &tc,
            &mut wavelength,
            || rng.next_f32(),
            &mut spectral,
        );
        beta *= spectral;
        let wo_world = -ray.dir.normalize();
        if !m.two_sided && !bsdf.transmits() && !hit.is_front(wo_world) {
            return; // the back of a one-sided surface absorbs
        }
        let ng_wo = hit.ng.dot(wo_world);
        if ng_wo == 0.0 {
            return;
        }
        let frame = m.shading_frame(&scene.textures, &hit, wo_world);
        let wo = frame.to_local(wo_world);
        let front_o = ng_wo > 0.0;
        // The adjoint BSDF with shading normals (Veach 1997, eq. 5.21)
        // toward the lens, and a normal map's factor toward the light,
        // as the photons' bounces take them (`scatter_light`).
        let u_lens = Vec2::new(rng.next_f32(), rng.next_f32());
        if bsdf.has_smooth() {
            if let Some(c) = scene.camera.sample_wi_at(hit.p, u_lens, hit.time) {
                let wi = frame.to_local(c.wi);
                let front_i = hit.ng.dot(c.wi) > 0.0;
                let consistent = (front_i == front_o) == (wi.z * wo.z > 0.0);
                if consistent && wi.z != 0.0 {
                    let f = bsdf.eval(wo, wi, TransportMode::Importance);
                    if f != Rgb::ZERO {
                        let l = beta
                            * f
                            * (frame.factor(wo_world)
                                * wi.z.abs()
                                * adjoint_shading_factor(hit.ng, wo_world, wo.z, c.wi, wi.z)
                                * c.weight);
                        *rays += 1;
                        if l.is_finite() && !scene.occluded(&hit.spawn_ray_to(hit.p + c.wi * c.dist)) {
                            target.add_splat(c.raster, l, out);
                        }
                    }
                }
            }
        }
        if segments == max_depth {
            return;
        }

        let Some((next, next_ray, _)) = crate::integrator::scatter_light(&hit, &bsdf, &frame, wo_world, beta, rng)
        else {
            return;
        };
        beta = next;
        ray = next_ray;
        segments += 1;
    }
}
