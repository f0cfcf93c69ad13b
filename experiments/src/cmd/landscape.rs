//! `ifslab landscape RUN_DIR`: the objective of an inversion run on a 2-D slice of parameter
//! space through its recovered code (or the target's true code), as a heat map.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, bail};
use ifslab::model::IfsCode;
use ifslab_strategies::problems::image::{
    Directions, ImageProblem, InversionConfig, LandscapeConfig, landscape,
};

use crate::bars::bar;
use crate::cmd::resolve_code;
use ifslab_experiments::plot::{Heat, heatmaps};
use ifslab_experiments::runs::inversion::{CONFIG_FILE, run_target};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A run folder written by `invert`, `run` or `demo` (holds config.toml and code.json).
    pub run_dir: PathBuf,
    /// Centre the slice on the recovered code or on the target's true code (code targets).
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
    let cfg_path = a.run_dir.join(CONFIG_FILE);
    let cfg = InversionConfig::load(&cfg_path)
        .with_context(|| format!("{} is not a run folder", a.run_dir.display()))?;
    let directions = parse_directions(&a.directions, a.seed)?;
    let maps = match a.at {
        At::Recovered => IfsCode::load(a.run_dir.join("code.json"))
            .with_context(|| format!("{} has no recovered code", a.run_dir.display()))?
            .affine2()?,
        At::Truth => {
            let Some(spec) = cfg.target.code.as_deref() else {
                bail!("--at truth needs a run whose target is a code, not an image");
            };
            resolve_code(spec)?.affine2()?
        }
    };
    let target = run_target(&cfg, &a.run_dir)?;
    let problem = ImageProblem::from_config(&cfg, target)?;
    let theta = problem
        .parameterisation()
        .encode(&maps)
        .context("the centre code cannot be expressed in the run's parameterisation")?;
    let lc = LandscapeConfig {
        resolution: a.resolution,
        extent: a.extent,
        directions,
        streams: a.streams,
    };
    lc.validate(theta.len())?;
    let pb = bar((lc.resolution * lc.resolution) as u64, "landscape");
    let l = landscape(&problem, &theta, &lc, &|| pb.inc(1))?;
    pb.finish_and_clear();

    let out = a.output.unwrap_or_else(|| {
        let at = match a.at {
            At::Recovered => "recovered",
            At::Truth => "truth",
        };
        a.run_dir.join(format!("landscape_{at}.png"))
    });
    let mut csv = String::from("alpha,beta,total,msmse\n");
    let n = l.alphas.len();
    for (k, (t, m)) in l.total.iter().zip(&l.msmse).enumerate() {
        writeln!(csv, "{},{},{t},{m}", l.alphas[k % n], l.betas[k / n])?;
    }
    let csv_path = out.with_extension("csv");
    std::fs::write(&csv_path, csv).with_context(|| format!("writing {}", csv_path.display()))?;
    let (ma, mb, mv) = l.minimum();
    let axes = match lc.directions {
        Directions::Random { .. } => ("α (direction 1)".to_owned(), "β (direction 2)".to_owned()),
        Directions::Coordinates { i, j } => (format!("Δθ[{i}]"), format!("Δθ[{j}]")),
    };
    heatmaps(
        &out,
        &format!(
            "loss landscape around the {} code ({})",
            match a.at {
                At::Recovered => "recovered",
                At::Truth => "true",
            },
            cfg.target
                .code
                .as_deref()
                .or(cfg.target.image.as_ref().and_then(|p| p.to_str()))
                .unwrap_or("target")
        ),
        (&axes.0, &axes.1),
        &l.alphas,
        &l.betas,
        &[
            Heat {
                title: "objective",
                values: &l.total,
            },
            Heat {
                title: "multi-scale MSE",
                values: &l.msmse,
            },
        ],
        &if (ma, mb) == (0.0, 0.0) {
            vec![("θ* = min", 0.0, 0.0)]
        } else {
            vec![("θ*", 0.0, 0.0), ("min", ma, mb)]
        },
    )?;
    println!(
        "{}: {n}×{n} grid, objective at the centre {:.4}, grid minimum {mv:.4} at (α, β) = ({ma:.3}, {mb:.3}){}",
        out.display(),
        l.centre_total(),
        if l.failed.is_empty() {
            String::new()
        } else {
            format!(
                "; {} points had no loss (first: {})",
                l.failed.len(),
                l.failed[0]
            )
        }
    );
    Ok(())
}
