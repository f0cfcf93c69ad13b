//! `ifslab invert TARGET -o DIR`: recover an IFS code from an image (or from a code's render).
//! The flags are a shorthand for a config file; the resolved config is written to DIR.

use std::path::{Path, PathBuf};

use anyhow::Context;
use ifslab::model::ParamKind;
use ifslab_strategies::driver::Params;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::optim::hybrid::{ColdHybridConfig, HybridConfig};
use ifslab_strategies::optim::noisy::NoisyConfig;
use ifslab_strategies::problems::image::config::{
    GeneratorConfig, ModelConfig, RendererConfig, TargetConfig,
};
use ifslab_strategies::problems::image::{InitKind, InversionConfig, Polarity, StrategyConfig};

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
    /// Optimisation iterations.
    #[arg(long, default_value_t = 2000)]
    pub iters: u64,
    /// Any registered strategy (hybrid, cold_hybrid, adam, annealing, noisy, gd, and the
    /// value-only baselines evolutionary, cmaes, cuckoo and swarm: one generation per
    /// iteration; learning-fractals: Tu et al.'s whole recipe — their rotation–scale–rotation
    /// maps drawn ∝ |det|, 50 × 300 points, summed Gaussians in the fixed window [−5, 5]², MSE,
    /// Adam at 0.05 with clipping, halvings and weight noise; it replaces --param,
    /// --supersample, --sigma, --trajectories and --length). `hybrid`
    /// from an EM start means `cold_hybrid` (τ₀ 0.02, noise 0.05), from a random one the
    /// paper's (τ₀ 1, noise 0.2).
    #[arg(long, default_value = "hybrid")]
    pub strategy: String,
    /// Side of the (square) target and render in pixels.
    #[arg(long, default_value_t = 128)]
    pub size: usize,
    /// svd | naive (affine maps).
    #[arg(long, default_value = "svd")]
    pub param: String,
    /// Map family: affine | similitude (see `[model] family` in configs).
    #[arg(long, default_value = "affine")]
    pub family: String,
    /// Supersampling of the differentiable renderer.
    #[arg(long, default_value_t = 4)]
    pub supersample: usize,
    /// Gaussian σ in supersampled pixels.
    #[arg(long, default_value_t = 1.0)]
    pub sigma: f64,
    /// σ at the last iteration: σ shrinks geometrically from --sigma to it (coarse-to-fine).
    #[arg(long)]
    pub sigma_final: Option<f64>,
    /// Where the splat runs: cpu, or cuda (an NVIDIA GPU; needs a build with --features cuda).
    #[arg(long, default_value = "cpu")]
    pub device: ifslab::render::splat::SplatDevice,
    /// Chaos-game trajectories per iteration.
    #[arg(long, default_value_t = 2000)]
    pub trajectories: usize,
    /// Steps per trajectory (10 dropped as warm-up).
    #[arg(long, default_value_t = 250)]
    pub length: usize,
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
    /// Initial code: em (similitudes fitted by EM to points drawn from the target, the
    /// reliable start) or random (an Anderson–Farrell code: the paper's recipe, which at CPU
    /// budgets rarely recovers a fractal).
    #[arg(long, default_value = "em")]
    pub init: String,
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
        let cfg = InversionConfig::load(&dir.join(CONFIG_FILE))
            .with_context(|| format!("reading the run in {}", dir.display()))?;
        return report(&cfg, &dir, true);
    }
    let cfg = config_from_flags(&a)?;
    report(&cfg, &a.output, false)
}

fn report(cfg: &InversionConfig, dir: &Path, resume: bool) -> anyhow::Result<()> {
    let s = run_and_report(cfg, dir, resume, Box::new(crate::bars::Bar::default()))?;
    println!(
        "{}: {} iterations of {} in {:.1} s, {} → {}",
        dir.display(),
        s.iterations,
        s.strategy,
        s.seconds,
        s.scores(),
        dir.join("code.json").display()
    );
    Ok(())
}

fn config_from_flags(a: &Args) -> anyhow::Result<InversionConfig> {
    let spec = a.target.clone().expect("clap: target or --resume");
    let is_image = Path::new(&spec).is_file() && !spec.to_ascii_lowercase().ends_with(".json");
    let target = TargetConfig {
        image: is_image.then(|| PathBuf::from(&spec)),
        code: (!is_image).then(|| spec.clone()),
        suite: None,
        index: None,
        size: a.size,
        polarity: if a.dark_on_light {
            Polarity::DarkOnLight
        } else {
            a.polarity
        },
    };
    let init = match a.init.as_str() {
        "random" => InitKind::Random,
        "em" => InitKind::Em,
        other => anyhow::bail!("unknown --init `{other}`: use em or random"),
    };
    let mut strategy = match (a.strategy.as_str(), init) {
        // From an EM fit the paper's hot annealing would throw the fit away.
        ("hybrid", InitKind::Em) => StrategyConfig::new(&ColdHybridConfig::default()),
        // Command-line spelling with hyphens (`learning-fractals`) or underscores.
        (name, _) => StrategyConfig::by_name(&name.replace('-', "_"))?,
    };
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
    let parameterisation = match a.param.as_str() {
        "svd" => ParamKind::Svd,
        "naive" => ParamKind::Naive,
        "rsr" => ParamKind::Rsr,
        other => anyhow::bail!("unknown parameterisation `{other}`: use svd, naive or rsr"),
    };
    let cfg = InversionConfig {
        seed: a.seed,
        iterations: a.iters,
        checkpoint_every: a.checkpoint_every,
        output: Some(a.output.clone()),
        target,
        model: ModelConfig {
            family: a.family.clone(),
            maps: a.maps,
            parameterisation,
            init,
            ..Default::default()
        },
        generator: GeneratorConfig {
            trajectories: a.trajectories,
            length: a.length,
            ..GeneratorConfig::default()
        },
        renderer: RendererConfig {
            supersample: a.supersample,
            sigma: a.sigma,
            sigma_final: a.sigma_final,
            device: a.device,
            ..RendererConfig::default()
        },
        loss: Default::default(),
        strategy,
    };
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
