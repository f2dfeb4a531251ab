//! Transforms that change while the shutter is open (motion blur), as
//! pbrt-v4's `AnimatedTransform` (pbrt-v4 section 3.10.1, after Shoemake
//! and Duff 1992): each end's matrix is split into a translation T, a
//! rotation R and a remaining stretch S (a polar decomposition), and the
//! transform at a time between the ends interpolates T and S linearly and R
//! by spherical interpolation, so that a turning object keeps its shape.

use super::bounds::Aabb;
use super::transform::Transform;
use glam::{Mat3, Mat4, Quat, Vec3};

/// An object-to-world transform given at two times; before the first it is
/// the first's, after the second the second's.
#[derive(Clone, Debug, PartialEq)]
pub struct MotionTransform {
    ends: [Transform; 2],
    times: [f32; 2],
    translation: [Vec3; 2],
    rotation: [Quat; 2],
    stretch: [Mat3; 2],
    /// The angle (radians) the rotation turns through between the ends.
    angle: f32,
}

impl MotionTransform {
    /// The motion from `start` at `start_time` to `end` at `end_time`
    /// (`end_time > start_time`); `None` where an end's matrix cannot be
    /// split into translation, rotation and stretch in f32 (entries so
    /// large or small that the polar decomposition overflows).
    pub fn new(start: Transform, end: Transform, start_time: f32, end_time: f32) -> Option<MotionTransform> {
        let (t0, r0, s0) = decompose(&start.m);
        let (t1, mut r1, s1) = decompose(&end.m);
        // q and −q are the same rotation; the nearer one makes the
        // interpolation take the short way round (pbrt-v4 does the same).
        if r0.dot(r1) < 0.0 {
            r1 = -r1;
        }
        let finite = |r: Quat, s: Mat3| r.is_finite() && s.is_finite();
        if !(finite(r0, s0) && finite(r1, s1)) {
            return None;
        }
        let angle = 2.0 * r0.dot(r1).clamp(-1.0, 1.0).acos();
        Some(MotionTransform {
            ends: [start, end],
            times: [start_time, end_time],
            translation: [t0, t1],
            rotation: [r0, r1],
            stretch: [s0, s1],
            angle,
        })
    }

    /// The transform at the shutter's opening.
    pub fn start(&self) -> &Transform {
        &self.ends[0]
    }

    /// The transform at `time`.
    #[inline]
    pub fn at(&self, time: f32) -> Transform {
        let [t0, t1] = self.times;
        if time <= t0 {
            return self.ends[0];
        }
        if time >= t1 {
            return self.ends[1];
        }
        self.between((time - t0) / (t1 - t0))
    }

    /// The transform a fraction `u` ∈ [0, 1] of the way from start to end.
    fn between(&self, u: f32) -> Transform {
        let t = self.translation[0].lerp(self.translation[1], u);
        let r = self.rotation[0].slerp(self.rotation[1], u).normalize();
        let s = self.stretch[0] * (1.0 - u) + self.stretch[1] * u;
        let rs = Mat3::from_quat(r) * s;
        let m = Mat4::from_cols(
            rs.x_axis.extend(0.0),
            rs.y_axis.extend(0.0),
            rs.z_axis.extend(0.0),
            t.extend(1.0),
        );
        // (T·R·S)⁻¹ = S⁻¹·Rᵀ·T⁻¹, with no general 4×4 inverse.
        let inv3 = s.inverse() * Mat3::from_quat(r.conjugate());
        let inv = Mat4::from_cols(
            inv3.x_axis.extend(0.0),
            inv3.y_axis.extend(0.0),
            inv3.z_axis.extend(0.0),
            (-(inv3 * t)).extend(1.0),
        );
        Transform { m, inv }
    }

    /// A box holding `b` (object space) at every time of the motion.
    ///
    /// Without rotation every point moves on a straight line and the boxes
    /// at the two ends bound it. With rotation the box's corners are placed
    /// at `STEPS + 1` times and each placement is grown by how far a corner
    /// can move in half a step: |ΔT| + θ·max(|S₀c|, |S₁c|) + |ΔS·c| bounds
    /// its speed (θ the angle turned, R's rate of turn being constant under
    /// spherical interpolation), so the box holds every time in between.
    pub fn bounds(&self, b: &Aabb) -> Aabb {
        let ends = self.ends[0].aabb(b).union(&self.ends[1].aabb(b));
        if b.is_empty() || self.angle <= 1e-6 {
            return ends;
        }
        const STEPS: usize = 32;
        let corners: [Vec3; 8] = std::array::from_fn(|i| {
            Vec3::new(
                [b.min.x, b.max.x][i & 1],
                [b.min.y, b.max.y][(i >> 1) & 1],
                [b.min.z, b.max.z][i >> 2],
            )
        });
        let dt = (self.translation[1] - self.translation[0]).length();
        let ds = self.stretch[1] - self.stretch[0];
        let speed = corners
            .iter()
            .map(|&c| {
                let reach = (self.stretch[0] * c).length().max((self.stretch[1] * c).length());
                dt + self.angle * reach + (ds * c).length()
            })
            .fold(0.0f32, f32::max);
        let pad = Vec3::splat(speed * 0.5 / STEPS as f32);
        let mut out = ends;
        for step in 0..=STEPS {
            let m = self.between(step as f32 / STEPS as f32);
            for &c in &corners {
                let p = m.point(c);
                out = out.union(&Aabb::new(p - pad, p + pad));
            }
        }
        out
    }
}

