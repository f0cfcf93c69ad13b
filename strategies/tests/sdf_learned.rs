//! Learned symmetry patterns: the gradient of the loss in the logits (and points) equals
//! central finite differences, the hard assignment of a start biased towards the pattern is
//! the pattern's own, and bad settings are refused with the field named.

use std::path::Path;

use ifslab::model::Map;
use ifslab::model::segment::{Pattern, SegmentMap, builtin};
use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView};
use ifslab_strategies::problems::sdf::{LearnedConfig, SdfConfig, SdfLossConfig, SdfProblem};

fn koch_truth() -> Pattern {
    let to = SegmentMap::between([0.0, 0.0], [1.0, 0.0], [0.15, 0.4], [0.85, 0.4]).unwrap();
    builtin("koch").unwrap().transformed(&to).unwrap()
}

fn problem(cfg: LearnedConfig, loss: SdfLossConfig) -> SdfProblem {
    let truth = koch_truth();
    let view = SdfView::unit_square(48);
    let rc = SdfRenderConfig {
        depth: 3,
        cutoff: None,
    };
    let target = SdfRaster::render(&truth, &view, &rc).unwrap().to_image(1.5);
    SdfProblem::new(truth, target, view, 3, 2.0, loss)
        .unwrap()
        .with_learned_pattern(cfg, 100)
        .unwrap()
}

#[test]
fn logit_and_point_gradients_match_central_differences() {
    let cfg = LearnedConfig {
        temperature: 0.7,
        temperature_end: 0.7,
        bias: 4.0,
        noise: 0.5,
    };
    for loss in [
        SdfLossConfig::default(),
        SdfLossConfig {
            distance: 1.0,
            crossing: 10.0,
            ..SdfLossConfig::default()
        },
    ] {
        let p = problem(cfg.clone(), loss);
        let l = p.learned().unwrap();
        let mut pts = koch_truth().flat_points();
        for (k, x) in pts.iter_mut().enumerate() {
            *x += 0.02 * ((k as f64 * 1.7).sin());
        }
        let theta = l.start(&pts, 3).unwrap();
        assert_eq!(theta.len(), l.dim());
        assert_eq!(theta.len(), 10 + 16 * 5);
        let tau = 0.7;
        let g = p.eval_at(&theta, true, 2.0, tau).unwrap().grad.unwrap();
        let h = 1e-6;
        let mut worst: f64 = 0.0;
        let scale = g.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        assert!(scale > 0.0);
        let mut logit_nonzero = 0;
        for k in 0..theta.len() {
            let (mut up, mut down) = (theta.clone(), theta.clone());
            up[k] += h;
            down[k] -= h;
            let fd = (p.eval_at(&up, false, 2.0, tau).unwrap().loss
                - p.eval_at(&down, false, 2.0, tau).unwrap().loss)
                / (2.0 * h);
            worst = worst.max((fd - g[k]).abs());
            if k >= 10 && g[k].abs() > 1e-3 * scale {
                logit_nonzero += 1;
            }
        }
        assert!(worst < 1e-4 * scale, "worst {worst:e} of scale {scale:e}");
        // The logits are not a dead part of θ.
        assert!(logit_nonzero > 10, "{logit_nonzero} logits with a gradient");
    }
}

