//! Tiles: the viewer's square base window cut into `2^level × 2^level` tiles, each a
//! `size × size` PNG drawn on demand by the evaluation renderer with deep zoom on.
//!
//! A tile request is an input like any other and is checked before any work: whole numbers
//! only, `level` in `0..=max_level`, `x` and `y` in `0..2^level`, `size` at most
//! [`TILE_SIZE_MAX`], a known mode and colour map, no unknown or repeated parameter. A
//! refusal is a [`TileError`] naming the parameter, served as `400 Bad Request`.
//!
//! **How deep.** The renderer refuses a window narrower than 2²⁰ doubles at its centre
//! (`ifslab::render::zoom_window`: a megapixel image could not place its points apart past
//! that). A tile at level `L` of a base window of side `s` is `s / 2^L` wide, and doubles
//! near its centre are `scale · ε` apart, `scale` at most the base window's largest
//! coordinate (or its side, if larger). So every tile of every level up to
//! `⌊log₂(s / (scale · ε · 2²⁰))⌋` renders ([`Tiling::max_level`]): 32 for a base window
//! wider than its distance from the origin (the classic codes: zoom 2³², tiles about
//! 3·10⁻¹⁰ of the attractor wide), fewer for a window far from the origin (22 for a window
//! 1.5 wide at 1000). A tile's pixel there is still about 2¹² doubles wide. The deep-zoom
//! sampler's own limit (words composed in f64, about 2⁴³) lies beyond it.
//!
//! **One brightness for all density tiles.** A density tile is not normalised by its own
//! brightest pixel (neighbours would disagree and seams would show): each pixel is first an
//! estimate of the invariant measure's density per unit area there
//! ([`TileRenderer::render_density`]: the deep-zoom words' probability mass times the share
//! of the tile's points in the pixel, over its area), then coloured by one log tone map per
//! code ([`ToneMap`], set by the level-0 tile), the same at every level and size.

use std::fmt;
use std::sync::OnceLock;

use ifslab::model::affine::Affine2;
use ifslab::model::code::Window;
use ifslab::progress::Progress;
use ifslab::render::{Raster, RenderConfig, RenderMode, View, Zoom, render, zoom_window};

use super::colormap::Colormap;

/// Tile side in pixels when the request names none.
pub const TILE_SIZE_DEFAULT: u32 = 256;
/// The largest tile side a request may ask for.
pub const TILE_SIZE_MAX: u32 = 512;
/// The smallest tile side a request may ask for.
pub const TILE_SIZE_MIN: u32 = 16;
/// No level past this, whatever the window (the deep-zoom sampler ends near 2⁴³).
pub const LEVEL_CAP: u32 = 40;
/// Doubles the renderer asks a window to span ([`ifslab::render::zoom_window`]'s bound).
const WINDOW_DOUBLES: f64 = (1u64 << 20) as f64;

/// How a tile is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileMode {
    /// Binary coverage of a code's attractor (a colour map's brightest colour).
    Coverage,
    /// A code's log density through a colour map.
    Density,
    /// A flame's own colours and tone map.
    Colour,
}

impl TileMode {
    /// The mode's name in a request.
    pub fn name(self) -> &'static str {
        match self {
            TileMode::Coverage => "coverage",
            TileMode::Density => "density",
            TileMode::Colour => "colour",
        }
    }

    fn from_name(name: &str) -> Option<Self> {
        [TileMode::Coverage, TileMode::Density, TileMode::Colour]
            .into_iter()
            .find(|m| m.name() == name)
    }
}

/// A tile request refused, with the parameter to change.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TileError {
    /// A parameter the endpoint needs is absent.
    Missing(&'static str),
    /// A parameter the endpoint does not know.
    Unknown(String),
    /// A parameter given twice.
    Repeated(String),
    /// A parameter whose value is out of range or not a number.
    Invalid {
        /// The parameter.
        param: &'static str,
        /// What it must be, and what it was.
        reason: String,
    },
}

impl fmt::Display for TileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TileError::Missing(p) => write!(f, "tile parameter `{p}` is missing"),
            TileError::Unknown(p) => write!(
                f,
                "unknown tile parameter `{p}` (known: level, x, y, size, mode, cmap, gen, sid)"
            ),
            TileError::Repeated(p) => write!(f, "tile parameter `{p}` is given twice"),
            TileError::Invalid { param, reason } => {
                write!(f, "bad tile parameter `{param}`: {reason}")
            }
        }
    }
}

impl std::error::Error for TileError {}

/// The base window and how deep its tiles go.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tiling {
    base: Window,
    max_level: u32,
}

