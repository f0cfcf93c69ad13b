//! Reading a points config (TOML, file names relative to it), resolving it for the run folder, validating it with errors that name the key, and the EM config of each fit.

use super::*;

impl PointsConfig {
    /// A config from a parsed TOML table (without the `problem` key), relative file names
    /// read from `origin`'s folder: what `RunConfig` and a resumed run read a table with.
    pub fn from_table(table: toml::Table, origin: &Path) -> crate::Result<Self> {
        let text = toml::to_string(&table).context("re-serialising the config")?;
        Ok(PointsConfig::from_toml(&text, origin)?
            .relative_to(origin.parent().unwrap_or(Path::new(""))))
    }

    /// Parses TOML text (without the `problem` key) and validates it; `origin` names the
    /// text in errors.
    pub fn from_toml(text: &str, origin: &Path) -> crate::Result<Self> {
        let invalid = || format!("{} is not a valid points config", origin.display());
        let cfg: PointsConfig = toml::from_str(text).config_context(origin, invalid)?;
        cfg.validate().config_context(origin, invalid)?;
        Ok(cfg)
    }

    /// The same config with its relative file names (point file, `ifs:` code file, truth
    /// code file, `save_data`) read as relative to `dir`, the folder of its config file.
    pub fn relative_to(mut self, dir: &Path) -> Self {
        let file_spec = |spec: &str| -> Option<String> {
            let p = Path::new(spec);
            (p.is_relative() && dir.join(p).is_file())
                .then(|| dir.join(p).to_string_lossy().into_owned())
        };
        if let Some(code) = self.data.strip_prefix("ifs:") {
            if let Some(s) = file_spec(code) {
                self.data = format!("ifs:{s}");
            }
        } else if Path::new(&self.data).is_relative() && !self.data.is_empty() {
            self.data = dir.join(&self.data).to_string_lossy().into_owned();
        }
        if let Some(t) = &self.truth
            && let Some(s) = file_spec(t)
        {
            self.truth = Some(s);
        }
        for p in [&mut self.save_data, &mut self.output]
            .into_iter()
            .flatten()
        {
            if p.is_relative() {
                *p = dir.join(&*p);
            }
        }
        self
    }

    /// Every file it names made absolute (against the working directory) and every choice
    /// written out: what a run folder's `config.toml` holds.
    pub fn resolved(&self) -> crate::Result<Self> {
        let abs = |p: &Path| std::path::absolute(p).doing("resolving", p);
        let file_spec = |spec: &str| -> crate::Result<String> {
            let p = Path::new(spec);
            Ok(if p.is_file() {
                abs(p)?.to_string_lossy().into_owned()
            } else {
                spec.to_string()
            })
        };
        let mut c = self.clone();
        c.data = match self.data.strip_prefix("ifs:") {
            Some(code) => format!("ifs:{}", file_spec(code)?),
            None => abs(Path::new(&self.data))?.to_string_lossy().into_owned(),
        };
        c.truth = self.truth.as_deref().map(file_spec).transpose()?;
        c.save_data = self.save_data.as_deref().map(abs).transpose()?;
        c.output = self.output.as_deref().map(abs).transpose()?;
        let (s, b, r, e, rc, u) = self.choices();
        c.preselect_schedule = Some(s);
        c.preselect_by = Some(b);
        c.reorient = Some(r);
        c.reorient_every = Some(e);
        c.recentre = Some(rc);
        c.update = Some(u);
        c.reflections = Some(self.reflections());
        c.words = Some(self.words());
        c.runs = Some(self.runs());
        c.keep = Some(self.keep());
        c.trim_outliers = Some(self.trim_outliers());
        Ok(c)
    }

    /// Whether isolated points are left out (off unless asked for).
    pub fn trim_outliers(&self) -> bool {
        self.trim_outliers.unwrap_or(false)
    }

    /// Whether the maps may reflect, as given or by the recipe.
    pub fn reflections(&self) -> bool {
        self.reflections
            .unwrap_or_else(|| !self.paper && MStepConfig::default().reflections)
    }

    /// Independent runs, as given or by default ([`default_runs`]).
    pub fn runs(&self) -> usize {
        self.runs
            .unwrap_or_else(|| if self.paper { 1 } else { default_runs(self.k) })
    }

