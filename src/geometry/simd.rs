//! `f32` numbers of one path or of several paths at once, for code written
//! once and run on one lane (`f32`) or on eight in a vector register
//! (`lanes::F8`, on x86-64 with AVX), as Mitsuba 3 compiles one integrator
//! for its scalar and vector variants. Both instances do the same
//! operations in the same order, so a lane computes the bits the one-lane
//! code computes.
//!
//! Values every lane holds in its own register slot are [`Floats`] and
//! [`Vec3s`]; values only per-lane (scalar) code reads are kept in
//! [`Floats::Each`] arrays of plain values.

use glam::Vec3;

/// `f32` lanes: one (`f32`) or eight (`lanes::F8`).
pub trait Floats:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
{
    /// Lanes per value.
    const N: usize;
    /// One plain value per lane.
    type Each<T: Copy>: Copy + AsRef<[T]> + AsMut<[T]>;
    /// Per-lane booleans.
    type Mask: Copy;

    /// Plain values made lane by lane.
    fn each<T: Copy>(f: impl FnMut(usize) -> T) -> Self::Each<T>;
    /// `value` in every lane, as plain values (an array's repeat, which
    /// compiles to a few wide stores where `each` may loop).
    fn repeat<T: Copy>(value: T) -> Self::Each<T>;
    /// `x` in every lane.
    fn splat(x: f32) -> Self;
    /// Lanes from plain values.
    fn gather(values: &Self::Each<f32>) -> Self;
    /// Lane `i`.
    fn lane(self, i: usize) -> f32;
    /// The square root (correctly rounded in every instance).
    fn sqrt(self) -> Self;
    /// `if self < other { self } else { other }`.
    fn min(self, other: Self) -> Self;
    /// `if self > other { self } else { other }`.
    fn max(self, other: Self) -> Self;
    /// `self >= other` (false for NaN).
    fn ge(self, other: Self) -> Self::Mask;
    /// `self > other` (false for NaN).
    fn gt(self, other: Self) -> Self::Mask;
    /// The magnitude.
    fn abs(self) -> Self;
    /// 1 with this value's sign bit (`1.0f32.copysign(self)`).
    fn sign_one(self) -> Self;
    /// Every lane, as plain values.
    fn each_lane(self) -> Self::Each<f32>;
    /// `if mask { a } else { b }`.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
    /// A mask from bits (lane `i` true where bit `i` is set).
    fn mask_from_bits(bits: u32) -> Self::Mask;
    /// Bit `i` set where lane `i` is true.
    fn mask_bits(mask: Self::Mask) -> u32;
}

impl Floats for f32 {
    const N: usize = 1;
    type Each<T: Copy> = [T; 1];
    type Mask = bool;

    #[inline(always)]
    fn each<T: Copy>(mut f: impl FnMut(usize) -> T) -> [T; 1] {
        [f(0)]
    }
    #[inline(always)]
    fn repeat<T: Copy>(value: T) -> [T; 1] {
        [value]
    }
    #[inline(always)]
    fn splat(x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn gather(values: &[f32; 1]) -> f32 {
        values[0]
    }
    #[inline(always)]
    fn lane(self, _i: usize) -> f32 {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> f32 {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn min(self, other: f32) -> f32 {
        if self < other { self } else { other }
    }
    #[inline(always)]
    fn max(self, other: f32) -> f32 {
        if self > other { self } else { other }
    }
    #[inline(always)]
    fn ge(self, other: f32) -> bool {
        self >= other
    }
    #[inline(always)]
    fn gt(self, other: f32) -> bool {
        self > other
    }
    #[inline(always)]
    fn abs(self) -> f32 {
        f32::abs(self)
    }
    #[inline(always)]
    fn sign_one(self) -> f32 {
        1.0f32.copysign(self)
    }
    #[inline(always)]
    fn each_lane(self) -> [f32; 1] {
        [self]
    }
    #[inline(always)]
    fn select(mask: bool, a: f32, b: f32) -> f32 {
        if mask { a } else { b }
    }
    #[inline(always)]
    fn mask_from_bits(bits: u32) -> bool {
        bits & 1 != 0
    }
    #[inline(always)]
    fn mask_bits(mask: bool) -> u32 {
        mask as u32
    }
}

/// The lanes whose bits are set in `bits`, in order.
#[inline(always)]
pub fn lanes(mut bits: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (bits != 0).then(|| {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            i
        })
    })
}

/// Three-vectors (directions, points, RGB colours) in lanes.
#[derive(Clone, Copy, Debug)]
pub struct Vec3s<F> {
    pub x: F,
    pub y: F,
    pub z: F,
}

impl<F: Floats> Vec3s<F> {
    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: Vec3) -> Self {
        Vec3s {
            x: F::splat(v.x),
            y: F::splat(v.y),
            z: F::splat(v.z),
        }
    }

