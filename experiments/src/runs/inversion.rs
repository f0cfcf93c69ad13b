//! Running an image inversion from the command line and writing what a user looks at: the
//! recovered code, renders, a zoom strip, the loss curve, a summary.

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
    BestOfStarts, FRAMED_TARGET_FILE, InitKind, InversionConfig, InversionOutcome,
    TARGET_READING_FILE, TargetReading, ensure_new_run_dir, load_framed_picture_with,
    load_framed_target, load_target, run_inversion, save_framed_target,
};
use plotters::prelude::*;
use serde::Serialize;

use crate::codes::resolve_code;
use crate::plot::{Series, ensure_font, line_chart};
use crate::progress::{Progress, ProgressObserver};
use crate::runs::legs::{LegProgress, leg_resumes, refuse_existing_legs};

/// The resolved config inside a run folder.
pub const CONFIG_FILE: &str = "config.toml";

/// The per-iteration log inside a run folder (what a sweep's pack keeps as columns).
pub const LOG_FILE: &str = "log.csv";

/// Points per evaluation render (the chaotic-splatting paper's 50 M per view).
pub const EVAL_POINTS: u64 = 50_000_000;
/// Binary supersampling per side of evaluation renders (the paper's 8×8).
pub const EVAL_SUPERSAMPLE: u32 = 8;

/// The framed target image for a config: an image file loaded and framed, or a code drawn
/// by the evaluation renderer with the differentiable renderer's supersampling (so that the
/// target's grey levels — the covered fraction of each pixel — are on the splat's scale) and
/// about 200 points per pixel (2 M to 50 M), framed the same way. What a run is *scored*
/// against is [`ground_truth`].
pub fn prepare_target(cfg: &InversionConfig) -> crate::Result<Image> {
    let size = cfg.target.size;
    if let Some(path) = &cfg.target.image {
        return load_target(path, size, cfg.target.polarity)
            .with_context(|| format!("preparing the target {}", path.display()));
    }
    let (maps, probs) = target_code(cfg)?;
    let points = (200 * (size * size) as u64).clamp(2_000_000, EVAL_POINTS);
    let rc = RenderConfig {
        points,
        supersample: cfg.renderer.supersample as u32,
        ..eval_config(size, cfg.seed)
    };
    Ok(Image::square(
        size,
        render(&maps, &probs, &rc, None)?.image.values,
    )?)
}

/// The maps and evaluation probabilities of a config's target code (a code, or a suite's).
fn target_code(cfg: &InversionConfig) -> crate::Result<(Vec<Affine2>, Vec<f64>)> {
    let code = match (&cfg.target.suite, cfg.target.index) {
        (Some(dir), Some(index)) => {
            let manifest = crate::suite::load(dir)?;
            let path = dir.join(&manifest.entry(index)?.code);
            IfsCode::load(&path).with_context(|| format!("loading {}", path.display()))?
        }
        _ => {
            let spec = cfg
                .target
                .code
                .as_deref()
                .context("the target is an image, not a code")?;
            resolve_code(spec)?
        }
    };
    let maps = code.affine2().context("the target code must be 2-D")?;
    let probs = code.evaluation_probabilities()?;
    Ok((maps, probs))
}

/// What a run is scored against: for a code target, its render at the paper's evaluation
/// setting ([`EVAL_POINTS`] points, [`EVAL_SUPERSAMPLE`]² binary supersampling); for an image,
/// the framed image itself.
pub fn ground_truth(cfg: &InversionConfig, target: &[f32]) -> crate::Result<Vec<f32>> {
    if cfg.target.image.is_some() {
        return Ok(target.to_vec());
    }
    let (maps, probs) = target_code(cfg)?;
    Ok(
        render(&maps, &probs, &eval_config(cfg.target.size, cfg.seed), None)?
            .image
            .values,
    )
}

/// The target a run in `dir` optimises against: the framed copy the run stored when it
/// started (exactly the same values, whatever the working directory and whether the original
/// file still exists); for run folders from before that copy existed, prepared again from the
/// config.
pub fn run_target(cfg: &InversionConfig, dir: &Path) -> crate::Result<Image> {
    let stored = dir.join(FRAMED_TARGET_FILE);
    if stored.is_file() {
        return Ok(load_framed_target(&stored, cfg.target.size)?);
    }
    prepare_target(cfg).with_context(|| {
        format!(
            "{} has no stored target ({FRAMED_TARGET_FILE}), so it was prepared again from the config",
            dir.display()
        )
    })
}

