//! Lambertian reflection: f = ρ/π, sampled by the cosine-weighted
//! hemisphere. Two-sided.

use super::bsdf::{BsdfSample, TransportMode};
use crate::color::Rgb;
use crate::geometry::simd::{Floats, Vec3s};
use crate::sampling::warp::{pdf_hemisphere_cosine, sample_hemisphere_cosine_lanes};
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
        lambert_eval(Vec3s::<f32>::splat(self.albedo), wo.z, wi.z).lane(0)
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        lambert_pdf(wo.z, wi.z)
    }

    pub(crate) fn sample(&self, wo: Vec3, _u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let wi = lambert_sample(wo.z, u.x, u.y).lane(0);
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

/// The Lambertian BSDF's value over lanes for directions whose cosines to
/// the shading normal are `cos_o` and `cos_i`: ρ/π where they lie on one
/// side, else 0. [`LambertBsdf::eval`] is its one-lane instance, the path
/// tracer's diffuse bounces in lanes its eight-lane one.
#[inline(always)]
pub(crate) fn lambert_eval<F: Floats>(albedo: Vec3s<F>, cos_o: F, cos_i: F) -> Vec3s<F> {
    let same = (cos_o * cos_i).gt(F::splat(0.0));
    Vec3s::select(same, albedo.scale(F::splat(FRAC_1_PI)), Vec3s::splat(Vec3::ZERO))
}

/// The density of [`lambert_sample`] over lanes: cos θi/π on wo's side,
/// else 0.
#[inline(always)]
pub(crate) fn lambert_pdf<F: Floats>(cos_o: F, cos_i: F) -> F {
    let same = (cos_o * cos_i).gt(F::splat(0.0));
    F::select(same, pdf_hemisphere_cosine(cos_i.abs()), F::splat(0.0))
}

/// A cosine-weighted direction on the side of wo (whose cosine is
/// `cos_o`), in the shading frame, over lanes.
#[inline(always)]
pub(crate) fn lambert_sample<F: Floats>(cos_o: F, ux: F, uy: F) -> Vec3s<F> {
    let mut wi = sample_hemisphere_cosine_lanes(ux, uy);
    wi.z = F::select(F::splat(0.0).gt(cos_o), F::splat(0.0) - wi.z, wi.z);
    wi
}
