//! Vertex connection and merging (Georgiev, Křivánek, Davidovič and
//! Slusallek 2012, "Light Transport Simulation with Vertex Connection and
//! Merging"; Hachisuka, Pantaleoni and Jensen 2012 derived the same
//! "unified path sampling"): bidirectional path tracing and photon
//! mapping under one multiple importance sampling.
//!
//! In each iteration every pixel traces a camera subpath and a light
//! subpath and makes every bidirectional strategy as [`super::Bdpt`] does;
//! at each camera vertex with a non-delta lobe it also *merges*: every
//! light vertex y that the previous iteration's N light subpaths (N the
//! pixels) left on a surface with a non-delta lobe, within radius r of
//! camera vertex x, is taken as if the light subpath had reached x, its
//! throughput times the BSDF at x over π r² N (photon density estimation
//! with a box kernel). The previous iteration's light subpaths are
//! independent of this one's camera subpaths, as merging needs, and so
//! each light subpath serves the connections of its pixel and, stored in
//! a kd-tree, the merges of the next iteration; the first iteration is
//! BDPT alone.
//!
//! Merging at x is one more way to sample a path, of density (eq. 11)
//! p_VM = p_light(x) · p_camera(x) · π r² N, where p_light(x) and
//! p_camera(x) are the densities of the path's vertices up to x sampled
//! from either side; so the power heuristic weighs merges against
//! connections with the same ratios of densities that BDPT's weights use,
//! each merge at a vertex adding (ratio · p(x) · η)², η = π r² N. The
//! weights of all strategies that make a path, connections and merges,
//! sum to one (a unit test over random paths). A merge's weight needs the
//! light subpath behind the photon: its sums are accumulated along the
//! subpath when the photon is stored ([`LightVertex`]), where Georgiev's
//! implementation carries them as its recursive dVCM, dVC, dVM.
//!
//! Where glass disperses, a pixel's camera and light subpaths share one
//! wavelength, drawn first from the light subpath's numbers (so that a
//! resumed render traces the stored light subpaths again alike); a merge
//! weights the camera subpath by its wavelength and the light vertex by
//! its own where each disperses, as photon mapping joins photons and
//! camera paths.
//!
//! The radius shrinks as r_i = r₁ · i^((α−1)/2) over the iterations
//! (Knaus and Zwicker 2011), so the bias of merging vanishes and the
//! image converges; r₁ and α are photon mapping's (`photon_radius`, by
//! default two pixel footprints, and `sppm_alpha`).

use super::{Kind, LIGHT_STREAM, STREAM, Subpaths, Tracer, Vertex, delta_before, remap, sq, vertex_f};
use crate::color::Rgb;
use crate::color::spectrum::{WavelengthSample, visible_wavelength_weight};
use crate::film::Film;
use crate::integrator::light::{SplatImage, chunk_len};
use crate::integrator::photon::map::Located;
use crate::integrator::photon::{PhotonMap, same_surface};
use crate::integrator::{Progressive, Work};
use crate::sampling::Uniforms;
use crate::sampling::rng::{Pcg32, hash_u64s};
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::f32::consts::PI;
use std::sync::Mutex;
use std::sync::atomic::AtomicBool;

/// Separates the light subpaths' random numbers from the pixels'.
const LIGHT_PASS_STREAM: u64 = 0x7663_6d6c;

/// A light-subpath vertex stored for merging, with what a merge's weight
/// needs of the subpath behind it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LightVertex {
    p: Vec3,
    /// Geometric normal.
    ng: Vec3,
    /// Unit direction toward the previous vertex, where the light came
    /// from.
    wi: Vec3,
    /// Throughput of the light subpath up to here: the photon's power.
    beta: Rgb,
    /// Segments from the light to here.
    segments: u32,
    /// Density of this vertex sampled from the light's side, per unit
    /// area (after a delta bounce, the Dirac's cos/d²).
    pdf_fwd: f32,
    /// The previous vertex's density from the light's side; the factor
    /// turning a density per solid angle here toward it into one per its
    /// unit area; whether it scattered by a delta lobe.
    prev_pdf_fwd: f32,
    prev_to_area: f32,
    prev_delta: bool,
    /// The strategies that end the light subpath at the previous vertex,
    /// relative to their density: one for a connection there (where
    /// possible), (p(prev)·η)² for a merge there.
    prev_strategies: f32,
    /// Σ over the strategies ending the light subpath before the previous
    /// vertex of their squared density ratio to the one ending at it
    /// ([`Tracer::mis_weight`]'s light-side sum, stopped one vertex short).
    earlier: f32,
    /// The bin of the light subpath's wavelength where a vertex before
    /// this one disperses ([`visible_wavelength_weight`]), else
    /// [`NOT_DISPERSED`]: two bytes that fit beside `prev_delta`.
    wavelength_bin: u16,
}

