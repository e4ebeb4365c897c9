//! Per-call costs of glint-brdf: smooth eval, multiscale eval at the Table 1 settings, the glint
//! sampler (direction, f̂ and pdf, as a renderer's `sample` pays them) and its 64-point pdf.

use criterion::{Criterion, criterion_group, criterion_main};
use glint_benches::{TABLE1, table1_brdf_workload};
use glint_brdf::{Bxdf, QueryScratch};
use std::hint::black_box;

const POOL: usize = 1024;

fn brdf(c: &mut Criterion) {
    let mut group = c.benchmark_group("brdf");
    let (first, first_queries) = table1_brdf_workload(&TABLE1[0], POOL, 1);
    let mut i = 0;
    group.bench_function("smooth_eval", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            let (wi, wo, _) = &first_queries[i];
            first.smooth().eval(black_box(*wi), *wo)
        })
    });
    let mut i = 0;
    let mut scratch = QueryScratch::new();
    group.bench_function("glint_sample", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            let (wi, _, f) = &first_queries[i];
            let u = [f.center().x, f.center().y, 0.37, 0.61];
            first.at(f, &mut scratch).sample(black_box(*wi), u)
        })
    });
    let mut i = 0;
    group.bench_function("glint_pdf_64", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            let (wi, wo, _) = &first_queries[i];
            first.sampling_pdf(black_box(*wi), *wo)
        })
    });
    // What a multiscale evaluation adds to its tree query: the conic (every query).
    let cone = glint_sphere::ConeRadius::new(first.parameters().gamma_radians).expect("valid cone");
    let mut i = 0;
    group.bench_function("eval_overhead_conic", |b| {
        b.iter(|| {
            i = (i + 1) % POOL;
            let (wi, wo, _) = &first_queries[i];
            glint_sphere::SphericalConic::with_cone(black_box(*wi), *wo, &cone)
        })
    });
    for setting in &TABLE1 {
        let (brdf, queries) = table1_brdf_workload(setting, POOL, 1);
        let mut scratch = QueryScratch::new();
        let mut i = 0;
        group.bench_function(format!("eval_{}", setting.name), |b| {
            b.iter(|| {
                i = (i + 1) % POOL;
                let (wi, wo, f) = &queries[i];
                brdf.at(f, &mut scratch).eval(black_box(*wi), *wo)
            })
        });
    }
    group.finish();
}

criterion_group!(benches, brdf);
criterion_main!(benches);
