//! The SDF raster as a [`Renderer`]: a segment pattern → the paper's intensity
//! `exp(−d²/σ²)` and/or the distance field itself, deterministic (no sampling state).

use super::raster::{SdfRaster, SdfRenderConfig, SdfView};
use crate::error::{Error, Result};
use crate::model::segment::Pattern;
use crate::render::renderer::{Draws, Planes, Renderer};

/// The SDF raster of a pattern in `view`, drawn to `cfg.depth` with lines of width `sigma`
/// pixels. Its image holds the intensity plane `exp(−d²/σ²)` when `intensity`, then the
/// distance plane `d` in units of the image's longer side when `distance` (a loss on
/// distances, which the intensity flattens far from the figure).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SdfRenderer {
    /// Which part of the plane the pixels show.
    pub view: SdfView,
    /// Depth and cut-off.
    pub cfg: SdfRenderConfig,
    /// Line width in pixels.
    pub sigma: f64,
    /// Draw the intensity plane.
    pub intensity: bool,
    /// Draw the distance plane (needs the exact distances: no cut-off).
    pub distance: bool,
}

impl SdfRenderer {
    /// The intensity image alone.
    pub fn new(view: SdfView, cfg: SdfRenderConfig, sigma: f64) -> Self {
        SdfRenderer {
            view,
            cfg,
            sigma,
            intensity: true,
            distance: false,
        }
    }

    /// The longer side of the image, the distance plane's unit, in pixels.
    fn side(&self) -> f64 {
        self.view.width.max(self.view.height) as f64
    }
}

impl Renderer for SdfRenderer {
    type Scene = Pattern;
    type Pixel = f64;
    type Sampling = ();
    /// The distance field and the nearest primitive of every pixel.
    type Tape = SdfRaster;

    const DRAWS: Draws = Draws::Never;

    fn planes(&self) -> Planes {
        Planes {
            channels: self.intensity as usize + self.distance as usize,
            height: self.view.height,
            width: self.view.width,
        }
    }

    fn sampling(&self, _pattern: &Pattern, _seed: u64, _draw: u64) {}

    fn forward(&self, pattern: &Pattern, _: &()) -> Result<(Vec<f64>, SdfRaster)> {
        let r = SdfRaster::render(pattern, &self.view, &self.cfg)?;
        let image = match (self.intensity, self.distance) {
            (true, false) => r.image(self.sigma),
            (i, d) => {
                let side = self.side();
                let mut out = Vec::with_capacity(self.planes().len());
                if i {
                    out.extend(r.image(self.sigma));
                }
                if d {
                    out.extend(r.distances().iter().map(|x| x / side));
                }
                out
            }
        };
        Ok((image, r))
    }

    fn backward(
        &self,
        pattern: &Pattern,
        _: &(),
        raster: &SdfRaster,
        grad_image: &[f64],
    ) -> Result<Vec<f64>> {
        let n = self.view.width * self.view.height;
        if grad_image.len() != self.planes().len() {
            return Err(Error::Shape(format!(
                "{} image gradients for {} planes of {n} pixels",
                grad_image.len(),
                self.planes().channels
            )));
        }
        let (gi, gd) = grad_image.split_at(if self.intensity { n } else { 0 });
        let grad_dist = match (self.intensity, self.distance) {
            (true, false) => raster.image_backward(self.sigma, gi),
            (false, true) => {
                let side = self.side();
                gd.iter().map(|x| x / side).collect()
            }
            (true, true) => {
                let side = self.side();
                let mut g = raster.image_backward(self.sigma, gi);
                for (a, x) in g.iter_mut().zip(gd) {
                    *a += x / side;
                }
                g
            }
            (false, false) => vec![0.0; n],
        };
        raster.backward(pattern, &grad_dist)
    }
}
