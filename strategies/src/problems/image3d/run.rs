//! A multi-view inversion into a run folder: the hull and its EM code (the baseline), the
//! registered strategy under the shared driver from that code (or a random one), and what
//! people open — the code (`code.json`, and the baseline's `baseline.json`), the attractor
//! as a point cloud (`points.ply`), a turntable of renders (`turntable.png`), the views
//! beside the fit's renders through the same cameras (`views.png`; views it never saw, when
//! given, in `other_views.png`) and `summary.json` (losses; voxel IoU and Chamfer distance
//! of baseline and fit when a truth is given).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use argmin::core::State;
use argmin::core::observers::Observe;
use ifslab::chaos::{ChaosGame, mix_seed, points3};
use ifslab::image::Image;
use ifslab::metrics3d::{chamfer_distance, voxel_iou};
use ifslab::model::IfsCode;
use ifslab::model::map3::{Affine3, SvdMap3, flat_params};
use ifslab::progress::Progress;
use ifslab::render::splat3d::{Camera, Lens, MultiViewConfig, turntable};
use serde::Serialize;

use crate::driver::GradState;
use crate::driver::plan::{CHECKPOINT_FILE, RunPlan};
use crate::error::{Error, Result};
use crate::problems::image3d::collage::{CollageSearch3, collage_covers3, silhouette_score};
use crate::problems::image3d::config::{Image3dConfig, Start3d};
use crate::problems::image3d::hull::{Hull, encode_start, hull_start, random_start, visual_hull};
use crate::problems::image3d::problem::{IMAGE3D_TERMS, Image3dProblem};
use crate::problems::image3d::views::{Views, render_views};

/// Random streams the start and the last iterate are compared on (never an iteration's).
const SELECTION_STREAMS: [u64; 2] = [u64::MAX - 1, u64::MAX - 2];

/// Points of an attractor for the point cloud and the scores (500 trajectories of 200).
fn evaluation_game(seed: u64) -> ChaosGame {
    ChaosGame {
        trajectories: 500,
        length: 220,
        warmup: 20,
        start_half_width: 1.0,
        seed,
    }
}

/// How the collage start chose (`Start3d::Collage`): the silhouette scores
/// ([`silhouette_score`]) of the best cover and of the hull's EM code, and which started.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct StartScores3d {
    /// The best collage cover's.
    pub collage: f64,
    /// The hull's EM code's.
    pub hull: f64,
    /// `collage` or `hull`: the start (the higher score; the collage on a tie).
    pub chosen: &'static str,
}

/// What a multi-view inversion found.
#[derive(Clone, Debug)]
pub struct Image3dOutcome {
    /// With a collage start, how it chose.
    pub start_scores: Option<StartScores3d>,
    /// The start's maps.
    pub start: Vec<Affine3>,
    /// The fitted maps.
    pub maps: Vec<Affine3>,
    /// The same maps as the fit's parameterisation holds them.
    pub svd_maps: Vec<SvdMap3>,
    /// The baseline: the visual hull's EM code.
    pub baseline: Vec<Affine3>,
    /// The same code as the fit's parameterisation holds it.
    pub baseline_svd: Vec<SvdMap3>,
    /// `start` or `last`: which the run returns (the lower loss on fixed streams).
    pub returned: &'static str,
    /// The loss of the start (mean over views, final σ, fixed streams).
    pub start_loss: f64,
    /// The loss of the baseline (the same way).
    pub baseline_loss: f64,
    /// The loss of the returned code (the same way).
    pub loss: f64,
    /// Strategy iterations run.
    pub iterations: u64,
    /// Ink of the baseline's and the returned code's renders over the fitted views' ink
    /// (means over views; 1: as much as the views hold).
    pub ink_ratio: [f64; 2],
    /// Scores on the held-out views, when some were held out.
    pub held_out: Option<HeldOut3d>,
    /// Voxels of the visual hull.
    pub hull_voxels: usize,
    /// Seconds of the hull and its EM fit.
    pub hull_seconds: f64,
    /// Seconds of the strategy.
    pub fit_seconds: f64,
    /// The CSV log.
    pub log: PathBuf,
}

