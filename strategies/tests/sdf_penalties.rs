//! The two penalties of segment-pattern fits.
//!
//! The self-crossing penalty: zero on the true Koch curve, positive on a polyline that
//! crosses itself, its gradient (alone and inside the whole loss) equal to central finite
//! differences, and bad settings refused with the field named.
//!
//! The barrier on the maps' scales: zero while every map contracts below the threshold, the
//! exact sum of squared excesses above it, its gradient (alone and inside the whole loss)
//! equal to central finite differences, a fit to a filled square that keeps its maps below
//! the threshold where the plain fit lets one expand, and bad settings refused.

use std::path::Path;

use ifslab::image::Image;
use ifslab::model::segment::{Pattern, SegmentMap, builtin};
use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView};
use ifslab_strategies::driver::Differentiable;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image::StrategyConfig;
use ifslab_strategies::problems::sdf::{
    SdfConfig, SdfLossConfig, SdfProblem, crossing_depth2, crossing_penalty, run_sdf, scale_barrier,
};

fn koch_truth() -> Pattern {
    let to = SegmentMap::between([0.0, 0.0], [1.0, 0.0], [0.15, 0.4], [0.85, 0.4]).unwrap();
    builtin("koch").unwrap().transformed(&to).unwrap()
}

/// Koch's five points with p₁ and p₃ pulled past each other: the first and last segments of
/// the polyline cross near (0.5, 0.07).
fn crossed_points() -> Vec<f64> {
    vec![0.0, 0.0, 0.7, 0.1, 0.52, 0.31, 0.3, 0.13, 1.0, 0.0]
}

fn central_diff(f: impl Fn(&[f64]) -> f64, x: &[f64], h: f64) -> Vec<f64> {
    (0..x.len())
        .map(|k| {
            let (mut up, mut down) = (x.to_vec(), x.to_vec());
            up[k] += h;
            down[k] -= h;
            (f(&up) - f(&down)) / (2.0 * h)
        })
        .collect()
}

#[test]
fn two_segments_cross_by_the_smallest_endpoint_distance() {
    // An X: (0,0)–(1,1) and (0.2,0.9)–(0.9,0.0); depth is the nearest endpoint's distance to
    // the other line.
    let s = [[0.0, 0.0], [1.0, 1.0]];
    let t = [[0.2, 0.9], [0.9, 0.0]];
    let (v, _) = crossing_depth2(s, t);
    let line = |p: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        let u = [b[0] - a[0], b[1] - a[1]];
        ((u[0] * (p[1] - a[1]) - u[1] * (p[0] - a[0])) / u[0].hypot(u[1])).abs()
    };
    let want = [
        line(t[0], s[0], s[1]),
        line(t[1], s[0], s[1]),
        line(s[0], t[0], t[1]),
        line(s[1], t[0], t[1]),
    ]
    .into_iter()
    .fold(f64::INFINITY, f64::min);
    assert!((v - want * want).abs() < 1e-15, "{v} vs {}", want * want);
    // Disjoint, touching at an endpoint, and parallel: no crossing.
    for t in [
        [[2.0, 0.0], [3.0, 1.0]],
        [[1.0, 1.0], [2.0, 0.0]],
        [[0.0, 0.5], [1.0, 1.5]],
    ] {
        assert_eq!(crossing_depth2(s, t).0, 0.0, "{t:?}");
    }
    // Its gradient in all eight coordinates.
    let flat = [s[0], s[1], t[0], t[1]].concat();
    let f =
        |x: &[f64]| crossing_depth2([[x[0], x[1]], [x[2], x[3]]], [[x[4], x[5]], [x[6], x[7]]]).0;
    let g: Vec<f64> = crossing_depth2(s, t).1.iter().flatten().copied().collect();
    let fd = central_diff(f, &flat, 1e-7);
    for (a, b) in g.iter().zip(&fd) {
        assert!((a - b).abs() < 1e-7, "{g:?} vs {fd:?}");
    }
    assert!(g.iter().any(|x| x.abs() > 0.1));
}

