//! Measured BRDFs in the RGL format (Dupuy and Jakob 2018, "An Adaptive
//! Parameterization for Efficient Material Acquisition and Rendering"), as
//! pbrt-v4's `measured` material and Mitsuba 3's `measured` BSDF read them.
//!
//! A `.bsdf` file is a tensor file of named arrays. The BRDF is factored as
//!
//! ```text
//! f(ωo, ωi) = S(u; ωo) · D(ωm) / (4 σ(ωo) cos θi)
//! ```
//!
//! with ωm the half vector, D the normal distribution (`ndf`), σ the
//! projected area of the microsurface (`sigma`), and S the measured
//! remainder (`spectra`, Fresnel and shadowing) tabulated not over
//! directions but over the unit square u that the warp of the visible
//! normals (`vndf`) maps onto ωm. Importance sampling runs the two warps
//! backwards: `luminance` (S's luminance) then `vndf`. Every table is a
//! piecewise-bilinear function of the unit square, interpolated linearly in
//! the outgoing direction's φ and θ ([`PiecewiseLinear2D`], the same
//! scheme as the authors' and pbrt-v4's). Angles map to the square by
//! u = √(2θ/π) and v = φ/2π + ½.
//!
//! trazo renders in RGB: each tabulated spectrum becomes linear sRGB as a
//! reflectance under D65 (see [`crate::color::spectrum`]) when the file is
//! read, where pbrt-v4 evaluates it at the path's wavelengths.

use super::bsdf::{BsdfSample, TransportMode};
use crate::color::Rgb;
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::f32::consts::PI;

/// Largest measured BSDF file read, in bytes.
pub const MAX_MEASURED_BYTES: u64 = 1 << 30;

/// The element types a tensor file names (Mitsuba's `Struct::Type` order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum DType {
    UInt8,
    Float32,
    /// Any other valid type: read past, never used.
    Other(usize),
}

impl DType {
    fn from_code(code: u8) -> Option<DType> {
        Some(match code {
            1 => DType::UInt8,
            10 => DType::Float32,
            2 => DType::Other(1),
            3 | 4 | 9 => DType::Other(2),
            5 | 6 => DType::Other(4),
            7 | 8 | 11 => DType::Other(8),
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            DType::UInt8 => 1,
            DType::Float32 => 4,
            DType::Other(n) => n,
        }
    }
}

/// One named array of a tensor file.
struct Field<'a> {
    dtype: DType,
    shape: Vec<usize>,
    bytes: &'a [u8],
}

impl Field<'_> {
    fn floats(&self) -> Vec<f32> {
        self.bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    }
}

/// Reads the header of a tensor file (Mitsuba's format, version 1.0: the
/// 12 bytes `tensor_file\0`, two version bytes, a u32 field count, then for
/// each field its name, rank, type, offset and shape; little-endian).
fn read_tensor(bytes: &[u8]) -> Result<HashMap<String, Field<'_>>, String> {
    struct Cursor<'a> {
        bytes: &'a [u8],
        at: usize,
    }
    impl<'a> Cursor<'a> {
        fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
            let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
            let end = end.ok_or("the tensor file is truncated in its header")?;
            let s = &self.bytes[self.at..end];
            self.at = end;
            Ok(s)
        }
        fn u16(&mut self) -> Result<u16, String> {
            let b = self.take(2)?;
            Ok(u16::from_le_bytes([b[0], b[1]]))
        }
        fn u32(&mut self) -> Result<u32, String> {
            let b = self.take(4)?;
            Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        }
        fn u64(&mut self) -> Result<u64, String> {
            let b = self.take(8)?;
            Ok(u64::from_le_bytes(b.try_into().expect("8 bytes")))
        }
    }
    let mut c = Cursor { bytes, at: 0 };
    if c.take(12).ok() != Some(b"tensor_file\0".as_slice()) {
        return Err("not a tensor file (it does not start with \"tensor_file\")".into());
    }
    let version = c.take(2)?;
    if version != [1, 0] {
        return Err(format!(
            "tensor file version {}.{} (only 1.0 is known)",
            version[0], version[1]
        ));
    }
    let count = c.u32()?;
    let mut fields = HashMap::new();
    for _ in 0..count {
        let name_len = c.u16()? as usize;
        let name = String::from_utf8_lossy(c.take(name_len)?).into_owned();
        let rank = c.u16()? as usize;
        let dtype = DType::from_code(c.take(1)?[0]).ok_or_else(|| format!("field \"{name}\" has an unknown type"))?;
        let offset = c.u64()?;
        let mut shape = Vec::with_capacity(rank.min(16));
        let mut len = dtype.size() as u64;
        for _ in 0..rank {
            let n = c.u64()?;
            shape.push(n as usize);
            len = len.saturating_mul(n);
        }
        let end = offset.saturating_add(len);
        if end > bytes.len() as u64 {
            return Err(format!("field \"{name}\" lies past the end of the file"));
        }
        let bytes = &bytes[offset as usize..end as usize];
        fields.insert(name, Field { dtype, shape, bytes });
    }
    Ok(fields)
}

