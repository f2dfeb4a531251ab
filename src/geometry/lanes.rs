//! Eight `f32` lanes in one AVX register ([`F8`]), for the eight-wide
//! rectangle, triangle and sphere tests of primitive blocks
//! (`accel::blocks`); the sphere blocks run the one sphere test written
//! over [`Real`](super::real::Real).
//!
//! Every operation is a function built for AVX: it may only run where the
//! processor has AVX, which the compiler enforces by letting only other
//! AVX functions call it. The aggregate's traversal checks
//! for AVX once and enter the lane code through such functions (one ray
//! against blocks of eight primitives). (Plain loops over `[f32; 8]` were
//! tried first: the compiler vectorised them across the wrong dimension and
//! the test took more instructions than the tree it replaced.)
//!
//! Comparisons follow Rust's scalar ones: ordered (false for NaN) except
//! `ne`, which is true for NaN, so a lane computes what the one-primitive
//! test computes.
//!
//! The module also holds the other places where trazo calls intrinsics,
//! both on SSE or SSE2, which every x86-64 processor has: `step_away_sse2`,
//! the last step of a robust ray origin (the compiler did not vectorise it
//! from plain code), and `prefetch`, a cache hint for tree traversal.
#![allow(unsafe_code)]

use std::arch::x86_64::*;

/// Lanes per value.
pub const LANES: usize = 8;

/// Eight `f32` as stored in a primitive block: aligned for one load.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct Lanes(pub [f32; LANES]);

/// Eight `f32` lanes in a register.
#[derive(Clone, Copy, Debug)]
pub struct F8(__m256);

/// A lane mask: each lane all ones (true) or zero (false).
#[derive(Clone, Copy, Debug)]
pub struct M8(__m256);

macro_rules! compare {
    ($name:ident, $predicate:ident, $doc:literal) => {
        #[doc = $doc]
        #[inline]
        #[target_feature(enable = "avx")]
        pub fn $name(self, other: F8) -> M8 {
            M8(_mm256_cmp_ps::<$predicate>(self.0, other.0))
        }
    };
}

macro_rules! binary {
    ($name:ident, $intrinsic:ident, $doc:literal) => {
        #[doc = $doc]
        #[inline]
        #[target_feature(enable = "avx")]
        pub fn $name(self, other: F8) -> F8 {
            F8($intrinsic(self.0, other.0))
        }
    };
}

impl F8 {
    /// The stored lanes.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn load(lanes: &Lanes) -> F8 {
        // SAFETY: `Lanes` is eight f32 aligned to 32 bytes.
        F8(unsafe { _mm256_load_ps(lanes.0.as_ptr()) })
    }

    /// All lanes `x`.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn splat(x: f32) -> F8 {
        F8(_mm256_set1_ps(x))
    }

    /// The lanes as an array.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn to_array(self) -> [f32; LANES] {
        let mut out = Lanes([0.0; LANES]);
        // SAFETY: `Lanes` is eight f32 aligned to 32 bytes.
        unsafe { _mm256_store_ps(out.0.as_mut_ptr(), self.0) };
        out.0
    }

    /// Eight consecutive values, at any alignment.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn load_unaligned(values: &[f32; LANES]) -> F8 {
        // SAFETY: eight f32 are readable from the reference.
        F8(unsafe { _mm256_loadu_ps(values.as_ptr()) })
    }

    /// Stores the lanes into `out`, at any alignment.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn store_unaligned(self, out: &mut [f32; LANES]) {
        // SAFETY: eight f32 are writable through the reference.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) }
    }

    /// Lanes from an array.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn from_array(a: [f32; LANES]) -> F8 {
        F8::load(&Lanes(a))
    }

    binary!(add, _mm256_add_ps, "Lane-wise sum.");
    binary!(sub, _mm256_sub_ps, "Lane-wise difference.");
    binary!(mul, _mm256_mul_ps, "Lane-wise product.");
    binary!(div, _mm256_div_ps, "Lane-wise quotient.");
    binary!(
        max,
        _mm256_max_ps,
        "Lane-wise `if self > other { self } else { other }` (SSE's and glam's max)."
    );
    binary!(
        min,
        _mm256_min_ps,
        "Lane-wise `if self < other { self } else { other }` (SSE's and glam's min)."
    );

    /// Lane-wise absolute value.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn abs(self) -> F8 {
        F8(_mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0))
    }

    compare!(lt, _CMP_LT_OQ, "Lanes where `self < other`.");
    compare!(le, _CMP_LE_OQ, "Lanes where `self <= other`.");
    compare!(gt, _CMP_GT_OQ, "Lanes where `self > other`.");
    compare!(ge, _CMP_GE_OQ, "Lanes where `self >= other`.");
    compare!(eq, _CMP_EQ_OQ, "Lanes where `self == other`.");
    compare!(
        ne,
        _CMP_NEQ_UQ,
        "Lanes where `self != other` (true for NaN, as in Rust)."
    );
}

