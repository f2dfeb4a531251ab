//! Materials: how surfaces reflect, transmit and emit light.
//!
//! A material is one of the classical ray-tracing course's material record
//! ([`MaterialKind::Classic`]: diffuse and specular colour, Phong exponent,
//! mirror reflectivity, transmission with an index of refraction) or a
//! physically based model (diffuse, conductor, dielectric, plastic). Every
//! material answers to both integrators: the Whitted ray tracer reads its
//! classical parameters ([`Material::classic`]), the path tracer its BSDF
//! ([`Material::bsdf`]).
//!
//! ```toml
//! [[material]]
//! name = "glass"
//! type = "dielectric"
//! ior = 1.5
//! roughness = 0.0
//! ```

pub mod bsdf;
pub mod classic;
pub mod conductor;
pub mod dielectric;
pub mod frame;
pub mod lambert;
pub mod microfacet;
pub mod optics;
pub mod phong;
pub mod plastic;
pub mod thin;

pub use bsdf::{Bsdf, BsdfSample, DirectionSampling, TransportMode};
pub use frame::Frame;

use crate::color::Rgb;
use crate::texture::{ImageTexture, TexCoord, Texture};
use classic::ClassicBsdf;
use conductor::{ConductorBsdf, ConductorFresnel};
use dielectric::DielectricBsdf;
use lambert::LambertBsdf;
pub use microfacet::{Microfacet, MicrofacetDistribution};
use plastic::{CoatTables, PlasticBsdf};
use thin::ThinBsdf;

/// The scattering model of a material.
#[derive(Clone, Debug, PartialEq)]
pub enum MaterialKind {
    /// The classical material record.
    Classic {
        /// Diffuse colour kd.
        diffuse: Texture,
        /// Phong specular colour ks.
        specular: Texture,
        /// Phong exponent s.
        shininess: f32,
        /// Mirror reflectivity kr.
        reflectivity: Rgb,
        /// Transmission kt.
        transmission: Rgb,
        /// Index of refraction of the inside.
        ior: f32,
    },
    /// Lambertian reflection.
    Diffuse {
        /// Albedo.
        reflectance: Texture,
    },
    /// A metal (or an ideal mirror), smooth or rough.
    Conductor {
        /// Reflectance model.
        fresnel: ConductorFresnel,
        /// Colour multiplier.
        tint: Rgb,
        /// Microfacet roughness along the tangent and the bitangent.
        microfacet: Microfacet,
    },
    /// Glass, smooth or rough.
    Dielectric {
        /// Relative index of refraction, inside over outside.
        eta: f32,
        /// Microfacet roughness.
        microfacet: Microfacet,
        /// Reflection multiplier.
        reflect_tint: Rgb,
        /// Transmission multiplier.
        transmit_tint: Rgb,
    },
    /// A diffuse base under a dielectric coat.
    Plastic {
        /// Base colour.
        diffuse: Texture,
        /// Relative index of refraction of the coat.
        eta: f32,
        /// Microfacet roughness of the coat (isotropic).
        microfacet: Microfacet,
        /// Coat reflection multiplier.
        specular_tint: Rgb,
        /// Whether internal scattering saturates the colour.
        nonlinear: bool,
        /// Share of samples given to the coat.
        specular_weight: f32,
        /// Internal reflectance of the smooth coat.
        smooth_internal_reflectance: f32,
        /// Tables of the rough coat (`None` when smooth).
        tables: Option<Box<CoatTables>>,
    },
    /// A thin dielectric sheet (index 1: no surface, only the boundary of
    /// a medium).
    Thin {
        /// Index of the sheet relative to its surroundings.
        eta: f32,
        /// Reflection multiplier.
        reflect_tint: Rgb,
        /// Transmission multiplier.
        transmit_tint: Rgb,
    },
}

/// A surface material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// How it scatters light.
    pub kind: MaterialKind,
    /// Emitted radiance, from the front side.
    pub emission: Texture,
    /// Whether the back side scatters like the front (false: the back of
    /// an opaque surface is black, as Mitsuba's one-sided BSDFs).
    pub two_sided: bool,
    /// A cut-out mask: the probability (first channel) that light meets
    /// the surface rather than passing it unchanged; `None`: opaque.
    pub opacity: Option<Texture>,
}

