//! The moments loss of the chaotic-splatting paper's ablation: squared differences of the
//! images' intensity-weighted spatial moments along each axis.
//!
//! Each image is read as a mass distribution `I(x, y) ≥ 0` over pixel centres with
//! normalised coordinates `u = (x + ½)/W`, `v = (y + ½)/H` (row 0 at the top). Along the
//! u-axis, with the column sums `c_j = Σ_y I(j, y)` and total mass `M = Σ_j c_j`:
//!
//! - order 1, the centroid: `f₁ = m = Σ_j c_j u_j / M`;
//! - order 2, the variance: `f₂ = μ₂`, with central moments `μ_k = Σ_j c_j (u_j − m)^k / M`;
//! - order k ≥ 3, standardised moments: `f_k = μ_k / (μ₂ + ε)^{k/2}` (3: skewness,
//!   4: kurtosis), `ε = 1e-12`;
//!
//! and the same along the v-axis with the row sums. The loss is
//!
//! `L = Σ_{axis ∈ {u, v}} Σ_{k = 1}^{K} (f_k(pred) − f_k(target))²`,
//!
//! with `K` = [`Moments::max_order`] (default 4: mean, variance, skewness and kurtosis, as
//! in the reference code; coordinates there are `x/W`, a constant shift that cancels in
//! every term). The moments are normalised by the mass, so the loss ignores overall
//! brightness. The tiny `ε` only keeps the standardised moments finite for a one-column or
//! one-row image; an all-black image has no moments and is refused with an error.
//!
//! **Gradient**: the loss depends on the image only through the column and row sums, so
//! `∂L/∂I(x, y) = ∂L/∂c_x + ∂L/∂r_y`, with
//! `∂m/∂c_j = (u_j − m)/M` and `∂μ_k/∂c_j = ((u_j − m)^k − μ_k − k·μ_{k−1}·(u_j − m))/M`
//! (`μ₀ = 1`, `μ₁ = 0`); the standardised moments follow by the quotient rule.
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point
//!   Splatting*, Eurographics 2025 (ablation of the image loss).

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::loss::{ImageLoss, Real, check_pair, cst, f64_of};

/// Regulariser of the variance in the standardised moments.
const VAR_EPS: f64 = 1e-12;

/// The moments loss (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Moments {
    /// Highest moment order matched, 1 to 6 (default 4).
    pub max_order: usize,
}

impl Default for Moments {
    fn default() -> Self {
        Moments { max_order: 4 }
    }
}

/// Moment features of one axis and what their gradient needs.
struct Axis {
    mass: f64,
    mean: f64,
    /// Central moments μ₀ … μ_K (μ₀ = 1, μ₁ = 0).
    mu: Vec<f64>,
}

impl Axis {
    fn new(sums: &[f64], max_order: usize) -> Self {
        let n = sums.len() as f64;
        let coord = |j: usize| (j as f64 + 0.5) / n;
        let mass: f64 = sums.iter().sum();
        let mean = sums
            .iter()
            .enumerate()
            .map(|(j, &c)| c * coord(j))
            .sum::<f64>()
            / mass;
        let mut mu = vec![0.0; max_order.max(2) + 1];
        mu[0] = 1.0;
        for (j, &c) in sums.iter().enumerate() {
            let d = coord(j) - mean;
            let mut p = d;
            for m in mu.iter_mut().skip(2) {
                p *= d;
                *m += c * p;
            }
        }
        for m in mu.iter_mut().skip(2) {
            *m /= mass;
        }
        Axis { mass, mean, mu }
    }

    /// Feature f_k.
    fn feature(&self, k: usize) -> f64 {
        match k {
            1 => self.mean,
            2 => self.mu[2],
            _ => self.mu[k] / (self.mu[2] + VAR_EPS).powf(k as f64 / 2.0),
        }
    }

    /// ∂L/∂c_j for every column given ∂L/∂f_k (`gf[k]`, k = 1..=K).
    fn backward(&self, gf: &[f64], len: usize) -> Vec<f64> {
        let n = len as f64;
        let k_max = gf.len() - 1;
        let var = self.mu[2] + VAR_EPS;
        (0..len)
            .map(|j| {
                let d = (j as f64 + 0.5) / n - self.mean;
                // ∂μ_k/∂c_j for k = 2..=K.
                let dmu = |k: usize| {
                    (d.powi(k as i32) - self.mu[k] - k as f64 * self.mu[k - 1] * d) / self.mass
                };
                let dmu2 = dmu(2);
                let mut g = gf[1] * d / self.mass;
                if k_max >= 2 {
                    g += gf[2] * dmu2;
                }
                for (k, &gk) in gf.iter().enumerate().skip(3) {
                    let kf = k as f64;
                    let df = dmu(k) / var.powf(kf / 2.0)
                        - 0.5 * kf * self.mu[k] * var.powf(-kf / 2.0 - 1.0) * dmu2;
                    g += gk * df;
                }
                g
            })
            .collect()
    }
}

impl Moments {
    fn check(&self) -> Result<()> {
        if !(1..=6).contains(&self.max_order) {
            return Err(Error::param(
                "max_order",
                format!(
                    "the moments loss matches orders 1 to 6, got {}",
                    self.max_order
                ),
            ));
        }
        Ok(())
    }

