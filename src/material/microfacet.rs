//! Microfacet normal distributions — GGX (Trowbridge–Reitz) and Beckmann —
//! with Smith's separable masking–shadowing and sampling of visible normals.
//!
//! The separable form G = G1(wo)·G1(wi) is Walter et al.'s (2007) and
//! Mitsuba's; trazo uses it so that its rough materials converge to
//! Mitsuba's images. (The height-correlated form of Heitz 2014, used by
//! pbrt-v4, is slightly brighter at grazing angles.) Beckmann's G1 is
//! Walter et al.'s rational approximation (eq. 27), as Mitsuba's.
//!
//! References: Walter et al. 2007, "Microfacet Models for Refraction
//! through Rough Surfaces"; Heitz 2014, "Understanding the Masking-Shadowing
//! Function in Microfacet-Based BRDFs"; Heitz and d'Eon 2014, "Importance
//! Sampling Microfacet-Based BSDFs using the Distribution of Visible
//! Normals"; Heitz 2018, "Sampling the GGX Distribution of Visible Normals".
//! All directions are in the local frame (macro-normal +z).

use crate::sampling::erf::{erf, erf_inv};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Which distribution of microfacet normals a rough surface has.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MicrofacetDistribution {
    /// Trowbridge–Reitz: long tails, pbrt-v4's only distribution.
    #[default]
    Ggx,
    /// Beckmann (Gaussian slopes): Mitsuba's default.
    Beckmann,
}

impl MicrofacetDistribution {
    /// The name scene files use for it.
    pub fn name(self) -> &'static str {
        match self {
            MicrofacetDistribution::Ggx => "ggx",
            MicrofacetDistribution::Beckmann => "beckmann",
        }
    }

    /// The distribution a scene file names, if any.
    pub fn from_name(name: &str) -> Option<MicrofacetDistribution> {
        match name {
            "ggx" => Some(MicrofacetDistribution::Ggx),
            "beckmann" => Some(MicrofacetDistribution::Beckmann),
            _ => None,
        }
    }
}

/// An anisotropic microfacet distribution with roughness `alpha_x`,
/// `alpha_y` (α = roughness², in Disney's terms; Mitsuba's `alpha`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    /// GGX or Beckmann.
    pub distribution: MicrofacetDistribution,
    /// Roughness along the local x axis.
    pub alpha_x: f32,
    /// Roughness along the local y axis.
    pub alpha_y: f32,
}

/// Below this roughness a surface is treated as perfectly smooth.
pub const SMOOTH_ALPHA: f32 = 1e-4;

/// 1/√π.
const FRAC_1_SQRT_PI: f32 = 0.564_189_6;

impl Microfacet {
    /// An isotropic GGX distribution.
    pub fn isotropic(alpha: f32) -> Microfacet {
        Microfacet::new(MicrofacetDistribution::Ggx, alpha, alpha)
    }

    /// A distribution of either kind.
    pub fn new(distribution: MicrofacetDistribution, alpha_x: f32, alpha_y: f32) -> Microfacet {
        Microfacet {
            distribution,
            alpha_x,
            alpha_y,
        }
    }

    /// Whether the surface is smooth enough to be treated as a delta BSDF.
    pub fn is_smooth(&self) -> bool {
        self.alpha_x.max(self.alpha_y) < SMOOTH_ALPHA
    }

