//! A camera of real lenses: rays from the film traced through the spherical
//! interfaces and the aperture stop of a lens description (pbrt-v4's
//! `RealisticCamera`, after Kolb, Mitchell and Hanrahan 1995, "A realistic
//! camera model for computer graphics").
//!
//! Camera space is the other cameras': the film lies in the plane z = 0,
//! centred on the optical axis, and the scene toward +z; lengths are
//! metres. The lens description lists the interfaces from the scene's side
//! to the film's, each with its curvature radius (0 for the aperture stop),
//! its distance to the next one along the axis (the last one's: to the
//! film), the index of refraction behind it (toward the film) and its
//! aperture diameter. Rays are drawn toward the rear element through the
//! exit pupil's bounds, precomputed over rings of the film; each carries
//! the weight cos⁴θ·A/d² of the irradiance it measures (A the area drawn
//! over, d the rear element's distance).

use glam::{Vec2, Vec3};

/// One interface of the lens system.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Interface {
    /// Radius of curvature (m): positive when the centre lies toward the
    /// film; 0 for the aperture stop.
    curvature_radius: f32,
    /// Distance to the next interface toward the film, or to the film.
    thickness: f32,
    /// Index of refraction of the medium behind it (toward the film); 0
    /// (the stop) and 1 are air.
    eta: f32,
    /// Radius of its opening (m).
    aperture_radius: f32,
}

/// A lens system focused on a plane, with the exit pupil's bounds.
#[derive(Clone, Debug, PartialEq)]
pub struct LensSystem {
    /// From the scene's side to the film's.
    interfaces: Vec<Interface>,
    /// Half the film's width and height (m).
    film_half: Vec2,
    /// The film's diagonal (m).
    film_diagonal: f32,
    /// Per ring of the film from its centre out (equal widths up to half
    /// the diagonal), the bounds (min, max) on the rear element's plane of
    /// the points through which rays from a point of the ring on the +x
    /// axis leave the system; `None` where none do.
    exit_pupils: Vec<Option<(Vec2, Vec2)>>,
    /// The aperture stop's shape, where it is not round.
    stop_mask: Option<ApertureMask>,
}

/// Rings of the film with their own exit pupil bounds.
const PUPIL_RINGS: usize = 64;
/// Points tried per ring to find its exit pupil (pbrt-v4 tries 1024²;
/// fewer here widen the bounds' margin instead, which costs only samples
/// that the lens then blocks).
const PUPIL_SAMPLES: usize = 128 * 128;

impl LensSystem {
    /// A lens system from a lens description's numbers (millimetres, four
    /// per interface: curvature radius, thickness, index, aperture
    /// diameter), its stop opened to `aperture_diameter` (mm; no wider than
    /// the stop), focused on the plane `focus_distance` (m) in front of
    /// it, over a film of `width` × `height` pixels and diagonal
    /// `film_diagonal` (m); its stop shaped by `stop_mask`, or round.
    pub fn new(
        numbers: &[f32],
        aperture_diameter: f32,
        focus_distance: f32,
        film_diagonal: f32,
        (width, height): (u32, u32),
        stop_mask: Option<ApertureMask>,
    ) -> Result<LensSystem, String> {
        if numbers.is_empty() || numbers.len() % 4 != 0 {
            return Err(format!(
                "a lens description needs four numbers per interface (curvature radius, thickness, index, aperture diameter), found {}",
                numbers.len()
            ));
        }
        if let Some(bad) = numbers.iter().find(|x| !x.is_finite()) {
            return Err(format!("the lens description has a number that is not finite ({bad})"));
        }
        let interfaces: Vec<Interface> = numbers
            .chunks_exact(4)
            .map(|c| {
                let stop = c[0] == 0.0;
                let diameter = if stop { aperture_diameter.min(c[3]) } else { c[3] };
                Interface {
                    curvature_radius: c[0] / 1000.0,
                    thickness: c[1] / 1000.0,
                    eta: c[2],
                    aperture_radius: diameter / 2000.0,
                }
            })
            .collect();
        if interfaces
            .iter()
            .any(|i| i.aperture_radius <= 0.0 || i.thickness < 0.0 || i.eta < 0.0)
        {
            return Err(
                "every interface of the lens needs a positive aperture, a thickness of at least 0 and an index of at least 0"
                    .into(),
            );
        }
        let aspect = height as f32 / width as f32;
        let x = (film_diagonal * film_diagonal / (1.0 + aspect * aspect)).sqrt();
        let mut lens = LensSystem {
            interfaces,
            film_half: Vec2::new(x, aspect * x) / 2.0,
            film_diagonal,
            exit_pupils: Vec::new(),
            stop_mask,
        };
        let film_distance = lens.focus_thick_lens(focus_distance)?;
        lens.interfaces.last_mut().expect("at least one interface").thickness = film_distance;
        lens.exit_pupils = (0..PUPIL_RINGS)
            .map(|i| {
                let r = |k: usize| k as f32 / PUPIL_RINGS as f32 * film_diagonal / 2.0;
                lens.bound_exit_pupil(r(i), r(i + 1))
            })
            .collect();
        if lens.exit_pupils.iter().all(Option::is_none) {
            return Err("no ray from the film passes through the lens (is its stop closed?)".into());
        }
        Ok(lens)
    }

