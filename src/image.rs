//! The one image type of the stack: `channels` planes of `height × width` values in [0, 1],
//! plane after plane (channel-major, the layout of a candle `(C, H, W)` tensor, so an image
//! goes to the losses and comes back without reordering).
//!
//! The values are `f32` by default: pictures, renders and every target a problem fits.
//! `Image<f64>` is the same type at the precision of the SDF raster, whose gradients are
//! checked against f64 finite differences; [`Image::widened`] takes a picture there exactly.
//!
//! One channel is grey (renders of IFS attractors, framed targets: the fast path every loss
//! and renderer keeps); three are RGB and four RGBA (flames). Files are read and written
//! through the `image` crate; PNG writes are atomic.

use std::io::Cursor;
use std::path::Path;

use candle_core::{DType, Device, Tensor};
use image::{ImageBuffer, ImageFormat, Luma, Rgb, Rgba};

use crate::error::{Error, Result};
use crate::io::write_atomic;

/// A planar image of `T` values, `f32` unless said otherwise (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Image<T = f32> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Planes: 1 grey, 3 RGB, 4 RGBA.
    pub channels: u32,
    /// `channels × height × width` values, plane after plane, each plane row-major.
    pub values: Vec<T>,
}

/// Rec. 709 luma of linear-free sRGB values, as the grey loaders use.
fn luma(r: f32, g: f32, b: f32) -> f32 {
    0.2126 * r + 0.7152 * g + 0.0722 * b
}

impl<T: Copy> Image<T> {
    /// An image from its planes; an error when the value count does not match.
    pub fn new(width: u32, height: u32, channels: u32, values: Vec<T>) -> Result<Self> {
        if width == 0 || height == 0 || channels == 0 {
            return Err(Error::Empty(format!(
                "a {width}×{height} image with {channels} channels has no pixels"
            )));
        }
        let n = channels as usize * height as usize * width as usize;
        if values.len() != n {
            return Err(Error::Shape(format!(
                "{} values for a {width}×{height} image with {channels} channels ({n} expected)",
                values.len()
            )));
        }
        Ok(Image {
            width,
            height,
            channels,
            values,
        })
    }

    /// A grey image from row-major values.
    pub fn grey(width: u32, height: u32, values: Vec<T>) -> Result<Self> {
        Image::new(width, height, 1, values)
    }

    /// A grey `side × side` image from row-major values (a framed target).
    pub fn square(side: usize, values: Vec<T>) -> Result<Self> {
        let side = u32::try_from(side)
            .map_err(|_| Error::Shape(format!("a square image of side {side} is too large")))?;
        Image::grey(side, side, values)
    }

    /// Refuses an image that is not `channels` planes of `width × height`, saying what it
    /// is (`what`: "the target", …) and what was expected of it.
    pub fn expect_shape(
        &self,
        what: &str,
        channels: u32,
        width: usize,
        height: usize,
    ) -> Result<()> {
        if self.channels == channels
            && self.width as usize == width
            && self.height as usize == height
        {
            return Ok(());
        }
        let planes = |c: u32| match c {
            1 => "grey".to_string(),
            3 => "RGB".to_string(),
            4 => "RGBA".to_string(),
            c => format!("{c}-plane"),
        };
        Err(Error::Shape(format!(
            "{what} is a {}×{} {} image; {width}×{height} {} is needed",
            self.width,
            self.height,
            planes(self.channels),
            planes(channels)
        )))
    }

    /// Pixels per plane.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Plane `c` (row-major).
    pub fn plane(&self, c: usize) -> &[T] {
        let n = self.pixels();
        &self.values[c * n..(c + 1) * n]
    }
}

impl Image {
    /// The same image in f64, exactly (every `f32` is an `f64`).
    pub fn widened(&self) -> Image<f64> {
        Image {
            width: self.width,
            height: self.height,
            channels: self.channels,
            values: self.values.iter().map(|&v| v as f64).collect(),
        }
    }

