//! Thin sheets: a pane of glass of negligible thickness (Mitsuba's
//! `thindielectric`, pbrt-v4's `thindielectric`), and, as the sheet of
//! index 1, the surface that is not there (Mitsuba's `null` BSDF, pbrt's
//! `interface` material), which bounds a medium without scattering.
//!
//! Light crossing the sheet leaves it in its own direction; what is
//! reflected sums the reflections between the two faces, R' = R + T²R/(1 −
//! R²) with R the Fresnel reflectance of one face and T = 1 − R (pbrt-v4,
//! section 9.5.2). Both lobes are delta lobes; the crossing is a
//! pass-through: it does not bend the path, so a volumetric path tracer
//! does not count it as a bounce and lets shadow rays through it with the
//! weight [`ThinBsdf::pass_through`].

use super::bsdf::{BsdfSample, TransportMode};
use super::optics::fresnel_dielectric;
use crate::color::Rgb;
use glam::{Vec2, Vec3};

/// A thin dielectric sheet; of index 1, no surface at all.
#[derive(Clone, Copy, Debug)]
pub struct ThinBsdf {
    /// Index of refraction of the sheet relative to its surroundings.
    pub eta: f32,
    /// Multiplier of reflected light.
    pub reflect_tint: Rgb,
    /// Multiplier of transmitted light.
    pub transmit_tint: Rgb,
}

impl ThinBsdf {
    /// The surface that is not there.
    pub const NULL: ThinBsdf = ThinBsdf {
        eta: 1.0,
        reflect_tint: Rgb::ONE,
        transmit_tint: Rgb::ONE,
    };

    /// R', the share of light the sheet reflects for direction `wo`.
    #[inline]
    fn reflectance(&self, wo: Vec3) -> f32 {
        if self.eta == 1.0 {
            return 0.0;
        }
        let r = fresnel_dielectric(wo.z.abs(), self.eta);
        if r < 1.0 {
            r + (1.0 - r) * (1.0 - r) * r / (1.0 - r * r)
        } else {
            1.0
        }
    }

    /// The weight of light that crosses the sheet along `wo` unchanged.
    #[inline]
    pub fn pass_through(&self, wo: Vec3) -> Rgb {
        self.transmit_tint * (1.0 - self.reflectance(wo))
    }

    pub(crate) fn eval(&self, _wo: Vec3, _wi: Vec3, _mode: TransportMode) -> Rgb {
        Rgb::ZERO
    }

    pub(crate) fn pdf(&self, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, _u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        self.sample_delta(wo, u_lobe, mode)
    }

    pub(crate) fn delta_probability(&self, _wo: Vec3) -> f32 {
        1.0
    }

    pub(crate) fn sample_delta(&self, wo: Vec3, u: f32, _mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let r = self.reflectance(wo);
        if u < r {
            return Some(BsdfSample::mirror(wo, r, self.reflect_tint));
        }
        // Negation is exact: the path goes on in its own direction, and
        // integrators can tell the crossing by `wi == −wo`.
        let wi = -wo;
        Some(BsdfSample {
            wi,
            f: self.transmit_tint * ((1.0 - r) / wi.z.abs()),
            pdf: 1.0 - r,
            delta: true,
            eta: 1.0,
        })
    }

    pub(crate) fn has_smooth(&self) -> bool {
        false
    }

    pub(crate) fn albedo(&self) -> Rgb {
        self.transmit_tint.max(self.reflect_tint).min(Rgb::ONE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::bsdf::reflect_local;

    #[test]
    fn a_sheet_conserves_energy_and_the_null_sheet_lets_everything_through() {
        let glass = ThinBsdf {
            eta: 1.5,
            ..ThinBsdf::NULL
        };
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let (mut reflected, mut crossed) = (0.0, 0.0);
        for i in 0..1000 {
            let s = glass
                .sample_delta(wo, (i as f32 + 0.5) / 1000.0, TransportMode::Radiance)
                .unwrap();
            let w = s.weight().x / 1000.0;
            if s.wi == -wo {
                crossed += w;
            } else {
                assert_eq!(s.wi, reflect_local(wo));
                reflected += w;
            }
        }
        assert!((reflected + crossed - 1.0).abs() < 1e-4);
        // At normal incidence R = 0.04 and R' = 2R/(1 + R) = 0.0769.
        let r = 1.0 - glass.pass_through(Vec3::Z).x;
        assert!((r - 0.08 / 1.04).abs() < 1e-5, "{r}");
        assert!((crossed - glass.pass_through(wo).x).abs() < 2e-3);
        let s = ThinBsdf::NULL.sample_delta(wo, 0.999, TransportMode::Radiance).unwrap();
        assert_eq!((s.wi, s.weight()), (-wo, Rgb::ONE));
        assert_eq!(ThinBsdf::NULL.pass_through(wo), Rgb::ONE);
    }
}
