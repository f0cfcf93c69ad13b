//! One module per subcommand: its clap `Args` and a `run` function.

pub mod codes;
pub mod collect;
pub mod demo;
pub mod fit_points;
pub mod flame;
pub mod invert;
pub mod landscape;
pub mod render;
pub mod run;
pub mod sample;
pub mod sdf;
pub mod suite;
pub mod sweep;
pub mod texture;
pub mod weights;

pub use ifslab_experiments::codes::resolve_code;
