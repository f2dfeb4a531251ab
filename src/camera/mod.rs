//! Cameras: perspective and orthographic projections with optional thin-lens
//! depth of field, each defined by a view transform (camera to world) and a
//! projection transform (camera to screen), as in pbrt-v4 chapter 5.
//!
//! Camera space has +x to the right of the image, +y up and +z along the
//! viewing direction. Raster space has (0, 0) at the top-left corner of the
//! image and (width, height) at the bottom-right.
//!
//! ```toml
//! [camera]
//! type = "perspective"      # or "orthographic"
//! from = [0, 1, 6.8]
//! to = [0, 1, 0]
//! up = [0, 1, 0]
//! fov = 40                  # vertical field of view, degrees
//! aperture_radius = 0.0     # > 0 turns on depth of field
//! focus_distance = 6.8
//! ```

use crate::geometry::{Ray, Transform};
use crate::sampling::Sampler;
use crate::sampling::warp::sample_disk_concentric;
use glam::{Mat4, Vec2, Vec3, Vec4};

/// The projection of a camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Perspective with a vertical field of view in degrees.
    Perspective {
        /// Vertical field of view, degrees, in (0, 180).
        fov_y: f32,
    },
    /// Orthographic with the height of the view plane in world units.
    Orthographic {
        /// Height of the visible region; its width follows the aspect ratio.
        height: f32,
    },
}

/// A camera ready to generate rays.
#[derive(Clone, Debug)]
pub struct Camera {
    /// The projection.
    pub projection: Projection,
    /// Camera space to world space (the inverse of the view transform).
    camera_to_world: Transform,
    /// Raster space to camera space (the inverse of projection followed by
    /// the screen-to-raster mapping).
    raster_to_camera: Transform,
    /// For a perspective projection, the world direction of a pinhole ray
    /// through raster point (x, y) up to a positive factor, as
    /// x·`[0]` + y·`[1]` + `[2]`, and the pinhole: both transforms folded
    /// into one affine map, so that a ray costs a few multiply-adds and
    /// one normalisation instead of a projective divide, two matrix
    /// products and two normalisations.
    pinhole: Option<([Vec3; 3], Vec3)>,
    /// The clipping planes' distances along the viewing axis, near and
    /// far, where there are any.
    clip: Option<(f32, f32)>,
    /// The viewing axis in world space (unit length).
    forward: Vec3,
    /// Lens radius; 0 for a pinhole.
    pub lens_radius: f32,
    /// Distance to the plane in focus.
    pub focus_distance: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// The perspective projection of pbrt-v4 (eq. 5.1): maps camera space to
/// screen space so that z = near goes to 0 and z = far to 1, and x, y are
/// divided by z and scaled by 1/tan(fov/2).
pub fn perspective_matrix(fov_y_degrees: f32, near: f32, far: f32) -> Mat4 {
    let persp = Mat4::from_cols(
        Vec4::new(1.0, 0.0, 0.0, 0.0),
        Vec4::new(0.0, 1.0, 0.0, 0.0),
        Vec4::new(0.0, 0.0, far / (far - near), 1.0),
        Vec4::new(0.0, 0.0, -far * near / (far - near), 0.0),
    );
    let inv_tan = 1.0 / (fov_y_degrees.to_radians() / 2.0).tan();
    Mat4::from_scale(Vec3::new(inv_tan, inv_tan, 1.0)) * persp
}

/// Orthographic projection: keeps x and y, maps z ∈ [near, far] to [0, 1].
pub fn orthographic_matrix(near: f32, far: f32) -> Mat4 {
    Mat4::from_scale(Vec3::new(1.0, 1.0, 1.0 / (far - near))) * Mat4::from_translation(Vec3::new(0.0, 0.0, -near))
}

impl Camera {
    /// A pinhole camera at `from` looking at `to`, with `up` giving the
    /// image's vertical. Errors if the view is degenerate (`from == to`, or
    /// `up` parallel to the view direction) or the image is empty.
    pub fn look_at(
        projection: Projection,
        from: Vec3,
        to: Vec3,
        up: Vec3,
        width: u32,
        height: u32,
    ) -> Result<Camera, String> {
        let camera_to_world = Transform::look_at(from, to, up).map_err(|_| {
            "the camera's `from`, `to` and `up` do not define a view (from = to, or up parallel to the view direction)"
                .to_string()
        })?;
        Self::from_transform(projection, camera_to_world, width, height)
    }

