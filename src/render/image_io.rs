//! PNG output (8- or 16-bit grey) and grey image loading, with errors that name the file.

use std::io::Cursor;
use std::path::Path;

use image::{ImageBuffer, ImageFormat, Luma};

use crate::error::{Error, Result};
use crate::image::Image;
use crate::io::write_atomic;
use crate::render::raster::Raster;

/// Bits per sample of a written PNG.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BitDepth {
    /// 8-bit grey.
    #[default]
    Eight,
    /// 16-bit grey (keeps the 256 coverage levels of 16× supersampling distinct).
    Sixteen,
}

/// Encodes grey values in [0, 1] (row-major) as PNG bytes; `invert` draws dark on light.
pub fn encode_png(
    values: &[f32],
    width: u32,
    height: u32,
    depth: BitDepth,
    invert: bool,
) -> Result<Vec<u8>> {
    if values.len() != width as usize * height as usize {
        return Err(Error::Shape(format!(
            "{} values for a {width}×{height} image",
            values.len()
        )));
    }
    let tone = |v: f32| {
        let v = v.clamp(0.0, 1.0);
        if invert { 1.0 - v } else { v }
    };
    let mut out = Cursor::new(Vec::new());
    let res = match depth {
        BitDepth::Eight => {
            let buf: Vec<u8> = values
                .iter()
                .map(|&v| (tone(v) * 255.0).round() as u8)
                .collect();
            ImageBuffer::<Luma<u8>, _>::from_raw(width, height, buf)
                .expect("length checked")
                .write_to(&mut out, ImageFormat::Png)
        }
        BitDepth::Sixteen => {
            let buf: Vec<u16> = values
                .iter()
                .map(|&v| (tone(v) * 65535.0).round() as u16)
                .collect();
            ImageBuffer::<Luma<u16>, _>::from_raw(width, height, buf)
                .expect("length checked")
                .write_to(&mut out, ImageFormat::Png)
        }
    };
    res.map_err(|e| Error::Image {
        path: "<memory>".into(),
        message: e.to_string(),
    })?;
    Ok(out.into_inner())
}

/// Writes grey values as a PNG file, atomically.
pub fn save_grey_png(
    path: &Path,
    values: &[f32],
    width: u32,
    height: u32,
    depth: BitDepth,
    invert: bool,
) -> Result<()> {
    let bytes = encode_png(values, width, height, depth, invert).map_err(|e| match e {
        Error::Image { message, .. } => Error::Image {
            path: path.to_owned(),
            message,
        },
        other => other,
    })?;
    write_atomic(path, &bytes)
}

impl Raster {
    /// Writes the render as a PNG (white attractor on black unless `invert`).
    pub fn save_png(&self, path: &Path, depth: BitDepth, invert: bool) -> Result<()> {
        save_grey_png(path, &self.values, self.width, self.height, depth, invert)
    }

    /// Pixels whose value exceeds `threshold`, as a mask.
    pub fn mask(&self, threshold: f32) -> Vec<bool> {
        self.values.iter().map(|&v| v > threshold).collect()
    }
}

/// A grey image with values in [0, 1].
/// Loads any image `image` reads as grey in [0, 1] (alpha composited onto white): a
/// one-channel [`Image`].
pub fn load_grey(path: &Path) -> Result<Image> {
    Image::load(path, false)
}
