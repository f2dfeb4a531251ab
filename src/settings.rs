//! Render settings: how a scene is to be rendered — the image, the
//! algorithm and its parameters, the reconstruction filter, the tone map —
//! as plain data.
//!
//! This is a bottom layer. Scene descriptions (`scene`) read and validate
//! these values, the command line overrides them, and the algorithms
//! (`integrator`), the film (`film`) and the renderer (`render`) act on
//! them; none of those is imported here, so descriptions need not know the
//! algorithms, and the algorithms need not know the descriptions. What a
//! setting does lives with the code that does it: the filter's sampling in
//! `film::filter`, the tone curves in `film::tonemap`, the photon kernels'
//! weights in `integrator::photon`.

use crate::color::space::ColorSpace;
use crate::sampling::SamplerKind;

/// Render settings that a scene file may give and the command line may
/// override.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Longest light path, in segments from the camera (1: emitters seen
    /// directly; 2: direct light; each more: one more bounce).
    pub max_depth: u32,
    /// The rendering algorithm.
    pub integrator: IntegratorKind,
    /// The path tracer's estimator.
    pub sampling: PathSampling,
    /// Path segments after which Russian roulette starts.
    pub rr_depth: u32,
    /// Seed of all random numbers.
    pub seed: u64,
    /// Placement of samples within pixels.
    pub sampler: SamplerKind,
    /// The stratified sampler's grid of 2D strata, `[x, y]` (pbrt-v4's
    /// `xsamples`, `ysamples`), where its product is `spp`; otherwise (and
    /// `None`) one derived from `spp` (`sampling::strata_grid`).
    pub strata: Option<[u32; 2]>,
    /// Whether the stratified sampler jitters samples inside their strata
    /// (pbrt-v4's `jitter`); false: at their centres.
    pub jitter: bool,
    /// Pixel reconstruction filter (along x; see `filter_y_radius`).
    pub filter: Filter,
    /// The filter's radius along y where it differs from its radius along
    /// x (pbrt-v4's `yradius`); `None`: the same. See
    /// [`RenderSettings::pixel_filter`].
    pub filter_y_radius: Option<f32>,
    /// Tone mapping for 8-bit output.
    pub tonemap: Tonemap,
    /// Exposure compensation in stops, applied before tone mapping.
    pub exposure: f32,
    /// Largest RGB component of one camera sample once exposed: brighter
    /// samples are scaled down to it (pbrt-v4's film `maxcomponentvalue`,
    /// which trades fireflies for bias); infinite: no limit.
    pub max_component_value: f32,
    /// The colour temperature, in kelvin, of the illuminant the image is
    /// balanced for (pbrt-v4's film `whitebalance`: its white becomes
    /// sRGB's, `color::white_balance`); 0: none.
    pub white_balance: f32,
    /// The RGB space of the image written (pbrt-v4's film colour space):
    /// trazo renders in linear sRGB and converts at output.
    pub color_space: ColorSpace,
    /// Photon mapping and SPPM parameters.
    pub photon: PhotonSettings,
    /// The volumetric path tracer's estimator: `None`, delta and ratio
    /// tracking (unbiased); `Some(step)`, fixed-step ray marching with
    /// steps of this length in scene units (biased, for comparison).
    pub march_step: Option<f32>,
    /// Whether emitters are hidden from the camera (Mitsuba's
    /// `hide_emitters`): emitting surfaces and the environment seen
    /// directly show black, and light the scene as before.
    pub hide_emitters: bool,
    /// Ambient occlusion: how far a surface still occludes (infinite:
    /// any).
    pub ao_distance: f32,
    /// Where the image is a window cut from a larger one; `width` and
    /// `height` are then the window's size.
    pub crop: Option<Crop>,
    /// Bidirectional path tracing also records each strategy's image,
    /// weighted and unweighted (pbrt-v4's `visualizeweights` and
    /// `visualizestrategies`).
    pub bdpt_strategies: bool,
    /// Metropolis light transport's parameters.
    pub mlt: MltSettings,
    /// Whether the film also records a G-buffer of what the camera sees
    /// first (pbrt-v4's `Film "gbuffer"`), in these coordinates: written as
    /// pbrt-v4's channels of one OpenEXR file.
    pub gbuffer: Option<GBufferSpace>,
}

