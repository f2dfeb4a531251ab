//! The background: what rays leaving the scene see, and — for the path
//! tracer — light arriving from infinitely far away in every direction.
//!
//! An environment image is equirectangular (latitude–longitude) with the
//! convention of Mitsuba's `envmap`: a direction d (after the map's
//! rotation) has u = atan2(d.x, −d.z)/2π and v = acos(d.y)/π; columns are
//! centred at u = (i + ½)/W and rows lie at v = j/(H − 1), the first row
//! exactly at the zenith and the last at the nadir. So the top
//! row of the image is straight up (+y), the left edge (u = 0) looks down
//! −z, a quarter of the way across looks down +x and the centre column +z.
//! It is evaluated with bilinear interpolation between pixel centres (as
//! Mitsuba does) and sampled with a density proportional to the bilinear
//! interpolation of luminance × sin θ between the same pixel centres
//! ([`BilinearDistribution2D`]), so the density follows the radiance a
//! lookup returns, inside pixels too: a sun of one or two pixels is sampled
//! where its light is, with no margin of dim density around it (a step
//! density over pixels would leave one there, half a pixel wide, and every
//! sample that lands in it is a firefly).
//!
//! Integrators that weigh light samples against BSDF samples by multiple
//! importance sampling may ask for a second density, the *compensated* one
//! (Karlík et al. 2019, "MIS compensation", as pbrt-v4's
//! `ImageInfiniteLight` with `allowIncompletePDF`): luminance minus its
//! mean over the sphere, clamped at zero. The bright part of the sky (a
//! sun) then gets every light sample, and the even part, which BSDF
//! sampling finds as well, gets none. It is incomplete, so only estimators
//! that also sample the BSDF and weigh the two may use it.

use crate::color::{Rgb, luminance};
use crate::geometry::Transform;
use crate::math;
pub use crate::sampling::warp::{equal_area_sphere_to_square, equal_area_square_to_sphere};
use crate::sampling::warp::{pdf_sphere_uniform, sample_sphere_uniform};
use crate::sampling::{BilinearDistribution2D, Distribution2D};
pub use crate::scene::desc::EnvironmentLayout;
use crate::texture::ImageTexture;
use glam::{Vec2, Vec3, Vec4};
use std::f32::consts::{FRAC_1_PI, PI};

/// An environment map ready for lookup and sampling.
#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    /// Linear radiance.
    pub image: ImageTexture,
    /// Radiance multiplier.
    pub scale: f32,
    /// Map-to-world rotation.
    pub to_world: Transform,
    /// Whether `to_world` keeps lengths (a rotation), so that directions
    /// it turns need no normalising.
    turns_only: bool,
    /// How pixels map to directions.
    pub layout: EnvironmentLayout,
    distribution: BilinearDistribution2D,
    /// The equal-area layout's density: constant over each pixel, like its
    /// nearest-pixel lookup.
    pixel_distribution: Distribution2D,
    /// The compensated densities of the two layouts (see the module's
    /// text); `None` where no pixel is brighter than the mean (a constant
    /// map), whose light samples then use the full density, as pbrt-v4's
    /// do.
    compensated: Option<BilinearDistribution2D>,
    compensated_pixels: Option<Distribution2D>,
    /// The latitude–longitude lookup's nodes, the pixel centres (the first
    /// column again after the last, closing the wrap-around; an image of
    /// one row as two equal rows): scaled radiance in x, y, z and, in w,
    /// the node of the density that light samples for MIS draw from
    /// ([`EnvironmentMap::density`] with `incomplete`). A direction's
    /// radiance and density are one bilinear interpolation of four of them.
    grid: Vec<Vec4>,
    average: Rgb,
}

impl EnvironmentMap {
    /// Prepares a latitude–longitude image for lookup and importance sampling.
    pub fn new(image: ImageTexture, scale: f32, to_world: Transform) -> Self {
        Self::with_layout(image, scale, to_world, EnvironmentLayout::LatLong)
    }

