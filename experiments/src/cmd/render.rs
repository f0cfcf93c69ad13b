//! `ifslab render CODE -o OUT.png`: the evaluation renderer from the command line.

use std::path::PathBuf;

use anyhow::Context;
use ifslab::render::image_io::BitDepth;
use ifslab::render::{RenderConfig, RenderMode, View, Zoom, render};

use super::resolve_code;
use crate::bars::{self as progress, Bar};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A code file (JSON) or a built-in name (see `ifslab codes`).
    pub code: String,
    /// Output PNG.
    #[arg(short, long, default_value = "render.png")]
    pub output: PathBuf,
    /// Points to generate (after warm-up): 50000000, 5e7 or 50M.
    #[arg(long, default_value = "50M", value_parser = ifslab::budget::parse_count)]
    pub points: u64,
    /// Image side in pixels (square), or WIDTHxHEIGHT.
    #[arg(long, default_value = "1024")]
    pub size: String,
    /// Supersampling factor per side for binary coverage (16 = the papers' ground truth).
    #[arg(long, default_value_t = 1)]
    pub supersample: u32,
    /// Density image with log tone mapping instead of binary coverage.
    #[arg(long)]
    pub density: bool,
    /// Zoom factor (e.g. 8 or 64) applied to the fitted window.
    #[arg(long)]
    pub zoom: Option<f64>,
    /// Zoom centre as X,Y in the code's coordinates (default: the window's centre); without
    /// --zoom it moves the window there at its size.
    #[arg(long, value_parser = parse_pair, allow_hyphen_values = true)]
    pub center: Option<[f64; 2]>,
    /// Write the image even when no point lands in the window (by default that is an
    /// error: a zoom that missed the attractor, or one too deep to reach it).
    #[arg(long)]
    pub allow_empty: bool,
    /// Keep generating until this many points land in the (zoomed) window.
    #[arg(long, default_value = "0", value_parser = ifslab::budget::parse_count)]
    pub min_hits: u64,
    /// Cap on points generated when --min-hits is set (default 64 × --points).
    #[arg(long, default_value = "0", value_parser = ifslab::budget::parse_count)]
    pub max_points: u64,
    /// Wall-clock cap in seconds for --min-hits rounds (result then depends on speed).
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// Zoom by keeping only the chaos-game points that land in the window (as the suites'
    /// zoomed views are drawn), instead of sending the points through the words of the code
    /// whose images meet the window — which makes a zoom at any depth (to about 2^43) cost
    /// what the full view costs.
    #[arg(long)]
    pub plain_zoom: bool,
    /// Seed of the chaos game.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write 16-bit PNG (keeps every coverage level of 16× supersampling).
    #[arg(long)]
    pub sixteen_bit: bool,
    /// Dark attractor on a white background.
    #[arg(long)]
    pub invert: bool,
}

pub fn parse_pair(s: &str) -> Result<[f64; 2], String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 2 {
        return Err(format!("expected X,Y, got `{s}`"));
    }
    let x = parts[0]
        .trim()
        .parse::<f64>()
        .map_err(|e| format!("bad X: {e}"))?;
    let y = parts[1]
        .trim()
        .parse::<f64>()
        .map_err(|e| format!("bad Y: {e}"))?;
    if !(x.is_finite() && y.is_finite()) {
        return Err(format!("X and Y must be finite numbers, got `{s}`"));
    }
    Ok([x, y])
}

pub fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let parse = |t: &str| {
        t.trim()
            .parse::<u32>()
            .with_context(|| format!("`{t}` is not a pixel count"))
    };
    match s.split_once(['x', 'X']) {
        Some((w, h)) => Ok((parse(w)?, parse(h)?)),
        None => {
            let n = parse(s)?;
            Ok((n, n))
        }
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let code = resolve_code(&a.code)?;
    let maps = code
        .affine2()
        .context("the evaluation renderer draws 2-D codes only")?;
    let probs = code.evaluation_probabilities()?;
    let (width, height) = parse_size(&a.size)?;
    let cfg = RenderConfig {
        width,
        height,
        points: a.points,
        supersample: a.supersample,
        mode: if a.density {
            RenderMode::Density
        } else {
            RenderMode::Coverage
        },
        seed: a.seed,
        view: code.framing.map_or(View::Fit, View::Window),
        // A centre without a zoom pans the window (zoom 1).
        zoom: (a.zoom.is_some() || a.center.is_some()).then(|| Zoom {
            factor: a.zoom.unwrap_or(1.0),
            center: a.center,
        }),
        min_hits: a.min_hits,
        max_points: a.max_points,
        time_limit: a.time_limit,
        deep_zoom: !a.plain_zoom,
        ..RenderConfig::default()
    };
    let pb = progress::bar(cfg.points, "points");
    let raster = render(&maps, &probs, &cfg, Some(&Bar::of(pb.clone())))?;
    pb.finish_and_clear();
    let s = &raster.stats;
    if s.points_in_window == 0 && !a.allow_empty {
        anyhow::bail!(
            "none of the {} points landed in the window x [{}, {}] y [{}, {}]: the zoom or \
             centre misses the attractor (nothing written; --allow-empty writes the empty image)",
            s.points_generated,
            s.window.min[0],
            s.window.max[0],
            s.window.min[1],
            s.window.max[1]
        );
    }
    let depth = if a.sixteen_bit {
        BitDepth::Sixteen
    } else {
        BitDepth::Eight
    };
    raster.save_png(&a.output, depth, a.invert)?;
    eprintln!(
        "{}: {} points in {:.2} s ({:.1} M points/s), {} in window, window x [{:.4}, {:.4}] y [{:.4}, {:.4}]{}",
        a.output.display(),
        s.points_generated,
        s.seconds,
        s.points_generated as f64 / s.seconds / 1e6,
        s.points_in_window,
        s.window.min[0],
        s.window.max[0],
        s.window.min[1],
        s.window.max[1],
        if s.stopped_by_time {
            " (stopped by --time-limit)"
        } else {
            ""
        }
    );
    Ok(())
}