impl M8 {
    /// Lanes true in both.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn and(self, other: M8) -> M8 {
        M8(_mm256_and_ps(self.0, other.0))
    }

    /// Lanes true in either.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn or(self, other: M8) -> M8 {
        M8(_mm256_or_ps(self.0, other.0))
    }

    /// Lanes true in `self` and false in `other`.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn and_not(self, other: M8) -> M8 {
        M8(_mm256_andnot_ps(other.0, self.0))
    }

    /// Bit `i` set where lane `i` is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn bits(self) -> u32 {
        _mm256_movemask_ps(self.0) as u32
    }
}

/// Each coordinate of `x` moved by one unit in the last place toward the
/// sign of `o`'s, as `interaction::offset_ray_origin` needs, the three in
/// one SSE2 register (see `step_away_3` there for the rule).
#[cfg(target_feature = "sse2")]
#[inline]
pub fn step_away_sse2(x: glam::Vec3, o: glam::Vec3) -> glam::Vec3 {
    // SAFETY: this is compiled only where SSE2 is enabled for the whole
    // build, as it is on every x86-64 target.
    unsafe { step_away_sse2_lanes(x, o) }
}

#[cfg(target_feature = "sse2")]
#[inline]
#[target_feature(enable = "sse2")]
fn step_away_sse2_lanes(x: glam::Vec3, o: glam::Vec3) -> glam::Vec3 {
    use glam::Vec3A;
    let (xf, of): (__m128, __m128) = (Vec3A::from(x).into(), Vec3A::from(o).into());
    let (xb, ob) = (_mm_castps_si128(xf), _mm_castps_si128(of));
    let sign = _mm_set1_epi32(i32::MIN);
    let one = _mm_set1_epi32(1);
    // +1 where x and o have the same sign, −1 (all ones) where they differ.
    let step = _mm_or_si128(_mm_srai_epi32::<31>(_mm_xor_si128(xb, ob)), one);
    let magnitude = _mm_andnot_si128(sign, xb);
    // From ±0 the step goes to the smallest subnormal of o's sign.
    let from_zero = _mm_or_si128(_mm_and_si128(ob, sign), one);
    let stepped = select_bits(
        _mm_cmpeq_epi32(magnitude, _mm_setzero_si128()),
        from_zero,
        _mm_add_epi32(xb, step),
    );
    let keep = _mm_or_si128(
        _mm_castps_si128(_mm_cmpeq_ps(of, _mm_setzero_ps())),
        _mm_cmpeq_epi32(magnitude, _mm_set1_epi32(0x7f80_0000)),
    );
    glam::Vec3::from(Vec3A::from(_mm_castsi128_ps(select_bits(keep, xb, stepped))))
}

/// `a` where `mask` is set, `b` elsewhere.
#[cfg(target_feature = "sse2")]
#[inline]
#[target_feature(enable = "sse2")]
fn select_bits(mask: __m128i, a: __m128i, b: __m128i) -> __m128i {
    _mm_or_si128(_mm_and_si128(mask, a), _mm_andnot_si128(mask, b))
}

/// Whether this processor runs AVX instructions.
pub fn avx_available() -> bool {
    std::arch::is_x86_feature_detected!("avx")
}

/// Asks the processor to start loading the cache lines that `value`
/// spans, at most `lines` of them from its start, into the first-level
/// cache: a hint, which never faults and changes no result.
#[inline(always)]
pub fn prefetch<T>(value: &T, lines: usize) {
    let start = value as *const T as usize;
    let first_line = start & !63;
    let last_line = (start + std::mem::size_of::<T>().max(1) - 1) & !63;
    let n = ((last_line - first_line) / 64 + 1).min(lines);
    for line in 0..n {
        let address = (first_line + 64 * line) as *const i8;
        // SAFETY: a prefetch reads nothing architecturally and cannot
        // fault, whatever the address; SSE is part of every x86-64 target.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(address) };
    }
}

use super::real::Real;

impl std::ops::BitAnd for M8 {
    type Output = M8;
    #[inline(always)]
    fn bitand(self, other: M8) -> M8 {
        // SAFETY: a mask exists only where the processor has AVX.
        M8(unsafe { _mm256_and_ps(self.0, other.0) })
    }
}

