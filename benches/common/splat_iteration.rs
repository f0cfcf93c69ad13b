// The body of the per-iteration benchmark, shared by `splat.rs` (mimalloc, as shipped) and
// `splat_system_alloc.rs` (glibc's allocator: the baseline for the allocator choice).
// With `--features cuda`, the `*_cuda` groups run the splat on the GPU; there
// `full_iteration` is the candle route (image down, loss on the CPU, gradient up) and
// `full_iteration_fused` the fused GPU iteration, in the same run.
// Included with `include!`; the including file defines `GROUP_SUFFIX`.

use std::hint::black_box;

use candle_core::{DType, Device, Tensor, Var};
use criterion::{Criterion, criterion_group, criterion_main};
use ifslab::loss::{ImageLoss, LossConfig, MsMse, Objective};
use ifslab::model::param::Parameterisation;
use ifslab::model::random::sample_code;
use ifslab::model::{Affine2, Svd};
use ifslab::render::splat::{self, Blend, SplatConfig, SplatOp, maps_to_tensor};

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
        // What `ifslab demo` and the reproduction runs use: 96², 4×, σ = 1, coverage,
        // 1000 × 110 trajectories (100 k points).
        "demo" => SplatConfig {
            width: 96,
            height: 96,
            supersample: 4,
            sigma: 1.0,
            blend: Blend::Coverage,
            game: ifslab::chaos::ChaosGame {
                trajectories: 1000,
                length: 110,
                warmup: 10,
                ..SplatConfig::default().game
            },
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
    let dev = Device::Cpu;
    #[cfg_attr(not(feature = "cuda"), allow(unused_mut))]
    let mut settings: Vec<(String, SplatConfig)> = ["paper", "cheap", "demo"]
        .iter()
        .map(|n| (n.to_string(), setting(n)))
        .collect();
    // With the GPU backend, each setting again with the splat on the GPU (groups
    // `iteration_paper_cuda`, …): the CPU figures and the GPU's in one run, on one machine.
    #[cfg(feature = "cuda")]
    for n in ["paper", "cheap", "demo"] {
        settings.push((
            format!("{n}_cuda"),
            SplatConfig {
                device: ifslab::render::splat::SplatDevice::Cuda,
                ..setting(n)
            },
        ));
    }
    for (name, cfg) in settings {
        let (w, h) = (cfg.width, cfg.height);
        // The target: the same code rendered with other trajectories.
        let (target, _) = splat::forward::<f32>(&setting(name.trim_end_matches("_cuda")), &maps, 99)
            .unwrap();
        let target_t = Tensor::from_vec(target.clone(), (h, w), &dev).unwrap();
        let loss_cfg = LossConfig {
            lpips_weight: 0.0,
            ..LossConfig::default()
        };
        let objective = Objective::new(loss_cfg.clone(), &target_t).unwrap();
        let msmse = MsMse::new(loss_cfg.msmse_levels);

        let mut g = c.benchmark_group(format!("iteration_{name}{}", GROUP_SUFFIX));
        g.sample_size(10);
        g.bench_function("generation", |b| {
            b.iter(|| {
                black_box(
                    splat::trajectories::run(&cfg.game, &maps, None, 1)
                        .unwrap()
                        .states
                        .len(),
                )
            })
        });
        g.bench_function("splat_forward", |b| {
            b.iter(|| black_box(splat::forward::<f32>(&cfg, &maps, 1).unwrap().0.len()))
        });
        let (img, tape) = splat::forward::<f32>(&cfg, &maps, 1).unwrap();
        let pred = Var::from_tensor(&Tensor::from_vec(img.clone(), (h, w), &dev).unwrap()).unwrap();
        g.bench_function("loss", |b| {
            b.iter(|| {
                let ev = objective.evaluate(pred.as_tensor(), &maps).unwrap();
                let grads = ev.image_total.backward().unwrap();
                black_box(grads.get(pred.as_tensor()).is_some())
            })
        });
        let grad: Vec<f32> = img.iter().zip(&target).map(|(a, t)| a - t).collect();
        g.bench_function("splat_backward", |b| {
            b.iter(|| black_box(splat::backward(&cfg, &maps, &tape, &grad).unwrap().len()))
        });
        g.bench_function("anneal_candidate", |b| {
            b.iter(|| {
                let (p, _) = splat::forward::<f32>(&cfg, &maps, 2).unwrap();
                black_box(msmse.value(&p, &target, w, h).unwrap())
            })
        });
        let p = Svd::default();
        let theta = p.encode(&maps).unwrap();
        g.bench_function("full_iteration", |b| {
            b.iter(|| {
                let m = p.decode(&theta).unwrap();
                let var = Var::from_tensor(&maps_to_tensor(&m, DType::F32, &dev).unwrap()).unwrap();
                let pred = var
                    .as_tensor()
                    .apply_op1(SplatOp::new(cfg.clone(), 3))
                    .unwrap();
                let ev = objective.evaluate(&pred, &m).unwrap();
                let grads = ev.image_total.backward().unwrap();
                let gm =
                    ifslab::render::splat::maps_from_tensor(grads.get(var.as_tensor()).unwrap())
                        .unwrap();
                black_box(p.backward(&theta, &gm).unwrap().len())
            })
        });
        // With the splat on the GPU, the same iteration fused (`splat::objective_and_grad`:
        // the image, the loss and its gradient stay on the GPU, page-locked transfers) and
        // the annealing candidate's score on the GPU, beside the candle route above.
        #[cfg(feature = "cuda")]
        if splat::gpu_route(&cfg, &objective, false).is_ok() {
            g.bench_function("full_iteration_fused", |b| {
                b.iter(|| {
                    let m = p.decode(&theta).unwrap();
                    let (_, grad) =
                        splat::objective_and_grad(&cfg, &m, None, false, 3, &objective).unwrap();
                    let gm: Vec<Affine2> =
                        grad.chunks_exact(6).map(Affine2::from_coefficients).collect();
                    black_box(p.backward(&theta, &gm).unwrap().len())
                })
            });
            g.bench_function("anneal_candidate_fused", |b| {
                b.iter(|| {
                    black_box(
                        splat::render_msmse(&cfg, &maps, None, false, 2, &objective)
                            .unwrap()
                            .unwrap(),
                    )
                })
            });
        }
        g.finish();
    }
}

