//! Multi-view inversion runs (`problem = "image3d"`, `ifslab invert3d`): pictures taken
//! around a 3-D fractal, with their cameras, → an IFS code of space, in a run folder.
//!
//! A config names the views folder (`views`: the pictures and a NeRF-style
//! `transforms.json` or a `turntable.json`), optionally the code that drew them (`truth`: a
//! 3-D code file or a built-in name, for the voxel IoU and Chamfer scores) and views to score
//! on that the fit never sees (`score_views`); every other key is the fit's
//! ([`Image3dConfig`]: maps, start, strategy, splat, loss, hull). The folder gets the
//! resolved config (`config.toml`, `problem = "image3d"`), `invert3d.json` (the views'
//! fingerprint, so that a resumed run refuses views that changed), checkpoints and
//! `log.csv` as it goes, then `code.json`, `baseline.json`, `points.ply`, `views.png`,
//! `turntable.png` and `summary.json` ([`write_outputs`]).
//!
//! ```toml
//! problem = "image3d"
//! views = "views/"          # relative to the config file
//! maps = 4
//! iterations = 150
//! truth = "tetrahedron"     # optional
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::Error;
use crate::error::{Context, IoContext, bail, bail_config};
use ifslab::model::IfsCode;
use ifslab::model::map3::{Affine3, fern_3d, sierpinski_tetrahedron};
use ifslab_strategies::problems::image3d::{
    Image3dConfig, Render3dConfig, Summary3d, TurntableFile, Views, load_views, render_code,
    run_image3d_in, write_outputs, write_views,
};
use serde::{Deserialize, Serialize};

use crate::progress::{Progress, ProgressObserver};
use crate::runs::inversion::CONFIG_FILE;
use crate::runs::legs::LegProgress;
use crate::runs::lock::lock_run_dir;
use crate::runs::table::{PROBLEM_KEY, problem_of, read_resolved};

mod config;
use config::Inputs;
pub use config::{BUILT_IN_CODES, INPUTS_FILE, Image3dRunConfig, PROBLEM, load_code3};

/// The views of a run, read from `dir` and named in the error.
fn read_views(dir: &Path, what: &str) -> crate::Result<Views> {
    load_views(dir).with_context(|| format!("reading {what} in {}", dir.display()))
}

/// Runs `cfg` into `dir` (a fresh folder, or with `resume` the folder of a stopped run of
/// the same config, continued to the result it would have reached without stopping),
/// reporting the phases and iterations to `progress`; returns the summary it wrote.
pub fn run(
    cfg: &Image3dRunConfig,
    dir: &Path,
    resume: bool,
    progress: Box<dyn Progress>,
) -> crate::Result<Summary3d> {
    cfg.fit.validate()?;
    let cfg = cfg.with_absolute_paths()?;
    // Refused before the folder is locked (which would create it).
    if resume && !dir.join(CONFIG_FILE).is_file() {
        bail!(
            "{} holds no invert3d run to resume (no {CONFIG_FILE}); start one with \
             `ifslab invert3d VIEWS -o {}`",
            dir.display(),
            dir.display()
        );
    }
    // Inputs that cannot be read are refused before the folder is locked (and made).
    let views = read_views(&cfg.views, "the views")?;
    let truth = cfg.truth.as_deref().map(load_code3).transpose()?;
    let other = match &cfg.score_views {
        Some(d) => Some(read_views(d, "the views to score")?),
        None => None,
    };
    let _lock = lock_run_dir(dir)?;
    let digest = views.digest();
    if resume {
        if !load_run(dir)?.with_absolute_paths()?.same_run(&cfg) {
            bail!(
                "{} holds a run of another config ({CONFIG_FILE}); a resumed run continues its \
                 own (resume it with the config it started with, or `ifslab invert3d --resume \
                 {}`)",
                dir.display(),
                dir.display()
            );
        }
        let inputs = read_inputs(dir)?;
        if digest != inputs.views_digest {
            bail!(
                "the views in {} changed since the run in {} started (their fingerprint was \
                 {}, now {}); a resumed run must fit the pictures it started on",
                cfg.views.display(),
                dir.display(),
                inputs.views_digest,
                digest
            );
        }
    } else {
        if dir.join(CONFIG_FILE).exists() {
            bail!(
                "{} already holds a run ({CONFIG_FILE}); continue it with `ifslab invert3d \
                 --resume {}` or choose another output folder",
                dir.display(),
                dir.display()
            );
        }
        std::fs::create_dir_all(dir).doing("creating", dir)?;
        let resolved = cfg.resolved_table()?;
        ifslab::io::write_atomic(
            &dir.join(CONFIG_FILE),
            toml::to_string_pretty(&resolved)?.as_bytes(),
        )?;
        let inputs = Inputs {
            views_digest: digest,
            views: None,
            truth: None,
            score_views: None,
        };
        ifslab::io::write_atomic(
            &dir.join(INPUTS_FILE),
            serde_json::to_string_pretty(&inputs)?.as_bytes(),
        )?;
    }
    let progress: Arc<dyn Progress> = Arc::from(progress);
    let observer = LegProgress::new(progress.clone(), 0, 1, cfg.fit.iterations);
    let outcome = run_image3d_in(
        &cfg.fit,
        &views,
        dir,
        resume,
        &*progress,
        vec![Box::new(ProgressObserver::new(Box::new(observer)))],
    )
    .map_err(|e| match e {
        ifslab_strategies::Error::Interrupted(_) => Error::from(e).context(format!(
            "continue it with `ifslab invert3d --resume {}`",
            dir.display()
        )),
        e => e.into(),
    })?;
    let truth_ref = truth.as_ref().map(|(m, p)| (m.as_slice(), p.as_deref()));
    Ok(write_outputs(
        dir,
        &cfg.fit,
        &views,
        &outcome,
        truth_ref,
        other.as_ref(),
    )?)
}

