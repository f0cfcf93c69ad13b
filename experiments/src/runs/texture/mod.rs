//! Fractal-coding texture upsampling (Kominami & Mukai) as a run: a [`TextureConfig`] in
//! (a source texture, a preset and any of its choices overridden one by one, a factor), a
//! run folder out: the packed code (`code/`), the upsampled texture (`upsampled.png`), the
//! resolved `config.toml` and `summary.json` with the PSNR of the 1× reconstruction, of a
//! hold-out upsampling and the times. With `filter` the folder holds an interpolation
//! baseline instead, scored the same way.
//!
//! Also the pieces `ifslab texture encode` / `upsample` are made of ([`encode_to_dir`],
//! [`upsample_to_file`], [`decode_dir_to_file`]) and the paper's tables and figures
//! ([`repro`]).
//!
//! A texture run is one encoding of seconds and is not checkpointed: `resume` runs it again.
//!
//! ## References
//! - K. Kominami and N. Mukai, *Texture upsampling by fractal coding* (the paper reproduced
//!   in `paper_repro/texture_upsampling`).

mod config;
pub mod repro;

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Context, IoContext, bail};
use ifslab_strategies::problems::fractal_coding::{
    CoordStorage, Filter, FractalCode, Texture, decode, encode, levels_for_factor, load_dir, psnr,
    refine, save_dir, upsample,
};
use serde::{Deserialize, Serialize};

use crate::progress::Progress;
use crate::runs::inversion::CONFIG_FILE;
use crate::runs::table::PROBLEM_KEY;
pub use config::{CandidateCap, Settings, TextureConfig};

/// Loads a source texture with a message that says what is accepted.
pub fn load_texture(path: &Path, grey: bool) -> crate::Result<Texture> {
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

/// An encoding: the code, and what the encoder and refinement reported (for the code
/// folder's manifest).
pub struct Encoded {
    /// The (refined) code.
    pub code: FractalCode,
    /// Settings, encode statistics and the refinement report, as JSON.
    pub info: serde_json::Value,
    /// Seconds of the encoding.
    pub encode_seconds: f64,
    /// Seconds of the refinement.
    pub refine_seconds: f64,
}

/// Encodes (and refines) a texture, reporting what it did to `progress`.
pub fn encode_with(
    tex: &Texture,
    settings: &Settings,
    progress: &dyn Progress,
) -> crate::Result<Encoded> {
    let (enc_cfg, ref_cfg) = (&settings.encoder, &settings.refine);
    let mut enc = encode(tex, enc_cfg)?;
    progress.message(&format!(
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
    ));
    let mut info = serde_json::to_value(settings)?;
    info["encode_stats"] = serde_json::to_value(&enc.stats)?;
    let mut refine_seconds = 0.0;
    if ref_cfg.passes > 0 {
        let rep = refine(&mut enc.code, &enc.candidates, ref_cfg)?;
        progress.message(&format!(
            "refined in {:.2} s: variance of the Laplacian {:.1} → {:.1}, changes per pass {:?}",
            rep.seconds,
            rep.objective[0],
            rep.objective.last().copied().unwrap_or(f64::NAN),
            rep.changes
        ));
        refine_seconds = rep.seconds;
        info["refine_report"] = serde_json::to_value(&rep)?;
    }
    Ok(Encoded {
        code: enc.code,
        info,
        encode_seconds: enc.stats.seconds,
        refine_seconds,
    })
}

/// What writing a code folder measured.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PackReport {
    /// PSNR of the 1× reconstruction from R with the code in memory (dB).
    pub psnr_1x: f64,
    /// The same through the packed 8-bit files (dB).
    pub psnr_1x_packed: f64,
    /// Quantisation step of the packed offsets.
    pub offset_step: f32,
    /// Largest change of an offset by the packing.
    pub max_offset_error: f32,
}

/// Writes `enc` as a packed code folder `dir` and measures the 1× reconstruction of `tex`
/// from the code in memory and from the folder read back.
fn pack(
    tex: &Texture,
    enc: &Encoded,
    storage: CoordStorage,
    dir: &Path,
) -> crate::Result<PackReport> {
    let rec = decode(&enc.code, 1)?;
    let err = save_dir(&enc.code, dir, storage, enc.info.clone())
        .with_context(|| format!("writing the code folder {}", dir.display()))?;
    let (packed, _) = load_dir(dir)?;
    let rec_packed = decode(&packed, 1)?;
    Ok(PackReport {
        psnr_1x: psnr(&rec, tex)?,
        psnr_1x_packed: psnr(&rec_packed, tex)?,
        offset_step: err.offset_step,
        max_offset_error: err.max_offset_error,
    })
}

