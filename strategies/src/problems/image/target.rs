//! Target images: loaded as grey, turned bright-on-dark, and framed the way the model frames
//! its points — the foreground's bounding box centred, its longest side spanning 75% of a
//! square canvas.

use std::path::Path;

use ifslab::image::Image;
use ifslab::render::FIT_FILL;
use image::{ImageBuffer, Luma, imageops};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::em::PointSet;

/// The framed target inside a run folder, stored losslessly (a NumPy `float64` array of
/// `size` rows × `size` columns) so that a resumed run optimises against exactly the image the
/// interrupted one did, whatever the working directory and whether the original file still
/// exists (`target.png` beside it is an 8-bit picture for people).
pub const FRAMED_TARGET_FILE: &str = "target.npy";

/// Which way round the target's shape is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Polarity {
    /// Decide from the border: a bright border means a dark shape on a light background.
    #[default]
    Auto,
    /// The shape is bright on a dark background (as the renderers draw it).
    BrightOnDark,
    /// The shape is dark on a light background.
    DarkOnLight,
}

impl std::str::FromStr for Polarity {
    type Err = Error;

    /// `auto`, `bright-on-dark` or `dark-on-light` (`_` for `-` as in configs).
    fn from_str(s: &str) -> Result<Self> {
        match s.replace('_', "-").as_str() {
            "auto" => Ok(Self::Auto),
            "bright-on-dark" => Ok(Self::BrightOnDark),
            "dark-on-light" => Ok(Self::DarkOnLight),
            _ => Err(Error::param(
                "polarity",
                format!("`{s}` is not one of auto, bright-on-dark, dark-on-light"),
            )),
        }
    }
}

/// Width in pixels of the border ring a picture's background is read from.
const RING: usize = 2;
/// How far the middle half of the border ring's levels may spread, as a share of the
/// picture's range, before `auto` gives up: the border is then not a background to tell
/// the shape from (a photo, a gradient).
const MAX_RING_SPREAD: f32 = 0.25;
/// A pixel belongs to the shape when it departs from the background by more than this many
/// robust standard deviations of the ring (and at least [`MIN_CONTRAST`]).
const SHAPE_NOISE: f32 = 4.0;
/// The smallest difference between background and ink levels taken as a shape.
const MIN_CONTRAST: f32 = 0.03;
/// Noise (robust standard deviations of the background) left out below the ink.
const NOISE_FLOOR: f32 = 3.0;

/// What the loader read from a picture and how it framed it: written beside a run's framed
/// target (`target.json`), so a person sees what was decided and a resumed run reads the
/// measurements it started with.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetReading {
    /// The picture's width and height in pixels.
    pub picture: [u32; 2],
    /// `opacity` (a transparent picture's alpha plane), or the luma taken `as_is` (bright on
    /// dark) or `inverted` (dark on light).
    pub read: String,
    /// The background level of that plane (the border ring's median), before normalising.
    pub background: f32,
    /// The ink level (95th percentile of the shape's Otsu class), before normalising.
    pub ink: f32,
    /// The background's robust standard deviation (noise), before normalising.
    pub noise: f32,
    /// Framed pixels per picture pixel.
    pub scale: f64,
    /// The shape's stroke width in picture pixels ([`stroke_width`]), when it has strokes.
    pub stroke: Option<f64>,
}

/// The name of [`TargetReading`]'s file in a run folder.
pub const TARGET_READING_FILE: &str = "target.json";

/// A picture framed as a target, and what was read from it.
#[derive(Clone, Debug)]
pub struct FramedTarget {
    /// The grey `size × size` target, values in [0, 1], the shape bright.
    pub image: Image,
    /// What the loader read.
    pub reading: TargetReading,
}

impl TargetReading {
    /// Writes the reading as JSON (atomically).
    pub fn save(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(|e| Error::file(path, e))?;
        ifslab::io::write_atomic(path, text.as_bytes())?;
        Ok(())
    }

    /// Reads a reading written by [`TargetReading::save`].
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
        serde_json::from_str(&text).map_err(|e| Error::file(path, e))
    }

    /// The stroke width in framed pixels.
    pub fn framed_stroke(&self) -> Option<f64> {
        self.stroke.map(|w| w * self.scale)
    }
}

/// Loads `path` and frames it into a `size × size` target.
pub fn load_target(path: &Path, size: usize, polarity: Polarity) -> Result<Image> {
    Ok(load_framed_picture(path, size, polarity)?.image)
}

/// Loads `path` and frames it into a `size × size` target, with what was read from it.
pub fn load_framed_picture(path: &Path, size: usize, polarity: Polarity) -> Result<FramedTarget> {
    load_framed_picture_with(path, size, polarity, None)
}

