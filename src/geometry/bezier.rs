//! Bicubic Bézier patches, intersected directly: the surface
//!
//! ```text
//! S(u, v) = Σᵢ Σⱼ Bᵢ(u) Bⱼ(v) P[j][i],   Bᵢ the cubic Bernstein polynomials,
//! ```
//!
//! over 4 × 4 control points (Newell's teapot is 32 of them). A ray is
//! tested against the patch by recursive subdivision (de Casteljau halving
//! in u and v in turn): a piece whose control points' box the ray misses
//! is dropped (the convex hull property), a piece flat to a millionth of
//! the patch's size, or at the depth limit, is intersected as the bilinear
//! patch of its corners, and that hit is refined by Newton's method on
//! S(u, v) = o + t·d (Nishita, Sederberg and Kakimoto 1990 clip instead of
//! halving; the subdivision and the Newton step are Toth 1985's and
//! Martin et al. 2000's). Neighbouring pieces share their corners, so the
//! bilinear pieces leave no cracks for a ray to slip through.

use super::bilinear::intersect_bilinear;
use super::bounds::gamma;
use super::shape::{AreaSample, LocalSurface};
use super::{Aabb, Ray};
use glam::{DVec2, DVec3, Vec2, Vec3};

/// Deepest halving: 2⁶ × 2⁶ pieces at most per axis pair.
const MAX_DEPTH: u32 = 12;

/// A bicubic Bézier patch in its object space.
#[derive(Clone, Debug, PartialEq)]
pub struct BezierPatch {
    /// Control points, `p[j][i]` the i-th along u of the j-th row along v.
    pub p: [[DVec3; 4]; 4],
    /// Its area (Gauss–Legendre quadrature of |∂S/∂u × ∂S/∂v|).
    area: f64,
    /// The box of the control points.
    bounds: Aabb,
    /// A piece flatter than this is intersected as a bilinear patch.
    flatness: f64,
}

/// Nodes and weights of 4-point Gauss–Legendre quadrature on [0, 1].
const GAUSS_4: [(f64, f64); 4] = [
    (0.06943184420297371, 0.17392742256872692),
    (0.33000947820757187, 0.32607257743127306),
    (0.6699905217924281, 0.32607257743127306),
    (0.9305681557970262, 0.17392742256872692),
];

/// The cubic Bernstein polynomials and their derivatives at `t`.
fn bernstein(t: f64) -> ([f64; 4], [f64; 4]) {
    let s = 1.0 - t;
    (
        [s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t],
        [
            -3.0 * s * s,
            3.0 * s * (s - 2.0 * t),
            3.0 * t * (2.0 * s - t),
            3.0 * t * t,
        ],
    )
}

/// Splits a cubic Bézier curve at t = ½ (de Casteljau).
fn split([a, b, c, d]: [DVec3; 4]) -> ([DVec3; 4], [DVec3; 4]) {
    let (ab, bc, cd) = ((a + b) * 0.5, (b + c) * 0.5, (c + d) * 0.5);
    let (abc, bcd) = ((ab + bc) * 0.5, (bc + cd) * 0.5);
    let m = (abc + bcd) * 0.5;
    ([a, ab, abc, m], [m, bcd, cd, d])
}

/// A piece of the patch: its control points and where it lies in (u, v).
#[derive(Clone, Copy)]
struct Piece {
    p: [[DVec3; 4]; 4],
    u: (f64, f64),
    v: (f64, f64),
}

impl Piece {
    fn halve_u(&self) -> (Piece, Piece) {
        let (mut a, mut b) = (self.p, self.p);
        for j in 0..4 {
            (a[j], b[j]) = split(self.p[j]);
        }
        let mid = 0.5 * (self.u.0 + self.u.1);
        (
            Piece {
                p: a,
                u: (self.u.0, mid),
                ..*self
            },
            Piece {
                p: b,
                u: (mid, self.u.1),
                ..*self
            },
        )
    }

