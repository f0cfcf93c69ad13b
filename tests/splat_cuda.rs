//! The splat on the GPU (`--features cuda`), against the CPU kernel: the same image, the
//! same gradients, finite differences of its own forward pass, determinism, the candle op;
//! the loss on the GPU (MS-MSE, D-SSIM) against the CPU loss, and the fused iteration (image,
//! loss and gradient on the GPU) against the candle route.
//!
//! These tests need an NVIDIA GPU, its driver and NVRTC, and fail without them (except
//! `nvrtc_compiles_the_kernels`, which needs NVRTC only). CI compiles them; they run on a GPU
//! machine through `scripts/gpu/run.sh` (docs/GPU.md).
#![cfg(feature = "cuda")]

use candle_core::{DType, Device, Var};
use ifslab::chaos::ChaosGame;
use ifslab::loss::cuda::GpuLoss;
use ifslab::loss::{DSsim, ImageLoss, LossBreakdown, LossConfig, MsMse, Objective, Real};
use ifslab::model::Affine2;
use ifslab::render::splat::{
    self, Blend, SplatConfig, SplatDevice, SplatOp, SplatReal, SplatView, maps_from_tensor,
    maps_to_tensor,
};

fn maps() -> Vec<Affine2> {
    vec![
        Affine2::new(0.45, 0.1, -0.05, 0.5, -0.4, -0.3),
        Affine2::new(0.5, -0.12, 0.08, 0.42, 0.45, -0.2),
        Affine2::new(0.38, 0.05, 0.1, 0.4, 0.05, 0.5),
    ]
}

fn config(blend: Blend, supersample: usize, sigma: f64, trajectories: usize) -> SplatConfig {
    SplatConfig {
        width: 48,
        height: 40,
        supersample,
        sigma,
        radius: 3.0,
        blend,
        alpha_max: 0.99,
        game: ChaosGame {
            trajectories,
            length: 110,
            warmup: 10,
            start_half_width: 2.0,
            seed: 0,
        },
        framing: SplatView::default(),
        device: SplatDevice::Cpu,
    }
}

fn on(cfg: &SplatConfig, device: SplatDevice) -> SplatConfig {
    SplatConfig {
        device,
        ..cfg.clone()
    }
}

/// Fixed pseudo-random weights W: L = Σ W ⊙ image, ∂L/∂image = W.
fn weights(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| ((i as f64 * 12.9898).sin() * 43758.5453).fract() - 0.25)
        .collect()
}

fn settings() -> Vec<SplatConfig> {
    let mut v = Vec::new();
    for blend in [Blend::Coverage, Blend::Additive] {
        v.push(config(blend, 1, 1.3, 200));
        v.push(config(blend, 3, 2.5, 200));
        // Dense: many splats per pixel, covered pixels (the transmittance floor).
        v.push(config(blend, 2, 1.0, 2000));
    }
    v
}

fn max_abs<T: SplatReal>(a: &[T], b: &[T]) -> (f64, f64) {
    let d = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x.to_f64().unwrap() - y.to_f64().unwrap()).abs())
        .fold(0.0, f64::max);
    let m = b
        .iter()
        .map(|x| x.to_f64().unwrap().abs())
        .fold(0.0, f64::max);
    (d, m)
}

#[test]
fn nvrtc_compiles_the_kernels() {
    for arch in ["compute_75", "compute_90"] {
        let n = splat::cuda::compile_only(arch).unwrap();
        assert!(n > 1000, "{arch}: PTX of {n} bytes");
    }
}

#[test]
fn a_gpu_is_there() {
    let d = splat::cuda::describe().unwrap();
    eprintln!("GPU: {d}");
}

