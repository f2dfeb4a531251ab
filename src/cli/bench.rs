//! `trazo bench`: measurements of the renderer's kernels on the user's own
//! inputs, in the formats that peers' benchmarks share.

use super::check_writable;
use crate::accel::TriangleBvh;
use crate::accel::queries::{encode_hits, parse_rays};
use crate::error::{Error, Result};
use crate::film::io::write_atomic;
use crate::scene::{obj, ply};
use clap::{Args, Subcommand};
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub(super) enum BenchCommand {
    /// Ray queries against a triangle mesh: builds the BVH, then traces
    /// every ray with closest-hit and with any-hit queries on all cores.
    /// Prints `build: S s`, `closest-hit: N rays/s`, `any-hit: N rays/s`.
    Rays(BenchRaysArgs),
}

#[derive(Args, Debug)]
pub(super) struct BenchRaysArgs {
    /// The mesh: .ply (primitive numbers are the PLY's face numbers) or
    /// .obj (triangle numbers).
    #[arg(long, value_name = "MESH")]
    mesh: PathBuf,
    /// The rays: little-endian f32 `ox oy oz dx dy dz` per ray; hits are
    /// accepted for t in (1e-4, ∞).
    #[arg(long, value_name = "RAYS.bin")]
    rays: PathBuf,
    /// Write the closest hits: per ray, t (f32, +inf for a miss) then the
    /// primitive number (u32, 0xFFFFFFFF for a miss), little-endian.
    #[arg(long, value_name = "OUT.bin")]
    hits: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=4096))]
    threads: Option<u32>,
    /// Trace each query this many times and report the fastest.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
}

pub(super) fn run(command: BenchCommand) -> Result<()> {
    match command {
        BenchCommand::Rays(args) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(args.threads.unwrap_or(0) as usize)
                .build()
                .map_err(|e| Error::Invalid(format!("cannot start the worker threads: {e}")))?;
            pool.install(|| bench_rays(&args))
        }
    }
}

fn bench_rays(args: &BenchRaysArgs) -> Result<()> {
    if let Some(p) = &args.hits {
        check_writable(p)?;
    }
    let ext = args
        .mesh
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let (mesh, ids) = match ext.as_str() {
        "ply" => {
            let p = ply::read_ply(&args.mesh)?;
            (p.mesh, Some(p.face_of_triangle))
        }
        "obj" => (obj::load_obj_mesh(&args.mesh)?, None),
        _ => {
            return Err(Error::file(&args.mesh, "unknown mesh format: expected .ply or .obj"));
        }
    };
    if mesh.is_empty() {
        return Err(Error::file(&args.mesh, "the mesh has no triangles"));
    }
    let bytes = std::fs::read(&args.rays).map_err(|e| Error::file(&args.rays, format!("cannot read the rays: {e}")))?;
    let rays = parse_rays(&bytes).map_err(|e| Error::file(&args.rays, e))?;
    drop(bytes);

    let start = Instant::now();
    let bvh = TriangleBvh::build(&mesh, ids.as_deref());
    let build = start.elapsed().as_secs_f64();
    drop(mesh);

    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "build: {build:.3} s");
    let mut hits = Vec::new();
    let closest = best_of(args.repeat, || hits = bvh.closest_hits(&rays));
    let _ = writeln!(out, "closest-hit: {:.0} rays/s", rays.len() as f64 / closest);
    let mut occluded = 0;
    let any = best_of(args.repeat, || occluded = bvh.count_any_hits(&rays));
    let _ = writeln!(out, "any-hit: {:.0} rays/s", rays.len() as f64 / any);
    let hit_count = hits.iter().filter(|h| h.t.is_finite()).count();
    if hit_count != occluded {
        // Both queries see the same geometry; a difference is a bug.
        return Err(Error::Invalid(format!(
            "internal error: {hit_count} closest hits but {occluded} any hits"
        )));
    }
    if let Some(p) = &args.hits {
        let data = encode_hits(&hits);
        write_atomic(p, |f| f.write_all(&data).map_err(|e| e.to_string()))?;
    }
    Ok(())
}

/// Runs `f` `n` times; returns the shortest wall time in seconds.
fn best_of(n: u32, mut f: impl FnMut()) -> f64 {
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64().max(1e-9)
        })
        .fold(f64::INFINITY, f64::min)
}