/// Metropolis light transport's parameters (`--integrator mlt` and
/// `pssmlt`), with pbrt-v4's defaults. The samples per pixel are the
/// mutations per pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MltSettings {
    /// Paths drawn independently to estimate the image's brightness and
    /// to start the chains from (pbrt's `bootstrapsamples`).
    pub bootstrap: u32,
    /// Markov chains run side by side (pbrt's `chains`).
    pub chains: u32,
    /// Probability that a mutation draws a new path independently of the
    /// current one (pbrt's `largestepprobability`).
    pub large_step_probability: f32,
    /// Standard deviation of a small step's perturbation of each primary
    /// sample (pbrt's `sigma`).
    pub sigma: f32,
}

impl Default for MltSettings {
    fn default() -> Self {
        MltSettings {
            bootstrap: 100_000,
            chains: 1000,
            large_step_probability: 0.3,
            sigma: 0.01,
        }
    }
}

/// A crop window: the rendered image is the part of a `full_width` ×
/// `full_height` image whose top-left pixel is (`x`, `y`), as pbrt-v4's
/// `cropwindow` and `pixelbounds` and Mitsuba's `crop_offset_x/y`,
/// `crop_width/height` cut it. The camera frames the full image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crop {
    /// Width of the full image, in pixels.
    pub full_width: u32,
    /// Height of the full image, in pixels.
    pub full_height: u32,
    /// Column of the window's top-left pixel in the full image.
    pub x: u32,
    /// Row of the window's top-left pixel in the full image.
    pub y: u32,
}

impl RenderSettings {
    /// The size of the whole image the camera frames: `width` × `height`,
    /// or the full image a crop window is cut from.
    pub fn full_size(&self) -> (u32, u32) {
        self.crop
            .map_or((self.width, self.height), |c| (c.full_width, c.full_height))
    }

    /// Whether emission met by the `segment`-th segment of a camera path
    /// (1: the camera ray itself) is counted.
    #[inline]
    pub fn shows_emission(&self, segment: u32) -> bool {
        segment > 1 || !self.hide_emitters
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 512,
            height: 512,
            spp: 16,
            max_depth: 8,
            integrator: IntegratorKind::default(),
            sampling: PathSampling::default(),
            rr_depth: 5,
            seed: 0,
            sampler: SamplerKind::default(),
            strata: None,
            jitter: true,
            filter: Filter::default(),
            filter_y_radius: None,
            tonemap: Tonemap::default(),
            exposure: 0.0,
            max_component_value: f32::INFINITY,
            white_balance: 0.0,
            color_space: ColorSpace::Srgb,
            photon: PhotonSettings::default(),
            march_step: None,
            hide_emitters: false,
            ao_distance: f32::INFINITY,
            crop: None,
            bdpt_strategies: false,
            mlt: MltSettings::default(),
            gbuffer: None,
        }
    }
}

/// The coordinates of a G-buffer's positions, normals and depth slopes
/// (pbrt-v4's `GBufferFilm` `coordinatesystem`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GBufferSpace {
    /// The camera's: x to the image's right, y up, z along the view.
    Camera,
    /// The scene's world space.
    World,
}

/// A sampler study instead of a render (pbrt-v4's `Integrator "function"`):
/// each pixel estimates the integral over [0, 1]² of a test function whose
/// integral is 1 from the positions in the pixel that the sampler gives its
/// samples, and the mean over pixels of the squared error is written, one
/// line per sample count (`integrator::function`).
#[derive(Clone, Debug, PartialEq)]
pub struct SamplerStudy {
    /// The function integrated.
    pub function: TestFunction,
    /// Whether only the sample counts a sampler is designed for are
    /// reported (pbrt-v4's `skipbad`): square counts for stratified
    /// sampling, powers of two for Sobol points, 2ᵃ·3ᵃ for Halton points.
    pub skip_bad: bool,
    /// The text file of the errors (pbrt-v4's `filename`); `None`: `-o`, or
    /// `<function>-mse.txt`.
    pub output: Option<std::path::PathBuf>,
    /// An image of the function to write too (pbrt-v4's `imagefilename`).
    pub image: Option<std::path::PathBuf>,
}

