//! Measures what building the scene's BVH costs in memory, to check the
//! per-triangle prices of `--max-memory`'s estimate (`src/scene/memory.rs`).
//!
//! `cargo run --release --example memory_probe -- SIDE COUNT` builds COUNT
//! square grids of SIDE×SIDE quads (2·SIDE² triangles each, placed side by
//! side as separate meshes) and prints, per triangle, the peak resident set
//! of the build over what the description already held, what stays resident
//! after it, and the estimate. Linux only (reads `/proc/self/status`).

use glam::Vec3;
use trazo::geometry::TriangleMesh;
use trazo::scene::SceneDesc;
use trazo::scene::desc::{MeshSource, ShapeDesc, ShapeKind};

/// A `/proc/self/status` figure in bytes (`VmRSS:`, `VmHWM:`).
fn status_bytes(key: &str) -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("this probe needs Linux's /proc");
    let kib: u64 = status
        .lines()
        .find(|l| l.starts_with(key))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    kib * 1024
}

/// A slightly bumpy grid of `side`×`side` quads with its corner at (x, 0, z).
fn grid(side: usize, x: f32, z: f32) -> TriangleMesh {
    let mut positions = Vec::new();
    for j in 0..=side {
        for i in 0..=side {
            let bump = ((i * 7 + j * 13) % 10) as f32 * 0.001;
            positions.push(Vec3::new(x + i as f32 * 0.01, bump, z + j as f32 * 0.01));
        }
    }
    let mut indices = Vec::new();
    let row = side as u32 + 1;
    for j in 0..side as u32 {
        for i in 0..side as u32 {
            let a = j * row + i;
            indices.push([a, a + 1, a + row + 1]);
            indices.push([a, a + row + 1, a + row]);
        }
    }
    TriangleMesh {
        positions,
        normals: Vec::new(),
        uvs: Vec::new(),
        indices,
        attributes: Vec::new(),
    }
}

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let [side, count] = args[..] else {
        eprintln!("usage: memory_probe SIDE COUNT (COUNT grids of SIDE×SIDE quads)");
        std::process::exit(2);
    };
    let mut desc = SceneDesc::default();
    for k in 0..count {
        let mesh = grid(
            side,
            (k % 100) as f32 * (side as f32 * 0.01 + 0.02),
            (k / 100) as f32 * (side as f32 * 0.01 + 0.02),
        );
        desc.shapes
            .push(ShapeDesc::new(ShapeKind::InlineMesh(MeshSource::Inline(mesh)), None));
    }
    let triangles = 2 * side * side;
    let vertices = (side + 1) * (side + 1);
    let all = (triangles * count) as f64;
    let before = status_bytes("VmRSS:");
    // Resets the peak (VmHWM) to the current resident set.
    let _ = std::fs::write("/proc/self/clear_refs", "5");
    let scene = trazo::scene::build(&desc).expect("the grids make a valid scene");
    let peak = status_bytes("VmHWM:");
    let after = status_bytes("VmRSS:");
    let estimate = count as u64 * trazo::scene::memory::mesh_bytes(triangles as u64, vertices as u64);
    println!(
        "{count} meshes of {triangles} triangles and {vertices} vertices, bytes per triangle: \
         build peak {:.1}, resident after {:.1}, estimate {:.1} (the description itself {:.1}; {} top-level primitives)",
        peak.saturating_sub(before) as f64 / all,
        after.saturating_sub(before) as f64 / all,
        estimate as f64 / all,
        before as f64 / all,
        scene.geometry.stats().primitives,
    );
}
