//! Perlin's gradient noise (Perlin 2002, "Improving Noise") and the sums of
//! its octaves that pbrt-v4's procedural textures are made of (pbrt-v4
//! `util/noise.cpp`; Physically Based Rendering, 4th ed., §10.6).
//!
//! pbrt-v4 drops the octaves finer than a pixel's footprint, which it knows
//! from ray differentials. trazo has none, so it sums every octave: the
//! finest ones are what supersampling averages away (for [`turbulence`],
//! pbrt-v4 replaces each dropped octave by its mean of 0.2, so the averages
//! agree too).

use glam::Vec3;

/// Perlin's permutation of 0–255, the table pbrt-v4 uses.
const PERMUTATION: [u8; 256] = [
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69, 142, 8, 99, 37, 240,
    21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219, 203, 117, 35, 11, 32, 57, 177, 33, 88,
    237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175, 74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83,
    111, 229, 122, 60, 211, 133, 230, 220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216,
    80, 73, 209, 76, 132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173, 186,
    3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206, 59, 227, 47, 16, 58, 17,
    182, 189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43, 172, 9, 129,
    22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232, 178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238,
    210, 144, 12, 191, 179, 162, 241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184,
    84, 204, 176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141, 128, 195,
    78, 66, 215, 61, 156, 180,
];

#[inline]
fn perm(i: i32) -> i32 {
    PERMUTATION[(i & 255) as usize] as i32
}

/// The gradient at lattice point (x, y, z) dotted with the offset
/// (dx, dy, dz) from it: one of the 12 edge directions of a cube, picked by
/// the hashed lattice point.
#[inline]
fn gradient(x: i32, y: i32, z: i32, dx: f32, dy: f32, dz: f32) -> f32 {
    let h = perm(perm(perm(x) + y) + z) & 15;
    let u = if h < 8 || h == 12 || h == 13 { dx } else { dy };
    let v = if h < 4 || h == 12 || h == 13 { dy } else { dz };
    (if h & 1 != 0 { -u } else { u }) + (if h & 2 != 0 { -v } else { v })
}

/// Perlin's quintic fade, 6t⁵ − 15t⁴ + 10t³: zero first and second
/// derivatives at the lattice.
#[inline]
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp(t: f32, a: f32, b: f32) -> f32 {
    (1.0 - t) * a + t * b
}

/// Gradient noise at `p`: zero on the integer lattice, within about ±1,
/// mean zero.
pub fn noise(p: Vec3) -> f32 {
    // Coordinates are wrapped (as pbrt-v4 wraps them by 2³⁰) so that the
    // cell index fits an integer; a non-finite one reads as 0.
    let wrap = |x: f32| if x.is_finite() { x % (1u32 << 30) as f32 } else { 0.0 };
    let (x, y, z) = (wrap(p.x), wrap(p.y), wrap(p.z));
    let (fx, fy, fz) = (crate::math::floor(x), crate::math::floor(y), crate::math::floor(z));
    let (dx, dy, dz) = (x - fx, y - fy, z - fz);
    let (ix, iy, iz) = (fx as i32 & 255, fy as i32 & 255, fz as i32 & 255);
    let w000 = gradient(ix, iy, iz, dx, dy, dz);
    let w100 = gradient(ix + 1, iy, iz, dx - 1.0, dy, dz);
    let w010 = gradient(ix, iy + 1, iz, dx, dy - 1.0, dz);
    let w110 = gradient(ix + 1, iy + 1, iz, dx - 1.0, dy - 1.0, dz);
    let w001 = gradient(ix, iy, iz + 1, dx, dy, dz - 1.0);
    let w101 = gradient(ix + 1, iy, iz + 1, dx - 1.0, dy, dz - 1.0);
    let w011 = gradient(ix, iy + 1, iz + 1, dx, dy - 1.0, dz - 1.0);
    let w111 = gradient(ix + 1, iy + 1, iz + 1, dx - 1.0, dy - 1.0, dz - 1.0);
    let (wx, wy, wz) = (fade(dx), fade(dy), fade(dz));
    let y0 = lerp(wy, lerp(wx, w000, w100), lerp(wx, w010, w110));
    let y1 = lerp(wy, lerp(wx, w001, w101), lerp(wx, w011, w111));
    lerp(wz, y0, y1)
}

