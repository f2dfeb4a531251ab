//! Signed distance functions sampled on a grid (Mitsuba 3's `sdfgrid`
//! shape): values at the corners of the cells of a regular grid over the
//! unit cube, interpolated trilinearly; the surface is where the
//! interpolant is zero.
//!
//! A ray walks the cells it crosses (Amanatides and Woo 1987, "A Fast
//! Voxel Traversal Algorithm for Ray Tracing"). In a cell where the values
//! change sign the interpolant along the ray is a cubic in the distance,
//! whose first root is found exactly: the cubic's critical points cut the
//! cell's stretch of the ray into pieces on which it is monotonic, and the
//! first piece whose ends differ in sign is bisected (Marmitt et al. 2004,
//! "Fast and Accurate Ray-Voxel Intersection Techniques for Iso-Surface
//! Ray Tracing"; Hansson-Söderlund et al. 2022, "Ray Tracing of Signed
//! Distance Function Grids", JCGT 11(3), whose voxel test Mitsuba uses).
//!
//! The geometric normal is the gradient of the interpolant; the shading
//! normal is either the same (`analytic`) or, by default, the gradients of
//! the eight cells around the nearest grid vertex blended trilinearly
//! (`smooth`, Hansson-Söderlund et al. 2022, section 5), continuous across
//! cells, as Mitsuba computes them.

use glam::{DVec3, Vec2, Vec3};

use super::ray::Ray;
use super::roots::{bisect, quadratic_roots};
use super::shape::LocalSurface;
use crate::sampling::warp::orthonormal_basis;

/// The most values a grid may hold (a 1024³ grid).
pub const MAX_SDF_VALUES: usize = 1 << 30;

/// A grid of signed distances over [0, 1]³ in object space.
#[derive(Clone, Debug, PartialEq)]
pub struct SdfGrid {
    /// Values along x, y and z (at least 2 each).
    res: [usize; 3],
    /// The values, x fastest, then y, then z.
    values: Vec<f32>,
    /// One bit per cell (x fastest): whether its corners' values are not
    /// all of one sign, so that the surface may cross it.
    occupied: Vec<u64>,
    /// The lowest and one past the highest occupied cell on each axis.
    cells_lo: [usize; 3],
    cells_hi: [usize; 3],
    /// Whether shading normals are blended across cells.
    smooth: bool,
}