/// The test functions of a [`SamplerStudy`], pbrt-v4's: each integrates to
/// 1 over [0, 1]².
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TestFunction {
    /// 2 where x < ½: an edge along a stratum boundary.
    Step,
    /// 2 below the diagonal x + y = 1: an edge across strata.
    Diagonal,
    /// 4/π inside the disk of radius ½ about the centre.
    Disk,
    /// A 10 × 10 checkerboard of 2 and 0.
    Checkerboard,
    /// The checkerboard turned by 45°.
    RotatedCheckerboard,
    /// A Gaussian of σ = ¼ about the centre, normalised over the square.
    Gaussian,
}

impl TestFunction {
    /// The names, as pbrt-v4 writes them.
    pub const NAMES: [&'static str; 6] = [
        "step",
        "diagonal",
        "disk",
        "checkerboard",
        "rotatedcheckerboard",
        "gaussian",
    ];

    /// Parses one of [`TestFunction::NAMES`].
    pub fn from_name(s: &str) -> Option<TestFunction> {
        use TestFunction::*;
        [Step, Diagonal, Disk, Checkerboard, RotatedCheckerboard, Gaussian]
            .into_iter()
            .find(|f| f.name() == s)
    }

    /// This function's name.
    pub fn name(&self) -> &'static str {
        Self::NAMES[*self as usize]
    }
}

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: u32 = 65_536;
/// Largest accepted image, in pixels (about 268 megapixels).
pub const MAX_IMAGE_PIXELS: u64 = 1 << 28;
/// Most bootstrap paths Metropolis light transport draws (over all path
/// lengths): each keeps a weight.
pub const MAX_MLT_BOOTSTRAP: u64 = 1 << 26;
/// Most Markov chains: each keeps its state.
pub const MAX_MLT_CHAINS: u32 = 1 << 20;
/// Largest accepted samples per pixel.
pub const MAX_SPP: u32 = 1 << 24;
/// Largest accepted recursion depth.
pub const MAX_DEPTH: u32 = 1024;

/// The rendering algorithms.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum IntegratorKind {
    /// Whitted's recursive ray tracer.
    Whitted,
    /// Kajiya's path tracer.
    #[default]
    Path,
    /// Jensen's two-pass photon mapping.
    Photon,
    /// Stochastic progressive photon mapping.
    Sppm,
    /// The volumetric path tracer (participating media).
    VolPath,
    /// Light tracing: paths from the lights connected to the camera.
    Light,
    /// Bidirectional path tracing: subpaths from the camera and from a
    /// light, joined every way and weighted by multiple importance.
    Bdpt,
    /// Multiplexed Metropolis light transport (Hachisuka et al. 2014, as
    /// pbrt-v4's `mlt`): Markov chains over bidirectional strategies.
    Mlt,
    /// Primary-sample-space Metropolis light transport (Kelemen et al.
    /// 2002) over whole bidirectional samples.
    Pssmlt,
    /// Vertex connection and merging (Georgiev et al. 2012): the
    /// bidirectional connections and photon merging under one multiple
    /// importance sampling.
    Vcm,
    /// Ambient occlusion: the share of the hemisphere open within a
    /// distance.
    AmbientOcclusion,
}

impl IntegratorKind {
    /// The names accepted on the command line and in scene files.
    pub const NAMES: [&'static str; 11] = [
        "whitted", "path", "photon", "sppm", "volpath", "light", "bdpt", "mlt", "pssmlt", "vcm", "ao",
    ];

    /// Parses one of [`IntegratorKind::NAMES`].
    pub fn from_name(s: &str) -> Option<IntegratorKind> {
        match s {
            "whitted" => Some(IntegratorKind::Whitted),
            "path" => Some(IntegratorKind::Path),
            "photon" => Some(IntegratorKind::Photon),
            "sppm" => Some(IntegratorKind::Sppm),
            "volpath" => Some(IntegratorKind::VolPath),
            "light" => Some(IntegratorKind::Light),
            "bdpt" => Some(IntegratorKind::Bdpt),
            "mlt" => Some(IntegratorKind::Mlt),
            "pssmlt" => Some(IntegratorKind::Pssmlt),
            "vcm" => Some(IntegratorKind::Vcm),
            "ao" => Some(IntegratorKind::AmbientOcclusion),
            _ => None,
        }
    }

