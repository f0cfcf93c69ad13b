//! The evaluation renderer: streams N chaos-game points (default 50 million) into an image
//! without storing them.
//!
//! Two modes:
//! - [`RenderMode::Coverage`]: the papers' ground truth. Every point sets one bit of an
//!   `s×`-supersampled binary buffer; each output pixel is the covered fraction of its
//!   `s×s` sub-pixels (a box downsample). The buffer holds the supersampled grid row by row,
//!   so a pixel's sub-pixels in one row are adjacent bits and the downsample is popcounts.
//! - [`RenderMode::Density`]: hit counts per pixel, log tone-mapped
//!   (`log(1 + c) / log(1 + max c)`).
//!
//! Trajectories run in batches of four on whichever worker thread is free, all writing one
//! buffer by OR (coverage) or saturating sum (density). Both are order-independent, and
//! every trajectory has its own seeded generator, so the image is bit-identical for any
//! thread count and any schedule.
//!
//! The buffer is far larger than the caches, so points are not written where they land:
//! gathered in batches, each is appended to the bin of its buffer tile (each worker has
//! its own bins), and a full bin is written into its tile, locked for the while, after the
//! tile was read in order into the cache ([`bins`]). The trajectories run as a [`PointStream`], compiled
//! for FMA where the CPU has it ([`Isa`]); neither changes a bit of the image.
//!
//! Zoom views generate points everywhere and keep those in the window; `min_hits` asks for
//! more rounds of fresh trajectories until the window has received that many points (or
//! `max_points` were generated), which stays deterministic; `time_limit` caps wall time
//! (its result then depends on the machine's speed).

mod bins;
mod coverage;
mod density;

use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::budget::{MemoryEstimate, check_memory, check_rate};
use crate::chaos::{LANES, MapSampler, PointSink, PointStream, WindowWords, WordSink};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::isa::Isa;
use crate::model::code::Window;
use crate::model::{Affine2, Map2};
use crate::progress::Progress;
use crate::render::view::{FIT_FILL, View, Zoom, fit_window, pilot_bbox, zoom_window};

/// What each pixel measures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RenderMode {
    /// Fraction of covered sub-pixels (binary supersampling).
    #[default]
    Coverage,
    /// Log tone-mapped hit counts.
    Density,
}

/// Everything a render needs besides the code.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderConfig {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Points generated per round (after warm-up).
    pub points: u64,
    /// Supersampling factor per side (coverage mode).
    pub supersample: u32,
    /// What each pixel measures.
    pub mode: RenderMode,
    /// Trajectories per round; `0` picks `min(1024, points / 256)`.
    pub trajectories: usize,
    /// Steps dropped at the start of each trajectory.
    pub warmup: usize,
    /// Seed of the run (trajectory generators and pilot run).
    pub seed: u64,
    /// Fit the attractor or use a fixed window.
    pub view: View,
    /// Optional zoom applied to the window.
    pub zoom: Option<Zoom>,
    /// Keep generating rounds until this many points landed in the window (0: one round).
    pub min_hits: u64,
    /// Cap on points generated in all rounds when `min_hits` is set (0: 64 × `points`).
    pub max_points: u64,
    /// Optional wall-clock cap in seconds on the rounds (not deterministic).
    pub time_limit: Option<f64>,
    /// Draw a zoomed view of an affine code through the words of the code whose images
    /// meet the window ([`WindowWords`]): nearly every point lands in the window, so a zoom
    /// at any depth (to about 2⁴³) costs what the full view costs. The image has the plain
    /// game's distribution, not its bits. A code whose maps overlap so much that the window
    /// needs more than [`DEEP_ZOOM_MAX_WORDS`] words is drawn the plain way. Off by default
    /// in the library (the suites' zoomed views were drawn without it); `ifslab render
    /// --zoom` and a run's zoom strip turn it on.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub deep_zoom: bool,
}

/// Most words a deep zoom keeps ([`RenderConfig::deep_zoom`]); 48 bytes each.
pub const DEEP_ZOOM_MAX_WORDS: usize = 200_000;

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            width: 1024,
            height: 1024,
            points: 50_000_000,
            supersample: 1,
            mode: RenderMode::Coverage,
            trajectories: 0,
            warmup: 100,
            seed: 0,
            view: View::Fit,
            zoom: None,
            min_hits: 0,
            max_points: 0,
            time_limit: None,
            deep_zoom: false,
        }
    }
}

