//! What a fitting run writes: the kept fit's code, its history and plots, a render, and
//! the Gaussian-mixture baselines in `report.json`.

use std::path::Path;
use std::time::Instant;

use ifslab::chaos::mix_seed;
use ifslab::model::IfsCode;
use ifslab::render::image_io::BitDepth;
use ifslab::render::{RenderConfig, RenderMode, render};
use ifslab_strategies::problems::em::{Covariance, EmFit, Gmm, GmmConfig, PointSet};
use serde_json::json;

use super::{Data, PointsConfig};
use crate::plot::{Series, line_chart, scatter};
use crate::progress::Progress;

/// What the outputs add to the summary.
pub(super) struct Written {
    /// The best held-out log-likelihood among the GMM baselines.
    pub best_gmm: Option<f64>,
    /// Each baseline's held-out log-likelihood by name (`isotropic_8`, `full_16`).
    pub gmm: std::collections::BTreeMap<String, f64>,
}

/// Writes the kept fit `result` (run `best_run`, held-out score `best_score`) and its
/// baselines into `dir`; `runs` are the per-run records of `report.json`.
#[allow(clippy::too_many_arguments)]
pub(super) fn write_fit(
    cfg: &PointsConfig,
    dir: &Path,
    data: &Data,
    result: &EmFit,
    best_score: f64,
    best_run: usize,
    runs: Vec<serde_json::Value>,
    started: Instant,
    progress: &dyn Progress,
) -> crate::Result<Written> {
    let (train, heldout) = (&data.train, data.heldout());
    let model = &result.model;
    let name = format!("em-k{}-d{}", cfg.k, cfg.depth);
    let mut code = model.to_code(Some(&name))?;
    code.meta
        .insert("source".into(), data.source.clone().into());
    code.meta
        .insert("heldout_log_likelihood".into(), best_score.into());
    code.meta
        .insert("converged".into(), result.converged.into());
    let code_path = dir.join("code.json");
    code.save(&code_path)?;
    write_history(&dir.join("history.csv"), result)?;
    plot_history(&dir.join("loglik.png"), result, &name)?;
    let samples = model.sample(3000.min(data.all.len().max(500)), mix_seed(cfg.seed, 0x5a))?;
    plot_scatter(&dir.join("scatter.png"), &data.all, &samples, &name)?;
    if data.all.dim() == 2
        && let Some(note) = render_fit(cfg, dir, &code)?
    {
        progress.message(&note);
    }

    // Gaussian-mixture baselines in the same units.
    let em_params = model.parameter_count();
    let mut gmms = Vec::new();
    let mut best_gmm: Option<f64> = None;
    let mut gmm_by_name = std::collections::BTreeMap::new();
    for (cov, m) in gmm_counts(cfg, data.all.dim(), em_params) {
        if m > train.len() {
            continue;
        }
        let g = Gmm::fit(
            train,
            &GmmConfig {
                components: m,
                covariance: cov,
                seed: cfg.seed,
                ..GmmConfig::default()
            },
        )?;
        let ho = heldout.map(|h| g.mean_log_likelihood(h)).transpose()?;
        let tr = g.mean_log_likelihood(train)?;
        progress.message(&format!(
            "GMM {:>9} M = {m:>3} ({:>4} parameters): held-out {}, train {tr:.4}",
            format!("{cov:?}").to_lowercase(),
            g.parameter_count(),
            ho.map_or("-".into(), |v| format!("{v:.4}"))
        ));
        if let Some(v) = ho {
            best_gmm = Some(best_gmm.map_or(v, |b| b.max(v)));
            gmm_by_name.insert(format!("{}_{m}", format!("{cov:?}").to_lowercase()), v);
        }
        gmms.push(json!({
            "covariance": format!("{cov:?}").to_lowercase(), "components": m,
            "parameters": g.parameter_count(), "heldout_log_likelihood": ho,
            "train_log_likelihood": tr, "iterations": g.iterations(),
        }));
    }
    let report = json!({
        "data": {"source": data.source, "dim": data.all.dim(), "points": data.all.len(),
                 "train": train.len(), "heldout": data.test.len()},
        "em": {"best_run": best_run, "heldout_log_likelihood": best_score,
               "train_log_likelihood": model.mean_log_likelihood(train)?,
               "parameters": em_params, "converged": result.converged,
               "depth_weights": model.depth_weights, "weights": model.weights,
               "scales": model.components.iter().map(|c| c.s).collect::<Vec<_>>(),
               "runs": runs},
        "gmm": gmms,
        "seconds": started.elapsed().as_secs_f64(),
        "units": "mean log-likelihood per point, nats, in the data's coordinates",
    });
    write_json(&dir.join("report.json"), &report)?;
    write_json(
        &dir.join("config.json"),
        &json!({"config": cfg.resolved()?, "em": cfg.em_config(cfg.seed, cfg.pool)}),
    )?;
    progress.message(&format!(
        "{}: best run {best_run}, held-out {best_score:.4} nats/point",
        code_path.display(),
    ));
    Ok(Written {
        best_gmm,
        gmm: gmm_by_name,
    })
}

/// Baseline component counts: `gmm` if given, else K and the parameter-matched counts.
fn gmm_counts(cfg: &PointsConfig, h: usize, em_params: usize) -> Vec<(Covariance, usize)> {
    let mut out = Vec::new();
    for cov in [Covariance::Isotropic, Covariance::Full] {
        let per = match cov {
            Covariance::Isotropic => h + 2,
            Covariance::Full => h + h * (h + 1) / 2 + 1,
        };
        let mut ms: Vec<usize> = if cfg.gmm.is_empty() {
            // M·per − 1 parameters ≤ the IFS model's.
            vec![cfg.k, ((em_params + 1) / per).max(1)]
        } else {
            cfg.gmm.clone()
        };
        ms.sort_unstable();
        ms.dedup();
        out.extend(ms.into_iter().filter(|&m| m > 0).map(|m| (cov, m)));
    }
    out
}

/// Pretty JSON, written atomically.
pub(super) fn write_json(path: &Path, v: &serde_json::Value) -> crate::Result<()> {
    let text = serde_json::to_string_pretty(v)?;
    ifslab::io::write_atomic(path, text.as_bytes())?;
    Ok(())
}

fn write_history(path: &Path, f: &EmFit) -> crate::Result<()> {
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

fn plot_history(path: &Path, f: &EmFit, name: &str) -> crate::Result<()> {
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
fn plot_scatter(path: &Path, data: &PointSet, samples: &PointSet, name: &str) -> crate::Result<()> {
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

/// The 512² density render of a 2-D fit, or why there is none.
fn render_fit(cfg: &PointsConfig, dir: &Path, code: &IfsCode) -> crate::Result<Option<String>> {
    let maps = code.affine2()?;
    let probs = code.evaluation_probabilities()?;
    let rc = RenderConfig {
        width: 512,
        height: 512,
        points: cfg.render_points,
        mode: RenderMode::Density,
        seed: cfg.seed,
        ..RenderConfig::default()
    };
    match render(&maps, &probs, &rc, None) {
        Ok(r) => {
            r.save_png(&dir.join("render.png"), BitDepth::Eight, true)?;
            Ok(None)
        }
        Err(e) => Ok(Some(format!("render skipped: {e}"))),
    }
}
