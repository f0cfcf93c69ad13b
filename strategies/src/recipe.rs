//! Recipes: which values a config gets for the keys it leaves out.
//!
//! Every problem whose paper this project reproduces has two recipes: **ifslab's** (the
//! default: the settings measured best on inputs the project did not make,
//! `robustness/README.md`) and **the paper's** (`paper = true` in a config, `--paper` on the
//! command line: what the reproductions run). A recipe is a *preset* — a TOML table of the
//! keys whose defaults differ between the two — merged into a config wherever the config
//! leaves a key out ([`fill_absent`]), before the config is parsed. A key the config gives
//! always wins, so a config can start from either recipe and change any part of it.
//!
//! The resolved config a run writes (`config.toml`) spells out every value, the `paper` key
//! included. Optional values the paper's recipe leaves unset (no σ schedule) stay absent in
//! a paper run's table, while ifslab's recipe always writes them, so the two recipes never
//! resolve to the same table unless they mean the same run; that is why a run's id (a hash
//! of its resolved table) leaves the `paper` key out for these problems, and why runs made
//! before recipes existed (whose tables had no `paper` key and meant the paper's defaults)
//! keep their ids: [`mark_legacy`] reads such a table as the paper's.

use crate::error::{Error, Result};

/// The config key that chooses the recipe.
pub const PAPER_KEY: &str = "paper";

/// Which recipe a parsed config table asks for (`paper = true`; absent: ifslab's). Anything
/// but a boolean is refused, naming the key.
pub fn paper_flag(table: &toml::Table) -> Result<bool> {
    match table.get(PAPER_KEY) {
        None => Ok(false),
        Some(toml::Value::Boolean(b)) => Ok(*b),
        Some(v) => Err(Error::param(
            PAPER_KEY,
            format!("must be true (the paper's recipe) or false (ifslab's), got {v}"),
        )),
    }
}

/// Merges `preset` into `table` wherever `table` leaves a key out: tables are merged key by
/// key, every other value of `table` is kept as it is.
pub fn fill_absent(table: &mut toml::Table, preset: toml::Table) {
    for (k, v) in preset {
        match (table.get_mut(&k), v) {
            (None, v) => {
                table.insert(k, v);
            }
            (Some(toml::Value::Table(mine)), toml::Value::Table(theirs)) => {
                fill_absent(mine, theirs);
            }
            // The config's own value wins.
            (Some(_), _) => {}
        }
    }
}

/// Parses a config from `table` with the recipe it names filled in where it leaves keys
/// out (`preset(paper, table)`, merged by [`fill_absent`]); errors name `origin`. The caller
/// validates the result.
pub fn resolve<T: serde::de::DeserializeOwned>(
    mut table: toml::Table,
    origin: &std::path::Path,
    preset: impl FnOnce(bool, &toml::Table) -> toml::Table,
) -> Result<T> {
    let paper = paper_flag(&table).map_err(|e| Error::file(origin, e))?;
    let preset = preset(paper, &table);
    fill_absent(&mut table, preset);
    from_table(table).map_err(|e| Error::file(origin, e))
}

/// `T` from a TOML table; a refusal names the dotted key it is about (`config field
/// `iterations`: invalid value: integer `-5`, expected u64`), which a table (unlike TOML
/// text) cannot point at by line.
pub fn from_table<T: serde::de::DeserializeOwned>(
    table: toml::Table,
) -> std::result::Result<T, String> {
    serde_path_to_error::deserialize(toml::Value::Table(table)).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner();
        let message = inner.message().trim_end().to_string();
        if path.is_empty() || path == "." {
            message
        } else {
            format!("config field `{path}`: {message}")
        }
    })
}

/// A resolved table written before recipes existed has no `paper` key, and its absent
/// optional values meant the paper's defaults: it is read as the paper's recipe. Tables
/// that name a recipe are left as they are.
pub fn mark_legacy(table: &mut toml::Table) {
    table.entry(PAPER_KEY).or_insert(toml::Value::Boolean(true));
}

/// `value` at the dotted `path` of `table`, if there is one.
pub fn get_dotted<'a>(table: &'a toml::Table, path: &str) -> Option<&'a toml::Value> {
    let mut parts = path.split('.');
    let mut v = table.get(parts.next()?)?;
    for p in parts {
        v = v.as_table()?.get(p)?;
    }
    Some(v)
}

/// A table from dotted `(key, value)` pairs (`("renderer.sigma_final", 0.4)`), for presets.
pub fn table_of(pairs: impl IntoIterator<Item = (&'static str, toml::Value)>) -> toml::Table {
    let mut t = toml::Table::new();
    for (path, value) in pairs {
        let mut parts: Vec<&str> = path.split('.').collect();
        let last = parts.pop().expect("a non-empty key");
        let mut cur = &mut t;
        for p in parts {
            cur = cur
                .entry(p)
                .or_insert_with(|| toml::Value::Table(toml::Table::new()))
                .as_table_mut()
                .expect("preset keys do not overlap with values");
        }
        cur.insert(last.to_owned(), value);
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(s: &str) -> toml::Table {
        s.parse().unwrap()
    }

    #[test]
    fn the_configs_own_keys_win_and_tables_merge_key_by_key() {
        let mut c = t("a = 1\n[r]\nsigma = 2.0\n");
        fill_absent(
            &mut c,
            t("a = 5\nb = 6\n[r]\nsigma = 9.0\nsigma_final = 0.4\n[s]\nkind = \"x\"\n"),
        );
        assert_eq!(
            c,
            t("a = 1\nb = 6\n[r]\nsigma = 2.0\nsigma_final = 0.4\n[s]\nkind = \"x\"\n")
        );
    }

    #[test]
    fn the_recipe_key_is_a_boolean_and_legacy_tables_are_the_papers() {
        assert!(!paper_flag(&t("x = 1")).unwrap());
        assert!(paper_flag(&t("paper = true")).unwrap());
        let e = paper_flag(&t("paper = \"yes\"")).unwrap_err().to_string();
        assert!(e.contains("paper") && e.contains("yes"), "{e}");
        let mut old = t("x = 1");
        mark_legacy(&mut old);
        assert!(paper_flag(&old).unwrap());
        let mut new = t("paper = false");
        mark_legacy(&mut new);
        assert!(!paper_flag(&new).unwrap());
    }

    #[test]
    fn dotted_presets_build_nested_tables() {
        let p = table_of([
            ("model.init", "em".into()),
            ("renderer.sigma_final", 0.4.into()),
            ("model.maps", 3.into()),
        ]);
        assert_eq!(
            p,
            t("[model]\ninit = \"em\"\nmaps = 3\n[renderer]\nsigma_final = 0.4\n")
        );
        assert_eq!(get_dotted(&p, "model.maps"), Some(&toml::Value::Integer(3)));
        assert_eq!(get_dotted(&p, "model.nope"), None);
    }
}
