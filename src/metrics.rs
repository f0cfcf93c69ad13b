//! Evaluation metrics on rendered images and masks.
//!
//! Mask metrics: [`iou`], [`f1`], [`box_counting_dimension`]. Image metrics on row-major grey
//! images in [0, 1]: [`psnr`], [`ssim`] (the loss module's zero-padded SSIM with an
//! 11-pixel, σ = 1.5 window), [`lpips`] (AlexNet v0.1), their masked variants, and
//! [`paper_metrics`], the chaotic-splatting paper's evaluation protocol: a 12.5% border crop
//! (the margin the framing leaves around the attractor) and PSNR/SSIM on the pixels where
//! either image is > 0, so the black background does not inflate the scores.
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point
//!   Splatting*, Eurographics 2025 (evaluation protocol).
//! - Wang et al., *Image Quality Assessment: From Error Visibility to Structural
//!   Similarity*, IEEE TIP 2004; Zhang et al., *The Unreasonable Effectiveness of Deep
//!   Features as a Perceptual Metric*, CVPR 2018.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::loss::lpips::Lpips;
use crate::loss::{Real, f64_of};

/// Intersection over union of two masks of equal length; 1 when both are empty.
pub fn iou(a: &[bool], b: &[bool]) -> Result<f64> {
    if a.len() != b.len() {
        return Err(Error::Shape(format!(
            "masks of {} and {} pixels",
            a.len(),
            b.len()
        )));
    }
    let (mut inter, mut uni) = (0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        inter += u64::from(x && y);
        uni += u64::from(x || y);
    }
    Ok(if uni == 0 {
        1.0
    } else {
        inter as f64 / uni as f64
    })
}

/// F1 score (Dice coefficient) of a predicted mask against a target mask of equal length:
/// `2·|a ∧ b| / (|a| + |b|)`; 1 when both are empty. Per image it is `2·IoU/(1 + IoU)`; the
/// paper reports both because their means over many images differ.
pub fn f1(pred: &[bool], target: &[bool]) -> Result<f64> {
    if pred.len() != target.len() {
        return Err(Error::Shape(format!(
            "masks of {} and {} pixels",
            pred.len(),
            target.len()
        )));
    }
    let (mut inter, mut total) = (0u64, 0u64);
    for (&x, &y) in pred.iter().zip(target) {
        inter += u64::from(x && y);
        total += u64::from(x) + u64::from(y);
    }
    Ok(if total == 0 {
        1.0
    } else {
        2.0 * inter as f64 / total as f64
    })
}

/// Box-counting (Minkowski–Bouligand) dimension estimate of a `width × height` mask.
///
/// Counts occupied boxes of side `2^k` pixels for `k` in `min_log2..=max_log2` and returns
/// the least-squares slope of `log N(ε)` against `log(1/ε)`, with the counts used.
pub fn box_counting_dimension(
    mask: &[bool],
    width: usize,
    height: usize,
    min_log2: u32,
    max_log2: u32,
) -> Result<(f64, Vec<(usize, u64)>)> {
    if mask.len() != width * height {
        return Err(Error::Shape(format!(
            "mask of {} pixels for {width}×{height}",
            mask.len()
        )));
    }
    if min_log2 >= max_log2 {
        return Err(Error::param("box sizes", "need min_log2 < max_log2"));
    }
    let mut counts = Vec::new();
    for k in min_log2..=max_log2 {
        let b = 1usize << k;
        let (bw, bh) = (width.div_ceil(b), height.div_ceil(b));
        let mut occ = vec![false; bw * bh];
        for y in 0..height {
            for x in 0..width {
                if mask[y * width + x] {
                    occ[(y / b) * bw + x / b] = true;
                }
            }
        }
        counts.push((b, occ.iter().filter(|&&o| o).count() as u64));
    }
    if counts.iter().any(|&(_, n)| n == 0) {
        return Err(Error::Empty("the mask has no set pixels".into()));
    }
    let xs: Vec<f64> = counts.iter().map(|&(b, _)| -(b as f64).ln()).collect();
    let ys: Vec<f64> = counts.iter().map(|&(_, n)| (n as f64).ln()).collect();
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    Ok((sxy / sxx, counts))
}

/// The fraction of each side the paper's evaluation crops away (the framing's margin).
pub const EVAL_BORDER_FRACTION: f64 = 0.125;

