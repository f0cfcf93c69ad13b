//! Running an image inversion from the command line and writing what a user looks at: the
//! recovered code, renders, a zoom strip, the loss curve, a summary.
//!
//! `mod.rs` runs it (one run, or the best of several, each resumable); `target.rs` prepares
//! and stores the framed target a run fits and the ground truth it is scored against;
//! `outputs.rs` writes what a finished run shows — the code file, renders, the zoom strip,
//! the loss curve — and scores a recovered code against the one that drew its target.

mod outputs;
mod target;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use crate::error::{Context, IoContext};
use ifslab::image::Image;
use ifslab::loss::lpips::LPIPS_MIN_SIDE;
use ifslab::loss::{Lpips, default_lpips_weights_path};
use ifslab::metrics::{EVAL_BORDER_FRACTION, ImageMetrics, border_crop_rect, paper_metrics};
use ifslab::model::{Affine2, IfsCode, Window};
use ifslab::render::image_io::{BitDepth, save_grey_png};
use ifslab::render::{RenderConfig, View, Zoom, render};
use ifslab_strategies::driver::plan::{CHECKPOINT_FILE, START_FILE};
use ifslab_strategies::problems::image::{
    BestOfStarts, FIT_FILE, FRAMED_TARGET_FILE, FitFile, Fitted, InitKind, InversionConfig,
    InversionOutcome, Recovered, TARGET_READING_FILE, TargetReading, ensure_new_run_dir,
    load_framed_picture_with, load_framed_target, load_target, run_inversion, save_framed_target,
};
use plotters::prelude::*;
use serde::Serialize;

use crate::codes::resolve_code;
use crate::plot::{Series, ensure_font, line_chart};
use crate::progress::{Progress, ProgressObserver};
use crate::runs::legs::{LegProgress, leg_resumes, refuse_existing_legs};

pub use outputs::{TRUTH_SIZE, TruthScore, loss_plot, redraw_pictures, truth_score, zoom_strip};
use outputs::{ZOOM_STRIP_FILE, draw_zoom_strip, save_square_grey, write_outputs};
use target::{Framed, eval_config, new_run_dir};
pub use target::{ground_truth, prepare_target, run_target};

/// The resolved config inside a run folder.
pub const CONFIG_FILE: &str = "config.toml";

/// The per-iteration log inside a run folder (what a sweep's pack keeps as columns).
pub const LOG_FILE: &str = "log.csv";

/// Points per evaluation render (the chaotic-splatting paper's 50 M per view).
pub const EVAL_POINTS: u64 = 50_000_000;
/// Binary supersampling per side of evaluation renders (the paper's 8×8).
pub const EVAL_SUPERSAMPLE: u32 = 8;

/// What `summary.json` holds.
#[derive(Serialize)]
pub struct Summary {
    /// Strategy name.
    pub strategy: String,
    /// Iterations completed.
    pub iterations: u64,
    /// Wall-clock seconds of the optimisation (this process).
    pub seconds: f64,
    /// Loss at the last iteration.
    pub final_loss: f64,
    /// IoU of the `> 0` masks (12.5% border cropped).
    pub iou: f64,
    /// F1 (Dice) of the `> 0` masks (12.5% border cropped).
    pub f1: f64,
    /// PSNR on the foreground pixels.
    pub psnr: f64,
    /// SSIM on the foreground pixels.
    pub ssim: f64,
    /// LPIPS (AlexNet) of the cropped render against the cropped target; absent without
    /// weights or below 31 pixels a side (`lpips_metric_note` says which).
    pub lpips: Option<f64>,
    /// Why the LPIPS metric is absent, if it is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lpips_metric_note: Option<String>,
    /// Why LPIPS was not used in the loss, if it was not.
    pub lpips_note: Option<String>,
    /// Which θ the run returned — the last iterate or the best one it saw — and their
    /// objectives on fixed random streams.
    pub selection: ifslab_strategies::problems::image::Selection,
    /// For a suite target: the paper's metrics over the suite's views (full view and
    /// zoomed-in patches) and their means.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub suite: Option<crate::suite::SuiteScore>,
    /// For an image target drawn by a known code (`target.truth`): the recovered code
    /// against that code ([`truth_score`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<TruthScore>,
    /// What the IoU polish did (`model.polish`), where it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub polish: Option<ifslab_strategies::problems::image::polish::Polished>,
    /// With several whole runs (`best_of`), every one of them, in the order they ran; the
    /// one with the highest `ssim` is the run's result (the first of equals), and every
    /// other number of this summary is its.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub legs: Vec<InvertLegSummary>,
}

