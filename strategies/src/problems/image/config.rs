//! The configuration of an image inversion: target, model, generator, renderer, loss,
//! strategy, seed. Read from TOML (`ifslab run CONFIG.toml`) or built from `ifslab invert`'s
//! flags, validated before anything runs, and written beside the results.

use std::path::{Path, PathBuf};

use ifslab::chaos::ChaosGame;
use ifslab::loss::LossConfig;
use ifslab::model::ParamKind;
use ifslab::render::splat::{Blend, SplatConfig, SplatDevice, SplatView};
use serde::{Deserialize, Serialize};

use crate::driver::Params;
use crate::error::{Error, Result};
use crate::optim::hybrid::HybridConfig;
pub use crate::problems::image::model::{InitKind, MapProbabilities, ModelConfig};
use crate::problems::image::target::Polarity;
pub use crate::strategy_config::StrategyConfig;

/// Where the target comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetConfig {
    /// An image file (PNG, JPEG, …); relative paths are relative to the config file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image: Option<PathBuf>,
    /// Or a code (file or built-in name) rendered as the target.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub code: Option<String>,
    /// Or code `index` of a test suite (a folder made by `ifslab suite make`): its code is
    /// rendered as the target, and the run is also scored on the suite's views.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub suite: Option<PathBuf>,
    /// Which code of `suite` (0-based).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index: Option<usize>,
    /// The code that drew an `image` target, when it is known (a code file or built-in
    /// name): the run is then also scored against it — both codes drawn by the evaluation
    /// renderer, each in its own fitted window, as a suite's full view — whatever the
    /// picture's framing, colours or noise (summary `truth`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<String>,
    /// Side of the square target and render, in pixels.
    #[serde(default = "default_size")]
    pub size: usize,
    /// Which way round the image's shape is drawn.
    #[serde(default)]
    pub polarity: Polarity,
    /// Read the grey levels of an `image` target reduced at least twice as the splat makes
    /// its own: each pixel cut into the renderer's `supersample × supersample` cells, a cell
    /// inked where the picture reaches this share of its ink level, the pixel the share of
    /// its cells inked (`target::Cells`). Unset or 0: the picture's own levels, resampled.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cells: Option<f64>,
}

fn default_size() -> usize {
    128
}

/// The chaos-game layout of every iteration (a fresh seed per iteration).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GeneratorConfig {
    /// Parallel trajectories.
    pub trajectories: usize,
    /// Steps per trajectory, warm-up included.
    pub length: usize,
    /// Steps dropped at the start of each trajectory.
    pub warmup: usize,
    /// Start points are uniform in `[−h, h]²`.
    pub start_half_width: f64,
}

impl Default for GeneratorConfig {
    fn default() -> Self {
        let g = ChaosGame::default();
        GeneratorConfig {
            trajectories: g.trajectories,
            length: g.length,
            warmup: g.warmup,
            start_half_width: g.start_half_width,
        }
    }
}

/// The differentiable renderer (its size is the target's).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RendererConfig {
    /// Supersampling per side.
    pub supersample: usize,
    /// Gaussian σ in supersampled pixels.
    pub sigma: f64,
    /// Footprint radius in σ.
    pub radius: f64,
    /// Blend mode.
    pub blend: Blend,
    /// Largest α of one splat.
    pub alpha_max: f64,
    /// σ at the end of the run (coarse-to-fine, this project's addition): σ moves
    /// geometrically from `sigma` at t = 0 to `sigma_final` at t = T, for the gradient steps
    /// and the annealing phases alike. A wide splat gives a smooth loss early; a thin one
    /// removes the blur's bias at the end (a splat wider than the target's lines makes the
    /// loss prefer slightly shrunken maps). Unset: σ stays `sigma`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_final: Option<f64>,
    /// Clamp the rendered image to [0, 1] (Learning Fractals sums its Gaussians with
    /// `blend = "additive"`, then clamps).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub clamp: bool,
    /// A fixed window `[x_min, y_min, x_max, y_max]` of the plane instead of fitting the
    /// points (Learning Fractals draws [−5, 5]²); points outside it are not drawn.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub window: Option<[f64; 4]>,
    /// Where the splat runs: `"cpu"` (default) or `"cuda"` (an NVIDIA GPU; needs a build
    /// with `--features cuda`).
    #[serde(skip_serializing_if = "SplatDevice::is_cpu")]
    pub device: SplatDevice,
}