    /// The image in grey: itself when it has one channel, else the Rec. 709 luma of its
    /// RGB planes, composited onto white by its alpha plane when it has one.
    pub fn to_grey(&self) -> Image {
        if self.channels == 1 {
            return self.clone();
        }
        let n = self.pixels();
        let values = (0..n)
            .map(|i| {
                let ch = |c: usize| self.values[c.min(self.channels as usize - 1) * n + i];
                let y = luma(ch(0), ch(1), ch(2));
                if self.channels == 4 {
                    let a = ch(3);
                    (y * a + (1.0 - a)).clamp(0.0, 1.0)
                } else {
                    y.clamp(0.0, 1.0)
                }
            })
            .collect();
        Image {
            width: self.width,
            height: self.height,
            channels: 1,
            values,
        }
    }

    /// The image as a tensor: `(H, W)` for grey, `(C, H, W)` otherwise — the shapes the
    /// losses take.
    pub fn to_tensor(&self, dtype: DType, device: &Device) -> Result<Tensor> {
        let (h, w) = (self.height as usize, self.width as usize);
        let t = if self.channels == 1 {
            Tensor::from_slice(&self.values, (h, w), device)?
        } else {
            Tensor::from_slice(&self.values, (self.channels as usize, h, w), device)?
        };
        Ok(t.to_dtype(dtype)?)
    }

    /// An image from an `(H, W)` or `(C, H, W)` tensor (leading dimensions of size 1
    /// allowed), in any float dtype.
    pub fn from_tensor(t: &Tensor) -> Result<Self> {
        let (c, h, w) = crate::loss::candle_ops::image_chw(t.dims()).map_err(Error::Shape)?;
        let values = t.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>()?;
        Image::new(w as u32, h as u32, c as u32, values)
    }

    /// Reads any file the `image` crate reads as four planes, RGB and alpha, nothing
    /// composited (alpha 1 where the file has none): for loaders that decide themselves what
    /// a transparent pixel means.
    pub fn load_rgba(path: &Path) -> Result<Self> {
        let rgba = decode_rgba(path)?;
        let (width, height) = rgba.dimensions();
        let values: Vec<f32> = (0..4)
            .flat_map(|c| rgba.pixels().map(move |p| p.0[c].clamp(0.0, 1.0)))
            .collect();
        Image::new(width, height, 4, values)
    }

    /// Reads any file the `image` crate reads, as grey (luma, alpha composited onto white)
    /// or, with `rgb`, as three planes (alpha composited onto white).
    pub fn load(path: &Path, rgb: bool) -> Result<Self> {
        let rgba = decode_rgba(path)?;
        let (width, height) = rgba.dimensions();
        let over_white = |v: f32, a: f32| (v * a + (1.0 - a)).clamp(0.0, 1.0);
        let values: Vec<f32> = if rgb {
            (0..3)
                .flat_map(|c| rgba.pixels().map(move |p| over_white(p.0[c], p.0[3])))
                .collect()
        } else {
            rgba.pixels()
                .map(|p| {
                    let [r, g, b, a] = p.0;
                    over_white(luma(r, g, b), a)
                })
                .collect()
        };
        Image::new(width, height, if rgb { 3 } else { 1 }, values)
    }

    /// PNG bytes: grey, RGB or RGBA, 8 bits per channel; values are clamped to [0, 1].
    pub fn encode_png(&self) -> Result<Vec<u8>> {
        let n = self.pixels();
        let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        let interleaved: Vec<u8> = (0..n)
            .flat_map(|i| (0..self.channels as usize).map(move |c| (i, c)))
            .map(|(i, c)| q(self.values[c * n + i]))
            .collect();
        let (w, h) = (self.width, self.height);
        let mut out = Cursor::new(Vec::new());
        let res = match self.channels {
            1 => ImageBuffer::<Luma<u8>, _>::from_raw(w, h, interleaved)
                .map(|b| b.write_to(&mut out, ImageFormat::Png)),
            3 => ImageBuffer::<Rgb<u8>, _>::from_raw(w, h, interleaved)
                .map(|b| b.write_to(&mut out, ImageFormat::Png)),
            4 => ImageBuffer::<Rgba<u8>, _>::from_raw(w, h, interleaved)
                .map(|b| b.write_to(&mut out, ImageFormat::Png)),
            c => {
                return Err(Error::Shape(format!(
                    "PNG holds 1, 3 or 4 channels, the image has {c}"
                )));
            }
        };
        match res {
            Some(Ok(())) => Ok(out.into_inner()),
            Some(Err(e)) => Err(Error::Image {
                path: "<memory>".into(),
                message: e.to_string(),
            }),
            None => Err(Error::Shape("image buffer size mismatch".into())),
        }
    }

