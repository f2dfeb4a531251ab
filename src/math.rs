//! Elementary functions for the hot paths, inlined where baseline x86-64
//! would call out of line: it has no rounding instruction (SSE4.1), so
//! `f32::floor` is a call into compiler-builtins, and the arctangent a
//! call into libm. Environment-map and texture look-ups make these calls
//! once or several times per path vertex.
//!
//! The polynomial is Cephes' single-precision one (Moshier, "Methods and
//! Programs for Mathematical Functions", 1989: `atanf.c`),
//! as SIMD libraries use it (Dr.Jit, SLEEF's low-precision variants):
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

/// Cephes' `atanf` polynomial: atan(r) for |r| ≤ tan(π/8), odd, of
/// degree 9.
#[inline(always)]
fn atan_reduced(r: f32) -> f32 {
    let z = r * r;
    (((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_295e-1) * z * r + r
}

/// `if condition { a } else { b }` on floats as a mask rather than a
/// branch where the compiler keeps it so: the conditions below depend on
/// the octant of a direction, which is as good as random along a path.
#[inline(always)]
fn select(condition: bool, a: f32, b: f32) -> f32 {
    let mask = (condition as u32).wrapping_neg();
    f32::from_bits((a.to_bits() & mask) | (b.to_bits() & !mask))
}

/// The angle of the point (x, y) from the +x axis, in [−π, π], as
/// `f32::atan2` (signs of zeros included), within a few units in the
/// last place.
///
/// The smaller magnitude over the larger is reduced to |r| ≤ tan(π/8) as
/// Cephes' `atanf` reduces its argument, atan(t) = π/4 + atan((t − 1)/(t + 1)),
/// with the two quotients written as one, (lo − k·hi)/(hi + k·lo) for
/// k ∈ {0, 1}; the octant is then restored by selections.
#[inline(always)]
pub fn atan2(y: f32, x: f32) -> f32 {
    if !(x.is_finite() && y.is_finite()) {
        return y.atan2(x);
    }
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    // tan(π/8).
    let k = select(lo > 0.414_213_57 * hi, 1.0, 0.0);
    let quotient = (lo - k * hi) / (hi + k * lo);
    // At the origin hi = 0: the angle of the zeros' quadrant, from r = 0.
    let r = select(hi > 0.0, quotient, 0.0);
    // atan(lo/hi) ∈ [0, π/4], then the angle of (ax, ay) ∈ [0, π/2].
    let first_octant = k * FRAC_PI_4 + atan_reduced(r);
    let quadrant = select(ay > ax, FRAC_PI_2 - first_octant, first_octant);
    // The left half-plane (−0 included) mirrors about the y axis.
    select(x.is_sign_negative(), PI - quadrant, quadrant).copysign(y)
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
        for i in 0..=72_000 {
            let angle = -PI + 2.0 * PI * i as f32 / 72_000.0;
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
}