impl Tiling {
    /// Tiles of `window` made square (its longer side around its centre).
    pub fn new(window: &Window) -> crate::Result<Self> {
        window.validate()?;
        let [w, h] = window.size();
        let side = w.max(h);
        let c = window.center();
        // A square window (to rounding) is kept to the bit: a code's framing is `ifslab
        // render`'s window.
        let base = match (w - h).abs() <= 1e-9 * side {
            true => *window,
            false => Window {
                min: [c[0] - 0.5 * side, c[1] - 0.5 * side],
                max: [c[0] + 0.5 * side, c[1] + 0.5 * side],
            },
        };
        let scale = base
            .min
            .iter()
            .chain(&base.max)
            .fold(side, |m, v| m.max(v.abs()));
        let ratio = side / (scale * f64::EPSILON * WINDOW_DOUBLES);
        let mut tiling = Tiling {
            base,
            max_level: ratio.log2().floor().clamp(0.0, LEVEL_CAP as f64) as u32,
        };
        // The renderer's own test decides at the edge: the corner tiles lie farthest from
        // the origin.
        while tiling.max_level > 0 {
            let last = (1u64 << tiling.max_level) - 1;
            let corners = [(0, 0), (0, last), (last, 0), (last, last)];
            if corners
                .iter()
                .all(|&(x, y)| zoom_window(&base, &tiling.zoom(tiling.max_level, x, y)).is_ok())
            {
                break;
            }
            tiling.max_level -= 1;
        }
        Ok(tiling)
    }

    /// The tiling no deeper than `level`.
    pub fn capped(mut self, level: u32) -> Self {
        self.max_level = self.max_level.min(level);
        self
    }

    /// The square window level 0's single tile shows.
    pub fn base(&self) -> Window {
        self.base
    }

    /// The deepest level whose every tile the renderer draws (see the module docs).
    pub fn max_level(&self) -> u32 {
        self.max_level
    }

    /// The zoom of the base window that shows tile `(x, y)` of `level` (row 0 at the top).
    pub fn zoom(&self, level: u32, x: u64, y: u64) -> Zoom {
        let n = (level as f64).exp2();
        let side = self.base.size()[0];
        Zoom {
            factor: n,
            center: Some([
                self.base.min[0] + (x as f64 + 0.5) * (side / n),
                self.base.max[1] - (y as f64 + 0.5) * (side / n),
            ]),
        }
    }
}

/// One tile: where, how big, drawn how, and which view generation asked for it.
#[derive(Clone, Debug, PartialEq)]
pub struct TileRequest {
    /// Level: the base window cut into `2^level` tiles a side.
    pub level: u32,
    /// Column, from the left.
    pub x: u64,
    /// Row, from the top.
    pub y: u64,
    /// Side in pixels.
    pub size: u32,
    /// Density or binary coverage (codes), or colour (flames).
    pub mode: TileMode,
    /// Colour map of the inked pixels.
    pub cmap: Colormap,
    /// The page's view generation and the page's id: a tile of a generation older than the
    /// latest its page asked for is skipped (`None`: never skipped).
    pub generation: Option<(u64, u64)>,
}

impl TileRequest {
    /// Parses and checks a query string (`level=3&x=1&y=5&mode=density…`) against `tiling`
    /// and the view's `modes` (the first one when the request names none).
    pub fn parse(query: &str, tiling: &Tiling, modes: &[TileMode]) -> Result<Self, TileError> {
        let mut seen: Vec<&str> = Vec::new();
        let (mut level, mut x, mut y) = (None, None, None);
        let (mut size, mut mode, mut cmap) = (TILE_SIZE_DEFAULT, modes[0], Colormap::default());
        let (mut gen_, mut sid) = (None, None);
        for pair in query.split('&').filter(|p| !p.is_empty()) {
            let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
            if seen.contains(&key) {
                return Err(TileError::Repeated(shown(key)));
            }
            seen.push(key);
            match key {
                "level" => level = Some(whole("level", value, tiling.max_level as u64)? as u32),
                "x" => x = Some(value),
                "y" => y = Some(value),
                "size" => {
                    size = whole("size", value, TILE_SIZE_MAX as u64)? as u32;
                    if size < TILE_SIZE_MIN {
                        return Err(TileError::Invalid {
                            param: "size",
                            reason: format!(
                                "must lie in {TILE_SIZE_MIN}..={TILE_SIZE_MAX} pixels, got {size}"
                            ),
                        });
                    }
                }
                "mode" => {
                    mode = match TileMode::from_name(value) {
                        Some(m) if modes.contains(&m) => m,
                        _ => {
                            let names: Vec<String> =
                                modes.iter().map(|m| format!("`{}`", m.name())).collect();
                            return Err(TileError::Invalid {
                                param: "mode",
                                reason: format!(
                                    "must be {} for this view, got `{}`",
                                    names.join(" or "),
                                    shown(value)
                                ),
                            });
                        }
                    }
                }
                "cmap" => {
                    cmap = Colormap::from_name(value).ok_or_else(|| TileError::Invalid {
                        param: "cmap",
                        reason: format!(
                            "must be one of {}, got `{}`",
                            Colormap::NAMES.join(", "),
                            shown(value)
                        ),
                    })?
                }
                "gen" => gen_ = Some(whole("gen", value, u64::MAX)?),
                "sid" => sid = Some(whole("sid", value, u64::MAX)?),
                _ => return Err(TileError::Unknown(shown(key))),
            }
        }
        let level = level.ok_or(TileError::Missing("level"))?;
        // Columns and rows are checked against their level's count.
        let last = (1u64 << level) - 1;
        let x = whole("x", x.ok_or(TileError::Missing("x"))?, last)?;
        let y = whole("y", y.ok_or(TileError::Missing("y"))?, last)?;
        let generation = match (gen_, sid) {
            (Some(g), Some(s)) => Some((s, g)),
            (None, None) => None,
            _ => {
                return Err(TileError::Invalid {
                    param: if gen_.is_some() { "sid" } else { "gen" },
                    reason: "`gen` and `sid` come together (a page's view generation and its id)"
                        .into(),
                });
            }
        };
        Ok(TileRequest {
            level,
            x,
            y,
            size,
            mode,
            cmap,
            generation,
        })
    }

