//! Segment-pattern fits: the whole loss's gradient (SDF raster → multi-scale MSE on pixels
//! and on distances) equals central finite differences in f64; Adam recovers the Koch curve's
//! control points from the paper's best-fit-line start; a resumed fit is bit-identical to an
//! uninterrupted one.

use std::path::Path;

use ifslab::image::Image;
use ifslab::model::segment::{Pattern, SegmentMap, builtin};
use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView};
use ifslab_strategies::driver::Differentiable;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image::StrategyConfig;
use ifslab_strategies::problems::sdf::{
    SdfConfig, SdfInit, SdfLossConfig, SdfProblem, initial_points, run_sdf,
};

/// The Koch curve from (0.15, 0.4) to (0.85, 0.4) in the unit square.
fn koch_truth() -> Pattern {
    let to = SegmentMap::between([0.0, 0.0], [1.0, 0.0], [0.15, 0.4], [0.85, 0.4]).unwrap();
    builtin("koch").unwrap().transformed(&to).unwrap()
}

/// The truth drawn by the renderer itself: the fit's minimum is exactly at the truth.
fn koch_target(size: usize, depth: usize, sigma: f64) -> Image<f64> {
    pattern_target(&koch_truth(), size, depth, sigma)
}

/// `pattern` drawn by the renderer in the unit square.
fn pattern_target(pattern: &Pattern, size: usize, depth: usize, sigma: f64) -> Image<f64> {
    SdfRaster::render(
        pattern,
        &SdfView::unit_square(size),
        &SdfRenderConfig {
            depth,
            cutoff: None,
        },
    )
    .unwrap()
    .to_image(sigma)
}

/// Distance between two point sets up to the Koch pattern's symmetry (reading the points in
/// reverse order draws the same curve).
fn koch_error(theta: &[f64], truth: &[f64]) -> f64 {
    let n = truth.len() / 2;
    let direct = (0..2 * n)
        .map(|k| (theta[k] - truth[k]).abs())
        .fold(0.0, f64::max);
    let reversed = (0..n)
        .flat_map(|i| (0..2).map(move |c| (i, c)))
        .map(|(i, c)| (theta[2 * i + c] - truth[2 * (n - 1 - i) + c]).abs())
        .fold(0.0, f64::max);
    direct.min(reversed)
}

/// `∂L/∂θ` of L = 1·MS-MSE(pixels) + 0.7·MS-MSE(distances), against central differences
/// (h = 1e-7) at a start away from the truth; and with the pixel term alone (which renders
/// with the 6σ cut-off).
#[test]
fn the_whole_loss_gradient_matches_finite_differences() {
    let size = 40;
    let target = koch_target(size, 3, 1.5);
    for loss in [
        SdfLossConfig {
            pixel: 1.0,
            distance: 0.7,
            levels: 3,
            ..SdfLossConfig::default()
        },
        SdfLossConfig {
            pixel: 1.0,
            distance: 0.0,
            levels: 3,
            ..SdfLossConfig::default()
        },
    ] {
        let p = SdfProblem::new(
            koch_truth(),
            target.clone(),
            SdfView::unit_square(size),
            3,
            1.5,
            loss.clone(),
        )
        .unwrap();
        let mut theta = koch_truth().flat_points();
        let bumps = [
            0.012, -0.02, 0.03, 0.011, -0.017, 0.025, 0.009, -0.031, -0.014, 0.022,
        ];
        for (v, b) in theta.iter_mut().zip(bumps) {
            *v += b;
        }
        let e = p.evaluate(&theta, 0).unwrap();
        let h = 1e-7;
        let mut worst = 0.0f64;
        let mut scale = 0.0f64;
        for k in 0..theta.len() {
            let (mut up, mut down) = (theta.clone(), theta.clone());
            up[k] += h;
            down[k] -= h;
            let fd =
                (p.eval(&up, false).unwrap().loss - p.eval(&down, false).unwrap().loss) / (2.0 * h);
            worst = worst.max((fd - e.grad[k]).abs());
            scale = scale.max(fd.abs());
        }
        assert!(
            scale > 1e-3,
            "{loss:?}: the loss should depend on the points ({scale})"
        );
        assert!(
            worst < 1e-4 * scale,
            "{loss:?}: worst error {worst} against {scale}"
        );
    }
}

fn koch_config(dir: &std::path::Path, iterations: u64, final_lr_factor: f64) -> SdfConfig {
    let mut c = SdfConfig::paper(dir.join("unused.png"), "koch");
    c.size = 64;
    c.depth = 4;
    c.sigma = 1.5;
    c.iterations = iterations;
    c.checkpoint_every = 5;
    c.loss = SdfLossConfig {
        pixel: 1.0,
        distance: 0.0,
        levels: 4,
        ..SdfLossConfig::default()
    };
    c.strategy = StrategyConfig::new(&AdamConfig {
        lr: 2e-3,
        final_lr_factor,
        ..AdamConfig::default()
    });
    c
}