    /// Whether the integrator joins paths from the lights to the camera
    /// (and so splats onto the image rather than sampling its pixels).
    pub fn splats_light_paths(&self) -> bool {
        matches!(
            self,
            IntegratorKind::Light
                | IntegratorKind::Bdpt
                | IntegratorKind::Mlt
                | IntegratorKind::Pssmlt
                | IntegratorKind::Vcm
        )
    }

    /// This integrator's name.
    pub fn name(&self) -> &'static str {
        match self {
            IntegratorKind::Whitted => "whitted",
            IntegratorKind::Path => "path",
            IntegratorKind::Photon => "photon",
            IntegratorKind::Sppm => "sppm",
            IntegratorKind::VolPath => "volpath",
            IntegratorKind::Light => "light",
            IntegratorKind::Bdpt => "bdpt",
            IntegratorKind::Mlt => "mlt",
            IntegratorKind::Pssmlt => "pssmlt",
            IntegratorKind::Vcm => "vcm",
            IntegratorKind::AmbientOcclusion => "ao",
        }
    }
}

/// How the path tracer chooses directions and gathers light.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PathSampling {
    /// Uniform hemisphere sampling, emission collected on hits only.
    Uniform,
    /// Cosine-weighted hemisphere sampling, emission on hits only.
    Cosine,
    /// BSDF importance sampling, emission on hits only.
    Bsdf,
    /// Next-event estimation (a shadow ray to a sampled light point at
    /// every vertex) and BSDF sampling onward, without MIS: emission that
    /// next-event estimation could have found counts on hits only from the
    /// camera and after delta bounces (pbrt-v4's `simplepath`).
    Nee,
    /// Next-event estimation as `Nee`, uniform directions onward (pbrt-v4's
    /// `simplepath` with `samplebsdf` false).
    NeeUniform,
    /// Next-event estimation and BSDF sampling combined by MIS.
    #[default]
    Mis,
}

impl PathSampling {
    /// The names accepted on the command line and in scene files.
    pub const NAMES: [&'static str; 6] = ["uniform", "cosine", "bsdf", "nee", "nee-uniform", "mis"];

    /// Parses one of [`PathSampling::NAMES`].
    pub fn from_name(s: &str) -> Option<PathSampling> {
        match s {
            "uniform" => Some(PathSampling::Uniform),
            "cosine" => Some(PathSampling::Cosine),
            "bsdf" => Some(PathSampling::Bsdf),
            "nee" => Some(PathSampling::Nee),
            "nee-uniform" => Some(PathSampling::NeeUniform),
            "mis" => Some(PathSampling::Mis),
            _ => None,
        }
    }

    /// This estimator's name.
    pub fn name(&self) -> &'static str {
        match self {
            PathSampling::Uniform => "uniform",
            PathSampling::Cosine => "cosine",
            PathSampling::Bsdf => "bsdf",
            PathSampling::Nee => "nee",
            PathSampling::NeeUniform => "nee-uniform",
            PathSampling::Mis => "mis",
        }
    }
}

/// The weighting of photons by distance in a density estimate (the
/// weights themselves are computed in `integrator::photon`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PhotonKernel {
    /// Constant over the disk (the plain nearest-neighbour estimate).
    Box,
    /// Jensen's cone filter, w = 1 − d/r (Jensen 2001, eq. 7.8 with k = 1),
    /// normalised by 1 − 2/3.
    #[default]
    Cone,
    /// Epanechnikov's kernel, w = 1 − d²/r², normalised by 1/2 (Silverman
    /// 1986: the kernel of least mean integrated squared error).
    Epanechnikov,
}

