//! Axis-aligned bounding boxes.

use super::ray::Ray;
use glam::Vec3;

/// An axis-aligned box `[min, max]`. The empty box has `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// `1 + 2·γ(3)`: widening of the slab test's far distance that makes it
/// conservative under rounding (pbrt-v4, section 6.8.2).
const SLAB_ROUNDING: f32 = 1.0 + 2.0 * gamma(3);

/// γ(n) = n·ε / (1 − n·ε), the bound on the relative error of `n` chained
/// floating-point operations (Higham; pbrt-v4 eq. 6.23).
#[inline]
pub const fn gamma(n: i32) -> f32 {
    let e = f32::EPSILON * 0.5 * n as f32;
    e / (1.0 - e)
}

impl Aabb {
    /// The empty box: the identity of `union`.
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The box spanned by two corners given in any order.
    #[inline]
    pub fn new(a: Vec3, b: Vec3) -> Self {
        Aabb {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// The degenerate box holding one point.
    #[inline]
    pub fn from_point(p: Vec3) -> Self {
        Aabb { min: p, max: p }
    }

    /// The smallest box holding all the points.
    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, |b, p| b.union_point(p))
    }

    /// Whether the box holds no point.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// The smallest box holding both boxes.
    #[inline]
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// The smallest box holding this box and `p`.
    #[inline]
    pub fn union_point(&self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// `max − min` (negative for the empty box).
    #[inline]
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    /// The centre point.
    #[inline]
    pub fn centroid(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Surface area; 0 for the empty box.
    #[inline]
    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Index of the longest axis.
    #[inline]
    pub fn longest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    /// Whether `p` lies inside or on the boundary.
    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// Slab test against a ray whose reciprocal direction is given.
    /// Returns the entry and exit distances clipped to the ray's interval.
    #[inline]
    pub fn intersect(&self, ray: &Ray, inv_dir: Vec3) -> Option<(f32, f32)> {
        let t0 = (self.min - ray.origin) * inv_dir;
        let t1 = (self.max - ray.origin) * inv_dir;
        let near = t0.min(t1);
        let far = t0.max(t1) * SLAB_ROUNDING;
        let t_enter = near.max_element().max(ray.t_min);
        let t_exit = far.min_element().min(ray.t_max);
        if t_enter <= t_exit {
            Some((t_enter, t_exit))
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn union_and_area() {
        let a = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let b = Aabb::new(Vec3::splat(2.0), Vec3::splat(3.0));
        let u = a.union(&b);
        assert_eq!(u.min, Vec3::ZERO);
        assert_eq!(u.max, Vec3::splat(3.0));
        assert_eq!(a.surface_area(), 6.0);
        assert_eq!(Aabb::EMPTY.surface_area(), 0.0);
        assert!(Aabb::EMPTY.is_empty());
        assert_eq!(Aabb::EMPTY.union(&a), a);
    }

    #[test]
    fn slab_hit_miss_and_inside() {
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        let (t0, t1) = b.intersect(&r, r.dir.recip()).unwrap();
        assert!((t0 - 4.0).abs() < 1e-6 && (t1 - 6.0).abs() < 1e-5);
        let miss = Ray::new(Vec3::new(2.0, 0.0, -5.0), Vec3::Z);
        assert!(b.intersect(&miss, miss.dir.recip()).is_none());
        let inside = Ray::new(Vec3::ZERO, Vec3::X);
        let (t0, _) = b.intersect(&inside, inside.dir.recip()).unwrap();
        assert_eq!(t0, 0.0);
        // An interval that ends before the box reaches no hit.
        let behind = Ray::with_interval(Vec3::new(0.0, 0.0, -5.0), Vec3::Z, 0.0, 3.0);
        assert!(b.intersect(&behind, behind.dir.recip()).is_none());
    }
}