    fn halve_v(&self) -> (Piece, Piece) {
        let (mut a, mut b) = (self.p, self.p);
        for i in 0..4 {
            let (lo, hi) = split([self.p[0][i], self.p[1][i], self.p[2][i], self.p[3][i]]);
            for j in 0..4 {
                (a[j][i], b[j][i]) = (lo[j], hi[j]);
            }
        }
        let mid = 0.5 * (self.v.0 + self.v.1);
        (
            Piece {
                p: a,
                v: (self.v.0, mid),
                ..*self
            },
            Piece {
                p: b,
                v: (mid, self.v.1),
                ..*self
            },
        )
    }

    /// How far the control points lie from the bilinear patch of the
    /// corners at their own parameters.
    fn deviation(&self) -> f64 {
        let [p00, p10, p01, p11] = self.corners();
        let mut worst: f64 = 0.0;
        for j in 0..4 {
            for i in 0..4 {
                let (s, t) = (i as f64 / 3.0, j as f64 / 3.0);
                let flat = (1.0 - t) * p00.lerp(p10, s) + t * p01.lerp(p11, s);
                worst = worst.max((self.p[j][i] - flat).length());
            }
        }
        worst
    }

    fn corners(&self) -> [DVec3; 4] {
        [self.p[0][0], self.p[0][3], self.p[3][0], self.p[3][3]]
    }

    /// Whether the ray o + t·d, t in (t_min, t_max), meets the box of the
    /// control points.
    fn may_hit(&self, o: DVec3, inv_d: DVec3, t_min: f64, t_max: f64) -> bool {
        let (mut lo, mut hi) = (self.p[0][0], self.p[0][0]);
        for row in &self.p {
            for q in row {
                lo = lo.min(*q);
                hi = hi.max(*q);
            }
        }
        let (t0, t1) = ((lo - o) * inv_d, (hi - o) * inv_d);
        // NaN (0 · ∞ on a slab's plane) is passed over by max/min.
        let near = t0.min(t1).max_element().max(t_min);
        let far = t0.max(t1).min_element().min(t_max);
        near <= far * (1.0 + 4.0 * f64::EPSILON)
    }
}

impl BezierPatch {
    /// The patch of 16 control points, row by row along v, each row along u.
    pub fn new(points: [Vec3; 16]) -> BezierPatch {
        let mut p = [[DVec3::ZERO; 4]; 4];
        for (k, q) in points.iter().enumerate() {
            p[k / 4][k % 4] = q.as_dvec3();
        }
        let bounds = Aabb::from_points(points);
        let size = (bounds.max - bounds.min).length() as f64;
        let mut patch = BezierPatch {
            p,
            area: 0.0,
            bounds,
            flatness: 1e-6 * size,
        };
        let mut area = 0.0;
        // Four nodes per axis in each of 8 × 8 cells.
        for cu in 0..8 {
            for cv in 0..8 {
                for &(x, wx) in &GAUSS_4 {
                    for &(y, wy) in &GAUSS_4 {
                        let (du, dv) = patch.tangents((cu as f64 + x) / 8.0, (cv as f64 + y) / 8.0);
                        area += wx * wy * du.cross(dv).length();
                    }
                }
            }
        }
        patch.area = area / 64.0;
        patch
    }

    /// The box of the control points, which holds the patch.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The surface area.
    pub fn area(&self) -> f32 {
        self.area as f32
    }

