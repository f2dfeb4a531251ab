//! `SceneDesc`: the plain-data description of a scene that every format
//! reader produces and that [`crate::scene::build()`] turns into a renderable
//! [`crate::scene::Scene`].
//!
//! Every element carries where it came from ([`Locs`]), so that validation,
//! which happens once here for all formats, can point at the offending
//! line, column and key.

use crate::color::{Encoding, Rgb};
use crate::error::{Error, Result, SourceLoc};
use crate::geometry::{Transform, TriangleMesh};
use crate::light::{ProjectorLaw, SpotProfile};
pub use crate::material::MicrofacetDistribution;
use crate::settings::{
    Filter, IntegratorKind, MAX_DEPTH, MAX_GATHER, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, MAX_MLT_BOOTSTRAP, MAX_MLT_CHAINS,
    MAX_PHOTONS, MAX_SPP, RenderSettings,
};
pub use crate::texture::{ImageFilter, WrapMode};
use crate::texture::{Mapping2D, NoisePattern, TextureNode};
use glam::{Mat4, Vec2, Vec3};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Where an element and each of its keys were written.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Locs {
    /// The element itself (e.g. the `[[shape]]` header).
    pub item: Option<SourceLoc>,
    /// Individual keys, as the reader saw them.
    pub keys: Vec<(String, SourceLoc)>,
}

impl Locs {
    /// Locations of an element with no per-key information.
    pub fn at(item: Option<SourceLoc>) -> Locs {
        Locs { item, keys: Vec::new() }
    }

    /// The location of `key`, or of the element if the key was not seen.
    pub fn key(&self, key: &str) -> Option<SourceLoc> {
        self.keys
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, l)| l.clone())
            .or_else(|| self.item.clone())
    }
}

/// Camera projection as described.
#[derive(Clone, Debug, PartialEq)]
pub enum ProjectionDesc {
    /// Perspective with vertical field of view in degrees.
    Perspective {
        /// Vertical field of view, degrees.
        fov: f32,
    },
    /// Orthographic with the height of the view plane.
    Orthographic {
        /// Height of the view plane in world units.
        size: f32,
    },
    /// Every direction around the eye (see
    /// [`crate::camera::Projection::Spherical`]).
    Spherical {
        /// How directions lie on the image.
        mapping: crate::camera::SphericalMapping,
    },
    /// A system of real lenses (see [`crate::camera::LensSystem`]).
    Realistic {
        /// The lens description's numbers (mm): curvature radius,
        /// thickness, index and aperture diameter per interface, from the
        /// scene's side to the film's.
        lenses: Vec<f32>,
        /// The aperture stop's diameter (mm), at most the description's.
        aperture_diameter: f32,
        /// Distance from the film to the plane in focus (scene units, as
        /// metres).
        focus_distance: f32,
        /// The film's diagonal (m).
        film_diagonal: f32,
        /// The aperture stop's shape (pbrt-v4's `aperture`); `None`: round.
        stop_mask: Option<crate::camera::ApertureMask>,
    },
}

/// The camera.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraDesc {
    /// Projection.
    pub projection: ProjectionDesc,
    /// Eye position.
    pub from: Vec3,
    /// Point looked at.
    pub to: Vec3,
    /// Up direction.
    pub up: Vec3,
    /// Lens radius (0: pinhole).
    pub aperture_radius: f32,
    /// Distance to the plane in focus; `None`: the distance from `from` to `to`.
    pub focus_distance: Option<f32>,
    /// The screen window laid over the image (pbrt-v4's `screenwindow`:
    /// x min, x max, y min, y max; see
    /// [`crate::camera::Camera::from_transform_windowed`]), for a
    /// perspective camera on the plane where tan(fov/2) is one unit;
    /// `None`: centred, following the image's aspect.
    pub screen_window: Option<[f32; 4]>,
    /// Distance along the viewing axis before which nothing is seen
    /// (Mitsuba's `near_clip`; 0: none).
    pub near_clip: f32,
    /// Distance along the viewing axis beyond which nothing is seen
    /// (Mitsuba's `far_clip`; infinite: none).
    pub far_clip: f32,
    /// An explicit camera-to-world matrix (camera space: +x right in the
    /// image, +y up, +z forward); when given, `from`, `to` and `up` are
    /// ignored. Format readers use it for their cameras' transforms.
    pub to_world: Option<Mat4>,
    /// When the shutter opens and closes (pbrt-v4's `shutteropen` and
    /// `shutterclose`): moving shapes are seen at times uniform in between.
    pub shutter: (f32, f32),
    /// Where the camera moves (motion blur): its camera-to-world matrix
    /// at the second of two times (`to_world` holds at the first), and the
    /// times.
    pub motion: Option<(Mat4, (f32, f32))>,
    /// Source locations.
    pub locs: Locs,
}

impl Default for CameraDesc {
    fn default() -> Self {
        CameraDesc {
            projection: ProjectionDesc::Perspective { fov: 40.0 },
            from: Vec3::new(0.0, 0.0, 5.0),
            to: Vec3::ZERO,
            up: Vec3::Y,
            aperture_radius: 0.0,
            focus_distance: None,
            screen_window: None,
            near_clip: 0.0,
            far_clip: f32::INFINITY,
            to_world: None,
            shutter: (0.0, 1.0),
            motion: None,
            locs: Locs::default(),
        }
    }
}

/// A colour parameter: a constant, or a reference to a named texture.
#[derive(Clone, Debug, PartialEq)]
pub enum ColorSource {
    /// A constant linear RGB colour.
    Rgb(Rgb),
    /// The texture with this name.
    Texture(String),
}

impl From<Rgb> for ColorSource {
    fn from(c: Rgb) -> Self {
        ColorSource::Rgb(c)
    }
}

/// The most octaves a noise texture sums: each one is a noise look-up
/// per texture read, and past 30 they are finer than a float resolves.
pub const MAX_NOISE_OCTAVES: u32 = 64;

/// A texture definition.
#[derive(Clone, Debug, PartialEq)]
pub enum TextureKind {
    /// A constant colour.
    Constant(Rgb),
    /// 2-D checks over (u, v).
    Checkerboard {
        /// First colour.
        even: Rgb,
        /// Second colour.
        odd: Rgb,
        /// Checks per unit of u and v.
        scale: Vec2,
    },
    /// 3-D (solid) checks in world space.
    Checkerboard3d {
        /// First colour.
        even: Rgb,
        /// Second colour.
        odd: Rgb,
        /// Cubes per unit length.
        scale: f32,
    },
    /// An image.
    Image {
        /// Where the pixels come from.
        source: ImageSource,
        /// Repetitions per unit of u and v.
        scale: Vec2,
        /// Offset in (u, v).
        offset: Vec2,
        /// How the file's values are decoded (`None`: by the file's type,
        /// integer images from sRGB, float images as linear).
        encoding: Option<Encoding>,
        /// Colour multiplier.
        tint: Rgb,
        /// How the image continues beyond [0, 1]², along u and along v.
        wrap: [WrapMode; 2],
        /// How it is read between texel centres.
        filter: ImageFilter,
    },
    /// A mesh's values per vertex or per face, by name (`vertex_color`,
    /// `face_weight`: Mitsuba's `mesh_attribute`); 0 on surfaces without it.
    MeshAttribute {
        /// The attribute's name.
        name: String,
    },
    /// A texture made of textures, or a procedural one: its inputs are
    /// colours or the names of textures defined before it.
    Node(TextureNode<ColorSource>),
}

/// Where an image texture's pixels come from.
#[derive(Clone, Debug, PartialEq)]
pub enum ImageSource {
    /// A file, relative to the scene file.
    File(PathBuf),
    /// A file of emitted light (a light's image), relative to the scene
    /// file: its colours convert from another colour space as emitted
    /// light does ([`crate::texture::ImageColors`]).
    EmissionFile(PathBuf),
    /// A file of numbers that are not colours (a normal map), relative to
    /// the scene file: no colour space converts them.
    DataFile(PathBuf),
    /// A file read as pbrt-v4 reads a float image texture: its alpha where
    /// it has one that is not 1 everywhere, else the mean of its colour
    /// channels, as a grey ([`crate::texture::ImageTexture::load_float`]).
    FloatFile(PathBuf),
    /// A file whose alpha channel is read, as a grey (1 where the image
    /// has none): glTF's coverage in a base colour image
    /// ([`crate::texture::ImageTexture::load_alpha`]).
    AlphaFile(PathBuf),
    /// Pixels already decoded (images embedded in a glTF binary, say).
    Data(Arc<crate::texture::ImageTexture>),
}

/// A named texture.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureDesc {
    /// Name that materials refer to.
    pub name: String,
    /// Definition.
    pub kind: TextureKind,
    /// Source locations.
    pub locs: Locs,
}

/// The classical material record (see [`crate::material::MaterialKind::Classic`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ClassicDesc {
    /// Diffuse colour.
    pub diffuse: ColorSource,
    /// Specular colour.
    pub specular: ColorSource,
    /// Phong exponent.
    pub shininess: f32,
    /// Mirror reflectivity.
    pub reflectivity: Rgb,
    /// Transmission.
    pub transmission: Rgb,
    /// Index of refraction.
    pub ior: f32,
}

impl Default for ClassicDesc {
    fn default() -> Self {
        ClassicDesc {
            diffuse: ColorSource::Rgb(Rgb::splat(0.5)),
            specular: ColorSource::Rgb(Rgb::ZERO),
            shininess: 0.0,
            reflectivity: Rgb::ZERO,
            transmission: Rgb::ZERO,
            ior: 1.0,
        }
    }
}

/// The base of a layered material.
#[derive(Clone, Debug, PartialEq)]
pub enum LayeredBaseDesc {
    /// Lambertian, of this albedo.
    Diffuse(ColorSource),
    /// A conductor (η and k relative to the outside, as written; the
    /// build divides them by the coat's index).
    Conductor {
        /// Reflectance.
        fresnel: ConductorDesc,
        /// Microfacet α along tangent and bitangent (0: smooth).
        roughness: (f32, f32),
        /// Roughness that varies over the surface, replacing `roughness`.
        roughness_map: Option<RoughnessMapDesc>,
    },
}

/// How a conductor's reflectance is given.
#[derive(Clone, Debug, PartialEq)]
pub enum ConductorDesc {
    /// Complex index of refraction per channel.
    Complex {
        /// Real part.
        eta: Rgb,
        /// Imaginary part.
        k: Rgb,
    },
    /// Colour at normal incidence (Schlick's approximation).
    Reflectance(Rgb),
    /// An ideal mirror of this reflectance at every angle.
    Mirror(Rgb),
}

