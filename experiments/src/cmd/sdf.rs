//! `ifslab sdf`: segment-pattern IFSs drawn with the differentiable SDF raster — `fit` a
//! pattern's control points to an image, `render` a pattern (built-in, file, or a fit's
//! `pattern.json`) to a PNG.

use std::path::{Path, PathBuf};

use anyhow::Context;
use ifslab::model::segment::{BUILTIN_PATTERNS, PatternFile, builtin};
use ifslab::render::FIT_FILL;
use ifslab::render::image_io::{BitDepth, save_grey_png};
use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView, WordTree};
use ifslab_experiments::runs::RunConfig;
use ifslab_strategies::driver::Params;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image::Polarity;
use ifslab_strategies::problems::sdf::SdfInit;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

// Parsed once per process: the size of the larger variant costs nothing.
#[allow(clippy::large_enum_variant)]
#[derive(clap::Subcommand, Debug)]
pub enum Command {
    /// Fit a pattern's control points to a target image (Adam on multi-scale MSE).
    Fit(FitArgs),
    /// Draw a pattern (built-in name, pattern file, or a fit's pattern.json) to a PNG.
    Render(RenderArgs),
}

/// `ifslab sdf fit`'s flags: a shorthand for a `problem = "sdf"` config. Flags left out are
/// left out of the config too, so the recipe (ifslab's, or Scott's with `--paper`) decides
/// them exactly as it does for `ifslab run`.
#[derive(clap::Args, Debug)]
pub struct FitArgs {
    /// The target image (the shape dark on light, or bright on dark: see --polarity).
    #[arg(required_unless_present = "resume")]
    pub target: Option<PathBuf>,
    /// A built-in pattern (koch, carpet, carpet-square) or a pattern file (.json).
    #[arg(long, default_value = "koch")]
    pub pattern: String,
    /// Scott's recipe instead of ifslab's: the best-fit-line start, --sigma as given, 128².
    /// ifslab's (the default): the best of up to seven starts, σ as wide as the picture's strokes
    /// and 0.75 and 0.5 times that (three fits, the one closest to the target kept), 192²
    /// (robustness/README.md measures both).
    #[arg(long)]
    pub paper: bool,
    /// Which way round the target's shape is drawn: auto (decide from the picture),
    /// bright-on-dark or dark-on-light.
    #[arg(long)]
    pub polarity: Option<Polarity>,
    /// Recursion depth K. [default: 5]
    #[arg(long)]
    pub depth: Option<usize>,
    /// Side of the (square, framed) target in pixels. [default: 192; --paper: 128]
    #[arg(long)]
    pub size: Option<usize>,
    /// Width σ of the drawn figure in pixels; with a segment base figure ifslab's recipe
    /// takes the picture's stroke width instead (set --sigma to fix it). [default: 1.5]
    #[arg(long)]
    pub sigma: Option<f64>,
    /// Multiples of the strokes' σ to fit at, one whole fit each, the one whose render agrees
    /// best with the target kept (comma-separated; 1 = a single fit at the strokes' σ).
    /// [default: 1,0.75,0.5; --paper: none]
    #[arg(long, value_delimiter = ',')]
    pub sigma_factors: Option<Vec<f64>>,
    /// Fit twice more (coarse to fine, and with a distance term) when the kept fit's render
    /// agrees with the target on an IoU below this; 0 never. [default: 0.5; --paper: 0]
    #[arg(long)]
    pub rescue_below: Option<f64>,
    /// Coarse to fine: σ at the first iteration, shrinking geometrically to --sigma.
    /// [default: none]
    #[arg(long)]
    pub sigma_start: Option<f64>,
    /// Iterations over which σ shrinks from --sigma-start. [default: all of them]
    #[arg(long)]
    pub sigma_iterations: Option<u64>,
    /// 2×2 poolings of the multi-scale MSE after the full-resolution level. [default: 4]
    #[arg(long)]
    pub levels: Option<usize>,
    /// Iterations (300, 3e2, 1K). [default: 300]
    #[arg(long, visible_alias = "iters", value_parser = ifslab::budget::parse_count)]
    pub iterations: Option<u64>,
    /// Adam's learning rate (control points live in the unit square). [default: 2e-3]
    #[arg(long)]
    pub lr: Option<f64>,
    /// Weight of the multi-scale MSE on distance values (0: pixels only). [default: 0]
    #[arg(long)]
    pub distance_weight: Option<f64>,
    /// Weight of the self-crossing penalty on the base figure's copies (0: off). [default: 0]
    #[arg(long)]
    pub crossing_weight: Option<f64>,
    /// Length of the words whose copies the crossing penalty compares (1–3). [default: 1]
    #[arg(long)]
    pub crossing_depth: Option<usize>,
    /// Weight of the barrier on map scales above --max-scale (0: off; keeps the fit an IFS).
    /// [default: 0]
    #[arg(long)]
    pub scale_barrier: Option<f64>,
    /// The scale above which the barrier acts, in (0, 1). [default: 0.9]
    #[arg(long)]
    pub max_scale: Option<f64>,
    /// Where the points start: line (the paper's best-fit line), pattern (its shape on that
    /// line), given (the pattern file's points), best (the best of up to seven starts — the line, the
    /// pattern on it, the pattern in the ink's box with its aspect kept and stretched to fill
    /// it, each either way round —, each followed for `init.probe_steps` Adam steps, 80 by
    /// default; `init.stretched = false` in a config leaves the two stretched ones out).
    /// [default: best; --paper: line]
    #[arg(long)]
    pub init: Option<String>,
    /// Gaussian noise added to the start (units of the target's side). [default: 0]
    #[arg(long)]
    pub jitter: Option<f64>,
    /// Seed (of the jitter). [default: 0]
    #[arg(long)]
    pub seed: Option<u64>,
    /// The pattern that drew the target (a built-in name or a pattern file), where it is
    /// known: the summary then reports `truth_iou`, the fit against it, both drawn framed in
    /// their own boxes at 128² (a score that does not depend on the picture's line width).
    #[arg(long)]
    pub truth: Option<String>,
    /// Run folder.
    #[arg(short, long, default_value = "out/sdf")]
    pub output: PathBuf,
    /// Continue the run in the output folder from its last checkpoint (its config.toml says
    /// what it is; no other flag is read).
    #[arg(long)]
    pub resume: bool,
}

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// A built-in pattern, a pattern file, or a fit's pattern.json (drawn in the fit's view,
    /// depth and σ unless overridden).
    pub pattern: String,
    /// Output PNG.
    #[arg(short, long, default_value = "sdf.png")]
    pub output: PathBuf,
    /// Image side in pixels (square).
    #[arg(long)]
    pub size: Option<usize>,
    /// Recursion depth K.
    #[arg(long)]
    pub depth: Option<usize>,
    /// Width σ in pixels.
    #[arg(long)]
    pub sigma: Option<f64>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    match a.command {
        Command::Fit(f) => fit(f),
        Command::Render(r) => render(r),
    }
}

