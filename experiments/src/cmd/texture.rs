//! `ifslab texture`: fractal-coding texture upsampling (Kominami & Mukai).
//!
//! - `ifslab texture encode IN.png -o CODE_DIR`: the packed code (three PNGs and a manifest);
//! - `ifslab texture upsample CODE_DIR --factor 8 -o OUT.png`: decode a packed code;
//! - `ifslab texture upsample IN.png --factor 8 -o OUT.png`: encode and decode in one go
//!   (`--factor 1` reconstructs the source from R; `--filter bilinear` etc. for a baseline);
//! - `ifslab texture repro`: the paper's tables and figures (paper_repro/texture_upsampling).
//!
//! `--preset paper|ifslab` picks the settings (the paper's method as published, or this
//! project's default variant); `--matching`, `--grid`, `--distance`, `--delta-e-max`,
//! `--max-candidates`, `--passes`, `--coord-storage` … override one choice at a time.
//! Arguments only: the work is `ifslab_experiments::runs::texture`, whose `TextureConfig`
//! holds the same settings as a `problem = "texture"` config of `ifslab run`.

use std::path::PathBuf;
use std::str::FromStr;

use anyhow::bail;
use ifslab_experiments::runs::texture::{self, CandidateCap, TextureConfig, repro::ReproConfig};
use ifslab_strategies::problems::fractal_coding::{
    CoordStorage, DistanceCentre, Filter, Matching, Preset, Reduction, SearchGrid,
};

use crate::bars::Bar;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(clap::Subcommand, Debug)]
pub enum Command {
    /// Encode a texture into a packed fractal code folder (reduced.png, coords.png,
    /// offsets.png, code.json).
    Encode(EncodeArgs),
    /// Upsample by a power of two, from a code folder or straight from an image.
    Upsample(UpsampleArgs),
    /// Reproduce the paper's Table I, Fig. 4–6 and timing comparison.
    Repro(ReproArgs),
}

/// Encoder, refinement and packing settings shared by `encode` and one-shot `upsample`: a
/// preset, and any of its choices overridden one by one.
#[derive(clap::Args, Debug, Clone)]
pub struct EncodeOpts {
    /// Named settings: `paper` (the method as published: raw SSE, even-index blocks,
    /// |x − 2c| proximity, ΔE_max = 100, all candidates, 3 refinement passes) or `ifslab`
    /// (mean-removed SSE over every block, |x − c| proximity, ΔE_max = 400, 16 candidates,
    /// 4 passes). The options below override single choices.
    #[arg(long, default_value_t = Preset::default(), value_parser = parse_named::<Preset>)]
    pub preset: Preset,
    /// Convert a colour image to grey (Rec. 709 luma) before encoding.
    #[arg(long)]
    pub grey: bool,
    /// Refinement passes (block-coordinate descent on the variance of the Laplacian);
    /// 0 = the plain encoder (β = 0, best block only, unless given below) [default: the
    /// preset's].
    #[arg(long)]
    pub passes: Option<usize>,
    /// How the reduced texture is made: box (2×2 mean, the first mipmap level; both presets)
    /// or binomial (OpenCV's pyrDown) [default: box].
    #[arg(long, value_parser = parse_named::<Reduction>)]
    pub reduction: Option<Reduction>,
    /// Search window half-width in texels of the reduced texture [default: 255].
    #[arg(long)]
    pub window: Option<u32>,
    /// Matching criterion: raw (‖r − d‖², offset afterwards, the paper's Eq. 3) or
    /// mean-removed [default: the preset's].
    #[arg(long, value_parser = parse_named::<Matching>)]
    pub matching: Option<Matching>,
    /// Search set: all, even (even-index blocks, the paper's §IV) or even-offset (blocks at
    /// an even offset from the texel) [default: the preset's].
    #[arg(long, value_parser = parse_named::<SearchGrid>)]
    pub grid: Option<SearchGrid>,
    /// Centre of the proximity term: domain (|x − c|) or range (|x − 2c|, the paper's
    /// Eq. 12) [default: the preset's].
    #[arg(long, value_parser = parse_named::<DistanceCentre>)]
    pub distance: Option<DistanceCentre>,
    /// Proximity weight β (squared grey levels per texel of distance) [default: 1 when
    /// refining, else 0].
    #[arg(long)]
    pub beta: Option<f32>,
    /// Keep candidates whose score is below the best's plus ΔE_max (squared grey levels)
    /// [default: the preset's when refining, else 0].
    #[arg(long)]
    pub delta_e_max: Option<f32>,
    /// Most candidates kept per texel, or `all` [default: the preset's when refining, else 1].
    #[arg(long, value_parser = CandidateCap::from_str)]
    pub max_candidates: Option<CandidateCap>,
    /// Coordinate layout of the packed code: half-signed (the paper's), half-signed-offset
    /// or sign-magnitude [default: the one that holds the grid's codes].
    #[arg(long, value_parser = parse_named::<CoordStorage>)]
    pub coord_storage: Option<CoordStorage>,
}

