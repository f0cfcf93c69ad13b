//! A sweep's axes: each a config key (or several, in a group) and the values it takes,
//! applied to a copy of the base config, with the labels a report names them by.

use super::*;

/// An axis with its values resolved to (label, overrides).
pub(super) struct Axis {
    pub(super) name: String,
    pub(super) values: Vec<AxisValue>,
}

/// One value of an axis: its label and the config keys it sets.
pub(super) struct AxisValue {
    pub(super) label: String,
    pub(super) set: Vec<(String, toml::Value)>,
}

impl Axis {
    pub(super) fn resolve(a: &AxisConfig, here: &Path) -> crate::Result<Self> {
        let name = a.display_name();
        let mut values = Vec::new();
        if let Some(vs) = &a.values {
            let key = a.key.clone().unwrap_or_default();
            for (i, v) in vs.iter().enumerate() {
                let label = match &a.labels {
                    Some(l) => l[i].clone(),
                    None => label_of(v),
                };
                values.push(AxisValue {
                    label,
                    set: vec![(key.clone(), v.clone())],
                });
            }
        } else if let Some(folder) = &a.folder {
            let folder = here.join(folder);
            let key = a.key.clone().unwrap_or_default();
            let mut files: Vec<PathBuf> = std::fs::read_dir(&folder)
                .io_context(&folder, || {
                    format!("axis `{name}`: reading the folder {}", folder.display())
                })?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.is_file()
                        && p.extension().is_some_and(|e| {
                            let e = e.to_string_lossy().to_ascii_lowercase();
                            e == "png" || e == "jpg" || e == "jpeg"
                        })
                })
                .collect();
            files.sort();
            if files.is_empty() {
                bail!(
                    "axis `{name}`: {} holds no .png or .jpg image",
                    folder.display()
                );
            }
            for f in files {
                values.push(AxisValue {
                    label: f
                        .file_stem()
                        .map_or_else(String::new, |s| s.to_string_lossy().into_owned()),
                    set: vec![(key.clone(), f.to_string_lossy().into_owned().into())],
                });
            }
        } else {
            for v in &a.value {
                if values.iter().any(|x: &AxisValue| x.label == v.label) {
                    bail!("axis `{name}` has two values labelled `{}`", v.label);
                }
                values.push(AxisValue {
                    label: v.label.clone(),
                    set: flatten(&v.set),
                });
            }
        }
        for (i, v) in values.iter().enumerate() {
            if values[..i].iter().any(|x| x.label == v.label) {
                bail!(
                    "axis `{name}` has two values labelled `{}`: give `labels`",
                    v.label
                );
            }
        }
        Ok(Axis { name, values })
    }
}

/// A value as a label: strings as they are, anything else as TOML.
pub(super) fn label_of(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Overrides as (dotted key, value) pairs: nested tables are paths, so `strategy.kind =
/// "adam"` and `"strategy.kind" = "adam"` both set one key and leave its siblings alone.
pub fn flatten(t: &toml::Table) -> Vec<(String, toml::Value)> {
    let mut out = Vec::new();
    for (k, v) in t {
        match v {
            toml::Value::Table(inner) if !inner.is_empty() => {
                for (ik, iv) in flatten(inner) {
                    out.push((format!("{k}.{ik}"), iv));
                }
            }
            other => out.push((k.clone(), other.clone())),
        }
    }
    out
}