/// The classical parameters that the Whitted integrator reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClassicParams {
    /// Diffuse colour kd.
    pub kd: Rgb,
    /// Specular colour ks.
    pub ks: Rgb,
    /// Phong exponent.
    pub shininess: f32,
    /// Mirror reflectivity kr.
    pub kr: Rgb,
    /// Transmission kt.
    pub kt: Rgb,
    /// Index of refraction.
    pub ior: f32,
}

impl Default for Material {
    fn default() -> Self {
        Material::new_classic(
            Texture::Constant(Rgb::splat(0.5)),
            Texture::Constant(Rgb::ZERO),
            0.0,
            Rgb::ZERO,
            Rgb::ZERO,
            1.0,
        )
    }
}

/// The Phong exponent whose lobe is about as wide as a GGX lobe of
/// roughness α (Walter et al. 2007: s = 2/α² − 2).
pub fn phong_exponent_for_alpha(alpha: f32) -> f32 {
    (2.0 / (alpha * alpha).max(1e-6) - 2.0).clamp(1.0, 10_000.0)
}

/// A diffuse material's BSDF: Lambert with the reflectance at `tc`.
#[inline(always)]
fn diffuse_bsdf<'a>(reflectance: &Texture, images: &[ImageTexture], tc: &TexCoord) -> Bsdf<'a> {
    Bsdf::Lambert(LambertBsdf {
        albedo: reflectance.eval(images, tc),
    })
}

impl Material {
    /// A classical material; a [`MaterialKind::Diffuse`] one where only
    /// the diffuse colour is not zero.
    pub fn new_classic(
        diffuse: Texture,
        specular: Texture,
        shininess: f32,
        reflectivity: Rgb,
        transmission: Rgb,
        ior: f32,
    ) -> Material {
        // With only its diffuse lobe a classical material is Lambertian,
        // and the same BSDF to the bit (the lobe choice has probability
        // 1): built as `Diffuse`, it skips the lobe selection and the
        // Phong terms at every bounce. The built-in default scene is all
        // such materials. A black one stays classical, which has no lobe
        // to sample (no light sampling at a black lamp, say).
        let zero = Texture::Constant(Rgb::ZERO);
        if diffuse != zero && specular == zero && reflectivity == Rgb::ZERO && transmission == Rgb::ZERO {
            return Material {
                kind: MaterialKind::Diffuse { reflectance: diffuse },
                emission: Texture::Constant(Rgb::ZERO),
                two_sided: true,
                opacity: None,
            };
        }
        Material {
            kind: MaterialKind::Classic {
                diffuse,
                specular,
                shininess,
                reflectivity,
                transmission,
                ior,
            },
            emission: Texture::Constant(Rgb::ZERO),
            two_sided: true,
            opacity: None,
        }
    }

    /// A plain diffuse (classical) material.
    pub fn diffuse(color: Rgb) -> Material {
        Material::new_classic(
            Texture::Constant(color),
            Texture::Constant(Rgb::ZERO),
            0.0,
            Rgb::ZERO,
            Rgb::ZERO,
            1.0,
        )
    }

    /// A plastic material; precomputes the coat tables when rough.
    pub fn plastic(
        diffuse: Texture,
        eta: f32,
        microfacet: Microfacet,
        specular_tint: Rgb,
        nonlinear: bool,
        images: &[ImageTexture],
    ) -> Material {
        let d_mean = {
            let a = diffuse.average(images);
            (a.x + a.y + a.z) / 3.0
        };
        let s_mean = (specular_tint.x + specular_tint.y + specular_tint.z) / 3.0;
        let specular_weight = if d_mean + s_mean > 0.0 {
            s_mean / (d_mean + s_mean)
        } else {
            0.5
        };
        Material {
            kind: MaterialKind::Plastic {
                diffuse,
                eta,
                microfacet,
                specular_tint,
                nonlinear,
                specular_weight,
                smooth_internal_reflectance: plastic::smooth_internal_reflectance(eta),
                tables: (!microfacet.is_smooth()).then(|| Box::new(CoatTables::new(&microfacet, eta))),
            },
            emission: Texture::Constant(Rgb::ZERO),
            two_sided: true,
            opacity: None,
        }
    }

