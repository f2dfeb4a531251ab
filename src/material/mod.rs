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

pub mod blend;
pub mod bsdf;
pub mod classic;
pub mod conductor;
pub mod dielectric;
pub mod diffuse_transmission;
pub mod dispersion;
pub mod frame;
pub mod hair;
pub mod lambert;
pub mod layered;
pub mod measured;
pub mod microfacet;
pub mod optics;
pub mod phong;
pub mod plastic;
pub mod principled;
pub mod thin;

pub use bsdf::{Bsdf, BsdfSample, DirectionSampling, TransportMode};
pub use frame::Frame;

use crate::color::Rgb;
use crate::geometry::SurfaceHit;
use crate::texture::{TexCoord, Texture, TextureStore};
use classic::ClassicBsdf;
use conductor::{ConductorBsdf, ConductorFresnel};
use dielectric::DielectricBsdf;
use glam::Vec3;
use lambert::LambertBsdf;
use layered::{LayerBase, LayeredBsdf};
pub use microfacet::{Microfacet, MicrofacetDistribution};
use plastic::{CoatTables, PlasticBsdf};
use principled::PrincipledParams;
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
    /// Lambertian reflection and Lambertian transmission (pbrt-v4's
    /// `diffusetransmission`, Mitsuba's `difftrans`).
    DiffuseTransmission {
        /// Reflectance R.
        reflectance: Texture,
        /// Transmittance T.
        transmittance: Texture,
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
        /// Relative index of refraction, inside over outside (at the
        /// sodium d line where it disperses).
        eta: f32,
        /// Microfacet roughness.
        microfacet: Microfacet,
        /// Reflection multiplier.
        reflect_tint: Rgb,
        /// Transmission multiplier.
        transmit_tint: Rgb,
        /// The index as it varies with wavelength; `None`: the same at
        /// every wavelength.
        dispersion: Option<Box<dispersion::Dispersion>>,
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
    /// pbrt-v4's layered BSDF: a dielectric coat over a base (see
    /// [`layered`]).
    Layered {
        /// What lies under the coat.
        base: LayerBaseKind,
        /// Index of refraction of the coat, relative to the outside.
        coat_eta: f32,
        /// Roughness of the coat.
        coat: Microfacet,
        /// Thickness of the slab between coat and base.
        thickness: f32,
        /// Single-scattering albedo of the slab's medium.
        albedo: Rgb,
        /// The medium's phase function.
        phase: crate::media::phase::Phase,
        /// Most scattering events of one walk.
        max_depth: u32,
        /// Walks per evaluation.
        samples: u32,
        /// The coat's index as it varies with wavelength; `None`: the
        /// same at every wavelength.
        coat_dispersion: Option<Box<dispersion::Dispersion>>,
    },
    /// Disney's principled BSDF, as Mitsuba 3's `principled`.
    Principled {
        /// Its parameters.
        params: Box<PrincipledParams<Texture>>,
        /// Index of refraction inside, relative to the outside.
        eta: f32,
        /// The thin form (Mitsuba's `principledthin`).
        thin: bool,
    },
    /// Hair fibres (see [`hair`]): meant for curves, whose v runs across
    /// the fibre.
    Hair(hair::HairParams),
    /// A measured BRDF (an RGL `.bsdf` file; see [`measured`]).
    Measured {
        /// Its tables, shared by the materials that name the same file.
        brdf: std::sync::Arc<measured::MeasuredBrdf>,
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
        /// The sheet's index as it varies with wavelength; `None`: the
        /// same at every wavelength.
        dispersion: Option<Box<dispersion::Dispersion>>,
    },
}

/// The base of a layered material.
#[derive(Clone, Debug, PartialEq)]
pub enum LayerBaseKind {
    /// Lambertian.
    Diffuse(Texture),
    /// A conductor, its indices relative to the coat.
    Conductor {
        /// Reflectance model.
        fresnel: ConductorFresnel,
        /// Roughness.
        microfacet: Microfacet,
        /// Roughness that varies over the surface, replacing `microfacet`'s.
        roughness_map: Option<RoughnessMap>,
    },
}

/// A surface material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// How it scatters light.
    pub kind: MaterialKind,
    /// Emitted radiance, from the front side (both with
    /// `emits_both_sides`).
    pub emission: Texture,
    /// Whether the back emits as the front does (pbrt-v4's `twosided`
    /// area lights).
    pub emits_both_sides: bool,
    /// Whether the back side scatters like the front (false: the back of
    /// an opaque surface is black, as Mitsuba's one-sided BSDFs).
    pub two_sided: bool,
    /// A cut-out mask: the probability (first channel) that light meets
    /// the surface rather than passing it unchanged; `None`: opaque.
    pub opacity: Option<Texture>,
    /// A tangent-space normal map; `None`: none.
    pub normal_map: Option<NormalMap>,
    /// A bump map: heights that tilt the shading normal; `None`: none.
    pub bump_map: Option<BumpMap>,
    /// Microfacet roughness that varies over the surface; it replaces the
    /// constant α of a conductor or a dielectric. `None`: constant.
    pub roughness_map: Option<RoughnessMap>,
}

