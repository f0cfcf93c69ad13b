//! `ifslab invert3d VIEWS_DIR --maps N -o OUT`: recover an IFS code of space from pictures
//! taken around it (the flags of a `problem = "image3d"` config, run by
//! [`ifslab_experiments::runs::image3d`], which says what the folder gets). VIEWS_DIR holds
//! the pictures (PNG, all one size) and their cameras: a NeRF-style `transforms.json` or a
//! `turntable.json`. The fit starts from EM in 3-D on the views' visual hull (the
//! baseline) and runs any registered strategy through the multi-view splat. Every
//! `--checkpoint-every` iterations, and when stopped by a signal, it checkpoints;
//! `--resume DIR` continues a stopped run to the result it would have reached without
//! stopping; a fresh run refuses a folder that holds one.
//!
//! With `--render-views CODE` it instead draws the views of a 3-D code into VIEWS_DIR with
//! the library's multi-view splat: `--views` turntable views of `--size`² (what the tests
//! and the README's numbers invert).

use std::path::{Path, PathBuf};

use ifslab_experiments::runs::RunConfig;
use ifslab_experiments::runs::image3d::{self, Image3dRunConfig};
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image3d::{Image3dConfig, MapChoice, Render3dConfig, Start3d};
use ifslab_strategies::strategy_config::StrategyConfig;

use crate::bars::Bar;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum StartArg {
    /// EM in 3-D on points of the views' visual hull (the baseline).
    Hull,
    /// Random maps drawn from the seed.
    Random,
    /// Affine copies of the visual hull found inside it (a collage search in space), or
    /// the hull's EM code where its silhouettes match the views better.
    Collage,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum ChoiceArg {
    /// pᵢ ∝ |det Mᵢ|, floored at 1 % (the library's rule for codes without probabilities).
    Determinant,
    /// Every map equally likely.
    Uniform,
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
    #[arg(long, value_enum, default_value = "collage")]
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
    /// Chaos-game trajectories per step (150 kept points each). [default: 400 per 64² of a view: 1600 at 128²]
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

pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(spec) = &a.render_views {
        let dir = a.views.as_deref().expect("clap: VIEWS or --resume");
        image3d::render_turntable(spec, dir, a.views_count, a.size, a.seed)?;
        println!(
            "{} views of {}² of {spec} → {}",
            a.views_count,
            a.size,
            dir.display()
        );
        return Ok(());
    }
    let (cfg, out, resume) = match &a.resume {
        Some(dir) => (image3d::load_run(dir)?, dir.clone(), true),
        None => {
            let cfg = config(&a)?;
            let out = a
                .output
                .clone()
                .unwrap_or_else(|| default_output(&cfg.views));
            (cfg, out, false)
        }
    };
    eprintln!(
        "{} maps, {} iterations of {} on the views in {} → {}{}",
        cfg.fit.maps,
        cfg.fit.iterations,
        cfg.fit.strategy.name(),
        cfg.views.display(),
        out.display(),
        if resume { " (resumed)" } else { "" }
    );
    let report = RunConfig::Image3d(Box::new(cfg)).run(
        &out,
        resume,
        Box::new(Bar::for_problem("image3d")),
    )?;
    println!("{}: {}", out.display(), report.headline);
    Ok(())
}

/// The run the flags describe.
fn config(a: &Args) -> anyhow::Result<Image3dRunConfig> {
    let mut strategy = StrategyConfig::by_name(&a.strategy)?;
    strategy.update::<AdamConfig>(|c| c.lr = a.lr);
    let defaults = Render3dConfig::default();
    let fit = Image3dConfig {
        maps: a.maps,
        iterations: a.iters,
        seed: a.seed,
        start: match (a.start, &a.start_code) {
            (_, Some(_)) => Start3d::Code,
            (StartArg::Hull, None) => Start3d::Hull,
            (StartArg::Random, None) => Start3d::Random,
            (StartArg::Collage, None) => Start3d::Collage,
        },
        start_code: a.start_code.clone(),
        probabilities: match a.probabilities {
            ChoiceArg::Determinant => MapChoice::Determinant,
            ChoiceArg::Uniform => MapChoice::Uniform,
        },
        strategy,
        render: Render3dConfig {
            trajectories: a.trajectories.or(defaults.trajectories),
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
    // A truth is a built-in name or a file; one that is neither is refused by the run
    // before the fit starts.
    Ok(Image3dRunConfig {
        views: a.views.clone().expect("clap: VIEWS or --resume"),
        truth: a.truth.clone(),
        score_views: a.score_views.clone(),
        output: None,
        fit,
    })
}

/// `VIEWS-invert3d` beside the views folder.
fn default_output(views: &Path) -> PathBuf {
    let name = views
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "views".into());
    views.with_file_name(format!("{name}-invert3d"))
}
