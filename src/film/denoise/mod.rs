//! Denoising: removing the noise left in a render, guided by the albedo
//! and normal images (the AOVs of [`crate::integrator::aov`]) which tell
//! edges of the scene from noise.
//!
//! Two denoisers:
//!
//! - [`atrous`]: the built-in edge-avoiding à-trous wavelet filter, always
//!   available;
//! - [`oidn`]: Intel Open Image Denoise (a trained neural network), loaded
//!   at run time from a shared library that `tools/oidn/setup` installs
//!   from PyPI; trazo builds and runs without it.
//!
//! `--denoise` (or `--denoise auto`) uses Open Image Denoise when its
//! library is found, the built-in filter otherwise, and says which.

pub mod atrous;
pub mod oidn;

use super::{Aov, Film, Image};
use crate::error::{Error, Result};

/// Which denoiser to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DenoiserKind {
    /// Open Image Denoise if its library is found, else the built-in filter.
    #[default]
    Auto,
    /// The built-in à-trous filter.
    Atrous,
    /// Intel Open Image Denoise (an error if its library is not found).
    Oidn,
}

impl DenoiserKind {
    /// The names accepted on the command line.
    pub const NAMES: [&'static str; 3] = ["auto", "atrous", "oidn"];

    /// Parses one of [`DenoiserKind::NAMES`].
    pub fn from_name(s: &str) -> Option<DenoiserKind> {
        match s {
            "auto" => Some(DenoiserKind::Auto),
            "atrous" => Some(DenoiserKind::Atrous),
            "oidn" => Some(DenoiserKind::Oidn),
            _ => None,
        }
    }

    /// This kind's name.
    pub fn name(&self) -> &'static str {
        match self {
            DenoiserKind::Auto => "auto",
            DenoiserKind::Atrous => "atrous",
            DenoiserKind::Oidn => "oidn",
        }
    }
}

/// What a denoiser reads: the noisy image, the guides, and the variance of
/// each pixel's mean luminance.
#[derive(Clone, Copy, Debug)]
pub struct DenoiseInput<'a> {
    /// The noisy image (linear radiance).
    pub color: &'a Image,
    /// Albedo at the first non-specular surface.
    pub albedo: &'a Image,
    /// World-space normal there (zero where nothing was hit).
    pub normal: &'a Image,
    /// Variance of each pixel's mean luminance (zero: converged).
    pub variance: &'a [f32],
}

/// A denoised image and a description of the denoiser that made it.
#[derive(Clone, Debug)]
pub struct Denoised {
    /// The image.
    pub image: Image,
    /// Which denoiser ran (for messages), e.g. "built-in à-trous filter".
    pub denoiser: String,
}

/// Denoises a film that recorded its AOVs.
pub fn denoise_film(film: &Film, kind: DenoiserKind) -> Result<Denoised> {
    let color = film.to_image();
    let (Some(albedo), Some(normal)) = (film.aov_image(Aov::Albedo), film.aov_image(Aov::Normal)) else {
        return Err(Error::Invalid(
            "denoising needs the albedo and normal images: render with AOVs".into(),
        ));
    };
    let variance: Vec<f32> = film.pixels.iter().map(|p| p.sum().variance_of_mean() as f32).collect();
    denoise(
        &DenoiseInput {
            color: &color,
            albedo: &albedo,
            normal: &normal,
            variance: &variance,
        },
        kind,
    )
}

/// Denoises `input` with the chosen denoiser.
pub fn denoise(input: &DenoiseInput, kind: DenoiserKind) -> Result<Denoised> {
    let builtin = || Denoised {
        image: atrous::denoise(input),
        denoiser: "the built-in à-trous filter".into(),
    };
    match kind {
        DenoiserKind::Atrous => Ok(builtin()),
        DenoiserKind::Oidn => oidn::denoise(input),
        DenoiserKind::Auto => match oidn::Library::find() {
            Ok(_) => oidn::denoise(input),
            Err(_) => Ok(builtin()),
        },
    }
}
