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
//!
//! `mod.rs` holds the tiling ([`Tiling`]: how deep a view goes); `request.rs` checks a
//! request; `render.rs` draws the tile.

mod render;
mod request;

use std::fmt;
use std::sync::OnceLock;

use ifslab::model::affine::Affine2;
use ifslab::model::code::Window;
use ifslab::progress::Progress;
use ifslab::render::{Raster, RenderConfig, RenderMode, View, Zoom, render, zoom_window};

use super::colormap::Colormap;

pub use render::{DensityTile, TileRenderer, ToneMap, encode_png};
pub use request::{TileError, TileMode, TileRequest};

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
