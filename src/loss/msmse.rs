//! Multi-scale mean squared error over a 2×2 average-pooling mip pyramid.
//!
//! Level 0 is the image itself; level `l + 1` averages each 2×2 block of level `l`. A side
//! of odd length `n` becomes `⌈n/2⌉`: the last block along that side covers the single
//! remaining row or column and averages only the pixels that exist, so every pixel feeds
//! exactly one cell at every level and no border is dropped (`torch.avg_pool2d` would drop
//! it). The pyramid stops after [`MsMse::levels`] poolings, or as soon as a side has reached
//! one pixel (that level included): a 1024² image gives the 11 levels 1024², 512², …, 1².
//!
//! The loss is
//!
//! `L = Σ_l w_l · MSE_l`,   `MSE_l = (1/N_l) Σ_p (P_l(p) − T_l(p))²`
//!
//! with `w_l = 1` for [`MsMseReduction::Sum`] (the default) or `w_l = 1/#levels` for
//! [`MsMseReduction::Mean`]. The default follows the chaotic-splatting reference code,
//! which adds the MSE of the full-resolution image and of 10 coarser levels; that code also
//! re-normalises each coarser level with a helper whose definition is not public, so we keep
//! plain average pooling, which is linear and mass-preserving. Because pooling is linear,
//! the pyramid is built once from the difference `P − T`, and the gradient is the sum of
//! `2·w_l/N_l · (P_l − T_l)` pulled back through the pooling (each fine pixel receives its
//! cell's gradient divided by the cell's pixel count).
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point
//!   Splatting*, Eurographics 2025 (10·MSE over 10 mip levels).
//! - Williams, *Pyramidal Parametrics*, SIGGRAPH 1983 (mip maps).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::loss::{ImageLoss, Real, check_pair, cst, f64_of};

/// How the per-level MSEs are combined.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MsMseReduction {
    /// `Σ_l MSE_l` (the reference implementation's choice).
    #[default]
    Sum,
    /// `(1/#levels) Σ_l MSE_l`.
    Mean,
}

/// The difference pyramid `P_l − T_l`, the level sizes and the loss value.
struct Pyramid<T> {
    diffs: Vec<Vec<T>>,
    sizes: Vec<(usize, usize)>,
    value: f64,
}

/// Multi-scale MSE (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MsMse {
    /// Number of 2×2 poolings after the full-resolution level (the paper: 10).
    pub levels: usize,
    /// How levels are combined.
    pub reduction: MsMseReduction,
}

impl Default for MsMse {
    fn default() -> Self {
        MsMse {
            levels: 10,
            reduction: MsMseReduction::Sum,
        }
    }
}

impl MsMse {
    /// `levels` poolings after the full-resolution level, levels summed.
    pub fn new(levels: usize) -> Self {
        MsMse {
            levels,
            reduction: MsMseReduction::Sum,
        }
    }

    /// The same loss with another reduction.
    pub fn with_reduction(mut self, reduction: MsMseReduction) -> Self {
        self.reduction = reduction;
        self
    }

    /// The `(width, height)` of every level used for a `width × height` image, finest first.
    pub fn level_sizes(&self, width: usize, height: usize) -> Vec<(usize, usize)> {
        let mut sizes = vec![(width, height)];
        let (mut w, mut h) = (width, height);
        while sizes.len() <= self.levels && w > 1 && h > 1 {
            w = w.div_ceil(2);
            h = h.div_ceil(2);
            sizes.push((w, h));
        }
        sizes
    }

    fn level_weight(&self, n_levels: usize) -> f64 {
        match self.reduction {
            MsMseReduction::Sum => 1.0,
            MsMseReduction::Mean => 1.0 / n_levels as f64,
        }
    }

