//! The texture type shared by the encoder, the decoder and the baselines: grey or RGB texels
//! as `f32` grey levels (0–255 for 8-bit sources), with PNG input and output.
//!
//! Values are kept in 8-bit units rather than [0, 1] so that the arithmetic of the fractal code
//! (means of 2×2 blocks, offsets that are multiples of ¼) is exact in `f32` for 8-bit sources,
//! which is what lets the packed 8-bit format round-trip exactly.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageBuffer, ImageFormat, Luma, Rgb};

use crate::error::{Error, Result};

/// A grey (1 channel) or RGB (3 channels) texture, row-major, channels interleaved.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: usize,
    height: usize,
    channels: usize,
    data: Vec<f32>,
}

impl Texture {
    /// A texture from interleaved values; refuses a wrong length, a channel count other than
    /// 1 or 3, and non-finite values.
    pub fn new(width: usize, height: usize, channels: usize, data: Vec<f32>) -> Result<Self> {
        if channels != 1 && channels != 3 {
            return Err(Error::InvalidInput(format!(
                "a texture has 1 (grey) or 3 (RGB) channels, got {channels}"
            )));
        }
        if width == 0 || height == 0 {
            return Err(Error::InvalidInput(format!(
                "a texture needs at least one texel, got {width}×{height}"
            )));
        }
        if data.len() != width * height * channels {
            return Err(Error::InvalidInput(format!(
                "{} values for a {width}×{height} texture with {channels} channel(s) (expected {})",
                data.len(),
                width * height * channels
            )));
        }
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "texel {} channel {} is not finite ({})",
                i / channels,
                i % channels,
                data[i]
            )));
        }
        Ok(Texture {
            width,
            height,
            channels,
            data,
        })
    }

    /// A texture from values the caller guarantees finite and of the right length (checked
    /// in debug builds only): for outputs computed from validated inputs.
    pub(crate) fn from_trusted(
        width: usize,
        height: usize,
        channels: usize,
        data: Vec<f32>,
    ) -> Self {
        debug_assert_eq!(data.len(), width * height * channels);
        debug_assert!(data.iter().all(|v| v.is_finite()));
        Texture {
            width,
            height,
            channels,
            data,
        }
    }

    /// A texture whose value at `(x, y, channel)` is `f(x, y, channel)`.
    pub fn from_fn(
        width: usize,
        height: usize,
        channels: usize,
        f: impl Fn(usize, usize, usize) -> f32,
    ) -> Result<Self> {
        let mut data = Vec::with_capacity(width * height * channels);
        for y in 0..height {
            for x in 0..width {
                for k in 0..channels {
                    data.push(f(x, y, k));
                }
            }
        }
        Texture::new(width, height, channels, data)
    }

    /// Width in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Channels per texel: 1 (grey) or 3 (RGB).
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Interleaved values, row-major.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// The texture's values, consumed.
    pub fn into_data(self) -> Vec<f32> {
        self.data
    }

    /// The channels of texel `(x, y)`.
    pub fn texel(&self, x: usize, y: usize) -> &[f32] {
        let i = (y * self.width + x) * self.channels;
        &self.data[i..i + self.channels]
    }

    /// Value of one channel of texel `(x, y)`.
    pub fn get(&self, x: usize, y: usize, channel: usize) -> f32 {
        self.data[(y * self.width + x) * self.channels + channel]
    }

    /// Decodes an image file's bytes: grey images stay grey, anything with colour becomes RGB
    /// (alpha is dropped); `force_grey` converts colour to Rec. 709 luma.
    pub fn from_image_bytes(bytes: &[u8], force_grey: bool) -> std::result::Result<Self, String> {
        let img =
            image::load_from_memory(bytes).map_err(|e| format!("not a readable image ({e})"))?;
        Ok(Texture::from_dynamic(&img, force_grey))
    }

    /// Converts a decoded image (8- or 16-bit, any layout) to a texture in 8-bit units
    /// (8-bit images exactly; 16-bit ones keep their fraction of a grey level).
    pub fn from_dynamic(img: &DynamicImage, force_grey: bool) -> Self {
        let (width, height) = (img.width() as usize, img.height() as usize);
        let colour = img.color().has_color();
        let eight_bit = img.color().bytes_per_pixel() / img.color().channel_count() == 1;
        let rgb: Vec<f32> = if eight_bit {
            img.to_rgb8()
                .into_raw()
                .into_iter()
                .map(f32::from)
                .collect()
        } else {
            img.to_rgb32f()
                .into_raw()
                .into_iter()
                .map(|v| 255.0 * v)
                .collect()
        };
        let (channels, data) = if force_grey && colour {
            let luma = rgb
                .chunks_exact(3)
                .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
                .collect();
            (1, luma)
        } else if !colour {
            (1, rgb.chunks_exact(3).map(|p| p[0]).collect())
        } else {
            (3, rgb)
        };
        Texture {
            width,
            height,
            channels,
            data,
        }
    }

    /// Loads a PNG (or any format the `image` crate reads here) as a texture.
    pub fn load(path: &Path, force_grey: bool) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
        let tex =
            Texture::from_image_bytes(&bytes, force_grey).map_err(|m| Error::file(path, m))?;
        if tex.width == 0 || tex.height == 0 {
            return Err(Error::file(path, "image has no pixels"));
        }
        Ok(tex)
    }

    /// Values rounded and clamped to 8 bits, interleaved.
    pub fn to_u8(&self) -> Vec<u8> {
        self.data
            .iter()
            .map(|&v| v.round().clamp(0.0, 255.0) as u8)
            .collect()
    }

    /// The texture as an 8-bit PNG (grey or RGB), in memory.
    pub fn encode_png(&self) -> Result<Vec<u8>> {
        let (w, h) = (self.width as u32, self.height as u32);
        let buf = self.to_u8();
        let mut out = Cursor::new(Vec::new());
        let res = if self.channels == 1 {
            ImageBuffer::<Luma<u8>, _>::from_raw(w, h, buf)
                .expect("length checked at construction")
                .write_to(&mut out, ImageFormat::Png)
        } else {
            ImageBuffer::<Rgb<u8>, _>::from_raw(w, h, buf)
                .expect("length checked at construction")
                .write_to(&mut out, ImageFormat::Png)
        };
        res.map_err(|e| Error::file("<memory>", e))?;
        Ok(out.into_inner())
    }

    /// Writes the texture as an 8-bit PNG, atomically.
    pub fn save_png(&self, path: &Path) -> Result<()> {
        let bytes = self.encode_png().map_err(|e| match e {
            Error::File { message, .. } => Error::file(path, message),
            other => other,
        })?;
        ifslab::io::write_atomic(path, &bytes)?;
        Ok(())
    }

    /// The `w × h` window whose top-left texel is `(x, y)`.
    pub fn crop(&self, x: usize, y: usize, w: usize, h: usize) -> Result<Texture> {
        if w == 0 || h == 0 || x + w > self.width || y + h > self.height {
            return Err(Error::InvalidInput(format!(
                "crop {w}×{h} at ({x}, {y}) does not fit a {}×{} texture",
                self.width, self.height
            )));
        }
        let c = self.channels;
        let mut data = Vec::with_capacity(w * h * c);
        for row in y..y + h {
            let start = (row * self.width + x) * c;
            data.extend_from_slice(&self.data[start..start + w * c]);
        }
        Texture::new(w, h, c, data)
    }

    /// The reduced texture R: each texel the mean of a 2×2 block (a box filter, i.e. the
    /// first mipmap level), rounded to whole grey levels because R is stored as an 8-bit
    /// texture. Needs even sides.
    pub fn reduce(&self) -> Result<Texture> {
        if !self.width.is_multiple_of(2) || !self.height.is_multiple_of(2) {
            return Err(Error::InvalidInput(format!(
                "the reduced texture halves each side: {}×{} has an odd side",
                self.width, self.height
            )));
        }
        let (w, h, c) = (self.width / 2, self.height / 2, self.channels);
        let mut data = Vec::with_capacity(w * h * c);
        for y in 0..h {
            for x in 0..w {
                for k in 0..c {
                    let s = self.get(2 * x, 2 * y, k)
                        + self.get(2 * x + 1, 2 * y, k)
                        + self.get(2 * x, 2 * y + 1, k)
                        + self.get(2 * x + 1, 2 * y + 1, k);
                    data.push((0.25 * s).round());
                }
            }
        }
        Texture::new(w, h, c, data)
    }

    /// The reduced texture by OpenCV's `pyrDown`: the 5×5 binomial filter ([1 4 6 4 1] / 16
    /// along each axis, borders reflected without repeating the edge texel), sampled at the
    /// even texels and rounded to whole grey levels. An alternative to the box filter of
    /// [`Texture::reduce`] for measuring how much the choice of downsampler matters (the paper
    /// only says "a standard downsampling algorithm"). Needs even sides of at least 4.
    pub fn reduce_binomial(&self) -> Result<Texture> {
        if !self.width.is_multiple_of(2)
            || !self.height.is_multiple_of(2)
            || self.width < 4
            || self.height < 4
        {
            return Err(Error::InvalidInput(format!(
                "the binomial reduction halves each side and needs even sides of at least 4, got {}×{}",
                self.width, self.height
            )));
        }
        const K: [f32; 5] = [1.0, 4.0, 6.0, 4.0, 1.0];
        let reflect = |i: isize, n: usize| -> usize {
            let n = n as isize;
            let j = if i < 0 {
                -i
            } else if i >= n {
                2 * n - 2 - i
            } else {
                i
            };
            j as usize
        };
        let (w, h, c) = (self.width / 2, self.height / 2, self.channels);
        let mut data = Vec::with_capacity(w * h * c);
        for y in 0..h {
            for x in 0..w {
                for k in 0..c {
                    let mut acc = 0.0f32;
                    for (j, ky) in K.iter().enumerate() {
                        let sy = reflect(2 * y as isize + j as isize - 2, self.height);
                        for (i, kx) in K.iter().enumerate() {
                            let sx = reflect(2 * x as isize + i as isize - 2, self.width);
                            acc += ky * kx * self.get(sx, sy, k);
                        }
                    }
                    data.push((acc / 256.0).round());
                }
            }
        }
        Texture::new(w, h, c, data)
    }

    /// Rec. 709 luma of an RGB texture (a grey texture is returned as is).
    pub fn to_grey(&self) -> Texture {
        if self.channels == 1 {
            return self.clone();
        }
        let data = self
            .data
            .chunks_exact(3)
            .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
            .collect();
        Texture {
            width: self.width,
            height: self.height,
            channels: 1,
            data,
        }
    }

    /// Each texel repeated `k × k` times (for figures: shows texels as blocks).
    pub fn scale_nearest(&self, k: usize) -> Result<Texture> {
        if k == 0 {
            return Err(Error::param("scale", "must be at least 1"));
        }
        let c = self.channels;
        Texture::from_fn(self.width * k, self.height * k, c, |x, y, ch| {
            self.get(x / k, y / k, ch)
        })
    }
}

