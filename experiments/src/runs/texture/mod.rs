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

pub mod repro;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use ifslab_strategies::problems::fractal_coding::{
    CoordStorage, DistanceCentre, EncoderConfig, Filter, FractalCode, Matching, Preset, Reduction,
    RefineConfig, SearchGrid, Texture, decode, encode, levels_for_factor, load_dir, psnr, refine,
    save_dir, upsample,
};
use serde::{Deserialize, Serialize};

use crate::progress::Progress;
use crate::runs::config::PROBLEM_KEY;
use crate::runs::inversion::CONFIG_FILE;

/// A cap on the candidates kept per texel: a whole number ≥ 1, or `"all"` (every candidate
/// of Ω).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CapValue", into = "CapValue")]
pub struct CandidateCap(pub Option<usize>);

#[derive(Serialize, Deserialize)]
#[serde(untagged)]
enum CapValue {
    Count(i64),
    Word(String),
}

impl TryFrom<CapValue> for CandidateCap {
    type Error = String;
    fn try_from(v: CapValue) -> Result<Self, String> {
        match v {
            CapValue::Word(w) => w.parse(),
            CapValue::Count(n) => usize::try_from(n)
                .ok()
                .filter(|&n| n > 0)
                .map(|n| CandidateCap(Some(n)))
                .ok_or_else(|| format!("`{n}` is neither `all` nor a whole number ≥ 1")),
        }
    }
}

impl From<CandidateCap> for CapValue {
    fn from(c: CandidateCap) -> Self {
        match c.0 {
            None => CapValue::Word("all".into()),
            Some(n) => CapValue::Count(n as i64),
        }
    }
}

impl std::str::FromStr for CandidateCap {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "all" {
            return Ok(CandidateCap(None));
        }
        s.parse::<usize>()
            .ok()
            .filter(|&n| n > 0)
            .map(|n| CandidateCap(Some(n)))
            .ok_or_else(|| format!("`{s}` is neither `all` nor a whole number ≥ 1"))
    }
}

/// A texture run, and the settings `ifslab texture encode` / `upsample` take as flags (one
/// key per flag). The encoder choices start from `preset` and each one given overrides it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TextureConfig {
    /// The source texture (PNG or JPEG, grey or colour; even sides of at least 4 texels).
    pub source: PathBuf,
    /// Upsampling factor relative to the source: a power of two (1 = reconstruction from R).
    pub factor: u32,
    /// An interpolation baseline instead of fractal decoding (nearest, bilinear, bicubic,
    /// lanczos).
    pub filter: Option<Filter>,
    /// Convert a colour texture to grey (Rec. 709 luma) first.
    pub grey: bool,
    /// Also score the method on a hold-out: the half-size texture upsampled 2× against the
    /// real source (costs one more encoding of a quarter of the texels).
    pub holdout: bool,
    /// Named settings: `paper` (the method as published) or `ifslab` (this project's
    /// default variant).
    pub preset: Preset,
    /// Refinement passes (0 = the plain encoder) [default: the preset's].
    pub passes: Option<usize>,
    /// How the reduced texture is made: box or binomial [default: box].
    pub reduction: Option<Reduction>,
    /// Search window half-width in texels of the reduced texture [default: 255].
    pub window: Option<u32>,
    /// Matching criterion: raw or mean-removed [default: the preset's].
    pub matching: Option<Matching>,
    /// Search set: all, even or even-offset [default: the preset's].
    pub grid: Option<SearchGrid>,
    /// Centre of the proximity term: domain or range [default: the preset's].
    pub distance: Option<DistanceCentre>,
    /// Proximity weight β [default: 1 when refining, else 0].
    pub beta: Option<f32>,
    /// ΔE_max of the candidate sets [default: the preset's when refining, else 0].
    pub delta_e_max: Option<f32>,
    /// Most candidates kept per texel, or `"all"` [default: the preset's when refining,
    /// else 1].
    pub max_candidates: Option<CandidateCap>,
    /// Coordinate layout of the packed code [default: the one that holds the grid's codes].
    pub coord_storage: Option<CoordStorage>,
    /// The run folder (the command line's `-o` wins).
    pub output: Option<PathBuf>,
}