#[test]
fn the_koch_curve_does_not_cross_itself_and_a_folded_one_does() {
    let truth = koch_truth();
    for depth in 1..=3 {
        let (v, _) = crossing_penalty(&truth, depth, true).unwrap();
        assert!(v < 1e-20, "depth {depth}: {v}");
    }
    let crossed = truth.with_flat_points(&crossed_points()).unwrap();
    for depth in 1..=2 {
        let (v, g) = crossing_penalty(&crossed, depth, true).unwrap();
        assert!(v > 1e-3, "depth {depth}: {v}");
        let fd = central_diff(
            |x| {
                crossing_penalty(&truth.with_flat_points(x).unwrap(), depth, false)
                    .unwrap()
                    .0
            },
            &crossed_points(),
            1e-7,
        );
        let scale = fd.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let worst = g
            .iter()
            .zip(&fd)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(scale > 1e-2, "depth {depth}: {fd:?}");
        assert!(worst < 1e-5 * scale, "depth {depth}: {g:?} vs {fd:?}");
    }
    assert!(crossing_penalty(&truth, 0, false).is_err());
}

/// Pixels + crossing (weight 0.5, words of length 2) against central differences, at the
/// crossed points.
#[test]
fn the_loss_with_the_crossing_term_matches_finite_differences() {
    let size = 40;
    let target = SdfRaster::render(
        &koch_truth(),
        &SdfView::unit_square(size),
        &SdfRenderConfig {
            depth: 3,
            cutoff: None,
        },
    )
    .unwrap()
    .to_image(1.5);
    let loss = SdfLossConfig {
        levels: 3,
        crossing: 0.5,
        crossing_depth: 2,
        ..SdfLossConfig::default()
    };
    let p = SdfProblem::new(
        koch_truth(),
        target,
        SdfView::unit_square(size),
        3,
        1.5,
        loss,
    )
    .unwrap();
    assert_whole_loss_gradient(&p, &crossed_points(), "crossing");
}

/// The whole loss's gradient at θ against central differences, with the penalty `term`
/// active there.
fn assert_whole_loss_gradient(p: &SdfProblem, theta: &[f64], term: &str) {
    let e = p.evaluate(theta, 0).unwrap();
    let value = e.terms.iter().find(|t| t.0 == term).unwrap().1;
    assert!(value > 1e-3, "{term} = {value}");
    let fd = central_diff(|x| p.eval(x, false).unwrap().loss, theta, 1e-7);
    let scale = fd.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let worst = e
        .grad
        .iter()
        .zip(&fd)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst < 1e-4 * scale, "{:?} vs {fd:?}", e.grad);
}

#[test]
fn bad_crossing_settings_are_refused() {
    let base = "target = \"t.png\"\npattern = \"koch\"\n[loss]\n";
    for (extra, field) in [
        ("crossing = -1.0\n", "loss.crossing"),
        ("crossing = nan\n", "loss.crossing"),
        (
            "crossing = 1.0\ncrossing_depth = 0\n",
            "loss.crossing_depth",
        ),
        (
            "crossing = 1.0\ncrossing_depth = 9\n",
            "loss.crossing_depth",
        ),
    ] {
        let e = SdfConfig::from_toml(&format!("{base}{extra}"), Path::new("c.toml")).unwrap_err();
        assert!(e.to_string().contains(field), "{extra}: {e}");
    }
    let ok = SdfConfig::from_toml(
        &format!("{base}crossing = 2.0\ncrossing_depth = 2\n"),
        Path::new("c.toml"),
    )
    .unwrap();
    assert_eq!(ok.loss.crossing, 2.0);
}

#[test]
fn the_barrier_is_the_squared_excess_of_each_scale() {
    let koch = koch_truth();
    // Every Koch map has scale 1/3.
    assert_eq!(scale_barrier(&koch, 0.5).unwrap().0, 0.0);
    let (v, g) = scale_barrier(&koch, 0.2).unwrap();
    let want = 4.0 * (1.0 / 3.0 - 0.2f64).powi(2);
    assert!((v - want).abs() < 1e-12, "{v} vs {want}");
    // Its gradient against central differences, with two maps past 1 after moving p₂ up.
    let mut pts = koch.flat_points();
    pts[5] += 0.5;
    let f = |x: &[f64]| {
        scale_barrier(&koch.with_flat_points(x).unwrap(), 0.2)
            .unwrap()
            .0
    };
    let (_, g2) = scale_barrier(&koch.with_flat_points(&pts).unwrap(), 0.2).unwrap();
    let fd = central_diff(f, &pts, 1e-7);
    for (a, b) in g2.iter().zip(&fd) {
        assert!((a - b).abs() < 1e-6, "{g2:?} vs {fd:?}");
    }
    assert!(g.iter().any(|x| x.abs() > 1e-3));
}

