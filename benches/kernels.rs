//! Micro-benchmarks of the hot kernels, and a whole small render.
//!
//! Run with `cargo bench --bench kernels`; figures are recorded in
//! BENCHMARKS.md.

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use trazo::Vec3;
use trazo::accel::TriangleBvh;
use trazo::accel::aggregate::{Aggregate, MeshObject, ShapeInstance};
use trazo::geometry::Aabb;
use trazo::geometry::shape::{Rectangle, Shape, Sphere};
use trazo::geometry::triangle::intersect_triangle;
use trazo::geometry::{Ray, TriangleMesh};
use trazo::integrator::{Integrator, PathTracer, RayStats};
use trazo::material::bsdf::{Bsdf, TransportMode};
use trazo::material::conductor::{ConductorBsdf, ConductorFresnel};
use trazo::material::lambert::LambertBsdf;
use trazo::material::microfacet::Microfacet;
use trazo::render::{RenderOptions, render};
use trazo::sampling::Pcg32;
use trazo::sampling::{Sampler, SamplerKind};
use trazo::scene::builtin::cornell_box;
use trazo::settings::PathSampling;
use trazo::{Rgb, Vec2};

fn random_rays(n: usize, seed: u64) -> Vec<Ray> {
    random_rays_into(n, seed, 1.0)
}

/// Rays from a cube of side `6 * extent` toward points in the centred cube
/// of side `extent`.
fn random_rays_into(n: usize, seed: u64, extent: f32) -> Vec<Ray> {
    let mut r = Pcg32::new(seed, 0);
    (0..n)
        .map(|_| {
            let o = (Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 6.0 - 3.0) * extent;
            let target = (Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) - 0.5) * extent;
            Ray::new(o, (target - o).normalize())
        })
        .collect()
}

fn intersection(c: &mut Criterion) {
    let rays = random_rays(1024, 1);
    let sphere = Shape::Sphere(Sphere::new(Vec3::ZERO, 0.8));
    c.bench_function("ray-sphere x1024", |b| {
        b.iter(|| rays.iter().filter(|r| sphere.intersect(black_box(r)).is_some()).count())
    });
    let (p0, p1, p2) = (
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    );
    let aabb = Aabb::new(Vec3::splat(-0.5), Vec3::splat(0.5));
    c.bench_function("ray-box x1024", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| black_box(&aabb).intersect(r, r.dir.recip()).is_some())
                .count()
        })
    });
    c.bench_function("ray-triangle x1024", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| intersect_triangle(black_box(r), p0, p1, p2).is_some())
                .count()
        })
    });
}

fn traversal(c: &mut Criterion) {
    let mesh = TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 400, 200);
    let g = Aggregate::build(
        vec![mesh],
        vec![],
        vec![MeshObject {
            mesh: 0,
            material: 0,
            light: None,
        }],
        vec![],
    );
    let rays = random_rays(4096, 2);
    c.bench_function("aggregate closest-hit 160k triangles x4096", |b| {
        b.iter(|| rays.iter().filter(|r| g.intersect(black_box(r)).is_some()).count())
    });
    c.bench_function("aggregate any-hit 160k triangles x4096", |b| {
        b.iter(|| rays.iter().filter(|r| g.occluded(black_box(r))).count())
    });
    let wide = TriangleBvh::build(&TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 400, 200), None);
    c.bench_function("triangle-bvh closest-hit 160k triangles x4096", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| wide.closest_hit(black_box(r)).t.is_finite())
                .count()
        })
    });
    c.bench_function("triangle-bvh any-hit 160k triangles x4096", |b| {
        b.iter(|| rays.iter().filter(|r| wide.any_hit(black_box(r))).count())
    });
    let mesh = TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 400, 200);
    let bounds: Vec<_> = (0..mesh.len()).map(|i| mesh.triangle_bounds(i)).collect();
    c.bench_function("bvh build 160k triangles", |b| {
        b.iter(|| trazo::accel::Bvh::build(black_box(&bounds)))
    });
}

/// A clutter of `n` rectangles and triangles (edges up to 0.4 long) around
/// the origin, half of each, their corners in the centred cube of side
/// `extent`.
fn clutter(n: usize, seed: u64, extent: f32) -> Aggregate {
    let mut r = Pcg32::new(seed, 9);
    let mut v = || Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) - 0.5;
    let shapes = (0..n / 2)
        .map(|_| ShapeInstance {
            shape: Shape::Rectangle(Rectangle::new(v() * extent, v() * 0.4, v() * 0.4)),
            motion: None,
            transform: None,
            material: 0,
            light: None,
            flip_normals: false,
        })
        .collect();
    let mut mesh = TriangleMesh::default();
    for t in 0..n - n / 2 {
        let c = v() * extent;
        mesh.positions.extend([c, c + v() * 0.4, c + v() * 0.4]);
        mesh.indices.push([3 * t as u32, 3 * t as u32 + 1, 3 * t as u32 + 2]);
    }
    let object = MeshObject {
        mesh: 0,
        material: 0,
        light: None,
    };
    Aggregate::build(vec![mesh], shapes, vec![object], vec![])
}

