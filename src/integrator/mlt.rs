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
use super::light::{SplatImage, Splats, gather};
use super::{Progressive, Work};
use crate::color::{Rgb, luminance};
use crate::film::Film;
use crate::sampling::rng::{ONE_MINUS_EPSILON, Pcg32, hash_u64s};
use crate::sampling::{Distribution1D, PrimarySamples, Uniforms};
use crate::scene::Scene;
use crate::settings::MltSettings;
use glam::Vec2;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Why Metropolis renders refuse checkpoints.
pub const NOT_RESUMABLE: &str = "Metropolis light transport renders cannot be checkpointed, resumed or sharded yet (their state is the chains' and the image a sum of splats over whole iterations): drop --checkpoint-every/--resume/--shard, or use --integrator path";

/// Separates Metropolis light transport's random numbers from the others'.
const STREAM: u64 = 0x6d6c_7400;

/// Chains advanced side by side before their splats are added to the
/// image: bounds the splats held at once.
const CHAIN_BATCH: usize = 32;

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

/// Metropolis light transport: its settings, its chains once bootstrapped
/// and the image of its iterations.
pub struct Metropolis {
    multiplexed: bool,
    max_depth: u32,
    settings: MltSettings,
    image: SplatImage,
    /// The image's brightness b and the chains, once bootstrapped.
    chains: Option<(f32, Vec<Chain>)>,
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

    /// Estimates the brightness b from the bootstrap samples and starts
    /// the chains from states drawn among them in proportion to c, by
    /// systematic resampling (one draw in each of as many equal parts of
    /// the distribution as there are chains): each path length gets its
    /// share of the chains to within one, where independent draws would
    /// add the noise of a multinomial to the image (pbrt-v4 draws them
    /// independently). `None` when cancelled.
    fn bootstrap(&self, scene: &Scene, cancel: Option<&AtomicBool>, rays: &mut u64) -> Option<(f32, Vec<Chain>)> {
        let tracer = Tracer::new(scene, self.max_depth);
        let lengths = if self.multiplexed { self.max_depth.max(1) } else { 1 } as usize;
        let count = self.settings.bootstrap.max(1) as usize * lengths;
        let parts: Vec<(Vec<f32>, u64)> = (0..count.div_ceil(BOOTSTRAP_CHUNK))
            .into_par_iter()
            .map(|chunk| {
                let (mut work, mut out, mut rays) = (Subpaths::default(), Vec::new(), 0u64);
                let mut weights = Vec::with_capacity(BOOTSTRAP_CHUNK);
                if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return (weights, rays);
                }
                for i in chunk * BOOTSTRAP_CHUNK..((chunk + 1) * BOOTSTRAP_CHUNK).min(count) {
                    let mut samples = self.samples_of(scene, i);
                    let segments = self.segments_of(i);
                    weights.push(Self::evaluate(
                        &tracer,
                        scene,
                        segments,
                        &mut samples,
                        &mut work,
                        &mut rays,
                        &mut out,
                    ));
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
                let mut samples = self.samples_of(scene, index);
                let segments = self.segments_of(index);
                let (mut work, mut current, mut rays) = (Subpaths::default(), Vec::new(), 0u64);
                let importance = Self::evaluate(
                    &tracer,
                    scene,
                    segments,
                    &mut samples,
                    &mut work,
                    &mut rays,
                    &mut current,
                );
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
    const NOT_RESUMABLE: &'static str = NOT_RESUMABLE;

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
        let tracer = Tracer::new(scene, self.max_depth);
        let target = self.image.target();
        let mut this = self.image.blank();
        let mutations = scene.settings.width as usize * scene.settings.height as usize;
        let count = chains.len();
        for (batch, group) in chains.chunks_mut(CHAIN_BATCH).enumerate() {
            let parts: Vec<(Splats, u64)> = group
                .par_iter_mut()
                .enumerate()
                .map(|(k, chain)| {
                    let (mut splats, mut rays) = (Splats::default(), 0u64);
                    if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                        return (splats, rays);
                    }
                    let j = batch * CHAIN_BATCH + k;
                    let steps = mutations * (j + 1) / count - mutations * j / count;
                    let (mut work, mut proposed) = (Subpaths::default(), Vec::new());
                    for _ in 0..steps {
                        chain.samples.start_iteration();
                        let c = Self::evaluate(
                            &tracer,
                            scene,
                            chain.segments,
                            &mut chain.samples,
                            &mut work,
                            &mut rays,
                            &mut proposed,
                        );
                        let accept = if chain.importance > 0.0 {
                            (c / chain.importance).min(1.0)
                        } else {
                            1.0
                        };
                        if accept > 0.0 && c > 0.0 {
                            let k = accept / c * brightness;
                            for &(at, l) in &proposed {
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
                            std::mem::swap(&mut chain.current, &mut proposed);
                            chain.importance = c;
                        } else {
                            chain.samples.reject();
                        }
                    }
                    (splats, rays)
                })
                .collect();
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
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
}