impl RenderConfig {
    /// Checks every field; the error names the one to change.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::param("size", "width and height must be at least 1"));
        }
        if self.supersample == 0 || self.supersample > 64 {
            return Err(Error::param(
                "supersample",
                format!("must lie in 1..=64, got {}", self.supersample),
            ));
        }
        if self.points == 0 {
            return Err(Error::param("points", "must be at least 1"));
        }
        if let Some(z) = &self.zoom
            && !(z.factor.is_finite() && z.factor > 0.0)
        {
            return Err(Error::param(
                "zoom",
                format!("factor must be finite and > 0, got {}", z.factor),
            ));
        }
        if let View::Window(w) = &self.view {
            w.validate()?;
        }
        if let Some(t) = self.time_limit
            && !(t.is_finite() && t > 0.0)
        {
            return Err(Error::param(
                "time_limit",
                format!("must be > 0 seconds, got {t}"),
            ));
        }
        Ok(())
    }

    /// What the render's buffers take on `threads` worker threads: the accumulator
    /// (coverage bits of the supersampled grid, or a count per pixel), each thread's tile
    /// bins (half as much again per thread), and the image's values and its PNG.
    pub fn memory_estimate(&self, threads: usize) -> MemoryEstimate {
        let (w, h, s) = (
            self.width as u64,
            self.height as u64,
            self.supersample as u64,
        );
        let (buffer, tile, label) = match self.mode {
            RenderMode::Coverage => (
                (w * s).div_ceil(64) * 8 * h * s,
                coverage::tile_bytes(self.width, self.height, self.supersample),
                "coverage bits",
            ),
            RenderMode::Density => (
                w * h * 4,
                density::tile_bytes(self.width, self.height),
                "counts",
            ),
        };
        // The buffer is padded to whole tiles.
        let buffer = buffer.div_ceil(tile) * tile;
        let bins = bins::bin_bytes(buffer, tile);
        MemoryEstimate::new()
            .with(label, buffer)
            .with(
                format!("tile bins × {threads} threads"),
                bins.saturating_mul(threads.max(1) as u64),
            )
            .with("image", w * h * 4)
            .with("PNG", w * h * 2)
    }

    fn trajectories_per_round(&self) -> usize {
        if self.trajectories > 0 {
            self.trajectories
        } else {
            (self.points / 256).clamp(1, 1024) as usize
        }
    }
}

/// What a render did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RenderStats {
    /// The window the image shows.
    pub window: Window,
    /// Points generated (after warm-up) in all rounds.
    pub points_generated: u64,
    /// Points that landed in the window.
    pub points_in_window: u64,
    /// Rounds of trajectories run.
    pub rounds: u32,
    /// Wall-clock seconds of the render (pilot run included).
    pub seconds: f64,
    /// Whether the time limit stopped the rounds before `min_hits` was reached.
    pub stopped_by_time: bool,
    /// The share of the invariant measure μ the points were drawn from: Σ p_w over the
    /// deep-zoom words the points were sent through ([`RenderConfig::deep_zoom`],
    /// [`WindowWords::mass`]), 1 for the plain chaos game. A region of the window holds
    /// about `sampled_mass × its points / points_generated` of μ (the words' images cover
    /// all of μ in the window, and a point sent through them is distributed as μ there
    /// divided by `sampled_mass`).
    #[serde(default = "unit_mass")]
    pub sampled_mass: f64,
    /// Density mode: the largest hit count of a pixel, the top of the tone map (a pixel of
    /// `c` hits has the value `ln(1 + c) / ln(1 + max_count)`); 0 in coverage mode.
    #[serde(default)]
    pub max_count: u64,
}

/// [`RenderStats::sampled_mass`] of a record written without it: the plain game's.
fn unit_mass() -> f64 {
    1.0
}

/// A render and how it was made: a grey [`Image`], values in [0, 1] (1 = attractor), row 0
/// at the top (largest y). It reads as its image (`raster.values`, `raster.width`).
#[derive(Clone, Debug)]
pub struct Raster {
    /// The render.
    pub image: Image,
    /// How it was made.
    pub stats: RenderStats,
}

impl std::ops::Deref for Raster {
    type Target = Image;

