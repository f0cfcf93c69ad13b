//! A multi-view run's config: the views, the code that drew them, held-out views, the fit's keys; read, resolved and written back.

use super::*;

/// The run folder's record of its inputs besides its config: where the views are and their
/// fingerprint when the run started (a resumed run refuses views that changed since).
pub const INPUTS_FILE: &str = "invert3d.json";

/// The `problem` key's value that names this run kind.
pub const PROBLEM: &str = "image3d";

/// The built-in 3-D codes a `truth` may name instead of a file.
pub const BUILT_IN_CODES: &[&str] = &["tetrahedron", "sierpinski-tetrahedron", "fern3d", "fern-3d"];

/// The keys of an `image3d` config that name its inputs; every other key is the fit's.
pub(super) const INPUT_KEYS: [&str; 4] = ["views", "truth", "score_views", "output"];

/// A multi-view inversion: its inputs and the fit's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct Image3dRunConfig {
    /// The views folder (pictures and cameras).
    pub views: PathBuf,
    /// The code that drew the views (a 3-D code file or one of [`BUILT_IN_CODES`]): the
    /// summary then scores baseline and fit against its attractor.
    pub truth: Option<String>,
    /// A folder of views the fit never sees, to score baseline and fit on.
    pub score_views: Option<PathBuf>,
    /// The output folder, when the config names one.
    pub output: Option<PathBuf>,
    /// The fit.
    pub fit: Image3dConfig,
}

/// What [`INPUTS_FILE`] holds: the views' fingerprint. A run made before configs named
/// their views kept its inputs here as well (its `config.toml` has the fit's keys alone);
/// [`load_run`] reads them back. A new run's inputs are in its config.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(super) struct Inputs {
    /// [`Views::digest`] of the views when the run started.
    pub(super) views_digest: String,
    /// An older run's views folder (absolute).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) views: Option<PathBuf>,
    /// An older run's truth (a file's absolute path, or a built-in name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) truth: Option<String>,
    /// An older run's views to score on (absolute).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) score_views: Option<PathBuf>,
}

impl Image3dRunConfig {
    /// A config from a TOML table without its `problem` key; `origin` (the file it came
    /// from) names it in errors. File names are as written (see
    /// [`Image3dRunConfig::relative_to`]). The fit's keys are checked like every config's:
    /// an unknown one is named.
    pub fn from_table(mut table: toml::Table, origin: &Path) -> crate::Result<Self> {
        let [views, truth, score_views, output] =
            INPUT_KEYS.map(|key| table.remove(key).map(|v| (key, v)));
        let text = |entry: Option<(&str, toml::Value)>| -> crate::Result<Option<String>> {
            match entry {
                None => Ok(None),
                Some((_, toml::Value::String(s))) => Ok(Some(s)),
                Some((key, v)) => bail_config!(
                    origin,
                    "{}: `{key}` must be a string (a file or folder name), got {v}",
                    origin.display()
                ),
            }
        };
        let views = text(views)?.ok_or_else(|| {
            Error::config(
                origin,
                format!(
                    "{}: an image3d run needs `views`, the folder of its pictures and their \
                     cameras (a transforms.json or turntable.json beside the pictures)",
                    origin.display()
                ),
            )
        })?;
        let truth = text(truth)?;
        let score_views = text(score_views)?.map(PathBuf::from);
        let output = text(output)?.map(PathBuf::from);
        let fit: Image3dConfig = toml::Value::Table(table)
            .try_into()
            .config_context(origin, || {
                format!("{}: an image3d config", origin.display())
            })?;
        fit.validate().config_context(origin, || {
            format!("{}: an image3d config", origin.display())
        })?;
        Ok(Image3dRunConfig {
            views: PathBuf::from(views),
            truth,
            score_views,
            output,
            fit,
        })
    }

    /// Relative file names read from `dir` (the config file's folder); built-in code names
    /// stay names.
    pub fn relative_to(mut self, dir: &Path) -> Self {
        let join = |p: &Path| {
            if p.is_relative() {
                dir.join(p)
            } else {
                p.to_path_buf()
            }
        };
        self.views = join(&self.views);
        self.score_views = self.score_views.as_deref().map(join);
        self.output = self.output.as_deref().map(join);
        self.fit.start_code = self.fit.start_code.as_deref().map(join);
        self.truth = self.truth.map(|t| {
            if BUILT_IN_CODES.contains(&t.as_str()) {
                t
            } else {
                join(Path::new(&t)).to_string_lossy().into_owned()
            }
        });
        self
    }

    /// The config with every file named absolutely (what a run's id hashes).
    pub fn with_absolute_paths(&self) -> crate::Result<Self> {
        let abs = |p: &Path| std::path::absolute(p).doing("resolving", p);
        let mut c = self.clone();
        c.views = abs(&c.views)?;
        c.score_views = c.score_views.as_deref().map(abs).transpose()?;
        c.output = c.output.as_deref().map(abs).transpose()?;
        c.fit.start_code = c.fit.start_code.as_deref().map(abs).transpose()?;
        c.truth = match c.truth {
            Some(t) if !BUILT_IN_CODES.contains(&t.as_str()) => {
                Some(abs(Path::new(&t))?.to_string_lossy().into_owned())
            }
            t => t,
        };
        Ok(c)
    }

    /// Whether `other` is the same run: equal but for where it writes and how often it
    /// checkpoints (neither changes a bit of the result).
    pub(super) fn same_run(&self, other: &Self) -> bool {
        let plain = |c: &Self| Self {
            output: None,
            fit: Image3dConfig {
                checkpoint_every: 0,
                ..c.fit.clone()
            },
            ..c.clone()
        };
        plain(self) == plain(other)
    }

    /// The resolved config as a run folder's `config.toml` holds it (and a sweep hashes
    /// it): `problem = "image3d"` first, every file named absolutely.
    pub fn resolved_table(&self) -> crate::Result<toml::Table> {
        let mut t = toml::Table::new();
        t.insert(PROBLEM_KEY.into(), PROBLEM.into());
        t.extend(self.with_absolute_paths()?.to_table()?);
        Ok(t)
    }

    /// The config as a TOML table without its `problem` key: the fit's keys and the inputs'.
    pub fn to_table(&self) -> crate::Result<toml::Table> {
        let mut t = toml::Table::try_from(&self.fit).context("writing the image3d config")?;
        let path = |p: &Path| toml::Value::String(p.to_string_lossy().into_owned());
        t.insert("views".into(), path(&self.views));
        if let Some(truth) = &self.truth {
            t.insert("truth".into(), truth.clone().into());
        }
        if let Some(s) = &self.score_views {
            t.insert("score_views".into(), path(s));
        }
        if let Some(o) = &self.output {
            t.insert("output".into(), path(o));
        }
        Ok(t)
    }
}

/// A 3-D code by built-in name ([`BUILT_IN_CODES`]) or file, with its probabilities.
pub fn load_code3(spec: &str) -> crate::Result<(Vec<Affine3>, Option<Vec<f64>>)> {
    match spec {
        "tetrahedron" | "sierpinski-tetrahedron" => Ok((sierpinski_tetrahedron(), None)),
        "fern3d" | "fern-3d" => {
            let (maps, probs) = fern_3d();
            Ok((maps, Some(probs)))
        }
        path => {
            let code = IfsCode::load(path).with_context(|| {
                format!(
                    "reading the 3-D code {path} (or name one of {})",
                    BUILT_IN_CODES.join(", ")
                )
            })?;
            let maps = Affine3::from_code(&code).with_context(|| path.to_owned())?;
            Ok((maps, code.probabilities.clone()))
        }
    }
}
