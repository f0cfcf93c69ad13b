//! SSIM and the D-SSIM loss (1 − SSIM), with its exact gradient.
//!
//! Local statistics come from a separable, normalised Gaussian window (11 pixels, σ = 1.5):
//! with `G∗` that blur,
//!
//! `μx = G∗x`, `μy = G∗y`, `σx² = G∗x² − μx²`, `σy² = G∗y² − μy²`, `σxy = G∗(xy) − μx·μy`,
//!
//! `S = (2μxμy + C1)(2σxy + C2) / ((μx² + μy² + C1)(σx² + σy² + C2))`, `C1 = 0.01²`, `C2 = 0.03²`
//!
//! (the constants for a dynamic range of 1), and `SSIM = mean_p S(p)` over all `W·H` pixels.
//!
//! **Borders**: the blur is a "same"-size convolution with zero padding, as in the reference
//! implementation of the chaotic-splatting paper (and the 3D Gaussian splatting SSIM it
//! comes from). For our targets — white fractals on black — zero is also the true
//! continuation of the image outside the frame. Metric-style SSIM (scikit-image) instead
//! crops the border; [`crate::metrics`] offers cropping and masking on top of [`ssim_map`].
//!
//! **Gradient**: writing `A1 = 2μxμy + C1`, `A2 = 2σxy + C2`, `B1 = μx² + μy² + C1`,
//! `B2 = σx² + σy² + C2` and treating `S` as a function of `μx` and the raw moments
//! `mxx = G∗x²`, `mxy = G∗(xy)`:
//!
//! `∂S/∂μx = 2μy·(A2 − A1)/(B1B2) − 2μx·S·(1/B1 − 1/B2)`, `∂S/∂mxx = −S/B2`,
//! `∂S/∂mxy = 2A1/(B1B2)`,
//!
//! and since the zero-padded blur with a symmetric kernel is self-adjoint,
//!
//! `∂(1 − SSIM)/∂x = −(1/N)·[G∗(∂S/∂μx) + 2x·G∗(∂S/∂mxx) + y·G∗(∂S/∂mxy)]`.
//!
//! Forward and backward cost eight separable blurs; every pass is parallel over rows.
//!
//! ## References
//! - Wang, Bovik, Sheikh, Simoncelli, *Image Quality Assessment: From Error Visibility to
//!   Structural Similarity*, IEEE TIP 2004.
//! - Kerbl, Kopanas, Leimkühler, Drettakis, *3D Gaussian Splatting for Real-Time Radiance
//!   Field Rendering*, SIGGRAPH 2023 (the zero-padded variant).
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point
//!   Splatting*, Eurographics 2025.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::loss::{ImageLoss, Real, check_pair, cst, f64_of};

/// SSIM's luminance constant `(0.01·L)²` for the dynamic range `L = 1`.
pub const SSIM_C1: f64 = 0.01 * 0.01;
/// SSIM's contrast constant `(0.03·L)²` for the dynamic range `L = 1`.
pub const SSIM_C2: f64 = 0.03 * 0.03;

/// The D-SSIM loss `1 − SSIM` (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DSsim {
    /// Window size in pixels (odd; the paper: 11).
    pub window: usize,
    /// Standard deviation of the Gaussian window in pixels (the paper: 1.5).
    pub sigma: f64,
}

impl Default for DSsim {
    fn default() -> Self {
        DSsim {
            window: 11,
            sigma: 1.5,
        }
    }
}

impl DSsim {
    /// The normalised 1-D window, or an error naming the bad field.
    pub fn kernel(&self) -> Result<Vec<f64>> {
        if self.window.is_multiple_of(2) {
            return Err(Error::param(
                "window",
                format!(
                    "the SSIM window must be an odd number of pixels, got {}",
                    self.window
                ),
            ));
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return Err(Error::param(
                "sigma",
                format!("the SSIM window's sigma must be > 0, got {}", self.sigma),
            ));
        }
        let r = (self.window / 2) as f64;
        let g: Vec<f64> = (0..self.window)
            .map(|i| (-(i as f64 - r).powi(2) / (2.0 * self.sigma * self.sigma)).exp())
            .collect();
        let s: f64 = g.iter().sum();
        Ok(g.into_iter().map(|v| v / s).collect())
    }
}

