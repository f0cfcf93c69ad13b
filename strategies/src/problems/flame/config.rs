//! The configuration of a flame fit (`problem = "flame"` in `ifslab run`, or `ifslab flame
//! learn`'s flags), validated before anything runs and written beside the results.

use std::path::{Path, PathBuf};

use ifslab::model::flame::VariationKind;
use ifslab::model::flame::learnable::{Learn, LearnableInit};
use ifslab::render::flame_diff::DiffFlameConfig;
use serde::{Deserialize, Serialize};

use crate::driver::Params;
use crate::error::{Error, Result};
use crate::optim::adam::AdamConfig;
use crate::optim::gd::GdConfig;
use crate::strategy_config::StrategyConfig;

/// One layer: `xforms` generators; the first `linear` of them are pre-affine maps only, the
/// others apply every variation of `variations` (weight 1 each) after their pre-affine map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerSpec {
    /// Generators.
    pub xforms: usize,
    /// flam3 variation names (deterministic ones).
    pub variations: Vec<String>,
    /// How many leading generators are linear only (the authors' Fighting Forms: 13 of 24).
    #[serde(default)]
    pub linear: usize,
}

impl LayerSpec {
    /// The variations of every generator; an error names an unknown or random variation.
    pub fn generators(&self) -> Result<Vec<Vec<VariationKind>>> {
        let mut kinds = Vec::with_capacity(self.variations.len());
        for name in &self.variations {
            let k = VariationKind::from_name(name).ok_or_else(|| {
                Error::param(
                    "variations",
                    format!("unknown variation `{name}` (flam3 3.1.1 names, e.g. spherical, handkerchief)"),
                )
            })?;
            if k.is_random() {
                return Err(Error::param(
                    "variations",
                    format!(
                        "`{name}` draws random numbers and has no derivative; learnable flames take deterministic variations only"
                    ),
                ));
            }
            kinds.push(k);
        }
        if kinds.is_empty() {
            kinds.push(VariationKind::Linear);
        }
        Ok((0..self.xforms)
            .map(|i| {
                if i < self.linear {
                    vec![VariationKind::Linear]
                } else {
                    kinds.clone()
                }
            })
            .collect())
    }
}

/// The compositor's background: `"white"`, `"black"`, `"learned"`, `"auto"` (fixed to the
/// mean colour of the target's border pixels) or `[r, g, b]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum BackgroundConfig {
    /// A name.
    Named(String),
    /// A fixed colour, components in [0, 1].
    Rgb([f64; 3]),
}

impl Default for BackgroundConfig {
    fn default() -> Self {
        BackgroundConfig::Named("white".into())
    }
}

/// Learning rates per parameter group, as multiples of the strategy's `lr` (the authors set
/// one rate per module: sampler, splatter, palette, compositor).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Rates {
    /// Generators (pre- and post-affine maps, variation weights).
    pub generators: f64,
    /// The final transform.
    pub final_transform: f64,
    /// κ's raw parameter.
    pub kappa: f64,
    /// The colour logits.
    pub color: f64,
    /// The background logits.
    pub background: f64,
    /// Iterations at the start during which the generators, final transform and κ stay put
    /// and only colours and background learn (the authors' painting runs: 100).
    pub freeze_geometry: u64,
}

impl Default for Rates {
    /// The authors' linear flame on circles3: sampler 0.1, splatter 0.01 (κ 0.05), palette
    /// 100, compositor 1 — relative to the sampler's 0.1.
    fn default() -> Self {
        Rates {
            generators: 1.0,
            final_transform: 0.1,
            kappa: 0.5,
            color: 1000.0,
            background: 10.0,
            freeze_geometry: 0,
        }
    }
}

impl Rates {
    /// ifslab's rates for Adam (relative to its lr 0.05): every module at the sampler's
    /// rate but the palette and compositor at five times it (paper_repro/fractal_flames:
    /// half the authors' MSE at their budget).
    pub fn for_adam() -> Self {
        Rates {
            final_transform: 1.0,
            kappa: 1.0,
            color: 5.0,
            background: 5.0,
            ..Rates::default()
        }
    }
}

