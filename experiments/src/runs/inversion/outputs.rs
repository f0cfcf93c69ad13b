//! What a finished image run shows: the recovered code file, its render and zoom strip, the
//! loss curve, its metrics against the ground truth, and its score against the code that
//! drew the target — each drawn from the run's result as its model gives it
//! ([`Recovered`]), so a map family that is not affine shows the same files (without the
//! affine code file: its fit file is what it is drawn again from).

use super::*;

/// The recovered code's 1×–64× views ([`zoom_strip`]).
pub(super) const ZOOM_STRIP_FILE: &str = "zoom_strip.png";

/// Side of the full views a recovered code and its truth are compared at.
pub const TRUTH_SIZE: usize = 256;

/// A recovered code against the code that drew its target: both drawn by the evaluation
/// renderer ([`EVAL_POINTS`] points, [`EVAL_SUPERSAMPLE`]² binary supersampling) at
/// [`TRUTH_SIZE`]², each in its own fitted window — a suite's full view — and compared with
/// the paper's metrics (12.5 % border crop). The picture's framing, colours, noise and file
/// format play no part.
#[derive(Clone, Debug, Serialize)]
pub struct TruthScore {
    /// IoU of the `> 0` masks.
    pub iou: f64,
    /// F1 (Dice) of the `> 0` masks.
    pub f1: f64,
    /// PSNR on the foreground pixels.
    pub psnr: f64,
    /// SSIM on the foreground pixels.
    pub ssim: f64,
}

/// [`TruthScore`] of the recovered `fit` against the code `spec` names; writes the truth's
/// full view as `truth.png` into `dir`.
pub fn truth_score(
    spec: &str,
    fit: &dyn Recovered,
    seed: u64,
    dir: &Path,
) -> crate::Result<TruthScore> {
    let code = resolve_code(spec).with_context(|| format!("`target.truth` {spec}"))?;
    let truth_maps = code
        .affine2()
        .with_context(|| format!("`target.truth` {spec} must be a 2-D code"))?;
    let cfg = eval_config(TRUTH_SIZE, seed);
    let truth = render(&truth_maps, &code.evaluation_probabilities()?, &cfg, None)?;
    truth.save_png(&dir.join("truth.png"), BitDepth::Eight, false)?;
    let ours = fit.render(&cfg)?;
    let m = paper_metrics::<f32>(&ours.values, &truth.values, TRUTH_SIZE, TRUTH_SIZE, None)?;
    Ok(TruthScore {
        iou: m.iou,
        f1: m.f1,
        psnr: m.psnr,
        ssim: m.ssim,
    })
}

/// Code file, final render, zoom strip (where `strip`), loss plot; returns the render's
/// metrics and, when LPIPS is not among them, why.
pub(super) fn write_outputs(
    cfg: &InversionConfig,
    dir: &Path,
    out: &InversionOutcome,
    target: &[f32],
    strip: bool,
) -> crate::Result<(ImageMetrics, Option<String>)> {
    let size = cfg.target.size;
    let fit = out.result.as_ref();
    if !fit.contractive() {
        crate::error::bail!(
            "the recovered code failed validation: a map of family `{}` does not contract",
            cfg.model.family
        );
    }
    let final_render = fit.render(&eval_config(size, cfg.seed))?;
    let mut meta = serde_json::Map::new();
    meta.insert("strategy".into(), cfg.strategy.name().into());
    meta.insert("iterations".into(), out.iterations.into());
    meta.insert("final_loss".into(), out.final_loss.into());
    meta.insert("seed".into(), cfg.seed.into());
    // θ with the model that decodes it, for every family; the affine code file beside it
    // where the maps are affine (what other programs read).
    FitFile {
        model: cfg.model.clone(),
        theta: out.theta.clone(),
        framing: Some(final_render.stats.window),
        meta: meta.clone(),
    }
    .save(&dir.join(FIT_FILE))?;
    if let Some(maps) = fit.affine() {
        let mut code = IfsCode::from_affine2(Some("recovered"), maps)
            .context("the recovered code failed validation")?;
        code.framing = Some(final_render.stats.window);
        code.meta = meta;
        code.save(dir.join("code.json"))?;
    }
    final_render.save_png(&dir.join("render.png"), BitDepth::Eight, false)?;
    let truth = ground_truth(cfg, target)?;
    if cfg.target.code.is_some() || cfg.target.suite.is_some() {
        save_square_grey(&dir.join("truth.png"), &truth, size)?;
    }
    let (net, lpips_metric_note) = lpips_for_metrics(size)?;
    let metrics = paper_metrics::<f32>(&final_render.values, &truth, size, size, net.as_ref())?;
    if strip {
        zoom_strip(
            fit,
            &final_render.stats.window,
            &dir.join(ZOOM_STRIP_FILE),
            cfg.seed,
        )?;
    }
    loss_plot(&out.log, &dir.join("loss.png"))?;
    Ok((metrics, lpips_metric_note))
}