/// The paper's claim for the Koch curve: from control points spread along the best-fit line
/// of the target's dark pixels, Adam on the multi-scale pixel loss finds the curve. Checked
/// to 1e-2 (in units of the target's side) on every point, up to the reversal symmetry.
#[test]
fn koch_is_recovered_from_the_best_fit_line() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = koch_config(dir.path(), 400, 0.05);
    let target = koch_target(cfg.size, cfg.depth, cfg.sigma);
    let start = initial_points(
        &builtin("koch").unwrap(),
        &target.values,
        &SdfView::unit_square(cfg.size),
        SdfInit::Line,
        0.0,
        0,
    )
    .unwrap();
    let truth = koch_truth().flat_points();
    assert!(
        koch_error(&start, &truth) > 0.05,
        "the start is not already the answer"
    );
    let out = run_sdf(&cfg, target, None, dir.path(), false, vec![]).unwrap();
    let err = koch_error(&out.theta, &truth);
    assert!(
        err < 1e-2,
        "control points off by {err}: {:?} vs {truth:?}",
        out.theta
    );
    assert_eq!(out.returned, "last");
}

/// Ten iterations, then ten more resumed from the checkpoint, give the bits of twenty in one go
/// (at a constant learning rate: a decaying one depends on the run's length, which the
/// first part would not share).
#[test]
fn a_resumed_fit_is_bit_identical() {
    let target = koch_target(64, 4, 1.5);
    let a = tempfile::tempdir().unwrap();
    let whole = run_sdf(
        &koch_config(a.path(), 20, 1.0),
        target.clone(),
        None,
        a.path(),
        false,
        vec![],
    )
    .unwrap();
    let b = tempfile::tempdir().unwrap();
    run_sdf(
        &koch_config(b.path(), 10, 1.0),
        target.clone(),
        None,
        b.path(),
        false,
        vec![],
    )
    .unwrap();
    let resumed = run_sdf(
        &koch_config(b.path(), 20, 1.0),
        target.clone(),
        None,
        b.path(),
        true,
        vec![],
    )
    .unwrap();
    assert_eq!(resumed.iterations, 20);
    assert!(
        whole
            .theta
            .iter()
            .zip(&resumed.theta)
            .all(|(x, y)| x.to_bits() == y.to_bits()),
        "{:?} vs {:?}",
        whole.theta,
        resumed.theta
    );
    // A fresh run into a folder that holds one is refused.
    let e = run_sdf(
        &koch_config(b.path(), 20, 1.0),
        target,
        None,
        b.path(),
        false,
        vec![],
    )
    .unwrap_err();
    assert!(e.to_string().contains("already holds a run"), "{e}");
}

/// At 256² a 1.5-pixel line is too thin for the straight start to feel the target's bump:
/// with σ = 1.5 throughout, 400 Adam steps end in a local optimum (IoU 0.07 on a framed
/// Koch picture, `ifslab sdf fit --size 256`). Coarse to fine — σ from 6 down to 1.5 —
/// recovers the control points to 1e-2.
#[test]
fn coarse_to_fine_recovers_koch_at_256() {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = koch_config(dir.path(), 400, 0.05);
    cfg.size = 256;
    cfg.depth = 5;
    cfg.sigma_start = Some(6.0);
    let target = koch_target(cfg.size, cfg.depth, cfg.sigma);
    let out = run_sdf(&cfg, target, None, dir.path(), false, vec![]).unwrap();
    let err = koch_error(&out.theta, &koch_truth().flat_points());
    assert!(err < 1e-2, "control points off by {err}: {:?}", out.theta);
}

#[test]
fn the_landscape_through_the_true_points_has_its_minimum_at_the_centre() {
    use ifslab_strategies::problems::image::{Directions, LandscapeConfig};
    use ifslab_strategies::problems::sdf::sdf_landscape;
    let (size, depth, sigma) = (64, 3, 1.5);
    let problem = SdfProblem::new(
        koch_truth(),
        koch_target(size, depth, sigma),
        SdfView::unit_square(size),
        depth,
        sigma,
        SdfLossConfig::default(),
    )
    .unwrap();
    let truth = koch_truth().flat_points();
    for directions in [
        Directions::Coordinates { i: 2, j: 3 },
        Directions::Random { seed: 3 },
    ] {
        let lc = LandscapeConfig {
            resolution: 7,
            extent: 0.05,
            directions: directions.clone(),
            streams: 4,
        };
        let l = sdf_landscape(&problem, &truth, &lc, &|| {}).unwrap();
        assert_eq!(l.total.len(), 49);
        assert!(l.failed.is_empty(), "{:?}", l.failed);
        let (a, b, v) = l.minimum();
        let step = 2.0 * lc.extent / 6.0;
        assert!(
            a.abs() <= step + 1e-12 && b.abs() <= step + 1e-12,
            "{directions:?}: minimum {v} at ({a}, {b}), centre {}",
            l.centre_total()
        );
        assert!(l.centre_total() < 1e-9, "centre loss {}", l.centre_total());
        let corner = l.total[0];
        assert!(
            corner > 10.0 * l.centre_total().max(1e-12),
            "flat slice: corner {corner}"
        );
    }
    // A θ of the wrong length is refused.
    let lc = LandscapeConfig::default();
    assert!(sdf_landscape(&problem, &truth[..4], &lc, &|| {}).is_err());
}