    /// Distance from the film to the rear element.
    fn rear_z(&self) -> f32 {
        self.interfaces.last().map_or(0.0, |i| i.thickness)
    }

    /// Distance from the film to the front element.
    fn front_z(&self) -> f32 {
        self.interfaces.iter().map(|i| i.thickness).sum()
    }

    /// The ray (origin, direction) in camera space that leaves the front
    /// of the lens for the ray from the film `o + t·d`, and the share of
    /// it a shaped stop lets through; `None` where an interface blocks it
    /// or reflects it totally.
    pub fn trace_from_film(&self, o: Vec3, d: Vec3) -> Option<(Vec3, Vec3, f32)> {
        // Lens space: z negated, so the scene lies toward −z.
        let (mut o, mut d) = (o * Vec3::new(1.0, 1.0, -1.0), d * Vec3::new(1.0, 1.0, -1.0));
        let mut z = 0.0;
        let mut weight = 1.0;
        for i in (0..self.interfaces.len()).rev() {
            let e = self.interfaces[i];
            z -= e.thickness;
            if let (Some(mask), true) = (&self.stop_mask, e.curvature_radius == 0.0) {
                // A shaped stop replaces the round one (pbrt-v4 tests the
                // stop against its aperture image alone).
                let (t, _) = intersect_interface(0.0, z, o, d)?;
                o += d * t;
                weight *= mask.weight(o.truncate() / e.aperture_radius);
                if weight <= 0.0 {
                    return None;
                }
                continue;
            }
            let ahead = if i > 0 {
                air_if_zero(self.interfaces[i - 1].eta)
            } else {
                1.0
            };
            (o, d) = cross_interface(&e, z, o, d, air_if_zero(e.eta), ahead)?;
        }
        Some((o * Vec3::new(1.0, 1.0, -1.0), d * Vec3::new(1.0, 1.0, -1.0), weight))
    }

    /// The ray in camera space that reaches the film for the ray from the
    /// scene `o + t·d`, or `None`.
    fn trace_from_scene(&self, o: Vec3, d: Vec3) -> Option<(Vec3, Vec3)> {
        let (mut o, mut d) = (o * Vec3::new(1.0, 1.0, -1.0), d * Vec3::new(1.0, 1.0, -1.0));
        let mut z = -self.front_z();
        for (i, e) in self.interfaces.iter().enumerate() {
            let before = if i > 0 {
                air_if_zero(self.interfaces[i - 1].eta)
            } else {
                1.0
            };
            (o, d) = cross_interface(e, z, o, d, before, air_if_zero(e.eta))?;
            z += e.thickness;
        }
        Some((o * Vec3::new(1.0, 1.0, -1.0), d * Vec3::new(1.0, 1.0, -1.0)))
    }

