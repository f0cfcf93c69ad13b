//! The evaluation renderer draws what the attractor is: the Sierpiński triangle has its
//! box-counting dimension, the fern fills its known region, zoom views keep their promises.

use ifslab::metrics::{box_counting_dimension, iou};
use ifslab::model::{Framing, library};
use ifslab::render::{RenderConfig, View, Zoom, render};

fn render_builtin(name: &str, cfg: &RenderConfig) -> ifslab::render::Raster {
    let code = library::builtin(name).unwrap();
    let maps = code.affine2().unwrap();
    let probs = code.evaluation_probabilities().unwrap();
    render(&maps, &probs, cfg, None).unwrap()
}

#[test]
fn sierpinski_has_box_counting_dimension_log3_over_log2() {
    let cfg = RenderConfig {
        width: 1024,
        height: 1024,
        points: 8_000_000,
        ..RenderConfig::default()
    };
    let r = render_builtin("sierpinski", &cfg);
    let mask = r.mask(0.0);
    // Boxes of 2..64 px: below that the pixel grid, above it the triangle's outline dominate.
    let (d, counts) = box_counting_dimension(&mask, 1024, 1024, 1, 6).unwrap();
    let expected = 3f64.ln() / 2f64.ln();
    assert!(
        (d - expected).abs() < 0.04,
        "box-counting dimension {d:.4}, expected {expected:.4} ± 0.04 (counts {counts:?})"
    );
    // And it is not a filled triangle (dimension 2) nor a curve (1): the tolerance is tight
    // enough to tell them apart.
}

#[test]
fn fern_covers_its_known_region() {
    // Barnsley's fern lies in x ∈ [−2.182, 2.6558], y ∈ [0, 9.9983].
    let window = Framing {
        min: [-3.0, -0.5],
        max: [3.5, 10.5],
    };
    let cfg = RenderConfig {
        width: 260,
        height: 440,
        points: 4_000_000,
        view: View::Window(window),
        ..RenderConfig::default()
    };
    let r = render_builtin("fern", &cfg);
    assert_eq!(r.stats.points_in_window, r.stats.points_generated);
    let (w, h) = (260usize, 440usize);
    let to_px = |x: f64, y: f64| {
        let c = ((x - window.min[0]) / 6.5 * w as f64) as usize;
        let row = ((window.max[1] - y) / 11.0 * h as f64) as usize;
        (c, row)
    };
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (usize::MAX, 0, usize::MAX, 0);
    let mut covered = 0;
    for row in 0..h {
        for c in 0..w {
            if r.values[row * w + c] > 0.0 {
                covered += 1;
                xmin = xmin.min(c);
                xmax = xmax.max(c);
                ymin = ymin.min(row);
                ymax = ymax.max(row);
            }
        }
    }
    let (ex0, ey1) = to_px(-2.182, 0.0);
    let (ex1, ey0) = to_px(2.6558, 9.9983);
    for (got, want, what) in [
        (xmin, ex0, "left"),
        (xmax, ex1, "right"),
        (ymin, ey0, "top"),
        (ymax, ey1, "bottom"),
    ] {
        assert!(
            got.abs_diff(want) <= 2,
            "{what} edge at pixel {got}, expected {want}"
        );
    }
    // The fern is leafy, not a blob and not dust: it covers a known share of its box.
    let frac = covered as f64 / ((xmax - xmin + 1) * (ymax - ymin + 1)) as f64;
    assert!(
        frac > 0.2 && frac < 0.5,
        "fern covers {frac:.3} of its bounding box"
    );
}

#[test]
fn fitted_framing_uses_75_percent_of_the_frame() {
    let r = render_builtin(
        "sierpinski",
        &RenderConfig {
            width: 200,
            height: 200,
            points: 200_000,
            ..RenderConfig::default()
        },
    );
    // The triangle is 1 wide: the window must be 1 / 0.75 wide.
    let s = r.stats.window.size();
    assert!((s[0] - 1.0 / 0.75).abs() < 1e-6, "window width {}", s[0]);
    // Nothing is drawn in the 12.5% border.
    let border = 200 / 8 - 1;
    for row in 0..200 {
        for c in 0..200 {
            if row < border || row >= 200 - border || c < border || c >= 200 - border {
                assert_eq!(
                    r.values[row * 200 + c],
                    0.0,
                    "pixel ({c}, {row}) in the border"
                );
            }
        }
    }
}

#[test]
fn zoom_views_discard_outside_points_and_meet_hit_targets() {
    let base = RenderConfig {
        width: 128,
        height: 128,
        points: 400_000,
        seed: 3,
        ..RenderConfig::default()
    };
    let full = render_builtin("sierpinski", &base);
    // Zoom 8× on the bottom-left corner of the triangle (a fixed point on the attractor).
    let zoom = Zoom {
        factor: 8.0,
        center: Some([0.05, 0.05]),
    };
    let zoomed = render_builtin(
        "sierpinski",
        &RenderConfig {
            zoom: Some(zoom),
            ..base.clone()
        },
    );
    let s = zoomed.stats.window.size();
    let fs = full.stats.window.size();
    assert!((s[0] - fs[0] / 8.0).abs() < 1e-12);
    assert!(zoomed.stats.points_in_window < zoomed.stats.points_generated / 4);
    // Self-similarity: the corner at 8× looks like the triangle at 1×, so a decent share of
    // the window is covered (not empty, not full).
    let cov = zoomed.values.iter().filter(|&&v| v > 0.0).count() as f64 / (128.0 * 128.0);
    assert!(cov > 0.05 && cov < 0.6, "coverage {cov}");
    // Ask for a number of hits: rounds continue until the window received them.
    let want = 300_000;
    let hit = render_builtin(
        "sierpinski",
        &RenderConfig {
            zoom: Some(zoom),
            min_hits: want,
            ..base.clone()
        },
    );
    assert!(hit.stats.points_in_window >= want);
    assert!(hit.stats.rounds > 1);
    // More hits, same window: at least as much is covered, and what 1 round drew is kept.
    let a = zoomed.mask(0.0);
    let b = hit.mask(0.0);
    assert!(
        a.iter().zip(&b).all(|(x, y)| !x || *y),
        "round 1's points must stay drawn"
    );
    assert!(iou(&a, &b).unwrap() > 0.5);
}

#[test]
fn supersampled_coverage_is_fractional_and_consistent() {
    let cfg = RenderConfig {
        width: 64,
        height: 64,
        points: 2_000_000,
        supersample: 16,
        ..RenderConfig::default()
    };
    let r = render_builtin("koch", &cfg);
    // A curve of dimension 1.26 covers few of the 256 sub-pixels of the pixels it crosses.
    let lit: Vec<f32> = r.values.iter().copied().filter(|&v| v > 0.0).collect();
    assert!(!lit.is_empty());
    let mean = lit.iter().sum::<f32>() / lit.len() as f32;
    assert!(
        mean > 0.02 && mean < 0.6,
        "mean coverage of lit pixels {mean}"
    );
    // Values are multiples of 1/256.
    assert!(
        r.values
            .iter()
            .all(|v| ((v * 256.0) - (v * 256.0).round()).abs() < 1e-3)
    );
}
