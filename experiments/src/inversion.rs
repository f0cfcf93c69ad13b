//! Running an image inversion from the command line and writing what a user looks at: the
//! recovered code, renders, a zoom strip, the loss curve, a summary.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use ifslab::metrics::{ImageMetrics, paper_metrics};
use ifslab::model::{Affine2, Framing, IfsCode};
use ifslab::render::image_io::{BitDepth, save_grey_png};
use ifslab::render::{RenderConfig, View, Zoom, render};
use ifslab_strategies::image::{InversionConfig, InversionOutcome, load_target, run_inversion};
use plotters::prelude::*;
use serde::Serialize;

use crate::cmd::resolve_code;
use crate::plot::{Series, ensure_font, line_chart};
use crate::progress::{ProgressObserver, bar};

/// The resolved config inside a run folder.
pub const CONFIG_FILE: &str = "config.toml";

/// The framed target image for a config: an image file loaded and framed, or a code rendered
/// with the evaluation renderer (coverage, 4× supersampling) framed the same way.
pub fn prepare_target(cfg: &InversionConfig) -> anyhow::Result<Vec<f32>> {
    let size = cfg.target.size;
    if let Some(path) = &cfg.target.image {
        return load_target(path, size, cfg.target.polarity)
            .with_context(|| format!("preparing the target {}", path.display()));
    }
    let spec = cfg
        .target
        .code
        .as_deref()
        .expect("validated: image or code");
    let code = resolve_code(spec)?;
    let maps = code.affine2().context("the target code must be 2-D")?;
    let probs = code.evaluation_probabilities()?;
    let r = render(&maps, &probs, &eval_config(size, 2_000_000, cfg.seed), None)?;
    Ok(r.values)
}

fn eval_config(size: usize, points: u64, seed: u64) -> RenderConfig {
    RenderConfig {
        width: size as u32,
        height: size as u32,
        points,
        supersample: 4,
        seed,
        ..RenderConfig::default()
    }
}

/// What `summary.json` holds.
#[derive(Serialize)]
pub struct Summary {
    /// Strategy name.
    pub strategy: String,
    /// Iterations completed.
    pub iterations: u64,
    /// Wall-clock seconds of the optimisation (this process).
    pub seconds: f64,
    /// Loss at the last iteration.
    pub final_loss: f64,
    /// IoU of the `> 0` masks (12.5% border cropped).
    pub iou: f64,
    /// PSNR on the foreground pixels.
    pub psnr: f64,
    /// SSIM on the foreground pixels.
    pub ssim: f64,
    /// Why LPIPS was not used, if it was not.
    pub lpips_note: Option<String>,
}

/// Runs (or resumes) the inversion of `cfg` into `dir` and writes every output.
pub fn run_and_report(cfg: &InversionConfig, dir: &Path, resume: bool) -> anyhow::Result<Summary> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    if !resume {
        ifslab::io::write_atomic(&dir.join(CONFIG_FILE), cfg.to_toml().as_bytes())?;
    }
    let target = prepare_target(cfg)?;
    let size = cfg.target.size;
    save_grey_png(
        &dir.join("target.png"),
        &target,
        size as u32,
        size as u32,
        BitDepth::Eight,
        false,
    )?;
    let pb = bar(cfg.iterations, "iterations");
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {prefix} [{elapsed_precise}] {bar:40} {pos}/{len} ({per_sec}, eta {eta}) {msg}",
        )
        .expect("valid template"),
    );
    pb.set_prefix(cfg.strategy.name());
    let started = Instant::now();
    let outcome = run_inversion(
        cfg,
        target.clone(),
        dir,
        resume,
        vec![Box::new(ProgressObserver::new(pb))],
    )?;
    let metrics = write_outputs(cfg, dir, &outcome, &target)?;
    let summary = Summary {
        strategy: cfg.strategy.name().into(),
        iterations: outcome.iterations,
        seconds: started.elapsed().as_secs_f64(),
        final_loss: outcome.final_loss,
        iou: metrics.iou,
        psnr: metrics.psnr,
        ssim: metrics.ssim,
        lpips_note: outcome.lpips_note.clone(),
    };
    ifslab::io::write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    Ok(summary)
}

/// Code file, final render, zoom strip, loss plot; returns the render's metrics.
fn write_outputs(
    cfg: &InversionConfig,
    dir: &Path,
    out: &InversionOutcome,
    target: &[f32],
) -> anyhow::Result<ImageMetrics> {
    let size = cfg.target.size;
    let mut code = IfsCode::from_affine2(Some("recovered"), &out.maps)
        .context("the recovered code failed validation")?;
    let probs = code.evaluation_probabilities()?;
    let final_render = render(
        &out.maps,
        &probs,
        &eval_config(size, 4_000_000, cfg.seed),
        None,
    )?;
    code.framing = Some(final_render.stats.window);
    code.meta
        .insert("strategy".into(), cfg.strategy.name().into());
    code.meta.insert("iterations".into(), out.iterations.into());
    code.meta.insert("final_loss".into(), out.final_loss.into());
    code.meta.insert("seed".into(), cfg.seed.into());
    code.save(dir.join("code.json"))?;
    final_render.save_png(&dir.join("render.png"), BitDepth::Eight, false)?;
    let metrics = paper_metrics::<f32>(&final_render.values, target, size, size, None)?;
    zoom_strip(
        &out.maps,
        &probs,
        &final_render.stats.window,
        &dir.join("zoom_strip.png"),
        cfg.seed,
    )?;
    loss_plot(&out.log, &dir.join("loss.png"))?;
    Ok(metrics)
}

/// A point on the attractor with detail around it: the fixed point of `f₀∘f₁`.
pub fn interesting_point(maps: &[Affine2]) -> Option<[f64; 2]> {
    match maps {
        [a, b, ..] => a.compose(b).fixed_point(),
        [a] => a.fixed_point(),
        [] => None,
    }
}

/// Renders 1×, 4×, 16×, 64× views around an interesting point side by side, with captions.
pub fn zoom_strip(
    maps: &[Affine2],
    probs: &[f64],
    base: &Framing,
    path: &Path,
    seed: u64,
) -> anyhow::Result<()> {
    const PANEL: u32 = 256;
    const CAPTION: u32 = 28;
    let center = interesting_point(maps).unwrap_or_else(|| base.center());
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
            ..RenderConfig::default()
        };
        panels.push(render(maps, probs, &cfg, None)?);
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
    let img = image::RgbImage::from_raw(w, h, buf).context("strip buffer")?;
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)?;
    ifslab::io::write_atomic(path, bytes.get_ref())?;
    Ok(())
}

/// Plots `loss` and each logged term of a run's CSV log against the iteration.
pub fn loss_plot(log: &Path, out: &Path) -> anyhow::Result<()> {
    let text =
        std::fs::read_to_string(log).with_context(|| format!("reading {}", log.display()))?;
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

/// The run folder named by `-o`, the config, or a default.
pub fn output_dir(cli: Option<PathBuf>, cfg: &InversionConfig, default: &str) -> PathBuf {
    cli.or_else(|| cfg.output.clone())
        .unwrap_or_else(|| PathBuf::from(default))
}
