//! Warps: maps from uniform samples in [0,1)ⁿ to distributions over
//! geometric domains, each with its probability density.
//!
//! Conventions: hemispheres are around +z (the local shading frame's
//! normal); solid-angle densities are per steradian, area densities per unit
//! area. Derivations follow pbrt-v4, chapter A.5.

use crate::geometry::simd::{Floats, Vec3s};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_4, PI};

/// 1/(2π).
pub const INV_2PI: f32 = 0.5 * FRAC_1_PI;
/// 1/(4π).
pub const INV_4PI: f32 = 0.25 * FRAC_1_PI;

/// Uniform point on the unit disk by Shirley and Chiu's concentric map,
/// which keeps strata compact (pdf 1/π).
#[inline]
pub fn sample_disk_concentric(u: Vec2) -> Vec2 {
    let (x, y) = sample_disk_concentric_lanes(u.x, u.y);
    Vec2::new(x, y)
}

/// [`sample_disk_concentric`] over lanes.
#[inline(always)]
pub fn sample_disk_concentric_lanes<F: Floats>(ux: F, uy: F) -> (F, F) {
    let (zero, one, two) = (F::splat(0.0), F::splat(1.0), F::splat(2.0));
    let (ox, oy) = (two * ux - one, two * uy - one);
    // θ = φ or π/2 − φ with |φ| ≤ π/4, so cos θ and sin θ are cos φ and
    // sin φ, possibly swapped: short polynomials instead of a libm call.
    // Which of the two is a coin toss per sample, so it is chosen by
    // selects, not a branch the processor would mispredict half the time.
    let x_wider = ox.abs().gt(oy.abs());
    let (r, other) = (F::select(x_wider, ox, oy), F::select(x_wider, oy, ox));
    let (sin, cos) = sin_cos_quarter_pi(F::splat(FRAC_PI_4) * (other / r));
    let (a, b) = (F::select(x_wider, cos, sin), F::select(x_wider, sin, cos));
    // The centre (where r is 0 and the angle 0/0) maps to itself.
    let centre = F::mask_from_bits(!F::mask_bits(ox.abs().gt(zero)) & !F::mask_bits(oy.abs().gt(zero)));
    (F::select(centre, zero, r * a), F::select(centre, zero, r * b))
}

/// (sin x, cos x) for |x| ≤ π/4 by their Taylor series to x⁹ and x⁸,
/// whose remainders there are below 2·10⁻⁹ and 3·10⁻⁸: within an f32
/// rounding or two of the library functions, and much cheaper.
#[inline(always)]
pub(crate) fn sin_cos_quarter_pi<F: Floats>(x: F) -> (F, F) {
    let c = F::splat;
    let x2 = x * x;
    let sin =
        x * (c(1.0) + x2 * (c(-1.0 / 6.0) + x2 * (c(1.0 / 120.0) + x2 * (c(-1.0 / 5040.0) + x2 * c(1.0 / 362_880.0)))));
    let cos = c(1.0) + x2 * (c(-0.5) + x2 * (c(1.0 / 24.0) + x2 * (c(-1.0 / 720.0) + x2 * c(1.0 / 40320.0))));
    (sin, cos)
}

/// Uniform direction on the hemisphere z ≥ 0 (pdf 1/(2π)).
#[inline]
pub fn sample_hemisphere_uniform(u: Vec2) -> Vec3 {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`sample_hemisphere_uniform`].
#[inline]
pub fn pdf_hemisphere_uniform() -> f32 {
    INV_2PI
}

/// Cosine-weighted direction on the hemisphere z ≥ 0 by Malley's method
/// (pdf cosθ/π).
#[inline]
pub fn sample_hemisphere_cosine(u: Vec2) -> Vec3 {
    sample_hemisphere_cosine_lanes(u.x, u.y).lane(0)
}

/// [`sample_hemisphere_cosine`] over lanes.
#[inline(always)]
pub fn sample_hemisphere_cosine_lanes<F: Floats>(ux: F, uy: F) -> Vec3s<F> {
    let (x, y) = sample_disk_concentric_lanes(ux, uy);
    let z = (F::splat(1.0) - (x * x + y * y)).max(F::splat(0.0)).sqrt();
    Vec3s { x, y, z }
}

/// Density of [`sample_hemisphere_cosine`] for a direction with cosθ = `cos_theta`.
#[inline]
pub fn pdf_hemisphere_cosine<F: Floats>(cos_theta: F) -> F {
    cos_theta.max(F::splat(0.0)) * F::splat(FRAC_1_PI)
}

/// Uniform direction on the unit sphere (pdf 1/(4π)).
#[inline]
pub fn sample_sphere_uniform(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`sample_sphere_uniform`].
#[inline]
pub fn pdf_sphere_uniform() -> f32 {
    INV_4PI
}