    /// A pinhole camera with an explicit camera-to-world transform.
    pub fn from_transform(
        projection: Projection,
        camera_to_world: Transform,
        width: u32,
        height: u32,
    ) -> Result<Camera, String> {
        if width == 0 || height == 0 {
            return Err("image size must be at least 1×1".into());
        }
        let aspect = width as f32 / height as f32;
        // Screen window: y ∈ [-1, 1] for perspective (scaled by the
        // projection), [-h/2, h/2] for orthographic.
        let (camera_to_screen, half_h) = match projection {
            Projection::Perspective { fov_y } => (perspective_matrix(fov_y, 1e-2, 1000.0), 1.0),
            Projection::Orthographic { height } => (orthographic_matrix(0.0, 1.0), height / 2.0),
        };
        let half_w = half_h * aspect;
        // Screen (x right, y up) → raster (x right, y down).
        let screen_to_raster = Mat4::from_scale(Vec3::new(width as f32, height as f32, 1.0))
            * Mat4::from_scale(Vec3::new(1.0 / (2.0 * half_w), -1.0 / (2.0 * half_h), 1.0))
            * Mat4::from_translation(Vec3::new(half_w, -half_h, 0.0));
        let camera_to_raster = screen_to_raster * camera_to_screen;
        let raster_to_camera = Transform {
            m: camera_to_raster.inverse(),
            inv: camera_to_raster,
        };
        // The raster plane z = 0 maps to homogeneous camera points
        // x·m₀ + y·m₁ + m₃; where their w is the same positive number
        // everywhere (as for this projection), the direction through the
        // pinhole is their x, y, z part up to that factor.
        let m = raster_to_camera.m;
        let pinhole = (matches!(projection, Projection::Perspective { .. })
            && m.x_axis.w == 0.0
            && m.y_axis.w == 0.0
            && m.w_axis.w > 0.0)
            .then(|| {
                let basis = [m.x_axis, m.y_axis, m.w_axis].map(|c| camera_to_world.vector(c.truncate()));
                (basis, camera_to_world.point(Vec3::ZERO))
            });
        let forward = camera_to_world.vector(Vec3::Z).normalize();
        Ok(Camera {
            projection,
            camera_to_world,
            raster_to_camera,
            pinhole,
            clip: None,
            forward,
            lens_radius: 0.0,
            focus_distance: 1.0,
            width,
            height,
        })
    }

    /// The same camera with a thin lens of the given radius focused at
    /// `focus_distance` (measured along the viewing direction).
    pub fn with_thin_lens(mut self, lens_radius: f32, focus_distance: f32) -> Camera {
        self.lens_radius = lens_radius;
        self.focus_distance = focus_distance;
        self
    }

    /// The same camera seeing only what lies between `near` and `far`
    /// along its viewing axis, as Mitsuba's `near_clip` and `far_clip`: a
    /// ray starts where it crosses the near plane and ends at the far one.
    pub fn with_clipping(mut self, near: f32, far: f32) -> Camera {
        self.clip = (near > 0.0 || far.is_finite()).then_some((near, far));
        self
    }

    /// The lens position of a camera sample: drawn from `sampler` for a
    /// camera with a lens, passed over (and zero, which
    /// [`Camera::generate_ray`] then ignores) for a pinhole.
    #[inline]
    pub fn draw_lens(&self, sampler: &mut Sampler) -> Vec2 {
        if self.lens_radius > 0.0 {
            sampler.next_2d()
        } else {
            sampler.skip_2d();
            Vec2::ZERO
        }
    }

    /// The ray through raster position `film` (pixels, continuous), using
    /// `lens` ∈ [0,1)² to pick a point on the lens. Directions are unit length.
    pub fn generate_ray(&self, film: Vec2, lens: Vec2) -> Ray {
        let ray = self.unclipped_ray(film, lens);
        match self.clip {
            None => ray,
            Some((near, far)) => {
                // Distances along the ray to the planes (Mitsuba's
                // `near_clip / d.z`, d.z the cosine to the viewing axis).
                let cos = ray.dir.dot(self.forward);
                let (t_near, t_far) = (near / cos, far / cos);
                Ray::with_interval(ray.origin + ray.dir * t_near, ray.dir, 0.0, t_far - t_near)
            }
        }
    }