/// A material's scattering model as described.
#[derive(Clone, Debug, PartialEq)]
pub enum MaterialKindDesc {
    /// The classical record.
    Classic(ClassicDesc),
    /// Lambertian.
    Diffuse {
        /// Albedo.
        reflectance: ColorSource,
    },
    /// Lambertian reflection and transmission.
    DiffuseTransmission {
        /// Reflectance R.
        reflectance: ColorSource,
        /// Transmittance T.
        transmittance: ColorSource,
    },
    /// Metal or mirror.
    Conductor {
        /// Reflectance.
        fresnel: ConductorDesc,
        /// Colour multiplier.
        tint: Rgb,
        /// Microfacet α along tangent and bitangent (0: smooth).
        roughness: (f32, f32),
        /// The distribution of microfacet normals.
        distribution: MicrofacetDistribution,
    },
    /// Glass.
    Dielectric {
        /// Index of refraction inside.
        ior: f32,
        /// Index of refraction outside.
        ext_ior: f32,
        /// Microfacet α along tangent and bitangent (0: smooth).
        roughness: (f32, f32),
        /// The distribution of microfacet normals.
        distribution: MicrofacetDistribution,
        /// Reflection multiplier.
        reflect_tint: Rgb,
        /// Transmission multiplier.
        transmit_tint: Rgb,
        /// The inside's index as it varies with wavelength (`ior` is then
        /// its value at the sodium d line); `None`: `ior` at every
        /// wavelength.
        dispersion: Option<crate::material::dispersion::IorSpectrum>,
    },
    /// Diffuse base under a dielectric coat.
    Plastic {
        /// Base colour.
        diffuse: ColorSource,
        /// Index of refraction of the coat.
        ior: f32,
        /// Index of refraction outside.
        ext_ior: f32,
        /// Microfacet α of the coat (0: smooth).
        roughness: f32,
        /// The distribution of the coat's microfacet normals.
        distribution: MicrofacetDistribution,
        /// Coat reflection multiplier.
        specular_tint: Rgb,
        /// Colour saturation by internal scattering.
        nonlinear: bool,
    },
    /// pbrt-v4's layered material (`coateddiffuse`, `coatedconductor`): a
    /// dielectric coat over a base, a slab between them that may hold a
    /// scattering medium, rendered by a random walk between the layers.
    Layered {
        /// What lies under the coat.
        base: LayeredBaseDesc,
        /// Index of refraction of the coat (outside: 1).
        coat_ior: f32,
        /// Microfacet α of the coat along tangent and bitangent (0: smooth).
        coat_roughness: (f32, f32),
        /// Thickness of the slab, in mean free paths of its medium.
        thickness: f32,
        /// Single-scattering albedo of the slab's medium (zero: empty).
        albedo: Rgb,
        /// Henyey–Greenstein asymmetry of the medium, in [−1, 1].
        g: f32,
        /// Most scattering events of one walk.
        max_depth: u32,
        /// Walks per evaluation.
        samples: u32,
        /// The coat's index as it varies with wavelength (`coat_ior` is
        /// then its value at the sodium d line); `None`: the same at every
        /// wavelength.
        coat_dispersion: Option<crate::material::dispersion::IorSpectrum>,
    },
    /// Hair fibres (pbrt-v4's `hair`; Chiang et al. 2016), for curves.
    Hair(crate::material::hair::HairParams),
    /// A measured BRDF: an RGL `.bsdf` file (pbrt-v4's and Mitsuba's
    /// `measured`), relative to the scene's folder.
    Measured {
        /// The file.
        file: PathBuf,
    },
    /// A thin dielectric sheet; with `ior` equal to `ext_ior`, no surface
    /// at all (only the boundary of a medium).
    Thin {
        /// Index of refraction of the sheet.
        ior: f32,
        /// Index of refraction outside.
        ext_ior: f32,
        /// Reflection multiplier.
        reflect_tint: Rgb,
        /// Transmission multiplier.
        transmit_tint: Rgb,
        /// The sheet's index as it varies with wavelength (`ior` is then
        /// its value at the sodium d line); `None`: the same at every
        /// wavelength.
        dispersion: Option<crate::material::dispersion::IorSpectrum>,
    },
    /// One of two materials at each point, chosen at random or by the
    /// side a ray arrives from ([`MixChoice`]). Its own emission,
    /// sidedness, opacity and normal map, where given, apply to both.
    Mix {
        /// How the material is chosen.
        choice: MixChoice,
        /// The two materials' names.
        materials: [String; 2],
    },
    /// Disney's principled BSDF (Mitsuba's `principled`; see
    /// [`crate::material::principled`]).
    Principled {
        /// The parameters: the base colour, the others' first channels.
        params: Box<crate::material::principled::PrincipledParams<ColorSource>>,
        /// Index of refraction inside, relative to the outside.
        eta: f32,
        /// The thin form (Mitsuba's `principledthin`): a two-sided sheet.
        thin: bool,
    },
}

/// How deep mixes may nest (a deeper chain is refused as a likely cycle).
pub const MAX_MIX_DEPTH: usize = 16;

impl MaterialKindDesc {
    /// Whether its index of refraction varies with wavelength (a glass, a
    /// thin sheet or a coat that disperses light).
    pub fn disperses(&self) -> bool {
        matches!(
            self,
            MaterialKindDesc::Dielectric {
                dispersion: Some(_),
                ..
            } | MaterialKindDesc::Thin {
                dispersion: Some(_),
                ..
            } | MaterialKindDesc::Layered {
                coat_dispersion: Some(_),
                ..
            }
        )
    }

    /// The surface that is not there: it bounds a medium and does not
    /// scatter (Mitsuba's `null` BSDF, pbrt-v4's `interface` material).
    pub const NULL: MaterialKindDesc = MaterialKindDesc::Thin {
        ior: 1.0,
        ext_ior: 1.0,
        reflect_tint: Rgb::ONE,
        transmit_tint: Rgb::ONE,
        dispersion: None,
    };
}

/// How a mix material chooses between its two materials.
#[derive(Clone, Debug, PartialEq)]
pub enum MixChoice {
    /// The second with the weight's first channel as its probability: on
    /// average (1 − w)·f₀ + w·f₁ (Mitsuba's `blendbsdf`, pbrt-v4's `mix`,
    /// which chooses likewise).
    Weight(ColorSource),
    /// The first where a ray arrives at the front of the surface (the side
    /// its geometric normal faces), the second at the back, each seen as
    /// from its front (Mitsuba's `twosided` with two BSDFs).
    Side,
}

/// A named material (see [`crate::material::Material`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDesc {
    /// Name that shapes refer to.
    pub name: String,
    /// Scattering model.
    pub kind: MaterialKindDesc,
    /// Emitted radiance (a colour or a texture).
    pub emission: ColorSource,
    /// Whether the back emits as the front does (pbrt-v4's `twosided` area
    /// lights); emitters are one-sided otherwise.
    pub emits_both_sides: bool,
    /// Whether the back side scatters like the front.
    pub two_sided: bool,
    /// Opacity in [0, 1] (its first channel), a cut-out mask: where it is
    /// below 1 light passes the surface unchanged with the rest (Mitsuba's
    /// `mask` BSDF); `None`: opaque.
    pub opacity: Option<ColorSource>,
    /// A tangent-space normal map; `None`: the surface's own normal.
    pub normal_map: Option<NormalMapDesc>,
    /// A bump map: a texture whose luminance times `scale` is a height
    /// over the surface, tilting the shading normal; `None`: none.
    pub bump_map: Option<BumpMapDesc>,
    /// Roughness that varies over the surface, for a conductor or a
    /// dielectric: it replaces the kind's constant roughness.
    pub roughness_map: Option<RoughnessMapDesc>,
    /// Source locations.
    pub locs: Locs,
}

/// Microfacet roughness from textures (see
/// [`crate::material::RoughnessMap`]): the first channel of `u` is α along
/// the tangent, of `v` along the bitangent.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughnessMapDesc {
    /// Roughness along the tangent.
    pub u: ColorSource,
    /// Roughness along the bitangent.
    pub v: ColorSource,
    /// The textures hold pbrt-v4's roughness r, whose α is √r.
    pub remap_sqrt: bool,
}

/// A material's normal map (see [`crate::material::NormalMap`]): colours c
/// in [0, 1]³ meaning the normal 2c − 1 in the frame of (tangent along u,
/// bitangent, shading normal), read raw (no sRGB decoding).
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMapDesc {
    /// The colours.
    pub texture: ColorSource,
    /// Scale of the normal's tangential part (1: as stored).
    pub scale: f32,
    /// glTF's tangent space: the bitangent follows increasing v.
    pub bitangent_along_v: bool,
}

impl NormalMapDesc {
    /// Mitsuba's and pbrt-v4's normal map: scale 1, bitangent n × tangent.
    pub fn new(texture: ColorSource) -> NormalMapDesc {
        NormalMapDesc {
            texture,
            scale: 1.0,
            bitangent_along_v: false,
        }
    }
}

/// A material's bump map (see [`crate::material::BumpMap`]).
#[derive(Clone, Debug, PartialEq)]
pub struct BumpMapDesc {
    /// The heights: the texture's luminance.
    pub height: ColorSource,
    /// Height per unit of the texture's value.
    pub scale: f32,
}

impl MaterialDesc {
    /// A classical material with the record's defaults (grey diffuse).
    pub fn new(name: impl Into<String>) -> MaterialDesc {
        Self::with_kind(name, MaterialKindDesc::Classic(ClassicDesc::default()))
    }

    /// A classical material.
    pub fn classic(name: impl Into<String>, c: ClassicDesc) -> MaterialDesc {
        Self::with_kind(name, MaterialKindDesc::Classic(c))
    }

    /// A material of any kind.
    pub fn with_kind(name: impl Into<String>, kind: MaterialKindDesc) -> MaterialDesc {
        MaterialDesc {
            name: name.into(),
            kind,
            emission: ColorSource::Rgb(Rgb::ZERO),
            emits_both_sides: false,
            two_sided: true,
            opacity: None,
            normal_map: None,
            bump_map: None,
            roughness_map: None,
            locs: Locs::default(),
        }
    }
}