/// Generators of the one linear layer a config without `flames` learns: 16 (ifslab's: as
/// fast per iteration at 10⁶ samples, and 23 of 24 of the robustness suite's shape pictures
/// under 0.3 of a flat colour's MSE against 16 with 8) or the authors' 8.
pub fn default_xforms(paper: bool) -> usize {
    if paper { 8 } else { 16 }
}

/// ifslab's Adam learning rate for flames (group rates multiply it).
pub const DEFAULT_ADAM_LR: f64 = 0.05;

/// The loss: the authors' MSE, plus the existing image losses where they help.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FlameLoss {
    /// Weight of the authors' MSE (squared error summed over RGB, averaged over pixels).
    pub mse: f64,
    /// Weight of D-SSIM (1 − SSIM, 11-pixel Gaussian window σ 1.5), averaged over R, G, B.
    pub dssim: f64,
}

impl Default for FlameLoss {
    fn default() -> Self {
        FlameLoss {
            mse: 1.0,
            dssim: 0.0,
        }
    }
}

impl FlameLoss {
    /// Whether this is the authors' loss alone.
    pub fn is_paper(&self) -> bool {
        *self == FlameLoss::default()
    }

    /// Checks the weights, naming the field.
    pub fn validate(&self) -> Result<()> {
        for (name, w) in [("loss.mse", self.mse), ("loss.dssim", self.dssim)] {
            if !(w.is_finite() && w >= 0.0) {
                return Err(Error::param(
                    name,
                    format!("must be finite and ≥ 0, got {w}"),
                ));
            }
        }
        if self.mse == 0.0 && self.dssim == 0.0 {
            return Err(Error::param("loss", "at least one weight must be > 0"));
        }
        Ok(())
    }
}

/// A whole fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FlameLearnConfig {
    /// The recipe the keys a config leaves out come from: ifslab's (false, the default) or
    /// Bannister & Nowrouzezahrai's (true); see [`FlameLearnConfig::preset`].
    #[serde(default)]
    pub paper: bool,
    /// The target image, RGB (relative to the config file's folder).
    pub target: PathBuf,
    /// The layers, bottom first.
    pub flames: Vec<LayerSpec>,
    /// Sampling and image size (the image is `size × size`; the target is resized to it).
    #[serde(default)]
    pub sampler: DiffFlameConfig,
    /// The background.
    #[serde(default)]
    pub background: BackgroundConfig,
    /// Cut the picture to what differs from its background (with a margin) and pad it to a
    /// square before resizing it to `sampler.size` (the authors resize the whole picture):
    /// shapes small in a corner of a wide canvas are learned large and undistorted. Written
    /// only when on.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub frame: bool,
    /// What is learned besides the pre-affine maps, final transform, κ and colours.
    #[serde(default)]
    pub learn: Learn,
    /// The start.
    #[serde(default)]
    pub init: LearnableInit,
    /// Per-group learning-rate multipliers.
    #[serde(default)]
    pub rates: Rates,
    /// The loss (the authors' MSE unless set; left out of written configs then).
    #[serde(default, skip_serializing_if = "FlameLoss::is_paper")]
    pub loss: FlameLoss,
    /// Redraw the generator order every this many iterations (0: drawn once, as the paper).
    #[serde(default)]
    pub redraw_every: u64,
    /// Optimisation iterations.
    #[serde(default = "default_iterations")]
    pub iterations: u64,
    /// Seed of the start and of the generator order.
    #[serde(default)]
    pub seed: u64,
    /// Write a checkpoint every this many iterations (0: never).
    #[serde(default = "default_checkpoint_every")]
    pub checkpoint_every: u64,
    /// Side of the final render, written beside the training-size one (0: none).
    #[serde(default = "default_eval_size")]
    pub eval_size: usize,
    /// Output folder (the command line's `-o` wins).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output: Option<PathBuf>,
    /// The strategy (any registered one; gradient descent with lr 0.1 by default).
    #[serde(default = "default_strategy")]
    pub strategy: StrategyConfig,
}

fn default_iterations() -> u64 {
    150
}
fn default_checkpoint_every() -> u64 {
    25
}
fn default_eval_size() -> usize {
    400
}
/// Plain gradient descent at the authors' sampler rate.
pub fn default_strategy() -> StrategyConfig {
    StrategyConfig::new(&GdConfig {
        lr: 0.1,
        ..GdConfig::default()
    })
}