    fn deref(&self) -> &Image {
        &self.image
    }
}

/// The world → super-resolution mapping shared by both accumulators.
#[derive(Clone, Copy)]
pub(crate) struct PixelMap {
    x0: f64,
    y1: f64,
    /// Supersampled pixels per world unit.
    kx: f64,
    ky: f64,
    /// Grid size in supersampled pixels.
    w: f64,
    h: f64,
    /// Cells per row of the accumulator's grid.
    row: u64,
    s: u64,
    /// `log2 s` when `s` is a power of two (shifts instead of divisions).
    shift: Option<u32>,
    /// Whether the grid's coordinates fit an `i32` and its rows' cells a `u32`.
    narrow: bool,
}

impl PixelMap {
    fn new(win: &Window, width: u32, height: u32, s: u32, row: u64) -> Self {
        let size = win.size();
        let sf = s as f64;
        PixelMap {
            x0: win.min[0],
            y1: win.max[1],
            kx: width as f64 * sf / size[0],
            ky: height as f64 * sf / size[1],
            w: width as f64 * sf,
            h: height as f64 * sf,
            row,
            s: s as u64,
            shift: s.is_power_of_two().then(|| s.trailing_zeros()),
            narrow: width as u64 * s as u64 <= 1 << 31
                && height as u64 * s as u64 <= 1 << 31
                && row <= u32::MAX as u64,
        }
    }

    /// The supersampled pixel `(x, y)` of a point, or `None` outside the window (and for
    /// non-finite points, whose comparisons fail).
    #[inline(always)]
    fn grid(&self, p: [f64; 2]) -> Option<(u64, u64)> {
        let fx = (p[0] - self.x0) * self.kx;
        let fy = (self.y1 - p[1]) * self.ky;
        if (fx >= 0.0) & (fx < self.w) & (fy >= 0.0) & (fy < self.h) {
            // SAFETY: 0 ≤ fx < w ≤ 2^32 · 64 and likewise fy (neither is NaN, both
            // comparisons held), so both truncate to integers an i64 represents.
            let (x, y) = unsafe { (fx.to_int_unchecked::<i64>(), fy.to_int_unchecked::<i64>()) };
            Some((x as u64, y as u64))
        } else {
            None
        }
    }

    /// The sub-pixel cell of a point (row-major in the supersampled grid).
    #[inline(always)]
    fn subpixel_cell(&self, p: [f64; 2]) -> Option<u64> {
        let (x, y) = self.grid(p)?;
        Some(y * self.row + x)
    }

    /// The output-pixel cell of a point (row-major).
    #[inline(always)]
    fn pixel_cell(&self, p: [f64; 2]) -> Option<u64> {
        let (x, y) = self.grid(p)?;
        let (px, py) = match self.shift {
            Some(k) => (x >> k, y >> k),
            None => (x / self.s, y / self.s),
        };
        Some(py * self.row + px)
    }
}

/// Bins a stream's in-window points: points are gathered [`bins::BATCH`] at a time, their
/// cells computed in one loop and appended to the bins in another, so neither the chaos
/// game's loop nor these carry each other's state.
struct BinSink<'b, 't, 'a, A: Accumulator> {
    pm: PixelMap,
    isa: Isa,
    bins: bins::BinWriter<'b, 't, 'a, A>,
    /// Points gathered so far.
    n: usize,
    points: [[f64; 2]; bins::BATCH],
    cells: [u64; bins::BATCH],
}

const _: () = assert!(bins::BATCH.is_multiple_of(LANES));

impl<'b, 't, 'a, A: Accumulator> BinSink<'b, 't, 'a, A> {
    fn new(pm: PixelMap, isa: Isa, bins: bins::BinWriter<'b, 't, 'a, A>) -> Self {
        BinSink {
            pm,
            isa,
            bins,
            n: 0,
            points: [[0.0; 2]; bins::BATCH],
            cells: [0; bins::BATCH],
        }
    }

