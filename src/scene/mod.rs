//! Scenes: the format-independent description ([`SceneDesc`]), the readers
//! that produce it, and the immutable render-time [`Scene`] built from it.
//!
//! ```text
//! scene file ──► native::load / pbrt::load ──► SceneDesc ──► build ──► Scene
//! ```

pub mod build;
pub mod builtin;
pub mod desc;
pub mod gltf;
pub mod memory;
pub mod mitsuba;
pub mod native;
pub mod obj;
pub mod pbrt;
pub mod ply;
pub mod serialized;

pub use build::{BuildLimits, build, build_limited};
pub use desc::SceneDesc;

use crate::accel::Aggregate;
use crate::camera::Camera;
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::geometry::{Ray, SurfaceHit};
use crate::light::{Background, Light};
use crate::material::Material;
use crate::sampling::Distribution1D;
use crate::settings::RenderSettings;
use crate::texture::TextureStore;
use std::path::Path;

/// Everything needed to render, ready for many threads to read at once.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The camera.
    pub camera: Camera,
    /// Geometry and its acceleration structure.
    pub geometry: Aggregate,
    /// Materials, indexed by the surfaces.
    pub materials: Vec<Material>,
    /// Texture images and nodes, indexed by the textures.
    pub textures: TextureStore,
    /// Lights, including one per emissive shape.
    pub lights: Vec<Light>,
    /// What escaping rays see.
    pub background: Background,
    /// Ambient light (Whitted's ambient term).
    pub ambient: Rgb,
    /// Render settings.
    pub settings: RenderSettings,
    /// Problems found while building that did not stop it.
    pub warnings: Vec<String>,
    /// Whether any material is transmissive (cached for shadow rays).
    pub any_transmissive: bool,
    /// Per material, whether it reads surface coordinates
    /// ([`Material::reads_uv`](crate::material::Material::reads_uv)):
    /// surface records of the others are made without them.
    pub materials_reading_uv: Vec<bool>,
    /// Chooses lights in proportion to their power (for emitting photons,
    /// light tracing and the light subpaths of BDPT, VCM and MLT).
    pub light_distribution: Distribution1D,
    /// Chooses a light for a shading point (next-event estimation).
    pub light_sampler: crate::light::LightSampler,
    /// Index of the environment light (a background that is not black).
    pub environment_light: Option<u32>,
    /// Participating media.
    pub media: Vec<crate::media::Medium>,
    /// Per material, the media on the two sides of the surfaces that have
    /// it; `None`: the surfaces bound no medium (rays that cross them keep
    /// theirs). Shapes that bound media get materials of their own.
    pub material_media: Vec<Option<crate::media::MediumInterface>>,
    /// The medium the camera is in.
    pub camera_medium: Option<u32>,
    /// Per material, how it mixes two others (`None` for most; empty where
    /// no material mixes);
    /// [`Scene::intersect`] records the chosen one in the hit, except for a
    /// blend, whose BSDF [`Scene::bsdf`] makes.
    pub material_mixes: Vec<Option<crate::material::MaterialMix>>,
    /// Whether any mix is blended exactly: where none is, [`Scene::bsdf`]
    /// looks no mix up.
    pub any_blend: bool,
    /// Whether any material disperses light ([`Scene::disperses`]).
    pub any_dispersive: bool,
    /// Per material, [`crate::material::Material::lane_bounce`] where it
    /// is no mix; empty where no material has one, so that the path
    /// tracer does not look for bounces to make in lanes.
    pub lane_bounces: Vec<Option<crate::material::LaneBounce>>,
}