    /// Lanes from plain vectors.
    #[inline(always)]
    pub fn gather(values: &F::Each<Vec3>) -> Self {
        let v = values.as_ref();
        Vec3s {
            x: F::gather(&F::each(|i| v[i].x)),
            y: F::gather(&F::each(|i| v[i].y)),
            z: F::gather(&F::each(|i| v[i].z)),
        }
    }

    /// Lane `i`.
    #[inline(always)]
    pub fn lane(self, i: usize) -> Vec3 {
        Vec3::new(self.x.lane(i), self.y.lane(i), self.z.lane(i))
    }

    /// The dot product, summed as glam sums it: (x + y) + z.
    #[inline(always)]
    pub fn dot(self, o: Self) -> F {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Each component's magnitude.
    #[inline(always)]
    pub fn abs(self) -> Self {
        Vec3s {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    /// The largest component (glam's `max_element`: `max(max(x, y), z)`).
    #[inline(always)]
    pub fn max_element(self) -> F {
        self.x.max(self.y).max(self.z)
    }

    /// The largest magnitude of a component: [`Vec3s::max_element`]
    /// where no component is negative (a throughput that a wavelength's
    /// weight made negative in a channel still counts by its size).
    #[inline(always)]
    pub fn max_magnitude(self) -> F {
        let min = self.x.min(self.y).min(self.z);
        self.max_element().max(F::splat(0.0) - min)
    }

    /// Lane-wise `if mask { a } else { b }`.
    #[inline(always)]
    pub fn select(mask: F::Mask, a: Self, b: Self) -> Self {
        Vec3s {
            x: F::select(mask, a.x, b.x),
            y: F::select(mask, a.y, b.y),
            z: F::select(mask, a.z, b.z),
        }
    }

    /// Each component times `s`.
    #[inline(always)]
    pub fn scale(self, s: F) -> Self {
        Vec3s {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }

    /// Each component over `s`.
    #[inline(always)]
    pub fn over(self, s: F) -> Self {
        Vec3s {
            x: self.x / s,
            y: self.y / s,
            z: self.z / s,
        }
    }
}

impl<F: Floats> std::ops::Add for Vec3s<F> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Vec3s {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }
}

impl<F: Floats> std::ops::Sub for Vec3s<F> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Vec3s {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }
}

impl<F: Floats> std::ops::Mul for Vec3s<F> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Vec3s {
            x: self.x * o.x,
            y: self.y * o.y,
            z: self.z * o.z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The one-lane and eight-lane instances give each lane the same bits.
    #[cfg(target_arch = "x86_64")]
    #[test]
    #[allow(unsafe_code)]
    fn eight_lanes_compute_what_one_lane_computes() {
        use super::super::lanes::{F8, avx_available};
        if !avx_available() {
            return;
        }
        fn work<F: Floats>(a: Vec3s<F>, b: Vec3s<F>, u: F) -> (Vec3s<F>, u32) {
            let q = (a * b).max_element().min(F::splat(0.95));
            let keep = F::mask_bits(u.ge(q)) ^ ((1 << F::N) - 1);
            let c = Vec3s::select(F::mask_from_bits(keep), (a + b).over(q), a.scale(u.sqrt()));
            (c, keep)
        }
        #[target_feature(enable = "avx")]
        fn eight(a: &[Vec3; 8], b: &[Vec3; 8], u: &[f32; 8]) -> ([Vec3; 8], u32) {
            let (c, keep) = work::<F8>(Vec3s::gather(a), Vec3s::gather(b), F8::gather(u));
            (std::array::from_fn(|i| c.lane(i)), keep)
        }
        let a: [Vec3; 8] = std::array::from_fn(|i| Vec3::new(i as f32 * 0.37, 1.0 / (i as f32 + 0.5), -0.25));
        let b: [Vec3; 8] = std::array::from_fn(|i| Vec3::new(0.3, i as f32 * 0.11, f32::NAN.min(i as f32)));
        let u: [f32; 8] = std::array::from_fn(|i| (i as f32 * 0.13) % 1.0);
        // SAFETY: the processor has AVX (checked above).
        let (wide, bits) = unsafe { eight(&a, &b, &u) };
        for i in 0..8 {
            let (one, keep) = work::<f32>(Vec3s::gather(&[a[i]]), Vec3s::gather(&[b[i]]), u[i]);
            assert_eq!(
                one.lane(0).to_array().map(f32::to_bits),
                wide[i].to_array().map(f32::to_bits),
                "lane {i}"
            );
            assert_eq!(keep, (bits >> i) & 1, "lane {i}");
        }
    }
}