/// [`load_framed_picture`], the grey levels read as [`Cells`] says when it is given.
pub fn load_framed_picture_with(
    path: &Path,
    size: usize,
    polarity: Polarity,
    cells: Option<Cells>,
) -> Result<FramedTarget> {
    let img = Image::load_rgba(path)?;
    frame_picture_with(&img, size, polarity, cells).map_err(|e| match e {
        Error::InvalidInput(m) => Error::file(path, m),
        other => other,
    })
}

/// How a framed target's grey levels can be read the way the splat makes its own, where
/// the picture is reduced to the target (at most [`CELLS_MAX_SCALE`]): each pixel is cut into `per_side × per_side` cells
/// (the renderer's supersampling) and its level is the share of its cells inked, a cell
/// being inked when the picture under it reaches `threshold` of the ink level (the largest
/// of the picture pixels whose centres it holds, or the picture interpolated at its centre
/// where it is smaller than a picture pixel). A splat point inks about one cell whatever the
/// attractor's width below it, so this is the level the splat gives a thin filament, where
/// the picture's own area coverage, reduced, averages it to a faint grey. A picture reduced
/// less, or enlarged, is resampled as it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cells {
    /// Cells per pixel side.
    pub per_side: usize,
    /// The share of the ink level at which a cell counts as inked.
    pub threshold: f32,
}

/// The largest framing scale (framed pixels per picture pixel) at which [`Cells`] read a
/// picture: a target pixel then spans two picture pixels or more. On the robustness suite's
/// first tuning split, the random codes drawn at scales 0.2–0.45 all fitted closer to their
/// truth with the cells' levels (8 of 8 fits, +0.08 to +0.14 truth IoU), and those at
/// 0.5–0.93 closer on 5 of 15 (robustness/README.md): where a cell is smaller than a
/// picture pixel the picture's level at it is a guess, and a threshold on it drops faint
/// filaments. An enlarged picture holds no finer detail to read at all.
pub const CELLS_MAX_SCALE: f64 = 0.5;

impl Cells {
    /// Checks the numbers; the error names the config field.
    pub fn validate(&self) -> Result<()> {
        if self.per_side == 0
            || self.per_side > 16
            || !(self.threshold > 0.0 && self.threshold <= 1.0)
        {
            return Err(Error::param(
                "target.cells",
                format!(
                    "the threshold must lie in (0, 1] and the cells per side in 1..=16, got {} and {}",
                    self.threshold, self.per_side
                ),
            ));
        }
        Ok(())
    }
}

/// The stroke width of a shape plane (values in [0, 1], shape bright), in its pixels: the
/// distance of each half-inked pixel to the nearest pixel that is not, whose 90th
/// percentile `d` is the middle of the strokes (`W ≈ 2d − 1`, 1 for a one-pixel line).
/// `None` when no pixel, or every pixel, is half-inked.
pub fn stroke_width(plane: &[f32], width: usize, height: usize) -> Option<f64> {
    let outside: Vec<bool> = plane.iter().map(|&v| v < 0.5).collect();
    let d = ifslab::image::distance_to(&outside, width, height)?;
    let mut inside: Vec<f64> = d
        .iter()
        .zip(&outside)
        .filter(|(_, o)| !**o)
        .map(|(d, _)| *d)
        .collect();
    if inside.is_empty() {
        return None;
    }
    let k = ((inside.len() - 1) as f64 * 0.9).round() as usize;
    let d90 = *inside.select_nth_unstable_by(k, f64::total_cmp).1;
    Some((2.0 * d90 - 1.0).max(1.0))
}

/// The `q`-quantile (0–1) of `values` (which it reorders).
fn quantile(values: &mut [f32], q: f64) -> f32 {
    let k = ((values.len() - 1) as f64 * q).round() as usize;
    *values.select_nth_unstable_by(k, f32::total_cmp).1
}

/// The pixels of a `w × h` plane within [`RING`] of its border.
fn border_ring(v: &[f32], w: usize, h: usize) -> Vec<f32> {
    let r = RING.min(w / 2).min(h / 2).max(1);
    let mut out = Vec::with_capacity(2 * r * (w + h));
    for y in 0..h {
        for x in 0..w {
            if x < r || y < r || x + r >= w || y + r >= h {
                out.push(v[y * w + x]);
            }
        }
    }
    out
}

