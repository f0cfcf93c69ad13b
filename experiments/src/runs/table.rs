//! Run configs as TOML tables, below any one problem: the key that names the problem, a
//! dotted key set in a table, and a run folder's stored (resolved) config read back the way
//! it was meant when it was written.

use std::path::Path;

use crate::error::{Context, IoContext, bail};
use ifslab_strategies::recipe;

/// The config key that names the problem a config describes.
pub const PROBLEM_KEY: &str = "problem";

/// The name of the problem every config without a `problem` key describes.
pub const DEFAULT_PROBLEM: &str = "image";

/// The problems whose `paper` key only picks the defaults of keys a config leaves out
/// ([`ifslab_strategies::recipe`]): their resolved tables spell every choice out, so the key
/// takes no part in a run's id. (`points` has its own `paper` switch, which also changes
/// values no key spells out, and stays in the id.)
pub const HAS_RECIPES: &[&str] = &["image", "sdf", "flame"];

/// The problem a config table names (absent: [`DEFAULT_PROBLEM`]).
pub fn problem_of(table: &toml::Table) -> &str {
    table
        .get(PROBLEM_KEY)
        .and_then(toml::Value::as_str)
        .unwrap_or(DEFAULT_PROBLEM)
}

/// Sets the dotted `key` (`renderer.device`) of `table` to `value`, making the tables on
/// the way; refuses a key that runs through a value that is not a table.
pub fn set_dotted(table: &mut toml::Table, key: &str, value: toml::Value) -> crate::Result<()> {
    let parts: Vec<&str> = key.split('.').collect();
    let (last, path) = parts.split_last().context("an empty config key")?;
    let mut t = table;
    for (i, p) in path.iter().enumerate() {
        let entry = t
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        t = match entry {
            toml::Value::Table(inner) => inner,
            other => bail!(
                "cannot set `{key}`: `{}` is {other}, not a table",
                parts[..=i].join(".")
            ),
        };
    }
    t.insert(last.to_string(), value);
    Ok(())
}

/// The resolved config a run folder stored at `path`, as the table it meant when it was
/// written: one written before recipes existed has no `paper` key and meant the paper's
/// defaults ([`recipe::mark_legacy`]); a points config writes `reflections`, `words` and
/// `trim_outliers` only when they are on, so absent they were off (and absent from every
/// run made before they existed), and `keep` only when it is the closeness, so absent the
/// likelihood kept the run.
pub fn read_resolved(path: &Path) -> crate::Result<toml::Table> {
    let text = std::fs::read_to_string(path).doing("reading", path)?;
    let mut table: toml::Table = text
        .parse()
        .config_context(path, || format!("{} is not valid TOML", path.display()))?;
    let problem = problem_of(&table).to_owned();
    if HAS_RECIPES.contains(&problem.as_str()) {
        recipe::mark_legacy(&mut table);
    }
    if problem == "points" {
        for key in ["reflections", "words", "trim_outliers"] {
            table.entry(key).or_insert(toml::Value::Boolean(false));
        }
        table
            .entry("keep")
            .or_insert(toml::Value::String("likelihood".into()));
    }
    Ok(table)
}
