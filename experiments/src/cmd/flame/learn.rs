//! `ifslab flame learn`: a flame learned from a picture, as a `problem = "flame"` run.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};

use crate::bars::Bar;

/// `ifslab flame learn`'s flags: a shorthand for a `problem = "flame"` config. Flags left
/// out are left out of the config too, so the recipe (ifslab's, or the authors' with
/// `--paper`) decides them exactly as it does for `ifslab run`.
#[derive(clap::Args, Debug)]
pub struct LearnArgs {
    /// The target image (RGB; grey images are used as equal channels, transparency is
    /// composited over the background).
    #[arg(required_unless_present_any = ["config", "resume"])]
    pub target: Option<PathBuf>,
    /// Bannister & Nowrouzezahrai's recipe instead of ifslab's: plain gradient descent with
    /// their per-module rates, on white (ifslab's, the default: Adam with per-group rates,
    /// half their MSE at their budget, on the target's border colour).
    #[arg(long)]
    pub paper: bool,
    /// Flame layers, composited bottom first.
    #[arg(long, default_value_t = 1)]
    pub flames: usize,
    /// Generators per layer. [default: 16; --paper: 8]
    #[arg(long)]
    pub xforms: Option<usize>,
    /// Variations (flam3 names, comma-separated). As many as --flames: one per layer (the
    /// authors' Fighting Forms); otherwise every layer's non-linear generators get all.
    #[arg(long, value_delimiter = ',', default_value = "linear")]
    pub variations: Vec<String>,
    /// Leading generators of each layer that stay linear.
    #[arg(long, default_value_t = 0)]
    pub linear: usize,
    /// Training image side in pixels. [default: 100]
    #[arg(long)]
    pub size: Option<usize>,
    /// Trajectories per layer (each of 1000 steps: the default draws 10⁶ samples).
    /// [default: 1000]
    #[arg(long)]
    pub trajectories: Option<usize>,
    /// Side of the final render beside the training-size one (0: none). [default: 400]
    #[arg(long)]
    pub eval_size: Option<usize>,
    /// Iterations (150, 1.5e2, 1K). [default: 150]
    #[arg(long, visible_alias = "iterations", value_parser = ifslab::budget::parse_count)]
    pub iters: Option<u64>,
    /// `adam`: Adam with per-group rates (half the paper's MSE at Fig. 4's budget,
    /// paper_repro/fractal_flames); `gd`: the paper's plain gradient descent with the
    /// authors' per-module rates. [default: adam; --paper: gd]
    #[arg(long, value_parser = ["gd", "adam"])]
    pub optimiser: Option<String>,
    /// Base learning rate (group rates multiply it). [default: 0.05 for adam, 0.1 for gd]
    #[arg(long)]
    pub lr: Option<f64>,
    /// Background: auto (fixed to the mean colour of the target's border), white, black,
    /// learned. [default: auto; --paper: white]
    #[arg(long)]
    pub background: Option<String>,
    /// Seed of the start and the generator order. [default: 0]
    #[arg(long)]
    pub seed: Option<u64>,
    /// A TOML config (`problem = "flame"`) instead of the flags above.
    #[arg(long, conflicts_with = "target")]
    pub config: Option<PathBuf>,
    /// Run folder.
    #[arg(short, long, default_value = "out/flame")]
    pub output: PathBuf,
    /// Continue the run in the output folder from its last checkpoint (its config.toml says
    /// what it is; no other flag is read).
    #[arg(long)]
    pub resume: bool,
}

pub(super) fn learn(a: LearnArgs) -> anyhow::Result<()> {
    use ifslab_experiments::runs::RunConfig;
    let run = if a.resume {
        let path = a
            .output
            .join(ifslab_experiments::runs::inversion::CONFIG_FILE);
        // The run's own config, with the settings given now on top (`--iters 300`).
        let mut overrides = toml::Table::new();
        if let Some(n) = a.iters {
            overrides.insert("iterations".into(), (n as i64).into());
        }
        RunConfig::load_resolved_with(&path, overrides)
            .with_context(|| format!("reading the run in {}", a.output.display()))?
    } else {
        match &a.config {
            Some(path) => {
                let mut table: toml::Table = std::fs::read_to_string(path)
                    .with_context(|| format!("reading {}", path.display()))?
                    .parse()
                    .with_context(|| format!("{} is not valid TOML", path.display()))?;
                table.insert("output".into(), a.output.to_string_lossy().as_ref().into());
                RunConfig::from_table(table, path)?
            }
            None => RunConfig::from_table(learn_table(&a)?, Path::new("./the command line"))?,
        }
    };
    if run.problem() != "flame" {
        bail!(
            "a `problem = \"{}\"` config; flame learn takes `problem = \"flame\"`",
            run.problem()
        );
    }
    let r = run.run(&a.output, a.resume, Box::new(Bar::for_problem("flame")))?;
    println!("{}: {}", a.output.display(), r.headline);
    Ok(())
}

/// The flags as a `problem = "flame"` config table.
pub(super) fn learn_table(a: &LearnArgs) -> anyhow::Result<toml::Table> {
    if a.flames == 0 {
        bail!("--flames must be at least 1");
    }
    let target = a
        .target
        .clone()
        .expect("clap: a target unless --config or --resume");
    let per_layer = a.variations.len() == a.flames && a.flames > 1;
    let layers: Vec<toml::Value> = (0..a.flames)
        .map(|i| {
            let variations: Vec<toml::Value> = if per_layer {
                vec![a.variations[i].clone().into()]
            } else {
                a.variations.iter().map(|v| v.clone().into()).collect()
            };
            let mut l = toml::Table::new();
            let xforms = a
                .xforms
                .unwrap_or_else(|| ifslab_strategies::problems::flame::default_xforms(a.paper));
            l.insert("xforms".into(), (xforms as i64).into());
            l.insert("variations".into(), variations.into());
            l.insert("linear".into(), (a.linear as i64).into());
            l.into()
        })
        .collect();
    let mut t = crate::cmd::Flags::default();
    t.set("problem", Some("flame".into()));
    t.set("paper", Some(a.paper.into()));
    t.set("target", Some(target.to_string_lossy().into_owned().into()));
    t.set("flames", Some(layers.into()));
    t.set("sampler.size", crate::cmd::count(a.size));
    t.set("sampler.trajectories", crate::cmd::count(a.trajectories));
    t.set("eval_size", crate::cmd::count(a.eval_size));
    t.set("iterations", crate::cmd::count(a.iters));
    t.set("seed", crate::cmd::count(a.seed));
    t.set("background", a.background.clone().map(Into::into));
    let kind = a.optimiser.clone().or_else(|| {
        a.lr.is_some()
            .then(|| if a.paper { "gd" } else { "adam" }.into())
    });
    if let Some(kind) = kind {
        let lr = a.lr.unwrap_or(if kind == "adam" {
            ifslab_strategies::problems::flame::DEFAULT_ADAM_LR
        } else {
            0.1
        });
        t.set("strategy.kind", Some(kind.into()));
        t.set("strategy.lr", Some(lr.into()));
    }
    t.set(
        "output",
        Some(a.output.to_string_lossy().into_owned().into()),
    );
    Ok(t.0)
}
