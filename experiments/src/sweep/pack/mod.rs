//! Finished runs in one compressed file: the compact form committed results are kept in.
//!
//! A folder of finished run folders `X/` packs into `X.jsonl.gz` beside it (a sweep folder's
//! `runs/` into `runs.jsonl.gz`): gzip'd JSON lines, a header, then one line per run holding
//! its text files verbatim (`config.toml`, `run.json`, `summary.json`, the codes, …) and its
//! `log.csv` cut to the iteration and a few columns ([`DEFAULT_LOG_COLUMNS`]) rounded to
//! [`LOG_DIGITS`] significant digits. Pictures and other binary files are left out and
//! listed: they are drawn again from the code and the config
//! ([`crate::runs::redraw_pictures`], `ifslab unpack --pictures`).
//!
//! A packed run is a finished run: `collect` tables it (its loss curve from the packed
//! columns), `sweep` skips it and `sweep --adopt X` takes it in as it takes a folder of `X/`;
//! [`unpack`] writes the folders back. A run folder beside the pack wins over the packed copy.
//!
//! `mod.rs` holds the format and reads a pack ([`Pack`]); `columns.rs` cuts a run's log to its
//! columns; `write.rs` packs folders and unpacks them.

mod columns;
mod write;

use std::collections::{BTreeMap, HashSet};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext, bail, bail_config};
use serde::{Deserialize, Serialize};

pub use columns::LogColumns;
pub use write::{Packed, Unpacked, pack, unpack};
use write::{is_text, walk};

/// The format named in a pack's header line.
pub const PACK_FORMAT: &str = "ifslab-runs/1";
/// The suffix of a pack: `X/` packs into `X.jsonl.gz`.
pub const PACK_SUFFIX: &str = ".jsonl.gz";
/// The log a run writes, kept as columns.
pub use crate::runs::inversion::LOG_FILE;
use ifslab_strategies::driver::plan::CHECKPOINT_FILE;
/// Significant digits the packed log columns keep (the first column, the iteration, is exact).
pub const LOG_DIGITS: usize = 5;
/// The log columns kept besides the first (the iteration): what the report plots and what
/// the chaotic-splatting README reads from the logs.
pub const DEFAULT_LOG_COLUMNS: &[&str] = &["loss", "anneal_accepted"];
/// Files kept verbatim, by extension; anything else (pictures, `target.npy`) is left out, and
/// so are checkpoints ([`CHECKPOINT_FILE`], at any depth: a finished run resumes from nothing,
/// and a checkpoint weighs more than the rest of its run).
const TEXT_EXTENSIONS: &[&str] = &["json", "toml", "csv", "txt", "flame", "md"];

/// The first line of a pack.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct Header {
    format: String,
    runs: usize,
    log_digits: usize,
    note: String,
}

/// One finished run in a pack.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PackedRun {
    /// Its folder's name (a sweep run's id).
    pub name: String,
    /// Its text files, by path inside the folder, verbatim.
    pub files: BTreeMap<String, String>,
    /// Its `log.csv`, compacted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub log: Option<LogColumns>,
    /// The files of the folder that were not kept (pictures, binary files).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub left_out: Vec<String>,
}

impl PackedRun {
    /// Reads a run folder: text files verbatim, `log.csv` compacted to `keep` columns.
    pub fn from_folder(dir: &Path, keep: &[String]) -> crate::Result<PackedRun> {
        let name = dir
            .file_name()
            .with_context(|| format!("{} has no folder name", dir.display()))?
            .to_string_lossy()
            .into_owned();
        let mut run = PackedRun {
            name,
            files: BTreeMap::new(),
            log: None,
            left_out: Vec::new(),
        };
        let mut paths = Vec::new();
        walk(dir, dir, &mut paths)?;
        paths.sort();
        for rel in paths {
            let path = dir.join(&rel);
            let text = is_text(&rel)
                .then(|| std::fs::read_to_string(&path).ok())
                .flatten();
            match text {
                Some(t) if rel == LOG_FILE => match LogColumns::parse(&t) {
                    Some(log) => run.log = Some(log.compact(keep, LOG_DIGITS)),
                    None => run.left_out.push(rel),
                },
                Some(t) => {
                    run.files.insert(rel, t);
                }
                None => run.left_out.push(rel),
            }
        }
        Ok(run)
    }

    /// Moves the run's checkpoints (packed before they were left out) to `left_out`.
    fn leave_out_checkpoints(&mut self) {
        let names: Vec<String> = self
            .files
            .keys()
            .filter(|rel| !is_text(rel))
            .cloned()
            .collect();
        if names.is_empty() {
            return;
        }
        for rel in names {
            self.files.remove(&rel);
            self.left_out.push(rel);
        }
        self.left_out.sort();
    }

    /// A text file of the run.
    pub fn file(&self, name: &str) -> Option<&str> {
        self.files.get(name).map(String::as_str)
    }

