//! Entry points for fuzzing (the targets in `fuzz/`) and for the tests that
//! replay what fuzzing found (`tests/integration/fuzz_regressions.rs`).
//!
//! Each takes untrusted bytes and runs them through one reader; whatever
//! the reader accepts goes on through [`crate::scene::build_limited`] and a
//! 4×4-pixel render with auxiliary images. Errors are expected and
//! ignored: the only failures are panics, hangs and runaway allocations.
//! Relative file names resolve against the current folder, where the
//! fuzzer's made-up names find nothing.

use crate::film::io::{ImageFormat, decode_image};
use crate::render::checkpoint::Checkpoint;
use crate::render::{RenderOptions, render};
use crate::scene::{self, BuildLimits, SceneDesc};
use std::path::Path;

/// A fuzzing target: a function of the input bytes.
pub type Target = fn(&[u8]);

/// The fuzzing targets, by name.
pub const TARGETS: [(&str, Target); 12] = [
    ("native", native),
    ("mitsuba", mitsuba),
    ("pbrt", pbrt),
    ("obj", obj),
    ("ply", ply),
    ("serialized", serialized),
    ("sdfgrid", sdfgrid),
    ("nanovdb", nanovdb),
    ("measured", measured),
    ("gltf", gltf),
    ("image", image),
    ("checkpoint", checkpoint),
];

/// Memory a fuzzed scene may use.
const MAX_MEMORY: u64 = 64 << 20;

/// Builds and renders a scene that a reader accepted, shrunk to 4×4 pixels,
/// one sample and at most four bounces.
fn exercise(mut desc: SceneDesc) {
    let s = &mut desc.settings;
    s.width = s.width.min(4);
    s.height = s.height.min(4);
    s.spp = 1;
    s.max_depth = s.max_depth.min(4);
    let limits = BuildLimits {
        max_memory: Some(MAX_MEMORY),
        aovs: true,
    };
    let Ok(scene) = scene::build_limited(&desc, &limits) else {
        return;
    };
    let options = RenderOptions {
        threads: Some(1),
        aovs: true,
        ..RenderOptions::default()
    };
    if let Ok(out) = render(&scene, &options) {
        assert!(
            out.film
                .pixels
                .iter()
                .all(|p| p.0.iter().all(|v| v.abs() < i128::MAX / 2)),
            "a pixel's sums came near the end of the fixed point's range"
        );
    }
}

fn text(data: &[u8]) -> Option<&str> {
    std::str::from_utf8(data).ok()
}

/// trazo's TOML scenes.
pub fn native(data: &[u8]) {
    if let Some(Ok(desc)) = text(data).map(|t| scene::native::parse(t, Path::new("fuzz.toml"))) {
        exercise(desc);
    }
}

/// Mitsuba 3 XML, with one `-D` definition.
pub fn mitsuba(data: &[u8]) {
    let defines = [("spp".to_string(), "1".to_string())];
    if let Some(Ok(desc)) = text(data).map(|t| scene::mitsuba::parse(t, Path::new("fuzz.xml"), &defines)) {
        exercise(desc);
    }
}

/// pbrt-v4 scenes.
pub fn pbrt(data: &[u8]) {
    if let Some(Ok(desc)) = text(data).map(|t| scene::pbrt::parse(t, Path::new("fuzz.pbrt"))) {
        exercise(desc);
    }
}

/// OBJ models; the same bytes serve as their MTL library.
pub fn obj(data: &[u8]) {
    let path = Path::new("fuzz.obj");
    let _ = scene::obj::parse_obj_mesh(data, path);
    if let Ok(s) = scene::obj::parse_obj_scene(data, Some(data), path) {
        if let Ok(desc) = scene::builtin::framed_obj(s, path) {
            exercise(desc);
        }
    }
}

/// PLY meshes.
pub fn ply(data: &[u8]) {
    let path = Path::new("fuzz.ply");
    if let Ok(p) = scene::ply::parse_ply(data, path) {
        if let Ok(desc) = scene::builtin::framed_ply(p, path) {
            exercise(desc);
        }
    }
}

/// Mitsuba's `.serialized` meshes: the file's first mesh and its second
/// (found through the table at the end), framed as a PLY model is.
pub fn serialized(data: &[u8]) {
    for index in [0, 1] {
        if let Ok(s) = scene::serialized::parse_serialized(data, index) {
            let ply = scene::ply::PlyMesh {
                mesh: s.mesh,
                ..Default::default()
            };
            if let Ok(desc) = scene::builtin::framed_ply(ply, Path::new("fuzz.serialized")) {
                exercise(desc);
            }
        }
    }
}