    /// The film distance that focuses the system on the plane at
    /// `focus_distance`, from its thick-lens approximation: the principal
    /// and focal planes found by tracing rays parallel to the axis from
    /// either side (Kolb et al. 1995; pbrt-v4 `FocusThickLens`).
    fn focus_thick_lens(&self, focus_distance: f32) -> Result<f32, String> {
        let x = 0.001 * self.film_diagonal;
        // Where the traced ray crosses the axis (focal plane) and where it
        // meets the incoming ray's line (principal plane), as z.
        let cardinal = |o_in: Vec3, (o, d): (Vec3, Vec3)| {
            let at = |t: f32| o.z + d.z * t;
            (at((o_in.x - o.x) / d.x), at(-o.x / d.x))
        };
        let blocked =
            || "a ray parallel to the axis does not pass through the lens (is its stop very small?)".to_string();
        let from_scene = Vec3::new(x, 0.0, self.front_z() + 1.0);
        let (p_film, f_film) = cardinal(
            from_scene,
            self.trace_from_scene(from_scene, Vec3::NEG_Z).ok_or_else(blocked)?,
        );
        let from_film = Vec3::new(x, 0.0, self.rear_z() - 1.0);
        let (o, d, _) = self.trace_from_film(from_film, Vec3::Z).ok_or_else(blocked)?;
        let (p_scene, _) = cardinal(from_film, (o, d));
        // pbrt-v4's terms: its cardinal points are −z of these.
        let (pz0, fz0, pz1) = (-p_film, -f_film, -p_scene);
        let f = fz0 - pz0;
        let z = -focus_distance;
        let c = (pz1 - z - pz0) * (pz1 - z - 4.0 * f - pz0);
        if c.is_nan() || c <= 0.0 {
            return Err(format!(
                "the lens cannot focus at {focus_distance} m: it is closer than the lens's focal length allows"
            ));
        }
        let delta = (pz1 - z + pz0 - c.sqrt()) / 2.0;
        let distance = self.rear_z() + delta;
        if !(distance > 0.0 && distance.is_finite()) {
            return Err(format!("the lens cannot focus at {focus_distance} m"));
        }
        Ok(distance)
    }

    /// Bounds on the rear element's plane of the points through which
    /// rays from film points (x, 0, 0), x in [x0, x1], leave the system.
    fn bound_exit_pupil(&self, x0: f32, x1: f32) -> Option<(Vec2, Vec2)> {
        let rear = self.interfaces.last().expect("at least one interface").aperture_radius;
        let half = 1.5 * rear;
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for i in 0..PUPIL_SAMPLES {
            let film = Vec3::new(x0 + (x1 - x0) * (i as f32 + 0.5) / PUPIL_SAMPLES as f32, 0.0, 0.0);
            let u = Vec2::new(radical_inverse_2(i as u32), radical_inverse_3(i as u32));
            let p = Vec2::splat(-half) + u * (2.0 * half);
            if p.cmpge(lo).all() && p.cmple(hi).all() {
                continue;
            }
            if self.trace_from_film(film, p.extend(self.rear_z()) - film).is_some() {
                (lo, hi) = (lo.min(p), hi.max(p));
            }
        }
        if !(lo.x <= hi.x && lo.y <= hi.y) {
            return None;
        }
        // The sampling grid's spacing, twice over, as pbrt-v4 widens them.
        let margin = 2.0 * (2.0 * half * std::f32::consts::SQRT_2) / (PUPIL_SAMPLES as f32).sqrt();
        Some((lo - Vec2::splat(margin), hi + Vec2::splat(margin)))
    }

    /// The camera-space ray through film point `s` ((0, 0) the image's
    /// top-left corner, (1, 1) its bottom-right) and lens sample `u`, and
    /// its weight; `None` where the lens blocks it.
    pub fn ray(&self, s: Vec2, u: Vec2) -> Option<(Vec3, Vec3, f32)> {
        // The lens forms an inverted image: the film's right (raster +x)
        // lies at camera −x.
        let p = -self.film_half + s * (2.0 * self.film_half);
        let film = Vec3::new(-p.x, p.y, 0.0);
        let r = film.truncate().length();
        let ring = ((r / (self.film_diagonal / 2.0) * PUPIL_RINGS as f32) as usize).min(PUPIL_RINGS - 1);
        let (lo, hi) = self.exit_pupils[ring]?;
        let q = lo + u * (hi - lo);
        let area = (hi.x - lo.x) * (hi.y - lo.y);
        // The bounds were found along +x: turn them to the point's angle.
        let (sin, cos) = if r > 0.0 { (film.y / r, film.x / r) } else { (0.0, 1.0) };
        let pupil = Vec3::new(cos * q.x - sin * q.y, sin * q.x + cos * q.y, self.rear_z());
        let d = pupil - film;
        let (o, dir, transmitted) = self.trace_from_film(film, d)?;
        let cos_theta = d.normalize().z;
        let weight = transmitted * cos_theta.powi(4) * area / (self.rear_z() * self.rear_z());
        Some((o, dir.normalize(), weight))
    }
}

