//! Mitsuba's `blendbsdf` evaluated exactly: the BSDF (1 − w)·f₀ + w·f₁ of
//! two BSDFs, each with its own textures. A sample comes from one of them,
//! chosen with probability 1 − w or w, and is weighted by the blend's value
//! over the mixture of both densities (as a BSDF of several lobes is), so
//! that `eval`, `pdf` and `sample` agree; next-event estimation evaluates
//! both, which is what makes it less noisy than choosing one BSDF per
//! shading point.

use super::bsdf::{Bsdf, BsdfSample, TransportMode};
use crate::color::Rgb;
use crate::sampling::rng::ONE_MINUS_EPSILON;
use glam::{Vec2, Vec3};

/// Two BSDFs blended by a weight (neither itself a blend).
#[derive(Clone, Copy, Debug)]
pub struct BlendBsdf<'a> {
    /// The share of `parts[1]`, in [0, 1].
    pub weight: f32,
    /// The two BSDFs, held by the caller for as long as the blend is used.
    pub parts: &'a [Bsdf<'a>; 2],
}

// The methods call the parts' through `Bsdf`'s dispatch: kept out of line,
// so that the recursion does not stop `Bsdf`'s methods from inlining.
impl BlendBsdf<'_> {
    /// The two parts' shares.
    #[inline]
    fn shares(&self) -> [f32; 2] {
        [1.0 - self.weight, self.weight]
    }

    #[inline(never)]
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        let [s0, s1] = self.shares();
        self.parts[0].eval(wo, wi, mode) * s0 + self.parts[1].eval(wo, wi, mode) * s1
    }

    #[inline(never)]
    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let [s0, s1] = self.shares();
        s0 * self.parts[0].pdf(wo, wi) + s1 * self.parts[1].pdf(wo, wi)
    }

    #[inline(never)]
    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let w = self.weight;
        let (k, u_part) = if u_lobe < w {
            (1, u_lobe / w)
        } else {
            (0, (u_lobe - w) / (1.0 - w))
        };
        let share = self.shares()[k];
        let mut s = self.parts[k].sample(wo, u_part.min(ONE_MINUS_EPSILON), u, mode)?;
        if s.delta {
            // The part's delta lobe, chosen with probability `share`, in a
            // BSDF that holds `share` of it: the weight is the part's.
            s.f *= share;
            s.pdf *= share;
        } else {
            s.f = self.eval(wo, s.wi, mode);
            s.pdf = self.pdf(wo, s.wi);
        }
        Some(s)
    }

    #[inline(never)]
    pub(crate) fn delta_probability(&self, wo: Vec3) -> f32 {
        let [s0, s1] = self.shares();
        s0 * self.parts[0].delta_probability(wo) + s1 * self.parts[1].delta_probability(wo)
    }

    /// A delta lobe of either part, each in proportion to its share of the
    /// blend's delta probability (so that, scaled by that probability as
    /// [`Bsdf::sample_with`] scales it, the density is that of `sample`).
    #[inline(never)]
    pub(crate) fn sample_delta(&self, wo: Vec3, u: f32, mode: TransportMode) -> Option<BsdfSample> {
        let shares = self.shares();
        let p = [0, 1].map(|k| shares[k] * self.parts[k].delta_probability(wo));
        let total = p[0] + p[1];
        if total <= 0.0 {
            return None;
        }
        let q1 = p[1] / total;
        let (k, u_part) = if u < q1 {
            (1, u / q1)
        } else {
            (0, (u - q1) / (1.0 - q1))
        };
        let mut s = self.parts[k].sample_delta(wo, u_part.min(ONE_MINUS_EPSILON), mode)?;
        s.f *= shares[k];
        s.pdf *= p[k] / total;
        Some(s)
    }

    #[inline(never)]
    pub(crate) fn has_smooth(&self) -> bool {
        let [s0, s1] = self.shares();
        (s0 > 0.0 && self.parts[0].has_smooth()) || (s1 > 0.0 && self.parts[1].has_smooth())
    }

    #[inline(never)]
    pub(crate) fn has_smooth_transmission(&self) -> bool {
        self.parts.iter().any(Bsdf::has_smooth_transmission)
    }

    #[inline(never)]
    pub(crate) fn transmits(&self) -> bool {
        self.parts.iter().any(Bsdf::transmits)
    }

    #[inline(never)]
    pub(crate) fn pass_through(&self, wo: Vec3) -> Rgb {
        let [s0, s1] = self.shares();
        self.parts[0].pass_through(wo) * s0 + self.parts[1].pass_through(wo) * s1
    }

    #[inline(never)]
    pub(crate) fn passed_through(&self, wo: Vec3, s: &BsdfSample) -> bool {
        self.parts.iter().any(|p| p.passed_through(wo, s))
    }

    #[inline(never)]
    pub(crate) fn albedo(&self) -> Rgb {
        let [s0, s1] = self.shares();
        self.parts[0].albedo() * s0 + self.parts[1].albedo() * s1
    }
}