/// Uniform direction in the cone around +z with cos θ ≥ `cos_max`
/// (pdf 1/(2π(1 − cos_max))).
#[inline]
pub fn sample_cone_uniform(u: Vec2, cos_max: f32) -> Vec3 {
    let z = 1.0 - u.x * (1.0 - cos_max);
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`sample_cone_uniform`].
#[inline]
pub fn pdf_cone_uniform(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Uniform barycentric coordinates (b0, b1, b2) on a triangle
/// (Heitz 2019, "A Low-Distortion Map Between Triangle and Square").
#[inline]
pub fn sample_triangle_uniform(u: Vec2) -> [f32; 3] {
    let (b0, b1) = if u.x < u.y {
        let b0 = u.x / 2.0;
        (b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        (u.x - b1, b1)
    };
    [b0, b1, 1.0 - b0 - b1]
}

/// The point of the unit square that Clarberg's equal-area octahedral
/// mapping (pbrt-v4 `EqualAreaSphereToSquare`, §3.8.3) takes unit direction
/// `d` to: +z at the centre, −z at the corners, the four quadrants of the
/// square the signs of x and y.
pub fn equal_area_sphere_to_square(d: Vec3) -> Vec2 {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let (a, b) = (x.max(y), x.min(y));
    let b = if a == 0.0 { 0.0 } else { b / a };
    // φ/(π/2) within the octant.
    let mut phi = b.atan() * (2.0 / PI);
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        (u, v) = (1.0 - v, 1.0 - u);
    }
    Vec2::new(0.5 * (u.copysign(d.x) + 1.0), 0.5 * (v.copysign(d.y) + 1.0))
}

/// The unit direction at point `p` of the unit square: the inverse of
/// [`equal_area_sphere_to_square`] (pbrt-v4 `EqualAreaSquareToSphere`).
pub fn equal_area_square_to_sphere(p: Vec2) -> Vec3 {
    let (u, v) = (2.0 * p.x - 1.0, 2.0 * p.y - 1.0);
    let (up, vp) = (u.abs(), v.abs());
    // Signed distance from the diagonal |u| + |v| = 1: its sign is z's.
    let signed = 1.0 - (up + vp);
    let r = 1.0 - signed.abs();
    let phi = if r == 0.0 { 1.0 } else { (vp - up) / r + 1.0 } * (PI / 4.0);
    let z = (1.0 - r * r).copysign(signed);
    let s = r * (2.0 - r * r).max(0.0).sqrt();
    Vec3::new(phi.cos().copysign(u) * s, phi.sin().copysign(v) * s, z)
}

/// An orthonormal basis around a unit vector (Duff et al. 2017, "Building an
/// Orthonormal Basis, Revisited"): returns (s, t) with s × t = n.
#[inline]
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let (s, t) = orthonormal_basis_lanes(Vec3s::<f32>::splat(n));
    (s.lane(0), t.lane(0))
}

/// [`orthonormal_basis`] over lanes.
#[inline(always)]
pub fn orthonormal_basis_lanes<F: Floats>(n: Vec3s<F>) -> (Vec3s<F>, Vec3s<F>) {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    let sign = n.z.sign_one();
    let a = F::splat(-1.0) / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3s {
            x: one + sign * n.x * n.x * a,
            y: sign * b,
            z: (zero - sign) * n.x,
        },
        Vec3s {
            x: b,
            y: sign + n.y * n.y * a,
            z: F::splat(-1.0) * n.y,
        },
    )
}