// The bin costs a stored vertex nothing (`BYTES_PER_LIGHT_VERTEX` counts these).
const _: () = assert!(std::mem::size_of::<LightVertex>() == 76);

/// [`LightVertex::wavelength_bin`] of light that no glass dispersed.
const NOT_DISPERSED: u16 = u16::MAX;

impl LightVertex {
    /// The weight of its light subpath's wavelength, where that matters.
    #[inline]
    fn spectral(&self) -> Rgb {
        if self.wavelength_bin == NOT_DISPERSED {
            Rgb::ONE
        } else {
            visible_wavelength_weight(self.wavelength_bin)
        }
    }
}

impl Located for LightVertex {
    #[inline]
    fn position(&self) -> Vec3 {
        self.p
    }
}

impl<'s> Tracer<'s> {
    /// The strategies that end a light subpath at its vertex `i`,
    /// relative to their density: a connection from there (where neither
    /// it nor the vertex before is delta) and a merge there (at a surface
    /// that did not scatter by a delta lobe).
    fn strategies_at(&self, light: &[Vertex], i: usize) -> f32 {
        let v = &light[i];
        let connection = if !v.delta && !delta_before(light, i) { 1.0 } else { 0.0 };
        let merge = if i > 0 && v.merges() {
            sq(remap(v.pdf_fwd) * self.merge_eta)
        } else {
            0.0
        };
        connection + merge
    }

    /// Appends the vertices of light subpath `light` where merging can
    /// happen (surfaces with a non-delta lobe), each with the sums over
    /// the subpath behind it.
    pub(super) fn light_vertices(
        &self,
        light: &[Vertex],
        wavelength: Option<WavelengthSample>,
        out: &mut Vec<LightVertex>,
    ) {
        // Σ_{i ≤ j−2} strategies(i) · Π_{m=i}^{j−2} (rev_m / fwd_m)², the
        // light-side sum of the weights up to vertex j − 2.
        let mut earlier = 0.0f32;
        let mut wavelength_bin = NOT_DISPERSED;
        for j in 1..light.len() {
            let (y, prev) = (&light[j], &light[j - 1]);
            // The light reaching y depends on the wavelength where a vertex
            // before y scattered it dispersively (y's own BSDF is x's in a
            // merge).
            if let (Some(w), true) = (wavelength, prev.disperses) {
                wavelength_bin = w.bin;
            }
            let prev_strategies = self.strategies_at(light, j - 1);
            if y.kind == Kind::Surface && y.connectible {
                out.push(LightVertex {
                    p: y.p,
                    ng: y.ng,
                    wi: y.wo,
                    beta: y.beta,
                    segments: j as u32,
                    pdf_fwd: y.pdf_fwd,
                    prev_pdf_fwd: prev.pdf_fwd,
                    prev_to_area: self.convert(1.0, y, prev),
                    prev_delta: prev.delta,
                    prev_strategies,
                    earlier,
                    wavelength_bin,
                });
            }
            // prev's reverse density is the walk's: the one from y.
            earlier = sq(remap(prev.pdf_rev) / remap(prev.pdf_fwd)) * (prev_strategies + earlier);
        }
    }

    /// The strategies that end a camera subpath at its vertex `i` ≥ 1,
    /// relative to their density (as [`Tracer::strategies_at`] on the
    /// light side).
    fn camera_strategies_at(&self, camera: &[Vertex], i: usize) -> f32 {
        let v = &camera[i];
        let connection = if !v.delta && !camera[i - 1].delta { 1.0 } else { 0.0 };
        let merge = if v.merges() {
            sq(remap(v.pdf_fwd) * self.merge_eta)
        } else {
            0.0
        };
        connection + merge
    }

