//! Cameras: perspective and orthographic projections with optional thin-lens
//! depth of field, each defined by a view transform (camera to world) and a
//! projection transform (camera to screen), as in pbrt-v4 chapter 5; and a
//! spherical camera that sees every direction, laid on the image by an
//! equal-area or an equirectangular mapping (pbrt-v4's `SphericalCamera`).
//!
//! Camera space has +x to the right of the image, +y up and +z along the
//! viewing direction. Raster space has (0, 0) at the top-left corner of the
//! image and (width, height) at the bottom-right.
//!
//! ```toml
//! [camera]
//! type = "perspective"      # or "orthographic", "spherical"
//! from = [0, 1, 6.8]
//! to = [0, 1, 0]
//! up = [0, 1, 0]
//! fov = 40                  # vertical field of view, degrees
//! aperture_radius = 0.0     # > 0 turns on depth of field
//! focus_distance = 6.8
//! ```

pub mod lens_system;

pub use lens_system::{ApertureMask, LensSystem};

use crate::geometry::lanes::LANES;
use crate::geometry::simd::{Floats, Vec3s};
use crate::geometry::{Ray, Transform};
use crate::sampling::Sampler;
use crate::sampling::warp::{equal_area_square_to_sphere, sample_disk_concentric};
use glam::{Mat4, Vec2, Vec3, Vec4};

/// A connection from a scene point to the camera's lens
/// ([`Camera::sample_wi`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraConnection {
    /// Raster position of the image point the connection reaches.
    pub raster: Vec2,
    /// The point on the lens (or view plane) it reaches.
    pub origin: Vec3,
    /// Unit direction from the scene point toward the lens.
    pub wi: Vec3,
    /// Length of the segment that must be unoccluded (to the lens, or to
    /// the near clipping plane).
    pub dist: f32,
    /// The importance over its density, `We/pdf`: the factor by which
    /// `β·f·|cos|` at the scene point becomes the splat.
    pub weight: f32,
}

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
    /// Every direction around the eye, laid on the image by `mapping`
    /// (pbrt-v4's `SphericalCamera`); the image's top is camera +y. It
    /// has no lens, no clipping planes, and light paths do not connect to
    /// it (neither do pbrt-v4's).
    Spherical {
        /// How directions lie on the image.
        mapping: SphericalMapping,
    },
    /// Rays from the film traced through a system of real lenses (pbrt-v4's
    /// `RealisticCamera`; the [`LensSystem`] is the camera's). Its rays
    /// carry weights and the lens blocks some: drawn by
    /// [`Camera::generate_weighted_ray_into`]. Light paths do not connect to it.
    Realistic,
}

/// How a spherical camera lays the sphere of directions on its image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SphericalMapping {
    /// Clarberg's equal-area octahedral mapping (pbrt-v4's default,
    /// `equalarea`): every pixel of a square image sees the same solid
    /// angle; the image's centre looks along camera +y.
    #[default]
    EqualArea,
    /// Latitude and longitude (`equirectangular`): rows from camera +y
    /// (the top) to −y, columns around from +x through +z (a quarter of the
    /// way across) and −x (the middle).
    Equirectangular,
}

impl SphericalMapping {
    /// The unit camera-space direction at point `uv` of the image ((0, 0)
    /// its top-left corner, (1, 1) its bottom-right), as pbrt-v4's
    /// `SphericalCamera::GenerateRay`: the mapping's direction with its y
    /// and z swapped.
    pub fn direction(self, uv: Vec2) -> Vec3 {
        let d = match self {
            SphericalMapping::Equirectangular => {
                let (theta, phi) = (std::f32::consts::PI * uv.y, 2.0 * std::f32::consts::PI * uv.x);
                let st = theta.sin();
                Vec3::new(st * phi.cos(), st * phi.sin(), theta.cos())
            }
            SphericalMapping::EqualArea => equal_area_square_to_sphere(wrap_equal_area_square(uv)),
        };
        Vec3::new(d.x, d.z, d.y)
    }

    /// The density per steradian of the direction through a uniformly
    /// drawn point of the image, at unit camera-space direction `dir`.
    pub fn pdf(self, dir: Vec3) -> f32 {
        use std::f32::consts::PI;
        match self {
            SphericalMapping::EqualArea => 1.0 / (4.0 * PI),
            SphericalMapping::Equirectangular => {
                // dω = 2π² sin θ du dv, θ from camera +y.
                let sin_theta = (1.0 - dir.y * dir.y).max(0.0).sqrt();
                if sin_theta > 0.0 {
                    1.0 / (2.0 * PI * PI * sin_theta)
                } else {
                    0.0
                }
            }
        }
    }
}