    /// Bins the points gathered so far.
    #[inline(never)]
    fn drain(&mut self) {
        let n = std::mem::take(&mut self.n);
        let (points, cells) = (&self.points[..n], &mut self.cells[..n]);
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the renderer's `isa` passed `Isa::checked`: `Fma` only where the CPU
            // has AVX2, FMA and BMI1/2.
            Isa::Fma => unsafe { bin_fma::<A>(&self.pm, points, cells, &mut self.bins) },
            _ => bin::<A>(&self.pm, points, cells, &mut self.bins),
        }
    }

    /// Bins what is left.
    fn finish(mut self) {
        if self.n > 0 {
            self.drain();
        }
    }
}

/// The accumulator's cell of each point, `u64::MAX` outside the window.
#[inline(always)]
fn cells_of<A: Accumulator>(pm: &PixelMap, points: &[[f64; 2]], cells: &mut [u64]) {
    if pm.narrow {
        // The loop of `PixelMap::grid` without its branch, in 32-bit integers (four points
        // per AVX2 instruction): the same cells.
        let (row, s) = (pm.row as u32, pm.s as u32);
        for (c, &p) in cells.iter_mut().zip(points) {
            let fx = (p[0] - pm.x0) * pm.kx;
            let fy = (pm.y1 - p[1]) * pm.ky;
            let inside = (fx >= 0.0) & (fx < pm.w) & (fy >= 0.0) & (fy < pm.h);
            let (fx, fy) = if inside { (fx, fy) } else { (0.0, 0.0) };
            // SAFETY: 0 ≤ fx < w ≤ 2^31 and 0 ≤ fy < h ≤ 2^31 (`narrow`), or both are 0.
            let (x, y) = unsafe { (fx.to_int_unchecked::<i32>(), fy.to_int_unchecked::<i32>()) };
            let (x, y) = (x as u32, y as u32);
            let (x, y) = match (A::SUBPIXELS, pm.shift) {
                (true, _) => (x, y),
                (false, Some(k)) => (x >> k, y >> k),
                (false, None) => (x / s, y / s),
            };
            let cell = y as u64 * row as u64 + x as u64;
            *c = if inside { cell } else { u64::MAX };
        }
        return;
    }
    for (c, &p) in cells.iter_mut().zip(points) {
        let cell = if A::SUBPIXELS {
            pm.subpixel_cell(p)
        } else {
            pm.pixel_cell(p)
        };
        *c = cell.unwrap_or(u64::MAX);
    }
}

/// The points' cells ([`cells_of`], into `cells`) appended to the bins.
#[inline(always)]
fn bin<A: Accumulator>(
    pm: &PixelMap,
    points: &[[f64; 2]],
    cells: &mut [u64],
    bins: &mut bins::BinWriter<'_, '_, '_, A>,
) {
    cells_of::<A>(pm, points, cells);
    bins.push(cells);
}

/// [`bin`] compiled for AVX2 and BMI2 ([`crate::isa`]); the same cells.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2")]
fn bin_fma<A: Accumulator>(
    pm: &PixelMap,
    points: &[[f64; 2]],
    cells: &mut [u64],
    bins: &mut bins::BinWriter<'_, '_, '_, A>,
) {
    bin::<A>(pm, points, cells, bins)
}

impl<A: Accumulator> PointSink for BinSink<'_, '_, '_, A> {
    #[inline(always)]
    fn put(&mut self, p: [f64; 2]) {
        self.points[self.n] = p;
        self.n += 1;
        if self.n == bins::BATCH {
            self.drain();
        }
    }

    #[inline(always)]
    fn put_lanes(&mut self, ps: [[f64; 2]; LANES]) {
        if self.n + LANES > bins::BATCH {
            self.drain();
        }
        self.points[self.n..self.n + LANES].copy_from_slice(&ps);
        self.n += LANES;
        if self.n == bins::BATCH {
            self.drain();
        }
    }
}

/// Accumulates points in a buffer of cells (bits or counts) cut into tiles of
/// `2^tile_shift` contiguous cells, which every thread's bins write into.
pub(crate) trait Accumulator: Send {
    /// What the buffer is made of.
    type Word: Send + Copy + Default + std::ops::BitOr<Output = Self::Word>;
    /// Whether cells are sub-pixels (else output pixels), row by row.
    const SUBPIXELS: bool;
    /// Bits per cell.
    const CELL_BITS: u32;
    /// Cells per row (at least the grid's width).
    fn row_cells(&self) -> u64;
    /// `log2` of the cells per tile.
    fn tile_shift(&self) -> u32;
    /// Words per tile.
    fn tile_words(&self) -> usize;
    /// The buffer, padded to whole tiles.
    fn words_mut(&mut self) -> &mut [Self::Word];
    /// Records one point on each cell `offset mod 2^tile_shift` of a tile's words.
    fn write_tile(tile: &mut [Self::Word], offsets: &[u32]);
    /// Final pixel values in [0, 1], and the largest count of a pixel (density; 0 for
    /// coverage).
    fn finish(self, width: u32, height: u32) -> (Vec<f32>, u64);
}

