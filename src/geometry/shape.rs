//! Analytic shapes, each defined in its own object space: sphere, infinite
//! plane, rectangle (any parallelogram), disk and axis-aligned box.
//!
//! A shape answers three questions: where a ray first meets it
//! ([`Shape::intersect`], returning only the distance, so that BVH traversal
//! stays light), what the surface looks like at that point
//! ([`Shape::surface`]), and — for area lights — how to pick a point on it
//! uniformly by area ([`Shape::sample_area`]).

use super::bounds::{Aabb, gamma};
use super::ray::Ray;
use super::real::Real;
use super::simd::{Floats, Vec3s};
use crate::sampling::warp::{orthonormal_basis, sample_disk_concentric, sample_sphere_uniform};
use glam::{DVec3, Mat3, Vec2, Vec3};
use std::f32::consts::PI;

/// A sphere given by centre and radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius (> 0).
    pub radius: f32,
    /// The orientation of its surface coordinates: the axes of the space
    /// in which u runs around +y and v from −y to +y, as columns in the
    /// sphere's space (orthonormal; the identity unless a rotation was
    /// baked into the sphere, or a reader follows another renderer's
    /// convention).
    pub uv_frame: Mat3,
}

/// An infinite plane through `point` with unit normal `normal`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// A point on the plane; the origin of its (u, v) coordinates.
    pub point: Vec3,
    /// Unit normal: the front side.
    pub normal: Vec3,
    /// Unit tangent giving the u direction (v = normal × u).
    pub u_axis: Vec3,
}

/// The parallelogram `corner + a·edge_u + b·edge_v`, a, b ∈ [0, 1]; its
/// front side is along `edge_u × edge_v`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rectangle {
    corner: Vec3,
    edge_u: Vec3,
    edge_v: Vec3,
    // Computed once, not per ray: the unit normal and the dual basis of
    // the edges, which gives (a, b) of a point in the plane by two dot
    // products. Each ray meets a wall of a room in its first test.
    normal: Vec3,
    dual_u: Vec3,
    dual_v: Vec3,
    /// The unit tangent along edge_u, perpendicular to the normal: what
    /// a surface record would compute from dp/du at every hit.
    tangent: Vec3,
}

/// A disk with centre, unit normal (front side) and radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disk {
    /// Centre.
    pub center: Vec3,
    /// Unit normal.
    pub normal: Vec3,
    /// Radius (> 0).
    pub radius: f32,
    /// Which of its surface coordinates is the angle.
    pub uv: DiskUv,
}

/// How a disk's surface coordinates follow its angle φ (from the first
/// axis of its frame towards the second) and its radius r.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DiskUv {
    /// u = φ/2π, v = 1 − r/R (pbrt's disk).
    #[default]
    AngleRadius,
    /// u = r/R, v = φ/2π (Mitsuba's disk).
    RadiusAngle,
}

/// An axis-aligned box; rotate it with a transform for an oriented one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cuboid {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

/// An open tube (no end caps) of radius `radius` around the segment
/// from `p0` to `p1`; its front side is the outside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    /// Centre of one end.
    pub p0: Vec3,
    /// Centre of the other end.
    pub p1: Vec3,
    /// Radius.
    pub radius: f32,
}

/// An analytic shape in object space.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A sphere.
    Sphere(Sphere),
    /// An infinite plane.
    Plane(Plane),
    /// A parallelogram.
    Rectangle(Rectangle),
    /// A disk.
    Disk(Disk),
    /// An axis-aligned box.
    Cuboid(Cuboid),
    /// An open cylinder.
    Cylinder(Cylinder),
    /// A signed distance function sampled on a grid over [0, 1]³.
    SdfGrid(std::sync::Arc<super::sdf_grid::SdfGrid>),
    /// A tree of signed distance functions, sphere traced.
    Sdf(std::sync::Arc<super::sdf::Sdf>),
    /// The surface f(x, y, z) = 0 of an equation, within a box.
    Implicit(std::sync::Arc<super::implicit::ImplicitSurface>),
    /// A sphere, cylinder, cone, paraboloid or hyperboloid cut to heights
    /// and angles, or a disk with a hole.
    Quadric(super::quadric::Quadric),
    /// A bilinear patch through four corners (pbrt-v4's `bilinearmesh`).
    Bilinear(super::bilinear::BilinearPatch),
    /// A piece of a cubic Bézier curve swept by a width (pbrt-v4's
    /// `curve`).
    Curve(super::curve::Curve),
    /// A bicubic Bézier patch, intersected directly.
    Bezier(std::sync::Arc<super::bezier::BezierPatch>),
}

/// The surface of a shape at a point, in the shape's object space.
#[derive(Clone, Copy, Debug)]
pub struct LocalSurface {
    /// The point, moved onto the surface where that reduces error.
    pub p: Vec3,
    /// Per-axis bound on the error of `p`.
    pub p_error: Vec3,
    /// Outward (front) normal, unit length.
    pub n: Vec3,
    /// Surface coordinates.
    pub uv: Vec2,
    /// Tangent along increasing u (not normalised; may be zero at poles).
    pub dpdu: Vec3,
    /// Tangent along increasing v (not normalised), which bump maps need.
    pub dpdv: Vec3,
}

impl From<LocalSurface> for AreaSample {
    /// The point, normal and coordinates of a surface, as a sampled point.
    fn from(s: LocalSurface) -> AreaSample {
        AreaSample {
            p: s.p,
            n: s.n,
            uv: s.uv,
        }
    }
}

/// A point sampled on a surface.
#[derive(Clone, Copy, Debug)]
pub struct AreaSample {
    /// The point.
    pub p: Vec3,
    /// Unit front normal there.
    pub n: Vec3,
    /// Surface coordinates there (for textured emission).
    pub uv: Vec2,
}

impl Plane {
    /// The plane through `point` with normal `normal` (normalised here).
    pub fn new(point: Vec3, normal: Vec3) -> Self {
        let normal = normal.normalize();
        let (u_axis, _) = orthonormal_basis(normal);
        Plane { point, normal, u_axis }
    }
}

impl Shape {
    /// Object-space bounds; `None` for the unbounded plane.
    pub fn bounds(&self) -> Option<Aabb> {
        match *self {
            Shape::Sphere(s) => Some(Aabb::new(
                s.center - Vec3::splat(s.radius),
                s.center + Vec3::splat(s.radius),
            )),
            Shape::Plane(_) => None,
            Shape::Rectangle(r) => Some(r.bounds()),
            Shape::Disk(d) => {
                // Extent of a disk along axis i is r·sqrt(1 − n_i²).
                let e = (Vec3::ONE - d.normal * d.normal).max(Vec3::ZERO);
                let half = Vec3::new(e.x.sqrt(), e.y.sqrt(), e.z.sqrt()) * d.radius;
                Some(Aabb::new(d.center - half, d.center + half))
            }
            Shape::Cuboid(c) => Some(Aabb::new(c.min, c.max)),
            Shape::Cylinder(c) => {
                // The two end circles bound the tube.
                let a = (c.p1 - c.p0).normalize();
                let e = (Vec3::ONE - a * a).max(Vec3::ZERO);
                let half = Vec3::new(e.x.sqrt(), e.y.sqrt(), e.z.sqrt()) * c.radius;
                Some(Aabb::new(c.p0 - half, c.p0 + half).union(&Aabb::new(c.p1 - half, c.p1 + half)))
            }
            Shape::SdfGrid(ref g) => Some(g.bounds()),
            Shape::Sdf(ref f) => Some(f.bounds()),
            Shape::Implicit(ref f) => Some(f.bounds()),
            Shape::Quadric(ref q) => Some(q.bounds()),
            Shape::Bilinear(ref b) => Some(b.bounds()),
            Shape::Curve(ref c) => Some(c.bounds()),
            Shape::Bezier(ref b) => Some(b.bounds()),
        }
    }

