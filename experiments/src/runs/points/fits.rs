//! Checkpoints of a points run: every finished EM fit of a run is written to its own file
//! under `fits/` as soon as it ends (atomically), so that a run killed part-way and resumed
//! fits only what is missing and merges exactly what an uninterrupted run would have. One
//! fit takes seconds, so a fit is the unit: nothing is saved inside EM.

use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext};
use ifslab::model::IfsCode;
use ifslab_strategies::problems::em::{EmConfig, EmFit, EmModel, IterationRecord};
use serde::{Deserialize, Serialize};

/// The folder of a run folder that holds finished fits until the run completes.
pub const FITS_DIR: &str = "fits";

/// A finished fit as stored on disk.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct FitRecord {
    /// The fit's config: a checkpoint is used only for the very config that made it.
    em: EmConfig,
    /// Wall-clock seconds the fit took.
    seconds: f64,
    /// The fit, or why it failed.
    outcome: Outcome,
}

#[derive(Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum Outcome {
    Fitted {
        /// The model as a code file's JSON (`meta.em` holds it exactly).
        code: serde_json::Value,
        history: Vec<IterationRecord>,
        chosen: usize,
        converged: bool,
    },
    Failed(String),
}

/// A fit's outcome as a run merges it: the fit, or the error message of a failed one.
pub type Finished = (Result<EmFit, String>, f64);

/// The checkpoint file of fit `label` in run folder `dir`.
pub fn path(dir: &Path, label: &str) -> PathBuf {
    dir.join(FITS_DIR).join(format!("{label}.json"))
}

/// Writes a finished fit atomically.
pub fn save(
    dir: &Path,
    label: &str,
    em: &EmConfig,
    fit: &Result<EmFit, String>,
    seconds: f64,
) -> crate::Result<()> {
    let outcome = match fit {
        Ok(f) => Outcome::Fitted {
            code: serde_json::from_str(&f.model.to_code(None)?.to_json())?,
            history: f.history.clone(),
            chosen: f.chosen,
            converged: f.converged,
        },
        Err(e) => Outcome::Failed(e.clone()),
    };
    let rec = FitRecord {
        em: em.clone(),
        seconds,
        outcome,
    };
    let p = path(dir, label);
    ifslab::io::write_atomic(&p, serde_json::to_string(&rec)?.as_bytes())
        .with_context(|| format!("writing the checkpoint {}", p.display()))?;
    Ok(())
}

/// The finished fit `label` of the run in `dir`, if it was checkpointed with config `em`.
/// A checkpoint that cannot be read back (for instance a non-finite log-likelihood, which
/// JSON cannot hold) is `Ok(None)`: the fit runs again. One made with another config is
/// an error: the folder holds a different run.
pub fn load(dir: &Path, label: &str, em: &EmConfig) -> crate::Result<Option<Finished>> {
    let p = path(dir, label);
    let Ok(text) = std::fs::read_to_string(&p) else {
        return Ok(None);
    };
    let Ok(rec) = serde_json::from_str::<FitRecord>(&text) else {
        return Ok(None);
    };
    crate::error::ensure!(
        rec.em == *em,
        "{} was made with another EM config than this run's; resume the run with the config \
         in its folder (config.toml), or start it in a new folder",
        p.display()
    );
    let fit = match rec.outcome {
        Outcome::Failed(e) => Err(e),
        Outcome::Fitted {
            code,
            history,
            chosen,
            converged,
        } => {
            let code = IfsCode::from_json(&code.to_string(), &p)?;
            let model = EmModel::from_code(&code, em.depth)?;
            Ok(EmFit {
                model,
                history,
                candidates: Vec::new(),
                chosen,
                converged,
            })
        }
    };
    Ok(Some((fit, rec.seconds)))
}

/// Removes the checkpoints of a completed run.
pub fn clear(dir: &Path) -> crate::Result<()> {
    let d = dir.join(FITS_DIR);
    if d.exists() {
        std::fs::remove_dir_all(&d).doing("removing", &d)?;
    }
    Ok(())
}

/// Whether `dir` holds checkpoints of an unfinished run.
pub fn any(dir: &Path) -> bool {
    std::fs::read_dir(dir.join(FITS_DIR)).is_ok_and(|mut d| d.next().is_some())
}
