//! The record of a ray–surface intersection and robust spawning of new rays
//! from it.

use super::ray::Ray;
use glam::{Vec2, Vec3};

/// Everything shading needs to know about the point a ray hit.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// World-space hit point.
    pub p: Vec3,
    /// Conservative per-axis bound on the rounding error in `p`.
    pub p_error: Vec3,
    /// Geometric normal (unit length), on the shape's outside (front) side.
    pub ng: Vec3,
    /// Shading normal (unit length): interpolated for meshes with vertex
    /// normals, otherwise equal to `ng`; always in `ng`'s hemisphere.
    pub ns: Vec3,
    /// Surface parameterisation, used by textures.
    pub uv: Vec2,
    /// A unit tangent along increasing `u`, perpendicular to `ns`.
    pub tangent: Vec3,
    /// The surface's derivatives along u and v (not normalised, not
    /// perpendicular to `ns`), which bump maps tilt.
    pub dpdu: Vec3,
    /// See `dpdu`.
    pub dpdv: Vec3,
    /// Index of the surface's material in the scene.
    pub material: u32,
    /// Index of the area light this surface is, if it emits.
    pub light: Option<u32>,
    /// The value of the mesh attribute its material reads (first three
    /// channels), 0 where there is none.
    pub attribute: Vec3,
    /// The time of the ray that found it, which rays leaving it keep.
    pub time: f32,
}

impl SurfaceHit {
    /// Whether `w` (pointing away from the surface) is on the front side.
    #[inline]
    pub fn is_front(&self, w: Vec3) -> bool {
        self.ng.dot(w) > 0.0
    }

    /// A ray leaving the surface in direction `dir`, its origin pushed past
    /// the rounding error of `p` so that it cannot re-hit this surface.
    #[inline]
    pub fn spawn_ray(&self, dir: Vec3) -> Ray {
        self.spawn_point().spawn_ray(dir)
    }

    /// A shadow ray from this surface toward `target`, ending just short of it.
    /// The direction is `target − origin`, so t ∈ (0, 1) spans the segment.
    #[inline]
    pub fn spawn_ray_to(&self, target: Vec3) -> Ray {
        self.spawn_point().spawn_ray_to(target)
    }

    /// What spawning rays from this hit needs of it.
    #[inline]
    pub fn spawn_point(&self) -> SpawnPoint {
        SpawnPoint {
            p: self.p,
            p_error: self.p_error,
            ng: self.ng,
            time: self.time,
        }
    }
}

/// A surface point from which rays leave: the point, the bound on its
/// rounding error, and the geometric normal.
#[derive(Clone, Copy, Debug, Default)]
pub struct SpawnPoint {
    /// World-space point.
    pub p: Vec3,
    /// Conservative per-axis bound on the rounding error in `p`.
    pub p_error: Vec3,
    /// Geometric normal (unit length).
    pub ng: Vec3,
    /// The time rays leaving it are traced at.
    pub time: f32,
}

impl SpawnPoint {
    /// See [`SurfaceHit::spawn_ray`].
    #[inline]
    pub fn spawn_ray(&self, dir: Vec3) -> Ray {
        Ray::new(offset_ray_origin(self.p, self.p_error, self.ng, dir), dir).at_time(self.time)
    }

    /// See [`SurfaceHit::spawn_ray_to`].
    #[inline]
    pub fn spawn_ray_to(&self, target: Vec3) -> Ray {
        let o = offset_ray_origin(self.p, self.p_error, self.ng, target - self.p);
        let d = target - o;
        Ray::with_interval(o, d, 0.0, SHADOW_EPSILON).at_time(self.time)
    }
}

