//! The packed 8-bit format: the code as three 8-bit textures (PNG files) a GPU samples
//! directly, plus a small manifest.
//!
//! | file | size | layout |
//! |---|---|---|
//! | `reduced.png` | R's size | R, 8-bit grey or RGB |
//! | `coords.png` | R's size | RGB8, by [`CoordStorage`] (below) |
//! | `offsets.png` | R's size | 8-bit grey or RGB: q = clamp(round(O / step) + 128, 0, 255) |
//! | `code.json` | — | format name and version, sizes, channels, `offset_step`, `coord_storage`, encoder settings |
//!
//! Coordinates, for texel c whose virtual range block has top-left texel C(c) = (x, y):
//! - `half-signed` (the paper's §IV): the half relative coordinate s = x/2 − ⌊c_x/2⌋ (and the
//!   same for y), a signed value in [−125, 126], as a two's-complement byte in R (x) and G (y);
//!   B = 0. Decoding: x = 2⌊c_x/2⌋ + 2s. It holds the codes of the `even` search grid.
//! - `half-signed-offset`: s = (x − c_x)/2, same bytes; x = c_x + 2s. For the `even-offset` grid.
//! - `sign-magnitude` (this project's layout for the `all` grid): R = |Δx|, G = |Δy|,
//!   B = sign bits (bit 0: Δx < 0, bit 1: Δy < 0), Δ = C(c) − c, |Δ| ≤ 255.
//!
//! Every layout stores its coordinates exactly. R is already rounded to whole grey levels by
//! the encoder, so it round-trips exactly too (for sources in 0–255). Offsets are the lossy
//! part: O is quantised with the step `offset_step` = 2ᵏ (k ≥ −2), the smallest such that
//! every offset fits the byte (max |O| ≤ 127.5·step); the decoded offset is (q − 128)·step,
//! within step / 2 of O. For an 8-bit source every offset is a multiple of ¼ (a difference of
//! means of four integers), so when max |O| ≤ 31.875 the step is ¼ and the round trip is exact;
//! otherwise each offset is off by at most step / 2 and a texel decoded with n levels by at
//! most n·step / 2 (before rounding the output to 8 bits). For 8-bit sources |O| ≤ 255, so
//! step ≤ 2. The paper stores O in an 8-bit RGB texture without saying how; the adaptive step
//! is this project's choice.

use std::path::Path;

use image::{DynamicImage, ImageBuffer, Rgb};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::fractal_coding::code::FractalCode;
use crate::problems::fractal_coding::encoder::{HALF_MAX, HALF_MIN, SearchGrid, named_enum};
use crate::problems::fractal_coding::texture::Texture;

/// Format name written in the manifest.
pub const FORMAT: &str = "ifslab-fractal-texture-8bit";
/// Version of the layout above (version 1 files, sign–magnitude only, are read too).
pub const VERSION: u32 = 2;
/// Largest relative coordinate the sign–magnitude layout holds.
pub const MAX_RELATIVE: i32 = 255;

/// How `coords.png` stores the coordinate texture (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CoordStorage {
    /// |Δx|, |Δy| and sign bits: any code with |Δ| ≤ 255.
    #[default]
    SignMagnitude,
    /// The paper's half relative coordinate x/2 − ⌊c_x/2⌋ in [−125, 126], signed bytes.
    HalfSigned,
    /// The half relative coordinate (x − c_x)/2 in [−125, 126], signed bytes.
    HalfSignedOffset,
}
named_enum!(
    CoordStorage,
    "coord_storage",
    SignMagnitude => "sign-magnitude",
    HalfSigned => "half-signed",
    HalfSignedOffset => "half-signed-offset",
);

impl CoordStorage {
    /// The storage that holds every code of a search grid in a byte per axis.
    pub fn for_grid(grid: SearchGrid) -> CoordStorage {
        match grid {
            SearchGrid::All => CoordStorage::SignMagnitude,
            SearchGrid::Even => CoordStorage::HalfSigned,
            SearchGrid::EvenOffset => CoordStorage::HalfSignedOffset,
        }
    }

    /// The base b(c) of the half coordinate along an axis, for the half layouts.
    fn half_base(self, c: usize) -> Option<i64> {
        match self {
            CoordStorage::SignMagnitude => None,
            CoordStorage::HalfSigned => SearchGrid::Even.half_base(c).map(|b| b as i64),
            CoordStorage::HalfSignedOffset => SearchGrid::EvenOffset.half_base(c).map(|b| b as i64),
        }
    }