impl FlameLearnConfig {
    /// A config of ifslab's recipe (the default): one layer of `xforms` generators with
    /// `variations`, what a config naming only those resolves to.
    pub fn new(target: impl Into<PathBuf>, xforms: usize, variations: Vec<String>) -> Self {
        let mut cfg = FlameLearnConfig::paper(target, xforms, variations);
        cfg.paper = false;
        cfg.strategy = StrategyConfig::new(&AdamConfig {
            lr: DEFAULT_ADAM_LR,
            ..AdamConfig::default()
        });
        cfg.rates = Rates::for_adam();
        cfg.background = BackgroundConfig::Named("auto".into());
        cfg.frame = true;
        cfg
    }

    /// A config of the authors' recipe (`paper = true`): plain gradient descent with their
    /// per-module rates on a white background.
    pub fn paper(target: impl Into<PathBuf>, xforms: usize, variations: Vec<String>) -> Self {
        FlameLearnConfig {
            paper: true,
            target: target.into(),
            flames: vec![LayerSpec {
                xforms,
                variations,
                linear: 0,
            }],
            sampler: DiffFlameConfig::default(),
            background: BackgroundConfig::default(),
            frame: false,
            learn: Learn::default(),
            init: LearnableInit::default(),
            rates: Rates::default(),
            loss: FlameLoss::default(),
            redraw_every: 0,
            iterations: default_iterations(),
            seed: 0,
            checkpoint_every: default_checkpoint_every(),
            eval_size: default_eval_size(),
            output: None,
            strategy: default_strategy(),
        }
    }

    /// The values of the keys whose defaults depend on the recipe, for a config `table`
    /// that asks for the paper's recipe (`paper`) or not; merged where the table leaves a
    /// key out ([`crate::recipe`]).
    ///
    /// | key | ifslab's (default) | the paper's (`paper = true`) |
    /// |---|---|---|
    /// | `flames` | one layer of 16 linear generators | one of 8 (their Fig. 4) |
    /// | `strategy` | Adam, lr 0.05 | plain gradient descent, lr 0.1 |
    /// | `rates` | [`Rates::for_adam`] | the authors' ([`Rates::default`]); Adam's with Adam |
    /// | `background` | `auto` (the mean colour of the target's border) | `white` |
    /// | `frame` | true (the picture cut to its content, padded square) | false (resized whole) |
    pub fn preset(paper: bool, table: &toml::Table) -> toml::Table {
        use crate::recipe::{get_dotted, table_of};
        let mut preset = toml::Table::new();
        if !table.contains_key("flames") {
            let mut layer = toml::Table::new();
            layer.insert("xforms".into(), (default_xforms(paper) as i64).into());
            layer.insert(
                "variations".into(),
                vec![toml::Value::from("linear")].into(),
            );
            preset.insert("flames".into(), vec![toml::Value::Table(layer)].into());
        }
        if !paper {
            preset.extend(table_of([
                ("background", "auto".into()),
                ("frame", true.into()),
            ]));
            // A strategy is chosen whole: the recipe's only where the config names none.
            if !table.contains_key("strategy") {
                preset.extend(table_of([
                    ("strategy.kind", AdamConfig::KIND.into()),
                    ("strategy.lr", DEFAULT_ADAM_LR.into()),
                ]));
            }
        }
        let recipe_kind = if paper {
            GdConfig::KIND
        } else {
            AdamConfig::KIND
        };
        let kind = get_dotted(table, "strategy.kind")
            .and_then(toml::Value::as_str)
            .unwrap_or(recipe_kind);
        // Adam's steps are scale-free, so its rates are far smaller than the authors'
        // gradient-descent ones (in either recipe); any other strategy keeps theirs.
        if kind == AdamConfig::KIND {
            let r = Rates::for_adam();
            preset.extend(table_of([
                ("rates.final_transform", r.final_transform.into()),
                ("rates.kappa", r.kappa.into()),
                ("rates.color", r.color.into()),
                ("rates.background", r.background.into()),
            ]));
        }
        preset
    }