impl Default for RendererConfig {
    /// 4× supersampling with σ = 1 supersampled pixel: splats about as thin as the binary
    /// coverage of the evaluation renderer, so a code's render matches its ground truth (the
    /// paper's 5× / σ = 2.5 at 1024² is a config away).
    fn default() -> Self {
        RendererConfig {
            supersample: 4,
            sigma: 1.0,
            radius: 3.0,
            blend: Blend::Coverage,
            alpha_max: 0.99,
            sigma_final: None,
            clamp: false,
            window: None,
            device: SplatDevice::Cpu,
        }
    }
}

impl RendererConfig {
    /// σ at progress `frac = t/T` ∈ [0, 1] (clamped): `sigma·(sigma_final/sigma)^frac`.
    pub fn sigma_at(&self, frac: f64) -> f64 {
        match self.sigma_final {
            Some(end) => self.sigma * (end / self.sigma).powf(frac.clamp(0.0, 1.0)),
            None => self.sigma,
        }
    }
}

/// A whole image inversion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InversionConfig {
    /// The recipe the keys a config leaves out come from: ifslab's (false, the default) or
    /// the chaotic-splatting paper's (true); see [`InversionConfig::preset`].
    #[serde(default)]
    pub paper: bool,
    /// Seed of everything random in the run.
    #[serde(default)]
    pub seed: u64,
    /// Optimisation iterations T (of each run, where there are several: `best_of`).
    #[serde(default = "default_iterations")]
    pub iterations: u64,
    /// Whole runs at seeds `seed`, `seed + 1`, …, each in a folder of the run (`run-0`,
    /// `run-1`, …), the one whose render agrees best with the target (SSIM) kept; 1: one
    /// run (the paper's; left out of the resolved table, so a run's id does not change).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub best_of: u32,
    /// Where the `best_of` runs start: `seeded` (each run's own start, drawn with its own
    /// seed: three collage searches) or `ranked` (one collage search at `seed`, run `i`
    /// starting from its `i`-th best start, [`ranked_starts`](crate::problems::image::init::ranked_starts)).
    /// Starts that are not the collage's (`model.init` random or EM, `model.init_code`) are
    /// always seeded. Written only when `ranked`.
    #[serde(default, skip_serializing_if = "BestOfStarts::is_seeded")]
    pub best_of_starts: BestOfStarts,
    /// Write a checkpoint every this many iterations (0: never).
    #[serde(default = "default_checkpoint_every")]
    pub checkpoint_every: u64,
    /// Output folder (the command line's `-o` wins).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output: Option<PathBuf>,
    /// The target.
    pub target: TargetConfig,
    /// The model.
    #[serde(default)]
    pub model: ModelConfig,
    /// The chaos game.
    #[serde(default)]
    pub generator: GeneratorConfig,
    /// The differentiable renderer.
    #[serde(default)]
    pub renderer: RendererConfig,
    /// Loss weights.
    #[serde(default)]
    pub loss: LossConfig,
    /// The strategy.
    #[serde(default)]
    pub strategy: StrategyConfig,
}

fn default_checkpoint_every() -> u64 {
    100
}

fn one() -> u32 {
    1
}

/// Where the runs of a `best_of` inversion start (see [`InversionConfig::best_of_starts`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BestOfStarts {
    /// Each run draws its own start with its own seed.
    #[default]
    Seeded,
    /// One collage search; run `i` starts from its `i`-th best start.
    Ranked,
}

impl BestOfStarts {
    fn is_seeded(&self) -> bool {
        *self == BestOfStarts::Seeded
    }
}

fn is_one(n: &u32) -> bool {
    *n == 1
}

/// ifslab's number of whole runs (`best_of`), at seeds `seed`, `seed + 1`, `seed + 2`, the
/// one whose render has the highest SSIM against the target kept. On the robustness
/// suite's tuning split (24 random codes, their true map count) single runs at seeds 0, 1
/// and 2 scored 0.594, 0.569 and 0.560 (mean IoU against the true codes), the best of the
/// three by SSIM 0.61; the SSIM picked the seed best for the truth on most codes
/// (robustness/README.md).
pub const DEFAULT_BEST_OF: u32 = 3;

/// The most whole runs `best_of` may ask for.
pub const MAX_BEST_OF: u32 = 64;

fn default_iterations() -> u64 {
    2000
}

/// ifslab's iterations (`iterations`, of each of the `best_of` runs): on the robustness
/// suite's tuning split, 1000 iterations of 1000 × 110 points scored as 2000 of the paper's
/// 2000 × 250 (the mean IoU against the true codes within 0.03 either way) in a fifth of the
/// time, and 400 as 1000 (24 random codes at seeds 0, 1 and 2: 0.592 against 0.594, 0.565
/// against 0.569, and the third seed's likewise; robustness/README.md).
pub const DEFAULT_ITERATIONS: u64 = 400;
/// ifslab's chaos-game trajectories per iteration (`generator.trajectories`).
pub const DEFAULT_TRAJECTORIES: usize = 1000;
/// ifslab's steps per trajectory, warm-up included (`generator.length`).
pub const DEFAULT_LENGTH: usize = 110;