    /// Writes the image as a PNG, atomically.
    pub fn save_png(&self, path: &Path) -> Result<()> {
        let bytes = self.encode_png().map_err(|e| match e {
            Error::Image { message, .. } => Error::Image {
                path: path.to_owned(),
                message,
            },
            other => other,
        })?;
        write_atomic(path, &bytes)
    }
}

/// The exact Euclidean distance, in pixels, from every pixel centre of a `width × height`
/// image to the nearest pixel set in `mask` (0 on those), by the separable lower-envelope
/// algorithm of Felzenszwalb & Huttenlocher (columns, then rows); `None` when `mask` has no
/// pixel set or does not have `width × height` entries.
pub fn distance_to(mask: &[bool], width: usize, height: usize) -> Option<Vec<f64>> {
    if mask.len() != width * height || !mask.iter().any(|&m| m) {
        return None;
    }
    const FAR: f64 = 1e20;
    let mut f: Vec<f64> = mask.iter().map(|&m| if m { 0.0 } else { FAR }).collect();
    let mut col = vec![0.0; height];
    let mut out = vec![0.0; height.max(width)];
    for j in 0..width {
        for i in 0..height {
            col[i] = f[i * width + j];
        }
        squared_1d(&col, &mut out[..height]);
        for i in 0..height {
            f[i * width + j] = out[i];
        }
    }
    let mut row = vec![0.0; width];
    for i in 0..height {
        row.copy_from_slice(&f[i * width..(i + 1) * width]);
        squared_1d(&row, &mut out[..width]);
        for j in 0..width {
            f[i * width + j] = out[j].sqrt();
        }
    }
    Some(f)
}

/// [`distance_to`] on a voxel grid of `dims = [nx, ny, nz]` (index `x + nx·(y + ny·z)`):
/// the exact Euclidean distance, in voxels, from every voxel centre to the nearest voxel set
/// in `mask` (the same separable algorithm along x, then y, then z); `None` when `mask` has
/// no voxel set or does not have `nx·ny·nz` entries.
pub fn distance_to_3d(mask: &[bool], dims: [usize; 3]) -> Option<Vec<f64>> {
    let [nx, ny, nz] = dims;
    if mask.len() != nx * ny * nz || !mask.iter().any(|&m| m) {
        return None;
    }
    const FAR: f64 = 1e20;
    let mut f: Vec<f64> = mask.iter().map(|&m| if m { 0.0 } else { FAR }).collect();
    let longest = nx.max(ny).max(nz);
    let (mut line, mut out) = (vec![0.0; longest], vec![0.0; longest]);
    // Along each axis in turn: the lines of that axis, each start and stride.
    let axes = [
        (nx, 1usize, ny * nz),
        (ny, nx, nx * nz),
        (nz, nx * ny, nx * ny),
    ];
    for (axis, &(n, stride, lines)) in axes.iter().enumerate() {
        for l in 0..lines {
            let start = match axis {
                0 => l * nx,
                1 => (l / nx) * nx * ny + l % nx,
                _ => l,
            };
            for i in 0..n {
                line[i] = f[start + i * stride];
            }
            squared_1d(&line[..n], &mut out[..n]);
            for i in 0..n {
                f[start + i * stride] = out[i];
            }
        }
    }
    f.iter_mut().for_each(|v| *v = v.sqrt());
    Some(f)
}

/// `out[q] = min_p (q − p)² + f[p]`: the 1-D squared distance transform.
fn squared_1d(f: &[f64], out: &mut [f64]) {
    let n = f.len();
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64);
            if s <= z[k] && k > 0 {
                k -= 1;
                continue;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
            break;
        }
    }
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let d = q as f64 - v[k] as f64;
        *o = d * d + f[v[k]];
    }
}

