//! Affine transforms as 4×4 homogeneous matrices.
//!
//! Points carry w = 1 and are translated; vectors carry w = 0 and are not;
//! normals transform by the inverse transpose so that they stay perpendicular
//! to transformed surfaces (pbrt-v4, section 3.10). Every transform stores its
//! inverse, computed once when it is built.

use super::bounds::Aabb;
use super::ray::Ray;
use glam::{Mat3, Mat4, Vec3, Vec4};

/// An invertible affine transform and its inverse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// The matrix that maps points from the source space to the target space.
    pub m: Mat4,
    /// Its inverse.
    pub inv: Mat4,
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

/// Why a matrix can't be used as a transform.
#[derive(Clone, Debug, PartialEq)]
pub enum TransformError {
    /// The matrix has a zero (or nearly zero) determinant.
    Singular,
    /// Some entry is NaN or infinite.
    NotFinite,
    /// The bottom row is not (0, 0, 0, 1).
    NotAffine,
}

impl std::fmt::Display for TransformError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TransformError::Singular => write!(f, "the matrix is singular (determinant 0)"),
            TransformError::NotFinite => write!(f, "the matrix has a NaN or infinite entry"),
            TransformError::NotAffine => write!(f, "the bottom row must be 0 0 0 1"),
        }
    }
}

impl Transform {
    /// The identity transform.
    pub const IDENTITY: Transform = Transform {
        m: Mat4::IDENTITY,
        inv: Mat4::IDENTITY,
    };

    /// A transform from an affine matrix, checking that it can be inverted.
    pub fn from_matrix(m: Mat4) -> Result<Self, TransformError> {
        if !m.is_finite() {
            return Err(TransformError::NotFinite);
        }
        if m.row(3) != Vec4::W {
            return Err(TransformError::NotAffine);
        }
        let linear = Mat3::from_mat4(m);
        let det = linear.determinant();
        // Relative test: a matrix is singular if its determinant is tiny
        // compared with the product of its column lengths.
        let scale = linear.x_axis.length() * linear.y_axis.length() * linear.z_axis.length();
        if det == 0.0 || !det.is_finite() || det.abs() <= 1e-12 * scale {
            return Err(TransformError::Singular);
        }
        let inv = m.inverse();
        if !inv.is_finite() {
            return Err(TransformError::Singular);
        }
        Ok(Transform { m, inv })
    }

    /// Translation by `t`.
    pub fn translate(t: Vec3) -> Self {
        Transform {
            m: Mat4::from_translation(t),
            inv: Mat4::from_translation(-t),
        }
    }

    /// Scale by `s` along the axes. Zero factors give a singular transform.
    pub fn scale(s: Vec3) -> Result<Self, TransformError> {
        if s.x == 0.0 || s.y == 0.0 || s.z == 0.0 {
            return Err(TransformError::Singular);
        }
        if !s.is_finite() {
            return Err(TransformError::NotFinite);
        }
        Ok(Transform {
            m: Mat4::from_scale(s),
            inv: Mat4::from_scale(s.recip()),
        })
    }

    /// Rotation by `degrees` about `axis` (right-hand rule), by Rodrigues'
    /// formula. The axis need not be normalised but must not be zero.
    pub fn rotate(axis: Vec3, degrees: f32) -> Result<Self, TransformError> {
        if !axis.is_finite() || !degrees.is_finite() {
            return Err(TransformError::NotFinite);
        }
        let a = axis.try_normalize().ok_or(TransformError::Singular)?;
        let m = Mat4::from_axis_angle(a, degrees.to_radians());
        // A rotation's inverse is its transpose.
        Ok(Transform { m, inv: m.transpose() })
    }

    /// Shear: each coordinate gains multiples of the other two,
    /// `x' = x + xy·y + xz·z`, `y' = y + yx·x + yz·z`, `z' = z + zx·x + zy·y`.
    pub fn shear(xy: f32, xz: f32, yx: f32, yz: f32, zx: f32, zy: f32) -> Result<Self, TransformError> {
        let m = Mat4::from_cols(
            Vec4::new(1.0, yx, zx, 0.0),
            Vec4::new(xy, 1.0, zy, 0.0),
            Vec4::new(xz, yz, 1.0, 0.0),
            Vec4::W,
        );
        Self::from_matrix(m)
    }

    /// The camera-to-world transform of a viewer at `eye` looking at
    /// `target`, with `up` giving the vertical. Camera space has +x to the
    /// right of the image, +y up and +z forward (the viewing direction).
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> Result<Self, TransformError> {
        if !eye.is_finite() || !target.is_finite() || !up.is_finite() {
            return Err(TransformError::NotFinite);
        }
        let forward = (target - eye).try_normalize().ok_or(TransformError::Singular)?;
        let right = forward.cross(up).try_normalize().ok_or(TransformError::Singular)?;
        let true_up = right.cross(forward);
        let m = Mat4::from_cols(
            right.extend(0.0),
            true_up.extend(0.0),
            forward.extend(0.0),
            eye.extend(1.0),
        );
        Self::from_matrix(m)
    }

