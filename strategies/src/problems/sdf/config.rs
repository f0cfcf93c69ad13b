//! The configuration of a segment-pattern fit (`problem = "sdf"` in `ifslab run`, or
//! `ifslab sdf fit`'s flags), validated before anything runs and written beside the results.

use std::path::{Path, PathBuf};

use ifslab::model::segment::{Pattern, resolve_pattern};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::optim::adam::AdamConfig;
use crate::problems::image::target::Polarity;
use crate::problems::sdf::init::{PROBE_STEPS, SdfInit};
use crate::problems::sdf::learned::LearnedConfig;
use crate::problems::sdf::problem::SdfLossConfig;
use crate::strategy_config::StrategyConfig;

/// The most Adam steps `init.probe_steps` may ask for per start (a whole fit's worth of
/// probing many times over; the run's work budget refuses long ones before this does).
pub const MAX_PROBE_STEPS: u64 = 1_000_000;

/// How the control points start.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SdfInitConfig {
    /// `line` (the paper's best-fit line), `pattern` or `given`.
    pub kind: SdfInit,
    /// Standard deviation of Gaussian noise added to the start (units of the target's side),
    /// drawn from the run's seed.
    pub jitter: f64,
    /// Adam steps each candidate of `best` is followed for before they are compared.
    pub probe_steps: u64,
    /// Whether `best` also tries the pattern stretched into the ink's box on both axes (see
    /// [`candidate_starts`](crate::problems::sdf::candidate_starts)); on by default, written
    /// only when off, so configs made before it resolve as they did.
    #[serde(skip_serializing_if = "is_true")]
    pub stretched: bool,
}

fn is_true(v: &bool) -> bool {
    *v
}

impl Default for SdfInitConfig {
    fn default() -> Self {
        SdfInitConfig {
            kind: SdfInit::Line,
            jitter: 0.0,
            probe_steps: PROBE_STEPS,
            stretched: true,
        }
    }
}

/// A whole fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SdfConfig {
    /// The recipe the keys a config leaves out come from: ifslab's (false, the default) or
    /// Scott's paper's (true); see [`SdfConfig::preset`].
    #[serde(default)]
    pub paper: bool,
    /// The target image (relative to the config file's folder).
    pub target: PathBuf,
    /// A built-in pattern (`koch`, `carpet`, `carpet-square`) or a pattern file.
    pub pattern: String,
    /// Side of the square target and render, in pixels.
    #[serde(default = "default_size")]
    pub size: usize,
    /// Recursion depth K.
    #[serde(default = "default_depth")]
    pub depth: usize,
    /// Width σ of the drawn figure, in pixels (`exp(−d²/σ²)`).
    #[serde(default = "default_sigma")]
    pub sigma: f64,
    /// Draw the figure as wide as the target's strokes instead of `sigma`, for patterns
    /// whose base figure is a segment (filled base figures keep `sigma`): σ from the stroke
    /// width measured on the picture, in its own pixels, times the framing's scale
    /// ([`crate::problems::sdf::sigma_for_stroke`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub stroke_sigma: bool,
    /// With `stroke_sigma`: fit once at each of these multiples of the strokes' σ (each
    /// at least the lower bound of [`crate::problems::sdf::STROKE_SIGMA_RANGE`], equal
    /// widths once), each fit whole and from its own start, and keep the one whose render
    /// agrees best with the target (IoU of the half-inked pixels;
    /// [`crate::problems::sdf::stroke_sigma_legs`]). Empty: one fit at the strokes' σ.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sigma_factors: Vec<f64>,
    /// When the kept fit's render agrees with the target on an IoU below this (of the
    /// half-inked pixels: a fit stuck in a wrong optimum, as thin curves can be), two more
    /// whole fits at its σ — coarse to fine from [`RESCUE_SIGMA_START`] px (or twice its σ),
    /// and with the distance term at [`RESCUE_DISTANCE`] — and the one that agrees best kept.
    /// 0 (the paper's): never.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub rescue_below: f64,
    /// Coarse to fine: σ at the first iteration, shrinking geometrically to `sigma` at the
    /// last (absent: `sigma` throughout, as the paper).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_start: Option<f64>,
    /// Iterations over which σ shrinks from `sigma_start` (absent: all of them); the rest
    /// run at `sigma`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_iterations: Option<u64>,
    /// Optimisation iterations.
    #[serde(default = "default_iterations")]
    pub iterations: u64,
    /// Seed of the start's jitter (and of any randomised strategy).
    #[serde(default)]
    pub seed: u64,
    /// Write a checkpoint every this many iterations (0: never).
    #[serde(default = "default_checkpoint_every")]
    pub checkpoint_every: u64,
    /// Which way round the target's shape is drawn.
    #[serde(default)]
    pub polarity: Polarity,
    /// Output folder (the command line's `-o` wins).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output: Option<PathBuf>,
    /// The loss.
    #[serde(default)]
    pub loss: SdfLossConfig,
    /// The start.
    #[serde(default)]
    pub init: SdfInitConfig,
    /// The strategy (any registered one; Adam with lr 2e-3 by default).
    #[serde(default = "default_strategy")]
    pub strategy: StrategyConfig,
    /// Learned pairs (absent: the pattern's own pairs, fixed; see
    /// [`crate::problems::sdf::learned`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learned: Option<LearnedConfig>,
    /// The pattern that drew the target, when it is known (a pattern file or built-in
    /// name): the fit is then also scored against it, both drawn alike, each framed in its
    /// own box (summary `truth_iou`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<String>,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}