/// The differentiable splat's speed used to estimate a run's time before it starts:
/// points splatted forward and backward per second and thread, about ten times what this
/// machine measures (BENCHMARKS.md §2), so that only runs that would surely take past the
/// work budget are refused.
pub const SPLAT_POINTS_PER_SECOND_PER_THREAD: f64 = 2e7;

/// ifslab's reading of the grey levels of a picture reduced at least twice into the target
/// (`target.cells`; `target::CELLS_MAX_SCALE`): a pixel's level is the share of its 4 × 4
/// cells under which the picture reaches 0.35 of its ink level — the level the splat gives
/// a thin filament — instead of the picture's area coverage, which averages a filament to a
/// faint grey that the fit answers by reshaping the maps. On the robustness suite's random
/// codes so drawn, both tuning splits: closer to the truth on 15 of 19 fits, further on 3
/// (robustness/README.md).
pub const DEFAULT_TARGET_CELLS: f64 = 0.35;

/// ifslab's σ at the end of a run (`renderer.sigma_final`): σ shrinks from 1 to 0.4
/// supersampled pixels, Table 3's best row (paper_repro/chaotic_splatting/README.md).
pub const DEFAULT_SIGMA_FINAL: f64 = 0.4;

/// ifslab's weight of the LPIPS term (`loss.lpips_weight`; the paper's is 2). On the
/// robustness suite's tuning split (24 random codes with their true map count, 22 with 10,
/// six classic codes with both) the fits without it scored as the fits with it within their
/// noise, in about 60 % of the time (the test split: 0.51 against 0.50 on random codes),
/// and the chaotic-splatting reproduction's Table 4 found the same at its budget ("w/o
/// LPIPS", `paper_repro/chaotic_splatting/README.md`). Without it the default loss
/// also needs no weights file: a machine without the file runs the same recipe.
pub const DEFAULT_LPIPS_WEIGHT: f64 = 0.0;

/// Prefixes a validation error with the config section it came from.
fn in_section<T>(section: &str, r: Result<T>) -> Result<T> {
    r.map_err(|e| match e {
        Error::InvalidParameter { name, message } => {
            Error::InvalidInput(format!("config field `{section}.{name}`: {message}"))
        }
        Error::Core(ifslab::Error::InvalidParameter { name, message }) => {
            Error::InvalidInput(format!("config field `{section}.{name}`: {message}"))
        }
        other => Error::InvalidInput(format!("config section [{section}]: {other}")),
    })
}

impl InversionConfig {
    /// The same config with Learning Fractals' recipe (Tu et al.; facts from the authors'
    /// `deep_fractal.py` and `run_reconstruct.sh`): rotation–scale–rotation maps drawn ∝ |det|,
    /// 50 sequences of 300 points a step (here each after 10 warm-up steps from a random start,
    /// where theirs start at map 0's fixed point), Gaussians `exp(−d²)` (σ = 1/√2 pixel) summed
    /// and clamped to 1 in the fixed window [−5, 5]², plain MSE, and their optimiser
    /// ([`crate::optim::learning_fractals`]). The target and its size, the number of maps, the
    /// start and the iterations are left as they are.
    pub fn with_learning_fractals_recipe(mut self) -> Self {
        use crate::optim::learning_fractals::LearningFractalsConfig;
        self.model.parameterisation = ParamKind::Rsr;
        self.model.probabilities = MapProbabilities::Determinant;
        self.generator.trajectories = 50;
        self.generator.length = 310;
        self.generator.warmup = 10;
        self.renderer = RendererConfig {
            supersample: 1,
            sigma: std::f64::consts::FRAC_1_SQRT_2,
            radius: 4.0,
            blend: Blend::Additive,
            clamp: true,
            window: Some([-5.0, -5.0, 5.0, 5.0]),
            ..RendererConfig::default()
        };
        self.loss = LossConfig {
            msmse_weight: 1.0,
            msmse_levels: 0,
            dssim_weight: 0.0,
            lpips_weight: 0.0,
            moments_weight: 0.0,
            regulariser: ifslab::loss::Regulariser {
                scale_weight: 0.0,
                condition_weight: 0.0,
                ..self.loss.regulariser
            },
            ..self.loss
        };
        self.strategy = StrategyConfig::new(&LearningFractalsConfig::default());
        self
    }

