//! Tiles of a flame, drawn by the flame renderer ([`ifslab::render::flame::render_flame`],
//! flam3's algorithm): a `.flame` file's flame, or its layers composited over the first
//! one's background as `ifslab flame render --composite` lays them (a learned stack).
//!
//! **How deep.** The flame renderer has no deep zoom: its chaos game spreads its samples
//! over the whole attractor, so a tile `2^L` deep sees about `4^-L` of them. flam3's tone
//! map is set by the samples per unit of area, so brightness holds at any depth, but the
//! grain does not: a tile keeps the density of the flame's own `quality` (samples per pixel)
//! only with `4^L` times the samples. Each tile draws at most `samples` ([`FlameTiles::new`];
//! `--points`, 4 M by default for a flame): `min(quality·4^L, samples/T²)` samples per pixel
//! of a `T × T` tile. The deepest level is where that is still
//! [`MIN_SAMPLES_PER_PIXEL`] or more: `⌊log₄(samples / (T²·MIN_SAMPLES_PER_PIXEL))⌋` —
//! level 2 (zoom 4×) at 4 M samples and 256² tiles, level 5 (32×) at the most `--points`
//! allows (10⁸). The page enlarges the deepest tiles past it.
//!
//! Pages show flames with +y up; flam3's images have +y down, so the tiling's `y` is the
//! flame's `-y`. A rotated flame (`rotate`) turns about its own centre: each tile's camera
//! is placed so that its rotation about the tile's centre shows the same part of the plane.

use std::path::Path;

use crate::error::Context;
use ifslab::model::code::Window;
use ifslab::model::flame::{Flame, read_flames};
use ifslab::progress::Progress;
use ifslab::render::flame::{Composite, FlameRenderConfig, render_flame};

use super::tile::{TILE_SIZE_DEFAULT, TileRequest, Tiling};

/// Fewest samples per tile pixel a tile level is drawn with: the flame's density bound.
pub const MIN_SAMPLES_PER_PIXEL: f64 = 1.0;
/// Samples per tile by default (about a quarter of a second per layer on two cores).
pub const DEFAULT_FLAME_SAMPLES: u64 = 4_000_000;

/// A flame file's flames, cut in tiles.
#[derive(Clone, Debug)]
pub struct FlameTiles {
    layers: Vec<Flame>,
    tiling: Tiling,
    samples: u64,
    seed: u64,
}

impl FlameTiles {
    /// The flames of `path` (all of them laid over one another; `name` picks one) in tiles
    /// of at most `samples` samples each, and the tiling of the first flame's framing.
    pub fn load(path: &Path, name: Option<&str>, samples: u64, seed: u64) -> crate::Result<Self> {
        let mut layers = read_flames(path)?;
        if let Some(n) = name {
            layers.retain(|f| f.name.as_deref() == Some(n));
            if layers.is_empty() {
                crate::error::bail!("no flame named `{n}` in {}", path.display());
            }
        }
        if layers.is_empty() {
            crate::error::bail!("{} holds no flame", path.display());
        }
        for f in &layers {
            f.validate()
                .with_context(|| format!("checking {}", path.display()))?;
        }
        Self::new(layers, samples, seed)
    }

    /// Tiles of `layers` (the first one framing them all).
    pub fn new(layers: Vec<Flame>, samples: u64, seed: u64) -> crate::Result<Self> {
        let first = layers.first().context("a flame file without flames")?;
        let ppu = first.pixels_per_unit();
        let side = first.size[0].max(first.size[1]) as f64 / ppu;
        let [cx, cy] = first.center;
        // The page's y is the flame's −y.
        let window = Window {
            min: [cx - 0.5 * side, -cy - 0.5 * side],
            max: [cx + 0.5 * side, -cy + 0.5 * side],
        };
        let tiling = Tiling::new(&window)?;
        let t2 = (TILE_SIZE_DEFAULT as f64).powi(2);
        let by_density = (samples as f64 / (t2 * MIN_SAMPLES_PER_PIXEL))
            .log(4.0)
            .floor();
        let tiling = tiling.capped(by_density.max(0.0) as u32);
        Ok(FlameTiles {
            layers,
            tiling,
            samples,
            seed,
        })
    }

    /// The tiling: the first flame's framing made square, as deep as the density allows.
    pub fn tiling(&self) -> Tiling {
        self.tiling
    }

    /// Samples per tile pixel at `level` for `T × T` tiles of `flame`.
    pub fn quality(&self, flame: &Flame, level: u32, size: u32) -> f64 {
        let pixels = (size as f64).powi(2);
        (flame.quality * 4f64.powi(level as i32)).min(self.samples as f64 / pixels)
    }

    /// The flame `layer` framed to show tile `req`.
    fn framed(&self, layer: &Flame, req: &TileRequest) -> Flame {
        let zoom = self.tiling.zoom(req.level, req.x, req.y);
        let [px, py] = zoom.center.expect("a tile's zoom has a centre");
        let q = [px, -py];
        let side = self.tiling.base().size()[0] / zoom.factor;
        let mut f = layer.clone();
        let c0 = layer.center;
        // The camera turns points by `rotate` about its own centre c; the tile is centred at
        // q in the frame turned about c0 when c = c0 + R⁻¹(q − c0).
        f.center = if layer.rotate == 0.0 {
            q
        } else {
            let a = -layer.rotate.to_radians();
            let (s, c) = a.sin_cos();
            let d = [q[0] - c0[0], q[1] - c0[1]];
            [c0[0] + c * d[0] - s * d[1], c0[1] + s * d[0] + c * d[1]]
        };
        f.size = [req.size, req.size];
        f.scale = req.size as f64 / side;
        f.zoom = 0.0;
        f.quality = self.quality(layer, req.level, req.size);
        f
    }

    /// The tile as RGBA pixels (opaque: the flame's background where nothing lands).
    pub fn render_rgba(
        &self,
        req: &TileRequest,
        progress: &dyn Progress,
    ) -> crate::Result<Vec<u8>> {
        let cfg = |transparent| FlameRenderConfig {
            seed: self.seed,
            transparent,
            ..FlameRenderConfig::default()
        };
        if let [one] = self.layers.as_slice() {
            let img = render_flame(&self.framed(one, req), &cfg(false), Some(progress))?;
            return Ok(img.to_rgba8(false));
        }
        let mut canvas = Composite::new(req.size, req.size, self.layers[0].background);
        for layer in &self.layers {
            let img = render_flame(&self.framed(layer, req), &cfg(true), Some(progress))?;
            canvas.over(&img)?;
        }
        let img = canvas.into_image()?;
        let n = (req.size * req.size) as usize;
        let mut rgba = vec![255u8; 4 * n];
        for (i, px) in rgba.chunks_exact_mut(4).enumerate() {
            for (c, v) in px[..3].iter_mut().enumerate() {
                *v = (img.values[c * n + i] * 255.0).round() as u8;
            }
        }
        Ok(rgba)
    }
}