fn check_same_len<T, U>(pred: &[T], target: &[U]) -> Result<()> {
    if pred.len() != target.len() {
        return Err(Error::Shape(format!(
            "images of {} and {} pixels",
            pred.len(),
            target.len()
        )));
    }
    if pred.is_empty() {
        return Err(Error::Empty("images with no pixels".into()));
    }
    Ok(())
}

fn psnr_from_mse(mse: f64, peak: f64) -> f64 {
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (peak * peak / mse).log10()
    }
}

/// Peak signal-to-noise ratio in dB, `10·log10(peak² / MSE)`, for images with values in
/// `[0, peak]`; `+∞` for identical images.
pub fn psnr<T: Real>(pred: &[T], target: &[T], peak: f64) -> Result<f64> {
    check_same_len(pred, target)?;
    let se: f64 = pred
        .iter()
        .zip(target)
        .map(|(&p, &t)| (f64_of(p) - f64_of(t)).powi(2))
        .sum();
    Ok(psnr_from_mse(se / pred.len() as f64, peak))
}

/// [`psnr`] over the pixels where `mask` is true.
pub fn psnr_masked<T: Real>(pred: &[T], target: &[T], mask: &[bool], peak: f64) -> Result<f64> {
    check_same_len(pred, target)?;
    check_same_len(pred, mask)?;
    let (mut se, mut n) = (0.0, 0usize);
    for ((&p, &t), &m) in pred.iter().zip(target).zip(mask) {
        if m {
            se += (f64_of(p) - f64_of(t)).powi(2);
            n += 1;
        }
    }
    if n == 0 {
        return Err(Error::Empty("the PSNR mask selects no pixel".into()));
    }
    Ok(psnr_from_mse(se / n as f64, peak))
}

/// Mean SSIM of two `width × height` images (see [`crate::loss::ssim()`]: 11-pixel Gaussian
/// window, σ = 1.5, zero-padded borders); 1 for identical images.
pub fn ssim<T: Real>(pred: &[T], target: &[T], width: usize, height: usize) -> Result<f64> {
    crate::loss::ssim::ssim(pred, target, width, height)
}

/// SSIM averaged over the pixels where `mask` is true. The SSIM map is computed on the
/// whole image first, so masked pixels still see their true neighbourhood.
pub fn ssim_masked<T: Real>(
    pred: &[T],
    target: &[T],
    width: usize,
    height: usize,
    mask: &[bool],
) -> Result<f64> {
    let map = crate::loss::ssim::ssim_map(pred, target, width, height)?;
    check_same_len(&map, mask)?;
    let (mut s, mut n) = (0.0, 0usize);
    for (&v, &m) in map.iter().zip(mask) {
        if m {
            s += f64_of(v);
            n += 1;
        }
    }
    if n == 0 {
        return Err(Error::Empty("the SSIM mask selects no pixel".into()));
    }
    Ok(s / n as f64)
}

/// LPIPS (AlexNet, v0.1 heads) between two `width × height` grey images; 0 for identical
/// images. Load the network once with [`Lpips::load_default`] or [`Lpips::try_load_default`].
pub fn lpips<T: Real + candle_core::WithDType>(
    net: &Lpips,
    pred: &[T],
    target: &[T],
    width: usize,
    height: usize,
) -> Result<f64> {
    net.distance_images(pred, target, width, height)
}

/// The rectangle `(x0, y0, width, height)` left after cropping `fraction` of each side from
/// every border (rounded to whole pixels).
pub fn border_crop_rect(
    width: usize,
    height: usize,
    fraction: f64,
) -> Result<(usize, usize, usize, usize)> {
    if !(0.0..0.5).contains(&fraction) {
        return Err(Error::param(
            "fraction",
            format!("the border fraction must be in [0, 0.5), got {fraction}"),
        ));
    }
    let x0 = (fraction * width as f64).round() as usize;
    let y0 = (fraction * height as f64).round() as usize;
    let (w, h) = (width.saturating_sub(2 * x0), height.saturating_sub(2 * y0));
    if w == 0 || h == 0 {
        return Err(Error::Empty(format!(
            "cropping {fraction} of each side of a {width}×{height} image leaves no pixel"
        )));
    }
    Ok((x0, y0, w, h))
}

/// The pixels of a row-major `width × height` image inside `rect = (x0, y0, w, h)`.
pub fn crop<T: Copy>(img: &[T], width: usize, rect: (usize, usize, usize, usize)) -> Vec<T> {
    let (x0, y0, w, h) = rect;
    (y0..y0 + h)
        .flat_map(|y| img[y * width + x0..y * width + x0 + w].iter().copied())
        .collect()
}