/// A tangent-space normal map: the colour c at a point means the normal
/// (s·(2c_x − 1), ±s·(2c_y − 1), 2c_z − 1), normalised, in the frame of the
/// tangent along u, the bitangent and the shading normal, for the `scale`
/// s. The bitangent is n × tangent (Mitsuba's and pbrt-v4's frame), or,
/// with `bitangent_along_v`, that vector turned toward increasing v: glTF's
/// tangent space (MikkTSpace), whose bitangent follows the texture's v on
/// mirrored texture coordinates too.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMap {
    /// The colours (read raw, without sRGB decoding).
    pub texture: Texture,
    /// Scale of the normal's tangential part (glTF's `normalTexture.scale`).
    pub scale: f32,
    /// Whether the bitangent follows increasing v.
    pub bitangent_along_v: bool,
}

impl NormalMap {
    /// Mitsuba's and pbrt-v4's normal map of `texture`.
    pub fn new(texture: Texture) -> NormalMap {
        NormalMap {
            texture,
            scale: 1.0,
            bitangent_along_v: false,
        }
    }

    /// The mapped normal at `hit` in the local coordinates of `base` (its
    /// frame of tangent, n × tangent and shading normal), or `None` where
    /// a black texel names no direction.
    #[inline]
    fn local_normal(&self, textures: &TextureStore, hit: &SurfaceHit, base: &Frame) -> Option<Vec3> {
        let c = self.texture.eval(textures, &TexCoord::at(hit));
        let mut y = self.scale * (2.0 * c.y - 1.0);
        if self.bitangent_along_v && hit.dpdv.dot(base.t) < 0.0 {
            y = -y;
        }
        Vec3::new(self.scale * (2.0 * c.x - 1.0), y, 2.0 * c.z - 1.0).try_normalize()
    }
}

/// Heights over the surface (a texture's luminance times `scale`) that
/// tilt the shading normal as the displaced surface's would be tilted
/// (Blinn 1978): the derivatives of the height along u and v replace the
/// normal components of dp/du and dp/dv, as Mitsuba's `bumpmap` does.
#[derive(Clone, Debug, PartialEq)]
pub struct BumpMap {
    /// The heights (luminance).
    pub height: Texture,
    /// Height per unit of the texture's value.
    pub scale: f32,
}

impl BumpMap {
    /// The bumped normal at `hit` (world, unit, on the geometric normal's
    /// side), or `None` where the tilted derivatives are parallel.
    #[inline]
    pub fn normal(&self, textures: &TextureStore, hit: &SurfaceHit) -> Option<Vec3> {
        let g = self.height.luminance_gradient(textures, &TexCoord::at(hit)) * self.scale;
        let n = hit.ns;
        let dpdu = hit.dpdu + n * (g.x - n.dot(hit.dpdu));
        let dpdv = hit.dpdv + n * (g.y - n.dot(hit.dpdv));
        let bumped = dpdu.cross(dpdv).try_normalize()?;
        Some(if bumped.dot(hit.ng) < 0.0 { -bumped } else { bumped })
    }
}

/// Roughness read from textures (their first channel) at each hit: α along
/// the tangent and along the bitangent, as Mitsuba's rough BSDFs take
/// `alpha_u`/`alpha_v` textures and pbrt-v4's materials float textures for
/// `uroughness`/`vroughness`.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughnessMap {
    /// Roughness along the tangent.
    pub u: Texture,
    /// Roughness along the bitangent.
    pub v: Texture,
    /// Whether the texture holds pbrt-v4's perceptual roughness r, whose α
    /// is √r (`remaproughness`, `TrowbridgeReitzDistribution::RoughnessToAlpha`),
    /// rather than α itself.
    pub remap_sqrt: bool,
}

impl RoughnessMap {
    /// `base` with the map's α at `tc`, kept in [0, 1] as constant
    /// roughness is.
    #[inline]
    pub fn microfacet_at(&self, base: Microfacet, textures: &TextureStore, tc: &TexCoord) -> Microfacet {
        let alpha = |t: &Texture| {
            let a = t.eval(textures, tc).x.clamp(0.0, 1.0);
            if self.remap_sqrt { a.sqrt() } else { a }
        };
        Microfacet::new(base.distribution, alpha(&self.u), alpha(&self.v))
    }

    /// The α of the textures' averages: what a material with this map is
    /// built with, so that it counts as rough unless every texel is 0.
    pub fn average_alpha(&self, textures: &TextureStore) -> (f32, f32) {
        let alpha = |t: &Texture| {
            let a = t.average(textures).x.max(0.0);
            if self.remap_sqrt { a.sqrt() } else { a }
        };
        (alpha(&self.u), alpha(&self.v))
    }

    /// Whether either texture reads surface coordinates.
    pub fn reads_uv(&self) -> bool {
        self.u.reads_uv() || self.v.reads_uv()
    }
}

/// A material that scatters as (1 − w)·f₀ + w·f₁ (Mitsuba's `blendbsdf`,
/// pbrt-v4's `mix`), w the weight's first channel. Where the two differ
/// only in their BSDFs (`exact`), both are evaluated at each point
/// ([`crate::material::blend::BlendBsdf`]). Otherwise (normal or bump maps,
/// opacity, emission, sides or nested mixes of their own) the second is
/// chosen with probability w at each point, by a hash of the point and the
/// direction as pbrt-v4's `MixMaterial` chooses: the same for every look-up
/// of one shading point, and independent of the sampler's dimensions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialMix {
    /// The share of `materials[1]` (first channel, clamped to [0, 1]);
    /// unread where `by_side`.
    pub weight: Texture,
    /// Whether the side a ray arrives from chooses, not the weight:
    /// `materials[0]` at the front (the side the geometric normal faces),
    /// `materials[1]` at the back.
    pub by_side: bool,
    /// The two materials (indices into the scene's).
    pub materials: [u32; 2],
    /// Whether the two are blended as one BSDF rather than chosen between.
    pub exact: bool,
}