fn forward_matches<T: SplatReal>(tol: f64) {
    for cfg in settings() {
        let (cpu, _) = splat::forward::<T>(&cfg, &maps(), 7).unwrap();
        let (gpu, _) = splat::forward::<T>(&on(&cfg, SplatDevice::Cuda), &maps(), 7).unwrap();
        let (d, m) = max_abs(&gpu, &cpu);
        eprintln!(
            "{} {:?} s={} n={}: max |gpu − cpu| = {d:.3e}, max |cpu| = {m:.3}",
            std::any::type_name::<T>(),
            cfg.blend,
            cfg.supersample,
            cfg.game.trajectories * 100
        );
        assert!(m > 0.05, "the render must not be empty");
        assert!(d <= tol * m, "max |gpu − cpu| = {d:e} against {m}");
    }
}

#[test]
fn gpu_forward_matches_the_cpu_kernel_f32() {
    forward_matches::<f32>(1e-4);
}

#[test]
fn gpu_forward_matches_the_cpu_kernel_f64() {
    forward_matches::<f64>(1e-8);
}

fn gradient_matches<T: SplatReal>(tol: f64) {
    for cfg in settings() {
        let w: Vec<T> = weights(cfg.width * cfg.height)
            .into_iter()
            .map(|x| T::from(x).unwrap())
            .collect();
        let (_, tc) = splat::forward::<T>(&cfg, &maps(), 7).unwrap();
        let gc = splat::backward(&cfg, &maps(), &tc, &w).unwrap();
        let gpu_cfg = on(&cfg, SplatDevice::Cuda);
        let (_, tg) = splat::forward::<T>(&gpu_cfg, &maps(), 7).unwrap();
        let gg = splat::backward(&gpu_cfg, &maps(), &tg, &w).unwrap();
        let num: f64 = gc.iter().zip(&gg).map(|(a, b)| (a - b).powi(2)).sum();
        let den: f64 = gc.iter().map(|a| a * a).sum();
        let rel = (num / den).sqrt();
        eprintln!(
            "{} {:?} s={}: |∇gpu − ∇cpu| / |∇cpu| = {rel:.3e}",
            std::any::type_name::<T>(),
            cfg.blend,
            cfg.supersample
        );
        assert!(
            den > 0.0 && rel <= tol,
            "relative gradient difference {rel:e}"
        );
    }
}

#[test]
fn gpu_gradient_matches_the_cpu_gradient_f32() {
    gradient_matches::<f32>(1e-3);
}

#[test]
fn gpu_gradient_matches_the_cpu_gradient_f64() {
    gradient_matches::<f64>(1e-8);
}

/// ∂L/∂θ from the GPU's reverse pass against central differences of the GPU's own forward
/// pass (f64), on the CPU test's problem (24×20, no supersampling, 2k points). The step is
/// 1e-6, ten times the CPU test's: the forward pass sums in fixed point with a quantum of
/// 9e-13, whose rounding a 1e-7 step would amplify to ~2e-4. The loss has kinks (the α_max
/// clamp, where ∂I/∂α jumps by T/(1 − α_max); the footprint's cut-off; the fitted frame's
/// extreme points), so the step and the problem are ones where the CPU's own differences are
/// clean (measured on the CPU at h = 1e-6: 3e-9 relative, coverage; 2e-8, additive; at
/// 48×40 with 2× supersampling the CPU's own differences are off by 8e-4 at this step).
#[test]
fn gpu_gradient_matches_finite_differences() {
    for blend in [Blend::Coverage, Blend::Additive] {
        let cfg = SplatConfig {
            width: 24,
            height: 20,
            ..on(&config(blend, 1, 1.3, 20), SplatDevice::Cuda)
        };
        let maps = maps();
        let w = weights(cfg.width * cfg.height);
        let loss = |m: &[Affine2]| -> f64 {
            let (img, _) = splat::forward::<f64>(&cfg, m, 7).unwrap();
            img.iter().zip(&w).map(|(a, b)| a * b).sum()
        };
        let (_, tape) = splat::forward::<f64>(&cfg, &maps, 7).unwrap();
        let grad = splat::backward(&cfg, &maps, &tape, &w).unwrap();
        let (mut worst, mut scale) = (0.0f64, 0.0f64);
        for i in 0..maps.len() {
            for k in 0..6 {
                let h = 1e-6;
                let bump = |d: f64| {
                    let mut m = maps.clone();
                    let mut c = m[i].coefficients();
                    c[k] += d;
                    m[i] = Affine2::from_coefficients(&c);
                    m
                };
                let fd = (loss(&bump(h)) - loss(&bump(-h))) / (2.0 * h);
                let an = grad[i * 6 + k];
                worst = worst.max((fd - an).abs());
                scale = scale.max(fd.abs());
                assert!(
                    (fd - an).abs() <= 2e-4 * (1.0 + fd.abs()),
                    "{blend:?} map {i} coef {k}: analytic {an} vs finite difference {fd}"
                );
            }
        }
        assert!(scale > 1e-3, "gradients should not all vanish");
        eprintln!("{blend:?}: max |analytic − fd| = {worst:.2e} (max |fd| = {scale:.2e})");
    }
}

