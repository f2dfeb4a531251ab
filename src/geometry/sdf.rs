//! Signed distance functions, rendered by sphere tracing (Hart 1996,
//! "Sphere Tracing: A Geometric Method for the Antialiased Ray Tracing of
//! Implicit Surfaces").
//!
//! A shape is a tree of nodes: primitives (sphere, box, torus, capsule,
//! capped cylinder and cone, half-space, the Mandelbulb), constructive
//! solid geometry (union, intersection, difference, each optionally
//! smooth), and operators on space (affine transforms, limited repetition,
//! twist, bend, displacement by noise, rounding). Every node's value is a
//! lower bound of the distance to its surface that is 1-Lipschitz: where a
//! map of space stretches distances by at most L, its child's value is
//! divided by L. A ray may then step forward by the value without passing
//! the surface; that is all sphere tracing needs.
//!
//! The marcher over-relaxes its steps (ω = 1.6) and steps back to a plain
//! step whenever two consecutive unbounding spheres fail to overlap
//! (Keinert et al. 2014, "Enhanced Sphere Tracing"). A hit is where the
//! value falls below ε; a few plain steps then bring the point closer to
//! the surface. Normals are the gradient: analytic for the primitives and
//! through CSG and transforms, central differences below the operators
//! that have none (cone, Mandelbulb, twist, bend, noise). Rays that run
//! out of steps are counted and reported after the render, not dropped in
//! silence.
//!
//! The Mandelbulb's value is the usual distance estimate
//! 0.5·ln r·r/|dr| (Hart et al. 1989 for Julia sets; the bulb after
//! White and Nylander 2009), which is an estimate, not a proven bound.

use super::bounds::Aabb;
use super::ray::Ray;
use super::shape::LocalSurface;
use crate::sampling::warp::orthonormal_basis;
use glam::{Affine3A, Mat3, Vec2, Vec3};
use std::sync::atomic::{AtomicU64, Ordering};

/// The most nodes one tree may hold.
pub const MAX_SDF_NODES: usize = 4096;
/// The deepest a tree may nest (the marcher's evaluation recurses).
pub const MAX_SDF_DEPTH: usize = 64;
/// Steps a ray may take before the marcher gives up on it.
pub const DEFAULT_MAX_STEPS: u32 = 512;
/// The most steps a scene may allow.
pub const MAX_MAX_STEPS: u32 = 1 << 20;
/// ε as a fraction of the tree's largest extent, unless given.
pub const DEFAULT_RELATIVE_EPSILON: f32 = 2e-5;
/// The most iterations of the Mandelbulb's formula.
pub const MAX_MANDELBULB_ITERATIONS: u32 = 64;
/// Over-relaxation factor ω of the steps (Keinert et al. 2014, section 3.1).
const OVER_RELAXATION: f32 = 1.6;
/// The noise's gradient is at most this many times its frequency: value
/// noise in [−1, 1] blended by smoothstep, whose slope is at most 1.5,
/// changes by at most 1.5·2 along each axis.
const NOISE_LIPSCHITZ: f32 = 3.0 * 1.732_050_8;

/// Node of a tree, referring to its children by index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SdfNode {
    /// Sphere of `radius` at the origin.
    Sphere {
        /// Radius.
        radius: f32,
    },
    /// Box of half-sizes `half` centred on the origin.
    Box {
        /// Half-sizes.
        half: Vec3,
    },
    /// Torus around the y axis.
    Torus {
        /// Distance from the axis to the tube's centre.
        major: f32,
        /// Radius of the tube.
        minor: f32,
    },
    /// Segment from `a` to `b`, thickened by `radius`.
    Capsule {
        /// One end.
        a: Vec3,
        /// The other end.
        b: Vec3,
        /// Radius.
        radius: f32,
    },
    /// Capped cylinder along y, centred on the origin.
    Cylinder {
        /// Radius.
        radius: f32,
        /// Half of its height.
        half_height: f32,
    },
    /// Capped cone along y: base of `radius` at y = 0, apex at y = `height`.
    Cone {
        /// Radius of the base.
        radius: f32,
        /// Height of the apex.
        height: f32,
    },
    /// Half-space n·p ≤ offset (unbounded: it must be intersected with
    /// something bounded).
    Plane {
        /// Unit normal, pointing out of the solid.
        normal: Vec3,
        /// Offset along the normal.
        offset: f32,
    },
    /// The Mandelbulb of `power` (8 for the classic one), around the z axis.
    Mandelbulb {
        /// Power of the formula z ← z^power + c.
        power: f32,
        /// Iterations.
        iterations: u32,
    },
    /// Union, hard (`smooth` 0) or smooth with blend radius `smooth`.
    Union {
        /// First operand.
        a: u32,
        /// Second operand.
        b: u32,
        /// Blend radius.
        smooth: f32,
    },
    /// Intersection.
    Intersection {
        /// First operand.
        a: u32,
        /// Second operand.
        b: u32,
        /// Blend radius.
        smooth: f32,
    },
    /// `a` with `b` taken out.
    Difference {
        /// What remains.
        a: u32,
        /// What is taken out.
        b: u32,
        /// Blend radius.
        smooth: f32,
    },
    /// The child grown by `radius` (rounded edges).
    Round {
        /// Child.
        child: u32,
        /// Radius.
        radius: f32,
    },
    /// The child under an affine map (child space → this node's space).
    Transform {
        /// Child.
        child: u32,
        /// This node's space → the child's.
        to_child: Affine3A,
        /// 1 / the largest stretch of `to_child`.
        scale: f32,
    },
    /// Copies of the child every `period`, `count` on each side of the
    /// original along each axis (0: not repeated along that axis).
    Repeat {
        /// Child.
        child: u32,
        /// Spacing.
        period: Vec3,
        /// Copies on each side.
        count: Vec3,
        /// Least gap between the child's bounds and its cell's faces.
        margin: f32,
    },
    /// The child twisted around the y axis by `rate` radians per unit of y.
    Twist {
        /// Child.
        child: u32,
        /// Radians per unit.
        rate: f32,
        /// 1 / the largest stretch of the map within `region`.
        scale: f32,
        /// Where the surface lies (this node's bounds).
        region: Aabb,
    },
    /// The child bent in the xy plane by `rate` radians per unit of x.
    Bend {
        /// Child.
        child: u32,
        /// Radians per unit.
        rate: f32,
        /// 1 / the largest stretch of the map within `region`.
        scale: f32,
        /// Where the surface lies (this node's bounds).
        region: Aabb,
    },
    /// The child's surface moved along its normal by value noise.
    Displace {
        /// Child.
        child: u32,
        /// Largest displacement.
        amplitude: f32,
        /// Lattice cells per unit.
        frequency: f32,
        /// Seed of the noise.
        seed: u32,
        /// 1 / the Lipschitz constant of the displaced value.
        scale: f32,
    },
}