    /// The point S(u, v).
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        let ((bu, _), (bv, _)) = (bernstein(u), bernstein(v));
        let mut s = DVec3::ZERO;
        for (row, wv) in self.p.iter().zip(bv) {
            for (q, wu) in row.iter().zip(bu) {
                s += wu * wv * *q;
            }
        }
        s
    }

    /// ∂S/∂u and ∂S/∂v at (u, v).
    pub fn tangents(&self, u: f64, v: f64) -> (DVec3, DVec3) {
        let ((bu, du), (bv, dv)) = (bernstein(u), bernstein(v));
        let (mut su, mut sv) = (DVec3::ZERO, DVec3::ZERO);
        for (j, row) in self.p.iter().enumerate() {
            for (i, q) in row.iter().enumerate() {
                su += du[i] * bv[j] * *q;
                sv += bu[i] * dv[j] * *q;
            }
        }
        (su, sv)
    }

    /// Distance to the nearest point of the patch within the ray's
    /// interval.
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        self.intersect_uv(ray).map(|(t, _)| t as f32)
    }

    /// The nearest hit within the ray's interval: its distance and (u, v).
    pub fn intersect_uv(&self, ray: &Ray) -> Option<(f64, DVec2)> {
        let o = ray.origin.as_dvec3();
        let d = ray.dir.as_dvec3();
        let inv_d = d.recip();
        let (t_min, mut t_max) = (ray.t_min as f64, ray.t_max as f64);
        let mut best = None;
        let root = Piece {
            p: self.p,
            u: (0.0, 1.0),
            v: (0.0, 1.0),
        };
        // Depth first, each level leaving at most one piece waiting: no
        // more than MAX_DEPTH + 1 pieces are ever held, on the stack frame.
        let mut stack = [(root, 0u32); MAX_DEPTH as usize + 2];
        let mut held = 1;
        while held > 0 {
            held -= 1;
            let (piece, depth) = stack[held];
            if !piece.may_hit(o, inv_d, t_min, t_max) {
                continue;
            }
            if depth >= MAX_DEPTH || piece.deviation() <= self.flatness {
                let [p00, p10, p01, p11] = piece.corners();
                let Some((t, st)) = intersect_bilinear([p00, p10, p01, p11], o, d, t_min, t_max) else {
                    continue;
                };
                let uv = DVec2::new(
                    piece.u.0 + st.x * (piece.u.1 - piece.u.0),
                    piece.v.0 + st.y * (piece.v.1 - piece.v.0),
                );
                let (t, uv) = self.refine(o, d, t, uv).unwrap_or((t, uv));
                if t > t_min && t < t_max {
                    t_max = t;
                    best = Some((t, uv));
                }
                continue;
            }
            let (a, b) = if depth % 2 == 0 {
                piece.halve_u()
            } else {
                piece.halve_v()
            };
            stack[held] = (a, depth + 1);
            stack[held + 1] = (b, depth + 1);
            held += 2;
        }
        best
    }

    /// Newton's method on S(u, v) − (o + t·d) = 0 from (t, uv): the hit
    /// on the true surface, where it converges within the patch.
    fn refine(&self, o: DVec3, d: DVec3, t: f64, uv: DVec2) -> Option<(f64, DVec2)> {
        let (mut t, mut u, mut v) = (t, uv.x, uv.y);
        let scale = (self.bounds.max - self.bounds.min).length() as f64;
        for _ in 0..8 {
            let f = self.point(u, v) - (o + t * d);
            if f.length() <= 1e-12 * scale.max(1.0) {
                break;
            }
            let (su, sv) = self.tangents(u, v);
            // Solve [su sv −d]·(Δu, Δv, Δt) = −f by Cramer's rule.
            let det = su.dot(sv.cross(-d));
            if det.abs() < 1e-300 {
                return None;
            }
            let du = -f.dot(sv.cross(-d)) / det;
            let dv = -su.dot(f.cross(-d)) / det;
            let dt = -su.dot(sv.cross(f)) / det;
            (u, v, t) = (u + du, v + dv, t + dt);
        }
        let eps = 1e-9;
        let inside = (-eps..=1.0 + eps).contains(&u) && (-eps..=1.0 + eps).contains(&v);
        let close = (self.point(u, v) - (o + t * d)).length() <= 1e-7 * scale.max(1.0);
        (inside && close && t.is_finite()).then(|| (t, DVec2::new(u.clamp(0.0, 1.0), v.clamp(0.0, 1.0))))
    }

    /// The (u, v) of a point on (or within rounding of) the patch: the
    /// nearest of a 9 × 9 grid of the patch's points, then Gauss–Newton
    /// steps on the distance.
    pub fn uv_of(&self, p: DVec3) -> DVec2 {
        let mut best = (f64::INFINITY, DVec2::ZERO);
        for j in 0..=8 {
            for i in 0..=8 {
                let uv = DVec2::new(i as f64 / 8.0, j as f64 / 8.0);
                let dist = (self.point(uv.x, uv.y) - p).length_squared();
                if dist < best.0 {
                    best = (dist, uv);
                }
            }
        }
        let mut uv = best.1;
        for _ in 0..12 {
            let r = self.point(uv.x, uv.y) - p;
            let (su, sv) = self.tangents(uv.x, uv.y);
            // Normal equations of the 3 × 2 system [su sv]·Δ = −r.
            let (a, b, c) = (su.dot(su), su.dot(sv), sv.dot(sv));
            let det = a * c - b * b;
            if det.abs() < 1e-300 {
                break;
            }
            let (gu, gv) = (-su.dot(r), -sv.dot(r));
            let step = DVec2::new((c * gu - b * gv) / det, (a * gv - b * gu) / det);
            uv = (uv + step).clamp(DVec2::ZERO, DVec2::ONE);
            if step.length() < 1e-12 {
                break;
            }
        }
        uv
    }

    /// The surface at a point found by [`BezierPatch::intersect`].
    pub fn surface(&self, p: Vec3) -> LocalSurface {
        self.surface_at(self.uv_of(p.as_dvec3()))
    }

    /// The surface at (u, v).
    pub fn surface_at(&self, uv: DVec2) -> LocalSurface {
        let (du, dv) = self.tangents(uv.x, uv.y);
        let mut n = du.cross(dv);
        if n.length_squared() <= 1e-24 * du.length_squared().max(dv.length_squared()).powi(2) {
            // A degenerate corner (a pole, as the teapot's lid has): the
            // normal a little inside the patch.
            let inward = DVec2::new(0.5, 0.5) - uv;
            let (a, b) = self.tangents(uv.x + 1e-4 * inward.x, uv.y + 1e-4 * inward.y);
            n = a.cross(b);
        }
        let p = self.point(uv.x, uv.y).as_vec3();
        let extent = self.p.iter().flatten().fold(p.abs(), |m, c| m.max(c.abs().as_vec3()));
        LocalSurface {
            p,
            p_error: extent * gamma(16),
            n: n.normalize_or(DVec3::Z).as_vec3(),
            uv: uv.as_vec2(),
            dpdu: du.as_vec3(),
            dpdv: dv.as_vec3(),
        }
    }
}