/// Where a mesh's triangles come from.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshSource {
    /// Given in the scene.
    Inline(TriangleMesh),
    /// A Wavefront OBJ file, relative to the scene file.
    File(PathBuf),
    /// A latitude–longitude unit sphere with this many segments and rings.
    UvSphere {
        /// Divisions around the axis.
        segments: u32,
        /// Divisions from pole to pole.
        rings: u32,
    },
    /// A mesh displaced along its normals by a float texture, its edges
    /// first cut shorter than `edge_length` (pbrt-v4's `plymesh`
    /// `displacement`; `geometry::displacement`).
    Displaced {
        /// The mesh before displacement; it needs texture coordinates.
        mesh: Box<MeshSource>,
        /// The name of the texture of heights (the mean of its channels).
        height: String,
        /// The longest edge left, in world units (after the shape's
        /// transform).
        edge_length: f32,
        /// pbrt-v4's area light `power` given each displaced triangle,
        /// whose radiance then follows from its area after displacement.
        power: Option<TrianglePower>,
    },
}

/// pbrt-v4's area light `power` on each triangle of a mesh whose
/// triangles are known only when the scene is built (a displaced mesh):
/// the build gives the mesh a per-face attribute of `radiance` ×
/// `power` / (`per_area` × the triangle's world-space area), which its
/// emission reads.
#[derive(Clone, Debug, PartialEq)]
pub struct TrianglePower {
    /// The power, in watts.
    pub power: f32,
    /// k·π·sides: the luminance of the light's image (1 without one)
    /// times π, times 2 for a two-sided light.
    pub per_area: f32,
    /// The radiance scaled (white where the attribute scales an image).
    pub radiance: Rgb,
    /// The name of the attribute.
    pub attribute: String,
}

/// A named mesh that shapes can place, once or many times.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshDesc {
    /// Name that shapes refer to.
    pub name: String,
    /// Triangles.
    pub source: MeshSource,
    /// Source locations.
    pub locs: Locs,
}

/// A light.
#[derive(Clone, Debug, PartialEq)]
pub enum LightKind {
    /// Point light.
    Point {
        /// Position.
        position: Vec3,
        /// Intensity, W/sr.
        intensity: Rgb,
        /// Inverse-square falloff.
        falloff: bool,
    },
    /// Spot light.
    Spot {
        /// Position.
        position: Vec3,
        /// Point the cone is aimed at.
        to: Vec3,
        /// Intensity on the axis, W/sr.
        intensity: Rgb,
        /// Half-angle of full intensity, degrees.
        inner_angle: f32,
        /// Half-angle beyond which there is no light, degrees.
        outer_angle: f32,
        /// How the intensity falls between the two angles.
        profile: SpotProfile,
        /// An image the light projects (Mitsuba's `texture`).
        projection: Option<SpotProjectionDesc>,
        /// Inverse-square falloff.
        falloff: bool,
    },
    /// A projector: a point light that projects an image through a
    /// pinhole (Mitsuba 3's `projector`; see [`crate::light::Light::Projector`]).
    Projector {
        /// Position of the pinhole.
        position: Vec3,
        /// The light's frame: the linear part of its `to_world` (light
        /// leaves along +z; +x toward the image's left, +y toward its top).
        to_world: glam::Mat3,
        /// Field of view, degrees, along `fov_axis`.
        fov: f32,
        /// Which extent of the image `fov` spans.
        fov_axis: FovAxis,
        /// The image (a colour or a texture name): what its value is, `law`
        /// says.
        irradiance: ColorSource,
        /// Multiplier.
        scale: f32,
        /// What the image's value is: irradiance over π on the plane at
        /// depth 1 (Mitsuba) or radiant intensity (pbrt-v4).
        law: ProjectorLaw,
        /// The power (by luminance) the light emits, where given: `scale`
        /// is then multiplied by what makes the intensity's integral over
        /// the frame this (pbrt-v4's `power`).
        power: Option<f32>,
    },
    /// A point light whose intensity varies with direction as a square
    /// image in pbrt-v4's equal-area octahedral layout says (pbrt-v4's
    /// `goniometric`; see [`crate::light::Light::Goniometric`]).
    Goniometric {
        /// Position of the light.
        position: Vec3,
        /// The image's frame to the world (the centre of its square is +z
        /// there).
        to_world: glam::Mat3,
        /// Intensity (W/sr) where the image's value is 1.
        intensity: Rgb,
        /// The image (a texture name); a pixel's value is the mean of its
        /// RGB, as pbrt-v4 reads an RGB image.
        image: String,
        /// The power (by luminance) where given: the intensity is then
        /// multiplied by power over 4π × the image's mean (pbrt-v4's
        /// `power`).
        power: Option<f32>,
    },
    /// Directional light.
    Directional {
        /// Direction the light travels in.
        direction: Vec3,
        /// Irradiance, W/m².
        irradiance: Rgb,
    },
}

/// An image a spot light projects, as Mitsuba 3 projects it (see
/// [`crate::light::SpotProjection`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SpotProjectionDesc {
    /// The texture (a name in [`SceneDesc::textures`]).
    pub texture: String,
    /// The light's frame: the linear part of its `to_world` (the axis is
    /// its +z).
    pub to_world: glam::Mat3,
}

/// Which extent of an image a field of view spans (Mitsuba's `fov_axis`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FovAxis {
    /// Across.
    #[default]
    X,
    /// Up.
    Y,
    /// Along the diagonal.
    Diagonal,
    /// Along the shorter side.
    Smaller,
    /// Along the longer side.
    Larger,
}

impl FovAxis {
    /// The axis Mitsuba names so (`x`, `y`, `diagonal`, `smaller`, `larger`).
    pub fn from_name(name: &str) -> Option<FovAxis> {
        Some(match name {
            "x" => FovAxis::X,
            "y" => FovAxis::Y,
            "diagonal" => FovAxis::Diagonal,
            "smaller" => FovAxis::Smaller,
            "larger" => FovAxis::Larger,
            _ => return None,
        })
    }

    /// tan of half the field of view across and up a `w` × `h` image
    /// whose field of view along this axis is `fov_degrees`.
    pub fn tan_half(self, fov_degrees: f32, w: u32, h: u32) -> glam::Vec2 {
        let (w, h) = (w.max(1) as f32, h.max(1) as f32);
        let t = (fov_degrees.to_radians() / 2.0).tan();
        let across = match self {
            FovAxis::X => t,
            FovAxis::Y => t * w / h,
            FovAxis::Diagonal => t * w / w.hypot(h),
            FovAxis::Smaller if w < h => t,
            FovAxis::Larger if w > h => t,
            FovAxis::Smaller | FovAxis::Larger => t * w / h,
        };
        glam::Vec2::new(across, across * h / w)
    }
}

/// A light with its location.
#[derive(Clone, Debug, PartialEq)]
pub struct LightDesc {
    /// Definition.
    pub kind: LightKind,
    /// Source locations.
    pub locs: Locs,
}

impl LightDesc {
    /// A light with no source location (for scenes built in code).
    pub fn new(kind: LightKind) -> LightDesc {
        LightDesc {
            kind,
            locs: Locs::default(),
        }
    }
}

/// One step of a shape's transform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TransformOp {
    /// Translation.
    Translate(Vec3),
    /// Rotation about an axis by degrees (right-hand rule).
    Rotate {
        /// Axis.
        axis: Vec3,
        /// Angle in degrees.
        degrees: f32,
    },
    /// Scale per axis.
    Scale(Vec3),
    /// Shear factors (see [`Transform::shear`]).
    Shear {
        /// x += xy·y
        xy: f32,
        /// x += xz·z
        xz: f32,
        /// y += yx·x
        yx: f32,
        /// y += yz·z
        yz: f32,
        /// z += zx·x
        zx: f32,
        /// z += zy·y
        zy: f32,
    },
    /// A full 4×4 affine matrix.
    Matrix(Mat4),
}

impl TransformOp {
    /// The transform of this step.
    pub fn to_transform(&self) -> Result<Transform, crate::geometry::transform::TransformError> {
        match *self {
            TransformOp::Translate(t) => {
                if t.is_finite() {
                    Ok(Transform::translate(t))
                } else {
                    Err(crate::geometry::transform::TransformError::NotFinite)
                }
            }
            TransformOp::Rotate { axis, degrees } => Transform::rotate(axis, degrees),
            TransformOp::Scale(s) => Transform::scale(s),
            TransformOp::Shear { xy, xz, yx, yz, zx, zy } => Transform::shear(xy, xz, yx, yz, zx, zy),
            TransformOp::Matrix(m) => Transform::from_matrix(m),
        }
    }

    /// The name of this step in scene files.
    pub fn name(&self) -> &'static str {
        match self {
            TransformOp::Translate(_) => "translate",
            TransformOp::Rotate { .. } => "rotate",
            TransformOp::Scale(_) => "scale",
            TransformOp::Shear { .. } => "shear",
            TransformOp::Matrix(_) => "matrix",
        }
    }
}

/// The geometry of a shape.
#[derive(Clone, Debug, PartialEq)]
pub enum ShapeKind {
    /// Sphere.
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius.
        radius: f32,
    },
    /// Infinite plane.
    Plane {
        /// A point on it.
        point: Vec3,
        /// Normal (front side).
        normal: Vec3,
    },
    /// Parallelogram.
    Rectangle {
        /// Corner.
        corner: Vec3,
        /// First edge.
        edge_u: Vec3,
        /// Second edge.
        edge_v: Vec3,
    },
    /// Disk.
    Disk {
        /// Centre.
        center: Vec3,
        /// Normal (front side).
        normal: Vec3,
        /// Radius.
        radius: f32,
        /// Which surface coordinate is the angle.
        uv: crate::geometry::DiskUv,
    },
    /// Axis-aligned box (before its transform).
    Cuboid {
        /// Lower corner.
        min: Vec3,
        /// Upper corner.
        max: Vec3,
    },
    /// Open cylinder (a tube without end caps).
    Cylinder {
        /// Centre of one end.
        p0: Vec3,
        /// Centre of the other end.
        p1: Vec3,
        /// Radius.
        radius: f32,
    },
    /// A signed distance function sampled on a grid over [0, 1]³ (before
    /// its transform).
    SdfGrid(std::sync::Arc<crate::geometry::sdf_grid::SdfGrid>),
    /// A tree of signed distance functions, sphere traced (before its
    /// transform).
    Sdf(std::sync::Arc<crate::geometry::sdf::Sdf>),
    /// The surface of an equation f(x, y, z) = 0 within a box (before its
    /// transform).
    Implicit(std::sync::Arc<crate::geometry::implicit::ImplicitSurface>),
    /// A quadric cut to heights and angles about its z axis (before its
    /// transform).
    Quadric(crate::geometry::quadric::Quadric),
    /// A bilinear patch through four corners (before its transform).
    Bilinear(crate::geometry::bilinear::BilinearPatch),
    /// A bicubic Bézier patch, intersected directly.
    Bezier(std::sync::Arc<crate::geometry::bezier::BezierPatch>),
    /// A piece of a cubic Bézier curve (pbrt-v4's `curve`).
    Curve(crate::geometry::curve::Curve),
    /// A named mesh from the scene's meshes.
    Mesh(String),
    /// A mesh given with the shape itself.
    InlineMesh(MeshSource),
}

