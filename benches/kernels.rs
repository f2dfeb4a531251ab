//! Micro-benchmarks of the hot kernels, and a whole small render.
//!
//! Run with `cargo bench --bench kernels`; figures are recorded in
//! BENCHMARKS.md.

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use trazo::Vec3;
use trazo::accel::aggregate::{Aggregate, MeshObject};
use trazo::geometry::shape::{Shape, Sphere};
use trazo::geometry::triangle::intersect_triangle;
use trazo::geometry::{Ray, TriangleMesh};
use trazo::render::{RenderOptions, render};
use trazo::sampling::Pcg32;
use trazo::scene::builtin::cornell_box;

fn random_rays(n: usize, seed: u64) -> Vec<Ray> {
    let mut r = Pcg32::new(seed, 0);
    (0..n)
        .map(|_| {
            let o = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 6.0 - 3.0;
            let target = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) - 0.5;
            Ray::new(o, (target - o).normalize())
        })
        .collect()
}

fn intersection(c: &mut Criterion) {
    let rays = random_rays(1024, 1);
    let sphere = Shape::Sphere(Sphere {
        center: Vec3::ZERO,
        radius: 0.8,
    });
    c.bench_function("ray-sphere x1024", |b| {
        b.iter(|| rays.iter().filter(|r| sphere.intersect(black_box(r)).is_some()).count())
    });
    let (p0, p1, p2) = (
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    );
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
    c.bench_function("bvh closest-hit 160k triangles x4096", |b| {
        b.iter(|| rays.iter().filter(|r| g.intersect(black_box(r)).is_some()).count())
    });
    c.bench_function("bvh any-hit 160k triangles x4096", |b| {
        b.iter(|| rays.iter().filter(|r| g.occluded(black_box(r))).count())
    });
    let mesh = TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 400, 200);
    let bounds: Vec<_> = (0..mesh.len()).map(|i| mesh.triangle_bounds(i)).collect();
    c.bench_function("bvh build 160k triangles", |b| {
        b.iter(|| trazo::accel::Bvh::build(black_box(&bounds)))
    });
}

fn whole_render(c: &mut Criterion) {
    let mut d = cornell_box();
    d.settings.width = 128;
    d.settings.height = 128;
    d.settings.spp = 4;
    let scene = trazo::scene::build(&d).unwrap();
    let mut g = c.benchmark_group("render");
    g.sample_size(10);
    g.bench_function("cornell box whitted 128x128 4spp", |b| {
        b.iter(|| render(&scene, &RenderOptions::default()).unwrap())
    });
    g.finish();
}

criterion_group!(benches, intersection, traversal, whole_render);
criterion_main!(benches);
