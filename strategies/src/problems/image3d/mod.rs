//! Pictures taken around a 3-D fractal → an IFS code of space (issue 39).
//!
//! - [`views`]: the targets — pictures with their cameras, read from a folder holding a
//!   NeRF-style `transforms.json` or a `turntable.json` — and the library's own renders
//!   written as such a folder.
//! - [`hull`]: the visual hull carved from the views' silhouettes and an IFS of similitudes
//!   fitted to its points by EM in 3-D: the start of the fit and the baseline it must beat.
//! - [`problem`]: `Image3dProblem`, θ → SVD maps of space → the multi-view splat → the 2-D
//!   image loss on every view; [`Differentiable`](crate::driver::Differentiable) and
//!   [`Anneal`](crate::optim::annealing::Anneal), so every registered strategy drives it.
//! - [`collage`]: the collage start in space — affine copies of the hull found inside the
//!   hull, the cover whose silhouettes match the views best.
//! - [`config`]: `Image3dConfig` (maps, start, strategy, splat, loss, hull).
//! - [`run`]: the run folder — hull, EM, the strategy under the shared driver — and the
//!   outputs people open: `code.json`, `baseline.json`, `points.ply`, `views.png`,
//!   `turntable.png`, `summary.json` (voxel IoU of baseline and fit against a truth).
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point
//!   Splatting* (3-D named as future work).
//! - A. Laurentini, *The visual hull concept for silhouette-based image understanding*,
//!   IEEE TPAMI 16(2), 1994.

pub mod collage;
pub mod config;
pub mod hull;
pub mod problem;
pub mod run;
pub mod views;

pub use collage::{
    CollageSearch3, ScoredCover3, collage_candidates3, collage_covers3, silhouette_score,
};
pub use config::{Image3dConfig, MapChoice, Render3dConfig, Start3d};
pub use hull::{Hull, HullConfig, encode_start, hull_start, random_start, visual_hull};
pub use problem::{IMAGE3D_TERMS, Image3dLoss, Image3dModel, Image3dProblem};
pub use run::{
    HeldOut3d, Image3dOutcome, Summary3d, attractor, render_code, run_image3d, run_image3d_in,
    score_views, write_outputs, write_ply,
};
pub use views::{TurntableFile, Views, load_views, render_views, write_views};
