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
use glam::{Vec3, Vec4};

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
    pub(crate) kx: usize,
    pub(crate) ky: usize,
    pub(crate) kz: usize,
    pub(crate) sx: f32,
    pub(crate) sy: f32,
    pub(crate) sz: f32,
}

impl TriangleRay {
    /// Precomputes for `ray`; `None` for a zero direction.
    #[inline]
    pub fn new(ray: &Ray) -> Option<TriangleRay> {
        let (_, dir, _) = ray.read_by_field();
        let kz = dir.abs().max_position();
        let kx = if kz == 2 { 0 } else { kz + 1 };
        let ky = if kx == 2 { 0 } else { kx + 1 };
        let d = permute(dir, kx, ky, kz);
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

/// [`intersect_triangle`] with the per-ray part precomputed. Always
/// inlined: it is the leaf test of every traversal that calls it.
#[inline(always)]
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

/// Four triangles in structure-of-arrays form, tested against one ray with
/// the same vector instructions (the layout of Embree's "triangle4"). An
/// empty lane holds NaN vertices, which no comparison accepts.
#[derive(Clone, Copy, Debug)]
pub struct Triangle4 {
    /// `v[vertex][axis]`: one coordinate of one vertex of the four triangles.
    v: [[Vec4; 3]; 3],
    /// The caller's number of each lane's triangle.
    pub ids: [u32; 4],
}

impl Triangle4 {
    /// Packs up to four triangles with their numbers.
    pub fn new(triangles: &[([Vec3; 3], u32)]) -> Triangle4 {
        debug_assert!(triangles.len() <= 4);
        let mut v = [[[f32::NAN; 4]; 3]; 3];
        let mut ids = [u32::MAX; 4];
        for (lane, (tri, id)) in triangles.iter().take(4).enumerate() {
            for (vertex, p) in tri.iter().enumerate() {
                for axis in 0..3 {
                    v[vertex][axis][lane] = p[axis];
                }
            }
            ids[lane] = *id;
        }
        Triangle4 {
            v: v.map(|vertex| vertex.map(Vec4::from_array)),
            ids,
        }
    }

    /// The nearest of the four hits within the ray's interval, as (lane,
    /// t): the watertight test of [`intersect_triangle_with`] on four lanes.
    /// Edge functions are computed in f32 (for an edge shared by two
    /// triangles both get exactly opposite values, which is what
    /// watertightness needs) and again in f64 in a lane where one is zero.
    #[inline]
    pub fn intersect(&self, ray: &Ray, pre: &TriangleRay) -> Option<(usize, f32)> {
        self.intersect_barycentric(ray, pre).map(|(lane, t, _)| (lane, t))
    }

    /// [`Triangle4::intersect`] with the barycentrics of the hit, as
    /// [`intersect_triangle_with`] gives them.
    #[inline(always)]
    pub fn intersect_barycentric(&self, ray: &Ray, pre: &TriangleRay) -> Option<(usize, f32, [f32; 3])> {
        let (kx, ky, kz) = (pre.kx, pre.ky, pre.kz);
        let (ox, oy, oz) = (
            Vec4::splat(ray.origin[kx]),
            Vec4::splat(ray.origin[ky]),
            Vec4::splat(ray.origin[kz]),
        );
        let (sx, sy, sz) = (Vec4::splat(pre.sx), Vec4::splat(pre.sy), Vec4::splat(pre.sz));
        // Translate to the origin, permute so that |d.z| is largest, shear
        // the direction onto +z; z is scaled for the distance only.
        let transform = |v: &[Vec4; 3]| {
            let z = v[kz] - oz;
            (v[kx] - ox + sx * z, v[ky] - oy + sy * z, z * sz)
        };
        let (x0, y0, z0) = transform(&self.v[0]);
        let (x1, y1, z1) = transform(&self.v[1]);
        let (x2, y2, z2) = transform(&self.v[2]);
        let mut e0 = x1 * y2 - y1 * x2;
        let mut e1 = x2 * y0 - y2 * x0;
        let mut e2 = x0 * y1 - y0 * x1;
        let zero = Vec4::ZERO;
        if (e0.cmpeq(zero) | e1.cmpeq(zero) | e2.cmpeq(zero)).any() {
            let f = |ax: Vec4, by: Vec4, ay: Vec4, bx: Vec4| {
                let (ax, by, ay, bx) = (ax.to_array(), by.to_array(), ay.to_array(), bx.to_array());
                Vec4::from_array(std::array::from_fn(|i| {
                    (ax[i] as f64 * by[i] as f64 - ay[i] as f64 * bx[i] as f64) as f32
                }))
            };
            e0 = f(x1, y2, y1, x2);
            e1 = f(x2, y0, y2, x0);
            e2 = f(x0, y1, y0, x1);
        }
        let negative = e0.cmplt(zero) | e1.cmplt(zero) | e2.cmplt(zero);
        let positive = e0.cmpgt(zero) | e1.cmpgt(zero) | e2.cmpgt(zero);
        let det = e0 + e1 + e2;
        let mut valid = !(negative & positive) & det.cmpne(zero);
        if !valid.any() {
            return None;
        }
        let t = (e0 * z0 + e1 * z1 + e2 * z2) / det;
        valid &= t.cmpgt(Vec4::splat(ray.t_min)) & t.cmple(Vec4::splat(ray.t_max));
        if !valid.any() {
            return None;
        }
        // Reject hits whose t is not certainly positive given rounding
        // (pbrt-v4, section 6.8.4), as the one-triangle test does.
        let max_zt = z0.abs().max(z1.abs()).max(z2.abs());
        let max_xt = x0.abs().max(x1.abs()).max(x2.abs());
        let max_yt = y0.abs().max(y1.abs()).max(y2.abs());
        let delta_z = gamma(3) * max_zt;
        let delta_x = gamma(5) * (max_xt + max_zt);
        let delta_y = gamma(5) * (max_yt + max_zt);
        let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t = 3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) / det.abs();
        valid &= t.cmpgt(delta_t);
        let mask = valid.bitmask();
        if mask == 0 {
            return None;
        }
        let t = t.to_array();
        let mut best: Option<(usize, f32)> = None;
        for (lane, &tl) in t.iter().enumerate() {
            if mask & (1 << lane) != 0 && best.is_none_or(|(_, tb)| tl < tb) {
                best = Some((lane, tl));
            }
        }
        best.map(|(lane, t)| {
            let inv_det = 1.0 / det.to_array()[lane];
            let b = [e0, e1, e2].map(|e| e.to_array()[lane] * inv_det);
            (lane, t, b)
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
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

    /// A skew quad split along its diagonal q0–q2 into two triangles.
    pub(crate) const DIAGONAL_QUAD: [Vec3; 4] = [
        Vec3::new(-0.3, -0.7, 0.1),
        Vec3::new(1.7, -0.2, 0.3),
        Vec3::new(1.1, 1.9, -0.2),
        Vec3::new(-0.6, 1.3, 0.0),
    ];

    /// Checks that `hits` finds a hit for 20 000 rays aimed at points on
    /// the diagonal shared by `DIAGONAL_QUAD`'s two triangles (q0, q1, q2)
    /// and (q0, q2, q3): no ray may slip through between them.
    pub(crate) fn assert_diagonal_is_watertight(seed: u64, hits: impl Fn(&Ray) -> bool) {
        let q = DIAGONAL_QUAD;
        let mut rng = Pcg32::new(seed, 0);
        for _ in 0..20_000 {
            let s = rng.next_f32();
            let target = q[0] + (q[2] - q[0]) * s;
            let origin = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 3.0);
            let r = Ray::new(origin, target - origin);
            assert!(hits(&r), "ray slipped through the diagonal at s = {s}");
        }
    }

    #[test]
    fn shared_edges_are_watertight() {
        let q = DIAGONAL_QUAD;
        assert_diagonal_is_watertight(12, |r| {
            intersect_triangle(r, q[0], q[1], q[2]).is_some() || intersect_triangle(r, q[0], q[2], q[3]).is_some()
        });
    }

    #[test]
    fn large_coordinates() {
        let off = Vec3::splat(1e6);
        let r = Ray::new(off + Vec3::new(0.25, 0.25, 10.0), -Vec3::Z);
        let h = intersect_triangle(&r, off + P0 * 10.0, off + P1 * 10.0, off + P2 * 10.0).unwrap();
        assert!((h.t - 10.0).abs() < 1e-2);
    }

    /// The four-lane test finds what the one-triangle test finds: the
    /// nearest hit of the lanes that hold a triangle, never an empty lane.
    #[test]
    fn four_lanes_agree_with_one_at_a_time() {
        let mut rng = Pcg32::new(21, 4);
        let mut v = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let mut hits = 0;
        for case in 0..4000 {
            let lanes = 1 + case % 4;
            let tris: Vec<([Vec3; 3], u32)> = (0..lanes).map(|i| ([v(), v(), v()], 10 + i as u32)).collect();
            let block = Triangle4::new(&tris);
            let origin = v() * 3.0;
            let ray = Ray::with_interval(
                origin,
                v() - origin,
                1e-4,
                if case % 3 == 0 { 0.7 } else { f32::INFINITY },
            );
            let expected = tris
                .iter()
                .enumerate()
                .filter_map(|(lane, (t, _))| intersect_triangle(&ray, t[0], t[1], t[2]).map(|h| (lane, h.t)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let got = block.intersect(&ray, &TriangleRay::new(&ray).unwrap());
            match (got, expected) {
                (None, None) => {}
                (Some((lane, t)), Some((_, te))) => {
                    hits += 1;
                    assert!(lane < lanes && block.ids[lane] == 10 + lane as u32);
                    assert!((t - te).abs() <= 1e-5 * te.max(1.0), "case {case}: {t} vs {te}");
                }
                _ => panic!("case {case}: {got:?} vs {expected:?}"),
            }
        }
        assert!(hits > 500, "{hits}: the rays should often hit");
    }

    /// Rays through the diagonal shared by two triangles in one block hit
    /// one of them, as with the one-triangle test.
    #[test]
    fn four_lanes_are_watertight() {
        let q = DIAGONAL_QUAD;
        let block = Triangle4::new(&[([q[0], q[1], q[2]], 0), ([q[0], q[2], q[3]], 1)]);
        assert_diagonal_is_watertight(13, |r| block.intersect(r, &TriangleRay::new(r).unwrap()).is_some());
    }
}
