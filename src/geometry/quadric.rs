//! Quadrics with partial sweeps, as pbrt's shapes (Pharr et al.,
//! "Physically Based Rendering", chapter 3 (v3) and 6 (v4)): spheres,
//! cylinders, cones, paraboloids and hyperboloids cut to a range of heights
//! `z_min..z_max` and of angles `0..phi_max` about the z axis, and disks
//! with a hole (annuli), also cut by `phi_max`.
//!
//! Every one of the first five is a surface of revolution about z whose
//! squared radius is a quadratic in the height, x² + y² = α z² + β z + γ:
//! a sphere of radius R is (−1, 0, R²), a cylinder (0, 0, R²), the cone of
//! base radius R at z = 0 and apex at z = h is k(h − z)² with k = (R/h)²,
//! the paraboloid whose rim of radius R is at z_max is (0, R²/z_max, 0),
//! and the hyperboloid swept by the segment p1–p2 has the quadratic of
//! that segment's squared distance from the axis. So one intersection
//! serves them all: the ray o + t·d in that equation is a quadratic in t,
//! solved in double precision; a root counts where its point lies within
//! the heights and the angle, the second root where the first does not.
//! The normal is the gradient (x, y, −(α z + β/2)), outwards.

use super::bounds::{Aabb, gamma};
use super::ray::Ray;
use super::roots::quadratic_roots;
use super::shape::{AreaSample, LocalSurface};
use glam::{DVec3, Vec2, Vec3};
use std::f64::consts::TAU;

/// A cut quadric in its own object space (axis z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Quadric {
    /// x² + y² = α z² + β z + γ for z in `z_min..=z_max`, φ ≤ `phi_max`.
    Revolution {
        /// α.
        alpha: f64,
        /// β.
        beta: f64,
        /// γ.
        gamma: f64,
        /// Lowest height.
        z_min: f64,
        /// Highest height.
        z_max: f64,
        /// Largest angle about z, radians in (0, 2π].
        phi_max: f64,
    },
    /// The ring `inner ≤ r ≤ outer` of the plane z = `height`, φ ≤ `phi_max`.
    Annulus {
        /// Its height.
        height: f64,
        /// Radius of the hole.
        inner: f64,
        /// Outer radius.
        outer: f64,
        /// Largest angle about z, radians.
        phi_max: f64,
    },
}

fn check_phi(phi_max_degrees: f32) -> Result<f64, String> {
    if phi_max_degrees.is_finite() && phi_max_degrees > 0.0 {
        Ok((phi_max_degrees.min(360.0) as f64).to_radians())
    } else {
        Err(format!(
            "phimax must be a positive angle in degrees, got {phi_max_degrees}"
        ))
    }
}

fn check_heights(z_min: f32, z_max: f32) -> Result<(f64, f64), String> {
    if !(z_min.is_finite() && z_max.is_finite()) {
        return Err("zmin and zmax must be finite".into());
    }
    let (lo, hi) = (z_min.min(z_max) as f64, z_min.max(z_max) as f64);
    if lo == hi {
        return Err(format!("zmin and zmax are both {lo}: the surface has no height"));
    }
    Ok((lo, hi))
}

fn positive(what: &str, x: f32) -> Result<f64, String> {
    if x.is_finite() && x > 0.0 {
        Ok(x as f64)
    } else {
        Err(format!("{what} must be a positive number, got {x}"))
    }
}

impl Quadric {
    /// A sphere of `radius` about the origin cut to heights `z_min..z_max`
    /// (clamped to the sphere) and angles up to `phi_max` degrees.
    pub fn sphere(radius: f32, z_min: f32, z_max: f32, phi_max: f32) -> Result<Quadric, String> {
        let r = positive("a sphere's radius", radius)?;
        let (lo, hi) = check_heights(z_min.clamp(-radius, radius), z_max.clamp(-radius, radius))?;
        Ok(Quadric::Revolution {
            alpha: -1.0,
            beta: 0.0,
            gamma: r * r,
            z_min: lo,
            z_max: hi,
            phi_max: check_phi(phi_max)?,
        })
    }