#[test]
fn the_whole_loss_gradient_with_the_barrier_matches_finite_differences() {
    let truth = koch_truth();
    let view = SdfView::unit_square(32);
    let rc = SdfRenderConfig {
        depth: 3,
        cutoff: None,
    };
    let target = SdfRaster::render(&truth, &view, &rc).unwrap().to_image(1.5);
    let loss = SdfLossConfig {
        scale_barrier: 5.0,
        max_scale: 0.3,
        ..SdfLossConfig::default()
    };
    let p = SdfProblem::new(truth.clone(), target, view, 3, 1.5, loss).unwrap();
    let mut theta = truth.flat_points();
    theta[5] += 0.2;
    theta[3] -= 0.05;
    assert_whole_loss_gradient(&p, &theta, "scale_barrier");
}

/// The largest map scale of Koch fitted to a filled square from seed 5's start, the setting
/// of `examples/sdf_unit_square.rs` (paper_repro/differentiable_ifs/: this seed's plain fit
/// ends with a map of scale 1.095).
fn square_fit_max_scale(barrier: f64) -> f64 {
    let (size, m) = (64usize, 0.2);
    let view = SdfView::unit_square(size);
    let target: Vec<f64> = (0..size * size)
        .map(|i| {
            let [x, y] = view.centre(i / size, i % size);
            (x >= m && x <= 1.0 - m && y >= m && y <= 1.0 - m) as u8 as f64
        })
        .collect();
    let target = Image::square(size, target).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = SdfConfig::paper(dir.path().join("unused.png"), "koch");
    cfg.size = size;
    cfg.depth = 5;
    cfg.sigma = 1.5;
    cfg.sigma_start = Some(6.0);
    cfg.iterations = 600;
    cfg.checkpoint_every = 0;
    cfg.seed = 5;
    cfg.init.jitter = 0.1;
    cfg.loss.scale_barrier = barrier;
    cfg.strategy = StrategyConfig::new(&AdamConfig {
        lr: 2e-3,
        final_lr_factor: 0.05,
        ..AdamConfig::default()
    });
    let out = run_sdf(&cfg, target, None, dir.path(), false, vec![]).unwrap();
    builtin("koch")
        .unwrap()
        .with_flat_points(&out.theta)
        .unwrap()
        .maps()
        .unwrap()
        .iter()
        .map(|m| m.scale())
        .fold(0.0, f64::max)
}

#[test]
fn a_fit_to_a_filled_square_stays_contractive_with_the_barrier() {
    let plain = square_fit_max_scale(0.0);
    let held = square_fit_max_scale(100.0);
    eprintln!("largest map scale: {plain:.3} without the barrier, {held:.3} with it");
    assert!(plain > 1.0, "the plain fit lets a map expand: {plain}");
    assert!(held < 0.92, "the barrier holds the maps near 0.9: {held}");
}

#[test]
fn bad_barrier_settings_are_refused() {
    let base = "target = \"t.png\"\npattern = \"koch\"\n[loss]\n";
    for (extra, field) in [
        ("scale_barrier = -1.0\n", "loss.scale_barrier"),
        ("scale_barrier = nan\n", "loss.scale_barrier"),
        ("scale_barrier = 1.0\nmax_scale = 1.0\n", "loss.max_scale"),
        ("scale_barrier = 1.0\nmax_scale = 0\n", "loss.max_scale"),
    ] {
        let e = SdfConfig::from_toml(&format!("{base}{extra}"), Path::new("c.toml")).unwrap_err();
        assert!(e.to_string().contains(field), "{extra}: {e}");
    }
    let ok = SdfConfig::from_toml(
        &format!("{base}scale_barrier = 10.0\nmax_scale = 0.8\n"),
        Path::new("c.toml"),
    )
    .unwrap();
    assert_eq!((ok.loss.scale_barrier, ok.loss.max_scale), (10.0, 0.8));
}
