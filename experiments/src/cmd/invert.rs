//! `ifslab invert TARGET -o DIR`: recover an IFS code from an image (or from a code's render).
//! The flags are a shorthand for a config file: they become the config's keys, the recipe
//! (ifslab's, or the paper's with `--paper`) fills in the rest exactly as it does for
//! `ifslab run`, and the resolved config is written to DIR.

use std::path::{Path, PathBuf};

use anyhow::Context;
use ifslab::model::ParamKind;
use ifslab_strategies::driver::Params;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::optim::hybrid::{ColdHybridConfig, HybridConfig};
use ifslab_strategies::optim::noisy::NoisyConfig;
use ifslab_strategies::problems::image::{
    FIT_FILE, InitKind, InversionConfig, Polarity, StrategyConfig,
};

use ifslab_experiments::runs::RunConfig;
use ifslab_experiments::runs::inversion::{CONFIG_FILE, run_and_report};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Target image (PNG, JPEG, …), or a code file / built-in name whose render is the target.
    #[arg(required_unless_present = "resume")]
    pub target: Option<String>,
    /// Output folder.
    #[arg(short, long, default_value = "out/invert")]
    pub output: PathBuf,
    /// Continue the run in DIR from its last checkpoint (bit-identical to not stopping).
    #[arg(long, value_name = "DIR", conflicts_with = "target")]
    pub resume: Option<PathBuf>,
    /// Number of maps.
    #[arg(long, default_value_t = 3)]
    pub maps: usize,
    /// Optimisation iterations of each run (400, 4e2, 1K). [default: 400; --paper: 2000]
    #[arg(long, visible_alias = "iterations", value_parser = ifslab::budget::parse_count)]
    pub iters: Option<u64>,
    /// Whole runs at seeds --seed, --seed + 1, …, each in a folder of the run (run-0, …),
    /// the one whose render is closest to the target (SSIM) kept; 1 = a single run.
    /// [default: 3; --paper: 1]
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub best_of: Option<u32>,
    /// The chaotic-splatting paper's recipe instead of ifslab's: a random (Anderson–Farrell)
    /// start, the hybrid with its hot annealing, σ fixed, 2000 iterations of 2000 × 250
    /// points. ifslab's (the default): the collage start (or the EM start with maps that may
    /// mirror, whichever matches the picture better), the cold hybrid,
    /// σ 1 → 0.4, 400 iterations of 1000 × 110 points, no LPIPS term, the best of three
    /// seeds (robustness/README.md).
    #[arg(long)]
    pub paper: bool,
    /// Any registered strategy (hybrid, cold_hybrid, adam, annealing, noisy, gd, and the
    /// value-only baselines evolutionary, cmaes, cuckoo and swarm: one generation per
    /// iteration; learning-fractals: Tu et al.'s whole recipe — their rotation–scale–rotation
    /// maps drawn ∝ |det|, 50 × 300 points, summed Gaussians in the fixed window [−5, 5]², MSE,
    /// Adam at 0.05 with clipping, halvings and weight noise; it replaces --param,
    /// --supersample, --sigma, --trajectories and --length). `hybrid`
    /// from a collage or EM start means `cold_hybrid` (τ₀ 0.02, noise 0.05), from a random
    /// one the paper's (τ₀ 1, noise 0.2). [default: the recipe's: hybrid]
    #[arg(long)]
    pub strategy: Option<String>,
    /// Side of the (square) target and render in pixels.
    #[arg(long, default_value_t = 128)]
    pub size: usize,
    /// svd | naive (affine maps).
    #[arg(long, default_value = "svd")]
    pub param: String,
    /// Map family: affine | similitude | flame (linear + sinusoidal variations: not affine, the
    /// result is `fit.json`), or a registered one (see `[model] family` in configs).
    #[arg(long, default_value = "affine")]
    pub family: String,
    /// Supersampling of the differentiable renderer.
    #[arg(long, default_value_t = 4)]
    pub supersample: usize,
    /// Gaussian σ in supersampled pixels.
    #[arg(long, default_value_t = 1.0)]
    pub sigma: f64,
    /// σ at the last iteration: σ shrinks geometrically from --sigma to it (coarse-to-fine;
    /// --sigma-final equal to --sigma keeps it fixed). [default: 0.4; --paper: fixed]
    #[arg(long)]
    pub sigma_final: Option<f64>,
    /// Weight of the LPIPS term of the loss (AlexNet features; needs the weights that
    /// `ifslab weights fetch` puts in the per-user cache). [default: 0; --paper: 2]
    #[arg(long, value_name = "W")]
    pub lpips: Option<f64>,
    /// Where the splat runs: cpu, or cuda (an NVIDIA GPU; needs a build with --features cuda).
    #[arg(long, default_value = "cpu")]
    pub device: ifslab::render::splat::SplatDevice,
    /// Chaos-game trajectories per iteration. [default: 1000; --paper: 2000]
    #[arg(long)]
    pub trajectories: Option<usize>,
    /// Steps per trajectory (10 dropped as warm-up). [default: 110; --paper: 250]
    #[arg(long)]
    pub length: Option<usize>,
    /// Learning rate of Adam-based strategies.
    #[arg(long)]
    pub lr: Option<f64>,
    /// Iterations between annealing phases (hybrid).
    #[arg(long)]
    pub anneal_every: Option<u64>,
    /// Checkpoint every K iterations.
    #[arg(long, default_value_t = 100)]
    pub checkpoint_every: u64,
    /// Seed of the run.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Initial code: collage (affine copies of the target found inside it and assembled
    /// into a cover, or the EM start where its attractor matches the picture better), em
    /// (similitudes fitted by EM to points drawn from the target) or random (an
    /// Anderson–Farrell code: the paper's recipe, which at CPU budgets rarely recovers a
    /// fractal). [default: collage; --paper: random]
    #[arg(long)]
    pub init: Option<String>,
    /// Side in pixels at which the collage start reads the picture (the fit runs at
    /// --size), e.g. 256: thin detail that --size blurs away still shapes the start
    /// (measured in robustness/README.md; not the default). [default: --size]
    #[arg(long)]
    pub start_size: Option<usize>,
    /// Rounds of the collage start's closest-point refinement, which moves each cover of
    /// the picture towards an exact collage before the covers are scored, e.g. 20: a better
    /// start, not a better fit at the default budget (measured in robustness/README.md; not
    /// the default). [default: 0]
    #[arg(long)]
    pub collage_refine: Option<usize>,
    /// Rounds of the IoU polish after the fit: the fitted maps moved (8 proposals a round)
    /// to raise their attractor's IoU with the picture's ink read at 256², kept where a
    /// second draw agrees; 0: off. [default: 0]
    #[arg(long, value_name = "ROUNDS")]
    pub polish: Option<usize>,
    /// Read the picture's grey levels the way the splat makes its own: where the picture is
    /// reduced at least twice into the target, each pixel's level is the share of its cells
    /// (the renderer's supersampling) under which the picture reaches this share of its ink
    /// level, so a thin filament gets the level a splat point gives it rather than a faint
    /// grey; 0 reads the picture's levels as they are (measured in robustness/README.md).
    /// [default: 0.35; --paper: 0]
    #[arg(long, value_name = "SHARE")]
    pub cells: Option<f64>,
    /// Which way round the target's shape is drawn: auto (decide from the border),
    /// bright-on-dark or dark-on-light.
    #[arg(long, default_value = "auto", conflicts_with = "dark_on_light")]
    pub polarity: Polarity,
    /// Short for --polarity dark-on-light.
    #[arg(long)]
    pub dark_on_light: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    if let Some(dir) = a.resume {
        let cfg = match RunConfig::load_resolved(&dir.join(CONFIG_FILE))
            .with_context(|| format!("reading the run in {}", dir.display()))?
        {
            RunConfig::Image(c) => *c,
            other => anyhow::bail!(
                "{} holds a `{}` run; `ifslab invert --resume` continues image inversions",
                dir.display(),
                other.problem()
            ),
        };
        return report(&cfg, &dir, true);
    }
    let cfg = config_from_flags(&a)?;
    report(&cfg, &a.output, false)
}