impl BezierPatch {
    /// A point for an area light: (u, v) uniform over the square, so the
    /// density per unit area is 1/|∂S/∂u × ∂S/∂v| there ([`BezierPatch::density_at`]);
    /// `None` for a patch of no area.
    pub fn sample_area(&self, u: Vec2) -> Option<AreaSample> {
        if self.area <= 0.0 {
            return None;
        }
        Some(self.surface_at(u.as_dvec2()).into())
    }

    /// The density per unit area with which [`BezierPatch::sample_area`]
    /// draws the point `p` of the patch.
    pub fn density_at(&self, p: Vec3) -> f32 {
        let uv = self.uv_of(p.as_dvec3());
        let (du, dv) = self.tangents(uv.x, uv.y);
        let factor = du.cross(dv).length();
        if factor > 0.0 { (1.0 / factor) as f32 } else { 0.0 }
    }
}

/// Newell's teapot format (`.bpt`, as distributed with the Utah teapot
/// data): the number of patches, then for each "3 3" (the degrees) and
/// its 16 control points, one "x y z" per line, row by row. Errors name
/// the line.
pub fn parse_bpt(text: &str) -> Result<Vec<BezierPatch>, String> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty());
    let numbers = |line: usize, l: &str, n: usize| -> Result<Vec<f64>, String> {
        let v: Vec<f64> = l
            .split_whitespace()
            .map(|w| {
                w.parse::<f64>()
                    .map_err(|_| format!("line {line}: \"{w}\" is not a number"))
            })
            .collect::<Result<_, _>>()?;
        if v.len() != n || v.iter().any(|x| !x.is_finite()) {
            return Err(format!("line {line}: expected {n} finite numbers, got \"{l}\""));
        }
        Ok(v)
    };
    let (line, first) = lines.next().ok_or("the file is empty")?;
    let count = numbers(line, first, 1)?[0];
    if !((1.0..=100_000.0).contains(&count) && count.fract() == 0.0) {
        return Err(format!("line {line}: {count} is not a number of patches (1 to 100000)"));
    }
    let mut patches = Vec::with_capacity(count as usize);
    for k in 0..count as usize {
        let (line, degrees) = lines
            .next()
            .ok_or_else(|| format!("patch {} of {count}: the file ends before it", k + 1))?;
        if numbers(line, degrees, 2)? != [3.0, 3.0] {
            return Err(format!(
                "line {line}: only bicubic patches (\"3 3\") are read, got \"{degrees}\""
            ));
        }
        let mut points = [Vec3::ZERO; 16];
        for q in &mut points {
            let (line, l) = lines
                .next()
                .ok_or_else(|| format!("patch {} of {count}: the file ends in its control points", k + 1))?;
            let v = numbers(line, l, 3)?;
            *q = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
            if !q.is_finite() {
                return Err(format!("line {line}: a control point beyond single precision"));
            }
        }
        patches.push(BezierPatch::new(points));
    }
    Ok(patches)
}

