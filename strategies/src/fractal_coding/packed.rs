//! The packed 8-bit format: the code as three 8-bit textures (PNG files) a GPU samples
//! directly, plus a small manifest.
//!
//! | file | size | layout |
//! |---|---|---|
//! | `reduced.png` | R's size | R, 8-bit grey or RGB |
//! | `coords.png` | R's size | RGB8: R = \|Δx\|, G = \|Δy\|, B = sign bits (bit 0: Δx < 0, bit 1: Δy < 0) |
//! | `offsets.png` | R's size | 8-bit grey or RGB: q = clamp(round(O / step) + 128, 0, 255) |
//! | `code.json` | — | format name and version, sizes, channels, `offset_step`, encoder settings |
//!
//! Δ = C(c) − c is the relative coordinate of texel c's virtual range block: with the paper's
//! ±255 window its magnitude fits a byte, so coordinates round-trip exactly. R is already
//! rounded to whole grey levels by the encoder, so it round-trips exactly too (for sources in
//! 0–255). Offsets are the lossy part: O is quantised with the step
//! `offset_step` = 2ᵏ (k ≥ −2), the smallest such that every offset fits the byte
//! (max |O| ≤ 127.5·step); the decoded offset is (q − 128)·step, within step / 2 of O. For an
//! 8-bit source every offset is a multiple of ¼ (a difference of means of four integers), so
//! when max |O| ≤ 31.875 the step is ¼ and the round trip is exact; otherwise each offset is
//! off by at most step / 2 and a texel decoded with n levels by at most n·step / 2 (before
//! rounding the output to 8 bits). For 8-bit sources |O| ≤ 255, so step ≤ 2.
//!
//! The bit layout is this project's reading of the paper's 8-bit packing (relative
//! coordinates in a byte per axis, offsets in a byte per channel); the sign byte and the
//! adaptive offset step are documented choices of ours.

use std::path::Path;

use image::{DynamicImage, ImageBuffer, Rgb};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::fractal_coding::code::FractalCode;
use crate::fractal_coding::texture::Texture;

/// Format name written in the manifest.
pub const FORMAT: &str = "ifslab-fractal-texture-8bit";
/// Version of the layout above.
pub const VERSION: u32 = 1;
/// Largest relative coordinate a byte holds (the paper's search window).
pub const MAX_RELATIVE: i32 = 255;

/// The manifest `code.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`].
    pub version: u32,
    /// Source width (twice R's).
    pub width: usize,
    /// Source height (twice R's).
    pub height: usize,
    /// 1 (grey) or 3 (RGB).
    pub channels: usize,
    /// Quantisation step of the offsets (grey levels).
    pub offset_step: f32,
    /// Free-form description of how the code was made (encoder and refinement settings).
    #[serde(default)]
    pub encoder: serde_json::Value,
}

/// A code in its packed form: three 8-bit images and the offset step.
#[derive(Clone, Debug, PartialEq)]
pub struct PackedCode {
    /// R, 8-bit, interleaved (`channels` per texel).
    pub reduced: Vec<u8>,
    /// RGB8 relative coordinates, as in the table of the module docs.
    pub coords: Vec<u8>,
    /// Quantised offsets, 8-bit, `channels` per texel.
    pub offsets: Vec<u8>,
    /// Width of R.
    pub width: usize,
    /// Height of R.
    pub height: usize,
    /// 1 or 3.
    pub channels: usize,
    /// Offset quantisation step.
    pub offset_step: f32,
}

/// How far the packing moved the code.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PackError {
    /// Largest change of an R value (0 for codes from 8-bit sources).
    pub max_reduced_error: f32,
    /// Largest change of an offset (≤ `offset_step` / 2).
    pub max_offset_error: f32,
    /// The offset step used.
    pub offset_step: f32,
}

/// The offset step of the module docs for offsets whose largest magnitude is `max_abs`.
pub fn offset_step_for(max_abs: f32) -> f32 {
    let mut step = 0.25f32;
    while max_abs > 127.5 * step {
        step *= 2.0;
    }
    step
}

