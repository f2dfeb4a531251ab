//! Numbers of one lane or several, for geometry written once.

/// Real numbers of one lane or several, for geometry written once and run
/// on one value (`f32`) or on eight in a vector register (`lanes::F8`, on x86-64 with AVX): the
/// sphere test of `shape::sphere_distance`
/// is one function for the one-sphere test and the sphere blocks, so both
/// compute the same bits. `min` and `max` are SSE's (`if a < b { a } else
/// { b }`), for both.
pub trait Real:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
{
    /// Per-lane booleans.
    type Mask: Copy + std::ops::BitAnd<Output = Self::Mask>;
    /// `x` in every lane (the receiver only says which type).
    fn like(self, x: f32) -> Self;
    /// Square root.
    fn sqrt(self) -> Self;
    /// The magnitude of `self` with the sign of `sign`.
    fn copysign(self, sign: Self) -> Self;
    /// `if self < other { self } else { other }`.
    fn min(self, other: Self) -> Self;
    /// `if self > other { self } else { other }`.
    fn max(self, other: Self) -> Self;
    /// `self == other` (false for NaN).
    fn eq(self, other: Self) -> Self::Mask;
    /// `self > other` (false for NaN).
    fn gt(self, other: Self) -> Self::Mask;
    /// `self <= other` (false for NaN).
    fn le(self, other: Self) -> Self::Mask;
    /// `if mask { a } else { b }`.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
}

impl Real for f32 {
    type Mask = bool;
    #[inline(always)]
    fn like(self, x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn sqrt(self) -> f32 {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn copysign(self, sign: f32) -> f32 {
        f32::copysign(self, sign)
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
    fn eq(self, other: f32) -> bool {
        self == other
    }
    #[inline(always)]
    fn gt(self, other: f32) -> bool {
        self > other
    }
    #[inline(always)]
    fn le(self, other: f32) -> bool {
        self <= other
    }
    #[inline(always)]
    fn select(mask: bool, a: f32, b: f32) -> f32 {
        if mask { a } else { b }
    }
}
