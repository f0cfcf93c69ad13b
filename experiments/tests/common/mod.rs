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

/// Sends `signal` (`-TERM`, `-INT`) to `child` and waits for it: whether it succeeded, and
/// its stderr (the child's stderr must be piped).
pub fn signal_and_wait(child: std::process::Child, signal: &str) -> (bool, String) {
    let pid = child.id().to_string();
    assert!(
        Command::new("kill")
            .args([signal, pid.as_str()])
            .status()
            .unwrap()
            .success()
    );
    let out = child.wait_with_output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}