    /// What a merge at x = `camera[t − 1]` (a surface with a non-delta
    /// lobe) needs of the camera subpath, whichever light vertex it meets.
    pub(super) fn merge_site(&self, camera: &[Vertex], t: usize) -> Option<MergeSite> {
        let x = &camera[t - 1];
        let (_, frame) = x.bsdf.as_ref()?;
        // Σ_{1 ≤ i ≤ t−3} strategies(i) · Π_{m=i}^{t−3} (rev_m / fwd_m)²,
        // with the walk's reverse densities (those through x's
        // neighbour), then the strategies at t − 2.
        let mut before = 0.0f32;
        for m in 1..t.saturating_sub(2) {
            let r = remap(camera[m].pdf_rev) / remap(camera[m].pdf_fwd);
            before = sq(r) * (self.camera_strategies_at(camera, m) + before);
        }
        if t >= 3 {
            before += self.camera_strategies_at(camera, t - 2);
        }
        Some(MergeSite {
            t,
            wo: frame.to_local(x.wo),
            before,
            to_prev: if t >= 3 {
                self.convert(1.0, x, &camera[t - 2])
            } else {
                0.0
            },
        })
    }

    /// The power heuristic's weight of merging at `site` with `y` (whose
    /// direction toward the light is `wi` in x's shading frame) among
    /// every strategy that makes the path: the light subpath behind y,
    /// then x and the camera subpath. As [`Tracer::mis_weight`] weighs
    /// connections: ratios of each strategy's density to that of the
    /// connection between y's previous vertex and x, outward from x on
    /// both sides.
    pub(super) fn merge_weight(&self, camera: &[Vertex], site: &MergeSite, y: &LightVertex, wi: Vec3) -> f32 {
        let (t, wo) = (site.t, site.wo);
        let x = &camera[t - 1];
        let Some((bsdf, _)) = &x.bsdf else {
            return 0.0;
        };
        let eta = self.merge_eta;
        // This merge: x reached from both sides.
        let own = sq(remap(y.pdf_fwd) * eta);
        let mut sum = own;
        // The camera side: x, then the vertices before it, sampled from
        // the light's side instead.
        let ratio = remap(y.pdf_fwd) / remap(x.pdf_fwd);
        if !camera[t - 2].delta {
            sum += ratio * ratio;
        }
        if t >= 3 {
            let rev = bsdf.pdf(wi, wo) * site.to_prev;
            sum += sq(ratio * remap(rev) / remap(camera[t - 2].pdf_fwd)) * site.before;
        }
        // The connection of y's previous vertex to x.
        if !y.prev_delta {
            sum += 1.0;
        }
        // The light side: y's previous vertex and those before it sampled
        // from the camera's side, through x.
        let rev = bsdf.pdf(wo, wi) * y.prev_to_area;
        sum += sq(remap(rev) / remap(y.prev_pdf_fwd)) * (y.prev_strategies + y.earlier);
        let w = own / sum;
        if w.is_finite() { w } else { 0.0 }
    }

    /// Every merge along the sample's camera subpath with the stored
    /// light vertices within √`r2`, weighted, with the kernel's
    /// 1/(π r² N): at x, a light vertex y taken to lie at x adds the
    /// camera subpath's throughput, the BSDF at x toward y's light and
    /// y's throughput.
    fn merges(&self, map: &PhotonMap<LightVertex>, r2: f32, work: &Subpaths) -> Rgb {
        let camera = &work.camera;
        let mut total = Rgb::ZERO;
        let mut spectral = Rgb::ONE;
        for t in 2..=camera.len() {
            let x = &camera[t - 1];
            // x's BSDF is evaluated at the camera subpath's wavelength too.
            if let (Some(w), true) = (work.wavelength, x.disperses || camera[t - 2].disperses) {
                spectral = w.weight;
            }
            // Light segments the path has room for.
            let room = (self.max_depth as usize + 1).saturating_sub(t);
            if x.kind != Kind::Surface || !x.connectible || room == 0 {
                continue;
            }
            let Some(site) = self.merge_site(camera, t) else {
                continue;
            };
            let Some((_, frame)) = &x.bsdf else {
                continue;
            };
            map.for_each_within(x.p, r2, |y, _| {
                if y.segments as usize > room || !same_surface(y.ng, x.ng) {
                    return;
                }
                let f = vertex_f(x, y.wi);
                if f != Rgb::ZERO {
                    let w = self.merge_weight(camera, &site, y, frame.to_local(y.wi));
                    total += x.beta * f * y.beta * (spectral * y.spectral() * w);
                }
            });
        }
        let l = total * (1.0 / self.merge_eta);
        if l.is_finite() { l } else { Rgb::ZERO }
    }
}