/// One of the whole runs of a run that keeps the best of several (`best_of`).
#[derive(Clone, Debug, Serialize)]
pub struct InvertLegSummary {
    /// Its seed.
    pub seed: u64,
    /// Its folder inside the run's (`run-0`, `run-1`, …).
    pub folder: String,
    /// Its loss at the last iteration.
    pub final_loss: f64,
    /// IoU of its render against the target.
    pub iou: f64,
    /// SSIM of its render against the target (what chooses among them).
    pub ssim: f64,
    /// IoU against the true code, when given (`target.truth`; reported only, never used to
    /// choose).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_iou: Option<f64>,
    /// Whether it is the run's result.
    pub chosen: bool,
}

/// The folder of a run's `i`-th whole run where it keeps the best of several (`best_of`).
pub fn leg_folder(i: usize) -> String {
    format!("run-{i}")
}

/// The files of the kept whole run that a best-of run shows where a single run's would be.
const KEPT_FILES: [&str; 9] = [
    "code.json",
    FIT_FILE,
    "render.png",
    ZOOM_STRIP_FILE,
    "loss.png",
    "truth.png",
    "target.png",
    LOG_FILE,
    START_FILE,
];

impl Summary {
    /// The paper's metrics in one line: IoU, F1, PSNR, SSIM and LPIPS (when measured).
    pub fn scores(&self) -> String {
        let lpips = self
            .lpips
            .map_or_else(String::new, |v| format!(", LPIPS {v:.3}"));
        let suite = self.suite.as_ref().map_or_else(String::new, |s| {
            let lpips = s
                .lpips
                .map_or_else(String::new, |v| format!(", LPIPS {v:.3}"));
            format!(
                "; over the suite's {} views: F1 {:.3}, IoU {:.3}, PSNR {:.2} dB, SSIM {:.3}{lpips}",
                s.views.len(),
                s.f1,
                s.iou,
                s.psnr,
                s.ssim
            )
        });
        let truth = self.truth.as_ref().map_or_else(String::new, |t| {
            format!(
                "; against the true code: IoU {:.3}, F1 {:.3}, SSIM {:.3}",
                t.iou, t.f1, t.ssim
            )
        });
        format!(
            "IoU {:.3}, F1 {:.3}, PSNR {:.2} dB, SSIM {:.3}{lpips}{suite}{truth}",
            self.iou, self.f1, self.psnr, self.ssim
        )
    }

    /// What ran, for a headline: `400 iterations of cold_hybrid`, or with several whole
    /// runs `the best of 3 runs (run-1 kept) of 400 iterations of cold_hybrid`.
    pub fn work(&self) -> String {
        let kept = self.legs.iter().find(|l| l.chosen);
        match kept {
            Some(k) if self.legs.len() > 1 => format!(
                "the best of {} runs ({} kept) of {} iterations of {}",
                self.legs.len(),
                k.folder,
                self.iterations,
                self.strategy
            ),
            _ => format!("{} iterations of {}", self.iterations, self.strategy),
        }
    }
}

