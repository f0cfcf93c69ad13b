//! What a fit sees of its target: ink in [0, 1] (the shape bright, as the image problem
//! loads it), the Euclidean distance transform of its dark pixels for the distance loss, and
//! the best-fit line of those pixels for the paper's initialisation.

use ifslab::render::sdf::SdfView;

use crate::error::{Error, Result};

/// Pixels with at least this much ink are the shape ("the black pixels" of the paper).
pub const INK: f64 = 0.5;

/// The exact Euclidean distance, in pixels, from every pixel centre of a `width × height`
/// image to the nearest pixel with `ink ≥ INK` (0 on those pixels), by the separable
/// lower-envelope algorithm of Felzenszwalb & Huttenlocher (columns, then rows). Refuses an
/// image with no such pixel.
pub fn distance_transform(ink: &[f64], width: usize, height: usize) -> Result<Vec<f64>> {
    if ink.len() != width * height {
        return Err(Error::InvalidInput(format!(
            "{} values for a {width}×{height} image",
            ink.len()
        )));
    }
    if !ink.iter().any(|&v| v >= INK) {
        return Err(Error::InvalidInput(format!(
            "the target has no pixel with ink ≥ {INK}: nothing to fit (is the polarity right?)"
        )));
    }
    const FAR: f64 = 1e20;
    let mut f: Vec<f64> = ink
        .iter()
        .map(|&v| if v >= INK { 0.0 } else { FAR })
        .collect();
    let mut col = vec![0.0; height];
    let mut out = vec![0.0; height.max(width)];
    for j in 0..width {
        for i in 0..height {
            col[i] = f[i * width + j];
        }
        squared_1d(&col, &mut out[..height]);
        for i in 0..height {
            f[i * width + j] = out[i];
        }
    }
    let mut row = vec![0.0; width];
    for i in 0..height {
        row.copy_from_slice(&f[i * width..(i + 1) * width]);
        squared_1d(&row, &mut out[..width]);
        for j in 0..width {
            f[i * width + j] = out[j].sqrt();
        }
    }
    Ok(f)
}

/// `out[q] = min_p (q − p)² + f[p]`: the 1-D squared distance transform.
fn squared_1d(f: &[f64], out: &mut [f64]) {
    let n = f.len();
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64);
            if s <= z[k] && k > 0 {
                k -= 1;
                continue;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
            break;
        }
    }
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let d = q as f64 - v[k] as f64;
        *o = d * d + f[v[k]];
    }
}

/// The best-fit line of the target's dark pixels (ink ≥ [`INK`]) in the plane of `view`:
/// its two ends, the extreme projections of those pixels' centres on their principal axis.
/// The axis points to +x (to +y when vertical), so the result is deterministic.
pub fn best_fit_line(ink: &[f64], view: &SdfView) -> Result<[[f64; 2]; 2]> {
    let pts: Vec<[f64; 2]> = (0..view.height)
        .flat_map(|i| (0..view.width).map(move |j| (i, j)))
        .filter(|&(i, j)| ink[i * view.width + j] >= INK)
        .map(|(i, j)| view.centre(i, j))
        .collect();
    if pts.len() < 2 {
        return Err(Error::InvalidInput(format!(
            "the target has {} pixel(s) with ink ≥ {INK}; a best-fit line needs at least 2",
            pts.len()
        )));
    }
    let n = pts.len() as f64;
    let c = pts
        .iter()
        .fold([0.0, 0.0], |s, p| [s[0] + p[0] / n, s[1] + p[1] / n]);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in &pts {
        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    // Principal axis of [[sxx, sxy], [sxy, syy]]: angle ½·atan2(2 sxy, sxx − syy).
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let mut u = [angle.cos(), angle.sin()];
    if u[0] < -1e-12 || (u[0].abs() <= 1e-12 && u[1] < 0.0) {
        u = [-u[0], -u[1]];
    }
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in &pts {
        let t = (p[0] - c[0]) * u[0] + (p[1] - c[1]) * u[1];
        lo = lo.min(t);
        hi = hi.max(t);
    }
    Ok([
        [c[0] + lo * u[0], c[1] + lo * u[1]],
        [c[0] + hi * u[0], c[1] + hi * u[1]],
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_transform_is_exact_on_a_small_image() {
        let (w, h) = (7, 5);
        let mut ink = vec![0.0; w * h];
        ink[w + 2] = 1.0;
        ink[3 * w + 5] = 0.8;
        let d = distance_transform(&ink, w, h).unwrap();
        for i in 0..h {
            for j in 0..w {
                let brute = [(1.0, 2.0), (3.0, 5.0)]
                    .iter()
                    .map(|&(a, b): &(f64, f64)| (i as f64 - a).hypot(j as f64 - b))
                    .fold(f64::INFINITY, f64::min);
                assert!((d[i * w + j] - brute).abs() < 1e-12, "({i}, {j})");
            }
        }
        assert!(distance_transform(&[0.0; 4], 2, 2).is_err());
    }

    #[test]
    fn best_fit_line_of_a_diagonal() {
        let v = SdfView::unit_square(10);
        let mut ink = vec![0.0; 100];
        for k in 2..8 {
            ink[(9 - k) * 10 + k] = 1.0; // rows go down, y up: the line y = x
        }
        let [a, b] = best_fit_line(&ink, &v).unwrap();
        assert!(
            (a[0] - 0.25).abs() < 1e-12 && (a[1] - 0.25).abs() < 1e-12,
            "{a:?}"
        );
        assert!(
            (b[0] - 0.75).abs() < 1e-12 && (b[1] - 0.75).abs() < 1e-12,
            "{b:?}"
        );
    }
}
