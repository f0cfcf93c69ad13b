//! `ifslab invert3d VIEWS_DIR --maps N -o OUT`: recover an IFS code of space from pictures
//! taken around it. VIEWS_DIR holds the pictures (PNG, all one size) and their cameras: a
//! NeRF-style `transforms.json` or a `turntable.json`
//! (`ifslab_strategies::problems::image3d::views`). The fit starts from EM in 3-D on the
//! views' visual hull (the baseline), runs any registered strategy through the multi-view
//! splat, and writes `code.json` (dim 3), `baseline.json`, `points.ply`, `views.png`,
//! `turntable.png`, `summary.json` and the run's `config.toml`, `log.csv`, `start.json`,
//! `invert3d.json` (where the views are and a fingerprint of them, the truth and the views
//! to score on) and, every `--checkpoint-every` iterations or when stopped by a signal,
//! `checkpoint.json` (written atomically: a temporary file renamed over the last).
//! `--resume DIR` continues a stopped run from its checkpoint to the result it would have
//! reached without stopping; a fresh run refuses a folder that holds one.
//!
//! With `--render-views CODE` it instead draws the views of a 3-D code into VIEWS_DIR with
//! the library's multi-view splat: `--views` turntable views of `--size`² (what the tests
//! and the README's numbers invert).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use anyhow::Context;
use ifslab::model::IfsCode;
use ifslab::model::map3::{Affine3, fern_3d, sierpinski_tetrahedron};
use ifslab_experiments::progress::ProgressObserver;
use ifslab_experiments::runs::lock_run_dir;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image3d::{
    CONFIG_FILE, Image3dConfig, MapChoice, Render3dConfig, Start3d, TurntableFile, Views,
    load_run_config, load_views, render_code, run_image3d_in, write_outputs, write_views,
};
use ifslab_strategies::strategy_config::StrategyConfig;
use indicatif::ProgressBar;

use crate::bars::Bar;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum StartArg {
    /// EM in 3-D on points of the views' visual hull (the baseline).
    Hull,
    /// Random maps drawn from the seed.
    Random,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum ChoiceArg {
    /// pᵢ ∝ |det Mᵢ|, floored at 1 % (the library's rule for codes without probabilities).
    Determinant,
    /// Every map equally likely.
    Uniform,
}

/// What a run folder keeps of its inputs besides its config (`invert3d.json`): a resumed
/// run reads the same views (refusing them if they changed) and scores the same way.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct Inputs {
    /// The views folder (absolute).
    views: PathBuf,
    /// [`Views::digest`] of the views when the run started.
    views_digest: String,
    /// `--truth` (a file's path made absolute, or a built-in name).
    truth: Option<String>,
    /// `--score-views` (absolute).
    score_views: Option<PathBuf>,
}

/// The run folder's record of its inputs.
const INPUTS_FILE: &str = "invert3d.json";

