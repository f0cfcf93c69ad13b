//! `ifslab pack DIR`: a sweep folder's finished runs (or any folder of run folders) in one
//! compressed file beside them, the form committed results are kept in.

use std::path::PathBuf;

use ifslab_experiments::sweep::pack::{DEFAULT_LOG_COLUMNS, pack, runs_of};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A sweep's output folder (its `runs/` are packed into `runs.jsonl.gz`), or a folder
    /// of run folders `X` (packed into `X.jsonl.gz`). Runs already packed there stay; a
    /// folder replaces its packed copy.
    pub dir: PathBuf,
    /// Columns of each run's `log.csv` to keep besides the first (the iteration), rounded to
    /// five significant digits (repeatable). [default: loss, anneal_accepted]
    #[arg(long, value_name = "NAME")]
    pub log_column: Vec<String>,
    /// Delete the packed run folders once the pack has been read back and holds each of
    /// them (text files verbatim; pictures are drawn again by `ifslab unpack --pictures`).
    #[arg(long)]
    pub remove: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let runs = runs_of(&a.dir);
    let keep: Vec<String> = if a.log_column.is_empty() {
        DEFAULT_LOG_COLUMNS.iter().map(|s| s.to_string()).collect()
    } else {
        a.log_column
    };
    let p = pack(&runs, &keep, a.remove)?;
    println!(
        "{}: {} runs ({} packed now, {} folders removed), {:.2} MB",
        p.path.display(),
        p.runs,
        p.added,
        p.removed,
        p.bytes as f64 / 1e6
    );
    for d in &p.skipped {
        println!("  left alone {}: not a finished run", d.display());
    }
    Ok(())
}
