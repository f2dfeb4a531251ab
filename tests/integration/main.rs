//! Every integration test in one binary: one link (with the release
//! profile's whole-program optimisation) instead of one per file. Each
//! module is one area, as its own doc comment says.

mod bdpt;
mod bench_rays;
mod cli;
mod denoise;
mod dispersion;
mod display;
mod equal_time;
mod farm;
mod fuzz_regressions;
mod gltf;
mod light;
mod long_renders;
mod malformed;
mod media;
mod mitsuba;
mod mlt;
mod motion;
mod path;
mod pbrt;
mod pbrt_refs;
mod photon;
mod ply;
mod render;
mod sampling;
mod surfaces;