    /// Which run is kept, as given or by the recipe; one run is kept whatever the rule.
    pub fn keep(&self) -> KeepBy {
        if self.runs() == 1 {
            return KeepBy::Likelihood;
        }
        self.keep.unwrap_or(if self.paper {
            KeepBy::Likelihood
        } else {
            KeepBy::Closeness
        })
    }

    /// Whether the word search runs, as given or by the recipe.
    pub fn words(&self) -> bool {
        self.words.unwrap_or(!self.paper)
    }

    /// The six choices `paper` fixes, as given or by default.
    fn choices(&self) -> Choices {
        let d = choices(self.paper, self.k, self.depth);
        (
            self.preselect_schedule.unwrap_or(d.0),
            self.preselect_by.unwrap_or(d.1),
            self.reorient.unwrap_or(d.2),
            self.reorient_every.unwrap_or(d.3),
            self.recentre.unwrap_or(d.4),
            self.update.unwrap_or(d.5),
        )
    }

    /// Checks every field before anything runs; errors name the field and say what to change.
    pub fn validate(&self) -> crate::Result<()> {
        if self.data.is_empty() {
            bail!(
                "`data` is missing: name a point cloud (.csv, .txt or .npy) or `ifs:NAME` to sample one from a code"
            );
        }
        if self.data.starts_with("ifs:") && self.points == 0 {
            bail!("`points` must be at least 1 to sample `{}`", self.data);
        }
        if self.runs == Some(0) {
            bail!("`runs` must be at least 1");
        }
        if !(0.0..1.0).contains(&self.heldout) {
            bail!(
                "`heldout` is the share of points held out: give a number in [0, 1), got {}",
                self.heldout
            );
        }
        if !self.sweep_pool.is_empty() {
            if self.repeats == 0 {
                bail!("`repeats` must be at least 1");
            }
            if let Some(p) = self.sweep_pool.iter().find(|&&p| p == 0) {
                bail!("`sweep_pool` sizes must be at least 1, got {p}");
            }
        }
        if self.paper {
            let paper = choices(true, self.k, self.depth);
            let given = [
                (
                    "preselect_schedule",
                    self.preselect_schedule.map(|v| v != paper.0),
                ),
                ("preselect_by", self.preselect_by.map(|v| v != paper.1)),
                ("reorient", self.reorient.map(|v| v != paper.2)),
                ("reorient_every", self.reorient_every.map(|v| v != paper.3)),
                ("recentre", self.recentre.map(|v| v != paper.4)),
                ("update", self.update.map(|v| v != paper.5)),
                ("reflections", self.reflections),
                ("words", self.words),
                ("trim_outliers", self.trim_outliers),
            ];
            if let Some((name, _)) = given.iter().find(|(_, differs)| *differs == Some(true)) {
                bail!(
                    "`{name}` conflicts with `paper = true`, which fixes it to the paper's choice; \
                     leave `{name}` out or set `paper = false`"
                );
            }
        }
        for pool in self.sweep_pool.iter().copied().chain([self.pool]) {
            self.em_config(self.seed, pool).validate()?;
        }
        Ok(())
    }

    /// The EM config of one fit.
    pub fn em_config(&self, seed: u64, pool: usize) -> EmConfig {
        let (schedule, by, rotations, every, recentre, update) = self.choices();
        let base = if self.paper {
            EmConfig::paper()
        } else {
            EmConfig::default()
        };
        EmConfig {
            components: self.k,
            depth: self.depth,
            iterations: self.iterations,
            batch_size: self.batch,
            pool,
            preselect_depth: self.preselect_depth,
            preselect_iterations: self.preselect_iterations,
            curriculum: schedule == PreselectSchedule::Curriculum,
            preselect_by: by,
            reorient: ReorientConfig {
                rotations,
                every,
                words: self.words(),
            },
            recentre,
            mstep: MStepConfig {
                update,
                reflections: self.reflections(),
                ..base.mstep.clone()
            },
            eval_points: self.eval_points,
            eval_every: self.eval_every,
            seed,
            ..base
        }
    }

    /// TOML text of the resolved config, `problem = "points"` first: a run folder's
    /// `config.toml`, which `ifslab run` reads back as the same run.
    pub fn to_toml(&self) -> crate::Result<String> {
        Ok(format!(
            "{PROBLEM_KEY} = \"points\"\n{}",
            toml::to_string_pretty(&self.resolved()?)?
        ))
    }
}