    /// Distance to the first intersection within the ray's interval.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        match self {
            Shape::Sphere(s) => s.intersect(ray),
            Shape::Plane(p) => intersect_plane(ray, p.point, p.normal),
            Shape::Rectangle(r) => r.intersect(ray),
            Shape::Disk(d) => d.intersect(ray),
            Shape::Cuboid(c) => c.intersect(ray),
            Shape::Cylinder(c) => c.intersect(ray),
            Shape::SdfGrid(g) => g.intersect(ray),
            Shape::Sdf(f) => f.intersect(ray),
            Shape::Implicit(f) => f.intersect(ray),
            Shape::Quadric(q) => q.intersect(ray),
            Shape::Bilinear(b) => b.intersect(ray),
            Shape::Curve(c) => c.intersect(ray),
            Shape::Bezier(b) => b.intersect(ray),
        }
    }

    /// The surface at a point found by [`Shape::intersect`].
    pub fn surface(&self, p: Vec3) -> LocalSurface {
        self.surface_with(p, true)
    }

    /// [`Shape::surface`], with surface coordinates only if `uv` (a
    /// sphere's (u, v) and dp/dv are then zero; the other shapes' cost
    /// little and are always there).
    pub fn surface_with(&self, p: Vec3, uv: bool) -> LocalSurface {
        match self {
            Shape::Sphere(s) => s.surface(p, uv),
            Shape::Plane(pl) => {
                let p = project_to_plane(p, pl.point, pl.normal);
                let v_axis = pl.normal.cross(pl.u_axis);
                let d = p - pl.point;
                LocalSurface {
                    p,
                    p_error: planar_error(p, pl.point),
                    n: pl.normal,
                    uv: Vec2::new(d.dot(pl.u_axis), d.dot(v_axis)),
                    dpdu: pl.u_axis,
                    dpdv: v_axis,
                }
            }
            Shape::Rectangle(r) => r.surface(p),
            Shape::Disk(d) => {
                let p = project_to_plane(p, d.center, d.normal);
                let (s, t) = orthonormal_basis(d.normal);
                let q = p - d.center;
                let (x, y) = (q.dot(s), q.dot(t));
                let phi = y.atan2(x).rem_euclid(2.0 * PI);
                let dist = (x * x + y * y).sqrt();
                let around = (-y * s + x * t) * (2.0 * PI);
                let outward = if dist > 0.0 {
                    q * (d.radius / dist)
                } else {
                    s * d.radius
                };
                let (uv, dpdu, dpdv) = match d.uv {
                    DiskUv::AngleRadius => (Vec2::new(phi / (2.0 * PI), 1.0 - dist / d.radius), around, -outward),
                    DiskUv::RadiusAngle => (Vec2::new(dist / d.radius, phi / (2.0 * PI)), outward, around),
                };
                LocalSurface {
                    p,
                    p_error: planar_error(p, d.center),
                    n: d.normal,
                    uv,
                    dpdu,
                    dpdv,
                }
            }
            Shape::Cuboid(c) => c.surface(p),
            Shape::Cylinder(c) => c.surface(p),
            Shape::SdfGrid(g) => g.surface(p),
            Shape::Sdf(f) => f.surface(p),
            Shape::Implicit(f) => f.surface(p),
            Shape::Quadric(q) => q.surface(p),
            Shape::Bilinear(b) => b.surface(p),
            Shape::Bezier(b) => b.surface(p),
            // A curve's surface depends on the ray (see
            // `Shape::surface_at_hit`); from a point alone, a ray toward
            // it along the curve's normal plane is assumed.
            Shape::Curve(c) => {
                let b = c.bounds();
                let ray = Ray::new(p + (b.max - b.min).length().max(1.0) * Vec3::Z, -Vec3::Z);
                c.surface(&ray, (ray.origin - p).length())
            }
        }
    }

    /// The surface where `ray` meets the shape at `t`: [`Shape::surface_with`]
    /// at the point, but for curves, whose surface faces the ray.
    #[inline]
    pub fn surface_at_hit(&self, ray: &Ray, t: f32, uv: bool) -> LocalSurface {
        match self {
            Shape::Curve(c) => c.surface(ray, t),
            _ => self.surface_with(ray.at(t), uv),
        }
    }

    /// The shading normal at a point of the surface, where it differs from
    /// the geometric one (a signed distance grid's smooth normals).
    #[inline]
    pub fn shading_normal(&self, p: Vec3) -> Option<Vec3> {
        match self {
            Shape::SdfGrid(g) => g.shading_normal(p),
            _ => None,
        }
    }

    /// Surface area; infinite for the plane.
    pub fn area(&self) -> f32 {
        match *self {
            Shape::Sphere(s) => 4.0 * PI * s.radius * s.radius,
            Shape::Plane(_) => f32::INFINITY,
            Shape::Rectangle(r) => r.edge_u.cross(r.edge_v).length(),
            Shape::Disk(d) => PI * d.radius * d.radius,
            Shape::Cuboid(c) => Aabb::new(c.min, c.max).surface_area(),
            Shape::Cylinder(c) => 2.0 * PI * c.radius * (c.p1 - c.p0).length(),
            // No closed form: an emitter of these is sampled by direction,
            // its area estimated for its power (`light::crofton_area`).
            Shape::SdfGrid(_) | Shape::Sdf(_) | Shape::Implicit(_) => 0.0,
            Shape::Quadric(q) => q.area(),
            Shape::Bilinear(b) => b.area(),
            Shape::Curve(ref c) => c.area(),
            Shape::Bezier(ref b) => b.area(),
        }
    }

    /// The unit tangent along u (dp/du normalised) at the point of the
    /// surface nearest `p`, where it comes cheaper than from dp/du and the
    /// normal: a rectangle's constant one, a sphere's ([`Sphere::tangent_at`]).
    #[inline]
    pub fn tangent_at(&self, p: Vec3) -> Option<Vec3> {
        match self {
            Shape::Rectangle(r) => Some(r.tangent),
            Shape::Sphere(s) => Some(s.tangent_at(p)),
            _ => None,
        }
    }

    /// A point distributed over the surface by area: uniformly (density
    /// 1/area) but on a curved bilinear patch, whose density is
    /// [`Shape::relative_area_density`]/area; `None` for the plane, which
    /// has no finite area. Its
    /// surface coordinates are found where `uv` asks for them (a textured
    /// emitter), and left zero elsewhere: for curved shapes they take
    /// inverse trigonometric functions.
    pub fn sample_area(&self, u: Vec2, uv: bool) -> Option<AreaSample> {
        let mut s = self.sample_area_point(u)?;
        s.uv = match self {
            // The sample is corner + u.x·edge_u + u.y·edge_v: its surface
            // coordinates are u itself (no need to project it back).
            Shape::Rectangle(_) => u,
            _ if uv => self.surface(s.p).uv,
            _ => Vec2::ZERO,
        };
        Some(s)
    }

    /// The density with which [`Shape::sample_area`] draws the point `p`
    /// of the surface, relative to the uniform one, 1/area: 1 but for a
    /// bilinear patch.
    #[inline]
    pub fn relative_area_density(&self, p: Vec3) -> f32 {
        match self {
            Shape::Bilinear(b) => b.density_at(p) * b.area(),
            Shape::Bezier(b) => b.density_at(p) * b.area(),
            _ => 1.0,
        }
    }

    fn sample_area_point(&self, u: Vec2) -> Option<AreaSample> {
        match *self {
            // Curves cannot emit either (nor in pbrt-v4).
            Shape::SdfGrid(_) | Shape::Sdf(_) | Shape::Implicit(_) | Shape::Curve(_) => None,
            Shape::Quadric(q) => q.sample_area(u),
            Shape::Bilinear(b) => b.sample_area(u),
            Shape::Bezier(ref b) => b.sample_area(u),
            Shape::Sphere(s) => {
                let n = sample_sphere_uniform(u);
                Some(AreaSample {
                    p: s.center + n * s.radius,
                    n,
                    uv: Vec2::ZERO,
                })
            }
            Shape::Plane(_) => None,
            Shape::Rectangle(r) => Some(AreaSample {
                p: r.corner + u.x * r.edge_u + u.y * r.edge_v,
                n: r.normal,
                uv: Vec2::ZERO,
            }),
            Shape::Disk(d) => {
                let q = sample_disk_concentric(u) * d.radius;
                let (s, t) = orthonormal_basis(d.normal);
                Some(AreaSample {
                    p: d.center + q.x * s + q.y * t,
                    n: d.normal,
                    uv: Vec2::ZERO,
                })
            }
            Shape::Cuboid(c) => {
                // Pick a face pair in proportion to its area, reusing u.x.
                let e = c.max - c.min;
                let areas = [e.y * e.z, e.x * e.z, e.x * e.y];
                let total = areas[0] + areas[1] + areas[2];
                let mut x = u.x * total;
                let mut axis = 2;
                for (i, a) in areas.iter().enumerate() {
                    if x < *a {
                        axis = i;
                        break;
                    }
                    x -= a;
                }
                let a = areas[axis].max(f32::MIN_POSITIVE);
                // Remap the remainder to [0, 1) twice: side, then position.
                let r = (x / a).clamp(0.0, 1.0);
                let (high, r) = if r < 0.5 {
                    (false, r * 2.0)
                } else {
                    (true, r * 2.0 - 1.0)
                };
                let (j, k) = ((axis + 1) % 3, (axis + 2) % 3);
                let mut p = Vec3::ZERO;
                p[axis] = if high { c.max[axis] } else { c.min[axis] };
                p[j] = c.min[j] + r.min(0.999_999_9) * e[j];
                p[k] = c.min[k] + u.y * e[k];
                let mut n = Vec3::ZERO;
                n[axis] = if high { 1.0 } else { -1.0 };
                Some(AreaSample { p, n, uv: Vec2::ZERO })
            }
            Shape::Cylinder(c) => {
                let axis = c.p1 - c.p0;
                let (s, t) = orthonormal_basis(axis.normalize());
                let phi = 2.0 * PI * u.y;
                let n = phi.cos() * s + phi.sin() * t;
                Some(AreaSample {
                    p: c.p0 + axis * u.x + n * c.radius,
                    n,
                    uv: Vec2::ZERO,
                })
            }
        }
    }
}

