//! What a fit sees of its target: ink in [0, 1] (the shape bright, as the image problem
//! loads it), the Euclidean distance transform of its dark pixels for the distance loss, and
//! the best-fit line of those pixels for the paper's initialisation.

use ifslab::render::sdf::SdfView;

use crate::error::{Error, Result};

/// Pixels with at least this much ink are the shape ("the black pixels" of the paper).
pub const INK: f64 = 0.5;

/// Scales a framed target (ink in [0, 1]) so that its lines reach full ink: a line thinner
/// than a pixel of the framed size (a 1-pixel curve of a 1024² picture seen at 128²) keeps
/// its place but loses its level in the resampling, while the fit draws every line at full
/// ink, `exp(−d²/σ²)`. The ink level is the 98th percentile of the pixels above a tenth of
/// the brightest; a target already at full ink is left as it is.
pub fn stretch_ink(target: &mut [f32]) {
    let max = target.iter().copied().fold(0.0f32, f32::max);
    let mut inked: Vec<f32> = target.iter().copied().filter(|&v| v > 0.1 * max).collect();
    if inked.is_empty() {
        return;
    }
    let k = ((inked.len() - 1) as f64 * 0.98).round() as usize;
    let level = *inked.select_nth_unstable_by(k, f32::total_cmp).1;
    if level > 0.0 && level < 1.0 {
        for v in target.iter_mut() {
            *v = (*v / level).min(1.0);
        }
    }
}

/// Bounds of the σ [`stroke_sigma`] returns, in pixels.
pub const STROKE_SIGMA_RANGE: (f64, f64) = (0.75, 4.0);

/// The width σ (pixels) at which the fit's figure, `exp(−d²/σ²)`, is as wide above half ink
/// as a stroke `width` pixels wide (`σ = W / (2√ln 2)`), within [`STROKE_SIGMA_RANGE`].
pub fn sigma_for_stroke(width: f64) -> f64 {
    (width / (2.0 * std::f64::consts::LN_2.sqrt()))
        .clamp(STROKE_SIGMA_RANGE.0, STROKE_SIGMA_RANGE.1)
}

/// The exact Euclidean distance, in pixels, from every pixel centre of a `width × height`
/// image to the nearest pixel with `ink ≥ INK` (0 on those pixels)
/// ([`ifslab::image::distance_to`]). Refuses an image with no such pixel.
pub fn distance_transform(ink: &[f64], width: usize, height: usize) -> Result<Vec<f64>> {
    if ink.len() != width * height {
        return Err(Error::InvalidInput(format!(
            "{} values for a {width}×{height} image",
            ink.len()
        )));
    }
    let mask: Vec<bool> = ink.iter().map(|&v| v >= INK).collect();
    ifslab::image::distance_to(&mask, width, height).ok_or_else(|| {
        Error::InvalidInput(format!(
            "the target has no pixel with ink ≥ {INK}: nothing to fit (is the polarity right?)"
        ))
    })
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

    #[test]
    fn faint_lines_are_stretched_to_full_ink_and_strokes_set_sigma() {
        let mut t = vec![0.0f32, 0.3, 0.1, 0.32, 0.0, 0.31];
        stretch_ink(&mut t);
        assert!(
            t[3] == 1.0 && t[0] == 0.0 && (t[1] - 0.3 / 0.32).abs() < 1e-6,
            "{t:?}"
        );
        let mut full = vec![0.0f32, 1.0, 0.5];
        stretch_ink(&mut full);
        assert_eq!(full, vec![0.0, 1.0, 0.5]);
        // σ for a stroke: half ink at the stroke's edge, within the bounds.
        let s = sigma_for_stroke(2.5);
        assert!((2.0 * s * std::f64::consts::LN_2.sqrt() - 2.5).abs() < 1e-12);
        assert_eq!(sigma_for_stroke(0.1), STROKE_SIGMA_RANGE.0);
        assert_eq!(sigma_for_stroke(100.0), STROKE_SIGMA_RANGE.1);
    }
}
