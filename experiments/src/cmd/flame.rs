//! `ifslab flame …`: fractal flames — render `.flame` files like flam3-render, make random
//! flames like flam3-genome, describe flames, turn affine codes into flames.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use ifslab::model::flame::{
    Flame, RandomFlameConfig, VariationKind, estimate_bounds, flame_from_affine, read_flames,
    write_flames,
};
use ifslab::render::flame::draft::usable_random_flame;
use ifslab::render::flame::{Depth, FlameRenderConfig, render_flame};

use crate::bars::{self as progress, Bar};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(clap::Subcommand, Debug)]
pub enum Command {
    /// Render every flame of a .flame file (or the one named) to PNG, as flam3-render does.
    Render(RenderArgs),
    /// Random flames in flam3-genome's style, written as a .flame file.
    Random(RandomArgs),
    /// Describe the flames of a file: transforms, variations, estimated attractor box.
    Info(InfoArgs),
    /// An affine IFS code (JSON file or built-in name) as a linear flame.
    Convert(ConvertArgs),
    /// SSIM and PSNR of two renders' grey (luminance) images, e.g. ours against flam3's.
    Compare(CompareArgs),
    /// Learn a colour flame from an image (Bannister & Nowrouzezahrai): one or more layers
    /// of generators, composited; writes the learned .flame, renders and the loss curve.
    Learn(LearnArgs),
}

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

#[derive(clap::Args, Debug)]
pub struct RandomArgs {
    /// Seed of the first genome (the others use seed + 1, seed + 2, …).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Variations to draw from, by name or flam3 number, comma-separated (all 99 if absent).
    #[arg(long, value_delimiter = ',')]
    pub variations: Vec<String>,
    /// Number of transforms (flam3's random 2–6, maybe with a final transform, if absent).
    #[arg(long)]
    pub xforms: Option<usize>,
    /// Number of flames in the file.
    #[arg(long, default_value_t = 1)]
    pub count: usize,
    /// Image size WIDTH HEIGHT written into the genomes.
    #[arg(long, num_args = 2, value_names = ["WIDTH", "HEIGHT"], default_values_t = [512, 512])]
    pub size: Vec<u32>,
    /// Samples per pixel written into the genomes.
    #[arg(long, default_value_t = 100.0)]
    pub quality: f64,
    /// Drafts tried per genome before giving up on flam3-genome's brightness test (mean
    /// grey ≥ 20/255, ≥ 1 % black and ≤ 5 % white pixels on a quick 100² render).
    #[arg(long, default_value_t = 10)]
    pub tries: u32,
    /// Output .flame file.
    #[arg(short, long, default_value = "random.flame")]
    pub output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The .flame file (optional with --variations).
    pub file: Option<PathBuf>,
    /// List the 99 supported variations and their parameters with flam3's defaults.
    #[arg(long)]
    pub variations: bool,
}

#[derive(clap::Args, Debug)]
pub struct ConvertArgs {
    /// The affine code: a JSON code file or a built-in code's name.
    pub code: String,
    /// Output .flame file.
    #[arg(short, long, default_value = "code.flame")]
    pub output: PathBuf,
    /// Image size WIDTH HEIGHT.
    #[arg(long, num_args = 2, value_names = ["WIDTH", "HEIGHT"], default_values_t = [512, 512])]
    pub size: Vec<u32>,
}