fn default_size() -> usize {
    128
}
fn default_depth() -> usize {
    5
}
fn default_sigma() -> f64 {
    1.5
}
fn default_iterations() -> u64 {
    300
}
fn default_checkpoint_every() -> u64 {
    25
}
/// ifslab's multiples of the strokes' σ, one fit each, the best kept (`sigma_factors`). On
/// the robustness suite's Koch pictures, both tuning splits: 20 → 23 and 19 → 22 of 24
/// recovered (truth IoU ≥ 0.8), no fit worse by more than 0.005; a thick or enlarged
/// stroke's σ blurs away the detail a narrower one keeps (robustness/README.md).
pub const DEFAULT_SIGMA_FACTORS: [f64; 3] = [1.0, 0.75, 0.5];

/// ifslab's `rescue_below`. On the robustness suite's fourth tuning split, whose Koch pictures
/// held three thin curves fitted into wrong optima (their renders' IoU with the picture
/// 0.13–0.23, where every passing thin curve's is at least 0.67), the two further fits
/// recovered two (truth IoU 0.21 → 0.98, 0.15 → 0.95); no passing fit of the tuning splits
/// agrees below 0.5, so none is fitted again (robustness/README.md).
pub const DEFAULT_RESCUE_BELOW: f64 = 0.5;
/// σ, in pixels, the coarse-to-fine rescue fit starts from (at least twice the kept σ).
pub const RESCUE_SIGMA_START: f64 = 2.0;
/// The distance term's weight in the other rescue fit.
pub const RESCUE_DISTANCE: f64 = 0.1;

/// The most `sigma_factors` a config may list (each is a whole fit).
pub const MAX_SIGMA_FACTORS: usize = 8;

/// ifslab's side of the framed target (`size`), in pixels.
pub const DEFAULT_SIZE: usize = 192;
/// Adam with a learning rate for points in the unit square.
pub fn default_strategy() -> StrategyConfig {
    StrategyConfig::new(&AdamConfig {
        lr: 2e-3,
        ..AdamConfig::default()
    })
}

impl SdfConfig {
    /// A config of ifslab's recipe (the default) for `target` and `pattern`: what a config
    /// naming only those two keys resolves to.
    pub fn new(target: impl Into<PathBuf>, pattern: impl Into<String>) -> Self {
        let mut cfg = SdfConfig::paper(target, pattern);
        cfg.paper = false;
        cfg.init.kind = SdfInit::Best;
        cfg.stroke_sigma = true;
        cfg.sigma_factors = DEFAULT_SIGMA_FACTORS.to_vec();
        cfg.rescue_below = DEFAULT_RESCUE_BELOW;
        cfg.size = DEFAULT_SIZE;
        cfg
    }