/// A point near the unit square brought into it as the equal-area
/// octahedral mapping continues across its edges (pbrt-v4's
/// `WrapEqualAreaSquare`): beyond an edge the square continues mirrored
/// along it and flipped across it, as a filter's samples beyond the
/// image's border reach.
fn wrap_equal_area_square(mut uv: Vec2) -> Vec2 {
    if uv.x < 0.0 {
        uv = Vec2::new(-uv.x, 1.0 - uv.y);
    } else if uv.x > 1.0 {
        uv = Vec2::new(2.0 - uv.x, 1.0 - uv.y);
    }
    if uv.y < 0.0 {
        uv = Vec2::new(1.0 - uv.x, -uv.y);
    } else if uv.y > 1.0 {
        uv = Vec2::new(1.0 - uv.x, 2.0 - uv.y);
    }
    uv
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
    /// Area of the image on the plane one unit in front of the pinhole
    /// (perspective), or of the view plane in world units (orthographic):
    /// the normalisation of the camera's importance.
    image_area: f32,
    /// Lens radius; 0 for a pinhole.
    pub lens_radius: f32,
    /// Distance to the plane in focus.
    pub focus_distance: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The corner of the crop window in the full image's raster (zero
    /// without one): the window's raster positions plus it are the full
    /// image's, which the projection maps.
    offset: Vec2,
    /// The full image's size in pixels, which a spherical camera's
    /// mapping spans.
    full_size: Vec2,
    /// A realistic camera's lenses.
    lens_system: Option<std::sync::Arc<LensSystem>>,
    /// When the shutter opens and closes, where something in the scene
    /// moves; `None`: every ray is traced at time 0.
    shutter: Option<(f32, f32)>,
    /// How the camera moves while the shutter is open (camera to world
    /// over time, starting from `camera_to_world`); `None`: it stands
    /// still.
    motion: Option<Box<crate::geometry::motion::MotionTransform>>,
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
        Self::from_transform_cropped(projection, camera_to_world, width, height, None)
    }

    /// [`Camera::from_transform`] framing a `width` × `height` image of
    /// which it renders only the window `crop` = (x, y, crop width, crop
    /// height) in pixels: its raster positions, [`Camera::sample_wi`]'s
    /// and its importance (normalised over the window) are the window's.
    pub fn from_transform_cropped(
        projection: Projection,
        camera_to_world: Transform,
        width: u32,
        height: u32,
        crop: Option<(u32, u32, u32, u32)>,
    ) -> Result<Camera, String> {
        Self::from_transform_windowed(projection, camera_to_world, width, height, crop, None)
    }

    /// [`Camera::from_transform_cropped`] with the screen window
    /// `[x min, x max, y min, y max]` (pbrt-v4's `screenwindow`) laid over
    /// the image: on the plane where a perspective projection's
    /// tan(fov_y/2) is one unit, or in camera units for an orthographic
    /// one, and off centre or of another aspect than the image's if so
    /// given. `None`: the window centred, its height the projection's and
    /// its width following the image's aspect. Other projections have
    /// none.
    pub fn from_transform_windowed(
        projection: Projection,
        camera_to_world: Transform,
        width: u32,
        height: u32,
        crop: Option<(u32, u32, u32, u32)>,
        screen_window: Option<[f32; 4]>,
    ) -> Result<Camera, String> {
        if width == 0 || height == 0 {
            return Err("image size must be at least 1×1".into());
        }
        let (x0, y0, crop_width, crop_height) = crop.unwrap_or((0, 0, width, height));
        if crop_width == 0
            || crop_height == 0
            || x0 as u64 + crop_width as u64 > width as u64
            || y0 as u64 + crop_height as u64 > height as u64
        {
            return Err(format!(
                "the crop window ({x0}, {y0}) + {crop_width}×{crop_height} does not lie within the {width}×{height} image"
            ));
        }
        let aspect = width as f32 / height as f32;
        // Screen window: y ∈ [-1, 1] for perspective (scaled by the
        // projection), [-h/2, h/2] for orthographic.
        let (camera_to_screen, half_h) = match projection {
            Projection::Perspective { fov_y } => (perspective_matrix(fov_y, 1e-2, 1000.0), 1.0),
            Projection::Orthographic { height } => (orthographic_matrix(0.0, 1.0), height / 2.0),
            // Their rays come from their mapping or their lenses; the
            // matrices go unused.
            Projection::Spherical { .. } | Projection::Realistic => (orthographic_matrix(0.0, 1.0), 1.0),
        };
        let half_w = half_h * aspect;
        let projective = matches!(
            projection,
            Projection::Perspective { .. } | Projection::Orthographic { .. }
        );
        let [x_min, x_max, y_min, y_max] = match screen_window {
            Some(window) if projective => {
                if !(window.iter().all(|v| v.is_finite()) && window[0] < window[1] && window[2] < window[3]) {
                    return Err(format!(
                        "the screen window {window:?} needs finite bounds with x min < x max and y min < y max"
                    ));
                }
                window
            }
            _ => [-half_w, half_w, -half_h, half_h],
        };
        // Screen (x right, y up) → raster (x right, y down): the window's
        // top-left corner to (0, 0).
        let screen_to_raster = Mat4::from_scale(Vec3::new(width as f32, height as f32, 1.0))
            * Mat4::from_scale(Vec3::new(1.0 / (x_max - x_min), -1.0 / (y_max - y_min), 1.0))
            * Mat4::from_translation(Vec3::new(-x_min, -y_max, 0.0));
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
        let corner = |x: f32, y: f32| raster_to_camera.m.project_point3(Vec3::new(x, y, 0.0));
        // The window's corners: the importance is normalised over it.
        let (x0f, y0f) = (x0 as f32, y0 as f32);
        let (c00, c10, c01) = (
            corner(x0f, y0f),
            corner(x0f + crop_width as f32, y0f),
            corner(x0f, y0f + crop_height as f32),
        );
        let image_area = match projection {
            // Directions are what a pinhole sees: the corners projected to z = 1.
            Projection::Perspective { .. } => {
                let unit = |c: Vec3| c / c.z;
                (unit(c10) - unit(c00)).cross(unit(c01) - unit(c00)).length()
            }
            Projection::Orthographic { .. } => camera_to_world
                .vector(c10 - c00)
                .cross(camera_to_world.vector(c01 - c00))
                .length(),
            Projection::Spherical { .. } | Projection::Realistic => 4.0 * std::f32::consts::PI,
        };
        Ok(Camera {
            projection,
            camera_to_world,
            raster_to_camera,
            pinhole,
            clip: None,
            forward,
            image_area,
            lens_radius: 0.0,
            focus_distance: 1.0,
            width: crop_width,
            height: crop_height,
            offset: Vec2::new(x0f, y0f),
            full_size: Vec2::new(width as f32, height as f32),
            lens_system: None,
            shutter: None,
            motion: None,
        })
    }

    /// The same camera with a thin lens of the given radius focused at
    /// `focus_distance` (measured along the viewing direction).
    pub fn with_thin_lens(mut self, lens_radius: f32, focus_distance: f32) -> Camera {
        if matches!(self.projection, Projection::Spherical { .. } | Projection::Realistic) {
            return self;
        }
        self.lens_radius = lens_radius;
        self.focus_distance = focus_distance;
        self
    }

    /// The same camera seeing only what lies between `near` and `far`
    /// along its viewing axis, as Mitsuba's `near_clip` and `far_clip`: a
    /// ray starts where it crosses the near plane and ends at the far one.
    pub fn with_clipping(mut self, near: f32, far: f32) -> Camera {
        if matches!(self.projection, Projection::Spherical { .. } | Projection::Realistic) {
            return self;
        }
        self.clip = (near > 0.0 || far.is_finite()).then_some((near, far));
        self
    }

    /// The lens position of a camera sample: drawn from `sampler` for a
    /// camera with a lens, passed over (and zero, which
    /// [`Camera::generate_ray`] then ignores) for a pinhole.
    #[inline]
    pub fn draw_lens(&self, sampler: &mut Sampler) -> Vec2 {
        if self.lens_radius > 0.0 || self.lens_system.is_some() {
            sampler.next_2d()
        } else {
            sampler.skip_2d();
            Vec2::ZERO
        }
    }

    /// The same camera with its shutter open from `open` to `close`, each
    /// camera sample then drawing its time in between (a scene with moving
    /// objects; in one without, no sample is spent on time).
    pub fn with_shutter(mut self, open: f32, close: f32) -> Camera {
        self.shutter = Some((open, close));
        self
    }

    /// The same camera moving from where it is to `end` (camera to world)
    /// between `times`.
    pub fn with_motion(mut self, end: Transform, times: (f32, f32)) -> Option<Camera> {
        let motion = crate::geometry::motion::MotionTransform::new(self.camera_to_world, end, times.0, times.1)?;
        self.motion = Some(Box::new(motion));
        Some(self)
    }

    /// Whether the camera moves during the shutter (`Camera::moved` then
    /// changes rays).
    #[inline]
    pub fn moves(&self) -> bool {
        self.motion.is_some()
    }

    /// A ray the still camera generated, from where the camera is at the
    /// ray's time: moved by (camera to world at that time) · (camera to
    /// world at the start)⁻¹, its direction unit length again.
    #[inline]
    pub fn moved(&self, ray: Ray) -> Ray {
        let Some(relative) = self.relative_motion(ray.time) else {
            return ray;
        };
        let dir = relative.transform_vector3(ray.dir);
        let len = dir.length();
        Ray::with_interval(
            relative.transform_point3(ray.origin),
            dir / len,
            ray.t_min * len,
            ray.t_max * len,
        )
        .at_time(ray.time)
    }

    /// Where a moving camera is at `time` relative to where it starts:
    /// (camera to world at `time`) · (camera to world at the start)⁻¹;
    /// `None` for a still camera.
    #[inline]
    fn relative_motion(&self, time: f32) -> Option<Mat4> {
        let motion = self.motion.as_ref()?;
        Some(motion.at(time).m * self.camera_to_world.inv)
    }

    /// [`Camera::sample_wi`] for the camera as it is at `time`: the point
    /// carried back to where the camera starts, the connection carried
    /// forward again. A camera's motion moves it rigidly, so distances,
    /// raster positions and weights are those at the start.
    pub fn sample_wi_at(&self, p: Vec3, lens: Vec2, time: f32) -> Option<CameraConnection> {
        let Some(relative) = self.relative_motion(time) else {
            return self.sample_wi(p, lens);
        };
        let c = self.sample_wi(relative.inverse().transform_point3(p), lens)?;
        Some(CameraConnection {
            origin: relative.transform_point3(c.origin),
            wi: relative.transform_vector3(c.wi).normalize_or_zero(),
            ..c
        })
    }

    /// [`Camera::pdf_dir`] of a direction from the camera as it is at
    /// `time`.
    pub fn pdf_dir_at(&self, dir: Vec3, time: f32) -> f32 {
        match self.relative_motion(time) {
            None => self.pdf_dir(dir),
            Some(relative) => self.pdf_dir(relative.inverse().transform_vector3(dir).normalize_or_zero()),
        }
    }

    /// The time of a camera sample: uniform over the shutter interval,
    /// drawn from `sampler` where the camera has a shutter, else 0 and no
    /// number drawn (pbrt-v4's `SampleTime`).
    #[inline]
    pub fn draw_time(&self, sampler: &mut Sampler) -> f32 {
        self.time_from(|| sampler.next_1d())
    }

    /// [`Camera::draw_time`] with the uniform number from `u`, called only
    /// where the camera has a shutter.
    #[inline]
    pub fn time_from(&self, u: impl FnOnce() -> f32) -> f32 {
        match self.shutter {
            Some((open, close)) => open + (close - open) * u(),
            None => 0.0,
        }
    }

    /// The same camera seeing through `lenses` (a realistic camera).
    pub fn with_lens_system(mut self, lenses: LensSystem) -> Camera {
        self.projection = Projection::Realistic;
        self.lens_system = Some(std::sync::Arc::new(lenses));
        self
    }

    /// The ray through raster position `film` and lens sample `lens`, as
    /// [`Camera::generate_ray`], written into `ray`, where the caller keeps
    /// it (a returned ray is copied with wider loads than the stores that
    /// wrote it, and the copy waits on them); returns the weight of what it
    /// measures: 1 for every camera but a realistic one, whose rays carry
    /// cos⁴θ·A/d², and 0 where its lens blocks the ray (`ray` is then
    /// [`Camera::generate_ray`]'s).
    #[inline]
    pub fn generate_weighted_ray_into(&self, film: Vec2, lens: Vec2, ray: &mut Ray) -> f32 {
        if let Some(lenses) = &self.lens_system {
            if let Some((o, d, weight)) = lenses.ray((film + self.offset) / self.full_size, lens) {
                *ray = Ray::new(
                    self.camera_to_world.point(o),
                    self.camera_to_world.vector(d).normalize(),
                );
                return weight;
            }
            self.generate_ray_into(film, lens, ray);
            return 0.0;
        }
        self.generate_ray_into(film, lens, ray);
        1.0
    }

    /// Camera space (x to the image's right, y up, z along the view, as
    /// pbrt-v4's) to world space, at time 0.
    pub fn camera_to_world(&self) -> &Transform {
        &self.camera_to_world
    }

    /// The ray through raster position `film` (pixels, continuous), using
    /// `lens` ∈ [0,1)² to pick a point on the lens. Directions are unit
    /// length. A realistic camera gives the ray through the centre of its
    /// exit pupil, or along its axis where the lens blocks that (for the
    /// estimates that want a ray per pixel: a photon radius, an AOV).
    #[inline]
    pub fn generate_ray(&self, film: Vec2, lens: Vec2) -> Ray {
        let mut ray = Ray::new(Vec3::ZERO, Vec3::Z);
        self.generate_ray_into(film, lens, &mut ray);
        ray
    }

    /// [`Camera::generate_ray`] written into `out`.
    #[inline]
    pub fn generate_ray_into(&self, film: Vec2, lens: Vec2, out: &mut Ray) {
        if let Some(lenses) = &self.lens_system {
            let at = |u: Vec2| lenses.ray((film + self.offset) / self.full_size, u);
            let (o, d) = at(lens)
                .or_else(|| at(Vec2::splat(0.5)))
                .map_or((Vec3::ZERO, Vec3::Z), |(o, d, _)| (o, d));
            *out = Ray::new(
                self.camera_to_world.point(o),
                self.camera_to_world.vector(d).normalize(),
            );
            return;
        }
        if let Some((corners, origin)) = self.plain_pinhole() {
            let film = film + self.offset;
            let rays = self.pinhole_rays(corners, origin, film.x, film.y);
            *out = Ray::with_interval(rays.origin.lane(0), rays.dir.lane(0), 0.0, rays.t_max.lane(0));
            return;
        }
        let ray = self.unclipped_ray(film, lens);
        *out = match self.clip {
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

    /// The pinhole's direction map and position where the camera is a
    /// perspective pinhole without a lens (see [`Camera::pinhole_rays`]).
    #[inline(always)]
    fn plain_pinhole(&self) -> Option<(&[Vec3; 3], Vec3)> {
        match &self.pinhole {
            Some((corners, origin)) if self.lens_radius <= 0.0 && self.lens_system.is_none() => {
                Some((corners, *origin))
            }
            _ => None,
        }
    }

    /// The rays of a pinhole camera through the film points `(x, y)`
    /// (raster, crop offset added), for one ray (`F = f32`) or for the
    /// render loop's eight at once (`F8`), which therefore get the same
    /// bits: their origins, unit directions and lengths, the clipping
    /// planes applied.
    #[inline(always)]
    fn pinhole_rays<F: Floats>(&self, [a, b, c]: &[Vec3; 3], origin: Vec3, x: F, y: F) -> PinholeRays<F> {
        let s = Vec3s::<F>::splat;
        let (a, b, c) = (s(*a), s(*b), s(*c));
        let d = Vec3s {
            x: a.x * x + b.x * y + c.x,
            y: a.y * x + b.y * y + c.y,
            z: a.z * x + b.z * y + c.z,
        };
        // glam's `normalize`: d times the reciprocal of its length.
        let length = (d.x * d.x + d.y * d.y + d.z * d.z).sqrt();
        let dir = d.scale(F::splat(1.0) / length);
        let origin = s(origin);
        match self.clip {
            None => PinholeRays {
                origin,
                dir,
                t_max: F::splat(f32::INFINITY),
            },
            Some((near, far)) => {
                // Distances along the ray to the planes (Mitsuba's
                // `near_clip / d.z`, d.z the cosine to the viewing axis).
                let f = s(self.forward);
                let cos = dir.x * f.x + dir.y * f.y + dir.z * f.z;
                let (t_near, t_far) = (F::splat(near) / cos, F::splat(far) / cos);
                PinholeRays {
                    origin: origin + dir.scale(t_near),
                    dir,
                    t_max: t_far - t_near,
                }
            }
        }
    }

    /// Rays through the first `count` film points of `film` (as
    /// [`Camera::generate_weighted_ray_into`] with `lens`) into `rays`, and
    /// their weights: a pinhole camera's in vector lanes where the
    /// processor has AVX (all eight, whatever `count`), the others' one
    /// by one.
    #[allow(unsafe_code)]
    pub(crate) fn generate_weighted_rays_into(
        &self,
        film: &[Vec2; LANES],
        lens: &[Vec2; LANES],
        count: usize,
        rays: &mut [Ray; LANES],
        weights: &mut [f32; LANES],
    ) {
        #[cfg(target_arch = "x86_64")]
        if let (Some((corners, origin)), true) = (self.plain_pinhole(), crate::geometry::lanes::avx_available()) {
            // SAFETY: the processor has AVX.
            unsafe { self.pinhole_rays_avx(corners, origin, film, rays) };
            *weights = [1.0; LANES];
            return;
        }
        for i in 0..count.min(LANES) {
            weights[i] = self.generate_weighted_ray_into(film[i], lens[i], &mut rays[i]);
        }
    }

    /// [`Camera::pinhole_rays`] over eight lanes, written into `rays`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn pinhole_rays_avx(&self, corners: &[Vec3; 3], origin: Vec3, film: &[Vec2; LANES], rays: &mut [Ray; LANES]) {
        use crate::geometry::lanes::F8;
        let x = F8::gather(&std::array::from_fn(|i| film[i].x + self.offset.x));
        let y = F8::gather(&std::array::from_fn(|i| film[i].y + self.offset.y));
        let r = self.pinhole_rays(corners, origin, x, y);
        let (ox, oy, oz) = (r.origin.x.to_array(), r.origin.y.to_array(), r.origin.z.to_array());
        let (dx, dy, dz) = (r.dir.x.to_array(), r.dir.y.to_array(), r.dir.z.to_array());
        let t_max = r.t_max.to_array();
        for (i, ray) in rays.iter_mut().enumerate() {
            *ray = Ray::with_interval(
                Vec3::new(ox[i], oy[i], oz[i]),
                Vec3::new(dx[i], dy[i], dz[i]),
                0.0,
                t_max[i],
            );
        }
    }

    #[inline]
    fn unclipped_ray(&self, film: Vec2, lens: Vec2) -> Ray {
        let film = film + self.offset;
        if let Projection::Spherical { mapping } = self.projection {
            let dir = mapping.direction(film / self.full_size);
            return Ray::new(
                self.camera_to_world.point(Vec3::ZERO),
                self.camera_to_world.vector(dir).normalize(),
            );
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
            Projection::Spherical { .. } | Projection::Realistic => unreachable!("returned above"),
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

    /// A point on the lens seen from the scene point `p`, for algorithms
    /// that trace from the lights and connect to the camera (pbrt-v4's
    /// `Camera::SampleWi`, Veach 1997 §10.3.1): `lens` ∈ [0,1)² picks the
    /// lens point as [`Camera::generate_ray`] does. `None` where the
    /// camera does not see `p` (behind it, outside the image or the
    /// clipping planes).
    ///
    /// The importance is pbrt's, `We = 1/(A·A_lens·cos⁴θ)` for a
    /// perspective camera (A the image's area on the plane at unit
    /// distance) with the solid-angle density `dist²/(A_lens·cos θ)` of
    /// the lens point, so `We/pdf = 1/(A·cos³θ·dist²)` with or without a
    /// lens; an orthographic camera sees `p` along its axis only (a delta
    /// in direction), with `We = 1/A` over its view plane. An image of
    /// `N` such connections per pixel, each splatted with its weight into
    /// the pixel it reaches and divided by `N`, estimates the radiance the
    /// camera's rays measure.
    pub fn sample_wi(&self, p: Vec3, lens: Vec2) -> Option<CameraConnection> {
        let q = self.camera_to_world.inv_point(p);
        let (raster, lens_point, cos) = match self.projection {
            Projection::Perspective { .. } => {
                if q.z <= 0.0 {
                    return None;
                }
                let p_lens = if self.lens_radius > 0.0 {
                    let d = self.lens_radius * sample_disk_concentric(lens);
                    Vec3::new(d.x, d.y, 0.0)
                } else {
                    Vec3::ZERO
                };
                // The camera ray from the lens point through q meets the
                // plane in focus where the pinhole ray of its raster point
                // does (see `unclipped_ray`); a pinhole projects q itself.
                let through = if self.lens_radius > 0.0 {
                    p_lens + (q - p_lens) * (self.focus_distance / q.z)
                } else {
                    q
                };
                let raster = self.raster_to_camera.inv.project_point3(through);
                let lens_world = self.camera_to_world.point(p_lens);
                let cos = (p - lens_world).normalize_or_zero().dot(self.forward);
                (raster, lens_world, cos)
            }
            Projection::Orthographic { .. } => {
                if self.lens_radius > 0.0 {
                    // A thin lens over a parallel projection focuses
                    // nowhere; such cameras are refused before rendering
                    // (see `Camera::connects`).
                    return None;
                }
                if q.z <= 0.0 {
                    return None;
                }
                let raster = self.raster_to_camera.inv.transform_point3(Vec3::new(q.x, q.y, 0.0));
                let lens_world = self.camera_to_world.point(Vec3::new(q.x, q.y, 0.0));
                (raster, lens_world, 1.0)
            }
            // Refused before rendering (see `Camera::connects`).
            Projection::Spherical { .. } | Projection::Realistic => return None,
        };
        let raster = Vec2::new(raster.x, raster.y) - self.offset;
        let (w, h) = (self.width as f32, self.height as f32);
        if !(raster.x >= 0.0 && raster.x < w && raster.y >= 0.0 && raster.y < h && cos > 0.0) {
            return None;
        }
        let to_lens = lens_point - p;
        let dist = to_lens.length();
        if !(dist > 0.0 && dist.is_finite()) {
            return None;
        }
        let wi = to_lens / dist;
        // Depth along the viewing axis from the lens plane, which the
        // clipping planes bound (as `generate_ray` measures them).
        let depth = dist * cos;
        let mut visible = dist;
        if let Some((near, far)) = self.clip {
            if depth < near || depth > far {
                return None;
            }
            visible = dist - near / cos;
        }
        let weight = match self.projection {
            Projection::Perspective { .. } => 1.0 / (self.image_area * cos * cos * cos * dist * dist),
            Projection::Orthographic { .. } => 1.0 / self.image_area,
            Projection::Spherical { .. } | Projection::Realistic => return None,
        };
        weight.is_finite().then_some(CameraConnection {
            raster,
            origin: lens_point,
            wi,
            dist: visible,
            weight,
        })
    }

    /// The density with which [`Camera::generate_ray`] draws the unit
    /// direction `dir` from its lens point: per unit solid angle for a
    /// perspective camera, `1/(A·cos³θ)` (pbrt-v4's `PDF_We`); for an
    /// orthographic one, whose direction is its axis, the density `1/A`
    /// of the ray's point on the view plane, which bidirectional methods
    /// convert to area without the inverse square
    /// ([`Camera::is_orthographic`]).
    pub fn pdf_dir(&self, dir: Vec3) -> f32 {
        match self.projection {
            Projection::Perspective { .. } => {
                let cos = dir.dot(self.forward);
                if cos <= 0.0 {
                    0.0
                } else {
                    1.0 / (self.image_area * cos * cos * cos)
                }
            }
            Projection::Orthographic { .. } => 1.0 / self.image_area,
            Projection::Spherical { mapping } => mapping.pdf(self.camera_to_world.inv_vector(dir).normalize_or_zero()),
            Projection::Realistic => 0.0,
        }
    }

    /// Whether the camera projects in parallel.
    pub fn is_orthographic(&self) -> bool {
        matches!(self.projection, Projection::Orthographic { .. })
    }

    /// The point on the lens (or view plane) that camera ray `ray` leaves
    /// from: its origin, before the near clipping plane moved it.
    pub fn lens_point(&self, ray: &Ray) -> Vec3 {
        match self.clip {
            None => ray.origin,
            Some((near, _)) => {
                let forward = match self.relative_motion(ray.time) {
                    None => self.forward,
                    Some(relative) => relative.transform_vector3(self.forward).normalize_or_zero(),
                };
                ray.origin - ray.dir * (near / ray.dir.dot(forward))
            }
        }
    }

    /// Whether light paths can connect to this camera
    /// ([`Camera::sample_wi`]): all but an orthographic one with a lens
    /// and a spherical one.
    pub fn connects(&self) -> bool {
        match self.projection {
            Projection::Perspective { .. } => true,
            Projection::Orthographic { .. } => self.lens_radius <= 0.0,
            Projection::Spherical { .. } | Projection::Realistic => false,
        }
    }
}

/// What [`Camera::pinhole_rays`] computes, in lanes.
struct PinholeRays<F> {
    origin: Vec3s<F>,
    dir: Vec3s<F>,
    t_max: F,
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

    /// The render loop's eight camera rays at once are, bit for bit, the
    /// rays made one by one: with and without clipping planes, in a crop
    /// window, for fewer samples than lanes; and a thin-lens camera's
    /// (made one by one) too.
    #[test]
    fn rays_made_in_lanes_are_the_rays_made_one_by_one() {
        use crate::geometry::Transform;
        let to_world = Transform::look_at(Vec3::new(0.3, 1.0, 5.0), Vec3::new(0.1, 0.2, 0.0), Vec3::Y).unwrap();
        let cropped = Camera::from_transform_cropped(
            Projection::Perspective { fov_y: 35.0 },
            to_world,
            64,
            48,
            Some((9, 5, 20, 30)),
        )
        .unwrap();
        let lens = persp(50.0, 64, 48).with_thin_lens(0.1, 4.0);
        let cameras = [
            persp(60.0, 64, 48),
            persp(60.0, 64, 48).with_clipping(0.01, 1e4),
            cropped.clone().with_clipping(0.5, 7.0),
            cropped,
            lens,
        ];
        let film: [Vec2; LANES] = std::array::from_fn(|i| Vec2::new(i as f32 * 7.3 + 0.21, 47.9 - i as f32 * 5.1));
        let lens_u: [Vec2; LANES] = std::array::from_fn(|i| Vec2::new(i as f32 / 8.0, 0.9 - i as f32 / 9.0));
        for (c, camera) in cameras.iter().enumerate() {
            for count in [LANES, 3] {
                let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); LANES];
                let mut weights = [0.0; LANES];
                camera.generate_weighted_rays_into(&film, &lens_u, count, &mut rays, &mut weights);
                for i in 0..count {
                    let mut one = Ray::new(Vec3::ZERO, Vec3::Z);
                    let weight = camera.generate_weighted_ray_into(film[i], lens_u[i], &mut one);
                    let bits = |r: &Ray| {
                        [r.origin.to_array(), r.dir.to_array(), [r.t_min, r.t_max, r.time]].map(|a| a.map(f32::to_bits))
                    };
                    assert_eq!(bits(&rays[i]), bits(&one), "camera {c}, lane {i} of {count}");
                    assert_eq!(weights[i], weight);
                }
            }
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

    /// Connecting a point on a camera ray back to the camera with the
    /// ray's lens sample lands on the ray's raster position, for pinhole,
    /// thin-lens and orthographic cameras, clipped or not; points behind
    /// the camera, outside the image or beyond the clipping planes are
    /// not seen.
    #[test]
    fn connections_to_the_lens_invert_the_camera_rays() {
        let ortho = Camera::look_at(
            Projection::Orthographic { height: 3.0 },
            Vec3::new(1.0, 2.0, 5.0),
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::Y,
            40,
            30,
        )
        .unwrap();
        let cameras = [
            persp(50.0, 40, 30),
            persp(50.0, 40, 30).with_thin_lens(0.3, 4.0),
            ortho.clone(),
            persp(70.0, 40, 30).with_thin_lens(0.2, 6.0).with_clipping(1.0, 9.0),
            ortho.with_clipping(2.0, 8.0),
        ];
        for (k, camera) in cameras.iter().enumerate() {
            for (film, lens, t) in [
                (Vec2::new(20.0, 15.0), Vec2::new(0.3, 0.6), 3.0f32),
                (Vec2::new(1.5, 28.25), Vec2::new(0.9, 0.1), 5.5),
                (Vec2::new(37.75, 0.5), Vec2::new(0.5, 0.5), 7.0),
            ] {
                let ray = camera.generate_ray(film, lens);
                let p = ray.at(t.min(0.9 * ray.t_max));
                let c = camera
                    .sample_wi(p, lens)
                    .unwrap_or_else(|| panic!("camera {k}: {film} unseen"));
                assert!((c.raster - film).length() < 2e-3, "camera {k}: {} vs {film}", c.raster);
                assert!((c.wi + ray.dir).length() < 1e-4, "camera {k}: {} vs {}", c.wi, -ray.dir);
                // The segment to check ends where the ray starts.
                assert!((p + c.wi * c.dist - ray.origin).length() < 1e-3, "camera {k}");
                assert!(c.weight > 0.0 && c.weight.is_finite());
            }
            let ahead = camera.generate_ray(Vec2::new(20.0, 15.0), Vec2::ZERO);
            let behind = ahead.origin - ahead.dir * 2.0;
            assert_eq!(camera.sample_wi(behind, Vec2::splat(0.5)), None, "camera {k}");
            let aside = ahead.at(3.0) + Vec3::new(50.0, 0.0, 0.0);
            assert_eq!(camera.sample_wi(aside, Vec2::splat(0.5)), None, "camera {k}");
        }
        let clipped = &cameras[3];
        let ray = clipped.generate_ray(Vec2::new(20.0, 15.0), Vec2::splat(0.5));
        assert!(clipped.sample_wi(ray.at(ray.t_max + 0.5), Vec2::splat(0.5)).is_none());
        assert!(
            clipped
                .sample_wi(ray.origin - ray.dir * 0.5, Vec2::splat(0.5))
                .is_none()
        );
        assert!(!ortho_with_lens().connects() && cameras.iter().all(Camera::connects));
    }

    fn ortho_with_lens() -> Camera {
        Camera::look_at(
            Projection::Orthographic { height: 2.0 },
            Vec3::Z,
            Vec3::ZERO,
            Vec3::Y,
            8,
            8,
        )
        .unwrap()
        .with_thin_lens(0.1, 1.0)
    }

    /// The importance integrates to one over the image: for a pinhole, the
    /// weight `We/pdf` at unit distance times the solid angle that each
    /// direction stands for, summed over a grid of directions through the
    /// image plane, is 1.
    #[test]
    fn perspective_importance_is_normalised_over_the_image() {
        let c = persp(60.0, 48, 32);
        let n = 200;
        let mut sum = 0.0f64;
        // Directions through raster points; the solid angle of a raster
        // cell is its area on the plane at unit distance times cos³θ.
        let cell_area = c.image_area as f64 / (n * n) as f64;
        for i in 0..n {
            for j in 0..n {
                let film = Vec2::new(48.0 * (i as f32 + 0.5) / n as f32, 32.0 * (j as f32 + 0.5) / n as f32);
                let ray = c.generate_ray(film, Vec2::ZERO);
                let p = ray.at(1.0);
                let conn = c.sample_wi(p, Vec2::ZERO).unwrap();
                let cos = ray.dir.dot(-Vec3::Z) as f64;
                sum += conn.weight as f64 * cell_area * cos * cos * cos;
            }
        }
        assert!((sum - 1.0).abs() < 1e-3, "{sum}");
    }

    #[test]
    fn degenerate_views_are_errors() {
        let p = Projection::Perspective { fov_y: 40.0 };
        assert!(Camera::look_at(p, Vec3::ZERO, Vec3::ZERO, Vec3::Y, 8, 8).is_err());
        assert!(Camera::look_at(p, Vec3::ZERO, Vec3::Y, Vec3::Y, 8, 8).is_err());
        assert!(Camera::look_at(p, Vec3::ZERO, Vec3::Z, Vec3::Y, 0, 8).is_err());
    }

    /// pbrt-v4's spherical mappings: equirectangular rows from +y to −y,
    /// columns around from +x through +z; equal-area +y at the centre
    /// and −y at the corners, continuous across the square's edges (as
    /// its wrapping continues it), every pixel the same solid angle.
    #[test]
    fn spherical_mappings_are_pbrts() {
        let eq = SphericalMapping::Equirectangular;
        for (uv, d) in [
            (Vec2::new(0.0, 0.5), Vec3::X),
            (Vec2::new(0.25, 0.5), Vec3::Z),
            (Vec2::new(0.5, 0.5), Vec3::NEG_X),
            (Vec2::new(0.75, 0.5), Vec3::NEG_Z),
            (Vec2::new(0.3, 0.0), Vec3::Y),
            (Vec2::new(0.3, 1.0), Vec3::NEG_Y),
        ] {
            assert!(close(eq.direction(uv), d), "equirectangular {uv}: {}", eq.direction(uv));
        }
        let ea = SphericalMapping::EqualArea;
        assert!(close(ea.direction(Vec2::splat(0.5)), Vec3::Y));
        assert!(close(ea.direction(Vec2::ZERO), Vec3::NEG_Y));
        for v in [0.1, 0.3, 0.77] {
            for (a, b) in [
                (Vec2::new(-1e-4, v), Vec2::new(1e-4, v)),
                (Vec2::new(1.0 - 1e-4, v), Vec2::new(1.0 + 1e-4, v)),
                (Vec2::new(v, -1e-4), Vec2::new(v, 1e-4)),
            ] {
                let (da, db) = (ea.direction(a), ea.direction(b));
                assert!((da - db).length() < 1e-3, "across the edge at {a}: {da} vs {db}");
            }
        }
        // Equal solid angles: the mean of a function over the image's
        // pixels is its mean over the sphere (z², whose mean is 1/3).
        let n = 64;
        let mut sum = 0.0;
        for y in 0..n {
            for x in 0..n {
                let d = ea.direction(Vec2::new((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32));
                assert!((d.length() - 1.0).abs() < 1e-5);
                sum += d.z * d.z;
            }
        }
        let mean = sum / (n * n) as f32;
        assert!((mean - 1.0 / 3.0).abs() < 2e-3, "{mean}");
        assert!((ea.pdf(Vec3::X) * 4.0 * std::f32::consts::PI - 1.0).abs() < 1e-6);
    }

    /// A spherical camera's rays leave its eye, its image spanning the
    /// whole sphere around its frame; it has no lens and light paths do
    /// not connect to it.
    #[test]
    fn spherical_cameras_see_all_around() {
        let p = Projection::Spherical {
            mapping: SphericalMapping::Equirectangular,
        };
        let eye = Vec3::new(1.0, 2.0, 3.0);
        let cam = Camera::look_at(p, eye, eye + Vec3::NEG_Z, Vec3::Y, 40, 20)
            .unwrap()
            .with_thin_lens(0.5, 2.0)
            .with_clipping(1.0, 2.0);
        // A quarter of the way across is the view direction; the top row
        // looks up.
        let forward = cam.generate_ray(Vec2::new(10.0, 10.0), Vec2::splat(0.3));
        assert!(
            close(forward.origin, eye) && close(forward.dir, Vec3::NEG_Z),
            "{forward:?}"
        );
        assert!(close(cam.generate_ray(Vec2::new(7.0, 0.0), Vec2::ZERO).dir, Vec3::Y));
        assert!(!cam.connects());
        assert!(cam.sample_wi(Vec3::ZERO, Vec2::ZERO).is_none());
        // Its density over the sphere integrates to 1 (the equirectangular
        // one by rows: ∫ pdf · 2π sin θ dθ).
        let rows = 2000;
        let total: f32 = (0..rows)
            .map(|i| {
                let theta = (i as f32 + 0.5) / rows as f32 * std::f32::consts::PI;
                let d = Vec3::new(theta.sin(), theta.cos(), 0.0);
                cam.pdf_dir(d) * 2.0 * std::f32::consts::PI * theta.sin() * (std::f32::consts::PI / rows as f32)
            })
            .sum();
        assert!((total - 1.0).abs() < 1e-3, "{total}");
    }
}
