//! `ifslab sdf`: segment-pattern IFSs drawn with the differentiable SDF raster — `fit` a
//! pattern's control points to an image, `render` a pattern (built-in, file, or a fit's
//! `pattern.json`) to a PNG.

use std::path::PathBuf;

use anyhow::Context;
use ifslab::model::segment::{BUILTIN_PATTERNS, PatternFile, builtin};
use ifslab::render::FIT_FILL;
use ifslab::render::image_io::{BitDepth, save_grey_png};
use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView, WordTree};
use ifslab_experiments::runs::RunConfig;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image::{Polarity, StrategyConfig};
use ifslab_strategies::problems::sdf::{SdfConfig, SdfInit};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(clap::Subcommand, Debug)]
pub enum Command {
    /// Fit a pattern's control points to a target image (Adam on multi-scale MSE).
    Fit(FitArgs),
    /// Draw a pattern (built-in name, pattern file, or a fit's pattern.json) to a PNG.
    Render(RenderArgs),
}

#[derive(clap::Args, Debug)]
pub struct FitArgs {
    /// The target image (the shape dark on light, or bright on dark: see --polarity).
    pub target: PathBuf,
    /// A built-in pattern (koch, carpet, carpet-square) or a pattern file (.json).
    #[arg(long, default_value = "koch")]
    pub pattern: String,
    /// Which way round the target's shape is drawn: auto (decide from the border),
    /// bright-on-dark or dark-on-light.
    #[arg(long, default_value = "auto")]
    pub polarity: Polarity,
    /// Recursion depth K.
    #[arg(long, default_value_t = 5)]
    pub depth: usize,
    /// Side of the (square, framed) target in pixels.
    #[arg(long, default_value_t = 128)]
    pub size: usize,
    /// Width σ of the drawn figure in pixels.
    #[arg(long, default_value_t = 1.5)]
    pub sigma: f64,
    /// Coarse to fine: σ at the first iteration, shrinking geometrically to --sigma.
    #[arg(long)]
    pub sigma_start: Option<f64>,
    /// Iterations over which σ shrinks from --sigma-start (default: all of them).
    #[arg(long)]
    pub sigma_iterations: Option<u64>,
    /// 2×2 poolings of the multi-scale MSE after the full-resolution level.
    #[arg(long, default_value_t = 4)]
    pub levels: usize,
    /// Iterations.
    #[arg(long, default_value_t = 300)]
    pub iterations: u64,
    /// Adam's learning rate (control points live in the unit square).
    #[arg(long, default_value_t = 2e-3)]
    pub lr: f64,
    /// Weight of the multi-scale MSE on distance values (0: pixels only).
    #[arg(long, default_value_t = 0.0)]
    pub distance_weight: f64,
    /// Weight of the self-crossing penalty on the base figure's copies (0: off).
    #[arg(long, default_value_t = 0.0)]
    pub crossing_weight: f64,
    /// Length of the words whose copies the crossing penalty compares (1–3).
    #[arg(long, default_value_t = 1)]
    pub crossing_depth: usize,
    /// Weight of the barrier on map scales above --max-scale (0: off; keeps the fit an IFS).
    #[arg(long, default_value_t = 0.0)]
    pub scale_barrier: f64,
    /// The scale above which the barrier acts, in (0, 1).
    #[arg(long, default_value_t = 0.9)]
    pub max_scale: f64,
    /// Where the points start: line (the paper's best-fit line), pattern, given.
    #[arg(long, default_value = "line")]
    pub init: String,
    /// Gaussian noise added to the start (units of the target's side).
    #[arg(long, default_value_t = 0.0)]
    pub jitter: f64,
    /// Seed (of the jitter).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Run folder.
    #[arg(short, long, default_value = "out/sdf")]
    pub output: PathBuf,
    /// Continue the run in the output folder from its last checkpoint.
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
    let mut cfg = SdfConfig::new(a.target, a.pattern);
    cfg.depth = a.depth;
    cfg.polarity = a.polarity;
    cfg.size = a.size;
    cfg.sigma = a.sigma;
    cfg.sigma_start = a.sigma_start;
    cfg.sigma_iterations = a.sigma_iterations;
    cfg.loss.levels = a.levels;
    cfg.iterations = a.iterations;
    cfg.seed = a.seed;
    cfg.loss.distance = a.distance_weight;
    cfg.loss.crossing = a.crossing_weight;
    cfg.loss.crossing_depth = a.crossing_depth;
    cfg.loss.scale_barrier = a.scale_barrier;
    cfg.loss.max_scale = a.max_scale;
    cfg.init.kind = match a.init.as_str() {
        "line" => SdfInit::Line,
        "pattern" => SdfInit::Pattern,
        "given" => SdfInit::Given,
        other => anyhow::bail!("--init must be line, pattern or given, got `{other}`"),
    };
    cfg.init.jitter = a.jitter;
    cfg.strategy = StrategyConfig::new(&AdamConfig {
        lr: a.lr,
        ..AdamConfig::default()
    });
    cfg.output = Some(a.output.clone());
    let run = RunConfig::Sdf(Box::new(cfg));
    let r = run.run(
        &a.output,
        a.resume,
        Box::new(crate::bars::Bar::for_problem("sdf")),
    )?;
    println!("{}: {}", a.output.display(), r.headline);
    Ok(())
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
