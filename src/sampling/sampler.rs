//! Per-pixel sample generators.
//!
//! A sample's random numbers depend only on (pixel, sample index, seed),
//! never on which thread draws them or in which order pixels are visited:
//! this is what makes renders bit-identical for any thread count and lets an
//! interrupted render resume exactly.

use super::halton::{self, DigitPermutations, HaltonPixels, ONE_MINUS_EPSILON, Scramble};
use super::rng::{Pcg32, hash_u64s};
use super::sobol::{PairSeeds, fraction_to_f32, sobol_1d, sobol_2d};
use glam::Vec2;
use std::sync::Arc;

/// How the sample positions inside a pixel are chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SamplerKind {
    /// Every sample goes through the pixel centre: one sample per pixel
    /// shows the aliasing that supersampling removes.
    Center,
    /// Independent uniform jitter inside the pixel.
    Independent,
    /// Jittered stratification of every dimension, as pbrt-v4's
    /// `stratified` sampler: a 1D number falls in one of `spp` equal
    /// intervals, a 2D point (the pixel position included) in one cell of
    /// an `x × y = spp` grid; each pixel and dimension visits the strata
    /// in its own random order (a sample's strata in different dimensions
    /// are unrelated, and the first k samples of an interrupted render are
    /// spread over the strata), jittered inside them or at their centres.
    Stratified,
    /// Owen-scrambled Sobol points (Burley 2020): every 2D dimension pair
    /// of a pixel, the pixel position included, is a shuffled and scrambled
    /// (0,2)-sequence, so the first 2^k samples are stratified in every
    /// elementary interval of area 2^-k; 1D dimensions are stratified too.
    /// The default: the least error of trazo's samplers on the Cornell
    /// boxes at 16–64 spp (BENCHMARKS.md, "Samplers").
    #[default]
    Sobol,
    /// The Halton sequence over the whole image, each dimension's digits
    /// randomly permuted (`sampling::halton`, pbrt-v4's `halton` sampler
    /// with its default `permutedigits`).
    Halton,
    /// The Halton sequence with Owen-scrambled digits (pbrt-v4's `halton`
    /// with `randomize "owen"`).
    HaltonOwen,
    /// The Halton sequence as it is, the same points for every seed
    /// (pbrt-v4's `halton` with `randomize "none"`).
    HaltonPlain,
}

impl SamplerKind {
    /// The names accepted on the command line and in scene files.
    pub const NAMES: [&'static str; 7] = [
        "center",
        "independent",
        "stratified",
        "sobol",
        "halton",
        "halton-owen",
        "halton-plain",
    ];

    /// Parses one of [`SamplerKind::NAMES`].
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "center" => Some(SamplerKind::Center),
            "independent" => Some(SamplerKind::Independent),
            "stratified" => Some(SamplerKind::Stratified),
            "sobol" => Some(SamplerKind::Sobol),
            "halton" => Some(SamplerKind::Halton),
            "halton-owen" => Some(SamplerKind::HaltonOwen),
            "halton-plain" => Some(SamplerKind::HaltonPlain),
            _ => None,
        }
    }

    /// The name of this kind.
    pub fn name(&self) -> &'static str {
        match self {
            SamplerKind::Center => "center",
            SamplerKind::Independent => "independent",
            SamplerKind::Stratified => "stratified",
            SamplerKind::Sobol => "sobol",
            SamplerKind::Halton => "halton",
            SamplerKind::HaltonOwen => "halton-owen",
            SamplerKind::HaltonPlain => "halton-plain",
        }
    }
}

/// A sample generator owned by one thread and restarted for every sample.
#[derive(Clone, Debug)]
pub struct Sampler {
    kind: SamplerKind,
    spp: u32,
    seed: u64,
    rng: Pcg32,
    pixel_key: u64,
    /// The pixel `pixel_key` is of: a pixel's samples follow one another,
    /// so its hash is computed once for them all.
    keyed_pixel: Option<(u32, u32)>,
    sample_index: u32,
    /// The next Sobol dimension pair of the current sample: each
    /// `next_1d`/`next_2d` call takes a fresh one.
    dimension: u32,
    /// `sample_index` with its bits reversed, as the Sobol scrambles take it.
    reversed_index: u32,
    /// Stratification grid of the 2D dimensions: `cols × rows = spp`
    /// cells.
    cols: u32,
    rows: u32,
    /// Whether stratified samples are jittered inside their strata (else
    /// at their centres).
    jitter: bool,
    /// The Halton samplers' tiling of the image, and the current sample's
    /// index in their sequence.
    halton: HaltonPixels,
    halton_index: u64,
    /// The Halton sampler's digit permutations.
    permutations: Option<Arc<DigitPermutations>>,
}