/// Image scores on views the fit did not see (final σ, the selection streams).
#[derive(Clone, Debug, Serialize)]
pub struct HeldOut3d {
    /// Which views (indices into the folder's list).
    pub views: Vec<usize>,
    /// The image loss (the fit's, without volume and ink terms): baseline, then fit.
    pub loss: [f64; 2],
    /// Ink of the renders over the views' ink: baseline, then fit.
    pub ink_ratio: [f64; 2],
}

/// Image scores of the `baseline` and `fit` codes on `views` (pictures the fit did not
/// see: held out of the folder, or drawn apart), rendered as the fit renders at its final
/// σ on the selection streams; `indices` names the views in the summary.
pub fn score_views(
    cfg: &Image3dConfig,
    baseline: &[SvdMap3],
    fit: &[SvdMap3],
    views: &Views,
    indices: Vec<usize>,
) -> Result<HeldOut3d> {
    let score = |maps: &[SvdMap3]| -> Result<(f64, f64)> {
        let mut scorer = Image3dProblem::<f32>::new(
            maps,
            views,
            cfg.render.multi_view(views.size()),
            cfg.loss(),
            cfg.seed,
        )?
        .with_map_choice(cfg.probabilities);
        if let Some(end) = cfg.render.sigma_final {
            scorer = scorer.with_sigma_schedule(end, cfg.iterations)?;
        }
        let theta = flat_params(maps);
        Ok((
            selection_loss(&scorer, &theta)?,
            ink_ratio(&scorer, &theta)?,
        ))
    };
    let (b, f) = (score(baseline)?, score(fit)?);
    Ok(HeldOut3d {
        views: indices,
        loss: [b.0, f.0],
        ink_ratio: [b.1, f.1],
    })
}

/// The mean over the selection streams of θ's ink over the targets' ink (each a mean
/// over views, final σ).
fn ink_ratio(problem: &Image3dProblem, theta: &[f64]) -> Result<f64> {
    let target: f64 = problem.target_ink().iter().sum();
    let mut total = 0.0;
    for &s in &SELECTION_STREAMS {
        let (_, image) = problem.render(theta, s, 1.0)?;
        total += image.iter().map(|&v| f64::from(v)).sum::<f64>()
            / (image.len() / problem.target_ink().len()) as f64;
    }
    Ok(total / SELECTION_STREAMS.len() as f64 / target.max(1e-12))
}

/// The mean loss of θ over the selection streams at the end of the σ schedule.
fn selection_loss(problem: &Image3dProblem, theta: &[f64]) -> Result<f64> {
    let mut total = 0.0;
    for &s in &SELECTION_STREAMS {
        total += problem.cost(theta, s, 1.0)?;
    }
    Ok(total / SELECTION_STREAMS.len() as f64)
}

/// Runs the inversion `cfg` describes on `views` into `dir` (a new folder or an empty
/// one): the hull and its EM start, then the strategy. `progress` hears the phases;
/// `observers` see every iteration. A fresh run; [`run_image3d_in`] also resumes.
pub fn run_image3d(
    cfg: &Image3dConfig,
    views: &Views,
    dir: &Path,
    progress: &dyn Progress,
    observers: Vec<Box<dyn Observe<GradState> + Send>>,
) -> Result<Image3dOutcome> {
    run_image3d_in(cfg, views, dir, false, progress, observers)
}