#[test]
fn the_scale_barrier_lets_expanding_soft_maps_through_with_an_exact_gradient() {
    // No prior on the assignment: the soft endpoints are averages of the points, and some
    // soft map expands. Without a barrier the pattern is refused; with one it is drawn and
    // the barrier's gradient joins the loss's.
    let cfg = LearnedConfig {
        temperature: 1.0,
        temperature_end: 1.0,
        bias: 0.0,
        noise: 1.0,
    };
    let pts = koch_truth().flat_points();
    let refused = problem(cfg.clone(), SdfLossConfig::default());
    let theta = refused.learned().unwrap().start(&pts, 1).unwrap();
    let e = refused
        .eval_at(&theta, true, 2.0, 1.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("not contractive"), "{e}");
    let p = problem(
        cfg,
        SdfLossConfig {
            scale_barrier: 10.0,
            max_scale: 0.8,
            ..SdfLossConfig::default()
        },
    );
    let ev = p.eval_at(&theta, true, 2.0, 1.0).unwrap();
    assert!(
        ev.scale_barrier > 0.0,
        "this start has an expanding soft map"
    );
    let g = ev.grad.unwrap();
    let scale = g.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let h = 1e-6;
    let mut worst: f64 = 0.0;
    for k in 0..theta.len() {
        let (mut up, mut down) = (theta.clone(), theta.clone());
        up[k] += h;
        down[k] -= h;
        let fd = (p.eval_at(&up, false, 2.0, 1.0).unwrap().loss
            - p.eval_at(&down, false, 2.0, 1.0).unwrap().loss)
            / (2.0 * h);
        worst = worst.max((fd - g[k]).abs());
    }
    assert!(worst < 1e-4 * scale, "worst {worst:e} of scale {scale:e}");
}

#[test]
fn a_biased_start_is_the_patterns_own_assignment_and_renders_it() {
    let cfg = LearnedConfig {
        temperature: 1.0,
        temperature_end: 0.05,
        bias: 3.0,
        noise: 0.3,
    };
    let p = problem(cfg, SdfLossConfig::default());
    let l = p.learned().unwrap();
    let truth = koch_truth();
    let theta = l.start(&truth.flat_points(), 0).unwrap();
    assert_eq!(l.assignment(&theta).unwrap(), l.own_assignment());
    assert_eq!(p.pattern_at(&theta).unwrap().pairs(), truth.pairs());
    // τ follows its schedule; at τ 0.05 the soft pattern is the hard one.
    assert!((l.temperature_at(0) - 1.0).abs() < 1e-12);
    assert!((l.temperature_at(100) - 0.05).abs() < 1e-12);
    assert!((l.temperature_at(50) - 0.05f64.sqrt()).abs() < 1e-12);
    let soft = l.soft_pattern(&theta, 0.05, false).unwrap();
    let hard = p.pattern_at(&theta).unwrap();
    for (a, b) in soft.maps().unwrap().iter().zip(hard.maps().unwrap()) {
        let (x, y) = (a.apply([0.3, 0.7]), b.apply([0.3, 0.7]));
        assert!((x[0] - y[0]).abs() < 1e-9 && (x[1] - y[1]).abs() < 1e-9);
    }
    // Same seed, same start; another seed, other logits.
    assert_eq!(l.start(&truth.flat_points(), 0).unwrap(), theta);
    assert_ne!(l.start(&truth.flat_points(), 1).unwrap(), theta);
}

#[test]
fn bad_learned_settings_are_refused_with_the_field_named() {
    for (field, cfg) in [
        (
            "learned.temperature",
            LearnedConfig {
                temperature: 0.0,
                ..LearnedConfig::default()
            },
        ),
        (
            "learned.temperature_end",
            LearnedConfig {
                temperature_end: -1.0,
                ..LearnedConfig::default()
            },
        ),
        (
            "learned.bias",
            LearnedConfig {
                bias: f64::NAN,
                ..LearnedConfig::default()
            },
        ),
        (
            "learned.noise",
            LearnedConfig {
                noise: -0.1,
                ..LearnedConfig::default()
            },
        ),
    ] {
        let e = cfg.validate().unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
        let mut c = SdfConfig::paper("t.png", "koch");
        c.learned = Some(cfg);
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
    // From TOML, too; and absent means off.
    let text = "target = \"t.png\"\npattern = \"koch\"\n[learned]\ntemperature = 0\n";
    let e = SdfConfig::from_toml(text, Path::new("c.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("learned.temperature"), "{e}");
    let text = "target = \"t.png\"\npattern = \"koch\"\n";
    assert!(
        SdfConfig::from_toml(text, Path::new("c.toml"))
            .unwrap()
            .learned
            .is_none()
    );
}