/// The unit tangent along `dpdu` perpendicular to unit normal `n`
/// (Gram–Schmidt), or an arbitrary one where `dpdu` lies nearly along the
/// normal: rounding in the projection would leave that one visibly off
/// the perpendicular, and shading frames take the tangent as it is
/// (`Frame::from_orthonormal`).
#[inline]
pub fn unit_tangent(dpdu: Vec3, n: Vec3) -> Vec3 {
    let along = dpdu - n * n.dot(dpdu);
    let len2 = along.length_squared();
    if len2 > 1e-6 * dpdu.length_squared() {
        along * (1.0 / len2.sqrt())
    } else {
        crate::sampling::warp::orthonormal_basis(n).0
    }
}

/// Shadow rays toward a point end at `1 − SHADOW_EPSILON` of the way
/// (pbrt-v4 uses the same constant) so they do not hit the light itself.
pub const SHADOW_EPSILON: f32 = 1.0 - 1e-4;

/// Offsets `p` along the normal by the projection of its error box onto the
/// normal, to the side that `w` points to, then rounds away from `p`
/// (pbrt-v4, section 6.8.6). Rays spawned there cannot hit the surface they
/// left because of rounding.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let d = if w.dot(n) < 0.0 { -d } else { d };
    let offset = n * d;
    let po = p + offset;
    // Which way each coordinate moves is as good as random from ray to
    // ray, so the step is taken on the bits with masks instead of the
    // branches of next_float_up/down (which it equals, as a test checks).
    step_away_3(po, offset)
}

/// Each coordinate of `x` moved by one unit in the last place in the
/// direction of the sign of `o`'s (unchanged where `o` is zero or `x`
/// infinite), on the bits with masks and no branch. On x86-64 the three
/// are one SSE2 register: a ray is spawned at every bounce and toward
/// every light sample, where three scalar steps cost more (and the
/// compiler did not vectorise the loop below).
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[inline]
fn step_away_3(x: Vec3, o: Vec3) -> Vec3 {
    super::lanes::step_away_sse2(x, o)
}

/// `step_away_3` elsewhere.
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
#[inline]
fn step_away_3(x: Vec3, o: Vec3) -> Vec3 {
    step_away_3_portable(x, o)
}

/// `step_away_3` in portable code.
#[cfg(any(test, not(all(target_arch = "x86_64", target_feature = "sse2"))))]
#[inline]
fn step_away_3_portable(x: Vec3, o: Vec3) -> Vec3 {
    const SIGN: u32 = 0x8000_0000;
    let xb = [x.x.to_bits(), x.y.to_bits(), x.z.to_bits(), 0];
    let ob = [o.x.to_bits(), o.y.to_bits(), o.z.to_bits(), 0];
    let mut out = [0u32; 4];
    for i in 0..4 {
        let (xb, ob) = (xb[i], ob[i]);
        // All ones where a condition holds.
        let mask = |c: bool| 0u32.wrapping_sub(c as u32);
        // +1 where x and o have the same sign, −1 where they differ.
        let step = (((xb ^ ob) as i32 >> 31) | 1) as u32;
        let magnitude = xb & !SIGN;
        let zero = mask(magnitude == 0);
        let stepped = (xb.wrapping_add(step) & !zero) | (((ob & SIGN) | 1) & zero);
        let keep = mask((ob & !SIGN) == 0) | mask(magnitude == 0x7f80_0000);
        out[i] = (xb & keep) | (stepped & !keep);
    }
    Vec3::new(f32::from_bits(out[0]), f32::from_bits(out[1]), f32::from_bits(out[2]))
}

/// One coordinate of `step_away_3`, written with branches: the reference
/// its tests compare with.
#[cfg(test)]
fn step_away(x: f32, o: f32) -> f32 {
    let (xb, ob) = (x.to_bits(), o.to_bits());
    let magnitude = xb & 0x7fff_ffff;
    // Same sign: the magnitude grows by one ulp; otherwise it shrinks, and
    // from zero the result is the smallest subnormal of o's sign.
    let same_sign = (xb ^ ob) & 0x8000_0000 == 0;
    let stepped = if same_sign {
        xb.wrapping_add(1)
    } else {
        xb.wrapping_sub(1)
    };
    let stepped = if magnitude == 0 {
        (ob & 0x8000_0000) | 1
    } else {
        stepped
    };
    let keep = (o == 0.0) | (magnitude == 0x7f80_0000);
    f32::from_bits(if keep { xb } else { stepped })
}