/// (sin 2πu, cos 2πu) over lanes for u in [0, 1): the quarter turn u
/// falls in, then the short polynomials of [`sin_cos_quarter_pi`] about
/// its middle, turned by an eighth and by the quarters.
#[inline(always)]
pub fn sin_cos_turn<F: Floats>(u: F) -> (F, F) {
    let c = F::splat;
    let (q1, q2, q3) = (u.ge(c(0.25)), u.ge(c(0.5)), u.ge(c(0.75)));
    let quarters = F::select(q1, c(1.0), c(0.0)) + F::select(q2, c(1.0), c(0.0)) + F::select(q3, c(1.0), c(0.0));
    // The angle less its quarters, about the quarter's middle: |x| ≤ π/4.
    let x = c(2.0 * PI) * (u - quarters * c(0.25)) - c(FRAC_PI_4);
    let (s, co) = sin_cos_quarter_pi(x);
    // sin and cos of π/4 + x.
    let half = c(std::f32::consts::FRAC_1_SQRT_2);
    let (sin, cos) = ((s + co) * half, (co - s) * half);
    // Turned by the quarters: (sin, cos) → (cos, −sin) → (−sin, −cos) → (−cos, sin).
    let (odd, upper) = (
        F::mask_from_bits(F::mask_bits(q1) & !F::mask_bits(q2) | F::mask_bits(q3)),
        q2,
    );
    let (s1, c1) = (F::select(odd, cos, sin), F::select(odd, c(0.0) - sin, cos));
    (F::select(upper, c(0.0) - s1, s1), F::select(upper, c(0.0) - c1, c1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// The polynomial sine and cosine of a turn agree with the library's
    /// within a few f32 roundings over the whole turn, quarter ends
    /// included.
    #[test]
    fn sine_and_cosine_of_a_turn_match_the_library() {
        let mut worst = 0.0f32;
        let ends = [
            0.0,
            0.25,
            0.5,
            0.75,
            0.125,
            0.375,
            0.625,
            0.875,
            1.0 - f32::EPSILON / 2.0,
        ];
        for u in (0..100_000).map(|k| k as f32 / 100_000.0).chain(ends) {
            let (s, c) = sin_cos_turn(u);
            let phi = 2.0 * std::f64::consts::PI * u as f64;
            worst = worst
                .max((s as f64 - phi.sin()).abs() as f32)
                .max((c as f64 - phi.cos()).abs() as f32);
        }
        assert!(worst < 4e-7, "{worst}");
    }

    fn uniform_2d(r: &mut Pcg32) -> Vec2 {
        Vec2::new(r.next_f32(), r.next_f32())
    }

    #[test]
    fn quarter_circle_sin_cos_match_the_library() {
        for i in -1000..=1000 {
            let x = FRAC_PI_4 * i as f32 / 1000.0;
            let (sin, cos) = sin_cos_quarter_pi(x);
            assert!((sin - x.sin()).abs() <= 2.5e-7, "sin {x}: {sin} vs {}", x.sin());
            assert!((cos - x.cos()).abs() <= 2.5e-7, "cos {x}: {cos} vs {}", x.cos());
        }
        // The concentric map agrees with the trigonometric formula.
        let mut r = Pcg32::new(5, 0);
        for _ in 0..10_000 {
            let u = uniform_2d(&mut r);
            let o = 2.0 * u - Vec2::ONE;
            let (radius, theta) = if o.x.abs() > o.y.abs() {
                (o.x, FRAC_PI_4 * (o.y / o.x))
            } else {
                (o.y, std::f32::consts::FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y))
            };
            let expect = radius * Vec2::new(theta.cos(), theta.sin());
            assert!((sample_disk_concentric(u) - expect).length() < 1e-6, "{u}");
        }
    }

    #[test]
    fn warps_land_in_their_domains() {
        let mut r = Pcg32::new(3, 0);
        for _ in 0..10_000 {
            let u = uniform_2d(&mut r);
            assert!(sample_disk_concentric(u).length() <= 1.0 + 1e-6);
            let h = sample_hemisphere_uniform(u);
            assert!(h.z >= 0.0 && (h.length() - 1.0).abs() < 1e-5);
            let c = sample_hemisphere_cosine(u);
            assert!(c.z >= 0.0 && (c.length() - 1.0).abs() < 1e-5);
            let s = sample_sphere_uniform(u);
            assert!((s.length() - 1.0).abs() < 1e-5);
            let k = sample_cone_uniform(u, 0.8);
            assert!(k.z >= 0.8 - 1e-6);
            let b = sample_triangle_uniform(u);
            assert!(b.iter().all(|&x| x >= -1e-6) && (b.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn basis_is_orthonormal() {
        let mut r = Pcg32::new(5, 0);
        for _ in 0..1000 {
            let n = sample_sphere_uniform(uniform_2d(&mut r));
            let (s, t) = orthonormal_basis(n);
            assert!((s.length() - 1.0).abs() < 1e-5 && (t.length() - 1.0).abs() < 1e-5);
            assert!(s.dot(t).abs() < 1e-5 && s.dot(n).abs() < 1e-5 && t.dot(n).abs() < 1e-5);
            assert!((s.cross(t) - n).length() < 1e-4);
        }
    }

    /// Chi-square test of a 2-D warp onto the disk against its uniform density,
    /// over a polar grid of equal-area cells.
    #[test]
    fn concentric_disk_is_uniform() {
        let (nr, nphi) = (8usize, 16usize);
        let mut counts = vec![0u32; nr * nphi];
        let mut r = Pcg32::new(11, 0);
        let n = 200_000;
        for _ in 0..n {
            let p = sample_disk_concentric(uniform_2d(&mut r));
            // Equal-area rings: r² is uniform.
            let ir = ((p.length_squared() * nr as f32) as usize).min(nr - 1);
            let phi = p.y.atan2(p.x).rem_euclid(2.0 * PI);
            let ip = ((phi / (2.0 * PI) * nphi as f32) as usize).min(nphi - 1);
            counts[ir * nphi + ip] += 1;
        }
        let e = n as f64 / (nr * nphi) as f64;
        let chi2: f64 = counts.iter().map(|&c| (c as f64 - e).powi(2) / e).sum();
        // 127 degrees of freedom: the 0.999 quantile is about 181.
        assert!(chi2 < 181.0, "chi2 = {chi2}");
    }
}