/// A shape placed in the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeDesc {
    /// Geometry.
    pub kind: ShapeKind,
    /// Transform steps, applied in order (the first to the object first).
    pub transform: Vec<TransformOp>,
    /// Material name; `None`: the default grey diffuse material.
    pub material: Option<String>,
    /// Swap the front and back sides (Mitsuba's `flip_normals`, pbrt's
    /// `ReverseOrientation`).
    pub flip_normals: bool,
    /// The media inside and outside the shape; `None`: the shape does not
    /// bound a medium, and rays keep theirs when they cross it.
    pub media: Option<MediumInterfaceDesc>,
    /// How the shape moves while the shutter is open (motion blur); `None`:
    /// it stands still, placed by `transform`.
    pub motion: Option<MotionDesc>,
    /// Source locations.
    pub locs: Locs,
}

/// A shape's motion: `transform` places it at the first time, `end` at
/// the second; in between it moves as pbrt-v4's animated transforms do
/// ([`crate::geometry::motion::MotionTransform`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MotionDesc {
    /// Transform steps at the second time, applied in order.
    pub end: Vec<TransformOp>,
    /// The times of the two transforms, the first smaller.
    pub times: (f32, f32),
}

/// The media on the two sides of a surface, by name; `None`: vacuum.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MediumInterfaceDesc {
    /// The medium inside (behind the surface's front side).
    pub inside: Option<String>,
    /// The medium outside.
    pub outside: Option<String>,
}

/// Where a grid's values come from.
#[derive(Clone, Debug, PartialEq)]
pub enum GridSource {
    /// A Mitsuba `.vol` file, relative to the scene file.
    MitsubaVol(PathBuf),
    /// The grid named `grid` of a NanoVDB file, relative to the scene
    /// file, placed by its own index-to-world map before `to_world`.
    NanoVdb {
        /// The file.
        path: PathBuf,
        /// The grid's name.
        grid: String,
    },
    /// Values given in the scene.
    Data(Arc<crate::media::VoxelGrid>),
}

/// A property of a medium (σt, albedo, emission).
#[derive(Clone, Debug, PartialEq)]
pub enum FieldDesc {
    /// The same value everywhere.
    Constant(Rgb),
    /// One value inside the unit cube mapped by `to_world` (Mitsuba's
    /// `constvolume`), which bounds the medium when it gives σt.
    Boxed {
        /// The value.
        value: Rgb,
        /// Transform steps from the unit cube to the world.
        to_world: Vec<TransformOp>,
    },
    /// A voxel grid over the unit cube mapped by `to_world`.
    Grid {
        /// The values.
        source: GridSource,
        /// Transform steps from the unit cube to the world.
        to_world: Vec<TransformOp>,
        /// Whether the grid spans the box its file gives (inside the
        /// unit cube's space) rather than the unit cube.
        use_file_bounds: bool,
    },
    /// pbrt-v4's procedural cloud (see [`crate::media::CloudField`]): the
    /// value times the cloud's density in the box [p0, p1] of the space
    /// `to_world` maps, which bounds the medium when it gives σt.
    Cloud {
        /// The value where the density is 1.
        value: Rgb,
        /// `density`, `wispiness` and `frequency`.
        density: f32,
        /// See [`crate::media::CloudField::wispiness`].
        wispiness: f32,
        /// See [`crate::media::CloudField::frequency`].
        frequency: f32,
        /// The box in the medium's space.
        p0: Vec3,
        /// Its far corner.
        p1: Vec3,
        /// Transform steps from the medium's space to the world.
        to_world: Vec<TransformOp>,
    },
}

/// A named participating medium (see [`crate::media::Medium`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MediumDesc {
    /// Name that shapes and the camera refer to.
    pub name: String,
    /// Extinction coefficient σt, per unit length; a grid or box here
    /// confines the medium to its box.
    pub sigma_t: FieldDesc,
    /// Single-scattering albedo σs/σt, in [0, 1].
    pub albedo: FieldDesc,
    /// Emitted radiance, if any.
    pub emission: Option<FieldDesc>,
    /// Multiplier of σt, per channel.
    pub scale: Rgb,
    /// Henyey–Greenstein asymmetry g in (−1, 1); 0: isotropic.
    pub g: f32,
    /// Source locations.
    pub locs: Locs,
}

impl ShapeDesc {
    /// A shape with no transform.
    pub fn new(kind: ShapeKind, material: Option<&str>) -> ShapeDesc {
        ShapeDesc {
            kind,
            transform: Vec::new(),
            material: material.map(str::to_string),
            flip_normals: false,
            media: None,
            motion: None,
            locs: Locs::default(),
        }
    }

    /// The same shape with one more transform step.
    pub fn with(mut self, op: TransformOp) -> ShapeDesc {
        self.transform.push(op);
        self
    }
}

/// What rays leaving the scene see (and, in the path tracer, the light
/// that arrives from infinitely far away).
#[derive(Clone, Debug, PartialEq)]
pub enum BackgroundDesc {
    /// One colour.
    Constant(Rgb),
    /// Vertical gradient.
    Gradient {
        /// Looking up.
        top: Rgb,
        /// Looking down.
        bottom: Rgb,
    },
    /// An environment image.
    Image {
        /// Path, relative to the scene file.
        path: PathBuf,
        /// Radiance multiplier.
        scale: f32,
        /// Rotation of the map (steps applied to directions).
        transform: Vec<TransformOp>,
        /// How the image's pixels map to directions.
        layout: EnvironmentLayout,
        /// pbrt-v4's `illuminance` of an image infinite light (equal-area
        /// maps only): `scale` is multiplied by it over the illuminance
        /// pbrt-v4 computes for the map's upper hemisphere (+z of its
        /// frame), Σ luminance·cos θ over those pixels × 2π/N for N pixels
        /// (pbrt-v4's sum, which gives each pixel 2π/N steradians where
        /// it subtends 4π/N).
        illuminance: Option<f32>,
    },
    /// Several environments lighting the scene together (pbrt-v4's
    /// infinite lights, of which a scene may have any number): constants
    /// and images, made into one map (`EnvironmentMap::summed`).
    Sum(Vec<BackgroundDesc>),
}

/// How an environment image's pixels map to directions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EnvironmentLayout {
    /// Latitude–longitude (equirectangular), Mitsuba's convention: +y up,
    /// bilinear between pixel centres.
    #[default]
    LatLong,
    /// pbrt-v4's equal-area octahedral square (Clarberg 2008): +z at the
    /// centre, −z at the corners, every pixel the same solid angle, each
    /// looked up as the nearest pixel (as pbrt-v4's `ImageInfiniteLight`).
    EqualAreaOctahedral,
}

/// A complete scene description.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneDesc {
    /// The file it was read from, which relative paths are resolved
    /// against; `None` for scenes built in code.
    pub source: Option<Arc<Path>>,
    /// Render settings.
    pub settings: RenderSettings,
    /// Where the settings were written.
    pub settings_locs: Locs,
    /// Camera.
    pub camera: CameraDesc,
    /// Background.
    pub background: BackgroundDesc,
    /// A portal (four corners of a rectangle, in order, in world space)
    /// through which alone the background lights the scene (pbrt-v4's
    /// `portal`); `None`: the whole background.
    pub portal: Option<[Vec3; 4]>,
    /// Ambient light for the Whitted integrator's ambient term.
    pub ambient: Rgb,
    /// Where the world settings were written.
    pub world_locs: Locs,
    /// Named textures.
    pub textures: Vec<TextureDesc>,
    /// Named materials.
    pub materials: Vec<MaterialDesc>,
    /// Named meshes.
    pub meshes: Vec<MeshDesc>,
    /// Lights.
    pub lights: Vec<LightDesc>,
    /// Shapes.
    pub shapes: Vec<ShapeDesc>,
    /// Participating media.
    pub media: Vec<MediumDesc>,
    /// The medium the camera is in; `None`: vacuum.
    pub camera_medium: Option<String>,
    /// Problems the reader found that did not stop it (unsupported or
    /// approximated elements), each naming its place in the file.
    pub warnings: Vec<String>,
    /// The image file the scene names for its render (pbrt-v4's `Film`
    /// `filename`), relative to the current folder as pbrt-v4 writes it;
    /// where it was written is `settings_locs`' key "output". `None`: the
    /// scene names none.
    pub output: Option<std::path::PathBuf>,
    /// A sampler study to run instead of rendering (pbrt-v4's `Integrator
    /// "function"`); where it was written is `settings_locs`' key
    /// "integrator".
    pub sampler_study: Option<crate::settings::SamplerStudy>,
}

impl Default for SceneDesc {
    fn default() -> Self {
        SceneDesc {
            source: None,
            settings: RenderSettings::default(),
            settings_locs: Locs::default(),
            camera: CameraDesc::default(),
            background: BackgroundDesc::Constant(Rgb::ZERO),
            portal: None,
            ambient: Rgb::ZERO,
            world_locs: Locs::default(),
            textures: Vec::new(),
            materials: Vec::new(),
            meshes: Vec::new(),
            lights: Vec::new(),
            shapes: Vec::new(),
            media: Vec::new(),
            camera_medium: None,
            warnings: Vec::new(),
            output: None,
            sampler_study: None,
        }
    }
}

/// Checks that builds one error message at a time.
struct Check<'a> {
    locs: &'a Locs,
    prefix: String,
}

impl Check<'_> {
    fn err(&self, key: &str, msg: impl Into<String>) -> Error {
        Error::scene(self.locs.key(key), format!("{}{}", self.prefix, key), msg)
    }
    fn finite(&self, key: &str, v: f32) -> Result<()> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(self.err(key, format!("must be a finite number, got {v}")))
        }
    }
    fn positive(&self, key: &str, v: f32) -> Result<()> {
        self.finite(key, v)?;
        if v > 0.0 {
            Ok(())
        } else {
            Err(self.err(key, format!("must be positive, got {v}")))
        }
    }
    fn non_negative(&self, key: &str, v: f32) -> Result<()> {
        self.finite(key, v)?;
        if v >= 0.0 {
            Ok(())
        } else {
            Err(self.err(key, format!("must not be negative, got {v}")))
        }
    }
    fn vec3(&self, key: &str, v: Vec3) -> Result<()> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(self.err(key, format!("must be finite, got [{}, {}, {}]", v.x, v.y, v.z)))
        }
    }
    fn nonzero_vec3(&self, key: &str, v: Vec3) -> Result<()> {
        self.vec3(key, v)?;
        if v.length_squared() > 0.0 {
            Ok(())
        } else {
            Err(self.err(key, "must not be the zero vector"))
        }
    }
    fn color(&self, key: &str, c: Rgb) -> Result<()> {
        if !c.is_finite() {
            return Err(self.err(key, format!("must be finite, got [{}, {}, {}]", c.x, c.y, c.z)));
        }
        if c.min_element() < 0.0 {
            return Err(self.err(key, format!("must not be negative, got [{}, {}, {}]", c.x, c.y, c.z)));
        }
        Ok(())
    }
}

