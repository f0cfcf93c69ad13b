//! Learned symmetry patterns on the Koch curve: every pair endpoint a softmax-weighted
//! combination of the control points, fitted jointly with the points from a few seeds, under
//! several logit settings. Counts how many fits recover the Koch pattern's assignment (the
//! same four maps, up to pair order, the order of a map's two endpoints and the curve's
//! reversal) and its points (every point within 1e-2), and how many fail with a degenerate
//! or non-contractive soft map (without a scale barrier; with one, expanding soft maps are
//! drawn and penalised instead). Prints one CSV row per fit and a summary per setting.
//!
//! `cargo run --profile ci -p ifslab-strategies --example sdf_learned -- [--seeds N]`

use std::time::Instant;

use ifslab::image::Image;
use ifslab::model::segment::Pattern;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image::StrategyConfig;
use ifslab_strategies::problems::sdf::{LearnedConfig, SdfConfig, SdfInit, run_sdf};

mod common;
use common::{iou, koch_truth};

const SIZE: usize = 64;
const DEPTH: usize = 4;
const SIGMA: f64 = 1.5;

fn render(p: &Pattern) -> Vec<f64> {
    common::render(p, SIZE, DEPTH, SIGMA)
}

/// Pairs as a sorted list of `(source, target)` with the source's first index the smaller,
/// the points renumbered by `map`.
fn canonical(p: &Pattern, map: impl Fn(usize) -> usize) -> Vec<[usize; 4]> {
    let mut v: Vec<[usize; 4]> = p
        .pairs()
        .iter()
        .map(|pr| {
            let (s, t) = (pr.source.map(&map), pr.target.map(&map));
            if s[0] <= s[1] {
                [s[0], s[1], t[0], t[1]]
            } else {
                [s[1], s[0], t[1], t[0]]
            }
        })
        .collect();
    v.sort();
    v
}

/// Largest coordinate error, directly or with the points reversed.
fn point_error(theta: &[f64], truth: &[f64]) -> (f64, f64) {
    let n = truth.len() / 2;
    let direct = (0..2 * n)
        .map(|k| (theta[k] - truth[k]).abs())
        .fold(0.0, f64::max);
    let reversed = (0..n)
        .flat_map(|i| (0..2).map(move |c| (i, c)))
        .map(|(i, c)| (theta[2 * i + c] - truth[2 * (n - 1 - i) + c]).abs())
        .fold(0.0, f64::max);
    (direct, reversed)
}

fn main() {
    let seeds: u64 = std::env::args()
        .skip_while(|a| a != "--seeds")
        .nth(1)
        .map(|s| s.parse().expect("--seeds N"))
        .unwrap_or(5);
    let truth = koch_truth();
    let n = truth.points().len();
    let truth_theta = truth.flat_points();
    let target = render(&truth);
    let picture = Image::square(SIZE, target.clone()).expect("a target");
    // (name, bias, noise, τ start, τ end, scale barrier weight)
    let settings = [
        ("uniform prior, τ 1", 0.0, 1.0, 1.0, 1.0, 0.0),
        ("uniform prior, τ 1 → 0.05", 0.0, 1.0, 1.0, 0.05, 0.0),
        ("uniform prior, τ 0.3 → 0.02", 0.0, 1.0, 0.3, 0.02, 0.0),
        ("bias 2 to Koch, τ 1 → 0.05", 2.0, 1.0, 1.0, 0.05, 0.0),
        ("bias 4 to Koch, τ 1 → 0.05", 4.0, 1.0, 1.0, 0.05, 0.0),
        (
            "uniform prior, τ 1 → 0.05, barrier 1",
            0.0,
            1.0,
            1.0,
            0.05,
            1.0,
        ),
        (
            "uniform prior, τ 1 → 0.05, barrier 100",
            0.0,
            1.0,
            1.0,
            0.05,
            100.0,
        ),
        ("uniform prior, τ 1, barrier 100", 0.0, 1.0, 1.0, 1.0, 100.0),
        (
            "bias 2 to Koch, τ 1 → 0.05, barrier 100",
            2.0,
            1.0,
            1.0,
            0.05,
            100.0,
        ),
    ];
    println!("setting,seed,outcome,assignment,point_error,iou,soft_iou,seconds");
    let mut summary = Vec::new();
    for (name, bias, noise, t0, t1, barrier) in settings {
        let (mut assign, mut points, mut failed) = (0, 0, 0);
        let clock = Instant::now();
        for seed in 0..seeds {
            let dir = tempfile::tempdir().unwrap();
            let mut cfg = SdfConfig::paper(dir.path().join("unused.png"), "koch");
            cfg.size = SIZE;
            cfg.depth = DEPTH;
            cfg.sigma = SIGMA;
            cfg.iterations = 400;
            cfg.checkpoint_every = 0;
            cfg.seed = seed;
            cfg.init.kind = SdfInit::Line;
            cfg.init.jitter = 0.03;
            cfg.strategy = StrategyConfig::new(&AdamConfig {
                lr: 2e-3,
                final_lr_factor: 0.05,
                ..AdamConfig::default()
            });
            cfg.learned = Some(LearnedConfig {
                temperature: t0,
                temperature_end: t1,
                bias,
                noise,
            });
            cfg.loss.scale_barrier = barrier;
            let t = Instant::now();
            match run_sdf(&cfg, picture.clone(), None, dir.path(), false, vec![]) {
                Err(e) => {
                    failed += 1;
                    let msg = e.to_string().replace(',', ";");
                    println!("\"{name}\",{seed},failed: {msg},,,,,");
                }
                Ok(out) => {
                    let secs = t.elapsed().as_secs_f64();
                    let problem =
                        ifslab_strategies::problems::sdf::sdf_problem(&cfg, picture.clone(), None)
                            .unwrap();
                    let (fit, ok_assign) = match problem.pattern_at(&out.theta) {
                        Ok(fit) => {
                            let c = canonical(&fit, |k| k);
                            let ok = c == canonical(&truth, |k| k)
                                || c == canonical(&truth, |k| n - 1 - k);
                            (Some(fit), ok)
                        }
                        Err(_) => (None, false),
                    };
                    let (d, r) = point_error(&out.theta, &truth_theta);
                    let err = d.min(r);
                    let q = fit.as_ref().map_or(0.0, |f| iou(&render(f), &target));
                    // The soft pattern the loss saw at the end (final τ), before the
                    // arg-max readout.
                    let learned = problem.learned().unwrap();
                    let q_soft = learned
                        .soft_pattern(&out.theta, learned.temperature_at(u64::MAX), barrier > 0.0)
                        .map_or(0.0, |p| iou(&render(&p), &target));
                    assign += ok_assign as usize;
                    let ok_points = ok_assign && err < 1e-2;
                    points += ok_points as usize;
                    println!(
                        "\"{name}\",{seed},{},{ok_assign},{err:.4},{q:.3},{q_soft:.3},{secs:.2}",
                        if fit.is_some() {
                            "ran"
                        } else {
                            "degenerate hard pattern"
                        }
                    );
                }
            }
        }
        summary.push((
            name,
            assign,
            points,
            failed,
            clock.elapsed().as_secs_f64() / seeds as f64,
        ));
    }
    println!();
    println!("| setting | Koch assignment | and points to 1e-2 | failed | s / fit |");
    println!("|---|---:|---:|---:|---:|");
    for (name, a, p, f, s) in summary {
        println!("| {name} | {a} of {seeds} | {p} of {seeds} | {f} | {s:.2} |");
    }
}
