//! An environment map seen through a portal (pbrt-v4's
//! `PortalImageInfiniteLight`, after Bitterli et al. 2015, "Portal-Masked
//! Environment Map Sampling"): a rectangle, typically a window, through
//! which alone the map's light enters. A direction is parameterised by its
//! two angles in the portal's frame, α = atan(x/z) and β = atan(y/z), each
//! over (−π/2, π/2); seen from a point, the portal is then an axis-aligned
//! rectangle of that square, within which directions are sampled in
//! proportion to the map's brightness, using a summed-area table of the
//! map resampled into the parameterisation.
//!
//! As in pbrt-v4, light arrives only from directions through the portal
//! as seen from the point the ray left; a light path (photons, BDPT's light
//! subpaths) leaves from the whole map in front of the portal.

use crate::color::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_PI_2, PI};

/// A piecewise-constant function on [0, 1]² that can be sampled within
/// any axis-aligned window (pbrt-v4's `WindowedPiecewiseConstant2D`).
#[derive(Clone, Debug, PartialEq)]
pub struct WindowedDistribution2D {
    nx: usize,
    ny: usize,
    func: Vec<f32>,
    /// Summed-area table: sat[y·nx + x] = Σ func over [0, x] × [0, y].
    sat: Vec<f64>,
}

/// A rectangle of [0, 1]².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// Lower corner.
    pub min: Vec2,
    /// Upper corner.
    pub max: Vec2,
}

impl WindowedDistribution2D {
    /// The function of `func` (row after row, `nx` per row).
    pub fn new(func: Vec<f32>, nx: usize, ny: usize) -> Self {
        assert_eq!(func.len(), nx * ny);
        let mut sat = vec![0.0f64; nx * ny];
        for y in 0..ny {
            let mut row = 0.0f64;
            for x in 0..nx {
                row += func[y * nx + x].max(0.0) as f64;
                sat[y * nx + x] = row + if y > 0 { sat[(y - 1) * nx + x] } else { 0.0 };
            }
        }
        WindowedDistribution2D { nx, ny, func, sat }
    }

    /// The table at integer corner (x, y) of the grid (0 on the low edges).
    fn corner(&self, x: usize, y: usize) -> f64 {
        if x == 0 || y == 0 {
            return 0.0;
        }
        self.sat[(y - 1).min(self.ny - 1) * self.nx + (x - 1).min(self.nx - 1)]
    }

    /// ∫ over [0, x] × [0, y], the table interpolated bilinearly.
    fn lookup(&self, x: f32, y: f32) -> f64 {
        let (x, y) = ((x * self.nx as f32) as f64, (y * self.ny as f32) as f64);
        let (x0, y0) = (x.max(0.0) as usize, y.max(0.0) as usize);
        let (dx, dy) = (x - x0 as f64, y - y0 as f64);
        (1.0 - dx) * (1.0 - dy) * self.corner(x0, y0)
            + (1.0 - dx) * dy * self.corner(x0, y0 + 1)
            + dx * (1.0 - dy) * self.corner(x0 + 1, y0)
            + dx * dy * self.corner(x0 + 1, y0 + 1)
    }

    /// The function's integral over a window of the unit square.
    pub fn integral(&self, w: Window) -> f64 {
        let s = self.lookup(w.max.x, w.max.y) - self.lookup(w.min.x, w.max.y) + self.lookup(w.min.x, w.min.y)
            - self.lookup(w.max.x, w.min.y);
        (s / (self.nx * self.ny) as f64).max(0.0)
    }

    fn eval(&self, p: Vec2) -> f32 {
        let x = ((p.x * self.nx as f32) as usize).min(self.nx - 1);
        let y = ((p.y * self.ny as f32) as usize).min(self.ny - 1);
        self.func[y * self.nx + x].max(0.0)
    }

    /// Inverts a monotone CDF by bisection down to one cell, then linearly.
    fn bisect(cdf: impl Fn(f32) -> f64, u: f64, mut min: f32, mut max: f32, n: usize) -> f32 {
        let n = n as f32;
        while (n * max).ceil() - (n * min).floor() > 1.0 {
            let mid = 0.5 * (min + max);
            if cdf(mid) > u {
                max = mid;
            } else {
                min = mid;
            }
        }
        let (lo, hi) = (cdf(min), cdf(max));
        let t = if hi > lo { ((u - lo) / (hi - lo)) as f32 } else { 0.5 };
        (min + t * (max - min)).clamp(min, max)
    }