    /// The pyramid of `pred − target` and the loss value.
    fn forward<T: Real>(
        &self,
        pred: &[T],
        target: &[T],
        width: usize,
        height: usize,
    ) -> Result<Pyramid<T>> {
        check_pair(pred, target, width, height)?;
        let sizes = self.level_sizes(width, height);
        let mut diffs = Vec::with_capacity(sizes.len());
        let d0: Vec<T> = pred
            .par_iter()
            .zip(target.par_iter())
            .with_min_len(4096)
            .map(|(&p, &t)| p - t)
            .collect();
        diffs.push(d0);
        for l in 1..sizes.len() {
            let (w, h) = sizes[l - 1];
            diffs.push(downsample2x(&diffs[l - 1], w, h).0);
        }
        let weight = self.level_weight(sizes.len());
        let value = diffs
            .iter()
            .zip(&sizes)
            .map(|(d, &(w, h))| weight * sum_sq(d) / (w * h) as f64)
            .sum();
        Ok(Pyramid {
            diffs,
            sizes,
            value,
        })
    }
}

impl ImageLoss for MsMse {
    fn name(&self) -> &'static str {
        "ms_mse"
    }

    fn value_and_grad<T: Real>(
        &self,
        pred: &[T],
        target: &[T],
        width: usize,
        height: usize,
    ) -> Result<(T, Vec<T>)> {
        let Pyramid {
            diffs,
            sizes,
            value,
        } = self.forward(pred, target, width, height)?;
        let weight = self.level_weight(sizes.len());
        let coeff = |l: usize| {
            let (w, h) = sizes[l];
            cst::<T>(2.0 * weight / (w * h) as f64)
        };
        let last = sizes.len() - 1;
        let c = coeff(last);
        let mut grad: Vec<T> = diffs[last].iter().map(|&d| c * d).collect();
        for l in (0..last).rev() {
            let (w, h) = sizes[l];
            let c = coeff(l);
            let mut fine = downsample2x_adjoint(&grad, w, h);
            fine.par_iter_mut()
                .zip(diffs[l].par_iter())
                .with_min_len(4096)
                .for_each(|(g, &d)| *g = *g + c * d);
            grad = fine;
        }
        Ok((cst(value), grad))
    }

    fn value<T: Real>(&self, pred: &[T], target: &[T], width: usize, height: usize) -> Result<T> {
        Ok(cst(self.forward(pred, target, width, height)?.value))
    }
}

/// Σ d² in f64, in fixed-size chunks summed in order: the same bits whatever the thread count.
fn sum_sq<T: Real>(d: &[T]) -> f64 {
    d.par_chunks(4096)
        .map(|c| c.iter().map(|&v| f64_of(v * v)).sum::<f64>())
        .collect::<Vec<f64>>()
        .iter()
        .sum()
}

/// Averages each 2×2 block of a `width × height` image; returns the image and its size
/// `(⌈width/2⌉, ⌈height/2⌉)`. A block cut by an odd border averages the pixels it has.
pub fn downsample2x<T: Real>(src: &[T], width: usize, height: usize) -> (Vec<T>, usize, usize) {
    let (w2, h2) = (width.div_ceil(2), height.div_ceil(2));
    let mut out = vec![T::zero(); w2 * h2];
    out.par_chunks_mut(w2).enumerate().for_each(|(j, row)| {
        let y0 = 2 * j;
        let two_rows = y0 + 1 < height;
        let r0 = &src[y0 * width..][..width];
        for (i, o) in row.iter_mut().enumerate() {
            let x0 = 2 * i;
            let two_cols = x0 + 1 < width;
            let (mut s, mut n) = (r0[x0], 1.0);
            if two_cols {
                s = s + r0[x0 + 1];
                n += 1.0;
            }
            if two_rows {
                let r1 = &src[(y0 + 1) * width..][..width];
                s = s + r1[x0];
                n += 1.0;
                if two_cols {
                    s = s + r1[x0 + 1];
                    n += 1.0;
                }
            }
            *o = s / cst(n);
        }
    });
    (out, w2, h2)
}

