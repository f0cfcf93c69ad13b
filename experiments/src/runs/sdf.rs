//! Segment-pattern fit runs (`problem = "sdf"`, `ifslab sdf fit`): config → run folder with
//! the resolved config, the framed target (`target.npy` bit for bit, `target.png` to look
//! at), checkpoints and `log.csv` as it goes, then the final render, the fitted pattern
//! (a pattern file whose `meta` holds the view, depth and σ the fit used, so `ifslab sdf
//! render` draws it as the fit saw it), the loss plot and `summary.json`.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use ifslab::model::segment::PatternFile;
use ifslab::render::image_io::{BitDepth, save_grey_png};
use ifslab_strategies::problems::image::{
    FRAMED_TARGET_FILE, ensure_new_run_dir, load_framed_target, load_target, save_framed_target,
};
use ifslab_strategies::problems::sdf::{INK, SdfConfig, run_sdf, sdf_problem};
use serde::Serialize;

use crate::progress::{Progress, ProgressObserver};
use crate::runs::inversion::{CONFIG_FILE, loss_plot};

/// The fitted pattern inside a run folder.
pub const FITTED_PATTERN_FILE: &str = "pattern.json";

/// What `summary.json` holds.
#[derive(Clone, Debug, Serialize)]
pub struct SdfSummary {
    /// The pattern fitted (its name).
    pub pattern: String,
    /// The strategy.
    pub strategy: String,
    /// Iterations completed.
    pub iterations: u64,
    /// Wall-clock seconds of this process's part of the run.
    pub seconds: f64,
    /// Seconds per iteration of this process's part.
    pub seconds_per_iteration: f64,
    /// Loss of the returned control points.
    pub loss: f64,
    /// Plain MSE between the final render and the target.
    pub mse: f64,
    /// IoU of the render and the target thresholded at 0.5.
    pub iou: f64,
    /// `last` or `start` (see `SdfOutcome::returned`).
    pub returned: String,
    /// The returned control points.
    pub points: Vec<[f64; 2]>,
}

impl SdfSummary {
    /// A line for the terminal.
    pub fn headline(&self) -> String {
        format!(
            "{} iterations of {} on `{}` in {:.1} s ({:.1} ms/iteration), IoU {:.3}, MSE {:.5}",
            self.iterations,
            self.strategy,
            self.pattern,
            self.seconds,
            1e3 * self.seconds_per_iteration,
            self.iou,
            self.mse
        )
    }
}

/// Runs (or resumes) the fit of `cfg` into `dir` and writes every output.
pub fn run(
    cfg: &SdfConfig,
    dir: &Path,
    resume: bool,
    progress: Box<dyn Progress>,
) -> anyhow::Result<SdfSummary> {
    cfg.validate()?;
    let size = cfg.size;
    let target: Vec<f32> = if resume {
        load_framed_target(&dir.join(FRAMED_TARGET_FILE), size)?
    } else {
        ensure_new_run_dir(dir)?;
        let t = load_target(&cfg.target, size, cfg.polarity)?;
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let resolved = crate::runs::RunConfig::Sdf(Box::new(cfg.clone())).to_table()?;
        ifslab::io::write_atomic(
            &dir.join(CONFIG_FILE),
            toml::to_string_pretty(&resolved)?.as_bytes(),
        )?;
        save_framed_target(&dir.join(FRAMED_TARGET_FILE), &t, size)?;
        t
    };
    save_grey_png(
        &dir.join("target.png"),
        &target,
        size as u32,
        size as u32,
        BitDepth::Eight,
        true,
    )?;
    let ink: Vec<f64> = target.iter().map(|&v| v as f64).collect();
    let done_before = if resume {
        ifslab_strategies::driver::checkpoint_iteration(dir)?
    } else {
        0
    };
    progress.start(cfg.strategy.name(), cfg.iterations);
    let clock = Instant::now();
    let out = run_sdf(
        cfg,
        ink.clone(),
        dir,
        resume,
        vec![Box::new(ProgressObserver::new(progress))],
    )?;
    let seconds = clock.elapsed().as_secs_f64();
    let problem = sdf_problem(cfg, ink.clone())?;
    let fitted = problem.pattern_at(&out.theta)?;
    let image = problem.image(&out.theta)?;
    let img32: Vec<f32> = image.iter().map(|&v| v as f32).collect();
    save_grey_png(
        &dir.join("render.png"),
        &img32,
        size as u32,
        size as u32,
        BitDepth::Eight,
        true,
    )?;
    let meta = serde_json::json!({
        "view": problem.view(),
        "depth": cfg.depth,
        "sigma": cfg.sigma,
        "loss": out.loss,
        "iterations": out.iterations,
    });
    PatternFile::of(&fitted, Some(meta)).save(dir.join(FITTED_PATTERN_FILE))?;
    loss_plot(&out.log, &dir.join("loss.png"))?;
    let mse = image
        .iter()
        .zip(&ink)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / image.len() as f64;
    let pm: Vec<bool> = image.iter().map(|&v| v >= INK).collect();
    let tm: Vec<bool> = ink.iter().map(|&v| v >= INK).collect();
    let iou = ifslab::metrics::iou(&pm, &tm)?;
    // Only this process's iterations were timed.
    let fresh = out.iterations.saturating_sub(done_before).max(1);
    let summary = SdfSummary {
        pattern: fitted.name().to_owned(),
        strategy: cfg.strategy.name().to_owned(),
        iterations: out.iterations,
        seconds,
        seconds_per_iteration: out.seconds / fresh as f64,
        loss: out.loss,
        mse,
        iou,
        returned: out.returned.to_owned(),
        points: fitted.points().to_vec(),
    };
    ifslab::io::write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    Ok(summary)
}
