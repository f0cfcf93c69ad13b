//! The fractal flame renderer: flam3's algorithm (Draves & Reckase), deterministic and
//! parallel.
//!
//! 1. **Chaos game** ([`chaos`]): `quality · width · height · 4^zoom` samples per image in
//!    trajectories of 10 000 plotted points after 15 unplotted steps (flam3-render's
//!    sub-batches and fuse), each trajectory with its own generator seeded by
//!    `(seed, pass, trajectory)`. Transforms are chosen through flam3's 16384-entry table
//!    (with xaos rows), bad values restart from a random point, the final transform is
//!    applied to the plotted point only.
//! 2. **Histogram**: the palette colour (× 255, integer) and hit count of every point, at
//!    `supersample²` cells per pixel plus a gutter for the filters. Each thread fills its own
//!    histogram over a fixed block of trajectories; integer sums merge exactly, so the image
//!    is the same for any thread count (flam3's own threads race and are not reproducible).
//! 3. **Density estimation and log scaling** ([`density`]): `k1·ln(1 + k2·a)/a` with
//!    flam3's constants, spread by density-dependent Gaussian kernels.
//! 4. **Spatial filter and tone map** ([`filter`], [`tonemap`]): flam3's kernels, gamma
//!    with the linear range below `gamma_threshold`, vibrancy, highlight power, background.
//!
//! Images are RGBA with rows from the smallest y (flam3's +y-down camera), written as 8- or
//! 16-bit PNG with or without alpha like `flam3-render`.
//!
//! ## Agreement with flam3
//!
//! `tests/flame_images.rs` renders 117 flam3-genome flames (one per variation, mixed ones,
//! and copies with other camera, filter and tone-map settings) and compares them with
//! flam3-render's PNGs: over all of them the mean SSIM is the one flam3 reaches against
//! itself with another seed. One pair of renders is a poor judge of a difference, though: at
//! the fixtures' 128² and quality 250 the SSIM of a single pair of flam3's own renders from
//! two seeds spreads by ~0.01 (standard deviation) on sparse pictures, so
//! `scripts/flame_seed_spread.sh` compares six renders from each program (15 flam3 pairs,
//! 15 of ours, 36 mixed). Measured with it (mean SSIM, ours against flam3 / flam3 against
//! flam3 / ours against ours):
//! - vibrancy 0.5 with highlight power 1 and gamma threshold 0.1 (`f01`): 0.9746 / 0.9755 /
//!   0.9763 — noise (the single pair in the test scores 0.970 against 0.981 by chance; with
//!   vibrancy 0 at quality 1000 the mixed and flam3 pairs score 0.9772 and 0.9769, where
//!   two pairs of seeds had given 0.976 and 0.987). With density estimation switched off
//!   the single pairs agree to the fourth digit: density estimation spreads lone hits into
//!   discs that `(1 − vibrancy)·256·(channel/255)^(1/gamma)` lifts into view, which makes
//!   these pictures noisy, in flam3 as here;
//! - filters with negative lobes at the sampled points (`mitchell`, `lanczos3`, `hanning`,
//!   `hamming` at radius 1.2; fixtures `f06`–`f09`) leave negative or NaN channels along
//!   the attractor's edges, which flam3's clamps turn into white specks (its `-ffast-math`
//!   build clamps with `minsd` taking 255 when the value is NaN); we do the same. Mitchell
//!   0.8642 / 0.8687 / 0.8715, lanczos3 0.8749 / 0.8781 / 0.8833, hanning 0.8776 / 0.8808 /
//!   0.8857, hamming 0.8548 / 0.8582 / 0.8624: ours against flam3 sits 0.003–0.005 below
//!   flam3 against itself, a third to half of one pair's spread, and our renders are as
//!   much closer to each other; we draw 2–3 % fewer saturated pixels (mean of six renders:
//!   705 against 722 on mitchell, 630 against 653 on hamming). Kernel values,
//!   normalisation, the gutter and the order of filter and tone map are flam3's
//!   (`filters.c`, `rect.c`); the single pairs of the test (0.849 against 0.885 on mitchell)
//!   were mostly the draw of the seeds. A linear flame without those filters (`m06`):
//!   0.9824 / 0.9824 / 0.9822.
//!
//! ## References
//! - S. Draves, E. Reckase, "The Fractal Flame Algorithm", 2008.
//! - flam3 3.1.1 (`rect.c`, `filters.c`, `palettes.c`): constants and conventions.