    /// Prepares an image of either layout (an equal-area one must be
    /// square) for lookup and importance sampling.
    pub fn with_layout(image: ImageTexture, scale: f32, to_world: Transform, layout: EnvironmentLayout) -> Self {
        if layout == EnvironmentLayout::EqualAreaOctahedral {
            return Self::equal_area(image, scale, to_world);
        }
        let (w, h) = (image.width as usize, image.height as usize);
        let mut map = EnvironmentMap {
            average: Rgb::ZERO,
            image,
            scale,
            turns_only: keeps_lengths(&to_world),
            to_world,
            layout,
            distribution: BilinearDistribution2D::default(),
            pixel_distribution: Distribution2D::default(),
            compensated: None,
            compensated_pixels: None,
            grid: Vec::new(),
        };
        // The density's nodes are the lookup's: pixel centres, columns at
        // u = (i + ½)/W (one more column, the first again, closes the
        // wrap-around) and rows at v = j/(H − 1) (an image of one row is
        // read as two equal rows). Each node holds luminance × sin θ.
        let rows = h.max(2);
        let node_rows = |brightness: &dyn Fn(Rgb) -> f32| {
            let mut nodes = Vec::with_capacity((w + 1) * rows);
            for j in 0..rows {
                let sin_theta = (PI * j as f32 / (rows - 1) as f32).sin();
                let row = &map.image.pixels[j.min(h - 1) * w..(j.min(h - 1) + 1) * w];
                nodes.extend(row.iter().map(|&c| brightness(c * map.scale) * sin_theta));
                nodes.push(brightness(row[0] * map.scale) * sin_theta);
            }
            nodes
        };
        map.distribution = BilinearDistribution2D::new(&node_rows(&|c| luminance(c).max(0.0)), w + 1, rows);
        map.grid = (0..rows)
            .flat_map(|j| (0..=w).map(move |i| (j.min(h - 1), i % w)))
            .map(|(j, i)| (map.image.pixels[j * w + i] * map.scale).extend(0.0))
            .collect();
        let mut sum = glam::DVec3::ZERO;
        let mut solid_angle = 0.0f64;
        for y in 0..h {
            let v = (y as f32 + 0.5) / h as f32;
            let sin_theta = (PI * v).sin();
            for x in 0..w {
                let c = map.eval_uv(Vec2::new((x as f32 + 0.5) / w as f32, v));
                sum += c.as_dvec3() * sin_theta as f64;
                solid_angle += sin_theta as f64;
            }
        }
        map.average = (sum / solid_angle.max(1e-12)).as_vec3();
        let mean = luminance(map.average);
        let nodes = node_rows(&|c| (luminance(c) - mean).max(0.0));
        if nodes.iter().any(|&v| v > 0.0) {
            map.compensated = Some(BilinearDistribution2D::new(&nodes, w + 1, rows));
        }
        let nodes = map.density(true).nodes().to_vec();
        for (texel, node) in map.grid.iter_mut().zip(nodes) {
            texel.w = node;
        }
        map
    }

    /// An equal-area octahedral map: every pixel subtends 4π/N steradians,
    /// so the density is each pixel's luminance over their sum, and the
    /// average radiance the mean of the pixels.
    fn equal_area(image: ImageTexture, scale: f32, to_world: Transform) -> Self {
        let (w, h) = (image.width as usize, image.height as usize);
        let weights: Vec<f32> = image.pixels.iter().map(|&c| luminance(c).max(0.0)).collect();
        let sum: glam::DVec3 = image.pixels.iter().map(|c| c.as_dvec3()).sum();
        let mean = luminance((sum / (w * h).max(1) as f64).as_vec3());
        let compensated: Vec<f32> = image.pixels.iter().map(|&c| (luminance(c) - mean).max(0.0)).collect();
        EnvironmentMap {
            average: (sum * scale as f64 / (w * h).max(1) as f64).as_vec3(),
            pixel_distribution: Distribution2D::new(&weights, w, h),
            distribution: BilinearDistribution2D::default(),
            compensated: None,
            grid: Vec::new(),
            compensated_pixels: compensated
                .iter()
                .any(|&v| v > 0.0)
                .then(|| Distribution2D::new(&compensated, w, h)),
            image,
            scale,
            turns_only: keeps_lengths(&to_world),
            to_world,
            layout: EnvironmentLayout::EqualAreaOctahedral,
        }
    }

    /// The point of the sampling density's domain (the unit square spanned
    /// by its nodes) that map coordinates `uv` fall on: the
    /// density's columns start half a pixel to the right of u = 0.
    fn density_point(&self, uv: Vec2) -> Vec2 {
        let w = self.image.width as f32;
        let x = uv.x - 0.5 / w;
        Vec2::new(x - math::floor(x), uv.y)
    }

    /// The map coordinates of direction `dir_world` (of any length), and
    /// sin θ there.
    #[inline]
    fn uv_of(&self, dir_world: Vec3) -> (Vec2, f32) {
        let d = self.to_world.inv_vector(dir_world);
        // Both angles as arctangents of the unnormalised direction: no
        // square root and division before them, as normalising and an
        // arccosine would need.
        let across = (d.x * d.x + d.z * d.z).sqrt();
        let length = (across * across + d.y * d.y).sqrt();
        let u = math::atan2(d.x, -d.z) * (0.5 * FRAC_1_PI);
        let v = math::atan2(across, d.y) * FRAC_1_PI;
        let sin_theta = if length > 0.0 { across / length } else { 0.0 };
        let u = if u < 0.0 { u + 1.0 } else { u };
        (Vec2::new(u.min(1.0), v.clamp(0.0, 1.0)), sin_theta)
    }

    /// Direction `d` of the map's frame in the world's, of unit length.
    #[inline]
    fn turn(&self, d: Vec3) -> Vec3 {
        let turned = self.to_world.vector(d);
        if self.turns_only { turned } else { turned.normalize() }
    }

    #[inline]
    fn dir_of(&self, uv: Vec2) -> (Vec3, f32) {
        let (sin_phi, cos_phi) = (2.0 * PI * uv.x).sin_cos();
        let (st, cos_theta) = (PI * uv.y).sin_cos();
        let d = Vec3::new(st * sin_phi, cos_theta, -st * cos_phi);
        (self.turn(d), st)
    }