/// What merging at a camera vertex x needs of the camera subpath.
pub(super) struct MergeSite {
    /// x is the subpath's vertex t − 1.
    t: usize,
    /// Unit direction from x toward the camera, in x's shading frame.
    wo: Vec3,
    /// The strategies ending the camera subpath at its vertex t − 2 and
    /// before, relative to their densities, as ratios to the one ending
    /// at t − 2 (zero for t = 2).
    before: f32,
    /// The factor turning a density per solid angle at x toward vertex
    /// t − 2 into one per its unit area.
    to_prev: f32,
}

/// The numbers of one pixel sample: the light subpath's from a generator
/// of their own, seeded by (seed, iteration, pixel) alone, so that the
/// light vertices an iteration leaves for the next can be traced again
/// without the camera subpath (to resume from a checkpoint); the rest
/// from the pixel's generator.
struct SeparateLight<'a> {
    pixel: &'a mut Pcg32,
    light: Pcg32,
    on_light: bool,
}

impl Uniforms for SeparateLight<'_> {
    #[inline]
    fn next_f32(&mut self) -> f32 {
        if self.on_light {
            self.light.next_f32()
        } else {
            self.pixel.next_f32()
        }
    }

    #[inline]
    fn start_stream(&mut self, index: u32) {
        self.on_light = index == LIGHT_STREAM;
    }
}

/// The generator of pixel `i`'s light subpath in iteration `iteration`.
fn light_generator(seed: u64, iteration: u32, i: u32) -> Pcg32 {
    Pcg32::new(
        hash_u64s(&[seed, LIGHT_PASS_STREAM, iteration as u64, i as u64]),
        0x5bd1,
    )
}

/// Vertex connection and merging's state between iterations: its image,
/// and the light vertices the last iteration left.
pub struct Vcm {
    max_depth: u32,
    image: SplatImage,
    /// The first iteration's radius r₁, and α of the radius' reduction.
    radius: f32,
    alpha: f32,
    /// The vertices of the last iteration's light subpaths, with their
    /// sums for the next iteration's radius: the next iteration's camera
    /// vertices merge with them.
    previous: PhotonMap<LightVertex>,
}

impl Vcm {
    /// Nothing traced yet; `aovs` asks for the auxiliary sums.
    pub fn new(scene: &Scene, aovs: bool) -> Vcm {
        let s = &scene.settings;
        Vcm {
            max_depth: s.max_depth,
            image: SplatImage::new(scene, aovs),
            radius: s.photon.radius_for(scene),
            alpha: s.photon.alpha,
            previous: PhotonMap::default(),
        }
    }

    /// The merging radius of iteration `i` (from 0).
    pub fn radius_of_iteration(&self, i: u32) -> f32 {
        self.radius * ((i + 1) as f32).powf(0.5 * (self.alpha - 1.0))
    }

    /// The tracer whose weights are those of iteration `i`: η = π r_i² N
    /// for N light subpaths, none in the first, which has no light
    /// vertices to merge with.
    fn tracer<'s>(&self, scene: &'s Scene, i: u32) -> Tracer<'s> {
        let r = self.radius_of_iteration(i);
        let paths = (scene.settings.width * scene.settings.height) as f32;
        let eta = if i == 0 { 0.0 } else { PI * r * r * paths };
        Tracer::new(scene, self.max_depth).merging(eta)
    }
}