fn fit(a: FitArgs) -> anyhow::Result<()> {
    let run = if a.resume {
        let path = a
            .output
            .join(ifslab_experiments::runs::inversion::CONFIG_FILE);
        // The run's own config, with the flags given now on top (`--iterations 400`
        // continues a fit further).
        let run = RunConfig::load_resolved_with(&path, flag_table(&a)?)
            .with_context(|| format!("reading the run in {}", a.output.display()))?;
        anyhow::ensure!(
            run.problem() == "sdf",
            "{} holds a `{}` run; `ifslab sdf fit --resume` continues segment-pattern fits",
            a.output.display(),
            run.problem()
        );
        run
    } else {
        fit_config(&a)?
    };
    let r = run.run(
        &a.output,
        a.resume,
        Box::new(crate::bars::Bar::for_problem("sdf")),
    )?;
    println!("{}: {}", a.output.display(), r.headline);
    Ok(())
}

/// The flags as a `problem = "sdf"` config, resolved by the recipe they name.
fn fit_config(a: &FitArgs) -> anyhow::Result<RunConfig> {
    let target = a.target.clone().expect("clap: a target unless --resume");
    let mut t = flag_table(a)?;
    for (key, value) in [
        ("problem", "sdf".into()),
        ("paper", a.paper.into()),
        ("target", target.to_string_lossy().into_owned().into()),
        ("pattern", a.pattern.clone().into()),
        ("output", a.output.to_string_lossy().into_owned().into()),
    ] {
        t.insert(key.into(), value);
    }
    // Relative names are the command line's: read from the working directory.
    Ok(RunConfig::from_table(t, Path::new("./the command line"))?)
}