/// A piecewise-bilinear density on the unit square, conditioned on up to
/// three parameters between whose tabulated values it is interpolated
/// linearly (Dupuy and Jakob 2018; pbrt-v4's `PiecewiseLinear2D`). Samples
/// are warped by inverting its marginal (rows) and conditional (columns)
/// CDFs, each of which is piecewise quadratic.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseLinear2D {
    /// Columns (x) and rows (y) of the grid.
    size: [usize; 2],
    /// Cells per unit along x and y.
    inv_patch: Vec2,
    /// Tabulated values of each parameter, ascending.
    param_values: Vec<Vec<f32>>,
    /// Offset, in slices, from one value of each parameter to the next (0
    /// for a parameter with one value).
    param_strides: Vec<usize>,
    /// The values, slice after slice, normalised to integrate to 1 where
    /// the CDFs are built.
    data: Vec<f32>,
    marginal_cdf: Vec<f32>,
    conditional_cdf: Vec<f32>,
}

/// Where parameters fall between their tabulated values: the first slice
/// and each parameter's two weights.
struct ParamLookup {
    slice: usize,
    weights: [[f32; 2]; 3],
    dims: usize,
}

/// The index i in 0..n − 1 of the last entry with `below(i)` true, as
/// pbrt-v4's `FindInterval` (entries ascending).
fn find_interval(n: usize, below: impl Fn(usize) -> bool) -> usize {
    let (mut first, mut size) = (1usize, n as isize - 2);
    while size > 0 {
        let half = (size as usize) >> 1;
        let middle = first + half;
        if below(middle) {
            first = middle + 1;
            size -= half as isize + 1;
        } else {
            size = half as isize;
        }
    }
    first.saturating_sub(1).min(n.saturating_sub(2))
}

fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

impl PiecewiseLinear2D {
    /// The function tabulated by `data` (slices of `ys` rows of `xs`
    /// values, the last parameter varying fastest between slices). With
    /// `build_cdf` it is normalised and can be sampled; without, it is
    /// only interpolated, as it stands.
    pub fn new(data: &[f32], xs: usize, ys: usize, params: Vec<Vec<f32>>, build_cdf: bool) -> Result<Self, String> {
        if xs < 2 || ys < 2 {
            return Err(format!("a table of {xs} × {ys} values is too small (2 × 2 at least)"));
        }
        let mut strides = vec![0; params.len()];
        let mut slices = 1usize;
        for (i, p) in params.iter().enumerate().rev() {
            if p.is_empty() {
                return Err("a parameter has no values".into());
            }
            if p.windows(2).any(|w| w[0] >= w[1] || !w[1].is_finite()) || !p[0].is_finite() {
                return Err("a parameter's values are not ascending".into());
            }
            strides[i] = if p.len() > 1 { slices } else { 0 };
            slices = slices.saturating_mul(p.len());
        }
        let n = xs * ys;
        if data.len() as u64 != slices as u64 * n as u64 {
            return Err(format!(
                "{} values where the shape says {}",
                data.len(),
                slices as u64 * n as u64
            ));
        }
        if data.iter().any(|v| !v.is_finite()) {
            return Err("the table holds NaN or infinite values".into());
        }
        let inv_patch = Vec2::new((xs - 1) as f32, (ys - 1) as f32);
        let mut out = PiecewiseLinear2D {
            size: [xs, ys],
            inv_patch,
            param_values: params,
            param_strides: strides,
            data: Vec::with_capacity(data.len()),
            marginal_cdf: Vec::new(),
            conditional_cdf: Vec::new(),
        };
        if !build_cdf {
            // Stored as given: `evaluate` returns the interpolated value.
            let k = 1.0 / (inv_patch.x * inv_patch.y);
            out.data.extend(data.iter().map(|v| v * k));
            return Ok(out);
        }
        out.marginal_cdf = vec![0.0; slices * ys];
        out.conditional_cdf = vec![0.0; slices * n];
        for s in 0..slices {
            let src = &data[s * n..(s + 1) * n];
            let cond = &mut out.conditional_cdf[s * n..(s + 1) * n];
            for y in 0..ys {
                let mut sum = 0.0f64;
                for x in 0..xs - 1 {
                    let i = y * xs + x;
                    sum += 0.5 * (src[i] as f64 + src[i + 1] as f64);
                    cond[i + 1] = sum as f32;
                }
            }
            let marg = &mut out.marginal_cdf[s * ys..(s + 1) * ys];
            let mut sum = 0.0f64;
            for y in 0..ys - 1 {
                sum += 0.5 * (cond[(y + 1) * xs - 1] as f64 + cond[(y + 2) * xs - 1] as f64);
                marg[y + 1] = sum as f32;
            }
            let total = marg[ys - 1];
            // A slice with nothing in it cannot be sampled; it stays zero.
            let k = if total > 0.0 { 1.0 / total } else { 0.0 };
            cond.iter_mut().for_each(|c| *c *= k);
            marg.iter_mut().for_each(|c| *c *= k);
            out.data.extend(src.iter().map(|v| v * k));
        }
        Ok(out)
    }

    fn lookup_params(&self, params: &[f32]) -> ParamLookup {
        debug_assert_eq!(params.len(), self.param_values.len());
        let mut l = ParamLookup {
            slice: 0,
            weights: [[1.0, 0.0]; 3],
            dims: self.param_values.len(),
        };
        for (d, values) in self.param_values.iter().enumerate() {
            if values.len() == 1 {
                continue;
            }
            let p = params[d];
            let i = find_interval(values.len(), |k| values[k] <= p);
            let (p0, p1) = (values[i], values[i + 1]);
            let w1 = ((p - p0) / (p1 - p0)).clamp(0.0, 1.0);
            // NaN (a parameter at NaN) reads the first value.
            let w1 = if w1.is_nan() { 0.0 } else { w1 };
            l.weights[d] = [1.0 - w1, w1];
            l.slice += self.param_strides[d] * i;
        }
        l
    }

