//! Primary sample space (Kelemen et al. 2002, "A Simple and Robust Mutation
//! Strategy for the Metropolis Light Transport Algorithm"): a path is a
//! function of the uniform numbers its sampler drew, so a Markov chain can
//! explore paths by perturbing those numbers instead of the path's vertices.
//!
//! [`Uniforms`] is what an estimator draws from: an independent generator
//! ([`Pcg32`]) or the chain's current vector ([`PrimarySamples`]). The
//! vector is split into interleaved streams (camera subpath, light
//! subpath, connections) so that a change in the number of values one part
//! draws leaves the others' values where they were (pbrt-v4's
//! `MLTSampler`).

use super::erf::erf_inv;
use super::rng::{ONE_MINUS_EPSILON, Pcg32};

/// A source of uniform numbers in [0, 1) for an estimator.
pub trait Uniforms {
    /// The next number.
    fn next_f32(&mut self) -> f32;

    /// Continues from stream `index`'s first number. Independent numbers
    /// have no streams: the default does nothing.
    #[inline]
    fn start_stream(&mut self, _index: u32) {}
}

impl Uniforms for Pcg32 {
    #[inline]
    fn next_f32(&mut self) -> f32 {
        Pcg32::next_f32(self)
    }
}

/// One coordinate of the primary sample vector.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Coordinate {
    pub(crate) value: f32,
    /// The iteration that last changed the value.
    pub(crate) modified: u64,
    /// The value and iteration before the current proposal changed them
    /// (two fields, not a pair, which would pad the record from 24 bytes
    /// to 32: a thousand chains' coordinates are read from memory at
    /// every step).
    pub(crate) backup_value: f32,
    pub(crate) backup_modified: u64,
}

/// A Markov chain's state in primary sample space and its mutations:
/// large steps draw every number afresh (with probability
/// `large_step_probability`), small steps move each by a normal offset of
/// deviation `sigma`, wrapped around [0, 1). Numbers are mutated lazily,
/// when drawn: one not drawn for n small steps takes the n offsets at
/// once (a normal of deviation σ√n), one not drawn since the last large
/// step is drawn afresh.
#[derive(Debug)]
pub struct PrimarySamples {
    pub(crate) rng: Pcg32,
    sigma: f32,
    large_step_probability: f32,
    streams: u32,
    pub(crate) coordinates: Vec<Coordinate>,
    pub(crate) iteration: u64,
    pub(crate) large_step: bool,
    pub(crate) last_large_step: u64,
    stream: u32,
    next: u32,
}

impl Clone for PrimarySamples {
    fn clone(&self) -> Self {
        let mut c = PrimarySamples::new(0, self.streams, self.sigma, self.large_step_probability);
        c.clone_from(self);
        c
    }

    /// Reuses `self`'s coordinates' storage: the renderer backs its
    /// chains up every iteration.
    fn clone_from(&mut self, source: &Self) {
        self.coordinates.clone_from(&source.coordinates);
        let PrimarySamples {
            rng,
            sigma,
            large_step_probability,
            streams,
            coordinates: _,
            iteration,
            large_step,
            last_large_step,
            stream,
            next,
        } = source;
        (self.rng, self.sigma, self.large_step_probability, self.streams) =
            (rng.clone(), *sigma, *large_step_probability, *streams);
        (
            self.iteration,
            self.large_step,
            self.last_large_step,
            self.stream,
            self.next,
        ) = (*iteration, *large_step, *last_large_step, *stream, *next);
    }
}

impl PrimarySamples {
    /// A chain whose first state is drawn by the generator seeded with
    /// `seed` (so a state found while bootstrapping is found again from
    /// its seed), with `streams` interleaved streams.
    pub fn new(seed: u64, streams: u32, sigma: f32, large_step_probability: f32) -> PrimarySamples {
        PrimarySamples {
            rng: Pcg32::new(seed, 0x006d_6c74),
            sigma,
            large_step_probability,
            streams: streams.max(1),
            coordinates: Vec::new(),
            iteration: 0,
            // The first state is a large step: every number fresh.
            large_step: true,
            last_large_step: 0,
            stream: 0,
            next: 0,
        }
    }

    /// Starts again as [`PrimarySamples::new`] with `seed` would, keeping
    /// the storage of the coordinates (bootstrapping draws a million
    /// first states).
    pub fn restart(&mut self, seed: u64) {
        self.rng = Pcg32::new(seed, 0x006d_6c74);
        self.coordinates.clear();
        (self.iteration, self.large_step, self.last_large_step) = (0, true, 0);
        (self.stream, self.next) = (0, 0);
    }