/// The settings given as flags (those left out are not in the table).
fn flag_table(a: &FitArgs) -> anyhow::Result<toml::Table> {
    let mut t = super::Flags::default();
    t.set(
        "polarity",
        a.polarity.map(toml::Value::try_from).transpose()?,
    );
    t.set("depth", super::count(a.depth));
    t.set("truth", a.truth.clone().map(toml::Value::String));
    t.set("size", super::count(a.size));
    t.set("sigma", super::float(a.sigma));
    // A width given is the width drawn.
    t.set("stroke_sigma", a.sigma.map(|_| false.into()));
    t.set(
        "sigma_factors",
        a.sigma_factors
            .as_ref()
            .map(|f| toml::Value::Array(f.iter().map(|&x| x.into()).collect())),
    );
    t.set("rescue_below", super::float(a.rescue_below));
    t.set("sigma_start", super::float(a.sigma_start));
    t.set("sigma_iterations", super::count(a.sigma_iterations));
    t.set("loss.levels", super::count(a.levels));
    t.set("iterations", super::count(a.iterations));
    t.set("seed", super::count(a.seed));
    t.set("loss.distance", super::float(a.distance_weight));
    t.set("loss.crossing", super::float(a.crossing_weight));
    t.set("loss.crossing_depth", super::count(a.crossing_depth));
    t.set("loss.scale_barrier", super::float(a.scale_barrier));
    t.set("loss.max_scale", super::float(a.max_scale));
    if let Some(init) = &a.init {
        let kind = match init.as_str() {
            "line" => SdfInit::Line,
            "pattern" => SdfInit::Pattern,
            "given" => SdfInit::Given,
            "best" => SdfInit::Best,
            other => anyhow::bail!("--init must be line, pattern, given or best, got `{other}`"),
        };
        t.set("init.kind", Some(toml::Value::try_from(kind)?));
    }
    t.set("init.jitter", super::float(a.jitter));
    if let Some(lr) = a.lr {
        t.set("strategy.kind", Some(AdamConfig::KIND.into()));
        t.set("strategy.lr", Some(lr.into()));
    }
    Ok(t.0)
}

fn render(a: RenderArgs) -> anyhow::Result<()> {
    let (pattern, meta) = if BUILTIN_PATTERNS.iter().any(|(n, _)| *n == a.pattern) {
        (builtin(&a.pattern)?, None)
    } else {
        let path = PathBuf::from(&a.pattern);
        let doc = PatternFile::load(&path)?;
        (doc.pattern(&path)?, doc.meta)
    };
    let meta = meta.unwrap_or(serde_json::Value::Null);
    let depth = a
        .depth
        .or_else(|| meta["depth"].as_u64().map(|d| d as usize))
        .unwrap_or(6);
    let sigma = a.sigma.or_else(|| meta["sigma"].as_f64()).unwrap_or(1.0);
    anyhow::ensure!(
        sigma.is_finite() && sigma > 0.0,
        "--sigma must be a width > 0 pixels, got {sigma}"
    );
    let fitted_view: Option<SdfView> = serde_json::from_value(meta["view"].clone()).ok();
    let view = match (fitted_view, a.size) {
        (Some(v), None) => v,
        (Some(v), Some(size)) => {
            // The fit's window at another resolution.
            let side = v.pixel * v.width.max(v.height) as f64;
            SdfView {
                width: size,
                height: size,
                origin: v.origin,
                pixel: side / size as f64,
            }
        }
        (None, size) => {
            let tree = WordTree::new(&pattern.maps()?, pattern.base_points(), depth)?;
            let (lo, hi) = tree.bbox();
            SdfView::around(lo, hi, size.unwrap_or(512), FIT_FILL)
        }
    };
    let r = SdfRaster::render(
        &pattern,
        &view,
        &SdfRenderConfig {
            depth,
            cutoff: Some(6.0 * sigma),
        },
    )?;
    let img: Vec<f32> = r.image(sigma).iter().map(|&v| v as f32).collect();
    save_grey_png(
        &a.output,
        &img,
        view.width as u32,
        view.height as u32,
        BitDepth::Eight,
        true,
    )
    .with_context(|| format!("writing {}", a.output.display()))?;
    println!(
        "{}: `{}` at depth {depth} ({} primitives), {}×{}, σ = {sigma} px",
        a.output.display(),
        pattern.name(),
        r.stats().primitives,
        view.width,
        view.height
    );
    Ok(())
}