    /// The value at `index` of the first slice, interpolated over the
    /// parameters; `size` is the length of one slice.
    #[inline]
    fn lookup(&self, table: &[f32], index: usize, size: usize, l: &ParamLookup) -> f32 {
        let mut sum = 0.0;
        for corner in 0..1usize << l.dims {
            let mut w = 1.0;
            let mut i = index;
            for d in 0..l.dims {
                let bit = (corner >> d) & 1;
                w *= l.weights[d][bit];
                i += bit * self.param_strides[d] * size;
            }
            if w != 0.0 {
                sum += w * table[i];
            }
        }
        sum
    }

    fn cells(&self) -> f32 {
        self.inv_patch.x * self.inv_patch.y
    }

    /// The function at `pos` in the unit square.
    pub fn evaluate(&self, pos: Vec2, params: &[f32]) -> f32 {
        let l = self.lookup_params(params);
        let [xs, ys] = self.size;
        let p = (pos * self.inv_patch).max(Vec2::ZERO);
        let (ox, oy) = ((p.x as usize).min(xs - 2), (p.y as usize).min(ys - 2));
        let w1 = p - Vec2::new(ox as f32, oy as f32);
        let w0 = Vec2::ONE - w1;
        let size = xs * ys;
        let index = ox + oy * xs + l.slice * size;
        let v00 = self.lookup(&self.data, index, size, &l);
        let v10 = self.lookup(&self.data, index + 1, size, &l);
        let v01 = self.lookup(&self.data, index + xs, size, &l);
        let v11 = self.lookup(&self.data, index + xs + 1, size, &l);
        (w0.y * (w0.x * v00 + w1.x * v10) + w1.y * (w0.x * v01 + w1.x * v11)) * self.cells()
    }

    /// Warps a uniform sample to the density; returns the point and its
    /// density.
    pub fn sample(&self, u: Vec2, params: &[f32]) -> (Vec2, f32) {
        let l = self.lookup_params(params);
        let [xs, ys] = self.size;
        let one_minus = crate::sampling::rng::ONE_MINUS_EPSILON;
        let mut s = u.clamp(Vec2::splat(1.0 - one_minus), Vec2::splat(one_minus));
        let marginal = |i: usize| self.lookup(&self.marginal_cdf, l.slice * ys + i, ys, &l);
        let row = find_interval(ys, |i| marginal(i) < s.y);
        s.y -= marginal(row);
        let size = xs * ys;
        let mut offset = row * xs + l.slice * size;
        let r0 = self.lookup(&self.conditional_cdf, offset + xs - 1, size, &l);
        let r1 = self.lookup(&self.conditional_cdf, offset + 2 * xs - 1, size, &l);
        // The row's density is linear in y: invert its quadratic CDF.
        let constant = (r0 - r1).abs() < 1e-4 * (r0 + r1);
        s.y = if constant {
            2.0 * s.y / (r0 + r1)
        } else {
            (r0 - safe_sqrt(r0 * r0 - 2.0 * s.y * (r0 - r1))) / (r0 - r1)
        };
        s.x *= (1.0 - s.y) * r0 + s.y * r1;
        let conditional = |i: usize| {
            let v0 = self.lookup(&self.conditional_cdf, offset + i, size, &l);
            let v1 = self.lookup(&self.conditional_cdf, offset + xs + i, size, &l);
            (1.0 - s.y) * v0 + s.y * v1
        };
        let col = find_interval(xs, |i| conditional(i) < s.x);
        s.x -= conditional(col);
        offset += col;
        let v00 = self.lookup(&self.data, offset, size, &l);
        let v10 = self.lookup(&self.data, offset + 1, size, &l);
        let v01 = self.lookup(&self.data, offset + xs, size, &l);
        let v11 = self.lookup(&self.data, offset + xs + 1, size, &l);
        let c0 = (1.0 - s.y) * v00 + s.y * v01;
        let c1 = (1.0 - s.y) * v10 + s.y * v11;
        let constant = (c0 - c1).abs() < 1e-4 * (c0 + c1);
        s.x = if constant {
            2.0 * s.x / (c0 + c1)
        } else {
            (c0 - safe_sqrt(c0 * c0 - 2.0 * s.x * (c0 - c1))) / (c0 - c1)
        };
        let pdf = ((1.0 - s.x) * c0 + s.x * c1) * self.cells();
        (
            Vec2::new(
                (col as f32 + s.x) / self.inv_patch.x,
                (row as f32 + s.y) / self.inv_patch.y,
            ),
            pdf,
        )
    }