    /// A cylinder of `radius` about z from `z_min` to `z_max`.
    pub fn cylinder(radius: f32, z_min: f32, z_max: f32, phi_max: f32) -> Result<Quadric, String> {
        let r = positive("a cylinder's radius", radius)?;
        let (lo, hi) = check_heights(z_min, z_max)?;
        Ok(Quadric::Revolution {
            alpha: 0.0,
            beta: 0.0,
            gamma: r * r,
            z_min: lo,
            z_max: hi,
            phi_max: check_phi(phi_max)?,
        })
    }

    /// A cone of base `radius` at z = 0 and apex at z = `height` (pbrt-v3's).
    pub fn cone(radius: f32, height: f32, phi_max: f32) -> Result<Quadric, String> {
        let r = positive("a cone's radius", radius)?;
        let h = positive("a cone's height", height)?;
        let k = (r / h) * (r / h);
        Ok(Quadric::Revolution {
            alpha: k,
            beta: -2.0 * k * h,
            gamma: k * h * h,
            z_min: 0.0,
            z_max: h,
            phi_max: check_phi(phi_max)?,
        })
    }

    /// The paraboloid x² + y² = R² z / z_max between `z_min` and `z_max`
    /// (pbrt-v3's, 0 ≤ z_min < z_max).
    pub fn paraboloid(radius: f32, z_min: f32, z_max: f32, phi_max: f32) -> Result<Quadric, String> {
        let r = positive("a paraboloid's radius", radius)?;
        let (lo, hi) = check_heights(z_min, z_max)?;
        if lo < 0.0 {
            return Err(format!("a paraboloid's heights must be 0 or more, got {lo}"));
        }
        Ok(Quadric::Revolution {
            alpha: 0.0,
            beta: r * r / hi,
            gamma: 0.0,
            z_min: lo,
            z_max: hi,
            phi_max: check_phi(phi_max)?,
        })
    }

    /// The hyperboloid swept about z by the segment `p1`–`p2` (pbrt-v3's),
    /// whose ends must differ in height.
    pub fn hyperboloid(p1: Vec3, p2: Vec3, phi_max: f32) -> Result<Quadric, String> {
        if !(p1.is_finite() && p2.is_finite()) {
            return Err("a hyperboloid's points must be finite".into());
        }
        let (a, b) = (p1.as_dvec3(), p2.as_dvec3());
        if a.z == b.z {
            return Err("a hyperboloid's two points must differ in z (one height gives a flat ring)".into());
        }
        // The segment at height z: a + s(b − a), s = (z − a.z)/(b.z − a.z);
        // its squared distance from the axis, a quadratic in z.
        let e = b - a;
        let (ex, ey) = (e.x / e.z, e.y / e.z);
        // x(z) = (a.x − ex·a.z) + ex·z, likewise y.
        let (cx, cy) = (a.x - ex * a.z, a.y - ey * a.z);
        Ok(Quadric::Revolution {
            alpha: ex * ex + ey * ey,
            beta: 2.0 * (cx * ex + cy * ey),
            gamma: cx * cx + cy * cy,
            z_min: a.z.min(b.z),
            z_max: a.z.max(b.z),
            phi_max: check_phi(phi_max)?,
        })
    }

    /// A disk of `outer` radius at `height` with a hole of `inner` radius.
    pub fn annulus(height: f32, inner: f32, outer: f32, phi_max: f32) -> Result<Quadric, String> {
        let r = positive("a disk's radius", outer)?;
        if !(inner.is_finite() && inner >= 0.0 && (inner as f64) < r) {
            return Err(format!(
                "a disk's innerradius must be at least 0 and below its radius {r}, got {inner}"
            ));
        }
        if !height.is_finite() {
            return Err("a disk's height must be finite".into());
        }
        Ok(Quadric::Annulus {
            height: height as f64,
            inner: inner as f64,
            outer: r,
            phi_max: check_phi(phi_max)?,
        })
    }

