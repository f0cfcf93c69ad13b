//! End-to-end image inversion: the strategies must actually recover fractals from renders.

use ifslab::loss::LossConfig;
use ifslab::metrics::paper_metrics;
use ifslab::model::ParamKind;
use ifslab::model::library;
use ifslab::render::{RenderConfig, render};
use ifslab_strategies::adam::AdamConfig;
use ifslab_strategies::image::config::GeneratorConfig;
use ifslab_strategies::image::config::{ModelConfig, RendererConfig, TargetConfig};
use ifslab_strategies::image::{InversionConfig, StrategyConfig, run_inversion};

fn target(code: &str, size: usize) -> Vec<f32> {
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
    .values
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
        seed: 1,
        iterations,
        checkpoint_every: 0,
        output: None,
        target: TargetConfig {
            image: None,
            code: Some("sierpinski".into()),
            size,
            polarity: Default::default(),
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
        StrategyConfig::Adam(AdamConfig {
            lr: 5e-3,
            ..AdamConfig::default()
        }),
    );
    cfg.model = ModelConfig {
        maps: 3,
        parameterisation: ParamKind::Naive,
        init_code: Some("sierpinski".into()),
        init_noise: 0.05,
        ..ModelConfig::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let start = ifslab_strategies::image::initial_theta(
        &cfg,
        cfg.model.parameterisation.build().as_ref(),
        &t,
    )
    .unwrap();
    let start_maps = cfg.model.parameterisation.build().decode(&start).unwrap();
    let before = iou_of(&start_maps, &t, size);
    let out = run_inversion(&cfg, t.clone(), dir.path(), false, vec![]).unwrap();
    let after = iou_of(&out.maps, &t, size);
    eprintln!("IoU before {before:.3}, after {after:.3}");
    assert!(
        after > 0.8 && after > before + 0.1,
        "IoU before {before:.3}, after {after:.3}"
    );
}