/// The shape of a picture as one plane in [0, 1], bright on a black background, whatever
/// way it was drawn: a transparent picture's opacity (when its background — the border
/// ring's median opacity — is transparent, it holds opaque pixels, and no polarity says
/// otherwise); otherwise its luma (alpha composited onto white). An opaque picture with a
/// few stray see-through pixels (scikit-image's horse has eight) is read by its luma. The background is the border ring's median level; the shape is
/// what departs from it by more than [`SHAPE_NOISE`] robust standard deviations of the
/// ring, and `auto` turns the picture round when more of that lies below the background
/// than above (a tiny figure decides it as well as a large one). Then the background goes
/// to 0, the ink level (the shape's 95th percentile) to 1, and noise up to [`NOISE_FLOOR`]
/// robust standard deviations is left out — so a faint anti-aliased line, a grey
/// background, JPEG ringing or sensor noise frame like a clean black-and-white drawing. A
/// uniform picture, a shape too faint to tell from the noise, and (`auto`) a picture whose
/// border is not one plain background are refused, saying why.
pub fn shape_plane(img: &Image, polarity: Polarity) -> Result<(Vec<f32>, TargetReading)> {
    let (w, h) = (img.width as usize, img.height as usize);
    let n = w * h;
    if img.channels == 4 && polarity != Polarity::DarkOnLight {
        let alpha = img.plane(3);
        let hi = alpha.iter().copied().fold(0.0f32, f32::max);
        let mut ring = border_ring(alpha, w, h);
        if quantile(&mut ring, 0.5) < 0.5 && hi > 0.5 {
            let (v, mut r) = normalise(alpha.to_vec(), w, h, Polarity::BrightOnDark)?;
            r.read = "opacity".into();
            return Ok((v, r));
        }
    }
    let grey = if img.channels == 1 {
        img.values[..n].to_vec()
    } else {
        img.to_grey().values
    };
    normalise(grey, w, h, polarity)
}

/// Orients (for `auto`, by which side of the background the picture departs to) and
/// normalises a grey plane.
fn normalise(
    grey: Vec<f32>,
    w: usize,
    h: usize,
    polarity: Polarity,
) -> Result<(Vec<f32>, TargetReading)> {
    let (lo, hi) = grey
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, u), &v| {
            (l.min(v), u.max(v))
        });
    if hi - lo < MIN_CONTRAST {
        let mean = grey.iter().map(|&v| v as f64).sum::<f64>() / grey.len() as f64;
        let what = if mean > 0.5 {
            "all white (or uniformly light)"
        } else {
            "all black (or uniformly dark)"
        };
        return Err(Error::InvalidInput(format!(
            "the target is empty: it is {what}, every pixel within {:.3} of the others, so \
             there is no shape to fit",
            hi - lo
        )));
    }
    // The background: the border ring's median level and robust spread.
    let mut ring = border_ring(&grey, w, h);
    let mut background = quantile(&mut ring, 0.5);
    let spread = quantile(&mut ring, 0.75) - quantile(&mut ring, 0.25);
    let plain = spread <= MAX_RING_SPREAD * (hi - lo);
    if polarity == Polarity::Auto && !plain {
        return Err(Error::InvalidInput(format!(
            "the target has no background: its border is not one plain colour (the middle \
             half of its levels spans {:.0} % of the picture's range); give a picture of a \
             shape on a plain background, or say which way round it is drawn (`--polarity \
             bright-on-dark` or `dark-on-light` on the command line, `polarity` in a config)",
            100.0 * spread / (hi - lo)
        )));
    }
    let mut deviations: Vec<f32> = ring.iter().map(|&x| (x - background).abs()).collect();
    let mut noise = 1.4826 * quantile(&mut deviations, 0.5);
    if !plain {
        // No plain border, but the polarity was given: the background is the picture's
        // far end on the background's side (its 2nd percentile, turned round when dark on
        // light), with no noise to leave out.
        let mut all = grey.clone();
        background = if polarity == Polarity::DarkOnLight {
            quantile(&mut all, 0.98)
        } else {
            quantile(&mut all, 0.02)
        };
        noise = 0.0;
    }
    // What departs from the background beyond its noise, on either side: the shape is on
    // the side with more of it (`auto`).
    let significant = (SHAPE_NOISE * noise).max(MIN_CONTRAST);
    let (mut above, mut below) = (0.0f64, 0.0f64);
    for &x in &grey {
        let d = x - background;
        if d > significant {
            above += d as f64;
        } else if d < -significant {
            below -= d as f64;
        }
    }
    let invert = match polarity {
        Polarity::Auto => below > above,
        Polarity::BrightOnDark => false,
        Polarity::DarkOnLight => true,
    };
    let o: Vec<f32> = grey
        .iter()
        .map(|&x| {
            if invert {
                background - x
            } else {
                x - background
            }
        })
        .collect();
    let mut shape: Vec<f32> = o.iter().copied().filter(|&x| x > significant).collect();
    if shape.is_empty() {
        return Err(Error::InvalidInput(format!(
            "the target's shape is too faint: nothing departs from its background {background:.3} \
             by more than {significant:.3}{}",
            if polarity == Polarity::Auto {
                ""
            } else {
                " on the side `polarity` says (is it the other way round?)"
            }
        )));
    }
    let ink = quantile(&mut shape, 0.95);
    let floor = (NOISE_FLOOR * noise).min(0.5 * ink);
    let scale = 1.0 / (ink - floor);
    let plane = o
        .iter()
        .map(|&x| ((x - floor) * scale).clamp(0.0, 1.0))
        .collect();
    let reading = TargetReading {
        picture: [w as u32, h as u32],
        read: if invert { "inverted" } else { "as_is" }.into(),
        background,
        ink: if invert {
            background - ink
        } else {
            background + ink
        },
        noise,
        scale: 1.0,
        stroke: None,
    };
    Ok((plane, reading))
}