fn read_inputs(dir: &Path) -> crate::Result<Inputs> {
    let path = dir.join(INPUTS_FILE);
    let bytes = std::fs::read(&path).io_context(&path, || {
        format!(
            "{} holds no record of its views ({INPUTS_FILE}), so it cannot resume",
            dir.display()
        )
    })?;
    serde_json::from_slice(&bytes).config_context(&path, || format!("reading {}", path.display()))
}

/// The config of the run in `dir`, to resume it: its `config.toml`, or for a folder made
/// before configs named their views (a `config.toml` of the fit's keys alone), that with
/// the inputs its `invert3d.json` kept.
pub fn load_run(dir: &Path) -> crate::Result<Image3dRunConfig> {
    let path = dir.join(CONFIG_FILE);
    if !path.is_file() {
        bail!(
            "{} holds no invert3d run to resume (no {CONFIG_FILE}); start one with \
             `ifslab invert3d VIEWS -o {}`",
            dir.display(),
            dir.display()
        );
    }
    let text = std::fs::read_to_string(&path).doing("reading", &path)?;
    let table: toml::Table = text
        .parse()
        .config_context(&path, || format!("{} is not valid TOML", path.display()))?;
    if table.contains_key(PROBLEM_KEY) {
        let mut table = read_resolved(&path)?;
        let problem = problem_of(&table).to_owned();
        if problem != PROBLEM {
            bail!(
                "{} holds a {problem} run, not an invert3d one (resume it with `ifslab run \
                 --resume`)",
                dir.display()
            );
        }
        table.remove(PROBLEM_KEY);
        let folder = path.parent().unwrap_or(Path::new(""));
        return Ok(Image3dRunConfig::from_table(table, &path)?.relative_to(folder));
    }
    let fit: Image3dConfig = toml::Value::Table(table)
        .try_into()
        .config_context(&path, || {
            format!(
                "{}: not the config of an invert3d run, so nothing to resume",
                path.display()
            )
        })?;
    let inputs = read_inputs(dir)?;
    let views = inputs.views.ok_or_else(|| {
        Error::config(
            dir.join(CONFIG_FILE),
            format!(
                "{}: neither its {CONFIG_FILE} nor its {INPUTS_FILE} names the views it fits, \
                 so it cannot resume",
                dir.display()
            ),
        )
    })?;
    Ok(Image3dRunConfig {
        views,
        truth: inputs.truth,
        score_views: inputs.score_views,
        output: None,
        fit,
    })
}