/// The shape of a realistic camera's aperture stop (pbrt-v4's `aperture`):
/// a grey image over the square the stop's circle fits in, its top row at
/// +y, looked up bilinearly (black outside) where a ray crosses the stop,
/// and scaled so that its mean over the square is π/4, the circle's share:
/// every shape lets through as much light as the round stop of the same
/// diameter would. pbrt-v4 draws the built-in shapes on an image of
/// 256 × 256 with its rows running toward +y, so they appear turned upside
/// down on the stop (the pentagon's tip toward −y), and so they do here.
#[derive(Clone, Debug, PartialEq)]
pub struct ApertureMask {
    width: usize,
    height: usize,
    values: Vec<f32>,
}

impl ApertureMask {
    /// Resolution of the built-in shapes.
    const BUILT_IN: usize = 256;

    /// pbrt-v4's built-in shapes: `gaussian` (exp(−r²) − e⁻¹, zero at the
    /// rim), `square` (half the stop's width), `pentagon` (a regular one,
    /// 0.8 of the radius) and `star` (five points, its inner corners on
    /// the pentagram's circle); `None` for any other name.
    pub fn built_in(name: &str) -> Option<ApertureMask> {
        let n = Self::BUILT_IN;
        // Pixel centres in [−1, 1]², rows along +y.
        let centre = |i: usize| -1.0 + 2.0 * (i as f32 + 0.5) / n as f32;
        let draw = |f: &dyn Fn(Vec2) -> f32| -> Vec<f32> {
            (0..n * n).map(|k| f(Vec2::new(centre(k % n), centre(k / n)))).collect()
        };
        let values = match name {
            "gaussian" => draw(&|p| ((-p.length_squared()).exp() - (-1.0f32).exp()).max(0.0)),
            "square" => draw(&|p| f32::from(p.x.abs() < 0.5 && p.y.abs() < 0.5)),
            "pentagon" => {
                let corners: Vec<Vec2> = (0..5)
                    .map(|k| {
                        let a = std::f32::consts::FRAC_PI_2 - k as f32 * 0.4 * std::f32::consts::PI;
                        0.8 * Vec2::new(a.cos(), a.sin())
                    })
                    .collect();
                draw(&|p| f32::from(inside_polygon(p, &corners)))
            }
            "star" => {
                // The inner corners lie where the pentagram's edges cross:
                // at cos 72° / cos 36° of the outer radius.
                let inner = 72f32.to_radians().cos() / 36f32.to_radians().cos();
                let corners: Vec<Vec2> = (0..10)
                    .map(|k| {
                        let a = k as f32 * std::f32::consts::PI / 5.0;
                        let r = if k % 2 == 1 { 1.0 } else { inner };
                        r * Vec2::new(a.cos(), a.sin())
                    })
                    .collect();
                draw(&|p| f32::from(inside_polygon(p, &corners)))
            }
            _ => return None,
        };
        // Read as an image (top row first), as pbrt-v4 reads it.
        Self::from_image(n, n, values).ok()
    }

