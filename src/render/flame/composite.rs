//! Flames laid over one another: each transparent render (RGB 0–255, alpha in [0, 1], as
//! [`render_flame`](super::render_flame) makes with `transparent`) weighted by its alpha
//! over what lies below, on a background colour — `ifslab flame render --composite`.

use super::FlameImage;
use crate::error::{Error, Result};
use crate::image::Image;

/// A canvas that transparent flame renders are laid over in turn.
#[derive(Clone, Debug)]
pub struct Composite {
    width: u32,
    height: u32,
    /// Row-major RGB in 0–255.
    acc: Vec<[f32; 3]>,
}

impl Composite {
    /// A `width × height` canvas of `background` (RGB in [0, 1], as a flame's).
    pub fn new(width: u32, height: u32, background: [f64; 3]) -> Self {
        let bg = background.map(|v| (v * 255.0) as f32);
        Composite {
            width,
            height,
            acc: vec![bg; width as usize * height as usize],
        }
    }

    /// Lays `img` over the canvas: `c ← c_img·α + c·(1 − α)` per pixel. A render of
    /// another size is refused.
    pub fn over(&mut self, img: &FlameImage) -> Result<()> {
        if (img.width, img.height) != (self.width, self.height) {
            return Err(Error::Shape(format!(
                "flames of different sizes ({}×{} and {}×{}) cannot be composited",
                self.width, self.height, img.width, img.height
            )));
        }
        for (d, p) in self.acc.iter_mut().zip(&img.pixels) {
            for c in 0..3 {
                d[c] = p[c] * p[3] + d[c] * (1.0 - p[3]);
            }
        }
        Ok(())
    }

    /// The canvas as an RGB image in [0, 1].
    pub fn into_image(self) -> Result<Image> {
        let n = self.acc.len();
        let mut planes = vec![0f32; 3 * n];
        for (i, p) in self.acc.iter().enumerate() {
            for c in 0..3 {
                planes[c * n + i] = (p[c] / 255.0).clamp(0.0, 1.0);
            }
        }
        Image::new(self.width, self.height, 3, planes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::flame::FlameStats;

    fn layer(w: u32, h: u32, rgba: [f32; 4]) -> FlameImage {
        FlameImage {
            width: w,
            height: h,
            pixels: vec![rgba; (w * h) as usize],
            stats: FlameStats::default(),
        }
    }

    #[test]
    fn layers_mix_by_their_alpha_over_the_background_and_sizes_must_match() {
        let mut c = Composite::new(2, 1, [1.0, 1.0, 1.0]);
        // Half-transparent red over white, then fully transparent blue (no change).
        c.over(&layer(2, 1, [255.0, 0.0, 0.0, 0.5])).unwrap();
        c.over(&layer(2, 1, [0.0, 0.0, 255.0, 0.0])).unwrap();
        let e = c.over(&layer(3, 1, [0.0; 4])).unwrap_err().to_string();
        assert!(e.contains("2×1 and 3×1"), "{e}");
        let img = c.clone().into_image().unwrap();
        assert_eq!(img.plane(0), &[1.0, 1.0]);
        assert!((img.plane(1)[0] - 0.5).abs() < 1e-6 && (img.plane(2)[1] - 0.5).abs() < 1e-6);
        // An opaque layer covers what is below.
        c.over(&layer(2, 1, [0.0, 255.0, 0.0, 1.0])).unwrap();
        let img = c.into_image().unwrap();
        assert_eq!(
            (img.plane(0)[0], img.plane(1)[0], img.plane(2)[0]),
            (0.0, 1.0, 0.0)
        );
    }
}