mod chaos;
pub mod composite;
mod density;
pub mod draft;
pub mod filter;
mod tonemap;

use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::chaos::{mix_seed, trajectory_rng};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::io::write_atomic;
use crate::isa::Isa;
use crate::model::flame::{Flame, PreparedXform};
use crate::progress::Progress;

use chaos::{Camera, Colors, Game, GameStats, HIT_BATCH, Histogram, Selector};
use filter::{DensityFilters, SpatialFilter};
use tonemap::Tone;

pub use composite::Composite;

/// How to render a flame, beyond what the flame itself says.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FlameRenderConfig {
    /// Seed of the trajectories' generators.
    pub seed: u64,
    /// Plotted points per trajectory (flam3-render's `sub_batch_size`).
    pub trajectory_length: u64,
    /// Unplotted steps at the start of each trajectory (flam3's fuse).
    pub fuse: usize,
    /// Most memory the per-thread histograms may take together, in bytes; fewer thread
    /// histograms are used beyond it (the image does not change).
    pub histogram_budget: u64,
    /// Keep transparency: pixels are divided by their alpha instead of composited onto
    /// the background (flam3-render `transparency=1`); write the PNG with alpha.
    pub transparent: bool,
}

impl Default for FlameRenderConfig {
    fn default() -> Self {
        FlameRenderConfig {
            seed: 0,
            trajectory_length: 10_000,
            fuse: 15,
            histogram_budget: 4 << 30,
            transparent: false,
        }
    }
}

/// What a render did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FlameStats {
    /// Samples iterated (plotted or not), fuse excluded.
    pub samples: u64,
    /// Samples that landed in the histogram.
    pub hits: u64,
    /// flam3's bad values: steps that produced NaN or a coordinate beyond ±10¹⁰ and were
    /// restarted from a random point. A large fraction means the flame diverges.
    pub badvals: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// A rendered flame as flam3 keeps it: RGB in [0, 255] and alpha in [0, 1] per pixel
/// (interleaved, what its PNG writer and the 8-bit comparisons read), rows top first;
/// [`FlameImage::to_image`] and [`FlameImage::grey`] give it as the stack's [`Image`].
#[derive(Clone, Debug)]
pub struct FlameImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major pixels.
    pub pixels: Vec<[f32; 4]>,
    /// How it was made.
    pub stats: FlameStats,
}

/// Bits per channel of a written PNG.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Depth {
    /// 8 bits, as flam3-render's default.
    #[default]
    Eight,
    /// 16 bits (flam3-render `bpc=16`: values up to 255·256).
    Sixteen,
}