    /// A JSON file of the run, parsed; `None` when the run has none.
    pub fn json<T: serde::de::DeserializeOwned>(&self, name: &str) -> crate::Result<Option<T>> {
        self.file(name)
            .map(|t| {
                serde_json::from_str(t)
                    .with_context(|| format!("{name} of the packed run {} is not valid", self.name))
            })
            .transpose()
    }

    /// Its loss against the iteration, from the packed log.
    pub fn loss_curve(&self) -> Option<Vec<(f64, f64)>> {
        self.log.as_ref()?.curve("loss")
    }

    /// Writes the run's folder: its text files and the compacted `log.csv` (pictures are
    /// [`crate::runs::redraw_pictures`]'s).
    pub fn write_folder(&self, dir: &Path) -> crate::Result<()> {
        for (rel, text) in &self.files {
            let path = dir.join(rel);
            if let Some(parent) = path.parent() {
                std::fs::create_dir_all(parent).doing("creating", parent)?;
            }
            ifslab::io::write_atomic(&path, text.as_bytes())?;
        }
        if let Some(log) = &self.log {
            std::fs::create_dir_all(dir).doing("creating", dir)?;
            ifslab::io::write_atomic(&dir.join(LOG_FILE), log.to_csv().as_bytes())?;
        }
        Ok(())
    }
}

/// The pack of a folder of runs: `X/` → `X.jsonl.gz`.
pub fn pack_path(runs: &Path) -> PathBuf {
    let name = runs
        .file_name()
        .map_or_else(|| "runs".to_string(), |n| n.to_string_lossy().into_owned());
    runs.with_file_name(format!("{name}{PACK_SUFFIX}"))
}

/// The folder of runs a pack stands for: `X.jsonl.gz` → `X/` (a folder is itself).
pub fn runs_folder(path: &Path) -> PathBuf {
    let s = path.to_string_lossy();
    match s.strip_suffix(PACK_SUFFIX) {
        Some(folder) => PathBuf::from(folder),
        None => path.to_path_buf(),
    }
}

/// The folder of runs a command names: a sweep folder's `runs/` (the folder has a
/// `sweep.json`), the folder a pack stands for, or the folder itself.
pub fn runs_of(dir: &Path) -> PathBuf {
    if dir.join(super::layout::PLAN_FILE).is_file() {
        dir.join(super::layout::RUNS_DIR)
    } else {
        runs_folder(dir)
    }
}

/// Packed runs, in name order.
#[derive(Clone, Debug, Default)]
pub struct Pack {
    /// The runs.
    pub runs: Vec<PackedRun>,
}

impl Pack {
    /// Reads a pack file.
    pub fn read(path: &Path) -> crate::Result<Pack> {
        let file = std::fs::File::open(path).doing("opening", path)?;
        let mut lines = BufReader::new(flate2::read::GzDecoder::new(file)).lines();
        let first = lines
            .next()
            .config_context(path, || format!("{} is empty", path.display()))?
            .doing("reading", path)?;
        let header: Header = serde_json::from_str(&first)
            .config_context(path, || format!("{} has no pack header", path.display()))?;
        if header.format != PACK_FORMAT {
            bail_config!(
                path,
                "{} is a pack of format `{}`; this ifslab reads `{PACK_FORMAT}`",
                path.display(),
                header.format
            );
        }
        let mut runs = Vec::with_capacity(header.runs);
        for (k, line) in lines.enumerate() {
            let line = line.doing("reading", path)?;
            runs.push(serde_json::from_str(&line).config_context(path, || {
                format!("{}: run {} is not valid", path.display(), k + 1)
            })?);
        }
        if runs.len() != header.runs {
            bail_config!(
                path,
                "{} holds {} runs where its header says {}: the file is cut short",
                path.display(),
                runs.len(),
                header.runs
            );
        }
        Ok(Pack { runs })
    }

    /// The pack beside a folder of runs (`X.jsonl.gz` for `X/`), empty when there is none.
    pub fn beside(runs: &Path) -> crate::Result<Pack> {
        let path = pack_path(runs);
        if path.is_file() {
            Pack::read(&path)
        } else {
            Ok(Pack::default())
        }
    }

    /// Writes the pack (runs in name order; the same runs give the same bytes).
    pub fn write(&mut self, path: &Path) -> crate::Result<()> {
        self.runs.sort_by(|a, b| a.name.cmp(&b.name));
        let header = Header {
            format: PACK_FORMAT.into(),
            runs: self.runs.len(),
            log_digits: LOG_DIGITS,
            note: "one finished run a line: its text files verbatim, log.csv as columns \
                   (the iteration and a few others, rounded); pictures left out — \
                   `ifslab unpack --pictures` draws them again"
                .into(),
        };
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        writeln!(gz, "{}", serde_json::to_string(&header)?)?;
        for r in &self.runs {
            writeln!(gz, "{}", serde_json::to_string(r)?)?;
        }
        ifslab::io::write_atomic(path, &gz.finish()?)?;
        Ok(())
    }

