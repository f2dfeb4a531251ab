//! Bilinear patches, as pbrt-v4's `bilinearmesh`: the surface
//!
//! ```text
//! S(u, v) = (1 − u)(1 − v)·p00 + u(1 − v)·p10 + (1 − u)v·p01 + uv·p11,   u, v ∈ [0, 1],
//! ```
//!
//! a hyperbolic paraboloid through four corners that need not lie in a
//! plane. A ray meets it exactly (Reshetov, "Cool Patches", Ray Tracing
//! Gems 2019, ch. 8): the iso-line of a fixed u, S(u, ·), is a segment, and
//! the ray meets it only where the two are coplanar, (S(u, 0) − o)·(d ×
//! ∂S/∂v) = 0, a quadratic in u; each root in [0, 1] gives v and t from
//! the two lines' closest points. Everything is computed in double
//! precision.
//!
//! Points are drawn for area lights as pbrt-v4 draws them: (u, v) with the
//! bilinear density through the corners' area factors |∂S/∂u × ∂S/∂v|,
//! which is exact for a parallelogram and close to uniform by area
//! otherwise, with the density per unit area that this gives at the point
//! (`density_at`).

use super::bounds::{Aabb, gamma};
use super::ray::Ray;
use super::roots::quadratic_roots;
use super::shape::{AreaSample, LocalSurface};
use crate::sampling::distribution::sample_linear;
use glam::{DVec2, DVec3, Vec2, Vec3};

/// A bilinear patch in its object space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BilinearPatch {
    /// The corners S(0, 0), S(1, 0), S(0, 1), S(1, 1).
    pub p: [DVec3; 4],
    /// The texture coordinates at the corners, interpolated bilinearly
    /// (pbrt-v4's per-vertex `uv`); (0, 0), (1, 0), (0, 1), (1, 1) unless
    /// given, so that they are (u, v) itself.
    pub uvs: [Vec2; 4],
    /// Its area (Gauss–Legendre quadrature of |∂S/∂u × ∂S/∂v|).
    area: f64,
}

/// Nodes and weights of 8-point Gauss–Legendre quadrature on [0, 1]: the
/// area factor is the length of a vector linear in u and v, smooth over the
/// square, so this is exact to the float precision for any patch that does
/// not pass through a point of zero area factor.
const GAUSS_8: [(f64, f64); 8] = [
    (0.019855071751231912, 0.05061426814518853),
    (0.10166676129318664, 0.11119051722668721),
    (0.2372337950418355, 0.15685332293894344),
    (0.4082826787521751, 0.18134189168918083),
    (0.5917173212478248, 0.18134189168918083),
    (0.7627662049581645, 0.15685332293894344),
    (0.8983332387068134, 0.11119051722668721),
    (0.9801449282487681, 0.05061426814518853),
];

impl BilinearPatch {
    /// The patch through corners p00, p10, p01, p11 (pbrt-v4's vertex order
    /// of a `bilinearmesh` patch).
    pub fn new(p00: Vec3, p10: Vec3, p01: Vec3, p11: Vec3) -> BilinearPatch {
        let mut patch = BilinearPatch {
            p: [p00.as_dvec3(), p10.as_dvec3(), p01.as_dvec3(), p11.as_dvec3()],
            uvs: [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE],
            area: 0.0,
        };
        let mut area = 0.0;
        // Eight nodes per axis; a larger patch is split into 4 × 4 cells
        // first, so that strongly bent ones stay exact too.
        for cu in 0..4 {
            for cv in 0..4 {
                for &(x, wx) in &GAUSS_8 {
                    for &(y, wy) in &GAUSS_8 {
                        let (u, v) = ((cu as f64 + x) / 4.0, (cv as f64 + y) / 4.0);
                        area += wx * wy * patch.area_factor(u, v);
                    }
                }
            }
        }
        patch.area = area / 16.0;
        patch
    }

    /// The same patch with texture coordinates `uvs` at its corners.
    pub fn with_uvs(self, uvs: [Vec2; 4]) -> BilinearPatch {
        BilinearPatch { uvs, ..self }
    }