impl Sphere {
    /// The sphere with surface coordinates around +y.
    pub const fn new(center: Vec3, radius: f32) -> Sphere {
        Sphere {
            center,
            radius,
            uv_frame: Mat3::IDENTITY,
        }
    }

    /// Ray–sphere intersection with the refined quadratic of Haines et al.,
    /// "Precision Improvements for Ray/Sphere Intersection" (Ray Tracing
    /// Gems, ch. 7), in single precision as pbrt-v4's: its rounding in c =
    /// |o − centre|² − r² is a few ulps of the larger square, while a ray
    /// spawned from the sphere starts `p_error` (a few ulps of the centre's
    /// and the radius's magnitudes) off the surface, which moves c by
    /// about 2r·p_error, an order of magnitude more, so that the ray does
    /// not find its own start even on radii of 10⁵ (smallpt's walls).
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let c = self.center;
        let (t, hit) = sphere_distance(&SphereRay::new(ray)?, c.x, c.y, c.z, self.radius);
        hit.then_some(t)
    }

    /// The unit tangent along u at the sphere's point nearest `p`: dp/du
    /// normalised ([`sphere_tangent`]); at the poles, where dp/du
    /// vanishes, a tangent of the normal's frame.
    #[inline]
    pub fn tangent_at(&self, p: Vec3) -> Vec3 {
        let (tangent, found) = sphere_tangent::<f32>(Vec3s::splat(self.center), self.frame_lanes(), Vec3s::splat(p));
        if found != 0 {
            tangent.lane(0)
        } else {
            orthonormal_basis((p - self.center).normalize_or(Vec3::Z)).0
        }
    }

    /// [`Sphere::uv_frame`]'s columns, as the lane functions take them.
    #[inline(always)]
    fn frame_lanes(&self) -> [Vec3s<f32>; 3] {
        [self.uv_frame.x_axis, self.uv_frame.y_axis, self.uv_frame.z_axis].map(Vec3s::splat)
    }

    fn surface(&self, p: Vec3, with_uv: bool) -> LocalSurface {
        let center = Vec3s::splat(self.center);
        let (n, normal) = sphere_normal::<f32>(center, Vec3s::splat(p));
        let n = if normal != 0 {
            n
        } else {
            // Zero, or beyond single precision's range once squared.
            Vec3s::splat((p - self.center).as_dvec3().normalize_or(DVec3::Z).as_vec3())
        };
        let at = sphere_at_normal::<f32>(center, self.radius, self.frame_lanes(), n);
        let (n, local) = (n.lane(0), at.local.lane(0));
        // Longitude around +y, latitude from the south pole: v = 1 at the
        // top, in the frame of the surface coordinates.
        let uv = if with_uv {
            let phi = local.z.atan2(local.x).rem_euclid(2.0 * PI);
            Vec2::new(phi / (2.0 * PI), 0.5 + local.y.clamp(-1.0, 1.0).asin() / PI)
        } else {
            Vec2::ZERO
        };
        // v = 1/2 + θ/π for latitude θ: dp/dv = π·r·dn/dθ, which turns
        // along the meridian (undefined at the poles: a zero vector there).
        // Only bump maps read it, and only through textures that read
        // (u, v): without those it is left zero.
        let cos_lat = (local.x * local.x + local.z * local.z).sqrt();
        let dpdv = if with_uv && cos_lat > 0.0 {
            let k = -local.y / cos_lat;
            self.uv_frame * Vec3::new(k * local.x, cos_lat, k * local.z) * (PI * self.radius)
        } else {
            Vec3::ZERO
        };
        LocalSurface {
            p: at.p.lane(0),
            p_error: at.p_error.lane(0),
            n,
            uv,
            dpdu: at.dpdu.lane(0),
            dpdv,
        }
    }
}