impl Sampler {
    /// A sampler for `spp` samples per pixel with the user's `seed`.
    pub fn new(kind: SamplerKind, spp: u32, seed: u64) -> Self {
        let spp = spp.max(1);
        let [cols, rows] = strata_grid(spp);
        Sampler {
            kind,
            spp,
            seed,
            rng: Pcg32::new(0, 0),
            pixel_key: 0,
            keyed_pixel: None,
            sample_index: 0,
            dimension: 0,
            reversed_index: 0,
            cols,
            rows,
            jitter: true,
            halton: HaltonPixels::new(u32::MAX, u32::MAX),
            halton_index: 0,
            permutations: (kind == SamplerKind::Halton).then(|| DigitPermutations::shared(seed)),
        }
    }

    /// The sampler for an image of `width` × `height` pixels, which the
    /// Halton samplers tile as pbrt-v4's does (the others ignore it).
    pub fn for_image(mut self, width: u32, height: u32) -> Self {
        self.halton = HaltonPixels::new(width, height);
        self
    }

    /// The stratified sampler's 2D grid `[x, y]` where its product is the
    /// samples per pixel (pbrt-v4's `xsamples` × `ysamples`; otherwise the
    /// grid of [`strata_grid`] stays), and whether it jitters.
    pub fn with_strata(mut self, grid: Option<[u32; 2]>, jitter: bool) -> Self {
        if let Some([x, y]) = grid.filter(|&[x, y]| x >= 1 && y >= 1 && x.checked_mul(y) == Some(self.spp)) {
            (self.cols, self.rows) = (x, y);
        }
        self.jitter = jitter;
        self
    }

    /// Whether the kind is a Halton sampler.
    #[inline]
    fn is_halton(&self) -> bool {
        matches!(
            self.kind,
            SamplerKind::Halton | SamplerKind::HaltonOwen | SamplerKind::HaltonPlain
        )
    }

    /// Dimension `dim` of the current Halton point. The Halton paths are
    /// kept out of line, so that the others' stay small enough to be
    /// inlined into the render loop.
    #[inline(never)]
    fn halton_dimension(&self, dim: u32) -> f32 {
        let scramble = match (&self.permutations, self.kind) {
            (Some(permutations), _) => Scramble::PermuteDigits(permutations),
            (None, SamplerKind::HaltonPlain) => return halton::radical_inverse(dim, self.halton_index),
            (None, _) => Scramble::Owen { seed: self.seed },
        };
        halton::scrambled_radical_inverse(dim, self.halton_index, scramble)
    }

    /// [`Sampler::start_pixel_sample`] for the Halton kinds: dimensions 0
    /// and 1 chose the pixel; they give the position in it.
    #[inline(never)]
    fn start_halton_sample(&mut self, x: u32, y: u32, index: u32) {
        self.halton_index = self.halton.index(x, y, index);
        self.dimension = 2;
    }

    /// A pair of dimensions of the current Halton point.
    #[inline(never)]
    fn halton_2d(&mut self) -> Vec2 {
        let d = self.next_halton_dimension(2);
        Vec2::new(self.halton_dimension(d), self.halton_dimension(d + 1))
    }

    /// The position in its pixel of the current Halton point.
    #[inline(never)]
    fn halton_pixel_2d(&self) -> Vec2 {
        let (x, y) = self.halton.pixel_position(self.halton_index);
        Vec2::new(x, y)
    }

    /// The next Halton dimension, or pair of dimensions (`count` 2), the
    /// sequence starting over at its third dimension after its last, as
    /// pbrt-v4's.
    #[inline]
    fn next_halton_dimension(&mut self, count: u32) -> u32 {
        if self.dimension + count > halton::DIMENSIONS {
            self.dimension = 2;
        }
        let d = self.dimension;
        self.dimension += count;
        d
    }