/// [`run_image3d`], or with `resume` the run in `dir` continued from its last checkpoint
/// to exactly what it would have reached without stopping (`cfg` must be the run's own:
/// the caller keeps the run's config beside it; the hull and its EM code are drawn again —
/// they depend on the views and the seed alone —, the start is read back from
/// `start.json`). A run stopped before its first checkpoint starts again from its start. A
/// fresh run refuses a folder that holds a checkpoint.
pub fn run_image3d_in(
    cfg: &Image3dConfig,
    views: &Views,
    dir: &Path,
    resume: bool,
    progress: &dyn Progress,
    observers: Vec<Box<dyn Observe<GradState> + Send>>,
) -> Result<Image3dOutcome> {
    cfg.validate()?;
    let checkpointed = dir.join(CHECKPOINT_FILE).is_file();
    if resume && !checkpointed {
        progress.message("no checkpoint yet: the run starts again from its start");
    }
    let plan = RunPlan {
        dir,
        resume: resume && checkpointed,
        strategy: (cfg.strategy.name(), cfg.strategy.params()),
        iterations: cfg.iterations,
        seed: cfg.seed,
        checkpoint_every: cfg.checkpoint_every,
        terms: &IMAGE3D_TERMS,
    };
    let resume_from = plan.prepare()?;

    let (fit_views, held_views) = if cfg.hold_out > 0 {
        let (fit, held) = views.hold_out(cfg.hold_out)?;
        (
            views.subset(&fit)?,
            Some((held.clone(), views.subset(&held)?)),
        )
    } else {
        (views.clone(), None)
    };
    let views = &fit_views;
    progress.message("carving the visual hull and fitting EM to it");
    let clock = Instant::now();
    let hull = visual_hull(views, &cfg.hull)?;
    let baseline = hull_start(&hull, cfg.maps, &cfg.hull, cfg.seed)?;
    let hull_seconds = clock.elapsed().as_secs_f64();
    progress.message(&format!(
        "hull: {} voxels; EM code of {} maps in {hull_seconds:.1} s",
        hull.kept.len(),
        cfg.maps
    ));
    let mut start_scores = None;
    let start_maps = match cfg.start {
        Start3d::Hull => baseline.clone(),
        Start3d::Random => random_start(cfg.maps, cfg.seed)?,
        Start3d::Code => code_start(cfg)?,
        Start3d::Collage => {
            progress.message("searching the hull for copies of itself (collage start)");
            let (maps, scores) = collage_start(&hull, views, cfg, &baseline)?;
            progress.message(&format!(
                "collage start: silhouettes {:.3} against the hull's EM code's {:.3}",
                scores.collage, scores.hull
            ));
            start_scores = Some(scores);
            maps
        }
    };
    let hull_seconds = clock.elapsed().as_secs_f64();

    let mut problem = Image3dProblem::<f32>::new(
        &start_maps,
        views,
        cfg.render.multi_view(views.size()),
        cfg.loss(),
        cfg.seed,
    )?
    .with_volume(cfg.volume)?
    .with_ink(cfg.ink, cfg.ink_slack)?
    .with_map_choice(cfg.probabilities);
    if let Some(end) = cfg.render.sigma_final {
        problem = problem.with_sigma_schedule(end, cfg.iterations)?;
    }
    // A folder without `start.json` resumes from the start drawn again (the same: it
    // depends on the views and the seed alone).
    let start = plan
        .start(resume_from, || Ok(flat_params(&start_maps)))?
        .unwrap_or_else(|| flat_params(&start_maps));
    progress.start("invert3d", cfg.iterations);
    let clock = Instant::now();
    let (problem, state) = plan.execute(problem, &start, resume_from, observers)?;
    let fit_seconds = clock.elapsed().as_secs_f64();
    progress.finish();
    let last = state
        .get_param()
        .cloned()
        .ok_or_else(|| Error::Numerical("the run ended without parameters".into()))?;
    let start_loss = selection_loss(&problem, &start)?;
    let baseline_loss = selection_loss(&problem, &flat_params(&baseline))?;
    let (theta, returned, loss) = match selection_loss(&problem, &last) {
        Ok(l) if l <= start_loss => (last, "last", l),
        _ => (start, "start", start_loss),
    };
    let svd_maps = problem.maps_at(&theta)?;
    let baseline_theta = flat_params(&baseline);
    let ink = [
        ink_ratio(&problem, &baseline_theta)?,
        ink_ratio(&problem, &theta)?,
    ];
    let held_out = match held_views {
        Some((indices, held)) => Some(score_views(cfg, &baseline, &svd_maps, &held, indices)?),
        None => None,
    };
    Ok(Image3dOutcome {
        start_scores,
        start: to_affine(&start_maps),
        maps: to_affine(&svd_maps),
        svd_maps,
        baseline: to_affine(&baseline),
        baseline_svd: baseline.clone(),
        returned,
        start_loss,
        baseline_loss,
        loss,
        iterations: state.get_iter(),
        ink_ratio: ink,
        held_out,
        hull_voxels: hull.kept.len(),
        hull_seconds,
        fit_seconds,
        log: plan.log_path(),
    })
}