    /// The world direction at which [`EnvironmentMap::eval`] returns pixel
    /// (`x`, `y`) itself: its centre for the equal-area layout; for the
    /// latitude–longitude one its node of the lookup's grid (rows spread
    /// from pole to pole, so that the first and last rows' pixels all lie
    /// at a pole, where the lookup blends them).
    pub fn pixel_direction(&self, x: u32, y: u32) -> Vec3 {
        let (w, h) = (self.image.width as f32, self.image.height as f32);
        match self.layout {
            EnvironmentLayout::EqualAreaOctahedral => {
                let uv = Vec2::new((x as f32 + 0.5) / w, (y as f32 + 0.5) / h);
                self.turn(equal_area_square_to_sphere(uv))
            }
            EnvironmentLayout::LatLong => {
                let v = if self.image.height > 1 {
                    y as f32 / (h - 1.0)
                } else {
                    0.5
                };
                self.dir_of(Vec2::new((x as f32 + 0.5) / w, v)).0
            }
        }
    }

    /// The sum of several environments as one map: the largest of `maps`
    /// (by pixels) keeps its layout, frame and scale, and each of its
    /// pixels adds the other maps' radiance toward that pixel's direction
    /// ([`EnvironmentMap::pixel_direction`]) and `constant`. Exact for a
    /// map and constants; other maps are resampled at its pixels. `None`
    /// without maps.
    pub fn summed(maps: Vec<EnvironmentMap>, constant: Rgb) -> Option<EnvironmentMap> {
        let largest = (0..maps.len()).max_by_key(|&i| maps[i].image.pixels.len())?;
        let mut maps = maps;
        let target = maps.swap_remove(largest);
        if maps.is_empty() && constant == Rgb::ZERO {
            return Some(target);
        }
        let mut image = target.image.clone();
        let w = image.width;
        for y in 0..image.height {
            for x in 0..w {
                let d = target.pixel_direction(x, y);
                let added = maps.iter().map(|m| m.eval(d)).sum::<Rgb>() + constant;
                // The target's scale multiplies its pixels: what is added
                // is divided by it (a zero scale leaves only the others).
                let p = &mut image.pixels[(y * w + x) as usize];
                *p = if target.scale > 0.0 {
                    *p + added / target.scale
                } else {
                    added
                };
            }
        }
        let scale = if target.scale > 0.0 { target.scale } else { 1.0 };
        Some(EnvironmentMap::with_layout(
            image,
            scale,
            target.to_world,
            target.layout,
        ))
    }

    /// Radiance arriving from direction `dir`: for a latitude–longitude
    /// map bilinear between pixels, wrapping around in longitude, rows
    /// running from pole to pole; for an equal-area map the nearest pixel.
    #[inline]
    pub fn eval(&self, dir: Vec3) -> Rgb {
        match self.layout {
            EnvironmentLayout::LatLong => self.eval_uv(self.uv_of(dir).0),
            EnvironmentLayout::EqualAreaOctahedral => {
                let d = self.to_world.inv_vector(dir).normalize_or_zero();
                self.nearest(equal_area_sphere_to_square(d))
            }
        }
    }

    /// The pixel that holds point `uv` of the image (row 0 at v = 0).
    fn nearest(&self, uv: Vec2) -> Rgb {
        let (w, h) = (self.image.width as usize, self.image.height as usize);
        let x = ((uv.x * w as f32) as usize).min(w - 1);
        let y = ((uv.y * h as f32) as usize).min(h - 1);
        self.image.pixels[y * w + x] * self.scale
    }

    #[inline]
    fn eval_uv(&self, uv: Vec2) -> Rgb {
        self.grid_lookup(uv).truncate()
    }

    /// The bilinear interpolation of the grid at map coordinates `uv`: the
    /// radiance there and the node value of the MIS light samples' density.
    #[inline]
    fn grid_lookup(&self, uv: Vec2) -> Vec4 {
        let w = self.image.width as usize;
        let rows = self.grid.len() / (w + 1);
        // Columns lie at pixel centres, u = (i + ½)/W: left of the first
        // one lies between the last and the first again, at the end.
        let mut x = uv.x * w as f32 - 0.5;
        if x < 0.0 {
            x += w as f32;
        }
        let y = (uv.y * (rows - 1) as f32).clamp(0.0, (rows - 1) as f32);
        // Truncation is ⌊·⌋ here (x, y ≥ 0; NaN gives 0).
        let (i, j) = ((x as usize).min(w - 1), (y as usize).min(rows - 2));
        self.grid_bilerp(j * (w + 1) + i, Vec2::new(x - i as f32, y - j as f32))
    }

    /// The grid's cell whose first corner is `index`, interpolated at
    /// fractions `f`.
    #[inline(always)]
    fn grid_bilerp(&self, index: usize, f: Vec2) -> Vec4 {
        let below = index + self.image.width as usize + 1;
        let top = self.grid[index].lerp(self.grid[index + 1], f.x);
        let bottom = self.grid[below].lerp(self.grid[below + 1], f.x);
        top.lerp(bottom, f.y)
    }

