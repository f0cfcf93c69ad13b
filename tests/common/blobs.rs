//! A renderer written outside the crate, shared by the core's renderer tests and the
//! strategies' one-image-problem test.

use ifslab::render::{Draws, Planes, Renderer};

/// A renderer written outside the crate: isotropic Gaussian blobs `(x, y, a)` (centre in
/// pixels, amplitude) summed on a grey `size × size` image,
/// `image(i, j) = Σ a·exp(−((j − x)² + (i − y)²)/2s²)`.
#[derive(Clone, Debug)]
pub struct Blobs {
    /// Image side in pixels.
    pub size: usize,
    /// Blob width in pixels.
    pub s: f64,
}

impl Renderer for Blobs {
    type Scene = [f64];
    type Pixel = f64;
    type Sampling = ();
    type Tape = ();

    const DRAWS: Draws = Draws::Never;

    fn planes(&self) -> Planes {
        Planes {
            channels: 1,
            height: self.size,
            width: self.size,
        }
    }

    fn sampling(&self, _: &[f64], _: u64, _: u64) {}

    fn forward(&self, blobs: &[f64], _: &()) -> ifslab::Result<(Vec<f64>, ())> {
        let n = self.size;
        let mut image = vec![0.0; n * n];
        for b in blobs.chunks_exact(3) {
            for (q, v) in image.iter_mut().enumerate() {
                let (dx, dy) = ((q % n) as f64 - b[0], (q / n) as f64 - b[1]);
                *v += b[2] * (-(dx * dx + dy * dy) / (2.0 * self.s * self.s)).exp();
            }
        }
        Ok((image, ()))
    }

    /// `∂image/∂a = g`, `∂image/∂x = a·g·(j − x)/s²`, `∂image/∂y = a·g·(i − y)/s²` with `g`
    /// the blob's Gaussian at the pixel.
    fn backward(&self, blobs: &[f64], _: &(), _: &(), grad: &[f64]) -> ifslab::Result<Vec<f64>> {
        let (n, s2) = (self.size, self.s * self.s);
        let mut out = vec![0.0; blobs.len()];
        for (b, o) in blobs.chunks_exact(3).zip(out.chunks_exact_mut(3)) {
            for (q, lam) in grad.iter().enumerate() {
                let (dx, dy) = ((q % n) as f64 - b[0], (q / n) as f64 - b[1]);
                let g = (-(dx * dx + dy * dy) / (2.0 * s2)).exp();
                o[0] += lam * b[2] * g * dx / s2;
                o[1] += lam * b[2] * g * dy / s2;
                o[2] += lam * g;
            }
        }
        Ok(out)
    }
}