    /// Proposes the next state: from here on numbers come mutated.
    pub fn start_iteration(&mut self) {
        self.iteration += 1;
        self.large_step = self.rng.next_f32() < self.large_step_probability;
    }

    /// Whether the current proposal is a large step.
    pub fn is_large_step(&self) -> bool {
        self.large_step
    }

    /// Keeps the proposal as the chain's state.
    pub fn accept(&mut self) {
        if self.large_step {
            self.last_large_step = self.iteration;
        }
    }

    /// Puts back the state before the proposal.
    pub fn reject(&mut self) {
        for c in &mut self.coordinates {
            if c.modified == self.iteration {
                (c.value, c.modified) = (c.backup_value, c.backup_modified);
            }
        }
        self.iteration -= 1;
    }

    /// The number of coordinates drawn so far.
    pub fn len(&self) -> usize {
        self.coordinates.len()
    }

    /// Whether no coordinate was drawn yet.
    pub fn is_empty(&self) -> bool {
        self.coordinates.is_empty()
    }

    /// Brings coordinate `i` to the current proposal.
    fn ensure_ready(&mut self, i: usize) -> f32 {
        if i >= self.coordinates.len() {
            self.coordinates.resize(i + 1, Coordinate::default());
        }
        let c = &mut self.coordinates[i];
        // Untouched since the last accepted large step: that step would
        // have drawn it afresh.
        if c.modified < self.last_large_step {
            c.value = self.rng.next_f32();
            c.modified = self.last_large_step;
        }
        (c.backup_value, c.backup_modified) = (c.value, c.modified);
        if self.large_step {
            c.value = self.rng.next_f32();
        } else {
            let steps = (self.iteration - c.modified) as f32;
            // A normal offset of deviation σ√steps, by the inverse CDF.
            let u = self.rng.next_f32().max(f32::MIN_POSITIVE);
            let offset = self.sigma * steps.sqrt() * std::f32::consts::SQRT_2 * erf_inv(2.0 * u - 1.0);
            let v = c.value + offset;
            let v = v - v.floor();
            c.value = if v < 1.0 { v } else { 0.0 };
        }
        c.modified = self.iteration;
        c.value.min(ONE_MINUS_EPSILON)
    }
}

impl Uniforms for PrimarySamples {
    #[inline]
    fn next_f32(&mut self) -> f32 {
        let i = self.stream + self.streams * self.next;
        self.next += 1;
        self.ensure_ready(i as usize)
    }

