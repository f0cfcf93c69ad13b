//! Runs as library calls: config → run folder.
//!
//! - [`config`]: [`RunConfig`], any config `ifslab run` accepts (its `problem` key picks the
//!   problem), and [`RunConfig::run`], the one entry every front end calls;
//! - [`inversion`]: image inversion runs;
//! - [`landscape`]: loss landscapes of an image-inversion run folder;
//! - [`points`]: point cloud → IFS of similitudes by EM, single fits and pool sweeps, each
//!   finished fit checkpointed;
//! - [`flame`]: image → colour fractal flame by the differentiable flame pipeline
//!   (learned `.flame` file, renders side by side with the target);
//! - [`sdf`]: image → segment pattern by the differentiable SDF raster (fitted pattern,
//!   render, loss plot, summary);
//! - [`texture`]: fractal-coding texture upsampling, and the paper's tables and figures
//!   ([`texture::repro`]);
//! - [`lock`]: one process per run folder; [`table`]: configs as TOML tables.

pub mod config;
pub mod flame;
pub mod inversion;
pub mod landscape;
pub mod lock;
pub mod points;
pub mod sdf;
pub mod table;
pub mod texture;

pub use config::{RunConfig, RunReport};
pub use lock::{LOCK_FILE, RunLock, lock_run_dir};