    /// Whether light passes through the surface.
    #[inline]
    pub fn is_transmissive(&self) -> bool {
        match &self.kind {
            MaterialKind::Classic { transmission, .. } => *transmission != Rgb::ZERO,
            MaterialKind::Dielectric { .. } | MaterialKind::Thin { .. } => true,
            _ => false,
        }
    }

    /// Whether any of its textures reads surface coordinates (u, v).
    pub fn reads_uv(&self) -> bool {
        let textures: &[&Texture] = match &self.kind {
            MaterialKind::Classic { diffuse, specular, .. } => &[diffuse, specular],
            MaterialKind::Diffuse { reflectance } => &[reflectance],
            MaterialKind::Plastic { diffuse, .. } => &[diffuse],
            MaterialKind::Conductor { .. } | MaterialKind::Dielectric { .. } | MaterialKind::Thin { .. } => &[],
        };
        self.emission.reads_uv()
            || self.opacity.as_ref().is_some_and(|o| o.reads_uv())
            || textures.iter().any(|t| t.reads_uv())
    }

    /// The opacity at a point (1 where the material has no mask).
    #[inline]
    pub fn opacity_at(&self, images: &[ImageTexture], tc: &TexCoord) -> f32 {
        self.opacity
            .as_ref()
            .map_or(1.0, |o| o.eval(images, tc).x.clamp(0.0, 1.0))
    }

    /// Whether the surface emits.
    #[inline]
    pub fn is_emissive(&self) -> bool {
        self.emission != Texture::Constant(Rgb::ZERO)
    }

    /// Emitted radiance at a point (front side).
    #[inline]
    pub fn emission_at(&self, images: &[ImageTexture], tc: &TexCoord) -> Rgb {
        self.emission.eval(images, tc)
    }

    /// The classical parameters at a point: the record itself for classic
    /// materials, the nearest classical equivalent for the others.
    pub fn classic(&self, images: &[ImageTexture], tc: &TexCoord) -> ClassicParams {
        let zero = ClassicParams {
            kd: Rgb::ZERO,
            ks: Rgb::ZERO,
            shininess: 0.0,
            kr: Rgb::ZERO,
            kt: Rgb::ZERO,
            ior: 1.0,
        };
        match &self.kind {
            MaterialKind::Classic {
                diffuse,
                specular,
                shininess,
                reflectivity,
                transmission,
                ior,
            } => ClassicParams {
                kd: diffuse.eval(images, tc),
                ks: specular.eval(images, tc),
                shininess: *shininess,
                kr: *reflectivity,
                kt: *transmission,
                ior: *ior,
            },
            MaterialKind::Diffuse { reflectance } => ClassicParams {
                kd: reflectance.eval(images, tc),
                ..zero
            },
            MaterialKind::Conductor {
                fresnel,
                tint,
                microfacet,
            } => {
                let f0 = *tint * fresnel.eval(1.0);
                let a = microfacet.alpha_x.max(microfacet.alpha_y);
                if microfacet.is_smooth() {
                    ClassicParams { kr: f0, ..zero }
                } else {
                    ClassicParams {
                        ks: f0,
                        shininess: phong_exponent_for_alpha(a),
                        ..zero
                    }
                }
            }
            MaterialKind::Dielectric { eta, transmit_tint, .. } => ClassicParams {
                kt: *transmit_tint,
                ior: *eta,
                ..zero
            },
            MaterialKind::Plastic {
                diffuse,
                eta,
                microfacet,
                specular_tint,
                ..
            } => {
                let f0 = optics::fresnel_dielectric(1.0, *eta);
                let alpha = microfacet.alpha_x;
                let smooth = microfacet.is_smooth();
                ClassicParams {
                    kd: diffuse.eval(images, tc),
                    ks: *specular_tint * f0,
                    shininess: if smooth {
                        1000.0
                    } else {
                        phong_exponent_for_alpha(alpha)
                    },
                    kr: if smooth { *specular_tint * f0 } else { Rgb::ZERO },
                    ..zero
                }
            }
            MaterialKind::Thin {
                eta,
                reflect_tint,
                transmit_tint,
            } => {
                // Reflection and transmission at normal incidence; the
                // sheet does not bend rays (index 1).
                let t = ThinBsdf {
                    eta: *eta,
                    reflect_tint: Rgb::ONE,
                    transmit_tint: Rgb::ONE,
                }
                .pass_through(glam::Vec3::Z);
                ClassicParams {
                    kr: *reflect_tint * (1.0 - t.x),
                    kt: *transmit_tint * t,
                    ior: 1.0,
                    ..zero
                }
            }
        }
    }

