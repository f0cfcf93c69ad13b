//! Adopting runs made elsewhere: finished run folders from another sweep, an `ifslab run` or another machine taken in as this sweep's runs where their resolved configs are the plan's.

use super::*;

/// What [`adopt`] did.
#[derive(Debug, Default)]
pub struct Adopted {
    /// (run index, the folder it came from) of the runs copied in.
    pub adopted: Vec<(usize, PathBuf)>,
    /// Runs of the plan that were already finished in the sweep folder.
    pub already: usize,
    /// Folders whose config is no run of the plan (or could not be read: why).
    pub unmatched: Vec<(PathBuf, String)>,
}

/// Takes finished run folders made outside the sweep (`ifslab run`, an older script) into
/// the sweep folder: each folder of `from` — and each run packed in `from.jsonl.gz` beside it
/// that has no folder there ([`super::super::pack`]; `from` may name the pack itself) — whose
/// `config.toml` resolves to one of the plan's runs (same id) and which has a `summary.json`
/// is copied to `runs/ID/` as a finished run, so that `collect` tables it and the sweep does
/// not run it again. Folders of other configs (other settings, or defaults that changed
/// since) are left out and listed.
pub fn adopt(plan: &Plan, out: &Path, from: &Path) -> crate::Result<Adopted> {
    write_plan(plan, out)?;
    let sweep_dir = plan.source.parent().unwrap_or(Path::new("/"));
    let folder = pack::runs_folder(from);
    let packed = Pack::beside(&folder)?;
    let mut candidates: Vec<(PathBuf, Option<&PackedRun>)> = Vec::new();
    if folder.is_dir() {
        for e in std::fs::read_dir(&folder).doing("reading", &folder)? {
            let p = e?.path();
            if p.is_dir() {
                candidates.push((p, None));
            }
        }
    } else if packed.runs.is_empty() {
        bail!(
            "{} is neither a folder of runs nor beside a pack of them ({})",
            folder.display(),
            pack::pack_path(&folder).display()
        );
    }
    for r in &packed.runs {
        let p = folder.join(&r.name);
        if !p.is_dir() {
            candidates.push((p, Some(r)));
        }
    }
    candidates.sort_by(|a, b| a.0.cmp(&b.0));
    let finished = FinishedRuns::of(out)?;
    // A packed run is written out here to be read like a folder.
    let staging = out.join(RUNS_DIR).join(".adopting");
    let mut result = Adopted::default();
    for (source, packed_run) in candidates {
        let d = match packed_run {
            None => source.clone(),
            Some(r) => {
                if staging.exists() {
                    std::fs::remove_dir_all(&staging).doing("clearing", &staging)?;
                }
                r.write_folder(&staging)?;
                staging.clone()
            }
        };
        let cfg_path = d.join("config.toml");
        if !cfg_path.is_file() || !d.join("summary.json").is_file() {
            result.unmatched.push((
                source,
                "no config.toml and summary.json: not a finished run".into(),
            ));
            continue;
        }
        let id = match crate::runs::RunConfig::load_resolved(&cfg_path).and_then(|c| c.to_table()) {
            Ok(t) => super::super::expand::run_id(&t, sweep_dir),
            Err(e) => {
                result.unmatched.push((source, format!("{e:#}")));
                continue;
            }
        };
        let Some(r) = plan.runs.iter().find(|r| r.id == id) else {
            result.unmatched.push((
                source,
                format!("its config (id {id}) is no run of the sweep"),
            ));
            continue;
        };
        if finished.contains(&id) {
            result.already += 1;
            continue;
        }
        let partial = partial_dir(out, &id);
        if partial.exists() {
            std::fs::remove_dir_all(&partial).doing("clearing", &partial)?;
        }
        if packed_run.is_some() {
            std::fs::rename(&d, &partial).io_context(&d, || {
                format!("moving {} to {}", d.display(), partial.display())
            })?;
        } else {
            copy_dir(&d, &partial)?;
        }
        let summary: serde_json::Value = serde_json::from_slice(
            &std::fs::read(partial.join("summary.json"))
                .doing("reading", &source.join("summary.json"))?,
        )
        .config_context(&source.join("summary.json"), || {
            format!(
                "{} is not valid JSON",
                source.join("summary.json").display()
            )
        })?;
        let record = RunRecord {
            id: id.clone(),
            name: r.name.clone(),
            problem: r.config.problem().into(),
            labels: r.labels.clone(),
            headline: format!("adopted from {}", source.display()),
            seconds: summary["seconds"].as_f64().unwrap_or(f64::NAN),
            resumed: false,
            threads: 0,
        };
        ifslab::io::write_atomic(
            &partial.join(RECORD_FILE),
            serde_json::to_string_pretty(&record)?.as_bytes(),
        )?;
        std::fs::rename(&partial, run_dir(out, &id)).io_context(&partial, || {
            format!("moving {} into place", partial.display())
        })?;
        result.adopted.push((r.index, source));
    }
    if staging.exists() {
        std::fs::remove_dir_all(&staging).doing("clearing", &staging)?;
    }
    Ok(result)
}

pub(super) fn copy_dir(from: &Path, to: &Path) -> crate::Result<()> {
    std::fs::create_dir_all(to).doing("creating", to)?;
    for e in std::fs::read_dir(from).doing("reading", from)? {
        let p = e?.path();
        let dest = to.join(p.file_name().unwrap_or_default());
        if p.is_dir() {
            copy_dir(&p, &dest)?;
        } else {
            std::fs::copy(&p, &dest).io_context(&p, || {
                format!("copying {} to {}", p.display(), dest.display())
            })?;
        }
    }
    Ok(())
}