    /// The configured kind.
    pub fn kind(&self) -> SamplerKind {
        self.kind
    }

    /// Starts sample `index` of pixel `(x, y)`: from here on the sampler
    /// returns that sample's numbers.
    #[inline(always)]
    pub fn start_pixel_sample(&mut self, x: u32, y: u32, index: u32) {
        if self.keyed_pixel != Some((x, y)) {
            self.pixel_key = hash_u64s(&[x as u64, y as u64, self.seed]);
            self.keyed_pixel = Some((x, y));
        }
        self.sample_index = index;
        self.dimension = 0;
        self.reversed_index = index.reverse_bits();
        if self.is_halton() {
            self.start_halton_sample(x, y, index);
        } else if self.kind != SamplerKind::Sobol {
            self.rng = Pcg32::new(hash_u64s(&[self.pixel_key, index as u64]), 0);
        }
    }

    /// A uniform number in [0, 1).
    #[inline(always)]
    pub fn next_1d(&mut self) -> f32 {
        match self.kind {
            SamplerKind::Sobol => {
                let seeds = self.next_pair_seeds();
                fraction_to_f32(sobol_1d(self.reversed_index, seeds))
            }
            SamplerKind::Independent | SamplerKind::Center => self.rng.next_f32(),
            _ => self.sequence_1d(),
        }
    }

    /// [`Sampler::next_1d`] for the Halton and stratified kinds, out of
    /// line (see [`Sampler::halton_dimension`]).
    #[inline(never)]
    fn sequence_1d(&mut self) -> f32 {
        if self.kind == SamplerKind::Stratified {
            return self.stratified_1d();
        }
        let d = self.next_halton_dimension(1);
        self.halton_dimension(d)
    }

    /// A uniform point in [0, 1)².
    #[inline(always)]
    pub fn next_2d(&mut self) -> Vec2 {
        match self.kind {
            SamplerKind::Sobol => {
                let seeds = self.next_pair_seeds();
                let (x, y) = sobol_2d(self.reversed_index, seeds);
                Vec2::new(fraction_to_f32(x), fraction_to_f32(y))
            }
            SamplerKind::Independent | SamplerKind::Center => {
                let x = self.rng.next_f32();
                let y = self.rng.next_f32();
                Vec2::new(x, y)
            }
            SamplerKind::Stratified => self.stratified_2d(),
            _ => self.halton_2d(),
        }
    }

    /// The stratum, of `spp`, of the current sample in the next
    /// dimension: element `sample_index` of that pixel's and dimension's
    /// permutation of the strata (pbrt-v4's `StratifiedSampler`).
    #[inline]
    fn next_stratum(&mut self) -> u32 {
        let key = hash_u64s(&[self.pixel_key, self.dimension as u64]);
        self.dimension = self.dimension.wrapping_add(1);
        permutation_element(self.sample_index % self.spp, self.spp, key as u32)
    }

    /// Where in its stratum a stratified number lies: jittered, or the
    /// centre.
    #[inline]
    fn stratum_offset(&mut self) -> f32 {
        if self.jitter { self.rng.next_f32() } else { 0.5 }
    }

    /// A stratified number: in one of `spp` equal intervals.
    #[inline(never)]
    fn stratified_1d(&mut self) -> f32 {
        let stratum = self.next_stratum();
        // Below 1 also where rounding would reach it.
        ((stratum as f32 + self.stratum_offset()) / self.spp as f32).min(ONE_MINUS_EPSILON)
    }

    /// A stratified point: in one cell of the `cols × rows` grid.
    #[inline(never)]
    fn stratified_2d(&mut self) -> Vec2 {
        let stratum = self.next_stratum();
        let (cx, cy) = (stratum % self.cols, stratum / self.cols);
        let (dx, dy) = (self.stratum_offset(), self.stratum_offset());
        Vec2::new(
            ((cx as f32 + dx) / self.cols as f32).min(ONE_MINUS_EPSILON),
            ((cy as f32 + dy) / self.rows as f32).min(ONE_MINUS_EPSILON),
        )
    }

