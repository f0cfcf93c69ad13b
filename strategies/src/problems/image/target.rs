//! Target images: loaded as grey, turned bright-on-dark, and framed the way the model frames
//! its points — the foreground's bounding box centred, its longest side spanning 75% of a
//! square canvas.

use std::path::Path;

use ifslab::image::Image;
use ifslab::render::FIT_FILL;
use ifslab::render::image_io::load_grey;
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

/// Pixels above this fraction of the brightest one count as foreground for framing.
const FOREGROUND: f32 = 0.1;

/// Loads `path` and frames it into a `size × size` target.
pub fn load_target(path: &Path, size: usize, polarity: Polarity) -> Result<Vec<f32>> {
    let img = load_grey(path)?;
    frame_target(&img, size, polarity).map_err(|e| match e {
        Error::InvalidInput(m) => Error::file(path, m),
        other => other,
    })
}

/// Frames an image (colour images by their luma) into a `size × size` grey target (values
/// in [0, 1], shape bright).
pub fn frame_target(img: &Image, size: usize, polarity: Polarity) -> Result<Vec<f32>> {
    let grey;
    let img = if img.channels == 1 {
        img
    } else {
        grey = img.to_grey();
        &grey
    };
    if size < 8 {
        return Err(Error::param(
            "size",
            format!("targets need at least 8×8 pixels, got {size}"),
        ));
    }
    let (w, h) = (img.width as usize, img.height as usize);
    let border_mean = {
        let mut s = 0.0f64;
        let mut n = 0usize;
        for y in 0..h {
            for x in 0..w {
                if x < 2 || y < 2 || x + 2 >= w || y + 2 >= h {
                    s += img.values[y * w + x] as f64;
                    n += 1;
                }
            }
        }
        s / n.max(1) as f64
    };
    let invert = match polarity {
        Polarity::Auto => border_mean > 0.5,
        Polarity::BrightOnDark => false,
        Polarity::DarkOnLight => true,
    };
    let v: Vec<f32> = img
        .values
        .iter()
        .map(|&x| if invert { 1.0 - x } else { x })
        .collect();
    let max = v.iter().copied().fold(0.0f32, f32::max);
    if max < 0.05 {
        let what = if invert {
            "all white (or uniformly light)"
        } else {
            "all black (or uniformly dark)"
        };
        return Err(Error::InvalidInput(format!(
            "the target is empty: it is {what}, so there is no shape to fit"
        )));
    }
    let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
    for y in 0..h {
        for x in 0..w {
            if v[y * w + x] > FOREGROUND * max {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
    }
    let (bw, bh) = (x1 - x0 + 1, y1 - y0 + 1);
    if bw * bh == w * h && polarity == Polarity::Auto && border_mean > 0.05 && border_mean < 0.95 {
        return Err(Error::InvalidInput(
            "the target has no background: its shape touches every border; give a picture of \
             a shape on a plain background, or say which way round it is drawn (`--polarity \
             bright-on-dark` or `dark-on-light` on the command line, `polarity` in a config)"
                .into(),
        ));
    }
    let crop: ImageBuffer<Luma<f32>, Vec<f32>> =
        ImageBuffer::from_fn(bw as u32, bh as u32, |x, y| {
            Luma([v[(y0 + y as usize) * w + x0 + x as usize]])
        });
    let scale = FIT_FILL * size as f64 / bw.max(bh) as f64;
    let (nw, nh) = (
        ((bw as f64 * scale).round() as u32).max(1),
        ((bh as f64 * scale).round() as u32).max(1),
    );
    let resized = imageops::resize(&crop, nw, nh, imageops::FilterType::Triangle);
    let mut out = vec![0.0f32; size * size];
    let (ox, oy) = ((size - nw as usize) / 2, (size - nh as usize) / 2);
    for (x, y, p) in resized.enumerate_pixels() {
        out[(oy + y as usize) * size + ox + x as usize] = p.0[0].clamp(0.0, 1.0);
    }
    Ok(out)
}

/// Writes a framed `size × size` target atomically as a lossless `.npy` array.
pub fn save_framed_target(path: &Path, target: &[f32], size: usize) -> Result<()> {
    if target.len() != size * size {
        return Err(Error::param(
            "target",
            format!("{} values do not make a {size}×{size} image", target.len()),
        ));
    }
    PointSet::new(size, target.iter().map(|&v| v as f64).collect())?.save(path)
}

/// Reads a target written by [`save_framed_target`]; it must be `size × size`.
pub fn load_framed_target(path: &Path, size: usize) -> Result<Vec<f32>> {
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
    Ok(rows.as_slice().iter().map(|&v| v as f32).collect())
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
        let t = frame_target(&img, 64, Polarity::Auto).unwrap();
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
        save_framed_target(&path, &t, 16).unwrap();
        let back = load_framed_target(&path, 16).unwrap();
        assert!(t.iter().zip(&back).all(|(a, b)| a.to_bits() == b.to_bits()));
        let e = load_framed_target(&path, 32).unwrap_err().to_string();
        assert!(e.contains("16×16") && e.contains("32×32"), "{e}");
        assert!(save_framed_target(&path, &t, 15).is_err());
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
        let bright = frame_target(&photo, 32, "bright-on-dark".parse().unwrap()).unwrap();
        let dark = frame_target(&photo, 32, "dark_on_light".parse().unwrap()).unwrap();
        assert_ne!(bright, dark);
        assert_eq!("auto".parse::<Polarity>().unwrap(), Polarity::Auto);
        let e = "sideways".parse::<Polarity>().unwrap_err().to_string();
        assert!(e.contains("sideways") && e.contains("dark-on-light"), "{e}");
    }
}