/// The result of the finished run in `dir`, as it was recovered.
pub(super) struct RunResult {
    /// The maps, drawable.
    pub(super) fit: Box<dyn Recovered>,
    /// The window of the run's evaluation render, where the file keeps it.
    pub(super) framing: Option<Window>,
    /// The seed of the run that found it (`cfg.seed` where the file does not say: a best-of
    /// run keeps one of several runs at seeds of their own).
    pub(super) seed: u64,
    /// The file it was read from.
    pub(super) file: PathBuf,
}

/// The recovered result of the run in `dir`: its affine code file (`code.json`, what
/// affine runs and run folders from before fit files keep), or else its fit file (θ and
/// the model family that decodes it, `fit.json`).
pub(super) fn recovered_code(dir: &Path, seed: u64) -> crate::Result<RunResult> {
    let code_path = dir.join("code.json");
    if code_path.is_file() || !dir.join(FIT_FILE).is_file() {
        let code = IfsCode::load(&code_path)
            .with_context(|| format!("loading the recovered code {}", code_path.display()))?;
        let maps = code
            .affine2()
            .with_context(|| format!("{} must be a 2-D code", code_path.display()))?;
        let fit = Fitted::with_probabilities(maps, code.evaluation_probabilities()?)?;
        let seed = code
            .meta
            .get("seed")
            .and_then(|v| v.as_u64())
            .unwrap_or(seed);
        return Ok(RunResult {
            fit: Box::new(fit),
            framing: code.framing,
            seed,
            file: code_path,
        });
    }
    let fit_path = dir.join(FIT_FILE);
    let file = FitFile::load(&fit_path)?;
    let fit = file
        .recovered()
        .with_context(|| format!("decoding the fit {}", fit_path.display()))?;
    Ok(RunResult {
        fit,
        framing: file.framing,
        seed: file.seed().unwrap_or(seed),
        file: fit_path,
    })
}

/// Draws the zoom strip of the finished run in `dir` from its result (its framing and
/// seed), as [`write_outputs`] would have.
pub(super) fn draw_zoom_strip(dir: &Path) -> crate::Result<()> {
    let r = recovered_code(dir, 0)?;
    let window = r
        .framing
        .with_context(|| format!("{} has no framing", r.file.display()))?;
    zoom_strip(r.fit.as_ref(), &window, &dir.join(ZOOM_STRIP_FILE), r.seed)
}

/// Writes a `size × size` grey picture (values in [0, 1]) as an 8-bit PNG.
pub(super) fn save_square_grey(path: &Path, values: &[f32], size: usize) -> crate::Result<()> {
    save_grey_png(
        path,
        values,
        size as u32,
        size as u32,
        BitDepth::Eight,
        false,
    )?;
    Ok(())
}

/// Draws a finished run's pictures again from its config and its result (`code.json`, or
/// `fit.json` for a family that is not affine) — a folder
/// written back from a pack, say ([`crate::sweep::pack`]): `render.png`, `target.png`,
/// `truth.png` (code and suite targets, or the `target.truth` code), `zoom_strip.png`, and
/// `loss.png` where the folder has a `log.csv`. The renders are seeded as the run's were, so
/// they are its pictures. Returns the files written.
pub fn redraw_pictures(cfg: &InversionConfig, dir: &Path) -> crate::Result<Vec<PathBuf>> {
    let size = cfg.target.size;
    let RunResult { fit, seed, .. } = recovered_code(dir, cfg.seed)?;
    let fit = fit.as_ref();
    let mut written = Vec::new();
    let final_render = fit.render(&eval_config(size, seed))?;
    final_render.save_png(&dir.join("render.png"), BitDepth::Eight, false)?;
    written.push(dir.join("render.png"));
    let target = run_target(cfg, dir)?.values;
    save_square_grey(&dir.join("target.png"), &target, size)?;
    written.push(dir.join("target.png"));
    if cfg.target.code.is_some() || cfg.target.suite.is_some() {
        let truth = ground_truth(cfg, &target)?;
        save_square_grey(&dir.join("truth.png"), &truth, size)?;
        written.push(dir.join("truth.png"));
    }
    if let Some(spec) = &cfg.target.truth {
        truth_score(spec, fit, seed, dir)?;
        written.push(dir.join("truth.png"));
    }
    zoom_strip(
        fit,
        &final_render.stats.window,
        &dir.join(ZOOM_STRIP_FILE),
        seed,
    )?;
    written.push(dir.join(ZOOM_STRIP_FILE));
    let log = dir.join(LOG_FILE);
    if log.is_file() {
        loss_plot(&log, &dir.join("loss.png"))?;
        written.push(dir.join("loss.png"));
    }
    written.dedup();
    Ok(written)
}