impl MaterialMix {
    /// The material chosen at a point of geometric normal `ng` seen from
    /// direction `dir`.
    #[inline]
    pub fn choose(&self, textures: &TextureStore, tc: &TexCoord, dir: Vec3, ng: Vec3) -> u32 {
        if self.by_side {
            return self.materials[(dir.dot(ng) > 0.0) as usize];
        }
        let w = self.weight.eval(textures, tc).x;
        if w <= 0.0 {
            return self.materials[0];
        }
        if w >= 1.0 {
            return self.materials[1];
        }
        let bits = [tc.p.x, tc.p.y, tc.p.z, dir.x, dir.y, dir.z].map(|x| x.to_bits() as u64);
        let h = crate::sampling::rng::hash_u64s(&bits);
        let u = (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32);
        self.materials[(u < w) as usize]
    }
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

/// The frame a BSDF is evaluated in at a surface point, and what a normal
/// map changed there (see [`Material::shading_frame`]). It derefs to its
/// [`Frame`].
#[derive(Clone, Copy, Debug)]
pub struct ShadingFrame {
    /// The BSDF's frame.
    pub frame: Frame,
    /// Where a normal map turned the frame: the surface's own shading
    /// normal and the α² of the terminator softening below.
    unmapped: Option<(Vec3, f32)>,
}

impl std::ops::Deref for ShadingFrame {
    type Target = Frame;
    #[inline]
    fn deref(&self) -> &Frame {
        &self.frame
    }
}

impl ShadingFrame {
    /// The factor by which a normal map scales the BSDF toward `w` (world,
    /// unit, away from the surface), 1 without one. As Mitsuba 3's
    /// `normalmap`: 0 where the mapped and the surface's own normal put
    /// `w` on different sides, and otherwise a Smith masking term that
    /// darkens light arriving near the surface's own horizon, with a
    /// roughness from how far the normal was turned (Estevez et al. 2019,
    /// "A Microfacet-Based Shadowing Function to Solve the Bump Terminator
    /// Problem").
    #[inline]
    pub fn factor(&self, w: Vec3) -> f32 {
        let Some((n0, alpha2)) = self.unmapped else {
            return 1.0;
        };
        let cos0 = n0.dot(w);
        if cos0 * self.frame.n.dot(w) <= 0.0 {
            return 0.0;
        }
        let c2 = cos0 * cos0;
        let tan2 = (1.0 - c2).max(0.0) / c2;
        2.0 / (1.0 + (1.0 + alpha2 * tan2).sqrt())
    }
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
fn diffuse_bsdf<'a>(reflectance: &Texture, textures: &TextureStore, tc: &TexCoord) -> Bsdf<'a> {
    Bsdf::Lambert(LambertBsdf {
        albedo: reflectance.eval(textures, tc),
    })
}

/// The materials whose bounces the path tracer makes in lanes, several
/// paths at once ([`Material::lane_bounce`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LaneBounce {
    /// A smooth dielectric: it turns light about its shading normal alone,
    /// with no frame, texture or light sample.
    SmoothGlass {
        /// Relative index of refraction.
        eta: f32,
        /// Reflection multiplier.
        reflect_tint: Rgb,
        /// Transmission multiplier.
        transmit_tint: Rgb,
    },
    /// A Lambertian surface: its reflectance, read lane by lane, is all
    /// that varies.
    Diffuse,
}

impl Material {
    /// A material of this kind that emits nothing, is two-sided, opaque and
    /// without normal, bump or roughness maps (a scene's reader adds those).
    pub fn plain(kind: MaterialKind) -> Material {
        Material {
            kind,
            emission: Texture::Constant(Rgb::ZERO),
            emits_both_sides: false,
            two_sided: true,
            opacity: None,
            normal_map: None,
            bump_map: None,
            roughness_map: None,
        }
    }

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
            return Material::plain(MaterialKind::Diffuse { reflectance: diffuse });
        }
        Material::plain(MaterialKind::Classic {
            diffuse,
            specular,
            shininess,
            reflectivity,
            transmission,
            ior,
        })
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
        textures: &TextureStore,
    ) -> Material {
        let d_mean = {
            let a = diffuse.average(textures);
            (a.x + a.y + a.z) / 3.0
        };
        let s_mean = (specular_tint.x + specular_tint.y + specular_tint.z) / 3.0;
        let specular_weight = if d_mean + s_mean > 0.0 {
            s_mean / (d_mean + s_mean)
        } else {
            0.5
        };
        Material::plain(MaterialKind::Plastic {
            diffuse,
            eta,
            microfacet,
            specular_tint,
            nonlinear,
            specular_weight,
            smooth_internal_reflectance: plastic::smooth_internal_reflectance(eta),
            tables: (!microfacet.is_smooth()).then(|| Box::new(CoatTables::new(&microfacet, eta))),
        })
    }

    /// How its index varies with wavelength, where it does.
    #[inline]
    pub fn dispersion(&self) -> Option<&dispersion::Dispersion> {
        match &self.kind {
            MaterialKind::Dielectric { dispersion, .. } | MaterialKind::Thin { dispersion, .. } => {
                dispersion.as_deref()
            }
            MaterialKind::Layered { coat_dispersion, .. } => coat_dispersion.as_deref(),
            _ => None,
        }
    }

    /// Whether light passes through the surface.
    #[inline]
    pub fn is_transmissive(&self) -> bool {
        match &self.kind {
            MaterialKind::Classic { transmission, .. } => *transmission != Rgb::ZERO,
            MaterialKind::Dielectric { .. } | MaterialKind::Thin { .. } => true,
            MaterialKind::Principled { params, thin, .. } => {
                params.spec_trans != Texture::Constant(Rgb::ZERO)
                    || (*thin && params.diff_trans != Texture::Constant(Rgb::ZERO))
            }
            _ => false,
        }
    }

    /// Whether any of its textures reads surface coordinates (u, v).
    pub fn reads_uv(&self) -> bool {
        // Hair reads v: where across the fibre the ray met it.
        matches!(self.kind, MaterialKind::Hair(_)) || self.textures().iter().any(|t| t.reads_uv())
    }

    /// Every texture it reads.
    pub(crate) fn textures(&self) -> Vec<&Texture> {
        let textures: &[&Texture] = match &self.kind {
            MaterialKind::Classic { diffuse, specular, .. } => &[diffuse, specular],
            MaterialKind::Diffuse { reflectance } => &[reflectance],
            MaterialKind::DiffuseTransmission {
                reflectance,
                transmittance,
            } => &[reflectance, transmittance],
            MaterialKind::Plastic { diffuse, .. }
            | MaterialKind::Layered {
                base: LayerBaseKind::Diffuse(diffuse),
                ..
            } => &[diffuse],
            MaterialKind::Layered { .. } => &[],
            MaterialKind::Conductor { .. } | MaterialKind::Dielectric { .. } | MaterialKind::Thin { .. } => &[],
            MaterialKind::Principled { .. } | MaterialKind::Measured { .. } | MaterialKind::Hair(_) => &[],
        };
        let mut all = vec![&self.emission];
        if let MaterialKind::Principled { params, .. } = &self.kind {
            all.extend(params.named().map(|(_, t)| t));
        }
        if let MaterialKind::Layered {
            base: LayerBaseKind::Conductor {
                roughness_map: Some(map),
                ..
            },
            ..
        } = &self.kind
        {
            all.extend([&map.u, &map.v]);
        }
        all.extend(self.opacity.as_ref());
        all.extend(self.normal_map.as_ref().map(|n| &n.texture));
        all.extend(self.bump_map.as_ref().map(|b| &b.height));
        if let Some(r) = &self.roughness_map {
            all.extend([&r.u, &r.v]);
        }
        all.extend(textures);
        all
    }

    /// Whether a path passes through the cut-out part of a mask here:
    /// with probability 1 − α, from the number `draw` gives, which is drawn
    /// only where the material has a mask (paths elsewhere keep their
    /// random numbers).
    #[inline]
    pub fn cut_out(&self, textures: &TextureStore, tc: &TexCoord, draw: impl FnOnce() -> f32) -> bool {
        self.opacity.is_some() && draw() >= self.opacity_at(textures, tc)
    }

    /// The opacity at a point (1 where the material has no mask).
    #[inline]
    pub fn opacity_at(&self, textures: &TextureStore, tc: &TexCoord) -> f32 {
        self.opacity
            .as_ref()
            .map_or(1.0, |o| o.eval(textures, tc).x.clamp(0.0, 1.0))
    }

    /// How the path tracer may bounce paths off it in lanes, where it is
    /// a material that nothing varies over but its texture: no mask,
    /// mapped normal, roughness map or dispersion (see
    /// [`LaneBounce`]).
    pub(crate) fn lane_bounce(&self) -> Option<LaneBounce> {
        if self.opacity.is_some()
            || self.normal_map.is_some()
            || self.bump_map.is_some()
            || self.roughness_map.is_some()
        {
            return None;
        }
        match &self.kind {
            MaterialKind::Dielectric {
                eta,
                microfacet,
                reflect_tint,
                transmit_tint,
                dispersion: None,
            } if *eta == 1.0 || microfacet.is_smooth() => Some(LaneBounce::SmoothGlass {
                eta: *eta,
                reflect_tint: *reflect_tint,
                transmit_tint: *transmit_tint,
            }),
            MaterialKind::Diffuse { .. } => Some(LaneBounce::Diffuse),
            _ => None,
        }
    }

    /// The frame in which the BSDF sees directions at `hit`, seen from
    /// `wo` (world, away from the surface): the shading normal and the
    /// tangent along u, turned to the normal map's or the bump map's normal
    /// where there is one.
    ///
    /// A mapped normal is Mitsuba 3's (`normalmap`): the colour c means the
    /// normal 2c − 1 relative to (tangent, bitangent, shading normal); one
    /// that faces away from `wo` has its tilt mirrored (Schüssler et al.
    /// 2017's fix, Mitsuba's `flip_invalid_normals`); the tangent is the
    /// hit's, made perpendicular to the new normal. A bumped normal
    /// ([`BumpMap::normal`]) is mirrored and weighted the same way, as
    /// Mitsuba's `bumpmap` does.
    #[inline]
    pub fn shading_frame(&self, textures: &TextureStore, hit: &SurfaceHit, wo: Vec3) -> ShadingFrame {
        if self.normal_map.is_none() && self.bump_map.is_none() {
            return ShadingFrame {
                frame: Frame::from_orthonormal(hit.ns, hit.tangent),
                unmapped: None,
            };
        }
        self.mapped_frame(textures, hit, wo)
    }

    /// [`Material::shading_frame`] of a material with a normal or bump
    /// map: kept out of line, so that the common case above inlines.
    #[inline(never)]
    fn mapped_frame(&self, textures: &TextureStore, hit: &SurfaceHit, wo: Vec3) -> ShadingFrame {
        let base = Frame::from_orthonormal(hit.ns, hit.tangent);
        let unmapped = ShadingFrame {
            frame: base,
            unmapped: None,
        };
        let local = if let Some(map) = &self.normal_map {
            map.local_normal(textures, hit, &base)
        } else if let Some(bump) = &self.bump_map {
            bump.normal(textures, hit).map(|n| base.to_local(n))
        } else {
            None
        };
        let Some(mut local) = local else {
            return unmapped;
        };
        let wo_local = base.to_local(wo);
        if wo_local.z * wo_local.dot(local) <= 0.0 {
            local = Vec3::new(-local.x, -local.y, local.z);
        }
        let n = base.to_world(local);
        let frame = match (hit.tangent - n * n.dot(hit.tangent)).try_normalize() {
            Some(s) => Frame::from_orthonormal(n, s),
            None => Frame::from_normal(n),
        };
        let z2 = (local.z * local.z).max(1e-12);
        ShadingFrame {
            frame,
            unmapped: Some((hit.ns, (0.125 * (1.0 - z2) / z2).min(1.0))),
        }
    }

    /// Whether the surface emits.
    #[inline]
    pub fn is_emissive(&self) -> bool {
        // A match, not `!=`: the derived comparison of textures is a call,
        // made at every hit of every path.
        !matches!(self.emission, Texture::Constant(c) if c == Rgb::ZERO)
    }

    /// Whether the surface's emission (if any) leaves `hit` toward `wo`
    /// (pointing away from the surface): from the front, or from either
    /// side with `emits_both_sides`.
    #[inline]
    pub fn emits_toward(&self, hit: &crate::geometry::SurfaceHit, wo: Vec3) -> bool {
        self.emits_both_sides || hit.is_front(wo)
    }

    /// Emitted radiance at a point (of the side that emits).
    #[inline]
    pub fn emission_at(&self, textures: &TextureStore, tc: &TexCoord) -> Rgb {
        self.emission.eval(textures, tc)
    }

    /// The classical parameters at a point: the record itself for classic
    /// materials, the nearest classical equivalent for the others.
    pub fn classic(&self, textures: &TextureStore, tc: &TexCoord) -> ClassicParams {
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
                kd: diffuse.eval(textures, tc),
                ks: specular.eval(textures, tc),
                shininess: *shininess,
                kr: *reflectivity,
                kt: *transmission,
                ior: *ior,
            },
            MaterialKind::Diffuse { reflectance } => ClassicParams {
                kd: reflectance.eval(textures, tc),
                ..zero
            },
            MaterialKind::DiffuseTransmission { reflectance, .. } => ClassicParams {
                kd: reflectance.eval(textures, tc),
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
                    kd: diffuse.eval(textures, tc),
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
            MaterialKind::Layered {
                base, coat_eta, coat, ..
            } => {
                // The coat as a mirror or a Phong lobe over the base.
                let f0 = optics::fresnel_dielectric(1.0, *coat_eta);
                let smooth = coat.is_smooth();
                let kd = match base {
                    LayerBaseKind::Diffuse(r) => r.eval(textures, tc),
                    LayerBaseKind::Conductor { .. } => Rgb::ZERO,
                };
                let kr = match base {
                    LayerBaseKind::Conductor { fresnel, .. } => fresnel.eval(1.0),
                    LayerBaseKind::Diffuse(_) => Rgb::ZERO,
                };
                ClassicParams {
                    kd,
                    ks: Rgb::splat(f0),
                    shininess: if smooth {
                        1000.0
                    } else {
                        phong_exponent_for_alpha(coat.alpha_x.max(coat.alpha_y))
                    },
                    kr: kr.max(if smooth { Rgb::splat(f0) } else { Rgb::ZERO }),
                    ..zero
                }
            }
            MaterialKind::Principled { params, eta, thin } => {
                // The lobes' weights at normal incidence.
                let b = params.bsdf_at(textures, tc, *eta, *thin);
                let dielectric = 1.0 - b.metallic;
                let f0 = optics::fresnel_dielectric(1.0, *eta);
                let alpha = (b.roughness * b.roughness).max(0.001);
                ClassicParams {
                    kd: b.base_color * dielectric * (1.0 - b.spec_trans),
                    ks: Rgb::splat(dielectric * f0) + b.base_color * b.metallic,
                    shininess: phong_exponent_for_alpha(alpha),
                    kt: b.base_color.powf(0.5) * dielectric * b.spec_trans,
                    ior: *eta,
                    ..zero
                }
            }
            MaterialKind::Thin {
                eta,
                reflect_tint,
                transmit_tint,
                ..
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
            MaterialKind::Hair(hair) => ClassicParams {
                kd: hair.bsdf(0.0).albedo(),
                ..zero
            },
            // Its albedo at normal incidence, as a diffuse colour.
            MaterialKind::Measured { brdf } => ClassicParams {
                kd: measured::MeasuredBsdf { brdf }.albedo(),
                ..zero
            },
        }
    }

    /// The BSDF at a point. A diffuse material's is built in place, without
    /// a call: it is the commonest material, its BSDF is one texture look-up,
    /// and inlined the BSDF needs no trip through memory.
    #[inline(always)]
    pub fn bsdf<'a>(&'a self, textures: &TextureStore, tc: &TexCoord) -> Bsdf<'a> {
        match &self.kind {
            MaterialKind::Diffuse { reflectance } => diffuse_bsdf(reflectance, textures, tc),
            _ => self.bsdf_other(textures, tc),
        }
    }

    /// `base`, or the roughness map's α at `tc` where there is one.
    #[inline]
    fn microfacet_at(&self, base: Microfacet, textures: &TextureStore, tc: &TexCoord) -> Microfacet {
        match &self.roughness_map {
            None => base,
            Some(map) => map.microfacet_at(base, textures, tc),
        }
    }

    /// [`Material::bsdf`] of the materials other than diffuse.
    fn bsdf_other<'a>(&'a self, textures: &TextureStore, tc: &TexCoord) -> Bsdf<'a> {
        match &self.kind {
            MaterialKind::Classic { .. } => {
                let c = self.classic(textures, tc);
                Bsdf::Classic(ClassicBsdf::new(c.kd, c.ks, c.shininess, c.kr, c.kt, c.ior))
            }
            MaterialKind::Diffuse { reflectance } => diffuse_bsdf(reflectance, textures, tc),
            MaterialKind::DiffuseTransmission {
                reflectance,
                transmittance,
            } => Bsdf::DiffuseTransmission(diffuse_transmission::DiffuseTransmissionBsdf {
                // In [0, 1], as pbrt-v4 clamps them: a texture may exceed 1.
                reflectance: reflectance.eval(textures, tc).clamp(Rgb::ZERO, Rgb::ONE),
                transmittance: transmittance.eval(textures, tc).clamp(Rgb::ZERO, Rgb::ONE),
            }),
            MaterialKind::Conductor {
                fresnel,
                tint,
                microfacet,
            } => Bsdf::Conductor(ConductorBsdf {
                fresnel: *fresnel,
                tint: *tint,
                microfacet: self.microfacet_at(*microfacet, textures, tc),
            }),
            MaterialKind::Dielectric {
                eta,
                microfacet,
                reflect_tint,
                transmit_tint,
                ..
            } => Bsdf::Dielectric(DielectricBsdf {
                eta: *eta,
                microfacet: self.microfacet_at(*microfacet, textures, tc),
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
                diffuse: diffuse.eval(textures, tc),
                eta: *eta,
                microfacet: *microfacet,
                specular_tint: *specular_tint,
                nonlinear: *nonlinear,
                specular_weight: *specular_weight,
                smooth_internal_reflectance: *smooth_internal_reflectance,
                tables: tables.as_deref(),
            }),
            MaterialKind::Layered {
                base,
                coat_eta,
                coat,
                thickness,
                albedo,
                phase,
                max_depth,
                samples,
                ..
            } => Bsdf::Layered(LayeredBsdf {
                coat: DielectricBsdf {
                    eta: *coat_eta,
                    // A roughness map of a layered material is its coat's.
                    microfacet: self.microfacet_at(*coat, textures, tc),
                    reflect_tint: Rgb::ONE,
                    transmit_tint: Rgb::ONE,
                },
                base: match base {
                    LayerBaseKind::Diffuse(r) => LayerBase::Diffuse(r.eval(textures, tc)),
                    LayerBaseKind::Conductor {
                        fresnel,
                        microfacet,
                        roughness_map,
                    } => LayerBase::Conductor(ConductorBsdf {
                        fresnel: *fresnel,
                        tint: Rgb::ONE,
                        microfacet: match roughness_map {
                            Some(map) => map.microfacet_at(*microfacet, textures, tc),
                            None => *microfacet,
                        },
                    }),
                },
                thickness: *thickness,
                albedo: *albedo,
                phase: *phase,
                max_depth: *max_depth,
                samples: *samples,
            }),
            MaterialKind::Principled { params, eta, thin } => {
                Bsdf::Principled(params.bsdf_at(textures, tc, *eta, *thin))
            }
            MaterialKind::Measured { brdf } => Bsdf::Measured(measured::MeasuredBsdf { brdf }),
            MaterialKind::Hair(hair) => Bsdf::Hair(hair.bsdf(-1.0 + 2.0 * tc.uv.y)),
            MaterialKind::Thin {
                eta,
                reflect_tint,
                transmit_tint,
                ..
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

    /// A roughness map sets α per hit from its textures: the checks of a
    /// checkerboard give a conductor their two roughnesses, and pbrt's
    /// remapping takes the square root.
    #[test]
    fn roughness_maps_set_alpha_per_hit() {
        let checks = |even: f32, odd: f32| Texture::Checkerboard {
            even: Rgb::splat(even),
            odd: Rgb::splat(odd),
            scale: Vec2::splat(2.0),
        };
        let mut m = Material::diffuse(Rgb::ONE);
        m.kind = MaterialKind::Conductor {
            fresnel: ConductorFresnel::Constant(Rgb::ONE),
            tint: Rgb::ONE,
            microfacet: Microfacet::new(MicrofacetDistribution::Beckmann, 0.1, 0.1),
        };
        m.roughness_map = Some(RoughnessMap {
            u: checks(0.05, 0.3),
            v: checks(0.3, 0.05),
            remap_sqrt: false,
        });
        assert!(m.reads_uv());
        let at = |m: &Material, u: f32| {
            let tc = TexCoord::new(Vec2::new(u, 0.25), Vec3::ZERO);
            match m.bsdf(&crate::texture::TextureStore::default(), &tc) {
                Bsdf::Conductor(c) => (c.microfacet.alpha_x, c.microfacet.alpha_y, c.microfacet.distribution),
                other => panic!("not a conductor: {other:?}"),
            }
        };
        assert_eq!(at(&m, 0.25), (0.05, 0.3, MicrofacetDistribution::Beckmann));
        assert_eq!(at(&m, 0.75), (0.3, 0.05, MicrofacetDistribution::Beckmann));
        m.roughness_map.as_mut().unwrap().remap_sqrt = true;
        let (ax, ay, _) = at(&m, 0.25);
        assert!((ax - 0.05f32.sqrt()).abs() < 1e-6 && (ay - 0.3f32.sqrt()).abs() < 1e-6);
        let avg = m
            .roughness_map
            .as_ref()
            .unwrap()
            .average_alpha(&crate::texture::TextureStore::default());
        assert!((avg.0 - 0.175f32.sqrt()).abs() < 1e-6, "{avg:?}");
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

    /// Diffuse transmission's reflectance and transmittance are clamped to
    /// [0, 1] where the BSDF is made, as pbrt-v4 clamps them: a scaled
    /// texture may exceed 1.
    #[test]
    fn diffuse_transmission_clamps_its_colours() {
        let tc = TexCoord::new(Vec2::ZERO, Vec3::ZERO);
        let m = Material::plain(MaterialKind::DiffuseTransmission {
            reflectance: Texture::Constant(Rgb::new(2.0, 0.5, -1.0)),
            transmittance: Texture::Constant(Rgb::new(0.3, 1.5, 0.0)),
        });
        let Bsdf::DiffuseTransmission(b) = m.bsdf(&crate::texture::TextureStore::default(), &tc) else {
            panic!("a diffuse transmitter")
        };
        assert_eq!(
            (b.reflectance, b.transmittance),
            (Rgb::new(1.0, 0.5, 0.0), Rgb::new(0.3, 1.0, 0.0))
        );
    }

    /// Lambert's sampling ignores the lobe choice, which integrators then
    /// pass over drawing; the other BSDFs say they read it.
    #[test]
    fn only_lambert_ignores_the_lobe_choice() {
        let tc = TexCoord::new(Vec2::ZERO, Vec3::ZERO);
        let lambert = Material::diffuse(Rgb::new(0.5, 0.6, 0.7));
        let lambert = lambert.bsdf(&crate::texture::TextureStore::default(), &tc);
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
        assert!(
            classic
                .bsdf(&crate::texture::TextureStore::default(), &tc)
                .reads_lobe_choice()
        );
    }

    /// The claim that lets a diffuse-only classical material be built as
    /// `Diffuse`: its classical BSDF gives the same bits in every query.
    #[test]
    fn diffuse_only_classical_bsdf_equals_lambert_bit_for_bit() {
        let mut rng = Pcg32::new(7, 3);
        let tc = TexCoord::new(Vec2::ZERO, Vec3::ZERO);
        for kd in [Rgb::new(0.8, 0.5, 0.2), Rgb::new(0.05, 0.9, 1.0), Rgb::splat(1e-3)] {
            let material = Material::diffuse(kd);
            let lambert = material.bsdf(&crate::texture::TextureStore::default(), &tc);
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

    fn hit_at_origin() -> SurfaceHit {
        SurfaceHit {
            t: 1.0,
            p: Vec3::ZERO,
            p_error: Vec3::ZERO,
            ng: Vec3::Z,
            ns: Vec3::Z,
            uv: Vec2::new(0.3, 0.7),
            tangent: Vec3::X,
            dpdu: Vec3::X,
            dpdv: Vec3::Y,
            material: 0,
            light: None,
            attribute: Vec3::ZERO,
            time: 0.0,
        }
    }

    /// A bump map tilts the normal by the height's slope: on a plane with
    /// dp/du = x and dp/dv = y, heights s·u give the normal (−s, 0, 1)
    /// normalised, whatever the texture's resolution; the frame is then
    /// mirrored and weighted as a normal map's is.
    #[test]
    fn bump_maps_tilt_the_normal_by_the_heights_slope() {
        // A ramp along u: luminance 0, 1, …, 7 at the texel centres.
        let ramp = crate::texture::ImageTexture {
            width: 8,
            height: 2,
            pixels: (0..16).map(|i| Rgb::splat((i % 8) as f32)).collect(),
        };
        let mut hit = hit_at_origin();
        hit.uv = Vec2::new(0.5, 0.5);
        let mut m = Material::diffuse(Rgb::splat(0.5));
        m.bump_map = Some(BumpMap {
            height: Texture::Image {
                image: 0,
                scale: Vec2::ONE,
                offset: Vec2::ZERO,
                tint: Rgb::ONE,
                wrap: [crate::texture::WrapMode::Clamp; 2],
                filter: crate::texture::ImageFilter::Bilinear,
            },
            scale: 0.05,
        });
        // Height 0.05·8·u: slope 0.4 along u.
        let mut textures = crate::texture::TextureStore::with_images(vec![ramp]);
        let expected = Vec3::new(-0.4, 0.0, 1.0).normalize();
        let f = m.shading_frame(&textures, &hit, Vec3::new(-0.3, 0.1, 0.9).normalize());
        assert!((f.n - expected).length() < 1e-5, "{}", f.n);
        // The same heights through a node (times 1) are differentiated by
        // forward differences: the same tilt, to their rounding.
        let image = m.bump_map.as_ref().unwrap().height;
        let unit = Texture::Constant(Rgb::ONE);
        let node = textures
            .push(crate::texture::TextureNode::Scale {
                tex: image,
                scale: unit,
            })
            .unwrap();
        let mut by_node = m.clone();
        by_node.bump_map.as_mut().unwrap().height = node;
        let f = by_node.shading_frame(&textures, &hit, Vec3::new(-0.3, 0.1, 0.9).normalize());
        assert!((f.n - expected).length() < 1e-3, "{}", f.n);
        assert!(f.s.dot(f.n).abs() < 1e-6 && (f.s.length() - 1.0).abs() < 1e-6);
        // Longer dp/du (the same heights over a wider surface): half the slope.
        hit.dpdu = Vec3::X * 2.0;
        let f = m.shading_frame(&textures, &hit, Vec3::Z);
        assert!((f.n - Vec3::new(-0.2, 0.0, 1.0).normalize()).length() < 1e-5, "{}", f.n);
        // Seen from far on the +x side the tilt would hide the viewer: mirrored.
        hit.dpdu = Vec3::X;
        let g = m.shading_frame(&textures, &hit, Vec3::new(0.95, 0.0, 0.3).normalize());
        assert!(
            (g.n - Vec3::new(-expected.x, 0.0, expected.z)).length() < 1e-5,
            "{}",
            g.n
        );
        assert_eq!(g.factor(Vec3::new(-0.99, 0.0, 0.05).normalize()), 0.0);
        // A constant height is no bump.
        m.bump_map.as_mut().unwrap().height = Texture::Constant(Rgb::ONE);
        let flat = m.shading_frame(&textures, &hit, Vec3::Z);
        assert!((flat.n - Vec3::Z).length() < 1e-6);
    }

    /// A normal map turns the frame to 2c − 1 about (tangent, bitangent,
    /// normal), mirrors a tilt that hides the viewer, and weighs directions
    /// as Mitsuba's `normalmap` does.
    #[test]
    fn normal_maps_turn_the_shading_frame() {
        let hit = hit_at_origin();
        let mut m = Material::diffuse(Rgb::splat(0.5));
        let view = Vec3::new(-0.3, 0.2, 0.93).normalize();
        let plain = m.shading_frame(&crate::texture::TextureStore::default(), &hit, view);
        assert_eq!((plain.n, plain.s), (Vec3::Z, Vec3::X));
        assert_eq!(plain.factor(Vec3::new(0.9, 0.0, 0.1).normalize()), 1.0);

        // The identity map changes nothing.
        m.normal_map = Some(NormalMap::new(Texture::Constant(Rgb::new(0.5, 0.5, 1.0))));
        let same = m.shading_frame(&crate::texture::TextureStore::default(), &hit, view);
        assert!((same.n - Vec3::Z).length() < 1e-6 && (same.s - Vec3::X).length() < 1e-6);
        assert_eq!(same.factor(Vec3::new(0.6, 0.0, 0.8)), 1.0);

        // Tilted towards +x (the tangent), seen from the +x side.
        m.normal_map = Some(NormalMap::new(Texture::Constant(Rgb::new(0.85, 0.5, 0.75))));
        let tilted = Vec3::new(0.7, 0.0, 0.5).normalize();
        let f = m.shading_frame(&crate::texture::TextureStore::default(), &hit, Vec3::new(0.6, 0.0, 0.8));
        assert!((f.n - tilted).length() < 1e-5, "{}", f.n);
        assert!(f.s.dot(f.n).abs() < 1e-6 && (f.s.length() - 1.0).abs() < 1e-6 && f.s.x > 0.0);
        // Seen from far on the −x side the tilt would hide the viewer: mirrored.
        let g = m.shading_frame(
            &crate::texture::TextureStore::default(),
            &hit,
            Vec3::new(-0.9, 0.0, 0.3).normalize(),
        );
        assert!((g.n - Vec3::new(-tilted.x, 0.0, tilted.z)).length() < 1e-5, "{}", g.n);
        // Below the mapped plane but above the surface's own: nothing.
        let w = Vec3::new(-0.8, 0.0, 0.2).normalize();
        assert!(w.dot(f.n) < 0.0 && f.factor(w) == 0.0);
        // Above both: Estevez et al.'s masking, 1 along the normal, falling
        // towards the surface's horizon.
        let (near, grazing) = (f.factor(Vec3::Z), f.factor(Vec3::new(0.99, 0.0, 0.14).normalize()));
        assert!((near - 1.0).abs() < 1e-6, "{near}");
        assert!(grazing > 0.0 && grazing < 0.9, "{grazing}");
    }
}