/// Frames an image (colour images by their luma, transparent ones by their opacity: see
/// [`shape_plane`]) into a `size × size` grey target (values in [0, 1], shape bright).
pub fn frame_target(img: &Image, size: usize, polarity: Polarity) -> Result<Image> {
    Ok(frame_picture(img, size, polarity)?.image)
}

/// [`frame_target`], with what was read from the picture: its polarity, levels, noise, the
/// framing's scale and the shape's stroke width.
pub fn frame_picture(img: &Image, size: usize, polarity: Polarity) -> Result<FramedTarget> {
    frame_picture_with(img, size, polarity, None)
}

/// [`frame_picture`], the grey levels read as [`Cells`] says when it is given (the framing
/// is the same either way).
pub fn frame_picture_with(
    img: &Image,
    size: usize,
    polarity: Polarity,
    cells: Option<Cells>,
) -> Result<FramedTarget> {
    if size < 8 {
        return Err(Error::param(
            "size",
            format!("targets need at least 8×8 pixels, got {size}"),
        ));
    }
    if let Some(c) = &cells {
        c.validate()?;
    }
    let (w, h) = (img.width as usize, img.height as usize);
    let (v, mut reading) = shape_plane(img, polarity)?;
    // The shape's box: pixels at least half-inked with an inked neighbour (a lone speck of
    // noise does not stretch it); failing those, any pixel a fifth inked.
    let lit = |x: usize, y: usize, level: f32| v[y * w + x] > level;
    let boxed = |level: f32, neighbour: bool| {
        let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
        for y in 0..h {
            for x in 0..w {
                if !lit(x, y, level) {
                    continue;
                }
                let keep = !neighbour
                    || (y.saturating_sub(1)..(y + 2).min(h)).any(|yy| {
                        (x.saturating_sub(1)..(x + 2).min(w))
                            .any(|xx| (xx, yy) != (x, y) && lit(xx, yy, level))
                    });
                if keep {
                    x0 = x0.min(x);
                    x1 = x1.max(x);
                    y0 = y0.min(y);
                    y1 = y1.max(y);
                }
            }
        }
        (x0 <= x1).then_some((x0, x1, y0, y1))
    };
    let Some((x0, x1, y0, y1)) = boxed(0.5, true).or_else(|| boxed(0.2, false)) else {
        return Err(Error::InvalidInput(
            "the target has no pixel inked above a fifth of its ink level: nothing to fit".into(),
        ));
    };
    let (bw, bh) = (x1 - x0 + 1, y1 - y0 + 1);
    let crop: ImageBuffer<Luma<f32>, Vec<f32>> =
        ImageBuffer::from_fn(bw as u32, bh as u32, |x, y| {
            Luma([v[(y0 + y as usize) * w + x0 + x as usize]])
        });
    let scale = FIT_FILL * size as f64 / bw.max(bh) as f64;
    let (nw, nh) = (
        ((bw as f64 * scale).round() as u32).max(1),
        ((bh as f64 * scale).round() as u32).max(1),
    );
    let mut out = vec![0.0f32; size * size];
    let (ox, oy) = ((size - nw as usize) / 2, (size - nh as usize) / 2);
    // Cells read a picture reduced at least twice only (see `CELLS_MAX_SCALE`).
    match cells.filter(|_| scale <= CELLS_MAX_SCALE) {
        None => {
            let resized = imageops::resize(&crop, nw, nh, imageops::FilterType::Triangle);
            for (x, y, p) in resized.enumerate_pixels() {
                out[(oy + y as usize) * size + ox + x as usize] = p.0[0].clamp(0.0, 1.0);
            }
        }
        Some(c) => cell_levels(
            &crop,
            [nw as usize, nh as usize],
            [ox, oy],
            size,
            c,
            &mut out,
        ),
    }
    reading.scale = scale;
    reading.stroke = stroke_width(&v, w, h);
    Ok(FramedTarget {
        image: Image::square(size, out)?,
        reading,
    })
}

