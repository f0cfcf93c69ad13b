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
//! - [`image3d`]: pictures taken around a 3-D fractal → an IFS code of space (code, point
//!   cloud, turntable, scores against a truth);
//! - [`texture`]: fractal-coding texture upsampling, and the paper's tables and figures
//!   ([`texture::repro`]);
//! - [`lock`]: one process per run folder; [`table`]: configs as TOML tables;
//! - [`redraw_pictures`]: a finished run's pictures drawn again (packed runs keep none).

pub mod config;
pub mod flame;
pub mod image3d;
pub mod inversion;
pub mod landscape;
pub mod legs;
pub mod lock;
pub mod points;
pub mod sdf;
pub mod table;
pub mod texture;

pub use config::{RunConfig, RunReport};

use std::path::{Path, PathBuf};

use crate::error::bail;

/// Draws the pictures of a finished run folder again from its `config.toml`, results and
/// log (a folder written back from a pack: [`crate::sweep::pack`]); returns the files
/// written. Image inversions get every picture ([`inversion::redraw_pictures`]); a learned
/// flame its `loss.png` (its renders need the learned stack, which only its run has); a run
/// of another problem is quick to run again, which is what the error says.
pub fn redraw_pictures(dir: &Path) -> crate::Result<Vec<PathBuf>> {
    match RunConfig::load_resolved(&dir.join(inversion::CONFIG_FILE))? {
        RunConfig::Image(cfg) => inversion::redraw_pictures(&cfg, dir),
        RunConfig::Flame(_) => {
            let log = dir.join(inversion::LOG_FILE);
            if !log.is_file() {
                bail!("{}: no log.csv to draw loss.png from", dir.display());
            }
            inversion::loss_plot(&log, &dir.join("loss.png"))?;
            Ok(vec![dir.join("loss.png")])
        }
        other => bail!(
            "{}: the pictures of a {} run are drawn by running it again \
             (`ifslab run {}/config.toml -o NEW_FOLDER`, or the sweep into a new folder)",
            dir.display(),
            other.problem(),
            dir.display()
        ),
    }
}
pub use lock::{LOCK_FILE, RunLock, lock_run_dir};
