//! Owen-scrambled Sobol points with hash-based scrambling and shuffling
//! (Burley 2020, "Practical Hash-based Owen Scrambling", JCGT 9(4)).
//!
//! Every 2D sample is the pair of Sobol dimensions 0 and 1, the first two
//! dimensions of the Sobol sequence and together a (0,2)-sequence in base 2:
//! any aligned block of 2^k consecutive indices puts exactly one point in
//! every elementary interval of area 2^-k. Higher dimensions of a path are
//! not taken from higher Sobol dimensions (whose 2D projections are poorly
//! distributed) but "padded": each dimension pair of a path re-uses
//! dimensions 0 and 1 with its own random shuffle of the sample order and
//! its own Owen scramble, so that pairs are decorrelated from one another
//! while each keeps the (0,2) stratification.
//!
//! Owen's nested uniform scrambling randomly permutes each base-2 digit of a
//! point conditioned on the digits above it; it keeps the net property and
//! makes each point uniform over [0, 1). Burley implements it with a hash of
//! the bit-reversed value in which each bit is flipped by a function of the
//! less significant bits only (Laine and Karras 2011, "Stratified sampling
//! for stochastic transparency"). Applied to the sample index instead of the
//! point, the same scramble maps the first 2^k indices onto an aligned block
//! of 2^k indices in a random order: the shuffle.

/// Generator matrix columns of Sobol dimension 1, for primitive polynomial
/// x + 1 with m = 1: v_0 = 2^31 and v_k = v_{k-1} ^ (v_{k-1} >> 1), which is
/// Pascal's triangle modulo 2. Column k is XORed in when bit k of the index
/// is set. (Dimension 0 is the identity matrix in reversed order: the
/// van der Corput sequence, `index.reverse_bits()`.)
const SOBOL_DIM1: [u32; 32] = {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    v
};

/// Sobol dimension 1 with its bits reversed, as a function of the index
/// with its bits reversed, one table per byte of that reversed index: entry
/// `b` of table `t` XORs the reversed columns of the index bits that byte
/// `t` holds. Taking the reversed index saves reversing it, and the tables
/// replace a loop over the set bits (the shuffle sets about half the bits
/// of an index).
const SOBOL_DIM1_REVERSED_BY_BYTE: [[u32; 256]; 4] = {
    let mut t = [[0u32; 256]; 4];
    let mut table = 0;
    while table < 4 {
        let mut byte = 0;
        while byte < 256 {
            let mut x = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if byte & (1 << bit) != 0 {
                    // Bit `8 table + bit` of the reversed index is index
                    // bit `31 - 8 table - bit`.
                    x ^= SOBOL_DIM1[31 - 8 * table - bit].reverse_bits();
                }
                bit += 1;
            }
            t[table][byte] = x;
            byte += 1;
        }
        table += 1;
    }
    t
};

/// Sobol dimension 1, bit-reversed, of the index whose reversed bits are
/// `reversed_index`.
#[inline]
fn sobol_dim1_reversed(reversed_index: u32) -> u32 {
    let t = &SOBOL_DIM1_REVERSED_BY_BYTE;
    t[0][(reversed_index & 0xff) as usize]
        ^ t[1][((reversed_index >> 8) & 0xff) as usize]
        ^ t[2][((reversed_index >> 16) & 0xff) as usize]
        ^ t[3][(reversed_index >> 24) as usize]
}

/// Sobol dimension 0 of `index` as a 32-bit binary fraction.
#[inline]
pub fn sobol_dim0(index: u32) -> u32 {
    index.reverse_bits()
}

/// Sobol dimension 1 of `index` as a 32-bit binary fraction.
#[inline]
pub fn sobol_dim1(index: u32) -> u32 {
    let mut bits = index;
    let mut x = 0;
    // Sample indices are small: one XOR per set bit.
    while bits != 0 {
        x ^= SOBOL_DIM1[bits.trailing_zeros() as usize];
        bits &= bits - 1;
    }
    x
}

