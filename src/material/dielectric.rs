//! Dielectrics (glass, water): a smooth interface reflects and refracts by
//! the exact Fresnel equations and Snell's law; a rough one is a GGX
//! microfacet interface (Walter et al. 2007) sampled by visible normals.
//!
//! `eta` is the relative index of refraction inside/outside; the side is
//! told by the sign of cos θ (the normal points outside).
//!
//! **Radiance scaling.** Radiance crossing into a denser medium is
//! compressed into a smaller solid angle: L_t = (η_t/η_i)²·(1−F)·L_i
//! (Veach 1997, §5.2). In [`TransportMode::Radiance`] the transmitted
//! BSDF value is divided by η'² (η' = η_t/η_i of the crossing, as the
//! path is traced backwards from the camera); paths traced from the lights
//! ([`TransportMode::Importance`]) are not scaled.

use super::bsdf::{BsdfSample, TransportMode};
use super::layered::Lobes;
use super::microfacet::Microfacet;
use super::optics::{fresnel_dielectric, fresnel_of_cosines, reflect_lanes, refracted, refracted_lanes, snell_lanes};
use crate::color::Rgb;
use crate::geometry::simd::{Floats, Vec3s};
use glam::{Vec2, Vec3};

/// A smooth or rough dielectric interface.
#[derive(Clone, Copy, Debug)]
pub struct DielectricBsdf {
    /// Relative index of refraction, inside over outside.
    pub eta: f32,
    /// Roughness; smooth below [`super::microfacet::SMOOTH_ALPHA`].
    pub microfacet: Microfacet,
    /// Multiplier of reflected light (Mitsuba's `specular_reflectance`).
    pub reflect_tint: Rgb,
    /// Multiplier of transmitted light (Mitsuba's `specular_transmittance`).
    pub transmit_tint: Rgb,
}

impl DielectricBsdf {
    /// The generalised half vector of (wo, wi) and the relative index of
    /// the crossing, or `None` if degenerate or back-facing.
    pub(super) fn half_vector(&self, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, bool)> {
        let (cos_o, cos_i) = (wo.z, wi.z);
        if cos_o == 0.0 || cos_i == 0.0 {
            return None;
        }
        let reflect = cos_o * cos_i > 0.0;
        let etap = if reflect {
            1.0
        } else if cos_o > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let wm = wi * etap + wo;
        if wm.length_squared() == 0.0 {
            return None;
        }
        let mut wm = wm.normalize();
        if wm.z < 0.0 {
            wm = -wm;
        }
        // Microfacets seen from behind contribute nothing.
        if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
            return None;
        }
        Some((wm, etap, reflect))
    }

    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        if self.eta == 1.0 || self.microfacet.is_smooth() {
            return Rgb::ZERO;
        }
        let Some((wm, etap, reflect)) = self.half_vector(wo, wi) else {
            return Rgb::ZERO;
        };
        let f = fresnel_dielectric(wo.dot(wm), self.eta);
        let (d, g) = (self.microfacet.d(wm), self.microfacet.g(wo, wi));
        if reflect {
            return self.reflect_tint * (d * g * f / (4.0 * wi.z * wo.z).abs());
        }
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2) * wi.z * wo.z;
        let mut ft = d * (1.0 - f) * g * (wi.dot(wm) * wo.dot(wm) / denom).abs();
        if mode == TransportMode::Radiance {
            ft /= etap * etap;
        }
        self.transmit_tint * ft
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.eta == 1.0 || self.microfacet.is_smooth() {
            return 0.0;
        }
        let Some((wm, etap, reflect)) = self.half_vector(wo, wi) else {
            return 0.0;
        };
        let r = fresnel_dielectric(wo.dot(wm), self.eta);
        let t = 1.0 - r;
        let pdf_m = self.microfacet.pdf_visible_normal(wo, wm);
        if reflect {
            pdf_m / (4.0 * wo.dot(wm).abs()) * r
        } else {
            let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
            pdf_m * wi.dot(wm).abs() / denom * t
        }
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if self.eta == 1.0 || self.microfacet.is_smooth() {
            return self.sample_delta(wo, u_lobe, mode);
        }
        self.sample_lobes(wo, u_lobe, u, mode, Lobes::Both)
    }

    pub(crate) fn delta_probability(&self, _wo: Vec3) -> f32 {
        if self.eta == 1.0 || self.microfacet.is_smooth() {
            1.0
        } else {
            0.0
        }
    }

    pub(crate) fn sample_delta(&self, wo: Vec3, u: f32, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 || !(self.eta == 1.0 || self.microfacet.is_smooth()) {
            return None;
        }
        let c = SmoothChoice::<f32>::new(wo.z, self.eta, u, mode);
        if c.reflects {
            return Some(BsdfSample::mirror(wo, c.pdf, self.reflect_tint));
        }
        let n = if wo.z < 0.0 { -Vec3::Z } else { Vec3::Z };
        let wi = refracted(wo, n, c.cos_i, c.etap, c.cos_t);
        Some(BsdfSample {
            wi,
            f: self.transmit_tint * (c.pdf / wi.z.abs()) * c.scale,
            pdf: c.pdf,
            delta: true,
            eta: c.etap,
        })
    }

    pub(crate) fn has_smooth(&self) -> bool {
        !(self.eta == 1.0 || self.microfacet.is_smooth())
    }

    pub(crate) fn albedo(&self) -> Rgb {
        self.transmit_tint.max(self.reflect_tint).min(Rgb::ONE)
    }
}