/// The unit normal of a sphere of centre `c` at its point nearest `p`,
/// in every lane (one sphere's record, `F = f32`, or eight in vector lanes,
/// which then compute the same bits), and the bits of the lanes where it
/// is exact: those where |p − c|² is a normal number (neither zero nor
/// beyond single precision's range), which the caller treats apart.
#[inline(always)]
pub(crate) fn sphere_normal<F: Floats>(c: Vec3s<F>, p: Vec3s<F>) -> (Vec3s<F>, u32) {
    let q = p - c;
    let length_squared = q.dot(q);
    let normal = F::mask_bits(length_squared.ge(F::splat(f32::MIN_POSITIVE)))
        & !F::mask_bits(length_squared.ge(F::splat(f32::INFINITY)));
    (q.scale(F::splat(1.0) / length_squared.sqrt()), normal)
}

/// What a sphere's surface record holds at the point of unit normal `n`
/// (in lanes, as [`sphere_normal`]).
pub(crate) struct SphereAt<F> {
    /// The point, reprojected onto the sphere: it then carries only the
    /// error of this computation (pbrt-v4, section 6.8.5), in single
    /// precision as there: a few ulps of the centre's and the radius's
    /// magnitudes, which `p_error` bounds.
    pub p: Vec3s<F>,
    pub p_error: Vec3s<F>,
    /// The normal in the frame of the surface coordinates.
    pub local: Vec3s<F>,
    /// dp/du: u runs once around +y of that frame.
    pub dpdu: Vec3s<F>,
}

/// [`SphereAt`] for the sphere of centre `c`, radius `r` and frame of
/// surface coordinates `frame` (columns), at unit normal `n`.
#[inline(always)]
pub(crate) fn sphere_at_normal<F: Floats>(c: Vec3s<F>, r: F, frame: [Vec3s<F>; 3], n: Vec3s<F>) -> SphereAt<F> {
    let p = c + n.scale(r);
    let p_error = ((p - c).abs() + c.abs()).scale(F::splat(gamma(5)));
    let local = transposed_times(frame, n);
    let dpdu = frame_times(frame, around(local)).scale(F::splat(2.0 * PI) * r);
    SphereAt {
        p,
        p_error,
        local,
        dpdu,
    }
}

/// The unit tangent along u of the sphere of centre `c` and frame `frame`
/// at its point nearest `p` (in lanes, as [`sphere_normal`]): dp/du
/// normalised, the direction of (p − c) × a for the axis a of the frame.
/// Made from p − c, not from the unit normal, so that its square root and
/// division run alongside the normal's instead of after them. The bits of
/// the lanes where it is defined: not at the poles, where dp/du vanishes.
#[inline(always)]
pub(crate) fn sphere_tangent<F: Floats>(c: Vec3s<F>, frame: [Vec3s<F>; 3], p: Vec3s<F>) -> (Vec3s<F>, u32) {
    let q = p - c;
    let along = frame_times(frame, around(transposed_times(frame, q)));
    let length_squared = along.dot(along);
    let defined = F::mask_bits(length_squared.gt(F::splat(1e-6) * q.dot(q)));
    (along.scale(F::splat(1.0) / length_squared.sqrt()), defined)
}

/// (−z, 0, x): the direction around +y at (x, y, z).
#[inline(always)]
fn around<F: Floats>(v: Vec3s<F>) -> Vec3s<F> {
    Vec3s {
        x: F::splat(0.0) - v.z,
        y: F::splat(0.0),
        z: v.x,
    }
}

/// `v` in the frame whose columns are `frame` (its transpose times `v`).
#[inline(always)]
fn transposed_times<F: Floats>(frame: [Vec3s<F>; 3], v: Vec3s<F>) -> Vec3s<F> {
    Vec3s {
        x: frame[0].dot(v),
        y: frame[1].dot(v),
        z: frame[2].dot(v),
    }
}

/// The frame whose columns are `frame` times `v`.
#[inline(always)]
fn frame_times<F: Floats>(frame: [Vec3s<F>; 3], v: Vec3s<F>) -> Vec3s<F> {
    frame[0].scale(v.x) + frame[1].scale(v.y) + frame[2].scale(v.z)
}

/// What the sphere test needs of a ray (in every lane for `R` of
/// several): its origin, direction, |d|² (not zero) and interval.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SphereRay<R> {
    pub o: [R; 3],
    pub d: [R; 3],
    pub a: R,
    /// 1/|d|², so that a ray tested against many spheres divides once.
    pub inv_a: R,
    pub t_min: R,
    pub t_max: R,
}

impl SphereRay<f32> {
    /// The ray, or `None` for a zero direction, which meets no sphere.
    #[inline(always)]
    pub fn new(ray: &Ray) -> Option<SphereRay<f32>> {
        let (origin, d, t_min) = ray.read_by_field();
        let a = d.length_squared();
        (a != 0.0).then(|| SphereRay {
            o: origin.to_array(),
            d: d.to_array(),
            a,
            inv_a: 1.0 / a,
            t_min,
            t_max: ray.t_max,
        })
    }

    /// The same ray in every lane of `R`, made from `like`.
    #[inline(always)]
    pub fn splat<R: Real>(&self, like: R) -> SphereRay<R> {
        let s = |x: f32| like.like(x);
        SphereRay {
            o: self.o.map(s),
            d: self.d.map(s),
            a: s(self.a),
            inv_a: s(self.inv_a),
            t_min: s(self.t_min),
            t_max: s(self.t_max),
        }
    }
}

