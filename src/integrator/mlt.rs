//! Metropolis light transport in primary sample space (Veach and Guibas
//! 1997; Kelemen et al. 2002): Markov chains whose states are the uniform
//! numbers a bidirectional sample draws, mutated by small perturbations
//! and by independent large steps, each proposal accepted with the
//! Metropolis–Hastings probability min(1, c(new) / c(current)), c the
//! luminance of what the state contributes. The chains visit paths in
//! proportion to their brightness, so they linger where light is hard to
//! find (through a door left ajar, in a caustic seen in a mirror) and
//! spend little on what is easy.
//!
//! Two contribution functions over [`crate::integrator::bdpt`]'s tracer:
//! - `pssmlt` (Kelemen et al. 2002): the whole bidirectional sample, one
//!   camera and one light subpath joined by every strategy under MIS; c
//!   sums the luminance of all its contributions, which may land on
//!   several pixels.
//! - `mlt`, multiplexed (Hachisuka et al. 2014, as pbrt-v4's `mlt`): each
//!   chain renders paths of one length; one number of the state chooses
//!   the strategy (s, t), so the chain moves between strategies as it
//!   moves between paths, and each proposal traces only the subpaths that
//!   strategy needs.
//!
//! Every mutation splats both the proposal and the current state, weighted
//! by the probability of accepting and of rejecting the proposal (Veach
//! 1997, §11.3.3, "expected values"), each as its contribution over c: a
//! mutation adds luminance 1 to the image. The image's brightness b, the
//! integral of c over primary sample space (over each path length, for
//! `mlt`), is estimated beforehand from independent bootstrap samples,
//! from which the chains also start, in proportion to c, so that no
//! burn-in is needed (pbrt-v4's `MLTIntegrator`). An iteration makes as
//! many mutations as the image has pixels, spread over the chains, so the
//! samples per pixel are the mutations per pixel; its splats times b
//! estimate the image.

use super::bdpt::{CAMERA_STREAM, STREAMS, Subpaths, Tracer};
use super::light::{SplatImage, SplatTarget, Splats, gather};
use super::state::{StateReader, StateWriter};
use super::{Progressive, Work};
use crate::color::{Rgb, luminance};
use crate::film::Film;
use crate::sampling::primary::Coordinate;
use crate::sampling::rng::{ONE_MINUS_EPSILON, Pcg32, hash_u64s};
use crate::sampling::{Distribution1D, PrimarySamples, Uniforms};
use crate::scene::Scene;
use crate::settings::MltSettings;
use glam::Vec2;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Separates Metropolis light transport's random numbers from the others'.
const STREAM: u64 = 0x6d6c_7400;

/// Chains advanced side by side before their splats are added to the
/// image: bounds the splats held at once.
const CHAIN_BATCH: usize = 256;

/// Chains a thread steps in a row, with one working memory and one list
/// of splats.
const CHAINS_PER_TASK: usize = 8;

/// Bootstrap samples per parallel task.
const BOOTSTRAP_CHUNK: usize = 1024;

/// A contribution of a state: the raster position it lands on and its
/// radiance.
type Splat = (Vec2, Rgb);

/// One Markov chain.
struct Chain {
    samples: PrimarySamples,
    /// Draws the acceptances.
    rng: Pcg32,
    /// The length of the paths it renders in segments (`mlt`); 0 for
    /// `pssmlt`, whose samples have every length.
    segments: usize,
    /// What the current state contributes, and its luminance c.
    current: Vec<Splat>,
    importance: f32,
}

impl Clone for Chain {
    fn clone(&self) -> Self {
        Chain {
            samples: self.samples.clone(),
            rng: self.rng.clone(),
            segments: self.segments,
            current: self.current.clone(),
            importance: self.importance,
        }
    }

    /// Reuses `self`'s storage (see [`Metropolis::backup`]).
    fn clone_from(&mut self, source: &Self) {
        self.samples.clone_from(&source.samples);
        self.rng.clone_from(&source.rng);
        self.segments = source.segments;
        self.current.clone_from(&source.current);
        self.importance = source.importance;
    }
}

/// Metropolis light transport: its settings, its chains once bootstrapped
/// and the image of its iterations.
pub struct Metropolis {
    multiplexed: bool,
    max_depth: u32,
    settings: MltSettings,
    image: SplatImage,
    /// The image's brightness b and the chains, once bootstrapped.
    chains: Option<(f32, Vec<Chain>)>,
    /// The chains as they were before the iteration under way, which a
    /// cancelled iteration puts back; kept from one iteration to the next
    /// so that the copy reuses its storage instead of allocating a
    /// thousand vectors each time.
    backup: Vec<Chain>,
}

