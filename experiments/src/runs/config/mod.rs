//! Any run `ifslab run` accepts: one TOML config whose top-level `problem` key says which
//! problem it describes (`"image"` — the default, so older configs keep working —,
//! `"points"`, `"texture"`, `"sdf"`, `"flame"` or `"image3d"`), and
//! one call that turns it into a run folder. The command line, the sweeps and any other front
//! end go through [`RunConfig::run`].

use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext, bail, bail_config};
use ifslab::loss::lpips::default_lpips_weights_path;
use ifslab_strategies::problems::flame::FlameLearnConfig;
use ifslab_strategies::problems::image::InversionConfig;
use ifslab_strategies::problems::sdf::SdfConfig;
use serde::Serialize;

use crate::progress::Progress;
use crate::runs::flame;
use crate::runs::image3d::{self, Image3dRunConfig};
use crate::runs::inversion;
use crate::runs::points::{self, PointsConfig};
use crate::runs::sdf;
use crate::runs::texture::{self, TextureConfig};

use super::table::set_dotted;
pub use super::table::{DEFAULT_PROBLEM, PROBLEM_KEY};

/// A validated run config of any problem.
#[derive(Clone, Debug, PartialEq)]
pub enum RunConfig {
    /// Image → IFS code by differentiable splatting (`problem = "image"`).
    Image(Box<InversionConfig>),
    /// Point cloud → IFS of similitudes by EM (`problem = "points"`).
    Points(Box<PointsConfig>),
    /// Fractal-coding texture upsampling (`problem = "texture"`).
    Texture(Box<TextureConfig>),
    /// Image → segment pattern by the SDF raster (`problem = "sdf"`).
    Sdf(Box<SdfConfig>),
    /// Image → colour fractal flame (`problem = "flame"`).
    Flame(Box<FlameLearnConfig>),
    /// Pictures around a 3-D fractal → an IFS code of space (`problem = "image3d"`).
    Image3d(Box<Image3dRunConfig>),
}

/// What every run reports when it ends: a one-line headline for people and the
/// `summary.json` it wrote, as JSON, for tables.
#[derive(Clone, Debug, Serialize)]
pub struct RunReport {
    /// The problem's name (`"image"`, …).
    pub problem: String,
    /// A line for the terminal ("300 iterations of adam in 41.2 s, IoU 0.91, …").
    pub headline: String,
    /// The run's `summary.json`.
    pub summary: serde_json::Value,
}