impl PhotonKernel {
    /// The names accepted on the command line and in scene files.
    pub const NAMES: [&'static str; 3] = ["box", "cone", "epanechnikov"];

    /// Parses one of [`PhotonKernel::NAMES`].
    pub fn from_name(s: &str) -> Option<PhotonKernel> {
        match s {
            "box" => Some(PhotonKernel::Box),
            "cone" => Some(PhotonKernel::Cone),
            "epanechnikov" => Some(PhotonKernel::Epanechnikov),
            _ => None,
        }
    }

    /// This kernel's name.
    pub fn name(&self) -> &'static str {
        match self {
            PhotonKernel::Box => "box",
            PhotonKernel::Cone => "cone",
            PhotonKernel::Epanechnikov => "epanechnikov",
        }
    }
}

/// The photon mappers' parameters (the `[render]` keys of
/// `integrator::photon`'s documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotonSettings {
    /// Photons emitted for the global map.
    pub photons: u32,
    /// Photons emitted for the caustic map.
    pub caustic_photons: u32,
    /// Photons in a radiance estimate (k nearest).
    pub gather: u32,
    /// Largest search radius (SPPM: the initial radius); 0 chooses one from
    /// the scene's size.
    pub radius: f32,
    /// Final-gather rays per camera sample; 0 reads the global map at the
    /// first diffuse surface.
    pub final_gather: u32,
    /// Density estimation kernel.
    pub kernel: PhotonKernel,
    /// Photons per SPPM iteration; 0: as many as pixels (pbrt's default).
    pub sppm_photons: u32,
    /// SPPM's α: the share of new photons kept at each iteration.
    pub alpha: f32,
}

impl Default for PhotonSettings {
    fn default() -> Self {
        PhotonSettings {
            photons: 200_000,
            caustic_photons: 200_000,
            gather: 64,
            radius: 0.0,
            final_gather: 16,
            kernel: PhotonKernel::default(),
            sppm_photons: 0,
            alpha: 2.0 / 3.0,
        }
    }
}

/// Most photons one map may hold (32 bytes each).
pub const MAX_PHOTONS: u32 = 100_000_000;
/// Most photons in one radiance estimate, and most final-gather rays.
pub const MAX_GATHER: u32 = 16_384;

impl PhotonSettings {
    /// Photons per SPPM iteration for an image of `pixels` pixels.
    pub fn sppm_photons_for(&self, pixels: u64) -> u32 {
        if self.sppm_photons > 0 {
            self.sppm_photons
        } else {
            pixels.clamp(1, MAX_PHOTONS as u64) as u32
        }
    }
}

/// A separable pixel reconstruction filter, centred on the pixel centre
/// (how it is sampled and splatted: `film::filter`, `film::splat`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    /// Uniform weight within `radius` pixels (0.5: exactly the pixel).
    Box {
        /// Half-width in pixels.
        radius: f32,
    },
    /// Weight falling linearly to 0 at `radius`.
    Tent {
        /// Half-width in pixels.
        radius: f32,
    },
    /// A Gaussian of standard deviation `stddev`, cut off at `radius`.
    Gaussian {
        /// Standard deviation in pixels.
        stddev: f32,
        /// Cut-off in pixels.
        radius: f32,
    },
    /// Mitchell and Netravali's cubic (1988) of parameters `b` and `c`,
    /// stretched to `radius` (its own support is 2): pbrt-v4's `mitchell`
    /// and Mitsuba's `mitchell` (B = C = 1/3) and `catmullrom` (B = 0,
    /// C = 1/2). Negative lobes: always splatted (radius at most
    /// [`Filter::MAX_SIGNED_RADIUS`]).
    Mitchell {
        /// Half-width in pixels.
        radius: f32,
        /// B, the blur.
        b: f32,
        /// C, the ringing.
        c: f32,
    },
    /// Lanczos' windowed sinc, sinc(x)·sinc(x/τ) within `radius`: pbrt-v4's
    /// `sinc` (radius 4, τ 3) and Mitsuba's `lanczos` (radius = τ = its
    /// `lobes`, 3). Negative lobes: always splatted.
    Lanczos {
        /// Half-width in pixels.
        radius: f32,
        /// The window's width τ.
        tau: f32,
    },
}

impl Default for Filter {
    fn default() -> Self {
        Filter::Box { radius: 0.5 }
    }
}

