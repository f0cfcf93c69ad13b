//! Per-iteration breakdown of the fused splat op, like the chaotic-splatting paper's Table 2:
//! generation (chaos game), splat forward (framing + splat + pooling), reverse pass.
//!
//! Settings:
//! - `paper`: 2000 × 250 trajectories (480k kept points), 1024² output, 5× supersampling,
//!   σ = 2.5 supersampled pixels, coverage blending;
//! - `cheap`: same points, 256², 1×, σ = 1, additive.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use ifslab::model::param::Parameterisation;
use ifslab::model::random::sample_code;
use ifslab::model::{Affine2, Svd};
use ifslab::render::splat::{self, Blend, SplatConfig};

fn setting(name: &str) -> SplatConfig {
    match name {
        "paper" => SplatConfig {
            width: 1024,
            height: 1024,
            supersample: 5,
            sigma: 2.5,
            blend: Blend::Coverage,
            ..SplatConfig::default()
        },
        _ => SplatConfig {
            width: 256,
            height: 256,
            supersample: 1,
            sigma: 1.0,
            blend: Blend::Additive,
            ..SplatConfig::default()
        },
    }
}

fn maps() -> Vec<Affine2> {
    // A 10-map code inside the SVD parameterisation's normalised square.
    let s = sample_code(10, 3).unwrap();
    let p = Svd::default();
    let theta = p
        .encode(
            &s.maps
                .iter()
                .map(|m| Affine2 {
                    m: m.m,
                    b: m.b * 0.9,
                })
                .collect::<Vec<_>>(),
        )
        .unwrap();
    p.decode(&theta).unwrap()
}

fn bench_splat(c: &mut Criterion) {
    let maps = maps();
    for name in ["paper", "cheap"] {
        let cfg = setting(name);
        let mut g = c.benchmark_group(format!("splat_{name}"));
        g.sample_size(10);
        g.bench_function("generation", |b| {
            b.iter(|| {
                black_box(
                    splat::trajectories::run(&cfg.game, &maps, 1)
                        .unwrap()
                        .states
                        .len(),
                )
            })
        });
        g.bench_function("forward", |b| {
            b.iter(|| black_box(splat::forward::<f32>(&cfg, &maps, 1).unwrap().0.len()))
        });
        let (img, tape) = splat::forward::<f32>(&cfg, &maps, 1).unwrap();
        let grad: Vec<f32> = img.iter().map(|v| v - 0.5).collect();
        g.bench_function("backward", |b| {
            b.iter(|| black_box(splat::backward(&cfg, &maps, &tape, &grad).unwrap().len()))
        });
        g.finish();
    }
}

criterion_group!(benches, bench_splat);
criterion_main!(benches);