/// `path` made absolute against the working directory.
fn absolute(path: &Path) -> anyhow::Result<PathBuf> {
    std::path::absolute(path).with_context(|| format!("resolving {}", path.display()))
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder of PNG views with a transforms.json (NeRF-style) or a turntable.json.
    #[arg(required_unless_present = "resume")]
    pub views: Option<PathBuf>,
    /// Continue the run in DIR from its last checkpoint (to exactly the result it would
    /// have reached without stopping); every other flag is the run's own.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["views", "render_views"])]
    pub resume: Option<PathBuf>,
    /// Checkpoint every K iterations (0: only when stopped by a signal).
    #[arg(long, default_value_t = 10)]
    pub checkpoint_every: u64,
    /// Number of maps.
    #[arg(long, default_value_t = 4)]
    pub maps: usize,
    /// Output folder (must not hold a run). [default: VIEWS-invert3d beside VIEWS]
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Strategy iterations (150, 1e3, 1K).
    #[arg(long, visible_alias = "iterations", default_value = "150", value_parser = ifslab::budget::parse_count)]
    pub iters: u64,
    /// Seed of the hull's points, EM, a random start and every step's trajectories.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Where the fit starts.
    #[arg(long, value_enum, default_value = "hull")]
    pub start: StartArg,
    /// Start from this 3-D code file instead (as many maps as --maps): a previous fit's
    /// code.json, or the truth, to see whether the loss keeps it.
    #[arg(long, value_name = "CODE", conflicts_with = "start")]
    pub start_code: Option<PathBuf>,
    /// How the chaos game picks the maps of the fit and the baseline (renders, point
    /// clouds, scores): determinant (∝ |det M|, floored at 1 %) or uniform.
    #[arg(long, value_enum, default_value = "determinant")]
    pub probabilities: ChoiceArg,
    /// Any registered strategy (adam, gd, hybrid, annealing, noisy, …).
    #[arg(long, default_value = "adam")]
    pub strategy: String,
    /// Adam's learning rate (with --strategy adam).
    #[arg(long, default_value_t = 0.03)]
    pub lr: f64,
    /// Chaos-game trajectories per step (150 kept points each). [default: 400]
    #[arg(long)]
    pub trajectories: Option<usize>,
    /// The splat's supersampling per side. [default: 4]
    #[arg(long)]
    pub supersample: Option<usize>,
    /// σ at the start, in supersampled pixels. [default: 1.5]
    #[arg(long)]
    pub sigma: Option<f64>,
    /// σ at the end (geometric schedule). [default: 0.5]
    #[arg(long)]
    pub sigma_final: Option<f64>,
    /// Poolings of the multi-scale MSE on each view (0: plain MSE).
    #[arg(long, default_value_t = 0)]
    pub loss_levels: usize,
    /// Weight of Σ |det M_i| in the loss: prefers the thinnest code the silhouettes allow
    /// (0: off).
    #[arg(long, default_value_t = 0.01)]
    pub volume: f64,
    /// Weight of the ink guard: the mean over views of max(0, 1 − ink of the render / ink
    /// of the view)², against fits that shrink to less ink than the views hold (0: off).
    /// [default: 3]
    #[arg(long)]
    pub ink: Option<f64>,
    /// Fraction of a view's ink a render may lack before the ink guard charges. [default: 0]
    #[arg(long)]
    pub ink_slack: Option<f64>,
    /// Views held out of the fit and the hull, spread evenly around the list: the summary
    /// scores baseline and fit on them.
    #[arg(long, default_value_t = 0)]
    pub hold_out: usize,
    /// A second views folder (any cameras, the views' size) the fit never sees: the
    /// summary scores baseline and fit on it (image loss, ink).
    #[arg(long, value_name = "DIR")]
    pub score_views: Option<PathBuf>,
    /// The code that made the views (a 3-D code file, or `tetrahedron` / `fern3d`): the
    /// summary then scores the baseline and the fit against it (voxel IoU at 64³ within
    /// one voxel, Chamfer distance).
    #[arg(long, value_name = "CODE")]
    pub truth: Option<String>,
    /// Draw the views of CODE (a 3-D code file, `tetrahedron` or `fern3d`) into VIEWS with
    /// the multi-view splat, with a turntable.json, instead of inverting.
    #[arg(long, value_name = "CODE")]
    pub render_views: Option<String>,
    /// With --render-views: number of turntable views.
    #[arg(long, default_value_t = 8)]
    pub views_count: usize,
    /// With --render-views: side of each view in pixels.
    #[arg(long, default_value_t = 64)]
    pub size: usize,
}