    /// Object-space bounds.
    pub fn bounds(&self) -> Aabb {
        match *self {
            Quadric::Revolution {
                alpha,
                beta,
                gamma,
                z_min,
                z_max,
                ..
            } => {
                let r2 = |z: f64| alpha * z * z + beta * z + gamma;
                let mut most = r2(z_min).max(r2(z_max));
                if alpha < 0.0 {
                    let vertex = -beta / (2.0 * alpha);
                    if (z_min..=z_max).contains(&vertex) {
                        most = most.max(r2(vertex));
                    }
                }
                let r = most.max(0.0).sqrt() as f32;
                Aabb::new(Vec3::new(-r, -r, z_min as f32), Vec3::new(r, r, z_max as f32))
            }
            Quadric::Annulus { height, outer, .. } => {
                let (h, r) = (height as f32, outer as f32);
                Aabb::new(Vec3::new(-r, -r, h), Vec3::new(r, r, h))
            }
        }
    }

    /// Distance to the first intersection within the ray's interval.
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let o = ray.origin.as_dvec3();
        let d = ray.dir.as_dvec3();
        let (t_min, t_max) = (ray.t_min as f64, ray.t_max as f64);
        match *self {
            Quadric::Revolution {
                alpha,
                beta,
                gamma,
                z_min,
                z_max,
                phi_max,
            } => {
                let a = d.x * d.x + d.y * d.y - alpha * d.z * d.z;
                let b = 2.0 * (o.x * d.x + o.y * d.y - alpha * o.z * d.z) - beta * d.z;
                let c = o.x * o.x + o.y * o.y - alpha * o.z * o.z - beta * o.z - gamma;
                let roots = quadratic_roots(a, b, c);
                for t in roots.into_iter().flatten() {
                    if t <= t_min || t > t_max {
                        continue;
                    }
                    let p = o + d * t;
                    if p.z < z_min || p.z > z_max || angle(p) > phi_max {
                        continue;
                    }
                    return Some(t as f32);
                }
                None
            }
            Quadric::Annulus {
                height,
                inner,
                outer,
                phi_max,
            } => {
                if d.z == 0.0 {
                    return None;
                }
                let t = (height - o.z) / d.z;
                if t <= t_min || t > t_max {
                    return None;
                }
                let p = o + d * t;
                let r2 = p.x * p.x + p.y * p.y;
                if r2 > outer * outer || r2 < inner * inner || angle(p) > phi_max {
                    return None;
                }
                Some(t as f32)
            }
        }
    }

    /// The surface at a point found by [`Quadric::intersect`]: (u, v) are
    /// the angle over φ_max and the height (revolutions) or radius
    /// (annuli) over their ranges, as pbrt's.
    pub fn surface(&self, p: Vec3) -> LocalSurface {
        let q = p.as_dvec3();
        let phi = angle(q);
        let (n, uv, dpdu, dpdv) = match *self {
            Quadric::Revolution {
                alpha,
                beta,
                z_min,
                z_max,
                phi_max,
                ..
            } => {
                let n = DVec3::new(q.x, q.y, -(alpha * q.z + 0.5 * beta));
                let dpdu = DVec3::new(-q.y, q.x, 0.0) * phi_max;
                // dr²/dz = 2αz + β, so d(x, y)/dz = (x, y)·(2αz + β)/(2r²).
                let r2 = q.x * q.x + q.y * q.y;
                let slope = if r2 > 0.0 {
                    (2.0 * alpha * q.z + beta) / (2.0 * r2)
                } else {
                    0.0
                };
                let dpdv = DVec3::new(q.x * slope, q.y * slope, 1.0) * (z_max - z_min);
                let v = (q.z - z_min) / (z_max - z_min);
                (n, Vec2::new((phi / phi_max) as f32, v as f32), dpdu, dpdv)
            }
            Quadric::Annulus {
                inner, outer, phi_max, ..
            } => {
                let dist = (q.x * q.x + q.y * q.y).sqrt();
                let dpdu = DVec3::new(-q.y, q.x, 0.0) * phi_max;
                let radial = if dist > 0.0 {
                    DVec3::new(q.x, q.y, 0.0) / dist
                } else {
                    DVec3::X
                };
                let dpdv = radial * (inner - outer);
                let v = (outer - dist) / (outer - inner);
                (DVec3::Z, Vec2::new((phi / phi_max) as f32, v as f32), dpdu, dpdv)
            }
        };
        LocalSurface {
            p,
            // The root was found in double precision; what remains is the
            // point's rounding to single precision.
            p_error: p.abs() * gamma(4),
            n: n.normalize_or(DVec3::Z).as_vec3(),
            uv,
            dpdu: dpdu.as_vec3(),
            dpdv: dpdv.as_vec3(),
        }
    }

    /// Surface area (0 where it cannot be sampled by area, which only a
    /// degenerate surface gives).
    pub fn area(&self) -> f32 {
        match *self {
            Quadric::Revolution {
                alpha,
                beta,
                gamma,
                z_min,
                z_max,
                phi_max,
            } => match AreaProfile::new(alpha, beta, gamma) {
                Some(s) => {
                    let a = phi_max * (s.antiderivative(z_max) - s.antiderivative(z_min));
                    if a.is_finite() && a > 0.0 { a as f32 } else { 0.0 }
                }
                None => 0.0,
            },
            Quadric::Annulus {
                inner, outer, phi_max, ..
            } => (0.5 * phi_max * (outer * outer - inner * inner)) as f32,
        }
    }

    /// A point uniformly distributed by area, where [`Quadric::area`] is
    /// not 0.
    pub fn sample_area(&self, u: Vec2) -> Option<AreaSample> {
        if self.area() == 0.0 {
            return None;
        }
        let (u0, u1) = (u.x as f64, u.y as f64);
        let p = match *self {
            Quadric::Revolution {
                alpha,
                beta,
                gamma,
                z_min,
                z_max,
                phi_max,
            } => {
                // Uniform in angle, and in height with the density of the
                // area per unit height.
                let profile = AreaProfile::new(alpha, beta, gamma)?;
                let z = profile.height_at_share(z_min, z_max, u0);
                let r = (alpha * z * z + beta * z + gamma).max(0.0).sqrt();
                let phi = u1 * phi_max;
                DVec3::new(r * phi.cos(), r * phi.sin(), z)
            }
            Quadric::Annulus {
                height,
                inner,
                outer,
                phi_max,
            } => {
                let r = (inner * inner + u0 * (outer * outer - inner * inner)).sqrt();
                let phi = u1 * phi_max;
                DVec3::new(r * phi.cos(), r * phi.sin(), height)
            }
        };
        Some(self.surface(p.as_vec3()).into())
    }
}