    /// Passes over the number [`Sampler::next_1d`] would return, without
    /// computing it: every later number is the one it would have been.
    /// Estimators draw their numbers in a fixed order and pass over those
    /// a case does not use (the choice among lights where there is one
    /// light, say), which costs an increment or one generator step instead
    /// of a scrambled Sobol point.
    #[inline]
    pub fn skip_1d(&mut self) {
        match self.kind {
            SamplerKind::Sobol => self.dimension = self.dimension.wrapping_add(1),
            SamplerKind::Independent | SamplerKind::Center => self.rng.skip(),
            SamplerKind::Stratified => {
                self.dimension = self.dimension.wrapping_add(1);
                if self.jitter {
                    self.rng.skip();
                }
            }
            _ => {
                self.next_halton_dimension(1);
            }
        }
    }

    /// Passes over the point [`Sampler::next_2d`] would return; see
    /// [`Sampler::skip_1d`].
    #[inline]
    pub fn skip_2d(&mut self) {
        match self.kind {
            SamplerKind::Sobol => self.dimension = self.dimension.wrapping_add(1),
            SamplerKind::Independent | SamplerKind::Center => {
                self.rng.skip();
                self.rng.skip();
            }
            SamplerKind::Stratified => {
                self.dimension = self.dimension.wrapping_add(1);
                if self.jitter {
                    self.rng.skip();
                    self.rng.skip();
                }
            }
            _ => {
                self.next_halton_dimension(2);
            }
        }
    }

    /// The seeds of the next padded Sobol dimension pair.
    #[inline]
    fn next_pair_seeds(&mut self) -> PairSeeds {
        let seeds = PairSeeds::new(self.pixel_key, self.dimension);
        self.dimension = self.dimension.wrapping_add(1);
        seeds
    }

    /// The sample's position inside its pixel, in [0, 1)².
    #[inline(always)]
    pub fn pixel_2d(&mut self) -> Vec2 {
        match self.kind {
            SamplerKind::Center => Vec2::splat(0.5),
            // The first dimension pair of a sample is its pixel position
            // (pixel_2d is the first call after start_pixel_sample).
            SamplerKind::Independent | SamplerKind::Sobol | SamplerKind::Stratified => self.next_2d(),
            SamplerKind::Halton | SamplerKind::HaltonOwen | SamplerKind::HaltonPlain => self.halton_pixel_2d(),
        }
    }
}

/// The stratified sampler's grid for `spp` samples: `[x, y]` with
/// `x · y = spp` and y the largest divisor of `spp` not above its square
/// root, as pbrt-v4 divides a sample count given on its command line. Every
/// cell holds one sample: a grid with more cells than samples would leave
/// part of the pixel unsampled.
pub fn strata_grid(spp: u32) -> [u32; 2] {
    let spp = spp.max(1);
    let mut y = (spp as f64).sqrt().floor() as u32;
    while spp % y != 0 {
        y -= 1;
    }
    [spp / y, y]
}