    /// Whether the four corners lie in one plane and make a parallelogram,
    /// which is then flat and could be two triangles, or a rectangle.
    pub fn is_parallelogram(&self) -> bool {
        let [p00, p10, p01, p11] = self.p;
        let scale = (p10 - p00).length().max((p01 - p00).length()).max(f64::MIN_POSITIVE);
        (p11 - p10 - p01 + p00).length() <= 1e-6 * scale
    }

    /// Whether the four corners lie in one plane (to a millionth of the
    /// patch's size).
    pub fn is_planar(&self) -> bool {
        let [p00, p10, p01, p11] = self.p;
        let n = (p11 - p00).cross(p01 - p10);
        let len = n.length();
        if len == 0.0 {
            return true;
        }
        let scale = (p11 - p00).length().max((p01 - p10).length());
        ((p10 - p00).dot(n) / len).abs() <= 1e-6 * scale
    }

    /// The box of the corners, which holds the whole patch (each point is
    /// a convex combination of them).
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.p.map(|p| p.as_vec3()))
    }

    /// The point S(u, v).
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        let [p00, p10, p01, p11] = self.p;
        (1.0 - v) * p00.lerp(p10, u) + v * p01.lerp(p11, u)
    }

    /// ∂S/∂u and ∂S/∂v at (u, v).
    pub fn tangents(&self, u: f64, v: f64) -> (DVec3, DVec3) {
        let [p00, p10, p01, p11] = self.p;
        ((p10 - p00).lerp(p11 - p01, v), (p01 - p00).lerp(p11 - p10, u))
    }

    /// |∂S/∂u × ∂S/∂v| at (u, v): area per unit area of the (u, v) square.
    pub fn area_factor(&self, u: f64, v: f64) -> f64 {
        let (du, dv) = self.tangents(u, v);
        du.cross(dv).length()
    }

    /// The surface area.
    pub fn area(&self) -> f32 {
        self.area as f32
    }

    /// Distance to the nearest point of the patch within the ray's
    /// interval.
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        self.intersect_uv(ray).map(|(t, _)| t as f32)
    }

    /// The nearest hit within the ray's interval: its distance and (u, v).
    pub fn intersect_uv(&self, ray: &Ray) -> Option<(f64, DVec2)> {
        let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
        intersect_bilinear(self.p, o, d, ray.t_min as f64, ray.t_max as f64)
    }

    /// The (u, v) of a point on (or within rounding of) the patch: the
    /// closed-form inverse of the patch projected along its mean normal's
    /// largest axis, then Newton steps on the distance in space, which also
    /// settle a projection that folds the patch over itself.
    pub fn uv_of(&self, p: DVec3) -> DVec2 {
        let [p00, p10, p01, p11] = self.p;
        let mean_n = (p11 - p00).cross(p01 - p10);
        let an = mean_n.abs();
        let axis = if an.x >= an.y && an.x >= an.z {
            0
        } else if an.y >= an.z {
            1
        } else {
            2
        };
        let drop = |x: DVec3| match axis {
            0 => DVec2::new(x.y, x.z),
            1 => DVec2::new(x.z, x.x),
            _ => DVec2::new(x.x, x.y),
        };
        let (a, b, c, dd, x) = (drop(p00), drop(p10), drop(p11), drop(p01), drop(p));
        // x = a + u·e + v·f + uv·g2 (Quilez's inverse bilinear
        // interpolation): a quadratic in v.
        let (e, f, g2, hh) = (b - a, dd - a, a - b + c - dd, x - a);
        let cross = |s: DVec2, t: DVec2| s.x * t.y - s.y * t.x;
        let k2 = cross(g2, f);
        let k1 = cross(e, f) + cross(hh, g2);
        let k0 = cross(hh, e);
        let mut candidates: [Option<DVec2>; 2] = [None, None];
        for (slot, v) in candidates.iter_mut().zip(quadratic_roots(k2, k1, k0)) {
            let Some(v) = v else { continue };
            let den = e + g2 * v;
            let u = if den.x.abs() > den.y.abs() {
                (hh.x - f.x * v) / den.x
            } else {
                (hh.y - f.y * v) / den.y
            };
            if u.is_finite() {
                *slot = Some(DVec2::new(u, v).clamp(DVec2::ZERO, DVec2::ONE));
            }
        }
        let mut uv = candidates
            .into_iter()
            .flatten()
            .min_by(|s, t| {
                let ds = (self.point(s.x, s.y) - p).length_squared();
                let dt = (self.point(t.x, t.y) - p).length_squared();
                ds.total_cmp(&dt)
            })
            .unwrap_or(DVec2::splat(0.5));
        // Gauss–Newton on |S(u, v) − p|², within the square.
        for _ in 0..4 {
            let r = self.point(uv.x, uv.y) - p;
            let (du, dv) = self.tangents(uv.x, uv.y);
            let (m11, m12, m22) = (du.dot(du), du.dot(dv), dv.dot(dv));
            let det = m11 * m22 - m12 * m12;
            if det.abs() <= 1e-300 {
                break;
            }
            let (r1, r2) = (du.dot(r), dv.dot(r));
            let step = DVec2::new(m22 * r1 - m12 * r2, m11 * r2 - m12 * r1) / det;
            uv = (uv - step).clamp(DVec2::ZERO, DVec2::ONE);
            if step.length_squared() < 1e-24 {
                break;
            }
        }
        uv
    }

    /// The surface at a point found by [`BilinearPatch::intersect`]. The
    /// normal is ∂S/∂u × ∂S/∂v (pbrt-v4's orientation), where that is not
    /// zero; at a corner where two edges meet in a line, the cross product
    /// of the diagonals.
    pub fn surface(&self, p: Vec3) -> LocalSurface {
        let uv = self.uv_of(p.as_dvec3());
        self.surface_at(uv)
    }

    /// The surface at (u, v).
    pub fn surface_at(&self, uv: DVec2) -> LocalSurface {
        let [p00, p10, p01, p11] = self.p;
        let (du, dv) = self.tangents(uv.x, uv.y);
        let mut n = du.cross(dv);
        if n.length_squared() <= 1e-24 * du.length_squared().max(dv.length_squared()).powi(2) {
            n = (p11 - p00).cross(p01 - p10);
        }
        let p = self.point(uv.x, uv.y).as_vec3();
        // Texture coordinates st interpolated from the corners', and the
        // tangents along them: [∂p/∂s ∂p/∂t] = [∂p/∂u ∂p/∂v] · J⁻¹ with J
        // the Jacobian of st in (u, v) (kept in (u, v) where J is singular).
        let [t00, t10, t01, t11] = self.uvs.map(|t| t.as_dvec2());
        let (u, v) = (uv.x, uv.y);
        let st = (1.0 - v) * t00.lerp(t10, u) + v * t01.lerp(t11, u);
        let (ds_du, ds_dv) = ((t10 - t00).lerp(t11 - t01, v), (t01 - t00).lerp(t11 - t10, u));
        let det = ds_du.x * ds_dv.y - ds_dv.x * ds_du.y;
        let (dpds, dpdt) = if det.abs() > 1e-12 {
            ((du * ds_dv.y - dv * ds_du.y) / det, (dv * ds_du.x - du * ds_dv.x) / det)
        } else {
            (du, dv)
        };
        LocalSurface {
            p,
            // The point is recomputed from (u, v) in double precision: what
            // remains is (u, v)'s own error, a few ulps of the corners, and
            // the rounding to single precision.
            p_error: self.p.iter().fold(p.abs(), |m, c| m.max(c.abs().as_vec3())) * gamma(8),
            n: n.normalize_or(DVec3::Z).as_vec3(),
            uv: st.as_vec2(),
            dpdu: dpds.as_vec3(),
            dpdv: dpdt.as_vec3(),
        }
    }

    /// The corners' area factors, which the light's point density
    /// interpolates; all equal (a uniform density) where they are all 0.
    fn corner_weights(&self) -> [f64; 4] {
        let w = [
            self.area_factor(0.0, 0.0),
            self.area_factor(1.0, 0.0),
            self.area_factor(0.0, 1.0),
            self.area_factor(1.0, 1.0),
        ];
        if w.iter().sum::<f64>() > 0.0 { w } else { [1.0; 4] }
    }

    /// A point for an area light: (u, v) drawn with the density bilinear
    /// through the corners' area factors; `None` for a patch of no area.
    pub fn sample_area(&self, u: Vec2) -> Option<AreaSample> {
        if self.area <= 0.0 {
            return None;
        }
        let [w00, w10, w01, w11] = self.corner_weights();
        // v from its marginal density, linear from w00 + w10 to w01 + w11,
        // then u from the density linear along that row.
        let v = sample_linear(u.y, (w00 + w10) as f32, (w01 + w11) as f32) as f64;
        let uu = sample_linear(u.x, (w00 + v * (w01 - w00)) as f32, (w10 + v * (w11 - w10)) as f32) as f64;
        Some(self.surface_at(DVec2::new(uu, v)).into())
    }

    /// The density per unit area with which [`BilinearPatch::sample_area`]
    /// draws the point `p` of the patch.
    pub fn density_at(&self, p: Vec3) -> f32 {
        let uv = self.uv_of(p.as_dvec3());
        let [w00, w10, w01, w11] = self.corner_weights();
        let mean = 0.25 * (w00 + w10 + w01 + w11);
        let (u, v) = (uv.x, uv.y);
        let bilinear = ((1.0 - u) * (1.0 - v) * w00 + u * (1.0 - v) * w10 + (1.0 - u) * v * w01 + u * v * w11) / mean;
        let factor = self.area_factor(u, v);
        if factor > 0.0 { (bilinear / factor) as f32 } else { 0.0 }
    }
}