/// Small scenes through their tree (leaves of blocks of eight): in a clutter (primitives overlapping in a unit cube, as
/// the walls and boxes of a room overlap in extent), spread out (a cube of
/// side 8, where a tree separates them well), and between.
fn small_scenes(c: &mut Criterion) {
    for (name, extent, sizes) in [
        ("small scene", 1.0, &[8, 16, 24, 32, 48, 64, 96, 128][..]),
        ("small scene in a cube of side 2", 2.0, &[24, 48, 64, 96, 128][..]),
        ("small scene in a cube of side 3", 3.0, &[24, 48, 64, 96, 128][..]),
        ("small scene in a cube of side 4", 4.0, &[24, 48, 64, 96, 128][..]),
        ("small spread-out scene", 8.0, &[24, 48, 64, 96, 128][..]),
    ] {
        let rays = random_rays_into(4096, 3, extent);
        let mut g = c.benchmark_group(format!("{name} closest-hit x4096"));
        for &n in sizes {
            let tree = clutter(n, n as u64, extent);
            g.bench_function(format!("{n} primitives ({} nodes)", tree.stats().nodes), |b| {
                b.iter(|| rays.iter().filter(|r| tree.intersect(black_box(r)).is_some()).count())
            });
        }
        g.finish();
    }
}

/// The Mitsuba Cornell box's room (18 rectangles, a tree of one leaf)
/// queried as the path tracer asks: segments from points inside the room
/// in uniform directions, and shadow rays from the same points to points
/// on the ceiling.
fn rectangle_room(c: &mut Criterion) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/crosscheck/scenes/cornell-box.xml");
    let scene = trazo::scene::build(&trazo::scene::load(&path, &[]).unwrap()).unwrap();
    let room = &scene.geometry;
    let bounds = room.bounds();
    let mut r = Pcg32::new(17, 3);
    let mut inside = || {
        bounds.min
            + (bounds.max - bounds.min) * Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 0.98
            + (bounds.max - bounds.min) * 0.01
    };
    let points: Vec<Vec3> = (0..4096).map(|_| inside()).collect();
    let segments: Vec<Ray> = points
        .iter()
        .zip(random_rays(4096, 5))
        .map(|(&p, ray)| Ray::new(p, ray.dir))
        .collect();
    let shadows: Vec<Ray> = points
        .iter()
        .map(|&p| {
            let target = Vec3::new(p.x * 0.3, bounds.max.y * 0.999, p.z * 0.3);
            Ray::with_interval(p, target - p, 1e-4, 1.0 - 1e-3)
        })
        .collect();
    let mut g = c.benchmark_group(format!(
        "rectangle room ({} nodes, {} leaf blocks) x4096",
        room.stats().nodes,
        room.stats().leaf_blocks
    ));
    g.bench_function("closest hit", |b| {
        b.iter(|| {
            segments
                .iter()
                .filter(|r| room.intersect(black_box(r)).is_some())
                .count()
        })
    });
    g.bench_function("any hit", |b| {
        b.iter(|| shadows.iter().filter(|r| room.occluded(black_box(r))).count())
    });
    g.finish();
}

fn bsdf_sampling(c: &mut Criterion) {
    let mut r = Pcg32::new(5, 0);
    let inputs: Vec<(Vec3, f32, Vec2)> = (0..1024)
        .map(|_| {
            let wo = Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() + 0.05).normalize();
            (wo, r.next_f32(), Vec2::new(r.next_f32(), r.next_f32()))
        })
        .collect();
    let bsdfs = [
        (
            "lambert",
            Bsdf::Lambert(LambertBsdf {
                albedo: Rgb::splat(0.5),
            }),
        ),
        (
            "rough conductor",
            Bsdf::Conductor(ConductorBsdf {
                fresnel: ConductorFresnel::Complex {
                    eta: Rgb::new(0.2, 0.9, 1.1),
                    k: Rgb::new(3.9, 2.4, 2.2),
                },
                tint: Rgb::splat(1.0),
                microfacet: Microfacet::isotropic(0.2),
            }),
        ),
    ];
    for (name, bsdf) in bsdfs {
        c.bench_function(&format!("bsdf sample {name} x1024"), |b| {
            b.iter(|| {
                inputs
                    .iter()
                    .filter_map(|&(wo, ul, u)| black_box(&bsdf).sample(wo, ul, u, TransportMode::Radiance))
                    .count()
            })
        });
    }
}

fn path_sample(c: &mut Criterion) {
    let scene = trazo::scene::build(&cornell_box()).unwrap();
    let integrator = PathTracer {
        max_depth: 8,
        rr_depth: 5,
        sampling: PathSampling::Mis,
    };
    let mut sampler = Sampler::new(SamplerKind::Independent, 1 << 20, 0);
    let mut stats = RayStats::default();
    let mut index = 0u32;
    c.bench_function("path sample cornell box mis (one camera ray)", |b| {
        b.iter(|| {
            index = index.wrapping_add(1);
            let (x, y) = (index % 512, (index / 512) % 512);
            sampler.start_pixel_sample(x, y, index);
            let ray = scene
                .camera
                .generate_ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), sampler.next_2d());
            integrator.radiance(&scene, black_box(&ray), &mut sampler, &mut stats)
        })
    });
}