/// Builds a tree node by node, checking each node's parameters and
/// computing its bounds.
#[derive(Clone, Debug, Default)]
pub struct SdfBuilder {
    nodes: Vec<SdfNode>,
    bounds: Vec<Aabb>,
    depth: Vec<usize>,
}

fn everywhere() -> Aabb {
    Aabb {
        min: Vec3::splat(f32::NEG_INFINITY),
        max: Vec3::splat(f32::INFINITY),
    }
}

fn is_finite_box(b: &Aabb) -> bool {
    b.min.is_finite() && b.max.is_finite()
}

fn positive(what: &str, x: f32) -> Result<f32, String> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(format!("{what} must be a positive number, got {x}"))
    }
}

fn non_negative(what: &str, x: f32) -> Result<f32, String> {
    if x.is_finite() && x >= 0.0 {
        Ok(x)
    } else {
        Err(format!("{what} must be zero or positive, got {x}"))
    }
}

impl SdfBuilder {
    /// An empty tree.
    pub fn new() -> SdfBuilder {
        SdfBuilder::default()
    }

    fn push(&mut self, node: SdfNode, bounds: Aabb, children: &[u32]) -> Result<u32, String> {
        if self.nodes.len() >= MAX_SDF_NODES {
            return Err(format!("a distance function may have at most {MAX_SDF_NODES} nodes"));
        }
        let depth = 1 + children.iter().map(|&c| self.depth[c as usize]).max().unwrap_or(0);
        if depth > MAX_SDF_DEPTH {
            return Err(format!("a distance function may nest at most {MAX_SDF_DEPTH} deep"));
        }
        self.nodes.push(node);
        self.bounds.push(bounds);
        self.depth.push(depth);
        Ok((self.nodes.len() - 1) as u32)
    }

    fn child_bounds(&self, c: u32) -> Result<Aabb, String> {
        self.bounds
            .get(c as usize)
            .copied()
            .ok_or_else(|| format!("node {c} does not exist"))
    }

    /// The bounds of node `i`.
    pub fn bounds(&self, i: u32) -> Aabb {
        self.bounds[i as usize]
    }

    /// A sphere.
    pub fn sphere(&mut self, radius: f32) -> Result<u32, String> {
        let r = positive("a sphere's radius", radius)?;
        self.push(
            SdfNode::Sphere { radius: r },
            Aabb::new(-Vec3::splat(r), Vec3::splat(r)),
            &[],
        )
    }

    /// A box of half-sizes `half`.
    pub fn cuboid(&mut self, half: Vec3) -> Result<u32, String> {
        for h in half.to_array() {
            positive("a box's half-sizes", h)?;
        }
        self.push(SdfNode::Box { half }, Aabb::new(-half, half), &[])
    }

    /// A torus around y.
    pub fn torus(&mut self, major: f32, minor: f32) -> Result<u32, String> {
        positive("a torus's major radius", major)?;
        positive("a torus's minor radius", minor)?;
        let e = Vec3::new(major + minor, minor, major + minor);
        self.push(SdfNode::Torus { major, minor }, Aabb::new(-e, e), &[])
    }

    /// A capsule.
    pub fn capsule(&mut self, a: Vec3, b: Vec3, radius: f32) -> Result<u32, String> {
        positive("a capsule's radius", radius)?;
        if !a.is_finite() || !b.is_finite() {
            return Err("a capsule's ends must be finite".into());
        }
        let bounds = Aabb::new(a.min(b) - Vec3::splat(radius), a.max(b) + Vec3::splat(radius));
        self.push(SdfNode::Capsule { a, b, radius }, bounds, &[])
    }

    /// A capped cylinder along y of total `height`.
    pub fn cylinder(&mut self, radius: f32, height: f32) -> Result<u32, String> {
        positive("a cylinder's radius", radius)?;
        let h = positive("a cylinder's height", height)? * 0.5;
        let e = Vec3::new(radius, h, radius);
        self.push(SdfNode::Cylinder { radius, half_height: h }, Aabb::new(-e, e), &[])
    }

    /// A capped cone along y, base at y = 0.
    pub fn cone(&mut self, radius: f32, height: f32) -> Result<u32, String> {
        positive("a cone's radius", radius)?;
        positive("a cone's height", height)?;
        let bounds = Aabb::new(Vec3::new(-radius, 0.0, -radius), Vec3::new(radius, height, radius));
        self.push(SdfNode::Cone { radius, height }, bounds, &[])
    }

    /// The half-space n·p ≤ offset.
    pub fn plane(&mut self, normal: Vec3, offset: f32) -> Result<u32, String> {
        let n = normal
            .try_normalize()
            .filter(|n| n.is_finite())
            .ok_or_else(|| format!("a plane's normal must be a non-zero vector, got {normal}"))?;
        if !offset.is_finite() {
            return Err(format!("a plane's offset must be finite, got {offset}"));
        }
        self.push(SdfNode::Plane { normal: n, offset }, everywhere(), &[])
    }

    /// The Mandelbulb.
    pub fn mandelbulb(&mut self, power: f32, iterations: u32) -> Result<u32, String> {
        if !(power.is_finite() && (2.0..=32.0).contains(&power)) {
            return Err(format!("a Mandelbulb's power must be between 2 and 32, got {power}"));
        }
        if !(1..=MAX_MANDELBULB_ITERATIONS).contains(&iterations) {
            return Err(format!(
                "a Mandelbulb's iterations must be between 1 and {MAX_MANDELBULB_ITERATIONS}, got {iterations}"
            ));
        }
        // Points farther than 2 from the origin escape: the set lies within.
        self.push(
            SdfNode::Mandelbulb { power, iterations },
            Aabb::new(Vec3::splat(-2.0), Vec3::splat(2.0)),
            &[],
        )
    }

    /// Union (`smooth` > 0: blended over that radius).
    pub fn union(&mut self, a: u32, b: u32, smooth: f32) -> Result<u32, String> {
        let k = non_negative("a blend radius (smooth)", smooth)?;
        let bounds = self.child_bounds(a)?.union(&self.child_bounds(b)?);
        // A smooth minimum lowers the value by at most k/4: the surface
        // grows by at most that much.
        self.push(SdfNode::Union { a, b, smooth: k }, grow(bounds, k * 0.25), &[a, b])
    }

    /// Intersection.
    pub fn intersection(&mut self, a: u32, b: u32, smooth: f32) -> Result<u32, String> {
        let k = non_negative("a blend radius (smooth)", smooth)?;
        let (ba, bb) = (self.child_bounds(a)?, self.child_bounds(b)?);
        let bounds = Aabb {
            min: ba.min.max(bb.min),
            max: ba.max.min(bb.max),
        };
        if bounds.min.cmpgt(bounds.max).any() {
            return Err("an intersection of shapes whose bounds do not overlap is empty".into());
        }
        self.push(SdfNode::Intersection { a, b, smooth: k }, bounds, &[a, b])
    }