    /// The values of the keys whose defaults depend on the recipe, for a config `table`
    /// that asks for the paper's recipe (`paper`) or not; merged where the table leaves a
    /// key out ([`crate::recipe`]).
    ///
    /// | key | ifslab's (default) | the paper's (`paper = true`) |
    /// |---|---|---|
    /// | `iterations` | 400 (each of three runs) | 2000 |
    /// | `best_of` | 3 (seeds `seed`, `seed + 1`, `seed + 2`; the render closest to the target by SSIM kept) | 1 |
    /// | `generator` | 1000 trajectories × 110 steps | the paper's 2000 × 250 |
    /// | `model.init` | `collage` (copies of the target found in it, or the EM start where it matches better) | `random` (Anderson–Farrell) |
    /// | `model.em_reflections` | true (the EM start's maps may mirror) | false |
    /// | `strategy` | `cold_hybrid` from a collage or EM start, `hybrid` from a random one | `hybrid` |
    /// | `renderer.sigma_final` | 0.4 (σ 1 → 0.4 over the run) | none (σ fixed) |
    /// | `loss.lpips_weight` | 0 (MS-MSE and D-SSIM only) | 2 |
    pub fn preset(paper: bool, table: &toml::Table) -> toml::Table {
        use crate::optim::hybrid::ColdHybridConfig;
        use crate::recipe::{get_dotted, table_of};
        // The recipe's strategy where the config names no kind (a config that only tunes
        // the default strategy's parameters keeps that strategy).
        let named = table
            .get("strategy")
            .and_then(|s| s.as_table())
            .is_some_and(|s| s.contains_key("kind"));
        if paper {
            let mut preset = table_of([("model.init", "random".into())]);
            if !named && table.contains_key("strategy") {
                preset.extend(table_of([("strategy.kind", HybridConfig::KIND.into())]));
            }
            return preset;
        }
        let init = get_dotted(table, "model.init")
            .and_then(|v| v.as_str())
            .unwrap_or("collage");
        let keys = [
            ("iterations", (DEFAULT_ITERATIONS as i64).into()),
            ("best_of", (DEFAULT_BEST_OF as i64).into()),
            (
                "generator.trajectories",
                (DEFAULT_TRAJECTORIES as i64).into(),
            ),
            ("generator.length", (DEFAULT_LENGTH as i64).into()),
            ("model.init", "collage".into()),
            ("model.em_reflections", true.into()),
            ("renderer.sigma_final", DEFAULT_SIGMA_FINAL.into()),
            ("loss.lpips_weight", DEFAULT_LPIPS_WEIGHT.into()),
            ("target.cells", DEFAULT_TARGET_CELLS.into()),
        ];
        let mut preset = table_of(keys);
        if !named {
            let kind = if init != "random" {
                ColdHybridConfig::KIND
            } else {
                HybridConfig::KIND
            };
            preset.extend(table_of([("strategy.kind", kind.into())]));
        }
        preset
    }

    /// A config from a parsed TOML table: the recipe's values merged where the table
    /// leaves keys out ([`InversionConfig::preset`]), then parsed and validated; an unknown
    /// or mistyped field is an error that names it.
    pub fn from_table(table: toml::Table, origin: &Path) -> Result<Self> {
        let cfg: InversionConfig = crate::recipe::resolve(table, origin, InversionConfig::preset)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Parses TOML (see [`InversionConfig::from_table`]).
    pub fn from_toml(text: &str, origin: &Path) -> Result<Self> {
        let table: toml::Table = text.parse().map_err(|e| Error::file(origin, e))?;
        InversionConfig::from_table(table, origin)
    }

    /// TOML text of the resolved configuration (every default written out).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("an inversion config always serialises")
    }