/// Packs a code; refuses relative coordinates beyond ±255 (encode with a window ≤ 255).
pub fn pack(code: &FractalCode) -> Result<(PackedCode, PackError)> {
    let (w, h, ch) = (code.width(), code.height(), code.channels());
    let mut coords = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let (dx, dy) = code.relative(x, y);
            if dx.abs() > MAX_RELATIVE || dy.abs() > MAX_RELATIVE {
                return Err(Error::InvalidInput(format!(
                    "texel ({x}, {y}) has relative coordinate ({dx}, {dy}), beyond the ±{MAX_RELATIVE} \
                     the 8-bit format holds; encode with a window of at most {MAX_RELATIVE}"
                )));
            }
            coords.push(dx.unsigned_abs() as u8);
            coords.push(dy.unsigned_abs() as u8);
            coords.push(u8::from(dx < 0) | (u8::from(dy < 0) << 1));
        }
    }
    let rd = code.reduced().data();
    let reduced: Vec<u8> = code.reduced().to_u8();
    let max_reduced_error = rd
        .iter()
        .zip(&reduced)
        .map(|(&v, &q)| (v - f32::from(q)).abs())
        .fold(0.0f32, f32::max);
    let max_abs = code.offsets().iter().fold(0.0f32, |a, &o| a.max(o.abs()));
    let step = offset_step_for(max_abs);
    let offsets: Vec<u8> = code
        .offsets()
        .iter()
        .map(|&o| ((o / step).round() + 128.0).clamp(0.0, 255.0) as u8)
        .collect();
    let max_offset_error = code
        .offsets()
        .iter()
        .zip(&offsets)
        .map(|(&o, &q)| (o - dequantise(q, step)).abs())
        .fold(0.0f32, f32::max);
    Ok((
        PackedCode {
            reduced,
            coords,
            offsets,
            width: w,
            height: h,
            channels: ch,
            offset_step: step,
        },
        PackError {
            max_reduced_error,
            max_offset_error,
            offset_step: step,
        },
    ))
}

fn dequantise(q: u8, step: f32) -> f32 {
    (f32::from(q) - 128.0) * step
}

/// Unpacks a code, checking that every relative coordinate lands on a block inside R.
pub fn unpack(p: &PackedCode) -> Result<FractalCode> {
    let (w, h, ch) = (p.width, p.height, p.channels);
    if p.reduced.len() != w * h * ch || p.offsets.len() != w * h * ch || p.coords.len() != w * h * 3
    {
        return Err(Error::InvalidInput(format!(
            "packed planes of {}, {} and {} bytes do not fit a {w}×{h} code with {ch} channel(s)",
            p.reduced.len(),
            p.coords.len(),
            p.offsets.len()
        )));
    }
    if !(p.offset_step.is_finite() && p.offset_step > 0.0) {
        return Err(Error::InvalidInput(format!(
            "offset step must be a positive number, got {}",
            p.offset_step
        )));
    }
    let reduced = Texture::new(w, h, ch, p.reduced.iter().map(|&v| f32::from(v)).collect())?;
    let mut coords = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let b = &p.coords[(y * w + x) * 3..(y * w + x) * 3 + 3];
            if b[2] > 3 {
                return Err(Error::InvalidInput(format!(
                    "texel ({x}, {y}): sign byte {} has bits other than 0 and 1 set",
                    b[2]
                )));
            }
            let dx = if b[2] & 1 != 0 {
                -i64::from(b[0])
            } else {
                i64::from(b[0])
            };
            let dy = if b[2] & 2 != 0 {
                -i64::from(b[1])
            } else {
                i64::from(b[1])
            };
            let (kx, ky) = (x as i64 + dx, y as i64 + dy);
            if kx < 0 || ky < 0 || kx + 1 >= w as i64 || ky + 1 >= h as i64 {
                return Err(Error::InvalidInput(format!(
                    "texel ({x}, {y}): relative coordinate ({dx}, {dy}) leaves the {w}×{h} reduced texture"
                )));
            }
            coords.push((ky as usize * w + kx as usize) as u32);
        }
    }
    let offsets = p
        .offsets
        .iter()
        .map(|&q| dequantise(q, p.offset_step))
        .collect();
    FractalCode::new(reduced, coords, offsets)
}