    /// `a` minus `b`.
    pub fn difference(&mut self, a: u32, b: u32, smooth: f32) -> Result<u32, String> {
        let k = non_negative("a blend radius (smooth)", smooth)?;
        let bounds = self.child_bounds(a)?;
        self.child_bounds(b)?;
        self.push(SdfNode::Difference { a, b, smooth: k }, bounds, &[a, b])
    }

    /// The child grown by `radius`.
    pub fn round(&mut self, child: u32, radius: f32) -> Result<u32, String> {
        let r = non_negative("a rounding radius", radius)?;
        let bounds = grow(self.child_bounds(child)?, r);
        self.push(SdfNode::Round { child, radius: r }, bounds, &[child])
    }

    /// The child under `to_parent` (an invertible affine map).
    pub fn transform(&mut self, child: u32, to_parent: &super::Transform) -> Result<u32, String> {
        let cb = self.child_bounds(child)?;
        let to_child = Affine3A::from_mat4(to_parent.inv);
        let stretch = largest_singular_value(Mat3::from(to_child.matrix3));
        if !(stretch.is_finite() && stretch > 0.0) {
            return Err("a distance function's transform must be invertible".into());
        }
        let bounds = if is_finite_box(&cb) {
            to_parent.aabb(&cb)
        } else {
            everywhere()
        };
        self.push(
            SdfNode::Transform {
                child,
                to_child,
                scale: 1.0 / stretch,
            },
            bounds,
            &[child],
        )
    }

    /// `count` copies on each side every `period` along each axis.
    pub fn repeat(&mut self, child: u32, period: Vec3, count: [u32; 3]) -> Result<u32, String> {
        let cb = self.child_bounds(child)?;
        if !is_finite_box(&cb) {
            return Err("only a bounded shape can be repeated".into());
        }
        let mut margin = f32::INFINITY;
        for axis in 0..3 {
            if count[axis] == 0 {
                continue;
            }
            if count[axis] > 10_000 {
                return Err(format!("at most 10000 copies on each side, got {}", count[axis]));
            }
            let p = positive("a repetition's period", period[axis])?;
            let reach = cb.min[axis].abs().max(cb.max[axis].abs());
            let gap = 0.5 * p - reach;
            if gap <= 0.0 {
                return Err(format!(
                    "the repeated shape reaches {reach} from its centre along {}, more than half the period {p}: copies would overlap",
                    ["x", "y", "z"][axis]
                ));
            }
            margin = margin.min(gap);
        }
        if margin == f32::INFINITY {
            return Err("a repetition needs a count above 0 along some axis".into());
        }
        let count_v = Vec3::new(count[0] as f32, count[1] as f32, count[2] as f32);
        let reach = Vec3::select(count_v.cmpgt(Vec3::ZERO), period * count_v, Vec3::ZERO);
        let bounds = Aabb::new(cb.min - reach, cb.max + reach);
        self.push(
            SdfNode::Repeat {
                child,
                period: Vec3::select(count_v.cmpgt(Vec3::ZERO), period, Vec3::ONE),
                count: count_v,
                margin,
            },
            bounds,
            &[child],
        )
    }

    /// The child twisted around y, by `rate` radians per unit of y.
    pub fn twist(&mut self, child: u32, rate: f32) -> Result<u32, String> {
        self.rotated_along(child, rate, true)
    }

    /// The child bent in the xy plane, by `rate` radians per unit of x.
    pub fn bend(&mut self, child: u32, rate: f32) -> Result<u32, String> {
        self.rotated_along(child, rate, false)
    }

    /// A twist (xz turned by an angle growing with y) or a bend (xy turned
    /// by an angle growing with x).
    fn rotated_along(&mut self, child: u32, rate: f32, twist: bool) -> Result<u32, String> {
        let cb = self.child_bounds(child)?;
        if !is_finite_box(&cb) || !rate.is_finite() {
            let what = if twist { "twisted" } else { "bent" };
            return Err(format!("only a bounded shape can be {what}, by a finite rate"));
        }
        // The plane turned, and the axis left alone: the surface stays
        // within the child's largest distance ρ from that axis.
        let (a, b, free) = if twist { (0, 2, 1) } else { (0, 1, 2) };
        let rho = radius_around(cb, a, b);
        let mut region = Aabb::new(Vec3::splat(-rho), Vec3::splat(rho));
        region.min[free] = cb.min[free];
        region.max[free] = cb.max[free];
        // The map is a rotation plus a rank-one term of norm |rate|·r,
        // r ≤ ρ√2 within the region: it stretches by at most 1 + |rate|·r.
        let scale = 1.0 / (1.0 + rate.abs() * rho * std::f32::consts::SQRT_2);
        let node = if twist {
            SdfNode::Twist {
                child,
                rate,
                scale,
                region,
            }
        } else {
            SdfNode::Bend {
                child,
                rate,
                scale,
                region,
            }
        };
        self.push(node, region, &[child])
    }

    /// The child displaced by value noise.
    pub fn displace(&mut self, child: u32, amplitude: f32, frequency: f32, seed: u32) -> Result<u32, String> {
        let a = non_negative("a displacement's amplitude", amplitude)?;
        let f = positive("a displacement's frequency", frequency)?;
        let bounds = grow(self.child_bounds(child)?, a);
        let scale = 1.0 / (1.0 + a * f * NOISE_LIPSCHITZ);
        self.push(
            SdfNode::Displace {
                child,
                amplitude: a,
                frequency: f,
                seed,
                scale,
            },
            bounds,
            &[child],
        )
    }

    /// The finished shape with `root` as its root; `epsilon` (hit
    /// tolerance, object units) defaults to a fraction of the largest
    /// extent.
    pub fn build(self, root: u32, epsilon: Option<f32>, max_steps: u32) -> Result<Sdf, String> {
        let bounds = self.child_bounds(root)?;
        if !is_finite_box(&bounds) {
            return Err(
                "the distance function is unbounded (a plane must be intersected with or cut from a bounded shape)"
                    .into(),
            );
        }
        let extent = bounds.extent().max_element();
        let epsilon = match epsilon {
            Some(e) => positive("epsilon", e)?,
            None => DEFAULT_RELATIVE_EPSILON * extent,
        };
        if !(1..=MAX_MAX_STEPS).contains(&max_steps) {
            return Err(format!(
                "max_steps must be between 1 and {MAX_MAX_STEPS}, got {max_steps}"
            ));
        }
        Ok(Sdf {
            nodes: self.nodes,
            root,
            bounds,
            epsilon,
            max_steps,
            gradient_step: (epsilon * 0.5).max(extent * 1e-6),
            cap_hits: RayCount::default(),
            origin: None,
        })
    }
}

/// The largest distance from the axis perpendicular to axes `a` and `b`
/// of a point of `b`.
fn radius_around(b: Aabb, a: usize, c: usize) -> f32 {
    let m = |i: usize| b.min[i].abs().max(b.max[i].abs());
    (m(a) * m(a) + m(c) * m(c)).sqrt()
}

