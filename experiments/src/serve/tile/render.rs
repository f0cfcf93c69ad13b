//! Drawing a tile: the evaluation renderer with deep zoom on over the tile's window, density
//! tiles tone-mapped with one brightness for the whole view, encoded as PNG.

use super::*;

/// A 2-D code and how its tiles are drawn.
#[derive(Clone, Debug)]
pub struct TileRenderer {
    maps: Vec<Affine2>,
    probs: Vec<f64>,
    tiling: Tiling,
    points: u64,
    seed: u64,
    /// The code's density tone map, set by the first density tile that needs it.
    tone: OnceLock<ToneMap>,
}

/// A density tile before its tone map: each pixel's share of the invariant measure μ per
/// unit of area, estimated from the tile's points (see [`TileRenderer::render_density`]).
#[derive(Clone, Debug, PartialEq)]
pub struct DensityTile {
    /// Side in pixels.
    pub size: u32,
    /// Row-major, row 0 at the top: `μ(pixel) / area(pixel)`, 0 where no point landed.
    pub density: Vec<f64>,
    /// The estimate of μ(tile's window): `sampled_mass × points in the window / points
    /// generated` ([`ifslab::render::RenderStats::sampled_mass`]).
    pub mass: f64,
    /// The density one point in a pixel stands for (the estimator's step): `sampled_mass /
    /// (points generated × pixel area)`.
    pub quantum: f64,
    /// The area of one pixel.
    pub pixel_area: f64,
}

/// The log tone map all density tiles of a code share: a density per unit area `d` has
/// the tone `ln(1 + d / floor) / ln(1 + top / floor)`, clamped to 1, whatever the tile,
/// its level and its size.
///
/// Both ends come from the code's level-0 tile at the default size
/// ([`TILE_SIZE_DEFAULT`], the tiles' points and seed): `floor` is the density of one point
/// in one of its pixels and `top` its densest pixel. So the top tile looks as a density
/// render of the full view normalised by its own brightest pixel (`ifslab render
/// --density`), and every other tile is drawn to the same scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToneMap {
    /// Density per unit area of one point in a pixel of the level-0 tile.
    pub floor: f64,
    /// The level-0 tile's largest density per unit area (tone 1; at least `floor`).
    pub top: f64,
}

impl ToneMap {
    /// The tone map of the level-0 tile `top_tile`.
    pub fn from_top_tile(top_tile: &DensityTile) -> Self {
        let max = top_tile.density.iter().copied().fold(0.0, f64::max);
        ToneMap {
            floor: top_tile.quantum,
            top: max.max(top_tile.quantum),
        }
    }

    /// The tone in [0, 1] of a density per unit area.
    pub fn tone(&self, density: f64) -> f32 {
        let t = (density / self.floor).ln_1p() / (self.top / self.floor).ln_1p();
        if t.is_finite() {
            t.clamp(0.0, 1.0) as f32
        } else {
            // A density past f64's range (a 0 floor cannot occur: it is a density of one
            // point) is the top's colour.
            1.0
        }
    }
}

impl TileRenderer {
    /// Tiles of `maps` drawn with `probs`, `points` chaos-game points each, seeded by `seed`.
    pub fn new(
        maps: Vec<Affine2>,
        probs: Vec<f64>,
        tiling: Tiling,
        points: u64,
        seed: u64,
    ) -> Self {
        TileRenderer {
            maps,
            probs,
            tiling,
            points,
            seed,
            tone: OnceLock::new(),
        }
    }

    /// The tile as RGBA pixels (row-major, row 0 at the top): the colour map on inked
    /// pixels, transparent elsewhere. A tile the attractor misses is a transparent tile.
    /// Density tiles go through the code's shared [`ToneMap`] ([`TileRenderer::tone_map`]).
    /// `progress` may cancel the render ([`Progress::cancelled`]).
    pub fn render_rgba(
        &self,
        req: &TileRequest,
        progress: &dyn Progress,
    ) -> crate::Result<Vec<u8>> {
        let colour = |v: f32| {
            let [r, g, b] = req.cmap.colour(v);
            [r, g, b, 255]
        };
        match req.mode {
            TileMode::Coverage => {
                let raster = self.render_raster(req, RenderMode::Coverage, progress)?;
                let mut rgba = vec![0u8; raster.values.len() * 4];
                for (px, &v) in rgba.chunks_exact_mut(4).zip(&raster.values) {
                    if v > 0.0 {
                        px.copy_from_slice(&colour(v));
                    }
                }
                Ok(rgba)
            }
            TileMode::Density => {
                let tile = self.render_density(req, progress)?;
                let tone = self.tone_map(progress)?;
                let mut rgba = vec![0u8; tile.density.len() * 4];
                for (px, &d) in rgba.chunks_exact_mut(4).zip(&tile.density) {
                    if d > 0.0 {
                        px.copy_from_slice(&colour(tone.tone(d)));
                    }
                }
                Ok(rgba)
            }
            TileMode::Colour => {
                crate::error::bail!("a code's tiles are drawn as coverage or density")
            }
        }
    }

