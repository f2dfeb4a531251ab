//! Random numbers, per-pixel samplers and warps from the unit square to
//! geometric domains.

pub mod chi2;
pub mod distribution;
pub mod erf;
pub mod halton;
pub mod primary;
pub mod rng;
pub mod sampler;
pub mod sobol;
pub mod warp;

pub use distribution::{BilinearDistribution2D, Distribution1D, Distribution2D};
pub use primary::{PrimarySamples, Uniforms};
pub use rng::Pcg32;
pub use sampler::{Sampler, SamplerKind};
