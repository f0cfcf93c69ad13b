//! `ifslab suite make`: codes, views and ground-truth renders.

use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext, bail};
use ifslab::chaos::ChaosGame;
use ifslab::chaos::{mix_seed, trajectory_rng};
use ifslab::model::random::sample_code;
use ifslab::model::{IfsCode, Window};
use ifslab::progress::Progress;
use ifslab::render::image_io::{BitDepth, save_grey_png};
use ifslab::render::{Raster, RenderConfig, View, Zoom, render};
use rand::Rng;

use super::spec::{CodeEntry, Manifest, SuiteSpec, ViewEntry};
use super::{FORMAT, MANIFEST};

const SPEC_FILE: &str = "spec.json";
const VIEWS_FILE: &str = "views.json";

/// Makes (or completes) the suite `spec` in `dir`; `progress` counts codes.
pub fn make(spec: &SuiteSpec, dir: &Path, progress: &dyn Progress) -> crate::Result<Manifest> {
    spec.validate()?;
    std::fs::create_dir_all(dir).doing("creating", dir)?;
    let spec_path = dir.join(SPEC_FILE);
    if spec_path.is_file() {
        let old: SuiteSpec = serde_json::from_str(&std::fs::read_to_string(&spec_path)?)
            .config_context(&spec_path, || format!("parsing {}", spec_path.display()))?;
        if old != *spec {
            bail!(
                "{} holds a different suite ({}); give another folder",
                dir.display(),
                serde_json::to_string(&old)?
            );
        }
    } else {
        ifslab::io::write_atomic(&spec_path, serde_json::to_string_pretty(spec)?.as_bytes())?;
    }
    progress.start("suite", spec.codes as u64);
    let mut codes = Vec::with_capacity(spec.codes);
    for index in 0..spec.codes {
        let folder = dir.join(format!("{index:03}"));
        let views = folder.join(VIEWS_FILE);
        let entry = if views.is_file() {
            serde_json::from_str(&std::fs::read_to_string(&views)?)
                .config_context(&views, || format!("parsing {}", views.display()))?
        } else {
            make_code(spec, dir, index)?
        };
        codes.push(entry);
        progress.inc(1);
    }
    progress.finish();
    let manifest = Manifest {
        format: FORMAT.into(),
        spec: spec.clone(),
        codes,
    };
    ifslab::io::write_atomic(
        &dir.join(MANIFEST),
        serde_json::to_string_pretty(&manifest)?.as_bytes(),
    )?;
    Ok(manifest)
}

/// Draws code `index`, renders its views into `.NNN.partial/` and renames it.
fn make_code(spec: &SuiteSpec, dir: &Path, index: usize) -> crate::Result<CodeEntry> {
    let name = format!("{index:03}");
    let mut rng = trajectory_rng(spec.seed ^ 0x5017_E5EE_D000_0000, index as u64);
    let [lo, hi] = spec.maps;
    let n = rng.random_range(lo..=hi);
    let seed: u64 = rng.random();
    let sampled = sample_code(n, seed)?;
    let mut code = IfsCode::from_affine2(Some(&format!("suite-{name}")), &sampled.maps)?;
    code.meta
        .insert("sampler".into(), "anderson-farrell".into());
    code.meta.insert("seed".into(), seed.into());
    let probs = code.evaluation_probabilities()?;
    let render_seed = mix_seed(spec.seed, index as u64);

    let partial = dir.join(format!(".{name}.partial"));
    if partial.exists() {
        std::fs::remove_dir_all(&partial).doing("removing", &partial)?;
    }
    std::fs::create_dir_all(&partial)?;
    code.save(partial.join("code.json"))?;

    let full = render(
        &sampled.maps,
        &probs,
        &spec.render_config(render_seed),
        None,
    )?;
    let window = full.stats.window;
    let mut views = vec![save_view(
        spec, &partial, &name, "full", 1.0, [0.5; 2], &full,
    )?];
    // Patch centres are points of the attractor (so every patch shows some of it), drawn
    // from a short seeded chaos game; factors are uniform in [2, max_zoom].
    let pool = ChaosGame {
        trajectories: 64,
        length: 300,
        warmup: 100,
        start_half_width: 1.0,
        seed: render_seed ^ 0xCE47E5,
    }
    .generate(&sampled.maps, &probs)?
    .data;
    for k in 0..spec.patches {
        let factor = rng.random_range(2.0..=spec.max_zoom);
        let p = pool[rng.random_range(0..pool.len())];
        let size = window.size();
        let center = [
            (p[0] - window.min[0]) / size[0],
            (p[1] - window.min[1]) / size[1],
        ];
        let raster = render(
            &sampled.maps,
            &probs,
            &view_config(spec, &window, factor, center, render_seed),
            None,
        )?;
        views.push(save_view(
            spec,
            &partial,
            &name,
            &format!("zoom{}", k + 1),
            factor,
            center,
            &raster,
        )?);
    }
    let entry = CodeEntry {
        index,
        maps: n,
        seed,
        code: PathBuf::from(&name).join("code.json"),
        render_seed,
        window,
        views,
    };
    ifslab::io::write_atomic(
        &partial.join(VIEWS_FILE),
        serde_json::to_string_pretty(&entry)?.as_bytes(),
    )?;
    std::fs::rename(&partial, dir.join(&name)).doing("finishing", &dir.join(&name))?;
    Ok(entry)
}

/// Renders the view of `maps` at `factor` around `center` (fractions of `window`), until
/// the tier's point count lands in it or 64 times that count has been generated.
pub(super) fn view_config(
    spec: &SuiteSpec,
    window: &Window,
    factor: f64,
    center: [f64; 2],
    seed: u64,
) -> RenderConfig {
    let size = window.size();
    let world = [
        window.min[0] + center[0] * size[0],
        window.min[1] + center[1] * size[1],
    ];
    RenderConfig {
        view: View::Window(*window),
        zoom: Some(Zoom {
            factor,
            center: Some(world),
        }),
        ..spec.render_config(seed)
    }
}

fn save_view(
    spec: &SuiteSpec,
    folder: &Path,
    code: &str,
    name: &str,
    factor: f64,
    center: [f64; 2],
    raster: &Raster,
) -> crate::Result<ViewEntry> {
    let file = format!("{name}.png");
    save_grey_png(
        &folder.join(&file),
        &raster.values,
        raster.width,
        raster.height,
        BitDepth::Sixteen,
        false,
    )?;
    Ok(ViewEntry {
        name: name.into(),
        factor,
        center,
        truth: PathBuf::from(code).join(file),
        points_in_window: raster.stats.points_in_window,
        complete: raster.stats.points_in_window >= spec.tier.points(),
    })
}
