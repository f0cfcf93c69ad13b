//! `ifslab run CONFIG.toml`: the run a config file describes (its `problem` key says which
//! problem; image inversion when it has none).

use std::path::PathBuf;

use ifslab_experiments::runs::RunConfig;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The config file (see experiments/configs/).
    pub config: PathBuf,
    /// Output folder (overrides the config's `output`).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Continue the run in the output folder from its last checkpoint (image inversions: the
    /// last checkpointed iteration; points: the finished fits; texture runs have none and
    /// run again).
    #[arg(long)]
    pub resume: bool,
    /// Override a config key before the config is validated (repeatable; dotted keys):
    /// `--set renderer.device=cuda --set iterations=100`. A value is read as TOML
    /// (numbers, booleans, arrays, quoted strings) and otherwise as a string. A resumed run
    /// needs the same overrides.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let cfg = RunConfig::load_with(&a.config, &a.set)?;
    let dir = cfg.output_dir(a.output, "out/run");
    let r = cfg.run(
        &dir,
        a.resume,
        Box::new(crate::bars::Bar::for_problem(cfg.problem())),
    )?;
    println!("{}: {}", dir.display(), r.headline);
    Ok(())
}