/// The refined quadratic of [`Sphere::intersect`] for the sphere of centre
/// (cx, cy, cz) and radius r, on one sphere (`R = f32`) or on several in
/// vector lanes (the sphere blocks of `accel::blocks`), which therefore
/// compute the same bits: the nearest distance within the ray's interval
/// and whether there is one.
#[inline(always)]
pub(crate) fn sphere_distance<R: Real>(ray: &SphereRay<R>, cx: R, cy: R, cz: R, r: R) -> (R, R::Mask) {
    let [dx, dy, dz] = ray.d;
    let (fx, fy, fz) = (ray.o[0] - cx, ray.o[1] - cy, ray.o[2] - cz);
    let b_half = fx * dx + fy * dy + fz * dz;
    // b'² − a·c rewritten as a·r² − |f × d|² = a·(r² − ρ²), ρ the distance
    // of the ray's line from the centre (Lagrange's identity; Haines et
    // al. write ρ² as |f − (b'/a)·d|², which takes a division first): no
    // cancellation between b'² and a·c, and no division on the way to the
    // square root.
    let (gx, gy, gz) = (fy * dz - fz * dy, fz * dx - fx * dz, fx * dy - fy * dx);
    let disc = ray.a * (r * r) - (gx * gx + gy * gy + gz * gz);
    let c = (fx * fx + fy * fy + fz * fz) - r * r;
    // A negative discriminant (a miss) makes q, and every distance, NaN,
    // which the comparisons below reject.
    let q = (b_half.like(0.0) - b_half) - disc.sqrt().copysign(b_half);
    let (x, y) = (c / q, q * ray.inv_a);
    let zero = q.eq(q.like(0.0));
    let t0 = R::select(zero, q.like(0.0), x.min(y));
    let t1 = R::select(zero, q.like(0.0), x.max(y));
    // Hits must lie strictly after t_min: a ray that starts exactly on the
    // surface (its origin offset by a zero error bound) must not find its
    // own starting point.
    let t = R::select(t0.gt(ray.t_min), t0, t1);
    (t, t.gt(ray.t_min) & t.le(ray.t_max))
}

impl Rectangle {
    /// The box of its four corners.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points([
            self.corner,
            self.corner + self.edge_u,
            self.corner + self.edge_v,
            self.corner + self.edge_u + self.edge_v,
        ])
    }

    /// The parallelogram with this corner and edges. A zero-area one (parallel
    /// edges) is never hit.
    pub fn new(corner: Vec3, edge_u: Vec3, edge_v: Vec3) -> Rectangle {
        let n = edge_u.cross(edge_v);
        let len2 = n.length_squared();
        // (edge_v × n)·edge_u = (n × edge_u)·edge_v = |n|², and each is
        // orthogonal to the other edge.
        let normal = n / len2.sqrt();
        Rectangle {
            corner,
            edge_u,
            edge_v,
            normal,
            dual_u: edge_v.cross(n) / len2,
            dual_v: n.cross(edge_u) / len2,
            tangent: crate::geometry::interaction::unit_tangent(edge_u, normal),
        }
    }

    /// Whether the normal and the dual basis are finite: false where the
    /// edges' cross product underflows or overflows.
    pub fn is_regular(&self) -> bool {
        self.normal.is_finite() && self.dual_u.is_finite() && self.dual_v.is_finite()
    }

    /// The unit tangent along edge_u, perpendicular to the normal (as
    /// [`crate::geometry::interaction::unit_tangent`] makes it).
    pub fn tangent(&self) -> Vec3 {
        self.tangent
    }

    /// The corner at (u, v) = (0, 0).
    pub fn corner(&self) -> Vec3 {
        self.corner
    }

    /// The edge along u.
    pub fn edge_u(&self) -> Vec3 {
        self.edge_u
    }

    /// The edge along v.
    pub fn edge_v(&self) -> Vec3 {
        self.edge_v
    }

    /// The unit normal, along edge_u × edge_v.
    pub fn normal(&self) -> Vec3 {
        self.normal
    }

    /// The corner, the unit normal and the dual basis of the edges, with
    /// which [`Rectangle::intersect`] tests a ray.
    pub(crate) fn test_frame(&self) -> [Vec3; 4] {
        [self.corner, self.normal, self.dual_u, self.dual_v]
    }

    /// Distance to the intersection within the ray's interval. Always
    /// inlined: the scene aggregate tests rectangles in its traversal loop.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        // NaN for a zero-area rectangle, which every comparison rejects.
        let t = intersect_plane(ray, self.corner, self.normal)?;
        let uv = self.coordinates(ray.at(t));
        if (0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y) {
            Some(t)
        } else {
            None
        }
    }

    /// The surface at a point found by [`Rectangle::intersect`].
    #[inline]
    pub fn surface(&self, p: Vec3) -> LocalSurface {
        let p = project_to_plane(p, self.corner, self.normal);
        LocalSurface {
            p,
            p_error: planar_error(p, self.corner),
            n: self.normal,
            uv: self.coordinates(p),
            dpdu: self.edge_u,
            dpdv: self.edge_v,
        }
    }

    /// (a, b) with `p = corner + a·edge_u + b·edge_v` for `p` in the plane,
    /// by the dual basis of the two edges.
    #[inline]
    fn coordinates(&self, p: Vec3) -> Vec2 {
        let q = p - self.corner;
        Vec2::new(self.dual_u.dot(q), self.dual_v.dot(q))
    }
}

impl Disk {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<f32> {
        let t = intersect_plane(ray, self.center, self.normal)?;
        if (ray.at(t) - self.center).length_squared() <= self.radius * self.radius {
            Some(t)
        } else {
            None
        }
    }
}

impl Cuboid {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<f32> {
        let inv = ray.dir.recip();
        let t0 = (self.min - ray.origin) * inv;
        let t1 = (self.max - ray.origin) * inv;
        let near = t0.min(t1).max_element();
        let far = t0.max(t1).min_element();
        if near > far {
            return None;
        }
        if near > ray.t_min && near <= ray.t_max {
            Some(near)
        } else if far > ray.t_min && far <= ray.t_max {
            Some(far) // the origin is inside the box
        } else {
            None
        }
    }

    fn surface(&self, p: Vec3) -> LocalSurface {
        // The face is the one the point lies closest to.
        let mut best = (f32::INFINITY, 0usize, false);
        for axis in 0..3 {
            let dl = (p[axis] - self.min[axis]).abs();
            let dh = (p[axis] - self.max[axis]).abs();
            if dl < best.0 {
                best = (dl, axis, false);
            }
            if dh < best.0 {
                best = (dh, axis, true);
            }
        }
        let (_, axis, high) = best;
        let mut q = p.clamp(self.min, self.max);
        q[axis] = if high { self.max[axis] } else { self.min[axis] };
        let mut n = Vec3::ZERO;
        n[axis] = if high { 1.0 } else { -1.0 };
        let (j, k) = ((axis + 1) % 3, (axis + 2) % 3);
        let e = (self.max - self.min).max(Vec3::splat(f32::MIN_POSITIVE));
        let (mut dpdu, mut dpdv) = (Vec3::ZERO, Vec3::ZERO);
        dpdu[j] = e[j];
        dpdv[k] = e[k];
        // The face coordinate is exact; the others carry the ray's error.
        let mut p_error = gamma(6) * q.abs();
        p_error[axis] = 0.0;
        LocalSurface {
            p: q,
            p_error,
            n,
            uv: Vec2::new((q[j] - self.min[j]) / e[j], (q[k] - self.min[k]) / e[k]),
            dpdu,
            dpdv,
        }
    }