/// Element `i` of a pseudo-random permutation of `[0, n)` chosen by `seed`
/// (Kensler 2013, "Correlated Multi-Jittered Sampling", listing 3: a
/// hash-based bijection on the next power of two, with cycle walking).
pub fn permutation_element(mut i: u32, n: u32, seed: u32) -> u32 {
    if n <= 1 {
        return 0;
    }
    let mut w = n - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
        i ^= seed;
        i = i.wrapping_mul(0xe170893d);
        i ^= seed >> 16;
        i ^= (i & w) >> 4;
        i ^= seed >> 8;
        i = i.wrapping_mul(0x0929eb3f);
        i ^= seed >> 23;
        i ^= (i & w) >> 1;
        i = i.wrapping_mul(1 | seed >> 27);
        i = i.wrapping_mul(0x6935fa69);
        i ^= (i & w) >> 11;
        i = i.wrapping_mul(0x74dcb303);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0x9e501cc3);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0xc860a3df);
        i &= w;
        i ^= i >> 5;
        if i < n {
            break;
        }
    }
    (i.wrapping_add(seed)) % n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Passing over a number leaves every later one as it was.
    #[test]
    fn skipped_numbers_leave_the_later_ones_unchanged() {
        for kind in [
            SamplerKind::Independent,
            SamplerKind::Stratified,
            SamplerKind::Sobol,
            SamplerKind::Center,
            SamplerKind::Halton,
            SamplerKind::HaltonOwen,
        ] {
            for (index, jitter) in [(0u32, true), (1, true), (5, false), (63, true), (63, false)] {
                let new = || Sampler::new(kind, 64, 3).with_strata(None, jitter);
                let (mut taken, mut skipped) = (new(), new());
                taken.start_pixel_sample(7, 2, index);
                skipped.start_pixel_sample(7, 2, index);
                assert_eq!(taken.pixel_2d(), skipped.pixel_2d());
                for step in 0..12 {
                    if step % 3 == 0 {
                        taken.next_2d();
                        skipped.skip_2d();
                    } else {
                        taken.next_1d();
                        skipped.skip_1d();
                    }
                    assert_eq!(
                        taken.next_1d(),
                        skipped.next_1d(),
                        "{kind:?} sample {index} step {step}"
                    );
                    assert_eq!(
                        taken.next_2d(),
                        skipped.next_2d(),
                        "{kind:?} sample {index} step {step}"
                    );
                }
            }
        }
    }

    /// A pixel's Halton samples: positions stratified in x over 2^k
    /// consecutive samples and in y over 3^k (the tile's strides are odd
    /// and prime to 3); low dimensions integrate better than independent
    /// numbers, high ones (the last pair before the sequence starts over,
    /// the first after) no worse.
    #[test]
    fn halton_samples_are_stratified_and_integrate_well() {
        for kind in [SamplerKind::Halton, SamplerKind::HaltonOwen] {
            let mut s = Sampler::new(kind, 64, 9).for_image(200, 150);
            for (px, py) in [(0u32, 0u32), (17, 3), (199, 149), (130, 140)] {
                let (mut xs, mut ys) = (Vec::new(), Vec::new());
                for i in 0..16 {
                    s.start_pixel_sample(px, py, i);
                    let p = s.pixel_2d();
                    assert!(p.cmpge(Vec2::ZERO).all() && p.cmplt(Vec2::ONE).all());
                    xs.push((p.x * 16.0) as u32);
                    if i < 9 {
                        ys.push((p.y * 9.0) as u32);
                    }
                }
                xs.sort();
                ys.sort();
                assert_eq!(xs, (0..16).collect::<Vec<_>>(), "{kind:?} ({px}, {py})");
                assert_eq!(ys, (0..9).collect::<Vec<_>>(), "{kind:?} ({px}, {py})");
            }
            // The first pair after the pixel's (bases 5 and 7): over 64
            // pixels, the root mean square error of the pixels' estimates
            // of ∫∫ xy = 1/4 from 64 samples is below a quarter of
            // independent sampling's standard error (0.028).
            let mut squares = 0.0f64;
            for (px, py) in (0..64).map(|k| (k % 8 + 50, k / 8 + 20)) {
                let mut sum = 0.0f64;
                for i in 0..64 {
                    s.start_pixel_sample(px, py, i);
                    let u = s.next_2d();
                    sum += (u.x * u.y) as f64;
                }
                squares += (sum / 64.0 - 0.25).powi(2);
            }
            let rms = (squares / 64.0).sqrt();
            assert!(rms < 0.25 * 0.028, "{kind:?}: {rms}");
            // Large bases with few samples are no better than independent
            // numbers (Halton's known weakness), but no worse: over 64
            // pixels of 64 samples, within 4 standard errors of independent
            // sampling (0.0034).
            for skipped_pairs in [40u32, 497, 498] {
                let mut sum = 0.0f64;
                for (px, py) in (0..64).map(|k| (k % 8 + 50, k / 8 + 20)) {
                    for i in 0..64 {
                        s.start_pixel_sample(px, py, i);
                        for _ in 0..skipped_pairs {
                            s.skip_2d();
                        }
                        let u = s.next_2d();
                        sum += (u.x * u.y) as f64;
                    }
                }
                let mean = sum / 4096.0;
                assert!(
                    (mean - 0.25).abs() < 4.0 * 0.0034,
                    "{kind:?} pair {skipped_pairs}: {mean}"
                );
            }
        }
    }

    /// Unrandomised Halton points are the sequence's own (pbrt-v4's
    /// `randomize "none"`): the radical inverses of the point's index, the
    /// same for every seed, the pixel positions stratified as the others'.
    #[test]
    fn plain_halton_points_are_the_radical_inverses() {
        let mut a = Sampler::new(SamplerKind::HaltonPlain, 64, 9).for_image(200, 150);
        let mut b = Sampler::new(SamplerKind::HaltonPlain, 64, 1234).for_image(200, 150);
        for (px, py, i) in [(0u32, 0u32, 0u32), (17, 3, 5), (199, 149, 63)] {
            a.start_pixel_sample(px, py, i);
            b.start_pixel_sample(px, py, i);
            let index = a.halton_index;
            assert_eq!(a.pixel_2d(), b.pixel_2d());
            for d in [2u32, 4, 6] {
                let (ua, ub) = (a.next_2d(), b.next_2d());
                assert_eq!(ua, ub);
                let want = Vec2::new(halton::radical_inverse(d, index), halton::radical_inverse(d + 1, index));
                assert_eq!(ua, want, "dimensions {d}, {}", d + 1);
            }
        }
        let mut xs: Vec<u32> = (0..16)
            .map(|i| {
                a.start_pixel_sample(30, 40, i);
                (a.pixel_2d().x * 16.0) as u32
            })
            .collect();
        xs.sort();
        assert_eq!(xs, (0..16).collect::<Vec<_>>());
    }

    #[test]
    fn permutation_is_a_bijection() {
        for n in [1u32, 2, 3, 7, 16, 17, 100] {
            for seed in [0u32, 1, 0xdeadbeef] {
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let p = permutation_element(i, n, seed);
                    assert!(p < n && !seen[p as usize], "n={n} seed={seed}");
                    seen[p as usize] = true;
                }
            }
        }
    }

    #[test]
    fn same_pixel_and_index_give_same_numbers() {
        let mut a = Sampler::new(SamplerKind::Stratified, 16, 7);
        let mut b = Sampler::new(SamplerKind::Stratified, 16, 7);
        b.start_pixel_sample(9, 9, 3);
        b.next_2d(); // disturb
        a.start_pixel_sample(5, 6, 3);
        b.start_pixel_sample(5, 6, 3);
        assert_eq!(a.pixel_2d(), b.pixel_2d());
        assert_eq!(a.next_1d(), b.next_1d());
        let mut c = Sampler::new(SamplerKind::Stratified, 16, 8);
        c.start_pixel_sample(5, 6, 3);
        a.start_pixel_sample(5, 6, 3);
        assert_ne!(a.pixel_2d(), c.pixel_2d(), "the seed changes the numbers");
    }

    /// Every dimension of the stratified sampler, 1D and 2D, the pixel
    /// position included, puts one of a pixel's samples in each stratum,
    /// for square and oblong grids, jittered or at the centres.
    #[test]
    fn stratified_puts_one_sample_in_each_stratum_of_every_dimension() {
        for (spp, grid) in [(16, None), (12, None), (6, Some([3, 2])), (6, Some([1, 6])), (7, None)] {
            for jitter in [true, false] {
                let [nx, ny] = grid.unwrap_or(strata_grid(spp));
                let mut s = Sampler::new(SamplerKind::Stratified, spp, 1).with_strata(grid, jitter);
                // Per dimension: the strata its samples fell in.
                let mut cells = vec![vec![0u32; spp as usize]; 6];
                for i in 0..spp {
                    s.start_pixel_sample(3, 4, i);
                    for (d, counts) in cells.iter_mut().enumerate() {
                        let stratum = if d % 2 == 0 {
                            let p = if d == 0 { s.pixel_2d() } else { s.next_2d() };
                            assert!(p.cmpge(Vec2::ZERO).all() && p.cmplt(Vec2::ONE).all());
                            let (fx, fy) = (p.x * nx as f32, p.y * ny as f32);
                            if !jitter {
                                assert_eq!((fx.fract(), fy.fract()), (0.5, 0.5), "centres");
                            }
                            fx as usize + nx as usize * fy as usize
                        } else {
                            let u = s.next_1d();
                            assert!((0.0..1.0).contains(&u));
                            let f = u * spp as f32;
                            if !jitter {
                                assert!((f.fract() - 0.5).abs() < 1e-5, "centre: {f}");
                            }
                            f as usize
                        };
                        counts[stratum] += 1;
                    }
                }
                for (d, c) in cells.iter().enumerate() {
                    assert!(c.iter().all(|&n| n == 1), "spp {spp} {grid:?} dim {d}: {c:?}");
                }
            }
        }
    }

    /// The grid for a sample count is exact, its y the largest divisor not
    /// above the square root (pbrt-v4's rule); a scene's grid is kept only
    /// where it holds the samples.
    #[test]
    fn strata_grids_hold_every_sample() {
        for (spp, grid) in [
            (1, [1, 1]),
            (16, [4, 4]),
            (8, [4, 2]),
            (12, [4, 3]),
            (7, [7, 1]),
            (1024, [32, 32]),
        ] {
            assert_eq!(strata_grid(spp), grid, "{spp}");
        }
        let s = Sampler::new(SamplerKind::Stratified, 6, 1).with_strata(Some([3, 2]), true);
        assert_eq!((s.cols, s.rows), (3, 2));
        let s = Sampler::new(SamplerKind::Stratified, 8, 1).with_strata(Some([3, 2]), false);
        assert_eq!((s.cols, s.rows, s.jitter), (4, 2, false));
    }

    /// The first `n` points of dimension pair `pair` (0 is pixel_2d) of
    /// pixel (x, y).
    fn sobol_points(s: &mut Sampler, x: u32, y: u32, pair: u32, n: u32) -> Vec<Vec2> {
        (0..n)
            .map(|i| {
                s.start_pixel_sample(x, y, i);
                let p = s.pixel_2d();
                for _ in 0..pair {
                    s.next_2d();
                }
                if pair == 0 { p } else { s.next_2d() }
            })
            .collect()
    }

    #[test]
    fn sobol_prefixes_are_0_m_2_nets() {
        // Owen scrambling keeps the (0,2)-sequence property: the first 2^k
        // samples put one point in each elementary interval of area 2^-k,
        // for every shape 2^-a × 2^-(k-a), in the pixel position and in any
        // later dimension pair.
        let mut s = Sampler::new(SamplerKind::Sobol, 256, 3);
        for (x, y) in [(0, 0), (17, 5), (1000, 999)] {
            for pair in [0, 1, 4] {
                for k in [4u32, 6, 8] {
                    let pts = sobol_points(&mut s, x, y, pair, 1 << k);
                    for a in 0..=k {
                        let (nx, ny) = ((1u32 << a) as f32, (1u32 << (k - a)) as f32);
                        let mut seen = vec![false; 1 << k];
                        for p in &pts {
                            assert!(p.cmpge(Vec2::ZERO).all() && p.cmplt(Vec2::ONE).all());
                            let cell = (p.x * nx) as usize * (1 << (k - a)) + (p.y * ny) as usize;
                            assert!(
                                !seen[cell],
                                "pixel ({x},{y}) pair {pair} k {k} a {a}: interval {cell} twice"
                            );
                            seen[cell] = true;
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn sobol_1d_prefixes_are_stratified() {
        let mut s = Sampler::new(SamplerKind::Sobol, 64, 5);
        for pick in [0, 2] {
            let mut seen = [false; 64];
            for i in 0..64 {
                s.start_pixel_sample(4, 2, i);
                s.pixel_2d();
                let mut u = s.next_1d();
                for _ in 0..pick {
                    u = s.next_1d();
                }
                let c = (u * 64.0) as usize;
                assert!(!seen[c], "call {pick}: interval {c} twice");
                seen[c] = true;
            }
        }
    }

    #[test]
    fn sobol_dimensions_are_uniform_over_pixels() {
        // Chi-square test per dimension with 16 bins over 4096 pixels ×
        // 4 samples, first sample index and later ones: with 15 degrees of
        // freedom the 99.9% quantile is 37.7. Different pixels use
        // independent scrambles, so the counts are multinomial.
        let mut s = Sampler::new(SamplerKind::Sobol, 4, 11);
        const BINS: usize = 16;
        let mut counts = vec![[0u32; BINS]; 7];
        let mut n = 0;
        for y in 0..64 {
            for x in 0..64 {
                for i in 0..4 {
                    s.start_pixel_sample(x, y, i);
                    let p = s.pixel_2d();
                    let q = s.next_2d();
                    let u = s.next_1d();
                    let r = s.next_2d();
                    for (d, v) in [p.x, p.y, q.x, q.y, u, r.x, r.y].into_iter().enumerate() {
                        counts[d][(v * BINS as f32) as usize] += 1;
                    }
                    n += 1;
                }
            }
        }
        let expected = n as f64 / BINS as f64;
        for (d, c) in counts.iter().enumerate() {
            let chi2: f64 = c.iter().map(|&o| (o as f64 - expected).powi(2) / expected).sum();
            assert!(chi2 < 37.7, "dimension {d}: chi2 {chi2}, counts {c:?}");
        }
    }

    #[test]
    fn sobol_numbers_depend_only_on_pixel_index_and_seed() {
        let draw = |s: &mut Sampler, x: u32, y: u32, i: u32| {
            s.start_pixel_sample(x, y, i);
            let p = s.pixel_2d();
            let u = s.next_1d();
            let q = s.next_2d();
            [p.x, p.y, u, q.x, q.y]
        };
        let pixels: Vec<(u32, u32, u32)> = (0..8)
            .flat_map(|y| (0..8).flat_map(move |x| (0..8).map(move |i| (x, y, i))))
            .collect();
        let mut a = Sampler::new(SamplerKind::Sobol, 8, 7);
        let forward: Vec<_> = pixels.iter().map(|&(x, y, i)| draw(&mut a, x, y, i)).collect();
        let mut b = Sampler::new(SamplerKind::Sobol, 8, 7);
        let mut backward: Vec<_> = pixels.iter().rev().map(|&(x, y, i)| draw(&mut b, x, y, i)).collect();
        backward.reverse();
        assert_eq!(forward, backward, "visiting order changes nothing");

        let mut c = Sampler::new(SamplerKind::Sobol, 8, 8);
        let other: Vec<_> = pixels.iter().map(|&(x, y, i)| draw(&mut c, x, y, i)).collect();
        let same = forward.iter().zip(&other).filter(|(f, o)| f == o).count();
        assert_eq!(same, 0, "a different seed gives a different pattern");
        // Neighbouring pixels are decorrelated too.
        assert_ne!(forward[0], forward[8]);
    }

    #[test]
    fn sobol_estimates_are_unbiased() {
        // f(u, v, w) = u² + v w e^u has integral 1/3 + (e - 1)/4 over
        // [0,1)³. Each pixel's 16-sample Sobol estimate is one independent
        // draw of the randomised quasi-Monte Carlo estimator (independent
        // scrambles); the mean over pixels must match the integral within
        // 4 standard errors of that mean, measured from the pixel estimates.
        let f = |u: f64, v: f64, w: f64| u * u + v * w * u.exp();
        let integral = 1.0 / 3.0 + (std::f64::consts::E - 1.0) / 4.0;
        // Each pixel's 16-sample estimate of f, for 50×50 pixels, and
        // their mean and variance.
        let pixel_estimates = |kind: SamplerKind| {
            let spp = 16;
            let mut s = Sampler::new(kind, spp, 1);
            let mut estimates = Vec::new();
            for y in 0..50 {
                for x in 0..50 {
                    let mut sum = 0.0;
                    for i in 0..spp {
                        s.start_pixel_sample(x, y, i);
                        let p = s.pixel_2d();
                        let w = s.next_1d();
                        sum += f(p.x as f64, p.y as f64, w as f64);
                    }
                    estimates.push(sum / spp as f64);
                }
            }
            let n = estimates.len() as f64;
            let mean = estimates.iter().sum::<f64>() / n;
            let var = estimates.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0);
            (mean, var, n)
        };
        let (mean, var, n) = pixel_estimates(SamplerKind::Sobol);
        let stderr = (var / n).sqrt();
        assert!(
            (mean - integral).abs() < 4.0 * stderr,
            "mean {mean}, integral {integral}, stderr {stderr}"
        );
        // Stratification pays: the per-pixel variance is below that of 16
        // independent samples of f, measured the same way.
        let (_, ind_var, _) = pixel_estimates(SamplerKind::Independent);
        assert!(var < 0.5 * ind_var, "sobol variance {var} vs independent {ind_var}");
    }

    #[test]
    fn center_sampler_hits_pixel_centres() {
        let mut s = Sampler::new(SamplerKind::Center, 4, 0);
        s.start_pixel_sample(0, 0, 2);
        assert_eq!(s.pixel_2d(), Vec2::splat(0.5));
    }
}