    /// A point of the window drawn in proportion to the function, and its
    /// density with respect to area of the unit square.
    pub fn sample(&self, u: Vec2, w: Window) -> Option<(Vec2, f32)> {
        let total = self.integral(w);
        if total <= 0.0 {
            return None;
        }
        let x = Self::bisect(
            |x| {
                self.integral(Window {
                    min: w.min,
                    max: Vec2::new(x, w.max.y),
                }) / total
            },
            u.x as f64,
            w.min.x,
            w.max.x,
            self.nx,
        );
        // The column of cells the point fell in.
        let nx = self.nx as f32;
        let mut column = Window {
            min: Vec2::new((x * nx).floor() / nx, w.min.y),
            max: Vec2::new((x * nx).ceil() / nx, w.max.y),
        };
        if column.min.x == column.max.x {
            column.max.x += 1.0 / nx;
        }
        let column_total = self.integral(column);
        if column_total <= 0.0 {
            return None;
        }
        let y = Self::bisect(
            |y| {
                self.integral(Window {
                    min: column.min,
                    max: Vec2::new(column.max.x, y),
                }) / column_total
            },
            u.y as f64,
            w.min.y,
            w.max.y,
            self.ny,
        );
        let p = Vec2::new(x, y);
        Some((p, (self.eval(p) as f64 / total) as f32))
    }

    /// The density [`WindowedDistribution2D::sample`] draws `p` with.
    pub fn pdf(&self, p: Vec2, w: Window) -> f32 {
        let total = self.integral(w);
        if total <= 0.0 {
            return 0.0;
        }
        (self.eval(p) as f64 / total) as f32
    }
}

/// An environment map masked by a rectangular portal.
#[derive(Clone, Debug, PartialEq)]
pub struct PortalMap {
    /// The portal's corners, in order around it.
    corners: [Vec3; 4],
    /// Its frame: x along corner 0 → 3, y along 0 → 1, z = x × y (the
    /// side light comes from).
    frame: [Vec3; 3],
    /// The map resampled into (α, β), `res`² pixels, row by row.
    image: Vec<Rgb>,
    res: usize,
    distribution: WindowedDistribution2D,
    /// Mean radiance over the directions in front of the portal.
    pub average: Rgb,
}

impl PortalMap {
    /// The portal `corners` (a rectangle) over `map`, resampled at `res`²
    /// (pbrt-v4 keeps the map's resolution). Errors say why the corners
    /// are not a rectangle.
    pub fn new(map: impl Fn(Vec3) -> Rgb, corners: [Vec3; 4], res: usize) -> Result<PortalMap, String> {
        let edge = |a: usize, b: usize| (corners[b] - corners[a]).normalize_or_zero();
        let (p01, p12, p32, p03) = (edge(0, 1), edge(1, 2), edge(3, 2), edge(0, 3));
        if [p01, p12, p32, p03].contains(&Vec3::ZERO) {
            return Err("two of its corners coincide".into());
        }
        let parallel = (p01.dot(p32) - 1.0).abs() <= 1e-3 && (p12.dot(p03) - 1.0).abs() <= 1e-3;
        let square = [p01.dot(p12), p12.dot(p32), p32.dot(p03), p03.dot(p01)]
            .iter()
            .all(|d| d.abs() <= 1e-3);
        if !(parallel && square) {
            return Err("its corners do not make a rectangle (pbrt-v4 wants one, corners in order)".into());
        }
        let x = p03;
        let y = p01;
        let z = x.cross(y).normalize();
        let mut portal = PortalMap {
            corners,
            frame: [x, y, z],
            image: Vec::with_capacity(res * res),
            res,
            distribution: WindowedDistribution2D::new(vec![0.0], 1, 1),
            average: Rgb::ZERO,
        };
        let mut weights = Vec::with_capacity(res * res);
        let mut sum = Rgb::ZERO;
        let mut solid_angle = 0.0f32;
        for j in 0..res {
            for i in 0..res {
                let uv = Vec2::new((i as f32 + 0.5) / res as f32, (j as f32 + 0.5) / res as f32);
                let (w, duv_dw) = portal.direction(uv);
                let c = map(w);
                portal.image.push(c);
                // Sampling density in (α, β) ∝ radiance per steradian.
                weights.push((c.x + c.y + c.z) / 3.0 * duv_dw);
                // (`duv_dw` is pbrt-v4's name; it is dω per unit of (α, β).)
                sum += c * duv_dw;
                solid_angle += duv_dw;
            }
        }
        portal.average = if solid_angle > 0.0 {
            sum / solid_angle
        } else {
            Rgb::ZERO
        };
        portal.distribution = WindowedDistribution2D::new(weights, res, res);
        Ok(portal)
    }