/// `ifslab texture encode`: encodes `cfg.source` into the packed code folder `out`.
pub fn encode_to_dir(
    cfg: &TextureConfig,
    out: &Path,
    progress: &dyn Progress,
) -> crate::Result<PackReport> {
    let tex = load_texture(&cfg.source, cfg.grey)?;
    let settings = cfg.settings();
    settings.check_storage()?;
    let mut enc = encode_with(&tex, &settings, progress)?;
    enc.info["source"] = cfg.source.display().to_string().into();
    let rep = pack(&tex, &enc, settings.coord_storage, out)?;
    progress.message(&format!(
        "{}: offset step {} (largest offset change {}); 1× reconstruction PSNR {:.2} dB ({:.2} dB from the packed code)",
        out.display(),
        rep.offset_step,
        rep.max_offset_error,
        rep.psnr_1x,
        rep.psnr_1x_packed
    ));
    Ok(rep)
}

/// Decodes `code` at `factor` into the PNG `out`; returns the seconds of the decode.
fn decode_to_file(
    code: &FractalCode,
    factor: u32,
    out: &Path,
    progress: &dyn Progress,
) -> crate::Result<(Texture, f64)> {
    let t0 = Instant::now();
    let up = decode(code, factor)?;
    let secs = t0.elapsed().as_secs_f64();
    up.save_png(out)?;
    progress.message(&format!(
        "{}: {}×{} ({}× the source) decoded in {:.1} ms ({:.1} M texels/s)",
        out.display(),
        up.width(),
        up.height(),
        factor,
        secs * 1e3,
        (up.width() * up.height()) as f64 / secs / 1e6
    ));
    Ok((up, secs))
}

/// `ifslab texture upsample CODE_DIR`: decodes a packed code folder at `factor` into `out`.
pub fn decode_dir_to_file(
    code_dir: &Path,
    factor: u32,
    out: &Path,
    progress: &dyn Progress,
) -> crate::Result<()> {
    levels_for_factor(factor)?;
    let (code, _) = load_dir(code_dir)?;
    decode_to_file(&code, factor, out, progress)?;
    Ok(())
}

/// Upsamples `tex` by an interpolation filter into `out`; returns the seconds.
fn filter_to_file(
    tex: &Texture,
    factor: u32,
    filter: Filter,
    out: &Path,
    progress: &dyn Progress,
) -> crate::Result<(Texture, f64)> {
    let t0 = Instant::now();
    let up = upsample(tex, factor, filter)?;
    let secs = t0.elapsed().as_secs_f64();
    up.save_png(out)?;
    progress.message(&format!(
        "{}: {}×{} by {} in {:.1} ms",
        out.display(),
        up.width(),
        up.height(),
        filter.name(),
        secs * 1e3
    ));
    Ok((up, secs))
}

/// `ifslab texture upsample IN.png`: encodes `cfg.source` and decodes it at `cfg.factor`
/// (or interpolates with `cfg.filter`) into the PNG `out`.
pub fn upsample_to_file(
    cfg: &TextureConfig,
    out: &Path,
    progress: &dyn Progress,
) -> crate::Result<()> {
    levels_for_factor(cfg.factor)?;
    let tex = load_texture(&cfg.source, cfg.grey)?;
    if let Some(f) = cfg.filter {
        filter_to_file(&tex, cfg.factor, f, out, progress)?;
        return Ok(());
    }
    let enc = encode_with(&tex, &cfg.settings(), progress)?;
    if cfg.factor == 1 {
        let rec = decode(&enc.code, 1)?;
        progress.message(&format!(
            "1× reconstruction PSNR {:.2} dB",
            psnr(&rec, &tex)?
        ));
    }
    decode_to_file(&enc.code, cfg.factor, out, progress)?;
    Ok(())
}

