//! The evaluation renderer draws what the attractor is: the Sierpiński triangle has its
//! box-counting dimension, the fern fills its known region, zoom views keep their promises;
//! and it draws exactly what a plain reference renderer draws from the same points, on
//! every instruction set.

use ifslab::chaos::{Isa, MapSampler, Trajectory};
use ifslab::metrics::{box_counting_dimension, iou};
use ifslab::model::random::sample_code;
use ifslab::model::{Affine2, IfsCode, Window, library};
use ifslab::render::{RenderConfig, RenderMode, View, Zoom, render, render_with_isa};

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
    let window = Window {
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

/// A deep zoom draws the window's points through the code's words: at 2²⁰ the plain game
/// puts none of its points in the window, the words most of them; at 8× both draw the same
/// shape, the plain game from four rounds of points where the words need one.
#[test]
fn deep_zoom_fills_a_window_the_plain_game_cannot_reach() {
    let base = RenderConfig {
        width: 128,
        height: 128,
        points: 400_000,
        seed: 5,
        deep_zoom: true,
        ..RenderConfig::default()
    };
    // The midpoint of the triangle's base lies on the attractor at every depth.
    let deep = Zoom {
        factor: f64::powi(2.0, 20),
        center: Some([0.5, 0.0]),
    };
    let words = render_builtin(
        "sierpinski",
        &RenderConfig {
            zoom: Some(deep),
            ..base.clone()
        },
    );
    let plain = render_builtin(
        "sierpinski",
        &RenderConfig {
            zoom: Some(deep),
            deep_zoom: false,
            ..base.clone()
        },
    );
    assert_eq!(plain.stats.points_in_window, 0);
    assert!(
        words.stats.points_in_window * 2 > words.stats.points_generated,
        "{} of {} points in the window",
        words.stats.points_in_window,
        words.stats.points_generated
    );
    // The triangle's base at 2²⁰: a thin triangle corner pattern, neither empty nor full.
    let cov = words.values.iter().filter(|&&v| v > 0.0).count() as f64 / (128.0 * 128.0);
    assert!(cov > 0.05 && cov < 0.6, "coverage {cov}");

    // At 8× on the fern both ways draw the same picture.
    let zoom = Zoom {
        factor: 8.0,
        center: Some([0.0, 5.0]),
    };
    let w = render_builtin(
        "fern",
        &RenderConfig {
            zoom: Some(zoom),
            ..base.clone()
        },
    );
    let p = render_builtin(
        "fern",
        &RenderConfig {
            zoom: Some(zoom),
            deep_zoom: false,
            min_hits: w.stats.points_in_window,
            max_points: 64 * base.points,
            ..base.clone()
        },
    );
    assert!(p.stats.rounds >= 4, "{} rounds", p.stats.rounds);
    let same = iou(&w.mask(0.0), &p.mask(0.0)).unwrap();
    assert!(same > 0.9, "IoU {same}");
    // The same seed draws the same deep zoom.
    let again = render_builtin(
        "fern",
        &RenderConfig {
            zoom: Some(zoom),
            ..base
        },
    );
    assert_eq!(again.values, w.values);

    // Six maps of scale 0.95 overlap so much that a 64× window would need billions of
    // words: the render falls back to the plain game instead of failing.
    let maps: Vec<Affine2> = (0..6)
        .map(|k| {
            let a = k as f64 * std::f64::consts::FRAC_PI_3;
            Affine2::similitude(0.95, a, false, [0.05 * a.cos(), 0.05 * a.sin()])
        })
        .collect();
    let probs = vec![1.0 / 6.0; 6];
    let cfg = RenderConfig {
        zoom: Some(Zoom {
            factor: 64.0,
            center: None,
        }),
        ..base
    };
    let r = render(&maps, &probs, &cfg, None).unwrap();
    assert!(r.stats.points_in_window > 0);
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

fn with_threads<T: Send>(n: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
        .install(f)
}

fn random_code(seed: u64) -> (Vec<Affine2>, Vec<f64>) {
    let code = sample_code(10, seed).unwrap();
    let probs = IfsCode::from_affine2(None, &code.maps)
        .unwrap()
        .evaluation_probabilities()
        .unwrap();
    (code.maps, probs)
}

/// What a render must produce, the plain way: every point of every trajectory (trajectory
/// `round·t + i` keeps `points / t` points, the first `points mod t` one more, after
/// `warmup` steps from `[−1, 1]²`) sets one sub-pixel of a `(w·s) × (h·s)` grid or counts
/// on its pixel; rounds repeat until `min_hits` points landed or `max_points` were made.
/// Returns the pixel values and the in-window count.
fn reference(maps: &[Affine2], probs: &[f64], cfg: &RenderConfig, win: &Window) -> (Vec<f32>, u64) {
    let sampler = MapSampler::new(probs).unwrap();
    let t = if cfg.trajectories > 0 {
        cfg.trajectories as u64
    } else {
        (cfg.points / 256).clamp(1, 1024)
    };
    let (w, h, s) = (
        cfg.width as usize,
        cfg.height as usize,
        cfg.supersample as usize,
    );
    let (gw, gh) = (w * s, h * s);
    let size = win.size();
    // Supersampled pixels per world unit, as the renderer computes them.
    let kx = cfg.width as f64 * s as f64 / size[0];
    let ky = cfg.height as f64 * s as f64 / size[1];
    let mut sub = vec![false; gw * gh];
    let mut counts = vec![0u32; w * h];
    let max_points = if cfg.max_points > 0 {
        cfg.max_points
    } else {
        cfg.points * 64
    };
    let (mut hits, mut generated, mut round) = (0u64, 0u64, 0u64);
    loop {
        for i in 0..t {
            let n = cfg.points / t + u64::from(i < cfg.points % t);
            let mut tr = Trajectory::new(maps, &sampler, cfg.seed, round * t + i, 1.0);
            tr.skip_steps(cfg.warmup);
            for _ in 0..n {
                let p = tr.step();
                let fx = (p[0] - win.min[0]) * kx;
                let fy = (win.max[1] - p[1]) * ky;
                if fx >= 0.0 && fx < gw as f64 && fy >= 0.0 && fy < gh as f64 {
                    let (x, y) = (fx as usize, fy as usize);
                    sub[y * gw + x] = true;
                    counts[(y / s) * w + x / s] += 1;
                    hits += 1;
                }
            }
        }
        generated += cfg.points;
        round += 1;
        if cfg.min_hits == 0 || hits >= cfg.min_hits || generated >= max_points {
            break;
        }
    }
    let values = match cfg.mode {
        RenderMode::Coverage => {
            // The covered count of each pixel's s² sub-pixels, times 1/s².
            let inv = 1.0 / (s * s) as f32;
            (0..w * h)
                .map(|p| {
                    let (px, py) = (p % w, p / w);
                    let n = (0..s * s)
                        .filter(|k| sub[(py * s + k / s) * gw + px * s + k % s])
                        .count();
                    n as f32 * inv
                })
                .collect()
        }
        RenderMode::Density => {
            let max = counts.iter().copied().max().unwrap();
            let norm = 1.0 / (1.0 + max as f64).ln();
            counts
                .iter()
                .map(|&c| ((1.0 + c as f64).ln() * norm) as f32)
                .collect()
        }
    };
    (values, hits)
}

fn assert_matches_reference(maps: &[Affine2], probs: &[f64], cfg: &RenderConfig, what: &str) {
    for threads in [1, 3] {
        let r = with_threads(threads, || render(maps, probs, cfg, None).unwrap());
        let (want, hits) = reference(maps, probs, cfg, &r.stats.window);
        assert_eq!(r.stats.points_in_window, hits, "{what}, {threads} threads");
        let differ = r.values.iter().zip(&want).filter(|(a, b)| a != b).count();
        assert_eq!(
            differ, 0,
            "{what}, {threads} threads: {differ} pixels differ"
        );
        assert!(want.iter().any(|&v| v > 0.0), "{what}: nothing drawn");
    }
}

#[test]
fn renders_equal_the_reference_renderer() {
    let (maps, probs) = random_code(5);
    let base = RenderConfig {
        width: 97,
        height: 61,
        points: 300_000,
        supersample: 4,
        seed: 11,
        ..RenderConfig::default()
    };
    assert_matches_reference(&maps, &probs, &base, "97×61 at 4×");
    // Sub-pixels by division rather than shifts.
    let odd = RenderConfig {
        supersample: 3,
        ..base.clone()
    };
    assert_matches_reference(&maps, &probs, &odd, "3×");
    let density = RenderConfig {
        supersample: 1,
        mode: RenderMode::Density,
        ..base.clone()
    };
    assert_matches_reference(&maps, &probs, &density, "density");
    // Density cells are output pixels; the supersampling factor must not change them.
    let density_odd = RenderConfig {
        supersample: 3,
        ..density.clone()
    };
    assert_matches_reference(&maps, &probs, &density_odd, "density at 3×");
    // Sixteen 512 KiB tiles (2^26 bits), most bins filled and written several times.
    let tiled = RenderConfig {
        width: 512,
        height: 512,
        points: 3_000_000,
        supersample: 16,
        seed: 2,
        ..RenderConfig::default()
    };
    assert_matches_reference(&maps, &probs, &tiled, "512² at 16×");
    // A zoom window that most points miss, filled over several rounds.
    let zoomed = RenderConfig {
        width: 80,
        height: 80,
        points: 100_000,
        supersample: 2,
        zoom: Some(Zoom {
            factor: 6.0,
            center: None,
        }),
        min_hits: 150_000,
        seed: 4,
        ..RenderConfig::default()
    };
    let r = render(&maps, &probs, &zoomed, None).unwrap();
    assert!(r.stats.rounds > 2, "{} rounds", r.stats.rounds);
    assert!(r.stats.points_in_window < r.stats.points_generated / 2);
    assert_matches_reference(&maps, &probs, &zoomed, "zoom 6× with min_hits");
}

#[test]
fn hit_targets_stop_at_max_points_or_the_time_limit() {
    let (maps, probs) = random_code(5);
    // A window few points reach and a hit target it cannot meet.
    let unreachable = RenderConfig {
        width: 64,
        height: 64,
        points: 50_000,
        supersample: 4,
        zoom: Some(Zoom {
            factor: 50.0,
            center: None,
        }),
        min_hits: u64::MAX,
        max_points: 150_000,
        seed: 9,
        ..RenderConfig::default()
    };
    let r = render(&maps, &probs, &unreachable, None).unwrap();
    assert_eq!(r.stats.rounds, 3);
    assert_eq!(r.stats.points_generated, 150_000);
    assert!(!r.stats.stopped_by_time);
    assert_matches_reference(&maps, &probs, &unreachable, "stopped by max_points");
    // Any round outlasts a nanosecond, so the limit stops the rounds after the first.
    let timed = RenderConfig {
        max_points: 0,
        time_limit: Some(1e-9),
        ..unreachable.clone()
    };
    let r = render(&maps, &probs, &timed, None).unwrap();
    assert_eq!(r.stats.rounds, 1);
    assert_eq!(r.stats.points_generated, 50_000);
    assert!(r.stats.stopped_by_time);
    let one_round = RenderConfig {
        min_hits: 0,
        time_limit: None,
        ..timed.clone()
    };
    let want = render(&maps, &probs, &one_round, None).unwrap();
    assert_eq!(r.values, want.values);
}

#[test]
fn the_fma_path_renders_the_same_bits_as_the_portable_one() {
    if Isa::detect() == Isa::Portable {
        eprintln!("this CPU has no AVX2 + FMA: only the portable path exists here");
        assert!(matches!(
            render_with_isa(
                &[Affine2::new(0.5, 0.0, 0.0, 0.5, 0.0, 0.0)],
                &[1.0],
                &RenderConfig::default(),
                None,
                Isa::Fma
            ),
            Err(ifslab::Error::InvalidParameter { .. })
        ));
        return;
    }
    let (maps, probs) = random_code(8);
    let fern = library::builtin("fern").unwrap();
    let cases = [
        (maps, probs),
        (
            fern.affine2().unwrap(),
            fern.evaluation_probabilities().unwrap(),
        ),
    ];
    for (maps, probs) in &cases {
        for mode in [RenderMode::Coverage, RenderMode::Density] {
            // Fitted view: the pilot run and the rounds both go through the maps.
            let cfg = RenderConfig {
                width: 256,
                height: 256,
                points: 2_000_000,
                supersample: 8,
                mode,
                seed: 21,
                ..RenderConfig::default()
            };
            let fast = render_with_isa(maps, probs, &cfg, None, Isa::Fma).unwrap();
            let portable = render_with_isa(maps, probs, &cfg, None, Isa::Portable).unwrap();
            assert_eq!(fast.stats.window, portable.stats.window);
            assert_eq!(fast.stats.points_in_window, portable.stats.points_in_window);
            let differ = fast
                .values
                .iter()
                .zip(&portable.values)
                .filter(|(a, b)| a != b)
                .count();
            assert_eq!(differ, 0, "{mode:?}: {differ} pixels differ");
        }
    }
}

/// FNV-1a over the pixel values' bits and the in-window count.
fn image_hash(r: &ifslab::render::Raster) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let words = r.values.iter().map(|v| v.to_bits() as u64);
    for w in words.chain([r.stats.points_in_window]) {
        for b in w.to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// The images stay bit for bit what the renderer drew when these hashes were recorded
/// (2026-11-28, before the fused binning of issue 37), on one and two threads and on both
/// instruction sets: a change to how points reach the buffer must not move a bit.
#[test]
fn images_keep_their_recorded_bits() {
    let (maps, probs) = random_code(3);
    let cases = [
        // The benchmark's grid (64 tiles of 2^22 bits), bins filled and written many times.
        (
            "1024² at 16×",
            RenderConfig {
                width: 1024,
                height: 1024,
                points: 6_000_000,
                supersample: 16,
                seed: 1,
                ..RenderConfig::default()
            },
            0x163e_31ce_e45c_11d8u64,
        ),
        (
            "density 300×200",
            RenderConfig {
                width: 300,
                height: 200,
                points: 2_000_000,
                mode: RenderMode::Density,
                seed: 7,
                ..RenderConfig::default()
            },
            0x092d_4df3_88e7_f80au64,
        ),
        (
            "97×61 at 3×, zoomed, several rounds",
            RenderConfig {
                width: 97,
                height: 61,
                points: 200_000,
                supersample: 3,
                zoom: Some(Zoom {
                    factor: 3.0,
                    center: None,
                }),
                min_hits: 400_000,
                seed: 5,
                ..RenderConfig::default()
            },
            0x1744_045a_bd3b_97e4u64,
        ),
    ];
    let mut isas = vec![Isa::Portable];
    if Isa::detect() != Isa::Portable {
        isas.push(Isa::detect());
    }
    for (what, cfg, want) in &cases {
        for threads in [1, 2] {
            for &isa in &isas {
                let r = with_threads(threads, || {
                    render_with_isa(&maps, &probs, cfg, None, isa).unwrap()
                });
                let got = image_hash(&r);
                assert_eq!(
                    got, *want,
                    "{what}, {threads} threads, {isa:?}: {got:#018x}"
                );
            }
        }
    }
}
