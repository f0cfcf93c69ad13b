//! End-to-end image inversion: the strategies must actually recover fractals from renders.

use ifslab::image::Image;
use ifslab::loss::LossConfig;
use ifslab::metrics::paper_metrics;
use ifslab::model::ParamKind;
use ifslab::model::library;
use ifslab::render::{RenderConfig, render};
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image::config::GeneratorConfig;
use ifslab_strategies::problems::image::config::{ModelConfig, RendererConfig, TargetConfig};
use ifslab_strategies::problems::image::{InversionConfig, StrategyConfig, run_inversion};

fn target(code: &str, size: usize) -> Image {
    let c = library::builtin(code).unwrap();
    let cfg = RenderConfig {
        width: size as u32,
        height: size as u32,
        points: 1_000_000,
        supersample: 4,
        ..RenderConfig::default()
    };
    render(
        &c.affine2().unwrap(),
        &c.evaluation_probabilities().unwrap(),
        &cfg,
        None,
    )
    .unwrap()
    .image
}

fn iou_of(maps: &[ifslab::model::Affine2], t: &[f32], size: usize) -> f64 {
    let code = ifslab::model::IfsCode::from_affine2(None, maps).unwrap();
    let cfg = RenderConfig {
        width: size as u32,
        height: size as u32,
        points: 1_000_000,
        supersample: 4,
        ..RenderConfig::default()
    };
    let r = render(maps, &code.evaluation_probabilities().unwrap(), &cfg, None).unwrap();
    paper_metrics::<f32>(&r.values, t, size, size, None)
        .unwrap()
        .iou
}

fn base_config(size: usize, iterations: u64, strategy: StrategyConfig) -> InversionConfig {
    InversionConfig {
        paper: true,
        seed: 1,
        iterations,
        best_of: 1,
        best_of_starts: Default::default(),
        checkpoint_every: 0,
        output: None,
        target: TargetConfig {
            image: None,
            code: Some("sierpinski".into()),
            suite: None,
            index: None,
            truth: None,
            size,
            polarity: Default::default(),
            cells: None,
        },
        model: ModelConfig::default(),
        generator: GeneratorConfig {
            trajectories: 500,
            length: 110,
            warmup: 10,
            start_half_width: 2.0,
        },
        renderer: RendererConfig::default(),
        loss: LossConfig {
            lpips_weight: 0.0,
            ..LossConfig::default()
        },
        strategy,
    }
}

