//! `ifslab fit-points DATA --k K --depth D --pool P -o DIR`: fit an IFS of similitudes to a
//! point cloud of any dimension with EM (Bloem & de Rooij), compare its held-out
//! log-likelihood with isotropic and full-covariance Gaussian mixtures, and write the code,
//! a log-likelihood curve and (2-D/3-D) a scatter of data against model samples.
//!
//! With `--sweep-pool 1,2,4,…` it instead measures the proportion of converged runs per
//! pre-selection pool size over `--repeats` seeded runs (the paper's Fig. 5b). With
//! `--truth CODE.json` (2-D) every fit is also compared with the code that made the data:
//! the agreement of the two attractors' coverage and the largest difference of their sorted
//! scales, since a run can meet the convergence criterion with a wrong code.
//!
//! The defaults are ifslab's (see `ifslab_strategies::problems::em::EmConfig`); `--paper` runs the
//! paper's algorithm instead.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{Context, bail};
use ifslab::chaos::{ChaosGame, generate_nd, mix_seed};
use ifslab::model::IfsCode;
use ifslab::render::image_io::BitDepth;
use ifslab::render::{RenderConfig, RenderMode, View, render};
use ifslab_strategies::problems::em::{
    ComponentUpdate, Covariance, EmConfig, EmFit, EmModel, Event, Gmm, GmmConfig, MStepConfig,
    PointSet, PreselectBy, ReorientConfig, fit, fit_all,
};
use serde_json::json;

