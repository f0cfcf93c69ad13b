//! The target an image run fits, prepared from a config (a picture framed, or a code drawn)
//! and stored in the run's folder, and the ground truth the run is scored against.

use super::*;

/// The framed target image for a config: an image file loaded and framed, or a code drawn
/// by the evaluation renderer with the differentiable renderer's supersampling (so that the
/// target's grey levels — the covered fraction of each pixel — are on the splat's scale) and
/// about 200 points per pixel (2 M to 50 M), framed the same way. What a run is *scored*
/// against is [`ground_truth`].
pub fn prepare_target(cfg: &InversionConfig) -> crate::Result<Image> {
    let size = cfg.target.size;
    if let Some(path) = &cfg.target.image {
        return load_target(path, size, cfg.target.polarity)
            .with_context(|| format!("preparing the target {}", path.display()));
    }
    let (maps, probs) = target_code(cfg)?;
    let points = (200 * (size * size) as u64).clamp(2_000_000, EVAL_POINTS);
    let rc = RenderConfig {
        points,
        supersample: cfg.renderer.supersample as u32,
        ..eval_config(size, cfg.seed)
    };
    Ok(Image::square(
        size,
        render(&maps, &probs, &rc, None)?.image.values,
    )?)
}

/// The maps and evaluation probabilities of a config's target code (a code, or a suite's).
pub(super) fn target_code(cfg: &InversionConfig) -> crate::Result<(Vec<Affine2>, Vec<f64>)> {
    let code = match (&cfg.target.suite, cfg.target.index) {
        (Some(dir), Some(index)) => {
            let manifest = crate::suite::load(dir)?;
            let path = dir.join(&manifest.entry(index)?.code);
            IfsCode::load(&path).with_context(|| format!("loading {}", path.display()))?
        }
        _ => {
            let spec = cfg
                .target
                .code
                .as_deref()
                .context("the target is an image, not a code")?;
            resolve_code(spec)?
        }
    };
    let maps = code.affine2().context("the target code must be 2-D")?;
    let probs = code.evaluation_probabilities()?;
    Ok((maps, probs))
}

/// What a run is scored against: for a code target, its render at the paper's evaluation
/// setting ([`EVAL_POINTS`] points, [`EVAL_SUPERSAMPLE`]² binary supersampling); for an image,
/// the framed image itself.
pub fn ground_truth(cfg: &InversionConfig, target: &[f32]) -> crate::Result<Vec<f32>> {
    if cfg.target.image.is_some() {
        return Ok(target.to_vec());
    }
    let (maps, probs) = target_code(cfg)?;
    Ok(
        render(&maps, &probs, &eval_config(cfg.target.size, cfg.seed), None)?
            .image
            .values,
    )
}

/// The target a run in `dir` optimises against: the framed copy the run stored when it
/// started (exactly the same values, whatever the working directory and whether the original
/// file still exists); for run folders from before that copy existed, prepared again from the
/// config.
pub fn run_target(cfg: &InversionConfig, dir: &Path) -> crate::Result<Image> {
    let stored = dir.join(FRAMED_TARGET_FILE);
    if stored.is_file() {
        return Ok(load_framed_target(&stored, cfg.target.size)?);
    }
    prepare_target(cfg).with_context(|| {
        format!(
            "{} has no stored target ({FRAMED_TARGET_FILE}), so it was prepared again from the config",
            dir.display()
        )
    })
}

pub(super) fn eval_config(size: usize, seed: u64) -> RenderConfig {
    RenderConfig {
        width: size as u32,
        height: size as u32,
        points: EVAL_POINTS,
        supersample: EVAL_SUPERSAMPLE,
        seed,
        ..RenderConfig::default()
    }
}

/// A framed target and how the picture was read (none for a code or suite target).
pub(super) type Framed<'a> = (&'a Image, Option<&'a TargetReading>);

/// Fills a fresh run folder: the resolved config, the framed target (`framed`, else
/// prepared from the config) and how the picture was read; returns the target.
pub(super) fn new_run_dir(
    cfg: &InversionConfig,
    dir: &Path,
    framed: Option<Framed>,
) -> crate::Result<Image> {
    let size = cfg.target.size;
    let (target, reading) = match (framed, &cfg.target.image) {
        (Some((t, r)), _) => (t.clone(), r.cloned()),
        (None, Some(path)) => {
            let f = load_framed_picture_with(path, size, cfg.target.polarity, cfg.target_cells())
                .with_context(|| format!("preparing the target {}", path.display()))?;
            (f.image, Some(f.reading))
        }
        (None, None) => (prepare_target(cfg)?, None),
    };
    std::fs::create_dir_all(dir).doing("creating", dir)?;
    if let Some(r) = reading {
        r.save(&dir.join(TARGET_READING_FILE))?;
    }
    let resolved = cfg.with_absolute_paths()?;
    ifslab::io::write_atomic(&dir.join(CONFIG_FILE), resolved.to_toml().as_bytes())?;
    save_framed_target(&dir.join(FRAMED_TARGET_FILE), &target)?;
    Ok(target)
}