fn grow(b: Aabb, by: f32) -> Aabb {
    Aabb {
        min: b.min - Vec3::splat(by),
        max: b.max + Vec3::splat(by),
    }
}

/// The largest singular value of `m`: the most it stretches a vector,
/// from the largest eigenvalue of mᵀm (Smith 1961's closed form for
/// symmetric 3×3 matrices), in double precision, rounded up.
fn largest_singular_value(m: Mat3) -> f32 {
    let d = m.as_dmat3();
    let a = d.transpose() * d;
    let (a00, a11, a22) = (a.x_axis.x, a.y_axis.y, a.z_axis.z);
    let (a01, a02, a12) = (a.y_axis.x, a.z_axis.x, a.z_axis.y);
    let p1 = a01 * a01 + a02 * a02 + a12 * a12;
    let lambda = if p1 == 0.0 {
        a00.max(a11).max(a22)
    } else {
        let q = (a00 + a11 + a22) / 3.0;
        let p2 = (a00 - q).powi(2) + (a11 - q).powi(2) + (a22 - q).powi(2) + 2.0 * p1;
        let p = (p2 / 6.0).sqrt();
        let b = (a - glam::DMat3::from_diagonal(glam::DVec3::splat(q))) * (1.0 / p);
        let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
        let phi = r.acos() / 3.0;
        q + 2.0 * p * phi.cos()
    };
    (lambda.max(0.0).sqrt() * (1.0 + 1e-6)) as f32
}

/// A count of rays kept by a shape for a report after the render (rays
/// whose march or root search gave up). Not part of the shape's identity:
/// clones start from zero and compare equal.
#[derive(Debug, Default)]
pub struct RayCount(AtomicU64);

impl RayCount {
    /// Counts one more ray.
    pub fn add(&self) {
        self.0.fetch_add(1, Ordering::Relaxed);
    }