impl Scene {
    /// The nearest surface along `ray`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        let mut slot = None;
        self.intersect_into(ray, &mut slot);
        slot
    }

    /// [`Scene::intersect`] written into `slot`. The record is built where
    /// the caller keeps it: a returned one is copied with wider loads than
    /// the stores that wrote its fields, and the copy waits on them.
    /// Kept out of line: inlined into the path tracer's loop, it made
    /// that loop twice as large and slower.
    #[inline(never)]
    pub fn intersect_into(&self, ray: &Ray, slot: &mut Option<SurfaceHit>) {
        // The hit is read where the traversal wrote it, for the same reason.
        let mut found = None;
        self.geometry.intersect_into(ray, &mut found);
        self.surface_into(ray, &found, slot);
    }

    /// [`Scene::intersect_into`] for the rays of `rays` whose bits are set
    /// in `live` (a path tracer's lanes, at most eight), into the same
    /// places of `slots`, where the rays are better tested together
    /// ([`Aggregate::intersect_together`]): whether it did. Each ray finds
    /// what it finds by itself.
    #[inline]
    pub fn intersect_together(&self, rays: &[Ray], live: u32, slots: &mut [Option<SurfaceHit>]) -> bool {
        self.geometry.tests_together(rays.len(), live) && self.intersect_packet(rays, live, slots)
    }

    /// [`Scene::intersect_together`] where the rays are tested together.
    #[inline(never)]
    fn intersect_packet(&self, rays: &[Ray], live: u32, slots: &mut [Option<SurfaceHit>]) -> bool {
        let mut found = [None; 8];
        let found = &mut found[..rays.len()];
        if !self.geometry.intersect_together(rays, live, found) {
            return false;
        }
        // The records of hits on spheres are made together.
        #[cfg(target_arch = "x86_64")]
        let together = self.sphere_records_together(rays, found, live, slots);
        #[cfg(not(target_arch = "x86_64"))]
        let together = 0;
        // The lanes' bits, not a test of each lane: which lanes missed or
        // were left is as good as random from packet to packet.
        for i in crate::geometry::simd::lanes(live & !together) {
            self.surface_into(&rays[i], &found[i], &mut slots[i]);
        }
        true
    }

    /// The records of a packet's hits on spheres, made together
    /// ([`Aggregate::sphere_surfaces`]), their materials chosen: the bits
    /// of the lanes whose slots it filled.
    ///
    /// [`Aggregate::sphere_surfaces`]: crate::accel::aggregate::Aggregate::sphere_surfaces
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    fn sphere_records_together(
        &self,
        rays: &[Ray],
        found: &[Option<crate::accel::aggregate::Hit>],
        live: u32,
        slots: &mut [Option<SurfaceHit>],
    ) -> u32 {
        let (Ok(rays), Ok(found)) = (<&[Ray; 8]>::try_from(rays), <&[_; 8]>::try_from(found)) else {
            return 0;
        };
        // SAFETY: the rays were tested together, which only a processor
        // with AVX does.
        let together = unsafe {
            self.geometry
                .sphere_surfaces(rays, found, live, |m| self.reads_uv(m), slots)
        };
        for i in crate::geometry::simd::lanes(together) {
            if let Some(surface) = &mut slots[i] {
                self.choose_material(surface, rays[i].dir);
            }
        }
        together
    }

    /// Whether material `m` reads surface coordinates.
    #[inline(always)]
    fn reads_uv(&self, m: u32) -> bool {
        self.materials_reading_uv.get(m as usize).copied().unwrap_or(true)
    }

    /// The surface record of `found` on `ray` (its material chosen), or
    /// `None`, in `slot`.
    #[inline(always)]
    fn surface_into(&self, ray: &Ray, found: &Option<crate::accel::aggregate::Hit>, slot: &mut Option<SurfaceHit>) {
        let Some(hit) = found else {
            *slot = None;
            return;
        };
        let surface = slot.insert(self.geometry.surface_with(ray, hit, |m| self.reads_uv(m)));
        self.choose_material(surface, ray.dir);
    }

    /// Replaces a mix material of a hit seen along `dir` by the material it
    /// chooses there (through nested mixes), except a mix that is blended
    /// exactly, whose BSDF [`Scene::bsdf`] makes.
    #[inline]
    pub fn choose_material(&self, hit: &mut SurfaceHit, dir: glam::Vec3) {
        // Checked here, inline: the call costs more than the look-up.
        if !self.material_mixes.is_empty() {
            self.resolve_mixes(hit, dir, true);
        }
    }

    /// [`Scene::choose_material`] for every mix, those blended exactly too:
    /// for Whitted's tracer, which reads one material's classical
    /// parameters, and photon mapping, whose shading points outlive a
    /// blend's parts.
    #[inline]
    pub fn choose_any_material(&self, hit: &mut SurfaceHit, dir: glam::Vec3) {
        if !self.material_mixes.is_empty() {
            self.resolve_mixes(hit, dir, false);
        }
    }

    #[inline]
    fn resolve_mixes(&self, hit: &mut SurfaceHit, dir: glam::Vec3, keep_blends: bool) {
        for _ in 0..crate::scene::desc::MAX_MIX_DEPTH {
            let Some(mix) = self.material_mixes.get(hit.material as usize).and_then(Option::as_ref) else {
                return;
            };
            if keep_blends && mix.exact {
                return;
            }
            hit.material = mix.choose(&self.textures, &crate::texture::TexCoord::at(hit), dir, hit.ng);
        }
    }

    /// The BSDF of material `m` at `tc`: the material's own, or for a mix
    /// blended exactly the blend of its two materials' BSDFs, which are
    /// kept in `parts`.
    #[inline]
    pub fn bsdf<'s>(
        &'s self,
        m: u32,
        tc: &crate::texture::TexCoord,
        parts: &'s mut Option<[crate::material::Bsdf<'s>; 2]>,
    ) -> crate::material::Bsdf<'s> {
        if self.any_blend {
            if let Some(mix) = self.material_mixes.get(m as usize).and_then(Option::as_ref) {
                if mix.exact {
                    return self.blend(mix, tc, parts, None);
                }
            }
        }
        self.materials[m as usize].bsdf(&self.textures, tc)
    }

    /// Whether the BSDF of material `m` (or of a part of its blend)
    /// depends on wavelength: a dielectric that disperses.
    #[inline]
    pub fn disperses(&self, m: u32) -> bool {
        if !self.any_dispersive {
            return false;
        }
        let mix = self
            .material_mixes
            .get(m as usize)
            .and_then(Option::as_ref)
            .filter(|mix| mix.exact);
        match mix {
            Some(mix) => mix.materials.iter().any(|&k| self.disperses(k)),
            None => self.materials[m as usize].dispersion().is_some(),
        }
    }

    /// [`Scene::bsdf`] for a path of wavelength `nm`: dispersive
    /// dielectrics take their index at it.
    #[inline(never)]
    pub fn bsdf_at_wavelength<'s>(
        &'s self,
        m: u32,
        tc: &crate::texture::TexCoord,
        parts: &'s mut Option<[crate::material::Bsdf<'s>; 2]>,
        nm: f32,
    ) -> crate::material::Bsdf<'s> {
        if let Some(mix) = self
            .material_mixes
            .get(m as usize)
            .and_then(Option::as_ref)
            .filter(|mix| mix.exact)
        {
            return self.blend(mix, tc, parts, Some(nm));
        }
        self.material_bsdf_at(m, tc, nm)
    }

    /// Material `m`'s own BSDF at wavelength `nm`.
    pub fn material_bsdf_at(&self, m: u32, tc: &crate::texture::TexCoord, nm: f32) -> crate::material::Bsdf<'_> {
        use crate::material::Bsdf;
        let material = &self.materials[m as usize];
        let mut bsdf = material.bsdf(&self.textures, tc);
        let Some(d) = material.dispersion() else {
            return bsdf;
        };
        let eta = d.eta(nm);
        match &mut bsdf {
            Bsdf::Dielectric(glass) => glass.eta = eta,
            Bsdf::Thin(sheet) => sheet.eta = eta,
            Bsdf::Layered(layers) => {
                // A conductor base's indices are relative to the coat's.
                if let crate::material::layered::LayerBase::Conductor(base) = &mut layers.base {
                    if let crate::material::conductor::ConductorFresnel::Complex { eta: n, k } = &mut base.fresnel {
                        let ratio = layers.coat.eta / eta;
                        *n *= ratio;
                        *k *= ratio;
                    }
                }
                layers.coat.eta = eta;
            }
            _ => {}
        }
        bsdf
    }

    #[inline(never)]
    fn blend<'s>(
        &'s self,
        mix: &crate::material::MaterialMix,
        tc: &crate::texture::TexCoord,
        parts: &'s mut Option<[crate::material::Bsdf<'s>; 2]>,
        nm: Option<f32>,
    ) -> crate::material::Bsdf<'s> {
        let weight = mix.weight.eval(&self.textures, tc).x.clamp(0.0, 1.0);
        let parts = parts.insert(mix.materials.map(|k| match nm {
            Some(nm) => self.material_bsdf_at(k, tc, nm),
            None => self.materials[k as usize].bsdf(&self.textures, tc),
        }));
        crate::material::Bsdf::Blend(crate::material::blend::BlendBsdf { weight, parts })
    }

    /// Whether any material lets light through (shadow rays then have to
    /// look past the first surface they meet).
    #[inline]
    pub fn has_transmissive_materials(&self) -> bool {
        self.any_transmissive
    }

    /// Whether anything blocks `ray` within its interval.
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.geometry.occluded(ray)
    }
}