/// What `summary.json` of a texture run holds.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TextureSummary {
    /// The source texture.
    pub source: PathBuf,
    /// Its width, height and channels.
    pub size: [usize; 3],
    /// `fractal (PRESET preset)` or the filter's name.
    pub method: String,
    /// The upsampling factor.
    pub factor: u32,
    /// Width and height of `upsampled.png`.
    pub output_size: [usize; 2],
    /// Fractal coding: PSNR of the 1× reconstruction from R (the paper's Table I measure, dB).
    pub psnr_1x: Option<f64>,
    /// Fractal coding: the same through the packed 8-bit code folder (dB).
    pub psnr_1x_packed: Option<f64>,
    /// PSNR of the half-size texture upsampled 2× by the same method against the source
    /// (dB; with `holdout`).
    pub psnr_holdout_2x: Option<f64>,
    /// Seconds of the encoding (fractal coding).
    pub encode_seconds: f64,
    /// Seconds of the refinement (fractal coding).
    pub refine_seconds: f64,
    /// Seconds of the decode or interpolation to the output size.
    pub upsample_seconds: f64,
    /// Wall-clock seconds of the whole run.
    pub seconds: f64,
}

impl TextureSummary {
    /// A line for the terminal.
    pub fn headline(&self) -> String {
        let db = |v: Option<f64>| v.map_or("—".into(), |v| format!("{v:.2} dB"));
        format!(
            "{} {}× in {:.1} s: 1× PSNR {}, hold-out 2× PSNR {}",
            self.method,
            self.factor,
            self.seconds,
            db(self.psnr_1x),
            db(self.psnr_holdout_2x)
        )
    }
}

/// The folder a texture run writes its packed code to.
pub const CODE_DIR: &str = "code";
/// The upsampled texture in a run folder.
pub const UPSAMPLED_FILE: &str = "upsampled.png";

/// Runs the texture config `cfg` into `dir`: the resolved `config.toml`, the packed code
/// (fractal coding), `upsampled.png` and `summary.json`. A run is one encoding of seconds,
/// so there are no checkpoints: with `resume` it runs again from the start.
pub fn run(
    cfg: &TextureConfig,
    dir: &Path,
    resume: bool,
    progress: Box<dyn Progress>,
) -> crate::Result<TextureSummary> {
    let start = Instant::now();
    cfg.validate()?;
    let _lock = crate::runs::lock::lock_run_dir(dir)?;
    let tex = load_texture(&cfg.source, cfg.grey)?;
    std::fs::create_dir_all(dir).doing("creating", dir)?;
    if resume {
        progress.message("a texture run has no checkpoints; running it again from the start");
    }
    let resolved = cfg.resolved()?;
    let text = format!(
        "{PROBLEM_KEY} = \"texture\"\n{}",
        toml::to_string_pretty(&resolved)?
    );
    ifslab::io::write_atomic(&dir.join(CONFIG_FILE), text.as_bytes())?;
    let out = dir.join(UPSAMPLED_FILE);
    let settings = cfg.settings();
    let half = || tex.reduce().context("halving the source for the hold-out");
    let mut s = TextureSummary {
        source: resolved.source.clone(),
        size: [tex.width(), tex.height(), tex.channels()],
        method: String::new(),
        factor: cfg.factor,
        output_size: [0, 0],
        psnr_1x: None,
        psnr_1x_packed: None,
        psnr_holdout_2x: None,
        encode_seconds: 0.0,
        refine_seconds: 0.0,
        upsample_seconds: 0.0,
        seconds: 0.0,
    };
    let up = if let Some(f) = cfg.filter {
        s.method = f.name().into();
        let (up, secs) = filter_to_file(&tex, cfg.factor, f, &out, &*progress)?;
        s.upsample_seconds = secs;
        if cfg.holdout {
            s.psnr_holdout_2x = Some(psnr(&upsample(&half()?, 2, f)?, &tex)?);
        }
        up
    } else {
        s.method = format!("fractal ({} preset)", settings.preset);
        let mut enc = encode_with(&tex, &settings, &*progress)?;
        enc.info["source"] = resolved.source.display().to_string().into();
        let rep = pack(&tex, &enc, settings.coord_storage, &dir.join(CODE_DIR))?;
        s.psnr_1x = Some(rep.psnr_1x);
        s.psnr_1x_packed = Some(rep.psnr_1x_packed);
        s.encode_seconds = enc.encode_seconds;
        s.refine_seconds = enc.refine_seconds;
        let (up, secs) = decode_to_file(&enc.code, cfg.factor, &out, &*progress)?;
        s.upsample_seconds = secs;
        if cfg.holdout {
            let h = encode_with(&half()?, &settings, &crate::progress::Silent)?;
            s.psnr_holdout_2x = Some(psnr(&decode(&h.code, 2)?, &tex)?);
        }
        up
    };
    s.output_size = [up.width(), up.height()];
    s.seconds = start.elapsed().as_secs_f64();
    ifslab::io::write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&s)?.as_bytes(),
    )?;
    Ok(s)
}