/// The start of a `start = "code"` fit: the code in `cfg.start_code`, brought inside what
/// the parameterisation reaches ([`encode_start`]).
fn code_start(cfg: &Image3dConfig) -> Result<Vec<SvdMap3>> {
    let path = cfg
        .start_code
        .as_deref()
        .ok_or_else(|| Error::param("start_code", "the start's code file is missing"))?;
    let code = IfsCode::load(path).map_err(|e| Error::file(path, e))?;
    let maps = Affine3::from_code(&code).map_err(|e| Error::file(path, e))?;
    if maps.len() != cfg.maps {
        return Err(Error::file(
            path,
            format!(
                "the start code has {} maps and the fit {}; ask for {} maps",
                maps.len(),
                cfg.maps,
                maps.len()
            ),
        ));
    }
    maps.iter().map(encode_start).collect()
}

/// The picture of views drawn apart from the fitted ones (`--score-views`) above the fit's
/// renders through their cameras.
pub const OTHER_VIEWS_PNG: &str = "other_views.png";

/// Stream the collage start's scores are drawn on (never an iteration's).
const START_SCORE_STREAM: u64 = u64::MAX - 3;

/// The start of a `start = "collage"` fit: the best cover of the collage search in space,
/// or the hull's EM code `baseline` where its silhouettes match the views better, as SVD
/// maps ([`encode_start`]).
fn collage_start(
    hull: &Hull,
    views: &Views,
    cfg: &Image3dConfig,
    baseline: &[SvdMap3],
) -> Result<(Vec<SvdMap3>, StartScores3d)> {
    let search = CollageSearch3 {
        ink_level: cfg.hull.threshold,
        ..CollageSearch3::default()
    };
    let covers = collage_covers3(hull, views, cfg.maps, cfg.seed, &search)?;
    let best = &covers[0];
    let encoded: Vec<SvdMap3> = best.maps.iter().map(encode_start).collect::<Result<_>>()?;
    // Both scored as encoded (singular values and offsets brought inside what the fit
    // reaches), on one stream.
    let score = |maps: &[SvdMap3]| {
        silhouette_score(
            views,
            &to_affine(maps),
            search.score_points,
            search.ink_level,
            mix_seed(cfg.seed, START_SCORE_STREAM),
        )
    };
    let (collage, hull) = (score(&encoded)?, score(baseline)?);
    let (maps, chosen) = if collage >= hull {
        (encoded, "collage")
    } else {
        (baseline.to_vec(), "hull")
    };
    Ok((
        maps,
        StartScores3d {
            collage,
            hull,
            chosen,
        },
    ))
}

fn to_affine(maps: &[SvdMap3]) -> Vec<Affine3> {
    maps.iter().map(SvdMap3::to_affine).collect()
}

/// Scores of a code against the truth's attractor.
#[derive(Clone, Debug, Serialize)]
pub struct Scores3d {
    /// Voxel IoU at 64³ within one voxel.
    pub voxel_iou: f64,
    /// Chamfer distance (world units) of 10 000 points of each attractor.
    pub chamfer: f64,
}

/// `summary.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Summary3d {
    /// Views fitted.
    pub views: usize,
    /// Their width and height.
    pub size: [usize; 2],
    /// Maps fitted.
    pub maps: usize,
    /// Chaos-game trajectories per step (named, or by the views' size).
    pub trajectories: usize,
    /// Strategy iterations run.
    pub iterations: u64,
    /// `start` or `last`.
    pub returned: &'static str,
    /// Losses (mean over views, final σ, fixed streams).
    pub loss: Losses3d,
    /// Ink of the renders over the fitted views' ink: baseline, then fit.
    pub ink_ratio: [f64; 2],
    /// Image scores on the held-out views, when some were held out.
    pub held_out: Option<HeldOut3d>,
    /// Image scores on views drawn apart from the fitted ones (`--score-views`), if any.
    pub other_views: Option<HeldOut3d>,
    /// Voxels of the visual hull.
    pub hull_voxels: usize,
    /// Seconds: hull and EM (and the collage search, with a collage start), then the
    /// strategy.
    pub seconds: [f64; 2],
    /// With a collage start, how it chose between the collage and the hull's EM code.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_choice: Option<StartScores3d>,
    /// With a collage start and a truth, the start's scores against the truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start: Option<Scores3d>,
    /// The baseline's scores against the truth, when one was given.
    pub baseline: Option<Scores3d>,
    /// The fit's scores against the truth, when one was given.
    pub fit: Option<Scores3d>,
}