/// A signed distance grid from a Mitsuba `.vol` file, met by rays across
/// the unit cube in both shading modes.
pub fn sdfgrid(data: &[u8]) {
    let Ok(grid) = crate::media::grid::VoxelGrid::parse_mitsuba_vol(data) else {
        return;
    };
    for smooth in [false, true] {
        let Ok(sdf) = crate::geometry::sdf_grid::SdfGrid::new(grid.res, grid.data.clone(), smooth) else {
            return;
        };
        for k in 0..16 {
            let a = k as f32 * 0.7;
            let origin = glam::Vec3::new(0.5 + 2.0 * a.cos(), 0.5 + (a * 1.3).sin(), 0.5 + 2.0 * a.sin());
            let ray = crate::geometry::Ray::new(origin, (glam::Vec3::splat(0.5) - origin).normalize());
            if let Some(t) = sdf.intersect(&ray) {
                let p = ray.at(t);
                let _ = (sdf.surface(p), sdf.shading_normal(p));
            }
        }
    }
}

/// A NanoVDB file: its grids' names, then the grid "density" (or else
/// the first) read, looked up, and made dense where that stays small.
pub fn nanovdb(data: &[u8]) {
    use crate::media::nanovdb::{NanoVdbGrid, grid_names};
    let Ok(names) = grid_names(data) else {
        return;
    };
    let name = names
        .iter()
        .find(|n| *n == "density")
        .or(names.first())
        .cloned()
        .unwrap_or_default();
    let Ok(Some(grid)) = NanoVdbGrid::from_file(data, &name) else {
        return;
    };
    let _ = grid.value([0, 0, 0]);
    let Some((lo, hi)) = grid.active_box() else {
        return;
    };
    let _ = grid.value(lo);
    let voxels: i64 = (0..3).map(|a| i64::from(hi[a]) - i64::from(lo[a]) + 2).product();
    if voxels <= 1 << 16 {
        let _ = grid.to_voxel_grid();
    }
}

/// A measured BRDF (an RGL `.bsdf` tensor file), evaluated and sampled
/// for a few directions.
pub fn measured(data: &[u8]) {
    let Ok(brdf) = crate::material::measured::MeasuredBrdf::from_bytes(data) else {
        return;
    };
    let bsdf = crate::material::Bsdf::Measured(crate::material::measured::MeasuredBsdf { brdf: &brdf });
    let mode = crate::material::TransportMode::Radiance;
    for k in 0..8 {
        let a = k as f32 * 0.7;
        let wo = glam::Vec3::new(a.cos() * 0.6, a.sin() * 0.6, 0.5).normalize();
        let u = glam::Vec2::new((a * 0.37).fract(), (a * 0.91).fract());
        if let Some(s) = bsdf.sample(wo, 0.5, u, mode) {
            let _ = (bsdf.eval(wo, s.wi, mode), bsdf.pdf(wo, s.wi));
        }
    }
}

/// glTF, as JSON or GLB (told apart by the first bytes).
pub fn gltf(data: &[u8]) {
    let name = if data.starts_with(b"glTF") {
        "fuzz.glb"
    } else {
        "fuzz.gltf"
    };
    if let Ok(desc) = scene::gltf::parse_bytes(data, Path::new(name), &[]) {
        exercise(desc);
    }
}

/// Image readers: the first byte chooses PNG, Radiance HDR, OpenEXR or PFM
/// (through [`decode_image`]) or any texture format, JPEG included
/// (through [`crate::texture::ImageTexture::decode`]).
pub fn image(data: &[u8]) {
    let Some((&which, bytes)) = data.split_first() else {
        return;
    };
    let format = match which % 5 {
        0 => ImageFormat::Png,
        1 => ImageFormat::Hdr,
        2 => ImageFormat::Exr,
        3 => ImageFormat::Pfm,
        _ => {
            if let Ok(mut t) = crate::texture::ImageTexture::decode(bytes, None) {
                t.sanitize();
                let _ = t.lookup_bilinear(glam::Vec2::new(0.3, 0.7));
            }
            return;
        }
    };
    let _ = decode_image(bytes, format);
}

/// Checkpoint files.
pub fn checkpoint(data: &[u8]) {
    if let Ok(c) = Checkpoint::from_bytes(data) {
        // What was read writes back to the same bytes.
        assert_eq!(c.to_bytes(), data, "a checkpoint does not round-trip");
    }
}