/// Integer atomics and fixed reductions: two runs are bit-identical.
#[test]
fn gpu_results_are_bit_identical_between_runs() {
    for cfg in settings() {
        let cfg = on(&cfg, SplatDevice::Cuda);
        let w: Vec<f32> = weights(cfg.width * cfg.height)
            .into_iter()
            .map(|x| x as f32)
            .collect();
        let run = || {
            let (img, tape) = splat::forward::<f32>(&cfg, &maps(), 3).unwrap();
            (img, splat::backward(&cfg, &maps(), &tape, &w).unwrap())
        };
        let (a, b) = (run(), run());
        assert_eq!(a.0, b.0, "{:?} image", cfg.blend);
        assert_eq!(a.1, b.1, "{:?} gradient", cfg.blend);
    }
}

/// The candle op runs the GPU splat when its config says so, with the same image and
/// gradient as the direct calls.
#[test]
fn the_candle_op_runs_on_the_gpu() {
    let cfg = on(&config(Blend::Coverage, 2, 1.3, 200), SplatDevice::Cuda);
    let dev = Device::Cpu;
    // The op reads f32 maps: round them the same way for the direct calls.
    let maps = maps_from_tensor(&maps_to_tensor(&maps(), DType::F32, &dev).unwrap()).unwrap();
    let (img, tape) = splat::forward::<f32>(&cfg, &maps, 5).unwrap();
    let w: Vec<f32> = weights(cfg.width * cfg.height)
        .into_iter()
        .map(|x| x as f32)
        .collect();
    let direct = splat::backward(&cfg, &maps, &tape, &w).unwrap();
    let var = Var::from_tensor(&maps_to_tensor(&maps, DType::F32, &dev).unwrap()).unwrap();
    let out = var
        .as_tensor()
        .apply_op1(SplatOp::new(cfg.clone(), 5))
        .unwrap();
    let got: Vec<f32> = out.flatten_all().unwrap().to_vec1().unwrap();
    assert_eq!(got, img);
    let wt = candle_core::Tensor::from_vec(w, (cfg.height, cfg.width), &dev).unwrap();
    let grads = (out * wt).unwrap().sum_all().unwrap().backward().unwrap();
    let g = maps_from_tensor(grads.get(var.as_tensor()).unwrap()).unwrap();
    for (i, m) in g.iter().enumerate() {
        for (k, v) in m.coefficients().iter().enumerate() {
            let d = direct[i * 6 + k];
            assert!(
                (v - d).abs() <= 1e-5 * (1.0 + d.abs()),
                "map {i} coef {k}: {v} vs {d}"
            );
        }
    }
}

