//! The view: which window of the plane an image shows ([`Window`]), fitted to the
//! attractor or given, and zoomed.
//!
//! The papers centre the attractor's bounding box and scale it so its longest side spans
//! 75% of the frame (12.5% margin each side, the "25% padding"); evaluation crops that
//! border. Zoom views shrink the window by a factor around a centre.

use serde::{Deserialize, Serialize};

use crate::chaos::{ChaosGame, Points};
use crate::error::{Error, Result};
use crate::model::Map2;
use crate::model::code::Window;

/// Fraction of the frame the attractor's longest side spans when fitted.
pub const FIT_FILL: f64 = 0.75;

/// A zoom-in: shrink the window by `factor` around `center` (world coordinates; `None`
/// keeps the window's own centre).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Zoom {
    /// Magnification, ≥ 1 zooms in.
    pub factor: f64,
    /// Centre of the zoomed window.
    pub center: Option<[f64; 2]>,
}

/// How a render chooses its window.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum View {
    /// Fit the attractor (pilot run's bounding box) with [`FIT_FILL`].
    #[default]
    Fit,
    /// A fixed window.
    Window(Window),
}

/// A window with the aspect of a `width × height` image, centred on the box `lo..hi`,
/// whose longest side (relative to the image) spans `fill` of the frame.
pub fn fit_window(
    lo: [f64; 2],
    hi: [f64; 2],
    width: u32,
    height: u32,
    fill: f64,
) -> Result<Window> {
    if !(fill > 0.0 && fill <= 1.0) {
        return Err(Error::param(
            "fill",
            format!("must lie in (0, 1], got {fill}"),
        ));
    }
    if !(lo.iter().chain(hi.iter()).all(|v| v.is_finite())) {
        return Err(Error::NonFinite {
            what: "bounding box".into(),
            location: "corner".into(),
            value: f64::NAN,
        });
    }
    let (w, h) = (width as f64, height as f64);
    let bw = (hi[0] - lo[0]).max(0.0);
    let bh = (hi[1] - lo[1]).max(0.0);
    // World units per pixel so that the limiting side spans `fill` of its image side.
    let mut unit = (bw / (fill * w)).max(bh / (fill * h));
    if unit <= 0.0 {
        // A single point: give it a unit-sized window.
        unit = 1.0 / w.max(h);
    }
    let c = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
    Ok(Window {
        min: [c[0] - 0.5 * w * unit, c[1] - 0.5 * h * unit],
        max: [c[0] + 0.5 * w * unit, c[1] + 0.5 * h * unit],
    })
}

/// The window `base` zoomed by `zoom`.
pub fn zoom_window(base: &Window, zoom: &Zoom) -> Result<Window> {
    if !(zoom.factor.is_finite() && zoom.factor > 0.0) {
        return Err(Error::param(
            "zoom",
            format!("factor must be finite and > 0, got {}", zoom.factor),
        ));
    }
    let c = zoom.center.unwrap_or_else(|| base.center());
    if !(c[0].is_finite() && c[1].is_finite()) {
        return Err(Error::param("center", "must be finite"));
    }
    let s = base.size();
    let half = [0.5 * s[0] / zoom.factor, 0.5 * s[1] / zoom.factor];
    // Doubles near the centre are `scale·ε` apart; a window fewer than 2^20 of those wide
    // cannot place a megapixel's points apart (nor, far enough, hold any).
    let scale = c[0].abs().max(c[1].abs()).max(s[0]).max(s[1]);
    let resolution = scale * f64::EPSILON * (1u64 << 20) as f64;
    if 2.0 * half[0].min(half[1]) < resolution {
        return Err(Error::param(
            "zoom",
            format!(
                "{:e} is past double precision here: the window would be {:.1e} wide around \
                 ({}, {}), where doubles are {:.1e} apart; zoom at most about {:.1e} at this centre",
                zoom.factor,
                2.0 * half[0].min(half[1]),
                c[0],
                c[1],
                scale * f64::EPSILON,
                s[0].min(s[1]) / resolution
            ),
        ));
    }
    Ok(Window {
        min: [c[0] - half[0], c[1] - half[1]],
        max: [c[0] + half[0], c[1] + half[1]],
    })
}

/// The bounding box of the attractor from a pilot chaos-game run (256 × 1000 steps,
/// 100 dropped), seeded so the fitted window is reproducible.
///
/// Extreme points of an attractor are often fixed points of single maps or of short
/// compositions (the corners of the Sierpiński triangle are), which a random orbit reaches
/// only approximately; they are added exactly by iterating every `fᵢ` and every `fᵢ∘fⱼ`
/// (up to 24 maps) to convergence from a pilot point.
pub fn pilot_bbox<M: Map2>(maps: &[M], probs: &[f64], seed: u64) -> Result<([f64; 2], [f64; 2])> {
    let game = ChaosGame {
        trajectories: 256,
        length: 1000,
        warmup: 100,
        start_half_width: 1.0,
        seed: seed ^ 0x5EED_F1A7,
    };
    let mut pts: Points = game.generate(maps, probs)?;
    let start = pts.data[0];
    let settle = |f: &dyn Fn([f64; 2]) -> [f64; 2]| {
        let mut p = start;
        for _ in 0..400 {
            p = f(p);
        }
        p
    };
    for (i, fi) in maps.iter().enumerate() {
        if probs[i] <= 0.0 {
            continue;
        }
        let p = settle(&|p| fi.apply(p));
        if crate::chaos::is_bounded(&p) {
            pts.data.push(p);
        }
        if maps.len() <= 24 {
            for (j, fj) in maps.iter().enumerate() {
                if i != j && probs[j] > 0.0 {
                    let q = settle(&|p| fi.apply(fj.apply(p)));
                    if crate::chaos::is_bounded(&q) {
                        pts.data.push(q);
                    }
                }
            }
        }
    }
    Ok(pts.bbox())
}