// SAFETY (every block below): an `F8` or `M8` exists only where the
// processor has AVX (see the type).
impl Real for F8 {
    type Mask = M8;
    #[inline(always)]
    fn like(self, x: f32) -> F8 {
        F8(unsafe { _mm256_set1_ps(x) })
    }
    #[inline(always)]
    fn sqrt(self) -> F8 {
        F8(unsafe { _mm256_sqrt_ps(self.0) })
    }
    #[inline(always)]
    fn copysign(self, sign: F8) -> F8 {
        unsafe {
            let sign_bit = _mm256_set1_ps(-0.0);
            F8(_mm256_or_ps(
                _mm256_andnot_ps(sign_bit, self.0),
                _mm256_and_ps(sign_bit, sign.0),
            ))
        }
    }
    #[inline(always)]
    fn min(self, other: F8) -> F8 {
        F8(unsafe { _mm256_min_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn max(self, other: F8) -> F8 {
        F8(unsafe { _mm256_max_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn eq(self, other: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn gt(self, other: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn le(self, other: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn select(mask: M8, a: F8, b: F8) -> F8 {
        F8(unsafe { _mm256_blendv_ps(b.0, a.0, mask.0) })
    }
}

macro_rules! f8_operator {
    ($trait:ident, $method:ident, $intrinsic:ident) => {
        impl std::ops::$trait for F8 {
            type Output = F8;
            #[inline(always)]
            fn $method(self, other: F8) -> F8 {
                // SAFETY: an `F8` exists only where the processor has AVX.
                F8(unsafe { $intrinsic(self.0, other.0) })
            }
        }
    };
}
f8_operator!(Add, add, _mm256_add_ps);
f8_operator!(Sub, sub, _mm256_sub_ps);
f8_operator!(Mul, mul, _mm256_mul_ps);
f8_operator!(Div, div, _mm256_div_ps);

// SAFETY (every block below): an `F8` or `M8` exists only where the
// processor has AVX (see the type), and functions that make one from
// plain values are entered only from functions built for AVX.
impl super::simd::Floats for F8 {
    const N: usize = LANES;
    type Each<T: Copy> = [T; LANES];
    type Mask = M8;

    #[inline(always)]
    fn each<T: Copy>(f: impl FnMut(usize) -> T) -> [T; LANES] {
        std::array::from_fn(f)
    }
    #[inline(always)]
    fn repeat<T: Copy>(value: T) -> [T; LANES] {
        [value; LANES]
    }
    #[inline(always)]
    fn splat(x: f32) -> F8 {
        F8(unsafe { _mm256_set1_ps(x) })
    }
    #[inline(always)]
    fn gather(values: &[f32; LANES]) -> F8 {
        F8(unsafe { _mm256_loadu_ps(values.as_ptr()) })
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        let mut out = [0.0f32; LANES];
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
        out[i]
    }
    #[inline(always)]
    fn sqrt(self) -> F8 {
        F8(unsafe { _mm256_sqrt_ps(self.0) })
    }
    #[inline(always)]
    fn min(self, other: F8) -> F8 {
        F8(unsafe { _mm256_min_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn max(self, other: F8) -> F8 {
        F8(unsafe { _mm256_max_ps(self.0, other.0) })
    }
    #[inline(always)]
    fn ge(self, other: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn gt(self, other: F8) -> M8 {
        M8(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, other.0) })
    }
    #[inline(always)]
    fn abs(self) -> F8 {
        F8(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
    }
    #[inline(always)]
    fn sign_one(self) -> F8 {
        F8(unsafe { _mm256_or_ps(_mm256_and_ps(self.0, _mm256_set1_ps(-0.0)), _mm256_set1_ps(1.0)) })
    }
    #[inline(always)]
    fn each_lane(self) -> [f32; LANES] {
        let mut out = [0.0f32; LANES];
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
        out
    }
    #[inline(always)]
    fn select(mask: M8, a: F8, b: F8) -> F8 {
        F8(unsafe { _mm256_blendv_ps(b.0, a.0, mask.0) })
    }
    #[inline(always)]
    fn mask_from_bits(bits: u32) -> M8 {
        let lanes = unsafe { _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128) };
        let bits = unsafe { _mm256_set1_epi32(bits as i32) };
        // AVX (without AVX2) has no integer compare on 256 bits: the lanes'
        // bits, as floats, are nonzero exactly where the bit is set.
        let masked = unsafe { _mm256_and_ps(_mm256_castsi256_ps(lanes), _mm256_castsi256_ps(bits)) };
        M8(unsafe { _mm256_cmp_ps::<_CMP_NEQ_OQ>(masked, _mm256_setzero_ps()) })
    }
    #[inline(always)]
    fn mask_bits(mask: M8) -> u32 {
        unsafe { _mm256_movemask_ps(mask.0) as u32 }
    }
}