/// The lines that report a finished run: the hull, the fit, the scores against a truth,
/// the ink of the renders, and the scores on views the fit never saw.
pub fn report(s: &Summary3d) -> String {
    let mut out = format!(
        "hull {} voxels + EM in {:.1} s, {} iterations in {:.1} s; loss baseline {:.5} → \
         fit {:.5} ({})",
        s.hull_voxels,
        s.seconds[0],
        s.iterations,
        s.seconds[1],
        s.loss.baseline,
        s.loss.fit,
        s.returned,
    );
    if let (Some(b), Some(f)) = (&s.baseline, &s.fit) {
        out += &format!(
            "; voxel IoU baseline {:.3} → fit {:.3}, Chamfer {:.4} → {:.4}",
            b.voxel_iou, f.voxel_iou, b.chamfer, f.chamfer
        );
    }
    out += &format!(
        "\nink of the renders over the views': baseline {:.2}, fit {:.2}",
        s.ink_ratio[0], s.ink_ratio[1]
    );
    if let Some(h) = &s.held_out {
        out += &format!(
            "; held-out views {:?}: loss baseline {:.5} → fit {:.5}, ink {:.2} → {:.2}",
            h.views, h.loss[0], h.loss[1], h.ink_ratio[0], h.ink_ratio[1]
        );
    }
    if let Some(h) = &s.other_views {
        out += &format!(
            "\nother views ({}): loss baseline {:.5} → fit {:.5}, ink {:.2} → {:.2}",
            h.views.len(),
            h.loss[0],
            h.loss[1],
            h.ink_ratio[0],
            h.ink_ratio[1]
        );
    }
    out
}

/// Draws `count` turntable views of `side²` of the 3-D code `spec` (a built-in name or a
/// file) into `dir` with the library's multi-view splat (σ 0.8 at 1×, 400 trajectories, 25°
/// elevation, a pinhole of 50° at distance 4): the views the tests and the README's numbers
/// invert.
pub fn render_turntable(
    spec: &str,
    dir: &Path,
    count: usize,
    side: usize,
    seed: u64,
) -> crate::Result<()> {
    let (maps, probs) = load_code3(spec)?;
    let table = TurntableFile {
        views: count,
        elevation_deg: 25.0,
        distance: 4.0,
        fov_x_deg: Some(50.0),
        orthographic_extent: None,
        files: None,
    };
    let cameras = table.cameras(side, side)?;
    let mut render = Render3dConfig::default().multi_view((side, side));
    render.supersample = 1;
    render.sigma = 0.8;
    render.game.trajectories = 400;
    let planes = render_code(&maps, &cameras, &render, probs.as_deref(), seed)?;
    write_views(dir, &table, &planes)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::config::INPUT_KEYS;
    use super::*;

    #[test]
    fn the_inputs_keys_are_not_the_fits() {
        let fit = toml::Table::try_from(Image3dConfig::default()).unwrap();
        for k in INPUT_KEYS {
            assert!(!fit.contains_key(k), "{k}");
        }
    }

    #[test]
    fn a_config_reads_back_from_its_table_with_files_from_its_folder() {
        let text = "views = \"v\"\ntruth = \"fern3d\"\nscore_views = \"w\"\nmaps = 3\n\
                    start = \"code\"\nstart_code = \"c.json\"\n";
        let table: toml::Table = text.parse().unwrap();
        let c = Image3dRunConfig::from_table(table, Path::new("/a/b/x.toml"))
            .unwrap()
            .relative_to(Path::new("/a/b"));
        assert_eq!(c.views, Path::new("/a/b/v"));
        assert_eq!(c.score_views.as_deref(), Some(Path::new("/a/b/w")));
        assert_eq!(c.fit.start_code.as_deref(), Some(Path::new("/a/b/c.json")));
        assert_eq!(
            c.truth.as_deref(),
            Some("fern3d"),
            "a built-in name stays a name"
        );
        assert_eq!(c.fit.maps, 3);
        let back =
            Image3dRunConfig::from_table(c.to_table().unwrap(), Path::new("y.toml")).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn a_config_without_views_or_with_an_unknown_key_is_refused_by_name() {
        for (text, want) in [
            ("maps = 3\n", "needs `views`"),
            ("views = \"v\"\nmapz = 3\n", "mapz"),
            ("views = 3\n", "`views` must be a string"),
            ("views = \"v\"\nmaps = 0\n", "maps"),
        ] {
            let e = Image3dRunConfig::from_table(text.parse().unwrap(), Path::new("x.toml"))
                .unwrap_err();
            assert!(format!("{e:#}").contains(want), "{text}: {e:#}");
        }
    }
}
