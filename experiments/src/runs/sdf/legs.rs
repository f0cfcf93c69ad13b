//! A fit at several widths σ, or followed by rescue fits: each whole fit (a leg) in a folder of its own, resumed where it stopped, and the one kept.

use super::*;

/// One fit of a run at several widths σ.
#[derive(Clone, Debug, Serialize)]
pub struct SdfLegSummary {
    /// Its width σ in pixels.
    pub sigma: f64,
    /// Its folder inside the run's (`sigma-0`, `sigma-1`, …).
    pub folder: String,
    /// Its loss.
    pub loss: f64,
    /// IoU of its render and the target thresholded at 0.5 (what chooses among them).
    pub iou: f64,
    /// IoU against the truth, when given (reported only, never used to choose).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_iou: Option<f64>,
    /// Its start (`SdfOutcome::start_kind`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start: Option<&'static str>,
    /// Whether it is the run's result.
    pub chosen: bool,
}

/// A finished fit with its render scored against the target.
pub(super) struct Leg {
    pub(super) problem: SdfProblem,
    pub(super) out: SdfOutcome,
    pub(super) image: Vec<f64>,
    pub(super) mse: f64,
    pub(super) iou: f64,
}

impl Leg {
    pub(super) fn score(problem: SdfProblem, out: SdfOutcome, ink: &[f64]) -> crate::Result<Leg> {
        let image = problem.image(&out.theta)?;
        let mse = image
            .iter()
            .zip(ink)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            / image.len() as f64;
        let pm: Vec<bool> = image.iter().map(|&v| v >= INK).collect();
        let tm: Vec<bool> = ink.iter().map(|&v| v >= INK).collect();
        let iou = ifslab::metrics::iou(&pm, &tm)?;
        Ok(Leg {
            problem,
            out,
            image,
            mse,
            iou,
        })
    }
}

/// The folder of a run's `i`-th fit at several widths σ.
pub(super) fn leg_folder(i: usize) -> String {
    format!("sigma-{i}")
}

/// A run's result with the time this process spent on it.
pub(super) struct Timed {
    pub(super) leg: Leg,
    pub(super) seconds: f64,
    /// Iterations this process ran (at least 1).
    pub(super) fresh: u64,
}

/// The fits of `cfg` at each width of `sigmas`, one after another, each whole in its own
/// folder `sigma-<i>` of `dir` (so each checkpoints and resumes as a run of its own); the
/// one whose render agrees best with the target (IoU of the half-inked pixels) is
/// returned with all of them summarised, each scored by `truth_iou` too.
pub(super) fn run_legs(
    cfg: &SdfConfig,
    ink: &Image<f64>,
    legs: &[(String, SdfConfig)],
    dir: &Path,
    resume: bool,
    progress: Arc<dyn Progress>,
    truth_iou: &dyn Fn(&Pattern) -> crate::Result<Option<f64>>,
) -> crate::Result<(Timed, Vec<SdfLegSummary>)> {
    progress.start(cfg.strategy.name(), cfg.iterations * legs.len() as u64);
    let clock = Instant::now();
    let mut fresh = 0;
    let mut best: Option<(usize, Leg)> = None;
    let mut summaries = Vec::with_capacity(legs.len());
    for (i, (folder, leg_cfg)) in legs.iter().enumerate() {
        let sigma = leg_cfg.sigma;
        let folder = folder.clone();
        let leg_dir = dir.join(&folder);
        let leg_resume = leg_resumes(&leg_dir, resume);
        let done_before = if leg_resume {
            ifslab_strategies::driver::plan::checkpoint_iteration(&leg_dir)?
        } else {
            0
        };
        let observer = ProgressObserver::new(Box::new(LegProgress::new(
            progress.clone(),
            i,
            legs.len(),
            cfg.iterations,
        )));
        let out = run_sdf(
            leg_cfg,
            ink.clone(),
            None,
            &leg_dir,
            leg_resume,
            vec![Box::new(observer)],
        )
        .with_context(|| format!("the fit at σ = {sigma:.3} px ({folder})"))?;
        fresh += out.iterations.saturating_sub(done_before);
        let leg = Leg::score(sdf_problem(leg_cfg, ink.clone(), None)?, out, &ink.values)?;
        summaries.push(SdfLegSummary {
            sigma,
            folder,
            loss: leg.out.loss,
            iou: leg.iou,
            truth_iou: truth_iou(&leg.problem.pattern_at(&leg.out.theta)?)?,
            start: leg.out.start_kind,
            chosen: false,
        });
        if best.as_ref().is_none_or(|(_, b)| leg.iou > b.iou) {
            best = Some((i, leg));
        }
    }
    let (chosen, leg) = best.context("no width σ to fit at")?;
    summaries[chosen].chosen = true;
    Ok((
        Timed {
            leg,
            seconds: clock.elapsed().as_secs_f64(),
            fresh: fresh.max(1),
        },
        summaries,
    ))
}