    /// The normal distribution D(m): density of microfacet normals per
    /// unit projected area (Walter et al. 2007, eqs. 25 and 33, in their
    /// anisotropic forms).
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let slope2 = (m.x / ax) * (m.x / ax) + (m.y / ay) * (m.y / ay);
        match self.distribution {
            MicrofacetDistribution::Ggx => {
                let e = slope2 + m.z * m.z;
                1.0 / (PI * ax * ay * e * e)
            }
            MicrofacetDistribution::Beckmann => {
                let z2 = m.z * m.z;
                let d = (-slope2 / z2).exp() / (PI * ax * ay * z2 * z2);
                // exp underflows to 0 long before the quotient matters, but
                // keep far-tail values from reaching the pdfs as denormals.
                if d * m.z > 1e-20 { d } else { 0.0 }
            }
        }
    }

    /// Smith's Λ(w).
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        if z2 == 0.0 {
            return f32::INFINITY;
        }
        let a2 = (self.alpha_x * w.x) * (self.alpha_x * w.x) + (self.alpha_y * w.y) * (self.alpha_y * w.y);
        match self.distribution {
            MicrofacetDistribution::Ggx => ((1.0 + a2 / z2).sqrt() - 1.0) * 0.5,
            MicrofacetDistribution::Beckmann => {
                // a = 1/(α tan θ) along w's azimuth.
                if a2 == 0.0 {
                    return 0.0;
                }
                let a = (z2 / a2).sqrt();
                if a >= 1.6 {
                    0.0
                } else {
                    (1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a)
                }
            }
        }
    }

    /// Smith masking G1(w): the fraction of microfacets visible from w.
    /// Which facets face away from w is for the caller to check.
    #[inline]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Separable masking–shadowing G(wo, wi) = G1(wo)·G1(wi).
    #[inline]
    pub fn g(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.g1(wo) * self.g1(wi)
    }

    /// Samples a microfacet normal (in the upper hemisphere) visible from
    /// `wo`, distributed as D_wo(m) = G1(wo)·|wo·m|·D(m)/|cos θo|. A `wo`
    /// below the surface is treated as −wo, which has the same density, as
    /// transmission from below needs.
    #[inline]
    pub fn sample_visible_normal(&self, wo: Vec3, u: Vec2) -> Vec3 {
        match self.distribution {
            MicrofacetDistribution::Ggx => self.sample_visible_ggx(wo, u),
            MicrofacetDistribution::Beckmann => self.sample_visible_beckmann(if wo.z < 0.0 { -wo } else { wo }, u),
        }
    }

    /// GGX's visible normals (Heitz 2018, listing 1).
    #[inline]
    fn sample_visible_ggx(&self, wo: Vec3, u: Vec2) -> Vec3 {
        // Stretch to the hemisphere configuration.
        let mut vh = Vec3::new(self.alpha_x * wo.x, self.alpha_y * wo.y, wo.z).normalize();
        if vh.z < 0.0 {
            vh = -vh;
        }
        // Orthonormal basis around vh.
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        // Uniform point on the projected disk, squeezed toward vh.
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let mut p2 = r * phi.sin();
        let s = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        // Unstretch.
        Vec3::new(self.alpha_x * nh.x, self.alpha_y * nh.y, nh.z.max(1e-6)).normalize()
    }

    /// Beckmann's visible normals (Heitz and d'Eon 2014, §4): stretch `wo`
    /// to roughness 1, draw a slope from the visible-slope distribution
    /// there, rotate it to `wo`'s azimuth and unstretch. Kept out of line:
    /// its root finding would bloat every BSDF sampler it is inlined into.
    #[inline(never)]
    fn sample_visible_beckmann(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let w = Vec3::new(self.alpha_x * wo.x, self.alpha_y * wo.y, wo.z).normalize();
        let sin_theta = (w.x * w.x + w.y * w.y).sqrt();
        let (cos_phi, sin_phi) = if sin_theta > 0.0 {
            (w.x / sin_theta, w.y / sin_theta)
        } else {
            (1.0, 0.0)
        };
        let slope = beckmann_visible_slope(w.z.max(1e-6), u);
        let sx = (cos_phi * slope.x - sin_phi * slope.y) * self.alpha_x;
        let sy = (sin_phi * slope.x + cos_phi * slope.y) * self.alpha_y;
        Vec3::new(-sx, -sy, 1.0).normalize()
    }

    /// Density of [`Microfacet::sample_visible_normal`]: D_wo(m).
    #[inline]
    pub fn pdf_visible_normal(&self, wo: Vec3, m: Vec3) -> f32 {
        if wo.z == 0.0 {
            return 0.0;
        }
        self.g1(wo) * wo.dot(m).abs() * self.d(m) / wo.z.abs()
    }
}

