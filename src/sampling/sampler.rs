//! Per-pixel sample generators.
//!
//! A sample's random numbers depend only on (pixel, sample index, seed),
//! never on which thread draws them or in which order pixels are visited:
//! this is what makes renders bit-identical for any thread count and lets an
//! interrupted render resume exactly.

use super::rng::{Pcg32, hash_u64s};
use glam::Vec2;

/// How the sample positions inside a pixel are chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SamplerKind {
    /// Every sample goes through the pixel centre: one sample per pixel
    /// shows the aliasing that supersampling removes.
    Center,
    /// Independent uniform jitter inside the pixel.
    Independent,
    /// Jittered stratification: the pixel is divided into about `spp`
    /// cells and each sample is jittered inside its own cell.
    #[default]
    Stratified,
}

impl SamplerKind {
    /// The names accepted on the command line and in scene files.
    pub const NAMES: [&'static str; 3] = ["center", "independent", "stratified"];

    /// Parses one of [`SamplerKind::NAMES`].
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "center" => Some(SamplerKind::Center),
            "independent" => Some(SamplerKind::Independent),
            "stratified" => Some(SamplerKind::Stratified),
            _ => None,
        }
    }

    /// The name of this kind.
    pub fn name(&self) -> &'static str {
        match self {
            SamplerKind::Center => "center",
            SamplerKind::Independent => "independent",
            SamplerKind::Stratified => "stratified",
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
    sample_index: u32,
    /// Stratification grid: `cols × rows ≥ spp` cells.
    cols: u32,
    rows: u32,
}

impl Sampler {
    /// A sampler for `spp` samples per pixel with the user's `seed`.
    pub fn new(kind: SamplerKind, spp: u32, seed: u64) -> Self {
        let spp = spp.max(1);
        let cols = (spp as f64).sqrt().floor().max(1.0) as u32;
        let rows = spp.div_ceil(cols);
        Sampler {
            kind,
            spp,
            seed,
            rng: Pcg32::new(0, 0),
            pixel_key: 0,
            sample_index: 0,
            cols,
            rows,
        }
    }

    /// The configured kind.
    pub fn kind(&self) -> SamplerKind {
        self.kind
    }

    /// Starts sample `index` of pixel `(x, y)`: from here on the sampler
    /// returns that sample's numbers.
    #[inline]
    pub fn start_pixel_sample(&mut self, x: u32, y: u32, index: u32) {
        self.pixel_key = hash_u64s(&[x as u64, y as u64, self.seed]);
        self.sample_index = index;
        self.rng = Pcg32::new(hash_u64s(&[self.pixel_key, index as u64]), 0);
    }

    /// A uniform number in [0, 1).
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        self.rng.next_f32()
    }

    /// A uniform point in [0, 1)².
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let x = self.rng.next_f32();
        let y = self.rng.next_f32();
        Vec2::new(x, y)
    }

    /// The sample's position inside its pixel, in [0, 1)².
    #[inline]
    pub fn pixel_2d(&mut self) -> Vec2 {
        match self.kind {
            SamplerKind::Center => Vec2::splat(0.5),
            SamplerKind::Independent => self.next_2d(),
            SamplerKind::Stratified => {
                // Each pixel visits the cells in its own random order, so
                // that the first k samples of an interrupted render are
                // spread over the pixel rather than filling its top rows.
                let cell = permutation_element(self.sample_index % self.spp, self.spp, self.pixel_key as u32);
                let (cx, cy) = (cell % self.cols, cell / self.cols);
                let j = self.next_2d();
                Vec2::new(
                    (cx as f32 + j.x) / self.cols as f32,
                    (cy as f32 + j.y) / self.rows as f32,
                )
            }
        }
    }
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

    #[test]
    fn stratified_puts_one_sample_in_each_cell() {
        let spp = 16;
        let mut s = Sampler::new(SamplerKind::Stratified, spp, 1);
        let mut cells = [0u32; 16];
        for i in 0..spp {
            s.start_pixel_sample(3, 4, i);
            let p = s.pixel_2d();
            assert!(p.cmpge(Vec2::ZERO).all() && p.cmplt(Vec2::ONE).all());
            let c = (p.x * 4.0) as usize + 4 * (p.y * 4.0) as usize;
            cells[c] += 1;
        }
        assert!(cells.iter().all(|&c| c == 1), "{cells:?}");
    }

    #[test]
    fn center_sampler_hits_pixel_centres() {
        let mut s = Sampler::new(SamplerKind::Center, 4, 0);
        s.start_pixel_sample(0, 0, 2);
        assert_eq!(s.pixel_2d(), Vec2::splat(0.5));
    }
}
