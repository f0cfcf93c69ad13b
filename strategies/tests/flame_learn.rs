//! Learning flames end to end: a target drawn by a known flame stack (its own pipeline) and
//! one drawn by flam3-render from a .flame file (an independent renderer) are both learned
//! from the authors' random start to a much lower MSE; a resumed run is bit-identical; the
//! learned flame loads in flam3-render and draws where ours does; bad input is answered
//! clearly.

use std::path::{Path, PathBuf};
use std::process::Command;

use ifslab::image::Image;
use ifslab::model::flame::VariationKind as V;
use ifslab::model::flame::learnable::{
    Background, FlameStack, Learn, LearnableFlame, LearnableInit,
};
use ifslab::render::flame_diff::{DiffFlameConfig, GeneratorOrder, forward};
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::flame::{
    BackgroundConfig, FlameLearnConfig, LayerSpec, load_rgb_target, run_flame,
};
use ifslab_strategies::problems::image::StrategyConfig;

fn sampler(size: usize) -> DiffFlameConfig {
    DiffFlameConfig {
        size,
        trajectories: 200,
        steps: 300,
        warmup: 20,
        chunks: 4,
    }
}

/// A three-map Sierpiński flame in red, green and blue, as a target image file.
fn sierpinski_target(dir: &Path, size: usize) -> PathBuf {
    let mut layer = LearnableFlame::random(
        &vec![vec![V::Linear]; 3],
        Learn::default(),
        &LearnableInit::default(),
        9,
    )
    .unwrap();
    let t = [[-0.5, -0.45], [0.5, -0.45], [0.0, 0.45]];
    for (g, tr) in layer.generators.iter_mut().zip(t) {
        g.coefs = [0.5, 0.0, 0.0, 0.5, tr[0] * 0.9, tr[1] * 0.9];
    }
    layer.final_coefs = [0.95, 0.0, 0.0, 0.95, 0.0, 0.0];
    layer.color_logits = vec![
        [3.0, -3.0, -3.0, 2.0],
        [-3.0, 3.0, -3.0, 2.0],
        [-3.0, -3.0, 3.0, 2.0],
    ];
    let st = FlameStack {
        layers: vec![layer],
        background: Background::Fixed([1.0; 3]),
    };
    let cfg = DiffFlameConfig {
        trajectories: 2000,
        ..sampler(size)
    };
    let f = forward(&st, &cfg, &GeneratorOrder::draw(&st, &cfg, 1)).unwrap();
    let v: Vec<f32> = f.image.iter().map(|&x| x as f32).collect();
    let path = dir.join("sierpinski.png");
    Image::new(size as u32, size as u32, 3, v)
        .unwrap()
        .save_png(&path)
        .unwrap();
    path
}

fn config(target: &Path, iterations: u64) -> FlameLearnConfig {
    let mut cfg = FlameLearnConfig::paper(target, 6, vec!["linear".into()]);
    cfg.sampler = sampler(32);
    cfg.iterations = iterations;
    cfg.seed = 3;
    cfg.checkpoint_every = 5;
    cfg.strategy = StrategyConfig::new(&AdamConfig {
        lr: 0.02,
        ..AdamConfig::default()
    });
    cfg.rates.color = 10.0;
    cfg.rates.final_transform = 0.5;
    cfg
}

#[test]
fn a_flame_drawn_by_its_own_pipeline_is_learned_from_the_random_start() {
    let dir = tempfile::tempdir().unwrap();
    let target = sierpinski_target(dir.path(), 32);
    let cfg = config(&target, 150);
    let (t, note) = load_rgb_target(&target, 32, [1.0; 3]).unwrap();
    assert!(note.is_none());
    let run = dir.path().join("run");
    let out = run_flame(&cfg, t, &run, false, vec![]).unwrap();
    assert_eq!(out.returned, "last");
    eprintln!("own pipeline: MSE {:.4} → {:.4}", out.start_loss, out.loss);
    assert!(
        out.loss < 0.35 * out.start_loss,
        "MSE {} from {}",
        out.loss,
        out.start_loss
    );
}

