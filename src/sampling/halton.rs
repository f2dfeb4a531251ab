//! The Halton sequence (Halton 1960) as pbrt-v4's `HaltonSampler` draws it:
//! dimension i of point a is the radical inverse of a in the i-th prime
//! base, its digits randomised by random permutations (Faure 1992) or by
//! Owen's nested scrambling, and the image covered by one sequence whose
//! first two dimensions, scaled to 2^j × 3^k pixels, pick the pixel
//! (pbrt-v4, section 8.6).
//!
//! Point a of the sequence lies in pixel (x, y) of a tile of 2^j × 3^k
//! pixels when the first j base-2 digits of a, reversed, are x, and the
//! first k base-3 digits, reversed, are y; by the Chinese remainder theorem
//! these are the indices a ≡ a₀ (mod 2^j·3^k) for one a₀ per pixel, which
//! [`HaltonPixels::index`] finds. Each pixel thus gets its own
//! well-distributed subsequence, and the image as a whole one sequence.

use super::sampler::permutation_element;
use std::sync::{Arc, Mutex, OnceLock};

/// How many prime bases the sequence has; later dimensions start over at
/// the third (as pbrt-v4's `PrimeTableSize`).
pub const DIMENSIONS: u32 = 1000;

/// The tile of pixels a sequence spans is at most this many pixels wide
/// and tall, before the powers of 2 and 3 (pbrt-v4's `MaxHaltonResolution`).
const MAX_RESOLUTION: u32 = 128;

/// The first [`DIMENSIONS`] primes.
fn primes() -> &'static [u32] {
    static PRIMES: OnceLock<Vec<u32>> = OnceLock::new();
    PRIMES.get_or_init(|| {
        // The 1000th prime is 7919.
        let limit = 7920;
        let mut composite = vec![false; limit];
        let mut found = Vec::with_capacity(DIMENSIONS as usize);
        for n in 2..limit {
            if !composite[n] {
                found.push(n as u32);
                for m in (n * n..limit).step_by(n) {
                    composite[m] = true;
                }
            }
        }
        debug_assert_eq!(found.len(), DIMENSIONS as usize);
        found
    })
}

/// The base of dimension `dim`.
pub fn base(dim: u32) -> u32 {
    primes()[dim as usize]
}

/// The largest f32 below 1.
pub(super) const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// How the digits of each dimension are randomised.
#[derive(Clone, Copy, Debug)]
pub enum Scramble<'a> {
    /// Each digit position of each dimension has its own random permutation
    /// of the digits (pbrt-v4's `permutedigits`, its default), these.
    PermuteDigits(&'a DigitPermutations),
    /// Each digit is permuted by a permutation chosen by the digits before
    /// it and the seed (Owen 1995; pbrt-v4's `owen`).
    Owen {
        /// The user's seed.
        seed: u64,
    },
}

/// The number of base-`b` digits that still change an f32 in [0, 1), as
/// pbrt-v4's `DigitPermutation` counts them.
fn digit_count(b: u32) -> u32 {
    let inv_base = 1.0 / b as f32;
    let mut inv_base_m = 1.0f32;
    let mut n = 0;
    while 1.0 - (b - 1) as f32 * inv_base_m < 1.0 {
        n += 1;
        inv_base_m *= inv_base;
    }
    n
}

/// The digit counts of the bases, computed once.
fn digit_counts() -> &'static [u32] {
    static COUNTS: OnceLock<Vec<u32>> = OnceLock::new();
    COUNTS.get_or_init(|| primes().iter().map(|&b| digit_count(b)).collect())
}

/// A 32-bit hash of the numbers (the finaliser of MurmurHash3 over each).
fn hash(values: [u64; 3]) -> u32 {
    let mut h = 0x9e37_79b9_7f4a_7c15u64;
    for v in values {
        h ^= v;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        h ^= h >> 33;
    }
    h as u32
}

/// Dimension `dim` of point `a`, without randomisation: the digits of a in
/// base b mirrored about the radix point.
pub fn radical_inverse(dim: u32, mut a: u64) -> f32 {
    let b = base(dim) as u64;
    let (mut reversed, mut scale) = (0u64, 1.0f64);
    while a > 0 {
        let next = a / b;
        reversed = reversed * b + (a - next * b);
        scale /= b as f64;
        a = next;
    }
    ((reversed as f64 * scale) as f32).min(ONE_MINUS_EPSILON)
}

/// The random digit permutations of one seed (pbrt-v4's
/// `DigitPermutation`s): for each dimension and digit position, a
/// permutation of the base's digits, tabulated when the dimension is first
/// used (a path uses a few dozen of the thousand), and shared by every
/// sampler of that seed.
pub struct DigitPermutations {
    seed: u64,
    /// Per dimension: `table[position · b + digit]`.
    tables: Vec<OnceLock<Box<[u16]>>>,
}