/// The paper's setting (1024², 5×, σ 2.5, 480 k points) once, CPU against GPU: the image and
/// the gradient agree, and the timings of one forward + backward are printed.
#[test]
fn the_paper_setting_agrees_with_the_cpu() {
    let cfg = SplatConfig {
        width: 1024,
        height: 1024,
        supersample: 5,
        sigma: 2.5,
        ..SplatConfig::default()
    };
    let maps = maps();
    let w: Vec<f32> = weights(cfg.width * cfg.height)
        .into_iter()
        .map(|x| x as f32 * 1e-3)
        .collect();
    let time = |c: &SplatConfig| {
        let t0 = std::time::Instant::now();
        let (img, tape) = splat::forward::<f32>(c, &maps, 11).unwrap();
        let g = splat::backward(c, &maps, &tape, &w).unwrap();
        (img, g, t0.elapsed().as_secs_f64())
    };
    let gpu_cfg = on(&cfg, SplatDevice::Cuda);
    let _warm = time(&gpu_cfg);
    let (ic, gc, tc) = time(&cfg);
    let (ig, gg, tg) = time(&gpu_cfg);
    let (d, m) = max_abs(&ig, &ic);
    let num: f64 = gc.iter().zip(&gg).map(|(a, b)| (a - b).powi(2)).sum();
    let den: f64 = gc.iter().map(|a| a * a).sum();
    eprintln!(
        "paper setting: max |gpu − cpu| = {d:.3e} (max {m:.3}); gradient rel. diff {:.3e}; \
         forward+backward CPU {:.1} ms, GPU {:.1} ms",
        (num / den).sqrt(),
        tc * 1e3,
        tg * 1e3
    );
    assert!(d <= 1e-4 * m);
    assert!((num / den).sqrt() <= 1e-3);
    // Where the GPU's time goes: each stage's GPU time (CUDA events), the points of one call.
    let (_, tape) = splat::forward::<f32>(&cfg, &maps, 11).unwrap();
    let uv = match &tape.splat {
        splat::SplatStateOn::Cpu(state) => state.uv().to_vec(),
        _ => unreachable!("a CPU tape"),
    };
    for (stage, ms) in splat::cuda::profile(&cfg.grid(), &uv, &w).unwrap() {
        eprintln!("  {stage:>32}: {ms:8.3} ms");
    }
}

/// Calls from several threads at once (annealing candidates, a sweep's workers) share the
/// GPU: each gets what it would get alone, and tapes dropped on other threads free cleanly.
#[test]
fn concurrent_calls_from_many_threads_agree_with_sequential_ones() {
    let cfg = on(&config(Blend::Coverage, 3, 2.5, 200), SplatDevice::Cuda);
    let w: Vec<f32> = weights(cfg.width * cfg.height)
        .into_iter()
        .map(|x| x as f32)
        .collect();
    let run = |seed: u64| {
        let (img, tape) = splat::forward::<f32>(&cfg, &maps(), seed).unwrap();
        (
            img,
            splat::backward(&cfg, &maps(), &tape, &w).unwrap(),
            tape,
        )
    };
    let alone: Vec<_> = (0..8).map(run).collect();
    let together: Vec<_> = std::thread::scope(|sc| {
        let hs: Vec<_> = (0..8).map(|s| sc.spawn(move || run(s))).collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (a, b) in alone.iter().zip(&together) {
        assert_eq!(a.0, b.0);
        assert_eq!(a.1, b.1);
    }
    // Drop the second batch's tapes on another thread, then use the GPU again here.
    std::thread::spawn(move || drop(together)).join().unwrap();
    let again = run(0);
    assert_eq!(again.0, alone[0].0);
}

// ---- The loss on the GPU and the fused iteration -------------------------------------------

#[test]
fn nvrtc_compiles_the_loss_kernels() {
    for arch in ["compute_75", "compute_90"] {
        let n = ifslab::loss::cuda::compile_only(arch).unwrap();
        assert!(n > 1000, "{arch}: PTX of {n} bytes");
    }
}

/// A reproducible image in [0, 1]; `sparse` leaves 70 % of the pixels at 0 (a fractal on
/// black), otherwise every pixel is uniform in [0, 1).
fn image<T: Real>(n: usize, salt: u64, sparse: bool) -> Vec<T> {
    let mut s = salt.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let u = (s >> 40) as f64 / (1u64 << 24) as f64;
            T::from(if sparse && u < 0.7 { 0.0 } else { u }).unwrap()
        })
        .collect()
}

