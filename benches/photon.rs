//! Photon mapping's kernels: the photon pass (tracing, all threads), the
//! kd-tree build, and the two lookups of density estimation.
//!
//! Run with `cargo bench --bench photon`; figures are recorded in
//! BENCHMARKS.md.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use trazo::Vec3;
use trazo::integrator::photon::trace::{PhotonStore, trace_photons};
use trazo::integrator::photon::{Nearest, PhotonMap};
use trazo::sampling::Pcg32;
use trazo::scene::builtin::cornell_box;

fn photon_kernels(c: &mut Criterion) {
    let scene = trazo::scene::build(&cornell_box()).unwrap();
    let mut group = c.benchmark_group("photon");
    group.sample_size(10);
    group.throughput(Throughput::Elements(100_000));
    group.bench_function("trace 100k photons, cornell box", |b| {
        b.iter(|| trace_photons(&scene, 100_000, 1, 0, 8, PhotonStore::All).photons.len())
    });
    let photons = trace_photons(&scene, 200_000, 1, 0, 8, PhotonStore::All).photons;
    let stored = photons.len();
    group.throughput(Throughput::Elements(stored as u64));
    group.bench_function(format!("build kd-tree of {stored} photons"), |b| {
        b.iter(|| PhotonMap::build(black_box(photons.clone())).len())
    });
    let map = PhotonMap::build(photons);
    // Queries where the light is: at stored photons, jittered.
    let mut r = Pcg32::new(3, 0);
    let queries: Vec<Vec3> = (0..1024)
        .map(|_| {
            let ph = map.photon(r.next_below(map.len() as u32));
            ph.p + (Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) - 0.5) * 0.01
        })
        .collect();
    let mut found = Nearest::default();
    let within: usize = queries
        .iter()
        .map(|q| {
            let mut n = 0;
            map.for_each_within(*q, 0.035 * 0.035, |_, _| n += 1);
            n
        })
        .sum();
    eprintln!(
        "{stored} photons stored from 200k emitted; a radius-0.035 query finds {:.1} photons on average",
        within as f64 / queries.len() as f64
    );
    group.throughput(Throughput::Elements(queries.len() as u64));
    for k in [8usize, 64] {
        group.bench_function(format!("k-nearest k={k} x1024"), |b| {
            b.iter(|| {
                let mut s = 0.0f32;
                for q in &queries {
                    s += map.nearest(*q, k, 0.03, &mut found).unwrap_or(0.0);
                }
                s
            })
        });
    }
    group.bench_function("radius 0.035 x1024", |b| {
        b.iter(|| {
            let mut n = 0usize;
            for q in &queries {
                map.for_each_within(*q, 0.035 * 0.035, |_, _| n += 1);
            }
            n
        })
    });
    group.finish();
}

criterion_group!(benches, photon_kernels);
criterion_main!(benches);
