//! Lambertian reflection: f = ρ/π, sampled by the cosine-weighted
//! hemisphere. Two-sided.

use super::bsdf::{BsdfSample, TransportMode, flip_z, same_hemisphere};
use crate::color::Rgb;
use crate::sampling::warp::{pdf_hemisphere_cosine, sample_hemisphere_cosine};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Lambertian reflection with albedo ρ.
#[derive(Clone, Copy, Debug)]
pub struct LambertBsdf {
    /// Albedo ρ.
    pub albedo: Rgb,
}

impl LambertBsdf {
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        if same_hemisphere(wo, wi) {
            self.albedo * FRAC_1_PI
        } else {
            Rgb::ZERO
        }
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if same_hemisphere(wo, wi) {
            pdf_hemisphere_cosine(wi.z.abs())
        } else {
            0.0
        }
    }

    pub(crate) fn sample(&self, wo: Vec3, _u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let mut wi = sample_hemisphere_cosine(u);
        if wo.z < 0.0 {
            wi = flip_z(wi);
        }
        let pdf = self.pdf(wo, wi);
        if pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.eval(wo, wi, mode),
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

    pub(crate) fn albedo(&self) -> Rgb {
        self.albedo
    }
}