    /// A direction drawn in proportion to the map's brightness, and its
    /// density per steradian.
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        self.sample_radiance(u, false).map(|(d, pdf, _)| (d, pdf))
    }

    /// The latitude–longitude density of light samples: the compensated
    /// one if `incomplete` and the map has one (see the module's text).
    #[inline]
    fn density(&self, incomplete: bool) -> &BilinearDistribution2D {
        match (&self.compensated, incomplete) {
            (Some(d), true) => d,
            _ => &self.distribution,
        }
    }

    /// [`EnvironmentMap::density`] for the equal-area layout.
    #[inline]
    fn pixel_density(&self, incomplete: bool) -> &Distribution2D {
        match (&self.compensated_pixels, incomplete) {
            (Some(d), true) => d,
            _ => &self.pixel_distribution,
        }
    }

    /// [`EnvironmentMap::sample`] with the radiance arriving from the
    /// direction drawn, looked up where it was drawn rather than found
    /// again from the direction (which costs an arctangent and an
    /// arccosine); from the compensated density if `incomplete`.
    pub fn sample_radiance(&self, u: Vec2, incomplete: bool) -> Option<(Vec3, f32, Rgb)> {
        if self.layout == EnvironmentLayout::EqualAreaOctahedral {
            let (uv, pdf_uv) = self.pixel_density(incomplete).sample(u);
            if pdf_uv <= 0.0 {
                return None;
            }
            let d = self.turn(equal_area_square_to_sphere(uv));
            return Some((d, pdf_uv / (4.0 * PI), self.nearest(uv)));
        }
        let density = self.density(incomplete);
        let (x, y, f, pdf_uv) = density.sample_in_cell(u);
        // The radiance from the grid at the same cell and fractions: the
        // density's nodes are the grid's.
        let w = self.image.width as usize;
        let rows = self.grid.len() / (w + 1);
        let li = self.grid_bilerp(y * (w + 1) + x, f).truncate();
        // The density's column x lies half a pixel right of pixel x's left
        // edge, and its last column, the first pixel again, at u = 1 + ½/W.
        let mut column = x as f32 + f.x + 0.5;
        if column >= w as f32 {
            column -= w as f32;
        }
        let uv = Vec2::new(column / w as f32, (y as f32 + f.y) / (rows - 1) as f32);
        let (d, sin_theta) = self.dir_of(uv);
        if sin_theta <= 0.0 || pdf_uv <= 0.0 {
            return None;
        }
        // dω = 2π² sin θ du dv.
        Some((d, pdf_uv / (2.0 * PI * PI * sin_theta), li))
    }

    /// [`EnvironmentMap::eval`] and the density of
    /// [`EnvironmentMap::sample_radiance`] (with the same `incomplete`) of
    /// one direction, which is mapped to the image once.
    pub fn eval_pdf(&self, dir: Vec3, incomplete: bool) -> (Rgb, f32) {
        if self.layout == EnvironmentLayout::EqualAreaOctahedral {
            let d = self.to_world.inv_vector(dir).normalize_or_zero();
            let uv = equal_area_sphere_to_square(d);
            return (self.nearest(uv), self.pixel_density(incomplete).pdf(uv) / (4.0 * PI));
        }
        let (uv, sin_theta) = self.uv_of(dir);
        let texel = self.grid_lookup(uv);
        // The grid holds the nodes of `density(true)`; the full density,
        // where that is the compensated one, is interpolated apart.
        let node = if incomplete || self.compensated.is_none() {
            texel.w * self.density(incomplete).norm()
        } else {
            self.distribution.pdf(self.density_point(uv))
        };
        let pdf = if sin_theta <= 0.0 {
            0.0
        } else {
            node / (2.0 * PI * PI * sin_theta)
        };
        (texel.truncate(), pdf)
    }

    /// Density of [`EnvironmentMap::sample`] for direction `dir`.
    pub fn pdf(&self, dir: Vec3) -> f32 {
        if self.layout == EnvironmentLayout::EqualAreaOctahedral {
            let d = self.to_world.inv_vector(dir).normalize_or_zero();
            return self.pixel_distribution.pdf(equal_area_sphere_to_square(d)) / (4.0 * PI);
        }
        let (uv, sin_theta) = self.uv_of(dir);
        if sin_theta <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(self.density_point(uv)) / (2.0 * PI * PI * sin_theta)
    }
}

/// Whether `t` maps every vector to one of the same length (a rotation,
/// perhaps a reflection), to the precision of its entries.
fn keeps_lengths(t: &Transform) -> bool {
    let m = glam::Mat3::from_mat4(t.m);
    (m.transpose() * m - glam::Mat3::IDENTITY)
        .to_cols_array()
        .iter()
        .all(|e| e.abs() < 1e-6)
}

/// What rays that leave the scene see.
#[derive(Clone, Debug)]
pub enum Background {
    /// One colour in every direction.
    Constant(Rgb),
    /// A vertical blend from `bottom` (looking straight down) to `top`
    /// (straight up).
    Gradient {
        /// Colour looking straight up.
        top: Rgb,
        /// Colour looking straight down.
        bottom: Rgb,
    },
    /// An environment image.
    Image(Box<EnvironmentMap>),
    /// An environment image seen through a portal.
    Portal(Box<super::portal::PortalMap>),
}

impl Default for Background {
    fn default() -> Self {
        Background::Constant(Rgb::ZERO)
    }
}

impl Background {
    /// Radiance arriving from direction `dir` (need not be normalised).
    #[inline]
    pub fn eval(&self, dir: Vec3) -> Rgb {
        match self {
            Background::Constant(c) => *c,
            Background::Gradient { top, bottom } => {
                let y = dir.normalize_or_zero().y;
                let t = 0.5 * (y + 1.0);
                *bottom * (1.0 - t) + *top * t
            }
            Background::Image(map) => map.eval(dir),
            Background::Portal(map) => map.eval(dir),
        }
    }

