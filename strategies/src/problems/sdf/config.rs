//! The configuration of a segment-pattern fit (`problem = "sdf"` in `ifslab run`, or
//! `ifslab sdf fit`'s flags), validated before anything runs and written beside the results.

use std::path::{Path, PathBuf};

use ifslab::model::segment::{Pattern, resolve_pattern};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::optim::adam::AdamConfig;
use crate::problems::image::config::StrategyConfig;
use crate::problems::image::target::Polarity;
use crate::problems::sdf::init::SdfInit;
use crate::problems::sdf::learned::LearnedConfig;
use crate::problems::sdf::problem::SdfLossConfig;

/// How the control points start.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SdfInitConfig {
    /// `line` (the paper's best-fit line), `pattern` or `given`.
    pub kind: SdfInit,
    /// Standard deviation of Gaussian noise added to the start (units of the target's side),
    /// drawn from the run's seed.
    pub jitter: f64,
}

impl Default for SdfInitConfig {
    fn default() -> Self {
        SdfInitConfig {
            kind: SdfInit::Line,
            jitter: 0.0,
        }
    }
}

/// A whole fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SdfConfig {
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
/// Adam with a learning rate for points in the unit square.
pub fn default_strategy() -> StrategyConfig {
    StrategyConfig::new(&AdamConfig {
        lr: 2e-3,
        ..AdamConfig::default()
    })
}

impl SdfConfig {
    /// A config with every default, for `target` and `pattern`.
    pub fn new(target: impl Into<PathBuf>, pattern: impl Into<String>) -> Self {
        SdfConfig {
            target: target.into(),
            pattern: pattern.into(),
            size: default_size(),
            depth: default_depth(),
            sigma: default_sigma(),
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
        }
    }

    /// Parses and validates TOML text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &Path) -> Result<Self> {
        let cfg: SdfConfig = toml::from_str(text).map_err(|e| Error::file(origin, e))?;
        cfg.validate()?;
        Ok(cfg)
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
        if dir.join(&self.pattern).is_file() {
            self.pattern = dir.join(&self.pattern).to_string_lossy().into_owned();
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
        Ok(())
    }
}