    /// The inverse of [`PiecewiseLinear2D::sample`]: the uniform sample
    /// that lands on `p`, and the density there.
    pub fn invert(&self, p: Vec2, params: &[f32]) -> (Vec2, f32) {
        let l = self.lookup_params(params);
        let [xs, ys] = self.size;
        let mut s = (p * self.inv_patch).max(Vec2::ZERO);
        let (px, py) = ((s.x as usize).min(xs - 2), (s.y as usize).min(ys - 2));
        s -= Vec2::new(px as f32, py as f32);
        let size = xs * ys;
        let offset = px + py * xs + l.slice * size;
        let v00 = self.lookup(&self.data, offset, size, &l);
        let v10 = self.lookup(&self.data, offset + 1, size, &l);
        let v01 = self.lookup(&self.data, offset + xs, size, &l);
        let v11 = self.lookup(&self.data, offset + xs + 1, size, &l);
        let (w1, w0) = (s, Vec2::ONE - s);
        let c0 = w0.y * v00 + w1.y * v01;
        let c1 = w0.y * v10 + w1.y * v11;
        let pdf = w0.x * c0 + w1.x * c1;
        s.x *= c0 + 0.5 * s.x * (c1 - c0);
        let v0 = self.lookup(&self.conditional_cdf, offset, size, &l);
        let v1 = self.lookup(&self.conditional_cdf, offset + xs, size, &l);
        s.x += (1.0 - s.y) * v0 + s.y * v1;
        let row = py * xs + l.slice * size;
        let r0 = self.lookup(&self.conditional_cdf, row + xs - 1, size, &l);
        let r1 = self.lookup(&self.conditional_cdf, row + 2 * xs - 1, size, &l);
        s.x /= (1.0 - s.y) * r0 + s.y * r1;
        s.y *= r0 + 0.5 * s.y * (r1 - r0);
        s.y += self.lookup(&self.marginal_cdf, py + l.slice * ys, ys, &l);
        (s, pdf * self.cells())
    }
}

/// A measured BRDF read from an RGL `.bsdf` file.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasuredBrdf {
    /// Whether the table depends on φo (false: only on φm − φo).
    isotropic: bool,
    ndf: PiecewiseLinear2D,
    sigma: PiecewiseLinear2D,
    vndf: PiecewiseLinear2D,
    luminance: PiecewiseLinear2D,
    /// The remainder S, as linear sRGB.
    rgb: [PiecewiseLinear2D; 3],
    /// Directional albedo at normal incidence, for the denoiser's albedo.
    normal_albedo: Rgb,
}

fn theta_to_u(theta: f32) -> f32 {
    (theta * (2.0 / PI)).sqrt()
}
fn phi_to_u(phi: f32) -> f32 {
    phi * (0.5 / PI) + 0.5
}
fn u_to_theta(u: f32) -> f32 {
    u * u * (PI / 2.0)
}
fn u_to_phi(u: f32) -> f32 {
    (2.0 * u - 1.0) * PI
}

/// θ and φ of a unit direction.
fn spherical(w: Vec3) -> (f32, f32) {
    (w.z.clamp(-1.0, 1.0).acos(), w.y.atan2(w.x))
}

impl MeasuredBrdf {
    /// Reads the BRDF from a `.bsdf` file (gzip-compressed where its name
    /// ends in `.gz`).
    pub fn load(path: &std::path::Path) -> Result<MeasuredBrdf, String> {
        let bytes = crate::files::read_limited_gz(path, MAX_MEASURED_BYTES)?;
        Self::from_bytes(&bytes)
    }

    /// Reads the BRDF from the bytes of a `.bsdf` file. Errors say what is
    /// wrong with the file.
    pub fn from_bytes(bytes: &[u8]) -> Result<MeasuredBrdf, String> {
        let fields = read_tensor(bytes)?;
        let field = |name: &str, dtype: DType, rank: usize| -> Result<&Field<'_>, String> {
            let f = fields
                .get(name)
                .ok_or_else(|| format!("the file has no \"{name}\" field (is it an RGL measured BRDF?)"))?;
            if f.dtype != dtype || f.shape.len() != rank {
                return Err(format!(
                    "field \"{name}\" should be a {rank}-dimensional {} array",
                    if dtype == DType::UInt8 { "byte" } else { "float32" }
                ));
            }
            Ok(f)
        };
        let theta_i = field("theta_i", DType::Float32, 1)?;
        let phi_i = field("phi_i", DType::Float32, 1)?;
        let ndf = field("ndf", DType::Float32, 2)?;
        let sigma = field("sigma", DType::Float32, 2)?;
        let vndf = field("vndf", DType::Float32, 4)?;
        let luminance = field("luminance", DType::Float32, 4)?;
        let spectra = field("spectra", DType::Float32, 5)?;
        let wavelengths = field("wavelengths", DType::Float32, 1)?;
        let (n_phi, n_theta) = (phi_i.shape[0], theta_i.shape[0]);
        let (ls, ss) = (&luminance.shape, &spectra.shape);
        if vndf.shape[0] != n_phi
            || vndf.shape[1] != n_theta
            || ls[0] != n_phi
            || ls[1] != n_theta
            || ss[0] != n_phi
            || ss[1] != n_theta
            || ss[2] != wavelengths.shape[0]
            || ls[2] != ss[3]
            || ls[3] != ss[4]
        {
            return Err("the shapes of its fields disagree (phi_i, theta_i, vndf, luminance, spectra)".into());
        }
        if wavelengths.shape[0] < 2 {
            return Err("field \"wavelengths\" has fewer than two wavelengths".into());
        }
        let phis = phi_i.floats();
        let thetas = theta_i.floats();
        let isotropic = n_phi <= 2;
        if !isotropic {
            let span = phis[n_phi - 1] - phis[0];
            if (2.0 * PI / span).round() != 1.0 {
                return Err("the table covers a fraction of the φ range (a symmetry reduction), which pbrt-v4 does not read either".into());
            }
        }
        let params = vec![phis.clone(), thetas.clone()];
        let named = |name: &str, r: Result<PiecewiseLinear2D, String>| r.map_err(|e| format!("field \"{name}\": {e}"));
        let ndf_t = named(
            "ndf",
            PiecewiseLinear2D::new(&ndf.floats(), ndf.shape[1], ndf.shape[0], vec![], false),
        )?;
        let sigma_t = named(
            "sigma",
            PiecewiseLinear2D::new(&sigma.floats(), sigma.shape[1], sigma.shape[0], vec![], false),
        )?;
        let vndf_t = named(
            "vndf",
            PiecewiseLinear2D::new(&vndf.floats(), vndf.shape[3], vndf.shape[2], params.clone(), true),
        )?;
        let luminance_t = named(
            "luminance",
            PiecewiseLinear2D::new(&luminance.floats(), ls[3], ls[2], params.clone(), true),
        )?;
        // Spectra to RGB: the conversion is linear in the samples, so each
        // wavelength's share of R, G and B is found once.
        let lambdas = wavelengths.floats();
        if lambdas.windows(2).any(|w| w[0] >= w[1]) || lambdas.iter().any(|l| !l.is_finite()) {
            return Err("field \"wavelengths\" is not ascending".into());
        }
        let weights = crate::color::spectrum::sample_weights(&lambdas, crate::color::spectrum::SpectrumUse::Unbounded);
        let values = spectra.floats();
        let cell = ss[3] * ss[4];
        let n_lambda = lambdas.len();
        let mut channels = [Vec::with_capacity(n_phi * n_theta * cell), Vec::new(), Vec::new()];
        for slice in 0..n_phi * n_theta {
            let block = &values[slice * n_lambda * cell..(slice + 1) * n_lambda * cell];
            for k in 0..cell {
                let mut rgb = Rgb::ZERO;
                for (j, w) in weights.iter().enumerate() {
                    rgb += *w * block[j * cell + k];
                }
                channels[0].push(rgb.x.max(0.0));
                channels[1].push(rgb.y.max(0.0));
                channels[2].push(rgb.z.max(0.0));
            }
        }
        let [r, g, b] = channels.map(|c| PiecewiseLinear2D::new(&c, ss[4], ss[3], params.clone(), false));
        let mut brdf = MeasuredBrdf {
            isotropic,
            ndf: ndf_t,
            sigma: sigma_t,
            vndf: vndf_t,
            luminance: luminance_t,
            rgb: [named("spectra", r)?, named("spectra", g)?, named("spectra", b)?],
            normal_albedo: Rgb::ZERO,
        };
        brdf.normal_albedo = brdf.directional_albedo(Vec3::Z, 32);
        Ok(brdf)
    }

    /// ∫ f cos θi dωi for `wo`, by its own sampling on an n × n grid.
    pub fn directional_albedo(&self, wo: Vec3, n: usize) -> Rgb {
        let bsdf = MeasuredBsdf { brdf: self };
        let mut sum = Rgb::ZERO;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                if let Some(s) = bsdf.sample(wo, 0.5, u, TransportMode::Radiance).filter(|s| s.pdf > 0.0) {
                    sum += s.weight();
                }
            }
        }
        sum / (n * n) as f32
    }
}