    fn unclipped_ray(&self, film: Vec2, lens: Vec2) -> Ray {
        if let (Some(([a, b, c], origin)), true) = (self.pinhole, self.lens_radius <= 0.0) {
            return Ray::new(origin, (a * film.x + b * film.y + c).normalize());
        }
        let p_film = Vec3::new(film.x, film.y, 0.0);
        let (mut origin, mut dir) = match self.projection {
            Projection::Perspective { .. } => {
                // Homogeneous divide: the raster point maps to the near plane.
                let p = self.raster_to_camera.m.project_point3(p_film);
                (Vec3::ZERO, p.normalize())
            }
            Projection::Orthographic { .. } => {
                let p = self.raster_to_camera.m.transform_point3(p_film);
                (Vec3::new(p.x, p.y, 0.0), Vec3::Z)
            }
        };
        if self.lens_radius > 0.0 {
            // Thin lens: all rays through a point of the focal plane meet there.
            let p_lens = self.lens_radius * sample_disk_concentric(lens);
            let ft = self.focus_distance / dir.z;
            let p_focus = origin + dir * ft;
            origin += Vec3::new(p_lens.x, p_lens.y, 0.0);
            dir = (p_focus - origin).normalize();
        }
        let o = self.camera_to_world.point(origin);
        let d = self.camera_to_world.vector(dir).normalize();
        Ray::new(o, d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    fn persp(fov: f32, w: u32, h: u32) -> Camera {
        Camera::look_at(
            Projection::Perspective { fov_y: fov },
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::ZERO,
            Vec3::Y,
            w,
            h,
        )
        .unwrap()
    }

    /// Clipped rays start on the near plane and end on the far one, both
    /// measured along the viewing axis, for perspective and orthographic
    /// cameras; unclipped cameras give the rays they gave.
    #[test]
    fn clipping_planes_bound_the_rays() {
        let ortho = Camera::look_at(
            Projection::Orthographic { height: 2.0 },
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::ZERO,
            Vec3::Y,
            100,
            100,
        )
        .unwrap();
        for camera in [persp(90.0, 200, 100), ortho] {
            let clipped = camera.clone().with_clipping(2.0, 4.0);
            for film in [Vec2::new(100.0, 50.0), Vec2::new(3.0, 97.0), Vec2::new(180.0, 10.0)] {
                let (r, c) = (
                    camera.generate_ray(film, Vec2::ZERO),
                    clipped.generate_ray(film, Vec2::ZERO),
                );
                assert!(close(r.dir, c.dir));
                // Depths along the axis (−z here) of the clipped ray's ends.
                let depth = |p: Vec3| 5.0 - p.z;
                assert!((depth(c.origin) - 2.0).abs() < 1e-5, "{film}: {c:?}");
                assert!((depth(c.at(c.t_max)) - 4.0).abs() < 1e-5, "{film}: {c:?}");
                assert!(close(c.origin, r.at((c.origin - r.origin).length())));
            }
            let same = camera.clone().with_clipping(0.0, f32::INFINITY);
            let film = Vec2::new(7.0, 9.0);
            assert_eq!(
                same.generate_ray(film, Vec2::ZERO),
                camera.generate_ray(film, Vec2::ZERO)
            );
        }
    }

    #[test]
    fn perspective_centre_and_corners() {
        let c = persp(90.0, 200, 100);
        let centre = c.generate_ray(Vec2::new(100.0, 50.0), Vec2::ZERO);
        assert!(close(centre.origin, Vec3::new(0.0, 0.0, 5.0)));
        assert!(close(centre.dir, -Vec3::Z));
        // fov 90°: tan(45°) = 1 so the top edge centre is at 45° up;
        // aspect 2: the right edge is at atan(2) to the side.
        let top = c.generate_ray(Vec2::new(100.0, 0.0), Vec2::ZERO);
        assert!(close(top.dir, Vec3::new(0.0, 1.0, -1.0).normalize()));
        let top_left = c.generate_ray(Vec2::new(0.0, 0.0), Vec2::ZERO);
        assert!(close(top_left.dir, Vec3::new(-2.0, 1.0, -1.0).normalize()));
        let bottom_right = c.generate_ray(Vec2::new(200.0, 100.0), Vec2::ZERO);
        assert!(close(bottom_right.dir, Vec3::new(2.0, -1.0, -1.0).normalize()));
    }

    #[test]
    fn perspective_fov_is_vertical() {
        let c = persp(40.0, 64, 64);
        let top = c.generate_ray(Vec2::new(32.0, 0.0), Vec2::ZERO);
        let angle = top.dir.angle_between(-Vec3::Z).to_degrees();
        assert!((angle - 20.0).abs() < 1e-3, "{angle}");
    }

    #[test]
    fn orthographic_rays_are_parallel() {
        let c = Camera::look_at(
            Projection::Orthographic { height: 4.0 },
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::ZERO,
            Vec3::Y,
            100,
            50,
        )
        .unwrap();
        let centre = c.generate_ray(Vec2::new(50.0, 25.0), Vec2::ZERO);
        assert!(close(centre.origin, Vec3::new(0.0, 0.0, 5.0)) && close(centre.dir, -Vec3::Z));
        // Height 4, aspect 2: the view plane spans x ∈ [-4, 4], y ∈ [-2, 2].
        let tl = c.generate_ray(Vec2::new(0.0, 0.0), Vec2::ZERO);
        assert!(close(tl.origin, Vec3::new(-4.0, 2.0, 5.0)) && close(tl.dir, -Vec3::Z));
        let br = c.generate_ray(Vec2::new(100.0, 50.0), Vec2::ZERO);
        assert!(close(br.origin, Vec3::new(4.0, -2.0, 5.0)));
    }

    /// A pinhole camera passes over the lens sample, and its rays do not
    /// depend on it; a thin lens draws it.
    #[test]
    fn only_a_lens_draws_the_lens_sample() {
        use crate::sampling::SamplerKind;
        let pinhole = persp(45.0, 64, 48);
        let lens = persp(45.0, 64, 48).with_thin_lens(0.5, 5.0);
        let film = Vec2::new(10.3, 20.7);
        let a = pinhole.generate_ray(film, Vec2::new(0.1, 0.9));
        let b = pinhole.generate_ray(film, Vec2::new(0.8, 0.2));
        assert_eq!((a.origin, a.dir), (b.origin, b.dir));
        let mut s = Sampler::new(SamplerKind::Independent, 4, 1);
        s.start_pixel_sample(0, 0, 0);
        assert_eq!(pinhole.draw_lens(&mut s), Vec2::ZERO);
        let mut t = Sampler::new(SamplerKind::Independent, 4, 1);
        t.start_pixel_sample(0, 0, 0);
        let drawn = t.next_2d();
        // The pinhole passed over the point: the sampler is where drawing
        // it would have left it.
        assert_eq!(s.next_1d(), t.next_1d());
        s.start_pixel_sample(0, 0, 0);
        assert_eq!(lens.draw_lens(&mut s), drawn);
    }

    #[test]
    fn thin_lens_rays_meet_on_the_focal_plane() {
        let c = Camera::look_at(
            Projection::Perspective { fov_y: 50.0 },
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::ZERO,
            Vec3::Y,
            64,
            64,
        )
        .unwrap()
        .with_thin_lens(0.5, 5.0);
        let film = Vec2::new(10.0, 20.0);
        let pinhole = c.generate_ray(film, Vec2::ZERO);
        let focus = pinhole.origin + pinhole.dir * (5.0 / pinhole.dir.dot(-Vec3::Z));
        for lens in [Vec2::new(0.1, 0.9), Vec2::new(0.7, 0.3), Vec2::new(0.95, 0.95)] {
            let r = c.generate_ray(film, lens);
            assert!((r.origin - Vec3::new(0.0, 0.0, 5.0)).length() <= 0.5 + 1e-5);
            let t = (r.origin.z - 0.0) / -r.dir.z;
            assert!(close(r.at(t), focus), "{:?} vs {focus:?}", r.at(t));
        }
    }

    #[test]
    fn degenerate_views_are_errors() {
        let p = Projection::Perspective { fov_y: 40.0 };
        assert!(Camera::look_at(p, Vec3::ZERO, Vec3::ZERO, Vec3::Y, 8, 8).is_err());
        assert!(Camera::look_at(p, Vec3::ZERO, Vec3::Y, Vec3::Y, 8, 8).is_err());
        assert!(Camera::look_at(p, Vec3::ZERO, Vec3::Z, Vec3::Y, 0, 8).is_err());
    }
}