/// Writes `reduced.png`, `coords.png`, `offsets.png` and `code.json` into `dir` (created if
/// needed), each atomically; returns what the packing changed.
pub fn save_dir(code: &FractalCode, dir: &Path, encoder: serde_json::Value) -> Result<PackError> {
    let (p, err) = pack(code)?;
    std::fs::create_dir_all(dir).map_err(|e| Error::file(dir, e))?;
    let (w, h) = (p.width as u32, p.height as u32);
    write_png(&dir.join("reduced.png"), w, h, p.channels, &p.reduced)?;
    write_png(&dir.join("coords.png"), w, h, 3, &p.coords)?;
    write_png(&dir.join("offsets.png"), w, h, p.channels, &p.offsets)?;
    let manifest = Manifest {
        format: FORMAT.into(),
        version: VERSION,
        width: 2 * p.width,
        height: 2 * p.height,
        channels: p.channels,
        offset_step: p.offset_step,
        encoder,
    };
    let json = serde_json::to_vec_pretty(&manifest).map_err(|e| Error::file(dir, e))?;
    let path = dir.join("code.json");
    ifslab::io::write_atomic(&path, &json)?;
    Ok(err)
}

fn write_png(path: &Path, w: u32, h: u32, ch: usize, data: &[u8]) -> Result<()> {
    let img = if ch == 1 {
        DynamicImage::ImageLuma8(
            ImageBuffer::from_raw(w, h, data.to_vec()).expect("length checked by pack"),
        )
    } else {
        DynamicImage::ImageRgb8(
            ImageBuffer::<Rgb<u8>, _>::from_raw(w, h, data.to_vec())
                .expect("length checked by pack"),
        )
    };
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)
        .map_err(|e| Error::file(path, e))?;
    ifslab::io::write_atomic(path, &out.into_inner())?;
    Ok(())
}

fn read_png(path: &Path, w: usize, h: usize, ch: usize) -> Result<Vec<u8>> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
    let img = image::load_from_memory(&bytes)
        .map_err(|e| Error::file(path, format!("not a readable PNG ({e})")))?;
    if (img.width() as usize, img.height() as usize) != (w, h) {
        return Err(Error::file(
            path,
            format!(
                "is {}×{}, the manifest says the code is {w}×{h}",
                img.width(),
                img.height()
            ),
        ));
    }
    let want = if ch == 1 { "8-bit grey" } else { "8-bit RGB" };
    match (ch, &img) {
        (1, DynamicImage::ImageLuma8(b)) => Ok(b.as_raw().clone()),
        (3, DynamicImage::ImageRgb8(b)) => Ok(b.as_raw().clone()),
        _ => Err(Error::file(
            path,
            format!("must be {want}, found {:?}", img.color()),
        )),
    }
}

/// Reads a code folder written by [`save_dir`]; returns the code and its manifest.
pub fn load_dir(dir: &Path) -> Result<(FractalCode, Manifest)> {
    let mpath = dir.join("code.json");
    let text = std::fs::read(&mpath).map_err(|e| {
        Error::file(
            &mpath,
            format!("{e}; a code folder is made by `ifslab texture encode`"),
        )
    })?;
    let m: Manifest = serde_json::from_slice(&text).map_err(|e| Error::file(&mpath, e))?;
    if m.format != FORMAT || m.version != VERSION {
        return Err(Error::file(
            &mpath,
            format!(
                "format {} version {} is not {FORMAT} version {VERSION}",
                m.format, m.version
            ),
        ));
    }
    if !m.width.is_multiple_of(2) || !m.height.is_multiple_of(2) || m.width < 4 || m.height < 4 {
        return Err(Error::file(
            &mpath,
            format!(
                "source size {}×{} must have even sides ≥ 4",
                m.width, m.height
            ),
        ));
    }
    if m.channels != 1 && m.channels != 3 {
        return Err(Error::file(
            &mpath,
            format!("channels must be 1 or 3, got {}", m.channels),
        ));
    }
    let (w, h, ch) = (m.width / 2, m.height / 2, m.channels);
    let p = PackedCode {
        reduced: read_png(&dir.join("reduced.png"), w, h, ch)?,
        coords: read_png(&dir.join("coords.png"), w, h, 3)?,
        offsets: read_png(&dir.join("offsets.png"), w, h, ch)?,
        width: w,
        height: h,
        channels: ch,
        offset_step: m.offset_step,
    };
    let code = unpack(&p).map_err(|e| Error::file(dir, e))?;
    Ok((code, m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_step_is_the_smallest_that_fits() {
        assert_eq!(offset_step_for(0.0), 0.25);
        assert_eq!(offset_step_for(31.875), 0.25);
        assert_eq!(offset_step_for(32.0), 0.5);
        assert_eq!(offset_step_for(255.0), 2.0);
    }
}
