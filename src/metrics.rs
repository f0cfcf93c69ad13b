//! Evaluation metrics on rendered images and masks.

use crate::error::{Error, Result};

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