#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// First image.
    pub a: PathBuf,
    /// Second image, same size.
    pub b: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// The .flame file (flam3, Apophysis and JWildfire's flam3 subset).
    pub file: PathBuf,
    /// Output PNG; with several flames, `-N` (the flame's index) is added before `.png`.
    #[arg(short, long, default_value = "flame.png")]
    pub output: PathBuf,
    /// Only the flame with this name.
    #[arg(long)]
    pub name: Option<String>,
    /// Output size WIDTH HEIGHT; the framing is kept (pixels per unit scale with the height,
    /// as a flam3 template does).
    #[arg(long, num_args = 2, value_names = ["WIDTH", "HEIGHT"])]
    pub size: Option<Vec<u32>>,
    /// Samples per output pixel (the flame's `quality`).
    #[arg(long)]
    pub quality: Option<f64>,
    /// Histogram supersampling per side (the flame's `supersample`).
    #[arg(long)]
    pub supersample: Option<u32>,
    /// Seed of the chaos game (the same seed gives the same image on any thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// 16 bits per channel.
    #[arg(long)]
    pub sixteen_bit: bool,
    /// Keep transparency (alpha channel) instead of compositing onto the background.
    #[arg(long)]
    pub alpha: bool,
    /// Composite every flame of the file into one picture, first at the bottom, each drawn
    /// with transparency and laid "over" the first flame's background (a learned flame
    /// stack's layers, as `ifslab flame learn` writes them).
    #[arg(long, conflicts_with = "alpha")]
    pub composite: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::Render(a) => render(a),
        Command::Random(a) => random(a),
        Command::Info(a) => info(a),
        Command::Convert(a) => convert(a),
        Command::Compare(a) => compare(a),
        Command::Learn(a) => learn(a),
    }
}

