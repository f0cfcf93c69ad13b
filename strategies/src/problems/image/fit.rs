//! A run's θ with the model that decodes it (`fit.json`): what any family's result is
//! redrawn, packed and unpacked from. Affine results (the `affine` and `similitude`
//! families, a plugin's affine maps) also write the classic code file (`code.json`, an
//! [`IfsCode`](ifslab::model::IfsCode)) that the other programs of the field read; a family
//! that is not affine writes only its fit file.

use std::path::Path;

use ifslab::model::Window;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::image::model::ModelConfig;
use crate::problems::image::result::Recovered;

/// The fit file of a run folder: θ and the model that decodes it ([`FitFile`]).
pub const FIT_FILE: &str = "fit.json";

/// A run's θ with the model that decodes it (`fit.json`): what any family's result is
/// redrawn from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitFile {
    /// The model section of the run's config (its `family` names the map type).
    pub model: ModelConfig,
    /// The fitted parameters.
    pub theta: Vec<f64>,
    /// The window the evaluation render fitted around the attractor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub framing: Option<Window>,
    /// What found it: strategy, iterations, final loss, seed.
    #[serde(default)]
    pub meta: serde_json::Map<String, serde_json::Value>,
}

impl FitFile {
    /// Writes the file atomically (a temporary file renamed into place).
    pub fn save(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| Error::file(path, format!("could not write the fit: {e}")))?;
        ifslab::io::write_atomic(path, text.as_bytes())?;
        Ok(())
    }

    /// Reads a fit file; an error names the file and what is wrong in it.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::file(path, format!("could not read the fit: {e}")))?;
        serde_json::from_str(&text).map_err(|e| Error::file(path, format!("not a fit file: {e}")))
    }

    /// The recovered maps: θ decoded by the model family the file names (built in or
    /// registered in this process).
    pub fn recovered(&self) -> Result<Box<dyn Recovered>> {
        self.model.build()?.recovered(&self.theta)
    }

    /// The seed of the run that found it, where the file says.
    pub fn seed(&self) -> Option<u64> {
        self.meta.get("seed").and_then(|v| v.as_u64())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::image::FlameModel;
    use crate::problems::image::model::ImageModel;
    use ifslab::model::library;

    #[test]
    fn a_fit_file_round_trips_and_names_what_it_cannot_decode() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join(FIT_FILE);
        let start = library::builtin("sierpinski").unwrap().affine2().unwrap();
        let mut file = FitFile {
            model: ModelConfig {
                family: "flame".into(),
                ..ModelConfig::default()
            },
            theta: ImageModel::encode(&FlameModel, &start).unwrap(),
            framing: None,
            meta: Default::default(),
        };
        file.meta.insert("seed".into(), 7.into());
        file.save(&path).unwrap();
        let back = FitFile::load(&path).unwrap();
        assert_eq!(back, file);
        assert_eq!(back.seed(), Some(7));
        assert_eq!(back.recovered().unwrap().n_maps(), 3);
        file.model.family = "nope".into();
        file.save(&path).unwrap();
        let e = FitFile::load(&path).unwrap().recovered().err().unwrap();
        assert!(e.to_string().contains("unknown model family `nope`"), "{e}");
        std::fs::write(&path, "{\"theta\": 3}").unwrap();
        let e = FitFile::load(&path).unwrap_err().to_string();
        assert!(
            e.contains("fit.json") && e.contains("not a fit file"),
            "{e}"
        );
    }
}