/// A bijection of u32 in which output bit k is input bit k flipped by a
/// function of the input bits below k and the seed (Laine–Karras). The
/// operations are those of Burley 2020, listing 2, with the constants of
/// Vegdahl's improvement (2021, "Building a better LK hash"): adding the
/// seed, multiplying by an odd number and XORing in a product with an even
/// number each change bit k only as a function of the bits below it.
#[inline]
fn laine_karras_permutation(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3d20_adea);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6c56);
    x ^= x.wrapping_mul(0x53a2_2864);
    x
}

/// Owen's nested uniform scramble of a 32-bit binary fraction: each bit is
/// flipped by a function of the bits above it and the seed.
#[inline]
pub fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    laine_karras_permutation(x.reverse_bits(), seed).reverse_bits()
}

/// A 32-bit binary fraction as an `f32` in [0, 1): the top 24 bits, so that
/// every value is exact and below 1.
#[inline]
pub fn fraction_to_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Seeds of one dimension pair: the index shuffle and one scramble per axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairSeeds {
    /// Scrambles the sample index: the order of the pattern's points.
    pub shuffle: u32,
    /// Scrambles the first coordinate.
    pub x: u32,
    /// Scrambles the second coordinate.
    pub y: u32,
}

impl PairSeeds {
    /// The seeds of dimension pair `dimension` of the pixel whose hashed key
    /// is `pixel_key`: one 64-bit mix gives the first two; the third is the
    /// high half of its product with an odd constant, which depends on all
    /// of its bits.
    #[inline]
    pub fn new(pixel_key: u64, dimension: u32) -> Self {
        let a = super::rng::mix_bits(pixel_key ^ (dimension as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        PairSeeds {
            shuffle: a as u32,
            x: (a >> 32) as u32,
            y: (a.wrapping_mul(0xd1b5_4a32_d192_ed03) >> 32) as u32,
        }
    }
}

/// Point `index` of the shuffled, Owen-scrambled 2D Sobol pattern chosen by
/// `seeds`, as two 32-bit binary fractions. `reversed_index` is
/// `index.reverse_bits()`, which the caller computes once per sample.
#[inline]
pub fn sobol_2d(reversed_index: u32, seeds: PairSeeds) -> (u32, u32) {
    // The scrambles work on reversed bits. The shuffled index, reversed, is
    // the scrambled reversed index; dimension 0 reversed is the index
    // itself, and dimension 1 reversed comes from the reversed index.
    let shuffled_reversed = laine_karras_permutation(reversed_index, seeds.shuffle);
    (
        laine_karras_permutation(shuffled_reversed.reverse_bits(), seeds.x).reverse_bits(),
        laine_karras_permutation(sobol_dim1_reversed(shuffled_reversed), seeds.y).reverse_bits(),
    )
}

/// Point `index` of the shuffled, Owen-scrambled 1D pattern (Sobol
/// dimension 0) chosen by `seeds`, as a 32-bit binary fraction, from
/// `reversed_index = index.reverse_bits()`.
#[inline]
pub fn sobol_1d(reversed_index: u32, seeds: PairSeeds) -> u32 {
    let shuffled_reversed = laine_karras_permutation(reversed_index, seeds.shuffle);
    laine_karras_permutation(shuffled_reversed.reverse_bits(), seeds.x).reverse_bits()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts points per elementary interval of shape 2^-a × 2^-(k-a) and
    /// checks each holds exactly one point, for every a in 0..=k.
    fn assert_is_0_k_2_net(points: &[(u32, u32)], k: u32) {
        assert_eq!(points.len(), 1 << k);
        for a in 0..=k {
            let mut seen = vec![false; 1 << k];
            for &(x, y) in points {
                let cx = if a == 0 { 0 } else { x >> (32 - a) };
                let cy = if a == k { 0 } else { y >> (32 - (k - a)) };
                let cell = ((cx << (k - a)) | cy) as usize;
                assert!(
                    !seen[cell],
                    "two points in interval {cell} of shape 2^-{a} x 2^-{}",
                    k - a
                );
                seen[cell] = true;
            }
        }
    }

    #[test]
    fn first_columns_match_the_sobol_sequence() {
        // The first points of Sobol dimension 1 in natural (not Gray-code)
        // index order: index 4 = v_2 = 5/8, index 5 = v_0 ^ v_2 = 1/8, ...
        let expected = [0.0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875];
        for (i, e) in expected.iter().enumerate() {
            assert_eq!(sobol_dim1(i as u32) as f64 / 4_294_967_296.0, *e, "index {i}");
        }
        assert_eq!(sobol_dim0(1), 1 << 31);
        assert_eq!(sobol_dim0(3), 3 << 30);
    }

    #[test]
    fn unscrambled_sobol_blocks_are_nets() {
        for k in [1, 4, 7] {
            for block in [0u32, 1, 5] {
                let pts: Vec<_> = (0..1u32 << k)
                    .map(|i| {
                        let j = (block << k) | i;
                        (sobol_dim0(j), sobol_dim1(j))
                    })
                    .collect();
                assert_is_0_k_2_net(&pts, k);
            }
        }
    }

    #[test]
    fn laine_karras_flips_bits_from_lower_bits_only() {
        // Two inputs that agree on bits 0..k give outputs that agree there.
        let seeds = [0u32, 1, 0x9e37_79b9, 0xdead_beef];
        let mut rng = super::super::rng::Pcg32::new(3, 0);
        for &seed in &seeds {
            for _ in 0..200 {
                let a = rng.next_u32();
                let b = rng.next_u32();
                let k = rng.next_below(32);
                let mask = (1u32 << k) - 1;
                let b = (a & mask) | (b & !mask);
                let (fa, fb) = (laine_karras_permutation(a, seed), laine_karras_permutation(b, seed));
                assert_eq!(fa & mask, fb & mask, "seed {seed:#x}, k {k}");
            }
        }
    }

    #[test]
    fn scrambled_and_shuffled_prefixes_are_nets() {
        for seed in 0..20u64 {
            let seeds = PairSeeds::new(super::super::rng::mix_bits(seed), seed as u32);
            for k in [0, 3, 4, 6, 8] {
                let pts: Vec<_> = (0..1u32 << k).map(|i| sobol_2d(i.reverse_bits(), seeds)).collect();
                assert_is_0_k_2_net(&pts, k);
            }
        }
    }

    #[test]
    fn shuffle_maps_a_prefix_onto_an_aligned_block() {
        for seed in [0u32, 7, 0xffff_ffff, 0x1234_5678] {
            for k in [2u32, 5, 9] {
                let blocks: Vec<u32> = (0..1u32 << k).map(|i| nested_uniform_scramble(i, seed) >> k).collect();
                assert!(blocks.iter().all(|&b| b == blocks[0]), "seed {seed:#x} k {k}");
                let mut low: Vec<u32> = (0..1u32 << k)
                    .map(|i| nested_uniform_scramble(i, seed) & ((1 << k) - 1))
                    .collect();
                low.sort_unstable();
                assert!(low.iter().enumerate().all(|(i, &v)| v == i as u32));
            }
        }
    }

    #[test]
    fn fast_paths_equal_the_plain_definitions() {
        let seeds = PairSeeds::new(42, 3);
        for index in [0u32, 1, 2, 3, 100, 65_535, 1 << 20, u32::MAX] {
            let i = nested_uniform_scramble(index, seeds.shuffle);
            let plain = (
                nested_uniform_scramble(sobol_dim0(i), seeds.x),
                nested_uniform_scramble(sobol_dim1(i), seeds.y),
            );
            assert_eq!(sobol_2d(index.reverse_bits(), seeds), plain, "index {index}");
            assert_eq!(sobol_1d(index.reverse_bits(), seeds), plain.0, "index {index}");
        }
    }

    #[test]
    fn fractions_stay_below_one() {
        assert_eq!(fraction_to_f32(u32::MAX), 1.0 - f32::EPSILON / 2.0);
        assert_eq!(fraction_to_f32(0), 0.0);
    }
}
