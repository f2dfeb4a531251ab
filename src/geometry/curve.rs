//! Curves: cubic Bézier segments swept by a width, as pbrt-v4's `curve`
//! shape draws hair and fur. A `flat` curve is a ribbon that always faces
//! the ray; a `cylinder` curve is the same ribbon shaded as if round (its
//! normal turns across the width); a `ribbon` curve has a fixed
//! orientation given by normals at its ends.
//!
//! The intersection follows pbrt-v4 (after Nakamaru and Ohno 2002): the
//! control points go into a frame whose z axis is the ray, the segment is
//! split recursively (to a depth set by its curvature against its width)
//! while the bounds of its control points, grown by half the width, meet
//! the ray, and a piece flat enough is tested as a line: the nearest point
//! of its chord to the ray gives u, and the hit counts if it lies within
//! half the width. v runs across the width, 0 to 1.

use super::Ray;
use super::bounds::Aabb;
use super::shape::LocalSurface;
use glam::{Vec2, Vec3};

/// How a curve presents itself to rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurveKind {
    /// A ribbon facing the ray.
    Flat,
    /// A ribbon facing the ray, shaded as a tube.
    Cylinder,
    /// A ribbon whose orientation the normals at its ends give.
    Ribbon,
}

impl CurveKind {
    /// The kind by pbrt-v4's name.
    pub fn named(name: &str) -> Option<CurveKind> {
        Some(match name {
            "flat" => CurveKind::Flat,
            "cylinder" => CurveKind::Cylinder,
            "ribbon" => CurveKind::Ribbon,
            _ => return None,
        })
    }
}

/// A piece [u0, u1] of a cubic Bézier segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Curve {
    /// Control points of the piece (of the segment between u0 and u1).
    cp: [Vec3; 4],
    /// The piece of it this shape is.
    u_range: [f32; 2],
    /// Width at u = 0 and u = 1 of the whole segment.
    width: [f32; 2],
    kind: CurveKind,
    /// Unit normals at u = 0 and 1 (ribbons).
    normals: [Vec3; 2],
    /// Angle between the normals, and 1/sin of it.
    normal_angle: f32,
    inv_sin_normal_angle: f32,
}

/// Where a ray meets a curve.
#[derive(Clone, Copy, Debug)]
pub struct CurveHit {
    /// Ray parameter.
    pub t: f32,
    /// Along the curve.
    pub u: f32,
    /// Across it.
    pub v: f32,
    /// The width there (for ribbons, as seen along the ray).
    pub width: f32,
    /// The ribbon's normal there (ribbons only).
    normal: Vec3,
}

fn lerp3(t: f32, a: Vec3, b: Vec3) -> Vec3 {
    a + (b - a) * t
}

/// The point of a cubic Bézier curve at u and its derivative.
pub fn evaluate_bezier(cp: &[Vec3; 4], u: f32) -> (Vec3, Vec3) {
    let a = [lerp3(u, cp[0], cp[1]), lerp3(u, cp[1], cp[2]), lerp3(u, cp[2], cp[3])];
    let b = [lerp3(u, a[0], a[1]), lerp3(u, a[1], a[2])];
    let d = if (b[1] - b[0]).length_squared() > 0.0 {
        3.0 * (b[1] - b[0])
    } else {
        cp[3] - cp[0]
    };
    (lerp3(u, b[0], b[1]), d)
}

/// The control points of the curve between u0 and u1 (by blossoming).
fn sub_curve(cp: &[Vec3; 4], u0: f32, u1: f32) -> [Vec3; 4] {
    let blossom = |a: f32, b: f32, c: f32| {
        let x = [lerp3(a, cp[0], cp[1]), lerp3(a, cp[1], cp[2]), lerp3(a, cp[2], cp[3])];
        let y = [lerp3(b, x[0], x[1]), lerp3(b, x[1], x[2])];
        lerp3(c, y[0], y[1])
    };
    [
        blossom(u0, u0, u0),
        blossom(u0, u0, u1),
        blossom(u0, u1, u1),
        blossom(u1, u1, u1),
    ]
}