/// Decodes any file the `image` crate reads to RGBA floats; refuses an unreadable file and
/// one without pixels, naming it.
fn decode_rgba(path: &Path) -> Result<image::Rgba32FImage> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let img = image::load_from_memory(&bytes).map_err(|e| Error::Image {
        path: path.to_owned(),
        message: format!("not a readable image ({e})"),
    })?;
    let rgba = img.to_rgba32f();
    if rgba.width() == 0 || rgba.height() == 0 {
        return Err(Error::Image {
            path: path.to_owned(),
            message: "image has no pixels".into(),
        });
    }
    Ok(rgba)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rgb() -> Image {
        let (w, h) = (5, 3);
        let values = (0..3 * w * h).map(|i| (i % 7) as f32 / 6.0).collect();
        Image::new(w as u32, h as u32, 3, values).unwrap()
    }

    /// The voxel distance transform equals the brute-force nearest set voxel, on a grid
    /// whose three sides differ (so a swapped axis would show).
    #[test]
    fn voxel_distances_match_brute_force() {
        let dims = [7usize, 5, 4];
        let n = dims[0] * dims[1] * dims[2];
        let mask: Vec<bool> = (0..n).map(|i| (i * 37 + 11) % 53 == 0).collect();
        let at = |i: usize| {
            let (x, y, z) = (i % 7, (i / 7) % 5, i / 35);
            [x as f64, y as f64, z as f64]
        };
        let d = distance_to_3d(&mask, dims).unwrap();
        for (i, &di) in d.iter().enumerate() {
            let p = at(i);
            let best = (0..n)
                .filter(|&j| mask[j])
                .map(|j| {
                    let q = at(j);
                    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
                })
                .fold(f64::INFINITY, f64::min);
            assert!((di - best).abs() < 1e-12, "voxel {i}: {di} against {best}");
        }
        assert!(distance_to_3d(&vec![false; n], dims).is_none());
        assert!(distance_to_3d(&mask[1..], dims).is_none());
    }

    #[test]
    fn png_and_tensor_round_trips_keep_planes_in_place() {
        let img = rgb();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.png");
        img.save_png(&p).unwrap();
        let back = Image::load(&p, true).unwrap();
        assert_eq!((back.width, back.height, back.channels), (5, 3, 3));
        for (a, b) in img.values.iter().zip(&back.values) {
            assert!((a - b).abs() <= 0.5 / 255.0 + 1e-6, "{a} vs {b}");
        }
        let t = img.to_tensor(DType::F64, &Device::Cpu).unwrap();
        assert_eq!(t.dims(), &[3, 3, 5]);
        assert_eq!(Image::from_tensor(&t).unwrap(), img);
        // Grey from file equals grey from the RGB planes (both luma).
        let g = Image::load(&p, false).unwrap();
        for (a, b) in g.values.iter().zip(&back.to_grey().values) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
    }

    #[test]
    fn bad_shapes_are_refused() {
        assert!(Image::new(2, 2, 3, vec![0.0; 11]).is_err());
        assert!(Image::<f32>::new(0, 2, 1, vec![]).is_err());
        let two = Image::new(1, 1, 2, vec![0.0, 1.0]).unwrap();
        let e = two.encode_png().unwrap_err();
        assert!(e.to_string().contains("1, 3 or 4 channels"), "{e}");
    }

    #[test]
    fn shapes_are_checked_by_name_and_pictures_widen_exactly() {
        let img = rgb();
        img.expect_shape("the target", 3, 5, 3).unwrap();
        let e = img
            .expect_shape("the target", 1, 5, 3)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the target is a 5×3 RGB image; 5×3 grey is needed"),
            "{e}"
        );
        let e = img
            .expect_shape("the views", 8, 4, 4)
            .unwrap_err()
            .to_string();
        assert!(e.contains("4×4 8-plane is needed"), "{e}");
        let wide = img.widened();
        assert_eq!((wide.width, wide.height, wide.channels), (5, 3, 3));
        assert!(
            wide.values
                .iter()
                .zip(&img.values)
                .all(|(&a, &b)| a == b as f64)
        );
        assert!(Image::square(4, vec![0.5f64; 15]).is_err());
        assert_eq!(
            Image::square(4, vec![0.5f64; 16]).unwrap().plane(0).len(),
            16
        );
    }
}