/// Sizes with sides that are not multiples of the pooling factor (odd, prime, 1 pixel wide)
/// or smaller than the SSIM window, and the paper's 1024².
const LOSS_SIZES: [(usize, usize); 7] = [
    (1024, 1024),
    (37, 23),
    (129, 70),
    (300, 257),
    (5, 3),
    (1, 9),
    (250, 1),
];

/// The CPU's weighted loss and gradient: `wm·MS-MSE + ws·D-SSIM`.
fn cpu_loss<T: Real>(
    loss: &GpuLoss,
    p: &[T],
    t: &[T],
    w: usize,
    h: usize,
) -> (Option<f64>, Option<f64>, Vec<T>) {
    let mut g = vec![T::zero(); w * h];
    let (mut vm, mut vs) = (None, None);
    if loss.msmse_weight > 0.0 {
        let (v, gm) = loss.msmse.value_and_grad(p, t, w, h).unwrap();
        let wt = T::from(loss.msmse_weight).unwrap();
        g.iter_mut().zip(&gm).for_each(|(a, b)| *a = wt * *b);
        vm = Some(v.to_f64().unwrap());
    }
    if loss.dssim_weight > 0.0 {
        let (v, gs) = loss.dssim.value_and_grad(p, t, w, h).unwrap();
        let wt = T::from(loss.dssim_weight).unwrap();
        g.iter_mut().zip(&gs).for_each(|(a, b)| *a = *a + wt * *b);
        vs = Some(v.to_f64().unwrap());
    }
    (vm, vs, g)
}

fn loss_matches<T: Real + SplatReal>(tol: f64) {
    let terms = [(10.0, 1.0), (1.0, 0.0), (0.0, 1.0)];
    for &(w, h) in &LOSS_SIZES {
        let p: Vec<T> = image(w * h, 1 + w as u64, true);
        let t: Vec<T> = image(w * h, 7 + h as u64, false);
        for &(wm, ws) in &terms {
            let loss = GpuLoss {
                msmse: MsMse::default(),
                msmse_weight: wm,
                dssim: DSsim::default(),
                dssim_weight: ws,
            };
            let (v, g) = loss.value_and_grad(&p, &t, w, h).unwrap();
            let (cm, cs, cg) = cpu_loss(&loss, &p, &t, w, h);
            let close = |a: Option<f64>, b: Option<f64>| match (a, b) {
                (Some(a), Some(b)) => (a - b).abs() <= tol * b.abs().max(1e-12),
                (None, None) => true,
                _ => false,
            };
            assert!(
                close(v.msmse, cm) && close(v.dssim, cs),
                "{w}×{h} ({wm}, {ws}): GPU {v:?} against CPU msmse {cm:?} dssim {cs:?}"
            );
            let (d, m) = max_abs(&g, &cg);
            let same = g.iter().zip(&cg).filter(|(a, b)| a == b).count();
            eprintln!(
                "{} {w}×{h} ({wm}, {ws}): values {:?}/{:?} against {cm:?}/{cs:?}; gradient \
                 max |gpu − cpu| = {d:.2e} (max {m:.2e}), {same}/{} pixels identical",
                std::any::type_name::<T>(),
                v.msmse,
                v.dssim,
                w * h
            );
            assert!(
                d <= tol * m,
                "{w}×{h}: gradient differs by {d:e} against {m:e}"
            );
        }
    }
}

/// The GPU loss against the CPU loss (src/loss): the same values and the same image
/// gradient, for each term alone and for the paper's weighting.
#[test]
fn gpu_loss_matches_the_cpu_loss_f32() {
    loss_matches::<f32>(1e-5);
}

#[test]
fn gpu_loss_matches_the_cpu_loss_f64() {
    loss_matches::<f64>(1e-12);
}