/// Whether a scene file of this name may name its own output image: a
/// pbrt-v4 scene does (`Film` "filename").
pub fn may_name_its_output(path: &Path) -> bool {
    let name = if crate::files::is_gzip_name(path) {
        path.with_extension("")
    } else {
        path.to_path_buf()
    };
    name.extension().is_some_and(|e| e.eq_ignore_ascii_case("pbrt"))
}

/// Reads a scene file, choosing the reader by its extension. `defines`
/// are `name=value` pairs from the command line (`-D`): Mitsuba's `$name`
/// parameters; formats without parameters warn that they are unused.
pub fn load(path: &Path, defines: &[(String, String)]) -> Result<SceneDesc> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    let mut desc = match ext.as_str() {
        "xml" => return mitsuba::load(path, defines),
        "toml" => native::load(path)?,
        "obj" | "ply" | "serialized" => builtin::framed_model(path)?,
        // These readers warn about -D definitions themselves.
        "pbrt" => return pbrt::load(path, defines),
        // pbrt-v4 reads gzip-compressed scenes.
        "gz" if path
            .file_stem()
            .is_some_and(|s| Path::new(s).extension().is_some_and(|e| e.eq_ignore_ascii_case("pbrt"))) =>
        {
            return pbrt::load(path, defines);
        }
        "gltf" | "glb" => return gltf::load(path, defines),
        _ => {
            return Err(Error::file(
                path,
                format!(
                    "unknown scene format{}: trazo reads .toml (trazo), .xml (Mitsuba 3), .pbrt (pbrt-v4) and .gltf/.glb (glTF 2.0) scenes, and .obj, .ply and .serialized (Mitsuba) models",
                    if ext.is_empty() {
                        String::new()
                    } else {
                        format!(" \".{ext}\"")
                    }
                ),
            ));
        }
    };
    for (name, _) in defines {
        desc.warnings.push(format!(
            "-D {name}: {} scenes have no parameters; the definition is not used",
            ext
        ));
    }
    Ok(desc)
}