    /// A mask from an image's grey values, row by row from the top;
    /// an error where no value is positive.
    pub fn from_image(width: usize, height: usize, values: Vec<f32>) -> Result<ApertureMask, String> {
        assert_eq!(values.len(), width * height, "one value per pixel");
        let values: Vec<f32> = values
            .into_iter()
            .map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 })
            .collect();
        let mean = values.iter().map(|&v| v as f64).sum::<f64>() / values.len().max(1) as f64;
        if mean <= 0.0 {
            return Err("the aperture image is black: it lets no light through".into());
        }
        let scale = (std::f64::consts::FRAC_PI_4 / mean) as f32;
        Ok(ApertureMask {
            width,
            height,
            values: values.into_iter().map(|v| v * scale).collect(),
        })
    }

    /// The mask at point `p` of the stop, in units of its radius
    /// ((±1, ±1) the corners of the square around it).
    pub fn weight(&self, p: Vec2) -> f32 {
        // Continuous pixel coordinates: pixel centres at integers + ½.
        let x = (p.x + 1.0) / 2.0 * self.width as f32 - 0.5;
        let y = (1.0 - p.y) / 2.0 * self.height as f32 - 0.5;
        if !(x > -1.0 && y > -1.0 && x < self.width as f32 && y < self.height as f32) {
            return 0.0;
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |i: f32, j: f32| {
            if i < 0.0 || j < 0.0 || i >= self.width as f32 || j >= self.height as f32 {
                0.0
            } else {
                self.values[j as usize * self.width + i as usize]
            }
        };
        let top = texel(x0, y0) * (1.0 - fx) + texel(x0 + 1.0, y0) * fx;
        let bottom = texel(x0, y0 + 1.0) * (1.0 - fx) + texel(x0 + 1.0, y0 + 1.0) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// Whether `p` lies inside the polygon with `corners` (either winding):
/// its winding number about `p` is not zero.
fn inside_polygon(p: Vec2, corners: &[Vec2]) -> bool {
    let mut winding = 0;
    for (i, &a) in corners.iter().enumerate() {
        let b = corners[(i + 1) % corners.len()];
        // Which side of edge a → b the point lies on.
        let side = (b - a).perp_dot(p - a);
        if a.y <= p.y {
            if b.y > p.y && side > 0.0 {
                winding += 1;
            }
        } else if b.y <= p.y && side < 0.0 {
            winding -= 1;
        }
    }
    winding != 0
}

/// The ray (lens space) `o + t·d` across interface `e`, whose vertex lies
/// at `z`, from the medium of index `eta_from` into that of `eta_to`:
/// from the point where it meets the interface, refracted (the stop only
/// limits it); `None` where the interface's opening blocks it or it is
/// reflected totally.
fn cross_interface(e: &Interface, z: f32, o: Vec3, d: Vec3, eta_from: f32, eta_to: f32) -> Option<(Vec3, Vec3)> {
    let (t, n) = intersect_interface(e.curvature_radius, z, o, d)?;
    let p = o + d * t;
    if p.x * p.x + p.y * p.y > e.aperture_radius * e.aperture_radius {
        return None;
    }
    match n {
        Some(n) => Some((p, refract((-d).normalize(), n, eta_to / eta_from)?)),
        None => Some((p, d)),
    }
}

/// 0 (the stop, which has no glass of its own) read as air.
fn air_if_zero(eta: f32) -> f32 {
    if eta == 0.0 { 1.0 } else { eta }
}

/// The distance along `o + t·d` (lens space) to the interface whose vertex
/// lies at `z` on the axis: a plane for the stop (radius 0), else the
/// sphere of the radius, the nearer or farther hit as the ray's direction
/// and the curvature's sign select (pbrt-v4 `IntersectSphericalElement`),
/// with the sphere's unit normal facing the ray's origin.
fn intersect_interface(radius: f32, z: f32, o: Vec3, d: Vec3) -> Option<(f32, Option<Vec3>)> {
    if radius == 0.0 {
        let t = (z - o.z) / d.z;
        return (t >= 0.0 && t.is_finite()).then_some((t, None));
    }
    let oc = o - Vec3::new(0.0, 0.0, z + radius);
    let a = d.length_squared() as f64;
    let b = 2.0 * d.dot(oc) as f64;
    let c = (oc.length_squared() - radius * radius) as f64;
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 || a == 0.0 {
        return None;
    }
    let q = -0.5 * (b + disc.sqrt().copysign(b));
    let (t0, t1) = (q / a, c / q);
    let (near, far) = (t0.min(t1) as f32, t0.max(t1) as f32);
    let t = if (d.z > 0.0) ^ (radius < 0.0) { near } else { far };
    if t.is_nan() || t < 0.0 {
        return None;
    }
    let n = (oc + d * t).normalize();
    Some((t, Some(if n.dot(-d) < 0.0 { -n } else { n })))
}

/// The direction refracted from unit `wi` (pointing away from the
/// interface, on the side of unit normal `n`) into the medium of relative
/// index `eta` = ηt/ηi; `None` under total internal reflection.
fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = n.dot(wi);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-wi / eta + (cos_i / eta - cos_t) * n)
}

/// The base-2 radical inverse of `i` (van der Corput).
fn radical_inverse_2(i: u32) -> f32 {
    (i.reverse_bits() as f64 / 4_294_967_296.0) as f32
}