/// Fixed-order reductions: two evaluations give the same bits.
#[test]
fn gpu_loss_is_bit_identical_between_runs() {
    let loss = GpuLoss {
        msmse: MsMse::default(),
        msmse_weight: 10.0,
        dssim: DSsim::default(),
        dssim_weight: 1.0,
    };
    for &(w, h) in &[(1024, 1024), (129, 70)] {
        let p: Vec<f32> = image(w * h, 3, true);
        let t: Vec<f32> = image(w * h, 4, true);
        let a = loss.value_and_grad(&p, &t, w, h).unwrap();
        let b = loss.value_and_grad(&p, &t, w, h).unwrap();
        assert_eq!(a.0, b.0);
        assert_eq!(a.1, b.1);
    }
}

/// An objective without LPIPS against the render of `maps()` with other trajectories.
fn objective_for(cfg: &SplatConfig) -> Objective {
    let cpu = on(cfg, SplatDevice::Cpu);
    let (target, _) = splat::forward::<f32>(&cpu, &maps(), 99).unwrap();
    let t = candle_core::Tensor::from_vec(target, (cfg.height, cfg.width), &Device::Cpu).unwrap();
    let loss = LossConfig {
        lpips_weight: 0.0,
        ..LossConfig::default()
    };
    Objective::new(loss, &t).unwrap()
}