/// A picture flam3-render drew (a committed fixture: a random flame of flam3-genome's,
/// sinusoidal and other variations, on black) is learned by a linear flame over a black
/// background to under a fifth of its starting MSE.
#[test]
fn a_picture_flam3_drew_is_learned() {
    let dir = tempfile::tempdir().unwrap();
    let target =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/flame/images/f03.png");
    let mut cfg = config(&target, 150);
    cfg.flames[0].xforms = 8;
    cfg.background = BackgroundConfig::Named("black".into());
    let (t, note) = load_rgb_target(&target, 32, [0.0; 3]).unwrap();
    assert!(note.unwrap().contains("alpha"));
    let out = run_flame(&cfg, t, &dir.path().join("run"), false, vec![]).unwrap();
    eprintln!(
        "flam3's picture: MSE {:.4} → {:.4}",
        out.start_loss, out.loss
    );
    assert!(
        out.loss < 0.2 * out.start_loss,
        "MSE {} from {}",
        out.loss,
        out.start_loss
    );
}

/// Ten iterations, then ten more resumed from the checkpoint, give the bits of twenty in
/// one go.
#[test]
fn a_resumed_flame_fit_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let target = sierpinski_target(dir.path(), 24);
    let mut cfg = config(&target, 20);
    cfg.sampler = DiffFlameConfig {
        trajectories: 40,
        steps: 100,
        ..sampler(24)
    };
    let (t, _) = load_rgb_target(&target, 24, [1.0; 3]).unwrap();
    let a = dir.path().join("a");
    let whole = run_flame(&cfg, t.clone(), &a, false, vec![]).unwrap();
    let b = dir.path().join("b");
    let mut first = cfg.clone();
    first.iterations = 10;
    run_flame(&first, t.clone(), &b, false, vec![]).unwrap();
    let resumed = run_flame(&cfg, t.clone(), &b, true, vec![]).unwrap();
    assert_eq!(resumed.iterations, 20);
    assert!(
        whole
            .theta
            .iter()
            .zip(&resumed.theta)
            .all(|(x, y)| x.to_bits() == y.to_bits())
    );
    // A fresh run into a folder that holds one is refused.
    assert!(run_flame(&cfg, t, &b, false, vec![]).is_err());
}

