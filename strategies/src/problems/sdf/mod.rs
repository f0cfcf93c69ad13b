//! Image → segment pattern: fit the control points of a symmetry pattern so that its SDF
//! render matches a target image (Scott's differentiable IFS), with any registered strategy
//! (Adam by default) under the shared driver — checkpoints, CSV log, `--resume`.
//!
//! - [`target`]: the target's distance transform and the best-fit line of its dark pixels;
//! - [`init`]: where the control points start (the paper's best-fit line);
//! - [`problem`]: θ → maps → SDF raster → multi-scale MSE on pixels and distances, with its
//!   gradient;
//! - [`crossing`]: the penalty on copies of the base figure crossing each other (the
//!   barrier the paper proposes against the local optima of its Fig. 4 and 7);
//! - [`barrier`]: the barrier on the maps' scales (keeps a fit an IFS; lets learned soft
//!   maps that expand through);
//! - [`mod@landscape`]: the loss on a 2-D slice of control-point space (`ifslab landscape`);
//! - [`config`]: the validated TOML configuration (`problem = "sdf"`);
//! - [`run`]: start, solver, executor, resume.
//!
//! ## References
//! - Scott, *Differentiable Iterated Function Systems*, Differentiable Almost Everything
//!   workshop, ICML 2024.

pub mod barrier;
pub mod config;
pub mod crossing;
pub mod init;
pub mod landscape;
pub mod learned;
pub mod problem;
pub mod run;
pub mod target;

pub use barrier::scale_barrier;
pub use config::{
    DEFAULT_RESCUE_BELOW, DEFAULT_SIGMA_FACTORS, RESCUE_DISTANCE, RESCUE_SIGMA_START, SdfConfig,
    SdfInitConfig,
};
pub use crossing::{MAX_CROSSING_DEPTH, crossing_depth2, crossing_penalty};
pub use init::{PROBE_STEPS, SdfInit, candidate_starts, initial_points};
pub use landscape::sdf_landscape;
pub use learned::{LearnedConfig, LearnedPattern};
pub use problem::{
    CUTOFF_SIGMAS, SDF_TERMS, SdfEval, SdfLoss, SdfLossConfig, SdfModel, SdfProblem, SdfScene,
};
pub use run::{
    SdfOutcome, at_sigma, best_start, rescue_legs, run_sdf, sdf_problem, stroke_sigma_legs,
};
pub use target::{
    INK, STROKE_SIGMA_RANGE, best_fit_line, distance_transform, sigma_for_stroke, stretch_ink,
};