/// Maps a little off the target's, so the loss and its gradient are not small.
fn moved_maps() -> Vec<Affine2> {
    maps()
        .iter()
        .map(|m| Affine2 {
            m: m.m * 0.97,
            b: m.b * 0.9,
        })
        .collect()
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

fn breakdown_close(a: &LossBreakdown, b: &LossBreakdown, tol: f64) -> bool {
    let c = |x: Option<f64>, y: Option<f64>| match (x, y) {
        (Some(x), Some(y)) => (x - y).abs() <= tol * y.abs().max(1e-12),
        (None, None) => true,
        _ => false,
    };
    c(a.msmse, b.msmse)
        && c(a.dssim, b.dssim)
        && c(a.regulariser, b.regulariser)
        && c(Some(a.total), Some(b.total))
}

/// One iteration fused on the GPU (image, loss and gradient never leave it) against the
/// candle route: with the same GPU splat the image gradient is the same, so the θ gradient
/// agrees to the loss values' summation order; against the CPU splat, to the kernels'
/// rounding (as the splat's own gradient test). Reruns are bit-identical.
#[test]
fn the_fused_iteration_matches_the_candle_route() {
    for cfg in settings() {
        let gpu_cfg = on(&cfg, SplatDevice::Cuda);
        let objective = objective_for(&cfg);
        let maps = moved_maps();
        assert_eq!(splat::gpu_route(&gpu_cfg, &objective, false), Ok(()));
        let (bf, gf) =
            splat::objective_and_grad(&gpu_cfg, &maps, None, false, 5, &objective).unwrap();
        let (bg, gg) =
            splat::objective_and_grad_candle(&gpu_cfg, &maps, None, false, 5, &objective).unwrap();
        let (bc, gc) =
            splat::objective_and_grad_candle(&cfg, &maps, None, false, 5, &objective).unwrap();
        let (r_gpu, r_cpu) = (rel_diff(&gf, &gg), rel_diff(&gf, &gc));
        eprintln!(
            "{:?} s={} n={}: fused {:.6} | candle, GPU splat {:.6} | candle, CPU splat {:.6}; \
             |∇fused − ∇candle| / |∇candle| = {r_gpu:.2e} (GPU splat), {r_cpu:.2e} (CPU splat); \
             θ gradient identical to the GPU-splat candle route: {}",
            cfg.blend,
            cfg.supersample,
            cfg.game.trajectories * 100,
            bf.total,
            bg.total,
            bc.total,
            gf == gg
        );
        assert!(breakdown_close(&bf, &bg, 1e-5), "{bf:?} against {bg:?}");
        assert!(breakdown_close(&bf, &bc, 1e-3), "{bf:?} against {bc:?}");
        assert!(
            r_gpu <= 1e-5,
            "fused against candle with the GPU splat: {r_gpu:e}"
        );
        assert!(
            r_cpu <= 1e-3,
            "fused against candle with the CPU splat: {r_cpu:e}"
        );
        let (bf2, gf2) =
            splat::objective_and_grad(&gpu_cfg, &maps, None, false, 5, &objective).unwrap();
        assert_eq!((bf, gf), (bf2, gf2), "a rerun differs");
        // The annealing candidate's score: the render's MS-MSE, only the scalar comes back.
        let score = splat::render_msmse(&gpu_cfg, &maps, None, false, 8, &objective)
            .unwrap()
            .expect("the GPU route applies");
        let (img, _) = splat::forward::<f32>(&gpu_cfg, &maps, 8).unwrap();
        let target: Vec<f32> = objective.target().flatten_all().unwrap().to_vec1().unwrap();
        let want = MsMse::default()
            .value(&img, &target, cfg.width, cfg.height)
            .unwrap() as f64;
        assert!(
            (score - want).abs() <= 1e-6 * want,
            "render_msmse {score} against {want}"
        );
    }
}

/// Fused iterations from several threads at once get what they get alone.
#[test]
fn concurrent_fused_iterations_agree_with_sequential_ones() {
    let cfg = on(&config(Blend::Coverage, 3, 2.5, 200), SplatDevice::Cuda);
    let objective = objective_for(&cfg);
    let maps = moved_maps();
    let run =
        |seed: u64| splat::objective_and_grad(&cfg, &maps, None, false, seed, &objective).unwrap();
    let alone: Vec<_> = (0..6).map(run).collect();
    let together: Vec<_> = std::thread::scope(|sc| {
        let hs: Vec<_> = (0..6).map(|s| sc.spawn(move || run(s))).collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(alone, together);
}

/// The paper's setting (1024², 5×, σ 2.5, 480 k points, MS-MSE ×10 + D-SSIM): the fused
/// iteration against the candle route with the CPU splat, the time of each route once warm,
/// and where the fused iteration's GPU time goes.
#[test]
fn the_fused_iteration_at_the_paper_setting() {
    let cfg = SplatConfig {
        width: 1024,
        height: 1024,
        supersample: 5,
        sigma: 2.5,
        ..SplatConfig::default()
    };
    let gpu_cfg = on(&cfg, SplatDevice::Cuda);
    let objective = objective_for(&cfg);
    let maps = moved_maps();
    let time = |c: &SplatConfig, candle: bool| {
        let f = if candle {
            splat::objective_and_grad_candle::<Affine2>
        } else {
            splat::objective_and_grad::<Affine2>
        };
        let _warm = f(c, &maps, None, false, 11, &objective).unwrap();
        let t0 = std::time::Instant::now();
        let r = f(c, &maps, None, false, 11, &objective).unwrap();
        (r, t0.elapsed().as_secs_f64() * 1e3)
    };
    let ((bf, gf), tf) = time(&gpu_cfg, false);
    let ((bg, gg), tg) = time(&gpu_cfg, true);
    let ((bc, gc), tc) = time(&cfg, true);
    eprintln!(
        "paper setting: loss fused {:.6} / candle+GPU splat {:.6} / candle+CPU splat {:.6}; \
         θ gradient rel. diff {:.2e} (GPU splat), {:.2e} (CPU splat); one iteration: fused \
         {tf:.1} ms, candle + GPU splat {tg:.1} ms, candle + CPU splat {tc:.1} ms",
        bf.total,
        bg.total,
        bc.total,
        rel_diff(&gf, &gg),
        rel_diff(&gf, &gc)
    );
    assert!(breakdown_close(&bf, &bg, 1e-5));
    assert!(breakdown_close(&bf, &bc, 1e-3));
    assert!(rel_diff(&gf, &gg) <= 1e-5);
    assert!(rel_diff(&gf, &gc) <= 1e-3);
    for (stage, ms) in splat::iteration::profile_fused(&gpu_cfg, &maps, 11, &objective).unwrap() {
        eprintln!("  {stage:>42}: {ms:8.3} ms");
    }
}