/// The gradient of [`noise`] at `p` by forward differences of 0.01
/// (pbrt-v4's `DNoise`).
pub fn dnoise(p: Vec3) -> Vec3 {
    const DELTA: f32 = 0.01;
    let n = noise(p);
    Vec3::new(
        noise(p + Vec3::X * DELTA),
        noise(p + Vec3::Y * DELTA),
        noise(p + Vec3::Z * DELTA),
    ) / DELTA
        - Vec3::splat(n / DELTA)
}

/// Noise at (x, y) in the plane z = ½ (pbrt-v4's two-argument `Noise`,
/// which the polka dots read).
pub fn noise_2d(x: f32, y: f32) -> f32 {
    noise(Vec3::new(x, y, 0.5))
}

/// Fractional Brownian motion: Σ ωⁱ·noise(1.99ⁱ·p) over `octaves` octaves.
pub fn fbm(p: Vec3, omega: f32, octaves: u32) -> f32 {
    let (mut sum, mut lambda, mut o) = (0.0, 1.0, 1.0);
    for _ in 0..octaves {
        sum += o * noise(lambda * p);
        lambda *= 1.99;
        o *= omega;
    }
    sum
}

/// Turbulence: [`fbm`] of |noise|, plus pbrt-v4's mean of 0.2 for the
/// first octave beyond the last (what it adds once every octave is summed).
pub fn turbulence(p: Vec3, omega: f32, octaves: u32) -> f32 {
    let (mut sum, mut lambda, mut o) = (0.0, 1.0, 1.0);
    for _ in 0..octaves {
        sum += o * noise(lambda * p).abs();
        lambda *= 1.99;
        o *= omega;
    }
    sum + o * 0.2
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_a_permutation() {
        let mut seen = [false; 256];
        for &v in &PERMUTATION {
            assert!(!seen[v as usize], "{v} twice");
            seen[v as usize] = true;
        }
    }

    #[test]
    fn noise_vanishes_on_the_lattice_and_is_continuous_across_cells() {
        for (x, y, z) in [(0, 0, 0), (3, -7, 12), (255, 256, -1), (1000, 2, 3)] {
            assert_eq!(noise(Vec3::new(x as f32, y as f32, z as f32)), 0.0);
        }
        // Across a cell face the two cells' interpolants meet.
        for k in 0..50 {
            let p = Vec3::new(2.0, 0.37 + 0.013 * k as f32, -1.61 + 0.02 * k as f32);
            let e = Vec3::X * 1e-4;
            assert!((noise(p - e) - noise(p + e)).abs() < 1e-3, "{p}");
        }
    }

    #[test]
    fn noise_is_bounded_with_mean_near_zero() {
        // 20³ points spread over many cells (a lattice of irrational step).
        let (mut sum, mut n) = (0.0f64, 0);
        for i in 0..20 {
            for j in 0..20 {
                for k in 0..20 {
                    let p = Vec3::new(i as f32 * 1.618, j as f32 * 2.414, k as f32 * 0.732) + 0.25;
                    let v = noise(p);
                    assert!(v.abs() <= 1.1, "{p}: {v}");
                    sum += v as f64;
                    n += 1;
                }
            }
        }
        assert!((sum / n as f64).abs() < 0.03, "mean {}", sum / n as f64);
    }

    #[test]
    fn octave_sums_follow_their_definitions() {
        let p = Vec3::new(0.3, 1.7, -2.2);
        assert_eq!(fbm(p, 0.5, 1), noise(p));
        let two = noise(p) + 0.5 * noise(1.99 * p);
        assert!((fbm(p, 0.5, 2) - two).abs() < 1e-6);
        let t = noise(p).abs() + 0.5 * noise(1.99 * p).abs() + 0.25 * 0.2;
        assert!((turbulence(p, 0.5, 2) - t).abs() < 1e-6);
        assert_eq!(fbm(p, 0.5, 0), 0.0);
        assert!(noise(Vec3::new(f32::NAN, f32::INFINITY, 1.5)).is_finite());
    }
}
