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