/// Writes the levels of [`Cells`] for `crop` (framed as `[nw, nh]` pixels at `[ox, oy]` of the
/// `size × size` target, the geometry [`frame_picture`]'s resampling uses: a target coordinate
/// `u` reads the crop at `(u − ox)·bw/nw`) into `out`.
fn cell_levels(
    crop: &ImageBuffer<Luma<f32>, Vec<f32>>,
    framed: [usize; 2],
    origin: [usize; 2],
    size: usize,
    cells: Cells,
    out: &mut [f32],
) {
    let s = cells.per_side;
    let (bw, bh) = (crop.width() as usize, crop.height() as usize);
    let at = |x: usize, y: usize| crop.get_pixel(x as u32, y as u32).0[0];
    // Crop pixels per cell along each axis, and the crop coordinate of a target one.
    let step = [bw as f64 / framed[0] as f64, bh as f64 / framed[1] as f64];
    let to_crop = |u: f64, axis: usize| (u - origin[axis] as f64) * step[axis];
    // The level of the cell [u0, u1) × [v0, v1) (target pixels), 1 or 0: read from the
    // picture pixels it holds or, where it is smaller than one, from the picture
    // interpolated at its centre.
    let level = |u0: f64, u1: f64, v0: f64, v1: f64| -> f32 {
        let (x0, x1) = (to_crop(u0, 0), to_crop(u1, 0));
        let (y0, y1) = (to_crop(v0, 1), to_crop(v1, 1));
        if x1 - x0 >= 1.0 && y1 - y0 >= 1.0 {
            // The largest level of the crop pixels whose centres the cell holds.
            let first = |a: f64| (a - 0.5).ceil().max(0.0) as usize;
            let end = |b: f64, n: usize| ((b - 0.5).ceil().max(0.0) as usize).min(n);
            let mut m = 0.0f32;
            for y in first(y0)..end(y1, bh) {
                for x in first(x0)..end(x1, bw) {
                    m = m.max(at(x, y));
                }
            }
            if m >= cells.threshold { 1.0 } else { 0.0 }
        } else {
            // Bilinear at the cell's centre (crop pixel centres at integer + 0.5; zero
            // outside the crop), then thresholded.
            let (cx, cy) = (0.5 * (x0 + x1) - 0.5, 0.5 * (y0 + y1) - 0.5);
            let (fx, fy) = (cx.floor(), cy.floor());
            let (tx, ty) = ((cx - fx) as f32, (cy - fy) as f32);
            let get = |x: f64, y: f64| {
                if x < 0.0 || y < 0.0 || x >= bw as f64 || y >= bh as f64 {
                    0.0
                } else {
                    at(x as usize, y as usize)
                }
            };
            let top = get(fx, fy) * (1.0 - tx) + get(fx + 1.0, fy) * tx;
            let bottom = get(fx, fy + 1.0) * (1.0 - tx) + get(fx + 1.0, fy + 1.0) * tx;
            let v = top * (1.0 - ty) + bottom * ty;
            if v >= cells.threshold { 1.0 } else { 0.0 }
        }
    };
    let inv = 1.0 / s as f64;
    let share = 1.0 / (s * s) as f32;
    for py in origin[1]..(origin[1] + framed[1]).min(size) {
        for px in origin[0]..(origin[0] + framed[0]).min(size) {
            let mut sum = 0.0f32;
            for j in 0..s {
                let v0 = py as f64 + j as f64 * inv;
                for i in 0..s {
                    let u0 = px as f64 + i as f64 * inv;
                    sum += level(u0, u0 + inv, v0, v0 + inv);
                }
            }
            out[py * size + px] = sum * share;
        }
    }
}

/// Writes a framed target (grey, square) atomically as a lossless `.npy` array.
pub fn save_framed_target(path: &Path, target: &Image) -> Result<()> {
    let size = target.width as usize;
    target.expect_shape("a framed target", 1, size, size)?;
    PointSet::new(size, target.values.iter().map(|&v| v as f64).collect())?.save(path)
}

