//! `ifslab landscape RUN_DIR`: the objective of an inversion (or segment-map) run on a 2-D slice of parameter
//! space through its recovered code (or the target's true code), as a heat map.

use std::path::PathBuf;

use anyhow::{Context, bail};
use ifslab_experiments::runs::landscape::{Centre, run_landscape};
use ifslab_strategies::problems::image::{Directions, LandscapeConfig};

use crate::bars::Bar;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A run folder written by `invert`, `run` or `demo` (holds config.toml and code.json),
    /// or a segment-map fit by `sdf fit` (config.toml and pattern.json: the slice is through
    /// its control points; θ index 2k, 2k+1 is point k's x, y).
    pub run_dir: PathBuf,
    /// Centre the slice on the recovered code or on the target's true code (code targets);
    /// for a segment-map fit, `truth` is the pattern its config names.
    #[arg(long, value_enum, default_value_t = At::Recovered)]
    pub at: At,
    /// `random` (two filter-normalised random directions) or `I,J` (raw θ coordinates).
    #[arg(long, default_value = "random")]
    pub directions: String,
    /// Seed of the random directions.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Grid points per side (odd).
    #[arg(long, default_value_t = 41)]
    pub resolution: usize,
    /// The grid spans [−extent, extent]² in units of the directions.
    #[arg(long, default_value_t = 1.0)]
    pub extent: f64,
    /// Random streams averaged per grid point.
    #[arg(long, default_value_t = 1)]
    pub streams: u64,
    /// Output PNG (a CSV with the same stem is written beside it).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum At {
    Recovered,
    Truth,
}

fn parse_directions(s: &str, seed: u64) -> anyhow::Result<Directions> {
    if s == "random" {
        return Ok(Directions::Random { seed });
    }
    let parts: Vec<&str> = s.split(',').collect();
    match parts.as_slice() {
        [i, j] => Ok(Directions::Coordinates {
            i: i.trim()
                .parse()
                .context("--directions I,J: I is not an index")?,
            j: j.trim()
                .parse()
                .context("--directions I,J: J is not an index")?,
        }),
        _ => bail!("--directions must be `random` or two θ indices `I,J`, got {s:?}"),
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let lc = LandscapeConfig {
        resolution: a.resolution,
        extent: a.extent,
        directions: parse_directions(&a.directions, a.seed)?,
        streams: a.streams,
    };
    let centre = match a.at {
        At::Recovered => Centre::Recovered,
        At::Truth => Centre::Truth,
    };
    let out = a
        .output
        .unwrap_or_else(|| a.run_dir.join(format!("landscape_{}.png", centre.name())));
    let r = run_landscape(&a.run_dir, centre, &lc, &out, &Bar::default())?;
    let n = r.resolution;
    let (ma, mb, mv) = r.minimum;
    println!(
        "{}: {n}×{n} grid, objective at the centre {:.4}, grid minimum {mv:.4} at (α, β) = ({ma:.3}, {mb:.3}){}",
        out.display(),
        r.centre,
        if r.failed.is_empty() {
            String::new()
        } else {
            format!(
                "; {} points had no loss (first: {})",
                r.failed.len(),
                r.failed[0]
            )
        }
    );
    Ok(())
}