    /// Radiance arriving at `origin` from direction `dir`: [`Background::eval`]
    /// but through a portal, which only lets in what `origin` sees through
    /// it.
    #[inline]
    pub fn eval_from(&self, origin: Vec3, dir: Vec3) -> Rgb {
        // One match, not a second through `eval`: this is the path
        // tracer's every escaping ray.
        match self {
            Background::Constant(c) => *c,
            Background::Image(map) => map.eval(dir),
            Background::Portal(map) => map.eval_from(origin, dir),
            Background::Gradient { .. } => self.eval(dir),
        }
    }

    /// Whether no light comes from the background.
    pub fn is_black(&self) -> bool {
        match self {
            Background::Constant(c) => *c == Rgb::ZERO,
            Background::Gradient { top, bottom } => *top == Rgb::ZERO && *bottom == Rgb::ZERO,
            Background::Image(map) => map.average == Rgb::ZERO,
            Background::Portal(map) => map.average == Rgb::ZERO,
        }
    }

    /// Mean radiance over the sphere of directions.
    pub fn average(&self) -> Rgb {
        match self {
            Background::Constant(c) => *c,
            Background::Gradient { top, bottom } => 0.5 * (*top + *bottom),
            Background::Image(map) => map.average,
            // Black behind the portal.
            Background::Portal(map) => 0.5 * map.average,
        }
    }