impl SceneDesc {
    /// Whether the scene file states its samples per pixel (rather than
    /// taking its format's default).
    pub fn sets_spp(&self) -> bool {
        self.settings_locs.keys.iter().any(|(k, _)| k == "spp")
    }

    /// Checks every value and reference; the first problem found is
    /// returned with its location.
    pub fn validate(&self) -> Result<()> {
        self.validate_settings()?;
        self.validate_camera()?;
        let w = Check {
            locs: &self.world_locs,
            prefix: "world.".into(),
        };
        let terms = match &self.background {
            BackgroundDesc::Sum(terms) => terms.as_slice(),
            one => std::slice::from_ref(one),
        };
        for term in terms {
            if terms.len() > 1 && matches!(term, BackgroundDesc::Gradient { .. }) {
                return Err(w.err("background", "a sum of environments holds constants and images"));
            }
            validate_background(&w, term)?;
        }
        w.color("ambient", self.ambient)?;

        let mut names = std::collections::HashSet::new();
        for (i, t) in self.textures.iter().enumerate() {
            let c = Check {
                locs: &t.locs,
                prefix: format!("texture[{i}]."),
            };
            if names.contains(t.name.as_str()) {
                return Err(c.err("name", format!("a texture named \"{}\" is already defined", t.name)));
            }
            // A texture is made of textures defined before it: no cycles.
            let inputs = match &t.kind {
                TextureKind::Node(node) => node.inputs(),
                _ => vec![],
            };
            for (key, input) in inputs {
                match input {
                    // Inputs may be negative (a float texture's).
                    ColorSource::Rgb(col) => c.vec3(key, *col)?,
                    ColorSource::Texture(name) if !names.contains(name.as_str()) => {
                        return Err(c.err(
                            key,
                            format!(
                                "no texture named \"{name}\" before this one{}",
                                suggest(name, names.iter().copied())
                            ),
                        ));
                    }
                    ColorSource::Texture(_) => {}
                }
            }
            names.insert(t.name.as_str());
            let mapping = |m: &Mapping2D| -> Result<()> {
                let finite = match m {
                    Mapping2D::Uv { scale, offset } => scale.is_finite() && offset.is_finite(),
                    Mapping2D::UvAffine { u_axis, v_axis, offset } => {
                        u_axis.is_finite() && v_axis.is_finite() && offset.is_finite()
                    }
                    Mapping2D::Spherical { to_texture } | Mapping2D::Cylindrical { to_texture } => {
                        to_texture.is_finite()
                    }
                    Mapping2D::Planar {
                        to_texture,
                        s_axis,
                        t_axis,
                        offset,
                    } => to_texture.is_finite() && s_axis.is_finite() && t_axis.is_finite() && offset.is_finite(),
                };
                if finite {
                    Ok(())
                } else {
                    Err(c.err("mapping", "the mapping's numbers must be finite"))
                }
            };
            match &t.kind {
                TextureKind::Constant(col) => c.color("color", *col)?,
                TextureKind::Checkerboard { even, odd, scale } => {
                    c.color("even", *even)?;
                    c.color("odd", *odd)?;
                    c.positive("scale", scale.x)?;
                    c.positive("scale", scale.y)?;
                }
                TextureKind::Checkerboard3d { even, odd, scale } => {
                    c.color("even", *even)?;
                    c.color("odd", *odd)?;
                    c.positive("scale", *scale)?;
                }
                TextureKind::MeshAttribute { name } => {
                    if !(name.starts_with("vertex_") || name.starts_with("face_")) {
                        return Err(c.err(
                            "name",
                            format!("\"{name}\" names no mesh attribute: their names start with vertex_ or face_"),
                        ));
                    }
                }
                TextureKind::Image {
                    scale, offset, tint, ..
                } => {
                    c.finite("scale", scale.x)?;
                    c.finite("scale", scale.y)?;
                    c.finite("offset", offset.x)?;
                    c.finite("offset", offset.y)?;
                    c.color("tint", *tint)?;
                }
                TextureKind::Node(node) => match node {
                    TextureNode::Scale { .. } | TextureNode::Mix { .. } | TextureNode::Invert(_) => {}
                    TextureNode::Cutoff { cutoff, .. } => c.finite("cutoff", *cutoff)?,
                    TextureNode::Channel { channel, .. } => {
                        if *channel > 2 {
                            return Err(c.err("channel", format!("must be 0, 1 or 2, got {channel}")));
                        }
                    }
                    TextureNode::DirectionMix { dir, .. } => {
                        if !dir.is_finite() || dir.length_squared() == 0.0 {
                            return Err(c.err("direction", "must be a finite, non-zero direction"));
                        }
                    }
                    TextureNode::Checkerboard { mapping: m, .. }
                    | TextureNode::Dots { mapping: m, .. }
                    | TextureNode::Mapped { mapping: m, .. } => mapping(m)?,
                    TextureNode::Bilerp { corners, mapping: m } => {
                        for col in corners {
                            c.color("corners", *col)?;
                        }
                        mapping(m)?;
                    }
                    TextureNode::SolidCheckerboard { to_texture, .. } | TextureNode::Noise { to_texture, .. } => {
                        if !to_texture.is_finite() {
                            return Err(c.err("transform", "the texture's transform must be finite"));
                        }
                        if let TextureNode::Noise { pattern, .. } = node {
                            let (octaves, numbers) = match *pattern {
                                NoisePattern::Fbm { octaves, omega } | NoisePattern::Wrinkled { octaves, omega } => {
                                    (octaves, vec![omega])
                                }
                                NoisePattern::Windy => (0, vec![]),
                                NoisePattern::Marble {
                                    octaves,
                                    omega,
                                    scale,
                                    variation,
                                } => (octaves, vec![omega, scale, variation]),
                            };
                            if octaves > MAX_NOISE_OCTAVES {
                                return Err(
                                    c.err("octaves", format!("must be at most {MAX_NOISE_OCTAVES}, got {octaves}"))
                                );
                            }
                            for v in numbers {
                                c.finite("roughness", v)?;
                            }
                        }
                    }
                },
            }
        }

        let mut names = std::collections::HashSet::new();
        for (i, m) in self.materials.iter().enumerate() {
            let c = Check {
                locs: &m.locs,
                prefix: format!("material[{i}]."),
            };
            if !names.insert(m.name.as_str()) {
                return Err(c.err("name", format!("a material named \"{}\" is already defined", m.name)));
            }
            let texture = |key: &str, src: &ColorSource| -> Result<()> {
                match src {
                    ColorSource::Rgb(col) => c.color(key, *col),
                    ColorSource::Texture(name) => {
                        if self.textures.iter().any(|t| &t.name == name) {
                            Ok(())
                        } else {
                            Err(c.err(
                                key,
                                format!(
                                    "no texture named \"{name}\"{}",
                                    suggest(name, self.textures.iter().map(|t| t.name.as_str()))
                                ),
                            ))
                        }
                    }
                }
            };
            let ior = |key: &str, v: f32| -> Result<()> {
                c.finite(key, v)?;
                if v <= 0.0 {
                    return Err(c.err(key, format!("index of refraction must be positive, got {v}")));
                }
                Ok(())
            };
            // An index that varies must stay physical over the visible range.
            let dispersion_range = |key: &str, d: Option<&crate::material::dispersion::IorSpectrum>| -> Result<()> {
                let Some((lo, hi)) = d.map(|d| d.visible_range()) else {
                    return Ok(());
                };
                if lo > 0.0 && hi.is_finite() {
                    return Ok(());
                }
                Err(c.err(
                    key,
                    format!("index of refraction must be positive and finite over 360-830 nm, ranges over {lo}..{hi}"),
                ))
            };
            let roughness = |key: &str, v: f32| -> Result<()> {
                c.non_negative(key, v)?;
                if v > 1.0 {
                    return Err(c.err(key, format!("roughness (GGX α) must be between 0 and 1, got {v}")));
                }
                Ok(())
            };
            if let Some(o) = &m.opacity {
                texture("opacity", o)?;
            }
            if let Some(n) = &m.normal_map {
                texture("normal_map", &n.texture)?;
                c.finite("normal_scale", n.scale)?;
            }
            if let Some(b) = &m.bump_map {
                texture("bump_map", &b.height)?;
                c.finite("bump_scale", b.scale)?;
                if m.normal_map.is_some() {
                    return Err(c.err("bump_map", "a material takes a normal map or a bump map, not both"));
                }
            }
            if let Some(r) = &m.roughness_map {
                texture("roughness_texture", &r.u)?;
                texture("roughness_texture", &r.v)?;
                if !matches!(
                    m.kind,
                    MaterialKindDesc::Conductor { .. }
                        | MaterialKindDesc::Dielectric { .. }
                        | MaterialKindDesc::Layered { .. }
                ) {
                    return Err(c.err(
                        "roughness_texture",
                        "a roughness texture applies to conductors, dielectrics and the coats of layered materials only",
                    ));
                }
            }
            match &m.kind {
                MaterialKindDesc::Classic(cl) => {
                    texture("diffuse", &cl.diffuse)?;
                    texture("specular", &cl.specular)?;
                    c.non_negative("shininess", cl.shininess)?;
                    c.color("reflectivity", cl.reflectivity)?;
                    c.color("transmission", cl.transmission)?;
                    ior("ior", cl.ior)?;
                }
                MaterialKindDesc::Diffuse { reflectance } => texture("reflectance", reflectance)?,
                MaterialKindDesc::DiffuseTransmission {
                    reflectance,
                    transmittance,
                } => {
                    texture("reflectance", reflectance)?;
                    texture("transmittance", transmittance)?;
                }
                MaterialKindDesc::Conductor {
                    fresnel,
                    tint,
                    roughness: (ax, ay),
                    ..
                } => {
                    match fresnel {
                        ConductorDesc::Complex { eta, k } => {
                            c.color("eta", *eta)?;
                            c.color("k", *k)?;
                            if eta.min_element() <= 0.0 {
                                return Err(c.err("eta", "must be positive"));
                            }
                        }
                        ConductorDesc::Reflectance(r) | ConductorDesc::Mirror(r) => c.color("reflectance", *r)?,
                    }
                    c.color("tint", *tint)?;
                    roughness("roughness", *ax)?;
                    roughness("roughness", *ay)?;
                }
                MaterialKindDesc::Dielectric {
                    ior: int,
                    ext_ior,
                    roughness: r,
                    reflect_tint,
                    transmit_tint,
                    dispersion,
                    ..
                } => {
                    ior("ior", *int)?;
                    ior("ext_ior", *ext_ior)?;
                    dispersion_range("ior", dispersion.as_ref())?;
                    roughness("roughness", r.0)?;
                    roughness("roughness", r.1)?;
                    c.color("reflect_tint", *reflect_tint)?;
                    c.color("transmit_tint", *transmit_tint)?;
                }
                MaterialKindDesc::Plastic {
                    diffuse,
                    ior: int,
                    ext_ior,
                    roughness: r,
                    specular_tint,
                    ..
                } => {
                    texture("diffuse", diffuse)?;
                    ior("ior", *int)?;
                    ior("ext_ior", *ext_ior)?;
                    if int == ext_ior {
                        return Err(c.err("ior", "a plastic coat needs `ior` different from `ext_ior`"));
                    }
                    roughness("roughness", *r)?;
                    c.color("specular_tint", *specular_tint)?;
                }
                MaterialKindDesc::Layered {
                    base,
                    coat_ior,
                    coat_roughness: (cx, cy),
                    thickness,
                    albedo,
                    g,
                    max_depth,
                    samples,
                    coat_dispersion,
                } => {
                    dispersion_range("coat_ior", coat_dispersion.as_ref())?;
                    match base {
                        LayeredBaseDesc::Diffuse(r) => texture("reflectance", r)?,
                        LayeredBaseDesc::Conductor {
                            fresnel,
                            roughness: (ax, ay),
                            roughness_map,
                        } => {
                            if let Some(r) = roughness_map {
                                texture("conductor.roughness", &r.u)?;
                                texture("conductor.roughness", &r.v)?;
                            }
                            match fresnel {
                                ConductorDesc::Complex { eta, k } => {
                                    c.color("conductor.eta", *eta)?;
                                    c.color("conductor.k", *k)?;
                                    if eta.min_element() <= 0.0 {
                                        return Err(c.err("conductor.eta", "must be positive"));
                                    }
                                }
                                ConductorDesc::Reflectance(r) | ConductorDesc::Mirror(r) => {
                                    c.color("reflectance", *r)?
                                }
                            }
                            roughness("conductor.roughness", *ax)?;
                            roughness("conductor.roughness", *ay)?;
                        }
                    }
                    ior("interface.eta", *coat_ior)?;
                    roughness("interface.roughness", *cx)?;
                    roughness("interface.roughness", *cy)?;
                    if !(thickness.is_finite() && *thickness > 0.0) {
                        return Err(c.err("thickness", format!("must be positive, got {thickness}")));
                    }
                    c.color("albedo", *albedo)?;
                    if albedo.max_element() > 1.0 {
                        return Err(c.err("albedo", "must be at most 1"));
                    }
                    if !(-1.0..=1.0).contains(g) {
                        return Err(c.err("g", format!("must be in [-1, 1], got {g}")));
                    }
                    if *max_depth == 0 || *max_depth > 4096 {
                        return Err(c.err("maxdepth", format!("must be 1 to 4096, got {max_depth}")));
                    }
                    if *samples == 0 || *samples > 4096 {
                        return Err(c.err("nsamples", format!("must be 1 to 4096, got {samples}")));
                    }
                }
                MaterialKindDesc::Thin {
                    ior: int,
                    ext_ior,
                    reflect_tint,
                    transmit_tint,
                    dispersion,
                } => {
                    ior("ior", *int)?;
                    ior("ext_ior", *ext_ior)?;
                    dispersion_range("ior", dispersion.as_ref())?;
                    c.color("reflect_tint", *reflect_tint)?;
                    c.color("transmit_tint", *transmit_tint)?;
                }
                MaterialKindDesc::Principled { params, eta, .. } => {
                    for (key, t) in params.named() {
                        texture(key, t)?;
                    }
                    ior("eta", *eta)?;
                }
                MaterialKindDesc::Hair(h) => {
                    c.color("sigma_a", h.sigma_a)?;
                    ior("eta", h.eta)?;
                    for (key, b) in [("beta_m", h.beta_m), ("beta_n", h.beta_n)] {
                        if !(0.0..=1.0).contains(&b) {
                            return Err(c.err(key, format!("must be in [0, 1], got {b}")));
                        }
                    }
                    if !h.alpha.is_finite() || h.alpha.abs() > 90.0 {
                        return Err(c.err(
                            "alpha",
                            format!("must be an angle in [-90, 90] degrees, got {}", h.alpha),
                        ));
                    }
                }
                MaterialKindDesc::Measured { file } => {
                    if file.as_os_str().is_empty() {
                        return Err(c.err("file", "names no file"));
                    }
                }
                MaterialKindDesc::Mix { choice, materials } => {
                    if let MixChoice::Weight(weight) = choice {
                        texture("weight", weight)?;
                    }
                    for name in materials {
                        if !self.materials.iter().any(|other| &other.name == name) {
                            return Err(c.err(
                                "materials",
                                format!(
                                    "no material named \"{name}\"{}",
                                    suggest(name, self.materials.iter().map(|m| m.name.as_str()))
                                ),
                            ));
                        }
                    }
                    // Follow the first materials down: a chain deeper than
                    // the limit is a cycle or absurd.
                    let mut depth = 0;
                    let mut stack: Vec<&str> = materials.iter().map(String::as_str).collect();
                    while let Some(name) = stack.pop() {
                        let Some(MaterialKindDesc::Mix { materials: inner, .. }) =
                            self.materials.iter().find(|o| o.name == name).map(|o| &o.kind)
                        else {
                            continue;
                        };
                        depth += 1;
                        if depth > MAX_MIX_DEPTH * MAX_MIX_DEPTH || inner.iter().any(|n| n == &m.name) {
                            return Err(c.err(
                                "materials",
                                format!(
                                    "mixes nest in a cycle, or deeper than {MAX_MIX_DEPTH} levels, below \"{}\"",
                                    m.name
                                ),
                            ));
                        }
                        stack.extend(inner.iter().map(String::as_str));
                    }
                }
            }
            texture("emission", &m.emission)?;
        }

        let mut names = std::collections::HashSet::new();
        for (i, m) in self.meshes.iter().enumerate() {
            let c = Check {
                locs: &m.locs,
                prefix: format!("mesh[{i}]."),
            };
            if !names.insert(m.name.as_str()) {
                return Err(c.err("name", format!("a mesh named \"{}\" is already defined", m.name)));
            }
            validate_mesh_source(&c, &m.source)?;
        }

        for (i, l) in self.lights.iter().enumerate() {
            let c = Check {
                locs: &l.locs,
                prefix: format!("light[{i}]."),
            };
            match &l.kind {
                LightKind::Point {
                    position, intensity, ..
                } => {
                    c.vec3("position", *position)?;
                    c.color("intensity", *intensity)?;
                }
                LightKind::Spot {
                    position,
                    to,
                    intensity,
                    inner_angle,
                    outer_angle,
                    ..
                } => {
                    c.vec3("position", *position)?;
                    c.vec3("to", *to)?;
                    if (*to - *position).length_squared() == 0.0 {
                        return Err(c.err("to", "must differ from `position`"));
                    }
                    c.color("intensity", *intensity)?;
                    c.non_negative("inner_angle", *inner_angle)?;
                    c.positive("outer_angle", *outer_angle)?;
                    if *outer_angle > 180.0 {
                        return Err(c.err("outer_angle", format!("must be at most 180 degrees, got {outer_angle}")));
                    }
                    if inner_angle > outer_angle {
                        return Err(c.err(
                            "inner_angle",
                            format!("must not exceed outer_angle ({outer_angle}), got {inner_angle}"),
                        ));
                    }
                    if let LightKind::Spot {
                        projection: Some(image),
                        ..
                    } = &l.kind
                    {
                        if *outer_angle >= 90.0 {
                            return Err(c.err(
                                "outer_angle",
                                format!("must be below 90 degrees for a projected image, got {outer_angle}"),
                            ));
                        }
                        let det = image.to_world.determinant();
                        if !(det.is_finite() && det != 0.0) {
                            return Err(c.err("texture", "the light's transform is singular"));
                        }
                        if !self.textures.iter().any(|t| t.name == image.texture) {
                            return Err(c.err("texture", format!("no texture named \"{}\"", image.texture)));
                        }
                    }
                }
                LightKind::Projector {
                    position,
                    to_world,
                    fov,
                    irradiance,
                    scale,
                    power,
                    ..
                } => {
                    c.vec3("position", *position)?;
                    if let Some(power) = power {
                        c.positive("power", *power)?;
                    }
                    let det = to_world.determinant();
                    if !(det.is_finite() && det != 0.0) {
                        return Err(c.err("to_world", "the light's transform is singular"));
                    }
                    c.positive("fov", *fov)?;
                    if *fov >= 180.0 {
                        return Err(c.err("fov", format!("must be below 180 degrees, got {fov}")));
                    }
                    c.non_negative("scale", *scale)?;
                    match irradiance {
                        ColorSource::Rgb(rgb) => c.color("irradiance", *rgb)?,
                        ColorSource::Texture(t) => {
                            if !self.textures.iter().any(|x| &x.name == t) {
                                return Err(c.err("irradiance", format!("no texture named \"{t}\"")));
                            }
                        }
                    }
                }
                LightKind::Goniometric {
                    position,
                    to_world,
                    intensity,
                    image,
                    power,
                } => {
                    c.vec3("position", *position)?;
                    let det = to_world.determinant();
                    if !(det.is_finite() && det != 0.0) {
                        return Err(c.err("to_world", "the light's transform is singular"));
                    }
                    c.color("intensity", *intensity)?;
                    if let Some(power) = power {
                        c.positive("power", *power)?;
                    }
                    if !self.textures.iter().any(|t| &t.name == image) {
                        return Err(c.err("image", format!("no texture named \"{image}\"")));
                    }
                }
                LightKind::Directional { direction, irradiance } => {
                    c.nonzero_vec3("direction", *direction)?;
                    c.color("irradiance", *irradiance)?;
                }
            }
        }

        let mut names = std::collections::HashSet::new();
        for (i, m) in self.media.iter().enumerate() {
            let c = Check {
                locs: &m.locs,
                prefix: format!("medium[{i}]."),
            };
            if !names.insert(m.name.as_str()) {
                return Err(c.err("name", format!("a medium named \"{}\" is already defined", m.name)));
            }
            let field = |key: &str, f: &FieldDesc, at_most_one: bool| -> Result<()> {
                let value = match f {
                    FieldDesc::Constant(v) | FieldDesc::Boxed { value: v, .. } | FieldDesc::Cloud { value: v, .. } => {
                        Some(*v)
                    }
                    FieldDesc::Grid { .. } => None,
                };
                if let FieldDesc::Cloud {
                    density,
                    wispiness,
                    frequency,
                    p0,
                    p1,
                    ..
                } = f
                {
                    if !([*density, *wispiness, *frequency].iter().all(|x| x.is_finite())
                        && p0.is_finite()
                        && p1.is_finite())
                    {
                        return Err(c.err(key, "a cloud's density, wispiness, frequency and box must be finite"));
                    }
                }
                if let Some(v) = value {
                    c.color(key, v)?;
                    if at_most_one && v.max_element() > 1.0 {
                        return Err(c.err(key, "must lie in [0, 1]"));
                    }
                }
                if let FieldDesc::Boxed { to_world, .. }
                | FieldDesc::Grid { to_world, .. }
                | FieldDesc::Cloud { to_world, .. } = f
                {
                    for op in to_world {
                        op.to_transform()
                            .map_err(|e| c.err(key, format!("transform {}: {e}", op.name())))?;
                    }
                }
                Ok(())
            };
            field("sigma_t", &m.sigma_t, false)?;
            field("albedo", &m.albedo, true)?;
            if let Some(e) = &m.emission {
                field("emission", e, false)?;
            }
            c.color("scale", m.scale)?;
            if !(m.g > -1.0 && m.g < 1.0) {
                return Err(c.err("g", format!("must lie strictly between -1 and 1, not {}", m.g)));
            }
        }
        let medium_exists = |c: &Check, key: &str, name: &Option<String>| -> Result<()> {
            match name {
                Some(n) if !self.media.iter().any(|m| &m.name == n) => Err(c.err(
                    key,
                    format!(
                        "no medium named \"{n}\"{}",
                        suggest(n, self.media.iter().map(|m| m.name.as_str()))
                    ),
                )),
                _ => Ok(()),
            }
        };
        medium_exists(
            &Check {
                locs: &self.camera.locs,
                prefix: "camera.".into(),
            },
            "medium",
            &self.camera_medium,
        )?;

        for (i, s) in self.shapes.iter().enumerate() {
            let c = Check {
                locs: &s.locs,
                prefix: format!("shape[{i}]."),
            };
            if let Some(mi) = &s.media {
                medium_exists(&c, "inside", &mi.inside)?;
                medium_exists(&c, "outside", &mi.outside)?;
                let mix = s.material.as_ref().is_some_and(|name| {
                    self.materials
                        .iter()
                        .any(|m| &m.name == name && matches!(m.kind, MaterialKindDesc::Mix { .. }))
                });
                if mix {
                    return Err(c.err(
                        "material",
                        "a mix material cannot bound a medium in trazo: give the shape one material",
                    ));
                }
            }
            if let Some(m) = &s.motion {
                c.finite("motion_times", m.times.0)?;
                c.finite("motion_times", m.times.1)?;
                if m.times.0 >= m.times.1 {
                    return Err(c.err(
                        "motion_times",
                        format!("must increase, got {} then {}", m.times.0, m.times.1),
                    ));
                }
            }
            match &s.kind {
                ShapeKind::Sphere { center, radius } => {
                    c.vec3("center", *center)?;
                    c.positive("radius", *radius)?;
                }
                ShapeKind::Plane { point, normal } => {
                    c.vec3("point", *point)?;
                    c.nonzero_vec3("normal", *normal)?;
                }
                ShapeKind::Rectangle { corner, edge_u, edge_v } => {
                    c.vec3("corner", *corner)?;
                    c.nonzero_vec3("edge_u", *edge_u)?;
                    c.nonzero_vec3("edge_v", *edge_v)?;
                    if edge_u.cross(*edge_v).length_squared() == 0.0 {
                        return Err(c.err("edge_v", "is parallel to edge_u: the rectangle has zero area"));
                    }
                }
                ShapeKind::Disk {
                    center, normal, radius, ..
                } => {
                    c.vec3("center", *center)?;
                    c.nonzero_vec3("normal", *normal)?;
                    c.positive("radius", *radius)?;
                }
                ShapeKind::Cuboid { min, max } => {
                    c.vec3("min", *min)?;
                    c.vec3("max", *max)?;
                    if !min.cmplt(*max).all() {
                        return Err(c.err("max", "must be greater than `min` on every axis"));
                    }
                }
                ShapeKind::Cylinder { p0, p1, radius } => {
                    c.vec3("p0", *p0)?;
                    c.vec3("p1", *p1)?;
                    c.positive("radius", *radius)?;
                    if (*p1 - *p0).length_squared() == 0.0 {
                        return Err(c.err("p1", "must differ from `p0`"));
                    }
                }
                ShapeKind::Mesh(name) => {
                    if !self.meshes.iter().any(|m| &m.name == name) {
                        return Err(c.err(
                            "mesh",
                            format!(
                                "no mesh named \"{name}\"{}",
                                suggest(name, self.meshes.iter().map(|m| m.name.as_str()))
                            ),
                        ));
                    }
                }
                ShapeKind::InlineMesh(src) => {
                    validate_mesh_source(&c, src)?;
                    if let MeshSource::Displaced { height, .. } = src {
                        if !self.textures.iter().any(|t| &t.name == height) {
                            return Err(c.err("height", format!("no texture named \"{height}\"")));
                        }
                    }
                }
                ShapeKind::Bilinear(b) if !b.p.iter().all(|p| p.is_finite()) => {
                    for (p, key) in b.p.iter().zip(["p00", "p10", "p01", "p11"]) {
                        c.vec3(key, p.as_vec3())?;
                    }
                }
                ShapeKind::SdfGrid(_)
                | ShapeKind::Sdf(_)
                | ShapeKind::Implicit(_)
                | ShapeKind::Quadric(_)
                | ShapeKind::Curve(_)
                | ShapeKind::Bezier(_)
                | ShapeKind::Bilinear(_) => {
                    let emits = s.material.as_ref().is_some_and(|name| {
                        self.materials
                            .iter()
                            .any(|m| &m.name == name && m.emission != ColorSource::Rgb(Rgb::ZERO))
                    });
                    let why = match &s.kind {
                        ShapeKind::Quadric(q) if q.area() > 0.0 => None,
                        ShapeKind::Quadric(_) => Some("a quadric without area (degenerate) cannot emit light"),
                        ShapeKind::Bilinear(b) if b.area() > 0.0 => None,
                        ShapeKind::Bilinear(_) => Some("a bilinear patch without area (degenerate) cannot emit light"),
                        ShapeKind::Bezier(b) if b.area() > 0.0 => None,
                        ShapeKind::Bezier(_) => Some("a Bézier patch without area (degenerate) cannot emit light"),
                        ShapeKind::Curve(_) => Some("a curve cannot emit light (nor in pbrt-v4)"),
                        // Distance functions and implicit surfaces emit:
                        // lights sample them by direction, light subpaths
                        // start on lines drawn through them.
                        _ => None,
                    };
                    if let (true, Some(why)) = (emits, why) {
                        return Err(c.err("material", why));
                    }
                }
            }
            for op in &s.transform {
                op.to_transform()
                    .map_err(|e| c.err("transform", format!("{}: {e}", op.name())))?;
            }
            if let Some(name) = &s.material {
                if !self.materials.iter().any(|m| &m.name == name) {
                    return Err(c.err(
                        "material",
                        format!(
                            "no material named \"{name}\"{}",
                            suggest(name, self.materials.iter().map(|m| m.name.as_str()))
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    fn validate_settings(&self) -> Result<()> {
        let s = &self.settings;
        let c = Check {
            locs: &self.settings_locs,
            prefix: "render.".into(),
        };
        for (key, v) in [("width", s.width), ("height", s.height)] {
            if v == 0 || v > MAX_IMAGE_SIDE {
                return Err(c.err(key, format!("must be between 1 and {MAX_IMAGE_SIDE} pixels, got {v}")));
            }
        }
        if s.width as u64 * s.height as u64 > MAX_IMAGE_PIXELS {
            return Err(c.err(
                "width",
                format!(
                    "an image of {}×{} pixels is larger than the limit of {MAX_IMAGE_PIXELS} pixels",
                    s.width, s.height
                ),
            ));
        }
        if s.spp == 0 || s.spp > MAX_SPP {
            return Err(c.err("spp", format!("must be between 1 and {MAX_SPP}, got {}", s.spp)));
        }
        if let Some(step) = s.march_step {
            if !(step.is_finite() && step > 0.0) {
                return Err(c.err("march_step", format!("must be a positive length, got {step}")));
            }
        }
        if s.ao_distance.is_nan() || s.ao_distance <= 0.0 {
            return Err(c.err(
                "ao_distance",
                format!("must be a positive length, got {}", s.ao_distance),
            ));
        }
        if s.max_depth > MAX_DEPTH {
            return Err(c.err("max_depth", format!("must be at most {MAX_DEPTH}, got {}", s.max_depth)));
        }
        let m = &s.mlt;
        // Multiplexed MLT draws bootstrap samples for every path length.
        let lengths = if s.integrator == IntegratorKind::Mlt {
            s.max_depth.max(1) as u64
        } else {
            1
        };
        if m.bootstrap == 0 || m.bootstrap as u64 * lengths > MAX_MLT_BOOTSTRAP {
            return Err(c.err(
                "mlt_bootstrap",
                format!(
                    "must be between 1 and {} (at most {MAX_MLT_BOOTSTRAP} paths over the {lengths} path lengths of max_depth), got {}",
                    MAX_MLT_BOOTSTRAP / lengths,
                    m.bootstrap
                ),
            ));
        }
        if m.chains == 0 || m.chains > MAX_MLT_CHAINS {
            return Err(c.err(
                "mlt_chains",
                format!("must be between 1 and {MAX_MLT_CHAINS}, got {}", m.chains),
            ));
        }
        if !(0.0..=1.0).contains(&m.large_step_probability) {
            return Err(c.err(
                "mlt_large_step",
                format!(
                    "must be a probability between 0 and 1, got {}",
                    m.large_step_probability
                ),
            ));
        }
        if !(m.sigma > 0.0 && m.sigma.is_finite()) {
            return Err(c.err("mlt_sigma", format!("must be a positive number, got {}", m.sigma)));
        }
        c.finite("exposure", s.exposure)?;
        let wb = crate::color::white_balance::WHITE_BALANCE_RANGE;
        if s.white_balance != 0.0 && !wb.contains(&s.white_balance) {
            return Err(c.err(
                "white_balance",
                format!(
                    "must be 0 (none) or a colour temperature from {} to {} K, got {}",
                    wb.start(),
                    wb.end(),
                    s.white_balance
                ),
            ));
        }
        if s.max_component_value.is_nan() || s.max_component_value <= 0.0 {
            return Err(c.err(
                "max_component_value",
                format!("must be positive, got {}", s.max_component_value),
            ));
        }
        let ph = &s.photon;
        for (key, v, max) in [
            ("photons", ph.photons, MAX_PHOTONS),
            ("caustic_photons", ph.caustic_photons, MAX_PHOTONS),
            ("sppm_photons", ph.sppm_photons, MAX_PHOTONS),
            ("photon_gather", ph.gather, MAX_GATHER),
            ("final_gather", ph.final_gather, MAX_GATHER),
        ] {
            if v > max {
                return Err(c.err(key, format!("must be at most {max}, got {v}")));
            }
        }
        if ph.gather == 0 {
            return Err(c.err("photon_gather", "must be at least 1"));
        }
        c.finite("photon_radius", ph.radius)?;
        if ph.radius < 0.0 {
            return Err(c.err(
                "photon_radius",
                format!("must be 0 (automatic) or positive, got {}", ph.radius),
            ));
        }
        if !(ph.alpha > 0.0 && ph.alpha < 1.0) {
            return Err(c.err(
                "sppm_alpha",
                format!("must be between 0 and 1 (exclusive), got {}", ph.alpha),
            ));
        }
        match s.filter {
            Filter::Box { .. } | Filter::Tent { .. } => {}
            Filter::Gaussian { stddev, .. } => c.positive("filter_stddev", stddev)?,
            Filter::Mitchell { b, c: cc, .. } => {
                c.finite("filter_b", b)?;
                c.finite("filter_c", cc)?;
            }
            // A window much narrower than the sinc's main lobe leaves a
            // filter of vanishing integral (min(1, τ)), which splatting
            // divides by.
            Filter::Lanczos { tau, .. } => {
                c.finite("filter_tau", tau)?;
                if tau < 0.1 {
                    return Err(c.err("filter_tau", format!("must be at least 0.1 pixels, got {tau}")));
                }
            }
        }
        // The radius along each axis.
        let filter = s.pixel_filter();
        for (f, key) in [(filter.x, "filter_radius"), (filter.y, "filter_y_radius")] {
            let radius = f.radius();
            c.positive(key, radius)?;
            if f.has_negative_lobes() {
                let max = Filter::MAX_SIGNED_RADIUS;
                if radius > max {
                    return Err(c.err(
                        key,
                        format!("must be at most {max} pixels for a filter with negative lobes, got {radius}"),
                    ));
                }
            } else if radius > 16.0 {
                return Err(c.err(key, format!("must be at most 16 pixels, got {radius}")));
            }
        }
        Ok(())
    }

    fn validate_camera(&self) -> Result<()> {
        let cam = &self.camera;
        let c = Check {
            locs: &cam.locs,
            prefix: "camera.".into(),
        };
        c.vec3("from", cam.from)?;
        c.vec3("to", cam.to)?;
        c.nonzero_vec3("up", cam.up)?;
        c.finite("shutter", cam.shutter.0)?;
        c.finite("shutter", cam.shutter.1)?;
        if cam.shutter.0 > cam.shutter.1 {
            return Err(c.err(
                "shutter",
                format!("closes before it opens: {} then {}", cam.shutter.0, cam.shutter.1),
            ));
        }
        match cam.projection {
            ProjectionDesc::Perspective { fov } => {
                c.finite("fov", fov)?;
                if !(fov > 0.0 && fov < 180.0) {
                    return Err(c.err(
                        "fov",
                        format!("must be between 0 and 180 degrees (exclusive), got {fov}"),
                    ));
                }
            }
            ProjectionDesc::Orthographic { size } => c.positive("size", size)?,
            ProjectionDesc::Spherical { .. } => {}
            ProjectionDesc::Realistic {
                aperture_diameter,
                focus_distance,
                film_diagonal,
                ..
            } => {
                c.positive("aperture_diameter", aperture_diameter)?;
                c.positive("focus_distance", focus_distance)?;
                c.positive("film_diagonal", film_diagonal)?;
            }
        }
        c.non_negative("aperture_radius", cam.aperture_radius)?;
        c.non_negative("near_clip", cam.near_clip)?;
        if cam.far_clip.is_nan() || cam.far_clip <= cam.near_clip {
            return Err(c.err(
                "far_clip",
                format!("must exceed near_clip ({}), got {}", cam.near_clip, cam.far_clip),
            ));
        }
        if let Some(m) = cam.to_world {
            crate::geometry::Transform::from_matrix(m).map_err(|e| c.err("to_world", format!("{e}")))?;
            return Ok(());
        }
        if let Some(f) = cam.focus_distance {
            c.positive("focus_distance", f)?;
        }
        let view = cam.to - cam.from;
        if view.length_squared() == 0.0 {
            return Err(c.err("to", "must differ from `from`"));
        }
        if view.normalize().cross(cam.up.normalize()).length_squared() < 1e-12 {
            return Err(c.err("up", "is parallel to the viewing direction"));
        }
        Ok(())
    }
}

fn validate_mesh_source(c: &Check, src: &MeshSource) -> Result<()> {
    match src {
        MeshSource::Inline(m) => {
            if m.indices.is_empty() {
                return Err(c.err("indices", "the mesh has no triangles"));
            }
            m.validate().map_err(|e| c.err("indices", e.to_string()))
        }
        MeshSource::File(_) => Ok(()),
        MeshSource::Displaced { mesh, edge_length, .. } => {
            if matches!(**mesh, MeshSource::Displaced { .. }) {
                return Err(c.err("mesh", "a displaced mesh cannot be displaced again"));
            }
            if !(*edge_length > 0.0 && edge_length.is_finite()) {
                return Err(c.err(
                    "edge_length",
                    format!("the edge length must be positive and finite, got {edge_length}"),
                ));
            }
            validate_mesh_source(c, mesh)
        }
        MeshSource::UvSphere { segments, rings } => {
            if *segments < 3 || *rings < 2 {
                return Err(c.err("segments", "a uv_sphere needs at least 3 segments and 2 rings"));
            }
            if *segments as u64 * *rings as u64 > 50_000_000 {
                return Err(c.err("segments", "segments × rings must be at most 50 million"));
            }
            Ok(())
        }
    }
}

/// Checks one environment of the scene's background.
fn validate_background(w: &Check, background: &BackgroundDesc) -> Result<()> {
    match background {
        BackgroundDesc::Constant(c) => w.color("background", *c)?,
        BackgroundDesc::Gradient { top, bottom } => {
            w.color("background", *top)?;
            w.color("background", *bottom)?;
        }
        BackgroundDesc::Image {
            scale,
            transform,
            layout,
            illuminance,
            ..
        } => {
            w.non_negative("background", *scale)?;
            if let Some(e) = illuminance {
                w.positive("background", *e)?;
                if *layout != EnvironmentLayout::EqualAreaOctahedral {
                    return Err(w.err(
                        "background",
                        "an illuminance is given only to equal-area maps (pbrt-v4's image infinite lights)",
                    ));
                }
            }
            for op in transform {
                op.to_transform()
                    .map_err(|e| w.err("background", format!("transform {}: {e}", op.name())))?;
            }
        }
        BackgroundDesc::Sum(_) => {
            return Err(w.err(
                "background",
                "a sum of environments holds constants and images, not sums",
            ));
        }
    }
    Ok(())
}

/// ", did you mean \"x\"?" for the closest of `candidates` to `name`, if
/// one is close.
pub fn suggest<'a>(name: &str, candidates: impl Iterator<Item = &'a str>) -> String {
    let best = candidates.map(|c| (edit_distance(name, c), c)).min_by_key(|(d, _)| *d);
    match best {
        Some((d, c)) if d <= 2.max(name.len() / 3) => format!(" (did you mean \"{c}\"?)"),
        _ => String::new(),
    }
}

/// Levenshtein distance.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, &cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + usize::from(ca != cb)).min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(radius: f32) -> SceneDesc {
        let mut d = SceneDesc::default();
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Sphere {
                center: Vec3::ZERO,
                radius,
            },
            None,
        ));
        d
    }

    #[test]
    fn good_scene_validates() {
        assert!(sphere(1.0).validate().is_ok());
    }

    #[test]
    fn bad_values_are_named() {
        for r in [-1.0, 0.0, f32::NAN, f32::INFINITY] {
            let e = sphere(r).validate().unwrap_err().to_string();
            assert!(e.contains("shape[0].radius"), "{e}");
        }
        let mut d = sphere(1.0);
        d.settings.width = 0;
        assert!(d.validate().unwrap_err().to_string().contains("render.width"));
        let mut d = sphere(1.0);
        d.camera.to = d.camera.from;
        assert!(d.validate().unwrap_err().to_string().contains("camera.to"));
        let mut d = sphere(1.0);
        d.materials.push(MaterialDesc::classic(
            "glass",
            ClassicDesc {
                ior: -1.5,
                ..ClassicDesc::default()
            },
        ));
        assert!(d.validate().unwrap_err().to_string().contains("material[0].ior"));
    }

    #[test]
    fn missing_references_suggest_names() {
        let mut d = sphere(1.0);
        d.materials.push(MaterialDesc::new("mirror"));
        d.shapes[0].material = Some("miror".into());
        let e = d.validate().unwrap_err().to_string();
        assert!(
            e.contains("no material named \"miror\"") && e.contains("did you mean \"mirror\""),
            "{e}"
        );
    }

    #[test]
    fn singular_transforms_are_rejected() {
        let mut d = sphere(1.0);
        d.shapes[0].transform.push(TransformOp::Scale(Vec3::new(1.0, 0.0, 1.0)));
        let e = d.validate().unwrap_err().to_string();
        assert!(e.contains("shape[0].transform") && e.contains("singular"), "{e}");
    }

    #[test]
    fn edit_distances() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("same", "same"), 0);
    }
}
