//! Elementary functions for the hot paths, inlined where baseline x86-64
//! would call out of line: it has no rounding instruction (SSE4.1), so
//! `f32::floor` is a call into compiler-builtins, and the arctangent and
//! arccosine are calls into libm. Environment-map and texture look-ups
//! make these calls once or several times per path vertex.
//!
//! The polynomials are Cephes' single-precision ones (Moshier, "Methods
//! and Programs for Mathematical Functions", 1989: `atanf.c`, `asinf.c`),
//! as SIMD libraries use them (Dr.Jit, SLEEF's low-precision variants):
//! within a few units in the last place, which the tests check against
//! the standard library over the whole domain.

use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// ⌊x⌋ for every f32, computed by truncation: exact (−0 gives +0, NaN
/// gives NaN, and numbers of magnitude 2²³ or more, which are integers,
/// themselves).
#[inline(always)]
pub fn floor(x: f32) -> f32 {
    // `x.abs() < 2²³` is false for NaN too.
    if x.abs() < 8_388_608.0 {
        let t = (x as i32) as f32;
        // Truncation rounds negative non-integers up: one less then.
        t - f32::from(t > x)
    } else {
        x
    }
}

/// The arctangent of x, within a few units in the last place (Cephes'
/// `atanf`: the argument reduced to |x| ≤ tan(π/8), then an odd
/// polynomial of degree 9).
#[inline(always)]
pub fn atan(x: f32) -> f32 {
    let a = x.abs();
    // tan(3π/8) and tan(π/8).
    let (offset, r) = if a > 2.414_213_6 {
        (FRAC_PI_2, -1.0 / a)
    } else if a > 0.414_213_57 {
        (FRAC_PI_4, (a - 1.0) / (a + 1.0))
    } else {
        (0.0, a)
    };
    let z = r * r;
    let p = (((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_295e-1) * z * r + r;
    (offset + p).copysign(x)
}

/// The angle of the point (x, y) from the +x axis, in [−π, π], as
/// `f32::atan2` (signs of zeros included), within a few units in the
/// last place.
#[inline(always)]
pub fn atan2(y: f32, x: f32) -> f32 {
    if x == 0.0 {
        // ±π/2 off the axis; at the origin, the quadrant of the zeros.
        return if y == 0.0 {
            if x.is_sign_negative() { PI.copysign(y) } else { y }
        } else {
            FRAC_PI_2.copysign(y)
        };
    }
    if x.is_infinite() || y.is_infinite() || x.is_nan() || y.is_nan() {
        return y.atan2(x);
    }
    // Divide the smaller by the larger: the quotient stays finite and
    // |quotient| ≤ 1 keeps the reduction short.
    let base = if x.abs() >= y.abs() {
        atan(y / x)
    } else {
        FRAC_PI_2.copysign(y) - atan(x / y)
    };
    if x < 0.0 {
        // The left half-plane: turn by π toward y's side.
        if x.abs() >= y.abs() {
            base + PI.copysign(y)
        } else {
            base
        }
    } else {
        base
    }
}

/// The arcsine of x ∈ [−1, 1] (NaN outside), within a few units in the
/// last place (Cephes' `asinf`: an odd polynomial near 0, and
/// asin(x) = π/2 − 2·asin(√((1 − x)/2)) beyond |x| = 1/2).
#[inline(always)]
pub fn asin(x: f32) -> f32 {
    let a = x.abs();
    let (z, r) = if a > 0.5 {
        let z = 0.5 * (1.0 - a);
        (z, z.sqrt())
    } else {
        (a * a, a)
    };
    let p =
        ((((4.216_32e-2 * z + 2.418_131e-2) * z + 4.547_002_6e-2) * z + 7.495_300_3e-2) * z + 1.666_675_2e-1) * z * r
            + r;
    let y = if a > 0.5 { FRAC_PI_2 - 2.0 * p } else { p };
    // NaN stays NaN through copysign; |x| > 1 takes the square root of
    // a negative number above.
    y.copysign(x)
}

/// The arccosine of x ∈ [−1, 1] (NaN outside), within a few units in the
/// last place: π/2 − asin(x) near 0, and 2·asin(√((1 ∓ x)/2)) near ±1,
/// which keeps the small angles exact.
#[inline(always)]
pub fn acos(x: f32) -> f32 {
    if x > 0.5 {
        2.0 * asin((0.5 * (1.0 - x)).sqrt())
    } else if x < -0.5 {
        PI - 2.0 * asin((0.5 * (1.0 + x)).sqrt())
    } else {
        FRAC_PI_2 - asin(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two finite floats of
    /// the same sign (or zeros).
    fn ulps(a: f32, b: f32) -> u32 {
        if a == b {
            return 0;
        }
        assert_eq!(a.is_sign_negative(), b.is_sign_negative(), "{a} against {b}");
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs() as u32
    }

    /// Every n-th float in [lo, hi], both ends included.
    fn sweep(lo: f32, hi: f32, n: usize) -> impl Iterator<Item = f32> {
        (0..=n).map(move |i| lo + (hi - lo) * (i as f32 / n as f32))
    }

    #[test]
    fn floor_is_exact_everywhere() {
        let specials = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.0e-30,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            1.0e20,
            -1.0e20,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MIN_POSITIVE,
        ];
        for x in specials.into_iter().chain(sweep(-1000.0, 1000.0, 200_001)) {
            // −0.0 → +0.0 is the one documented difference (equal as floats).
            assert_eq!(floor(x), x.floor(), "floor({x})");
        }
        assert!(floor(f32::NAN).is_nan());
        // Every float near integers: the neighbours on both sides.
        for k in -300..300 {
            let k = k as f32 * 7.25;
            for x in [k.next_down(), k, k.next_up()] {
                assert_eq!(floor(x), x.floor(), "floor({x})");
            }
        }
    }

    #[test]
    fn atan2_matches_the_standard_library() {
        let mut worst = 0;
        for i in 0..=720 {
            let angle = -PI + 2.0 * PI * i as f32 / 720.0;
            for r in [1.0e-30, 1.0e-3, 1.0, 7.0, 1.0e30] {
                let (y, x) = (r * angle.sin(), r * angle.cos());
                let (ours, std) = (atan2(y, x), y.atan2(x));
                // Near ±π the sign flips with the sign of y: compare
                // magnitudes where y is a zero of either sign.
                worst = worst.max(ulps(ours, std));
            }
        }
        assert!(worst <= 4, "atan2 is {worst} ulps away");
        for (y, x) in [
            (0.0, 0.0),
            (-0.0, 0.0),
            (0.0, -0.0),
            (-0.0, -0.0),
            (1.0, 0.0),
            (-1.0, -0.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (f32::INFINITY, 1.0),
            (1.0, f32::NEG_INFINITY),
        ] {
            assert_eq!(atan2(y, x).to_bits(), y.atan2(x).to_bits(), "atan2({y}, {x})");
        }
        assert!(atan2(f32::NAN, 1.0).is_nan() && atan2(1.0, f32::NAN).is_nan());
    }

    #[test]
    fn acos_and_asin_match_the_standard_library() {
        let (mut worst_acos, mut worst_asin) = (0, 0);
        for x in sweep(-1.0, 1.0, 400_000).chain([1.0f32.next_down(), (-1.0f32).next_up(), 1.0e-20, -1.0e-20]) {
            worst_acos = worst_acos.max(ulps(acos(x), x.acos()));
            worst_asin = worst_asin.max(ulps(asin(x), x.asin()));
        }
        assert!(worst_acos <= 4, "acos is {worst_acos} ulps away");
        assert!(worst_asin <= 4, "asin is {worst_asin} ulps away");
        for x in [1.5, -1.5, f32::NAN] {
            assert!(acos(x).is_nan() && asin(x).is_nan(), "{x}");
        }
    }
}