#[test]
fn adam_on_the_naive_parameterisation_recovers_a_perturbed_code() {
    let size = 64;
    let t = target("sierpinski", size);
    let mut cfg = base_config(
        size,
        150,
        StrategyConfig::from(AdamConfig {
            lr: 5e-3,
            ..AdamConfig::default()
        }),
    );
    cfg.model = ModelConfig {
        maps: 3,
        parameterisation: ParamKind::Naive,
        init_code: Some("sierpinski".into()),
        init_noise: 0.03,
        ..ModelConfig::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let model = cfg.model.build().unwrap();
    let start =
        ifslab_strategies::problems::image::initial_theta(&cfg, model.as_ref(), &t.values).unwrap();
    let start_maps = model.affine_maps(&start).unwrap();
    let before = iou_of(&start_maps, &t.values, size);
    let out = run_inversion(&cfg, t.clone(), dir.path(), false, vec![]).unwrap();
    let after = iou_of(out.result.affine().unwrap(), &t.values, size);
    eprintln!("IoU before {before:.3}, after {after:.3}");
    assert!(
        after > 0.8 && after > before + 0.1,
        "IoU before {before:.3}, after {after:.3}"
    );
}

/// The similitude family (θ = s, φ, t per map) through the same problem, strategy and run:
/// from a perturbed Sierpiński code it must come back to the triangle (coarse-to-fine σ, as
/// the demo runs; at a fixed σ = 1 the blur's bias leaves IoU ≈ 0.85).
#[test]
fn adam_on_similitudes_recovers_a_perturbed_code() {
    let size = 64;
    let t = target("sierpinski", size);
    for seed in [1, 7] {
        let mut cfg = base_config(
            size,
            150,
            StrategyConfig::from(AdamConfig {
                lr: 5e-3,
                ..AdamConfig::default()
            }),
        );
        cfg.seed = seed;
        cfg.renderer.sigma_final = Some(0.4);
        cfg.model = ModelConfig {
            family: "similitude".into(),
            maps: 3,
            init_code: Some("sierpinski".into()),
            init_noise: 0.03,
            ..ModelConfig::default()
        };
        let model = cfg.model.build().unwrap();
        let start =
            ifslab_strategies::problems::image::initial_theta(&cfg, model.as_ref(), &t.values)
                .unwrap();
        assert_eq!(start.len(), 12, "4 parameters per similitude");
        let before = iou_of(&model.affine_maps(&start).unwrap(), &t.values, size);
        let dir = tempfile::tempdir().unwrap();
        let out = run_inversion(&cfg, t.clone(), dir.path(), false, vec![]).unwrap();
        let after = iou_of(out.result.affine().unwrap(), &t.values, size);
        eprintln!("seed {seed}: IoU before {before:.3}, after {after:.3}");
        assert!(
            after > 0.9 && after > before + 0.1,
            "seed {seed}: IoU before {before:.3}, after {after:.3}"
        );
        for m in out.result.affine().unwrap() {
            let (c0, c1) = (m.m.column(0), m.m.column(1));
            assert!(
                (c0.norm() - c1.norm()).abs() < 1e-9 && c0.dot(&c1).abs() < 1e-9,
                "a similitude stays one: {m:?}"
            );
        }
    }
}

/// IoU of the EM start and of the hybrid run from it (cold annealing phases every 50
/// iterations, coarse-to-fine σ 1 → 0.4), for `maps` maps against `code`'s 64² render.
fn em_then_hybrid(code: &str, maps: usize, seed: u64, iterations: u64) -> (f64, f64) {
    em_then_hybrid_on(code, maps, seed, iterations, Default::default())
}

/// [`em_then_hybrid`] with the splat on `device`.
fn em_then_hybrid_on(
    code: &str,
    maps: usize,
    seed: u64,
    iterations: u64,
    device: ifslab::render::splat::SplatDevice,
) -> (f64, f64) {
    use ifslab_strategies::optim::hybrid::HybridConfig;
    use ifslab_strategies::problems::image::InitKind;
    let size = 64;
    let t = target(code, size);
    let mut cfg = base_config(
        size,
        iterations,
        StrategyConfig::from(HybridConfig {
            anneal_every: 50,
            ..HybridConfig::from_good_start()
        }),
    );
    cfg.seed = seed;
    cfg.target.code = Some(code.into());
    cfg.model.maps = maps;
    cfg.model.init = InitKind::Em;
    cfg.renderer.sigma_final = Some(0.4);
    cfg.renderer.device = device;
    let model = cfg.model.build().unwrap();
    let start =
        ifslab_strategies::problems::image::initial_theta(&cfg, model.as_ref(), &t.values).unwrap();
    let em_only = iou_of(&model.affine_maps(&start).unwrap(), &t.values, size);
    let dir = tempfile::tempdir().unwrap();
    let out = run_inversion(&cfg, t.clone(), dir.path(), false, vec![]).unwrap();
    let iou = iou_of(out.result.affine().unwrap(), &t.values, size);
    eprintln!("{code}, seed {seed}: IoU of the EM start {em_only:.3}, after the hybrid {iou:.3}");
    (em_only, iou)
}

/// The hybrid recovers the Sierpiński triangle from its 64² render in 300 iterations for
/// every seed tried (a perfect recovery scores IoU ≈ 1 on these masks; a wrong attractor
/// framed the same way scores 0.1–0.35), never worse than the EM fit it starts from.
#[test]
fn hybrid_recovers_the_sierpinski_triangle_across_seeds() {
    for seed in [0, 1, 2] {
        let (em_only, iou) = em_then_hybrid("sierpinski", 3, seed, 300);
        assert!(
            iou > 0.95 && iou >= em_only,
            "seed {seed}: IoU {iou:.3} from an EM start at {em_only:.3}"
        );
    }
}

/// The same recovery with the splat on the GPU (run by `scripts/gpu/run.sh`): every seed
/// recovers the triangle as on the CPU, and the final IoU is the CPU run's to within 0.02 (the
/// GPU's sums round differently, so the runs drift apart slowly).
#[cfg(feature = "cuda")]
#[test]
fn hybrid_recovers_the_sierpinski_triangle_on_the_gpu() {
    use ifslab::render::splat::SplatDevice;
    for seed in [0, 1, 2] {
        let t0 = std::time::Instant::now();
        let (em_only, gpu) = em_then_hybrid_on("sierpinski", 3, seed, 300, SplatDevice::Cuda);
        let t_gpu = t0.elapsed().as_secs_f64();
        let t0 = std::time::Instant::now();
        let (_, cpu) = em_then_hybrid_on("sierpinski", 3, seed, 300, SplatDevice::Cpu);
        let t_cpu = t0.elapsed().as_secs_f64();
        eprintln!(
            "seed {seed}: EM start {em_only:.3}, GPU {gpu:.3} ({t_gpu:.1} s), CPU {cpu:.3} \
             ({t_cpu:.1} s)"
        );
        assert!(
            gpu > 0.95 && gpu >= em_only && (gpu - cpu).abs() < 0.02,
            "seed {seed}: GPU IoU {gpu:.3}, CPU {cpu:.3}, EM start {em_only:.3}"
        );
    }
}

/// The fern's maps are not similitudes, so the EM start (similitudes) cannot draw it
/// exactly: the gradient part must do real work. It beats the EM-only baseline clearly
/// (measured: 0.80 → 0.86).
#[test]
fn hybrid_beats_its_em_start_on_the_fern() {
    let (em_only, iou) = em_then_hybrid("fern", 4, 0, 300);
    assert!(
        iou > em_only + 0.03 && iou > 0.83,
        "IoU {iou:.3} from an EM start at {em_only:.3}"
    );
}

/// A run stopped after a checkpoint and resumed ends with bit-identical parameters to a run
/// that was never stopped, for every strategy (their solver state, Adam moments and
/// annealing schedules, all go through the checkpoint).
#[test]
fn resume_is_bit_identical() {
    use argmin::core::observers::Observe;
    use argmin::core::{Error as ArgminError, KV, State};
    use ifslab_strategies::driver::GradState;
    use ifslab_strategies::optim::hybrid::{ColdHybridConfig, HybridConfig};

    /// Fails the run at a given iteration, like a crash.
    struct Crash(u64);
    impl Observe<GradState> for Crash {
        fn observe_iter(&mut self, state: &GradState, _kv: &KV) -> Result<(), ArgminError> {
            if state.get_iter() == self.0 {
                return Err(ArgminError::msg("simulated crash"));
            }
            Ok(())
        }
    }

    let size = 32;
    let t = target("sierpinski", size);
    // Every registered strategy (a new one is covered as soon as it is registered); the
    // hybrids anneal within these 20 iterations.
    let strategies = ifslab_strategies::registry::kinds().into_iter().map(|k| {
        let mut s = StrategyConfig::by_name(k).unwrap();
        let quick = |h: &mut HybridConfig| {
            h.anneal_every = 4;
            h.annealing.candidates = 2;
        };
        if !s.update(quick) {
            s.update(|c: &mut ColdHybridConfig| quick(&mut c.0));
        }
        s
    });
    for strategy in strategies {
        let mut cfg = base_config(size, 20, strategy);
        cfg.generator.trajectories = 100;
        cfg.checkpoint_every = 5;
        let name = cfg.strategy.name();
        let whole = tempfile::tempdir().unwrap();
        let full = run_inversion(&cfg, t.clone(), whole.path(), false, vec![]).unwrap();

        let split = tempfile::tempdir().unwrap();
        let crashed = run_inversion(
            &cfg,
            t.clone(),
            split.path(),
            false,
            vec![Box::new(Crash(12))],
        );
        assert!(
            crashed.is_err(),
            "{name}: the simulated crash must stop the run"
        );
        // A fresh run into a folder with a checkpoint is refused, nothing is overwritten.
        assert!(run_inversion(&cfg, t.clone(), split.path(), false, vec![]).is_err());
        let resumed = run_inversion(&cfg, t.clone(), split.path(), true, vec![]).unwrap();
        assert_eq!(resumed.iterations, 20, "{name}");
        assert_eq!(
            resumed.theta, full.theta,
            "{name}: resumed θ differs from the uninterrupted run"
        );
        // The log has one row per iteration, none duplicated by the replay after the crash.
        let log = std::fs::read_to_string(split.path().join("log.csv")).unwrap();
        let iters: Vec<u64> = log
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap().parse().unwrap())
            .collect();
        assert_eq!(iters, (0..20).collect::<Vec<u64>>(), "{name}");
        // The strategy's own statistics are columns of the log, filled where it reports them.
        let header: Vec<&str> = log.lines().next().unwrap().split(',').collect();
        for stat in ifslab_strategies::registry::stats(name).unwrap() {
            let col = header
                .iter()
                .position(|h| h == stat)
                .unwrap_or_else(|| panic!("{name}: no `{stat}` column in {header:?}"));
            let reported = log
                .lines()
                .skip(1)
                .filter(|l| l.split(',').nth(col).unwrap() != "NaN")
                .count();
            assert!(reported > 0, "{name}: `{stat}` never logged");
        }
    }
}

