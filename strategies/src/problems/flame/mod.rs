//! Image → colour fractal flame (Bannister & Nowrouzezahrai, *Learnable Fractal Flames*):
//! learn the generators, final transform, quality blend κ, colours and background of one or
//! more flame layers so that the differentiable flame pipeline
//! ([`ifslab::render::flame_diff`]) reproduces a colour target, with any registered
//! strategy (plain gradient descent by default, as the paper) under the shared driver —
//! checkpoints, CSV log, `--resume`.
//!
//! - [`config`]: the validated TOML configuration (`problem = "flame"`);
//! - [`problem`]: θ → stack → image → the authors' MSE, with its gradient, and the
//!   per-group learning rates of the authors' code;
//! - [`run`]: start, solver, executor, resume.
//!
//! ## References
//! - J. J. Bannister, D. Nowrouzezahrai, *Learnable Fractal Flames*.

pub mod config;
pub mod problem;
pub mod run;

pub use config::{
    BackgroundConfig, DEFAULT_ADAM_LR, FlameLearnConfig, FlameLoss, LayerSpec, Rates,
    default_xforms,
};
pub use problem::{FLAME_TERMS, FlameImageLoss, FlameModel, FlameProblem};
pub use run::{
    FlameOutcome, flame_problem, initial_stack, load_rgb_picture, load_rgb_target, run_flame,
};