    /// A config of Scott's recipe (`paper = true`) for `target` and `pattern`.
    pub fn paper(target: impl Into<PathBuf>, pattern: impl Into<String>) -> Self {
        SdfConfig {
            paper: true,
            target: target.into(),
            pattern: pattern.into(),
            size: default_size(),
            depth: default_depth(),
            sigma: default_sigma(),
            stroke_sigma: false,
            sigma_factors: Vec::new(),
            rescue_below: 0.0,
            sigma_start: None,
            sigma_iterations: None,
            iterations: default_iterations(),
            seed: 0,
            checkpoint_every: default_checkpoint_every(),
            polarity: Polarity::Auto,
            output: None,
            loss: SdfLossConfig::default(),
            init: SdfInitConfig::default(),
            strategy: default_strategy(),
            learned: None,
            truth: None,
        }
    }

    /// The values of the keys whose defaults depend on the recipe, for a config `table`
    /// that asks for the paper's recipe (`paper`) or not; merged where the table leaves a
    /// key out ([`crate::recipe`]). Measured on the robustness suite's tuning split
    /// (`robustness/README.md`).
    ///
    /// | key | ifslab's (default) | the paper's (`paper = true`) |
    /// |---|---|---|
    /// | `init.kind` | `best` (the best of up to seven starts after a few coarse steps; `init.stretched` true) | `line` |
    /// | `stroke_sigma` | true (σ as wide as the picture's strokes) | false (`sigma`) |
    /// | `sigma_factors` | 1, 0.75, 0.5 (three fits, the one that agrees best with the target kept) | none |
    /// | `rescue_below` | 0.5 (two more fits where the kept one agrees on an IoU below it) | 0 |
    /// | `size` | 192 | 128 |
    pub fn preset(paper: bool, _table: &toml::Table) -> toml::Table {
        use crate::recipe::table_of;
        if paper {
            return toml::Table::new();
        }
        table_of([
            ("init.kind", SdfInit::Best.name().into()),
            ("stroke_sigma", true.into()),
            (
                "sigma_factors",
                toml::Value::Array(DEFAULT_SIGMA_FACTORS.iter().map(|&f| f.into()).collect()),
            ),
            ("rescue_below", DEFAULT_RESCUE_BELOW.into()),
            ("size", (DEFAULT_SIZE as i64).into()),
        ])
    }

    /// A config from a parsed TOML table: the recipe's values merged where the table
    /// leaves keys out ([`SdfConfig::preset`]), then parsed and validated.
    pub fn from_table(table: toml::Table, origin: &Path) -> Result<Self> {
        let cfg: SdfConfig = crate::recipe::resolve(table, origin, SdfConfig::preset)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Parses and validates TOML text (see [`SdfConfig::from_table`]); `origin` names it in
    /// errors.
    pub fn from_toml(text: &str, origin: &Path) -> Result<Self> {
        let table: toml::Table = text.parse().map_err(|e| Error::file(origin, e))?;
        SdfConfig::from_table(table, origin)
    }

    /// TOML text of the resolved configuration.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("an sdf config always serialises")
    }

    /// Relative file names (target, pattern file) read as relative to `dir`.
    pub fn relative_to(mut self, dir: &Path) -> Self {
        if self.target.is_relative() {
            self.target = dir.join(&self.target);
        }
        for spec in std::iter::once(&mut self.pattern).chain(self.truth.as_mut()) {
            if dir.join(&*spec).is_file() {
                *spec = dir.join(&*spec).to_string_lossy().into_owned();
            }
        }
        self
    }

    /// Every file named absolutely (against the working directory); built-in names kept.
    pub fn with_absolute_paths(&self) -> Result<Self> {
        let abs = |p: &Path| std::path::absolute(p).map_err(|e| Error::file(p, e));
        let mut cfg = self.clone();
        cfg.target = abs(&self.target)?;
        if Path::new(&self.pattern).is_file() {
            cfg.pattern = abs(Path::new(&self.pattern))?
                .to_string_lossy()
                .into_owned();
        }
        if let Some(t) = &self.truth
            && Path::new(t).is_file()
        {
            cfg.truth = Some(abs(Path::new(t))?.to_string_lossy().into_owned());
        }
        if let Some(out) = &self.output {
            cfg.output = Some(abs(out)?);
        }
        Ok(cfg)
    }