    /// The request without its generation: what makes two tiles the same picture.
    pub fn key(&self) -> String {
        format!(
            "{}/{}/{}/{}/{}/{}",
            self.level,
            self.x,
            self.y,
            self.size,
            self.mode.name(),
            self.cmap.name()
        )
    }
}

/// A parameter's value as a whole number in `0..=max`.
fn whole(param: &'static str, value: &str, max: u64) -> Result<u64, TileError> {
    let bad = |what: &str| TileError::Invalid {
        param,
        reason: format!(
            "must be a whole number in 0..={max}{what}, got `{}`",
            shown(value)
        ),
    };
    if value.is_empty() || !value.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad(""));
    }
    match value.parse::<u64>() {
        Ok(v) if v <= max => Ok(v),
        _ if param == "level" => Err(bad(
            " (deeper tiles would be narrower than the renderer's double-precision bound here)",
        )),
        _ => Err(bad("")),
    }
}

/// A request's text as an error message shows it: at most 40 characters, no control
/// characters.
fn shown(s: &str) -> String {
    let mut out: String = s
        .chars()
        .take(40)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if s.chars().count() > 40 {
        out.push('…');
    }
    out
}

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

#[cfg(test)]
mod tests {
    use super::*;

    fn tiling() -> Tiling {
        Tiling::new(&Window {
            min: [-0.25, -0.3],
            max: [1.25, 1.2],
        })
        .unwrap()
    }

    /// The level bound is where the renderer's own precision test would start refusing:
    /// every tile at `max_level` renders its window, one level deeper does not for some tile.
    #[test]
    fn max_level_is_the_renderers_precision_bound() {
        let t = tiling();
        assert_eq!(t.max_level(), 32, "side 1.5, coordinates up to 1.25");
        let base = t.base();
        for (x, y) in [(0, 0), ((1u64 << 32) - 1, (1u64 << 32) - 1), (1 << 31, 7)] {
            ifslab::render::zoom_window(&base, &t.zoom(t.max_level(), x, y)).unwrap();
        }
        let deeper = t.zoom(t.max_level() + 1, 0, 0);
        assert!(ifslab::render::zoom_window(&base, &deeper).is_err());
        // Far from the origin fewer levels fit.
        let far = Tiling::new(&Window {
            min: [1000.0, 1000.0],
            max: [1001.5, 1001.5],
        })
        .unwrap();
        assert_eq!(far.max_level(), 22);
    }

    #[test]
    fn tile_parameters_are_checked() {
        let t = tiling();
        let modes = [TileMode::Coverage, TileMode::Density];
        let ok = TileRequest::parse(
            "level=3&x=7&y=0&mode=density&cmap=grey&gen=4&sid=9",
            &t,
            &modes,
        )
        .unwrap();
        assert_eq!(
            (ok.level, ok.x, ok.y, ok.size),
            (3, 7, 0, TILE_SIZE_DEFAULT)
        );
        assert_eq!(ok.generation, Some((9, 4)));
        for (query, words) in [
            ("level=NaN&x=0&y=0", "`level`"),
            ("level=-1&x=0&y=0", "`level`"),
            ("level=33&x=0&y=0", "double-precision"),
            ("level=1e3&x=0&y=0", "`level`"),
            ("level=3&x=8&y=0", "`x`: must be a whole number in 0..=7"),
            ("level=3&x=0&y=inf", "`y`"),
            ("level=3&x=0", "`y` is missing"),
            ("level=1&x=0&y=0&size=4096", "`size`"),
            ("level=1&x=0&y=0&size=0", "`size`"),
            ("level=1&x=0&y=0&mode=fancy", "`mode`"),
            (
                "level=1&x=0&y=0&mode=colour",
                "`coverage` or `density` for this view",
            ),
            ("level=1&x=0&y=0&cmap=jet", "`cmap`"),
            ("level=1&x=0&y=0&zoom=2", "unknown tile parameter `zoom`"),
            ("level=1&level=2&x=0&y=0", "given twice"),
            ("level=1&x=0&y=0&gen=3", "`sid`"),
        ] {
            let e = TileRequest::parse(query, &t, &modes)
                .unwrap_err()
                .to_string();
            assert!(e.contains(words), "{query}: {e}");
        }
    }
}