    /// The world direction of (α, β) coordinates `uv`, and the solid angle
    /// per unit area of (α, β) there, π²(1 − x²)(1 − y²)/z (pbrt-v4's
    /// `duv_dw`): a density in (α, β) divided by it is one per steradian.
    fn direction(&self, uv: Vec2) -> (Vec3, f32) {
        let alpha = -FRAC_PI_2 + uv.x * PI;
        let beta = -FRAC_PI_2 + uv.y * PI;
        let w = Vec3::new(alpha.tan(), beta.tan(), 1.0).normalize();
        let duv_dw = PI * PI * (1.0 - w.x * w.x) * (1.0 - w.y * w.y) / w.z;
        let [x, y, z] = self.frame;
        (x * w.x + y * w.y + z * w.z, duv_dw)
    }

    /// The (α, β) coordinates of a world direction in front of the portal,
    /// and the solid angle per unit of them there.
    fn coordinates(&self, dir: Vec3) -> Option<(Vec2, f32)> {
        let d = dir.normalize_or_zero();
        let [x, y, z] = self.frame;
        let w = Vec3::new(d.dot(x), d.dot(y), d.dot(z));
        if w.z <= 0.0 {
            return None;
        }
        let duv_dw = PI * PI * (1.0 - w.x * w.x) * (1.0 - w.y * w.y) / w.z;
        let uv = Vec2::new(
            ((w.x.atan2(w.z) + FRAC_PI_2) / PI).clamp(0.0, 1.0),
            ((w.y.atan2(w.z) + FRAC_PI_2) / PI).clamp(0.0, 1.0),
        );
        Some((uv, duv_dw))
    }

    /// The window of (α, β) through which the portal is seen from `p`.
    fn window(&self, p: Vec3) -> Option<Window> {
        let (a, _) = self.coordinates(self.corners[0] - p)?;
        let (b, _) = self.coordinates(self.corners[2] - p)?;
        Some(Window {
            min: a.min(b),
            max: a.max(b),
        })
    }

    fn lookup(&self, uv: Vec2) -> Rgb {
        let n = self.res as f32;
        let i = ((uv.x * n) as usize).min(self.res - 1);
        let j = ((uv.y * n) as usize).min(self.res - 1);
        self.image[j * self.res + i]
    }

    /// The map toward `dir`, for any point in front of the portal (black
    /// behind it): what light paths leave with.
    pub fn eval(&self, dir: Vec3) -> Rgb {
        self.coordinates(dir).map_or(Rgb::ZERO, |(uv, _)| self.lookup(uv))
    }

    /// Radiance arriving at `origin` from `dir`: the map where `dir` passes
    /// through the portal as seen from `origin`, black elsewhere.
    pub fn eval_from(&self, origin: Vec3, dir: Vec3) -> Rgb {
        let (Some((uv, _)), Some(w)) = (self.coordinates(dir), self.window(origin)) else {
            return Rgb::ZERO;
        };
        if uv.cmplt(w.min).any() || uv.cmpgt(w.max).any() {
            return Rgb::ZERO;
        }
        self.lookup(uv)
    }

    /// A direction from `p` through the portal, by brightness, and its
    /// density per steradian.
    pub fn sample_from(&self, p: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        self.sample_in(self.window(p)?, u)
    }