/// A 3-D code by name or file, with its probabilities.
fn code3(spec: &str) -> anyhow::Result<(Vec<Affine3>, Option<Vec<f64>>)> {
    match spec {
        "tetrahedron" | "sierpinski-tetrahedron" => Ok((sierpinski_tetrahedron(), None)),
        "fern3d" | "fern-3d" => {
            let (maps, probs) = fern_3d();
            Ok((maps, Some(probs)))
        }
        path => {
            let code = IfsCode::load(path).with_context(|| {
                format!("reading the 3-D code {path} (or name tetrahedron, fern3d)")
            })?;
            let maps = Affine3::from_code(&code).with_context(|| path.to_owned())?;
            Ok((maps, code.probabilities.clone()))
        }
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(spec) = &a.render_views {
        return render(&a, spec);
    }
    if let Some(dir) = &a.resume {
        return resume(dir);
    }
    let views_dir = a.views.clone().expect("clap: VIEWS or --resume");
    let views = load_views(&views_dir)
        .with_context(|| format!("reading the views in {}", views_dir.display()))?;
    // A truth given as a file is kept by its absolute path (a built-in name as it is).
    let truth_spec = match &a.truth {
        Some(t) if Path::new(t).is_file() => {
            Some(absolute(Path::new(t))?.to_string_lossy().into_owned())
        }
        t => t.clone(),
    };
    let truth = truth_spec.as_deref().map(code3).transpose()?;
    let other = match &a.score_views {
        Some(dir) => Some(
            load_views(dir)
                .with_context(|| format!("reading the views to score in {}", dir.display()))?,
        ),
        None => None,
    };
    let mut strategy = StrategyConfig::by_name(&a.strategy)?;
    strategy.update::<AdamConfig>(|c| c.lr = a.lr);
    let defaults = Render3dConfig::default();
    let cfg = Image3dConfig {
        maps: a.maps,
        iterations: a.iters,
        seed: a.seed,
        start: match (a.start, &a.start_code) {
            (_, Some(_)) => Start3d::Code,
            (StartArg::Hull, None) => Start3d::Hull,
            (StartArg::Random, None) => Start3d::Random,
        },
        start_code: a.start_code.as_deref().map(absolute).transpose()?,
        probabilities: match a.probabilities {
            ChoiceArg::Determinant => MapChoice::Determinant,
            ChoiceArg::Uniform => MapChoice::Uniform,
        },
        strategy,
        render: Render3dConfig {
            trajectories: a.trajectories.unwrap_or(defaults.trajectories),
            supersample: a.supersample.unwrap_or(defaults.supersample),
            sigma: a.sigma.unwrap_or(defaults.sigma),
            sigma_final: a.sigma_final.or(defaults.sigma_final),
            ..defaults
        },
        loss_levels: a.loss_levels,
        volume: a.volume,
        ink: a.ink.unwrap_or(Image3dConfig::default().ink),
        ink_slack: a.ink_slack.unwrap_or(Image3dConfig::default().ink_slack),
        hold_out: a.hold_out,
        checkpoint_every: a.checkpoint_every,
        ..Image3dConfig::default()
    };
    cfg.validate()?;
    let out = a
        .output
        .clone()
        .unwrap_or_else(|| default_output(&views_dir));
    let inputs = Inputs {
        views: absolute(&views_dir)?,
        views_digest: views.digest(),
        truth: truth_spec,
        score_views: a.score_views.as_deref().map(absolute).transpose()?,
    };
    let _lock = lock_run_dir(&out)?;
    if out.join(CONFIG_FILE).exists() {
        anyhow::bail!(
            "{} already holds a run ({CONFIG_FILE}); continue it with `ifslab invert3d \
             --resume {}` or choose another output folder",
            out.display(),
            out.display()
        );
    }
    ifslab::io::write_atomic(
        &out.join(INPUTS_FILE),
        serde_json::to_string_pretty(&inputs)?.as_bytes(),
    )?;
    fit(&cfg, &views, &views_dir, &out, false, truth, other.as_ref())
}

/// `--resume DIR`: the run's config and inputs read back, its views read again and
/// checked against the fingerprint the run started with, the fit continued.
fn resume(dir: &Path) -> anyhow::Result<()> {
    // Refused before the folder is locked (which would create it).
    if !dir.join(CONFIG_FILE).is_file() {
        anyhow::bail!(
            "{} holds no invert3d run to resume (no {CONFIG_FILE}); start one with \
             `ifslab invert3d VIEWS -o {}`",
            dir.display(),
            dir.display()
        );
    }
    let _lock = lock_run_dir(dir)?;
    let cfg = load_run_config(dir)?;
    let path = dir.join(INPUTS_FILE);
    let inputs: Inputs = serde_json::from_slice(&std::fs::read(&path).with_context(|| {
        format!(
            "{} holds no record of its views ({INPUTS_FILE}), so it cannot resume",
            dir.display()
        )
    })?)
    .with_context(|| format!("reading {}", path.display()))?;
    let views = load_views(&inputs.views).with_context(|| {
        format!(
            "reading the views the run in {} fits ({})",
            dir.display(),
            inputs.views.display()
        )
    })?;
    if views.digest() != inputs.views_digest {
        anyhow::bail!(
            "the views in {} changed since the run in {} started (their fingerprint was {}, \
             now {}); a resumed run must fit the pictures it started on",
            inputs.views.display(),
            dir.display(),
            inputs.views_digest,
            views.digest()
        );
    }
    let truth = inputs.truth.as_deref().map(code3).transpose()?;
    let other = match &inputs.score_views {
        Some(d) => Some(
            load_views(d)
                .with_context(|| format!("reading the views to score in {}", d.display()))?,
        ),
        None => None,
    };
    fit(
        &cfg,
        &views,
        &inputs.views,
        dir,
        true,
        truth,
        other.as_ref(),
    )
}

/// The fit of `cfg` on `views` into `out` (resumed with `resume`), its outputs and the
/// lines that report it.
fn fit(
    cfg: &Image3dConfig,
    views: &Views,
    views_dir: &Path,
    out: &Path,
    resume: bool,
    truth: Option<(Vec<Affine3>, Option<Vec<f64>>)>,
    other: Option<&Views>,
) -> anyhow::Result<()> {
    let (w, h) = views.size();
    eprintln!(
        "{} views of {w}×{h} from {}; {} maps, {} iterations of {} → {}{}",
        views.len(),
        views_dir.display(),
        cfg.maps,
        cfg.iterations,
        cfg.strategy.name(),
        out.display(),
        if resume { " (resumed)" } else { "" }
    );
    let pb = ProgressBar::hidden();
    let bar = Bar::of(pb.clone());
    let observer = ProgressObserver::new(Box::new(Bar::of(pb)));
    let outcome = run_image3d_in(cfg, views, out, resume, &bar, vec![Box::new(observer)]).map_err(
        |e| match e {
            ifslab_strategies::Error::Interrupted(_) => anyhow::Error::new(e).context(format!(
                "continue it with `ifslab invert3d --resume {}`",
                out.display()
            )),
            e => e.into(),
        },
    )?;
    let truth_ref = truth.as_ref().map(|(m, p)| (m.as_slice(), p.as_deref()));
    let s = write_outputs(out, cfg, views, &outcome, truth_ref, other)?;
    println!(
        "{}: hull {} voxels + EM in {:.1} s, {} iterations in {:.1} s; loss baseline {:.5} → \
         fit {:.5} ({}){}",
        out.display(),
        s.hull_voxels,
        s.seconds[0],
        s.iterations,
        s.seconds[1],
        s.loss.baseline,
        s.loss.fit,
        s.returned,
        match (&s.baseline, &s.fit) {
            (Some(b), Some(f)) => format!(
                "; voxel IoU baseline {:.3} → fit {:.3}, Chamfer {:.4} → {:.4}",
                b.voxel_iou, f.voxel_iou, b.chamfer, f.chamfer
            ),
            _ => String::new(),
        }
    );
    print!(
        "ink of the renders over the views': baseline {:.2}, fit {:.2}",
        s.ink_ratio[0], s.ink_ratio[1]
    );
    match &s.held_out {
        Some(h) => println!(
            "; held-out views {:?}: loss baseline {:.5} → fit {:.5}, ink {:.2} → {:.2}",
            h.views, h.loss[0], h.loss[1], h.ink_ratio[0], h.ink_ratio[1]
        ),
        None => println!(),
    }
    if let Some(h) = &s.other_views {
        println!(
            "other views ({}): loss baseline {:.5} → fit {:.5}, ink {:.2} → {:.2}",
            h.views.len(),
            h.loss[0],
            h.loss[1],
            h.ink_ratio[0],
            h.ink_ratio[1]
        );
    }
    Ok(())
}

/// `VIEWS-invert3d` beside the views folder.
fn default_output(views: &Path) -> PathBuf {
    let name = views
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "views".into());
    views.with_file_name(format!("{name}-invert3d"))
}

fn render(a: &Args, spec: &str) -> anyhow::Result<()> {
    let dir = a.views.as_deref().expect("clap: VIEWS or --resume");
    let (maps, probs) = code3(spec)?;
    let table = TurntableFile {
        views: a.views_count,
        elevation_deg: 25.0,
        distance: 4.0,
        fov_x_deg: Some(50.0),
        orthographic_extent: None,
        files: None,
    };
    let cameras = table.cameras(a.size, a.size)?;
    let mut render = Render3dConfig::default().multi_view();
    render.supersample = 1;
    render.sigma = 0.8;
    render.game.trajectories = 400;
    let planes = render_code(&maps, &cameras, &render, probs.as_deref(), a.seed)?;
    write_views(dir, &table, a.size, a.size, &planes)?;
    println!(
        "{} views of {}² of {spec} → {}",
        a.views_count,
        a.size,
        dir.display()
    );
    Ok(())
}