/// Pixels where either image is above `threshold` (the paper: 0).
pub fn foreground_mask<T: Real>(pred: &[T], target: &[T], threshold: f64) -> Vec<bool> {
    pred.iter()
        .zip(target)
        .map(|(&p, &t)| f64_of(p) > threshold || f64_of(t) > threshold)
        .collect()
}

/// Scores of a rendered image against its target under the paper's protocol.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageMetrics {
    /// PSNR (dB) on the foreground pixels of the crop.
    pub psnr: f64,
    /// SSIM averaged over the foreground pixels of the crop.
    pub ssim: f64,
    /// LPIPS of the cropped images, when a network was given.
    pub lpips: Option<f64>,
    /// IoU of the `> 0` masks inside the crop.
    pub iou: f64,
    /// F1 score (Dice) of the `> 0` masks inside the crop.
    pub f1: f64,
    /// Number of foreground pixels the PSNR and SSIM averaged over.
    pub foreground_pixels: usize,
    /// PSNR (dB) over every pixel of the crop, background included (the usual image-metric
    /// reading where a protocol does not say "foreground").
    pub psnr_crop: f64,
    /// SSIM averaged over every pixel of the crop, background included (black on black
    /// scores 1 there).
    pub ssim_crop: f64,
}

/// The chaotic-splatting paper's evaluation: crop [`EVAL_BORDER_FRACTION`] of each side, then
/// PSNR and SSIM over the pixels where either image is > 0 (the SSIM map is computed on the
/// full image, then cropped and masked), IoU and F1 of the `> 0` masks, and LPIPS of the
/// cropped images if `net` is given (the crop must be at least [`LPIPS_MIN_SIDE`] pixels a
/// side). PSNR and SSIM over the whole crop come too: the paper's text does not say which
/// pixels its PSNR and SSIM average over.
///
/// [`LPIPS_MIN_SIDE`]: crate::loss::lpips::LPIPS_MIN_SIDE Images are row-major, values in [0, 1].
pub fn paper_metrics<T: Real + candle_core::WithDType>(
    pred: &[T],
    target: &[T],
    width: usize,
    height: usize,
    net: Option<&Lpips>,
) -> Result<ImageMetrics> {
    cropped_metrics(pred, target, width, height, EVAL_BORDER_FRACTION, net)
}