    /// Reads and validates a config file; relative paths of the target image and of code
    /// files become relative to its folder.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
        let cfg = InversionConfig::from_toml(&text, path)?;
        Ok(match path.parent() {
            Some(dir) => cfg.relative_to(dir),
            None => cfg,
        })
    }

    /// The same config with its relative file names (target image, code files that exist
    /// there) read as relative to `dir`, the folder of the file the config came from.
    pub fn relative_to(mut self, dir: &Path) -> Self {
        for path in [&mut self.target.image, &mut self.target.suite]
            .into_iter()
            .flatten()
        {
            if path.is_relative() {
                *path = dir.join(&*path);
            }
        }
        for spec in [
            &mut self.target.code,
            &mut self.target.truth,
            &mut self.model.init_code,
        ]
        .into_iter()
        .flatten()
        {
            if dir.join(&*spec).is_file() {
                *spec = dir.join(&*spec).to_string_lossy().into_owned();
            }
        }
        self
    }

    /// The same config with every file it names made absolute (against the working
    /// directory): what a run folder's `config.toml` holds, so that the run means the same
    /// thing read from any folder (`--resume`, `ifslab run DIR/config.toml`). Built-in code
    /// names are left as they are.
    pub fn with_absolute_paths(&self) -> Result<Self> {
        let abs = |p: &Path| std::path::absolute(p).map_err(|e| Error::file(p, e));
        let file_spec = |spec: &String| -> Result<String> {
            let p = Path::new(spec);
            Ok(if p.is_file() {
                abs(p)?.to_string_lossy().into_owned()
            } else {
                spec.clone()
            })
        };
        let mut cfg = self.clone();
        if let Some(img) = &self.target.image {
            cfg.target.image = Some(abs(img)?);
        }
        if let Some(suite) = &self.target.suite {
            cfg.target.suite = Some(abs(suite)?);
        }
        cfg.target.code = self.target.code.as_ref().map(file_spec).transpose()?;
        cfg.target.truth = self.target.truth.as_ref().map(file_spec).transpose()?;
        cfg.model.init_code = self.model.init_code.as_ref().map(file_spec).transpose()?;
        if let Some(out) = &self.output {
            cfg.output = Some(abs(out)?);
        }
        Ok(cfg)
    }

    /// Checks every field before anything runs; errors name the field.
    pub fn validate(&self) -> Result<()> {
        if self.iterations == 0 {
            return Err(Error::InvalidInput(
                "config field `iterations`: must be at least 1".into(),
            ));
        }
        if !(1..=MAX_BEST_OF).contains(&self.best_of) {
            return Err(Error::InvalidInput(format!(
                "config field `best_of`: the number of whole runs, 1..={MAX_BEST_OF}, got {}",
                self.best_of
            )));
        }
        let t = &self.target;
        let given = [t.image.is_some(), t.code.is_some(), t.suite.is_some()];
        match given.iter().filter(|&&g| g).count() {
            0 => {
                return Err(Error::InvalidInput(
                    "config section [target]: give `image = \"file.png\"`, `code = \"sierpinski\"` or `suite = \"SUITE\", index = 0`".into(),
                ));
            }
            1 => {}
            _ => {
                return Err(Error::InvalidInput(
                    "config section [target]: give one of `image`, `code` and `suite`, not several"
                        .into(),
                ));
            }
        }
        if t.truth.is_some() && t.image.is_none() {
            return Err(Error::InvalidInput(
                "config field `target.truth`: the code that drew an `image` target; a `code` or \
                 `suite` target is scored against its own code already"
                    .into(),
            ));
        }
        if t.suite.is_some() != t.index.is_some() {
            return Err(Error::InvalidInput(
                "config section [target]: `suite` and `index` go together (which code of the suite)".into(),
            ));
        }
        if !(8..=4096).contains(&t.size) {
            return Err(Error::InvalidInput(format!(
                "config field `target.size`: must lie in 8..=4096 pixels, got {}",
                t.size
            )));
        }
        if let Some(share) = t.cells
            && !(0.0..=1.0).contains(&share)
        {
            return Err(Error::InvalidInput(format!(
                "config field `target.cells`: the share of the ink level at which a cell counts \
                 as inked must lie in (0, 1] (0: the picture's own levels), got {share}"
            )));
        }
        crate::problems::image::model::find_model(&self.model.family).map_err(|e| match e {
            Error::InvalidInput(why) => {
                Error::InvalidInput(format!("config field `model.family`: {why}"))
            }
            other => other,
        })?;
        if self.model.polish > 0 && !self.model.build()?.maps_are_affine()? {
            return Err(polish_needs_affine(&self.model.family));
        }
        if !(1..=64).contains(&self.model.maps) {
            return Err(Error::InvalidInput(format!(
                "config field `model.maps`: must lie in 1..=64, got {}",
                self.model.maps
            )));
        }
        if !(self.model.init_noise.is_finite() && self.model.init_noise >= 0.0) {
            return Err(Error::InvalidInput(format!(
                "config field `model.init_noise`: must be ≥ 0, got {}",
                self.model.init_noise
            )));
        }
        if let Some(side) = self.model.start_size {
            if !(16..=2048).contains(&side) {
                return Err(Error::InvalidInput(format!(
                    "config field `model.start_size`: must lie in 16..=2048 pixels, got {side}"
                )));
            }
            if self.target.image.is_none() {
                return Err(Error::InvalidInput(
                    "config field `model.start_size`: the start reads a picture again at that \
                     side, so it needs a picture target (`target.image`); a code or suite \
                     target starts from the fit's own target"
                        .into(),
                ));
            }
        }
        in_section("generator", self.game().validate().map_err(Error::from))?;
        in_section(
            "renderer",
            self.splat_config().validate().map_err(Error::from),
        )?;
        // The run's work: every iteration of every whole run splats (and differentiates)
        // every point.
        let points = (self.generator.trajectories as f64) * (self.generator.length as f64);
        let runs = if self.best_of > 1 {
            format!("{} runs of ", self.best_of)
        } else {
            String::new()
        };
        ifslab::budget::check_rate(
            self.best_of as f64 * self.iterations as f64 * points,
            SPLAT_POINTS_PER_SECOND_PER_THREAD,
            rayon::current_num_threads(),
            "points",
            &format!("{runs}{} iterations of {points} points", self.iterations),
            "`iterations` (--iters), `best_of` (--best-of) or `generator.trajectories` \
             (--trajectories)",
        )?;
        // The differentiable render's buffers, before a run allocates any of them.
        ifslab::budget::check_memory(
            &self.splat_config().memory_estimate(),
            "`target.size` (--size), `renderer.supersample` (--supersample) or \
             `generator.trajectories` (--trajectories)",
        )?;
        if let Some(end) = self.renderer.sigma_final
            && !(end.is_finite() && end > 0.0)
        {
            return Err(Error::InvalidInput(format!(
                "config field `renderer.sigma_final`: must be > 0, got {end}"
            )));
        }
        in_section("loss", self.loss.validate().map_err(Error::from))?;
        in_section("strategy", self.strategy.validate())
    }

    /// The chaos-game layout (its seed is set per iteration).
    pub fn game(&self) -> ChaosGame {
        let g = &self.generator;
        ChaosGame {
            trajectories: g.trajectories,
            length: g.length,
            warmup: g.warmup,
            start_half_width: g.start_half_width,
            seed: 0,
        }
    }

    /// How an `image` target's grey levels are read (`target.cells`), if not as they are.
    pub fn target_cells(&self) -> Option<crate::problems::image::target::Cells> {
        self.target.cells.filter(|share| *share > 0.0).map(|share| {
            crate::problems::image::target::Cells {
                per_side: self.renderer.supersample,
                threshold: share as f32,
            }
        })
    }

    /// The fused op's configuration.
    pub fn splat_config(&self) -> SplatConfig {
        let r = &self.renderer;
        SplatConfig {
            width: self.target.size,
            height: self.target.size,
            supersample: r.supersample,
            sigma: r.sigma,
            radius: r.radius,
            blend: r.blend,
            alpha_max: r.alpha_max,
            game: self.game(),
            framing: match r.window {
                Some([x0, y0, x1, y1]) => SplatView::Window(ifslab::model::Window {
                    min: [x0, y0],
                    max: [x1, y1],
                }),
                None => SplatView::default(),
            },
            device: r.device,
        }
    }
}

