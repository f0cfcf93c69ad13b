//! Interpolation baselines the paper compares against: nearest, bilinear, bicubic
//! (Catmull–Rom) and Lanczos-3 from the `image` crate, plus a hand-written parallel bilinear
//! with the GPU's texel-centre convention for a like-for-like timing with the decoder.

use image::imageops::{FilterType, resize};
use image::{ImageBuffer, Luma, Rgb};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::fractal_coding::texture::Texture;

/// An interpolation filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Filter {
    /// Nearest neighbour (texel replication).
    Nearest,
    /// Bilinear (the `image` crate's triangle filter).
    Bilinear,
    /// Bicubic, Catmull–Rom.
    Bicubic,
    /// Lanczos with a = 3.
    Lanczos,
}

impl Filter {
    /// Every filter, for comparison tables.
    pub const ALL: [Filter; 4] = [
        Filter::Nearest,
        Filter::Bilinear,
        Filter::Bicubic,
        Filter::Lanczos,
    ];

    /// The name used on the command line and in tables.
    pub fn name(self) -> &'static str {
        match self {
            Filter::Nearest => "nearest",
            Filter::Bilinear => "bilinear",
            Filter::Bicubic => "bicubic",
            Filter::Lanczos => "lanczos",
        }
    }

    /// Parses a name from [`Filter::name`].
    pub fn parse(s: &str) -> Result<Filter> {
        Filter::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                Error::param(
                    "filter",
                    format!("unknown filter `{s}`; use nearest, bilinear, bicubic or lanczos"),
                )
            })
    }

    fn image_filter(self) -> FilterType {
        match self {
            Filter::Nearest => FilterType::Nearest,
            Filter::Bilinear => FilterType::Triangle,
            Filter::Bicubic => FilterType::CatmullRom,
            Filter::Lanczos => FilterType::Lanczos3,
        }
    }
}

fn check_factor(factor: u32) -> Result<()> {
    if factor == 0 {
        return Err(Error::param("factor", "must be at least 1"));
    }
    Ok(())
}

/// Upsamples by an integer `factor` with the `image` crate's resampler (values are clamped to
/// 0–255, as an 8-bit texture would be).
pub fn upsample(t: &Texture, factor: u32, filter: Filter) -> Result<Texture> {
    check_factor(factor)?;
    let (w, h, ch) = (t.width() as u32, t.height() as u32, t.channels());
    let (ow, oh) = (w * factor, h * factor);
    let scaled: Vec<f32> = t.data().iter().map(|v| v / 255.0).collect();
    let out: Vec<f32> = if ch == 1 {
        let img = ImageBuffer::<Luma<f32>, _>::from_raw(w, h, scaled).expect("texture shape");
        resize(&img, ow, oh, filter.image_filter()).into_raw()
    } else {
        let img = ImageBuffer::<Rgb<f32>, _>::from_raw(w, h, scaled).expect("texture shape");
        resize(&img, ow, oh, filter.image_filter()).into_raw()
    };
    Texture::new(
        ow as usize,
        oh as usize,
        ch,
        out.into_iter()
            .map(|v| (v * 255.0).clamp(0.0, 255.0))
            .collect(),
    )
}

/// Bilinear upsampling by an integer `factor` as texture hardware does it: output texel p
/// samples the source at (p + ½)/factor − ½ with clamp-to-edge, every texel independently,
/// rows in parallel.
pub fn bilinear_parallel(t: &Texture, factor: u32) -> Result<Texture> {
    check_factor(factor)?;
    let f = factor as usize;
    let (w, h, ch) = (t.width(), t.height(), t.channels());
    let mut out = vec![0.0f32; w * f * h * f * ch];
    bilinear_into(t, factor, &mut out)?;
    Texture::new(w * f, h * f, ch, out)
}

/// [`bilinear_parallel`] into a caller's buffer of `factor²` times the texture's values (e.g.
/// one reused frame after frame).
pub fn bilinear_into(t: &Texture, factor: u32, out: &mut [f32]) -> Result<()> {
    check_factor(factor)?;
    let f = factor as usize;
    let (w, h, ch) = (t.width(), t.height(), t.channels());
    let (ow, oh) = (w * f, h * f);
    if out.len() != ow * oh * ch {
        return Err(Error::InvalidInput(format!(
            "output buffer of {} values for a {ow}×{oh}×{ch} output",
            out.len()
        )));
    }
    // Per output column: left texel, right texel and weight (the same for every row).
    let taps = |n: usize, i: usize| -> (usize, usize, f32) {
        let s = ((i as f32 + 0.5) / factor as f32 - 0.5).max(0.0);
        let i0 = (s.floor() as usize).min(n - 1);
        let i1 = (i0 + 1).min(n - 1);
        (i0, i1, s - i0 as f32)
    };
    let cols: Vec<(u32, u32, f32)> = (0..ow)
        .map(|x| {
            let (a, b, f) = taps(w, x);
            ((a * ch) as u32, (b * ch) as u32, f)
        })
        .collect();
    let src = t.data();
    out.par_chunks_mut(ow * ch).enumerate().for_each_init(
        || vec![0.0f32; w * ch],
        |tmp, (y, row)| {
            // Vertical pass once per output row over the source width, then horizontal.
            let (y0, y1, fy) = taps(h, y);
            let r0 = &src[y0 * w * ch..(y0 + 1) * w * ch];
            let r1 = &src[y1 * w * ch..(y1 + 1) * w * ch];
            for ((t, &a), &b) in tmp.iter_mut().zip(r0).zip(r1) {
                *t = a + fy * (b - a);
            }
            if ch == 1 {
                horizontal::<1>(tmp, &cols, row);
            } else {
                horizontal::<3>(tmp, &cols, row);
            }
        },
    );
    Ok(())
}

/// The horizontal pass of [`bilinear_into`] for `CH` channels.
fn horizontal<const CH: usize>(tmp: &[f32], cols: &[(u32, u32, f32)], row: &mut [f32]) {
    for (o, &(x0, x1, fx)) in row.chunks_exact_mut(CH).zip(cols) {
        let a: &[f32; CH] = tmp[x0 as usize..x0 as usize + CH]
            .try_into()
            .expect("CH values");
        let b: &[f32; CH] = tmp[x1 as usize..x1 as usize + CH]
            .try_into()
            .expect("CH values");
        for k in 0..CH {
            o[k] = a[k] + fx * (b[k] - a[k]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_of_a_ramp_is_a_ramp_inside() {
        let t = Texture::from_fn(8, 4, 1, |x, _, _| 10.0 * x as f32).unwrap();
        let u = bilinear_parallel(&t, 4).unwrap();
        // Sample position of output x is (x + ½)/4 − ½ in source texels.
        for x in 2..30 {
            let s = (x as f32 + 0.5) / 4.0 - 0.5;
            assert!((u.get(x, 5, 0) - 10.0 * s).abs() < 1e-4);
        }
        let lib = upsample(&t, 4, Filter::Bilinear).unwrap();
        assert_eq!((lib.width(), lib.height()), (32, 16));
        assert!((lib.get(12, 5, 0) - u.get(12, 5, 0)).abs() < 0.5);
    }

    #[test]
    fn filter_names_round_trip() {
        for f in Filter::ALL {
            assert_eq!(Filter::parse(f.name()).unwrap(), f);
        }
        assert!(Filter::parse("sinc").is_err());
    }
}
