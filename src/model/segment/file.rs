//! The JSON pattern file, `ifslab-pattern/1`:
//!
//! ```json
//! {
//!   "format": "ifslab-pattern/1",
//!   "name": "koch",
//!   "points": [[0, 0], [0.3333, 0], [0.5, 0.2887], [0.6667, 0], [1, 0]],
//!   "pairs": [{"source": [0, 4], "target": [0, 1]}, …],
//!   "base": {"kind": "segment", "points": [0, 4]},
//!   "meta": {"depth": 5, …}
//! }
//! ```
//!
//! `name`, `base` (default: a segment on the first pair's source) and `meta` are optional.
//! `meta` is free-form and kept as it is: a fit writes its view, depth and σ there, so
//! `ifslab sdf render` draws a fitted result the way the fit saw it. Loading validates the
//! pattern ([`Pattern::new`]): indices in range, no zero-length segment, contractive maps,
//! finite coordinates (bare `NaN`/`Infinity` tokens are named with their line and column).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::model::code::json_error;
use crate::model::segment::pattern::{BaseFigure, Pair, Pattern};

/// The format tag written into every pattern file.
pub const PATTERN_FORMAT: &str = "ifslab-pattern/1";

/// A pattern file as written on disk.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatternFile {
    /// Always [`PATTERN_FORMAT`].
    pub format: String,
    /// A name for people and file names.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Control points `[x, y]`.
    pub points: Vec<[f64; 2]>,
    /// Symmetry pairs.
    pub pairs: Vec<Pair>,
    /// The base figure.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<BaseFigure>,
    /// Anything else (a fit's view, depth, σ, loss): kept, not interpreted here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub meta: Option<serde_json::Value>,
}

impl PatternFile {
    /// The file form of `pattern` with optional `meta`.
    pub fn of(pattern: &Pattern, meta: Option<serde_json::Value>) -> Self {
        PatternFile {
            format: PATTERN_FORMAT.into(),
            name: Some(pattern.name().to_owned()),
            points: pattern.points().to_vec(),
            pairs: pattern.pairs().to_vec(),
            base: Some(pattern.base()),
            meta,
        }
    }

    /// Parses JSON text; `origin` names the source in errors. The pattern is not yet
    /// validated (see [`PatternFile::pattern`]).
    pub fn from_json(text: &str, origin: &Path) -> Result<Self> {
        let doc: PatternFile =
            serde_json::from_str(text).map_err(|e| json_error(e, text, origin, "pattern file"))?;
        if doc.format != PATTERN_FORMAT {
            return Err(Error::Parse {
                path: origin.to_owned(),
                message: format!(
                    "format tag is `{}`, expected `{PATTERN_FORMAT}`",
                    doc.format
                ),
            });
        }
        Ok(doc)
    }

    /// The validated pattern; `origin` names the file in errors and gives the default name.
    pub fn pattern(&self, origin: &Path) -> Result<Pattern> {
        let name = self.name.clone().unwrap_or_else(|| {
            origin
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "pattern".into())
        });
        Pattern::new(name, self.points.clone(), self.pairs.clone(), self.base).map_err(
            |e| match e {
                Error::Pattern(m) => Error::Pattern(format!("{}: {m}", origin.display())),
                other => other,
            },
        )
    }

    /// Reads a pattern file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        PatternFile::from_json(&text, path)
    }

    /// Pretty JSON (floats written so they read back bit-exactly).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a pattern file always serialises")
    }

    /// Writes the file atomically.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        crate::io::write_atomic(path.as_ref(), self.to_json().as_bytes())
    }
}

impl Pattern {
    /// Loads and validates a pattern file (its `meta` is dropped; see [`PatternFile`]).
    pub fn load(path: impl AsRef<Path>) -> Result<Pattern> {
        let path = path.as_ref();
        PatternFile::load(path)?.pattern(path)
    }

    /// Writes the pattern as a file without `meta`.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        PatternFile::of(self, None).save(path)
    }
}