/// A smooth dielectric's choice between mirror reflection and refraction
/// for light leaving along a direction whose cosine to the normal is
/// `cos_o` (negative: inside): Snell's law once for the Fresnel reflectance
/// and the refracted direction (`fresnel_dielectric` and `refract` apart
/// would each solve it). Written once over lanes, for the one-path BSDF
/// ([`DielectricBsdf::sample_delta`]) and for the path tracer's bounces
/// off smooth glass made in lanes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SmoothChoice<F: Floats> {
    /// The lanes that reflect.
    pub reflects: F::Mask,
    /// The chosen event's probability: the Fresnel reflectance R, or
    /// 1 − R.
    pub pdf: F,
    /// |cos θ_o|.
    pub cos_i: F,
    /// The relative index of the crossing (η, or 1/η from inside).
    pub etap: F,
    /// |cos θ_t| (0 under total internal reflection).
    pub cos_t: F,
    /// The factor of refracted radiance: 1/η'² for radiance (pbrt-v4,
    /// section 9.5.2), 1 for importance.
    pub scale: F,
}

impl<F: Floats> SmoothChoice<F> {
    /// The choice for the uniform number `u`: reflection where `u` < R.
    #[inline(always)]
    pub(crate) fn new(cos_o: F, eta: F, u: F, mode: TransportMode) -> SmoothChoice<F> {
        let one = F::splat(1.0);
        let (cos_i, etap, cos_t, crosses) = snell_lanes(cos_o.max(F::splat(-1.0)).min(one), eta);
        let r = F::select(crosses, fresnel_of_cosines(cos_i, etap, cos_t), one);
        let reflects = r.gt(u);
        let scale = match mode {
            // (A factor known ahead of `f`, not a division after it.)
            TransportMode::Radiance => one / (etap * etap),
            TransportMode::Importance => one,
        };
        SmoothChoice {
            reflects,
            pdf: F::select(reflects, r, one - r),
            cos_i,
            etap,
            cos_t,
            scale,
        }
    }
}