/// The two halves of a cubic Bézier curve: seven points, the middle shared.
fn split_bezier(cp: &[Vec3; 4]) -> [Vec3; 7] {
    [
        cp[0],
        (cp[0] + cp[1]) / 2.0,
        (cp[0] + 2.0 * cp[1] + cp[2]) / 4.0,
        (cp[0] + 3.0 * cp[1] + 3.0 * cp[2] + cp[3]) / 8.0,
        (cp[1] + 2.0 * cp[2] + cp[3]) / 4.0,
        (cp[2] + cp[3]) / 2.0,
        cp[3],
    ]
}

fn control_bounds(cp: &[Vec3]) -> Aabb {
    let min = cp.iter().fold(Vec3::splat(f32::INFINITY), |m, p| m.min(*p));
    let max = cp.iter().fold(Vec3::splat(f32::NEG_INFINITY), |m, p| m.max(*p));
    Aabb::new(min, max)
}

/// Converts control points of pbrt-v4's bases to cubic Bézier segments:
/// `bezier` of degree 3 (4 + 3n points) or 2 (3 + 2n, raised to cubic),
/// or a uniform `bspline` of degree 3 or 2 (at least degree + 1 points).
pub fn bezier_segments(points: &[Vec3], bspline: bool, degree: usize) -> Result<Vec<[Vec3; 4]>, String> {
    if degree != 2 && degree != 3 {
        return Err(format!("degree {degree}: only 2 and 3 are supported"));
    }
    let elevate = |p: [Vec3; 3]| [p[0], lerp3(2.0 / 3.0, p[0], p[1]), lerp3(1.0 / 3.0, p[1], p[2]), p[2]];
    if !bspline {
        if points.len() < degree + 1 || (points.len() - 1 - degree) % degree != 0 {
            return Err(format!(
                "{} control points: a degree-{degree} Bézier curve takes {} + n·{degree}",
                points.len(),
                degree + 1
            ));
        }
        return Ok(points
            .windows(degree + 1)
            .step_by(degree)
            .map(|w| {
                if degree == 3 {
                    [w[0], w[1], w[2], w[3]]
                } else {
                    elevate([w[0], w[1], w[2]])
                }
            })
            .collect());
    }
    if points.len() < degree + 1 {
        return Err(format!(
            "{} control points: a degree-{degree} b-spline takes at least {}",
            points.len(),
            degree + 1
        ));
    }
    Ok(points
        .windows(degree + 1)
        .map(|w| {
            if degree == 2 {
                // The quadratic's Bézier points are the midpoints of its legs.
                elevate([lerp3(0.5, w[0], w[1]), w[1], lerp3(0.5, w[1], w[2])])
            } else {
                let p122 = lerp3(2.0 / 3.0, w[0], w[1]);
                let p223 = lerp3(1.0 / 3.0, w[1], w[2]);
                let p233 = lerp3(2.0 / 3.0, w[1], w[2]);
                let p334 = lerp3(1.0 / 3.0, w[2], w[3]);
                [lerp3(0.5, p122, p223), p223, p233, lerp3(0.5, p233, p334)]
            }
        })
        .collect())
}

/// An orthonormal frame whose z axis is `dir`, its y axis as near `up` as
/// it can be (pbrt-v4's `LookAt`): rows of the rotation into it.
fn ray_frame(dir: Vec3, up: Vec3) -> [Vec3; 3] {
    let z = dir.normalize();
    let x = up.normalize().cross(z).normalize();
    let y = z.cross(x);
    [x, y, z]
}

