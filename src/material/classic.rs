//! The classical material of the ray-tracing course as a BSDF, so that the
//! Whitted material record renders in the path tracer too:
//!
//! ```text
//! f = kd/π  +  ks·(s+2)/(2π)·max(r·wi, 0)^s  +  kr·δ(mirror)  +  kt·[F·δ(mirror) + (1−F)·δ(refraction)]
//! ```
//!
//! The Phong lobe is energy-normalised (Lewis 1994) and sampled around the
//! mirror direction with density (s+1)/(2π)·cos^s α; the diffuse lobe by
//! the cosine-weighted hemisphere; the delta lobes exactly. A lobe is chosen
//! in proportion to the mean of its colour. The diffuse, Phong and mirror
//! lobes are two-sided; the glass lobe knows inside from outside.

use super::bsdf::{BsdfSample, TransportMode, flip_z, reflect_local, same_hemisphere};
use super::frame::Frame;
use super::optics::{fresnel_dielectric, refract};
use crate::color::Rgb;
use crate::sampling::warp::{pdf_hemisphere_cosine, sample_hemisphere_cosine};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// The classical material's BSDF.
#[derive(Clone, Copy, Debug)]
pub struct ClassicBsdf {
    /// Diffuse colour.
    pub kd: Rgb,
    /// Phong specular colour.
    pub ks: Rgb,
    /// Phong exponent.
    pub exponent: f32,
    /// Mirror reflectivity.
    pub kr: Rgb,
    /// Transmission (glass) weight.
    pub kt: Rgb,
    /// Relative index of refraction of the glass lobe.
    pub eta: f32,
    /// Lobe selection probabilities: diffuse, Phong, mirror, glass.
    p: [f32; 4],
}

fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

impl ClassicBsdf {
    /// The BSDF with the given lobe weights.
    pub fn new(kd: Rgb, ks: Rgb, exponent: f32, kr: Rgb, kt: Rgb, eta: f32) -> Self {
        let w = [mean(kd), mean(ks), mean(kr), mean(kt)];
        let total: f32 = w.iter().sum();
        let p = if total > 0.0 { w.map(|x| x / total) } else { [0.0; 4] };
        ClassicBsdf {
            kd,
            ks,
            exponent,
            kr,
            kt,
            eta,
            p,
        }
    }

    fn phong_cos(&self, wo: Vec3, wi: Vec3) -> f32 {
        reflect_local(wo).dot(wi).max(0.0)
    }

    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        if !same_hemisphere(wo, wi) {
            return Rgb::ZERO;
        }
        let mut f = self.kd * FRAC_1_PI;
        if self.ks != Rgb::ZERO {
            let c = self.phong_cos(wo, wi);
            if c > 0.0 {
                f += self.ks * ((self.exponent + 2.0) / (2.0 * PI) * c.powf(self.exponent));
            }
        }
        f
    }

    fn phong_pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let c = self.phong_cos(wo, wi);
        if c > 0.0 {
            (self.exponent + 1.0) / (2.0 * PI) * c.powf(self.exponent)
        } else {
            0.0
        }
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !same_hemisphere(wo, wi) {
            return 0.0;
        }
        self.p[0] * pdf_hemisphere_cosine(wi.z.abs()) + self.p[1] * self.phong_pdf(wo, wi)
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let [pd, ps, _, _] = self.p;
        if u_lobe < pd + ps {
            let wi = if u_lobe < pd {
                let w = sample_hemisphere_cosine(u);
                if wo.z < 0.0 { flip_z(w) } else { w }
            } else {
                // Phong lobe around the mirror direction: cos α = u^(1/(s+1)).
                let cos_a = u.x.powf(1.0 / (self.exponent + 1.0));
                let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let local = Vec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a);
                Frame::from_normal(reflect_local(wo)).to_world(local)
            };
            if !same_hemisphere(wo, wi) {
                return None; // the Phong lobe reaches below the surface
            }
            let pdf = self.pdf(wo, wi);
            if pdf <= 0.0 {
                return None;
            }
            return Some(BsdfSample {
                wi,
                f: self.eval(wo, wi, mode),
                pdf,
                delta: false,
                eta: 1.0,
            });
        }
        let start = pd + ps;
        let p_delta = 1.0 - start;
        let mut s = self.sample_delta(wo, ((u_lobe - start) / p_delta).min(0.999_999_9), mode)?;
        s.pdf *= p_delta;
        Some(s)
    }

    pub(crate) fn delta_probability(&self, _wo: Vec3) -> f32 {
        self.p[2] + self.p[3]
    }

    pub(crate) fn sample_delta(&self, wo: Vec3, u: f32, mode: TransportMode) -> Option<BsdfSample> {
        let (pm, pg) = (self.p[2], self.p[3]);
        let total = pm + pg;
        if total <= 0.0 || wo.z == 0.0 {
            return None;
        }
        let (pm, pg) = (pm / total, pg / total);
        if u < pm {
            let wi = reflect_local(wo);
            return Some(BsdfSample {
                wi,
                f: self.kr / wi.z.abs(),
                pdf: pm,
                delta: true,
                eta: 1.0,
            });
        }
        let u = ((u - pm) / pg).min(0.999_999_9);
        let fr = fresnel_dielectric(wo.z, self.eta);
        if u < fr {
            let wi = reflect_local(wo);
            Some(BsdfSample {
                wi,
                f: self.kt * (fr / wi.z.abs()),
                pdf: pg * fr,
                delta: true,
                eta: 1.0,
            })
        } else {
            let (wi, etap) = refract(wo, Vec3::Z, self.eta)?;
            let mut f = self.kt * ((1.0 - fr) / wi.z.abs());
            if mode == TransportMode::Radiance {
                f /= etap * etap;
            }
            Some(BsdfSample {
                wi,
                f,
                pdf: pg * (1.0 - fr),
                delta: true,
                eta: etap,
            })
        }
    }

    pub(crate) fn has_smooth(&self) -> bool {
        self.p[0] + self.p[1] > 0.0
    }

    pub(crate) fn albedo(&self) -> Rgb {
        (self.kd + self.ks + self.kr + self.kt).min(Rgb::ONE)
    }
}