/// Sphere tracing (and interval root finding) on the gallery's scenes of
/// distance functions and equations: closest hits, with their surfaces, of
/// a 160 × 90 grid of camera rays through the scene's own camera, reported
/// as rays per second; the mean steps per ray (the `--aov steps` count) is
/// printed once before the timing.
fn sphere_tracing(c: &mut Criterion) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut g = c.benchmark_group("sphere tracing closest-hit 160x90 camera rays");
    for name in ["distance-functions", "implicit-surfaces"] {
        let d = trazo::scene::load(&root.join(format!("scenes/{name}.toml")), &[]).unwrap();
        let (w, h) = (d.settings.width as f32, d.settings.height as f32);
        let scene = trazo::scene::build(&d).unwrap();
        let rays: Vec<Ray> = (0..90 * 160)
            .map(|i| {
                let film = Vec2::new(
                    ((i % 160) as f32 + 0.5) * w / 160.0,
                    ((i / 160) as f32 + 0.5) * h / 90.0,
                );
                scene.camera.generate_ray(film, Vec2::splat(0.5))
            })
            .collect();
        let trace = || {
            let mut slot = None;
            rays.iter()
                .filter(|ray| {
                    scene.intersect_into(black_box(ray), &mut slot);
                    slot.is_some()
                })
                .count()
        };
        // Steps per ray, and per ray that marched at all (rays that meet
        // only the floor or the sky take none).
        let steps = trazo::geometry::sdf::steps_on_this_thread;
        let mut slot = None;
        let per_ray: Vec<u64> = rays
            .iter()
            .map(|ray| {
                let before = steps();
                scene.intersect_into(ray, &mut slot);
                steps() - before
            })
            .collect();
        let marched = per_ray.iter().filter(|&&n| n > 0).count();
        let total: u64 = per_ray.iter().sum();
        eprintln!(
            "{name}: {:.1} steps per camera ray; {:.0} % of them march, {:.1} steps each; {:.0} % hit",
            total as f64 / rays.len() as f64,
            100.0 * marched as f64 / rays.len() as f64,
            total as f64 / marched.max(1) as f64,
            100.0 * trace() as f64 / rays.len() as f64
        );
        g.throughput(criterion::Throughput::Elements(rays.len() as u64));
        g.sample_size(10);
        g.bench_function(name, |b| b.iter(trace));
    }
    g.finish();
}

/// The environment map of bench/suite/sky-sun.xml (scenes/textures/sky.hdr,
/// 256 × 128 with a small sun), 4096 directions each: radiance and density
/// of directions that escape (what a BSDF-sampled ray that leaves the scene
/// asks), and light samples (what next-event estimation asks), both with
/// the compensated density the path tracer's MIS uses.
fn environment_map(c: &mut Criterion) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let d = trazo::scene::load(&root.join("bench/suite/sky-sun.xml"), &[]).unwrap();
    let scene = trazo::scene::build(&d).unwrap();
    let background = &scene.background;
    let dirs: Vec<Vec3> = random_rays(4096, 7).iter().map(|r| r.dir).collect();
    let mut r = Pcg32::new(8, 0);
    let us: Vec<Vec2> = (0..4096).map(|_| Vec2::new(r.next_f32(), r.next_f32())).collect();
    let mut g = c.benchmark_group("environment map x4096");
    g.throughput(criterion::Throughput::Elements(4096));
    g.bench_function("radiance and density of a direction", |b| {
        b.iter(|| {
            dirs.iter()
                .map(|&d| background.eval_pdf_from(Vec3::ZERO, black_box(d), true).1)
                .sum::<f32>()
        })
    });
    g.bench_function("light sample", |b| {
        b.iter(|| {
            us.iter()
                .filter_map(|&u| background.sample_radiance_from(Vec3::ZERO, black_box(u), true))
                .map(|(_, pdf, _)| pdf)
                .sum::<f32>()
        })
    });
    g.finish();
}

fn whole_render(c: &mut Criterion) {
    let mut d = cornell_box();
    d.settings.width = 128;
    d.settings.height = 128;
    d.settings.spp = 4;
    d.settings.integrator = trazo::settings::IntegratorKind::Path;
    let scene = trazo::scene::build(&d).unwrap();
    let mut g = c.benchmark_group("render");
    g.sample_size(10);
    g.bench_function("cornell box path mis 128x128 4spp", |b| {
        b.iter(|| render(&scene, &RenderOptions::default()).unwrap())
    });
    g.finish();
}

criterion_group!(
    benches,
    intersection,
    traversal,
    small_scenes,
    rectangle_room,
    bsdf_sampling,
    path_sample,
    sphere_tracing,
    environment_map,
    whole_render
);
criterion_main!(benches);