/// The triangles of `patch` on an `n` × `n` grid of (u, v): positions,
/// normals and uv per vertex, and the triangles' indices (for tessellating
/// patches instead of intersecting them).
pub fn tessellate(patch: &BezierPatch, n: u32) -> (Vec<Vec3>, Vec<Vec3>, Vec<Vec2>, Vec<[u32; 3]>) {
    let n = n.max(1);
    let (mut positions, mut normals, mut uvs) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..=n {
        for i in 0..=n {
            let s = patch.surface_at(DVec2::new(i as f64 / n as f64, j as f64 / n as f64));
            positions.push(s.p);
            normals.push(s.n);
            uvs.push(s.uv);
        }
    }
    let mut indices = Vec::new();
    let at = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            indices.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            indices.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    (positions, normals, uvs, indices)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// A bent patch: a saddle with bulges.
    fn bent() -> BezierPatch {
        let mut pts = [Vec3::ZERO; 16];
        for j in 0..4 {
            for i in 0..4 {
                let (x, y) = (i as f32 - 1.5, j as f32 - 1.5);
                let z =
                    0.4 * x * y + if (i, j) == (1, 2) { 1.2 } else { 0.0 } - if (i, j) == (2, 1) { 0.9 } else { 0.0 };
                pts[4 * j + i] = Vec3::new(x, y, z);
            }
        }
        BezierPatch::new(pts)
    }

    /// A flat patch is a rectangle: its area, and rays hit it where the
    /// plane is, with (u, v) the position across it.
    #[test]
    fn a_flat_patch_is_a_rectangle() {
        let mut pts = [Vec3::ZERO; 16];
        for (k, q) in pts.iter_mut().enumerate() {
            *q = Vec3::new(2.0 * (k % 4) as f32 / 3.0, 3.0 * (k / 4) as f32 / 3.0, 1.0);
        }
        let patch = BezierPatch::new(pts);
        assert!((patch.area() - 6.0).abs() < 1e-4, "{}", patch.area());
        let ray = Ray::new(Vec3::new(0.5, 2.4, 5.0), Vec3::new(0.0, 0.0, -1.0));
        let (t, uv) = patch.intersect_uv(&ray).unwrap();
        assert!((t - 4.0).abs() < 1e-9, "{t}");
        assert!((uv - DVec2::new(0.25, 0.8)).length() < 1e-6, "{uv}");
        assert!(patch.intersect(&Ray::new(Vec3::new(2.1, 1.0, 5.0), -Vec3::Z)).is_none());
        let s = patch.surface(Vec3::new(0.5, 2.4, 1.0));
        assert!((s.n.abs() - Vec3::Z).length() < 1e-6 && (s.uv - Vec2::new(0.25, 0.8)).length() < 1e-6);
    }

    /// Every hit lies on the surface (S(u, v) is the ray's point), and no
    /// point of a fine grid of the patch that a ray passes first is
    /// missed: rays aimed at random points of the patch hit it at or
    /// before them.
    #[test]
    fn rays_aimed_at_the_patch_hit_it_on_the_surface() {
        let patch = bent();
        let mut rng = Pcg32::new(7, 1);
        for _ in 0..3000 {
            let (u, v) = (rng.next_f32() as f64, rng.next_f32() as f64);
            let target = patch.point(u, v);
            let origin = DVec3::new(
                8.0 * rng.next_f32() as f64 - 4.0,
                8.0 * rng.next_f32() as f64 - 4.0,
                if rng.next_f32() < 0.5 { 6.0 } else { -6.0 },
            );
            let dir = (target - origin).normalize();
            let ray = Ray::new(origin.as_vec3(), dir.as_vec3());
            let (t, uv) = patch.intersect_uv(&ray).expect("a ray aimed at the patch hits it");
            let expected = (target - origin).length();
            assert!(t <= expected + 1e-4, "hit at {t}, the aimed point at {expected}");
            let on = patch.point(uv.x, uv.y);
            let p = origin + t * dir;
            assert!((on - p).length() < 1e-5, "hit {p} but S(uv) {on}");
        }
    }

    /// The patch against a fine tessellation of itself: the same hits to
    /// the tessellation's error, on random rays through its box.
    #[test]
    fn the_patch_agrees_with_its_fine_tessellation() {
        let patch = bent();
        let (positions, _, _, indices) = tessellate(&patch, 256);
        let tri_hit = |o: Vec3, d: Vec3| -> Option<f32> {
            let mut best: Option<f32> = None;
            for tri in &indices {
                let [a, b, c] = tri.map(|i| positions[i as usize]);
                let (e1, e2) = (b - a, c - a);
                let h = d.cross(e2);
                let det = e1.dot(h);
                if det.abs() < 1e-12 {
                    continue;
                }
                let s = o - a;
                let u = s.dot(h) / det;
                let q = s.cross(e1);
                let v = d.dot(q) / det;
                let t = e2.dot(q) / det;
                if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 1e-4 && best.is_none_or(|b| t < b) {
                    best = Some(t);
                }
            }
            best
        };
        let mut rng = Pcg32::new(3, 2);
        let (mut both, mut disagree) = (0, 0);
        for _ in 0..300 {
            let o = Vec3::new(6.0 * rng.next_f32() - 3.0, 6.0 * rng.next_f32() - 3.0, 5.0);
            let d = (Vec3::new(3.0 * rng.next_f32() - 1.5, 3.0 * rng.next_f32() - 1.5, 0.0) - o).normalize();
            match (patch.intersect(&Ray::new(o, d)), tri_hit(o, d)) {
                (Some(a), Some(b)) => {
                    both += 1;
                    assert!((a - b).abs() < 2e-3, "patch {a}, tessellation {b}");
                }
                (None, None) => {}
                // At the silhouette the two may differ by the tessellation's error.
                _ => disagree += 1,
            }
        }
        assert!(both > 100 && disagree <= 3, "{both} hits in both, {disagree} in one");
    }

    /// The area against the tessellation's.
    #[test]
    fn the_area_is_the_tessellations() {
        let patch = bent();
        let (positions, _, _, indices) = tessellate(&patch, 256);
        let area: f64 = indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        assert!(
            (patch.area() as f64 - area).abs() < 1e-4 * area,
            "{} against {area}",
            patch.area()
        );
    }

    #[test]
    fn bpt_files_are_read_and_malformed_ones_name_the_line() {
        let mut text = String::from("1\n3 3\n");
        for k in 0..16 {
            text += &format!("{} {} 0\n", k % 4, k / 4);
        }
        let patches = parse_bpt(&text).unwrap();
        assert_eq!(patches.len(), 1);
        assert!((patches[0].area() - 9.0).abs() < 1e-4);
        assert!(parse_bpt("").unwrap_err().contains("empty"));
        assert!(parse_bpt("2\n3 3\n0 0 0\n").unwrap_err().contains("patch 1 of 2"));
        assert!(parse_bpt("1\n2 3\n").unwrap_err().contains("line 2"));
        assert!(parse_bpt("1\n3 3\n0 0 x\n").unwrap_err().contains("line 3"));
        assert!(parse_bpt("1e9\n").unwrap_err().contains("number of patches"));
        assert!(parse_bpt("1\n3 3\n0 0 nan\n").unwrap_err().contains("line 3"));
    }
}
