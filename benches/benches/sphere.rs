//! Per-call costs of glint-sphere: conic construction, membership, classification, overlap.

use criterion::{Criterion, criterion_group, criterion_main};
use glint_benches::{mixed_cases, partial_tree_cases, tree_cases};
use glint_sphere::{OverlapMethod, SphericalConic, overlap_solid_angle};
use std::hint::black_box;

const POOL: usize = 4096;

fn sphere(c: &mut Criterion) {
    let mixed = mixed_cases(POOL, 1);
    let tree = tree_cases(POOL, 2);
    let partial = partial_tree_cases(POOL, 3);
    let mut group = c.benchmark_group("sphere");

    let mut i = 0;
    group.bench_function("conic_new", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            let case = &mixed[i];
            SphericalConic::new(
                black_box(case.conic.wi()),
                case.conic.wo(),
                case.conic.gamma(),
            )
        })
    });
    let mut i = 0;
    group.bench_function("contains", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            mixed[i]
                .conic
                .contains(black_box(mixed[(i * 7) % POOL].triangle.centroid()))
        })
    });
    let mut i = 0;
    group.bench_function("classify_tree", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            let (conic, triangle) = &tree[i];
            conic.classify(black_box(triangle))
        })
    });
    let mut i = 0;
    group.bench_function("classify_mixed", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            mixed[i].conic.classify(black_box(&mixed[i].triangle))
        })
    });
    let mut i = 0;
    group.bench_function("solid_angle", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            black_box(&tree[i].1).solid_angle()
        })
    });
    for (name, method) in [
        ("overlap_planar", OverlapMethod::Planar),
        ("overlap_precise", OverlapMethod::Precise),
    ] {
        let mut i = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                i = (i + 1) % POOL;
                let (conic, triangle) = &partial[i];
                overlap_solid_angle(black_box(triangle), conic, method)
            })
        });
    }
    group.finish();
}

criterion_group!(benches, sphere);
criterion_main!(benches);