/// The LPIPS network for scoring `size²` renders, or why there is none.
pub(super) fn lpips_for_metrics(size: usize) -> crate::Result<(Option<Lpips>, Option<String>)> {
    let rect = border_crop_rect(size, size, EVAL_BORDER_FRACTION)?;
    if rect.2.min(rect.3) < LPIPS_MIN_SIDE {
        return Ok((
            None,
            Some(format!(
                "the {}² evaluation crop is below LPIPS's {LPIPS_MIN_SIDE}² minimum",
                rect.2
            )),
        ));
    }
    Ok(match Lpips::try_load_default()? {
        Some(net) => (Some(net), None),
        None => (
            None,
            Some(format!(
                "no LPIPS weights at {}",
                default_lpips_weights_path().display()
            )),
        ),
    })
}

/// Renders 1×, 4×, 16×, 64× views of `fit` around a point with detail
/// ([`Recovered::detail_point`]) side by side, with captions.
pub fn zoom_strip(fit: &dyn Recovered, base: &Window, path: &Path, seed: u64) -> crate::Result<()> {
    const PANEL: u32 = 256;
    const CAPTION: u32 = 28;
    let center = fit.detail_point().unwrap_or_else(|| base.center());
    let factors = [1.0, 4.0, 16.0, 64.0];
    let mut panels = Vec::new();
    for &f in &factors {
        let cfg = RenderConfig {
            width: PANEL,
            height: PANEL,
            points: 2_000_000,
            supersample: 2,
            seed,
            view: View::Window(*base),
            zoom: Some(Zoom {
                factor: f,
                center: Some(if f == 1.0 { base.center() } else { center }),
            }),
            min_hits: 1_000_000,
            max_points: 200_000_000,
            // The zoomed panels' points come through the code's words: the first round
            // fills them, where the plain game needed up to 64² times the points.
            deep_zoom: true,
            ..RenderConfig::default()
        };
        panels.push(fit.render(&cfg)?);
    }
    let w = PANEL * 4 + 3 * 6;
    let h = PANEL + CAPTION;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    for (i, p) in panels.iter().enumerate() {
        let x0 = i as u32 * (PANEL + 6);
        for y in 0..PANEL {
            for x in 0..PANEL {
                let v = (p.values[(y * PANEL + x) as usize].clamp(0.0, 1.0) * 255.0) as u8;
                let o = (((y + CAPTION) * w + x0 + x) * 3) as usize;
                buf[o..o + 3].copy_from_slice(&[v, v, v]);
            }
        }
    }
    ensure_font();
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        for (i, f) in factors.iter().enumerate() {
            let x = i as i32 * (PANEL as i32 + 6) + 8;
            root.draw(&Text::new(
                format!("{f}×"),
                (x, 4),
                ("sans-serif", 20).into_font().color(&BLACK),
            ))?;
        }
        root.present()?;
    }
    crate::plot::write_rgb_png(path, (w, h), &buf)?;
    Ok(())
}

/// Plots `loss` and each logged term of a run's CSV log against the iteration.
pub fn loss_plot(log: &Path, out: &Path) -> crate::Result<()> {
    let text = std::fs::read_to_string(log).doing("reading", log)?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().context("empty log")?.split(',').collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .filter(|r: &Vec<f64>| r.len() == header.len())
        .collect();
    let mut series = Vec::new();
    for (c, name) in header.iter().enumerate().skip(1) {
        if *name == "seconds" {
            continue;
        }
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| (r[0], r[c]))
            .filter(|p| p.1.is_finite() && p.1 > 0.0)
            .collect();
        if !pts.is_empty() {
            series.push(Series { name, points: pts });
        }
    }
    line_chart(out, "loss", "iteration", "value", &series, true)
}