#[test]
fn a_coarse_to_fine_schedule_over_part_of_the_run_is_checked() {
    let base = "target = \"t.png\"\npattern = \"koch\"\niterations = 400\n";
    for (extra, want) in [
        ("sigma_iterations = 200\n", "needs sigma_start"),
        (
            "sigma_start = 6.0\nsigma_iterations = 0\n",
            "between 1 and iterations",
        ),
        (
            "sigma_start = 6.0\nsigma_iterations = 401\n",
            "between 1 and iterations",
        ),
    ] {
        let e = SdfConfig::from_toml(&format!("{base}{extra}"), Path::new("c.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("sigma_iterations") && e.contains(want),
            "{extra}: {e}"
        );
    }
    let ok = SdfConfig::from_toml(
        &format!("{base}sigma_start = 6.0\nsigma_iterations = 200\n"),
        Path::new("c.toml"),
    )
    .unwrap();
    assert_eq!(ok.sigma_iterations, Some(200));
}

/// A Koch curve whose apex is lower than the template's (0.6 of its height, as in the
/// robustness suite's perturbed patterns) from (0.1, 0.45) to (0.9, 0.45).
fn low_koch() -> Pattern {
    let h = 0.6 * 0.8 * 3f64.sqrt() / 6.0;
    builtin("koch")
        .unwrap()
        .with_flat_points(&[
            0.1,
            0.45,
            0.1 + 0.8 / 3.0,
            0.45,
            0.5,
            0.45 + h,
            0.9 - 0.8 / 3.0,
            0.45,
            0.9,
            0.45,
        ])
        .unwrap()
}

/// The template's box fitted into the ink's with its aspect kept starts a low Koch curve
/// contracted (its ends 20 % inside the curve's), where a thin curve's fit stays (the
/// robustness suite's `tune4` `patterns_koch-40`: truth IoU 0.10); the stretched box spans
/// the ink's width, and the best of the starts, which now includes it, recovers the points.
#[test]
fn a_low_koch_curve_starts_from_the_stretched_box_and_is_recovered() {
    use ifslab_strategies::problems::sdf::candidate_starts;
    let (size, depth, sigma) = (96, 4, 0.75);
    let truth = low_koch();
    let view = SdfView::unit_square(size);
    let target = pattern_target(&truth, size, depth, sigma);
    let koch = builtin("koch").unwrap();
    let starts = candidate_starts(&koch, &target.values, &view, true).unwrap();
    let width = |t: &[f64]| (t[8] - t[0]).abs();
    let named = |n: &str| starts.iter().find(|(s, _)| *s == n).map(|(_, t)| t.clone());
    let kept = named("box").expect("the box start");
    let stretched = named("box_stretched").expect("the stretched box start");
    assert!(width(&kept) < 0.85 * 0.8, "kept aspect: {kept:?}");
    assert!((width(&stretched) - 0.8).abs() < 0.03, "{stretched:?}");
    // Without `stretched` the two are not offered.
    let plain = candidate_starts(&koch, &target.values, &view, false).unwrap();
    assert!(plain.iter().all(|(n, _)| !n.starts_with("box_stretched")));
    assert_eq!(plain.len() + 2, starts.len());

    let dir = tempfile::tempdir().unwrap();
    let mut cfg = koch_config(dir.path(), 300, 1.0);
    cfg.size = size;
    cfg.depth = depth;
    cfg.sigma = sigma;
    cfg.init.kind = SdfInit::Best;
    let out = run_sdf(&cfg, target, None, dir.path(), false, vec![]).unwrap();
    let err = koch_error(&out.theta, &truth.flat_points());
    assert!(
        out.start_kind
            .is_some_and(|k| k.starts_with("box_stretched")),
        "{:?}",
        out.start_kind
    );
    assert!(err < 1e-2, "control points off by {err}: {:?}", out.theta);
}
