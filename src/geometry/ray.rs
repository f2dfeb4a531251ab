//! Rays: r(t) = o + t·d for t in the open-ended interval [t_min, t_max].

use glam::Vec3;

/// A ray with a parametric validity interval.
///
/// The direction is not required to be normalised: an affine transform of a
/// ray keeps `t` meaning the same point, which lets shapes intersect in their
/// object space and report world-space distances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin `o`.
    pub origin: Vec3,
    /// Direction `d`.
    pub dir: Vec3,
    /// Smallest accepted parameter.
    pub t_min: f32,
    /// Largest accepted parameter; shrinks to the closest hit during traversal.
    pub t_max: f32,
    /// When the ray is traced, within the camera's shutter interval: what
    /// moving objects it meets depends on it (motion blur). Rays continuing
    /// a path keep their path's time.
    pub time: f32,
}

impl Ray {
    /// A ray over `[0, ∞)`.
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray {
            origin,
            dir,
            t_min: 0.0,
            t_max: f32::INFINITY,
            time: 0.0,
        }
    }

    /// A ray over `[t_min, t_max]`.
    #[inline]
    pub fn with_interval(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Self {
        Ray {
            origin,
            dir,
            t_min,
            t_max,
            time: 0.0,
        }
    }

    /// Origin, direction and interval start, each coordinate read by a
    /// load of its own, for the intersection tests. Rays are often read
    /// right after they were written (a ray copied to shrink its interval,
    /// a shadow ray just spawned), and the compiler otherwise merges the
    /// reads of neighbouring coordinates into one wider load, which cannot
    /// take its value from the narrower stores still in flight and waits
    /// for them to reach the cache (a store-forwarding stall; its cost is
    /// in BENCHMARKS.md). Volatile reads are never merged.
    #[inline(always)]
    #[allow(unsafe_code)]
    pub fn read_by_field(&self) -> (Vec3, Vec3, f32) {
        // SAFETY: a reference is valid and aligned for reads.
        let f = |x: &f32| unsafe { std::ptr::read_volatile(x) };
        (
            Vec3::new(f(&self.origin.x), f(&self.origin.y), f(&self.origin.z)),
            Vec3::new(f(&self.dir.x), f(&self.dir.y), f(&self.dir.z)),
            f(&self.t_min),
        )
    }

    /// A copy of the ray made from [`Ray::read_by_field`]'s reads, for a
    /// traversal that shrinks the copy's interval: a plain copy reads the
    /// ray with wide loads, which wait on the stores of a ray just written.
    #[inline(always)]
    #[allow(unsafe_code)]
    pub fn copy_by_field(&self) -> Ray {
        let (origin, dir, t_min) = self.read_by_field();
        // SAFETY: a reference is valid and aligned for reads.
        let f = |x: &f32| unsafe { std::ptr::read_volatile(x) };
        Ray {
            origin,
            dir,
            t_min,
            t_max: f(&self.t_max),
            time: f(&self.time),
        }
    }

    /// The same ray traced at `time`.
    #[inline]
    pub fn at_time(mut self, time: f32) -> Self {
        self.time = time;
        self
    }

    /// The point `o + t·d`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}
