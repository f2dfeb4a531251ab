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

    /// Surface area where the surface can be sampled uniformly by area
    /// (spheres, cylinders and annuli); 0 for the others, which cannot
    /// emit.
    pub fn area(&self) -> f32 {
        match *self {
            // A zone of a sphere has the area of the cylinder around it
            // (Archimedes): φ_max·R·(z_max − z_min) for both.
            Quadric::Revolution {
                alpha,
                beta,
                gamma,
                z_min,
                z_max,
                phi_max,
            } if beta == 0.0 && (alpha == 0.0 || alpha == -1.0) => (phi_max * gamma.sqrt() * (z_max - z_min)) as f32,
            Quadric::Annulus {
                inner, outer, phi_max, ..
            } => (0.5 * phi_max * (outer * outer - inner * inner)) as f32,
            Quadric::Revolution { .. } => 0.0,
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
                gamma,
                z_min,
                z_max,
                phi_max,
                ..
            } => {
                // Uniform in height and angle is uniform in area for both.
                let z = z_min + u0 * (z_max - z_min);
                let r = (alpha * z * z + gamma).max(0.0).sqrt();
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
        let s = self.surface(p.as_vec3());
        Some(AreaSample {
            p: s.p,
            n: s.n,
            uv: s.uv,
        })
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
        assert_eq!(Quadric::cone(1.0, 1.0, 360.0).unwrap().area(), 0.0);
        assert!(
            Quadric::cone(1.0, 1.0, 360.0)
                .unwrap()
                .sample_area(Vec2::ZERO)
                .is_none()
        );
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
