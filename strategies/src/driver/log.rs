//! A CSV log of every iteration: `iter,loss,<terms…>,seconds`. Rows are appended and
//! flushed as they come; on resume the file is first rewritten (atomically) without the
//! rows past the checkpoint, so an interrupted run leaves no duplicates or half lines.

use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use argmin::core::observers::Observe;
use argmin::core::{Error as ArgminError, KV, State};

use super::GradState;
use crate::error::{Error, Result};

/// Observer writing one CSV row per iteration.
pub struct CsvLog {
    path: PathBuf,
    columns: Vec<String>,
    file: File,
    start: Instant,
    offset_seconds: f64,
}

impl CsvLog {
    /// Opens the log. Without `resume_from` the file is created afresh with a header; with
    /// `resume_from = Some(k)` the rows of iterations ≥ k are dropped and new rows appended.
    pub fn open(
        path: impl Into<PathBuf>,
        columns: &[&str],
        resume_from: Option<u64>,
    ) -> Result<Self> {
        let path = path.into();
        let header = std::iter::once("iter")
            .chain(std::iter::once("loss"))
            .chain(columns.iter().copied())
            .chain(std::iter::once("seconds"))
            .collect::<Vec<_>>()
            .join(",");
        let mut offset_seconds = 0.0;
        match resume_from {
            None => ifslab::io::write_atomic(&path, format!("{header}\n").as_bytes())?,
            Some(k) => {
                let kept = kept_rows(&path, &header, k)?;
                if let Some(last) = kept.last() {
                    offset_seconds = last
                        .rsplit(',')
                        .next()
                        .and_then(|s| s.parse().ok())
                        .unwrap_or(0.0);
                }
                let mut text = format!("{header}\n");
                for row in kept {
                    text.push_str(&row);
                    text.push('\n');
                }
                ifslab::io::write_atomic(&path, text.as_bytes())?;
            }
        }
        let file = OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| Error::file(&path, e))?;
        Ok(CsvLog {
            path,
            columns: columns.iter().map(|s| s.to_string()).collect(),
            file,
            start: Instant::now(),
            offset_seconds,
        })
    }

    /// The log file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// Rows of `path` (header checked) whose iteration is below `k`.
fn kept_rows(path: &Path, header: &str, k: u64) -> Result<Vec<String>> {
    let f =
        File::open(path).map_err(|e| Error::file(path, format!("cannot resume the log: {e}")))?;
    let mut lines = BufReader::new(f).lines();
    match lines.next() {
        Some(Ok(h)) if h == header => {}
        _ => {
            return Err(Error::file(
                path,
                "log header does not match this run's loss terms",
            ));
        }
    }
    let n_fields = header.split(',').count();
    let mut out = Vec::new();
    for line in lines {
        let line = line.map_err(|e| Error::file(path, e))?;
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != n_fields {
            continue; // a half-written last line
        }
        match fields[0].parse::<u64>() {
            Ok(it) if it < k => out.push(line),
            _ => {}
        }
    }
    Ok(out)
}

impl Observe<GradState> for CsvLog {
    fn observe_iter(&mut self, state: &GradState, kv: &KV) -> Result<(), ArgminError> {
        let mut row = format!("{},{}", state.get_iter(), state.get_cost());
        for c in &self.columns {
            let v = kv.get(c).and_then(|v| v.get_float()).unwrap_or(f64::NAN);
            row.push_str(&format!(",{v}"));
        }
        row.push_str(&format!(
            ",{:.3}\n",
            self.offset_seconds + self.start.elapsed().as_secs_f64()
        ));
        self.file.write_all(row.as_bytes())?;
        self.file.flush()?;
        Ok(())
    }
}
