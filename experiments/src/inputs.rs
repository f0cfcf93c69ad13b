//! Every input format ifslab reads, parsed from bytes by one call: the entry point of the
//! fuzz targets (`fuzz/`) and of the regression corpus (`experiments/tests/corpus/`), so
//! that both exercise exactly the parsers the commands use.

use std::path::Path;

use ifslab::model::IfsCode;
use ifslab::model::flame::format::parse_flames;
use ifslab::model::segment::PatternFile;
use ifslab_strategies::problems::em::data::{parse_npy, parse_text};

use crate::runs::RunConfig;
use crate::sweep::SweepConfig;

/// The formats, by the name the fuzz targets and the corpus folders use.
pub const FORMATS: [&str; 8] = [
    "code", "flame", "pattern", "config", "sweep", "csv", "npy", "image",
];

/// Parses `bytes` as `format` (one of [`FORMATS`]), read as if from `path` (relative
/// names in configs resolve beside it; an image is decoded from a file, so it is written
/// there first). `Ok` when accepted, else the refusal's whole text.
///
/// # Panics
/// On a format not in [`FORMATS`]: that is a mistake of the caller, not of the input.
pub fn parse(format: &str, bytes: &[u8], path: &Path) -> Result<(), String> {
    let text = || String::from_utf8_lossy(bytes).into_owned();
    match format {
        "code" => IfsCode::from_json(&text(), path)
            .map(drop)
            .map_err(|e| e.to_string()),
        "flame" => parse_flames(&text(), path)
            .map(drop)
            .map_err(|e| e.to_string()),
        "pattern" => PatternFile::from_json(&text(), path)
            .and_then(|f| f.pattern(path))
            .map(drop)
            .map_err(|e| e.to_string()),
        "config" => RunConfig::from_toml(&text(), path)
            .map(drop)
            .map_err(|e| format!("{e:#}")),
        "sweep" => SweepConfig::from_toml(&text(), path)
            .map(drop)
            .map_err(|e| format!("{e:#}")),
        "csv" => parse_text(&text(), path)
            .map(drop)
            .map_err(|e| e.to_string()),
        "npy" => parse_npy(bytes, path).map(drop).map_err(|e| e.to_string()),
        "image" => {
            std::fs::write(path, bytes).map_err(|e| format!("{}: {e}", path.display()))?;
            let grey = ifslab::image::Image::load(path, false).map(drop);
            let rgba = ifslab::image::Image::load_rgba(path).map(drop);
            grey.and(rgba).map_err(|e| e.to_string())
        }
        other => panic!(
            "no input format `{other}` (formats: {})",
            FORMATS.join(", ")
        ),
    }
}