fn report(cfg: &InversionConfig, dir: &Path, resume: bool) -> anyhow::Result<()> {
    let s = run_and_report(cfg, dir, resume, Box::new(crate::bars::Bar::default()))?;
    println!(
        "{}: {} in {:.1} s, {} → {}",
        dir.display(),
        s.work(),
        s.seconds,
        s.scores(),
        // The affine code file, or the fit file of a family that is not affine.
        [dir.join("code.json"), dir.join(FIT_FILE)]
            .into_iter()
            .find(|p| p.is_file())
            .unwrap_or_else(|| dir.join("code.json"))
            .display()
    );
    Ok(())
}

fn config_from_flags(a: &Args) -> anyhow::Result<InversionConfig> {
    let spec = a.target.clone().expect("clap: target or --resume");
    let is_image = Path::new(&spec).is_file() && !spec.to_ascii_lowercase().ends_with(".json");
    let polarity = if a.dark_on_light {
        Polarity::DarkOnLight
    } else {
        a.polarity
    };
    // The flags as a config table: what a config file with these keys says.
    let mut t = toml::Table::new();
    let mut set = |key: &str, v: toml::Value| {
        ifslab_experiments::sweep::expand::set_dotted(&mut t, key, v)
            .expect("flag keys are distinct config keys");
    };
    set("paper", a.paper.into());
    set("seed", (a.seed as i64).into());
    if let Some(n) = a.iters {
        set("iterations", (n as i64).into());
    }
    if let Some(n) = a.best_of {
        set("best_of", (n as i64).into());
    }
    set("checkpoint_every", (a.checkpoint_every as i64).into());
    set(
        if is_image {
            "target.image"
        } else {
            "target.code"
        },
        spec.clone().into(),
    );
    set("target.size", (a.size as i64).into());
    set("target.polarity", value(&polarity)?);
    set("model.family", a.family.clone().into());
    set("model.maps", (a.maps as i64).into());
    let parameterisation = match a.param.as_str() {
        "svd" => ParamKind::Svd,
        "naive" => ParamKind::Naive,
        "rsr" => ParamKind::Rsr,
        other => anyhow::bail!("unknown parameterisation `{other}`: use svd, naive or rsr"),
    };
    set("model.parameterisation", value(&parameterisation)?);
    if let Some(init) = &a.init {
        let kind = match init.as_str() {
            "random" => InitKind::Random,
            "em" => InitKind::Em,
            "collage" => InitKind::Collage,
            other => anyhow::bail!("unknown --init `{other}`: use collage, em or random"),
        };
        set("model.init", value(&kind)?);
    }
    if let Some(side) = a.start_size {
        set("model.start_size", (side as i64).into());
    }
    if let Some(share) = a.cells {
        set("target.cells", share.into());
    }
    if let Some(rounds) = a.collage_refine {
        set("model.collage_refine", (rounds as i64).into());
    }
    if let Some(rounds) = a.polish {
        set("model.polish", (rounds as i64).into());
    }
    if let Some(n) = a.trajectories {
        set("generator.trajectories", (n as i64).into());
    }
    if let Some(n) = a.length {
        set("generator.length", (n as i64).into());
    }
    set("renderer.supersample", (a.supersample as i64).into());
    set("renderer.sigma", a.sigma.into());
    if let Some(end) = a.sigma_final {
        set("renderer.sigma_final", end.into());
    }
    if let Some(w) = a.lpips {
        set("loss.lpips_weight", w.into());
    }
    if !a.device.is_cpu() {
        set("renderer.device", value(&a.device)?);
    }
    if let Some(name) = &a.strategy {
        // Command-line spelling with hyphens (`learning-fractals`) or underscores.
        let name = name.replace('-', "_");
        let fitted = a
            .init
            .as_deref()
            .unwrap_or(if a.paper { "random" } else { "collage" })
            != "random";
        // From a fitted start (collage or EM) the paper's hot annealing would throw the
        // fit away.
        let kind = if name == HybridConfig::KIND && fitted {
            ColdHybridConfig::KIND.to_owned()
        } else {
            name
        };
        StrategyConfig::by_name(&kind)?;
        set("strategy.kind", kind.into());
    }
    let mut cfg = InversionConfig::from_table(t, Path::new("the command line"))?;
    cfg.output = Some(a.output.clone());
    let strategy = &mut cfg.strategy;
    if let Some(lr) = a.lr {
        let applied = strategy.update(|c: &mut AdamConfig| c.lr = lr)
            || strategy.update(|c: &mut NoisyConfig| c.adam.lr = lr)
            || strategy.update(|c: &mut HybridConfig| c.adam.lr = lr)
            || strategy.update(|c: &mut ColdHybridConfig| c.0.adam.lr = lr);
        anyhow::ensure!(
            applied,
            "--lr applies to adam, noisy and hybrid, not to {}",
            strategy.name()
        );
    }
    if let Some(every) = a.anneal_every {
        anyhow::ensure!(
            strategy.update(|c: &mut HybridConfig| c.anneal_every = every)
                || strategy.update(|c: &mut ColdHybridConfig| c.0.anneal_every = every),
            "--anneal-every applies to hybrid, not to {}",
            strategy.name()
        );
    }
    // A baseline whose recipe is more than an optimiser: its parameterisation, renderer,
    // generator and loss come with it (the flags for those are then not used).
    let lf = ifslab_strategies::optim::learning_fractals::LearningFractalsConfig::KIND;
    let cfg = if cfg.strategy.name() == lf {
        cfg.with_learning_fractals_recipe()
    } else {
        cfg
    };
    cfg.validate()?;
    Ok(cfg)
}

/// A flag's value as a config file writes it.
fn value<T: serde::Serialize>(v: &T) -> anyhow::Result<toml::Value> {
    Ok(toml::Value::try_from(v)?)
}