impl Metropolis {
    /// Nothing rendered yet: `multiplexed` chooses `mlt` over `pssmlt`;
    /// `aovs` asks for the auxiliary sums.
    pub fn new(scene: &Scene, multiplexed: bool, aovs: bool) -> Metropolis {
        Metropolis {
            multiplexed,
            max_depth: scene.settings.max_depth,
            settings: scene.settings.mlt,
            image: SplatImage::new(scene, aovs),
            chains: None,
            backup: Vec::new(),
        }
    }

    /// The state's contributions (into `out`) and their luminance c.
    fn evaluate<'s>(
        tracer: &Tracer<'s>,
        scene: &Scene,
        segments: usize,
        samples: &mut PrimarySamples,
        work: &mut Subpaths<'s>,
        rays: &mut u64,
        out: &mut Vec<Splat>,
    ) -> f32 {
        out.clear();
        if segments > 0 {
            out.extend(tracer.strategy(segments, samples, work, rays));
        } else {
            samples.start_stream(CAMERA_STREAM);
            let (width, height) = (scene.settings.width as f32, scene.settings.height as f32);
            let raster = Vec2::new(samples.next_f32() * width, samples.next_f32() * height);
            let mut sum = Rgb::ZERO;
            tracer.sample(raster, samples, work, rays, |_, _, at, l, _| match at {
                Some(r) => out.push((r, l)),
                None => sum += l,
            });
            if sum != Rgb::ZERO {
                out.push((raster, sum));
            }
        }
        let c: f32 = out.iter().map(|(_, l)| luminance(*l).max(0.0)).sum();
        if c.is_finite() { c } else { 0.0 }
    }

    /// One step of `chain`: a proposal from its state, accepted or not
    /// (Kelemen et al. 2002), both states splatted with their expected
    /// weights (Veach 1997, ch. 11). `work` and `proposed` are working memory.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn mutate<'s>(
        tracer: &Tracer<'s>,
        scene: &Scene,
        chain: &mut Chain,
        brightness: f32,
        (target, splats): (&SplatTarget, &mut Splats),
        work: &mut Subpaths<'s>,
        proposed: &mut Vec<Splat>,
        rays: &mut u64,
    ) {
        chain.samples.start_iteration();
        let c = Self::evaluate(tracer, scene, chain.segments, &mut chain.samples, work, rays, proposed);
        let accept = if chain.importance > 0.0 {
            (c / chain.importance).min(1.0)
        } else {
            1.0
        };
        if accept > 0.0 && c > 0.0 {
            let k = accept / c * brightness;
            for &(at, l) in proposed.iter() {
                target.add_splat(at, l * k, &mut splats.image);
            }
        }
        if accept < 1.0 {
            let k = (1.0 - accept) / chain.importance * brightness;
            for &(at, l) in &chain.current {
                target.add_splat(at, l * k, &mut splats.image);
            }
        }
        if chain.rng.next_f32() < accept {
            chain.samples.accept();
            std::mem::swap(&mut chain.current, proposed);
            chain.importance = c;
        } else {
            chain.samples.reject();
        }
    }

    /// The chain-start seed of bootstrap sample `i`.
    fn seed_of(scene: &Scene, i: usize) -> u64 {
        hash_u64s(&[scene.settings.seed, STREAM, i as u64])
    }

    /// A fresh state in primary sample space for bootstrap sample `i`.
    fn samples_of(&self, scene: &Scene, i: usize) -> PrimarySamples {
        let s = &self.settings;
        PrimarySamples::new(Self::seed_of(scene, i), STREAMS, s.sigma, s.large_step_probability)
    }

    /// The path length bootstrap sample `i` renders: the samples of each
    /// length are consecutive.
    fn segments_of(&self, i: usize) -> usize {
        if self.multiplexed {
            i / self.settings.bootstrap.max(1) as usize + 1
        } else {
            0
        }
    }

    /// Bootstrap sample `i`: its state in primary sample space (put in
    /// `samples`, whose storage it reuses), the path length it renders,
    /// and its luminance c (its contributions in `out`). A chain started
    /// from sample `i` finds the same again.
    #[allow(clippy::too_many_arguments)]
    fn first_state<'s>(
        &self,
        tracer: &Tracer<'s>,
        scene: &Scene,
        i: usize,
        samples: &mut PrimarySamples,
        work: &mut Subpaths<'s>,
        rays: &mut u64,
        out: &mut Vec<Splat>,
    ) -> (usize, f32) {
        samples.restart(Self::seed_of(scene, i));
        let segments = self.segments_of(i);
        let c = Self::evaluate(tracer, scene, segments, samples, work, rays, out);
        (segments, c)
    }

    /// Estimates the brightness b from the bootstrap samples and starts
    /// the chains from states drawn among them in proportion to c, by
    /// systematic resampling (one draw in each of as many equal parts of
    /// the distribution as there are chains): each path length gets its
    /// share of the chains to within one, where independent draws would
    /// add the noise of a multinomial to the image (pbrt-v4 draws them
    /// independently). `None` when cancelled.
    fn bootstrap(&self, scene: &Scene, cancel: Option<&AtomicBool>, rays: &mut u64) -> Option<(f32, Vec<Chain>)> {
        let tracer = Tracer::new(scene, self.max_depth);
        // No path length at all (max_depth 0): nothing is bootstrapped,
        // the image stays black.
        let lengths = if self.multiplexed { self.max_depth as usize } else { 1 };
        let count = self.settings.bootstrap as usize * lengths;
        let parts: Vec<(Vec<f32>, u64)> = (0..count.div_ceil(BOOTSTRAP_CHUNK))
            .into_par_iter()
            .map(|chunk| {
                let (mut work, mut out, mut rays) = (Subpaths::default(), Vec::new(), 0u64);
                let mut samples = self.samples_of(scene, 0);
                let mut weights = Vec::with_capacity(BOOTSTRAP_CHUNK);
                if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return (weights, rays);
                }
                for i in chunk * BOOTSTRAP_CHUNK..((chunk + 1) * BOOTSTRAP_CHUNK).min(count) {
                    let (_, c) = self.first_state(&tracer, scene, i, &mut samples, &mut work, &mut rays, &mut out);
                    weights.push(c);
                }
                (weights, rays)
            })
            .collect();
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return None;
        }
        let mut weights = Vec::with_capacity(count);
        for (w, r) in parts {
            weights.extend(w);
            *rays += r;
        }
        let total: f64 = weights.iter().map(|&w| w as f64).sum();
        let brightness = (total / self.settings.bootstrap.max(1) as f64) as f32;
        if !(brightness > 0.0 && brightness.is_finite()) {
            return Some((0.0, Vec::new()));
        }
        let starts = Distribution1D::new(&weights);
        let pixels = scene.settings.width as usize * scene.settings.height as usize;
        let chains = (self.settings.chains.max(1) as usize).min(pixels);
        let built: Vec<(Chain, u64)> = (0..chains)
            .into_par_iter()
            .map(|j| {
                let mut rng = Pcg32::new(hash_u64s(&[scene.settings.seed, STREAM + 1, j as u64]), 0);
                let u = (j as f32 + rng.next_f32()) / chains as f32;
                let (index, _, _) = starts.sample(u.min(ONE_MINUS_EPSILON));
                let (mut work, mut current, mut rays) = (Subpaths::default(), Vec::new(), 0u64);
                let mut samples = self.samples_of(scene, index);
                let (segments, importance) =
                    self.first_state(&tracer, scene, index, &mut samples, &mut work, &mut rays, &mut current);
                let chain = Chain {
                    samples,
                    rng,
                    segments,
                    current,
                    importance,
                };
                (chain, rays)
            })
            .collect();
        let mut list = Vec::with_capacity(chains);
        for (chain, r) in built {
            list.push(chain);
            *rays += r;
        }
        Some((brightness, list))
    }
}