fn eval_config(size: usize, seed: u64) -> RenderConfig {
    RenderConfig {
        width: size as u32,
        height: size as u32,
        points: EVAL_POINTS,
        supersample: EVAL_SUPERSAMPLE,
        seed,
        ..RenderConfig::default()
    }
}

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
const KEPT_FILES: [&str; 8] = [
    "code.json",
    "render.png",
    ZOOM_STRIP_FILE,
    "loss.png",
    "truth.png",
    "target.png",
    LOG_FILE,
    START_FILE,
];

/// The recovered code's 1×–64× views ([`zoom_strip`]).
const ZOOM_STRIP_FILE: &str = "zoom_strip.png";

/// Side of the full views a recovered code and its truth are compared at.
pub const TRUTH_SIZE: usize = 256;

/// A recovered code against the code that drew its target: both drawn by the evaluation
/// renderer ([`EVAL_POINTS`] points, [`EVAL_SUPERSAMPLE`]² binary supersampling) at
/// [`TRUTH_SIZE`]², each in its own fitted window — a suite's full view — and compared with
/// the paper's metrics (12.5 % border crop). The picture's framing, colours, noise and file
/// format play no part.
#[derive(Clone, Debug, Serialize)]
pub struct TruthScore {
    /// IoU of the `> 0` masks.
    pub iou: f64,
    /// F1 (Dice) of the `> 0` masks.
    pub f1: f64,
    /// PSNR on the foreground pixels.
    pub psnr: f64,
    /// SSIM on the foreground pixels.
    pub ssim: f64,
}

/// [`TruthScore`] of `maps` against the code `spec` names; writes the truth's full view as
/// `truth.png` into `dir`.
pub fn truth_score(
    spec: &str,
    maps: &[Affine2],
    seed: u64,
    dir: &Path,
) -> crate::Result<TruthScore> {
    let code = resolve_code(spec).with_context(|| format!("`target.truth` {spec}"))?;
    let truth_maps = code
        .affine2()
        .with_context(|| format!("`target.truth` {spec} must be a 2-D code"))?;
    let cfg = eval_config(TRUTH_SIZE, seed);
    let truth = render(&truth_maps, &code.evaluation_probabilities()?, &cfg, None)?;
    truth.save_png(&dir.join("truth.png"), BitDepth::Eight, false)?;
    let probs = IfsCode::from_affine2(None, maps)?.evaluation_probabilities()?;
    let ours = render(maps, &probs, &cfg, None)?;
    let m = paper_metrics::<f32>(&ours.values, &truth.values, TRUTH_SIZE, TRUTH_SIZE, None)?;
    Ok(TruthScore {
        iou: m.iou,
        f1: m.f1,
        psnr: m.psnr,
        ssim: m.ssim,
    })
}

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

/// A framed target and how the picture was read (none for a code or suite target).
type Framed<'a> = (&'a Image, Option<&'a TargetReading>);

