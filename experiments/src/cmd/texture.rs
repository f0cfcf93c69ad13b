//! `ifslab texture`: fractal-coding texture upsampling (Kominami & Mukai).
//!
//! - `ifslab texture encode IN.png -o CODE_DIR`: the packed code (three PNGs and a manifest);
//! - `ifslab texture upsample CODE_DIR --factor 8 -o OUT.png`: decode a packed code;
//! - `ifslab texture upsample IN.png --factor 8 -o OUT.png`: encode and decode in one go
//!   (`--factor 1` reconstructs the source from R; `--filter bilinear` etc. for a baseline);
//! - `ifslab texture repro`: the paper's tables and figures (paper_repro/texture_upsampling).

mod repro;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use ifslab_strategies::fractal_coding::{
    EncoderConfig, Filter, FractalCode, RefineConfig, Texture, decode, encode, levels_for_factor,
    load_dir, psnr, refine, save_dir, upsample,
};

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

/// Encoder and refinement settings shared by `encode` and one-shot `upsample`.
#[derive(clap::Args, Debug, Clone)]
pub struct EncodeOpts {
    /// Search window half-width in texels of the reduced texture (the paper: 255, the
    /// largest the 8-bit packed format holds).
    #[arg(long, default_value_t = 255)]
    pub window: u32,
    /// Convert a colour image to grey (Rec. 709 luma) before encoding.
    #[arg(long)]
    pub grey: bool,
    /// Refinement passes (block-coordinate descent on the variance of the Laplacian);
    /// 0 = plain fractal coding.
    #[arg(long, default_value_t = 0)]
    pub passes: usize,
    /// Proximity weight β (squared grey levels per texel of distance) [default: 0, or
    /// the refinement default with --passes].
    #[arg(long)]
    pub beta: Option<f32>,
    /// Keep candidates within this score of the best, ΔE_max (squared grey levels)
    /// [default: 0, or the refinement default with --passes].
    #[arg(long)]
    pub delta_e_max: Option<f32>,
    /// Most candidates kept per texel [default: 1, or the refinement default with --passes].
    #[arg(long)]
    pub max_candidates: Option<usize>,
}

/// Candidate-search settings used when refining and the user gives none.
pub const REFINE_BETA: f32 = 1.0;
/// See [`REFINE_BETA`].
pub const REFINE_DELTA_E_MAX: f32 = 400.0;
/// See [`REFINE_BETA`].
pub const REFINE_MAX_CANDIDATES: usize = 16;

impl EncodeOpts {
    /// The resolved encoder and refinement settings.
    pub fn configs(&self) -> (EncoderConfig, RefineConfig) {
        let refining = self.passes > 0;
        let enc = EncoderConfig {
            window: self.window,
            beta: self
                .beta
                .unwrap_or(if refining { REFINE_BETA } else { 0.0 }),
            delta_e_max: self.delta_e_max.unwrap_or(if refining {
                REFINE_DELTA_E_MAX
            } else {
                0.0
            }),
            max_candidates: self.max_candidates.unwrap_or(if refining {
                REFINE_MAX_CANDIDATES
            } else {
                1
            }),
        };
        (
            enc,
            RefineConfig {
                passes: self.passes,
            },
        )
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
    opts: &EncodeOpts,
) -> anyhow::Result<(FractalCode, serde_json::Value)> {
    let (enc_cfg, ref_cfg) = opts.configs();
    let mut enc = encode(tex, &enc_cfg)?;
    eprintln!(
        "encoded {}×{}×{} in {:.2} s: {} candidates scored, mean collage SSE {:.1}, {:.2} candidates/texel",
        tex.width(),
        tex.height(),
        tex.channels(),
        enc.stats.seconds,
        enc.stats.candidates_scored,
        enc.stats.mean_sse,
        enc.stats.mean_candidates
    );
    let mut info = serde_json::json!({
        "encoder": enc_cfg,
        "refine": ref_cfg,
        "encode_stats": enc.stats,
    });
    if ref_cfg.passes > 0 {
        let rep = refine(&mut enc.code, &enc.candidates, &ref_cfg)?;
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
    let (code, mut info) = encode_with(&tex, &a.opts)?;
    info["source"] = a.input.display().to_string().into();
    let rec = decode(&code, 1)?;
    let err = save_dir(&code, &a.output, info)
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
    let (code, _) = encode_with(&tex, &a.opts)?;
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