impl Progressive for Metropolis {
    /// As many mutations as the image has pixels, spread evenly over the
    /// chains (bootstrapping them first).
    fn iterate(&mut self, scene: &Scene, cancel: Option<&AtomicBool>) -> Option<Work> {
        let mut rays = 0u64;
        if self.chains.is_none() {
            self.chains = Some(self.bootstrap(scene, cancel, &mut rays)?);
        }
        let Some((brightness, chains)) = self.chains.as_mut() else {
            unreachable!("bootstrapped above");
        };
        let brightness = *brightness;
        // An iteration given up leaves the state as it was before it, so
        // that a checkpoint written then continues exactly.
        if cancel.is_some() {
            self.backup.clone_from(chains);
        }
        let tracer = Tracer::new(scene, self.max_depth);
        let target = self.image.target();
        let mut this = self.image.blank();
        let mutations = scene.settings.width as usize * scene.settings.height as usize;
        let count = chains.len();
        for (batch, group) in chains.chunks_mut(CHAIN_BATCH).enumerate() {
            let parts: Vec<(Splats, u64)> = group
                .par_chunks_mut(CHAINS_PER_TASK)
                .enumerate()
                .map(|(task, part)| {
                    let (mut splats, mut rays) = (Splats::default(), 0u64);
                    if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                        return (splats, rays);
                    }
                    let (mut work, mut proposed) = (Subpaths::default(), Vec::new());
                    for (k, chain) in part.iter_mut().enumerate() {
                        let j = batch * CHAIN_BATCH + task * CHAINS_PER_TASK + k;
                        let steps = mutations * (j + 1) / count - mutations * j / count;
                        for _ in 0..steps {
                            Self::mutate(
                                &tracer,
                                scene,
                                chain,
                                brightness,
                                (target, &mut splats),
                                &mut work,
                                &mut proposed,
                                &mut rays,
                            );
                        }
                    }
                    (splats, rays)
                })
                .collect();
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                chains.clone_from(&self.backup);
                return None;
            }
            for (splats, r) in parts {
                rays += r;
                gather(&mut this, splats, &mut |_, _, _| {});
            }
        }
        rays += self.image.end_iteration(scene, STREAM, &this);
        Some(Work {
            rays,
            ..Work::default()
        })
    }

    fn film(&self) -> Film {
        self.image.film()
    }

    /// The image's sums, the brightness, and every chain: its state in
    /// primary sample space, its generators and its current contribution.
    fn state(&self) -> Vec<u8> {
        let mut w = StateWriter::default();
        self.image.write_state(&mut w);
        let Some((brightness, chains)) = &self.chains else {
            w.u32(0);
            return w.0;
        };
        w.u32(1);
        w.f32(*brightness);
        w.u64(chains.len() as u64);
        for c in chains {
            let p = &c.samples;
            for (state, inc) in [p.rng.parts(), c.rng.parts()] {
                w.u64(state);
                w.u64(inc);
            }
            w.u64(p.iteration);
            w.u32(u32::from(p.large_step));
            w.u64(p.last_large_step);
            w.u64(p.coordinates.len() as u64);
            for x in &p.coordinates {
                w.f32(x.value);
                w.u64(x.modified);
            }
            w.u64(c.segments as u64);
            w.f32(c.importance);
            w.u64(c.current.len() as u64);
            for (at, l) in &c.current {
                for v in [at.x, at.y, l.x, l.y, l.z] {
                    w.f32(v);
                }
            }
        }
        w.0
    }

    fn restore(&mut self, scene: &Scene, state: &[u8]) -> Result<(), String> {
        let mut r = StateReader::new(state);
        self.image.read_state(&mut r)?;
        if r.u32()? == 0 {
            self.chains = None;
            return r.finish();
        }
        let brightness = r.f32()?;
        let count = r.count(64)?;
        let mut chains = Vec::with_capacity(count);
        let generator = |r: &mut StateReader| -> Result<Pcg32, String> {
            let (state, inc) = (r.u64()?, r.u64()?);
            Pcg32::from_parts(state, inc).ok_or_else(|| "a saved generator is invalid".to_string())
        };
        for i in 0..count {
            let mut samples = self.samples_of(scene, 0);
            samples.rng = generator(&mut r)?;
            let rng = generator(&mut r)?;
            samples.iteration = r.u64()?;
            samples.large_step = r.u32()? == 1;
            samples.last_large_step = r.u64()?;
            let n = r.count(12)?;
            samples.coordinates = (0..n)
                .map(|_| {
                    let (value, modified) = (r.f32()?, r.u64()?);
                    if !(0.0..1.0).contains(&value) {
                        return Err(format!("chain {i}: a saved primary sample is outside [0, 1)"));
                    }
                    Ok(Coordinate {
                        value,
                        modified,
                        backup_value: value,
                        backup_modified: modified,
                    })
                })
                .collect::<Result<_, String>>()?;
            let segments = r.u64()? as usize;
            if segments > self.max_depth as usize || (segments == 0) == self.multiplexed {
                return Err(format!("chain {i} renders paths of a length this render does not"));
            }
            let importance = r.f32()?;
            let n = r.count(20)?;
            let current = (0..n)
                .map(|_| {
                    let v = [r.f32()?, r.f32()?, r.f32()?, r.f32()?, r.f32()?];
                    Ok((Vec2::new(v[0], v[1]), Rgb::new(v[2], v[3], v[4])))
                })
                .collect::<Result<_, String>>()?;
            chains.push(Chain {
                samples,
                rng,
                segments,
                current,
                importance,
            });
        }
        self.chains = Some((brightness, chains));
        r.finish()
    }
}