/// The brief's determinism rule, end to end: the same seed gives the same θ whatever the
/// thread count — chaos game, splat, every loss term (LPIPS too when its weights are
/// present) and the annealing draws.
#[test]
fn same_seed_same_code_with_any_thread_count() {
    use ifslab_strategies::optim::annealing::AnnealingConfig;
    use ifslab_strategies::optim::hybrid::HybridConfig;

    let size = 48;
    let t = target("sierpinski", size);
    let mut cfg = base_config(
        size,
        12,
        StrategyConfig::from(HybridConfig {
            anneal_every: 4,
            annealing: AnnealingConfig {
                candidates: 3,
                ..AnnealingConfig::default()
            },
            ..HybridConfig::default()
        }),
    );
    cfg.generator.trajectories = 300;
    let lpips = ifslab::loss::default_lpips_weights_path().is_file();
    if lpips {
        cfg.loss.lpips_weight = 2.0;
    } else {
        eprintln!("LPIPS weights absent: checking the other loss terms only");
    }
    let run = |threads: usize| {
        let dir = tempfile::tempdir().unwrap();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run_inversion(&cfg, t.clone(), dir.path(), false, vec![]).unwrap())
    };
    let one = run(1);
    let three = run(3);
    assert_eq!(one.iterations, 12);
    if lpips {
        assert!(
            one.lpips_note.is_none(),
            "LPIPS is used when its weights are present"
        );
    }
    assert_eq!(one.theta, three.theta, "θ depends on the thread count");
    assert_eq!(one.final_loss.to_bits(), three.final_loss.to_bits());
}