impl Curve {
    /// The segment `cp` of widths `width0` to `width1`, split into
    /// 2^`split_depth` pieces (pbrt-v4's `splitdepth`, so that each piece
    /// has tight bounds). Ribbons take `normals` at the segment's ends.
    pub fn pieces(
        cp: [Vec3; 4],
        width0: f32,
        width1: f32,
        kind: CurveKind,
        normals: Option<[Vec3; 2]>,
        split_depth: u32,
    ) -> Vec<Curve> {
        let normals = normals.map_or([Vec3::Z; 2], |n| n.map(|v| v.normalize_or_zero()));
        let normal_angle = normals[0].dot(normals[1]).clamp(-1.0, 1.0).acos();
        let n = 1u32 << split_depth.min(10);
        (0..n)
            .map(|i| Curve {
                cp: sub_curve(&cp, i as f32 / n as f32, (i + 1) as f32 / n as f32),
                u_range: [i as f32 / n as f32, (i + 1) as f32 / n as f32],
                width: [width0, width1],
                kind,
                normals,
                normal_angle,
                inv_sin_normal_angle: 1.0 / normal_angle.sin(),
            })
            .collect()
    }

    fn width_at(&self, u: f32) -> f32 {
        self.width[0] + (self.width[1] - self.width[0]) * u
    }

    /// Object-space bounds of the piece, grown by half its width.
    pub fn bounds(&self) -> Aabb {
        let [u0, u1] = self.u_range;
        let b = control_bounds(&self.cp);
        let half = Vec3::splat(0.5 * self.width_at(u0).max(self.width_at(u1)));
        Aabb::new(b.min - half, b.max + half)
    }

    /// pbrt-v4's area: the control polygon's length times the mean width.
    pub fn area(&self) -> f32 {
        let [u0, u1] = self.u_range;
        let length: f32 = self.cp.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        length * 0.5 * (self.width_at(u0) + self.width_at(u1))
    }