impl Default for TextureConfig {
    fn default() -> Self {
        TextureConfig {
            source: PathBuf::new(),
            factor: 8,
            filter: None,
            grey: false,
            holdout: true,
            preset: Preset::default(),
            passes: None,
            reduction: None,
            window: None,
            matching: None,
            grid: None,
            distance: None,
            beta: None,
            delta_e_max: None,
            max_candidates: None,
            coord_storage: None,
            output: None,
        }
    }
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
                     use a `window` of 255 or less"
                );
            }
        } else if storage != CoordStorage::for_grid(grid) {
            let fits = match CoordStorage::for_grid(grid) {
                CoordStorage::SignMagnitude => "sign-magnitude".to_string(),
                other => format!("{other} or sign-magnitude"),
            };
            bail!(
                "the {storage} coordinate layout holds codes of grid `{}` only, not `{grid}`; \
                 use coord storage {fits}",
                match storage {
                    CoordStorage::HalfSignedOffset => SearchGrid::EvenOffset,
                    _ => SearchGrid::Even,
                },
            );
        }
        Ok(())
    }
}

impl TextureConfig {
    /// Parses TOML text (without the `problem` key) and validates it; `origin` names the
    /// text in errors.
    pub fn from_toml(text: &str, origin: &Path) -> anyhow::Result<Self> {
        let what = || format!("{} is not a valid texture config", origin.display());
        let cfg: TextureConfig = toml::from_str(text).with_context(what)?;
        cfg.validate().with_context(what)?;
        Ok(cfg)
    }

    /// Checks every field before anything runs; errors name the field.
    pub fn validate(&self) -> anyhow::Result<()> {
        if self.source.as_os_str().is_empty() {
            bail!("`source` is missing: name the texture to upsample (PNG or JPEG)");
        }
        levels_for_factor(self.factor).context("`factor`")?;
        let s = self.settings();
        s.encoder.validate()?;
        s.check_storage().context("`coord_storage`")?;
        Ok(())
    }

    /// The same config with its relative file names read as relative to `dir`.
    pub fn relative_to(mut self, dir: &Path) -> Self {
        for p in [Some(&mut self.source), self.output.as_mut()]
            .into_iter()
            .flatten()
        {
            if p.is_relative() {
                *p = dir.join(&*p);
            }
        }
        self
    }

    /// Every file named absolutely and every encoder choice written out: what a run
    /// folder's `config.toml` holds.
    pub fn resolved(&self) -> anyhow::Result<Self> {
        let abs =
            |p: &Path| std::path::absolute(p).with_context(|| format!("resolving {}", p.display()));
        let s = self.settings();
        Ok(TextureConfig {
            source: abs(&self.source)?,
            output: self.output.as_deref().map(abs).transpose()?,
            passes: Some(s.refine.passes),
            reduction: Some(s.encoder.reduction),
            window: Some(s.encoder.window),
            matching: Some(s.encoder.matching),
            grid: Some(s.encoder.grid),
            distance: Some(s.encoder.distance),
            beta: Some(s.encoder.beta),
            delta_e_max: Some(s.encoder.delta_e_max),
            max_candidates: Some(CandidateCap(s.encoder.max_candidates)),
            coord_storage: Some(s.coord_storage),
            ..self.clone()
        })
    }

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
) -> anyhow::Result<Encoded> {
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
) -> anyhow::Result<PackReport> {
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
) -> anyhow::Result<PackReport> {
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
) -> anyhow::Result<(Texture, f64)> {
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
) -> anyhow::Result<()> {
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
) -> anyhow::Result<(Texture, f64)> {
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
) -> anyhow::Result<()> {
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
) -> anyhow::Result<TextureSummary> {
    let start = Instant::now();
    cfg.validate()?;
    let tex = load_texture(&cfg.source, cfg.grey)?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
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