    /// The tile's density per unit area of the invariant measure μ, pixel by pixel.
    ///
    /// **The estimator.** The renderer draws a zoomed tile through the deep-zoom words
    /// whose images meet its window ([`ifslab::chaos::WindowWords`]): the kept words `K`
    /// and the dropped ones (whose images miss the window) make a complete set of words, so
    /// `μ = Σ_w p_w · (f_w)_# μ` over them and, inside the window, `μ = Σ_{w∈K} p_w ·
    /// (f_w)_# μ`. A chaos-game point sent through a word of `K` drawn ∝ `p_w` is
    /// distributed as that sum divided by `M = Σ_{w∈K} p_w`, which the sampler knows
    /// exactly ([`ifslab::render::RenderStats::sampled_mass`]). So a pixel that receives `c`
    /// of the `N` points generated holds `μ(pixel) ≈ M · c / N`, and its density is that
    /// over the pixel's area; the tile's mass is `M` times the share of points that landed
    /// in it. A tile drawn the plain way (a window around the whole attractor, or a code
    /// whose overlapping maps need too many words) has `M = 1`, the ordinary chaos-game
    /// estimate.
    ///
    /// **Its limits.** `c` is a Poisson-like count: a pixel's density is known to about
    /// `1/√c` (a tile spreads its points over the part of the attractor it shows, so this
    /// holds at every level); the chaos game's points follow μ only after their warm-up,
    /// and the word is drawn by a hash of the point rather than by a fresh random number
    /// (both are far below that noise: `experiments/tests/serve_density.rs` finds a tile's
    /// mass within 0.3 % of its four children's). A fractal measure's density grows as one
    /// zooms (by `2^(2 − α)` a level where its local dimension is `α`), so on the shared
    /// scale the deep tiles of an attractor's thin parts reach the top of the tone map (most
    /// of the Sierpiński triangle's by level 4), where density mode looks as coverage does.
    /// Counts are read back from the renderer's log values
    /// and their largest count ([`ifslab::render::RenderStats::max_count`]), to the count
    /// below about 10⁵ points a pixel and to 10⁻⁶ above.
    pub fn render_density(
        &self,
        req: &TileRequest,
        progress: &dyn Progress,
    ) -> crate::Result<DensityTile> {
        let raster = self.render_raster(req, RenderMode::Density, progress)?;
        let s = &raster.stats;
        let [w, h] = s.window.size();
        let pixel_area = (w / req.size as f64) * (h / req.size as f64);
        let generated = s.points_generated.max(1) as f64;
        let quantum = s.sampled_mass / (generated * pixel_area);
        // The renderer's values are `ln(1 + c) / ln(1 + max_count)`.
        let log_top = (s.max_count as f64).ln_1p();
        let density = raster
            .values
            .iter()
            .map(|&v| match v > 0.0 {
                true => (v as f64 * log_top).exp_m1().round().max(1.0) * quantum,
                false => 0.0,
            })
            .collect();
        let tile = DensityTile {
            size: req.size,
            density,
            mass: s.sampled_mass * s.points_in_window as f64 / generated,
            quantum,
            pixel_area,
        };
        // The level-0 tile at the default size is the tone map's reference: keep it.
        if req.level == 0 && req.size == TILE_SIZE_DEFAULT && self.tone.get().is_none() {
            let _ = self.tone.set(ToneMap::from_top_tile(&tile));
        }
        Ok(tile)
    }

    /// The code's density tone map, from its level-0 tile (drawn once, by the first density
    /// tile that needs it; `progress` may cancel that, and the next tile draws it again).
    pub fn tone_map(&self, progress: &dyn Progress) -> crate::Result<ToneMap> {
        if let Some(t) = self.tone.get() {
            return Ok(*t);
        }
        let top = TileRequest {
            level: 0,
            x: 0,
            y: 0,
            size: TILE_SIZE_DEFAULT,
            mode: TileMode::Density,
            cmap: Colormap::default(),
            generation: None,
        };
        let tile = self.render_density(&top, progress)?;
        // Two workers may both draw it: the same picture, the same map.
        Ok(*self.tone.get_or_init(|| ToneMap::from_top_tile(&tile)))
    }

    /// The tile drawn by the evaluation renderer with deep zoom.
    fn render_raster(
        &self,
        req: &TileRequest,
        mode: RenderMode,
        progress: &dyn Progress,
    ) -> crate::Result<Raster> {
        let cfg = RenderConfig {
            width: req.size,
            height: req.size,
            points: self.points,
            mode,
            seed: self.seed,
            view: View::Window(self.tiling.base),
            zoom: Some(self.tiling.zoom(req.level, req.x, req.y)),
            deep_zoom: true,
            ..RenderConfig::default()
        };
        Ok(render(&self.maps, &self.probs, &cfg, Some(progress))?)
    }

    /// The tile as a PNG file's bytes.
    pub fn render_png(&self, req: &TileRequest, progress: &dyn Progress) -> crate::Result<Vec<u8>> {
        let rgba = self.render_rgba(req, progress)?;
        encode_png(&rgba, req.size, req.size)
    }
}

/// RGBA pixels as a PNG (fast compression: a tile is made to be sent at once).
pub fn encode_png(rgba: &[u8], width: u32, height: u32) -> crate::Result<Vec<u8>> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::{ExtendedColorType, ImageEncoder};
    let mut bytes = Vec::new();
    PngEncoder::new_with_quality(&mut bytes, CompressionType::Fast, FilterType::Sub).write_image(
        rgba,
        width,
        height,
        ExtendedColorType::Rgba8,
    )?;
    Ok(bytes)
}