/// The area of the surface of revolution x² + y² = q(z) = α z² + β z + γ
/// per unit height and radian: with r² = q, r·√(1 + r′²) = √(q + q′²/4) =
/// √(A z² + B z + C) with A = α(1 + α), B = β(1 + α), C = γ + β²/4. A is
/// 0 for spheres (α = −1: Archimedes' zones), cylinders and paraboloids,
/// positive for cones and hyperboloids.
#[derive(Clone, Copy, Debug)]
struct AreaProfile {
    a: f64,
    b: f64,
    c: f64,
}

impl AreaProfile {
    /// The profile, or `None` where A < 0 (no quadric of this module).
    fn new(alpha: f64, beta: f64, gamma: f64) -> Option<AreaProfile> {
        let a = alpha * (1.0 + alpha);
        (a >= 0.0).then_some(AreaProfile {
            a,
            b: beta * (1.0 + alpha),
            c: gamma + 0.25 * beta * beta,
        })
    }

    /// The area per unit height and radian at height z.
    fn at(&self, z: f64) -> f64 {
        (self.a * z * z + self.b * z + self.c).max(0.0).sqrt()
    }

    /// An antiderivative of [`AreaProfile::at`] (the integrals of √(linear)
    /// and of √(u² + k), completed to a square in u = z + B/2A).
    fn antiderivative(&self, z: f64) -> f64 {
        let (a, b, c) = (self.a, self.b, self.c);
        if a == 0.0 {
            if b == 0.0 {
                return c.max(0.0).sqrt() * z;
            }
            let w = (b * z + c).max(0.0);
            return 2.0 / (3.0 * b) * w * w.sqrt();
        }
        let u = z + b / (2.0 * a);
        let k = (c - b * b / (4.0 * a)) / a;
        let root = (u * u + k).max(0.0).sqrt();
        // A cone (k = 0) has no logarithm: its profile is linear in u.
        let log = if k == 0.0 { 0.0 } else { k * (u + root).abs().ln() };
        0.5 * a.sqrt() * (u * root + log)
    }