impl FlameImage {
    /// 8-bit RGBA as flam3-render writes it (truncated, alpha opaque unless `alpha`).
    pub fn to_rgba8(&self, alpha: bool) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.pixels.len() * 4);
        for p in &self.pixels {
            out.extend([p[0] as u8, p[1] as u8, p[2] as u8]);
            out.push(if alpha {
                (p[3] as f64 * 255.0) as u8
            } else {
                255
            });
        }
        out
    }

    /// The luminance image in [0, 1] (Rec. 709 weights on the 8-bit values), what the
    /// comparisons with flam3 measure.
    pub fn grey(&self) -> Image {
        let values = self
            .pixels
            .iter()
            .map(|p| {
                let q = |v: f32| (v as u8) as f32 / 255.0;
                0.2126 * q(p[0]) + 0.7152 * q(p[1]) + 0.0722 * q(p[2])
            })
            .collect();
        Image {
            width: self.width,
            height: self.height,
            channels: 1,
            values,
        }
    }

    /// The render as the stack's [`Image`]: four planes, RGB scaled to [0, 1] and alpha, at
    /// the full precision of the histogram's tone map (not truncated to 8 bits).
    pub fn to_image(&self) -> Image {
        let n = self.pixels.len();
        let mut values = vec![0.0f32; 4 * n];
        for (i, p) in self.pixels.iter().enumerate() {
            for c in 0..3 {
                values[c * n + i] = p[c] / 255.0;
            }
            values[3 * n + i] = p[3];
        }
        Image {
            width: self.width,
            height: self.height,
            channels: 4,
            values,
        }
    }

    /// Writes a PNG: RGB, or RGBA when `alpha`; 8 or 16 bits per channel.
    pub fn save_png(&self, path: &Path, depth: Depth, alpha: bool) -> Result<()> {
        use image::{ExtendedColorType, ImageEncoder, codecs::png::PngEncoder};
        let (w, h) = (self.width, self.height);
        let mut bytes = Vec::new();
        let enc = PngEncoder::new(&mut bytes);
        let res = match depth {
            Depth::Eight => {
                let rgba = self.to_rgba8(alpha);
                if alpha {
                    enc.write_image(&rgba, w, h, ExtendedColorType::Rgba8)
                } else {
                    let rgb: Vec<u8> = rgba
                        .chunks_exact(4)
                        .flat_map(|c| [c[0], c[1], c[2]])
                        .collect();
                    enc.write_image(&rgb, w, h, ExtendedColorType::Rgb8)
                }
            }
            Depth::Sixteen => {
                // The encoder takes 16-bit samples in native byte order.
                let mut data: Vec<u8> = Vec::with_capacity(self.pixels.len() * 8);
                for p in &self.pixels {
                    for &v in &p[..3] {
                        data.extend(((v as f64 * 256.0) as u16).to_ne_bytes());
                    }
                    if alpha {
                        data.extend(((p[3] as f64 * 65535.0) as u16).to_ne_bytes());
                    }
                }
                let t = if alpha {
                    ExtendedColorType::Rgba16
                } else {
                    ExtendedColorType::Rgb16
                };
                enc.write_image(&data, w, h, t)
            }
        };
        res.map_err(|e| Error::Image {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        write_atomic(path, &bytes)
    }
}

/// Renders `flame` as flam3-render would (one temporal sample), deterministically for
/// `cfg.seed` whatever the thread count, on the instruction set this CPU has best.
pub fn render_flame(
    flame: &Flame,
    cfg: &FlameRenderConfig,
    progress: Option<&dyn Progress>,
) -> Result<FlameImage> {
    render_flame_with_isa(flame, cfg, progress, Isa::detect())
}

/// [`render_flame`] with the chaos game on instruction set `isa` (an error if this CPU
/// lacks it): the same image on every instruction set.
pub fn render_flame_with_isa(
    flame: &Flame,
    cfg: &FlameRenderConfig,
    progress: Option<&dyn Progress>,
    isa: Isa,
) -> Result<FlameImage> {
    let isa = isa.checked()?;
    let start = Instant::now();
    flame.validate()?;
    if cfg.trajectory_length == 0 {
        return Err(Error::param("trajectory_length", "must be at least 1"));
    }
    let os = flame.supersample as usize;
    let (iw, ih) = (flame.size[0] as usize, flame.size[1] as usize);

    let filter = SpatialFilter::new(flame.filter_shape.kernel(), flame.supersample, flame.filter)?;
    let mut gutter = (filter.width as isize - os as isize).max(0) as usize / 2;
    let max_de = if flame.estimator_radius > 0.0 {
        flame.estimator_radius.ceil() as usize * os + (os - 1)
    } else {
        0
    };
    let offset = if max_de > gutter {
        let o = max_de - gutter;
        gutter = max_de;
        o
    } else {
        0
    };
    let width = os * iw + 2 * gutter;
    let height = os * ih + 2 * gutter;
    let cells = width as u64 * height as u64;
    let colors = Colors::new(flame);
    let separate_count = !colors.opaque();
    let hist_bytes = cells * (16 + if separate_count { 4 } else { 0 });
    // One histogram at least (more copies only within `histogram_budget`), the density
    // accumulator and the image: checked before any of them is allocated.
    crate::budget::check_memory(
        &crate::budget::MemoryEstimate::new()
            .with(
                format!("{iw}×{ih} at supersample {os}: histogram"),
                hist_bytes,
            )
            .with("accumulator", cells.saturating_mul(16))
            .with("image", iw as u64 * ih as u64 * 4),
        "the size (--size) or the supersampling (--supersample)",
    )?;

    let camera = Camera::new(flame, width, height, gutter);
    let selector = Selector::new(flame)?;
    let xforms: Vec<PreparedXform> = flame.xforms.iter().map(|x| x.prepare()).collect();
    let final_prepared = flame.final_xform.as_ref().map(|x| x.prepare());
    let game = Game {
        xforms: &xforms,
        final_xform: final_prepared.as_ref(),
        final_opacity: flame.final_xform.as_ref().map_or(1.0, |x| x.opacity),
        selector: &selector,
        camera: &camera,
        colors: &colors,
        fuse: cfg.fuse,
        isa,
    };

    let passes = flame.passes as u64;
    let scale = 2f64.powf(flame.zoom);
    let sample_density = flame.quality * scale * scale;
    let per_pass = (sample_density * iw as f64 * ih as f64 / passes as f64).floor() as u64;
    let ppu = flame.pixels_per_unit();
    let k1 = (flame.brightness * 255.0 * 268.0 / passes as f64) / 256.0;
    let area = iw as f64 * ih as f64 / (ppu * ppu);
    let k2 = (os * os) as f64 * passes as f64 / (area * 255.0 * sample_density);
    let de = if flame.estimator_radius > 0.0 {
        Some(DensityFilters::new(
            flame.estimator_radius,
            flame.estimator_minimum,
            flame.estimator_curve,
            flame.supersample,
        )?)
    } else {
        None
    };

    let l = cfg.trajectory_length;
    let trajectories = per_pass.div_ceil(l).max(1);
    let copies = (cfg.histogram_budget / hist_bytes.max(1)).max(1);
    let groups = (rayon::current_num_threads() as u64)
        .min(trajectories)
        .min(copies)
        .max(1);
    if let Some(pb) = progress {
        pb.set_length(per_pass * passes);
    }

    let mut acc = vec![[0f32; 4]; cells as usize];
    let mut stats = GameStats::default();
    for pass in 0..passes {
        let pass_seed = mix_seed(cfg.seed, pass);
        let results: Vec<(Histogram, GameStats)> = (0..groups)
            .into_par_iter()
            .map(|g| {
                let mut hist = Histogram::new(cells as usize, separate_count);
                let mut st = GameStats::default();
                let mut buf = Vec::with_capacity(HIT_BATCH);
                let (lo, hi) = (g * trajectories / groups, (g + 1) * trajectories / groups);
                for t in lo..hi {
                    if progress.is_some_and(|p| p.cancelled()) {
                        break;
                    }
                    let n = l.min(per_pass - (t * l).min(per_pass));
                    if n == 0 {
                        continue;
                    }
                    let mut rng = trajectory_rng(pass_seed, t);
                    st += game.run(&mut rng, n, &mut hist, &mut buf);
                    if let Some(pb) = progress {
                        pb.inc(n);
                    }
                }
                (hist, st)
            })
            .collect();
        if progress.is_some_and(|p| p.cancelled()) {
            return Err(Error::Cancelled(
                "the render's caller stopped waiting".into(),
            ));
        }
        let mut it = results.into_iter();
        let (mut hist, st) = it.next().expect("at least one group");
        stats += st;
        for (h, s) in it {
            hist.merge(&h);
            stats += s;
        }
        match &de {
            Some(de) => density::estimate(&hist, &mut acc, width, height, os, de, k1, k2),
            None => density::log_scale(&hist, &mut acc, k1, k2),
        }
    }

    let tone = Tone {
        gamma: flame.gamma,
        linrange: flame.gamma_threshold,
        vibrancy: flame.vibrancy,
        highpow: flame.highlight_power,
        background: flame.background.map(|b| b * 256.0),
        transparent: cfg.transparent,
    };
    let pixels = tonemap::finish(&acc, width, iw, ih, os, offset, &filter, &tone);
    Ok(FlameImage {
        width: iw as u32,
        height: ih as u32,
        pixels,
        stats: FlameStats {
            samples: per_pass * passes,
            hits: stats.hits,
            badvals: stats.badvals,
            seconds: start.elapsed().as_secs_f64(),
        },
    })
}