/// Runs (or resumes) the inversion of `cfg` into `dir` and writes every output: the
/// resolved config, the framed target, checkpoints and `log.csv` as it goes, then the code,
/// renders, zoom strip, loss plot and `summary.json`. Iterations are reported to `progress`.
///
/// With several whole runs (`best_of`), each runs in a folder of the run ([`leg_folder`]:
/// its own resolved config, target, checkpoints, log and outputs, resumed where it stopped),
/// one after another, and the one whose render agrees best with the target (SSIM) is kept:
/// its code, renders, log and start are copied where a single run's would be, and
/// `summary.json` is its summary with every run listed (`legs`).
pub fn run_and_report(
    cfg: &InversionConfig,
    dir: &Path,
    resume: bool,
    progress: Box<dyn Progress>,
) -> crate::Result<Summary> {
    // A folder holding one run at its top (written before `best_of`, or with `best_of = 1`)
    // resumes as that one run.
    if cfg.best_of > 1 && !(resume && dir.join(CHECKPOINT_FILE).is_file()) {
        return run_best_of(cfg, dir, resume, progress);
    }
    run_one(cfg, dir, resume, progress, None)
}

/// The whole runs of `cfg` at seeds `seed`, `seed + 1`, … (see [`run_and_report`]).
fn run_best_of(
    cfg: &InversionConfig,
    dir: &Path,
    resume: bool,
    progress: Box<dyn Progress>,
) -> crate::Result<Summary> {
    cfg.validate()?;
    let _lock = crate::runs::lock::lock_run_dir(dir)?;
    // The target is prepared once, in the run's folder, and every run fits it (a run
    // resumed after the picture is gone still has it).
    let target = if resume {
        run_target(cfg, dir)?
    } else {
        ensure_new_run_dir(dir)?;
        refuse_existing_legs(dir, &leg_folder(0))?;
        new_run_dir(cfg, dir, None)?
    };
    let reading_file = dir.join(TARGET_READING_FILE);
    let reading = reading_file
        .is_file()
        .then(|| TargetReading::load(&reading_file))
        .transpose()?;
    let n = cfg.best_of as usize;
    let progress: Arc<dyn Progress> = Arc::from(progress);
    progress.start(cfg.strategy.name(), cfg.iterations * n as u64);
    let clock = Instant::now();
    let mut legs: Vec<InvertLegSummary> = Vec::with_capacity(n);
    let mut best: Option<(usize, Summary)> = None;
    for i in 0..n {
        let seed = cfg.seed.wrapping_add(i as u64);
        let mut leg_cfg = InversionConfig {
            best_of: 1,
            best_of_starts: BestOfStarts::Seeded,
            seed,
            output: None,
            ..cfg.clone()
        };
        // Ranked starts: every run reads the one collage search at the inversion's start
        // seed and takes its own rank of it.
        if cfg.best_of_starts == BestOfStarts::Ranked && ranks_collage_starts(cfg) {
            leg_cfg.model.init_seed = Some(cfg.model.init_seed.unwrap_or(cfg.seed));
            leg_cfg.model.start_rank = i;
        }
        let folder = leg_folder(i);
        let leg_dir = dir.join(&folder);
        let leg_progress = LegProgress::new(progress.clone(), i, n, cfg.iterations);
        let s = run_one(
            &leg_cfg,
            &leg_dir,
            leg_resumes(&leg_dir, resume),
            Box::new(leg_progress),
            Some((&target, reading.as_ref())),
        )
        .with_context(|| format!("the run at seed {seed} ({folder})"))?;
        legs.push(InvertLegSummary {
            seed,
            folder,
            final_loss: s.final_loss,
            iou: s.iou,
            ssim: s.ssim,
            truth_iou: s.truth.as_ref().map(|t| t.iou),
            chosen: false,
        });
        if best.as_ref().is_none_or(|(_, b)| s.ssim > b.ssim) {
            best = Some((i, s));
        }
    }
    let (chosen, mut summary) = best.context("`best_of` asks for no run")?;
    legs[chosen].chosen = true;
    let kept = dir.join(leg_folder(chosen));
    // Only the kept run's zoom strip is drawn (the runs draw none: four deep renders each).
    if !kept.join(ZOOM_STRIP_FILE).is_file() {
        draw_zoom_strip(&kept)?;
    }
    for name in KEPT_FILES {
        let from = kept.join(name);
        if from.is_file() {
            ifslab::io::write_atomic(
                &dir.join(name),
                &std::fs::read(&from).doing("reading", &from)?,
            )?;
        }
    }
    summary.seconds = clock.elapsed().as_secs_f64();
    summary.legs = legs;
    ifslab::io::write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    Ok(summary)
}

