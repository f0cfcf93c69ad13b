//! Image → IFS code: fit the maps of an IFS so that the fused splat op's render matches a
//! target image, with any of the gradient or annealing strategies.
//!
//! - [`target`]: load and frame targets the way the model frames its points;
//! - [`init`]: the starting code (random, given, fitted by EM to the target's points, or
//!   the [`collage`] start: copies of the target found inside it);
//! - [`collage`]: the collage search (candidate maps that carry the ink onto itself, greedy
//!   covers, scored by their attractors);
//! - [`model`]: θ ↔ maps of one type (affine under a parameterisation, similitudes, …): the
//!   open set of map types an inversion can fit (`[model] family`);
//! - [`problem`]: θ → maps → splat → composite loss and its gradient, each evaluation a pass
//!   of the one image problem's instance for the model's map type ([`instance`]);
//! - [`result`]: what a finished run recovered, drawn by its model (any family); [`fit`]:
//!   the file that keeps it (θ and the model);
//! - [`config`]: the validated TOML configuration of a run;
//! - [`run`]: initial code, solver, executor, checkpoint and resume;
//! - [`mod@landscape`]: the objective on a 2-D slice of parameter space (loss landscapes).
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point Splatting*.

pub mod collage;
pub mod config;
pub mod fit;
pub mod init;
pub mod instance;
pub mod landscape;
pub mod model;
pub mod polish;
pub mod problem;
pub mod result;
pub mod run;
pub mod target;

pub use config::{BestOfStarts, InitKind, InversionConfig, StrategyConfig, TargetConfig};
pub use fit::{FIT_FILE, FitFile};
pub use init::{initial_theta, ranked_starts};
pub use instance::{ImageRendering, SplatProblem, splat_problem};
pub use landscape::{Directions, Landscape, LandscapeConfig, landscape, slice};
pub use model::{
    AffineModel, AnyModel, FlameModel, ImageModel, MODELS, ModelEntry, SimilitudeModel, find_model,
    models, register_model,
};
pub use problem::ImageProblem;
pub use result::{Fitted, Recovered};
pub use run::{InversionOutcome, SELECTION_STREAMS, Selection, ensure_new_run_dir, run_inversion};
pub use target::{
    Cells, FRAMED_TARGET_FILE, FramedTarget, Polarity, TARGET_READING_FILE, TargetReading,
    frame_picture, frame_picture_with, frame_target, load_framed_picture, load_framed_picture_with,
    load_framed_target, load_target, save_framed_target, stroke_width,
};