/// Losses of the start, the baseline and the fit.
#[derive(Clone, Debug, Serialize)]
pub struct Losses3d {
    /// The start's.
    pub start: f64,
    /// The baseline's (hull + EM).
    pub baseline: f64,
    /// The returned code's.
    pub fit: f64,
}

/// The attractor of `maps` (uniform map choice unless `probs`) as 110 000 points.
pub fn attractor(maps: &[Affine3], probs: Option<&[f64]>, seed: u64) -> Result<Vec<[f64; 3]>> {
    Ok(points3(&evaluation_game(seed), maps, probs)?)
}

/// Writes the outputs of `outcome` into `dir` (see the module docs) and returns the
/// summary; `truth` (maps and their probabilities) adds the scores, `other` (views the
/// fit never saw, e.g. drawn at another elevation) the image scores on them.
pub fn write_outputs(
    dir: &Path,
    cfg: &Image3dConfig,
    views: &Views,
    outcome: &Image3dOutcome,
    truth: Option<(&[Affine3], Option<&[f64]>)>,
    other: Option<&Views>,
) -> Result<Summary3d> {
    // Each code carries the probabilities it is drawn with here, so that it is drawn the
    // same way wherever it is read.
    let probs = cfg.probabilities.for_affine(&outcome.maps);
    let baseline_probs = cfg.probabilities.for_affine(&outcome.baseline);
    let save = |name: &str, maps: &[Affine3], probs: &Option<Vec<f64>>, file: &str| {
        let mut code = Affine3::to_code(Some(name), maps)?;
        code.probabilities = probs.clone();
        code.save(dir.join(file))
    };
    save("invert3d", &outcome.maps, &probs, "code.json")?;
    save(
        "visual hull + EM",
        &outcome.baseline,
        &baseline_probs,
        "baseline.json",
    )?;
    let points = attractor(&outcome.maps, probs.as_deref(), cfg.seed)?;
    write_ply(&dir.join("points.ply"), &points)?;

    // The fit and the views through the views' cameras, and a turntable around the fit.
    let mut render = cfg.render.multi_view(views.size());
    render.sigma = cfg.render.sigma_final.unwrap_or(cfg.render.sigma);
    render.game.trajectories *= 4;
    let svd = &outcome.svd_maps;
    let (w, h) = views.size();
    let fitted = render_views(svd, &views.cameras, &render, probs.as_deref(), cfg.seed)?;
    let rows = [views.image.values.as_slice(), fitted.values.as_slice()];
    save_strip(&dir.join("views.png"), &rows, views.len(), w, h)?;
    // Views the fit never saw, above the fit's renders through their cameras.
    if let Some(other) = other {
        let (ow, oh) = other.size();
        let fitted = render_views(svd, &other.cameras, &render, probs.as_deref(), cfg.seed)?;
        let rows = [other.image.values.as_slice(), fitted.values.as_slice()];
        save_strip(&dir.join(OTHER_VIEWS_PNG), &rows, other.len(), ow, oh)?;
    }
    let table = turntable_around(&views.cameras, 128)?;
    let turn = render_views(svd, &table, &render, probs.as_deref(), cfg.seed)?;
    save_strip(
        &dir.join("turntable.png"),
        &[&turn.values],
        table.len(),
        128,
        128,
    )?;

    let (baseline, fit, start) = match truth {
        Some((maps, probs)) => {
            let t = attractor(maps, probs, cfg.seed.wrapping_add(1))?;
            let b = attractor(&outcome.baseline, baseline_probs.as_deref(), cfg.seed)?;
            // The Chamfer distance on every 11th point (10 000 a set): its nearest-neighbour
            // search scans empty cells for points far from the other set, minutes for
            // 110 000 points of a collapsed fit.
            let thin =
                |p: &[[f64; 3]]| -> Vec<[f64; 3]> { p.iter().step_by(11).copied().collect() };
            let t_thin = thin(&t);
            let score = |p: &[[f64; 3]]| -> Result<Scores3d> {
                Ok(Scores3d {
                    voxel_iou: voxel_iou(&t, p, 64, 1)?,
                    chamfer: chamfer_distance(&t_thin, &thin(p))?,
                })
            };
            let start = match &outcome.start_scores {
                Some(_) => {
                    let probs = cfg.probabilities.for_affine(&outcome.start);
                    Some(score(&attractor(
                        &outcome.start,
                        probs.as_deref(),
                        cfg.seed,
                    )?)?)
                }
                None => None,
            };
            (Some(score(&b)?), Some(score(&points)?), start)
        }
        None => (None, None, None),
    };
    let summary = Summary3d {
        views: views.len(),
        size: [w, h],
        maps: outcome.maps.len(),
        trajectories: cfg.render.trajectories_for((w, h)),
        iterations: outcome.iterations,
        returned: outcome.returned,
        loss: Losses3d {
            start: outcome.start_loss,
            baseline: outcome.baseline_loss,
            fit: outcome.loss,
        },
        ink_ratio: outcome.ink_ratio,
        held_out: outcome.held_out.clone(),
        other_views: match other {
            Some(v) => Some(score_views(
                cfg,
                &outcome.baseline_svd,
                &outcome.svd_maps,
                v,
                (0..v.len()).collect(),
            )?),
            None => None,
        },
        hull_voxels: outcome.hull_voxels,
        seconds: [outcome.hull_seconds, outcome.fit_seconds],
        start_choice: outcome.start_scores,
        start,
        baseline,
        fit,
    };
    let text = serde_json::to_string_pretty(&summary)
        .map_err(|e| Error::Numerical(format!("summary: {e}")))?;
    ifslab::io::write_atomic(&dir.join("summary.json"), text.as_bytes())?;
    Ok(summary)
}