impl std::fmt::Debug for DigitPermutations {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DigitPermutations {{ seed: {} }}", self.seed)
    }
}

impl DigitPermutations {
    /// The permutations of `seed`, made once for all the samplers of a
    /// render (the few seeds used last are kept).
    pub fn shared(seed: u64) -> Arc<DigitPermutations> {
        static RECENT: Mutex<Vec<Arc<DigitPermutations>>> = Mutex::new(Vec::new());
        let mut recent = RECENT.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = recent.iter().find(|p| p.seed == seed) {
            return p.clone();
        }
        let made = Arc::new(DigitPermutations {
            seed,
            tables: (0..DIMENSIONS).map(|_| OnceLock::new()).collect(),
        });
        if recent.len() == 4 {
            recent.remove(0);
        }
        recent.push(made.clone());
        made
    }

    /// The permutation of digit position `position` of dimension `dim`.
    fn permutation(seed: u64, dim: u32, position: u32) -> impl Fn(u32) -> u32 {
        let (b, key) = (base(dim), hash([seed, dim as u64, position as u64]));
        move |digit| permutation_element(digit, b, key)
    }

    /// Dimension `dim`'s table.
    fn table(&self, dim: u32) -> &[u16] {
        self.tables[dim as usize].get_or_init(|| {
            let b = base(dim);
            (0..digit_counts()[dim as usize])
                .flat_map(|position| (0..b).map(move |digit| (position, digit)))
                .map(|(position, digit)| Self::permutation(self.seed, dim, position)(digit) as u16)
                .collect()
        })
    }
}

/// Dimension `dim` of point `a`, its digits randomised by `scramble`.
/// Every digit position up to f32's precision is permuted, the leading
/// zeros of a too, so that the points fill [0, 1) and not only its left
/// part.
pub fn scrambled_radical_inverse(dim: u32, mut a: u64, scramble: Scramble) -> f32 {
    let b = base(dim);
    let (mut reversed, mut scale) = (0u64, 1.0f64);
    let table = match scramble {
        Scramble::PermuteDigits(permutations) => permutations.table(dim),
        Scramble::Owen { .. } => &[],
    };
    for position in 0..digit_counts()[dim as usize] {
        let next = a / b as u64;
        let digit = (a - next * b as u64) as u32;
        let permuted = match scramble {
            Scramble::PermuteDigits(_) => table[(position * b + digit) as usize] as u32,
            // The digits so far choose the permutation: nested scrambling.
            Scramble::Owen { seed } => {
                permutation_element(digit, b, hash([seed, dim as u64 | (position as u64) << 32, reversed]))
            }
        };
        reversed = reversed * b as u64 + permuted as u64;
        scale /= b as f64;
        a = next;
    }
    ((reversed as f64 * scale) as f32).min(ONE_MINUS_EPSILON)
}

/// Which points of the sequence fall in which pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HaltonPixels {
    /// 2^j and 3^k: the tile of pixels one sequence spans.
    scales: [u32; 2],
    /// j and k.
    exponents: [u32; 2],
    /// The inverse of 3^k modulo 2^j, and of 2^j modulo 3^k.
    inverses: [u64; 2],
}

impl HaltonPixels {
    /// The tiling of an image of `width` × `height` pixels: the smallest
    /// powers of 2 and 3 at least the image's sides, or 128.
    pub fn new(width: u32, height: u32) -> HaltonPixels {
        let mut scales = [1u32; 2];
        let mut exponents = [0u32; 2];
        for (i, (b, side)) in [(2u32, width), (3, height)].into_iter().enumerate() {
            while scales[i] < side.clamp(1, MAX_RESOLUTION) {
                scales[i] *= b;
                exponents[i] += 1;
            }
        }
        HaltonPixels {
            scales,
            exponents,
            inverses: [
                inverse_mod(scales[1] as u64, scales[0] as u64),
                inverse_mod(scales[0] as u64, scales[1] as u64),
            ],
        }
    }

    /// The index in the sequence of sample `sample` of pixel (x, y).
    pub fn index(&self, x: u32, y: u32, sample: u32) -> u64 {
        let stride = self.scales[0] as u64 * self.scales[1] as u64;
        let mut first = 0u64;
        if stride > 1 {
            for (i, (p, b)) in [(x, 2u32), (y, 3)].into_iter().enumerate() {
                // The index whose first digits, reversed, are p's.
                let mut digits = (p % MAX_RESOLUTION) as u64;
                let mut offset = 0u64;
                for _ in 0..self.exponents[i] {
                    offset = offset * b as u64 + digits % b as u64;
                    digits /= b as u64;
                }
                first += offset * (stride / self.scales[i] as u64) * self.inverses[i];
            }
            first %= stride;
        }
        first + sample as u64 * stride
    }

    /// The position within its pixel of point `index`: its first two
    /// dimensions with the digits that chose the pixel taken off.
    pub fn pixel_position(&self, index: u64) -> (f32, f32) {
        (
            radical_inverse(0, index >> self.exponents[0]),
            radical_inverse(1, index / self.scales[1] as u64),
        )
    }
}