/// The nearest hit of the ray o + t·d, t in (`t_min`, `t_max`], with the
/// bilinear patch of corners S(0, 0), S(1, 0), S(0, 1), S(1, 1): its
/// distance and (u, v). A ray meets the iso-line S(u, ·) only where the
/// two are coplanar, a quadratic in u (Reshetov 2019, as pbrt-v4).
pub fn intersect_bilinear(
    [p00, p10, p01, p11]: [DVec3; 4],
    o: DVec3,
    d: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<(f64, DVec2)> {
    // S(u, 0) − o = q + u·e and ∂S/∂v = g + u·h.
    let (q, e) = (p00 - o, p10 - p00);
    let (g, h) = (p01 - p00, p11 - p10 - p01 + p00);
    let (dg, dh) = (d.cross(g), d.cross(h));
    let a = e.dot(dh);
    let b = q.dot(dh) + e.dot(dg);
    let c = q.dot(dg);
    let mut best: Option<(f64, DVec2)> = None;
    for u in quadratic_roots(a, b, c).into_iter().flatten() {
        if !(0.0..=1.0).contains(&u) {
            continue;
        }
        // The ray o + t·d against the segment S(u, 0) + v·∂S/∂v:
        // with Δ = S(u, 0) − o and n = d × ∂S/∂v, t = (Δ × ∂S/∂v)·n / |n|²
        // and v = (Δ × d)·n / |n|².
        let start = q + u * e;
        let dir_v = g + u * h;
        let n = d.cross(dir_v);
        let nn = n.length_squared();
        if nn == 0.0 {
            continue; // the ray runs along the iso-line
        }
        let v = start.cross(d).dot(n) / nn;
        let t = start.cross(dir_v).dot(n) / nn;
        if !(0.0..=1.0).contains(&v) || t <= t_min || t > t_max {
            continue;
        }
        if best.is_none_or(|(t_best, _)| t < t_best) {
            best = Some((t, DVec2::new(u, v)));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// z = xy over [−1, 1]²: the patch through (±1, ±1, ±1).
    fn saddle() -> BilinearPatch {
        BilinearPatch::new(
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, 1.0),
        )
    }

    #[test]
    fn vertical_rays_meet_the_saddle_at_z_equals_xy() {
        let s = saddle();
        let mut rng = Pcg32::new(7, 1);
        for _ in 0..2000 {
            let (x, y) = (2.0 * rng.next_f32() - 1.0, 2.0 * rng.next_f32() - 1.0);
            for dir in [-1.0f32, 1.0] {
                let ray = Ray::new(Vec3::new(x, y, -3.0 * dir), Vec3::new(0.0, 0.0, dir));
                let t = s
                    .intersect(&ray)
                    .expect("a vertical ray over the square meets the saddle");
                let z = ray.at(t).z;
                assert!((z - x * y).abs() < 1e-5, "z {z} vs {}", x * y);
                let surf = s.surface(ray.at(t));
                assert!((surf.p.z - x * y).abs() < 1e-5);
                let want = Vec3::new(-y, -x, 1.0).normalize();
                assert!(surf.n.dot(want) > 0.99999, "normal {:?} vs {want:?}", surf.n);
                assert!(
                    (surf.uv - Vec2::new((x + 1.0) / 2.0, (y + 1.0) / 2.0))
                        .abs()
                        .max_element()
                        < 1e-5
                );
            }
        }
        // Outside the square: nothing.
        let ray = Ray::new(Vec3::new(1.2, 0.0, -3.0), Vec3::Z);
        assert!(s.intersect(&ray).is_none());
    }

    /// Horizontal rays through the saddle along x at height z0 and offset y0
    /// cross z = x·y0 where x = z0 / y0: a line meeting the surface once.
    #[test]
    fn grazing_and_oblique_rays_agree_with_the_closed_form() {
        let s = saddle();
        let mut rng = Pcg32::new(3, 5);
        let mut hits = 0;
        for _ in 0..2000 {
            let y0 = 0.1 + 0.9 * rng.next_f32();
            let z0 = (2.0 * rng.next_f32() - 1.0) * y0;
            let ray = Ray::new(Vec3::new(-3.0, y0, z0), Vec3::X);
            let t = s.intersect(&ray).expect("the line meets the saddle once");
            let want = z0 / y0 + 3.0;
            assert!((t - want).abs() < 1e-4, "t {t} vs {want}");
            hits += 1;
        }
        assert_eq!(hits, 2000);
    }

    /// Random rays against random bent patches: every hit lies on the
    /// patch, and the hits agree with a fine triangulation of it (the first
    /// hit, or a miss) except within the triangulation's own error.
    #[test]
    fn hits_match_a_fine_triangulation() {
        let mut rng = Pcg32::new(11, 2);
        let mut r = || rng.next_f32();
        let (mut compared, mut disagree) = (0, 0);
        for _ in 0..40 {
            let mut corner = || Vec3::new(2.0 * r() - 1.0, 2.0 * r() - 1.0, 2.0 * r() - 1.0);
            let patch = BilinearPatch::new(corner(), corner(), corner(), corner());
            let n = 64;
            let tris: Vec<[Vec3; 3]> = (0..n * n)
                .flat_map(|k| {
                    let (i, j) = ((k % n) as f64, (k / n) as f64);
                    let s = |a: f64, b: f64| patch.point(a / n as f64, b / n as f64).as_vec3();
                    [
                        [s(i, j), s(i + 1.0, j), s(i + 1.0, j + 1.0)],
                        [s(i, j), s(i + 1.0, j + 1.0), s(i, j + 1.0)],
                    ]
                })
                .collect();
            for _ in 0..200 {
                let mut rr = Pcg32::new(compared as u64, 9);
                let o = Vec3::new(4.0 * rr.next_f32() - 2.0, 4.0 * rr.next_f32() - 2.0, 3.0);
                let target = Vec3::new(rr.next_f32() - 0.5, rr.next_f32() - 0.5, rr.next_f32() - 0.5);
                let ray = Ray::new(o, target - o);
                let exact = patch.intersect(&ray);
                let mesh = tris
                    .iter()
                    .filter_map(|t| crate::geometry::triangle::intersect_triangle(&ray, t[0], t[1], t[2]).map(|h| h.t))
                    .min_by(f32::total_cmp);
                compared += 1;
                if let Some(t) = exact {
                    let p = ray.at(t).as_dvec3();
                    let uv = patch.uv_of(p);
                    assert!((patch.point(uv.x, uv.y) - p).length() < 1e-5, "hit off the surface");
                }
                match (exact, mesh) {
                    (Some(a), Some(b)) if (a - b).abs() < 2e-3 * ray.dir.length().recip().max(1.0) => {}
                    (None, None) => {}
                    _ => disagree += 1,
                }
            }
        }
        // Rays at the patch's silhouette or edge may fall on either side of
        // the triangulation's chords.
        assert!(disagree * 200 < compared, "{disagree} of {compared} disagree");
    }

    #[test]
    fn area_matches_a_fine_triangulation() {
        let mut rng = Pcg32::new(5, 5);
        for _ in 0..10 {
            let mut c = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0;
            let patch = BilinearPatch::new(c(), c(), c(), c());
            let n = 400;
            let mut sum = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let s = |a: usize, b: usize| patch.point(a as f64 / n as f64, b as f64 / n as f64);
                    sum += 0.5 * (s(i + 1, j) - s(i, j)).cross(s(i + 1, j + 1) - s(i, j)).length();
                    sum += 0.5 * (s(i + 1, j + 1) - s(i, j)).cross(s(i, j + 1) - s(i, j)).length();
                }
            }
            assert!(
                (patch.area() as f64 - sum).abs() < 1e-4 * sum,
                "{} vs {sum}",
                patch.area()
            );
        }
        // z = xy over [−1, 1]²: ∫∫ √(1 + x² + y²) dx dy.
        let s = saddle();
        let mut reference = 0.0;
        let n = 2000;
        for i in 0..n {
            for j in 0..n {
                let (x, y) = (
                    -1.0 + (i as f64 + 0.5) * 2.0 / n as f64,
                    -1.0 + (j as f64 + 0.5) * 2.0 / n as f64,
                );
                reference += (1.0 + x * x + y * y).sqrt() * 4.0 / (n * n) as f64;
            }
        }
        assert!((s.area() as f64 - reference).abs() < 1e-5 * reference);
    }

    /// Points drawn for lights: E[1/density] is the area, and the density
    /// reported at each point is the one the points fall with (cell counts
    /// against the density integrated over each cell).
    #[test]
    fn light_points_fall_with_the_density_they_report() {
        let patch = BilinearPatch::new(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(3.0, 0.0, 0.5),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.5, 2.0),
        );
        let mut rng = Pcg32::new(1, 1);
        let n = 400_000;
        let cells = 8;
        let mut counts = vec![0u32; cells * cells];
        let mut inverse_sum = 0.0f64;
        for _ in 0..n {
            let s = patch.sample_area(Vec2::new(rng.next_f32(), rng.next_f32())).unwrap();
            let d = patch.density_at(s.p) as f64;
            inverse_sum += 1.0 / d;
            let cell = |x: f32| ((x * cells as f32) as usize).min(cells - 1);
            counts[cell(s.uv.y) * cells + cell(s.uv.x)] += 1;
        }
        let area = patch.area() as f64;
        let mean = inverse_sum / n as f64;
        assert!((mean - area).abs() < 0.01 * area, "E[1/pdf] {mean} vs area {area}");
        // Each cell's probability: the density times the area element,
        // integrated over the cell.
        for cv in 0..cells {
            for cu in 0..cells {
                let mut prob = 0.0;
                let k = 6;
                for i in 0..k {
                    for j in 0..k {
                        let u = (cu as f64 + (i as f64 + 0.5) / k as f64) / cells as f64;
                        let v = (cv as f64 + (j as f64 + 0.5) / k as f64) / cells as f64;
                        let p = patch.point(u, v).as_vec3();
                        prob += patch.density_at(p) as f64 * patch.area_factor(u, v) / (k * k * cells * cells) as f64;
                    }
                }
                let expected = prob * n as f64;
                let got = counts[cv * cells + cu] as f64;
                assert!(
                    (got - expected).abs() < 5.0 * expected.sqrt() + 0.002 * expected,
                    "cell ({cu}, {cv}): {got} vs {expected}"
                );
            }
        }
    }

    #[test]
    fn flat_patches_are_recognised() {
        let square = BilinearPatch::new(Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0));
        assert!(square.is_parallelogram() && square.is_planar());
        let kite = BilinearPatch::new(Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(2.0, 2.0, 0.0));
        assert!(!kite.is_parallelogram() && kite.is_planar());
        assert!(!saddle().is_planar());
        assert!((square.area() - 1.0).abs() < 1e-6);
    }
}