/// Fills a fresh run folder: the resolved config, the framed target (`framed`, else
/// prepared from the config) and how the picture was read; returns the target.
fn new_run_dir(cfg: &InversionConfig, dir: &Path, framed: Option<Framed>) -> crate::Result<Image> {
    let size = cfg.target.size;
    let (target, reading) = match (framed, &cfg.target.image) {
        (Some((t, r)), _) => (t.clone(), r.cloned()),
        (None, Some(path)) => {
            let f = load_framed_picture_with(path, size, cfg.target.polarity, cfg.target_cells())
                .with_context(|| format!("preparing the target {}", path.display()))?;
            (f.image, Some(f.reading))
        }
        (None, None) => (prepare_target(cfg)?, None),
    };
    std::fs::create_dir_all(dir).doing("creating", dir)?;
    if let Some(r) = reading {
        r.save(&dir.join(TARGET_READING_FILE))?;
    }
    let resolved = cfg.with_absolute_paths()?;
    ifslab::io::write_atomic(&dir.join(CONFIG_FILE), resolved.to_toml().as_bytes())?;
    save_framed_target(&dir.join(FRAMED_TARGET_FILE), &target)?;
    Ok(target)
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
            let probs = IfsCode::from_affine2(None, &outcome.maps)?.evaluation_probabilities()?;
            let net = Lpips::try_load_default()?;
            Some(crate::suite::score_maps(
                suite_dir,
                &manifest,
                index,
                &outcome.maps,
                &probs,
                net.as_ref(),
            )?)
        }
        _ => None,
    };
    let truth = match &cfg.target.truth {
        Some(spec) => Some(truth_score(spec, &outcome.maps, cfg.seed, dir)?),
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

/// Code file, final render, zoom strip (where `strip`), loss plot; returns the render's
/// metrics and, when LPIPS is not among them, why.
fn write_outputs(
    cfg: &InversionConfig,
    dir: &Path,
    out: &InversionOutcome,
    target: &[f32],
    strip: bool,
) -> crate::Result<(ImageMetrics, Option<String>)> {
    let size = cfg.target.size;
    let mut code = IfsCode::from_affine2(Some("recovered"), &out.maps)
        .context("the recovered code failed validation")?;
    let probs = code.evaluation_probabilities()?;
    let final_render = render(&out.maps, &probs, &eval_config(size, cfg.seed), None)?;
    code.framing = Some(final_render.stats.window);
    code.meta
        .insert("strategy".into(), cfg.strategy.name().into());
    code.meta.insert("iterations".into(), out.iterations.into());
    code.meta.insert("final_loss".into(), out.final_loss.into());
    code.meta.insert("seed".into(), cfg.seed.into());
    code.save(dir.join("code.json"))?;
    final_render.save_png(&dir.join("render.png"), BitDepth::Eight, false)?;
    let truth = ground_truth(cfg, target)?;
    if cfg.target.code.is_some() || cfg.target.suite.is_some() {
        save_square_grey(&dir.join("truth.png"), &truth, size)?;
    }
    let (net, lpips_metric_note) = lpips_for_metrics(size)?;
    let metrics = paper_metrics::<f32>(&final_render.values, &truth, size, size, net.as_ref())?;
    if strip {
        zoom_strip(
            &out.maps,
            &probs,
            &final_render.stats.window,
            &dir.join(ZOOM_STRIP_FILE),
            cfg.seed,
        )?;
    }
    loss_plot(&out.log, &dir.join("loss.png"))?;
    Ok((metrics, lpips_metric_note))
}

/// The recovered code of the run in `dir` (`code.json`): its maps, evaluation probabilities
/// and the seed of the run that found it (`cfg.seed` where the file does not say).
fn recovered_code(dir: &Path, seed: u64) -> crate::Result<(IfsCode, Vec<Affine2>, Vec<f64>, u64)> {
    let code_path = dir.join("code.json");
    let code = IfsCode::load(&code_path)
        .with_context(|| format!("loading the recovered code {}", code_path.display()))?;
    let maps = code
        .affine2()
        .with_context(|| format!("{} must be a 2-D code", code_path.display()))?;
    let probs = code.evaluation_probabilities()?;
    // A best-of run keeps one of several runs at seeds of their own; the code file says which.
    let seed = code
        .meta
        .get("seed")
        .and_then(|v| v.as_u64())
        .unwrap_or(seed);
    Ok((code, maps, probs, seed))
}

/// Draws the zoom strip of the finished run in `dir` from its `code.json` (its framing and
/// seed), as [`write_outputs`] would have.
fn draw_zoom_strip(dir: &Path) -> crate::Result<()> {
    let (code, maps, probs, seed) = recovered_code(dir, 0)?;
    let window = code
        .framing
        .with_context(|| format!("{} has no framing", dir.join("code.json").display()))?;
    zoom_strip(&maps, &probs, &window, &dir.join(ZOOM_STRIP_FILE), seed)
}

/// Writes a `size × size` grey picture (values in [0, 1]) as an 8-bit PNG.
fn save_square_grey(path: &Path, values: &[f32], size: usize) -> crate::Result<()> {
    save_grey_png(
        path,
        values,
        size as u32,
        size as u32,
        BitDepth::Eight,
        false,
    )?;
    Ok(())
}

/// Draws a finished run's pictures again from its config and `code.json` — a folder
/// written back from a pack, say ([`crate::sweep::pack`]): `render.png`, `target.png`,
/// `truth.png` (code and suite targets, or the `target.truth` code), `zoom_strip.png`, and
/// `loss.png` where the folder has a `log.csv`. The renders are seeded as the run's were, so
/// they are its pictures. Returns the files written.
pub fn redraw_pictures(cfg: &InversionConfig, dir: &Path) -> crate::Result<Vec<PathBuf>> {
    let size = cfg.target.size;
    let (_, maps, probs, seed) = recovered_code(dir, cfg.seed)?;
    let mut written = Vec::new();
    let final_render = render(&maps, &probs, &eval_config(size, seed), None)?;
    final_render.save_png(&dir.join("render.png"), BitDepth::Eight, false)?;
    written.push(dir.join("render.png"));
    let target = run_target(cfg, dir)?.values;
    save_square_grey(&dir.join("target.png"), &target, size)?;
    written.push(dir.join("target.png"));
    if cfg.target.code.is_some() || cfg.target.suite.is_some() {
        let truth = ground_truth(cfg, &target)?;
        save_square_grey(&dir.join("truth.png"), &truth, size)?;
        written.push(dir.join("truth.png"));
    }
    if let Some(spec) = &cfg.target.truth {
        truth_score(spec, &maps, seed, dir)?;
        written.push(dir.join("truth.png"));
    }
    zoom_strip(
        &maps,
        &probs,
        &final_render.stats.window,
        &dir.join(ZOOM_STRIP_FILE),
        seed,
    )?;
    written.push(dir.join(ZOOM_STRIP_FILE));
    let log = dir.join(LOG_FILE);
    if log.is_file() {
        loss_plot(&log, &dir.join("loss.png"))?;
        written.push(dir.join("loss.png"));
    }
    written.dedup();
    Ok(written)
}

/// The LPIPS network for scoring `size²` renders, or why there is none.
fn lpips_for_metrics(size: usize) -> crate::Result<(Option<Lpips>, Option<String>)> {
    let rect = border_crop_rect(size, size, EVAL_BORDER_FRACTION)?;
    if rect.2.min(rect.3) < LPIPS_MIN_SIDE {
        return Ok((
            None,
            Some(format!(
                "the {}² evaluation crop is below LPIPS's {LPIPS_MIN_SIDE}² minimum",
                rect.2
            )),
        ));
    }
    Ok(match Lpips::try_load_default()? {
        Some(net) => (Some(net), None),
        None => (
            None,
            Some(format!(
                "no LPIPS weights at {}",
                default_lpips_weights_path().display()
            )),
        ),
    })
}

/// A point on the attractor with detail around it: the fixed point of `f₀∘f₁`.
pub fn interesting_point(maps: &[Affine2]) -> Option<[f64; 2]> {
    match maps {
        [a, b, ..] => a.compose(b).fixed_point(),
        [a] => a.fixed_point(),
        [] => None,
    }
}

/// Renders 1×, 4×, 16×, 64× views around an interesting point side by side, with captions.
pub fn zoom_strip(
    maps: &[Affine2],
    probs: &[f64],
    base: &Window,
    path: &Path,
    seed: u64,
) -> crate::Result<()> {
    const PANEL: u32 = 256;
    const CAPTION: u32 = 28;
    let center = interesting_point(maps).unwrap_or_else(|| base.center());
    let factors = [1.0, 4.0, 16.0, 64.0];
    let mut panels = Vec::new();
    for &f in &factors {
        let cfg = RenderConfig {
            width: PANEL,
            height: PANEL,
            points: 2_000_000,
            supersample: 2,
            seed,
            view: View::Window(*base),
            zoom: Some(Zoom {
                factor: f,
                center: Some(if f == 1.0 { base.center() } else { center }),
            }),
            min_hits: 1_000_000,
            max_points: 200_000_000,
            // The zoomed panels' points come through the code's words: the first round
            // fills them, where the plain game needed up to 64² times the points.
            deep_zoom: true,
            ..RenderConfig::default()
        };
        panels.push(render(maps, probs, &cfg, None)?);
    }
    let w = PANEL * 4 + 3 * 6;
    let h = PANEL + CAPTION;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    for (i, p) in panels.iter().enumerate() {
        let x0 = i as u32 * (PANEL + 6);
        for y in 0..PANEL {
            for x in 0..PANEL {
                let v = (p.values[(y * PANEL + x) as usize].clamp(0.0, 1.0) * 255.0) as u8;
                let o = (((y + CAPTION) * w + x0 + x) * 3) as usize;
                buf[o..o + 3].copy_from_slice(&[v, v, v]);
            }
        }
    }
    ensure_font();
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        for (i, f) in factors.iter().enumerate() {
            let x = i as i32 * (PANEL as i32 + 6) + 8;
            root.draw(&Text::new(
                format!("{f}×"),
                (x, 4),
                ("sans-serif", 20).into_font().color(&BLACK),
            ))?;
        }
        root.present()?;
    }
    crate::plot::write_rgb_png(path, (w, h), &buf)?;
    Ok(())
}

/// Plots `loss` and each logged term of a run's CSV log against the iteration.
pub fn loss_plot(log: &Path, out: &Path) -> crate::Result<()> {
    let text = std::fs::read_to_string(log).doing("reading", log)?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().context("empty log")?.split(',').collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .filter(|r: &Vec<f64>| r.len() == header.len())
        .collect();
    let mut series = Vec::new();
    for (c, name) in header.iter().enumerate().skip(1) {
        if *name == "seconds" {
            continue;
        }
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| (r[0], r[c]))
            .filter(|p| p.1.is_finite() && p.1 > 0.0)
            .collect();
        if !pts.is_empty() {
            series.push(Series { name, points: pts });
        }
    }
    line_chart(out, "loss", "iteration", "value", &series, true)
}

/// The run folder named by `-o`, the config, or a default.
pub fn output_dir(cli: Option<PathBuf>, cfg: &InversionConfig, default: &str) -> PathBuf {
    cli.or_else(|| cfg.output.clone())
        .unwrap_or_else(|| PathBuf::from(default))
}