/// Parses a named setting (preset, matching, grid, …) with the library's message.
pub fn parse_named<T: FromStr<Err = ifslab_strategies::Error>>(s: &str) -> Result<T, String> {
    s.parse()
        .map_err(|e: ifslab_strategies::Error| e.to_string())
}

impl EncodeOpts {
    /// The texture config of `source` with these settings.
    fn config(&self, source: PathBuf, factor: u32, filter: Option<Filter>) -> TextureConfig {
        TextureConfig {
            source,
            factor,
            filter,
            grey: self.grey,
            preset: self.preset,
            passes: self.passes,
            reduction: self.reduction,
            window: self.window,
            matching: self.matching,
            grid: self.grid,
            distance: self.distance,
            beta: self.beta,
            delta_e_max: self.delta_e_max,
            max_candidates: self.max_candidates,
            coord_storage: self.coord_storage,
            ..TextureConfig::default()
        }
    }
}

#[derive(clap::Args, Debug)]
pub struct EncodeArgs {
    /// Source texture (PNG; even sides of at least 4 texels).
    pub input: PathBuf,
    /// Output code folder.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub opts: EncodeOpts,
}

#[derive(clap::Args, Debug)]
pub struct UpsampleArgs {
    /// A code folder from `ifslab texture encode`, or a texture to encode first.
    pub input: PathBuf,
    /// Upsampling factor relative to the source: a power of two (1 = reconstruction from R).
    #[arg(long, default_value_t = 8)]
    pub factor: u32,
    /// Output PNG.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Use an interpolation baseline instead of fractal decoding (nearest, bilinear,
    /// bicubic, lanczos); needs an image input.
    #[arg(long)]
    pub filter: Option<String>,
    #[command(flatten)]
    pub opts: EncodeOpts,
}

#[derive(clap::Args, Debug)]
pub struct ReproArgs {
    /// Output folder (tables, figures, results.json).
    #[arg(short, long, default_value = "paper_repro/texture_upsampling/results")]
    pub out: PathBuf,
    /// Folder with brick.png, grass.png, gravel.png (grey) and wood.png (colour).
    #[arg(long, default_value = "data/textures")]
    pub data: PathBuf,
    /// Only these textures (comma-separated names without .png).
    #[arg(long, value_delimiter = ',')]
    pub textures: Option<Vec<String>>,
    /// Repetitions of each timed decode (the median is reported).
    #[arg(long, default_value_t = 9)]
    pub timing_reps: usize,
    /// Skip figures and timing.
    #[arg(long)]
    pub tables_only: bool,
    /// Skip the one-choice-at-a-time table (the longest part).
    #[arg(long)]
    pub skip_ablation: bool,
    /// Continue an interrupted reproduction in the output folder: the textures it finished
    /// are not done again.
    #[arg(long)]
    pub resume: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let bar = Bar::logging();
    match a.command {
        Command::Encode(e) => {
            let cfg = e.opts.config(e.input, 1, None);
            texture::encode_to_dir(&cfg, &e.output, &bar)?;
        }
        Command::Upsample(u) => {
            let filter = u.filter.as_deref().map(Filter::parse).transpose()?;
            if u.input.is_dir() {
                if filter.is_some() {
                    bail!("--filter needs an image input, not a code folder");
                }
                texture::decode_dir_to_file(&u.input, u.factor, &u.output, &bar)?;
            } else {
                let cfg = u.opts.config(u.input, u.factor, filter);
                texture::upsample_to_file(&cfg, &u.output, &bar)?;
            }
        }
        Command::Repro(r) => {
            let cfg = ReproConfig {
                out: r.out,
                data: r.data,
                textures: r.textures,
                timing_reps: r.timing_reps,
                tables_only: r.tables_only,
                skip_ablation: r.skip_ablation,
            };
            let md = texture::repro::run(&cfg, r.resume, &bar)?;
            eprintln!("{md}");
        }
    }
    Ok(())
}