    /// The six faces as rectangles with the box's surface coordinates
    /// (face on axis a: u along axis a+1, v along axis a+2, both in
    /// [0, 1]), each with whether the rectangle's front (edge_u × edge_v)
    /// is the box's outside: true for the faces at `max`, false at `min`.
    pub fn faces(&self) -> [(Rectangle, bool); 6] {
        let e = self.max - self.min;
        std::array::from_fn(|f| {
            let (axis, high) = (f / 2, f % 2 == 1);
            let (j, k) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut corner = self.min;
            if high {
                corner[axis] = self.max[axis];
            }
            let (mut edge_u, mut edge_v) = (Vec3::ZERO, Vec3::ZERO);
            edge_u[j] = e[j];
            edge_v[k] = e[k];
            // x̂_j × x̂_k = x̂_axis for the cyclic order.
            (Rectangle::new(corner, edge_u, edge_v), high)
        })
    }
}

impl Cylinder {
    /// Ray–cylinder intersection in double precision: the quadratic of the
    /// ray's distance from the axis, then the hit's height along the axis
    /// must lie between the ends.
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<f32> {
        let p0 = self.p0.as_dvec3();
        let axis = self.p1.as_dvec3() - p0;
        let h = axis.length();
        if h == 0.0 {
            return None;
        }
        let a = axis / h;
        let o = ray.origin.as_dvec3() - p0;
        let d = ray.dir.as_dvec3();
        // Components perpendicular to the axis.
        let dp = d - a * d.dot(a);
        let op = o - a * o.dot(a);
        let qa = dp.length_squared();
        if qa == 0.0 {
            return None; // parallel to the axis
        }
        let b_half = op.dot(dp);
        let r = self.radius as f64;
        let l = op - dp * (b_half / qa);
        let disc = qa * (r * r - l.length_squared());
        if disc < 0.0 {
            return None;
        }
        let c = op.length_squared() - r * r;
        let q = -b_half - disc.sqrt().copysign(b_half);
        let (t0, t1) = if q == 0.0 {
            (0.0, 0.0)
        } else {
            let (x, y) = (c / q, q / qa);
            (x.min(y), x.max(y))
        };
        let (tmin, tmax) = (ray.t_min as f64, ray.t_max as f64);
        for t in [t0, t1] {
            if t > tmin && t <= tmax {
                let z = (o + d * t).dot(a);
                if (0.0..=h).contains(&z) {
                    return Some(t as f32);
                }
            }
        }
        None
    }

    fn surface(&self, p: Vec3) -> LocalSurface {
        let axis = self.p1 - self.p0;
        let h = axis.length();
        let a = axis / h;
        let q = p - self.p0;
        let z = q.dot(a);
        let radial = q - a * z;
        let n = radial.try_normalize().unwrap_or_else(|| orthonormal_basis(a).0);
        // Reproject onto the tube, as for spheres.
        let p = self.p0 + a * z + n * self.radius;
        let (s, t) = orthonormal_basis(a);
        let phi = n.dot(t).atan2(n.dot(s)).rem_euclid(2.0 * PI);
        LocalSurface {
            p,
            p_error: gamma(6) * (p.abs() + self.p0.abs()),
            n,
            uv: Vec2::new(phi / (2.0 * PI), (z / h).clamp(0.0, 1.0)),
            dpdu: a.cross(n) * (2.0 * PI * self.radius),
            dpdv: axis,
        }
    }
}

/// Distance along `ray` to the plane through `p0` with normal `n` (any
/// length), if it lies in the ray's interval (strictly after `t_min`).
#[inline]
fn intersect_plane(ray: &Ray, p0: Vec3, n: Vec3) -> Option<f32> {
    let denom = n.dot(ray.dir);
    if denom == 0.0 {
        return None; // parallel
    }
    let t = n.dot(p0 - ray.origin) / denom;
    if t > ray.t_min && t <= ray.t_max && t.is_finite() {
        Some(t)
    } else {
        None
    }
}

/// Moves `p` along the unit normal `n` onto the plane through `p0`.
#[inline]
fn project_to_plane(p: Vec3, p0: Vec3, n: Vec3) -> Vec3 {
    p - n * n.dot(p - p0)
}

