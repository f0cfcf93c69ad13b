//! The check every fuzz target runs: the bytes parsed as one input format by the parser the
//! commands use ([`ifslab_experiments::inputs::parse`]); a value or a refusal is fine, a
//! refusal without text or a panic (libFuzzer reports it as a crash) is not.

use std::path::PathBuf;
use std::sync::OnceLock;

/// The file an input is read as: a private folder per process (configs resolve relative
/// names beside it; images are decoded from it).
fn path(format: &str) -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("ifslab-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("a scratch folder for the fuzz inputs");
        d
    });
    let ext = match format {
        "code" | "pattern" => "json",
        "config" | "sweep" => "toml",
        "image" => "png",
        other => other,
    };
    dir.join(format!("input.{ext}"))
}

/// Parses `data` as `format`; panics (a crash to libFuzzer) if a refusal says nothing.
pub fn check(format: &str, data: &[u8]) {
    if let Err(msg) = ifslab_experiments::inputs::parse(format, data, &path(format)) {
        assert!(!msg.trim().is_empty(), "a refusal without text");
    }
}