/// Separable "same"-size correlation with zero padding of `cin` channels at once, fused
/// with what comes before and after it.
///
/// `fill(y, row)` writes input row `y` of every channel into `row` (`cin` blocks of `w`
/// values, channel after channel). The horizontal pass convolves each block into an
/// interleaved temporary image; the vertical pass accumulates the `cin` blurred blocks of
/// output row `y` and hands them to `emit(y, blurred, out_row)`, which writes `cout` blocks
/// of `w` values and returns a number; the numbers are summed in row order (deterministic
/// whatever the thread count). Both passes are parallel over rows and vectorise along x;
/// no intermediate image is stored except the horizontal pass's output.
fn separable<T: Real>(
    w: usize,
    h: usize,
    k: &[T],
    cin: usize,
    fill: impl Fn(usize, &mut [T]) + Sync,
    cout: usize,
    emit: impl Fn(usize, &[T], &mut [T]) -> f64 + Sync,
) -> (Vec<T>, f64) {
    let r = (k.len() / 2) as isize;
    let wi = w as isize;
    let mut tmp = vec![T::zero(); cin * w * h];
    tmp.par_chunks_mut(cin * w).enumerate().for_each_init(
        || vec![T::zero(); cin * w],
        |row, (y, trow)| {
            fill(y, row);
            for c in 0..cin {
                let (src, out) = (&row[c * w..][..w], &mut trow[c * w..][..w]);
                for (j, &kj) in k.iter().enumerate() {
                    let off = j as isize - r;
                    let (a, b) = ((-off).max(0), (wi - off).min(wi));
                    if a >= b {
                        continue;
                    }
                    let (a, b) = (a as usize, b as usize);
                    let s0 = (a as isize + off) as usize;
                    for (o, &v) in out[a..b].iter_mut().zip(&src[s0..s0 + (b - a)]) {
                        *o = *o + kj * v;
                    }
                }
            }
        },
    );
    let mut out = vec![T::zero(); cout * w * h];
    let sums: Vec<f64> = out
        .par_chunks_mut(cout * w)
        .enumerate()
        .map_init(
            || vec![T::zero(); cin * w],
            |acc, (y, orow)| {
                acc.iter_mut().for_each(|a| *a = T::zero());
                for (j, &kj) in k.iter().enumerate() {
                    let yy = y as isize + j as isize - r;
                    if yy < 0 || yy >= h as isize {
                        continue;
                    }
                    let trow = &tmp[yy as usize * cin * w..][..cin * w];
                    for (a, &t) in acc.iter_mut().zip(trow) {
                        *a = *a + kj * t;
                    }
                }
                emit(y, acc, orow)
            },
        )
        .collect();
    (out, sums.iter().sum())
}

/// The four SSIM factors at one pixel.
#[inline(always)]
fn factors<T: Real>(mx: T, my: T, mxx: T, myy: T, mxy: T) -> (T, T, T, T) {
    let two = cst::<T>(2.0);
    let (c1, c2) = (cst::<T>(SSIM_C1), cst::<T>(SSIM_C2));
    let a1 = two * mx * my + c1;
    let a2 = two * (mxy - mx * my) + c2;
    let b1 = mx * mx + my * my + c1;
    let b2 = (mxx - mx * mx) + (myy - my * my) + c2;
    (a1, a2, b1, b2)
}

/// Row `y` of the five SSIM inputs `x, y, x², y², xy`.
fn fill_moments<'a, T: Real>(
    x: &'a [T],
    t: &'a [T],
    w: usize,
) -> impl Fn(usize, &mut [T]) + Sync + 'a {
    move |y, row| {
        let (xr, tr) = (&x[y * w..][..w], &t[y * w..][..w]);
        let (r0, rest) = row.split_at_mut(w);
        let (r1, rest) = rest.split_at_mut(w);
        let (r2, rest) = rest.split_at_mut(w);
        let (r3, r4) = rest.split_at_mut(w);
        for i in 0..w {
            let (a, b) = (xr[i], tr[i]);
            r0[i] = a;
            r1[i] = b;
            r2[i] = a * a;
            r3[i] = b * b;
            r4[i] = a * b;
        }
    }
}