    /// The three bytes of texel `c`'s coordinate `k` (both per axis: (x, y)).
    fn encode(self, c: (usize, usize), k: (usize, usize)) -> Result<[u8; 3]> {
        let Some(bx) = self.half_base(c.0) else {
            let (dx, dy) = (k.0 as i64 - c.0 as i64, k.1 as i64 - c.1 as i64);
            if dx.abs() > i64::from(MAX_RELATIVE) || dy.abs() > i64::from(MAX_RELATIVE) {
                return Err(Error::InvalidInput(format!(
                    "texel ({}, {}) has relative coordinate ({dx}, {dy}), beyond the ±{MAX_RELATIVE} \
                     the sign-magnitude layout holds; encode with a window of at most {MAX_RELATIVE}",
                    c.0, c.1
                )));
            }
            return Ok([
                dx.unsigned_abs() as u8,
                dy.unsigned_abs() as u8,
                u8::from(dx < 0) | (u8::from(dy < 0) << 1),
            ]);
        };
        let by = self
            .half_base(c.1)
            .expect("a half layout has a base on both axes");
        let half = |k: usize, b: i64| -> Option<i8> {
            let d = k as i64 - b;
            let s = d / 2;
            (d % 2 == 0 && (i64::from(HALF_MIN)..=i64::from(HALF_MAX)).contains(&s))
                .then_some(s as i8)
        };
        match (half(k.0, bx), half(k.1, by)) {
            (Some(sx), Some(sy)) => Ok([sx as u8, sy as u8, 0]),
            _ => Err(Error::InvalidInput(format!(
                "texel ({}, {}) points at the block at ({}, {}), which the {self} layout cannot \
                 hold (it stores half the relative coordinate, in [{HALF_MIN}, {HALF_MAX}]): encode \
                 with grid `{}` or store the coordinates as sign-magnitude",
                c.0,
                c.1,
                k.0,
                k.1,
                match self {
                    CoordStorage::HalfSignedOffset => SearchGrid::EvenOffset,
                    _ => SearchGrid::Even,
                }
            ))),
        }
    }

    /// The coordinate of texel `c` stored as `b` (not yet checked against R's size).
    fn decode(self, c: (usize, usize), b: &[u8]) -> Result<(i64, i64)> {
        let Some(bx) = self.half_base(c.0) else {
            if b[2] > 3 {
                return Err(Error::InvalidInput(format!(
                    "texel ({}, {}): sign byte {} has bits other than 0 and 1 set",
                    c.0, c.1, b[2]
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
            return Ok((c.0 as i64 + dx, c.1 as i64 + dy));
        };
        let by = self
            .half_base(c.1)
            .expect("a half layout has a base on both axes");
        let (sx, sy) = (i32::from(b[0] as i8), i32::from(b[1] as i8));
        if b[2] != 0 || ![sx, sy].iter().all(|s| (HALF_MIN..=HALF_MAX).contains(s)) {
            return Err(Error::InvalidInput(format!(
                "texel ({}, {}): half coordinates ({sx}, {sy}) with third byte {} are not a {self} \
                 coordinate (values in [{HALF_MIN}, {HALF_MAX}], third byte 0)",
                c.0, c.1, b[2]
            )));
        }
        Ok((bx + 2 * i64::from(sx), by + 2 * i64::from(sy)))
    }
}

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
    /// How `coords.png` stores the coordinates (version 1 files: sign-magnitude).
    #[serde(default)]
    pub coord_storage: CoordStorage,
    /// Free-form description of how the code was made (encoder and refinement settings).
    #[serde(default)]
    pub encoder: serde_json::Value,
}

/// A code in its packed form: three 8-bit images and the offset step.
#[derive(Clone, Debug, PartialEq)]
pub struct PackedCode {
    /// R, 8-bit, interleaved (`channels` per texel).
    pub reduced: Vec<u8>,
    /// RGB8 coordinates, laid out by `coord_storage`.
    pub coords: Vec<u8>,
    /// The layout of `coords`.
    pub coord_storage: CoordStorage,
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

/// Packs a code with the given coordinate layout; refuses coordinates the layout cannot hold.
pub fn pack(code: &FractalCode, storage: CoordStorage) -> Result<(PackedCode, PackError)> {
    let (w, h, ch) = (code.width(), code.height(), code.channels());
    let mut coords = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let k = code.coords()[y * w + x] as usize;
            coords.extend_from_slice(&storage.encode((x, y), (k % w, k / w))?);
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
            coord_storage: storage,
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
            let (kx, ky) = p.coord_storage.decode((x, y), b)?;
            if kx < 0 || ky < 0 || kx + 1 >= w as i64 || ky + 1 >= h as i64 {
                return Err(Error::InvalidInput(format!(
                    "texel ({x}, {y}): its block at ({kx}, {ky}) leaves the {w}×{h} reduced texture"
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
pub fn save_dir(
    code: &FractalCode,
    dir: &Path,
    storage: CoordStorage,
    encoder: serde_json::Value,
) -> Result<PackError> {
    let (p, err) = pack(code, storage)?;
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
        coord_storage: p.coord_storage,
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
    let v1 = m.version == 1 && m.coord_storage == CoordStorage::SignMagnitude;
    if m.format != FORMAT || !(m.version == VERSION || v1) {
        return Err(Error::file(
            &mpath,
            format!(
                "format {} version {} is not {FORMAT} version 1 or {VERSION}",
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
        coord_storage: m.coord_storage,
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
