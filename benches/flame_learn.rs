//! One iteration of learning a flame at the peer's setting of the paper's Fig. 4: one layer
//! of 8 generators, 1000 trajectories × 1000 steps (10⁶ samples), 100², the authors' MSE
//! against a target and its gradient back to every parameter — the work of one gradient
//! step. Linear generators (the peer, Taichi on 2 CPU threads: 0.85 s per iteration) and the
//! same with the disc variation; the forward pass alone beside them (what bounds it).
//! The Fighting Forms setting (3 layers × 24 generators, half of them non-linear, 200²) too.
//!
//! Run with `cargo bench --bench flame_learn`; sized for a 2-core machine.

/// The allocator the `ifslab` binary ships with, so the figures are what users get.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use ifslab::model::flame::VariationKind as V;
use ifslab::model::flame::learnable::{
    Background, FlameStack, Learn, LearnableFlame, LearnableInit,
};
use ifslab::render::flame_diff::{DiffFlameConfig, GeneratorOrder, backward, forward, mse};

fn stack(layers: &[Vec<Vec<V>>], bg: Background) -> FlameStack {
    FlameStack {
        layers: layers
            .iter()
            .enumerate()
            .map(|(i, v)| {
                LearnableFlame::random(v, Learn::default(), &LearnableInit::default(), i as u64)
                    .unwrap()
            })
            .collect(),
        background: bg,
    }
}

fn target(size: usize) -> Vec<f32> {
    (0..3 * size * size)
        .map(|i| ((i * 7919) % 101) as f32 / 100.0)
        .collect()
}

fn flame_iteration(c: &mut Criterion) {
    let mut g = c.benchmark_group("flame_learn");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    let cfg = DiffFlameConfig::default();
    let t = target(cfg.size);
    for (label, var) in [("linear", V::Linear), ("disc", V::Disc)] {
        let st = stack(&[vec![vec![var]; 8]], Background::Fixed([1.0; 3]));
        let order = GeneratorOrder::draw(&st, &cfg, 1);
        g.bench_function(format!("fig4_{label}_8x1M_100/forward"), |b| {
            b.iter(|| black_box(forward(&st, &cfg, &order).unwrap()))
        });
        g.bench_function(format!("fig4_{label}_8x1M_100/iteration"), |b| {
            b.iter(|| {
                let f = forward(&st, &cfg, &order).unwrap();
                let (_, gi) = mse(&f.image, &t).unwrap();
                black_box(backward(&st, &cfg, &order, &f, &gi).unwrap())
            })
        });
    }
    let cfg = DiffFlameConfig {
        size: 200,
        ..DiffFlameConfig::default()
    };
    let t = target(cfg.size);
    let layer = |v: V| -> Vec<Vec<V>> {
        (0..24)
            .map(|i| if i > 12 { vec![v] } else { vec![V::Linear] })
            .collect()
    };
    let st = stack(
        &[
            layer(V::Spherical),
            layer(V::Handkerchief),
            layer(V::Exponential),
        ],
        Background::Learned([0.0; 3]),
    );
    let order = GeneratorOrder::draw(&st, &cfg, 1);
    g.bench_function("fighting_forms_3x24x1M_200/iteration", |b| {
        b.iter(|| {
            let f = forward(&st, &cfg, &order).unwrap();
            let (_, gi) = mse(&f.image, &t).unwrap();
            black_box(backward(&st, &cfg, &order, &f, &gi).unwrap())
        })
    });
    g.finish();
}

criterion_group!(benches, flame_iteration);
criterion_main!(benches);
