//! Watertight ray–triangle intersection (Woop, Benthin and Wald 2013,
//! "Watertight Ray/Triangle Intersection", as in pbrt-v4 section 6.5.3).
//!
//! The test shears space so that the ray runs along +z from the origin, then
//! evaluates the three edge functions in 2-D. Neighbouring triangles compute
//! identical edge functions for a shared edge, so a ray can never slip
//! between them; values that round to zero are recomputed in double
//! precision.

use super::bounds::gamma;
use super::ray::Ray;
use glam::Vec3;

/// Where a ray met a triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter.
    pub t: f32,
    /// Barycentric weights of the three vertices.
    pub b: [f32; 3],
}

#[inline]
fn permute(v: Vec3, x: usize, y: usize, z: usize) -> Vec3 {
    Vec3::new(v[x], v[y], v[z])
}

/// `a·b − c·d` with its sign exact: products of two f32 are exact in f64,
/// so only the difference is rounded. (Kahan's FMA form is as accurate but
/// calls a library `fmaf` on targets built without FMA.)
#[inline]
fn difference_of_products(a: f32, b: f32, c: f32, d: f32) -> f32 {
    (a as f64 * b as f64 - c as f64 * d as f64) as f32
}

/// What the watertight test needs of a ray, computed once per ray rather
/// than once per triangle (Woop et al. 2013, section 3): the axis
/// permutation that makes |d.z| largest and the shear that maps the
/// direction to +z.
#[derive(Clone, Copy, Debug)]
pub struct TriangleRay {
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl TriangleRay {
    /// Precomputes for `ray`; `None` for a zero direction.
    #[inline]
    pub fn new(ray: &Ray) -> Option<TriangleRay> {
        let kz = ray.dir.abs().max_position();
        let kx = if kz == 2 { 0 } else { kz + 1 };
        let ky = if kx == 2 { 0 } else { kx + 1 };
        let d = permute(ray.dir, kx, ky, kz);
        if d.z == 0.0 {
            return None;
        }
        let sz = 1.0 / d.z;
        Some(TriangleRay {
            kx,
            ky,
            kz,
            sx: -d.x * sz,
            sy: -d.y * sz,
            sz,
        })
    }
}

/// Intersects `ray` with the triangle (p0, p1, p2) within the ray's interval.
#[inline]
pub fn intersect_triangle(ray: &Ray, p0: Vec3, p1: Vec3, p2: Vec3) -> Option<TriangleHit> {
    intersect_triangle_with(ray, &TriangleRay::new(ray)?, p0, p1, p2)
}

/// [`intersect_triangle`] with the per-ray part precomputed.
#[inline]
pub fn intersect_triangle_with(ray: &Ray, pre: &TriangleRay, p0: Vec3, p1: Vec3, p2: Vec3) -> Option<TriangleHit> {
    let (kx, ky, kz) = (pre.kx, pre.ky, pre.kz);
    let (sx, sy, sz) = (pre.sx, pre.sy, pre.sz);
    // Translate to the ray origin and permute so that |d.z| is largest.
    let mut p0t = permute(p0 - ray.origin, kx, ky, kz);
    let mut p1t = permute(p1 - ray.origin, kx, ky, kz);
    let mut p2t = permute(p2 - ray.origin, kx, ky, kz);
    // Shear so that the ray direction becomes +z.
    p0t.x += sx * p0t.z;
    p0t.y += sy * p0t.z;
    p1t.x += sx * p1t.z;
    p1t.y += sy * p1t.z;
    p2t.x += sx * p2t.z;
    p2t.y += sy * p2t.z;

    // Edge functions with exact signs: a ray through an edge shared by two
    // triangles hits exactly one of them (watertightness).
    let e0 = difference_of_products(p1t.x, p2t.y, p1t.y, p2t.x);
    let e1 = difference_of_products(p2t.x, p0t.y, p2t.y, p0t.x);
    let e2 = difference_of_products(p0t.x, p1t.y, p0t.y, p1t.x);
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 {
        return None; // degenerate, or the ray lies in the triangle's plane
    }

    // Scaled distance, compared against the interval before dividing.
    p0t.z *= sz;
    p1t.z *= sz;
    p2t.z *= sz;
    let t_scaled = e0 * p0t.z + e1 * p1t.z + e2 * p2t.z;
    if det < 0.0 && (t_scaled >= ray.t_min * det || t_scaled < ray.t_max * det) {
        return None;
    }
    if det > 0.0 && (t_scaled <= ray.t_min * det || t_scaled > ray.t_max * det) {
        return None;
    }
    let inv_det = 1.0 / det;
    let b = [e0 * inv_det, e1 * inv_det, e2 * inv_det];
    let t = t_scaled * inv_det;

    // Reject hits whose t is not certainly positive given rounding
    // (pbrt-v4, section 6.8.4).
    let max_zt = Vec3::new(p0t.z, p1t.z, p2t.z).abs().max_element();
    let delta_z = gamma(3) * max_zt;
    let max_xt = Vec3::new(p0t.x, p1t.x, p2t.x).abs().max_element();
    let max_yt = Vec3::new(p0t.y, p1t.y, p2t.y).abs().max_element();
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = Vec3::new(e0, e1, e2).abs().max_element();
    let delta_t = 3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    if t <= delta_t {
        return None;
    }
    Some(TriangleHit { t, b })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    const P0: Vec3 = Vec3::new(0.0, 0.0, 0.0);
    const P1: Vec3 = Vec3::new(1.0, 0.0, 0.0);
    const P2: Vec3 = Vec3::new(0.0, 1.0, 0.0);

    #[test]
    fn hit_gives_distance_and_barycentrics() {
        let r = Ray::new(Vec3::new(0.25, 0.5, 2.0), -Vec3::Z);
        let h = intersect_triangle(&r, P0, P1, P2).unwrap();
        assert!((h.t - 2.0).abs() < 1e-6);
        let [b0, b1, b2] = h.b;
        assert!((b1 - 0.25).abs() < 1e-6 && (b2 - 0.5).abs() < 1e-6 && (b0 - 0.25).abs() < 1e-6);
        // Both sides hit.
        let r = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z);
        assert!(intersect_triangle(&r, P0, P1, P2).is_some());
    }