/// The base-3 radical inverse of `i`.
fn radical_inverse_3(mut i: u32) -> f32 {
    let (mut inv, mut f) = (0.0f64, 1.0 / 3.0);
    while i > 0 {
        inv += (i % 3) as f64 * f;
        i /= 3;
        f /= 3.0;
    }
    inv as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A single biconvex lens of glass (index 1.5, radii ±100 mm, 10 mm
    /// thick) with a stop just behind it: its thick-lens focal length is
    /// the lensmaker's, so the film distance that focuses at infinity is
    /// about f, and rays from a film point all meet at its conjugate.
    fn biconvex(focus: f32, stop_mm: f32) -> LensSystem {
        let numbers = [
            100.0, 10.0, 1.5, 40.0, //
            -100.0, 1.0, 1.0, 40.0, //
            0.0, 50.0, 0.0, 20.0,
        ];
        LensSystem::new(&numbers, stop_mm, focus, 0.035, (64, 48), None).unwrap()
    }

    #[test]
    fn a_thick_lens_focuses_where_the_lensmaker_says() {
        // 1/f = (n − 1)(1/R1 − 1/R2 + (n − 1)d/(n R1 R2)).
        let (n, r1, r2, d) = (1.5f32, 0.1f32, -0.1f32, 0.01f32);
        let f = 1.0 / ((n - 1.0) * (1.0 / r1 - 1.0 / r2 + (n - 1.0) * d / (n * r1 * r2)));
        // Focused on a plane at distance 2 m from the film: every ray from
        // the film's centre through a small stop (nearly paraxial: a
        // simple lens's spherical aberration moves the crossing of wider
        // rays by the square of their height) reaches the axis there.
        let lens = biconvex(2.0, 2.0);
        let mut crossings = Vec::new();
        for k in 0..64 {
            let u = Vec2::new((k % 8) as f32 / 8.0 + 0.06, (k / 8) as f32 / 8.0 + 0.06);
            if let Some((o, dir, w)) = lens.ray(Vec2::splat(0.5), u) {
                assert!(w > 0.0);
                // Where the ray crosses the axis's plane x = 0 (it lies in
                // a plane through the axis).
                let t = if dir.x.abs() > 1e-6 { -o.x / dir.x } else { continue };
                crossings.push(o.z + dir.z * t);
            }
        }
        assert!(crossings.len() > 20, "{} rays passed", crossings.len());
        // The focus distance is measured from the film.
        for z in &crossings {
            assert!(
                (z - 2.0).abs() < 0.02,
                "a ray meets the axis at {z}, the plane in focus at 2"
            );
        }
        // For a distant focus the film lies f behind the rear principal
        // plane, which is (n − 1)·d·f/(n·R1) inside the lens from its back
        // vertex; the stop is 1 mm behind that vertex.
        let far = biconvex(1e4, 20.0);
        let principal = (n - 1.0) * d * f / (n * r1);
        let film_to_principal = far.rear_z() + 0.001 + principal;
        assert!(
            (film_to_principal - f).abs() < 0.005 * f,
            "film at {film_to_principal} from the principal plane, f = {f}"
        );
    }

    #[test]
    fn the_image_is_inverted_and_bad_descriptions_are_errors() {
        let lens = biconvex(2.0, 20.0);
        // The image's right (raster +x) sees the scene's +x side, its top
        // (raster −y) the scene's +y side.
        let (o, d, _) = lens.ray(Vec2::new(0.8, 0.5), Vec2::splat(0.5)).unwrap();
        let at = o + d * ((lens.front_z() + 2.0 - o.z) / d.z);
        assert!(at.x > 0.0 && at.y.abs() < 1e-3 * at.x.abs().max(1.0), "{at}");
        let (o, d, _) = lens.ray(Vec2::new(0.5, 0.2), Vec2::splat(0.5)).unwrap();
        let at = o + d * ((lens.front_z() + 2.0 - o.z) / d.z);
        assert!(at.y > 0.0, "{at}");
        assert!(LensSystem::new(&[1.0, 2.0, 3.0], 1.0, 1.0, 0.035, (4, 4), None).is_err());
        assert!(
            LensSystem::new(
                &[100.0, 10.0, 1.5, 40.0, -100.0, 1.0, 1.0, 40.0],
                10.0,
                0.01,
                0.035,
                (4, 4),
                None
            )
            .is_err()
        );
    }

    #[test]
    fn built_in_apertures_have_pbrt_v4s_shapes_and_a_round_stops_mean() {
        // The share of the square each covers: the square half the width;
        // the pentagon of circumradius 0.8, (5/2)·0.8²·sin 72°; the star of
        // ten triangles with sides 1 and cos 72°/cos 36° at 36°; the disc
        // where the Gaussian is positive.
        let inner = 72f32.to_radians().cos() / 36f32.to_radians().cos();
        let star = 5.0 * inner * 36f32.to_radians().sin();
        for (name, area) in [
            ("square", 1.0),
            ("pentagon", 2.5 * 0.64 * 72f32.to_radians().sin()),
            ("star", star),
            ("gaussian", std::f32::consts::PI),
        ] {
            let mask = ApertureMask::built_in(name).unwrap();
            let n = mask.values.len() as f32;
            let mean = mask.values.iter().map(|&v| v as f64).sum::<f64>() / n as f64;
            assert!((mean - std::f64::consts::FRAC_PI_4).abs() < 1e-5, "{name}: mean {mean}");
            let covered = mask.values.iter().filter(|&&v| v > 0.0).count() as f32 / n;
            assert!(
                (covered - area / 4.0).abs() < 0.01 * area / 4.0,
                "{name}: covers {covered} of the square, {} expected",
                area / 4.0
            );
            // Nothing outside the stop's square.
            assert_eq!(mask.weight(Vec2::new(1.05, 0.0)), 0.0);
            assert_eq!(mask.weight(Vec2::new(0.0, -1.05)), 0.0);
        }
        // Drawn with rows toward +y and read top row first, as pbrt-v4
        // does: the pentagon's tip, at +y as drawn, points to −y on the
        // stop, its flat side to +y.
        let pentagon = ApertureMask::built_in("pentagon").unwrap();
        assert!(pentagon.weight(Vec2::new(0.0, -0.75)) > 0.0);
        assert_eq!(pentagon.weight(Vec2::new(0.0, 0.7)), 0.0);
        let square = ApertureMask::built_in("square").unwrap();
        assert!((square.weight(Vec2::new(0.3, -0.3)) - std::f32::consts::PI).abs() < 1e-4);
        assert_eq!(square.weight(Vec2::new(0.6, 0.0)), 0.0);
        assert!(ApertureMask::built_in("hexagon").is_none());
        assert!(ApertureMask::from_image(2, 2, vec![0.0; 4]).is_err());
        assert!(ApertureMask::from_image(1, 1, vec![f32::NAN]).is_err());
    }

    #[test]
    fn a_shaped_stop_passes_the_light_of_a_round_one_through_its_shape() {
        // A small stop (2 mm, 51 mm from the film), so cos⁴θ is the same
        // over it: the film's centre measures the same irradiance through
        // every shape, each normalised to the round stop's area.
        let numbers = [
            100.0, 10.0, 1.5, 40.0, //
            -100.0, 1.0, 1.0, 40.0, //
            0.0, 50.0, 0.0, 20.0,
        ];
        let irradiance = |mask: Option<ApertureMask>| {
            let lens = LensSystem::new(&numbers, 2.0, 2.0, 0.035, (64, 48), mask).unwrap();
            let k = 512;
            let mut sum = 0.0f64;
            for i in 0..k * k {
                let u = Vec2::new(((i % k) as f32 + 0.5) / k as f32, ((i / k) as f32 + 0.5) / k as f32);
                if let Some((_, _, w)) = lens.ray(Vec2::splat(0.5), u) {
                    sum += w as f64;
                }
            }
            sum / (k * k) as f64
        };
        let round = irradiance(None);
        assert!(round > 0.0);
        for name in ["square", "pentagon", "star", "gaussian"] {
            let shaped = irradiance(ApertureMask::built_in(name));
            // The grid's error on the shapes' edges, a pixel of 256 wide.
            assert!((shaped / round - 1.0).abs() < 0.01, "{name}: {shaped} against {round}");
        }
        // The square lets rays through only within its half width: the
        // exit pupil at the film's centre (here the stop itself, the last
        // interface) shrinks to it, with the bounds' margin.
        let pupil_reach = |mask: Option<ApertureMask>| {
            let lens = LensSystem::new(&numbers, 2.0, 2.0, 0.035, (64, 48), mask).unwrap();
            let (lo, hi) = lens.exit_pupils[0].unwrap();
            lo.abs().max(hi.abs()).max_element()
        };
        let (round, square) = (pupil_reach(None), pupil_reach(ApertureMask::built_in("square")));
        assert!(round > 0.001 && square < 0.0006, "reach {round} round, {square} square");
    }
}