impl RunConfig {
    /// The problems a config can name, in the order the help text lists them.
    pub const PROBLEMS: &'static [&'static str] =
        &["image", "points", "texture", "sdf", "flame", "image3d"];

    /// The problems whose `paper` key only picks the defaults of keys a config leaves out
    /// ([`super::table::HAS_RECIPES`]).
    pub const HAS_RECIPES: &'static [&'static str] = super::table::HAS_RECIPES;

    /// A config from a parsed TOML table; `origin` (the file it came from) names it in
    /// errors and relative file names in it are read from its folder.
    pub fn from_table(mut table: toml::Table, origin: &Path) -> crate::Result<Self> {
        let problem = match table.remove(PROBLEM_KEY) {
            None => DEFAULT_PROBLEM.to_string(),
            Some(toml::Value::String(s)) => s,
            Some(v) => bail_config!(
                origin,
                "{}: `{PROBLEM_KEY}` must be a string (one of {}), got {v}",
                origin.display(),
                Self::PROBLEMS.join(", ")
            ),
        };
        let dir = origin.parent().unwrap_or(Path::new(""));
        let text = toml::to_string(&table).context("re-serialising the config")?;
        match problem.as_str() {
            "image" => {
                let cfg = InversionConfig::from_table(table, origin)?.relative_to(dir);
                Ok(RunConfig::Image(Box::new(cfg)))
            }
            "points" => Ok(RunConfig::Points(Box::new(PointsConfig::from_table(
                table, origin,
            )?))),
            "texture" => {
                let cfg = TextureConfig::from_toml(&text, origin)?.relative_to(dir);
                Ok(RunConfig::Texture(Box::new(cfg)))
            }
            "sdf" => {
                let cfg = SdfConfig::from_table(table, origin)?.relative_to(dir);
                Ok(RunConfig::Sdf(Box::new(cfg)))
            }
            "flame" => {
                let cfg = FlameLearnConfig::from_table(table, origin)?.relative_to(dir);
                Ok(RunConfig::Flame(Box::new(cfg)))
            }
            "image3d" => {
                let cfg = Image3dRunConfig::from_table(table, origin)?.relative_to(dir);
                Ok(RunConfig::Image3d(Box::new(cfg)))
            }
            other => bail_config!(
                origin,
                "{}: unknown problem `{other}` (known: {})",
                origin.display(),
                Self::PROBLEMS.join(", ")
            ),
        }
    }

    /// A config from TOML text (see [`RunConfig::from_table`]).
    pub fn from_toml(text: &str, origin: &Path) -> crate::Result<Self> {
        let table: toml::Table = text
            .parse()
            .config_context(origin, || format!("{} is not valid TOML", origin.display()))?;
        RunConfig::from_table(table, origin)
    }

    /// Reads and validates a config file.
    pub fn load(path: &Path) -> crate::Result<Self> {
        RunConfig::load_with(path, &[])
    }

    /// Reads the resolved config a run wrote into its folder (`config.toml`), for resuming,
    /// adopting or slicing that run. A resolved config written before recipes existed has
    /// no `paper` key and meant the paper's defaults ([`ifslab_strategies::recipe::mark_legacy`]); it is read
    /// that way, so an old run resumes as it started.
    pub fn load_resolved(path: &Path) -> crate::Result<Self> {
        RunConfig::load_resolved_with(path, toml::Table::new())
    }

    /// [`RunConfig::load_resolved`] with `overrides` (a table of keys, nested tables merged
    /// key by key) applied on top: a resumed run told to go on longer, say.
    pub fn load_resolved_with(path: &Path, overrides: toml::Table) -> crate::Result<Self> {
        let mut table = super::table::read_resolved(path)?;
        merge_into(&mut table, overrides);
        RunConfig::from_table(table, path)
    }

    /// Reads a config file, applies `overrides` (`KEY=VALUE` with dotted keys, as
    /// `ifslab run --set` takes them: `renderer.device=cuda`, `iterations=100`) and validates
    /// the result, so an override is checked like the file's own keys. A value is read as a
    /// TOML value (`100`, `0.5`, `true`, `[1, 2]`, `"text"`) and otherwise as a string; file
    /// names in an override are read, like the file's own, from the config's folder.
    pub fn load_with(path: &Path, overrides: &[String]) -> crate::Result<Self> {
        let text = std::fs::read_to_string(path).doing("reading", path)?;
        let mut table: toml::Table = text
            .parse()
            .config_context(path, || format!("{} is not valid TOML", path.display()))?;
        for o in overrides {
            let (key, value) = parse_override(o)?;
            set_dotted(&mut table, &key, value).with_context(|| format!("applying `--set {o}`"))?;
        }
        RunConfig::from_table(table, path)
    }

    /// The LPIPS weights file this run would use but which is not there: an image run whose
    /// loss weighs LPIPS (the file its config names, or the default) or that is scored on a
    /// suite (whose tables have an LPIPS column; the default file). Such a run still goes —
    /// without the term, or without the score, and saying so in its summary — but its run id
    /// does not record that, so a sweep asks this first (`ifslab sweep --without-lpips`).
    pub fn missing_lpips_weights(&self) -> Option<PathBuf> {
        let RunConfig::Image(c) = self else {
            return None;
        };
        let mut wanted = Vec::new();
        if c.loss.lpips_weight > 0.0 {
            wanted.push(c.loss.lpips_weights_path());
        }
        if c.target.suite.is_some() {
            wanted.push(default_lpips_weights_path());
        }
        wanted.into_iter().find(|p| !p.exists())
    }

    /// The problem's name.
    pub fn problem(&self) -> &'static str {
        match self {
            RunConfig::Image(_) => "image",
            RunConfig::Points(_) => "points",
            RunConfig::Texture(_) => "texture",
            RunConfig::Sdf(_) => "sdf",
            RunConfig::Flame(_) => "flame",
            RunConfig::Image3d(_) => "image3d",
        }
    }

    /// The resolved config as a TOML table, `problem` key first, every default written out
    /// and every file named absolutely: what identifies a run (sweeps hash it) and what a run
    /// folder's `config.toml` holds.
    pub fn to_table(&self) -> crate::Result<toml::Table> {
        let body = match self {
            RunConfig::Image(c) => toml::Table::try_from(c.with_absolute_paths()?)?,
            RunConfig::Points(c) => toml::Table::try_from(c.resolved()?)?,
            RunConfig::Texture(c) => toml::Table::try_from(c.resolved()?)?,
            RunConfig::Sdf(c) => toml::Table::try_from(c.with_absolute_paths()?)?,
            RunConfig::Flame(c) => toml::Table::try_from(c.with_absolute_paths()?)?,
            RunConfig::Image3d(c) => return c.resolved_table(),
        };
        let mut t = toml::Table::new();
        t.insert(PROBLEM_KEY.into(), self.problem().into());
        t.extend(body);
        Ok(t)
    }

    /// The output folder the config names, if it names one.
    pub fn output(&self) -> Option<&Path> {
        match self {
            RunConfig::Image(c) => c.output.as_deref(),
            RunConfig::Points(c) => c.output.as_deref(),
            RunConfig::Texture(c) => c.output.as_deref(),
            RunConfig::Sdf(c) => c.output.as_deref(),
            RunConfig::Flame(c) => c.output.as_deref(),
            RunConfig::Image3d(c) => c.output.as_deref(),
        }
    }

    /// Runs the config into `dir` (a fresh folder, or with `resume` the folder of an
    /// interrupted run of the same config), reporting to `progress`.
    pub fn run(
        &self,
        dir: &Path,
        resume: bool,
        progress: Box<dyn Progress>,
    ) -> crate::Result<RunReport> {
        // Each problem's runner takes its folder's lock (`lock::lock_run_dir`) first.
        match self {
            RunConfig::Image(cfg) => {
                let s = inversion::run_and_report(cfg, dir, resume, progress)?;
                Ok(RunReport {
                    problem: self.problem().into(),
                    headline: format!("{} in {:.1} s, {}", s.work(), s.seconds, s.scores()),
                    summary: serde_json::to_value(&s)?,
                })
            }
            RunConfig::Points(cfg) => {
                let s = points::run(cfg, dir, resume, progress)?;
                Ok(RunReport {
                    problem: self.problem().into(),
                    headline: s.headline(),
                    summary: serde_json::to_value(&s)?,
                })
            }
            RunConfig::Texture(cfg) => {
                let s = texture::run(cfg, dir, resume, progress)?;
                Ok(RunReport {
                    problem: self.problem().into(),
                    headline: s.headline(),
                    summary: serde_json::to_value(&s)?,
                })
            }
            RunConfig::Sdf(cfg) => {
                let s = sdf::run(cfg, dir, resume, progress)?;
                Ok(RunReport {
                    problem: self.problem().into(),
                    headline: s.headline(),
                    summary: serde_json::to_value(&s)?,
                })
            }
            RunConfig::Flame(cfg) => {
                let s = flame::run(cfg, dir, resume, progress)?;
                Ok(RunReport {
                    problem: self.problem().into(),
                    headline: s.headline(),
                    summary: serde_json::to_value(&s)?,
                })
            }
            RunConfig::Image3d(cfg) => {
                let s = image3d::run(cfg, dir, resume, progress)?;
                Ok(RunReport {
                    problem: self.problem().into(),
                    headline: image3d::report(&s),
                    summary: serde_json::to_value(&s)?,
                })
            }
        }
    }

    /// The folder a run goes to: the command line's choice, else the config's, else
    /// `default`.
    pub fn output_dir(&self, cli: Option<PathBuf>, default: &str) -> PathBuf {
        cli.or_else(|| self.output().map(Path::to_path_buf))
            .unwrap_or_else(|| PathBuf::from(default))
    }
}

