//! Evaluation-render throughput: a 10-map random code, 50M points into 1024² with 16×
//! binary supersampling (the chaotic-splatting paper's ground-truth setting).
//!
//! Measurements in the same run:
//! - `render`: the streaming renderer as shipped (chaos game compiled for FMA where the CPU
//!   has it, points binned by tile);
//! - `chaos_only`: the same trajectories through the same `PointStream` (same instruction
//!   set, same four-lane loop, same warm-up, same schedule), each point only folded into a
//!   checksum: the floor;
//! - `render_portable` / `chaos_only_portable`: both again with the chaos game compiled for
//!   baseline x86-64, where every `mul_add` is a call (what the FMA dispatch buys);
//! - `baseline_store_then_raster`: the straightforward pipeline — store every point, then
//!   draw them into a byte-per-sub-pixel 16384² buffer and box-downsample — at 1/10 of the
//!   points (its buffer alone is 256 MiB), reported per point for comparison.

/// The allocator the `ifslab` binary ships with, so the figures are what users get.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ifslab::chaos::{ChaosGame, Isa, LANES, MapSampler, PointSink, PointStream};
use ifslab::model::IfsCode;
use ifslab::model::random::sample_code;
use ifslab::render::{RenderConfig, View, render, render_with_isa};
use rayon::prelude::*;

const POINTS: u64 = 50_000_000;

/// Folds every point into one word, so nothing is optimised away and nothing is stored.
struct Checksum(u64);

impl PointSink for Checksum {
    #[inline(always)]
    fn put(&mut self, p: [f64; 2]) {
        self.0 ^= p[0].to_bits() ^ p[1].to_bits();
    }
}

fn setup() -> (Vec<ifslab::model::Affine2>, Vec<f64>) {
    let s = sample_code(10, 3).unwrap();
    let probs = IfsCode::from_affine2(None, &s.maps)
        .unwrap()
        .evaluation_probabilities()
        .unwrap();
    (s.maps, probs)
}

fn bench_render(c: &mut Criterion) {
    let (maps, probs) = setup();
    let cfg = RenderConfig {
        width: 1024,
        height: 1024,
        points: POINTS,
        supersample: 16,
        seed: 1,
        ..RenderConfig::default()
    };
    // Fix the window once so every variant measures drawing, not the pilot run.
    let window = render(
        &maps,
        &probs,
        &RenderConfig {
            points: 10_000,
            ..cfg.clone()
        },
        None,
    )
    .unwrap()
    .stats
    .window;
    let cfg = RenderConfig {
        view: View::Window(window),
        ..cfg
    };
    let draw = |isa| render_with_isa(&maps, &probs, &cfg, None, isa);
    let mut g = c.benchmark_group("eval_render_10maps_1024px_16x");
    g.sample_size(10);
    g.throughput(Throughput::Elements(POINTS));
    let sampler = MapSampler::new(&probs).unwrap();
    // The renderer's layout and schedule: 1024 trajectories in batches of four taken by
    // whichever thread is free, 100 warm-up steps, start points in [−1, 1]².
    let chaos_only = |isa| {
        let stream = PointStream::new(&maps, &sampler, cfg.seed, 1.0, cfg.warmup)
            .unwrap()
            .with_isa(isa)
            .unwrap();
        let t = 1024usize;
        let points_of = |i: usize| POINTS / t as u64 + u64::from((i as u64) < POINTS % t as u64);
        (0..t.div_ceil(LANES))
            .into_par_iter()
            .map(|b| {
                let (lo, hi) = (b * LANES, ((b + 1) * LANES).min(t));
                let ns: Vec<u64> = (lo..hi).map(points_of).collect();
                let mut sink = Checksum(0);
                stream.run(lo as u64, &ns, &mut sink).unwrap();
                sink.0
            })
            .reduce(|| 0, |a, b| a ^ b)
    };
    let isa = Isa::detect();
    g.bench_function("render", |b| {
        b.iter(|| black_box(draw(isa).unwrap().values.len()))
    });
    g.bench_function("chaos_only", |b| b.iter(|| black_box(chaos_only(isa))));
    if isa != Isa::Portable {
        g.bench_function("render_portable", |b| {
            b.iter(|| black_box(draw(Isa::Portable).unwrap().values.len()))
        });
        g.bench_function("chaos_only_portable", |b| {
            b.iter(|| black_box(chaos_only(Isa::Portable)))
        });
    }
    let n_base = POINTS / 10;
    g.throughput(Throughput::Elements(n_base));
    g.bench_function("baseline_store_then_raster_5M", |b| {
        b.iter(|| {
            let game = ChaosGame {
                trajectories: 1024,
                length: (n_base / 1024) as usize + 100,
                warmup: 100,
                start_half_width: 1.0,
                seed: 1,
            };
            let pts = game.generate(&maps, &probs).unwrap();
            let (w, s) = (1024usize, 16usize);
            let big = w * s;
            let mut buf = vec![0u8; big * big];
            let size = window.size();
            for p in &pts.data {
                let fx = (p[0] - window.min[0]) / size[0] * big as f64;
                let fy = (window.max[1] - p[1]) / size[1] * big as f64;
                if fx >= 0.0 && fy >= 0.0 && fx < big as f64 && fy < big as f64 {
                    buf[fy as usize * big + fx as usize] = 1;
                }
            }
            let out: Vec<f32> = (0..w * w)
                .into_par_iter()
                .map(|i| {
                    let (py, px) = (i / w, i % w);
                    let mut n = 0u32;
                    for sy in 0..s {
                        let row = &buf[(py * s + sy) * big + px * s..][..s];
                        n += row.iter().map(|&v| v as u32).sum::<u32>();
                    }
                    n as f32 / (s * s) as f32
                })
                .collect();
            black_box(out.len())
        })
    });
    g.finish();
}

criterion_group!(benches, bench_render);
criterion_main!(benches);