    /// Distance to the nearest hit within the ray's interval.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        self.hit(ray).map(|h| h.t)
    }

    /// The nearest hit within the ray's interval.
    pub fn hit(&self, ray: &Ray) -> Option<CurveHit> {
        let [u0, u1] = self.u_range;
        let cp_obj = self.cp;
        let mut up = ray.dir.cross(cp_obj[3] - cp_obj[0]);
        if up.length_squared() == 0.0 {
            up = crate::sampling::warp::orthonormal_basis(ray.dir.normalize()).0;
        }
        if ray.dir.length_squared() == 0.0 || !up.is_finite() {
            return None;
        }
        let frame = ray_frame(ray.dir, up);
        let to_ray = |p: Vec3| {
            let d = p - ray.origin;
            Vec3::new(frame[0].dot(d), frame[1].dot(d), frame[2].dot(d))
        };
        let cp = cp_obj.map(to_ray);
        let ray_length = ray.dir.length();
        let z_max = ray_length * ray.t_max;
        let max_width = self.width_at(u0).max(self.width_at(u1));
        if !overlaps_ray(&cp, max_width, z_max) {
            return None;
        }
        // Depth of refinement: the curvature against a twentieth of the
        // width (pbrt-v4's bound).
        let mut l0 = 0.0f32;
        for i in 0..2 {
            let d = (cp[i] - 2.0 * cp[i + 1] + cp[i + 2]).abs();
            l0 = l0.max(d.max_element());
        }
        let depth = if l0 > 0.0 {
            let eps = self.width[0].max(self.width[1]) * 0.05;
            let r = (std::f32::consts::SQRT_2 * 6.0 * l0 / (8.0 * eps)).log2().floor() as i32 / 2;
            r.clamp(0, 10)
        } else {
            0
        };
        let mut best: Option<CurveHit> = None;
        self.recurse(ray, &cp, u0, u1, depth, ray_length, &mut best);
        best
    }

    #[allow(clippy::too_many_arguments)]
    fn recurse(
        &self,
        ray: &Ray,
        cp: &[Vec3; 4],
        u0: f32,
        u1: f32,
        depth: i32,
        ray_length: f32,
        best: &mut Option<CurveHit>,
    ) {
        let z_max = ray_length * best.map_or(ray.t_max, |h| h.t);
        if depth > 0 {
            let split = split_bezier(cp);
            let u = [u0, 0.5 * (u0 + u1), u1];
            for seg in 0..2 {
                let piece = [
                    split[3 * seg],
                    split[3 * seg + 1],
                    split[3 * seg + 2],
                    split[3 * seg + 3],
                ];
                let max_width = self.width_at(u[seg]).max(self.width_at(u[seg + 1]));
                if overlaps_ray(&piece, max_width, z_max) {
                    self.recurse(ray, &piece, u[seg], u[seg + 1], depth - 1, ray_length, best);
                }
            }
            return;
        }
        // The ray (the origin of the projection) must lie between the
        // perpendiculars to the tangents at the piece's ends.
        let edge = (cp[1].y - cp[0].y) * -cp[0].y + cp[0].x * (cp[0].x - cp[1].x);
        if edge < 0.0 {
            return;
        }
        let edge = (cp[2].y - cp[3].y) * -cp[3].y + cp[3].x * (cp[3].x - cp[2].x);
        if edge < 0.0 {
            return;
        }
        // The point of the chord nearest the ray.
        let chord = Vec2::new(cp[3].x - cp[0].x, cp[3].y - cp[0].y);
        let denom = chord.length_squared();
        if denom == 0.0 {
            return;
        }
        let w = Vec2::new(-cp[0].x, -cp[0].y).dot(chord) / denom;
        let u = (u0 + (u1 - u0) * w).clamp(u0, u1);
        let mut width = self.width_at(u);
        let mut normal = Vec3::ZERO;
        if self.kind == CurveKind::Ribbon {
            normal = if self.normal_angle == 0.0 {
                self.normals[0]
            } else {
                let s0 = ((1.0 - u) * self.normal_angle).sin() * self.inv_sin_normal_angle;
                let s1 = (u * self.normal_angle).sin() * self.inv_sin_normal_angle;
                s0 * self.normals[0] + s1 * self.normals[1]
            };
            width *= normal.dot(ray.dir).abs() / ray_length;
        }
        let (pc, dpcdw) = evaluate_bezier(cp, w.clamp(0.0, 1.0));
        let dist2 = pc.x * pc.x + pc.y * pc.y;
        if dist2 > width * width * 0.25 || pc.z < 0.0 || pc.z > z_max {
            return;
        }
        let t = pc.z / ray_length;
        if t < ray.t_min {
            return;
        }
        let dist = dist2.sqrt();
        let edge = dpcdw.x * -pc.y + pc.x * dpcdw.y;
        let v = if edge > 0.0 {
            0.5 + dist / width
        } else {
            0.5 - dist / width
        };
        *best = Some(CurveHit { t, u, v, width, normal });
    }

    /// The surface where the ray meets the piece at `t`, found again (the
    /// traversal keeps only the distance): the point on the ray, (u, v),
    /// ∂p/∂u along the curve, ∂p/∂v across it (turned about the curve
    /// for cylinders), the normal ∂p/∂u × ∂p/∂v, and an error bound of the
    /// width, as pbrt-v4's, so that rays leaving it clear the ribbon.
    pub fn surface(&self, ray: &Ray, t: f32) -> LocalSurface {
        let mut probe = *ray;
        probe.t_max = t * (1.0 + 1e-4) + 1e-6;
        let hit = self.hit(&probe).unwrap_or(CurveHit {
            t,
            u: 0.5 * (self.u_range[0] + self.u_range[1]),
            v: 0.5,
            width: self.width_at(0.5),
            normal: self.normals[0],
        });
        // ∂p/∂u of the whole segment: the piece's derivative over its span.
        let [u0, u1] = self.u_range;
        let (_, dpdw) = evaluate_bezier(&self.cp, ((hit.u - u0) / (u1 - u0)).clamp(0.0, 1.0));
        let dpdu = dpdw / (u1 - u0);
        let dpdv = match self.kind {
            CurveKind::Ribbon => hit.normal.cross(dpdu).normalize_or_zero() * hit.width,
            _ => {
                // Across the curve, perpendicular to it and to the ray.
                let z = ray.dir.normalize();
                let across = z.cross(dpdu).normalize_or_zero();
                let across = if across == Vec3::ZERO {
                    crate::sampling::warp::orthonormal_basis(z).0
                } else {
                    across
                };
                let across = if self.kind == CurveKind::Cylinder {
                    // Turned by θ from −90° to 90° across the width.
                    let theta = (-90.0 + 180.0 * hit.v).to_radians();
                    let axis = dpdu.normalize_or_zero();
                    let (s, c) = (-theta).sin_cos();
                    across * c + axis.cross(across) * s + axis * axis.dot(across) * (1.0 - c)
                } else {
                    across
                };
                across * hit.width
            }
        };
        let n = dpdu.cross(dpdv).normalize_or_zero();
        LocalSurface {
            p: ray.at(hit.t),
            p_error: Vec3::splat(hit.width),
            n: if n == Vec3::ZERO { -ray.dir.normalize() } else { n },
            uv: Vec2::new(hit.u, hit.v),
            dpdu,
            dpdv,
        }
    }
}