    /// The rays counted so far.
    pub fn get(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
}

impl Clone for RayCount {
    fn clone(&self) -> Self {
        RayCount::default()
    }
}

impl PartialEq for RayCount {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// A distance function ready to be traced.
#[derive(Clone, Debug, PartialEq)]
pub struct Sdf {
    nodes: Vec<SdfNode>,
    root: u32,
    bounds: Aabb,
    /// Hit tolerance, object units.
    epsilon: f32,
    /// Steps allowed to one ray.
    max_steps: u32,
    /// Step of the central differences.
    gradient_step: f32,
    cap_hits: RayCount,
    /// Where the scene defines it ("file:line:column"), for messages.
    origin: Option<String>,
}

/// What one march found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct March {
    /// The ray parameter of the hit.
    pub hit: Option<f32>,
    /// Evaluations of the function.
    pub steps: u32,
    /// Whether the march gave up at its cap of steps.
    pub capped: bool,
}

thread_local! {
    static STEPS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Evaluations of distance functions by marches on this thread so far
/// (read before and after a query to learn what it cost: the `steps`
/// image).
pub fn steps_on_this_thread() -> u64 {
    STEPS.with(|s| s.get())
}

/// Adds `n` to this thread's count of [`steps_on_this_thread`] (the
/// implicit surfaces' interval evaluations count as steps too).
pub(crate) fn add_steps(n: u64) {
    STEPS.with(|s| s.set(s.get() + n));
}

impl Sdf {
    /// Object-space bounds.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The shape, named by where the scene defines it.
    pub fn with_origin(mut self, origin: String) -> Sdf {
        self.origin = Some(origin);
        self
    }

    /// Where the scene defines the shape, if known.
    pub fn origin(&self) -> Option<&str> {
        self.origin.as_deref()
    }

    /// Hit tolerance.
    pub fn epsilon(&self) -> f32 {
        self.epsilon
    }

    /// Rays that ran out of steps since the shape was made.
    pub fn step_cap_hits(&self) -> u64 {
        self.cap_hits.get()
    }

    /// Steps a ray may take.
    pub fn max_steps(&self) -> u32 {
        self.max_steps
    }

    /// The value at `p`: negative inside, a lower bound of the distance to
    /// the surface outside.
    pub fn value(&self, p: Vec3) -> f32 {
        self.eval(self.root, p)
    }

    /// Distance to the first intersection within the ray's interval, the
    /// ray in object space.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let m = self.march(ray);
        add_steps(m.steps as u64);
        m.hit
    }

    /// Sphere traces `ray` (object space).
    pub fn march(&self, ray: &Ray) -> March {
        let mut out = March {
            hit: None,
            steps: 0,
            capped: false,
        };
        let len = ray.dir.length();
        if !(len > 0.0 && len.is_finite() && ray.origin.is_finite()) {
            return out;
        }
        let Some((t0, t1)) = self.bounds.intersect(ray, ray.dir.recip()) else {
            return out;
        };
        let d = ray.dir / len;
        let (start, end) = (t0 * len, t1 * len);
        let at = |s: f32| ray.origin + d * s;
        // The side the ray starts on: it looks for the surface from there.
        let side = if self.value(at(start)) < 0.0 { -1.0 } else { 1.0 };
        let eps = self.epsilon;
        let mut s = start;
        let mut omega = OVER_RELAXATION;
        let (mut prev_r, mut step) = (0.0f32, 0.0f32);
        while out.steps < self.max_steps {
            out.steps += 1;
            let r = side * self.value(at(s));
            if !r.is_finite() {
                return out;
            }
            // Over-relaxed, the last step may have jumped past the surface:
            // its unbounding sphere and this one must overlap, or it goes
            // back to a plain step (Keinert et al. 2014, listing 2).
            if omega > 1.0 && (r < 0.0 || r + prev_r < step) {
                s -= step - prev_r;
                step = prev_r;
                omega = 1.0;
                continue;
            }
            if r < eps {
                out.hit = Some(self.refine(ray.origin, d, s, side) / len);
                return out;
            }
            prev_r = r;
            step = r * omega;
            s += step;
            if s > end {
                // An over-relaxed step may have jumped past a surface near
                // the end of the bounds (the far side of a solid a ray
                // leaves): the plain step, which cannot, decides.
                if omega > 1.0 && s - step + prev_r <= end {
                    s -= step - prev_r;
                    step = prev_r;
                    omega = 1.0;
                    continue;
                }
                return out;
            }
        }
        // Out of steps: a ray that has crept along within a few ε of a
        // surface (a concave or fractal one) stops there; any other passes
        // through, and is counted.
        let r = side * self.value(at(s));
        if r.abs() < 16.0 * eps {
            out.hit = Some(self.refine(ray.origin, d, s, side) / len);
            return out;
        }
        out.capped = true;
        self.cap_hits.add();
        out
    }

    /// A few plain steps from a hit at `s`, which never pass the surface,
    /// to bring the point closer to it.
    fn refine(&self, o: Vec3, d: Vec3, mut s: f32, side: f32) -> f32 {
        let target = self.epsilon * 0.01;
        for _ in 0..8 {
            let r = side * self.value(o + d * s);
            if r.is_nan() || r <= target {
                break;
            }
            s += r;
        }
        s
    }

    /// The surface at a point found by [`Sdf::intersect`] (object space):
    /// the gradient as the normal; (u, v) are spherical coordinates around
    /// the bounds' centre.
    pub fn surface(&self, p: Vec3) -> LocalSurface {
        let g = self.gradient(self.root, p);
        let n = g.try_normalize().unwrap_or(Vec3::Z);
        let (dpdu, dpdv) = orthonormal_basis(n);
        let c = (p - self.bounds.centroid()).normalize_or(Vec3::Y);
        let uv = Vec2::new(
            c.z.atan2(c.x) * (0.5 * std::f32::consts::FRAC_1_PI) + 0.5,
            c.y.clamp(-1.0, 1.0).acos() * std::f32::consts::FRAC_1_PI,
        );
        // A ray leaving the surface must start where the value exceeds ε,
        // or it would meet the surface again at once: the value grows by
        // |∇f| per unit along the normal.
        let offset = 3.0 * self.epsilon / g.length().clamp(1e-3, 1.0);
        LocalSurface {
            p,
            p_error: Vec3::splat(offset) + p.abs() * (8.0 * f32::EPSILON),
            n,
            uv,
            dpdu,
            dpdv,
        }
    }

    fn eval(&self, i: u32, p: Vec3) -> f32 {
        match self.nodes[i as usize] {
            SdfNode::Sphere { radius } => p.length() - radius,
            SdfNode::Box { half } => {
                let q = p.abs() - half;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            }
            SdfNode::Torus { major, minor } => Vec2::new(Vec2::new(p.x, p.z).length() - major, p.y).length() - minor,
            SdfNode::Capsule { a, b, radius } => {
                let (pa, ba) = (p - a, b - a);
                let h = (pa.dot(ba) / ba.dot(ba).max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
                (pa - ba * h).length() - radius
            }
            SdfNode::Cylinder { radius, half_height } => {
                let d = Vec2::new(Vec2::new(p.x, p.z).length() - radius, p.y.abs() - half_height);
                d.max_element().min(0.0) + d.max(Vec2::ZERO).length()
            }
            SdfNode::Cone { radius, height } => cone(p, radius, height),
            SdfNode::Plane { normal, offset } => p.dot(normal) - offset,
            SdfNode::Mandelbulb { power, iterations } => mandelbulb(p, power, iterations),
            SdfNode::Union { a, b, smooth } => smooth_min(self.eval(a, p), self.eval(b, p), smooth).0,
            SdfNode::Intersection { a, b, smooth } => -smooth_min(-self.eval(a, p), -self.eval(b, p), smooth).0,
            SdfNode::Difference { a, b, smooth } => -smooth_min(-self.eval(a, p), self.eval(b, p), smooth).0,
            SdfNode::Round { child, radius } => self.eval(child, p) - radius,
            SdfNode::Transform { child, to_child, scale } => {
                self.eval(child, to_child.transform_point3a(p.into()).into()) * scale
            }
            SdfNode::Repeat {
                child,
                period,
                count,
                margin,
            } => {
                let (q, boundary) = repeat_cell(p, period, count);
                self.eval(child, q).min(boundary + margin)
            }
            SdfNode::Twist {
                child,
                rate,
                scale,
                region,
            } => bounded(region, p, |q| self.eval(child, twist(q, rate)) * scale),
            SdfNode::Bend {
                child,
                rate,
                scale,
                region,
            } => bounded(region, p, |q| self.eval(child, bend(q, rate)) * scale),
            SdfNode::Displace {
                child,
                amplitude,
                frequency,
                seed,
                scale,
            } => (self.eval(child, p) + amplitude * value_noise(p * frequency, seed)) * scale,
        }
    }

    /// The gradient of node `i` at `p` (not normalised): analytic where
    /// the node has one, central differences below the others.
    fn gradient(&self, i: u32, p: Vec3) -> Vec3 {
        match self.nodes[i as usize] {
            SdfNode::Sphere { .. } => p.normalize_or(Vec3::Y),
            SdfNode::Box { half } => {
                let q = p.abs() - half;
                let sign = Vec3::ONE.copysign(p);
                if q.max_element() > 0.0 {
                    (q.max(Vec3::ZERO) * sign).normalize_or(Vec3::Y)
                } else {
                    let axis = if q.x >= q.y && q.x >= q.z {
                        Vec3::X
                    } else if q.y >= q.z {
                        Vec3::Y
                    } else {
                        Vec3::Z
                    };
                    axis * sign
                }
            }
            SdfNode::Torus { major, .. } => {
                let radial = Vec2::new(p.x, p.z).normalize_or(Vec2::X);
                let q = Vec2::new(Vec2::new(p.x, p.z).length() - major, p.y).normalize_or(Vec2::Y);
                Vec3::new(q.x * radial.x, q.y, q.x * radial.y)
            }
            SdfNode::Capsule { a, b, .. } => {
                let (pa, ba) = (p - a, b - a);
                let h = (pa.dot(ba) / ba.dot(ba).max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
                (pa - ba * h).normalize_or(Vec3::Y)
            }
            SdfNode::Cylinder { radius, half_height } => {
                let radial = Vec2::new(p.x, p.z).normalize_or(Vec2::X);
                let d = Vec2::new(Vec2::new(p.x, p.z).length() - radius, p.y.abs() - half_height);
                let side = Vec3::new(radial.x, 0.0, radial.y);
                let cap = Vec3::Y * 1.0f32.copysign(p.y);
                if d.max_element() > 0.0 {
                    let o = d.max(Vec2::ZERO);
                    (side * o.x + cap * o.y).normalize_or(Vec3::Y)
                } else if d.x > d.y {
                    side
                } else {
                    cap
                }
            }
            SdfNode::Plane { normal, .. } => normal,
            SdfNode::Union { a, b, smooth } => {
                let (fa, fb) = (self.eval(a, p), self.eval(b, p));
                let w = smooth_min(fa, fb, smooth).1;
                self.blend(a, b, p, w, 1.0)
            }
            SdfNode::Intersection { a, b, smooth } => {
                let (fa, fb) = (self.eval(a, p), self.eval(b, p));
                let w = smooth_min(-fa, -fb, smooth).1;
                self.blend(a, b, p, w, 1.0)
            }
            SdfNode::Difference { a, b, smooth } => {
                let (fa, fb) = (self.eval(a, p), self.eval(b, p));
                let w = smooth_min(-fa, fb, smooth).1;
                self.blend(a, b, p, w, -1.0)
            }
            SdfNode::Round { child, .. } => self.gradient(child, p),
            SdfNode::Transform { child, to_child, scale } => {
                let q: Vec3 = to_child.transform_point3a(p.into()).into();
                Mat3::from(to_child.matrix3).transpose() * self.gradient(child, q) * scale
            }
            SdfNode::Repeat {
                child,
                period,
                count,
                margin,
            } => {
                let (q, boundary) = repeat_cell(p, period, count);
                if self.eval(child, q) <= boundary + margin {
                    self.gradient(child, q)
                } else {
                    self.differences(i, p)
                }
            }
            SdfNode::Cone { .. }
            | SdfNode::Mandelbulb { .. }
            | SdfNode::Twist { .. }
            | SdfNode::Bend { .. }
            | SdfNode::Displace { .. } => self.differences(i, p),
        }
    }

    /// w·∇a + (1 − w)·sign·∇b, skipping an operand whose weight is zero.
    fn blend(&self, a: u32, b: u32, p: Vec3, w: f32, sign: f32) -> Vec3 {
        let mut g = Vec3::ZERO;
        if w > 0.0 {
            g += self.gradient(a, p) * w;
        }
        if w < 1.0 {
            g += self.gradient(b, p) * ((1.0 - w) * sign);
        }
        g
    }

    /// The gradient of node `i` by central differences on a tetrahedron
    /// (four evaluations).
    fn differences(&self, i: u32, p: Vec3) -> Vec3 {
        let h = self.gradient_step;
        let k = [
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, 1.0),
        ];
        k.iter().map(|&k| k * self.eval(i, p + k * h)).sum::<Vec3>() / (4.0 * h)
    }
}

/// The polynomial smooth minimum of `a` and `b` over blend radius `k`
/// (Quilez 2013), and the weight of `a` in its gradient. It is at most
/// min(a, b), by at most k/4, and 1-Lipschitz: its gradient is a convex
/// combination of the two.
#[inline]
fn smooth_min(a: f32, b: f32, k: f32) -> (f32, f32) {
    if k <= 0.0 {
        return if a <= b { (a, 1.0) } else { (b, 0.0) };
    }
    let h = (k - (a - b).abs()).max(0.0) / k;
    let m = a.min(b) - h * h * k * 0.25;
    let w_min = 1.0 - 0.5 * h;
    (m, if a <= b { w_min } else { 1.0 - w_min })
}

/// The point of the original cell for `p`, and the distance from it to
/// the faces of its cell behind which a neighbouring copy lies.
#[inline]
fn repeat_cell(p: Vec3, period: Vec3, count: Vec3) -> (Vec3, f32) {
    let k = (p / period).round().clamp(-count, count);
    let q = p - period * k;
    let mut boundary = f32::INFINITY;
    for axis in 0..3 {
        if count[axis] == 0.0 {
            continue;
        }
        if k[axis] > -count[axis] {
            boundary = boundary.min(q[axis] + 0.5 * period[axis]);
        }
        if k[axis] < count[axis] {
            boundary = boundary.min(0.5 * period[axis] - q[axis]);
        }
    }
    (q, boundary)
}

/// A value that is a lower bound of the distance to a surface inside the
/// convex `region` (where `inner` is), extended to the whole space: from a
/// point outside, every point of the surface is at least
/// √(d² + inner(p′)²) away, d the distance to the region and p′ the
/// nearest point of it (the projection onto a convex set makes an obtuse
/// angle with every point of the set).
#[inline]
fn bounded(region: Aabb, p: Vec3, inner: impl Fn(Vec3) -> f32) -> f32 {
    let pc = p.clamp(region.min, region.max);
    let d = (p - pc).length();
    let v = inner(pc);
    if d == 0.0 {
        v
    } else {
        (d * d + v.max(0.0).powi(2)).sqrt()
    }
}

/// The twisted space's point in the child's space.
#[inline]
fn twist(p: Vec3, rate: f32) -> Vec3 {
    let (s, c) = (-rate * p.y).sin_cos();
    Vec3::new(c * p.x - s * p.z, p.y, s * p.x + c * p.z)
}

/// The bent space's point in the child's space.
#[inline]
fn bend(p: Vec3, rate: f32) -> Vec3 {
    let (s, c) = (-rate * p.x).sin_cos();
    Vec3::new(c * p.x - s * p.y, s * p.x + c * p.y, p.z)
}

/// The exact distance to a capped cone along y, base of `radius` at y = 0
/// and apex at y = `height`: in the half-plane (r, y) of the point, the
/// nearest of the base segment and the slanted side, negative inside.
fn cone(p: Vec3, radius: f32, height: f32) -> f32 {
    let q = Vec2::new(Vec2::new(p.x, p.z).length(), p.y);
    // The base: the segment from (0, 0) to (radius, 0).
    let base = Vec2::new((q.x - radius).max(0.0), q.y);
    // The side: the segment from (radius, 0) to (0, height).
    let e = Vec2::new(-radius, height);
    let w = q - Vec2::new(radius, 0.0);
    let t = (w.dot(e) / e.dot(e)).clamp(0.0, 1.0);
    let side = w - e * t;
    let d = base.length_squared().min(side.length_squared()).sqrt();
    // Inside: above the base and on the axis's side of the slanted line.
    let inside = q.y > 0.0 && q.y < height && e.perp_dot(w) > 0.0;
    if inside { -d } else { d }
}

/// The distance estimate of the Mandelbulb of `power`.
fn mandelbulb(p: Vec3, power: f32, iterations: u32) -> f32 {
    let mut z = p;
    let mut dr = 1.0f32;
    let mut r = z.length();
    for _ in 0..iterations {
        if !(1e-12..=2.0).contains(&r) {
            break;
        }
        let theta = (z.z / r).clamp(-1.0, 1.0).acos() * power;
        let phi = z.y.atan2(z.x) * power;
        dr = r.powf(power - 1.0) * power * dr + 1.0;
        let zr = r.powf(power);
        z = zr * Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()) + p;
        r = z.length();
    }
    if r < 1e-12 {
        return -1e-3;
    }
    0.5 * r.ln() * r / dr
}

/// Value noise in [−1, 1]: random values at the integer lattice, blended
/// by smoothstep.
fn value_noise(p: Vec3, seed: u32) -> f32 {
    let cell = p.floor();
    let f = p - cell;
    let w = f * f * (Vec3::splat(3.0) - 2.0 * f);
    let (x, y, z) = (cell.x as i32, cell.y as i32, cell.z as i32);
    let v = |dx: i32, dy: i32, dz: i32| lattice(x + dx, y + dy, z + dz, seed);
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let x00 = lerp(v(0, 0, 0), v(1, 0, 0), w.x);
    let x10 = lerp(v(0, 1, 0), v(1, 1, 0), w.x);
    let x01 = lerp(v(0, 0, 1), v(1, 0, 1), w.x);
    let x11 = lerp(v(0, 1, 1), v(1, 1, 1), w.x);
    lerp(lerp(x00, x10, w.y), lerp(x01, x11, w.y), w.z)
}

/// A pseudo-random value in [−1, 1] for a lattice point.
fn lattice(x: i32, y: i32, z: i32, seed: u32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343)
        ^ (y as u32).wrapping_mul(0xd816_3841)
        ^ (z as u32).wrapping_mul(0xcb1a_b31f)
        ^ seed.wrapping_mul(0x9e37_79b9);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7feb_352d);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846c_a68b);
    h ^= h >> 16;
    (h >> 8) as f32 * (2.0 / 16_777_216.0) - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Transform;
    use crate::sampling::rng::Pcg32;

    fn build(f: impl FnOnce(&mut SdfBuilder) -> Result<u32, String>) -> Sdf {
        let mut b = SdfBuilder::new();
        let root = f(&mut b).unwrap();
        b.build(root, None, DEFAULT_MAX_STEPS).unwrap()
    }

    /// A ray from a random point 3 bounds-radii out towards a random point
    /// of the bounds.
    fn aimed_ray(s: &Sdf, rng: &mut Pcg32) -> Ray {
        let b = s.bounds();
        let o = b.centroid() + random_dir(rng) * 1.5 * b.extent().length();
        let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let target = b.min + b.extent() * u;
        Ray::new(o, (target - o) * 0.5)
    }

    fn random_dir(rng: &mut Pcg32) -> Vec3 {
        crate::sampling::warp::sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()))
    }

    #[test]
    fn rays_meet_a_sphere_where_it_is() {
        let s = build(|b| b.sphere(1.0));
        let mut rng = Pcg32::new(7, 1);
        for _ in 0..500 {
            let o = random_dir(&mut rng) * 3.0;
            let target = random_dir(&mut rng) * 0.9;
            let ray = Ray::new(o, (target - o) * 0.5);
            let t = s.intersect(&ray).expect("a ray towards the inside hits");
            let p = ray.at(t);
            assert!((p.length() - 1.0).abs() < 2.0 * s.epsilon(), "{p}");
            let n = s.surface(p).n;
            assert!(n.dot(p.normalize()) > 0.9999);
        }
        // Past the sphere and away from it: no hit.
        assert!(s.intersect(&Ray::new(Vec3::new(0.0, 1.5, 3.0), -Vec3::Z)).is_none());
        assert!(s.intersect(&Ray::new(Vec3::new(0.0, 0.0, 3.0), Vec3::Z)).is_none());
        // A short ray stops before the surface.
        let short = Ray::with_interval(Vec3::new(0.0, 0.0, 3.0), -Vec3::Z, 0.0, 1.5);
        assert!(s.intersect(&short).is_none());
    }

    /// From just inside a sphere, every chord ends where it leaves: the
    /// over-relaxed steps overshoot the far side, which lies at the end
    /// of the bounds, and the plain step must still find it (it did not,
    /// for about one ray in fourteen).
    #[test]
    fn rays_from_inside_find_the_far_side_at_the_end_of_the_bounds() {
        let s = build(|b| b.sphere(0.5));
        let mut rng = Pcg32::new(11, 3);
        for _ in 0..2000 {
            let o = random_dir(&mut rng) * 0.4999;
            let mut d = random_dir(&mut rng);
            if d.dot(o) > 0.0 {
                d = -d;
            }
            let t = s.intersect(&Ray::new(o, d)).expect("the chord ends on the sphere");
            let p = o + d * t;
            assert!((p.length() - 0.5).abs() < 2.0 * s.epsilon(), "{p}");
        }
    }

    #[test]
    fn rays_leaving_the_surface_do_not_meet_it_again() {
        let s = build(|b| {
            let t = b.torus(1.0, 0.3)?;
            b.twist(t, 0.5)
        });
        let mut rng = Pcg32::new(3, 2);
        let mut hits = 0;
        for _ in 0..400 {
            let o = random_dir(&mut rng) * 4.0;
            let ray = Ray::new(o, random_dir(&mut rng) * 0.5 - o * 0.25);
            let Some(t) = s.intersect(&ray) else { continue };
            hits += 1;
            let ls = s.surface(ray.at(t));
            // Leave outwards along a random direction above the surface,
            // from the point offset as spawned rays are.
            let mut w = random_dir(&mut rng);
            if w.dot(ls.n) < 0.0 {
                w = -w;
            }
            let origin = ls.p + ls.n * ls.p_error.dot(ls.n.abs());
            if let Some(t2) = s.intersect(&Ray::new(origin, w)) {
                assert!(t2 > 10.0 * s.epsilon(), "met again at once: t = {t2}");
            }
            // Into the solid: the exit is found, beyond the offset.
            let inside = ls.p - ls.n * ls.p_error.dot(ls.n.abs());
            let t3 = s.intersect(&Ray::new(inside, -ls.n)).expect("the solid has an exit");
            assert!(t3 > 10.0 * s.epsilon());
        }
        assert!(hits > 50);
    }

    #[test]
    fn transformed_nodes_stay_bounds_and_hit_the_transformed_surface() {
        // A sphere scaled non-uniformly and sheared: an ellipsoid, whose
        // hits are checked by mapping them back onto the unit sphere.
        let to_parent = Transform::scale(Vec3::new(3.0, 0.5, 1.0))
            .unwrap()
            .then(&Transform::shear(0.7, 0.0, 0.0, 0.3, 0.0, 0.0).unwrap())
            .then(&Transform::rotate(Vec3::new(1.0, 1.0, 0.0), 40.0).unwrap());
        let s = build(|b| {
            let sp = b.sphere(1.0)?;
            b.transform(sp, &to_parent)
        });
        let mut rng = Pcg32::new(11, 5);
        let mut hits = 0;
        for _ in 0..500 {
            let ray = aimed_ray(&s, &mut rng);
            // The value is a bound: never above the true distance, checked
            // against points of the surface.
            let p = ray.origin * 0.3;
            let v = s.value(p);
            for _ in 0..50 {
                let q = to_parent.point(random_dir(&mut rng));
                assert!(v <= (p - q).length() + 1e-5);
            }
            let Some(t) = s.intersect(&ray) else { continue };
            hits += 1;
            let local = to_parent.inv_point(ray.at(t));
            assert!((local.length() - 1.0).abs() < 1e-3, "{}", local.length());
            let n = s.surface(ray.at(t)).n;
            let expected = to_parent.normal(local).normalize();
            assert!(n.dot(expected) > 0.999, "{n} {expected}");
        }
        assert!(hits > 100);
    }

    #[test]
    fn constructive_solids_and_their_gradients() {
        // A box minus a sphere: the ray down the axis passes the hole.
        let s = build(|b| {
            let bx = b.cuboid(Vec3::ONE)?;
            let sp = b.sphere(1.2)?;
            b.difference(bx, sp, 0.0)
        });
        let through_corner = Ray::new(Vec3::new(0.9, 0.9, 5.0), -Vec3::Z);
        let t = s.intersect(&through_corner).unwrap();
        assert!((through_corner.at(t).z - 1.0).abs() < 1e-3);
        let down_axis = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
        assert!(s.intersect(&down_axis).is_none());
        // Analytic gradients agree with differences wherever the value is
        // differentiable, smooth blends included.
        let smooth = build(|b| {
            let a = b.sphere(1.0)?;
            let c = b.torus(1.0, 0.25)?;
            let u = b.union(a, c, 0.4)?;
            let cut = b.cylinder(0.3, 4.0)?;
            let d = b.difference(u, cut, 0.1)?;
            let k = b.capsule(Vec3::new(-1.5, 0.0, 0.0), Vec3::new(1.5, 0.0, 0.0), 0.2)?;
            b.intersection(d, k, 0.05).and_then(|_| b.union(d, k, 0.2))
        });
        let mut rng = Pcg32::new(1, 9);
        for _ in 0..300 {
            let p = random_dir(&mut rng) * (0.5 + 1.5 * rng.next_f32());
            let a = smooth.gradient(smooth.root, p);
            let h = 1e-3;
            let num = Vec3::new(
                smooth.value(p + Vec3::X * h) - smooth.value(p - Vec3::X * h),
                smooth.value(p + Vec3::Y * h) - smooth.value(p - Vec3::Y * h),
                smooth.value(p + Vec3::Z * h) - smooth.value(p - Vec3::Z * h),
            ) / (2.0 * h);
            // Skip creases (where the numeric gradient straddles a kink).
            if (num.length() - 1.0).abs() > 0.05 || a.length() < 0.5 {
                continue;
            }
            assert!(a.normalize().dot(num.normalize()) > 0.99, "{p}: {a} vs {num}");
        }
    }

    #[test]
    fn operators_keep_the_value_a_lower_bound_of_the_distance() {
        // For each tree, sample points of the surface (by marching) and
        // check that no point's value exceeds its distance to any of them.
        let trees: Vec<Sdf> = vec![
            build(|b| {
                let bx = b.cuboid(Vec3::new(0.3, 1.0, 0.3))?;
                b.twist(bx, 1.5)
            }),
            build(|b| {
                let c = b.cylinder(0.2, 2.0)?;
                let r = b.transform(c, &Transform::rotate(Vec3::Z, 90.0).unwrap())?;
                b.bend(r, 0.6)
            }),
            build(|b| {
                let s = b.sphere(0.3)?;
                b.repeat(s, Vec3::new(1.0, 1.0, 0.0), [2, 1, 0])
            }),
            build(|b| {
                let s = b.sphere(1.0)?;
                b.displace(s, 0.1, 3.0, 4)
            }),
            build(|b| b.cone(1.0, 1.5)),
        ];
        let mut rng = Pcg32::new(5, 5);
        for (k, s) in trees.iter().enumerate() {
            let mut surface = Vec::new();
            for _ in 0..4000 {
                let ray = aimed_ray(s, &mut rng);
                if let Some(t) = s.intersect(&ray) {
                    surface.push(ray.at(t));
                }
            }
            assert!(surface.len() > 100, "tree {k}: {} hits", surface.len());
            for _ in 0..300 {
                let p = random_dir(&mut rng) * 3.0 * rng.next_f32();
                let v = s.value(p);
                let nearest = surface.iter().map(|q| (p - *q).length()).fold(f32::INFINITY, f32::min);
                assert!(
                    v <= nearest + 3e-3,
                    "tree {k}: value {v} at {p}, a surface point {nearest} away"
                );
            }
        }
    }

    #[test]
    fn the_cone_is_exact() {
        let s = build(|b| b.cone(1.0, 2.0));
        // On the axis above the apex, below the base, beside the rim, and
        // inside on the axis.
        assert!((s.value(Vec3::new(0.0, 3.0, 0.0)) - 1.0).abs() < 1e-6);
        assert!((s.value(Vec3::new(0.0, -0.5, 0.0)) - 0.5).abs() < 1e-6);
        assert!((s.value(Vec3::new(2.0, 0.0, 0.0)) - 1.0).abs() < 1e-6);
        let inside = s.value(Vec3::new(0.0, 0.1, 0.0));
        assert!((inside + 0.1).abs() < 1e-6, "{inside}");
    }

    #[test]
    fn a_mandelbulb_is_found_and_a_capped_march_is_counted() {
        let s = build(|b| b.mandelbulb(8.0, 10));
        let ray = Ray::new(Vec3::new(0.0, 0.0, 3.0), -Vec3::Z);
        let t = s.intersect(&ray).expect("the bulb is hit down its axis");
        assert!(t > 1.5 && t < 2.5, "{t}");
        assert_eq!(s.step_cap_hits(), 0);
        let mut b = SdfBuilder::new();
        let root = b.mandelbulb(8.0, 10).unwrap();
        let starved = b.build(root, Some(1e-6), 3).unwrap();
        let m = starved.march(&ray);
        assert!(m.capped && m.hit.is_none() && m.steps == 3);
        assert_eq!(starved.step_cap_hits(), 1);
    }

    #[test]
    fn bad_trees_are_errors() {
        let mut b = SdfBuilder::new();
        assert!(b.sphere(-1.0).unwrap_err().contains("radius"));
        assert!(b.cuboid(Vec3::new(1.0, f32::NAN, 1.0)).is_err());
        let p = b.plane(Vec3::Y, 0.0).unwrap();
        assert!(b.clone().build(p, None, 100).unwrap_err().contains("unbounded"));
        let s = b.sphere(1.0).unwrap();
        assert!(
            b.repeat(s, Vec3::splat(1.5), [1, 1, 1])
                .unwrap_err()
                .contains("overlap")
        );
        let far = b.sphere(0.1).unwrap();
        let moved = b
            .transform(far, &Transform::translate(Vec3::new(5.0, 0.0, 0.0)))
            .unwrap();
        assert!(b.intersection(s, moved, 0.0).unwrap_err().contains("empty"));
        assert!(b.mandelbulb(8.0, 1000).is_err());
        let cut = b.intersection(s, p, 0.0).unwrap();
        assert!(b.clone().build(cut, Some(0.0), 100).is_err());
        assert!(b.clone().build(cut, None, 0).is_err());
        assert!(b.build(cut, None, 100).is_ok());
        // Too deep.
        let mut b = SdfBuilder::new();
        let mut n = b.sphere(1.0).unwrap();
        let mut err = None;
        for _ in 0..100 {
            match b.round(n, 0.0) {
                Ok(m) => n = m,
                Err(e) => {
                    err = Some(e);
                    break;
                }
            }
        }
        assert!(err.unwrap().contains("nest"));
    }

    #[test]
    fn singular_values() {
        let m = Mat3::from_diagonal(Vec3::new(2.0, -5.0, 0.5));
        assert!((largest_singular_value(m) - 5.0).abs() < 1e-4);
        let r = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 1.0);
        assert!((largest_singular_value(r) - 1.0).abs() < 1e-5);
        let shear = Mat3::from_cols(Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Z);
        // Its largest singular value is the golden ratio.
        assert!((largest_singular_value(shear) - 1.618_034).abs() < 1e-4);
    }
}
