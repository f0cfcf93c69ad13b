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

mod repro;

use std::path::{Path, PathBuf};
use std::time::Instant;

use std::str::FromStr;

use anyhow::{Context, bail};
use ifslab_strategies::problems::fractal_coding::{
    CoordStorage, DistanceCentre, EncoderConfig, Filter, FractalCode, Matching, Preset, Reduction,
    RefineConfig, SearchGrid, Texture, decode, encode, levels_for_factor, load_dir, psnr, refine,
    save_dir, upsample,
};
use serde::Serialize;

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
    Repro(repro::Args),
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
    #[arg(long, value_parser = parse_cap)]
    pub max_candidates: Option<CandidateCap>,
    /// Coordinate layout of the packed code: half-signed (the paper's), half-signed-offset
    /// or sign-magnitude [default: the one that holds the grid's codes].
    #[arg(long, value_parser = parse_named::<CoordStorage>)]
    pub coord_storage: Option<CoordStorage>,
}

/// A cap on the candidates kept per texel; `None` keeps all of Ω.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CandidateCap(pub Option<usize>);

fn parse_cap(s: &str) -> Result<CandidateCap, String> {
    if s == "all" {
        return Ok(CandidateCap(None));
    }
    s.parse::<usize>()
        .ok()
        .filter(|&n| n > 0)
        .map(|n| CandidateCap(Some(n)))
        .ok_or_else(|| format!("`{s}` is neither `all` nor a whole number ≥ 1"))
}

/// Parses a named setting (preset, matching, grid, …) with the library's message.
pub fn parse_named<T: FromStr<Err = ifslab_strategies::Error>>(s: &str) -> Result<T, String> {
    s.parse()
        .map_err(|e: ifslab_strategies::Error| e.to_string())
}

/// Resolved settings of one encoding.
#[derive(Clone, Debug, Serialize)]
pub struct Settings {
    /// The preset the settings start from.
    pub preset: Preset,
    /// Encoder settings.
    pub encoder: EncoderConfig,
    /// Refinement settings (0 passes: none).
    pub refine: RefineConfig,
    /// Packed coordinate layout.
    pub coord_storage: CoordStorage,
}

impl Settings {
    /// Refuses, before encoding, a coordinate layout that cannot hold the grid's codes.
    pub fn check_storage(&self) -> anyhow::Result<()> {
        let (storage, grid) = (self.coord_storage, self.encoder.grid);
        if storage == CoordStorage::SignMagnitude {
            if self.encoder.window > 255 {
                bail!(
                    "the sign-magnitude coordinate layout holds relative coordinates up to ±255; \
                     use --window 255 or less"
                );
            }
        } else if storage != CoordStorage::for_grid(grid) {
            let fits = match CoordStorage::for_grid(grid) {
                CoordStorage::SignMagnitude => "sign-magnitude".to_string(),
                other => format!("{other} or sign-magnitude"),
            };
            bail!(
                "the {storage} coordinate layout holds codes of grid `{}` only, not `{grid}`; \
                 use --coord-storage {fits}",
                match storage {
                    CoordStorage::HalfSignedOffset => SearchGrid::EvenOffset,
                    _ => SearchGrid::Even,
                },
            );
        }
        Ok(())
    }
}