/// The inverse of `a` modulo `n` (a and n coprime; 0 for n = 1).
fn inverse_mod(a: u64, n: u64) -> u64 {
    // The extended Euclidean algorithm on (a, n).
    let (mut r0, mut r1) = (a as i64, n as i64);
    let (mut s0, mut s1) = (1i64, 0i64);
    while r1 != 0 {
        let q = r0 / r1;
        (r0, r1) = (r1, r0 - q * r1);
        (s0, s1) = (s1, s0 - q * s1);
    }
    s0.rem_euclid(n as i64) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bases_are_the_primes() {
        assert_eq!(&primes()[..6], &[2, 3, 5, 7, 11, 13]);
        assert_eq!(base(DIMENSIONS - 1), 7919);
        assert_eq!(digit_count(2), 25);
    }

    /// Base 2 is van der Corput's sequence; base 3 mirrors ternary digits.
    #[test]
    fn radical_inverses_mirror_the_digits() {
        let vdc = [0.0, 0.5, 0.25, 0.75, 0.125, 0.625, 0.375, 0.875];
        for (a, v) in vdc.iter().enumerate() {
            assert_eq!(radical_inverse(0, a as u64), *v);
        }
        // 5 = 12₃ → 0.21₃ = 2/3 + 1/9.
        assert!((radical_inverse(1, 5) - 7.0 / 9.0).abs() < 1e-7);
    }

    /// Randomised, each dimension is still a (0, 1)-sequence: the first b^k
    /// points put one point in each of the b^k intervals of length b^-k,
    /// for both scrambles, in a small and a large base; different seeds
    /// give different points.
    #[test]
    fn scrambled_dimensions_stay_stratified() {
        let (one, two) = (DigitPermutations::shared(1), DigitPermutations::shared(2));
        for (scramble, other) in [
            (Scramble::PermuteDigits(&one), Scramble::PermuteDigits(&two)),
            (Scramble::Owen { seed: 1 }, Scramble::Owen { seed: 2 }),
        ] {
            for (dim, k) in [(0u32, 10u32), (1, 6), (4, 3), (40, 1)] {
                let b = base(dim) as u64;
                let n = b.pow(k);
                let mut seen = vec![false; n as usize];
                for a in 0..n {
                    let v = scrambled_radical_inverse(dim, a, scramble);
                    assert!((0.0..1.0).contains(&v));
                    let cell = ((v as f64 * n as f64) as usize).min(n as usize - 1);
                    assert!(!seen[cell], "{scramble:?} dim {dim}: two points in cell {cell}");
                    seen[cell] = true;
                }
            }
            assert_ne!(
                scrambled_radical_inverse(3, 12, scramble),
                scrambled_radical_inverse(3, 12, other)
            );
        }
    }

    /// Sample i of pixel (x, y) is a point of the sequence whose first two
    /// dimensions, scaled to the tile, fall in that pixel, at the position
    /// `pixel_position` gives; the pixels of a tile share out the indices.
    #[test]
    fn each_pixel_gets_the_points_that_fall_in_it() {
        for (w, h) in [(128u32, 243u32), (300, 200), (5, 7), (1, 1)] {
            let pixels = HaltonPixels::new(w, h);
            let stride = pixels.scales[0] as u64 * pixels.scales[1] as u64;
            let mut firsts = std::collections::HashSet::new();
            for y in 0..h.min(30) {
                for x in 0..w.min(40) {
                    for sample in [0u32, 1, 7] {
                        let a = pixels.index(x, y, sample);
                        let gx = radical_inverse(0, a) as f64 * pixels.scales[0] as f64;
                        let gy = radical_inverse(1, a) as f64 * pixels.scales[1] as f64;
                        let (px, py) = pixels.pixel_position(a);
                        let (tx, ty) = (
                            (x % MAX_RESOLUTION) % pixels.scales[0],
                            (y % MAX_RESOLUTION) % pixels.scales[1],
                        );
                        // (Within f32's rounding of the radical inverses.)
                        let inside = |g: f64, t: u32| g > t as f64 - 1e-4 && g < t as f64 + 1.0 + 1e-4;
                        assert!(
                            inside(gx, tx) && inside(gy, ty),
                            "{w}×{h} ({x}, {y}) #{sample}: {gx} {gy}"
                        );
                        assert!((gx - tx as f64 - px as f64).abs() < 1e-4 && (gy - ty as f64 - py as f64).abs() < 1e-4);
                        if sample == 0 {
                            firsts.insert(a);
                        }
                        assert_eq!(a % stride, pixels.index(x, y, 0));
                    }
                }
            }
            if w <= 40 && h <= 30 {
                assert_eq!(firsts.len() as u64, stride.min((w * h) as u64));
            }
        }
    }
}