/// Error bound of a point projected onto a plane through `p0`.
#[inline]
fn planar_error(p: Vec3, p0: Vec3) -> Vec3 {
    gamma(7) * (p.abs() + p0.abs())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn near(a: f32, b: f32, eps: f32) -> bool {
        (a - b).abs() <= eps * (1.0 + b.abs())
    }

    fn unit_sphere() -> Shape {
        Shape::Sphere(Sphere::new(Vec3::ZERO, 1.0))
    }

    #[test]
    fn sphere_hit_miss_tangent_inside() {
        let s = unit_sphere();
        // Head-on hit: t = 4.
        let r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        assert!(near(s.intersect(&r).unwrap(), 4.0, 1e-6));
        // Miss.
        assert!(s.intersect(&Ray::new(Vec3::new(0.0, 1.5, -5.0), Vec3::Z)).is_none());
        // Tangent: grazes at y = 1.
        let t = s.intersect(&Ray::new(Vec3::new(0.0, 1.0, -5.0), Vec3::Z));
        assert!(near(t.unwrap(), 5.0, 1e-5));
        // Origin inside: the far root.
        assert!(near(s.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).unwrap(), 1.0, 1e-6));
        // Sphere behind the ray.
        assert!(s.intersect(&Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::Z)).is_none());
        // Interval ends before the sphere.
        let short = Ray::with_interval(Vec3::new(0.0, 0.0, -5.0), Vec3::Z, 0.0, 3.9);
        assert!(s.intersect(&short).is_none());
        // Unnormalised directions give t in units of the direction.
        let r2 = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z * 2.0);
        assert!(near(s.intersect(&r2).unwrap(), 2.0, 1e-6));
    }

    #[test]
    fn sphere_grazing_offset_hits_the_closed_form() {
        // Ray at height h hits at z = -sqrt(1 − h²).
        let s = unit_sphere();
        for h in [0.0f32, 0.5, 0.9, 0.999, 0.999_99] {
            let t = s.intersect(&Ray::new(Vec3::new(0.0, h, -10.0), Vec3::Z)).unwrap();
            let expect = 10.0 - (1.0 - h * h).sqrt();
            assert!(near(t, expect, 1e-6), "h={h}: {t} vs {expect}");
        }
    }

    #[test]
    fn huge_and_tiny_spheres_are_found_within_their_rounding() {
        // smallpt's wall: radius 1e5, seen from 50 units. In single
        // precision c = |o − centre|² − r² rounds by a few ulps of 10¹⁰,
        // which moves t by that over |q| ≈ 2·10⁵; the hit point's error
        // bound, beyond which spawned rays start, is larger still.
        let big = Shape::Sphere(Sphere::new(Vec3::new(1e5 + 1.0, 40.8, 81.6), 1e5));
        let r = Ray::new(Vec3::new(50.0, 40.8, 81.6), -Vec3::X);
        let t = big.intersect(&r).unwrap();
        let rounding = 4.0 * f32::EPSILON * 1e10 / 2e5;
        assert!((t - 49.0).abs() <= rounding, "t = {t}");
        let p_error = big.surface(r.at(t)).p_error;
        assert!(p_error.x > 10.0 * (t - 49.0).abs(), "{p_error} against t = {t}");
        let tiny = Shape::Sphere(Sphere::new(Vec3::new(1e-6, 0.0, 0.0), 1e-7));
        let r = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(near(tiny.intersect(&r).unwrap(), 9e-7, 1e-5));
    }

    #[test]
    fn sphere_surface_normal_and_uv() {
        let s = Shape::Sphere(Sphere::new(Vec3::new(1.0, 2.0, 3.0), 2.0));
        let ls = s.surface(Vec3::new(1.0, 4.0, 3.0));
        assert!((ls.n - Vec3::Y).length() < 1e-6);
        assert!(near(ls.uv.y, 1.0, 1e-6)); // north pole
        let ls = s.surface(Vec3::new(3.0, 2.0, 3.0));
        assert!((ls.n - Vec3::X).length() < 1e-6);
        assert!(near(ls.uv.x, 0.0, 1e-6) && near(ls.uv.y, 0.5, 1e-6));
        assert!(ls.dpdu.dot(ls.n).abs() < 1e-5);
    }

    #[test]
    fn plane_hits_from_both_sides_and_misses_parallel() {
        let p = Shape::Plane(Plane::new(Vec3::ZERO, Vec3::Y));
        assert!(near(
            p.intersect(&Ray::new(Vec3::new(3.0, 2.0, 1.0), -Vec3::Y)).unwrap(),
            2.0,
            1e-6
        ));
        assert!(near(
            p.intersect(&Ray::new(Vec3::new(0.0, -1.0, 0.0), Vec3::Y)).unwrap(),
            1.0,
            1e-6
        ));
        assert!(p.intersect(&Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::X)).is_none());
        assert!(p.intersect(&Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::Y)).is_none());
        assert!(p.bounds().is_none());
    }

    #[test]
    fn rectangle_tangent_is_its_surface_tangent() {
        // Sheared and skewed parallelograms too: the tangent follows edge_u,
        // is unit length and perpendicular to the normal, and is what a
        // surface record would compute from dp/du.
        let mut rng = Pcg32::new(8, 8);
        let mut v = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
        for _ in 0..1000 {
            let r = Rectangle::new(v(), v(), v());
            let t = r.tangent();
            assert!((t.length() - 1.0).abs() < 1e-6);
            assert!(t.dot(r.normal()).abs() < 1e-5);
            assert!(t.dot(r.edge_u().normalize()) > 0.0);
            let dpdu = Shape::Rectangle(r).surface(r.corner() + 0.5 * r.edge_u()).dpdu;
            assert_eq!(t, crate::geometry::interaction::unit_tangent(dpdu, r.normal()));
            assert_eq!(Shape::Rectangle(r).tangent_at(v()), Some(t));
        }
    }

    #[test]
    fn sphere_tangent_is_its_surface_tangent() {
        // Unit length, perpendicular to the normal and along dp/du, on
        // spheres with turned coordinates, far from their origin; a tangent
        // of the normal at the poles.
        let mut rng = Pcg32::new(3, 9);
        let mut u = || rng.next_f32();
        for _ in 0..1000 {
            let mut s = Sphere::new(Vec3::new(u(), u(), u()) * 2e3 - 1e3, 0.1 + 100.0 * u());
            s.uv_frame = Mat3::from_quat(glam::Quat::from_euler(
                glam::EulerRot::XYZ,
                7.0 * u(),
                7.0 * u(),
                7.0 * u(),
            ));
            let d = sample_sphere_uniform(Vec2::new(u(), u()));
            let ls = Shape::Sphere(s).surface(s.center + d * s.radius);
            let t = Shape::Sphere(s).tangent_at(s.center + d * s.radius).unwrap();
            assert!((t.length() - 1.0).abs() < 1e-5, "{t}");
            assert!(t.dot(ls.n).abs() < 1e-3, "{t} against {}", ls.n);
            assert!((t - ls.dpdu.normalize()).length() < 1e-3, "{t} against {}", ls.dpdu);
        }
        let s = Sphere::new(Vec3::ONE, 2.0);
        let pole = s.tangent_at(Vec3::new(1.0, 3.0, 1.0));
        assert!((pole.length() - 1.0).abs() < 1e-6 && pole.y.abs() < 1e-6, "{pole}");
    }

    #[test]
    fn rectangle_inside_edges_outside() {
        let r = Shape::Rectangle(Rectangle::new(
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -1.0),
        ));
        let down = -Vec3::Y;
        assert!(r.intersect(&Ray::new(Vec3::new(1.0, 1.0, -0.5), down)).is_some());
        // Exactly on the edge counts as a hit.
        assert!(r.intersect(&Ray::new(Vec3::new(2.0, 1.0, -0.5), down)).is_some());
        assert!(r.intersect(&Ray::new(Vec3::new(2.1, 1.0, -0.5), down)).is_none());
        assert!(r.intersect(&Ray::new(Vec3::new(1.0, 1.0, 0.1), down)).is_none());
        let ls = r.surface(Vec3::new(1.0, 0.0, -0.25));
        assert!(near(ls.uv.x, 0.5, 1e-6) && near(ls.uv.y, 0.25, 1e-6));
        assert!((ls.n - Vec3::Y).length() < 1e-6); // (x) × (−z) = +y
        assert!(near(r.area(), 2.0, 1e-6));
    }

    #[test]
    fn sheared_parallelogram_coordinates() {
        let r = Rectangle::new(
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
        );
        let p = r.corner + 0.3 * r.edge_u + 0.6 * r.edge_v;
        let uv = r.coordinates(p);
        assert!(near(uv.x, 0.3, 1e-6) && near(uv.y, 0.6, 1e-6));
    }

    #[test]
    fn disk_hit_and_rim() {
        let d = Shape::Disk(Disk {
            center: Vec3::new(0.0, 1.0, 0.0),
            normal: Vec3::Y,
            radius: 2.0,
            uv: crate::geometry::DiskUv::AngleRadius,
        });
        assert!(near(
            d.intersect(&Ray::new(Vec3::new(1.0, 3.0, 1.0), -Vec3::Y)).unwrap(),
            2.0,
            1e-6
        ));
        assert!(d.intersect(&Ray::new(Vec3::new(2.0, 3.0, 0.0), -Vec3::Y)).is_some());
        assert!(d.intersect(&Ray::new(Vec3::new(1.5, 3.0, 1.5), -Vec3::Y)).is_none());
        let b = d.bounds().unwrap();
        assert!(near(b.max.x, 2.0, 1e-6) && near(b.max.y, 1.0, 1e-6));
    }

    #[test]
    fn cuboid_outside_inside_and_faces() {
        let c = Shape::Cuboid(Cuboid {
            min: Vec3::splat(-1.0),
            max: Vec3::new(1.0, 2.0, 1.0),
        });
        let t = c.intersect(&Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z)).unwrap();
        assert!(near(t, 4.0, 1e-6));
        let ls = c.surface(Vec3::new(0.0, 0.0, -1.0));
        assert_eq!(ls.n, -Vec3::Z);
        let t = c.intersect(&Ray::new(Vec3::ZERO, Vec3::Y)).unwrap();
        assert!(near(t, 2.0, 1e-6));
        assert_eq!(c.surface(Vec3::new(0.0, 2.0, 0.0)).n, Vec3::Y);
        assert!(c.intersect(&Ray::new(Vec3::new(0.0, 5.0, -5.0), Vec3::Z)).is_none());
        assert!(near(c.area(), 2.0 * (2.0 * 3.0 + 3.0 * 2.0 + 2.0 * 2.0), 1e-6));
    }

    /// A box's faces as rectangles meet every ray the box meets, at the
    /// same distance, with the box's surface there: point, (u, v), dp/du,
    /// and the outward normal (the rectangle's front, or its back where
    /// `faces` says so).
    #[test]
    fn cuboid_faces_are_the_cuboid() {
        let cuboid = Cuboid {
            min: Vec3::new(-1.0, -0.5, 0.25),
            max: Vec3::new(1.5, 2.0, 1.0),
        };
        let faces = cuboid.faces();
        let c = Shape::Cuboid(cuboid);
        let mut rng = crate::sampling::Pcg32::new(17, 3);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0 - 4.0;
            let target = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 3.0 - 1.0;
            let ray = Ray::new(o, target - o);
            let nearest = faces
                .iter()
                .filter_map(|(r, outward)| r.intersect(&ray).map(|t| (t, r, *outward)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            match (c.intersect(&ray), nearest) {
                (None, None) => {}
                (Some(t), Some((t_face, r, outward))) => {
                    assert!(near(t, t_face, 1e-5 * t.max(1.0)), "{ray:?}: {t} vs {t_face}");
                    let p = ray.at(t);
                    // Away from edges, where the box picks its face by
                    // distance and either is right.
                    let (box_s, face_s) = (c.surface(p), r.surface(ray.at(t_face)));
                    let margin = (box_s.uv.min_element()).min(1.0 - box_s.uv.max_element());
                    if margin > 1e-3 {
                        assert!((box_s.p - face_s.p).length() < 1e-5, "{ray:?}");
                        assert!((box_s.uv - face_s.uv).length() < 1e-5, "{ray:?}");
                        assert!((box_s.dpdu - face_s.dpdu).length() < 1e-5, "{ray:?}");
                        let n = if outward { face_s.n } else { -face_s.n };
                        assert!((box_s.n - n).length() < 1e-6, "{ray:?}: {} vs {n}", box_s.n);
                        hits += 1;
                    }
                }
                (a, b) => panic!("{ray:?}: box {a:?}, faces {:?}", b.map(|b| b.0)),
            }
        }
        assert!(hits > 500, "the test must exercise hits ({hits})");
    }

    #[test]
    fn cylinder_hit_inside_and_ends() {
        let c = Shape::Cylinder(Cylinder {
            p0: Vec3::new(0.0, -1.0, 0.0),
            p1: Vec3::new(0.0, 1.0, 0.0),
            radius: 0.5,
        });
        let t = c.intersect(&Ray::new(Vec3::new(-5.0, 0.0, 0.0), Vec3::X)).unwrap();
        assert!(near(t, 4.5, 1e-6));
        assert!((c.surface(Vec3::new(-0.5, 0.0, 0.0)).n - -Vec3::X).length() < 1e-6);
        // Open ends: a ray along the axis passes through.
        assert!(c.intersect(&Ray::new(Vec3::new(0.0, -5.0, 0.0), Vec3::Y)).is_none());
        // Beyond the ends: missed.
        assert!(c.intersect(&Ray::new(Vec3::new(-5.0, 1.5, 0.0), Vec3::X)).is_none());
        // From inside: the far wall, its outward normal facing away.
        let t = c.intersect(&Ray::new(Vec3::ZERO, Vec3::Z)).unwrap();
        assert!(near(t, 0.5, 1e-6));
        // A slanted ray entering through the open end hits the inside wall.
        let r = Ray::new(Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.5, -2.0, 0.0));
        let t = c.intersect(&r).unwrap();
        assert!(near(r.at(t).x, 0.5, 1e-5) && r.at(t).y < 1.0);
        assert!(near(c.area(), 2.0 * PI * 0.5 * 2.0, 1e-6));
    }

    #[test]
    fn area_samples_lie_on_the_surface() {
        let shapes = [
            Shape::Sphere(Sphere::new(Vec3::ONE, 0.5)),
            Shape::Rectangle(Rectangle::new(Vec3::ZERO, Vec3::X, Vec3::Z)),
            Shape::Disk(Disk {
                center: Vec3::Y,
                normal: Vec3::new(0.0, 0.6, 0.8),
                radius: 1.5,
                uv: crate::geometry::DiskUv::AngleRadius,
            }),
            Shape::Cuboid(Cuboid {
                min: Vec3::ZERO,
                max: Vec3::new(1.0, 2.0, 3.0),
            }),
            Shape::Cylinder(Cylinder {
                p0: Vec3::new(1.0, 0.0, 0.0),
                p1: Vec3::new(1.0, 1.0, 2.0),
                radius: 0.3,
            }),
        ];
        let mut rng = Pcg32::new(2, 0);
        for s in shapes {
            for _ in 0..500 {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let a = s.sample_area(u, true).unwrap();
                // A ray from just outside along −n must hit the shape at the sample.
                let r = Ray::new(a.p + a.n * 1e-2, -a.n);
                let t = s.intersect(&r).expect("sample not on surface");
                assert!((t - 1e-2).abs() < 1e-3, "{s:?}: {t}");
                assert!((s.surface(a.p).n - a.n).length() < 1e-3);
                // Textured emitters read the sample's surface coordinates.
                assert!((s.surface(a.p).uv - a.uv).length() < 1e-4, "{s:?}: {}", a.uv);
            }
        }
        // A sheared parallelogram's samples carry their (a, b) coordinates.
        let sheared = Shape::Rectangle(Rectangle::new(
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(2.0, 0.5, 0.0),
            Vec3::new(0.7, 0.0, 1.5),
        ));
        let a = sheared.sample_area(Vec2::new(0.25, 0.8), true).unwrap();
        assert!((sheared.surface(a.p).uv - Vec2::new(0.25, 0.8)).length() < 1e-5);
    }

    #[test]
    fn cuboid_area_sampling_is_uniform_over_faces() {
        // Fractions of samples per face pair match the area fractions.
        let c = Shape::Cuboid(Cuboid {
            min: Vec3::ZERO,
            max: Vec3::new(1.0, 2.0, 4.0),
        });
        let mut rng = Pcg32::new(4, 0);
        let mut counts = [0f64; 3];
        let n = 60_000;
        for _ in 0..n {
            let a = c.sample_area(Vec2::new(rng.next_f32(), rng.next_f32()), true).unwrap();
            counts[a.n.abs().max_position()] += 1.0;
        }
        let areas = [8.0, 4.0, 2.0];
        let total: f64 = areas.iter().sum();
        for i in 0..3 {
            let p = areas[i] / total;
            let sigma = (n as f64 * p * (1.0 - p)).sqrt();
            assert!((counts[i] - n as f64 * p).abs() < 5.0 * sigma, "{counts:?}");
        }
    }
}