    /// Column sums and row sums in f64.
    fn marginals<T: Real>(img: &[T], width: usize, height: usize) -> (Vec<f64>, Vec<f64>) {
        let rows: Vec<f64> = img
            .par_chunks(width)
            .map(|r| r.iter().map(|&v| f64_of(v)).sum())
            .collect();
        // Column sums over fixed blocks of rows, added in order (deterministic).
        let blocks: Vec<Vec<f64>> = img
            .par_chunks(width * 64)
            .map(|block| {
                let mut acc = vec![0.0; width];
                for r in block.chunks(width) {
                    for (a, &v) in acc.iter_mut().zip(r) {
                        *a += f64_of(v);
                    }
                }
                acc
            })
            .collect();
        let mut cols = vec![0.0; width];
        for b in &blocks {
            for (c, v) in cols.iter_mut().zip(b) {
                *c += v;
            }
        }
        debug_assert_eq!(rows.len(), height);
        (cols, rows)
    }

    fn axes<T: Real>(
        &self,
        img: &[T],
        width: usize,
        height: usize,
        what: &str,
    ) -> Result<[Axis; 2]> {
        let (cols, rows) = Self::marginals(img, width, height);
        let mass: f64 = rows.iter().sum();
        if !mass.is_finite() || mass <= 0.0 {
            return Err(Error::Empty(format!(
                "the {what} image has total intensity {mass}; the moments loss needs an image \
                 with some positive intensity (is the render all black?)"
            )));
        }
        Ok([
            Axis::new(&cols, self.max_order),
            Axis::new(&rows, self.max_order),
        ])
    }

    /// The moment features `[f_1 … f_K]` of each axis (`[u-axis, v-axis]`), for logging and tests.
    pub fn features<T: Real>(
        &self,
        img: &[T],
        width: usize,
        height: usize,
    ) -> Result<[Vec<f64>; 2]> {
        self.check()?;
        check_pair(img, img, width, height)?;
        let axes = self.axes(img, width, height, "given")?;
        Ok(axes.map(|a| (1..=self.max_order).map(|k| a.feature(k)).collect()))
    }
}

impl ImageLoss for Moments {
    fn name(&self) -> &'static str {
        "moments"
    }

    fn value_and_grad<T: Real>(
        &self,
        pred: &[T],
        target: &[T],
        width: usize,
        height: usize,
    ) -> Result<(T, Vec<T>)> {
        self.check()?;
        check_pair(pred, target, width, height)?;
        let p = self.axes(pred, width, height, "predicted")?;
        let t = self.axes(target, width, height, "target")?;
        let mut value = 0.0;
        let mut grads = Vec::with_capacity(2);
        for (a, (pa, ta)) in p.iter().zip(&t).enumerate() {
            let mut gf = vec![0.0; self.max_order + 1];
            for (k, g) in gf.iter_mut().enumerate().skip(1) {
                let diff = pa.feature(k) - ta.feature(k);
                value += diff * diff;
                *g = 2.0 * diff;
            }
            grads.push(pa.backward(&gf, if a == 0 { width } else { height }));
        }
        let (gc, gr) = (&grads[0], &grads[1]);
        let mut grad = vec![T::zero(); width * height];
        grad.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
            for (x, g) in row.iter_mut().enumerate() {
                *g = cst(gc[x] + gr[y]);
            }
        });
        Ok((cst(value), grad))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn features_of_a_single_bright_column() {
        // A single lit pixel column at x = 2 of a 4-wide image: centroid (2.5)/4.
        let (w, h) = (4, 3);
        let mut img = vec![0.0f64; w * h];
        for y in 0..h {
            img[y * w + 2] = 1.0;
        }
        let [u, v] = Moments::default().features(&img, w, h).unwrap();
        assert!((u[0] - 2.5 / 4.0).abs() < 1e-15);
        assert!(u[1].abs() < 1e-15, "no spread along u");
        assert!((v[0] - 0.5).abs() < 1e-15);
        // v: three equal rows at 1/6, 1/2, 5/6 → variance (2·(1/3)²)/3 = 2/27, symmetric.
        assert!((v[1] - 2.0 / 27.0).abs() < 1e-15);
        assert!(v[2].abs() < 1e-9, "symmetric ⇒ zero skewness");
    }

    #[test]
    fn brightness_does_not_matter() {
        let (w, h) = (11, 7);
        let a: Vec<f64> = (0..w * h).map(|i| ((i * 13 % 17) as f64) / 17.0).collect();
        let b: Vec<f64> = a.iter().map(|v| 0.5 * v).collect();
        let (v, _) = Moments::default().value_and_grad(&a, &b, w, h).unwrap();
        assert!(v < 1e-24, "{v}");
    }

    #[test]
    fn black_image_is_refused_with_a_clear_message() {
        let err = Moments::default()
            .value_and_grad(&[0.0f32; 12], &[1.0; 12], 4, 3)
            .unwrap_err();
        assert!(err.to_string().contains("all black"), "{err}");
        assert!(
            Moments { max_order: 9 }
                .value_and_grad(&[1.0f32; 12], &[1.0; 12], 4, 3)
                .is_err()
        );
    }
}
