//! The loss landscape of an inversion run: the objective on a 2-D slice of parameter space
//! through its recovered code (or the target's true code), written as a CSV and a heat map.
//! Segment-map fits (`problem = "sdf"`) get the same slice through their fitted control
//! points (or the pattern's own points), on the same grid and plots.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::{Context, bail};
use ifslab::model::IfsCode;
use ifslab::model::segment::PatternFile;
use ifslab_strategies::problems::image::{
    Directions, FIT_FILE, FRAMED_TARGET_FILE, FitFile, ImageProblem, Landscape, LandscapeConfig,
    TARGET_READING_FILE, TargetReading, landscape, load_framed_target,
};
use ifslab_strategies::problems::sdf::{SdfConfig, sdf_landscape, sdf_problem};

use crate::codes::resolve_code;
use crate::plot::{Heat, heatmaps};
use crate::progress::Progress;
use crate::runs::RunConfig;
use crate::runs::inversion::{CONFIG_FILE, run_target};
use crate::runs::sdf::FITTED_PATTERN_FILE;

/// Which code the slice goes through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Centre {
    /// The run's recovered code (`code.json`; a segment-map fit's `pattern.json`).
    Recovered,
    /// The run's target code (code targets only); for a segment-map fit, the control
    /// points of the pattern its config names (the truth when the target was drawn from it).
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
) -> crate::Result<LandscapeReport> {
    let cfg_path = run_dir.join(CONFIG_FILE);
    if !cfg_path.is_file() {
        bail!(
            "{} is not a run folder (no readable {CONFIG_FILE})",
            run_dir.display()
        );
    }
    let cfg = match RunConfig::load_resolved(&cfg_path)
        .with_context(|| format!("{} is not a run folder", run_dir.display()))?
    {
        RunConfig::Image(c) => *c,
        RunConfig::Sdf(c) => return run_sdf_landscape(&c, run_dir, centre, lc, out, progress),
        other => bail!(
            "{}: a `{}` run has no loss landscape (image and sdf runs do)",
            run_dir.display(),
            other.problem()
        ),
    };
    let target = run_target(&cfg, run_dir)?;
    let problem = ImageProblem::from_config(&cfg, target)?;
    let fit_path = run_dir.join(FIT_FILE);
    let maps = match centre {
        // The run's own θ where its fit file keeps it (any family, exactly as fitted).
        Centre::Recovered if fit_path.is_file() => None,
        Centre::Recovered => Some(
            IfsCode::load(run_dir.join("code.json"))
                .with_context(|| format!("{} has no recovered code", run_dir.display()))?
                .affine2()?,
        ),
        Centre::Truth => {
            let Some(spec) = cfg.target.code.as_deref() else {
                bail!("--at truth needs a run whose target is a code, not an image");
            };
            Some(resolve_code(spec)?.affine2()?)
        }
    };
    let theta = match maps {
        Some(maps) => problem
            .model()
            .encode(&maps)
            .context("the centre code cannot be expressed in the run's model")?,
        None => FitFile::load(&fit_path)?.theta,
    };
    lc.validate(theta.len())?;
    let cells = (lc.resolution * lc.resolution) as u64;
    progress.start("landscape", cells);
    let l = landscape(&problem, &theta, lc, &|| progress.inc(1))?;
    progress.finish();

    let title = format!(
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
    );
    write_landscape(&l, lc, out, &title, "multi-scale MSE", "θ")
}

/// The landscape of a segment-map fit: the loss over a slice of control-point space.
fn run_sdf_landscape(
    cfg: &SdfConfig,
    run_dir: &Path,
    centre: Centre,
    lc: &LandscapeConfig,
    out: &Path,
    progress: &dyn Progress,
) -> crate::Result<LandscapeReport> {
    if cfg.learned.is_some() {
        bail!(
            "{}: the landscape of a learned-pattern fit is not supported",
            run_dir.display()
        );
    }
    let theta = match centre {
        Centre::Recovered => {
            let path = run_dir.join(FITTED_PATTERN_FILE);
            PatternFile::load(&path)
                .and_then(|f| f.pattern(&path))
                .with_context(|| {
                    format!(
                        "{} has no fitted pattern ({FITTED_PATTERN_FILE}): has the fit finished?",
                        run_dir.display()
                    )
                })?
                .flat_points()
        }
        Centre::Truth => cfg.pattern()?.flat_points(),
    };
    let ink = load_framed_target(&run_dir.join(FRAMED_TARGET_FILE), cfg.size)
        .with_context(|| format!("{} has no framed target", run_dir.display()))?
        .widened();
    let reading = run_dir.join(TARGET_READING_FILE);
    let stroke = if reading.is_file() {
        TargetReading::load(&reading)?.framed_stroke()
    } else {
        None
    };
    let problem = sdf_problem(cfg, ink, stroke)?;
    lc.validate(theta.len())?;
    progress.start("landscape", (lc.resolution * lc.resolution) as u64);
    let l = sdf_landscape(&problem, &theta, lc, &|| progress.inc(1))?;
    progress.finish();
    let title = format!(
        "loss landscape around the {} control points ({})",
        match centre {
            Centre::Recovered => "fitted",
            Centre::Truth => "pattern's",
        },
        cfg.pattern
    );
    write_landscape(&l, lc, out, &title, "pixel MSE", "θ")
}

/// Writes the slice's CSV (`alpha,beta,total,<term>`) beside `out` and its two heat maps
/// (the objective and `term`) to `out`; `param` names θ on coordinate axes.
fn write_landscape(
    l: &Landscape,
    lc: &LandscapeConfig,
    out: &Path,
    title: &str,
    term: &'static str,
    param: &str,
) -> crate::Result<LandscapeReport> {
    let mut csv = String::from("alpha,beta,total,msmse\n");
    let n = l.alphas.len();
    for (k, (t, m)) in l.total.iter().zip(&l.msmse).enumerate() {
        let _ = writeln!(csv, "{},{},{t},{m}", l.alphas[k % n], l.betas[k / n]);
    }
    ifslab::io::write_atomic(&out.with_extension("csv"), csv.as_bytes())?;
    let (ma, mb, mv) = l.minimum();
    let axes = match lc.directions {
        Directions::Random { .. } => ("α (direction 1)".to_owned(), "β (direction 2)".to_owned()),
        Directions::Coordinates { i, j } => (format!("Δ{param}[{i}]"), format!("Δ{param}[{j}]")),
    };
    heatmaps(
        out,
        title,
        (&axes.0, &axes.1),
        &l.alphas,
        &l.betas,
        &[
            Heat {
                title: "objective",
                values: &l.total,
            },
            Heat {
                title: term,
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