fn learn(a: LearnArgs) -> anyhow::Result<()> {
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
fn learn_table(a: &LearnArgs) -> anyhow::Result<toml::Table> {
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
    let mut t = super::Flags::default();
    t.set("problem", Some("flame".into()));
    t.set("paper", Some(a.paper.into()));
    t.set("target", Some(target.to_string_lossy().into_owned().into()));
    t.set("flames", Some(layers.into()));
    t.set("sampler.size", super::count(a.size));
    t.set("sampler.trajectories", super::count(a.trajectories));
    t.set("eval_size", super::count(a.eval_size));
    t.set("iterations", super::count(a.iters));
    t.set("seed", super::count(a.seed));
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

/// `flame` with its size and quality overridden as the command line asks.
pub fn apply_overrides(
    flame: &mut Flame,
    size: Option<&[u32]>,
    quality: Option<f64>,
    supersample: Option<u32>,
) -> anyhow::Result<()> {
    if let Some(s) = size {
        let (w, h) = (s[0], s[1]);
        if w == 0 || h == 0 {
            bail!("--size must be at least 1×1, got {w}×{h}");
        }
        flame.scale *= h as f64 / flame.size[1] as f64;
        flame.size = [w, h];
    }
    if let Some(q) = quality {
        if !(q.is_finite() && q > 0.0) {
            bail!("--quality must be > 0, got {q}");
        }
        flame.quality = q;
    }
    if let Some(s) = supersample {
        flame.supersample = s;
    }
    Ok(())
}

fn output_for(base: &Path, index: usize, several: bool) -> PathBuf {
    if !several {
        return base.to_owned();
    }
    let stem = base
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "flame".into());
    base.with_file_name(format!("{stem}-{index}.png"))
}

fn render(a: RenderArgs) -> anyhow::Result<()> {
    let flames = read_flames(&a.file)?;
    let chosen: Vec<(usize, Flame)> = match &a.name {
        Some(n) => {
            let found: Vec<_> = flames
                .into_iter()
                .enumerate()
                .filter(|(_, f)| f.name.as_deref() == Some(n.as_str()))
                .collect();
            if found.is_empty() {
                bail!("no flame named `{n}` in {}", a.file.display());
            }
            found
        }
        None => flames.into_iter().enumerate().collect(),
    };
    let several = chosen.len() > 1 && !a.composite;
    let cfg = FlameRenderConfig {
        seed: a.seed,
        transparent: a.alpha || a.composite,
        ..FlameRenderConfig::default()
    };
    // The composite: RGB in 0–255 over the first flame's background.
    let mut composite: Option<(u32, u32, Vec<[f32; 3]>)> = None;
    for (i, mut flame) in chosen {
        apply_overrides(&mut flame, a.size.as_deref(), a.quality, a.supersample)?;
        let out = output_for(&a.output, i, several);
        let pb = progress::bar(0, "samples");
        let img = render_flame(&flame, &cfg, Some(&Bar::of(pb.clone())))
            .with_context(|| format!("rendering {} of {}", flame.label(), a.file.display()))?;
        pb.finish_and_clear();
        let depth = if a.sixteen_bit {
            Depth::Sixteen
        } else {
            Depth::Eight
        };
        if a.composite {
            let bg = flame.background.map(|v| (v * 255.0) as f32);
            let (w, h, acc) = composite
                .get_or_insert_with(|| (img.width, img.height, vec![bg; img.pixels.len()]));
            if (*w, *h) != (img.width, img.height) {
                bail!(
                    "{}: flames of different sizes ({}×{} and {}×{}) cannot be composited",
                    a.file.display(),
                    w,
                    h,
                    img.width,
                    img.height
                );
            }
            for (d, p) in acc.iter_mut().zip(&img.pixels) {
                for c in 0..3 {
                    d[c] = p[c] * p[3] + d[c] * (1.0 - p[3]);
                }
            }
        } else {
            img.save_png(&out, depth, a.alpha)?;
        }
        let s = &img.stats;
        let bad = s.badvals as f64 / s.samples.max(1) as f64;
        eprintln!(
            "{}: {}×{}, {} samples in {:.2} s ({:.1} M/s), badvals {:.3e} → {}",
            flame.label(),
            img.width,
            img.height,
            s.samples,
            s.seconds,
            s.samples as f64 / s.seconds / 1e6,
            bad,
            out.display()
        );
        if bad > 0.01 {
            eprintln!(
                "warning: {:.1}% of the steps left the plane (NaN or beyond ±1e10) and restarted \
                 from a random point: the flame's orbit diverges",
                100.0 * bad
            );
        }
    }
    if let Some((w, h, acc)) = composite {
        let n = acc.len();
        let mut planes = vec![0f32; 3 * n];
        for (i, p) in acc.iter().enumerate() {
            for c in 0..3 {
                planes[c * n + i] = (p[c] / 255.0).clamp(0.0, 1.0);
            }
        }
        ifslab::image::Image::new(w, h, 3, planes)?.save_png(&a.output)?;
        eprintln!("composite → {}", a.output.display());
    }
    Ok(())
}

fn compare(a: CompareArgs) -> anyhow::Result<()> {
    let ga = ifslab::render::image_io::load_grey(&a.a)?;
    let gb = ifslab::render::image_io::load_grey(&a.b)?;
    if (ga.width, ga.height) != (gb.width, gb.height) {
        bail!(
            "{} is {}×{} but {} is {}×{}",
            a.a.display(),
            ga.width,
            ga.height,
            a.b.display(),
            gb.width,
            gb.height
        );
    }
    let (w, h) = (ga.width as usize, ga.height as usize);
    let ssim = ifslab::metrics::ssim(&ga.values, &gb.values, w, h)?;
    let psnr = ifslab::metrics::psnr(&ga.values, &gb.values, 1.0)?;
    println!("ssim {ssim:.4} psnr {psnr:.2} dB");
    Ok(())
}

fn parse_variation(s: &str) -> anyhow::Result<VariationKind> {
    let s = s.trim();
    if let Ok(n) = s.parse::<usize>() {
        return VariationKind::from_index(n)
            .with_context(|| format!("variation number {n} does not exist (0–98)"));
    }
    VariationKind::from_name(s)
        .with_context(|| format!("unknown variation `{s}` (see `ifslab flame info --variations`)"))
}

fn random(a: RandomArgs) -> anyhow::Result<()> {
    let variations = a
        .variations
        .iter()
        .filter(|s| !s.trim().is_empty())
        .map(|s| parse_variation(s))
        .collect::<anyhow::Result<Vec<_>>>()?;
    if a.count == 0 {
        bail!("--count must be at least 1");
    }
    if a.tries == 0 {
        bail!("--tries must be at least 1");
    }
    let cfg = RandomFlameConfig {
        variations,
        xforms: a.xforms,
        size: [a.size[0], a.size[1]],
        quality: a.quality,
    };
    let mut flames = Vec::with_capacity(a.count);
    for k in 0..a.count as u64 {
        let seed = a.seed.wrapping_add(k);
        let (mut f, passed) = usable_random_flame(seed, &cfg, a.tries as u64)?;
        if !passed {
            eprintln!(
                "warning: genome {k}: no draft passed the brightness test in {} tries; \
                 keeping the last",
                a.tries
            );
        }
        f.name = Some(format!("random-{seed}"));
        flames.push(f);
    }
    write_flames(&a.output, &flames)?;
    eprintln!("wrote {} flame(s) to {}", flames.len(), a.output.display());
    Ok(())
}

fn info(a: InfoArgs) -> anyhow::Result<()> {
    if a.variations {
        for k in VariationKind::ALL {
            let params: Vec<String> = k.params().iter().map(|(n, d)| format!("{n}={d}")).collect();
            println!(
                "{:2} {:<14} {}{}",
                k.index(),
                k.name(),
                if k.is_random() { "(random) " } else { "" },
                params.join(" ")
            );
        }
    }
    let Some(file) = &a.file else {
        if !a.variations {
            bail!("give a .flame file, or --variations");
        }
        return Ok(());
    };
    let flames = read_flames(file)?;
    for (i, f) in flames.iter().enumerate() {
        println!(
            "[{i}] {}: {}×{}, centre ({}, {}), scale {}, zoom {}, rotate {}°, quality {}, \
             supersample {}",
            f.label(),
            f.size[0],
            f.size[1],
            f.center[0],
            f.center[1],
            f.scale,
            f.zoom,
            f.rotate,
            f.quality,
            f.supersample
        );
        let describe = |x: &ifslab::model::flame::Xform| {
            let vars: Vec<String> = x
                .variations
                .iter()
                .map(|v| {
                    let ps: Vec<String> = v
                        .kind()
                        .params()
                        .iter()
                        .zip(v.params())
                        .map(|((n, _), p)| format!("{n}={p}"))
                        .collect();
                    if ps.is_empty() {
                        format!("{} {}", v.kind().name(), v.weight)
                    } else {
                        format!("{} {} ({})", v.kind().name(), v.weight, ps.join(", "))
                    }
                })
                .collect();
            let c = &x.coefs;
            format!(
                "color {} speed {} opacity {}; coefs [{} {} {} {} {} {}]{}; {}",
                x.color,
                x.color_speed,
                x.opacity,
                c[0],
                c[1],
                c[2],
                c[3],
                c[4],
                c[5],
                if x.has_post() { " + post" } else { "" },
                vars.join(", ")
            )
        };
        for (k, x) in f.xforms.iter().enumerate() {
            println!(
                "  xform {k}{}: weight {}, {}{}",
                if x.from_symmetry { " (symmetry)" } else { "" },
                x.weight,
                describe(x),
                if x.chaos.is_empty() {
                    String::new()
                } else {
                    format!(", xaos {:?}", x.chaos)
                }
            );
        }
        if let Some(x) = &f.final_xform {
            println!("  final: {}", describe(x));
        }
        match estimate_bounds(f, 0.01, 100_000, 1) {
            Ok(b) => println!(
                "  attractor box (98 % of 100 000 orbit points): x {:.6} … {:.6}, y {:.6} … {:.6}; \
                 bad values {:.2} %",
                b.min[0],
                b.max[0],
                b.min[1],
                b.max[1],
                100.0 * b.badvals as f64 / b.samples.max(1) as f64
            ),
            Err(e) => println!("  attractor box: {e}"),
        }
    }
    Ok(())
}

fn convert(a: ConvertArgs) -> anyhow::Result<()> {
    let code = crate::cmd::resolve_code(&a.code)?;
    if code.dim() != 2 {
        bail!("{} is a {}-D code; flames are 2-D", a.code, code.dim());
    }
    let maps = code.affine2()?;
    let probs = code.evaluation_probabilities()?;
    let flame = flame_from_affine(code.name.as_deref(), &maps, &probs, [a.size[0], a.size[1]])?;
    write_flames(&a.output, std::slice::from_ref(&flame))?;
    eprintln!(
        "wrote {} ({} linear transforms) to {}",
        flame.label(),
        flame.xforms.len(),
        a.output.display()
    );
    Ok(())
}