/// A measured BRDF at a surface point. Two-sided: below the surface, both
/// directions are mirrored through the origin, as pbrt-v4 does.
#[derive(Clone, Copy, Debug)]
pub struct MeasuredBsdf<'a> {
    /// The tables.
    pub brdf: &'a MeasuredBrdf,
}

impl MeasuredBsdf<'_> {
    /// The half vector's place in the unit square of the tables, for the
    /// outgoing direction at (θo, φo).
    fn half_vector_uv(&self, wm: Vec3, phi_o: f32) -> Vec2 {
        let (theta_m, phi_m) = spherical(wm);
        let phi = if self.brdf.isotropic { phi_m - phi_o } else { phi_m };
        let v = phi_to_u(phi);
        Vec2::new(theta_to_u(theta_m), v - v.floor())
    }

    /// S(u) in RGB.
    fn remainder(&self, u: Vec2, params: &[f32]) -> Rgb {
        let [r, g, b] = &self.brdf.rgb;
        Rgb::new(
            r.evaluate(u, params).max(0.0),
            g.evaluate(u, params).max(0.0),
            b.evaluate(u, params).max(0.0),
        )
    }

    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        if wo.z * wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
        let wm = wo + wi;
        if wm.length_squared() == 0.0 {
            return Rgb::ZERO;
        }
        let wm = wm.normalize();
        let (theta_o, phi_o) = spherical(wo);
        let params = [phi_o, theta_o];
        let u_wm = self.half_vector_uv(wm, phi_o);
        let (ui, _) = self.brdf.vndf.invert(u_wm, &params);
        let u_wo = Vec2::new(theta_to_u(theta_o), phi_to_u(phi_o));
        self.remainder(ui, &params) * self.brdf.ndf.evaluate(u_wm, &[])
            / (4.0 * self.brdf.sigma.evaluate(u_wo, &[]) * wi.z)
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
        let wm = wo + wi;
        if wm.length_squared() == 0.0 {
            return 0.0;
        }
        let wm = wm.normalize();
        let (theta_o, phi_o) = spherical(wo);
        let params = [phi_o, theta_o];
        let u_wm = self.half_vector_uv(wm, phi_o);
        let (sample, vndf_pdf) = self.brdf.vndf.invert(u_wm, &params);
        let pdf = self.brdf.luminance.evaluate(sample, &params);
        let sin_theta_m = (wm.x * wm.x + wm.y * wm.y).sqrt();
        // dω_m = 2π² u sin θm du dv, and dωi = 4 (wo·wm) dωm.
        let jacobian = 4.0 * wo.dot(wm) * (2.0 * PI * PI * u_wm.x * sin_theta_m).max(1e-6);
        vndf_pdf * pdf / jacobian
    }

    pub(crate) fn sample(&self, wo: Vec3, _u_lobe: f32, u: Vec2, _mode: TransportMode) -> Option<BsdfSample> {
        let flip = wo.z <= 0.0;
        let wo = if flip { -wo } else { wo };
        let (theta_o, phi_o) = spherical(wo);
        let params = [phi_o, theta_o];
        let (u, lum_pdf) = self.brdf.luminance.sample(u, &params);
        let (u_wm, vndf_pdf) = self.brdf.vndf.sample(u, &params);
        let theta_m = u_to_theta(u_wm.x);
        let phi_m = u_to_phi(u_wm.y) + if self.brdf.isotropic { phi_o } else { 0.0 };
        let (sin_t, cos_t) = theta_m.sin_cos();
        let (sin_p, cos_p) = phi_m.sin_cos();
        let wm = Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t);
        let wi = 2.0 * wo.dot(wm) * wm - wo;
        if wi.z <= 0.0 || vndf_pdf <= 0.0 || lum_pdf <= 0.0 {
            return None;
        }
        let u_wo = Vec2::new(theta_to_u(theta_o), phi_to_u(phi_o));
        let f = self.remainder(u, &params) * self.brdf.ndf.evaluate(u_wm, &[])
            / (4.0 * self.brdf.sigma.evaluate(u_wo, &[]) * wi.z);
        let jacobian = 4.0 * wo.dot(wm) * (2.0 * PI * PI * u_wm.x * sin_t).max(1e-6);
        let pdf = vndf_pdf * lum_pdf / jacobian;
        Some(BsdfSample {
            wi: if flip { -wi } else { wi },
            f,
            pdf,
            delta: false,
            eta: 1.0,
        })
    }

    pub(crate) fn delta_probability(&self, _wo: Vec3) -> f32 {
        0.0
    }

    pub(crate) fn sample_delta(&self, _wo: Vec3, _u: f32, _mode: TransportMode) -> Option<BsdfSample> {
        None
    }

    pub(crate) fn has_smooth(&self) -> bool {
        true
    }

    /// Its directional albedo at normal incidence.
    pub fn albedo(&self) -> Rgb {
        self.brdf.normal_albedo
    }
}