/// The smallest float greater than `v`.
#[inline]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The largest float less than `v`.
#[inline]
pub fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_stepping() {
        assert!(next_float_up(1.0) > 1.0);
        assert!(next_float_down(1.0) < 1.0);
        assert!(next_float_up(0.0) > 0.0);
        assert!(next_float_down(0.0) < 0.0);
        assert!(next_float_up(-1.0) > -1.0);
        assert_eq!(next_float_up(next_float_down(3.5)), 3.5);
    }

    /// The branch-free step equals pbrt's next_float_up/down.
    #[test]
    fn step_away_matches_next_float() {
        let mut rng = crate::sampling::rng::Pcg32::new(7, 0);
        let mut values = vec![
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::MAX,
            -f32::MAX,
        ];
        values.extend([f32::from_bits(1), -f32::from_bits(1)]); // subnormals
        for _ in 0..10_000 {
            let e = rng.next_f32() * 60.0 - 30.0;
            values.push((rng.next_f32() - 0.5) * 2f32.powf(e));
        }
        for &x in &values {
            for o in [1e-7f32, -1e-7, 0.0, -0.0] {
                let expect = if o > 0.0 {
                    next_float_up(x)
                } else if o < 0.0 {
                    next_float_down(x)
                } else {
                    x
                };
                assert_eq!(step_away(x, o).to_bits(), expect.to_bits(), "x = {x:e}, o = {o:e}");
            }
        }
        assert_eq!(step_away(f32::INFINITY, 1.0), f32::INFINITY);
        assert_eq!(step_away(f32::NEG_INFINITY, -1.0), f32::NEG_INFINITY);
    }

    /// The three-coordinate steps (SSE2 and portable) are the scalar one
    /// in each coordinate, bit for bit, over signed zeros, subnormals,
    /// infinities, NaN and random values of both signs.
    #[test]
    fn step_away_3_matches_step_away() {
        let specials = [
            0.0f32,
            -0.0,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MIN_POSITIVE,
            1.0,
            -1.0,
            f32::MAX,
            -f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut rng = crate::sampling::rng::Pcg32::new(7, 1);
        let mut values: Vec<f32> = specials.to_vec();
        values.extend((0..200).map(|_| f32::from_bits(rng.next_u32())).filter(|v| !v.is_nan()));
        for (i, &x) in values.iter().enumerate() {
            for (j, &o) in values.iter().enumerate().step_by(3) {
                let (y, z) = (values[(i + j) % values.len()], values[(i * 7 + j) % values.len()]);
                let (ox, oz) = (values[(j + 5) % values.len()], values[(i + 2 * j) % values.len()]);
                let expect = [step_away(x, ox), step_away(y, o), step_away(z, oz)].map(f32::to_bits);
                let (xs, os) = (Vec3::new(x, y, z), Vec3::new(ox, o, oz));
                for got in [step_away_3(xs, os), step_away_3_portable(xs, os)] {
                    assert_eq!(got.to_array().map(f32::to_bits), expect, "x = {xs:?}, o = {os:?}");
                }
            }
        }
    }

    #[test]
    fn offset_moves_to_the_side_of_w() {
        let p = Vec3::new(1.0, 2.0, 3.0);
        let err = Vec3::splat(1e-6);
        let up = offset_ray_origin(p, err, Vec3::Z, Vec3::Z);
        let down = offset_ray_origin(p, err, Vec3::Z, -Vec3::Z);
        assert!(up.z > p.z && down.z < p.z);
        assert_eq!(up.x, p.x);
    }
}