    #[inline]
    fn start_stream(&mut self, index: u32) {
        debug_assert!(index < self.streams);
        self.stream = index;
        self.next = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn draw(s: &mut PrimarySamples, stream: u32, n: usize) -> Vec<f32> {
        s.start_stream(stream);
        (0..n).map(|_| s.next_f32()).collect()
    }

    /// The values the chain's state holds in stream 0.
    fn state(s: &PrimarySamples, n: usize) -> Vec<f32> {
        (0..n).map(|k| s.coordinates[k * s.streams as usize].value).collect()
    }

    /// The first state depends on the seed alone; a rejected proposal
    /// gives back the state before it, an accepted one stays.
    #[test]
    fn rejection_restores_and_acceptance_keeps() {
        let mut a = PrimarySamples::new(7, 3, 0.01, 0.3);
        let first = draw(&mut a, 0, 5);
        assert_eq!(first, draw(&mut PrimarySamples::new(7, 3, 0.01, 0.3), 0, 5));
        assert_ne!(first, draw(&mut PrimarySamples::new(8, 3, 0.01, 0.3), 0, 5));
        assert!(first.iter().all(|v| (0.0..1.0).contains(v)));
        for _ in 0..50 {
            a.start_iteration();
            let proposed = draw(&mut a, 0, 5);
            assert_ne!(proposed, first);
            a.reject();
            assert_eq!(state(&a, 5), first);
        }
        a.start_iteration();
        let kept = draw(&mut a, 0, 5);
        a.accept();
        assert_eq!(state(&a, 5), kept);
        a.start_iteration();
        draw(&mut a, 0, 3);
        a.reject();
        assert_eq!(state(&a, 5), kept);
    }

    /// The record the comment on `Coordinate::backup_value` promises.
    #[test]
    fn a_coordinate_takes_24_bytes() {
        assert_eq!(std::mem::size_of::<Coordinate>(), 24);
    }

    /// A restarted state is the fresh one of its seed, and a copy made
    /// over another chain's storage is the original, in what it draws
    /// next and in what a rejection puts back.
    #[test]
    fn restart_and_clone_from_give_the_same_chain() {
        let mut used = PrimarySamples::new(1, 3, 0.01, 0.3);
        for _ in 0..20 {
            used.start_iteration();
            draw(&mut used, 1, 40);
            used.accept();
        }
        used.restart(9);
        let mut fresh = PrimarySamples::new(9, 3, 0.01, 0.3);
        assert_eq!(draw(&mut used, 2, 12), draw(&mut fresh, 2, 12));

        let mut copy = PrimarySamples::new(5, 3, 0.01, 0.3);
        draw(&mut copy, 0, 90);
        fresh.start_iteration();
        draw(&mut fresh, 0, 6);
        fresh.accept();
        copy.clone_from(&fresh);
        assert_eq!(copy.coordinates, fresh.coordinates);
        for s in [&mut copy, &mut fresh] {
            s.start_iteration();
        }
        assert_eq!(draw(&mut copy, 0, 8), draw(&mut fresh, 0, 8));
        copy.reject();
        fresh.reject();
        assert_eq!(state(&copy, 8), state(&fresh, 8));
    }

    /// Small steps move a number by about σ (wrapping around), large steps
    /// anywhere; with probability p a step is large.
    #[test]
    fn small_steps_are_small_and_large_steps_are_uniform() {
        let (sigma, p) = (0.01, 0.25);
        let mut s = PrimarySamples::new(3, 1, sigma, p);
        let mut current = draw(&mut s, 0, 1)[0];
        let (mut large, mut small_sq, mut smalls, mut large_sum) = (0u32, 0.0f64, 0u32, 0.0f64);
        let n = 20_000;
        for _ in 0..n {
            s.start_iteration();
            let v = draw(&mut s, 0, 1)[0];
            if s.is_large_step() {
                large += 1;
                large_sum += v as f64;
            } else {
                let mut d = v - current;
                d -= d.round(); // the shortest way around the circle
                small_sq += (d * d) as f64;
                smalls += 1;
            }
            s.accept();
            current = v;
        }
        // Binomial(n, p): within 5 deviations.
        let sd = (n as f64 * p as f64 * (1.0 - p as f64)).sqrt();
        assert!(
            (large as f64 - n as f64 * p as f64).abs() < 5.0 * sd,
            "{large} large steps"
        );
        // The mean of uniform numbers: within 5 deviations of 1/2.
        let mean = large_sum / large as f64;
        assert!((mean - 0.5).abs() < 5.0 * (1.0 / 12.0 / large as f64).sqrt(), "{mean}");
        // The variance of the normal offsets: σ², within 5 deviations of
        // the sample variance's (√(2/n) σ²).
        let var = small_sq / smalls as f64;
        let s2 = (sigma * sigma) as f64;
        assert!(
            (var - s2).abs() < 5.0 * s2 * (2.0 / smalls as f64).sqrt(),
            "{var} against {s2}"
        );
    }

    /// A number not drawn for n small steps moves by σ√n when drawn again;
    /// one not drawn since an accepted large step is drawn afresh.
    #[test]
    fn lazy_mutation_catches_up() {
        let sigma = 0.001;
        let (mut far, mut near) = (0u32, 0u32);
        for seed in 0..200 {
            let mut s = PrimarySamples::new(seed, 1, sigma, 0.0);
            let first = draw(&mut s, 0, 2);
            for _ in 0..100 {
                s.start_iteration();
                draw(&mut s, 0, 1);
                s.accept();
            }
            s.start_iteration();
            let second = draw(&mut s, 0, 2)[1];
            let mut d = second - first[1];
            d -= d.round();
            // 101 steps at once: deviation σ√101 ≈ 0.01.
            if d.abs() > 0.003 {
                far += 1;
            }
            if d.abs() < 0.05 {
                near += 1;
            }
        }
        // |N(0, 0.01)| > 0.003 with probability 0.76; < 0.05 always.
        assert!(far > 120 && near == 200, "{far} {near}");
    }

    /// Streams interleave: when one stream draws more numbers than before,
    /// a small step leaves the other streams' numbers near where they were.
    #[test]
    fn streams_keep_their_numbers_when_another_draws_more() {
        let mut s = PrimarySamples::new(11, 3, 0.01, 0.0);
        draw(&mut s, 0, 2);
        let before = draw(&mut s, 1, 4);
        s.start_iteration();
        draw(&mut s, 0, 9);
        let after = draw(&mut s, 1, 4);
        for (a, b) in before.iter().zip(&after) {
            let mut d = a - b;
            d -= d.round();
            assert!(d.abs() < 0.1, "{before:?} {after:?}");
        }
        assert_eq!(s.len(), 3 * 8 + 1);
    }
}
