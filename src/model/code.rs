//! IFS code files: a JSON document holding the maps, their probabilities and an optional
//! name and framing, validated when loaded.
//!
//! ```json
//! {
//!   "format": "ifslab-code/1",
//!   "name": "sierpinski",
//!   "dim": 2,
//!   "maps": [ { "matrix": [[0.5, 0.0], [0.0, 0.5]], "offset": [0.0, 0.0] }, ... ],
//!   "probabilities": [0.3333333333333333, ...],
//!   "framing": { "min": [-0.1, -0.1], "max": [1.1, 1.1] },
//!   "allow_non_contractive": false,
//!   "meta": { "strategy": "..." }
//! }
//! ```
//!
//! `probabilities` may be left out (evaluation then uses ∝|det| with a floor), `framing`
//! may be left out (renderers fit the attractor), and `meta` holds free-form data a
//! strategy wants to keep with its result (EM's depth weights, a run's loss).

use std::path::Path;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::model::affine::{Affine2, AffineN};
use crate::model::probs::{ProbabilityRule, validate_probabilities};

/// The error for JSON `text` (from `origin`, a `what` such as "code file") that serde
/// refused: JSON has no NaN or infinity, but Python's json module writes bare `NaN` and
/// `Infinity` tokens and overflowing literals parse as infinite, so those are named with
/// their line and column; anything else is a parse error.
pub(crate) fn json_error(e: serde_json::Error, text: &str, origin: &Path, what: &str) -> Error {
    if let Some((line, col, token)) = find_non_finite_token(text) {
        return Error::NonFinite {
            what: format!("{what} {}", origin.display()),
            location: format!("line {line}, column {col} (`{token}`)"),
            value: if token.contains("NaN") {
                f64::NAN
            } else {
                f64::INFINITY
            },
        };
    }
    Error::Parse {
        path: origin.to_owned(),
        message: e.to_string(),
    }
}

/// The first bare `NaN`/`Infinity` token or out-of-range number outside strings, as
/// `(line, column, token)`, both 1-based.
fn find_non_finite_token(text: &str) -> Option<(usize, usize, String)> {
    let mut in_string = false;
    let mut escaped = false;
    let bytes = text.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if in_string {
            match (escaped, c) {
                (true, _) => escaped = false,
                (false, b'\\') => escaped = true,
                (false, b'"') => in_string = false,
                _ => {}
            }
            i += 1;
            continue;
        }
        if c == b'"' {
            in_string = true;
            i += 1;
            continue;
        }
        if c == b'-' || c == b'+' || c.is_ascii_alphanumeric() || c == b'.' {
            let start = i;
            while i < bytes.len()
                && (bytes[i].is_ascii_alphanumeric() || matches!(bytes[i], b'-' | b'+' | b'.'))
            {
                i += 1;
            }
            let token = &text[start..i];
            let bare = token.trim_start_matches(['-', '+']);
            let overflow = token.parse::<f64>().is_ok_and(|v| v.is_infinite())
                && !bare.eq_ignore_ascii_case("inf")
                && !bare.eq_ignore_ascii_case("infinity");
            if bare == "NaN" || bare == "Infinity" || bare == "inf" || overflow {
                let line = text[..start].matches('\n').count() + 1;
                let col = start - text[..start].rfind('\n').map_or(0, |p| p + 1) + 1;
                return Some((line, col, token.to_owned()));
            }
            continue;
        }
        i += 1;
    }
    None
}

/// The format tag written into every code file.
pub const FORMAT_TAG: &str = "ifslab-code/1";

/// An axis-aligned window of the plane: what part of it an image shows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Window {
    /// Lower-left corner (smallest x and y).
    pub min: [f64; 2],
    /// Upper-right corner (largest x and y).
    pub max: [f64; 2],
}

/// [`Window`]'s former name (a code file's `framing` is a window).
#[deprecated(note = "renamed `Window`")]
pub type Framing = Window;

impl Window {
    /// Width and height.
    pub fn size(&self) -> [f64; 2] {
        [self.max[0] - self.min[0], self.max[1] - self.min[1]]
    }

    /// Centre point.
    pub fn center(&self) -> [f64; 2] {
        [
            0.5 * (self.min[0] + self.max[0]),
            0.5 * (self.min[1] + self.max[1]),
        ]
    }

