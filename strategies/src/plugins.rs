//! Extending ifslab from another crate: a strategy or a map family defined there joins the
//! registries for the rest of the process, and every run — `ifslab run`'s library call
//! ([`RunConfig::run`](../../ifslab_experiments/runs/enum.RunConfig.html)), sweeps,
//! checkpoints and `--resume` — can name it in a config like the built-in ones.
//!
//! - A **strategy**: its hyper-parameters (a [`Params`](crate::driver::Params) type) and an
//!   argmin `Solver<P, GradState>` for any problem `P` with a loss and a cost; implement
//!   [`StrategyPlugin`] and call [`register_strategy`].
//! - A **map family** for image inversion: an [`ImageModel`](crate::problems::image::ImageModel)
//!   (θ ↔ maps of any [`DiffMap2`](ifslab::model::diff_map::DiffMap2) type) behind a
//!   [`ModelEntry`]; call [`register_model`]. Its runs write their result as the model gives
//!   it ([`Recovered`](crate::problems::image::Recovered)): `fit.json` always, `code.json`
//!   where its maps are affine.
//!
//! `experiments/examples/plugin.rs` adds one of each and runs an inversion with them; the
//! test `experiments/tests/plugin.rs` runs that example.

pub use crate::problems::image::{ModelEntry, register_model};
pub use crate::registry::{StrategyEntry, StrategyPlugin, StrategyProblem, register_for};

use crate::error::Result;
use crate::problems::flame::FlameProblem;
use crate::problems::image::ImageProblem;
use crate::problems::sdf::problem::SdfProblem;
use crate::registry::ParamsOnly;

/// Registers the strategy `T` for every problem this crate runs (image inversion, segment
/// patterns, flames) and for the config checks that name it before a problem exists. A name
/// already registered is refused (call it once per process).
pub fn register_strategy<T: StrategyPlugin>() -> Result<()> {
    register_for::<ParamsOnly>(T::entry::<ParamsOnly>)?;
    register_for::<ImageProblem>(T::entry::<ImageProblem>)?;
    register_for::<SdfProblem>(T::entry::<SdfProblem>)?;
    register_for::<FlameProblem>(T::entry::<FlameProblem>)
}
