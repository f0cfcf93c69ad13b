//! A run's stable id: a hash of its resolved config in canonical form (keys sorted, file
//! names relative to the sweep file's folder, the operational keys left out), and the
//! labels that name its axis values.

use super::*;

/// The stable id of a resolved run config: the first 16 hex digits of the SHA-256 of its
/// canonical text (keys sorted, floats in shortest round-trip form), leaving out the
/// [`OPERATIONAL_KEYS`]. File names under `sweep_dir` (the sweep file's folder, where its
/// relative names are read from) are hashed relative to it, so a sweep and its committed
/// results keep their ids wherever the checkout lies.
pub fn run_id(resolved: &toml::Table, sweep_dir: &Path) -> String {
    let mut t = resolved.clone();
    for k in OPERATIONAL_KEYS {
        t.remove(*k);
    }
    // A recipe only fills in the keys a config leaves out, and the resolved table spells
    // them out: the `paper` key adds nothing to what such a run computes (and runs made
    // before recipes existed keep their ids).
    let problem = t
        .get(crate::runs::table::PROBLEM_KEY)
        .and_then(toml::Value::as_str)
        .unwrap_or(crate::runs::table::DEFAULT_PROBLEM);
    if RunConfig::HAS_RECIPES.contains(&problem) {
        t.remove(ifslab_strategies::recipe::PAPER_KEY);
    }
    let mut prefix = sweep_dir.to_string_lossy().into_owned();
    if !prefix.ends_with('/') {
        prefix.push('/');
    }
    relative_strings(&mut t, &prefix);
    let mut text = String::from("ifslab-run-v1\n");
    canonical_table(&t, &mut text);
    let digest = Sha256::digest(text.as_bytes());
    digest[..8].iter().fold(String::new(), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

/// Every string holding `prefix` (a folder with its trailing `/`) gets `@sweep/` instead.
pub(super) fn relative_strings(t: &mut toml::Table, prefix: &str) {
    fn walk(v: &mut toml::Value, prefix: &str) {
        match v {
            toml::Value::String(s) if s.contains(prefix) => *s = s.replace(prefix, "@sweep/"),
            toml::Value::Array(a) => a.iter_mut().for_each(|x| walk(x, prefix)),
            toml::Value::Table(t) => t.iter_mut().for_each(|(_, x)| walk(x, prefix)),
            _ => {}
        }
    }
    t.iter_mut().for_each(|(_, x)| walk(x, prefix));
}

pub(super) fn canonical_table(t: &toml::Table, out: &mut String) {
    let mut keys: Vec<&String> = t.keys().collect();
    keys.sort();
    out.push('{');
    for (i, k) in keys.into_iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(&serde_json::to_string(k).unwrap_or_default());
        out.push(':');
        canonical_value(&t[k], out);
    }
    out.push('}');
}

pub(super) fn canonical_value(v: &toml::Value, out: &mut String) {
    match v {
        toml::Value::String(s) => out.push_str(&serde_json::to_string(s).unwrap_or_default()),
        toml::Value::Integer(i) => {
            let _ = write!(out, "{i}");
        }
        // `{:?}` is the shortest text that reads back as the same f64, with a `.` or `e`
        // that keeps 1.0 apart from the integer 1.
        toml::Value::Float(f) => {
            let _ = write!(out, "{f:?}");
        }
        toml::Value::Boolean(b) => {
            let _ = write!(out, "{b}");
        }
        toml::Value::Datetime(d) => {
            let _ = write!(out, "\"{d}\"");
        }
        toml::Value::Array(a) => {
            out.push('[');
            for (i, x) in a.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                canonical_value(x, out);
            }
            out.push(']');
        }
        toml::Value::Table(t) => canonical_table(t, out),
    }
}

pub(super) fn join_labels(labels: &[(String, String)], sep: &str, with_names: bool) -> String {
    labels
        .iter()
        .map(|(n, l)| {
            if with_names {
                format!("{n}={l}")
            } else {
                l.clone()
            }
        })
        .collect::<Vec<_>>()
        .join(sep)
}