/// `renderer.sigma_final`: gradient steps and annealing costs see σ moved geometrically
/// from `sigma` (t = 0) to `sigma_final` (t = T).
#[test]
fn sigma_schedule_renders_with_the_scheduled_sigma() {
    use ifslab_strategies::driver::Differentiable;
    use ifslab_strategies::optim::annealing::Anneal;
    use ifslab_strategies::problems::image::ImageProblem;

    let size = 32;
    let t = target("sierpinski", size);
    let mut cfg = base_config(size, 10, StrategyConfig::from(AdamConfig::default()));
    cfg.generator.trajectories = 100;
    let maps = library::builtin("sierpinski").unwrap().affine2().unwrap();
    let theta = cfg.model.parameterisation.build().encode(&maps).unwrap();
    let with_sigma = |sigma: f64, end: Option<f64>| {
        let mut c = cfg.clone();
        c.renderer.sigma = sigma;
        c.renderer.sigma_final = end;
        ImageProblem::from_config(&c, t.clone()).unwrap()
    };
    let scheduled = with_sigma(1.0, Some(0.25));
    let (start, middle, end) = (
        with_sigma(1.0, None),
        with_sigma(0.5, None),
        with_sigma(0.25, None),
    );
    let loss = |p: &ImageProblem, iter: u64| p.evaluate(&theta, iter).unwrap().loss;
    assert_eq!(loss(&scheduled, 0), loss(&start, 0));
    assert_eq!(loss(&scheduled, 5), loss(&middle, 5));
    assert_eq!(loss(&scheduled, 10), loss(&end, 10));
    assert_ne!(
        loss(&start, 5),
        loss(&middle, 5),
        "σ must matter to the loss"
    );
    let cost = |p: &ImageProblem, frac: f64| p.anneal_cost(&theta, 7, frac).unwrap();
    assert_eq!(cost(&scheduled, 0.5), cost(&middle, 0.0));
    assert_eq!(cost(&scheduled, 1.0), cost(&end, 0.3));
    // Landscapes and evaluation renders use the σ the run ends with.
    assert_eq!(
        scheduled.loss_breakdown(&theta, 3).unwrap().total,
        end.loss_breakdown(&theta, 3).unwrap().total
    );
}