/// Reads a target written by [`save_framed_target`]; it must be `size × size`.
pub fn load_framed_target(path: &Path, size: usize) -> Result<Image> {
    let rows = PointSet::load(path)?;
    if rows.dim() != size || rows.len() != size {
        return Err(Error::file(
            path,
            format!(
                "holds a {}×{} target where the run's config says {size}×{size}",
                rows.len(),
                rows.dim()
            ),
        ));
    }
    // f32 → f64 → f32 is exact, so the values are the ones that were saved.
    Ok(Image::square(
        size,
        rows.as_slice().iter().map(|&v| v as f32).collect(),
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> f32) -> Image {
        Image {
            channels: 1,
            width: w,
            height: h,
            values: (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .map(|(x, y)| f(x, y))
                .collect(),
        }
    }

    #[test]
    fn dark_shape_on_white_is_inverted_centred_and_scaled() {
        // A dark 20×10 bar at the top-left of a white 100×80 image.
        let img = image(100, 80, |x, y| {
            if (5..25).contains(&x) && (3..13).contains(&y) {
                0.0
            } else {
                1.0
            }
        });
        let t = frame_target(&img, 64, Polarity::Auto).unwrap().values;
        let lit: Vec<(usize, usize)> = (0..64 * 64)
            .filter(|&i| t[i] > 0.5)
            .map(|i| (i % 64, i / 64))
            .collect();
        let (xs, ys): (Vec<_>, Vec<_>) = lit.iter().copied().unzip();
        let (x0, x1) = (*xs.iter().min().unwrap(), *xs.iter().max().unwrap());
        let (y0, y1) = (*ys.iter().min().unwrap(), *ys.iter().max().unwrap());
        assert!((x1 - x0 + 1).abs_diff(48) <= 1, "width {}", x1 - x0 + 1);
        assert!((y1 - y0 + 1).abs_diff(24) <= 1, "height {}", y1 - y0 + 1);
        assert!(
            (x0 + x1).abs_diff(63) <= 1 && (y0 + y1).abs_diff(63) <= 1,
            "not centred"
        );
    }

    #[test]
    fn framed_targets_round_trip_bit_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(FRAMED_TARGET_FILE);
        let t: Vec<f32> = (0..16 * 16)
            .map(|i| (i as f32 * 0.37).sin().abs() / 3.0)
            .collect();
        let t = Image::square(16, t).unwrap();
        save_framed_target(&path, &t).unwrap();
        let back = load_framed_target(&path, 16).unwrap();
        assert!(
            t.values
                .iter()
                .zip(&back.values)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        let e = load_framed_target(&path, 32).unwrap_err().to_string();
        assert!(e.contains("16×16") && e.contains("32×32"), "{e}");
        let wide = Image::grey(16, 15, vec![0.0; 240]).unwrap();
        let e = save_framed_target(&path, &wide).unwrap_err().to_string();
        assert!(e.contains("16×15 grey image; 16×16 grey is needed"), "{e}");
    }

    #[test]
    fn empty_targets_are_refused() {
        let white = image(40, 40, |_, _| 1.0);
        let e = frame_target(&white, 32, Polarity::Auto)
            .unwrap_err()
            .to_string();
        assert!(e.contains("all white"), "{e}");
        let black = image(40, 40, |_, _| 0.0);
        let e = frame_target(&black, 32, Polarity::Auto)
            .unwrap_err()
            .to_string();
        assert!(e.contains("all black"), "{e}");
    }

    #[test]
    fn a_picture_without_background_names_the_polarity_setting_and_honours_it() {
        // A grey gradient over the whole frame: no border colour to take as background.
        let photo = image(40, 40, |x, y| 0.2 + 0.6 * (x + y) as f32 / 78.0);
        let e = frame_target(&photo, 32, Polarity::Auto)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("no background") && e.contains("--polarity"),
            "{e}"
        );
        // Said explicitly, the same picture is framed, and the two ways round differ.
        let bright = frame_target(&photo, 32, "bright-on-dark".parse().unwrap())
            .unwrap()
            .values;
        let dark = frame_target(&photo, 32, "dark_on_light".parse().unwrap())
            .unwrap()
            .values;
        assert_ne!(bright, dark);
        assert_eq!("auto".parse::<Polarity>().unwrap(), Polarity::Auto);
        let e = "sideways".parse::<Polarity>().unwrap_err().to_string();
        assert!(e.contains("sideways") && e.contains("dark-on-light"), "{e}");
    }

    /// The box of the pixels above `level` in a framed `size²` target.
    fn lit_box(t: &[f32], size: usize, level: f32) -> (usize, usize, usize, usize) {
        let lit: Vec<(usize, usize)> = (0..size * size)
            .filter(|&i| t[i] > level)
            .map(|i| (i % size, i / size))
            .collect();
        assert!(!lit.is_empty(), "nothing above {level}");
        let (xs, ys): (Vec<_>, Vec<_>) = lit.iter().copied().unzip();
        (
            *xs.iter().min().unwrap(),
            *xs.iter().max().unwrap(),
            *ys.iter().min().unwrap(),
            *ys.iter().max().unwrap(),
        )
    }

    /// A deterministic stand-in for sensor noise: uniform in ±`amp`, by a hash of (x, y).
    fn noise(x: u32, y: u32, amp: f32) -> f32 {
        let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (y as u64 + 7);
        h ^= h >> 29;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 32;
        amp * (2.0 * (h % 10_000) as f32 / 10_000.0 - 1.0)
    }

    #[test]
    fn a_thin_faint_curve_on_a_noisy_grey_background_is_framed_by_the_curve() {
        // A sine curve one pixel wide drawn at 0.35 over a 0.2 grey background with ±0.05
        // noise, in the left third of a 300×200 canvas: the noise covers the whole canvas
        // above a tenth of the brightest pixel, the curve does not.
        let img = image(300, 200, |x, y| {
            let on = (20..100).contains(&x)
                && (y as f32 - (100.0 + 30.0 * (x as f32 / 9.0).sin())).abs() < 0.5;
            0.2 + if on { 0.35 } else { 0.0 } + noise(x, y, 0.05)
        });
        let t = frame_target(&img, 64, Polarity::Auto).unwrap().values;
        // The curve spans 80 × ~61 pixels: its longer side fills 75 % of the frame.
        let (x0, x1, y0, y1) = lit_box(&t, 64, 0.3);
        assert!((x1 - x0 + 1).abs_diff(48) <= 2, "width {}", x1 - x0 + 1);
        assert!(
            (x0 + x1).abs_diff(63) <= 2 && (y0 + y1).abs_diff(63) <= 2,
            "not centred"
        );
        // The background is black: the noise was left below the ink.
        let dark = t.iter().filter(|&&v| v == 0.0).count();
        assert!(dark > 64 * 64 * 3 / 4, "{dark} of {} pixels black", 64 * 64);
        // The curve stands out at the framed size, and reaches full ink at its own.
        assert!(t.iter().copied().fold(0.0f32, f32::max) > 0.5);
        let (plane, reading) = shape_plane(&img, Polarity::Auto).unwrap();
        assert_eq!(plane.iter().copied().fold(0.0f32, f32::max), 1.0);
        assert_eq!(reading.read, "as_is");
        assert!((reading.background - 0.2).abs() < 0.01, "{reading:?}");
        assert!(reading.noise > 0.02 && reading.noise < 0.05, "{reading:?}");
    }

    #[test]
    fn polarity_follows_the_background_whatever_its_grey_and_noise() {
        // A dark disc on a light grey (0.7) background with ±0.1 noise (JPEG-like speckle
        // around it): `auto` turns it round; the same on a dark background does not.
        let disc = |x: u32, y: u32| (x as f32 - 40.0).hypot(y as f32 - 30.0) < 12.0;
        let light = image(90, 70, |x, y| {
            (if disc(x, y) { 0.15 } else { 0.7 } + noise(x, y, 0.1)).clamp(0.0, 1.0)
        });
        let dark = image(90, 70, |x, y| {
            (if disc(x, y) { 0.8 } else { 0.25 } + noise(x, y, 0.1)).clamp(0.0, 1.0)
        });
        for img in [light, dark] {
            let t = frame_target(&img, 32, Polarity::Auto).unwrap().values;
            // The disc is the bright, centred shape.
            assert!(t[16 * 32 + 16] > 0.6, "centre {}", t[16 * 32 + 16]);
            assert!(t[2 * 32 + 2] < 0.1, "corner {}", t[2 * 32 + 2]);
        }
    }

    #[test]
    fn a_transparent_picture_is_its_opacity_even_white_on_clear() {
        // A white square on a transparent background (white underneath): composited onto
        // white it vanishes; its alpha plane is the shape.
        let (w, h) = (50u32, 40u32);
        let inside = |x: u32, y: u32| (10..25).contains(&x) && (5..20).contains(&y);
        let mut values = vec![1.0f32; 3 * (w * h) as usize];
        values.extend(
            (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .map(|(x, y)| if inside(x, y) { 1.0 } else { 0.0 }),
        );
        let img = Image::new(w, h, 4, values).unwrap();
        let t = frame_target(&img, 32, Polarity::Auto).unwrap().values;
        let (x0, x1, y0, y1) = lit_box(&t, 32, 0.5);
        assert_eq!((x1 - x0 + 1, y1 - y0 + 1), (24, 24), "a 75 % square");
        // Said to be dark on light, the picture is read by its colours instead: white on
        // white has nothing to show.
        let e = frame_target(&img, 32, Polarity::DarkOnLight)
            .unwrap_err()
            .to_string();
        assert!(e.contains("empty"), "{e}");
    }

    #[test]
    fn an_opaque_picture_with_stray_see_through_pixels_is_read_by_its_colours() {
        // A black disc on opaque white, four corner pixels half transparent (as in
        // scikit-image's horse): the background is opaque, so the luma is the shape, dark on
        // light — read by the opacity it would be refused as too faint.
        let (w, h) = (60u32, 50u32);
        let inside = |x: u32, y: u32| (x as f32 - 30.0).hypot(y as f32 - 25.0) < 12.0;
        let grey: Vec<f32> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| if inside(x, y) { 0.0 } else { 1.0 })
            .collect();
        let mut values: Vec<f32> = [grey.clone(), grey.clone(), grey].concat();
        let mut alpha = vec![1.0f32; (w * h) as usize];
        for i in [
            0,
            (w - 1) as usize,
            ((h - 1) * w) as usize,
            (w * h - 1) as usize,
        ] {
            alpha[i] = 0.43;
        }
        values.extend(alpha);
        let img = Image::new(w, h, 4, values).unwrap();
        let (_, reading) = shape_plane(&img, Polarity::Auto).unwrap();
        assert_eq!(reading.read, "inverted", "{reading:?}");
        let t = frame_target(&img, 32, Polarity::Auto).unwrap().values;
        let (x0, x1, y0, y1) = lit_box(&t, 32, 0.5);
        assert!((x1 - x0 + 1).abs_diff(24) <= 1 && (y1 - y0 + 1).abs_diff(24) <= 1);
    }

    #[test]
    fn a_shape_too_faint_to_tell_from_its_noise_is_refused_saying_why() {
        // Contrast 0.02 on a uniform background: below the smallest contrast taken.
        let faint = image(40, 40, |x, y| {
            0.5 + if (10..30).contains(&x) && (10..30).contains(&y) {
                0.025
            } else {
                0.0
            }
        });
        let e = frame_target(&faint, 32, Polarity::Auto)
            .unwrap_err()
            .to_string();
        assert!(e.contains("empty") && e.contains("no shape"), "{e}");
    }

    #[test]
    fn cells_give_a_thin_filament_the_level_a_splat_gives_it() {
        // A 400² picture: a filled 40² square (it frames the box with the cross below) and a
        // one-pixel vertical line from it, reduced about 6× into a 64² target.
        let img = image(400, 400, |x, y| {
            let square = (20..60).contains(&x) && (20..60).contains(&y);
            let line = x == 200 && (20..380).contains(&y);
            let bar = (20..380).contains(&x) && y == 379;
            if square || line || bar { 1.0 } else { 0.0 }
        });
        let pol = Polarity::BrightOnDark;
        let area = frame_picture(&img, 64, pol).unwrap().image.values;
        let cells = Cells {
            per_side: 4,
            threshold: 0.5,
        };
        let framed = frame_picture_with(&img, 64, pol, Some(cells))
            .unwrap()
            .image
            .values;
        // The line's column: the largest level in each row, over rows away from the
        // square and the bar.
        let peak = |t: &[f32], y: usize| (20..44).map(|x| t[y * 64 + x]).fold(0.0f32, f32::max);
        for y in 24..50 {
            let (a, c) = (peak(&area, y), peak(&framed, y));
            // One cell in four across the pixel: the splat's level for a filament.
            assert!((c - 0.25).abs() < 1e-6, "row {y}: cells give {c}");
            assert!(a < 0.2, "row {y}: the resampled picture gives {a}");
        }
        // Inside the square both read full ink.
        assert_eq!(framed[10 * 64 + 10], 1.0);
        assert!(area[10 * 64 + 10] > 0.99);
        // The same framing: nothing inked outside the resampled picture's box.
        for (i, (&a, &c)) in area.iter().zip(&framed).enumerate() {
            assert!(a > 0.0 || c == 0.0, "pixel {i}: {a} against {c}");
        }
    }

    #[test]
    fn cells_are_refused_with_a_bad_threshold() {
        let img = image(40, 40, |x, y| {
            ((10..30).contains(&x) && (10..30).contains(&y)) as u8 as f32
        });
        let e = frame_picture_with(
            &img,
            32,
            Polarity::BrightOnDark,
            Some(Cells {
                per_side: 4,
                threshold: 0.0,
            }),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("target.cells") && e.contains("threshold"), "{e}");
    }
}
