//! The BSDF interface: every scattering model evaluates, samples and gives
//! the density of directions in the local shading frame (normal = +z), with
//! both directions pointing away from the surface (`wo` toward the viewer,
//! `wi` toward the light).
//!
//! Delta lobes (perfect mirrors, smooth glass) have no density: their
//! samples carry `delta = true`, the discrete probability of the lobe as
//! `pdf`, and `f` scaled so that `f·|cos θi|/pdf` is the right weight; `eval`
//! and `pdf` ignore them.

use super::blend::BlendBsdf;
use super::classic::ClassicBsdf;
use super::conductor::ConductorBsdf;
use super::dielectric::DielectricBsdf;
use super::hair::HairBsdf;
use super::lambert::LambertBsdf;
use super::layered::LayeredBsdf;
use super::measured::MeasuredBsdf;
use super::plastic::PlasticBsdf;
use super::principled::PrincipledBsdf;
use super::thin::ThinBsdf;
use crate::color::Rgb;
use crate::sampling::warp::{
    pdf_hemisphere_cosine, pdf_hemisphere_uniform, pdf_sphere_uniform, sample_hemisphere_cosine,
    sample_hemisphere_uniform, sample_sphere_uniform,
};
use glam::{Vec2, Vec3};

/// Whether a path carries radiance (from the camera) or importance (from
/// the lights, as in photon mapping): refraction scales them differently.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TransportMode {
    /// Paths traced from the camera.
    #[default]
    Radiance,
    /// Paths traced from the lights.
    Importance,
}

/// A sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// The sampled direction (local frame, unit length).
    pub wi: Vec3,
    /// BSDF value for (wo, wi).
    pub f: Rgb,
    /// Density per solid angle, or the lobe's probability for delta lobes.
    pub pdf: f32,
    /// Whether the direction came from a delta lobe.
    pub delta: bool,
    /// Relative index of refraction crossed (1 for reflection).
    pub eta: f32,
}

impl BsdfSample {
    /// The mirror reflection of `wo`, chosen with probability `p` (a
    /// Fresnel reflectance) and carrying `tint`: a delta lobe of weight
    /// `tint`.
    #[inline]
    pub(crate) fn mirror(wo: Vec3, p: f32, tint: crate::color::Rgb) -> BsdfSample {
        let wi = reflect_local(wo);
        BsdfSample {
            wi,
            f: tint * (p / wi.z.abs()),
            pdf: p,
            delta: true,
            eta: 1.0,
        }
    }

    /// The Monte Carlo weight f·|cos θi|/pdf.
    #[inline]
    pub fn weight(&self) -> Rgb {
        self.f * (self.wi.z.abs() / self.pdf)
    }
}

/// How the smooth (non-delta) part of a BSDF is sampled: by the BSDF's own
/// importance sampling, or by the textbook hemisphere distributions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DirectionSampling {
    /// The BSDF's own importance sampling.
    Bsdf,
    /// Uniform over the hemisphere (pdf 1/2π), or the sphere (1/4π) for
    /// surfaces that transmit diffusely or glossily.
    Uniform,
    /// Cosine-weighted over the hemisphere (pdf cos θ/π), each hemisphere
    /// with probability ½ for surfaces that transmit.
    Cosine,
}

