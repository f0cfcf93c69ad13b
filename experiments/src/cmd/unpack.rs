//! `ifslab unpack DIR`: the run folders of a pack written back, and with `--pictures` their
//! pictures drawn again from each run's config and code.

use std::path::PathBuf;

use ifslab_experiments::runs::redraw_pictures;
use ifslab_experiments::sweep::pack::{runs_of, unpack};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A sweep's output folder (its `runs.jsonl.gz` unpacks into `runs/`), a folder of runs
    /// `X` or its pack `X.jsonl.gz`. Folders there already are left alone.
    pub dir: PathBuf,
    /// Only this run (its folder name: a sweep run's id; repeatable).
    #[arg(long, value_name = "NAME")]
    pub run: Vec<String>,
    /// Draw the pictures (renders, target, truth, zoom strip, loss plot) of every run asked
    /// for that has no `render.png` yet: evaluation renders, seconds a run. A suite run needs
    /// its suite where its config names it (`make_suite.sh`).
    #[arg(long)]
    pub pictures: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let runs = runs_of(&a.dir);
    let u = unpack(&runs, &a.run)?;
    println!(
        "{}: {} run folders ({} written now)",
        runs.display(),
        u.folders.len(),
        u.written
    );
    if a.pictures {
        let todo: Vec<&PathBuf> = u
            .folders
            .iter()
            .filter(|d| !d.join("render.png").exists())
            .collect();
        for (k, d) in todo.iter().enumerate() {
            let files = redraw_pictures(d)?;
            println!(
                "  [{}/{}] {}: {} pictures",
                k + 1,
                todo.len(),
                d.display(),
                files.len()
            );
        }
    }
    Ok(())
}