    /// A config from a parsed TOML table: the recipe's values merged where the table
    /// leaves keys out ([`FlameLearnConfig::preset`]), then parsed and validated.
    pub fn from_table(table: toml::Table, origin: &Path) -> Result<Self> {
        let cfg: FlameLearnConfig =
            crate::recipe::resolve(table, origin, FlameLearnConfig::preset)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Parses and validates TOML text (see [`FlameLearnConfig::from_table`]); `origin`
    /// names it in errors.
    pub fn from_toml(text: &str, origin: &Path) -> Result<Self> {
        let table: toml::Table = text.parse().map_err(|e| Error::file(origin, e))?;
        FlameLearnConfig::from_table(table, origin)
    }

    /// Relative file names read as relative to `dir`.
    pub fn relative_to(mut self, dir: &Path) -> Self {
        if self.target.is_relative() {
            self.target = dir.join(&self.target);
        }
        self
    }

    /// Every file named absolutely (against the working directory).
    pub fn with_absolute_paths(&self) -> Result<Self> {
        let abs = |p: &Path| std::path::absolute(p).map_err(|e| Error::file(p, e));
        let mut cfg = self.clone();
        cfg.target = abs(&self.target)?;
        if let Some(out) = &self.output {
            cfg.output = Some(abs(out)?);
        }
        Ok(cfg)
    }

    /// The background as the model holds it for `target` (three planes of `size²`; only
    /// `"auto"` reads it).
    pub fn background(
        &self,
        target: &[f32],
    ) -> Result<ifslab::model::flame::learnable::Background> {
        use ifslab::model::flame::learnable::Background;
        Ok(match &self.background {
            BackgroundConfig::Rgb(c) => {
                if c.iter().any(|v| !(0.0..=1.0).contains(v)) {
                    return Err(Error::param(
                        "background",
                        format!("components lie in [0, 1], got {c:?}"),
                    ));
                }
                Background::Fixed(*c)
            }
            BackgroundConfig::Named(n) => match n.as_str() {
                "white" => Background::Fixed([1.0; 3]),
                "black" => Background::Fixed([0.0; 3]),
                "learned" => Background::Learned([0.0; 3]),
                "auto" => Background::Fixed(border_mean(target, self.sampler.size)),
                other => {
                    return Err(Error::param(
                        "background",
                        format!("`{other}`: use white, black, learned, auto or [r, g, b]"),
                    ));
                }
            },
        })
    }

    /// Checks every field; errors name the field.
    pub fn validate(&self) -> Result<()> {
        if self.iterations == 0 {
            return Err(Error::param("iterations", "must be at least 1"));
        }
        self.sampler.validate()?;
        if self.sampler.size < 4 {
            return Err(Error::param(
                "sampler.size",
                format!("at least 4 pixels, got {}", self.sampler.size),
            ));
        }
        if self.flames.is_empty() {
            return Err(Error::param("flames", "give at least one flame layer"));
        }
        for (i, l) in self.flames.iter().enumerate() {
            if !(1..=255).contains(&l.xforms) {
                return Err(Error::param(
                    "flames.xforms",
                    format!("flame {i}: between 1 and 255 generators, got {}", l.xforms),
                ));
            }
            if l.linear > l.xforms {
                return Err(Error::param(
                    "flames.linear",
                    format!("flame {i}: {} linear generators of {}", l.linear, l.xforms),
                ));
            }
            l.generators()?;
        }
        if let BackgroundConfig::Named(n) = &self.background
            && !["white", "black", "learned", "auto"].contains(&n.as_str())
        {
            return Err(Error::param(
                "background",
                format!("`{n}`: use white, black, learned, auto or [r, g, b]"),
            ));
        }
        if let BackgroundConfig::Rgb(c) = &self.background
            && c.iter().any(|v| !(0.0..=1.0).contains(v))
        {
            return Err(Error::param(
                "background",
                format!("components lie in [0, 1], got {c:?}"),
            ));
        }
        self.loss.validate()?;
        let r = &self.rates;
        for (name, v) in [
            ("rates.generators", r.generators),
            ("rates.final_transform", r.final_transform),
            ("rates.kappa", r.kappa),
            ("rates.color", r.color),
            ("rates.background", r.background),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::param(
                    name,
                    format!("must be finite and ≥ 0, got {v}"),
                ));
            }
        }
        ifslab::model::flame::learnable::kappa_raw_of(self.init.kappa)
            .map_err(|e| Error::param("init.kappa", e.to_string()))?;
        for (name, v) in [
            ("init.translation", self.init.translation),
            ("init.scale", self.init.scale),
            ("init.final_translation", self.init.final_translation),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::param(
                    name,
                    format!("must be finite and ≥ 0, got {v}"),
                ));
            }
        }
        if self.eval_size > 8192 {
            return Err(Error::param(
                "eval_size",
                format!("at most 8192, got {}", self.eval_size),
            ));
        }
        self.strategy.validate()?;
        // The run's work: every iteration draws (and differentiates) every layer's samples.
        let s = &self.sampler;
        let samples = s.trajectories as f64 * (s.steps + s.warmup) as f64;
        let layers = self.flames.len() as f64;
        ifslab::budget::check_rate(
            self.iterations as f64 * layers * samples,
            SAMPLES_PER_SECOND_PER_THREAD,
            rayon::current_num_threads(),
            "samples",
            &format!(
                "{} iterations of {layers} layer(s) × {samples:.0e} samples",
                self.iterations
            ),
            "`iterations` (--iters) or `sampler.trajectories` / `sampler.steps`",
        )?;
        Ok(())
    }
}