#[test]
fn bad_input_is_answered_clearly() {
    let dir = tempfile::tempdir().unwrap();
    // Greyscale and RGBA targets load, with a note saying what was done.
    let grey = dir.path().join("grey.png");
    image::GrayImage::from_fn(20, 20, |x, _| image::Luma([(x * 12) as u8]))
        .save(&grey)
        .unwrap();
    let (t, note) = load_rgb_target(&grey, 10, [1.0; 3]).unwrap();
    assert!(note.unwrap().contains("greyscale"));
    assert_eq!((t.channels, t.width, t.height), (3, 10, 10));
    assert_eq!(t.values[0], t.values[100]);
    let rgba = dir.path().join("rgba.png");
    image::RgbaImage::from_fn(20, 20, |_, _| image::Rgba([255, 0, 0, 0]))
        .save(&rgba)
        .unwrap();
    let (t, note) = load_rgb_target(&rgba, 10, [0.0, 0.0, 1.0]).unwrap();
    assert!(note.unwrap().contains("alpha"));
    assert_eq!(
        (t.values[0], t.values[200]),
        (0.0, 1.0),
        "transparent pixels take the background"
    );
    // `auto` fixes the background to the target's border colour (here the blue it was laid
    // over).
    let mut auto = FlameLearnConfig::paper(&rgba, 4, vec!["linear".into()]);
    auto.sampler.size = 10;
    auto.background = BackgroundConfig::Named("auto".into());
    assert_eq!(
        auto.background(&t.values).unwrap(),
        ifslab::model::flame::learnable::Background::Fixed([0.0, 0.0, 1.0])
    );
    // A file that is not an image.
    let junk = dir.path().join("junk.png");
    std::fs::write(&junk, b"not a png").unwrap();
    let e = load_rgb_target(&junk, 10, [1.0; 3])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("junk.png") && e.contains("not a readable image"),
        "{e}"
    );
    // Unknown and random variations are named.
    let mut cfg = FlameLearnConfig::paper(&grey, 4, vec!["sphericall".into()]);
    let e = cfg.validate().unwrap_err().to_string();
    assert!(e.contains("unknown variation `sphericall`"), "{e}");
    cfg.flames = vec![LayerSpec {
        xforms: 4,
        variations: vec!["julia".into()],
        linear: 0,
    }];
    let e = cfg.validate().unwrap_err().to_string();
    assert!(e.contains("`julia` draws random numbers"), "{e}");
    // κ must exceed 1.
    let text = format!(
        "target = {:?}\n[[flames]]\nxforms = 4\nvariations = [\"linear\"]\n[init]\nkappa = 0.0\n",
        grey
    );
    // Refused when the config is read, naming the field.
    let e = FlameLearnConfig::from_toml(&text, Path::new("k.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("κ must be a finite number > 1, got 0"), "{e}");
    assert!(e.contains("init.kappa"), "{e}");
    // Other config mistakes name their field.
    let bad = FlameLearnConfig::from_toml(
        &format!("target = {grey:?}\nflames = []\n"),
        Path::new("x.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(bad.contains("flames"), "{bad}");
    let mut cfg = FlameLearnConfig::paper(&grey, 4, vec!["linear".into()]);
    cfg.background = BackgroundConfig::Named("purple".into());
    assert!(cfg.validate().unwrap_err().to_string().contains("purple"));
}

/// The learned flame opens in flam3-render and draws where our render draws. Needs
/// flam3-render, which scripts/test.sh installs.
#[test]
fn the_learned_flame_renders_in_flam3_where_ours_draws() {
    assert!(
        Command::new("flam3-render")
            .arg("--version")
            .output()
            .is_ok(),
        "flam3-render is not installed: `apt-get install flam3-utils flam3-palette`"
    );
    let dir = tempfile::tempdir().unwrap();
    let target = sierpinski_target(dir.path(), 32);
    let cfg = config(&target, 40);
    let (t, _) = load_rgb_target(&target, 32, [1.0; 3]).unwrap();
    let run = dir.path().join("run");
    let out = run_flame(&cfg, t.clone(), &run, false, vec![]).unwrap();
    let problem = ifslab_strategies::problems::flame::flame_problem(&cfg, t).unwrap();
    let stack = problem.stack_at(&out.theta).unwrap();
    let size = 64;
    let flames = stack.to_flames(size, "test");
    let file = dir.path().join("learned.flame");
    ifslab::model::flame::write_flames(&file, &flames).unwrap();
    let png = dir.path().join("flam3.png");
    let res = Command::new("flam3-render")
        .env("in", &file)
        .env("out", &png)
        .env("nthreads", "1")
        .env("isaac_seed", "1")
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let theirs = Image::load(&png, true).unwrap();
    assert_eq!((theirs.width, theirs.height), (size, size));
    // Ours at the same size.
    let ecfg = DiffFlameConfig {
        trajectories: 800,
        ..sampler(size as usize)
    };
    let ours = forward(&stack, &ecfg, &GeneratorOrder::draw(&stack, &ecfg, 2)).unwrap();
    let n = (size * size) as usize;
    // Foreground: darker than the white background by a margin.
    let fg =
        |planes: &dyn Fn(usize) -> f64| -> Vec<bool> { (0..n).map(|i| planes(i) < 0.9).collect() };
    let a = fg(&|i| (0..3).map(|c| ours.image[c * n + i]).sum::<f64>() / 3.0);
    let b = fg(&|i| (0..3).map(|c| theirs.values[c * n + i] as f64).sum::<f64>() / 3.0);
    let inter = a.iter().zip(&b).filter(|(x, y)| **x && **y).count();
    let union = a.iter().zip(&b).filter(|(x, y)| **x || **y).count();
    let iou = inter as f64 / union.max(1) as f64;
    assert!(union > n / 20, "nothing drawn");
    eprintln!("foreground IoU of flam3's render and ours: {iou:.3}");
    assert!(
        iou > 0.5,
        "foreground IoU of flam3's render and ours: {iou}"
    );
}

/// The strategies that are not gradient descent run on flames too: Adam's hybrid with
/// annealing phases (value-only Metropolis steps on the start's generator order) and pure
/// annealing, each lowering the MSE of the random start.
#[test]
fn hybrid_and_annealing_strategies_run_on_flames() {
    use ifslab_strategies::optim::annealing::AnnealingConfig;
    use ifslab_strategies::optim::hybrid::HybridConfig;
    let dir = tempfile::tempdir().unwrap();
    let target = sierpinski_target(dir.path(), 24);
    let (t, _) = load_rgb_target(&target, 24, [1.0; 3]).unwrap();
    for (name, strategy) in [
        (
            "hybrid",
            StrategyConfig::new(&HybridConfig {
                adam: AdamConfig {
                    lr: 0.02,
                    ..AdamConfig::default()
                },
                anneal_every: 10,
                anneal_fraction: 0.5,
                ..HybridConfig::default()
            }),
        ),
        (
            "annealing",
            StrategyConfig::new(&AnnealingConfig {
                noise: 0.05,
                ..AnnealingConfig::default()
            }),
        ),
    ] {
        let mut cfg = config(&target, 30);
        cfg.sampler = DiffFlameConfig {
            trajectories: 60,
            steps: 200,
            ..sampler(24)
        };
        cfg.strategy = strategy;
        let out = run_flame(&cfg, t.clone(), &dir.path().join(name), false, vec![]).unwrap();
        assert_eq!(out.iterations, 30, "{name}");
        assert!(
            out.loss.is_finite() && out.loss < out.start_loss,
            "{name}: MSE {} from {}",
            out.loss,
            out.start_loss
        );
    }
}

/// With D-SSIM added to the MSE, the problem's gradient still matches finite differences of
/// its loss (the pipeline's reverse pass fed the composite image gradient), and bad weights
/// are named.
#[test]
fn the_composite_loss_gradient_matches_finite_differences() {
    use ifslab_strategies::driver::Differentiable;
    let dir = tempfile::tempdir().unwrap();
    let target = sierpinski_target(dir.path(), 16);
    let mut cfg = config(&target, 10);
    cfg.sampler = DiffFlameConfig {
        trajectories: 8,
        steps: 60,
        warmup: 5,
        chunks: 2,
        size: 16,
    };
    cfg.loss.dssim = 0.7;
    let (t, _) = load_rgb_target(&target, 16, [1.0; 3]).unwrap();
    let problem = ifslab_strategies::problems::flame::flame_problem(&cfg, t).unwrap();
    let theta = problem.initial_params();
    let e = problem.evaluate(&theta, 0).unwrap();
    assert_eq!(e.terms.len(), 2);
    assert!(e.terms[1].1 > 0.0, "D-SSIM term logged");
    let h = 1e-6;
    let mut checked = 0;
    for i in (0..theta.len()).step_by(3) {
        let mut p = theta.clone();
        p[i] += h;
        let lp = problem.evaluate(&p, 0).unwrap().loss;
        p[i] -= 2.0 * h;
        let lm = problem.evaluate(&p, 0).unwrap().loss;
        let fd = (lp - lm) / (2.0 * h);
        let err = (fd - e.grad[i]).abs() / (1e-4 + fd.abs().max(e.grad[i].abs()));
        assert!(err < 1e-3, "θ[{i}]: {} vs {fd}", e.grad[i]);
        checked += (fd.abs() > 1e-8) as usize;
    }
    assert!(checked > 5, "only {checked} entries move the loss");
    cfg.loss.dssim = -1.0;
    let msg = cfg.validate().unwrap_err().to_string();
    assert!(msg.contains("loss.dssim"), "{msg}");
}

/// The generator order is drawn once (the paper) unless `redraw_every = k` asks for a new
/// one every k iterations.
#[test]
fn the_generator_order_is_redrawn_only_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let target = sierpinski_target(dir.path(), 16);
    let (t, _) = load_rgb_target(&target, 16, [1.0; 3]).unwrap();
    let mut cfg = config(&target, 10);
    cfg.sampler = DiffFlameConfig {
        trajectories: 8,
        steps: 60,
        warmup: 5,
        chunks: 2,
        size: 16,
    };
    let fixed = ifslab_strategies::problems::flame::flame_problem(&cfg, t.clone()).unwrap();
    assert_eq!(fixed.order_at(0), fixed.order_at(7));
    cfg.redraw_every = 3;
    let redrawn = ifslab_strategies::problems::flame::flame_problem(&cfg, t).unwrap();
    assert_eq!(redrawn.order_at(0), fixed.order_at(0));
    assert_eq!(redrawn.order_at(2), redrawn.order_at(0));
    assert_ne!(redrawn.order_at(3), redrawn.order_at(0));
    assert_ne!(redrawn.order_at(6), redrawn.order_at(3));
}