/// Whether the runs of `cfg` start from the collage search's ranked starts where
/// `best_of_starts = "ranked"`: a collage start (`model.init`), no start code, and every run
/// at rank 0 (the leg sets the rank).
fn ranks_collage_starts(cfg: &InversionConfig) -> bool {
    cfg.model.init == InitKind::Collage
        && cfg.model.init_code.is_none()
        && cfg.model.start_rank == 0
}

/// One whole run of `cfg` into `dir` (see [`run_and_report`]); with `framed`, one of a
/// best-of run's runs: a fresh one fits that target (prepared once for all the runs), and
/// it draws no zoom strip (the kept run's is drawn once it is chosen).
fn run_one(
    cfg: &InversionConfig,
    dir: &Path,
    resume: bool,
    progress: Box<dyn Progress>,
    framed: Option<Framed>,
) -> crate::Result<Summary> {
    let _lock = crate::runs::lock::lock_run_dir(dir)?;
    let size = cfg.target.size;
    let target = if resume {
        run_target(cfg, dir)?
    } else {
        ensure_new_run_dir(dir)?;
        new_run_dir(cfg, dir, framed)?
    };
    save_square_grey(&dir.join("target.png"), &target.values, size)?;
    progress.start(cfg.strategy.name(), cfg.iterations);
    let started = Instant::now();
    let outcome = run_inversion(
        cfg,
        target.clone(),
        dir,
        resume,
        vec![Box::new(ProgressObserver::new(progress))],
    )?;
    let (metrics, lpips_metric_note) =
        write_outputs(cfg, dir, &outcome, &target.values, framed.is_none())?;
    let seconds = started.elapsed().as_secs_f64();
    let suite = match (&cfg.target.suite, cfg.target.index) {
        (Some(suite_dir), Some(index)) => {
            let manifest = crate::suite::load(suite_dir)?;
            let net = Lpips::try_load_default()?;
            Some(crate::suite::score_maps(
                suite_dir,
                &manifest,
                index,
                outcome.result.as_ref(),
                net.as_ref(),
            )?)
        }
        _ => None,
    };
    let truth = match &cfg.target.truth {
        Some(spec) => Some(truth_score(spec, outcome.result.as_ref(), cfg.seed, dir)?),
        None => None,
    };
    let summary = Summary {
        strategy: cfg.strategy.name().into(),
        iterations: outcome.iterations,
        seconds,
        final_loss: outcome.final_loss,
        iou: metrics.iou,
        f1: metrics.f1,
        psnr: metrics.psnr,
        ssim: metrics.ssim,
        lpips: metrics.lpips,
        lpips_metric_note,
        lpips_note: outcome.lpips_note.clone(),
        selection: outcome.selection.clone(),
        suite,
        truth,
        polish: outcome.polished.clone(),
        legs: Vec::new(),
    };
    ifslab::io::write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    Ok(summary)
}

/// The run folder named by `-o`, the config, or a default.
pub fn output_dir(cli: Option<PathBuf>, cfg: &InversionConfig, default: &str) -> PathBuf {
    cli.or_else(|| cfg.output.clone())
        .unwrap_or_else(|| PathBuf::from(default))
}
