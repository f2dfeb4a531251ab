//! The GGX (Trowbridge–Reitz) microfacet distribution with Smith's
//! separable masking–shadowing and sampling of visible normals.
//!
//! The separable form G = G1(wo)·G1(wi) is Walter et al.'s (2007) and
//! Mitsuba's; trazo uses it so that its rough materials converge to
//! Mitsuba's images. (The height-correlated form of Heitz 2014, used by
//! pbrt-v4, is slightly brighter at grazing angles.)
//!
//! References: Walter et al. 2007, "Microfacet Models for Refraction
//! through Rough Surfaces"; Heitz 2014, "Understanding the Masking-Shadowing
//! Function in Microfacet-Based BRDFs"; Heitz 2018, "Sampling the GGX
//! Distribution of Visible Normals". All directions are in the local frame
//! (macro-normal +z).

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// An anisotropic GGX distribution with roughness `alpha_x`, `alpha_y`
/// (α = roughness², in Disney's terms; Mitsuba's `alpha`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// Roughness along the local x axis.
    pub alpha_x: f32,
    /// Roughness along the local y axis.
    pub alpha_y: f32,
}

/// Below this roughness a surface is treated as perfectly smooth.
pub const SMOOTH_ALPHA: f32 = 1e-4;

impl Ggx {
    /// An isotropic distribution.
    pub fn isotropic(alpha: f32) -> Ggx {
        Ggx {
            alpha_x: alpha,
            alpha_y: alpha,
        }
    }

    /// Whether the surface is smooth enough to be treated as a delta BSDF.
    pub fn is_smooth(&self) -> bool {
        self.alpha_x.max(self.alpha_y) < SMOOTH_ALPHA
    }

    /// The normal distribution D(m): density of microfacet normals per
    /// unit projected area (Walter et al. 2007, eq. 33, anisotropic form).
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let e = (m.x / ax) * (m.x / ax) + (m.y / ay) * (m.y / ay) + m.z * m.z;
        1.0 / (PI * ax * ay * e * e)
    }

    /// Smith's Λ(w) for GGX.
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        if z2 == 0.0 {
            return f32::INFINITY;
        }
        let a2 = (self.alpha_x * w.x) * (self.alpha_x * w.x) + (self.alpha_y * w.y) * (self.alpha_y * w.y);
        ((1.0 + a2 / z2).sqrt() - 1.0) * 0.5
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
    /// `wo`, distributed as D_wo(m) = G1(wo)·|wo·m|·D(m)/|cos θo| (Heitz 2018,
    /// listing 1). A `wo` below the surface is treated as its mirror image
    /// above it, as transmission from below needs.
    #[inline]
    pub fn sample_visible_normal(&self, wo: Vec3, u: Vec2) -> Vec3 {
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

    /// Density of [`Ggx::sample_visible_normal`]: D_wo(m).
    #[inline]
    pub fn pdf_visible_normal(&self, wo: Vec3, m: Vec3) -> f32 {
        if wo.z == 0.0 {
            return 0.0;
        }
        self.g1(wo) * wo.dot(m).abs() * self.d(m) / wo.z.abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// ∫ D(m) cos θm dω = 1: projected microfacet area equals macro area.
    #[test]
    fn normal_distribution_is_normalised() {
        for (ax, ay) in [(0.1f32, 0.1f32), (0.5, 0.5), (0.3, 0.8)] {
            let g = Ggx {
                alpha_x: ax,
                alpha_y: ay,
            };
            let (nt, np) = (2000, 200);
            let mut sum = 0.0f64;
            for i in 0..nt {
                // Map θ with a quadratic to put points near the peak.
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
                    sum +=
                        g.d(m) as f64 * theta.cos() * theta.sin() * dtheta * (2.0 * std::f64::consts::PI / np as f64);
                }
            }
            assert!((sum - 1.0).abs() < 5e-3, "α = ({ax}, {ay}): {sum}");
        }
    }

    /// The visible-normal density integrates to 1 and samples lie where it is positive.
    #[test]
    fn visible_normals_have_their_density() {
        let g = Ggx::isotropic(0.4);
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