    /// Checks the window is finite and has positive size.
    pub fn validate(&self) -> Result<()> {
        let v = [self.min[0], self.min[1], self.max[0], self.max[1]];
        if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
            return Err(Error::NonFinite {
                what: "framing".into(),
                location: "min/max".into(),
                value: *bad,
            });
        }
        let s = self.size();
        if !(s[0] > 0.0 && s[1] > 0.0) {
            return Err(Error::Shape(format!(
                "framing must have max > min on both axes, got min {:?} max {:?}",
                self.min, self.max
            )));
        }
        Ok(())
    }
}

/// One map as written in a file: row-major matrix and offset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapRecord {
    /// H rows of H numbers.
    pub matrix: Vec<Vec<f64>>,
    /// H numbers.
    pub offset: Vec<f64>,
}

/// The raw file document, before validation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CodeFile {
    /// Always [`FORMAT_TAG`].
    pub format: String,
    /// Optional human-readable name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Dimension H of the space.
    pub dim: usize,
    /// The maps.
    pub maps: Vec<MapRecord>,
    /// One probability per map, summing to 1; absent means ∝|det| at evaluation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probabilities: Option<Vec<f64>>,
    /// Optional window for 2-D renders.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub framing: Option<Window>,
    /// Skip the contractivity check (flame-like codes whose attractor exists anyway).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub allow_non_contractive: bool,
    /// Free-form data a strategy keeps with its result.
    #[serde(default, skip_serializing_if = "serde_json::Map::is_empty")]
    pub meta: serde_json::Map<String, serde_json::Value>,
}

/// A validated IFS code in any dimension.
#[derive(Clone, Debug, PartialEq)]
pub struct IfsCode {
    /// Optional human-readable name.
    pub name: Option<String>,
    /// The maps, all of the same dimension.
    pub maps: Vec<AffineN>,
    /// Explicit probabilities, if the code fixes them.
    pub probabilities: Option<Vec<f64>>,
    /// Window for 2-D renders, if the code fixes one.
    pub framing: Option<Window>,
    /// Whether non-contractive maps are allowed.
    pub allow_non_contractive: bool,
    /// Free-form strategy data.
    pub meta: serde_json::Map<String, serde_json::Value>,
}

impl IfsCode {
    /// A 2-D code from affine maps, validated (contractive, finite).
    pub fn from_affine2(name: Option<&str>, maps: &[Affine2]) -> Result<Self> {
        IfsCode::from_affine_n(name, maps.iter().map(Affine2::to_affine_n).collect())
    }

    /// A code of any dimension from its maps, validated (contractive, finite).
    pub fn from_affine_n(name: Option<&str>, maps: Vec<AffineN>) -> Result<Self> {
        let code = IfsCode {
            name: name.map(str::to_owned),
            maps,
            probabilities: None,
            framing: None,
            allow_non_contractive: false,
            meta: Default::default(),
        };
        code.validate()?;
        Ok(code)
    }

    /// With explicit probabilities (validated).
    pub fn with_probabilities(mut self, p: Vec<f64>) -> Result<Self> {
        validate_probabilities(&p, self.maps.len())?;
        self.probabilities = Some(p);
        Ok(self)
    }

    /// Dimension H of the code's space.
    pub fn dim(&self) -> usize {
        self.maps.first().map_or(0, AffineN::dim)
    }

    /// The maps as 2-D affine maps; an error if the code is not 2-D.
    pub fn affine2(&self) -> Result<Vec<Affine2>> {
        self.maps.iter().map(AffineN::to_affine2).collect()
    }

    /// The probabilities for evaluation renders: the code's own, or ∝|det| with the default floor.
    pub fn evaluation_probabilities(&self) -> Result<Vec<f64>> {
        match &self.probabilities {
            Some(p) => Ok(p.clone()),
            None => ProbabilityRule::default()
                .resolve(&self.maps.iter().map(AffineN::abs_det).collect::<Vec<_>>()),
        }
    }