/// The refusal of the IoU polish for a family whose maps are not affine.
pub(crate) fn polish_needs_affine(family: &str) -> Error {
    Error::InvalidInput(format!(
        "config field `model.polish`: the polish moves affine maps, and family `{family}` has \
         maps that are not affine (remove `polish` or choose an affine family)"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = "iterations = 10\n[target]\ncode = \"sierpinski\"\n";

    #[test]
    fn a_parameterisation_is_refused_where_the_family_has_none() {
        let mut m = ModelConfig {
            family: "similitude".into(),
            ..ModelConfig::default()
        };
        assert!(m.build().is_ok());
        m.parameterisation = ParamKind::Naive;
        let err = m.build().err().unwrap().to_string();
        assert!(
            err.contains("parameterisation") && err.contains("similitude"),
            "{err}"
        );
        m.family = "affine".into();
        assert!(m.build().is_ok());
    }

    #[test]
    fn the_start_size_is_checked_and_written_only_when_set() {
        let small = InversionConfig::from_toml(
            &format!("{MINIMAL}[model]\nstart_size = 8\n"),
            Path::new("c.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(small.contains("model.start_size"), "{small}");
        // A code target has no picture to read again: refused, not ignored.
        let code = InversionConfig::from_toml(
            &format!("{MINIMAL}[model]\nstart_size = 256\n"),
            Path::new("c.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(code.contains("target.image"), "{code}");
        // Unset, it is not written, so the runs of recipes that do not use it keep their ids.
        let em = InversionConfig::from_toml(
            &format!("{MINIMAL}[model]\ninit = \"em\"\n"),
            Path::new("c.toml"),
        )
        .unwrap();
        assert_eq!(em.model.start_size, None);
        assert!(!em.to_toml().contains("start_size"));
    }

    #[test]
    fn minimal_config_gets_ifslabs_recipe_and_round_trips() {
        let cfg = InversionConfig::from_toml(MINIMAL, Path::new("c.toml")).unwrap();
        assert!(!cfg.paper);
        assert_eq!(cfg.model.init, InitKind::Collage);
        assert_eq!(cfg.model.start_size, None);
        // The collage start's refinement is an option, off unless asked for.
        assert_eq!(cfg.model.collage_refine, 0);
        assert!(!cfg.to_toml().contains("collage_refine"));
        assert_eq!(cfg.strategy.name(), "cold_hybrid");
        assert_eq!(cfg.renderer.sigma_final, Some(DEFAULT_SIGMA_FINAL));
        // A reduced picture's levels read by cells; the paper's recipe reads them as they
        // are, and 0 turns the reading off.
        assert_eq!(cfg.target.cells, Some(DEFAULT_TARGET_CELLS));
        assert!(cfg.target_cells().is_some());
        // The best of three whole runs of 400 iterations; the paper's recipe runs once,
        // and its resolved table has no `best_of` (so its runs' ids are what they were).
        assert_eq!(cfg.best_of, DEFAULT_BEST_OF);
        let bare = MINIMAL.replace("iterations = 10\n", "");
        let bare_ours = InversionConfig::from_toml(&bare, Path::new("c.toml")).unwrap();
        assert_eq!(bare_ours.iterations, DEFAULT_ITERATIONS);
        let bare_paper =
            InversionConfig::from_toml(&format!("paper = true\n{bare}"), Path::new("c.toml"))
                .unwrap();
        assert_eq!((bare_paper.best_of, bare_paper.iterations), (1, 2000));
        assert!(cfg.to_toml().contains("best_of = 3"));
        let paper =
            InversionConfig::from_toml(&format!("paper = true\n{MINIMAL}"), Path::new("c.toml"))
                .unwrap();
        assert_eq!(paper.target.cells, None);
        assert_eq!(paper.best_of, 1);
        assert!(!paper.to_toml().contains("best_of"));
        let once =
            InversionConfig::from_toml(&format!("best_of = 1\n{MINIMAL}"), Path::new("c.toml"))
                .unwrap();
        assert_eq!(once.best_of, 1);
        let off = InversionConfig::from_toml(
            &MINIMAL.replace("[target]\n", "[target]\ncells = 0.0\n"),
            Path::new("c.toml"),
        )
        .unwrap();
        assert!(off.target_cells().is_none());
        let bad = InversionConfig::from_toml(
            &MINIMAL.replace("[target]\n", "[target]\ncells = 1.5\n"),
            Path::new("c.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(bad.contains("target.cells"), "{bad}");
        // No LPIPS term (and so no weights file needed); every other term as the paper's.
        assert_eq!(
            cfg.loss,
            LossConfig {
                lpips_weight: DEFAULT_LPIPS_WEIGHT,
                ..LossConfig::default()
            }
        );
        assert_eq!(DEFAULT_LPIPS_WEIGHT, 0.0);
        // The config's own weight wins.
        let with = InversionConfig::from_toml(
            &format!("{MINIMAL}[loss]\nlpips_weight = 2.0\n"),
            Path::new("c.toml"),
        )
        .unwrap();
        assert_eq!(with.loss, LossConfig::default());
        let back = InversionConfig::from_toml(&cfg.to_toml(), Path::new("c.toml")).unwrap();
        assert_eq!(back, cfg);
        // A random start under ifslab's recipe gets the paper's hot hybrid, as the command
        // line's `--init random`.
        let r = InversionConfig::from_toml(
            &format!("{MINIMAL}[model]\ninit = \"random\"\n"),
            Path::new("c.toml"),
        )
        .unwrap();
        assert_eq!(r.strategy.name(), "hybrid");
        // The EM start keeps the cold hybrid.
        let em = InversionConfig::from_toml(
            &format!("{MINIMAL}[model]\ninit = \"em\"\n"),
            Path::new("c.toml"),
        )
        .unwrap();
        assert_eq!(
            (em.model.init, em.strategy.name()),
            (InitKind::Em, "cold_hybrid")
        );
        // A config that tunes the recipe's strategy without naming it keeps it, under
        // either recipe.
        for (paper, kind) in [("", "cold_hybrid"), ("paper = true\n", "hybrid")] {
            let tuned = InversionConfig::from_toml(
                &format!("{paper}{MINIMAL}[strategy.adam]\nlr = 0.03\n"),
                Path::new("c.toml"),
            )
            .unwrap();
            assert_eq!(tuned.strategy.name(), kind);
            assert!(tuned.to_toml().contains("lr = 0.03"), "{}", tuned.to_toml());
        }
    }

    #[test]
    fn the_papers_recipe_is_one_key_away_and_is_what_configs_meant_before_recipes() {
        let paper =
            InversionConfig::from_toml(&format!("paper = true\n{MINIMAL}"), Path::new("c.toml"))
                .unwrap();
        assert!(paper.paper);
        assert_eq!(paper.model.init, InitKind::Random);
        assert_eq!(paper.strategy.name(), "hybrid");
        assert_eq!(paper.strategy, StrategyConfig::default());
        assert_eq!(paper.renderer.sigma_final, None);
        assert_eq!(paper.loss.lpips_weight, 2.0);
        assert_eq!(paper.model.collage_refine, 0);
        // Its resolved table has no σ schedule nor collage refinement, and reads back as
        // itself.
        let text = paper.to_toml();
        assert!(!text.contains("sigma_final"), "{text}");
        assert!(!text.contains("collage_refine"), "{text}");
        assert_eq!(
            InversionConfig::from_toml(&text, Path::new("c.toml")).unwrap(),
            paper
        );
        // A resolved table written before recipes (no `paper` key) is the paper's run.
        let mut legacy: toml::Table = text.parse().unwrap();
        legacy.remove("paper");
        crate::recipe::mark_legacy(&mut legacy);
        assert_eq!(
            InversionConfig::from_table(legacy, Path::new("c.toml")).unwrap(),
            paper
        );
        // Any key the config gives wins over either recipe.
        let mixed = InversionConfig::from_toml(
            &format!("paper = true\n{MINIMAL}[renderer]\nsigma_final = 0.5\n"),
            Path::new("c.toml"),
        )
        .unwrap();
        assert_eq!(mixed.renderer.sigma_final, Some(0.5));
        assert_eq!(mixed.model.init, InitKind::Random);
        let e = InversionConfig::from_toml(&format!("paper = 1\n{MINIMAL}"), Path::new("c.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("paper"), "{e}");
    }

    #[test]
    fn sigma_schedule_is_geometric_and_round_trips() {
        let text = format!("{MINIMAL}[renderer]\nsigma = 2.0\nsigma_final = 0.5\n");
        let cfg = InversionConfig::from_toml(&text, Path::new("c.toml")).unwrap();
        let r = &cfg.renderer;
        assert_eq!(r.sigma_at(0.0), 2.0);
        assert!((r.sigma_at(0.5) - 1.0).abs() < 1e-12);
        assert!((r.sigma_at(1.0) - 0.5).abs() < 1e-12);
        assert!((r.sigma_at(7.0) - 0.5).abs() < 1e-12, "progress is clamped");
        let back = InversionConfig::from_toml(&cfg.to_toml(), Path::new("c.toml")).unwrap();
        assert_eq!(back, cfg);
        assert_eq!(RendererConfig::default().sigma_at(0.7), 1.0);
    }

    #[test]
    fn errors_name_the_field() {
        let e = |s: &str| {
            InversionConfig::from_toml(s, Path::new("c.toml"))
                .unwrap_err()
                .to_string()
        };
        assert!(e(&format!("{MINIMAL}[renderer]\nsigma = -1\n")).contains("renderer.sigma"));
        assert!(
            e(&format!("{MINIMAL}[renderer]\nsigma_final = 0\n")).contains("renderer.sigma_final")
        );
        assert!(
            e(&format!(
                "{MINIMAL}[strategy]\nkind = \"hybrid\"\nanneal_every = 0\n"
            ))
            .contains("anneal_every")
        );
        assert!(e(&format!("{MINIMAL}[strategy]\nkind = \"magic\"\n")).contains("magic"));
        assert!(e(&format!("{MINIMAL}[model]\nmapz = 3\n")).contains("mapz"));
        assert!(e(&format!("{MINIMAL}[loss]\nlpips_weight = -2\n")).contains("lpips_weight"));
        assert!(e("iterations = 0\n[target]\ncode = \"fern\"\n").contains("iterations"));
        for n in [0, MAX_BEST_OF + 1] {
            assert!(e(&format!("best_of = {n}\n{MINIMAL}")).contains("best_of"));
        }
        assert!(e("iterations = 5\n[target]\n").contains("[target]"));
        assert!(
            e("iterations = 5\n[target]\ncode = \"fern\"\nimage = \"x.png\"\n")
                .contains("not several")
        );
        assert!(e("this is = = not toml").contains("c.toml"));
    }
}