/// The per-pixel SSIM map `S(p)` of two `width × height` images (zero-padded borders,
/// 11-pixel window, σ = 1.5).
pub fn ssim_map<T: Real>(pred: &[T], target: &[T], width: usize, height: usize) -> Result<Vec<T>> {
    Ok(ssim_map_with(&DSsim::default(), pred, target, width, height)?.0)
}

/// The SSIM map and its sum.
fn ssim_map_with<T: Real>(
    cfg: &DSsim,
    pred: &[T],
    target: &[T],
    width: usize,
    height: usize,
) -> Result<(Vec<T>, f64)> {
    check_pair(pred, target, width, height)?;
    let k: Vec<T> = cfg.kernel()?.into_iter().map(cst).collect();
    let w = width;
    Ok(separable(
        width,
        height,
        &k,
        5,
        fill_moments(pred, target, w),
        1,
        |_, b, out| {
            let mut sum = 0.0;
            for (i, o) in out.iter_mut().enumerate() {
                let (a1, a2, b1, b2) =
                    factors(b[i], b[w + i], b[2 * w + i], b[3 * w + i], b[4 * w + i]);
                *o = a1 * a2 / (b1 * b2);
                sum += f64_of(*o);
            }
            sum
        },
    ))
}

/// Mean SSIM of two `width × height` images (zero-padded borders, 11-pixel window, σ = 1.5).
pub fn ssim<T: Real>(pred: &[T], target: &[T], width: usize, height: usize) -> Result<f64> {
    let (_, sum) = ssim_map_with(&DSsim::default(), pred, target, width, height)?;
    Ok(sum / (width * height) as f64)
}

impl ImageLoss for DSsim {
    fn name(&self) -> &'static str {
        "d_ssim"
    }

    fn value_and_grad<T: Real>(
        &self,
        pred: &[T],
        target: &[T],
        width: usize,
        height: usize,
    ) -> Result<(T, Vec<T>)> {
        check_pair(pred, target, width, height)?;
        let k: Vec<T> = self.kernel()?.into_iter().map(cst).collect();
        let (w, n) = (width, width * height);
        let two = cst::<T>(2.0);
        // Forward, fused with the per-pixel derivatives ∂S/∂μx, ∂S/∂mxx, ∂S/∂mxy
        // (three interleaved blocks per row).
        let (derivs, sum) = separable(
            width,
            height,
            &k,
            5,
            fill_moments(pred, target, w),
            3,
            |_, b, out| {
                let mut sum = 0.0;
                let (d_mu, rest) = out.split_at_mut(w);
                let (d_xx, d_xy) = rest.split_at_mut(w);
                for i in 0..w {
                    let (mx, my) = (b[i], b[w + i]);
                    let (a1, a2, b1, b2) =
                        factors(mx, my, b[2 * w + i], b[3 * w + i], b[4 * w + i]);
                    let inv = T::one() / (b1 * b2);
                    let v = a1 * a2 * inv;
                    sum += f64_of(v);
                    d_mu[i] =
                        two * my * (a2 - a1) * inv - two * mx * v * (T::one() / b1 - T::one() / b2);
                    d_xx[i] = -v / b2;
                    d_xy[i] = two * a1 * inv;
                }
                sum
            },
        );
        let value = 1.0 - sum / n as f64;
        // Backward: blur the three derivative maps (the blur is self-adjoint) and combine.
        let scale = cst::<T>(-1.0 / n as f64);
        let (grad, _) = separable(
            width,
            height,
            &k,
            3,
            |y, row| row.copy_from_slice(&derivs[y * 3 * w..][..3 * w]),
            1,
            |y, b, out| {
                let (xr, tr) = (&pred[y * w..][..w], &target[y * w..][..w]);
                for (i, o) in out.iter_mut().enumerate() {
                    *o = scale * (b[i] + two * xr[i] * b[w + i] + tr[i] * b[2 * w + i]);
                }
                0.0
            },
        );
        Ok((cst(value), grad))
    }

    fn value<T: Real>(&self, pred: &[T], target: &[T], width: usize, height: usize) -> Result<T> {
        let (_, sum) = ssim_map_with(self, pred, target, width, height)?;
        Ok(cst(1.0 - sum / (width * height) as f64))
    }
}