impl SdfGrid {
    /// The grid of `res` values (x fastest); `smooth` blends shading
    /// normals across cells. An error names what is wrong: a size below 2,
    /// a count that does not match, a NaN or infinite value, or no cell
    /// that the surface crosses (which Mitsuba rejects too).
    pub fn new(res: [usize; 3], values: Vec<f32>, smooth: bool) -> Result<SdfGrid, String> {
        if res.iter().any(|&n| n < 2) {
            return Err(format!(
                "a {}×{}×{} grid has no cells (a signed distance grid needs at least 2 values along each axis)",
                res[0], res[1], res[2]
            ));
        }
        let count = res.iter().try_fold(1usize, |a, &n| a.checked_mul(n));
        if count.is_none_or(|c| c > MAX_SDF_VALUES) {
            return Err(format!("the grid holds more than {MAX_SDF_VALUES} values"));
        }
        if count != Some(values.len()) {
            return Err(format!(
                "{} values given for a {}×{}×{} grid",
                values.len(),
                res[0],
                res[1],
                res[2]
            ));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("value {i} of the grid is NaN or infinite"));
        }
        let cells = [res[0] - 1, res[1] - 1, res[2] - 1];
        let mut grid = SdfGrid {
            res,
            values,
            occupied: vec![0; (cells[0] * cells[1] * cells[2]).div_ceil(64)],
            cells_lo: cells,
            cells_hi: [0; 3],
            smooth,
        };
        for z in 0..cells[2] {
            for y in 0..cells[1] {
                for x in 0..cells[0] {
                    let c = grid.corners([x, y, z]);
                    let crossed = !(c.iter().all(|&v| v > 0.0) || c.iter().all(|&v| v < 0.0));
                    if crossed {
                        let i = (z * cells[1] + y) * cells[0] + x;
                        grid.occupied[i / 64] |= 1 << (i % 64);
                        for (axis, k) in [x, y, z].into_iter().enumerate() {
                            grid.cells_lo[axis] = grid.cells_lo[axis].min(k);
                            grid.cells_hi[axis] = grid.cells_hi[axis].max(k + 1);
                        }
                    }
                }
            }
        }
        if grid.cells_hi[0] == 0 {
            return Err("no cell of the grid holds the surface (its values are all of one sign)".into());
        }
        Ok(grid)
    }

    /// Object-space bounds of the cells the surface may cross.
    pub fn bounds(&self) -> super::Aabb {
        let scale = self.cell_size();
        super::Aabb::new(
            Vec3::from(self.cells_lo.map(|c| c as f32)) * scale,
            Vec3::from(self.cells_hi.map(|c| c as f32)) * scale,
        )
    }

    /// A cell's extent along each axis, in object space.
    fn cell_size(&self) -> Vec3 {
        Vec3::new(
            1.0 / (self.res[0] - 1) as f32,
            1.0 / (self.res[1] - 1) as f32,
            1.0 / (self.res[2] - 1) as f32,
        )
    }

    fn value(&self, [x, y, z]: [usize; 3]) -> f64 {
        self.values[(z * self.res[1] + y) * self.res[0] + x] as f64
    }

    /// The values at a cell's corners, corner `i` at offset (i & 1,
    /// (i >> 1) & 1, (i >> 2) & 1).
    fn corners(&self, [x, y, z]: [usize; 3]) -> [f64; 8] {
        std::array::from_fn(|i| self.value([x + (i & 1), y + ((i >> 1) & 1), z + ((i >> 2) & 1)]))
    }

    fn is_occupied(&self, [x, y, z]: [usize; 3]) -> bool {
        let i = (z * (self.res[1] - 1) + y) * (self.res[0] - 1) + x;
        self.occupied[i / 64] >> (i % 64) & 1 == 1
    }

    /// The interpolant at grid coordinates `g` (object coordinates times
    /// cells per axis), clamped to the grid.
    fn interpolate(&self, g: DVec3) -> f64 {
        let mut cell = [0; 3];
        let mut f = [0.0; 3];
        for axis in 0..3 {
            let hi = (self.res[axis] - 1) as f64;
            let x = g[axis].clamp(0.0, hi);
            let c = (x.floor() as usize).min(self.res[axis] - 2);
            cell[axis] = c;
            f[axis] = x - c as f64;
        }
        trilinear(&self.corners(cell), f)
    }

    /// Distance to the first point of the surface within the ray's
    /// interval (strictly after `t_min`), the ray in object space.
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let scale = DVec3::new(
            (self.res[0] - 1) as f64,
            (self.res[1] - 1) as f64,
            (self.res[2] - 1) as f64,
        );
        let o = ray.origin.as_dvec3() * scale;
        let d = ray.dir.as_dvec3() * scale;
        let lo = DVec3::from(self.cells_lo.map(|c| c as f64));
        let hi = DVec3::from(self.cells_hi.map(|c| c as f64));
        // The stretch of the ray inside the occupied cells' box.
        let (mut t0, mut t1) = (ray.t_min as f64, ray.t_max as f64);
        for axis in 0..3 {
            let inv = 1.0 / d[axis];
            let (mut a, mut b) = ((lo[axis] - o[axis]) * inv, (hi[axis] - o[axis]) * inv);
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            // NaN (a direction of 0 with the origin on a face) keeps the
            // interval, as the cell walk below then never moves on that axis.
            if a > t0 {
                t0 = a;
            }
            if b < t1 {
                t1 = b;
            }
        }
        if t0 > t1 {
            return None;
        }
        // Walk the cells from the one at t0.
        let start = o + d * t0;
        let mut cell = [0usize; 3];
        let mut step = [0isize; 3];
        let mut t_next = [f64::INFINITY; 3];
        let mut t_delta = [f64::INFINITY; 3];
        for axis in 0..3 {
            let c = start[axis]
                .floor()
                .clamp(self.cells_lo[axis] as f64, (self.cells_hi[axis] - 1) as f64);
            cell[axis] = c as usize;
            if d[axis] > 0.0 {
                step[axis] = 1;
                t_next[axis] = (c + 1.0 - o[axis]) / d[axis];
                t_delta[axis] = 1.0 / d[axis];
            } else if d[axis] < 0.0 {
                step[axis] = -1;
                t_next[axis] = (c - o[axis]) / d[axis];
                t_delta[axis] = -1.0 / d[axis];
            }
        }
        let mut t_enter = t0;
        loop {
            let axis = if t_next[0] <= t_next[1] && t_next[0] <= t_next[2] {
                0
            } else if t_next[1] <= t_next[2] {
                1
            } else {
                2
            };
            let t_exit = t_next[axis].min(t1);
            if self.is_occupied(cell) {
                if let Some(t) = self.cell_root(cell, o, d, t_enter, t_exit, ray.t_min as f64) {
                    return Some(t as f32);
                }
            }
            if t_next[axis] >= t1 {
                return None;
            }
            let next = cell[axis] as isize + step[axis];
            if next < self.cells_lo[axis] as isize || next >= self.cells_hi[axis] as isize {
                return None;
            }
            cell[axis] = next as usize;
            t_enter = t_next[axis];
            t_next[axis] += t_delta[axis];
        }
    }

    /// The first root in `[ta, tb]`, after `t_min`, of the interpolant of
    /// `cell` along the ray `o + t·d` (grid coordinates).
    fn cell_root(&self, cell: [usize; 3], o: DVec3, d: DVec3, ta: f64, tb: f64, t_min: f64) -> Option<f64> {
        if ta > tb || ta.is_nan() || tb.is_nan() {
            return None;
        }
        // The ray from ta in the cell's own coordinates, [0, 1]³.
        let base = DVec3::from(cell.map(|c| c as f64));
        let p = o + d * ta - base;
        let poly = along_ray(&self.corners(cell), p, d);
        let len = tb - ta;
        let eval = |s: f64| ((poly[3] * s + poly[2]) * s + poly[1]) * s + poly[0];
        // Ends of the monotonic pieces: 0, the critical points inside, len.
        let mut cuts = [0.0, len, len, len];
        let mut n = 1;
        for r in quadratic_roots(3.0 * poly[3], 2.0 * poly[2], poly[1])
            .into_iter()
            .flatten()
        {
            if r > 0.0 && r < len {
                cuts[n] = r;
                n += 1;
            }
        }
        cuts[1..n].sort_by(f64::total_cmp);
        cuts[n] = len;
        let mut a = 0.0;
        let mut fa = eval(a);
        for &b in &cuts[1..=n] {
            let fb = eval(b);
            if fa == 0.0 && ta + a > t_min {
                return Some(ta + a);
            }
            if fa * fb < 0.0 || (fb == 0.0 && fa != 0.0) {
                let t = ta + bisect(&eval, a, b, fa);
                if t > t_min {
                    return Some(t);
                }
            }
            a = b;
            fa = fb;
        }
        None
    }

    /// The surface at a point found by [`SdfGrid::intersect`] (object
    /// space): the interpolant's gradient as the normal, no surface
    /// coordinates (as in Mitsuba).
    pub fn surface(&self, p: Vec3) -> LocalSurface {
        let n = self.gradient(p).try_normalize().unwrap_or(Vec3::Z);
        let (dpdu, dpdv) = orthonormal_basis(n);
        // The root is exact to far below a cell; what remains is the
        // rounding of the distance and of the point in single precision.
        let p_error = Vec3::splat(1e-5) * self.cell_size() + p.abs() * (8.0 * f32::EPSILON);
        LocalSurface {
            p,
            p_error,
            n,
            uv: Vec2::ZERO,
            dpdu,
            dpdv,
        }
    }

    /// The shading normal at `p` (object space, unit length, or `None`
    /// where it is the geometric normal).
    pub fn shading_normal(&self, p: Vec3) -> Option<Vec3> {
        if !self.smooth {
            return None;
        }
        let scale = DVec3::new(
            (self.res[0] - 1) as f64,
            (self.res[1] - 1) as f64,
            (self.res[2] - 1) as f64,
        );
        let g = p.as_dvec3() * scale;
        // The eight cells around the grid vertex nearest to p, the first
        // at (nearest − 1); cells off the grid's low side take no part.
        let first = g.round() - DVec3::ONE;
        let mut valid = [false; 8];
        let mut normals = [DVec3::ZERO; 8];
        for (i, (v, n)) in valid.iter_mut().zip(&mut normals).enumerate() {
            let c = first + DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64);
            *v = c.min_element() >= 0.0;
            if *v {
                *n = self.cell_gradient(g, c).normalize_or_zero();
            }
        }
        let mut w = g - (first + DVec3::ONE) + DVec3::splat(0.5);
        // An axis whose low (or high) four cells are all off the grid
        // takes the other four alone.
        for axis in 0..3 {
            let bit = 1 << axis;
            let low_invalid = (0..8).filter(|i| i & bit == 0).all(|i| !valid[i]);
            let high_invalid = (0..8).filter(|i| i & bit != 0).all(|i| !valid[i]);
            if low_invalid {
                w[axis] = 1.0;
            }
            if high_invalid {
                w[axis] = 0.0;
            }
        }
        let mut n = DVec3::ZERO;
        for (i, cell_n) in normals.iter().enumerate() {
            let f = |axis: usize| if i >> axis & 1 == 1 { w[axis] } else { 1.0 - w[axis] };
            n += *cell_n * (f(0) * f(1) * f(2));
        }
        n.as_vec3().try_normalize()
    }

    /// The gradient of the interpolant at `p` (object space), in the cell
    /// that holds p.
    fn gradient(&self, p: Vec3) -> Vec3 {
        let scale = DVec3::new(
            (self.res[0] - 1) as f64,
            (self.res[1] - 1) as f64,
            (self.res[2] - 1) as f64,
        );
        let g = p.as_dvec3() * scale;
        let cell = DVec3::new(
            g.x.floor().clamp(0.0, scale.x - 1.0),
            g.y.floor().clamp(0.0, scale.y - 1.0),
            g.z.floor().clamp(0.0, scale.z - 1.0),
        );
        self.cell_gradient(g, cell).as_vec3()
    }

    /// The gradient at grid point `g` (object units) of cell `c`'s
    /// interpolant: along each axis the difference of the grid's
    /// interpolant at the cell's two faces, the other two coordinates
    /// those of g (Mitsuba's `voxel_grad`). The trilinear interpolant is
    /// linear along each axis, so inside the cell this is its exact
    /// gradient.
    fn cell_gradient(&self, g: DVec3, c: DVec3) -> DVec3 {
        let mut grad = DVec3::ZERO;
        for axis in 0..3 {
            let (mut lo, mut hi) = (g, g);
            lo[axis] = c[axis];
            hi[axis] = c[axis] + 1.0;
            // Per object unit: the cell spans 1/(res − 1).
            grad[axis] = (self.interpolate(hi) - self.interpolate(lo)) * (self.res[axis] - 1) as f64;
        }
        grad
    }
}