    /// The pattern the config names (validated).
    pub fn pattern(&self) -> Result<Pattern> {
        Ok(resolve_pattern(&self.pattern)?)
    }

    /// Checks every field; errors name the field.
    pub fn validate(&self) -> Result<()> {
        if self.iterations == 0 {
            return Err(Error::param("iterations", "must be at least 1"));
        }
        if self.size < 8 {
            return Err(Error::param(
                "size",
                format!("targets need at least 8×8 pixels, got {}", self.size),
            ));
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return Err(Error::param(
                "sigma",
                format!("must be > 0 pixels, got {}", self.sigma),
            ));
        }
        if self.sigma_factors.len() > MAX_SIGMA_FACTORS
            || self
                .sigma_factors
                .iter()
                .any(|f| !(f.is_finite() && *f > 0.0 && *f <= 4.0))
        {
            return Err(Error::param(
                "sigma_factors",
                format!(
                    "at most {MAX_SIGMA_FACTORS} multiples of the strokes' σ, each in (0, 4], got {:?}",
                    self.sigma_factors
                ),
            ));
        }
        if !(self.rescue_below.is_finite() && (0.0..=1.0).contains(&self.rescue_below)) {
            return Err(Error::param(
                "rescue_below",
                format!("must be an IoU in [0, 1], got {}", self.rescue_below),
            ));
        }
        if let Some(s0) = self.sigma_start
            && !(s0.is_finite() && s0 > 0.0)
        {
            return Err(Error::param(
                "sigma_start",
                format!("must be > 0 pixels, got {s0}"),
            ));
        }
        if let Some(k) = self.sigma_iterations {
            if self.sigma_start.is_none() {
                return Err(Error::param(
                    "sigma_iterations",
                    "needs sigma_start (the width the schedule starts from)",
                ));
            }
            if k == 0 || k > self.iterations {
                return Err(Error::param(
                    "sigma_iterations",
                    format!(
                        "must be between 1 and iterations ({}), got {k}",
                        self.iterations
                    ),
                ));
            }
        }
        if !(self.init.jitter.is_finite() && self.init.jitter >= 0.0) {
            return Err(Error::param(
                "init.jitter",
                format!("must be ≥ 0, got {}", self.init.jitter),
            ));
        }
        if self.init.probe_steps > MAX_PROBE_STEPS {
            return Err(Error::param(
                "init.probe_steps",
                format!(
                    "must be at most {MAX_PROBE_STEPS} Adam steps per start, got {}",
                    self.init.probe_steps
                ),
            ));
        }
        self.loss.validate()?;
        if let Some(l) = &self.learned {
            l.validate()?;
        }
        self.strategy.validate()?;
        let p = self.pattern()?;
        let n = p.n_maps();
        let leaves = (0..self.depth).try_fold(1usize, |a, _| a.checked_mul(n));
        if leaves.is_none_or(|l| l > ifslab::render::sdf::MAX_PRIMITIVES) {
            return Err(Error::param(
                "depth",
                format!(
                    "depth {} with {n} maps is more than {} primitives; lower the depth",
                    self.depth,
                    ifslab::render::sdf::MAX_PRIMITIVES
                ),
            ));
        }
        // The fit's work: every step draws (and differentiates) every pixel, and every
        // primitive moves; the best-of-starts probes come first.
        let probes = if self.init.kind == SdfInit::Best {
            self.init.probe_steps.saturating_mul(7)
        } else {
            0
        };
        // Each width of `sigma_factors` is a whole fit (fewer where widths coincide).
        let fits = if self.stroke_sigma {
            self.sigma_factors.len().max(1)
        } else {
            1
        };
        let steps = self.iterations.saturating_add(probes) as f64 * fits as f64;
        let per_step =
            (self.size as f64) * (self.size as f64) + leaves.unwrap_or(usize::MAX) as f64;
        ifslab::budget::check_rate(
            steps * per_step,
            PIXELS_PER_SECOND_PER_THREAD,
            rayon::current_num_threads(),
            "pixels",
            &format!("{steps} steps over {}² pixels", self.size),
            "`iterations` (--iters) or `size` (--size)",
        )?;
        Ok(())
    }
}