/// Separable "same"-size correlation with zero padding: `out = k ⊗ k ∗ src` for an odd,
/// symmetric 1-D kernel `k`. Both passes are parallel over rows and vectorise along x.
pub fn blur_same<T: Real>(src: &[T], width: usize, height: usize, k: &[T]) -> Vec<T> {
    separable(
        width,
        height,
        k,
        1,
        |y, row| row.copy_from_slice(&src[y * width..][..width]),
        1,
        |_, b, out| {
            out.copy_from_slice(b);
            0.0
        },
    )
    .0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_is_normalised_and_symmetric() {
        let k = DSsim::default().kernel().unwrap();
        assert_eq!(k.len(), 11);
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        for i in 0..11 {
            assert_eq!(k[i], k[10 - i]);
        }
        assert!(
            DSsim {
                window: 10,
                sigma: 1.5
            }
            .kernel()
            .unwrap_err()
            .to_string()
            .contains("odd")
        );
    }

    #[test]
    fn blur_is_self_adjoint() {
        // <G x, y> = <x, G y> for the zero-padded blur with a symmetric kernel.
        let (w, h) = (13, 9);
        let k = DSsim::default().kernel().unwrap();
        let x: Vec<f64> = (0..w * h)
            .map(|i| ((i * 31 % 17) as f64 * 0.3).sin())
            .collect();
        let y: Vec<f64> = (0..w * h)
            .map(|i| ((i * 7 % 23) as f64 * 0.2).cos())
            .collect();
        let gx = blur_same(&x, w, h, &k);
        let gy = blur_same(&y, w, h, &k);
        let lhs: f64 = gx.iter().zip(&y).map(|(a, b)| a * b).sum();
        let rhs: f64 = x.iter().zip(&gy).map(|(a, b)| a * b).sum();
        assert!((lhs - rhs).abs() < 1e-12);
    }

    #[test]
    fn blur_matches_direct_2d_sum() {
        let (w, h) = (9, 7);
        let k = DSsim::default().kernel().unwrap();
        let x: Vec<f64> = (0..w * h).map(|i| (i as f64 * 0.37).sin().abs()).collect();
        let b = blur_same(&x, w, h, &k);
        for yy in 0..h as isize {
            for xx in 0..w as isize {
                let mut s = 0.0;
                for dy in -5..=5isize {
                    for dx in -5..=5isize {
                        let (u, v) = (xx + dx, yy + dy);
                        if u >= 0 && v >= 0 && u < w as isize && v < h as isize {
                            s += k[(dx + 5) as usize]
                                * k[(dy + 5) as usize]
                                * x[v as usize * w + u as usize];
                        }
                    }
                }
                assert!((s - b[yy as usize * w + xx as usize]).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn ssim_of_an_image_with_itself_is_one() {
        let (w, h) = (20, 16);
        let x: Vec<f64> = (0..w * h).map(|i| ((i * 29 % 31) as f64) / 31.0).collect();
        assert!((ssim(&x, &x, w, h).unwrap() - 1.0).abs() < 1e-12);
        let (v, g) = DSsim::default().value_and_grad(&x, &x, w, h).unwrap();
        assert!(v.abs() < 1e-12);
        // SSIM is maximal at pred = target, so the gradient vanishes there.
        assert!(g.iter().all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn value_only_path_agrees_with_value_and_grad() {
        let (w, h) = (17, 12);
        let x: Vec<f32> = (0..w * h).map(|i| ((i * 29 % 31) as f32) / 31.0).collect();
        let y: Vec<f32> = (0..w * h).map(|i| ((i * 11 % 19) as f32) / 19.0).collect();
        let a = DSsim::default().value(&x, &y, w, h).unwrap();
        let b = DSsim::default().value_and_grad(&x, &y, w, h).unwrap().0;
        assert_eq!(a, b);
    }
}