/// Whether the bounds of control points in the ray's frame, grown by half
/// `width`, meet the ray's segment [0, z_max] on the z axis.
fn overlaps_ray(cp: &[Vec3; 4], width: f32, z_max: f32) -> bool {
    let b = control_bounds(cp);
    let h = 0.5 * width;
    b.min.x - h <= 0.0
        && b.max.x + h >= 0.0
        && b.min.y - h <= 0.0
        && b.max.y + h >= 0.0
        && b.max.z + h >= 0.0
        && b.min.z - h <= z_max
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(kind: CurveKind, width: f32) -> Vec<Curve> {
        let cp = [
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(-1.0 / 3.0, 0.0, 0.0),
            Vec3::new(1.0 / 3.0, 0.0, 0.0),
            Vec3::X,
        ];
        Curve::pieces(cp, width, width, kind, Some([Vec3::Z, Vec3::Z]), 2)
    }

    fn nearest(pieces: &[Curve], ray: &Ray) -> Option<CurveHit> {
        pieces
            .iter()
            .filter_map(|c| c.hit(ray))
            .min_by(|a, b| a.t.total_cmp(&b.t))
    }

    /// A straight flat curve of width 0.2 along x is a strip |y| < 0.1
    /// facing every ray: hit at its centre line's depth, u along it, v
    /// across it.
    #[test]
    fn a_straight_curve_is_a_strip_facing_the_ray() {
        let pieces = straight(CurveKind::Flat, 0.2);
        for (x, y) in [(-0.9f32, 0.0f32), (-0.5, 0.05), (0.3, -0.08), (0.95, 0.099)] {
            let ray = Ray::new(Vec3::new(x, y, 5.0), Vec3::new(0.0, 0.0, -2.0));
            let h = nearest(&pieces, &ray).unwrap_or_else(|| panic!("({x}, {y}) missed"));
            assert!((h.t - 2.5).abs() < 1e-4, "t {}", h.t);
            assert!((h.u - (x + 1.0) / 2.0).abs() < 1e-3, "u {} at x {x}", h.u);
            assert!(
                (h.v - (0.5 + y / 0.2).clamp(0.0, 1.0)).abs() < 1e-3 || (h.v - (0.5 - y / 0.2)).abs() < 1e-3,
                "v {}",
                h.v
            );
        }
        for (x, y) in [(0.0f32, 0.11f32), (0.5, -0.12), (1.2, 0.0), (-1.05, 0.0)] {
            let ray = Ray::new(Vec3::new(x, y, 5.0), Vec3::new(0.0, 0.0, -1.0));
            assert!(nearest(&pieces, &ray).is_none(), "({x}, {y}) hit");
        }
        // Seen edge-on along y, a flat curve still faces the ray.
        let ray = Ray::new(Vec3::new(0.2, -5.0, 0.05), Vec3::Y);
        assert!((nearest(&pieces, &ray).expect("hit").t - 5.0).abs() < 1e-4);
        // Behind the ray's interval: no hit.
        let mut short = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
        short.t_max = 4.9;
        assert!(nearest(&pieces, &short).is_none());
    }

    /// A bent curve: hits lie within half the width of the curve's own
    /// points, and rays far from it miss.
    #[test]
    fn hits_lie_on_the_curve_within_half_its_width() {
        let cp = [
            Vec3::ZERO,
            Vec3::new(1.0, 1.0, 0.2),
            Vec3::new(2.0, -1.0, -0.2),
            Vec3::new(3.0, 0.0, 0.0),
        ];
        let pieces = Curve::pieces(cp, 0.1, 0.05, CurveKind::Cylinder, None, 3);
        let mut hits = 0;
        let mut rng = crate::sampling::rng::Pcg32::new(5, 0);
        for _ in 0..2000 {
            let o = Vec3::new(-0.2 + 3.4 * rng.next_f32(), -1.0 + 2.0 * rng.next_f32(), 4.0);
            let ray = Ray::new(o, -Vec3::Z);
            if let Some(h) = nearest(&pieces, &ray) {
                hits += 1;
                let (p, _) = evaluate_bezier(&cp, h.u);
                let at = ray.at(h.t);
                let across = (at - p).truncate().length();
                let width = 0.1 + (0.05 - 0.1) * h.u;
                assert!(
                    across <= 0.5 * width * 1.05 + 1e-3,
                    "{across} from the curve at u {}",
                    h.u
                );
                assert!((0.0..=1.0).contains(&h.v));
                // Its surface: the normal perpendicular to the curve.
                let ls = pieces
                    .iter()
                    .find(|c| c.hit(&ray).is_some_and(|x| x.t == h.t))
                    .unwrap()
                    .surface(&ray, h.t);
                assert!(ls.n.dot(ls.dpdu.normalize()).abs() < 1e-3, "{} {}", ls.n, ls.dpdu);
                assert!((ls.uv - Vec2::new(h.u, h.v)).length() < 1e-5);
            }
        }
        assert!(hits > 20, "{hits} hits");
    }

    /// A ribbon facing up is hit from above across its full width and not
    /// at all edge-on.
    #[test]
    fn ribbons_keep_their_orientation() {
        let pieces = straight(CurveKind::Ribbon, 0.2);
        let down = Ray::new(Vec3::new(0.0, 0.09, 3.0), -Vec3::Z);
        let h = nearest(&pieces, &down).expect("facing: hit");
        let ls = pieces
            .iter()
            .find_map(|c| c.hit(&down).map(|_| c.surface(&down, h.t)))
            .unwrap();
        assert!(ls.n.z.abs() > 0.999, "{}", ls.n);
        let edge_on = Ray::new(Vec3::new(0.0, -3.0, 0.01), Vec3::Y);
        assert!(nearest(&pieces, &edge_on).is_none());
    }

    #[test]
    fn bases_and_degrees_become_cubic_bezier_segments() {
        let p: Vec<Vec3> = (0..7).map(|i| Vec3::new(i as f32, (i * i) as f32, 0.0)).collect();
        assert_eq!(bezier_segments(&p, false, 3).unwrap().len(), 2);
        assert_eq!(bezier_segments(&p, false, 2).unwrap().len(), 3);
        assert_eq!(bezier_segments(&p, true, 3).unwrap().len(), 4);
        assert_eq!(bezier_segments(&p, true, 2).unwrap().len(), 5);
        assert!(bezier_segments(&p[..6], false, 3).unwrap_err().contains("4 + n·3"));
        assert!(bezier_segments(&p, false, 4).is_err());
        // A quadratic raised to cubic is the same curve; the b-spline
        // segments join where the spline passes.
        let q = bezier_segments(&p[..3], false, 2).unwrap()[0];
        let (mid, _) = evaluate_bezier(&q, 0.5);
        assert!((mid - (0.25 * p[0] + 0.5 * p[1] + 0.25 * p[2])).length() < 1e-5);
        let s = bezier_segments(&p, true, 3).unwrap();
        assert!((s[0][3] - s[1][0]).length() < 1e-5);
        assert!((s[0][3] - (p[1] + 4.0 * p[2] + p[3]) / 6.0).length() < 1e-4);
    }
}