/// Pixels (or primitives) one thread draws and differentiates per second in a fit: an
/// optimistic figure (default fits measure ~4 × 10⁶), so only runs that would clearly take
/// too long are refused.
pub const PIXELS_PER_SECOND_PER_THREAD: f64 = 2e7;

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = "target = \"t.png\"\npattern = \"koch\"\n";

    #[test]
    fn the_default_recipe_starts_best_at_the_strokes_width_and_the_papers_is_one_key_away() {
        let ours = SdfConfig::from_toml(MINIMAL, Path::new("c.toml")).unwrap();
        assert_eq!(ours, SdfConfig::new("t.png", "koch"));
        assert_eq!(ours.init.kind, SdfInit::Best);
        assert!(ours.stroke_sigma && ours.size == DEFAULT_SIZE);
        assert_eq!((ours.sigma_start, ours.sigma_iterations), (None, None));
        let paper =
            SdfConfig::from_toml(&format!("paper = true\n{MINIMAL}"), Path::new("c.toml")).unwrap();
        assert_eq!(paper, SdfConfig::paper("t.png", "koch"));
        assert_eq!(paper.init.kind, SdfInit::Line);
        assert!(!paper.stroke_sigma && paper.size == 128);
        for cfg in [ours, paper] {
            let back = SdfConfig::from_toml(&cfg.to_toml(), Path::new("c.toml")).unwrap();
            assert_eq!(back, cfg);
        }
        // The paper's recipe writes nothing it did not write before recipes existed.
        let text = SdfConfig::paper("t.png", "koch").to_toml();
        assert!(
            !text.contains("stroke_sigma")
                && !text.contains("sigma_factors")
                && !text.contains("truth"),
            "{text}"
        );
        // Keys given win: a coarse-to-fine schedule over the default start.
        let given = SdfConfig::from_toml(
            &format!("{MINIMAL}sigma_start = 3.0\nsize = 96\n"),
            Path::new("c"),
        )
        .unwrap();
        assert_eq!((given.sigma_start, given.size), (Some(3.0), 96));
        assert_eq!(given.init.kind, SdfInit::Best);
    }

    #[test]
    fn the_starts_are_probed_80_steps_and_an_absurd_count_is_refused() {
        let ours = SdfConfig::from_toml(MINIMAL, Path::new("c.toml")).unwrap();
        assert_eq!(ours.init.probe_steps, 80);
        let huge = SdfConfig::from_toml(
            &format!("{MINIMAL}[init]\nprobe_steps = 9223372036854775807\n"),
            Path::new("c.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(huge.contains("init.probe_steps"), "{huge}");
    }

    #[test]
    fn three_widths_by_default_one_under_the_paper_and_bad_factors_are_refused() {
        let ours = SdfConfig::from_toml(MINIMAL, Path::new("c.toml")).unwrap();
        assert_eq!(ours.sigma_factors, vec![1.0, 0.75, 0.5]);
        let paper =
            SdfConfig::from_toml(&format!("paper = true\n{MINIMAL}"), Path::new("c.toml")).unwrap();
        assert!(paper.sigma_factors.is_empty());
        let one =
            SdfConfig::from_toml(&format!("{MINIMAL}sigma_factors = [1.0]\n"), Path::new("c"))
                .unwrap();
        assert_eq!(one.sigma_factors, vec![1.0]);
        for bad in ["[0.0]", "[-1.0]", "[5.0]", "[1, 1, 1, 1, 1, 1, 1, 1, 1]"] {
            let e =
                SdfConfig::from_toml(&format!("{MINIMAL}sigma_factors = {bad}\n"), Path::new("c"))
                    .unwrap_err()
                    .to_string();
            assert!(e.contains("sigma_factors"), "{bad}: {e}");
        }
    }
}