/// End to end in the precision that runs: θ → SVD parameterisation → f32 fused splat (chaos
/// game, differentiable framing, coverage blending, pooling) → the whole objective (MS-MSE,
/// D-SSIM, LPIPS when its weights exist, regulariser), against central finite differences of
/// the same objective on the same random stream, for each model family (the flame family
/// through its non-linear variations). Each stage is checked alone in f64
/// elsewhere; this catches a wrong composition or an f32 path that drifts.
#[test]
fn end_to_end_gradient_matches_finite_differences_in_f32() {
    for family in ["affine", "similitude", "flame"] {
        eprintln!("model family {family}");
        end_to_end_gradient(family);
    }
}

fn end_to_end_gradient(family: &str) {
    use ifslab_strategies::driver::Differentiable;
    use ifslab_strategies::problems::image::ImageProblem;

    let size = 32;
    let t = target("sierpinski", size);
    let mut cfg = base_config(size, 10, StrategyConfig::from(AdamConfig::default()));
    cfg.generator.trajectories = 200;
    cfg.generator.length = 60;
    cfg.renderer.sigma = 1.5;
    cfg.loss.lpips_weight = if ifslab::loss::default_lpips_weights_path().is_file() {
        2.0
    } else {
        0.0
    };
    cfg.model.family = family.into();
    let problem = ImageProblem::from_config(&cfg, t).unwrap();
    // A Sierpiński code, perturbed so no map sits at a symmetric point.
    let maps = library::builtin("sierpinski").unwrap().affine2().unwrap();
    let mut theta = problem.model().encode(&maps).unwrap();
    for (i, v) in theta.iter_mut().enumerate() {
        *v += 0.05 * ((i * 7 % 11) as f64 / 11.0 - 0.5);
    }
    let stream = 3;
    let eval = problem.evaluate(&theta, stream).unwrap();
    let loss = |th: &[f64]| problem.evaluate(th, stream).unwrap().loss;
    let h = 1e-3;
    let fd: Vec<f64> = (0..theta.len())
        .map(|i| {
            let mut th = theta.clone();
            th[i] += h;
            let up = loss(&th);
            th[i] -= 2.0 * h;
            (up - loss(&th)) / (2.0 * h)
        })
        .collect();
    let dot: f64 = eval.grad.iter().zip(&fd).map(|(a, b)| a * b).sum();
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let cosine = dot / (norm(&eval.grad) * norm(&fd));
    let scale = norm(&fd) / (theta.len() as f64).sqrt();
    for (i, (a, b)) in eval.grad.iter().zip(&fd).enumerate() {
        eprintln!("θ[{i:2}] analytic {a:+.5}  finite difference {b:+.5}");
    }
    eprintln!("cosine {cosine:.5}");
    assert!(cosine > 0.995, "cosine similarity {cosine}");
    for (i, (a, b)) in eval.grad.iter().zip(&fd).enumerate() {
        assert!(
            (a - b).abs() <= 0.1 * b.abs() + 0.05 * scale,
            "θ[{i}]: analytic {a} vs finite difference {b}"
        );
    }
}