/// A BSDF at one surface point, with its textures already evaluated.
#[derive(Clone, Copy, Debug)]
pub enum Bsdf<'a> {
    /// Lambertian diffuse reflection.
    Lambert(LambertBsdf),
    /// Lambertian reflection and transmission.
    DiffuseTransmission(super::diffuse_transmission::DiffuseTransmissionBsdf),
    /// The classical material: diffuse + Phong + mirror + glass lobes.
    Classic(ClassicBsdf),
    /// Smooth or rough (GGX) metal.
    Conductor(ConductorBsdf),
    /// Smooth or rough (GGX) glass.
    Dielectric(DielectricBsdf),
    /// A diffuse base under a smooth or rough dielectric coat.
    Plastic(PlasticBsdf<'a>),
    /// A thin dielectric sheet, or (of index 1) no surface at all.
    Thin(ThinBsdf),
    /// pbrt-v4's stochastic layered BSDF: a dielectric coat over a diffuse
    /// or conductor base.
    Layered(LayeredBsdf),
    /// Disney's principled BSDF, as Mitsuba 3 evaluates it.
    Principled(PrincipledBsdf),
    /// Two BSDFs blended by a weight (Mitsuba's `blendbsdf`).
    Blend(BlendBsdf<'a>),
    /// A measured BRDF.
    Measured(MeasuredBsdf<'a>),
    /// Hair fibres.
    Hair(HairBsdf),
}

macro_rules! dispatch {
    ($self:expr, $b:ident => $e:expr) => {
        match $self {
            Bsdf::Lambert($b) => $e,
            Bsdf::DiffuseTransmission($b) => $e,
            Bsdf::Classic($b) => $e,
            Bsdf::Conductor($b) => $e,
            Bsdf::Dielectric($b) => $e,
            Bsdf::Plastic($b) => $e,
            Bsdf::Thin($b) => $e,
            Bsdf::Layered($b) => $e,
            Bsdf::Principled($b) => $e,
            Bsdf::Blend($b) => $e,
            Bsdf::Measured($b) => $e,
            Bsdf::Hair($b) => $e,
        }
    };
}

impl Bsdf<'_> {
    /// The BSDF value f(wo, wi) of the non-delta lobes.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        dispatch!(self, b => b.eval(wo, wi, mode))
    }

    /// Density with which [`Bsdf::sample`] picks `wi` through its non-delta lobes.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch!(self, b => b.pdf(wo, wi))
    }

    /// Samples a direction by the BSDF's own importance sampling; `u_lobe`
    /// picks a lobe, `u` the direction within it.
    #[inline]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        dispatch!(self, b => b.sample(wo, u_lobe, u, mode))
    }

    /// Probability that [`Bsdf::sample`] picks a delta lobe for `wo`.
    #[inline]
    pub fn delta_probability(&self, wo: Vec3) -> f32 {
        dispatch!(self, b => b.delta_probability(wo))
    }

    /// Samples only the delta lobes (pdf relative to them alone).
    #[inline]
    pub fn sample_delta(&self, wo: Vec3, u_lobe: f32, mode: TransportMode) -> Option<BsdfSample> {
        dispatch!(self, b => b.sample_delta(wo, u_lobe, mode))
    }

    /// Whether some lobe has a density (so light sampling can help).
    #[inline]
    pub fn has_smooth(&self) -> bool {
        dispatch!(self, b => b.has_smooth())
    }

    /// Whether [`Bsdf::sample`] and [`Bsdf::sample_with`] read their lobe
    /// choice `u_lobe`: all but Lambert's single lobe do.
    #[inline]
    pub fn reads_lobe_choice(&self) -> bool {
        !matches!(self, Bsdf::Lambert(_))
    }

    /// Whether a non-delta lobe transmits (glossy or diffuse transmission).
    #[inline]
    pub fn has_smooth_transmission(&self) -> bool {
        match self {
            Bsdf::Dielectric(d) => d.has_smooth(),
            Bsdf::DiffuseTransmission(_) | Bsdf::Hair(_) => true,
            Bsdf::Principled(p) => p.transmits(),
            Bsdf::Blend(b) => b.has_smooth_transmission(),
            _ => false,
        }
    }

    /// Whether light can pass through the surface.
    #[inline]
    pub fn transmits(&self) -> bool {
        match self {
            Bsdf::Dielectric(_) | Bsdf::Thin(_) | Bsdf::DiffuseTransmission(_) | Bsdf::Hair(_) => true,
            Bsdf::Classic(c) => c.kt != Rgb::ZERO,
            Bsdf::Principled(p) => p.transmits(),
            Bsdf::Blend(b) => b.transmits(),
            _ => false,
        }
    }

    /// The weight of light that crosses the surface along `wo` without
    /// changing direction (a thin sheet's transmission; the whole of it
    /// for a surface that is not there); zero for every other BSDF.
    /// Volumetric shadow rays go through such surfaces with this weight.
    #[inline]
    pub fn pass_through(&self, wo: Vec3) -> Rgb {
        match self {
            Bsdf::Thin(t) => t.pass_through(wo),
            Bsdf::Blend(b) => b.pass_through(wo),
            _ => Rgb::ZERO,
        }
    }

    /// Whether `s`, sampled from this BSDF for `wo`, crossed the surface
    /// without changing direction (see [`Bsdf::pass_through`]).
    #[inline]
    pub fn passed_through(&self, wo: Vec3, s: &BsdfSample) -> bool {
        match self {
            Bsdf::Thin(_) => s.wi == -wo,
            Bsdf::Blend(b) => b.passed_through(wo, s),
            _ => false,
        }
    }

    /// An estimate of the surface's colour (its reflectance at normal
    /// incidence), for the albedo image that denoisers use.
    pub fn albedo(&self) -> Rgb {
        dispatch!(self, b => b.albedo())
    }

    /// Samples with the given strategy: delta lobes always by their own
    /// sampling (a random direction never finds a delta peak), the rest by
    /// the strategy.
    pub fn sample_with(
        &self,
        strategy: DirectionSampling,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        if strategy == DirectionSampling::Bsdf {
            return self.sample(wo, u_lobe, u, mode);
        }
        let p_delta = self.delta_probability(wo);
        if u_lobe < p_delta {
            let mut s = self.sample_delta(wo, u_lobe / p_delta, mode)?;
            s.pdf *= p_delta;
            return Some(s);
        }
        let u_rest = ((u_lobe - p_delta) / (1.0 - p_delta)).min(crate::sampling::rng::ONE_MINUS_EPSILON);
        let side = if wo.z < 0.0 { -1.0 } else { 1.0 };
        let (wi, pdf) = if self.has_smooth_transmission() {
            match strategy {
                DirectionSampling::Uniform => (sample_sphere_uniform(u), pdf_sphere_uniform()),
                _ => {
                    let w = sample_hemisphere_cosine(u);
                    let s = if u_rest < 0.5 { 1.0 } else { -1.0 };
                    let w = Vec3::new(w.x, w.y, w.z * s);
                    (w, 0.5 * pdf_hemisphere_cosine(w.z.abs()))
                }
            }
        } else {
            match strategy {
                DirectionSampling::Uniform => {
                    let w = sample_hemisphere_uniform(u);
                    (Vec3::new(w.x, w.y, w.z * side), pdf_hemisphere_uniform())
                }
                _ => {
                    let w = sample_hemisphere_cosine(u);
                    (Vec3::new(w.x, w.y, w.z * side), pdf_hemisphere_cosine(w.z))
                }
            }
        };
        if pdf <= 0.0 || wi.z == 0.0 {
            return None; // on the horizon: no light either way
        }
        let eta = if wi.z * wo.z < 0.0 {
            match self {
                Bsdf::Dielectric(d) if wo.z > 0.0 => d.eta,
                Bsdf::Dielectric(d) => 1.0 / d.eta,
                _ => 1.0,
            }
        } else {
            1.0
        };
        Some(BsdfSample {
            wi,
            f: self.eval(wo, wi, mode),
            pdf: (1.0 - p_delta) * pdf,
            delta: false,
            eta,
        })
    }
}

/// Mirrors a direction into the upper hemisphere's frame: reflection-only
/// BSDFs are two-sided by evaluating the lower side as a mirror image.
#[inline]
pub(crate) fn flip_z(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.y, -v.z)
}

/// Whether two local directions are on the same side of the surface.
#[inline]
pub fn same_hemisphere(a: Vec3, b: Vec3) -> bool {
    a.z * b.z > 0.0
}

/// The direction mirrored about the normal (+z).
#[inline]
pub fn reflect_local(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}