/// Trilinear interpolation of a cell's corner values at fractions `f`.
fn trilinear(c: &[f64; 8], f: [f64; 3]) -> f64 {
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let x00 = lerp(c[0], c[1], f[0]);
    let x10 = lerp(c[2], c[3], f[0]);
    let x01 = lerp(c[4], c[5], f[0]);
    let x11 = lerp(c[6], c[7], f[0]);
    lerp(lerp(x00, x10, f[1]), lerp(x01, x11, f[1]), f[2])
}

/// The cell's interpolant along `p + s·d` as the coefficients of a cubic in
/// s (lowest first): the interpolant written as
/// k0 + k1·x + k2·y + k3·z + k4·xy + k5·xz + k6·yz + k7·xyz, each
/// coordinate a line in s.
fn along_ray(c: &[f64; 8], p: DVec3, d: DVec3) -> [f64; 4] {
    let k = [
        c[0],
        c[1] - c[0],
        c[2] - c[0],
        c[4] - c[0],
        c[3] - c[2] - c[1] + c[0],
        c[5] - c[4] - c[1] + c[0],
        c[6] - c[4] - c[2] + c[0],
        c[7] - c[6] - c[5] - c[3] + c[4] + c[2] + c[1] - c[0],
    ];
    let mul = |a: &[f64], b: [f64; 2]| -> [f64; 4] {
        let mut r = [0.0; 4];
        for (i, &ai) in a.iter().enumerate() {
            r[i] += ai * b[0];
            if i + 1 < 4 {
                r[i + 1] += ai * b[1];
            }
        }
        r
    };
    let (x, y, z) = ([p.x, d.x], [p.y, d.y], [p.z, d.z]);
    let xy = mul(&x, y);
    let xz = mul(&x, z);
    let yz = mul(&y, z);
    let xyz = mul(&xy[..3], z);
    let mut out = [k[0], 0.0, 0.0, 0.0];
    for (coef, poly) in [
        (k[1], [x[0], x[1], 0.0, 0.0]),
        (k[2], [y[0], y[1], 0.0, 0.0]),
        (k[3], [z[0], z[1], 0.0, 0.0]),
    ]
    .into_iter()
    .chain([(k[4], xy), (k[5], xz), (k[6], yz), (k[7], xyz)])
    {
        for i in 0..4 {
            out[i] += coef * poly[i];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sphere of radius r about the cube's centre, sampled on n³ values.
    fn sphere_grid(n: usize, r: f32, smooth: bool) -> SdfGrid {
        let mut values = Vec::with_capacity(n * n * n);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let p = Vec3::new(x as f32, y as f32, z as f32) / (n - 1) as f32;
                    values.push((p - Vec3::splat(0.5)).length() - r);
                }
            }
        }
        SdfGrid::new([n, n, n], values, smooth).unwrap()
    }

    #[test]
    fn the_cubic_along_a_ray_is_the_interpolant() {
        let c = [0.3, -0.2, 0.7, 0.1, -0.5, 0.9, 0.4, -0.8];
        let (p, d) = (DVec3::new(0.1, 0.2, 0.3), DVec3::new(0.5, -0.1, 0.4));
        let poly = along_ray(&c, p, d);
        for s in [0.0, 0.3, 0.7, 1.2] {
            let q = p + d * s;
            let direct = trilinear(&c, [q.x, q.y, q.z]);
            let cubic = ((poly[3] * s + poly[2]) * s + poly[1]) * s + poly[0];
            assert!((direct - cubic).abs() < 1e-12, "{direct} {cubic}");
        }
    }

    #[test]
    fn rays_meet_a_sampled_sphere_where_it_is() {
        let g = sphere_grid(33, 0.3, true);
        // Straight at the centre along each axis, from outside.
        for axis in 0..3 {
            let mut o = Vec3::splat(0.5);
            o[axis] = -1.0;
            let mut d = Vec3::ZERO;
            d[axis] = 1.0;
            let t = g.intersect(&Ray::new(o, d)).unwrap();
            // Sampling a sphere's distance on a grid moves its surface by
            // less than a cell's curvature error.
            assert!((t - 1.2).abs() < 2e-3, "axis {axis}: {t}");
            let s = g.surface(o + d * t);
            assert!(s.n.dot(-d) > 0.99, "{}", s.n);
            assert!(g.shading_normal(s.p).unwrap().dot(-d) > 0.999);
        }
        // Oblique rays: the hit lies on the sphere, the normal points out.
        for k in 0..50 {
            let a = k as f32 * 0.7;
            let o = Vec3::new(0.5 + 2.0 * a.cos(), 0.5 + 0.3 * (a * 1.3).sin(), 0.5 + 2.0 * a.sin());
            let target = Vec3::splat(0.5) + 0.15 * Vec3::new((a * 2.1).sin(), (a * 0.9).cos(), (a * 1.7).sin());
            let d = (target - o).normalize();
            let t = g
                .intersect(&Ray::new(o, d))
                .unwrap_or_else(|| panic!("ray {k} aimed inside the sphere: {o} {d}"));
            let p = o + d * t;
            assert!(((p - Vec3::splat(0.5)).length() - 0.3).abs() < 2e-3);
            let n = g.surface(p).n;
            assert!(n.dot((p - Vec3::splat(0.5)).normalize()) > 0.99);
            // A ray leaving the surface along the normal meets nothing.
            let s = g.surface(p);
            let away = Ray::new(p + s.n * s.p_error.length(), s.n);
            assert_eq!(g.intersect(&away), None, "ray {k} found its own surface");
        }
        // Misses: beside the sphere, and pointing away.
        assert_eq!(g.intersect(&Ray::new(Vec3::new(-1.0, 0.95, 0.5), Vec3::X)), None);
        assert_eq!(g.intersect(&Ray::new(Vec3::new(-1.0, 0.5, 0.5), -Vec3::X)), None);
        // From inside, the far side.
        let t = g.intersect(&Ray::new(Vec3::splat(0.5), Vec3::Y)).unwrap();
        assert!((t - 0.3).abs() < 2e-3);
    }

    #[test]
    fn smooth_normals_are_continuous_across_cells_and_analytic_ones_are_not() {
        let smooth = sphere_grid(9, 0.3, true);
        let analytic = sphere_grid(9, 0.3, false);
        assert_eq!(analytic.shading_normal(Vec3::splat(0.5)), None);
        // Walk along a ray that crosses cell faces, comparing normals at
        // neighbouring hits: the blended normals change little between
        // them, the cells' own gradients jump at faces.
        let mut max_smooth = 0.0f32;
        let mut max_analytic = 0.0f32;
        let mut prev: Option<(Vec3, Vec3)> = None;
        for k in 0..400 {
            let y = 0.35 + 0.3 * k as f32 / 400.0;
            let o = Vec3::new(-1.0, y, 0.52);
            let Some(t) = smooth.intersect(&Ray::new(o, Vec3::X)) else {
                continue;
            };
            let p = o + Vec3::X * t;
            let ns = smooth.shading_normal(p).unwrap();
            let na = analytic.surface(p).n;
            if let Some((ps, pa)) = prev {
                max_smooth = max_smooth.max((ns - ps).length());
                max_analytic = max_analytic.max((na - pa).length());
            }
            prev = Some((ns, na));
        }
        assert!(
            max_smooth < 0.5 * max_analytic,
            "smooth {max_smooth}, analytic {max_analytic}"
        );
    }

    #[test]
    fn bad_grids_are_errors() {
        assert!(
            SdfGrid::new([1, 2, 2], vec![0.0; 4], true)
                .unwrap_err()
                .contains("no cells")
        );
        assert!(
            SdfGrid::new([2, 2, 2], vec![0.0; 7], true)
                .unwrap_err()
                .contains("7 values")
        );
        let mut v = vec![1.0; 8];
        assert!(
            SdfGrid::new([2, 2, 2], v.clone(), true)
                .unwrap_err()
                .contains("all of one sign")
        );
        v[3] = f32::NAN;
        assert!(SdfGrid::new([2, 2, 2], v, true).unwrap_err().contains("NaN"));
        assert!(
            SdfGrid::new([1 << 11, 1 << 11, 1 << 11], vec![], true)
                .unwrap_err()
                .contains("more than")
        );
    }
}