    #[test]
    fn misses_outside_behind_parallel_and_degenerate() {
        assert!(intersect_triangle(&Ray::new(Vec3::new(0.6, 0.6, 1.0), -Vec3::Z), P0, P1, P2).is_none());
        assert!(intersect_triangle(&Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::Z), P0, P1, P2).is_none());
        assert!(intersect_triangle(&Ray::new(Vec3::new(-1.0, 0.2, 0.0), Vec3::X), P0, P1, P2).is_none());
        assert!(intersect_triangle(&Ray::new(Vec3::new(0.2, 0.0, 1.0), -Vec3::Z), P0, P1, P1).is_none());
        let short = Ray::with_interval(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z, 0.0, 0.5);
        assert!(intersect_triangle(&short, P0, P1, P2).is_none());
    }

    #[test]
    fn shared_edges_are_watertight() {
        // A quad split along its diagonal: every ray through the quad must
        // hit at least one of the two triangles, including rays through the
        // diagonal itself.
        let q = [
            Vec3::new(-0.3, -0.7, 0.1),
            Vec3::new(1.7, -0.2, 0.3),
            Vec3::new(1.1, 1.9, -0.2),
            Vec3::new(-0.6, 1.3, 0.0),
        ];
        let mut rng = Pcg32::new(12, 0);
        for _ in 0..20_000 {
            // Points on the shared diagonal q0–q2.
            let s = rng.next_f32();
            let target = q[0] + (q[2] - q[0]) * s;
            let origin = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 3.0);
            let r = Ray::new(origin, target - origin);
            let a = intersect_triangle(&r, q[0], q[1], q[2]);
            let b = intersect_triangle(&r, q[0], q[2], q[3]);
            assert!(
                a.is_some() || b.is_some(),
                "ray slipped through the diagonal at s = {s}"
            );
        }
    }

    #[test]
    fn large_coordinates() {
        let off = Vec3::splat(1e6);
        let r = Ray::new(off + Vec3::new(0.25, 0.25, 10.0), -Vec3::Z);
        let h = intersect_triangle(&r, off + P0 * 10.0, off + P1 * 10.0, off + P2 * 10.0).unwrap();
        assert!((h.t - 10.0).abs() < 1e-2);
    }
}
