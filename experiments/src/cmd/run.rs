//! `ifslab run CONFIG.toml`: the inversion a config file describes.

use std::path::PathBuf;

use ifslab_strategies::problems::image::InversionConfig;

use ifslab_experiments::runs::inversion::{output_dir, run_and_report};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The config file (see experiments/configs/).
    pub config: PathBuf,
    /// Output folder (overrides the config's `output`).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Continue the run in the output folder from its last checkpoint.
    #[arg(long)]
    pub resume: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let cfg = InversionConfig::load(&a.config)?;
    let dir = output_dir(a.output, &cfg, "out/run");
    let s = run_and_report(&cfg, &dir, a.resume, Box::new(crate::bars::Bar::default()))?;
    println!(
        "{}: {} iterations of {} in {:.1} s, {}",
        dir.display(),
        s.iterations,
        s.strategy,
        s.seconds,
        s.scores()
    );
    Ok(())
}