impl Filter {
    /// The names accepted in scene files.
    pub const NAMES: [&'static str; 6] = ["box", "tent", "gaussian", "mitchell", "catmullrom", "lanczos"];

    /// The widest filter with negative lobes: those are splatted, and a
    /// splat reaches at most this far.
    pub const MAX_SIGNED_RADIUS: f32 = 7.5;

    /// The filter called `name` with its default size (box 0.5, tent 1,
    /// Gaussian σ = 0.5 cut off at 4σ, as Mitsuba's; Mitchell's and
    /// Catmull–Rom's cubics 2, Lanczos 3 lobes, as Mitsuba's).
    pub fn from_name(name: &str) -> Option<Filter> {
        match name {
            "box" => Some(Filter::Box { radius: 0.5 }),
            "tent" => Some(Filter::Tent { radius: 1.0 }),
            "gaussian" => Some(Filter::Gaussian {
                stddev: 0.5,
                radius: 2.0,
            }),
            "mitchell" => Some(Filter::Mitchell {
                radius: 2.0,
                b: 1.0 / 3.0,
                c: 1.0 / 3.0,
            }),
            "catmullrom" => Some(Filter::Mitchell {
                radius: 2.0,
                b: 0.0,
                c: 0.5,
            }),
            "lanczos" => Some(Filter::Lanczos { radius: 3.0, tau: 3.0 }),
            _ => None,
        }
    }

    /// Half-width in pixels.
    pub fn radius(&self) -> f32 {
        match *self {
            Filter::Box { radius }
            | Filter::Tent { radius }
            | Filter::Gaussian { radius, .. }
            | Filter::Mitchell { radius, .. }
            | Filter::Lanczos { radius, .. } => radius,
        }
    }

    /// Whether the filter has negative lobes, which filter importance
    /// sampling cannot draw (its samples all count +1): such filters are
    /// always splatted.
    pub fn has_negative_lobes(&self) -> bool {
        matches!(self, Filter::Mitchell { .. } | Filter::Lanczos { .. })
    }

    /// The same filter with half-width `radius`.
    pub fn with_radius(self, radius: f32) -> Filter {
        match self {
            Filter::Box { .. } => Filter::Box { radius },
            Filter::Tent { .. } => Filter::Tent { radius },
            Filter::Gaussian { stddev, .. } => Filter::Gaussian { stddev, radius },
            Filter::Mitchell { b, c, .. } => Filter::Mitchell { radius, b, c },
            Filter::Lanczos { tau, .. } => Filter::Lanczos { radius, tau },
        }
    }

    /// [`PixelFilter::splat_margin`] of this filter along both axes.
    pub fn splat_margin(&self) -> Option<u32> {
        PixelFilter::same(*self).splat_margin()
    }
}

/// A separable pixel filter: a profile along x and one along y, which
/// differ only in their radii (pbrt-v4's filters of two radii: the
/// profile along each axis is the filter's 1D profile cut off at that
/// axis's radius).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelFilter {
    /// Along x.
    pub x: Filter,
    /// Along y.
    pub y: Filter,
}

impl PixelFilter {
    /// `filter` along both axes.
    pub fn same(filter: Filter) -> PixelFilter {
        PixelFilter { x: filter, y: filter }
    }

    /// Whether samples are splatted into every pixel the filter covers,
    /// and if so how many pixels a tile's buffer reaches beyond the tile on
    /// each side. `None` for the one-pixel box, for which filter importance
    /// sampling is the same estimator, and for radii outside (0, 8] pixels
    /// (scenes keep filters with negative lobes within
    /// [`Filter::MAX_SIGNED_RADIUS`]).
    pub fn splat_margin(&self) -> Option<u32> {
        let one_pixel_box = |f: &Filter| matches!(f, Filter::Box { .. }) && f.radius() <= 0.5;
        let splattable = |f: &Filter| f.radius() > 0.0 && f.radius() <= 8.0;
        let (x, y) = (&self.x, &self.y);
        if one_pixel_box(x) && one_pixel_box(y) || !(splattable(x) && splattable(y)) {
            return None;
        }
        Some((x.radius().max(y.radius()) - 0.5).ceil().max(0.0) as u32)
    }
}

