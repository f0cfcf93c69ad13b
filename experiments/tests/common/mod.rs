//! What the command-line tests share: running the built `ifslab` binary.

#![allow(dead_code)]

use std::path::Path;
use std::process::Command;

/// Runs the binary with `args` in `dir` with extra environment variables; whether it
/// succeeded, and its stdout then stderr.
pub fn ifslab_with(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_ifslab"))
        .current_dir(dir)
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .envs(env.iter().copied())
        .output()
        .expect("the binary runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// Runs the binary with `args` in `dir`.
pub fn ifslab_in(dir: &Path, args: &[&str]) -> (bool, String) {
    ifslab_with(dir, args, &[])
}

/// Runs the binary with `args` in the working directory.
pub fn ifslab(args: &[&str]) -> (bool, String) {
    ifslab_in(Path::new("."), args)
}