impl EncodeOpts {
    /// The resolved encoder, refinement and packing settings.
    pub fn settings(&self) -> Settings {
        let passes = self.passes.unwrap_or(self.preset.refine().passes);
        let mut enc = self.preset.encoder(passes > 0);
        if let Some(v) = self.reduction {
            enc.reduction = v;
        }
        if let Some(v) = self.window {
            enc.window = v;
        }
        if let Some(v) = self.matching {
            enc.matching = v;
        }
        if let Some(v) = self.grid {
            enc.grid = v;
        }
        if let Some(v) = self.distance {
            enc.distance = v;
        }
        if let Some(v) = self.beta {
            enc.beta = v;
        }
        if let Some(v) = self.delta_e_max {
            enc.delta_e_max = v;
        }
        if let Some(v) = self.max_candidates {
            enc.max_candidates = v.0;
        }
        Settings {
            preset: self.preset,
            coord_storage: self
                .coord_storage
                .unwrap_or(CoordStorage::for_grid(enc.grid)),
            encoder: enc,
            refine: RefineConfig { passes },
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

pub fn run(a: Args) -> anyhow::Result<()> {
    match a.command {
        Command::Encode(e) => run_encode(e),
        Command::Upsample(u) => run_upsample(u),
        Command::Repro(r) => repro::run(r),
    }
}

/// Loads a source texture with a message that says what is accepted.
pub fn load_texture(path: &Path, grey: bool) -> anyhow::Result<Texture> {
    if !path.exists() {
        bail!("{} does not exist", path.display());
    }
    Texture::load(path, grey).with_context(|| {
        format!(
            "reading {} as a texture (PNG or JPEG, grey or colour)",
            path.display()
        )
    })
}

/// Encodes (and refines) a texture, reporting what it did on stderr.
pub fn encode_with(
    tex: &Texture,
    settings: &Settings,
) -> anyhow::Result<(FractalCode, serde_json::Value)> {
    let (enc_cfg, ref_cfg) = (&settings.encoder, &settings.refine);
    let mut enc = encode(tex, enc_cfg)?;
    eprintln!(
        "encoded {}×{}×{} in {:.2} s (preset {}): {} candidates scored, mean collage SSE {:.1}, \
         {:.2} candidates/texel (most {})",
        tex.width(),
        tex.height(),
        tex.channels(),
        enc.stats.seconds,
        settings.preset,
        enc.stats.candidates_scored,
        enc.stats.mean_sse,
        enc.stats.mean_candidates,
        enc.stats.most_candidates
    );
    let mut info = serde_json::to_value(settings)?;
    info["encode_stats"] = serde_json::to_value(&enc.stats)?;
    if ref_cfg.passes > 0 {
        let rep = refine(&mut enc.code, &enc.candidates, ref_cfg)?;
        eprintln!(
            "refined in {:.2} s: variance of the Laplacian {:.1} → {:.1}, changes per pass {:?}",
            rep.seconds,
            rep.objective[0],
            rep.objective.last().copied().unwrap_or(f64::NAN),
            rep.changes
        );
        info["refine_report"] = serde_json::to_value(&rep)?;
    }
    Ok((enc.code, info))
}

fn run_encode(a: EncodeArgs) -> anyhow::Result<()> {
    let tex = load_texture(&a.input, a.opts.grey)?;
    let settings = a.opts.settings();
    settings.check_storage()?;
    let (code, mut info) = encode_with(&tex, &settings)?;
    info["source"] = a.input.display().to_string().into();
    let rec = decode(&code, 1)?;
    let err = save_dir(&code, &a.output, settings.coord_storage, info)
        .with_context(|| format!("writing the code folder {}", a.output.display()))?;
    let (packed, _) = load_dir(&a.output)?;
    let rec_packed = decode(&packed, 1)?;
    eprintln!(
        "{}: offset step {} (largest offset change {}); 1× reconstruction PSNR {:.2} dB ({:.2} dB from the packed code)",
        a.output.display(),
        err.offset_step,
        err.max_offset_error,
        psnr(&rec, &tex)?,
        psnr(&rec_packed, &tex)?
    );
    Ok(())
}

fn run_upsample(a: UpsampleArgs) -> anyhow::Result<()> {
    levels_for_factor(a.factor)?;
    if a.input.is_dir() {
        if a.filter.is_some() {
            bail!("--filter needs an image input, not a code folder");
        }
        let (code, _) = load_dir(&a.input)?;
        return decode_and_save(&code, a.factor, &a.output);
    }
    let tex = load_texture(&a.input, a.opts.grey)?;
    if let Some(f) = &a.filter {
        let filter = Filter::parse(f)?;
        let t0 = Instant::now();
        let out = upsample(&tex, a.factor, filter)?;
        out.save_png(&a.output)?;
        eprintln!(
            "{}: {}×{} by {} in {:.1} ms",
            a.output.display(),
            out.width(),
            out.height(),
            filter.name(),
            t0.elapsed().as_secs_f64() * 1e3
        );
        return Ok(());
    }
    let (code, _) = encode_with(&tex, &a.opts.settings())?;
    if a.factor == 1 {
        let rec = decode(&code, 1)?;
        eprintln!("1× reconstruction PSNR {:.2} dB", psnr(&rec, &tex)?);
    }
    decode_and_save(&code, a.factor, &a.output)
}

fn decode_and_save(code: &FractalCode, factor: u32, out: &Path) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let up = decode(code, factor)?;
    let secs = t0.elapsed().as_secs_f64();
    up.save_png(out)?;
    eprintln!(
        "{}: {}×{} ({}× the source) decoded in {:.1} ms ({:.1} M texels/s)",
        out.display(),
        up.width(),
        up.height(),
        factor,
        secs * 1e3,
        (up.width() * up.height()) as f64 / secs / 1e6
    );
    Ok(())
}
