//! `ifslab serve`: a local web page that pans and zooms deep into an attractor.
//!
//! What a page shows is a [`Site`]: a code (a file or a built-in name) as one view, or a
//! run folder as two linked views — its target picture and its recovered code in the same
//! window, the code's `framing` — with the loss curve beneath. Code views are drawn in
//! tiles ([`tile`]): the square base window cut into `2^level × 2^level` tiles, each
//! rendered on demand by the evaluation renderer with deep zoom on, so a tile at level 30
//! costs what the full view costs. [`server`] answers the page's requests on a small pool of
//! worker threads and skips tiles its page no longer shows.
//!
//! A `.flame` file (or a folder holding `learned.flame`, as `ifslab flame learn` writes it)
//! is shown in tiles of the flame renderer, in the flame's own colours; how deep those go
//! is bounded by the samples a tile may draw ([`flame`]).
//!
//! The page (`experiments/assets/viewer/`: one HTML file, one script, one style sheet, no
//! build step) is compiled into the binary; it takes its initial view from the URL
//! (`#level=20&x=0.3&y=0.0001`: the full view zoomed 2²⁰ around that point).

pub mod colormap;
pub mod flame;
pub mod http;
pub mod server;
pub mod tile;

use std::path::Path;

use crate::error::{Context, IoContext};
use ifslab::model::IfsCode;
use ifslab::render::{FIT_FILL, fit_window};
use ifslab_strategies::problems::image::FIT_FILE;

pub use flame::FlameTiles;
pub use server::{RunningServer, ServeOptions, TileStats, serve};
pub use tile::{DensityTile, TileError, TileMode, TileRenderer, TileRequest, Tiling, ToneMap};

use ifslab::progress::Progress;

use crate::codes::resolve_code;

/// The most chaos-game points a tile may cost (`--points`).
pub const MAX_POINTS_PER_TILE: u64 = 100_000_000;

/// How code views draw their tiles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileOptions {
    /// Chaos-game points per code tile (at most [`MAX_POINTS_PER_TILE`]).
    pub points: u64,
    /// Samples per flame tile (at most [`MAX_POINTS_PER_TILE`]): how deep flames go.
    pub flame_samples: u64,
    /// Seed of every tile's chaos game.
    pub seed: u64,
}

impl Default for TileOptions {
    fn default() -> Self {
        TileOptions {
            points: 1_000_000,
            flame_samples: flame::DEFAULT_FLAME_SAMPLES,
            seed: 0,
        }
    }
}

/// What draws a view's tiles.
#[derive(Debug)]
pub enum TileSource {
    /// A code, by the evaluation renderer with deep zoom.
    Code(TileRenderer),
    /// A flame (or layers of one), by the flame renderer.
    Flame(FlameTiles),
}

impl TileSource {
    /// The modes its tiles come in, the default first.
    pub fn modes(&self) -> &'static [TileMode] {
        match self {
            TileSource::Code(_) => &[TileMode::Coverage, TileMode::Density],
            TileSource::Flame(_) => &[TileMode::Colour],
        }
    }

    /// The tile as a PNG file's bytes; `progress` may cancel it.
    pub fn render_png(&self, req: &TileRequest, progress: &dyn Progress) -> crate::Result<Vec<u8>> {
        match self {
            TileSource::Code(r) => r.render_png(req, progress),
            TileSource::Flame(f) => {
                let rgba = f.render_rgba(req, progress)?;
                tile::encode_png(&rgba, req.size, req.size)
            }
        }
    }
}

/// One panel of the page.
#[derive(Debug)]
pub enum View {
    /// A code or a flame drawn in tiles on demand.
    Tiles {
        /// The name the page and the tile URLs use.
        name: String,
        /// How its tiles are drawn.
        renderer: TileSource,
    },
    /// A picture that covers the base window (a run's target).
    Picture {
        /// The name the page and the picture's URL use.
        name: String,
        /// The PNG file's bytes.
        png: Vec<u8>,
    },
}

