//! Segment-pattern fit runs (`problem = "sdf"`, `ifslab sdf fit`): config → run folder with
//! the resolved config, the framed target (`target.npy` bit for bit, `target.png` to look
//! at), checkpoints and `log.csv` as it goes, then the final render, the fitted pattern
//! (a pattern file whose `meta` holds the view, depth and σ the fit used, so `ifslab sdf
//! render` draws it as the fit saw it), the loss plot and `summary.json`. A fit at several
//! widths σ (`sigma_factors`) runs each whole in a folder of its own (`sigma-0`, `sigma-1`,
//! … with their checkpoints, starts and logs, each resumed where it stopped) and writes
//! the kept one's render, pattern, log and loss plot where a single fit's would be. A kept
//! fit whose render agrees with the target on an IoU below `rescue_below` is followed by two
//! more (`rescue-0`, `rescue-1`: coarse to fine, and with a distance term), the best kept.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use crate::error::{Context, IoContext};
use ifslab::image::Image;
use ifslab::model::segment::{Pattern, PatternFile, resolve_pattern};
use ifslab::render::FIT_FILL;
use ifslab::render::image_io::{BitDepth, save_grey_png};
use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView, WordTree};
use ifslab_strategies::problems::image::{
    FRAMED_TARGET_FILE, TARGET_READING_FILE, TargetReading, ensure_new_run_dir,
    load_framed_picture, load_framed_target, save_framed_target,
};
use ifslab_strategies::problems::sdf::{
    CUTOFF_SIGMAS, INK, SdfConfig, SdfOutcome, SdfProblem, at_sigma, rescue_legs, run_sdf,
    sdf_problem, stretch_ink, stroke_sigma_legs,
};
use serde::Serialize;