/// T, R and S with M = T·R·S for an affine `m`: the translation, the
/// rotation of the polar decomposition of the upper 3×3 part (by averaging
/// it with its inverse transpose until it stops changing; Higham 1986) and
/// what remains. A part that mirrors is kept in S, so that R is a rotation.
fn decompose(m: &Mat4) -> (Vec3, Quat, Mat3) {
    let t = m.w_axis.truncate();
    let a = Mat3::from_mat4(*m);
    let mut r = a;
    for _ in 0..100 {
        let next = (r + r.inverse().transpose()) * 0.5;
        let change = (next - r)
            .to_cols_array()
            .iter()
            .fold(0.0f32, |acc, x| acc.max(x.abs()));
        r = next;
        if change <= 1e-6 {
            break;
        }
    }
    if r.determinant() < 0.0 {
        r = -r;
    }
    let q = Quat::from_mat3(&r).normalize();
    // S from the rotation actually used, so that T·R·S gives `m` back.
    let s = Mat3::from_quat(q).transpose() * a;
    (t, q, s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn close(a: &Mat4, b: &Mat4, tol: f32) -> bool {
        a.to_cols_array()
            .iter()
            .zip(b.to_cols_array())
            .all(|(x, y)| (x - y).abs() <= tol * (1.0 + y.abs()))
    }

    fn random_transform(rng: &mut Pcg32) -> Transform {
        let mut u = || rng.next_f32();
        let axis = Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5).normalize();
        let m = Mat4::from_translation(Vec3::new(u() * 10.0 - 5.0, u() * 10.0 - 5.0, u() * 10.0 - 5.0))
            * Mat4::from_axis_angle(axis, u() * 6.0)
            * Mat4::from_scale(Vec3::new(0.5 + u(), 0.5 + u(), 0.5 + u()));
        Transform::from_matrix(m).unwrap()
    }

    #[test]
    fn the_ends_are_the_given_transforms() {
        let mut rng = Pcg32::new(7, 1);
        for _ in 0..100 {
            let (a, b) = (random_transform(&mut rng), random_transform(&mut rng));
            let motion = MotionTransform::new(a, b, 0.0, 1.0).unwrap();
            assert!(
                close(&motion.between(0.0).m, &a.m, 1e-4),
                "{:?} {:?}",
                motion.between(0.0).m,
                a.m
            );
            assert!(close(&motion.between(1.0).m, &b.m, 1e-4));
            assert_eq!(motion.at(-1.0), a);
            assert_eq!(motion.at(2.0), b);
            let mid = motion.between(0.37);
            assert!(close(&(mid.m * mid.inv), &Mat4::IDENTITY, 1e-4));
        }
    }

    #[test]
    fn a_mirroring_end_decomposes_into_a_rotation() {
        let m = Mat4::from_scale(Vec3::new(-1.0, 2.0, 1.0)) * Mat4::from_rotation_z(0.3);
        let (t, r, s) = decompose(&m);
        assert!((r.length() - 1.0).abs() < 1e-5);
        let back = Mat4::from_translation(t) * Mat4::from_quat(r) * Mat4::from_mat3(s);
        assert!(close(&back, &m, 1e-5));
    }

    #[test]
    fn a_rotation_turns_at_constant_rate_about_its_axis() {
        let a = Transform::IDENTITY;
        let b = Transform::rotate(Vec3::Z, 90.0).unwrap();
        let motion = MotionTransform::new(a, b, 2.0, 4.0).unwrap();
        let p = motion.at(3.0).point(Vec3::X);
        let h = std::f32::consts::FRAC_1_SQRT_2;
        assert!((p - Vec3::new(h, h, 0.0)).length() < 1e-5, "{p}");
    }

    #[test]
    fn bounds_hold_the_box_at_every_time() {
        let mut rng = Pcg32::new(3, 5);
        for _ in 0..200 {
            let (a, b) = (random_transform(&mut rng), random_transform(&mut rng));
            let motion = MotionTransform::new(a, b, 0.0, 1.0).unwrap();
            let lo = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let bx = Aabb::new(lo, lo + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 3.0);
            let bounds = motion.bounds(&bx);
            for _ in 0..64 {
                let time = rng.next_f32();
                let p = bx.min + (bx.max - bx.min) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                let q = motion.at(time).point(p);
                let slack = 1e-4 * (1.0 + q.abs().max_element());
                assert!(
                    q.cmpge(bounds.min - slack).all() && q.cmple(bounds.max + slack).all(),
                    "{q} outside {bounds:?}"
                );
            }
            // Not much looser than the boxes swept at many times.
            let mut swept = Aabb::EMPTY;
            for i in 0..=1000 {
                swept = swept.union(&motion.between(i as f32 / 1000.0).aabb(&bx));
            }
            let (e, s) = (bounds.extent(), swept.extent());
            assert!(e.cmple(s * 1.25 + 0.5).all(), "{e} against {s}");
        }
    }
}