/// Samples one thread draws and differentiates per second while learning a flame: an
/// optimistic figure (the learnable-flame benchmark measures ~1.5 × 10⁷), so only runs that
/// would clearly take too long are refused.
pub const SAMPLES_PER_SECOND_PER_THREAD: f64 = 1e8;

/// The mean colour of the outermost ring of pixels of a `size²` RGB target (white for an
/// empty or mis-sized one).
fn border_mean(target: &[f32], size: usize) -> [f64; 3] {
    let n = size * size;
    if size == 0 || target.len() != 3 * n {
        return [1.0; 3];
    }
    let mut sum = [0.0f64; 3];
    let mut count = 0usize;
    for y in 0..size {
        for x in 0..size {
            if x == 0 || y == 0 || x + 1 == size || y + 1 == size {
                for (ch, s) in sum.iter_mut().enumerate() {
                    *s += target[ch * n + y * size + x] as f64;
                }
                count += 1;
            }
        }
    }
    sum.map(|s| (s / count as f64).clamp(0.0, 1.0))
}

#[cfg(test)]
mod recipe_tests {
    use super::*;

    const MINIMAL: &str = "target = \"t.png\"\n[[flames]]\nxforms = 8\nvariations = [\"linear\"]\n";

    #[test]
    fn the_default_recipe_is_adam_and_the_papers_is_one_key_away() {
        let ours = FlameLearnConfig::from_toml(MINIMAL, Path::new("c.toml")).unwrap();
        assert_eq!(
            ours,
            FlameLearnConfig::new("t.png", 8, vec!["linear".into()])
        );
        assert_eq!(ours.strategy.name(), "adam");
        assert_eq!(ours.rates, Rates::for_adam());
        assert_eq!(ours.background, BackgroundConfig::Named("auto".into()));
        let paper =
            FlameLearnConfig::from_toml(&format!("paper = true\n{MINIMAL}"), Path::new("c.toml"))
                .unwrap();
        assert_eq!(
            paper,
            FlameLearnConfig::paper("t.png", 8, vec!["linear".into()])
        );
        assert_eq!(paper.strategy.name(), "gd");
        assert_eq!(paper.rates, Rates::default());
        // Gradient descent named under ifslab's recipe keeps the authors' rates; Adam named
        // under the paper's gets Adam's.
        let gd = FlameLearnConfig::from_toml(
            &format!("{MINIMAL}[strategy]\nkind = \"gd\"\nlr = 0.1\n"),
            Path::new("c.toml"),
        )
        .unwrap();
        assert_eq!(gd.rates, Rates::default());
        let adam = FlameLearnConfig::from_toml(
            &format!("paper = true\n{MINIMAL}[strategy]\nkind = \"adam\"\nlr = 0.05\n"),
            Path::new("c.toml"),
        )
        .unwrap();
        assert_eq!(adam.rates, Rates::for_adam());
    }
}