/// The evaluation renderer's speed used to estimate a job's time before it starts: points
/// per second and thread, on the fast side of what this machine measures (BENCHMARKS.md),
/// so that only jobs that would surely run past the work budget are refused.
pub const POINTS_PER_SECOND_PER_THREAD: f64 = 1e8;

/// Renders the attractor of `maps` (drawn with `probs`) as configured.
pub fn render<M: Map2>(
    maps: &[M],
    probs: &[f64],
    cfg: &RenderConfig,
    progress: Option<&dyn Progress>,
) -> Result<Raster> {
    render_with_isa(maps, probs, cfg, progress, Isa::detect())
}

/// [`render`] with the chaos game compiled for `isa` (an error if this CPU lacks it). The
/// image is the same on every instruction set; this exists to show it and to measure.
pub fn render_with_isa<M: Map2>(
    maps: &[M],
    probs: &[f64],
    cfg: &RenderConfig,
    progress: Option<&dyn Progress>,
    isa: Isa,
) -> Result<Raster> {
    cfg.validate()?;
    let threads = rayon::current_num_threads();
    check_memory(
        &cfg.memory_estimate(threads),
        "the size (--size) or the supersampling (--supersample)",
    )?;
    // The most points the rounds may generate; a time limit bounds the work itself.
    if cfg.time_limit.is_none() {
        let most = if cfg.min_hits > 0 {
            if cfg.max_points > 0 {
                cfg.max_points
            } else {
                cfg.points.saturating_mul(64)
            }
        } else {
            cfg.points
        };
        check_rate(
            most as f64,
            POINTS_PER_SECOND_PER_THREAD,
            threads,
            "points",
            &format!("{most} points"),
            "the points (--points, or --max-points with --min-hits)",
        )?;
    }
    let isa = isa.checked()?;
    if maps.is_empty() {
        return Err(Error::Empty("the code has no maps".into()));
    }
    let sampler = MapSampler::new(probs)?;
    if sampler.len() != maps.len() {
        return Err(Error::Shape(format!(
            "{} probabilities for {} maps",
            sampler.len(),
            maps.len()
        )));
    }
    let start = Instant::now();
    let base = match cfg.view {
        View::Window(w) => w,
        View::Fit => {
            let (lo, hi) = pilot_bbox(maps, probs, cfg.seed)?;
            fit_window(lo, hi, cfg.width, cfg.height, FIT_FILL)?
        }
    };
    let window = match &cfg.zoom {
        Some(z) => zoom_window(&base, z)?,
        None => base,
    };
    let words = deep_zoom_words(maps, probs, cfg, &window)?;
    let stream = PointStream::new(maps, &sampler, cfg.seed, 1.0, cfg.warmup)?.with_isa(isa)?;
    let (values, counts) = match cfg.mode {
        RenderMode::Coverage => run_rounds(
            &stream,
            words.as_ref(),
            cfg,
            &window,
            progress,
            start,
            coverage::Coverage::new(cfg.width, cfg.height, cfg.supersample),
        )?,
        RenderMode::Density => run_rounds(
            &stream,
            words.as_ref(),
            cfg,
            &window,
            progress,
            start,
            density::Density::new(cfg.width, cfg.height),
        )?,
    };
    Ok(Raster {
        image: Image::grey(cfg.width, cfg.height, values)?,
        stats: RenderStats {
            window,
            points_generated: counts.0,
            points_in_window: counts.1,
            rounds: counts.2,
            seconds: start.elapsed().as_secs_f64(),
            stopped_by_time: counts.3,
            sampled_mass: words.as_ref().map_or(1.0, WindowWords::mass),
            max_count: counts.4,
        },
    })
}