/// Writing tensor files, for tests and fixtures: an RGL-style measured
/// BRDF tabulated from trazo's GGX conductor.
#[cfg(test)]
pub(crate) mod fixture {
    use super::*;
    use crate::material::microfacet::Microfacet;

    /// A tensor file of float32 fields (and the two byte fields RGL files
    /// carry).
    pub fn tensor_file(fields: &[(&str, Vec<usize>, Vec<f32>)]) -> Vec<u8> {
        let mut all: Vec<(String, u8, Vec<usize>, Vec<u8>)> = fields
            .iter()
            .map(|(n, s, v)| {
                (
                    n.to_string(),
                    10u8,
                    s.clone(),
                    v.iter().flat_map(|x| x.to_le_bytes()).collect(),
                )
            })
            .collect();
        all.push(("description".into(), 1, vec![4], b"test".to_vec()));
        all.push(("jacobian".into(), 1, vec![1], vec![1]));
        let header_len: usize = 12
            + 2
            + 4
            + all
                .iter()
                .map(|(n, _, s, _)| 2 + n.len() + 2 + 1 + 8 + 8 * s.len())
                .sum::<usize>();
        let mut out = b"tensor_file\0".to_vec();
        out.extend([1u8, 0]);
        out.extend((all.len() as u32).to_le_bytes());
        let mut offset = header_len as u64;
        for (name, dtype, shape, data) in &all {
            out.extend((name.len() as u16).to_le_bytes());
            out.extend(name.as_bytes());
            out.extend((shape.len() as u16).to_le_bytes());
            out.push(*dtype);
            out.extend(offset.to_le_bytes());
            for &n in shape {
                out.extend((n as u64).to_le_bytes());
            }
            offset += data.len() as u64;
        }
        assert_eq!(out.len(), header_len);
        for (_, _, _, data) in &all {
            out.extend(data);
        }
        out
    }

