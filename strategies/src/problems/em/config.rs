//! What an EM fit is told: [`EmConfig`] (the defaults and [`EmConfig::paper`]), its
//! validation, and the stream tags that keep a fit's random draws apart.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::em::mstep::{ComponentUpdate, MStepConfig};
use crate::problems::em::reorient::ReorientConfig;

/// How the pre-selection winner is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PreselectBy {
    /// The highest mean log-likelihood of the evaluation points (default).
    #[default]
    LogLikelihood,
    /// The highest mean depth Σ d·v_d (the paper's criterion).
    MeanDepth,
}

/// Stream tags that keep the run's random draws apart.
pub(crate) mod stream {
    pub const INIT: u64 = 0x1a17;
    pub const PRESELECT: u64 = 0x9e5e;
    pub const MAIN: u64 = 0x3a17;
    pub const EVAL: u64 = 0xe7a1;
    pub const ROTATIONS: u64 = 0x7047;
}

/// The largest number of codes a model may have (memory and time grow with it).
pub const MAX_CODES: usize = 4_000_000;

/// Everything a fit needs.
///
/// The defaults are the paper's Fig. 5a settings (K = 3, D = 6, 300 iterations, N′ = 500,
/// a pool of 10 trained for 100 iterations up to depth 3) with two changes that make a fit
/// converge far more often — the re-orientation search and the moment-matched base Gaussian
/// at the start of the main run (on an independent Sierpiński sample, 8/8 seeds against 3/8
/// and 1/8 with either one off) — and three that each alone changed nothing there: the
/// all-positions M-step, the depth curriculum and selection by likelihood in pre-selection.
/// The last two together make a random 4-map code converge (8/8 against 1/8 without), and
/// cost the Heighway dragon 0.24 nats/point (`paper_repro/ifs_em/README.md`).
/// [`EmConfig::paper`] gives the paper's algorithm.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EmConfig {
    /// Number of components K.
    pub components: usize,
    /// Maximum depth D of the codes.
    pub depth: usize,
    /// EM iterations of the chosen candidate at depth D.
    pub iterations: usize,
    /// Minibatch size N′ (0: full batch).
    pub batch_size: usize,
    /// Pre-selection pool size (1: a single random start, no pre-selection).
    pub pool: usize,
    /// Deepest depth at which pool candidates are trained (capped at `depth`).
    pub preselect_depth: usize,
    /// Iterations each pool candidate is trained (over all its curriculum stages).
    pub preselect_iterations: usize,
    /// Train candidates at depths 1, 2, …, `preselect_depth` in turn, the iterations spread
    /// evenly; false: all at `preselect_depth` (the paper).
    pub curriculum: bool,
    /// How the pre-selection winner is chosen.
    pub preselect_by: PreselectBy,
    /// The re-orientation search (see [`crate::problems::em::reorient`]).
    pub reorient: ReorientConfig,
    /// Training points that score candidates and re-orientations, drawn once per fit
    /// (0: all of them).
    pub eval_points: usize,
    /// Move the model frame so that the base Gaussian has the invariant measure's mean and
    /// spread when the main run starts ([`crate::problems::em::EmModel::recentred`]).
    pub recentre: bool,
    /// A run has converged when this share of the depth weight is on depth D.
    pub convergence: f64,
    /// Scale of the initial maps.
    pub init_scale: f64,
    /// Evaluate the held-out log-likelihood every this many iterations (0: only at the end).
    pub eval_every: usize,
    /// M-step variant, bounds and repairs.
    pub mstep: MStepConfig,
    /// Seed of the run.
    pub seed: u64,
}

impl Default for EmConfig {
    fn default() -> Self {
        EmConfig {
            components: 3,
            depth: 6,
            iterations: 300,
            batch_size: 500,
            pool: 10,
            preselect_depth: 3,
            preselect_iterations: 100,
            curriculum: true,
            preselect_by: PreselectBy::LogLikelihood,
            reorient: ReorientConfig::default(),
            eval_points: 1000,
            recentre: true,
            convergence: 0.95,
            init_scale: 0.5,
            eval_every: 0,
            mstep: MStepConfig::default(),
            seed: 0,
        }
    }
}

impl EmConfig {
    /// The paper's algorithm at the paper's Fig. 5a settings: the outermost-map M-step,
    /// candidates trained at depth 3 only and chosen by mean depth, no re-orientation, the
    /// base Gaussian left where pre-selection put it.
    pub fn paper() -> Self {
        EmConfig {
            curriculum: false,
            preselect_by: PreselectBy::MeanDepth,
            reorient: ReorientConfig::off(),
            recentre: false,
            mstep: MStepConfig {
                update: ComponentUpdate::Outermost,
                reflections: false,
                ..MStepConfig::default()
            },
            ..EmConfig::default()
        }
    }
}

/// Number of codes of length 0 … `depth` over `k` symbols, saturating.
pub fn code_count(k: usize, depth: usize) -> usize {
    let mut n = 0usize;
    let mut level = 1usize;
    for _ in 0..=depth {
        n = n.saturating_add(level);
        level = level.saturating_mul(k);
    }
    n
}

impl EmConfig {
    /// Checks every field; the error names the one to change.
    pub fn validate(&self) -> Result<()> {
        if self.components == 0 {
            return Err(Error::param("k", "need at least one component"));
        }
        if self.depth == 0 {
            return Err(Error::param("depth", "must be at least 1"));
        }
        for (name, d) in [
            ("depth", self.depth),
            ("preselect_depth", self.preselect_depth),
        ] {
            let n = code_count(self.components, d);
            if n > MAX_CODES {
                return Err(Error::param(
                    if name == "depth" {
                        "depth"
                    } else {
                        "preselect_depth"
                    },
                    format!(
                        "K = {} at {name} {d} gives {n} codes (more than {MAX_CODES}); lower the depth",
                        self.components
                    ),
                ));
            }
        }
        if self.pool == 0 {
            return Err(Error::param("pool", "must be at least 1"));
        }
        if self.pool > 1 && self.preselect_depth == 0 {
            return Err(Error::param("preselect_depth", "must be at least 1"));
        }
        if !(self.convergence > 0.0 && self.convergence <= 1.0) {
            return Err(Error::param(
                "convergence",
                format!("must lie in (0, 1], got {}", self.convergence),
            ));
        }
        if !(self.init_scale > 0.0 && self.init_scale < 1.0) {
            return Err(Error::param(
                "init_scale",
                format!("must lie in (0, 1), got {}", self.init_scale),
            ));
        }
        self.reorient.validate()?;
        self.mstep.validate()
    }
}