/// The words a deep zoom draws through: only for a zoomed view of affine maps with
/// [`RenderConfig::deep_zoom`] on, and only when the window needs more than the whole
/// attractor (a window around all of it keeps the plain game's bits).
fn deep_zoom_words<M: Map2>(
    maps: &[M],
    probs: &[f64],
    cfg: &RenderConfig,
    window: &Window,
) -> Result<Option<WindowWords>> {
    if !cfg.deep_zoom || cfg.zoom.is_none() {
        return Ok(None);
    }
    let Some(affine) = maps.iter().map(Affine2::of_map).collect::<Option<Vec<_>>>() else {
        return Ok(None);
    };
    // A window that misses the attractor is drawn the plain way (an empty view), and so is
    // one that would need too many words (maps that overlap heavily: a fitted code of many
    // near-unit maps can need millions at 64×).
    match WindowWords::new(&affine, probs, window, 0.5, DEEP_ZOOM_MAX_WORDS) {
        Ok(words) => Ok(words.filter(|w| w.depth() > 0)),
        Err(Error::TooManyWords { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}

/// Points generated, points in the window, rounds, whether the time limit stopped them,
/// the largest count of a pixel (density).
type RoundCounts = (u64, u64, u32, bool, u64);

fn run_rounds<M: Map2, A: Accumulator>(
    stream: &PointStream<'_, M>,
    words: Option<&WindowWords>,
    cfg: &RenderConfig,
    window: &Window,
    progress: Option<&dyn Progress>,
    start: Instant,
    mut acc: A,
) -> Result<(Vec<f32>, RoundCounts)> {
    let t = cfg.trajectories_per_round();
    let max_points = if cfg.max_points > 0 {
        cfg.max_points
    } else {
        cfg.points.saturating_mul(64)
    };
    if let Some(pb) = progress {
        pb.set_length(cfg.points);
    }
    let pm = PixelMap::new(
        window,
        cfg.width,
        cfg.height,
        cfg.supersample,
        acc.row_cells(),
    );
    let tiles = bins::Tiles::new(&mut acc, stream.isa());
    // One set of bins per worker thread, kept across rounds, all in front of the one
    // buffer. Workers take batches of trajectories as they become free (a busy machine
    // does not leave one thread waiting for another); which bins a trajectory lands in does
    // not change the image.
    let threads = rayon::current_num_threads().max(1);
    let bins: Vec<Mutex<bins::Bins<'_, '_, A>>> = (0..threads)
        .map(|_| Mutex::new(bins::Bins::new(&tiles)))
        .collect();
    let batches = t.div_ceil(LANES);
    let (mut generated, mut rounds, mut by_time) = (0u64, 0u32, false);
    let hits = loop {
        let first = rounds as u64 * t as u64;
        let results: Vec<Result<()>> = (0..batches)
            .into_par_iter()
            .map(|b| {
                if progress.is_some_and(|p| p.cancelled()) {
                    return Err(Error::Cancelled(
                        "the render's caller stopped waiting".into(),
                    ));
                }
                let (lo, hi) = (b * LANES, ((b + 1) * LANES).min(t));
                let ns: Vec<u64> = (lo..hi).map(|j| points_of(cfg.points, t, j)).collect();
                let slot = rayon::current_thread_index().unwrap_or(0) % threads;
                let mut own = bins::lock(&bins[slot]);
                let mut sink = BinSink::new(pm, stream.isa(), own.writer());
                match words {
                    Some(w) => {
                        let mut words = WordSink::new(w, sink);
                        stream.run(first + lo as u64, &ns, &mut words)?;
                        words.into_inner().finish();
                    }
                    None => {
                        stream.run(first + lo as u64, &ns, &mut sink)?;
                        sink.finish();
                    }
                }
                if let Some(pb) = progress {
                    pb.inc(ns.iter().sum());
                }
                Ok(())
            })
            .collect();
        // The first failing batch in trajectory order, whatever ran first.
        results.into_iter().collect::<Result<()>>()?;
        let hits: u64 = bins.iter().map(|b| bins::lock(b).recorded()).sum();
        generated += cfg.points;
        rounds += 1;
        if cfg.min_hits == 0 || hits >= cfg.min_hits || generated >= max_points {
            break hits;
        }
        if let Some(limit) = cfg.time_limit
            && start.elapsed().as_secs_f64() > limit
        {
            by_time = true;
            break hits;
        }
        if let Some(pb) = progress {
            pb.set_length(generated + cfg.points);
        }
    };
    bins.into_par_iter().for_each(|b| {
        b.into_inner().unwrap_or_else(|e| e.into_inner()).flush();
    });
    drop(tiles);
    let (values, max_count) = acc.finish(cfg.width, cfg.height);
    Ok((values, (generated, hits, rounds, by_time, max_count)))
}

/// Points kept by trajectory `i` of `t` when a round has `total` points.
fn points_of(total: u64, t: usize, i: usize) -> u64 {
    let base = total / t as u64;
    base + u64::from((i as u64) < total % t as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimate the memory budget checks is what the accumulator and each thread's
    /// bins allocate.
    #[test]
    fn memory_estimate_is_what_the_buffers_take() {
        fn check<A: Accumulator>(mut acc: A, cfg: &RenderConfig, label: &str) {
            let buffer = (std::mem::size_of_val(acc.words_mut())) as u64;
            let tiles = bins::Tiles::new(&mut acc, Isa::Portable);
            let bin = bins::Bins::new(&tiles).bytes();
            let est = cfg.memory_estimate(3);
            let part = |name: &str| {
                est.parts()
                    .into_iter()
                    .find(|p| p.0 == name)
                    .map(|p| p.1)
                    .unwrap()
            };
            let what = format!("{}×{} at {}×", cfg.width, cfg.height, cfg.supersample);
            assert_eq!(part(label), buffer, "{what}");
            assert_eq!(part("tile bins × 3 threads"), 3 * bin, "{what}");
        }
        for (width, height, supersample) in [(1024, 1024, 16), (97, 61, 3), (300, 200, 1)] {
            let cfg = RenderConfig {
                width,
                height,
                supersample,
                ..RenderConfig::default()
            };
            let acc = coverage::Coverage::new(width, height, supersample);
            check(acc, &cfg, "coverage bits");
            let cfg = RenderConfig {
                mode: RenderMode::Density,
                ..cfg
            };
            check(density::Density::new(width, height), &cfg, "counts");
        }
    }

    /// The 32-bit cell loop gives the cells of the general one, inside the window, at its
    /// edges and outside it (non-finite points included).
    #[test]
    fn narrow_cells_equal_wide_cells() {
        let win = Window {
            min: [-1.25, -0.75],
            max: [1.5, 1.0],
        };
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut points: Vec<[f64; 2]> = (0..4000)
            .map(|_| [next() * 3.5 - 1.75, next() * 2.5 - 1.25])
            .collect();
        points.extend([
            win.min,
            win.max,
            [win.min[0], win.max[1]],
            [win.max[0], win.min[1]],
            [f64::NAN, 0.0],
            [0.0, f64::INFINITY],
            [f64::NEG_INFINITY, 0.0],
        ]);
        fn check<A: Accumulator>(pm: PixelMap, points: &[[f64; 2]], what: &str) {
            assert!(pm.narrow, "{what}");
            let wide = PixelMap {
                narrow: false,
                ..pm
            };
            for chunk in points.chunks(bins::BATCH) {
                let (mut a, mut b) = (vec![0; chunk.len()], vec![1; chunk.len()]);
                cells_of::<A>(&pm, chunk, &mut a);
                cells_of::<A>(&wide, chunk, &mut b);
                assert_eq!(a, b, "{what}");
                assert!(a.contains(&u64::MAX) && a.iter().any(|&c| c < u64::MAX));
            }
        }
        for (w, h, s) in [(97, 61, 3), (1024, 1024, 16), (300, 200, 1), (50, 40, 4)] {
            let row = coverage::Coverage::new(w, h, s).row_cells();
            let pm = PixelMap::new(&win, w, h, s, row);
            check::<coverage::Coverage>(pm, &points, &format!("coverage {w}×{h} at {s}×"));
            let pm = PixelMap::new(&win, w, h, s, w as u64);
            check::<density::Density>(pm, &points, &format!("density {w}×{h} at {s}×"));
        }
    }

    #[test]
    fn trajectory_split_sums_to_total() {
        for (total, t) in [(10u64, 3usize), (1000, 1024), (50_000_000, 1024)] {
            let s: u64 = (0..t).map(|i| points_of(total, t, i)).sum();
            assert_eq!(s, total);
        }
    }
}
