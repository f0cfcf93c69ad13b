//! What an EM fit is told: [`EmConfig`] (the defaults and [`EmConfig::paper`]), its
//! validation, and the stream tags that keep a fit's random draws apart.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::em::mstep::{ComponentUpdate, MStepConfig};
use crate::problems::em::reorient::ReorientConfig;
use crate::problems::em::words::WordMoves;

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

impl EmConfig {
    /// The word search's bounds when it runs (`reorient.words`), else `None`.
    pub fn word_moves(&self) -> Option<WordMoves> {
        self.reorient.words.then_some(WordMoves {
            max_scale: self.mstep.max_scale,
            reflections: self.mstep.reflections,
        })
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

/// Point × code evaluations (an E-step's unit of work) one thread does per second: an
/// optimistic figure (the suite's fits measured 1–3 × 10⁸), so that only runs that would
/// clearly take too long are refused.
pub const EVALS_PER_SECOND_PER_THREAD: f64 = 1e9;

impl EmConfig {
    /// The point × code evaluations one fit to `n` training points plans: the pool's
    /// candidates at the pre-selection depth, the main run at depth D (a minibatch or all
    /// points per iteration), and each re-orientation search (every component, every
    /// orientation, the evaluation points).
    pub fn work(&self, n: usize) -> f64 {
        let batch = if self.batch_size == 0 {
            n
        } else {
            self.batch_size.min(n)
        } as f64;
        let codes = code_count(self.components, self.depth) as f64;
        let pre_codes = code_count(self.components, self.preselect_depth.min(self.depth)) as f64;
        let pool = if self.pool > 1 {
            self.pool as f64 * self.preselect_iterations as f64 * batch * pre_codes
        } else {
            0.0
        };
        let main = self.iterations as f64 * batch * codes;
        let eval = if self.eval_points == 0 {
            n
        } else {
            self.eval_points.min(n)
        } as f64;
        let searches = if self.reorient.enabled() && self.reorient.every > 0 {
            (self.iterations / self.reorient.every) as f64
        } else {
            0.0
        };
        let reorient =
            searches * self.components as f64 * self.reorient.rotations as f64 * eval * codes;
        pool + main + reorient
    }

    /// Refuses `fits` fits to `n` points whose [`work`](Self::work) would take longer than
    /// the work budget ([`ifslab::budget::check_work`]) on this process's threads.
    pub fn check_work(&self, n: usize, fits: usize) -> Result<()> {
        let work = self.work(n) * fits.max(1) as f64;
        Ok(ifslab::budget::check_rate(
            work,
            EVALS_PER_SECOND_PER_THREAD,
            rayon::current_num_threads(),
            "evaluations",
            &format!(
                "{work:.1e} point × code evaluations ({fits} fit(s) of {} iterations, K = {}, \
                 depth {})",
                self.iterations, self.components, self.depth
            ),
            "the iterations, the depth, the pool or the points",
        )?)
    }

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