/// A smooth dielectric's bounce in world space, over lanes: for light
/// leaving along the unit vector `wo` a surface whose shading normal is
/// `n`, of relative index `eta` and tints `reflect_tint` and
/// `transmit_tint`, the choice made with `u`, the direction the light
/// arrives from, and f·|cos θi|/pdf of the lobe chosen (its tint, times
/// 1/η'² through refraction). No frame is needed: the surface turns light
/// about its normal alone.
#[inline(always)]
pub(crate) fn smooth_bounce<F: Floats>(
    wo: Vec3s<F>,
    n: Vec3s<F>,
    eta: F,
    u: F,
    reflect_tint: Vec3s<F>,
    transmit_tint: Vec3s<F>,
) -> (SmoothChoice<F>, Vec3s<F>, Vec3s<F>) {
    let cos_o = wo.dot(n);
    let c = SmoothChoice::new(cos_o, eta, u, TransportMode::Radiance);
    let side = Vec3s::select(F::splat(0.0).gt(cos_o), Vec3s::splat(Vec3::ZERO) - n, n);
    let wi = Vec3s::select(
        c.reflects,
        reflect_lanes(wo, n),
        refracted_lanes(wo, side, c.cos_i, c.etap, c.cos_t),
    );
    let factor = Vec3s::select(c.reflects, reflect_tint, transmit_tint.scale(c.scale));
    (c, wi, factor)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::Frame;
    use crate::sampling::rng::Pcg32;

    /// [`smooth_bounce`] with white tints: the direction, the weight
    /// f·|cos θi|/pdf (one channel) and the probability.
    fn world_bounce<F: Floats>(wo: Vec3s<F>, n: Vec3s<F>, eta: F, u: F) -> (Vec3s<F>, F, F) {
        let white = Vec3s::splat(Rgb::ONE);
        let (c, wi, factor) = smooth_bounce(wo, n, eta, u, white, white);
        (wi, factor.x, c.pdf)
    }

    /// In world space about any normal, the choice gives the direction,
    /// weight and probability of the one-path BSDF's sample in the normal's
    /// frame, and eight lanes give each lane the bits of one; the cases
    /// include light from inside and total internal reflection.
    #[test]
    #[allow(unsafe_code)]
    fn smooth_choice_in_world_space_and_in_lanes_is_the_bsdf_sample() {
        let mut rng = Pcg32::new(7, 0);
        let mut cases = Vec::new();
        for k in 0..256 {
            let n = crate::sampling::warp::sample_sphere_uniform(glam::Vec2::new(rng.next_f32(), rng.next_f32()));
            let mut wo = crate::sampling::warp::sample_sphere_uniform(glam::Vec2::new(rng.next_f32(), rng.next_f32()));
            if k % 4 == 0 {
                // Grazing from inside: beyond the critical angle.
                wo = (-0.1 * n + (n.any_orthonormal_vector())).normalize();
            }
            let eta = [1.5, 1.33, 1.0 / 1.5, 1.0][k % 4];
            cases.push((wo, n, eta, rng.next_f32()));
        }
        for &(wo, n, eta, u) in &cases {
            let bsdf = DielectricBsdf {
                eta,
                microfacet: Microfacet::new(crate::material::MicrofacetDistribution::Ggx, 0.0, 0.0),
                reflect_tint: Rgb::ONE,
                transmit_tint: Rgb::ONE,
            };
            let frame = Frame::from_normal(n);
            let s = bsdf
                .sample_delta(frame.to_local(wo), u, TransportMode::Radiance)
                .unwrap();
            let (wi, weight, pdf) = world_bounce::<f32>(Vec3s::splat(wo), Vec3s::splat(n), eta, u);
            let wi = wi.lane(0);
            assert!(
                (wi - frame.to_world(s.wi)).length() < 1e-5,
                "{wi} {}",
                frame.to_world(s.wi)
            );
            assert!((pdf - s.pdf).abs() < 1e-6);
            let expect = s.weight().x;
            assert!((weight - expect).abs() < 1e-5 * expect, "{weight} {expect}");
        }
        #[cfg(target_arch = "x86_64")]
        if crate::geometry::lanes::avx_available() {
            use crate::geometry::lanes::F8;
            /// A case: wo, n, η and u.
            type Case = (Vec3, Vec3, f32, f32);
            #[target_feature(enable = "avx")]
            fn eight(c: &[Case]) -> [(Vec3, f32, f32); 8] {
                let wo = Vec3s::gather(&std::array::from_fn(|i| c[i].0));
                let n = Vec3s::gather(&std::array::from_fn(|i| c[i].1));
                let eta = F8::gather(&std::array::from_fn(|i| c[i].2));
                let u = F8::gather(&std::array::from_fn(|i| c[i].3));
                let (wi, weight, pdf) = world_bounce::<F8>(wo, n, eta, u);
                std::array::from_fn(|i| (wi.lane(i), weight.lane(i), pdf.lane(i)))
            }
            for chunk in cases.chunks(8) {
                // SAFETY: the processor has AVX (checked above).
                let wide = unsafe { eight(chunk) };
                for (i, &(wo, n, eta, u)) in chunk.iter().enumerate() {
                    let (wi, weight, pdf) = world_bounce::<f32>(Vec3s::splat(wo), Vec3s::splat(n), eta, u);
                    let one = (wi.lane(0), weight, pdf);
                    assert_eq!(
                        (one.0.to_array().map(f32::to_bits), one.1.to_bits(), one.2.to_bits()),
                        (
                            wide[i].0.to_array().map(f32::to_bits),
                            wide[i].1.to_bits(),
                            wide[i].2.to_bits()
                        )
                    );
                }
            }
        }
    }
}