impl RenderSettings {
    /// The pixel filter: `filter` along x, and along y the same filter
    /// with `filter_y_radius` where that is given.
    pub fn pixel_filter(&self) -> PixelFilter {
        PixelFilter {
            x: self.filter,
            y: self.filter_y_radius.map_or(self.filter, |r| self.filter.with_radius(r)),
        }
    }
}

/// A tone-mapping operator (the curves: `film::tonemap`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Tonemap {
    /// Clip each channel to [0, 1].
    #[default]
    Clamp,
    /// Reinhard et al. 2002 on luminance: L/(1 + L), keeping hue.
    Reinhard,
    /// Narkowicz's 2015 fit of the ACES filmic curve, per channel.
    Aces,
}

impl Tonemap {
    /// The names accepted on the command line and in scene files.
    pub const NAMES: [&'static str; 3] = ["clamp", "reinhard", "aces"];

    /// Parses one of [`Tonemap::NAMES`].
    pub fn from_name(s: &str) -> Option<Tonemap> {
        match s {
            "clamp" => Some(Tonemap::Clamp),
            "reinhard" => Some(Tonemap::Reinhard),
            "aces" => Some(Tonemap::Aces),
            _ => None,
        }
    }

    /// This operator's name.
    pub fn name(&self) -> &'static str {
        match self {
            Tonemap::Clamp => "clamp",
            Tonemap::Reinhard => "reinhard",
            Tonemap::Aces => "aces",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_reads_back() {
        for n in IntegratorKind::NAMES {
            assert_eq!(IntegratorKind::from_name(n).unwrap().name(), n);
        }
        for n in PathSampling::NAMES {
            assert_eq!(PathSampling::from_name(n).unwrap().name(), n);
        }
        for n in PhotonKernel::NAMES {
            assert_eq!(PhotonKernel::from_name(n).unwrap().name(), n);
        }
        for n in Tonemap::NAMES {
            assert_eq!(Tonemap::from_name(n).unwrap().name(), n);
        }
        for n in Filter::NAMES {
            assert!(Filter::from_name(n).is_some(), "{n}");
        }
        assert_eq!(IntegratorKind::from_name("bidir"), None);
    }

    /// Only filters wider than a pixel splat; Mitsuba's Gaussian reaches
    /// two pixels beyond a tile.
    #[test]
    fn splat_margins() {
        assert_eq!(Filter::default().splat_margin(), None);
        assert_eq!(Filter::Box { radius: 1.5 }.splat_margin(), Some(1));
        assert_eq!(Filter::from_name("tent").unwrap().splat_margin(), Some(1));
        assert_eq!(Filter::from_name("gaussian").unwrap().splat_margin(), Some(2));
        assert_eq!(Filter::Tent { radius: 9.0 }.splat_margin(), None);
        for name in ["mitchell", "catmullrom", "lanczos"] {
            let f = Filter::from_name(name).unwrap();
            assert!(f.has_negative_lobes() && f.splat_margin().is_some(), "{name}");
        }
        let widest = Filter::Lanczos {
            radius: Filter::MAX_SIGNED_RADIUS,
            tau: 3.0,
        };
        assert_eq!(widest.splat_margin(), Some(7));
        // Two radii: the wider decides; a one-pixel box along one axis
        // still splats along the other.
        let tent = Filter::Tent { radius: 1.0 };
        let two = |x: Filter, y: Filter| PixelFilter { x, y }.splat_margin();
        assert_eq!(two(tent, tent.with_radius(2.6)), Some(3));
        assert_eq!(two(Filter::default(), Filter::Box { radius: 1.5 }), Some(1));
        assert_eq!(two(tent, tent.with_radius(9.0)), None);
    }

    #[test]
    fn sppm_photons_default_to_one_per_pixel() {
        let mut p = PhotonSettings::default();
        assert_eq!(p.sppm_photons_for(640 * 480), 640 * 480);
        assert_eq!(p.sppm_photons_for(0), 1);
        p.sppm_photons = 1000;
        assert_eq!(p.sppm_photons_for(640 * 480), 1000);
    }
}
