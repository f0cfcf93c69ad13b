//! EM iteration throughput: one E-step + M-step on a batch of N′ = 500 points.
//!
//! - `em_step/k3_d6_h2`: the paper's setting (K = 3, D = 6 → 1093 codes, 2-D).
//! - `em_depth/d{2..7}`: K = 3 in 2-D, codes grow as 3^D.
//! - `em_dim/h{2,3,5,10}`: K = 3, D = 6, in H dimensions.
//! - `em_update/{outermost,all-positions}`: the two component-update rules at K = 3, D = 6.
//!
//! Run: `CARGO_TARGET_DIR=… cargo bench -p ifslab-strategies --bench em`.

/// The allocator the `ifslab` binary ships with, so the figures are what users get.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ifslab::chaos::trajectory_rng;
use ifslab::model::Similitude;
use ifslab_strategies::problems::em::{
    ComponentUpdate, EmModel, MStepConfig, PointSet, em_step, init,
};

/// A batch of 500 points from a random 3-map IFS in R^h, and a random starting model.
fn setup(h: usize, depth: usize) -> (EmModel, PointSet) {
    let mut rng = trajectory_rng(1, h as u64);
    let generator = init::random_model(3, 10, 0.5, Similitude::identity(h), &mut rng).unwrap();
    let batch = generator.sample(500, 2).unwrap();
    let start =
        init::random_model(3, depth, 0.5, init::normalising_post(&batch), &mut rng).unwrap();
    (start, batch)
}

fn bench(c: &mut Criterion) {
    let cfg = MStepConfig::default();
    let mut g = c.benchmark_group("em_step");
    g.throughput(Throughput::Elements(1));
    let (m, batch) = setup(2, 6);
    g.bench_function("k3_d6_h2", |b| {
        let mut rng = trajectory_rng(0, 0);
        b.iter(|| em_step(&m, &batch, &cfg, &mut rng).unwrap())
    });
    g.finish();

    let mut g = c.benchmark_group("em_depth");
    for depth in 2..=7 {
        let (m, batch) = setup(2, depth);
        g.bench_with_input(BenchmarkId::from_parameter(depth), &depth, |b, _| {
            let mut rng = trajectory_rng(0, 0);
            b.iter(|| em_step(&m, &batch, &cfg, &mut rng).unwrap())
        });
    }
    g.finish();

    let mut g = c.benchmark_group("em_dim");
    for h in [2usize, 3, 5, 10] {
        let (m, batch) = setup(h, 6);
        g.bench_with_input(BenchmarkId::from_parameter(h), &h, |b, _| {
            let mut rng = trajectory_rng(0, 0);
            b.iter(|| em_step(&m, &batch, &cfg, &mut rng).unwrap())
        });
    }
    g.finish();

    let mut g = c.benchmark_group("em_update");
    let (m, batch) = setup(2, 6);
    for (name, update) in [
        ("outermost", ComponentUpdate::Outermost),
        ("all-positions", ComponentUpdate::AllPositions),
    ] {
        let cfg = MStepConfig {
            update,
            ..MStepConfig::default()
        };
        g.bench_function(name, |b| {
            let mut rng = trajectory_rng(0, 0);
            b.iter(|| em_step(&m, &batch, &cfg, &mut rng).unwrap())
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(std::time::Duration::from_secs(4));
    targets = bench
}
criterion_main!(benches);