/// A slope (x along the view's azimuth, y across it) of the roughness-1
/// Beckmann surface, drawn from the slopes visible from a direction at
/// `cos_theta` from the normal.
///
/// The y slope is Gaussian; the x slope's distribution has, in the erf
/// domain b = erf(x), the cumulative 1 + b + tanθ/√π·exp(−erf⁻¹(b)²)
/// (up to its value at b = erf(cot θ)). It is inverted by Newton's method
/// kept inside a bracket, from the exact inverse at grazing angles as the
/// first guess (Jakob's numerical inversion, as in Mitsuba 3: smooth in
/// `u`, unlike the fitted curve of Heitz and d'Eon).
fn beckmann_visible_slope(cos_theta: f32, u: Vec2) -> Vec2 {
    let u = u.clamp(Vec2::splat(1e-6), Vec2::splat(1.0 - 1e-6));
    let tan_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt() / cos_theta;
    let cot_theta = 1.0 / tan_theta;
    let b_max = erf(cot_theta);
    let total = 1.0 + b_max + FRAC_1_SQRT_PI * tan_theta * (-cot_theta * cot_theta).exp();
    let target = u.x * total;
    let (mut lo, mut hi) = (-1.0f32, b_max);
    let mut b = b_max - (b_max + 1.0) * erf((-u.x.ln()).sqrt());
    for _ in 0..8 {
        if !(b > lo && b < hi) {
            b = 0.5 * (lo + hi);
        }
        let slope = erf_inv(b);
        let value = 1.0 + b + FRAC_1_SQRT_PI * tan_theta * (-slope * slope).exp() - target;
        if value.abs() < 1e-6 * total {
            break;
        }
        if value > 0.0 {
            hi = b;
        } else {
            lo = b;
        }
        b -= value / (1.0 - slope * tan_theta);
    }
    Vec2::new(erf_inv(b), erf_inv(2.0 * u.y - 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    const DISTRIBUTIONS: [MicrofacetDistribution; 2] = [MicrofacetDistribution::Ggx, MicrofacetDistribution::Beckmann];

    /// ∫ f(m) dω over the upper hemisphere by a midpoint rule whose θ
    /// steps crowd towards the pole, where the lobes peak.
    fn hemisphere_integral(f: impl Fn(Vec3) -> f64) -> f64 {
        let (nt, np) = (2000, 200);
        let mut sum = 0.0f64;
        for i in 0..nt {
            let x = (i as f64 + 0.5) / nt as f64;
            let theta = x * x * std::f64::consts::FRAC_PI_2;
            let dtheta = 2.0 * x * std::f64::consts::FRAC_PI_2 / nt as f64;
            for j in 0..np {
                let phi = (j as f64 + 0.5) / np as f64 * 2.0 * std::f64::consts::PI;
                let m = Vec3::new(
                    (theta.sin() * phi.cos()) as f32,
                    (theta.sin() * phi.sin()) as f32,
                    theta.cos() as f32,
                );
                sum += f(m) * theta.sin() * dtheta * (2.0 * std::f64::consts::PI / np as f64);
            }
        }
        sum
    }

    /// ∫ D(m) cos θm dω = 1: projected microfacet area equals macro area.
    #[test]
    fn normal_distribution_is_normalised() {
        for distribution in DISTRIBUTIONS {
            for (ax, ay) in [(0.1f32, 0.1f32), (0.5, 0.5), (0.3, 0.8)] {
                let g = Microfacet::new(distribution, ax, ay);
                let sum = hemisphere_integral(|m| g.d(m) as f64 * m.z as f64);
                assert!((sum - 1.0).abs() < 5e-3, "{distribution:?} α = ({ax}, {ay}): {sum}");
            }
        }
    }

    /// ∫ D_wo(m) dω = 1 (Smith's G1 is what makes it so: for Beckmann, to
    /// the accuracy of Walter's rational approximation, under 0.35 %).
    #[test]
    fn visible_normal_density_is_normalised() {
        for distribution in DISTRIBUTIONS {
            for (ax, ay) in [(0.15f32, 0.15f32), (0.6, 0.6), (0.2, 0.5)] {
                let g = Microfacet::new(distribution, ax, ay);
                for wo in [
                    Vec3::new(0.3, 0.1, 0.95),
                    Vec3::new(0.8, -0.4, 0.3),
                    Vec3::new(-0.2, 0.9, -0.4),
                ] {
                    let wo = wo.normalize();
                    let sum = hemisphere_integral(|m| {
                        g.pdf_visible_normal(wo, m) as f64 * (wo.dot(m) * wo.z > 0.0) as u8 as f64
                    });
                    assert!(
                        (sum - 1.0).abs() < 6e-3,
                        "{distribution:?} α = ({ax}, {ay}), wo = {wo}: {sum}"
                    );
                }
            }
        }
    }

    /// The Beckmann slope inversion lands where its cumulative says, at
    /// every angle including normal and grazing incidence.
    #[test]
    fn beckmann_slopes_invert_their_cumulative() {
        for cos_theta in [1.0f32, 0.999_99, 0.9, 0.5, 0.1, 0.01, 1e-6] {
            let tan_theta = (1.0 - cos_theta * cos_theta).sqrt() / cos_theta;
            let cdf = |x: f32| {
                let b = erf(x);
                let t = FRAC_1_SQRT_PI * tan_theta * (-x * x).exp();
                let b_max = erf(1.0 / tan_theta);
                let total = 1.0 + b_max + FRAC_1_SQRT_PI * tan_theta * (-1.0 / (tan_theta * tan_theta)).exp();
                (1.0 + b + if t.is_finite() { t } else { 0.0 }) / total
            };
            for u in [0.001f32, 0.1, 0.37, 0.5, 0.8, 0.999] {
                let s = beckmann_visible_slope(cos_theta, Vec2::new(u, 0.5));
                assert!(s.is_finite(), "cos θ = {cos_theta}, u = {u}: {s}");
                if cos_theta > 1e-3 {
                    assert!(
                        (cdf(s.x) - u).abs() < 2e-4,
                        "cos θ = {cos_theta}, u = {u}: cdf {}",
                        cdf(s.x)
                    );
                }
                assert!(s.y.abs() < 1e-6, "the median slope across is 0");
            }
        }
    }

    /// Sampled visible normals lie where their density is positive.
    #[test]
    fn visible_normals_have_their_density() {
        for distribution in DISTRIBUTIONS {
            let g = Microfacet::new(distribution, 0.4, 0.4);
            let wo = Vec3::new(0.6, 0.1, 0.79).normalize();
            let mut r = Pcg32::new(1, 0);
            for _ in 0..2000 {
                let m = g.sample_visible_normal(wo, Vec2::new(r.next_f32(), r.next_f32()));
                assert!((m.length() - 1.0).abs() < 1e-4 && m.z > 0.0);
                assert!(g.pdf_visible_normal(wo, m) > 0.0);
                assert!(wo.dot(m) > 0.0, "sampled normals face the viewer");
            }
        }
    }
}
