//! The config of a texture run, also what `ifslab texture encode` / `upsample` take as
//! flags: a source, a preset and any of its choices overridden one by one, validated with
//! errors that name the key and resolved (every choice written out) for `config.toml`.

use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext, bail};
use ifslab_strategies::problems::fractal_coding::{
    CoordStorage, DistanceCentre, EncoderConfig, Filter, Matching, Preset, Reduction, RefineConfig,
    SearchGrid, levels_for_factor,
};
use serde::{Deserialize, Serialize};

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
    pub fn check_storage(&self) -> crate::Result<()> {
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
    pub fn from_toml(text: &str, origin: &Path) -> crate::Result<Self> {
        let what = || format!("{} is not a valid texture config", origin.display());
        let cfg: TextureConfig = toml::from_str(text).config_context(origin, what)?;
        cfg.validate().config_context(origin, what)?;
        Ok(cfg)
    }

    /// Checks every field before anything runs; errors name the field.
    pub fn validate(&self) -> crate::Result<()> {
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
    pub fn resolved(&self) -> crate::Result<Self> {
        let abs = |p: &Path| std::path::absolute(p).doing("resolving", p);
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