use super::resolve_code;
use crate::bars as progress;
use ifslab_experiments::plot::{Series, line_chart, scatter};

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Update {
    /// Every occurrence of a map in a code informs its update (default).
    AllPositions,
    /// Only codes whose outermost map it is (the paper's rule).
    Outermost,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SelectBy {
    /// Highest log-likelihood of the evaluation points (default).
    LogLikelihood,
    /// Highest mean depth (the paper's criterion).
    MeanDepth,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum PreselectSchedule {
    /// Depths 1, 2, …, --preselect-depth in turn (default).
    Curriculum,
    /// Every iteration at --preselect-depth (the paper).
    Fixed,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Point cloud: CSV/text (one point per line) or NumPy .npy (N×H), any dimension H;
    /// or `ifs:NAME` / `ifs:CODE.json` to sample --points points from a code.
    pub data: String,
    /// Number of similitudes K.
    #[arg(long, default_value_t = 3)]
    pub k: usize,
    /// Maximum code depth D.
    #[arg(long, default_value_t = 6)]
    pub depth: usize,
    /// Pre-selection pool size (1 = a single random start).
    #[arg(long, default_value_t = 10)]
    pub pool: usize,
    /// Output folder.
    #[arg(short, long)]
    pub output: PathBuf,
    /// EM iterations at depth D.
    #[arg(long, default_value_t = 300)]
    pub iterations: usize,
    /// Minibatch size N′ (0 = full batch).
    #[arg(long, default_value_t = 500)]
    pub batch: usize,
    /// Deepest depth of the pre-selection runs.
    #[arg(long, default_value_t = 3)]
    pub preselect_depth: usize,
    /// Iterations of each pre-selection run (the paper's 100).
    #[arg(long, default_value_t = 100)]
    pub preselect_iterations: usize,
    /// How pre-selection candidates are trained.
    #[arg(long, value_enum, default_value = "curriculum")]
    pub preselect_schedule: PreselectSchedule,
    /// How the pre-selection winner is chosen.
    #[arg(long, value_enum, default_value = "log-likelihood")]
    pub preselect_by: SelectBy,
    /// Orientations tried per component by the re-orientation search (0 = off).
    #[arg(long, default_value_t = 12)]
    pub reorient: usize,
    /// Re-orientation search every this many main iterations (0 = only in pre-selection).
    #[arg(long, default_value_t = 100)]
    pub reorient_every: usize,
    /// Training points that score candidates and re-orientations (0 = all).
    #[arg(long, default_value_t = 1000)]
    pub eval_points: usize,
    /// Keep the base Gaussian where pre-selection left it (no moment matching).
    #[arg(long)]
    pub no_recentre: bool,
    /// Component update rule of the M-step.
    #[arg(long, value_enum, default_value = "all-positions")]
    pub update: Update,
    /// The paper's algorithm: outermost update, fixed-depth pre-selection by mean depth,
    /// no re-orientation, no recentring.
    #[arg(long, conflicts_with_all = ["preselect_schedule", "preselect_by", "reorient", "reorient_every", "no_recentre", "update"])]
    pub paper: bool,
    /// Independent runs; the one with the best held-out log-likelihood is kept.
    #[arg(long, default_value_t = 1)]
    pub runs: usize,
    /// Fraction of the points held out for evaluation.
    #[arg(long, default_value_t = 0.1)]
    pub heldout: f64,
    /// Evaluate the held-out log-likelihood every this many iterations.
    #[arg(long, default_value_t = 10)]
    pub eval_every: usize,
    /// Seed (data sampling, split, initialisation, minibatches).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Points to sample when DATA is `ifs:…`.
    #[arg(long, default_value_t = 20_000)]
    pub points: usize,
    /// Also write the (sampled or loaded) points here (.csv or .npy).
    #[arg(long)]
    pub save_data: Option<PathBuf>,
    /// The code that made the data (2-D): report each fit's coverage agreement with it (the
    /// share of covered pixels within one pixel of the other's, at 128²) and the largest
    /// difference of the sorted scales.
    #[arg(long)]
    pub truth: Option<String>,
    /// Gaussian-mixture baselines: component counts (default: K, and the largest counts
    /// with no more parameters than the IFS model).
    #[arg(long, value_delimiter = ',')]
    pub gmm: Vec<usize>,
    /// Sweep mode: pre-selection pool sizes to compare (writes pool_sweep.csv/png only).
    #[arg(long, value_delimiter = ',')]
    pub sweep_pool: Vec<usize>,
    /// Sweep mode: seeded runs per pool size.
    #[arg(long, default_value_t = 16)]
    pub repeats: usize,
    /// Points in the render of a 2-D fit.
    #[arg(long, default_value_t = 2_000_000)]
    pub render_points: u64,
}

/// Loads DATA or samples it from a code.
fn load_points(a: &Args) -> anyhow::Result<(PointSet, String)> {
    if let Some(spec) = a.data.strip_prefix("ifs:") {
        let code = resolve_code(spec)?;
        if a.points == 0 {
            bail!("--points must be at least 1");
        }
        let probs = code.evaluation_probabilities()?;
        // Many short trajectories: points close to independent draws from the measure.
        let per = 50usize;
        let game = ChaosGame {
            trajectories: a.points.div_ceil(per),
            length: per + 30,
            warmup: 30,
            start_half_width: 1.0,
            seed: mix_seed(a.seed, 0xda7a),
        };
        let pts = generate_nd(&game, &code.maps, &probs)?;
        let all = PointSet::new(code.dim(), pts)?;
        let src = format!(
            "{} points sampled from `{spec}` by the chaos game (seed {})",
            a.points, a.seed
        );
        Ok((all.head(a.points), src))
    } else {
        let p = PointSet::load(&a.data).with_context(|| format!("reading {}", a.data))?;
        Ok((p, a.data.clone()))
    }
}

fn em_config(a: &Args, seed: u64, pool: usize) -> EmConfig {
    let base = if a.paper {
        EmConfig::paper()
    } else {
        EmConfig {
            curriculum: matches!(a.preselect_schedule, PreselectSchedule::Curriculum),
            preselect_by: match a.preselect_by {
                SelectBy::LogLikelihood => PreselectBy::LogLikelihood,
                SelectBy::MeanDepth => PreselectBy::MeanDepth,
            },
            reorient: ReorientConfig {
                rotations: a.reorient,
                every: a.reorient_every,
            },
            recentre: !a.no_recentre,
            mstep: MStepConfig {
                update: match a.update {
                    Update::AllPositions => ComponentUpdate::AllPositions,
                    Update::Outermost => ComponentUpdate::Outermost,
                },
                ..MStepConfig::default()
            },
            ..EmConfig::default()
        }
    };
    EmConfig {
        components: a.k,
        depth: a.depth,
        iterations: a.iterations,
        batch_size: a.batch,
        pool,
        preselect_depth: a.preselect_depth,
        preselect_iterations: a.preselect_iterations,
        eval_points: a.eval_points,
        eval_every: a.eval_every,
        seed,
        ..base
    }
}

/// The code that made the data, and the window its attractor fills, for `--truth`.
struct Truth {
    scales: Vec<f64>,
    window: View,
    mask: Vec<bool>,
}

/// A fit counts as right when its coverage agreement with `--truth` reaches this.
const RIGHT_AGREEMENT: f64 = 0.9;

/// Side of the coverage masks compared with `--truth`, and points per render.
const TRUTH_SIZE: u32 = 128;
const TRUTH_POINTS: u64 = 2_000_000;

/// Coverage mask of a 2-D code in `view`.
fn coverage(code: &IfsCode, view: View, seed: u64) -> anyhow::Result<(Vec<bool>, View)> {
    let maps = code.affine2()?;
    let probs = code.evaluation_probabilities()?;
    let cfg = RenderConfig {
        width: TRUTH_SIZE,
        height: TRUTH_SIZE,
        points: TRUTH_POINTS,
        mode: RenderMode::Coverage,
        seed,
        view,
        ..RenderConfig::default()
    };
    let r = render(&maps, &probs, &cfg, None)?;
    Ok((
        r.values.iter().map(|&v| v > 0.0).collect(),
        View::Window(r.stats.window),
    ))
}

fn load_truth(a: &Args, dim: usize) -> anyhow::Result<Option<Truth>> {
    let Some(spec) = &a.truth else {
        return Ok(None);
    };
    let code = resolve_code(spec).with_context(|| format!("--truth {spec}"))?;
    if code.dim() != 2 || dim != 2 {
        bail!(
            "--truth compares 2-D attractors; the code is {}-D and the data {dim}-D",
            code.dim()
        );
    }
    let mut scales = Vec::new();
    for (i, m) in code.maps.iter().enumerate() {
        let d = m.m.determinant();
        if d.is_nan() || d <= 0.0 {
            bail!("--truth {spec}: map {i} is not a similitude with a proper rotation");
        }
        scales.push(d.sqrt());
    }
    scales.sort_by(f64::total_cmp);
    let (mask, window) = coverage(&code, View::Fit, 0)?;
    Ok(Some(Truth {
        scales,
        window,
        mask,
    }))
}

/// `a` grown by one pixel in every direction (3×3 neighbourhood) on an `n × n` grid.
fn dilate(a: &[bool], n: usize) -> Vec<bool> {
    let mut out = vec![false; a.len()];
    for y in 0..n {
        for x in 0..n {
            if a[y * n + x] {
                for yy in y.saturating_sub(1)..(y + 2).min(n) {
                    for xx in x.saturating_sub(1)..(x + 2).min(n) {
                        out[yy * n + xx] = true;
                    }
                }
            }
        }
    }
    out
}

/// Share of covered pixels of either mask with a covered pixel of the other within one
/// pixel: `(|A ∩ dil B| + |B ∩ dil A|) / (|A| + |B|)`, 1 for equal masks. A plain IoU of
/// thin attractors punishes sub-pixel differences: a right fit of the Sierpiński triangle,
/// scales within 0.001, scored 0.7–0.85 at 64²–128².
fn tolerant_agreement(a: &[bool], b: &[bool], n: usize) -> f64 {
    let (da, db) = (dilate(a, n), dilate(b, n));
    let hits = a.iter().zip(&db).filter(|(x, y)| **x && **y).count()
        + b.iter().zip(&da).filter(|(x, y)| **x && **y).count();
    let total = a.iter().filter(|v| **v).count() + b.iter().filter(|v| **v).count();
    if total == 0 {
        1.0
    } else {
        hits as f64 / total as f64
    }
}

/// Coverage agreement of a fitted model with the truth ([`tolerant_agreement`]), and the
/// largest difference of the sorted scales (∞ when the map counts differ).
fn compare(truth: &Truth, model: &EmModel) -> anyhow::Result<(f64, f64)> {
    let code = model.to_code(None)?;
    let (mask, _) = coverage(&code, truth.window, 0)?;
    let iou = tolerant_agreement(&truth.mask, &mask, TRUTH_SIZE as usize);
    let mut scales: Vec<f64> = model.components.iter().map(|c| c.s).collect();
    scales.sort_by(f64::total_cmp);
    let err = if scales.len() == truth.scales.len() {
        scales
            .iter()
            .zip(&truth.scales)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    } else {
        f64::INFINITY
    };
    Ok((iou, err))
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let start = Instant::now();
    if a.runs == 0 {
        bail!("--runs must be at least 1");
    }
    let (data, source) = load_points(&a)?;
    if let Some(p) = &a.save_data {
        data.save(p)?;
    }
    let (train, test) = data.split(a.heldout, a.seed)?;
    if train.len() < a.k {
        bail!(
            "{} training points (after holding out {}) for --k {}: give at least as many \
             points as components, or lower --k / --heldout",
            train.len(),
            test.len(),
            a.k
        );
    }
    let heldout = (!test.is_empty()).then_some(&test);
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("creating {}", a.output.display()))?;
    eprintln!(
        "{source}: {} points in {} dimensions ({} training, {} held out)",
        data.len(),
        data.dim(),
        train.len(),
        test.len()
    );
    let truth = load_truth(&a, data.dim())?;
    if !a.sweep_pool.is_empty() {
        return sweep(&a, &train, heldout, truth.as_ref(), &source, start);
    }

    // EM runs; the best held-out likelihood wins.
    let mut runs = Vec::new();
    let mut best: Option<(f64, usize, EmFit)> = None;
    for r in 0..a.runs {
        let cfg = em_config(&a, mix_seed(a.seed, r as u64), a.pool);
        let t0 = Instant::now();
        let pb = progress::bar(
            cfg.iterations as u64,
            &format!("EM run {}/{}", r + 1, a.runs),
        );
        let result = fit(&train, heldout, &cfg, &mut |e| {
            if let Event::Iteration(rec) = e {
                pb.inc(1);
                if let Some(h) = rec.heldout_log_likelihood {
                    pb.set_message(format!("held-out {h:.3}"));
                }
            }
        })
        .with_context(|| format!("EM run {r}"))?;
        pb.finish_and_clear();
        let score_set = heldout.unwrap_or(&train);
        let score = result.model.mean_log_likelihood(score_set)?;
        let train_ll = result.model.mean_log_likelihood(&train)?;
        let secs = t0.elapsed().as_secs_f64();
        let against = truth
            .as_ref()
            .map(|t| compare(t, &result.model))
            .transpose()?;
        eprintln!(
            "run {r}: held-out {score:.4} nats/point, train {train_ll:.4}, v_D {:.3}, mean depth {:.2}, {}converged{}, {secs:.1} s",
            result.model.deepest_weight(),
            result.model.mean_depth(),
            if result.converged { "" } else { "not " },
            against.map_or(String::new(), |(iou, e)| format!(
                ", agreement with the truth {iou:.3}, scales within {e:.4}"
            ))
        );
        runs.push(json!({
            "truth_agreement": against.map(|v| v.0), "truth_scale_error": against.map(|v| v.1),
            "run": r, "seed": cfg.seed, "heldout_log_likelihood": score,
            "train_log_likelihood": train_ll, "converged": result.converged,
            "deepest_weight": result.model.deepest_weight(), "mean_depth": result.model.mean_depth(),
            "chosen_candidate": result.chosen, "seconds": secs,
            "repairs": {"dead_components": result.degeneracy_counts()[0],
                        "undetermined_rotations": result.degeneracy_counts()[1],
                        "clamped_scales": result.degeneracy_counts()[2],
                        "non_finite": result.degeneracy_counts()[3]},
        }));
        if best.as_ref().is_none_or(|b| score > b.0) {
            best = Some((score, r, result));
        }
    }
    let (best_score, best_run, result) = best.expect("at least one run");
    let model = &result.model;

    // Outputs: the code, the history, the plots.
    let name = format!("em-k{}-d{}", a.k, a.depth);
    let mut code = model.to_code(Some(&name))?;
    code.meta.insert("source".into(), source.clone().into());
    code.meta
        .insert("heldout_log_likelihood".into(), best_score.into());
    code.meta
        .insert("converged".into(), result.converged.into());
    let code_path = a.output.join("code.json");
    code.save(&code_path)?;
    write_history(&a.output.join("history.csv"), &result)?;
    plot_history(&a.output.join("loglik.png"), &result, &name)?;
    let samples = model.sample(3000.min(data.len().max(500)), mix_seed(a.seed, 0x5a))?;
    plot_scatter(&a.output.join("scatter.png"), &data, &samples, &name)?;
    if data.dim() == 2 {
        let maps = code.affine2()?;
        let probs = code.evaluation_probabilities()?;
        let cfg = RenderConfig {
            width: 512,
            height: 512,
            points: a.render_points,
            mode: RenderMode::Density,
            seed: a.seed,
            ..RenderConfig::default()
        };
        match render(&maps, &probs, &cfg, None) {
            Ok(r) => r.save_png(&a.output.join("render.png"), BitDepth::Eight, true)?,
            Err(e) => eprintln!("render skipped: {e}"),
        }
    }

    // Gaussian-mixture baselines in the same units.
    let em_params = model.parameter_count();
    let counts = gmm_counts(&a, data.dim(), em_params);
    let mut gmms = Vec::new();
    for (cov, m) in counts {
        if m > train.len() {
            continue;
        }
        let g = Gmm::fit(
            &train,
            &GmmConfig {
                components: m,
                covariance: cov,
                seed: a.seed,
                ..GmmConfig::default()
            },
        )?;
        let ho = heldout.map(|h| g.mean_log_likelihood(h)).transpose()?;
        let tr = g.mean_log_likelihood(&train)?;
        eprintln!(
            "GMM {:>9} M = {m:>3} ({:>4} parameters): held-out {}, train {tr:.4}",
            format!("{cov:?}").to_lowercase(),
            g.parameter_count(),
            ho.map_or("-".into(), |v| format!("{v:.4}"))
        );
        gmms.push(json!({
            "covariance": format!("{cov:?}").to_lowercase(), "components": m,
            "parameters": g.parameter_count(), "heldout_log_likelihood": ho,
            "train_log_likelihood": tr, "iterations": g.iterations(),
        }));
    }
    let report = json!({
        "data": {"source": source, "dim": data.dim(), "points": data.len(),
                 "train": train.len(), "heldout": test.len()},
        "em": {"best_run": best_run, "heldout_log_likelihood": best_score,
               "train_log_likelihood": model.mean_log_likelihood(&train)?,
               "parameters": em_params, "converged": result.converged,
               "depth_weights": model.depth_weights, "weights": model.weights,
               "scales": model.components.iter().map(|c| c.s).collect::<Vec<_>>(),
               "runs": runs},
        "gmm": gmms,
        "seconds": start.elapsed().as_secs_f64(),
        "units": "mean log-likelihood per point, nats, in the data's coordinates",
    });
    write_json(&a.output.join("report.json"), &report)?;
    write_json(
        &a.output.join("config.json"),
        &json!({"args": format!("{a:?}"), "em": em_config(&a, a.seed, a.pool)}),
    )?;
    eprintln!(
        "{}: best run {best_run}, held-out {best_score:.4} nats/point ({:.1} s)",
        code_path.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Baseline component counts: `--gmm` if given, else K and the parameter-matched counts.
fn gmm_counts(a: &Args, h: usize, em_params: usize) -> Vec<(Covariance, usize)> {
    let mut out = Vec::new();
    for cov in [Covariance::Isotropic, Covariance::Full] {
        let per = match cov {
            Covariance::Isotropic => h + 2,
            Covariance::Full => h + h * (h + 1) / 2 + 1,
        };
        let mut ms: Vec<usize> = if a.gmm.is_empty() {
            // M·per − 1 parameters ≤ the IFS model's.
            vec![a.k, ((em_params + 1) / per).max(1)]
        } else {
            a.gmm.clone()
        };
        ms.sort_unstable();
        ms.dedup();
        out.extend(ms.into_iter().filter(|&m| m > 0).map(|m| (cov, m)));
    }
    out
}

fn write_json(path: &Path, v: &serde_json::Value) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(v)?;
    ifslab::io::write_atomic(path, text.as_bytes())?;
    Ok(())
}

fn write_history(path: &Path, f: &EmFit) -> anyhow::Result<()> {
    let mut s = String::from(
        "iteration,batch_log_likelihood,heldout_log_likelihood,deepest_weight,mean_depth,accepted,repairs\n",
    );
    for r in &f.history {
        s.push_str(&format!(
            "{},{},{},{},{},{},{}\n",
            r.iteration,
            r.batch_log_likelihood,
            r.heldout_log_likelihood
                .map_or(String::new(), |v| v.to_string()),
            r.deepest_weight,
            r.mean_depth,
            r.accepted,
            r.degeneracies.len()
        ));
    }
    ifslab::io::write_atomic(path, s.as_bytes())?;
    Ok(())
}

fn plot_history(path: &Path, f: &EmFit, name: &str) -> anyhow::Result<()> {
    let batch: Vec<(f64, f64)> = f
        .history
        .iter()
        .map(|r| (r.iteration as f64 + 1.0, r.batch_log_likelihood))
        .collect();
    let held: Vec<(f64, f64)> = f
        .history
        .iter()
        .filter_map(|r| {
            r.heldout_log_likelihood
                .map(|v| (r.iteration as f64 + 1.0, v))
        })
        .collect();
    let mut series = vec![Series {
        name: "minibatch (before update)",
        points: batch,
    }];
    if !held.is_empty() {
        series.push(Series {
            name: "held-out",
            points: held,
        });
    }
    line_chart(
        path,
        &format!("{name}: log-likelihood"),
        "iteration",
        "nats per point",
        &series,
        false,
    )
}

/// 2-D: the points as they are; 3-D: projected on the data's two principal axes.
fn plot_scatter(
    path: &Path,
    data: &PointSet,
    samples: &PointSet,
    name: &str,
) -> anyhow::Result<()> {
    let h = data.dim();
    if !(h == 2 || h == 3) {
        return Ok(());
    }
    let axes = data.principal_axes();
    let project = |p: &[f64]| -> (f64, f64) {
        if h == 2 {
            (p[0], p[1])
        } else {
            let dot = |ax: &[f64]| p.iter().zip(ax).map(|(a, b)| a * b).sum::<f64>();
            (dot(&axes[0]), dot(&axes[1]))
        }
    };
    let n = samples.len();
    let shown = data.head(n);
    let title = if h == 2 {
        format!("{name}: data vs model samples")
    } else {
        format!("{name}: data vs model samples (principal-axes projection)")
    };
    scatter(
        path,
        &title,
        &[
            Series {
                name: "data",
                points: shown.iter().map(project).collect(),
            },
            Series {
                name: "model samples",
                points: samples.iter().map(project).collect(),
            },
        ],
        1,
    )
}

/// Fig. 5b: proportion of runs that converge (v_D ≥ 0.95) per pre-selection pool size.
fn sweep(
    a: &Args,
    train: &PointSet,
    heldout: Option<&PointSet>,
    truth: Option<&Truth>,
    source: &str,
    start: Instant,
) -> anyhow::Result<()> {
    if a.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    let mut cfgs = Vec::new();
    for &p in &a.sweep_pool {
        if p == 0 {
            bail!("--sweep-pool sizes must be at least 1");
        }
        for r in 0..a.repeats {
            cfgs.push(em_config(
                a,
                mix_seed(a.seed, (p as u64) << 20 | r as u64),
                p,
            ));
        }
    }
    let pb = progress::bar(cfgs.len() as u64, "runs");
    let failed = AtomicBool::new(false);
    let t0 = Instant::now();
    let results = fit_all(train, heldout, &cfgs, &|_| pb.inc(1));
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let mut csv = String::from(
        "pool,repeat,seed,converged,deepest_weight,mean_depth,heldout_log_likelihood,scales,truth_agreement,truth_scale_error\n",
    );
    let mut summary = Vec::new();
    let mut curve = Vec::new();
    for (pi, &p) in a.sweep_pool.iter().enumerate() {
        let mut conv = 0;
        let mut right = 0;
        let mut both = 0;
        let mut lls = Vec::new();
        for r in 0..a.repeats {
            let i = pi * a.repeats + r;
            match &results[i] {
                Ok(f) => {
                    let ll = heldout
                        .map(|h| f.model.mean_log_likelihood(h))
                        .transpose()?
                        .unwrap_or(f64::NAN);
                    let against = truth.map(|t| compare(t, &f.model)).transpose()?;
                    let is_right = against.is_some_and(|(iou, _)| iou >= RIGHT_AGREEMENT);
                    conv += usize::from(f.converged);
                    right += usize::from(is_right);
                    both += usize::from(is_right && f.converged);
                    lls.push(ll);
                    let mut scales: Vec<f64> = f.model.components.iter().map(|c| c.s).collect();
                    scales.sort_by(f64::total_cmp);
                    let scales: Vec<String> = scales.iter().map(|v| format!("{v:.5}")).collect();
                    csv.push_str(&format!(
                        "{p},{r},{},{},{},{},{ll},{},{},{}\n",
                        cfgs[i].seed,
                        f.converged,
                        f.model.deepest_weight(),
                        f.model.mean_depth(),
                        scales.join(";"),
                        against.map_or(String::new(), |v| v.0.to_string()),
                        against.map_or(String::new(), |v| v.1.to_string()),
                    ));
                }
                Err(e) => {
                    failed.store(true, Ordering::Relaxed);
                    eprintln!("pool {p}, repeat {r}: {e}");
                    csv.push_str(&format!("{p},{r},{},false,,,,,,\n", cfgs[i].seed));
                }
            }
        }
        let prop = conv as f64 / a.repeats as f64;
        lls.sort_by(f64::total_cmp);
        let median = lls.get(lls.len() / 2).copied().unwrap_or(f64::NAN);
        eprintln!(
            "pool {p:>3}: {conv}/{} converged ({prop:.3}){}, median held-out {median:.4}",
            a.repeats,
            if truth.is_some() {
                format!(", {right} right (agreement ≥ {RIGHT_AGREEMENT}), {both} both")
            } else {
                String::new()
            }
        );
        curve.push((p as f64, prop));
        summary.push(json!({"pool": p, "converged": conv, "repeats": a.repeats,
                            "proportion": prop, "median_heldout_log_likelihood": median,
                            "right": truth.map(|_| right), "converged_and_right": truth.map(|_| both)}));
    }
    ifslab::io::write_atomic(&a.output.join("pool_sweep.csv"), csv.as_bytes())?;
    write_json(
        &a.output.join("pool_sweep.json"),
        &json!({"source": source, "k": a.k, "depth": a.depth, "iterations": a.iterations,
                "batch": a.batch, "preselect_depth": a.preselect_depth,
                "preselect_iterations": a.preselect_iterations, "update": format!("{:?}", a.update),
                "em": em_config(a, a.seed, a.sweep_pool[0]), "truth": a.truth, "right_agreement": RIGHT_AGREEMENT,
                "results": summary, "seconds": secs, "total_seconds": start.elapsed().as_secs_f64()}),
    )?;
    line_chart(
        &a.output.join("pool_sweep.png"),
        &format!("proportion converged ({} runs per pool size)", a.repeats),
        "pool size",
        "proportion converged",
        &[Series {
            name: "converged",
            points: curve,
        }],
        false,
    )?;
    if failed.load(Ordering::Relaxed) {
        eprintln!("some runs failed; see above");
    }
    eprintln!("sweep: {} runs in {secs:.1} s", cfgs.len());
    Ok(())
}