/// Peak signal-to-noise ratio (dB, peak 255) between two textures of the same shape, on their
/// 8-bit quantised values (what is stored and displayed); infinite when they are equal.
pub fn psnr(a: &Texture, b: &Texture) -> Result<f64> {
    if a.width != b.width || a.height != b.height || a.channels != b.channels {
        return Err(Error::InvalidInput(format!(
            "PSNR of a {}×{}×{} and a {}×{}×{} texture",
            a.width, a.height, a.channels, b.width, b.height, b.channels
        )));
    }
    let sse: f64 = a
        .to_u8()
        .iter()
        .zip(b.to_u8())
        .map(|(&x, y)| (f64::from(x) - f64::from(y)).powi(2))
        .sum();
    let mse = sse / a.data.len() as f64;
    Ok(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduce_is_a_rounded_box_filter() {
        let t = Texture::new(2, 2, 1, vec![0.0, 1.0, 1.0, 1.0]).unwrap();
        assert_eq!(t.reduce().unwrap().data(), &[1.0]); // 0.75 rounds to 1
        let odd = Texture::new(3, 2, 1, vec![0.0; 6]).unwrap();
        assert!(odd.reduce().is_err());
    }

    #[test]
    fn the_binomial_reduction_is_pyrdown() {
        // A constant stays constant; an impulse of 256 at (2, 2) spreads with the 5×5 binomial
        // weights: 6·6 at the sample on it, 1·6 twice (once reflected) one sample over, 1·1
        // two texels over on both axes, nothing beyond.
        let flat = Texture::from_fn(8, 6, 1, |_, _, _| 77.0).unwrap();
        assert!(
            flat.reduce_binomial()
                .unwrap()
                .data()
                .iter()
                .all(|&v| v == 77.0)
        );
        let imp = Texture::from_fn(
            8,
            8,
            1,
            |x, y, _| if (x, y) == (2, 2) { 256.0 } else { 0.0 },
        )
        .unwrap();
        let r = imp.reduce_binomial().unwrap();
        assert_eq!(r.get(1, 1, 0), 36.0);
        assert_eq!(r.get(0, 1, 0), 12.0);
        assert_eq!(r.get(2, 2, 0), 1.0);
        assert_eq!(r.get(3, 3, 0), 0.0);
        // Reflect-101 border: an impulse at the edge texel 0 is counted once, at 6/16.
        let edge = Texture::from_fn(
            8,
            8,
            1,
            |x, y, _| if (x, y) == (0, 0) { 256.0 } else { 0.0 },
        )
        .unwrap();
        assert_eq!(edge.reduce_binomial().unwrap().get(0, 0, 0), 36.0);
        assert!(
            Texture::from_fn(6, 2, 1, |_, _, _| 0.0)
                .unwrap()
                .reduce_binomial()
                .is_err()
        );
    }

    #[test]
    fn png_round_trip_is_exact_for_8_bit_values() {
        let t = Texture::from_fn(5, 3, 3, |x, y, c| {
            ((x * 37 + y * 11 + c * 101) % 256) as f32
        })
        .unwrap();
        let back = Texture::from_image_bytes(&t.encode_png().unwrap(), false).unwrap();
        assert_eq!(back, t);
        let g = t.to_grey();
        let back = Texture::from_image_bytes(&g.encode_png().unwrap(), false).unwrap();
        assert_eq!(back.channels(), 1);
        assert_eq!(psnr(&back, &g).unwrap(), f64::INFINITY);
    }

    #[test]
    fn bad_shapes_are_refused() {
        assert!(Texture::new(2, 2, 2, vec![0.0; 8]).is_err());
        assert!(Texture::new(2, 2, 1, vec![0.0; 3]).is_err());
        assert!(Texture::new(1, 1, 1, vec![f32::NAN]).is_err());
        let t = Texture::new(2, 2, 1, vec![0.0; 4]).unwrap();
        assert!(t.crop(1, 1, 2, 1).is_err());
    }
}