    /// The BSDF at a point. A diffuse material's is built in place, without
    /// a call: it is the commonest material, its BSDF is one texture look-up,
    /// and inlined the BSDF needs no trip through memory.
    #[inline(always)]
    pub fn bsdf<'a>(&'a self, images: &[ImageTexture], tc: &TexCoord) -> Bsdf<'a> {
        match &self.kind {
            MaterialKind::Diffuse { reflectance } => diffuse_bsdf(reflectance, images, tc),
            _ => self.bsdf_other(images, tc),
        }
    }

    /// [`Material::bsdf`] of the materials other than diffuse.
    fn bsdf_other<'a>(&'a self, images: &[ImageTexture], tc: &TexCoord) -> Bsdf<'a> {
        match &self.kind {
            MaterialKind::Classic { .. } => {
                let c = self.classic(images, tc);
                Bsdf::Classic(ClassicBsdf::new(c.kd, c.ks, c.shininess, c.kr, c.kt, c.ior))
            }
            MaterialKind::Diffuse { reflectance } => diffuse_bsdf(reflectance, images, tc),
            MaterialKind::Conductor {
                fresnel,
                tint,
                microfacet,
            } => Bsdf::Conductor(ConductorBsdf {
                fresnel: *fresnel,
                tint: *tint,
                microfacet: *microfacet,
            }),
            MaterialKind::Dielectric {
                eta,
                microfacet,
                reflect_tint,
                transmit_tint,
            } => Bsdf::Dielectric(DielectricBsdf {
                eta: *eta,
                microfacet: *microfacet,
                reflect_tint: *reflect_tint,
                transmit_tint: *transmit_tint,
            }),
            MaterialKind::Plastic {
                diffuse,
                eta,
                microfacet,
                specular_tint,
                nonlinear,
                specular_weight,
                smooth_internal_reflectance,
                tables,
            } => Bsdf::Plastic(PlasticBsdf {
                diffuse: diffuse.eval(images, tc),
                eta: *eta,
                microfacet: *microfacet,
                specular_tint: *specular_tint,
                nonlinear: *nonlinear,
                specular_weight: *specular_weight,
                smooth_internal_reflectance: *smooth_internal_reflectance,
                tables: tables.as_deref(),
            }),
            MaterialKind::Thin {
                eta,
                reflect_tint,
                transmit_tint,
            } => Bsdf::Thin(ThinBsdf {
                eta: *eta,
                reflect_tint: *reflect_tint,
                transmit_tint: *transmit_tint,
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;
    use crate::sampling::warp::sample_sphere_uniform;
    use glam::{Vec2, Vec3};

    fn classic(diffuse: Rgb, specular: Rgb, reflectivity: Rgb, transmission: Rgb) -> Material {
        Material::new_classic(
            Texture::Constant(diffuse),
            Texture::Constant(specular),
            20.0,
            reflectivity,
            transmission,
            1.5,
        )
    }

    #[test]
    fn only_a_diffuse_classical_material_becomes_lambertian() {
        let (kd, some) = (Rgb::new(0.8, 0.5, 0.2), Rgb::splat(0.3));
        let z = Rgb::ZERO;
        assert!(matches!(classic(kd, z, z, z).kind, MaterialKind::Diffuse { .. }));
        assert!(matches!(Material::diffuse(kd).kind, MaterialKind::Diffuse { .. }));
        for m in [
            classic(kd, some, z, z),
            classic(kd, z, some, z),
            classic(kd, z, z, some),
            classic(z, z, z, z),
        ] {
            assert!(matches!(m.kind, MaterialKind::Classic { .. }), "{:?}", m.kind);
        }
    }

    /// Lambert's sampling ignores the lobe choice, which integrators then
    /// pass over drawing; the other BSDFs say they read it.
    #[test]
    fn only_lambert_ignores_the_lobe_choice() {
        let tc = TexCoord {
            uv: Vec2::ZERO,
            p: Vec3::ZERO,
        };
        let lambert = Material::diffuse(Rgb::new(0.5, 0.6, 0.7));
        let lambert = lambert.bsdf(&[], &tc);
        assert!(!lambert.reads_lobe_choice());
        let mut rng = Pcg32::new(1, 2);
        for _ in 0..1000 {
            let wo = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            for strategy in [
                DirectionSampling::Uniform,
                DirectionSampling::Cosine,
                DirectionSampling::Bsdf,
            ] {
                let mode = TransportMode::Radiance;
                let a = lambert.sample_with(strategy, wo, 0.0, u, mode);
                let b = lambert.sample_with(strategy, wo, 0.999, u, mode);
                assert_eq!(a.map(|s| (s.wi, s.f, s.pdf)), b.map(|s| (s.wi, s.f, s.pdf)));
            }
        }
        let classic = classic(Rgb::splat(0.4), Rgb::splat(0.3), Rgb::ZERO, Rgb::ZERO);
        assert!(classic.bsdf(&[], &tc).reads_lobe_choice());
    }

    /// The claim that lets a diffuse-only classical material be built as
    /// `Diffuse`: its classical BSDF gives the same bits in every query.
    #[test]
    fn diffuse_only_classical_bsdf_equals_lambert_bit_for_bit() {
        let mut rng = Pcg32::new(7, 3);
        let tc = TexCoord {
            uv: Vec2::ZERO,
            p: Vec3::ZERO,
        };
        for kd in [Rgb::new(0.8, 0.5, 0.2), Rgb::new(0.05, 0.9, 1.0), Rgb::splat(1e-3)] {
            let material = Material::diffuse(kd);
            let lambert = material.bsdf(&[], &tc);
            let classical = Bsdf::Classic(ClassicBsdf::new(kd, Rgb::ZERO, 20.0, Rgb::ZERO, Rgb::ZERO, 1.5));
            assert!(matches!(lambert, Bsdf::Lambert(_)));
            assert_eq!(lambert.has_smooth(), classical.has_smooth());
            assert_eq!(lambert.transmits(), classical.transmits());
            assert_eq!(lambert.albedo(), classical.albedo());
            for _ in 0..2000 {
                let wo = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
                let wi = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
                let mode = TransportMode::Radiance;
                assert_eq!(lambert.eval(wo, wi, mode), classical.eval(wo, wi, mode));
                assert_eq!(lambert.pdf(wo, wi).to_bits(), classical.pdf(wo, wi).to_bits());
                assert_eq!(lambert.delta_probability(wo), classical.delta_probability(wo));
                let (u_lobe, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
                for strategy in [
                    DirectionSampling::Uniform,
                    DirectionSampling::Cosine,
                    DirectionSampling::Bsdf,
                ] {
                    let a = lambert.sample_with(strategy, wo, u_lobe, u, mode);
                    let b = classical.sample_with(strategy, wo, u_lobe, u, mode);
                    match (a, b) {
                        (None, None) => {}
                        (Some(a), Some(b)) => {
                            assert_eq!(a.wi, b.wi);
                            assert_eq!(a.f, b.f);
                            assert_eq!(a.pdf.to_bits(), b.pdf.to_bits());
                            assert_eq!((a.delta, a.eta), (b.delta, b.eta));
                        }
                        _ => panic!("one sampled and the other did not: wo {wo}, u {u}"),
                    }
                }
            }
        }
    }
}