    /// The BRDF R·D·G/(4 cos θo cos θi) of an isotropic GGX surface of
    /// roughness `alpha` and flat reflectance `r`, tabulated as RGL files
    /// are: n × n grids, `thetas` incident angles.
    pub fn ggx_file(alpha: f32, r: f32, n: usize, thetas: &[f32]) -> Vec<u8> {
        let mf = Microfacet::isotropic(alpha);
        let grid = |i: usize| i as f32 / (n - 1) as f32;
        let normal = |theta: f32, phi: f32| {
            let (s, c) = theta.sin_cos();
            Vec3::new(s * phi.cos(), s * phi.sin(), c)
        };
        let wo_at = |theta: f32| Vec3::new(theta.sin(), 0.0, theta.cos());
        let mut ndf = Vec::new();
        let mut sigma = Vec::new();
        for _y in 0..n {
            for x in 0..n {
                let theta = u_to_theta(grid(x));
                ndf.push(mf.d(normal(theta, 0.0)));
                // σ(ωo) = ∫ D(m) ⟨ωo·m⟩ dm = cos θo / G1(ωo) for GGX.
                let (s, c) = theta.sin_cos();
                sigma.push(0.5 * (c + (c * c + alpha * alpha * s * s).sqrt()));
            }
        }
        let mut vndf = Vec::new();
        for &theta_o in thetas {
            let wo = wo_at(theta_o);
            for y in 0..n {
                for x in 0..n {
                    let (u, v) = (grid(x), grid(y));
                    let theta_m = u_to_theta(u);
                    let m = normal(theta_m, u_to_phi(v));
                    vndf.push(mf.d(m) * wo.dot(m).max(0.0) * u * theta_m.sin());
                }
            }
        }
        let params = vec![vec![0.0], thetas.to_vec()];
        let vndf_t = PiecewiseLinear2D::new(&vndf, n, n, params, true).expect("a valid table");
        let mut luminance = Vec::new();
        let mut spectra = Vec::new();
        for &theta_o in thetas {
            let wo = wo_at(theta_o);
            let mut slice = Vec::new();
            for y in 0..n {
                for x in 0..n {
                    let (u_wm, _) = vndf_t.sample(Vec2::new(grid(x), grid(y)), &[0.0, theta_o]);
                    let m = normal(u_to_theta(u_wm.x), u_to_phi(u_wm.y));
                    let wi = 2.0 * wo.dot(m) * m - wo;
                    let g1 = mf.g1(wo);
                    slice.push(if wi.z > 0.0 && g1 > 0.0 {
                        r * mf.g(wo, wi) / g1
                    } else {
                        0.0
                    });
                }
            }
            luminance.extend(&slice);
            // Two wavelengths, the same value: a flat spectrum.
            spectra.extend(&slice);
            spectra.extend(&slice);
        }
        let t = thetas.len();
        tensor_file(&[
            ("theta_i", vec![t], thetas.to_vec()),
            ("phi_i", vec![1], vec![0.0]),
            ("ndf", vec![n, n], ndf),
            ("sigma", vec![n, n], sigma),
            ("vndf", vec![1, t, n, n], vndf),
            ("luminance", vec![1, t, n, n], luminance),
            ("spectra", vec![1, t, 2, n, n], spectra),
            ("wavelengths", vec![2], vec![360.0, 830.0]),
        ])
    }