/// `overrides` written into `table`, tables merged key by key, other values replaced.
fn merge_into(table: &mut toml::Table, overrides: toml::Table) {
    for (k, v) in overrides {
        match (table.get_mut(&k), v) {
            (Some(toml::Value::Table(mine)), toml::Value::Table(theirs)) => {
                merge_into(mine, theirs)
            }
            (_, v) => {
                table.insert(k, v);
            }
        }
    }
}

/// One `KEY=VALUE` override: the dotted key and its value, read as a TOML value where it is
/// one (`3`, `0.5`, `true`, `"a b"`, `[1, 2]`) and as a string otherwise (`cuda`, `fern`).
pub fn parse_override(s: &str) -> crate::Result<(String, toml::Value)> {
    let Some((key, value)) = s.split_once('=') else {
        bail!("`{s}` is not KEY=VALUE (e.g. renderer.device=cuda)");
    };
    let key = key.trim();
    if key.is_empty() || key.split('.').any(str::is_empty) {
        bail!("`{s}`: `{key}` is not a dotted config key");
    }
    let value = value.trim();
    let parsed = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"));
    Ok((
        key.to_string(),
        parsed.unwrap_or_else(|| toml::Value::String(value.to_string())),
    ))
}

#[cfg(test)]
mod tests;