/// [`paper_metrics`] with another border: `border_fraction` of each side is left out (0 for
/// a zoomed-in patch, whose window is filled edge to edge, where a full view's margin is
/// empty by construction).
pub fn cropped_metrics<T: Real + candle_core::WithDType>(
    pred: &[T],
    target: &[T],
    width: usize,
    height: usize,
    border_fraction: f64,
    net: Option<&Lpips>,
) -> Result<ImageMetrics> {
    crate::loss::check_pair(pred, target, width, height)?;
    let rect = border_crop_rect(width, height, border_fraction)?;
    let (p, t) = (crop(pred, width, rect), crop(target, width, rect));
    let mask = foreground_mask(&p, &t, 0.0);
    let foreground_pixels = mask.iter().filter(|&&m| m).count();
    if foreground_pixels == 0 {
        return Err(Error::Empty(
            "both images are black inside the evaluation crop; nothing to score".into(),
        ));
    }
    let map = crate::loss::ssim::ssim_map(pred, target, width, height)?;
    let map = crop(&map, width, rect);
    let ssim = map
        .iter()
        .zip(&mask)
        .filter(|(_, m)| **m)
        .map(|(&v, _)| f64_of(v))
        .sum::<f64>()
        / foreground_pixels as f64;
    let ssim_crop = map.iter().map(|&v| f64_of(v)).sum::<f64>() / map.len() as f64;
    let pm: Vec<bool> = p.iter().map(|&v| f64_of(v) > 0.0).collect();
    let tm: Vec<bool> = t.iter().map(|&v| f64_of(v) > 0.0).collect();
    let lpips = match net {
        Some(net) => Some(net.distance_images(&p, &t, rect.2, rect.3)?),
        None => None,
    };
    Ok(ImageMetrics {
        psnr: psnr_masked(&p, &t, &mask, 1.0)?,
        ssim,
        lpips,
        iou: iou(&pm, &tm)?,
        f1: f1(&pm, &tm)?,
        foreground_pixels,
        psnr_crop: psnr(&p, &t, 1.0)?,
        ssim_crop,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f1_is_dice_and_agrees_with_iou_per_image() {
        let a = [true, true, true, false, false, true];
        let b = [true, false, true, true, false, false];
        // |a ∧ b| = 2, |a| = 4, |b| = 3: F1 = 4/7, IoU = 2/5.
        let (f, j) = (f1(&a, &b).unwrap(), iou(&a, &b).unwrap());
        assert!((f - 4.0 / 7.0).abs() < 1e-15 && (j - 0.4).abs() < 1e-15);
        assert!((f - 2.0 * j / (1.0 + j)).abs() < 1e-15);
        assert_eq!(f1(&[false; 3], &[false; 3]).unwrap(), 1.0);
        assert_eq!(f1(&[true, false], &[false, true]).unwrap(), 0.0);
        assert!(f1(&[true], &[true, false]).is_err());
    }

    #[test]
    fn full_square_has_dimension_two() {
        let (d, _) = box_counting_dimension(&vec![true; 256 * 256], 256, 256, 0, 6).unwrap();
        assert!((d - 2.0).abs() < 1e-9);
    }

    #[test]
    fn line_has_dimension_one() {
        let mut m = vec![false; 256 * 256];
        for x in 0..256 {
            m[100 * 256 + x] = true;
        }
        let (d, _) = box_counting_dimension(&m, 256, 256, 0, 6).unwrap();
        assert!((d - 1.0).abs() < 1e-9);
    }

    #[test]
    fn psnr_of_a_known_error() {
        // MSE = 0.01 ⇒ PSNR = 20 dB.
        let t = vec![0.5f64; 100];
        let p: Vec<f64> = t.iter().map(|v| v + 0.1).collect();
        assert!((psnr(&p, &t, 1.0).unwrap() - 20.0).abs() < 1e-9);
        assert_eq!(psnr(&t, &t, 1.0).unwrap(), f64::INFINITY);
        let mut mask = vec![false; 100];
        mask[3] = true;
        assert!((psnr_masked(&p, &t, &mask, 1.0).unwrap() - 20.0).abs() < 1e-9);
        assert!(psnr_masked(&p, &t, &[false; 100], 1.0).is_err());
    }

    #[test]
    fn crop_takes_the_centre() {
        let (w, h) = (16, 8);
        let img: Vec<usize> = (0..w * h).collect();
        let rect = border_crop_rect(w, h, EVAL_BORDER_FRACTION).unwrap();
        assert_eq!(rect, (2, 1, 12, 6));
        let c = crop(&img, w, rect);
        assert_eq!(c.len(), 72);
        assert_eq!(c[0], w + 2);
        assert!(border_crop_rect(4, 4, 0.5).is_err());
    }

    #[test]
    fn paper_metrics_ignore_the_border_and_the_background() {
        let (w, h) = (64, 64);
        let mut t = vec![0.0f64; w * h];
        for y in 24..40 {
            for x in 20..44 {
                t[y * w + x] = 0.8;
            }
        }
        // Garbage in the cropped border changes nothing.
        let mut p = t.clone();
        for v in p.iter_mut().take(w * 4) {
            *v = 1.0;
        }
        let m = paper_metrics(&p, &t, w, h, None).unwrap();
        assert_eq!(m.psnr, f64::INFINITY);
        assert_eq!(m.iou, 1.0);
        assert_eq!(m.foreground_pixels, 16 * 24);
        assert!((m.ssim - ssim_masked(&t, &t, w, h, &vec![true; w * h]).unwrap()).abs() < 1e-12);
        // An error on the foreground shows.
        let mut q = t.clone();
        q[30 * w + 30] = 0.0;
        let m = paper_metrics(&q, &t, w, h, None).unwrap();
        assert!(m.psnr.is_finite() && m.ssim < 1.0 && m.iou < 1.0);
        // Over the whole crop the one wrong pixel weighs less: the background matches.
        let (fg, all) = (m.foreground_pixels as f64, (48 * 48) as f64);
        let db = 10.0 * (all / fg).log10();
        assert!(
            (m.psnr_crop - m.psnr - db).abs() < 1e-9,
            "{} {}",
            m.psnr_crop,
            m.psnr
        );
        assert!(m.ssim_crop > m.ssim && m.ssim_crop < 1.0);
        assert!(paper_metrics(&vec![0.0; w * h], &vec![0.0; w * h], w, h, None).is_err());
    }
}