    /// A run by its folder name.
    pub fn get(&self, name: &str) -> Option<&PackedRun> {
        self.runs
            .binary_search_by(|r| r.name.as_str().cmp(name))
            .ok()
            .map(|k| &self.runs[k])
    }

    /// The names of the packed runs.
    pub fn names(&self) -> HashSet<&str> {
        self.runs.iter().map(|r| r.name.as_str()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_packed_folder_unpacks_to_its_text_files_and_a_compacted_log() {
        let tmp = tempfile::tempdir().unwrap();
        let runs = tmp.path().join("runs");
        let a = runs.join("abc");
        std::fs::create_dir_all(a.join("sub")).unwrap();
        std::fs::write(a.join("summary.json"), "{\n  \"iou\": 0.123456789\n}").unwrap();
        std::fs::write(a.join("config.toml"), "seed = 1\n").unwrap();
        std::fs::write(a.join("sub/notes.txt"), "kept").unwrap();
        std::fs::write(a.join("render.png"), [0u8, 159, 146, 150]).unwrap();
        // Checkpoints, the run's own and its legs', are left out too.
        std::fs::write(a.join(CHECKPOINT_FILE), "{\"theta\": [1.0]}").unwrap();
        std::fs::write(a.join("sub").join(CHECKPOINT_FILE), "{}").unwrap();
        std::fs::write(
            a.join("log.csv"),
            "iter,loss,msmse,seconds\n0,1.234567891,0.5,0.1\n1,NaN,0.4,0.2\n123456,0.000123456789,0.3,0.3\n",
        )
        .unwrap();
        // Not finished: left alone.
        std::fs::create_dir_all(runs.join("partial")).unwrap();
        std::fs::create_dir_all(runs.join(".locks")).unwrap();
        let keep: Vec<String> = DEFAULT_LOG_COLUMNS.iter().map(|s| s.to_string()).collect();
        let p = pack(&runs, &keep, true).unwrap();
        assert_eq!((p.added, p.runs, p.removed), (1, 1, 1));
        assert_eq!(p.skipped, vec![runs.join("partial")]);
        assert!(!a.exists() && p.path == tmp.path().join("runs.jsonl.gz"));
        let back = Pack::read(&p.path).unwrap();
        let r = back.get("abc").unwrap();
        assert_eq!(
            r.left_out,
            [CHECKPOINT_FILE, "render.png", "sub/checkpoint.json"]
        );
        assert_eq!(r.file("sub/notes.txt"), Some("kept"));
        assert_eq!(
            r.loss_curve().unwrap(),
            [(0.0, 1.2346), (123456.0, 0.00012346)],
            "the iteration exact, the loss to 5 digits, NaN left out"
        );
        // A pack written before checkpoints were left out loses them when packed again.
        let mut old = back.clone();
        old.runs[0]
            .files
            .insert(CHECKPOINT_FILE.into(), "{\"theta\": [1.0]}".into());
        old.runs[0].left_out.retain(|f| f != CHECKPOINT_FILE);
        old.write(&p.path).unwrap();
        pack(&runs, &keep, false).unwrap();
        assert_eq!(Pack::read(&p.path).unwrap().get("abc"), Some(r));
        // Packing again changes nothing, byte for byte.
        let bytes = std::fs::read(&p.path).unwrap();
        pack(&runs, &keep, false).unwrap();
        assert_eq!(std::fs::read(&p.path).unwrap(), bytes);
        let u = unpack(&runs, &[]).unwrap();
        assert_eq!((u.folders, u.written), (vec![a.clone()], 1));
        assert_eq!(
            unpack(&runs, &[]).unwrap().written,
            0,
            "a folder there is left alone"
        );
        assert_eq!(
            std::fs::read_to_string(a.join("summary.json")).unwrap(),
            "{\n  \"iou\": 0.123456789\n}"
        );
        assert_eq!(
            std::fs::read_to_string(a.join("log.csv")).unwrap(),
            "iter,loss\n0,1.2346\n1,NaN\n123456,0.00012346\n"
        );
        assert!(!a.join("render.png").exists());
        assert!(unpack(&runs, &["nope".into()]).is_err());
    }

    #[test]
    fn a_cut_pack_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("runs.jsonl.gz");
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        writeln!(
            gz,
            "{{\"format\":\"{PACK_FORMAT}\",\"runs\":2,\"log_digits\":5,\"note\":\"\"}}"
        )
        .unwrap();
        writeln!(gz, "{{\"name\":\"a\",\"files\":{{}}}}").unwrap();
        std::fs::write(&path, gz.finish().unwrap()).unwrap();
        let e = Pack::read(&path).unwrap_err().to_string();
        assert!(e.contains("cut short"), "{e}");
    }
}
