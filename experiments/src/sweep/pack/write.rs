//! Packing and unpacking: finished run folders into one pack ([`pack`]: text files kept
//! verbatim, the log cut to its columns, pictures listed) and a pack back into folders
//! ([`unpack`]).

use super::*;

pub(super) fn is_text(rel: &str) -> bool {
    let path = Path::new(rel);
    path.extension()
        .is_some_and(|e| TEXT_EXTENSIONS.contains(&e.to_string_lossy().as_ref()))
        && path.file_name().is_none_or(|n| n != CHECKPOINT_FILE)
}

/// Files under `dir`, relative to `root` with `/` separators; dot files and folders (locks)
/// left out.
pub(super) fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) -> crate::Result<()> {
    for e in std::fs::read_dir(dir).doing("reading", dir)? {
        let p = e?.path();
        if p.file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        {
            continue;
        }
        if p.is_dir() {
            walk(root, &p, out)?;
        } else {
            let rel = p.strip_prefix(root).unwrap_or(&p);
            out.push(
                rel.components()
                    .map(|c| c.as_os_str().to_string_lossy())
                    .collect::<Vec<_>>()
                    .join("/"),
            );
        }
    }
    Ok(())
}

/// Whether a folder holds a finished run: its `summary.json`, which every problem writes
/// last of its own files (a sweep's `run.json` comes after it, but `ifslab run` folders
/// have none).
pub(super) fn is_finished_folder(dir: &Path) -> bool {
    dir.join("summary.json").is_file()
}

/// What [`pack`] did.
#[derive(Debug, Default)]
pub struct Packed {
    /// The pack written.
    pub path: PathBuf,
    /// Runs taken from folders now.
    pub added: usize,
    /// Runs in the pack in all.
    pub runs: usize,
    /// Folders removed after the pack was read back and found equal.
    pub removed: usize,
    /// Folders left alone: not finished runs (partial, failed, other files).
    pub skipped: Vec<PathBuf>,
    /// Bytes of the pack.
    pub bytes: u64,
}

/// Packs the finished run folders of `runs` (a sweep folder's `runs/`, or any folder of run
/// folders) into `runs.jsonl.gz` beside it, added to the runs already packed there (a folder
/// replaces its packed copy). With `remove`, the packed folders are deleted once the pack
/// has been read back and holds each of them as packed.
pub fn pack(runs: &Path, keep: &[String], remove: bool) -> crate::Result<Packed> {
    let path = pack_path(runs);
    let mut pack = Pack::beside(runs)?;
    // Runs packed before checkpoints were left out lose theirs now.
    for r in &mut pack.runs {
        r.leave_out_checkpoints();
    }
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(runs)
        .doing("reading", runs)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .filter(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        })
        .collect();
    dirs.sort();
    let mut out = Packed {
        path: path.clone(),
        ..Packed::default()
    };
    let mut fresh = Vec::new();
    for d in dirs {
        if !is_finished_folder(&d) {
            out.skipped.push(d);
            continue;
        }
        let run = PackedRun::from_folder(&d, keep)?;
        pack.runs.retain(|r| r.name != run.name);
        pack.runs.push(run.clone());
        fresh.push((d, run));
    }
    out.added = fresh.len();
    pack.write(&path)?;
    let back = Pack::read(&path)?;
    out.runs = back.runs.len();
    out.bytes = std::fs::metadata(&path)?.len();
    if remove {
        for (d, run) in &fresh {
            if back.get(&run.name) != Some(run) {
                bail!(
                    "{} read back differs from the folder {}: nothing removed after it",
                    path.display(),
                    d.display()
                );
            }
            std::fs::remove_dir_all(d).doing("removing", d)?;
            out.removed += 1;
        }
    }
    Ok(out)
}

/// What [`unpack`] did.
#[derive(Debug, Default)]
pub struct Unpacked {
    /// The folders of the runs asked for, written now or there already.
    pub folders: Vec<PathBuf>,
    /// How many were written now.
    pub written: usize,
}

/// Writes the folders of packed runs back into `runs/` (those named in `only`, else all),
/// leaving folders that exist alone.
pub fn unpack(runs: &Path, only: &[String]) -> crate::Result<Unpacked> {
    let path = pack_path(runs);
    if !path.is_file() {
        bail!(
            "{} has no pack beside it ({})",
            runs.display(),
            path.display()
        );
    }
    let pack = Pack::read(&path)?;
    for name in only {
        if pack.get(name).is_none() {
            bail!("{} has no run `{name}`", path.display());
        }
    }
    let mut out = Unpacked::default();
    for r in &pack.runs {
        if !only.is_empty() && !only.contains(&r.name) {
            continue;
        }
        let dir = runs.join(&r.name);
        out.folders.push(dir.clone());
        if dir.exists() {
            continue;
        }
        // Written aside and renamed, so a folder that exists is a whole run.
        let tmp = runs.join(format!(".{}.unpacking", r.name));
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).doing("clearing", &tmp)?;
        }
        r.write_folder(&tmp)?;
        std::fs::rename(&tmp, &dir)
            .io_context(&tmp, || format!("moving {} into place", tmp.display()))?;
        out.written += 1;
    }
    Ok(out)
}
