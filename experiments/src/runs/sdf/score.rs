//! A fitted pattern against the pattern that drew its target: both drawn at one size and compared by the IoU of their ink.

use super::*;

/// Side of the canvas a fitted pattern and its truth are compared on.
pub const TRUTH_SIZE: usize = 128;

/// Width σ (pixels of [`TRUTH_SIZE`]) both are drawn with when compared.
pub const TRUTH_SIGMA: f64 = 1.5;

/// The ink of `pattern` at `depth` and width `sigma`, framed in its own box on a `size²`
/// canvas as a target is framed ([`FIT_FILL`]).
pub(super) fn framed_ink(
    pattern: &Pattern,
    size: usize,
    depth: usize,
    sigma: f64,
) -> crate::Result<Vec<f64>> {
    let tree = WordTree::new(&pattern.maps()?, pattern.base_points(), depth)?;
    let (lo, hi) = tree.bbox();
    let view = SdfView::around(lo, hi, size, FIT_FILL);
    let r = SdfRaster::render(
        pattern,
        &view,
        &SdfRenderConfig {
            depth,
            cutoff: Some(CUTOFF_SIGMAS * sigma),
        },
    )?;
    Ok(r.image(sigma))
}

/// IoU of two patterns' ink (≥ [`INK`]), each drawn at `depth` and width `sigma` framed in
/// its own box on a `size²` canvas: where they differ in shape, not in where a picture put
/// them.
pub fn pattern_iou(
    a: &Pattern,
    b: &Pattern,
    size: usize,
    depth: usize,
    sigma: f64,
) -> crate::Result<f64> {
    let mask = |p: &Pattern| -> crate::Result<Vec<bool>> {
        Ok(framed_ink(p, size, depth, sigma)?
            .iter()
            .map(|&v| v >= INK)
            .collect())
    };
    Ok(ifslab::metrics::iou(&mask(a)?, &mask(b)?)?)
}