/// The value-only baselines on the image problem: from a perturbed Sierpiński code (naive
/// parameterisation, 18 numbers) each must raise the IoU (measured, 40 generations:
/// 0.317 → 0.430 evolutionary (640 renders), 0.536 CMA-ES (520), 0.663 cuckoo (720),
/// 0.593 swarm (640)), scoring codes with the annealing
/// MSE on each generation's stream. Budgets are in renders (the log's `evals`).
#[test]
fn the_value_only_baselines_improve_a_perturbed_code() {
    use ifslab_strategies::optim::cmaes::CmaesConfig;
    use ifslab_strategies::optim::cuckoo::CuckooConfig;
    use ifslab_strategies::optim::evolutionary::EvolutionaryConfig;
    use ifslab_strategies::optim::swarm::SwarmConfig;
    let size = 48;
    let t = target("sierpinski", size);
    let strategies = [
        StrategyConfig::from(EvolutionaryConfig {
            population: 8,
            sigma: 0.02,
            ..EvolutionaryConfig::default()
        }),
        StrategyConfig::from(CmaesConfig {
            sigma: 0.02,
            ..CmaesConfig::default()
        }),
        StrategyConfig::from(CuckooConfig {
            nests: 6,
            sigma: 0.02,
            ..CuckooConfig::default()
        }),
        StrategyConfig::from(SwarmConfig {
            particles: 8,
            sigma: 0.02,
            ..SwarmConfig::default()
        }),
    ];
    for strategy in strategies {
        let name = strategy.name().to_string();
        let mut cfg = base_config(size, 40, strategy);
        cfg.model = ModelConfig {
            maps: 3,
            parameterisation: ParamKind::Naive,
            init_code: Some("sierpinski".into()),
            init_noise: 0.05,
            ..ModelConfig::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let model = cfg.model.build().unwrap();
        let start =
            ifslab_strategies::problems::image::initial_theta(&cfg, model.as_ref(), &t.values)
                .unwrap();
        let before = iou_of(&model.affine_maps(&start).unwrap(), &t.values, size);
        let out = run_inversion(&cfg, t.clone(), dir.path(), false, vec![]).unwrap();
        let after = iou_of(out.result.affine().unwrap(), &t.values, size);
        let log = std::fs::read_to_string(&out.log).unwrap();
        let evals = log.lines().last().unwrap().to_string();
        eprintln!("{name}: IoU before {before:.3}, after {after:.3}; last log line {evals}");
        assert!(
            after > before + 0.08,
            "{name}: IoU before {before:.3}, after {after:.3}"
        );
    }
}

/// A run that wanders off a perfect start (annealing that accepts every proposal) must not
/// return where it wandered to: the returned θ is the best of the last iterate, the recorded
/// best and the start, scored on fixed random streams.
#[test]
fn a_run_that_wanders_off_returns_the_best_code_it_saw() {
    use ifslab_strategies::optim::annealing::AnnealingConfig;
    let size = 48;
    let t = target("sierpinski", size);
    let mut cfg = base_config(
        size,
        12,
        StrategyConfig::from(AnnealingConfig {
            noise: 0.3,
            temperature: 1e12,
            ..AnnealingConfig::default()
        }),
    );
    cfg.model = ModelConfig {
        maps: 3,
        init_code: Some("sierpinski".into()),
        ..ModelConfig::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let out = run_inversion(&cfg, t.clone(), dir.path(), false, vec![]).unwrap();
    let s = &out.selection;
    eprintln!("{s:?}");
    // Here the start itself wins: argmin's recorded best (iteration 0's cost) comes with the
    // θ after that iteration's move, which is already worse.
    assert_eq!(s.returned, "start", "{s:?}");
    assert!(
        s.start.unwrap() < s.best.unwrap() && s.best.unwrap() < s.last,
        "{s:?}"
    );
    let iou = iou_of(out.result.affine().unwrap(), &t.values, size);
    assert!(iou > 0.6, "IoU of the returned code {iou:.3}");
}

/// Learning Fractals' whole recipe (rsr maps ∝ |det|, summed and clamped Gaussians in the
/// fixed window [−5, 5]², MSE, their optimiser) runs as one config and learns: from a random
/// start its MSE falls (by a tenth or more of its own objective, in its own frame, on fixed
/// random streams) and its learning rate ends halved three times. The method is weak — the
/// paper measured IoU 0.08 at 32² — and here too its IoU in the evaluation's fitted frame
/// does not follow its MSE (printed), so the bound is on what it optimises.
#[test]
fn the_learning_fractals_recipe_learns_a_target() {
    let size = 32;
    let t = target("sierpinski", size);
    let mut cfg = base_config(size, 300, StrategyConfig::by_name("adam").unwrap());
    cfg.model = ModelConfig {
        maps: 3,
        init: ifslab_strategies::problems::image::InitKind::Random,
        ..ModelConfig::default()
    };
    let cfg = cfg.with_learning_fractals_recipe();
    assert_eq!(cfg.strategy.name(), "learning_fractals");
    let dir = tempfile::tempdir().unwrap();
    let model = cfg.model.build().unwrap();
    let start =
        ifslab_strategies::problems::image::initial_theta(&cfg, model.as_ref(), &t.values).unwrap();
    assert_eq!(
        start.len(),
        3 * 8,
        "rotation–scale–rotation: 8 numbers a map"
    );
    let out = run_inversion(&cfg, t.clone(), dir.path(), false, vec![]).unwrap();
    let log = std::fs::read_to_string(dir.path().join("log.csv")).unwrap();
    let rows: Vec<Vec<f64>> = log
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    let first: f64 = rows[..10].iter().map(|r| r[1]).sum::<f64>() / 10.0;
    let last: f64 = rows[rows.len() - 10..].iter().map(|r| r[1]).sum::<f64>() / 10.0;
    let (before, after) = (
        iou_of(&model.affine_maps(&start).unwrap(), &t.values, size),
        iou_of(out.result.affine().unwrap(), &t.values, size),
    );
    eprintln!("MSE {first:.4} → {last:.4}, IoU {before:.3} → {after:.3}");
    assert!(last < 0.85 * first, "MSE {first:.4} → {last:.4}");
    let lr = rows.last().unwrap()[7];
    assert!((lr - 0.05 / 8.0).abs() < 1e-12, "final lr {lr}");
    // On fixed random streams, the objective of what it learned against its start.
    let s = &out.selection;
    assert!(s.last < 0.9 * s.start.unwrap(), "{s:?}");
}