impl View {
    /// The view's name.
    pub fn name(&self) -> &str {
        match self {
            View::Tiles { name, .. } | View::Picture { name, .. } => name,
        }
    }
}

/// What a page shows: its views, linked to one base window, and a run's loss curve.
#[derive(Debug)]
pub struct Site {
    /// Shown as the page's title.
    pub title: String,
    /// The base window and its deepest level.
    pub tiling: Tiling,
    /// Side by side, in this order, all showing the same window.
    pub views: Vec<View>,
    /// A run's loss curve (`loss.png`).
    pub loss: Option<Vec<u8>>,
    /// A line the page shows under its title (a flame's depth bound).
    pub note: Option<String>,
}

impl Site {
    /// The site of a run folder (a folder with `code.json`), a code file or a built-in
    /// code's name.
    pub fn load(source: &str, tiles: TileOptions) -> crate::Result<Self> {
        for n in [tiles.points, tiles.flame_samples] {
            if !(1..=MAX_POINTS_PER_TILE).contains(&n) {
                crate::error::bail!(
                    "points per tile must lie in 1..={MAX_POINTS_PER_TILE}, got {n} (--points)"
                );
            }
        }
        let path = Path::new(source);
        if path.is_dir()
            && path.join("learned.flame").is_file()
            && !path.join("code.json").is_file()
        {
            return Self::flame(&path.join("learned.flame"), Some(path), tiles);
        }
        if path.is_dir() {
            return Self::run_folder(path, tiles);
        }
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("flame"))
        {
            return Self::flame(path, None, tiles);
        }
        let code = resolve_code(source)?;
        let name = code.name.clone().unwrap_or_else(|| "code".into());
        let (renderer, tiling) = code_view(&code, tiles)?;
        Ok(Site {
            title: name.clone(),
            tiling,
            views: vec![View::Tiles {
                name: url_name(&name),
                renderer: TileSource::Code(renderer),
            }],
            loss: None,
            note: None,
        })
    }

    /// A flame file's flames (layers laid over one another), and a flame run's target and
    /// loss curve when `run` is its folder.
    fn flame(file: &Path, run: Option<&Path>, tiles: TileOptions) -> crate::Result<Self> {
        let samples = tiles.flame_samples;
        let source = FlameTiles::load(file, None, samples, tiles.seed)?;
        let tiling = source.tiling();
        let deepest = tiling.max_level();
        let note = format!(
            "flame tiles: {samples} samples each, so at most {} samples per pixel at the top and \
             1 or more down to level {deepest} (zoom 2^{deepest}); deeper, the tiles are enlarged \
             (a flame has no deep zoom: 2^L deeper costs 4^L the samples; --points sets them)",
            samples / (tile::TILE_SIZE_DEFAULT as u64).pow(2),
        );
        let stem = file
            .file_stem()
            .map_or("flame".into(), |s| s.to_string_lossy().into_owned());
        let mut views = Vec::new();
        let mut loss = None;
        if let Some(dir) = run {
            let target = dir.join("target.png");
            if target.is_file() {
                let png = std::fs::read(&target).doing("reading", &target)?;
                views.push(View::Picture {
                    name: "target".into(),
                    png,
                });
            }
            let loss_path = dir.join("loss.png");
            if loss_path.is_file() {
                loss = Some(std::fs::read(&loss_path).doing("reading", &loss_path)?);
            }
        }
        views.push(View::Tiles {
            name: url_name(&stem),
            renderer: TileSource::Flame(source),
        });
        Ok(Site {
            title: format!("flame {}", file.display()),
            tiling,
            views,
            loss,
            note: Some(note),
        })
    }

    /// A run folder: `target.png` and `code.json` (framed alike, as the run wrote them)
    /// side by side, and `loss.png`.
    fn run_folder(dir: &Path, tiles: TileOptions) -> crate::Result<Self> {
        let code_path = dir.join("code.json");
        if !code_path.is_file() && dir.join(FIT_FILE).is_file() {
            crate::error::bail!(
                "{} holds a fit of maps that are not affine ({FIT_FILE}, no code.json): the \
                 tile server draws affine codes; `ifslab redraw` draws the run's pictures",
                dir.display()
            );
        }
        if !code_path.is_file() {
            crate::error::bail!(
                "{} is a folder without code.json: give a finished run folder (ifslab invert \
                 or ifslab run), a code file or a built-in code's name",
                dir.display()
            );
        }
        let code = IfsCode::load(&code_path)
            .with_context(|| format!("loading {}", code_path.display()))?;
        let (renderer, tiling) = code_view(&code, tiles)?;
        let mut views = Vec::new();
        let target = dir.join("target.png");
        if target.is_file() {
            let png = std::fs::read(&target).doing("reading", &target)?;
            views.push(View::Picture {
                name: "target".into(),
                png,
            });
        }
        views.push(View::Tiles {
            name: "recovered".into(),
            renderer: TileSource::Code(renderer),
        });
        let loss_path = dir.join("loss.png");
        let loss = match loss_path.is_file() {
            true => Some(std::fs::read(&loss_path).doing("reading", &loss_path)?),
            false => None,
        };
        let title = dir
            .canonicalize()
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| dir.display().to_string());
        Ok(Site {
            title: format!("run {title}"),
            tiling,
            views,
            loss,
            note: None,
        })
    }

    /// The view called `name`.
    pub fn view(&self, name: &str) -> Option<&View> {
        self.views.iter().find(|v| v.name() == name)
    }

    /// What the page needs to draw: the base window, the deepest tile level, the views and
    /// their URLs, the loss curve's URL, the modes and colour maps.
    pub fn info(&self) -> serde_json::Value {
        let base = self.tiling.base();
        let views: Vec<serde_json::Value> = self
            .views
            .iter()
            .map(|v| match v {
                View::Tiles { name, renderer } => serde_json::json!({
                    "name": name, "kind": "tiles", "url": format!("/tile/{name}"),
                    "modes": renderer.modes().iter().map(|m| m.name()).collect::<Vec<_>>(),
                }),
                View::Picture { name, .. } => serde_json::json!({
                    "name": name, "kind": "picture", "url": format!("/picture/{name}.png"),
                }),
            })
            .collect();
        serde_json::json!({
            "title": self.title,
            "base": { "min": base.min, "max": base.max },
            "max_level": self.tiling.max_level(),
            "tile_size": tile::TILE_SIZE_DEFAULT,
            "views": views,
            "loss": self.loss.as_ref().map(|_| "/picture/loss.png"),
            "modes": self.modes(),
            "cmaps": match self.modes().contains(&"colour") {
                true => Vec::new(),
                false => colormap::Colormap::NAMES.to_vec(),
            },
            "note": self.note,
        })
    }

    /// The tile modes of the site's views, each once, in order.
    fn modes(&self) -> Vec<&'static str> {
        let mut modes = Vec::new();
        for v in &self.views {
            if let View::Tiles { renderer, .. } = v {
                for m in renderer.modes() {
                    if !modes.contains(&m.name()) {
                        modes.push(m.name());
                    }
                }
            }
        }
        modes
    }
}

/// A code's tile renderer and its tiling: the code's `framing` if it has one, else the
/// attractor fitted as `ifslab render` fits it, in a square.
fn code_view(code: &IfsCode, tiles: TileOptions) -> crate::Result<(TileRenderer, Tiling)> {
    let maps = code.affine2().context("the viewer draws 2-D codes only")?;
    let probs = code.evaluation_probabilities()?;
    let window = match code.framing {
        Some(w) => w,
        None => {
            let (lo, hi) = ifslab::render::view::pilot_bbox(&maps, &probs, tiles.seed)?;
            fit_window(lo, hi, 1, 1, FIT_FILL)?
        }
    };
    let tiling = Tiling::new(&window)?;
    Ok((
        TileRenderer::new(maps, probs, tiling, tiles.points, tiles.seed),
        tiling,
    ))
}

/// A name safe in a URL path: letters, digits, `-` and `_`, others as `_`.
fn url_name(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() { "code".into() } else { s }
}
