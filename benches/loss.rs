//! Loss timings at the paper's setting: MS-MSE and D-SSIM (value + gradient) on 1024² f32
//! images, the composite loss without LPIPS through candle (forward + backward), and LPIPS
//! forward + backward at 224² (skipped with a message when the weights are absent: run
//! `python3 scripts/fetch_lpips.py`).
//!
//! Run with `cargo bench --bench loss`; sized for a 2-core machine.

/// The allocator the `ifslab` binary ships with, so the figures are what users get.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::hint::black_box;
use std::time::Duration;

use candle_core::{Device, Tensor, Var};
use criterion::{Criterion, criterion_group, criterion_main};
use ifslab::loss::{DSsim, ImageLoss, LossConfig, Lpips, Moments, MsMse, Objective};

/// A sparse, fractal-like grey image: bright specks on black, deterministic.
fn speckles(side: usize, salt: u64) -> Vec<f32> {
    (0..side * side)
        .map(|i| {
            let h = (i as u64 ^ salt).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
            if h.is_multiple_of(5) {
                (h % 1000) as f32 / 1000.0
            } else {
                0.0
            }
        })
        .collect()
}

fn image_losses(c: &mut Criterion) {
    let side = 1024;
    let (p, t) = (speckles(side, 1), speckles(side, 2));
    let mut g = c.benchmark_group("loss_1024");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    g.bench_function("msmse_value_grad_f32", |b| {
        b.iter(|| {
            MsMse::default()
                .value_and_grad(black_box(&p), &t, side, side)
                .unwrap()
        })
    });
    g.bench_function("dssim_value_grad_f32", |b| {
        b.iter(|| {
            DSsim::default()
                .value_and_grad(black_box(&p), &t, side, side)
                .unwrap()
        })
    });
    g.bench_function("moments_value_grad_f32", |b| {
        b.iter(|| {
            Moments::default()
                .value_and_grad(black_box(&p), &t, side, side)
                .unwrap()
        })
    });
    // 10·MS-MSE + D-SSIM as candle tensors, forward and backward (what an iteration pays).
    let dev = Device::Cpu;
    let target = Tensor::from_vec(t.clone(), (side, side), &dev).unwrap();
    let cfg = LossConfig {
        lpips_weight: 0.0,
        ..Default::default()
    };
    let obj = Objective::new(cfg, &target).unwrap();
    let x = Var::from_vec(p.clone(), (side, side), &dev).unwrap();
    g.bench_function("objective_no_lpips_fwd_bwd_f32", |b| {
        b.iter(|| {
            let (total, _) = obj.image_loss(x.as_tensor()).unwrap();
            total.backward().unwrap()
        })
    });
    g.finish();
}

fn lpips(c: &mut Criterion) {
    let net = match Lpips::try_load_default() {
        Ok(Some(net)) => net,
        Ok(None) => {
            eprintln!("skipping LPIPS benchmark: no weights (run `ifslab weights fetch`)");
            return;
        }
        Err(e) => panic!("{e}"),
    };
    let side = 224;
    let dev = Device::Cpu;
    let target = Tensor::from_vec(speckles(side, 3), (side, side), &dev).unwrap();
    let feats = net.features(&target).unwrap();
    let x = Var::from_vec(speckles(side, 4), (side, side), &dev).unwrap();
    let mut g = c.benchmark_group("lpips_224");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    g.bench_function("forward_backward_cached_target_f32", |b| {
        b.iter(|| {
            let d = net.distance_to(x.as_tensor(), &feats).unwrap();
            d.backward().unwrap()
        })
    });
    g.bench_function("forward_only_cached_target_f32", |b| {
        b.iter(|| net.distance_to(&x.as_tensor().detach(), &feats).unwrap())
    });
    g.finish();
}

criterion_group!(benches, image_losses, lpips);
criterion_main!(benches);