    /// A direction anywhere in front of the portal, by brightness.
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        self.sample_in(
            Window {
                min: Vec2::ZERO,
                max: Vec2::ONE,
            },
            u,
        )
    }

    fn sample_in(&self, w: Window, u: Vec2) -> Option<(Vec3, f32)> {
        let (uv, pdf_uv) = self.distribution.sample(u, w)?;
        let (dir, duv_dw) = self.direction(uv);
        if duv_dw <= 0.0 || pdf_uv <= 0.0 {
            return None;
        }
        Some((dir, pdf_uv / duv_dw))
    }

    /// The density of [`PortalMap::sample_from`] for `dir` from `p`.
    pub fn pdf_from(&self, p: Vec3, dir: Vec3) -> f32 {
        let (Some((uv, duv_dw)), Some(w)) = (self.coordinates(dir), self.window(p)) else {
            return 0.0;
        };
        if duv_dw <= 0.0 || uv.cmplt(w.min).any() || uv.cmpgt(w.max).any() {
            return 0.0;
        }
        self.distribution.pdf(uv, w) / duv_dw
    }

    /// The density of [`PortalMap::sample`] for `dir`.
    pub fn pdf(&self, dir: Vec3) -> f32 {
        let Some((uv, duv_dw)) = self.coordinates(dir) else {
            return 0.0;
        };
        if duv_dw <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(
            uv,
            Window {
                min: Vec2::ZERO,
                max: Vec2::ONE,
            },
        ) / duv_dw
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;
    use crate::sampling::warp::sample_sphere_uniform;

    fn lumpy(nx: usize, ny: usize) -> WindowedDistribution2D {
        let f = (0..nx * ny).map(|i| 0.1 + ((i * 7919) % 17) as f32).collect();
        WindowedDistribution2D::new(f, nx, ny)
    }

    /// Samples stay in their window, carry the density `pdf` gives, and
    /// fall in each cell in proportion to the function there.
    #[test]
    fn windowed_samples_follow_the_function_inside_the_window() {
        let d = lumpy(8, 6);
        let w = Window {
            min: Vec2::new(0.2, 0.3),
            max: Vec2::new(0.9, 0.75),
        };
        let mut rng = Pcg32::new(3, 0);
        let n = 200_000;
        let mut counts = [0u32; 48];
        for _ in 0..n {
            let (p, pdf) = d.sample(Vec2::new(rng.next_f32(), rng.next_f32()), w).unwrap();
            assert!(p.cmpge(w.min - 1e-6).all() && p.cmple(w.max + 1e-6).all(), "{p}");
            assert!((pdf - d.pdf(p, w)).abs() <= 1e-5 * pdf, "{pdf} {}", d.pdf(p, w));
            counts[((p.y * 6.0) as usize).min(5) * 8 + ((p.x * 8.0) as usize).min(7)] += 1;
        }
        // Expected share of each cell: its value times its overlap with the
        // window, over the window's integral.
        let total = d.integral(w);
        for (i, &c) in counts.iter().enumerate() {
            let (x, y) = (i % 8, i / 8);
            let cell = Window {
                min: Vec2::new(x as f32 / 8.0, y as f32 / 6.0).max(w.min),
                max: Vec2::new((x + 1) as f32 / 8.0, (y + 1) as f32 / 6.0).min(w.max),
            };
            let expected = if cell.max.cmpgt(cell.min).all() {
                d.integral(cell) / total
            } else {
                0.0
            };
            let got = c as f64 / n as f64;
            let sigma = (expected * (1.0 - expected) / n as f64).sqrt();
            assert!(
                (got - expected).abs() <= 5.0 * sigma + 1e-4,
                "cell {i}: {got} against {expected}"
            );
        }
    }

    fn window_portal(map: impl Fn(Vec3) -> Rgb) -> PortalMap {
        // A 2 × 1 window in the plane z = 3, light coming from +z.
        let corners = [
            Vec3::new(-1.0, -0.5, 3.0),
            Vec3::new(-1.0, 0.5, 3.0),
            Vec3::new(1.0, 0.5, 3.0),
            Vec3::new(1.0, -0.5, 3.0),
        ];
        PortalMap::new(map, corners, 64).unwrap()
    }

    /// Through the window: directions sampled from a point pass through
    /// it, with the density `pdf_from` gives, which integrates to 1; the
    /// map is seen through the window only.
    #[test]
    fn a_portal_lets_light_in_through_itself_only() {
        let sky = |d: Vec3| Rgb::new(1.0 + d.x.max(0.0) * 4.0, 1.0, 1.0 + d.y.abs());
        let portal = window_portal(sky);
        // Light comes from +z: the frame's z.
        let p = Vec3::new(0.3, -0.2, 0.5);
        // How far inside the window the line from p along d passes
        // (negative: outside, or away from it).
        let inside = |d: Vec3| {
            if d.z <= 0.0 {
                return -1.0;
            }
            let q = p + d * ((3.0 - p.z) / d.z);
            (1.0 - q.x.abs()).min(0.5 - q.y.abs())
        };
        let through = |d: Vec3| inside(d) > -1e-3;
        let mut rng = Pcg32::new(5, 0);
        for _ in 0..5000 {
            let (d, pdf) = portal
                .sample_from(p, Vec2::new(rng.next_f32(), rng.next_f32()))
                .unwrap();
            assert!(through(d), "{d} misses the window");
            assert!(
                (pdf - portal.pdf_from(p, d)).abs() <= 1e-3 * pdf,
                "{pdf} {}",
                portal.pdf_from(p, d)
            );
        }
        let n = 400_000;
        let mut integral = 0.0f64;
        for _ in 0..n {
            let d = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
            integral += portal.pdf_from(p, d) as f64 * 4.0 * std::f64::consts::PI;
            let le = portal.eval_from(p, d);
            if inside(d).abs() < 1e-3 {
                continue; // on the window's edge: either way
            }
            if through(d) {
                // The nearest of 64² resampled pixels: within the sky's
                // change across one.
                assert!((le - sky(d)).abs().max_element() < 0.2, "{le} against {}", sky(d));
            } else {
                assert_eq!(le, Rgb::ZERO, "{d} does not pass the window");
            }
        }
        let integral = integral / n as f64;
        assert!((integral - 1.0).abs() < 0.03, "∫ pdf = {integral}");
        // Beyond the window, or behind it, nothing is seen.
        assert!(portal.sample_from(Vec3::new(0.0, 0.0, 4.0), Vec2::splat(0.5)).is_none());
        // Corners out of order are refused.
        let c = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
        assert!(PortalMap::new(sky, c, 4).unwrap_err().contains("rectangle"));
    }
}