use crate::progress::{Progress, ProgressObserver};
use crate::runs::inversion::{CONFIG_FILE, loss_plot};
use crate::runs::legs::{LegProgress, leg_resumes, refuse_existing_legs};
mod legs;
pub use legs::SdfLegSummary;
use legs::{Leg, Timed, leg_folder, run_legs};
mod score;
pub use score::{TRUTH_SIGMA, TRUTH_SIZE, pattern_iou};

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
    /// Width σ the figure was drawn with at the end, in pixels (the config's, or the
    /// target's stroke width with `stroke_sigma`).
    pub sigma: f64,
    /// Loss of the returned control points.
    pub loss: f64,
    /// Plain MSE between the final render and the target.
    pub mse: f64,
    /// IoU of the render and the target thresholded at 0.5.
    pub iou: f64,
    /// IoU against the pattern that drew the target (`truth` in the config), both drawn at
    /// the fit's depth, [`TRUTH_SIZE`]² and σ [`TRUTH_SIGMA`] (whatever the fit's own
    /// size and σ), each framed in its own box ([`pattern_iou`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_iou: Option<f64>,
    /// `last` or `start` (see `SdfOutcome::returned`).
    pub returned: String,
    /// Which start the kept fit began from (`SdfOutcome::start_kind`: `line`, `pattern`,
    /// `box_stretched`, …).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start: Option<&'static str>,
    /// The returned control points.
    pub points: Vec<[f64; 2]>,
    /// With several widths σ (`sigma_factors`) or rescue fits (`rescue_below`; a single
    /// fit is then listed first, in folder `.`), every fit, in the order they ran; the one
    /// with the highest `iou` is the run's result (the first of equals).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub legs: Vec<SdfLegSummary>,
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
) -> crate::Result<SdfSummary> {
    cfg.validate()?;
    let _lock = crate::runs::lock::lock_run_dir(dir)?;
    let size = cfg.size;
    let (target, reading): (Image, Option<TargetReading>) = if resume {
        let reading_file = dir.join(TARGET_READING_FILE);
        (
            load_framed_target(&dir.join(FRAMED_TARGET_FILE), size)?,
            // Runs from before the reading was kept have none (nor use it).
            reading_file
                .is_file()
                .then(|| TargetReading::load(&reading_file))
                .transpose()?,
        )
    } else {
        ensure_new_run_dir(dir)?;
        // A fit at several widths checkpoints in its legs' folders.
        refuse_existing_legs(dir, &leg_folder(0))?;
        let framed = load_framed_picture(&cfg.target, size, cfg.polarity)?;
        let mut t = framed.image;
        stretch_ink(&mut t.values);
        if let Some(spec) = &cfg.truth {
            // A truth that does not load is refused before the fit, not after it.
            resolve_pattern(spec).with_context(|| format!("`truth` {spec}"))?;
        }
        std::fs::create_dir_all(dir).doing("creating", dir)?;
        let resolved = crate::runs::RunConfig::Sdf(Box::new(cfg.clone())).to_table()?;
        ifslab::io::write_atomic(
            &dir.join(CONFIG_FILE),
            toml::to_string_pretty(&resolved)?.as_bytes(),
        )?;
        save_framed_target(&dir.join(FRAMED_TARGET_FILE), &t)?;
        framed.reading.save(&dir.join(TARGET_READING_FILE))?;
        (t, Some(framed.reading))
    };
    let stroke = reading.as_ref().and_then(TargetReading::framed_stroke);
    save_grey_png(
        &dir.join("target.png"),
        &target.values,
        size as u32,
        size as u32,
        BitDepth::Eight,
        true,
    )?;
    let ink = target.widened();
    let truth = match &cfg.truth {
        Some(spec) => Some(resolve_pattern(spec).with_context(|| format!("`truth` {spec}"))?),
        None => None,
    };
    let truth_iou = |p: &Pattern| -> crate::Result<Option<f64>> {
        truth
            .as_ref()
            .map(|t| pattern_iou(t, p, TRUTH_SIZE, cfg.depth, TRUTH_SIGMA))
            .transpose()
    };
    let progress: Arc<dyn Progress> = Arc::from(progress);
    let legs = stroke_sigma_legs(cfg, stroke)?;
    let (leg, mut legs) = if legs.len() > 1 {
        let legs: Vec<(String, SdfConfig)> = legs
            .iter()
            .enumerate()
            .map(|(i, &sigma)| (leg_folder(i), at_sigma(cfg, sigma)))
            .collect();
        run_legs(cfg, &ink, &legs, dir, resume, progress.clone(), &truth_iou)?
    } else {
        let done_before = if resume {
            ifslab_strategies::driver::plan::checkpoint_iteration(dir)?
        } else {
            0
        };
        progress.start(cfg.strategy.name(), cfg.iterations);
        let clock = Instant::now();
        let out = run_sdf(
            cfg,
            ink.clone(),
            stroke,
            dir,
            resume,
            vec![Box::new(ProgressObserver::new(Box::new(LegProgress::new(
                progress.clone(),
                0,
                1,
                cfg.iterations,
            ))))],
        )?;
        let seconds = clock.elapsed().as_secs_f64();
        let problem = sdf_problem(cfg, ink.clone(), stroke)?;
        let scored = Leg::score(problem, out, &ink.values)?;
        let fresh = scored.out.iterations.saturating_sub(done_before).max(1);
        (
            Timed {
                leg: scored,
                seconds,
                fresh,
            },
            Vec::new(),
        )
    };
    // A fit that agrees poorly with its target is fitted twice more (`rescue_below`).
    let rescue = rescue_legs(cfg, leg.leg.problem.sigma());
    let leg = if !rescue.is_empty() && leg.leg.iou < cfg.rescue_below {
        if legs.is_empty() {
            // The single fit becomes the first of the run's fits, in the run's own folder.
            legs.push(SdfLegSummary {
                sigma: leg.leg.problem.sigma(),
                folder: ".".to_owned(),
                loss: leg.leg.out.loss,
                iou: leg.leg.iou,
                truth_iou: truth_iou(&leg.leg.problem.pattern_at(&leg.leg.out.theta)?)?,
                start: leg.leg.out.start_kind,
                chosen: true,
            });
        }
        let (extra, summaries) = run_legs(cfg, &ink, &rescue, dir, resume, progress, &truth_iou)?;
        let rescued = extra.leg.iou > leg.leg.iou;
        for l in &mut legs {
            l.chosen &= !rescued;
        }
        legs.extend(summaries.into_iter().map(|l| SdfLegSummary {
            chosen: l.chosen && rescued,
            ..l
        }));
        Timed {
            leg: if rescued { extra.leg } else { leg.leg },
            seconds: leg.seconds + extra.seconds,
            fresh: leg.fresh + extra.fresh,
        }
    } else {
        leg
    };
    let Timed {
        leg,
        seconds,
        fresh,
    } = leg;
    let Leg {
        problem,
        out,
        image,
        mse,
        iou,
    } = leg;
    let fitted = problem.pattern_at(&out.theta)?;
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
        "sigma": problem.sigma(),
        "loss": out.loss,
        "iterations": out.iterations,
    });
    PatternFile::of(&fitted, Some(meta)).save(dir.join(FITTED_PATTERN_FILE))?;
    loss_plot(&out.log, &dir.join("loss.png"))?;
    if !legs.is_empty() {
        // The kept fit's log where a single fit's would be.
        let log = std::fs::read(&out.log).io_context(&out.log, || out.log.display())?;
        ifslab::io::write_atomic(&dir.join("log.csv"), &log)?;
    }
    // The kept fit was scored against the truth with the others.
    let truth_iou = match legs.iter().find(|l| l.chosen) {
        Some(kept) => kept.truth_iou,
        None => truth_iou(&fitted)?,
    };
    let summary = SdfSummary {
        pattern: fitted.name().to_owned(),
        strategy: cfg.strategy.name().to_owned(),
        iterations: out.iterations,
        seconds,
        // Only this process's iterations were timed: a single fit's own time, or every
        // fit's together over their iterations together.
        seconds_per_iteration: if legs.is_empty() {
            out.seconds
        } else {
            seconds
        } / fresh as f64,
        sigma: problem.sigma(),
        loss: out.loss,
        mse,
        iou,
        truth_iou,
        returned: out.returned.to_owned(),
        start: out.start_kind,
        points: fitted.points().to_vec(),
        legs,
    };
    ifslab::io::write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    Ok(summary)
}