    /// The height below which lies `share` of the area between `z_min` and
    /// `z_max`: Newton's method on the antiderivative, kept inside a
    /// shrinking bracket by bisection. Linear for a constant profile
    /// (spheres and cylinders).
    fn height_at_share(&self, z_min: f64, z_max: f64, share: f64) -> f64 {
        if self.a == 0.0 && self.b == 0.0 {
            return z_min + share * (z_max - z_min);
        }
        let f0 = self.antiderivative(z_min);
        let target = share * (self.antiderivative(z_max) - f0);
        let (mut lo, mut hi) = (z_min, z_max);
        let mut z = z_min + share * (z_max - z_min);
        for _ in 0..64 {
            let g = self.antiderivative(z) - f0 - target;
            if g > 0.0 {
                hi = z;
            } else {
                lo = z;
            }
            let mut next = z - g / self.at(z);
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            let done = (next - z).abs() <= 1e-14 * (1.0 + z.abs());
            z = next;
            if done {
                break;
            }
        }
        z.clamp(z_min, z_max)
    }
}

/// The angle of `p` about z in [0, 2π).
fn angle(p: DVec3) -> f64 {
    let phi = p.y.atan2(p.x);
    if phi < 0.0 { phi + TAU } else { phi }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn ray_at(rng: &mut Pcg32, half: f32) -> Ray {
        let o = crate::sampling::warp::sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32())) * 6.0;
        let target = Vec3::new(
            (rng.next_f32() - 0.5) * 2.0 * half,
            (rng.next_f32() - 0.5) * 2.0 * half,
            (rng.next_f32() - 0.5) * 2.0 * half,
        );
        Ray::new(o, target - o)
    }

    #[test]
    fn hits_lie_on_the_surface_within_the_cuts() {
        let shapes = [
            Quadric::sphere(1.5, -0.5, 1.2, 270.0).unwrap(),
            Quadric::cylinder(1.0, -1.0, 0.5, 200.0).unwrap(),
            Quadric::cone(1.2, 2.0, 300.0).unwrap(),
            Quadric::paraboloid(1.0, 0.2, 1.5, 360.0).unwrap(),
            Quadric::hyperboloid(Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, 1.0), 360.0).unwrap(),
            Quadric::annulus(0.3, 0.5, 1.5, 250.0).unwrap(),
        ];
        let mut rng = Pcg32::new(6, 6);
        for (k, s) in shapes.iter().enumerate() {
            let b = s.bounds();
            let mut hits = 0;
            for _ in 0..2000 {
                let ray = ray_at(&mut rng, 1.5);
                let Some(t) = s.intersect(&ray) else { continue };
                hits += 1;
                let p = ray.at(t).as_dvec3();
                let slack = Vec3::splat(1e-5);
                let grown = Aabb::new(b.min - slack, b.max + slack);
                assert!(grown.contains(p.as_vec3()), "shape {k}: {p} outside its bounds");
                match *s {
                    Quadric::Revolution {
                        alpha,
                        beta,
                        gamma,
                        z_min,
                        z_max,
                        phi_max,
                    } => {
                        let f = p.x * p.x + p.y * p.y - (alpha * p.z * p.z + beta * p.z + gamma);
                        assert!(f.abs() < 1e-4, "shape {k}: off the surface by {f}");
                        assert!(p.z >= z_min - 1e-5 && p.z <= z_max + 1e-5);
                        assert!(angle(p) <= phi_max + 1e-5);
                    }
                    Quadric::Annulus { height, .. } => assert!((p.z - height).abs() < 1e-5),
                }
                // The normal is perpendicular to both tangents and they
                // are where the (u, v) parametrisation says.
                let ls = s.surface(ray.at(t));
                assert!(ls.n.dot(ls.dpdu.normalize_or_zero()).abs() < 1e-3, "shape {k}");
                assert!(ls.n.dot(ls.dpdv.normalize_or_zero()).abs() < 1e-3, "shape {k}");
                assert!((0.0..=1.0001).contains(&ls.uv.x) && (-1e-4..=1.0001).contains(&ls.uv.y));
            }
            assert!(hits > 200, "shape {k}: {hits} hits");
        }
    }

    #[test]
    fn cuts_let_rays_through_to_the_far_side() {
        // A hemisphere (z ≥ 0): a ray from below up the axis meets the
        // inside of the cap; a half cylinder (φ ≤ 180°) is entered from
        // -y through its missing half.
        let cap = Quadric::sphere(1.0, 0.0, 1.0, 360.0).unwrap();
        let t = cap.intersect(&Ray::new(Vec3::new(0.0, 0.0, -3.0), Vec3::Z)).unwrap();
        assert!((t - 4.0).abs() < 1e-5);
        let half = Quadric::cylinder(1.0, -1.0, 1.0, 180.0).unwrap();
        let t = half.intersect(&Ray::new(Vec3::new(0.0, -3.0, 0.0), Vec3::Y)).unwrap();
        assert!((t - 4.0).abs() < 1e-5, "{t}");
        // The annulus's hole lets the axis through.
        let ring = Quadric::annulus(0.0, 0.5, 1.0, 360.0).unwrap();
        assert!(ring.intersect(&Ray::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z)).is_none());
        assert!(ring.intersect(&Ray::new(Vec3::new(0.7, 0.0, 2.0), -Vec3::Z)).is_some());
    }

    #[test]
    fn areas_and_area_samples_agree() {
        // The mean of 1/pdf over a stratified grid of samples is the
        // area; every sample is on the surface.
        let shapes = [
            (
                Quadric::sphere(2.0, -1.0, 1.5, 200.0).unwrap(),
                200f64.to_radians() * 2.0 * 2.5,
            ),
            (
                Quadric::cylinder(0.5, 0.0, 3.0, 90.0).unwrap(),
                90f64.to_radians() * 0.5 * 3.0,
            ),
            (
                Quadric::annulus(1.0, 0.5, 1.0, 360.0).unwrap(),
                std::f64::consts::PI * 0.75,
            ),
        ];
        for (s, area) in shapes {
            assert!((s.area() as f64 - area).abs() < 1e-5 * area, "{} vs {area}", s.area());
            let p = s.sample_area(Vec2::new(0.3, 0.8)).unwrap();
            let ray = Ray::new(p.p + p.n * 0.5, -p.n);
            let t = s.intersect(&ray).expect("a sample is on the surface");
            assert!((ray.at(t) - p.p).length() < 1e-4);
        }
    }

    /// Cones, paraboloids and hyperboloids: the area matches the closed
    /// form where there is one (a cone's lateral area πRL; Archimedes'
    /// paraboloid (π R/6h²)((R² + 4h²)^{3/2} − R³)) and a fine quadrature
    /// of the profile otherwise, and the samples are uniform by area: the
    /// share of 200 000 samples in each of 16 bands of equal height
    /// matches the band's share of the area within 4.5 standard errors
    /// of a binomial count, and every sample lies on the surface.
    #[test]
    fn curved_quadrics_are_sampled_uniformly_by_area() {
        let (r, h) = (1.5f64, 2.0f64);
        let cone = Quadric::cone(r as f32, h as f32, 360.0).unwrap();
        let paraboloid = Quadric::paraboloid(r as f32, 0.0, h as f32, 360.0).unwrap();
        let hyperboloid = Quadric::hyperboloid(Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.3, 0.8, 1.5), 250.0).unwrap();
        let cut_paraboloid = Quadric::paraboloid(1.0, 0.5, 2.0, 90.0).unwrap();
        let pi = std::f64::consts::PI;
        let closed = [
            Some(pi * r * (r * r + h * h).sqrt()),
            Some(pi * r / (6.0 * h * h) * ((r * r + 4.0 * h * h).powf(1.5) - r * r * r)),
            None,
            None,
        ];
        for (k, (q, closed)) in [cone, paraboloid, hyperboloid, cut_paraboloid]
            .into_iter()
            .zip(closed)
            .enumerate()
        {
            let Quadric::Revolution {
                alpha,
                beta,
                gamma,
                z_min,
                z_max,
                phi_max,
            } = q
            else {
                unreachable!()
            };
            // The profile by the midpoint rule, from its definition
            // r·√(1 + r′²) with r′ by a central difference.
            let radius = |z: f64| (alpha * z * z + beta * z + gamma).max(0.0).sqrt();
            let band_area = |lo: f64, hi: f64| {
                let n = 20_000;
                (0..n)
                    .map(|i| {
                        let z = lo + (hi - lo) * (i as f64 + 0.5) / n as f64;
                        let e = 1e-6 * (z_max - z_min);
                        let dr = (radius(z + e) - radius(z - e)) / (2.0 * e);
                        radius(z) * (1.0 + dr * dr).sqrt()
                    })
                    .sum::<f64>()
                    * (hi - lo)
                    / n as f64
                    * phi_max
            };
            let total = band_area(z_min, z_max);
            let area = q.area() as f64;
            assert!(
                (area - total).abs() < 1e-4 * total,
                "quadric {k}: area {area}, quadrature {total}"
            );
            if let Some(c) = closed {
                assert!((area - c).abs() < 1e-5 * c, "quadric {k}: area {area}, closed form {c}");
            }
            let bands = 16;
            let mut counts = vec![0u32; bands];
            let n = 200_000;
            let mut rng = crate::sampling::Pcg32::new(k as u64, 3);
            for i in 0..n {
                let s = q.sample_area(Vec2::new(rng.next_f32(), rng.next_f32())).unwrap();
                let z = s.p.z as f64;
                let band = (((z - z_min) / (z_max - z_min)) * bands as f64) as usize;
                counts[band.min(bands - 1)] += 1;
                if i % 5_000 == 0 {
                    let ray = Ray::new(s.p + s.n * 0.3, -s.n);
                    let t = q.intersect(&ray).expect("a sample is on the surface");
                    assert!((ray.at(t) - s.p).length() < 1e-4, "quadric {k}");
                }
            }
            for (b, &count) in counts.iter().enumerate() {
                let (lo, hi) = (
                    z_min + (z_max - z_min) * b as f64 / bands as f64,
                    z_min + (z_max - z_min) * (b + 1) as f64 / bands as f64,
                );
                let p = band_area(lo, hi) / total;
                let expected = p * n as f64;
                let sigma = (n as f64 * p * (1.0 - p)).sqrt();
                assert!(
                    (count as f64 - expected).abs() < 4.5 * sigma,
                    "quadric {k}, band {b}: {count} samples, {expected:.0} ± {sigma:.0} expected"
                );
            }
        }
    }

    #[test]
    fn bad_quadrics_are_errors() {
        assert!(Quadric::sphere(1.0, 0.5, 0.5, 360.0).is_err());
        assert!(Quadric::sphere(-1.0, -1.0, 1.0, 360.0).is_err());
        assert!(Quadric::cylinder(1.0, 0.0, 1.0, 0.0).is_err());
        assert!(Quadric::paraboloid(1.0, -1.0, 1.0, 360.0).is_err());
        assert!(Quadric::hyperboloid(Vec3::X, Vec3::Y, 360.0).is_err());
        assert!(Quadric::annulus(0.0, 1.0, 1.0, 360.0).is_err());
        assert!(Quadric::cone(1.0, f32::NAN, 360.0).is_err());
    }
}