    /// Incident angles 0 to 85° in steps of 5°.
    pub fn thetas() -> Vec<f32> {
        (0..18).map(|i| (i as f32 * 5.0).to_radians()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::fixture::{ggx_file, tensor_file, thetas};
    use super::*;
    use crate::material::conductor::{ConductorBsdf, ConductorFresnel};
    use crate::material::microfacet::Microfacet;
    use crate::sampling::rng::Pcg32 as Rng;

    fn direction(theta_deg: f32, phi_deg: f32) -> Vec3 {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    #[test]
    fn warps_invert_each_other_and_report_the_density() {
        // A lumpy density over 2 parameters of 3 and 2 values.
        let (xs, ys) = (7, 5);
        let data: Vec<f32> = (0..3 * 2 * xs * ys)
            .map(|i| 0.2 + ((i * 7919) % 13) as f32 / 13.0)
            .collect();
        let t = PiecewiseLinear2D::new(&data, xs, ys, vec![vec![0.0, 1.0, 2.0], vec![-1.0, 1.0]], true).unwrap();
        let mut rng = Rng::new(7, 0);
        for _ in 0..2000 {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let params = [2.0 * rng.next_f32(), 2.0 * rng.next_f32() - 1.0];
            let (p, pdf) = t.sample(u, &params);
            assert!((0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y), "{p}");
            let (back, pdf_back) = t.invert(p, &params);
            assert!((back - u).abs().max_element() < 2e-3, "{u} → {p} → {back}");
            let density = t.evaluate(p, &params);
            assert!((pdf - density).abs() < 1e-3 * density.max(1.0), "{pdf} {density}");
            assert!(
                (pdf_back - density).abs() < 1e-3 * density.max(1.0),
                "{pdf_back} {density}"
            );
        }
        // Each slice integrates to 1 (midpoint rule on a fine grid).
        let params = [0.7, 0.2];
        let m = 400;
        let mut sum = 0.0f64;
        for i in 0..m {
            for j in 0..m {
                let p = Vec2::new((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32);
                sum += t.evaluate(p, &params) as f64;
            }
        }
        assert!((sum / (m * m) as f64 - 1.0).abs() < 1e-3, "{}", sum / (m * m) as f64);
    }

    fn ggx(alpha: f32) -> (MeasuredBrdf, ConductorBsdf, Rgb) {
        let brdf = MeasuredBrdf::from_bytes(&ggx_file(alpha, 0.8, 65, &thetas())).unwrap();
        // The flat spectrum's colour, as the file's conversion makes it.
        let w = crate::color::spectrum::sample_weights(&[360.0, 830.0], crate::color::spectrum::SpectrumUse::Unbounded);
        let r = (w[0] + w[1]) * 0.8;
        let conductor = ConductorBsdf {
            fresnel: ConductorFresnel::Constant(r),
            tint: Rgb::ONE,
            microfacet: Microfacet::isotropic(alpha),
        };
        (brdf, conductor, r)
    }

    #[test]
    fn a_tabulated_ggx_surface_evaluates_as_the_model() {
        let (brdf, conductor, _) = ggx(0.3);
        let measured = MeasuredBsdf { brdf: &brdf };
        let mode = TransportMode::Radiance;
        let mut worst = 0.0f32;
        for theta_o in [0.0, 20.0, 40.0, 60.0] {
            let wo = direction(theta_o, 30.0);
            for theta_i in [5.0, 25.0, 45.0, 65.0] {
                for phi_i in [30.0, 120.0, 210.0] {
                    let wi = direction(theta_i, phi_i);
                    let (a, b) = (measured.eval(wo, wi, mode).y, conductor.eval(wo, wi, mode).y);
                    // Where the lobe has any weight, within the grid's interpolation error.
                    if b > 0.05 {
                        worst = worst.max((a - b).abs() / b);
                    } else {
                        assert!(a < 0.06, "{theta_o} {theta_i} {phi_i}: {a} against {b}");
                    }
                }
            }
        }
        assert!(worst < 0.02, "worst relative error {worst}");
        // Both sides: the lower hemisphere mirrors the upper one.
        let (wo, wi) = (direction(30.0, 0.0), direction(35.0, 180.0));
        assert_eq!(measured.eval(-wo, -wi, mode), measured.eval(wo, wi, mode));
        assert_eq!(measured.eval(wo, -wi, mode), Rgb::ZERO);
    }

    #[test]
    fn sampling_agrees_with_eval_and_pdf_and_the_albedo_with_the_model() {
        let (brdf, conductor, _) = ggx(0.3);
        let measured = MeasuredBsdf { brdf: &brdf };
        let mode = TransportMode::Radiance;
        let mut rng = Rng::new(3, 0);
        for theta_o in [0.0, 35.0, 70.0] {
            let wo = direction(theta_o, 50.0);
            for _ in 0..500 {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let Some(s) = measured.sample(wo, 0.5, u, mode) else {
                    continue;
                };
                let pdf = measured.pdf(wo, s.wi);
                assert!((s.pdf - pdf).abs() <= 2e-3 * pdf.max(1.0), "{} against {pdf}", s.pdf);
                let f = measured.eval(wo, s.wi, mode);
                assert!(
                    (s.f - f).abs().max_element() <= 2e-3 * f.max_element().max(1.0),
                    "{} {f}",
                    s.f
                );
            }
            // The albedo by the tables' own sampling against the model's,
            // both on a 64² grid of samples.
            let n = 64;
            let mut model = Rgb::ZERO;
            for i in 0..n {
                for j in 0..n {
                    let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    if let Some(s) = conductor.sample(wo, 0.5, u, mode) {
                        model += s.weight();
                    }
                }
            }
            let model = model / (n * n) as f32;
            let table = brdf.directional_albedo(wo, n);
            assert!(
                (table.y - model.y).abs() < 0.005 * model.y,
                "θo {theta_o}: {table} against {model}"
            );
        }
        // The density integrates to 1 over the hemisphere (estimate: 100 000
        // uniform directions, standard error about 0.007).
        let wo = direction(40.0, 0.0);
        let mut sum = 0.0f64;
        let count = 100_000;
        for _ in 0..count {
            let w = crate::sampling::warp::sample_hemisphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
            sum += measured.pdf(wo, w) as f64 * 2.0 * std::f64::consts::PI;
        }
        let integral = sum / count as f64;
        assert!((0.97..1.03).contains(&integral), "∫ pdf = {integral}");
    }

    #[test]
    fn damaged_files_are_refused_with_a_reason() {
        let good = ggx_file(0.3, 0.5, 9, &thetas());
        assert!(MeasuredBrdf::from_bytes(&good).is_ok());
        // Cut at every length: an error each time, never a panic.
        for len in 0..good.len() {
            assert!(MeasuredBrdf::from_bytes(&good[..len]).is_err(), "cut at {len}");
        }
        let e = MeasuredBrdf::from_bytes(b"not a tensor").unwrap_err();
        assert!(e.contains("not a tensor file"), "{e}");
        let e = MeasuredBrdf::from_bytes(&good[..40]).unwrap_err();
        assert!(e.contains("truncated"), "{e}");
        let e = MeasuredBrdf::from_bytes(&good[..good.len() - 8]).unwrap_err();
        assert!(e.contains("past the end"), "{e}");
        let e = MeasuredBrdf::from_bytes(&tensor_file(&[("theta_i", vec![1], vec![0.0])])).unwrap_err();
        assert!(e.contains("no \"phi_i\" field"), "{e}");
        // A shape that disagrees with another field.
        let t = thetas();
        let n = 9;
        let e = MeasuredBrdf::from_bytes(&tensor_file(&[
            ("theta_i", vec![t.len()], t.clone()),
            ("phi_i", vec![1], vec![0.0]),
            ("ndf", vec![n, n], vec![1.0; n * n]),
            ("sigma", vec![n, n], vec![1.0; n * n]),
            ("vndf", vec![1, t.len() + 1, n, n], vec![1.0; (t.len() + 1) * n * n]),
            ("luminance", vec![1, t.len(), n, n], vec![1.0; t.len() * n * n]),
            ("spectra", vec![1, t.len(), 2, n, n], vec![1.0; 2 * t.len() * n * n]),
            ("wavelengths", vec![2], vec![400.0, 700.0]),
        ]))
        .unwrap_err();
        assert!(e.contains("disagree"), "{e}");
        // A huge shape claimed in a small file: the first field's shape
        // follows the 18-byte preamble and its name, rank, type and offset.
        let mut bytes = tensor_file(&[("theta_i", vec![1], vec![0.0])]);
        let shape_at = 18 + 2 + "theta_i".len() + 2 + 1 + 8;
        bytes[shape_at..shape_at + 8].copy_from_slice(&(1u64 << 62).to_le_bytes());
        let e = MeasuredBrdf::from_bytes(&bytes).unwrap_err();
        assert!(e.contains("\"theta_i\" lies past the end"), "{e}");
    }
}
