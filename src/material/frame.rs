//! Orthonormal shading frames: BSDFs work in a local space where the
//! shading normal is +z, so that cos θ is just the z component.

use crate::sampling::warp::orthonormal_basis;
use glam::Vec3;

/// An orthonormal basis (s, t, n).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub s: Vec3,
    /// Second tangent.
    pub t: Vec3,
    /// Normal.
    pub n: Vec3,
}

impl Frame {
    /// A frame around unit normal `n` with `s` along the projection of
    /// `tangent` (which need not be perpendicular; a degenerate one falls
    /// back to an arbitrary tangent).
    pub fn new(n: Vec3, tangent: Vec3) -> Frame {
        let s = (tangent - n * n.dot(tangent))
            .try_normalize()
            .unwrap_or_else(|| orthonormal_basis(n).0);
        Frame { s, t: n.cross(s), n }
    }

    /// The frame of unit normal `n` and a unit tangent `s` already
    /// perpendicular to it, such as a surface hit's `ns` and `tangent`:
    /// [`Frame::new`] would project and normalise `s` again, a square root
    /// and a division at every bounce for nothing.
    #[inline]
    pub fn from_orthonormal(n: Vec3, s: Vec3) -> Frame {
        debug_assert!(
            (s.length() - 1.0).abs() < 1e-3 && s.dot(n).abs() < 1e-3,
            "not a unit tangent perpendicular to the normal: {s} against {n}"
        );
        Frame { s, t: n.cross(s), n }
    }

    /// A frame around unit normal `n` with arbitrary tangents.
    pub fn from_normal(n: Vec3) -> Frame {
        let (s, t) = orthonormal_basis(n);
        Frame { s, t, n }
    }

    /// World direction to local coordinates.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// Local coordinates to a world direction.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_handedness() {
        let f = Frame::new(Vec3::new(0.0, 0.6, 0.8), Vec3::X);
        let v = Vec3::new(0.3, -0.2, 0.9);
        assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        assert!((f.to_local(f.n) - Vec3::Z).length() < 1e-6);
        assert!((f.s - Vec3::X).length() < 1e-6);
        assert!((f.s.cross(f.t) - f.n).length() < 1e-6);
        // An orthonormal pair gives the same frame without the projection.
        let g = Frame::from_orthonormal(f.n, f.s);
        assert_eq!(
            g,
            Frame {
                s: f.s,
                t: f.n.cross(f.s),
                n: f.n
            }
        );
        assert!((g.t - f.t).length() < 1e-6);
    }
}