/// The adjoint of [`downsample2x`]: spreads a gradient on the `⌈width/2⌉ × ⌈height/2⌉`
/// image back onto the `width × height` image (each pixel gets its block's value divided
/// by the block's pixel count).
pub fn downsample2x_adjoint<T: Real>(grad: &[T], width: usize, height: usize) -> Vec<T> {
    let w2 = width.div_ceil(2);
    let mut out = vec![T::zero(); width * height];
    out.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        let j = y / 2;
        let ny = if 2 * j + 1 < height { 2.0 } else { 1.0 };
        let g = &grad[j * w2..][..w2];
        for (x, o) in row.iter_mut().enumerate() {
            let i = x / 2;
            let nx = if 2 * i + 1 < width { 2.0 } else { 1.0 };
            *o = g[i] / cst(nx * ny);
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_sizes_stop_when_a_side_reaches_one() {
        let m = MsMse::new(10);
        assert_eq!(m.level_sizes(1024, 1024).len(), 11);
        assert_eq!(m.level_sizes(1024, 1024)[10], (1, 1));
        assert_eq!(
            m.level_sizes(5, 3),
            vec![(5, 3), (3, 2), (2, 1)],
            "odd sides round up; the level with a side of 1 is the last"
        );
        assert_eq!(MsMse::new(0).level_sizes(8, 8), vec![(8, 8)]);
    }

    #[test]
    fn odd_downsampling_averages_existing_pixels() {
        // 3×3 image: the last column and row are averaged on their own.
        let src = [1.0, 3.0, 5.0, 7.0, 9.0, 11.0, 13.0, 15.0, 17.0];
        let (d, w, h) = downsample2x(&src, 3, 3);
        assert_eq!((w, h), (2, 2));
        assert_eq!(d, vec![5.0, 8.0, 14.0, 17.0]);
    }

    #[test]
    fn downsample_adjoint_is_the_transpose() {
        // <D x, y> = <x, Dᵀ y> for the linear pooling D.
        let (w, h) = (7, 5);
        let x: Vec<f64> = (0..w * h).map(|i| ((i * 37 % 11) as f64).sin()).collect();
        let y: Vec<f64> = (0..4 * 3).map(|i| ((i * 13 % 7) as f64).cos()).collect();
        let (dx, _, _) = downsample2x(&x, w, h);
        let dty = downsample2x_adjoint(&y, w, h);
        let lhs: f64 = dx.iter().zip(&y).map(|(a, b)| a * b).sum();
        let rhs: f64 = x.iter().zip(&dty).map(|(a, b)| a * b).sum();
        assert!((lhs - rhs).abs() < 1e-12, "{lhs} vs {rhs}");
    }

    #[test]
    fn single_level_is_plain_mse() {
        let p = [0.0f64, 0.5, 1.0, 0.25];
        let t = [0.0, 0.0, 0.0, 0.0];
        let (v, g) = MsMse::new(0).value_and_grad(&p, &t, 2, 2).unwrap();
        assert!((v - (0.25 + 1.0 + 0.0625) / 4.0).abs() < 1e-15);
        // ∂/∂p (1/N)Σ(p − t)² = 2(p − t)/N
        assert_eq!(g, vec![0.0, 0.25, 0.5, 0.125]);
    }

    #[test]
    fn identical_images_have_zero_loss_and_gradient() {
        let p: Vec<f32> = (0..30 * 17).map(|i| (i % 13) as f32 / 13.0).collect();
        let (v, g) = MsMse::default().value_and_grad(&p, &p, 30, 17).unwrap();
        assert_eq!(v, 0.0);
        assert!(g.iter().all(|&x| x == 0.0));
    }

    #[test]
    fn mismatched_sizes_are_refused() {
        let err = MsMse::default()
            .value_and_grad(&[0.0f64; 6], &[0.0; 6], 4, 2)
            .unwrap_err();
        assert!(err.to_string().contains("4×2"), "{err}");
    }
}