/// Eight views of `side²` at 25° elevation around the origin, a pinhole of 50°, at the
/// mean distance of `cameras` from the origin.
fn turntable_around(cameras: &[Camera], side: usize) -> Result<Vec<Camera>> {
    let d = cameras
        .iter()
        .map(|c| c.position().iter().map(|v| v * v).sum::<f64>().sqrt())
        .sum::<f64>()
        / cameras.len() as f64;
    let d = if d.is_finite() && d > 0.5 { d } else { 4.0 };
    Ok(turntable(
        8,
        25.0,
        d,
        Lens::pinhole_fov(50f64.to_radians(), side, side),
        side,
        side,
    )?)
}

/// Rows of `n` planes of `w × h` (ink 1) side by side, as one PNG: dark ink on white.
fn save_strip(path: &Path, rows: &[&[f32]], n: usize, w: usize, h: usize) -> Result<()> {
    let width = n * w;
    let mut out = vec![1.0f32; width * h * rows.len()];
    for (r, planes) in rows.iter().enumerate() {
        for (k, plane) in planes.chunks_exact(w * h).enumerate() {
            for y in 0..h {
                for x in 0..w {
                    out[(r * h + y) * width + k * w + x] = 1.0 - plane[y * w + x].clamp(0.0, 1.0);
                }
            }
        }
    }
    Image::grey(width as u32, (h * rows.len()) as u32, out)?.save_png(path)?;
    Ok(())
}

/// An ASCII PLY of `points` (vertices only), written atomically.
pub fn write_ply(path: &Path, points: &[[f64; 3]]) -> Result<()> {
    let mut buf = Vec::with_capacity(points.len() * 30 + 200);
    let io = |e: std::io::Error| Error::file(path, e);
    write!(
        buf,
        "ply\nformat ascii 1.0\ncomment ifslab invert3d: the attractor of the fitted code\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        points.len()
    )
    .map_err(io)?;
    for p in points {
        writeln!(buf, "{:.6} {:.6} {:.6}", p[0], p[1], p[2]).map_err(io)?;
    }
    ifslab::io::write_atomic(path, &buf)?;
    Ok(())
}

/// The multi-view splat's image of the affine `maps` through `cameras`, map `i` drawn with
/// probability `probs[i]` (what the tests and `--render-views` draw targets with).
pub fn render_code(
    maps: &[Affine3],
    cameras: &[Camera],
    render: &MultiViewConfig,
    probs: Option<&[f64]>,
    seed: u64,
) -> Result<Image> {
    let svd: Vec<SvdMap3> = maps
        .iter()
        .map(|m| SvdMap3::from_affine(m, 1e-9))
        .collect::<ifslab::Result<_>>()?;
    render_views(&svd, cameras, render, probs, seed)
}