    /// Checks everything a loaded code promises: at least one map, consistent shapes,
    /// finite numbers, probabilities that sum to one, and contractive maps (unless allowed).
    pub fn validate(&self) -> Result<()> {
        if self.maps.is_empty() {
            return Err(Error::Empty("the code has no maps".into()));
        }
        let h = self.dim();
        if h == 0 {
            return Err(Error::Shape("dimension must be at least 1".into()));
        }
        for (i, map) in self.maps.iter().enumerate() {
            if map.dim() != h || map.m.nrows() != h || map.m.ncols() != h {
                return Err(Error::Shape(format!(
                    "map {i} is {}-dimensional but the code is {h}-dimensional",
                    map.dim()
                )));
            }
            for r in 0..h {
                for c in 0..h {
                    let v = map.m[(r, c)];
                    if !v.is_finite() {
                        return Err(Error::NonFinite {
                            what: "code".into(),
                            location: format!("map {i}, matrix[{r}][{c}]"),
                            value: v,
                        });
                    }
                }
                let v = map.b[r];
                if !v.is_finite() {
                    return Err(Error::NonFinite {
                        what: "code".into(),
                        location: format!("map {i}, offset[{r}]"),
                        value: v,
                    });
                }
            }
        }
        if let Some(p) = &self.probabilities {
            validate_probabilities(p, self.maps.len())?;
        }
        if let Some(f) = &self.framing {
            if h != 2 {
                return Err(Error::Shape(format!(
                    "framing is only meaningful for 2-D codes, this one is {h}-D"
                )));
            }
            f.validate()?;
        }
        if !self.allow_non_contractive {
            for (i, map) in self.maps.iter().enumerate() {
                let s = map.sigma_max();
                if s.is_nan() || s >= 1.0 {
                    return Err(Error::NonContractive {
                        index: i,
                        sigma_max: s,
                    });
                }
            }
        }
        Ok(())
    }

    /// Builds and validates a code from a parsed file document.
    pub fn from_file_doc(doc: CodeFile) -> Result<Self> {
        if doc.format != FORMAT_TAG {
            return Err(Error::Shape(format!(
                "format tag is `{}`, expected `{FORMAT_TAG}`",
                doc.format
            )));
        }
        let h = doc.dim;
        if h == 0 {
            return Err(Error::Shape("`dim` must be at least 1".into()));
        }
        let mut maps = Vec::with_capacity(doc.maps.len());
        for (i, rec) in doc.maps.iter().enumerate() {
            if rec.matrix.len() != h || rec.matrix.iter().any(|row| row.len() != h) {
                return Err(Error::Shape(format!(
                    "map {i}: `matrix` must have {h} rows of {h} numbers (dim = {h})"
                )));
            }
            if rec.offset.len() != h {
                return Err(Error::Shape(format!(
                    "map {i}: `offset` has {} numbers, expected {h}",
                    rec.offset.len()
                )));
            }
            let m = DMatrix::from_fn(h, h, |r, c| rec.matrix[r][c]);
            maps.push(AffineN {
                m,
                b: DVector::from_column_slice(&rec.offset),
            });
        }
        let code = IfsCode {
            name: doc.name,
            maps,
            probabilities: doc.probabilities,
            framing: doc.framing,
            allow_non_contractive: doc.allow_non_contractive,
            meta: doc.meta,
        };
        code.validate()?;
        Ok(code)
    }

    /// The file document for this code.
    pub fn to_file_doc(&self) -> CodeFile {
        let h = self.dim();
        CodeFile {
            format: FORMAT_TAG.to_owned(),
            name: self.name.clone(),
            dim: h,
            maps: self
                .maps
                .iter()
                .map(|m| MapRecord {
                    matrix: (0..h)
                        .map(|r| (0..h).map(|c| m.m[(r, c)]).collect())
                        .collect(),
                    offset: m.b.iter().copied().collect(),
                })
                .collect(),
            probabilities: self.probabilities.clone(),
            framing: self.framing,
            allow_non_contractive: self.allow_non_contractive,
            meta: self.meta.clone(),
        }
    }

    /// Parses and validates a code from JSON text; `origin` names the source in errors.
    pub fn from_json(text: &str, origin: &Path) -> Result<Self> {
        let doc: CodeFile =
            serde_json::from_str(text).map_err(|e| json_error(e, text, origin, "code file"))?;
        IfsCode::from_file_doc(doc)
    }

    /// Pretty JSON text of the code (floats written so they read back bit-exactly).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(&self.to_file_doc()).expect("a code always serialises")
    }

    /// Loads and validates a code file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        IfsCode::from_json(&text, path)
    }

    /// Writes the code atomically (temporary file in the same folder, then rename).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        crate::io::write_atomic(path.as_ref(), self.to_json().as_bytes())
    }
}
