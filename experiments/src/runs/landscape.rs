//! The loss landscape of an inversion run: the objective on a 2-D slice of parameter space
//! through its recovered code (or the target's true code), written as a CSV and a heat map.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, bail};
use ifslab::model::IfsCode;
use ifslab_strategies::problems::image::{
    Directions, ImageProblem, InversionConfig, LandscapeConfig, landscape,
};

use crate::codes::resolve_code;
use crate::plot::{Heat, heatmaps};
use crate::progress::Progress;
use crate::runs::inversion::{CONFIG_FILE, run_target};

/// Which code the slice goes through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Centre {
    /// The run's recovered code (`code.json`).
    Recovered,
    /// The run's target code (code targets only).
    Truth,
}

impl Centre {
    /// `recovered` or `truth`.
    pub fn name(self) -> &'static str {
        match self {
            Centre::Recovered => "recovered",
            Centre::Truth => "truth",
        }
    }
}

/// What a landscape run found.
#[derive(Clone, Debug)]
pub struct LandscapeReport {
    /// Grid points per side.
    pub resolution: usize,
    /// The objective at the slice's centre.
    pub centre: f64,
    /// The grid's minimum and where it is, `(α, β, value)`.
    pub minimum: (f64, f64, f64),
    /// Grid points whose loss could not be evaluated, with why.
    pub failed: Vec<String>,
}

/// Evaluates the landscape of the run in `run_dir` around `centre` on the grid `lc`, writes
/// `out` (PNG heat maps of the objective and of its MS-MSE term) and the CSV beside it.
/// Grid points are reported to `progress`.
pub fn run_landscape(
    run_dir: &Path,
    centre: Centre,
    lc: &LandscapeConfig,
    out: &Path,
    progress: &dyn Progress,
) -> anyhow::Result<LandscapeReport> {
    let cfg_path = run_dir.join(CONFIG_FILE);
    let cfg = InversionConfig::load(&cfg_path)
        .with_context(|| format!("{} is not a run folder", run_dir.display()))?;
    let maps = match centre {
        Centre::Recovered => IfsCode::load(run_dir.join("code.json"))
            .with_context(|| format!("{} has no recovered code", run_dir.display()))?
            .affine2()?,
        Centre::Truth => {
            let Some(spec) = cfg.target.code.as_deref() else {
                bail!("--at truth needs a run whose target is a code, not an image");
            };
            resolve_code(spec)?.affine2()?
        }
    };
    let target = run_target(&cfg, run_dir)?;
    let problem = ImageProblem::from_config(&cfg, target)?;
    let theta = problem
        .model()
        .encode(&maps)
        .context("the centre code cannot be expressed in the run's model")?;
    lc.validate(theta.len())?;
    let cells = (lc.resolution * lc.resolution) as u64;
    progress.start("landscape", cells);
    let l = landscape(&problem, &theta, lc, &|| progress.inc(1))?;
    progress.finish();

    let mut csv = String::from("alpha,beta,total,msmse\n");
    let n = l.alphas.len();
    for (k, (t, m)) in l.total.iter().zip(&l.msmse).enumerate() {
        writeln!(csv, "{},{},{t},{m}", l.alphas[k % n], l.betas[k / n])?;
    }
    ifslab::io::write_atomic(&out.with_extension("csv"), csv.as_bytes())?;
    let (ma, mb, mv) = l.minimum();
    let axes = match lc.directions {
        Directions::Random { .. } => ("α (direction 1)".to_owned(), "β (direction 2)".to_owned()),
        Directions::Coordinates { i, j } => (format!("Δθ[{i}]"), format!("Δθ[{j}]")),
    };
    heatmaps(
        out,
        &format!(
            "loss landscape around the {} code ({})",
            match centre {
                Centre::Recovered => "recovered",
                Centre::Truth => "true",
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
    Ok(LandscapeReport {
        resolution: n,
        centre: l.centre_total(),
        minimum: (ma, mb, mv),
        failed: l.failed.clone(),
    })
}