/// The light vertices of iteration `iteration`'s light subpaths, one per
/// pixel, as that iteration stored them (`tracer`: the next iteration's):
/// in chunks gathered in order, the same for any number of threads.
fn light_vertices_of(tracer: &Tracer, scene: &Scene, iteration: u32) -> Vec<LightVertex> {
    let s = &scene.settings;
    let paths = s.width * s.height;
    let vertices = if tracer.max_depth < 2 {
        0
    } else {
        tracer.max_depth as usize
    };
    let chunk = chunk_len(paths);
    let parts: Vec<Vec<LightVertex>> = (0..paths.div_ceil(chunk))
        .into_par_iter()
        .map(|c| {
            let (mut out, mut rays, mut path) = (Vec::new(), 0u64, Vec::new());
            for i in c * chunk..((c + 1) * chunk).min(paths) {
                let mut rng = light_generator(s.seed, iteration, i);
                // In the order of the sample's light stream: the
                // wavelength first.
                let wavelength = tracer.draw_wavelength(&mut rng);
                let time = tracer.scene.camera.time_from(|| rng.next_f32());
                tracer.light_subpath(&mut rng, time, vertices, &mut path, &mut rays, wavelength.map(|w| w.nm));
                tracer.light_vertices(&path, wavelength, &mut out);
            }
            out
        })
        .collect();
    parts.concat()
}

impl Progressive for Vcm {
    /// Per pixel one camera subpath and one light subpath, their
    /// connections, and the camera vertices' merges with the light
    /// vertices of the last iteration (independent of this one's camera
    /// subpaths, as merging needs: no light pass of its own). This
    /// iteration's light vertices are kept for the next.
    fn iterate(&mut self, scene: &Scene, cancel: Option<&AtomicBool>) -> Option<Work> {
        let s = &scene.settings;
        let k = self.image.iterations();
        let r = self.radius_of_iteration(k);
        let (tracer, next) = (self.tracer(scene, k), self.tracer(scene, k + 1));
        let (width, seed) = (s.width, s.seed);
        let previous = &self.previous;
        let stored = Mutex::new(Vec::new());
        let rays = self.image.iterate(
            scene,
            STREAM ^ LIGHT_PASS_STREAM,
            cancel,
            |i, rng, target, work: &mut Subpaths, out, rays| {
                let (x, y) = (i % width, i / width);
                let raster = Vec2::new(x as f32 + rng.next_f32(), y as f32 + rng.next_f32());
                let mut numbers = SeparateLight {
                    pixel: rng,
                    light: light_generator(seed, k, i),
                    on_light: false,
                };
                let mut sum = Rgb::ZERO;
                tracer.sample(raster, &mut numbers, work, rays, |_, _, at, l, _| match at {
                    Some(r) => target.add_splat(r, l, &mut out.image),
                    None => sum += l,
                });
                if k > 0 {
                    sum += tracer.merges(previous, r * r, work);
                }
                if sum != Rgb::ZERO {
                    target.add_splat(raster, sum, &mut out.image);
                }
                work.stored.clear();
                next.light_vertices(&work.light, work.wavelength, &mut work.stored);
                if !work.stored.is_empty() {
                    let mut all = stored.lock().unwrap_or_else(|e| e.into_inner());
                    all.extend(work.stored.iter().map(|v| (i, *v)));
                }
            },
            &mut |_, _, _| {},
        )?;
        // In the order of pixels, then of vertices: the tree is the same
        // for any number of threads.
        let mut stored = stored.into_inner().unwrap_or_else(|e| e.into_inner());
        stored.sort_unstable_by_key(|(i, v)| (*i, v.segments));
        self.previous = PhotonMap::build(stored.into_iter().map(|(_, v)| v).collect());
        Some(Work {
            rays,
            ..Work::default()
        })
    }

    fn film(&self) -> Film {
        self.image.film()
    }

    /// The image's sums: the radius follows from their iterations, and
    /// the last iteration's light vertices are traced again on restoring.
    fn state(&self) -> Vec<u8> {
        self.image.state()
    }

    fn restore(&mut self, scene: &Scene, state: &[u8]) -> Result<(), String> {
        self.image.restore(state)?;
        let k = self.image.iterations();
        self.previous = match k {
            0 => PhotonMap::default(),
            _ => PhotonMap::build(light_vertices_of(&self.tracer(scene, k), scene, k - 1)),
        };
        Ok(())
    }
}