    /// A direction toward the background and its density per steradian:
    /// uniform over the sphere for colours, by brightness for images.
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        match self {
            Background::Image(map) => map.sample(u),
            Background::Portal(map) => map.sample(u),
            _ => Some((sample_sphere_uniform(u), pdf_sphere_uniform())),
        }
    }

    /// Density of [`Background::sample`] for `dir`.
    pub fn pdf(&self, dir: Vec3) -> f32 {
        match self {
            Background::Image(map) => map.pdf(dir),
            Background::Portal(map) => map.pdf(dir),
            _ => pdf_sphere_uniform(),
        }
    }

    /// A direction toward the background from `p`: [`Background::sample`],
    /// but through a portal, only the directions `p` sees through it.
    #[inline]
    pub fn sample_from(&self, p: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        match self {
            Background::Image(map) => map.sample(u),
            Background::Portal(map) => map.sample_from(p, u),
            _ => Some((sample_sphere_uniform(u), pdf_sphere_uniform())),
        }
    }

    /// [`Background::sample_from`] with the radiance arriving from the
    /// direction drawn. With `incomplete` (pbrt-v4's `allowIncompletePDF`),
    /// for estimators that also sample the BSDF and weigh the two by
    /// multiple importance sampling, an image is sampled by its
    /// compensated density, which leaves out directions no brighter than
    /// the image's mean.
    ///
    /// A constant background's compensated density is zero everywhere:
    /// with `incomplete` it draws nothing (pbrt-v4's `UniformInfiniteLight`
    /// with `allowIncompletePDF`), and BSDF sampling, which for a constant
    /// radiance is the better strategy, finds all of its light.
    #[inline]
    pub fn sample_radiance_from(&self, p: Vec3, u: Vec2, incomplete: bool) -> Option<(Vec3, f32, Rgb)> {
        match self {
            Background::Image(map) => map.sample_radiance(u, incomplete),
            Background::Constant(_) if incomplete => None,
            _ => {
                let (wi, pdf) = self.sample_from(p, u)?;
                Some((wi, pdf, self.eval(wi)))
            }
        }
    }

    /// [`Background::eval_from`] and the density of
    /// [`Background::sample_radiance_from`] with the same `incomplete` at
    /// once (an image maps the direction to its pixels once).
    #[inline]
    pub fn eval_pdf_from(&self, p: Vec3, dir: Vec3, incomplete: bool) -> (Rgb, f32) {
        match self {
            Background::Image(map) => map.eval_pdf(dir, incomplete),
            Background::Constant(c) if incomplete => (*c, 0.0),
            _ => (self.eval_from(p, dir), self.pdf_from(p, dir)),
        }
    }

    /// Whether [`Background::sample_radiance_from`] with `incomplete` draws
    /// anything (not for a constant background).
    pub fn samples_when_incomplete(&self) -> bool {
        !matches!(self, Background::Constant(_))
    }

    /// Density of [`Background::sample_from`] for `dir` from `p`.
    #[inline]
    pub fn pdf_from(&self, p: Vec3, dir: Vec3) -> f32 {
        match self {
            Background::Image(map) => map.pdf(dir),
            Background::Portal(map) => map.pdf_from(p, dir),
            _ => pdf_sphere_uniform(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn test_map() -> EnvironmentMap {
        // A dim map with a bright blob of a few pixels.
        let (w, h) = (32u32, 16u32);
        let mut pixels = vec![Rgb::splat(0.1); (w * h) as usize];
        for (dy, dx, v) in [
            (0, 0, 50.0),
            (0, 1, 30.0),
            (1, 0, 30.0),
            (1, 1, 20.0),
            (0, -1, 10.0),
            (-1, 0, 10.0),
        ] {
            let (x, y) = ((10 + dx) as u32, (5 + dy) as u32);
            pixels[(y * w + x) as usize] = Rgb::new(v, 0.8 * v, 0.6 * v);
        }
        EnvironmentMap::new(
            ImageTexture {
                width: w,
                height: h,
                pixels,
            },
            2.0,
            Transform::rotate(Vec3::Y, 30.0).unwrap(),
        )
    }

    /// A random map of `w` × `h` pixels in `layout`, turned.
    fn random_map(w: u32, h: u32, layout: EnvironmentLayout, seed: u64) -> EnvironmentMap {
        let mut rng = Pcg32::new(seed, 3);
        let pixels = (0..w * h)
            .map(|_| Rgb::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0)
            .collect();
        let image = ImageTexture {
            width: w,
            height: h,
            pixels,
        };
        let turn = Transform::rotate(Vec3::new(1.0, 2.0, 0.5), 40.0).unwrap();
        EnvironmentMap::with_layout(image, 1.5, turn, layout)
    }

    /// Looked up toward [`EnvironmentMap::pixel_direction`], a map gives
    /// that pixel (scaled), in both layouts; summed with a constant it
    /// gives its own radiance plus the constant everywhere, and two maps
    /// of one layout and frame sum exactly at the pixels.
    #[test]
    fn pixel_directions_and_sums_of_environments() {
        let mut rng = Pcg32::new(9, 1);
        for (w, h, layout) in [
            (16, 8, EnvironmentLayout::LatLong),
            (8, 8, EnvironmentLayout::EqualAreaOctahedral),
        ] {
            let map = random_map(w, h, layout, 1);
            // A latitude–longitude map's first and last rows lie at the
            // poles, where every pixel of the row has the same direction.
            let rows = if layout == EnvironmentLayout::LatLong {
                1..h - 1
            } else {
                0..h
            };
            for y in rows {
                for x in 0..w {
                    let got = map.eval(map.pixel_direction(x, y));
                    let want = map.image.pixels[(y * w + x) as usize] * map.scale;
                    assert!(
                        (got - want).abs().max_element() < 1e-4,
                        "{layout:?} ({x}, {y}): {got} vs {want}"
                    );
                }
            }
            let c = Rgb::new(0.5, 0.25, 2.0);
            let sum = EnvironmentMap::summed(vec![map.clone()], c).unwrap();
            for _ in 0..200 {
                let d = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
                let (got, want) = (sum.eval(d), map.eval(d) + c);
                assert!(
                    (got - want).abs().max_element() < 1e-4,
                    "{layout:?} {d}: {got} vs {want}"
                );
            }
            let other = random_map(w, h, layout, 2);
            let both = EnvironmentMap::summed(vec![map.clone(), other.clone()], Rgb::ZERO).unwrap();
            for (x, y) in [(0, 1), (3, 5), (w - 1, h - 2)] {
                let d = map.pixel_direction(x, y);
                let (got, want) = (both.eval(d), map.eval(d) + other.eval(d));
                assert!(
                    (got - want).abs().max_element() < 1e-3,
                    "{layout:?} ({x}, {y}): {got} vs {want}"
                );
            }
            // Its mean is the sum of the means (within the resampling).
            let (a, b) = (both.average, map.average + other.average);
            assert!((a - b).abs().max_element() < 0.05 * b.max_element(), "{a} vs {b}");
        }
        assert!(EnvironmentMap::summed(Vec::new(), Rgb::ONE).is_none());
    }

    #[test]
    fn mapping_conventions() {
        let map = EnvironmentMap::new(
            ImageTexture {
                width: 4,
                height: 2,
                pixels: (0..8).map(|i| Rgb::splat(i as f32)).collect(),
            },
            1.0,
            Transform::IDENTITY,
        );
        // Up is the top row; −z is u = 0, +x is u = ¼, +z the centre column.
        assert!(map.eval(Vec3::Y).x < 4.0);
        assert!(map.eval(-Vec3::Y).x >= 4.0);
        let (uv, sin_theta) = map.uv_of(-Vec3::Z);
        assert!(uv.x.abs() < 1e-6 && (uv.y - 0.5).abs() < 1e-6, "{uv}");
        assert_eq!(sin_theta, 1.0);
        assert!((map.uv_of(Vec3::X).0.x - 0.25).abs() < 1e-6);
        assert!((map.uv_of(Vec3::Z).0.x - 0.5).abs() < 1e-6);
        for d in [
            Vec3::X,
            Vec3::new(0.3, 0.5, -0.8).normalize(),
            Vec3::new(-0.7, -0.2, 0.1).normalize(),
        ] {
            let (uv, sin_theta) = map.uv_of(d);
            let (back, sin_back) = map.dir_of(uv);
            assert!((back - d).length() < 1e-5, "{d} → {back}");
            assert!(
                (sin_theta - sin_back).abs() < 1e-6,
                "{d}: sin θ {sin_theta} and {sin_back}"
            );
        }
    }

    #[test]
    fn sampling_density_is_consistent_and_normalised() {
        let map = test_map();
        let mut r = Pcg32::new(8, 0);
        let n = 100_000;
        let mut mismatches = 0;
        // E[L/pdf] = ∫ L dω: the importance-sampled estimate and a uniform
        // one must agree within their standard errors.
        let (mut sum, mut sum_sq) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let (d, pdf) = map.sample(Vec2::new(r.next_f32(), r.next_f32())).unwrap();
            // A sample on a pixel border may round into the neighbour.
            if (pdf - map.pdf(d)).abs() > 1e-3 * pdf {
                mismatches += 1;
            }
            let v = (map.eval(d).x / pdf) as f64;
            sum += v;
            sum_sq += v * v;
        }
        assert!(mismatches < n / 1000, "{mismatches} samples disagree with pdf()");
        let (mut usum, mut usum_sq) = (0.0f64, 0.0f64);
        let m = 400_000;
        for _ in 0..m {
            let d = sample_sphere_uniform(Vec2::new(r.next_f32(), r.next_f32()));
            let v = (map.eval(d).x * 4.0 * PI) as f64;
            usum += v;
            usum_sq += v * v;
        }
        let (a, b) = (sum / n as f64, usum / m as f64);
        let var_a = (sum_sq / n as f64 - a * a) / n as f64;
        let var_b = (usum_sq / m as f64 - b * b) / m as f64;
        assert!((a - b).abs() < 4.0 * (var_a + var_b).sqrt(), "{a} vs {b}");
        // Importance sampling must pay: lower variance than uniform sampling.
        assert!(var_a * (n as f64) < var_b * (m as f64), "no variance reduction");
    }

    /// A map of random grey pixels whose brightness spans two orders of
    /// magnitude, with one-pixel suns.
    fn contrasty_map(w: u32, h: u32) -> EnvironmentMap {
        let mut r = Pcg32::new(21, 3);
        let mut pixels: Vec<Rgb> = (0..w * h).map(|_| Rgb::splat(0.1 + 10.0 * r.next_f32())).collect();
        for (x, y) in [(3, 5), (w - 1, h / 2), (w / 2, 1)] {
            if x < w && y < h {
                pixels[(y * w + x) as usize] = Rgb::splat(5000.0);
            }
        }
        EnvironmentMap::new(
            ImageTexture {
                width: w,
                height: h,
                pixels,
            },
            1.0,
            Transform::rotate(Vec3::new(0.3, 1.0, 0.2), 40.0).unwrap(),
        )
    }

    #[test]
    fn sampled_directions_follow_the_density() {
        use crate::sampling::chi2::Chi2Test;
        for map in [
            test_map(),
            contrasty_map(16, 8),
            contrasty_map(1, 1),
            contrasty_map(5, 1),
        ] {
            let mut r = Pcg32::new(9, 4);
            let result = Chi2Test::default().run(
                |_| map.sample(Vec2::new(r.next_f32(), r.next_f32())).map(|(d, _)| d),
                |d| map.pdf(d) as f64,
            );
            assert!(result.p_value > 0.001, "{result:?}");
        }
    }

    #[test]
    fn compensated_density_draws_only_what_is_brighter_than_the_mean() {
        use crate::sampling::chi2::Chi2Test;
        for map in [contrasty_map(16, 8), contrasty_map(5, 3), equal_area_map(16)] {
            let mean = luminance(map.average);
            let mut r = Pcg32::new(11, 6);
            let (mut drawn, mut mismatches) = (0, 0);
            for _ in 0..20_000 {
                let Some((d, pdf, li)) = map.sample_radiance(Vec2::new(r.next_f32(), r.next_f32()), true) else {
                    continue;
                };
                drawn += 1;
                // What the direction maps back to may round into the next
                // pixel.
                let (l, pdf_eval) = map.eval_pdf(d, true);
                if (pdf - pdf_eval).abs() > 1e-3 * pdf || (li - l).abs().max_element() > 1e-3 * l.max_element() {
                    mismatches += 1;
                }
                // An equal-area map's samples land on pixels brighter than
                // the mean (a bilinear map's between such a pixel and others).
                if map.layout == EnvironmentLayout::EqualAreaOctahedral {
                    assert!(luminance(li) > mean, "{li:?} drawn, mean {mean}");
                }
            }
            assert!(drawn > 19_000, "{drawn} of 20000 samples drawn");
            assert!(mismatches < 20, "{mismatches} samples disagree with eval_pdf");
            // Directions no brighter than the mean are never drawn: a
            // uniform direction toward the dimmest part has density 0.
            let dim = (0..2000)
                .map(|_| sample_sphere_uniform(Vec2::new(r.next_f32(), r.next_f32())))
                .filter(|&d| map.eval(d).max_element() < 0.5 * mean)
                .collect::<Vec<_>>();
            if map.layout == EnvironmentLayout::EqualAreaOctahedral {
                assert!(dim.iter().all(|&d| map.eval_pdf(d, true).1 == 0.0));
            }
            let mut r = Pcg32::new(12, 7);
            let result = Chi2Test::default().run(
                |_| {
                    map.sample_radiance(Vec2::new(r.next_f32(), r.next_f32()), true)
                        .map(|(d, _, _)| d)
                },
                |d| map.eval_pdf(d, true).1 as f64,
            );
            assert!(result.p_value > 0.001, "{result:?}");
        }
        // A constant map has nothing above its mean: its light samples
        // keep the full density.
        let flat = EnvironmentMap::new(
            ImageTexture {
                width: 8,
                height: 4,
                pixels: vec![Rgb::splat(0.5); 32],
            },
            1.0,
            Transform::IDENTITY,
        );
        let u = Vec2::new(0.3, 0.6);
        assert_eq!(flat.sample_radiance(u, true), flat.sample_radiance(u, false));
        assert!(flat.sample_radiance(u, true).is_some());
    }

    #[test]
    fn grey_maps_are_sampled_nearly_in_proportion_to_their_radiance() {
        // The density follows the bilinear lookup, so L/pdf varies only
        // where luminance × sin θ between rows is not luminance between
        // rows × sin θ: most near the poles, whose nodes are 0 however
        // bright their pixels (as in Mitsuba's envmap). Beside one-pixel
        // suns 500 times the sky its relative spread stays small; a density
        // constant over each pixel leaves a dim margin around each sun,
        // where L/pdf is hundreds of times its mean.
        let map = contrasty_map(64, 32);
        let mut r = Pcg32::new(10, 5);
        let n = 100_000;
        let (mut sum, mut sum_sq, mut max) = (0.0f64, 0.0f64, 0.0f64);
        for _ in 0..n {
            let (d, pdf) = map.sample(Vec2::new(r.next_f32(), r.next_f32())).unwrap();
            let v = (map.eval(d).x / pdf) as f64;
            sum += v;
            sum_sq += v * v;
            max = max.max(v);
        }
        let mean = sum / n as f64;
        let cv = (sum_sq / n as f64 - mean * mean).max(0.0).sqrt() / mean;
        assert!(
            cv < 0.15 && max < 5.0 * mean,
            "relative spread {cv}, largest {} × the mean",
            max / mean
        );
    }

    #[test]
    fn equal_area_mapping_round_trips_and_keeps_area() {
        let mut r = Pcg32::new(12, 6);
        for _ in 0..10_000 {
            let d = sample_sphere_uniform(Vec2::new(r.next_f32(), r.next_f32()));
            let p = equal_area_sphere_to_square(d);
            assert!((0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y), "{p}");
            let back = equal_area_square_to_sphere(p);
            assert!((back - d).length() < 2e-4, "{d} → {p} → {back}");
        }
        // pbrt-v4's conventions: +z at the centre, −z at the corners, +x right, +y down the rows.
        assert!((equal_area_square_to_sphere(Vec2::splat(0.5)) - Vec3::Z).length() < 1e-6);
        assert!((equal_area_square_to_sphere(Vec2::ZERO) + Vec3::Z).length() < 1e-6);
        assert!((equal_area_square_to_sphere(Vec2::new(1.0, 0.5)) - Vec3::X).length() < 1e-6);
        assert!((equal_area_square_to_sphere(Vec2::new(0.5, 1.0)) - Vec3::Y).length() < 1e-6);
        // Equal area: uniform points of the square are uniform on the
        // sphere, so each of 8 octants gets an eighth and the mean of z² is ⅓.
        let n = 200_000;
        let (mut octants, mut z2) = ([0u32; 8], 0.0f64);
        for _ in 0..n {
            let d = equal_area_square_to_sphere(Vec2::new(r.next_f32(), r.next_f32()));
            octants[(d.x > 0.0) as usize | ((d.y > 0.0) as usize) << 1 | ((d.z > 0.0) as usize) << 2] += 1;
            z2 += (d.z * d.z) as f64;
        }
        for c in octants {
            // 5 standard deviations of a binomial count.
            assert!(
                (c as f64 - n as f64 / 8.0).abs() < 5.0 * (n as f64 * 7.0 / 64.0).sqrt(),
                "{octants:?}"
            );
        }
        // Var(z²) = 4/45 for uniform directions.
        assert!((z2 / n as f64 - 1.0 / 3.0).abs() < 5.0 * (4.0 / 45.0 / n as f64).sqrt());
    }

    fn equal_area_map(w: u32) -> EnvironmentMap {
        let mut r = Pcg32::new(4, 4);
        let mut pixels: Vec<Rgb> = (0..w * w).map(|_| Rgb::splat(0.1 + r.next_f32())).collect();
        pixels[(w * w / 3) as usize] = Rgb::new(400.0, 300.0, 200.0);
        EnvironmentMap::with_layout(
            ImageTexture {
                width: w,
                height: w,
                pixels,
            },
            1.5,
            Transform::rotate(Vec3::new(1.0, 0.2, 0.0), -90.0).unwrap(),
            EnvironmentLayout::EqualAreaOctahedral,
        )
    }

    #[test]
    fn equal_area_maps_are_sampled_by_their_density_and_in_proportion_to_radiance() {
        use crate::sampling::chi2::Chi2Test;
        let map = equal_area_map(16);
        let mut r = Pcg32::new(13, 1);
        let result = Chi2Test::default().run(
            |_| map.sample(Vec2::new(r.next_f32(), r.next_f32())).map(|(d, _)| d),
            |d| map.pdf(d) as f64,
        );
        assert!(result.p_value > 0.001, "{result:?}");
        // Nearest-pixel lookup and a density constant over each pixel: L/pdf
        // is the same for every sample of a grey map (up to samples on a
        // pixel's edge, which the round trip may put in the neighbour).
        let (mut off, n) = (0, 20_000);
        let expected = 4.0 * PI * luminance(map.average);
        for _ in 0..n {
            let (d, pdf) = map.sample(Vec2::new(r.next_f32(), r.next_f32())).unwrap();
            let l = map.eval(d);
            let grey = l.x == l.y && l.y == l.z;
            if grey && (luminance(l) / pdf / expected - 1.0).abs() > 1e-3 {
                off += 1;
            }
        }
        assert!(off < n / 200, "{off} of {n} grey samples with L/pdf away from ∫L dω");
    }
}