    /// The transform that applies `self` first, then `next`.
    #[inline]
    pub fn then(&self, next: &Transform) -> Transform {
        Transform {
            m: next.m * self.m,
            inv: self.inv * next.inv,
        }
    }

    /// The inverse transform.
    #[inline]
    pub fn inverse(&self) -> Transform {
        Transform {
            m: self.inv,
            inv: self.m,
        }
    }

    /// Whether this is exactly the identity.
    pub fn is_identity(&self) -> bool {
        self.m == Mat4::IDENTITY
    }

    /// Transforms a point (w = 1).
    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        self.m.transform_point3(p)
    }

    /// Transforms a point that carries a per-axis error bound, returning the
    /// new point and a bound that adds the rounding of the transform itself
    /// (pbrt-v4, section 6.8.3).
    #[inline]
    pub fn point_with_error(&self, p: Vec3, p_error: Vec3) -> (Vec3, Vec3) {
        let m = &self.m;
        let abs_cols = [
            m.x_axis.truncate().abs(),
            m.y_axis.truncate().abs(),
            m.z_axis.truncate().abs(),
        ];
        let abs_t = m.w_axis.truncate().abs();
        let from_p = abs_cols[0] * p.x.abs() + abs_cols[1] * p.y.abs() + abs_cols[2] * p.z.abs() + abs_t;
        let from_err = abs_cols[0] * p_error.x + abs_cols[1] * p_error.y + abs_cols[2] * p_error.z;
        let g3 = super::bounds::gamma(3);
        (self.point(p), g3 * from_p + (1.0 + g3) * from_err)
    }

    /// Transforms a vector (w = 0).
    #[inline]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        self.m.transform_vector3(v)
    }

    /// Transforms a surface normal by the inverse transpose (not normalised).
    #[inline]
    pub fn normal(&self, n: Vec3) -> Vec3 {
        // (M⁻¹)ᵀ·n, written without forming the transpose.
        let i = &self.inv;
        Vec3::new(
            i.x_axis.x * n.x + i.x_axis.y * n.y + i.x_axis.z * n.z,
            i.y_axis.x * n.x + i.y_axis.y * n.y + i.y_axis.z * n.z,
            i.z_axis.x * n.x + i.z_axis.y * n.y + i.z_axis.z * n.z,
        )
    }

    /// Applies the inverse transform to a point.
    #[inline]
    pub fn inv_point(&self, p: Vec3) -> Vec3 {
        self.inv.transform_point3(p)
    }

    /// Applies the inverse transform to a vector.
    #[inline]
    pub fn inv_vector(&self, v: Vec3) -> Vec3 {
        self.inv.transform_vector3(v)
    }

    /// Transforms a ray, keeping its direction unnormalised so that its
    /// parameter `t` names the same points before and after.
    #[inline]
    pub fn ray(&self, r: &Ray) -> Ray {
        Ray::with_interval(self.point(r.origin), self.vector(r.dir), r.t_min, r.t_max).at_time(r.time)
    }

    /// Maps a ray by the inverse transform (world to object space for a
    /// shape's object-to-world transform).
    #[inline]
    pub fn inv_ray(&self, r: &Ray) -> Ray {
        Ray::with_interval(self.inv_point(r.origin), self.inv_vector(r.dir), r.t_min, r.t_max).at_time(r.time)
    }

    /// The bounding box of a transformed box (Arvo's method: exact for the
    /// box's eight corners at the cost of a few multiplies).
    pub fn aabb(&self, b: &Aabb) -> Aabb {
        if b.is_empty() {
            return *b;
        }
        let t = self.m.w_axis.truncate();
        let mut min = t;
        let mut max = t;
        let cols = [self.m.x_axis, self.m.y_axis, self.m.z_axis];
        for (j, col) in cols.iter().enumerate() {
            let c = col.truncate();
            let a = c * b.min[j];
            let e = c * b.max[j];
            min += a.min(e);
            max += a.max(e);
        }
        Aabb { min, max }
    }

    /// Whether the transform mirrors space (negative determinant), which
    /// turns outward normals inward unless they are flipped.
    pub fn swaps_handedness(&self) -> bool {
        Mat3::from_mat4(self.m).determinant() < 0.0
    }

    /// Largest absolute entry of the upper 3×4 block, used to bound the
    /// rounding error that applying the transform adds.
    pub fn max_abs_entry(&self) -> f32 {
        let mut m = 0.0f32;
        for c in [self.m.x_axis, self.m.y_axis, self.m.z_axis, self.m.w_axis] {
            m = m.max(c.truncate().abs().max_element());
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3, eps: f32) -> bool {
        (a - b).abs().max_element() <= eps
    }

    fn samples() -> Vec<Transform> {
        vec![
            Transform::translate(Vec3::new(1.0, -2.0, 3.0)),
            Transform::scale(Vec3::new(2.0, 0.5, -3.0)).unwrap(),
            Transform::rotate(Vec3::new(1.0, 1.0, 0.0), 37.0).unwrap(),
            Transform::shear(0.5, 0.0, 0.25, 0.0, -0.3, 0.1).unwrap(),
            Transform::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO, Vec3::Y).unwrap(),
        ]
    }

    #[test]
    fn inverse_round_trips_points_and_vectors() {
        let p = Vec3::new(0.3, -1.7, 2.2);
        for t in samples() {
            assert!(close(t.inv_point(t.point(p)), p, 1e-5), "{t:?}");
            assert!(close(t.inv_vector(t.vector(p)), p, 1e-5), "{t:?}");
            assert!(close((t.m * t.inv).transform_point3(p), p, 1e-5));
        }
        let all = samples().iter().fold(Transform::IDENTITY, |acc, t| acc.then(t));
        assert!(close(all.inv_point(all.point(p)), p, 1e-4));
    }

    #[test]
    fn points_translate_vectors_do_not() {
        let t = Transform::translate(Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(t.point(Vec3::ZERO), Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(t.vector(Vec3::X), Vec3::X);
        assert_eq!(t.normal(Vec3::Y), Vec3::Y);
    }

    #[test]
    fn composition_order() {
        // Scale then translate: the origin lands on the translation.
        let t = Transform::scale(Vec3::splat(2.0))
            .unwrap()
            .then(&Transform::translate(Vec3::X));
        assert_eq!(t.point(Vec3::ZERO), Vec3::X);
        assert_eq!(t.point(Vec3::X), Vec3::new(3.0, 0.0, 0.0));
    }

    #[test]
    fn rotation_follows_right_hand_rule() {
        let r = Transform::rotate(Vec3::Z, 90.0).unwrap();
        assert!(close(r.point(Vec3::X), Vec3::Y, 1e-6));
        let r = Transform::rotate(Vec3::Y, 90.0).unwrap();
        assert!(close(r.point(Vec3::Z), Vec3::X, 1e-6));
    }

    #[test]
    fn normals_stay_perpendicular_under_shear_and_scale() {
        // The plane x + y = 0 has normal (1, 1, 0) and tangents (1, -1, 0), (0, 0, 1).
        let n = Vec3::new(1.0, 1.0, 0.0);
        let tangents = [Vec3::new(1.0, -1.0, 0.0), Vec3::Z];
        for t in samples() {
            let nt = t.normal(n);
            for tan in tangents {
                let d = nt.dot(t.vector(tan));
                assert!(d.abs() < 1e-5, "{t:?}: n·t = {d}");
            }
        }
    }

    #[test]
    fn shear_matches_its_definition() {
        let s = Transform::shear(0.5, 0.0, 0.0, 0.0, 0.0, 0.0).unwrap();
        assert!(close(s.point(Vec3::new(0.0, 2.0, 0.0)), Vec3::new(1.0, 2.0, 0.0), 1e-6));
        let s = Transform::shear(0.0, 0.0, 0.0, 0.0, 2.0, -1.0).unwrap();
        assert!(close(s.point(Vec3::new(1.0, 1.0, 0.0)), Vec3::new(1.0, 1.0, 1.0), 1e-6));
    }

    #[test]
    fn look_at_frame() {
        let t = Transform::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        assert!(close(t.vector(Vec3::Z), -Vec3::Z, 1e-6)); // forward
        assert!(close(t.vector(Vec3::X), Vec3::X, 1e-6)); // right
        assert!(close(t.vector(Vec3::Y), Vec3::Y, 1e-6)); // up
        assert!(Transform::look_at(Vec3::ZERO, Vec3::Y, Vec3::Y).is_err());
    }

    #[test]
    fn singular_and_invalid_matrices_are_rejected() {
        assert_eq!(
            Transform::scale(Vec3::new(1.0, 0.0, 1.0)),
            Err(TransformError::Singular)
        );
        assert_eq!(Transform::rotate(Vec3::ZERO, 10.0), Err(TransformError::Singular));
        assert_eq!(
            Transform::shear(1.0, 0.0, 1.0, 0.0, 0.0, 0.0),
            Err(TransformError::Singular)
        );
        let mut m = Mat4::IDENTITY;
        m.x_axis.x = f32::NAN;
        assert_eq!(Transform::from_matrix(m), Err(TransformError::NotFinite));
        let mut m = Mat4::IDENTITY;
        m.x_axis.w = 1.0;
        assert_eq!(Transform::from_matrix(m), Err(TransformError::NotAffine));
    }

    #[test]
    fn transformed_box_holds_transformed_corners() {
        let b = Aabb::new(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 3.0, 4.0));
        for t in samples() {
            let tb = t.aabb(&b);
            for i in 0..8 {
                let c = Vec3::new(
                    if i & 1 == 0 { b.min.x } else { b.max.x },
                    if i & 2 == 0 { b.min.y } else { b.max.y },
                    if i & 4 == 0 { b.min.z } else { b.max.z },
                );
                let p = t.point(c);
                assert!(tb.min.cmple(p + 1e-5).all() && tb.max.cmpge(p - 1e-5).all());
            }
        }
    }

    #[test]
    fn handedness() {
        assert!(Transform::scale(Vec3::new(-1.0, 1.0, 1.0)).unwrap().swaps_handedness());
        assert!(!Transform::rotate(Vec3::X, 45.0).unwrap().swaps_handedness());
    }
}
